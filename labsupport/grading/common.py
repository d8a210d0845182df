r"""Pieces the Problems' checks share, none of them a reference solution.

* Test configurations are drawn in **joint space** (seeded) and put through MuJoCo's forward
  kinematics, so every target is reachable by construction and its joint angles are known
  without inverse kinematics.
* Every quantity of a stated formula (:math:`M`, :math:`h`, :math:`J`, :math:`\dot J\dot q`,
  the tip position) comes from MuJoCo at the test state (:func:`terms`).
* A student's torque is judged against the formula by :func:`judge_torque`: exact within
  floating-point error, accepted as a sound approximation when only its :math:`\dot J\dot q`
  is approximate, or matched against the typical mistakes, each named. A tracking law is first
  tested where its :math:`\dot J\dot q` term vanishes (the arm, or the reference, momentarily
  at rest): there every other term must match exactly, so no error elsewhere can pass for an
  approximate :math:`\dot J\dot q` at the moving states.
* A run is the grader's own simulation of the arm under the student's controller
  (:func:`run_student`).
"""

from __future__ import annotations

import itertools
import zlib
from collections.abc import Callable
from dataclasses import dataclass
from functools import lru_cache

import mujoco
import numpy as np

from labsupport.dynamics import bias_forces, mass_matrix, site_jacobian, site_jdot_qdot
from labsupport.grading.feedback import NotImplementedYet, Probe, State, StudentError, as_vector, show_pair
from labsupport.grading.stability import Trace, explain_divergence
from labsupport.plants import load_model
from labsupport.sim import Log, SimulationDiverged, simulate

SITE = "end_effector"
#: Shoulder (joint 2) of the 3R arm, the centre of its reachable ball of radius 2 m [m].
SHOULDER = np.array([0.0, 0.0, 1.0])
#: Torques equal to the formula within floating-point error [N·m] (absolute, relative): wide
#: enough for a law computed in single precision (float32), far narrower than any named mistake.
TORQUE_ATOL, TORQUE_RTOL = 1e-4, 1e-5
#: The explanation of a law whose bias term is gravity alone (both Problems).
GRAVITY_ONLY = (
    "the bias term holds gravity alone; h(q, q̇) = data.qfrc_bias also holds the Coriolis and "
    "centrifugal forces, which grow with the speed (gravity alone is h only at rest)"
)
#: Said where a law's bias term is missing: one from mj_rne with flg_acc=1 comes out as zero at the
#: checks' states (both Problems).
ZERO_BIAS_NOTE = (
    " (A bias term from mujoco.mj_rne with flg_acc=1 comes out as zero here: it adds M q̈, the "
    "acceleration of the arm left to itself, which cancels h; use flg_acc=0, or data.qfrc_bias.)"
)
#: A J̇q̇ approximated within this fraction of its size (finite differences) still counts as exact.
JDOT_APPROX = 0.05
#: Where the law's J̇q̇ term vanishes, the torque matches the formula within this fraction of its
#: size: room for a numerical IK solved to about a micrometre, never for a wrong gain or term.
STILL_RTOL = 1e-3
#: How many control steps of a smooth motion lead up to each test state (so a function that
#: remembers its previous call, e.g. J̇ by finite differences in time, sees what a run shows it).
LEAD_IN = 4


@dataclass(frozen=True)
class Margins:
    """How far test configurations keep from the 3R arm's singularities and from angle wraps.

    Attributes:
        inner, outer: tip distance from the shoulder within [inner, outer] [m] (the arm folds
            at 0 and stretches at 2).
        axis: tip distance from the z axis at least this [m] (pan singularity).
        height: tip height above the floor at least this [m].
        wrap: pan angle and the elbow-up shoulder angle this far from ±π [rad].
    """

    inner: float = 0.35
    outer: float = 1.75
    axis: float = 0.35
    height: float = 0.1
    wrap: float = 0.35


MARGINS = Margins()


