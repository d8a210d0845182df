"""Task 1: the analytic single joint, its controllers and gain design, against closed forms."""

import traceback

import numpy as np
import pytest
from scipy.integrate import solve_ivp
from scipy.optimize import brentq

from labsupport import gains, metrics, plants, sim
from labsupport.controllers.single_joint import computed_torque, feedforward_torque, pd_torque, pi_speed_torque
from labsupport.plants import SingleJoint, load_model
from labsupport.sim import RUNAWAY_SPEED, SimulationDiverged
from labsupport.trajectories import Reference, sinusoid, versine

HORIZONTAL = SingleJoint(g=0.0)
VERTICAL = SingleJoint(g=9.81)


def pd_to(theta_d, Kp, Kd):
    """PD to a set-point, as ``torque(t, state)`` for the analytic plant."""
    return lambda t, x: pd_torque(x[0], x[1], theta_d, 0.0, Kp, Kd)


def pd_along(reference, Kp, Kd):
    return lambda t, x: pd_torque(x[0], x[1], reference(t).pos, reference(t).vel, Kp, Kd)


def computed_torque_along(model, reference, Kp, Kd):
    return lambda t, x: computed_torque(model, x[0], x[1], *reference(t), Kp, Kd)


def feedforward_along(model, reference):
    return lambda t, x: feedforward_torque(model, *reference(t))


def test_first_order_step_response_matches_closed_form():
    tau = 1.0
    log = HORIZONTAL.simulate(lambda t, x: tau, 30.0, rtol=1e-11, atol=1e-12)
    tau_c, omega_ss = HORIZONTAL.M / HORIZONTAL.b, tau / HORIZONTAL.b
    expected = omega_ss * (1 - np.exp(-log.t / tau_c))
    assert np.max(np.abs(log.qdot[:, 0] - expected)) < 1e-6
    assert tau_c == pytest.approx(5.0) and omega_ss == pytest.approx(10.0)


def test_free_vertical_arm_settles_hanging_down():
    log = VERTICAL.simulate(lambda t, x: 0.0, 60.0, state0=(np.pi / 3, 0.0))
    assert log.q[:, 0][-1] == pytest.approx(-np.pi / 2, abs=1e-2)
    # energy only decreases under viscous friction
    energy = 0.5 * VERTICAL.M * log.qdot[:, 0] ** 2 + VERTICAL.m * VERTICAL.g * VERTICAL.r * np.sin(log.q[:, 0])
    assert np.all(np.diff(energy) < 1e-9)


def test_pd_meets_overshoot_and_settling_specification():
    zeta = gains.damping_for_overshoot(10.0)
    wn = gains.exact_settling_frequency(zeta, 2.0)
    g = gains.pd_gains(HORIZONTAL.M, HORIZONTAL.b, wn, zeta)
    theta_d = np.pi / 2
    log = HORIZONTAL.simulate(pd_to(theta_d, g.Kp, g.Kd), 8.0, rtol=1e-10, atol=1e-12)
    os = metrics.overshoot(log.q[:, 0], theta_d, 0.0)
    ts = metrics.settling_time(log.t, log.q[:, 0], theta_d, 0.0)
    assert abs(os - 10.0) < 0.5
    assert abs(ts - 2.0) < 0.05 * 2.0


@pytest.mark.parametrize("zeta, wn", [(0.5, 4.0), (1.0, 4.0), (3.0, 4.0), (20.0, 4.0), (0.7, 40.0)])
def test_step_settling_time_matches_an_integrated_response(zeta, wn):
    """The exact settling time, against the ODE integrated numerically (independent of the closed
    form): the last crossing of the 2 % band. Overdamped joints settle on their slow mode, far
    beyond 4/(zeta wn) (before, the search stopped there and returned nan). A stiff joint
    (wn = 40 rad/s) settles in a tenth of a second."""

    def rhs(t, x):
        return [x[1], wn**2 * (1.0 - x[0]) - 2 * zeta * wn * x[1]]

    t_end = 40.0 / (wn * (zeta - np.sqrt(zeta**2 - 1))) if zeta > 1 else 40.0 / (zeta * wn)
    sol = solve_ivp(rhs, (0.0, t_end), [0.0, 0.0], dense_output=True, rtol=1e-11, atol=1e-13)
    t = np.linspace(0.0, t_end, 400_001)
    outside = np.flatnonzero(np.abs(1.0 - sol.sol(t)[0]) > 0.02)
    k = outside[-1]
    crossing = brentq(lambda s: abs(1.0 - sol.sol(s)[0]) - 0.02, t[k], t[k + 1])
    assert gains.step_settling_time(wn, zeta) == pytest.approx(crossing, rel=1e-5)
    assert gains.exact_settling_frequency(zeta, 2.0) == pytest.approx(wn * crossing / 2.0, rel=1e-5)


def test_lab_envelope_rule_settles_early():
    """The lab's t_s = 4/(zeta wn) rule: its 'ts = 2 s' design settles in about 1.75 s."""
    (g, so) = gains.spec_gains(HORIZONTAL.M, HORIZONTAL.b, 10.0, 2.0)
    log = HORIZONTAL.simulate(pd_to(np.pi / 2, g.Kp, g.Kd), 8.0, rtol=1e-10, atol=1e-12)
    ts = metrics.settling_time(log.t, log.q[:, 0], np.pi / 2, 0.0)
    assert ts == pytest.approx(gains.step_settling_time(so.wn, so.zeta), abs=2e-3)
    assert ts < 1.8


