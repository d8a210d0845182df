r"""One loop that steps a MuJoCo model under a controller and returns a :class:`Log`.

At each step :math:`k` the controller ``controller(model, data) -> tau`` sees the data, returns
a torque :math:`\tau_k` (clipped to ``torque_limit`` if given) that is held over
:math:`[t_k, t_k + \Delta t)`, an optional actuation mapping turns it into ``data.ctrl`` (the
UR5e's position servos), and MuJoCo advances one step. Arrays are preallocated; nothing grows
inside the loop, so a lean controller runs at a good fraction of the speed of bare ``mj_step``.

What the controller sees depends on how the step is taken:

* by default, the data as the previous ``mj_step`` left it: ``qpos``, ``qvel`` and ``time`` are
  the new state; the derived quantities (``qfrc_bias``, the mass matrix, ``site_xpos``) are
  those of the integrator's last evaluation. With the RK4 integrator that evaluation is RK4's
  fourth stage, close to the new state but not at it (the 2R arm swinging at about 2 rad/s:
  ``site_xpos`` within about 1e-8 m; the 3R arm: within a few micrometres, and ``qfrc_bias``
  within about 1e-3 N·m); with Euler it is the start of the step.
* with ``split_step=True``: ``mj_step1`` first, so everything belongs to the current state,
  then the controller, then ``mj_step2`` (Euler and implicit integrators only).
* with ``lab_timing=True``: as the lab's UR5e loop, no ``mj_forward`` after the reset (the first
  step sees zeroed derived data), ``mj_step`` only, and steps while the accumulated time is
  below the duration.

A controller only reads the state: one whose first call changes ``data.qpos`` or ``data.qvel``
(an in-place operation on a view of the state, say) stops the run with a ``ValueError`` that
says so (:func:`state_written`), before the arm jumps.

Divergence stops the run with :class:`SimulationDiverged`, which names the time and the last
good state: one of MuJoCo's own instability warnings (after which MuJoCo resets the state), a
non-finite state, or a joint turning faster than :data:`RUNAWAY_SPEED`. The last one matters:
a numerically unstable run (a damping too stiff for the time step) first swings chaotically at
hundreds of rad/s, and whether it then overflows into MuJoCo's warnings depends on rounding,
so it differs between MuJoCo versions; the speed bound catches it at the same step on all.

While the loop runs, MuJoCo's warning messages come to the loop instead of MuJoCo's default
handler (which prints them and appends them to ``MUJOCO_LOG.TXT`` in the working directory):
the one that stops a run is quoted in the error (it names the joint or actuator), and any
other is shown as a Python ``RuntimeWarning`` when the run ends. Runs in several threads each
get their own thread's messages.
"""

from __future__ import annotations

import dataclasses
import functools
import math
import re
import sys
import threading
import warnings
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass

import mujoco
import numpy as np

from labsupport import dynamics, trajectories, validate

Controller = Callable[[mujoco.MjModel, mujoco.MjData], np.ndarray]
Actuation = Callable[[mujoco.MjModel, mujoco.MjData, np.ndarray], np.ndarray]

#: MuJoCo warnings that mean the integration has gone wrong (MuJoCo resets the state or
#: zeroes the controls when it raises them).
_FATAL_WARNINGS = (
    mujoco.mjtWarning.mjWARN_BADQPOS,
    mujoco.mjtWarning.mjWARN_BADQVEL,
    mujoco.mjtWarning.mjWARN_BADQACC,
    mujoco.mjtWarning.mjWARN_BADCTRL,
)
_W_QPOS, _W_QVEL, _W_QACC, _W_CTRL = (int(w) for w in _FATAL_WARNINGS)
#: What the loop logs each step with one ``mj_getState``: time, qpos, qvel and ctrl, in that order.
_LOGGED_STATE = int(
    mujoco.mjtState.mjSTATE_TIME
    | mujoco.mjtState.mjSTATE_QPOS
    | mujoco.mjtState.mjSTATE_QVEL
    | mujoco.mjtState.mjSTATE_CTRL
)
#: Joint speed [rad/s] above which a run counts as diverged: about 950 rpm, far beyond any
#: motion of the lab's arms (a few rad/s), and reached within a step or two of the onset of
#: a numerical instability.
RUNAWAY_SPEED = 100.0
_WARNING_MEANING = {
    _W_QPOS: "positions not finite or huge",
    _W_QVEL: "velocities not finite or huge",
    _W_QACC: "accelerations not finite or huge",
    _W_CTRL: "controls not finite or huge",
}


class SimulationDiverged(RuntimeError):
    """The simulation blew up; ``t``, ``qpos`` and ``qvel`` hold where and how."""

    #: What to do about a run that ran away: the advice unless a more specific one is given. The
    #: speed bound does not tell an unstable loop from a stable one so stiff that it moves this fast,
    #: so the advice names both.
    RUNAWAY_ADVICE = (
        "Either the closed loop is unstable (check the law for a sign error, and that its angles are in "
        "radians, not degrees), or it is so stiff that even a stable response moves this fast (gains far "
        "beyond the arm's scale): lower the gains, or clip the torque."
    )
    #: Added for an arm of more than one joint, whose target may be Cartesian.
    CARTESIAN_ADVICE = (
        " With a Cartesian target, check that it is within the arm's reach (near the edge of the "
        "workspace J is nearly singular and J⁻¹ huge)."
    )

    def __init__(self, t: float, qpos: np.ndarray, qvel: np.ndarray, reason: str, advice: str | None = None):
        self.t, self.qpos, self.qvel, self.reason = t, np.array(qpos), np.array(qvel), reason
        if advice is None:
            advice = self.RUNAWAY_ADVICE + (self.CARTESIAN_ADVICE if self.qvel.size > 1 else "")
        with np.printoptions(precision=4, suppress=True):
            super().__init__(
                f"simulation diverged at t = {t:.4f} s ({reason}); q = {self.qpos}, qdot = {self.qvel}. {advice}"
            )


