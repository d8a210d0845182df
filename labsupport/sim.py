r"""One loop that steps a MuJoCo model under a controller and returns a :class:`Log`.

At each step :math:`k` the controller sees the data as the previous ``mj_step`` left it,
returns a torque :math:`\tau_k` (clipped to ``torque_limit`` if given) that is held over
:math:`[t_k, t_k + \Delta t)`, and MuJoCo advances one step. Arrays are preallocated;
nothing grows inside the loop, and the loop itself does no NumPy reductions, so a lean
controller runs at a good fraction of the speed of bare ``mj_step``.

What "the data as ``mj_step`` left it" holds: ``qpos``, ``qvel`` and ``time`` are the new
state; the derived quantities (``qfrc_bias``, the mass matrix, ``site_xpos``) are those of
the integrator's last evaluation. With the RK4 integrator that evaluation is RK4's fourth
stage, within about 1e-8 of the new state; with Euler it is the state at the start of the
step. Neither loop here nor the lab's calls ``mj_forward`` in between.

Divergence (a non-finite state, or one of MuJoCo's own instability warnings, after which
MuJoCo resets the state) stops the run with :class:`SimulationDiverged`, which names the
time and the last good state.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import mujoco
import numpy as np

from labsupport.trajectories import Reference

Controller = Callable[[mujoco.MjModel, mujoco.MjData], np.ndarray]

#: MuJoCo warnings that mean the integration has gone wrong (MuJoCo resets the state or
#: zeroes the controls when it raises them).
_FATAL_WARNINGS = (mujoco.mjtWarning.mjWARN_BADQPOS, mujoco.mjtWarning.mjWARN_BADQVEL,
                   mujoco.mjtWarning.mjWARN_BADQACC, mujoco.mjtWarning.mjWARN_BADCTRL)
_W_QPOS, _W_QVEL, _W_QACC, _W_CTRL = (int(w) for w in _FATAL_WARNINGS)
_WARNING_MEANING = {
    _W_QPOS: "positions not finite or huge",
    _W_QVEL: "velocities not finite or huge",
    _W_QACC: "accelerations not finite or huge",
    _W_CTRL: "controls not finite or huge",
}


class SimulationDiverged(RuntimeError):
    """The simulation blew up; ``t``, ``qpos`` and ``qvel`` hold where and how."""

    def __init__(self, t: float, qpos: np.ndarray, qvel: np.ndarray, reason: str):
        self.t, self.qpos, self.qvel, self.reason = t, np.array(qpos), np.array(qvel), reason
        with np.printoptions(precision=4, suppress=True):
            super().__init__(
                f"simulation diverged at t = {t:.4f} s ({reason}); q = {self.qpos}, qdot = {self.qvel}. "
                "Lower the gains, clip the torque, or check the controller for a sign error.")


@dataclass(frozen=True)
class Log:
    """What one run recorded, one row per control step.

    Attributes:
        t: (N,) time at which the state was recorded [s] (the step's end with
            ``log_after_step``, its start otherwise).
        q, qdot: (N, nq), (N, nv) state at that time.
        tau: (N, nu) torque applied over the step.
        ee: (N, 3) end-effector site position, or (N, 0) without a site.
        ref: (N, d) reference position at the step's start, or (N, 0) without a reference.
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


