"""labsupport.dynamics against independent computations (MuJoCo's own products, finite differences)."""

import copy
import re
import subprocess
import sys
from pathlib import Path

import mujoco
import numpy as np
import pytest

from labsupport import dynamics
from labsupport.plants import load_model

# A small spatial 3-DOF arm with offsets, so that M, J and Jdot are all non-trivial.
ARM = """
<mujoco>
  <option gravity="0 0 -9.81"/>
  <worldbody>
    <body>
      <joint name="a" type="hinge" axis="0 0 1"/>
      <geom type="capsule" fromto="0 0 0 0 0 0.4" size="0.04" mass="1.2"/>
      <body pos="0 0.05 0.4">
        <joint name="b" type="hinge" axis="0 1 0"/>
        <geom type="capsule" fromto="0 0 0 0.5 0 0" size="0.03" mass="0.9"/>
        <body pos="0.5 0 0">
          <joint name="c" type="hinge" axis="0 1 0"/>
          <geom type="capsule" fromto="0 0 0 0.4 0 0.1" size="0.02" mass="0.6"/>
          <site name="tip" pos="0.4 0 0.1"/>
        </body>
      </body>
    </body>
  </worldbody>
</mujoco>
"""


@pytest.fixture
def arm():
    model = mujoco.MjModel.from_xml_string(ARM)
    return model, mujoco.MjData(model)


def _set_state(model, data, rng):
    data.qpos[:] = rng.uniform(-np.pi, np.pi, model.nq)
    data.qvel[:] = rng.normal(0, 2, model.nv)
    mujoco.mj_forward(model, data)


def _tip(model, data, q):
    scratch = mujoco.MjData(model)
    scratch.qpos[:] = q
    mujoco.mj_kinematics(model, scratch)
    return scratch.site_xpos[0].copy()


def test_mass_matrix_matches_mujoco_products(arm):
    model, data = arm
    rng = np.random.default_rng(0)
    for _ in range(20):
        _set_state(model, data, rng)
        M = dynamics.mass_matrix(model, data)
        columns = np.empty_like(M)
        for j in range(model.nv):
            col = np.zeros(model.nv)
            mujoco.mj_mulM(model, data, col, np.eye(model.nv)[j])
            columns[:, j] = col
        np.testing.assert_allclose(M, columns, atol=1e-12)
        np.testing.assert_allclose(M, M.T, atol=1e-12)
        assert np.all(np.linalg.eigvalsh(M) > 0)
        x = rng.normal(size=model.nv)
        np.testing.assert_allclose(dynamics.solve_mass(model, data, M @ x), x, atol=1e-10)


def test_mass_times_is_the_dense_mass_matrix_times_the_vector(arm):
    """mj_mulM on the sparse inertia against the dense M built column by column by mj_fullM."""
    model, data = arm
    rng = np.random.default_rng(6)
    out = np.full(model.nv, np.nan)
    for _ in range(20):
        _set_state(model, data, rng)
        v = rng.normal(size=model.nv)
        expected = dynamics.mass_matrix(model, data) @ v
        np.testing.assert_allclose(dynamics.mass_times(model, data, v), expected, rtol=1e-12, atol=1e-14)
        assert dynamics.mass_times(model, data, list(v), out=out) is out
        np.testing.assert_allclose(out, expected, rtol=1e-12, atol=1e-14)


def test_mass_matrix_uses_the_mujoco3_signature_when_qM_exists(monkeypatch):
    """On MuJoCo 3.x mj_fullM is (model, dst, qM); the function must call it that way."""
    calls = []

    def fake_fullm(model, dst, qm):
        calls.append(qm)
        dst[:] = 7.0

    class Data3:
        qM = np.array([1.0, 2.0])

    class Model:
        nv = 2

    monkeypatch.setattr(dynamics, "FULLM_TAKES_DATA", False)
    monkeypatch.setattr(dynamics.mujoco, "mj_fullM", fake_fullm)
    model, data = Model(), Data3()
    data.model = model  # as an MjData knows the MjModel it was made with
    out = dynamics.mass_matrix(model, data)
    assert calls and calls[0] is Data3.qM and np.all(out == 7.0)


