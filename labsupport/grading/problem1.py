r"""Checks of Problem 1 (reaching with the 3R arm): IK, joint PD, joint computed torque, and
the computed-torque reach itself. None needs a reference solution.

The student's notebook defines

* ``ik_3r(x, elbow_up=True) -> q``: joint angles putting the tip at ``x``; checked by putting
  them through MuJoCo's forward kinematics (and the elbow's side of the shoulder–tip line);
* ``pd_torque(model, data, q_d, Kp, Kd)``: :math:`\tau = K_p(q_d - q) - K_d\dot q`;
* ``ct_joint_torque(model, data, q_d, Kp, Kd)``:
  :math:`\tau = M(q)\big(K_p(q_d - q) - K_d\dot q\big) + h(q, \dot q)`, checked against that
  formula with MuJoCo's :math:`M` and :math:`h` at seeded states, and by its outcome: the run
  toward a seeded target.

Every check is ``check(probe, seed)``: the seed draws the targets and states.
"""

from __future__ import annotations

import itertools
import warnings
from functools import partial

import numpy as np

from labsupport.grading.common import (
    GRAVITY_ONLY,
    INVERSE_MASS,
    ZERO_BIAS_NOTE,
    Mistake,
    argument_order_mistakes,
    arm_model,
    degrees_mistake,
    draw_configuration,
    elbow_height,
    formula_scoring,
    gravity,
    has_unwrapped_angle,
    judge_torque,
    none_here_only,
    own_gains_mistake,
    pan_error,
    pan_turned_round,
    rng_for,
    run_student,
    swapped_gains_mistake,
    terms,
    tip,
)
from labsupport.grading.feedback import (
    NotImplementedYet,
    Probe,
    Result,
    State,
    StudentError,
    StudentTimeout,
    as_vector,
    failed,
    forbidden_reason,
    passed,
    refused,
    show_beside,
)

#: The Problem's numbers.
Q0 = np.array([0.0, np.pi / 6, -np.pi / 4])  # initial configuration [rad]
DURATION = 5.0  # [s]
WN_CT, ZETA_CT = 10.0, 0.9  # computed-torque design
KP_CT, KD_CT = WN_CT**2, 2 * ZETA_CT * WN_CT
KP_PD, KD_PD = 400.0, 50.0  # the notebook's PD gains, the lab's
#: The notebook's settings that the checks copy: for the code cell that opens with the key, each
#: name it sets and the constant here that must equal it (``labsupport.instructor.assign``
#: refuses to write the student notebook while the master and these differ).
NOTEBOOK_SETTINGS = {
    "q0 =": {"q0": "Q0", "T_sim": "DURATION", "Kp_pd": "KP_PD", "Kd_pd": "KD_PD", "Kp_ct": "KP_CT", "Kd_ct": "KD_CT"}
}
REACH_TOL = 1e-3  # final end-effector error the computed torque must reach [m]
#: An IK solution must put the tip this close to the target [m] (a tenth of the reach tolerance:
#: a numerical IK that stops at 1e-5 m passes).
IK_TOL = 1e-4
#: An IK answer this close to the target [m], but not within :data:`IK_TOL`, is told how a
#: numerical IK gets there (a closed form is either right or centimetres off).
NEARLY = 1e-2
#: Targets the IK check draws; each is solved on both elbow branches. Enough that an IK which
#: fails on a few percent of targets (a Newton iteration that sometimes does not converge) is
#: found in most batches, and scores about the same in each, where five targets found it in
#: about one batch in four; the calls are cheap next to the runs.
N_TARGETS = 25
#: After this many calls that did not return, the IK check makes no more calls on that elbow
#: branch and counts them wrong: an IK that hangs on a branch would otherwise spend the whole
#: check's time there (and the grader's on the checks after it).
MAX_TIMEOUTS = 2
#: The ranges the formula checks draw their gains from: (Kp range, Kd range).
PD_GAINS = ((100, 500), (10, 60))
CT_GAINS = ((50, 150), (5, 25))


