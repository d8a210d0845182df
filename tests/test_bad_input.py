"""Bad arguments to the package's helpers end in a ``ValueError`` raised by the package, whose
message names the argument in plain words, never in NumPy's or MuJoCo's own error from deep inside.

The cases are those a sweep found, each argument replaced in turn by text, NaN, a Python integer
too large for a float, nested lists of unequal lengths, a wrong shape, or a value of another
kind: the helpers' own checks had missed them.
"""

import traceback
import warnings

import numpy as np
import pytest

import labsupport  # noqa: F401  (before mujoco)
from labsupport import actuators, book, dynamics, gains, metrics, render, sim, trajectories, validate
from labsupport.controllers import single_joint
from labsupport.controllers.operational_space import os_ct_torque
from labsupport.grading import check, feedback
from labsupport.kinematics import planar_2r
from labsupport.plants import SingleJoint, load_model

RAGGED = [[1.0, 2.0], [3.0]]
HUGE = 10**400  # a Python integer beyond the largest float


@pytest.fixture(scope="module")
def arm():
    return load_model("planar_2r")


@pytest.fixture(scope="module")
def log(arm):
    model, data = arm
    return sim.simulate(model, data, lambda m, d: d.qfrc_bias.copy(), 0.02, q0=[0.2, 0.3])


