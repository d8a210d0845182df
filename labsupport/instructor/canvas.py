"""Grade from Canvas to Canvas: the "Download Submissions" zip in, a gradebook ready to import out.

Usage (from the repository root)::

    .venv/bin/python -m labsupport.instructor.canvas --problem problem1 submissions.zip \\
        --gradebook export.csv [--column "Problem 1 (12345)"] --out OUT

reads the zip that an assignment's *Download Submissions* gives and the CSV that the
Gradebook's *Export* gives, grades each student's notebook with
:func:`labsupport.instructor.batch.run_batch`, and writes

* ``OUT/gradebook_import.csv``: the export's identifying columns (``Student`` to ``Section``)
  and the Problem's column, filled, for the Gradebook's *Import*; the other assignments' columns
  are left out, so a stale export cannot revert grades changed in Canvas since;
* ``OUT/feedback/<canvas prefix>_feedback.txt``: one file per graded student (the score and
  each check's points in the column's points, as ``rubric_canvas.csv``), and
  ``OUT/feedback_upload.zip`` holding them all, for the assignment's *Re-upload Submissions*;
* ``OUT/report.txt``: what was graded and what was not, and why (grades in Canvas that the
  import replaces, files that match no student, students with no submission, unreadable files,
  late work, resubmissions, scaling, and a score below full marks beside another notebook of the
  student's, which the feedback names too);
* ``OUT/batch/``: the batch grader's own ``grades.csv`` and feedback, the Problem's rubric
  (``rubric.md``, and ``rubric_canvas.csv`` for the course's *Rubrics → Import Rubric*), and
  the pairs of students who share code (``similarity.html``: :mod:`labsupport.instructor.similarity`).

A regrade into the same ``OUT`` first moves the earlier run's import, report, zip, rubric and feedback
into ``OUT/previous/``, and the earlier batch's results into ``OUT/batch/previous/``; an even
earlier run's move one level down (:func:`labsupport.instructor.outputs.keep_previous`). The
command's last line says what moved.

What Canvas produces, and where each fact comes from (Canvas's own source), is told where it is
read: :mod:`labsupport.instructor.submissions` for the zip and the re-uploaded feedback files,
:mod:`labsupport.instructor.gradebook` for the export and the import.
"""

from __future__ import annotations

import argparse
import re
import shutil
import sys
import tempfile
import unicodedata
import zipfile
from collections.abc import Callable
from dataclasses import dataclass, field
from functools import partial
from pathlib import Path

from labsupport.instructor import isolation
from labsupport.instructor.assign import chosen_spec, load_spec, problem_arguments, seed_argument
from labsupport.instructor.batch import (
    check_compare_with,
    check_grading_arguments,
    compare_with_argument,
    grading_arguments,
    notes_block,
    run_batch,
)
from labsupport.instructor.gradebook import (
    Gradebook,
    apportion,
    choose_column,
    column_warning,
    decimal_point,
    fill_column,
    format_score,
    read_gradebook,
    scaled_score,
)
from labsupport.instructor.judge import OTHER_PROBLEM_MARK
from labsupport.instructor.outputs import (
    BATCH_RESULTS,
    CANVAS_RESULTS,
    FEEDBACK_HEADER,
    clean_text,
    counted,
    keep_previous,
    keep_private,
    problem_title,
)
from labsupport.instructor.rubric import canvas_rubric_csv, full_marks
from labsupport.instructor.submissions import (
    SubmissionFile,
    choose_notebook,
    is_os_metadata,
    notebook_stem,
    open_zip,
    other_problem,
    parse_submission_name,
    plain,
    read_notebook_entry,
    safe_zip_entries,
)

#: Batch statuses whose scores go into the gradebook; any other status (timed out, grader
#: error, or one this module does not know) leaves the student out of the import, and is reported.
SCORED_STATUSES = ("graded", "unreadable")


