r"""Operational-space computed torque for arms whose task Jacobian is square (2R in the
plane, 3R in space), as functions of plain arrays.
"""

from __future__ import annotations

import math

import numpy as np


def os_ct_torque(M, h, J, jdot_qdot, x, xdot, x_d, xdot_d, xddot_d, Kp, Kd):
    r"""Operational-space computed torque:

    .. math:: \tau = M(q)\,J^{-1}\big(\ddot x_d + K_d(\dot x_d - \dot x) + K_p(x_d - x) - \dot J\dot q\big) + h(q,\dot q)

    With an exact model the task error obeys :math:`\ddot e + K_d\dot e + K_p e = 0`.
    ``J`` must be square and non-singular: a singular ``J`` raises ``ValueError``.
    """
    a = xddot_d + Kd * (xdot_d - xdot) + Kp * (x_d - x) - jdot_qdot
    try:
        qddot = np.linalg.solve(J, a)
    except np.linalg.LinAlgError:
        raise ValueError(f"the Jacobian is singular at this configuration (det J = {np.linalg.det(J):.3g}): "
                         "the arm is stretched out or folded; move the target away from the "
                         "workspace boundary") from None
    return M @ qddot + h


# ---------------------------------------------------------------------------------------
# The 2R planar arm: controllers for labsupport.sim.simulate, written in scalar arithmetic
# (for a 2x2 system, NumPy's per-call overhead costs more than the arithmetic itself).
# ---------------------------------------------------------------------------------------

def _scalar_gain(name, value) -> float:
    value = float(value)
    if not np.isfinite(value) or value < 0:
        raise ValueError(f"{name} must be a non-negative number, got {value!r}")
    return value


def _inverse_dynamics_2r():
    r"""A preallocated :math:`\tau = M(q)\,u + h(q,\dot q)` for the 2R arm, in scalar arithmetic
    (for two joints, NumPy's per-call overhead costs more than the arithmetic)."""
    from labsupport.dynamics import mass_matrix

    M = np.zeros((2, 2))
    M_flat = M.reshape(4)
    tau = np.zeros(2)

    def apply(model, data, u1: float, u2: float) -> np.ndarray:
        mass_matrix(model, data, M)
        m11, m12, m21, m22 = M_flat.tolist()
        h1, h2 = data.qfrc_bias.tolist()
        tau[0] = m11 * u1 + m12 * u2 + h1
        tau[1] = m21 * u1 + m22 * u2 + h2
        return tau

    return apply


def _check_2r(model):
    if model.nv != 2 or model.nu != 2:
        raise ValueError(f"these controllers are for the 2R arm (nv = nu = 2), got nv={model.nv}, nu={model.nu}")


