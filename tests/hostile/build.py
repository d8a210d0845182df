"""Write the hostile submissions of this folder from the Problem 1 notebooks.

    .venv/bin/python tests/hostile/build.py           # rewrite them
    .venv/bin/python tests/hostile/build.py --check   # fail if any differs from what is committed

Each is the master (a correct notebook) or the student notebook (nothing implemented) with one
misbehaviour added, so a score different from what the test suite expects means either a
grading mistake or a successful attack; one, ``unusual_but_right``, is the master's answers
written another right way, which must keep full marks. Rebuild after changing a Problem 1
notebook.

The memoriser holds the answers of the *public* in-notebook checks (``PUBLIC_SEED``), recorded
here by running the checks against the master's functions.
"""

from __future__ import annotations

import argparse
import base64
import contextlib
import copy
import hashlib
import io
import os
import sys
import zlib
from pathlib import Path

import nbformat
import numpy as np

ROOT = Path(__file__).resolve().parents[2]
HERE = Path(__file__).resolve().parent
MASTER = ROOT / "notebooks" / "masters" / "problem1_reaching.ipynb"
STUDENT = ROOT / "notebooks" / "problem1_reaching.ipynb"
#: Functions of the Problem 1 TODOs.
TODO_FUNCTIONS = ("ik_3r", "pd_torque", "ct_joint_torque")


def _defining(nb, fname: str) -> int:
    for k, cell in enumerate(nb.cells):
        if cell.cell_type == "code" and f"def {fname}(" in cell.source:
            return k
    raise LookupError(f"no cell defines {fname}")


def _imports(nb) -> int:
    for k, cell in enumerate(nb.cells):
        if cell.cell_type == "code" and cell.source.startswith("import labsupport"):
            return k
    raise LookupError("no import cell")


def hidden(source: str) -> str:
    """``source`` run from a compressed, base64-encoded string: the same code, not in the text."""
    blob = base64.b64encode(zlib.compress(source.encode(), 9)).decode()
    return f"import base64, zlib\nexec(zlib.decompress(base64.b64decode({blob!r})).decode())"


def insert_after(nb, index: int, source: str):
    cell = nbformat.v4.new_code_cell(source)
    cell.id = hashlib.sha256(source.encode()).hexdigest()[:8]  # stable, so a rebuild changes nothing
    nb.cells.insert(index + 1, cell)
    return nb


def replace_function(nb, fname: str, source: str):
    nb.cells[_defining(nb, fname)].source = source
    return nb


def load(path: Path):
    return nbformat.read(str(path), as_version=4)


def from_colab(nb):
    """``nb`` as a student may save it from Colab: its imports cell opens with ``%matplotlib
    inline``, Colab's own modules (a Drive mounted) and a test for Colab that, passed, changes
    into Colab's working folder ``/content``; it ends with another backend and a download. A
    ``%%shell`` cell (Colab's own magic) follows it. Right answers there keep full marks."""
    k = _imports(nb)
    cell = nb.cells[k]
    cell.source = (
        "%matplotlib inline\n"
        "import os, sys\n"
        "from google.colab import drive, files\n"
        "from google.colab.patches import cv2_imshow\n"
        "drive.mount('/content/drive')\n"
        "if 'google.colab' in sys.modules:\n"
        "    os.chdir('/content')\n" + cell.source + "\n%matplotlib widget\nfiles.download('run.mp4')\n"
    )
    nb.metadata["colab"] = {"provenance": []}
    return insert_after(nb, k, "%%shell\necho the cells run on\n")


# --- attacks on the grader, each on a notebook that implements nothing -----------------------

#: Overwrite every grades.csv, every check module and every notebook it can reach.
VANDAL = r"""
import os
TARGETS = ("grades.csv", "problem1.py", "problem2.py", "common.py", "__init__.py", "batch.json")
def vandalise(top="/"):
    hits = []
    for base, dirs, files in os.walk(top):
        dirs[:] = [d for d in dirs if os.path.join(base, d) not in ("/proc", "/sys", "/dev")]
        for name in files:
            path = os.path.join(base, name)
            if name.endswith(".ipynb") or name in TARGETS or name.endswith(".txt"):
                try:
                    with open(path, "a") as f:
                        f.write("\nhacked\n")
                    hits.append(path)
                except OSError:
                    pass
    return hits
"""