@dataclass
class CanvasResult:
    """What one Canvas round trip did; every list is also written to the report."""

    column: str = ""
    points_possible: float | None = None
    maximum: float = 0.0
    scores: dict[int, str] = field(default_factory=dict)  #: user id -> cell written
    replaced: list[str] = field(default_factory=list)  #: grades already in Canvas that a score replaces
    feedback: dict[int, Path] = field(default_factory=dict)  #: user id -> feedback file
    unmatched: list[str] = field(default_factory=list)  #: files matching no student, and why
    missing: list[str] = field(default_factory=list)  #: gradebook students with nothing graded
    late: list[str] = field(default_factory=list)
    resubmissions: list[str] = field(default_factory=list)
    not_graded: list[str] = field(default_factory=list)  #: files of known students left aside
    others: dict[int, list[str]] = field(default_factory=dict)  #: user id -> other notebooks handed in, not graded
    not_scored: list[str] = field(default_factory=list)  #: graded files whose status gave no score
    excused: list[str] = field(default_factory=list)  #: graded files of students excused in Canvas, left so
    unreadable: list[str] = field(default_factory=list)  #: files the grader could not read (scored 0), and why
    notes: list[str] = field(default_factory=list)
    warning: str = ""  #: what to check before importing (a column that does not name the Problem)
    moved: str = ""  #: what of an earlier run in OUT went into OUT/previous/ (``""`` when nothing did)


GradeFn = Callable[[Path, Path, Path], list[dict]]


def grade_canvas(
    submissions_zip: Path,
    gradebook_path: Path,
    spec_path: Path,
    out: Path,
    column: str | None = None,
    jobs: int | None = None,
    grade: GradeFn | None = None,
    seed: int | None = None,
    compare_with: list[Path] | None = None,
    timeout: float | None = None,
) -> CanvasResult:
    """Grade a Canvas zip into a copy of a Canvas gradebook export; writes OUT as the module says.

    ``grade(folder, spec_path, out)`` grades a folder of notebooks and returns the batch rows
    (``file``, ``status``, ``scores``, ``messages``, ``notes``); by default it is
    :func:`labsupport.instructor.batch.run_batch` with ``jobs`` and ``seed`` (a fresh secret
    one if None; ``OUT/batch/batch.json`` records it, so ``--seed`` reproduces every grade) and
    ``compare_with`` (folders of earlier notebooks for the shared-code report), and ``timeout``
    (its wall-clock backstop per submission [s]; None: the batch grader's default).
    """
    spec_path, out = Path(spec_path), Path(out)
    spec = load_spec(spec_path)
    if out.exists() and not out.is_dir():
        raise ValueError(f"--out {out} is a file: give --out a folder (it is created if missing)")
    gradebook = read_gradebook(Path(gradebook_path))
    col = choose_column(gradebook, spec["problem"], column)
    result = CanvasResult(
        column=gradebook.header[col],
        points_possible=gradebook.points_possible(col),
        maximum=sum(float(c["points"]) for c in spec["checks"]),
        warning=column_warning(gradebook.header[col], spec["problem"]),
    )
    if result.points_possible is None:
        result.notes.append("the export has no Points Possible row: scores are written unscaled")
    elif abs(result.points_possible - result.maximum) > 1e-9:
        result.notes.append(
            f"the Problem's checks add up to {result.maximum:g} points and the column to "
            f"{result.points_possible:g}: every score is scaled by "
            f"{result.points_possible:g}/{result.maximum:g}, and so are each check's points in the feedback and "
            f"rubric_canvas.csv here (the one in batch/ is out of {result.maximum:g})"
        )
    chosen = _select_submissions(Path(submissions_zip), gradebook, spec, result)
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as err:
        raise ValueError(
            f"cannot write the output folder {out} ({err.strerror}): give --out a folder you can write to"
        ) from None
    result.moved = keep_previous(out, CANVAS_RESULTS, feedback="feedback", quiet=True)
    batch_options = {"jobs": jobs, "seed": seed, "compare_with": compare_with}
    if timeout is not None:
        batch_options["timeout"] = timeout
    grade = grade or partial(run_batch, **batch_options)
    try:
        rows = _grade(Path(submissions_zip), chosen, spec_path, out, result, grade)
    except (ValueError, isolation.SandboxUnavailable) as err:  # the earlier run was moved all the same
        if not result.moved:
            raise
        raise type(err)(f"{err}\n({result.moved})") from err
    except BaseException:  # Ctrl-C, say: its traceback follows, after where the earlier run went
        if result.moved:
            print(f"stopped; {result.moved}", file=sys.stderr)
        raise
    _record_scores(gradebook, col, spec, chosen, rows, out, result)
    (out / "gradebook_import.csv").write_bytes(fill_column(gradebook, col, result.scores).encode("utf-8"))
    _write_feedback_zip(out, result)
    (out / "report.txt").write_text(report_text(gradebook, spec, result), encoding="utf-8")
    (out / "rubric_canvas.csv").write_text(canvas_rubric_csv(spec, rubric_scale(result)), encoding="utf-8")
    return result


