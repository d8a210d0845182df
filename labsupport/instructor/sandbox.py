"""The server that runs one submission's cells inside its sandbox and answers the judge's calls.

:mod:`labsupport.instructor.isolation` copies this file into the sandbox and starts it there
(it imports nothing of labsupport.instructor, which the sandbox does not have). It speaks JSON
lines on the pipes it was started with (requests on stdin, answers on stdout); before any
student code runs, those pipes move to private descriptors and whatever the notebook prints
goes nowhere.

Requests (each carries a ``nonce`` echoed in the answer):

* ``{"op": "run", "cells": [...], "cell_cpu": s, "idle": s, "run_cpu": s, "run_idle": s}``: run
  the code cells in order in one IPython shell, each within ``cell_cpu`` and ``idle``, all of
  them within ``run_cpu`` (counted from the sandbox's start, as the judge counts it) and
  ``run_idle``: a cell that uses up what is left of those stops, and
  the cells after it do not run (the functions defined before are still graded); answers each
  cell's error and what the notebook replaced in the modules the checks rely on.
* ``{"op": "call", "name": f, "args": [...], "kwargs": {...}, "cpu": s, "idle": s}``: call the
  student's function; a ``{"state": {...}}`` argument becomes ``(model, data)`` of the 3R arm at
  that state.
* ``{"op": "get", "name": v}``: the value of a variable.
* ``{"op": "files"}``: the files the notebook wrote in its scratch space, new or altered since
  the server started (the sandbox's scratch starts empty; run without one, ``/dev/shm`` may not).

Limits count the process's own CPU time (``ITIMER_PROF``) and the time it spends waiting
without being runnable (wall time minus CPU time minus time spent queued for a CPU, from
``/proc/self/schedstat``): neither depends on how busy the machine is. The judge counts a
check's CPU budget from ``/proc`` itself, never from a figure this process could report: the
student's code runs in it and could change that figure. Values travel
as JSON (``{"none": true}``, ``{"array": [...], "shape": [...]}``, ``{"raised": "..."}``):
nothing the student returns is ever unpickled by the grader.
"""

from __future__ import annotations

import functools
import hashlib
import importlib.abc
import importlib.machinery
import json
import os
import signal
import sys
import threading
import time
import types

#: Largest array the sandbox sends back.
MAX_ELEMENTS = 10_000
#: The most file names each list of the ``files`` answer holds (the notes show five).
MAX_LISTED = 20
#: Files MuJoCo itself writes (its warning log): never the notebook's doing.
LIBRARY_FILES = ("MUJOCO_LOG.TXT",)

process_time = time.process_time  # the notebook may replace time.process_time; not this one


def timed_out(reason: str, in_all: bool = False) -> str:
    """What the run answers for a cell stopped at a limit: ``reason`` is ``"cpu"`` or ``"idle"``;
    ``in_all`` when the limit was what the cells together had left (the judge knows these texts)."""
    return f"timed out ({reason}{' of all cells together' if in_all else ''})"


def not_run(reason: str) -> str:
    """What the run answers for the first cell it leaves unrun, the cells together having used up
    their ``reason`` (``"cpu"`` or ``"idle"``) time."""
    return f"not run, nor any cell after it (the cells had used up their {reason} time together)"


class CellTimeout(BaseException):
    """A cell or call ran past its limit (BaseException: ``except Exception`` does not catch it)."""


class Watch:
    """CPU-time and waiting-time limits of the request in progress."""

    def __init__(self):
        self.idle_limit = None
        self.start = None
        self.cpu0 = 0.0
        self.reason = ""

    @staticmethod
    def running_and_queued() -> float:
        """CPU time plus time spent waiting for a CPU [s] (``/proc/self/schedstat``)."""
        try:
            with open("/proc/self/schedstat") as f:
                cpu, queued = f.read().split()[:2]
            return (int(cpu) + int(queued)) * 1e-9
        except (OSError, ValueError):
            return process_time()

    def idle(self) -> float:
        """Time spent waiting since :meth:`arm` [s]."""
        wall0, busy0 = self.start
        return (time.monotonic() - wall0) - (self.running_and_queued() - busy0)

    def cpu(self) -> float:
        """CPU time used since :meth:`arm` [s]."""
        return process_time() - self.cpu0

    def arm(self, cpu: float, idle: float) -> None:
        self.idle_limit = idle
        self.cpu0 = process_time()
        self.start = (time.monotonic(), self.running_and_queued())
        signal.setitimer(signal.ITIMER_PROF, max(cpu, 0.01))
        signal.setitimer(signal.ITIMER_REAL, 0.5, 0.5)

    def disarm(self) -> None:
        signal.setitimer(signal.ITIMER_PROF, 0)
        signal.setitimer(signal.ITIMER_REAL, 0)
        self.idle_limit = None

    def on_cpu(self, signum, frame):
        self.reason = "cpu"
        raise CellTimeout()

    def on_tick(self, signum, frame):
        if self.idle_limit is not None and self.idle() > self.idle_limit:
            self.reason = "idle"
            raise CellTimeout()


