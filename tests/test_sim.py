"""The simulation loop: logging conventions, torque limits, keyframes, actuation mappings,
split and lab stepping, and divergence detection."""

import warnings
from functools import partial

import mujoco
import numpy as np
import pytest

import labsupport  # noqa: F401
from labsupport import sim, validate
from labsupport.controllers.joint_space import pd_joint_torque
from labsupport.controllers.operational_space import os_ct_torque
from labsupport.dynamics import mass_matrix
from labsupport.plants import load_model, model_path
from labsupport.trajectories import Reference, circle_2d, sample


@pytest.fixture()
def arm():
    return load_model("planar_2r")


def constant(tau):
    tau = np.asarray(tau, dtype=float)
    return lambda model, data: tau


def test_free_motion_is_uniform_rotation(arm):
    """No torque and no gravity: the stretched arm spinning rigidly stays so (the centrifugal
    pull on link 2 runs along it), q1 = w t, q2 = 0."""
    model, data = arm
    log = sim.simulate(model, data, constant([0.0, 0.0]), 1.0, q0=[0.0, 0.0], qdot0=[2.0, 0.0])
    np.testing.assert_allclose(log.q[:, 0], 2.0 * log.t, atol=1e-9)
    np.testing.assert_allclose(log.q[:, 1], 0.0, atol=1e-9)
    assert log.t[0] == 0.0 and len(log.t) == 500


def test_log_after_step_shifts_state_by_one_step(arm):
    model, data = arm
    ctrl = constant([0.3, -0.1])
    before = sim.simulate(model, data, ctrl, 0.1, q0=[0.1, 0.5])
    after = sim.simulate(model, data, ctrl, 0.1, q0=[0.1, 0.5], log_after_step=True)
    np.testing.assert_allclose(after.q[:-1], before.q[1:], atol=1e-15)
    np.testing.assert_allclose(after.t, before.t + model.opt.timestep)


def test_reference_and_error_are_logged(arm):
    model, data = arm
    ref = lambda t: circle_2d(t, (0.5, 0.2), 0.15, 6.0)  # noqa: E731
    log = sim.simulate(model, data, constant([0.0, 0.0]), 0.2, q0=[0.0, 0.0], site="end_effector", reference=ref)
    np.testing.assert_allclose(log.ref, ref(log.t).pos)
    np.testing.assert_allclose(log.ee[:, :2], 0.9 * np.column_stack([np.ones(100), np.zeros(100)]), atol=1e-12)
    np.testing.assert_allclose(log.err, log.ref - log.ee[:, :2])


@pytest.mark.parametrize("log_after_step", [False, True])
def test_a_law_working_in_place_on_the_site_position_leaves_the_logged_tip_alone(arm, log_after_step):
    """``x = data.site_xpos[site, :2]; x -= x_d`` is a view of MuJoCo's data: the law reads right
    (MuJoCo recomputes the position at the next step) but the loop logged the tip after the law
    had run, so a right law showed an error of half a metre. The log holds the tip at each logged
    state, to the 1e-7 m by which RK4 leaves the site a stage behind the step's end."""
    model, data = arm
    site = model.site("end_effector").id
    Kp, Kd = 64.0, 16.0

    def subtracting_in_place(model, data):
        tau = os_ct_torque(model, data, site, np.array([0.5, 0.2]), np.zeros(2), np.zeros(2), Kp, Kd)
        x = data.site_xpos[site, :2]
        x -= (0.5, 0.2)  # the error, written into data.site_xpos
        return tau

    log = sim.simulate(
        model, data, subtracting_in_place, 0.5, q0=[0.3, 1.2], site="end_effector", log_after_step=log_after_step
    )
    tips = sim.site_poses(model, log.q, site)[0]
    np.testing.assert_allclose(log.ee, tips, atol=1e-6)
    assert np.linalg.norm(log.ee[0, :2]) > 0.5  # the tip itself, not tip minus target


def test_torque_limit_clips(arm):
    model, data = arm
    with pytest.warns(RuntimeWarning, match="held the torque at its bound on 5 of 5 steps"):  # held to the end
        log = sim.simulate(model, data, constant([50.0, -50.0]), 0.01, torque_limit=[5.0, 2.0])
    np.testing.assert_array_equal(log.tau, np.tile([5.0, -2.0], (5, 1)))
    with pytest.warns(RuntimeWarning, match="held the torque"):
        log = sim.simulate(model, data, constant([50.0, -50.0]), 0.01, torque_limit=3.0)  # one number: every actuator
    np.testing.assert_array_equal(log.tau, np.tile([3.0, -3.0], (5, 1)))


@pytest.mark.parametrize(
    ("limit", "words"),
    [
        ([1.0, 2.0, 3.0], "one per actuator: nu = 2) must have shape (2,), got shape (3,)"),
        (np.ones((2, 2)), "must have shape (2,), got shape (2, 2)"),
        ([1.0, np.nan], "must be finite"),
        ("abc", "torque_limit must be numbers, not text: got 'abc'"),
        ("10", "torque_limit must be numbers, not text"),  # NumPy would read it as 10.0
        ([1.0, "2"], "torque_limit (a number, or one per actuator: nu = 2) must be numbers, not text"),
        (np.array(["1", "2"]), "torque_limit (a number, or one per actuator: nu = 2) must be numbers, not text"),
        ([True, True], "must be numbers, got [True, True]: True and False are not numbers here"),
        ({"a": 1}, "torque_limit must be a single real number"),
        ([3.0, -4.0], "torque_limit must be positive"),
        (0.0, "torque_limit must be positive"),  # a motor that gives no torque at all
        ([2.0, 0.0], "torque_limit must be positive"),
    ],
)
def test_a_torque_limit_of_the_wrong_shape_or_value_is_named(arm, limit, words):
    """A limit that is not one number must have one entry per actuator (a (3,) limit on the 2R
    arm failed inside NumPy's broadcasting)."""
    model, data = arm
    with pytest.raises(ValueError) as err:
        sim.simulate(model, data, constant([1.0, 1.0]), 0.01, torque_limit=limit)
    assert words in str(err.value)


def test_mujoco_data_after_an_rk4_step_belongs_to_the_new_state(arm):
    """The controllers read M and h from data as mj_step left them (as the lab does); with
    RK4 they come from its last stage and agree with a fresh mj_forward to ~1e-8."""
    model, data = arm
    data.qpos[:], data.qvel[:], data.ctrl[:] = [0.3, 0.8], [1.5, -2.0], [0.5, -0.3]
    mujoco.mj_forward(model, data)
    mujoco.mj_step(model, data)
    fresh = mujoco.MjData(model)
    fresh.qpos[:], fresh.qvel[:] = data.qpos, data.qvel
    mujoco.mj_forward(model, fresh)
    np.testing.assert_allclose(mass_matrix(model, data), mass_matrix(model, fresh), atol=1e-7)
    np.testing.assert_allclose(data.qfrc_bias, fresh.qfrc_bias, atol=1e-7)


def test_divergence_is_detected_and_names_time_and_state(arm):
    """Positive velocity feedback makes the arm run away; the loop stops at the first state
    beyond the runaway speed (before MuJoCo flags the blow-up and resets), with time and state."""
    model, data = arm
    gain = np.array([0.0, 50.0])
    with pytest.raises(sim.SimulationDiverged, match=r"diverged at t = \d+\.\d+ s .*running away") as err:
        sim.simulate(model, data, lambda m, d: gain * d.qvel + np.array([1.0, 0.0]), 5.0, q0=[0.1, 1.0])
    exc = err.value
    assert 0 < exc.t < 5.0
    assert np.all(np.isfinite(exc.qpos)) and np.abs(exc.qvel).max() > sim.RUNAWAY_SPEED  # the runaway is visible
    assert "q = " in str(exc) and "qdot = " in str(exc)