ESCAPE = (
    VANDAL
    + r"""
import time
if os.fork() == 0:            # an escaped process: new session, double fork
    os.setsid()
    if os.fork() == 0:
        for _ in range(200):  # keeps trying for a while after the batch
            vandalise()
            time.sleep(0.2)
        os._exit(0)
    os._exit(0)
"""
)

WRITES_EVERYWHERE = (
    VANDAL
    + r"""
open("junk.txt", "w").write("x" * 1000)
vandalise()
"""
)

#: TODO 1 through Task 3's planar 2R solve, in the arm's vertical plane: right angles, off limits.
BORROWED_IK = """def ik_3r(x, elbow_up=True):
    from labsupport.kinematics.planar_2r import Planar2R, inverse_kinematics
    rho, h = np.hypot(x[0], x[1]), x[2] - 1.0
    q2, theta = inverse_kinematics(np.array([h, rho]), Planar2R(1.0, 1.0), elbow_up)
    return np.array([np.arctan2(x[1], x[0]), q2, theta - np.pi / 2])"""

#: TODO 3 through Task 3's generic joint computed torque: the right torque, off limits.
BORROWED_CT = """def ct_joint_torque(model, data, q_d, Kp, Kd):
    from labsupport.controllers.joint_space import ct_joint_torque as task3_ct
    return task3_ct(model, data, q_d, np.zeros(3), np.zeros(3), Kp, Kd)"""

#: The borrowing without an import of the law: its source copied with ``inspect`` and run with
#: ``exec``, so that the copy's code is not the library's.
COPIED_CT = """import inspect
from labsupport.controllers import joint_space

_copied = {}
exec(inspect.getsource(joint_space.ct_joint_torque), vars(joint_space) | {}, _copied)


def ct_joint_torque(model, data, q_d, Kp, Kd):
    return _copied["ct_joint_torque"](model, data, q_d, np.zeros(3), np.zeros(3), Kp, Kd)"""

#: The same borrowing, hidden: the IK solved in a worker thread (whose error the thread swallows)
#: and the torque computed only when the grader reads the returned value as numbers.
HIDDEN_IK = """def ik_3r(x, elbow_up=True):
    import threading
    from labsupport.kinematics.planar_2r import Planar2R, inverse_kinematics
    out = {}
    def work():
        rho, h = np.hypot(x[0], x[1]), x[2] - 1.0
        out["q"] = inverse_kinematics(np.array([h, rho]), Planar2R(1.0, 1.0), elbow_up)
    worker = threading.Thread(target=work)
    worker.start()
    worker.join()
    q2, theta = out["q"]
    return np.array([np.arctan2(x[1], x[0]), q2, theta - np.pi / 2])"""

HIDDEN_CT = """class Deferred:
    def __init__(self, *args):
        self.args = args
    def __array__(self, dtype=None, copy=None):
        from labsupport.controllers.joint_space import ct_joint_torque as task3_ct
        return np.asarray(task3_ct(*self.args), dtype=dtype)
    def __len__(self):
        return 3


def ct_joint_torque(model, data, q_d, Kp, Kd):
    return Deferred(model, data, np.array(q_d, dtype=float), np.zeros(3), np.zeros(3), Kp, Kd)"""

