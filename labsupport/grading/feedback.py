r"""What a check reports, and how the checks reach a student's code.

A check never touches a student's function directly: it asks a :class:`Probe` to call it by
name. :class:`DirectProbe` calls into a live namespace (the notebook's ``globals()``, for the
in-notebook feedback), watching that the call uses no part of labsupport a Problem TODO may not
use (:mod:`labsupport.grading.rules`); the batch grader's probe forwards the same calls to a separate process
that ran the submission (:mod:`labsupport.instructor.judge`). Either way the check gets plain
arrays back, or a :class:`StudentError` whose message says in plain words what went wrong.

Arguments that stand for MuJoCo's ``(model, data)`` pair are passed as a :class:`State`; the
probe turns it into a fresh ``MjData`` of the 3R arm at that state (``mj_forward`` run), so a
student's function sees exactly what it would see inside a simulation.
"""

from __future__ import annotations

import contextlib
import copy
import inspect
import os
import re
import signal
import sysconfig
import threading
import time
import traceback
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from functools import cache
from typing import Any

import mujoco
import numpy as np

from labsupport import validate
from labsupport.dynamics import ANGULAR_ROWS, SITE_JACOBIAN_ROWS, full_m_advice
from labsupport.grading.rules import ForbiddenUse, call_watched, forbidden_message, is_forbidden_message
from labsupport.sim import STATE_WRITE_ADVICE, state_changes

PASS, PARTIAL, FAIL, NOT_IMPLEMENTED = "pass", "partial", "fail", "not implemented yet"


#: CPU time the batch grader gives the student's code over one check [s] (a simulation calls it
#: at every control step); past it, that check scores zero there.
CHECK_CPU_SECONDS = 60.0
#: CPU time one call of a student's function may use [s], in the notebook's checks as in the
#: batch grader: an IK that never returns is stopped, and the check says so.
CALL_CPU_SECONDS = 10.0


@dataclass(frozen=True)
class Result:
    """Outcome of one check: a score in [0, 1] and plain-words feedback.

    Attributes:
        name: check name, e.g. ``"p1_ik"``.
        score: fraction of the check's points earned, in [0, 1].
        status: ``"pass"``, ``"partial"``, ``"fail"`` or ``"not implemented yet"``.
        message: what is right and what is wrong, in words a student can act on.
    """

    name: str
    score: float
    status: str
    message: str

    def __str__(self) -> str:
        mark = {PASS: "✔", PARTIAL: "◐", FAIL: "✘", NOT_IMPLEMENTED: "…"}.get(self.status, "?")
        share = f"({100 * self.score:.0f} % of this check's points) " if self.status == PARTIAL else ""
        return f"{mark} [{self.name}] {share}{self.message}"

    def _ipython_display_(self) -> None:
        """Show nothing as a cell's value: :func:`labsupport.grading.check` has already printed
        the feedback, and a second copy as a ``Result(...)`` repr only clutters the page."""


def passed(name: str, message: str) -> Result:
    return Result(name, 1.0, PASS, message)


def failed(name: str, message: str, score: float = 0.0) -> Result:
    score = float(np.clip(score, 0.0, 1.0))
    return Result(name, score, PARTIAL if score > 0 else FAIL, message)


def not_implemented(name: str, message: str) -> Result:
    return Result(name, 0.0, NOT_IMPLEMENTED, message)


class StudentError(Exception):
    """A student's function could not be used: missing, raised, or returned something unusable."""


class NotImplementedYet(StudentError):
    """The student's function returned ``None``: its TODO is not filled in yet."""


class StudentTimeout(StudentError):
    """The student's code did not answer within the time limit."""


class CallTimedOut(BaseException):
    """Raised inside the student's code when a call has used up its CPU time: a BaseException,
    so that an ``except Exception`` in a loop of theirs does not swallow it."""


