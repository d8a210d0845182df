"""The shared-code report at the size of a class: every pair of submissions is compared, so its
cost grows with the square of the class, unlike the grading, which grows with the class.

    .venv/bin/python tests/benchmarks/bench_similarity.py                 # 50, 100 and 200 students
    .venv/bin/python tests/benchmarks/bench_similarity.py --students 400 --large 5

Each submission is Problem 1's student notebook as handed out plus a cell of its own code,
generated at random (functions of random expressions over random numbers), between 1,500 and
8,000 characters (the master's own code is about 1,800). Code written apart still shares short
passages by chance (a function's first line, a ``return``), as real notebooks share idioms.
One student in ten hands in a classmate's notebook with every name changed: the pairs the
report should list, and the only ones it should. ``--large K`` makes K of the students hand in
100,000 characters of own code, half the most the report reads
(:data:`labsupport.instructor.similarity.MAX_CODE_CHARS`). For each class size it prints the
wall time of :func:`labsupport.instructor.similarity.similarity_reports` (what the batch grader
runs after grading), the pairs compared, the pairs listed and how many of them hand in the same
code, and the size of ``similarity.html``.
"""

from __future__ import annotations

import argparse
import csv
import io
import json
import random
import re
import time
from pathlib import Path

import nbformat

from labsupport.instructor import similarity

ROOT = Path(__file__).resolve().parents[2]
SPEC = ROOT / "tests" / "autograder" / "problem1.json"
CLASSES = (50, 100, 200)
COPY_EVERY = 10  # one student in ten hands in a classmate's notebook, renamed
#: The own code of a large notebook [characters]: half the most the report reads, so that a
#: renamed copy of it (longer names) is still read.
LARGE = similarity.MAX_CODE_CHARS // 2

_FUNCTIONS = ("np.sin", "np.cos", "np.sqrt", "np.abs", "np.tanh", "np.exp", "np.arctan")
_OPERATORS = ("+", "-", "*", "/")


def _number(rng: random.Random) -> str:
    """A random number of six significant digits (the report keeps numbers as written)."""
    return f"{rng.uniform(1, 10):.5f}"


def _expression(rng: random.Random, names: list[str], depth: int = 0) -> str:
    """A random arithmetic expression over ``names`` and random numbers."""
    if depth > 2 or rng.random() < 0.3:
        return rng.choice(names) if rng.random() < 0.5 else _number(rng)
    if rng.random() < 0.3:
        return f"{rng.choice(_FUNCTIONS)}({_expression(rng, names, depth + 1)})"
    op = rng.choice(_OPERATORS)
    return f"({_expression(rng, names, depth + 1)} {op} {_expression(rng, names, depth + 1)})"


def _code(rng: random.Random, chars: int) -> str:
    """About ``chars`` characters of random Python: functions of random statements."""
    lines, size, k = [], 0, 0
    while size < chars:
        args = [f"a{k}_{i}" for i in range(rng.randint(1, 3))]
        lines.append(f"def f{k}({', '.join(args)}):")
        names = list(args)
        for j in range(rng.randint(2, 6)):
            name = f"v{k}_{j}"
            lines.append(f"    {name} = {_number(rng)} * {_expression(rng, names)}")
            names.append(name)
        lines.append(f"    return {names[-1]}\n")
        size = sum(len(line) + 1 for line in lines)
        k += 1
    return "\n".join(lines)


def _renamed(code: str, rng: random.Random) -> str:
    """``code`` with every generated name replaced by another."""
    suffix = f"_{rng.randrange(10**6)}"
    return re.sub(r"\b([afv]\d+(?:_\d+)?)\b", lambda m: m.group(1) + suffix, code)


def _notebook(handed_out: list[str], own: str) -> bytes:
    cells = [nbformat.v4.new_code_cell(source) for source in handed_out]
    cells.append(nbformat.v4.new_code_cell(own))
    return nbformat.writes(nbformat.v4.new_notebook(cells=cells)).encode("utf-8")


def make_class(students: int, large: int, handed_out: list[str], seed: int = 0) -> tuple[dict[str, bytes], set]:
    """``students`` notebooks by file name: independent random code, one in :data:`COPY_EVERY`
    a renamed copy of a classmate's, the first ``large`` of :data:`LARGE` characters; and the
    pairs of file names that hand in the same code."""
    rng = random.Random(seed)
    codes: list[str] = []
    origin: list[int] = []  # whose code each student hands in
    for i in range(students):
        if i % COPY_EVERY == COPY_EVERY - 1:
            copied = rng.randrange(i)
            codes.append(_renamed(codes[copied], rng))
            origin.append(origin[copied])
        else:
            codes.append(_code(rng, LARGE if i < large else rng.randint(1_500, 8_000)))
            origin.append(i)
    names = [f"student{i:03d}.ipynb" for i in range(students)]
    same = {(names[i], names[j]) for i in range(students) for j in range(i + 1, students) if origin[i] == origin[j]}
    return {name: _notebook(handed_out, code) for name, code in zip(names, codes, strict=True)}, same


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--students", type=int, nargs="*", default=list(CLASSES), help="class sizes to time")
    parser.add_argument("--large", type=int, default=0, help="students with LARGE characters of own code")
    args = parser.parse_args(argv)
    spec = json.loads(SPEC.read_text(encoding="utf-8"))
    handed_out = sorted(similarity.handed_out_and_master(spec)[0])
    for n in args.students:
        notebooks, copies = make_class(n, args.large, handed_out)
        start = time.perf_counter()
        reports = similarity.similarity_reports(notebooks, spec)
        wall = time.perf_counter() - start
        listed = {tuple(row[:2]) for row in csv.reader(io.StringIO(reports["similarity.csv"]))} - {("file", "other")}
        compared = n * (n - 1) // 2 + n  # each pair, and each student with the master
        print(
            f"{n:4d} students ({args.large} with {LARGE:,} characters): {wall:6.1f} s, "
            f"{compared:,} pairs compared, {len(listed)} listed ({len(listed & copies)} of the {len(copies)} "
            f"that hand in the same code), similarity.html {len(reports['similarity.html']) / 1e6:.2f} MB"
        )


if __name__ == "__main__":
    main()