def test_a_runaway_joint_speed_stops_the_run_where_it_crosses_the_bound(arm):
    """A run that spins up past RUNAWAY_SPEED without any MuJoCo warning (a constant torque on
    the gravity-free 2R arm) stops at the first logged state beyond the bound, and the same run
    cut just before it is untouched."""
    model, data = arm
    push = constant([4.0, 0.0])
    with pytest.raises(
        sim.SimulationDiverged,
        match=r"rad/s, past 100 rad/s \(about 955 rpm\), the speed at which a run stops as running away",
    ) as err:
        sim.simulate(model, data, push, 30.0, q0=[0.0, 0.0])
    exc = err.value
    assert np.abs(exc.qvel).max() > sim.RUNAWAY_SPEED
    log = sim.simulate(model, data, push, exc.t - 1e-9, q0=[0.0, 0.0])
    assert np.abs(log.qdot).max() <= sim.RUNAWAY_SPEED and log.t[-1] < exc.t


def test_mujocos_own_warning_is_reported_when_nothing_ran_away_before_it(arm):
    """One huge torque: MuJoCo flags the accelerations of that very step (and resets), with no
    earlier state beyond the runaway speed; the loop reports MuJoCo's warning and the step's start."""
    model, data = arm
    kick = np.array([5e9, 0.0])
    with pytest.raises(sim.SimulationDiverged, match=r"t = 0\.0120 s \(MuJoCo warning mjWARN_BADQACC") as err:
        sim.simulate(model, data, lambda m, d: kick if d.time > 0.011 else np.zeros(2), 0.1)
    assert np.abs(err.value.qvel).max() < sim.RUNAWAY_SPEED


def test_mujocos_warnings_reach_the_error_and_no_log_file_or_other_handler(arm, tmp_path, monkeypatch):
    """MuJoCo's own message (which DOF) is in the error; MuJoCo writes no MUJOCO_LOG.TXT into the
    working directory, and a warning handler set before the run is in force again after it."""
    import mujoco

    model, data = arm
    monkeypatch.chdir(tmp_path)
    mine = []
    mujoco.set_mju_user_warning(mine.append)
    try:
        with pytest.raises(sim.SimulationDiverged, match=r"\(MuJoCo: Nan, Inf or huge value in QACC at DOF 0\)"):
            sim.simulate(model, data, lambda m, d: np.array([5e9, 0.0]) if d.time > 0.011 else np.zeros(2), 0.1)
        assert not (tmp_path / "MUJOCO_LOG.TXT").exists() and mine == []
        mujoco.mj_resetData(model, data)
        data.qvel[0] = np.nan
        mujoco.mj_step(model, data)  # outside the loop, MuJoCo's warnings go where they went before
        assert len(mine) == 1 and "QVEL" in mine[0]
    finally:
        mujoco.set_mju_user_warning(None)


def test_mujocos_other_warnings_become_python_warnings_after_the_run(arm, tmp_path, monkeypatch):
    """A warning that does not stop the run (MuJoCo's "Too many contacts", say, which the course's
    arms never raise) is not lost: the run finishes and the notebook shows it as a RuntimeWarning.
    MuJoCo passes such a message to the handler in force, which the controller plays here."""
    import mujoco

    model, data = arm
    monkeypatch.chdir(tmp_path)

    def warns_once(model, data):
        if abs(data.time - 0.02) < 1e-9:
            mujoco.get_mju_user_warning()("Too many contacts. Time = 0.0200.")
        return np.zeros(2)

    with pytest.warns(RuntimeWarning, match=r"MuJoCo: Too many contacts\. Time = 0\.0200\."):
        log = sim.simulate(model, data, warns_once, 0.05)
    assert len(log.t) == 25 and not (tmp_path / "MUJOCO_LOG.TXT").exists()


def test_runs_in_threads_keep_their_own_mujoco_warnings(arm, tmp_path, monkeypatch):
    """Two runs in two threads (a sweep in a thread pool; MuJoCo steps without the GIL): run A
    starts, run B starts, A ends, then B diverges. B's error still quotes MuJoCo's message, no
    MUJOCO_LOG.TXT is written, no Python warning comes out while A runs, and once both have
    ended the handler in force before them is back (none: MuJoCo's default), not a handler left
    over from a run."""
    import threading

    model, _ = arm
    monkeypatch.chdir(tmp_path)
    both_running, a_done = threading.Barrier(2, timeout=10), threading.Event()
    results = {}

    def run_a():
        def controller(model, data):
            if data.time == 0.0:
                both_running.wait()
            return np.zeros(2)

        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            results["a"] = (sim.simulate(model, mujoco.MjData(model), controller, 0.01), caught)
        a_done.set()

    def run_b():
        def controller(model, data):
            if data.time == 0.0:
                both_running.wait()
                a_done.wait(timeout=10)
            return np.array([5e9, 0.0]) if data.time > 0.011 else np.zeros(2)

        try:
            sim.simulate(model, mujoco.MjData(model), controller, 0.1)
        except sim.SimulationDiverged as err:
            results["b"] = str(err)

    assert mujoco.get_mju_user_warning() is None
    threads = [threading.Thread(target=run_a), threading.Thread(target=run_b)]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join(timeout=30)
    log_a, caught_a = results["a"]
    assert len(log_a.t) == 5 and caught_a == []
    assert "(MuJoCo: Nan, Inf or huge value in QACC at DOF 0)" in results["b"]
    assert not (tmp_path / "MUJOCO_LOG.TXT").exists()
    assert mujoco.get_mju_user_warning() is None


OTHER_THREAD_WARNS = r"""
import threading, warnings
import numpy as np
import labsupport, mujoco
from labsupport import sim
from labsupport.plants import load_model

model, _ = load_model("planar_2r")
inside, go = threading.Event(), threading.Event()

def waits(model, data):
    if data.time == 0.0:
        inside.set()
        go.wait(10)
    return np.zeros(2)

run = threading.Thread(target=sim.simulate, args=(model, mujoco.MjData(model), waits, 0.01))
run.start()
inside.wait(10)
warnings.simplefilter("error")  # as under pytest -W error
data = mujoco.MjData(model)
data.qvel[0] = np.nan
mujoco.mj_step(model, data)  # warns in this thread, which runs no loop
go.set()
run.join()
print("survived", mujoco.get_mju_user_warning())
"""


def test_a_warning_outside_the_runs_is_printed_and_never_raised_into_mujoco(tmp_path):
    """While a run goes on in one thread, MuJoCo warns in another that runs no loop: the message
    is printed to stderr as MuJoCo's default handler would (no MUJOCO_LOG.TXT), even where
    Python warnings are errors: an exception raised inside MuJoCo's handler aborts the process."""
    import subprocess
    import sys

    out = subprocess.run(
        [sys.executable, "-c", OTHER_THREAD_WARNS], cwd=tmp_path, capture_output=True, text=True, timeout=120
    )
    assert out.returncode == 0, out.stderr[-2000:]
    assert out.stdout.strip() == "survived None"
    assert "MuJoCo warning: Nan, Inf or huge value in QVEL at DOF 0" in out.stderr
    assert not (tmp_path / "MUJOCO_LOG.TXT").exists()


