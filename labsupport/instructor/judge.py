"""Grade one submission: run its cells in a sandbox, then run the grader's own checks against it.

The checks run here, in the grader's process, which the submission cannot see: the sandbox
(:mod:`labsupport.instructor.sandbox`, started by :mod:`labsupport.instructor.isolation`) only
ever sends back plain numbers. Every simulation a check runs uses this process's MuJoCo model
and loop; the submission's code is called once per control step, for its torque.

Limits that decide a score count what the submission itself consumed, never wall time, so a
busy machine cannot change a score:

* CPU time, per cell, per call and per check (the sandbox's own timer interrupts a cell; the
  judge reads the whole sandbox's CPU time from ``/proc`` and stops it if the timer was evaded);
* time spent waiting without being runnable (``sleep``, a blocked read), which does not depend
  on the machine's load either.

A wall-clock backstop per submission (generous) stops a sandbox that neither computes nor
waits measurably; that row is then marked "timed out: regrade", with no score.

The sandbox answers on a pipe, one JSON line per request, tagged with the request's nonce. The
judge reads whatever arrives, checking the limits above all the while, and never waits for a
line to end: a submission that writes into that pipe itself (half a line, then silence; or an
endless line, stopped at :data:`MAX_ANSWER`) cannot hold the judge or fill its memory, and one
that alters the answers (an answer that does not parse, or fields of the wrong kind) is stopped
or ignored, never trusted.
"""

from __future__ import annotations

import ast
import inspect
import json
import os
import re
import secrets
import select
import signal
import subprocess
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from labsupport.grading.feedback import (
    CALL_CPU_SECONDS,
    CHECK_CPU_SECONDS,
    NOT_IMPLEMENTED,
    PASS,
    Probe,
    Result,
    State,
    StudentError,
    StudentTimeout,
    complex_message,
    failed,
    not_a_function_message,
    noting_writes,
    raised_text,
)
from labsupport.instructor import isolation
from labsupport.instructor.sandbox import not_run, timed_out
from labsupport.sim import STATE_FIELDS

#: Status of a row stopped by the wall-clock backstop (no score: grade it again).
REGRADE = "timed out: regrade"


@dataclass(frozen=True)
class Budget:
    """The limits a submission's code runs under (CPU seconds unless said otherwise).

    Attributes:
        cell: CPU time of one cell.
        run: CPU time of all cells together: the cell that uses up the rest is stopped and the
            cells after it do not run; the checks then grade what was defined.
        call: CPU time of one call of a student's function.
        check: CPU time of the student's code over one check (a simulation calls it every step).
        idle: time one cell or call may wait without being runnable [s].
        run_idle: time all cells together may wait [s] (a notebook that pauses for an animation
            or two stays well within it); past it, as past ``run``.
        check_idle: time the student's calls may wait in all over one check [s] (a function that
            sleeps a little at every control step would otherwise hold the grader for hours).
        wall: wall-clock backstop for the whole submission [s]; past it the row says "timed out: regrade".
    """

    cell: float = 30.0
    run: float = 120.0
    call: float = CALL_CPU_SECONDS
    check: float = CHECK_CPU_SECONDS
    idle: float = 20.0
    run_idle: float = 60.0
    check_idle: float = 20.0
    wall: float = 900.0


#: The limits a batch uses unless told otherwise.
DEFAULT_BUDGET = Budget()

#: How far past a limit the judge lets the sandbox go before stopping it itself.
GRACE = 5.0
#: When the judge first measures a request still unanswered [s], then every :data:`POLL`: waiting
#: before the first measurement goes uncounted, so a call can hide at most this much each time.
FIRST_POLL, POLL = 0.02, 0.25
#: The most the sandbox may send back without ending a line [bytes]. An answer is a few hundred
#: kilobytes at most (arrays are capped at ``sandbox.MAX_ELEMENTS``, file lists at
#: ``sandbox.MAX_LISTED``); more means the submission writes into the grader's channel itself.
#: Each answer costs the judge, not the submission, the time to read it: padding every answer
#: to this size costs a check's 2,500 calls a few seconds.
MAX_ANSWER = 1 << 20
#: The longest file name a note shows [characters].
MAX_PATH_CHARS = 80
#: What the sandbox may name as an argument a call changed: a parameter's name, or its position.
_PARAMETER = re.compile(r"[A-Za-z_]\w{0,39}|argument \d{1,2}")


#: Why an answer whose fields have kinds the sandbox never writes scores nothing.
ALTERED_ANSWER = "the notebook altered its answer in the grader's channel (a field of a kind the sandbox never writes)"


class SandboxDied(StudentError):
    """The sandbox process ended (the notebook exited, crashed, or was stopped)."""


class ChannelTampered(SandboxDied):
    """The submission wrote into the grader's answer channel: more than any answer holds, or an
    answer (it carries the request's nonce) that does not parse; the sandbox was stopped."""


