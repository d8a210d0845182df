"""The Problems' grading: in-notebook feedback, the generated notebooks, and the batch grader
on the committed set of broken and hostile submissions (tests/hostile/)."""

import csv
import hashlib
import shutil
import subprocess
import sys
import time
from pathlib import Path

import nbformat
import numpy as np
import pytest
from nbclient import NotebookClient

import labsupport  # noqa: F401
from labsupport.controllers import joint_space
from labsupport.dynamics import bias_forces, mass_matrix
from labsupport.grading import check
from labsupport.instructor import assign
from labsupport.grading import problem1, problem2
from labsupport.grading.feedback import PASS, NOT_IMPLEMENTED, DirectProbe
from labsupport.kinematics import spatial_3r

ROOT = Path(__file__).resolve().parents[1]
HOSTILE = ROOT / "tests" / "hostile"


# --- in-notebook feedback -------------------------------------------------------------------

def ct_solution(model, data, q_d, Kp, Kd):
    return joint_space.ct_joint_torque(mass_matrix(model, data), bias_forces(data), data.qpos, data.qvel,
                                       q_d, 0.0, 0.0, Kp, Kd)


def test_ik_feedback_names_what_is_right_and_wrong():
    def wrong_elbow(x, elbow_up=True):
        q = spatial_3r.inverse_kinematics(x, elbow_up)
        return q + np.array([0.0, 0.3, 0.0])          # pan right, elbow wrong
    r = problem1.check_ik(DirectProbe({"ik_3r": wrong_elbow}))
    assert r.score == 0 and "the pan angle is right, but the elbow-up solution puts the end effector" in r.message
    one_branch = problem1.check_ik(DirectProbe({"ik_3r": lambda x, elbow_up=True: spatial_3r.inverse_kinematics(x)}))
    assert 0 < one_branch.score < 1 and "same solution" in one_branch.message
    swapped = problem1.check_ik(DirectProbe({"ik_3r": lambda x, elbow_up=True:
                                            spatial_3r.inverse_kinematics(x, not elbow_up)}))
    assert "swapped" in swapped.message
    good = problem1.check_ik(DirectProbe({"ik_3r": lambda x, elbow_up=True: spatial_3r.inverse_kinematics(x, elbow_up)}))
    assert good.status == PASS and good.score == 1


def test_controller_feedback_in_plain_words():
    probe = lambda **ns: DirectProbe(ns)
    r = problem1.check_ct(probe(ct_joint_torque=lambda m, d, q_d, Kp, Kd: None))
    assert r.status == NOT_IMPLEMENTED and "ct_joint_torque returned None" in r.message
    r = problem1.check_pd(probe(pd_torque=lambda m, d, q_d, Kp, Kd: np.zeros(2)))
    assert "the torque from pd_torque has shape (2,), expected (3,)" in r.message
    r = problem1.check_ct(probe(ct_joint_torque=lambda m, d, q_d, Kp, Kd:
                                mass_matrix(m, d) @ (Kp * (q_d - d.qpos) - Kd * d.qvel)))
    assert r.score == 0.25 and "h(q, q̇)" in r.message and "missing" in r.message
    r = problem1.check_pd(probe(pd_torque=lambda m, d, q_d, Kp, Kd: Kp * (q_d - d.qpos)))
    assert r.score == 0.5 and "damping term −Kd q̇ is missing" in r.message
    r = problem1.check_pd(probe(pd_torque=lambda m, d, q_d, Kp, Kd: Kp * (d.qpos - q_d) + Kd * d.qvel))
    assert r.score == 0 and "wrong sign" in r.message
    r = problem1.check_pd(probe(pd_torque=lambda m, d, q_d, Kp, Kd: 1 / 0))
    assert "pd_torque raised ZeroDivisionError" in r.message
    r = problem1.check_pd(probe())
    assert "pd_torque is not defined" in r.message


def test_os_ct_without_jdot_gets_half_marks_and_is_told_so():
    from labsupport.controllers.operational_space import os_ct_torque
    from labsupport.dynamics import site_jacobian

    def no_jdot(model, data, x_d, xd_d, xdd_d, Kp, Kd):
        J = site_jacobian(model, data, "end_effector")[:3]
        return os_ct_torque(mass_matrix(model, data), bias_forces(data), J, np.zeros(3),
                            data.site("end_effector").xpos, J @ data.qvel, x_d, xd_d, xdd_d, Kp, Kd)
    r = problem2.check_os_ct(DirectProbe({"ct_op_torque": no_jdot}))
    assert r.score == 0.5 and "J̇q̇" in r.message


