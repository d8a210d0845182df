r"""Checks of Problem 2 (tracking a 3-D circle with the 3R arm): the start on the circle,
operational-space CT, IK + joint-space CT, and the tracking itself. None needs a reference
solution, nor an inverse kinematics.

The student's notebook defines

* ``q0_traj``: joint angles putting the tip on the notebook circle's start point (elbow up);
  checked through MuJoCo's forward kinematics;
* ``ct_op_torque(model, data, x_d, xd_d, xdd_d, Kp, Kd)``:
  :math:`\tau = M J^{-1}(\ddot x_d + K_d(\dot x_d - J\dot q) + K_p(x_d - x) - \dot J\dot q) + h`;
* ``ct_ik_joint_torque(model, data, x_d, xd_d, xdd_d, Kp, Kd)``: :math:`q_d = \mathrm{IK}(x_d)`,
  :math:`\dot q_d = J(q_d)^{-1}\dot x_d`, :math:`\ddot q_d = J(q_d)^{-1}(\ddot x_d - \dot J(q_d,\dot q_d)\dot q_d)`,
  then :math:`\tau = M(\ddot q_d + K_d(\dot q_d - \dot q) + K_p(q_d - q)) + h`.

The laws are tested with a Cartesian reference made from a chosen joint reference
(:func:`~labsupport.grading.common.tracking_cases`), so the expected IK + joint-CT torque is
known without IK. The tracking run follows a seeded circle that starts at the tip of a drawn
configuration, so it starts on the circle with no IK either.
"""

from __future__ import annotations

import itertools

import numpy as np

from labsupport.grading.common import (
    GRAVITY_ONLY,
    INVERSE_MASS,
    MARGINS,
    RAN_AWAY,
    STILL_RTOL,
    ZERO_BIAS_NOTE,
    Case,
    Mistake,
    Verdict,
    argument_order_mistakes,
    arm_model,
    call_along,
    data_at,
    draw_configuration,
    elbow_height,
    formula_scoring,
    gravity,
    has_unwrapped_angle,
    judge_torque,
    mirror_elbow,
    none_here_only,
    over_the_top,
    own_gains_mistake,
    own_reference_mistake,
    pan_turned_round,
    rng_for,
    run_student,
    safe_point,
    swapped_gains_mistake,
    terms,
    tip,
    tracking_cases,
)
from labsupport.grading.feedback import (
    NotImplementedYet,
    Probe,
    Result,
    StudentError,
    as_vector,
    degrees_question,
    failed,
    forbidden_reason,
    not_implemented,
    passed,
    refused,
    show_beside,
)
from labsupport.metrics import rms_norm
from labsupport.trajectories import circle_3d, circle_basis

#: The notebook's circle (the one ``q0_traj`` starts on).
CENTER = np.array([1.0, 0.0, 1.5])  # circle centre [m]
RADIUS = 0.3  # [m]
NORMAL = np.array([0.0, 0.0, 1.0])
FREQUENCY = 0.2  # [Hz]
WN, ZETA = 8.0, 1.0
KP, KD = WN**2, 2 * ZETA * WN
#: The notebook's settings that the checks copy, as :data:`problem1.NOTEBOOK_SETTINGS` (the arm's
#: shoulder is :data:`common.SHOULDER`).
NOTEBOOK_SETTINGS = {
    "center, radius": {
        "center": "CENTER",
        "normal": "NORMAL",
        "radius": "RADIUS",
        "freq": "FREQUENCY",
        "SHOULDER": "common.SHOULDER",
    },
    "wn_t, zeta_t": {"Kp_t": "KP", "Kd_t": "KD"},
}
#: RMS error over one turn that both controllers must stay below [m]. Right laws track the drawn
#: circles to 0.075 mm at most (over 101 seeds, the public one the worst), and with a J̇q̇ 5 % off
#: (graded as right) to 0.16 mm; every known
#: mistake leaves 0.4 mm or more (no J̇q̇: 0.42-2.8 mm; gravity alone as h: 0.46-2.4 mm). A limit
#: between the two keeps each law's score the same whatever circle the batch's seed draws.
RMS_TOL = 0.25e-3
START_TOL = 1e-4  # [m]
#: A numerical IK accurate to this distance [m] is graded as right in IK + joint CT (Problem 1's
#: IK check takes one that stops at 1e-5 m). Where the reference is at rest, an IK off by δq
#: changes the torque by M Kp δq (and q̈_d = J(q_d)⁻¹ẍ_d by a few percent of that): the check
#: reads the offset back from the torque (:func:`_ik_case`) and allows twice this.
IK_APPROX = 1e-5
#: The tracking check follows one turn of a seeded circle.
TRACK_DURATION = 1 / FREQUENCY

#: What to do about an IK + joint CT run whose IK left the branch the arm starts on.
BRANCH_ADVICE = " Take q1 = atan2(y, x) and the elbow-up branch at every point"
#: Where to look when a value computed from the student's IK is None.
IK_NOT_PASTED = "check TODO 1 first: ik_3r returns None until your ik_3r from Problem 1 is pasted there"
#: A law without its bias term (both laws).
NO_BIAS = "the bias term h(q, q̇) = data.qfrc_bias is missing." + ZERO_BIAS_NOTE

OVER_THE_TOP = (
    "the over-the-top solution: it reaches x_d with the pan angle half a turn from atan2(y, x) and the "
    "arm leaning back over its shoulder"
)
#: What a tracking run that lags by centimetres says in place of :data:`TRACKING_HINT`: a wrong
#: J̇q̇ or h leaves millimetres, a damping without the reference velocity about 90 mm on the
#: notebook's circle.
LAG_HINT = (
    " (a lag of centimetres most often comes from a damping without the reference velocity, which brakes "
    "the arm toward standing still: Kd (ẋ_d − J q̇) needs ẋ_d, Kd (q̇_d − q̇) needs q̇_d = J(q_d)⁻¹ ẋ_d; the "
    "formula checks above say which term is wrong)"
)
#: Above it [m], a run's RMS error gets :data:`LAG_HINT` rather than :data:`TRACKING_HINT`.
LAG_RMS = 0.02
#: What a tracking error above :data:`RMS_TOL` from a law that runs usually means.
TRACKING_HINT = (
    " (a right law stays below 0.075 mm on every circle this check draws; 0.4 mm or more is what a missing "
    "or wrong term leaves: J̇q̇, the Coriolis part of h, or M, and the formula checks above say which. Where "
    "they pass and the run still misses, look for state your law keeps between calls, such as the last J of "
    "a J̇ by time differences: each run starts at t = 0, after the checks' calls, so start afresh when "
    "data.time goes back)"
)
JDOT_HINT = (
    'MuJoCo gives it: site_jdot_qdot(model, data, "end_effector")[:3]; a finite-difference '
    "approximation within 5 % gets full marks"
)