class WallClockExceeded(Exception):
    """The wall-clock backstop ran out: the row gets no score and must be graded again."""


def _stat(pid: int):
    with open(f"/proc/{pid}/stat") as f:
        fields = f.read().rsplit(")", 1)[1].split()
    return int(fields[1]), sum(int(x) for x in fields[11:15])  # ppid, utime+stime+cutime+cstime


def tree_cpu(root: int) -> float:
    """CPU time [s] of process ``root`` and all its descendants (children already reaped included)."""
    parents, cpu = {}, {}
    for entry in os.listdir("/proc"):
        if entry.isdigit():
            try:
                parents[int(entry)], cpu[int(entry)] = _stat(int(entry))
            except (OSError, ValueError, IndexError):
                continue
    members, frontier = {root}, [root]
    children: dict[int, list[int]] = {}
    for pid, ppid in parents.items():
        children.setdefault(ppid, []).append(pid)
    while frontier:
        for child in children.get(frontier.pop(), []):
            if child not in members:
                members.add(child)
                frontier.append(child)
    return sum(cpu.get(p, 0) for p in members) / os.sysconf("SC_CLK_TCK")


#: What a check's budget is for, where the check is not split into parts.
WHOLE = "the submission's code"


class SandboxProbe(Probe):
    """A :class:`Probe` whose calls go to a sandbox that ran the submission's cells."""

    def __init__(
        self,
        command,
        cells: list[tuple[int, str]],
        budget: Budget = DEFAULT_BUDGET,
        env=None,
        cwd=None,
        limits: isolation.Limits = isolation.DEFAULT_LIMITS,
        max_starts: int = 3,
    ):
        self.command, self.env, self.cwd, self.limits = command, env, cwd, limits
        self.depth = 2 if Path(command[0]).name == "bwrap" else 0
        self.cells, self.budget, self.max_starts = cells, budget, max_starts
        self.proc: subprocess.Popen | None = None
        self.unread = bytearray()  # what the sandbox sent after its last complete line
        self.starts = 0
        self.wall_deadline = time.monotonic() + budget.wall
        self.begin_part(WHOLE, 1.0)  # again for each check, and each part of one
        self.cpu_seen = 0.0
        self.server: tuple[int, int] | None = None  # (sandbox pid, its cell server's pid)
        self.first_run: dict | None = None
        self.start_problem: str | None = None

    def begin_part(self, label: str, share: float) -> None:
        self.part = label
        self.check_cpu_limit, self.check_idle_limit = share * self.budget.check, share * self.budget.check_idle
        self.check_cpu_left, self.check_idle_left = self.check_cpu_limit, self.check_idle_limit

    # -- process ---------------------------------------------------------------------------------
    def start(self) -> None:
        """Start a sandbox and run the notebook's cells in it."""
        if self.starts >= self.max_starts:
            raise SandboxDied(f"skipped: the submission's process had to be stopped {self.starts} times")
        self.stop()
        self.starts += 1
        self.unread = bytearray()
        limits = self.limits
        self.proc = subprocess.Popen(
            self.command,
            stdin=subprocess.PIPE,
            stdout=subprocess.PIPE,
            stderr=subprocess.DEVNULL,
            env=self.env,
            cwd=self.cwd,
            start_new_session=True,
            preexec_fn=lambda: isolation.apply_limits(limits),
        )
        self.cpu_seen = 0.0
        try:
            answer = self._request(
                {
                    "op": "run",
                    "cells": [src for _, src in self.cells],
                    "cell_cpu": self.budget.cell,
                    "idle": self.budget.idle,
                    "run_cpu": self.budget.run,
                    "run_idle": self.budget.run_idle,
                },
                self.budget.run,
                per_check=False,
            )
        except (StudentTimeout, ChannelTampered) as err:
            self.start_problem = f"the notebook's cells did not finish: {err}"
            raise type(err)(self.start_problem) from None
        except SandboxDied:
            self.start_problem = "the notebook ended the grading process while its cells ran (exit, crash or kill)"
            raise SandboxDied(self.start_problem) from None
        if self.first_run is None:
            self.first_run = answer

    def stop(self) -> None:
        """Stop the sandbox: killing bubblewrap tears down its PID namespace and everything in it."""
        if self.proc is not None:
            for kill in (lambda: os.killpg(self.proc.pid, signal.SIGKILL), lambda: self.proc.kill()):
                try:
                    kill()
                except (ProcessLookupError, PermissionError):
                    pass
            self.proc.wait()
            for f in (self.proc.stdin, self.proc.stdout):
                try:
                    f.close()
                except OSError:
                    pass
        self.proc = None

    def _request(self, payload: dict, cpu_limit: float, per_check: bool = True) -> dict:
        """Send one request; wait for its answer while the sandbox stays within ``cpu_limit`` CPU
        seconds, the idle limits, the check's budgets and the wall-clock backstop.

        Idle time is limited per call and, over a check, in all (:attr:`Budget.check_idle`); the
        cells' run (``per_check=False``) in all (:attr:`Budget.run_idle`), each cell being stopped
        by the sandbox's own watch when it waits longer than :attr:`Budget.idle`."""
        nonce = secrets.token_hex(8)
        payload["nonce"] = nonce
        try:
            self.proc.stdin.write((json.dumps(payload) + "\n").encode())
            self.proc.stdin.flush()
        except (BrokenPipeError, OSError):
            self.stop()
            raise SandboxDied("the submission's process has ended") from None
        fd = self.proc.stdout.fileno()
        sent = time.monotonic()
        cpu0 = busy0 = None
        idle = 0.0
        next_poll = sent + FIRST_POLL
        while True:
            # The limits are checked at every poll, also while the sandbox keeps sending: a
            # submission that writes into the channel itself must not hold the judge here.
            if time.monotonic() >= next_poll:
                next_poll = time.monotonic() + POLL
                if time.monotonic() > self.wall_deadline:
                    self.stop()
                    raise WallClockExceeded(f"grading took more than {self.budget.wall:g} s of wall-clock time")
                cpu, busy = tree_cpu(self.proc.pid), _busy(self._server_pid())
                if cpu0 is None:  # measured from the first poll: a quick answer costs no /proc reads
                    cpu0, busy0 = cpu - (time.monotonic() - sent), busy
                limit = min(cpu_limit, self.check_cpu_left) if per_check else cpu_limit
                if cpu - cpu0 > limit + GRACE:
                    self.stop()
                    raise StudentTimeout(f"it used more than {limit:g} s of CPU time")
                idle = (busy[0] - busy0[0]) - (busy[1] - busy0[1])
                self._check_idle(idle, per_check)
            answer = self._answer(fd, nonce, wait=max(0.0, next_poll - time.monotonic()))
            if answer is not None:
                cpu = self._server_cpu()
                if per_check:
                    self.check_cpu_left -= max(0.0, cpu - self.cpu_seen)
                    self.check_idle_left -= idle
                self.cpu_seen = cpu
                if per_check and self.check_cpu_left < 0:
                    raise StudentTimeout(f"the check ran out of CPU time ({self.check_cpu_limit:g} s for {self.part})")
                if per_check and self.check_idle_left < 0:
                    raise StudentTimeout(self._waited_in_all())
                return answer

    def _check_idle(self, idle: float, per_check: bool) -> None:
        """Stop the sandbox if the request has waited ``idle`` seconds beyond its limits."""
        if not per_check:
            if idle > self.budget.run_idle + GRACE:
                self.stop()
                raise StudentTimeout(f"its cells waited more than {self.budget.run_idle:g} s in all without computing")
            return
        if idle > self.budget.idle + GRACE:
            self.stop()
            raise StudentTimeout(f"it waited more than {self.budget.idle:g} s without computing")
        if idle > self.check_idle_left + GRACE:
            self.stop()
            raise StudentTimeout(self._waited_in_all())

    def _waited_in_all(self) -> str:
        return (
            f"over this check, the calls{'' if self.part == WHOLE else ' of ' + self.part} waited more than "
            f"{self.check_idle_limit:g} s in all without computing "
            "(sleep, input, a blocked read): a control law must return at once"
        )

    def _answer(self, fd: int, nonce: str, wait: float) -> dict | None:
        """The answer carrying ``nonce`` among the complete lines the sandbox has sent within
        ``wait`` seconds, or None. Reads what is there without waiting for a line's end (a
        submission that writes half a line into the channel cannot block the judge), keeps
        the unfinished rest for the next call, and skips lines that are not answers. A line that
        carries the nonce and does not parse was altered by the submission: it stops the sandbox."""
        if not select.select([fd], [], [], wait)[0]:
            return None
        chunk = os.read(fd, 1 << 16)
        if not chunk:
            self.stop()
            raise SandboxDied("the submission's process ended")
        self.unread += chunk
        if b"\n" not in chunk:
            if len(self.unread) > MAX_ANSWER:
                self.stop()
                raise ChannelTampered(f"it wrote more than {MAX_ANSWER >> 20} MiB into the grader's channel")
            return None
        *lines, rest = self.unread.split(b"\n")
        self.unread = bytearray(rest)
        tag = nonce.encode()
        for line in lines:
            if tag not in line:
                continue  # not ours: only the answer carries the nonce
            try:
                answer = json.loads(line)
            except (ValueError, RecursionError):  # RecursionError: nested a hundred thousand deep
                self.stop()
                raise ChannelTampered("the notebook altered an answer in the grader's channel") from None
            if isinstance(answer, dict) and answer.get("nonce") == nonce:
                return answer
        return None

    def _server_cpu(self) -> float:
        """CPU time [s] the cell server has used so far, all its threads and its ended children
        included, read by the judge from ``/proc``; where the server cannot be read (it has just
        ended), the whole sandbox's, also from ``/proc``. Never a figure the sandbox reports: the
        submission's code runs in that process and can change it (``time.process_time = lambda:
        0.0``), so a budget counted from it could be dodged."""
        try:
            return _stat(self._server_pid())[1] / os.sysconf("SC_CLK_TCK")
        except (OSError, ValueError, IndexError):
            return max(self.cpu_seen, tree_cpu(self.proc.pid))

    def _server_pid(self) -> int:
        """The cell server: bubblewrap's grandchild (bubblewrap, its PID-1 init, the server), or the
        process itself without a sandbox."""
        if self.server is not None and self.server[0] == self.proc.pid:
            return self.server[1]
        pid = self.proc.pid
        for _ in range(self.depth):
            try:
                with open(f"/proc/{pid}/task/{pid}/children") as f:
                    pid = int(f.read().split()[0])
            except (OSError, ValueError, IndexError):
                return pid
        self.server = (self.proc.pid, pid)  # found: kept for this sandbox's later requests
        return pid

    def _ensure(self) -> None:
        if self.proc is None or self.proc.poll() is not None:
            if self.start_problem is not None:
                raise StudentError(f"skipped: {self.start_problem}")
            self.start()

    # -- Probe -----------------------------------------------------------------------------------
    def _ask(self, payload: dict, name: str) -> dict:
        self._ensure()
        try:
            return self._request(payload, self.budget.call)
        except StudentTimeout as err:
            raise StudentTimeout(f"{name} did not return: {err}") from None

    def call(self, fname: str, *args, **kwargs):
        payload = {
            "op": "call",
            "name": fname,
            "args": [_encode_arg(a) for a in args],
            "kwargs": {k: _encode_arg(v) for k, v in kwargs.items()},
            "cpu": self.budget.call,
            "idle": self.budget.idle,
        }
        answer = self._ask(payload, fname)
        self._refuse_missing(fname, answer)
        changed = answer.get("state_written")  # words for a note: only what the sandbox writes is taken
        if isinstance(changed, list) and all(isinstance(f, str) and f in STATE_FIELDS for f in changed):
            self.notice_state_write(fname, changed)
        changed = answer.get("arguments_written")  # parameter names, shown in the note: names only
        if isinstance(changed, list) and all(isinstance(f, str) and _PARAMETER.fullmatch(f) for f in changed):
            self.notice_argument_write(fname, changed)
        return _decode(fname, answer, call=True)

    def get(self, name: str):
        answer = self._ask({"op": "get", "name": name, "cpu": self.budget.call, "idle": self.budget.idle}, name)
        self._refuse_missing(name, answer)
        return _decode(name, answer)

    def _refuse_missing(self, name: str, answer: dict) -> None:
        """``StudentError`` where the notebook has no ``name``, naming the cell that defines it
        and what went wrong there when that cell raised (a syntax error, say): "not defined"
        alone sends a student looking for a deleted cell."""
        if not answer.get("missing"):
            return
        errors = {e[0]: e[1] for e in _listed(self.first_run or {}, "errors") if _is_cell_error(e)}
        defines = re.compile(rf"^(?:def\s+{re.escape(name)}\b|{re.escape(name)}\s*=)", re.M)
        unrun = [k for k, text in errors.items() if text in _LIMIT_TEXTS and text.startswith("not run")]
        for k, (index, source) in enumerate(self.cells):
            if not defines.search(source):
                continue
            if k in errors:
                raise StudentError(f"{name} is not defined: its {_cell_named(index, source)} {_error_note(errors[k])}")
            if unrun and k > unrun[0]:
                raise StudentError(
                    f"{name} is not defined: its {_cell_named(index, source)} never ran, the cells before it "
                    "having used up their time together (see the notes)"
                )
        _decode(name, answer)  # the plain "not defined"

    def files(self) -> dict:
        """What the notebook wrote in its scratch space (empty if it is not running)."""
        if self.proc is None or self.proc.poll() is not None:
            return {}
        try:
            return self._request({"op": "files"}, self.budget.call, per_check=False)
        except StudentError:
            return {}


