"""2R planar arm: the MJCF model against closed forms, and the kinematics against finite
differences and round trips."""

import warnings

import mujoco
import numpy as np
import pytest

import labsupport  # noqa: F401  (chooses the GL backend before mujoco renders anything)
from labsupport.dynamics import mass_matrix
from labsupport.kinematics import planar_2r as k2
from labsupport.plants import load_model

M1, M2, L1, L2 = 1.0, 0.8, 0.5, 0.4


def uniform_rod_mass_matrix(q2):
    r"""Closed form for two uniform rods (CoM at l/2, I = m l^2/12 about the CoM):
    M11 = I1 + I2 + m1 lc1^2 + m2 (l1^2 + lc2^2 + 2 l1 lc2 cos q2), M12 = I2 + m2 (lc2^2 + l1 lc2 cos q2),
    M22 = I2 + m2 lc2^2."""
    lc1, lc2 = L1 / 2, L2 / 2
    i1, i2 = M1 * L1**2 / 12, M2 * L2**2 / 12
    c2 = np.cos(q2)
    m11 = i1 + i2 + M1 * lc1**2 + M2 * (L1**2 + lc2**2 + 2 * L1 * lc2 * c2)
    m12 = i2 + M2 * (lc2**2 + L1 * lc2 * c2)
    m22 = i2 + M2 * lc2**2
    return np.array([[m11, m12], [m12, m22]])


@pytest.fixture(scope="module")
def arm_model():
    return load_model("planar_2r")


def test_model_parameters(arm_model):
    model, _ = arm_model
    assert model.nv == 2 and model.nu == 2
    assert np.allclose(model.opt.gravity, 0.0)
    assert model.opt.timestep == 0.002
    assert model.opt.integrator == mujoco.mjtIntegrator.mjINT_RK4
    np.testing.assert_allclose(model.body_mass[1:], [M1, M2])


def test_mass_matrix_matches_uniform_rods(arm_model):
    model, data = arm_model
    rng = np.random.default_rng(0)
    for q in rng.uniform(-np.pi, np.pi, size=(50, 2)):
        data.qpos[:] = q
        mujoco.mj_forward(model, data)
        np.testing.assert_allclose(mass_matrix(model, data), uniform_rod_mass_matrix(q[1]), rtol=0, atol=1e-10)


def test_site_elbow_and_fk_agree(arm_model):
    """The tip and the elbow that the arm drawings use, against MuJoCo's site and link-2 body."""
    model, data = arm_model
    rng = np.random.default_rng(1)
    for q in rng.uniform(-np.pi, np.pi, size=(20, 2)):
        data.qpos[:] = q
        mujoco.mj_kinematics(model, data)
        np.testing.assert_allclose(data.site("end_effector").xpos[:2], k2.forward_kinematics(q), atol=1e-12)
        elbow = k2.elbow_position(q)
        np.testing.assert_allclose(elbow, data.xpos[2, :2], atol=1e-12)
        np.testing.assert_allclose(np.linalg.norm(k2.forward_kinematics(q) - elbow), L2, atol=1e-12)


def test_jacobian_matches_finite_differences():
    rng = np.random.default_rng(2)
    eps = 1e-6
    for q in rng.uniform(-np.pi, np.pi, size=(30, 2)):
        fd = np.column_stack(
            [(k2.forward_kinematics(q + eps * e) - k2.forward_kinematics(q - eps * e)) / (2 * eps) for e in np.eye(2)]
        )
        np.testing.assert_allclose(k2.jacobian(q), fd, atol=1e-8)


def test_jacobian_matches_mujoco(arm_model):
    from labsupport.dynamics import site_jacobian

    model, data = arm_model
    q = np.array([0.4, -1.1])
    data.qpos[:] = q
    mujoco.mj_forward(model, data)
    np.testing.assert_allclose(site_jacobian(model, data, "end_effector")[:2], k2.jacobian(q), atol=1e-12)


