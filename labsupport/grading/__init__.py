"""Checks behind the Problems' in-notebook feedback (the batch grader is instructor tooling,
outside what a student installs).

In a notebook::

    from labsupport.grading import check
    check("p1_ik", globals())      # prints plain-words feedback on ik_3r

``check`` runs the same check functions the batch grader runs, with the public seed
:data:`PUBLIC_SEED`; the batch grader draws its targets, states and circles from a secret seed
of its own, and runs the checks outside the submission's process.

Modules:

==================  ===================================================================
``feedback``        results, probes (how a check reaches student code), plain-words errors
``rules``           what a Problem TODO may use from labsupport, and how other uses are caught
``common``          seeded test states, judging a torque against its formula, runs
``stability``       why a run diverged: a too stiff damping for the time step, or the law
``problem1``        Problem 1 checks (IK, PD, CT, reach)
``problem2``        Problem 2 checks (start, OS-CT, IK + JS-CT, tracking)
==================  ===================================================================
"""

from __future__ import annotations

import contextlib
import os
from collections.abc import Callable, Mapping

import numpy as np

from labsupport.dynamics import ANGULAR_ROWS
from labsupport.grading.feedback import (
    CALL_CPU_SECONDS,
    CHECK_CPU_SECONDS,
    CallTimedOut,
    DirectProbe,
    NotImplementedYet,
    Result,
    StudentError,
    as_vector,
    cpu_limit,
    degrees_question,
    noting_writes,
    where_raised,
)
from labsupport.grading.rules import ForbiddenUse, call_watched, forbidden_message
from labsupport.grading.stability import Trace, explain_divergence, handed_gains, target_in_degrees
from labsupport.sim import CONTROLLER_RAISED, SimulationDiverged, controller_name, state_written
from labsupport.validate import short

#: Set in the batch grader's sandbox: in-notebook checks then stay quiet (the grader runs its own).
BATCH_ENV = "LABSUPPORT_GRADING_BATCH"
#: The seed of the in-notebook checks' targets, states and circles (the batch grader uses another).
PUBLIC_SEED = 2024
#: A torque no law of this lab asks for at a sane speed [N·m]: the 3R arm's weight takes at most
#: 12.3 N·m to hold.
HUGE_TORQUE = 1e6
#: Joint speeds below which a huge torque is the law's own doing, not a run away's [rad/s].
SANE_SPEED = 50.0
#: Where such a torque comes from, when a run that asked for one diverged.
HUGE_TORQUE_HINT = (
    "a solve with a singular or nearly singular matrix gives such numbers. Check the Jacobian, the end "
    f"effector's site's, computed for the state it is used at ({ANGULAR_ROWS}); and check the target is "
    "within the arm's reach."
)


def registry() -> dict[str, Callable]:
    """Every check, by name: ``check_fn(probe, seed) -> Result``.

    The check modules are imported here, on first use, not at the top: in the batch grader's
    sandbox they are replaced by stubs (:data:`labsupport.grading.rules.FORBIDDEN`), and a
    student's ``from labsupport.grading import check`` must still import.
    """
    from labsupport.grading import problem1, problem2

    return {**problem1.CHECKS, **problem2.CHECKS}


def check(name: str, namespace: dict) -> Result | None:
    """Run check ``name`` on the functions and variables of ``namespace`` (pass ``globals()``) and print feedback.

    Never raises because of the student's code: a missing or broken function is reported in words.
    """
    if os.environ.get(BATCH_ENV):  # in the batch sandbox the check modules are not even present
        print(f"[{name}] checked separately by the batch grader")
        return None
    if isinstance(name, Mapping) and isinstance(namespace, str):
        raise ValueError(f"check's two arguments are swapped: call check({namespace!r}, globals())")
    if not isinstance(name, str):
        raise ValueError(f"check's first argument is the check's name, such as 'p1_ik'; got {short(name)}")
    if not isinstance(namespace, Mapping):
        raise ValueError(f"check needs the notebook's variables: call check({name!r}, globals())")
    checks = registry()
    if name not in checks:
        raise ValueError(f"no check named {name!r}; the checks are {sorted(checks)}")
    probe = DirectProbe(namespace)
    result = noting_writes(checks[name](probe, PUBLIC_SEED), probe)
    print(result)
    note = cpu_note(*probe.busiest, stopped=probe.stopped)
    if note:
        print(note)
    return result


