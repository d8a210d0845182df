"""Generate the student notebooks and the autograder specs from the Problems' master notebooks.

Usage::

    .venv/bin/python -m labsupport.instructor.assign            # write notebooks/*.ipynb and tests/autograder/*.json
    .venv/bin/python -m labsupport.instructor.assign --check    # exit 1 if what is committed differs

A master (``notebooks/masters/*.ipynb``) holds the solution and the checks, in the spirit of
``otter assign``:

* notebook metadata ``labsupport_grading``: ``problem``, ``student`` (the path of the student
  notebook to write) and ``checks`` (``name``, ``points``, ``title``), the autograder's tests;
* in code cells, lines between ``# BEGIN SOLUTION`` and ``# END SOLUTION`` are the solution
  (removed), and a line ``# STUDENT: code`` becomes ``code`` in the student's version (the stub);
* in markdown cells, text between ``<!-- BEGIN SOLUTION -->`` and ``<!-- END SOLUTION -->`` is
  removed; a cell tagged ``solution`` is dropped whole;
* each check is a code cell ``check("name", globals())``, right after the TODO it checks.
* a cell's ``tags`` (but ``solution``) and its ``mystnb`` metadata (the book's options for the
  cell, e.g. a figure's alt text) are kept; other cell metadata is dropped;
* a markdown line ``<!-- POINTS TABLE -->`` becomes the table of the checks' points
  (:func:`points_table`), each check under the ``##`` heading of the section its cell is in, so
  the page a student reads gives the same points as the grader.

The student notebook keeps the checks' list in its metadata (so it needs no extra file, on
Colab too) and the spec ``tests/autograder/<problem>.json`` tells the batch grader which checks
to run and their points: the checks themselves are code in :mod:`labsupport.grading`, never
taken from a submission.
"""

from __future__ import annotations

import argparse
import ast
import copy
import importlib
import json
import re
import sys
from pathlib import Path

import nbformat
import numpy as np

from labsupport.grading import registry

MASTERS = Path("notebooks") / "masters"
#: Where the autograder specs are written, relative to the repository root.
SPEC_DIR = Path("tests") / "autograder"
#: The checkout, whatever the working folder.
ROOT = Path(__file__).resolve().parents[2]
#: Where ``--problem NAME`` of the batch and Canvas commands finds them, from any working folder.
SPECS = ROOT / SPEC_DIR
_CHECK_CELL = re.compile(r'^check\("([a-z0-9_]+)", globals\(\)\)\s*$')
_HEADING = re.compile(r"^##\s+(.+?)\s*$", re.M)
#: The markdown line that the student notebook gets the points table in place of.
POINTS_MARKER = "<!-- POINTS TABLE -->"
#: Cell metadata copied as is into the student's cell: ``mystnb`` holds the book's per-cell
#: options, such as a figure's text alternative (``{"mystnb": {"image": {"alt": ...}}}``).
CARRIED_METADATA = ("mystnb",)


class MasterError(ValueError):
    """The master notebook does not follow the format (message says where)."""


def load_spec(path: Path) -> dict:
    """The autograder spec at ``path`` (written by :func:`main`), or a ``ValueError`` that says
    the file is not one: it must be JSON naming the problem and its checks with their points
    (:func:`check_the_checks`)."""
    not_a_spec = f"{path} is not an autograder spec of this labsupport's checks"
    try:
        spec = json.loads(Path(path).read_text(encoding="utf-8"))
    except (OSError, ValueError) as err:
        raise ValueError(f"{not_a_spec}: {err}") from None
    if not isinstance(spec, dict) or not isinstance(spec.get("problem"), str) or "checks" not in spec:
        raise ValueError(
            f"{not_a_spec} (no problem, or no checks with points): pass --problem NAME, or a spec written by "
            "labsupport.instructor.assign"
        )
    try:
        check_the_checks(spec["checks"])
    except MasterError as err:
        raise ValueError(f"{not_a_spec}: {err}") from None
    return spec


