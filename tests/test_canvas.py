"""From Canvas to Canvas: the "Download Submissions" zip and the gradebook export, round trip.

The fixtures in tests/fixtures/canvas/ are synthetic but named and laid out as Canvas writes them
(see the docstrings of labsupport.instructor.submissions and labsupport.instructor.gradebook
for the sources):

* ``gradebook_export.csv``: an export with a custom column, a Manual Posting row, the Points
  Possible row (the Problem 1 column is worth 20 points, its checks 10), read-only totals,
  a grade already there (Lee), an excused cell (Patel) and Canvas's Test Student;
* ``submissions.zip``: built from :data:`ZIP_MEMBERS` below (a test checks that they agree);
  each notebook carries the scores a fake grader returns for it, so the round trip is checked
  without running the real grader; :func:`test_end_to_end_with_the_real_batch_grader` runs it;
* ``expected_import.csv``: what must come out: the export's identifying columns and the
  Problem's column, filled, for the students with a new score only.
"""

import csv
import io
import json
import os
import shutil
import stat
import warnings
import zipfile
from pathlib import Path

import nbformat
import pytest

from labsupport.instructor import canvas, gradebook, isolation, outputs, submissions

ROOT = Path(__file__).resolve().parents[1]
FIXTURES = ROOT / "tests" / "fixtures" / "canvas"
SPEC = ROOT / "tests" / "autograder" / "problem1.json"
EXPORT = FIXTURES / "gradebook_export.csv"
COLUMN = "Problem 1: Reaching (4101)"


def fake_notebook(status: str = "graded", **scores: float) -> bytes:
    """A small notebook whose metadata says what the fake grader returns for it."""
    nb = nbformat.v4.new_notebook()
    nb.cells = [nbformat.v4.new_code_cell("# the student's work", id="student-work")]
    nb.metadata["fake_grade"] = {"status": status, "scores": scores}
    return nbformat.writes(nb).encode()


#: The committed zip's entries: Canvas names, the cases the round trip must handle.
ZIP_MEMBERS = {
    # on time, full marks
    "smithbob_1234_50001_problem1_reaching.ipynb": fake_notebook(p1_ik=3, p1_pd=2, p1_ct=3, p1_reach=2),
    # late
    "garcíaana_LATE_1235_50002_problem1_reaching.ipynb": fake_notebook(p1_ik=3, p1_pd=2, p1_ct=1.5, p1_reach=1),
    # a resubmission, plus a file that is not a notebook
    "oharasean_1236_50003_problem1_reaching-1.ipynb": fake_notebook(p1_ik=1.5, p1_pd=0, p1_ct=1.5, p1_reach=0),
    "oharasean_1236_50004_notes.pdf": b"%PDF-1.4 not a notebook",
    # both Problems in one submission, the third upload of problem1_reaching.ipynb; Canvas has 10 already
    "leekim_1238_50005_problem2_tracking.ipynb": fake_notebook(p1_ik=0, p1_pd=0, p1_ct=0, p1_reach=0),
    "leekim_1238_50006_problem1_reaching-2.ipynb": fake_notebook(p1_ik=3, p1_pd=2, p1_ct=3, p1_reach=0),
    # the grader ran out of time: no score may be written
    "khanomar_1239_50007_Copy_of_problem1_reaching.ipynb": fake_notebook("timed out"),
    # excused in Canvas
    "patelriya_1240_50008_problem1_reaching.ipynb": fake_notebook(p1_ik=3, p1_pd=2, p1_ct=3, p1_reach=2),
    # a group submission: Canvas names the file after the group, with one member's id
    "theroboticists_1241_50009_problem1_reaching.ipynb": fake_notebook(p1_ik=2, p1_pd=2, p1_ct=2, p1_reach=2),
    # a student no longer in the gradebook, and a file Canvas did not name
    "doejane_4321_50010_problem1_reaching.ipynb": fake_notebook(p1_ik=3, p1_pd=2, p1_ct=3, p1_reach=2),
    "problem1_reaching.ipynb": fake_notebook(p1_ik=3, p1_pd=2, p1_ct=3, p1_reach=2),
}

#: The Problem 1 cells expected in the import (scaled from /10 to /20); the others keep their export.
EXPECTED_CELLS = {1234: "20", 1235: "15", 1236: "6", 1238: "16", 1241: "16"}


def build_zip(path: Path, members: dict[str, bytes]) -> Path:
    with zipfile.ZipFile(path, "w", zipfile.ZIP_DEFLATED) as zf:
        for name, data in members.items():
            zf.writestr(zipfile.ZipInfo(name, date_time=(2025, 3, 14, 9, 26, 0)), data, zipfile.ZIP_DEFLATED)
    return path


def build_legacy_zip(path: Path, members: dict[bytes, bytes]) -> Path:
    """A zip whose entry names are the raw bytes given, stored without the UTF-8 flag
    (general-purpose bit 11), as Info-ZIP and rubyzip write them.

    Each entry is written under an ASCII name of the same length (which sets no flag), then that
    name is overwritten in the entry's local header and in its central directory record.
    """
    names = list(members)
    build_zip(path, {str(k).rjust(len(name), "x"): data for k, (name, data) in enumerate(members.items())})
    raw = bytearray(path.read_bytes())
    with zipfile.ZipFile(path) as zf:
        starts = [info.header_offset + 30 for info in zf.infolist()]  # after each local header's fixed part
    central = int.from_bytes(raw[-6:-2], "little")  # the end record (no comment) says where the directory starts
    for _ in names:
        starts.append(central + 46)
        central += 46 + sum(int.from_bytes(raw[central + k : central + k + 2], "little") for k in (28, 30, 32))
    for start, name in zip(starts, names + names, strict=True):
        raw[start : start + len(name)] = name
    path.write_bytes(bytes(raw))
    return path


def fake_grade(calls: list):
    """A grading function with run_batch's shape that returns what each notebook's metadata says."""

    def grade(folder: Path, spec_path: Path, out: Path) -> list[dict]:
        calls.append(
            {
                "folder": folder,
                "mode": stat.S_IMODE(os.stat(folder).st_mode),
                "files": sorted(p.name for p in folder.iterdir()),
                "out": out,
            }
        )
        rows = []
        for p in sorted(folder.glob("*.ipynb")):
            fake = json.loads(p.read_text())["metadata"]["fake_grade"]
            rows.append(
                {
                    "file": p.name,
                    "status": fake["status"],
                    "scores": fake["scores"],
                    "messages": {n: f"{n} message for {p.stem}" for n in fake["scores"]},
                    "notes": [] if fake["status"] == "graded" else ["the check ran out of time"],
                    "seconds": 0.0,
                }
            )
        return rows

    return grade


@pytest.fixture
def round_trip(tmp_path):
    calls = []
    result = canvas.grade_canvas(FIXTURES / "submissions.zip", EXPORT, SPEC, tmp_path / "out", grade=fake_grade(calls))
    return result, tmp_path / "out", calls


# --- file names -----------------------------------------------------------------------------------


