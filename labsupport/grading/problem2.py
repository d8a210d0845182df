r"""Checks of Problem 2 (tracking a 3-D circle with the 3R arm): the start on the circle,
operational-space CT, IK + joint-space CT, and the tracking itself.

The student's notebook defines

* ``q0_traj``: joint angles putting the tip on the circle's start point;
* ``ct_op_torque(model, data, x_d, xd_d, xdd_d, Kp, Kd)``:
  :math:`\tau = M J^{-1}(\ddot x_d + K_d(\dot x_d - J\dot q) + K_p(x_d - x) - \dot J\dot q) + h`;
* ``ct_ik_joint_torque(model, data, x_d, xd_d, xdd_d, Kp, Kd)``: :math:`q_d = \mathrm{IK}(x_d)`,
  :math:`\dot q_d = J(q_d)^{-1}\dot x_d`, :math:`\ddot q_d = J(q_d)^{-1}(\ddot x_d - \dot J(q_d,\dot q_d)\dot q_d)`,
  then :math:`\tau = M(\ddot q_d + K_d(\dot q_d - \dot q) + K_p(q_d - q)) + h`.
"""

from __future__ import annotations

import numpy as np

from labsupport.grading.common import arm, close, diagnose, dynamics_at, run_student
from labsupport.grading.feedback import (NotImplementedYet, Probe, Result, State, StudentError, as_vector,
                                         failed, not_implemented, passed)
from labsupport.kinematics import spatial_3r
from labsupport.metrics import rms_norm
from labsupport.trajectories import circle_3d

#: The Problem's numbers.
CENTER = np.array([1.0, 0.0, 1.5])  # circle centre [m]
RADIUS = 0.3  # [m]
NORMAL = np.array([0.0, 0.0, 1.0])
FREQUENCY = 0.2  # [Hz]
DURATION = 2 / FREQUENCY  # two turns [s]
WN, ZETA = 8.0, 1.0
KP, KD = WN**2, 2 * ZETA * WN
RMS_TOL = 1e-3  # [m]


def reference(t):
    """The circle: position, velocity, acceleration at time ``t``."""
    return circle_3d(t, CENTER, RADIUS, NORMAL, FREQUENCY)


def start_state():
    r"""Start on the circle, moving with it: :math:`q_0 = \mathrm{IK}(x_d(0))`, :math:`\dot q_0 = J(q_0)^{-1}\dot x_d(0)`."""
    ref0 = reference(0.0)
    q0 = spatial_3r.inverse_kinematics(ref0.pos, elbow_up=True)
    return q0, np.linalg.solve(spatial_3r.jacobian(q0), ref0.vel)


def ik_joint_reference(x_d, xd_d, xdd_d):
    r"""Joint reference from the Cartesian one (elbow up): :math:`q_d, \dot q_d, \ddot q_d`."""
    q_d = spatial_3r.inverse_kinematics(x_d, elbow_up=True)
    J = spatial_3r.jacobian(q_d)
    qd_d = np.linalg.solve(J, xd_d)
    qdd_d = np.linalg.solve(J, xdd_d - spatial_3r.jdot_qdot(q_d, qd_d))
    return q_d, qd_d, qdd_d


def _test_cases(seed: int, n: int = 4):
    """States near the circle (perturbed from it) with the reference at a random time."""
    rng = np.random.default_rng(seed)
    cases = []
    for _ in range(n):
        t = float(rng.uniform(0, DURATION))
        ref = reference(t)
        q_d, qd_d, _ = ik_joint_reference(ref.pos, ref.vel, ref.acc)
        state = State(q_d + rng.uniform(-0.05, 0.05, 3), qd_d + rng.uniform(-0.3, 0.3, 3), t)
        cases.append((state, ref, float(rng.uniform(30, 90)), float(rng.uniform(8, 20))))
    return cases


def check_start(probe: Probe) -> Result:
    """``q0_traj`` puts the tip on the circle's start point."""
    name = "p2_start"
    try:
        q0 = as_vector("q0_traj", probe.get("q0_traj"), 3, "value")
    except NotImplementedYet:
        return not_implemented(name, "start: not implemented yet (q0_traj is None)")
    except StudentError as err:
        return failed(name, f"start: {err}")
    x0 = reference(0.0).pos
    err = float(np.linalg.norm(spatial_3r.forward_kinematics(q0) - x0))
    if err < 1e-6:
        return passed(name, "start: q0_traj puts the end effector on the circle's start point.")
    with np.printoptions(precision=3, suppress=True):
        return failed(name, f"start: q0_traj puts the end effector {err:.3f} m from the circle's start point {x0}; "
                            "solve the IK for x_d(0).")


def _os_terms(model, state, ref, Kp, Kd):
    M, h, data = dynamics_at(model, state)
    J = spatial_3r.jacobian(state.q)
    x = spatial_3r.forward_kinematics(state.q)
    jdq = spatial_3r.jdot_qdot(state.q, state.qdot)
    fb = Kd * (ref.vel - J @ state.qdot) + Kp * (ref.pos - x)
    return M, h, J, jdq, fb