def test_jdot_qdot_matches_finite_difference_of_j_qdot():
    r"""d/dt (J(q) qdot) at constant qdot is Jdot qdot: central difference along q + s qdot."""
    rng = np.random.default_rng(3)
    eps = 1e-6
    for q, qdot in zip(rng.uniform(-np.pi, np.pi, size=(30, 2)), rng.normal(0, 2, size=(30, 2)), strict=True):
        fd = (k2.jacobian(q + eps * qdot) @ qdot - k2.jacobian(q - eps * qdot) @ qdot) / (2 * eps)
        np.testing.assert_allclose(k2.jdot_qdot(q, qdot), fd, atol=1e-7)


def test_vectorised_calls_match_single_ones():
    rng = np.random.default_rng(4)
    q, qdot = rng.uniform(-3, 3, size=(5, 2)), rng.normal(size=(5, 2))
    for i in range(5):
        np.testing.assert_allclose(k2.jacobian(q)[i], k2.jacobian(q[i]))
        np.testing.assert_allclose(k2.jdot_qdot(q, qdot)[i], k2.jdot_qdot(q[i], qdot[i]))


@pytest.mark.parametrize("elbow_up", [True, False])
def test_ik_round_trip_on_1000_reachable_points(elbow_up):
    rng = np.random.default_rng(5)
    radius = rng.uniform(k2.LAB_ARM.reach_min + 1e-6, k2.LAB_ARM.reach_max - 1e-6, 1000)
    angle = rng.uniform(-np.pi, np.pi, 1000)
    x = radius[:, None] * np.column_stack([np.cos(angle), np.sin(angle)])
    q = k2.inverse_kinematics(x, elbow_up=elbow_up)
    np.testing.assert_allclose(k2.forward_kinematics(q), x, atol=1e-9)
    assert np.all(q[:, 1] >= 0) if elbow_up else np.all(q[:, 1] <= 0)


def test_the_two_branches_are_mirror_images():
    x = np.array([0.6, 0.3])
    up, down = k2.inverse_kinematics(x, elbow_up=True), k2.inverse_kinematics(x, elbow_up=False)
    assert up[1] == pytest.approx(-down[1])
    phi = np.arctan2(x[1], x[0])  # both elbows mirror about the line to the target
    assert up[0] - phi == pytest.approx(-(down[0] - phi))


@pytest.mark.parametrize("x", [(0.95, 0.0), (0.0, 0.05), (0.0, 0.0), (-0.7, 0.7)])
def test_unreachable_target_raises_clear_error(x):
    with pytest.raises(ValueError, match="outside the workspace"):
        k2.inverse_kinematics(x)


def test_a_target_too_far_to_square_is_named_without_overflow_warnings():
    """|x| = 1e308 overflowed x**2 and printed NumPy's warning before the error."""
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        with pytest.raises(ValueError, match=r"distance 1e\+308 m .* outside the workspace"):
            k2.inverse_kinematics([1e308, 0.0])
        assert k2.is_reachable([[1e308, 1e308], [0.5, 0.2]]).tolist() == [False, True]


def test_clip_moves_an_unreachable_target_to_the_boundary_and_warns():
    with pytest.warns(RuntimeWarning, match="clipped"):
        q = k2.inverse_kinematics([1.2, 0.0], clip=True)
    np.testing.assert_allclose(k2.forward_kinematics(q), [0.9, 0.0], atol=1e-12)


def test_bad_arguments():
    with pytest.raises(ValueError, match="elbow_up must be True or False, got 'down'"):
        k2.inverse_kinematics([0.5, 0.2], k2.LAB_ARM, "down")
    with pytest.raises(ValueError, match="2 components"):
        k2.forward_kinematics([0.1, 0.2, 0.3])
    for length in (-0.4, 0.0):  # a link of no length is no link
        with pytest.raises(ValueError, match="l2 .a link length. must be a positive number"):
            k2.Planar2R(0.5, length)
    # a NaN target used to come back as NaN angles, silently
    with pytest.raises(ValueError, match="x has entries that are not finite"):
        k2.inverse_kinematics([np.nan, 0.2])
    with pytest.raises(ValueError, match="qdot has entries that are not finite"):
        k2.jdot_qdot([0.1, 0.2], [np.inf, 0.0])
    with pytest.raises(ValueError, match="q must be numbers"):
        k2.jacobian("ab")