def problem_arguments(parser: argparse.ArgumentParser) -> None:
    """``--problem NAME`` or ``--spec PATH``, one of them required: the Problem an instructor's
    command works on (read back with :func:`chosen_spec`)."""
    which = parser.add_mutually_exclusive_group(required=True)
    which.add_argument("--problem", help="problem1 or problem2 (reads tests/autograder/NAME.json)")
    which.add_argument("--spec", type=Path, help="an autograder spec written by labsupport.instructor.assign")


def seed_argument(text: str) -> int:
    """``--seed``'s value: a whole number, 0 or more (the test states' generator takes no other)."""
    if not (text.isascii() and text.isdigit()):
        raise argparse.ArgumentTypeError(f"give a whole number, 0 or more (as batch.json records it), not {text!r}")
    return int(text)


def chosen_spec(parser: argparse.ArgumentParser, args: argparse.Namespace) -> Path:
    """The spec file that ``--problem`` or ``--spec`` named; where there is none, stop with the
    problems there are, or with what to give instead."""
    if args.spec is not None:
        if not args.spec.is_file():
            parser.error(f"no autograder spec at {args.spec}: give --spec PATH to a spec, or --problem NAME")
        return args.spec
    spec = SPECS / f"{args.problem}.json"
    if not spec.is_file():
        known = sorted(p.stem for p in SPECS.glob("*.json")) if SPECS.is_dir() else []
        parser.error(
            f"no autograder spec for --problem {args.problem} at {spec}: "
            + (f"the problems are {', '.join(known)}" if known else "give --spec PATH")
        )
    return spec


def strip_code(source: str, where: str) -> str:
    """The student's version of a code cell: solution blocks removed, ``# STUDENT:`` lines uncommented."""
    out, inside = [], False
    for line in source.split("\n"):
        marker = line.strip()
        if marker == "# BEGIN SOLUTION":
            if inside:
                raise MasterError(f"{where}: nested # BEGIN SOLUTION")
            inside = True
        elif marker == "# END SOLUTION":
            if not inside:
                raise MasterError(f"{where}: # END SOLUTION without # BEGIN SOLUTION")
            inside = False
        elif inside:
            continue
        elif marker.startswith("# STUDENT:"):
            indent = line[: len(line) - len(line.lstrip())]
            out.append(indent + marker[len("# STUDENT:") :].lstrip())
        else:
            out.append(line)
    if inside:
        raise MasterError(f"{where}: # BEGIN SOLUTION without # END SOLUTION")
    return "\n".join(out).strip("\n")


def strip_markdown(source: str) -> str:
    """The student's version of a markdown cell: solution blocks removed."""
    return re.sub(r"<!-- BEGIN SOLUTION -->.*?<!-- END SOLUTION -->\n?", "", source, flags=re.S).strip("\n")


def check_the_checks(checks) -> None:
    """``MasterError`` unless ``checks`` lists each check once, by a name that
    :func:`labsupport.grading.registry` knows, with a positive number of points and a title: the
    batch grader, the rubric and Canvas add the points up. The message names the check."""
    known = registry()
    if not isinstance(checks, list) or not checks:
        raise MasterError(f"the checks must be a list of {{name, points, title}}, got {checks!r}")
    for c in checks:
        if not isinstance(c, dict) or not {"name", "points", "title"} <= set(c):
            raise MasterError(f"each check needs a name, points and a title, got {c!r}")
        if c["name"] not in known:
            raise MasterError(f"no check named {c['name']!r} in labsupport.grading; they are {sorted(known)}")
        points = c["points"]
        if isinstance(points, bool) or not isinstance(points, (int, float)) or not 0 < points < float("inf"):
            raise MasterError(f"check {c['name']!r} must have a positive number of points, got {points!r}")
        if not isinstance(c["title"], str) or not c["title"].strip():
            raise MasterError(f"check {c['name']!r} needs a title (a few words), got {c['title']!r}")
    names = [c["name"] for c in checks]
    if len(set(names)) != len(names):
        raise MasterError(f"each check may be listed once, got {names}")