@pytest.mark.parametrize(
    "entry, name, user, late, attachment, original, resubmission, kind",
    [
        (
            "smithbob_1234_50001_problem1_reaching.ipynb",
            "smithbob",
            1234,
            False,
            50001,
            "problem1_reaching.ipynb",
            0,
            "upload",
        ),
        (
            "smithbob_LATE_1234_50002_problem1_reaching-1.ipynb",
            "smithbob",
            1234,
            True,
            50002,
            "problem1_reaching-1.ipynb",
            1,
            "upload",
        ),
        (
            "garcíaana_1235_7_problem1_reaching-12.ipynb",
            "garcíaana",
            1235,
            False,
            7,
            "problem1_reaching-12.ipynb",
            12,
            "upload",
        ),
        # names keep digits and underscores; file names keep spaces, digits and underscores
        (
            "student_2nd_88_99_2024_10 final (1).ipynb",
            "student_2nd",
            88,
            False,
            99,
            "2024_10 final (1).ipynb",
            0,
            "upload",
        ),
        ("my-notebook_5_6_my-notebook.ipynb", "my-notebook", 5, False, 6, "my-notebook.ipynb", 0, "upload"),
        ("smithbob_1234_5_archive-3.tar.gz", "smithbob", 1234, False, 5, "archive-3.tar.gz", 3, "upload"),
        # past -7 today's Canvas appends a UUID
        (
            "kim_1_9_p1-0b5e9f4c-6a1d-4c2e-9f3a-1b2c3d4e5f60.ipynb",
            "kim",
            1,
            False,
            9,
            "p1-0b5e9f4c-6a1d-4c2e-9f3a-1b2c3d4e5f60.ipynb",
            8,
            "upload",
        ),
        # anonymous grading: no name, an anonymous id instead of the user id
        (
            "LATE_anon_q7Kx2_50011_problem1_reaching.ipynb",
            "",
            None,
            True,
            50011,
            "problem1_reaching.ipynb",
            0,
            "upload",
        ),
        # text entry and URL submissions
        ("smithbob_1234_text.html", "smithbob", 1234, False, None, "smithbob_1234_text.html", 0, "text"),
        ("smithbob_LATE_1234_link.html", "smithbob", 1234, True, None, "smithbob_LATE_1234_link.html", 0, "link"),
        # inside a folder (a zip made again by hand)
        ("submissions/smithbob_1234_50001_p.ipynb", "smithbob", 1234, False, 50001, "p.ipynb", 0, "upload"),
    ],
)
def test_parse_submission_name(entry, name, user, late, attachment, original, resubmission, kind):
    f = submissions.parse_submission_name(entry)
    assert (f.name, f.user_id, f.late, f.attachment_id, f.original, f.resubmission, f.kind) == (
        name,
        user,
        late,
        attachment,
        original,
        resubmission,
        kind,
    )
    assert f.entry == entry


@pytest.mark.parametrize(
    "entry", ["problem1_reaching.ipynb", "notes.txt", "smithbob_problem1.ipynb", "__MACOSX/._smithbob", "1234.ipynb"]
)
def test_names_canvas_does_not_write_are_not_parsed(entry):
    assert submissions.parse_submission_name(entry) is None


def test_anonymous_and_resubmission_details():
    f = submissions.parse_submission_name("LATE_anon_q7Kx2_50011_problem1_reaching-2.ipynb")
    assert f.anonymous_id == "q7Kx2" and f.user_id is None
    assert f.base_name == "problem1_reaching.ipynb" and f.resubmission == 2
    assert f.prefix == "LATE_anon_q7Kx2_50011"
    assert submissions.parse_submission_name("a_1_2_lab-v2.ipynb").base_name == "lab-v2.ipynb"
    uuid = submissions.parse_submission_name("a_1_2_p1-0b5e9f4c-6a1d-4c2e-9f3a-1b2c3d4e5f60.ipynb")
    assert uuid.base_name == "p1.ipynb" and uuid.resubmission == 8


def test_choose_notebook_prefers_the_problem_then_the_latest_upload():
    files = [
        submissions.parse_submission_name(n)
        for n in (
            "kim_1_10_problem2_tracking.ipynb",
            "kim_1_11_problem1_reaching.ipynb",
            "kim_1_13_problem1_reaching-2.ipynb",
            "kim_1_12_problem1_reaching-1.ipynb",
            "kim_1_14_report.pdf",
        )
    ]
    assert submissions.choose_notebook(files, "problem1_reaching", "problem1").attachment_id == 13
    # the latest upload wins, whatever its suffix says (past -7 Canvas appends a UUID)
    later = submissions.parse_submission_name("kim_1_15_problem1_reaching-0b5e9f4c-6a1d-4c2e-9f3a-1b2c3d4e5f60.ipynb")
    assert submissions.choose_notebook([*files, later], "problem1_reaching", "problem1") is later
    # named after the Problem only, or not at all: still a notebook, never the PDF
    assert submissions.choose_notebook(files[:1] + files[4:], "problem1_reaching", "problem1").attachment_id == 10
    assert submissions.choose_notebook(files[4:], "problem1_reaching", "problem1") is None


@pytest.mark.parametrize(
    "value, text",
    [(20, "20"), (15.0, "15"), (7.5, "7.5"), (6.666666, "6.67"), (0.0, "0"), (-0.001, "0"), (12.345, "12.35")],
)
def test_format_score(value, text):
    assert gradebook.format_score(value) == text


def test_scaled_score():
    assert gradebook.scaled_score(7.5, 10, 20) == 15
    assert gradebook.scaled_score(7.5, 10, 10) == 7.5
    assert gradebook.scaled_score(7.5, 10, None) == 7.5
    assert gradebook.scaled_score(3, 10, 100) == pytest.approx(30)


# --- fixtures ---------------------------------------------------------------------------------------


def test_committed_zip_holds_exactly_the_manifest(tmp_path):
    with zipfile.ZipFile(FIXTURES / "submissions.zip") as zf:
        committed = {i.filename: zf.read(i) for i in zf.infolist()}
    assert committed == ZIP_MEMBERS


# --- the round trip -------------------------------------------------------------------------------


def test_round_trip_matches_the_expected_import(round_trip):
    result, out, calls = round_trip
    assert (out / "gradebook_import.csv").read_bytes() == (FIXTURES / "expected_import.csv").read_bytes()
    assert result.scores == EXPECTED_CELLS
    assert result.column == COLUMN and result.points_possible == 20 and result.maximum == 10


def test_the_import_holds_the_identifying_columns_and_the_problems_only(round_trip):
    """It used to echo every other column of the export: importing an export made before grades
    were changed in Canvas put the old grades back."""
    _, out, _ = round_trip
    before = gradebook.read_gradebook(EXPORT)
    after = gradebook.read_gradebook(out / "gradebook_import.csv")
    col = before.header.index(COLUMN)
    assert after.header == ["Student", "ID", "SIS User ID", "SIS Login ID", "Section", COLUMN]
    assert set(after.student_rows) == set(EXPECTED_CELLS) and after.points_row == before.points_row == 2
    user_of_row = {r: u for u, r in before.student_rows.items()}
    kept = [r for r in range(len(before.records)) if r not in user_of_row or user_of_row[r] in EXPECTED_CELLS]
    assert len(after.records) == len(kept)
    for r, new in zip(kept, after.records, strict=True):
        old = before.records[r]
        old_fields, old_end = gradebook.split_fields(old, ",")
        new_fields, new_end = gradebook.split_fields(new, ",")
        assert new_end == old_end and new_fields[:5] == old_fields[:5], f"record {r}"  # raw text, quotes kept
        assert new_fields[5:] == [EXPECTED_CELLS.get(user_of_row.get(r), old_fields[col])], f"record {r}"
    raw = (out / "gradebook_import.csv").read_text(encoding="utf-8")
    assert '"Smith, Bob",1234,S001,bsmith,Section A,20\n' in raw and "\n,,,,,Manual Posting\n" in raw
    for other in ("9.00", "Task 1 quiz", "Problem 2", "Current Score", "(read only)", "Extension"):
        assert other not in raw, other
    # re-read independently with the csv module: the Points Possible row keeps the column's points
    rows = list(csv.reader(io.StringIO(raw)))
    assert rows[2] == ["    Points Possible", "", "", "", "", "20.00"]


def test_students_without_a_new_score_are_left_out_of_the_import_never_zero(round_trip):
    """Their rows used to be kept with the exported cell, which put back what Canvas held at the
    export over a grade entered since; left out, they keep whatever Canvas holds."""
    result, out, _ = round_trip
    after = gradebook.read_gradebook(out / "gradebook_import.csv")
    for user in (1237, 9999, 1239, 1240):  # missing from the zip, Test Student, timed out, excused
        assert user not in after.student_rows, user
    assert any("Nguyen, Linh (ID 1237)" in m for m in result.missing)
    assert any("Khan, Omar" in m and "timed out" in m for m in result.not_scored)
    assert not any("Patel, Riya" in m for m in result.not_scored)