class SampledReference:
    r"""A reference :math:`(x_d, \dot x_d, \ddot x_d)(t)` read back as one flat tuple of floats.

    On the simulation's time grid :math:`t_k = k\,\Delta t` the values come from a table
    filled in chunks by one vectorised call of ``reference`` (cheap per step: a list lookup);
    any other time calls ``reference(t)`` directly. ``at(t)`` returns
    ``(*pos, *vel, *acc)``, each of ``dim`` components.

    Args:
        reference: ``reference(t) -> Reference``, vectorised over an array of times (as all
            of :mod:`labsupport.trajectories` are).
        dt: the time step of the grid [s].
        offset: evaluate the reference at ``t + offset`` instead of ``t`` [s].
    """

    def __init__(self, reference: Callable[[float], Reference], dt: float, offset: float = 0.0,
                 chunk: int = 4096):
        if not (np.isfinite(dt) and dt > 0):
            raise ValueError(f"dt must be a positive time step, got {dt!r}")
        self._reference, self._dt, self._offset, self._chunk = reference, float(dt), float(offset), int(chunk)
        self.dim = int(np.size(reference(0.0 + self._offset).pos))
        self._table: list[tuple] = []

    def _flat(self, ref: Reference, n: int | None) -> list[tuple]:
        parts = [np.asarray(a, dtype=float).reshape(-1 if n is None else n, self.dim) for a in ref]
        return [tuple(row) for row in np.concatenate(parts, axis=1).tolist()]

    def _extend(self) -> None:
        k0 = len(self._table)
        t = (k0 + np.arange(self._chunk)) * self._dt + self._offset
        try:
            rows = self._flat(self._reference(t), self._chunk)
        except (ValueError, TypeError):  # not vectorised: one call per time
            rows = [self._flat(self._reference(float(tk)), None)[0] for tk in t]
        self._table.extend(rows)

    def at(self, t: float) -> tuple:
        """``(*pos, *vel, *acc)`` at time ``t``."""
        k = int(t / self._dt + 0.5)
        if k >= 0 and abs(t - k * self._dt) <= 1e-9 * (1.0 + abs(t)):
            while k >= len(self._table):
                self._extend()
            return self._table[k]
        return self._flat(self._reference(t + self._offset), None)[0]


def simulate(model: mujoco.MjModel, data: mujoco.MjData, controller: Controller, duration: float,
             *, q0=None, qdot0=None, site: str | None = None,
             reference: Callable[[float], Reference] | None = None,
             torque_limit=None, log_after_step: bool = False) -> Log:
    r"""Run ``controller`` on ``model`` for ``duration`` seconds from ``(q0, qdot0)``.

    Args:
        controller: ``controller(model, data) -> tau`` with ``tau`` of shape ``(nu,)``; it reads
            the time as ``data.time``. It may return the same (preallocated) array every step.
        site: name of the end-effector site to record (and to compare with ``reference``).
        reference: ``reference(t)`` giving the desired site position, recorded with the error
            (vectorised over an array of times if possible; it is evaluated after the run).
        torque_limit: scalar or ``(nu,)`` symmetric limit; torques are clipped to it.
        log_after_step: record the state *after* the step beside the reference and torque of
            the step's start, as the lab's loops do (the reference then leads the state by one
            step). The default records state, reference and torque of the same instant.

    Raises:
        SimulationDiverged: MuJoCo flagged bad positions, velocities, accelerations or controls
            (it resets the state when it does), or the state became non-finite. The error names
            the time and the last good state.
    """
    dt = model.opt.timestep
    nsteps = int(round(float(duration) / dt))
    if nsteps <= 0:
        raise ValueError(f"duration must be at least one time step ({dt} s), got {duration!r}")
    reset(model, data, q0, qdot0)
    site_id = -1
    if site is not None:
        site_id = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SITE, site)
        if site_id < 0:
            raise ValueError(f"site {site!r} is not in the model")
    dim = int(np.size(reference(0.0).pos)) if reference is not None else 0
    nu = model.nu
    limit = None if torque_limit is None else np.broadcast_to(np.asarray(torque_limit, float), (nu,)).copy()
    if limit is not None and not np.all(limit > 0):
        raise ValueError(f"torque_limit must be positive, got {torque_limit!r}")
    neg_limit = None if limit is None else -limit
    clipped = np.empty(nu)

    t_ctrl = np.empty(nsteps)                       # time of each control (the step's start)
    q, qdot = np.empty((nsteps, model.nq)), np.empty((nsteps, model.nv))
    tau_log = np.empty((nsteps, nu))
    ee = np.empty((nsteps, 3 if site_id >= 0 else 0))
    qpos, qvel, ctrl, site_xpos = data.qpos, data.qvel, data.ctrl, data.site_xpos
    warn = data.warning.number                      # live view of MuJoCo's warning counters
    q_start, qdot_start = qpos.copy(), qvel.copy()
    step = mujoco.mj_step

    for k in range(nsteps):
        tk = data.time
        tau = controller(model, data)
        if type(tau) is not np.ndarray:
            tau = np.asarray(tau, dtype=float)
        if tau.shape != (nu,):
            if tau.size != nu:
                raise ValueError(f"the controller returned a torque of shape {tau.shape}, expected ({nu},)")
            tau = tau.reshape(nu)
        if limit is not None:
            tau = np.clip(tau, neg_limit, limit, out=clipped)
        ctrl[:] = tau
        tau_log[k] = tau
        t_ctrl[k] = tk
        if not log_after_step:
            q[k] = qpos
            qdot[k] = qvel
            if site_id >= 0:
                ee[k] = site_xpos[site_id]
        step(model, data)
        if warn[_W_QPOS] or warn[_W_QVEL] or warn[_W_QACC] or warn[_W_CTRL]:
            _raise_warning(k, t_ctrl, q, qdot, tau_log, q_start, qdot_start, warn, log_after_step)
        if log_after_step:
            q[k] = qpos
            qdot[k] = qvel

    _check_finite(t_ctrl, q, qdot, dt, log_after_step)
    t = t_ctrl + dt if log_after_step else t_ctrl
    if log_after_step and site_id >= 0:
        ee = site_positions(model, q, site_id)
    if dim:
        ref = _evaluate(reference, t_ctrl, dim)
        err = ref - ee[:, :dim]
    else:
        ref = err = np.empty((nsteps, 0))
    return Log(t, q, qdot, tau_log, ee, ref, err)


