r"""One loop that steps a MuJoCo model under a controller and returns a :class:`Log`.

At each step :math:`k` the controller sees the data as the previous ``mj_step`` left it,
returns a torque :math:`\tau_k` (clipped to ``torque_limit`` if given) that is held over
:math:`[t_k, t_k + \Delta t)`, and MuJoCo advances one step. Arrays are preallocated;
nothing grows inside the loop.

Divergence (a non-finite state, or one of MuJoCo's own instability warnings) stops the run
with :class:`SimulationDiverged`, which names the time and the state.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import mujoco
import numpy as np

from labsupport.trajectories import Reference

Controller = Callable[[mujoco.MjModel, mujoco.MjData], np.ndarray]

#: MuJoCo warnings that mean the integration has gone wrong.
_FATAL_WARNINGS = (mujoco.mjtWarning.mjWARN_BADQACC, mujoco.mjtWarning.mjWARN_BADQPOS,
                   mujoco.mjtWarning.mjWARN_BADQVEL)


class SimulationDiverged(RuntimeError):
    """The simulation blew up; ``t``, ``qpos`` and ``qvel`` hold where and how."""

    def __init__(self, t: float, qpos: np.ndarray, qvel: np.ndarray, reason: str):
        self.t, self.qpos, self.qvel, self.reason = t, qpos.copy(), qvel.copy(), reason
        with np.printoptions(precision=4, suppress=True):
            super().__init__(
                f"simulation diverged at t = {t:.4f} s ({reason}); q = {qpos}, qdot = {qvel}. "
                "Lower the gains, clip the torque, or check the controller for a sign error.")


@dataclass(frozen=True)
class Log:
    """What one run recorded, one row per control step.

    Attributes:
        t: (N,) time at which the control was computed [s].
        q, qdot: (N, nq), (N, nv) state at that time.
        tau: (N, nu) torque applied over the step.
        ee: (N, 3) end-effector site position, or (N, 0) without a site.
        ref: (N, d) reference position, or (N, 0) without a reference.
        err: (N, d) ``ref - ee[:, :d]``, or (N, 0).
    """

    t: np.ndarray
    q: np.ndarray
    qdot: np.ndarray
    tau: np.ndarray
    ee: np.ndarray
    ref: np.ndarray
    err: np.ndarray


def check_state(t: float, data: mujoco.MjData) -> None:
    """Raise :class:`SimulationDiverged` if the state is not finite or MuJoCo flagged instability."""
    if not (np.all(np.isfinite(data.qpos)) and np.all(np.isfinite(data.qvel))):
        raise SimulationDiverged(t, data.qpos, data.qvel, "non-finite state")
    for w in _FATAL_WARNINGS:
        if data.warning[w].number > 0:
            raise SimulationDiverged(t, data.qpos, data.qvel, f"MuJoCo warning {mujoco.mjtWarning(w).name}")


def reset(model: mujoco.MjModel, data: mujoco.MjData, q0=None, qdot0=None) -> None:
    """Reset ``data``, set the initial state (validated) and run ``mj_forward``."""
    mujoco.mj_resetData(model, data)
    for name, value, size, dest in (("q0", q0, model.nq, data.qpos), ("qdot0", qdot0, model.nv, data.qvel)):
        if value is None:
            continue
        value = np.asarray(value, dtype=float)
        if value.shape != (size,):
            raise ValueError(f"{name} must have shape ({size},), got {value.shape}")
        if not np.all(np.isfinite(value)):
            raise ValueError(f"{name} must be finite, got {value}")
        dest[:] = value
    mujoco.mj_forward(model, data)


def simulate(model: mujoco.MjModel, data: mujoco.MjData, controller: Controller, duration: float,
             *, q0=None, qdot0=None, site: str | None = None,
             reference: Callable[[float], Reference] | None = None,
             torque_limit=None, log_after_step: bool = False) -> Log:
    r"""Run ``controller`` on ``model`` for ``duration`` seconds from ``(q0, qdot0)``.

    Args:
        controller: ``controller(model, data) -> tau`` with ``tau`` of shape ``(nu,)``; it reads
            the time as ``data.time``.
        site: name of the end-effector site to record (and to compare with ``reference``).
        reference: ``reference(t)`` giving the desired site position, recorded with the error.
        torque_limit: scalar or ``(nu,)`` symmetric limit; torques are clipped to it.
        log_after_step: record the state *after* the step beside the reference and torque of
            the step's start, as the lab's loops do (the reference then leads the state by one
            step). The default records state, reference and torque of the same instant.
    """
    nsteps = int(round(float(duration) / model.opt.timestep))
    if nsteps <= 0:
        raise ValueError(f"duration must be at least one time step ({model.opt.timestep} s), got {duration!r}")
    reset(model, data, q0, qdot0)
    site_id = -1
    if site is not None:
        site_id = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SITE, site)
        if site_id < 0:
            raise ValueError(f"site {site!r} is not in the model")
    dim = len(np.atleast_1d(reference(0.0).pos)) if reference is not None else 0
    limit = None if torque_limit is None else np.broadcast_to(np.asarray(torque_limit, float), (model.nu,))

    t = np.empty(nsteps)
    q, qdot = np.empty((nsteps, model.nq)), np.empty((nsteps, model.nv))
    tau_log = np.empty((nsteps, model.nu))
    ee = np.empty((nsteps, 3 if site_id >= 0 else 0))
    ref = np.empty((nsteps, dim))

    for k in range(nsteps):
        tk = data.time
        tau = np.asarray(controller(model, data), dtype=float)
        if tau.shape != (model.nu,):
            raise ValueError(f"the controller returned a torque of shape {tau.shape}, expected ({model.nu},)")
        if not np.all(np.isfinite(tau)):
            raise SimulationDiverged(tk, data.qpos, data.qvel, f"the controller returned tau = {tau}")
        if limit is not None:
            tau = np.clip(tau, -limit, limit)
        data.ctrl[:] = tau
        if not log_after_step:
            _record(k, tk, data, site_id, t, q, qdot, ee)
        if dim:
            ref[k] = reference(tk).pos
        tau_log[k] = tau
        mujoco.mj_step(model, data)
        check_state(data.time, data)
        if log_after_step:
            _record(k, data.time, data, site_id, t, q, qdot, ee)
    if log_after_step and site_id >= 0:
        ee = _site_positions(model, data, site_id, q)
    err = ref - ee[:, :dim] if dim else np.empty((nsteps, 0))
    return Log(t, q, qdot, tau_log, ee, ref, err)


def _record(k, tk, data, site_id, t, q, qdot, ee):
    t[k] = tk
    q[k] = data.qpos
    qdot[k] = data.qvel
    if site_id >= 0:
        ee[k] = data.site_xpos[site_id]


def _site_positions(model, data, site_id, q):
    """Site positions at the recorded configurations (after ``mj_step`` the kinematics in
    ``data`` still belong to the step's start, so they are recomputed here)."""
    scratch = mujoco.MjData(model)
    out = np.empty((len(q), 3))
    for k, qk in enumerate(q):
        scratch.qpos[:] = qk
        mujoco.mj_kinematics(model, scratch)
        out[k] = scratch.site_xpos[site_id]
    return out