def test_non_finite_torque_is_reported(arm):
    """A NaN torque from a finite state is the law's doing, not the gains': the advice says
    where to look. A huge but finite torque keeps the advice for a run that ran away."""
    model, data = arm
    reference = np.array([0.3, None])  # a student's half-filled target: NumPy makes the None NaN

    def pd(m, d):
        return 50.0 * (reference.astype(float) - d.qpos) - 5.0 * d.qvel

    with pytest.raises(sim.SimulationDiverged, match="controller returned tau") as err:
        sim.simulate(model, data, pd, 0.1)
    assert "None becomes NaN" in str(err.value) and "sign error" not in str(err.value)
    assert err.value.t == 0.0
    with pytest.raises(sim.SimulationDiverged, match="controller returned tau") as err:
        sim.simulate(model, data, lambda m, d: np.array([1e12, 0.0]) if d.time > 0.01 else np.zeros(2), 0.1)
    assert "sign error" in str(err.value) and "None" not in str(err.value)


def test_bad_inputs_raise_value_errors(arm):
    model, data = arm
    with pytest.raises(ValueError, match="duration"):
        sim.simulate(model, data, constant([0.0, 0.0]), 0.0)
    with pytest.raises(ValueError, match="shape"):
        sim.simulate(model, data, constant([0.0, 0.0, 0.0]), 0.01)
    with pytest.raises(ValueError, match="q0"):
        sim.simulate(model, data, constant([0.0, 0.0]), 0.01, q0=[0.0])
    with pytest.raises(ValueError, match=r"site 'hand' is not in the model; its sites are \['end_effector'\]"):
        sim.simulate(model, data, constant([0.0, 0.0]), 0.01, site="hand")
    for site in (1, -1):  # ids MuJoCo does not have: refused, never read past its arrays
        with pytest.raises(ValueError, match="id from 0 to 0"):
            sim.simulate(model, data, constant([0.0, 0.0]), 0.01, site=site)
        with pytest.raises(ValueError, match="id from 0 to 0"):
            sim.site_positions(model, np.zeros((3, 2)), site)


def test_a_law_given_arrays_of_the_wrong_size_is_told_the_model_sizes(arm):
    """A reference of the wrong size makes NumPy fail inside the law; the loop says when, and
    which sizes the model's state has."""
    model, data = arm

    def controller(model, data):
        return pd_joint_torque(model, data, np.zeros(3), np.zeros(2), 10.0, 1.0)

    with pytest.raises(ValueError, match=r"at t = 0\.0000 s: operands .*\(3,\).*nq = 2, nv = 2 and nu = 2") as info:
        sim.simulate(model, data, controller, 0.01)
    assert "broadcast" in str(info.value.__cause__)


def test_a_law_error_is_passed_on_with_its_time(arm):
    model, data = arm

    def controller(model, data):
        if data.time > 0.0051:
            raise ValueError("the Jacobian is singular at this configuration")
        return np.zeros(2)

    with pytest.raises(ValueError, match=r"at t = 0\.0060 s: the Jacobian is singular at this configuration$"):
        sim.simulate(model, data, controller, 0.1)


def arm_with_keyframe():
    xml = (
        model_path("planar_2r")
        .read_text()
        .replace("</mujoco>", '<keyframe><key name="bent" qpos="0.3 1.2" qvel="0 0.5"/></keyframe></mujoco>')
    )
    model = mujoco.MjModel.from_xml_string(xml)
    return model, mujoco.MjData(model)


def test_keyframe_sets_the_start_and_q0_overrides_it():
    model, data = arm_with_keyframe()
    log = sim.simulate(model, data, constant([0.0, 0.0]), 0.01, keyframe="bent")
    np.testing.assert_array_equal(log.q[0], [0.3, 1.2])
    np.testing.assert_array_equal(log.qdot[0], [0.0, 0.5])
    log = sim.simulate(model, data, constant([0.0, 0.0]), 0.01, keyframe="bent", q0=[0.1, 0.2])
    np.testing.assert_array_equal(log.q[0], [0.1, 0.2])
    np.testing.assert_array_equal(log.qdot[0], [0.0, 0.5])
    with pytest.raises(ValueError, match="keyframe 'home' is not in the model; its keyframes are \\['bent'\\]"):
        sim.simulate(model, data, constant([0.0, 0.0]), 0.01, keyframe="home")


def test_actuation_maps_torque_to_ctrl(arm):
    """The log keeps the torque asked for and the ctrl written; the plant moves under ctrl."""
    model, data = arm
    doubled = sim.simulate(
        model, data, constant([0.3, -0.1]), 0.1, q0=[0.1, 0.5], actuation=lambda m, d, tau: 2.0 * tau
    )
    direct = sim.simulate(model, data, constant([0.6, -0.2]), 0.1, q0=[0.1, 0.5])
    np.testing.assert_array_equal(doubled.tau, np.tile([0.3, -0.1], (50, 1)))
    np.testing.assert_array_equal(doubled.ctrl, np.tile([0.6, -0.2], (50, 1)))
    np.testing.assert_allclose(doubled.q, direct.q, atol=1e-15)
    np.testing.assert_array_equal(direct.ctrl, direct.tau)


def test_an_actuation_mapping_that_fails_is_named_not_the_controller(arm):
    """A mapping returning the wrong shape used to surface as NumPy's broadcast error, and one
    returning None as a torque that was "not finite" although the controller's was [0, 0]."""
    model, data = arm
    zero = constant([0.0, 0.0])
    with pytest.raises(ValueError, match=r"actuation must be a function actuation\(model, data, tau\) -> ctrl, got 5"):
        sim.simulate(model, data, zero, 0.1, actuation=5)
    with pytest.raises(ValueError, match=r"the actuation mapping failed at t = 0\.0000 s: .*shape \(2,\)"):
        sim.simulate(model, data, zero, 0.1, actuation=lambda m, d, tau: np.zeros(3))
    with pytest.raises(sim.SimulationDiverged, match=r"the actuation mapping turned tau = \[0\. 0\.\] into controls"):
        sim.simulate(model, data, zero, 0.1, actuation=lambda m, d, tau: None)
    with pytest.raises(
        sim.SimulationDiverged, match="the controller returned tau = .*nan"
    ):  # the law's NaN stays its own
        sim.simulate(model, data, constant([np.nan, 0.0]), 0.1, actuation=lambda m, d, tau: tau)


def test_a_reference_that_is_not_finite_is_reported_and_the_run_kept(arm):
    model, data = arm

    def breaks_at_50_ms(t):  # a reference that breaks down part-way
        pos = np.where(np.asarray(t)[..., None] < 0.05, [0.5, 0.2], np.nan)
        return Reference(pos, np.zeros_like(pos), np.zeros_like(pos))

    with pytest.warns(RuntimeWarning, match=r"not finite at 25 of 50 steps, first at t = 0\.0500 s"):
        log = sim.simulate(model, data, constant([0.0, 0.0]), 0.1, site="end_effector", reference=breaks_at_50_ms)
    assert np.isfinite(log.err[:25]).all() and np.isnan(log.err[25:]).all()


def test_a_reference_shorter_than_the_run_is_refused_before_it(arm):
    """It used to fail after the whole run, when the log's error was computed, losing the run."""
    model, data = arm
    one_second = sample(partial(circle_2d, center=(0.5, 0.2), radius=0.15, period=6.0), model.opt.timestep, 1.0)
    with pytest.raises(ValueError, match=r"fails at the run's last control time, t = 1\.9980 s: .*\[0, 1\.002\] s"):
        sim.simulate(model, data, constant([0.0, 0.0]), 2.0, site="end_effector", reference=one_second)
    log = sim.simulate(model, data, constant([0.0, 0.0]), 1.0, site="end_effector", reference=one_second)
    assert log.err.shape == (500, 2) and np.isfinite(log.err).all()


