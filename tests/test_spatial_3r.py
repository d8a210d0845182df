"""The 3R spatial arm: model against kinematics, IK round trips, Jacobians, target samplers."""

import mujoco
import numpy as np
import pytest

import labsupport  # noqa: F401
from labsupport.dynamics import site_jacobian, site_jdot_qdot
from labsupport.kinematics import spatial_3r as k
from labsupport.plants import load_model


@pytest.fixture(scope="module")
def arm():
    return load_model("spatial_3r")


def test_model_parameters(arm):
    model, data = arm
    assert model.nv == 3 and model.nu == 3
    assert model.opt.timestep == 0.002 and model.opt.integrator == mujoco.mjtIntegrator.mjINT_RK4
    np.testing.assert_allclose(model.opt.gravity, [0, 0, -9.81])
    np.testing.assert_allclose(model.body_mass[1:], [1.0, 1.0, 0.5])
    # uniform rods: m l^2 / 12 across the rod
    np.testing.assert_allclose(model.body_inertia[1, :2], 1 / 12, rtol=1e-5)
    np.testing.assert_allclose(model.body_inertia[3, 1:], 0.5 / 12, rtol=1e-5)
    np.testing.assert_allclose(data.site("end_effector").xpos, [1.0, 0.0, 2.0])


def test_fk_matches_mujoco(arm):
    model, data = arm
    rng = np.random.default_rng(0)
    for _ in range(200):
        q = rng.uniform(-np.pi, np.pi, 3)
        data.qpos[:] = q
        mujoco.mj_kinematics(model, data)
        np.testing.assert_allclose(k.forward_kinematics(q), data.site_xpos[0], atol=1e-12)


@pytest.mark.parametrize("elbow_up", [True, False])
def test_ik_round_trip_1000_targets(elbow_up):
    targets = k.sample_targets(np.random.default_rng(42), 1000)
    for x in targets:
        q = k.inverse_kinematics(x, elbow_up=elbow_up)
        np.testing.assert_allclose(k.forward_kinematics(q), x, atol=1e-10)
        theta = q[2] + np.pi / 2   # relative angle of the planar 2R: positive on the elbow-up branch
        assert (np.sin(theta) > 0) == elbow_up


def test_ik_branches_are_mirror_images_and_up_is_higher():
    for x in k.sample_targets(np.random.default_rng(3), 200):
        up, down = k.inverse_kinematics(x, True), k.inverse_kinematics(x, False)
        assert not np.allclose(up, down)
        assert np.cos(up[1]) > np.cos(down[1])   # elbow height above the shoulder
        np.testing.assert_allclose(up[0], down[0])


def test_ik_recovers_the_initial_configuration():
    q0 = np.array([0.0, np.pi / 6, -np.pi / 4])
    np.testing.assert_allclose(k.inverse_kinematics(k.forward_kinematics(q0)), q0, atol=1e-12)


def test_unreachable_target_raises_clear_error():
    with pytest.raises(ValueError, match="out of reach"):
        k.inverse_kinematics([2.5, 0.0, 1.0])
    with pytest.raises(ValueError, match="z axis"):
        k.inverse_kinematics([0.0, 0.0, 2.5])
    with pytest.raises(ValueError, match="shape"):
        k.inverse_kinematics([1.0, 0.0])


def test_jacobian_matches_finite_differences_and_mujoco(arm):
    model, data = arm
    rng = np.random.default_rng(1)
    eps = 1e-6
    for _ in range(50):
        q = rng.uniform(-np.pi, np.pi, 3)
        fd = np.column_stack([(k.forward_kinematics(q + eps * e) - k.forward_kinematics(q - eps * e)) / (2 * eps)
                              for e in np.eye(3)])
        np.testing.assert_allclose(k.jacobian(q), fd, atol=1e-8)
        data.qpos[:] = q
        mujoco.mj_forward(model, data)
        np.testing.assert_allclose(k.jacobian(q), site_jacobian(model, data, "end_effector")[:3], atol=1e-12)


def test_jdot_qdot_matches_finite_differences_and_mujoco(arm):
    model, data = arm
    rng = np.random.default_rng(2)
    h = 1e-6
    for _ in range(50):
        q, w = rng.uniform(-np.pi, np.pi, 3), rng.uniform(-2, 2, 3)
        # d/dt (J(q(t)) qdot) along q(t) = q + t w, at t = 0
        fd = (k.jacobian(q + h * w) @ w - k.jacobian(q - h * w) @ w) / (2 * h)
        np.testing.assert_allclose(k.jdot_qdot(q, w), fd, atol=1e-7)
        data.qpos[:], data.qvel[:] = q, w
        mujoco.mj_forward(model, data)
        np.testing.assert_allclose(k.jdot_qdot(q, w), site_jdot_qdot(model, data, "end_effector")[:3], atol=1e-10)


def test_sampler_returns_only_reachable_points_away_from_singularities():
    m = k.TargetMargins()
    pts = k.sample_targets(np.random.default_rng(7), 5000, m)
    assert pts.shape == (5000, 3)
    d = np.linalg.norm(pts - k.LAB_ARM.shoulder, axis=1)
    assert d.max() <= k.LAB_ARM.max_reach - m.outer and d.min() >= k.LAB_ARM.min_reach + m.inner
    assert np.hypot(pts[:, 0], pts[:, 1]).min() >= m.axis and pts[:, 2].min() >= m.min_height
    assert all(k.is_reachable(x) for x in pts)
    # seeded: the same draws again
    np.testing.assert_array_equal(pts, k.sample_targets(np.random.default_rng(7), 5000, m))
    with pytest.raises(ValueError, match="Generator"):
        k.sample_targets(7, 3)


def test_lab_sampler_is_wrong_but_its_seed0_target_is_reachable():
    frac = k.lab_sampler_unreachable_fraction(200_000, seed=1)
    assert 0.165 < frac < 0.18          # about 17 % of the lab's draws cannot be reached
    x = k.lab_target(0)
    np.testing.assert_allclose(x, [-0.01617995, 0.1294726, 2.02450769], atol=1e-8)
    assert k.is_reachable(x)
    # an independent count: distance from the shoulder > 2 m
    rng = np.random.default_rng(5)
    draws = np.array([k.lab_sampler_target(rng) for _ in range(20_000)])
    frac2 = np.mean(np.linalg.norm(draws - [0, 0, 1], axis=1) > 2)
    assert abs(frac2 - frac) < 0.01
