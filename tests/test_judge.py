"""``judge.grade`` run in this process, on small notebooks and checks of the tests' own.

The batch runs it in its worker processes (``tests/test_grading.py``); here each rule of the
row it returns is seen on its own: the points of each check, the notes, a check that breaks,
a notebook that cannot be read, one that ends its own process, each limit of the budget, the
wall-clock backstop, what the sandbox's server sends back, and the judge's reading of /proc.
"""

import os
import re
import signal
import subprocess
import sys
import time
import types

import nbformat
import numpy as np
import pytest

import labsupport.grading
from labsupport.grading.feedback import State, failed, not_implemented, passed
from labsupport.instructor import isolation, judge, sandbox

SEED = 3


def notebook(*sources: str) -> bytes:
    nb = nbformat.v4.new_notebook(cells=[nbformat.v4.new_code_cell(s) for s in sources])
    return nbformat.writes(nb).encode()


def spec(**points: float) -> dict:
    return {"checks": [{"name": name, "points": p} for name, p in points.items()]}


@pytest.fixture(scope="module")
def start(tmp_path_factory):
    layout = isolation.prepare(tmp_path_factory.mktemp("judge") / "layout")
    return lambda: (isolation.server_command(layout), {}, "/")


@pytest.fixture
def checks(monkeypatch):
    """The judge's registry of checks, replaced by the dictionary a test fills."""
    chosen = {}
    monkeypatch.setattr(labsupport.grading, "registry", lambda: chosen)
    return chosen


def check_double(probe, seed):
    got = probe.call("double", np.array([1.0, float(seed)]))
    if np.allclose(got, [2.0, 2.0 * seed]):
        return passed("c_double", "double doubles")
    return failed("c_double", f"double returned {got}")


def check_written_before_seeds(probe):  # one argument: run_check leaves the seed out
    return passed("c_old", f"value is {float(probe.get('value')):g}")


def check_half(probe, seed):
    return failed("c_half", f"half right at seed {seed}", 0.5)


def check_missing(probe, seed):
    probe.call("not_there", 1.0)
    return passed("c_missing", "unreachable: the call raises")


def check_todo(probe, seed):
    return not_implemented("c_todo", "todo is None: not implemented yet")


NOTEBOOK = notebook(
    "def double(x):\n    return 2 * x",
    "value = 7.0",
    "with open('notes.txt', 'w') as f:\n    f.write('my notes')",
    "raise ValueError('on purpose')",
    "import numpy\nnumpy.allclose = lambda *args, **kwargs: True",
    "exec('last = ' + '1')",
)


def test_each_check_scores_its_share_of_its_points_and_the_notes_say_what_the_notebook_did(start, checks):
    checks.update(
        c_double=check_double,
        c_old=check_written_before_seeds,
        c_half=check_half,
        c_missing=check_missing,
        c_todo=check_todo,
    )
    row = judge.grade(spec(c_double=2, c_old=3, c_half=4, c_missing=1.5, c_todo=1), NOTEBOOK, SEED, start)
    assert row["status"] == "graded", row
    assert row["scores"] == {"c_double": 2.0, "c_old": 3.0, "c_half": 2.0, "c_missing": 0.0, "c_todo": 0.0}
    assert row["messages"] == {
        "c_double": "double doubles",
        "c_old": "value is 7",
        "c_half": "half right at seed 3",
        "c_missing": "not_there is not defined in the notebook (its cell was deleted, renamed or failed, or never ran)",
        "c_todo": "todo is None: not implemented yet",
    }
    assert row["notes"] == [
        "cell 6 (\"exec('last = ' + '1')\") runs code built while the notebook runs (exec, eval or compile of "
        "a string it makes, or code it unpickles, loads or builds), which is not in the notebook's text: the "
        "instructor reads it by hand",
        'cell 4 ("raise ValueError(\'on purpose\')") raised ValueError: "on purpose"',
        "the notebook replaced numpy.allclose (no effect on grading: the checks run in a separate process)",
        'the notebook wrote files: "/home/student/notes.txt" (in its private scratch space, removed after grading'
        + judge.HOME_IS_CONTENT
        + ")",
        "c_half: half right at seed 3",
        "c_missing: not_there is not defined in the notebook (its cell was deleted, renamed or failed, or never ran)",
        "c_todo: not implemented yet",
    ]
    assert row["sandbox_cpu"] > 0