def reference(t):
    """The notebook's circle: position, velocity, acceleration at time ``t``."""
    return circle_3d(t, CENTER, RADIUS, NORMAL, FREQUENCY)


#: Why a law that tracks in the notebook misses the circle a check hands it.
NOTEBOOK_CIRCLE = (
    "the arm followed the notebook's circle, reference(t), not the one handed to the law: use the law's "
    "arguments x_d, ẋ_d and ẍ_d, not the notebook's reference; the checks and the grader hand it other circles"
)


def _followed_the_notebooks_circle(log, within: float = 1e-3) -> bool:
    """Whether a run's end effector stayed within ``within`` [m] (RMS) of the notebook's circle
    over the run's second half, after the transient from the circle it was started on."""
    late = log.t >= log.t[-1] / 2
    return rms_norm(log.ee[late] - np.array([reference(t).pos for t in log.t[late]])) < within


def check_start(probe: Probe, seed: int) -> Result:
    """``q0_traj`` puts the tip on the notebook circle's start point, elbow up (the seed plays no
    part: ``q0_traj`` is a value computed for the notebook's own circle)."""
    name, label = "p2_start", "start"
    model = arm_model()
    try:
        q0 = as_vector("q0_traj", probe.get("q0_traj"), 3, "value")
    except NotImplementedYet as err:  # set from ik_3r, it is None until Problem 1's IK is pasted in
        return refused(name, label, NotImplementedYet(f"{err}; if it is set as ik_3r(x0), {IK_NOT_PASTED}"))
    except StudentError as err:  # q0_traj's cell failed: where ik_3r is off limits, that is why
        ik = _own_ik_answer(probe, reference(0.0).pos)
        return refused(name, label, ik if isinstance(ik, StudentError) and forbidden_reason(ik) else err)
    x0 = reference(0.0).pos
    err = float(np.linalg.norm(tip(model, q0) - x0))
    with np.printoptions(precision=4, suppress=True):
        if err <= START_TOL:
            if pan_turned_round(q0, x0):
                return failed(
                    name,
                    "start: q0_traj puts the end effector on the start point, but with the pan half a turn from "
                    "its azimuth (the over-the-top pose, the arm leaning back over its shoulder); the Problem "
                    "starts facing the target, q1 = atan2(y, x).",
                    0.5,
                )
            if elbow_height(model, q0) <= 0:
                return failed(
                    name,
                    "start: q0_traj puts the end effector on the start point, but elbow down; "
                    "the Problem starts elbow up (elbow_up=True).",
                    0.5,
                )
            not_own = _not_from_own_ik(probe, model, x0)
            if not_own:
                return failed(
                    name,
                    f"start: q0_traj puts the end effector on the start point, elbow up, but {not_own}; the start "
                    "counts when your own IK computes it: q0_traj = ik_3r(x0), with your ik_3r of TODO 1.",
                )
            return passed(name, "start: q0_traj puts the end effector on the circle's start point, elbow up.")
        if float(np.linalg.norm(tip(model, np.radians(q0)) - x0)) <= START_TOL:
            return failed(name, f"start: q0_traj = {q0} is in degrees; MuJoCo works in radians.")
        return failed(
            name,
            f"start: q0_traj puts the end effector {err:.4g} m from the circle's start point {x0}; "
            "solve the IK for x_d(0).",
        )


def _own_ik_answer(probe: Probe, x0) -> StudentError | np.ndarray:
    """The student's ``ik_3r(x0, elbow_up=True)`` as 3 angles, or the error that says why it gave none."""
    try:
        return as_vector("ik_3r", probe.call("ik_3r", x0, elbow_up=True), 3, "joint vector")
    except StudentError as err:
        return err


def _not_from_own_ik(probe: Probe, model, x0) -> str | None:
    """Why the student's own ``ik_3r`` does not reach the start point ``x0``, or None where it does.

    ``q0_traj`` is TODO 2's answer, the IK of ``x0``; its value alone cannot tell an IK from angles
    typed in (copied from elsewhere, or printed by an IK the Problem does not allow), so the start
    counts only where the student's ``ik_3r`` of TODO 1 also puts the tip on ``x0``."""
    q = _own_ik_answer(probe, x0)
    if isinstance(q, NotImplementedYet):
        return "ik_3r is not implemented yet"
    if isinstance(q, StudentError):
        return forbidden_reason(q) or str(q)
    miss = float(np.linalg.norm(tip(model, q) - x0))
    return None if miss <= START_TOL else f"your ik_3r(x0) puts it {miss:.4g} m from x0"


def _os_expected(T, state, x_d, xd_d, xdd_d, Kp, Kd):
    """OS-CT's formula with MuJoCo's terms, and the J̇q̇ a torque implies (everything else exact)."""
    fb = Kd * (xd_d - T.J @ state.qdot) + Kp * (x_d - T.x)
    expected = T.M @ np.linalg.solve(T.J, xdd_d + fb - T.jdq) + T.h

    def implied_jdq(tau):
        return xdd_d + fb - T.J @ np.linalg.solve(T.M, tau - T.h)

    return expected, implied_jdq, fb


