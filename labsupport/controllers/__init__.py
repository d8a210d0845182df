"""Control laws, one function each, named after the concept, with the equation in
the docstring.

``single_joint``       PI speed, PD, feedforward and computed torque for the 1R arm
``joint_space``        joint PD and joint computed torque for MuJoCo arms
``operational_space``  operational-space computed torque (IK + joint CT composes
                       ``kinematics.planar_2r.joint_reference`` with
                       ``joint_space.ct_joint_torque``)
``ur5e``               operational-space control of the UR5e through its servos
"""
