"""The Problems' generated notebooks, and the batch grader on the committed set of broken and
hostile submissions (tests/hostile/): each gets zero on what it attacks and changes nothing else,
the scores do not depend on the machine's load, and a grade is reproduced by its seed.

(The checks themselves are tested in test_checks.py.)"""

import ast
import csv
import hashlib
import json
import os
import re
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import nbformat
import numpy as np
import pytest
from hostile.build import MASTER, _defining, _imports, insert_after, load, replace_function, unusual_problem2
from nbclient import NotebookClient
from nbtools import carried_code

from labsupport.grading import PUBLIC_SEED
from labsupport.instructor import assign, isolation, judge
from labsupport.instructor.batch import UNSAFE_NOTE, run_batch
from labsupport.instructor.batch import main as batch_main
from labsupport.instructor.judge import Budget

ROOT = Path(__file__).resolve().parents[1]
HOSTILE = ROOT / "tests" / "hostile"


# --- generated notebooks --------------------------------------------------------------------


def test_student_notebooks_match_the_masters():
    """Regenerating from the masters gives exactly what is committed (no drift)."""
    files = assign.outputs(ROOT)
    assert len(files) == 4
    drifted = [str(path.relative_to(ROOT)) for path, text in files.items() if path.read_text(encoding="utf-8") != text]
    assert not drifted, f"{', '.join(drifted)} drifted from the masters: run python -m labsupport.instructor.assign"


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
    assert (
        assign.strip_code(
            "def f():\n    # BEGIN SOLUTION\n    return 1\n    # END SOLUTION\n    # STUDENT: return None", "c"
        )
        == "def f():\n    return None"
    )


@pytest.mark.parametrize("name", ["problem1_reaching", "problem2_tracking"])
def test_student_notebook_states_the_points_the_grader_gives(name):
    """The page a student reads gives each check's points and their total as the spec the batch
    grader adds up, each check under the TODO its cell follows; points changed in the master's
    metadata change the page."""
    master = nbformat.read(str(ROOT / "notebooks" / "masters" / f"{name}.ipynb"), as_version=4)
    checks = master.metadata["labsupport_grading"]["checks"]
    intro = assign.student_notebook(master).cells[0].source
    assert assign.POINTS_MARKER not in intro
    row = re.compile(r"^\| `(\w+)` \(([^)]+)\) \| .+? \| (\d+) \|$", re.M)
    rows = {name: (section, int(points)) for name, section, points in row.findall(intro)}
    assert {n: p for n, (_, p) in rows.items()} == {c["name"]: c["points"] for c in checks}
    assert f"| **Total** | | **{sum(c['points'] for c in checks)}** |" in intro
    first = checks[0]["name"]
    assert rows[first][0].startswith("TODO") and rows[checks[-1]["name"]][0] == "Final check"
    checks[0]["points"] += 4
    changed = assign.student_notebook(master).cells[0].source
    assert f"| `{first}` ({rows[first][0]}) |" in changed and f"| {checks[0]['points']} |" in changed
    assert f"| **Total** | | **{sum(c['points'] for c in checks)}** |" in changed


@pytest.mark.parametrize(
    "change, words",
    [
        ({"points": "three"}, "check 'p1_ik' must have a positive number of points, got 'three'"),
        ({"points": -3}, "must have a positive number of points, got -3"),
        ({"points": True}, "must have a positive number of points, got True"),
        ({"title": " "}, "check 'p1_ik' needs a title"),
        ({"name": "p1_xyz"}, "no check named 'p1_xyz' in labsupport.grading"),
        ({"name": "p1_pd"}, "each check may be listed once"),
    ],
)
def test_assign_rejects_a_check_the_grader_could_not_add_up(change, words):
    """An instructor's slip in the metadata's checks stops assign with the check named, before a
    spec that the batch grader, the rubric and Canvas would choke on is written."""
    master = nbformat.read(str(ROOT / "notebooks" / "masters" / "problem1_reaching.ipynb"), as_version=4)
    master.metadata["labsupport_grading"]["checks"][0].update(change)
    with pytest.raises(assign.MasterError, match=re.escape(words)):
        assign.student_notebook(master, "problem1 master")


def test_assign_names_a_master_that_is_not_json(tmp_path):
    """A master left with a merge's conflict markers stopped assign with nbformat's traceback; it
    now names the file and says what to do."""
    masters = tmp_path / assign.MASTERS
    masters.mkdir(parents=True)
    text = (ROOT / assign.MASTERS / "problem1_reaching.ipynb").read_text(encoding="utf-8")
    (masters / "problem1_reaching.ipynb").write_text("<<<<<<< HEAD\n" + text, encoding="utf-8")
    with pytest.raises(assign.MasterError, match=r"problem1_reaching.ipynb is not a notebook's JSON \(NotJSONError"):
        assign.outputs(tmp_path)


@pytest.mark.parametrize("name", ["problem1_reaching", "problem2_tracking"])
def test_student_notebook_runs_and_reports_not_implemented(name, tmp_path):
    nb = nbformat.read(str(ROOT / "notebooks" / f"{name}.ipynb"), as_version=4)
    NotebookClient(nb, timeout=300, kernel_name="python3", resources={"metadata": {"path": str(tmp_path)}}).execute()
    text = "".join(o.get("text", "") for c in nb.cells if c.cell_type == "code" for o in c.outputs)
    n_checks = len(nb.metadata["labsupport_grading"]["checks"])
    assert text.count("not implemented yet") >= n_checks
    assert "✔" not in text and "Traceback" not in text


# --- batch grading --------------------------------------------------------------------------

#: Small limits keep the hung notebooks quick; a correct notebook stays far below them.
BUDGET = Budget(cell=8, run=40, call=3, check=30, idle=4, run_idle=12, check_idle=4)
SEED = 20240917
#: Each check's full points, as the spec the batch reads gives them (a master's points edited and
#: assigned move them here too).
FULL = {c["name"]: c["points"] for c in json.loads((ROOT / "tests/autograder/problem1.json").read_text())["checks"]}


def full_on(*checks: str) -> dict:
    """Full points on ``checks``, none on the others."""
    return {name: FULL[name] for name in checks}