def test_a_singular_solve_in_a_law_is_explained(arm):
    model, data = arm

    def stretched(model, data):  # the 2R law a student writes, at a stretched-out arm
        J = np.array([[0.0, 0.0], [0.9, 0.4]])
        return np.linalg.solve(J, np.ones(2))

    with pytest.raises(ValueError, match="LinAlgError at t = 0.0000 s: Singular matrix. .*stretched out or folded"):
        sim.simulate(model, data, stretched, 0.1)


def test_split_step_shows_the_controller_the_current_kinematics(arm):
    """With mj_step1 before the controller, site_xpos belongs to the current qpos exactly; with
    the default Euler stepping it belongs to the start of the previous step."""
    model, data = arm
    model.opt.integrator = mujoco.mjtIntegrator.mjINT_EULER
    fresh = mujoco.MjData(model)
    gaps = []

    def controller(m, d):
        fresh.qpos[:] = d.qpos
        mujoco.mj_kinematics(m, fresh)
        gaps.append(np.abs(d.site_xpos[-1] - fresh.site_xpos[-1]).max())
        return np.array([0.5, -0.5])

    log = sim.simulate(
        model, data, controller, 0.2, q0=[0.2, 0.4], qdot0=[1.0, 1.0], split_step=True, site="end_effector"
    )
    assert max(gaps) < 1e-15
    np.testing.assert_allclose(log.ee, sim.site_positions(model, log.q, "end_effector"), atol=1e-15)
    np.testing.assert_allclose(log.ee_rot[5] @ log.ee_rot[5].T, np.eye(3), atol=1e-12)
    gaps.clear()
    sim.simulate(model, data, controller, 0.2, q0=[0.2, 0.4], qdot0=[1.0, 1.0])
    assert max(gaps) > 1e-4
    model.opt.integrator = mujoco.mjtIntegrator.mjINT_RK4
    with pytest.raises(ValueError, match="RK4"):
        sim.simulate(model, data, controller, 0.2, split_step=True)


def test_lab_timing_counts_steps_as_the_lab_and_skips_the_first_forward(arm):
    model, data = arm
    assert sim.step_count(8.0, 0.002, lab_timing=True) == 4001
    assert sim.step_count(8.0, 0.002) == 4000
    assert sim.step_count(1.0, 0.5, lab_timing=True) == 2  # 0.5 + 0.5 is 1.0 exactly: the loop stops there
    with pytest.raises(ValueError, match="duration must be finite"):
        sim.step_count(float("inf"), 0.002, lab_timing=True)  # would count for ever
    with pytest.raises(ValueError, match="dt must be positive"):
        sim.step_count(1.0, 0.0)
    first = []

    def controller(m, d):
        if not first:
            first.append(d.site_xpos[-1].copy())
        return np.zeros(2)

    log = sim.simulate(model, data, controller, 0.1, q0=[0.3, 0.3], site="end_effector", lab_timing=True)
    np.testing.assert_array_equal(first[0], 0.0)  # derived data still zeroed by the reset
    assert len(log.t) == sim.step_count(0.1, model.opt.timestep, lab_timing=True)
    np.testing.assert_array_equal(log.ee[0], 0.0)
    with pytest.raises(ValueError, match="exclude"):
        sim.simulate(model, data, controller, 0.1, lab_timing=True, split_step=True)


def test_log_has_one_shape_for_every_run(arm):
    model, data = arm
    log = sim.simulate(
        model,
        data,
        constant([0.0, 0.0]),
        0.02,
        site="end_effector",
        reference=lambda t: circle_2d(t, (0.5, 0.2), 0.15, 6.0),
    )
    assert (log.t.shape, log.q.shape, log.qdot.shape, log.tau.shape, log.ctrl.shape) == (
        (10,),
        (10, 2),
        (10, 2),
        (10, 2),
        (10, 2),
    )
    assert (log.ee.shape, log.ee_rot.shape, log.ref.shape, log.err.shape) == ((10, 3), (10, 3, 3), (10, 2), (10, 2))
    bare = sim.simulate(model, data, constant([0.0, 0.0]), 0.02)
    assert (bare.ee.shape, bare.ee_rot.shape, bare.ref.shape, bare.err.shape) == ((10, 0), (10, 0, 0), (10, 0), (10, 0))


def test_controller_returning_none_gets_a_clear_error(arm):
    model, data = arm
    with pytest.raises(ValueError, match="returned None"):
        sim.simulate(model, data, lambda m, d: None, 0.01)
    with pytest.raises(ValueError, match=r"controller returned complex numbers, but .* \(got \[0\.\+1\.j 0\.\+0\.j"):
        sim.simulate(model, data, lambda m, d: np.array([1j, 0]), 0.01)  # NumPy dropped the 1j with a warning
    as_ints = sim.simulate(model, data, lambda m, d: np.array([1, -2]), 0.01)
    np.testing.assert_array_equal(as_ints.tau[-1], [1.0, -2.0])


@pytest.mark.parametrize("split_step", [False, True])
def test_a_controller_that_changes_the_state_is_named_before_the_arm_jumps(arm, split_step):
    """``e = data.qpos; e -= q_d`` changes the state itself: the arm jumped every step and the run
    "diverged" with advice about gains and signs. The loop names the write at the first step."""
    model, data = arm
    if split_step:  # mj_step1/mj_step2 cannot split RK4, the arm's integrator
        model.opt.integrator = mujoco.mjtIntegrator.mjINT_EULER
    q_d = np.array([0.5, 0.5])

    def aliased_position_error(model, data):
        e = data.qpos  # a view of the state, not a copy
        e -= q_d
        return -100.0 * e - 20.0 * data.qvel + data.qfrc_bias

    def aliased_damping(model, data):
        v = data.qvel
        v *= 20.0
        return 100.0 * (q_d - data.qpos) - v

    for law, changed in ((aliased_position_error, "data.qpos"), (aliased_damping, "data.qvel")):
        with pytest.raises(
            ValueError,
            match=rf"{law.__name__} changed {changed}, the arm's own state, at t = 0.0000 s.*q = data.qpos.copy",
        ):
            sim.simulate(model, data, law, 1.0, q0=[0.1, 0.2], qdot0=[0.3, 0.0], split_step=split_step)

    def halves_its_speed(model, data):  # at rest the write changes nothing: it shows once the arm moves
        v = data.qvel
        v *= 0.5
        return 40.0 * (q_d - data.qpos) - v

    with pytest.raises(
        ValueError, match=r"halves_its_speed changed data.qvel, the arm's own state, at t = 0.00[24]0 s"
    ):
        sim.simulate(model, data, halves_its_speed, 1.0, q0=[0.1, 0.2], split_step=split_step)

    def steps_itself(model, data):  # the lab's loop copied into the controller
        mujoco.mj_step(model, data)
        return 10.0 * (q_d - data.qpos) - 1.0 * data.qvel

    with pytest.raises(
        ValueError, match=r"steps_itself moved data.time from 0.0000 s to 0.0020 s; .*do not call mujoco.mj_step"
    ):
        sim.simulate(model, data, steps_itself, 1.0, q0=[0.1, 0.2], split_step=split_step)

    def borrows_data_and_puts_it_back(model, data):  # a controller may evaluate another state, and restore this one
        q = data.qpos.copy()
        data.qpos[:] = q_d
        mujoco.mj_kinematics(model, data)
        data.qpos[:] = q
        mujoco.mj_kinematics(model, data)
        return 10.0 * (q_d - data.qpos) - 1.0 * data.qvel

    def plain(model, data):
        return 10.0 * (q_d - data.qpos) - 1.0 * data.qvel

    borrowed = sim.simulate(model, data, borrows_data_and_puts_it_back, 0.5, q0=[0.1, 0.2], split_step=split_step)
    same = sim.simulate(model, data, plain, 0.5, q0=[0.1, 0.2], split_step=split_step)
    np.testing.assert_array_equal(borrowed.q, same.q)
    assert np.abs(borrowed.q[-1] - borrowed.q[0]).min() > 0.1  # the arm did move towards q_d