def _error_text(err: BaseException, limit: int = 300) -> str:
    """An error as the sandbox reports it: its type's name, then its message cut to ``limit``. A
    syntax error of a private kind is named SyntaxError (Python 3.13 raises its subclass
    ``_IncompleteInputError`` for a cell that ends mid-statement)."""
    name = type(err).__name__
    if isinstance(err, SyntaxError) and name.startswith("_"):
        name = "SyntaxError"
    return f"{name}: {str(err).rstrip()[:limit]}"


class ThreadErrors:
    """Errors that ended threads a call started (``threading.excepthook``). A stub's
    off-limits message raised in a worker thread explains the call's failure better than the
    error the call then met (a result the thread never stored)."""

    def __init__(self, marker: str):
        self.marker = marker  # the words every off-limits message carries
        self.errors: list[str] = []

    def hook(self, args) -> None:
        self.errors.append(_error_text(args.exc_value))

    def instead_of(self, payload: dict) -> dict:
        """``payload``, or the first off-limits error a thread of the call raised."""
        for text in self.errors:
            if self.marker in text:
                return {"raised": text}
        return payload

    def clear(self) -> None:
        self.errors.clear()


def _encode(value):
    import numpy as np

    if value is None:
        return {"none": True}
    if isinstance(value, (str, bytes, dict)) or callable(value):
        return {"type": type(value).__name__}
    try:
        if np.iscomplexobj(value):
            return {"complex": True}
        arr = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        return {"type": type(value).__name__}
    except Exception as err:  # the object's own __array__ or __float__ failed: say how
        return {"raised": _error_text(err)}
    if arr.size > MAX_ELEMENTS:
        return {"type": f"array of {arr.size} numbers (too large)"}
    return {"array": arr.ravel().tolist(), "shape": list(arr.shape)}  # NaN/inf travel as JSON NaN/Infinity


def _encoded_call(fn, args: list, kwargs: dict):
    """``fn(*args, **kwargs)``, as the answer carries it (:func:`_encode`): reading the value as
    numbers may run code of the student's too (an ``__array__``)."""
    return _encode(fn(*args, **kwargs))


def _snapshot(prefixes=("labsupport", "mujoco", "numpy")):
    """Identity of every public attribute of the modules the grader relies on."""
    snap = {}
    for name, mod in list(sys.modules.items()):
        if mod is None or name.split(".")[0] not in prefixes:
            continue
        try:
            snap[name] = {k: id(v) for k, v in vars(mod).items() if not k.startswith("_")}
        except TypeError:
            continue
    return snap


def _changed(before, after):
    out = []
    for name, attrs in before.items():
        new = after.get(name, {})
        for k, ident in attrs.items():
            if new.get(k, None) != ident:
                out.append(f"{name}.{k}")
    return sorted(out)


def _listing(folders) -> dict[str, str]:
    """``{path: sha256}`` of the files under ``folders`` (MuJoCo's own log left out)."""
    out = {}
    for folder in folders:
        for base, dirs, files in os.walk(folder):
            dirs[:] = [d for d in dirs if d not in ("__pycache__", ".config", ".cache", ".ipython")]
            for name in files:
                path = os.path.join(base, name)
                if name in LIBRARY_FILES or os.path.islink(path):
                    continue
                try:
                    with open(path, "rb") as f:
                        out[path] = hashlib.sha256(f.read(1 << 20)).hexdigest()
                except OSError:
                    out[path] = "?"
    return out


class Nothing:
    """A stand-in for anything: each of its attributes, and what a call of it returns, is itself."""

    def __call__(self, *args, **kwargs):
        return self

    def __getattr__(self, name: str):
        if name.startswith("__"):
            raise AttributeError(name)
        return self


NOTHING = Nothing()