def test_an_excused_student_is_reported_as_excused_with_what_the_notebook_earned(round_trip):
    """Patel was listed under "Graded but not scored" with "(score 0)" for a notebook that earned
    full marks, and any unscored row read "score 0" too: the report now says the cell stays
    excused, and what the notebook earned, for the instructor alone."""
    result, out, _ = round_trip
    assert result.excused == [
        "Patel, Riya: patelriya_1240_50008_problem1_reaching.ipynb: the cell says EX in Canvas and is left so, "
        "out of the import and without feedback; the notebook earned 20 / 20, should you lift the excuse"
    ]
    report = (out / "report.txt").read_text(encoding="utf-8")
    section = next(part for part in report.split("\n\n") if part.startswith("Excused in Canvas"))
    assert section.splitlines() == [
        "Excused in Canvas (graded, but left excused: out of the import, no feedback): 1",
        f"  - {result.excused[0]}",
    ]
    unscored = canvas.excused_note("EX", {"status": "timed out", "scores": {}}, "0", result)
    assert unscored.endswith("without feedback; its grading gave no score (timed out)") and "earned" not in unscored


def test_unmatched_files_are_listed_never_dropped(round_trip):
    result, out, calls = round_trip
    unmatched = "\n".join(result.unmatched)
    assert "doejane_4321_50010_problem1_reaching.ipynb: no student with ID 4321" in unmatched
    assert "problem1_reaching.ipynb: not named as Canvas names submissions" in unmatched
    report = (out / "report.txt").read_text()
    feedback_names = {p.name for p in result.feedback.values()}
    for entry in ZIP_MEMBERS:  # every file of the zip is graded (it has feedback) or named in the report
        f = submissions.parse_submission_name(entry)
        assert entry in report or (f is not None and f"{f.prefix}_feedback.txt" in feedback_names), entry
    # the grader saw exactly one notebook per known student, in a private folder it no longer has
    assert calls[0]["mode"] == 0o700 and not calls[0]["folder"].exists()
    assert calls[0]["files"] == [
        "garcíaana_1235.ipynb",
        "khanomar_1239.ipynb",
        "leekim_1238.ipynb",
        "oharasean_1236.ipynb",
        "patelriya_1240.ipynb",
        "smithbob_1234.ipynb",
        "theroboticists_1241.ipynb",
    ]
    assert calls[0]["out"] == out / "batch"


def test_report_lists_late_resubmissions_groups_and_scaling(round_trip):
    result, out, _ = round_trip
    report = (out / "report.txt").read_text()
    assert result.late == ["García, Ana: garcíaana_LATE_1235_50002_problem1_reaching.ipynb"]
    assert result.resubmissions == [
        "O'Hara, Sean: problem1_reaching-1.ipynb (Canvas's name for a re-upload of problem1_reaching.ipynb)",
        "Lee, Kim: problem1_reaching-2.ipynb (Canvas's name for a re-upload of problem1_reaching.ipynb)",
    ]
    assert any("leekim_1238_50005_problem2_tracking.ipynb" in n for n in result.not_graded)
    assert any("oharasean_1236_50004_notes.pdf (not a notebook" in n for n in result.not_graded)
    # a grade the import overwrites is listed first, where it is seen before importing
    assert result.replaced == ["Lee, Kim: replaces the grade 10.00 already in Canvas with 16"]
    assert not any("replaces" in n for n in result.notes)
    assert report.split("\n\n")[1] == (
        "Grades already in Canvas that this import replaces: 1\n"
        "  - Lee, Kim: replaces the grade 10.00 already in Canvas with 16"
    )
    assert result.notes == [  # and nothing else: no name-differs note for Copy_of_..., no OS files skipped
        "the Problem's checks add up to 10 points and the column to 20: every score is scaled by 20/10, and so "
        "are each check's points in the feedback and rubric_canvas.csv here (the one in batch/ is out of 10)",
        "Wong, Mei: the file is named after 'theroboticists', not this student (a group submission?); the grade "
        "is written for this student only",
    ]
    assert "scaled by 20/10" in report and "Column: Problem 1: Reaching (4101) (points possible 20)" in report


def test_feedback_files_carry_the_score_and_every_message_and_canvas_can_match_them(round_trip):
    result, out, _ = round_trip
    # Patel Riya (1240) is excused in Canvas: no grade, and no feedback that would state one
    assert set(result.feedback) == {1234, 1235, 1236, 1238, 1239, 1241}
    smith = result.feedback[1234]
    assert smith.name == "smithbob_1234_50001_feedback.txt"
    text = smith.read_text()
    assert text.splitlines()[0] == "Feedback on Problem 1 for Smith, Bob"  # outputs.FEEDBACK_HEADER, as the batch's
    assert "Score: 20 / 20" in text and "(10 of the checks' 10 points, scaled)" in text
    for check, points in (("p1_ik", 6), ("p1_pd", 4), ("p1_ct", 6), ("p1_reach", 4)):  # in the column's 20
        assert f"- {check} ({points} / {points}): {check} message for smithbob_1234" in text
    timed_out = result.feedback[1239].read_text()
    assert "Not scored: timed out" in timed_out and timed_out.endswith("\nNotes:\n- the check ran out of time\n")
    assert "Notes:" not in text  # a graded row without notes has no Notes heading
    # Canvas's Re-upload Submissions: the first two all-digit parts are the user and attachment ids
    with zipfile.ZipFile(out / "feedback_upload.zip") as zf:
        names = sorted(zf.namelist())
    assert len(names) == 6
    for name in names:
        user_id, attachment_id = [p for p in name.split("_") if p.isdigit()][:2]
        submitted = next(e for e in ZIP_MEMBERS if e.startswith(name.removesuffix("_feedback.txt") + "_"))
        assert submissions.parse_submission_name(submitted).user_id == int(user_id)
        assert submissions.parse_submission_name(submitted).attachment_id == int(attachment_id)


def test_a_regrade_into_the_same_folder_leaves_no_stale_feedback(tmp_path):
    """The feedback files of an earlier zip used to stay in OUT/feedback beside the new ones."""
    out = tmp_path / "out"
    canvas.grade_canvas(FIXTURES / "submissions.zip", EXPORT, SPEC, out, grade=fake_grade([]))
    assert len(list((out / "feedback").iterdir())) == 6
    (out / "feedback" / "my notes.txt").write_text("the instructor's own file", encoding="utf-8")
    (out / "feedback" / "older_1_2_feedback.txt").write_text("problem1 feedback for someone", encoding="utf-8")
    members = {"smithbob_1234_50011_problem1_reaching-1.ipynb": fake_notebook(p1_ik=3)}
    result = canvas.grade_canvas(build_zip(tmp_path / "second.zip", members), EXPORT, SPEC, out, grade=fake_grade([]))
    assert sorted(p.name for p in (out / "feedback").iterdir()) == [
        "my notes.txt",  # not written by a grader: kept
        "older_1_2_feedback.txt",  # does not begin as a grader's feedback: kept
        "smithbob_1234_50011_feedback.txt",
    ]
    assert result.feedback == {1234: out / "feedback" / "smithbob_1234_50011_feedback.txt"}
    with zipfile.ZipFile(out / "feedback_upload.zip") as zf:
        assert zf.namelist() == ["smithbob_1234_50011_feedback.txt"]


