r"""Why a simulation under a student's controller blew up, in words a student can act on.

A run can diverge for two different reasons, and the cure differs:

* the **law** is unstable (a sign error, a missing term): the continuous closed loop itself
  runs away, and no time step helps;
* the **sampling** is: the law is fine, but its damping is too stiff for the time step. A joint
  with inertia :math:`M` under damping :math:`K_d` has the velocity pole :math:`-K_d/M`. The
  loop computes the torque once per step and holds it over the step, whatever the integrator
  (RK4's four stages all see the same torque), so each step multiplies the velocity by
  :math:`1 - K_d\,\Delta t/M`: stable only while :math:`K_d\,\Delta t / M < 2`.
  Problem 1's PD at the lab's gains hits this near the folded arm, where the pan inertia falls
  to about 0.004 kg·m².

:func:`explain_divergence` tells them apart from the closed loop's damping
:math:`D = -\partial(\tau - h)/\partial\dot q` (finite differences of the student's torque) at
the states before the divergence: the fastest velocity pole is the largest eigenvalue of
:math:`M^{-1}D`. The shape of :math:`D` says which words fit: the same :math:`K_d` on every
joint (PD), :math:`M K_d` (computed torque), or a law that inverts :math:`M` where it should
multiply by it, which no time step cures.
"""

from __future__ import annotations

import inspect
from collections.abc import Callable

import mujoco
import numpy as np

from labsupport.dynamics import mass_matrix

#: Largest :math:`\lambda\Delta t` for which a damping applied by the controller stays stable: a
#: torque computed from :math:`\dot q_k` and held over the step gives
#: :math:`\dot q_{k+1} = (1 - \lambda\Delta t)\,\dot q_k`, whatever the integrator (an implicit one
#: treats only the model's own damping implicitly, not the controller's).
STABILITY_LIMIT = 2.0
_JOINT_NAMES = ("pan joint 1", "joint 2", "joint 3")


def effective_damping(
    model: mujoco.MjModel, torque: Callable, q, qdot, t: float = 0.0, step: float = 1e-4
) -> tuple[np.ndarray, np.ndarray]:
    r"""The closed loop's damping :math:`D = -\partial(\tau - h)/\partial\dot q` (central
    differences) and :math:`M(q)` at a state.

    The arm obeys :math:`M\ddot q = \tau - h(q,\dot q)`, so what decides how fast the joint
    velocities decay is the controller's torque less the bias forces: a computed torque's
    :math:`+h` cancels the arm's own, and its damping is :math:`M K_d` at any speed, while
    :math:`-\partial\tau/\partial\dot q` alone would count the Coriolis forces of a fast motion
    as damping.

    Args:
        torque: ``torque(model, data) -> tau``, the controller.
    """
    data = mujoco.MjData(model)
    data.qpos[:], data.time = q, t
    nv = model.nv
    D = np.empty((nv, nv))
    for j in range(nv):
        pulls = []
        for sign in (1.0, -1.0):
            data.qvel[:] = qdot
            data.qvel[j] += sign * step
            mujoco.mj_forward(model, data)
            tau = np.asarray(torque(model, data), dtype=float)
            pulls.append(tau - data.qfrc_bias + data.qfrc_passive)
        D[:, j] = -(pulls[0] - pulls[1]) / (2 * step)
    data.qvel[:] = qdot
    mujoco.mj_forward(model, data)
    return D, mass_matrix(model, data)


def fastest_velocity_pole(D: np.ndarray, M: np.ndarray) -> float:
    r"""The largest real part of the eigenvalues of :math:`M^{-1}D`: the rate [1/s] at which the
    fastest combination of joint velocities decays under the damping :math:`D`."""
    return float(np.max(np.real(np.linalg.eigvals(np.linalg.solve(M, D)))))


def multiple_of(X: np.ndarray, B: np.ndarray, rtol: float = 0.05) -> float | None:
    r"""The number :math:`c` with :math:`X = c\,B` within ``rtol`` (in the Frobenius norm), or None."""
    c = float(np.sum(X * B) / np.sum(B * B))
    return c if np.linalg.norm(X - c * B) <= rtol * np.linalg.norm(X) else None


class Trace:
    """The states a controller was called at during a run (kept to explain a divergence)."""

    def __init__(self):
        self.states: list[tuple[np.ndarray, np.ndarray, float]] = []

    def record(self, data: mujoco.MjData) -> None:
        if self.states and data.time < self.states[-1][2]:
            self.states.clear()  # a new run started
        self.states.append((data.qpos.copy(), data.qvel.copy(), float(data.time)))


#: What to do about a damping that is right but too stiff for the time step.
_REMEDIES = (
    "clipping or saturating the torque, or implicit damping (MuJoCo's joint damping with the implicitfast integrator)."
)


