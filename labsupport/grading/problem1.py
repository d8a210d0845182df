r"""Checks of Problem 1 (reaching with the 3R arm): IK, joint PD, joint computed torque, and
the computed-torque reach itself.

The student's notebook defines

* ``ik_3r(x, elbow_up=True) -> q``: joint angles putting the tip at ``x``;
* ``pd_torque(model, data, q_d, Kp, Kd)``: :math:`\tau = K_p(q_d - q) - K_d\dot q`;
* ``ct_joint_torque(model, data, q_d, Kp, Kd)``:
  :math:`\tau = M(q)\big(K_p(q_d - q) - K_d\dot q\big) + h(q, \dot q)`.
"""

from __future__ import annotations

import numpy as np

from labsupport.grading.common import arm, close, diagnose, dynamics_at, random_states, run_student
from labsupport.grading.feedback import (NotImplementedYet, Probe, Result, StudentError, as_vector,
                                         failed, not_implemented, passed)
from labsupport.kinematics import spatial_3r

#: The Problem's numbers.
Q0 = np.array([0.0, np.pi / 6, -np.pi / 4])  # initial configuration [rad]
DURATION = 5.0  # [s]
WN_CT, ZETA_CT = 10.0, 0.9  # computed-torque design
KP_CT, KD_CT = WN_CT**2, 2 * ZETA_CT * WN_CT
REACH_TOL = 1e-3  # final end-effector error the computed torque must reach [m]
IK_TOL = 1e-6  # [m]


def _elbow_height(q) -> float:
    """Height of the elbow (joint 3) above the shoulder: :math:`l_2\\cos q_2`."""
    return float(np.cos(q[1]))


def _same_angles(a, b) -> bool:
    return bool(np.all(np.abs((np.asarray(a) - np.asarray(b) + np.pi) % (2 * np.pi) - np.pi) < 1e-6))


def check_ik(probe: Probe) -> Result:
    """``ik_3r`` on the lab's target and four sampled targets, both elbow branches."""
    name = "p1_ik"
    targets = np.vstack([spatial_3r.lab_target(0), spatial_3r.sample_targets(np.random.default_rng(11), 4)])
    good, total, problems = 0, 0, []
    worst = 0.0
    for x in targets:
        sols = {}
        for up in (True, False):
            total += 1
            branch = "elbow-up" if up else "elbow-down"
            try:
                q = as_vector("ik_3r", probe.call("ik_3r", x, elbow_up=up), 3, "joint vector")
            except NotImplementedYet:
                return not_implemented(name, "IK: not implemented yet (ik_3r returned None)")
            except StudentError as err:
                problems.append(f"IK: {err}")
                continue
            err = float(np.linalg.norm(spatial_3r.forward_kinematics(q) - x))
            if err <= IK_TOL:
                good += 1
                worst = max(worst, err)
                sols[up] = q
                continue
            azimuth = np.arctan2(x[1], x[0])
            pan_error = abs((q[0] - azimuth + np.pi) % (2 * np.pi) - np.pi)
            with np.printoptions(precision=3, suppress=True):
                if pan_error < 1e-3:
                    problems.append(f"IK: the pan angle is right, but the {branch} solution puts the end "
                                    f"effector {err:.2f} m from the target {x}")
                else:
                    problems.append(f"IK: the pan angle q1 = {q[0]:.3f} rad, but the target {x} has azimuth "
                                    f"atan2(y, x) = {azimuth:.3f} rad; the end effector lands {err:.2f} m away")
        if len(sols) == 2:
            if _same_angles(sols[True], sols[False]):
                good -= 1
                problems.append("IK: elbow_up=True and elbow_up=False give the same solution; "
                                "elbow_up=False should return the other (mirror) elbow branch")
            elif _elbow_height(sols[True]) < _elbow_height(sols[False]) - 1e-9:
                good -= 1
                problems.append("IK: both branches reach the target, but they are swapped: elbow_up=True "
                                "should put the elbow above the shoulder-to-target line")
    if good == total:
        return passed(name, f"IK: all {total} solutions ({len(targets)} targets × 2 elbow branches) put the "
                            f"end effector on the target (worst error {worst:.1e} m).")
    return failed(name, f"IK: {good} of {total} solutions are right. " + problems[0], good / total)


def _pd_mistakes(state, q_d, Kp, Kd, h):
    e = q_d - state.q
    return {
        "sign": (-(Kp * e - Kd * state.qdot), "the torque has the wrong sign: it pushes away from q_d. "
                 "Use Kp (q_d − q), not Kp (q − q_d).", 0.0),
        "no_damping": (Kp * e, "the spring term Kp (q_d − q) is right, but the damping term −Kd q̇ is missing.", 0.5),
        "damping_sign": (Kp * e + Kd * state.qdot, "the spring term is right, but the damping has the wrong sign: "
                         "it must oppose the motion, −Kd q̇.", 0.5),
        "with_bias": (Kp * e - Kd * state.qdot + h, "you added h(q, q̇): that is computed torque's model term; "
                      "the plain PD uses no model.", 0.5),
    }