def check_os_ct(probe: Probe) -> Result:
    """``ct_op_torque`` against the operational-space computed torque at states near the circle."""
    name = "p2_osct"
    model, _ = arm()
    for state, ref, Kp, Kd in _test_cases(41):
        M, h, J, jdq, fb = _os_terms(model, state, ref, Kp, Kd)
        expected = M @ np.linalg.solve(J, ref.acc + fb - jdq) + h
        try:
            tau = as_vector("ct_op_torque", probe.call("ct_op_torque", state, ref.pos, ref.vel, ref.acc, Kp, Kd),
                            3, "torque")
        except NotImplementedYet:
            return not_implemented(name, "OS-CT: not implemented yet (ct_op_torque returned None)")
        except StudentError as err:
            return failed(name, f"OS-CT: {err}")
        if not close(tau, expected):
            mistakes = {
                "no_jdot": (M @ np.linalg.solve(J, ref.acc + fb) + h,
                            "everything is right except the −J̇q̇ term, which is missing (the lab allows dropping "
                            "it, but then the error dynamics are no longer exactly linear).", 0.5),
                "no_bias": (M @ np.linalg.solve(J, ref.acc + fb - jdq),
                            "the bias term h(q, q̇) = data.qfrc_bias is missing.", 0.25),
                "no_mass": (np.linalg.solve(J, ref.acc + fb - jdq) + h,
                            "the mass matrix is missing: τ = M(q) J⁻¹(...) + h.", 0.25),
                "transpose": (M @ (J.T @ (ref.acc + fb - jdq)) + h,
                              "use J⁻¹ (np.linalg.solve(J, v)), not Jᵀ.", 0.0),
                "no_ff": (M @ np.linalg.solve(J, fb - jdq) + h,
                          "the feed-forward acceleration ẍ_d is missing.", 0.25),
            }
            _, text, score = diagnose(tau, expected, mistakes)
            return failed(name, f"OS-CT: {text}", score)
    return passed(name, "OS-CT: ct_op_torque gives M J⁻¹(ẍ_d + Kd ė + Kp e − J̇q̇) + h at every test state.")


def check_ik_ct(probe: Probe) -> Result:
    """``ct_ik_joint_torque`` against IK + joint-space computed torque at states near the circle."""
    name = "p2_ikct"
    model, _ = arm()
    for state, ref, Kp, Kd in _test_cases(51):
        M, h, _ = dynamics_at(model, state)
        q_d, qd_d, qdd_d = ik_joint_reference(ref.pos, ref.vel, ref.acc)
        expected = M @ (qdd_d + Kd * (qd_d - state.qdot) + Kp * (q_d - state.q)) + h
        try:
            tau = as_vector("ct_ik_joint_torque",
                            probe.call("ct_ik_joint_torque", state, ref.pos, ref.vel, ref.acc, Kp, Kd), 3, "torque")
        except NotImplementedYet:
            return not_implemented(name, "IK+JS-CT: not implemented yet (ct_ik_joint_torque returned None)")
        except StudentError as err:
            return failed(name, f"IK+JS-CT: {err}")
        if not close(tau, expected):
            J_d = spatial_3r.jacobian(q_d)
            no_jdot = np.linalg.solve(J_d, ref.acc)
            q_down = spatial_3r.inverse_kinematics(ref.pos, elbow_up=False)
            mistakes = {
                "no_jdot": (M @ (no_jdot + Kd * (qd_d - state.qdot) + Kp * (q_d - state.q)) + h,
                            "everything is right except the J̇(q_d, q̇_d) q̇_d term in q̈_d, which is missing.", 0.5),
                "no_bias": (expected - h, "the bias term h(q, q̇) = data.qfrc_bias is missing.", 0.25),
                "no_mass": (qdd_d + Kd * (qd_d - state.qdot) + Kp * (q_d - state.q) + h,
                            "the mass matrix is missing: τ = M(q)(...) + h.", 0.25),
                "no_ff": (M @ (Kd * (qd_d - state.qdot) + Kp * (q_d - state.q)) + h,
                          "the feed-forward acceleration q̈_d is missing.", 0.25),
                "elbow_down": (M @ (Kp * (q_down - state.q)) + h,
                               "the IK uses the elbow-down branch, but the arm runs elbow-up.", 0.0),
            }
            key, text, score = diagnose(tau, expected, mistakes)
            if key is None:
                # the elbow-down branch changes every term; recognise it by the position error alone
                text = ("the torque differs from IK + joint CT: check q_d = IK(x_d) (elbow up), "
                        "q̇_d = J(q_d)⁻¹ ẋ_d and q̈_d = J(q_d)⁻¹(ẍ_d − J̇ q̇_d); " + text)
            return failed(name, f"IK+JS-CT: {text}", score)
    return passed(name, "IK+JS-CT: ct_ik_joint_torque matches IK + joint-space computed torque at every test state.")


def check_tracking(probe: Probe) -> Result:
    """Both of the student's controllers track two turns of the circle with RMS error below 1 mm."""
    name = "p2_track"
    q0, qdot0 = start_state()
    score, notes = 0.0, []
    for fname, label in (("ct_op_torque", "OS-CT"), ("ct_ik_joint_torque", "IK+JS-CT")):
        try:
            log = run_student(probe, fname, _controller_args, DURATION, q0, qdot0, reference=reference)
        except NotImplementedYet:
            notes.append(f"{label}: not implemented yet ({fname} returned None)")
            continue
        except StudentError as err:
            notes.append(f"{label}: {err}")
            continue
        err = rms_norm(log.err)
        if err < RMS_TOL:
            score += 0.5
            notes.append(f"{label}: RMS error {err * 1e3:.3g} mm (needs < 1 mm)")
        else:
            notes.append(f"{label}: RMS error {err * 1e3:.2f} mm, should be below 1 mm")
    text = "tracking: " + "; ".join(notes) + "."
    if score == 1.0:
        return passed(name, text)
    if score == 0 and all("not implemented yet" in n for n in notes):
        return not_implemented(name, text)
    return failed(name, text, score)


def _controller_args(t):
    """The controllers' arguments after ``(model, data)`` at time ``t``: the reference and the gains."""
    ref = reference(t)
    return ref.pos, ref.vel, ref.acc, KP, KD

CHECKS = {"p2_start": check_start, "p2_osct": check_os_ct, "p2_ikct": check_ik_ct, "p2_track": check_tracking}