def test_bias_forces_are_gravity_at_rest(arm):
    model, data = arm
    data.qpos[:] = [0.3, -0.4, 0.8]
    mujoco.mj_forward(model, data)

    # gravity torque = -dV/dq, from finite differences of the potential energy
    def potential(q):
        d = mujoco.MjData(model)
        d.qpos[:] = q
        mujoco.mj_forward(model, d)
        return -sum(model.body_mass[i] * model.opt.gravity @ d.xipos[i] for i in range(model.nbody))

    h = 1e-6
    grad = np.array([(potential(data.qpos + h * e) - potential(data.qpos - h * e)) / (2 * h) for e in np.eye(3)])
    np.testing.assert_allclose(dynamics.bias_forces(data), grad, atol=1e-6)


def test_site_jacobian_matches_finite_differences(arm):
    model, data = arm
    rng = np.random.default_rng(1)
    for _ in range(10):
        _set_state(model, data, rng)
        J = dynamics.site_jacobian(model, data, "tip")
        h = 1e-6
        fd = np.column_stack(
            [
                (_tip(model, data, data.qpos + h * e) - _tip(model, data, data.qpos - h * e)) / (2 * h)
                for e in np.eye(model.nv)
            ]
        )
        np.testing.assert_allclose(J[:3], fd, atol=1e-8)


def test_jdot_qdot_matches_finite_difference_of_J_qdot(arm):
    model, data = arm
    rng = np.random.default_rng(2)
    for _ in range(10):
        _set_state(model, data, rng)
        h = 1e-6

        def j_qdot(q):
            d = mujoco.MjData(model)
            d.qpos[:] = q
            mujoco.mj_kinematics(model, d)
            mujoco.mj_comPos(model, d)
            return dynamics.site_jacobian(model, d, "tip") @ data.qvel

        fd = (j_qdot(data.qpos + h * data.qvel) - j_qdot(data.qpos - h * data.qvel)) / (2 * h)
        np.testing.assert_allclose(dynamics.site_jdot_qdot(model, data, "tip"), fd, atol=1e-6)


def test_task_space_inertia_equals_M_Jinv_for_a_square_jacobian(arm):
    model, data = arm
    rng = np.random.default_rng(3)
    for _ in range(10):
        _set_state(model, data, rng)
        J = dynamics.site_jacobian(model, data, "tip")[:3]
        if abs(np.linalg.det(J)) < 1e-3:
            continue
        lam = dynamics.task_space_inertia(model, data, J)
        M = dynamics.mass_matrix(model, data)
        np.testing.assert_allclose(J.T @ lam, M @ np.linalg.inv(J), rtol=1e-8, atol=1e-10)


def test_task_space_inertia_names_a_singular_jacobian(arm):
    model, data = arm
    mujoco.mj_forward(model, data)
    J = dynamics.site_jacobian(model, data, "tip")  # all six rows, for three joints: rank 3
    with pytest.raises(ValueError, match="J has lost rank.*Λ does not exist here.*damping > 0"):
        dynamics.task_space_inertia(model, data, J)
    # damped, Λ is the inverse of J M⁻¹ Jᵀ + λ I, here computed with NumPy's inverse of the dense M
    M = dynamics.mass_matrix(model, data)
    expected = np.linalg.inv(J @ np.linalg.inv(M) @ J.T + 1e-3 * np.eye(6))
    np.testing.assert_allclose(dynamics.task_space_inertia(model, data, J, damping=1e-3), expected, rtol=1e-9)


@pytest.mark.parametrize("q2", [1e-10, 1e-12, np.pi - 1e-9])
def test_task_space_inertia_of_a_nearly_stretched_or_folded_arm_is_named_as_such(q2):
    """Near q2 = 0 or pi, Λ was either 1.5e16 kg with no word, or refused with advice to run
    mj_forward, which had been run; jacobian_solve refuses the same J as singular."""
    model, data = load_model("planar_2r")
    data.qpos[:] = [0.3, q2]
    mujoco.mj_forward(model, data)
    J = dynamics.site_jacobian(model, data, "end_effector")[:2]
    with pytest.raises(ValueError, match="singular"):
        dynamics.jacobian_solve(J, np.array([1.0, 0.0]))
    with pytest.raises(ValueError, match="J has lost rank.*stretched out or folded"):
        dynamics.task_space_inertia(model, data, J)
    data.qpos[:] = [0.3, 1.0]  # a bent arm: Λ exists, and Jᵀ Λ = M J⁻¹
    mujoco.mj_forward(model, data)
    J = dynamics.site_jacobian(model, data, "end_effector")[:2]
    lam = dynamics.task_space_inertia(model, data, J)
    np.testing.assert_allclose(J.T @ lam, dynamics.mass_matrix(model, data) @ np.linalg.inv(J), rtol=1e-9)