def test_a_regrade_keeps_the_earlier_import_and_retires_the_earlier_batch(tmp_path):
    """A regrade used to overwrite the earlier import and report, and a regrade of a zip with no
    notebook left the earlier batch's grades.csv and feedback beside the new, empty import."""
    out = tmp_path / "out"
    canvas.grade_canvas(FIXTURES / "submissions.zip", EXPORT, SPEC, out, grade=fake_grade([]))
    first = {name: (out / name).read_bytes() for name in outputs.CANVAS_RESULTS}
    batch = out / "batch"  # what the real batch grader writes there (the fake one writes nothing)
    (batch / "feedback").mkdir(parents=True)
    (batch / "grades.csv").write_text("file,total\nsmithbob_1234.ipynb,20\n", encoding="utf-8")
    (batch / "batch.json").write_text('{"seed": 7}', encoding="utf-8")
    (batch / "feedback" / "smithbob_1234.txt").write_text(outputs.FEEDBACK_HEADER + "Bob", encoding="utf-8")
    only_text = build_zip(tmp_path / "text.zip", {"smithbob_1234_text.html": b"<p>no notebook</p>"})
    result = canvas.grade_canvas(only_text, EXPORT, SPEC, out, grade=fake_grade([]))
    assert result.scores == {}
    for name, earlier in first.items():
        assert (out / "previous" / name).read_bytes() == earlier, name
    assert (out / "gradebook_import.csv").read_bytes() != first["gradebook_import.csv"]
    assert not (batch / "grades.csv").exists() and not (batch / "batch.json").exists()
    assert (batch / "previous" / "grades.csv").read_text(encoding="utf-8").endswith("smithbob_1234.ipynb,20\n")
    assert json.loads((batch / "previous" / "batch.json").read_text(encoding="utf-8")) == {"seed": 7}
    assert list((batch / "feedback").iterdir()) == []


def test_semicolons_bom_crlf_and_decimal_commas_survive(tmp_path):
    text = EXPORT.read_text(encoding="utf-8")
    rows = list(csv.reader(io.StringIO(text)))
    rows[2] = [c.replace(".", ",") for c in rows[2]]  # a decimal-comma locale
    buf = io.StringIO()
    csv.writer(buf, delimiter=";", lineterminator="\r\n").writerows(rows)
    export = tmp_path / "export.csv"
    export.write_bytes(("\ufeff" + buf.getvalue()).encode("utf-8"))
    result = canvas.grade_canvas(FIXTURES / "submissions.zip", export, SPEC, tmp_path / "out", grade=fake_grade([]))
    assert result.points_possible == 20 and result.scores == EXPECTED_CELLS
    out = (tmp_path / "out" / "gradebook_import.csv").read_bytes()
    without_score = len(gradebook.read_gradebook(export).student_rows) - len(EXPECTED_CELLS)
    assert out.startswith("\ufeff".encode()) and out.count(b"\r\n") == len(rows) - without_score
    before, after = (
        gradebook.read_gradebook(export),
        gradebook.read_gradebook(tmp_path / "out" / "gradebook_import.csv"),
    )
    assert after.delimiter == ";" and after.rows[0] == [*before.rows[0][:5], COLUMN]
    assert after.rows[2] == [*before.rows[2][:5], "20,00"]  # the Points Possible row, decimal comma kept
    assert after.cell(1235, after.header.index(COLUMN)) == "15"


def test_the_canvas_rubric_beside_the_import_adds_up_to_the_columns_points(round_trip):
    """The rubric the batch writes is out of the checks' 10 while the column is out of 20: students
    saw a 10-point rubric beside a grade out of 20. The one beside the import is scaled alike."""
    import csv as csv_module
    import io

    result, out, _ = round_trip
    rows = list(csv_module.reader(io.StringIO((out / "rubric_canvas.csv").read_text(encoding="utf-8"))))[1:]
    tops = [float(row[6]) for row in rows]  # each criterion's first rating: its full marks
    assert sum(tops) == pytest.approx(result.points_possible) == pytest.approx(20.0)
    assert any("rubric_canvas.csv here" in n for n in result.notes)


def test_each_checks_points_in_the_feedback_are_the_canvas_rubrics(tmp_path):
    """The feedback said "Score: 11.25 / 15" and then each check out of the checks' own 10 points
    ("p1_ik (3 / 3)"), while the rubric students see beside it gives p1_ik 4.5: each check's points
    are now scaled as the rubric's, so the checks add up to the score."""
    export = _edited_export(tmp_path, ",10.00,20.00,20.00,", ",10.00,15.00,20.00,")  # 15 points, checks 10
    out = tmp_path / "out"
    result = canvas.grade_canvas(FIXTURES / "submissions.zip", export, SPEC, out, grade=fake_grade([]))
    text = result.feedback[1235].read_text(encoding="utf-8")  # García: 3, 2, 1.5 and 1 of 3, 2, 3 and 2
    assert "Score: 11.25 / 15" in text and "(7.5 of the checks' 10 points, scaled)" in text
    got = {line[2:].split(" (")[0]: line.split(" (")[1].split(")")[0] for line in text.splitlines() if line[:2] == "- "}
    assert got == {"p1_ik": "4.5 / 4.5", "p1_pd": "3 / 3", "p1_ct": "2.25 / 4.5", "p1_reach": "1.5 / 3"}
    rubric_rows = list(csv.reader(io.StringIO((out / "rubric_canvas.csv").read_text(encoding="utf-8"))))[1:]
    full_marks = {row[1].split(":")[0]: row[6] for row in rubric_rows}  # each criterion's first rating
    assert full_marks == {check: shown.split(" / ")[1] for check, shown in got.items()}
    assert sum(float(shown.split(" / ")[0]) for shown in got.values()) == float(result.scores[1235]) == 11.25


def test_a_notebook_of_another_problem_is_named_in_the_report(tmp_path):
    """Problem 2's work saved under Problem 1's file name was imported with no word: the batch's
    note on it (its metadata names problem2) now reaches the report, with the student's name."""
    from labsupport.instructor import judge

    note = judge.other_problem_note((ROOT / "notebooks" / "problem2_tracking.ipynb").read_bytes(), "problem1")
    base = fake_grade([])

    def grade(folder, spec_path, out):
        rows = base(folder, spec_path, out)
        rows[0]["notes"].append(note)
        return rows

    result = canvas.grade_canvas(FIXTURES / "submissions.zip", EXPORT, SPEC, tmp_path / "out", grade=grade)
    named = [n for n in result.notes if judge.OTHER_PROBLEM_MARK in n]
    assert len(named) == 1 and named[0].endswith(note) and ".ipynb: this notebook is problem2's" in named[0]
    assert named[0] in (tmp_path / "out" / "report.txt").read_text(encoding="utf-8")


def test_another_notebook_beside_the_graded_one_is_named_to_the_student_and_the_instructor(tmp_path):
    """A student handed in the blank hand-out under the Problem's name and the work as
    Untitled.ipynb: the blank one was graded, 0 was imported, and neither the feedback nor the
    report's notes said that another notebook was there (only the list of files not graded did)."""
    members = {
        "oharasean_1236_60003_problem1_reaching.ipynb": fake_notebook(p1_ik=0, p1_pd=0, p1_ct=0, p1_reach=0),
        "oharasean_1236_60011_Untitled.ipynb": fake_notebook(p1_ik=3, p1_pd=2, p1_ct=3, p1_reach=2),
        "oharasean_1236_60012_notes.pdf": b"%PDF-1.4 not a notebook",
        "smithbob_1234_60001_problem1_reaching.ipynb": fake_notebook(p1_ik=3, p1_pd=2, p1_ct=3, p1_reach=2),
        "smithbob_1234_60002_Untitled.ipynb": fake_notebook(p1_ik=0, p1_pd=0, p1_ct=0, p1_reach=0),
        "leekim_1238_60004_problem1_reaching.ipynb": fake_notebook(p1_ik=3, p1_pd=2, p1_ct=0, p1_reach=0),
        "leekim_1238_60005_problem1_reaching-1.ipynb": fake_notebook(p1_ik=3, p1_pd=2, p1_ct=3, p1_reach=0),
    }
    out = tmp_path / "out"
    result = canvas.grade_canvas(build_zip(tmp_path / "z.zip", members), EXPORT, SPEC, out, grade=fake_grade([]))
    assert result.scores[1236] == "0" and result.others == {1236: ["Untitled.ipynb"], 1234: ["Untitled.ipynb"]}
    sean = result.feedback[1236].read_text(encoding="utf-8")
    assert "File graded: problem1_reaching.ipynb\nAlso handed in, not graded: Untitled.ipynb. One notebook" in sean
    assert "Also handed in" in result.feedback[1234].read_text(encoding="utf-8")  # told, though full marks
    assert "Also handed in" not in result.feedback[1238].read_text(encoding="utf-8")  # an older upload only
    look = [n for n in result.notes if "also handed in" in n]
    assert (
        len(look) == 1 and "problem1_reaching.ipynb scored 0, and the student also handed in Untitled.ipynb" in look[0]
    )
    assert look[0] in (out / "report.txt").read_text(encoding="utf-8")


