"""The shared-code report (``similarity.csv``, ``similarity.html``) that the batch grader writes.

It must name a copy of the master's solution or of another student, even with its variables
renamed and its comments dropped, and leave independently written right answers unnamed; it
shows student code only as escaped text; and nothing in it can cost the grades.
"""

import csv
import json
import re
import shutil
import subprocess
import sys
import zipfile
from pathlib import Path

import nbformat
import numpy as np
import pytest
from hostile.build import unusual_problem2

from labsupport.instructor import batch, canvas, compare, similarity, submissions
from labsupport.instructor.assign import load_spec

ROOT = Path(__file__).resolve().parents[1]
SPEC1 = load_spec(ROOT / "tests" / "autograder" / "problem1.json")
SPEC2 = load_spec(ROOT / "tests" / "autograder" / "problem2.json")
BLANK = (ROOT / SPEC1["student"]).read_bytes()
#: Problem 1 solved another way (numerical IK, gain matrices, mj_mulM), written apart from the master.
UNUSUAL = (ROOT / "tests" / "hostile" / "unusual_but_right.ipynb").read_bytes()
#: Problem 2's master with its three functions written another way.
UNUSUAL2 = nbformat.writes(unusual_problem2(nbformat.read(ROOT / SPEC2["master"], as_version=4))).encode()
#: Names a copier changes, as a whole word.
RENAMES = {"r": "reach", "theta": "elbow", "q1": "pan", "q2": "lift", "qddot_cmd": "acc", "M": "inertia"}


def disguised_copy(spec: dict) -> bytes:
    """The student notebook with each TODO answered by the master's solution, its variables
    renamed and its comments dropped: what a student who found the master would hand in."""
    master = nbformat.read(ROOT / spec["master"], as_version=4)
    student = nbformat.read(ROOT / spec["student"], as_version=4)
    solutions = {c.id: c.source for c in master.cells if c.cell_type == "code" and "# BEGIN SOLUTION" in c.source}
    cells = {c.id: c for c in student.cells}
    assert solutions and set(solutions) <= set(cells)  # the student cells keep the masters' ids
    for cell_id, source in solutions.items():
        cell = cells[cell_id]
        lines = [line for line in source.splitlines() if "SOLUTION" not in line and "# STUDENT:" not in line]
        code = re.sub(r"\s*#.*", "", "\n".join(lines))
        for old, new in RENAMES.items():
            code = re.sub(rf"\b{old}\b", new, code)
        cell.source = code
    return nbformat.writes(student).encode()


def canvas_zip(path: Path, members: dict[str, bytes]) -> Path:
    """A zip holding ``members`` (entry name -> bytes), as Canvas's "Download Submissions" zips."""
    with zipfile.ZipFile(path, "w", zipfile.ZIP_DEFLATED) as zf:
        for name, data in members.items():
            zf.writestr(name, data)
    return path


def _pairs(reports: dict[str, str]) -> dict[tuple[str, str], dict]:
    rows = csv.DictReader(reports["similarity.csv"].splitlines())
    return {(r["file"], r["other"]): r for r in rows}


@pytest.mark.parametrize("spec", [SPEC1, SPEC2], ids=["problem1", "problem2"])
def test_a_disguised_copy_of_the_master_is_named_and_an_independent_answer_is_not(spec):
    unusual = UNUSUAL if spec is SPEC1 else UNUSUAL2
    copy = disguised_copy(spec)
    assert b"radius" in copy or b"inertia" in copy  # the renames took
    pairs = _pairs(similarity.similarity_reports({"copier.ipynb": copy, "other.ipynb": unusual}, spec))
    assert set(pairs) == {("copier.ipynb", similarity.MASTER)}
    row = pairs["copier.ipynb", similarity.MASTER]
    assert float(row["file's own code in other [%]"]) >= 90


def test_a_copy_of_another_student_is_named_both_ways_round():
    reports = similarity.similarity_reports({"a.ipynb": UNUSUAL, "b.ipynb": UNUSUAL, "c.ipynb": BLANK}, SPEC1)
    pairs = _pairs(reports)
    assert set(pairs) == {("a.ipynb", "b.ipynb")}
    assert pairs["a.ipynb", "b.ipynb"]["file's own code in other [%]"] == "100"


#: Three kinds of unrelated code, one per padding: copydetect replaces names, so two paddings of
#: one kind would share their code.
PADDINGS = (
    "def helper_{i}(values, scale={i}):\n    total = 0\n    for v in values:\n"
    "        total = total * v - scale % {j}\n    return [total, len(values), '{i}']\n",
    "class Thing{i}:\n    def __init__(self, a, b):\n        self.a, self.b = a, b * {i}\n"
    "    def go(self):\n        return sorted([self.a, self.b, {i}])\n",
    "table_{i} = {{k: str(k) * {j} for k in range({i})}}\nif len(table_{i}) > {j}:\n"
    "    print('large', table_{i}.keys(), sep=';')\nelse:\n    del table_{i}\n",
)