def rubric_scale(result: CanvasResult) -> float:
    """What each check's points are multiplied by in ``rubric_canvas.csv`` and in the feedback: the
    column's points possible over the checks' total (1 without a Points Possible row), so that the
    rubric and each student's points per check add up to the grade in the column."""
    return 1.0 if result.points_possible is None else result.points_possible / result.maximum


def _select_submissions(
    zip_path: Path, gradebook: Gradebook, spec: dict, result: CanvasResult
) -> dict[int, SubmissionFile]:
    """For each student of the gradebook with a notebook in the zip, the one file to grade."""
    with open_zip(zip_path) as zf:
        entries = safe_zip_entries(zf)
    by_user: dict[int, list[SubmissionFile]] = {}
    kept = [info for info in entries if not is_os_metadata(info.filename)]
    if len(kept) < len(entries):
        result.notes.append(
            f"{len(entries) - len(kept)} files the operating system added to the zip (__MACOSX/, ._ copies, "
            ".DS_Store) skipped"
        )
    for info in kept:
        f = parse_submission_name(info.filename)
        if f is None:
            result.unmatched.append(f"{info.filename}: not named as Canvas names submissions")
        elif f.user_id is None:
            result.unmatched.append(
                f"{info.filename}: anonymous grading hides the student; "
                "grade it by hand or download the zip after the names are shown"
            )
        elif f.user_id not in gradebook.student_rows:
            result.unmatched.append(f"{info.filename}: no student with ID {f.user_id} in the gradebook")
        else:
            by_user.setdefault(f.user_id, []).append(f)
    chosen = {}
    stem = notebook_stem(spec)
    for user, files in by_user.items():
        pick = choose_notebook(files, stem, spec["problem"])
        who = gradebook.student_name(user)
        for f in files:
            if f is not pick:
                why = "a notebook" if f.is_notebook else "not a notebook"
                result.not_graded.append(f"{who}: {f.entry} ({why}; not the file graded for {spec['problem']})")
        if pick is None:
            result.missing.append(f"{who} (ID {user}): no notebook in the zip; left out of the import")
            continue
        other = other_problem(pick.base_name, spec["problem"])
        if other:
            result.missing.append(
                f"{who} (ID {user}): {pick.original} is {other}'s notebook, not {stem}.ipynb; left out of the "
                f"import (grade that zip with --problem {other}, or this one by hand)"
            )
            continue
        chosen[user] = pick
        others = [  # the work may be in one (an Untitled.ipynb beside the blank hand-out), not another Problem's
            f.original
            for f in files
            if f.is_notebook
            and plain(f.base_name) != plain(pick.base_name)
            and not other_problem(f.base_name, spec["problem"])
        ]
        if others:
            result.others[user] = others
        if pick.late:
            result.late.append(f"{who}: {pick.entry}")
        if pick.resubmission:
            result.resubmissions.append(f"{who}: {pick.original} (Canvas's name for a re-upload of {pick.base_name})")
        if plain(stem) not in plain(pick.base_name):
            result.notes.append(f"{who}: graded {pick.original}, whose name differs from {stem}.ipynb")
        if pick.name and unicodedata.normalize("NFC", pick.name) != _zip_name(gradebook.student_name(user)):
            result.notes.append(
                f"{who}: the file is named after {pick.name!r}, not this student (a group "
                "submission?); the grade is written for this student only"
            )
    for user in gradebook.student_rows:
        if user not in by_user:
            result.missing.append(
                f"{gradebook.student_name(user)} (ID {user}): nothing in the zip; left out of the import"
            )
    return chosen


