r"""Reference trajectories. Each returns a :class:`Reference` of position, velocity and
acceleration, so feedforward and feedback read from one consistent source.

Scalars in, scalars out; arrays of times in, arrays out (vectorised with NumPy).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np


class Reference(NamedTuple):
    """Desired position, velocity and acceleration at one time (or many)."""

    pos: np.ndarray | float
    vel: np.ndarray | float
    acc: np.ndarray | float


def versine(t, c: float, amplitude: float = np.pi / 4) -> Reference:
    r"""Raised-cosine move of the lab's feedforward tasks, for :math:`0 \le t \le \pi`:

    .. math:: \theta_d = c - A\cos t,\quad \dot\theta_d = A\sin t,\quad \ddot\theta_d = A\cos t

    with :math:`A = \pi/4`: it starts and ends at rest, :math:`2A` apart.
    """
    t = np.asarray(t, dtype=float)
    return Reference(c - amplitude * np.cos(t), amplitude * np.sin(t), amplitude * np.cos(t))


def sinusoid(t, amplitude: float = np.pi / 4, omega: float = 1.0) -> Reference:
    r"""Sinusoidal joint reference :math:`\theta_d = A\sin\omega t` and its derivatives

    .. math:: \dot\theta_d = A\omega\cos\omega t,\qquad \ddot\theta_d = -A\omega^2\sin\omega t
    """
    t = np.asarray(t, dtype=float)
    s, c = np.sin(omega * t), np.cos(omega * t)
    return Reference(amplitude * s, amplitude * omega * c, -amplitude * omega**2 * s)


def circle_basis(normal) -> tuple[np.ndarray, np.ndarray]:
    r"""Two orthonormal vectors :math:`u, v` spanning the plane with the given normal.

    :math:`u = n \times r / \lVert n \times r\rVert` with :math:`r = e_z` (or :math:`e_x` when
    :math:`n` is nearly vertical) and :math:`v = n \times u`, as in the lab.
    """
    n = np.asarray(normal, dtype=float)
    if n.shape != (3,) or not np.all(np.isfinite(n)) or np.linalg.norm(n) == 0:
        raise ValueError(f"normal must be a finite, non-zero 3-vector, got {normal!r}")
    n = n / np.linalg.norm(n)
    ref = np.array([0.0, 0.0, 1.0]) if abs(n[2]) < 0.9 else np.array([1.0, 0.0, 0.0])
    u = np.cross(n, ref)
    u /= np.linalg.norm(u)
    return u, np.cross(n, u)


def circle_2d(t, center, radius: float, period: float) -> Reference:
    r"""Planar circle :math:`x_d = c + \rho(\cos\Omega t, \sin\Omega t)`, :math:`\Omega = 2\pi/T`.

    Velocity :math:`\rho\Omega(-\sin, \cos)`, acceleration :math:`-\rho\Omega^2(\cos, \sin)`.
    Arrays of ``t`` give arrays of shape ``(len(t), 2)``.
    """
    t = np.asarray(t, dtype=float)
    w = 2 * np.pi / period
    c, s = np.cos(w * t), np.sin(w * t)
    center = np.asarray(center, dtype=float)
    pos = center + radius * np.stack([c, s], axis=-1)
    vel = radius * w * np.stack([-s, c], axis=-1)
    acc = -radius * w**2 * np.stack([c, s], axis=-1)
    return Reference(pos, vel, acc)


def circle_3d(t, center, radius: float, normal, frequency: float) -> Reference:
    r"""Circle in 3-D: :math:`x_d = c + \rho(\cos\Omega t\,u + \sin\Omega t\,v)`, :math:`\Omega = 2\pi f`,

    with :math:`u, v` from :func:`circle_basis`. Velocity and acceleration are the exact
    derivatives. Arrays of ``t`` give arrays of shape ``(len(t), 3)``.
    """
    t = np.asarray(t, dtype=float)
    u, v = circle_basis(normal)
    w = 2 * np.pi * frequency
    c, s = np.cos(w * t)[..., None], np.sin(w * t)[..., None]
    center = np.asarray(center, dtype=float)
    pos = center + radius * (c * u + s * v)
    vel = radius * w * (-s * u + c * v)
    acc = -radius * w**2 * (c * u + s * v)
    return Reference(pos, vel, acc)