def test_joint_reference_reproduces_the_cartesian_one():
    from labsupport.trajectories import circle_2d

    t = np.linspace(0, 6, 301)
    ref = circle_2d(t, (0.5, 0.2), 0.15, 6.0)
    jref = k2.joint_reference(ref)
    np.testing.assert_allclose(k2.forward_kinematics(jref.pos), ref.pos, atol=1e-12)
    np.testing.assert_allclose(np.einsum("nij,nj->ni", k2.jacobian(jref.pos), jref.vel), ref.vel, atol=1e-12)
    xddot = np.einsum("nij,nj->ni", k2.jacobian(jref.pos), jref.acc) + k2.jdot_qdot(jref.pos, jref.vel)
    np.testing.assert_allclose(xddot, ref.acc, atol=1e-12)
    # and qdot_d is the time derivative of q_d (central differences)
    dt = t[1] - t[0]
    np.testing.assert_allclose(np.gradient(jref.pos, dt, axis=0)[1:-1], jref.vel[1:-1], atol=1e-3)


def test_a_path_that_touches_the_workspace_edge_is_refused_as_singular():
    """A circle centred 0.6 m out with radius 0.3 m touches the outer edge at t = 0, where 0.6 + 0.3
    rounds below 0.9: q2 came out 3e-8 rad, det J = 6.7e-9 passed the old bound of 1e-9, and the
    joint acceleration returned was 1e9 rad/s². A bound that is not a positive number used to
    switch the check off (0, negative, NaN) or fail inside NumPy (None, text)."""
    from labsupport.trajectories import circle_2d

    edge = circle_2d(0.0, (0.6, 0.0), 0.3, 1.0)
    assert k2.is_reachable(edge.pos) and k2.inverse_kinematics(edge.pos)[1] < 1e-7
    with pytest.raises(ValueError, match="singular configuration"):
        k2.joint_reference(edge)
    # the same touch 40 degrees round, where no entry of J vanishes, and a circle that passes just
    # inside, where |det J| = l1 l2 |sin q2| = 0.2 sin(0.01) = 2e-3 is far from the bound
    turn, t_turn = np.array([np.cos(0.7), np.sin(0.7)]), 0.7 / (2 * np.pi)  # one turn a second
    with pytest.raises(ValueError, match="singular configuration"):
        k2.joint_reference(circle_2d(t_turn, 0.6 * turn, 0.3, 1.0))
    reach = np.sqrt(0.5**2 + 0.4**2 + 2 * 0.5 * 0.4 * np.cos(0.01))
    near = k2.joint_reference(circle_2d(t_turn, (reach - 0.3) * turn, 0.3, 1.0))
    np.testing.assert_allclose(abs(near.pos[1]), 0.01, rtol=1e-9)
    inside = circle_2d(0.0, (0.5, 0.2), 0.15, 6.0)
    for bad in (0.0, -1.0, np.nan, None, "x"):
        with pytest.raises(ValueError, match="min_det must be"):
            k2.joint_reference(inside, min_det=bad)


def test_the_ik_of_a_point_rounded_just_past_the_outer_edge_is_the_stretched_arm():
    """On 287 of these 2000 points of the 0.9 m circle, cos q2 comes out 1 + 2e-16 or more: within
    the rounding tolerance, so the point counts as reachable, and the IK must not take arccos of it."""
    a = np.linspace(0.0, 2 * np.pi, 2000)
    edge = 0.9 * np.stack([np.cos(a), np.sin(a)], axis=1)
    assert (k2.elbow_cosine(edge) > 1).sum() > 100
    for elbow_up in (True, False):
        q = k2.inverse_kinematics(edge, elbow_up=elbow_up)
        np.testing.assert_allclose(q[:, 1], 0.0, atol=1e-7)
        np.testing.assert_allclose(k2.forward_kinematics(q), edge, atol=1e-12)


def test_annulus_sample_is_seeded_and_reachable():
    a = k2.sample_annulus(np.random.default_rng(42))
    b = k2.sample_annulus(np.random.default_rng(42))
    np.testing.assert_array_equal(a, b)
    assert 0.15 <= np.linalg.norm(a) <= 0.85
    np.testing.assert_array_equal(k2.sample_annulus(42), a)  # a seed makes the same generator
    with pytest.raises(ValueError, match=r"rng must be a NumPy generator, such as np.random.default_rng\(42\)"):
        k2.sample_annulus("42")