def rng_for(seed: int, check: str) -> np.random.Generator:
    """The random generator of one check under one seed (each check draws its own stream)."""
    return np.random.default_rng([int(seed), zlib.crc32(check.encode())])


@lru_cache(maxsize=1)
def arm_model() -> mujoco.MjModel:
    """The 3R arm's MuJoCo model (loaded once; each use makes its own ``MjData``)."""
    return load_model("spatial_3r")[0]


def data_at(model: mujoco.MjModel, q, qdot=None, t: float = 0.0) -> mujoco.MjData:
    """A fresh ``MjData`` at the state, ``mj_forward`` run."""
    data = mujoco.MjData(model)
    data.qpos[:] = q
    data.qvel[:] = 0.0 if qdot is None else qdot
    data.time = t
    mujoco.mj_forward(model, data)
    return data


def tip(model: mujoco.MjModel, q) -> np.ndarray:
    """End-effector position at ``q``: MuJoCo's forward kinematics (``mj_kinematics``)."""
    data = mujoco.MjData(model)
    data.qpos[:] = q
    mujoco.mj_kinematics(model, data)
    return data.site(SITE).xpos.copy()


def elbow_height(model: mujoco.MjModel, q) -> float:
    """Signed distance of the elbow (joint 3) above the line from the shoulder to the tip, in the
    arm's vertical plane: positive for the elbow-up branch, negative for elbow-down."""
    data = mujoco.MjData(model)
    data.qpos[:] = q
    mujoco.mj_kinematics(model, data)
    shoulder, elbow, p = data.body("link2").xpos, data.body("link3").xpos, data.site(SITE).xpos
    d = (p - shoulder) / np.linalg.norm(p - shoulder)
    up = np.array([0.0, 0.0, 1.0]) - d[2] * d  # vertical, made perpendicular to the line
    return float((elbow - shoulder) @ up / max(np.linalg.norm(up), 1e-12))


def safe_point(x, margins: Margins = MARGINS) -> bool:
    """Whether a tip position keeps the margins: reachable, off the z axis, above the floor, and
    with the pan angle ``atan2(y, x)`` and the elbow-up shoulder angle away from ±π."""
    x = np.asarray(x, dtype=float)
    d = float(np.linalg.norm(x - SHOULDER))
    rho = float(np.hypot(x[0], x[1]))
    return (
        margins.inner <= d <= margins.outer
        and rho >= margins.axis
        and x[2] >= margins.height
        and abs(np.arctan2(x[1], x[0])) <= np.pi - margins.wrap
        and np.arctan2(rho, x[2] - SHOULDER[2]) <= np.pi - margins.wrap
    )


#: The most configurations :func:`draw_configuration` draws before it gives up (one is kept
#: within a few draws: a thousand fail only where the functions it uses were replaced).
DRAW_TRIES = 1000


def draw_configuration(rng: np.random.Generator, elbow_up: bool = True, margins: Margins = MARGINS) -> np.ndarray:
    """A seeded joint configuration on the asked elbow branch whose tip keeps the margins.

    Its pan angle is the tip's azimuth and its angles lie away from ±π, so it is *the* solution
    the Problem's IK formula gives for its own tip (whatever range a student wraps angles to).
    """
    model = arm_model()
    for _ in range(DRAW_TRIES):
        theta = rng.uniform(0.25, np.pi - 0.25)  # elbow angle: q3 = theta - pi/2 (elbow up) or its mirror
        q3 = theta - np.pi / 2 if elbow_up else -theta - np.pi / 2
        q = np.array(
            [rng.uniform(-np.pi + margins.wrap, np.pi - margins.wrap), rng.uniform(-1.2, np.pi - margins.wrap), q3]
        )
        x = tip(model, q)
        forward = x[:2] @ np.array([np.cos(q[0]), np.sin(q[0])]) > 0  # tip in front: azimuth = q1
        if forward and safe_point(x, margins) and (elbow_height(model, q) > 0) == elbow_up:
            return q
    raise RuntimeError(
        f"the check drew {DRAW_TRIES:,} configurations and kept none: the NumPy or MuJoCo functions it "
        "uses no longer give their usual results. Has a cell replaced one (np.linalg.norm = ..., say)? "
        "Restart the kernel, run the cells again without that change, then run the check."
    )


