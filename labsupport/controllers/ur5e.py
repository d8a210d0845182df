r"""Operational-space control of the UR5e: the lab's law, and a tracking law that goes beyond it.

Both command a joint torque through the Menagerie's position servos
(:func:`labsupport.ur5e.servo_ctrl`). The task is the pose of the ``attachment_site``; its
error is :math:`e = (x - x_d,\; \log(R R_d^\top))`, position then rotation vector, in the world
frame, matching the rows of the site Jacobian :math:`J` (linear, then angular).

**The lab's law** (:func:`lab_osc_torque`), with :math:`\Lambda = (J M^{-1} J^\top)^{-1}`:

.. math:: \tau = J^\top \Lambda\,\big(-K_p e - K_d J\dot q\big) + h(q, \dot q)

It has no feedforward: its damping acts on the site's absolute velocity :math:`J\dot q`, not on
the velocity *error*, so on a moving target it drags behind.

**The tracking law** (:func:`osc_torque`) adds what the lab leaves out:

.. math::
    a &= \ddot x_d - K_d(J\dot q - \dot x_d) - K_p e - \dot J\dot q \\
    \tau_r &= J^\top \Lambda \big(a - J M^{-1}\tau_0\big) + \tau_0 + h \\
    \tau &= \tau_r + \Delta t\,K_v\,M^{-1}(\tau_r - h)

feedforward of the reference's velocity and acceleration, the :math:`\dot J\dot q` term, a
posture torque :math:`\tau_0` acting only in the task's null space (it vanishes for a
non-singular 6-D task and takes over near a singularity), a :math:`\Lambda` whose Cholesky
pivots are floored so that it stays bounded near singularities
(:func:`conditioned_task_solve`), and compensation of the servo damping that the integrator
treats implicitly (:func:`labsupport.ur5e.implicit_damping`).

The functions of plain arrays state the laws; :class:`LabController` and
:class:`OperationalSpaceController` evaluate the same laws in place, with no allocation per
step, for :func:`labsupport.ur5e.run` (the tests check that both give the same torque).
"""

from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np

from labsupport.dynamics import solve_mass


@dataclass(frozen=True)
class PoseGains:
    r"""Task-space PD gains, critically damped unless given: :math:`K_d = 2\sqrt{K_p}`.

    Attributes:
        kp_pos: position stiffness :math:`K_p` [1/s²] (per unit mass: :math:`\Lambda` supplies it).
        kp_ori: orientation stiffness [1/s²].
        kd_pos, kd_ori: damping [1/s]; ``None`` for :math:`2\sqrt{K_p}`.
    """

    kp_pos: float = 100.0
    kp_ori: float = 50.0
    kd_pos: float | None = None
    kd_ori: float | None = None

    def __post_init__(self):
        for name in ("kp_pos", "kp_ori", "kd_pos", "kd_ori"):
            v = getattr(self, name)
            if v is None and name.startswith("kd"):
                continue
            if not (isinstance(v, (int, float, np.floating, np.integer)) and np.isfinite(v) and v >= 0):
                raise ValueError(f"{name} must be a finite non-negative number, got {v!r}")

    @property
    def kp(self) -> np.ndarray:
        """:math:`K_p` as a (6,) diagonal: position then orientation."""
        return np.repeat([self.kp_pos, self.kp_ori], 3).astype(float)

    @property
    def kd(self) -> np.ndarray:
        """:math:`K_d` as a (6,) diagonal."""
        kd_pos = 2 * np.sqrt(self.kp_pos) if self.kd_pos is None else self.kd_pos
        kd_ori = 2 * np.sqrt(self.kp_ori) if self.kd_ori is None else self.kd_ori
        return np.repeat([kd_pos, kd_ori], 3).astype(float)


#: The lab's gains: Kp = 100 (position), 50 (orientation), Kd = 2 sqrt(Kp).
LAB_GAINS = PoseGains(100.0, 50.0)


# ---------------------------------------------------------------------------------------
# The laws, as functions of plain arrays
# ---------------------------------------------------------------------------------------