@contextlib.contextmanager
def cpu_limit(seconds: float):
    """Stop the block with :class:`CallTimedOut` once the process has used ``seconds`` of CPU
    time in it (``ITIMER_PROF``), and every half second after, should the block catch it. Only
    where signals can be used, the main thread of a POSIX process (a notebook's kernel); no
    limit elsewhere."""
    if threading.current_thread() is not threading.main_thread() or not hasattr(signal, "setitimer"):
        yield
        return

    def expire(signum, frame):
        raise CallTimedOut

    previous = signal.signal(signal.SIGPROF, expire)
    signal.setitimer(signal.ITIMER_PROF, seconds, 0.5)
    try:
        yield
    finally:
        signal.setitimer(signal.ITIMER_PROF, 0)
        signal.signal(signal.SIGPROF, previous)


class ForbiddenCall(StudentError):
    """The student's function called into a part of labsupport a Problem TODO may not use
    (:mod:`labsupport.grading.rules`); the message says which, in plain words."""


def forbidden_reason(err: Exception) -> str | None:
    """The plain-words reason if ``err`` reports a forbidden use of labsupport (caught here by the
    probe, or raised by the batch sandbox's stubs and passed on as text), else ``None``."""
    text = str(err)
    if not isinstance(err, ForbiddenCall) and not is_forbidden_message(text):
        return None
    # the sandbox reports "fname raised RuntimeError: <reason>": keep the reason
    head, sep, tail = text.partition("RuntimeError: ")
    return tail if sep and is_forbidden_message(tail) else text


def refused(name: str, label: str, err: StudentError) -> Result:
    """The result of a check whose student function could not be used: not implemented yet,
    a forbidden use of labsupport (zero, with the reason), or another plain-words problem."""
    if isinstance(err, NotImplementedYet):
        return not_implemented(name, f"{label}: {err}")
    reason = forbidden_reason(err)
    if reason is not None:
        return failed(name, f"{label}: {reason}")
    return failed(name, f"{label}: {err}")


def show_beside(value: float, limit: float) -> str:
    """``value`` with enough significant digits that it never prints like ``limit`` (4 at least):
    1.0004 beside a limit of 1 prints as 1.0004, not 1."""
    digits = 4
    while digits < 17 and value != limit and float(f"{value:.{digits}g}") == limit:  # 17 tell any two doubles apart
        digits += 1
    return f"{value:.{digits}g}"


def show_pair(got, expected) -> str:
    """``got … , expected …`` with enough digits that two different vectors never print alike,
    and their difference, also as a share of the expected value unless that is zero."""
    got, expected = np.asarray(got, dtype=float), np.asarray(expected, dtype=float)
    precision = 4
    while precision < 17:
        with np.printoptions(precision=precision, suppress=True, floatmode="fixed"):
            a, b = np.array2string(got), np.array2string(expected)
        if a != b:
            break
        precision += 1
    diff, size = float(np.linalg.norm(got - expected)), float(np.linalg.norm(expected))
    share = f", {100 * diff / size:.3g} % of the expected value" if size > 0 else ""  # none of zero
    return f"got {a}, expected {b} (difference {diff:.3g}{share})"


@dataclass(frozen=True)
class State:
    """Stands for ``(model, data)`` of the 3R arm at joint positions ``q``, velocities ``qdot``, time ``t``."""

    q: np.ndarray
    qdot: np.ndarray
    t: float = 0.0


def degrees_question(q) -> str | None:
    """Where joint angles ``q`` lie beyond 3π, past even an answer a full turn off, the question
    whether they are in degrees (as words to append); ``None`` where they fit radians."""
    if np.abs(q).max() <= 3 * np.pi:
        return None
    return (
        "angles beyond 3π, where no joint angle in radians needs to be: are they in degrees? MuJoCo's "
        "angles are radians"
    )


def complex_message(fname: str) -> str:
    """What to say when ``fname`` returned complex numbers (in the notebook and in the batch grader)."""
    return validate.complex_message(f"{fname} returned")


def not_a_function_message(fname: str, kind: str) -> str:
    """What to say when ``fname`` holds a ``kind``, not a function (in the notebook and in the batch grader)."""
    return f"{fname} should be a function, but it is of type {kind}"


