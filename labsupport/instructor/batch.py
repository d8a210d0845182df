"""Grade a folder of student notebooks: one CSV row per file, one feedback file per student.

The grader runs each notebook's code cells from their source and ignores stored outputs: the
notebooks need not be executed.

Usage (from the repository root)::

    .venv/bin/python -m labsupport.instructor.batch --problem problem1 SUBMISSIONS --out grades/problem1

``--problem NAME`` reads the autograder spec ``tests/autograder/NAME.json`` (or give
``--spec PATH``). Every ``*.ipynb`` in SUBMISSIONS (``.IPYNB`` too: any case) gets a row in
``OUT/grades.csv`` (a score per check, the total, a status, a reason and the row's feedback
file) and a ``OUT/feedback/<file>.txt`` (the file's name less ``.ipynb``), whatever the file
does (an empty one is "unreadable", with a reason saying to ask for it again); the other files
and the subfolders are named on stderr, left aside and listed in ``OUT/batch.json`` (a
subfolder holding notebooks says how many).
``OUT/batch.json`` also records the seed, the spec, the date and the versions, so that
``--seed`` reproduces every grade; ``OUT/rubric.md`` says how each check scores and what
partial credit each mistake it names keeps (``OUT/rubric_canvas.csv``: the same, for Canvas);
``OUT/similarity.csv`` and ``OUT/similarity.html`` list the notebooks that share code with each
other or with the master's solution (:mod:`labsupport.instructor.similarity`).
A row whose grading failed ("error") or ran out of wall-clock time ("timed out: regrade") gets
no score, never a zero. Every message is written on one line, without control characters
(student code writes into them); the files are the owner's alone when run as a command, and
an earlier batch's results in OUT, its feedback files included, move into ``OUT/previous/``.

How a submission is isolated:

* its bytes are read once, up front; it never runs where it was read from;
* its cells run in a bubblewrap sandbox of its own (:mod:`labsupport.instructor.isolation`):
  own PID namespace (everything it starts dies with it), no network, a private scratch space,
  a read-only view of the interpreter and of labsupport as a student installs it, and nothing
  else: not the checkout, the submissions, the output folder or the grader;
* the checks run outside, in the grader's processes (:mod:`labsupport.instructor.judge`), with
  test states drawn from a seed the sandbox never sees: fresh and secret for each batch unless
  ``--seed`` is given;
* the limits that decide a score count CPU time and idle waiting, never wall time, so a busy
  machine cannot change a score; a generous wall-clock backstop marks a row "timed out:
  regrade" instead of scoring it;
* the output folder is checked before anything is graded; results are kept in memory and
  written at the end, atomically.

Where bubblewrap cannot run the grader refuses, saying what to do; ``--unsafe-no-sandbox``
grades without isolation (for submissions you trust) and says so in every row.
"""

from __future__ import annotations

import argparse
import csv
import datetime
import hashlib
import io
import json
import multiprocessing
import os
import re
import secrets
import subprocess
import sys
import tempfile
import time
from concurrent.futures import ProcessPoolExecutor
from functools import partial
from pathlib import Path

import mujoco

import labsupport
from labsupport.grading import registry
from labsupport.instructor import isolation, judge, similarity
from labsupport.instructor.assign import chosen_spec, load_spec, problem_arguments, seed_argument
from labsupport.instructor.outputs import (
    BATCH_RESULTS,
    FEEDBACK_HEADER,
    clean_text,
    counted,
    csv_cell,
    keep_previous,
    keep_private,
    problem_title,
)
from labsupport.instructor.rubric import canvas_rubric_csv, rubric
from labsupport.instructor.submissions import held, is_os_metadata, is_zip, open_zip, safe_zip_entries, zip_notebooks

