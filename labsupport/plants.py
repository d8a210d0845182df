r"""Plants: the analytic single-joint arm (simulated with SciPy) and the MuJoCo models.

The single joint obeys (Lynch & Park, Eq. 11.21)

.. math:: \tau = M\ddot\theta + m g r\cos\theta + b\dot\theta = M\ddot\theta + h(\theta,\dot\theta)

with :math:`M` the inertia about the joint, :math:`m` the link mass, :math:`r` the distance
from the joint to the centre of mass, :math:`b` viscous friction and :math:`g` gravity
(:math:`g = 0` for an arm moving in a horizontal plane).
"""

from __future__ import annotations

from dataclasses import dataclass
from importlib import resources
from typing import Callable, NamedTuple

import numpy as np
from scipy.integrate import solve_ivp

#: The lab's (textbook) parameters.
LAB_M, LAB_m, LAB_r, LAB_b, LAB_g = 0.5, 1.0, 0.1, 0.1, 9.81


class JointLog(NamedTuple):
    """Sampled response of the single joint: time, angle, speed and applied torque."""

    t: np.ndarray
    theta: np.ndarray
    theta_dot: np.ndarray
    tau: np.ndarray


class _BadTorque(Exception):
    pass


@dataclass(frozen=True)
class SingleJoint:
    r"""One revolute joint with a link, viscous friction and (optionally) gravity.

    Attributes:
        M: inertia about the joint axis [kg·m²], > 0.
        m: link mass [kg], ≥ 0.
        r: joint-to-centre-of-mass distance [m].
        b: viscous friction [N·m·s/rad], ≥ 0.
        g: gravitational acceleration [m/s²]; 0 for the horizontal arm.
    """

    M: float = LAB_M
    m: float = LAB_m
    r: float = LAB_r
    b: float = LAB_b
    g: float = 0.0

    def __post_init__(self):
        for name in ("M", "m", "r", "b", "g"):
            value = getattr(self, name)
            if not isinstance(value, (int, float, np.floating, np.integer)) or not np.isfinite(value):
                raise ValueError(f"{name} must be a finite number, got {value!r}")
        if self.M <= 0:
            raise ValueError(f"M (inertia about the joint) must be positive, got {self.M!r}")
        if self.m < 0:
            raise ValueError(f"m (link mass) must be non-negative, got {self.m!r}")
        if self.b < 0:
            raise ValueError(f"b (viscous friction) must be non-negative, got {self.b!r}")

    @property
    def max_gravity_torque(self) -> float:
        r"""Largest gravity load :math:`mgr`, reached with the link horizontal (:math:`\theta = 0`)."""
        return self.m * self.g * self.r

    def h(self, theta, theta_dot):
        r"""State-dependent torque :math:`h(\theta,\dot\theta) = mgr\cos\theta + b\dot\theta`."""
        return self.m * self.g * self.r * np.cos(theta) + self.b * theta_dot

    def acceleration(self, theta, theta_dot, tau):
        r"""Forward dynamics :math:`\ddot\theta = (\tau - h(\theta,\dot\theta))/M`."""
        return (tau - self.h(theta, theta_dot)) / self.M

    def simulate(self, torque: Callable[[float, np.ndarray], float], duration: float,
                 state0=(0.0, 0.0), dt: float = 1e-3, rtol: float = 1e-6,
                 atol: float = 1e-8) -> JointLog:
        r"""Integrate :math:`\dot x = (\dot\theta, \ddot\theta)` under ``torque(t, state)`` with RK45.

        Args:
            torque: controller, called as ``torque(t, np.array([theta, theta_dot]))``; must
                return a finite scalar [N·m].
            duration: simulated time [s] from t = 0.
            state0: initial ``(theta, theta_dot)``.
            dt: spacing of the returned samples [s] (the solver picks its own steps).

        Returns:
            A :class:`JointLog` sampled at ``0, dt, 2dt, … < duration``, with the torque the
            controller returns at each sample.
        """
        state0 = np.asarray(state0, dtype=float)
        if state0.shape != (2,):
            raise ValueError(f"state0 must be (theta, theta_dot), shape (2,); got shape {state0.shape}")
        if not np.all(np.isfinite(state0)):
            raise ValueError(f"state0 must be finite, got {state0}")
        duration, dt = float(duration), float(dt)
        if not (np.isfinite(duration) and duration > 0):
            raise ValueError(f"duration must be a positive number of seconds, got {duration!r}")
        if not (np.isfinite(dt) and 0 < dt <= duration):
            raise ValueError(f"dt must be in (0, duration], got {dt!r}")

        def checked_torque(t, x):
            tau = torque(t, x)
            if tau is None:
                raise _BadTorque(f"the torque function returned None at t = {t:.4f} s")
            tau_arr = np.asarray(tau, dtype=float)
            if tau_arr.size != 1:
                raise _BadTorque(f"tau must be a scalar, got shape {tau_arr.shape} at t = {t:.4f} s")
            tau = float(tau_arr.reshape(()))
            if not np.isfinite(tau):
                raise _BadTorque(f"tau is {tau} (not finite) at t = {t:.4f} s, state = {x}")
            return tau

        def rhs(t, x):
            return (x[1], self.acceleration(x[0], x[1], checked_torque(t, x)))

        t_eval = np.arange(0.0, duration, dt)
        try:
            sol = solve_ivp(rhs, (0.0, duration), state0, t_eval=t_eval, method="RK45",
                            rtol=rtol, atol=atol)
        except _BadTorque as err:
            raise ValueError(str(err)) from None
        if not sol.success:
            raise RuntimeError(f"the integration stopped early: {sol.message}")
        tau = np.array([checked_torque(t, x) for t, x in zip(sol.t, sol.y.T)]) if len(sol.t) else np.zeros(0)
        return JointLog(sol.t, sol.y[0], sol.y[1], tau)


# ---------------------------------------------------------------------------------------
# MuJoCo models shipped in labsupport.models
# ---------------------------------------------------------------------------------------

def model_path(name: str):
    """Path of a shipped MJCF file, e.g. ``model_path("planar_2r")`` → ``.../planar_2r.xml``.

    Resolved inside the installed package, so it works from any working directory.
    """
    root = resources.files("labsupport.models")
    path = root / (name if name.endswith(".xml") else f"{name}.xml")
    if not path.is_file():
        shipped = sorted(p.name[:-4] for p in root.iterdir() if p.name.endswith(".xml"))
        raise ValueError(f"no model named {name!r}; the shipped models are {shipped}")
    return path


def load_model(name: str):
    """Load a shipped model: returns ``(model, data)`` with ``mj_forward`` already run."""
    import mujoco

    with resources.as_file(model_path(name)) as path:
        model = mujoco.MjModel.from_xml_path(str(path))
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    return model, data
