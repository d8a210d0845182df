r"""Performance measures: RMS error, cumulative effort, overshoot, settling time, the
closed-form second-order step response they are checked against, and the measures of a run's
:class:`labsupport.sim.Log` (position and orientation error, peak torque, saturation)."""

from __future__ import annotations

import warnings

import mujoco
import numpy as np
from scipy.integrate import cumulative_trapezoid

from labsupport import validate


def _samples(error) -> np.ndarray:
    """``error`` as a float array with at least one sample, or a ``ValueError``."""
    if error is None:
        raise ValueError("no error to take the RMS of (got None)")
    if validate.is_run_log(error):
        raise ValueError("the RMS is taken of an error, not of a whole Log: pass log.err (or a column of it)")
    validate.not_text("error", error)
    if isinstance(error, (list, tuple)) and any(value is None for value in error):
        raise ValueError(f"the RMS is taken of numbers, but the error holds None: {validate.short(error)}")
    values = validate.floats(error)
    if values is None:
        raise ValueError(f"the RMS is taken of numbers, got {validate.short(error)}")
    error = values
    if error.ndim == 0:
        raise ValueError(f"the RMS is taken over samples, an array of them; got the single number {error}")
    if error.size == 0 and error.ndim == 2 and len(error):
        raise ValueError(
            f"the error has {len(error)} samples of no component (shape {error.shape}): a run's log.err "
            "holds an error only when simulate was given site= and reference="
        )
    if error.size == 0:
        raise ValueError(
            f"no samples to take the RMS of (an empty array of shape {error.shape}); with "
            "after=..., check that the run lasts beyond it"
        )
    return error


def rms(error, axis=0):
    r"""Root mean square :math:`\sqrt{\tfrac1N\sum_k e_k^2}` along ``axis`` (per component)."""
    error = _samples(error)
    return np.sqrt(np.mean(error**2, axis=axis))


def rms_norm(error):
    r"""RMS of the error vector's norm, :math:`\sqrt{\tfrac1N\sum_k \lVert e_k\rVert^2}`, for ``(N, d)``
    errors; ``(N,)`` errors are N samples of one component (the norm of each is its size).

    Example: two planar errors of 5 mm each, in different directions.

    >>> rms_norm([[0.003, 0.004], [0.0, -0.005]])
    0.005
    """
    error = _samples(error)
    if error.ndim == 1:  # one component per sample, not one vector
        error = error[:, None]
    return float(np.sqrt(np.mean(np.sum(error**2, axis=-1))))


def cumulative_effort(t, tau):
    r"""Cumulative control effort :math:`E(t) = \int_0^t \lVert\tau\rVert^2\,dt'` (trapezoidal rule).

    ``tau`` is ``(N,)`` or ``(N, nu)``; the squared norm sums the joints.
    """
    t, tau = validate.times(t, increasing=True), validate.vector("tau", tau, None)
    if t.ndim != 1 or tau.ndim not in (1, 2) or len(tau) != len(t):
        raise ValueError(
            f"cumulative_effort needs one torque per time: t of shape (N,) and tau of shape (N,) or (N, nu), "
            f"got t of shape {t.shape} and tau of shape {tau.shape}"
        )
    sq = tau**2 if tau.ndim == 1 else np.sum(tau**2, axis=1)
    return cumulative_trapezoid(sq, t, initial=0.0)


def _step_response(y, t=None) -> tuple[np.ndarray, np.ndarray | None]:
    """A step response as float arrays: ``y`` one-dimensional with at least one sample and, if
    given, times ``t`` of the same length; a ``ValueError`` otherwise."""
    values = validate.floats(y)
    if values is None:
        raise ValueError(f"a step response is numbers, one per sample, got y = {validate.short(y)}")
    y = values
    t = None if t is None else validate.times(t, increasing=True)
    if y.ndim != 1:
        raise ValueError(
            f"a step response is one coordinate over time (a 1-D array), got y of shape {y.shape}; "
            "pick one column, for example log.q[:, 0]"
        )
    if y.size == 0:
        raise ValueError("the step response has no samples (y is empty)")
    if t is not None and t.shape != y.shape:
        raise ValueError(f"t and y must have one time per sample, got t of shape {t.shape} and y of shape {y.shape}")
    if not np.isfinite(y).all():
        raise ValueError(
            "the step response holds NaN or inf (did the run diverge?); its overshoot and settling time are undefined"
        )
    return y, t


