"""The Problems' checks, graded through DirectProbe: the masters' hand-written solutions, blank
TODOs, typical mistakes (each named), unusual but correct solutions, forbidden calls into
labsupport, secret seeds, and the student's package holding no answer."""

import ast
import contextlib
import importlib
import importlib.util
import inspect
import io
import json
import os
import pkgutil
import re
import subprocess
import sys
import threading
import time
import types
import warnings
from functools import partial
from pathlib import Path

import mujoco
import nbformat
import numpy as np
import pytest
from nbtools import carried_code

import labsupport
import labsupport.controllers.joint_space as joint_space_alias
from labsupport.dynamics import ANGULAR_ROWS, bias_forces, mass_matrix, site_jacobian, site_jdot_qdot
from labsupport.grading import PUBLIC_SEED, check, common, feedback, problem1, problem2, registry, rules, stability
from labsupport.grading.feedback import (
    FAIL,
    NOT_IMPLEMENTED,
    PARTIAL,
    PASS,
    DirectProbe,
    ForbiddenCall,
    NotImplementedYet,
    Probe,
    State,
    StudentError,
    failed,
    forbidden_reason,
    raised_text,
    refused,
    show_beside,
    show_pair,
    where_raised,
)
from labsupport.grading.stability import effective_damping, stiff_damping
from labsupport.instructor import assign
from labsupport.instructor.assign import settings_drift
from labsupport.kinematics.planar_2r import Planar2R
from labsupport.kinematics.planar_2r import inverse_kinematics as planar_ik
from labsupport.trajectories import circle_3d

ROOT = Path(__file__).resolve().parents[1]
OTHER_SEED = 918273
SITE = "end_effector"


# --- solutions, written the way students write them ---------------------------------------------


def namespace_of(notebook: Path) -> dict:
    """Run a Problem notebook's code cells up to its last TODO (check cells and IPython magics
    left out) and return its namespace: the functions a check grades."""
    nb = nbformat.read(str(notebook), as_version=4)
    cells = [c.source for c in nb.cells if c.cell_type == "code" and not c.source.startswith("check(")]
    last = max(k for k, src in enumerate(cells) if "TODO" in src or "BEGIN SOLUTION" in src)
    ns: dict = {"__name__": "__student__"}
    with contextlib.redirect_stdout(io.StringIO()):  # its pictures' HTML filled a failure's report
        for src in cells[: last + 1]:
            exec("\n".join(line for line in src.split("\n") if not line.lstrip().startswith("%")), ns)
    return ns


@pytest.fixture(scope="module")
def master1():
    return namespace_of(ROOT / "notebooks" / "masters" / "problem1_reaching.ipynb")


@pytest.fixture(scope="module")
def master2():
    return namespace_of(ROOT / "notebooks" / "masters" / "problem2_tracking.ipynb")


def grade(name: str, seed: int = PUBLIC_SEED, **functions):
    return registry()[name](DirectProbe(functions), seed)


def jacobian_at(model, q, qdot=None):
    """J and Jdot qdot of the tip at (q, qdot) on a scratch MjData, as a student computes them."""
    d = mujoco.MjData(model)
    d.qpos[:] = q
    d.qvel[:] = 0 if qdot is None else qdot
    mujoco.mj_kinematics(model, d)
    mujoco.mj_comPos(model, d)
    mujoco.mj_comVel(model, d)
    return site_jacobian(model, d, SITE)[:3].copy(), site_jdot_qdot(model, d, SITE)[:3]


def tip_at(model, q):
    d = mujoco.MjData(model)
    d.qpos[:] = q
    mujoco.mj_kinematics(model, d)
    return d.site(SITE).xpos.copy()


def posed_log(model, q, t):
    """A tracking run's log with the joint angles ``q`` at the times ``t``, its tip exactly on its
    reference at every step."""
    q = np.asarray(q, dtype=float)
    ee = np.array([tip_at(model, p) for p in q])
    return types.SimpleNamespace(q=q, ee=ee, ref=ee, t=np.asarray(t, dtype=float))


def newton_ik(x, elbow_up=True):
    """Numerical IK: Newton's method on MuJoCo's forward kinematics, its steps capped at 0.3 rad
    (full steps wander off by many turns from a poor start, and where they land then depends on
    the last bit of the arithmetic), restarted until it lands on the asked branch (elbow up:
    theta = q3 + pi/2 in (0, pi), i.e. cos q3 > 0)."""
    model = common.arm_model()
    x = np.asarray(x, float)
    for q3 in (0.5, -0.5, 1.2, -1.2, 0.0):
        q = np.array([np.arctan2(x[1], x[0]), 0.3, q3 if elbow_up else -np.pi - q3])
        for _ in range(200):
            err = x - tip_at(model, q)
            if np.linalg.norm(err) < 1e-12:
                break
            J, _ = jacobian_at(model, q)
            step = np.linalg.lstsq(J, err, rcond=None)[0]
            q = q + step * min(1.0, 0.3 / np.linalg.norm(step))
        if np.linalg.norm(x - tip_at(model, q)) < 1e-9 and (np.cos(q[2]) > 0) == elbow_up:
            return q
    raise ValueError(f"no solution for {x}")


def os_law(model, data, x_d, xd_d, xdd_d, Kp, Kd, jdq=None, *, inv=False):
    """OS-CT written out; ``jdq`` replaces MuJoCo's Jdot qdot (None: MuJoCo's)."""
    M, h = mass_matrix(model, data), bias_forces(data)
    J = site_jacobian(model, data, SITE)[:3]
    jdq = site_jdot_qdot(model, data, SITE)[:3] if jdq is None else jdq
    a = xdd_d + Kd * (xd_d - J @ data.qvel) + Kp * (x_d - data.site(SITE).xpos) - jdq
    return M @ (np.linalg.inv(J) @ a if inv else np.linalg.solve(J, a)) + h


def ik_ct_law(model, data, x_d, xd_d, xdd_d, Kp, Kd, ik=newton_ik, jdq_of=None):
    """IK + joint CT with a given IK; ``jdq_of(J_d, q_d, qd_d)`` replaces MuJoCo's Jdot qdot at the reference."""
    q_d = ik(x_d, elbow_up=True)
    J_d, _ = jacobian_at(model, q_d)
    qd_d = np.linalg.solve(J_d, xd_d)
    jdq = jacobian_at(model, q_d, qd_d)[1] if jdq_of is None else jdq_of(J_d, q_d, qd_d)
    qdd_d = np.linalg.solve(J_d, xdd_d - jdq)
    M, h = mass_matrix(model, data), bias_forces(data)
    return M @ (qdd_d + Kd * (qd_d - data.qvel) + Kp * (q_d - data.qpos)) + h


class TimeDifference:
    """Jdot by finite differences in time: remembers the previous call's J (reset when time goes back)."""

    def __init__(self):
        self.J = self.t = None

    def jdq(self, J, qdot, t):
        fresh = self.t is None or not (0 < t - self.t <= 0.01)
        value = np.zeros(3) if fresh else (J - self.J) / (t - self.t) @ qdot
        self.J, self.t = J.copy(), t
        return value


def os_fd_time():
    memory = TimeDifference()

    def ct_op_torque(model, data, x_d, xd_d, xdd_d, Kp, Kd):
        J = site_jacobian(model, data, SITE)[:3]
        return os_law(model, data, x_d, xd_d, xdd_d, Kp, Kd, memory.jdq(J, data.qvel, data.time), inv=True)

    return ct_op_torque


def os_fd_configuration(model, data, x_d, xd_d, xdd_d, Kp, Kd, eps=1e-6):
    """Jdot qdot = (J(q + eps qdot) - J(q)) / eps qdot: finite differences along the motion."""
    J, _ = jacobian_at(model, data.qpos)
    J2, _ = jacobian_at(model, data.qpos + eps * data.qvel)
    return os_law(model, data, x_d, xd_d, xdd_d, Kp, Kd, (J2 - J) / eps @ data.qvel)


def os_no_jdot(model, data, x_d, xd_d, xdd_d, Kp, Kd):
    return os_law(model, data, x_d, xd_d, xdd_d, Kp, Kd, np.zeros(3))


def ik_ct_fd_time(ik=newton_ik):
    memory = TimeDifference()

    def ct_ik_joint_torque(model, data, x_d, xd_d, xdd_d, Kp, Kd):
        def jdq_of(J_d, q_d, qd_d):
            return memory.jdq(J_d, qd_d, data.time)

        return ik_ct_law(model, data, x_d, xd_d, xdd_d, Kp, Kd, ik=ik, jdq_of=jdq_of)

    return ct_ik_joint_torque


# --- the masters earn full marks; blanks are "not implemented yet" ----------------------------------


@pytest.mark.parametrize("seed", [PUBLIC_SEED, OTHER_SEED])
def test_masters_get_full_marks(master1, master2, seed):
    for name, fn in registry().items():
        ns = master1 if name.startswith("p1") else master2
        result = fn(DirectProbe(ns), seed)
        assert result.status == PASS and result.score == 1.0, result
        if name == "p1_reach":  # it ends some 1e-12 mm off, which read "7.17e-12 mm"
            assert "the end effector ends within 0.001 mm of the target" in result.message, result


def test_the_masters_solution_text_quotes_its_own_pd_run(master1):
    """The solution's prose types in the PD run's sag and final error. A gain or target changed in
    the master moved them (to 41 mm, say) while the text kept "about 12 mm", and no test read it."""
    nb = nbformat.read(str(ROOT / "notebooks" / "masters" / "problem1_reaching.ipynb"), as_version=4)
    text = " ".join(next(c.source for c in nb.cells if "The measured sag matches" in c.source).split())
    log, q_d, Kp = master1["logs"]["PD"], master1["q_des"], master1["Kp_pd"]
    sag = q_d - log.q[-1]
    data = common.data_at(common.arm_model(), q_d)
    predicted = bias_forces(data) / Kp  # g(q_d) / Kp: at rest h = g
    off = np.max(np.abs(sag[1:] / predicted[1:] - 1))  # the pan carries no gravity load
    error_mm = 1e3 * np.linalg.norm(log.ee[-1] - master1["target_pos"])
    for said in (
        f"within about {100 * off:.0f} %",
        f"about {sag[1]:.3f} rad at the shoulder and {sag[2]:.3f} rad at the elbow".replace("-", "−"),
        f"ends about {error_mm:.0f} mm from the target",
    ):
        assert said in text, f'the master\'s solution cell ("The measured sag matches ...") should say {said!r}'


def test_masters_write_the_laws_by_hand():
    """No master imports labsupport's controllers or kinematics: the solutions are written out."""
    for name in ("problem1_reaching", "problem2_tracking"):
        nb = nbformat.read(str(ROOT / "notebooks" / "masters" / f"{name}.ipynb"), as_version=4)
        imported = []
        for cell in nb.cells:
            if cell.cell_type == "code":
                code = "\n".join(line for line in cell.source.split("\n") if not line.lstrip().startswith("%"))
                for node in ast.walk(ast.parse(code)):
                    if isinstance(node, ast.Import):
                        imported += [alias.name for alias in node.names]
                    elif isinstance(node, ast.ImportFrom):
                        imported += [node.module] + [f"{node.module}.{alias.name}" for alias in node.names]
        assert "labsupport.dynamics.mass_matrix" in imported
        assert not [m for m in imported if rules.is_forbidden_module(m)], imported


def test_blank_notebooks_are_not_implemented_yet():
    ns1 = namespace_of(ROOT / "notebooks" / "problem1_reaching.ipynb")
    ns2 = namespace_of(ROOT / "notebooks" / "problem2_tracking.ipynb")
    for name, fn in registry().items():
        result = fn(DirectProbe(ns1 if name.startswith("p1") else ns2), PUBLIC_SEED)
        assert result.status == NOT_IMPLEMENTED and result.score == 0, result
        assert "not implemented yet" in result.message


def test_in_notebook_check_uses_the_public_seed(master1, capsys):
    result = check("p1_ct", master1)
    assert result.score == 1 and "✔ [p1_ct]" in capsys.readouterr().out
    assert result == problem1.check_ct(DirectProbe(master1), PUBLIC_SEED)


# --- typical mistakes, each named ----------------------------------------------------------------


def pd_variant(spring=1.0, damping=-1.0, scale=1.0, bias=False, gravity=False):
    def pd_torque(model, data, q_d, Kp, Kd):
        tau = scale * (spring * Kp * (q_d - data.qpos) + damping * Kd * data.qvel)
        tau = tau + bias_forces(data) if bias else tau
        return tau + gravity_at(model, data.qpos) if gravity else tau

    return pd_torque


PD_MISTAKES = [
    (pd_variant(spring=-1.0, damping=1.0), 0.0, "wrong sign: it pushes away"),
    (pd_variant(spring=-1.0), 0.0, "spring term has the wrong sign"),
    (pd_variant(damping=0.0), 0.5, "damping term −Kd q̇ is missing"),
    (pd_variant(damping=1.0), 0.5, "damping has the wrong sign"),
    (pd_variant(bias=True), 0.5, "computed torque's model term"),
    (pd_variant(gravity=True), 0.5, "you added gravity compensation g(q)"),  # was a bare zero
    (pd_variant(scale=180 / np.pi), 0.25, "degrees"),
]


@pytest.mark.parametrize("fn, score, words", PD_MISTAKES)
def test_pd_mistakes_are_named(fn, score, words):
    result = grade("p1_pd", pd_torque=fn)
    assert result.score == score and words in result.message, result


def ct_variant(spring=1.0, damping=-1.0, mass=True, bias=1.0, scale=1.0, damping_outside=False, gravity=False):
    def ct_joint_torque(model, data, q_d, Kp, Kd):
        M = mass_matrix(model, data) if mass else np.eye(3)
        v = scale * (spring * Kp * (q_d - data.qpos) + (0 if damping_outside else damping * Kd * data.qvel))
        extra = damping * Kd * data.qvel if damping_outside else 0
        h = gravity_at(model, data.qpos) if gravity else bias_forces(data)
        return M @ v + extra + bias * h

    return ct_joint_torque


CT_MISTAKES = [
    (ct_variant(bias=0.0), 0.25, "bias term h(q, q̇)"),
    (ct_variant(mass=False), 0.25, "mass matrix is missing"),
    (ct_variant(spring=-1.0), 0.0, "spring term has the wrong sign"),
    (ct_variant(spring=-1.0, damping=1.0), 0.0, "feedback terms (Kp, Kd) have the wrong sign"),
    (ct_variant(bias=-1.0), 0.25, "added, not subtracted"),
    (ct_variant(damping_outside=True), 0.5, "inside M(q)"),
    (ct_variant(damping=0.0), 0.5, "the damping term −Kd q̇ inside M(q)(...) is missing"),
    (ct_variant(damping=1.0), 0.5, "the damping has the wrong sign: it must be −Kd q̇"),
    (ct_variant(gravity=True), 0.5, "the bias term holds gravity alone"),
    (ct_variant(scale=180 / np.pi), 0.25, "degrees"),
]


@pytest.mark.parametrize("fn, score, words", CT_MISTAKES)
def test_ct_mistakes_are_named(fn, score, words):
    result = grade("p1_ct", ct_joint_torque=fn)
    assert result.score == score and words in result.message, result


def test_check_names_a_wrong_call():
    with pytest.raises(ValueError, match=r"no check named 'p3'; the checks are \['p1_ct', 'p1_ik'"):
        check("p3", {})
    with pytest.raises(ValueError, match=r"call check\('p1_pd', globals\(\)\)"):
        check("p1_pd", None)


def test_a_reach_that_falls_short_points_back_at_the_law():
    """CT without h ends 13 cm from the target; the message said only that, with no word on where to look."""

    def ct_without_h(model, data, q_d, Kp, Kd):
        return mass_matrix(model, data) @ (Kp * (q_d - data.qpos) - Kd * data.qvel)

    result = grade("p1_reach", ct_joint_torque=ct_without_h)
    assert result.score == 0 and "h(q, q̇) or M(q) most often; the CT check, p1_ct, says which" in result.message


def test_a_law_written_with_the_labs_scaffold_signature_is_told_to_keep_the_stubs(master1):
    """The lab's own scaffold writes pd_torque(data, q_d, Kp, Kd): the check's call then fails in
    Python itself, and the message says which arguments the checks pass."""

    def pd_torque(data, q_d, Kp, Kd):
        return Kp * (q_d - data.qpos) - Kd * data.qvel

    result = grade("p1_pd", pd_torque=pd_torque)
    assert result.score == 0 and "takes 4 positional arguments but 5 were given" in result.message
    assert "keep the stub's def line as it was handed out" in result.message, result.message
    assert "out, def pd_torque(model, data, q_d, Kp, Kd))" in result.message, result.message


def test_the_signature_hint_quotes_each_stubs_def_line_as_handed_out():
    """The hint quotes the def line of the stub, so an IK written as ik_3r(x) (elbow-up only), or
    with its keyword renamed, is shown the line the checks call; each quoted line is the line
    the student notebooks hand out."""
    handed_out = set()
    for path in sorted((ROOT / "notebooks").glob("problem*.ipynb")):
        for cell in nbformat.read(path, as_version=4).cells:
            handed_out.update(re.findall(r"^def \w+\(.*\)(?=:)", cell.source, re.M))
    assert set(feedback.STUB_DEF_LINES.values()) <= handed_out, handed_out

    def ik_3r(x):
        return np.zeros(3)

    result = grade("p1_ik", ik_3r=ik_3r)
    assert "got an unexpected keyword argument 'elbow_up'" in result.message, result
    assert "keep the stub's def line as it was handed out, def ik_3r(x, elbow_up=True))" in result.message, result


def test_complex_numbers_are_named_in_the_notebook_and_in_the_batch_grader(master1):
    """(1 - c**2)**0.5 with |c| > 1 is complex in Python; NumPy used to drop the imaginary part
    with a ComplexWarning, and the check then compared the real part."""
    ik = master1["ik_3r"]
    complex_ik = grade("p1_ik", ik_3r=lambda x, elbow_up=True: ik(x, elbow_up) + 0j)
    assert complex_ik.score == 0 and "ik_3r returned complex numbers" in complex_ik.message, complex_ik
    pd = grade("p1_pd", pd_torque=lambda *args: [1j, 0.0, 0.0])
    assert pd.score == 0 and "(1 - c**2)**0.5" in pd.message, pd
    from labsupport.instructor import judge, sandbox

    assert sandbox._encode([1j, 0.0, 0.0]) == {"complex": True}
    with pytest.raises(StudentError, match="pd_torque returned complex numbers"):
        judge._decode("pd_torque", sandbox._encode(np.array([0.5 + 0j, 1, 2])), call=True)


def test_a_list_that_is_not_three_numbers_is_shown():
    ct = grade("p1_ct", ct_joint_torque=lambda *args: [[1.0], [2.0], [3.0, 4.0]])
    assert ct.score == 0 and "returned list [[1.0], [2.0], [3.0, 4.0]], expected 3 numbers" in ct.message


def test_an_object_that_fails_to_become_numbers_is_named_not_raised():
    """The check promises never to raise because of the student's code: a returned object whose
    own conversion fails with any exception is a zero with a reason, not a traceback."""

    class Weird:
        def __array__(self, dtype=None, copy=None):
            raise RuntimeError("not today")

    result = grade("p1_pd", pd_torque=lambda *args: Weird())
    assert result.score == 0, result
    assert (
        "pd_torque returned a value of type Weird that raised RuntimeError when read as numbers: not today"
        in result.message
    )


def test_ik_mistakes_are_named(master1):
    ik = master1["ik_3r"]
    degrees = grade("p1_ik", ik_3r=lambda x, elbow_up=True: np.degrees(ik(x, elbow_up)))
    assert degrees.score == 0 and "in degrees" in degrees.message and "radians" in degrees.message
    # both branches solved, but swapped: half, as an IK that solves one branch for both (it scored 0,
    # below that one, while it had done more)
    swapped = grade("p1_ik", ik_3r=lambda x, elbow_up=True: ik(x, not elbow_up))
    assert swapped.score == 0.5 and "but each on the other elbow branch than the one asked" in swapped.message
    assert "Swap the two branches" in swapped.message
    one_branch = grade("p1_ik", ik_3r=lambda x, elbow_up=True: ik(x, True))
    assert one_branch.score == 0.5 and "elbow-up branch" in one_branch.message
    # swapped on most targets but not all: counted call by call, as before
    first = problem1.draw_configuration(problem1.rng_for(PUBLIC_SEED, "p1_ik"), elbow_up=True)
    target = common.tip(common.arm_model(), first)
    mostly = grade("p1_ik", ik_3r=lambda x, elbow_up=True: ik(x, elbow_up == np.allclose(x, target)))
    assert mostly.score == pytest.approx(2 / (2 * problem1.N_TARGETS)) and "Swap" not in mostly.message

    def worst_error(result) -> float:
        return float(re.search(r"worst error (\S+) m", result.message).group(1))

    assert worst_error(grade("p1_ik", ik_3r=ik)) < 1e-12  # the closed form's: rounding only
    near = grade("p1_ik", ik_3r=lambda x, elbow_up=True: ik(x, elbow_up) + [0.0, 0.0, 3e-5])  # within IK_TOL
    assert near.score == 1 and 1e-5 < worst_error(near) < 1e-4
    wrong_elbow = grade("p1_ik", ik_3r=lambda x, elbow_up=True: ik(x, elbow_up) + [0.0, 0.3, 0.0])
    assert wrong_elbow.score == 0 and "the pan angle is right" in wrong_elbow.message
    assert "check the planar 2R solve" in wrong_elbow.message and "numerical IK" not in wrong_elbow.message
    # a numerical IK stopped a little early (about 0.15 mm off) is told to iterate further
    early = grade("p1_ik", ik_3r=lambda x, elbow_up=True: ik(x, elbow_up) + [0.0, 0.0, 1.5e-4])
    assert early.score < 1 and "more than the 0.1 mm allowed" in early.message
    assert "a numerical IK must go on until the tip is within 0.1 mm" in early.message
    swapped_pan = grade("p1_ik", ik_3r=lambda x, elbow_up=True: ik([x[1], x[0], x[2]], elbow_up))
    assert swapped_pan.score < 1 and "azimuth atan2(y, x)" in swapped_pan.message
    # and the azimuth it quotes is the target's own
    quoted = re.search(r"the target \[([^\]]+)\] has azimuth atan2\(y, x\) = (-?[\d.]+) rad", swapped_pan.message)
    x, y, _ = map(float, quoted.group(1).split())
    assert float(quoted.group(2)) == pytest.approx(np.arctan2(y, x), abs=2e-3)