@dataclass(frozen=True)
class Log:
    """What one run recorded, one row per control step. The one log type of the package: the
    analytic single joint's simulation returns it too. Metrics are functions of it
    (:mod:`labsupport.metrics`).

    Attributes:
        t: (N,) time at which the state was recorded [s] (the step's end with
            ``log_after_step``, its start otherwise).
        q, qdot: (N, nq), (N, nv) state at that time.
        tau: (N, nu) the controller's torque for the step, clipped to ``torque_limit`` and to
            a limited ``ctrlrange`` of a torque actuator (a torque at such a limit may have been
            asked for larger): the torque that acted, unless the actuators of an ``actuation``
            mapping bound it in turn (:func:`labsupport.metrics.saturation`).
        ctrl: (N, nu) what was written to ``data.ctrl`` (equal to ``tau`` without an actuation
            mapping).
        ee: (N, 3) end-effector site position, or (N, 0) without a site.
        ee_rot: (N, 3, 3) end-effector site orientation, or (N, 0, 0) without a site.
        ref: (N, d) reference position at the step's start, or (N, 0) without a reference.
        err: (N, d) ``ref - ee[:, :d]``, or (N, 0).
        site: id of the site whose pose ``ee`` and ``ee_rot`` hold, or -1 without a site.
    """

    t: np.ndarray
    q: np.ndarray
    qdot: np.ndarray
    tau: np.ndarray
    ctrl: np.ndarray
    ee: np.ndarray
    ee_rot: np.ndarray
    ref: np.ndarray
    err: np.ndarray
    site: int = -1


def reset(
    model: mujoco.MjModel,
    data: mujoco.MjData,
    q0=None,
    qdot0=None,
    *,
    keyframe: str | None = None,
    forward: bool = True,
) -> None:
    """Reset ``data`` (to ``keyframe`` if named), set the initial state (validated) and, unless
    ``forward=False``, run ``mj_forward``."""
    validate.model_and_data(model, data)
    if keyframe is None:
        mujoco.mj_resetData(model, data)
    else:
        key = validate.model_object(model, "keyframe", keyframe)
        mujoco.mj_resetDataKeyframe(model, data, key)
    if q0 is not None:
        data.qpos[:] = validate.vector("q0", q0, (model.nq,))
    if qdot0 is not None:
        data.qvel[:] = validate.vector("qdot0", qdot0, (model.nv,))
    if validate.flag("forward", forward):
        mujoco.mj_forward(model, data)


def _warn_state_set_by_hand(model: mujoco.MjModel, data: mujoco.MjData) -> None:
    """A ``RuntimeWarning`` where ``data`` holds, at time 0, a position other than the model's
    ``qpos0``: a state set by hand (``data.qpos[:] = ...``) or by a keyframe, which a run without
    ``q0`` or a keyframe does not start from (it resets first). After a run the time is past 0,
    so the next run, which starts afresh from ``qpos0`` as documented, is not warned about."""
    if data.time == 0 and not np.array_equal(data.qpos, model.qpos0):
        warnings.warn(
            f"data holds qpos = {validate.short(data.qpos)} at time 0 (set by hand, by a keyframe, or by a run "
            f"stopped at its first step), but simulate starts from the model's qpos0 = {validate.short(model.qpos0)} "
            "at rest unless it is given q0 (and qdot0) or a keyframe: pass q0=data.qpos.copy() to start where data is",
            RuntimeWarning,
            stacklevel=3,
        )


def step_count(duration: float, dt: float, lab_timing: bool = False) -> int:
    """Number of steps of a run: ``round(duration / dt)``, or with ``lab_timing`` as many as the
    lab's ``while data.time < duration`` loop takes (time accumulated step by step in floating
    point, so 8 s at 2 ms is 4001 steps, not 4000)."""
    n = validate.steps(duration, dt)
    if not validate.flag("lab_timing", lab_timing):
        return n
    n, time = 0, 0.0
    while time < duration:
        time += dt
        n += 1
    return n