def test_messages_name_a_lambda_a_partial_and_a_callable_object(arm):
    """A lambda was named "<lambda>" and a functools.partial "the controller"."""
    model, data = arm

    def damping(model, data, gain):
        return -gain * data.qvel

    class Damping:
        def __call__(self, model, data):
            return -data.qvel

    assert sim.controller_name(damping) == "damping"
    assert sim.controller_name(partial(partial(damping), gain=2.0)) == "damping"
    assert sim.controller_name(lambda m, d: -d.qvel) == "the lambda controller"
    assert sim.controller_name(Damping()) == "the Damping object"
    writes = lambda m, d: np.subtract(d.qpos, 0.1, out=d.qpos) * 0.0  # noqa: E731
    with pytest.raises(ValueError, match=r"^the lambda controller changed data\.qpos"):
        sim.simulate(model, data, writes, 0.01)


def test_sampled_reference_reads_the_samples_of_the_grid():
    ref = lambda t: circle_2d(t, (0.5, 0.2), 0.15, 6.0)  # noqa: E731
    sampled = sample(ref, 0.002, 1.0)
    for t in (0.0, 0.002 * 63, 0.5, 1.0, 1.002):  # the lab's loops take one step more
        r = ref(t)
        np.testing.assert_allclose(np.concatenate(sampled.at(t)), [*r.pos, *r.vel, *r.acc], atol=1e-12)
    t = np.arange(10) * 0.002
    np.testing.assert_allclose(sampled(t).pos, ref(t).pos, atol=1e-15)
    shifted = sample(ref, 0.002, 1.0, offset=0.001)
    np.testing.assert_allclose(shifted.at(0.004).pos, ref(0.005).pos, atol=1e-12)
    with pytest.raises(ValueError, match="outside the sampled reference"):
        sampled.at(2.0)


def test_sample_accepts_scalar_only_functions():
    def scalar_only(t):
        if np.ndim(t):
            raise TypeError("scalars only")
        return Reference(np.sin(t), np.cos(t), -np.sin(t))

    sampled = sample(scalar_only, 0.01, 0.5)
    assert sampled.pos.shape == (52,)
    np.testing.assert_allclose(sampled.at(0.1), [np.sin(0.1), np.cos(0.1), -np.sin(0.1)], atol=1e-12)


def test_a_reference_that_returns_a_bare_position_is_refused_not_misread():
    """``sample`` used to unpack a returned position (x, y, z) as position x, velocity y and
    acceleration z without a word; ``simulate`` failed with an AttributeError after the run."""
    target = np.array([0.4, 0.3, 0.2])
    with pytest.raises(ValueError, match=r"must return trajectories.Reference\(pos, vel, acc\).*ndarray"):
        sample(lambda t: target, 0.01, 0.5)
    with pytest.raises(ValueError, match="returned NoneType"):
        sample(lambda t: None, 0.01, 0.5)
    fixed = sample(lambda t: Reference(target, np.zeros_like(target), np.zeros_like(target)), 0.01, 0.5)
    np.testing.assert_array_equal(fixed.at(0.25).pos, target)


@pytest.mark.parametrize(
    ("site", "reference", "message"),
    [
        ("end_effector", lambda t: [0.5, 0.2], r"must return trajectories.Reference"),
        ("end_effector", lambda t: Reference(*np.zeros((3, 4))), "4 components; a site position has 3"),
        (None, lambda t: circle_2d(t, (0.5, 0.2), 0.15, 6.0), "pass site="),
    ],
)
def test_simulate_refuses_a_bad_reference_before_the_run(arm, site, reference, message):
    """The reference is evaluated after the run; a bad one used to fail only then, the run lost."""
    model, data = arm
    calls = []

    def controller(model, data):
        calls.append(data.time)
        return np.zeros(2)

    with pytest.raises(ValueError, match=message):
        sim.simulate(model, data, controller, 0.01, site=site, reference=reference)
    assert calls == []


@pytest.mark.parametrize("t", [float("nan"), float("inf"), "soon", None])
def test_sampled_reference_names_a_time_that_is_not_a_number(t):
    sampled = sample(lambda t: circle_2d(t, (0.5, 0.2), 0.15, 6.0), 0.002, 1.0)
    with pytest.raises(ValueError, match="t must be"):
        sampled.at(t)


def test_validate_names_the_argument_and_what_was_wrong():
    np.testing.assert_array_equal(validate.vector("q", [1, 2], (2,)), [1.0, 2.0])
    with pytest.raises(ValueError, match=r"q must have shape \(2,\), got shape \(3,\)"):
        validate.vector("q", [1, 2, 3], (2,))
    with pytest.raises(ValueError, match="q must be finite"):
        validate.vector("q", [1, np.nan], 2)
    with pytest.raises(ValueError, match="q must be numbers, not text"):
        validate.vector("q", ["a", "b"], 2)
    with pytest.raises(ValueError, match="q must be numbers of shape"):
        validate.vector("q", [{}, 1], 2)
    assert validate.number("Kp", np.float32(2.5), positive=True) == 2.5
    with pytest.raises(ValueError, match="Kp must be positive, got 0"):
        validate.number("Kp", 0, positive=True)
    with pytest.raises(ValueError, match="Kd must be non-negative"):
        validate.number("Kd", -1.0, nonnegative=True)
    with pytest.raises(ValueError, match="single real number"):
        validate.number("dt", [0.1, 0.2])
    with pytest.raises(ValueError, match="boolean"):
        validate.number("dt", True)


def test_the_wrong_model_data_or_controller_is_named(arm):
    """What a student passes by mistake is named before the run, not found by MuJoCo or NumPy."""
    model, data = arm
    other_model, other_data = load_model("spatial_3r")
    pd = constant([0.0, 0.0])
    for args, words in (
        ((None, data, pd), "model must be a mujoco.MjModel, got NoneType"),
        ((data, model, pd), "model and data are swapped"),
        ((model, None, pd), "data must be a mujoco.MjData"),
        ((model, other_data, pd), "data was made for another model: its nq = 3 (the model's 2)"),
        ((model, data, None), "controller must be a function controller(model, data) -> tau, got None"),
        ((model, data, np.zeros(2)), "controller must be a function"),
    ):
        with pytest.raises(ValueError) as err:
            sim.simulate(*args, 0.1)
        assert words in str(err.value)
    assert other_model.nq == 3