def pose_error(pos, xmat, pos_d, quat_d) -> np.ndarray:
    r"""Pose error :math:`e = (x - x_d,\ \log(R R_d^\top))`, shape (6,): metres, then a rotation
    vector in radians (world frame), computed through quaternions as the lab does."""
    e = np.empty(6)
    e[:3] = np.asarray(pos, float) - np.asarray(pos_d, float)
    quat, conj, diff = np.empty(4), np.empty(4), np.empty(4)
    mujoco.mju_mat2Quat(quat, np.asarray(xmat, float).reshape(9))
    mujoco.mju_negQuat(conj, np.asarray(quat_d, float))
    mujoco.mju_mulQuat(diff, quat, conj)
    mujoco.mju_quat2Vel(e[3:], diff, 1.0)
    return e


def lab_osc_torque(J, Minv, e, qdot, h, gains: PoseGains = LAB_GAINS) -> np.ndarray:
    r"""The lab's law :math:`\tau = J^\top \Lambda (-K_p e - K_d J\dot q) + h`, :math:`\Lambda = (J M^{-1} J^\top)^{-1}`.

    ``Minv`` is :math:`M^{-1}` (nv, nv). :math:`\Lambda` is applied by a solve, not a
    pseudo-inverse (the same result wherever :math:`J` has full rank).
    """
    J = np.asarray(J, float)
    xddot = -gains.kp * np.asarray(e, float) - gains.kd * (J @ qdot)
    return J.T @ np.linalg.solve(J @ Minv @ J.T, xddot) + h


def tracking_acceleration(e, xdot, ref_vel, ref_acc, jdot_qdot, gains: PoseGains) -> np.ndarray:
    r"""Desired joint-free task acceleration with feedforward and the velocity-product term:

    .. math:: a = \ddot x_d - K_d(\dot x - \dot x_d) - K_p e - \dot J\dot q
    """
    return (np.asarray(ref_acc, float) - gains.kd * (np.asarray(xdot, float) - ref_vel)
            - gains.kp * np.asarray(e, float) - jdot_qdot)


def posture_torque(q, qdot, q_rest, stiffness: float, damping: float) -> np.ndarray:
    r"""Joint-space pull towards a rest posture, :math:`\tau_0 = k_n(q_0 - q) - d_n\dot q`."""
    return stiffness * (np.asarray(q_rest, float) - q) - damping * np.asarray(qdot, float)


def conditioned_task_solve(lam_inv, rhs, pivot_floor: float = 0.0) -> np.ndarray:
    r""":math:`\Lambda\,y` with :math:`\Lambda^{-1} = J M^{-1} J^\top`, by a Cholesky factorisation
    whose pivots are raised to at least ``pivot_floor``.

    Away from singular configurations every pivot is far above the floor and this is the
    exact :math:`\Lambda y`; near one, the vanishing pivot is held at the floor, so
    :math:`\Lambda` stays bounded (at most about 1/``pivot_floor`` along the lost direction).
    """
    L = np.array(lam_inv, dtype=float)
    y = np.asarray(rhs, dtype=float)
    out = np.empty_like(y)
    mujoco.mju_cholFactor(L, float(pivot_floor))
    mujoco.mju_cholSolve(out, L, y)
    return out


def osc_torque(J, Minv, a, h, tau_posture, pivot_floor: float = 0.0, implicit_inertia=None) -> np.ndarray:
    r"""Operational-space torque with null-space posture, conditioned :math:`\Lambda` and servo compensation:

    .. math::
        \tau_r = J^\top \Lambda (a - J M^{-1}\tau_0) + \tau_0 + h,\qquad
        \tau = \tau_r + \Delta t K_v\, M^{-1}(\tau_r - h)

    For a square, non-singular :math:`J` the posture term cancels exactly
    (:math:`J^\top\Lambda J M^{-1} = I`): a 6-D pose task leaves no null space.

    Args:
        J: (6, nv) task Jacobian. Minv: (nv, nv) :math:`M^{-1}`. a: (6,) task acceleration.
        h: (nv,) bias forces. tau_posture: (nv,) :math:`\tau_0`.
        pivot_floor: see :func:`conditioned_task_solve`.
        implicit_inertia: (nv,) diagonal :math:`\Delta t K_v` the integrator adds, or None.
    """
    J, Minv = np.asarray(J, float), np.asarray(Minv, float)
    tau_posture = np.asarray(tau_posture, float)
    z = conditioned_task_solve(J @ Minv @ J.T, np.asarray(a, float) - J @ Minv @ tau_posture, pivot_floor)
    tau = J.T @ z + tau_posture
    if implicit_inertia is not None:
        tau = tau + implicit_inertia * (Minv @ tau)
    return tau + h


