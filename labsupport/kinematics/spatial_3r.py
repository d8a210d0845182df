r"""Kinematics of the 3R spatial arm of the Problems (``models/spatial_3r.xml``).

Joint 1 pans about :math:`z` at the base; joints 2 and 3 pitch about :math:`y`. Link 1 rises
from the base to the shoulder :math:`s = (0, 0, l_1)`; at :math:`q = 0` link 2 is vertical and
link 3 horizontal. In the vertical plane of azimuth :math:`q_1`, with :math:`\rho` the distance
from the :math:`z` axis and :math:`h` the height above the shoulder,

.. math::
    \rho &= l_2\sin q_2 + l_3\cos(q_2 + q_3), \\
    h &= l_2\cos q_2 - l_3\sin(q_2 + q_3), \\
    p &= (\rho\cos q_1,\; \rho\sin q_1,\; l_1 + h).

So the arm reaches the points within :math:`l_2 + l_3` of the shoulder (and at least
:math:`|l_2 - l_3|` from it). The Jacobian is singular on the :math:`z` axis
(:math:`\rho = 0`, the pan does not move the tip) and when the arm is stretched or folded
(:math:`\cos q_3 = 0`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class Spatial3R:
    """Link lengths of the 3R arm [m] (the lab's: all 1 m)."""

    l1: float = 1.0  # base to shoulder (vertical) [m]
    l2: float = 1.0  # shoulder to elbow [m]
    l3: float = 1.0  # elbow to tip [m]

    def __post_init__(self):
        for name in ("l1", "l2", "l3"):
            value = getattr(self, name)
            if not np.isfinite(value) or value <= 0:
                raise ValueError(f"{name} (link length) must be a positive number, got {value!r}")

    @property
    def shoulder(self) -> np.ndarray:
        """Position of joint 2, the centre of the reachable shell, shape (3,)."""
        return np.array([0.0, 0.0, self.l1])

    @property
    def max_reach(self) -> float:
        r"""Largest distance from the shoulder the tip reaches, :math:`l_2 + l_3`."""
        return self.l2 + self.l3

    @property
    def min_reach(self) -> float:
        r"""Smallest distance from the shoulder the tip reaches, :math:`|l_2 - l_3|`."""
        return abs(self.l2 - self.l3)


#: The lab's arm.
LAB_ARM = Spatial3R()


def _vector3(x, name: str, what: str) -> np.ndarray:
    x = np.asarray(x, dtype=float)
    if x.shape != (3,):
        raise ValueError(f"{name} must be {what}, shape (3,); got shape {x.shape}")
    if not np.all(np.isfinite(x)):
        raise ValueError(f"{name} must be finite, got {x}")
    return x


def _joint_vector(q, name: str = "q") -> np.ndarray:
    return _vector3(q, name, "three joint values")


def _point(x, name: str = "target") -> np.ndarray:
    return _vector3(x, name, "a 3-D point")


def forward_kinematics(q, arm: Spatial3R = LAB_ARM) -> np.ndarray:
    r"""Tip position :math:`p(q) = (\rho\cos q_1, \rho\sin q_1, l_1 + h)`, shape (3,).

    :math:`\rho = l_2\sin q_2 + l_3\cos(q_2+q_3)`, :math:`h = l_2\cos q_2 - l_3\sin(q_2+q_3)`.

    Example:
        >>> forward_kinematics([0.0, 0.0, 0.0])
        array([1., 0., 2.])
    """
    q1, q2, q3 = _joint_vector(q)
    rho = arm.l2 * np.sin(q2) + arm.l3 * np.cos(q2 + q3)
    h = arm.l2 * np.cos(q2) - arm.l3 * np.sin(q2 + q3)
    return np.array([rho * np.cos(q1), rho * np.sin(q1), arm.l1 + h])


def is_reachable(x, arm: Spatial3R = LAB_ARM, tol: float = 1e-9) -> bool:
    r"""Whether the point lies in the shell :math:`|l_2 - l_3| \le \lVert x - s\rVert \le l_2 + l_3`."""
    d = float(np.linalg.norm(_point(x) - arm.shoulder))
    return arm.min_reach - tol <= d <= arm.max_reach + tol


def inverse_kinematics(x, elbow_up: bool = True, arm: Spatial3R = LAB_ARM) -> np.ndarray:
    r"""Joint angles that put the tip at ``x``: pan from the azimuth, then a planar 2R solve.

    .. math::
        q_1 = \operatorname{atan2}(y, x), \qquad
        \cos\theta = \frac{\rho^2 + h^2 - l_2^2 - l_3^2}{2 l_2 l_3}, \qquad
        q_2 = \operatorname{atan2}(\rho, h) - \operatorname{atan2}(l_3\sin\theta,\, l_2 + l_3\cos\theta),
        \qquad q_3 = \theta - \tfrac{\pi}{2}

    with :math:`\rho = \sqrt{x^2+y^2}` and :math:`h = z - l_1`: in the vertical plane the arm
    is a 2R arm whose first angle :math:`q_2` is measured from the vertical and whose relative
    angle is :math:`\theta = q_3 + \pi/2` (link 3 is perpendicular to link 2 at
    :math:`q_3 = 0`). ``elbow_up=True`` takes :math:`\theta = +\arccos(\cdot)`, which puts the
    elbow above the shoulder-to-target line; ``False`` the mirror image below it.

    Raises:
        ValueError: if ``x`` is out of reach (further than :math:`l_2 + l_3` from the shoulder),
            or on the :math:`z` axis, where the pan angle is undefined.
    """
    x = _point(x)
    rho = float(np.hypot(x[0], x[1]))
    h = float(x[2] - arm.l1)
    d = float(np.hypot(rho, h))
    if not is_reachable(x, arm):
        raise ValueError(
            f"target {x} is out of reach: it is {d:.3f} m from the shoulder at {arm.shoulder}, but "
            f"the arm reaches between {arm.min_reach:.3f} and {arm.max_reach:.3f} m from it. "
            "Pick a target inside that shell (sample_targets draws only reachable ones).")
    if rho < 1e-9:
        raise ValueError(f"target {x} is on the z axis: the pan angle q1 is undefined there; "
                         "move the target off the axis")
    q1 = np.arctan2(x[1], x[0])
    c = np.clip((d**2 - arm.l2**2 - arm.l3**2) / (2 * arm.l2 * arm.l3), -1.0, 1.0)
    theta = np.arccos(c) if elbow_up else -np.arccos(c)
    q2 = np.arctan2(rho, h) - np.arctan2(arm.l3 * np.sin(theta), arm.l2 + arm.l3 * np.cos(theta))
    q3 = theta - np.pi / 2
    return np.array([q1, _wrap(q2), _wrap(q3)])


def _wrap(angle: float) -> float:
    """Angle wrapped to [-pi, pi)."""
    return float((angle + np.pi) % (2 * np.pi) - np.pi)


def jacobian(q, arm: Spatial3R = LAB_ARM) -> np.ndarray:
    r"""Translational Jacobian :math:`J = \partial p / \partial q`, shape (3, 3).

    .. math::
        J = \begin{bmatrix}
            -\rho s_1 & \rho_{,2} c_1 & \rho_{,3} c_1 \\
             \rho c_1 & \rho_{,2} s_1 & \rho_{,3} s_1 \\
             0 & h_{,2} & h_{,3} \end{bmatrix},\quad
        \begin{aligned}
        \rho_{,2} &= l_2 c_2 - l_3 s_{23}, & \rho_{,3} &= -l_3 s_{23},\\
        h_{,2} &= -l_2 s_2 - l_3 c_{23}, & h_{,3} &= -l_3 c_{23}.
        \end{aligned}
    """
    q1, q2, q3 = _joint_vector(q)
    s1, c1 = np.sin(q1), np.cos(q1)
    s2, c2 = np.sin(q2), np.cos(q2)
    s23, c23 = np.sin(q2 + q3), np.cos(q2 + q3)
    rho = arm.l2 * s2 + arm.l3 * c23
    rho2, rho3 = arm.l2 * c2 - arm.l3 * s23, -arm.l3 * s23
    h2, h3 = -arm.l2 * s2 - arm.l3 * c23, -arm.l3 * c23
    return np.array([[-rho * s1, rho2 * c1, rho3 * c1],
                     [rho * c1, rho2 * s1, rho3 * s1],
                     [0.0, h2, h3]])


def jdot_qdot(q, qdot, arm: Spatial3R = LAB_ARM) -> np.ndarray:
    r"""Velocity-product acceleration :math:`\dot J(q,\dot q)\,\dot q` (the tip's acceleration at :math:`\ddot q = 0`).

    .. math::
        \dot J\dot q = \begin{bmatrix}
            \ddot\rho\,c_1 - 2\dot\rho\,\dot q_1 s_1 - \rho\,\dot q_1^2 c_1 \\
            \ddot\rho\,s_1 + 2\dot\rho\,\dot q_1 c_1 - \rho\,\dot q_1^2 s_1 \\
            \ddot h \end{bmatrix},\quad
        \begin{aligned}
        \dot\rho &= l_2 c_2\dot q_2 - l_3 s_{23}\dot q_{23}, &
        \ddot\rho &= -l_2 s_2\dot q_2^2 - l_3 c_{23}\dot q_{23}^2,\\
        & & \ddot h &= -l_2 c_2\dot q_2^2 + l_3 s_{23}\dot q_{23}^2,
        \end{aligned}

    with :math:`\dot q_{23} = \dot q_2 + \dot q_3`.
    """
    q1, q2, q3 = _joint_vector(q)
    w1, w2, w3 = _joint_vector(qdot, "qdot")
    w23 = w2 + w3
    s1, c1 = np.sin(q1), np.cos(q1)
    s2, c2 = np.sin(q2), np.cos(q2)
    s23, c23 = np.sin(q2 + q3), np.cos(q2 + q3)
    rho = arm.l2 * s2 + arm.l3 * c23
    rho_dot = arm.l2 * c2 * w2 - arm.l3 * s23 * w23
    rho_ddot = -arm.l2 * s2 * w2**2 - arm.l3 * c23 * w23**2
    h_ddot = -arm.l2 * c2 * w2**2 + arm.l3 * s23 * w23**2
    return np.array([rho_ddot * c1 - 2 * rho_dot * w1 * s1 - rho * w1**2 * c1,
                     rho_ddot * s1 + 2 * rho_dot * w1 * c1 - rho * w1**2 * s1,
                     h_ddot])


# ---------------------------------------------------------------------------------------
# Targets
# ---------------------------------------------------------------------------------------

def lab_sampler_target(rng: np.random.Generator, arm: Spatial3R = LAB_ARM) -> np.ndarray:
    r"""One draw of the lab's original target sampler (kept to reproduce its seed-0 target).

    It draws a distance :math:`r \sim U(0.5,\, l_1+l_2+l_3-0.1)` *from the base*, an azimuth
    :math:`\phi \sim U(0, 2\pi)` and a polar angle :math:`\vartheta \sim U(0, \pi/2)`, and returns
    :math:`r(\sin\vartheta\cos\phi, \sin\vartheta\sin\phi, \cos\vartheta)`. That is wrong for
    this arm: the reachable set is a ball of radius :math:`l_2 + l_3` about the *shoulder*
    :math:`(0, 0, l_1)`, not a ball about the base, so some draws cannot be reached
    (:func:`lab_sampler_unreachable_fraction`). Use :func:`sample_targets` instead.
    """
    r = rng.uniform(0.5, arm.l1 + arm.l2 + arm.l3 - 0.1)
    az = rng.uniform(0, 2 * np.pi)
    el = rng.uniform(0, np.pi / 2)
    return r * np.array([np.sin(el) * np.cos(az), np.sin(el) * np.sin(az), np.cos(el)])


def lab_target(seed: int = 0, arm: Spatial3R = LAB_ARM) -> np.ndarray:
    """The lab's target: the first draw of its sampler with ``np.random.default_rng(seed)``."""
    return lab_sampler_target(np.random.default_rng(seed), arm)


def lab_sampler_unreachable_fraction(n: int = 100_000, seed: int = 1, arm: Spatial3R = LAB_ARM) -> float:
    """Fraction of the lab sampler's draws that lie out of reach (Monte Carlo, ``n`` draws)."""
    rng = np.random.default_rng(seed)
    r = rng.uniform(0.5, arm.l1 + arm.l2 + arm.l3 - 0.1, n)
    az = rng.uniform(0, 2 * np.pi, n)
    el = rng.uniform(0, np.pi / 2, n)
    pts = r[:, None] * np.stack([np.sin(el) * np.cos(az), np.sin(el) * np.sin(az), np.cos(el)], axis=1)
    d = np.linalg.norm(pts - arm.shoulder, axis=1)
    return float(np.mean((d > arm.max_reach) | (d < arm.min_reach)))


@dataclass(frozen=True)
class TargetMargins:
    """How far from the singular configurations :func:`sample_targets` keeps its targets.

    Attributes:
        outer: stay this far inside the outer boundary (stretched arm) [m].
        inner: stay this far outside the inner boundary (folded arm) [m].
        axis: stay this far from the z axis (pan singularity) [m].
        min_height: lowest target height (above the floor) [m].
    """

    outer: float = 0.2
    inner: float = 0.3
    axis: float = 0.3
    min_height: float = 0.1


def sample_targets(rng: np.random.Generator, n: int, margins: TargetMargins = TargetMargins(),
                   arm: Spatial3R = LAB_ARM) -> np.ndarray:
    r"""``n`` targets drawn uniformly (by volume) from the reachable shell, away from singularities.

    A point is kept when :math:`|l_2-l_3| + \text{inner} \le \lVert x - s\rVert \le l_2 + l_3 - \text{outer}`,
    its distance from the :math:`z` axis is at least ``axis`` and its height at least
    ``min_height``; candidates are drawn uniformly in the bounding box and rejected otherwise.
    Returns an array of shape ``(n, 3)``.
    """
    if not isinstance(rng, np.random.Generator):
        raise ValueError("rng must be a numpy Generator, e.g. np.random.default_rng(0)")
    n = int(n)
    if n < 0:
        raise ValueError(f"n must be non-negative, got {n}")
    r_out = arm.max_reach - margins.outer
    r_in = arm.min_reach + margins.inner
    if r_out <= r_in or margins.axis >= r_out:
        raise ValueError(f"the margins {margins} leave no reachable target for {arm}")
    out = np.empty((n, 3))
    filled = 0
    lo = arm.shoulder - r_out
    hi = arm.shoulder + r_out
    while filled < n:
        cand = rng.uniform(lo, hi, size=(max(64, 2 * (n - filled)), 3))
        d = np.linalg.norm(cand - arm.shoulder, axis=1)
        keep = ((d >= r_in) & (d <= r_out) & (np.hypot(cand[:, 0], cand[:, 1]) >= margins.axis)
                & (cand[:, 2] >= margins.min_height))
        cand = cand[keep][: n - filled]
        out[filled:filled + len(cand)] = cand
        filled += len(cand)
    return out