def is_computed_torque(name: str | None) -> bool:
    """Whether a law's name says it is a computed torque (``ct_joint_torque``, ``ct_op_torque``,
    ``ct_ik_joint_torque``: the Problems' TODO names hold ``ct`` as a word)."""
    return isinstance(name, str) and "ct" in name.lower().split("_")


def stiff_damping(
    model: mujoco.MjModel,
    torque: Callable,
    q,
    qdot,
    t: float = 0.0,
    computed_torque: bool = False,
    gains: tuple[float, float] | None = None,
) -> str | None:
    r"""If the controller's damping at this state is too stiff for the time step, say so with the
    numbers and what to do; ``None`` if it is not.

    The verdict is the fastest velocity pole :math:`\lambda` (:func:`fastest_velocity_pole`):
    too stiff when :math:`\lambda\Delta t` exceeds :data:`STABILITY_LIMIT`. The words depend on the
    damping's shape, found from :math:`D` itself: the same :math:`K_d` on every joint (PD: too
    stiff where a joint's inertia is small), :math:`M K_d` (computed torque: :math:`K_d` itself
    too large) or :math:`M^{-1}K_d` (the mass matrix inverted where it should multiply). A
    damping of none of these shapes gets ``None``: at the fast states of a run away (a sign
    error) the terms of an operational-space law that change with the speed look like a huge
    damping whatever the law. Every number printed is the one the verdict was drawn from.

    Args:
        torque: the controller, ``torque(model, data) -> tau``.
        computed_torque: the law is meant to be a computed torque: a damping of PD's shape then
            means the feedback is not multiplied by :math:`M(q)`, which the words say instead of
            blaming the time step (computed torque's own damping :math:`M K_d` decays at
            :math:`K_d`, far inside the limit at the Problems' gains).
        gains: the ``(Kp, Kd)`` the law was handed (:func:`handed_gains`), if known: a PD whose
            damping is its Kp instead has the two swapped, which the words then say.
    """
    limit = STABILITY_LIMIT
    if not (np.all(np.isfinite(q)) and np.all(np.isfinite(qdot))):
        return None  # nothing to judge on a bad state
    try:
        D, M = effective_damping(model, torque, q, qdot, t)
    except Exception:  # the student's controller may fail on the probing states
        return None
    if not np.all(np.isfinite(D)):
        return None
    dt = model.opt.timestep
    rate = fastest_velocity_pole(D, M)
    if rate * dt <= limit:
        return None
    above = f"above {limit:g}, the most that a torque held over each time step can damp"
    when = f"From t = {t:.3f} s on"
    eye = np.eye(model.nv)
    kd = multiple_of(D, eye)
    if kd is not None:  # PD: the same damping on every joint, whatever its inertia
        ratios = kd * dt / np.diag(M)
        j = int(np.argmax(ratios))
        if ratios[j] > limit:
            inertia = float(M[j, j])
            name = _JOINT_NAMES[j] if j < len(_JOINT_NAMES) else f"joint {j + 1}"
            if computed_torque:
                return (
                    f"{when}, your computed-torque law damps as PD does, with the same Kd = {kd:.3g} on every "
                    f"joint: its feedback is not multiplied by M(q). Where the {name}'s inertia is small "
                    f"(M = {inertia:.4g} kg·m²), Kd·Δt/M = {ratios[j]:.3g} is {above}. Computed torque's damping is "
                    f"M(q)·Kd, which makes every joint's velocity decay at Kd = {kd:.3g} 1/s whatever its inertia "
                    f"(Kd·Δt = {kd * dt:.3g}): multiply the whole feedback, Kp e + Kd ė (plus q̈_d), by M(q), "
                    "then add h. A smaller time step would only hide the missing M."
                )
            if gains is not None and np.isclose(kd, gains[0], rtol=0.05) and not np.isclose(*gains, rtol=0.05):
                return (
                    f"{when}, the closed loop damps with {kd:.3g} N·m·s/rad on every joint: the Kp = {gains[0]:g} "
                    f"the law was handed, not its Kd = {gains[1]:g}. Kp and Kd look swapped in the law: Kp "
                    f"multiplies the position error q_d − q, Kd the velocity q̇. With the swap, Kd·Δt/M = "
                    f"{ratios[j]:.3g} at {name} (M = {inertia:.4g} kg·m²) is {above}."
                )
            return (
                f"the damping is too stiff for the time step. {when}, the {name} has inertia "
                f"M = {inertia:.4g} kg·m² and the damping of the closed loop is Kd = {kd:.3g} N·m·s/rad on "
                "every joint (your gain, give or take what the arm's own velocity terms add at this speed), "
                f"so Kd·Δt/M = {kd:.3g} × {dt:g} / {inertia:.4g} = {ratios[j]:.3g}, {above} (the controller "
                "reads the speed once per step and holds its torque, so each step reverses the joint's speed and "
                "makes it larger; the continuous law would settle). Remedies: a smaller time "
                f"step (Δt < {limit * inertia / kd:.2g} s here), a lower Kd (below {limit * inertia / dt:.3g} "
                f"N·m·s/rad for this joint), " + _REMEDIES
            )
    pole = f"the fastest joint velocities decay at λ = {rate:.4g} 1/s, and λ·Δt = {rate * dt:.3g} is {above}"
    kd = multiple_of(np.linalg.solve(M, D), eye)
    if kd is not None:  # computed torque: M Kd, the rate Kd itself
        return (
            f"the damping is too stiff for the time step. {when}, your law damps as computed torque does, "
            f"M(q)·Kd with Kd = {kd:.4g} 1/s: {pole}. Lower Kd below {limit / dt:.3g} 1/s, or take a smaller "
            f"time step (Δt < {limit / rate:.2g} s)."
        )
    kd = multiple_of(M @ D, eye)
    if kd is not None:  # M⁻¹ Kd: the mass matrix inverted
        return (
            f"{when}, your law's damping is M(q)⁻¹·Kd with Kd = {kd:.4g}, where computed torque's is M(q)·Kd: "
            "the law divides by the mass matrix where it should multiply by it (np.linalg.solve(M, v) is "
            f"M⁻¹v; M @ v is M v). Where the arm's inertia is small, M⁻¹ is large: {pole}. Fix the law: "
            "a smaller time step would only hide the mistake."
        )
    # None of the three: far from a set-point a law's damping also holds the change of J⁻¹ and
    # J̇q̇ with the speeds, which a run away makes large whatever the law; no time step to blame.
    return None