def test_step_response_matches_second_order_closed_form():
    g = gains.pd_gains(HORIZONTAL.M, HORIZONTAL.b, 3.0, 0.4)
    log = HORIZONTAL.simulate(pd_to(1.0, g.Kp, g.Kd), 5.0, rtol=1e-10, atol=1e-12)
    assert np.max(np.abs(log.q[:, 0] - metrics.second_order_step(log.t, 3.0, 0.4))) < 1e-7


def test_computed_torque_with_exact_model_tracks_sinusoid():
    g = gains.pd_gains(VERTICAL.M, VERTICAL.b, 2.898, 0.69)
    log = VERTICAL.simulate(computed_torque_along(VERTICAL, sinusoid, g.Kp, g.Kd), 4 * np.pi, state0=sinusoid(0.0)[:2])
    assert np.max(np.abs(log.q[:, 0] - sinusoid(log.t).pos)) < 1e-5


def test_feedforward_with_exact_model_is_perfect_and_wrong_model_drifts():
    ref = lambda t: versine(t, np.pi / 2)  # noqa: E731
    exact = VERTICAL.simulate(feedforward_along(VERTICAL, ref), np.pi, state0=ref(0.0)[:2])
    wrong = VERTICAL.simulate(feedforward_along(SingleJoint(r=0.08, g=9.81), ref), np.pi, state0=ref(0.0)[:2])
    assert np.max(np.abs(exact.q[:, 0] - ref(exact.t).pos)) < 1e-5
    # Under-compensated gravity in the upper half-plane: the link lags (falls behind) the reference.
    assert (wrong.q[:, 0] - ref(wrong.t).pos)[-1] < -0.05


def test_pi_speed_control_matches_closed_form():
    wn, zeta, omega_d = 2.0, 0.8, 3.0
    g = gains.pd_gains(HORIZONTAL.M, HORIZONTAL.b, wn, zeta)  # Kp -> Ki, Kd -> Kp for PI
    Kp, Ki = g.Kd, g.Kp
    log = HORIZONTAL.simulate(lambda t, x: pi_speed_torque(t, x[0], x[1], omega_d, Kp, Ki), 8.0, rtol=1e-10, atol=1e-12)
    # speed error e = omega_d - omega: M e'' + (b + Kp) e' + Ki e = 0, e(0) = omega_d, e'(0) = -Kp omega_d / M
    e = metrics.second_order_error(log.t, omega_d, -Kp * omega_d / HORIZONTAL.M, wn, zeta)
    assert np.max(np.abs((omega_d - log.qdot[:, 0]) - e)) < 1e-7
    assert log.qdot[:, 0][-1] == pytest.approx(omega_d, abs=1e-3)


def test_a_critically_damped_pi_speed_loop_overshoots_where_the_closed_form_says():
    """Task 1's PI design (ωn = 2, ζ = 1) overshoots its 5 rad/s: the error starts moving,
    ė(0) = -Kp ω_d / M, so e = (ω_d + c t) e^(-ωn t) with c = ė(0) + ωn ω_d < 0 crosses zero at
    -ω_d / c and is most negative at 1/ωn - ω_d / c, where the page finds the peak speed."""
    wn, omega_d = 2.0, 5.0
    g = gains.pd_gains(HORIZONTAL.M, HORIZONTAL.b, wn, 1.0)
    Kp, Ki = g.Kd, g.Kp
    log = HORIZONTAL.simulate(lambda t, x: pi_speed_torque(t, x[0], x[1], omega_d, Kp, Ki), 6.0, rtol=1e-10, atol=1e-12)
    c = -Kp * omega_d / HORIZONTAL.M + wn * omega_d
    t_peak = 1 / wn - omega_d / c
    peak = omega_d - (omega_d + c * t_peak) * np.exp(-wn * t_peak)
    k = np.argmax(log.qdot[:, 0])
    assert c < 0 and peak > omega_d + 0.5  # an overshoot of more than 10 % at ζ = 1
    assert log.qdot[k, 0] == pytest.approx(peak, abs=1e-6)
    assert log.t[k] == pytest.approx(t_peak, abs=2 * (log.t[1] - log.t[0]))
    crossing = log.t[np.argmax(log.qdot[:, 0] > omega_d)]
    assert crossing == pytest.approx(-omega_d / c, abs=2 * (log.t[1] - log.t[0]))
    assert f"{peak:.2f}" == "5.54"  # the page's figure


def test_feedforward_alone_turns_back_short_of_the_top_in_move_b():
    """Task 1's move B with r̃ = 0.08: the link climbs only to about 71° and falls back past the
    horizontal; feedback alone lags while gravity holds the link back and runs past 135° after
    the top, where gravity pulls it on."""
    ref = lambda t: versine(t, np.pi / 2)  # noqa: E731
    wrong = SingleJoint(r=0.08, g=9.81)
    ff = VERTICAL.simulate(feedforward_along(wrong, ref), np.pi, state0=ref(0.0)[:2])
    top = np.degrees(ff.q[:, 0].max())
    assert 65 < top < 80 and np.degrees(ff.q[-1, 0]) < 0
    Kp, Kd = gains.spec_gains(VERTICAL.M, VERTICAL.b, 5.0, 2.0)[0]
    fb = VERTICAL.simulate(pd_along(ref, Kp, Kd), np.pi, state0=ref(0.0)[:2])
    behind = np.degrees(ref(fb.t).pos - fb.q[:, 0])  # θ_d − θ
    assert behind.max() > 10 and behind[-1] < -10  # first behind, then past the target
    crossed = fb.t[np.argmax((fb.t > 0.5) & (behind < 0))]
    assert np.degrees(ref(crossed).pos) > 90  # it runs ahead only once past the top