def _os_mistakes(model, T, state, x_d, xd_d, xdd_d, Kp, Kd, fb):
    M, h, J, jdq = T.M, T.h, T.J, T.jdq
    g = gravity(model, state.q)
    e, edot = x_d - T.x, xd_d - J @ state.qdot
    jdq_reference = terms(model, state.q, np.linalg.solve(J, xd_d)).jdq  # J̇q̇ at the velocity J⁻¹ẋ_d
    at_rest = not state.qdot.any()  # there −Kd J q̇ is zero: a damping without ẋ_d is no damping

    def law(a):
        return M @ np.linalg.solve(J, a) + h

    def formula(x_d, xd_d, xdd_d, Kp, Kd):  # the whole law, as a function of its arguments
        return law(xdd_d + Kd * (xd_d - J @ state.qdot) + Kp * (x_d - T.x) - jdq)

    at_notebook = reference(state.t)
    return {
        "own_reference": own_reference_mistake(
            formula(at_notebook.pos, at_notebook.vel, at_notebook.acc, Kp, Kd), "x_d, ẋ_d and ẍ_d"
        ),
        "no_jdot": Mistake(
            law(xdd_d + fb),
            "everything is right except the −J̇q̇ term, which is missing. The lab's hint "
            "allows dropping it as a simplification, but the formula of this Problem has it: without "
            f"it the Cartesian error is no longer exactly linear. {JDOT_HINT}.",
            0.5,
        ),
        "jdot_sign": Mistake(law(xdd_d + fb + jdq), "J̇q̇ must be subtracted: ẍ = J q̈ + J̇q̇, so J q̈ = ẍ − J̇q̇.", 0.25),
        "jdot_at_reference": Mistake(
            law(xdd_d + fb - jdq_reference),
            "J̇q̇ is taken at the reference's velocity J⁻¹ẋ_d; the law needs it at the arm's own, J̇(q, q̇) q̇ "
            "from the data the controller is given. The two agree once the arm is on the reference, so it "
            "still tracks.",
            0.75,
        ),
        "no_bias": Mistake(law(xdd_d + fb - jdq) - h, NO_BIAS, 0.25),
        "bias_sign": Mistake(law(xdd_d + fb - jdq) - 2 * h, "h(q, q̇) must be added, not subtracted.", 0.25),
        "gravity_only": Mistake(law(xdd_d + fb - jdq) - h + g, GRAVITY_ONLY, 0.5),
        "no_mass": Mistake(
            np.linalg.solve(J, xdd_d + fb - jdq) + h, "the mass matrix is missing: τ = M(q) J⁻¹(...) + h.", 0.25
        ),
        "inverse_mass": Mistake(np.linalg.solve(M, np.linalg.solve(J, xdd_d + fb - jdq)) + h, INVERSE_MASS, 0.25),
        "transpose": Mistake(M @ (J.T @ (xdd_d + fb - jdq)) + h, "use J⁻¹ (np.linalg.solve(J, v)), not Jᵀ.", 0.0),
        "no_ff": Mistake(law(fb - jdq), "the feed-forward acceleration ẍ_d is missing.", 0.25),
        "sign": Mistake(
            law(xdd_d - fb - jdq), "the feedback terms (Kp, Kd) have the wrong sign: e = x_d − x, ė = ẋ_d − J q̇.", 0.0
        ),
        "spring_sign": Mistake(
            law(xdd_d + Kd * edot - Kp * e - jdq),
            "the spring term has the wrong sign: Kp (x_d − x), not Kp (x − x_d); the damping term is right.",
            0.0,
        ),
        "damping_sign": Mistake(
            law(xdd_d - Kd * edot + Kp * e - jdq), "the damping has the wrong sign: it must be +Kd (ẋ_d − J q̇).", 0.5
        ),
        "no_damping": Mistake(
            law(xdd_d + Kp * e - jdq),
            "the damping term Kd (ẋ_d − J q̇) is missing"
            + (", or the ẋ_d in it (the arm is at rest here, where the two look alike)." if at_rest else "."),
            0.5,
        ),
        "no_tip_velocity": Mistake(
            law(xdd_d + Kd * xd_d + Kp * e - jdq),
            "the damping is Kd ẋ_d, with the tip's own velocity J q̇ missing: it must be Kd (ẋ_d − J q̇).",
            0.5,
        ),
        "no_reference_velocity": Mistake(
            law(xdd_d - Kd * (J @ state.qdot) + Kp * e - jdq),
            "the damping is −Kd J q̇, with ẋ_d missing: it must be Kd (ẋ_d − J q̇). Without ẋ_d the damping "
            "brakes the tip toward standing still, so on the moving circle it lags behind its reference.",
            0.5,
        ),
        "joint_velocity": Mistake(
            law(xdd_d + Kd * (xd_d - state.qdot) + Kp * e - jdq),
            "the damping compares ẋ_d with q̇, the joints' velocity: the end effector's is ẋ = J q̇, so ė = ẋ_d − J q̇.",
            0.25,
        ),
        "solve_transpose": Mistake(
            M @ np.linalg.solve(J.T, xdd_d + fb - jdq) + h, "solve with J, not Jᵀ: q̈ = J⁻¹(...).", 0.0
        ),
        "transposed_tip_velocity": Mistake(
            law(xdd_d + Kd * (xd_d - J.T @ state.qdot) + Kp * e - jdq),
            "the damping takes the tip's velocity as Jᵀ q̇; it is ẋ = J q̇, so ė = ẋ_d − J q̇.",
            0.25,
        ),
        "jdot_in_joint_space": Mistake(
            M @ (np.linalg.solve(J, xdd_d + fb) - jdq) + h,
            "J̇q̇ is subtracted after J⁻¹, from the joints' acceleration, but it is an acceleration of the tip: "
            "q̈ = J⁻¹(ẍ_d + Kd ė + Kp e − J̇q̇).",
            0.25,
        ),
        "own_gains": own_gains_mistake(law(xdd_d + KD * edot + KP * e - jdq), KP, KD),
        "swapped_gains": swapped_gains_mistake(law(xdd_d + Kp * edot + Kd * e - jdq), "x_d − x", "ẋ_d − J q̇"),
        **_wrong_point_mistakes(model, state, law, x_d, xdd_d, Kp, Kd, edot, jdq),
        **argument_order_mistakes(formula, (x_d, xd_d, xdd_d, Kp, Kd), ("x_d", "xd_d", "xdd_d", "Kp", "Kd")),
    }


def _wrong_point_mistakes(model, state, law, x_d, xdd_d, Kp, Kd, edot, jdq) -> dict[str, Mistake]:
    """The law right but for its x: the origin of one of the arm's bodies (the elbow's, say, read
    from ``data.xpos`` or ``data.body(...)``) where the end effector's site belongs."""
    data = data_at(model, state.q)
    found = {}
    for b in range(1, model.nbody):
        if model.body_mocapid[b] >= 0:  # the target's marker, not a point of the arm
            continue
        name = model.body(b).name or f"body {b}"
        found[f"point_{name}"] = Mistake(
            law(xdd_d + Kd * edot + Kp * (x_d - data.xpos[b]) - jdq),
            f"x is not the end effector's position: the law uses the origin of the body {name!r} "
            f"(data.xpos[{b}]), which is not the tip. Take x = data.site('end_effector').xpos, the point the "
            "Jacobian and the circle are about.",
            0.25,
        )
    return found


def _os_case(model, case: Case):
    """At the case's tested state: OS-CT's torque, the J̇q̇ a torque implies, MuJoCo's J̇q̇ and the
    named mistakes."""
    state = case.states[-1]
    T = terms(model, state.q, state.qdot, state.t)
    ref = (case.x_d[-1], case.xd_d[-1], case.xdd_d[-1], case.Kp, case.Kd)
    expected, implied, fb = _os_expected(T, state, *ref)
    return expected, implied, T.jdq, _os_mistakes(model, T, state, *ref, fb)