def _branch(up: bool) -> str:
    return "elbow-up" if up else "elbow-down"


def _ik_problem(model, q, x, up: bool) -> str | None:
    """What is wrong with ``q`` as the ``up`` branch's solution for target ``x`` (None if right)."""
    err = float(np.linalg.norm(tip(model, q) - x))
    azimuth = float(np.arctan2(x[1], x[0]))
    if err <= IK_TOL:
        if pan_turned_round(q, x):
            return (
                f"the {_branch(up)} call reaches the target, but its pan angle q1 = {q[0]:.4f} rad is half a "
                f"turn from the target's azimuth atan2(y, x) = {azimuth:.4f} rad: the arm "
                "leans back over its shoulder. That pose is another solution, not the one this Problem asks for, "
                "and Problem 2's arm runs on the one facing the target: take q1 = atan2(y, x) (a numerical IK: "
                "fix q1 there, or start from it, and solve for q2, q3)"
            )
        if (elbow_height(model, q) > 0) != up:
            return (
                f"the {_branch(up)} call reaches the target, but with the elbow "
                f"{'below' if up else 'above'} the shoulder-to-target line: that is the "
                f"{_branch(not up)} branch (elbow_up=True takes θ = +arccos(...))"
            )
        return None
    with np.printoptions(precision=4, suppress=True):
        if float(np.linalg.norm(tip(model, np.radians(q)) - x)) <= IK_TOL:
            return (
                f"the angles {q} are in degrees: MuJoCo (and np.sin, np.cos) work in radians; "
                "return them in radians (do not convert with np.degrees)"
            )
        if pan_error(q, x) < 1e-3:
            advice = "check the planar 2R solve for q2, q3"
            if err < NEARLY:  # close, as a numerical IK stopped too early is
                advice = (
                    f"a numerical IK must go on until the tip is within {IK_TOL * 1e3:g} mm (stop it at 1e-5 m: a "
                    f"tighter tolerance, or more iterations); a closed-form one: {advice}"
                )
            return (
                f"the pan angle is right, but the {_branch(up)} solution {q} puts the end effector "
                f"{err:.4g} m from the target {x}, more than the {IK_TOL * 1e3:g} mm allowed: {advice}"
            )
        return (
            f"the pan angle q1 = {q[0]:.5g} rad, but the target {x} has azimuth atan2(y, x) = {azimuth:.4f} rad; "
            f"the end effector lands {err:.4g} m away"
        )