@pytest.mark.parametrize("M,b", [(0.5, 0.1), (2.0, 0.0), (0.3, 0.05)])
@pytest.mark.parametrize("wn,zeta", [(2.523, 1.0), (3.383, 0.591), (10.0, 0.3)])
def test_gain_design_round_trips(M, b, wn, zeta):
    g = gains.pd_gains(M, b, wn, zeta)
    back = gains.second_order(M, b, g.Kp, g.Kd)
    assert back.wn == pytest.approx(wn, rel=1e-12) and back.zeta == pytest.approx(zeta, rel=1e-12)
    assert gains.ct_gains(wn, zeta) == pytest.approx((wn**2, 2 * zeta * wn))


def test_lab_gain_figures():
    m1 = gains.actuator_limited_gains(0.5, 0.1, 5.0, np.pi / 2)
    so1 = gains.second_order(0.5, 0.1, *m1)
    assert (round(m1.Kp, 3), round(m1.Kd, 3), round(so1.wn, 3), round(so1.zeta, 3)) == (3.183, 2.423, 2.523, 1.0)
    g2, so2 = gains.spec_gains(0.5, 0.1, 10.0, 2.0)
    assert (round(so2.zeta, 3), round(so2.wn, 3), round(g2.Kp, 3), round(g2.Kd, 3)) == (0.591, 3.383, 5.723, 1.9)
    assert round(g2.Kp * np.pi / 2, 2) == 8.99
    g3, so3 = gains.spec_gains(0.5, 0.1, 5.0, 2.0)
    assert (round(g3.Kp, 3), round(g3.Kd, 3), round(so3.zeta, 3), round(so3.wn, 3)) == (4.199, 1.9, 0.69, 2.898)


def test_lab_sinusoid_rms_figures():
    g, _ = gains.spec_gains(0.5, 0.1, 5.0, 2.0)
    wrong = SingleJoint(r=0.08, g=9.81)
    fb = VERTICAL.simulate(pd_along(sinusoid, g.Kp, g.Kd), 4 * np.pi, state0=sinusoid(0.0)[:2])
    ct = VERTICAL.simulate(computed_torque_along(wrong, sinusoid, g.Kp, g.Kd), 4 * np.pi, state0=sinusoid(0.0)[:2])
    rms_fb = metrics.rms(np.degrees(fb.q[:, 0] - sinusoid(fb.t).pos))
    rms_ct = metrics.rms(np.degrees(ct.q[:, 0] - sinusoid(ct.t).pos))
    assert round(rms_fb, 3) == 10.891 and round(rms_ct, 3) == 2.253
    assert round(100 * (1 - rms_ct / rms_fb), 1) == 79.3


def test_rms_of_nothing_is_refused_with_a_reason():
    """An empty window (``after`` past the run's end) used to give NaN and NumPy's "Mean of empty
    slice" warning; now the reason is named."""
    np.testing.assert_allclose(metrics.rms([3.0, -3.0]), 3.0)
    for empty in (np.zeros(0), np.zeros((0, 3))):
        with pytest.raises(ValueError, match="no samples"):
            metrics.rms(empty)
        with pytest.raises(ValueError, match="no samples"):
            metrics.rms_norm(empty)
    with pytest.raises(ValueError, match="holds None"):  # NaN before, as if the reference were not finite
        metrics.rms([1.0, None])


@pytest.mark.parametrize(
    ("tau", "message"),
    [
        (None, r"the torque function returned None at t = 0\.0000 s"),
        (np.zeros(2), r"tau must be a scalar, got shape \(2,\)"),
        (float("nan"), "tau is nan \\(not finite\\)"),
        (1j, r"the torque function \(at t = 0\.0000 s\) returned complex numbers, but angles and torques are real"),
        ("1", r"the torque function returned the text '1' at t = 0\.0000 s, not a number"),  # NumPy: 1 N·m
    ],
)
def test_the_analytic_joint_names_a_bad_torque(tau, message):
    with pytest.raises(ValueError, match=message):
        SingleJoint().simulate(lambda t, state: tau, 1.0)


def test_a_sign_error_stops_where_the_closed_form_reaches_the_runaway_speed():
    """``tau = +1000 theta`` (a sign error) used to return theta = 2.9e192 rad without a word.
    With g = 0 the closed loop is M theta'' + b theta' - 1000 theta = 0: from theta = 0.1 at rest,
    theta' = A s1 (e^(s1 t) - e^(s2 t)), which reaches RUNAWAY_SPEED at the time computed here."""
    arm = SingleJoint()
    s1, s2 = np.roots([arm.M, arm.b, -1000.0]).max(), np.roots([arm.M, arm.b, -1000.0]).min()
    A = 0.1 * -s2 / (s1 - s2)
    t_star = brentq(lambda t: A * s1 * (np.exp(s1 * t) - np.exp(s2 * t)) - RUNAWAY_SPEED, 0.0, 1.0)
    with pytest.raises(SimulationDiverged, match="check the law for a sign error") as caught:
        arm.simulate(lambda t, x: 1000.0 * x[0], 10.0, state0=(0.1, 0.0))
    assert caught.value.t == pytest.approx(t_star, rel=1e-4)
    assert caught.value.qvel[0] == pytest.approx(RUNAWAY_SPEED)


