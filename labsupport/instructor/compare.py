"""Compare a folder or a zip of submissions for shared code, without grading them.

Usage (from the repository root)::

    .venv/bin/python -m labsupport.instructor.compare --problem problem1 SUBMISSIONS --out REPORTS

writes ``REPORTS/similarity.csv`` and ``REPORTS/similarity.html``: the report the batch grader
writes beside ``grades.csv`` (:mod:`labsupport.instructor.similarity`), made the same way from
the same notebooks, compared with each other, with the master's solution and with the notebooks
of any ``--compare-with FOLDER_OR_ZIP``. SUBMISSIONS may be Canvas's "Download Submissions" zip
as it comes: each student's notebook for the Problem is compared, named as Canvas named it. It
runs no student code, so it needs no sandbox and takes seconds where grading takes minutes. Use
it to compare with another year's submissions once the grades are in, or to list the pairs at a
lower ``--flag`` (0.4, say) than the batch's
:data:`~labsupport.instructor.similarity.FLAG_SHARE`.

Each ``previous/`` level of an output folder is one earlier run of the command that writes there
(:func:`labsupport.instructor.outputs.keep_previous`). Given a grader's output folder (the batch's,
or the Canvas command's), this command writes into its ``compare/`` subfolder
(:func:`report_folder`): the grader's own report stays beside its grades, and what an earlier
comparison wrote moves into ``compare/previous/``.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from labsupport.instructor.assign import chosen_spec, load_spec, problem_arguments
from labsupport.instructor.batch import (
    atomic_write,
    check_compare_with,
    check_out_outside,
    check_submissions_folder,
    compare_with_argument,
    left_aside,
    list_notebooks,
    payload,
    read_submissions,
    shared_code_reports,
)
from labsupport.instructor.outputs import (
    BATCH_RESULTS,
    CANVAS_RESULTS,
    clean_text,
    counted,
    keep_previous,
    keep_private,
)
from labsupport.instructor.similarity import FLAG_SHARE, pairs_listed
from labsupport.instructor.submissions import is_zip, zip_notebooks

#: The files this command writes (and moves into ``previous/`` when an earlier run left them).
REPORTS = ("similarity.csv", "similarity.html")

#: The subfolder of a grader's output folder that this command writes into (:func:`report_folder`).
OWN_FOLDER = "compare"


def report_folder(out: Path) -> Path:
    """Where the reports go for ``--out out``: ``out`` itself, or ``out/compare/`` where a grader
    wrote its results in ``out`` (a batch's ``grades.csv`` or ``batch.json``, a Canvas run's import
    or report), now or in its ``previous/``. There, each ``previous/`` level holds one earlier run
    of the grader, its report with its grades: a report written beside them would move the
    grader's own into ``previous/``, apart from its grades, and push the earlier run's report a
    level down from its own. In a folder of its own, each ``previous/`` level is one earlier
    comparison."""
    graded = [name for name in (*BATCH_RESULTS, *CANVAS_RESULTS) if name not in REPORTS]
    if any((folder / name).is_file() for folder in (out, out / "previous") for name in graded):
        return out / OWN_FOLDER
    return out


def flag_argument(text: str) -> float:
    """``--flag``: a share above 0 and at most 1."""
    try:
        flag = float(text)
    except ValueError:
        flag = float("nan")
    if not 0 < flag <= 1:
        raise argparse.ArgumentTypeError(f"must be a share above 0 and at most 1 (0.6 is 60 %), got {text!r}")
    return flag


def folder_submissions(parser: argparse.ArgumentParser, folder: Path) -> list[tuple[str, bytes | None, str | None]]:
    """The notebooks at the top of ``folder`` (:func:`labsupport.instructor.batch.read_submissions`);
    what is left aside, and why, goes to stderr."""
    check_submissions_folder(parser, folder)
    aside = left_aside(folder)
    if aside:
        print("not compared (not .ipynb files): " + clean_text(", ".join(aside)), file=sys.stderr)
    payloads = read_submissions(list_notebooks(folder))
    for name, _, why in payloads:
        if why:
            print(f"not compared: {clean_text(name)} ({why})", file=sys.stderr)
    return payloads


def zip_submissions(
    parser: argparse.ArgumentParser, zip_path: Path, spec: dict
) -> list[tuple[str, bytes | None, str | None]]:
    """The notebooks of a zip as :func:`folder_submissions` gives a folder's: of a Canvas download,
    each student's notebook for the Problem (:func:`labsupport.instructor.submissions.zip_notebooks`);
    what is left out, and why, goes to stderr."""
    try:
        notebooks, left_out = zip_notebooks(zip_path, spec)
    except ValueError as err:
        parser.error(str(err))
    for entry in left_out:
        print(f"not compared: {clean_text(entry)}", file=sys.stderr)
    if not notebooks:
        parser.error(f"no notebook for {spec['problem']} in {zip_path}")
    return [payload(name, data) for name, data in notebooks.items()]


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(
        prog="python -m labsupport.instructor.compare",
        description="List the pairs of submissions that share code (similarity.csv, similarity.html), without "
        "grading them.",
    )
    parser.add_argument(
        "submissions",
        type=Path,
        help="folder holding the students' .ipynb files, or Canvas's 'Download Submissions' zip as it comes",
    )
    problem_arguments(parser)
    parser.add_argument(
        "--out",
        type=Path,
        required=True,
        help="folder for similarity.csv and similarity.html (a grader's output folder too: the reports go into "
        "its compare/ subfolder, and its own report stays beside its grades)",
    )
    parser.add_argument(
        "--flag",
        type=flag_argument,
        default=FLAG_SHARE,
        help=f"list a pair when either notebook has at least this share of its own code in the other, or the "
        f"two share this share of a whole answer (default {FLAG_SHARE}, as the batch grader)",
    )
    compare_with_argument(parser)
    args = parser.parse_args(argv)
    try:
        spec = load_spec(chosen_spec(parser, args))
    except ValueError as err:  # not JSON, or not a spec of known checks
        parser.error(str(err))
    check_compare_with(parser, args.compare_with, args.submissions)
    if is_zip(args.submissions):
        payloads = zip_submissions(parser, args.submissions, spec)
    elif args.submissions.is_dir():
        try:
            check_out_outside(args.out, args.submissions)
        except ValueError as err:
            parser.error(str(err))
        payloads = folder_submissions(parser, args.submissions)
    else:
        parser.error(
            f"{args.submissions} is neither a folder nor a .zip: give the folder that holds the .ipynb files, "
            "or Canvas's Download Submissions zip"
        )
    try:
        reports = shared_code_reports(payloads, spec, args.compare_with, args.flag)
    except ValueError as err:  # the spec's student notebook is gone
        parser.exit(2, f"{parser.prog}: cannot compare: {err}\n")
    folder = report_folder(args.out)
    try:
        folder.mkdir(parents=True, exist_ok=True)
        keep_previous(folder, REPORTS)
        for name, text in reports.items():
            atomic_write(folder / name, text)
    except OSError as err:
        parser.exit(
            2, f"{parser.prog}: cannot write {folder} ({err.strerror or err}): give --out a folder you can write to\n"
        )
    pairs = pairs_listed(reports)
    print(
        f"{counted(sum(1 for _, data, _ in payloads if data), 'submission')} compared; pairs sharing at least "
        f"{100 * args.flag:g} % of one's own code or of a whole answer: {pairs}; see {folder / 'similarity.html'}"
    )


if __name__ == "__main__":
    keep_private()
    main()
