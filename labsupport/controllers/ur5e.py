r"""Operational-space control of the UR5e: the lab's law, and a tracking law that
goes beyond it.

Both return a joint torque; the loop turns it into commands for the Menagerie's
position servos (:func:`labsupport.actuators.servo_actuation`). The task is the pose
of the ``attachment_site``; its error is :math:`e = (x - x_d,\; \log(R R_d^\top))`,
position then rotation vector, in the world frame, matching the rows of the site
Jacobian :math:`J` (linear, then angular). The target orientation :math:`R_d` is held
constant.

Each law is one function whose body follows its equation line by line, with MuJoCo's
own :math:`M`, :math:`h`, :math:`J` and :math:`\dot J\dot q`
(:mod:`labsupport.dynamics`). The arrays they fill are allocated once, in a
:class:`PoseArrays`, and passed in. A controller for :func:`labsupport.sim.simulate`
is a small closure that reads the reference at ``data.time`` and calls the law.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import mujoco
import numpy as np

from labsupport import validate
from labsupport.dynamics import (
    jacobian_solve,
    mass_times,
    site_id,
    site_jacobian,
    site_jdot_qdot,
    solve_mass,
)
from labsupport.metrics import rotation_error


@dataclass(frozen=True)
class PoseGains:
    r"""Task-space PD gains, critically damped unless given:
    :math:`K_d = 2\sqrt{K_p}`.

    Attributes:
        kp_pos: position stiffness :math:`K_p` [1/s²] (per unit mass:
            :math:`\Lambda` supplies it).
        kp_ori: orientation stiffness [1/s²].
        kd_pos, kd_ori: damping [1/s]; ``None`` for :math:`2\sqrt{K_p}`.
    """

    kp_pos: float = 100.0
    kp_ori: float = 50.0
    kd_pos: float | None = None
    kd_ori: float | None = None

    def __post_init__(self):
        for name in ("kp_pos", "kp_ori", "kd_pos", "kd_ori"):
            value = getattr(self, name)
            if value is not None or name.startswith("kp"):
                validate.number(name, value, nonnegative=True)

    @cached_property
    def kp(self) -> np.ndarray:
        """:math:`K_p` as a (6,) diagonal: position then orientation."""
        return np.repeat([self.kp_pos, self.kp_ori], 3).astype(float)

    @cached_property
    def kd(self) -> np.ndarray:
        """:math:`K_d` as a (6,) diagonal."""
        kd_pos = 2 * np.sqrt(self.kp_pos) if self.kd_pos is None else self.kd_pos
        kd_ori = 2 * np.sqrt(self.kp_ori) if self.kd_ori is None else self.kd_ori
        return np.repeat([kd_pos, kd_ori], 3).astype(float)


#: The lab's gains: Kp = 100 (position), 50 (orientation), Kd = 2 sqrt(Kp).
LAB_GAINS = PoseGains(100.0, 50.0)


@dataclass(frozen=True)
class PoseArrays:
    r"""Arrays the laws fill at every step, allocated once for a model
    (:meth:`for_model`).

    Attributes:
        J: (6, nv) site Jacobian. e: (6,) pose error. quats: two (4,) scratch
            quaternions.
        xdot_d, xddot_d: (6,) the target's twist and its rate (the angular parts
            stay zero: the target orientation is constant).
        jdot_qdot: (6,) :math:`\dot J\dot q`.
        qddot: (nv,) the joint acceleration :math:`\ddot q^*`.
        Mqddot: (nv,) its product with the mass matrix, :math:`M\ddot q^*`.
    """

    J: np.ndarray
    e: np.ndarray
    quats: tuple[np.ndarray, np.ndarray]
    xdot_d: np.ndarray
    xddot_d: np.ndarray
    jdot_qdot: np.ndarray
    qddot: np.ndarray
    Mqddot: np.ndarray

    @classmethod
    def for_model(cls, model: mujoco.MjModel) -> PoseArrays:
        validate.mujoco_model(model)
        nv = model.nv
        return cls(
            J=np.zeros((6, nv)),
            e=np.zeros(6),
            quats=(np.zeros(4), np.zeros(4)),
            xdot_d=np.zeros(6),
            xddot_d=np.zeros(6),
            jdot_qdot=np.zeros(6),
            qddot=np.zeros(nv),
            Mqddot=np.zeros(nv),
        )


def pose_error(
    data: mujoco.MjData, site: int, x_d, quat_d, out: np.ndarray, work=None
) -> np.ndarray:
    r"""Pose error :math:`e = (x - x_d,\ \log(R R_d^\top))` of site ``site`` (an id),
    written into ``out`` (6,): metres, then a rotation vector in radians (world
    frame). ``work`` holds two optional scratch quaternions
    (:attr:`PoseArrays.quats`)."""
    np.subtract(data.site_xpos[site], x_d, out=out[:3])
    rotation_error(data.site_xmat[site], quat_d, out=out[3:], work=work)
    return out


def lab_torque(
    model: mujoco.MjModel,
    data: mujoco.MjData,
    site: int | str,
    x_d,
    quat_d,
    gains: PoseGains,
    arrays: PoseArrays,
) -> np.ndarray:
    r"""The lab's operational-space law:

    .. math::
        \ddot x_{\text{des}} &= -K_p\,e - K_d\,J\dot q \\
        \tau &= J^\top \Lambda\,\ddot x_{\text{des}} + h, \qquad
        \Lambda = (J M^{-1} J^\top)^{+}

    Its damping acts on the site's absolute velocity :math:`J\dot q`, and it has no
    feedforward, so on a moving target it drags behind. ``site`` is the site's name
    or id; the target is the position ``x_d`` (3,) and the orientation ``quat_d``
    (w, x, y, z). As in the lab, :math:`\Lambda` is a pseudo-inverse: the inverse
    wherever :math:`J` has full rank, and zero on the all-zero data MuJoCo holds
    before its first evaluation (no torque then).
    """
    site = site_id(model, site)
    J = site_jacobian(model, data, site, out=arrays.J)
    e = pose_error(data, site, x_d, quat_d, out=arrays.e)
    Lam = np.linalg.pinv(J @ solve_mass(model, data, J).T)
    xddot_des = -gains.kp * e - gains.kd * (J @ data.qvel)
    return J.T @ (Lam @ xddot_des) + data.qfrc_bias


def tracking_torque(
    model: mujoco.MjModel,
    data: mujoco.MjData,
    site: int | str,
    x_d,
    xdot_d,
    xddot_d,
    quat_d,
    gains: PoseGains,
    implicit_inertia,
    arrays: PoseArrays,
    jdot: bool = True,
) -> np.ndarray:
    r"""Operational-space tracking: feedforward, damping of the velocity *error*,
    :math:`\dot J\dot q`, and compensation of the servo damping that the integrator
    treats implicitly:

    .. math::
        a &= \ddot x_d - K_d(J\dot q - \dot x_d) - K_p e - \dot J\dot q \\
        \ddot q^* &= J^{-1} a \\
        \tau &= (M + \Delta t\,K_v)\,\ddot q^* + h

    ``x_d``, ``xdot_d``, ``xddot_d`` (3,) are the target's position, velocity and
    acceleration; its orientation ``quat_d`` is constant. ``implicit_inertia`` is the
    diagonal :math:`\Delta t\,K_v` (:func:`labsupport.actuators.implicit_damping`;
    zeros leave the compensation out), and ``jdot=False`` leaves :math:`\dot J\dot q`
    out.

    This is the operational-space law :math:`\tau_r = J^\top\Lambda a + h`,
    :math:`\Lambda = (J M^{-1} J^\top)^{-1}`, written for the UR5e's square Jacobian:
    there :math:`J^\top\Lambda = M J^{-1}`, so :math:`\tau_r = M\ddot q^* + h`, and
    the servo compensation :math:`\Delta t\,K_v M^{-1}(\tau_r - h)` is
    :math:`\Delta t\,K_v\,\ddot q^*`. A singular :math:`J` raises ``ValueError``.
    """
    site = site_id(model, site)
    J = site_jacobian(model, data, site, out=arrays.J)
    e = pose_error(data, site, x_d, quat_d, out=arrays.e, work=arrays.quats)
    arrays.xdot_d[:3], arrays.xddot_d[:3] = xdot_d, xddot_d
    jdot_qdot = (
        site_jdot_qdot(model, data, site, out=arrays.jdot_qdot) if jdot else 0.0
    )
    a = (
        arrays.xddot_d
        - gains.kd * (J.dot(data.qvel) - arrays.xdot_d)
        - gains.kp * e
        - jdot_qdot
    )
    qddot = jacobian_solve(J, a, out=arrays.qddot)
    M_qddot = mass_times(model, data, qddot, out=arrays.Mqddot)
    return M_qddot + implicit_inertia * qddot + data.qfrc_bias
