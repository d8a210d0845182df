"""Grade one submission: run it in a sandbox process, then run the grader's own checks against it.

``python -m labsupport.instructor.judge --spec SPEC --workdir DIR --notebook NAME --lib LIB``
prints one JSON object (the row and the feedback) on stdout. The batch grader
(:mod:`labsupport.instructor.batch`) starts one judge per submission.

The checks run here, in a process the submission never touches: the sandbox
(:mod:`labsupport.instructor.sandbox`) only ever sends back plain numbers. Every simulation the
checks run uses this process's MuJoCo model and loop; the submission's code is called once per
control step, for its torque.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import os
import resource
import secrets
import select
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

from labsupport.grading.feedback import (NOT_IMPLEMENTED, PASS, Probe, Result, State, StudentError,
                                         StudentTimeout, failed)


class SandboxDied(StudentError):
    """The sandbox process ended (the notebook exited, crashed, or was stopped)."""


class SandboxProbe(Probe):
    """A :class:`Probe` whose calls go to a sandbox process that ran the submission's cells."""

    def __init__(self, workdir: Path, lib: Path, cells: list[tuple[int, str]], run_timeout: float = 120,
                 cell_timeout: float = 60, call_timeout: float = 10, max_starts: int = 3):
        self.workdir, self.lib, self.cells = Path(workdir), Path(lib), cells
        self.run_timeout, self.call_timeout = run_timeout, call_timeout
        self.cell_timeout = min(cell_timeout, max(1.0, run_timeout / 2))  # one hung cell leaves time for the rest
        self.max_starts = max_starts
        self.proc: subprocess.Popen | None = None
        self.starts = 0
        self.deadline = float("inf")  # set by the judge for each check
        self.first_run: dict | None = None
        self.start_problem: str | None = None

    # -- process ---------------------------------------------------------------------------------
    def _env(self) -> dict:
        scratch = self.workdir.parent
        env = {k: v for k, v in os.environ.items() if k in ("PATH", "LANG", "LC_ALL", "MUJOCO_GL", "SYSTEMROOT")}
        for sub in ("home", "tmp"):
            (scratch / sub).mkdir(exist_ok=True)
        env.update(PYTHONPATH=str(self.lib), PYTHONNOUSERSITE="1", PYTHONDONTWRITEBYTECODE="1",
                   HOME=str(scratch / "home"), TMPDIR=str(scratch / "tmp"), MPLBACKEND="Agg",
                   MPLCONFIGDIR=str(scratch / "home"), IPYTHONDIR=str(scratch / "home" / ".ipython"),
                   OMP_NUM_THREADS="1", OPENBLAS_NUM_THREADS="1", MKL_NUM_THREADS="1")
        return env

    def start(self) -> None:
        """Start a sandbox and run the notebook's cells in it."""
        if self.starts >= self.max_starts:
            raise SandboxDied(f"skipped: the submission's process had to be stopped {self.starts} times")
        self.stop()
        self.starts += 1
        cpu = int(self.run_timeout + 600)

        def limits():
            os.setpgid(0, 0)  # its own group (stopped as one), inside the judge's session
            resource.setrlimit(resource.RLIMIT_FSIZE, (64 << 20, 64 << 20))  # no file over 64 MB
            resource.setrlimit(resource.RLIMIT_CPU, (cpu, cpu))
            resource.setrlimit(resource.RLIMIT_CORE, (0, 0))

        self.proc = subprocess.Popen([sys.executable, "-m", "labsupport.instructor.sandbox"], cwd=self.workdir,
                                     stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=subprocess.DEVNULL,
                                     env=self._env(), preexec_fn=limits)
        try:
            answer = self._request({"op": "run", "cells": [src for _, src in self.cells],
                                    "cell_timeout": self.cell_timeout}, self.run_timeout, check_deadline=False)
        except StudentTimeout:
            self.start_problem = f"the notebook's cells did not finish within {self.run_timeout:g} s"
            raise StudentTimeout(self.start_problem) from None
        except SandboxDied:
            self.start_problem = "the notebook ended the grading process while its cells ran (exit, crash or kill)"
            raise SandboxDied(self.start_problem) from None
        if self.first_run is None:
            self.first_run = answer

    def stop(self) -> None:
        if self.proc is not None and self.proc.poll() is None:
            try:
                os.killpg(self.proc.pid, signal.SIGKILL)
            except (ProcessLookupError, PermissionError):
                pass
            self.proc.wait()
        self.proc = None

    def _request(self, payload: dict, timeout: float, check_deadline: bool = True) -> dict:
        nonce = secrets.token_hex(8)
        payload["nonce"] = nonce
        try:
            self.proc.stdin.write((json.dumps(payload) + "\n").encode())
            self.proc.stdin.flush()
        except (BrokenPipeError, OSError):
            self.stop()
            raise SandboxDied("the submission's process has ended") from None
        end = time.monotonic() + timeout
        if check_deadline:
            end = min(end, self.deadline)
        fd = self.proc.stdout
        while True:
            left = end - time.monotonic()
            if left <= 0 or not select.select([fd], [], [], left)[0]:
                self.stop()
                if check_deadline and time.monotonic() >= self.deadline:
                    raise StudentTimeout("the check ran out of time (the submission's code is too slow or hangs)")
                raise StudentTimeout(f"no answer within {timeout:g} s")
            line = fd.readline()
            if not line:
                self.stop()
                raise SandboxDied("the submission's process ended")
            try:
                answer = json.loads(line)
            except ValueError:
                continue  # not ours
            if isinstance(answer, dict) and answer.get("nonce") == nonce:
                return answer

    def _ensure(self) -> None:
        if self.proc is None or self.proc.poll() is not None:
            if self.start_problem is not None:
                raise StudentError(f"skipped: {self.start_problem}")
            self.start()

    # -- Probe -----------------------------------------------------------------------------------
    def _ask(self, payload: dict, name: str) -> dict:
        self._ensure()
        try:
            return self._request(payload, self.call_timeout)
        except StudentTimeout as err:
            raise StudentTimeout(f"{name} did not return: {err}") from None

    def call(self, fname: str, *args, **kwargs):
        payload = {"op": "call", "name": fname, "args": [_encode_arg(a) for a in args],
                   "kwargs": {k: _encode_arg(v) for k, v in kwargs.items()}, "timeout": self.call_timeout}
        return _decode(fname, self._ask(payload, fname), call=True)

    def get(self, name: str):
        return _decode(name, self._ask({"op": "get", "name": name, "timeout": self.call_timeout}, name))