def wrap_angle(angle):
    r"""An angle (or an array of them) wrapped into :math:`(-\pi, \pi]` [rad]."""
    return np.pi - (np.pi - angle) % (2 * np.pi)


def has_unwrapped_angle(q) -> bool:
    r"""Whether some angle of ``q`` lies beyond :math:`\pm\pi` (by more than a micro-radian,
    so that rounding at the boundary does not count), where :func:`wrap_angle` would move it by
    a full turn."""
    return bool(np.abs(q).max() > np.pi + 1e-6)


def over_the_top(q) -> np.ndarray:
    r"""The same tip reached with the pan half a turn round: :math:`q_1 \to q_1 + \pi`,
    :math:`q_2 \to -q_2`, :math:`q_3 \to -q_3 - \pi` (angles wrapped into :math:`(-\pi, \pi]`).
    The arm leans back over its shoulder, its elbow on the same side of the shoulder–tip line;
    it is not the Problem's solution, whose pan angle is the tip's azimuth."""
    return wrap_angle(np.array([q[0] + np.pi, -q[1], -q[2] - np.pi]))


def pan_error(q, x) -> float:
    r"""How far the pan angle ``q[0]`` is from the azimuth ``atan2(y, x)`` of the point ``x``, in
    :math:`[0, \pi]` rad (full turns ignored)."""
    return abs(wrap_angle(q[0] - np.arctan2(x[1], x[0])))


def pan_turned_round(q, x) -> bool:
    """Whether the pan angle ``q[0]`` points the arm's plane away from the target ``x`` (its
    azimuth plus about half a turn) instead of at it: the over-the-top solution."""
    return pan_error(q, x) > np.pi / 2


def mirror_elbow(q) -> np.ndarray:
    r"""The other elbow branch with the same tip: :math:`\theta = q_3 + \pi/2 \to -\theta`,
    :math:`q_2 \to q_2 + \theta` (reflection of the elbow across the shoulder–tip line)."""
    theta = q[2] + np.pi / 2
    return np.array([q[0], q[1] + theta, -theta - np.pi / 2])


@dataclass(frozen=True)
class Terms:
    """MuJoCo's quantities at one state of the 3R arm: :math:`M`, :math:`h`, the tip's
    translational Jacobian :math:`J` (3×3), :math:`\\dot J\\dot q` (3,) and position :math:`x`."""

    M: np.ndarray
    h: np.ndarray
    J: np.ndarray
    jdq: np.ndarray
    x: np.ndarray


def terms(model: mujoco.MjModel, q, qdot, t: float = 0.0) -> Terms:
    """:class:`Terms` at a state, from a scratch ``MjData``."""
    data = data_at(model, q, qdot, t)
    return Terms(
        mass_matrix(model, data),
        bias_forces(data),
        site_jacobian(model, data, SITE)[:3].copy(),
        site_jdot_qdot(model, data, SITE)[:3].copy(),
        data.site(SITE).xpos.copy(),
    )


def gravity(model: mujoco.MjModel, q) -> np.ndarray:
    """:math:`g(q) = h(q, 0)`: the bias forces at rest, gravity alone."""
    return terms(model, q, np.zeros(len(q))).h


#: What a law that inverts the mass matrix where it should multiply by it is told.
INVERSE_MASS = (
    "the law multiplies by M(q)⁻¹ where it should multiply by M(q): np.linalg.solve(M, v) is M⁻¹v, M @ v is M v."
)


@dataclass(frozen=True)
class Mistake:
    """A typical wrong answer: the value it gives, what it means, and the score it keeps."""

    value: np.ndarray
    text: str
    score: float


@dataclass(frozen=True)
class Verdict:
    """How a torque compares with the formula at one state."""

    score: float
    text: str  # empty when exact
    jdot_error: float | None = None  # relative error of the implied J̇q̇, where it applies