def test_gains_too_stiff_for_rk45_are_named_instead_of_running_for_minutes(monkeypatch):
    """Kd = 1e7 took 246 s to return; the solver's work is now bounded (smaller here, for speed)."""
    monkeypatch.setattr(plants, "MAX_EVALUATIONS", 20_000)
    stiff = lambda t, x: -1e5 * x[1] - 100.0 * x[0]  # noqa: E731
    with pytest.raises(RuntimeError, match="too stiff for it") as caught:
        SingleJoint().simulate(stiff, 1.0, state0=(0.1, 0.0))
    # raised by simulate itself, not from inside SciPy's solver: the student's call, then simulate
    assert [frame.name for frame in traceback.extract_tb(caught.tb)][-1] == "simulate"
    with pytest.raises(ValueError, match="returned None") as caught:  # a check of the law's torque
        SingleJoint().simulate(lambda t, x: None, 1.0)
    assert not any("scipy" in frame.filename for frame in traceback.extract_tb(caught.tb))
    log = SingleJoint().simulate(lambda t, x: 5.72 * (np.pi / 2 - x[0]) - 1.9 * x[1], 10.0)  # the lab's gains
    assert log.q[-1, 0] == pytest.approx(np.pi / 2, abs=1e-3)
    for tolerances in ({"atol": np.nan}, {"rtol": np.inf}, {"rtol": 0.0}):  # NaN and inf never returned
        with pytest.raises(ValueError, match="rtol|atol"):
            SingleJoint().simulate(lambda t, x: 0.1, 1.0, **tolerances)


def test_step_metrics_refuse_what_is_not_one_response():
    """``settling_time`` with fewer values than times used to answer with a number."""
    t = np.linspace(0.0, 2.0, 5)
    with pytest.raises(ValueError, match="one time per sample"):
        metrics.settling_time(t, np.ones(4), 1.0, 0.0)
    with pytest.raises(ValueError, match=r"pick one column, for example log.q\[:, 0\]"):
        metrics.overshoot(np.ones((5, 2)), 1.0, 0.0)
    with pytest.raises(ValueError, match="no samples"):
        metrics.overshoot([], 1.0, 0.0)


def test_log_metrics_say_what_the_log_lacks():
    """A log without a reference used to give "no samples to take the RMS of"; an ``applied``
    torque of the wrong shape was broadcast into a report of limits hit at every step."""
    model, data = load_model("single_joint")
    log = sim.simulate(model, data, lambda model, data: np.zeros(1), 0.05)
    with pytest.raises(ValueError, match="no position error: pass site= and reference="):
        metrics.rms_position_error(log)
    with pytest.raises(ValueError, match=r"shape \(50, 1\) as log.tau, got shape \(2,\)"):
        metrics.saturation_report(log, np.zeros(2))
    assert metrics.saturation_report(log, np.zeros((50, 1))) == ""
    with pytest.raises(ValueError, match="the RMS is taken over samples, an array of them; got the single number"):
        metrics.rms(0.3)
    with pytest.raises(ValueError, match="log must be the Log that labsupport.sim.simulate returns, got tuple"):
        metrics.rms_position_error((log.t, log.q))  # a student's own (t, q) pair
    at_origin = sim.simulate(
        model, data, lambda model, data: np.zeros(1), 0.05, site="tip", reference=lambda t: Reference(0.0, 0.0, 0.0)
    )
    with pytest.raises(ValueError, match="after must be numbers, not text"):
        metrics.rms_position_error(at_origin, after="1 s")
    with pytest.raises(ValueError, match="a model is named by a string"):
        load_model(None)


@pytest.mark.parametrize(
    "kwargs,word",
    [({"M": 0.0}, "M"), ({"M": -1.0}, "M"), ({"b": -0.1}, "b"), ({"m": float("nan")}, "m"), ({"m": -0.1}, "m")],
)
def test_bad_parameters_are_named(kwargs, word):
    with pytest.raises(ValueError, match=rf"^{word} "):
        SingleJoint(**kwargs)


@pytest.mark.parametrize(
    "run, message",
    [
        ({"duration": 0.0}, "duration must be positive, got 0.0"),
        ({"dt": 0.0}, "dt must be positive, got 0.0"),
        ({"dt": 2.0}, r"dt must be at most the duration \(1.0 s\), got 2.0"),
        ({"atol": -1e-9}, "atol must be positive, got -1e-09"),
    ],
)
def test_bad_run_settings_are_named(run, message):
    """A zero or negative setting is named before SciPy sees it; a step as long as the run gives the
    one sample it promises (samples at 0, dt, 2dt, … < duration)."""
    settings = {"duration": 1.0} | run
    with pytest.raises(ValueError, match=message) as excinfo:
        HORIZONTAL.simulate(lambda t, x: 0.0, **settings)
    _assert_no_scipy_frames(excinfo)
    np.testing.assert_array_equal(HORIZONTAL.simulate(lambda t, x: 0.0, 1.0, dt=1.0).t, [0.0])


def _assert_no_scipy_frames(excinfo):
    assert not any("scipy" in str(entry.path) for entry in excinfo.traceback)


def test_wrong_shaped_state_is_named():
    with pytest.raises(ValueError, match="state0") as excinfo:
        HORIZONTAL.simulate(lambda t, x: 0.0, 1.0, state0=(0.0, 0.0, 0.0))
    _assert_no_scipy_frames(excinfo)


@pytest.mark.parametrize("bad", [float("nan"), None, np.array([1.0, 2.0])])
def test_bad_torque_is_named_without_scipy_traceback(bad):
    with pytest.raises(ValueError, match="tau|torque") as excinfo:
        HORIZONTAL.simulate(lambda t, x: bad, 1.0)
    _assert_no_scipy_frames(excinfo)