def simulate(
    model: mujoco.MjModel,
    data: mujoco.MjData,
    controller: Controller,
    duration: float,
    *,
    q0=None,
    qdot0=None,
    site: str | None = None,
    reference: Callable[[float], trajectories.Reference] | None = None,
    torque_limit=None,
    log_after_step: bool = False,
    keyframe: str | None = None,
    actuation: Actuation | None = None,
    split_step: bool = False,
    lab_timing: bool = False,
) -> Log:
    r"""Run ``controller`` on ``model`` for ``duration`` seconds from ``(q0, qdot0)``.

    Args:
        controller: ``controller(model, data) -> tau`` with ``tau`` of shape ``(nu,)``; it reads
            the time as ``data.time``. It may return the same (preallocated) array every step.
            It must only read the state: a call that changes ``data.qpos``, ``data.qvel`` or
            ``data.time`` stops the run (:func:`state_written`). The calls at steps 0, 1, 2, 4,
            8, … are checked, which keeps the check out of the loop's cost per step and still
            finds a law that writes at every call once the arm moves (a write of a zero velocity
            at rest changes nothing).
        q0, qdot0: initial state; they override the keyframe's when both are given.
        site: name of the end-effector site to record (and to compare with ``reference``).
        reference: ``reference(t)`` returning a :class:`~labsupport.trajectories.Reference`, whose
            ``pos`` is the desired site position, recorded with the error (vectorised over an
            array of times if possible; it is evaluated after the run).
        torque_limit: scalar or ``(nu,)`` symmetric limit; torques are clipped to it. Without an
            ``actuation`` mapping they are also clipped to the actuators' limited ``ctrlrange``
            (MuJoCo would clamp them there silently), so the log holds the torque that acted; a
            ``RuntimeWarning`` after the run says where that range bound, and another where the
            limit held the torque on most steps to the end (a flipped sign can do that without
            running away).
        log_after_step: record the state *after* the step beside the reference and torque of
            the step's start, as the lab's loops do (the reference then leads the state by one
            step). The default records state, reference and torque of the same instant.
        keyframe: name of a keyframe of the model to reset to.
        actuation: ``actuation(model, data, tau) -> ctrl`` (shape ``(nu,)``) turning the
            controller's torque into ``data.ctrl``; by default ``ctrl = tau``, which a model whose
            actuators are servos (the UR5e) refuses: give it
            :func:`labsupport.actuators.servo_actuation`.
        split_step: ``mj_step1``, controller, ``mj_step2``, so the controller sees the current
            state's kinematics and dynamics (Euler and implicit integrators only).
        lab_timing: step as the lab's UR5e loop (see the module's description).

    Raises:
        ValueError: bad arguments, a controller returning the wrong shape, or one whose first
            call changed the state.
        SimulationDiverged: MuJoCo flagged bad positions, velocities, accelerations or controls
            (it resets the state when it does), or the state became non-finite. The error names
            the time and the last good state.

    Example: the MuJoCo single joint brought to 30° by PD plus gravity compensation,
    :math:`\tau = K_p(\theta_d - \theta) - K_d\dot\theta + h`; the log holds one row per 1 ms step.

    >>> from labsupport.plants import load_model
    >>> model, data = load_model("single_joint")
    >>> def pd_plus_gravity(model, data):
    ...     return 20.0 * (np.radians(30) - data.qpos) - 5.0 * data.qvel + data.qfrc_bias
    >>> log = simulate(model, data, pd_plus_gravity, duration=3.0)
    >>> print(log.q.shape, f"{np.degrees(log.q[-1, 0]):.3f} deg")
    (3000, 1) 30.000 deg
    """
    validate.model_and_data(model, data)
    validate.function("controller", controller, "a function controller(model, data) -> tau")
    if reference is not None:
        validate.function("reference", reference, validate.REFERENCE)
    if actuation is not None:
        validate.function("actuation", actuation, "a function actuation(model, data, tau) -> ctrl")
    if actuation is None:
        _check_torque_actuators(model)
    log_after_step = validate.flag("log_after_step", log_after_step)
    split_step = validate.flag("split_step", split_step)
    dt = model.opt.timestep
    nsteps = step_count(duration, dt, lab_timing)  # checks the duration
    if nsteps <= 0:
        raise ValueError(f"duration must be at least one time step ({dt} s), got {duration!r}")
    if split_step and lab_timing:
        raise ValueError("split_step and lab_timing exclude each other: the lab's loop calls mj_step only")
    if split_step and model.opt.integrator == mujoco.mjtIntegrator.mjINT_RK4:
        raise ValueError(
            "split_step needs the Euler or an implicit integrator: mj_step1/mj_step2 "
            "cannot split an RK4 step; use the default stepping with RK4"
        )
    if q0 is None and keyframe is None:
        _warn_state_set_by_hand(model, data)
    reset(model, data, q0, qdot0, keyframe=keyframe, forward=not lab_timing)
    site_id = -1 if site is None else dynamics.site_id(model, site)
    if reference is not None:  # checked before the run, which would otherwise be lost to it
        _check_reference(reference, (data.time, data.time + (nsteps - 1) * dt), 3 if site_id >= 0 else 0)
        _warn_coarse_reference(reference, dt)
    nu = model.nu
    limit = None
    if torque_limit is not None:
        if np.ndim(torque_limit) == 0:  # one number for every actuator
            limit = np.full(nu, validate.number("torque_limit", torque_limit))
        else:
            limit = validate.vector(f"torque_limit (a number, or one per actuator: nu = {nu})", torque_limit, nu).copy()
        if not np.all(limit > 0):
            raise ValueError(f"torque_limit must be positive, got {torque_limit!r}")
    # MuJoCo clamps ctrl to a limited ctrlrange: a torque actuator's range is clipped here too, so the
    # log holds what acts
    ctrlrange = _ctrlrange(model) if actuation is None else None
    lower, upper = _torque_bounds(limit, ctrlrange)
    clipped = np.empty(nu)

    # One row per step: time, qpos, qvel and ctrl, copied in one mj_getState call.
    nq, nv = model.nq, model.nv
    state = np.empty((nsteps, mujoco.mj_stateSize(model, _LOGGED_STATE)))
    q, qdot, ctrl_log = state[:, 1 : 1 + nq], state[:, 1 + nq : 1 + nq + nv], state[:, 1 + nq + nv :]
    tau_log = ctrl_log if actuation is None else np.empty((nsteps, nu))
    with_site = site_id >= 0
    ee = np.empty((nsteps, 3 if with_site else 0))
    ee_rot = np.empty((nsteps, 3 if with_site else 0, 3 if with_site else 0))
    ctrl = data.ctrl
    site_xpos = data.site_xpos[site_id] if with_site else None
    site_xmat = data.site_xmat[site_id].reshape(3, 3) if with_site else None
    warn = memoryview(data.warning.number)  # live view of MuJoCo's warning counters
    start = data.time, data.qpos.copy(), data.qvel.copy()  # time and state before step 0
    name = controller_name(controller)
    step, step1, step2, get_state = mujoco.mj_step, mujoco.mj_step1, mujoco.mj_step2, mujoco.mj_getState
    log_before = not log_after_step

    said: list[str] = []  # MuJoCo's own warning messages during the run
    checked = 0  # the next step whose controller call is checked for writes into the state: 0, 1, 2, 4, ...
    with _MUJOCO_WARNINGS.to(said):
        for k in range(nsteps):
            if split_step:
                step1(model, data)
            if k == checked:
                before = data.qpos.copy(), data.qvel.copy(), data.time
            if log_before and with_site:  # before the law runs: one that works in place on a view of
                ee[k] = site_xpos  # data.site_xpos (x = data.site_xpos[s]; x -= x_d) changes it
                ee_rot[k] = site_xmat
            try:
                tau = controller(model, data)
            except _CONTROLLER_ERRORS as err:
                raise _controller_failed(err, model, data) from err
            except KeyboardInterrupt as err:  # the kernel interrupted: say where the run was
                raise KeyboardInterrupt(_interrupted(name, data.time, duration)) from err
            if k == checked:
                checked = 2 * k or 1
                if why := state_written(name, data, *before):
                    raise ValueError(why)
            if type(tau) is not np.ndarray or tau.shape != (nu,) or tau.dtype != np.float64:
                tau = _as_torque(tau, nu)
            if lower is not None:
                tau = np.clip(tau, lower, upper, out=clipped)
            if actuation is None:
                ctrl[:] = tau
            else:
                tau_log[k] = tau
                try:
                    ctrl[:] = actuation(model, data, tau)
                except (ValueError, TypeError) as err:
                    raise ValueError(
                        f"the actuation mapping failed at t = {data.time:.4f} s: {err}; it must "
                        f"return the controls as an array of shape ({nu},)"
                    ) from err
            if log_before:
                get_state(model, data, state[k], _LOGGED_STATE)
            if split_step:
                step2(model, data)
            else:
                step(model, data)
            if warn[_W_QPOS] or warn[_W_QVEL] or warn[_W_QACC] or warn[_W_CTRL]:
                _raise_warning(k, state, q, qdot, start, tau, warn, log_after_step, said, actuation is not None)
            if log_after_step:
                get_state(model, data, state[k], _LOGGED_STATE)
    for message in said:  # the run went on: MuJoCo's other warnings (a full contact buffer, ...)
        warnings.warn(f"MuJoCo: {message}", RuntimeWarning, stacklevel=2)

    if log_after_step:  # each row holds the state after its step; the control began one step earlier
        t = state[:, 0].copy()
        t_ctrl = np.concatenate(([start[0]], t[:-1]))
    else:
        t = t_ctrl = state[:, 0].copy()
    q, qdot, ctrl_log = q.copy(), qdot.copy(), ctrl_log.copy()
    tau_log = ctrl_log.copy() if actuation is None else tau_log
    if ctrlrange is not None:
        _warn_ctrlrange_bound(model, t_ctrl, tau_log, ctrlrange, limit)
    _check_runaway(t, q, qdot)
    if limit is not None:  # a run that ran away has said so
        _warn_held_at_torque_limit(tau_log, limit)
    if log_after_step and with_site:
        ee, ee_rot = site_poses(model, q, site_id)
    if reference is not None:
        ref = _evaluate(reference, t_ctrl)
        err = ref - ee[:, : ref.shape[1]]
        bad = ~np.isfinite(ref).all(axis=1)
        if bad.any():  # the run itself is sound: keep it, and say where its error is undefined
            warnings.warn(
                f"the reference is not finite at {bad.sum()} of {nsteps} steps, first at t = "
                f"{t_ctrl[np.argmax(bad)]:.4f} s: the log's err, and the error metrics, are NaN there",
                RuntimeWarning,
                stacklevel=2,
            )
    else:
        ref = err = np.empty((nsteps, 0))
    return Log(t, q, qdot, tau_log, ctrl_log, ee, ee_rot, ref, err, site_id)