#: The note every row carries when the batch ran without a sandbox.
UNSAFE_NOTE = "graded WITHOUT a sandbox (--unsafe-no-sandbox): only for submissions you trust"
#: Statuses of rows that carry no score (the grader failed, or the wall-clock backstop ran out):
#: their score cells stay blank, never 0, and their feedback says the score is not recorded.
UNSCORED = ("error", judge.REGRADE)
#: The reason of an empty (0-byte) file's row: an upload that went wrong, not a notebook's fault.
EMPTY_FILE = "the file is empty (0 bytes): the upload went wrong, and the notebook must be uploaded again"


def new_seed() -> int:
    """A fresh secret seed for a batch's test states."""
    return secrets.randbits(48)


#: Seeds below this one can be guessed: a notebook can store its answers for each of them (for
#: every seed up to a few thousand they fit in one notebook), as it cannot for a fresh 48-bit one.
GUESSABLE_SEEDS = 2**32


def guessable_seed_warning(seed: int | None) -> str:
    """The warning for a ``--seed`` a student could guess, or ``""``: such a seed is for
    reproducing a batch graded with it, never for grading new work."""
    if seed is None or seed >= GUESSABLE_SEEDS:
        return ""
    return (
        f"warning: --seed {seed} is a seed a notebook could have stored its answers for (a small number, "
        "a date): use --seed only to reproduce a batch graded with it. To grade new submissions, leave "
        "--seed out: each batch then draws a fresh secret seed (batch.json records it)"
    )


def is_notebook(path: Path) -> bool:
    """Whether ``path`` is a file named as a notebook: ``.ipynb`` in any case (``.IPYNB`` too); a
    folder so named is not one (it is left aside as a folder)."""
    return path.name.lower().endswith(".ipynb") and path.is_file()


def list_notebooks(folder: Path) -> list[Path]:
    """The notebooks at the top of ``folder``, sorted."""
    return [p for p in sorted(Path(folder).iterdir()) if is_notebook(p)]


def left_aside(folder: Path) -> list[str]:
    """Every other entry at the top of ``folder``, sorted: a file by its name, a subfolder with a
    ``/`` and, when it holds notebooks, how many and what to do about them."""
    aside = []
    for p in sorted(Path(folder).iterdir()):
        if not p.is_dir():
            if not is_notebook(p):
                aside.append(p.name)
            continue
        nested = sum(1 for q in p.rglob("*") if is_notebook(q))
        held = f"{nested} notebook{'s' if nested != 1 else ''}"
        aside.append(p.name + "/" + (f" (holds {held}: grade that folder, or move them up)" if nested else ""))
    return aside


def feedback_text(name: str, spec: dict, row: dict) -> str:
    """The feedback file of one student: total, then each check's score and message, then notes."""
    lines = [f"{FEEDBACK_HEADER}{clean_text(name)} ({problem_title(spec['problem'])})", ""]
    maximum = sum(float(c["points"]) for c in spec["checks"])
    if row["status"] in UNSCORED:
        lines.append(f"Score: not recorded / {maximum:g}   (status: {row['status']})")
    else:
        total = sum(row["scores"].get(c["name"], 0.0) for c in spec["checks"])
        lines.append(f"Score: {total:g} / {maximum:g}   (status: {row['status']})")
    lines.append("")
    for c in spec["checks"]:
        msg = row["messages"].get(c["name"], "not graded: " + "; ".join(row["notes"][:1]))
        got = row["scores"].get(c["name"])
        lines.append(
            f"- {c['name']} ({'-' if got is None else f'{got:g}'} / {float(c['points']):g}): {clean_text(msg)}"
        )
    return "\n".join(lines + notes_block(row, spec)) + "\n"


#: Said once under a feedback that names a cell by its number: Jupyter and Colab show none.
CELL_COUNTING = "(Cells are counted from the top of the notebook, Markdown cells too, and named by their first line.)"
_NAMED_CELL = re.compile(r"\bcell \d+ \(")


