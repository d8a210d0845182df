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