def cpu_note(who: str, seconds: float, share: float = 1.0, stopped: int = 0) -> str:
    """A warning when ``who`` (the student's functions, or one law of a check that gives each of
    its laws a ``share``) took more than half the CPU time the batch grader gives them there,
    ``share`` × :data:`~labsupport.grading.feedback.CHECK_CPU_SECONDS`, else ``""``. Where
    ``stopped`` calls ran out of the time one call may use, the advice is about a loop that
    never ends, not about speed."""
    limit = share * CHECK_CPU_SECONDS
    if seconds <= limit / 2:
        return ""
    verdict = "more than" if seconds > limit else "over half of"
    advice = (
        f"{stopped} of the calls were stopped at the {CALL_CPU_SECONDS:g} s one call may use: find the loop "
        "that never ends (a while loop whose condition stays true, an iteration with no cap on its steps)"
        if stopped
        else "Make them faster: a closed-form IK instead of an optimiser, fewer iterations, no work repeated "
        "at every control step"
    )
    return (
        f"  Note: {who} took {seconds:.3g} s of CPU time in this check, {verdict} the {limit:g} s the batch "
        "grader allows there (on a machine that may be slower than this one); past that, the check scores zero "
        f"there. {advice}."
    )


class StudentController:
    """A student's ``fn(model, data, *args)`` as a controller ``(model, data) -> tau`` for
    :func:`labsupport.sim.simulate`, which says plainly when ``fn`` is not implemented or returns
    a bad torque. ``args`` may also be a single function of the time returning the tuple or
    list of them, or one value, the law's only argument after ``data`` (an array is passed
    whole, not spread)."""

    def __init__(self, fn: Callable, *args):
        self.fn, self.args = fn, args
        self.name = controller_name(fn)
        self.moving = len(args) == 1 and callable(args[0])
        self.trace = Trace()  # the states of the last run, to explain a divergence
        self.before = (np.empty(0), np.empty(0))  # the state before each call, kept to see it changed
        self.watched = False  # whether a call has been watched for a forbidden use yet
        self.largest = 0.0  # the largest torque asked for at a sane speed so far [N·m] (HUGE_TORQUE)
        self.used = None  # the forbidden function that call ran, if any (rules.call_watched)

    def __call__(self, model, data):
        self.trace.record(data)
        tau = self.torque(model, data)
        if np.abs(data.qvel).max() < SANE_SPEED:  # a run away asks for huge torques at huge speeds anyway
            self.largest = max(self.largest, float(np.abs(tau).max()))
        return tau

    def torque(self, model, data):
        """The student's torque at ``data``, checked (nothing recorded). A law that writes into
        the arm's state (``e = data.qpos; e -= q_d``) is stopped with that reason: the run would
        otherwise go on from a state the law made up, and diverge as if its signs were wrong."""
        extra = self.args[0](float(data.time)) if self.moving else self.args
        extra = copies(extra if isinstance(extra, (tuple, list)) else (extra,))
        if self.before[0].shape != data.qpos.shape or self.before[1].shape != data.qvel.shape:
            self.before = (np.empty_like(data.qpos), np.empty_like(data.qvel))  # once per model
        self.before[0][:], self.before[1][:] = data.qpos, data.qvel
        time = data.time
        if self.watched:
            tau = self.fn(model, data, *extra)
        else:  # the first call only: the watch slows every Python call it sees
            self.watched = True
            tau, self.used = call_watched(self.fn, model, data, *extra)
        if why := state_written(self.name, data, *self.before, time):
            raise StudentError(why)
        return as_vector(self.name, tau, model.nu, "torque")


def copies(args) -> tuple:
    """``args`` with each NumPy array copied, for one call of a law. A law may work in place on
    what it is handed (``q_d -= data.qpos``), as the checks allow; handed the notebook's own
    target, it changed ``q_des`` for every later cell, and the run went astray from a target the
    student never set."""
    return tuple(a.copy() if isinstance(a, np.ndarray) else a for a in args)