def test_model_and_data_of_the_wrong_kind_are_named(arm):
    model, data = arm
    with pytest.raises(ValueError, match="model and data are swapped"):
        dynamics.mass_matrix(data, model)
    with pytest.raises(ValueError, match="data must be a mujoco.MjData"):
        dynamics.mass_matrix(model, data.qpos)
    with pytest.raises(ValueError, match="bias_forces takes the data"):
        dynamics.bias_forces(model)


@pytest.mark.parametrize(
    "call",
    [
        lambda m, d: dynamics.mass_times(m, d, np.ones(3)),
        lambda m, d: dynamics.solve_mass(m, d, np.ones(3)),
        lambda m, d: dynamics.site_jacobian(m, d, "tip"),
        lambda m, d: dynamics.site_jdot_qdot(m, d, "tip"),
        lambda m, d: dynamics.task_space_inertia(m, d, np.eye(3)),
    ],
)
def test_every_helper_names_a_model_and_data_swapped_or_missing(arm, call):
    """Each helper says which of the two is wrong, never an AttributeError from inside, nor an
    error that blames another argument (a missing data once blamed ``out``)."""
    model, data = arm
    mujoco.mj_forward(model, data)
    with pytest.raises(ValueError, match="model and data are swapped"):
        call(data, model)
    with pytest.raises(ValueError, match="data must be a mujoco.MjData"):
        call(model, None)


def test_task_space_inertia_on_data_never_forwarded_says_to_run_mj_forward(arm):
    model, data = arm  # a fresh MjData: MuJoCo has computed no mass matrix yet
    with pytest.raises(ValueError, match=r"run mujoco.mj_forward\(model, data\)"):
        dynamics.task_space_inertia(model, data, np.eye(3))
    mujoco.mj_forward(model, data)
    Lam = dynamics.task_space_inertia(model, data, np.eye(3).tolist())  # J = I: Λ = M
    np.testing.assert_allclose(Lam, dynamics.mass_matrix(model, data), rtol=1e-10)


def test_unknown_site_is_named(arm):
    model, data = arm
    with pytest.raises(ValueError, match="'hand'.*tip"):
        dynamics.site_jacobian(model, data, "hand")


@pytest.mark.parametrize("site", [1, -1, 7, np.int64(3), 0.0, True, None])
def test_a_site_id_out_of_range_is_refused(arm, site):
    """An id MuJoCo does not have would make it read past its arrays and return garbage."""
    model, data = arm
    assert model.nsite == 1
    with pytest.raises(ValueError, match=r"its sites are \['tip'\], by name or by id from 0 to 0"):
        dynamics.site_jacobian(model, data, site)
    with pytest.raises(ValueError, match="id from 0 to 0"):
        dynamics.site_jdot_qdot(model, data, site)


def test_a_site_id_in_range_is_taken_as_is(arm):
    model, data = arm
    by_name = dynamics.site_jacobian(model, data, "tip")
    for site in (0, np.int32(0)):
        np.testing.assert_array_equal(dynamics.site_jacobian(model, data, site), by_name)


def test_jacobian_solve_never_calls_a_nan_jacobian_singular_nor_returns_numbers():
    """Where MuJoCo's factorisation reports NaN as rank loss, the error says "not finite"; where it
    does not (MuJoCo 3), the result is NaN, never finite numbers."""
    J = np.eye(3)
    J[1, 2] = np.nan
    try:
        x = dynamics.jacobian_solve(J, np.ones(3))
    except ValueError as err:
        assert "not finite" in str(err)
    else:
        assert not np.isfinite(x).all()


def test_jacobian_solve_is_the_inverse_and_refuses_a_singular_jacobian():
    rng = np.random.default_rng(3)
    for _ in range(20):
        J, y = rng.normal(size=(3, 3)), rng.normal(size=3)
        np.testing.assert_allclose(dynamics.jacobian_solve(J, y), np.linalg.solve(J, y), rtol=1e-8, atol=1e-10)
    J = np.array([[0.9, 0.4], [0.0, 0.0]])  # the 2R stretched out along x
    with pytest.raises(ValueError, match="singular"):
        dynamics.jacobian_solve(J, np.array([1.0, 0.0]))