def test_an_ik_that_returns_none_on_one_branch_scores_the_other(master1):
    """An IK right elbow-up that returns None elbow-down scored 0, told "not implemented yet":
    it now keeps the share it solves, and is told where it returned None. An IK that returns
    None everywhere is still not implemented."""
    ik = master1["ik_3r"]
    half = grade("p1_ik", ik_3r=lambda x, elbow_up=True: ik(x, True) if elbow_up else None)
    assert half.score == 0.5 and "not implemented" not in half.message
    assert "elbow_up=False: ik_3r returned None there, where it returns angles for other calls" in half.message
    nothing = grade("p1_ik", ik_3r=lambda x, elbow_up=True: None)
    assert nothing.score == 0 and nothing.status == "not implemented yet"


def test_an_ik_that_never_returns_is_stopped_in_the_notebook_too(master1, monkeypatch):
    """In the notebook, a check of an IK that never returns ran for ever (the batch stops each
    call after CALL_CPU_SECONDS of CPU time): it stops now too, even in a loop that catches every
    Exception, and scores the calls that returned."""
    from labsupport.grading import feedback

    monkeypatch.setattr(feedback, "CALL_CPU_SECONDS", 0.3)
    ik = master1["ik_3r"]

    def stubborn(x, elbow_up=True):
        while not elbow_up:
            try:
                sum(range(1000))
            except Exception:
                pass
        return ik(x, elbow_up)

    t0 = time.monotonic()
    result = grade("p1_ik", ik_3r=stubborn)
    assert time.monotonic() - t0 < 30
    assert result.score == 0.5
    assert "ik_3r did not return: it used 0.3 s of CPU time, the most one call may use" in result.message
    assert "The other 23 elbow-down calls were not made (counted wrong)" in result.message


def test_ik_that_accepts_unreachable_targets_is_told(master1):
    def no_check(x, elbow_up=True):
        return master1["ik_3r"](np.asarray(x) * min(1.0, 1.9 / np.linalg.norm(np.asarray(x) - [0, 0, 1])), elbow_up)

    result = grade("p1_ik", ik_3r=no_check)
    assert result.score == 1 and "returned angles instead of raising a ValueError" in result.message
    for out_of_reach, said in ((None, "None"), (np.full(3, np.nan), "NaN")):

        def quiet(x, elbow_up=True, out_of_reach=out_of_reach):
            if np.linalg.norm(np.asarray(x) - [0, 0, 1]) > 2:
                return out_of_reach
            return master1["ik_3r"](x, elbow_up)

        result = grade("p1_ik", ik_3r=quiet)
        assert result.score == 1 and f"returned {said} instead of raising a ValueError" in result.message, result
        assert "no points lost" in result.message


def test_ik_that_refuses_unreachable_targets_with_another_error_is_told_which_to_raise(master1):
    """The master's ValueError gets no remark; an IK that refuses with another exception keeps
    its points and is told that ValueError is the one to raise."""
    assert "out of reach" not in grade("p1_ik", ik_3r=master1["ik_3r"]).message

    def arithmetic(x, elbow_up=True):
        if np.linalg.norm(np.asarray(x) - [0, 0, 1]) > 2:
            raise ArithmeticError("too far")
        return master1["ik_3r"](x, elbow_up)

    result = grade("p1_ik", ik_3r=arithmetic)
    assert result.score == 1, result
    assert "(For a target out of reach, [2.4 0.  1.5], it should raise ValueError; it raised ArithmeticError" in (
        result.message
    )


def test_the_out_of_reach_probe_leaks_no_numpy_warning_into_the_students_output(master1):
    """An IK that takes arccos of a cosine past 1 printed NumPy's "invalid value encountered in
    arccos" under the check: the check's own probe, not anything the student ran."""

    def arccos_anyway(x, elbow_up=True):
        x = np.asarray(x, float)
        if np.linalg.norm(x - [0, 0, 1]) > 2:
            return np.full(3, np.arccos(1.5))  # NaN, with NumPy's RuntimeWarning
        return master1["ik_3r"](x, elbow_up)

    with warnings.catch_warnings():
        warnings.simplefilter("error", RuntimeWarning)
        result = grade("p1_ik", ik_3r=arccos_anyway)
    assert result.score == 1 and "returned NaN instead of raising" in result.message


def test_a_start_that_is_none_because_ik_3r_is_not_pasted_says_where_to_look():
    """q0_traj = ik_3r(x0) with TODO 1 still empty said only "q0_traj is None", and the student
    looked for the mistake in TODO 2."""
    result = grade("p2_start", q0_traj=None, ik_3r=lambda x, elbow_up=True: None)
    assert "q0_traj is None: not implemented yet; if it is set as ik_3r(x0), check TODO 1 first" in result.message


OS_MISTAKES = [
    ("no_jdot", 0.5, "−J̇q̇ term, which is missing"),
    ("jdot_sign", 0.25, "must be subtracted"),
    ("no_bias", 0.25, "bias term"),
    ("bias_sign", 0.25, "h(q, q̇) must be added, not subtracted"),  # was a bare zero
    ("jdot_at_reference", 0.75, "J̇q̇ is taken at the reference's velocity J⁻¹ẋ_d"),  # was a bare zero
    ("transpose", 0.0, "not Jᵀ"),
    ("no_ff", 0.25, "feed-forward acceleration ẍ_d"),
    ("spring_sign", 0.0, "spring term has the wrong sign"),
]


def os_mistake(mistake):
    """A student's OS-CT with one of :data:`OS_MISTAKES`."""

    def ct_op_torque(model, data, x_d, xd_d, xdd_d, Kp, Kd):
        M, h = mass_matrix(model, data), bias_forces(data)
        J = site_jacobian(model, data, SITE)[:3]
        jdq = site_jdot_qdot(model, data, SITE)[:3]
        e, edot = x_d - data.site(SITE).xpos, xd_d - J @ data.qvel
        if mistake == "jdot_at_reference":  # J̇q̇ on a scratch MjData moving at J⁻¹ẋ_d
            jdq = jacobian_at(model, data.qpos, np.linalg.solve(J, xd_d))[1]
        a = {
            "no_jdot": xdd_d + Kd * edot + Kp * e,
            "jdot_sign": xdd_d + Kd * edot + Kp * e + jdq,
            "no_ff": Kd * edot + Kp * e - jdq,
            "spring_sign": xdd_d + Kd * edot - Kp * e - jdq,
        }.get(mistake, xdd_d + Kd * edot + Kp * e - jdq)
        if mistake == "transpose":
            return M @ (J.T @ a) + h
        return M @ np.linalg.solve(J, a) + {"no_bias": 0, "bias_sign": -h}.get(mistake, h)

    return ct_op_torque


@pytest.mark.parametrize("mistake, score, words", OS_MISTAKES)
def test_os_ct_mistakes_are_named(mistake, score, words):
    result = grade("p2_osct", ct_op_torque=os_mistake(mistake))
    assert result.score == score and words in result.message, result


def test_the_rubric_gives_each_named_mistake_the_credit_the_check_gives():
    """Each wrong law above, graded: its feedback quotes exactly one row of the rubric, and that
    row's credit is the score the check gave."""
    from labsupport.instructor.rubric import mistake_credits

    graded = [grade("p1_pd", pd_torque=fn) for fn, _, _ in PD_MISTAKES]
    graded += [grade("p1_ct", ct_joint_torque=fn) for fn, _, _ in CT_MISTAKES]
    graded += [grade("p2_osct", ct_op_torque=os_mistake(mistake)) for mistake, _, _ in OS_MISTAKES]
    for result in graded:
        quoted = [credit for credit, text in mistake_credits(result.name) if text.rstrip(".") in result.message]
        assert quoted == [result.score], result


def test_jdot_wording_says_what_the_problem_asks():
    result = grade("p2_osct", ct_op_torque=os_no_jdot)
    assert "The lab allows dropping" not in result.message
    assert "the formula of this Problem has it" in result.message and "finite-difference" in result.message


def test_ik_ct_mistakes_are_named(master2):
    model = common.arm_model()
    ik = master2["ik_3r"]

    def no_jdot(model, data, *ref):
        return ik_ct_law(model, data, *ref, ik=ik, jdq_of=lambda J_d, q_d, qd_d: np.zeros(3))

    def at_current_state(model, data, x_d, xd_d, xdd_d, Kp, Kd):
        q_d = ik(x_d)
        J, jdq = jacobian_at(model, data.qpos, data.qvel)
        qd_d = np.linalg.solve(J, xd_d)
        qdd_d = np.linalg.solve(J, xdd_d - jdq)
        return mass_matrix(model, data) @ (qdd_d + Kd * (qd_d - data.qvel) + Kp * (q_d - data.qpos)) + bias_forces(data)

    def elbow_down(model, data, *ref):
        return ik_ct_law(model, data, *ref, ik=lambda x, elbow_up=True: ik(x, False))

    def a_turn_away(model, data, *ref):  # the right pose, joint 3 a full turn from the nearest angle
        return ik_ct_law(model, data, *ref, ik=lambda x, elbow_up=True: ik(x, True) + np.array([0, 0, 2 * np.pi]))

    def down_and_a_turn_away(model, data, *ref):
        return ik_ct_law(model, data, *ref, ik=lambda x, elbow_up=True: ik(x, False) - np.array([2 * np.pi, 0, 0]))

    def jdot_at_arm(model, data, *ref):
        return ik_ct_law(
            model, data, *ref, ik=ik, jdq_of=lambda J_d, q_d, qd_d: jacobian_at(model, data.qpos, data.qvel)[1]
        )

    def at_reference(terms):  # M, h or both taken on a scratch MjData at (q_d, q̇_d)
        def law(model, data, x_d, xd_d, xdd_d, Kp, Kd):
            q_d = ik(x_d)
            J_d, _ = jacobian_at(model, q_d)
            qd_d = np.linalg.solve(J_d, xd_d)
            qdd_d = np.linalg.solve(J_d, xdd_d - jacobian_at(model, q_d, qd_d)[1])
            at_ref = mujoco.MjData(model)
            at_ref.qpos[:], at_ref.qvel[:] = q_d, qd_d
            mujoco.mj_forward(model, at_ref)
            M = mass_matrix(model, at_ref if "M" in terms else data)
            h = bias_forces(at_ref if "h" in terms else data)
            return M @ (qdd_d + Kd * (qd_d - data.qvel) + Kp * (q_d - data.qpos)) + h

        return law

    def bias_subtracted(model, data):
        return -bias_forces(data)

    def jdot_with_arm_velocity(model, data, *ref):  # the scratch's qvel set to the arm's
        return ik_ct_law(model, data, *ref, ik=ik, jdq_of=lambda J_d, q_d, qd_d: jacobian_at(model, q_d, data.qvel)[1])

    def jacobian_of_the_arm(model, data, x_d, xd_d, xdd_d, Kp, Kd):  # J from data, J̇q̇ from the scratch
        q_d = ik(x_d)
        J = site_jacobian(model, data, SITE)[:3]
        qd_d = np.linalg.solve(J, xd_d)
        qdd_d = np.linalg.solve(J, xdd_d - jacobian_at(model, q_d, qd_d)[1])
        return mass_matrix(model, data) @ (qdd_d + Kd * (qd_d - data.qvel) + Kp * (q_d - data.qpos)) + bias_forces(data)

    for fn, score, words in (
        (no_jdot, 0.5, "J̇(q_d, q̇_d) q̇_d term"),
        (jdot_at_arm, 0.75, "q̈_d takes J̇q̇ at the arm's state"),
        # these two were bare zeros, 0.14 % and 1.8 % off
        (jdot_with_arm_velocity, 0.75, "J̇q̇ at q_d but with the arm's velocity q̇"),
        (jacobian_of_the_arm, 0.75, "use the Jacobian of the arm's state, J(q)"),
        (at_current_state, 0.75, "at the arm's state"),
        (elbow_down, 0.0, "elbow-down branch"),
        (a_turn_away, 0.25, "elbow-up pose with an angle a full turn (2π) away"),
        (down_and_a_turn_away, 0.0, "elbow-down pose with an angle a full turn (2π) away"),
        # these four were bare zeros, each pointing at the IK and the reference
        (at_reference("Mh"), 0.75, "M and h are taken at the reference (q_d, q̇_d)"),
        # these two got the generic "the torque differs" message
        (at_reference("M"), 0.75, "M is taken at the reference (q_d, q̇_d), from the scratch MjData"),
        (at_reference("h"), 0.75, "h is taken at the reference (q_d, q̇_d), from the scratch MjData"),
        (ik_variant(ik, kd=0.0), 0.5, "the damping term Kd (q̇_d − q̇) inside M(q)(...) is missing"),
        (ik_variant(ik, kd=-1.0), 0.5, "the damping has the wrong sign: it must be +Kd (q̇_d − q̇)"),
        (ik_variant(ik, bias=lambda model, data: bias_subtracted(model, data)), 0.25, "must be added, not subtracted"),
    ):
        result = grade("p2_ikct", ct_ik_joint_torque=fn)
        assert result.score == score and words in result.message, result
    assert model.nv == 3


def test_a_scratch_forwarded_only_once_is_told_to_recompute_its_kinematics(master2):
    """A scratch MjData forwarded once, then given only mj_kinematics at each q_d, keeps the Jacobian
    data (cdof) of its first configuration: the torque is wrong, and the message names the calls."""
    model, ik = common.arm_model(), master2["ik_3r"]
    scratch = mujoco.MjData(model)
    mujoco.mj_forward(model, scratch)

    def stale(model, data, x_d, xd_d, xdd_d, Kp, Kd):
        q_d = ik(x_d, elbow_up=True)
        scratch.qpos[:] = q_d
        mujoco.mj_kinematics(model, scratch)  # mj_comPos missing: J(q_d) mixes two configurations
        J_d = site_jacobian(model, scratch, SITE)[:3]
        qd_d = np.linalg.solve(J_d, xd_d)
        scratch.qvel[:] = qd_d
        mujoco.mj_comVel(model, scratch)
        qdd_d = np.linalg.solve(J_d, xdd_d - site_jdot_qdot(model, scratch, SITE)[:3])
        M, h = mass_matrix(model, data), bias_forces(data)
        return M @ (qdd_d + Kd * (qd_d - data.qvel) + Kp * (q_d - data.qpos)) + h

    result = grade("p2_ikct", ct_ik_joint_torque=stale)
    assert result.score == 0 and "mujoco.mj_comPos ran after its qpos was set" in result.message, result


def gravity_at(model, q):
    """h(q, 0): the bias forces at rest, gravity alone."""
    d = mujoco.MjData(model)
    d.qpos[:] = q
    mujoco.mj_forward(model, d)
    return d.qfrc_bias.copy()


def tip_velocity_of(J, qdot):
    """ẋ = J q̇, the tip's velocity as the law must read it."""
    return J @ qdot


def term_changes(kp=1.0, kd=1.0, ff=1.0, vel=1.0, mass=lambda M: M, bias=lambda model, data: bias_forces(data)):
    """The terms both wrong-law builders below may change: Kp, Kd, the feed-forward and the damping's
    reference velocity scaled by ``kp``, ``kd``, ``ff``, ``vel``; M(q) replaced by ``mass(M)``, h by
    ``bias(model, data)``."""
    return types.SimpleNamespace(kp=kp, kd=kd, ff=ff, vel=vel, mass=mass, bias=bias)


def os_variant(tip_velocity=tip_velocity_of, joint_space_jdot=False, **changes):
    """OS-CT with one term changed (:func:`term_changes`), the tip's velocity read as
    ``tip_velocity(J, qdot)``, or J̇q̇ subtracted after J⁻¹ (``joint_space_jdot``)."""
    t = term_changes(**changes)

    def ct_op_torque(model, data, x_d, xd_d, xdd_d, Kp, Kd):
        J, jdq = site_jacobian(model, data, SITE)[:3], site_jdot_qdot(model, data, SITE)[:3]
        a = (
            t.ff * xdd_d
            + t.kd * Kd * (t.vel * xd_d - tip_velocity(J, data.qvel))
            + t.kp * Kp * (x_d - data.site(SITE).xpos)
        )
        qdd = np.linalg.solve(J, a) - jdq if joint_space_jdot else np.linalg.solve(J, a - jdq)
        return t.mass(mass_matrix(model, data)) @ qdd + t.bias(model, data)

    return ct_op_torque


def reference_velocity(J_d, J, xd_d):
    """q̇_d = J(q_d)⁻¹ ẋ_d, as the law must compute it (``J`` is the arm's Jacobian, for the
    variants that take it instead)."""
    return np.linalg.solve(J_d, xd_d)


def right_acceleration(J_d, xdd_d, jdq_d):
    """q̈_d = J(q_d)⁻¹(ẍ_d − J̇q̇_d)."""
    return np.linalg.solve(J_d, xdd_d - jdq_d)


def ik_variant(ik, velocity=reference_velocity, acceleration=right_acceleration, right_jdot=False, **changes):
    """IK + joint CT with one term changed (:func:`term_changes`); or with q̇_d computed as
    ``velocity(J_d, J, xd_d)`` and q̈_d as ``acceleration(J_d, xdd_d, jdq_d)``, J̇q̇_d taken at that
    q̇_d (or at the right one, ``right_jdot``)."""
    t = term_changes(**changes)

    def ct_ik_joint_torque(model, data, x_d, xd_d, xdd_d, Kp, Kd):
        q_d = ik(x_d, elbow_up=True)
        J_d, _ = jacobian_at(model, q_d)
        qd_d = velocity(J_d, site_jacobian(model, data, SITE)[:3], xd_d)
        jdq_d = jacobian_at(model, q_d, reference_velocity(J_d, None, xd_d) if right_jdot else qd_d)[1]
        qdd_d = acceleration(J_d, t.ff * xdd_d, jdq_d)
        fb = t.kd * Kd * (t.vel * qd_d - data.qvel) + t.kp * Kp * (q_d - data.qpos)
        return t.mass(mass_matrix(model, data)) @ (qdd_d + fb) + t.bias(model, data)

    return ct_ik_joint_torque


@pytest.mark.parametrize(
    "wrong",
    [
        {"kp": 0.97},
        {"kd": 0.97},
        {"ff": 0.97},
        {"mass": lambda M: np.diag(np.diag(M))},
        {"bias": lambda model, data: 0.97 * bias_forces(data)},
    ],
    ids=["Kp", "Kd", "feed-forward", "diagonal_M", "h"],
)
def test_an_error_outside_jdot_is_not_taken_for_an_approximate_jdot(master2, wrong):
    """J is square, so any wrong torque implies some J̇q̇: a slightly wrong gain once read as
    'everything right but J̇q̇, off by 6 %' and kept 97 % of the marks. The first test state has
    the arm (OS-CT) or the reference (IK + joint CT) at rest, where J̇q̇ is zero: every other
    term must match there."""
    for name, fname, law in (
        ("p2_osct", "ct_op_torque", os_variant(**wrong)),
        ("p2_ikct", "ct_ik_joint_torque", ik_variant(master2["ik_3r"], **wrong)),
    ):
        for seed in (PUBLIC_SEED, OTHER_SEED):
            result = grade(name, seed, **{fname: law})
            assert result.score == 0 and "momentarily at rest" in result.message, result
            assert "J̇q̇ ≈" not in result.message


def test_a_joint_velocity_in_the_task_damping_and_a_transposed_solve_are_named():
    """ė = ẋ_d − q̇ (J forgotten) and solve(Jᵀ, ...) got a bare "got … expected …", with a note on
    J̇q̇ that sent the student to the wrong term."""

    def joint_velocity(model, data, x_d, xd_d, xdd_d, Kp, Kd):
        J = site_jacobian(model, data, SITE)[:3]
        a = xdd_d + Kd * (xd_d - data.qvel) + Kp * (x_d - data.site(SITE).xpos) - site_jdot_qdot(model, data, SITE)[:3]
        return mass_matrix(model, data) @ np.linalg.solve(J, a) + bias_forces(data)

    def transposed(model, data, x_d, xd_d, xdd_d, Kp, Kd):
        J = site_jacobian(model, data, SITE)[:3]
        a = xdd_d + Kd * (xd_d - J @ data.qvel) + Kp * (x_d - data.site(SITE).xpos)
        return mass_matrix(model, data) @ np.linalg.solve(J.T, a - site_jdot_qdot(model, data, SITE)[:3]) + bias_forces(
            data
        )

    for seed in (PUBLIC_SEED, OTHER_SEED):
        result = grade("p2_osct", seed, ct_op_torque=joint_velocity)
        assert result.score == 0.25 and "the damping compares ẋ_d with q̇" in result.message, result
        assert "momentarily at rest" not in result.message
        result = grade("p2_osct", seed, ct_op_torque=transposed)
        assert result.score == 0 and "solve with J, not Jᵀ" in result.message, result


def zero_velocity(J_d, J, xd_d):
    return np.zeros(3)


def cartesian_velocity(J_d, J, xd_d):
    return xd_d


def velocity_through_the_arms_jacobian(J_d, J, xd_d):
    return np.linalg.solve(J, xd_d)


@pytest.mark.parametrize(
    ("velocity", "acceleration", "right_jdot", "score", "words"),
    [
        (zero_velocity, right_acceleration, False, 0.5, "q̇_d is zero throughout the law"),
        (zero_velocity, right_acceleration, True, 0.5, "the damping is −Kd q̇, with q̇_d missing"),
        (cartesian_velocity, right_acceleration, False, 0.25, "the damping compares ẋ_d, the tip's velocity, with q̇"),
        (cartesian_velocity, right_acceleration, True, 0.25, "the damping compares ẋ_d, the tip's velocity, with q̇"),
        (cartesian_velocity, lambda J_d, a, jdq: a, False, 0.25, "q̇_d and q̈_d are the Cartesian ẋ_d and ẍ_d"),
        (
            velocity_through_the_arms_jacobian,
            right_acceleration,
            False,
            0.75,
            "q̇_d uses the Jacobian of the arm's state",
        ),
        (
            velocity_through_the_arms_jacobian,
            right_acceleration,
            True,
            0.75,
            "q̇_d uses the Jacobian of the arm's state",
        ),
        (
            reference_velocity,
            lambda J_d, a, jdq: np.linalg.solve(J_d, -jdq),
            False,
            0.25,
            "q̈_d is missing, or zero: here the reference is at rest, so q̈_d = J(q_d)⁻¹ ẍ_d",
        ),
        (
            reference_velocity,
            lambda J_d, a, jdq: np.linalg.solve(J_d, a) - jdq,
            False,
            0.25,
            "J̇(q_d, q̇_d) q̇_d is subtracted after J(q_d)⁻¹, from the joints' acceleration",
        ),
    ],
    ids=[
        "zero",
        "zero_in_the_damping",
        "cartesian",
        "cartesian_in_the_damping",
        "cartesian_acceleration_too",
        "arms_jacobian",
        "arms_jacobian_in_the_damping",
        "acceleration_without_xdd",
        "jdot_in_joint_space",
    ],
)
def test_a_wrong_reference_velocity_in_ik_joint_ct_is_named(master2, velocity, acceleration, right_jdot, score, words):
    """q̇_d left at zero, taken as ẋ_d, or from the arm's J got the generic "the torque differs" (0), where
    the larger mistake of J(q) in both q̇_d and q̈_d kept 0.75; a q̈_d without ẍ_d, zero where the reference
    is at rest, was told that q̈_d is missing. Each with J̇q̇_d at its wrong q̇_d, or at the right one (the
    wrong q̇_d in the damping only)."""
    law = ik_variant(master2["ik_3r"], velocity=velocity, acceleration=acceleration, right_jdot=right_jdot)
    for seed in (PUBLIC_SEED, OTHER_SEED):
        result = grade("p2_ikct", seed, ct_ik_joint_torque=law)
        assert result.score == score and words in result.message, result


