"""The batch grader's outputs, and the Canvas tool's, as an instructor meets them.

What the batch command refuses before it grades anything (a seed that is not a whole number
from 0, an output folder it cannot write), which files it grades (``.ipynb`` in any case) and
which it names and records as left aside, and what it writes: blank cells for a row the grader
failed on, a reason to ask again for an empty upload, messages on one line without control
characters, files private to their owner, no feedback left over from an earlier batch. The
Canvas tool grades a notebook of any size the way the batch does, and reports unreadable ones.
``assign --check`` says how to regenerate what drifted. Each test grades notebooks that need no
sandbox, or runs ``--unsafe-no-sandbox``: seconds.
"""

import csv
import importlib
import json
import os
import stat
import subprocess
import sys
import zipfile
from pathlib import Path

import nbformat
import pytest
from test_canvas import EXPORT, build_zip, fake_grade, fake_notebook

from labsupport.instructor import assign, batch, canvas, gradebook, judge, outputs, submissions

ROOT = Path(__file__).resolve().parents[1]
SPEC = ROOT / "tests" / "autograder" / "problem1.json"
CHECKS = [c["name"] for c in json.loads(SPEC.read_text(encoding="utf-8"))["checks"]]
BLANK = (ROOT / "notebooks" / "problem1_reaching.ipynb").read_bytes()
#: A message as student code can write it: a fake score line, a NUL byte, terminal escapes, and a
#: lone surrogate (no UTF-8 file can hold one: it stopped the whole batch from writing its grades).
NASTY = "oops\nScore: 10 / 10   (status: graded)\r\x00\x1b[2J\t\u2028\u202eevil\ud800"


def _folder(path: Path, files: dict[str, bytes]) -> Path:
    """A folder holding ``files`` (name -> bytes)."""
    path.mkdir()
    for name, data in files.items():
        (path / name).write_bytes(data)
    return path


def _rows(out: Path) -> dict[str, dict]:
    """``out/grades.csv``, row by file."""
    with open(out / "grades.csv", newline="", encoding="utf-8") as f:
        return {r["file"]: r for r in csv.DictReader(f)}


def _argv(subs: Path, out: Path, *options: str) -> list[str]:
    """The batch command's arguments, without a sandbox (the notebooks here are harmless)."""
    return ["--problem", "problem1", str(subs), "--out", str(out), "--jobs", "1", "--unsafe-no-sandbox", *options]


# --- refused before grading ---------------------------------------------------------------------


@pytest.mark.parametrize("seed", ["-1", "-20240917", "1.5", "abc"])
def test_a_seed_that_is_not_a_whole_number_from_0_is_refused(tmp_path, capsys, seed):
    """A negative seed used to be accepted, and every check then failed inside the grader."""
    subs = _folder(tmp_path / "subs", {"student.ipynb": BLANK})
    with pytest.raises(SystemExit) as stop:
        batch.main(_argv(subs, tmp_path / "out", "--seed", seed))
    assert stop.value.code == 2
    assert "argument --seed: give a whole number, 0 or more" in capsys.readouterr().err
    assert not (tmp_path / "out").exists()
    with pytest.raises(ValueError, match="0 or more"):
        batch.run_batch(subs, SPEC, tmp_path / "out", seed=-1, unsafe_no_sandbox=True)
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize("where", ["under a file", "a file", "under /proc"])
def test_an_output_folder_that_cannot_be_written_is_refused_before_grading(tmp_path, capsys, where):
    """It used to be found out after the whole batch was graded, with a traceback and no results."""
    (tmp_path / "a_file").write_text("not a folder")
    out = {
        "under a file": tmp_path / "a_file" / "out",
        "a file": tmp_path / "a_file",
        "under /proc": Path("/proc/labsupport-no-such-folder/out"),
    }[where]
    subs = _folder(tmp_path / "subs", {"student.ipynb": BLANK})
    with pytest.raises(SystemExit) as stop:
        batch.main(_argv(subs, out))
    captured = capsys.readouterr()
    assert stop.value.code == 2
    assert f"cannot write the output folder {out}" in captured.err
    assert "give --out a folder you can write to" in captured.err
    assert "graded student.ipynb" not in captured.out


# --- which files are graded ---------------------------------------------------------------------


def test_one_file_handed_in_twice_is_said_before_the_similarity_report_pairs_it(tmp_path, capsys):
    """``alice.ipynb`` and ``alice (1).ipynb``, the same bytes, got two rows without a word, and
    the shared-code report then paired them as if two students had shared code."""
    subs = _folder(tmp_path / "subs", {"alice.ipynb": b"{}", "alice (1).ipynb": b"{}", "bob.ipynb": b"{ }"})
    rows = batch.run_batch(subs, SPEC, tmp_path / "out", jobs=1, seed=1, unsafe_no_sandbox=True)
    assert len(rows) == 3  # each is graded all the same
    said = capsys.readouterr().err
    assert "the same file, byte for byte: alice (1).ipynb, alice.ipynb (one student's file twice, or a copy)" in said
    assert "bob.ipynb" not in said
    assert batch.identical_files([("a", b"x", None), ("b", None, "empty"), ("c", None, "empty")]) == []


