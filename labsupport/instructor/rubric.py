"""The grading rubric of a Problem, in words, made from the checks themselves.

Usage::

    .venv/bin/python -m labsupport.instructor.rubric --problem problem1            # print it
    .venv/bin/python -m labsupport.instructor.rubric --problem problem2 --out rubric.md
    .venv/bin/python -m labsupport.instructor.rubric --spec path/to/spec.json   # a spec of your own
    .venv/bin/python -m labsupport.instructor.rubric --problem problem1 --out rubric.csv   # for Canvas

For each check of the Problem's autograder spec it gives the points, how the check scores, and
the mistakes the check names in its feedback with the credit each keeps (the ◐ marks). The
scoring rules are each check module's ``SCORING``; the mistakes are built by the checks' own
code (``named_mistakes``), so the rubric cannot drift from what the grader does. The batch
grader writes the same text to ``rubric.md`` beside ``grades.csv``.

An ``--out`` file ending in ``.csv`` gets the same rubric in the format of Canvas's *Import
Rubric* (the Rubrics page, with Enhanced Rubrics), and the batch grader writes that too, as
``rubric_canvas.csv``. The format is Canvas's own template and importer (``template_file`` in
``app/models/rubric_import.rb`` and ``lib/rubric_csv_importer.rb`` of canvas-lms): a header row,
then one row per criterion, the rubric's name repeated on each; after ``Criteria Enable Range``
come groups of ``Rating Name``, ``Rating Description``, ``Rating Points``, as many as a criterion
needs (a row may stop early); points take two decimals. The file is UTF-8 without a byte-order
mark, which would become part of the first column's name.
"""

from __future__ import annotations

import argparse
import csv
import io
import sys
from pathlib import Path

from labsupport import __version__
from labsupport.grading import PUBLIC_SEED, problem1, problem2
from labsupport.grading.rules import FORBIDDEN
from labsupport.instructor.assign import chosen_spec, load_spec, problem_arguments
from labsupport.instructor.gradebook import apportion
from labsupport.instructor.judge import DEFAULT_BUDGET

_MODULES = (problem1, problem2)


def _module_of(check: str):
    """The check module that defines ``check``."""
    for module in _MODULES:
        if check in module.CHECKS:
            return module
    raise ValueError(f"no check named {check!r}; the checks are {sorted(c for m in _MODULES for c in m.CHECKS)}")


def mistake_credits(check: str) -> list[tuple[float, str]]:
    """``(credit, explanation)`` of each mistake the formula check ``check`` names, highest credit
    first, one row per explanation (the IK + joint CT check names one per full turn an angle may be
    off; they share a row). Empty for a check that names none."""
    mistakes = _module_of(check).named_mistakes(check, PUBLIC_SEED)
    rows = dict.fromkeys((m.score, m.text) for m in mistakes.values())
    return sorted(rows, key=lambda row: -row[0])


def _points(credit: float, points: float) -> str:
    return f"{100 * credit:g} % ({credit * points:g} of {points:g})"


def _sentence(text: str) -> str:
    """``text`` with a capital first letter and a full stop; a text that opens with a one-letter
    symbol (``h(q, q̇)``, ``e = ...``) keeps its case, which is part of the symbol."""
    if text[1:2].isalpha():
        text = text[:1].upper() + text[1:]
    return text if text.endswith((".", ".)", "!", "?")) else text + "."  # "... (a remark)" too


def _cell(text: str) -> str:
    """Text safe inside a Markdown table cell."""
    return text.replace("|", "\\|").replace("\n", " ")


#: What scores 0 on any check, whatever the check asks (said in both forms of the rubric).
_BROKEN = "is missing, raises, returns a wrong shape or NaN, or runs past its time limits"


def rubric(spec: dict) -> str:
    """The rubric of the Problem an autograder spec describes, as Markdown."""
    checks = spec["checks"]
    total = sum(c["points"] for c in checks)
    budget = DEFAULT_BUDGET
    lines = [
        f"# Grading rubric: {spec['problem']}",
        "",
        f"Made by labsupport {__version__} from the checks the batch grader runs. {total:g} points in all.",
        "",
        "On every check:",
        "",
        "- a TODO answered by calling into labsupport's controllers, kinematics or checks "
        f"({', '.join(f'`{m}`' for m in FORBIDDEN)}) scores 0, with the reason;",
        f"- a function that {_BROKEN} "
        f"({budget.call:g} s of CPU per call, {budget.check:g} s over the check, which gives each of "
        "its laws an equal share where it runs two) scores 0 on that check, or on that law's share of it, "
        "the others keep their points;",
        "- a law that writes into the state it is handed (`e = data.qpos; e -= q_d`) is judged on its "
        "result alone, since each call gets its own copy of the state, and the feedback says that it wrote;",
        "- the test states, targets and circles are drawn from the batch's secret seed.",
    ]
    for c in checks:
        module = _module_of(c["name"])
        points = f"{c['points']:g} point" + ("" if c["points"] == 1 else "s")
        lines += ["", f"## {c['name']}: {c['title']} ({points})", "", module.SCORING[c["name"]]]
        rows = mistake_credits(c["name"])
        if rows:
            lines += ["", "| Credit kept | Mistake, as the feedback names it |", "| --- | --- |"]
            lines += [f"| {_points(credit, c['points'])} | {_cell(_sentence(text))} |" for credit, text in rows]
    return "\n".join(lines) + "\n"