def check_ik(probe: Probe, seed: int) -> Result:
    """``ik_3r`` on seeded reachable targets (tips of drawn configurations), both elbow branches."""
    name, label = "p1_ik", "IK"
    model = arm_model()
    rng = rng_for(seed, name)
    targets = [tip(model, draw_configuration(rng, elbow_up=bool(k % 2 == 0))) for k in range(N_TARGETS)]
    good, total, problems, errors, worst, unwrapped = 0, 0, [], [], 0.0, []
    other_branch = 0  # solutions right for the other elbow_up
    hung = dict.fromkeys((True, False), 0)  # calls per branch that did not return
    untried = dict.fromkeys((True, False), 0)  # calls not made after MAX_TIMEOUTS of them
    # one branch on every target, then the other: an IK that hangs on one branch does so after
    # the other branch has had all its calls
    for up, x in itertools.product((True, False), targets):
        total += 1
        where = f"target {np.round(x, 4)}, elbow_up={up}"
        if hung[up] >= MAX_TIMEOUTS:
            untried[up] += 1
            errors.append("not tried")
            continue
        try:
            q = as_vector("ik_3r", probe.call("ik_3r", x, elbow_up=up), 3, "joint vector")
        except NotImplementedYet as err:  # not implemented, unless it returns angles elsewhere
            problems.append(
                f"{where}: ik_3r returned None there, where it returns angles for other calls (a path "
                "through the function that ends without a return statement returns None)"
            )
            errors.append(err)
            continue
        except StudentError as err:
            if forbidden_reason(err) is not None:
                return refused(name, label, err)
            hung[up] += isinstance(err, StudentTimeout)
            problems.append(f"{where}: {err}")
            errors.append(str(err))
            continue
        problem = _ik_problem(model, q, x, up)
        if problem is None:
            good += 1
            worst = max(worst, float(np.linalg.norm(tip(model, q) - x)))
            if up and has_unwrapped_angle(q):  # the elbow-down branch's q3 lies below −π
                unwrapped.append(q)
        else:
            problems.append(f"{where}: {problem}")
            other_branch += _ik_problem(model, q, x, not up) is None
    if good == total:
        return passed(
            name,
            f"IK: all {total} solutions ({len(targets)} targets × 2 elbow branches) put the "
            f"end effector on the target, elbow on the side asked (worst error {worst:.1e} m)."
            + _unwrapped_note(unwrapped)
            + _unreachable_note(probe),
        )
    if other_branch == total:  # a convention swapped, as Kp and Kd can be: half, as for them
        return failed(
            name,
            f"IK: all {total} solutions put the end effector on the target, but each on the other elbow branch "
            "than the one asked: elbow_up=True must put the elbow above the shoulder-to-target line (θ = "
            "+arccos(...)), and elbow_up=False below it. Swap the two branches.",
            0.5,
        )
    if len(errors) == total and all(isinstance(err, NotImplementedYet) for err in errors):
        return refused(name, label, errors[0])  # None for every target: not implemented yet
    if len(errors) == total and len(set(map(str, errors))) == 1:  # the same failure on every call: say it once
        return failed(name, f"{label}: {errors[0]}")
    first = "The first wrong one" if len(problems) > 1 else "The wrong one"
    skipped = "".join(
        f" The other {n} {_branch(up)} calls were not made (counted wrong): ik_3r did not return on "
        f"{MAX_TIMEOUTS} of them already."
        for up, n in untried.items()
        if n
    )
    wrong = problems[0].rstrip(".")
    return failed(
        name,
        f"IK: {good} of {total} solutions are right. {first}, {wrong}.{skipped}{_unwrapped_note(unwrapped)}",
        good / total,
    )


def _unwrapped_note(unwrapped: list) -> str:
    """A remark (no points) on right elbow-up solutions with an angle outside (−π, π], where the
    elbow-up branch's angles lie: they reach the target, but Problem 2's joint CT, whose arm
    starts on the wrapped pose, would turn that joint a full turn."""
    if not unwrapped:
        return ""
    return (
        f" Note (no points taken): {len(unwrapped)} elbow-up solutions have an angle outside (−π, π], such as q = "
        f"{np.round(unwrapped[0], 4)}. They reach the target, but in Problem 2 the joint CT would turn that "
        "joint a full turn (2π) toward such an angle: wrap them into (−π, π] (np.arctan2 returns angles there)."
    )


def _unreachable_note(probe: Probe) -> str:
    """A remark (no points) if ``ik_3r`` returns angles for a target out of reach instead of raising."""
    x = np.array([2.4, 0.0, 1.5])  # 2.45 m from the shoulder; the arm reaches 2 m
    try:
        with warnings.catch_warnings():  # NumPy's "invalid value in arccos" is what the note says, better
            warnings.simplefilter("ignore", RuntimeWarning)
            value = probe.call("ik_3r", x, elbow_up=True)
    except StudentError as err:
        if "ValueError" in str(err):
            return ""
        return f" (For a target out of reach, {x}, it should raise ValueError; it {err}.)".replace("ik_3r ", "")
    try:
        returned = "None" if value is None else "NaN" if np.isnan(np.asarray(value, dtype=float)).any() else "angles"
    except (TypeError, ValueError):  # not numbers: the IK check itself says so
        returned = repr(value)[:40]
    return (
        f" (Note, no points lost: for a target out of reach, {x} is 2.45 m from the shoulder, ik_3r returned "
        f"{returned} instead of raising a ValueError that says so.)"
    )