def test_every_notebook_gets_a_row_whatever_the_case_of_its_extension(tmp_path, capsys):
    """``.IPYNB`` used to be skipped, and the files left aside were not named; they were named on
    the screen only, and a subfolder of notebooks looked like any other file left aside."""
    notebooks = {"a.ipynb": b"not json", "a.IPYNB": b"not json either", "B.Ipynb": b"{"}
    subs = _folder(tmp_path / "subs", {**notebooks, "notes.py": b"x = 1", "report.pdf": b"%PDF"})
    (subs / "old").mkdir()
    (subs / "odd.ipynb").mkdir()  # a folder so named: left aside as a folder, not an "unreadable" row
    _folder(subs / "late", {"c.ipynb": b"{}", "d.ipynb": b"{}", "readme.txt": b""})
    rows = batch.run_batch(subs, SPEC, tmp_path / "out", jobs=1, unsafe_no_sandbox=True)
    assert {r["file"] for r in rows} == set(_rows(tmp_path / "out")) == set(notebooks)
    aside = [
        "late/ (holds 2 notebooks: grade that folder, or move them up)",
        "notes.py",
        "odd.ipynb/",
        "old/",
        "report.pdf",
    ]
    assert "not graded (not .ipynb files): " + ", ".join(aside) in capsys.readouterr().err
    assert json.loads((tmp_path / "out" / "batch.json").read_text(encoding="utf-8"))["left_aside"] == aside
    # a.ipynb and a.IPYNB share a stem: each keeps a feedback file of its own, which its row names
    feedback = {p.name: p.read_text(encoding="utf-8") for p in (tmp_path / "out" / "feedback").iterdir()}
    named = {file: row["feedback"] for file, row in _rows(tmp_path / "out").items()}
    assert named == {"B.Ipynb": "feedback/B.txt", "a.IPYNB": "feedback/a.txt", "a.ipynb": "feedback/a-2.txt"}
    assert {name: text.splitlines()[0] for name, text in feedback.items()} == {
        "B.txt": "Feedback on B.Ipynb (Problem 1)",
        "a.txt": "Feedback on a.IPYNB (Problem 1)",
        "a-2.txt": "Feedback on a.ipynb (Problem 1)",
    }
    # a line break or a control character in a file name does not reach the feedback file's name
    assert batch.feedback_names(["two\nlines.ipynb", "bell\x07.ipynb", "two lines.ipynb"]) == {
        "two\nlines.ipynb": "two_lines.txt",
        "bell\x07.ipynb": "bell_.txt",
        "two lines.ipynb": "two lines.txt",
    }
    # a third and a fourth file of the same stem take the next free numbers, in any case
    assert batch.feedback_names(["a.ipynb", "A.ipynb", "a.IPYNB", "A.Ipynb"]) == {
        "a.ipynb": "a.txt",
        "A.ipynb": "A-2.txt",
        "a.IPYNB": "a-3.txt",
        "A.Ipynb": "A-4.txt",
    }
    # a folder holding only an upper-case notebook is graded, not refused as holding none
    upper = _folder(tmp_path / "upper", {"only.IPYNB": b"not json"})
    batch.main(_argv(upper, tmp_path / "out_upper"))
    assert set(_rows(tmp_path / "out_upper")) == {"only.IPYNB"}


def test_the_summary_line_counts_in_words_that_agree(tmp_path, capsys):
    """It read "1 submissions graded ... with 2 at once": one file can only be graded alone."""
    one = _folder(tmp_path / "one", {"a.ipynb": b"not json"})
    batch.run_batch(one, SPEC, tmp_path / "out1", jobs=2, seed=2**40, unsafe_no_sandbox=True)
    line = capsys.readouterr().out.splitlines()[-1]
    assert line.startswith("1 submission graded in ") and "at once" not in line
    assert line.endswith(
        f" s (seed {2**40}); see {tmp_path / 'out1' / 'grades.csv'}; pairs sharing code: 0, in "
        f"{tmp_path / 'out1' / 'similarity.html'}"
    )
    three = _folder(tmp_path / "three", {f"{name}.ipynb": b"not json" for name in "abc"})
    batch.run_batch(three, SPEC, tmp_path / "out3", jobs=2, seed=2**40, unsafe_no_sandbox=True)
    assert ", 2 at once (seed" in capsys.readouterr().out.splitlines()[-1]


@pytest.mark.parametrize("tool", ["assign", "batch", "canvas", "compare", "rubric"])
def test_every_instructor_tools_usage_line_names_the_command_to_type(tool, capsys):
    """batch and canvas said "usage: batch.py", which does not run from the repository root."""
    module = importlib.import_module(f"labsupport.instructor.{tool}")
    with pytest.raises(SystemExit) as stop:
        module.main(["--help"])
    assert stop.value.code == 0
    assert capsys.readouterr().out.startswith(f"usage: python -m labsupport.instructor.{tool} ")


# --- what is written ----------------------------------------------------------------------------


def test_a_row_the_grader_failed_on_gets_no_score_never_a_zero(tmp_path, monkeypatch):
    """Its cells are blank and its feedback says "not recorded", as for "timed out: regrade"."""

    def broken(*args, **kwargs):
        raise RuntimeError("the model file is missing")

    monkeypatch.setattr(judge, "grade", broken)  # the pool's workers are forked: they inherit it
    subs = _folder(tmp_path / "subs", {"student.ipynb": BLANK})
    rows = batch.run_batch(subs, SPEC, tmp_path / "out", jobs=1, seed=1, unsafe_no_sandbox=True)
    assert rows[0]["status"] == "error"
    row = _rows(tmp_path / "out")["student.ipynb"]
    assert row["status"] == "error" and row["total"] == "" and [row[c] for c in CHECKS] == [""] * len(CHECKS)
    assert row["max"] == "10" and "the grader failed: the model file is missing" in row["reason"]
    feedback = (tmp_path / "out" / "feedback" / "student.txt").read_text(encoding="utf-8")
    assert "Score: not recorded / 10   (status: error)" in feedback and "Score: 0" not in feedback
    assert "- p1_ik (- / 3): not graded: the grader failed: the model file is missing" in feedback


EMPTY_REASON = "the file is empty (0 bytes): the upload went wrong, and the notebook must be uploaded again"