def _busy(pid: int) -> tuple[float, float]:
    """``(wall clock, CPU time + time queued for a CPU)`` of process ``pid`` [s]: their difference
    grows only while it waits without being runnable, however busy the machine is."""
    try:
        with open(f"/proc/{pid}/schedstat") as f:
            cpu, queued = (int(x) for x in f.read().split()[:2])
        return time.monotonic(), (cpu + queued) * 1e-9
    except (OSError, ValueError):
        return time.monotonic(), time.monotonic()  # unknown: never counts as waiting


def _encode_arg(a):
    if isinstance(a, State):
        return {
            "state": {"q": np.asarray(a.q, float).tolist(), "qdot": np.asarray(a.qdot, float).tolist(), "t": float(a.t)}
        }
    if isinstance(a, np.ndarray):
        return a.astype(float).tolist()
    if isinstance(a, (np.floating, np.integer)):
        return float(a)
    return a


def _decode(name: str, answer: dict, call: bool = False):
    if answer.get("missing"):
        raise StudentError(
            f"{name} is not defined in the notebook (its cell was deleted, renamed or failed, or never ran)"
        )
    altered = f"{name}: {ALTERED_ANSWER}"
    kind = answer.get("type")
    typed = isinstance(kind, str) and kind != ""  # the sandbox names a type as text, for every value not numbers
    if (kind is not None or answer.get("not_callable")) and not typed:
        raise StudentError(altered)
    if answer.get("not_callable"):
        raise StudentError(not_a_function_message(name, kind))
    if answer.get("timeout"):
        why = "used too much CPU time" if answer["timeout"] == "cpu" else "waited too long"
        raise StudentTimeout(f"{name} did not return: it {why}")
    if "raised" in answer:
        if not isinstance(answer["raised"], str):  # the sandbox writes an error as text
            raise StudentError(altered)
        raise StudentError(raised_text(name, answer["raised"]))
    if answer.get("none"):
        return None
    if answer.get("complex"):
        raise StudentError(complex_message(name))
    if "array" in answer:
        if "shape" not in answer:  # the sandbox sends every array with its shape
            raise StudentError(altered)
        try:
            return np.asarray(answer["array"], dtype=float).reshape(answer["shape"])
        except (TypeError, ValueError):
            raise StudentError(f"{name} returned something unreadable") from None
    if not typed:
        raise StudentError(altered)
    raise StudentError(f"{name} {'returned' if call else 'is'} a value of type {kind}, expected numbers")