def notes_block(row: dict, spec: dict) -> list[str]:
    """The lines that end a feedback file: the row's notes that belong to no check (a note that
    starts with a check's name, ``"p1_ik: ..."``, is that check's, and its message says it), under
    a "Notes:" heading, and :data:`CELL_COUNTING` where a note or a message names a cell by its
    number; none when there is neither."""
    notes = [n for n in row.get("notes", []) if not any(n.startswith(c["name"] + ":") for c in spec["checks"])]
    lines = ["", "Notes:"] + [f"- {clean_text(n)}" for n in notes] if notes else []
    said = [*row.get("notes", []), *row.get("messages", {}).values()]
    if any(isinstance(text, str) and _NAMED_CELL.search(text) for text in said):
        lines += ["", CELL_COUNTING]
    return lines


def _grade_row(payload, spec: dict, seed: int, layout, unsafe_root, budget: judge.Budget) -> dict:
    """Grade one submission (runs in a worker process of the pool); always returns a row."""
    name, data, read_error = payload
    t0 = time.monotonic()
    if read_error is not None:
        row = judge.unreadable_row([c["name"] for c in spec["checks"]], read_error)
    else:
        if layout is not None:
            limits = layout.limits

            def start():
                return isolation.server_command(layout), {}, "/"
        else:
            limits = isolation.DEFAULT_LIMITS

            def start():
                cmd, env, scratch = isolation.unsafe_command(unsafe_root)
                return cmd, env, scratch

        try:
            row = judge.grade(spec, data, seed, start, budget, limits)
        except Exception as err:  # the row must exist whatever happened
            row = {"status": "error", "scores": {}, "messages": {}, "notes": [f"the grader failed: {err}"]}
    if layout is None:
        row["notes"].append(UNSAFE_NOTE)
    row["file"], row["seconds"] = name, round(time.monotonic() - t0, 1)
    return row


def check_out_outside(out: Path, submissions: Path) -> None:
    """``ValueError`` where the output folder ``out`` lies inside the folder of submissions."""
    if Path(out).resolve().is_relative_to(Path(submissions).resolve()):
        raise ValueError(
            f"the output folder {out} is inside the submissions folder {submissions}: the next batch would find the "
            "reports among the submissions (and a zip of the folder would carry them). Give --out a folder outside it"
        )