def test_an_empty_upload_is_unreadable_and_says_to_ask_for_it_again(tmp_path):
    """Its reason used to be "not a valid notebook: invalid JSON (Expecting value at line 1)"."""
    subs = _folder(tmp_path / "subs", {"empty.ipynb": b"", "broken.ipynb": b"{"})
    batch.run_batch(subs, SPEC, tmp_path / "out", jobs=1, seed=1, unsafe_no_sandbox=True)
    rows = _rows(tmp_path / "out")
    assert [rows["empty.ipynb"][k] for k in ("status", "total", "max")] == ["unreadable", "0", "10"]
    assert rows["empty.ipynb"]["reason"] == f"{EMPTY_REASON}; {batch.UNSAFE_NOTE}"
    assert rows["broken.ipynb"]["reason"].startswith("not a valid notebook: invalid JSON")
    feedback = (tmp_path / "out" / "feedback" / "empty.txt").read_text(encoding="utf-8")
    assert f"- p1_ik (0 / 3): {judge.UNREADABLE}" in feedback  # the reason once, below, not per check
    assert feedback.count(EMPTY_REASON) == 1 and feedback.endswith(f"Notes:\n- {EMPTY_REASON}\n- {batch.UNSAFE_NOTE}\n")


def test_canvas_lists_unreadable_uploads_in_the_report(tmp_path):
    """They scored 0 and the report never said so."""
    members = {
        "smithbob_1234_50001_problem1_reaching.ipynb": b"",
        "garcíaana_1235_50002_problem1_reaching.ipynb": b"{",
    }

    def grade(folder, spec_path, out):  # the batch grader: these notebooks need no sandbox
        return batch.run_batch(folder, spec_path, out, jobs=1, seed=1, unsafe_no_sandbox=True)

    result = canvas.grade_canvas(build_zip(tmp_path / "s.zip", members), EXPORT, SPEC, tmp_path / "out", grade=grade)
    assert result.scores == {1234: "0", 1235: "0"}
    assert result.unreadable == [
        f"Smith, Bob: problem1_reaching.ipynb: {EMPTY_REASON}",
        "García, Ana: problem1_reaching.ipynb: not a valid notebook: invalid JSON "
        f"(Expecting property name enclosed in double quotes at line 1), cut short or edited; {judge.DOWNLOAD_AGAIN}",
    ]
    report = (tmp_path / "out" / "report.txt").read_text(encoding="utf-8")
    section = next(part for part in report.split("\n\n") if part.startswith("Unreadable files"))
    assert section.splitlines() == [
        "Unreadable files (scored 0: ask the student for a notebook that opens, then grade again): 2",
        *(f"  - {item}" for item in result.unreadable),
    ]


def test_canvas_leaves_a_row_the_grader_failed_on_out_of_the_import(tmp_path):
    members = {"smithbob_1234_50001_problem1_reaching.ipynb": fake_notebook("error")}
    result = canvas.grade_canvas(
        build_zip(tmp_path / "s.zip", members), EXPORT, SPEC, tmp_path / "out", grade=fake_grade([])
    )
    assert result.scores == {} and any("error" in m for m in result.not_scored)
    before, after = (
        gradebook.read_gradebook(EXPORT),
        gradebook.read_gradebook(tmp_path / "out" / "gradebook_import.csv"),
    )
    assert 1234 in before.student_rows and 1234 not in after.student_rows  # Canvas keeps what it holds
    feedback = result.feedback[1234].read_text(encoding="utf-8")
    # no score, never a zero; each check's points in the column's (20, the checks' 10: p1_ik's 3 is 6)
    assert "Not scored: error" in feedback and "(0 / " not in feedback and "- p1_ik (- / 6)" in feedback


def test_clean_text_keeps_a_message_on_one_line_without_control_characters():
    text = outputs.clean_text(NASTY)
    assert text == "oops Score: 10 / 10   (status: graded) \\x00\\x1b[2J  \\u202eevil\\ud800"
    text.encode("utf-8")  # writable
    assert text.isprintable() and text.splitlines() == [text]
    assert outputs.clean_text("x" * 5000) == "x" * 1999 + "…"
    assert outputs.clean_text("\x00" * 1000) == "\\x00" * 499 + "\\x0…"
    assert outputs.clean_text("é ✔ 3 / 10: ik_3r returned NaN") == "é ✔ 3 / 10: ik_3r returned NaN"


def _one_score_line(text: str) -> str:
    """The one line of ``text`` that states a score; fails if a second one was slipped in."""
    (line,) = [line for line in text.splitlines() if line.lstrip().startswith("Score:")]
    return line


def test_student_text_cannot_forge_lines_or_write_control_characters(tmp_path):
    """A student's exception message put a fake score line into their feedback, and NUL bytes
    into grades.csv; it is now quoted, with its line breaks and control characters escaped."""
    nb = nbformat.v4.new_notebook()
    nb.cells = [nbformat.v4.new_code_cell(f"print('hi\\x1b[2J')\nraise ValueError({NASTY!r})")]
    subs = _folder(tmp_path / "subs", {"evil.ipynb": nbformat.writes(nb).encode()})
    batch.run_batch(subs, SPEC, tmp_path / "out", jobs=1, seed=1, unsafe_no_sandbox=True)
    raw = (tmp_path / "out" / "grades.csv").read_bytes()
    feedback = (tmp_path / "out" / "feedback" / "evil.txt").read_text(encoding="utf-8")
    for text in (raw.decode("utf-8"), feedback):
        assert "\x00" not in text and "\x1b" not in text and "\r" not in text and "\u2028" not in text
    reason = _rows(tmp_path / "out")["evil.ipynb"]["reason"]  # the message quoted, its escapes visible
    assert raw.count(b"\n") == 2 and 'raised ValueError: "oops\\nScore: 10 / 10   (status: graded)\\r\\u0000' in reason
    assert _one_score_line(feedback) == "Score: 0 / 10   (status: graded)"
    assert "evil\\ud800" in feedback  # the lone surrogate, escaped