@pytest.mark.parametrize("many", [5, 7])
def test_the_notes_name_five_failed_cells_replaced_names_and_files_at_most(start, checks, many):
    """A notebook of many errors gets a readable list, not a wall: five of each, and "..." only
    where there were more. A check's share of its points is kept to four decimals."""

    def check_third(probe, seed):
        return failed("c_third", "a third right", 1 / 3)

    checks.update(c_third=check_third)
    names = ("cos", "exp", "hypot", "log", "sin", "sqrt", "tan")[:many]
    replaces = (
        "import numpy\n"
        f"for name in {names!r}:\n"
        "    setattr(numpy, name, lambda *args, f=getattr(numpy, name), **kwargs: f(*args, **kwargs))"
    )
    writes = f"for n in range({many}):\n    open(f'file{{n}}.txt', 'w').close()"
    cells = [f"raise ValueError('error {n}')" for n in range(1, many + 1)] + [replaces, writes]
    row = judge.grade(spec(c_third=1), notebook(*cells), SEED, start)
    assert row["scores"] == {"c_third": 0.3333}
    failed_cells = [n for n in row["notes"] if n.startswith("cell ")]
    assert [n.rsplit(" ", 1)[1] for n in failed_cells] == [f'{n}"' for n in range(1, 6)], row["notes"]
    more = " ..." if many > 5 else ""
    assert (
        f"the notebook replaced numpy.cos, numpy.exp, numpy.hypot, numpy.log, numpy.sin{more} "
        "(no effect on grading: the checks run in a separate process)"
    ) in row["notes"], row["notes"]
    (files,) = [n for n in row["notes"] if n.startswith("the notebook wrote files: ")]
    assert files.count("/home/student/file") == 5 and (" ... (in its" in files) == (many > 5), files


def test_without_a_sandbox_the_same_notebook_scores_the_same(tmp_path, checks, monkeypatch):
    """``--unsafe-no-sandbox`` (trusted submissions): the server runs on this interpreter, with
    the student's labsupport first on the path, in a scratch folder of its own, and without the
    grader's environment."""
    monkeypatch.setenv("CANVAS_API_TOKEN", "the instructor's secret")
    root = isolation.prepare_unsafe(tmp_path / "unsafe")
    assert (root / "student" / "labsupport" / "__init__.py").is_file()
    assert (root / "runner" / isolation.SERVER).is_file()

    def check_secret(probe, seed):
        return passed("c_secret", f"{float(probe.get('secret')):g} characters of the secret")

    checks.update(c_double=check_double, c_old=check_written_before_seeds, c_half=check_half, c_secret=check_secret)
    secret = notebook("import os\nsecret = len(os.environ.get('CANVAS_API_TOKEN', ''))")
    row = judge.grade(spec(c_secret=1), secret, SEED, lambda: isolation.unsafe_command(root))
    assert row["messages"] == {"c_secret": "0 characters of the secret"}, row
    row = judge.grade(spec(c_double=2, c_old=3, c_half=4), NOTEBOOK, SEED, lambda: isolation.unsafe_command(root))
    assert row["status"] == "graded" and row["scores"] == {"c_double": 2.0, "c_old": 3.0, "c_half": 2.0}, row
    assert 'cell 4 ("raise ValueError(\'on purpose\')") raised ValueError: "on purpose"' in row["notes"]
    (files,) = [n for n in row["notes"] if n.startswith("the notebook wrote files: ")]
    (shown,) = re.findall(r'"(/[^"]+)"', files)  # the row's scratch folder, perhaps cut, and the file's name
    head = shown.removesuffix("/notes.txt").removesuffix("…")
    assert shown.endswith("/notes.txt") and head, files
    assert f"{tmp_path}/unsafe/row-".startswith(head) or head.startswith(f"{tmp_path}/unsafe/row-"), files