def test_the_mass_matrix_of_data_never_evaluated_is_refused_not_zero():
    """mass_matrix(model, mujoco.MjData(model)) returned a matrix of zeros without a word."""
    model, _ = load_model("planar_2r")
    fresh = mujoco.MjData(model)
    fresh.qpos[:] = [0.3, 1.2]
    with pytest.raises(ValueError, match=r"no mass matrix yet .*run mujoco\.mj_forward\(model, data\)"):
        dynamics.mass_matrix(model, fresh)
    mujoco.mj_forward(model, fresh)
    M = dynamics.mass_matrix(model, fresh)
    np.testing.assert_allclose(M, M.T)
    np.testing.assert_array_less(0.0, np.linalg.eigvalsh(M))  # symmetric positive definite


def test_the_jacobian_of_a_scratch_data_without_kinematics_is_named_as_such():
    """A scratch MjData set to a reference configuration without mj_comPos gives an all-zero
    Jacobian; it used to be called singular ("the arm is stretched out or folded"), which it
    was not."""
    model, _ = load_model("planar_2r")
    scratch = mujoco.MjData(model)
    scratch.qpos[:] = [0.3, 1.2]
    mujoco.mj_kinematics(model, scratch)  # mj_comPos forgotten
    J = dynamics.site_jacobian(model, scratch, "end_effector")[:2]
    with pytest.raises(ValueError, match=r"all zeros: its data holds no kinematics yet.*then mujoco\.mj_comPos"):
        dynamics.jacobian_solve(J, np.array([1.0, 0.0]))
    mujoco.mj_comPos(model, scratch)
    J = dynamics.site_jacobian(model, scratch, "end_effector")[:2]
    np.testing.assert_allclose(J @ dynamics.jacobian_solve(J, np.array([1.0, 0.0])), [1.0, 0.0], atol=1e-12)


def test_jdot_qdot_fills_out_and_returns_a_fresh_array_otherwise(arm):
    model, data = arm
    _set_state(model, data, np.random.default_rng(4))
    first = dynamics.site_jdot_qdot(model, data, "tip")
    out = np.full(6, np.nan)
    assert dynamics.site_jdot_qdot(model, data, "tip", out=out) is out
    np.testing.assert_array_equal(out, first)
    data.qvel[:] *= 2.0  # Jdot qdot is quadratic in qdot; the first result must not change with it
    mujoco.mj_forward(model, data)
    np.testing.assert_allclose(dynamics.site_jdot_qdot(model, data, "tip"), 4.0 * first, rtol=1e-9, atol=1e-12)
    assert not np.allclose(first, 4.0 * first)


def test_jacobian_solve_fills_out():
    rng = np.random.default_rng(7)
    J, y, out = rng.normal(size=(3, 3)), rng.normal(size=3), np.full(3, np.nan)
    assert dynamics.jacobian_solve(J, y, out=out) is out
    np.testing.assert_allclose(out, np.linalg.solve(J, y), rtol=1e-8, atol=1e-10)


def test_jacobian_solve_takes_a_wide_jacobian_and_any_memory_layout():
    rng = np.random.default_rng(5)
    J, y = rng.normal(size=(2, 3)), rng.normal(size=2)
    x = dynamics.jacobian_solve(np.asfortranarray(J), list(y))
    np.testing.assert_allclose(J @ x, y, atol=1e-12)
    np.testing.assert_allclose(dynamics.jacobian_solve(J.tolist(), y.astype(np.float32)), x, atol=1e-6)
    np.testing.assert_allclose(x, np.linalg.pinv(J) @ y, atol=1e-12)  # the least-norm solution


def test_jacobian_solve_names_the_shapes_it_needs():
    with pytest.raises(ValueError, match=r"\(d, nv\).*shape \(3, 2\)"):
        dynamics.jacobian_solve(np.ones((3, 2)), np.ones(3))
    with pytest.raises(ValueError, match=r"rhs of shape \(3,\)"):
        dynamics.jacobian_solve(np.eye(2), np.ones(3))