def test_step_metrics_refuse_what_would_give_a_wrong_number():
    """A NaN in the response (a run that diverged) once read as 0 % overshoot."""
    t = np.linspace(0.0, 10.0, 1001)
    y = metrics.second_order_step(t, 2.0, 0.5)
    assert metrics.overshoot(y, 1.0, 0.0) == pytest.approx(16.303, abs=1e-3)
    with pytest.raises(ValueError, match="NaN or inf.*did the run diverge"):
        metrics.overshoot(np.append(y, np.nan), 1.0, 0.0)
    with pytest.raises(ValueError, match="NaN or inf"):
        metrics.settling_time(np.append(t, 10.01), np.append(y, np.inf), 1.0, 0.0)
    for band in (0.0, -0.02):
        with pytest.raises(ValueError, match="band must be positive"):
            metrics.settling_time(t, y, 1.0, 0.0, band=band)
    with pytest.raises(ValueError, match="step of zero size has no settling time"):
        metrics.settling_time(t, y, 1.0, 1.0)
    with pytest.raises(ValueError, match="got None"):
        metrics.rms_norm(None)
    for wn, zeta, name in ((0.0, 0.5, "wn must be positive"), (2.0, -2.0, "zeta must be non-negative")):
        with pytest.raises(ValueError, match=name):
            metrics.second_order_step(t, wn, zeta)
        with pytest.raises(ValueError, match=name):
            metrics.second_order_error(t, 1.0, 0.0, wn, zeta)
    with pytest.raises(ValueError, match="one torque per time.*t of shape \\(1001,\\) and tau of shape \\(1000,\\)"):
        metrics.cumulative_effort(t, y[:-1])


def test_bad_gain_design_inputs():
    with pytest.raises(ValueError, match="percent_overshoot"):
        gains.damping_for_overshoot(0.0)
    with pytest.raises(ValueError, match="Kd"):
        gains.pd_gains(0.5, 5.0, 1.0, 0.1)
    with pytest.raises(ValueError, match="tau_max"):
        gains.actuator_limited_gains(0.5, 0.1, -1.0, 1.0)
    with pytest.raises(ValueError, match="Kd must be finite"):
        gains.second_order(0.5, 0.1, 10.0, float("nan"))
    # a small overshoot is a valid specification: ζ = −ln(0.005)/√(π² + ln²(0.005)) = 0.860 (warned
    # about below 1 %, where a fraction meant as a percentage lands)
    with pytest.warns(RuntimeWarning, match="it is a percentage"):
        assert gains.damping_for_overshoot(0.5) == pytest.approx(0.8601, abs=1e-4)
    for beyond in (100.0, 150.0):  # 100 % overshoot is no damping at all; more is none that exists
        with pytest.raises(ValueError, match=r"percent_overshoot must be in \(0, 100\)"):
            gains.damping_for_overshoot(beyond)


def test_pd_gains_at_the_edges_of_what_friction_allows():
    """Kd = 2ζωn M − b: zero where friction alone gives the damping asked for, small but positive
    just above it."""
    assert gains.pd_gains(0.5, 0.0, wn=10.0, zeta=0.0) == gains.Gains(Kp=50.0, Kd=0.0)
    assert gains.pd_gains(0.5, 0.1, wn=1.0, zeta=0.1) == gains.Gains(Kp=0.5, Kd=0.0)
    assert gains.pd_gains(0.5, 0.1, wn=1.0, zeta=0.5) == pytest.approx(gains.Gains(Kp=0.5, Kd=0.4), abs=1e-15)


def test_simulate_returns_the_one_log_type():
    log = HORIZONTAL.simulate(lambda t, x: 1.0, 1.0, dt=0.01)
    assert isinstance(log, sim.Log)
    assert (log.t.shape, log.q.shape, log.qdot.shape, log.tau.shape, log.ctrl.shape) == (
        (100,),
        (100, 1),
        (100, 1),
        (100, 1),
        (100, 1),
    )
    assert (log.ee.shape, log.ee_rot.shape, log.ref.shape, log.err.shape) == ((100, 0), (100, 0, 0), (100, 0), (100, 0))
    np.testing.assert_array_equal(log.tau, 1.0)


def test_laws_are_their_equations_at_a_state():
    """Each law against its formula written out by hand at one state."""
    model = SingleJoint(M=0.7, m=1.2, r=0.09, b=0.2, g=9.81)
    theta, theta_dot, theta_d, theta_dot_d, theta_ddot_d, Kp, Kd = 0.3, -0.4, 0.5, 0.1, -0.2, 7.0, 2.0
    assert pd_torque(theta, theta_dot, theta_d, theta_dot_d, Kp, Kd) == pytest.approx(7.0 * 0.2 + 2.0 * 0.5)
    tau_ff = 0.7 * -0.2 + 1.2 * 9.81 * 0.09 * np.cos(0.5) + 0.2 * 0.1
    assert feedforward_torque(model, theta_d, theta_dot_d, theta_ddot_d) == pytest.approx(tau_ff)
    assert computed_torque(model, theta, theta_dot, theta_d, theta_dot_d, theta_ddot_d, Kp, Kd) == pytest.approx(
        tau_ff + 2.4
    )
    assert pi_speed_torque(2.0, 1.5, 0.8, 1.0, 3.0, 4.0, theta0=0.5) == pytest.approx(3.0 * 0.2 + 4.0 * (2.0 - 1.0))