def run_batch(
    submissions: Path,
    spec_path: Path,
    out: Path,
    jobs: int | None = None,
    timeout: float = 900.0,
    seed: int | None = None,
    unsafe_no_sandbox: bool = False,
    budget: judge.Budget | None = None,
    compare_with: list[Path] | None = None,
) -> list[dict]:
    """Grade every notebook in ``submissions``; writes ``out/grades.csv``, ``out/feedback/`` and
    ``out/batch.json``.

    Args:
        timeout: wall-clock backstop per submission [s]; past it the row is "timed out: regrade".
        seed: the test states' seed (default: a fresh secret one, recorded in ``batch.json``).
        unsafe_no_sandbox: grade without bubblewrap (trusted submissions only; every row says so).
        budget: the CPU and idle limits (default :class:`labsupport.instructor.judge.Budget`).
        compare_with: folders of earlier notebooks (last year's, say) that the shared-code report
            compares the submissions with; they are not graded.

    Raises:
        ValueError: ``submissions`` is not a folder, ``seed`` is negative, or ``out`` cannot be
            written (checked before grading).
        isolation.SandboxUnavailable: bubblewrap cannot run here (the message says what to do).
    """
    if seed is not None and seed < 0:
        raise ValueError(f"the seed must be a whole number, 0 or more; got --seed {seed}")
    spec_path = Path(spec_path).resolve()
    spec = load_spec(spec_path)
    if not Path(submissions).exists():
        raise ValueError(f"submissions must be a folder of .ipynb files; {submissions} does not exist")
    if not Path(submissions).is_dir():
        raise ValueError(f"submissions must be a folder of .ipynb files; {submissions} is not a folder")
    check_out_outside(out, submissions)
    files, aside = list_notebooks(submissions), left_aside(submissions)
    if aside:  # nothing is left aside unsaid
        print("not graded (not .ipynb files): " + clean_text(", ".join(aside)), file=sys.stderr)
    # read everything first: nothing a submission does later can lose another one
    payloads = read_submissions(files)
    for same in identical_files(payloads):  # one student's file twice, most often: the report would pair it
        print(
            f"the same file, byte for byte: {clean_text(', '.join(same))} (one student's file twice, or a copy); "
            "each is graded, and similarity.html pairs them",
            file=sys.stderr,
        )
    seed = new_seed() if seed is None else int(seed)
    registry()  # the checks are loaded once, before the workers fork: every row uses the same code
    budget = budget or judge.Budget(wall=timeout)
    if budget.wall != timeout:
        budget = judge.Budget(**{**budget.__dict__, "wall": timeout})
    jobs = max(1, jobs or os.cpu_count() or 1)
    start = time.monotonic()
    with tempfile.TemporaryDirectory(prefix="grading-") as tmp:
        tmp = Path(tmp)
        os.chmod(tmp, 0o700)
        if unsafe_no_sandbox:
            layout, unsafe_root, sandbox = None, isolation.prepare_unsafe(tmp), "none (--unsafe-no-sandbox)"
            print("WARNING: " + UNSAFE_NOTE, file=sys.stderr)
        else:
            layout, unsafe_root = isolation.prepare(tmp), None
            sandbox = subprocess.run([layout.bwrap, "--version"], capture_output=True, text=True).stdout.strip()
        prepare_output(Path(out))
        task = partial(_grade_row, spec=spec, seed=seed, layout=layout, unsafe_root=unsafe_root, budget=budget)
        rows = []
        context = multiprocessing.get_context("fork")
        with ProcessPoolExecutor(max_workers=jobs, mp_context=context) as pool:
            for row in pool.map(task, payloads):
                rows.append(row)
                print(f"graded {clean_text(row['file'])}: {row['status']} in {row['seconds']:g} s", flush=True)
    elapsed = time.monotonic() - start
    record = {
        "problem": spec["problem"],
        "seed": seed,
        "spec": str(spec_path),
        "spec_sha256": _sha256(spec_path),
        "date": datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds"),
        "labsupport": _version(),
        "python": sys.version.split()[0],
        "mujoco": _mujoco_version(),
        "sandbox": sandbox,
        "jobs": jobs,
        "submissions": len(rows),
        "left_aside": aside,
        "seconds": round(elapsed, 1),
        "reproduce": f"--seed {seed}",
    }
    try:  # a lead for the instructor: nothing in it may cost the grades
        shared = shared_code_reports(payloads, spec, compare_with or [])
    except Exception as err:
        shared = {}
        print(f"the shared-code report was not written: {clean_text(str(err))}", file=sys.stderr)
    _write_results(out, spec, rows, record, shared)
    at_once = min(jobs, len(rows))
    print(
        f"{counted(len(rows), 'submission')} graded in {elapsed:.1f} s"
        + (f", {at_once} at once" if at_once > 1 else "")
        + f" (seed {seed}); see {Path(out) / 'grades.csv'}"
        + (
            f"; pairs sharing code: {similarity.pairs_listed(shared)}, in {Path(out) / 'similarity.html'}"
            if shared
            else ""
        )
    )
    return rows


def payload(name: str, data: bytes) -> tuple[str, bytes | None, str | None]:
    """A submission as the graders pass it on: its name, bytes and ``None``; or, for an empty
    file, its name, ``None`` and why it cannot be graded."""
    return (name, data, None) if data else (name, None, EMPTY_FILE)


def read_submissions(files: list[Path]) -> list[tuple[str, bytes | None, str | None]]:
    """Each file as a :func:`payload` of its bytes (:func:`read_notebook`); or its name, ``None``
    and why it cannot be read."""
    payloads = []
    for p in files:
        try:
            payloads.append(payload(p.name, read_notebook(p)))
        except OSError as err:
            payloads.append((p.name, None, f"could not read the file: {err.strerror}"))
    return payloads