#: Right answers written as a student may, unlike the master: a numerical IK (SciPy's bounded
#: least squares on MuJoCo's forward kinematics, the bounds keeping the elbow on the branch
#: asked, restarted where one start ends in a local minimum: from one start it missed a target
#: the grader's seed 424242 draws), the PD with gain matrices (``np.matrix``, whose torque is a (1, 3) row), and the
#: computed torque through MuJoCo's own product M(q) v (``mj_mulM``) and ``qfrc_bias``. They
#: must score full marks in the sandbox too.
UNUSUAL_IK = """from scipy.optimize import least_squares

L1, L2, L3 = 1.0, 1.0, 1.0   # link lengths [m]
fk_data = mujoco.MjData(model)   # scratch for forward kinematics


def tip(q):
    fk_data.qpos[:] = q
    mujoco.mj_kinematics(model, fk_data)
    return fk_data.site("end_effector").xpos.copy()


def ik_3r(x, elbow_up=True):
    x = np.asarray(x, dtype=float)
    q1 = np.arctan2(x[1], x[0])
    if elbow_up:   # theta = q3 + pi/2 in [0, pi]
        bounds, q3 = ([-np.pi, -np.pi / 2], [np.pi, np.pi / 2]), 0.0
    else:          # theta in [-pi, 0]
        bounds, q3 = ([-np.pi, -3 * np.pi / 2], [np.pi, -np.pi / 2]), -np.pi
    for q2 in (0.0, 1.0, -1.0, 2.0, -2.0):   # a local minimum from one start: try another
        fit = least_squares(lambda q23: tip([q1, *q23]) - x, [q2, q3], bounds=bounds,
                            xtol=1e-15, ftol=1e-15, gtol=1e-15)
        if np.linalg.norm(fit.fun) <= 1e-9:
            return (np.array([q1, *fit.x]) + np.pi) % (2 * np.pi) - np.pi
    raise ValueError(f"target {x} is out of reach")"""

UNUSUAL_PD = """def pd_torque(model, data, q_d, Kp, Kd):
    # gain matrices as np.matrix, a MATLAB habit: the torque comes out as a (1, 3) row
    K_p = np.matrix(np.diag(np.broadcast_to(Kp, 3)))
    K_d = np.matrix(np.diag(np.broadcast_to(Kd, 3)))
    return K_p @ (np.asarray(q_d) - data.qpos) - K_d @ data.qvel"""

UNUSUAL_CT = """def ct_joint_torque(model, data, q_d, Kp, Kd):
    qddot_cmd = Kp * (np.asarray(q_d) - data.qpos) - Kd * data.qvel
    M_qddot = np.zeros(model.nv)
    mujoco.mj_mulM(model, data, M_qddot, qddot_cmd)   # M(q) qddot_cmd
    return M_qddot + data.qfrc_bias"""

#: Problem 2's laws written unusually: J̇q̇ by finite differences along the motion (on a scratch
#: MjData, so that both Jacobians belong to the same instant), explicit inverses in place of
#: solves, the end effector placed by the IK's forward kinematics `tip` at the current q, and the
#: IK above.
UNUSUAL_OS_CT = """fd_data = mujoco.MjData(model)   # scratch for finite differences


def jacobian_at(q):
    fd_data.qpos[:] = q
    mujoco.mj_kinematics(model, fd_data)
    mujoco.mj_comPos(model, fd_data)
    return site_jacobian(model, fd_data, "end_effector")[:3].copy()


def ct_op_torque(model, data, x_d, xd_d, xdd_d, Kp, Kd):
    q, qdot, eps = data.qpos, data.qvel, 1e-6
    J = jacobian_at(q)
    jdot_qdot = (jacobian_at(q + eps * qdot) - J) / eps @ qdot
    a = xdd_d + Kd * (xd_d - J @ qdot) + Kp * (x_d - tip(q)) - jdot_qdot
    return mass_matrix(model, data) @ (np.linalg.inv(J) @ a) + data.qfrc_bias"""

UNUSUAL_IK_CT = """def ct_ik_joint_torque(model, data, x_d, xd_d, xdd_d, Kp, Kd):
    eps = 1e-6
    q_d = ik_3r(x_d, elbow_up=True)
    J_inv = np.linalg.inv(jacobian_at(q_d))
    qd_d = J_inv @ xd_d
    jdot_qdot_d = (jacobian_at(q_d + eps * qd_d) - jacobian_at(q_d)) / eps @ qd_d
    qdd_d = J_inv @ (xdd_d - jdot_qdot_d)
    v = qdd_d + Kd * (qd_d - data.qvel) + Kp * (q_d - data.qpos)
    return mass_matrix(model, data) @ v + bias_forces(data)"""


def unusual_problem2(master) -> nbformat.NotebookNode:
    """Problem 2's master (a notebook) with its three functions written unusually; the start
    cell keeps the master's solution (its markers are comments, which the grader ignores)."""
    nb = copy.deepcopy(master)
    for fname, source in (("ik_3r", UNUSUAL_IK), ("ct_op_torque", UNUSUAL_OS_CT), ("ct_ik_joint_torque", UNUSUAL_IK_CT)):
        replace_function(nb, fname, source)
    return nb