def with_cell(notebook: bytes, source: str) -> bytes:
    """``notebook`` with a code cell of ``source`` appended."""
    nb = nbformat.reads(notebook.decode(), as_version=4)
    nb.cells.append(nbformat.v4.new_code_cell(source))
    return nbformat.writes(nb).encode()


def padded(notebook: bytes, kind: int) -> bytes:
    """``notebook`` with a cell of 40 blocks of unrelated code, of the given ``kind`` (0, 1 or 2),
    appended: about four times the code of a whole answer."""
    return with_cell(notebook, "\n".join(PADDINGS[kind].format(i=i, j=i + 2) for i in range(40)))


@pytest.mark.parametrize("spec", [SPEC1, SPEC2], ids=["problem1", "problem2"])
def test_code_added_around_a_shared_answer_does_not_hide_it(spec):
    unusual = UNUSUAL if spec is SPEC1 else UNUSUAL2
    copy = disguised_copy(spec)
    notebooks = {"a.ipynb": padded(copy, 0), "b.ipynb": padded(copy, 1), "honest.ipynb": padded(unusual, 2)}
    pairs = _pairs(similarity.similarity_reports(notebooks, spec))
    assert set(pairs) == {("a.ipynb", "b.ipynb"), ("a.ipynb", similarity.MASTER), ("b.ipynb", similarity.MASTER)}
    row = pairs["a.ipynb", "b.ipynb"]
    # Each has under a quarter of its own code in the other: the shares alone would not list them.
    assert float(row["file's own code in other [%]"]) < 25 and float(row["other's own code in file [%]"]) < 25
    assert float(row["shared, of a whole answer [%]"]) >= 90
    assert "of a whole answer" in similarity.similarity_reports(notebooks, spec)["similarity.html"]


def test_a_pair_sharing_more_than_a_whole_answer_shows_how_much_and_the_page_says_why():
    """The report showed 122 % "of a whole answer" without a word: the share is of the size of the
    master's answer, not of either notebook, so two that share more code than it holds (here a
    copy and the same padding) are over 100 %. It is kept as measured, and the page says so."""
    copy = disguised_copy(SPEC1)
    reports = similarity.similarity_reports({"a.ipynb": padded(copy, 0), "b.ipynb": padded(copy, 0)}, SPEC1)
    row = _pairs(reports)["a.ipynb", "b.ipynb"]
    assert float(row["file's own code in other [%]"]) == 100 and float(row["shared, of a whole answer [%]"]) > 300
    page = reports["similarity.html"]
    assert "shared code, of a whole answer (over 100 %: more than a whole answer)</th>" in page
    assert "where two share more code than a whole answer holds" in page and "it is over 100 %" in page


def test_without_the_master_a_whole_answer_is_the_median_submissions():
    handed_out, _ = similarity.handed_out_and_master(SPEC1)
    copy = similarity.own_code(disguised_copy(SPEC1), handed_out)
    codes = {"a": similarity.own_code(padded(disguised_copy(SPEC1), 0), handed_out)}
    codes["b"] = similarity.own_code(padded(disguised_copy(SPEC1), 1), handed_out)
    codes |= {f"right{i}": copy for i in range(3)}  # three more of the answer's size: the median is one
    pairs = similarity.similar_pairs(codes, "\n\n".join(sorted(handed_out)))
    ab = next(p for p in pairs if (p.a, p.b) == ("a", "b"))
    assert max(ab.share_a, ab.share_b) < 0.25 and ab.share_answer == pytest.approx(1.0, abs=0.1)
    assert similarity.similar_pairs({"a": codes["a"]}, "") == []  # nobody to compare with


def test_a_lower_flag_lists_more_and_every_pair_listed_shares_code():
    handed_out, master = similarity.handed_out_and_master(SPEC1)
    codes = {"copier": similarity.own_code(disguised_copy(SPEC1), handed_out)}
    codes["unusual"] = similarity.own_code(UNUSUAL, handed_out)
    boilerplate = "\n\n".join(sorted(handed_out))
    flagged = similarity.similar_pairs(codes, boilerplate, {similarity.MASTER: master})
    everything = similarity.similar_pairs(codes, boilerplate, {similarity.MASTER: master}, flag=1e-9)
    assert [(p.a, p.b) for p in flagged] == [("copier", similarity.MASTER)]
    assert len(everything) >= len(flagged) and all(p.shared > 0 and "<mark>" in p.marked_a for p in everything)