def _zip_name(sortable_name: str) -> str:
    """The name part Canvas gives a student's files: lower case, word characters only."""
    name = unicodedata.normalize("NFC", sortable_name.removeprefix('="').removesuffix('"').lower())
    return re.sub(r"\W", "", re.sub(r"_(\d+)_", r"\1", name))


def _grade(
    zip_path: Path, chosen: dict[int, SubmissionFile], spec_path: Path, out: Path, result: CanvasResult, grade: GradeFn
) -> dict[int, dict]:
    """Unpack the chosen notebooks into a private folder, grade them, and key the rows by user id.
    With none to grade, an earlier batch's results in ``OUT/batch`` are moved into its
    ``previous/`` with its feedback, so that none of it stands beside this run's import."""
    if not chosen:
        _retire_batch(out / "batch")
        return {}
    folder = Path(tempfile.mkdtemp(prefix="canvas-submissions-"))  # mode 0700: private
    try:
        files = {}
        with open_zip(zip_path) as zf:
            infos = {info.filename: info for info in safe_zip_entries(zf)}
            for user, f in sorted(chosen.items()):
                data, why = read_notebook_entry(zf, infos[f.entry])
                if why:
                    result.not_scored.append(f"{f.entry}: {why}, not graded")
                    continue
                name = f"{f.name or 'student'}_{user}.ipynb"
                (folder / name).write_bytes(data)
                files[name] = user
        if files:
            rows = grade(folder, spec_path, out / "batch")
        else:
            rows = []
            _retire_batch(out / "batch")
    finally:
        shutil.rmtree(folder, ignore_errors=True)
    by_user = {}
    for row in rows:
        user = files.get(row.get("file"))
        if user is None:
            result.notes.append(f"the grader returned a row for {row.get('file')!r}, which it was not given")
        else:
            by_user[user] = row
    for user in files.values():
        if user not in by_user:
            result.not_scored.append(f"{chosen[user].entry}: the grader returned no row for it; left out of the import")
    return by_user


def _retire_batch(folder: Path) -> None:
    """Move an earlier batch's results in ``folder``, its feedback files included, into
    ``folder/previous/`` (a run with nothing to grade writes no batch of its own)."""
    if folder.is_dir():
        keep_previous(folder, BATCH_RESULTS, feedback="feedback")


def _record_scores(
    gradebook: Gradebook,
    col: int,
    spec: dict,
    chosen: dict[int, SubmissionFile],
    rows: dict[int, dict],
    out: Path,
    result: CanvasResult,
) -> None:
    """Turn each graded row into its cell and its feedback file; say which cells were left alone."""
    (out / "feedback").mkdir(parents=True, exist_ok=True)
    for user, row in sorted(rows.items()):
        f, who = chosen[user], gradebook.student_name(user)
        total = sum(float(row["scores"].get(c["name"], 0.0)) for c in spec["checks"])
        score = format_score(scaled_score(total, result.maximum, result.points_possible))
        previous = gradebook.cell(user, col).strip()
        if previous.upper() in ("EX", "N/A"):  # excused: no grade, and no feedback that says one
            result.excused.append(f"{who}: {f.entry}: {excused_note(previous, row, score, result)}")
            continue
        path = out / "feedback" / f"{f.prefix}_feedback.txt"
        path.write_text(feedback_text(who, f, spec, row, total, score, result), encoding="utf-8")
        result.feedback[user] = path
        if row.get("status") not in SCORED_STATUSES:
            reason = "; ".join(row.get("notes", [])[:1])
            result.not_scored.append(
                f"{who}: {f.original}: {row.get('status')} ({reason}); left out of the import: grade again or by hand"
            )
            continue
        if row.get("status") == "unreadable":
            reason = "; ".join(row.get("notes", [])[:1]) or "no reason given"
            result.unreadable.append(f"{who}: {f.original}: {reason}")
        for note in row.get("notes", []):  # Problem 2's work under Problem 1's file name, say
            if OTHER_PROBLEM_MARK in note:
                result.notes.append(f"{who}: {f.original}: {note}")
        if user in result.others and total < result.maximum:
            result.notes.append(
                f"{who}: {f.original} scored {score}, and the student also handed in "
                f"{', '.join(result.others[user])}, not graded: look at it in case the work is there"
            )
        if previous and previous not in ("-", score) and decimal_point(previous) != score:
            result.replaced.append(f"{who}: replaces the grade {previous} already in Canvas with {score}")
        result.scores[user] = score