#: Rewrites the sandbox's reports as they leave the notebook's process, to plant notes that
#: read like the grader's own.
FORGES_NOTES = r"""
import json
_honest_dumps = json.dumps
def _forged(obj, *args, **kwargs):
    if isinstance(obj, dict) and "errors" in obj:
        obj = dict(obj, errors=[[0, "NOTE TO GRADER: the autograder crashed here; full marks approved by the instructor"]])
    if isinstance(obj, dict) and "wrote" in obj:
        obj = dict(obj, wrote=["INSTRUCTOR OVERRIDE score=10"])
    return _honest_dumps(obj, *args, **kwargs)
json.dumps = _forged
"""

MASTERS_VIA_INTERPRETER = r"""
import os, sys, json, pathlib
import labsupport
starts = [sys.prefix, sys.base_prefix, sys.exec_prefix, os.path.dirname(labsupport.__file__), os.getcwd()]
solutions = []
for start in starts:
    for folder in [pathlib.Path(start), *pathlib.Path(start).parents]:
        for nb in list(folder.glob("*.ipynb")) + list(folder.glob("*/*.ipynb")) + list(folder.glob("*/*/*.ipynb")):
            try:
                cells = json.loads(nb.read_text())["cells"]
            except Exception:
                continue
            for cell in cells:
                src = "".join(cell.get("source", []))
                if cell.get("cell_type") == "code" and "BEGIN SOLUTION" in src:
                    solutions.append(src)
for src in solutions:
    try:
        exec(src, globals())
    except Exception:
        pass
"""

MEMORY_HOG = r"""
import numpy as np
big = np.ones(20 * 2**30 // 8)   # 20 GiB
"""

FORK_BOMB = r"""
import os, time
children = []
for _ in range(100):              # a bounded fork bomb: 100 sleepers
    pid = os.fork()
    if pid == 0:
        time.sleep(120)
        os._exit(0)
    children.append(pid)
"""

#: Silence the cell server's own timers, then write half an answer line into every descriptor
#: (one of them is the grader's channel) and wait: a judge that reads whole lines would wait
#: for the line's end forever.
BLOCKS_CHANNEL = r"""
import os, signal, time
for timer, sig in ((signal.ITIMER_REAL, signal.SIGALRM), (signal.ITIMER_PROF, signal.SIGPROF)):
    signal.setitimer(timer, 0)
    signal.signal(sig, signal.SIG_IGN)
for fd in range(3, 64):
    try:
        os.write(fd, b'{"nonce": ')
    except OSError:
        pass
time.sleep(3600)
"""

#: Write an endless line into every descriptor: a judge that buffers it runs out of memory.
FLOODS_CHANNEL = r"""
import os
chunk = b"x" * (1 << 20)
while True:
    for fd in range(3, 64):
        try:
            os.write(fd, chunk)
        except OSError:
            pass
"""

#: Alter the cells' run answer in the sandbox's own json.dumps: a number where the grader reads
#: a list of cell errors.
TAMPERS_ANSWERS = r"""
import json
honest_dumps = json.dumps
def altered(obj, *args, **kwargs):
    if isinstance(obj, dict) and "errors" in obj:
        obj = dict(obj, errors=5, patched=7)
    return honest_dumps(obj, *args, **kwargs)
json.dumps = altered
"""

#: An answer nested too deeply for any JSON parser: the grader must not crash on it.
CORRUPTS_ANSWERS = r"""
import json
honest_dumps = json.dumps
def altered(obj, *args, **kwargs):
    text = honest_dumps(obj, *args, **kwargs)
    return text[:-1] + ', "x": ' + "[" * 100000 + "]" * 100000 + "}" if '"errors"' in text else text
json.dumps = altered
"""

