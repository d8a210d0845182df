r"""Pieces the Problems' checks share: test states, the arm's reference dynamics, diagnosis of a
wrong torque by comparison with typical mistakes, and a simulation driven by a student's controller.
"""

from __future__ import annotations

from typing import Callable

import mujoco
import numpy as np

from labsupport.dynamics import bias_forces, mass_matrix
from labsupport.grading.feedback import Probe, State, StudentError, as_vector
from labsupport.kinematics import spatial_3r
from labsupport.plants import load_model
from labsupport.sim import Log, SimulationDiverged, simulate

#: Absolute and relative tolerance on a torque that should equal the reference [N·m].
TORQUE_ATOL, TORQUE_RTOL = 1e-6, 1e-6


def arm():
    """A fresh ``(model, data)`` of the 3R arm."""
    return load_model("spatial_3r")


def dynamics_at(model, state: State):
    r""":math:`M(q)` and :math:`h(q, \dot q)` at a state, from a scratch ``MjData``."""
    data = mujoco.MjData(model)
    data.qpos[:] = state.q
    data.qvel[:] = state.qdot
    data.time = state.t
    mujoco.mj_forward(model, data)
    return mass_matrix(model, data), bias_forces(data), data


def random_states(seed: int, n: int, speed: float = 1.5) -> list[State]:
    """``n`` seeded states: configurations reaching random targets (either elbow), random velocities."""
    rng = np.random.default_rng(seed)
    targets = spatial_3r.sample_targets(rng, n)
    states = []
    for k, x in enumerate(targets):
        q = spatial_3r.inverse_kinematics(x, elbow_up=bool(k % 2 == 0))
        states.append(State(q, rng.uniform(-speed, speed, 3), 0.0))
    return states


def close(a, b) -> bool:
    return bool(np.allclose(a, b, atol=TORQUE_ATOL, rtol=TORQUE_RTOL))


def diagnose(got: np.ndarray, expected: np.ndarray, mistakes: dict[str, tuple[np.ndarray, str, float]]):
    """Match a wrong value against typical mistakes.

    Args:
        got, expected: the student's value and the right one.
        mistakes: ``{key: (value_that_mistake_gives, explanation, partial_score)}``.

    Returns:
        ``(key, explanation, score)`` of the first mistake that reproduces ``got``, or
        ``(None, generic explanation, 0)``.
    """
    for key, (value, text, score) in mistakes.items():
        if close(got, value) and not close(value, expected):
            return key, text, score
    diff = float(np.max(np.abs(got - expected)))
    with np.printoptions(precision=4, suppress=True):
        return None, f"got {got}, expected {expected} (largest difference {diff:.3g})", 0.0


def student_controller(probe: Probe, fname: str, args) -> Callable:
    """A controller ``(model, data) -> tau`` that asks the probe for the student's torque each step.

    ``args`` are the function's arguments after ``(model, data)``: a tuple, or a function of
    the time returning the tuple (for a moving reference).
    """

    def controller(model, data):
        extra = args(float(data.time)) if callable(args) else args
        value = probe.call(fname, State(data.qpos.copy(), data.qvel.copy(), float(data.time)), *extra)
        return as_vector(fname, value, model.nu, "torque")

    return controller


def run_student(probe: Probe, fname: str, args, duration: float, q0, qdot0=None,
                reference=None) -> Log:
    """Simulate the 3R arm (the grader's own model and loop) under the student's controller.

    Raises:
        StudentError: if the controller fails or the simulation diverges (message in plain words).
    """
    model, data = arm()
    try:
        return simulate(model, data, student_controller(probe, fname, args), duration, q0=q0,
                        qdot0=qdot0, site="end_effector", reference=reference)
    except SimulationDiverged as err:
        raise StudentError(f"with {fname}, the simulation diverged at t = {err.t:.3f} s "
                           "(the arm ran away): check signs and the mass matrix") from None
    except ValueError as err:
        raise StudentError(f"{fname}: {err}") from None