def test_no_scaling_when_the_column_is_worth_the_checks(tmp_path):
    export = tmp_path / "export.csv"
    export.write_text(
        EXPORT.read_text(encoding="utf-8").replace(",10.00,20.00,20.00,", ",10.00,10.00,20.00,"), encoding="utf-8"
    )
    result = canvas.grade_canvas(FIXTURES / "submissions.zip", export, SPEC, tmp_path / "out", grade=fake_grade([]))
    assert result.scores == {u: gradebook.format_score(float(s) / 2) for u, s in EXPECTED_CELLS.items()}
    assert not any("scaled" in n for n in result.notes)


# --- bad input ------------------------------------------------------------------------------------


@pytest.mark.parametrize(
    "evil",
    [
        "../escaped_1234_1_problem1_reaching.ipynb",
        "/etc/x_1234_1_p.ipynb",
        "a/../../x_1234_1_p.ipynb",
        "C:\\x_1234_1_p.ipynb",
        "..\\x_1234_1_p.ipynb",
    ],
)
def test_zip_slip_is_refused(tmp_path, evil):
    members = dict(ZIP_MEMBERS)
    members[evil] = fake_notebook(p1_ik=3)
    zpath = build_zip(tmp_path / "evil.zip", members)
    calls = []
    with pytest.raises(ValueError, match="points outside the folder"):
        canvas.grade_canvas(zpath, EXPORT, SPEC, tmp_path / "out", grade=fake_grade(calls))
    assert calls == [] and not (tmp_path / "escaped_1234_1_problem1_reaching.ipynb").exists()


def test_a_zip_with_two_entries_of_one_name_is_refused(tmp_path):
    """zipfile keeps both, and the grader took the last: which copy counted was a guess."""
    zpath = tmp_path / "twice.zip"
    name = "smithbob_1234_50001_problem1_reaching.ipynb"
    with zipfile.ZipFile(zpath, "w") as zf, warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)  # zipfile warns of the duplicate name
        zf.writestr(name, fake_notebook(p1_ik=3))
        zf.writestr(name, fake_notebook())
    calls = []
    with pytest.raises(ValueError, match=f"two entries named '{name}'"):
        canvas.grade_canvas(zpath, EXPORT, SPEC, tmp_path / "out", grade=fake_grade(calls))
    assert calls == []


#: Entries named as Info-ZIP and rubyzip store them: bytes without the UTF-8 flag.
LEGACY_MEMBERS = {
    "garcíaana_LATE_1235_50002_problem1_reaching.ipynb".encode(): ZIP_MEMBERS[
        "garcíaana_LATE_1235_50002_problem1_reaching.ipynb"
    ],
    "oharasean_1236_50003_Lösung_problem1.ipynb".encode(): fake_notebook(p1_ik=1.5, p1_pd=0, p1_ct=1.5, p1_reach=0),
    # code page 437 bytes, which are not UTF-8: read as code page 437
    "smithbob_1234_50001_Lösung_problem1.ipynb".encode("cp437"): ZIP_MEMBERS[
        "smithbob_1234_50001_problem1_reaching.ipynb"
    ],
}


def test_names_stored_without_the_utf8_flag_are_read_as_utf8_where_they_decode(tmp_path):
    """Python's zipfile reads such names as code page 437: "garcíaana" came out "garc├¡aana",
    and the file was reported as named after another student."""
    zpath = build_legacy_zip(tmp_path / "legacy.zip", LEGACY_MEMBERS)
    with zipfile.ZipFile(zpath) as zf:
        assert [info.flag_bits & 0x800 for info in zf.infolist()] == [0, 0, 0]
        assert zf.namelist() == [
            "garc├¡aana_LATE_1235_50002_problem1_reaching.ipynb",
            "oharasean_1236_50003_L├╢sung_problem1.ipynb",
            "smithbob_1234_50001_Lösung_problem1.ipynb",
        ]
        assert [info.filename for info in submissions.safe_zip_entries(zf)] == [
            "garcíaana_LATE_1235_50002_problem1_reaching.ipynb",
            "oharasean_1236_50003_Lösung_problem1.ipynb",
            "smithbob_1234_50001_Lösung_problem1.ipynb",
        ]
    result = canvas.grade_canvas(zpath, EXPORT, SPEC, tmp_path / "out", grade=fake_grade([]))
    assert result.scores == {1234: "20", 1235: "15", 1236: "6"} and result.not_scored == []
    assert not any("named after" in n for n in result.notes), result.notes
    assert result.late == ["García, Ana: garcíaana_LATE_1235_50002_problem1_reaching.ipynb"]
    assert result.feedback[1236].name == "oharasean_1236_50003_feedback.txt"
    assert "File graded: Lösung_problem1.ipynb" in result.feedback[1236].read_text(encoding="utf-8")
    # the safety checks read the name used
    slip = build_legacy_zip(tmp_path / "slip.zip", {"../é_1234_1_p.ipynb".encode(): b"{}"})
    with zipfile.ZipFile(slip) as zf, pytest.raises(ValueError, match=r"named '\.\./é_1234_1_p\.ipynb'"):
        submissions.safe_zip_entries(zf)


def test_a_name_flagged_utf8_that_is_not_says_the_zip_is_unreadable(tmp_path):
    """zipfile raised UnicodeDecodeError from deep inside: now the message says what to do."""
    zpath = build_zip(tmp_path / "bad.zip", {"smithbob_1234_50001_AAAA.ipynb": fake_notebook()})
    raw = bytearray(zpath.read_bytes().replace(b"AAAA", b"\xff\xfeAA"))
    for signature, offset in ((b"PK\x03\x04", 6), (b"PK\x01\x02", 8)):  # local header, central directory
        at = raw.find(signature) + offset
        raw[at : at + 2] = (0x800).to_bytes(2, "little")  # general-purpose flag: the name is UTF-8
    zpath.write_bytes(raw)
    with pytest.raises(ValueError, match="is not a readable zip .*download the submissions from Canvas again"):
        canvas.grade_canvas(zpath, EXPORT, SPEC, tmp_path / "out", grade=fake_grade([]))


def test_zip_bombs_are_refused_or_left_ungraded(tmp_path, monkeypatch):
    big = build_zip(
        tmp_path / "big.zip", {"smithbob_1234_50001_problem1_reaching.ipynb": fake_notebook(p1_ik=3) + b" " * 200_000}
    )
    monkeypatch.setattr(submissions, "MAX_ZIP_BYTES", 100_000)
    with pytest.raises(ValueError, match="would unpack to"):
        canvas.grade_canvas(big, EXPORT, SPEC, tmp_path / "out", grade=fake_grade([]))
    monkeypatch.setattr(submissions, "MAX_ZIP_BYTES", 10**9)
    monkeypatch.setattr(submissions, "MAX_NOTEBOOK_BYTES", 100_000)
    calls = []
    result = canvas.grade_canvas(big, EXPORT, SPEC, tmp_path / "out", grade=fake_grade(calls))
    assert calls == [] and result.scores == {}
    assert any("larger than" in m for m in result.not_scored)