# ---------------------------------------------------------------------------------------------
# one submission
# ---------------------------------------------------------------------------------------------


#: The words of :func:`other_problem_note` that the Canvas report looks for among a row's notes.
OTHER_PROBLEM_MARK = "(its metadata says so)"


def other_problem_note(text: bytes, problem: str | None) -> str | None:
    """A note when the notebook says it is another Problem's (the ``labsupport_grading`` metadata
    that the handed-out notebooks carry): a Problem 2 notebook graded with Problem 1's checks
    finds none of their functions, and its feedback alone would read as cells deleted or renamed.
    The notebook is graded all the same (its metadata is the student's to edit); None when it
    names no Problem or this one."""
    try:
        meta = json.loads(text.decode("utf-8")).get("metadata", {}).get("labsupport_grading", {})
        named = meta.get("problem") if isinstance(meta, dict) else None
    except (ValueError, AttributeError, RecursionError):
        return None
    well_formed = isinstance(named, str) and re.fullmatch(r"[A-Za-z0-9_]{1,40}", named)
    if problem is None or not well_formed or named == problem:
        return None  # no Problem named, this one, or a name no spec could have (never quoted)
    return (
        f"this notebook is {named}'s {OTHER_PROBLEM_MARK}, graded here with {problem}'s checks: either the "
        f"wrong notebook was handed in, or it was graded as the wrong Problem"
    )