# ---------------------------------------------------------------------------------------
# The same laws, in place, for the simulation loop
# ---------------------------------------------------------------------------------------

class _PoseController:
    """What the in-place controllers share: buffers, and the pose error.

    :meth:`bind` preallocates everything and builds ``update``; each call ``update(k)`` reads
    ``data`` (kinematics and dynamics of the current state) and fills ``stack = [tau, q, qdot]``
    (so that the loop logs them and commands the servos with one product each) and ``error``
    (the (6,) pose error). The step's code is a closure over prebuilt views: no allocation and
    no attribute look-up per step.
    """

    def __init__(self, gains: PoseGains, site: str):
        if not isinstance(gains, PoseGains):
            raise ValueError(f"gains must be a PoseGains, got {type(gains).__name__}")
        self.gains, self.site = gains, site

    def bind(self, model: mujoco.MjModel, data: mujoco.MjData, ref, target_quat) -> None:
        """Preallocate for ``model`` and a reference ``ref`` (pos, vel, acc of shape (N, 3))."""
        sid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SITE, self.site)
        if sid < 0:
            raise ValueError(f"site {self.site!r} is not in the model")
        if model.nq != model.nv or model.nu != model.nv:
            raise ValueError("these controllers need one actuated hinge per degree of freedom")
        nv = model.nv
        self.nv, self.sid, self.body = nv, sid, int(model.site_bodyid[sid])
        self.ref_pos = np.ascontiguousarray(ref.pos, dtype=float)
        self.conj = np.empty(4)                    # conjugate of the target orientation
        mujoco.mju_negQuat(self.conj, np.asarray(target_quat, float))
        # [tau, q, qdot, 1]: the loop logs [tau, q, qdot] and turns it into servo commands
        self.stack_1 = np.zeros(3 * nv + 1)
        self.stack_1[-1] = 1.0
        self.stack = self.stack_1[:3 * nv]
        self.JD = np.zeros((12, nv))               # [J; Jdot]: one product gives J qdot, Jdot qdot
        self.X = np.zeros((6, nv))                 # J M^-1 (row i is M^-1 J_i^T)
        self.L = np.zeros((6, 6))                  # J M^-1 J^T, then its Cholesky factor

    def _pose_error_step(self, model, data, e):
        """A function ``pose_error(k)`` writing e = (x - x_d, log(R R_d^T)) into ``e`` (6,)."""
        xpos, xmat, ref_pos, conj = data.site_xpos[self.sid], data.site_xmat[self.sid], self.ref_pos, self.conj
        quat, dquat, e_pos, e_ori = np.empty(4), np.empty(4), e[0:3], e[3:6]
        subtract, mat2quat, mulquat, quat2vel = np.subtract, mujoco.mju_mat2Quat, mujoco.mju_mulQuat, mujoco.mju_quat2Vel

        def pose_error(k):
            subtract(xpos, ref_pos[k], out=e_pos)
            mat2quat(quat, xmat)
            mulquat(dquat, quat, conj)
            quat2vel(e_ori, dquat, 1.0)
        return pose_error


