r"""Reference trajectories. Each returns a :class:`Reference` of position, velocity and
acceleration, so feedforward and feedback read from one consistent source.

Scalars in, scalars out; arrays of times in, arrays out (vectorised with NumPy).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from functools import cached_property
from typing import NamedTuple

import numpy as np

from labsupport import validate


class Reference(NamedTuple):
    """Desired position, velocity and acceleration at one time (or many)."""

    pos: np.ndarray | float
    vel: np.ndarray | float
    acc: np.ndarray | float


def evaluate(reference: Callable, t) -> Reference:
    """``reference(t)`` with its parts as float arrays; a ``ValueError`` that says what to return
    when the function returns anything but a :class:`Reference` (a bare position array would
    otherwise be read as position, velocity and acceleration, one per entry)."""
    validate.function("reference", reference, validate.REFERENCE)
    result = reference(t)
    if not isinstance(result, Reference):
        raise ValueError(
            "a reference function must return trajectories.Reference(pos, vel, acc), the desired "
            f"position, velocity and acceleration at t, but it returned {type(result).__name__} "
            f"{validate.short(result)}; for a fixed target x use Reference(x, np.zeros_like(x), np.zeros_like(x))"
        )
    return Reference(*(np.asarray(part, dtype=float) for part in result))


def set_point(t, point) -> Reference:
    r"""A fixed target: :math:`x_d = p`, :math:`\dot x_d = \ddot x_d = 0` at every time.

    ``point`` is a position of any dimension ``d``; arrays of ``t`` give arrays of shape
    ``(len(t), d)``, as the moving references do, so a run logs its error to a set point the
    same way.

    >>> print(set_point([0.0, 1.0], (1.0, 0.0, 2.0)).pos)
    [[1. 0. 2.]
     [1. 0. 2.]]
    """
    t = validate.times(t)
    point = validate.vector("point", point, None)
    if point.ndim != 1:
        raise ValueError(f"point must be one position, a 1-D array, got shape {point.shape}")
    pos = np.broadcast_to(point, t.shape + point.shape).copy()
    return Reference(pos, np.zeros_like(pos), np.zeros_like(pos))


def versine(t, c: float, amplitude: float = np.pi / 4) -> Reference:
    r"""Raised-cosine move of the lab's feedforward tasks, for :math:`0 \le t \le \pi`:

    .. math:: \theta_d = c - A\cos t,\quad \dot\theta_d = A\sin t,\quad \ddot\theta_d = A\cos t

    with :math:`A = \pi/4`: it starts and ends at rest, :math:`2A` apart.

    Example: about :math:`c = 0`, from -45° to +45°, at rest at both ends.

    >>> ref = versine(np.array([0.0, np.pi]), c=0.0)
    >>> print(np.degrees(ref.pos), np.round(ref.vel, 12))
    [-45.  45.] [0. 0.]
    """
    t = validate.times(t)
    c, amplitude = validate.number("c", c), validate.number("amplitude", amplitude)
    return Reference(c - amplitude * np.cos(t), amplitude * np.sin(t), amplitude * np.cos(t))


def sinusoid(t, amplitude: float = np.pi / 4, omega: float = 1.0) -> Reference:
    r"""Sinusoidal joint reference :math:`\theta_d = A\sin\omega t` and its derivatives

    .. math:: \dot\theta_d = A\omega\cos\omega t,\qquad \ddot\theta_d = -A\omega^2\sin\omega t
    """
    t = validate.times(t)
    amplitude, omega = validate.number("amplitude", amplitude), validate.number("omega", omega)
    s, c = np.sin(omega * t), np.cos(omega * t)
    return Reference(amplitude * s, amplitude * omega * c, -amplitude * omega**2 * s)


def circle_basis(normal) -> tuple[np.ndarray, np.ndarray]:
    r"""Two orthonormal vectors :math:`u, v` spanning the plane with the given normal.

    :math:`u = n \times r / \lVert n \times r\rVert` with :math:`r = e_z` (or :math:`e_x` when
    :math:`n` is nearly vertical) and :math:`v = n \times u`, as in the lab.
    """
    n = validate.vector("normal", normal, (3,))
    if not n.any():
        raise ValueError(f"normal must be a non-zero 3-vector, got {normal!r}")
    n = n / np.abs(n).max()  # first to the order of 1: the norm of 1e200 or 1e-320 entries overflows or vanishes
    n = n / np.linalg.norm(n)
    ref = np.array([0.0, 0.0, 1.0]) if abs(n[2]) < 0.9 else np.array([1.0, 0.0, 0.0])
    u = np.cross(n, ref)
    u /= np.linalg.norm(u)
    return u, np.cross(n, u)


def circle_2d(t, center, radius: float, period: float) -> Reference:
    r"""Planar circle :math:`x_d = c + \rho(\cos\Omega t, \sin\Omega t)`, :math:`\Omega = 2\pi/T`.

    Velocity :math:`\rho\Omega(-\sin, \cos)`, acceleration :math:`-\rho\Omega^2(\cos, \sin)`.
    Arrays of ``t`` give arrays of shape ``(len(t), 2)``.

    Example: a circle of radius 0.15 m about (0.5, 0.2) m, one turn in 6 s, starts at its
    point of largest :math:`x`, moving at :math:`2\pi\rho/T` = 0.157 m/s.

    >>> ref = circle_2d(0.0, center=(0.5, 0.2), radius=0.15, period=6.0)
    >>> print(ref.pos, f"{np.linalg.norm(ref.vel):.4f} m/s")
    [0.65 0.2 ] 0.1571 m/s
    """
    t = validate.times(t)
    center = validate.vector("center", center, (2,))
    radius = validate.number("radius", radius, positive=True)
    w = 2 * np.pi / validate.number("period", period, positive=True)
    c, s = np.cos(w * t), np.sin(w * t)
    pos = center + radius * np.stack([c, s], axis=-1)
    vel = radius * w * np.stack([-s, c], axis=-1)
    acc = -radius * w**2 * np.stack([c, s], axis=-1)
    return Reference(pos, vel, acc)


def circle_3d(t, center, radius: float, normal, frequency: float) -> Reference:
    r"""Circle in 3-D: :math:`x_d = c + \rho(\cos\Omega t\,u + \sin\Omega t\,v)`, :math:`\Omega = 2\pi f`,

    with :math:`u, v` from :func:`circle_basis`. Velocity and acceleration are the exact
    derivatives. Arrays of ``t`` give arrays of shape ``(len(t), 3)``.
    """
    t = validate.times(t)
    center = validate.vector("center", center, (3,))
    radius = validate.number("radius", radius, positive=True)
    u, v = circle_basis(normal)
    w = 2 * np.pi * validate.number("frequency", frequency, positive=True)
    c, s = np.cos(w * t)[..., None], np.sin(w * t)[..., None]
    pos = center + radius * (c * u + s * v)
    vel = radius * w * (-s * u + c * v)
    acc = -radius * w**2 * (c * u + s * v)
    return Reference(pos, vel, acc)


@dataclass(frozen=True)
class SampledReference:
    r"""A reference sampled once on a control grid :math:`t_k = k\,\Delta t`, read by index.

    A controller that runs every :math:`\Delta t` reads row :math:`k` of three arrays instead
    of evaluating the reference each step (:func:`sample` builds it). ``at(t)`` returns the
    rows of the grid point nearest ``t`` (views, no copy, gathered once on first use: change the
    arrays before that, not after); calling the object on an array of
    grid times returns a :class:`Reference` of arrays, so it also serves as the ``reference``
    of :func:`labsupport.sim.simulate`.

    Attributes:
        dt: grid spacing [s].
        pos, vel, acc: ``(N,)`` or ``(N, d)`` samples; row ``k`` belongs to :math:`t_k + \text{offset}`.
        offset: the reference was evaluated at :math:`t_k + \text{offset}` [s].
    """

    dt: float
    pos: np.ndarray
    vel: np.ndarray
    acc: np.ndarray
    offset: float = 0.0

    def __post_init__(self):
        object.__setattr__(self, "dt", validate.number("dt", self.dt, positive=True))  # floats, as SingleJoint's
        object.__setattr__(self, "offset", validate.number("offset", self.offset))
        counts = {name: len(np.atleast_1d(getattr(self, name))) for name in ("pos", "vel", "acc")}
        if len(set(counts.values())) != 1:
            raise ValueError(f"pos, vel and acc must hold one sample per grid time each, got {counts} samples")

    def index(self, t) -> int:
        """Index of the grid point nearest ``t``; ``ValueError`` for a time that is not a finite
        number or lies past the sampled span."""
        k = math.floor(validate.number("t", t) / self.dt + 0.5)
        if not 0 <= k < len(self.pos):
            raise ValueError(
                f"t = {t!r} s is outside the sampled reference "
                f"[0, {(len(self.pos) - 1) * self.dt:.6g}] s; sample a longer duration"
            )
        return k

    def at(self, t) -> Reference:
        """``Reference(pos, vel, acc)`` at the grid point nearest ``t``."""
        try:
            k = math.floor(t / self.dt + 0.5)  # to the nearest, halves up (int() would take -0.9 to 0)
        except (TypeError, ValueError, OverflowError):  # not a finite number
            k = -1
        rows = self.rows
        if not 0 <= k < len(rows):
            k = self.index(t)  # the careful path: raises, saying why
        return rows[k]

    @cached_property
    def rows(self) -> list[Reference]:
        """Row :math:`k` of each array as one :class:`Reference` of views, made once on first use,
        so that reading a row inside a control loop costs one list index."""
        return [Reference(*row) for row in zip(self.pos, self.vel, self.acc, strict=True)]

    def __call__(self, t) -> Reference:
        """The samples at the grid times ``t`` (a float or an array of them)."""
        k = np.floor(validate.times(t) / self.dt + 0.5).astype(int)  # as at(): halves up
        if np.any((k < 0) | (k >= len(self.pos))):
            raise ValueError(f"some times are outside the sampled reference [0, {(len(self.pos) - 1) * self.dt:.6g}] s")
        return Reference(self.pos[k], self.vel[k], self.acc[k])


def sample(
    reference: Callable[[np.ndarray], Reference], dt: float, duration: float, offset: float = 0.0
) -> SampledReference:
    r"""Sample ``reference(t)`` on :math:`t_k = k\,\Delta t + \text{offset}`, :math:`k = 0, 1, \dots, n + 1`
    with :math:`n` = ``round(duration / dt)``: one step past ``duration`` (the lab's loops take
    one step more than ``duration / dt``).

    ``reference`` returns a :class:`Reference`. It is called once on the array of times (all
    references of this module are vectorised); one that only takes a float is called once per
    time instead.
    """
    dt = validate.number("dt", dt, positive=True)
    duration = validate.number("duration", duration, nonnegative=True)
    offset = validate.number("offset", offset)
    validate.function("reference", reference, validate.REFERENCE)
    if 0 < duration < dt:
        raise ValueError(
            f"duration ({duration:g} s) is shorter than one time step dt ({dt:g} s): the arguments are "
            "sample(reference, dt, duration)"
        )
    n = validate.steps(duration, dt) if duration > 0 else 0
    t = np.arange(n + 2) * dt + offset
    try:
        ref = evaluate(reference, t)
        if ref.pos.shape[:1] != t.shape:
            raise ValueError
    except (ValueError, TypeError):
        rows = [evaluate(reference, float(tk)) for tk in t]
        ref = Reference(*(np.array(parts) for parts in zip(*rows, strict=True)))
    return SampledReference(dt, *(np.ascontiguousarray(a) for a in ref), offset)


def within_reach(reference: SampledReference, anchor, radius: float) -> SampledReference:
    r"""The sampled ``reference`` with every point farther than ``radius`` from ``anchor`` pulled
    back onto that sphere,

    .. math:: x \leftarrow a + r\,\frac{x - a}{\lVert x - a\rVert}\quad\text{where}\quad \lVert x - a\rVert > r,

    and its velocity and acceleration recomputed by finite differences on the grid (second
    order, at the ends too) within two samples of a pulled-back point, so the feedforward
    matches the path that is actually tracked. Elsewhere every sample keeps its position,
    velocity and acceleration; a reference that is within reach everywhere comes back as it is.
    """
    if not isinstance(reference, SampledReference):
        raise ValueError(
            f"within_reach takes a sampled reference (trajectories.sample(...)), got {type(reference).__name__}"
        )
    if np.ndim(reference.pos) != 2:
        raise ValueError(
            "within_reach takes a reference of points, positions of shape (N, d); this one samples a "
            "single number per time"
        )
    anchor = validate.vector("anchor", anchor, (np.shape(reference.pos)[-1],))
    radius = validate.number("radius", radius, positive=True)
    offset = reference.pos - anchor
    dist = np.linalg.norm(offset, axis=-1, keepdims=True)
    outside = dist > radius
    if not outside.any():
        return reference
    pos = np.where(outside, anchor + offset * (radius / np.maximum(dist, 1e-12)), reference.pos)
    near = np.convolve(outside[:, 0], np.ones(5), mode="same")[:, None] > 0  # within two samples
    vel = np.gradient(pos, reference.dt, axis=0, edge_order=2)
    acc = np.gradient(vel, reference.dt, axis=0, edge_order=2)
    vel, acc = np.where(near, vel, reference.vel), np.where(near, acc, reference.acc)
    return SampledReference(reference.dt, pos, vel, acc, reference.offset)
