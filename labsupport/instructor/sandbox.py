"""The process that runs one submission and answers the judge's calls into it.

Started by :mod:`labsupport.instructor.judge` as ``python -m labsupport.instructor.sandbox`` in the
submission's scratch folder, with its own copy of labsupport on ``PYTHONPATH``. It speaks JSON
lines on the pipes it was started with (requests on stdin, answers on stdout); before any
student code runs, those pipes are moved to private descriptors and the student's prints go to
``notebook.log``.

Requests (each carries a ``nonce`` echoed in the answer):

* ``{"op": "run", "cells": [...], "cell_timeout": s}``: run the code cells in order in one
  IPython shell; answers the errors of each cell and what the notebook changed in labsupport.
* ``{"op": "call", "name": f, "args": [...], "kwargs": {...}}``: call the student's function;
  ``{"state": {...}}`` arguments become ``(model, data)`` of the 3R arm at that state.
* ``{"op": "get", "name": v}``: the value of a variable.

Values travel as JSON (``{"none": true}``, ``{"array": [...], "shape": [...]}``,
``{"raised": "..."}`` ...): nothing the student returns is ever unpickled by the grader.
"""

from __future__ import annotations

import json
import os
import signal
import sys

#: Largest array the sandbox sends back.
MAX_ELEMENTS = 10_000


class CellTimeout(BaseException):
    """A cell or call ran past its time limit (BaseException: ``except Exception`` does not catch it)."""


def _alarm(signum, frame):
    raise CellTimeout()


def _encode(value):
    import numpy as np

    if value is None:
        return {"none": True}
    if isinstance(value, (str, bytes, dict)) or callable(value):
        return {"type": type(value).__name__}
    try:
        arr = np.asarray(value, dtype=float)
    except Exception:
        return {"type": type(value).__name__}
    if arr.size > MAX_ELEMENTS:
        return {"type": f"array of {arr.size} numbers (too large)"}
    return {"array": arr.ravel().tolist(), "shape": list(arr.shape)}  # NaN/inf travel as JSON NaN/Infinity


def _snapshot(prefixes=("labsupport", "mujoco", "numpy")):
    """Identity of every public attribute of the modules the grader relies on."""
    snap = {}
    for name, mod in list(sys.modules.items()):
        if mod is None or not name.split(".")[0] in prefixes or name.startswith("labsupport.instructor.sandbox"):
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


def main() -> None:
    # keep the pipes to the judge private, send everything the notebook prints to a log
    rpc_in = os.fdopen(os.dup(0), "r", encoding="utf-8")
    rpc_out = os.fdopen(os.dup(1), "w", encoding="utf-8")
    log = os.open("notebook.log", os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o600)
    devnull = os.open(os.devnull, os.O_RDONLY)
    os.dup2(devnull, 0)
    os.dup2(log, 1)
    os.dup2(log, 2)
    sys.stdin = open(os.devnull, encoding="utf-8")
    sys.stdout = os.fdopen(1, "w", buffering=1, encoding="utf-8", errors="replace")
    sys.stderr = sys.stdout
    os.environ["LABSUPPORT_GRADING_BATCH"] = "1"
    os.environ.setdefault("MPLBACKEND", "Agg")

    import labsupport  # noqa: F401  (chooses the GL backend before mujoco)
    import mujoco
    import numpy as np
    from IPython.core.interactiveshell import InteractiveShell

    from labsupport.plants import load_model

    model, _ = load_model("spatial_3r")
    shell = InteractiveShell.instance()
    signal.signal(signal.SIGALRM, _alarm)

    def expand(args):
        out = []
        for a in args:
            if isinstance(a, dict) and "state" in a:
                data = mujoco.MjData(model)
                data.qpos[:] = a["state"]["q"]
                data.qvel[:] = a["state"]["qdot"]
                data.time = a["state"]["t"]
                mujoco.mj_forward(model, data)
                out.extend((model, data))
            elif isinstance(a, list):
                out.append(np.asarray(a, dtype=float))
            else:
                out.append(a)
        return out

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
        if op == "run":
            before = _snapshot()
            errors = []
            for k, src in enumerate(req["cells"]):
                signal.alarm(int(req.get("cell_timeout", 60)))
                try:
                    result = shell.run_cell(src, store_history=False, silent=True)
                    err = result.error_in_exec or result.error_before_exec
                    if isinstance(err, CellTimeout):
                        errors.append([k, "timed out"])
                    elif err is not None:
                        errors.append([k, f"{type(err).__name__}: {str(err)[:200]}"])
                except CellTimeout:
                    errors.append([k, "timed out"])
                finally:
                    signal.alarm(0)
            changed = _changed(before, _snapshot())
            answer(nonce, {"errors": errors, "patched": changed[:20]})
        elif op in ("call", "get"):
            name = req.get("name", "")
            ns = shell.user_ns
            if name not in ns:
                answer(nonce, {"missing": True})
                continue
            signal.alarm(int(req.get("timeout", 10)))
            try:
                if op == "get":
                    value = ns[name]
                elif not callable(ns[name]):
                    answer(nonce, {"type": type(ns[name]).__name__, "not_callable": True})
                    continue
                else:
                    value = ns[name](*expand(req.get("args", [])), **req.get("kwargs", {}))
                payload = _encode(value)
            except CellTimeout:
                payload = {"timeout": True}
            except BaseException as err:  # the student's code may raise anything, SystemExit included
                payload = {"raised": f"{type(err).__name__}: {str(err)[:200]}"}
            finally:
                signal.alarm(0)
            answer(nonce, payload)


if __name__ == "__main__":
    main()