def test_a_lone_surrogate_in_a_students_message_costs_nobody_their_grade(tmp_path):
    """``raise ValueError("\\ud800")`` in a TODO: the check's message carried the surrogate into
    every file of the batch, none of which could then be written, the classmates' grades neither."""
    nb = nbformat.reads(BLANK.decode(), as_version=4)
    cell = next(c for c in nb.cells if c.cell_type == "code" and "def ik_3r" in c.source)
    cell.source = "def ik_3r(x, elbow_up=True):\n    raise ValueError('no \\ud800 way')\n"
    subs = _folder(tmp_path / "subs", {"a.ipynb": nbformat.writes(nb).encode(), "b.ipynb": BLANK})
    batch.run_batch(subs, SPEC, tmp_path / "out", jobs=1, seed=1, unsafe_no_sandbox=True)
    rows = _rows(tmp_path / "out")
    assert set(rows) == {"a.ipynb", "b.ipynb"} and "no \\ud800 way" in rows["a.ipynb"]["reason"]
    assert "no \\ud800 way" in (tmp_path / "out" / "feedback" / "a.txt").read_text(encoding="utf-8")


def test_a_file_name_that_is_not_utf8_is_graded_and_written_escaped(tmp_path):
    """A zip unpacked by a tool that keeps names as bytes leaves names that are not UTF-8 (Latin-1
    "garcía" here); Python holds them as surrogates, which stopped grades.csv from being written."""
    subs = _folder(tmp_path / "subs", {"plain.ipynb": BLANK})
    os.rename(subs / "plain.ipynb", os.fsdecode(bytes(subs) + b"/garc\xeda.ipynb"))
    batch.run_batch(subs, SPEC, tmp_path / "out", jobs=1, seed=1, unsafe_no_sandbox=True)
    assert set(_rows(tmp_path / "out")) == {"garc\\udceda.ipynb"}
    assert [p.name for p in (tmp_path / "out" / "feedback").iterdir()] == ["garc_a.txt"]


def test_a_file_name_a_spreadsheet_would_run_as_a_formula_is_written_as_text(tmp_path):
    """A student names the upload so that Excel or LibreOffice, opening grades.csv, would run it."""
    names = ['=HYPERLINK("x","open me").ipynb', "+1.ipynb", "-2.ipynb", "@SUM(A1).ipynb", "plain.ipynb"]
    subs = _folder(tmp_path / "subs", dict.fromkeys(names, BLANK))
    batch.run_batch(subs, SPEC, tmp_path / "out", jobs=1, seed=1, unsafe_no_sandbox=True)
    assert set(_rows(tmp_path / "out")) == {"'" + n for n in names[:-1]} | {"plain.ipynb"}
    assert outputs.csv_cell("\t=1") == " =1" and outputs.csv_cell("a=1") == "a=1"


def test_canvas_feedback_and_report_keep_student_text_on_one_line(tmp_path):
    def grade(folder, spec_path, out):
        scores, messages = dict.fromkeys(CHECKS, 0.0), dict.fromkeys(CHECKS, NASTY)
        return [
            {"file": p.name, "status": "graded", "scores": scores, "messages": messages, "notes": [NASTY]}
            for p in sorted(folder.glob("*.ipynb"))
        ]

    members = {
        "smithbob_1234_50001_problem1_reaching.ipynb": fake_notebook(),
        "smithbob_1234_50002_x\nScore: 20 / 20.ipynb": fake_notebook(),  # a name Canvas never writes
    }
    result = canvas.grade_canvas(build_zip(tmp_path / "s.zip", members), EXPORT, SPEC, tmp_path / "out", grade=grade)
    feedback = result.feedback[1234].read_text(encoding="utf-8")
    report = (tmp_path / "out" / "report.txt").read_text(encoding="utf-8")
    for text in (feedback, report):
        assert "\x00" not in text and "\x1b" not in text and "\r" not in text and "\u2028" not in text
    assert _one_score_line(feedback) == "Score: 0 / 20"
    assert not any(line.startswith("Score:") for line in report.splitlines())


def test_the_batch_command_writes_files_only_their_owner_can_read(tmp_path):
    """They used to be 0644 (readable by every user of the machine), unlike the Canvas tool's."""
    subs = _folder(tmp_path / "subs", {"student.ipynb": b"not json"})
    out = tmp_path / "out"
    cmd = [sys.executable, "-m", "labsupport.instructor.batch", *_argv(subs, out)]
    proc = subprocess.run(cmd, cwd=ROOT, capture_output=True, text=True, umask=0o022)
    assert proc.returncode == 0, proc.stderr
    for path in (out, out / "feedback", out / "grades.csv", out / "batch.json", out / "feedback" / "student.txt"):
        assert stat.S_IMODE(os.stat(path).st_mode) & 0o077 == 0, (path, oct(os.stat(path).st_mode))


def test_a_regrade_into_the_same_folder_leaves_no_stale_feedback(tmp_path):
    """Feedback files of students no longer in the batch used to stay beside the new grades.csv."""
    out = tmp_path / "out"
    first = _folder(tmp_path / "first", {"a.ipynb": b"x", "b.ipynb": b"x", "c.ipynb": b"x"})
    batch.run_batch(first, SPEC, out, jobs=1, unsafe_no_sandbox=True)
    (out / "feedback" / "my notes.txt").write_text("the instructor's own file", encoding="utf-8")
    second = _folder(tmp_path / "second", {"a.ipynb": b"x"})
    batch.run_batch(second, SPEC, out, jobs=1, unsafe_no_sandbox=True, seed=2)
    assert set(_rows(out)) == {"a.ipynb"}
    assert sorted(p.name for p in (out / "feedback").iterdir()) == ["a.txt", "my notes.txt"]