def test_a_tracking_run_that_lags_by_centimetres_points_at_the_reference_velocity(master2):
    """A damping without ẋ_d lags the circle by some 5 cm; the hint named only J̇q̇, h and M, whose
    mistakes leave millimetres."""
    result = grade(
        "p2_track", ct_op_torque=os_variant(vel=0.0), **{f: master2[f] for f in ("ik_3r", "ct_ik_joint_torque")}
    )
    assert result.score == 0.5, result
    os_ct = re.search(r"OS-CT: RMS error ([\d.]+) mm.*?; IK\+JS-CT", result.message)
    assert os_ct and float(os_ct[1]) > 1e3 * problem2.LAG_RMS, result.message
    os_ct = os_ct[0]
    assert "a lag of centimetres most often comes from a damping without the reference velocity" in os_ct, os_ct
    assert "J̇q̇, the Coriolis part of h" not in os_ct, os_ct


@pytest.mark.parametrize(
    ("law", "score", "words"),
    [
        (
            os_variant(tip_velocity=lambda J, qdot: 0.0),
            0.5,
            "the damping is Kd ẋ_d, with the tip's own velocity J q̇ missing",
        ),
        (
            os_variant(tip_velocity=lambda J, qdot: J.T @ qdot),
            0.25,
            "the damping takes the tip's velocity as Jᵀ q̇; it is ẋ = J q̇",
        ),
        (os_variant(joint_space_jdot=True), 0.25, "J̇q̇ is subtracted after J⁻¹, from the joints' acceleration"),
    ],
    ids=["no_tip_velocity", "transposed_tip_velocity", "jdot_in_joint_space"],
)
def test_a_task_damping_or_jdot_in_the_wrong_space_is_named(law, score, words):
    """Kd ẋ_d with −J q̇ left out, ẋ read as Jᵀ q̇, and J̇q̇ subtracted from q̈ rather than from ẍ scored 0
    with a bare "got … expected …", where no damping at all kept half and ė = ẋ_d − q̇ a quarter."""
    for seed in (PUBLIC_SEED, OTHER_SEED):
        result = grade("p2_osct", seed, ct_op_torque=law)
        assert result.score == score and words in result.message, result


@pytest.mark.parametrize(
    ("wrong", "score", "words"),
    [
        ({"mass": lambda M: np.eye(3)}, 0.25, "the mass matrix is missing: τ = M(q) J⁻¹(...) + h"),
        ({"mass": np.linalg.inv}, 0.25, "the law multiplies by M(q)⁻¹ where it should multiply by M(q)"),
        ({"kp": -1.0, "kd": -1.0}, 0.0, "the feedback terms (Kp, Kd) have the wrong sign: e = x_d − x"),
        ({"kd": -1.0}, 0.5, "the damping has the wrong sign: it must be +Kd (ẋ_d − J q̇)"),
        ({"kd": 0.0}, 0.5, "the damping term Kd (ẋ_d − J q̇) is missing"),
        ({"vel": 0.0}, 0.5, "the damping term Kd (ẋ_d − J q̇) is missing, or the ẋ_d in it (the arm is at rest"),
    ],
    ids=["no_M", "inverse_M", "feedback_sign", "damping_sign", "no_damping", "no_reference_velocity"],
)
def test_an_operational_space_term_mistake_is_named_with_its_credit(wrong, score, words):
    result = grade("p2_osct", ct_op_torque=os_variant(**wrong))
    assert result.score == score and words in result.message, result


@pytest.mark.parametrize(
    ("wrong", "score", "words"),
    [
        ({"bias": lambda model, data: np.zeros(3)}, 0.25, "the bias term h(q, q̇) = data.qfrc_bias is missing"),
        ({"mass": lambda M: np.eye(3)}, 0.25, "the mass matrix is missing: τ = M(q)(...) + h"),
        ({"mass": np.linalg.inv}, 0.25, "the law multiplies by M(q)⁻¹ where it should multiply by M(q)"),
        ({"ff": 0.0}, 0.25, "the feed-forward acceleration q̈_d is missing"),
        ({"kp": -1.0, "kd": -1.0}, 0.0, "the feedback terms (Kp, Kd) have the wrong sign: e = q_d − q"),
        ({"kp": -1.0}, 0.0, "the spring term has the wrong sign: Kp (q_d − q)"),
        ({"vel": 0.0}, 0.5, "the damping is −Kd q̇, with q̇_d missing: it must be Kd (q̇_d − q̇)"),
    ],
    ids=["no_h", "no_M", "inverse_M", "no_feed_forward", "feedback_sign", "spring_sign", "no_reference_velocity"],
)
def test_an_ik_joint_ct_term_mistake_is_named_with_its_credit(master2, wrong, score, words):
    result = grade("p2_ikct", ct_ik_joint_torque=ik_variant(master2["ik_3r"], **wrong))
    assert result.score == score and words in result.message, result


def test_an_exact_law_is_not_told_its_jdot_is_an_approximation(master2):
    """The note on an approximate J̇q̇ (finite differences, accepted) is for approximations only:
    the master's exact laws pass without it."""
    for name, fname in (("p2_osct", "ct_op_torque"), ("p2_ikct", "ct_ik_joint_torque")):
        result = grade(name, **{fname: master2[fname]})
        assert result.score == 1 and "approximation" not in result.message, result


def test_the_at_rest_note_names_the_laws_own_term_and_follows_only_a_bare_difference(master2):
    """At the state at rest a bare difference is told which J̇q̇ term vanishes there (the arm's in
    OS-CT, the reference's in IK + joint CT); a named mistake, or a bare difference at a moving
    state, gets no such note."""
    for name, fname, law, term, velocity in (
        ("p2_osct", "ct_op_torque", os_variant(kp=0.97), "so J̇(q, q̇) q̇ is zero", "another velocity than q̇;"),
        (
            "p2_ikct",
            "ct_ik_joint_torque",
            ik_variant(master2["ik_3r"], kp=0.97),
            "so J̇(q_d, q̇_d) q̇_d is zero",
            "another velocity than q̇_d;",
        ),
    ):
        result = grade(name, **{fname: law})
        assert result.score == 0 and term in result.message and velocity in result.message, result

    result = grade("p2_osct", ct_op_torque=os_mistake("no_bias"))  # named at the state at rest
    assert result.score == 0.25 and "momentarily at rest" not in result.message, result

    def jdot_tripled(model, data, *ref):  # right at rest, a bare difference once the arm moves
        return os_law(model, data, *ref, jdq=3 * site_jdot_qdot(model, data, SITE)[:3])

    result = grade("p2_osct", ct_op_torque=jdot_tripled)
    assert result.score == 0 and "expected [" in result.message, result
    assert "momentarily at rest" not in result.message, result


def test_a_named_ik_ct_mistake_worth_nothing_is_not_told_to_recheck_the_whole_law(master2):
    """The long "the torque differs from IK + joint CT: check q_d = IK(x_d) ..." advice is for a
    bare difference only; a named mistake that scores 0 (the elbow-down IK) is told just what it is."""
    ik = master2["ik_3r"]

    def elbow_down(model, data, *ref):
        return ik_ct_law(model, data, *ref, ik=lambda x, elbow_up=True: ik(x, False))

    result = grade("p2_ikct", ct_ik_joint_torque=elbow_down)
    assert result.score == 0 and "elbow-down branch" in result.message, result
    assert "the torque differs from IK + joint CT" not in result.message, result


def test_gravity_alone_for_the_bias_is_named(master2):
    def gravity(model, data):
        return gravity_at(model, data.qpos)

    for name, fname, law in (
        ("p2_osct", "ct_op_torque", os_variant(bias=gravity)),
        ("p2_ikct", "ct_ik_joint_torque", ik_variant(master2["ik_3r"], bias=gravity)),
    ):
        result = grade(name, **{fname: law})
        assert result.score == 0.5 and "gravity alone" in result.message and "Coriolis" in result.message, result


def test_ik_ct_jdot_sign_is_named(master2):
    def jdot_added(model, data, *ref):
        return ik_ct_law(
            model, data, *ref, ik=master2["ik_3r"], jdq_of=lambda J_d, q_d, qd_d: -jacobian_at(model, q_d, qd_d)[1]
        )

    result = grade("p2_ikct", ct_ik_joint_torque=jdot_added)
    assert result.score == 0.25 and "must be subtracted" in result.message, result


def test_a_law_that_ignores_the_gains_it_is_given_is_named(master1, master2):
    """A law that used the notebook's gains (globals) in place of its arguments got a bare "got …,
    expected …": right formula, wrong inputs, and nothing said which."""

    def with_gains(law, Kp, Kd):  # the law with its last two arguments, the gains, replaced
        return lambda *args: law(*args[:-2], Kp, Kd)

    cases = (
        ("p1_pd", "pd_torque", problem1.KP_PD, problem1.KD_PD),
        ("p1_ct", "ct_joint_torque", problem1.KP_CT, problem1.KD_CT),
        ("p2_osct", "ct_op_torque", problem2.KP, problem2.KD),
        ("p2_ikct", "ct_ik_joint_torque", problem2.KP, problem2.KD),
    )
    cases = [  # each law with the notebook's own gains in place of those it is handed
        (
            name,
            fname,
            with_gains((master1 if name.startswith("p1") else master2)[fname], Kp, Kd),
            f"Kp = {Kp:g}, Kd = {Kd:g}",
        )
        for name, fname, Kp, Kd in cases
    ]
    for name, fname, law, gains in cases:
        for seed in (PUBLIC_SEED, OTHER_SEED):
            result = grade(name, seed, **{fname: law})
            assert result.score == 0.5 and f"notebook's gains ({gains})" in result.message, result


def test_wrong_numbers_are_printed_so_they_differ():
    a, b = np.array([1.00001, 2.0, 3.0]), np.array([1.00002, 2.0, 3.0])
    text = show_pair(a, b)
    got, expected = text.split(", expected ")
    assert got.removeprefix("got ") != expected.split(" (")[0]
    assert "%" in text
    assert show_beside(1.0004, 1.0) == "1.0004" and show_beside(1.00000004, 1.0) != "1"
    # four significant digits at least, one more at a time, and as many as a double needs
    assert show_beside(1.23456789, 2.0) == "1.235" and show_beside(1.00041, 1.0) == "1.0004"
    assert show_beside(1 + 2**-52, 1.0) == "1.0000000000000002"
    assert show_pair([1.00001], [1.00002]).startswith("got [1.00001], expected [1.00002] (difference 1e-05, ")
    assert show_pair([1 + 2**-52], [1.0]).startswith("got [1.0000000000000002], expected [1.0000000000000000]")
    assert show_pair([1, 2, 2], [1, 2, 3]) == (
        "got [1.0000 2.0000 2.0000], expected [1.0000 2.0000 3.0000] (difference 1, 26.7 % of the expected value)"
    )
    assert show_pair([0.5, 0.0], [0.0, 0.0]).endswith("(difference 0.5)")  # no share of a zero
    assert show_pair([0.1], [0.2]).endswith("(difference 0.1, 50 % of the expected value)")  # a small one has one
    generic = grade("p1_pd", pd_torque=lambda m, d, q_d, Kp, Kd: 1.0001 * (Kp * (q_d - d.qpos) - Kd * d.qvel))
    assert generic.score == 0 and "got" in generic.message
    shown = generic.message.split("got ")[1].split(" (difference")[0]
    assert shown.split(", expected ")[0] != shown.split(", expected ")[1]


def test_a_score_is_kept_within_its_check_and_a_refusal_says_why():
    """A score handed to ``failed`` stays in [0, 1]; a function that could not be used is told
    apart: not written yet, a forbidden call (its reason kept, also from the sandbox's "raised
    RuntimeError: ..." text), or any other problem, in the student's own words."""
    assert failed("x", "m", 1.5).score == 1.0 and failed("x", "m", 1.5).status == PARTIAL
    assert failed("x", "m", -0.5).score == 0.0 and failed("x", "m", -0.5).status == FAIL
    reason = rules.forbidden_message("labsupport.controllers.joint_space.ct_joint_torque")
    assert forbidden_reason(ForbiddenCall(reason)) == reason
    assert forbidden_reason(StudentError(f"ct_joint_torque raised RuntimeError: {reason}")) == reason
    assert forbidden_reason(StudentError(f"{reason} (then raised RuntimeError: out of memory)")).startswith(reason)
    assert forbidden_reason(StudentError("pd_torque raised RuntimeError: singular matrix")) is None
    assert refused("p1_ct", "CT", NotImplementedYet("ct is None")).status == NOT_IMPLEMENTED
    forbidden = refused("p1_ct", "CT", StudentError(f"ct_joint_torque raised RuntimeError: {reason}"))
    assert forbidden.score == 0 and forbidden.message == f"CT: {reason}"
    other = refused("p1_ct", "CT", StudentError("ct raised ValueError: shapes"))
    assert other.status == FAIL and other.message == "CT: ct raised ValueError: shapes"


def test_an_error_gets_the_hint_of_its_own_cause_and_the_students_line():
    """Each hint of ``raised_text`` needs both of its signs: a singular LinAlgError (not any
    LinAlgError, nor any error that says singular), a shape error about a six (not any shape
    error). ``where_raised`` names the student's line, not NumPy's, where NumPy raised."""
    singular = raised_text("f", "LinAlgError: Singular matrix")
    assert singular.endswith(feedback.SINGULAR_HINT)
    for error in ("LinAlgError: Array must not contain infs or NaNs", "ValueError: the Jacobian is singular here"):
        assert raised_text("f", error) == f"f raised {error}", error
    rows = "ValueError: operands could not be broadcast together with shapes (6,) (3,)"
    assert raised_text("f", rows).endswith(feedback.JACOBIAN_ROWS_HINT)
    for error in ("ValueError: shapes (3,) and (2,) not aligned", "ValueError: expected 6 numbers"):
        assert raised_text("f", error) == f"f raised {error}", error

    def law(model, data):
        return np.linalg.solve(np.zeros((2, 2)), np.ones(2))

    with pytest.raises(np.linalg.LinAlgError) as caught:
        law(None, None)
    assert (
        where_raised(caught.value)
        == f" (line {law.__code__.co_firstlineno + 1} of law: return np.linalg.solve(np.zeros((2, 2)), np.ones(2)))"
    )


# --- unusual but correct: full marks -------------------------------------------------------------------


def test_sound_approximations_get_full_marks(master2):
    cases = {
        "p2_osct": {"ct_op_torque": [os_fd_time(), os_fd_configuration, lambda *a: os_law(*a, inv=True)]},
        "p2_ikct": {
            "ct_ik_joint_torque": [
                ik_ct_fd_time(),
                ik_ct_law,  # Newton IK
                lambda m, d, *r: ik_ct_law(m, d, *r, ik=master2["ik_3r"]),
            ]
        },
    }
    for name, by_function in cases.items():
        for fname, variants in by_function.items():
            for fn in variants:
                for seed in (PUBLIC_SEED, OTHER_SEED):
                    result = grade(name, seed, **{fname: fn})
                    assert result.status == PASS and result.score == 1, result


def scribbles_on_its_arguments(fn):
    """``fn``, then every array it was given overwritten: the effect on the caller of a right law
    that works in place on its inputs (``q_d -= data.qpos``, ``x -= shoulder``)."""

    def scribbling(*args, **kwargs):
        value = fn(*args, **kwargs)
        for a in (*args, *kwargs.values()):
            if isinstance(a, np.ndarray) and a.flags.writeable:
                a[...] = 7.0
        return value

    return scribbling


def test_an_ik_solved_to_ten_micrometres_passes_ik_ct_whatever_the_seed(master2):
    """Problem 1 accepts an IK that stops at 1e-5 m, and Problem 2 asks for that IK; p2_ikct
    compared the torque at its still-reference state within 0.1 % per joint, which such an IK
    missed on some seeds (7 and 26 here): the batch's seed decided the grade of a right law."""
    model, exact = common.arm_model(), master2["ik_3r"]

    def ik_to_ten_micrometres(x, elbow_up=True):
        q = exact(x, elbow_up)
        J, _ = jacobian_at(model, q)
        return q + np.linalg.solve(J, 0.95e-5 * np.array([0.6, -0.48, 0.64]))  # the tip 9.5 µm off

    law = partial(ik_ct_law, ik=ik_to_ten_micrometres)
    for seed in (PUBLIC_SEED, OTHER_SEED, 7, 26):
        result = grade("p2_ikct", seed, ct_ik_joint_torque=law)
        assert result.status == PASS and result.score == 1, (seed, result)
    assert 0.9e-5 < np.linalg.norm(tip_at(model, ik_to_ten_micrometres([1.0, 0.2, 1.4])) - [1.0, 0.2, 1.4]) < 1e-5
    coarse = partial(ik_ct_law, ik=lambda x, elbow_up=True: ik_to_ten_micrometres(x, elbow_up) * (1 + 1e-3))
    assert grade("p2_ikct", 7, ct_ik_joint_torque=coarse).score < 1  # a q_d a milliradian off is no IK's rounding


def test_right_laws_that_change_their_arguments_in_place_get_full_marks(master1, master2):
    """A right pd_torque that did ``q_d -= data.qpos`` was marked wrong ("got" the right torque,
    "expected" one from the moved q_d), and a right IK that shifted its x moved the check's own
    target: the checks handed the student their own arrays. The batch grader sends copies."""
    problems = ((master1, ("p1_ik", "p1_pd", "p1_ct", "p1_reach")), (master2, ("p2_osct", "p2_ikct", "p2_track")))
    for master, names in problems:
        functions = {
            name: scribbles_on_its_arguments(master[name])
            for name in ("ik_3r", "pd_torque", "ct_joint_torque", "ct_op_torque", "ct_ik_joint_torque")
            if name in master
        }
        for name in names:
            result = grade(name, **functions, q0_traj=master.get("q0_traj"))
            assert result.status == PASS and result.score == 1, result


@pytest.mark.filterwarnings("ignore::PendingDeprecationWarning")  # NumPy's word on np.matrix, which students meet
def test_right_torques_as_a_row_or_a_column_get_full_marks_and_joint_vectors_are_told_to_be_flat(master1):
    """np.matrix products and x[:, None] keep two dimensions; the numbers are right, and
    :func:`labsupport.sim.simulate` takes such a torque too. A joint vector is another matter:
    the notebook's cells set it into data.qpos, which refuses a (3, 1) with a traceback, so the
    check says so first. Three numbers too few or too many are refused, with the shape asked for."""
    ik, pd, ct = master1["ik_3r"], master1["pd_torque"], master1["ct_joint_torque"]
    column = grade("p1_ik", ik_3r=lambda x, elbow_up=True: ik(x, elbow_up)[:, None])
    assert column.score == 0 and "has shape (3, 1), expected (3,): 3 numbers; return it flat" in column.message
    cases = {
        "p1_pd": {"pd_torque": lambda *args: pd(*args)[:, None]},
        "p1_ct": {"ct_joint_torque": lambda *args: np.matrix(ct(*args))},
        "p1_reach": {"ct_joint_torque": lambda *args: ct(*args)[None, :]},
    }
    for name, functions in cases.items():
        result = grade(name, OTHER_SEED, **functions)
        assert result.status == PASS and result.score == 1, result
    short = grade("p1_pd", pd_torque=lambda *args: pd(*args)[:2])
    assert short.score == 0 and "the torque from pd_torque has shape (2,), expected (3,): 3 numbers" in short.message


def test_mj_full_m_called_the_other_mujocos_way_is_told_what_changed():
    """The lab's text builds M with mj_fullM(model, M, data.qM), which MuJoCo 4 no longer runs
    (and MuJoCo 3 refuses MuJoCo 4's form): the student is told why, and what to call instead,
    by the check and by the loop alike. The law is written the way this MuJoCo does not take."""
    from labsupport.dynamics import FULLM_TAKES_DATA
    from labsupport.plants import load_model
    from labsupport.sim import simulate

    def ct_joint_torque(model, data, q_d, Kp, Kd):
        M = np.zeros((model.nv, model.nv))
        if FULLM_TAKES_DATA:
            mujoco.mj_fullM(model, M, data.qM)  # MuJoCo 3, as in the lab's text
        else:
            mujoco.mj_fullM(model, data, M)  # MuJoCo 4
        return M @ (Kp * (q_d - data.qpos) - Kd * data.qvel) + data.qfrc_bias

    told = "mj_fullM changed with MuJoCo 4: it was mj_fullM(model, M, data.qM), it is mj_fullM(model, data, M)"
    result = grade("p1_ct", ct_joint_torque=ct_joint_torque)
    assert result.score == 0 and told in result.message and "mass_matrix(model, data)" in result.message, result
    model, data = load_model("spatial_3r")
    with pytest.raises((TypeError, ValueError), match=re.escape(told)):
        simulate(model, data, lambda m, d: ct_joint_torque(m, d, np.zeros(3), 100.0, 20.0), 0.01)


def test_numerical_ik_gets_full_marks():
    result = grade("p1_ik", OTHER_SEED, ik_3r=newton_ik)
    assert result.status == PASS and result.score == 1, result


def elbow_above_line(model, q) -> bool:
    """Whether the elbow lies above the shoulder-to-tip line (world up, made perpendicular to it)."""
    d = mujoco.MjData(model)
    d.qpos[:] = q
    mujoco.mj_kinematics(model, d)
    shoulder, elbow, tip = d.body("link2").xpos, d.body("link3").xpos, d.site(SITE).xpos
    line = (tip - shoulder) / np.linalg.norm(tip - shoulder)
    return bool((elbow - shoulder) @ (np.array([0.0, 0.0, 1.0]) - line[2] * line) > 0)


def leaning_back(ik):
    """``ik`` turned into an IK that answers with the over-the-top pose: pan half a turn round,
    the planar pose mirrored across the vertical (q2 -> -q2, theta -> -theta), angles left
    unwrapped as a numerical IK may leave them."""

    def over_the_top_ik(x, elbow_up=True):
        q = ik(x, elbow_up)
        return np.array([q[0] + np.pi, -q[1], -q[2] - np.pi])

    return over_the_top_ik