#: How a student gets a file that opens as a notebook.
DOWNLOAD_AGAIN = "open the notebook in Jupyter or Colab, use File → Download → Download .ipynb, and hand in that file"

#: Each check's message for a file that could not be read as a notebook: the note below says why, once.
UNREADABLE = "no points: the file could not be read as a notebook; the note below says why"


def unreadable_row(names: list[str], reason: str) -> dict:
    """The row of a file that could not be read as a notebook: zero on every check of ``names``,
    each message pointing to the one note, ``reason``."""
    return {
        "status": "unreadable",
        "scores": dict.fromkeys(names, 0.0),
        "messages": dict.fromkeys(names, UNREADABLE),
        "notes": [reason],
    }


def _not_json(text: str, err: json.JSONDecodeError) -> str:
    """Why a file that is not JSON is no notebook: one cut short or edited by hand still starts
    with ``{``; one that does not was never a notebook (a ``.py`` file renamed, a web page)."""
    start = text.lstrip("\ufeff \t\r\n")
    if start.startswith("{"):
        where = f"{err.msg} at line {err.lineno}"
        return f"not a valid notebook: invalid JSON ({where}), cut short or edited; {DOWNLOAD_AGAIN}"
    if not start:
        return f"not a notebook: the file holds nothing but white space; {DOWNLOAD_AGAIN}"
    first = start.splitlines()[0][:60]
    return (
        f"not a notebook: a notebook (.ipynb) is JSON text that starts with {{, and this file starts with "
        f"{first!r} (a Python file renamed .ipynb, or a web page saved?); {DOWNLOAD_AGAIN}"
    )