def test_a_lying_size_header_does_not_get_past_the_limit(tmp_path):
    zpath = build_zip(tmp_path / "liar.zip", {"a_1_2_b.ipynb": b"x" * 5000})
    with zipfile.ZipFile(zpath) as zf:
        assert submissions.read_member(zf, zf.getinfo("a_1_2_b.ipynb"), limit=100) is None
        assert len(submissions.read_member(zf, zf.getinfo("a_1_2_b.ipynb"), limit=5000)) == 5000
    with zipfile.ZipFile(zpath) as zf:
        info = zf.getinfo("a_1_2_b.ipynb")
        info.file_size = 10  # the header claims 10 bytes: reading stops there, and the check sum says so
        with pytest.raises(zipfile.BadZipFile):
            submissions.read_member(zf, info, limit=100)


def test_a_damaged_notebook_is_reported_not_graded(tmp_path):
    data = bytearray(
        build_zip(
            tmp_path / "ok.zip", {"smithbob_1234_50001_problem1_reaching.ipynb": fake_notebook(p1_ik=3) * 20}
        ).read_bytes()
    )
    data[200:260] = bytes(60)  # zero a stretch of the compressed notebook
    (tmp_path / "damaged.zip").write_bytes(bytes(data))
    calls = []
    result = canvas.grade_canvas(tmp_path / "damaged.zip", EXPORT, SPEC, tmp_path / "out", grade=fake_grade(calls))
    assert calls == [] and result.scores == {}
    assert any("damaged in the zip" in m for m in result.not_scored)


def _smith_and_garcia(tmp_path: Path, text: str, points: float):
    """An export of Smith (ID 1234, row 2) and García (1235, row 3), read; and its Problem 1
    column, worth ``points``."""
    export = tmp_path / "export.csv"
    export.write_text(text, encoding="utf-8")
    book = gradebook.read_gradebook(export)
    assert book.student_rows == {1234: 2, 1235: 3}
    column = gradebook.choose_column(book, "problem1")
    assert book.points_possible(column) == points
    return book, column


def test_an_export_with_split_names_is_read_and_filled_alike(tmp_path):
    """Canvas's export option "show first and last names" begins the header LastName, FirstName,
    ID: the ID is the third column, the name is both cells, and the import keeps the layout."""
    book, column = _smith_and_garcia(
        tmp_path,
        "LastName,FirstName,ID,SIS Login ID,Section,Problem 1: Reaching (4101),Current Score\n"
        "    Points Possible,,,,,20.00,(read only)\n"
        "Smith,Bob,1234,bsmith,Section A,,90.00\n"
        "García,Ana,1235,agarcia,Section B,12.00,80.00\n",
        points=20.0,
    )
    assert (book.student_name(1234), book.student_name(1235)) == ("Smith, Bob", "García, Ana")
    assert gradebook.fill_column(book, column, {1234: "20", 1235: "15"}).splitlines() == [
        "LastName,FirstName,ID,SIS Login ID,Section,Problem 1: Reaching (4101)",
        "    Points Possible,,,,,20.00",
        "Smith,Bob,1234,bsmith,Section A,20",
        "García,Ana,1235,agarcia,Section B,15",
    ]


def test_a_notes_cell_of_several_lines_stays_in_its_students_record(tmp_path):
    """The Notes column is free text: a quoted cell with a line break is one record, and the
    import leaves the rest of that record alone; a column worth 1 point scales 10 to 1."""
    book, column = _smith_and_garcia(
        tmp_path,
        "Student,ID,SIS Login ID,Section,Notes,Problem 1: Reaching (4101)\n"
        "    Points Possible,,,,,1.00\n"
        '"Smith, Bob",1234,bsmith,Section A,"missed the lab,\nmade it up",\n'
        '"García, Ana",1235,agarcia,Section B,,0.50\n',
        points=1.0,
    )
    score = gradebook.format_score(gradebook.scaled_score(10.0, 10.0, book.points_possible(column)))
    assert gradebook.fill_column(book, column, {1234: score}).splitlines() == [
        "Student,ID,SIS Login ID,Section,Problem 1: Reaching (4101)",
        "    Points Possible,,,,1.00",
        '"Smith, Bob",1234,bsmith,Section A,1',
    ]


def test_a_csv_that_is_not_a_canvas_gradebook_says_so(tmp_path):
    other = tmp_path / "grades.csv"
    other.write_text("name,score\nBob,3\n", encoding="utf-8")
    with pytest.raises(
        ValueError,
        match=r"not a Canvas gradebook export: its first row should begin with "
        r"Student, ID.*Export Entire Gradebook",
    ):
        gradebook.read_gradebook(other)
    no_section = tmp_path / "nosection.csv"
    no_section.write_text("Student,ID,SIS Login ID,Problem 1 (4101)\n", encoding="utf-8")
    with pytest.raises(ValueError, match="no Section column"):
        gradebook.read_gradebook(no_section)
    latin = tmp_path / "latin.csv"
    latin.write_bytes(EXPORT.read_text(encoding="utf-8").encode("latin-1"))
    with pytest.raises(ValueError, match="not UTF-8"):
        gradebook.read_gradebook(latin)
    unclosed = tmp_path / "unclosed.csv"  # a cell's closing quote lost in an edit by hand
    unclosed.write_text(
        'Student,ID,SIS Login ID,Section,Problem 1 (4101)\n"Smith, Bob,1234,bsmith,A,\n"García, Ana",1235,a,B,\n',
        encoding="utf-8",
    )
    with pytest.raises(ValueError, match=r"gradebook export: a quote \(\"\) opened in row 2 is never closed"):
        gradebook.read_gradebook(unclosed)


def test_a_column_that_does_not_exist_lists_the_assignment_columns(tmp_path):
    book = gradebook.read_gradebook(EXPORT)
    with pytest.raises(ValueError) as err:
        gradebook.choose_column(book, "problem1", "Problem 3 (4103)")
    message = str(err.value)
    assert "no assignment column 'Problem 3 (4103)'" in message
    for header in ("'Task 1 quiz (4100)'", "'Problem 1: Reaching (4101)'", "'Problem 2: Tracking (4102)'"):
        assert header in message
    assert "Current Score" not in message and "Notes" not in message
    # the full header, the assignment id and the title all name the column; so does the Problem alone
    col = book.header.index(COLUMN)
    for name in (COLUMN, "4101", "Problem 1: Reaching", None):
        assert gradebook.choose_column(book, "problem1", name) == col
    with pytest.raises(ValueError, match="no assignment column of the gradebook names 'problem7'"):
        gradebook.choose_column(book, "problem7")


def test_cli_reports_a_bad_column_in_plain_words(tmp_path, capsys):
    with pytest.raises(SystemExit) as exit_:
        canvas.main(
            [
                "--spec",
                str(SPEC),
                str(FIXTURES / "submissions.zip"),
                "--gradebook",
                str(EXPORT),
                "--column",
                "Problem 9",
                "--out",
                str(tmp_path / "out"),
            ]
        )
    assert exit_.value.code == 2
    err = capsys.readouterr().err
    assert "no assignment column 'Problem 9'" in err and "Problem 1: Reaching (4101)" in err


def _cli_argv(out: Path, *options: str) -> list[str]:
    return ["--spec", str(SPEC), str(FIXTURES / "submissions.zip"), "--gradebook", str(EXPORT), "--out", str(out)] + [
        *options
    ]