def test_the_over_the_top_ik_is_named_in_both_problems(master1):
    """An IK that reaches every target leaning back over the shoulder gets zero in Problem 1 with
    the reason (it is not the asked q1 = atan2(y, x)), and Problem 2's checks of the start and of
    the law name it instead of a bare torque mismatch."""
    model, rng = common.arm_model(), np.random.default_rng(7)
    for up in (True, False) * 10:  # the pose is a right answer to the kinematics, on the side asked
        x = tip_at(model, common.draw_configuration(rng, up))
        q = leaning_back(newton_ik)(x, up)
        assert np.linalg.norm(tip_at(model, q) - x) < 1e-9 and elbow_above_line(model, q) == up
    p1 = grade("p1_ik", OTHER_SEED, ik_3r=leaning_back(newton_ik))
    ik = leaning_back(master1["ik_3r"])
    assert p1.score == 0 and "half a turn from the target's azimuth atan2(y, x)" in p1.message, p1

    def ct_ik_joint_torque(model, data, x_d, xd_d, xdd_d, Kp, Kd):
        return ik_ct_law(model, data, x_d, xd_d, xdd_d, Kp, Kd, ik=ik)

    p2 = grade("p2_ikct", OTHER_SEED, ct_ik_joint_torque=ct_ik_joint_torque)
    assert p2.score == 0 and "the IK returns the over-the-top solution" in p2.message, p2
    assert "other side" not in p2.message
    # leaning back with the elbow on the other side too (a warm-started Newton IK can land there):
    # it got the bare "the torque differs" advice

    def ct_ik_other_elbow(model, data, x_d, xd_d, xdd_d, Kp, Kd):
        return ik_ct_law(model, data, x_d, xd_d, xdd_d, Kp, Kd, ik=lambda x, elbow_up=True: ik(x, not elbow_up))

    p2 = grade("p2_ikct", OTHER_SEED, ct_ik_joint_torque=ct_ik_other_elbow)
    assert p2.score == 0 and "over-the-top solution" in p2.message and "with the elbow on the other side" in p2.message
    start = grade("p2_start", q0_traj=ik(problem2.reference(0.0).pos, elbow_up=True))
    assert start.score == 0.5 and "the over-the-top pose" in start.message, start


def test_an_ik_that_changes_branch_along_the_circle_is_named(master1, master2):
    """Front solution for the first part of the circle, then the over-the-top one: the law's check
    at its test states can pass, and the tracking run says when and why the arm left its branch."""
    center, radius, normal, q0, qdot0 = problem2.tracking_circle(OTHER_SEED)
    start = tip_at(common.arm_model(), q0)
    front = master1["ik_3r"]
    back = leaning_back(front)

    def switching_ik(x, elbow_up=True):
        return back(x, elbow_up) if np.linalg.norm(np.asarray(x) - start) > radius else front(x, elbow_up)

    def ct_ik_joint_torque(model, data, x_d, xd_d, xdd_d, Kp, Kd):
        return ik_ct_law(model, data, x_d, xd_d, xdd_d, Kp, Kd, ik=switching_ik)

    track = grade("p2_track", OTHER_SEED, ct_op_torque=master2["ct_op_torque"], ct_ik_joint_torque=ct_ik_joint_torque)
    assert track.score == 0.5, track
    assert "the arm faced away from its tip, on the over-the-top solution" in track.message
    t_switch = float(track.message.split("at t = ")[1].split(" s")[0])
    # the IK switches a sixth of the way round (chord = radius); the arm follows within a few tenths of a second
    assert problem2.TRACK_DURATION / 6 < t_switch < problem2.TRACK_DURATION / 6 + 0.5, track.message


def test_a_run_that_leaves_its_branch_is_told_which_way():
    """The poses a run logs tell the branch it left for: elbow down, over the top, or a full turn
    of the pan (the reference on the arm's own tip)."""
    model, rng = common.arm_model(), np.random.default_rng(11)
    front = [common.draw_configuration(rng, elbow_up=True) for _ in range(3)]
    full_turn = front[2] + [2 * np.pi * np.sign(front[2][0]), 0.0, 0.0]
    for other, words in (
        (common.mirror_elbow(front[2]), "at t = 0.20 s the elbow was below the shoulder-to-tip line"),
        (common.over_the_top(front[2]), "at t = 0.20 s the arm faced away from its tip, on the over-the-top"),
        (full_turn, "by t = 0.20 s the pan had swung round"),
    ):
        log = posed_log(model, [*front[:2], other], [0.0, 0.1, 0.2])
        q, ee = log.q, log.ee
        assert words in problem2._left_the_branch(model, log, every=1)
        before = types.SimpleNamespace(q=q[:2], ee=ee[:2], ref=ee[:2], t=log.t[:2])
        assert problem2._left_the_branch(model, before, 1) is None


def test_an_arm_that_falls_off_a_right_reference_is_not_blamed_on_the_ik(master2):
    """A joint CT that gave no torque let the arm fall onto the elbow-down branch, and the tracking
    run asked "does the IK switch to it there?" of an IK that never did. The student's ik_3r is
    now asked at that point; without one, the question stays."""
    limp = {"ct_op_torque": master2["ct_op_torque"], "ct_ik_joint_torque": lambda model, data, *ref: np.zeros(3)}
    track = grade("p2_track", PUBLIC_SEED, **limp, ik_3r=master2["ik_3r"])
    assert track.score == 0.5 and "the elbow was below the shoulder-to-tip line" in track.message, track
    assert "while your ik_3r gives the elbow-up solution facing the target there" in track.message
    assert "does the IK switch" not in track.message
    without_ik = grade("p2_track", PUBLIC_SEED, **limp)
    assert "does the IK switch to it there? Take q1 = atan2(y, x)" in without_ik.message, without_ik


def test_an_ik_a_full_turn_off_is_named_by_the_tracking_run(master2):
    """An IK that wraps q1 into [0, 2π) is right as kinematics, but where the circle's azimuth is
    negative the joint CT swings the pan a full turn: the tracking run says so, not "over the top"."""
    seed = 2
    assert problem2.tracking_circle(seed)[3][0] < -np.pi / 2  # the arm starts at a negative azimuth
    ik = master2["ik_3r"]

    def ik_0_to_2pi(x, elbow_up=True):
        q = ik(x, elbow_up)
        return np.array([q[0] % (2 * np.pi), q[1], q[2]])

    def ct_ik_joint_torque(model, data, x_d, xd_d, xdd_d, Kp, Kd):
        return ik_ct_law(model, data, x_d, xd_d, xdd_d, Kp, Kd, ik=ik_0_to_2pi)

    track = grade("p2_track", seed, ct_op_torque=master2["ct_op_torque"], ct_ik_joint_torque=ct_ik_joint_torque)
    assert track.score == 0.5, track
    assert "the pan had swung round" in track.message and "a full turn (2π) from the arm's" in track.message
    assert "over-the-top" not in track.message, track.message


def test_problem_1_notes_ik_angles_outside_minus_pi_to_pi_without_taking_points(master1):
    """Problem 1 gave full marks, without a word, to an IK returning q2 + 2π; Problem 2's checks
    then cut points for it. Problem 1 keeps the marks and now says why Problem 2 will not."""
    ik = master1["ik_3r"]
    result = grade("p1_ik", ik_3r=lambda x, elbow_up=True: ik(x, elbow_up) + np.array([0.0, 2 * np.pi, 0.0]))
    assert (
        result.score == 1
        and "Note (no points taken): 25 elbow-up solutions have an angle outside (−π, π]" in result.message
    )
    assert "Note (no points taken)" not in grade("p1_ik", ik_3r=ik).message


def test_an_ik_whose_elbow_angle_is_a_full_turn_off_is_named_by_the_tracking_run(master2):
    """An IK that returns q2 + 2π reaches every point, and the notebook's own run, which starts on
    that IK's pose, tracks well; the grader's run starts on the wrapped pose, so the joint CT
    turns the shoulder a full turn. The run said the arm "faced away, on the over-the-top
    solution"; it now names the angle outside (−π, π]."""
    ik = master2["ik_3r"]

    def ik_a_turn_on(x, elbow_up=True):
        return ik(x, elbow_up) + np.array([0.0, 2 * np.pi, 0.0])

    def ct_ik_joint_torque(model, data, x_d, xd_d, xdd_d, Kp, Kd):
        return ik_ct_law(model, data, x_d, xd_d, xdd_d, Kp, Kd, ik=ik_a_turn_on)

    track = grade(
        "p2_track", ct_op_torque=master2["ct_op_torque"], ct_ik_joint_torque=ct_ik_joint_torque, ik_3r=ik_a_turn_on
    )
    assert track.score == 0.5, track
    assert "an angle outside (−π, π]" in track.message and "Wrap the IK's angles" in track.message, track.message
    assert "over-the-top" not in track.message, track.message


def test_a_torque_that_came_out_as_a_matrix_is_told_to_use_the_matrix_product():
    """M * v in place of M @ v, or gains given as matrices, make the torque a 3 × 3 matrix: the
    check said only its shape."""

    def elementwise(model, data, q_d, Kp, Kd):
        return mass_matrix(model, data) * (Kp * (q_d - data.qpos) - Kd * data.qvel) + bias_forces(data)

    result = grade("p1_ct", ct_joint_torque=elementwise)
    assert result.score == 0 and "has shape (3, 3), expected (3,)" in result.message, result
    assert "M * v" in result.message and "use @ for a matrix times a vector" in result.message, result


def test_a_def_line_in_another_order_than_the_stubs_is_named(master1, master2):
    """def pd_torque(model, data, Kp, Kd, q_d): the checks pass (q_d, Kp, Kd) in the stub's order,
    so each lands on another parameter; the check printed only the two torques it compared."""
    pd, ct, op = master1["pd_torque"], master1["ct_joint_torque"], master2["ct_op_torque"]

    def pd_torque(model, data, Kp, Kd, q_d):
        return pd(model, data, q_d, Kp, Kd)

    def ct_joint_torque(model, data, Kd, q_d, Kp):
        return ct(model, data, q_d, Kp, Kd)

    def ct_op_torque(model, data, Kp, Kd, x_d, xd_d, xdd_d):
        return op(model, data, x_d, xd_d, xdd_d, Kp, Kd)

    for name, law, said in (
        ("p1_pd", pd_torque, "in the order (model, data, Kp, Kd, q_d), where the stub has (model, data, q_d, Kp"),
        ("p1_ct", ct_joint_torque, "in the order (model, data, Kd, q_d, Kp), where the stub has (model, data, q_d"),
        # the first state where it differs is at rest, where two orders give the same torque: neither is named
        ("p2_osct", ct_op_torque, "in another order than the stub's (model, data, x_d, xd_d, xdd_d, Kp, Kd)"),
    ):
        result = grade(name, **{law.__name__: law})
        assert result.score == 0.5 and f"your def line takes the arguments {said}" in result.message, result


def test_swapped_gains_are_named_in_both_laws_of_problem_2(master2):
    """Problem 1 named Kp and Kd exchanged; Problem 2 printed only the two torques, with a hint
    about J̇q̇ at a test state at rest."""
    for name, fname, words in (
        ("p2_osct", "ct_op_torque", "position error x_d − x, Kd the velocity term ẋ_d − J q̇"),
        ("p2_ikct", "ct_ik_joint_torque", "position error q_d − q, Kd the velocity term q̇_d − q̇"),
    ):
        law = master2[fname]
        swapped = lambda model, data, x_d, xd_d, xdd_d, Kp, Kd, law=law: law(model, data, x_d, xd_d, xdd_d, Kd, Kp)  # noqa: E731
        result = grade(name, **{fname: swapped})
        assert result.score == 0.5 and "Kp and Kd are swapped" in result.message and words in result.message, result


@pytest.mark.parametrize("seed", [PUBLIC_SEED, OTHER_SEED])
def test_one_law_handed_in_for_both_earns_no_tracking_credit_for_the_copy(master2, seed):
    """ct_ik_joint_torque answered by calling ct_op_torque (or the other way round) tracks the
    circle, but its run is not a run of its law: the copy earns nothing on p2_track (it earned
    half of it, more than leaving the TODO blank), the law it copies keeps its half."""
    op, ik_ct = master2["ct_op_torque"], master2["ct_ik_joint_torque"]

    def op_for_ik(model, data, *ref):
        return op(model, data, *ref)

    def ik_for_op(model, data, *ref):
        return ik_ct(model, data, *ref)

    for functions, copy, kept in (
        ({"ct_op_torque": op, "ct_ik_joint_torque": op_for_ik}, "IK+JS-CT", "OS-CT"),
        ({"ct_op_torque": ik_for_op, "ct_ik_joint_torque": ik_ct}, "OS-CT", "IK+JS-CT"),
    ):
        track = grade("p2_track", seed, **functions)
        assert track.score == 0.5, track
        assert f"{copy}: {'ct_ik_joint_torque' if copy == 'IK+JS-CT' else 'ct_op_torque'} returns" in track.message
        assert f"{kept}: RMS error" in track.message, track.message
    assert grade("p2_track", seed, ct_op_torque=op, ct_ik_joint_torque=ik_ct).score == 1


@pytest.mark.parametrize("seed", [PUBLIC_SEED, OTHER_SEED])
def test_a_run_counts_only_for_a_law_its_formula_check_recognises(master2, seed):
    """A function that tracks the circle but is not its law at the formula check's test states
    earned that law's half of p2_track: OS-CT with other gains handed in as IK + joint CT, or a law
    that answers the checks' states (never those of a run from t = 0) with anything and the run
    with OS-CT. Its run still tracks, and the note says why it does not count."""
    op, ik_ct = master2["ct_op_torque"], master2["ct_ik_joint_torque"]

    def stiffer_op(model, data, x_d, xd_d, xdd_d, Kp, Kd):
        return op(model, data, x_d, xd_d, xdd_d, 1.5 * Kp, 1.5 * Kd)

    last = {"t": None, "run": False}

    def two_faced(model, data, *ref):  # a run starts at t = 0 and steps by dt; the checks' states do not
        step = last["t"] is not None and abs(data.time - last["t"] - model.opt.timestep) < 1e-9
        last["run"], last["t"] = data.time == 0.0 or (last["run"] and step), data.time
        return op(model, data, *ref) if last["run"] else np.zeros(3)

    for law in (stiffer_op, two_faced):
        track = grade("p2_track", seed, ct_op_torque=op, ct_ik_joint_torque=law)
        assert track.score == 0.5, track
        assert "IK+JS-CT: RMS error" in track.message and "mm, but ct_ik_joint_torque scores zero on its own" in (
            track.message
        ), track.message
        assert "so this run does not count as IK + joint CT's" in track.message, track.message
    assert grade("p2_track", seed, ct_op_torque=op, ct_ik_joint_torque=ik_ct).score == 1


def test_a_previous_q_kept_as_a_view_of_data_is_graded_as_it_runs():
    """A finite-difference J̇q̇ whose "previous" q is ``data.qpos`` itself, not a copy: in a run
    (one MjData throughout) that q is always the current one, so J̇q̇ is zero. The in-notebook
    check handed each call a fresh MjData, the old values lived on behind the view, and the
    check gave the law full marks where the batch grader (one MjData) took the J̇q̇ points."""
    last = {}

    def ct_op_torque(model, data, x_d, xd_d, xdd_d, Kp, Kd):
        jdq = np.zeros(3)
        if "q" in last and 0 < data.time - last["t"] <= 0.01:
            J_then, J_now = jacobian_at(model, last["q"])[0], jacobian_at(model, data.qpos)[0]
            jdq = (J_now - J_then) / (data.time - last["t"]) @ data.qvel
        last["q"], last["t"] = data.qpos, data.time  # the slip: a view, not data.qpos.copy()
        return os_law(model, data, x_d, xd_d, xdd_d, Kp, Kd, jdq)

    with_view = grade("p2_osct", OTHER_SEED, ct_op_torque=ct_op_torque)
    dropped = grade("p2_osct", OTHER_SEED, ct_op_torque=os_no_jdot)
    assert with_view.score == dropped.score < 1, (with_view, dropped)
    last.clear()
    with_copy = grade("p2_osct", OTHER_SEED, ct_op_torque=os_fd_time())
    assert with_copy.score == 1, with_copy


def test_finite_difference_jdot_tracks_and_never_scores_below_dropping_it(master2):
    fd = {"ct_op_torque": os_fd_time(), "ct_ik_joint_torque": ik_ct_fd_time(master2["ik_3r"])}
    dropped = {"ct_op_torque": os_no_jdot, "ct_ik_joint_torque": master2["ct_ik_joint_torque"]}
    fd_track = grade("p2_track", OTHER_SEED, **fd)
    assert fd_track.score == 1, fd_track
    fd_total = grade("p2_osct", OTHER_SEED, **fd).score * 3 + fd_track.score * 3
    dropped_total = (
        grade("p2_osct", OTHER_SEED, **dropped).score * 3 + grade("p2_track", OTHER_SEED, **dropped).score * 3
    )
    assert fd_total == 6 and dropped_total < fd_total


def test_the_tracking_limit_parts_right_laws_from_known_mistakes_on_every_circle():
    """A law's tracking score must not depend on the circle the batch's secret seed draws: the
    right law, and one whose J̇q̇ is 5 % off (graded as right), stay below the limit on every
    circle; the law without J̇q̇ stays above it on every one (its error is 0.4-2.8 mm, and a limit
    of 1 mm once passed it on some circles and failed it on others)."""
    from labsupport.metrics import rms_norm

    def os_jdot_off(model, data, x_d, xd_d, xdd_d, Kp, Kd):
        return os_law(model, data, x_d, xd_d, xdd_d, Kp, Kd, 0.95 * site_jdot_qdot(model, data, SITE)[:3])

    for seed in range(3):
        center, radius, normal, q0, qdot0 = problem2.tracking_circle(seed)
        ref = partial(circle_3d, center=center, radius=radius, normal=normal, frequency=problem2.FREQUENCY)

        def args(t, ref=ref):
            r = ref(t)
            return r.pos, r.vel, r.acc, problem2.KP, problem2.KD

        for law, right in ((os_law, True), (os_jdot_off, True), (os_no_jdot, False)):
            probe = DirectProbe({"ct_op_torque": law})
            log = common.run_student(probe, "ct_op_torque", args, problem2.TRACK_DURATION, q0, qdot0, reference=ref)
            err = rms_norm(log.err)
            assert (err < problem2.RMS_TOL) == right, (seed, law.__name__, err)
            assert err < 0.6 * problem2.RMS_TOL if right else err > 1.5 * problem2.RMS_TOL, (seed, law.__name__, err)


def test_a_poor_jdot_approximation_keeps_half_and_two_mistakes_no_more_than_one():
    """A poor J̇q̇ keeps what leaving it out keeps. Its credit used to grow as the error shrank
    (1 − ε/2), which one state cannot tell from an error in another velocity term: the Coriolis
    part of h missing as well as J̇q̇ scored 63 %, more than either mistake alone (50 %)."""

    def rough(model, data, x_d, xd_d, xdd_d, Kp, Kd):
        return os_law(model, data, x_d, xd_d, xdd_d, Kp, Kd, 0.7 * site_jdot_qdot(model, data, SITE)[:3])

    def gravity_only_and_no_jdot(model, data, x_d, xd_d, xdd_d, Kp, Kd):
        moving = os_law(model, data, x_d, xd_d, xdd_d, Kp, Kd, np.zeros(3))
        coriolis = data.qfrc_bias - common.terms(model, data.qpos, np.zeros(3)).h  # h less gravity
        return moving - coriolis

    result = grade("p2_osct", ct_op_torque=rough)
    assert result.score == 0.5 and "off by 30 %" in result.message, result
    assert "Coriolis part of h" in result.message
    for seed in range(4):
        both = grade("p2_osct", seed=seed, ct_op_torque=gravity_only_and_no_jdot)
        assert both.score <= 0.5, (seed, both)


# --- forbidden calls into labsupport: zero, with the reason ---------------------------------------


def forbidden_ct(model, data, q_d, Kp, Kd):
    return joint_space_alias.ct_joint_torque(model, data, q_d, np.zeros(3), np.zeros(3), Kp, Kd)


def test_calling_labsupports_controllers_scores_zero():
    from labsupport.controllers.joint_space import ct_joint_torque as renamed

    def via_from_import(model, data, q_d, Kp, Kd):
        return renamed(model, data, q_d, np.zeros(3), np.zeros(3), Kp, Kd)

    for fn in (forbidden_ct, via_from_import):
        for name in ("p1_ct", "p1_reach"):
            result = grade(name, ct_joint_torque=fn)
            assert result.score == 0 and result.status == FAIL, result
            assert rules.MARKER in result.message
            assert "labsupport.controllers.joint_space.ct_joint_torque" in result.message


@pytest.mark.parametrize("notebook", ["problem1_reaching.ipynb", "problem2_tracking.ipynb"])
def test_each_problems_box_names_what_the_rules_allow_and_forbid(notebook):
    """The box listed two of the five forbidden modules: a student who reached for the checks'
    own helpers (wrap_angle, tip) scored zero without having been told."""
    box = nbformat.read(ROOT / "notebooks" / notebook, as_version=4).cells[0].source
    allowed, forbidden = box.split("Not allowed inside a TODO:")
    assert "What you may use from labsupport" in allowed
    for module in rules.FORBIDDEN:
        assert f"`{module}`" in forbidden, module
    for name in rules.ALLOWED:
        last = name.rsplit(".", 1)[-1]
        assert f"`{name}" in allowed or re.search(rf"`{last}[`(]", allowed), name


def test_an_error_in_the_students_code_names_its_line_and_a_six_row_jacobian_is_explained():
    """A law that raised said only NumPy's words ("operands could not be broadcast together with
    shapes (3,) (6,)"): no line, and no word that site_jacobian has six rows."""

    def all_six_rows(model, data, x_d, xd_d, xdd_d, Kp, Kd):
        J = site_jacobian(model, data, SITE)
        a = xdd_d + Kd * (xd_d - J @ data.qvel) + Kp * (x_d - data.site(SITE).xpos)
        return mass_matrix(model, data) @ np.linalg.solve(J, a) + bias_forces(data)

    result = grade("p2_osct", ct_op_torque=all_six_rows)
    assert result.score == 0
    assert "shapes (3,) (6,) (site_jacobian" in result.message and "rows 0–2, [:3]" in result.message
    assert "of all_six_rows: a = xdd_d + Kd * (xd_d - J @ data.qvel)" in result.message


def test_a_law_imported_inside_the_call_is_named_not_its_module(monkeypatch):
    """Importing the module inside the call ran its top-level code first, and the reason named
    "labsupport.controllers.joint_space.<module>" instead of the law that was called."""
    monkeypatch.delitem(sys.modules, "labsupport.controllers.joint_space")

    def imports_then_calls(model, data, q_d, Kp, Kd):
        from labsupport.controllers.joint_space import ct_joint_torque

        return ct_joint_torque(model, data, q_d, np.zeros(3), np.zeros(3), Kp, Kd)

    result = grade("p1_ct", ct_joint_torque=imports_then_calls)
    assert result.score == 0 and rules.MARKER in result.message
    assert "labsupport.controllers.joint_space.ct_joint_torque" in result.message
    assert "<module>" not in result.message


