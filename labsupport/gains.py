r"""PD gain design for a joint :math:`M\ddot\theta + b\dot\theta = \tau` and for computed torque.

Closing :math:`\tau = K_p e + K_d \dot e` around the joint gives the error dynamics

.. math:: M\ddot e + (b + K_d)\dot e + K_p e = 0
   \;\Longleftrightarrow\; \ddot e + 2\zeta\omega_n\dot e + \omega_n^2 e = 0,
   \qquad \omega_n = \sqrt{K_p/M},\; \zeta = \frac{b + K_d}{2\sqrt{K_p M}}.

Computed torque cancels :math:`M` and :math:`b`, so its gains act on a unit mass:
:math:`K_p = \omega_n^2`, :math:`K_d = 2\zeta\omega_n` (:func:`ct_gains`).
"""

from __future__ import annotations

import warnings
from typing import NamedTuple

import numpy as np

from labsupport import metrics, validate


class Gains(NamedTuple):
    """Proportional and derivative gains."""

    Kp: float
    Kd: float


class SecondOrder(NamedTuple):
    """Natural frequency [rad/s] and damping ratio of a second-order error response."""

    wn: float
    zeta: float


def _positive(name: str, value: float) -> float:
    return validate.number(name, value, positive=True)


def _non_negative(name: str, value: float) -> float:
    return validate.number(name, value, nonnegative=True)


def pd_gains(M: float, b: float, wn: float, zeta: float) -> Gains:
    r"""Gains that place the joint's error poles: :math:`K_p = M\omega_n^2`, :math:`K_d = 2\zeta\omega_n M - b`.

    Raises ``ValueError`` when the friction alone already damps more than asked
    (:math:`K_d < 0`).

    Example: the lab's joint (:math:`M = 0.5` kg·m², :math:`b = 0.1` N·m·s/rad), critically
    damped at 10 rad/s:

    >>> pd_gains(0.5, 0.1, wn=10.0, zeta=1.0)
    Gains(Kp=50.0, Kd=9.9)
    """
    M, wn = _positive("M", M), _positive("wn", wn)
    b, zeta = _non_negative("b", b), _non_negative("zeta", zeta)
    Kd = 2 * zeta * wn * M - b
    if Kd < 0:
        raise ValueError(
            f"zeta={zeta:g} with wn={wn:g} needs Kd={Kd:.3g} < 0: friction b={b:g} already "
            "damps more than that; raise wn or zeta"
        )
    return Gains(M * wn**2, Kd)


def second_order(M: float, b: float, Kp: float, Kd: float) -> SecondOrder:
    r"""Inverse of :func:`pd_gains`: :math:`\omega_n = \sqrt{K_p/M}`, :math:`\zeta = (b + K_d)/(2\sqrt{K_p M})`.

    Example: the gains of :func:`pd_gains`'s example give back its design.

    >>> wn, zeta = second_order(0.5, 0.1, Kp=50.0, Kd=9.9)
    >>> print(f"wn = {wn:.3f} rad/s, zeta = {zeta:.3f}")
    wn = 10.000 rad/s, zeta = 1.000
    """
    M, Kp = _positive("M", M), _positive("Kp", Kp)
    b, Kd = _non_negative("b", b), validate.number("Kd", Kd)
    return SecondOrder(np.sqrt(Kp / M), (b + Kd) / (2 * np.sqrt(Kp * M)))


def actuator_limited_gains(M: float, b: float, tau_max: float, initial_error: float) -> Gains:
    r"""Method 1: the largest :math:`K_p` whose step torque stays within the actuator, then :math:`\zeta = 1`.

    The PD torque peaks at :math:`t = 0`, :math:`\tau_0 = K_p e_0`, so
    :math:`K_p = \tau_{\max}/|e_0|` and :math:`K_d = 2\sqrt{K_p M} - b` (critical damping).
    """
    tau_max = _positive("tau_max", tau_max)
    e0 = _positive("|initial_error|", abs(validate.number("initial_error", initial_error)))
    Kp = tau_max / e0
    return pd_gains(M, b, np.sqrt(Kp / _positive("M", M)), 1.0)


def damping_for_overshoot(percent_overshoot: float) -> float:
    r"""Damping ratio giving a step overshoot of :math:`\%OS`:

    .. math:: \zeta = \frac{-\ln(\%OS/100)}{\sqrt{\pi^2 + \ln^2(\%OS/100)}}

    Example: 10 % overshoot, the lab's Method 2 specification.

    >>> print(f"{damping_for_overshoot(10.0):.4f}")
    0.5912
    """
    os = validate.number("percent_overshoot", percent_overshoot)
    if not 0 < os < 100:
        raise ValueError(f"percent_overshoot must be in (0, 100), got {percent_overshoot!r}")
    if os < 1:  # a fraction (0.1 for 10 %), as band= takes it, reads as a tenth of a percent here
        warnings.warn(
            f"percent_overshoot = {os:g} asks for {os:g} %, a nearly critically damped joint; it is a "
            f"percentage: {100 * os:g} for {100 * os:g} %",
            RuntimeWarning,
            stacklevel=2,
        )
    ln = np.log(os / 100)
    return float(-ln / np.sqrt(np.pi**2 + ln**2))