def excused_note(cell: str, row: dict, score: str, result: CanvasResult) -> str:
    """What the report says of an excused student's graded notebook: that the cell is left as it
    is, and, for the instructor alone, what the notebook earned (or that its grading gave no score)."""
    if row.get("status") in SCORED_STATUSES:
        out_of = result.points_possible if result.points_possible is not None else result.maximum
        earned = f"the notebook earned {score} / {format_score(out_of)}, should you lift the excuse"
    else:
        earned = f"its grading gave no score ({row.get('status')})"
    return f"the cell says {cell} in Canvas and is left so, out of the import and without feedback; {earned}"


def feedback_text(
    who: str, f: SubmissionFile, spec: dict, row: dict, total: float, score: str, result: CanvasResult
) -> str:
    """One student's feedback: the score in Canvas's points, then each check's points and message,
    in the column's points too (:func:`rubric_scale`, as ``rubric_canvas.csv``): what the rubric
    students see says a check is worth is what their feedback says it is worth."""
    lines = [
        f"{FEEDBACK_HEADER}{problem_title(spec['problem'])} for {clean_text(who)}",
        f"File graded: {clean_text(f.original)}" + ("  (late)" if f.late else ""),
        "",
    ]
    if others := result.others.get(f.user_id):
        lines[-1:-1] = [
            f"Also handed in, not graded: {clean_text(', '.join(others))}. One notebook is graded per Problem, "
            "the one named after it; if your work is in another, tell your instructor."
        ]
    if row.get("status") in SCORED_STATUSES:
        out_of = result.points_possible if result.points_possible is not None else result.maximum
        lines.append(f"Score: {score} / {format_score(out_of)}")
        if score != format_score(total):
            lines.append(f"  ({format_score(total)} of the checks' {format_score(result.maximum)} points, scaled)")
    else:
        lines.append(f"Not scored: {row.get('status')}; your instructor will grade it again.")
    lines.append("")
    scale = rubric_scale(result)
    got = [row["scores"].get(c["name"]) for c in spec["checks"]]
    if None not in got and row.get("status") in SCORED_STATUSES:  # adding up to the score above
        got = apportion([float(g) * scale for g in got], float(score))
    for c, earned, most in zip(spec["checks"], got, full_marks(spec, scale), strict=True):  # rubric's full marks
        shown = "-" if earned is None else format_score(float(earned))
        message = clean_text(row.get("messages", {}).get(c["name"], "not graded"))
        lines.append(f"- {c['name']} ({shown} / {format_score(most)}): {message}")
    return "\n".join(lines + notes_block(row, spec)) + "\n"


def _write_feedback_zip(out: Path, result: CanvasResult) -> None:
    """``OUT/feedback_upload.zip``: the feedback files, for the assignment's Re-upload Submissions."""
    with zipfile.ZipFile(out / "feedback_upload.zip", "w", zipfile.ZIP_DEFLATED) as zf:
        for path in sorted(result.feedback.values()):
            zf.write(path, path.name)