#: The columns that open Canvas's rubric import, and the three that each rating adds.
CANVAS_COLUMNS = ("Rubric Name", "Criteria Name", "Criteria Description", "Criteria Enable Range")
CANVAS_RATING = ("Rating Name", "Rating Description", "Rating Points")


def canvas_ratings(check: str, points: float) -> list[tuple[str, str, float]]:
    """``(name, description, points)`` of each rating of ``check`` in a Canvas rubric, from full
    marks down to none: full credit, then each credit a named mistake keeps (the mistakes that
    keep the same credit share one rating), then no credit, with what scores 0 on every check."""
    by_credit: dict[float, list[str]] = {}
    for credit, text in [*mistake_credits(check), *_module_of(check).PARTIAL_CREDIT.get(check, [])]:
        by_credit.setdefault(credit, []).append(_sentence(text))
    zero = [
        f"Fails the check, as its description says; or the function {_BROKEN}; or it answers the TODO "
        "through labsupport's controllers or kinematics.",
        *by_credit.pop(0.0, []),
    ]
    if check in _module_of(check).PROPORTIONAL:  # a range in Canvas: any share of the points
        top = ("Share of full marks", "The points times the share the description names (all right: full marks).")
    else:
        top = ("Full marks", "Passes the check, as its description says.")
    ratings = [(*top, float(points))]
    for credit in sorted(by_credit, reverse=True):
        ratings.append((f"{100 * credit:g} % kept", " ".join(by_credit[credit]), credit * points))
    ratings.append(("No marks", " ".join(zero), 0.0))
    return ratings


def full_marks(spec: dict, scale: float = 1.0) -> list[float]:
    """Each check's points times ``scale``, rounded to hundredths so that they add up to the
    total (:func:`labsupport.instructor.gradebook.apportion`): the rubric's and the Canvas
    feedback's full marks, one list for both."""
    return apportion([float(c["points"]) * scale for c in spec["checks"]])


def canvas_rubric_csv(spec: dict, scale: float = 1.0) -> str:
    """The rubric of the Problem an autograder spec describes, as a CSV for Canvas's *Import
    Rubric*: one criterion per check, named ``<check>: <title>``, described by how it scores,
    with the ratings of :func:`canvas_ratings`; every point times ``scale`` (the Canvas column's
    points possible over the checks' total, so the rubric adds up to the column's grade), each
    criterion's points rounded to hundredths so that they add up to it (:func:`full_marks`)."""
    rows = []
    for c, most in zip(spec["checks"], full_marks(spec, scale), strict=True):
        module = _module_of(c["name"])
        ranged = "true" if c["name"] in module.PROPORTIONAL else "false"  # any share of the points
        row = [f"{spec['problem']}: grading rubric", f"{c['name']}: {c['title']}", module.SCORING[c["name"]], ranged]
        for name, description, points in canvas_ratings(c["name"], most):
            row += [name, description, f"{round(points, 2):g}"]
        rows.append(row)
    most = max(len(row) for row in rows)
    header = list(CANVAS_COLUMNS) + list(CANVAS_RATING) * ((most - len(CANVAS_COLUMNS)) // len(CANVAS_RATING))
    buf = io.StringIO()
    writer = csv.writer(buf, lineterminator="\n")
    writer.writerow(header)
    writer.writerows(rows)
    return buf.getvalue()


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(
        prog="python -m labsupport.instructor.rubric", description="Write the grading rubric of a Problem."
    )
    problem_arguments(parser)
    parser.add_argument(
        "--out", type=Path, help="file to write (default: print); a name ending in .csv gets Canvas's import format"
    )
    args = parser.parse_args(argv)
    spec_path = chosen_spec(parser, args)
    try:
        spec = load_spec(spec_path)
    except ValueError as err:  # not JSON, or not a spec of known checks
        parser.error(str(err))
    canvas = args.out is not None and args.out.suffix.lower() == ".csv"
    text = canvas_rubric_csv(spec) if canvas else rubric(spec)
    if args.out is None:
        sys.stdout.write(text)
    else:
        try:
            args.out.write_text(text, encoding="utf-8")
        except OSError as err:  # a folder, a folder that does not exist, no permission
            parser.error(
                f"cannot write the rubric to {args.out}: {err.strerror}; give a file path in a folder you can write"
            )


if __name__ == "__main__":
    main()