def check_os_ct(probe: Probe, seed: int) -> Result:
    """``ct_op_torque`` against the operational-space computed torque at seeded states."""
    name, label, fname = "p2_osct", "OS-CT", "ct_op_torque"
    model = arm_model()
    worst = 0.0
    cases = tracking_cases(seed, name, still="arm")
    for case in cases:
        try:
            tau = call_along(probe, fname, case, lambda k, c=case: (c.x_d[k], c.xd_d[k], c.xdd_d[k], c.Kp, c.Kd))
        except StudentError as err:
            return refused(name, label, none_here_only(probe, fname, err, _elsewhere(cases, case)))
        expected, implied, jdq, mistakes = _os_case(model, case)
        if case.still:
            verdict = judge_torque(tau, expected, mistakes, rtol=STILL_RTOL)
        else:
            verdict = judge_torque(tau, expected, mistakes, implied, jdq)
        if verdict.score < 1:
            return failed(name, f"{label}: {_where(case, 'the arm', verdict.text)}", verdict.score)
        worst = max(worst, verdict.jdot_error or 0.0)
    note = f" Your J̇q̇ is an approximation (within {100 * worst:.2g} % of MuJoCo's): accepted." if worst > 1e-6 else ""
    return passed(name, "OS-CT: ct_op_torque gives M J⁻¹(ẍ_d + Kd ė + Kp e − J̇q̇) + h at every test state." + note)


def _where(case: Case, still: str, text: str) -> str:
    """``text``; a bare difference (no named mistake) found at a state where the law's J̇q̇ term is
    zero says so, so that the student looks elsewhere than J̇q̇ (``still`` names what is at rest)."""
    if not case.still or "expected [" not in text:  # a named mistake says what it is
        return text
    term = "J̇(q, q̇) q̇" if still == "the arm" else "J̇(q_d, q̇_d) q̇_d"
    velocity = "q̇" if still == "the arm" else "q̇_d"
    found = (
        f"at this test state {still} is momentarily at rest, so {term} is zero: if your J̇q̇ term is not zero "
        f"here, it is taken at another velocity than {velocity}; if it is, the difference lies in another term"
    )
    return f"{text.rstrip('.')} ({found})."


def _joint_reference_terms(model, q_d, xd_d, xdd_d):
    r""":math:`\dot q_d = J(q_d)^{-1}\dot x_d`, :math:`\ddot q_d = J(q_d)^{-1}(\ddot x_d - \dot J\dot q_d)` for a
    given :math:`q_d` (what a student's IK + joint CT does after its IK)."""
    J = terms(model, q_d, np.zeros(3)).J
    qd_d = np.linalg.solve(J, xd_d)
    jdq = terms(model, q_d, qd_d).jdq
    return qd_d, np.linalg.solve(J, xdd_d - jdq)


