"""Grade a folder of executed student notebooks: one CSV row per file, one feedback file per student.

Usage (from the repository root)::

    .venv/bin/python -m labsupport.instructor.batch --problem problem1 SUBMISSIONS --out grades/problem1

``--problem NAME`` reads the autograder spec ``tests/autograder/NAME.json`` (or give
``--spec PATH``). Every ``*.ipynb`` in SUBMISSIONS gets a row in ``OUT/grades.csv`` (a score
per check, the total, a status and a reason) and a ``OUT/feedback/<file>.txt``, whatever the
file does.

How a submission is isolated:

* its bytes are read once, up front, and copied into a scratch folder of its own, next to a
  fresh copy of labsupport; it runs there (:mod:`labsupport.instructor.sandbox`), never in the
  submissions folder;
* a judge process per submission (:mod:`labsupport.instructor.judge`) runs the checks with the
  grader's own copy of labsupport, restored from memory before each judge starts; the
  submission only ever hands back numbers;
* each judge has a time limit (the row then says so), and ``--jobs`` run at once;
* results are kept in memory and written at the end, atomically.

This isolates submissions from each other and from the grader against mistakes and ordinary
mischief; it is not a security boundary against a determined attacker running as your user
(grade untrusted work in a container or a throw-away account).
"""

from __future__ import annotations

import argparse
import csv
import io
import json
import os
import shutil
import signal
import subprocess
import sys
import tempfile
import threading
import time
from concurrent.futures import ThreadPoolExecutor
from importlib import resources
from pathlib import Path

_GRADER_LIB_LOCK = threading.Lock()

#: Where ``--problem NAME`` finds its spec, relative to the current directory (the repository root).
SPEC_DIR = Path("tests") / "autograder"


def package_snapshot() -> dict[str, bytes]:
    """Bytes of every file of the installed labsupport (models included), by path relative to the package."""
    import labsupport

    root = Path(labsupport.__file__).resolve().parent
    files = {}
    for p in sorted(root.rglob("*")):
        if p.is_file() and "__pycache__" not in p.parts and p.suffix != ".pyc":
            files[str(p.relative_to(root))] = p.read_bytes()
    if not any(k.startswith("models/") for k in files):  # editable install: models/ lives at the top
        models = resources.files("labsupport.models")
        with resources.as_file(models) as mdir:
            for p in sorted(Path(mdir).iterdir()):
                if p.is_file() and p.suffix in (".xml", ".py"):
                    files[f"models/{p.name}"] = p.read_bytes()
    return files


def write_package(snapshot: dict[str, bytes], lib: Path) -> None:
    """Make ``lib/labsupport`` exactly the snapshot (rewrite changed files, remove extra ones)."""
    root = lib / "labsupport"
    if root.exists():
        for p in sorted(root.rglob("*"), reverse=True):
            rel = str(p.relative_to(root))
            if p.is_symlink() or (p.is_file() and rel not in snapshot):
                p.unlink()
            elif p.is_dir() and not any(k.startswith(rel + "/") for k in snapshot):
                shutil.rmtree(p, ignore_errors=True)
    for rel, data in snapshot.items():
        p = root / rel
        p.parent.mkdir(parents=True, exist_ok=True)
        try:
            same = p.is_file() and not p.is_symlink() and p.read_bytes() == data
        except OSError:
            same = False
        if not same:
            if p.exists() or p.is_symlink():
                p.unlink()
            p.write_bytes(data)