def identical_files(payloads: list[tuple[str, bytes | None, str | None]]) -> list[list[str]]:
    """The names of the files whose bytes are the same, in groups of two or more."""
    by_content: dict[str, list[str]] = {}
    for name, data, _ in payloads:
        if data:
            by_content.setdefault(hashlib.sha256(data).hexdigest(), []).append(name)
    return [names for names in by_content.values() if len(names) > 1]


def shared_code_reports(
    payloads: list[tuple[str, bytes | None, str | None]],
    spec: dict,
    compare_with: list[Path],
    flag: float = similarity.FLAG_SHARE,
) -> dict[str, str]:
    """``similarity.csv`` and ``similarity.html`` (by file name) for the submissions read by
    :func:`read_submissions`, compared with each other, with the master's solution and with the
    notebooks of the ``compare_with`` folders and zips
    (:func:`labsupport.instructor.similarity.similarity_reports`)."""
    submitted = {name: data for name, data, _ in payloads if data}
    return similarity.similarity_reports(submitted, spec, earlier_notebooks(compare_with, spec), flag)


def read_notebook(path: Path) -> bytes:
    """The notebook at ``path`` as the grader holds it
    (:func:`labsupport.instructor.submissions.held`)."""
    return held(path.read_bytes())


def earlier_notebooks(folders: list[Path], spec: dict) -> dict[str, bytes]:
    """The notebooks at the top of each of ``folders``, or in each zip among them (a Canvas
    download: each student's notebook for the Problem of ``spec``,
    :func:`labsupport.instructor.submissions.zip_notebooks`), by ``<folder or zip name>/<file name>``
    (the path as given where two share a name), for the shared-code report; one that cannot be
    read is named on stderr and left out."""
    notebooks = {}
    for folder in folders:
        if is_zip(folder):
            found, left_out = zip_notebooks(folder, spec)
            for entry in left_out:
                print(f"not compared: {clean_text(f'{folder}/{entry}')}", file=sys.stderr)
        else:
            found, left_out = {}, []
            for path in list_notebooks(folder):
                try:
                    found[path.name] = read_notebook(path)
                except OSError as err:
                    print(f"not compared: {clean_text(str(path))} ({err.strerror})", file=sys.stderr)
        for entry, data in found.items():
            name = f"{folder.name}/{entry}"
            notebooks[f"{folder}/{entry}" if name in notebooks else name] = data
    return notebooks


def _sha256(path: Path) -> str:
    return hashlib.sha256(Path(path).read_bytes()).hexdigest()


def _version() -> str:
    return labsupport.__version__


def _mujoco_version() -> str:
    return mujoco.__version__


def prepare_output(out: Path) -> None:
    """Create ``out`` and ``out/feedback`` and make sure files can be written in them, before
    anything is graded: the results are written at the end, and would be lost then.

    Raises:
        ValueError: the folder cannot be created or written (the message says why).
    """
    try:
        (out / "feedback").mkdir(parents=True, exist_ok=True)
        for folder in (out, out / "feedback"):
            with tempfile.NamedTemporaryFile(dir=folder, prefix=".write-test-"):
                pass
    except OSError as err:
        raise ValueError(
            f"cannot write the output folder {out} ({err.strerror or err}): give --out a folder you can write to"
        ) from None


def grades_csv(spec: dict, rows: list[dict], seed: int, feedback: dict[str, str]) -> str:
    """The text of ``grades.csv``: a row per submission, ending with its feedback file (from
    ``feedback``, :func:`feedback_names`); an unscored row's score cells are blank."""
    names = [c["name"] for c in spec["checks"]]
    maximum = sum(float(c["points"]) for c in spec["checks"])
    buf = io.StringIO()
    writer = csv.writer(buf, lineterminator="\n")
    writer.writerow(["file", "problem", *names, "total", "max", "status", "reason", "seed", "feedback"])
    for row in rows:
        reason = "; ".join(clean_text(n) for n in row["notes"]) if row["notes"] else "all checks passed"
        if row["status"] in UNSCORED:  # no score at all, rather than a zero
            cells = [""] * len(names) + [""]
        else:
            scores = [row["scores"].get(n, 0.0) for n in names]
            cells = [f"{s:g}" for s in scores] + [f"{sum(scores):g}"]
        file, status = csv_cell(row["file"]), row["status"]
        writer.writerow([file, spec["problem"], *cells, f"{maximum:g}", status, reason, seed, feedback[row["file"]]])
    return buf.getvalue()