def as_controller(fn: Callable, *args) -> StudentController:
    """Wrap a student's ``fn(model, data, *args)`` into a controller (see :class:`StudentController`)."""
    return StudentController(fn, *args)


def attempt(label: str, run: Callable, controller: StudentController | None = None, model=None, joints=None):
    """Run ``run()`` (e.g. a simulation) and return its result, or print why it cannot run yet and return None.

    With the run's ``controller`` (from :func:`as_controller`) and ``model``, a divergence is
    explained: a damping too stiff for the time step is named as such, with its numbers and the
    remedies. With ``joints``, the result is a joint vector (an IK's answer), which must be that
    many finite numbers: one of another shape is refused here, in the checks' words, so the
    cells that use it wait instead of failing inside NumPy or MuJoCo, and it may use the CPU time one
    call of the checks may (:data:`~labsupport.grading.feedback.CALL_CPU_SECONDS`), so that an IK that
    never returns does not hang the notebook; angles beyond :math:`3\\pi`
    are returned with a note asking whether they are degrees.

    A run that went through a part of labsupport a Problem TODO may not use (Task 3's joint CT,
    the 2R arm's IK: :data:`~labsupport.grading.rules.FORBIDDEN`) still returns its result, with
    a note that the TODO's check scores it zero: the run itself says so, not only the check.
    ``run`` is watched whole when there is no ``controller``; a controller watches its first call.
    """
    try:
        if controller is None:
            # the batch sandbox times its cells itself, with the same timer: this one would disarm it
            limited = joints is not None and not os.environ.get(BATCH_ENV)
            with cpu_limit(CALL_CPU_SECONDS) if limited else contextlib.nullcontext():
                value, used = call_watched(run)
        else:
            value, used = run(), controller.used
        if joints is not None:
            value = as_vector(label, value, joints, "joint vector")
            if question := degrees_question(value):
                print(
                    f"{label}: note: {short(value)} has {question}, so the runs below would aim elsewhere: "
                    "return radians (no np.degrees)."
                )
        if used is not None:
            print(f"{label}: it ran, but {forbidden_message(used)[:-1]} in its check.")
        return value
    except NotImplementedYet as err:
        print(f"{label}: skipped, {err}. Fill in the TODO above and run again.")
    except ForbiddenUse as err:  # it raised after the forbidden call, or switched the watch off
        print(f"{label}: skipped, {err}")
    except CallTimedOut:
        print(
            f"{label}: skipped, it did not return within {CALL_CPU_SECONDS:g} s of CPU time, the most one call "
            "may use in the checks too (a loop that never ends, such as an IK that never converges?). Fix it, "
            "run its cell, then this one again."
        )
    except StudentError as err:
        print(f"{label}: skipped, {err}.")
    except SimulationDiverged as err:
        reason = None
        if controller is not None and not controller.moving:
            reason = target_in_degrees(controller.fn, controller.args)
        if reason is not None:
            reason += f" ({err.reason})."
        elif controller is not None and model is not None:
            gains = None if controller.moving else handed_gains(controller.fn, controller.args)
            reason = explain_divergence(
                model, controller.torque, controller.trace, err.t, law=controller.name, gains=gains
            )
        if reason is None and controller is not None and controller.largest > HUGE_TORQUE:
            largest = f"The law asked for torques of up to {controller.largest:.3g} N·m"
            reason = f"{err.reason}. {largest}: {HUGE_TORQUE_HINT}"
        print(
            f"{label}: the simulation diverged at t = {err.t:.3f} s: "
            + (reason or f"{err.reason}. Lower the gains, clip the torque, or check the signs of the law.")
        )
    except Exception as err:  # the student's code may raise anything
        where = where_raised(err.__cause__ or err)  # simulate says the controller's error again, with its time
        said = str(err) if str(err).startswith(CONTROLLER_RAISED) else f"it raised {type(err).__name__}: {err}"
        print(f"{label}: skipped, {said}{where}")
    return None