def explain_divergence(
    model: mujoco.MjModel,
    torque: Callable,
    trace: Trace,
    until: float,
    samples: int = 40,
    law: str | None = None,
    gains: tuple[float, float] | None = None,
) -> str | None:
    """Why a run that diverged at ``until`` [s] did: the stiff-damping explanation
    (:func:`stiff_damping`) at the earliest recorded state where it applies (up to ``samples``
    states checked, evenly spread over the run up to ``until``), or ``None`` if the time step is
    not the cause.

    States after ``until`` are left out: the loop runs on after a run away and checks the speeds
    when it ends, so the trace may hold states turning at thousands of rad/s, where the bias
    forces' dependence on the velocity alone looks like a huge damping, and a law that is itself
    unstable (a sign error) would be told it is not. ``law`` is the law's name, which says
    whether it is meant as a computed torque (:func:`is_computed_torque`); ``gains`` those it was
    handed, if known (:func:`stiff_damping`)."""
    states = [s for s in trace.states if s[2] <= until]
    if not states:
        return None
    for k in np.unique(np.linspace(0, len(states) - 1, min(samples, len(states))).astype(int)):
        q, qdot, t = states[k]
        reason = stiff_damping(model, torque, q, qdot, t, computed_torque=is_computed_torque(law), gains=gains)
        if reason is not None:
            return reason
    return None


def handed_gains(law: Callable, args: tuple) -> tuple[float, float] | None:
    """The ``(Kp, Kd)`` a law was handed in ``args`` (its arguments after ``data``), found by its
    parameters' names (``Kp`` and ``Kd``, in any case); ``None`` where it has no such two, or
    they were not handed numbers."""
    try:
        names = [name.lower() for name in list(inspect.signature(law).parameters)[2:]]
        return float(args[names.index("kp")]), float(args[names.index("kd")])
    except (TypeError, ValueError, IndexError):  # a builtin, no such names, or not numbers
        return None


def target_in_degrees(law: Callable, args: tuple) -> str | None:
    r"""Why a run away may have started before the law did anything wrong: the joint target it
    was handed looks like degrees. That is the law's first argument after ``data``, when its
    name says it holds joint angles (``q_d``, ``q_target``: it begins with ``q``), and one of
    its angles lies beyond :math:`2\pi`. ``None`` otherwise (a Cartesian target, a target
    that is a function of time, or angles that fit radians)."""
    try:
        names = list(inspect.signature(law).parameters)
    except (TypeError, ValueError):  # a builtin, say: no names to read
        return None
    if len(names) < 3 or not names[2].lower().startswith("q") or not args:
        return None
    try:
        target = np.asarray(args[0], dtype=float)
    except (TypeError, ValueError):
        return None
    if target.ndim != 1 or not np.isfinite(target).all() or np.abs(target).max() <= 2 * np.pi:
        return None
    return (
        f"the target it was handed, {names[2]} = [{', '.join(f'{v:.1f}' for v in target)}], has angles beyond "
        "2π: are they in degrees? MuJoCo's angles are in radians: convert them with np.radians, or, if ik_3r "
        "returned them, make it return radians (TODO 1)"
    )