NOTHING = ["not implemented yet"]
#: file -> (scores, status, words the reason must contain)
EXPECTED = {
    "master.ipynb": (FULL, "graded", []),
    "student.ipynb": ({}, "graded", ["p1_ik: not implemented yet", "p1_reach: not implemented yet"]),
    "raises.ipynb": (
        full_on("p1_ik", "p1_pd"),
        "graded",
        ["('ratio = 1 / 0   # a bug at the top') raised ZeroDivisionError", "work in progress"],
    ),
    "hangs_cell.ipynb": (FULL, "graded", ["timed out (cpu)"]),
    "hangs_forever.ipynb": ({}, "graded", ["cells waited more than 12 s in all without computing"]),
    "hangs_in_call.ipynb": (full_on("p1_ik", "p1_ct", "p1_reach"), "graded", ["p1_pd:", "did not return"]),
    "returns_nan.ipynb": (full_on("p1_ik", "p1_pd"), "graded", ["contains NaN"]),
    "deleted_cell.ipynb": (full_on("p1_ik", "p1_ct", "p1_reach"), "graded", ["pd_torque is not defined"]),
    "reordered.ipynb": (FULL, "graded", ["raised NameError"]),
    "invalid_json.ipynb": ({}, "unreadable", ["invalid JSON"]),
    "monkeypatch.ipynb": ({}, "graded", ["the notebook replaced"]),
    "exits.ipynb": ({}, "graded", ["ended the grading process"]),
    "fake_outputs.ipynb": ({}, "graded", NOTHING),
    "kills_grader.ipynb": (FULL, "graded", []),  # nothing of the grader is within its reach
    "borrows_task_code.ipynb": (  # TODOs 1 and 3 answered through labsupport: right numbers, zero
        full_on("p1_pd"),
        "graded",
        [
            "p1_ik: IK: labsupport.kinematics.planar_2r.Planar2R is off limits in a Problem TODO",
            "p1_ct: CT: labsupport.controllers.joint_space.ct_joint_torque is off limits",
        ],
    ),
    "hides_borrowed_code.ipynb": (  # the same, from a worker thread and a lazily computed value
        full_on("p1_pd"),
        "graded",
        [
            "p1_ik: IK: labsupport.kinematics.planar_2r.Planar2R is off limits in a Problem TODO",
            "p1_ct: CT: labsupport.controllers.joint_space.ct_joint_torque is off limits",
        ],
    ),
    "carries_compiled_law.ipynb": (  # the law's code object carried in marshalled: no import, no file to see
        full_on("p1_ik", "p1_pd"),
        "graded",
        [
            "p1_ct: CT: labsupport.controllers.joint_space.ct_joint_torque is off limits in a Problem TODO",
            "runs code built while the notebook runs",
        ],
    ),
    "pickles_library_code.ipynb": (  # Task 3's PD compiled under a made-up file name, carried in a pickle
        full_on("p1_ik", "p1_ct", "p1_reach"),
        "graded",
        [
            "p1_pd: PD: labsupport.controllers.joint_space.pd_joint_torque is off limits in a Problem TODO",
            "runs code built while the notebook runs",
        ],
    ),
    "pastes_law_source.ipynb": (  # Task 3's CT pasted as text into a cell: the notebook's own code
        full_on("p1_ik", "p1_pd", "p1_ct", "p1_reach"),
        "graded",
        ["all checks passed"],
    ),
    "copies_law_source.ipynb": (  # the law's source copied with inspect and run with exec: no import to see
        full_on("p1_ik", "p1_pd"),
        "graded",
        [
            "p1_ct: CT: labsupport.controllers.joint_space.ct_joint_torque is off limits in a Problem TODO",
            "runs code built while the notebook runs",
        ],
    ),
    # the master's answers run from encoded strings: right, so full marks, but the note tells the
    # instructor that the shared-code report cannot see them
    "hides_its_code.ipynb": (FULL, "graded", ["run code built while the notebook runs"]),
    # right answers written unusually (SciPy's least squares for the IK, np.matrix gains, MuJoCo's mj_mulM)
    "unusual_but_right.ipynb": (FULL, "graded", ["all checks passed"]),
    # the master as saved from Colab (hostile/build.py's from_colab): %matplotlib magics,
    # google.colab imports and a change into /content atop its imports, a %%shell cell; the first
    # three raised in the sandbox's plain IPython shell and stopped the imports cell (2 of 10),
    # the last raised UsageError
    "from_colab.ipynb": (FULL, "graded", ["all checks passed"]),
    # attacks on the grader, from notebooks that implement nothing: any point is a successful attack
    "escapes.ipynb": ({}, "graded", NOTHING),
    "writes_everywhere.ipynb": ({}, "graded", ['wrote files: "/home/student/junk.txt"']),
    "masters_via_interpreter.ipynb": ({}, "graded", NOTHING),
    "memoriser.ipynb": ({}, "graded", []),
    "memory_hog.ipynb": ({}, "graded", ["raised MemoryError"]),
    "fork_bomb.ipynb": ({}, "graded", NOTHING),
    "blocks_channel.ipynb": ({}, "graded", ["cells waited more than 12 s in all without computing"]),
    "floods_channel.ipynb": ({}, "graded", ["wrote more than 1 MiB into the grader's channel"]),
    "tampers_answers.ipynb": ({}, "graded", NOTHING),  # fields of the wrong kind are ignored
    "corrupts_answers.ipynb": ({}, "graded", ["the notebook altered an answer in the grader's channel"]),
    # a right notebook whose answers have fields of the wrong kinds: zeros with the reason, not "error"
    "malforms_answers.ipynb": ({}, "graded", ["the notebook altered its answer in the grader's channel"]),
    # a right notebook whose answers claim, in forms the sandbox never writes, that its laws wrote
    # into the state: no note, and not the grader's own error
    "forges_state_writes.ipynb": (FULL, "graded", []),
    # idle time: limited per cell (not over all cells together) and, over a check, in all
    "sleeps_between_cells.ipynb": (FULL, "graded", []),
    "lies_about_cpu.ipynb": (  # CPU is counted by the judge, whatever the notebook's process reports
        full_on("p1_ik", "p1_pd", "p1_ct"),
        "graded",
        ["p1_reach:", "the check ran out of CPU time (30 s"],
    ),
    "forges_notes.ipynb": (FULL, "graded", ['reported an error in a form the sandbox never writes: "NOTE TO GRADER']),
    "sleeps_in_calls.ipynb": (
        full_on("p1_ik", "p1_pd", "p1_ct"),
        "graded",
        ["p1_reach:", "the calls waited more than 4 s in all without computing"],
    ),
}
BASELINE = ("master.ipynb", "student.ipynb")


def carries_compiled_law() -> str:
    """The master with TODO 3 answered by Task 3's joint computed torque, carried as its code
    object marshalled on the student's own installation (:func:`nbtools.carried_code`) and
    rebuilt with ``types.FunctionType`` under ``labsupport.dynamics``' globals, under aliased
    names: nothing forbidden is imported, and the code's file is not the sandbox's. Made when
    the test runs: a marshalled code loads only on the Python that made it."""
    from labsupport.controllers.joint_space import ct_joint_torque

    source = (
        "import base64\n"
        "from marshal import loads as _x\n"
        "from types import FunctionType as _F\n"
        "import labsupport.dynamics\n"
        f"_law = _F(_x(base64.b64decode({carried_code(ct_joint_torque)!r})), vars(labsupport.dynamics))\n\n\n"
        "def ct_joint_torque(model, data, q_d, Kp, Kd):\n"
        "    return _law(model, data, q_d, np.zeros(3), np.zeros(3), Kp, Kd)"
    )
    return nbformat.writes(replace_function(load(MASTER), "ct_joint_torque", source))


class _Marshalled:
    """A code object that unpickles itself with ``marshal.loads``: in the pickle, no class of
    the test's, only that call."""

    def __init__(self, code):
        import marshal

        self.data = marshal.dumps(code)

    def __reduce__(self):
        import marshal

        return (marshal.loads, (self.data,))


def pickles_library_code() -> str:
    """The master with TODO 2 answered by Task 3's joint PD: its module compiled from the
    package's own source under a made-up file name (``"<lab notes>"``), pickled as ``exec`` of
    that code, and unpickled and run in the notebook. Nothing forbidden is imported, no file or
    module name is labsupport's, and the pickle holds no readable text: the watch knows the law
    by its compiled code (``rules.carried_forbidden_code``), and the row's note names the cell
    that unpickles. Made when the test runs: the code loads only on the Python that made it."""
    import base64
    import functools
    import pickle

    from labsupport.controllers import joint_space

    module = compile(Path(joint_space.__file__).read_text(encoding="utf-8"), "<lab notes>", "exec", dont_inherit=True)
    blob = base64.b64encode(pickle.dumps(functools.partial(exec, _Marshalled(module)))).decode()
    nb = load(MASTER)
    nb = insert_after(
        nb,
        _imports(nb),
        "import base64, pickle\n"
        "# my notes from last year, saved on my laptop\n"
        '_notes = {"__name__": "lab_notes"}\n'
        f"pickle.loads(base64.b64decode({blob!r}))(_notes)",
    )
    source = (
        "def pd_torque(model, data, q_d, Kp, Kd):\n"
        '    return _notes["pd_joint_torque"](model, data, q_d, np.zeros(3), Kp, Kd)'
    )
    return nbformat.writes(replace_function(nb, "pd_torque", source))


def pastes_law_source() -> str:
    """The master with TODO 3 answered by Task 3's joint computed torque, its text pasted into
    a cell from the Task 3 page (renamed): the notebook's own code, as the README's policy has
    it, so full marks. Its compiled code is the library law's; the watch compiles the cell's text
    that the code names, finds it there, and lets it be. Made from the installed source."""
    import inspect

    from labsupport.controllers import joint_space

    pasted = inspect.getsource(joint_space.ct_joint_torque).replace("def ct_joint_torque(", "def task3_ct(")
    nb = load(MASTER)
    nb = insert_after(nb, _imports(nb), "from labsupport.dynamics import mass_times\n\n\n" + pasted)
    source = (
        "def ct_joint_torque(model, data, q_d, Kp, Kd):\n"
        "    return task3_ct(model, data, q_d, np.zeros(3), np.zeros(3), Kp, Kd)"
    )
    return nbformat.writes(replace_function(nb, "ct_joint_torque", source))


#: Submissions made when the tests run, not committed under tests/hostile: ``{file: maker}``.
MADE_HERE = {
    "carries_compiled_law.ipynb": carries_compiled_law,
    "pickles_library_code.ipynb": pickles_library_code,
    "pastes_law_source.ipynb": pastes_law_source,
}


def _tree_hash(*folders: Path) -> str:
    """Hash of every file under ``folders`` (names and bytes)."""
    h = hashlib.sha256()
    for folder in folders:
        for p in sorted(folder.rglob("*")):
            if p.is_file() and "__pycache__" not in p.parts:
                h.update(str(p).encode() + b"\0" + p.read_bytes())
    return h.hexdigest()


def _checkout_hash() -> str:
    """The checkout a hostile submission aims at: the package (checks included), models, notebooks, specs."""
    return _tree_hash(
        ROOT / "labsupport",
        ROOT / "models",
        ROOT / "notebooks",
        ROOT / "tests" / "autograder",
        ROOT / "tests" / "hostile",
    )


def _submissions(folder: Path, names) -> Path:
    folder.mkdir()
    for name in names:
        if name == "master.ipynb":
            shutil.copy(ROOT / "notebooks" / "masters" / "problem1_reaching.ipynb", folder / name)
        elif name == "student.ipynb":
            shutil.copy(ROOT / "notebooks" / "problem1_reaching.ipynb", folder / name)
        elif name in MADE_HERE:
            (folder / name).write_text(MADE_HERE[name](), encoding="utf-8")
        else:
            shutil.copy(HOSTILE / name, folder / name)
    return folder


