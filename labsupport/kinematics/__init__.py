"""Forward and inverse kinematics, Jacobians and workspace sampling.

``planar_2r``   the 2R planar arm of Task 3
``spatial_3r``  the 3R spatial arm of the Problems
"""