def test_rms_norm_of_one_component_per_sample_is_its_rms():
    """A 1-D error was summed over all its samples as if it were one vector: √N too large."""
    error = np.full(100, 0.01)
    assert metrics.rms_norm(error) == pytest.approx(0.01) == metrics.rms(error)
    assert metrics.rms_norm(error) == pytest.approx(metrics.rms_norm(error[:, None]))


def test_the_free_response_broadcasts_a_scalar_start_over_vector_rates():
    """``e0`` a number and ``edot0`` a vector paired each time with one component (shape (2,)
    for two times, a NumPy error for three); each component must be its own response, checked
    against an ODE solution."""
    t = np.linspace(0.0, 2.0, 5)
    both = metrics.second_order_error(t, 0.1, [0.0, 1.0], 2.0, 0.5)
    assert both.shape == (5, 2)
    for j, rate in enumerate((0.0, 1.0)):
        ode = solve_ivp(
            lambda s, x: [x[1], -2.0 * x[1] - 4.0 * x[0]], (0, 2), [0.1, rate], t_eval=t, rtol=1e-10, atol=1e-12
        )
        np.testing.assert_allclose(both[:, j], ode.y[0], atol=1e-8)
    with pytest.raises(ValueError, match="same number of components"):
        metrics.second_order_error(t, [0.1, 0.2, 0.3], [0.0, 1.0], 2.0, 0.5)
    for bad, message in ((None, "e0 must be finite"), ("1", "not text")):
        with pytest.raises(ValueError, match=message):
            metrics.second_order_error(t, bad, 0.0, 2.0, 0.5)


def test_orientation_measures_name_a_missing_site_and_a_nan_target():
    model, data = load_model("single_joint")
    log = sim.simulate(model, data, lambda m, d: np.zeros(1), 0.01)
    with pytest.raises(ValueError, match="no site orientation: pass site="):
        metrics.rms_orientation_error(log, (1.0, 0.0, 0.0, 0.0))
    with pytest.raises(ValueError, match="unit quaternion"):
        metrics.rotation_error(np.eye(3), (np.nan, 0.0, 0.0, 0.0))
    # an orientation of the wrong size ended in NumPy's "cannot reshape array of size 4"
    for xmat, got in ((np.eye(2), "shape \\(2, 2\\)"), ("R", "not numbers"), ([[1, 0], [0, 1, 0]], "not numbers")):
        with pytest.raises(ValueError, match=f"xmat must be a rotation matrix, 3x3 or 9 numbers.*got {got}"):
            metrics.rotation_error(xmat, (1.0, 0.0, 0.0, 0.0))
    # the same orientation as a 3x3 list and as 9 numbers: the same error, a quarter turn about z
    quarter = [[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]]
    for xmat in (quarter, np.ravel(quarter), np.asarray(quarter).T.copy().T):
        assert np.allclose(metrics.rotation_error(xmat, (1.0, 0.0, 0.0, 0.0)), [0.0, 0.0, np.pi / 2])


def test_the_analytic_plant_names_a_torque_that_is_not_a_function_of_t_and_state():
    """``torque=0.1``, ``lambda t: ...`` or a MuJoCo-style ``lambda model, data: ...`` ended in
    a raw error from inside solve_ivp."""
    for torque, message in (
        (0.1, "torque must be a function torque"),
        (lambda t: 0.1, "called as torque\\(t, state\\)"),
        (lambda model, data: -data.qpos, "called as torque\\(t, state\\)"),
    ):
        with pytest.raises(ValueError, match=message):
            SingleJoint().simulate(torque, 0.1)


def test_load_model_points_to_the_ur5e_loader():
    """``load_model("ur5e_scene")`` compiled the scene without its robot (nq = 0), and the list
    of shipped models offered it."""
    for name in ("ur5e", "ur5e_scene"):
        with pytest.raises(ValueError, match=r"labsupport.ur5e.load_ur5e\(\)"):
            load_model(name)
    with pytest.raises(ValueError, match=r"shipped models are \['planar_2r', 'single_joint', 'spatial_3r'\]"):
        load_model("2r")


def test_gains_and_settling_time_name_inputs_that_are_not_numbers():
    """Text was read as a number ("10" as 10 %), None ended in a raw TypeError, and a settling
    time was computed on times that run backwards."""
    with pytest.raises(ValueError, match="percent_overshoot must be numbers, not text"):
        gains.damping_for_overshoot("10")
    with pytest.raises(ValueError, match="percent_overshoot must be a number, got the boolean"):
        gains.damping_for_overshoot(True)
    with pytest.raises(ValueError, match=r"initial_error must be a number, got None \(a value never set\?\)"):
        gains.actuator_limited_gains(0.5, 0.1, 2.0, None)
    t = np.linspace(0.0, 1.0, 11)
    y = 1.0 - np.exp(-5 * t)
    with pytest.raises(ValueError, match="t must be a time in seconds"):
        metrics.settling_time(None, y, 1.0, 0.0)
    with pytest.raises(ValueError, match="must increase"):
        metrics.settling_time(t[::-1], y, 1.0, 0.0)