def test_the_annulus_sampler_refuses_a_margin_that_is_not_a_distance():
    """A negative margin let targets fall outside the workspace; None ended in a raw TypeError."""
    for margin, message in ((-0.05, "margin must be non-negative"), (None, "margin must be a number, got None")):
        with pytest.raises(ValueError, match=message):
            k2.sample_annulus(0, margin=margin)
    arm = k2.Planar2R(0.5, 0.25)  # annulus [0.25, 0.75] m: a margin of 0.25 m leaves one radius, 0.5 m
    with pytest.raises(ValueError, match="leaves no room in the workspace annulus"):
        k2.sample_annulus(0, arm, margin=0.25)
    assert 0.25 + 0.249 <= np.linalg.norm(k2.sample_annulus(0, arm, margin=0.249)) <= 0.75 - 0.249


def test_a_whole_reference_where_positions_belong_is_named():
    """k2.inverse_kinematics(circle_2d(0, ...)) read (pos, vel, acc) as three targets and returned
    three solutions; k2.joint_reference of a sampled reference or of bare points failed deep in
    NumPy, or read three points as pos, vel and acc."""
    from labsupport.trajectories import Reference, circle_2d, sample, set_point

    ref = circle_2d(0.0, (0.5, 0.2), 0.15, 6.0)
    with pytest.raises(ValueError, match=r"x must be positions, got a whole Reference .*pass its position, ref\.pos"):
        k2.inverse_kinematics(ref)
    with pytest.raises(ValueError, match=r"got a whole Reference"):
        k2.inverse_kinematics(set_point(0.0, [0.5, 0.2]))
    np.testing.assert_allclose(k2.forward_kinematics(k2.inverse_kinematics(ref.pos)), ref.pos, atol=1e-12)
    points = np.array([[0.5, 0.2], [0.5, 0.1], [0.4, 0.2]])
    with pytest.raises(ValueError, match=r"ref must be a trajectories\.Reference .*got ndarray"):
        k2.joint_reference(points)
    sampled = sample(lambda t: circle_2d(t, (0.5, 0.2), 0.15, 6.0), 0.01, 1.0)
    with pytest.raises(ValueError, match=r"got SampledReference"):
        k2.joint_reference(sampled)
    with pytest.raises(ValueError, match=r"ref\.vel must have 2 components on its last axis, got shape \(\)"):
        k2.joint_reference(Reference(np.array([0.5, 0.2]), np.float64(0.0), np.float64(0.0)))
    with pytest.raises(ValueError, match=r"one shape, got \(2,\), \(3, 2\) and \(2,\)"):
        k2.joint_reference(Reference(ref.pos, np.zeros((3, 2)), ref.acc))
    joint = k2.joint_reference(ref)  # the right call still works, and its rates match the path's
    np.testing.assert_allclose(k2.jacobian(joint.pos) @ joint.vel, ref.vel, atol=1e-12)


def test_clip_must_be_true_or_false():
    """clip="no" would otherwise clip silently, and move the target."""
    with pytest.raises(ValueError, match="clip must be True or False"):
        k2.inverse_kinematics([0.8, 0.0], clip="no")


@pytest.mark.parametrize(
    "call",
    [
        lambda arm: k2.forward_kinematics([0.1, 0.2], arm),
        lambda arm: k2.elbow_position([0.1, 0.2], arm),
        lambda arm: k2.jacobian([0.1, 0.2], arm),
        lambda arm: k2.jdot_qdot([0.1, 0.2], [0.3, 0.4], arm),
        lambda arm: k2.is_reachable([0.5, 0.2], arm),
        lambda arm: k2.inverse_kinematics([0.5, 0.2], arm),
        lambda arm: k2.sample_annulus(1, arm),
    ],
)
def test_an_arm_that_is_not_a_planar2r_is_named(call):
    """Link lengths given as a tuple failed on ``arm.l1`` (AttributeError)."""
    with pytest.raises(ValueError, match=r"arm must be a Planar2R, such as Planar2R\(l1=0.5, l2=0.4\)"):
        call((0.5, 0.4))
    call(k2.Planar2R(0.5, 0.4))