def read_cells(text: bytes) -> list[tuple[int, str]]:
    """``(cell index, source)`` of every code cell; ValueError with a plain reason if unreadable.

    Reads the notebook format 4 (``cells``, each with a ``source``) and the older format 3 that
    Jupyter still opens (``worksheets`` of cells, a code cell's text in ``input``)."""
    try:
        decoded = text.decode("utf-8")
        nb = json.loads(decoded)
    except UnicodeDecodeError:
        raise ValueError(f"not a notebook: the file is not UTF-8 text; {DOWNLOAD_AGAIN}") from None
    except json.JSONDecodeError as err:
        raise ValueError(_not_json(decoded, err)) from None
    except RecursionError:
        raise ValueError("not a valid notebook: its JSON is nested too deeply") from None
    if isinstance(nb, dict) and nb.get("nbformat") == 3 and isinstance(nb.get("worksheets"), list):
        sheets = [w.get("cells") for w in nb["worksheets"] if isinstance(w, dict)]
        every, source_key = [c for cells in sheets if isinstance(cells, list) for c in cells], "input"
    elif isinstance(nb, dict) and isinstance(nb.get("cells"), list):
        every, source_key = nb["cells"], "source"
    else:
        raise ValueError("not a valid notebook: no list of cells")
    cells = []
    for k, cell in enumerate(every):
        if not isinstance(cell, dict) or cell.get("cell_type") != "code":
            continue
        src = cell.get(source_key, "")
        if isinstance(src, list):
            src = "".join(s for s in src if isinstance(s, str))
        if not isinstance(src, str):
            raise ValueError(f"not a valid notebook: cell {k} has no readable source")
        cells.append((k, src))
    return cells


#: The most code [characters] the grader parses in its own process for the instructor's leads
#: (the scan for code built at run time, the shared-code report), where no time or memory limit
#: charges it to the submission: a right answer is a few thousand characters, while 10 MB of code
#: takes Python's parser about 6 GB and 40 s.
MAX_CODE_CHARS = 200_000

#: Calls that run code given as data, as their modules name them: what they run is not in the
#: notebook's text (a code object loaded with ``marshal`` or built with ``types`` may be any
#: function's, carried from elsewhere).
_RUNS_DATA = frozenset(
    {
        "exec",
        "eval",
        "compile",
        "builtins.exec",
        "builtins.eval",
        "builtins.compile",
        "marshal.loads",
        "marshal.load",
        "pickle.loads",
        "pickle.load",
        "pickle.Unpickler",
        "_pickle.loads",
        "_pickle.load",
        "dill.loads",
        "dill.load",
        "cloudpickle.loads",
        "cloudpickle.load",
        "joblib.load",
        "types.CodeType",
        "types.FunctionType",
    }
)


def _imported_names(tree: ast.AST) -> dict[str, str]:
    """``{name in the code: what it names}`` for the code's imports (``import marshal as m``:
    ``m`` → ``marshal``; ``from marshal import loads as f``: ``f`` → ``marshal.loads``)."""
    names = {}
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            for alias in node.names:
                if alias.asname:
                    names[alias.asname] = alias.name
        elif isinstance(node, ast.ImportFrom) and node.module and not node.level:
            for alias in node.names:
                names[alias.asname or alias.name] = f"{node.module}.{alias.name}"
    return names


def code_built_at_run_time(cells: list[tuple[int, str]]) -> list[str]:
    """The cells (as :func:`_cell_named` names them) that run code they build while they run:
    ``exec``, ``eval`` or ``compile`` of anything but a written-out string, a code object loaded
    with ``marshal``, anything unpickled (``pickle``, ``dill``, ``cloudpickle``, ``joblib``: an
    unpickled object can be a function, and unpickling can call any function), or a code or
    function object built with ``types.CodeType`` or ``types.FunctionType``, under whatever name
    the notebook imported them (``from marshal import loads as f``). The shared-code report
    compares the code as written, so code decoded from a string (say
    ``exec(zlib.decompress(base64.b64decode(...)))``) is invisible to it: the instructor reads
    it. A lead, never a score."""
    trees = []
    for k, source in cells:
        code = "\n".join("" if line.lstrip().startswith(("%", "!")) else line for line in source.splitlines())
        try:
            trees.append((k, source, ast.parse(code)))
        except (SyntaxError, ValueError, RecursionError, MemoryError):
            continue
    imported = {}  # a name imported in one cell is used in the cells after it
    for _, _, tree in trees:
        imported |= _imported_names(tree)
    found = []
    for k, source, tree in trees:
        for node in ast.walk(tree):
            if not isinstance(node, ast.Call):
                continue
            func = node.func
            if isinstance(func, ast.Name):  # exec(...), loads(...) imported from marshal
                name = imported.get(func.id, func.id)
            elif isinstance(func, ast.Attribute) and isinstance(func.value, ast.Name):  # marshal.loads, m.loads
                name = f"{imported.get(func.value.id, func.value.id)}.{func.attr}"
            else:
                continue
            written_out = node.args and isinstance(node.args[0], ast.Constant) and isinstance(node.args[0].value, str)
            if name in _RUNS_DATA and not written_out:
                found.append(_cell_named(k, source))
                break
    return found