def overshoot(y, final: float, initial: float) -> float:
    r"""Percent overshoot of a step response, :math:`100\,\max_t (y - y_f)/(y_f - y_0)`, 0 if none."""
    y, _ = _step_response(y)
    span = validate.number("final", final) - validate.number("initial", initial)
    if span == 0:
        raise ValueError("final and initial are equal: a step of zero size has no overshoot")
    _warn_swapped(y, final, initial)
    return max(0.0, 100.0 * float(np.max((y - final) / span)))


def _warn_swapped(y: np.ndarray, final: float, initial: float) -> bool:
    """A ``RuntimeWarning`` where the response starts nearer ``final`` than ``initial`` and ends
    nearer ``initial``: the two given the other way round (the order is ``final, initial``) gave
    an overshoot of 0 and a settling time of NaN, numbers that look like a result. (A record that
    starts already near ``final`` and stays there is a response that has settled.) Returns
    whether it warned."""
    swapped = abs(y[0] - final) < abs(y[0] - initial) and abs(y[-1] - initial) < abs(y[-1] - final)
    if swapped:
        warnings.warn(
            f"the response goes from {y[0]:.4g} to {y[-1]:.4g}, from near final = {final:.4g} to near "
            f"initial = {initial:.4g}: are the two swapped? The order is (y, final, initial), final being "
            "the value it steps to",
            RuntimeWarning,
            stacklevel=3,
        )
    return swapped


def settling_time(t, y, final: float, initial: float, band: float = 0.02) -> float:
    r"""First time after which :math:`|y - y_f| \le \text{band}\,|y_f - y_0|` for good.

    Returns ``nan``, with a ``RuntimeWarning`` that says so, if the response is still outside
    the band at the end of the record.
    """
    y, t = _step_response(y, validate.times(t))
    final, initial = validate.number("final", final), validate.number("initial", initial)
    band = validate.band(band)
    if final == initial:
        raise ValueError("final and initial are equal: a step of zero size has no settling time")
    swapped = _warn_swapped(y, final, initial)
    outside = np.abs(y - final) > band * abs(final - initial)
    if not outside.any():
        return float(t[0])
    last = int(np.flatnonzero(outside)[-1])
    if last == len(t) - 1:
        if swapped:  # said already, and the likelier reason
            return float("nan")
        warnings.warn(
            f"settling_time: the response is still outside its ±{100 * band:g} % band at the end of the record "
            f"(t = {t[-1]:.4g} s), so it has no settling time there (NaN): record longer, or check that it "
            "settles at all",
            RuntimeWarning,
            stacklevel=2,
        )
        return float("nan")
    # interpolate the band crossing between the last sample outside and the next one inside
    e0, e1 = abs(y[last] - final), abs(y[last + 1] - final)
    lim = band * abs(final - initial)
    frac = (e0 - lim) / (e0 - e1) if e0 != e1 else 0.0
    return float(t[last] + frac * (t[last + 1] - t[last]))


def _natural_frequency_and_damping(wn, zeta) -> tuple[float, float]:
    r""":math:`\omega_n > 0` and :math:`\zeta \ge 0` checked: the closed forms below are those of a
    stable second-order system (a negative :math:`\zeta` grows without bound, and
    :math:`\zeta \le -1` gave NaN)."""
    return validate.number("wn", wn, positive=True), validate.number("zeta", zeta, nonnegative=True)


def second_order_step(t, wn: float, zeta: float):
    r"""Closed-form unit step response of :math:`\ddot y + 2\zeta\omega_n\dot y + \omega_n^2 y = \omega_n^2 u(t)`.

    Underdamped (:math:`\zeta<1`): :math:`y = 1 - e^{-\zeta\omega_n t}\left(\cos\omega_d t +
    \frac{\zeta}{\sqrt{1-\zeta^2}}\sin\omega_d t\right)`, :math:`\omega_d = \omega_n\sqrt{1-\zeta^2}`;
    critical: :math:`y = 1 - (1+\omega_n t)e^{-\omega_n t}`; overdamped: sum of two exponentials.

    Example: at :math:`\zeta = 0.5` the overshoot is :math:`100\,e^{-\pi\zeta/\sqrt{1-\zeta^2}}`
    = 16.30 %, and the response settles (2 % band) at 4.04 s, close to the envelope rule's
    :math:`4/(\zeta\omega_n)` = 4 s.

    >>> t = np.linspace(0.0, 10.0, 100_001)
    >>> y = second_order_step(t, wn=2.0, zeta=0.5)
    >>> print(f"{overshoot(y, final=1.0, initial=0.0):.2f} %, settles at {settling_time(t, y, 1.0, 0.0):.3f} s")
    16.30 %, settles at 4.038 s
    """
    t = validate.times(t)
    wn, zeta = _natural_frequency_and_damping(wn, zeta)
    if zeta < 1:
        wd = wn * np.sqrt(1 - zeta**2)
        return 1 - np.exp(-zeta * wn * t) * (np.cos(wd * t) + zeta / np.sqrt(1 - zeta**2) * np.sin(wd * t))
    if zeta == 1:
        return 1 - (1 + wn * t) * np.exp(-wn * t)
    s1, s2 = overdamped_poles(wn, zeta)
    return 1 + (s2 * np.exp(s1 * t) - s1 * np.exp(s2 * t)) / (s1 - s2)