def close(a, b, rtol: float = TORQUE_RTOL) -> bool:
    """Equal within floating-point error (:data:`TORQUE_ATOL`, and ``rtol``, by default
    :data:`TORQUE_RTOL`)."""
    return bool(np.allclose(a, b, atol=TORQUE_ATOL, rtol=rtol))


def judge_torque(
    got: np.ndarray,
    expected: np.ndarray,
    mistakes: dict[str, Mistake],
    implied_jdq: Callable[[np.ndarray], np.ndarray] | None = None,
    jdq: np.ndarray | None = None,
    rtol: float = TORQUE_RTOL,
) -> Verdict:
    r"""Judge a student's torque against the formula's at one state.

    1. Equal within floating-point error (relative ``rtol``): right (``inv`` instead of
       ``solve`` lands here). At a still case (:attr:`Case.still`) the checks pass
       :data:`STILL_RTOL` and no ``implied_jdq``: steps 2 and 4 do not apply there.
    2. Where the law holds :math:`\dot J\dot q`: ``implied_jdq(got)`` is the :math:`\dot J\dot q`
       the student's torque implies if everything else is exact. Within :data:`JDOT_APPROX` of
       MuJoCo's ``jdq``: right (a finite-difference :math:`\dot J\dot q`, or a numerical IK, lands
       here).
    3. One of the named ``mistakes`` reproduces it: that mistake's score and explanation.
    4. The implied :math:`\dot J\dot q` is closer to MuJoCo's than zero is (relative error
       :math:`\varepsilon < 1`): half credit, as for leaving the term out. One state cannot tell
       a poor approximation of :math:`\dot J\dot q` from an error in another velocity term (the
       Coriolis part of :math:`h`, a reference velocity from the wrong Jacobian): any torque error
       maps onto some :math:`\dot J\dot q`. A score growing as :math:`\varepsilon` shrinks
       would vary with the seed and could give two mistakes more than one; the message names
       both readings.
    5. Otherwise: zero, with both values printed to as many digits as tell them apart.
    """
    if close(got, expected, rtol):
        return Verdict(1.0, "")
    eps = None
    if implied_jdq is not None and jdq is not None and np.linalg.norm(jdq) > 0:
        eps = float(np.linalg.norm(implied_jdq(got) - jdq) / np.linalg.norm(jdq))
        if eps <= JDOT_APPROX:
            return Verdict(1.0, "", eps)
    for m in mistakes.values():
        if close(got, m.value) and not close(m.value, expected):
            return Verdict(m.score, m.text, eps)
    if eps is not None and eps < 1.0:
        with np.printoptions(precision=4, suppress=True):
            text = (
                f"your torque differs from the formula's as a different J̇q̇ would make it: it implies "
                f"J̇q̇ ≈ {implied_jdq(got)}, MuJoCo's is {jdq} (off by {100 * eps:.2g} %). An approximation "
                f"of J̇q̇ within {100 * JDOT_APPROX:g} % gets full marks; if yours is exact, look at the other "
                "terms that depend on the velocities (the Coriolis part of h, the reference's velocity)"
            )
        return Verdict(0.5, text, eps)
    return Verdict(0.0, show_pair(got, expected), eps)


def _power_of_ten(x: float) -> str:
    """``1e-06`` as ``1e-6``."""
    return f"{x:.0e}".replace("e-0", "e-")