#: The errors of a controller that the loop says again with the time they happened at
#: (``LinAlgError`` is not a ``ValueError`` in NumPy 1).
_CONTROLLER_ERRORS = (
    ValueError,
    TypeError,
    np.linalg.LinAlgError,
    IndexError,
    KeyError,
    AttributeError,
    ArithmeticError,
)
#: How the loop's message begins when it says a controller's error again (the Problems' checks
#: recognise the loop's message by it, and show it as it is).
CONTROLLER_RAISED = "the controller raised"


def _interrupted(name: str, t: float, duration: float) -> str:
    """What a run stopped by the kernel's interrupt (Ctrl-C, Jupyter's stop button) says: where it
    was, and why a controller may never return."""
    return (
        f"the run was stopped at t = {t:.4f} s of {duration:g} s, inside {name}: if it "
        "seemed never to return, look in it for a loop that does not end (an IK iterating toward a "
        "tolerance it cannot reach, say); the traceback above shows the line it was on"
    )


#: What a function that makes controllers, passed where its controller goes, leads to.
MAKER_PASSED = (
    "the function passed as the controller seems to make controllers (its parameters are settings, such "
    "as gains or an offset) rather than be one: call it first and pass what it returns, as in "
    "simulate(model, data, make(...), duration)"
)


def _other_shape_hint(err: Exception) -> str:
    """Why a controller may treat MuJoCo's model or data as something else: a law of the analytic
    single joint (Task 1), which takes a ``SingleJoint``, or a ``torque(t, state)`` function; or
    the controller is a function that makes controllers, whose settings got ``(model, data)``; or a
    reference function read as a sampled reference."""
    text = str(err)
    if isinstance(err, AttributeError) and re.search(r"'function' object has no attribute '(at|pos|vel|acc)'", text):
        return (
            ". A function of time was used as a sampled reference: sample it first, "
            "reference = trajectories.sample(f, dt, duration), then reference.at(t); or call it, f(t)"
        )
    if re.search(r"got <mujoco\._structs\.Mj(Model|Data) object|non-iterable mujoco\._structs\.Mj", text):
        return f". MuJoCo's model or data reached a parameter that expected something else: {MAKER_PASSED}"
    if isinstance(err, ValueError) and "setting an array element with a sequence" in text:
        return f". Several numbers went where one goes (tau[0] = ...): is it {validate.REFERENCE_WHOLE}?"
    missing = getattr(err, "name", None)
    if isinstance(err, AttributeError) and "MjModel' object has no attribute" in text and _is_data_field(missing):
        return (
            f". {missing} is a field of MuJoCo's data, not of its model: the law was handed the two in "
            "the other order. simulate calls controller(model, data), and a law, like MuJoCo's own "
            "functions, takes (model, data) in that order"
        )
    if isinstance(err, AttributeError) and "MjModel' object has no attribute" in text:
        return (
            ". A law was handed the MuJoCo model where it expects another: the single-joint laws of "
            "labsupport.controllers.single_joint take a plants.SingleJoint as their model"
        )
    if isinstance(err, TypeError) and "MjData' object is not subscriptable" in text:
        return (
            ". simulate calls controller(model, data); a function torque(t, state) is the form "
            "SingleJoint.simulate calls: here read the state from data.qpos and data.qvel"
        )
    if raised_by_the_call(err):  # controller(model, data) itself: its parameters are others
        if isinstance(err, TypeError):
            return (
                ". simulate calls controller(model, data), with these two arguments only: a law that takes "
                "more goes inside such a function (def controller(model, data): return law(model, data, ...)); "
                "a function that makes a controller is called first, and what it returns is passed"
            )
        return ""
    return law_call_hint(err)