class ColabStandIn(importlib.abc.MetaPathFinder, importlib.abc.Loader):
    """Google Colab's own modules, which the sandbox does not have: ``google.colab`` and every
    module under it import as a module whose every attribute is :data:`NOTHING`. A notebook from
    Colab that mounts its Drive, downloads a file or turns on a widget manager runs on, where the
    import raised and the rest of its cell (often the imports) never ran. Found last on
    :data:`sys.meta_path`, so a real ``google`` or ``google.colab`` is used where there is one."""

    PACKAGE = "google.colab"

    def find_spec(self, fullname, path=None, target=None):
        if fullname in ("google", self.PACKAGE) or fullname.startswith(self.PACKAGE + "."):
            return importlib.machinery.ModuleSpec(fullname, self, is_package=True)
        return None

    def create_module(self, spec):
        module = types.ModuleType(spec.name)
        module.__getattr__ = NOTHING.__getattr__  # a module's own __getattr__ (PEP 562)
        module.__path__ = []
        return module

    def exec_module(self, module):
        pass


def run_cells(cells, run_cell, watch: Watch, per_cell: dict, left: dict) -> list:
    """Run ``cells`` in order with ``run_cell`` (IPython's), each within ``per_cell`` seconds of
    CPU and waiting time (``{"cpu": s, "idle": s}``), and all of them within ``left``, which they
    spend as they run. A cell that meets what the cells had left is stopped "of all cells
    together", and the cells after it do not run. Returns the errors, ``[[cell, text], ...]``."""
    errors = []
    for k, src in enumerate(cells):
        used_up = [reason for reason, seconds in left.items() if seconds <= 0]
        if used_up:
            errors.append([k, not_run(used_up[0])])
            break
        limit = {reason: min(per_cell[reason], left[reason]) for reason in left}
        in_all = {reason: limit[reason] < per_cell[reason] for reason in limit}  # which limit binds
        stopped = None
        try:
            watch.arm(limit["cpu"], limit["idle"])
            result = run_cell(src)
            watch.disarm()
            err = result.error_in_exec or result.error_before_exec
            if isinstance(err, CellTimeout):
                stopped = watch.reason
            elif err is not None:
                errors.append([k, _error_text(err, 200)])
        except CellTimeout:
            stopped = watch.reason
        finally:
            watch.disarm()
            left["cpu"] -= watch.cpu()
            left["idle"] -= watch.idle()
        if stopped is not None:
            of_all_cells = in_all.get(stopped, False)
            errors.append([k, timed_out(stopped, of_all_cells)])
            if of_all_cells:  # the kernel's CPU timer and this clock may differ by a tick;
                left[stopped] = 0  # the cells' common limit is spent all the same
    return errors