def run_time_code_note(cells: list[tuple[int, str]]) -> str | None:
    """The row's note on code built at run time (:func:`code_built_at_run_time`), or None; for a
    notebook with more than :data:`MAX_CODE_CHARS` of code, a note that it was not scanned."""
    size = sum(len(source) for _, source in cells)
    if size > MAX_CODE_CHARS:
        return (
            f"the notebook holds {size:,} characters of code, more than the {MAX_CODE_CHARS:,} the grader scans "
            "for code built while the notebook runs: the instructor reads it by hand"
        )
    built = code_built_at_run_time(cells)
    if not built:
        return None
    return (
        f"{', '.join(built[:3])} run{'s' if len(built) == 1 else ''} code built while the notebook runs "
        "(exec, eval or compile of a string it makes, or code it unpickles, loads or builds), which is not in "
        "the notebook's text: the instructor reads it by hand"
    )


def _cell_named(index: int, source: str) -> str:
    """A cell as a student finds it in Jupyter, which shows no cell numbers: its place among all
    cells (counted from 1) and its first line."""
    first = next((line.strip() for line in source.splitlines() if line.strip()), "")
    return f"cell {index + 1} ({first[:40] + ('…' if len(first) > 40 else '')!r})"


def _is_cell_error(entry) -> bool:
    """Whether ``entry`` of the first run's ``errors`` is what the sandbox writes: ``[cell, text]``."""
    return isinstance(entry, list) and [type(x) for x in entry] == [int, str]


def _listed(answer: dict, key: str) -> list:
    """``answer[key]`` if it is a list, else an empty one: an answer comes from the submission's
    process, which may have tampered with it."""
    value = answer.get(key) if isinstance(answer, dict) else None
    return value if isinstance(value, list) else []


#: The shape of an error as the sandbox reports it: an exception's name, then its message.
_ERROR_TEXT = re.compile(r"([A-Za-z_][A-Za-z0-9_.]*)(?:: (.*))?", re.DOTALL)


#: What the sandbox answers for a cell stopped at a limit, or left unrun after the cells used up
#: their time together: notes quote them as they are.
_LIMIT_TEXTS = frozenset(
    [timed_out(reason, in_all) for reason in ("cpu", "idle") for in_all in (False, True)]
    + [not_run(reason) for reason in ("cpu", "idle")]
)


def _error_note(text: str) -> str:
    """What a cell's error says in the notes, its message quoted: the message is the notebook's
    own text (and its process could rewrite the whole report), so no message can pass for a
    note of the grader's."""
    if text in _LIMIT_TEXTS:
        return text
    match = _ERROR_TEXT.fullmatch(text)
    if match is None:
        return f"reported an error in a form the sandbox never writes: {json.dumps(text[:200], ensure_ascii=False)}"
    name, message = match.groups()
    if name in ("SyntaxError", "IndentationError", "TabError") and message:
        # IPython names the cell <ipython-input-1-7158b2399f77>; the student knows it as the cell
        message = re.sub(r"\(<ipython-input-[^>]*>, line (\d+)\)", r"(line \1 of the cell)", message)
    note = f"raised {name}" + ("" if message is None else f": {json.dumps(message, ensure_ascii=False)}")
    missing = _MISSING_MODULE.fullmatch(message or "") if name == "ModuleNotFoundError" else None
    if missing and missing.group(1).split(".")[0] != "labsupport":
        note += f" ({MISSING_MODULE_ADVICE})"
    return note


#: ModuleNotFoundError's message, and the module it names.
_MISSING_MODULE = re.compile(r"No module named '([A-Za-z0-9_.]+)'")
#: What the notes add where a cell imported a module the grader's Python lacks (not one of
#: labsupport's, which the sandbox leaves out on purpose), for the instructor and the student
#: alike: the feedback file shows the notes too.
MISSING_MODULE_ADVICE = (
    "the grader's Python does not have this module, so the rest of that cell did not run; where the "
    "course allows the module (Colab preinstalls many), the grader can install it and grade the notebook again"
)


#: Said where a file listed sits in the sandbox's home: a notebook from Colab that wrote to
#: ``/content/notes.txt`` finds it listed as ``/home/student/notes.txt``, the same file.
HOME_IS_CONTENT = f"; {isolation.HOME} is the notebook's home folder, and Colab's /content is the same folder"


def _shown_path(path: str) -> str:
    """``path`` cut to about :data:`MAX_PATH_CHARS`: in the middle where its file name is short
    enough to keep whole (``/home/student/runs/…/results.csv``), else at the end."""
    if len(path) <= MAX_PATH_CHARS:
        return path
    name = path.rsplit("/", 1)[1]
    if len(name) <= MAX_PATH_CHARS // 2:
        return path[: MAX_PATH_CHARS - len(name) - 2] + "…/" + name
    return path[:MAX_PATH_CHARS] + "…"