def _joint_law_cases(seed: int, check: str, gains, n: int = 4):
    """Seeded states (either elbow branch, random velocities), set points and gains. The first
    state is at t = 0, as a run starts; the others at drawn times within the run, so that a law
    that does something else after the start (replays its first torque, say) is seen to. One
    more case comes last, drawn from a stream of its own (the first ``n`` stay as they are): the
    arm at rest at t = 0, where every run starts, so that a law with a path that only rest takes
    (one that returns nothing while q̇ = 0, say) is seen to here, and not first in its run."""
    rng, clock = rng_for(seed, check), rng_for(seed, check + " time")
    cases = []
    for k in range(n):
        q = draw_configuration(rng, elbow_up=bool(k % 2 == 0))
        state = State(q, rng.uniform(-1.5, 1.5, 3), 0.0 if k == 0 else float(clock.uniform(0.1, DURATION)))
        cases.append(
            (state, q + rng.uniform(-0.5, 0.5, 3), float(rng.uniform(*gains[0])), float(rng.uniform(*gains[1])))
        )
    rest = rng_for(seed, check + " rest")
    q = draw_configuration(rest, elbow_up=True)
    cases.append(
        (
            State(q, np.zeros(3), 0.0),
            q + rest.uniform(-0.5, 0.5, 3),
            float(rest.uniform(*gains[0])),
            float(rest.uniform(*gains[1])),
        )
    )
    return cases


def _check_joint_law(
    probe: Probe, seed: int, name: str, label: str, function: str, gains, law, mistakes, summary: str
) -> Result:
    """Compare the student's ``function(model, data, q_d, Kp, Kd)`` with ``law(T, state, q_d, Kp, Kd)``
    (``T``: MuJoCo's :class:`~labsupport.grading.common.Terms` at the state) at seeded states; on a
    mismatch, name the mistake ``mistakes(T, state, q_d, Kp, Kd)`` explains."""
    model = arm_model()
    cases = _joint_law_cases(seed, name, gains)
    for k, (state, q_d, Kp, Kd) in enumerate(cases):
        T = terms(model, state.q, state.qdot)
        try:
            tau = as_vector(function, probe.call(function, state, q_d, Kp, Kd), 3, "torque")
        except StudentError as err:
            return refused(name, label, none_here_only(probe, function, err, cases[(k + 1) % len(cases)]))
        verdict = judge_torque(tau, law(T, state, q_d, Kp, Kd), mistakes(T, state, q_d, Kp, Kd))
        if verdict.score < 1:
            return failed(name, f"{label}: {verdict.text}", verdict.score)
    return passed(name, f"{label}: {function} gives {summary} at every test state.")


#: The arguments of the joint laws' stubs after ``model, data``.
STUB_ARGUMENTS = ("q_d", "Kp", "Kd")


def pd_law(T, state, q_d, Kp, Kd):
    return Kp * (q_d - state.q) - Kd * state.qdot


def _pd_mistakes(T, state, q_d, Kp, Kd):
    e, qdot = q_d - state.q, state.qdot
    return {
        "sign": Mistake(
            -(Kp * e - Kd * qdot),
            "the torque has the wrong sign: it pushes away from q_d. Use Kp (q_d − q) − Kd q̇.",
            0.0,
        ),
        "spring_sign": Mistake(
            Kp * (-e) - Kd * qdot,
            "the damping −Kd q̇ is right, but the spring term has the "
            "wrong sign: it must pull toward the set point, Kp (q_d − q), not Kp (q − q_d).",
            0.0,
        ),
        "no_damping": Mistake(
            Kp * e, "the spring term Kp (q_d − q) is right, but the damping term −Kd q̇ is missing.", 0.5
        ),
        "damping_sign": Mistake(
            Kp * e + Kd * qdot,
            "the spring term is right, but the damping has the wrong sign: it must oppose the motion, −Kd q̇.",
            0.5,
        ),
        "with_bias": Mistake(
            Kp * e - Kd * qdot + T.h,
            "you added h(q, q̇): that is computed torque's model term; the plain PD uses no model.",
            0.5,
        ),
        "with_gravity": Mistake(
            Kp * e - Kd * qdot + gravity(arm_model(), state.q),
            "you added gravity compensation g(q): a good law (PD plus gravity), but not the one asked for; "
            "the plain PD uses no model, and its sag under gravity is what this Problem measures.",
            0.5,
        ),
        "degrees": degrees_mistake(np.degrees(Kp * e - Kd * qdot)),
        "own_gains": own_gains_mistake(KP_PD * e - KD_PD * qdot, KP_PD, KD_PD),
        "swapped_gains": swapped_gains_mistake(Kd * e - Kp * qdot),
        **argument_order_mistakes(partial(pd_law, T, state), (q_d, Kp, Kd), STUB_ARGUMENTS),
    }