def test_the_notebook_as_handed_out_is_nobodys_own_code():
    handed_out, _ = similarity.handed_out_and_master(SPEC1)
    assert similarity.own_code(BLANK, handed_out) == ""
    assert _pairs(similarity.similarity_reports({"a.ipynb": BLANK, "b.ipynb": BLANK}, SPEC1)) == {}


def task_code(name: str) -> str:
    """Every code cell of a Task notebook as the course hands it out, in one piece."""
    nb = nbformat.read(ROOT / "notebooks" / f"{name}.ipynb", as_version=4)
    return "\n\n".join(c.source for c in nb.cells if c.cell_type == "code")


TASKS = ("task1_single_joint", "task2_single_joint_mujoco", "task3_planar_2r", "task4_ur5e")


def test_code_pasted_from_the_course_notebooks_is_nobodys_own_code():
    # Four students each explore with one Task's code; one of them has also solved the Problem.
    notebooks = {f"{task}.ipynb": with_cell(UNUSUAL if task == TASKS[-1] else BLANK, task_code(task)) for task in TASKS}
    handed_out, master = similarity.handed_out_and_master(SPEC1)
    codes = {name: similarity.own_code(data, handed_out) for name, data in notebooks.items()}
    # Counted as their own, Task 1's and Task 2's code alone would list them: they share plots and runs.
    assert similarity.similar_pairs(codes, "\n\n".join(sorted(handed_out)), {similarity.MASTER: master})
    assert _pairs(similarity.similarity_reports(notebooks, SPEC1)) == {}
    # A copy of the master with Task 3's code around it is still a copy of the master.
    copy = with_cell(disguised_copy(SPEC1), task_code("task3_planar_2r"))
    row = _pairs(similarity.similarity_reports({"copier.ipynb": copy}, SPEC1))["copier.ipynb", similarity.MASTER]
    assert float(row["file's own code in other [%]"]) >= 90


#: One-line idioms of exploration code that two students write alike without copying anything,
#: each 25 to 59 characters once names are replaced and spaces dropped: copydetect counts each,
#: and none is a passage long enough to count toward a whole answer.
IDIOMS = (
    "fig, ax = plt.subplots(1, 2, figsize=(9, 3.5), sharex=True)",
    "ax[0].plot(log.t, np.degrees(log.q[:, 0]), label='q1', color='C0')",
    "ax[1].set_xlabel('time [s]'); ax[1].set_ylabel('torque [N m]')",
    "err = np.linalg.norm(log.ee[-1] - target, axis=-1) * 1e3",
    "for i, name in enumerate(['pan', 'shoulder', 'elbow']): print(i, name)",
    "q_all = np.array([ik_3r(p, elbow_up=True) for p in points])",
    "plt.legend(loc='upper right', frameon=False, fontsize='small')",
    "dist = np.sqrt(np.sum((pts - center[None, :]) ** 2, axis=1))",
    "plt.savefig('figure.png', dpi=150, bbox_inches='tight')",
    "rng = np.random.default_rng(12); qs = rng.uniform(-np.pi, np.pi, (50, 3))",
    "print(f'max {np.max(np.abs(errors)):.3e}, mean {np.mean(errors):.3e}')",
    "tau_log = np.zeros((len(log.t), model.nv)); tau_log[:, :] = log.tau",
)


def explorations(order: list[int], seed: int) -> str:
    """The idioms in ``order``, each after lines of a student's own (numbers no one else writes)."""
    rng = np.random.default_rng(seed)

    def own() -> str:
        return "\n".join(f"x{k} = {rng.uniform(1, 10):.6f} * (x{k} - {rng.uniform(1, 10):.6f})" for k in range(3))

    return "\n".join(f"{own()}\n{IDIOMS[i]}" for i in order)


def test_idioms_two_long_notebooks_share_by_chance_do_not_add_up_to_a_whole_answer():
    handed_out, master = similarity.handed_out_and_master(SPEC1)
    a = explorations(list(range(len(IDIOMS))), seed=1)
    b = explorations(list(range(len(IDIOMS)))[::-1], seed=2)
    boilerplate = "\n\n".join(sorted(handed_out))
    print_a, print_b, print_m = (similarity._fingerprint(n, c, None) for n, c in (("a", a), ("b", b), ("m", master)))
    shared, (share_a, share_b), _ = similarity.compare_files(print_a, print_b)
    # Together the idioms are more than the flag's share of a whole answer, but none is a passage that counts.
    assert shared >= similarity.FLAG_SHARE * print_m.token_coverage and max(share_a, share_b) < similarity.FLAG_SHARE
    assert similarity.in_long_passages(print_a, print_b) == 0
    assert similarity.similar_pairs({"a": a, "b": b}, boilerplate, {similarity.MASTER: master}) == []
    # The same idioms around a copied answer: the answer is one long passage, and it counts.
    copy = similarity.own_code(disguised_copy(SPEC1), handed_out)
    pairs = similarity.similar_pairs(
        {"a": a + "\n" + copy, "b": copy + "\n" + b}, boilerplate, {similarity.MASTER: master}
    )
    ab = next(p for p in pairs if (p.a, p.b) == ("a", "b"))
    assert ab.share_answer == pytest.approx(1.0, abs=0.1)