def report_text(gradebook: Gradebook, spec: dict, result: CanvasResult) -> str:
    """The plain-text report: the column written, then each list of what needs a look, the
    grades in Canvas that the import replaces first."""
    out_of = format_score(result.points_possible) if result.points_possible is not None else "?"
    lines = [
        f"Canvas grading report: {spec['problem']}",
        f"Column: {result.column} (points possible {out_of})",
        f"Students in the gradebook: {len(gradebook.student_rows)}; scores written: {len(result.scores)}",
        "",
    ]
    if result.warning:
        lines[2:2] = [result.warning]
    sections = [
        ("Grades already in Canvas that this import replaces", result.replaced),
        ("Files that match no student of the gradebook (not graded)", result.unmatched),
        ("Students with nothing graded (left out of the import: Canvas keeps what it holds)", result.missing),
        ("Graded but not scored (left out of the import: Canvas keeps what it holds)", result.not_scored),
        ("Excused in Canvas (graded, but left excused: out of the import, no feedback)", result.excused),
        ("Unreadable files (scored 0: ask the student for a notebook that opens, then grade again)", result.unreadable),
        ("Late submissions (graded; any late penalty is yours to apply)", result.late),
        ("Resubmissions graded (Canvas renames a re-uploaded file name-1, name-2, ...)", result.resubmissions),
        ("Other files of students, not graded", result.not_graded),
        ("Notes", result.notes),
    ]
    for title, items in sections:
        lines.append(f"{title}: {len(items) if items else 'none'}")
        lines += [f"  - {clean_text(item)}" for item in items]
        lines.append("")
    lines += [
        "Next, in Canvas: Grades -> Import -> gradebook_import.csv; then, on the assignment's page,",
        "Re-upload Submissions -> feedback_upload.zip attaches each student's feedback file as a comment.",
    ]
    return "\n".join(lines) + "\n"


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(
        prog="python -m labsupport.instructor.canvas",
        description="Grade a Canvas 'Download Submissions' zip into a Canvas gradebook export, ready to import.",
    )
    parser.add_argument("submissions", type=Path, help="the zip that Canvas's Download Submissions gives")
    problem_arguments(parser)
    parser.add_argument("--gradebook", type=Path, required=True, help="the CSV that Canvas's Grades -> Export gives")
    parser.add_argument("--column", help='the assignment column to fill, e.g. "Problem 1 (12345)" or 12345')
    parser.add_argument(
        "--out", type=Path, required=True, help="folder for gradebook_import.csv, feedback/, report.txt"
    )
    grading_arguments(parser)
    parser.add_argument(
        "--seed",
        type=seed_argument,
        default=None,
        help="seed of the test states (default: a fresh secret one; OUT/batch/batch.json records it)",
    )
    compare_with_argument(parser)
    args = parser.parse_args(argv)
    check_compare_with(parser, args.compare_with, Path(args.submissions))
    spec = chosen_spec(parser, args)
    check_grading_arguments(parser, args)
    if args.submissions.is_dir():
        parser.error(
            f"{args.submissions} is a folder: give the zip as Canvas gives it (the assignment's Download "
            "Submissions), not unzipped; files unzipped from it can be zipped again, with their names as they are. "
            "For a folder of notebooks without Canvas's names, run python -m labsupport.instructor.batch"
        )
    if args.gradebook.is_dir():
        parser.error(f"--gradebook {args.gradebook} is a folder: give the CSV file Canvas's Grades -> Export gives")
    for path, what in ((args.submissions, "submissions zip"), (args.gradebook, "gradebook")):
        if not Path(path).is_file():
            parser.error(f"no {what} at {path}")
    try:
        result = grade_canvas(
            args.submissions,
            args.gradebook,
            spec,
            args.out,
            args.column,
            args.jobs,
            seed=args.seed,
            compare_with=args.compare_with,
            timeout=args.timeout,
        )
    except ValueError as err:
        parser.error(str(err))
    except isolation.SandboxUnavailable as err:  # as the batch says it: what to do, no traceback
        parser.exit(2, f"{parser.prog}: cannot grade: {err}\n")
    if result.warning:
        print(result.warning)
    print(
        f"{counted(len(result.scores), 'score')} written to {args.out / 'gradebook_import.csv'} "
        f"({result.column}); {counted(len(result.unmatched), 'unmatched file')}, "
        f"{counted(len(result.missing), 'student')} with nothing graded: see {args.out / 'report.txt'}"
    )
    if result.moved:
        print(result.moved)


if __name__ == "__main__":
    keep_private()
    main()