def raised_by_the_call(err: Exception) -> bool:
    """Whether ``err``, caught where a loop calls the controller, was raised by that call itself
    (the function does not take the arguments it is called with), not inside the function."""
    return err.__traceback__ is None or err.__traceback__.tb_next is None


def law_call_hint(err: Exception) -> str:
    """For a law that a controller called with fewer arguments than it takes, the two likely
    causes: an argument left out (Python then names the *last* ones as missing, whichever was
    left out), or a :class:`~labsupport.trajectories.Reference` (or ``Gains``) passed whole where
    the law takes its parts, which then fill the places of the arguments after it. Also for a law
    called with its arguments in another order, where one reaches a place that takes another, and
    for a gain or reference given as text or as a list, which do no arithmetic."""
    if isinstance(err, TypeError) and "missing" in str(err) and "argument" in str(err):
        return (
            "; a law inside it was called with fewer arguments than it takes. Python names the last "
            "ones as missing, whichever was left out: compare the call with the law's def line "
            "(help(law) shows it). A Reference or Gains passed whole also counts as one argument: "
            "unpack it with *, as in *reference(t)"
        )
    text = str(err)
    if isinstance(err, TypeError) and (
        re.search(r"unsupported operand type\(s\).*'(SingleJoint|Gains|MjModel|MjData|function)'", text)
        or re.search(r"object of type '(float|int)' has no len\(\)", text)
    ):
        return (
            "; an argument reached a place that takes another (an arm, gains or a number where something "
            "else goes): compare the call with the law's def line, argument by argument (help(law) shows it)"
        )
    if isinstance(err, TypeError) and (
        "can't multiply sequence by non-int" in text
        or re.search(r"dtype\('<U\d*'\)|operand type\(s\) for .*'(str|list|tuple)'", text)
    ):
        return (
            '; a number reached the law as text ("4.2") or as a list ([1.0, 2.0]), neither of which does '
            "arithmetic: write numbers without quotes, and vectors as np.array([...])"
        )
    return ""


def _is_data_field(name) -> bool:
    """Whether ``name`` is a field of ``MjData`` that ``MjModel`` lacks (``qpos``, ``qfrc_bias``),
    and so no attribute of a single joint's model (``M``, ``m``, ``r``, ``b``, ``g``) either."""
    from labsupport.plants import SingleJoint  # plants imports this module

    single_joint = {f.name for f in dataclasses.fields(SingleJoint)}
    return isinstance(name, str) and hasattr(mujoco.MjData, name) and name not in single_joint


def _controller_failed(err: Exception, model: mujoco.MjModel, data: mujoco.MjData) -> Exception:
    """The controller's error (say, ``None - 1.0`` from a reference not set, or an index past
    ``data.qpos``) again, as a ``TypeError`` if it was one and a ``ValueError`` otherwise, with the
    time it happened at; for a shape mismatch (a NumPy broadcast error from inside a law) or an
    index out of range also the sizes the model's state has."""
    kind = TypeError if isinstance(err, TypeError) else ValueError
    message = f"{CONTROLLER_RAISED} {type(err).__name__} at t = {data.time:.4f} s: {str(err).rstrip()}"
    if isinstance(err, np.linalg.LinAlgError) and "square" in str(err):
        message += f". np.linalg.solve and inv take a square matrix; {dynamics.SITE_JACOBIAN_ROWS}"
    elif isinstance(err, np.linalg.LinAlgError):
        message += (
            ". A matrix the law solves with or inverts is singular here: the Jacobian when the arm is stretched "
            "out or folded (keep the target inside the workspace, away from its edge), the wrong rows of the "
            f"site's Jacobian ({dynamics.ANGULAR_ROWS}), or a matrix of data whose state was set without "
            "mj_forward (on a scratch MjData: mj_kinematics, then mj_comPos)"
        )
    message += dynamics.full_m_advice(message) + _other_shape_hint(err)
    if isinstance(err, IndexError) and "only integers, slices" in str(err):
        message += (
            ". An array was indexed with something other than a whole number, such as a site's name: "
            "data.site_xpos[i] takes the site's id, model.site(name).id, and data.site(name).xpos takes its name"
        )
    elif "shape" in message or isinstance(err, IndexError):
        message += (
            f". The model's state has nq = {model.nq}, nv = {model.nv} and nu = {model.nu}: check that "
            "the references and gains given to the law have these sizes"
        )
    return kind(message)


def _check_torque_actuators(model: mujoco.MjModel) -> None:
    """``ValueError`` when the model's actuators are servos (a bias term: ``ctrl`` is their target
    position or velocity, not a torque) and no actuation mapping turns torques into targets."""
    servos = np.flatnonzero(model.actuator_biastype != mujoco.mjtBias.mjBIAS_NONE)
    if servos.size:
        name = model.actuator(int(servos[0])).name or f"actuator {servos[0]}"
        raise ValueError(
            f"{servos.size} of the model's {model.nu} actuators ({name}, ...) are servos: data.ctrl is their "
            "target, not a torque. For a controller that returns torques pass "
            "actuation=labsupport.actuators.servo_actuation(model); for one that returns the servos' targets, "
            "actuation=lambda model, data, target: target"
        )