def overdamped_poles(wn: float, zeta: float) -> tuple[float, float]:
    r"""The two real poles of an overdamped second-order system (:math:`\zeta > 1`), slow then fast:

    .. math:: s_{1,2} = -\omega_n\big(\zeta \mp \sqrt{\zeta^2 - 1}\big)

    :math:`s_1` is computed as :math:`\omega_n^2 / s_2` (their product), since
    :math:`\zeta - \sqrt{\zeta^2 - 1}` cancels to 0 in floating point for a large
    :math:`\zeta` (1e8) while the slow mode still decays; and :math:`\sqrt{\zeta^2 - 1}` as
    :math:`\sqrt{\zeta - 1}\,\sqrt{\zeta + 1}`, whose factors overflow for no finite
    :math:`\zeta`.
    """
    wn, zeta = _natural_frequency_and_damping(wn, zeta)
    if not zeta > 1:
        raise ValueError(f"overdamped poles need a damping ratio zeta > 1, got {zeta!r}")
    s2 = -wn * (zeta + np.sqrt(zeta - 1) * np.sqrt(zeta + 1))
    return wn * (wn / s2), s2


def second_order_error(t, e0, edot0, wn: float, zeta: float):
    r"""Closed-form free response of :math:`\ddot e + 2\zeta\omega_n\dot e + \omega_n^2 e = 0` from
    :math:`e(0)=e_0`, :math:`\dot e(0)=\dot e_0` (any :math:`\zeta>0`); broadcasts over components.
    """
    e0, edot0 = validate.vector("e0", e0, None), validate.vector("edot0", edot0, None)
    if e0.ndim > 1 or edot0.ndim > 1:
        raise ValueError(
            f"e0 and edot0 are a number or one value per component (1-D), got shapes {e0.shape} and {edot0.shape}"
        )
    try:
        e0, edot0 = np.broadcast_arrays(e0, edot0)  # float arrays already (validate.vector)
    except ValueError:
        raise ValueError(
            f"e0 and edot0 must have the same number of components, got shapes {np.shape(e0)} and {np.shape(edot0)}"
        ) from None
    t = validate.times(t)[..., None] if e0.ndim else validate.times(t)
    wn, zeta = _natural_frequency_and_damping(wn, zeta)
    a = zeta * wn
    if zeta < 1:
        wd = wn * np.sqrt(1 - zeta**2)
        return np.exp(-a * t) * (e0 * np.cos(wd * t) + (edot0 + a * e0) / wd * np.sin(wd * t))
    if zeta == 1:
        return np.exp(-wn * t) * (e0 + (edot0 + wn * e0) * t)
    s1, s2 = overdamped_poles(wn, zeta)
    c1 = (edot0 - s2 * e0) / (s1 - s2)
    c2 = e0 - c1
    return c1 * np.exp(s1 * t) + c2 * np.exp(s2 * t)


# ---------------------------------------------------------------------------------------
# Functions of a run's log (labsupport.sim.Log)
# ---------------------------------------------------------------------------------------


def rotation_error(xmat, quat_d, out=None, work=None) -> np.ndarray:
    r"""Rotation error :math:`\log(R R_d^\top)` as a rotation vector [rad] (world frame), from the
    orientation ``xmat`` (3x3 or 9 numbers, row-major) and the target quaternion ``quat_d``
    (w, x, y, z), through quaternions as the lab computes it: :math:`q` of :math:`R`, the product
    :math:`q\,q_d^{-1}`, and its rotation vector. ``out`` is an optional (3,) result and ``work``
    two optional (4,) scratch quaternions.
    """
    quat, quat_d_inv = (np.empty(4), np.empty(4)) if work is None else work
    out = np.empty(3) if out is None else out
    try:
        mujoco.mju_mat2Quat(quat, xmat)  # q of R
    except TypeError:  # a 3x3 matrix or a list: as 9 floats, row-major
        mujoco.mju_mat2Quat(quat, _nine_floats(xmat))
    try:
        mujoco.mju_negQuat(quat_d_inv, quat_d)  # q_d^-1
    except TypeError:
        got = validate.short(quat_d)
        raise ValueError(f"quat_d must be a quaternion (w, x, y, z) of 4 floats, got {got}") from None
    if not abs(mujoco.mju_normalize4(quat_d_inv) - 1.0) <= 1e-6:  # its norm (NaN fails too)
        raise ValueError(f"quat_d must be a unit quaternion (w, x, y, z), got {validate.short(quat_d)}")
    mujoco.mju_mulQuat(quat, quat, quat_d_inv)  # q q_d^-1
    mujoco.mju_quat2Vel(out, quat, 1.0)  # its rotation vector
    return out