def points_table(checks: list[dict], sections: dict[str, str]) -> str:
    """A Markdown table of the checks in the order listed: each check's name with the section its
    cell is in (``sections``, check name to heading, of which the part before a colon is shown:
    "TODO 1"), what it grades (its title), its points, and the total."""
    total = sum(c["points"] for c in checks)
    rows = ["| Check cell | What it grades | Points |", "| --- | --- | ---: |"]
    for c in checks:
        section = sections.get(c["name"], "").split(":")[0]  # "TODO 1: inverse kinematics" -> "TODO 1"
        rows.append(f"| `{c['name']}` ({section}) | {c['title']} | {c['points']:g} |")
    rows.append(f"| **Total** | | **{total:g}** |")
    return "\n".join(rows)


def student_notebook(master: nbformat.NotebookNode, where: str = "master") -> nbformat.NotebookNode:
    """The student notebook generated from a master (no outputs, same cell ids)."""
    meta = master.metadata.get("labsupport_grading")
    if not meta or not {"problem", "student", "checks"} <= set(meta):
        raise MasterError(f"{where}: metadata 'labsupport_grading' with problem, student and checks is missing")
    try:
        check_the_checks(meta["checks"])
    except MasterError as err:
        raise MasterError(f"{where}: {err}") from None
    nb = nbformat.v4.new_notebook()
    nb.metadata = {
        "kernelspec": copy.deepcopy(master.metadata.get("kernelspec", {})),
        "language_info": {"name": "python"},
        "labsupport_grading": {"problem": meta["problem"], "checks": copy.deepcopy(meta["checks"])},
    }
    seen, sections, section = [], {}, ""
    for k, cell in enumerate(master.cells):
        if "solution" in cell.metadata.get("tags", []):
            continue
        if cell.cell_type == "code":
            src = strip_code(cell.source, f"{where}, cell {k}")
            m = _CHECK_CELL.match(src)
            if m:
                seen.append(m.group(1))
                sections[m.group(1)] = section
            new = nbformat.v4.new_code_cell(src)
        elif cell.cell_type == "markdown":
            new = nbformat.v4.new_markdown_cell(strip_markdown(cell.source))
            section = ([section] + _HEADING.findall(new.source))[-1]
        else:
            new = nbformat.v4.new_raw_cell(cell.source)
        new.id = cell.get("id", f"cell-{k}")
        tags = [t for t in cell.metadata.get("tags", []) if t != "solution"]
        if tags:
            new.metadata["tags"] = tags
        for key in CARRIED_METADATA:
            if key in cell.metadata:
                new.metadata[key] = copy.deepcopy(cell.metadata[key])
        nb.cells.append(new)
    names = [c["name"] for c in meta["checks"]]
    if sorted(seen) != sorted(names):
        raise MasterError(f"{where}: check cells {seen} do not match the metadata's checks {names}")
    table = points_table(meta["checks"], sections)
    for cell in nb.cells:
        if cell.cell_type == "markdown":
            cell.source = cell.source.replace(POINTS_MARKER, table)
    return nb


def cell_settings(nb: nbformat.NotebookNode, first_name: str, where: str = "the notebook") -> dict:
    """The settings that open the code cell of ``nb`` whose source starts with ``first_name``: its
    first assignments of values made from NumPy and each other, evaluated, up to the first
    statement that is not such a setting (``{"q0": array([...]), "T_sim": 5.0, ...}``)."""
    cell = next((c for c in nb.cells if c.cell_type == "code" and c.source.startswith(first_name)), None)
    if cell is None:
        raise MasterError(f"{where} has no code cell that starts with {first_name!r}, where its settings are read")
    names = {"np": np}
    for node in ast.parse(cell.source).body:
        loads = {n.id for n in ast.walk(node) if isinstance(n, ast.Name) and isinstance(n.ctx, ast.Load)}
        if not isinstance(node, ast.Assign) or not loads <= names.keys():
            break
        exec(compile(ast.Module([node], type_ignores=[]), where, "exec"), names)
    return names