def test_a_cli_regrade_says_last_what_moved_and_passes_timeout_to_the_batch(tmp_path, capsys, monkeypatch):
    """A regrade said that the import, report and zip moved into previous/ before grading, under
    every "graded ..." line, where the batch's own line was the one seen; and the command had no
    --timeout, which the batch grader has."""
    seen = []

    def run_batch(folder, spec_path, out, **options):
        seen.append(options)
        return fake_grade([])(folder, spec_path, out)

    monkeypatch.setattr(canvas, "run_batch", run_batch)
    out = tmp_path / "out"
    canvas.main(_cli_argv(out))
    first = capsys.readouterr().out.splitlines()
    assert first == [
        f"5 scores written to {out / 'gradebook_import.csv'} (Problem 1: Reaching (4101)); 2 unmatched files, "
        f"2 students with nothing graded: see {out / 'report.txt'}"
    ]
    canvas.main(_cli_argv(out, "--timeout", "30"))
    second = capsys.readouterr().out.splitlines()
    assert second == [
        first[0],
        "the earlier run's gradebook_import.csv, report.txt, feedback_upload.zip, rubric_canvas.csv, feedback/ "
        f"(6 files) are now in {out / 'previous'}",
    ]
    assert [options["timeout"] for options in seen] == [900.0, 30.0]  # the batch's default, then --timeout
    with pytest.raises(SystemExit) as stop:
        canvas.main(_cli_argv(out, "--timeout", "0"))
    assert stop.value.code == 2
    assert "--timeout must be a positive number of seconds, got 0.0" in capsys.readouterr().err


def test_an_unzipped_download_is_refused_saying_to_give_the_zip(tmp_path, capsys):
    """It said "no submissions zip at FOLDER", as if the path were wrong."""
    folder = tmp_path / "submissions"
    folder.mkdir()
    (folder / "smithbob_1234_50001_problem1_reaching.ipynb").write_bytes(fake_notebook(p1_ik=3))
    with pytest.raises(SystemExit) as stop:
        canvas.main(["--spec", str(SPEC), str(folder), "--gradebook", str(EXPORT), "--out", str(tmp_path / "out")])
    err = capsys.readouterr().err
    assert stop.value.code == 2 and not (tmp_path / "out").exists()
    assert f"{folder} is a folder: give the zip as Canvas gives it (the assignment's Download Submissions)" in err


# --- end to end (slow: grades one real notebook with the batch grader, about a minute) ----------


def test_end_to_end_with_the_real_batch_grader(tmp_path):
    """SLOW. The master notebook of Problem 1, submitted through Canvas, earns full marks in the import."""
    master = (ROOT / "notebooks" / "masters" / "problem1_reaching.ipynb").read_bytes()
    zpath = build_zip(
        tmp_path / "submissions.zip",
        {"smithbob_1234_50001_problem1_reaching.ipynb": master, "garcíaana_LATE_1235_50002_notes.pdf": b"%PDF"},
    )
    shutil.copy(EXPORT, tmp_path / "export.csv")
    result = canvas.grade_canvas(zpath, tmp_path / "export.csv", SPEC, tmp_path / "out", jobs=1)
    assert result.scores == {1234: "20"}, (tmp_path / "out" / "report.txt").read_text()
    after = gradebook.read_gradebook(tmp_path / "out" / "gradebook_import.csv")
    assert after.cell(1234, after.header.index(COLUMN)) == "20"
    assert list(after.student_rows) == [1234]  # Ana sent no notebook: left out of the import
    assert (tmp_path / "out" / "batch" / "grades.csv").is_file()


def test_a_rezipped_download_is_graded_as_the_original(tmp_path):
    """Unzipped and zipped again on a Mac, the download holds its files in a folder, a
    ``__MACOSX/`` copy of each and ``._`` resource forks. The folder put the feedback file's path
    under feedback/ (a crash after grading, with no import written), and a ``._`` copy, which
    is not a notebook, could be taken for the student's file and scored 0."""
    real = fake_notebook(p1_ik=3, p1_pd=2, p1_ct=3, p1_reach=2)
    members = {
        "._smithbob_1234_50001_problem1_reaching.ipynb": b"\x00\x05\x16\x07 AppleDouble",
        "submissions/smithbob_1234_50001_problem1_reaching.ipynb": real,
        "__MACOSX/submissions/._smithbob_1234_50001_problem1_reaching.ipynb": b"\x00\x05\x16\x07",
        "submissions/.DS_Store": b"\x00\x00\x00\x01Bud1",
    }
    out = tmp_path / "out"
    result = canvas.grade_canvas(build_zip(tmp_path / "mac.zip", members), EXPORT, SPEC, out, grade=fake_grade([]))
    assert result.scores[1234] == "20" and not result.unreadable
    assert result.feedback[1234] == out / "feedback" / "smithbob_1234_50001_feedback.txt"
    assert any("3 files the operating system added" in note for note in result.notes)
    with zipfile.ZipFile(out / "feedback_upload.zip") as zf:
        assert zf.namelist() == ["smithbob_1234_50001_feedback.txt"]


def test_another_problems_notebook_is_left_out_not_scored_zero(tmp_path):
    """The Problem 2 zip given with --problem problem1 wrote a 0 for every student, with a note
    at the end of the report only."""
    members = {"smithbob_1234_50001_problem2_tracking.ipynb": fake_notebook(p1_ik=0, p1_pd=0, p1_ct=0, p1_reach=0)}
    result = canvas.grade_canvas(
        build_zip(tmp_path / "p2.zip", members), EXPORT, SPEC, tmp_path / "out", grade=fake_grade([])
    )
    assert 1234 not in result.scores
    assert any(
        "problem2_tracking.ipynb is problem2's notebook" in m and "--problem problem2" in m for m in result.missing
    )


def test_a_bad_output_folder_or_spec_is_refused_before_grading(tmp_path):
    calls = []
    afile = tmp_path / "afile"
    afile.write_text("not a folder")
    with pytest.raises(ValueError, match="is a file: give --out a folder"):
        canvas.grade_canvas(FIXTURES / "submissions.zip", EXPORT, SPEC, afile, grade=fake_grade(calls))
    with pytest.raises(ValueError, match="cannot write the output folder"):
        canvas.grade_canvas(FIXTURES / "submissions.zip", EXPORT, SPEC, afile / "sub", grade=fake_grade(calls))
    wrong = tmp_path / "batch.json"
    wrong.write_text('{"seed": 1, "date": "today"}')
    with pytest.raises(ValueError, match="is not an autograder spec of this labsupport's checks"):
        canvas.grade_canvas(FIXTURES / "submissions.zip", EXPORT, wrong, tmp_path / "out", grade=fake_grade(calls))
    assert not calls


def test_the_batch_grader_refuses_a_file_that_is_not_a_spec(tmp_path):
    """``--spec`` given the batch's own batch.json graded every row as an error, then stopped
    with KeyError: 'checks'."""
    from labsupport.instructor.batch import run_batch

    wrong = tmp_path / "batch.json"
    wrong.write_text('{"seed": 1, "date": "today"}')
    with pytest.raises(ValueError, match="is not an autograder spec of this labsupport's checks"):
        run_batch(tmp_path, wrong, tmp_path / "out")


def _edited_export(tmp_path: Path, old: str, new: str) -> Path:
    export = tmp_path / "export.csv"
    text = EXPORT.read_text(encoding="utf-8")
    assert old in text
    export.write_text(text.replace(old, new), encoding="utf-8")
    return export


def test_two_columns_of_one_title_are_told_apart_by_their_ids(tmp_path):
    """Two columns titled the same made --column report that none matched; and "Problem 10"
    counted as naming problem1."""
    header = "Problem 2: Tracking (4102)"
    book = gradebook.read_gradebook(_edited_export(tmp_path, header, "Problem 1: Reaching (4201)"))
    with pytest.raises(ValueError, match=r"2 assignment columns match --column 'Problem 1: Reaching'.*assignment id"):
        gradebook.choose_column(book, "problem1", "Problem 1: Reaching")
    assert book.header[gradebook.choose_column(book, "problem1", "4201")] == "Problem 1: Reaching (4201)"
    with pytest.raises(ValueError, match="several assignment columns .* 'Problem 1: Reaching \\(4101\\)'"):
        gradebook.choose_column(book, "problem1")
    tenth = gradebook.read_gradebook(_edited_export(tmp_path, header, "Problem 10: Extra (4110)"))
    assert tenth.header[gradebook.choose_column(tenth, "problem1")] == COLUMN