def _ik_mistakes(model, T, state, q_d, qd_d, qdd_d, x_d, xd_d, xdd_d, Kp, Kd):
    M, h, q, qdot = T.M, T.h, state.q, state.qdot
    Td = terms(model, q_d, qd_d)

    def law(qdd, qd=qd_d, qq=q_d):
        return M @ (qdd + Kd * (qd - qdot) + Kp * (qq - q)) + h

    fb = Kd * (qd_d - qdot) + Kp * (q_d - q)
    qd_now = np.linalg.solve(T.J, xd_d)
    q_down = mirror_elbow(q_d)
    qd_down, qdd_down = _joint_reference_terms(model, q_down, xd_d, xdd_d)
    tops = []  # leaning back over the shoulder, with either elbow
    for q_top in (over_the_top(q_d), over_the_top(q_down)):
        tops.append((q_top, *_joint_reference_terms(model, q_top, xd_d, xdd_d)))
    # The same pose with some angle a full turn away: the IK is right as kinematics, but joint-space
    # control then drives that joint a full turn (q_d - q is off by 2π).
    shifts = [np.array(k) for k in itertools.product((-1, 0, 1), repeat=3)]
    turns = [k for k in shifts if any(k)]
    unwrapped = {
        f"unwrapped_{branch}_{i}": Mistake(
            law(qdd, qd=qd, qq=qq + 2 * np.pi * k),
            f"your IK returns the {branch} pose with an angle a full turn (2π) away from the one nearest the "
            "arm, so q_d − q is off by 2π and the joint CT drives that joint round a full turn: wrap the IK's "
            "angles into (−π, π]" + (" and take the elbow-up branch." if branch == "elbow-down" else "."),
            0.25 if branch == "elbow-up" else 0.0,
        )
        for branch, qq, qd, qdd in (("elbow-up", q_d, qd_d, qdd_d), ("elbow-down", q_down, qd_down, qdd_down))
        for i, k in enumerate(turns)
    }
    return {
        "no_jdot": Mistake(
            law(np.linalg.solve(Td.J, xdd_d)),
            "everything is right except the J̇(q_d, q̇_d) q̇_d term in q̈_d, which is missing or zero. "
            f"{JDOT_HINT} (at q_d, q̇_d: on the scratch MjData, after setting its qvel to q̇_d, call "
            "mujoco.mj_comVel before site_jdot_qdot).",
            0.5,
        ),
        "jdot_in_joint_space": Mistake(
            law(np.linalg.solve(Td.J, xdd_d) - Td.jdq),
            "J̇(q_d, q̇_d) q̇_d is subtracted after J(q_d)⁻¹, from the joints' acceleration, but it is an "
            "acceleration of the tip: q̈_d = J(q_d)⁻¹(ẍ_d − J̇q̇_d).",
            0.25,
        ),
        "jdot_sign": Mistake(
            law(np.linalg.solve(Td.J, xdd_d + Td.jdq)),
            "J̇(q_d, q̇_d) q̇_d must be subtracted: ẍ_d = J q̈_d + J̇q̇_d, so q̈_d = J(q_d)⁻¹(ẍ_d − J̇q̇_d).",
            0.25,
        ),
        "no_bias": Mistake(M @ (qdd_d + fb), NO_BIAS, 0.25),
        "bias_sign": Mistake(M @ (qdd_d + fb) - h, "h(q, q̇) must be added, not subtracted.", 0.25),
        "gravity_only": Mistake(M @ (qdd_d + fb) + gravity(model, q), GRAVITY_ONLY, 0.5),
        "no_damping": Mistake(
            M @ (qdd_d + Kp * (q_d - q)) + h, "the damping term Kd (q̇_d − q̇) inside M(q)(...) is missing.", 0.5
        ),
        "damping_sign": Mistake(
            M @ (qdd_d - Kd * (qd_d - qdot) + Kp * (q_d - q)) + h,
            "the damping has the wrong sign: it must be +Kd (q̇_d − q̇).",
            0.5,
        ),
        "no_reference_velocity_at_all": Mistake(
            law(np.linalg.solve(Td.J, xdd_d), qd=np.zeros_like(qd_d)),
            "q̇_d is zero throughout the law: the damping is −Kd q̇, and J̇(q_d, q̇_d) q̇_d in q̈_d vanishes with "
            "it. The reference moves: q̇_d = J(q_d)⁻¹ ẋ_d, in the damping Kd (q̇_d − q̇) and in J̇(q_d, q̇_d) q̇_d.",
            0.5,
        ),
        **{  # a wrong q̇_d in the damping, with J̇q̇_d in q̈_d taken at the right q̇_d or at the same wrong one
            f"{name}{suffix}": Mistake(law(qdd, qd=qd), text, score)
            for name, qd, text, score in (
                (
                    "unmapped_velocity",
                    xd_d,
                    "the damping compares ẋ_d, the tip's velocity, with q̇, the joints': the joints' reference "
                    "velocity is q̇_d = J(q_d)⁻¹ ẋ_d.",
                    0.25,
                ),
                (
                    "velocity_jacobian_at_arm",
                    qd_now,
                    "q̇_d uses the Jacobian of the arm's state, J(q)⁻¹ ẋ_d from the data the law is given; the "
                    "reference needs J(q_d)⁻¹ ẋ_d, from the scratch MjData set to q_d, as your q̈_d does. The two "
                    "agree once the arm is on the reference, so it still tracks.",
                    0.75,
                ),
            )
            for suffix, qdd in (("", qdd_d), ("_jdot", np.linalg.solve(Td.J, xdd_d - terms(model, q_d, qd).jdq)))
        },
        "unmapped_reference": Mistake(
            law(xdd_d, qd=xd_d),
            "q̇_d and q̈_d are the Cartesian ẋ_d and ẍ_d: the joint reference maps them through J(q_d)⁻¹, "
            "q̇_d = J(q_d)⁻¹ ẋ_d and q̈_d = J(q_d)⁻¹(ẍ_d − J̇q̇_d).",
            0.25,
        ),
        "no_reference_velocity": Mistake(
            law(qdd_d, qd=np.zeros_like(qd_d)),
            "the damping is −Kd q̇, with q̇_d missing: it must be Kd (q̇_d − q̇), where q̇_d = J(q_d)⁻¹ ẋ_d. "
            "Without q̇_d the damping brakes the joints toward standing still, so on the moving circle the arm "
            "lags behind its reference.",
            0.5,
        ),
        "own_gains": own_gains_mistake(M @ (qdd_d + KD * (qd_d - qdot) + KP * (q_d - q)) + h, KP, KD),
        "swapped_gains": swapped_gains_mistake(
            M @ (qdd_d + Kp * (qd_d - qdot) + Kd * (q_d - q)) + h, "q_d − q", "q̇_d − q̇"
        ),
        "model_at_reference": Mistake(
            Td.M @ (qdd_d + fb) + Td.h,
            "M and h are taken at the reference (q_d, q̇_d); the law needs them at the arm's state (q, q̇), "
            "from the data the controller is given. The two agree once the arm is on the reference, so it "
            "still tracks.",
            0.75,
        ),
        **{
            f"{term}_at_reference": Mistake(
                torque,
                f"{said} is taken at the reference (q_d, q̇_d), from the scratch MjData, while {other} is the "
                f"arm's; the law needs both at the arm's state (q, q̇): take {said} from the data the controller "
                "is given too.",
                0.75,
            )
            for term, said, other, torque in (
                ("mass", "M", "h", Td.M @ (qdd_d + fb) + h),
                ("bias", "h", "M", M @ (qdd_d + fb) + Td.h),
            )
        },
        "no_mass": Mistake(qdd_d + fb + h, "the mass matrix is missing: τ = M(q)(...) + h.", 0.25),
        "inverse_mass": Mistake(np.linalg.solve(M, qdd_d + fb) + h, INVERSE_MASS, 0.25),
        "no_ff": Mistake(
            M @ fb + h,
            "the feed-forward acceleration q̈_d is missing"
            + (
                ", or zero: here the reference is at rest, so q̈_d = J(q_d)⁻¹ ẍ_d; check that ẍ_d is in it."
                if not np.any(xd_d)
                else "."
            ),
            0.25,
        ),
        "sign": Mistake(M @ (qdd_d - fb) + h, "the feedback terms (Kp, Kd) have the wrong sign: e = q_d − q.", 0.0),
        "spring_sign": Mistake(
            law(qdd_d, qq=2 * q - q_d),
            "the spring term has the wrong sign: Kp (q_d − q), not Kp (q − q_d); the damping term is right.",
            0.0,
        ),
        "current_state": Mistake(
            law(np.linalg.solve(T.J, xdd_d - T.jdq), qd=qd_now),
            "q̇_d and q̈_d use J and J̇q̇ at the arm's state (q, q̇); the reference needs them at "
            "(q_d, q̇_d): J(q_d)⁻¹ ẋ_d and J(q_d)⁻¹(ẍ_d − J̇(q_d, q̇_d) q̇_d). The two agree "
            "once the arm is on the reference, so it still tracks.",
            0.75,
        ),
        "jdot_arm_velocity": Mistake(
            law(np.linalg.solve(Td.J, xdd_d - terms(model, q_d, qdot).jdq)),
            "q̈_d takes J̇q̇ at q_d but with the arm's velocity q̇ (the scratch MjData's qvel set to data.qvel); "
            "the reference needs J̇(q_d, q̇_d) q̇_d, with its qvel set to q̇_d. The two agree once the arm is on "
            "the reference, so it still tracks.",
            0.75,
        ),
        "jacobian_at_arm": Mistake(
            law(np.linalg.solve(T.J, xdd_d - terms(model, q_d, qd_now).jdq), qd=qd_now),
            "q̇_d and q̈_d use the Jacobian of the arm's state, J(q) from the data the law is given; the "
            "reference needs J(q_d), from the scratch MjData set to q_d. The two agree once the arm is on the "
            "reference, so it still tracks.",
            0.75,
        ),
        "jdot_at_arm": Mistake(
            law(np.linalg.solve(Td.J, xdd_d - T.jdq)),
            "q̈_d takes J̇q̇ at the arm's state, J̇(q, q̇) q̇; the reference needs it at (q_d, q̇_d): "
            "J̇(q_d, q̇_d) q̇_d, from the same scratch MjData as J(q_d). The two agree once the arm is "
            "on the reference, so it still tracks.",
            0.75,
        ),
        "elbow_down": Mistake(
            law(qdd_down, qd=qd_down, qq=q_down),
            "the IK returns the elbow-down branch, but the arm runs elbow up (elbow_up=True).",
            0.0,
        ),
        **unwrapped,
        **{  # whatever full turns the IK adds to it
            f"over_the_top{'_other_elbow' if j else ''}_{i}": Mistake(
                law(qdd_top, qd=qd_top, qq=q_top + 2 * np.pi * k),
                f"the IK returns {OVER_THE_TOP}{', with the elbow on the other side' if j else ''}, while the "
                "arm runs facing the target, so the joint CT swings it half a turn round: take q1 = atan2(y, x)"
                + (" and the elbow-up branch." if j else "."),
                0.0,
            )
            for j, (q_top, qd_top, qdd_top) in enumerate(tops)
            for i, k in enumerate(shifts)
        },
    }