def check_pd(probe: Probe, seed: int) -> Result:
    """``pd_torque`` against :math:`K_p(q_d-q) - K_d\\dot q` at seeded states."""
    return _check_joint_law(
        probe, seed, "p1_pd", "PD", "pd_torque", PD_GAINS, pd_law, _pd_mistakes, "Kp (q_d − q) − Kd q̇"
    )


def ct_law(T, state, q_d, Kp, Kd):
    return T.M @ (Kp * (q_d - state.q) - Kd * state.qdot) + T.h


def _ct_mistakes(T, state, q_d, Kp, Kd):
    M, h, e, qdot = T.M, T.h, q_d - state.q, state.qdot
    v = Kp * e - Kd * qdot
    return {
        "no_bias": Mistake(
            M @ v,
            "M(q)(Kp e − Kd q̇) is right, but the bias term h(q, q̇) (data.qfrc_bias: gravity and Coriolis) is missing."
            + ZERO_BIAS_NOTE,
            0.25,
        ),
        "no_mass": Mistake(
            v + h, "h(q, q̇) is there, but the mass matrix is missing: multiply the PD term by M(q).", 0.25
        ),
        "inverse_mass": Mistake(
            np.linalg.solve(M, v) + h,
            INVERSE_MASS,
            0.25,
        ),
        "sign": Mistake(
            M @ (-v) + h, "the feedback terms (Kp, Kd) have the wrong sign: use e = q_d − q and −Kd q̇.", 0.0
        ),
        "spring_sign": Mistake(
            M @ (-Kp * e - Kd * qdot) + h,
            "the spring term has the wrong sign: Kp (q_d − q), not Kp (q − q_d); the damping −Kd q̇ is right.",
            0.0,
        ),
        "no_damping": Mistake(M @ (Kp * e) + h, "the damping term −Kd q̇ inside M(q)(...) is missing.", 0.5),
        "damping_sign": Mistake(M @ (Kp * e + Kd * qdot) + h, "the damping has the wrong sign: it must be −Kd q̇.", 0.5),
        "bias_sign": Mistake(M @ v - h, "h(q, q̇) must be added, not subtracted.", 0.25),
        "gravity_only": Mistake(M @ v + gravity(arm_model(), state.q), GRAVITY_ONLY, 0.5),
        "outside": Mistake(
            M @ (Kp * e) - Kd * qdot + h, "the damping −Kd q̇ must sit inside M(q)(...), with the spring term.", 0.5
        ),
        "degrees": degrees_mistake(M @ np.degrees(v) + h),
        "own_gains": own_gains_mistake(M @ (KP_CT * e - KD_CT * qdot) + h, KP_CT, KD_CT),
        "swapped_gains": swapped_gains_mistake(M @ (Kd * e - Kp * qdot) + h),
        **argument_order_mistakes(partial(ct_law, T, state), (q_d, Kp, Kd), STUB_ARGUMENTS),
    }


def check_ct(probe: Probe, seed: int) -> Result:
    """``ct_joint_torque`` against :math:`M(q)(K_p e - K_d\\dot q) + h` at seeded states."""
    return _check_joint_law(
        probe,
        seed,
        "p1_ct",
        "CT",
        "ct_joint_torque",
        CT_GAINS,
        ct_law,
        _ct_mistakes,
        "M(q)(Kp e − Kd q̇) + h(q, q̇)",
    )