def test_a_controller_failing_or_returning_text_is_named_with_the_time(arm):
    model, data = arm
    target = None  # a reference the student forgot to set

    def pd(model, data):
        return 10.0 * (target - data.qpos)

    with pytest.raises(TypeError, match=r"the controller raised TypeError at t = 0\.0000 s: unsupported operand"):
        sim.simulate(model, data, pd, 0.1)
    with pytest.raises(ValueError, match="the controller returned .*not numbers; it must return a torque of shape"):
        sim.simulate(model, data, lambda m, d: {"tau": 1.0}, 0.1)
    with pytest.raises(ValueError, match="the controller returned the text 'abc'; it must return a torque of shape"):
        sim.simulate(model, data, lambda m, d: "abc", 0.1)
    one, one_data = load_model("single_joint")  # "1" used to act as 1 N·m
    with pytest.raises(
        ValueError, match=r"the controller returned the text '1'; it must return a torque of shape \(1,\)"
    ):
        sim.simulate(one, one_data, lambda m, d: "1", 0.1)
    # an array of text, or of booleans, used to act as torques of 1 and 0 N·m
    with pytest.raises(ValueError, match=r"the controller returned the text \['1' '2'\]; it must return a torque"):
        sim.simulate(model, data, lambda m, d: np.array(["1", "2"]), 0.1)
    with pytest.raises(ValueError, match=r"returned \[ True  True\], not torques: True and False are not numbers"):
        sim.simulate(model, data, lambda m, d: d.qpos > -1.0, 0.1)
    with pytest.raises(ValueError, match=r"returned \[True, False\], not torques: .*a comparison such as q > 0"):
        sim.simulate(model, data, lambda m, d: [True, False], 0.1)


@pytest.mark.parametrize(
    ("law", "kind", "words"),
    [
        (lambda m, d: d.qpos[1], ValueError, r"raised IndexError at t = 0\.0000 s: .*nq = 1, nv = 1 and nu = 1"),
        (lambda m, d: {"kp": 1.0}["Kp"], ValueError, r"raised KeyError at t = 0\.0000 s: 'Kp'"),
        (lambda m, d: d.qpos.kp, ValueError, r"raised AttributeError at t = 0\.0000 s: .*kp"),
        (lambda m, d: 1 / 0, ValueError, r"raised ZeroDivisionError at t = 0\.0000 s"),
    ],
)
def test_any_usual_error_of_a_controller_is_passed_on_with_its_time(law, kind, words):
    """IndexError, KeyError, AttributeError and ZeroDivisionError used to come out bare, with no
    time and, for an index past the state, no sizes."""
    model, data = load_model("single_joint")
    with pytest.raises(kind, match=words):
        sim.simulate(model, data, law, 0.1)


def test_the_ctrlrange_that_mujoco_clamps_to_is_the_torque_in_the_log():
    """The single joint's motor stops at 20 N·m. MuJoCo clamps ctrl there silently, so the log used
    to show the 200 N·m asked for, while the run was the same as one with torque_limit=20."""
    model, data = load_model("single_joint")
    stiff = lambda m, d: 200.0 * (1.0 - d.qpos) - 20.0 * d.qvel + d.qfrc_bias  # noqa: E731
    with pytest.warns(RuntimeWarning, match=r"ctrlrange bound the torque on \d+ of 500 steps, first at t = 0\.0000 s"):
        log = sim.simulate(model, data, stiff, 0.5)
    limited = sim.simulate(model, data, stiff, 0.5, torque_limit=20.0)
    assert log.tau.max() == 20.0 and np.abs(log.tau).max() == 20.0
    np.testing.assert_array_equal(log.tau, limited.tau)
    np.testing.assert_array_equal(log.q, limited.q)  # the torque logged is the torque that acted
    with pytest.warns(RuntimeWarning) as said:  # a tighter torque_limit is the run's own: not ctrlrange's
        sim.simulate(model, data, stiff, 0.5, torque_limit=5.0)
    assert [str(w.message).split(" held")[0] for w in said] == ["torque_limit"]  # held at it to the end
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        sim.simulate(model, data, lambda m, d: d.qfrc_bias, 0.5)  # within the range: no warning


def test_a_servo_model_without_an_actuation_mapping_is_refused():
    """The UR5e's servos read ctrl as target angles: torques written there used to run without a
    word, 93 mm off the target."""
    from labsupport import actuators, ur5e

    model, data = ur5e.load_ur5e()
    with pytest.raises(ValueError, match=r"6 of the model's 6 actuators .* are servos: .*servo_actuation\(model\)"):
        sim.simulate(model, data, lambda m, d: d.qfrc_bias, 0.01, keyframe=ur5e.HOME)
    held = sim.simulate(
        model, data, lambda m, d: d.qfrc_bias, 0.01, keyframe=ur5e.HOME, actuation=actuators.servo_actuation(model)
    )
    assert held.q.shape == (5, 6)


def test_site_positions_of_one_configuration_and_bad_configurations():
    """One configuration (nq,) was read as nq configurations of one joint each: the 2R's
    q = (0.1, 0.2) gave two rows, for (0.1, 0.1) and (0.2, 0.2)."""
    from labsupport.kinematics import planar_2r

    model, _ = load_model("planar_2r")
    (row,) = sim.site_positions(model, np.array([0.1, 0.2]), "end_effector")
    np.testing.assert_allclose(row[:2], planar_2r.forward_kinematics(np.array([0.1, 0.2])), atol=1e-12)
    for bad in ([0.1, 0.2, 0.3], 0.5, "ab", [[0.1, "a"]]):
        with pytest.raises(ValueError, match=r"one configuration per row, shape \(N, 2\)"):
            sim.site_positions(model, bad, "end_effector")


def test_a_reference_given_as_a_value_is_named():
    """A Reference (say, a set point evaluated once) where a function of time belongs ended in
    "'Reference' object is not callable"."""
    from labsupport.trajectories import set_point

    model, data = load_model("planar_2r")
    with pytest.raises(ValueError, match="reference must be a function of time"):
        sim.simulate(
            model, data, lambda m, d: np.zeros(2), 0.1, site="end_effector", reference=set_point(0.0, [0.5, 0.2])
        )


def test_a_duration_past_what_memory_holds_is_refused_at_once():
    """duration=1e12 (meant as something else) ended in "Unable to allocate 28.4 PiB", and with the
    lab's timing counted steps for hours before anything ran; a reference sampled as finely and a
    log passed to rms whole ended deep in NumPy."""
    from labsupport import metrics, validate
    from labsupport.plants import SingleJoint
    from labsupport.trajectories import sinusoid

    model, data = load_model("single_joint")
    hold = lambda m, d: d.qfrc_bias  # noqa: E731
    for timing in (False, True):
        with pytest.raises(ValueError, match=r"is 1e\+15 steps, more than the 10,000,000 one run may hold"):
            sim.simulate(model, data, hold, 1e12, lab_timing=timing)
    with pytest.raises(ValueError, match="more than the 10,000,000"):
        sample(sinusoid, 1e-9, 1e6)
    with pytest.raises(ValueError, match="more than the 10,000,000"):
        SingleJoint().simulate(lambda t, s: 0.0, 1e7)
    assert sim.step_count(validate.MAX_STEPS * 1e-3, 1e-3) == validate.MAX_STEPS  # the bound itself is fine
    log = sim.simulate(model, data, hold, 0.01)
    with pytest.raises(ValueError, match="not of a whole Log: pass log.err"):
        metrics.rms(log)
    with pytest.raises(ValueError, match="error must be numbers, not text"):
        metrics.rms(["1", "2"])


@pytest.mark.parametrize("flag", ["log_after_step", "split_step", "lab_timing"])
@pytest.mark.parametrize("value", ["no", 0, 1.0, None])
def test_a_flag_that_is_not_true_or_false_is_named(arm, flag, value):
    """Python reads "no" as true: the loop refuses anything but True and False (NumPy's too),
    before the run."""
    model, data = arm
    with pytest.raises(ValueError, match=f"{flag} must be True or False"):
        sim.simulate(model, data, constant([0.0, 0.0]), 0.01, **{flag: value})
    log = sim.simulate(model, data, constant([0.0, 0.0]), 0.01, **{flag: np.bool_(False)})
    assert len(log.t) == 5
    with pytest.raises(ValueError, match="forward must be True or False"):
        sim.reset(model, data, forward="no")


