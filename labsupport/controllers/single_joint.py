r"""Control laws for the single joint
:math:`\tau = M\ddot\theta + h(\theta,\dot\theta)`.

Each law is a plain function of numbers (or arrays of them) returning the torque, so
the same function runs on the analytic plant (wrapped as ``torque(t, state)`` for
:meth:`labsupport.plants.SingleJoint.simulate`) and on the MuJoCo arm (wrapped as
``controller(model, data)`` for :func:`labsupport.sim.simulate`). A law's *model*
(:math:`\tilde M`, :math:`\tilde h`) is a :class:`~labsupport.plants.SingleJoint`
that may differ from the true plant.
"""

from __future__ import annotations

from labsupport.plants import SingleJoint


def pi_speed_torque(t, theta, theta_dot, omega_d, Kp, Ki, theta0=0.0):
    r"""PI speed control of :math:`M\dot\omega + b\omega = \tau`:

    .. math:: \tau = K_p(\omega_d - \omega) + K_i\int_0^t(\omega_d - \omega)\,dt'
                   = K_p(\omega_d - \dot\theta)
                     + K_i\big(\omega_d t - (\theta - \theta_0)\big)

    The angle is the integral of the speed, so the integral of the speed error needs
    no extra state. The speed error :math:`e = \omega_d - \omega` obeys
    :math:`M\ddot e + (b + K_p)\dot e + K_i e = 0`, so
    :func:`labsupport.gains.pd_gains` designs (Ki, Kp) as it designs (Kp, Kd) for PD.
    """
    speed_error = omega_d - theta_dot
    integral_of_speed_error = omega_d * t - (theta - theta0)
    return Kp * speed_error + Ki * integral_of_speed_error


def pd_torque(theta, theta_dot, theta_d, theta_dot_d, Kp, Kd):
    r"""PD feedback:
    :math:`\tau_{fb} = K_p(\theta_d - \theta) + K_d(\dot\theta_d - \dot\theta)`.

    For a set-point, :math:`\dot\theta_d = 0`, and on the horizontal joint the
    error :math:`\theta_e = \theta_d - \theta` is a second-order system
    [MR 11.25-11.26].
    """
    return Kp * (theta_d - theta) + Kd * (theta_dot_d - theta_dot)


def feedforward_torque(model: SingleJoint, theta_d, theta_dot_d, theta_ddot_d):
    r"""Model-based feedforward [MR 11.32]:

    .. math:: \tau_{ff} = \tilde M\ddot\theta_d + \tilde h(\theta_d,\dot\theta_d)

    It uses the reference only, never the measured state: the torque the model says
    the move needs.
    """
    return model.M * theta_ddot_d + model.h(theta_d, theta_dot_d)


def computed_torque(
    model: SingleJoint, theta, theta_dot, theta_d, theta_dot_d, theta_ddot_d, Kp, Kd
):
    r"""Feedforward plus feedback, the law the lab calls computed torque (it cites
    [MR 11.35], whose feedback also passes through the model :math:`\tilde M`):

    .. math::
        \tau = \underbrace{\tilde M\ddot\theta_d
                           + \tilde h(\theta_d,\dot\theta_d)}_{\tau_{ff}}
               + \underbrace{K_p(\theta_d-\theta)
                             + K_d(\dot\theta_d-\dot\theta)}_{\tau_{fb}}
    """
    tau_ff = feedforward_torque(model, theta_d, theta_dot_d, theta_ddot_d)
    tau_fb = pd_torque(theta, theta_dot, theta_d, theta_dot_d, Kp, Kd)
    return tau_ff + tau_fb