def laws_only(pd: str, ct: str) -> bytes:
    """Problem 1's notebook as handed out with only its PD and CT TODOs answered, by these bodies."""
    nb = nbformat.reads(BLANK.decode(), as_version=4)
    cells = {c.id: c for c in nb.cells}
    cells["p1-pd"].source = f"def pd_torque(model, data, q_d, Kp, Kd):\n    {pd}\n"
    cells["p1-ct"].source = f"def ct_joint_torque(model, data, q_d, Kp, Kd):\n    {ct}\n"
    return nbformat.writes(nb).encode()


def test_two_notebooks_that_hold_only_the_textbook_laws_are_no_lead():
    pd = "return Kp * (q_d - data.qpos) - Kd * data.qvel"
    ct = "return mass_matrix(model, data) @ (Kp * (q_d - data.qpos) - Kd * data.qvel) + bias_forces(data)"
    a = laws_only(pd, ct)
    b = laws_only(pd.replace(" ", ""), ct.replace("@", "@ ").replace("mass_matrix", "mass_matrix "))
    handed_out, master = similarity.handed_out_and_master(SPEC1)
    boilerplate = sorted(similarity._fingerprint("handed out", "\n\n".join(sorted(handed_out)), None).hashes)
    codes = {"a": similarity.own_code(a, handed_out), "b": similarity.own_code(b, handed_out), "m": master}
    print_a, print_b, print_m = (similarity._fingerprint(n, code, boilerplate) for n, code in codes.items())
    shared, (share_a, share_b), _ = similarity.compare_files(print_a, print_b)
    # Almost all of each one's own code is in the other, but that is little: under a third of an answer.
    assert min(share_a, share_b) >= similarity.FLAG_SHARE and shared < similarity.MIN_SHARED * print_m.token_coverage
    assert _pairs(similarity.similarity_reports({"a.ipynb": a, "b.ipynb": b}, SPEC1)) == {}
    # The same laws in two notebooks that also share an inverse kinematics: listed.
    ik = next(c.source for c in nbformat.read(ROOT / SPEC1["master"], as_version=4).cells if c.get("id") == "p1-ik")
    both = {name: with_cell(data, ik) for name, data in (("a.ipynb", a), ("b.ipynb", b))}
    assert ("a.ipynb", "b.ipynb") in _pairs(similarity.similarity_reports(both, SPEC1))


def test_student_code_and_file_names_reach_the_page_only_as_text():
    nb = nbformat.read(ROOT / SPEC1["student"], as_version=4)
    own = "".join(f"x{i} = {i} + 2 * {3 * i + 1}\n" for i in range(20))  # enough shared code to be listed
    nb.cells.append(nbformat.v4.new_code_cell('evil = "</pre><script>alert(1)</script>"\n' + own))
    nb.cells.append(nbformat.v4.new_code_cell("surrogate = '\ud800'\n"))  # no UTF-8 page can hold it
    data = json.dumps(nb).encode()  # the surrogate as JSON writes it, "\\ud800"
    names = {"<img src=x onerror=alert(1)>.ipynb": data, "=B(1).ipynb": data, "garc\udceda.ipynb": data}
    reports = similarity.similarity_reports(names, SPEC1)
    assert ("<img src=x onerror=alert(1)>.ipynb", "'=B(1).ipynb") in _pairs(reports)  # a spreadsheet shows text
    assert ("'=B(1).ipynb", "garc\\udceda.ipynb") in _pairs(reports)  # a name that is not UTF-8, escaped
    page = reports["similarity.html"]
    assert "<script>" not in page and "<img" not in page
    assert "&lt;script&gt;" in page and "&lt;img src=x" in page
    assert "surrogate = &#39;\\ud800&#39;" in page and "garc\\udceda.ipynb" in page
    for text in reports.values():
        text.encode("utf-8")  # writable
    assert '<html lang="en">' in page and "<caption>" in page