def _ctrlrange(model: mujoco.MjModel) -> tuple[np.ndarray, np.ndarray] | None:
    """``(lo, hi)`` of the actuators' ``ctrlrange``, infinite where it is not limited; ``None`` when
    no actuator's is."""
    limited = model.actuator_ctrllimited.astype(bool)
    if not limited.any():
        return None
    lo, hi = model.actuator_ctrlrange.T
    return np.where(limited, lo, -np.inf), np.where(limited, hi, np.inf)


def _torque_bounds(limit, ctrlrange) -> tuple:
    """The torque bounds ``(lower, upper)``: the symmetric ``limit`` (or none), narrowed to
    ``ctrlrange`` (or not); ``(None, None)`` when neither bounds anything."""
    if ctrlrange is None:
        return (None, None) if limit is None else (-limit, limit)
    if limit is None:
        return ctrlrange
    return np.maximum(-limit, ctrlrange[0]), np.minimum(limit, ctrlrange[1])


def _warn_ctrlrange_bound(model: mujoco.MjModel, t: np.ndarray, tau: np.ndarray, ctrlrange, limit) -> None:
    """A ``RuntimeWarning`` when the actuators' ``ctrlrange`` (not ``torque_limit``) bound the
    torque: the controller asked for more than the motors give."""
    lo, hi = ctrlrange
    tighter = np.ones(len(lo), bool) if limit is None else (lo > -limit) | (hi < limit)  # else torque_limit's doing
    bound = tighter & ((tau == lo) | (tau == hi))
    if bound.any():
        steps = bound.any(axis=1)
        which = np.flatnonzero(bound.any(axis=0))
        warnings.warn(
            f"the actuators' ctrlrange bound the torque on {steps.sum()} of {len(tau)} steps, first at t = "
            f"{t[np.argmax(steps)]:.4f} s (actuators {', '.join(model.actuator(i).name or str(i) for i in which)}; "
            f"ctrlrange {', '.join(f'[{lo[i]:g}, {hi[i]:g}]' for i in which)}): the log holds "
            "the torque applied, not the one asked for. Ask for less (smaller gains or a gentler reference), or "
            "pass torque_limit= to make the limit part of the design",
            RuntimeWarning,
            stacklevel=3,
        )


#: Above this share of a run's steps, the last among them, a torque held at ``torque_limit`` is
#: warned of: the run is then the limit's, not the law's.
HELD_AT_LIMIT_SHARE = 0.5


def _warn_held_at_torque_limit(tau: np.ndarray, limit: np.ndarray) -> None:
    """A ``RuntimeWarning`` when ``torque_limit`` held the torque at its bound on more than
    :data:`HELD_AT_LIMIT_SHARE` of the steps, the last among them. A law with a flipped sign
    runs away; held at a limit, it need not, and the run ends without an error, far off."""
    held = (np.abs(tau) >= limit).any(axis=1)
    if held[-1] and held.mean() > HELD_AT_LIMIT_SHARE:
        warnings.warn(
            f"torque_limit held the torque at its bound on {held.sum()} of {len(held)} steps, the last among "
            "them: for most of the run the law asked for more than the limit, so the log shows what the limit "
            "allows, not the law's response. If that is not the design, look for a sign error in the law, or "
            "gains too high for the limit",
            RuntimeWarning,
            stacklevel=3,
        )


def controller_name(controller: Callable) -> str:
    """How the messages name ``controller``: its function's name (``pd_torque``); "the lambda
    controller" for a lambda; the wrapped function's name for a ``functools.partial``; "the
    ``Class`` object" for a callable object without a name."""
    while isinstance(controller, functools.partial):
        controller = controller.func
    name = getattr(controller, "__name__", None)
    if name == "<lambda>":
        return "the lambda controller"
    return name if isinstance(name, str) else f"the {type(controller).__name__} object"


#: What to do about a controller that changed the arm's state (see :func:`state_written`).
STATE_WRITE_ADVICE = (
    "a controller must only read the state. An in-place operation on an array that shares memory with the "
    "state writes into it, as e = data.qpos followed by e -= q_d does: compute with new arrays, "
    "e = q_d - data.qpos, or take a copy first, q = data.qpos.copy(). To evaluate another state, use a "
    "scratch mujoco.MjData(model)"
)


#: The fields of the arm's state, as messages name them, that a controller must only read.
STATE_FIELDS = ("data.qpos", "data.qvel")


def state_changes(data: mujoco.MjData, qpos_before, qvel_before) -> list[str]:
    """Those of :data:`STATE_FIELDS` whose values in ``data`` differ from ``qpos_before`` and
    ``qvel_before`` (NaN equal to NaN)."""
    now = (data.qpos, data.qvel)
    return [
        field
        for field, value, before in zip(STATE_FIELDS, now, (qpos_before, qvel_before), strict=True)
        if not np.array_equal(value, before, equal_nan=True)
    ]


#: What to do about a controller that moved the simulation's clock (see :func:`state_written`).
STEPPED_ADVICE = (
    "a controller only computes the torque for the state it is handed; simulate steps the simulation "
    "itself, once per call, so do not call mujoco.mj_step (or change data.time) inside the controller"
)