def test_check_prints_feedback_and_never_raises(capsys):
    result = check("p1_ct", {"ct_joint_torque": ct_solution})
    assert result.status == PASS and "✔ [p1_ct]" in capsys.readouterr().out
    result = check("p1_reach", {"ct_joint_torque": ct_solution})
    assert result.status == PASS
    assert check("p2_start", {}).score == 0
    with pytest.raises(ValueError, match="no check named"):
        check("p9", {})


# --- generated notebooks --------------------------------------------------------------------

def test_student_notebooks_match_the_masters():
    """Regenerating from the masters gives exactly what is committed (no drift)."""
    files = assign.outputs(ROOT)
    assert len(files) == 4
    for path, text in files.items():
        assert path.read_text(encoding="utf-8") == text, f"{path} drifted: run python -m labsupport.instructor.assign"


def test_student_notebooks_hide_the_solutions():
    for name in ("problem1_reaching", "problem2_tracking"):
        master = (ROOT / "notebooks" / "masters" / f"{name}.ipynb").read_text(encoding="utf-8")
        student = (ROOT / "notebooks" / f"{name}.ipynb").read_text(encoding="utf-8")
        assert "BEGIN SOLUTION" in master and "BEGIN SOLUTION" not in student
        assert "**Solution.**" in master and "**Solution.**" not in student
        assert "STUDENT:" not in student and "TODO" in student
        nb = nbformat.reads(student, as_version=4)
        assert all(c.get("outputs", []) == [] for c in nb.cells if c.cell_type == "code")
        assert nb.metadata["labsupport_grading"]["checks"]


def test_assign_rejects_unbalanced_markers():
    with pytest.raises(assign.MasterError, match="without # END SOLUTION"):
        assign.strip_code("x = 1\n# BEGIN SOLUTION\ny = 2", "cell 3")
    assert assign.strip_code("def f():\n    # BEGIN SOLUTION\n    return 1\n    # END SOLUTION\n"
                             "    # STUDENT: return None", "c") == "def f():\n    return None"


@pytest.mark.parametrize("name", ["problem1_reaching", "problem2_tracking"])
def test_student_notebook_runs_and_reports_not_implemented(name, tmp_path):
    nb = nbformat.read(str(ROOT / "notebooks" / f"{name}.ipynb"), as_version=4)
    NotebookClient(nb, timeout=300, kernel_name="python3", resources={"metadata": {"path": str(tmp_path)}}).execute()
    text = "".join(o.get("text", "") for c in nb.cells if c.cell_type == "code" for o in c.outputs)
    n_checks = len(nb.metadata["labsupport_grading"]["checks"])
    assert text.count("not implemented yet") >= n_checks
    assert "✔" not in text and "Traceback" not in text


# --- batch grading --------------------------------------------------------------------------

TIMEOUT = 90.0
FULL = {"p1_ik": 3, "p1_pd": 2, "p1_ct": 3, "p1_reach": 2}
#: file -> (scores, status, words the reason must contain)
EXPECTED = {
    "master.ipynb": (FULL, "graded", ["all checks passed"]),
    "student.ipynb": ({}, "graded", ["p1_ik: not implemented yet", "p1_reach: not implemented yet"]),
    "raises.ipynb": ({"p1_ik": 3, "p1_pd": 2}, "graded", ["raised ZeroDivisionError", "ct_joint_torque raised RuntimeError"]),
    "hangs_cell.ipynb": (FULL, "graded", ["timed out"]),
    "hangs_forever.ipynb": ({}, "graded", ["did not finish within"]),
    "hangs_in_call.ipynb": ({"p1_ik": 3, "p1_ct": 3, "p1_reach": 2}, "graded", ["p1_pd:", "did not return"]),
    "returns_nan.ipynb": ({"p1_ik": 3, "p1_pd": 2}, "graded", ["contains NaN"]),
    "deleted_cell.ipynb": ({"p1_ik": 3, "p1_ct": 3, "p1_reach": 2}, "graded", ["pd_torque is not defined"]),
    "reordered.ipynb": (FULL, "graded", ["raised NameError"]),
    "invalid_json.ipynb": ({}, "unreadable", ["invalid JSON"]),
    "monkeypatch.ipynb": ({}, "graded", ["the notebook replaced", "IK: 0 of 10"]),
    "writes_deletes_files.ipynb": (FULL, "graded", ["wrote files: junk.txt", "deleted files",
                                                    "modified its copy of labsupport"]),
    "exits.ipynb": ({}, "graded", ["ended the grading process"]),
    "fake_outputs.ipynb": ({}, "graded", ["not implemented yet"]),
    "kills_grader.ipynb": ({}, "error", ["killed"]),
}


