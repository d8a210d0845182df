"""The simulation loop: logging conventions, torque limits, sampled references, and
divergence detection."""

import mujoco
import numpy as np
import pytest

import labsupport  # noqa: F401
from labsupport import sim
from labsupport.dynamics import mass_matrix
from labsupport.plants import load_model
from labsupport.trajectories import Reference, circle_2d


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


def test_torque_limit_clips(arm):
    model, data = arm
    log = sim.simulate(model, data, constant([50.0, -50.0]), 0.01, torque_limit=[5.0, 2.0])
    np.testing.assert_array_equal(log.tau, np.tile([5.0, -2.0], (5, 1)))


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


def test_sampled_reference_matches_direct_calls():
    ref = lambda t: circle_2d(t, (0.5, 0.2), 0.15, 6.0)  # noqa: E731
    sampled = sim.SampledReference(ref, 0.002, chunk=64)
    for t in (0.0, 0.002 * 63, 0.002 * 64, 0.002 * 1000, 0.0031):   # on the grid, chunk edges, off the grid
        r = ref(t)
        np.testing.assert_allclose(sampled.at(t), [*r.pos, *r.vel, *r.acc], atol=1e-12)
    shifted = sim.SampledReference(ref, 0.002, offset=0.001)
    np.testing.assert_allclose(shifted.at(0.004)[:2], ref(0.005).pos, atol=1e-12)


def test_sampled_reference_accepts_scalar_only_functions():
    def scalar_only(t):
        if np.ndim(t):
            raise TypeError("scalars only")
        return Reference(np.sin(t), np.cos(t), -np.sin(t))
    sampled = sim.SampledReference(scalar_only, 0.01, chunk=8)
    np.testing.assert_allclose(sampled.at(0.1), [np.sin(0.1), np.cos(0.1), -np.sin(0.1)], atol=1e-12)


def test_divergence_is_detected_and_names_time_and_state(arm):
    """Positive velocity feedback makes the arm run away; MuJoCo flags it (and resets the
    state); the loop stops with the time and the last good state."""
    model, data = arm
    gain = np.array([0.0, 50.0])
    with pytest.raises(sim.SimulationDiverged, match=r"diverged at t = \d+\.\d+ s .*BADQ") as err:
        sim.simulate(model, data, lambda m, d: gain * d.qvel + np.array([1.0, 0.0]), 5.0, q0=[0.1, 1.0])
    exc = err.value
    assert 0 < exc.t < 5.0
    assert np.all(np.isfinite(exc.qpos)) and np.abs(exc.qvel).max() > 1e3   # the runaway is visible
    assert "q = " in str(exc) and "qdot = " in str(exc)


def test_non_finite_torque_is_reported(arm):
    model, data = arm
    with pytest.raises(sim.SimulationDiverged, match="controller returned tau"):
        sim.simulate(model, data, lambda m, d: np.array([np.nan, 0.0]) if d.time > 0.01 else np.zeros(2), 0.1)


def test_bad_inputs_raise_value_errors(arm):
    model, data = arm
    with pytest.raises(ValueError, match="duration"):
        sim.simulate(model, data, constant([0.0, 0.0]), 0.0)
    with pytest.raises(ValueError, match="shape"):
        sim.simulate(model, data, constant([0.0, 0.0, 0.0]), 0.01)
    with pytest.raises(ValueError, match="q0"):
        sim.simulate(model, data, constant([0.0, 0.0]), 0.01, q0=[0.0])
    with pytest.raises(ValueError, match="site"):
        sim.simulate(model, data, constant([0.0, 0.0]), 0.01, site="hand")


def test_from_state_torque_adapts_single_joint_laws():
    model, data = load_model("single_joint")
    seen = []
    ctrl = sim.from_state_torque(lambda t, x: seen.append((t, *x)) or 0.5)
    data.qpos[0], data.qvel[0], data.time = 0.2, -1.0, 0.3
    np.testing.assert_array_equal(ctrl(model, data), [0.5])
    assert seen == [(0.3, 0.2, -1.0)]