def feedback_names(files: list[str]) -> dict[str, str]:
    """Each submission's feedback file name, ``<stem>.txt``, with ``_`` for any character that
    :func:`~labsupport.instructor.outputs.clean_text` would not write as it is (a line break, a
    control character); a stem already taken in any case (``a.ipynb`` and ``a.IPYNB``) gets
    ``<stem>-2.txt``, and so on: no feedback overwrites another."""
    names, taken = {}, set()
    for file in files:
        stem = "".join(c if clean_text(c) == c else "_" for c in Path(file).stem)
        name, k = f"{stem}.txt", 2
        while name.casefold() in taken:
            name, k = f"{stem}-{k}.txt", k + 1
        taken.add(name.casefold())
        names[file] = name
    return names


def _write_results(out: Path, spec: dict, rows: list[dict], record: dict, shared: dict[str, str]) -> None:
    """Write ``grades.csv``, a feedback file per row, ``batch.json``, the Problem's grading
    rubric (``rubric.md``, and ``rubric_canvas.csv`` for Canvas: :mod:`labsupport.instructor.rubric`)
    and the ``shared`` code reports (:mod:`labsupport.instructor.similarity`) into ``out``.
    An earlier batch's ``grades.csv``, ``batch.json`` (its seed), code reports and feedback move
    to ``out/previous/`` first, and what an even earlier one left there to ``previous/previous/``."""
    out = Path(out)
    keep_previous(out, BATCH_RESULTS, feedback="feedback")
    names = feedback_names([row["file"] for row in rows])
    atomic_write(
        out / "grades.csv", grades_csv(spec, rows, record["seed"], {f: f"feedback/{n}" for f, n in names.items()})
    )
    for row in rows:
        atomic_write(out / "feedback" / names[row["file"]], feedback_text(row["file"], spec, row))
    atomic_write(out / "batch.json", json.dumps(record, indent=2) + "\n")
    atomic_write(out / "rubric.md", rubric(spec))
    atomic_write(out / "rubric_canvas.csv", canvas_rubric_csv(spec))
    for name, text in shared.items():
        atomic_write(out / name, text)


def atomic_write(path: Path, text: str) -> None:
    """Write ``text`` to ``path`` whole or not at all (a file beside it, then renamed)."""
    tmp = path.with_name(path.name + ".tmp")
    tmp.write_text(text, encoding="utf-8")
    os.replace(tmp, path)


def check_submissions_folder(parser: argparse.ArgumentParser, folder: Path) -> None:
    """Stop with what to do when ``folder`` is a zip, or holds no notebook at its top level."""
    if is_zip(folder):
        parser.error(
            f"{folder} is a zip file: for Canvas's 'Download Submissions' zip run "
            "python -m labsupport.instructor.canvas (see the README); otherwise unzip it into a folder"
        )
    if folder.is_dir() and not any(is_notebook(p) for p in folder.iterdir()):
        nested = sum(1 for p in folder.rglob("*") if is_notebook(p))
        parser.error(
            f"no .ipynb file in {folder}"
            + (f"; its subfolders hold {nested}: give the folder that holds them" if nested else "")
        )


def compare_with_argument(parser: argparse.ArgumentParser) -> None:
    """``--compare-with FOLDER_OR_ZIP``, repeatable: earlier notebooks for the shared-code report."""
    parser.add_argument(
        "--compare-with",
        type=Path,
        action="append",
        default=[],
        metavar="FOLDER_OR_ZIP",
        help="a folder of earlier notebooks, or a zip of them such as last year's Canvas 'Download "
        "Submissions' zip, to compare the submissions with in similarity.html; they are not graded "
        "(repeat for several)",
    )