def test_unreadable_and_oversized_notebooks_are_left_out_and_named():
    nb = nbformat.read(ROOT / SPEC1["student"], as_version=4)
    nb.cells.append(nbformat.v4.new_code_cell("x = (1 + 2) * 3\n" * 20_000))
    reports = similarity.similarity_reports(
        {"a.ipynb": b"{not json", "b.ipynb": UNUSUAL, "c.ipynb": nbformat.writes(nb).encode()}, SPEC1
    )
    page = reports["similarity.html"]
    assert "Submissions compared: 1," in page
    assert "a.ipynb (not a notebook the grader can read)" in page and "c.ipynb (320,000 characters" in page


def _argv(subs: Path, out: Path, spec: Path) -> list[str]:
    return ["--spec", str(spec), str(subs), "--out", str(out), "--jobs", "1", "--unsafe-no-sandbox"]


def test_the_batch_writes_the_report_and_a_regrade_keeps_the_earlier_one(tmp_path, capsys):
    subs = tmp_path / "subs"
    subs.mkdir()
    (subs / "copier.ipynb").write_bytes(disguised_copy(SPEC1))
    out = tmp_path / "out"
    spec = ROOT / "tests" / "autograder" / "problem1.json"
    batch.main(_argv(subs, out, spec))
    first = (out / "similarity.csv").read_text(encoding="utf-8")
    assert "copier.ipynb,master solution," in first
    assert f"; pairs sharing code: 1, in {out / 'similarity.html'}" in capsys.readouterr().out
    (subs / "copier.ipynb").write_bytes(BLANK)
    batch.main(_argv(subs, out, spec))
    assert (out / "previous" / "similarity.csv").read_text(encoding="utf-8") == first
    assert len((out / "similarity.csv").read_text(encoding="utf-8").splitlines()) == 1  # the header alone
    assert "; pairs sharing code: 0, in " in capsys.readouterr().out


def test_earlier_notebooks_are_compared_with_the_submissions_not_graded_and_not_with_each_other(tmp_path, capsys):
    subs, earlier = tmp_path / "subs", tmp_path / "2025"
    subs.mkdir()
    earlier.mkdir()
    (subs / "copier.ipynb").write_bytes(UNUSUAL)
    (subs / "blank.ipynb").write_bytes(BLANK)
    (earlier / "last_year.ipynb").write_bytes(UNUSUAL)
    (earlier / "last_year_twin.ipynb").write_bytes(UNUSUAL)
    out = tmp_path / "out"
    spec = ROOT / "tests" / "autograder" / "problem1.json"
    batch.main([*_argv(subs, out, spec), "--compare-with", str(earlier)])
    with open(out / "grades.csv", newline="", encoding="utf-8") as f:
        assert {r["file"] for r in csv.DictReader(f)} == {"copier.ipynb", "blank.ipynb"}
    pairs = _pairs({"similarity.csv": (out / "similarity.csv").read_text(encoding="utf-8")})
    assert set(pairs) == {("copier.ipynb", "2025/last_year.ipynb"), ("copier.ipynb", "2025/last_year_twin.ipynb")}
    assert "reference notebooks" in (out / "similarity.html").read_text(encoding="utf-8")


@pytest.mark.parametrize(
    "where, words",
    [
        ("missing", "no such folder or zip"),
        ("empty", "no .ipynb file"),
        ("subs", "is the submissions themselves"),
        ("empty.zip", "the zip holds no .ipynb file"),
        ("broken.zip", "is not a readable zip"),
        ("notes.txt", "neither a folder nor a .zip file"),
        ("slip.zip", "points outside the folder"),
    ],
)
def test_a_compare_with_folder_that_cannot_serve_is_refused_before_grading(tmp_path, capsys, where, words):
    subs = tmp_path / "subs"
    subs.mkdir()
    (subs / "a.ipynb").write_bytes(BLANK)
    (tmp_path / "empty").mkdir()
    canvas_zip(tmp_path / "empty.zip", {"__MACOSX/._smithbob_11_12_problem1_reaching.ipynb": b"", "notes.txt": b"x"})
    (tmp_path / "broken.zip").write_bytes(b"PK\x03\x04 not a zip")
    (tmp_path / "notes.txt").write_text("last year's notes")
    canvas_zip(tmp_path / "slip.zip", {"../smithbob_11_12_problem1_reaching.ipynb": BLANK})
    out = tmp_path / "out"
    with pytest.raises(SystemExit) as stop:
        batch.main(
            [
                *_argv(subs, out, ROOT / "tests" / "autograder" / "problem1.json"),
                "--compare-with",
                str(tmp_path / where),
            ]
        )
    assert stop.value.code == 2 and words in capsys.readouterr().err
    assert not out.exists()


