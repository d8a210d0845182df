"""Benchmarks of the course: notebook execution times, then every ``bench_*.py`` beside this file.

Run from the repository root with the project's environment::

    .venv/bin/python tests/benchmarks/run.py            # all benchmarks
    .venv/bin/python tests/benchmarks/run.py --quick    # skip bench_book (the cold book build)

Each notebook is executed from a temporary directory outside the repository, as Colab would
run it. Each ``bench_*.py`` runs in its own process and prints its own figures.
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import nbformat
from nbclient import NotebookClient

HERE = Path(__file__).resolve().parent
ROOT = HERE.parents[1]


def time_notebook(path: Path, timeout: int = 600) -> float:
    """Wall-clock seconds to execute one notebook top to bottom in a fresh kernel."""
    nb = nbformat.read(str(path), as_version=4)
    with tempfile.TemporaryDirectory() as cwd:
        start = time.perf_counter()
        NotebookClient(nb, timeout=timeout, kernel_name="python3", resources={"metadata": {"path": cwd}}).execute()
        return time.perf_counter() - start


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="skip the book-build benchmark")
    args = parser.parse_args(argv)
    os.environ.setdefault("MUJOCO_GL", "egl")

    print(f"machine: {os.cpu_count()} cores, Python {sys.version.split()[0]}")
    print("\n== notebook execution (fresh kernel, temporary working directory) ==")
    total = 0.0
    for path in sorted((ROOT / "notebooks").glob("*.ipynb")):
        seconds = time_notebook(path)
        total += seconds
        print(f"{path.name:40s} {seconds:7.1f} s")
    print(f"{'all notebooks':40s} {total:7.1f} s")

    failed = 0
    for script in sorted(HERE.glob("bench_*.py")):
        if args.quick and script.name == "bench_book.py":
            continue
        print(f"\n== {script.name} ==", flush=True)
        failed |= subprocess.call([sys.executable, str(script)], cwd=ROOT) != 0
    return int(failed)


if __name__ == "__main__":
    sys.exit(main())