def _ik_expected(T, state, case: Case) -> np.ndarray:
    """IK + joint CT's formula with MuJoCo's terms ``T`` at the case's tested ``state``."""
    q_d, qd_d, qdd_d = case.q_d[-1], case.qd_d[-1], case.qdd_d[-1]
    return T.M @ (qdd_d + case.Kd * (qd_d - state.qdot) + case.Kp * (q_d - state.q)) + T.h


def _law_torque(model, case: Case, law: str) -> np.ndarray:
    """The torque of ``law`` (``"os"`` or ``"ik"``) at the case's tested state, without the named
    mistakes :func:`_os_case` and :func:`_ik_case` build besides."""
    state = case.states[-1]
    T = terms(model, state.q, state.qdot, state.t)
    if law == "os":
        return _os_expected(T, state, case.x_d[-1], case.xd_d[-1], case.xdd_d[-1], case.Kp, case.Kd)[0]
    return _ik_expected(T, state, case)


def _ik_case(model, case: Case):
    """At the case's tested state: IK + joint CT's torque, the J̇q̇ a torque implies, MuJoCo's J̇q̇
    at the reference, the IK offset a torque implies (where the reference is at rest) and the
    named mistakes."""
    state = case.states[-1]
    T = terms(model, state.q, state.qdot, state.t)
    q_d, qd_d, qdd_d = case.q_d[-1], case.qd_d[-1], case.qdd_d[-1]
    x_d, xd_d, xdd_d = case.x_d[-1], case.xd_d[-1], case.xdd_d[-1]
    Kp, Kd = case.Kp, case.Kd
    expected = _ik_expected(T, state, case)
    Td = terms(model, q_d, qd_d)

    def implied_jdq(tau):
        qdd = np.linalg.solve(T.M, tau - T.h) - Kd * (qd_d - state.qdot) - Kp * (q_d - state.q)
        return xdd_d - Td.J @ qdd

    def implied_ik_offset(tau):
        r"""How far [m] from :math:`x_d` the :math:`q_d` lies that would make ``tau`` the torque
        where the reference is at rest, everything else exact:
        :math:`\delta x = J(q_d)\,(K_p M)^{-1}(\tau - \tau_{\text{formula}})`."""
        return float(np.linalg.norm(Td.J @ np.linalg.solve(T.M, tau - expected)) / Kp)

    mistakes = _ik_mistakes(model, T, state, q_d, qd_d, qdd_d, x_d, xd_d, xdd_d, Kp, Kd)
    return expected, implied_jdq, Td.jdq, implied_ik_offset, mistakes


def _elsewhere(cases: list[Case], case: Case) -> tuple:
    """The arguments (state first) of a tracking law's first call in a case other than ``case``."""
    other = cases[-1] if case is not cases[-1] else cases[0]
    return (other.states[0], other.x_d[0], other.xd_d[0], other.xdd_d[0], other.Kp, other.Kd)


def _other_ik_answer(probe: Probe, case: Case) -> str:
    """Where the student's own ``ik_3r`` puts the arm elsewhere than the elbow-up IK at the tested
    reference point (another branch, an angle a turn off, a numerical IK that wandered), the words
    that say so, else ``""``."""
    x_d, q_d = case.x_d[-1], case.q_d[-1]
    q = _own_ik_answer(probe, x_d)
    if not isinstance(q, np.ndarray) or np.abs(q - q_d).max() <= 1e-3:
        return ""
    with np.printoptions(precision=3, suppress=True):
        return (
            f". At this x_d your ik_3r(x_d, elbow_up=True) gives q = {q}, where the elbow-up IK with angles in "
            f"(−π, π] is {q_d}: the law drives the arm towards whatever q_d its IK gives, so make ik_3r "
            "return that one"
        )


def check_ik_ct(probe: Probe, seed: int) -> Result:
    """``ct_ik_joint_torque`` against IK + joint-space computed torque at seeded states."""
    name, label, fname = "p2_ikct", "IK+JS-CT", "ct_ik_joint_torque"
    model = arm_model()
    worst = 0.0
    cases = tracking_cases(seed, name, still="reference")
    for case in cases:
        try:
            tau = call_along(probe, fname, case, lambda k, c=case: (c.x_d[k], c.xd_d[k], c.xdd_d[k], c.Kp, c.Kd))
        except StudentError as err:
            err = none_here_only(probe, fname, err, _elsewhere(cases, case))
            if "NoneType" in str(err) and isinstance(_own_ik_answer(probe, case.x_d[0]), NotImplementedYet):
                err = StudentError(f"{err}; ik_3r returned None there: {IK_NOT_PASTED}")  # the law's IK
            return refused(name, label, err)
        expected, implied, jdq, ik_offset, mistakes = _ik_case(model, case)
        if case.still and ik_offset(tau) <= 2 * IK_APPROX:
            verdict = Verdict(1.0, "")  # a numerical IK's q_d
        elif case.still:
            verdict = judge_torque(tau, expected, mistakes, rtol=STILL_RTOL)
        else:
            verdict = judge_torque(tau, expected, mistakes, implied, jdq)
        if verdict.score < 1:
            text = verdict.text
            if verdict.score == 0 and text.startswith("got"):
                text = (
                    "the torque differs from IK + joint CT: check q_d = IK(x_d) (elbow up), q̇_d = J(q_d)⁻¹ ẋ_d "
                    "and q̈_d = J(q_d)⁻¹(ẍ_d − J̇(q_d, q̇_d) q̇_d), with J and J̇q̇ from a scratch MjData on which "
                    "mujoco.mj_kinematics and mujoco.mj_comPos ran after its qpos was set, and mujoco.mj_comVel "
                    "after its qvel, at every call; " + text + _other_ik_answer(probe, case)
                )
            return failed(name, f"{label}: {_where(case, 'the reference', text)}", verdict.score)
        worst = max(worst, verdict.jdot_error or 0.0)
    note = (
        f" Your reference is an approximation (its J̇q̇ within {100 * worst:.2g} % of MuJoCo's): accepted."
        if worst > 1e-6
        else ""
    )
    return passed(
        name, "IK+JS-CT: ct_ik_joint_torque matches IK + joint-space computed torque at every test state." + note
    )