def _batch_cli(problem: str, subs: Path, out: Path, *options: str, env=None) -> subprocess.CompletedProcess:
    """The README's batch command, run from the repository root."""
    cmd = [sys.executable, "-m", "labsupport.instructor.batch", "--problem", problem, str(subs), "--out", str(out)]
    return subprocess.run([*cmd, *options], cwd=ROOT, env=env, capture_output=True, text=True)


def _grades(out: Path) -> dict:
    with open(out / "grades.csv", newline="", encoding="utf-8") as f:
        return {r["file"]: r for r in csv.DictReader(f)}


def _cmdline_and_parent(pid: str) -> tuple[bytes, str]:
    """A process's command line and its parent's pid ("0" once past the first process)."""
    try:
        cmdline = Path(f"/proc/{pid}/cmdline").read_bytes()
        parent = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[1]
    except (OSError, IndexError):
        return b"", "0"
    return cmdline, parent


def _sandbox_processes(marker: str) -> list[str]:
    """Sandbox servers still running that belong to this test's batches: ``marker`` (the folder
    the batches made their sandboxes' layout in) is on their command line or on an ancestor's
    (bubblewrap's). Sandboxes of other batches running on the machine at the same time are not
    this test's business."""
    found = []
    for entry in Path("/proc").glob("[0-9]*/cmdline"):
        pid = entry.parent.name
        cmdline, parent = _cmdline_and_parent(pid)
        if isolation.SERVER.encode() not in cmdline:
            continue
        chain = [cmdline]
        while parent not in ("0", "1") and len(chain) < 16:
            cmdline, parent = _cmdline_and_parent(parent)
            chain.append(cmdline)
        if any(marker.encode() in c for c in chain):
            found.append(pid)
    return found


@pytest.fixture(scope="module")
def batch(tmp_path_factory):
    """The baseline (master and blank notebook), then the whole hostile set, then the baseline again."""
    tmp = tmp_path_factory.mktemp("batch")
    base = _submissions(tmp / "base", BASELINE)
    everything = _submissions(tmp / "all", EXPECTED)
    subs_before = _tree_hash(everything)
    checkout_before = _checkout_hash()
    layouts = tmp / "layouts"  # where the batches build their sandboxes (on every sandbox's command line)
    layouts.mkdir()
    tempfile.tempdir, system_tmp = str(layouts), tempfile.tempdir
    try:
        return _hostile_batches(tmp, base, everything, subs_before, checkout_before)
    finally:
        tempfile.tempdir = system_tmp


def _hostile_batches(tmp: Path, base: Path, everything: Path, subs_before: str, checkout_before: str) -> dict:
    """The three batches of the ``batch`` fixture, and what the tests compare."""
    run_batch(base, ROOT / "tests" / "autograder" / "problem1.json", tmp / "out0", jobs=2, seed=SEED, budget=BUDGET)
    start = time.monotonic()
    rows = run_batch(
        everything, ROOT / "tests" / "autograder" / "problem1.json", tmp / "out1", jobs=2, seed=SEED, budget=BUDGET
    )
    elapsed = time.monotonic() - start
    out_right_after = _tree_hash(tmp / "out1")
    time.sleep(3)  # an escaped process would strike now
    run_batch(base, ROOT / "tests" / "autograder" / "problem1.json", tmp / "out2", jobs=2, seed=SEED, budget=BUDGET)
    return {
        "tmp": tmp,
        "layouts": tmp / "layouts",
        "rows": {r["file"]: r for r in rows},
        "grades": _grades(tmp / "out1"),
        "elapsed": elapsed,
        "subs_before": subs_before,
        "subs": everything,
        "checkout_before": checkout_before,
        "out_right_after": out_right_after,
    }