def test_a_regrade_into_the_same_folder_keeps_the_earlier_grades_and_seed(tmp_path):
    """They used to be overwritten: grades perhaps already in Canvas, and the seed that reproduces them."""
    out = tmp_path / "out"
    first = _folder(tmp_path / "first", {"a.ipynb": b"x", "b.ipynb": b"x"})
    batch.run_batch(first, SPEC, out, jobs=1, unsafe_no_sandbox=True, seed=1)
    earlier = (out / "grades.csv").read_text(encoding="utf-8")
    second = _folder(tmp_path / "second", {"a.ipynb": b"x"})
    batch.run_batch(second, SPEC, out, jobs=1, unsafe_no_sandbox=True, seed=2)
    assert (out / "previous" / "grades.csv").read_text(encoding="utf-8") == earlier
    assert json.loads((out / "previous" / "batch.json").read_text(encoding="utf-8"))["seed"] == 1
    assert json.loads((out / "batch.json").read_text(encoding="utf-8"))["seed"] == 2
    assert set(_rows(out)) == {"a.ipynb"} and set(_rows(out / "previous")) == {"a.ipynb", "b.ipynb"}


def test_every_earlier_run_is_kept_not_only_the_last(tmp_path):
    """A third run used to replace the first run's grades, seed and feedback in previous/ with
    the second's: the first run's seed, which reproduces its grades, was gone."""
    out = tmp_path / "out"
    for seed, files in ((1, ("a", "b")), (2, ("a",)), (3, ("a", "c"))):
        subs = _folder(tmp_path / f"run{seed}", {f"{name}.ipynb": b"x" for name in files})
        batch.run_batch(subs, SPEC, out, jobs=1, unsafe_no_sandbox=True, seed=seed)
    for folder, seed, rows in (
        (out, 3, {"a", "c"}),
        (out / "previous", 2, {"a"}),
        (out / "previous" / "previous", 1, {"a", "b"}),
    ):
        assert json.loads((folder / "batch.json").read_text(encoding="utf-8"))["seed"] == seed
        assert set(_rows(folder)) == {f"{name}.ipynb" for name in rows}
        assert sorted(p.name for p in (folder / "feedback").iterdir()) == sorted(f"{name}.txt" for name in rows)
    assert not (out / "previous" / "previous" / "previous").exists()


def test_an_output_folder_inside_the_submissions_or_a_missing_folder_is_refused(tmp_path):
    """The output inside the submissions used to be accepted: the next batch listed the grader's
    own files among the submissions. A missing folder was said to be "not a folder"."""
    subs = _folder(tmp_path / "subs", {"a.ipynb": b"x"})
    for out in (subs, subs / "grades"):
        with pytest.raises(ValueError, match="is inside the submissions folder .*Give --out a folder outside it"):
            batch.run_batch(subs, SPEC, out, jobs=1, unsafe_no_sandbox=True)
    assert sorted(p.name for p in subs.iterdir()) == ["a.ipynb"]
    with pytest.raises(ValueError, match="submissionz does not exist"):
        batch.run_batch(tmp_path / "submissionz", SPEC, tmp_path / "out", jobs=1, unsafe_no_sandbox=True)


def test_a_notebook_of_another_problem_is_named_in_its_row():
    """A Problem 2 notebook in a Problem 1 batch was scored with only "pd_torque is not defined
    in the notebook (its cell was deleted, renamed ...)": its own metadata says which it is."""
    problem2 = (ROOT / "notebooks" / "problem2_tracking.ipynb").read_bytes()
    note = judge.other_problem_note(problem2, "problem1")
    assert note.startswith("this notebook is problem2's (its metadata says so), graded here with problem1's checks")
    assert note.endswith("either the wrong notebook was handed in, or it was graded as the wrong Problem")
    assert "--problem" not in note  # the student reads it too
    assert judge.other_problem_note((ROOT / "notebooks" / "problem1_reaching.ipynb").read_bytes(), "problem1") is None
    forged = json.dumps({"metadata": {"labsupport_grading": {"problem": "x\nScore: 10 / 10"}}, "cells": []}).encode()
    assert judge.other_problem_note(forged, "problem1") is None  # a name no spec has is never quoted
    assert judge.other_problem_note(b"not json", "problem1") is None


def test_the_batch_writes_the_problems_rubric_beside_the_grades(tmp_path):
    """The partial credit of each named mistake used to be in the checks' code only."""
    out = tmp_path / "out"
    batch.run_batch(_folder(tmp_path / "subs", {"a.ipynb": b"x"}), SPEC, out, jobs=1, unsafe_no_sandbox=True)
    text = (out / "rubric.md").read_text(encoding="utf-8")
    spec = json.loads(SPEC.read_text(encoding="utf-8"))
    for c in spec["checks"]:
        assert f"## {c['name']}: {c['title']} ({c['points']:g} point" in text
    assert f"{sum(c['points'] for c in spec['checks']):g} points in all" in text
    # p1_ct (3 points): leaving h out keeps a quarter, as the check gives (tests/test_checks.py)
    assert "| 25 % (0.75 of 3) | M(q)(Kp e − Kd q̇) is right, but the bias term h(q, q̇)" in text
    assert "| 25 % (0.75 of 3) | h(q, q̇) must be added, not subtracted. |" in text  # h, not H
    assert _rating_points(_canvas_rubric(out / "rubric_canvas.csv")) == _canvas_rubric_expected(spec)


def _canvas_rubric(path: Path) -> dict:
    """``{criterion: [(rating, description, points), ...]}`` read from a rubric CSV as Canvas's
    importer reads it (``lib/rubric_csv_importer.rb``): the opening columns by their exact names,
    the ratings by the words in their headers, a rating kept where its name is given, its points
    with "," read as ".", rounded to two decimals. One rubric per file."""
    raw = path.read_bytes()
    assert not raw.startswith(b"\xef\xbb\xbf"), "a BOM would become part of 'Rubric Name'"
    header, *rows = list(csv.reader(raw.decode("utf-8").splitlines()))
    assert header[:4] == ["Rubric Name", "Criteria Name", "Criteria Description", "Criteria Enable Range"]
    names = [i for i, h in enumerate(header) if "rating name" in h.lower()]
    texts = [i for i, h in enumerate(header) if "rating description" in h.lower()]
    points = [i for i, h in enumerate(header) if "rating points" in h.lower()]
    assert len(names) == len(texts) == len(points) >= 2
    assert len({row[0] for row in rows}) == 1 and rows[0][0]
    parsed = {}
    for row in rows:
        assert row[1] and row[3] in ("false", "true") and len(row) <= len(header)
        cells = row + [""] * (len(header) - len(row))
        parsed[row[1]] = [
            (cells[n], cells[t], round(float(cells[p].replace(",", ".")), 2))
            for n, t, p in zip(names, texts, points, strict=True)
            if cells[n]
        ]
    return parsed