def test_calling_labsupports_kinematics_scores_zero(master1):
    def ik_through_2r(x, elbow_up=True):
        x = np.asarray(x, float)
        rho, h = np.hypot(x[0], x[1]), x[2] - 1.0
        q = planar_ik(np.array([rho, h]), elbow_up=not elbow_up)  # the 2R arm's own IK
        return master1["ik_3r"](x, elbow_up) + 0 * q[0]

    result = grade("p1_ik", ik_3r=ik_through_2r)
    assert result.score == 0 and rules.MARKER in result.message and "labsupport.kinematics" in result.message


def test_a_law_carried_as_compiled_code_from_another_installation_is_named():
    """A Task law's code object marshalled on the student's own installation (Colab's) and
    rebuilt with FunctionType under an allowed module's globals: nothing is imported, and its
    code names a file this machine does not have. The watch names it by its path from the
    package's folder on."""
    import base64
    import marshal

    code = marshal.loads(base64.b64decode(carried_code(joint_space_alias.ct_joint_torque)))
    assert code.co_filename.startswith("/usr/local/lib/") and not Path(code.co_filename).exists()
    law = types.FunctionType(code, vars(labsupport.dynamics))

    def carried(model, data, q_d, Kp, Kd):
        return law(model, data, q_d, np.zeros(3), np.zeros(3), Kp, Kd)

    result = grade("p1_ct", ct_joint_torque=carried)
    assert result.score == 0 and "labsupport.controllers.joint_space.ct_joint_torque is off limits" in result.message


def test_a_law_carried_under_a_made_up_file_name_is_known_by_its_compiled_code():
    """The same law carried with its file renamed ("<lab notes>"): neither its module nor its
    file is labsupport's; its bytecode, names and constants are, and the watch knows it by them."""
    import base64
    import marshal

    code = marshal.loads(base64.b64decode(carried_code(joint_space_alias.ct_joint_torque, filename="<lab notes>")))
    law = types.FunctionType(code, vars(labsupport.dynamics), "my_own_ct")

    def carried(model, data, q_d, Kp, Kd):
        return law(model, data, q_d, np.zeros(3), np.zeros(3), Kp, Kd)

    result = grade("p1_ct", ct_joint_torque=carried)
    assert result.score == 0 and "labsupport.controllers.joint_space.ct_joint_torque is off limits" in result.message


def test_a_law_written_to_a_file_from_data_and_imported_is_known_by_its_code(tmp_path):
    """The law's source written to a file of the student's own (decoded from a string, say) and
    imported from there: its module and file are not labsupport's, its text is not in a cell, and
    its compiled code is the library law's."""
    path = tmp_path / "notes.py"
    path.write_text(Path(joint_space_alias.__file__).read_text(encoding="utf-8"), encoding="utf-8")
    spec = importlib.util.spec_from_file_location("notes", path)
    notes = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(notes)

    def carried(model, data, q_d, Kp, Kd):
        return notes.ct_joint_torque(model, data, q_d, np.zeros(3), np.zeros(3), Kp, Kd)

    result = grade("p1_ct", ct_joint_torque=carried)
    assert result.score == 0 and "labsupport.controllers.joint_space.ct_joint_torque is off limits" in result.message


def test_a_law_pasted_into_a_cell_is_the_notebooks_own_code():
    """Its compiled code is the library law's, but its text is in the cell its code names (as
    IPython keeps it): graded as the notebook's own code, full marks for a right law. The same
    text run from a string with exec is not where its code says, and scores zero."""
    from IPython.core.interactiveshell import InteractiveShell

    shell = InteractiveShell.instance()
    pasted = inspect.getsource(joint_space_alias.ct_joint_torque).replace("def ct_joint_torque(", "def task3_ct(")
    shell.run_cell("import numpy as np\nfrom labsupport.dynamics import mass_times\n\n\n" + pasted, store_history=False)
    task3_ct = shell.user_ns["task3_ct"]
    assert rules.code_fingerprint(task3_ct.__code__) in rules.forbidden_code()

    def pasted_ct(model, data, q_d, Kp, Kd):
        return task3_ct(model, data, q_d, np.zeros(3), np.zeros(3), Kp, Kd)

    result = grade("p1_ct", ct_joint_torque=pasted_ct)
    assert result.score == 1.0, result.message
    namespace = dict(vars(labsupport.dynamics))
    exec(compile(pasted, "<string>", "exec"), namespace)  # the text in a string, not in a cell
    from_string = namespace["task3_ct"]

    def exec_ct(model, data, q_d, Kp, Kd):
        return from_string(model, data, q_d, np.zeros(3), np.zeros(3), Kp, Kd)

    result = grade("p1_ct", ct_joint_torque=exec_ct)
    assert result.score == 0 and "labsupport.controllers.joint_space.ct_joint_torque is off limits" in result.message


def test_a_fingerprint_is_what_the_code_does_not_what_it_is_called():
    """Name, file and line numbers do not change it; a changed constant, name or instruction does;
    a frozenset constant gives the same fingerprint whatever the process's string hashing."""
    source = 'def law(q, k):\n    """A law."""\n    return k * (q - 1.0) if q in {"a", "b"} else k\n'
    renamed = "\n\n" + source.replace("def law(", "def mine(")
    for other in (renamed, source.replace("1.0", "2.0"), source.replace("k * (q", "k * (-q")):
        a, b = rules.fingerprints_of_module(source, "m"), rules.fingerprints_of_module(other, "n")
        assert (set(a) == set(b)) == (other is renamed), other
    assert rules.fingerprints_of_module("def f(q):\n    return q + 1\n", "m") == {}  # undocumented: never a match
    script = f"from labsupport.grading import rules; print(*rules.fingerprints_of_module({source!r}, 'm'))"
    hashed = [
        subprocess.run(
            [sys.executable, "-c", script],
            env={**os.environ, "PYTHONHASHSEED": seed},
            capture_output=True,
            text=True,
            check=True,
        ).stdout
        for seed in ("1", "2")
    ]
    assert hashed[0] == hashed[1] == " ".join(rules.fingerprints_of_module(source, "m")) + "\n"


@pytest.mark.parametrize(
    ("filename", "module"),
    [
        (
            "/usr/local/lib/python3.13/dist-packages/labsupport/controllers/joint_space.py",
            "labsupport.controllers.joint_space",
        ),
        ("C:\\Users\\me\\site-packages\\labsupport\\kinematics\\planar_2r.py", "labsupport.kinematics.planar_2r"),
        ("/content/labsupport/labsupport/grading/problem2.py", "labsupport.grading.problem2"),
        ("/opt/x/labsupport/controllers/__init__.py", "labsupport.controllers"),
        ("/opt/x/labsupport/controllers/__pycache__/ur5e.cpython-311.pyc", None),  # never a code's file
        ("/opt/x/labsupport/dynamics.py", None),
        ("/opt/x/labsupport/grading/rules.py", None),
        ("/opt/x/my_labsupport/controllers/mine.py", None),
        ("/opt/x/labsupport/controllers/notes.txt", None),
        ("<ipython-input-3-0f1>", None),
    ],
)
def test_a_forbidden_module_is_known_by_its_file_wherever_installed(filename, module):
    assert rules.forbidden_module_of_file(filename) == module


def test_a_borrowed_class_is_named_as_the_student_wrote_it():
    """A dataclass's __init__ is generated code; the reason names the class, not that code."""

    def ik_with_a_2r_arm(x, elbow_up=True):
        arm = Planar2R(1.0, 1.0)
        return np.zeros(3) + 0 * arm.l1

    class MyArm(Planar2R):
        pass

    def ik_with_a_subclass(x, elbow_up=True):
        return np.zeros(3) + 0 * MyArm(1.0, 1.0).l1

    for ik in (ik_with_a_2r_arm, ik_with_a_subclass):
        result = grade("p1_ik", ik_3r=ik)
        assert result.score == 0 and "labsupport.kinematics.planar_2r.Planar2R is off limits" in result.message
        assert "<locals>" not in result.message


def test_calling_the_checks_internals_scores_zero():
    def borrowed(model, data, q_d, Kp, Kd):
        state = State(data.qpos.copy(), data.qvel.copy())
        return problem1.ct_law(common.terms(model, state.q, state.qdot), state, q_d, Kp, Kd)

    result = grade("p1_ct", ct_joint_torque=borrowed)
    assert result.score == 0 and "labsupport.grading.common.terms" in result.message


def test_the_sandboxs_stub_error_gives_the_same_zero_and_reason():
    qualified = "labsupport.controllers.joint_space.ct_joint_torque"

    def stubbed(model, data, q_d, Kp, Kd):  # what the batch sandbox's stub does when called
        raise RuntimeError(rules.forbidden_message(qualified))

    class SandboxLike(Probe):  # the batch probe passes the error on as text, cut at 200 characters
        def call(self, fname, *args, **kwargs):
            from labsupport.grading.feedback import StudentError

            raise StudentError(f"{fname} raised RuntimeError: {rules.forbidden_message(qualified)[:200]}")

    direct = grade("p1_ct", ct_joint_torque=stubbed)
    batch = problem1.check_ct(SandboxLike(), OTHER_SEED)
    for result in (direct, batch):
        assert result.score == 0 and result.message.startswith(f"CT: {qualified} {rules.MARKER}"), result
        assert "raised RuntimeError" not in result.message
    assert len(rules.forbidden_message(qualified)) <= 200


def test_the_watch_leaves_other_profilers_running():
    seen = []

    def outer(frame, event, arg):
        seen.append(event)

    sys.setprofile(outer)
    try:
        value, used = rules.call_watched(lambda: np.linalg.norm([3.0, 4.0]))
        assert sys.getprofile() is outer
    finally:
        sys.setprofile(None)
    assert value == 5.0 and used is None and "call" in seen
    assert rules.is_forbidden_module("labsupport.controllers.ur5e")
    assert not rules.is_forbidden_module("labsupport.dynamics") and not rules.is_forbidden_module("labsupport.grading")


def test_a_call_made_in_a_thread_the_law_starts_is_seen():
    def ct_in_a_thread(model, data, q_d, Kp, Kd):
        out, zero = [], np.zeros(3)
        worker = threading.Thread(
            target=lambda: out.append(joint_space_alias.ct_joint_torque(model, data, q_d, zero, zero, Kp, Kd))
        )
        worker.start()
        worker.join()
        return out[0]

    result = grade("p1_ct", ct_joint_torque=ct_in_a_thread)
    assert result.score == 0 and "labsupport.controllers.joint_space.ct_joint_torque is off limits" in result.message


def test_switching_the_watch_off_scores_zero_and_says_why():
    def pd_unwatched(model, data, q_d, Kp, Kd):
        sys.setprofile(None)
        return Kp * (q_d - data.qpos) - Kd * data.qvel  # even a right law: the check cannot see it

    result = grade("p1_pd", pd_torque=pd_unwatched)
    assert result.score == 0 and "sys.setprofile" in result.message and rules.MARKER in result.message
    assert sys.getprofile() is None


def test_a_law_rebuilt_from_its_code_or_loaded_from_its_file_under_another_name_is_seen():
    code = joint_space_alias.ct_joint_torque.__code__
    rebuilt = types.FunctionType(code, {**vars(joint_space_alias), "__name__": "mine"})
    spec = importlib.util.spec_from_file_location("my_controllers", joint_space_alias.__file__)
    reloaded = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(reloaded)
    for law in (rebuilt, reloaded.ct_joint_torque):

        def ct(model, data, q_d, Kp, Kd, law=law):
            return law(model, data, q_d, np.zeros(3), np.zeros(3), Kp, Kd)

        result = grade("p1_ct", ct_joint_torque=ct)
        assert result.score == 0, result
        assert "labsupport.controllers.joint_space.ct_joint_torque is off limits" in result.message


def test_a_value_that_runs_the_law_when_read_as_numbers_is_seen():
    class Lazy:  # computes the torque only when the check reads it, after the call returned
        def __init__(self, *args):
            self.args = args

        def __array__(self, dtype=None, copy=None):
            return np.asarray(joint_space_alias.ct_joint_torque(*self.args), dtype=dtype)

    def ct_lazy(model, data, q_d, Kp, Kd):
        return Lazy(model, data, np.array(q_d), np.zeros(3), np.zeros(3), Kp, Kd)

    result = grade("p1_ct", ct_joint_torque=ct_lazy)
    assert result.score == 0 and "labsupport.controllers.joint_space.ct_joint_torque is off limits" in result.message


# --- seeds ----------------------------------------------------------------------------------------------


class Recorder(Probe):
    """Records every argument a check passes; answers like the masters."""

    def __init__(self, ns):
        self.inner, self.seen = DirectProbe(ns), []

    def call(self, fname, *args, **kwargs):
        self.seen.append(np.concatenate([np.ravel(a.q) if isinstance(a, State) else np.ravel(a) for a in args]))
        return self.inner.call(fname, *args, **kwargs)

    def get(self, name):
        return self.inner.get(name)


def test_different_seeds_draw_different_tests(master1, master2):
    for name in ("p1_ik", "p1_pd", "p1_ct", "p2_osct", "p2_ikct"):
        ns = master1 if name.startswith("p1") else master2
        runs = {}
        for seed in (PUBLIC_SEED, OTHER_SEED, PUBLIC_SEED):
            probe = Recorder(ns)
            registry()[name](probe, seed)
            runs.setdefault(seed, []).append(np.concatenate(probe.seen))
        assert np.array_equal(*runs[PUBLIC_SEED]), f"{name}: the same seed must give the same tests"
        assert not np.allclose(runs[PUBLIC_SEED][0][:9], runs[OTHER_SEED][0][:9]), name
    assert not np.allclose(problem2.tracking_circle(PUBLIC_SEED)[0], problem2.tracking_circle(OTHER_SEED)[0])


def test_seeded_circles_stay_reachable_and_away_from_singularities():
    model = common.arm_model()
    for seed in range(6):
        center, radius, normal, q0, qdot0 = problem2.tracking_circle(seed)
        from labsupport.trajectories import circle_3d

        ref = circle_3d(np.linspace(0, 5, 200), center, radius, normal, problem2.FREQUENCY)
        assert np.allclose(ref.pos[0], tip_at(model, q0)) and common.elbow_height(model, q0) > 0
        assert all(common.safe_point(p) for p in ref.pos)
        J, _ = jacobian_at(model, q0)
        assert np.allclose(J @ qdot0, ref.vel[0])


# --- stability: the real cause of PD's divergence near the folded arm --------------------------------------


def test_the_closed_loops_damping_is_kd_for_pd_at_rest_and_m_kd_for_ct_at_any_speed():
    """D = −∂(τ − h)/∂q̇: a PD's is Kd·I where the arm is still (the velocity terms of h are quadratic
    in q̇), and computed torque's is M(q)·Kd at any speed, its +h cancelling the arm's own."""
    model, kd = common.arm_model(), 18.0
    q, fast = np.array([0.4, 0.6, -0.9]), np.array([3.0, -2.0, 4.0])
    D, _ = effective_damping(model, lambda m, d: -kd * d.qvel, q, np.zeros(3))
    np.testing.assert_allclose(D, kd * np.eye(3), atol=1e-6)
    D, M = effective_damping(model, lambda m, d: mass_matrix(m, d) @ (-kd * d.qvel) + bias_forces(d), q, fast)
    np.testing.assert_allclose(D, kd * M, rtol=1e-6, atol=1e-9)
    np.testing.assert_allclose(M, mass_matrix(model, common.data_at(model, q, fast)), rtol=1e-12)


def test_pd_divergence_near_the_folded_arm_is_explained(master1, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)  # MuJoCo's default handler would log the divergence to MUJOCO_LOG.TXT here
    model = common.arm_model()
    folded = np.array([0.0, 0.0, np.pi / 2])
    pd = master1["pd_torque"]
    text = stiff_damping(model, lambda m, d: pd(m, d, folded, 400.0, 50.0), folded, np.zeros(3))
    M11 = mass_matrix(model, common.data_at(model, folded))[0, 0]
    assert M11 == pytest.approx(0.003)
    assert "too stiff for the time step" in text and f"{50 * 0.002 / M11:.3g}" in text and "pan joint 1" in text
    assert "smaller time step" in text and "lower Kd" in text
    assert (
        stiff_damping(model, lambda m, d: master1["ct_joint_torque"](m, d, folded, 100.0, 18.0), folded, np.zeros(3))
        is None
    )

    probe = DirectProbe({"pd_torque": pd})
    with pytest.raises(Exception, match="too stiff for the time step.*Kd·Δt/M"):
        common.run_student(probe, "pd_torque", (np.array([0.8, 0.1, 1.5]), 400.0, 50.0), 2.0, problem1.Q0)
    assert not (tmp_path / "MUJOCO_LOG.TXT").exists()  # the loop took MuJoCo's warnings itself


def test_an_os_ct_that_reads_x_at_the_elbow_is_told_which_point_it_took():
    """x from the elbow's body origin where the tip's site belongs: named as that mistake (with its
    quarter of the points), not left as "the difference lies in another term"."""

    def ct_op_torque(model, data, x_d, xd_d, xdd_d, Kp, Kd):
        J = site_jacobian(model, data, "end_effector")[:3]
        x = data.body("link3").xpos  # the elbow, not the tip
        a = xdd_d + Kd * (xd_d - J @ data.qvel) + Kp * (x_d - x) - site_jdot_qdot(model, data, "end_effector")[:3]
        return mass_matrix(model, data) @ np.linalg.solve(J, a) + data.qfrc_bias

    result = grade("p2_osct", ct_op_torque=ct_op_torque)
    assert result.score == pytest.approx(0.25) and "x is not the end effector's position" in result.message
    assert "the body 'link3'" in result.message and "data.site('end_effector').xpos" in result.message


def test_an_os_ct_with_the_jacobian_of_the_wrong_point_is_told_so():
    """mj_jacBody of link3 (the elbow: its origin is on joint 3's axis, so joint 3's column is
    zero) makes np.linalg.solve raise "Singular matrix" at every test state: the reason names the
    wrong point and the end effector's site, not only a scratch MjData."""

    def ct_op_torque(model, data, x_d, xd_d, xdd_d, Kp, Kd):
        J = np.zeros((3, model.nv))
        mujoco.mj_jacBody(model, data, J, None, model.body("link3").id)
        x = data.site("end_effector").xpos
        a = xdd_d + Kd * (xd_d - J @ data.qvel) + Kp * (x_d - x)
        return mass_matrix(model, data) @ np.linalg.solve(J, a) + data.qfrc_bias

    result = grade("p2_osct", ct_op_torque=ct_op_torque)
    assert result.score == 0 and "Singular matrix" in result.message, result.message
    assert "the Jacobian of the wrong point" in result.message and "mj_jacSite with 'end_effector'" in result.message


def test_a_computed_torque_without_m_is_told_so_not_sent_to_the_time_step(tmp_path, monkeypatch, capsys):
    """A "computed torque" that forgets M(q), Kp e − Kd q̇ + h, damps as PD does and diverges near
    the folded arm at CT's gains (Kd·Δt/M = 18 × 0.002 / 0.0175 ≈ 2.06). Its message names the
    missing M, in the notebook's run as in the checks', not the time step; the same damping under
    a PD's name keeps the time-step words."""
    from labsupport.grading import as_controller, attempt
    from labsupport.sim import simulate

    monkeypatch.chdir(tmp_path)
    model = common.arm_model()

    def ct_joint_torque(model, data, q_d, Kp, Kd):
        return Kp * (q_d - data.qpos) - Kd * data.qvel + data.qfrc_bias

    q_fold = np.array([0.8, 0.1, 1.5])  # the fold demo's goal
    ctrl = as_controller(ct_joint_torque, q_fold, 100.0, 18.0)
    data = mujoco.MjData(model)
    assert attempt("CT", lambda: simulate(model, data, ctrl, 2.0, q0=problem1.Q0), ctrl, model) is None
    probe = DirectProbe({"ct_joint_torque": ct_joint_torque})
    with pytest.raises(StudentError) as err:
        common.run_student(probe, "ct_joint_torque", (q_fold, 100.0, 18.0), 2.0, problem1.Q0)
    for said in (capsys.readouterr().out, str(err.value)):
        assert "your computed-torque law damps as PD does, with the same Kd = 18 on every joint" in said, said
        assert "its feedback is not multiplied by M(q)" in said and "smaller time step would only hide" in said
        assert "Remedies: a smaller time step" not in said
    folded = np.array([0.0, 0.0, np.pi / 2])
    as_pd = stiff_damping(model, partial(ct_joint_torque, q_d=folded, Kp=100.0, Kd=18.0), folded, np.zeros(3))
    assert as_pd.startswith("the damping is too stiff for the time step") and "Remedies" in as_pd


def test_a_pd_with_its_gains_swapped_is_told_so_where_it_runs_not_sent_to_a_lower_kd(tmp_path, monkeypatch, capsys):
    """PD with Kd multiplying the position error and Kp the velocity diverges at the lab's gains
    (400, 50): its damping is 400 N·m·s/rad. The run cell advised "a lower Kd (below 167)", taking
    the swapped 400 for an intended Kd; it now names the swap. The right PD that diverges near the
    folded arm keeps the time-step words."""
    from labsupport.grading import as_controller, attempt
    from labsupport.grading.stability import handed_gains
    from labsupport.sim import simulate

    monkeypatch.chdir(tmp_path)
    model = common.arm_model()

    def pd_torque(model, data, q_d, Kp, Kd):
        return Kd * (q_d - data.qpos) - Kp * data.qvel  # swapped

    assert handed_gains(pd_torque, (np.zeros(3), 400.0, 50.0)) == (400.0, 50.0)
    assert handed_gains(lambda model, data, q_d, kd, kp: 0, (np.zeros(3), 50.0, 400.0)) == (400.0, 50.0)
    assert handed_gains(lambda model, data, q_d, gain: 0, (np.zeros(3), 1.0)) is None
    assert handed_gains(pd_torque, (np.zeros(3), "400", None)) is None

    q_target = np.array([0.3, 0.5, 0.6])
    ctrl = as_controller(pd_torque, q_target, 400.0, 50.0)
    data = mujoco.MjData(model)
    assert attempt("PD", lambda: simulate(model, data, ctrl, 2.0, q0=problem1.Q0), ctrl, model) is None
    said = capsys.readouterr().out
    assert "the closed loop damps with 400 N·m·s/rad on every joint: the Kp = 400 the law was handed" in said, said
    assert "Kp and Kd look swapped in the law" in said and "lower Kd" not in said