def make_os_ct_2r(model, reference, Kp, Kd, arm=None, offset: float = 0.0, min_det: float = 1e-9):
    r"""Operational-space computed torque for the 2R arm tracking ``reference(t)``:

    .. math:: \tau = M(q)\,J^{-1}\big(\ddot x_d + K_d(\dot x_d - J\dot q) + K_p(x_d - x) - \dot J\dot q\big) + h(q,\dot q)

    The same law as :func:`os_ct_torque`, with :math:`x`, :math:`J`, :math:`\dot J\dot q`
    from :mod:`labsupport.kinematics.planar_2r` written out and :math:`J^{-1}` by Cramer's
    rule; :math:`M` and :math:`h` come from MuJoCo.

    Args:
        reference: ``reference(t) -> Reference`` in the plane (``circle_2d`` for instance).
        Kp, Kd: scalar gains of :math:`\ddot e + K_d\dot e + K_p e = 0`.
        arm: link lengths (:data:`labsupport.kinematics.planar_2r.LAB_ARM` by default).
        offset: use the reference at :math:`t + \text{offset}` (0: the step's start, as the lab).
    """
    from labsupport.kinematics.planar_2r import LAB_ARM
    from labsupport.sim import SampledReference

    _check_2r(model)
    arm = LAB_ARM if arm is None else arm
    l1, l2 = arm.l1, arm.l2
    Kp, Kd = _scalar_gain("Kp", Kp), _scalar_gain("Kd", Kd)
    ref = SampledReference(reference, model.opt.timestep, offset)
    if ref.dim != 2:
        raise ValueError(f"reference must be planar (2 components), got {ref.dim}")
    apply = _inverse_dynamics_2r()
    cos, sin = math.cos, math.sin

    def controller(model, data):
        q1, q2 = data.qpos.tolist()
        w1, w2 = data.qvel.tolist()
        px, py, vx, vy, ax, ay = ref.at(data.time)
        c1, s1, c12, s12 = cos(q1), sin(q1), cos(q1 + q2), sin(q1 + q2)
        # forward kinematics, Jacobian and Jdot qdot
        x, y = l1 * c1 + l2 * c12, l1 * s1 + l2 * s12
        j11, j12, j21, j22 = -l1 * s1 - l2 * s12, -l2 * s12, l1 * c1 + l2 * c12, l2 * c12
        w12sq, w1sq = (w1 + w2) ** 2, w1 * w1
        jdx, jdy = -l1 * c1 * w1sq - l2 * c12 * w12sq, -l1 * s1 * w1sq - l2 * s12 * w12sq
        # desired task acceleration, then qddot = J^{-1} a
        a1 = ax + Kd * (vx - (j11 * w1 + j12 * w2)) + Kp * (px - x) - jdx
        a2 = ay + Kd * (vy - (j21 * w1 + j22 * w2)) + Kp * (py - y) - jdy
        det = j11 * j22 - j12 * j21
        if abs(det) < min_det:
            raise ValueError(f"the Jacobian is singular at q = ({q1:.4f}, {q2:.4f}) (det J = {det:.3g}): "
                             "the arm is stretched out or folded; keep the path inside the workspace")
        u1, u2 = (j22 * a1 - j12 * a2) / det, (j11 * a2 - j21 * a1) / det
        return apply(model, data, u1, u2)

    return controller


def make_ik_ct_2r(model, reference, Kp, Kd, arm=None, branch: str = "up", offset: float = 0.0):
    r"""IK plus joint-space computed torque for the 2R arm tracking ``reference(t)``.

    The Cartesian reference becomes a joint reference
    (:func:`labsupport.kinematics.planar_2r.joint_reference`:
    :math:`q_d = \mathrm{IK}(x_d)`, :math:`\dot q_d = J^{-1}\dot x_d`,
    :math:`\ddot q_d = J^{-1}(\ddot x_d - \dot J\dot q_d)`), computed once for the whole time
    grid, and the joint-space law of :func:`~labsupport.controllers.joint_space.ct_joint_torque`
    tracks it:

    .. math:: \tau = M(q)\big(\ddot q_d + K_d(\dot q_d - \dot q) + K_p(q_d - q)\big) + h(q,\dot q)
    """
    from labsupport.kinematics.planar_2r import LAB_ARM, joint_reference
    from labsupport.sim import SampledReference

    _check_2r(model)
    arm = LAB_ARM if arm is None else arm
    Kp, Kd = _scalar_gain("Kp", Kp), _scalar_gain("Kd", Kd)
    ref = SampledReference(lambda t: joint_reference(reference(t), arm, branch), model.opt.timestep, offset)
    apply = _inverse_dynamics_2r()

    def controller(model, data):
        q1, q2 = data.qpos.tolist()
        w1, w2 = data.qvel.tolist()
        p1, p2, v1, v2, a1, a2 = ref.at(data.time)
        u1 = a1 + Kd * (v1 - w1) + Kp * (p1 - q1)
        u2 = a2 + Kd * (v2 - w2) + Kp * (p2 - q2)
        return apply(model, data, u1, u2)

    return controller
