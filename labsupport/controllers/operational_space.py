r"""Operational-space computed torque for arms whose task Jacobian is square (the 2R
in its plane, a 3R in space).

The task is the first :math:`d` coordinates of a site's position, :math:`d` being the
length of the reference: :math:`(x, y)` for the planar 2R, :math:`(x, y, z)` for a
3R. Position, Jacobian and :math:`\dot J\dot q` come from MuJoCo
(:mod:`labsupport.dynamics`).

IK + joint-space CT needs no law of its own: the Cartesian reference becomes a joint
reference once, before the run
(:func:`labsupport.kinematics.planar_2r.joint_reference`), and
:func:`labsupport.controllers.joint_space.ct_joint_torque` tracks it.
"""

from __future__ import annotations

from labsupport.dynamics import (
    jacobian_solve,
    mass_times,
    site_id,
    site_jacobian,
    site_jdot_qdot,
)


def os_ct_torque(model, data, site, x_d, xdot_d, xddot_d, Kp, Kd):
    r"""Operational-space computed torque:

    .. math:: \tau = M(q)\,J^{-1}\big(\ddot x_d + K_d(\dot x_d - \dot x)
                     + K_p(x_d - x) - \dot J\dot q\big)
                     + h(q,\dot q), \qquad \dot x = J\dot q

    With an exact model the task error obeys :math:`\ddot e + K_d\dot e + K_p e = 0`.
    A singular :math:`J` (arm stretched out or folded) raises ``ValueError``.

    Args:
        site: name (or id) of the end-effector site.
        x_d, xdot_d, xddot_d: desired position, velocity and acceleration of the
            site's first ``d = len(x_d)`` coordinates.
    """
    site = site_id(model, site)
    d = len(x_d)
    x = data.site_xpos[site, :d]
    J = site_jacobian(model, data, site)[:d]
    xdot = J.dot(data.qvel)
    xddot = (
        xddot_d
        + Kd * (xdot_d - xdot)
        + Kp * (x_d - x)
        - site_jdot_qdot(model, data, site)[:d]
    )
    qddot = jacobian_solve(J, xddot)
    return mass_times(model, data, qddot) + data.qfrc_bias