def _encode_arg(a):
    if isinstance(a, State):
        return {"state": {"q": np.asarray(a.q, float).tolist(), "qdot": np.asarray(a.qdot, float).tolist(),
                          "t": float(a.t)}}
    if isinstance(a, np.ndarray):
        return a.astype(float).tolist()
    if isinstance(a, (np.floating, np.integer)):
        return float(a)
    return a


def _decode(name: str, answer: dict, call: bool = False):
    if answer.get("missing"):
        raise StudentError(f"{name} is not defined in the notebook (its cell was deleted, renamed or failed)")
    if answer.get("not_callable"):
        raise StudentError(f"{name} should be a function, but it is a {answer.get('type')}")
    if answer.get("timeout"):
        raise StudentTimeout(f"{name} did not return within the time limit")
    if "raised" in answer:
        raise StudentError(f"{name} raised {answer['raised']}")
    if answer.get("none"):
        return None
    if "array" in answer:
        try:
            return np.asarray(answer["array"], dtype=float).reshape(answer["shape"])
        except (TypeError, ValueError):
            raise StudentError(f"{name} returned something unreadable") from None
    what = "returned" if call else "is"
    raise StudentError(f"{name} {what} a {answer.get('type', 'value')}, expected numbers")


# ---------------------------------------------------------------------------------------------
# one submission
# ---------------------------------------------------------------------------------------------

def read_cells(path: Path) -> list[tuple[int, str]]:
    """``(cell index, source)`` of every code cell; ValueError with a plain reason if unreadable."""
    try:
        nb = json.loads(path.read_text(encoding="utf-8"))
    except UnicodeDecodeError:
        raise ValueError("not a notebook: the file is not UTF-8 text") from None
    except json.JSONDecodeError as err:
        raise ValueError(f"not a valid notebook: invalid JSON ({err.msg} at line {err.lineno})") from None
    if not isinstance(nb, dict) or not isinstance(nb.get("cells"), list):
        raise ValueError("not a valid notebook: no list of cells")
    cells = []
    for k, cell in enumerate(nb["cells"]):
        if not isinstance(cell, dict) or cell.get("cell_type") != "code":
            continue
        src = cell.get("source", "")
        if isinstance(src, list):
            src = "".join(s for s in src if isinstance(s, str))
        if not isinstance(src, str):
            raise ValueError(f"not a valid notebook: cell {k} has no readable source")
        cells.append((k, src))
    return cells