#: Why a law's torque may come out as a square matrix.
MATRIX_TORQUE_HINT = (
    "; a matrix times a vector written with * (M * v) makes a matrix, where M @ v is meant; so do gains "
    "given as matrices (Kp = 400 * np.eye(3)) multiplied with *: use @ for a matrix times a vector, or "
    "give the gains as numbers (or one number per joint)"
)


def as_vector(fname: str, value: Any, size: int, what: str = "result") -> np.ndarray:
    """Check a returned value is a finite vector of ``size`` numbers; say plainly what is wrong if not.

    Raises:
        NotImplementedYet: for ``None``.
        StudentError: for anything else unusable (wrong shape, NaN, not numbers).
    """
    if value is None:
        if what == "value":
            raise NotImplementedYet(f"{fname} is None: not implemented yet")
        raise NotImplementedYet(
            f"{fname} returned None: not implemented yet (a function that ends without a return "
            "statement returns None too)"
        )
    if validate.is_complex(value):
        raise StudentError(complex_message(fname))
    arr = validate.floats(value)
    if arr is None:
        shown = f" {validate.short(value)}" if isinstance(value, (list, tuple, np.ndarray)) else ""
        raise StudentError(f"{fname} returned {type(value).__name__}{shown}, expected {size} numbers")
    if arr.size == size and what == "torque":  # a row or a column (np.matrix, x[:, None]): simulate takes it
        arr = arr.reshape(size)
    if arr.shape != (size,):
        # a joint vector is set into data.qpos by the notebook's cells, which refuses a row or a column
        flat = f"; return it flat, np.ravel(...) (a row or a column of {size} numbers)" if arr.size == size else ""
        if what == "torque" and arr.shape == (size, size):
            flat = MATRIX_TORQUE_HINT
        raise StudentError(f"the {what} from {fname} has shape {arr.shape}, expected ({size},): {size} numbers{flat}")
    if not np.all(np.isfinite(arr)):
        note = validate.none_note(value)
        problem = "contains None" if note else "contains NaN" if np.any(np.isnan(arr)) else "is not finite"
        raise StudentError(f"the {what} from {fname} {problem}: {validate.short(value)}{note}")
    return arr


def arguments_written(fn: Callable, given: list[tuple[int, np.ndarray]], args: list) -> list[str]:
    """The names of ``fn``'s parameters whose array changed in the call: ``given`` holds
    ``(position, value before the call)`` for each array argument, ``args`` the arguments as
    handed. A parameter without a name (``*args``, a builtin) is named by its position."""
    try:
        names = [p.name for p in inspect.signature(fn).parameters.values() if p.kind <= p.POSITIONAL_OR_KEYWORD]
    except (TypeError, ValueError):
        names = []
    return [
        names[i] if i < len(names) else f"argument {i + 1}"
        for i, before in given
        if not (isinstance(args[i], np.ndarray) and np.array_equal(args[i], before, equal_nan=True))
    ]


def fields_written(data, qpos_before, qvel_before) -> list[str]:
    """:func:`labsupport.sim.state_changes` for a note only: ``[]`` where the comparison itself
    fails (the student's process may have replaced NumPy's functions), so that looking for a
    write can never cost an answer its points."""
    try:
        return state_changes(data, qpos_before, qvel_before)
    except Exception:
        return []


