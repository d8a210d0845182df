r"""Operational-space computed torque for arms whose task Jacobian is square (2R in the
plane, 3R in space), as functions of plain arrays.
"""

from __future__ import annotations

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
