r"""Joint-space controllers for MuJoCo arms (2R, 3R), as functions of plain arrays.

All return a torque of shape ``(n,)``. ``M`` is :math:`M(q)` (``n×n``) and ``h`` is
:math:`h(q,\dot q) = C\dot q + g` (``qfrc_bias``), e.g. from :mod:`labsupport.dynamics`.
"""

from __future__ import annotations

import numpy as np


def pd_joint_torque(q, qdot, q_d, qdot_d, Kp, Kd):
    r"""Independent-joint PD, no model: :math:`\tau = K_p(q_d - q) + K_d(\dot q_d - \dot q)`.

    ``Kp``, ``Kd`` are scalars or per-joint arrays.
    """
    return Kp * (q_d - q) + Kd * (qdot_d - qdot)


def ct_joint_torque(M, h, q, qdot, q_d, qdot_d, qddot_d, Kp, Kd):
    r"""Joint-space computed torque:

    .. math:: \tau = M(q)\big(\ddot q_d + K_d(\dot q_d - \dot q) + K_p(q_d - q)\big) + h(q,\dot q)

    With an exact model the error obeys :math:`\ddot e + K_d\dot e + K_p e = 0` in every joint.
    For a set-point pass ``qdot_d = qddot_d = 0``.
    """
    return M @ (qddot_d + Kd * (qdot_d - qdot) + Kp * (q_d - q)) + h


# ---------------------------------------------------------------------------------------
# Controllers for labsupport.sim.simulate: controller(model, data) -> tau
# ---------------------------------------------------------------------------------------

def _gain(name, value):
    value = np.asarray(value, dtype=float)
    if not np.all(np.isfinite(value)) or np.any(value < 0):
        raise ValueError(f"{name} must be non-negative and finite, got {value!r}")
    return value


def make_pd_setpoint(q_d, Kp, Kd):
    r"""Set-point PD on every joint, no model: :math:`\tau = K_p(q_d - q) - K_d\dot q`.

    Returns ``controller(model, data) -> tau`` for :func:`labsupport.sim.simulate`.
    """
    q_d = np.array(q_d, dtype=float)
    Kp, Kd = _gain("Kp", Kp), _gain("Kd", Kd)
    zero = np.zeros_like(q_d)

    def controller(model, data):
        return pd_joint_torque(data.qpos, data.qvel, q_d, zero, Kp, Kd)

    return controller


def make_ct_setpoint(model, q_d, Kp, Kd):
    r"""Set-point computed torque with MuJoCo's model: :math:`\tau = M(q)\big(K_p(q_d - q) - K_d\dot q\big) + h(q,\dot q)`.

    The error then obeys :math:`\ddot e + K_d\dot e + K_p e = 0` in every joint
    (:math:`\ddot q_d = \dot q_d = 0`). :math:`M` and :math:`h` are read from ``data`` as
    the last ``mj_step`` left them (:mod:`labsupport.dynamics`).
    """
    from labsupport.dynamics import mass_matrix

    q_d = np.array(q_d, dtype=float)
    if q_d.shape != (model.nv,):
        raise ValueError(f"q_d must have shape ({model.nv},), got {q_d.shape}")
    Kp, Kd = _gain("Kp", Kp), _gain("Kd", Kd)
    M = np.zeros((model.nv, model.nv))
    zero = np.zeros(model.nv)

    def controller(model, data):
        mass_matrix(model, data, M)
        return ct_joint_torque(M, data.qfrc_bias, data.qpos, data.qvel, q_d, zero, zero, Kp, Kd)

    return controller


def make_ct_tracking(model, joint_reference, Kp, Kd):
    r"""Trajectory-tracking computed torque in joint space:

    .. math:: \tau = M(q)\big(\ddot q_d + K_d(\dot q_d - \dot q) + K_p(q_d - q)\big) + h(q,\dot q)

    ``joint_reference(t) -> Reference`` gives :math:`(q_d, \dot q_d, \ddot q_d)`; it is sampled
    once on the model's time grid (:class:`labsupport.sim.SampledReference`).
    """
    from labsupport.dynamics import mass_matrix
    from labsupport.sim import SampledReference

    ref = SampledReference(joint_reference, model.opt.timestep)
    n = model.nv
    if ref.dim != n:
        raise ValueError(f"joint_reference must give {n} joint angles, got {ref.dim}")
    Kp, Kd = _gain("Kp", Kp), _gain("Kd", Kd)
    M = np.zeros((n, n))

    def controller(model, data):
        r = np.asarray(ref.at(data.time))
        mass_matrix(model, data, M)
        return ct_joint_torque(M, data.qfrc_bias, data.qpos, data.qvel, r[:n], r[n:2 * n], r[2 * n:], Kp, Kd)

    return controller
