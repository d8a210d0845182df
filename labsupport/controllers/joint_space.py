r"""Joint-space control laws for MuJoCo arms.

Each law has the controller's arguments first, ``(model, data, ...)``, reads the
state :math:`q, \dot q` from ``data`` and returns the torque, shape ``(nv,)``. A
notebook turns one into a controller for :func:`labsupport.sim.simulate` with a small
closure that supplies the reference and the gains. ``Kp`` and ``Kd`` are scalars or
per-joint arrays.
"""

from __future__ import annotations

from labsupport.dynamics import mass_times


def pd_joint_torque(model, data, q_d, qdot_d, Kp, Kd):
    r"""Independent-joint PD, no model:

    .. math:: \tau = K_p(q_d - q) + K_d(\dot q_d - \dot q)
    """
    q, qdot = data.qpos, data.qvel
    return Kp * (q_d - q) + Kd * (qdot_d - qdot)


def ct_joint_torque(model, data, q_d, qdot_d, qddot_d, Kp, Kd):
    r"""Joint-space computed torque:

    .. math::
        \tau = M(q)\big(\ddot q_d + K_d(\dot q_d - \dot q) + K_p(q_d - q)\big)
               + h(q,\dot q)

    :math:`M` and :math:`h = C\dot q + g` (``qfrc_bias``) are read from ``data`` as
    the last ``mj_step`` left them. With an exact model every joint's error obeys
    :math:`\ddot e + K_d\dot e + K_p e = 0`. For a set-point,
    :math:`\dot q_d = \ddot q_d = 0`.
    """
    q, qdot = data.qpos, data.qvel
    h = data.qfrc_bias
    qddot = qddot_d + Kd * (qdot_d - qdot) + Kp * (q_d - q)
    return mass_times(model, data, qddot) + h