def test_a_report_that_cannot_be_made_costs_no_grade(tmp_path, capsys):
    """A spec whose student notebook is gone: the grades are written all the same."""
    spec = tmp_path / "spec.json"
    spec.write_text(json.dumps({**SPEC1, "student": "notebooks/no_such_notebook.ipynb"}), encoding="utf-8")
    subs = tmp_path / "subs"
    subs.mkdir()
    shutil.copy(ROOT / SPEC1["student"], subs / "blank.ipynb")
    out = tmp_path / "out"
    batch.main(_argv(subs, out, spec))
    assert (out / "grades.csv").is_file() and not (out / "similarity.csv").exists()
    err = capsys.readouterr().err
    assert "shared-code report was not written" in err and "no_such_notebook" in err


def test_the_compare_command_writes_the_batchs_report_and_leaves_the_grades(tmp_path, capsys):
    """Run on a batch's output folder, it makes the batch's report again, in its compare/
    subfolder, and touches nothing of the batch's; --flag lowers the bar."""
    subs = tmp_path / "subs"
    subs.mkdir()
    (subs / "copier.ipynb").write_bytes(disguised_copy(SPEC1))
    partial = nbformat.reads(UNUSUAL.decode(), as_version=4)  # one of the master's answers, pasted in
    master = nbformat.read(ROOT / SPEC1["master"], as_version=4)
    partial.cells.append(
        nbformat.v4.new_code_cell([c.source for c in master.cells if "# BEGIN SOLUTION" in c.source][-1])
    )
    (subs / "partial.ipynb").write_text(nbformat.writes(partial), encoding="utf-8")
    (subs / "empty.ipynb").write_bytes(b"")
    out = tmp_path / "out"
    spec = ROOT / "tests" / "autograder" / "problem1.json"
    batch.main(_argv(subs, out, spec))
    graded = {p.relative_to(out): p.read_bytes() for p in out.rglob("*") if p.is_file()}
    capsys.readouterr()
    compare.main(["--problem", "problem1", str(subs), "--out", str(out)])
    captured = capsys.readouterr()
    said = "2 submissions compared; pairs sharing at least 60 % of one's own code or of a whole answer: 1;"
    assert said in captured.out
    assert "not compared: empty.ipynb (the file is empty" in captured.err
    assert f"see {out / 'compare' / 'similarity.html'}" in captured.out
    now = {p.relative_to(out): p.read_bytes() for p in out.rglob("*") if p.is_file()}
    for name in compare.REPORTS:
        assert now[Path("compare") / name] == graded[Path(name)]  # the same report as the batch's
    assert {k: v for k, v in now.items() if k.parts[0] != "compare"} == graded  # the batch's files, untouched
    compare.main(["--problem", "problem1", str(subs), "--out", str(out), "--flag", "0.05"])
    lowered = _pairs({"similarity.csv": (out / "compare" / "similarity.csv").read_text(encoding="utf-8")})
    assert ("copier.ipynb", similarity.MASTER) in lowered and ("partial.ipynb", similarity.MASTER) in lowered
    assert 5 <= float(lowered["partial.ipynb", similarity.MASTER]["other's own code in file [%]"]) < 60
    page = (out / "compare" / "similarity.html").read_text(encoding="utf-8")
    assert "at least 5 % of its own code" in page and "with 1 reference notebook (" in page
    assert (out / "compare" / "previous" / "similarity.csv").read_bytes() == graded[Path("similarity.csv")]


def test_each_previous_level_stays_one_run_after_batch_batch_compare(tmp_path, capsys):
    """batch, a regrade into the same folder, then compare into it: previous/ held the first
    batch's grades beside the second's report, and the first's report was pushed down to
    previous/previous/. Each previous/ level is now one earlier run, whole, through a third
    batch too; the comparisons keep their own levels in compare/."""
    subs = tmp_path / "subs"
    subs.mkdir()
    (subs / "copier.ipynb").write_bytes(disguised_copy(SPEC1))
    out = tmp_path / "out"
    spec = ROOT / "tests" / "autograder" / "problem1.json"

    def batch_run(seed: int) -> dict[str, bytes]:
        batch.main([*_argv(subs, out, spec), "--seed", str(seed)])
        return {name: (out / name).read_bytes() for name in ("batch.json", "grades.csv", *compare.REPORTS)}

    first, second = batch_run(2**40 + 1), batch_run(2**40 + 2)
    compare.main(["--problem", "problem1", str(subs), "--out", str(out), "--flag", "0.05"])
    compared = {name: (out / "compare" / name).read_bytes() for name in compare.REPORTS}
    assert compared["similarity.html"] != second["similarity.html"]  # made at another flag
    third = batch_run(2**40 + 3)
    levels = {"": third, "previous": second, "previous/previous": first}
    for level, run in levels.items():
        for name, data in run.items():
            assert (out / level / name).read_bytes() == data, (level, name)
        assert (out / level / "feedback" / "copier.txt").is_file()
    assert not (out / "previous" / "previous" / "previous").exists()
    assert sorted(p.name for p in (out / "compare").iterdir()) == sorted(compare.REPORTS)
    assert {name: (out / "compare" / name).read_bytes() for name in compare.REPORTS} == compared