def formula_scoring(with_jdot: bool) -> str:
    """How :func:`judge_torque` scores a law, in words, for the grading rubric."""
    text = (
        "The torque is compared with the formula (with MuJoCo's M, h"
        + (", J and J̇q̇" if with_jdot else "")
        + ") at drawn test states, and the first state where it differs decides. Equal to it within "
        f"{_power_of_ten(TORQUE_RTOL)} (relative) or {_power_of_ten(TORQUE_ATOL)} N·m: full credit "
        "(inv in place of solve lands here)"
    )
    if with_jdot:
        text += (
            f"; so is a torque whose implied J̇q̇ is within {100 * JDOT_APPROX:g} % of MuJoCo's (finite "
            "differences, a numerical IK), and, at a test state where the arm or the reference is "
            f"momentarily at rest (J̇q̇ zero), one within {_power_of_ten(STILL_RTOL)} (relative)"
        )
    text += ". A torque one of the named mistakes below reproduces keeps that mistake's credit"
    if with_jdot:
        text += (
            "; a torque that another J̇q̇, off by more (relative error ε < 1), would explain keeps half: "
            "a poor approximation, or an error in another velocity term, as one state cannot tell them apart"
        )
    return text + ". Anything else scores 0."


def own_gains_mistake(value: np.ndarray, Kp: float, Kd: float) -> Mistake:
    """The torque of the right law with the notebook's own gains ``Kp``, ``Kd`` (globals, say)
    in place of the ones the check passes."""
    return Mistake(
        value,
        f"the formula is right, but with the notebook's gains (Kp = {Kp:g}, Kd = {Kd:g}) in place of the Kp "
        "and Kd passed to the function: the checks pass others, so use the arguments.",
        0.5,
    )


def own_reference_mistake(value: np.ndarray, arguments: str) -> Mistake:
    """The torque of the right law on the notebook's own reference (its ``reference(t)`` at the
    state's time) in place of the ``arguments`` the check passes."""
    return Mistake(
        value,
        f"the formula is right, but with the notebook's reference, reference(data.time), in place of the "
        f"{arguments} passed to the function: the checks and the grader pass others, so use the arguments.",
        0.5,
    )


def swapped_gains_mistake(value: np.ndarray, position: str = "q_d − q", velocity: str = "q̇") -> Mistake:
    """The torque of the right law with ``Kp`` and ``Kd`` exchanged (parameters taken in the other
    order, say); ``position`` and ``velocity`` are the terms they multiply, in the law's words."""
    return Mistake(
        value,
        f"the formula is right, but Kp and Kd are swapped: Kp multiplies the position error {position}, Kd the "
        f"velocity term {velocity} (check the order of the parameters in the def line, and of the arguments in "
        "the call)",
        0.5,
    )


def argument_order_mistakes(formula: Callable, args: tuple, names: tuple[str, ...]) -> dict[str, Mistake]:
    """The torques of the right ``formula(*args)`` written with a def line that takes its
    arguments after ``model, data`` in another order than the stub's ``names``: the checks pass
    them in the stub's order, so each lands on another parameter. An order that only exchanges
    Kp and Kd is :func:`swapped_gains_mistake`'s. Where two orders give the same torque at the
    state (at rest, Kd and the desired velocity commute), the text names neither."""
    n, stub = len(names), ", ".join(names)
    swapped = (*range(n - 2), n - 1, n - 2)  # ..., Kd, Kp
    torques = {}
    for order in itertools.permutations(range(n)):  # names[k] sits at place order[k] of the def line
        if order in (tuple(range(n)), swapped):
            continue
        try:
            with np.errstate(all="ignore"):
                value = np.asarray(formula(*(args[order[k]] for k in range(n))), dtype=float)
        except (TypeError, ValueError, np.linalg.LinAlgError):
            continue
        if value.shape == (3,) and np.isfinite(value).all():
            torques[order] = value
    found = {}
    for order, value in torques.items():
        def_line = ", ".join(names[k] for k in sorted(range(n), key=lambda k: order[k]))
        alike = sum(close(value, other) for other in torques.values()) > 1
        which = (
            "in another order than the stub's"
            if alike
            else f"in the order (model, data, {def_line}), where the stub has"
        )
        found[f"order_{''.join(map(str, order))}"] = Mistake(
            value,
            f"the formula is right, but your def line takes the arguments {which} (model, data, {stub}): "
            "the checks and the runs pass them in the stub's order, so each lands on another parameter; keep "
            "the stub's def line",
            0.5,
        )
    return found