def grade_one(index: int, name: str, data: bytes | None, read_error: str | None, spec_path: Path,
              snapshot: dict, grader_lib: Path, scratch_root: Path, timeout: float) -> dict:
    """Grade one submission in its own scratch folder and judge process; always returns a row."""
    if read_error is not None:
        return {"status": "unreadable", "scores": {}, "messages": {}, "notes": [read_error]}
    scratch = Path(tempfile.mkdtemp(prefix=f"s{index:04d}-", dir=scratch_root))
    work = scratch / "work"
    work.mkdir(parents=True)
    write_package(snapshot, scratch / "lib")
    (work / name).write_bytes(data)
    with _GRADER_LIB_LOCK:
        write_package(snapshot, grader_lib)  # undo anything an earlier submission managed to change
    env = {k: v for k, v in os.environ.items() if not k.startswith("PYTHON")}
    env.update(PYTHONPATH=str(grader_lib), PYTHONNOUSERSITE="1", PYTHONDONTWRITEBYTECODE="1",
               OMP_NUM_THREADS="1", OPENBLAS_NUM_THREADS="1", MKL_NUM_THREADS="1")
    cmd = [sys.executable, "-m", "labsupport.instructor.judge", "--spec", str(spec_path), "--workdir", str(work),
           "--notebook", name, "--lib", str(scratch / "lib"),
           "--run-timeout", str(max(10.0, 0.4 * timeout)), "--check-timeout", str(max(10.0, 0.15 * timeout))]
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, env=env, cwd=scratch,
                            start_new_session=True)
    try:
        out, err = proc.communicate(timeout=timeout)
    except subprocess.TimeoutExpired:
        _kill_group(proc)
        return {"status": "timed out", "scores": {}, "messages": {},
                "notes": [f"grading did not finish within {timeout:g} s"]}
    finally:
        _kill_group(proc)  # and whatever the submission left running in that session
    try:
        return json.loads(out.decode().strip().splitlines()[-1])
    except (ValueError, IndexError, UnicodeDecodeError):
        if proc.returncode is not None and proc.returncode < 0:
            return {"status": "error", "scores": {}, "messages": {},
                    "notes": [f"the grading process was killed (signal {-proc.returncode}); "
                              "the submission probably killed it"]}
        tail = err.decode(errors="replace").strip().splitlines()[-1:] or ["no output"]
        return {"status": "error", "scores": {}, "messages": {}, "notes": [f"the grader failed: {tail[0][:200]}"]}


def _kill_group(proc: subprocess.Popen) -> None:
    """Kill the judge's whole session: the judge and the sandbox it started."""
    for pid in _session_members(proc.pid):
        try:
            os.kill(pid, signal.SIGKILL)
        except (ProcessLookupError, PermissionError):
            pass
    try:
        os.killpg(proc.pid, signal.SIGKILL)
    except (ProcessLookupError, PermissionError):
        pass
    proc.wait()


def _session_members(sid: int) -> list[int]:
    """Processes of session ``sid`` (Linux ``/proc``; empty elsewhere)."""
    members = []
    for entry in Path("/proc").glob("[0-9]*/stat"):
        try:
            fields = entry.read_text().rsplit(")", 1)[1].split()
            if int(fields[3]) == sid:
                members.append(int(entry.parent.name))
        except (OSError, IndexError, ValueError):
            continue
    return members


def feedback_text(name: str, spec: dict, row: dict) -> str:
    """The feedback file of one student: total, then each check's score and message, then notes."""
    lines = [f"Feedback on {name} ({spec['problem']})", ""]
    total = sum(row["scores"].get(c["name"], 0.0) for c in spec["checks"])
    maximum = sum(float(c["points"]) for c in spec["checks"])
    lines.append(f"Score: {total:g} / {maximum:g}   (status: {row['status']})")
    lines.append("")
    for c in spec["checks"]:
        msg = row["messages"].get(c["name"], "not graded: " + "; ".join(row["notes"][:1]))
        lines.append(f"- {c['name']} ({row['scores'].get(c['name'], 0.0):g} / {float(c['points']):g}): {msg}")
    notes = [n for n in row["notes"] if not any(n.startswith(c["name"] + ":") for c in spec["checks"])]
    if notes:
        lines += ["", "Notes:"] + [f"- {n}" for n in notes]
    return "\n".join(lines) + "\n"