def state_written(
    name: str, data: mujoco.MjData, qpos_before: np.ndarray, qvel_before: np.ndarray, time_before: float
) -> str | None:
    """Why the controller ``name`` is stopped, if its call changed ``data.qpos``, ``data.qvel`` or
    ``data.time`` (``qpos_before``, ``qvel_before`` and ``time_before`` as they were before the
    call), else None. A controller that writes into the state makes the arm jump, and the run
    then diverges for a reason no gain explains. Most often an array that shares memory with the
    state was changed in place; one that moved the clock stepped the simulation."""
    if data.time != time_before:
        return f"{name} moved data.time from {time_before:.4f} s to {data.time:.4f} s; {STEPPED_ADVICE}"
    changed = state_changes(data, qpos_before, qvel_before)
    if not changed:
        return None
    return (
        f"{name} changed {' and '.join(changed)}, the arm's own state, at t = {data.time:.4f} s; {STATE_WRITE_ADVICE}"
    )


def _as_torque(tau, nu: int) -> np.ndarray:
    """The controller's return value as a ``(nu,)`` float array, or a clear error."""
    if tau is None:
        raise ValueError(f"the controller returned None; it must return a torque of shape ({nu},)")
    if callable(tau):
        raise ValueError(f"the controller returned a function, not a torque of shape ({nu},): {MAKER_PASSED}")
    validate.real("the controller returned", tau)
    if validate.is_text(tau):  # NumPy would read "1" as 1 N·m
        raise ValueError(
            f"the controller returned the text {validate.short(tau)}; it must return a torque of shape ({nu},)"
        )
    if validate.is_boolean(tau):  # NumPy would read True as 1 N·m
        raise ValueError(
            f"the controller returned {validate.short(tau)}, not torques: {validate.BOOLEAN_NOTE}; it must "
            f"return a torque of shape ({nu},)"
        )
    values = validate.floats(tau)
    if values is None:
        raise ValueError(
            f"the controller returned {validate.short(tau)}, not numbers; it must return a torque of shape ({nu},)"
        )
    tau = values
    if tau.size != nu:
        whole = f"; three numbers per joint: {validate.REFERENCE_WHOLE}" if tau.size == 3 * nu else ""
        raise ValueError(f"the controller returned a torque of shape {tau.shape}, expected ({nu},){whole}")
    return tau.reshape(nu)


def _raise_warning(k, state, q, qdot, start, tau, warn, log_after_step, said, actuated=False):
    """MuJoCo flagged step ``k`` (and reset the state): report the state at the step's start
    (``start``, the time, qpos and qvel before step 0, for ``k = 0`` with ``log_after_step``),
    or the first earlier state beyond :data:`RUNAWAY_SPEED` (so a run that ran away reports the
    same time whether or not this MuJoCo's warnings fire as well). With an actuation mapping
    (``actuated``), controls that went bad from a sound torque are laid at the mapping's door."""
    _check_runaway(state[:k, 0], q[:k], qdot[:k])
    if log_after_step:
        tk, qk, qdk = (state[k - 1, 0], q[k - 1], qdot[k - 1]) if k else start
    else:
        tk, qk, qdk = state[k, 0], q[k], qdot[k]
    if warn[_W_CTRL]:
        with np.printoptions(precision=4):
            reason = f"the controller returned tau = {tau}: MuJoCo's {_WARNING_MEANING[_W_CTRL]}"
            if actuated and np.all(np.abs(tau) < mujoco.mjMAXVAL):  # a sound torque: the mapping made them
                reason = (
                    f"the actuation mapping turned tau = {tau} into controls that are not finite or huge "
                    "(a None in its result becomes NaN)"
                )
    else:
        w = next(i for i in (_W_QPOS, _W_QVEL, _W_QACC) if warn[i])
        reason = (
            f"MuJoCo warning {mujoco.mjtWarning(w).name}: {_WARNING_MEANING[w]} during the step "
            "from this state; MuJoCo reset the simulation"
        )
    if said:
        reason += f" (MuJoCo: {said[-1].split('. ')[0]})"
    advice = None  # the runaway's
    if warn[_W_CTRL] and not np.isfinite(tau).all() and np.isfinite(qk).all() and np.isfinite(qdk).all():
        advice = NOT_A_NUMBER_ADVICE
    raise SimulationDiverged(float(tk), qk, qdk, reason, advice)


#: What to do about a torque that is not a number computed from a finite state: gains and
#: clipping do not cause it, one of the law's inputs or operations does.
NOT_A_NUMBER_ADVICE = (
    "The state is finite, so the law computed NaN or inf from something it was given or did: check "
    "the references and gains it is passed (a None becomes NaN in a NumPy array), a division by "
    "zero, and arrays it reads before they are filled."
)


class _WarningRoute:
    """Where MuJoCo's warnings go while runs are in progress: each thread's run collects its own.

    MuJoCo has one warning handler for the whole process, called in the thread whose MuJoCo call
    warns. The first run to start installs :meth:`handle`, the last to end puts back the handler
    that was in force before, so runs in several threads (a parameter sweep in a thread pool)
    neither swap each other's messages nor leave a stale handler behind.
    """

    def __init__(self):
        self.lock = threading.Lock()
        self.runs = 0
        self.before = None
        self.local = threading.local()

    def handle(self, message: str) -> None:
        """MuJoCo's warning handler: to the run of the calling thread, else to the handler in
        force before the runs, else printed to stderr as MuJoCo's default handler does (without
        its log file). It must not raise: an exception cannot pass back through MuJoCo's C code
        (the process aborts), so no Python warning here, which a ``-W error`` filter would raise."""
        said = getattr(self.local, "said", None)
        if said is not None:
            said.append(message)
        elif self.before is not None:  # a thread that is not running the loop
            self.before(message)
        elif sys.stderr is not None:
            print(f"MuJoCo warning: {message}", file=sys.stderr)

    @contextmanager
    def to(self, said: list[str]) -> Iterator[None]:
        """Collect this thread's MuJoCo warnings in ``said`` for the length of the block."""
        with self.lock:
            if self.runs == 0:
                self.before = mujoco.get_mju_user_warning()
                mujoco.set_mju_user_warning(self.handle)
            self.runs += 1
        outer, self.local.said = getattr(self.local, "said", None), said
        try:
            yield
        finally:
            self.local.said = outer
            with self.lock:
                self.runs -= 1
                if self.runs == 0:
                    mujoco.set_mju_user_warning(self.before)
                    self.before = None