def _raise_warning(k, t_ctrl, q, qdot, tau_log, q_start, qdot_start, warn, log_after_step):
    """MuJoCo flagged step ``k`` (and reset the state): report the state at the step's start."""
    if log_after_step:
        qk, qdk = (q[k - 1], qdot[k - 1]) if k else (q_start, qdot_start)
    else:
        qk, qdk = q[k], qdot[k]
    if warn[_W_CTRL]:
        with np.printoptions(precision=4):
            reason = f"the controller returned tau = {tau_log[k]}: MuJoCo's {_WARNING_MEANING[_W_CTRL]}"
    else:
        w = next(i for i in (_W_QPOS, _W_QVEL, _W_QACC) if warn[i])
        reason = (f"MuJoCo warning {mujoco.mjtWarning(w).name}: {_WARNING_MEANING[w]} during the step "
                  "from this state; MuJoCo reset the simulation")
    raise SimulationDiverged(float(t_ctrl[k]), qk, qdk, reason)


def _check_finite(t_ctrl, q, qdot, dt, log_after_step):
    bad = ~(np.isfinite(q).all(axis=1) & np.isfinite(qdot).all(axis=1))
    if bad.any():
        k = int(np.argmax(bad))
        t = t_ctrl[k] + (dt if log_after_step else 0.0)
        raise SimulationDiverged(float(t), q[k], qdot[k], "non-finite state")


def _evaluate(reference, t, dim):
    """Reference positions at the times ``t``: one vectorised call when possible."""
    try:
        pos = np.asarray(reference(t).pos, dtype=float)
        if pos.size == len(t) * dim:
            return pos.reshape(len(t), dim)
    except (ValueError, TypeError):
        pass
    return np.array([np.atleast_1d(reference(float(tk)).pos) for tk in t], dtype=float).reshape(len(t), dim)


def site_positions(model: mujoco.MjModel, q: np.ndarray, site: str | int) -> np.ndarray:
    """Positions (N, 3) of ``site`` (name or id) at the configurations ``q`` (N, nq), by forward
    kinematics on a scratch ``MjData`` (after ``mj_step`` the kinematics in ``data`` belong to
    the integrator's last evaluation, so logged positions are recomputed with this)."""
    site_id = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SITE, site) if isinstance(site, str) else int(site)
    if site_id < 0:
        raise ValueError(f"site {site!r} is not in the model")
    scratch = mujoco.MjData(model)
    out = np.empty((len(q), 3))
    for k, qk in enumerate(q):
        scratch.qpos[:] = qk
        mujoco.mj_kinematics(model, scratch)
        out[k] = scratch.site_xpos[site_id]
    return out


def from_state_torque(torque: Callable[[float, np.ndarray], float]) -> Controller:
    r"""Adapt a single-joint law ``torque(t, (theta, theta_dot))`` (as in
    :mod:`labsupport.controllers.single_joint`, written for the analytic plant) to a MuJoCo
    controller ``controller(model, data) -> tau`` of shape ``(1,)``.
    """
    tau = np.zeros(1)

    def controller(model, data):
        tau[0] = torque(data.time, np.array((data.qpos[0], data.qvel[0])))
        return tau

    return controller
