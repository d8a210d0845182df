r"""Actuator mappings: how a controller's joint torque becomes MuJoCo's ``ctrl``.

A torque motor takes the torque itself (the default of :func:`labsupport.sim.simulate`). The
Menagerie UR5e has **position servos** instead: a ``general`` actuator with an affine bias,
whose force on its joint is

.. math:: f = k_p\,u - k_p\,q - k_v\,\dot q, \qquad |f| \le f_{\max}, \quad u \in [u_{\min}, u_{\max}]

for the command :math:`u`, which MuJoCo clamps to ``ctrlrange`` first (and :math:`f` to
``forcerange``). Inverting it once per step (:func:`servo_ctrl`) makes the servo exert
the torque a controller asks for; :func:`servo_actuation` is that inversion in the form the
loop applies, ``actuation(model, data, tau) -> ctrl``.

The servo's damping :math:`k_v` is integrated *implicitly* by the ``implicitfast``
integrator, so over one step the arm moves as if its inertia were :math:`M + \Delta t\,K_v`
(:func:`implicit_damping`).
"""

from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np

from labsupport import validate


@dataclass(frozen=True)
class Servo:
    """The joint position servos of a model, one entry per actuator.

    Attributes:
        kp: position gains :math:`k_p` [N·m/rad] (``gainprm[0]``).
        kv: velocity gains :math:`k_v` [N·m·s/rad] (``-biasprm[2]``).
        force_lo, force_hi: ``forcerange`` [N·m] (infinite where the force is not limited).
        ctrl_lo, ctrl_hi: ``ctrlrange`` [rad] (infinite where the command is not limited).
    """

    kp: np.ndarray
    kv: np.ndarray
    force_lo: np.ndarray
    force_hi: np.ndarray
    ctrl_lo: np.ndarray
    ctrl_hi: np.ndarray

    @classmethod
    def from_model(cls, model: mujoco.MjModel) -> Servo:
        """Read the servos of a model whose actuators are affine position servos, one per joint.

        Raises:
            ValueError: the model's actuators are not position servos on each of its joints;
                the message names the first condition that fails.
        """
        validate.mujoco_model(model)
        kp = model.actuator_gainprm[:, 0].copy()
        bias = model.actuator_biasprm[:, :3]
        reason = _not_a_servo(model, kp, bias)
        if reason:
            raise ValueError(
                f"the model's actuators are not position servos on each of its joints: {reason}. "
                "Servo.from_model needs one affine servo per hinge or slide joint, in joint order "
                "(gainprm kp, biasprm 0 -kp -kv, gear 1, no activation dynamics), as MuJoCo's "
                "<position> actuator writes it; use the default actuation (ctrl = tau) for torque motors"
            )
        inf = np.full(model.nu, np.inf)
        force_limited = model.actuator_forcelimited.astype(bool)
        ctrl_limited = model.actuator_ctrllimited.astype(bool)
        arrays = dict(
            kp=kp,
            kv=-bias[:, 2].copy(),
            force_lo=np.where(force_limited, model.actuator_forcerange[:, 0], -inf),
            force_hi=np.where(force_limited, model.actuator_forcerange[:, 1], inf),
            ctrl_lo=np.where(ctrl_limited, model.actuator_ctrlrange[:, 0], -inf),
            ctrl_hi=np.where(ctrl_limited, model.actuator_ctrlrange[:, 1], inf),
        )
        for a in arrays.values():
            a.setflags(write=False)
        return cls(**arrays)


def _not_a_servo(model: mujoco.MjModel, kp: np.ndarray, bias: np.ndarray) -> str:
    """Why the actuators of ``model`` are not one invertible position servo per joint, or ''."""
    joint = np.arange(model.nu)
    if model.nu != model.nv or model.nq != model.nv:
        return f"it has {model.nu} actuators, {model.nq} joint positions and {model.nv} joint velocities"
    if np.any(model.actuator_trntype != mujoco.mjtTrn.mjTRN_JOINT) or np.any(model.actuator_trnid[:, 0] != joint):
        return "actuator i must drive joint i"
    if np.any(model.actuator_gear[:, 0] != 1):
        return f"the gears are {model.actuator_gear[:, 0]}, not 1"
    if np.any(model.actuator_dyntype != mujoco.mjtDyn.mjDYN_NONE):
        return "an actuator has activation dynamics (a timeconst), so its force lags its command"
    if np.any(model.actuator_gaintype != mujoco.mjtGain.mjGAIN_FIXED) or np.any(
        model.actuator_biastype != mujoco.mjtBias.mjBIAS_AFFINE
    ):
        return "an actuator's gain is not fixed or its bias is not affine"
    if np.any(kp <= 0) or not np.allclose(bias[:, 1], -kp) or np.any(bias[:, 0] != 0):
        return f"the gains kp are {kp} and the biases (biasprm[:3]) are {bias.tolist()}"
    return ""