#: The one route of MuJoCo's warnings during runs (see the module's description).
_MUJOCO_WARNINGS = _WarningRoute()


def _check_runaway(t, q, qdot):
    """Raise :class:`SimulationDiverged` at the first logged state that is not finite or whose
    fastest joint exceeds :data:`RUNAWAY_SPEED`."""
    finite = np.isfinite(q).all(axis=1) & np.isfinite(qdot).all(axis=1)
    with np.errstate(invalid="ignore"):
        bad = ~finite | (np.abs(qdot) > RUNAWAY_SPEED).any(axis=1)
    if bad.any():
        k = int(np.argmax(bad))
        reason = "non-finite state" if not finite[k] else runaway_reason(np.abs(qdot[k]).max())
        raise SimulationDiverged(float(t[k]), q[k], qdot[k], reason)


def runaway_reason(speed: float) -> str:
    """Why a run stopped at :data:`RUNAWAY_SPEED`, in words that do not claim the loop is
    unstable: a stable but very stiff one reaches the bound too. A speed past the bound is rounded
    up, so that it never reads as the bound itself; one at the bound (the analytic joint stops
    exactly there) is said to reach it."""
    bound = (
        f"{RUNAWAY_SPEED:g} rad/s (about {RUNAWAY_SPEED * 30 / math.pi:.0f} rpm), the speed at which a run "
        "stops as running away"
    )
    if speed <= RUNAWAY_SPEED:
        return f"a joint reached {bound}"
    return f"a joint turns at {math.ceil(10 * speed) / 10:g} rad/s, past {bound}"


def _check_reference(reference, span: tuple[float, float], site_dims: int) -> None:
    """``ValueError`` unless ``reference`` gives, at the run's first and last control times
    (``span``), a :class:`Reference` whose position a site position of ``site_dims`` coordinates
    can be compared with (a sampled reference shorter than the run fails at the last)."""
    first, last = span
    d = np.size(trajectories.evaluate(reference, first).pos)
    if d > site_dims:
        raise ValueError(
            f"the reference has {d} components; a site position has {site_dims}: reference= is compared with "
            "a site's position (pass site= to name it); the error of a joint-space reference is "
            "reference(log.t).pos - log.q, computed after the run"
        )
    try:
        trajectories.evaluate(reference, last)
    except ValueError as err:
        raise ValueError(f"the reference fails at the run's last control time, t = {last:.4f} s: {err}") from None


def _warn_coarse_reference(reference, dt: float) -> None:
    """``RuntimeWarning`` for a sampled reference coarser than the model's step ``dt``: read at the
    nearest sample, it stands still between samples, and the error logged against that staircase
    measures the staircase too (Task 3's operational-space CT sampled every 10 ms: 0.55 mm RMS
    instead of 0.32 mm)."""
    if isinstance(reference, trajectories.SampledReference) and reference.dt > dt * (1 + 1e-9):
        warnings.warn(
            f"the reference is sampled every {reference.dt:g} s, more coarsely than the model's step of {dt:g} s: "
            "between samples it stands still, and the logged error measures that staircase too. Sample it at "
            "the model's step: trajectories.sample(f, model.opt.timestep, duration)",
            RuntimeWarning,
            stacklevel=3,
        )


def _evaluate(reference, t) -> np.ndarray:
    """Reference positions at the times ``t``, shape ``(len(t), d)``: one vectorised call when
    possible, else one call per time."""
    try:
        pos = trajectories.evaluate(reference, t).pos
        if pos.shape[:1] == (len(t),):
            return pos.reshape(len(t), -1)
    except (ValueError, TypeError):
        pass
    return np.array([np.atleast_1d(trajectories.evaluate(reference, float(tk)).pos) for tk in t]).reshape(len(t), -1)


def site_poses(model: mujoco.MjModel, q: np.ndarray, site: str | int) -> tuple[np.ndarray, np.ndarray]:
    """Positions (N, 3) and orientations (N, 3, 3) of ``site`` (name or id) at the
    configurations ``q`` (N, nq; one configuration (nq,) gives N = 1), by forward kinematics on
    a scratch ``MjData`` (after ``mj_step`` the kinematics in ``data`` belong to the
    integrator's last evaluation, so logged poses are recomputed with this)."""
    validate.mujoco_model(model)
    site_id = dynamics.site_id(model, site)
    rows = validate.floats(q)
    if rows is None:
        rows = np.empty(0)  # not numbers: refused below
    if rows.ndim == 1 and rows.size == model.nq:
        rows = rows[None]  # one configuration
    if rows.ndim != 2 or rows.shape[1] != model.nq:
        raise ValueError(
            f"q must hold one configuration per row, shape (N, {model.nq}) (or ({model.nq},) for one), "
            f"got {validate.short(q)}"
        )
    if not np.isfinite(rows).all():
        raise ValueError(f"q must be finite: row {np.flatnonzero(~np.isfinite(rows).all(axis=1))[0]} is not")
    q = rows
    scratch = mujoco.MjData(model)
    qpos, xpos, xmat = scratch.qpos, scratch.site_xpos[site_id], scratch.site_xmat[site_id]
    pos, rot = np.empty((len(q), 3)), np.empty((len(q), 9))
    kinematics = mujoco.mj_kinematics
    for k, qk in enumerate(q):
        qpos[:] = qk
        kinematics(model, scratch)
        pos[k] = xpos
        rot[k] = xmat
    return pos, rot.reshape(len(q), 3, 3)


def site_positions(model: mujoco.MjModel, q: np.ndarray, site: str | int) -> np.ndarray:
    """Positions (N, 3) of ``site`` at the configurations ``q`` (N, nq); see :func:`site_poses`."""
    return site_poses(model, q, site)[0]