def tracking_circle(seed: int):
    """A seeded circle (centre, radius, normal), its start configuration ``q0`` (elbow up) and
    ``qdot0`` moving with it; the whole circle keeps the margins of
    :func:`~labsupport.grading.common.safe_point`.

    The circle is built around ``q0``, so no IK is needed: :math:`x_0 = \\mathrm{FK}(q_0)`, a
    random normal :math:`n` with in-plane basis :math:`u, v`, radius :math:`\\rho`, centre
    :math:`x_0 - \\rho u` (the circle's point at :math:`t = 0` is :math:`x_0`).
    """
    model = arm_model()
    rng = rng_for(seed, "p2_track")
    phases = np.linspace(0.0, 2 * np.pi, 181)
    while True:
        q0 = draw_configuration(rng, elbow_up=True)
        normal = rng.normal(size=3)
        normal /= np.linalg.norm(normal)
        radius = float(rng.uniform(0.15, 0.3))
        u, v = circle_basis(normal)
        center = tip(model, q0) - radius * u
        points = center + radius * (np.cos(phases)[:, None] * u + np.sin(phases)[:, None] * v)
        if all(safe_point(p, MARGINS) for p in points):
            break
    J0 = terms(model, q0, np.zeros(3)).J
    qdot0 = np.linalg.solve(J0, circle_3d(0.0, center, radius, normal, FREQUENCY).vel)
    return center, radius, normal, q0, qdot0


def _left_the_branch(model, log, every: int = 10, ik=None) -> str | None:
    """Where a run of IK + joint CT left the elbow-up solution facing the target (the branch the
    arm starts on), found from the logged poses, or None if it kept to it.

    A pan angle more than three quarters of a turn from the reference's azimuth (which never
    crosses ±π) comes first: an IK whose q1 is a full turn (2π) from the arm's makes the joint CT
    swing the arm round, whatever branch it passes through on the way. Then an IK whose answer at
    the circle's start is the right pose with an angle outside (−π, π]: the arm starts on the
    wrapped pose, and the joint CT turns that joint a full turn to reach it. ``ik`` (the student's
    ``ik_3r`` as ``x -> q``, None where it fails) tells an IK that switches branch there from
    torques that let the arm fall off a reference that kept to its branch."""
    pan_offset = log.q[:, 0] - np.arctan2(log.ref[:, 1], log.ref[:, 0])
    turned = np.flatnonzero(np.abs(pan_offset) > 1.5 * np.pi)
    if turned.size:
        k = turned[0]
        return (
            f"by t = {log.t[k]:.2f} s the pan had swung round to q1 = {log.q[k, 0]:.2f} rad, "
            f"{pan_offset[k]:+.2f} rad from the target's azimuth atan2(y, x): does the IK return a q1 a full "
            f"turn (2π) from the arm's, outside (−π, π]?{BRANCH_ADVICE}"
        )
    q_start = ik(log.ref[0]) if ik is not None else None
    if (  # the right pose, elbow up and facing the target, with an angle a turn off
        q_start is not None
        and has_unwrapped_angle(q_start)
        and elbow_height(model, q_start) > 0
        and not pan_turned_round(q_start, log.ref[0])
    ):
        return (
            f"your ik_3r gives q = {np.round(q_start, 3)} at the circle's start, an angle outside (−π, π]: the "
            "arm starts on the same pose with its angles wrapped, so the joint CT drives that joint a full turn "
            "(2π) round to yours. Wrap the IK's angles into (−π, π] (np.arctan2 returns angles there)"
        )
    for k in range(0, len(log.t), every):
        q, t = log.q[k], log.t[k]
        if pan_turned_round(q, log.ee[k]):
            where = "the arm faced away from its tip, on the over-the-top solution (pan half a turn from atan2(y, x))"
        elif elbow_height(model, q) < 0:
            where = "the elbow was below the shoulder-to-tip line, on the elbow-down branch"
        else:
            continue
        q_ik = ik(log.ref[k]) if ik is not None else None
        if q_ik is not None and elbow_height(model, q_ik) > 0 and not pan_turned_round(q_ik, log.ref[k]):
            return (
                f"at t = {t:.2f} s {where}, while your ik_3r gives the elbow-up solution facing the target "
                "there: either the law asks its IK for another branch (ik_3r(x, elbow_up=False), say), or its "
                "torques let the arm fall off its reference (the IK+JS-CT check says which)"
            )
        return f"at t = {t:.2f} s {where}: does the IK switch to it there?{BRANCH_ADVICE}"
    return None


def _other_laws_torque(probe: Probe, seed: int, fname: str) -> str | None:
    """Why a run of the student's ``fname`` is not a run of its law, or None: at the test state of
    its own check where OS-CT and IK + joint CT differ most, it returns the *other* law's torque
    (within a tenth of their difference). An alias such as ``ct_ik_joint_torque = ct_op_torque``
    tracks the circle, and would otherwise earn the credit of a law never written. None too where
    the call fails: the run then says why."""
    own_check, still, own, other, label, other_label = {
        "ct_op_torque": ("p2_osct", "arm", "os", "ik", "OS-CT", "IK + joint CT"),
        "ct_ik_joint_torque": ("p2_ikct", "reference", "ik", "os", "IK + joint CT", "OS-CT"),
    }[fname]
    model = arm_model()
    torques = [
        (_law_torque(model, c, own), _law_torque(model, c, other), c)
        for c in tracking_cases(seed, own_check, still=still)
    ]
    tau_own, tau_other, case = max(torques, key=lambda t: np.linalg.norm(t[0] - t[1]))
    try:
        tau = call_along(probe, fname, case, lambda k: (case.x_d[k], case.xd_d[k], case.xdd_d[k], case.Kp, case.Kd))
    except StudentError:
        return None
    apart = np.linalg.norm(tau_own - tau_other)
    if np.linalg.norm(tau - tau_other) < 0.1 * apart:
        return (
            f"{fname} returns {other_label}'s torque, not {label}'s, at a test state where the two laws differ "
            f"by {100 * apart / np.linalg.norm(tau_own):.0f} %, so its run is not counted as {label}'s"
        )
    return None