def test_a_function_whose_cell_failed_is_told_why_it_is_not_defined(start, checks):
    """A function whose defining cell raised (a syntax error) is named with that cell and its
    error, the line counted in the cell, never IPython's <ipython-input-...> name; a function no
    cell defines keeps the plain "not defined"."""
    checks.update(c_double=check_double)
    broken = notebook("x = 1", "def double(x):\n    return 2 * (x")
    row = judge.grade(spec(c_double=2), broken, SEED, start)
    assert row["scores"] == {"c_double": 0.0}, row
    message = row["messages"]["c_double"]
    assert message.startswith("double is not defined: its cell 2 ('def double(x):') raised SyntaxError: "), message
    assert "(line 2 of the cell)" in message and "ipython-input" not in message, message
    assert "ipython-input" not in " ".join(row["notes"]), row["notes"]
    row = judge.grade(spec(c_double=2), notebook("x = 1"), SEED, start)
    assert "double is not defined in the notebook (its cell was deleted" in row["messages"]["c_double"], row


def test_errors_forged_in_the_graders_channel_are_named_and_never_break_the_row(start, checks):
    """The notebook's process writes the report of its own run, so a notebook can rewrite it:
    entries that are not ``[cell, text]`` are dropped, and a cell the notebook does not have
    is named by its number, never looked up."""
    forge = (
        "import json\n"
        "real = json.dumps\n"
        "def forged(obj, *args, **kwargs):\n"
        "    if isinstance(obj, dict) and 'errors' in obj:\n"
        "        obj = {**obj, 'errors': [['a', 1], [2, 'KeyError: at the last cell'], [3, 'no error at all'],\n"
        "                                 [-1, 'NameError: before the first'], [0]]}\n"
        "    return real(obj, *args, **kwargs)\n"
        "json.dumps = forged"
    )
    checks.update(c_double=check_double)
    row = judge.grade(spec(c_double=2), notebook("def double(x):\n    return 2 * x", "x = 1", forge), SEED, start)
    assert row["status"] == "graded" and row["scores"] == {"c_double": 2.0}, row
    assert row["notes"] == [
        "cell 3 ('import json') raised KeyError: \"at the last cell\"",
        'code cell 4 reported an error in a form the sandbox never writes: "no error at all"',
        'code cell 0 raised NameError: "before the first"',
    ], row["notes"]


def test_a_check_that_breaks_leaves_the_row_unrecorded_and_the_others_scored(start, checks):
    def check_with_a_bug(probe, seed):
        return {}["a key the check forgot"]

    checks.update(c_double=check_double, c_bug=check_with_a_bug)
    row = judge.grade(spec(c_double=2, c_bug=1), NOTEBOOK, SEED, start)
    assert row["status"] == "error"
    assert row["scores"] == {"c_double": 2.0, "c_bug": 0.0}
    assert row["messages"]["c_bug"] == "the grader could not run this check: KeyError: 'a key the check forgot'"
    assert "c_bug: the grader could not run this check: KeyError: 'a key the check forgot'" in row["notes"]


def test_an_unreadable_notebook_scores_zero_on_every_check_without_a_sandbox(checks):
    def no_sandbox():
        raise AssertionError("an unreadable notebook needs no sandbox")

    checks.update(c_double=check_double)
    row = judge.grade(spec(c_double=2, c_half=1), b"this is not a notebook", SEED, no_sandbox)
    assert row["status"] == "unreadable"
    assert row["scores"] == {"c_double": 0.0, "c_half": 0.0}
    reason = row["notes"][0]  # said once, in words a student can act on
    assert reason.startswith("not a notebook: a notebook (.ipynb) is JSON text that starts with {, and this file ")
    assert "starts with 'this is not a notebook' (a Python file renamed" in reason and judge.DOWNLOAD_AGAIN in reason
    assert row["notes"] == [reason] and row["messages"] == {"c_double": judge.UNREADABLE, "c_half": judge.UNREADABLE}
    for blank in (b"   \n", b"\xef\xbb\xbf"):  # white space, or a byte-order mark alone: an IndexError once
        said = judge.grade(spec(c_double=2, c_half=1), blank, SEED, no_sandbox)
        assert said["status"] == "unreadable" and said["notes"][0].startswith("not a notebook: the file holds nothing")
    cut = judge.grade(spec(c_double=2, c_half=1), b'{"cells": [', SEED, no_sandbox)["notes"][0]
    assert cut.startswith("not a valid notebook: invalid JSON (Expecting value at line 1), cut short or edited; open")