CASES = {
    "vector of a huge integer": (lambda a, g: validate.vector("q", [HUGE, 1.0], 2), "q must be numbers of shape"),
    "number of a huge integer": (lambda a, g: validate.number("dt", HUGE), "dt must be a single real number"),
    "times of a huge integer": (lambda a, g: validate.times([0.0, HUGE]), "t must be a time in seconds"),
    "set point of unequal lists": (lambda a, g: trajectories.set_point(0.0, RAGGED), "point must be numbers"),
    "reference not a function": (lambda a, g: trajectories.sample(None, 0.002, 1.0), "reference must be a function"),
    "evaluate a list": (lambda a, g: trajectories.evaluate([0.1, 0.2], 0.5), "reference must be a function of time"),
    "jacobian_solve of text": (lambda a, g: dynamics.jacobian_solve(np.eye(2), ["a", "b"]), "J and rhs must be"),
    "jacobian_solve of unequal lists": (lambda a, g: dynamics.jacobian_solve(RAGGED, [1, 2]), "J and rhs must be"),
    "solve_mass of a huge integer": (lambda a, g: dynamics.solve_mass(*a, [HUGE, 1]), "rhs must be numbers"),
    "task_space_inertia of one row": (
        lambda a, g: dynamics.task_space_inertia(*a, np.ones(2)),
        r"jac must be a Jacobian of shape \(k, 2\)",
    ),
    "a run shorter than one step": (
        lambda a, g: sim.simulate(*a, lambda m, d: d.qfrc_bias, 0.4 * a[0].opt.timestep),
        r"duration must be at least one time step \(0.002 s\), got 0.0008",
    ),
    "a run of no time": (
        lambda a, g: sim.simulate(*a, lambda m, d: d.qfrc_bias, 0.0),
        "duration must be positive, got 0.0",
    ),
    "sampled at no step": (
        lambda a, g: trajectories.sample(lambda t: trajectories.set_point(t, 1.0), 0.0, 1.0),
        "dt must be positive, got 0.0",
    ),
    "sampled over negative time": (
        lambda a, g: trajectories.sample(lambda t: trajectories.set_point(t, 1.0), 0.002, -1.0),
        "duration must be non-negative, got -1.0",
    ),
    "gains for negative friction": (lambda a, g: gains.pd_gains(0.5, -0.1, 10.0, 1.0), "b must be non-negative"),
    "gains for negative damping": (lambda a, g: gains.pd_gains(0.5, 0.1, 10.0, -1.0), "zeta must be non-negative"),
    "effort over a repeated time": (
        lambda a, g: metrics.cumulative_effort([0.0, 0.1, 0.1], [1.0, 2.0, 3.0]),
        "the times t must increase from sample to sample",
    ),
    "effort of text": (lambda a, g: metrics.cumulative_effort(g.t, "abc"), "tau must be numbers"),
    "effort of a huge integer": (lambda a, g: metrics.cumulative_effort([0.0, 1.0], [HUGE, 1]), "tau must be"),
    "overshoot of unequal lists": (lambda a, g: metrics.overshoot(RAGGED, 1.0, 0.0), "a step response is numbers"),
    "settling of text": (lambda a, g: metrics.settling_time([0, 1], ["a", "b"], 1.0, 0.0), "a step response is"),
    "saturation of text": (lambda a, g: metrics.saturation(g, ["a", "b"]), "applied must be numbers"),
    "error of a matrix": (
        lambda a, g: metrics.second_order_error([0.0, 1.0], np.ones((3, 3)), 0.0, 5.0, 0.7),
        "e0 and edot0 are a number or one value per component",
    ),
    "servo_ctrl without servos": (
        lambda a, g: actuators.servo_ctrl(None, np.zeros(2), np.zeros(2), np.zeros(2)),
        r"servo_ctrl takes the servos first, Servo.from_model\(model\), got None",
    ),
    "servo_force without servos": (
        lambda a, g: actuators.servo_force(2.0, np.zeros(2), np.zeros(2), np.zeros(2)),
        "servo_force takes the servos first",
    ),
    "renderer without a model": (lambda a, g: render.make_renderer(None, 64, 48), "model must be a mujoco.MjModel"),
    "renderer of text pixels": (lambda a, g: render.make_renderer(a[0], "wide", 48), "width must be a whole number"),
    "renderer of infinite pixels": (lambda a, g: render.make_renderer(a[0], 64, np.inf), "height must be a whole"),
    "renderer of half pixels": (lambda a, g: render.make_renderer(a[0], 64.5, 48), "width must be a whole number"),
    "renderer of a huge integer": (lambda a, g: render.make_renderer(a[0], HUGE, 48), "larger than the model's"),
    "video quality of a huge integer": (
        lambda a, g: render.video_html(
            np.zeros((2, 16, 16, 3), np.uint8), 12, description="the arm traces a circle in the plane", qp=2**70
        ),
        "qp must be a whole number from 0 to 51, got 1180591620717411303424",
    ),
    "video of unequal lists": (
        lambda a, g: render.video_html(RAGGED, 12, description="the arm traces a circle in the plane"),
        r"frames must be a video: an \(F, height, width, 3\) array",
    ),
    "video quality out of range": (
        lambda a, g: render.video_html(
            np.zeros((2, 16, 16, 3), np.uint8), 12, description="the arm traces a circle in the plane", qp=-1
        ),
        "qp must be a whole number from 0 to 51, got -1",
    ),
    "a 3-D target for the planar arm's OS-CT": (
        lambda a, g: os_ct_torque(*a, "end_effector", np.array([0.5, 0.2, 0.0]), np.zeros(3), np.zeros(3), 64.0, 16.0),
        r"a task of 3 coordinates for 2 joints has no inverse, so give the target as many coordinates as the arm",
    ),
    "a sampled reference built by hand with a missing sample": (
        lambda a, g: trajectories.SampledReference(0.002, np.zeros((5, 3)), np.zeros((4, 3)), np.zeros((5, 3))),
        r"pos, vel and acc must hold one sample per grid time each, got \{'pos': 5, 'vel': 4, 'acc': 5\} samples",
    ),
    "a sampled reference built by hand with no time step": (
        lambda a, g: trajectories.SampledReference(0.0, np.zeros(5), np.zeros(5), np.zeros(5)),
        "dt must be positive, got 0.0",
    ),
    "video frames of 64-bit integers": (
        lambda a, g: render.video_html(
            np.full((2, 16, 16, 3), 300), 12, description="the arm traces a circle in the plane"
        ),
        r"frames must be 8-bit colours \(uint8, 0 to 255.*got int64: convert with np.clip",
    ),
    "video frames as floats of 0 to 255": (  # mediapy clipped them all to white, without a word
        lambda a, g: render.video_html(np.full((2, 16, 16, 3), 200.0), 12, description="the arm traces a circle"),
        r"float frames hold colours from 0 to 1, got 200 to 200 .*divide colours of 0 to 255 by 255",
    ),
    "video frames not finite": (
        lambda a, g: render.video_html(np.full((2, 16, 16, 3), np.nan), 12, description="the arm traces a circle"),
        "frames must be finite: the video holds NaN",
    ),
    "text alternative an array": (lambda a, g: book.text_alternative(np.ones(3)), "needs a text alternative"),
    "initial state holding None": (
        lambda a, g: sim.simulate(*a, lambda m, d: d.qfrc_bias.copy(), 0.01, q0=[0.1, None]),
        r"q0 must be finite, got \[0.1, None\] \(None is not a number: a value never set\?\)",
    ),
    "site poses not finite": (
        lambda a, g: sim.site_positions(a[0], [[0.1, 0.2], [np.nan, 0.0]], 0),
        "q must be finite: row 1 is not",
    ),
    # the mistakes a student makes in the notebooks' own calls, each named with what to do
    "sample's dt and duration swapped": (
        lambda a, g: trajectories.sample(lambda t: trajectories.set_point(t, 1.0), 12.0, 0.002),
        r"duration \(0.002 s\) is shorter than one time step dt \(12 s\): "
        r"the arguments are sample\(reference, dt, duration\)",
    ),
    "RMS of a run recorded without a reference": (
        lambda a, g: metrics.rms(g.err),
        r"the error has 10 samples of no component \(shape \(10, 0\)\).*simulate was given site= and reference=",
    ),
    "a duration never set": (
        lambda a, g: sim.simulate(*a, lambda m, d: d.qfrc_bias.copy(), None),
        r"duration must be a number, got None \(a value never set\?\)",
    ),
    "check's arguments swapped": (
        lambda a, g: check(globals(), "p1_ik"),
        r"swapped: call check\('p1_ik', globals\(\)\)",
    ),
    "check named by a number": (
        lambda a, g: check(1, globals()),
        "first argument is the check's name, such as 'p1_ik'; got 1",
    ),
    "a single-joint law handed a Reference whole": (
        lambda a, g: SingleJoint().simulate(
            lambda t, x: single_joint.computed_torque(
                SingleJoint(), x[0], x[1], trajectories.versine(t, 1.0), 5.0, 2.0
            ),
            0.1,
        ),
        r"missing 2 required positional arguments.*"
        r"compare the call with the law's def line .* A Reference or Gains passed whole also counts as one "
        r"argument: unpack it with \*",
    ),
    "a single-joint law handed the MuJoCo model": (
        lambda a, g: sim.simulate(
            *a,
            lambda m, d: single_joint.computed_torque(m, d.qpos[0], d.qvel[0], 0.0, 0.0, 0.0, 5.0, 1.0) * np.ones(2),
            0.01,
        ),
        "the single-joint laws of labsupport.controllers.single_joint take a plants.SingleJoint as their model",
    ),
    "a controller taking (data, model)": (
        lambda a, g: sim.simulate(*a, lambda data, model: 40.0 * (0.5 - data.qpos) - data.qvel, 0.01),
        "qpos is a field of MuJoCo's data, not of its model: the law was handed the two in the other order",
    ),
    # NumPy keeps a complex number's real part with a mere warning: an IK's (1 - c**2)**0.5 went on
    "a complex initial state": (
        lambda a, g: sim.simulate(*a, lambda m, d: d.qfrc_bias, 0.01, q0=np.array([0.1 + 1j, 0.2])),
        r"q0 holds complex numbers, but angles and torques are real. .*\(1 - c\*\*2\)\*\*0.5",
    ),
    "complex angles to the planar kinematics": (
        lambda a, g: planar_2r.forward_kinematics(np.array([0.3 + 0.5j, 0.2])),
        "q holds complex numbers",
    ),
    "a complex set point": (lambda a, g: trajectories.set_point(0.0, [0.5 + 0.1j, 0.2]), "point holds complex numbers"),
    "np.linalg.solve with the site Jacobian's six rows": (
        lambda a, g: sim.simulate(*a, lambda m, d: np.linalg.solve(dynamics.site_jacobian(m, d, 0), np.zeros(2)), 0.01),
        r"np.linalg.solve and inv take a square matrix; .* 6 rows, "
        r"translation then rotation: the position task takes rows 0–2, \[:3\]",
    ),
}