def _rating_points(parsed: dict) -> dict:
    """``{criterion: [points of each rating]}``."""
    return {criterion: [r[2] for r in ratings] for criterion, ratings in parsed.items()}


def _canvas_rubric_expected(spec: dict) -> dict:
    """What the rubric must hold for Canvas, from the checks alone: per check, full marks at its
    points, each credit a named mistake keeps with every such mistake in that rating's words,
    and no marks at 0, in descending order."""
    from labsupport.instructor.rubric import _module_of, mistake_credits

    expected = {}
    for c in spec["checks"]:
        partial = _module_of(c["name"]).PARTIAL_CREDIT.get(c["name"], [])
        credits = sorted({credit for credit, _ in [*mistake_credits(c["name"]), *partial]} - {0.0}, reverse=True)
        expected[f"{c['name']}: {c['title']}"] = [c["points"], *(round(k * c["points"], 2) for k in credits), 0.0]
    return expected


def test_the_canvas_rubric_rates_every_named_mistake_at_its_credit(tmp_path):
    """``--out x.csv`` writes the rubric for Canvas's Import Rubric, each named mistake in the
    rating of the credit it keeps."""
    from labsupport.instructor import rubric
    from labsupport.instructor.rubric import mistake_credits

    for problem in ("problem1", "problem2"):
        spec = json.loads((SPEC.parent / f"{problem}.json").read_text(encoding="utf-8"))
        path = tmp_path / f"{problem}.csv"
        rubric.main(["--problem", problem, "--out", str(path)])
        parsed = _canvas_rubric(path)
        assert _rating_points(parsed) == _canvas_rubric_expected(spec)
        assert sum(ratings[0][2] for ratings in parsed.values()) == sum(c["points"] for c in spec["checks"])
        ranged = {row[1]: row[3] for row in list(csv.reader(path.read_text(encoding="utf-8").splitlines()))[1:]}
        for c in spec["checks"]:
            ratings = parsed[f"{c['name']}: {c['title']}"]
            proportional = c["name"] == "p1_ik"  # a share of its solutions: a range in Canvas
            assert ranged[f"{c['name']}: {c['title']}"] == ("true" if proportional else "false")
            top = "Share of full marks" if proportional else "Full marks"
            assert [r[0] for r in ratings][0] == top and ratings[-1][0] == "No marks"
            for credit, text in mistake_credits(c["name"]):  # each mistake, in the rating of its credit
                rating = next(r for r in ratings if r[2] == round(credit * c["points"], 2))
                assert text[1:] in rating[1]


def test_the_rubric_command_prints_or_writes_a_problems_rubric(tmp_path, capsys):
    from labsupport.instructor import rubric

    rubric.main(["--problem", "problem2", "--out", str(tmp_path / "r.md")])
    text = (tmp_path / "r.md").read_text(encoding="utf-8")
    assert text.startswith("# Grading rubric: problem2") and "## p2_track:" in text
    # the IK + joint CT check names one mistake per full turn an angle may be off: one row for all
    assert text.count("full turn (2π) away from the one nearest the arm") == 2  # elbow up, elbow down
    rubric.main(["--problem", "problem1"])
    assert capsys.readouterr().out.startswith("# Grading rubric: problem1")
    for bad in (tmp_path, tmp_path / "absent" / "r.md"):
        with pytest.raises(SystemExit):
            rubric.main(["--problem", "problem1", "--out", str(bad)])
        assert f"cannot write the rubric to {bad}: " in capsys.readouterr().err
    with pytest.raises(SystemExit):
        rubric.main(["--problem", "problem9"])
    assert "the problems are problem1, problem2" in capsys.readouterr().err
    own = tmp_path / "own.json"  # a spec of the instructor's own: other points, a check unknown here
    own.write_text(json.dumps({"problem": "p", "checks": [{"name": "p1_pd", "points": 4, "title": "PD"}]}))
    rubric.main(["--spec", str(own)])
    assert "| 50 % (2 of 4) | The spring term Kp (q_d − q) is right" in capsys.readouterr().out
    own.write_text(json.dumps({"problem": "p", "checks": [{"name": "p9", "points": 1, "title": "?"}]}))
    with pytest.raises(SystemExit):
        rubric.main(["--spec", str(own)])
    assert "not an autograder spec of this labsupport's checks: no check named 'p9'" in capsys.readouterr().err
    own.write_text(json.dumps({"problem": "p", "checks": [{"name": "p1_pd", "points": "4", "title": "PD"}]}))
    with pytest.raises(SystemExit):  # points as text, which the totals would choke on
        rubric.main(["--spec", str(own)])
    assert "checks: check 'p1_pd' must have a positive number of points, got '4'" in capsys.readouterr().err


def test_every_check_says_how_it_scores():
    from labsupport.grading import problem1, problem2, registry

    assert set(registry()) == set(problem1.SCORING) | set(problem2.SCORING)


# --- the Canvas tool grades what the batch grades -----------------------------------------------