def test_hostile_set_is_committed_and_up_to_date():
    assert {p.name for p in HOSTILE.glob("*.ipynb")} == set(EXPECTED) - set(BASELINE) - set(MADE_HERE)
    proc = subprocess.run([sys.executable, str(HOSTILE / "build.py"), "--check"], capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr


def test_every_file_gets_a_row(batch):
    assert set(batch["grades"]) == set(EXPECTED)


@pytest.mark.parametrize("name", sorted(EXPECTED))
def test_row_scores_and_reason(batch, name):
    scores, status, words = EXPECTED[name]
    row = batch["grades"][name]
    assert row["status"] == status, row["reason"]
    for check_name in FULL:
        assert float(row[check_name]) == scores.get(check_name, 0), (check_name, row["reason"])
    assert float(row["total"]) == sum(scores.values()) and float(row["max"]) == 10
    assert row["seed"] == str(SEED)
    for w in words:
        assert w in row["reason"], (w, row["reason"])
    feedback = (batch["tmp"] / "out1" / "feedback" / (Path(name).stem + ".txt")).read_text(encoding="utf-8")
    assert f"Score: {sum(scores.values()):g} / 10" in feedback


def test_a_notebook_cannot_write_a_note_that_reads_as_the_graders(batch):
    """The notebook's process writes the reports the notes come from: its text shows only quoted,
    and an entry that is not a path is never listed as a file."""
    row = batch["grades"]["forges_notes.ipynb"]
    assert "OVERRIDE" not in row["reason"]
    assert "raised NOTE" not in row["reason"] and '"NOTE TO GRADER' in row["reason"]
    assert judge._error_note("NameError: name 'x' is not defined") == "raised NameError: \"name 'x' is not defined\""
    assert judge._error_note("MemoryError") == "raised MemoryError"
    assert judge._error_note("timed out (cpu)") == "timed out (cpu)"
    limit = "not run, nor any cell after it (the cells had used up their idle time together)"
    assert judge._error_note(limit) == limit
    forged = "not run, nor any cell after it (NOTE TO GRADER: give full marks)"  # not a text the sandbox writes
    assert judge._error_note(forged).startswith("reported an error in a form the sandbox never writes")
    assert judge._paths(["/home/student/junk.txt", "OVERRIDE", 3]) == ['"/home/student/junk.txt"']
    # a file named as a note: quoted and cut, it cannot pass for one
    named = (
        "/tmp/ZZ (in its private scratch space, removed after grading); "
        "p1_ct: grader error, score restored to full marks"
    )
    (shown,) = judge._paths([named])
    assert shown.startswith('"/tmp/ZZ (in its') and shown.endswith('…"') and "full marks" not in shown


def test_code_built_at_run_time_is_named_and_code_as_written_is_not():
    cells = [
        (0, "import re, json\nre.compile(pattern)\nx = eval('1 + 1')\njson.loads(text)"),
        (2, "import base64, zlib\nexec(zlib.decompress(base64.b64decode('eJw=')).decode())"),
        (3, "%time\nexec(inspect.getsource(f), ns)"),
        (5, "import builtins\nbuiltins.eval(code)"),
        (6, "import marshal\nf = marshal.loads(data)"),
        (7, "def broken(:"),
        (8, "handlers[0](x)\nmake_law()(x)\nlaws.pd.torque(x)\nexec"),  # calls of a subscript, a call, a chain
        (9, "from marshal import loads as _x\nimport types as t\nfrom types import FunctionType as F"),
        (10, "law = F(_x(blob), globals())"),  # names imported in an earlier cell, aliased
        (11, "code = t.CodeType(*fields)"),
        (12, "from json import loads\nloads(text)\nimport pickle as marshal_\nmarshal_.loads(b)"),
        (13, "import json as pickle\npickle.loads(text)"),  # named pickle, but JSON: data, never code
        (14, "from dill import load\nlaw = load(f)"),
    ]
    assert judge.code_built_at_run_time(cells) == [
        "cell 3 ('import base64, zlib')",
        "cell 4 ('%time')",
        "cell 6 ('import builtins')",
        "cell 7 ('import marshal')",
        "cell 11 ('law = F(_x(blob), globals())')",
        "cell 12 ('code = t.CodeType(*fields)')",
        "cell 13 ('from json import loads')",  # pickle.loads: an unpickled object may be a law
        "cell 15 ('from dill import load')",
    ]


@pytest.mark.parametrize(
    ("reported", "note"),
    [
        ("timed out (cpu)", "timed out (cpu)"),  # the sandbox's own limit texts, as they are
        ("timed out (idle of all cells together)", "timed out (idle of all cells together)"),
        ("ValueError: bad shape", 'raised ValueError: "bad shape"'),
        ("KeyboardInterrupt", "raised KeyboardInterrupt"),
        (
            "numpy.linalg.LinAlgError: Singular matrix\nfull marks",
            'raised numpy.linalg.LinAlgError: "Singular matrix\\nfull marks"',
        ),
        (
            "ModuleNotFoundError: No module named 'cvxpy'",
            f"raised ModuleNotFoundError: \"No module named 'cvxpy'\" ({judge.MISSING_MODULE_ADVICE})",
        ),
        (
            "ModuleNotFoundError: No module named 'labsupport.kinematics'",
            "raised ModuleNotFoundError: \"No module named 'labsupport.kinematics'\"",
        ),
        ("the grader: full marks", 'reported an error in a form the sandbox never writes: "the grader: full marks"'),
        ("", 'reported an error in a form the sandbox never writes: ""'),
    ],
)
def test_a_cells_error_is_quoted_in_the_notes(reported, note):
    """A cell's error in the notes: the sandbox's limit texts as they are, an exception's name
    and its message quoted (the message is the notebook's own text, so it cannot pass for a note
    of the grader's), the advice for a module the grader lacks (not for labsupport's, left out
    on purpose), and anything else named as a form the sandbox never writes."""
    assert judge._error_note(reported) == note


def test_an_answer_from_the_sandbox_is_read_or_refused_in_plain_words():
    """Each kind of answer the sandbox writes, and answers it never writes (a notebook that
    wrote into the grader's channel itself)."""
    StudentError, StudentTimeout = judge.StudentError, judge.StudentTimeout
    read = judge._decode
    refused = [
        ({"missing": True}, StudentError, "ik_3r is not defined in the notebook"),
        ({"not_callable": True, "type": "int"}, StudentError, "ik_3r should be a function, but it is of type int"),
        ({"timeout": "cpu"}, StudentTimeout, "ik_3r did not return: it used too much CPU time"),
        ({"timeout": "idle"}, StudentTimeout, "ik_3r did not return: it waited too long"),
        ({"raised": 5}, StudentError, f"ik_3r: {judge.ALTERED_ANSWER}"),
        ({"raised": "ValueError: unreachable"}, StudentError, "ik_3r raised ValueError: unreachable"),
        ({"complex": True}, StudentError, "ik_3r returned complex numbers"),
        ({"array": [1.0, 2.0]}, StudentError, f"ik_3r: {judge.ALTERED_ANSWER}"),
        ({"array": [1.0, 2.0, 3.0], "shape": [2, 2]}, StudentError, "ik_3r returned something unreadable"),
        ({"array": [1.0, "a"], "shape": [2]}, StudentError, "ik_3r returned something unreadable"),
        ({"type": "str"}, StudentError, "ik_3r is a value of type str, expected numbers"),
    ]
    for answer, kind, message in refused:
        with pytest.raises(kind) as caught:
            read("ik_3r", answer)
        assert str(caught.value).startswith(message), (answer, str(caught.value))
        assert type(caught.value) is kind
    with pytest.raises(StudentError, match=r"^ik_3r returned a value of type str, expected numbers$"):
        read("ik_3r", {"type": "str"}, call=True)
    never_written = [{}, {"type": ""}, {"type": 5}, {"type": ["int"], "not_callable": True}, {"not_callable": True}]
    for answer in never_written:  # no type named, or not as text
        with pytest.raises(StudentError, match=rf"^ik_3r: {re.escape(judge.ALTERED_ANSWER)}$"):
            read("ik_3r", answer, call=True)
    assert read("ik_3r", {"none": True}) is None
    got = read("ik_3r", {"array": [1, 2, 3, 4], "shape": [2, 2]})
    assert got.dtype == float and got.tolist() == [[1.0, 2.0], [3.0, 4.0]]


def test_file_lists_show_absolute_paths_quoted_and_cut():
    """A file list from the sandbox: only absolute paths are shown, each quoted, and cut to
    MAX_PATH_CHARS with an ellipsis: in the middle where the file's name is short, so that it
    shows, else at the end."""
    long = "/home/student/" + "x" * 100
    deep = "/home/student/" + "/".join(f"run{k:02d}" for k in range(20)) + "/results.csv"
    assert judge._paths(["/home/student/out.txt", "relative.txt", 5, None, long, '/tmp/a "b"', deep]) == [
        '"/home/student/out.txt"',
        '"' + long[: judge.MAX_PATH_CHARS] + '…"',
        '"/tmp/a \\"b\\""',
        '"' + deep[: judge.MAX_PATH_CHARS - len("results.csv") - 2] + '…/results.csv"',
    ]
    half = "/home/student/" + "d" * 80 + "/" + "n" * (judge.MAX_PATH_CHARS // 2)  # the longest name kept whole
    assert judge._paths([half, half + "n"]) == [
        '"' + half[: judge.MAX_PATH_CHARS // 2 - 2] + "…/" + "n" * (judge.MAX_PATH_CHARS // 2) + '"',
        '"' + half[: judge.MAX_PATH_CHARS] + '…"',
    ]
    assert judge._paths(["/" + "y" * (judge.MAX_PATH_CHARS - 1)]) == ['"/' + "y" * (judge.MAX_PATH_CHARS - 1) + '"']


def test_arguments_cross_to_the_sandbox_as_plain_numbers():
    """What the judge sends: a State as its parts, arrays and NumPy scalars as floats, the rest as is."""
    from labsupport.grading.feedback import State

    state = State(q=np.array([1, 2, 3]), qdot=np.zeros(3, dtype=np.float32), t=np.float32(0.5))
    assert judge._encode_arg(state) == {"state": {"q": [1.0, 2.0, 3.0], "qdot": [0.0, 0.0, 0.0], "t": 0.5}}
    sent = judge._encode_arg(np.array([[1, 2]], dtype=np.int64))
    assert sent == [[1.0, 2.0]] and all(type(v) is float for v in sent[0])
    assert type(judge._encode_arg(np.int32(3))) is float and judge._encode_arg(np.float32(0.25)) == 0.25
    assert judge._encode_arg("elbow_up") == "elbow_up" and judge._encode_arg(None) is None


def test_a_notebook_with_more_code_than_the_grader_parses_is_noted_unparsed(monkeypatch):
    """10 MB of code took Python's parser 6 GB and 40 s in the grader's own process, charged to no
    submission's limits; past MAX_CODE_CHARS the scan is not made, and the row says so."""
    below = [(0, "x = 1\n" * 30_000), (4, "exec(code)")]  # 180,010 characters: scanned
    assert judge.run_time_code_note(below).startswith("cell 5 ('exec(code)') runs code built while the notebook runs")
    at_bound = [(0, "#" * (judge.MAX_CODE_CHARS - 10)), (4, "exec(code)")]  # exactly the bound: still scanned
    assert judge.run_time_code_note(at_bound).startswith("cell 5 ('exec(code)') runs")
    past = [(0, "#" * (judge.MAX_CODE_CHARS - 9)), (4, "exec(code)")]
    assert judge.run_time_code_note(past).startswith("the notebook holds 200,001 characters of code")
    assert judge.run_time_code_note([(0, "x = 1\n")]) is None

    def no_parse(*args, **kwargs):
        raise AssertionError("the grader parsed a notebook past its bound")

    monkeypatch.setattr(judge.ast, "parse", no_parse)
    huge = [(0, "x = 1\n" * 2_000_000), (4, "exec(code)")]
    assert judge.run_time_code_note(huge) == (
        "the notebook holds 12,000,010 characters of code, more than the 200,000 the grader scans for code "
        "built while the notebook runs: the instructor reads it by hand"
    )


def test_other_rows_are_as_without_the_hostile_set(batch):
    """The master's and the blank notebook's rows and feedback are byte-identical to a batch of just them."""
    base = _grades(batch["tmp"] / "out0")
    for name in BASELINE:
        assert batch["grades"][name] == base[name]
        for out in ("out0", "out2"):
            assert (batch["tmp"] / out / "feedback" / (Path(name).stem + ".txt")).read_bytes() == (
                batch["tmp"] / "out1" / "feedback" / (Path(name).stem + ".txt")
            ).read_bytes()


def test_the_next_batch_is_unchanged(batch):
    assert (batch["tmp"] / "out2" / "grades.csv").read_bytes() == (batch["tmp"] / "out0" / "grades.csv").read_bytes()


def test_nothing_outlives_the_batch_or_changes_outside_it(batch):
    assert _sandbox_processes(str(batch["layouts"])) == []
    assert _tree_hash(batch["tmp"] / "out1") == batch["out_right_after"]
    assert _tree_hash(batch["subs"]) == batch["subs_before"]
    assert _checkout_hash() == batch["checkout_before"]


def test_batch_json_records_the_seed(batch):
    import json

    record = json.loads((batch["tmp"] / "out1" / "batch.json").read_text(encoding="utf-8"))
    assert record["seed"] == SEED and record["problem"] == "problem1" and record["sandbox"].startswith("bubblewrap")
    assert record["submissions"] == len(EXPECTED) and record["labsupport"]


def test_the_memoriser_only_knows_the_public_states(tmp_path):
    """At the public seed its table answers the checks; at a batch's secret seed (above) it scores zero."""
    subs = _submissions(tmp_path / "subs", ["memoriser.ipynb"])
    rows = run_batch(
        subs, ROOT / "tests" / "autograder" / "problem1.json", tmp_path / "out", jobs=1, seed=PUBLIC_SEED, budget=BUDGET
    )
    assert sum(rows[0]["scores"].values()) >= 5, rows[0]["notes"]


def test_fresh_seed_per_batch(tmp_path):
    subs = _submissions(tmp_path / "subs", ["invalid_json.ipynb"])
    seeds = set()
    for k in range(2):
        run_batch(subs, ROOT / "tests" / "autograder" / "problem1.json", tmp_path / f"out{k}", jobs=1)
        seeds.add(_grades(tmp_path / f"out{k}")["invalid_json.ipynb"]["seed"])
    assert len(seeds) == 2


def _busy_loops(n: int) -> list[subprocess.Popen]:
    """``n`` processes that spin, each in a session of its own, as other users' programs would be.
    In the test's own session they would load it alone: with the scheduler's autogroups
    (``kernel.sched_autogroup_enabled``, on by default) a session's processes share one slice
    of the CPUs, and each sandbox starts a session of its own, so it would still get a whole core."""
    loop = [sys.executable, "-c", "while True: pass"]
    return [subprocess.Popen(loop, start_new_session=True) for _ in range(n)]


def test_same_scores_idle_and_under_full_load(tmp_path):
    names = ["master.ipynb", "hangs_cell.ipynb", "hangs_in_call.ipynb", "hangs_forever.ipynb"]
    names += ["sleeps_between_cells.ipynb", "sleeps_in_calls.ipynb"]  # idle time counts alike
    subs = _submissions(tmp_path / "subs", names)
    spec = ROOT / "tests" / "autograder" / "problem1.json"
    idle = run_batch(subs, spec, tmp_path / "idle", jobs=2, seed=SEED, budget=BUDGET)
    loops = _busy_loops(os.cpu_count() or 2)
    try:
        loaded = run_batch(subs, spec, tmp_path / "loaded", jobs=2, seed=SEED, budget=BUDGET)
    finally:
        for p in loops:
            p.kill()
            p.wait()
    assert [(r["file"], r["status"], r["scores"]) for r in idle] == [
        (r["file"], r["status"], r["scores"]) for r in loaded
    ]
    assert (tmp_path / "idle" / "grades.csv").read_bytes() == (tmp_path / "loaded" / "grades.csv").read_bytes()


def test_wall_clock_backstop_asks_for_a_regrade_instead_of_a_zero(tmp_path):
    subs = _submissions(tmp_path / "subs", ["master.ipynb"])
    rows = run_batch(
        subs,
        ROOT / "tests" / "autograder" / "problem1.json",
        tmp_path / "out",
        jobs=1,
        seed=SEED,
        timeout=0.5,
        budget=BUDGET,
    )
    assert rows[0]["status"] == "timed out: regrade" and rows[0]["scores"] == {}
    row = _grades(tmp_path / "out")["master.ipynb"]
    assert row["total"] == "" and row["p1_ik"] == ""


BURN = "import time\nstart = time.process_time()\nwhile time.process_time() - start < {seconds}:\n    pass"


def _graded(tmp_path, nb, budget: Budget) -> dict:
    """The row of the Problem 1 notebook ``nb``, graded alone under ``budget``."""
    subs = tmp_path / "subs"
    subs.mkdir()
    nbformat.write(nb, subs / "submission.ipynb")
    return run_batch(subs, ROOT / "tests" / "autograder" / "problem1.json", tmp_path / "out", jobs=1, budget=budget)[0]


def _burning(tmp_path, where: int, seconds: float, count: int, budget: Budget) -> dict:
    """The row of Problem 1's master with ``count`` cells, each burning ``seconds`` of CPU,
    inserted after its cell ``where``, graded under ``budget``."""
    nb = load(MASTER)
    for k in range(count):
        nb = insert_after(nb, where + k, BURN.format(seconds=seconds) + f"  # burn {k + 1}")
    return _graded(tmp_path, nb, budget)


def test_cells_past_their_cpu_in_all_stop_the_notebook_and_the_checks_still_run(tmp_path):
    """Each cell within its own limit, together past the cells' limit in all: the notebook stops
    in the cell that used up the rest, as an interrupted kernel would, the cells after it do not
    run, and the functions defined before are graded as usual (README: "Cells that use up the
    120 s ...")."""
    master = load(MASTER)
    budget = Budget(cell=4, run=14, call=3, check=30, idle=4, run_idle=12, check_idle=4)
    row = _burning(tmp_path, len(master.cells) - 1, 3.5, 6, budget)  # 21 s after a whole master
    assert row["status"] == "graded" and row["scores"] == FULL, row
    stopped = [n for n in row["notes"] if "timed out (cpu of all cells together)" in n]
    unrun = [n for n in row["notes"] if "not run, nor any cell after it (the cells had used up their cpu time" in n]
    assert len(stopped) == 1 and len(unrun) == 1, row["notes"]
    assert stopped[0].startswith("cell ") and "('import time')" in stopped[0], row["notes"]
    assert not any("did not finish" in n for n in row["notes"]), row["notes"]


def test_cells_that_run_out_before_the_todos_leave_their_functions_undefined(tmp_path):
    """The same limit met right after the imports: the TODO cells never run, so no check finds
    its function, and the notes name the cell where the notebook stopped."""
    budget = Budget(cell=4, run=6, call=3, check=30, idle=4, run_idle=12, check_idle=4)
    row = _burning(tmp_path, _imports(load(MASTER)), 3.5, 3, budget)
    assert row["status"] == "graded" and set(row["scores"].values()) == {0.0}, row
    assert any("timed out (cpu of all cells together)" in n for n in row["notes"]), row["notes"]
    assert any("not run, nor any cell after it (the cells had used up their cpu time" in n for n in row["notes"])
    assert "p1_ik: IK: ik_3r is not defined: its cell " in " ".join(row["notes"]), row["notes"]
    assert "never ran, the cells before it having used up their time together" in " ".join(row["notes"])


def test_cells_past_their_waiting_in_all_stop_the_notebook_and_the_checks_still_run(tmp_path):
    """As for CPU time, so for waiting: each pause within a cell's limit, together past the
    cells' limit in all, stops the notebook in the pause that used up the rest."""
    master = load(MASTER)
    nb = master
    for k in range(4):  # 14 s of waiting after a whole master, 3.5 s per cell
        nb = insert_after(nb, len(master.cells) - 1 + k, f"import time\ntime.sleep(3.5)  # pause {k + 1}")
    row = _graded(tmp_path, nb, Budget(cell=8, run=40, call=3, check=30, idle=4, run_idle=9, check_idle=4))
    assert row["status"] == "graded" and row["scores"] == FULL, row
    notes = " ".join(row["notes"])
    assert "timed out (idle of all cells together)" in notes and "used up their idle time together" in notes, notes


def test_a_notebook_that_ignores_the_interruption_is_stopped_and_not_graded(tmp_path):
    """A cell that catches the sandbox's interruption and computes on past the cells' limit in
    all (and its grace) is stopped by the judge itself: then no check is graded, not even those
    of the functions defined before, and the reason says why."""
    nb = load(MASTER)
    stubborn = "while True:\n    try:\n        while True:\n            pass\n    except BaseException:\n        pass"
    nb = insert_after(nb, _imports(nb), stubborn)
    row = _graded(tmp_path, nb, Budget(cell=4, run=2, call=3, check=30, idle=4, run_idle=12, check_idle=4))
    assert row["status"] == "graded" and set(row["scores"].values()) == {0.0}, row
    assert row["notes"] == ["the notebook's cells did not finish: it used more than 2 s of CPU time"]


def test_refuses_without_bubblewrap(tmp_path):
    subs = _submissions(tmp_path / "subs", ["master.ipynb"])
    env = {**os.environ, "PATH": str(tmp_path)}  # no bwrap on the path
    proc = _batch_cli("problem1", subs, tmp_path / "out", env=env)
    assert proc.returncode == 2
    assert "bubblewrap (bwrap) is not installed" in proc.stderr and "--unsafe-no-sandbox" in proc.stderr
    assert not (tmp_path / "out").exists()


def test_the_batch_command_says_what_is_wrong_with_its_arguments(tmp_path, capsys):
    """Each used to run and write an empty grades.csv (or, for --timeout, a batch of "timed out")."""
    (tmp_path / "empty").mkdir()
    nested = _submissions(tmp_path / "nested", [])
    _submissions(nested / "sub", ["master.ipynb"])
    (tmp_path / "submissions.zip").write_bytes(b"PK")
    cases = {
        ("--problem", "problem3", "empty"): "problem3.json: the problems are problem1, problem2",
        ("--spec", "none.json", "empty"): "no autograder spec at",
        ("--problem", "problem1", "empty"): "no .ipynb file in",
        ("--problem", "problem1", "nested"): "its subfolders hold 1: give the folder that holds them",
        ("--problem", "problem1", "submissions.zip"): "run python -m labsupport.instructor.canvas",
        ("--problem", "problem1", "nested/sub", "--jobs", "0"): "--jobs must be at least 1",
        ("--problem", "problem1", "nested/sub", "--timeout", "-5"): "--timeout must be a positive number",
    }
    for args, words in cases.items():
        *options, folder = args[:3]
        argv = [*options, str(tmp_path / folder), *args[3:], "--out", str(tmp_path / "out")]
        if options[0] == "--spec":
            argv[1] = str(tmp_path / argv[1])
        with pytest.raises(SystemExit) as stop:
            batch_main(argv)
        assert stop.value.code == 2 and words in capsys.readouterr().err, args
    assert not (tmp_path / "out").exists()


def test_the_batch_commands_defaults_and_the_least_it_accepts(tmp_path, monkeypatch, capsys):
    """The defaults that the help text promises reach the grader (a 900 s backstop, a job per
    CPU, a fresh seed, the sandbox); one job and a backstop under a second are accepted, and
    --out must be given."""
    from labsupport.instructor import batch

    subs = _submissions(tmp_path / "subs", ["master.ipynb"])
    asked = []
    monkeypatch.setattr(batch, "run_batch", lambda *args, **kwargs: asked.append((args, kwargs)))
    batch_main(["--problem", "problem1", str(subs), "--out", str(tmp_path / "out")])
    (folder, spec, out, jobs, timeout), options = asked.pop()
    assert (folder, out, jobs, timeout) == (subs, tmp_path / "out", None, 900.0) and spec.name == "problem1.json"
    assert options == {"seed": None, "unsafe_no_sandbox": False, "compare_with": []}
    batch_main(["--problem", "problem1", str(subs), "--out", str(tmp_path / "out"), "--jobs", "1", "--timeout", "0.5"])
    assert asked.pop()[0][3:] == (1, 0.5)
    for argv, words in (
        (["--problem", "problem1", str(subs)], "the following arguments are required: --out"),
        (["--problem", "problem1", str(subs), "--out", str(tmp_path / "out"), "--timeout", "0"], "--timeout must be"),
    ):
        with pytest.raises(SystemExit) as stop:
            batch_main(argv)
        assert stop.value.code == 2 and words in capsys.readouterr().err
    assert asked == []


def test_a_seed_a_student_could_guess_is_warned_about(tmp_path, monkeypatch, capsys):
    """A notebook can store its answers for each small seed (the red team's held nine, 42 among
    them, and scored full marks with no law at all): --seed below 2**32 warns that it is for
    reproducing a batch; a drawn 48-bit seed, or none, does not."""
    from labsupport.instructor import batch

    subs = _submissions(tmp_path / "subs", ["master.ipynb"])
    monkeypatch.setattr(batch, "run_batch", lambda *args, **kwargs: None)
    for seed, warned in (("42", True), ("20261129", True), (str(2**32), False), (str(batch.new_seed() | 2**40), False)):
        batch_main(["--problem", "problem1", str(subs), "--out", str(tmp_path / "out"), "--seed", seed])
        err = capsys.readouterr().err
        assert (f"warning: --seed {seed} is a seed a notebook could have stored its answers for" in err) == warned, err
    batch_main(["--problem", "problem1", str(subs), "--out", str(tmp_path / "out")])
    assert "warning" not in capsys.readouterr().err


def test_unsafe_opt_out_says_so_in_every_row(tmp_path):
    subs = _submissions(tmp_path / "subs", ["master.ipynb", "invalid_json.ipynb"])
    proc = _batch_cli("problem1", subs, tmp_path / "out", "--unsafe-no-sandbox", "--seed", str(SEED))
    assert proc.returncode == 0, proc.stderr
    rows = _grades(tmp_path / "out")
    assert rows["master.ipynb"]["total"] == "10"
    assert all(UNSAFE_NOTE in r["reason"] for r in rows.values())
    assert "WARNING" in proc.stderr


def test_a_bubblewrap_that_cannot_start_is_quoted_with_each_cause_and_its_remedy(tmp_path, monkeypatch):
    """Where bubblewrap refuses to start (user namespaces disabled, a Docker container's default
    profiles, a chroot), the grader quotes it and says what to do in each case."""
    fake = tmp_path / "bwrap"
    fake.write_text("#!/bin/sh\necho 'bwrap: Creating new namespace failed: Operation not permitted' >&2\nexit 1\n")
    fake.chmod(0o755)
    monkeypatch.setattr(isolation, "find_bwrap", lambda: str(fake))
    with pytest.raises(isolation.SandboxUnavailable) as refused:
        isolation.prepare(tmp_path / "layout")
    said = str(refused.value)
    assert "(bwrap: Creating new namespace failed: Operation not permitted)" in said
    for remedy in (
        "sysctl kernel.unprivileged_userns_clone=1",
        "--security-opt seccomp=unconfined --security-opt apparmor=unconfined",
        "Inside a chroot",
        "--unsafe-no-sandbox",
    ):
        assert remedy in said


def _in_sandbox(layout: isolation.Layout, code: str) -> subprocess.CompletedProcess:
    """``code`` run by Python in a fresh sandbox of ``layout``, under the batch's limits."""
    return subprocess.run(
        isolation.command(layout, [layout.python, "-c", code]),
        capture_output=True,
        text=True,
        timeout=120,
        preexec_fn=lambda: isolation.apply_limits(layout.limits),
    )


def test_the_sandbox_sees_no_checkout_and_no_forbidden_module(tmp_path, monkeypatch):
    monkeypatch.setenv("CANVAS_API_TOKEN", "the instructor's secret")  # the grader's environment stays outside
    layout = isolation.prepare(tmp_path / "layout")
    probe = (
        "import sys, os, labsupport, labsupport.controllers as c\n"
        "print(sys.prefix, sys.base_prefix, labsupport.__file__)\n"
        f"print(os.path.exists({str(ROOT)!r}), os.path.exists({str(tmp_path)!r}))\n"
        "try:\n    c.joint_space.ct_joint_torque()\nexcept RuntimeError as e:\n    print(e)\n"
        "import socket\ntry:\n    socket.create_connection(('1.1.1.1', 53), timeout=2)\n"
        "except OSError as e:\n    print('no network', e.errno)\n"
        # a star import used to define nothing (NameError at the call, not the rule's reason)
        "from labsupport.controllers.joint_space import *\n"
        "try:\n    ct_joint_torque()\nexcept RuntimeError as e:\n    print(e)\n"
        "print(' '.join(sorted(os.environ)))\n"
    )
    proc = _in_sandbox(layout, probe)
    lines = proc.stdout.splitlines()
    assert lines[0].split() == [
        "/opt/venv",
        "/opt/python" if not sys.base_prefix.startswith("/usr") else sys.base_prefix,
        "/opt/student/labsupport/__init__.py",
    ], proc.stderr
    assert lines[1] == "False False"
    assert "is off limits in a Problem TODO" in lines[2]
    assert lines[3].startswith("no network")
    assert "labsupport.controllers.joint_space.ct_joint_torque is off limits in a Problem TODO" in lines[4]
    seen, given = set(lines[5].split()), {name for name, _ in layout.env}
    assert given <= seen <= given | {"PWD", "LC_CTYPE"}  # the layout's, no more, no less


def test_the_sandbox_can_fill_only_its_capped_scratch_space(tmp_path):
    """bubblewrap's root and /dev are tmpfs mounts without a size limit, in the host's memory: a
    submission could fill gigabytes there. Only home, /tmp and /dev/shm take files, each capped;
    and memory its processes ask for together is taken back from them first."""
    layout = isolation.prepare(tmp_path / "layout")
    mib = 1 << 20
    cap = layout.limits.scratch // (8 * mib)  # 8 MiB files each folder can hold
    probe = (  # a few files past the cap at most, so that a regression cannot fill this machine
        "import os\n"
        "for d in ('/', '/opt', '/etc', '/home', '/dev', '/dev/shm', '/tmp', os.getcwd()):\n"
        "    n = 0\n"
        f"    while n < {cap + 2}:\n"
        "        try:\n"
        "            with open(os.path.join(d, f'f{n}'), 'wb') as f:\n"
        f"                f.write(bytes({8 * mib}))\n"
        "        except OSError:\n"
        "            break\n"
        "        n += 1\n"
        "    print(d, n)\n"
        "print(open('/proc/self/oom_score_adj').read().strip())\n"
    )
    proc = _in_sandbox(layout, probe)
    lines = proc.stdout.splitlines()
    assert lines.pop() == "1000", "the sandbox's processes must be the out-of-memory killer's first choice"
    written = {line.split()[0]: int(line.split()[1]) for line in lines}
    assert written.keys() == {"/", "/opt", "/etc", "/home", "/dev", "/dev/shm", "/tmp", "/home/student"}, proc.stderr
    assert all(written[d] == 0 for d in ("/", "/opt", "/etc", "/home", "/dev")), written
    assert all(0 < written[d] <= cap for d in ("/dev/shm", "/tmp", "/home/student")), written


def test_the_sandbox_runs_as_an_ordinary_user_who_writes_nowhere_else(tmp_path):
    """The notebook runs as user 1000, not as the grader's user, under the batch's limits and
    with matplotlib's font cache built once for all; the system, the interpreter, its packages
    and the student's labsupport take no file, even a tiny one; and a file past the size limit is
    refused even where scratch space is left (the limit is a second line, behind the capped
    mounts)."""
    layout = isolation.prepare(tmp_path / "layout")
    mib = 1 << 20
    assert layout.limits.file_size + mib < layout.limits.scratch  # the limit, not the cap, must refuse
    probe = (
        "import errno, glob, os, resource, site, sys, labsupport\n"
        "print(os.getuid(), os.getgid(), os.geteuid(), os.getegid())\n"
        "print(*(resource.getrlimit(getattr(resource, f'RLIMIT_{n}')) for n in ('AS', 'CPU', 'FSIZE', 'CORE')))\n"
        "print(*sorted(os.path.basename(p) for p in glob.glob(os.environ['MPLCONFIGDIR'] + '/fontlist-*.json')))\n"
        "places = ['/usr', '/usr/lib', '/lib', '/etc', sys.prefix, sys.base_prefix, site.getsitepackages()[0],\n"
        "          os.path.dirname(labsupport.__file__), os.path.dirname(os.__file__)]\n"
        "for d in places:\n"
        "    path = os.path.join(d, 'sandbox-probe')\n"
        "    try:\n"
        "        open(path, 'xb').close()\n"
        "    except OSError as e:\n"
        "        print(d, errno.errorcode[e.errno])\n"
        "    else:\n"
        "        os.remove(path)  # a tiny file, taken back at once: a regression leaves nothing behind\n"
        "        print(d, 'writable')\n"
        "try:\n"
        "    with open('/tmp/big', 'wb') as f:\n"
        f"        f.write(bytes({layout.limits.file_size + mib}))\n"
        "    print('big written')\n"
        "except OSError as e:\n"
        "    print('big', errno.errorcode[e.errno])\n"
    )
    proc = _in_sandbox(layout, probe)
    lines = proc.stdout.splitlines()
    assert lines and lines[0] == "1000 1000 1000 1000", (lines, proc.stderr)
    limits = layout.limits
    assert lines[1] == " ".join(str((x, x)) for x in (limits.memory, limits.cpu, limits.file_size, 0)), lines[1]
    font_cache = sorted(p.name for p in (layout.root / "mpl").glob("fontlist-*.json"))
    assert font_cache and lines[2] == " ".join(font_cache)  # matplotlib's, built once for the batch and shared
    places = dict(line.rsplit(" ", 1) for line in lines[3:-1])
    assert len(places) >= 7, (lines, proc.stderr)  # the venv and its base may be the same folder
    assert set(places.values()) <= {"EROFS", "EACCES", "EPERM"}, places
    assert lines[-1] == "big EFBIG", (lines, proc.stderr)


def test_a_forbidden_packages_stub_names_exactly_its_own_modules(tmp_path):
    """A stubbed package imports its modules on demand (``labsupport.controllers.joint_space``
    is a stub of its own); any other name is a refusal, not a failed import."""
    isolation.write_student_package(tmp_path / "student")
    for package in ("controllers", "kinematics"):
        stub = ast.parse((tmp_path / "student" / "labsupport" / package / "__init__.py").read_text())
        (listed,) = [
            ast.literal_eval(node.value)
            for node in stub.body
            if isinstance(node, ast.Assign) and [t.id for t in node.targets] == ["_SUBMODULES"]
        ]
        real = (ROOT / "labsupport" / package).glob("*.py")
        assert listed == tuple(sorted(p.stem for p in real if p.name != "__init__.py")), (package, listed)


def test_the_sandboxs_package_carries_the_forbidden_functions_fingerprints(tmp_path):
    """Its forbidden modules are stubs, so the grader writes the real ones' fingerprints beside
    the rules; they are those of this checkout's laws, and a stub's own functions are not among
    them."""
    import json

    from labsupport.grading import rules

    isolation.write_student_package(tmp_path / "student")
    shipped = json.loads((tmp_path / "student" / "labsupport" / "grading" / rules.FORBIDDEN_CODE_FILE).read_text())
    assert shipped == rules.forbidden_code_of_package(ROOT / "labsupport")
    names = set(shipped.values())
    assert {
        "labsupport.controllers.joint_space.ct_joint_torque",
        "labsupport.kinematics.planar_2r.inverse_kinematics",
        "labsupport.grading.common.tip",
    } <= names
    assert not any(name.startswith(("labsupport.dynamics.", "labsupport.grading.rules.")) for name in names)
    stub = (tmp_path / "student" / "labsupport" / "controllers" / "joint_space.py").read_text()
    assert not set(rules.fingerprints_of_module(stub, "labsupport.controllers.joint_space")) & set(shipped)


def test_the_installed_labsupport_is_masked_in_the_sandbox_whichever_way_it_was_installed(tmp_path, monkeypatch):
    """A wheel leaves ``labsupport/`` and its ``-info`` folder in site-packages; an editable
    install, a ``.pth`` file or finder naming the checkout or labsupport; setuptools' older way, an
    ``.egg-link``. The sandbox sees each of them empty, so the student's stubbed labsupport is
    the only one it can import; every other package stays as it is."""
    site = tmp_path / "site-packages"
    masked_dirs = ["labsupport", "labsupport-1.2.dist-info", "labsupport-0.9.egg-info"]
    masked_files = {
        "__editable__.labsupport-1.2.pth": "import __editable___labsupport_1_2_finder",
        "__editable___labsupport_1_2_finder.py": "MAPPING = {}",
        "course.pth": str(isolation.CHECKOUT),
        "labsupport.egg-link": "somewhere",
    }
    kept = {
        "numpy": None,
        "numpy-2.0.0.dist-info": None,
        "labsupport_extras": None,
        "distutils-precedence.pth": "import os",
        "six.py": "x = 1",
        "labsupport-notes.txt": "not a path file",
    }
    for name in masked_dirs + [n for n, text in kept.items() if text is None]:
        (site / name).mkdir(parents=True)
    for name, text in {**masked_files, **{n: t for n, t in kept.items() if t is not None}}.items():
        (site / name).write_text(text)
    monkeypatch.setattr(sys, "prefix", str(tmp_path / "a-virtual-environment"))
    monkeypatch.setattr(isolation.sysconfig, "get_paths", lambda: {"purelib": str(site)})
    mounts, _, _ = isolation._interpreter_mounts(tmp_path / "layout")
    inside = f"{isolation.VENV}/lib/python{sys.version_info.major}.{sys.version_info.minor}/site-packages"
    binds = {mounts[i + 2]: mounts[i + 1] for i, flag in enumerate(mounts) if flag == "--ro-bind"}
    assert binds[inside] == str(site.resolve())
    masks = {target.rsplit("/", 1)[1]: source for target, source in binds.items() if target.startswith(inside + "/")}
    empty = str(tmp_path / "layout" / "empty")
    assert masks == {**{name: empty for name in masked_dirs}, **{name: "/dev/null" for name in masked_files}}


def test_masters_and_unusual_right_answers_get_full_marks_on_problem2(tmp_path):
    """The master, and the same answers written another right way (a SciPy IK, J̇q̇ by finite
    differences, explicit inverses: ``hostile/build.py``), score full marks in the sandbox."""
    subs = tmp_path / "subs"
    subs.mkdir()
    master = ROOT / "notebooks" / "masters" / "problem2_tracking.ipynb"
    shutil.copy(master, subs / "master.ipynb")
    shutil.copy(ROOT / "notebooks" / "problem2_tracking.ipynb", subs / "student.ipynb")
    nbformat.write(unusual_problem2(nbformat.read(master, as_version=4)), subs / "unusual.ipynb")
    proc = _batch_cli("problem2", subs, tmp_path / "out")
    assert proc.returncode == 0, proc.stderr
    rows = _grades(tmp_path / "out")
    for name in ("master.ipynb", "unusual.ipynb"):
        assert rows[name]["total"] == "10", (name, rows[name]["reason"])
    assert rows["student.ipynb"]["total"] == "0"
    assert "p2_osct: not implemented yet" in rows["student.ipynb"]["reason"]


def test_a_slow_law_costs_only_its_own_share_of_the_tracking_check(tmp_path):
    """The tracking check runs two laws, each with half of the check's CPU time (6 ms a control
    step here; 12 ms under the default budget, as the notebook says). The master's OS-CT made
    slow after the notebook's own runs (20 ms of CPU a call) loses its half; the right and fast
    IK + joint CT that runs after it keeps its half, where one budget for both had lost it too."""
    nb = nbformat.read(ROOT / "notebooks" / "masters" / "problem2_tracking.ipynb", as_version=4)
    slow = (
        "import time\n"
        "honest_os_ct = ct_op_torque\n"
        "def ct_op_torque(model, data, *args):\n"
        "    start = time.process_time()\n"
        "    while time.process_time() - start < 0.02:\n"
        "        pass\n"
        "    return honest_os_ct(model, data, *args)"
    )
    nb = insert_after(nb, len(nb.cells) - 1, slow)
    subs = tmp_path / "subs"
    subs.mkdir()
    nbformat.write(nb, subs / "slow_os_ct.ipynb")
    budget = Budget(cell=30, run=120, call=3, check=30, idle=4, run_idle=12, check_idle=4)
    (row,) = run_batch(subs, ROOT / "tests" / "autograder" / "problem2.json", tmp_path / "out", jobs=1, budget=budget)
    assert row["scores"]["p2_track"] == 1.5, row
    assert row["scores"]["p2_osct"] == 3 and row["scores"]["p2_ikct"] == 3, row
    reason = row["messages"]["p2_track"]
    assert "OS-CT: ct_op_torque did not return: " in reason or "15 s for ct_op_torque" in reason, reason
    assert "IK+JS-CT: RMS error" in reason, reason


def test_the_batch_names_the_line_of_the_students_code_that_raised(tmp_path):
    """The batch's feedback said only NumPy's words for an error in the student's law; it now says
    the line, as the in-notebook check does, and what the six-row Jacobian means."""
    nb = nbformat.read(ROOT / "notebooks" / "masters" / "problem2_tracking.ipynb", as_version=4)
    cell = next(c for c in nb.cells if c.cell_type == "code" and "def ct_op_torque" in c.source)
    six_rows = cell.source.replace(
        'site_jacobian(model, data, "end_effector")[:3]', 'site_jacobian(model, data, "end_effector")'
    )
    assert six_rows != cell.source
    cell.source = six_rows
    subs = tmp_path / "subs"
    subs.mkdir()
    nbformat.write(nb, subs / "six_rows.ipynb")
    proc = _batch_cli("problem2", subs, tmp_path / "out", "--seed", str(SEED))
    assert proc.returncode == 0, proc.stderr
    reason = _grades(tmp_path / "out")["six_rows.ipynb"]["reason"]
    assert re.search(
        r"p2_osct: OS-CT: ct_op_torque raised ValueError: operands could not be broadcast together with shapes "
        r"\(3,\) \(6,\) \(line \d+ of ct_op_torque: e, edot = x_d - x, xd_d - J @ qdot # Cartesian",
        reason,
    ), reason
    assert "has 6 rows, translation then rotation" in reason


def test_a_law_that_writes_into_the_state_it_is_handed_keeps_its_points_and_is_told_so(tmp_path):
    """``e = data.qpos; e -= q_d`` returns the right torque, and each call of the grader gets its
    own copy of the state, so the law keeps its points; but the sandbox now sees the write and the
    row's message for that law says what the student's own run will do with it."""
    nb = load(MASTER)
    cell = next(c for c in nb.cells if c.cell_type == "code" and "def pd_torque" in c.source)
    aliased = cell.source.replace(
        "q, qdot = data.qpos, data.qvel\n    return Kp * (q_d - q) - Kd * qdot",
        "e = data.qpos\n    e -= q_d  # writes into data.qpos\n    return -Kp * e - Kd * data.qvel",
    )
    assert aliased != cell.source
    cell.source = aliased
    row = _graded(tmp_path, nb, BUDGET)
    assert row["status"] == "graded" and row["scores"] == FULL, row
    assert "Note: pd_torque changed data.qpos of the state the check handed it" in row["messages"]["p1_pd"]
    assert "e = q_d - data.qpos" in row["messages"]["p1_pd"]
    assert not any("Note:" in row["messages"][name] for name in row["messages"] if name != "p1_pd"), row["messages"]
    # the grades table's reason says it too (it said "all checks passed"), and the feedback file
    # says it once, under the law's check
    reason = _grades(tmp_path / "out")["submission.ipynb"]["reason"]
    assert reason == "p1_pd: passed, but pd_torque changed data.qpos of the state it was handed", reason
    feedback = (tmp_path / "out" / "feedback" / "submission.txt").read_text(encoding="utf-8")
    assert feedback.count("pd_torque changed data.qpos") == 1, feedback


def test_a_law_written_to_a_module_by_the_notebook_imports_as_in_jupyter(tmp_path):
    """A kernel puts the notebook's folder first on the path; the sandbox did not, so a right PD
    written with ``%%writefile my_pd.py`` and imported from it scored zero (ModuleNotFoundError)."""
    nb = load(MASTER)
    k = _defining(nb, "pd_torque")
    nb.cells[k].source = "%%writefile my_pd.py\nimport numpy as np\n\n" + nb.cells[k].source
    nb = insert_after(nb, k, "from my_pd import pd_torque")
    # a file saved into Colab's working folder is listed where it lies, with the word that the two are one
    nb = insert_after(nb, k + 1, "open('/content/notes.txt', 'w').write('tried Kp = 50')")
    row = _graded(tmp_path, nb, BUDGET)
    assert row["status"] == "graded" and row["scores"] == FULL, row
    wrote = (
        'the notebook wrote files: "/home/student/my_pd.py", "/home/student/notes.txt" (in its private scratch '
        "space, removed after grading; /home/student is the notebook's home folder, and Colab's /content is "
        "the same folder)"
    )
    assert row["notes"] == [wrote], row["notes"]


def test_a_module_the_grader_lacks_gets_a_note_that_says_what_to_do(tmp_path):
    """Colab preinstalls many packages the grader does not have. A cell importing one stops there,
    as it would anywhere without it, and its note now says how to grade it again; a module of
    labsupport that the sandbox leaves out on purpose gets no such advice."""
    nb = insert_after(load(MASTER), _imports(load(MASTER)), "import a_package_only_colab_has")
    nb = insert_after(nb, _imports(nb) + 1, "import labsupport.solutions")
    row = _graded(tmp_path, nb, BUDGET)
    assert row["status"] == "graded" and row["scores"] == FULL, row
    missing, ours = row["notes"]
    assert "No module named 'a_package_only_colab_has'" in missing and judge.MISSING_MODULE_ADVICE in missing
    assert "No module named 'labsupport.solutions'" in ours and judge.MISSING_MODULE_ADVICE not in ours


def test_a_notebook_of_the_older_format_is_read_like_a_current_one():
    """Jupyter still opens format 3 (worksheets of cells, code in ``input``); the grader reads it
    too, instead of calling it unreadable and scoring zero."""
    from labsupport.instructor.judge import read_cells

    current = nbformat.read(ROOT / "notebooks" / "masters" / "problem1_reaching.ipynb", as_version=4)
    code = [c.source for c in current.cells if c.cell_type == "code"]
    older = nbformat.writes(nbformat.convert(current, 3), version=3).encode()  # converts in place
    assert b'"worksheets"' in older and b'"input"' in older
    assert [src for _, src in read_cells(older)] == code
    with pytest.raises(ValueError, match="nested too deeply"):
        read_cells(b"[" * 100000 + b"]" * 100000)


@pytest.mark.parametrize(
    "text",
    [b"[]", b"{}", b'{"cells": {"0": {}}}', b'"cells"', b'{"nbformat": 3, "worksheets": {}}', b"null"],
    ids=["a list", "no cells", "cells not a list", "a string", "format 3 without a list of worksheets", "null"],
)
def test_json_that_is_no_notebook_is_refused_with_its_reason(text):
    """Valid JSON without a list of cells (what a renamed file or a hand-edited notebook can be)
    is refused as such, never with a Python error from inside the reader."""
    from labsupport.instructor.judge import read_cells

    with pytest.raises(ValueError, match=r"^not a valid notebook: no list of cells$"):
        read_cells(text)


def test_a_stubs_source_copied_with_inspect_and_run_with_exec_still_refuses(tmp_path, monkeypatch):
    """The sandbox's stand-in of a forbidden module: a copy of a law's source, run with ``exec``,
    raises the rule's message (an IndentationError before: the stub's functions were nested), as
    do an attribute the real module does not define at its top and a star import."""
    import importlib
    import inspect

    from labsupport.grading import rules

    src = isolation.stub_source("fake_laws", [], rules.forbidden_message("@@NAME@@"), ["ct_joint_torque", "LAB_ARM"])
    (tmp_path / "fake_laws.py").write_text(src, encoding="utf-8")
    monkeypatch.syspath_prepend(str(tmp_path))
    laws = importlib.import_module("fake_laws")
    copied: dict = {}
    exec(inspect.getsource(laws.ct_joint_torque), {}, copied)
    for call in (copied["ct_joint_torque"], laws.ct_joint_torque, laws.LAB_ARM, laws.Reference):
        with pytest.raises(RuntimeError) as err:
            call(1, 2, q_d=3)
        assert rules.is_forbidden_message(err.value) and "fake_laws." in str(err.value)
    with pytest.raises(RuntimeError, match="fake_laws.ct_joint_torque is off limits"):
        copied["ct_joint_torque"]()
    star: dict = {}
    exec("from fake_laws import *", star)
    assert {"ct_joint_torque", "LAB_ARM"} <= set(star)