@pytest.mark.parametrize(
    ("call", "message"),
    [
        (lambda m, d: dynamics.mass_matrix(m, d, out=np.zeros((2, 2))), r"\(3, 3\), got a float64 array of shape"),
        (lambda m, d: dynamics.mass_matrix(m, d, out=np.zeros((3, 3), int)), "got a int64 array"),
        (lambda m, d: dynamics.mass_matrix(m, d, out=np.zeros((3, 3), order="F")), "not C-contiguous"),
        (lambda m, d: dynamics.site_jacobian(m, d, "tip", out=np.zeros((3, 3))), r"shape \(6, 3\), got"),
        (lambda m, d: dynamics.site_jdot_qdot(m, d, "tip", out=np.zeros(3)), r"shape \(6,\), got"),
        (lambda m, d: dynamics.mass_times(m, d, np.ones(3), out=np.zeros(2)), r"mass_times: out .* shape \(3,\), got"),
        (lambda m, d: dynamics.mass_times(m, d, np.ones(2)), r"v must have shape \(3,\)"),
        (lambda m, d: dynamics.jacobian_solve(np.eye(3), np.ones(3), out=np.zeros(2)), r"jacobian_solve: out"),
        (lambda m, d: dynamics.jacobian_solve(np.eye(3), np.ones(3), out=np.zeros(3, int)), "got a int64 array"),
        (lambda m, d: dynamics.jacobian_solve(np.eye(3), np.ones(3), out=np.zeros((3, 2))[:, 0]), "not C-contiguous"),
        (
            lambda m, d: dynamics.jacobian_solve(np.eye(3), np.ones(3), min_pivot="tiny"),
            "min_pivot must be a positive number",
        ),
        (
            lambda m, d: dynamics.jacobian_solve(np.ones((2, 2)), [1.0, 0.0], min_pivot=0.0),
            "min_pivot must be a positive",
        ),
        (lambda m, d: dynamics.task_space_inertia(m, d, np.full((3, 3), np.nan)), "jac must be finite"),
        (lambda m, d: dynamics.task_space_inertia(m, d, np.ones(3)), r"jac must be a Jacobian of shape \(k, 3\)"),
        (lambda m, d: dynamics.task_space_inertia(m, d, np.ones((2, 2))), r"got shape \(2, 2\)"),
        (lambda m, d: dynamics.solve_mass(m, d, np.zeros(2)), r"rhs must have shape \(3,\) or \(k, 3\), got \(2,\)"),
        (lambda m, d: dynamics.solve_mass(m, d, np.zeros((3, 3, 3))), r"got \(3, 3, 3\)"),
        (lambda m, d: dynamics.task_space_inertia(m, d, np.eye(3), damping=-1.0), "damping must be non-negative"),
    ],
)
def test_the_helpers_name_an_array_they_cannot_fill(arm, call, message):
    """MuJoCo's own TypeErrors (a pybind11 signature dump for a wrong dtype) used to reach the caller."""
    with pytest.raises(ValueError, match=message):
        call(*arm)


@pytest.mark.parametrize(
    "call",
    [
        lambda m, d: dynamics.mass_matrix(m, d),
        lambda m, d: dynamics.mass_times(m, d, np.ones(3)),
        lambda m, d: dynamics.solve_mass(m, d, np.ones(3)),
        lambda m, d: dynamics.site_jacobian(m, d, 0),
        lambda m, d: dynamics.site_jdot_qdot(m, d, 0),
        lambda m, d: dynamics.task_space_inertia(m, d, np.eye(3)),
    ],
)
def test_the_helpers_refuse_the_data_of_another_model_and_swapped_arguments(arm, call):
    """MuJoCo 4 raises nothing for a data made for another model and reads it past its arrays
    (the 3R arm's mass matrix from the single joint's data came out as numbers); and model and
    data swapped, with a site given by id, used to end in an AttributeError. A copy of the model
    is still accepted."""
    model, data = arm
    mujoco.mj_forward(model, data)
    _, other_data = load_model("single_joint")
    with pytest.raises(ValueError, match=r"data was made for another model: its nq = 1 \(the model's 3\)"):
        call(model, other_data)
    with pytest.raises(ValueError, match="model and data are swapped"):
        call(data, model)
    np.testing.assert_array_equal(call(copy.copy(model), data), call(model, data))