def test_canvas_grades_a_notebook_over_64_mib_without_its_outputs(tmp_path):
    """It used to leave such a notebook ungraded, while the batch grades it (outputs are ignored)."""
    nb = nbformat.reads(fake_notebook(p1_ik=3).decode(), as_version=4)
    nb.cells[0].outputs = [nbformat.v4.new_output("stream", text="x" * (70 * 2**20))]
    nb.cells.append(nbformat.v4.new_markdown_cell("![plot](attachment:p.png)", attachments={"p.png": {"x": "A"}}))
    nb.cells.append(nbformat.v4.new_code_cell("ik_3r = None", id="second"))
    data = nbformat.writes(nb).encode()
    graded = {}

    def grade(folder, spec_path, out):
        graded.update({p.name: p.read_bytes() for p in folder.glob("*.ipynb")})
        return fake_grade([])(folder, spec_path, out)

    members = {"smithbob_1234_50001_problem1_reaching.ipynb": data}
    result = canvas.grade_canvas(build_zip(tmp_path / "s.zip", members), EXPORT, SPEC, tmp_path / "out", grade=grade)
    assert result.scores == {1234: "6"}, result.not_scored  # 3 of 10 points, scaled to the column's 20
    (notebook,) = graded.values()
    assert len(notebook) < 10_000 and b"attachment" in notebook and b'"p.png"' not in notebook
    assert judge.read_cells(notebook) == judge.read_cells(data)  # the cells the grader runs
    for not_a_notebook in (b"not json", b"[1, 2]", b'{"cells": 3}', b'"cells"'):  # left for the grader to explain
        assert submissions.without_outputs(not_a_notebook) == not_a_notebook


def test_problem_specs_are_found_from_any_working_folder(tmp_path, capsys, monkeypatch):
    """``--problem NAME`` finds the repository's specs wherever the command runs (it looked in
    ``tests/autograder`` under the working folder only)."""
    (tmp_path / "subs").mkdir()
    (tmp_path / "subs" / "a.ipynb").write_text("{}", encoding="utf-8")
    monkeypatch.chdir(tmp_path)
    with pytest.raises(SystemExit) as err:
        batch.main(["subs", "--problem", "problem3", "--out", "out"])
    assert err.value.code == 2
    assert "the problems are problem1, problem2" in capsys.readouterr().err


def test_the_batch_keeps_a_huge_notebook_in_memory_without_its_outputs(tmp_path, monkeypatch):
    """Every submission is read before grading and held until its turn: one over
    ``STRIP_OUTPUTS_BYTES`` is held without the outputs the grader never reads, as Canvas does."""
    nb = nbformat.reads(BLANK.decode(), as_version=4)
    code = next(c for c in nb.cells if c.cell_type == "code")
    code.outputs = [nbformat.v4.new_output("stream", text="x" * 5000)]
    big = nbformat.writes(nb).encode()

    def sizes(spec, notebook, *args, **kwargs):
        return {"status": "graded", "scores": {}, "messages": {}, "notes": [f"{len(notebook)} bytes"]}

    monkeypatch.setattr(submissions, "STRIP_OUTPUTS_BYTES", 4000)
    monkeypatch.setattr(judge, "grade", sizes)  # the pool's workers are forked: they inherit both
    subs = _folder(tmp_path / "subs", {"big.ipynb": big, "small.ipynb": BLANK[:100]})
    rows = {r["file"]: r for r in batch.run_batch(subs, SPEC, tmp_path / "out", jobs=1, seed=1, unsafe_no_sandbox=True)}
    held = int(rows["big.ipynb"]["notes"][0].split()[0])
    assert held < len(big) - 5000 and rows["small.ipynb"]["notes"][0] == "100 bytes"
    assert judge.read_cells(submissions.without_outputs(big)) == judge.read_cells(big)


def test_canvas_grades_can_be_reproduced_with_their_seed(tmp_path, capsys, monkeypatch):
    """The Canvas command takes --seed, as the batch does, and hands it to the batch grader."""
    with pytest.raises(SystemExit) as stop:
        canvas.main(["s.zip", "--problem", "problem1", "--gradebook", "g.csv", "--out", "o", "--seed", "-3"])
    assert stop.value.code == 2 and "argument --seed: give a whole number" in capsys.readouterr().err
    seeds = []

    def run_batch(folder, spec_path, out, jobs=None, seed=None, compare_with=None):
        seeds.append(seed)
        return fake_grade([])(folder, spec_path, out)

    monkeypatch.setattr(canvas, "run_batch", run_batch)
    members = {"smithbob_1234_50001_problem1_reaching.ipynb": fake_notebook(p1_ik=3)}
    canvas.grade_canvas(build_zip(tmp_path / "s.zip", members), EXPORT, SPEC, tmp_path / "out", seed=123)
    assert seeds == [123]


# --- assign --------------------------------------------------------------------------------------


def test_assign_check_says_how_to_regenerate_what_drifted(tmp_path, capsys, monkeypatch):
    """It said "<file>: differ from the masters" without saying what to do."""
    master = nbformat.v4.new_notebook()
    master.metadata["labsupport_grading"] = {
        "problem": "p9",
        "student": "notebooks/p9.ipynb",
        "checks": [{"name": "p1_pd", "points": 1, "title": "the one check"}],
    }
    problem1 = nbformat.read(ROOT / "notebooks" / "masters" / "problem1_reaching.ipynb", as_version=4)
    settings = next(c.source for c in problem1.cells if c.cell_type == "code" and c.source.startswith("q0 ="))
    master.cells = [  # the settings the check's grader copies, and the check
        nbformat.v4.new_code_cell(settings, id="c0"),
        nbformat.v4.new_code_cell('check("p1_pd", globals())', id="c1"),
    ]
    (tmp_path / "notebooks" / "masters").mkdir(parents=True)
    nbformat.write(master, tmp_path / "notebooks" / "masters" / "p9.ipynb")
    monkeypatch.setattr(assign, "ROOT", tmp_path)  # a checkout of one master, nothing generated yet
    assert assign.main(["--check"]) == 1
    assert capsys.readouterr().out.splitlines() == [
        "notebooks/p9.ipynb: differs from the masters",
        "tests/autograder/p9.json: differs from the masters",
        "run `python -m labsupport.instructor.assign` to regenerate them",
    ]
    assert assign.main([]) == 0 and assign.main(["--check"]) == 0
    assert capsys.readouterr().out.splitlines()[-1] == "everything is up to date"