def check_reach(probe: Probe, seed: int) -> Result:
    """The student's computed torque drives the tip from :data:`Q0` to a seeded target within
    1 mm in 5 s (the set point is a drawn elbow-up configuration, the target its tip)."""
    name, label = "p1_reach", "reach"
    model = arm_model()
    q_d = draw_configuration(rng_for(seed, name), elbow_up=True)
    target = tip(model, q_d)
    try:
        log = run_student(probe, "ct_joint_torque", (q_d, KP_CT, KD_CT), DURATION, Q0)
    except StudentError as err:
        return refused(name, label, err)
    final = float(np.linalg.norm(log.ee[-1] - target))
    with np.printoptions(precision=3, suppress=True):
        where = f"the target {target} (q_d = {q_d})"
    if final < REACH_TOL:  # a right law ends some 1e-12 mm off: said as such, not as "7.17e-12 mm"
        ends = f"{final * 1e3:.3g} mm from" if final >= 1e-6 else "within 0.001 mm of"
        return passed(
            name,
            f"reach: with your computed torque the end effector ends {ends} {where} after {DURATION:g} s "
            "(needs < 1 mm).",
        )
    return failed(
        name,
        f"reach: with your computed torque the end effector ends {show_beside(final * 1e3, REACH_TOL * 1e3)} mm "
        f"from {where} "
        f"after {DURATION:g} s; it should be below 1 mm (a right law ends far below it: one that falls "
        "short leaves out or gets wrong a term, h(q, q̇) or M(q) most often; the CT check, p1_ct, says which: "
        "in the notebook, run its cell again after changing the law).",
    )


CHECKS = {"p1_ik": check_ik, "p1_pd": check_pd, "p1_ct": check_ct, "p1_reach": check_reach}


def named_mistakes(check: str, seed: int) -> dict[str, Mistake]:
    """The mistakes check ``check`` names, with their credit, built at its first test state: what
    the grading rubric lists (none for a check that is not a formula check, ``p1_pd`` or ``p1_ct``)."""
    if check not in ("p1_pd", "p1_ct"):
        return {}
    mistakes, gains = {"p1_pd": (_pd_mistakes, PD_GAINS), "p1_ct": (_ct_mistakes, CT_GAINS)}[check]
    state, q_d, Kp, Kd = _joint_law_cases(seed, check, gains)[0]
    return mistakes(terms(arm_model(), state.q, state.qdot), state, q_d, Kp, Kd)


#: Checks whose score is a share of their points (any value between none and full marks): the
#: Canvas rubric gives them a range.
PROPORTIONAL = frozenset({"p1_ik"})
#: Partial credit a check gives besides its named mistakes, for the Canvas rubric's ratings.
PARTIAL_CREDIT: dict[str, list[tuple[float, str]]] = {}

#: How each check scores, for the grading rubric (the named mistakes come from the checks).
SCORING = {
    "p1_ik": (
        f"The student's ik_3r is called on {N_TARGETS} drawn reachable targets, each with elbow_up=True "
        f"and False: the share of the {2 * N_TARGETS} solutions that put the tip within {IK_TOL * 1e3:g} mm "
        "of the target (by MuJoCo's forward kinematics), on the elbow side asked, with the pan facing the "
        f"target. After {MAX_TIMEOUTS} calls on one branch that do not return, that branch's other calls are not "
        "made and count as wrong. Every solution on its target but on the other elbow branch (the two branches "
        "swapped) earns half. A target out of reach that does not raise ValueError gets a remark, no deduction."
    ),
    "p1_pd": formula_scoring(with_jdot=False),
    "p1_ct": formula_scoring(with_jdot=False),
    "p1_reach": (
        f"All or nothing: the student's ct_joint_torque, run from the Problem's start for {DURATION:g} s toward a "
        f"drawn target, must end within {REACH_TOL * 1e3:g} mm of it."
    ),
}