def test_a_reference_sampled_more_coarsely_than_the_step_is_named(arm):
    """A reference sampled every 10 ms on the 2 ms model stands still between samples; the run
    goes on, with a warning that says how to sample it. At the step, or finer, nothing is said."""
    model, data = arm
    circle = partial(circle_2d, center=(0.5, 0.2), radius=0.15, period=6.0)
    with pytest.warns(RuntimeWarning, match=r"sampled every 0\.01 s, more coarsely than the model's step of 0\.002 s"):
        sim.simulate(model, data, constant([0.0, 0.0]), 0.1, site="end_effector", reference=sample(circle, 0.01, 0.2))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        for dt in (model.opt.timestep, 0.001):
            sim.simulate(model, data, constant([0.0, 0.0]), 0.1, site="end_effector", reference=sample(circle, dt, 0.2))


def test_a_ctrlrange_on_some_motors_bounds_those_alone():
    """Motor a stops at -1 N·m (and 100), motor b has no range: b's torque passes whole, with or without a
    torque_limit, and the warning names a only, and only while its range is tighter than the limit."""
    model = mujoco.MjModel.from_xml_string(
        "<mujoco><worldbody><body><joint name='ja'/><geom size='.1' mass='50'/><body pos='0 0 .3'><joint name='jb'/>"
        "<geom size='.1' mass='50'/></body></body></worldbody><actuator><motor name='a' joint='ja' ctrlrange='-1 100'/>"
        "<motor name='b' joint='jb'/></actuator></mujoco>"
    )
    data = mujoco.MjData(model)
    with pytest.warns(RuntimeWarning, match=r"on 10 of 10 steps.*\(actuators a; ctrlrange \[-1, 100\]\)"):
        log = sim.simulate(model, data, constant([-5.0, -50.0]), 10 * model.opt.timestep)
    np.testing.assert_array_equal(log.tau, np.tile([-1.0, -50.0], (10, 1)))
    with pytest.warns(RuntimeWarning, match=r"\(actuators a; "), pytest.warns(RuntimeWarning, match="limit held"):
        log = sim.simulate(model, data, constant([-5.0, -50.0]), 10 * model.opt.timestep, torque_limit=30.0)
    np.testing.assert_array_equal(log.tau, np.tile([-1.0, -30.0], (10, 1)))
    with pytest.warns(RuntimeWarning) as said:  # the limit is tighter than a's range: the limit's doing
        log = sim.simulate(model, data, constant([-5.0, -50.0]), 10 * model.opt.timestep, torque_limit=0.5)
    assert [str(w.message).split(" held")[0] for w in said] == ["torque_limit"]  # not ctrlrange's
    np.testing.assert_array_equal(log.tau, np.tile([-0.5, -0.5], (10, 1)))


def test_a_state_set_by_hand_that_a_run_would_not_start_from_is_warned_about(arm):
    """``data.qpos[:] = [0.7, 0.4]`` then ``simulate`` without ``q0``: the run started from qpos0 at
    rest without a word. Now a warning says where it starts and how to start where data is. A run
    given q0, and the run after a run (the time is then past 0; it starts afresh, as documented),
    are not warned about."""
    model, data = arm
    hold = lambda m, d: d.qfrc_bias.copy()  # noqa: E731
    mujoco.mj_resetData(model, data)
    data.qpos[:] = [0.7, 0.4]
    with pytest.warns(RuntimeWarning, match=r"data holds qpos = \[0.7 0.4\] at time 0 .*pass q0=data.qpos.copy\(\)"):
        log = sim.simulate(model, data, hold, 0.01)
    np.testing.assert_array_equal(log.q[0], model.qpos0)  # what the warning says
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        sim.simulate(model, data, hold, 0.01)  # after a run
        mujoco.mj_resetData(model, data)
        data.qpos[:] = [0.7, 0.4]
        assert sim.simulate(model, data, hold, 0.01, q0=data.qpos.copy()).q[0].tolist() == [0.7, 0.4]


def test_a_reference_passed_whole_to_a_law_is_told_to_unpack_it(arm):
    """os_ct_torque(model, data, site, circle(t), Kp, Kd): the Reference fills x_d, and Kp, Kd the
    places of the velocity and acceleration, so Python says Kp and Kd are missing, which the
    student did pass. The single joint's loop said why; the MuJoCo loop now says it too. A
    controller that itself takes other arguments than (model, data) is told how simulate calls it."""
    model, data = arm
    circle = partial(circle_2d, center=(0.5, 0.2), radius=0.15, period=6.0)

    def whole(model, data):
        return os_ct_torque(model, data, "end_effector", circle(data.time), 64.0, 16.0)

    with pytest.raises(TypeError, match=r"missing 2 required .*'Kp' and 'Kd'; .*unpack it with \*"):
        sim.simulate(model, data, whole, 0.1, q0=[0.2, 0.9])
    with pytest.raises(TypeError, match=r"simulate calls controller\(model, data\), with these two arguments only"):
        sim.simulate(model, data, lambda model, data, Kp: np.zeros(2), 0.1, q0=[0.2, 0.9])


def test_a_run_stopped_by_the_kernel_says_where_it_was_and_why_a_law_may_hang(arm):
    """An IK loop that never ends hangs the run cell; the stop button then showed a bare
    KeyboardInterrupt from inside the loop. It now says when the run stopped, inside which
    controller, and what to look for, and keeps the traceback of the student's line."""
    model, data = arm

    def hangs_after_a_while(model, data):
        if data.time > 0.01:
            raise KeyboardInterrupt  # as the kernel's interrupt arrives in a loop that never ends
        return np.zeros(2)

    with pytest.raises(
        KeyboardInterrupt,
        match=r"stopped at t = 0\.01\d* s of 1 s, inside hangs_after_a_while: .*"
        r"a loop that does not end",
    ) as stopped:
        sim.simulate(model, data, hangs_after_a_while, 1.0, q0=[0.2, 0.9])
    assert isinstance(stopped.value.__cause__, KeyboardInterrupt)


def test_an_argument_left_out_of_a_law_is_not_blamed_on_a_reference(arm):
    """os_ct_torque called without its site: Python says Kd is missing, the last argument, though
    the site was left out. The message says so first, and names the Reference only as the other
    cause."""
    model, data = arm
    circle = partial(circle_2d, center=(0.5, 0.2), radius=0.15, period=6.0)

    def no_site(model, data):
        return os_ct_torque(model, data, *circle(data.time), 64.0, 16.0)

    with pytest.raises(
        TypeError,
        match=r"missing 1 required .*'Kd'.*Python names the last ones as missing, "
        r"whichever was left out: compare the call with the law's def line .* also counts",
    ):
        sim.simulate(model, data, no_site, 0.1, q0=[0.2, 0.9])


def test_a_function_that_makes_controllers_passed_as_one_is_told_to_be_called():
    """Tasks 2 and 3 make their controllers with a function (``os_ct(offset=0.0)``); one passed
    uncalled ended in "returned <function ...>, not numbers", "offset must be a single real number,
    got <MjModel ...>" or "cannot unpack non-iterable MjModel", none of which says what happened."""
    from labsupport import validate

    model, data = load_model("single_joint")

    def with_model(ctrl_model, Ki=1.0):  # simulate's (model, data) fill both: it returns a controller
        return lambda model, data: np.array([Ki])

    def with_offset(offset=0.0, law=None):
        validate.number("offset", offset)
        return with_model(None)

    def with_gains(gains=(1.0, 2.0), law=None):
        Kp, Kd = gains
        return with_model(None)

    for maker in (with_model, with_offset, with_gains):
        with pytest.raises((ValueError, TypeError)) as err:
            sim.simulate(model, data, maker, 0.01, q0=[0.0])
        assert sim.MAKER_PASSED in str(err.value), (maker.__name__, str(err.value))
    with pytest.raises(ValueError) as err:
        sim.simulate(model, data, lambda model, data: "1.0", 0.01, q0=[0.0])
    assert sim.MAKER_PASSED not in str(err.value)