def test_a_notebook_that_ends_its_own_process_is_not_graded_and_said_so_once(start, checks):
    checks.update(c_double=check_double, c_half=check_half)
    row = judge.grade(
        spec(c_double=2, c_half=1), notebook("def double(x):\n    return 2 * x", "import os\nos._exit(3)"), SEED, start
    )
    why = "the notebook ended the grading process while its cells ran (exit, crash or kill)"
    assert row["status"] == "graded"
    assert row["scores"] == {"c_double": 0.0, "c_half": 0.0}
    assert row["messages"] == {"c_double": f"not graded: {why}", "c_half": f"not graded: {why}"}
    assert row["notes"] == [why]  # not once more for each check


def test_past_the_wall_clock_backstop_the_row_asks_to_be_graded_again(start, checks):
    checks.update(c_double=check_double)
    waits = notebook("import time\nt0 = time.time()\nwhile time.time() - t0 < 20:\n    time.sleep(0.05)")
    row = judge.grade(spec(c_double=2), waits, SEED, start, judge.Budget(wall=1.0, idle=30.0, run_idle=60.0))
    assert row["status"] == judge.REGRADE and row["scores"] == {} and row["messages"] == {}
    (note,) = row["notes"]
    assert "grade it again (with the same --seed) before recording a score" in note, note


def test_a_passed_check_whose_law_wrote_into_its_state_keeps_its_points_and_gets_a_note(start, checks):
    def check_law(probe, seed):
        probe.call("law", State(q=np.array([0.1, 0.2, 0.3]), qdot=np.zeros(3)))
        return passed("c_law", "the law ran")

    checks.update(c_law=check_law)
    law = "def law(model, data):\n    data.qvel[:] = 1.0\n    return [0.0, 0.0, 0.0]"
    row = judge.grade(spec(c_law=4), notebook(law), SEED, start)
    assert row["status"] == "graded" and row["scores"] == {"c_law": 4.0}
    assert row["notes"] == ["c_law: passed, but law changed data.qvel of the state it was handed"], row["notes"]


def test_a_function_that_writes_into_the_array_it_is_handed_keeps_its_points_and_gets_a_note(start, checks):
    """An IK that works in place on its target (``x[2] -= L1``) answers right, since every call
    gets a copy, but the notebook's own run cell hands it the notebook's target, which it then
    moves. The sandbox sees the write, and the check's message says so, as in the notebook."""

    def check_ik(probe, seed):
        x = np.array([0.5, 0.2, 1.3])
        q = probe.call("ik", x)
        assert np.array_equal(x, [0.5, 0.2, 1.3]) and np.allclose(q, [0.5, 0.2, 0.3])
        return passed("c_ik", "the IK ran")

    checks.update(c_ik=check_ik)
    in_place = "def ik(x, elbow_up=True):\n    x[2] -= 1.0\n    return x"
    row = judge.grade(spec(c_ik=4), notebook(in_place), SEED, start)
    assert row["status"] == "graded" and row["scores"] == {"c_ik": 4.0}, row
    assert "Note: ik changed the array it was handed as x (an in-place operation" in row["messages"]["c_ik"], row
    copying = "def ik(x, elbow_up=True):\n    x = x - [0, 0, 1.0]\n    return x"
    row = judge.grade(spec(c_ik=4), notebook(copying), SEED, start)
    assert row["scores"] == {"c_ik": 4.0} and "Note" not in row["messages"]["c_ik"], row


SPIN = "import time\nt0 = time.process_time()\nwhile time.process_time() - t0 < {seconds}:\n    pass\n"


