"""Forward and inverse kinematics, Jacobians and workspace sampling of the Tasks'
arms.

``planar_2r``   the 2R planar arm of Task 3

The 3R spatial arm of the Problems has no kinematics here on purpose: its inverse
kinematics is the students' first TODO. Its forward kinematics is MuJoCo's
(``mj_kinematics``, then ``data.site_xpos``), its Jacobian and :math:`\\dot J\\dot q`
are in :mod:`labsupport.dynamics`.
"""