def servo_ctrl(servo: Servo, q, qdot, tau, out: np.ndarray | None = None) -> np.ndarray:
    r"""The command that makes the servo exert the torque ``tau`` (the servo inverted):

    .. math:: u = q + \tfrac{k_v}{k_p}\dot q + \tfrac{\tau}{k_p}

    The servo's force :math:`k_p(u - q) - k_v\dot q` is then exactly ``tau``, unless MuJoCo
    clamps: the command to ``ctrlrange`` or the force to ``forcerange``, as it does for every
    limited actuator (:func:`servo_force` clamps both the same way). Works row by row on arrays
    of shape ``(N, nu)``; ``out`` is an optional preallocated result.

    Example: one servo without limits; the command makes it exert the 12 N·m asked for.

    >>> inf = np.array([np.inf])
    >>> servo = Servo(kp=np.array([2000.0]), kv=np.array([400.0]), force_lo=-inf, force_hi=inf,
    ...               ctrl_lo=-inf, ctrl_hi=inf)
    >>> q, qdot = np.array([0.3]), np.array([0.5])
    >>> u = servo_ctrl(servo, q, qdot, tau=np.array([12.0]))
    >>> print(u, servo_force(servo, q, qdot, u))
    [0.406] [12.]
    """
    try:
        u = np.multiply(servo.kv, qdot, out=out)  # k_v qdot
        u += tau  # k_v qdot + tau
        u /= servo.kp  # (k_v qdot + tau) / k_p
        u += q  # q + (k_v qdot + tau) / k_p
    except (TypeError, ValueError, OverflowError, AttributeError):
        raise _bad_inputs("servo_ctrl", servo, q=q, qdot=qdot, tau=tau) from None
    return u


def servo_force(servo: Servo, q, qdot, ctrl) -> np.ndarray:
    r"""The torque the servo exerts for the command ``ctrl``, as MuJoCo computes it: the command
    clamped to ``ctrlrange``, then :math:`\operatorname{clip}(k_p(u - q) - k_v\dot q,\ f_{\min}, f_{\max})`.

    Row by row on arrays of shape ``(N, nu)``: with a :class:`labsupport.sim.Log`,
    ``servo_force(servo, log.q, log.qdot, log.ctrl)`` is the torque each step applied.
    """
    try:
        u = np.clip(np.asarray(ctrl, dtype=float), servo.ctrl_lo, servo.ctrl_hi)
        f = servo.kp * (u - q) - servo.kv * np.asarray(qdot, dtype=float)
    except (TypeError, ValueError, OverflowError, AttributeError):
        f = None
    if f is None or not np.isfinite(f).all():  # None becomes NaN in an array
        raise _bad_inputs("servo_force", servo, q=q, qdot=qdot, ctrl=ctrl)
    return np.clip(f, servo.force_lo, servo.force_hi)


def _bad_inputs(function: str, servo: Servo, **inputs) -> ValueError:
    """The error for inputs NumPy could not combine with the servos: what each one was."""
    if not isinstance(servo, Servo):
        return ValueError(f"{function} takes the servos first, Servo.from_model(model), got {validate.short(servo)}")
    nu, names = len(servo.kp), list(inputs)
    got = ", ".join(
        f"{name} of shape {np.shape(value)}" if isinstance(value, np.ndarray) else f"{name} = {validate.short(value)}"
        for name, value in inputs.items()
    )
    return ValueError(
        f"{function}: {', '.join(names[:-1])} and {names[-1]} must be finite numbers of shape ({nu},), "
        f"one per servo, or (N, {nu}) for N states; got {got}"
    )


def servo_actuation(model: mujoco.MjModel):
    """The actuation mapping for :func:`labsupport.sim.simulate`: ``actuation(model, data, tau)``
    returns :func:`servo_ctrl` of the current state, in an array allocated once."""
    servo = Servo.from_model(model)
    ctrl = np.zeros(model.nu)

    def actuation(model: mujoco.MjModel, data: mujoco.MjData, tau: np.ndarray) -> np.ndarray:
        return servo_ctrl(servo, data.qpos, data.qvel, tau, out=ctrl)

    return actuation


def implicit_damping(servo: Servo, timestep: float) -> np.ndarray:
    r"""Diagonal of :math:`\Delta t\,K_v`, the inertia the implicit integrator adds to each joint.

    With ``implicitfast`` the servo's damping is evaluated at the *next* velocity, so one step
    solves :math:`(M + \Delta t K_v)\,\ddot q = \tau - h` instead of :math:`M\ddot q = \tau - h`.
    A controller that wants :math:`\ddot q^*` therefore adds :math:`\Delta t K_v\,\ddot q^*`.
    This holds for a servo inside its force range only: at its limit the force is constant,
    MuJoCo (3.5 and newer) integrates it without damping, and the joint moves by
    :math:`M\ddot q = f_{\text{limit}} - h` on that step.
    """
    if not isinstance(servo, Servo):
        raise ValueError(f"implicit_damping takes the servos, Servo.from_model(model), got {type(servo).__name__}")
    return validate.number("timestep", timestep, positive=True) * servo.kv