class Probe:
    """How a check calls the student's code. Subclasses implement :meth:`call` and :meth:`get`.

    Attributes:
        state_write: the first call since it was last set to None that changed the state it was
            handed, as ``(function name, ["data.qpos", ...])``, else None (see :func:`noting_writes`).
    """

    state_write: tuple[str, list[str]] | None = None
    #: The first call that changed an array argument it was handed, as ``(function name,
    #: [parameter names])`` (:func:`arguments_written`), else None.
    argument_write: tuple[str, list[str]] | None = None

    def notice_state_write(self, fname: str, changed: list[str]) -> None:
        """Record that a call of ``fname`` changed the ``changed`` fields of the state it was handed."""
        if changed and self.state_write is None:
            self.state_write = (fname, list(changed))

    def notice_argument_write(self, fname: str, changed: list[str]) -> None:
        """Record that a call of ``fname`` changed the arrays it was handed as ``changed``."""
        if changed and self.argument_write is None:
            self.argument_write = (fname, list(changed))

    def begin_part(self, label: str, share: float) -> None:
        """Start a part of a check whose calls may use ``share`` of the check's CPU and idle
        budgets (:data:`CHECK_CPU_SECONDS`), as ``label``: the tracking check gives each of its
        two laws half, so that a slow law cannot use up the other's time. A check begins as one
        part, its whole. A probe that enforces no budget only notes the part's CPU time."""

    def call(self, fname: str, *args, **kwargs):
        """Call the student's function ``fname``; returns its value (arrays as arrays) or raises StudentError."""
        raise NotImplementedError

    def get(self, name: str):
        """The value of the student's variable ``name`` (arrays as arrays); raises StudentError if missing."""
        raise NotImplementedError


@dataclass
class DirectProbe(Probe):
    """Calls straight into a namespace (the notebook's ``globals()``)."""

    namespace: dict
    _model: Any = field(default=None, repr=False)
    _data: Any = field(default=None, repr=False)
    #: The parts of the check so far, each ``[label, CPU time of the student's calls in it [s],
    #: its share of the budget]``: a check begins as one part, its whole (:meth:`begin_part`).
    parts: list = field(default_factory=lambda: [["your functions", 0.0, 1.0]], repr=False)
    #: How many calls were stopped at :data:`CALL_CPU_SECONDS`; each is said at once, as it happens.
    stopped: int = 0

    def begin_part(self, label: str, share: float) -> None:
        self.parts.append([label, 0.0, share])

    @property
    def busiest(self) -> tuple[str, float, float]:
        """The part that came nearest its share of the CPU budget: ``(label, seconds, share)``."""
        return tuple(max(self.parts, key=lambda part: part[1] / part[2]))

    def _model_data(self, state: State):
        """The 3R arm's model and the probe's one ``MjData``, reset and set to ``state`` (then
        ``mj_forward``). One data for every call, as in the batch sandbox and in a run: a law
        that keeps a view of ``data.qpos`` from one call to the next (a finite difference's
        "previous" q) finds it changed, as it would in a run. A fresh data for each call kept
        the old values alive behind the view, and the check passed a law that runs wrong."""
        import mujoco

        from labsupport.plants import load_model

        if self._model is None:
            self._model, _ = load_model("spatial_3r")
            self._data = mujoco.MjData(self._model)
        data = self._data
        mujoco.mj_resetData(self._model, data)
        data.qpos[:] = state.q
        data.qvel[:] = state.qdot
        data.time = state.t
        mujoco.mj_forward(self._model, data)
        return self._model, data

    def _expand(self, args):
        """The arguments as the student's function gets them: a State as (model, data), and
        every array or list a copy, so that a function that changes its arguments in place does
        not change the check's own targets (as in the batch grader, which sends copies). Also
        returns each State with the data made of it, to see whether the call changed it, and each
        array with its position and a copy, to see whether the call changed that."""
        out, handed, given = [], [], []
        for a in args:
            if isinstance(a, State):
                model, data = self._model_data(a)
                out.extend((model, data))
                handed.append((a, data))
            else:
                if isinstance(a, np.ndarray):
                    given.append((len(out), a.copy()))
                out.append(copy.deepcopy(a))
        return out, handed, given

    def _lookup(self, name: str):
        if name not in self.namespace:
            raise StudentError(f"{name} is not defined: {self._why_undefined(name)}")
        return self.namespace[name]

    def _why_undefined(self, name: str) -> str:
        """Why ``name`` is missing, from the notebook's input history (IPython's ``In``): the last
        cell run that defines it, if its code does not compile, says so; a cell run that assigns
        it (``q0_traj = ...``) must have stopped at an error before it got there; else run its cell."""
        history = self.namespace.get("In")
        for source in reversed(history if isinstance(history, list) else []):
            if isinstance(source, str) and re.search(rf"^\s*def\s+{re.escape(name)}\s*\(", source, re.M):
                try:
                    compile(source, "<cell>", "exec")
                except SyntaxError as err:
                    return (
                        f"the cell that defines it raised SyntaxError: {err.msg} (line {err.lineno} of the cell); "
                        "fix it and run that cell again"
                    )
                break
            if isinstance(source, str) and re.search(rf"^{re.escape(name)}\s*(?::[^=\n]*)?=(?!=)", source, re.M):
                return (
                    "the cell that sets it ran, but stopped at an error before it got there (see that cell's "
                    "output): fix it and run that cell again"
                )
        return "run its cell (above) first, or restore it if it was deleted"

    def call(self, fname: str, *args, **kwargs):
        fn = self._lookup(fname)
        if not callable(fn):
            raise StudentError(not_a_function_message(fname, type(fn).__name__))

        (expanded, handed, given), kwargs = self._expand(args), copy.deepcopy(kwargs)

        def call_and_read():  # read as numbers under the watch too: an __array__ runs code
            value = fn(*expanded, **kwargs)
            if validate.is_complex(value):
                raise StudentError(complex_message(fname))
            return _plain(value, f"{fname} returned")

        start = time.process_time()
        try:
            with cpu_limit(CALL_CPU_SECONDS):
                value, used = call_watched(call_and_read)
        except CallTimedOut:
            self.stopped += 1
            print(
                f"  … {fname} was stopped after {CALL_CPU_SECONDS:g} s of CPU time without returning; the check "
                "goes on (a loop that never ends makes it wait this long at each call it tries)."
                if self.stopped == 1
                else f"  … {fname} stopped again ({self.stopped} calls so far).",
                flush=True,
            )
            raise StudentTimeout(
                f"{fname} did not return: it used {CALL_CPU_SECONDS:g} s of CPU time, the most one call may use (a "
                "loop that never ends, in it or in a function it calls, such as an IK that never converges?)"
            ) from None
        except ForbiddenUse as err:
            raise ForbiddenCall(forbidden_use_text(err)) from None
        except StudentError:
            raise
        except Exception as err:  # the student's code may raise anything
            raise StudentError(
                raised_text(fname, f"{type(err).__name__}: {str(err).rstrip()}") + where_raised(err)
            ) from None
        finally:
            self.parts[-1][1] += time.process_time() - start
        if used is not None:
            raise ForbiddenCall(forbidden_message(used))
        for state, data in handed:
            self.notice_state_write(fname, fields_written(data, state.q, state.qdot))
        if not handed:  # a law is run on copies (grading.copies); a function such as the IK is not
            self.notice_argument_write(fname, arguments_written(fn, given, expanded))
        return value

    def get(self, name: str):
        return _plain(self._lookup(name), f"{name} is")