class LabController(_PoseController):
    r"""The lab's law :math:`\tau = J^\top\Lambda(-K_p e - K_d J\dot q) + h`, in place.

    :math:`\Lambda` is applied through a Cholesky solve of :math:`J M^{-1} J^\top` (the lab
    uses ``pinv``; the two agree wherever :math:`J` has full rank).
    """

    def __init__(self, gains: PoseGains = LAB_GAINS, site: str = "attachment_site"):
        super().__init__(gains, site)

    def bind(self, model, data, ref, target_quat) -> None:
        super().bind(model, data, ref, target_quat)
        nv, sid = self.nv, self.sid
        s = np.zeros(12)                           # s = [e, J qdot]
        self.error = s[0:6]
        G = np.hstack([-np.diag(self.gains.kp), -np.diag(self.gains.kd)])   # a = G s
        a, z, Jt_z = np.zeros(6), np.zeros(6), np.zeros(nv)
        J, X, L = self.JD[:6], self.X, self.L
        Jp, Jr, J_qdot = self.JD[0:3], self.JD[3:6], s[6:12]
        tau, q, qdot = self.stack[:nv], self.stack[nv:2 * nv], self.stack[2 * nv:]
        qpos, qvel, h = data.qpos, data.qvel, data.qfrc_bias
        pose_error = self._pose_error_step(model, data, s)
        jac_site, solve_m, mul_mat_mat_t = mujoco.mj_jacSite, mujoco.mj_solveM, mujoco.mju_mulMatMatT
        chol_factor, chol_solve, mul_mat_t_vec = mujoco.mju_cholFactor, mujoco.mju_cholSolve, mujoco.mju_mulMatTVec
        dot, add = np.dot, np.add

        def update(k: int) -> np.ndarray:
            q[:] = qpos
            qdot[:] = qvel
            jac_site(model, data, Jp, Jr, sid)     # J
            solve_m(model, data, X, J)             # X = J M^-1
            mul_mat_mat_t(L, X, J)                 # Lambda^-1 = J M^-1 J^T
            chol_factor(L, 1e-12)
            pose_error(k)                          # e
            dot(J, qvel, out=J_qdot)               # J qdot
            dot(G, s, out=a)                       # a = -Kp e - Kd J qdot
            chol_solve(z, L, a)                    # z = Lambda a
            mul_mat_t_vec(Jt_z, J, z)              # J^T Lambda a
            add(Jt_z, h, out=tau)                  # tau = J^T Lambda a + h
            return tau
        self.update = update