def _check_joint_law(probe: Probe, name: str, label: str, function: str, seed: int, gains, law,
                     mistakes, summary: str) -> Result:
    """Compare the student's ``function(data, q_d, Kp, Kd)`` with ``law(M, h, state, q_d, Kp, Kd)``
    at seeded states; on a mismatch, name the mistake ``mistakes(M, h, state, q_d, Kp, Kd)`` explains."""
    model, _ = arm()
    rng = np.random.default_rng(seed)
    for state in random_states(seed, 4):
        q_d = state.q + rng.uniform(-0.5, 0.5, 3)
        Kp, Kd = float(rng.uniform(*gains[0])), float(rng.uniform(*gains[1]))
        M, h, _ = dynamics_at(model, state)
        expected = law(M, h, state, q_d, Kp, Kd)
        try:
            tau = as_vector(function, probe.call(function, state, q_d, Kp, Kd), 3, "torque")
        except NotImplementedYet:
            return not_implemented(name, f"{label}: not implemented yet ({function} returned None)")
        except StudentError as err:
            return failed(name, f"{label}: {err}")
        if not close(tau, expected):
            _, text, score = diagnose(tau, expected, mistakes(M, h, state, q_d, Kp, Kd))
            return failed(name, f"{label}: {text}", score)
    return passed(name, f"{label}: {function} gives {summary} at every test state.")


def check_pd(probe: Probe) -> Result:
    """``pd_torque`` against :math:`K_p(q_d-q) - K_d\\dot q` at seeded states."""
    return _check_joint_law(
        probe, "p1_pd", "PD", "pd_torque", 21, ((100, 500), (10, 60)),
        lambda M, h, state, q_d, Kp, Kd: Kp * (q_d - state.q) - Kd * state.qdot,
        lambda M, h, state, q_d, Kp, Kd: _pd_mistakes(state, q_d, Kp, Kd, h),
        "Kp (q_d − q) − Kd q̇")


def _ct_mistakes(M, h, state, q_d, Kp, Kd):
    e = q_d - state.q
    v = Kp * e - Kd * state.qdot
    return {
        "no_bias": (M @ v, "M(q)(Kp e − Kd q̇) is right, but the bias term h(q, q̇) (data.qfrc_bias: gravity and "
                    "Coriolis) is missing.", 0.25),
        "no_mass": (v + h, "h(q, q̇) is there, but the mass matrix is missing: multiply the PD term by M(q).", 0.25),
        "sign": (M @ (-v) + h, "the feedback has the wrong sign: use e = q_d − q.", 0.0),
        "no_damping": (M @ (Kp * e) + h, "the damping term −Kd q̇ inside M(q)(...) is missing.", 0.5),
        "damping_sign": (M @ (Kp * e + Kd * state.qdot) + h, "the damping has the wrong sign: it must be −Kd q̇.", 0.5),
        "bias_sign": (M @ v - h, "h(q, q̇) must be added, not subtracted.", 0.25),
    }


def check_ct(probe: Probe) -> Result:
    """``ct_joint_torque`` against :math:`M(q)(K_p e - K_d\\dot q) + h` at seeded states."""
    return _check_joint_law(
        probe, "p1_ct", "CT", "ct_joint_torque", 31, ((50, 150), (5, 25)),
        lambda M, h, state, q_d, Kp, Kd: M @ (Kp * (q_d - state.q) - Kd * state.qdot) + h,
        _ct_mistakes, "M(q)(Kp e − Kd q̇) + h(q, q̇)")


def check_reach(probe: Probe) -> Result:
    """The student's computed torque drives the tip to the lab's target within 1 mm in 5 s."""
    name = "p1_reach"
    target = spatial_3r.lab_target(0)
    q_d = spatial_3r.inverse_kinematics(target, elbow_up=True)
    try:
        log = run_student(probe, "ct_joint_torque", (q_d, KP_CT, KD_CT), DURATION, Q0)
    except NotImplementedYet:
        return not_implemented(name, "reach: not implemented yet (ct_joint_torque returned None)")
    except StudentError as err:
        return failed(name, f"reach: {err}")
    final = float(np.linalg.norm(log.ee[-1] - target))
    if final < REACH_TOL:
        return passed(name, f"reach: with your computed torque the end effector ends {final * 1e3:.3g} mm from "
                            f"the target after {DURATION:g} s (needs < 1 mm).")
    return failed(name, f"reach: with your computed torque the end effector ends {final * 1e3:.1f} mm from the "
                        f"target after {DURATION:g} s; it should be below 1 mm.")


CHECKS = {"p1_ik": check_ik, "p1_pd": check_pd, "p1_ct": check_ct, "p1_reach": check_reach}