def _not_its_law(probe: Probe, seed: int, fname: str) -> str | None:
    """Why a run of the student's ``fname`` that tracks the circle earns none of its law's credit,
    or None.

    A run shows how a law tracks, so it counts for the law that the law's own formula check
    (``p2_osct``, ``p2_ikct``) finds at this seed's test states. Where that check scores zero,
    ``fname`` is not that law there, however well it tracks: the same law with other gains, say,
    or a function that tells the checks' states from a run's and answers them apart (the other
    law handed in again is named before the run, by :func:`_other_laws_torque`)."""
    check, label = {"ct_op_torque": (check_os_ct, "OS-CT"), "ct_ik_joint_torque": (check_ik_ct, "IK + joint CT")}[fname]
    if check(probe, seed).score > 0:
        return None
    return (
        f"{fname} scores zero on its own formula check, so this run does not count as {label}'s (that check says why)"
    )


def check_tracking(probe: Probe, seed: int) -> Result:
    """Both of the student's controllers track one turn of a seeded circle with RMS error below
    :data:`RMS_TOL`, starting on it and moving with it."""
    name = "p2_track"
    center, radius, normal, q0, qdot0 = tracking_circle(seed)

    def ref(t):
        return circle_3d(t, center, radius, normal, FREQUENCY)

    def args(t):
        r = ref(t)
        return r.pos, r.vel, r.acc, KP, KD

    def student_ik(x):  # the student's elbow-up IK at x, or None where it fails
        try:
            return as_vector("ik_3r", probe.call("ik_3r", x, elbow_up=True), 3, "joint vector")
        except StudentError:
            return None

    score, notes, statuses = 0.0, [], []
    for fname, label in (("ct_op_torque", "OS-CT"), ("ct_ik_joint_torque", "IK+JS-CT")):
        probe.begin_part(fname, 0.5)  # each law its own half of the time: a slow one costs only its own points
        borrowed = _other_laws_torque(probe, seed, fname)
        if borrowed:
            notes.append(f"{label}: {borrowed}")
            statuses.append("ran")
            continue
        try:
            log = run_student(probe, fname, args, TRACK_DURATION, q0, qdot0, reference=ref)
        except StudentError as err:
            start = student_ik(ref(0.0).pos) if fname == "ct_ik_joint_torque" and RAN_AWAY in str(err) else None
            if start is not None and (question := degrees_question(start)):  # the law's own IK, in degrees
                with np.printoptions(precision=1, suppress=True):
                    err = StudentError(
                        f"{err}, but first: your ik_3r gives q = {start} at the circle's start, {question} (TODO 1)"
                    )
            result = refused(name, label, err)
            notes.append(result.message)
            statuses.append(result.status)
            continue
        err = rms_norm(log.err)
        statuses.append("ran")
        if err < RMS_TOL and (other := _not_its_law(probe, seed, fname)):
            notes.append(f"{label}: RMS error {err * 1e3:.3g} mm, but {other}")
        elif err < RMS_TOL:
            score += 0.5
            notes.append(f"{label}: RMS error {err * 1e3:.3g} mm (needs < {RMS_TOL * 1e3:g} mm)")
        else:
            left = _left_the_branch(arm_model(), log, ik=student_ik) if fname == "ct_ik_joint_torque" else None
            left = left or (NOTEBOOK_CIRCLE if _followed_the_notebooks_circle(log) else None)
            notes.append(
                f"{label}: RMS error {show_beside(err * 1e3, RMS_TOL * 1e3)} mm, should be below {RMS_TOL * 1e3:g} mm"
                f"{'' if left else LAG_HINT if err > LAG_RMS else TRACKING_HINT}" + (f" ({left})" if left else "")
            )
    with np.printoptions(precision=3, suppress=True):
        where = f"one turn of a circle of radius {radius:.3f} m about {center}, normal {normal}"
    text = f"tracking ({where}): " + "; ".join(note.rstrip(".") for note in notes) + "."
    if score == 1.0:
        return passed(name, text)
    if score == 0 and all(s == "not implemented yet" for s in statuses):
        return not_implemented(name, text)
    return failed(name, text, score)


CHECKS = {"p2_start": check_start, "p2_osct": check_os_ct, "p2_ikct": check_ik_ct, "p2_track": check_tracking}


def named_mistakes(check: str, seed: int) -> dict[str, Mistake]:
    """The mistakes check ``check`` names, with their credit, built at its first moving test state:
    what the grading rubric lists (none for a check that is not a formula check, ``p2_osct`` or
    ``p2_ikct``)."""
    if check not in ("p2_osct", "p2_ikct"):
        return {}
    case_of, still = {"p2_osct": (_os_case, "arm"), "p2_ikct": (_ik_case, "reference")}[check]
    case = next(c for c in tracking_cases(seed, check, still=still) if not c.still)
    return case_of(arm_model(), case)[-1]


#: Checks whose score is a share of their points: none here (see problem1.PROPORTIONAL).
PROPORTIONAL = frozenset()
#: Partial credit a check gives besides its named mistakes, for the Canvas rubric's ratings; the
#: same rules as :data:`SCORING` states.
PARTIAL_CREDIT = {
    "p2_start": [(0.5, "The start is on the circle's first point but elbow down, or with the pan half a turn round.")],
    "p2_track": [(0.5, "One of the two controllers keeps its RMS error below the limit, the other does not.")],
}

#: How each check scores, for the grading rubric (the named mistakes come from the checks).
SCORING = {
    "p2_start": (
        f"The student's q0_traj must put the tip within {START_TOL * 1e3:g} mm of the notebook circle's start "
        "point: full credit elbow up and facing it; half elbow down or with the pan half a turn round; 0 "
        "otherwise (in degrees too)."
    ),
    "p2_osct": formula_scoring(with_jdot=True),
    "p2_ikct": formula_scoring(with_jdot=True)
    + " Where the reference is at rest, a torque that a q_d whose tip is within "
    f"{2 * IK_APPROX * 1e6:g} µm of the target explains (a numerical IK's) counts as exact too.",
    "p2_track": (
        f"Each of the two controllers runs one {TRACK_DURATION:g} s turn of a drawn circle from a start on it: half "
        f"the credit for each whose RMS position error stays below {RMS_TOL * 1e3:g} mm and whose own formula "
        "check (p2_osct, p2_ikct) scores above zero. A controller that returns the other law's torque (one law "
        "handed in twice) is not run and earns nothing here."
    ),
}