@pytest.mark.parametrize("call, message", CASES.values(), ids=CASES.keys())
def test_a_bad_argument_is_named_by_the_package(arm, log, call, message):
    with pytest.raises(ValueError, match=message) as err:
        call(arm, log)
    assert "labsupport" in err.traceback[-1].path.parts, f"raised from {err.traceback[-1].path}, not the package"


def test_a_returned_none_inside_a_list_is_named_as_none_not_nan():
    """NumPy reads None as NaN; the student wrote None, and the check's message says so."""
    with pytest.raises(feedback.StudentError, match=r"contains None: \[0.1, 0.2, None\] \(None is not a number"):
        feedback.as_vector("ik_3r", [0.1, 0.2, None], 3)
    with pytest.raises(feedback.StudentError, match=r"contains NaN: \[0.1 nan\]$"):
        feedback.as_vector("ik_3r", np.array([0.1, np.nan]), 2)


def test_the_checks_keep_what_they_should_accept():
    """The stricter conversions still take what they took: any shape, whole floats as pixels."""
    np.testing.assert_array_equal(validate.vector("x", [[1, 2]], None), [[1.0, 2.0]])
    assert validate.whole("width", 320.0, 1) == 320 and validate.whole("qp", np.int64(0), 0, 51) == 0
    assert float(metrics.second_order_error(0.0, 0.1, 0.0, 5.0, 0.7)) == pytest.approx(0.1)
    np.testing.assert_allclose(metrics.second_order_error([0.0], [0.1, 0.2], 0.0, 5.0, 0.7), [[0.1, 0.2]])