def test_the_cpu_time_of_a_process_tree_counts_its_children_running_and_reaped():
    """What the processes say they used (``time.process_time``), against the judge's reading of
    /proc: a child still running, a child that ended and was reaped, and the root's own."""
    tree = (  # the running child leads a process group of its own: the tree follows parents, not groups
        "import subprocess, sys, time\n"
        f"spin = {SPIN!r}\n"
        "done = subprocess.run([sys.executable, '-c', spin.format(seconds=0.4) + 'print(time.process_time())'],\n"
        "                      capture_output=True, text=True)\n"
        "running = subprocess.Popen([sys.executable, '-c', spin.format(seconds=0.6)\n"
        "                            + 'print(time.process_time(), flush=True)\\ntime.sleep(60)'],\n"
        "                           stdout=subprocess.PIPE, text=True, start_new_session=True)\n"
        "exec(spin.format(seconds=0.3))\n"
        "print(running.pid, done.stdout.strip(), running.stdout.readline().strip(), time.process_time(), flush=True)\n"
        "time.sleep(60)\n"
    )
    root = subprocess.Popen([sys.executable, "-c", tree], stdout=subprocess.PIPE, text=True, start_new_session=True)
    line = root.stdout.readline().split()
    measured = judge.tree_cpu(root.pid)
    os.killpg(root.pid, signal.SIGKILL)
    if line:
        os.kill(int(line[0]), signal.SIGKILL)
    root.wait()
    said = [float(x) for x in line[1:]]
    assert len(said) == 3 and sum(said) > 1.3, said
    assert measured == pytest.approx(sum(said), abs=0.1), (measured, said)
    assert judge.tree_cpu(root.pid) == 0.0  # a process that is gone has used nothing the judge can see


def test_waiting_is_told_from_running_or_queueing_for_a_cpu():
    """``_busy``: the wall clock runs on past CPU time plus queueing only while a process waits
    (sleeps, reads); a process that runs, or is runnable on a machine kept busy, keeps up."""
    if not os.path.exists(f"/proc/{os.getpid()}/schedstat"):
        pytest.skip("this kernel keeps no scheduler statistics: the judge then counts no time as waiting")
    cpu = min(os.sched_getaffinity(0))  # three spinners share it: each queues two thirds of the time
    spin = f"import os\nos.sched_setaffinity(0, {{{cpu}}})\nprint(flush=True)\nwhile True:\n    pass"
    sleeper = subprocess.Popen(
        [sys.executable, "-c", "import time; print(flush=True); time.sleep(60)"], stdout=subprocess.PIPE
    )
    spinners = [subprocess.Popen([sys.executable, "-c", spin], stdout=subprocess.PIPE) for _ in range(3)]
    spinner = spinners[0]
    try:
        for proc in (sleeper, *spinners):
            proc.stdout.readline()  # started
        before = {p: judge._busy(p.pid) for p in (sleeper, spinner)}
        time.sleep(0.6)
        after = {p: judge._busy(p.pid) for p in (sleeper, spinner)}
    finally:
        for proc in (sleeper, *spinners):
            proc.kill()
            proc.wait()
    waited = {p: (after[p][0] - before[p][0]) - (after[p][1] - before[p][1]) for p in (sleeper, spinner)}
    assert waited[sleeper] > 0.5, waited
    assert abs(waited[spinner]) < 0.1, waited
    wall, busy = judge._busy(sleeper.pid)  # gone: unknown, never counted as waiting
    assert wall == pytest.approx(busy, abs=1e-3)


def test_each_limit_of_the_budget_stops_what_passes_it_and_says_which(start, checks):
    """A cell past its CPU or waiting time is stopped and the next cell runs; a call past its own
    limits scores zero on its check, and the other checks still run."""

    def check_spin(probe, seed):
        probe.call("spin")
        return passed("c_spin", "unreachable: the call is stopped")

    def check_wait(probe, seed):
        probe.call("wait")
        return passed("c_wait", "unreachable: the call is stopped")

    checks.update(c_spin=check_spin, c_wait=check_wait, c_double=check_double)
    cells = notebook(
        "while True:\n    pass",
        "import time\ntime.sleep(30)",
        "def double(x):\n    return 2 * x",
        "def spin():\n    while True:\n        pass",
        "def wait():\n    import time\n    time.sleep(30)",
    )
    budget = judge.Budget(cell=0.5, run=10.0, call=0.5, idle=0.5, run_idle=10.0, check_idle=5.0)
    row = judge.grade(spec(c_spin=1, c_wait=1, c_double=2), cells, SEED, start, budget)
    assert row["status"] == "graded" and row["scores"] == {"c_spin": 0.0, "c_wait": 0.0, "c_double": 2.0}, row
    assert row["notes"][:2] == [
        "cell 1 ('while True:') timed out (cpu)",
        "cell 2 ('import time') timed out (idle)",
    ], row["notes"]
    assert row["messages"]["c_spin"] == "spin did not return: it used too much CPU time", row["messages"]
    assert row["messages"]["c_wait"] == "wait did not return: it waited too long", row["messages"]