def _listing(folder: Path) -> dict[str, str]:
    out = {}
    for p in sorted(folder.rglob("*")):
        if p.is_file() and not p.is_symlink() and "__pycache__" not in p.parts:
            try:
                out[str(p.relative_to(folder))] = hashlib.sha256(p.read_bytes()).hexdigest()
            except OSError:
                out[str(p.relative_to(folder))] = "?"
    return out


def grade(spec: dict, workdir: Path, notebook: str, lib: Path, check_timeout: float = 90,
          run_timeout: float = 120) -> dict:
    """Grade ``workdir/notebook``; returns scores (points), messages and notes."""
    from labsupport.grading import registry

    checks = registry()
    names = [c["name"] for c in spec["checks"]]
    points = {c["name"]: float(c["points"]) for c in spec["checks"]}
    zero = {n: 0.0 for n in names}
    try:
        cells = read_cells(workdir / notebook)
    except (ValueError, OSError) as err:
        return {"status": "unreadable", "scores": zero, "messages": {n: str(err) for n in names},
                "notes": [str(err)]}

    before_files, before_lib = _listing(workdir), _listing(lib)
    probe = SandboxProbe(workdir, lib, cells, run_timeout=run_timeout)
    notes: list[str] = []
    try:
        probe.start()
    except StudentError as err:
        notes.append(str(err))
    if probe.first_run:
        for k, text in probe.first_run.get("errors", [])[:5]:
            cell_index = cells[k][0] if 0 <= k < len(cells) else k
            notes.append(f"cell {cell_index} {'timed out' if text == 'timed out' else 'raised ' + text}")
        patched = probe.first_run.get("patched", [])
        if patched:
            notes.append("the notebook replaced " + ", ".join(patched[:5]) + (" ..." if len(patched) > 5 else "")
                         + " (no effect on grading: the checks run in a separate process)")

    scores, messages, statuses = {}, {}, {}
    for name in names:
        probe.deadline = time.monotonic() + check_timeout
        try:
            if probe.start_problem is not None:  # the notebook itself never finished: nothing to check
                raise StudentError(f"not graded: {probe.start_problem}")
            result = checks[name](probe)
        except StudentError as err:
            result = failed(name, str(err))
        except Exception as err:  # a bug in a check must not lose the row
            result = Result(name, 0.0, "error", f"the grader could not run this check: {type(err).__name__}: {err}")
        scores[name] = round(result.score * points[name], 4)
        messages[name] = result.message
        statuses[name] = result.status
    probe.stop()

    after_files = _listing(workdir)
    wrote = [f for f in after_files if f not in before_files and f != "notebook.log"]
    changed = [f for f in after_files if f in before_files and after_files[f] != before_files[f]]
    deleted = [f for f in before_files if f not in after_files]
    for label, files in (("wrote", wrote), ("changed", changed), ("deleted", deleted)):
        if files:
            notes.append(f"the notebook {label} files: {', '.join(files[:5])}" + (" ..." if len(files) > 5 else "")
                         + " (in its scratch copy; ignored)")
    if _listing(lib) != before_lib:
        notes.append("the notebook modified its copy of labsupport's files (ignored: the grader uses its own)")
    for name in names:
        if statuses[name] == NOT_IMPLEMENTED:
            notes.append(f"{name}: not implemented yet")
        elif statuses[name] != PASS and probe.start_problem is None:
            notes.append(f"{name}: {messages[name]}")
    return {"status": "graded", "scores": scores, "messages": messages, "notes": notes}


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--spec", required=True, type=Path)
    parser.add_argument("--workdir", required=True, type=Path)
    parser.add_argument("--notebook", required=True)
    parser.add_argument("--lib", required=True, type=Path)
    parser.add_argument("--check-timeout", type=float, default=90)
    parser.add_argument("--run-timeout", type=float, default=120)
    args = parser.parse_args(argv)
    spec = json.loads(args.spec.read_text(encoding="utf-8"))
    out = grade(spec, args.workdir, args.notebook, args.lib, args.check_timeout, args.run_timeout)
    sys.stdout.write(json.dumps(out) + "\n")


if __name__ == "__main__":
    main()