def frequency_for_settling(zeta: float, settling_time: float) -> float:
    r"""Natural frequency for a 2 % settling time with the envelope rule :math:`t_s \approx 4/(\zeta\omega_n)`.

    This is the lab's rule. It is the time the envelope :math:`e^{-\zeta\omega_n t}` needs to
    fall to about 2 %; the response itself can settle earlier. :func:`exact_settling_frequency`
    gives the frequency for which the simulated response settles at exactly ``settling_time``.
    The rule is made for :math:`\zeta < 1`: at :math:`\zeta = 1` (critical damping) the response
    takes about :math:`5.8/\omega_n`, not :math:`4/\omega_n`, so there the rule's
    :math:`\omega_n` is about 30 % too low; use :func:`exact_settling_frequency`.

    Example: critical damping and a 2 s settling time, by the rule and exactly.

    >>> print(f"{frequency_for_settling(1.0, 2.0):.2f} rad/s, exactly {exact_settling_frequency(1.0, 2.0):.2f} rad/s")
    2.00 rad/s, exactly 2.92 rad/s
    """
    return 4.0 / (_positive("zeta", zeta) * _positive("settling_time", settling_time))


def spec_gains(M: float, b: float, percent_overshoot: float, settling_time: float) -> tuple[Gains, SecondOrder]:
    r"""Method 2: gains from a percent overshoot and a 2 % settling time (lab's rule).

    :math:`\zeta` from :func:`damping_for_overshoot`, :math:`\omega_n = 4/(\zeta t_s)`, then
    :func:`pd_gains`. Returns the gains and the (wn, zeta) they were designed for.

    Example: the lab's Method 2, 10 % overshoot and a 2 s settling time on its joint.

    >>> (Kp, Kd), (wn, zeta) = spec_gains(0.5, 0.1, percent_overshoot=10.0, settling_time=2.0)
    >>> print(f"Kp = {Kp:.3f} N·m/rad, Kd = {Kd:.3f} N·m·s/rad (wn = {wn:.3f} rad/s, zeta = {zeta:.3f})")
    Kp = 5.723 N·m/rad, Kd = 1.900 N·m·s/rad (wn = 3.383 rad/s, zeta = 0.591)
    """
    zeta = damping_for_overshoot(percent_overshoot)
    wn = frequency_for_settling(zeta, settling_time)
    return pd_gains(M, b, wn, zeta), SecondOrder(wn, zeta)


def step_settling_time(wn: float, zeta: float, band: float = 0.02) -> float:
    r"""Exact settling time of the unit step response of
    :math:`\ddot y + 2\zeta\omega_n\dot y + \omega_n^2 y = \omega_n^2`.

    The last instant :math:`|1 - y(t)| > \text{band}`, found on the closed-form response (no
    envelope approximation). Scales as :math:`1/\omega_n`. The response is searched over
    :math:`\max(12, \ln(1/\text{band}) + 8)` time constants of its slowest mode (twelve for
    bands of 2 % and wider),
    :math:`1/(\zeta\omega_n)` up to critical damping and
    :math:`1/\big(\omega_n(\zeta - \sqrt{\zeta^2 - 1})\big)` beyond, which an overdamped joint
    needs (at :math:`\zeta = 3` it settles about 17 times later than :math:`4/(\zeta\omega_n)`).
    """
    wn, zeta, band = _positive("wn", wn), _positive("zeta", zeta), validate.band(band)
    slowest = zeta * wn if zeta <= 1 else -metrics.overdamped_poles(wn, zeta)[0]  # decay rate of the slowest mode
    t = np.linspace(0.0, max(12.0, np.log(1 / band) + 8.0) / slowest + 10.0 / wn, 200_001)
    return metrics.settling_time(t, metrics.second_order_step(t, wn, zeta), final=1.0, initial=0.0, band=band)


def exact_settling_frequency(zeta: float, settling_time: float, band: float = 0.02) -> float:
    r""":math:`\omega_n` for which the step response settles (within ``band``) at exactly ``settling_time``.

    Because the settling time scales as :math:`1/\omega_n`,
    :math:`\omega_n = \omega_1\,t_s(\omega_1)/t_s` with :math:`\omega_1 = 1`.
    """
    return step_settling_time(1.0, zeta, band) / _positive("settling_time", settling_time)


def ct_gains(wn: float, zeta: float) -> Gains:
    r"""Computed-torque gains for the unit-mass error dynamics :math:`\ddot e + K_d\dot e + K_p e = 0`:
    :math:`K_p = \omega_n^2`, :math:`K_d = 2\zeta\omega_n`.

    Example: the Problems' design, :math:`\omega_n = 10` rad/s, :math:`\zeta = 0.9`.

    >>> ct_gains(10.0, 0.9)
    Gains(Kp=100.0, Kd=18.0)
    """
    wn, zeta = _positive("wn", wn), _non_negative("zeta", zeta)
    return Gains(wn**2, 2 * zeta * wn)