def settings_drift(master: nbformat.NotebookNode, where: str = "the master") -> list[str]:
    """Each setting of the master that the grader of its checks (the module of
    :mod:`labsupport.grading` that holds them) copies, in its ``NOTEBOOK_SETTINGS``, and holds
    another value of: the student would run one arm and be graded on another."""
    checks = registry()
    graders = {
        checks[c["name"]].__module__ for c in master.metadata["labsupport_grading"]["checks"] if c["name"] in checks
    }
    common = importlib.import_module("labsupport.grading.common")
    drift = []
    for grader in map(importlib.import_module, sorted(graders)):
        for first_name, names in grader.NOTEBOOK_SETTINGS.items():
            found = cell_settings(master, first_name, where)
            for name, constant in names.items():
                module, attr = (
                    (common, constant.removeprefix("common.")) if constant.startswith("common.") else (grader, constant)
                )
                value = getattr(module, attr)
                if name not in found:
                    drift.append(f"{where} no longer sets {name} in the cell that starts with {first_name!r}")
                elif np.shape(found[name]) != np.shape(value) or not np.array_equal(found[name], value):
                    drift.append(
                        f"{where} sets {name} = {found[name]!r}, its grader labsupport/grading/"
                        f"{module.__name__.rsplit('.', 1)[1]}.py has {attr} = {value!r}"
                    )
    return drift


def spec(master: nbformat.NotebookNode, master_path: str) -> dict:
    """The autograder spec of a master: problem, notebooks, and the checks with their points."""
    meta = master.metadata["labsupport_grading"]
    return {
        "problem": meta["problem"],
        "master": master_path,
        "student": meta["student"],
        "checks": [{"name": c["name"], "points": c["points"], "title": c["title"]} for c in meta["checks"]],
    }


def render(nb: nbformat.NotebookNode) -> str:
    """The exact text a notebook is committed as."""
    return nbformat.writes(nb) + "\n"


def outputs(root: Path = Path(".")) -> dict[Path, str]:
    """Every generated file and its text, from the masters under ``root``."""
    files = {}
    masters = sorted((root / MASTERS).glob("*.ipynb"))
    if not masters:
        raise MasterError(f"no master notebooks in {root / MASTERS}: run from the repository root")
    for path in masters:
        rel = path.relative_to(root).as_posix()
        try:
            master = nbformat.read(str(path), as_version=4)
        except (ValueError, UnicodeDecodeError) as err:  # NotJSONError is a ValueError
            raise MasterError(
                f"{rel} is not a notebook's JSON ({type(err).__name__}: {str(err)[:200]}): if a merge left "
                "conflict markers (<<<<<<<) in it, resolve them, then run this again"
            ) from None
        student = student_notebook(master, rel)
        sp = spec(master, rel)
        if drift := settings_drift(master, rel):
            raise MasterError(
                "; ".join(drift) + ". The checks run the student's laws with the grader's values: change both to "
                "the same value (and the prose and the tests that quote the old one), then run this again"
            )
        files[root / sp["student"]] = render(student)
        files[root / SPEC_DIR / f"{sp['problem']}.json"] = json.dumps(sp, indent=2, ensure_ascii=False) + "\n"
    return files


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(
        prog="python -m labsupport.instructor.assign",
        description="Generate student notebooks and autograder specs from the masters.",
    )
    parser.add_argument("--check", action="store_true", help="only compare with what is on disk; exit 1 on drift")
    args = parser.parse_args(argv)
    try:
        files = outputs(ROOT)
    except MasterError as err:
        parser.error(str(err))
    drift = []
    for path, text in files.items():
        current = path.read_text(encoding="utf-8") if path.exists() else None
        if current == text:
            continue
        drift.append(path)
        if not args.check:
            path.parent.mkdir(parents=True, exist_ok=True)
            path.write_text(text, encoding="utf-8")
    verb = "differs from the masters" if args.check else "written"
    lines = [f"{p.relative_to(ROOT)}: {verb}" for p in drift]
    if args.check and drift:
        lines.append(
            "run `python -m labsupport.instructor.assign` to regenerate " + ("it" if len(drift) == 1 else "them")
        )
    print("\n".join(lines) or "everything is up to date")
    return 1 if (args.check and drift) else 0


if __name__ == "__main__":
    sys.exit(main())