def degrees_mistake(value_in_radians: np.ndarray, text: str = "", score: float = 0.25) -> Mistake:
    """The torque of a law computed with angles in degrees (180/π times the angle terms)."""
    return Mistake(
        value_in_radians,
        text
        or (
            "your torque is 180/π ≈ 57.3 times the formula's feedback: "
            "the angles were converted to degrees; MuJoCo works in radians"
        ),
        score,
    )


# ---------------------------------------------------------------------------------------------
# test states
# ---------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class Case:
    """One test of a tracking law: the states leading up to the tested one, and the reference.

    Attributes:
        states: :data:`LEAD_IN` + 1 consecutive states, one control step apart (the last is tested).
        still: the arm (or the reference) is at rest at the tested state, so the law's
            :math:`\\dot J\\dot q` term is exactly zero there.
        q_d, qd_d, qdd_d: joint reference at each of those instants, shape (n, 3).
        x_d, xd_d, xdd_d: its Cartesian image ``FK(q_d)``, :math:`J\\dot q_d`,
            :math:`J\\ddot q_d + \\dot J\\dot q_d`, shape (n, 3).
        Kp, Kd: gains.
    """

    states: tuple[State, ...]
    q_d: np.ndarray
    qd_d: np.ndarray
    qdd_d: np.ndarray
    x_d: np.ndarray
    xd_d: np.ndarray
    xdd_d: np.ndarray
    Kp: float
    Kd: float
    still: bool = False


def cartesian_reference(model: mujoco.MjModel, q_d, qd_d, qdd_d):
    r"""The Cartesian image of a joint reference: :math:`x_d = \mathrm{FK}(q_d)`,
    :math:`\dot x_d = J\dot q_d`, :math:`\ddot x_d = J\ddot q_d + \dot J\dot q_d` (no IK needed)."""
    T = terms(model, q_d, qd_d)
    return T.x, T.J @ qd_d, T.J @ qdd_d + T.jdq


def tracking_cases(
    seed: int, check: str, n: int = 4, gains=((30.0, 90.0), (8.0, 20.0)), still: str | None = None
) -> list[Case]:
    r"""``n`` seeded tests of a tracking law near an elbow-up joint reference.

    Each reference is a smooth joint motion :math:`q_d(t)` (quadratic in time) around a drawn
    configuration; the arm's state is the reference plus a small offset that also moves
    smoothly, so consecutive states are what a simulation would hand the controller.

    With ``still`` (``"arm"`` or ``"reference"``) one more case comes first, drawn from a stream
    of its own (the other ``n`` stay as they are): the arm, or the reference, is at rest at the
    tested state, so a law's :math:`\dot J\dot q` term vanishes there, whether computed by
    MuJoCo or by finite differences. The arm at rest for a :math:`\dot J(q,\dot q)\dot q`
    taken at the arm's state (operational-space CT); the reference at rest for one taken at the
    reference (IK + joint CT), the arm still moving so that the whole of :math:`h(q,\dot q)` counts.
    """
    model = arm_model()
    cases = [] if still is None else [_tracking_case(model, rng_for(seed, f"{check}:still"), gains, still)]
    rng = rng_for(seed, check)
    return cases + [_tracking_case(model, rng, gains) for _ in range(n)]