#: Every answer replaced by one whose fields have the wrong kinds: an error that is not text, a
#: result without its shape. A right notebook then scores nothing, but its row is graded with the
#: reason, not left unrecorded as the grader's own error.
MALFORMS_ANSWERS = r"""
import json
honest_dumps = json.dumps
def altered(obj, *args, **kwargs):
    if isinstance(obj, dict) and "nonce" in obj:
        if "array" in obj:
            obj = {"array": obj["array"], "nonce": obj["nonce"]}
        else:
            obj = {"raised": {"not": "text"}, "nonce": obj["nonce"]}
    return honest_dumps(obj, *args, **kwargs)
json.dumps = altered
"""

#: A right notebook whose every call answer claims that the call wrote into the state, in forms
#: the sandbox never writes: a list inside the list, a number, a made-up field. The note is only
#: words, and these must give neither a note nor the grader's own error; the answers keep full marks.
FORGES_STATE_WRITES = r"""
import json
honest_dumps = json.dumps
forged = [[["data.qpos"]], ["data.qvel", 7], ["NOTE TO GRADER: give full marks"], "data.qpos"]
answers = [0]
def altered(obj, *args, **kwargs):
    if isinstance(obj, dict) and "array" in obj:
        answers[0] += 1
        obj = dict(obj, state_written=forged[answers[0] % len(forged)])
    return honest_dumps(obj, *args, **kwargs)
json.dumps = altered
"""

#: A correct law that sleeps at every control step of a run: the calls' waiting adds up over a check.
SLEEPS_IN_CALLS = r"""
import time
honest_ct = ct_joint_torque
def ct_joint_torque(model, data, q_d, Kp, Kd):
    if data.time > 0:  # the test states of the p1_ct check are at t = 0; a run's steps are not
        time.sleep(0.5)
    return honest_ct(model, data, q_d, Kp, Kd)
"""

#: Slow in every call of a run (more CPU over the reach check than a check may use), and it hides
#: that from any CPU figure the notebook's own process reports: only the judge's /proc reading counts.
#: Each call of a run burns tens of milliseconds, so the reach check's 2,500 calls need several
#: times the 30 s budget; the judge stops the check at 30 s, so the margin costs no time.
LIES_ABOUT_CPU = r"""
import time
time.process_time = lambda: 0.0
honest_ct = ct_joint_torque
def ct_joint_torque(model, data, q_d, Kp, Kd):
    if data.time > 0:  # the test states of the p1_ct check are at t = 0; a run's steps are not
        for _ in range(4_000_000):
            pass
    return honest_ct(model, data, q_d, Kp, Kd)
"""


def memoriser(table: dict) -> str:
    """A notebook cell answering the public checks from a lookup table (and nothing else)."""
    return f"""import numpy as np
TABLE = {table!r}

def _key(fname, args):
    parts = [fname]
    for a in args:
        if hasattr(a, "qpos"):
            parts += [round(float(v), 6) for v in np.concatenate([a.qpos, a.qvel])]
        elif hasattr(a, "nq"):
            continue
        else:
            parts += [round(float(v), 6) for v in np.ravel(a)]
    return repr(parts)

def _lookup(fname, *args):
    value = TABLE.get(_key(fname, args))
    return np.zeros(3) if value is None else np.array(value)

def ik_3r(x, elbow_up=True):
    return _lookup("ik_3r", x, float(elbow_up))

def pd_torque(model, data, q_d, Kp, Kd):
    return _lookup("pd_torque", data, q_d, Kp, Kd)

def ct_joint_torque(model, data, q_d, Kp, Kd):
    return _lookup("ct_joint_torque", data, q_d, Kp, Kd)
"""


def record_public_answers() -> dict:
    """``{key: answer}`` of every call the public checks make to the master's functions."""
    os.environ["LABSUPPORT_GRADING_BATCH"] = "1"  # the master's own check cells stay quiet
    from IPython.core.interactiveshell import InteractiveShell

    from labsupport.grading import PUBLIC_SEED, registry
    from labsupport.grading.feedback import DirectProbe, State

    shell = InteractiveShell.instance()
    with contextlib.redirect_stdout(io.StringIO()):  # the master's printouts are not the build's
        for cell in load(MASTER).cells:
            if cell.cell_type == "code":
                shell.run_cell(cell.source, silent=True)
    table = {}

    class Recorder(DirectProbe):
        def call(self, fname, *args, **kwargs):
            value = super().call(fname, *args, **kwargs)
            parts = [fname]
            for a in args:
                if isinstance(a, State):
                    parts += [round(float(v), 6) for v in np.concatenate([a.q, a.qdot])]
                else:
                    parts += [round(float(v), 6) for v in np.ravel(a)]
            if value is not None and len(table) < 400:
                table[repr(parts)] = np.asarray(value, dtype=float).round(12).tolist()
            return value

    for name, check in registry().items():
        if name.startswith("p1_") and name != "p1_reach":
            check(Recorder(shell.user_ns), PUBLIC_SEED)
    return table