@pytest.mark.parametrize(
    "args, words",
    [
        (["--flag", "0"], "--flag: must be a share above 0 and at most 1"),
        (["--flag", "60"], "--flag: must be a share above 0 and at most 1"),
        (["--flag", "nan"], "--flag: must be a share above 0 and at most 1"),
        (["--problem", "problem7"], "problem7.json: the problems are problem1, problem2"),
        (["SUBS/a.ipynb"], "is neither a folder nor a .zip: give the folder that holds the .ipynb files"),
        (["SUBS/b.zip"], "is not a readable zip"),
        (["SUBS/c.zip"], "no notebook for problem1 in"),
        (["--compare-with", "SUBS"], "is the submissions themselves"),
    ],
)
def test_the_compare_command_says_what_is_wrong_and_writes_nothing(tmp_path, capsys, args, words):
    subs = tmp_path / "subs"
    subs.mkdir()
    (subs / "a.ipynb").write_bytes(BLANK)
    (subs / "b.zip").write_bytes(b"PK")
    canvas_zip(subs / "c.zip", {"smithbob_11_12_problem2_tracking.ipynb": BLANK})
    args = [a.replace("SUBS", str(subs)) for a in args]
    folder = [a for a in args if a.endswith((".ipynb", ".zip"))] or [str(subs)]
    options = [a for a in args if not a.endswith((".ipynb", ".zip"))]
    problem = [] if "--problem" in options else ["--problem", "problem1"]
    with pytest.raises(SystemExit) as stop:
        compare.main([*problem, *options, *folder, "--out", str(tmp_path / "out")])
    assert stop.value.code == 2 and words in capsys.readouterr().err
    assert not (tmp_path / "out").exists()


