r"""Kinematics of the 2R planar arm: forward and inverse kinematics, Jacobian,
:math:`\dot J\dot q`.

Joint angles :math:`q = (q_1, q_2)` (relative, :math:`q_2` measured from link 1),
link lengths :math:`l_1, l_2`. With :math:`c_1 = \cos q_1`,
:math:`c_{12} = \cos(q_1 + q_2)` (and likewise for sines), the end effector is at

.. math:: x = l_1 c_1 + l_2 c_{12}, \qquad y = l_1 s_1 + l_2 s_{12}.

Every function takes arrays whose last axis holds the two components, so a whole
trajectory ``(N, 2)`` goes through one call.

The two inverse-kinematics branches are named as in the lab, and as the Problems'
3R arm names them: ``elbow_up=True`` is :math:`q_2 = +\arccos D \ge 0`,
``elbow_up=False`` is :math:`q_2 \le 0`. The name follows the lab, not the picture:
:math:`q_2 > 0` puts the elbow clockwise of the line from the base to the
target, below it (with :math:`y` up) for a target in front of the arm.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass

import numpy as np

from labsupport import validate
from labsupport.trajectories import Reference


@dataclass(frozen=True)
class Planar2R:
    """Link lengths of a 2R planar arm.

    Attributes:
        l1: length of link 1, joint 1 to joint 2 [m], > 0.
        l2: length of link 2, joint 2 to the end effector [m], > 0.
    """

    l1: float = 0.5
    l2: float = 0.4

    def __post_init__(self):
        for name in ("l1", "l2"):
            value = getattr(self, name)
            if (
                isinstance(value, (bool, np.bool_))
                or not isinstance(value, (int, float, np.floating, np.integer))
                or not np.isfinite(value)
                or value <= 0
            ):
                raise ValueError(
                    f"{name} (a link length) must be a positive number, "
                    f"got {value!r}"
                )

    @property
    def reach_min(self) -> float:
        r"""Inner radius of the workspace annulus, :math:`|l_1 - l_2|` [m]."""
        return abs(self.l1 - self.l2)

    @property
    def reach_max(self) -> float:
        r"""Outer radius of the workspace annulus, :math:`l_1 + l_2` [m]."""
        return self.l1 + self.l2


#: The lab's arm: l = (0.5, 0.4) m.
LAB_ARM = Planar2R()


def checked_arm(arm) -> Planar2R:
    """``arm`` if it is a :class:`Planar2R`, else a ``ValueError`` that says what to
    pass (a tuple of lengths used to fail on ``arm.l1``)."""
    if not isinstance(arm, Planar2R):
        raise ValueError(
            "arm must be a Planar2R, such as Planar2R(l1=0.5, l2=0.4) or LAB_ARM, "
            f"got {validate.short(arm)}"
        )
    return arm


def _q(q, name="q") -> np.ndarray:
    """``q`` (or a position ``x``) as a float array of shape ``(..., 2)`` with finite
    entries, or a ``ValueError`` naming it."""
    if isinstance(q, Reference):  # NumPy would read (pos, vel, acc) as three points
        raise ValueError(
            f"{name} must be positions, got a whole Reference (position, velocity, "
            f"acceleration): pass its position, ref.pos"
        )
    validate.real(f"{name} holds", q)
    values = validate.floats(q)
    if values is None:
        raise ValueError(f"{name} must be numbers of shape (..., 2), got {q!r}")
    q = values
    if q.shape[-1:] != (2,):
        raise ValueError(
            f"{name} must have 2 components on its last axis, got shape {q.shape}"
        )
    if not np.isfinite(q).all():
        raise ValueError(f"{name} has entries that are not finite (NaN or inf)")
    return q


def forward_kinematics(q, arm: Planar2R = LAB_ARM) -> np.ndarray:
    r"""End-effector position, shape ``(..., 2)``:
    :math:`x = (l_1 c_1 + l_2 c_{12},\; l_1 s_1 + l_2 s_{12})`.

    Example: the lab's arm stretched along :math:`x`, then turned by 90° with the
    elbow bent back by 90°.

    >>> print(forward_kinematics([0.0, 0.0]))
    [0.9 0. ]
    >>> print(forward_kinematics([np.pi / 2, -np.pi / 2]))
    [0.4 0.5]
    """
    q, arm = _q(q), checked_arm(arm)
    q1, q12 = q[..., 0], q[..., 0] + q[..., 1]
    return np.stack(
        [
            arm.l1 * np.cos(q1) + arm.l2 * np.cos(q12),
            arm.l1 * np.sin(q1) + arm.l2 * np.sin(q12),
        ],
        axis=-1,
    )


def elbow_position(q, arm: Planar2R = LAB_ARM) -> np.ndarray:
    r"""Position of joint 2, :math:`(l_1 c_1, l_1 s_1)`, shape ``(..., 2)``."""
    q, arm = _q(q), checked_arm(arm)
    return arm.l1 * np.stack([np.cos(q[..., 0]), np.sin(q[..., 0])], axis=-1)


def jacobian(q, arm: Planar2R = LAB_ARM) -> np.ndarray:
    r"""Jacobian :math:`J = \partial x/\partial q`, shape ``(..., 2, 2)``:

    .. math::
        J = \begin{bmatrix}
            -l_1 s_1 - l_2 s_{12} & -l_2 s_{12} \\
            \phantom{-}l_1 c_1 + l_2 c_{12} & \phantom{-}l_2 c_{12}
        \end{bmatrix},
        \qquad \det J = l_1 l_2 \sin q_2.

    Example: the determinant against :math:`l_1 l_2 \sin q_2`.

    >>> q = np.array([0.3, 1.0])
    >>> print(f"{np.linalg.det(jacobian(q)):.6f} {0.5 * 0.4 * np.sin(1.0):.6f}")
    0.168294 0.168294
    """
    q, arm = _q(q), checked_arm(arm)
    q1, q12 = q[..., 0], q[..., 0] + q[..., 1]
    s1, c1, s12, c12 = np.sin(q1), np.cos(q1), np.sin(q12), np.cos(q12)
    row1 = np.stack([-arm.l1 * s1 - arm.l2 * s12, -arm.l2 * s12], axis=-1)
    row2 = np.stack([arm.l1 * c1 + arm.l2 * c12, arm.l2 * c12], axis=-1)
    return np.stack([row1, row2], axis=-2)


def jdot_qdot(q, qdot, arm: Planar2R = LAB_ARM) -> np.ndarray:
    r"""Velocity-product acceleration :math:`\dot J(q,\dot q)\,\dot q`, shape
    ``(..., 2)``:

    .. math::
        \dot J\dot q = -\begin{bmatrix}
            l_1 c_1 \dot q_1^2 + l_2 c_{12}(\dot q_1 + \dot q_2)^2 \\
            l_1 s_1 \dot q_1^2 + l_2 s_{12}(\dot q_1 + \dot q_2)^2
        \end{bmatrix}

    (the centripetal accelerations of the two links), so that
    :math:`\ddot x = J\ddot q + \dot J\dot q`.
    """
    q, qdot, arm = _q(q), _q(qdot, "qdot"), checked_arm(arm)
    q1, q12 = q[..., 0], q[..., 0] + q[..., 1]
    w1sq, w12sq = qdot[..., 0] ** 2, (qdot[..., 0] + qdot[..., 1]) ** 2
    return -np.stack(
        [
            arm.l1 * np.cos(q1) * w1sq + arm.l2 * np.cos(q12) * w12sq,
            arm.l1 * np.sin(q1) * w1sq + arm.l2 * np.sin(q12) * w12sq,
        ],
        axis=-1,
    )


#: How far past 1 the elbow's cosine :math:`D` may be and the target still count as
#: on the workspace's boundary (rounding of a point computed to lie on it).
BOUNDARY_TOL = 1e-12


def elbow_cosine(x, arm: Planar2R = LAB_ARM) -> np.ndarray:
    r"""The elbow's cosine for target(s) ``x``, reachable where :math:`|D| \le 1`:

    .. math:: D = \cos q_2 = \frac{x^2 + y^2 - l_1^2 - l_2^2}{2 l_1 l_2}
    """
    x, arm = _q(x, "x"), checked_arm(arm)
    with np.errstate(over="ignore"):  # |x| past 1e154: D is inf, i.e. unreachable
        r_sq = np.sum(x**2, axis=-1)
    return (r_sq - arm.l1**2 - arm.l2**2) / (2 * arm.l1 * arm.l2)


def is_reachable(x, arm: Planar2R = LAB_ARM) -> np.ndarray:
    r"""True where :math:`|l_1 - l_2| \le \lVert x\rVert \le l_1 + l_2` (the
    workspace annulus), to the same rounding that :func:`inverse_kinematics`
    accepts (:data:`BOUNDARY_TOL`)."""
    return np.abs(elbow_cosine(x, arm)) <= 1 + BOUNDARY_TOL


def inverse_kinematics(
    x, arm: Planar2R = LAB_ARM, elbow_up: bool = True, clip: bool = False
) -> np.ndarray:
    r"""Joint angles that put the end effector at ``x``, shape ``(..., 2)``:

    .. math::
        D = \frac{x^2 + y^2 - l_1^2 - l_2^2}{2 l_1 l_2},\quad q_2 = \pm\arccos D,\\
        q_1 = \operatorname{atan2}(y, x)
              - \operatorname{atan2}(l_2 \sin q_2,\; l_1 + l_2\cos q_2)

    with :math:`+` for ``elbow_up=True`` and :math:`-` for ``elbow_up=False``.

    Args:
        x: target(s), shape ``(..., 2)``.
        elbow_up: ``True`` (:math:`q_2 \ge 0`) or ``False`` (:math:`q_2 \le 0`).
        clip: a target outside the annulus raises ``ValueError`` by default. With
            ``clip=True`` it is moved radially onto the nearest workspace boundary
            instead (``|D|`` clipped to 1, as the lab's code does silently), and a
            ``RuntimeWarning`` says so.

    Example: both branches reach the point (0.5, 0.2) m, and forward kinematics
    takes each back there.

    >>> x = np.array([0.5, 0.2])
    >>> q_up, q_down = inverse_kinematics(x), inverse_kinematics(x, elbow_up=False)
    >>> print(np.round(q_up, 4), np.round(q_down, 4))
    [-0.407   1.8755] [ 1.168  -1.8755]
    >>> back = forward_kinematics(np.stack([q_up, q_down]))
    >>> print(np.allclose(back, x))
    True
    """
    elbow_up = validate.flag("elbow_up", elbow_up)
    clip = validate.flag("clip", clip)
    x = _q(x, "x")
    D = elbow_cosine(x, arm)
    outside = np.abs(D) > 1 + BOUNDARY_TOL
    if np.any(outside):
        r = np.hypot(x[..., 0], x[..., 1])  # no overflow, even for 1e308
        bad = float(np.atleast_1d(r)[np.atleast_1d(outside)][0])
        message = (
            f"target at distance {bad:.4g} m from the base is outside the workspace "
            f"{arm.reach_min:.4g} m <= |x| <= {arm.reach_max:.4g} m"
        )
        if not clip:
            raise ValueError(
                message + "; choose a reachable target (or pass clip=True)"
            )
        warnings.warn(
            message + "; clipped onto the workspace boundary",
            RuntimeWarning,
            stacklevel=2,
        )
    D = np.clip(D, -1.0, 1.0)
    q2 = np.arccos(D) if elbow_up else -np.arccos(D)
    q1 = np.arctan2(x[..., 1], x[..., 0]) - np.arctan2(
        arm.l2 * np.sin(q2), arm.l1 + arm.l2 * np.cos(q2)
    )
    return np.stack([q1, q2], axis=-1)


def _path(ref) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The position, velocity and acceleration of a Cartesian ``Reference``, arrays
    of one shape ``(..., 2)``, or a ``ValueError`` that says what to pass."""
    if not isinstance(ref, Reference):
        raise ValueError(
            "ref must be a trajectories.Reference (pos, vel, acc) of the path, "
            "such as circle_2d(t, ...) for an array of times t; "
            f"got {type(ref).__name__}"
        )
    x, xdot = _q(ref.pos, "ref.pos"), _q(ref.vel, "ref.vel")
    xddot = _q(ref.acc, "ref.acc")
    if not x.shape == xdot.shape == xddot.shape:
        raise ValueError(
            "ref.pos, ref.vel and ref.acc must have one shape, got "
            f"{x.shape}, {xdot.shape} and {xddot.shape}"
        )
    return x, xdot, xddot


def joint_reference(
    ref: Reference,
    arm: Planar2R = LAB_ARM,
    elbow_up: bool = True,
    min_det: float = 1e-6,
) -> Reference:
    r"""Turn a Cartesian reference :math:`(x_d, \dot x_d, \ddot x_d)` into a joint
    reference:

    .. math::
        q_d &= \mathrm{IK}(x_d),\qquad \dot q_d = J(q_d)^{-1}\dot x_d,\\
        \ddot q_d &= J(q_d)^{-1}\big(\ddot x_d - \dot J(q_d,\dot q_d)\,\dot q_d\big)

    ``elbow_up`` picks the IK branch, as in :func:`inverse_kinematics`.
    Works on one instant ``(2,)`` or a whole trajectory ``(N, 2)``. Raises
    ``ValueError`` if the path reaches a singular configuration
    (:math:`|\det J| <` ``min_det`` > 0, in m²: arm stretched or folded; on the lab's
    arm the default is :math:`|q_2|` within 5e-6 rad of 0 or π, where a point on the
    workspace's edge lands after rounding).
    """
    min_det = validate.number("min_det", min_det, positive=True)
    x, xdot, xddot = _path(ref)
    q = inverse_kinematics(x, arm, elbow_up)
    J = jacobian(q, arm)
    det = J[..., 0, 0] * J[..., 1, 1] - J[..., 0, 1] * J[..., 1, 0]
    if np.any(np.abs(det) < min_det):
        raise ValueError(
            "the path passes through a singular configuration (arm stretched "
            "or folded): det J = 0 there, so no joint velocity reproduces the "
            "Cartesian one; keep the path inside the workspace annulus"
        )
    qdot = np.linalg.solve(J, xdot[..., None])[..., 0]
    qddot = np.linalg.solve(J, (xddot - jdot_qdot(q, qdot, arm))[..., None])[..., 0]
    return Reference(q, qdot, qddot)


def sample_annulus(
    rng: np.random.Generator | int, arm: Planar2R = LAB_ARM, margin: float = 0.05
) -> np.ndarray:
    r"""A random target inside the workspace, kept ``margin`` away from both
    boundaries. ``rng`` is a NumPy generator, used as it is, or a seed for one.

    Draws, as the lab does, first a radius
    :math:`\rho \sim U(|l_1 - l_2| + \text{margin},\; l_1 + l_2 - \text{margin})` and
    then an angle :math:`\phi \sim U(-\pi, \pi)`, and returns
    :math:`\rho(\cos\phi, \sin\phi)`. (Uniform in radius, so not uniform in area:
    points near the inner edge are denser.)
    """
    try:
        rng = np.random.default_rng(rng)  # a Generator comes back unchanged
    except (TypeError, ValueError):
        raise ValueError(
            "rng must be a NumPy generator, such as np.random.default_rng(42), "
            f"or a whole-number seed, got {rng!r}"
        ) from None
    margin = validate.number("margin", margin, nonnegative=True)
    arm = checked_arm(arm)
    lo, hi = arm.reach_min + margin, arm.reach_max - margin
    if not lo < hi:
        raise ValueError(
            f"margin={margin!r} leaves no room in the workspace annulus "
            f"[{arm.reach_min}, {arm.reach_max}]"
        )
    radius = rng.uniform(lo, hi)
    angle = rng.uniform(-np.pi, np.pi)
    return radius * np.array([np.cos(angle), np.sin(angle)])