def _paths(entries: list) -> list[str]:
    """The entries of a file list that are absolute paths, as the sandbox lists them, each quoted
    and cut by :func:`_shown_path` (a file's name is the notebook's own text: quoted, it cannot
    pass for a note of the grader's); anything else is never shown as a file."""
    return [json.dumps(_shown_path(p), ensure_ascii=False) for p in entries if isinstance(p, str) and p.startswith("/")]


def run_check(check, probe: Probe, seed: int) -> Result:
    """``check(probe, seed)`` (a check written before seeds existed takes only the probe)."""
    if len(inspect.signature(check).parameters) >= 2:
        return check(probe, seed)
    return check(probe)


def grade(
    spec: dict,
    notebook: bytes,
    seed: int,
    start,
    budget: Budget = DEFAULT_BUDGET,
    limits: isolation.Limits = isolation.DEFAULT_LIMITS,
) -> dict:
    """Grade one notebook (its bytes) with the checks of ``spec`` at ``seed``.

    ``start()`` returns ``(command, env, cwd)`` of a fresh sandbox server. Returns the row:
    status, scores (points), messages and notes.
    """
    from labsupport.grading import registry

    checks = registry()
    names = [c["name"] for c in spec["checks"]]
    points = {c["name"]: float(c["points"]) for c in spec["checks"]}
    try:
        cells = read_cells(notebook)
    except ValueError as err:
        return unreadable_row(names, str(err))

    command, env, cwd = start()
    probe = SandboxProbe(command, cells, budget, env=env, cwd=cwd, limits=limits)
    notes: list[str] = []
    if note := other_problem_note(notebook, spec.get("problem")):
        notes.append(note)
    if note := run_time_code_note(cells):
        notes.append(note)
    scores, messages, statuses, wrote_state = {}, {}, {}, {}
    try:
        try:
            probe.start()
        except StudentError as err:
            notes.append(str(err))
        if probe.first_run:
            for entry in _listed(probe.first_run, "errors")[:5]:
                if not _is_cell_error(entry):
                    continue  # not what the sandbox writes
                k, text = entry
                cell = _cell_named(*cells[k]) if 0 <= k < len(cells) else f"code cell {k + 1}"
                notes.append(f"{cell} {_error_note(text)}")
            patched = [p for p in _listed(probe.first_run, "patched") if isinstance(p, str)]
            if patched:
                notes.append(
                    "the notebook replaced "
                    + ", ".join(patched[:5])
                    + (" ..." if len(patched) > 5 else "")
                    + " (no effect on grading: the checks run in a separate process)"
                )
        for name in names:
            probe.begin_part(WHOLE, 1.0)
            probe.state_write = probe.argument_write = None
            try:
                if probe.start_problem is not None:  # the notebook itself never finished: nothing to check
                    raise StudentError(f"not graded: {probe.start_problem}")
                result = run_check(checks[name], probe, seed)
            except StudentError as err:
                result = failed(name, str(err))
            except WallClockExceeded:
                raise
            except Exception as err:  # a bug in a check must not lose the row
                result = Result(name, 0.0, "error", f"the grader could not run this check: {type(err).__name__}: {err}")
            result = noting_writes(result, probe)
            if probe.state_write is not None:
                wrote_state[name] = probe.state_write
            scores[name] = round(result.score * points[name], 4)
            messages[name] = result.message
            statuses[name] = result.status
        files = probe.files()
    except WallClockExceeded as err:
        return {
            "status": REGRADE,
            "scores": {},
            "messages": {},
            "notes": [
                f"{err}: the machine was too busy or the submission stalled; grade it again "
                "(with the same --seed) before recording a score"
            ],
        }
    finally:
        probe.stop()

    listed = _listed(files, "wrote")
    paths = _paths(listed)
    if paths:
        in_home = any(str(p).startswith(f"{isolation.HOME}/") for p in listed)
        notes.append(
            f"the notebook wrote files: {', '.join(paths[:5])}"
            + (" ..." if len(paths) > 5 else "")
            + " (in its private scratch space, removed after grading"
            + (HOME_IS_CONTENT if in_home else "")
            + ")"
        )
    for name in names:
        if statuses[name] == NOT_IMPLEMENTED:
            notes.append(f"{name}: not implemented yet")
        elif statuses[name] != PASS and probe.start_problem is None:
            notes.append(f"{name}: {messages[name]}")
        elif name in wrote_state:  # a passed check's note, in the grades table's reason too
            fname, changed = wrote_state[name]
            notes.append(f"{name}: passed, but {fname} changed {' and '.join(changed)} of the state it was handed")
    return {  # a check the grader itself could not run leaves the row unrecorded (grade it again or by hand)
        "status": "error" if "error" in statuses.values() else "graded",
        "scores": scores,
        "messages": messages,
        "notes": notes,
        "sandbox_cpu": round(probe.cpu_seen, 2),
    }