def _grader_hash() -> str:
    """Hash of the files a hostile submission aims at: the grader and the arm's model."""
    h = hashlib.sha256()
    for p in sorted((ROOT / "labsupport" / "grading").glob("*.py")) + [ROOT / "models" / "spatial_3r.xml"]:
        h.update(str(p).encode() + p.read_bytes())
    return h.hexdigest()


@pytest.fixture(scope="module")
def batch(tmp_path_factory):
    subs = tmp_path_factory.mktemp("submissions")
    for p in HOSTILE.glob("*.ipynb"):
        shutil.copy(p, subs / p.name)
    shutil.copy(ROOT / "notebooks" / "masters" / "problem1_reaching.ipynb", subs / "master.ipynb")
    shutil.copy(ROOT / "notebooks" / "problem1_reaching.ipynb", subs / "student.ipynb")
    before = {p.name: p.read_bytes() for p in subs.iterdir()}
    code_before = _grader_hash()
    out = tmp_path_factory.mktemp("grades")
    start = time.monotonic()
    proc = subprocess.run([sys.executable, "-m", "labsupport.instructor.batch", "--problem", "problem1", str(subs),
                           "--out", str(out), "--jobs", "2", "--timeout", str(TIMEOUT)],
                          cwd=ROOT, capture_output=True, text=True, timeout=900)
    elapsed = time.monotonic() - start
    assert proc.returncode == 0, proc.stderr
    with open(out / "grades.csv", newline="", encoding="utf-8") as f:
        rows = {r["file"]: r for r in csv.DictReader(f)}
    return {"rows": rows, "out": out, "elapsed": elapsed, "subs": subs, "before": before,
            "code_before": code_before, "stdout": proc.stdout}


def test_hostile_set_is_committed():
    assert len(list(HOSTILE.glob("*.ipynb"))) >= 8


def test_every_file_gets_a_row(batch):
    assert set(batch["rows"]) == set(EXPECTED)


@pytest.mark.parametrize("name", sorted(EXPECTED))
def test_row_scores_and_reason(batch, name):
    scores, status, words = EXPECTED[name]
    row = batch["rows"][name]
    assert row["status"] == status
    for check_name in FULL:
        assert float(row[check_name]) == scores.get(check_name, 0), (check_name, row["reason"])
    assert float(row["total"]) == sum(scores.values()) and float(row["max"]) == 10
    for w in words:
        assert w in row["reason"], (w, row["reason"])
    feedback = (batch["out"] / "feedback" / (Path(name).stem + ".txt")).read_text(encoding="utf-8")
    assert f"Score: {sum(scores.values()):g} / 10" in feedback


def test_batch_finishes_within_its_time_limits(batch):
    # every submission within its own limit (plus start-up), the batch well within the sum of them
    assert batch["elapsed"] < len(EXPECTED) * TIMEOUT / 2
    assert "graded in" in batch["stdout"]


def test_nothing_outside_the_scratch_copies_changed(batch):
    assert {p.name: p.read_bytes() for p in batch["subs"].iterdir()} == batch["before"]
    assert _grader_hash() == batch["code_before"]


def test_masters_get_full_marks_on_problem2(tmp_path):
    subs = tmp_path / "subs"
    subs.mkdir()
    shutil.copy(ROOT / "notebooks" / "masters" / "problem2_tracking.ipynb", subs / "master.ipynb")
    shutil.copy(ROOT / "notebooks" / "problem2_tracking.ipynb", subs / "student.ipynb")
    subprocess.run([sys.executable, "-m", "labsupport.instructor.batch", "--problem", "problem2", str(subs),
                    "--out", str(tmp_path / "out"), "--timeout", "300"], cwd=ROOT, check=True, capture_output=True)
    with open(tmp_path / "out" / "grades.csv", newline="", encoding="utf-8") as f:
        rows = {r["file"]: r for r in csv.DictReader(f)}
    assert rows["master.ipynb"]["total"] == "10" and rows["master.ipynb"]["reason"] == "all checks passed"
    assert rows["student.ipynb"]["total"] == "0"
    assert "p2_osct: not implemented yet" in rows["student.ipynb"]["reason"]