def test_a_reference_passed_whole_into_a_law_of_the_right_arity_is_named():
    """``law(..., sinusoid(t), ...)`` with a whole Reference where the law takes its position has
    the right number of arguments, so no argument is missing, but three numbers come out where one
    goes: the analytic plant said "tau must be a scalar", the loop "shape (1, 3)", and a
    preallocated torque "setting an array element with a sequence", none naming the Reference."""
    from labsupport.plants import SingleJoint
    from labsupport.trajectories import sinusoid

    def pd(theta_d, theta):  # called with sinusoid(t) whole
        return 2.0 * (np.asarray(theta_d) - theta)

    with pytest.raises(ValueError) as err:
        SingleJoint().simulate(lambda t, x: pd(sinusoid(t), x[0]), 0.1)
    assert validate.REFERENCE_WHOLE in str(err.value), str(err.value)

    model, data = load_model("single_joint")
    tau = np.zeros(1)

    def into_preallocated(model, data):
        tau[0] = pd(sinusoid(data.time), data.qpos[0])
        return tau

    for law in (lambda model, data: np.array([pd(sinusoid(data.time), data.qpos[0])]), into_preallocated):
        with pytest.raises(ValueError) as err:
            sim.simulate(model, data, law, 0.01, q0=[0.0])
        assert validate.REFERENCE_WHOLE in str(err.value), str(err.value)


def test_a_site_indexed_by_its_name_is_told_the_id(arm):
    """``data.site_xpos[site]`` with the site's name raised IndexError, which the loop followed with
    "check that the references and gains given to the law have these sizes": no size was wrong."""
    model, data = arm

    def by_name(model, data, site="end_effector"):
        return 10.0 * (np.array([0.5, 0.2]) - data.site_xpos[site][:2])

    with pytest.raises(ValueError) as err:
        sim.simulate(model, data, by_name, 0.01, q0=[0.3, 1.2])
    assert "data.site_xpos[i] takes the site's id, model.site(name).id" in str(err.value), str(err.value)
    assert "have these sizes" not in str(err.value)


def test_a_law_called_with_its_arguments_in_another_order_is_told_to_compare_the_def_line(arm):
    """Task 1's ``pd_gravity_torque(theta, theta_dot, theta_d, thetadot_d, arm, Kp, Kd)`` called with
    the arm before the gains, and Task 3's law with the gains before the reference, ended in
    "unsupported operand type(s) for *: 'SingleJoint' and 'float'" and "object of type 'float' has
    no len()", with no hint."""
    from labsupport.plants import SingleJoint

    def pd_gravity_torque(theta, theta_dot, theta_d, theta_dot_d, Kp, Kd, arm):  # the Try it's law
        return Kp * (theta_d - theta) + Kd * (theta_dot_d - theta_dot) + arm.m * arm.g * arm.r * np.cos(theta)

    vertical = SingleJoint(g=9.81)
    with pytest.raises(ValueError) as err:
        vertical.simulate(lambda t, x: pd_gravity_torque(x[0], x[1], 0.5, 0.0, vertical, 4.0, 2.0), 0.1)
    assert "compare the call with the law's def line, argument by argument" in str(err.value), str(err.value)

    model, data = arm
    site = model.site("end_effector").id
    x_d = np.array([0.5, 0.2])

    def other_order(model, data):
        return os_ct_torque(model, data, site, 64.0, 16.0, x_d, np.zeros(2), np.zeros(2))

    with pytest.raises(TypeError) as err:
        sim.simulate(model, data, other_order, 0.01, q0=[0.3, 1.2])
    assert "compare the call with the law's def line, argument by argument" in str(err.value), str(err.value)


def test_a_gain_given_as_text_or_a_list_is_named_as_such(arm):
    """``Kp = "4.2"`` (read from a widget or a file) and ``Kp = [64.0, 64.0]`` ended in NumPy's
    "can't multiply sequence by non-int" or "ufunc 'multiply' did not contain a loop", with no
    word of what to change."""
    from labsupport.controllers.single_joint import pd_torque
    from labsupport.plants import SingleJoint

    for Kp in ("4.2", [4.2]):
        with pytest.raises(ValueError) as err:
            SingleJoint().simulate(lambda t, x, Kp=Kp: pd_torque(x[0], x[1], 1.0, 0.0, Kp, 1.0), 0.1)
        assert 'a number reached the law as text ("4.2") or as a list' in str(err.value), str(err.value)

    model, data = arm
    site = model.site("end_effector").id
    x_d = np.array([0.5, 0.2])

    def law(model, data):
        return os_ct_torque(model, data, site, x_d, np.zeros(2), np.zeros(2), "64", 16.0)

    with pytest.raises(TypeError) as err:
        sim.simulate(model, data, law, 0.01, q0=[0.3, 1.2])
    assert "write numbers without quotes, and vectors as np.array([...])" in str(err.value), str(err.value)
    # the same gains as numbers run
    sim.simulate(
        model, data, lambda m, d: os_ct_torque(m, d, site, x_d, 0 * x_d, 0 * x_d, 64.0, 16.0), 0.01, q0=[0.3, 1.2]
    )


def test_a_function_of_time_read_as_a_sampled_reference_is_told_to_sample_it(arm):
    """Task 4's ``tracking_run(circle, ...)``, handed the circle function instead of its sampled
    reference, ended in "'function' object has no attribute 'at'" with no pointer to
    ``trajectories.sample``."""
    from labsupport import trajectories

    model, data = arm
    site = model.site("end_effector").id

    def circle(t):
        return trajectories.circle_2d(t, center=(0.5, 0.2), radius=0.1, period=6.0)

    def run(reference):
        def controller(model, data):
            ref = reference.at(data.time)
            return os_ct_torque(model, data, site, ref.pos, ref.vel, ref.acc, 64.0, 16.0)

        return sim.simulate(model, data, controller, 0.01, q0=[0.3, 1.2])

    with pytest.raises(ValueError, match=r"sample it first, reference = trajectories.sample\(f, dt, duration\)"):
        run(circle)
    assert run(trajectories.sample(circle, model.opt.timestep, 0.01)).t.size


def test_a_run_held_at_its_torque_limit_to_the_end_is_warned_of():
    """A law with a flipped sign, held at ``torque_limit``, need not run away: Task 2 with its
    integral's sign flipped ended with an RMS error of 1950° and no word. Here PD to 1 rad with
    both gains' signs flipped, held at 3 N·m, turns the arm over and over at under 20 rad/s."""
    model, data = load_model("single_joint")

    def pd(sign):
        return lambda model, data: np.array([sign * (5.72 * (1.0 - data.qpos[0]) - 1.9 * data.qvel[0])])

    with pytest.warns(RuntimeWarning, match=r"held the torque at its bound on 5000 of 5000 steps, the last"):
        log = sim.simulate(model, data, pd(-1.0), 5.0, torque_limit=3.0)
    assert abs(log.q[-1, 0]) > 10 * np.pi and np.abs(log.qdot).max() < sim.RUNAWAY_SPEED
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # the right sign: the limit acts at the start only
        log = sim.simulate(model, data, pd(1.0), 5.0, torque_limit=3.0)
    assert 0 < np.mean(np.abs(log.tau) >= 3.0) < sim.HELD_AT_LIMIT_SHARE