def test_gains_given_as_matrices_are_named_by_the_laws_that_meet_them():
    """``ct_joint_torque(..., Kp=100 * np.eye(2), ...)`` said only "v must have shape (2,), got
    shape (2, 2)", naming mass_times's argument; os_ct_torque, jacobian_solve's right-hand side."""
    import mujoco

    from labsupport.controllers.joint_space import ct_joint_torque

    model, data = load_model("planar_2r")
    mujoco.mj_forward(model, data)
    zero, matrix = np.zeros(2), 100.0 * np.eye(2)
    hint = "a gain given as a matrix makes a matrix too: pass Kp and Kd as numbers"
    with pytest.raises(ValueError, match=hint):
        ct_joint_torque(model, data, zero, zero, zero, matrix, 20.0)
    with pytest.raises(ValueError, match=hint):
        os_ct_torque(model, data, "end_effector", np.array([0.5, 0.2]), zero, zero, matrix, 20.0)
    with pytest.raises(ValueError, match=r"(?s)got shape \(3, 2\).*a Reference passed whole .* unpack it, as in \*ref"):
        ct_joint_torque(model, data, trajectories.Reference(zero, zero, zero), zero, zero, 100.0, 20.0)
    with pytest.raises(ValueError, match=r"v must have shape \(2,\), got shape \(3,\)") as caught:
        dynamics.mass_times(model, data, np.zeros(3))  # a vector of the wrong size: no word on gains
    assert "gain" not in str(caught.value)


def test_a_torque_function_in_the_ts_form_given_to_simulate_is_told_the_form_simulate_calls(arm):
    with pytest.raises(TypeError, match=r"not subscriptable\. simulate calls controller\(model, data\); .*data\.qpos"):
        sim.simulate(*arm, lambda t, x: np.array([x[0], x[1]]), 0.01)


def test_a_torque_function_that_writes_into_its_state_is_stopped_as_on_the_mujoco_arm():
    """The solver hands a copy, so a function that added 0.01 to the angle it is handed at every
    call went unnoticed on the analytic arm (``e = state; e -= ...`` too), while the MuJoCo loop
    refuses the same write, which there moves the arm. Now both refuse it, from ``simulate``
    itself, not from inside SciPy's solver."""

    def writes(t, x):
        x[0] += 0.01
        return 0.0

    with pytest.raises(
        ValueError, match=r"wrote into the state it is handed at t = 0.0000 s; .*state.copy\(\)"
    ) as caught:
        SingleJoint().simulate(writes, 0.1, state0=(0.5, 0.0))
    frames = traceback.extract_tb(caught.tb)  # from simulate, not from inside SciPy's solver
    assert "simulate" in [f.name for f in frames] and not any("scipy" in f.filename for f in frames)

    def copies(t, state):
        error = state.copy()
        error -= (np.pi / 2, 0.0)
        return -5.72 * error[0] - 1.9 * error[1]

    log = SingleJoint().simulate(copies, 10.0)
    assert log.q[-1, 0] == pytest.approx(np.pi / 2, abs=1e-3)  # the lab's gains settle it