@pytest.mark.parametrize("reason", ["cpu", "idle"])
def test_past_what_the_cells_have_together_no_later_cell_runs(start, checks, reason):
    """The cells together may use 0.8 s (of CPU time, the interpreter's start included, or of
    waiting), each 0.5 s: the cells that spin, or wait, are stopped one by one until they have
    used that up (after which cell depends on the machine), and no cell after runs."""
    checks.update(c_double=check_double)
    budget = judge.Budget(cell=0.5, run=0.8, idle=0.5, run_idle=0.8)
    stall = "while True:\n    pass" if reason == "cpu" else "import time\ntime.sleep(30)"
    cells = notebook(*[stall] * 3, "def double(x):\n    return 2 * x")
    row = judge.grade(spec(c_double=2), cells, SEED, start, budget)
    *stopped, unrun = [note.split(") ", 1)[1] for note in row["notes"] if note.startswith("cell ")]
    assert stopped and set(stopped) <= {f"timed out ({reason})", f"timed out ({reason} of all cells together)"}
    assert f"timed out ({reason} of all cells together)" not in stopped[:-1], stopped  # one such cell at most: the last
    assert unrun == f"not run, nor any cell after it (the cells had used up their {reason} time together)"
    assert row["scores"] == {"c_double": 0.0} and "double is not defined" in row["messages"]["c_double"]


def test_the_notebook_can_neither_write_into_the_graders_channel_nor_read_from_it(start, checks):
    """The server's own descriptors 0 and 1 lead to /dev/null before any cell runs: half a line
    written to descriptor 1 (as a C library or a shell command would print) cannot run into the
    server's next answer, and a thread reading descriptor 0 steals no request of the judge's."""
    checks.update(c_double=check_double)
    cells = notebook(
        "import os, threading\nos.write(1, b'{\"nonce\": ')\nos.system('printf half')",
        "threading.Thread(target=lambda: os.read(0, 1 << 16), daemon=True).start()",
        "def double(x):\n    return 2 * x",
    )
    row = judge.grade(spec(c_double=2), cells, SEED, start)
    assert row["status"] == "graded" and row["scores"] == {"c_double": 2.0}, row
    assert row["notes"] == [], row["notes"]


class TimerOneTickEarly(sandbox.Watch):
    """A watch whose CPU timer fires when its own clock reads 4 ms short of the limit, as the
    kernel's timer may against ``time.process_time`` on a crowded machine. Each cell's source is
    the CPU time it needs."""

    def arm(self, cpu, idle):
        self.limit, self.used, self.reason = max(cpu, 0.01), 0.0, ""  # the sandbox's smallest timer

    def disarm(self):
        pass

    def cpu(self):
        return self.used

    def idle(self):
        return 0.0

    def run_cell(self, src):
        if float(src) > self.limit:
            self.used, self.reason = self.limit - 0.004, "cpu"
            return types.SimpleNamespace(error_in_exec=sandbox.CellTimeout(), error_before_exec=None)
        self.used = float(src)
        return types.SimpleNamespace(error_in_exec=None, error_before_exec=None)


def test_the_cell_stopped_at_what_the_cells_had_left_is_the_last_that_runs():
    """Cells that each need 3 s of CPU time, with 4 s for each and 7 s for all: the third is
    stopped at the 1 s left, and the fourth does not run, even when the timer fired a hair
    before the clock read 1 s. (The fourth was given the sliver left, and named as stopped too.)"""
    watch = TimerOneTickEarly()
    left = {"cpu": 7.0, "idle": float("inf")}
    errors = sandbox.run_cells(["3", "3", "3", "3", "3"], watch.run_cell, watch, {"cpu": 4.0, "idle": 5.0}, left)
    assert errors == [[2, sandbox.timed_out("cpu", in_all=True)], [3, sandbox.not_run("cpu")]]
    assert left["cpu"] == 0