def test_an_environment_without_copydetect_is_told_how_to_get_it():
    code = (
        "import sys; sys.modules['copydetect'] = None\n"
        "try:\n    import labsupport.instructor.batch\nexcept ImportError as err:\n    print(err)\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert "needs copydetect" in out and "bash .ci/setup" in out


@pytest.mark.parametrize("kind", ["folder", "zip"])
def test_the_canvas_command_takes_compare_with_to_the_batch(tmp_path, capsys, monkeypatch, kind):
    fixtures = ROOT / "tests" / "fixtures" / "canvas"
    argv = ["--problem", "problem1", str(fixtures / "submissions.zip"), "--gradebook"]
    argv += [str(fixtures / "gradebook_export.csv"), "--out", str(tmp_path / "out"), "--compare-with"]
    for wrong, words in ((tmp_path / "missing", "no such folder"), (fixtures / "submissions.zip", "themselves")):
        with pytest.raises(SystemExit) as stop:
            canvas.main([*argv, str(wrong)])
        assert stop.value.code == 2 and words in capsys.readouterr().err
    earlier = tmp_path / "2025"
    if kind == "zip":
        earlier = canvas_zip(tmp_path / "2025.zip", {"smithbob_101_5001_problem1_reaching.ipynb": UNUSUAL})
    else:
        earlier.mkdir()
        (earlier / "last_year.ipynb").write_bytes(UNUSUAL)
    seen = {}
    monkeypatch.setattr(canvas, "run_batch", lambda folder, spec_path, out, **options: seen.update(options) or [])
    canvas.main([*argv, str(earlier)])
    assert seen["compare_with"] == [earlier]


def test_a_huge_earlier_notebook_is_held_without_its_outputs(tmp_path, monkeypatch):
    """Earlier years' notebooks are read as submissions are: one over ``STRIP_OUTPUTS_BYTES`` is
    held without the outputs, which the comparison never reads."""
    nb = nbformat.reads(UNUSUAL.decode(), as_version=4)
    next(c for c in nb.cells if c.cell_type == "code").outputs = [nbformat.v4.new_output("stream", text="x" * 50_000)]
    earlier = tmp_path / "2025"
    earlier.mkdir()
    (earlier / "big.ipynb").write_bytes(nbformat.writes(nb).encode())
    zipped = canvas_zip(tmp_path / "2024.zip", {"smithbob_101_5001_problem1_reaching.ipynb": nbformat.writes(nb)})
    monkeypatch.setattr(submissions, "STRIP_OUTPUTS_BYTES", 40_000)
    held = batch.earlier_notebooks([earlier, zipped], SPEC1)
    assert set(held) == {"2025/big.ipynb", "2024.zip/smithbob_101_5001_problem1_reaching.ipynb"}
    for data in held.values():
        assert len(data) < 40_000 and b"x" * 1000 not in data
    pairs = _pairs(similarity.similarity_reports({"copier.ipynb": UNUSUAL}, SPEC1, held))
    assert {other for _, other in pairs} == set(held)


def test_the_compare_command_reads_a_canvas_zip_as_it_comes(tmp_path, capsys):
    """Each student's notebook for the Problem, chosen as the Canvas command chooses it and named
    as Canvas named it; the rest is named on stderr."""
    copy = disguised_copy(SPEC1)
    zpath = canvas_zip(
        tmp_path / "submissions.zip",
        {
            "smithbob_101_5001_problem1_reaching.ipynb": copy,
            "smithbob_101_5002_problem2_tracking.ipynb": copy,  # his other notebook
            "garciaana_LATE_102_5003_problem1_reaching-1.ipynb": copy,  # Ana's re-upload, late
            "leejo_103_5004_problem2_tracking.ipynb": UNUSUAL,  # the wrong Problem's notebook only
            "anon_Xy12_5005_problem1_reaching.ipynb": UNUSUAL,  # anonymous grading
            "__MACOSX/._smithbob_101_5001_problem1_reaching.ipynb": b"\0",
            "kimmin_104_text.html": b"<p>see attachment</p>",
        },
    )
    out = tmp_path / "out"
    compare.main(["--problem", "problem1", str(zpath), "--out", str(out)])
    captured = capsys.readouterr()
    assert "3 submissions compared" in captured.out
    assert "not compared: smithbob_101_5002_problem2_tracking.ipynb (the student's other notebook)" in captured.err
    assert "not compared: leejo_103_5004_problem2_tracking.ipynb (problem2's notebook)" in captured.err
    pairs = _pairs({"similarity.csv": (out / "similarity.csv").read_text(encoding="utf-8")})
    bob, ana = "smithbob_101_5001_problem1_reaching.ipynb", "garciaana_LATE_102_5003_problem1_reaching-1.ipynb"
    assert set(pairs) == {(ana, bob), (ana, similarity.MASTER), (bob, similarity.MASTER)}


def test_last_years_canvas_zip_serves_as_compare_with(tmp_path, capsys):
    subs = tmp_path / "subs"
    subs.mkdir()
    (subs / "copier.ipynb").write_bytes(UNUSUAL)
    (subs / "own.ipynb").write_bytes(padded(BLANK, 2))
    last_year = canvas_zip(
        tmp_path / "2025.zip",
        {"smithbob_101_5001_problem1_reaching.ipynb": UNUSUAL, "leejo_103_5004_problem1_reaching.ipynb": BLANK},
    )
    out = tmp_path / "out"
    compare.main(["--problem", "problem1", str(subs), "--out", str(out), "--compare-with", str(last_year)])
    pairs = _pairs({"similarity.csv": (out / "similarity.csv").read_text(encoding="utf-8")})
    assert set(pairs) == {("copier.ipynb", "2025.zip/smithbob_101_5001_problem1_reaching.ipynb")}
    assert "with 3 reference notebooks" in (out / "similarity.html").read_text(encoding="utf-8")
    batch.main(
        [
            *_argv(subs, tmp_path / "graded", ROOT / "tests" / "autograder" / "problem1.json"),
            "--compare-with",
            str(last_year),
        ]
    )
    assert (tmp_path / "graded" / "similarity.csv").read_text(encoding="utf-8") == (out / "similarity.csv").read_text(
        encoding="utf-8"
    )


def test_the_compare_command_refuses_an_out_inside_the_submissions(tmp_path, capsys):
    """The batch refuses an output folder inside the submissions; compare wrote its report there,
    and the next batch listed it among what it left aside."""
    subs = tmp_path / "subs"
    subs.mkdir()
    (subs / "copier.ipynb").write_bytes(disguised_copy(SPEC1))
    with pytest.raises(SystemExit) as stop:
        compare.main(["--problem", "problem1", str(subs), "--out", str(subs / "reports")])
    assert stop.value.code == 2
    assert "is inside the submissions folder" in capsys.readouterr().err
    assert sorted(p.name for p in subs.iterdir()) == ["copier.ipynb"]