def _nine_floats(xmat) -> np.ndarray:
    """An orientation given as a 3x3 matrix (or a list) as the 9 floats MuJoCo reads, row-major,
    or a ``ValueError`` that says what :func:`rotation_error` takes."""
    values = validate.floats(xmat)
    if values is None or values.size != 9:
        got = "not numbers" if values is None else f"shape {values.shape}"
        raise ValueError(
            f"xmat must be a rotation matrix, 3x3 or 9 numbers row-major (data.site_xmat[site]), got {got}"
        )
    return np.ascontiguousarray(values).reshape(9)


def _after(log, after: float) -> np.ndarray:
    """Rows of ``log`` (already checked by :func:`labsupport.validate.run_log`) logged at ``t >= after``."""
    return log.t >= validate.number("after", after)


def rms_position_error(log, after: float = 0.0) -> float:
    r"""RMS of the site's position error norm over ``t >= after`` [m], from ``log.err``."""
    return rms_norm(validate.run_log(log, reference=True).err[_after(log, after)])


def orientation_error(log, quat_d) -> np.ndarray:
    r"""(N, 3) rotation errors :math:`\log(R_k R_d^\top)` of the logged site orientations
    ``log.ee_rot`` against the constant target orientation ``quat_d`` (w, x, y, z) [rad]."""
    if validate.run_log(log).ee_rot.shape[1:] != (3, 3):
        raise ValueError("the log has no site orientation: pass site= to simulate to record one")
    return np.array([rotation_error(rot, quat_d) for rot in validate.run_log(log).ee_rot]).reshape(len(log.t), 3)


def rms_orientation_error(log, quat_d, after: float = 0.0) -> float:
    r"""RMS of the rotation-error angle over ``t >= after`` [rad] (see :func:`orientation_error`)."""
    return rms_norm(orientation_error(log, quat_d)[_after(log, after)])


def peak_torque(log, applied=None) -> np.ndarray:
    r"""Largest :math:`|\tau|` of each actuator over the run: of the asked torque ``log.tau``,
    or of ``applied`` (N, nu), the torque the actuators actually exerted, when given."""
    if applied is None:
        return np.abs(validate.run_log(log).tau).max(axis=0)
    return np.abs(_applied(log, applied)).max(axis=0)


def saturation(log, applied) -> np.ndarray:
    """(N, nu) True where the actuators exerted another torque than the controller asked
    (a force or command limit bound); ``applied`` is the exerted torque, e.g.
    :func:`labsupport.actuators.servo_force` of the log."""
    return ~np.isclose(_applied(log, applied), log.tau, rtol=1e-9, atol=1e-9)


def _applied(log, applied) -> np.ndarray:
    """``applied`` as an array shaped like ``log.tau`` (one exerted torque per step and
    actuator), or a ``ValueError``."""
    applied = validate.vector("applied", applied, None)
    if applied.shape != validate.run_log(log).tau.shape:
        raise ValueError(
            f"applied must hold one exerted torque per step and actuator, shape {log.tau.shape} as log.tau, "
            f"got shape {applied.shape}"
        )
    return applied


def saturation_report(log, applied, names=None) -> str:
    """One sentence on where limits bound (empty when they never did): the share of the steps,
    the first time, and the actuators (``names``, else their indices)."""
    hits = saturation(log, applied)
    if not hits.any():
        return ""
    if isinstance(names, (str, bytes)):  # "ab" would name two actuators "a" and "b"
        raise ValueError(f"names must be a list of names, one per actuator, got the text {names!r}")
    names = [str(i) for i in range(hits.shape[1])] if names is None else [str(name) for name in names]
    if len(names) != hits.shape[1]:
        raise ValueError(f"names must name each of the {hits.shape[1]} actuators, got {len(names)} names")
    joints = [names[i] for i in range(hits.shape[1]) if hits[:, i].any()]
    first = int(np.flatnonzero(hits.any(axis=1))[0])
    return (
        f"Torque or command limits were hit on {100 * hits.any(axis=1).mean():.1f} % of the steps "
        f"(first at t = {log.t[first]:.3f} s; joints {', '.join(joints)}); the actuators applied "
        "the clipped torque."
    )
