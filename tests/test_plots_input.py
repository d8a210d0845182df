"""labsupport.plots: bad arguments of the figure functions end in a ValueError that names them,
says what was expected, what came instead and what to do; the calls the notebooks make still draw.

Each test first makes the call as the notebooks make it (a check that refused good input fails
here), then the bad calls a tester found, which used to raise a TypeError, AttributeError or
IndexError from inside NumPy or Matplotlib, or to draw a wrong figure without complaint.
"""

import dataclasses
import re
from functools import partial

import matplotlib

matplotlib.use("Agg")

import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pytest  # noqa: E402

from labsupport import plots, sim  # noqa: E402
from labsupport.kinematics import planar_2r as k2  # noqa: E402
from labsupport.plants import SingleJoint, load_model  # noqa: E402
from labsupport.trajectories import circle_2d, sinusoid  # noqa: E402

ARM = k2.LAB_ARM
CIRCLE = partial(circle_2d, center=(0.5, 0.2), radius=0.15, period=6.0)  # Task 3.2's circle


@pytest.fixture(autouse=True)
def _no_figure_left_open():
    """Every figure a test makes is closed; a refused call leaves none open (it is checked
    before the figure is made, else an empty grid would show under the notebook's error)."""
    plt.close("all")
    yield
    plt.close("all")


def refused(call, *words: str) -> str:
    """The ValueError's message of ``call()``, which must hold each of ``words`` (literal text),
    and must leave no figure open."""
    with pytest.raises(ValueError) as raised:
        call()
    message = str(raised.value)
    for word in words:
        assert re.search(re.escape(word), message), f"{word!r} not in: {message}"
    assert not plt.get_fignums(), "a refused call left a figure open"
    return message


def _planar_runs(duration: float = 0.3, reference=None) -> dict[str, sim.Log]:
    """Two runs of the lab's 2R arm logged as Task 3 logs them (site, optionally a reference)."""
    model, data = load_model("planar_2r")
    hold = np.zeros(2)
    return {
        name: sim.simulate(
            model,
            data,
            lambda m, d, gain=gain: gain * (hold - d.qpos),
            duration,
            q0=[0.2, 0.3],
            site="end_effector",
            reference=reference,
            log_after_step=True,
        )
        for name, gain in (("PD", 40.0), ("CT", 80.0))
    }


def _with_a_third_joint(log: sim.Log) -> sim.Log:
    """``log`` as if its arm had a third joint (one more column of q, qdot, tau)."""
    more = {name: np.c_[getattr(log, name), getattr(log, name)[:, :1]] for name in ("q", "qdot", "tau", "ctrl")}
    return dataclasses.replace(log, **more)


# --- reaching_figure ------------------------------------------------------------------------------


def test_reaching_figure_names_a_bad_q_d_reach_or_arm():
    runs = _planar_runs()
    target = k2.sample_annulus(np.random.default_rng(42), ARM, margin=0.05)
    q_d = k2.inverse_kinematics(target, ARM, elbow_up=True)
    fig = plots.reaching_figure(runs, q_d, target, (ARM.reach_min, ARM.reach_max))  # as Task 3 calls it
    assert len(fig.axes) == 6
    (path,) = [ax for ax in fig.axes if ax.get_title() == "end-effector path"]
    radii = sorted(np.hypot(*line.get_xydata()[0]) for line in path.lines[:2])  # the workspace's circles
    np.testing.assert_allclose(radii, [ARM.reach_min, ARM.reach_max])
    plt.close(fig)

    reach = (ARM.reach_min, ARM.reach_max)
    refused(lambda: plots.reaching_figure(runs, None, target, reach), "q_d", "shape (2,)", "None")
    refused(
        lambda: plots.reaching_figure(runs, q_d, target, ARM),  # the arm where its reach belongs
        "reach must be numbers of shape (2,)",
        "Planar2R",
        "pass (arm.reach_min, arm.reach_max)",
    )
    refused(
        lambda: plots.reaching_figure(runs, q_d, target, (0.9, 0.1)),
        "reach is the workspace's inner and outer radius",
        "smallest first",
        "got (0.9, 0.1)",
    )


def test_reaching_figure_refuses_runs_of_an_arm_without_two_joints():
    """Joint 3 of a 3-joint arm was dropped without a word."""
    runs = _planar_runs()
    runs["PD"] = _with_a_third_joint(runs["PD"])
    refused(
        lambda: plots.reaching_figure(runs, [0.0, 0.0], [0.5, 0.5], (ARM.reach_min, ARM.reach_max)),
        "run 'PD'",
        "2-joint arm",
        f"shape ({len(runs['PD'].t)}, 3)",
        "pass the runs of the planar 2R arm",
    )


# --- single_joint_figure and single_joint_panel ---------------------------------------------------


def _one_joint_runs() -> dict[str, sim.Log]:
    arm = SingleJoint()
    return {
        "PD": arm.simulate(lambda t, x: 3.0 * (0.5 - x[0]) - 0.5 * x[1], 0.5),
        "P only": arm.simulate(lambda t, x: 3.0 * (0.5 - x[0]), 0.5),
    }


def test_single_joint_figures_as_the_notebooks_draw_them():
    runs = _one_joint_runs()
    fig = plots.single_joint_figure(
        runs,
        ["angle", "rate", "torque"],
        titles=["PD position control, horizontal arm"],
        level=(r"$\theta_d$", 0.5),
        limit=1.5,
    )
    angle, _, torque = fig.axes
    assert [text.get_text() for text in angle.texts] == [r"$\theta_d$"]
    level = [line for line in angle.lines if line.get_linestyle() == ":"]
    np.testing.assert_allclose(level[0].get_ydata(), np.degrees(0.5))
    limits = sorted(line.get_ydata()[0] for line in torque.lines if line.get_color() == "tab:red")
    assert limits == [-1.5, 1.5]
    plt.close(fig)
    fig = plots.single_joint_figure(runs, ["speed", "torque"], side_by_side=True, level=(r"$\omega_d$", np.float64(2)))
    plt.close(fig)
    fig, axes = plt.subplots(1, 2)
    for ax in axes:
        plots.single_joint_panel(ax, {"feedforward": runs["PD"]}, "angle", reference=sinusoid, title="move")
    plt.close(fig)