def test_a_band_given_in_percent_and_effort_over_backward_times_are_refused():
    """band=2 (meant as 2 %) gave a settling time of 0; a band below e^-12 gave nan; effort over
    times that run backwards came out negative; a huge damping ratio gave a message about a t
    never passed."""
    t = np.linspace(0.0, 1.0, 11)
    y = 1.0 - np.exp(-5 * t)
    for band in (2, 1.0, 1.5):
        with pytest.raises(ValueError, match=r"band is a fraction of the step, below 1 \(0\.02 for 2 %\)"):
            metrics.settling_time(t, y, 1.0, 0.0, band=band)
        with pytest.raises(ValueError, match="band is a fraction"):
            gains.step_settling_time(1.0, 0.5, band=band)
    # a narrow band: the exact settling time of the envelope-bounded response, not nan
    narrow = gains.step_settling_time(1.0, 1.0, band=1e-9)
    assert np.isfinite(narrow) and 20.0 < narrow < 30.0  # critically damped: 1 - y = (1 + t) e^-t, no overshoot
    assert abs((1 + narrow) * np.exp(-narrow) - 1e-9) < 1e-12
    # overdamped: the slow mode's rate wn (zeta - sqrt(zeta^2 - 1)) = wn / (2 zeta) for large zeta
    assert gains.step_settling_time(1.0, 1e8) == pytest.approx(np.log(50) * 2e8, rel=1e-3)  # was nan
    # the poles of any finite damping ratio and frequency, with their product wn^2 and sum -2 zeta wn
    # (zeta**2 and wn**2 overflowed past 1e154)
    for wn, zeta in ((2.0, 1.25), (1e-100, 1e200), (3.0, 1e300)):
        s1, s2 = metrics.overdamped_poles(wn, zeta)
        assert s1 * (s2 / wn) == pytest.approx(wn) and s1 + s2 == pytest.approx(-2 * zeta * wn)
    assert metrics.overdamped_poles(2.0, 1.25) == pytest.approx((-1.0, -4.0))
    for wn, zeta, words in ((1.0, 1.0, "zeta > 1"), (np.nan, 2.0, "wn must be finite"), ([1.0, 2.0], 2.0, "single")):
        with pytest.raises(ValueError, match=words):  # NaN poles before, or complex ones' real parts
            metrics.overdamped_poles(wn, zeta)
    with pytest.raises(ValueError, match="must increase"):
        metrics.cumulative_effort([1.0, 0.0], [1.0, 1.0])


def test_the_saturation_measures_check_what_they_are_given():
    model, data = load_model("planar_2r")
    log = sim.simulate(model, data, lambda m, d: np.full(2, 5.0), 0.01)
    applied = np.clip(log.tau, -1.0, 1.0)
    assert "joints shoulder, elbow" in metrics.saturation_report(log, applied, names=["shoulder", "elbow"])
    with pytest.raises(ValueError, match="names must name each of the 2 actuators, got 1"):
        metrics.saturation_report(log, applied, names=["shoulder"])
    with pytest.raises(ValueError, match="names must be a list of names, one per actuator, got the text 'ab'"):
        metrics.saturation_report(log, applied, names="ab")  # two letters, two actuators: it used to pass
    with pytest.raises(ValueError, match="applied must hold one exerted torque per step and actuator"):
        metrics.peak_torque(log, applied[:, :1])


def test_the_peak_torque_is_per_actuator_and_the_report_names_the_first_limited_step():
    """Torques of 0.5 k on the shoulder and −3 on the elbow over five steps, clipped to ±1 N·m: the
    elbow is limited from the first step, the shoulder from the fourth (k = 3, t = 6 ms)."""
    model, data = load_model("planar_2r")
    log = sim.simulate(model, data, lambda m, d: np.array([0.5 * round(d.time / 0.002), -3.0]), 0.01)
    assert len(log.t) == 5
    np.testing.assert_allclose(metrics.peak_torque(log), [2.0, 3.0])
    applied = np.clip(log.tau, -1.0, 1.0)
    np.testing.assert_allclose(metrics.peak_torque(log, applied), [1.0, 1.0])
    np.testing.assert_array_equal(metrics.saturation(log, applied)[:, 0], [False, False, False, True, True])
    only_shoulder = np.c_[applied[:, 0], log.tau[:, 1]]  # the elbow given what it asked
    assert "(first at t = 0.006 s; joints shoulder)" in metrics.saturation_report(
        log, only_shoulder, names=["shoulder", "elbow"]
    )
    np.testing.assert_array_equal(metrics.peak_torque(log, applied), [1.0, 1.0])


def test_task1_try_it_predictions_hold():
    """Task 1's "Try it" box asks the student to add gravity compensation to PD on the sinusoid
    and lists what they will see; a law written as the box says must show each of them."""
    vertical = SingleJoint(M=0.5, m=1.0, r=0.1, b=0.1, g=9.81)
    wrong = SingleJoint(M=0.5, m=1.0, r=0.08, b=0.1, g=9.81)
    fb, _ = gains.spec_gains(vertical.M, vertical.b, 5.0, 2.0)

    def pd_gravity_torque(theta, theta_dot, theta_d, theta_dot_d, Kp, Kd, arm):
        return Kp * (theta_d - theta) + Kd * (theta_dot_d - theta_dot) + arm.m * arm.g * arm.r * np.cos(theta)

    def error_deg(torque):
        log = vertical.simulate(torque, 4 * np.pi, state0=sinusoid(0.0)[:2])
        return np.degrees(sinusoid(log.t).pos - log.q[:, 0])

    def ref(t):
        return sinusoid(t).pos, sinusoid(t).vel

    pd = error_deg(lambda t, x: pd_torque(x[0], x[1], *ref(t), *fb))
    pdg = error_deg(lambda t, x: pd_gravity_torque(x[0], x[1], *ref(t), *fb, vertical))
    pdg_wrong = error_deg(lambda t, x: pd_gravity_torque(x[0], x[1], *ref(t), *fb, wrong))
    ct_wrong = error_deg(lambda t, x: computed_torque(wrong, x[0], x[1], *sinusoid(t), *fb))
    ct_exact = error_deg(lambda t, x: computed_torque(vertical, x[0], x[1], *sinusoid(t), *fb))
    assert pd.min() >= 0.0 and pd.max() > 10  # PD alone: the link stays below the reference (the sag)
    assert abs(pdg.max() + pdg.min()) < 1e-3 * pdg.max()  # the sag is gone: even about zero
    assert metrics.rms(pdg) > 1.5 * metrics.rms(ct_wrong)  # but above computed torque's error
    assert np.abs(ct_exact).max() < 1e-4  # computed torque with the exact model: zero
    assert pdg_wrong.max() > 1.5 * -pdg_wrong.min() > 0  # the wrong r̃: no longer even