@pytest.mark.parametrize(
    "wrong",
    [
        lambda e, qdot, Kp, Kd: Kp * e + Kd * qdot,  # the damping's sign
        lambda e, qdot, Kp, Kd: -(Kp * e - Kd * qdot),  # the whole feedback's sign
    ],
    ids=["damping_sign", "feedback_sign"],
)
def test_a_law_that_is_itself_unstable_is_not_blamed_on_the_time_step(wrong, tmp_path, monkeypatch):
    """A sign error runs away smoothly; the loop notices when it ends, so states turning at
    thousands of rad/s follow the divergence, where the bias forces look like a huge damping.
    The explanation comes from the states up to the divergence only: check the signs."""
    monkeypatch.chdir(tmp_path)

    def ct(model, data, q_d, Kp, Kd):
        return mass_matrix(model, data) @ wrong(q_d - data.qpos, data.qvel, Kp, Kd) + data.qfrc_bias

    probe = DirectProbe({"ct_joint_torque": ct})
    with pytest.raises(StudentError) as err:
        common.run_student(probe, "ct_joint_torque", (np.array([0.8, 0.1, 1.5]), 100.0, 18.0), 2.0, problem1.Q0)
    assert "check the signs" in str(err.value) and "too stiff" not in str(err.value)


def ct_law(inertia_term):
    """Joint computed torque with ``inertia_term(M, v)`` standing for ``M @ v``."""

    def ct(model, data, q_d, Kp, Kd):
        return inertia_term(mass_matrix(model, data), Kp * (q_d - data.qpos) - Kd * data.qvel) + data.qfrc_bias

    return ct


def test_a_law_that_inverts_the_mass_matrix_is_named_and_not_blamed_on_the_time_step(tmp_path, monkeypatch):
    """``np.linalg.solve(M, v)`` where ``M @ v`` belongs: the closed loop's damping is M⁻¹Kd, whose
    fastest pole at the arm's small inertias is far beyond RK4's limit. The message names the
    mistake and the Kd the student passed, not a time step to shrink."""
    monkeypatch.chdir(tmp_path)
    probe = DirectProbe({"ct_joint_torque": ct_law(np.linalg.solve)})
    with pytest.raises(StudentError) as err:
        common.run_student(probe, "ct_joint_torque", (np.array([0.5, 0.6, 0.4]), 100.0, 18.0), 2.0, problem1.Q0)
    text = str(err.value)
    assert "M(q)⁻¹·Kd with Kd = 18," in text and "np.linalg.solve(M, v) is M⁻¹v" in text
    assert "too stiff" not in text


def test_a_computed_torque_with_too_large_a_kd_is_told_its_own_limit():
    """Computed torque's velocity poles are Kd itself: Kd·Δt above 2 diverges whatever the
    inertia, and the limit told is 2 / Δt."""
    model = common.arm_model()
    folded = np.array([0.0, 0.0, np.pi / 2])
    ct = ct_law(np.matmul)
    assert stiff_damping(model, lambda m, d: ct(m, d, folded, 100.0, 950.0), folded, np.zeros(3)) is None
    text = stiff_damping(model, lambda m, d: ct(m, d, folded, 100.0, 2000.0), folded, np.array([0.3, -0.2, 0.5]))
    assert "M(q)·Kd with Kd = 2000 1/s" in text and "λ·Δt = 4 is above 2, the most" in text
    assert f"below {2 / 0.002:.3g} 1/s" in text


@pytest.mark.parametrize("kd_dt", [1.9, 2.1])
def test_the_limit_told_is_where_a_held_torque_diverges_under_rk4(kd_dt):
    """The stability limit is that of the torque held over each step, Kd·Δt/M = 2, not RK4's own
    2.785 for a damping it evaluates at every stage: the 3R arm under computed torque (velocity
    pole Kd), integrated with RK4, settles at Kd·Δt = 1.9 and runs away at 2.1, and the verdict
    says so on both sides."""
    from labsupport.sim import SimulationDiverged, simulate

    model = common.arm_model()
    assert model.opt.integrator == mujoco.mjtIntegrator.mjINT_RK4
    q_d = np.array([0.3, 0.4, 1.2])
    kd = kd_dt / model.opt.timestep
    ct = ct_law(np.matmul)
    law = lambda m, d: ct(m, d, q_d, 100.0, kd)  # noqa: E731
    data = mujoco.MjData(model)
    start = q_d + 0.01, np.array([0.2, -0.1, 0.3])
    verdict = stiff_damping(model, law, *start)
    if kd_dt < 2:
        log = simulate(model, data, law, 1.0, q0=start[0], qdot0=start[1])
        assert np.abs(log.qdot[-1]).max() < 0.01 and verdict is None  # the speeds die out
    else:
        with pytest.raises(SimulationDiverged):
            simulate(model, data, law, 1.0, q0=start[0], qdot0=start[1])
        assert "too stiff" in verdict and "λ·Δt = 2.1 is above 2" in verdict


def test_an_operational_space_spring_of_the_wrong_sign_is_not_blamed_on_the_time_step(tmp_path, monkeypatch):
    """Kp (x − x_d) instead of Kp (x_d − x): the arm drifts off the circle and runs away, fast, where
    the change of J⁻¹ and J̇q̇ with the speeds looks like a huge damping; and the bias forces'
    change with the speeds would too if they were not taken out of the law's damping (they cancel
    the arm's own). Neither may be told to the student as a time step too large."""
    monkeypatch.chdir(tmp_path)
    center, radius, normal, q0, qdot0 = problem2.tracking_circle(PUBLIC_SEED)

    def args(t):
        r = circle_3d(t, center, radius, normal, problem2.FREQUENCY)
        return r.pos, r.vel, r.acc, problem2.KP, problem2.KD

    def os_ct_spring_sign(model, data, x_d, xd_d, xdd_d, Kp, Kd):
        J = site_jacobian(model, data, "end_effector")[:3]
        x = data.site("end_effector").xpos
        a = xdd_d + Kd * (xd_d - J @ data.qvel) + Kp * (x - x_d) - site_jdot_qdot(model, data, "end_effector")[:3]
        return mass_matrix(model, data) @ np.linalg.solve(J, a) + data.qfrc_bias

    probe = DirectProbe({"ct_op_torque": os_ct_spring_sign})
    with pytest.raises(StudentError) as err:
        common.run_student(probe, "ct_op_torque", args, problem2.TRACK_DURATION, q0, qdot0)
    assert "check the signs" in str(err.value) and "too stiff" not in str(err.value)
    assert "λ" not in str(err.value)


def test_the_notebooks_own_run_of_a_wrong_spring_is_not_blamed_on_the_time_step(tmp_path, monkeypatch, capsys):
    """The same mistake in the notebook's own run (the lab's circle, from rest): the message once
    said "this is not a sign error" with Kd·Δt/M = 0.0443 "above" 2.785."""
    from labsupport.grading import as_controller, attempt
    from labsupport.plants import load_model
    from labsupport.sim import simulate

    monkeypatch.chdir(tmp_path)
    model, data = load_model("spatial_3r")

    reference = problem2.reference  # the notebook's circle

    def reference_and_gains(t):
        r = reference(t)
        return r.pos, r.vel, r.acc, problem2.KP, problem2.KD

    def os_ct_spring_sign(model, data, x_d, xd_d, xdd_d, Kp, Kd):
        J = site_jacobian(model, data, "end_effector")[:3]
        x = data.site("end_effector").xpos
        a = xdd_d + Kd * (xd_d - J @ data.qvel) + Kp * (x - x_d) - site_jdot_qdot(model, data, "end_effector")[:3]
        return mass_matrix(model, data) @ np.linalg.solve(J, a) + data.qfrc_bias

    x0 = reference(0.0).pos  # elbow up, facing the target: the law of cosines in the arm's plane
    rho, h = np.hypot(x0[0], x0[1]), x0[2] - 1.0
    c = (rho**2 + h**2 - 2.0) / 2.0
    q0 = np.array(
        [
            np.arctan2(x0[1], x0[0]),
            np.arctan2(rho, h) - np.arctan2(np.sin(np.arccos(c)), 1 + c),
            np.arccos(c) - np.pi / 2,
        ]
    )
    assert np.allclose(common.tip(model, q0), reference(0.0).pos)
    ctrl = as_controller(os_ct_spring_sign, reference_and_gains)
    log = attempt("OS-CT", lambda: simulate(model, data, ctrl, 10.0, q0=q0, site="end_effector"), ctrl, model)
    said = capsys.readouterr().out
    assert log is None and "diverged" in said and "check the signs" in said
    assert "too stiff" not in said and "not a sign error" not in said


def test_a_run_through_a_forbidden_law_says_so_where_it_runs(capsys):
    """Problem 1's run cell printed a good result for a law that calls Task 3's joint CT, and
    q_des for an IK built on the 2R arm's, without a word: only the check said the TODO scores
    zero. The run now says it too, and still shows its result; a law of the student's own gets
    no such note."""
    from labsupport.grading import as_controller, attempt
    from labsupport.plants import load_model
    from labsupport.sim import simulate

    model, data = load_model("spatial_3r")
    zero = np.zeros(3)

    def borrowed(model, data, q_d, Kp, Kd):
        return joint_space_alias.ct_joint_torque(model, data, q_d, zero, zero, Kp, Kd)

    def own(model, data, q_d, Kp, Kd):
        return mass_matrix(model, data) @ (Kp * (q_d - data.qpos) - Kd * data.qvel) + bias_forces(data)

    q_d = np.array([0.3, 0.5, 0.2])
    logs = {}
    for law in (borrowed, own):
        ctrl = as_controller(law, q_d, 100.0, 18.0)
        logs[law.__name__] = attempt("CT", partial(simulate, model, data, ctrl, 0.5, q0=problem1.Q0), ctrl, model)
        said = capsys.readouterr().out
        assert ("labsupport.controllers.joint_space.ct_joint_torque is off limits" in said) == (law is borrowed), said
    np.testing.assert_allclose(logs["borrowed"].q, logs["own"].q, atol=1e-9)  # the same run, shown

    q = attempt("IK", lambda: np.array([0.0, *planar_ik(np.array([0.5, 0.3]))]), joints=3)
    assert q.shape == (3,)
    said = capsys.readouterr().out
    assert said.startswith("IK: it ran, but labsupport.kinematics.planar_2r.inverse_kinematics is off limits"), said
    assert said.rstrip().endswith("This TODO scores zero in its check."), said


def test_an_ik_answer_in_degrees_is_questioned_where_it_is_printed(capsys):
    """Problem 1 printed ``q_des = [97.1 -51.7 27.8] rad`` and a predicted sag for it without a
    remark. Angles beyond 3π (past even an answer a full turn off) now get a note; a full turn off
    does not (the check's own note names that)."""
    from labsupport.grading import attempt

    q = np.array([1.694, -0.902, 0.485])
    assert np.array_equal(attempt("IK", lambda: np.degrees(q), joints=3), np.degrees(q))
    said = capsys.readouterr().out
    assert said.startswith("IK: note: [ 97.0591 -51.6808  27.7885] has angles beyond 3π") and "degrees?" in said
    attempt("IK", lambda: q + [0.0, 0.0, 2 * np.pi], joints=3)
    assert capsys.readouterr().out == ""


def test_a_run_whose_law_raised_says_it_once_with_the_students_line(capsys):
    """The message "skipped, it raised TypeError: the controller raised TypeError at t = ..." said it
    twice, and gave no line of the student's code."""
    from labsupport.grading import as_controller, attempt
    from labsupport.plants import load_model
    from labsupport.sim import simulate

    model, data = load_model("spatial_3r")

    def ct_joint_torque(model, data, q_d, Kp, Kd):
        return mass_matrix(model, data) @ (Kp * (q_d - data.qpos)) + bias_forces(model, data)

    ctrl = as_controller(ct_joint_torque, np.zeros(3), 100.0, 20.0)
    assert attempt("CT", lambda: simulate(model, data, ctrl, 1.0), ctrl, model) is None
    said = capsys.readouterr().out
    assert said.startswith("CT: skipped, the controller raised TypeError at t = 0.0000 s: ")
    assert "it raised" not in said
    assert (
        "of ct_joint_torque: return mass_matrix(model, data) @ (Kp * (q_d - data.qpos)) + bias_forces(model, data)"
        in said
    )


def test_a_law_that_changes_its_target_in_place_leaves_the_notebooks_target_as_it_was():
    """``q_d -= data.qpos`` in a law run through ``as_controller`` changed the notebook's own
    ``q_des`` (to [61.9, -107.6, 175.8] after the PD run); the run diverged with advice about
    gains and signs, and the later runs silently used that target. Each call now gets its own
    copies, of fixed arguments and of what a moving reference hands it alike, so the law runs as
    the checks grade it (right), and ``q_des`` keeps its value."""
    from labsupport.grading import as_controller
    from labsupport.plants import load_model
    from labsupport.sim import simulate

    model, data = load_model("spatial_3r")
    q_des = np.array([0.3, 0.4, -0.5])
    kept = q_des.copy()

    def in_place(model, data, q_d, Kp, Kd):
        q_d -= data.qpos
        return mass_matrix(model, data) @ (Kp * q_d - Kd * data.qvel) + bias_forces(data)

    def plain(model, data, q_d, Kp, Kd):
        return mass_matrix(model, data) @ (Kp * (q_d - data.qpos) - Kd * data.qvel) + bias_forces(data)

    for args in ((q_des, 100.0, 20.0), (lambda t: (q_des, 100.0, 20.0),)):
        log = simulate(model, data, as_controller(in_place, *args), 1.0, q0=problem1.Q0)
        np.testing.assert_array_equal(q_des, kept)
        same = simulate(model, data, as_controller(plain, *args), 1.0, q0=problem1.Q0)
        np.testing.assert_array_equal(log.q, same.q)
        assert np.linalg.norm(log.q[-1] - q_des) < 1e-3  # it reached the target it was given


def test_a_moving_reference_that_returns_one_array_hands_it_whole():
    """``as_controller(law, lambda t: q_d(t))`` with ``law(model, data, q_d)``: the array the
    function returned was spread into three arguments, and the law failed on their number."""
    from labsupport.grading import as_controller
    from labsupport.plants import load_model
    from labsupport.sim import simulate

    model, data = load_model("spatial_3r")
    target = np.array([0.3, 0.4, -0.5])

    def hold(model, data, q_d):
        return mass_matrix(model, data) @ (100.0 * (q_d - data.qpos) - 20.0 * data.qvel) + bias_forces(data)

    log = simulate(model, data, as_controller(hold, lambda t: target), 1.0, q0=problem1.Q0)
    assert np.linalg.norm(log.q[-1] - target) < 1e-3


def test_a_law_that_writes_into_the_arms_state_is_told_so_not_that_it_diverged(capsys):
    """``e = data.qpos; e -= q_d`` gives the right torque at every test state (the checks pass
    copies), but in the notebook's run it moved the arm itself, which then diverged with the
    advice to check the law's signs, which were right."""
    from labsupport.grading import as_controller, attempt
    from labsupport.plants import load_model
    from labsupport.sim import simulate

    model, data = load_model("spatial_3r")
    q_d = np.array([0.5, -0.3, 0.2])

    def pd_torque(model, data, q_d, Kp, Kd):
        e = data.qpos
        e -= q_d  # writes into data.qpos
        return -Kp * e - Kd * data.qvel

    def pd_right(model, data, q_d, Kp, Kd):
        return Kp * (q_d - data.qpos) - Kd * data.qvel

    ctrl = as_controller(pd_torque, q_d, 100.0, 20.0)
    assert attempt("PD", lambda: simulate(model, data, ctrl, 1.0), ctrl, model) is None
    said = capsys.readouterr().out
    assert said.startswith("PD: skipped, pd_torque changed data.qpos, the arm's own state") and "diverged" not in said
    assert "e = q_d - data.qpos" in said
    ctrl = as_controller(pd_right, q_d, 100.0, 20.0)
    # the stopped run left data at time 0 with the state the law wrote: the next run says it starts afresh
    with pytest.warns(RuntimeWarning, match=r"at time 0 \(.*or by a run stopped at its first step\)"):
        log = attempt("PD", lambda: simulate(model, data, ctrl, 1.0), ctrl, model)
    assert np.abs(log.q[-1] - q_d).max() < 0.05


@pytest.mark.parametrize(
    ("answer", "said"),
    [
        ([0.1, 0.2], "IK: skipped, the joint vector from IK has shape (2,), expected (3,): 3 numbers."),
        ([[0.1], [0.2], [0.3]], "has shape (3, 1), expected (3,): 3 numbers; return it flat, np.ravel(...)"),
        ([0.1, None, 0.3], "IK: skipped, the joint vector from IK contains None"),
        (None, "IK: skipped, IK returned None: not implemented yet"),
        ("abc", "IK: skipped, IK returned str, expected 3 numbers."),
    ],
)
def test_an_ik_answer_of_the_wrong_shape_waits_with_the_checks_words(answer, said, capsys):
    """The Problems' run cells take the IK's answer through attempt(..., joints=3): a wrong one
    is named, and None comes back, so the cells after it wait instead of failing where the
    angles are set into data.qpos (a NumPy broadcast error, which stopped "Run all")."""
    from labsupport.grading import attempt

    assert attempt("IK", lambda: answer, joints=3) is None
    assert said in capsys.readouterr().out
    np.testing.assert_array_equal(attempt("IK", lambda: [0.1, 0.2, 0.3], joints=3), [0.1, 0.2, 0.3])


def test_a_law_check_names_a_write_into_the_state_and_keeps_the_score(capsys):
    """The law checks hand each call a copy of the state, so a law that writes into it is judged
    on its torque alone; the message now also says that it wrote, which the student's own run
    stops at, whether the torque was right (pass) or not (the mistake is still named)."""

    def pd_torque(model, data, q_d, Kp, Kd):
        e = data.qpos
        e -= q_d  # writes into data.qpos
        return -Kp * e - Kd * data.qvel

    def pd_wrong(model, data, q_d, Kp, Kd):
        e = data.qpos
        e -= q_d
        return Kp * e - Kd * data.qvel  # and the spring term's sign is wrong

    def pd_right(model, data, q_d, Kp, Kd):
        return Kp * (q_d - data.qpos) - Kd * data.qvel

    note = "Note: pd_torque changed data.qpos of the state the check handed it; a controller must only read the state."
    result = check("p1_pd", {"pd_torque": pd_torque})
    assert (result.score, result.status) == (1.0, "pass") and note in result.message
    assert "e = q_d - data.qpos" in result.message and "No points are lost here" in result.message
    result = check("p1_pd", {"pd_torque": pd_wrong})
    assert result.score == 0 and "the spring term has the wrong sign" in result.message and note in result.message
    result = check("p1_pd", {"pd_torque": pd_right})
    assert result.score == 1 and "Note:" not in result.message

    def ct_joint_torque(model, data, q_d, Kp, Kd):  # right, and it writes into data.qvel
        qdot = data.qvel
        qdot *= -1.0
        return mass_matrix(model, data) @ (Kp * (q_d - data.qpos) + Kd * qdot) + bias_forces(data)

    result = check("p1_ct", {"ct_joint_torque": ct_joint_torque})
    assert result.score == 1 and "Note: ct_joint_torque changed data.qvel" in result.message


# --- what a student installs holds no answer ------------------------------------------------------------


def installed_modules():
    """Every module a student installs: all of labsupport except the instructor's tooling (which
    pyproject leaves out of the wheel)."""
    pyproject = (ROOT / "pyproject.toml").read_text(encoding="utf-8")
    assert '"labsupport.instructor' not in pyproject.split("[tool.setuptools]")[1].split("[tool.setuptools.")[0]
    names = ["labsupport"]
    for info in pkgutil.walk_packages(labsupport.__path__, "labsupport."):
        if not info.name.startswith(("labsupport.instructor", "labsupport.models")):
            names.append(info.name)
    return names


def ik_like(name: str) -> bool:
    lowered = name.lower()
    return "inverse" in lowered or lowered == "ik" or lowered.startswith("ik_") or "_ik" in lowered


def test_no_installed_function_puts_the_3r_arm_on_a_target():
    model = common.arm_model()
    rng = common.rng_for(7, "install")
    targets = [common.tip(model, common.draw_configuration(rng, elbow_up=bool(k % 2))) for k in range(6)]
    tried = []
    for module_name in installed_modules():
        module = importlib.import_module(module_name)
        for name, fn in inspect.getmembers(module, callable):
            if not ik_like(name) or getattr(fn, "__module__", "") != module_name:
                continue
            tried.append(f"{module_name}.{name}")
            for x in targets:
                for args in ((x,), (x, True), (x, False)):
                    try:
                        q = np.asarray(fn(*args), dtype=float)
                    except Exception:
                        continue
                    if q.shape == (3,) and np.all(np.isfinite(q)):
                        assert np.linalg.norm(tip_at(model, q) - x) > 1e-3, f"{module_name}.{name} solves the 3R IK"
    assert "labsupport.kinematics.planar_2r.inverse_kinematics" in tried
    assert not (ROOT / "labsupport" / "kinematics" / "spatial_3r.py").exists()
    assert labsupport.__name__ == "labsupport"


# --- what the messages say ---------------------------------------------------------------------------


def test_an_ik_with_one_wrong_branch_is_told_which_target_and_branch(master1):
    """The message names the first wrong solution's target and branch, once, without repeating
    the label; the same failure on every call (the function is missing) is said once."""
    right = master1["ik_3r"]

    def down_is_up(x, elbow_up=True):
        return right(x, elbow_up=True)

    result = grade("p1_ik", ik_3r=down_is_up)
    assert result.score == 0.5 and result.message.count("IK:") == 1, result
    n = problem1.N_TARGETS
    assert f"{n} of {2 * n} solutions are right. The first wrong one, target [" in result.message
    assert "elbow_up=False: the elbow-down call reaches the target, but with the elbow above" in result.message
    assert str(result).startswith(f"◐ [p1_ik] (50 % of this check's points) IK: {n} of {2 * n}")
    missing = grade("p1_ik")
    assert missing.message == "IK: ik_3r is not defined: run its cell (above) first, or restore it if it was deleted"
    number = grade("p1_ik", ik_3r=3)
    assert number.score == 0 and number.message == "IK: ik_3r should be a function, but it is of type int"


def test_an_ik_that_raises_on_one_branch_keeps_the_other_branchs_credit(master1):
    """The same error on every elbow-down call is not the same failure on every call: the five
    right elbow-up solutions still count."""
    right = master1["ik_3r"]

    def up_only(x, elbow_up=True):
        if not elbow_up:
            raise ValueError("only the elbow-up branch is written")
        return right(x, elbow_up=True)

    result = grade("p1_ik", ik_3r=up_only)
    n = problem1.N_TARGETS
    assert result.score == 0.5, result
    assert f"IK: {n} of {2 * n} solutions are right. The first wrong one, target [" in result.message
    assert "elbow_up=False: ik_3r raised ValueError: only the elbow-up branch is written" in result.message