def main() -> None:
    # keep the pipes to the judge private; whatever the notebook prints goes nowhere
    rpc_in = os.fdopen(os.dup(0), "r", encoding="utf-8")
    rpc_out = os.fdopen(os.dup(1), "w", encoding="utf-8")
    devnull = os.open(os.devnull, os.O_RDWR)
    for fd in (0, 1, 2):
        os.dup2(devnull, fd)
    sys.stdin = open(os.devnull, encoding="utf-8")
    sys.stdout = sys.stderr = open(os.devnull, "w", encoding="utf-8")
    scratch = (os.getcwd(), os.environ.get("TMPDIR", "/tmp"), "/dev/shm")
    files_before = _listing(scratch)

    import labsupport  # noqa: F401, I001  (chooses the GL backend before mujoco)
    import mujoco
    import numpy as np
    from IPython.core.interactiveshell import InteractiveShell

    from labsupport.grading.feedback import arguments_written, fields_written, forbidden_use_text, where_raised
    from labsupport.grading.rules import MARKER, ForbiddenUse, call_watched, forbidden_message
    from labsupport.plants import load_model

    model, _ = load_model("spatial_3r")
    data = mujoco.MjData(model)
    shell = InteractiveShell.instance()
    run_cell = functools.partial(shell.run_cell, store_history=False, silent=True)
    # A plotting backend is the notebook's display, which is never graded: %matplotlib (inline,
    # widget, any other) and %pylab keep the sandbox's Agg. A plain IPython shell has no GUI loop
    # and raised at `%matplotlib inline`, so the rest of its cell (often the imports) never ran.
    shell.enable_gui = lambda gui=None: None
    shell.enable_matplotlib = lambda gui=None: (gui, "agg")
    sys.meta_path.append(ColabStandIn())
    shell.magics_manager.register_alias("shell", "sh", "cell")  # Colab's %%shell: IPython's %%sh
    # The notebook's own folder comes first on the path, as in a Jupyter kernel: a module that a
    # cell writes there (%%writefile my_law.py) imports, where it raised ModuleNotFoundError.
    sys.path.insert(0, "")
    watch = Watch()
    thread_errors = ThreadErrors(MARKER)
    threading.excepthook = thread_errors.hook
    signal.signal(signal.SIGPROF, watch.on_cpu)
    signal.signal(signal.SIGALRM, watch.on_tick)

    handed = []  # the state handed to the last call, as set (all states share one data), to see it changed
    given = []  # the arrays handed to the last call, with their positions and copies, to see them changed

    def expand(args):
        out = []
        handed.clear()
        given.clear()
        for a in args:
            if isinstance(a, dict) and "state" in a:
                mujoco.mj_resetData(model, data)
                data.qpos[:] = a["state"]["q"]
                data.qvel[:] = a["state"]["qdot"]
                data.time = a["state"]["t"]
                mujoco.mj_forward(model, data)
                out.extend((model, data))
                handed[:] = [(data.qpos.copy(), data.qvel.copy())]
            elif isinstance(a, list):
                given.append((len(out), np.asarray(a, dtype=float)))
                out.append(given[-1][1].copy())
            else:
                out.append(a)
        return out

    def refusal(reason: str) -> dict:
        """A forbidden use the watch saw, answered as a stub's refusal (a RuntimeError with the
        rule's reason), which the checks read the same way."""
        return {"raised": f"RuntimeError: {reason}"}

    def answer(nonce, payload):
        payload["nonce"] = nonce
        rpc_out.write(json.dumps(payload) + "\n")
        rpc_out.flush()

    for line in rpc_in:
        try:
            req = json.loads(line)
        except ValueError:
            continue
        nonce, op = req.get("nonce"), req.get("op")
        idle = float(req.get("idle", 30))
        if op == "run":
            before = _snapshot()
            per_cell = {"cpu": float(req.get("cell_cpu", 60)), "idle": idle}
            # CPU time counted from the process's start, imports included, as the judge counts it
            left = {"cpu": float(req.get("run_cpu", "inf")) - process_time(), "idle": float(req.get("run_idle", "inf"))}
            errors = run_cells(req["cells"], run_cell, watch, per_cell, left)
            changed = _changed(before, _snapshot())
            answer(nonce, {"errors": errors, "patched": changed[:20]})
        elif op in ("call", "get"):
            name = req.get("name", "")
            ns = shell.user_ns
            if name not in ns:
                answer(nonce, {"missing": True})
                continue
            try:
                watch.arm(float(req.get("cpu", 10)), idle)
                if op == "get":
                    payload = _encode(ns[name])  # under the watch: reading the value may run its code
                elif not callable(ns[name]):
                    watch.disarm()
                    answer(nonce, {"type": type(ns[name]).__name__, "not_callable": True})
                    continue
                else:  # the call watched as in the notebook (rules.call_watched)
                    args = expand(req.get("args", []))
                    payload, used = call_watched(_encoded_call, ns[name], args, req.get("kwargs", {}))
                    if used is not None:
                        payload = refusal(forbidden_message(used))
                watch.disarm()
                if op == "call" and handed and (changed := fields_written(data, *handed[0])):
                    payload["state_written"] = changed
                if op == "call" and not handed and (changed := arguments_written(ns[name], given, args)):
                    payload["arguments_written"] = changed
                if "raised" in payload or "type" in payload:
                    payload = thread_errors.instead_of(payload)
            except CellTimeout:
                payload = {"timeout": watch.reason}
            except ForbiddenUse as err:
                payload = refusal(forbidden_use_text(err))
            except BaseException as err:  # the student's code may raise anything, SystemExit included
                payload = thread_errors.instead_of({"raised": _error_text(err) + where_raised(err)})
            finally:
                watch.disarm()
                thread_errors.clear()
            answer(nonce, payload)
        elif op == "files":
            after = _listing(scratch)
            wrote = [f for f, digest in after.items() if files_before.get(f) != digest]  # new or altered
            answer(nonce, {"wrote": sorted(wrote)[:MAX_LISTED]})


if __name__ == "__main__":
    if sys.argv[1:] or sys.stdin.isatty():  # a person, not the judge, which starts it on pipes
        sys.exit(
            "labsupport.instructor.sandbox is the server the batch grader starts in each submission's sandbox, "
            "not a command: to grade, run python -m labsupport.instructor.batch --help (or ...canvas --help)"
        )
    main()