def test_what_the_server_sends_back_for_odd_values_long_errors_and_threads(start, checks):
    """A text that reads as a number is still text; an array of the largest size sent comes back
    whole, one element more is refused by its size; a long error is cut (200 characters for a
    cell, 300 for a call); an error in a thread the call started counts only where it is an
    off-limits call of labsupport."""

    def read(name):
        def check(probe, seed):
            value = probe.get(name)
            return passed(name, f"{np.shape(value)} {float(np.sum(value)):g}")

        return check

    def call(name):
        def check(probe, seed):
            return passed(name, f"{float(probe.call(name, 1.0)):g}")

        return check

    def read_none(probe, seed):
        return passed("nothing", f"{probe.get('nothing')}")

    values = ("text", "largest", "too_large", "cplx")
    names = [*values, "long_error", "thread_error", "thread_off_limits", "thread_off_limits_text", "thread_unneeded"]
    checks.update({name: (read if name in values else call)(name) for name in names}, nothing=read_none)
    checks["not_a_function"] = call("text")
    cells = notebook(
        "import threading\nimport numpy as np\nimport labsupport.controllers.joint_space as js",
        f"text = '1.5'\nlargest = np.ones({sandbox.MAX_ELEMENTS})\ntoo_large = np.ones({sandbox.MAX_ELEMENTS + 1})\n"
        "cplx = np.array([1 + 2j])\nnothing = None",
        "import os\nos.symlink('/etc/hostname', 'a_link')  # a link is no file of the notebook's\n"
        "for folder in ('runs', '.cache/pip', '__pycache__'):  # the last two: tools' caches, not listed\n"
        "    os.makedirs(folder)\n"
        "    open(f'{folder}/out.csv', 'w').close()",
        "raise ValueError('c' * 1000)",
        "def long_error(x):\n    raise ValueError('f' * 1000)",
        "def in_a_thread(work):\n    t = threading.Thread(target=work)\n    t.start()\n    t.join()",
        "def thread_error(x):\n    in_a_thread(lambda: 1 / 0)\n    return 2 * x",
        "def thread_off_limits(x):\n    out = {}\n    in_a_thread(lambda: out.update(tau=js.ct_joint_torque()))\n"
        "    return out['tau']  # never stored: KeyError",
        "def thread_off_limits_text(x):\n    out = {}\n    in_a_thread(lambda: out.update(tau=js.ct_joint_torque()))\n"
        "    return out.get('tau', 'no torque')  # text, not numbers",
        "def thread_unneeded(x):\n    in_a_thread(js.ct_joint_torque)\n    return 3 * x  # the right answer without it",
    )
    row = judge.grade(spec(**dict.fromkeys([*names, "nothing", "not_a_function"], 1)), cells, SEED, start)
    messages = row["messages"]
    assert messages["nothing"] == "None" and messages["cplx"].startswith("cplx returned complex numbers"), messages
    (files,) = [note for note in row["notes"] if note.startswith("the notebook wrote files: ")]
    assert files.startswith('the notebook wrote files: "/home/student/runs/out.csv" (in its'), files
    assert messages["text"] == "text is a value of type str, expected numbers", messages
    assert messages["largest"] == f"({sandbox.MAX_ELEMENTS},) {sandbox.MAX_ELEMENTS}", messages
    assert (
        messages["too_large"]
        == f"too_large is a value of type array of {sandbox.MAX_ELEMENTS + 1} numbers (too large), expected numbers"
    )
    assert messages["long_error"].startswith("long_error raised ValueError: " + "f" * 300), messages
    assert "f" * 301 not in messages["long_error"], messages
    assert f'raised ValueError: "{"c" * 200}"' in row["notes"][0] and "c" * 201 not in row["notes"][0], row["notes"]
    assert messages["thread_error"] == "2", messages  # the thread's ZeroDivisionError was not the call's
    assert messages["not_a_function"] == "text should be a function, but it is of type str", messages
    off_limits = "labsupport.controllers.joint_space.ct_joint_torque is off limits in a Problem TODO"
    assert off_limits in messages["thread_off_limits_text"], messages
    # the sandbox watches each call as the notebook does: a call into a forbidden module is a
    # forbidden use, whether or not the answer needs it
    assert off_limits in messages["thread_unneeded"], messages
    assert (
        "labsupport.controllers.joint_space.ct_joint_torque is off limits in a Problem TODO"
        in messages["thread_off_limits"]
    )


