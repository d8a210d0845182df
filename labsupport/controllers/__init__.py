"""Controllers as small functions of plain arrays (state, reference, gains) returning torque.

``single_joint``       PI speed, PD, feedforward and computed torque for the 1R arm
``joint_space``        joint PD and computed torque for MuJoCo arms (2R, 3R)
``operational_space``  operational-space CT and IK + joint CT (2R, 3R)
``ur5e``               operational-space control of the UR5e through its position servos
"""