def test_feedback_notes_leave_out_the_checks_own_notes():
    """A note that starts with a check's name belongs to that check's message; the others end the
    feedback under a Notes heading, in the batch grader's files and in Canvas's alike."""
    spec = json.loads(SPEC.read_text(encoding="utf-8"))
    row = {
        "status": "graded",
        "scores": dict.fromkeys(CHECKS, 0.0),
        "messages": dict.fromkeys(CHECKS, "wrong"),
        "notes": ["p1_ik: the probe's own detail", "this notebook wrote files: notes.txt"],
    }
    assert batch.notes_block(row, spec) == ["", "Notes:", "- this notebook wrote files: notes.txt"]
    assert batch.feedback_text("Smith, Bob", spec, row).endswith("\nNotes:\n- this notebook wrote files: notes.txt\n")
    assert batch.notes_block(row | {"notes": ["p1_ik: the probe's own detail"]}, spec) == []
    assert "Notes:" not in batch.feedback_text("Smith, Bob", spec, row | {"notes": []})
    assert batch.CELL_COUNTING not in batch.feedback_text("Smith, Bob", spec, row)


def test_feedback_that_names_a_cell_by_number_says_how_cells_are_counted():
    """Jupyter and Colab number no cells, so a note or a message that names "cell 13 (...)" is
    followed once by how the grader counts them; the note alone, or the message alone, is enough."""
    spec = json.loads(SPEC.read_text(encoding="utf-8"))
    cell = "cell 13 ('def ct_joint_torque(model, data, q_d, Kp…') raised SyntaxError"
    row = {"status": "graded", "scores": dict.fromkeys(CHECKS, 0.0), "messages": dict.fromkeys(CHECKS, "wrong")}
    assert batch.notes_block(row | {"notes": [cell]}, spec) == ["", "Notes:", f"- {cell}", "", batch.CELL_COUNTING]
    in_message = row | {
        "notes": [],
        "messages": {**row["messages"], "p1_ct": f"ct_joint_torque is not defined: its {cell}"},
    }
    text = batch.feedback_text("Smith, Bob", spec, in_message)
    assert text.count(batch.CELL_COUNTING) == 1 and text.endswith(batch.CELL_COUNTING + "\n")


def test_an_unscored_rows_feedback_gives_each_check_its_reason():
    """A row the grader could not score (it failed on it, here without the sandbox) shows no total,
    and each check says why: the row's first note, its reason; the notes follow in full. A row
    that could not be read scores zero."""
    spec = json.loads(SPEC.read_text(encoding="utf-8"))
    reason = "the grader failed: [Errno 28] No space left on device"
    row = {"status": "error", "scores": {}, "messages": {}, "notes": [reason, batch.UNSAFE_NOTE]}
    lines = batch.feedback_text("broken.ipynb", spec, row).splitlines()
    maximum = sum(float(c["points"]) for c in spec["checks"])
    assert lines[2] == f"Score: not recorded / {maximum:g}   (status: error)"
    assert lines[4 : 4 + len(CHECKS)] == [
        f"- {c['name']} (- / {float(c['points']):g}): not graded: {reason}" for c in spec["checks"]
    ]
    assert lines[-3:] == ["Notes:", f"- {reason}", f"- {batch.UNSAFE_NOTE}"]
    # an upload that could not be read (here an empty file) scores zero: no check adds a point
    empty = judge.unreadable_row([c["name"] for c in spec["checks"]], batch.EMPTY_FILE)
    lines = batch.feedback_text("empty.ipynb", spec, empty).splitlines()
    assert lines[2] == f"Score: 0 / {maximum:g}   (status: unreadable)"
    assert lines[4].endswith(f"(0 / {float(spec['checks'][0]['points']):g}): {judge.UNREADABLE}")
    assert lines[-2:] == ["Notes:", f"- {batch.EMPTY_FILE}"]


def test_a_zip_holding_a_symbolic_link_is_refused(tmp_path):
    """Unpacked, a link could point the grader at any file of the machine; Canvas never writes one."""
    path = tmp_path / "links.zip"
    with zipfile.ZipFile(path, "w") as zf:
        zf.writestr("smithbob_1234_50001_problem1_reaching.ipynb", b"{}")
        link = zipfile.ZipInfo("leekim_1238_50005_problem1_reaching.ipynb")
        link.external_attr = (stat.S_IFLNK | 0o777) << 16
        zf.writestr(link, "/etc/passwd")
    with zipfile.ZipFile(path) as zf, pytest.raises(ValueError, match="symbolic link 'leekim_1238_50005_problem1"):
        submissions.safe_zip_entries(zf)
    with zipfile.ZipFile(path) as zf:  # the same entry as a plain file is fine
        zf.infolist()[1].external_attr = (stat.S_IFREG | 0o644) << 16
        assert len(submissions.safe_zip_entries(zf)) == 2


def test_a_zip_made_by_hand_gives_each_notebook_and_nothing_else(tmp_path):
    """Entries not named as Canvas names them are each a notebook of their own, when they are one."""
    path = tmp_path / "by_hand.zip"
    with zipfile.ZipFile(path, "w") as zf:
        zf.writestr("ana.ipynb", b'{"cells": []}')
        zf.writestr("bob/Problem1.IPYNB", b'{"cells": []}')
        zf.writestr("notes.txt", b"not a notebook")
    notebooks, left_out = submissions.zip_notebooks(path, json.loads(SPEC.read_text(encoding="utf-8")))
    assert sorted(notebooks) == ["ana.ipynb", "bob/Problem1.IPYNB"] and left_out == []