def test_single_joint_figures_refuse_a_log_of_another_arm_or_a_value_that_is_no_log():
    runs = _one_joint_runs()
    two_joints = _planar_runs()["PD"]
    refused(
        lambda: plots.single_joint_figure({"a": two_joints}, ["angle"]),
        "run 'a'",
        "1-joint arm",
        f"shape ({len(two_joints.t)}, 2)",
        "log.q[:, j]",
    )
    fig, ax = plt.subplots()
    with pytest.raises(ValueError, match=r"run 'a': this figure draws a 1-joint arm's runs"):
        plots.single_joint_panel(ax, {"a": two_joints}, "angle")
    plt.close(fig)
    log = runs["PD"]
    refused(
        lambda: plots.single_joint_figure({"x": (log.t, log.q)}, ["angle"]),
        "run 'x': log must be the Log that labsupport.sim.simulate returns, got tuple",
    )


def test_single_joint_figures_name_a_level_the_wrong_way_round_and_a_limit_that_is_no_number():
    runs = _one_joint_runs()
    refused(
        lambda: plots.single_joint_figure(runs, ["angle"], level=(0.5, "target")),
        "level must be a pair (label, value), the label first",
        "got (0.5, 'target')",
    )
    refused(lambda: plots.single_joint_figure(runs, ["angle"], level=("target", "0.5")), "level's value", "not text")
    refused(lambda: plots.single_joint_figure(runs, ["angle", "torque"], limit="5"), "limit", "not text", "'5'")
    refused(lambda: plots.single_joint_figure(runs, ["torque"], limit=-1.5), "limit", "must be positive")
    fig, ax = plt.subplots()
    with pytest.raises(ValueError, match=r"level must be a pair \(label, value\), the label first"):
        plots.single_joint_panel(ax, runs, "angle", level=(0.5, "target"))
    with pytest.raises(ValueError, match="limit .* must be numbers, not text"):
        plots.single_joint_panel(ax, runs, "torque", limit="5")
    plt.close(fig)


# --- circle_tracking_figure ----------------------------------------------------------------------


def test_circle_tracking_figure_refuses_a_transposed_or_non_finite_path():
    runs = _planar_runs(reference=CIRCLE)
    desired = CIRCLE(np.linspace(0, 6, 301)).pos
    fig = plots.circle_tracking_figure(runs, desired)  # as Task 3 calls it
    (path,) = [ax for ax in fig.axes if ax.get_title() == "end-effector path"]
    assert len(path.lines[0].get_xdata()) == 301
    plt.close(fig)

    refused(
        lambda: plots.circle_tracking_figure(runs, desired.T),
        "desired_path must be the circle's points, an (N, 2) array",
        "got shape (2, 301): transpose it",
    )
    nan = np.full_like(desired, np.nan)
    refused(lambda: plots.circle_tracking_figure(runs, nan), "desired_path must be finite")
    refused(lambda: plots.circle_tracking_figure(runs, [[0.5, None]] * 3), "desired_path must be finite", "None")


def test_circle_tracking_figure_refuses_runs_of_an_arm_without_two_joints():
    """Its torque panel drew joints 1 and 2 only."""
    runs = _planar_runs(reference=CIRCLE)
    runs["CT"] = _with_a_third_joint(runs["CT"])
    refused(
        lambda: plots.circle_tracking_figure(runs, CIRCLE(np.linspace(0, 6, 301)).pos),
        "run 'CT'",
        "2-joint arm",
    )


# --- closed_form_figure --------------------------------------------------------------------------


def _speed_curves(Ms=(0.25, 0.5)) -> dict[str, tuple]:
    """Task 1's step responses: (t, closed form, simulation) for each inertia M."""
    curves = {}
    for M in Ms:
        arm = SingleJoint(M=M, b=0.1)
        log = arm.simulate(lambda t, x: 0.5, 30.0, dt=0.5)
        closed = 0.5 / arm.b * (1 - np.exp(-log.t * arm.b / arm.M))
        curves[f"M = {M}"] = (log.t, closed, log.qdot[:, 0])
    return curves


def test_closed_form_figure_names_a_curve_without_its_simulation_or_of_unequal_lengths():
    curves = _speed_curves()
    fig = plots.closed_form_figure({"varying M": curves, "varying b": _speed_curves((1.0,))}, ylabel="ω [rad/s]")
    assert len(fig.axes) == 2
    plt.close(fig)

    t, closed, simulated = curves["M = 0.25"]
    refused(
        lambda: plots.closed_form_figure({"p": {"a": (t, closed)}}, "y"),
        "panel 'p', curve 'a': each curve is (t, closed_form, simulated)",
        "equal lengths",
        f"shapes [({len(t)},), ({len(t)},)]",
    )
    refused(
        lambda: plots.closed_form_figure({"p": {"a": (t, closed, simulated[:10])}}, "y"),
        "panel 'p', curve 'a'",
        "equal lengths",
        "(10,)",
    )
    refused(
        lambda: plots.closed_form_figure({"p": (t, closed, simulated)}, "y"),  # the curve without its label
        "panel 'p' must map each curve's label to (t, closed_form, simulated)",
    )