def hostile() -> dict[str, object]:
    """``{file name: notebook}`` of the whole set."""
    from labsupport.instructor import assign

    # the student notebook as the master makes it now, so that a set built (or checked) before
    # assign has run is built from the master all the same
    master, student = load(MASTER), nbformat.reads(assign.outputs(ROOT)[STUDENT], as_version=4)
    out = {}

    def m():
        return copy.deepcopy(master)

    def s():
        return copy.deepcopy(student)

    # mistakes and misbehaviour on a correct notebook
    nb = m()
    del nb.cells[_defining(nb, "pd_torque")]
    out["deleted_cell.ipynb"] = nb
    out["exits.ipynb"] = insert_after(m(), _imports(master), "import os\nos._exit(3)")
    out["hangs_cell.ipynb"] = insert_after(m(), _defining(master, "pd_torque"), "while True:\n    pass")
    out["hangs_forever.ipynb"] = insert_after(
        m(),
        _imports(master),
        "import time\nwhile True:\n    try:\n        time.sleep(0.5)\n    except BaseException:\n        pass",
    )
    out["hangs_in_call.ipynb"] = replace_function(
        m(), "pd_torque", "def pd_torque(model, data, q_d, Kp, Kd):\n    while True:\n        pass"
    )
    nb = m()
    for k in range(3):  # each cell waits less than a cell may, together more
        nb = insert_after(nb, _imports(master) + k, f"import time\ntime.sleep(3.5)  # pause {k + 1}")
    out["sleeps_between_cells.ipynb"] = nb
    out["sleeps_in_calls.ipynb"] = insert_after(m(), len(master.cells) - 1, SLEEPS_IN_CALLS)
    out["lies_about_cpu.ipynb"] = insert_after(m(), len(master.cells) - 1, LIES_ABOUT_CPU)
    out["forges_notes.ipynb"] = insert_after(m(), _imports(master), FORGES_NOTES)
    out["kills_grader.ipynb"] = insert_after(
        m(), _imports(master), "import os, signal\nos.kill(os.getppid(), signal.SIGKILL)\nos.kill(-1, signal.SIGKILL)"
    )
    nb = insert_after(m(), _imports(master), "ratio = 1 / 0   # a bug at the top")
    out["raises.ipynb"] = replace_function(
        nb,
        "ct_joint_torque",
        "def ct_joint_torque(model, data, q_d, Kp, Kd):\n    raise RuntimeError('work in progress')",
    )
    out["returns_nan.ipynb"] = replace_function(
        m(), "ct_joint_torque", "def ct_joint_torque(model, data, q_d, Kp, Kd):\n    return np.full(3, np.nan)"
    )
    nb = replace_function(m(), "ik_3r", BORROWED_IK)  # answers through labsupport: zero, with the reason
    out["borrows_task_code.ipynb"] = replace_function(nb, "ct_joint_torque", BORROWED_CT)
    nb = replace_function(m(), "ik_3r", HIDDEN_IK)
    out["hides_borrowed_code.ipynb"] = replace_function(nb, "ct_joint_torque", HIDDEN_CT)
    out["copies_law_source.ipynb"] = replace_function(m(), "ct_joint_torque", COPIED_CT)
    nb = m()  # the master's answers, each run from an encoded string: right, but hidden from the report
    for fname in TODO_FUNCTIONS:
        nb = replace_function(nb, fname, hidden(nb.cells[_defining(nb, fname)].source))
    out["hides_its_code.ipynb"] = nb
    nb = replace_function(m(), "ik_3r", UNUSUAL_IK)
    nb = replace_function(nb, "pd_torque", UNUSUAL_PD)
    out["unusual_but_right.ipynb"] = replace_function(nb, "ct_joint_torque", UNUSUAL_CT)
    out["from_colab.ipynb"] = from_colab(m())
    nb = m()
    imports = nb.cells.pop(_imports(nb))
    nb.cells.insert(_defining(nb, "ik_3r") + 1, imports)
    out["reordered.ipynb"] = nb
    monkey = (
        "import labsupport.grading, labsupport.grading.problem1 as p1, labsupport.grading.feedback as fb\n"
        "import labsupport.dynamics, labsupport.sim, mujoco\n"
        "everything_passes = lambda *args: fb.passed('x', 'all good')\n"
        "p1.CHECKS = {name: everything_passes for name in ('p1_ik', 'p1_pd', 'p1_ct', 'p1_reach')}\n"
        "labsupport.grading.registry = lambda: p1.CHECKS\n"
        "labsupport.dynamics.mass_matrix = lambda *a, **k: np.eye(3)\n"
        "mujoco.mj_step = lambda *a, **k: None\n"
    )
    nb = insert_after(m(), _imports(master), monkey)
    for fname in TODO_FUNCTIONS:
        args = "x, elbow_up=True" if fname == "ik_3r" else "model, data, q_d, Kp, Kd"
        replace_function(nb, fname, f"def {fname}({args}):\n    return np.zeros(3)")
    out["monkeypatch.ipynb"] = nb
    nb = s()
    for cell in nb.cells:  # outputs claiming every check passed, on a notebook that implements nothing
        if cell.cell_type == "code" and cell.source.startswith("check("):
            name = cell.source.split('"')[1]
            cell.outputs = [nbformat.v4.new_output("stream", name="stdout", text=f"✔ [{name}] all good\n")]
    out["fake_outputs.ipynb"] = nb
    # attacks, each on a notebook that implements nothing
    out["escapes.ipynb"] = insert_after(s(), _imports(student), ESCAPE)
    out["writes_everywhere.ipynb"] = insert_after(s(), _imports(student), WRITES_EVERYWHERE)
    out["masters_via_interpreter.ipynb"] = insert_after(s(), len(student.cells) - 1, MASTERS_VIA_INTERPRETER)
    out["memory_hog.ipynb"] = insert_after(s(), _imports(student), MEMORY_HOG)
    out["fork_bomb.ipynb"] = insert_after(s(), _imports(student), FORK_BOMB)
    out["blocks_channel.ipynb"] = insert_after(s(), _imports(student), BLOCKS_CHANNEL)
    out["floods_channel.ipynb"] = insert_after(s(), _imports(student), FLOODS_CHANNEL)
    out["tampers_answers.ipynb"] = insert_after(s(), _imports(student), TAMPERS_ANSWERS)
    out["corrupts_answers.ipynb"] = insert_after(s(), _imports(student), CORRUPTS_ANSWERS)
    out["malforms_answers.ipynb"] = insert_after(m(), _imports(master), MALFORMS_ANSWERS)
    out["forges_state_writes.ipynb"] = insert_after(m(), _imports(master), FORGES_STATE_WRITES)
    nb = s()
    for fname in TODO_FUNCTIONS:
        del nb.cells[_defining(nb, fname)]
    out["memoriser.ipynb"] = insert_after(nb, _imports(nb), memoriser(record_public_answers()))
    return {name: nbformat.writes(nb) + "\n" for name, nb in out.items()}


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--check", action="store_true", help="only compare with the committed files")
    args = parser.parse_args(argv)
    files = hostile()
    if args.check:
        stale = [n for n, text in files.items() if (HERE / n).read_text(encoding="utf-8") != text]
        if stale:
            print("out of date: " + ", ".join(stale) + "; run python tests/hostile/build.py", file=sys.stderr)
            return 1
        return 0
    for name, text in files.items():
        (HERE / name).write_text(text, encoding="utf-8")
    (HERE / "writes_deletes_files.ipynb").unlink(missing_ok=True)  # replaced by writes_everywhere
    print(f"wrote {len(files)} notebooks to {HERE.relative_to(ROOT)}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