@pytest.mark.parametrize("points", ["0.00", "", "n/a"])
def test_points_possible_that_cannot_scale_a_score_is_refused(tmp_path, points):
    """0 points possible wrote every score as 0 (with a note), and a blank cell gave an error that
    did not say what to do."""
    export = _edited_export(tmp_path, ",10.00,20.00,20.00,", f",10.00,{points},20.00,")
    with pytest.raises(ValueError, match="not a positive number: set the assignment's points in Canvas"):
        canvas.grade_canvas(FIXTURES / "submissions.zip", export, SPEC, tmp_path / "out", grade=fake_grade([]))


def test_two_points_possible_rows_are_refused(tmp_path):
    """A second Points Possible row was read silently, the last one winning."""
    (line,) = [x for x in EXPORT.read_text(encoding="utf-8").splitlines() if "Points Possible" in x]
    export = _edited_export(tmp_path, line, line.replace("20.00,20.00", "10.00,20.00") + "\n" + line)
    with pytest.raises(ValueError, match="both say Points Possible"):
        gradebook.read_gradebook(export)


def test_a_column_chosen_by_hand_that_does_not_name_the_problem_is_flagged_first(tmp_path):
    """``--column "Task 1 quiz"`` filled the quiz with Problem 1 scores, with "Notes: none"."""
    out = tmp_path / "out"
    canvas.grade_canvas(FIXTURES / "submissions.zip", EXPORT, SPEC, out, column="4100", grade=fake_grade([]))
    report = (out / "report.txt").read_text(encoding="utf-8").splitlines()
    assert report[1] == "Column: Task 1 quiz (4100) (points possible 10)"
    assert report[2].startswith("Check first: the column's title does not name problem1")
    canvas.grade_canvas(FIXTURES / "submissions.zip", EXPORT, SPEC, out, column="4101", grade=fake_grade([]))
    assert not any("Check first" in line for line in (out / "report.txt").read_text(encoding="utf-8").splitlines())


def test_a_title_of_the_problem_alone_is_not_flagged():
    """The id in parentheses is not part of the title: "Problem 1 (4101)" names problem1."""
    assert gradebook.column_warning("Problem 1 (4101)", "problem1") == ""
    assert gradebook.column_warning("Problem 10 (4110)", "problem1").startswith("Check first")


def test_a_sandbox_that_cannot_start_ends_the_command_with_what_to_do(tmp_path, capsys, monkeypatch):
    """Where bubblewrap cannot run, the Canvas command ends as the batch does, with its message and
    exit status 2, where it ended in a traceback."""

    def run_batch(folder, spec_path, out, **options):
        raise isolation.SandboxUnavailable("bubblewrap (bwrap) is not installed: apt install bubblewrap")

    monkeypatch.setattr(canvas, "run_batch", run_batch)
    with pytest.raises(SystemExit) as stop:
        canvas.main(_cli_argv(tmp_path / "out"))
    assert stop.value.code == 2
    assert capsys.readouterr().err == (
        "python -m labsupport.instructor.canvas: cannot grade: bubblewrap (bwrap) is not installed: apt install "
        "bubblewrap\n"
    )


def _graded_then_failing(out, error: BaseException, monkeypatch) -> None:
    """One Canvas run into ``out`` (a fake batch), after which the batch raises ``error``: the
    next run is a regrade that fails once it has moved the first into ``out/previous``."""
    monkeypatch.setattr(
        canvas, "run_batch", lambda folder, spec_path, out, **options: fake_grade([])(folder, spec_path, out)
    )
    canvas.main(_cli_argv(out))

    def run_batch(folder, spec_path, out, **options):
        raise error

    monkeypatch.setattr(canvas, "run_batch", run_batch)


def test_a_regrade_that_cannot_grade_still_says_where_the_earlier_run_went(tmp_path, capsys, monkeypatch):
    """A regrade moves the earlier run into previous/ before it grades. When the grading then
    failed (here bubblewrap cannot start), the error was all the command said, and the earlier
    import seemed lost: the error now ends with where it went."""
    out = tmp_path / "out"
    _graded_then_failing(
        out, isolation.SandboxUnavailable("bubblewrap (bwrap) is not installed: apt install bubblewrap"), monkeypatch
    )
    capsys.readouterr()
    with pytest.raises(SystemExit) as stop:
        canvas.main(_cli_argv(out))
    assert stop.value.code == 2
    assert capsys.readouterr().err.splitlines() == [
        "python -m labsupport.instructor.canvas: cannot grade: bubblewrap (bwrap) is not installed: apt install "
        "bubblewrap",
        "(the earlier run's gradebook_import.csv, report.txt, feedback_upload.zip, rubric_canvas.csv, feedback/ "
        f"(6 files) are now in {out / 'previous'})",
    ]
    assert (out / "previous" / "gradebook_import.csv").is_file()


def test_a_regrade_stopped_by_ctrl_c_says_where_the_earlier_run_went(tmp_path, capsys, monkeypatch):
    """Stopped mid-grading (Ctrl-C), a regrade printed only Python's traceback, although it had
    already moved the earlier import into previous/: it now says where, before the traceback."""
    out = tmp_path / "out"
    _graded_then_failing(out, KeyboardInterrupt(), monkeypatch)
    capsys.readouterr()
    with pytest.raises(KeyboardInterrupt):
        canvas.main(_cli_argv(out))
    assert capsys.readouterr().err == (
        "stopped; the earlier run's gradebook_import.csv, report.txt, feedback_upload.zip, rubric_canvas.csv, "
        f"feedback/ (6 files) are now in {out / 'previous'}\n"
    )
    assert (out / "previous" / "gradebook_import.csv").is_file()


@pytest.mark.parametrize("points_possible", ["6.66", "13.33", "7.77", "9.99", "6.67"])
def test_each_checks_points_in_the_feedback_add_up_to_the_score(tmp_path, points_possible):
    """Each check's points, scaled to the column and rounded to hundredths one by one, could add
    up to a hundredth more or less than the score above them (García's 3, 2, 1.5 and 1 in a
    column of 6.66 points: 2, 1.33, 1 and 0.67 under a score of 4.99). They are now rounded so
    that they add up to it, the largest remainders rounded up first."""
    export = _edited_export(tmp_path, ",10.00,20.00,20.00,", f",10.00,{points_possible},20.00,")
    out = tmp_path / "out"
    result = canvas.grade_canvas(FIXTURES / "submissions.zip", export, SPEC, out, grade=fake_grade([]))
    rubric_rows = list(csv.reader(io.StringIO((out / "rubric_canvas.csv").read_text(encoding="utf-8"))))[1:]
    full_marks = [row[6] for row in rubric_rows]  # each criterion's first rating
    names = [row[1].split(":")[0] for row in rubric_rows]
    assert round(sum(float(p) for p in full_marks), 2) == float(points_possible)
    scored = 0
    for user, path in result.feedback.items():
        lines = path.read_text(encoding="utf-8").splitlines()
        checks = [line for line in lines if line[:2] == "- " and line[2:].split(" (")[0] in names]
        shown = [line.split(" (")[1].split(")")[0].split(" / ") for line in checks]
        assert [most for _, most in shown] == full_marks  # the feedback's full marks are the rubric's
        if user in result.scores:
            score = next(line for line in lines if line.startswith("Score: ")).split()[1]
            assert round(sum(float(got) for got, _ in shown), 2) == float(score) == float(result.scores[user]), lines
            scored += 1
    assert scored >= 3


def test_a_gradebook_given_as_a_folder_is_named_a_folder(tmp_path, capsys):
    """It said "no gradebook at FOLDER", as if the path were wrong."""
    argv = [str(tmp_path) if arg == str(EXPORT) else arg for arg in _cli_argv(tmp_path / "out")]
    with pytest.raises(SystemExit) as stop:
        canvas.main(argv)
    assert stop.value.code == 2
    assert f"--gradebook {tmp_path} is a folder: give the CSV file Canvas" in capsys.readouterr().err