class OperationalSpaceController(_PoseController):
    r"""The tracking law of :func:`osc_torque`, in place: feedforward, :math:`\dot J\dot q`,
    null-space posture, conditioned :math:`\Lambda`, and compensation of the implicit servo damping.

    Args:
        gains: task-space PD gains (the lab's by default, so that the comparison is fair).
        pivot_floor: smallest pivot allowed in the Cholesky factorisation of
            :math:`J M^{-1} J^\top` (units 1/kg, 1/(kg·m²)). Far from singularities it changes
            nothing; near one it caps :math:`\Lambda` (the directions the arm cannot move in
            get a bounded force instead of an unbounded one) and lets the posture act.
        posture_stiffness: :math:`k_n` [N·m/rad] of the null-space pull to the home posture
            (its damping is :math:`2\sqrt{k_n}`).
        feedforward, jdot, compensate_servo: switch the parts off to see what each one does.
    """

    def __init__(self, gains: PoseGains = LAB_GAINS, *, pivot_floor: float = 1e-3,
                 posture_stiffness: float = 10.0, feedforward: bool = True, jdot: bool = True,
                 compensate_servo: bool = True, site: str = "attachment_site"):
        super().__init__(gains, site)
        for name, v in (("pivot_floor", pivot_floor), ("posture_stiffness", posture_stiffness)):
            if not (isinstance(v, (int, float, np.floating, np.integer)) and np.isfinite(v) and v >= 0):
                raise ValueError(f"{name} must be a finite non-negative number, got {v!r}")
        self.pivot_floor, self.posture_stiffness = float(pivot_floor), float(posture_stiffness)
        self.feedforward, self.jdot, self.compensate_servo = feedforward, jdot, compensate_servo

    def bind(self, model, data, ref, target_quat) -> None:
        from labsupport.ur5e import Servo, implicit_damping

        super().bind(model, data, ref, target_quat)
        nv, sid, body, floor = self.nv, self.sid, self.body, self.pivot_floor
        kp, kd, kn = self.gains.kp, self.gains.kd, self.posture_stiffness
        # s = [e, J qdot, Jdot qdot, b_k, -tau0] and a - J M^-1 tau0 = G s, with
        # b_k = acc_d + Kd vel_d (the feedforward) and G's last block X = J M^-1 (set each step)
        s = np.zeros(24 + nv)
        self.error = s[0:6]
        G = np.hstack([-np.diag(kp), -np.diag(kd), -np.eye(6) * self.jdot, np.eye(6), np.zeros((6, nv))])
        b = np.zeros((len(self.ref_pos), 6))
        if self.feedforward:
            b[:, :3] = ref.acc + kd[:3] * ref.vel
        # -tau0 = Gn [q, qdot, 1], with tau0 = kn (q_rest - q) - 2 sqrt(kn) qdot, q_rest = qpos now
        Gn = np.hstack([kn * np.eye(nv), 2 * np.sqrt(kn) * np.eye(nv), -kn * data.qpos.reshape(-1, 1)])
        # r = [tau_r - h, qdd*, h] and tau = C r, with C = [I, dt Kv, I]
        kv_dt = implicit_damping(Servo.from_model(model), model.opt.timestep) * self.compensate_servo
        r = np.zeros(3 * nv)
        C = np.hstack([np.eye(nv), np.diag(kv_dt), np.eye(nv)])
        self.b, self.G, self.Gn, self.C = b, G, Gn, C

        J, X, L, a, z = self.JD[:6], self.X, self.L, np.zeros(6), np.zeros(6)
        Jp, Jr, Dp, Dr = self.JD[0:3], self.JD[3:6], self.JD[6:9], self.JD[9:12]
        rates, b_k, minus_tau0, G_X = s[6:18], s[18:24], s[24:], G[:, 24:]
        tau_r, h_copy = r[:nv], r[2 * nv:]
        tau_r_row, qdd_row = r[:nv].reshape(1, -1), r[nv:2 * nv].reshape(1, -1)
        tau, q, qdot, q_qdot_1 = self.stack[:nv], self.stack[nv:2 * nv], self.stack[2 * nv:], self.stack_1[nv:]
        qpos, qvel, h, xpos = data.qpos, data.qvel, data.qfrc_bias, data.site_xpos[sid]
        pose_error = self._pose_error_step(model, data, s)
        jac_site, jac_dot, solve_m = mujoco.mj_jacSite, mujoco.mj_jacDot, mujoco.mj_solveM
        mul_mat_mat_t, chol_factor, chol_solve = mujoco.mju_mulMatMatT, mujoco.mju_cholFactor, mujoco.mju_cholSolve
        mul_mat_t_vec, dot, subtract = mujoco.mju_mulMatTVec, np.dot, np.subtract
        with_jdot = self.jdot

        def update(k: int) -> np.ndarray:
            q[:] = qpos
            qdot[:] = qvel
            jac_site(model, data, Jp, Jr, sid)             # J
            if with_jdot:
                jac_dot(model, data, Dp, Dr, xpos, body)   # Jdot
            solve_m(model, data, X, J)                     # X = J M^-1
            mul_mat_mat_t(L, X, J)                         # Lambda^-1 = J M^-1 J^T
            chol_factor(L, floor)                          # ... factorised, pivots >= floor
            pose_error(k)                                  # e
            dot(JD, qvel, out=rates)                       # J qdot, Jdot qdot
            b_k[:] = b[k]                                  # acc_d + Kd vel_d
            dot(Gn, q_qdot_1, out=minus_tau0)              # -tau0
            G_X[:] = X
            dot(G, s, out=a)                               # a - J M^-1 tau0
            chol_solve(z, L, a)                            # z = Lambda (a - J M^-1 tau0)
            mul_mat_t_vec(tau_r, J, z)                     # J^T z
            subtract(tau_r, minus_tau0, out=tau_r)         # tau_r - h = J^T z + tau0
            solve_m(model, data, qdd_row, tau_r_row)       # qdd* = M^-1 (tau_r - h)
            h_copy[:] = h
            dot(C, r, out=tau)                             # tau = tau_r + dt Kv qdd*
            return tau
        JD = self.JD
        self.update = update


def minv(model: mujoco.MjModel, data: mujoco.MjData) -> np.ndarray:
    """:math:`M^{-1}` as a dense matrix (for the plain-array laws; the loop never forms it)."""
    return solve_mass(model, data, np.eye(model.nv))