def test_a_non_square_solve_in_a_problem_law_gets_the_jacobian_rows_hint():
    said = feedback.raised_text("os_ct_torque", "LinAlgError: Last 2 dimensions of the array must be square")
    assert said.endswith(feedback.JACOBIAN_ROWS_HINT) and feedback.SINGULAR_HINT not in said


def test_one_title_given_as_text_titles_the_first_panel_whole():
    """``titles="Free response"`` titled two panels "F" and "r"."""
    from labsupport import plots

    log = SingleJoint().simulate(lambda t, x: -x[0], 0.2, state0=(0.3, 0.0))
    fig = plots.single_joint_figure({"free": log}, ["angle", "rate"], titles="Free response")
    assert [ax.get_title() for ax in fig.axes] == ["Free response", ""]
    plots.plt.close(fig)


def test_a_plant_parameter_given_as_a_one_element_list_is_kept_as_its_number():
    """``SingleJoint(b=[0.1])`` was accepted, then ``simulate`` failed with "can't multiply
    sequence by non-int"; the run now equals that of ``b=0.1``."""
    as_list, as_number = SingleJoint(b=[0.1]), SingleJoint(b=0.1)
    assert as_list == as_number and isinstance(as_list.b, float)
    np.testing.assert_array_equal(
        as_list.simulate(lambda t, x: 0.2, 0.1).q, as_number.simulate(lambda t, x: 0.2, 0.1).q
    )


def test_a_sampled_reference_keeps_its_time_step_as_a_number():
    """A time step given as ``[0.5]`` passed the check and stayed a list in ``dt``."""
    ref = trajectories.SampledReference([0.5], np.arange(3.0), np.zeros(3), np.zeros(3))
    assert isinstance(ref.dt, float) and ref.at(1.0).pos == 2.0 and ref.index(0.6) == 1


def test_a_check_whose_numpy_was_replaced_says_so_instead_of_drawing_forever(monkeypatch):
    """A notebook cell that replaced ``np.linalg.norm`` made the in-notebook check draw test
    configurations for ever (none kept the margins): it now stops and says what to do."""
    import labsupport.grading as grading
    from labsupport.grading import common

    monkeypatch.setattr(np.linalg, "norm", lambda *args, **kwargs: 0.0)
    with pytest.raises(RuntimeError, match="Restart the kernel"):
        grading.check("p2_osct", {"ct_op_torque": lambda *args: np.zeros(3)})
    with pytest.raises(RuntimeError, match=f"drew {common.DRAW_TRIES:,} configurations"):
        common.draw_configuration(np.random.default_rng(0))


def test_a_step_response_given_final_and_initial_swapped_is_warned_about():
    """overshoot(y, initial, final) gave 0 % and settling_time NaN, numbers that look like results;
    a response that starts nearer ``final`` than ``initial`` is warned about, and one given the right
    way round is not."""
    t = np.linspace(0.0, 5.0, 501)
    y = 0.2 + 0.5 * metrics.second_order_step(t, 3.0, 0.5)  # from 0.2 to 0.7
    with pytest.warns(
        RuntimeWarning,
        match=r"goes from 0.2 to 0.69\d*, from near final = 0.2 to near initial = 0.7: are the two swapped",
    ):
        assert metrics.overshoot(y, 0.2, 0.7) == 0.0
    with pytest.warns(RuntimeWarning, match="are the two swapped"):
        metrics.settling_time(t, y, 0.2, 0.7)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert abs(metrics.overshoot(y, 0.7, 0.2) - 16.30) < 0.01
        assert 2.0 < metrics.settling_time(t, y, 0.7, 0.2) < 3.0


def test_an_overshoot_given_as_a_fraction_is_warned_about():
    """spec_gains(M, b, 0.1, 2.0), meant as 10 %, designed for 0.1 % (ζ = 0.91) without a word;
    band= takes fractions, so the two conventions are easy to mix up."""
    with pytest.warns(
        RuntimeWarning, match=r"percent_overshoot = 0.1 asks for 0.1 %.* it is a percentage: 10 for 10 %"
    ):
        _, design = gains.spec_gains(0.5, 0.1, 0.1, 2.0)
    assert design.zeta > 0.9
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert abs(gains.spec_gains(0.5, 0.1, 10.0, 2.0)[1].zeta - 0.591) < 1e-3