def run_batch(submissions: Path, spec_path: Path, out: Path, jobs: int | None = None,
              timeout: float = 240.0) -> list[dict]:
    """Grade every ``*.ipynb`` in ``submissions``; writes ``out/grades.csv`` and ``out/feedback/``."""
    spec_path = Path(spec_path).resolve()
    spec = json.loads(spec_path.read_text(encoding="utf-8"))
    if not Path(submissions).is_dir():
        raise ValueError(f"submissions must be a folder of .ipynb files; {submissions} is not a folder")
    files = sorted(p for p in Path(submissions).iterdir() if p.name.endswith(".ipynb"))
    payloads = []
    for p in files:  # read everything first: nothing a submission does later can lose another one
        try:
            payloads.append((p.name, p.read_bytes(), None))
        except OSError as err:
            payloads.append((p.name, None, f"could not read the file: {err.strerror}"))
    snapshot = package_snapshot()
    jobs = max(1, jobs or os.cpu_count() or 1)
    rows: list[dict] = [None] * len(payloads)
    start = time.monotonic()
    with tempfile.TemporaryDirectory(prefix="grading-") as tmp:
        tmp = Path(tmp)
        os.chmod(tmp, 0o700)
        grader_lib = tmp / "grader"
        scratch_root = tmp / "submissions"
        scratch_root.mkdir()
        write_package(snapshot, grader_lib)

        def task(i):
            name, data, read_error = payloads[i]
            t0 = time.monotonic()
            try:
                row = grade_one(i, _safe_name(name), data, read_error, spec_path, snapshot, grader_lib,
                                scratch_root, timeout)
            except Exception as err:  # the row must exist whatever happened
                row = {"status": "error", "scores": {}, "messages": {}, "notes": [f"the grader failed: {err}"]}
            row["file"], row["seconds"] = name, round(time.monotonic() - t0, 1)
            rows[i] = row
            print(f"graded {name}: {row['status']} in {row['seconds']:g} s", flush=True)

        with ThreadPoolExecutor(max_workers=jobs) as pool:
            list(pool.map(task, range(len(payloads))))
    elapsed = time.monotonic() - start
    _write_results(out, spec, rows)
    print(f"{len(rows)} submissions graded in {elapsed:.1f} s with {jobs} at once; see {out / 'grades.csv'}")
    return rows


def _safe_name(name: str) -> str:
    stem = "".join(c if c.isalnum() or c in "-_." else "_" for c in name)
    return stem if stem.endswith(".ipynb") else stem + ".ipynb"


def _write_results(out: Path, spec: dict, rows: list[dict]) -> None:
    names = [c["name"] for c in spec["checks"]]
    maximum = sum(float(c["points"]) for c in spec["checks"])
    buf = io.StringIO()
    writer = csv.writer(buf, lineterminator="\n")
    writer.writerow(["file", "problem", *names, "total", "max", "status", "reason"])
    for row in rows:
        scores = [row["scores"].get(n, 0.0) for n in names]
        reason = "; ".join(row["notes"]) if row["notes"] else "all checks passed"
        writer.writerow([row["file"], spec["problem"], *[f"{s:g}" for s in scores], f"{sum(scores):g}",
                         f"{maximum:g}", row["status"], reason])
    out = Path(out)
    (out / "feedback").mkdir(parents=True, exist_ok=True)
    _atomic_write(out / "grades.csv", buf.getvalue())
    for row in rows:
        _atomic_write(out / "feedback" / (Path(row["file"]).stem + ".txt"), feedback_text(row["file"], spec, row))


def _atomic_write(path: Path, text: str) -> None:
    tmp = path.with_name(path.name + ".tmp")
    tmp.write_text(text, encoding="utf-8")
    os.replace(tmp, path)


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description="Grade a folder of executed student notebooks into a CSV.")
    parser.add_argument("submissions", type=Path, help="folder holding the students' .ipynb files")
    which = parser.add_mutually_exclusive_group(required=True)
    which.add_argument("--problem", help="problem1 or problem2 (reads tests/autograder/NAME.json)")
    which.add_argument("--spec", type=Path, help="an autograder spec written by labsupport.instructor.assign")
    parser.add_argument("--out", type=Path, required=True, help="folder for grades.csv and feedback/")
    parser.add_argument("--jobs", type=int, default=None, help="submissions graded at once (default: CPU count)")
    parser.add_argument("--timeout", type=float, default=240.0, help="time limit per submission [s]")
    args = parser.parse_args(argv)
    spec = args.spec or SPEC_DIR / f"{args.problem}.json"
    if not Path(spec).is_file():
        parser.error(f"no autograder spec at {spec}: run from the repository root, or give --spec")
    try:
        run_batch(args.submissions, spec, args.out, args.jobs, args.timeout)
    except ValueError as err:
        parser.error(str(err))


if __name__ == "__main__":
    main()