def test_an_ik_that_hangs_on_one_branch_keeps_the_other_and_the_checks_time(master1):
    """Every elbow-up target is solved before the first elbow-down one, and after MAX_TIMEOUTS
    elbow-down calls that did not return no more are made: the elbow-up half counts, and a hung
    branch costs the check two call limits, not one per target (25 of them, past the check's
    budget, stopped the sandbox and cost the other checks their points)."""
    right, calls = master1["ik_3r"], []

    class HangsElbowDown(DirectProbe):
        def call(self, fname, *args, **kwargs):
            calls.append(kwargs["elbow_up"])
            if not kwargs["elbow_up"]:
                raise feedback.StudentTimeout("ik_3r did not return: it used too much CPU time")
            return super().call(fname, *args, **kwargs)

    result = problem1.check_ik(HangsElbowDown({"ik_3r": right}), PUBLIC_SEED)
    n = problem1.N_TARGETS
    assert calls == [True] * n + [False] * problem1.MAX_TIMEOUTS
    assert result.score == 0.5, result
    assert f"IK: {n} of {2 * n} solutions are right." in result.message
    assert f"The other {n - 2} elbow-down calls were not made (counted wrong)" in result.message


def test_a_computed_torque_that_inverts_the_mass_matrix_is_named(master1):
    def ct_inverse_mass(model, data, q_d, Kp, Kd):
        return np.linalg.solve(mass_matrix(model, data), Kp * (q_d - data.qpos) - Kd * data.qvel) + data.qfrc_bias

    result = grade("p1_ct", ct_joint_torque=ct_inverse_mass)
    assert result.score == 0.25 and "np.linalg.solve(M, v) is M⁻¹v" in result.message, result


def test_a_singular_matrix_from_a_scratch_data_without_kinematics_gets_the_hint(master2):
    """Forgetting mj_kinematics/mj_comPos on the scratch MjData leaves J(q_d) all zeros."""

    def no_kinematics(model, data, x_d, xd_d, xdd_d, Kp, Kd):
        scratch = mujoco.MjData(model)
        scratch.qpos[:] = master2["ik_3r"](x_d)
        J_d = site_jacobian(model, scratch, SITE)[:3]
        return np.linalg.solve(J_d, xd_d)

    result = grade("p2_ikct", ct_ik_joint_torque=no_kinematics)
    assert result.score == 0 and "raised LinAlgError: Singular matrix" in result.message, result
    assert "mujoco.mj_kinematics and mujoco.mj_comPos" in result.message


def test_a_slow_law_is_told_the_batch_graders_cpu_budget(monkeypatch, capsys):
    """The in-notebook check counts the CPU time of the student's calls and warns past half of
    what the batch grader allows per check; a quick law gets no note."""
    import labsupport.grading as grading

    def slow_pd(model, data, q_d, Kp, Kd):
        t0 = time.process_time()
        while time.process_time() - t0 < 0.05:
            pass
        return Kp * (q_d - data.qpos) - Kd * data.qvel

    monkeypatch.setattr(grading, "CHECK_CPU_SECONDS", 0.1)
    grading.check("p1_pd", {"pd_torque": slow_pd})
    out = capsys.readouterr().out
    assert out.startswith("✔ [p1_pd]") and "Note: your functions took 0.2" in out
    assert "s of CPU time in this check, more than the 0.1 s the batch grader allows there" in out
    grading.check("p1_pd", {"pd_torque": lambda model, data, q_d, Kp, Kd: Kp * (q_d - data.qpos) - Kd * data.qvel})
    assert "Note" not in capsys.readouterr().out


def test_a_slow_law_of_the_tracking_check_is_told_its_own_share(monkeypatch, capsys, master2):
    """The tracking check gives each of its two laws half of the check's CPU time, in the batch;
    the in-notebook note names the law and its half."""
    import labsupport.grading as grading

    def slow_os_ct(model, data, *args):
        t0 = time.process_time()
        while time.process_time() - t0 < 0.0004:
            pass
        return master2["ct_op_torque"](model, data, *args)

    monkeypatch.setattr(grading, "CHECK_CPU_SECONDS", 1.0)
    grading.check("p2_track", {**master2, "ct_op_torque": slow_os_ct})
    out = capsys.readouterr().out
    assert "Note: ct_op_torque took " in out and "more than the 0.5 s the batch grader allows there" in out, out


@pytest.mark.parametrize("problem", ["problem1", "problem2"])
def test_the_grader_runs_the_students_laws_with_the_problem_notebooks_own_settings(problem):
    """A student sees the runs of their notebook; the batch grades runs from the same start, with the
    same gains and the same circle. A setting changed in the notebook alone failed here with a bare
    `assert (300.0, 50.0, ...) == (400.0, 50.0, ...)`, one Problem at a time; each difference is
    named now, with the file to change, and assign refuses to write the student notebook."""
    spec = json.loads((ROOT / "tests" / "autograder" / f"{problem}.json").read_text())
    for path in (spec["master"], spec["student"]):
        nb = nbformat.read(str(ROOT / path), as_version=4)
        drift = settings_drift(nb, path)
        assert drift == [], drift


def test_assign_refuses_a_master_whose_settings_its_grader_does_not_share(tmp_path):
    """Kp_pd changed to 300 in the master alone graded every student's PD against 400 without a
    word; a circle changed in the master alone told a right IK that it missed the start."""
    master = nbformat.read(str(ROOT / "notebooks" / "masters" / "problem1_reaching.ipynb"), as_version=4)
    cell = next(c for c in master.cells if c.cell_type == "code" and c.source.startswith("q0 ="))
    cell.source = cell.source.replace("Kp_pd, Kd_pd = 400.0, 50.0", "Kp_pd, Kd_pd = 300.0, 50.0")
    (tmp_path / "notebooks" / "masters").mkdir(parents=True)
    nbformat.write(master, str(tmp_path / "notebooks" / "masters" / "problem1_reaching.ipynb"))
    with pytest.raises(assign.MasterError) as err:
        assign.outputs(tmp_path)
    said = str(err.value)
    assert "notebooks/masters/problem1_reaching.ipynb sets Kp_pd = 300.0" in said, said
    assert "labsupport/grading/problem1.py has KP_PD = 400.0" in said and "change both" in said, said


# --- drawn test states: margins, branches, and the tracking cases' promises ----------------------


def keeps_margins(x):
    """The margins of common.Margins, written out: tip 0.35..1.75 m from the shoulder, 0.35 m off
    the z axis, 0.1 m above the floor, pan angle and elbow-up shoulder angle 0.35 rad from ±π."""
    x = np.asarray(x, float)
    d, rho = np.linalg.norm(x - [0.0, 0.0, 1.0]), np.hypot(x[0], x[1])
    return (
        0.35 <= d <= 1.75
        and rho >= 0.35
        and x[2] >= 0.1
        and abs(np.arctan2(x[1], x[0])) <= np.pi - 0.35
        and np.arctan2(rho, x[2] - 1.0) <= np.pi - 0.35
    )


@pytest.mark.parametrize(
    ("x", "safe"),
    [
        ([1.0, 0.2, 1.3], True),
        ([-0.6, -0.5, 0.5], True),
        ([1.8, 0.0, 1.0], False),  # out of reach
        ([1.7, 0.0, 1.0], True),
        ([0.3, 0.0, 1.5], False),  # near the z axis
        ([0.4, 0.0, 1.5], True),
        ([1.0, 0.0, 0.05], False),  # below the floor margin
        ([1.0, 0.0, 0.15], True),
        ([np.cos(3.0), np.sin(3.0), 1.0], False),  # pan angle near ±π
        ([np.cos(-3.0), np.sin(-3.0), 1.0], False),
        ([np.cos(2.6), np.sin(2.6), 1.0], True),
        ([np.cos(-2.6), np.sin(-2.6), 1.0], True),
    ],
)
def test_safe_points_keep_each_margin(x, safe):
    assert bool(common.safe_point(x)) == safe and bool(keeps_margins(x)) == safe


def test_drawn_configurations_face_their_tip_on_the_asked_branch_within_the_margins():
    """draw_configuration: the tip keeps the margins, q1 is the tip's azimuth, the angles lie
    away from ±π (q1, q2), the elbow is on the asked branch (elbow up: cos q3 > 0), and the elbow angle
    θ (q3 = θ − π/2 elbow up, −θ − π/2 elbow down) spreads over (0, π)."""
    model, rng = common.arm_model(), np.random.default_rng(5)
    thetas = {True: [], False: []}
    for up in (True, False) * 60:
        q = common.draw_configuration(rng, elbow_up=up)
        x = tip_at(model, q)
        assert keeps_margins(x), (q, x)
        assert abs(q[0] - np.arctan2(x[1], x[0])) < 1e-9, q
        assert abs(q[0]) <= np.pi - 0.35 and -1.2 <= q[1] <= np.pi - 0.35, q
        assert (np.cos(q[2]) > 0) == up and (common.elbow_height(model, q) > 0) == up, q
        thetas[up].append(q[2] + np.pi / 2 if up else -q[2] - np.pi / 2)
    for up, th in thetas.items():
        assert 0 < min(th) and max(th) < np.pi and max(th) - min(th) > 1.0, (up, min(th), max(th))


@pytest.mark.parametrize("still", [None, "arm", "reference"])
def test_tracking_cases_are_consecutive_states_about_a_smooth_reference(still):
    """tracking_cases: LEAD_IN + 1 states one control step apart; a quadratic joint reference
    (q̇_d its derivative, q̈_d constant) about an elbow-up configuration within the margins, and
    its Cartesian image; the arm near the reference, its velocity that of its positions; gains
    in their ranges; the still case at rest (the arm, or the reference with the arm moving)."""
    model = common.arm_model()
    dt = model.opt.timestep
    cases = common.tracking_cases(PUBLIC_SEED, "p2_osct", still=still)
    assert len(cases) == 4 + (still is not None)
    n = common.LEAD_IN + 1
    for k, case in enumerate(cases):
        assert case.still == (still is not None and k == 0)
        assert len(case.states) == n and all(a.shape == (n, 3) for a in (case.q_d, case.qd_d, case.qdd_d, case.x_d))
        t = np.array([s.t for s in case.states])
        q = np.array([s.q for s in case.states])
        qdot = np.array([s.qdot for s in case.states])
        assert np.allclose(np.diff(t), dt) and 0.5 <= t[-1] <= 5.0, t
        assert np.allclose(case.qdd_d, case.qdd_d[0]) and np.all(np.abs(case.qdd_d) <= 3.0)
        assert np.allclose(np.diff(case.qd_d, axis=0), dt * case.qdd_d[1:])
        assert np.allclose(np.diff(case.q_d, axis=0), dt * (case.qd_d[:-1] + case.qd_d[1:]) / 2)
        assert np.all(np.abs(case.qd_d[-1]) <= 1.5)
        x_end = tip_at(model, case.q_d[-1])
        assert keeps_margins(x_end) and np.cos(case.q_d[-1][2]) > 0
        for j in range(n):
            J, jdq = jacobian_at(model, case.q_d[j], case.qd_d[j])
            assert np.allclose(case.x_d[j], tip_at(model, case.q_d[j]))
            assert np.allclose(case.xd_d[j], J @ case.qd_d[j])
            assert np.allclose(case.xdd_d[j], J @ case.qdd_d[j] + jdq)
        assert np.all(np.abs(q - case.q_d) < 0.05 + 0.3 * common.LEAD_IN * dt + 1e-12)
        assert np.allclose(np.diff(q, axis=0) / dt, (qdot[:-1] + qdot[1:]) / 2, atol=1e-9)
        assert 30.0 <= case.Kp <= 90.0 and 8.0 <= case.Kd <= 20.0
        if case.still and still == "arm":
            assert np.all(qdot == 0) and np.all(q == q[-1])
            continue
        assert np.all(np.abs(qdot - case.qd_d) <= 0.3)
        if case.still:
            assert np.all(case.qd_d[-1] == 0) and np.linalg.norm(qdot[-1]) > 0
        else:
            assert np.linalg.norm(case.qd_d[-1]) > 0 and np.linalg.norm(qdot[-1]) > 0


def test_an_unknown_still_is_refused():
    with pytest.raises(ValueError, match="still must be"):
        common.tracking_cases(PUBLIC_SEED, "p2_osct", still="both")


def test_the_over_the_top_and_mirrored_poses_reach_the_same_tip():
    """over_the_top: the same tip with the pan half a turn round, angles in (−π, π];
    mirror_elbow: the same tip on the other elbow branch."""
    model, rng = common.arm_model(), np.random.default_rng(3)
    for _ in range(10):
        q = common.draw_configuration(rng, elbow_up=True)
        x, back, mirrored = tip_at(model, q), common.over_the_top(q), common.mirror_elbow(q)
        assert np.allclose(tip_at(model, back), x, atol=1e-9) and np.allclose(tip_at(model, mirrored), x, atol=1e-9)
        assert common.pan_turned_round(back, x) and np.all(np.abs(back) <= np.pi), back
        assert common.elbow_height(model, mirrored) < 0 < common.elbow_height(model, back)


def test_a_pan_is_turned_round_only_past_a_quarter_turn_from_the_target():
    x = [1.0, 0.0, 1.0]
    for q1, turned in ((0.0, False), (1.2, False), (-1.2, False), (2.0, True), (-2.0, True), (np.pi, True)):
        assert common.pan_turned_round([q1, 0.3, 0.2], x) == turned, q1


def test_a_jdot_off_by_more_than_its_own_size_scores_nothing():
    """Half credit for another J̇q̇ holds only while it is closer to MuJoCo's than zero is
    (ε < 1): a torque implying −J̇q̇/2 (ε = 1.5) scores 0 with both values shown."""

    def jdot_half_reversed(model, data, *ref):
        return os_law(model, data, *ref, jdq=-0.5 * site_jdot_qdot(model, data, SITE)[:3])

    result = grade("p2_osct", ct_op_torque=jdot_half_reversed)
    assert result.score == 0 and "expected [" in result.message, result


# --- Problem 2: the start, the branch a run leaves, a law handed in for the other --------------


@pytest.mark.parametrize("azimuth", [-0.3, 2.7, -2.7, 0.6])
def test_a_run_is_told_its_branch_in_every_quadrant(azimuth):
    """The pan is measured from the target's own azimuth atan2(y, x) wherever the target lies: a
    pan a full turn round is named as such, and an arm that faces its target, elbow down, is
    told it is elbow down, not that its pan swung round."""
    model, rng = common.arm_model(), np.random.default_rng(11)
    front = common.draw_configuration(rng, elbow_up=True)
    front[0] = azimuth
    x = tip_at(model, front)
    assert abs(np.arctan2(x[1], x[0]) - azimuth) < 1e-9  # the arm faces its tip
    full_turn = front + [2 * np.pi * np.sign(azimuth), 0.0, 0.0]
    for other, words in (
        (common.mirror_elbow(front), "at t = 0.10 s the elbow was below the shoulder-to-tip line"),
        (full_turn, "by t = 0.10 s the pan had swung round"),
    ):
        log = posed_log(model, [front, other], [0.0, 0.1])
        assert words in problem2._left_the_branch(model, log, every=1)


def test_a_tracking_run_reads_its_poses_from_the_first_and_at_least_every_tenth():
    """By default a run's logged poses are read from the first one on, at least every tenth: an
    arm off its branch from the start is told so at t = 0, and one that leaves it within the
    first ten logged steps is told within ten steps of leaving."""
    model, rng = common.arm_model(), np.random.default_rng(11)
    front = common.draw_configuration(rng, elbow_up=True)
    down = common.mirror_elbow(front)
    t = 0.01 * np.arange(15)
    for leave in (0, 5):
        said = problem2._left_the_branch(
            model, posed_log(model, [front if k < leave else down for k in range(len(t))], t)
        )
        assert said is not None and "the elbow was below the shoulder-to-tip line" in said, said
        when = float(said.split("at t = ")[1].split(" s")[0])
        assert t[leave] <= when < t[leave] + 0.1 - 1e-9, said
        if leave == 0:
            assert when == 0.0, said


@pytest.mark.parametrize("fname", ["ct_op_torque", "ct_ik_joint_torque"])
@pytest.mark.parametrize("share, copied", [(0.0, True), (0.05, True), (0.15, False), (0.5, False), (1.0, False)])
def test_a_law_is_taken_for_the_other_only_within_a_tenth_of_their_difference(fname, share, copied):
    """A law whose torque lies a share of the way from the other law's torque to its own is
    taken for the other law (its run not counted) below a tenth of the way, and counted as its
    own beyond; the note says by how much the two laws differ at that test state."""

    def law(model, data, *ref):
        os_tau, ik_tau = os_law(model, data, *ref), ik_ct_law(model, data, *ref)
        own, other = (os_tau, ik_tau) if fname == "ct_op_torque" else (ik_tau, os_tau)
        return other + share * (own - other)

    said = problem2._other_laws_torque(DirectProbe({fname: law}), PUBLIC_SEED, fname)
    assert (said is not None) == copied, said
    if copied:
        other, own = ("IK + joint CT", "OS-CT") if fname == "ct_op_torque" else ("OS-CT", "IK + joint CT")
        assert f"{fname} returns {other}'s torque, not {own}'s" in said, said
        assert 0 < int(said.split("differ by ")[1].split(" %")[0]) < 100, said  # laws that both track differ little


@pytest.mark.parametrize(
    "fname, check, still", [("ct_op_torque", "p2_osct", "arm"), ("ct_ik_joint_torque", "p2_ikct", "reference")]
)
def test_a_copied_law_is_judged_where_the_two_laws_differ_most(fname, check, still):
    """A law handed in for the other is found at the test state of its own check where OS-CT and
    IK + joint CT differ most, and the note gives their difference there, relative to the law's."""
    model = common.arm_model()

    def own_and_other(case):
        state = case.states[-1]
        data = common.data_at(model, state.q, state.qdot, state.t)
        ref = (case.x_d[-1], case.xd_d[-1], case.xdd_d[-1], case.Kp, case.Kd)
        os_tau, ik_tau = os_law(model, data, *ref), ik_ct_law(model, data, *ref)
        return (os_tau, ik_tau) if fname == "ct_op_torque" else (ik_tau, os_tau)

    pairs = [own_and_other(c) for c in common.tracking_cases(PUBLIC_SEED, check, still=still)]
    own, other = max(pairs, key=lambda p: np.linalg.norm(p[0] - p[1]))
    percent = 100 * np.linalg.norm(own - other) / np.linalg.norm(own)
    copy = ik_ct_law if fname == "ct_op_torque" else os_law
    said = problem2._other_laws_torque(DirectProbe({fname: copy}), PUBLIC_SEED, fname)
    assert said is not None and abs(int(said.split("differ by ")[1].split(" %")[0]) - percent) <= 1, (said, percent)


@pytest.mark.parametrize("seed", [PUBLIC_SEED, OTHER_SEED])
def test_the_tracking_note_gives_the_circle_to_the_millimetre(seed):
    """The tracking note names the seeded circle: its radius, centre and normal to three decimals."""
    center, radius, normal, *_ = problem2.tracking_circle(seed)
    result = grade("p2_track", seed)
    shown = re.search(r"radius ([\d.]+) m about \[([^\]]*)\], normal \[([^\]]*)\]", result.message)
    assert shown is not None, result.message
    assert shown.group(1) == f"{radius:.3f}"
    for text, values in ((shown.group(2), center), (shown.group(3), normal)):
        numbers = text.split()
        assert [float(v) for v in numbers] == [round(float(v), 3) for v in values], result.message
        assert all(len(v.split(".")[1]) <= 3 for v in numbers if "." in v), result.message


def test_tracking_laws_that_raise_fail_and_are_not_taken_for_unwritten_ones():
    """Two tracking laws that both raise score nothing on p2_track and the check is failed, with the
    error named: it is not reported as not implemented yet, which only a law still left as its
    TODO is."""

    def broken(model, data, *ref):
        raise ValueError("a bug in the student's law")

    result = grade("p2_track", ct_op_torque=broken, ct_ik_joint_torque=broken)
    assert result.score == 0 and result.status == FAIL, result
    assert "a bug in the student's law" in result.message, result


@pytest.mark.parametrize("check", ["p2_start", "p2_track"])
def test_checks_that_name_no_mistakes_list_none(check):
    """The start and tracking checks name no mistakes: their catalogue and their rubric rows are empty."""
    from labsupport.instructor.rubric import mistake_credits

    assert problem2.named_mistakes(check, PUBLIC_SEED) == {}
    assert mistake_credits(check) == []


def test_an_ik_a_full_turn_off_is_told_to_take_the_elbow_up_branch_only_when_elbow_down(master2):
    """An IK answering with an angle a full turn away is told to wrap its angles; only one that also
    answers elbow down is told to take the elbow-up branch."""
    ik = master2["ik_3r"]
    turn = np.array([0.0, 0.0, 2 * np.pi])
    for elbow_up, branch in ((True, "elbow-up"), (False, "elbow-down")):

        def ct_ik_joint_torque(model, data, *ref, branch_up=elbow_up):
            return ik_ct_law(model, data, *ref, ik=lambda x, elbow_up=True: ik(x, branch_up) + turn)

        result = grade("p2_ikct", ct_ik_joint_torque=ct_ik_joint_torque)
        assert f"the {branch} pose with an angle a full turn (2π) away" in result.message, result
        assert "wrap the IK's angles into (−π, π]" in result.message, result
        assert ("take the elbow-up branch" in result.message) == (not elbow_up), result.message


def test_a_start_that_is_not_a_joint_vector_is_failed_with_the_reason():
    """A q0_traj of the wrong shape scores 0 on p2_start, failed, and the note gives the shape."""
    result = grade("p2_start", q0_traj=np.zeros(2))
    assert result.status == FAIL and result.score == 0, result
    assert "has shape (2,), expected (3,)" in result.message, result


def test_a_start_in_degrees_is_shown_to_four_decimals(master2):
    """A q0_traj given in degrees is told so, and the note shows it to four decimals."""
    q0 = np.degrees(master2["ik_3r"](problem2.reference(0.0).pos, elbow_up=True))
    result = grade("p2_start", q0_traj=q0)
    assert result.score == 0 and "is in degrees; MuJoCo works in radians" in result.message, result
    shown = re.search(r"q0_traj = \[([^\]]*)\] is in degrees", result.message)
    assert shown is not None, result.message
    numbers = shown.group(1).split()
    assert [float(v) for v in numbers] == [round(float(v), 4) for v in q0], result.message


def test_an_elbow_down_start_keeps_half_and_is_told_so(master2):
    """A q0_traj on the start point but elbow down keeps half of p2_start, and the note says the
    Problem starts elbow up."""
    q0 = master2["ik_3r"](problem2.reference(0.0).pos, elbow_up=False)
    result = grade("p2_start", q0_traj=q0)
    assert result.score == 0.5 and "but elbow down" in result.message and "elbow_up=True" in result.message, result