def noting_writes(result: Result, probe: Probe) -> Result:
    """``result`` with a note where a call of the check changed the state it was handed
    (:attr:`Probe.state_write`), or an array it was handed (:attr:`Probe.argument_write`), its
    score unchanged. Every call of a check gets a copy of the
    state, so such a write changes none of the check's numbers; but the notebook's own runs hand
    the law the arm's data, and the loop stops at the first call that changes it
    (:func:`labsupport.sim.state_written`)."""
    note = ""
    if probe.state_write is not None:
        fname, changed = probe.state_write
        note += (
            f" Note: {fname} changed {' and '.join(changed)} of the state the check handed it; {STATE_WRITE_ADVICE}. "
            "No points are lost here, where each call gets its own copy of the state, but your own runs, which "
            "hand the law the arm's data, stop at the first such call."
        )
    if probe.argument_write is not None:
        fname, changed = probe.argument_write
        note += (
            f" Note: {fname} changed the array it was handed as {' and '.join(changed)} (an in-place operation "
            "such as x[2] -= L1 writes into the caller's array): work on a copy, x = np.array(x, dtype=float), "
            "or compute new arrays. No points are lost here, where each call gets its own copy, but the "
            "notebook's cells hand it their own arrays, which then change under them: a target moved this way "
            "sends the runs below elsewhere."
        )
    return replace(result, message=result.message + note) if note else result


