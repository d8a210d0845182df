"""Batch grading throughput: N copies of each master (plus a few hostile notebooks), both Problems,
extrapolated to a class of 200 on this machine.

    .venv/bin/python tests/benchmarks/bench_grading.py            # N = 6 copies per Problem
    .venv/bin/python tests/benchmarks/bench_grading.py --copies 20

For each Problem it prints the wall time of the batch, the CPU time of everything the batch
ran (judges and sandboxes), and the CPU seconds per submission; then the wall time a class of
200 would take for both Problems with ``--jobs`` equal to this machine's cores, from the
measured CPU per submission (the batch is CPU-bound) and from the measured wall time.
"""

from __future__ import annotations

import argparse
import os
import resource
import shutil
import tempfile
import time
from pathlib import Path

from labsupport.instructor.batch import run_batch

ROOT = Path(__file__).resolve().parents[2]
MASTERS = {"problem1": "problem1_reaching.ipynb", "problem2": "problem2_tracking.ipynb"}
#: Quick hostile notebooks (Problem 1) graded alongside, as a class would hand some in.
HOSTILE = ("raises.ipynb", "returns_nan.ipynb", "escapes.ipynb", "masters_via_interpreter.ipynb")
CLASS = 200


def children_cpu() -> float:
    usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    return usage.ru_utime + usage.ru_stime


def bench(problem: str, copies: int, jobs: int, tmp: Path) -> tuple[float, float, int]:
    """``(wall s, CPU s, submissions)`` of grading ``copies`` masters (and the hostile few for Problem 1)."""
    subs = tmp / f"subs-{problem}"
    subs.mkdir()
    for k in range(copies):
        shutil.copy(ROOT / "notebooks" / "masters" / MASTERS[problem], subs / f"master{k:03d}.ipynb")
    if problem == "problem1":
        for name in HOSTILE:
            shutil.copy(ROOT / "tests" / "hostile" / name, subs / name)
    cpu0, t0 = children_cpu(), time.perf_counter()
    rows = run_batch(subs, ROOT / "tests" / "autograder" / f"{problem}.json", tmp / f"out-{problem}", jobs=jobs)
    # the judges' CPU (pool workers, reaped) plus each sandbox's own, as it reported it
    wall = time.perf_counter() - t0
    cpu = children_cpu() - cpu0 + sum(r.get("sandbox_cpu", 0.0) for r in rows)
    full = sum(
        1
        for r in rows
        if r["file"].startswith("master") and r["status"] == "graded" and sum(r["scores"].values()) == 10
    )
    print(
        f"{problem}: {len(rows)} submissions ({full}/{copies} masters at full marks) in {wall:.1f} s wall, "
        f"{cpu:.1f} s CPU, {cpu / len(rows):.2f} CPU s per submission"
    )
    return wall, cpu, len(rows)


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--copies", type=int, default=6, help="copies of each master")
    args = parser.parse_args(argv)
    jobs = os.cpu_count() or 1
    with tempfile.TemporaryDirectory(prefix="bench-grading-") as tmp:
        results = {p: bench(p, args.copies, jobs, Path(tmp)) for p in MASTERS}
    cpu_per_student = sum(cpu / n for _, cpu, n in results.values())
    wall_per_student = sum(wall / n for wall, _, n in results.values())
    print(f"per student, both Problems: {cpu_per_student:.2f} CPU s, {wall_per_student:.2f} s wall with {jobs} jobs")
    print(
        f"class of {CLASS}, both Problems, {jobs} cores: {CLASS * cpu_per_student / jobs / 60:.1f} min from CPU "
        f"time, {CLASS * wall_per_student / 60:.1f} min from measured wall time (target: 20 min on 2 cores)"
    )


if __name__ == "__main__":
    main()