def _tracking_case(model: mujoco.MjModel, rng: np.random.Generator, gains, still: str | None = None) -> Case:
    """One case of :func:`tracking_cases`, drawn from ``rng``."""
    if still not in (None, "arm", "reference"):
        raise ValueError(f"still must be None, 'arm' or 'reference', got {still!r}")
    dt = model.opt.timestep
    q_star = draw_configuration(rng, elbow_up=True)
    v, a = rng.uniform(-1.5, 1.5, 3), rng.uniform(-3.0, 3.0, 3)
    dq, dv = rng.uniform(-0.05, 0.05, 3), rng.uniform(-0.3, 0.3, 3)
    t_star = float(rng.uniform(0.5, 5.0))
    if still == "reference":  # turning round at the tested instant: q̇_d = 0 there, q̈_d = a
        v = np.zeros(3)
    s = dt * np.arange(-LEAD_IN, 1)
    q_d = q_star + np.outer(s, v) + 0.5 * np.outer(s**2, a)
    qd_d = v + np.outer(s, a)
    qdd_d = np.tile(a, (len(s), 1))
    refs = np.array([np.concatenate(cartesian_reference(model, *k)) for k in zip(q_d, qd_d, qdd_d, strict=True)])
    if still == "arm":  # held still, off the reference
        states = tuple(State(q_d[-1] + dq, np.zeros(3), t_star + float(s[k])) for k in range(len(s)))
    else:
        states = tuple(State(q_d[k] + dq + s[k] * dv, qd_d[k] + dv, t_star + float(s[k])) for k in range(len(s)))
    Kp, Kd = float(rng.uniform(*gains[0])), float(rng.uniform(*gains[1]))
    return Case(states, q_d, qd_d, qdd_d, refs[:, :3], refs[:, 3:6], refs[:, 6:], Kp, Kd, still is not None)


def none_here_only(probe: Probe, fname: str, err: StudentError, elsewhere: tuple) -> StudentError:
    """``err`` as a formula check reports it. A None (:class:`NotImplementedYet`) is "not
    implemented yet" only where ``fname`` returns None for ``elsewhere`` too (another test
    state's arguments, the state first); where it returns a value there, the function has a path
    that returns nothing, and is told so."""
    if not isinstance(err, NotImplementedYet):
        return err
    try:
        if probe.call(fname, *elsewhere) is None:
            return err
    except StudentError:
        return err
    return StudentError(
        f"{fname} returned None at one test state and a value at another: a path through the function that "
        "ends without a return statement (an if without an else, say) returns None"
    )


def call_along(probe: Probe, fname: str, case: Case, args_at: Callable[[int], tuple]) -> np.ndarray:
    """Call the student's ``fname`` at each state of ``case`` in order (arguments ``args_at(k)``
    after the state) and return the torque of the last, the tested one."""
    for k, state in enumerate(case.states):
        tau = as_vector(fname, probe.call(fname, state, *args_at(k)), 3, "torque")
    return tau


# ---------------------------------------------------------------------------------------------
# runs
# ---------------------------------------------------------------------------------------------


def student_controller(probe: Probe, fname: str, args, trace: Trace | None = None) -> Callable:
    """A controller ``(model, data) -> tau`` that asks the probe for the student's torque each step.

    ``args`` are the function's arguments after ``(model, data)``: a tuple, or a function of
    the time returning the tuple (for a moving reference). ``trace`` records the states.
    """

    def controller(model, data):
        if trace is not None:
            trace.record(data)
        extra = args(float(data.time)) if callable(args) else args
        value = probe.call(fname, State(data.qpos.copy(), data.qvel.copy(), float(data.time)), *extra)
        return as_vector(fname, value, model.nu, "torque")

    return controller


#: Why a run diverged when no stiff damping explains it.
RAN_AWAY = "the arm ran away; check the signs of the feedback terms"


def run_student(probe: Probe, fname: str, args, duration: float, q0, qdot0=None, reference=None) -> Log:
    """Simulate the 3R arm (the grader's own model and loop) under the student's controller.

    Raises:
        StudentError: if the controller fails or the simulation diverges; the message says why in
            plain words (for a too stiff damping, with the numbers and the remedies).
    """
    model = arm_model()
    data = mujoco.MjData(model)
    trace = Trace()
    controller = student_controller(probe, fname, args, trace)
    try:
        return simulate(model, data, controller, duration, q0=q0, qdot0=qdot0, site=SITE, reference=reference)
    except SimulationDiverged as err:
        reason = explain_divergence(model, student_controller(probe, fname, args), trace, err.t, law=fname)
        raise StudentError(
            f"with {fname}, the simulation diverged at t = {err.t:.3f} s: " + (reason or RAN_AWAY)
        ) from None
    except ValueError as err:
        raise StudentError(f"{fname}: {err}") from None