#: Why a law's matrix may be singular where the arm is not: the Jacobian of a point that a joint
#: does not move (a body whose origin is on that joint's axis: link3's, on joint 3's) has a zero
#: column; the angular rows 3–5 have rank 2 (the pitch axes are parallel); and a scratch
#: ``MjData`` whose positions were set but whose kinematics were not computed has a zero Jacobian.
SINGULAR_HINT = (
    " (where the arm is not stretched out or folded, a singular Jacobian is the Jacobian of the wrong "
    "point, of the wrong rows, or of data not yet computed: take the end effector's site, mj_jacSite with "
    "'end_effector' (a body's origin on a joint's axis, such as link3's, does not move with that joint, so "
    f"its column is zero); {ANGULAR_ROWS}; on a scratch MjData run mujoco.mj_kinematics and "
    "mujoco.mj_comPos after setting its qpos; check J before solving)"
)


#: Why a law's arrays may not fit together: the site Jacobian's six rows where the task has three.
JACOBIAN_ROWS_HINT = f" ({SITE_JACOBIAN_ROWS})"


#: Why a law may be called with more or fewer arguments than it takes: a signature other than the
#: stub's (the lab's own scaffold writes ``pd_torque(data, q_d, Kp, Kd)``, without ``model``).
SIGNATURE_HINT = (
    " (the checks and the runs call it with the arguments of the TODO's stub, in the stub's order, a "
    "law's model and data first: keep the stub's def line as it was handed out{line})"
)

#: The def line of each Problem TODO's stub, as the notebooks hand it out (a test holds the two
#: alike), quoted by :data:`SIGNATURE_HINT`.
STUB_DEF_LINES = {
    "ik_3r": "def ik_3r(x, elbow_up=True)",
    "pd_torque": "def pd_torque(model, data, q_d, Kp, Kd)",
    "ct_joint_torque": "def ct_joint_torque(model, data, q_d, Kp, Kd)",
    "ct_op_torque": "def ct_op_torque(model, data, x_d, xd_d, xdd_d, Kp, Kd)",
    "ct_ik_joint_torque": "def ct_ik_joint_torque(model, data, x_d, xd_d, xdd_d, Kp, Kd)",
}


def _top_level_split(text: str) -> list[str]:
    """``text`` split at the commas outside brackets and quotes (a parameter list)."""
    parts, depth, quote, start = [], 0, "", 0
    for i, c in enumerate(text):
        if quote:
            quote = "" if c == quote else quote
        elif c in "\"'":
            quote = c
        elif c in "[(":
            depth += 1
        elif c in "])":
            depth -= 1
        elif c == "," and depth == 0:
            parts.append(text[start:i].strip())
            start = i + 1
    return [*parts, text[start:].strip()]


def _plain_type(annotation: str) -> str:
    """A binding's type annotation in a student's words: ``model``, ``float64 array``, ``int``."""
    words = (("MjModel", "model"), ("MjData", "data"), ("ndarray", "float64 array"), ("NDArray", "float64 array"))
    kind = next((plain for key, plain in words if key in annotation), None)
    if kind is None:
        kind = "int" if "Int" in annotation or "int" in annotation else annotation.split(".")[-1]
    return kind + (" or None" if "None" in annotation else "")


def mujoco_arguments_text(error: str) -> str | None:
    """MuJoCo's "incompatible function arguments" error, which dumps its binding's types, said as
    the call it takes (``mj_jacSite(m: model, d: data, jacp: float64 array or None, ..., site:
    int)``), from the function's own signature (the error may come cut short); ``None`` for any
    other error."""
    match = re.match(r"TypeError: (mj[a-z]*_\w+)\(\): incompatible function arguments", error)
    function = getattr(mujoco, match.group(1), None) if match else None
    signature = re.match(r"\w+\((.*)\) ->", (getattr(function, "__doc__", None) or "").split("\n")[0])
    if signature is None:
        return None
    params = []
    for param in _top_level_split(signature.group(1)):
        name, _, annotation = param.partition(":")
        params.append(f"{name.strip()}: {_plain_type(annotation)}")
    given = error.partition("Invoked with:")[2]
    by_name = (
        ' (a name was given where it takes an id: model.site("end_effector").id, or model.body(name).id)'
        if re.search(r"'[^']*'", given) and any(p.endswith(": int") for p in params)
        else ""
    )
    return (
        f"TypeError: mujoco.{match.group(1)} does not take the arguments it was given: it takes "
        f"{match.group(1)}({', '.join(params)}), each array a C-contiguous float64 NumPy array{by_name}"
    )


