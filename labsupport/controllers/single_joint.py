r"""Controllers for the single joint :math:`\tau = M\ddot\theta + h(\theta,\dot\theta)`.

Each ``make_*`` function returns ``torque(t, state)`` for
:meth:`labsupport.plants.SingleJoint.simulate`; ``state = (theta, theta_dot)``.
A controller's *model* (:math:`\tilde M`, :math:`\tilde h`) is a
:class:`~labsupport.plants.SingleJoint` that may differ from the true plant.
"""

from __future__ import annotations

from typing import Callable

import numpy as np

from labsupport.plants import SingleJoint
from labsupport.trajectories import Reference

TorqueFn = Callable[[float, np.ndarray], float]
ReferenceFn = Callable[[float], Reference]


def pd_torque(theta, theta_dot, theta_d, theta_dot_d, Kp: float, Kd: float):
    r"""PD feedback :math:`\tau_{fb} = K_p(\theta_d - \theta) + K_d(\dot\theta_d - \dot\theta)` (Eq. 11.24)."""
    return Kp * (theta_d - theta) + Kd * (theta_dot_d - theta_dot)


def feedforward_torque(model: SingleJoint, ref: Reference):
    r"""Model-based feedforward :math:`\tau_{ff} = \tilde M\ddot\theta_d + \tilde h(\theta_d,\dot\theta_d)` (Eq. 11.32)."""
    return model.M * ref.acc + model.h(ref.pos, ref.vel)


def make_pd(Kp: float, Kd: float, reference: ReferenceFn | float) -> TorqueFn:
    r"""PD law :math:`\tau = K_p e + K_d\dot e` about a reference (a set-point if ``reference`` is a number)."""
    ref_fn = _as_reference(reference)

    def torque(t, state):
        ref = ref_fn(t)
        return pd_torque(state[0], state[1], ref.pos, ref.vel, Kp, Kd)

    return torque


def make_feedforward(model: SingleJoint, reference: ReferenceFn) -> TorqueFn:
    r"""Open-loop feedforward :math:`\tau = \tilde M\ddot\theta_d + \tilde h(\theta_d,\dot\theta_d)`; ignores the state."""

    def torque(t, state):
        return feedforward_torque(model, reference(t))

    return torque


def make_computed_torque(model: SingleJoint, Kp: float, Kd: float, reference: ReferenceFn) -> TorqueFn:
    r"""Feedforward plus feedback (Eq. 11.35):

    .. math:: \tau = \underbrace{\tilde M\ddot\theta_d + \tilde h(\theta_d,\dot\theta_d)}_{\tau_{ff}}
                   + \underbrace{K_p(\theta_d-\theta) + K_d(\dot\theta_d-\dot\theta)}_{\tau_{fb}}
    """

    def torque(t, state):
        ref = reference(t)
        return feedforward_torque(model, ref) + pd_torque(state[0], state[1], ref.pos, ref.vel, Kp, Kd)

    return torque


def make_pi_speed(Kp: float, Ki: float, omega_d: float, theta0: float = 0.0) -> TorqueFn:
    r"""PI speed control :math:`\tau = K_p(\omega_d - \omega) + K_i\int_0^t(\omega_d - \omega)\,dt'`.

    The angle is the integral of the speed, so the integral term is
    :math:`K_i(\omega_d t - (\theta - \theta_0))` and the law needs no extra state.
    On :math:`M\dot\omega + b\omega = \tau` the speed error :math:`e = \omega_d - \omega` obeys
    :math:`M\ddot e + (b + K_p)\dot e + K_i e = 0`, so
    :func:`labsupport.gains.pd_gains` designs (Ki, Kp) exactly as it designs (Kp, Kd) for PD.
    """

    def torque(t, state):
        return Kp * (omega_d - state[1]) + Ki * (omega_d * t - (state[0] - theta0))

    return torque


def _as_reference(reference) -> ReferenceFn:
    if callable(reference):
        return reference
    setpoint = float(reference)
    return lambda t: Reference(setpoint, 0.0, 0.0)