def test_the_oldest_mujoco_is_the_one_pyproject_admits():
    """``pyproject.toml``'s lower bound on MuJoCo is ``dynamics.OLDEST_MUJOCO`` (the version
    `.ci/test-oldest` runs the unit tests on)."""
    text = (Path(__file__).resolve().parents[1] / "pyproject.toml").read_text(encoding="utf-8")
    bound = re.search(r'"mujoco>=([0-9.]+),<(\d+)"', text)
    assert bound, "pyproject.toml must admit MuJoCo as 'mujoco>=X.Y.Z,<N'"
    assert tuple(int(p) for p in bound.group(1).split(".")) == dynamics.OLDEST_MUJOCO
    assert dynamics._version(mujoco.__version__) >= dynamics.OLDEST_MUJOCO
    for text, parsed in (
        ("3.5.0", (3, 5, 0)),
        ("4.0.dev0", (4, 0, 0)),
        ("3.5.0rc1", (3, 5, 0)),
        ("4.1.2.3", (4, 1, 2)),
    ):
        assert dynamics._version(text) == parsed


def test_a_too_old_mujoco_is_refused_with_what_to_do():
    code = "import mujoco; mujoco.__version__ = '3.2.7'; import labsupport"
    run = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=False)
    assert run.returncode != 0
    assert "ImportError: labsupport needs MuJoCo 3.5.0 or newer" in run.stderr
    assert "pip install --upgrade 'mujoco>=3.5.0,<5'" in run.stderr and "restart" in run.stderr
    assert dynamics._version("3.10.0rc1") == (3, 10, 0) > dynamics._version("3.5.0")


def test_the_3r_arm_has_the_problems_masses_and_its_scene_adds_none():
    """At q = 0 (links 1 and 2 upright, link 3 horizontal along +x) the thin-rod model of the
    Problems gives: gravity loads joints 2 and 3 with the weight of link 3 at half its length,
    m3 g l3 / 2, and the pan's inertia is the two upright links' axial 0.001 kg·m² each plus link 3's
    m3 l3²/12 + m3 (l3/2)² = m3 l3²/3. The sky, floor, camera and mocap target of the scene add
    nothing to either."""
    from labsupport.plants import load_model

    model, data = load_model("spatial_3r")
    mujoco.mj_forward(model, data)
    m3, l3, g = 0.5, 1.0, 9.81
    assert np.allclose(data.qfrc_bias, [0.0, -m3 * g * l3 / 2, -m3 * g * l3 / 2], atol=1e-9)
    assert dynamics.mass_matrix(model, data)[0, 0] == pytest.approx(0.002 + m3 * l3**2 / 3, rel=1e-5)
    assert model.body("target").mocapid[0] == 0 and model.body_mass[model.body("target").id] == 0


def test_a_wrist_singularity_is_not_blamed_on_the_target():
    """At q5 = 0 the UR5e's wrist axes 4 and 6 line up, with the target well inside the workspace;
    the message spoke only of an arm stretched out or folded."""
    from labsupport import ur5e

    model, data = ur5e.load_ur5e()
    data.qpos[4] = 0.0
    mujoco.mj_forward(model, data)
    J = dynamics.site_jacobian(model, data, ur5e.SITE)
    assert np.linalg.matrix_rank(J) == 5  # an independent look: one direction of motion is lost
    with pytest.raises(ValueError, match="two of its joint axes line up, as a six-axis wrist's do at q5 = 0"):
        dynamics.jacobian_solve(J, np.ones(6))


def test_the_mujoco4_advice_is_given_for_the_old_mj_fullM_call_only():
    """The lab's mj_fullM(model, M, data.qM) fails on MuJoCo 4 in one of two ways, and only those
    get the advice; another MuJoCo function's wrong arguments, or a wrong shape, do not."""
    for error in (
        "'mujoco._structs.MjData' object has no attribute 'qM'",
        "mj_fullM(): incompatible function arguments. The following argument types are supported:",
    ):
        assert dynamics.full_m_advice(error).startswith(". mj_fullM changed with MuJoCo 4")
    for error in (
        "mj_jacSite(): incompatible function arguments. The following argument types are supported:",
        "mj_fullM: dst should be of shape (nv, nv)",
        "",
    ):
        assert dynamics.full_m_advice(error) == ""