def raised_text(fname: str, error: str) -> str:
    """What to say when the student's ``fname`` raised ``error`` (``"TypeName: message"``), with a
    hint where the error has a common cause in this lab; MuJoCo's dump of its binding's types is
    said as the call the function takes."""
    hint = ""
    if error.startswith("LinAlgError") and "ingular" in error:
        hint = SINGULAR_HINT
    elif error.startswith("LinAlgError") and "square" in error:  # np.linalg.solve(J, ...) with 6 rows
        hint = JACOBIAN_ROWS_HINT
    elif re.search(r"\(6,|\b6\)", error) and re.search(r"broadcast|dimension|aligned|shape", error):
        hint = JACOBIAN_ROWS_HINT
    elif re.match(rf"TypeError: (?:\S+\.)?{re.escape(fname)}\(\) .*(?:positional|keyword) argument", error):
        line = STUB_DEF_LINES.get(fname)  # the call of fname itself does not fit its def line
        hint = SIGNATURE_HINT.format(line=f", {line}" if line else "")
    else:
        hint = full_m_advice(error)
    return f"{fname} raised {mujoco_arguments_text(error) or error}{hint}"


@cache
def _library_dirs() -> tuple[str, ...]:
    """Where code that is not the student's lives: labsupport, the installed packages, Python's own."""
    paths = sysconfig.get_paths()
    dirs = {os.path.dirname(os.path.dirname(__file__)), paths["purelib"], paths["platlib"], paths["stdlib"]}
    return tuple(os.path.join(os.path.realpath(d), "") for d in dirs)


#: Frames of library code that name no file: Python's frozen modules, and NumPy's dispatch
#: wrappers before NumPy 1.25 (np.linalg.solve raised from "<__array_function__ internals>").
_LIBRARY_PSEUDO_FILES = ("<frozen", "<__array_function__ internals>")


def where_raised(err: BaseException) -> str:
    """`` (line N of <function>: <its code>)`` for the last line of the student's own code that the
    error passed through (not NumPy's, MuJoCo's or labsupport's), or ``""``."""
    for frame in reversed(traceback.extract_tb(err.__traceback__)):
        if not os.path.realpath(frame.filename).startswith(_library_dirs()) and not frame.filename.startswith(
            _LIBRARY_PSEUDO_FILES
        ):
            code = f": {' '.join(frame.line.split())}" if frame.line else ""  # one line, runs of spaces as one
            return f" (line {frame.lineno} of {frame.name}{code})"
    return ""


def forbidden_use_text(err: ForbiddenUse) -> str:
    """The reason of a forbidden use, with the student's line it passed through where the call
    raised after it (a stub's refusal in the sandbox, or the borrowed law's own error)."""
    return str(err) + ("" if err.__context__ is None else where_raised(err.__context__))


def _plain(value, what: str):
    """Arrays and numbers as float arrays; anything else unchanged (``None`` stays ``None``). An
    object whose conversion raises something else than ``TypeError``/``ValueError`` (its own
    ``__array__`` or ``__float__`` failing) is a :class:`StudentError` naming ``what`` it is."""
    if value is None or isinstance(value, (str, bytes, dict)):
        return value
    try:
        return np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        return value
    except Exception as err:  # the student's object may raise anything while it is converted
        raise StudentError(
            f"{what} a value of type {type(value).__name__} that raised {type(err).__name__} "
            f"when read as numbers: {err}"
        ) from None