def check_compare_with(parser: argparse.ArgumentParser, folders: list[Path], submissions: Path | None) -> None:
    """Stop with what to do when a ``--compare-with`` folder or zip is missing, holds no notebook,
    cannot be read, or is the submissions themselves (whose notebooks are compared with each other
    already)."""
    for folder in folders:
        if is_zip(folder):
            try:
                with open_zip(folder) as zf:
                    entries = [i.filename for i in safe_zip_entries(zf) if not is_os_metadata(i.filename)]
            except ValueError as err:
                parser.error(f"--compare-with {folder}: {err}")
            if not any(entry.lower().endswith(".ipynb") for entry in entries):
                parser.error(f"--compare-with {folder}: the zip holds no .ipynb file")
        elif not folder.is_dir():
            why = "neither a folder nor a .zip file" if folder.exists() else "no such folder or zip"
            parser.error(f"--compare-with {folder}: {why}")
        elif not any(is_notebook(p) for p in folder.iterdir()):
            parser.error(f"--compare-with {folder}: no .ipynb file at its top level")
        if submissions is not None and folder.resolve() == submissions.resolve():
            parser.error(f"--compare-with {folder} is the submissions themselves: their notebooks are compared already")


def grading_arguments(parser: argparse.ArgumentParser) -> None:
    """``--jobs N`` and ``--timeout S``, the batch's and the Canvas command's alike
    (:func:`check_grading_arguments` checks them)."""
    parser.add_argument("--jobs", type=int, default=None, help="submissions graded at once (default: CPU count)")
    parser.add_argument(
        "--timeout",
        type=float,
        default=900.0,
        help="wall-clock backstop per submission [s] (default 900); a row past it is marked "
        "'timed out: regrade' and gets no score",
    )


def check_grading_arguments(parser: argparse.ArgumentParser, args: argparse.Namespace) -> None:
    """Stop with what to do when ``--jobs`` is below 1 or ``--timeout`` is not a positive number
    of seconds."""
    if args.jobs is not None and args.jobs < 1:
        parser.error(f"--jobs must be at least 1, got {args.jobs}")
    if not args.timeout > 0:
        parser.error(f"--timeout must be a positive number of seconds, got {args.timeout}")


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(
        prog="python -m labsupport.instructor.batch",
        description="Grade a folder of student notebooks into a CSV (outputs are ignored: they need not be executed).",
    )
    parser.add_argument("submissions", type=Path, help="folder holding the students' .ipynb files")
    problem_arguments(parser)
    parser.add_argument("--out", type=Path, required=True, help="folder for grades.csv, feedback/ and batch.json")
    grading_arguments(parser)
    parser.add_argument(
        "--seed",
        type=seed_argument,
        default=None,
        help="seed of the test states (default: a fresh secret one; batch.json records it)",
    )
    parser.add_argument(
        "--unsafe-no-sandbox",
        action="store_true",
        help="grade without bubblewrap: only for submissions you trust (every row says so)",
    )
    compare_with_argument(parser)
    args = parser.parse_args(argv)
    spec = chosen_spec(parser, args)
    check_grading_arguments(parser, args)
    check_submissions_folder(parser, args.submissions)
    check_compare_with(parser, args.compare_with, args.submissions)
    if warning := guessable_seed_warning(args.seed):
        print(warning, file=sys.stderr)
    try:
        run_batch(
            args.submissions,
            spec,
            args.out,
            args.jobs,
            args.timeout,
            seed=args.seed,
            unsafe_no_sandbox=args.unsafe_no_sandbox,
            compare_with=args.compare_with,
        )
    except (ValueError, isolation.SandboxUnavailable) as err:
        parser.exit(2, f"{parser.prog}: cannot grade: {err}\n")


if __name__ == "__main__":
    keep_private()
    main()