def test_a_start_typed_in_counts_only_where_the_students_own_ik_gives_it(master2):
    """q0_traj is TODO 2's answer, the IK of x0; typed in as numbers (copied, or printed by an IK the
    Problem does not allow) it scored full marks with TODO 1 left empty. It now counts where the
    student's own ik_3r also reaches x0, by whatever method; a borrowed ik_3r is named."""
    x0 = problem2.reference(0.0).pos
    q0 = master2["ik_3r"](x0, elbow_up=True)
    zeros_miss = np.linalg.norm(common.tip(common.arm_model(), np.zeros(3)) - x0)
    for ik, words in (
        (lambda x, elbow_up=True: None, "but ik_3r is not implemented yet"),
        (None, "but ik_3r is not defined"),
        (lambda x, elbow_up=True: np.zeros(3), f"but your ik_3r(x0) puts it {zeros_miss:.4g} m from x0"),
        (borrowed_ik, "planar_2r.inverse_kinematics is off limits"),
    ):
        result = grade("p2_start", q0_traj=q0, **({} if ik is None else {"ik_3r": ik}))
        assert result.score == 0 and words in result.message, result
        assert "the start counts when your own IK computes it: q0_traj = ik_3r(x0)" in result.message, result
    assert grade("p2_start", q0_traj=q0, ik_3r=newton_ik).score == 1  # a numerical IK of one's own
    # q0_traj's cell failed on the borrowed IK: the note says why, not only that q0_traj is missing
    result = grade("p2_start", ik_3r=borrowed_ik)
    assert result.score == 0 and "planar_2r.inverse_kinematics is off limits" in result.message, result


def borrowed_ik(x, elbow_up=True):
    """Problem 2's IK through Task 3's planar IK, which the Problem does not allow."""
    return np.array([np.arctan2(x[1], x[0]), *planar_ik(np.array([np.hypot(x[0], x[1]), x[2] - 0.1]))])


def test_a_start_off_the_circle_is_told_how_far():
    """A q0_traj whose tip is off the start point scores 0 on p2_start, and the note says how far
    off it is and which point it should reach."""
    result = grade("p2_start", q0_traj=np.zeros(3))
    assert result.status == FAIL and result.score == 0, result
    assert f"m from the circle's start point {problem2.reference(0.0).pos}; solve the IK" in result.message, result


def test_a_run_that_leaves_its_branch_asks_about_the_ik_only_where_the_ik_left_it():
    """Where the arm has left its branch, the student's ik_3r decides the question: an IK that
    gives that same other branch there is asked whether it switches; one that gives the elbow-up
    pose facing the target is not, and the torques are blamed instead."""
    model, rng = common.arm_model(), np.random.default_rng(11)
    front = common.draw_configuration(rng, elbow_up=True)
    down = common.mirror_elbow(front)
    log = posed_log(model, [front, down], [0.0, 0.1])
    for answer, words in (
        (down, "does the IK switch to it there?"),
        (common.over_the_top(front), "does the IK switch to it there?"),
        (front, "either the law asks its IK for another branch (ik_3r(x, elbow_up=False), say), or its torques"),
    ):
        said = problem2._left_the_branch(model, log, every=1, ik=lambda x, answer=answer: answer)
        assert said.startswith("at t = 0.10 s the elbow was below") and words in said, said


def test_a_mujoco_call_with_wrong_arguments_is_told_the_call_it_takes():
    """MuJoCo's "incompatible function arguments" dumps its binding's types (typing.Annotated[...],
    cut short in the batch's notes); the check says the call the function takes instead, and a
    site given by name where MuJoCo takes its id is told how to get the id."""

    def ct_op_torque(model, data, x_d, xd_d, xdd_d, Kp, Kd):
        jacp = np.zeros((3, model.nv))
        mujoco.mj_jacSite(model, data, jacp, None, "end_effector")
        return np.zeros(3)

    result = grade("p2_osct", ct_op_torque=ct_op_torque)
    assert result.score == 0
    assert (
        "ct_op_torque raised TypeError: mujoco.mj_jacSite does not take the arguments it was given: it takes "
        "mj_jacSite(m: model, d: data, jacp: float64 array or None, jacr: float64 array or None, site: int)"
    ) in result.message
    assert 'model.site("end_effector").id' in result.message and "typing" not in result.message
    cut = feedback.raised_text("f", "TypeError: mj_mulM(): incompatible function arguments. The following ar")
    assert cut.endswith(
        "mj_mulM(m: model, d: data, res: float64 array, vec: float64 array), each array a "
        "C-contiguous float64 NumPy array"
    )
    assert feedback.mujoco_arguments_text("TypeError: f(): incompatible function arguments") is None


def test_a_function_whose_cell_has_a_syntax_error_is_told_so_in_the_notebook():
    """In the notebook, a law whose cell did not compile was reported "not defined: run its cell
    first", which the student had done; the batch named the syntax error. The notebook's check
    now reads it from IPython's input history too."""
    from labsupport.grading import feedback

    broken = "import numpy as np\n\ndef pd_torque(model, data, q_d, Kp, Kd)\n    return Kp * (q_d - data.qpos)\n"
    probe = feedback.DirectProbe({"In": ["", broken, "check('p1_pd', globals())"]})
    with pytest.raises(feedback.StudentError) as err:
        probe.call("pd_torque")
    assert str(err.value).startswith("pd_torque is not defined: the cell that defines it raised SyntaxError: ")
    assert "(line 3 of the cell); fix it and run that cell again" in str(err.value)
    never_run = feedback.DirectProbe({"In": ["", "x = 1"]})
    with pytest.raises(feedback.StudentError, match="not defined: run its cell \\(above\\) first"):
        never_run.call("pd_torque")


def test_swapped_gains_are_named_in_pd_and_ct(master1):
    """A law with Kp and Kd exchanged was told only the numbers it got and expected."""
    pd, ct = master1["pd_torque"], master1["ct_joint_torque"]
    for name, law in (("p1_pd", pd), ("p1_ct", ct)):
        swapped = lambda model, data, q_d, Kp, Kd, law=law: law(model, data, q_d, Kd, Kp)  # noqa: E731
        result = grade(name, **{law.__name__: swapped})
        assert result.score == 0.5 and "Kp and Kd are swapped" in result.message, result


def test_an_ik_ct_whose_ik_is_not_filled_in_is_told_to_do_todo_1():
    """With ik_3r still the TODO (it returns None), the IK + joint CT raised a TypeError about
    NoneType, and the check said only that; it now says that ik_3r returned None, and why."""
    notebook = namespace_of(ROOT / "notebooks" / "masters" / "problem2_tracking.ipynb")
    notebook["ik_3r"] = lambda x, elbow_up=True: None  # the law calls the notebook's ik_3r
    result = grade("p2_ikct", **notebook)
    assert result.score == 0 and "NoneType" in result.message
    assert "ik_3r returned None there: check TODO 1 first" in result.message, result


def test_a_law_that_returns_none_at_some_states_is_told_it_has_a_path_without_a_return(master1):
    """A law that returns None at rest and a torque elsewhere was told "not implemented yet"; it
    is now told that a path through it returns nothing. One that returns None everywhere is still
    not implemented."""
    pd = master1["pd_torque"]

    def pd_none_at_first(model, data, q_d, Kp, Kd):
        if data.time == 0:  # the first test state, as a run's start
            return None
        return pd(model, data, q_d, Kp, Kd)

    result = grade("p1_pd", pd_torque=pd_none_at_first)
    assert result.score == 0 and result.status != "not implemented yet"
    assert "pd_torque returned None at one test state and a value at another" in result.message
    notebook = namespace_of(ROOT / "notebooks" / "masters" / "problem2_tracking.ipynb")
    os_ct = notebook["ct_op_torque"]

    def none_at_rest(model, data, *args):
        return None if not data.qvel.any() else os_ct(model, data, *args)

    result = grade("p2_osct", ct_op_torque=none_at_rest)
    assert result.score == 0 and "ct_op_torque returned None at one test state and a value at another" in result.message
    assert grade("p2_osct", ct_op_torque=lambda *args: None).status == "not implemented yet"


@pytest.mark.parametrize("check, name", [("p1_pd", "pd_torque"), ("p1_ct", "ct_joint_torque")])
def test_a_joint_law_with_a_path_only_rest_takes_is_caught_by_its_formula_check(master1, check, name):
    """Problem 1's formula checks drew every state with a velocity, so a law that returns nothing
    while q̇ = 0 passed them, and its run, which starts at rest, was then told "not implemented
    yet". A last test state at rest catches it in the formula check; a law that is only wrong
    where the arm moves is still caught where it moves."""
    law = master1[name]

    def none_at_rest(model, data, q_d, Kp, Kd):
        if data.qvel.any():
            return law(model, data, q_d, Kp, Kd)

    result = grade(check, **{name: none_at_rest})
    assert result.score == 0 and f"{name} returned None at one test state and a value at another" in result.message
    assert grade(check, **{name: law}).score == 1


def test_a_run_toward_a_target_in_degrees_is_told_the_degrees_not_the_gains(master1, capsys, tmp_path, monkeypatch):
    """Problem 1's right laws, handed the lab's target in degrees, run away within a few steps;
    the notebook's run was told to lower the gains or check the signs of the law. It now names
    the angles beyond 2π and radians. The same laws toward the target in radians are not told so."""
    from labsupport.grading import as_controller, attempt
    from labsupport.plants import load_model
    from labsupport.sim import simulate

    monkeypatch.chdir(tmp_path)
    model, data = load_model("spatial_3r")
    for name, gains in (
        ("pd_torque", (problem1.KP_PD, problem1.KD_PD)),
        ("ct_joint_torque", (problem1.KP_CT, problem1.KD_CT)),
    ):
        ctrl = as_controller(master1[name], np.degrees(master1["q_des"]), *gains)
        assert attempt("run", lambda ctrl=ctrl: simulate(model, data, ctrl, 1.0, q0=problem1.Q0), ctrl, model) is None
        said = capsys.readouterr().out
        assert "diverged" in said and "has angles beyond 2π: are they in degrees?" in said and "np.radians" in said
        assert "Lower the gains" not in said
    assert stability.target_in_degrees(master1["pd_torque"], (master1["q_des"], problem1.KP_PD, problem1.KD_PD)) is None
    x_far = np.array([10.0, 0.0, 0.0])  # a Cartesian target is not angles, however far
    assert stability.target_in_degrees(lambda model, data, x_d, Kp, Kd: None, (x_far, 1.0, 1.0)) is None


def test_an_ik_that_never_returns_is_said_as_it_happens_and_named_in_the_cpu_note(monkeypatch, capsys):
    """An IK that loops for ever kept the check silent for 40 s of CPU time (two calls a branch,
    10 s each), then advised "a closed-form IK instead of an optimiser". Each stopped call is now
    said at once, and the note points at the loop that never ends."""
    import labsupport.grading as grading

    monkeypatch.setattr(feedback, "CALL_CPU_SECONDS", 0.05)
    monkeypatch.setattr(grading, "CALL_CPU_SECONDS", 0.05)
    monkeypatch.setattr(grading, "CHECK_CPU_SECONDS", 0.3)

    def ik_3r(x, elbow_up=True):
        while True:
            pass

    grading.check("p1_ik", {"ik_3r": ik_3r})
    lines = capsys.readouterr().out.splitlines()
    assert lines[0] == (
        "  … ik_3r was stopped after 0.05 s of CPU time without returning; the check goes on (a loop that never "
        "ends makes it wait this long at each call it tries)."
    )
    assert lines[1:4] == [f"  … ik_3r stopped again ({n} calls so far)." for n in (2, 3, 4)]
    assert lines[4].startswith("✘ [p1_ik] IK: 0 of 50 solutions are right.")
    assert "4 of the calls were stopped at the 0.05 s one call may use: find the loop that never ends" in lines[5]
    assert "closed-form IK" not in lines[5]


def test_an_ik_that_never_returns_does_not_hang_the_run_cell(monkeypatch, capsys):
    """Problem 1's run cell, ``attempt("IK", lambda: ik_3r(target_pos), joints=3)``, spun for ever
    on an IK that never returns; a kernel interrupt then left ``logs`` and ``q_des`` undefined for
    the cells below. It now gives up after the CPU time one call of the checks may use. In the
    batch sandbox, which times each cell with the same timer, it leaves that timer alone."""
    import signal

    import labsupport.grading as grading

    monkeypatch.setattr(grading, "CALL_CPU_SECONDS", 0.05)

    def ik_3r(x, elbow_up=True):
        while True:
            pass

    assert grading.attempt("IK", lambda: ik_3r(None), joints=3) is None
    assert capsys.readouterr().out.startswith("IK: skipped, it did not return within 0.05 s of CPU time")

    monkeypatch.setenv(grading.BATCH_ENV, "1")
    previous = signal.signal(signal.SIGPROF, lambda *_: None)
    try:
        signal.setitimer(signal.ITIMER_PROF, 100.0)
        assert grading.attempt("IK", lambda: np.zeros(3), joints=3).shape == (3,)
        assert signal.getitimer(signal.ITIMER_PROF)[0] > 99.0  # still the cell's own timer
    finally:
        signal.setitimer(signal.ITIMER_PROF, 0)
        signal.signal(signal.SIGPROF, previous)


def test_an_ik_that_writes_into_its_target_keeps_its_points_and_is_told_so(master1, capsys):
    """An IK working in place on its target (``x[2] -= L1``) got ✔, then the notebook's run cell,
    which hands it the notebook's own target_pos, moved that target 1 m down, and the runs
    reported errors of a metre with every check passed. The check now says so; a law that works
    in place on its q_d (run on copies, grading.copies) gets no such note."""
    ik = master1["ik_3r"]

    def grade(name, **functions):  # with the notes check() adds
        probe = DirectProbe(functions)
        return feedback.noting_writes(registry()[name](probe, PUBLIC_SEED), probe)

    def ik_in_place(x, elbow_up=True):
        x = np.asarray(x, dtype=float)  # the caller's array itself
        x[2] -= 1.0
        return ik(x + [0.0, 0.0, 1.0], elbow_up)

    result = grade("p1_ik", ik_3r=ik_in_place)
    assert result.score == 1.0 and "Note: ik_3r changed the array it was handed as x" in result.message, result
    assert "Note" not in grade("p1_ik", ik_3r=ik).message

    def pd_in_place(model, data, q_d, Kp, Kd):
        q_d -= data.qpos
        return Kp * q_d - Kd * data.qvel

    result = grade("p1_pd", pd_torque=pd_in_place)
    assert result.score == 1.0 and "Note" not in result.message, result


def test_a_law_that_reads_the_notebooks_circle_is_told_to_use_its_arguments(master2):
    """An OS-CT that tracks ``reference(data.time)``, the notebook's circle, in place of the x_d,
    ẋ_d, ẍ_d it is handed ran perfectly in the notebook; its check blamed J̇q̇, and the tracking
    check "state your law keeps between calls". Both now name the notebook's reference."""

    def on_notebook_circle(law):
        def reads_notebook(model, data, x_d, xd_d, xdd_d, Kp, Kd):
            r = circle_3d(data.time, problem2.CENTER, problem2.RADIUS, problem2.NORMAL, problem2.FREQUENCY)
            return law(model, data, r.pos, r.vel, r.acc, Kp, Kd)

        return reads_notebook

    os_nb = on_notebook_circle(master2["ct_op_torque"])
    result = grade("p2_osct", ct_op_torque=os_nb)
    assert result.score == 0.5 and "with the notebook's reference, reference(data.time), in place of" in result.message
    assert "J̇" not in result.message, result
    laws = {name: master2[name] for name in ("ik_3r", "ct_op_torque", "ct_ik_joint_torque")}
    result = grade("p2_track", **{**laws, "ct_ik_joint_torque": on_notebook_circle(master2["ct_ik_joint_torque"])})
    assert result.score == 0.5, result
    assert "IK+JS-CT: RMS error" in result.message and problem2.NOTEBOOK_CIRCLE in result.message, result
    assert "state your law keeps" not in result.message, result


def test_the_angular_rows_of_the_jacobian_are_named_by_the_singular_hint(master2):
    """``site_jacobian(...)[3:]``, the angular rows, is singular on this arm (its pitch axes are
    parallel). The hint listed the wrong point and a scratch data without kinematics, not rows."""

    def angular_rows(model, data, x_d, xd_d, xdd_d, Kp, Kd):
        J = site_jacobian(model, data, SITE)[3:]
        x = data.site(SITE).xpos
        a = xdd_d + Kd * (xd_d - J @ data.qvel) + Kp * (x_d - x) - site_jdot_qdot(model, data, SITE)[:3]
        return mass_matrix(model, data) @ np.linalg.solve(J, a) + bias_forces(data)

    result = grade("p2_osct", ct_op_torque=angular_rows)
    assert result.score == 0 and "Singular matrix" in result.message, result
    assert ANGULAR_ROWS in result.message, result


def test_an_ik_on_another_branch_is_shown_by_the_ik_ct_check(master2, monkeypatch):
    """A numerical IK that wanders off (over the top, elbow down and a turn off was such a case,
    until that branch was named too; here a pose beside the target, which no named mistake
    covers) gave only "the torque differs … check q_d = IK(x_d)". The check now shows what the
    student's IK gives beside the elbow-up answer."""
    ik = master2["ik_3r"]

    def wandering(x, elbow_up=True):  # stopped short of the target
        return ik(x, elbow_up) + np.array([0.0, 0.05, -0.03])

    monkeypatch.setitem(master2, "ik_3r", wandering)  # the law's own IK too: it calls ik_3r
    result = grade("p2_ikct", ik_3r=wandering, ct_ik_joint_torque=master2["ct_ik_joint_torque"])
    assert result.score == 0 and "the torque differs from IK + joint CT" in result.message, result
    shown = r"At this x_d your ik_3r\(x_d, elbow_up=True\) gives q = \[.*\], where the elbow-up IK"
    assert re.search(shown, result.message), result
    monkeypatch.setitem(master2, "ik_3r", ik)
    assert "At this x_d" not in grade("p2_ikct", ik_3r=ik, ct_ik_joint_torque=master2["ct_ik_joint_torque"]).message


def test_a_run_that_asked_for_an_astronomical_torque_is_sent_to_its_matrices(capsys):
    """A law solving with the Jacobian's angular rows asked for torques of 1e16 N·m; the run's
    message said "Lower the gains, clip the torque, or check the signs". Past 1e6 N·m (the arm's
    weight takes at most 12.3 N·m to hold) it now points at a singular solve; an unstable law of sensible
    torques keeps the old words. A law that solves with the angular rows at a pose where they
    are exactly singular is told about the rows by the loop itself."""
    from labsupport.grading import as_controller, attempt
    from labsupport.plants import load_model
    from labsupport.sim import simulate

    model, data = load_model("spatial_3r")
    q0 = np.array([0.0, 0.5, -0.5])

    def near_singular(model, data, q_d, Kp, Kd):
        return np.full(3, 8.3e16)

    def wrong_sign(model, data, q_d, Kp, Kd):
        return -Kp * (q_d - data.qpos) + Kd * data.qvel + bias_forces(data)

    said = {}
    for law in (near_singular, wrong_sign):
        ctrl = as_controller(law, np.zeros(3), 400.0, 50.0)
        assert attempt("PD", partial(simulate, model, data, ctrl, 2.0, q0=q0), ctrl, model) is None
        said[law.__name__] = capsys.readouterr().out
    assert "The law asked for torques of up to 8.3e+16 N·m: a solve with a singular" in said["near_singular"]
    assert ANGULAR_ROWS in said["near_singular"], said
    assert "asked for torques of up to" not in said["wrong_sign"] and "diverged" in said["wrong_sign"], said

    def angular_rows(model, data, q_d, Kp, Kd):
        J = site_jacobian(model, data, SITE)[3:]
        return mass_matrix(model, data) @ np.linalg.solve(J, Kp * (q_d - data.qpos)) + bias_forces(data)

    ctrl = as_controller(angular_rows, np.zeros(3), 400.0, 50.0)
    assert attempt("CT", partial(simulate, model, data, ctrl, 1.0, q0=q0), ctrl, model) is None
    assert f"the wrong rows of the site's Jacobian ({ANGULAR_ROWS})" in capsys.readouterr().out


def test_a_value_whose_cell_stopped_before_setting_it_is_told_so():
    """``x0 = reference(0.0)`` followed by an error left ``q0_traj`` unset although its cell ran;
    the check said "run its cell (above) first". It now says that the cell ran and stopped
    before setting it. A value whose cell never ran keeps the old words."""
    ran = {"In": ["", "x0 = reference(0.0)\nq0_traj = ik_3r(x0.pos)  # raised: x0 has no .pos\n"]}
    result = grade("p2_start", **ran)
    assert "q0_traj is not defined: the cell that sets it ran, but stopped at an error" in result.message, result
    result = grade("p2_start", In=["", "print(1)"])
    assert "q0_traj is not defined: run its cell (above) first" in result.message, result


def test_a_tracking_run_sent_away_by_an_ik_in_degrees_is_told_so(master2, monkeypatch):
    """An IK returning degrees sends IK + joint CT's run away; the tracking check said "check the
    signs of the feedback terms". It now asks about degrees first, showing the IK's answer."""
    ik = master2["ik_3r"]

    def in_degrees(x, elbow_up=True):
        return np.degrees(ik(x, elbow_up))

    monkeypatch.setitem(master2, "ik_3r", in_degrees)  # the law calls ik_3r
    laws = {name: master2[name] for name in ("ik_3r", "ct_op_torque", "ct_ik_joint_torque")}
    result = grade("p2_track", **laws)
    assert result.score == 0.5 and "OS-CT: RMS error" in result.message, result
    assert re.search(r"IK\+JS-CT: .*, but first: your ik_3r gives q = \[.*\] at the circle's start", result.message)
    assert "at the circle's start, angles beyond 3π, where no joint angle in radians needs to be: are they in" in (
        result.message
    ), result


def test_a_bias_term_from_mj_rne_with_the_acceleration_is_told_why_it_is_missing():
    """``mj_rne(model, data, 1, h)`` adds M q̈ to h, and at the checks' states (the arm left to
    itself) that cancels h: the law was told its bias term is missing, though it has one."""

    def ct_joint_torque(model, data, q_d, Kp, Kd):
        h = np.zeros(model.nv)
        mujoco.mj_rne(model, data, 1, h)
        return mass_matrix(model, data) @ (Kp * (q_d - data.qpos) - Kd * data.qvel) + h

    result = grade("p1_ct", ct_joint_torque=ct_joint_torque)
    assert result.score == 0.25 and "is missing" in result.message and common.ZERO_BIAS_NOTE in result.message

    def fixed(model, data, q_d, Kp, Kd):
        h = np.zeros(model.nv)
        mujoco.mj_rne(model, data, 0, h)
        return mass_matrix(model, data) @ (Kp * (q_d - data.qpos) - Kd * data.qvel) + h

    assert grade("p1_ct", ct_joint_torque=fixed).score == 1.0
