r"""Why a simulation under a student's controller blew up, in words a student can act on.

A run can diverge for two different reasons, and the cure differs:

* the **law** is unstable (a sign error, a missing term): the continuous closed loop itself
  runs away, and no time step helps;
* the **discretisation** is: the law is fine, but its damping is too stiff for an explicit
  integrator at this time step. A joint with inertia :math:`M` under damping :math:`K_d` has the
  velocity pole :math:`-K_d/M`; an explicit method is stable only while
  :math:`K_d\,\Delta t / M` stays below a limit (2 for explicit Euler, about 2.785 for RK4).
  Problem 1's PD at the lab's gains hits this near the folded arm, where the pan inertia falls
  to about 0.004 kg·m².

:func:`explain_divergence` tells them apart from the controller's own effective damping
:math:`D = -\partial\tau/\partial\dot q` (finite differences of the student's torque) at the
last good state: the fastest velocity pole is the largest eigenvalue of :math:`M^{-1}D`.
"""

from __future__ import annotations

from collections.abc import Callable

import mujoco
import numpy as np

from labsupport.dynamics import mass_matrix

#: Largest :math:`\lambda\Delta t` for which each explicit integrator damps :math:`\dot x = -\lambda x`.
STABILITY_LIMIT = {
    int(mujoco.mjtIntegrator.mjINT_EULER): 2.0,
    int(mujoco.mjtIntegrator.mjINT_RK4): 2.785,
}
_INTEGRATOR_NAME = {int(mujoco.mjtIntegrator.mjINT_EULER): "explicit Euler", int(mujoco.mjtIntegrator.mjINT_RK4): "RK4"}
_JOINT_NAMES = ("pan joint 1", "joint 2", "joint 3")


def effective_damping(
    model: mujoco.MjModel, torque: Callable, q, qdot, t: float = 0.0, step: float = 1e-4
) -> tuple[np.ndarray, np.ndarray]:
    r"""The controller's damping :math:`D = -\partial\tau/\partial\dot q` (central differences) and
    :math:`M(q)` at a state.

    Args:
        torque: ``torque(model, data) -> tau``, the controller.
    """
    data = mujoco.MjData(model)
    data.qpos[:], data.time = q, t
    nv = model.nv
    D = np.empty((nv, nv))
    for j in range(nv):
        taus = []
        for sign in (1.0, -1.0):
            data.qvel[:] = qdot
            data.qvel[j] += sign * step
            mujoco.mj_forward(model, data)
            taus.append(np.asarray(torque(model, data), dtype=float).copy())
        D[:, j] = -(taus[0] - taus[1]) / (2 * step)
    data.qvel[:] = qdot
    mujoco.mj_forward(model, data)
    return D, mass_matrix(model, data)


class Trace:
    """The states a controller was called at during a run (kept to explain a divergence)."""

    def __init__(self):
        self.states: list[tuple[np.ndarray, np.ndarray, float]] = []

    def record(self, data: mujoco.MjData) -> None:
        if self.states and data.time < self.states[-1][2]:
            self.states.clear()  # a new run started
        self.states.append((data.qpos.copy(), data.qvel.copy(), float(data.time)))


def stiff_damping(model: mujoco.MjModel, torque: Callable, q, qdot, t: float = 0.0) -> str | None:
    r"""If the controller's damping at this state is too stiff for the integrator at this time
    step, say so with the numbers and what to do; ``None`` if it is not.

    Args:
        torque: the controller, ``torque(model, data) -> tau``.
    """
    limit = STABILITY_LIMIT.get(int(model.opt.integrator))
    if limit is None or not (np.all(np.isfinite(q)) and np.all(np.isfinite(qdot))):
        return None  # implicit integrators handle stiff damping; nothing to judge on a bad state
    try:
        D, M = effective_damping(model, torque, q, qdot, t)
    except Exception:  # the student's controller may fail on the probing states
        return None
    if not np.all(np.isfinite(D)):
        return None
    dt = model.opt.timestep
    fastest = float(np.max(np.real(np.linalg.eigvals(np.linalg.solve(M, D)))))
    if fastest * dt <= limit:
        return None
    ratios = np.diag(D) * dt / np.diag(M)
    j = int(np.argmax(ratios))
    kd, inertia = float(D[j, j]), float(M[j, j])
    name = _JOINT_NAMES[j] if j < len(_JOINT_NAMES) else f"joint {j + 1}"
    integrator = _INTEGRATOR_NAME[int(model.opt.integrator)]
    return (
        f"this is not a sign error: the damping is too stiff for the time step. From t = {t:.3f} s on, the "
        f"{name} has inertia M = {inertia:.4g} kg·m² and your controller's damping there is Kd = {kd:.4g} N·m·s/rad, "
        f"so Kd·Δt/M = {kd:.4g} × {dt:g} / {inertia:.4g} = {kd * dt / inertia:.3g}, above the {limit:g} that "
        f"{integrator} can integrate (explicit discretisation of a stiff damping term). Remedies: a smaller time "
        f"step (Δt < {limit * inertia / kd:.2g} s here), a lower Kd (below {limit * inertia / dt:.3g} N·m·s/rad for "
        "this joint), clipping or saturating the torque, or implicit damping (MuJoCo's joint damping with the "
        "implicitfast integrator)."
    )


def explain_divergence(
    model: mujoco.MjModel, torque: Callable, trace: Trace, until: float, samples: int = 40
) -> str | None:
    """Why a run that diverged at ``until`` [s] did: the stiff-damping explanation
    (:func:`stiff_damping`) at the earliest recorded state where it applies (up to ``samples``
    states checked, evenly spread over the run up to ``until``), or ``None`` if the time step is
    not the cause.

    States after ``until`` are left out: the loop runs on after a run away and checks the speeds
    when it ends, so the trace may hold states turning at thousands of rad/s, where the bias
    forces' dependence on the velocity alone looks like a huge damping, and a law that is itself
    unstable (a sign error) would be told it is not."""
    states = [s for s in trace.states if s[2] <= until]
    if not states:
        return None
    for k in np.unique(np.linspace(0, len(states) - 1, min(samples, len(states))).astype(int)):
        q, qdot, t = states[k]
        reason = stiff_damping(model, torque, q, qdot, t)
        if reason is not None:
            return reason
    return None