@pytest.mark.parametrize("zeta", [0.3, 1.0, 2.5])
def test_the_closed_form_step_responses_match_an_integrated_ode(zeta):
    """ÿ + 2ζωn ẏ + ωn² y = ωn² from rest, integrated by SciPy, for each of the three closed forms."""
    wn, t = 3.0, np.linspace(0.0, 4.0, 401)
    ode = solve_ivp(
        lambda _, x: [x[1], wn**2 * (1 - x[0]) - 2 * zeta * wn * x[1]], (0, 4), [0, 0], t_eval=t, rtol=1e-11, atol=1e-12
    )
    np.testing.assert_allclose(metrics.second_order_step(t, wn, zeta), ode.y[0], atol=1e-8)


def test_settling_time_interpolates_the_band_crossing_and_does_not_depend_on_the_start():
    """A first-order response 1 − e^{−t} enters the 2 % band at ln 50 s; on a 10 ms grid the answer
    must come from the crossing, not the nearest sample. The same step from 2 to 5 settles alike and
    overshoots alike; a response already inside the band settles at its first time."""
    t = np.arange(0.0, 8.0, 0.01)
    y = 1 - np.exp(-t)
    assert metrics.settling_time(t, y, 1.0, 0.0) == pytest.approx(np.log(50), abs=2e-4)
    assert metrics.settling_time(t, 2 + 3 * y, 5.0, 2.0) == pytest.approx(np.log(50), abs=2e-4)
    assert metrics.settling_time(t, 5 - 3 * y, 2.0, 5.0) == pytest.approx(np.log(50), abs=2e-4)  # a step down
    under = metrics.second_order_step(t, 2.0, 0.5)
    assert metrics.overshoot(2 + 3 * under, 5.0, 2.0) == pytest.approx(metrics.overshoot(under, 1.0, 0.0), rel=1e-12)
    assert metrics.overshoot(y, 1.0, 0.0) == 0.0  # 1 − e^{−t} never passes 1
    assert metrics.overshoot(5 - 3 * under, 2.0, 5.0) == pytest.approx(16.303, abs=1e-3)  # a step down dips below 2
    assert metrics.settling_time(t[100:], np.full(len(t) - 100, 0.99), 1.0, 0.0) == t[100]
    with pytest.warns(RuntimeWarning, match=r"still outside its ±2 % band at the end of the record \(t = 2.99 s\)"):
        assert np.isnan(metrics.settling_time(t[:300], y[:300], 1.0, 0.0))  # still 5 % short at 2.99 s


def test_cumulative_effort_integrates_the_squared_torque():
    """E(t) = ∫‖τ‖² dt: c² t for a constant torque, the sum over joints for several, and t³/3 for
    τ = t (the trapezoidal rule's error, (Δt²/6) t, is under 1e-4 here)."""
    t = np.linspace(0.0, 2.0, 201)
    np.testing.assert_allclose(metrics.cumulative_effort(t, np.full_like(t, 3.0)), 9.0 * t, rtol=1e-12)
    two = np.c_[np.full_like(t, 3.0), np.full_like(t, -4.0)]
    np.testing.assert_allclose(metrics.cumulative_effort(t, two), 25.0 * t, rtol=1e-12)
    np.testing.assert_allclose(metrics.cumulative_effort(t, t), t**3 / 3, atol=1e-4)


def test_a_stable_but_very_stiff_design_is_not_called_a_runaway_sign_error():
    """Method 2 asked for a 0.05 s settling time gives a stable loop whose step peaks near 107 rad/s
    (RK45 follows it closely, so nothing numerical is unstable); the run stops at the speed bound,
    but its message no longer says the run is running away or blames a sign error alone: it names
    both causes, and leaves out the Cartesian advice, which a single joint has no use for."""
    g, _ = gains.spec_gains(HORIZONTAL.M, HORIZONTAL.b, 10.0, 0.05)
    with pytest.raises(SimulationDiverged) as caught:
        HORIZONTAL.simulate(pd_to(np.pi / 2, g.Kp, g.Kd), 2.0)
    said = str(caught.value)
    assert "a joint reached 100 rad/s (about 955 rpm), the speed at which a run stops as running away" in said
    assert "or it is so stiff that even a stable response moves this fast" in said and "radians" in said
    assert "Cartesian" not in said


def test_a_nan_torque_from_a_nan_set_point_is_told_where_to_look():
    """theta_d = NaN gave only "tau is nan (not finite)"; the MuJoCo loop's advice for a NaN
    torque from a finite state (check the references and gains) now follows it here too."""
    with pytest.raises(ValueError, match=r"tau is nan \(not finite\) .*check the references and gains it is passed"):
        SingleJoint().simulate(pd_to(np.nan, 5.0, 1.0), 1.0)