def test_colabs_own_modules_import_as_stand_ins_and_the_notebook_runs_on(start, checks):
    """A notebook from Colab mounts its Drive, downloads a file and turns on widgets: in the
    sandbox each is a stand-in that does nothing, so the cells after it run; a module the grader
    lacks is still named, with advice."""

    def check_after(probe, seed):
        return passed("c_after", f"{float(probe.get('after')):g} {float(probe.get('has_dunder')):g}")

    checks.update(c_after=check_after)
    cells = notebook(
        "from google.colab import drive, files\ndrive.mount('/content/drive')\nfiles.download('results.csv')",
        "import google.colab.output\ngoogle.colab.output.enable_custom_widget_manager()",
        "import google.colab\nhas_dunder = hasattr(google.colab.drive, '__wrapped__')",
        "import a_module_nobody_has",
        "after = 42",
    )
    row = judge.grade(spec(c_after=1), cells, SEED, start)
    assert row["messages"] == {"c_after": "42 0"}, row
    (note,) = row["notes"]
    assert note.startswith("cell 4 ('import a_module_nobody_has') raised ModuleNotFoundError: "), note
    assert note.endswith(f"({judge.MISSING_MODULE_ADVICE})"), note


def test_a_cell_kept_from_its_cpu_by_other_work_is_not_counted_as_waiting(start, checks):
    """The cell pins itself and two spinning processes to one CPU, so that it queues for it two
    thirds of the time: it still meets its CPU limit, not its waiting limit (waiting counts only
    while it could not run at all)."""
    checks.update(c_double=check_double)
    crowded = (
        "import os, subprocess, sys, time\n"
        "cpu = min(os.sched_getaffinity(0))\n"
        "os.sched_setaffinity(0, {cpu})\n"
        "spin = f'import os\\nos.sched_setaffinity(0, {{{cpu}}})\\nwhile True:\\n    pass'\n"
        "others = [subprocess.Popen([sys.executable, '-c', spin]) for _ in range(2)]\n"
        "time.sleep(0.2)\n"
        "t0 = time.process_time()\n"
        "while time.process_time() - t0 < 5:\n"
        "    pass"
    )
    budget = judge.Budget(cell=1.0, idle=0.6, run=20.0, run_idle=20.0)
    row = judge.grade(spec(c_double=2), notebook(crowded, "def double(x):\n    return 2 * x"), SEED, start, budget)
    assert row["notes"] == ["cell 1 ('import os, subprocess, sys, time') timed out (cpu)"], row["notes"]
    assert row["scores"] == {"c_double": 2.0}


def test_the_cells_cpu_time_together_counts_from_the_processs_start(start, checks):
    """The run's CPU budget includes what the server used to start (Python, NumPy, MuJoCo,
    IPython), as the judge's own watch counts it: with 3 s for the run, a cell that brings the
    process's CPU time to 2 s runs to its end, and the next, which would bring it to 3.4 s, is
    stopped. Counted from the first cell instead, the second would end too, whenever the start
    took more than 0.2 s of CPU time (it takes more on any machine)."""
    checks.update(c_double=check_double)
    up_to = "import time\nwhile time.process_time() < {seconds}:\n    pass"
    cells = notebook(up_to.format(seconds=2.0), up_to.format(seconds=3.4), "def double(x):\n    return 2 * x")
    row = judge.grade(spec(c_double=2), cells, SEED, start, judge.Budget(cell=10.0, run=3.0))
    assert row["notes"] == [
        "cell 2 ('import time') timed out (cpu of all cells together)",
        "cell 3 ('def double(x):') not run, nor any cell after it (the cells had used up their cpu time together)",
        "c_double: double is not defined: its cell 3 ('def double(x):') not run, nor any cell after it (the cells "
        "had used up their cpu time together)",
    ], row["notes"]


def test_the_sandbox_server_run_by_hand_says_what_it_is_and_stops(tmp_path):
    """``python -m labsupport.instructor.sandbox --help`` printed nothing and hung: the server
    silences its output, lists every file under the working folder, then waits for the judge's
    requests on stdin. Given arguments (or a terminal), it now says what it is and exits."""
    done = subprocess.run(
        [sys.executable, "-m", "labsupport.instructor.sandbox", "--help"],
        cwd=tmp_path,
        stdin=subprocess.DEVNULL,
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert done.returncode == 1 and done.stdout == ""
    assert "not a command: to grade, run python -m labsupport.instructor.batch --help" in done.stderr
