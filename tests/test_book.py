"""labsupport.book.show_figure: the figure and its text alternative travel together."""

import base64
import dataclasses
import io

import matplotlib

matplotlib.use("Agg")

import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pytest  # noqa: E402

from labsupport import book, plots  # noqa: E402

ALT = "Speed in rad/s rising to 10 rad/s within 5 s, the simulation on the closed form."


@pytest.fixture()
def shown(monkeypatch):
    outputs = []

    def display(bundle, raw, metadata):
        outputs.append({**bundle, "metadata": metadata})

    monkeypatch.setattr(book, "display", display)
    return outputs


def two_curves(**second):
    fig, ax = plt.subplots()
    t = np.linspace(0, 1, 50)
    ax.plot(t, t, label="simulation")
    ax.plot(t, t**2, **{"label": "closed form", **second})
    ax.set_title("speed")
    return fig


def test_the_image_carries_the_alt_and_the_png(shown):
    fig = two_curves(linestyle="--")
    book.show_figure(fig, ALT + ' <script>"&')
    (bundle,) = shown
    html, png = bundle["text/html"], base64.b64decode(bundle["image/png"])
    assert png.startswith(b"\x89PNG") and bundle["image/png"] in html
    assert 'alt="Speed in rad/s rising to 10 rad/s' in html and "&lt;script&gt;&quot;&amp;" in html
    assert "<script>" not in html
    assert bundle["text/plain"] == ALT + ' <script>"&'
    assert f'width="{round(int.from_bytes(png[16:20], "big") / book.PIXEL_DENSITY)}"' in html
    assert not plt.fignum_exists(fig.number)  # closed: the inline backend will not show it again


def test_the_text_alternative_is_also_written_under_the_figure_collapsed(shown):
    """A sighted reader can read the description too, and a screen-reader user can move through
    it word by word, which an alt does not allow: the same text, escaped, in a <details> after
    the image, inside one <figure> no wider than the image."""
    book.show_figure(np.zeros((24, 32, 3), dtype=np.uint8), ALT + " <b>&")
    html = shown[0]["text/html"]
    escaped = ALT + " &lt;b&gt;&amp;"
    assert html.startswith('<figure class="course-figure" style="margin: 0; padding: 0; max-width: 32px"><img ')
    assert html.endswith(f"<details><summary>{book.FIGURE_IN_WORDS}</summary><p>{escaped}</p></details></figure>")
    assert html.count(escaped) == 2 and "<b>" not in html


def png_width(bundle) -> int:
    return int.from_bytes(base64.b64decode(bundle["image/png"])[16:20], "big")


def test_a_figure_is_shown_at_the_inline_backends_size_with_twice_its_pixels(shown):
    """The page shows a figure as wide as a notebook's inline backend would (``width``), drawn
    with twice the pixels each way, so its labels stay sharp on a phone's screen and zoomed in."""
    with plt.rc_context({"figure.dpi": 90}):  # as the notebooks draw them
        fig = two_curves(linestyle="--")
    inline = io.BytesIO()
    fig.savefig(inline, format="png", bbox_inches="tight")
    inline_width = int.from_bytes(inline.getvalue()[16:20], "big")
    book.show_figure(fig, ALT)
    (bundle,) = shown
    assert abs(png_width(bundle) - 2 * inline_width) <= 2, (png_width(bundle), inline_width)
    assert abs(bundle["metadata"]["image/png"]["width"] - inline_width) <= 1
    assert f'width="{bundle["metadata"]["image/png"]["width"]}"' in bundle["text/html"]


def test_a_rendered_frame_is_shown_too(shown):
    """A rendered frame is shown pixel for pixel."""
    frame = np.zeros((24, 32, 3), dtype=np.uint8)
    book.show_figure(frame, ALT)
    assert base64.b64decode(shown[0]["image/png"])[16:24] == (32).to_bytes(4, "big") + (24).to_bytes(4, "big")
    assert shown[0]["metadata"] == {"image/png": {"width": 32}} and 'width="32"' in shown[0]["text/html"]


def test_a_picture_rendered_at_twice_its_size_is_shown_at_its_size(shown):
    """A frame rendered with two pixels each way per pixel shown (render.show_picture) keeps
    them all and asks for half its width; a density that is not a whole number is refused."""
    book.show_figure(np.zeros((48, 64, 3), dtype=np.uint8), ALT, density=2)
    assert png_width(shown[0]) == 64 and shown[0]["metadata"] == {"image/png": {"width": 32}}
    assert 'width="32"' in shown[0]["text/html"]
    for density in (0, 1.5, "2"):
        with pytest.raises(ValueError, match="density"):
            book.show_figure(np.zeros((4, 4, 3), dtype=np.uint8), ALT, density=density)


@pytest.mark.parametrize(
    ("printed", "written"),
    [
        ("ends at 1.4e-09 mm", "ends at 1.4 × 10⁻⁹ mm"),
        ("a floor of 4e-13 degrees", "a floor of 4 × 10⁻¹³ degrees"),
        ("from -2.50e+03 to 1e6 N", "from -2.50 × 10³ to 1 × 10⁶ N"),
        ("file v1.2e3, time step 2e, sensor e-3, 1e-", "file v1.2e3, time step 2e, sensor e-3, 1e-"),
    ],
)
def test_exponent_notation_is_written_as_a_power_of_ten(printed, written):
    assert book.power_of_ten(printed) == written


def test_a_text_alternative_says_exponents_as_powers_of_ten(shown):
    book.show_figure(np.zeros((4, 4, 3), dtype=np.uint8), f"The error falls to {1.4e-9:.1e} mm within one second.")
    (bundle,) = shown
    assert bundle["text/plain"] == "The error falls to 1.4 × 10⁻⁹ mm within one second."
    assert 'alt="The error falls to 1.4 × 10⁻⁹ mm within one second."' in bundle["text/html"]


@pytest.mark.parametrize("alt", ["", "a plot", "../_images/ab12.png", "   "])
def test_an_alt_that_says_nothing_is_refused(shown, alt):
    with pytest.raises(ValueError, match="text alternative of at least 5 words"):
        book.show_figure(two_curves(linestyle="--"), alt)
    assert shown == []


@pytest.mark.parametrize("figure", [None, plt, [[0, 1], [1, 0]]])
def test_what_is_neither_a_figure_nor_an_image_is_named(shown, figure):
    """``show_figure(plt, ...)`` or a forgotten ``fig =`` used to end in an AttributeError from inside."""
    with pytest.raises(ValueError, match=r"a Matplotlib figure \(fig from plt.subplots\(\)\) or an RGB image array"):
        book.show_figure(figure, ALT)
    assert shown == []


def test_curves_told_apart_by_colour_alone_are_refused(shown):
    with pytest.raises(ValueError, match=r"panel 'speed'.*'simulation' and 'closed form' differ by colour alone"):
        book.show_figure(two_curves(), ALT)
    assert shown == []


@pytest.mark.parametrize("second", [dict(linestyle="--"), dict(marker="o"), dict(lw=5.0), dict(label="_hidden")])
def test_a_line_style_a_marker_a_band_or_no_label_is_enough(shown, second):
    book.show_figure(two_curves(**second), ALT)
    assert len(shown) == 1


def test_the_course_cycle_gives_six_distinct_curves(shown):
    with plt.rc_context():
        plots.course_style()
        fig, ax = plt.subplots()
        for k in range(6):
            ax.plot([0, 1], [k, k + 1], label=f"curve {k}")
        book.show_figure(fig, ALT)
        fig, ax = plt.subplots()
        for k in range(7):
            ax.plot([0, 1], [k, k + 1], label=f"curve {k}")
        with pytest.raises(ValueError, match="'curve 0' and 'curve 6'"):
            book.show_figure(fig, ALT)


def _log(t, offset, joints):
    """A run of ``joints`` joints all at the lab's sinusoid plus ``offset``, with a tip on the unit circle."""
    from labsupport import sim
    from labsupport.trajectories import sinusoid

    q = np.tile((sinusoid(t).pos + offset)[:, None], (1, joints))
    ee = np.c_[np.cos(q[:, 0]), np.sin(q[:, 0]), np.zeros_like(t)]
    none = np.empty((len(t), 0))
    return sim.Log(t, q, q, q, q, ee, np.zeros((len(t), 3, 3)), none, none)


def test_a_run_keeps_its_colour_in_every_panel_and_single_points_are_drawn():
    """Under the course's style, a reference band (or the workspace's circles) drawn first
    shifted the colour cycle in one panel only, so a run changed colour between panels; and the
    cycle's markevery left the reaching figure's start dot and target star undrawn."""
    from labsupport.trajectories import sinusoid

    t = np.linspace(0.0, 1.0, 11)
    plots.course_style()
    try:
        runs = {"FB": _log(t, 0.1, 1), "FF+FB": _log(t, 0.01, 1)}
        fig = plots.single_joint_figure(runs, ["angle", "error"], reference=sinusoid)
        colours = [{line.get_label(): line.get_color() for line in ax.lines} for ax in fig.axes]
        assert colours[0]["FB"] == colours[1]["FB"] == "C0" and colours[0]["FF+FB"] == colours[1]["FF+FB"] == "C1"
        plt.close(fig)
        runs = {"PD": _log(t, 0.1, 2), "CT": _log(t, 0.01, 2)}
        fig = plots.reaching_figure(runs, [0.0, 0.0], [0.5, 0.5], (0.1, 1.0))
        (panel,) = [ax for ax in fig.axes if ax.get_title() == "end-effector path"]
        path = {line.get_label(): line for line in panel.lines}
        assert path["start"].get_markevery() is None and path["target"].get_markevery() is None
        assert path["PD"].get_color() == "C0" and path["CT"].get_color() == "C1"
        plt.close(fig)
    finally:
        plt.rcdefaults()


def test_error_panels_show_desired_minus_actual():
    """The theory page's convention, e = desired - actual, on every error panel: a run that sits
    above its reference plots a negative error, and the axis says which way round it is."""
    from labsupport.trajectories import sinusoid

    t = np.linspace(0.0, 1.0, 11)
    fig = plots.single_joint_figure({"run": _log(t, 0.1, 1)}, ["error"], reference=sinusoid)
    (ax,) = fig.axes
    assert ax.get_ylabel() == r"$\theta_d - \theta$ [deg]"
    np.testing.assert_allclose(ax.lines[0].get_ydata(), -np.degrees(0.1))
    plt.close(fig)
    fig = plots.reaching_figure({"run": _log(t, 0.1, 2)}, [0.0, 0.0], [0.5, 0.5], (0.1, 1.0))
    for j, title in enumerate(("joint 1 error", "joint 2 error")):
        (ax,) = [a for a in fig.axes if a.get_title() == title]
        assert ax.get_ylabel() == f"$q_{{d,{j + 1}}} - q_{j + 1}$ [deg]"
        np.testing.assert_allclose(ax.lines[0].get_ydata(), -np.degrees(sinusoid(t).pos + 0.1))
    plt.close(fig)


def test_the_closed_form_figure_lets_each_line_style_show_between_the_simulated_marks():
    """The simulations were drawn as a dot at every sample, which covered the closed forms'
    line styles, the one cue besides colour: now a few hollow circles per curve, named in the
    legend."""
    t = np.linspace(0.0, 30.0, 301)
    fig = plots.closed_form_figure({"p": {"a": (t, t, t + 0.01), "b": (t, 2 * t, 2 * t)}}, "y")
    (ax,) = fig.axes
    marks = [line for line in ax.lines if line.get_marker() == "o"]
    assert len(marks) == 3  # two runs and the legend's entry
    for line in marks[:2]:
        assert 2 <= len(line.get_xdata()) <= plots.SIMULATION_MARKS and line.get_markerfacecolor() == "none"
    np.testing.assert_allclose(marks[0].get_ydata(), marks[0].get_xdata() + 0.01)
    labels = [text.get_text() for text in ax.get_legend().get_texts()]
    assert labels == ["a", "b", "simulated (circles)"]
    plt.close(fig)


def test_the_reaching_paths_legend_hides_no_workspace_circle():
    """The path panel's workspace circles fill the panel, so a legend inside it (matplotlib's
    "best" place was the left edge) hid part of the outer circle: it sits below the panel, in
    full, with every run and both markers."""
    t = np.linspace(0.0, 1.0, 11)
    fig = plots.reaching_figure({"PD": _log(t, 0.1, 2), "CT": _log(t, 0.01, 2)}, [0.0, 0.0], [0.5, 0.5], (0.1, 1.0))
    fig.canvas.draw()
    (panel,) = [ax for ax in fig.axes if ax.get_title() == "end-effector path"]
    legend = panel.get_legend()
    assert [text.get_text() for text in legend.get_texts()] == ["PD", "CT", "start", "target"]
    box, frame = panel.get_window_extent(), legend.get_window_extent()
    assert frame.y1 < box.y0 and box.x0 <= frame.x0 and frame.x1 <= box.x1 + 1
    assert frame.y0 >= fig.bbox.y0
    plt.close(fig)


@pytest.mark.parametrize("dpi", [80, 90])
@pytest.mark.parametrize("name", ["reaching", "circle", "side_by_side", "stacked", "closed_form"])
def test_the_shared_figures_fit_the_text_column(name, dpi):
    """At the notebooks' dpi each figure is at most 752 px wide, the page's text column, as a
    notebook's inline backend saves it (tight box, 0.1 in of padding): the page shows it
    unscaled, so its tick labels and legends keep their size. The circle figure used to be
    961 px wide and Task 1's side-by-side ones 910 px, shown at 78 % and 83 %."""

    t = np.linspace(0.0, 1.0, 11)
    log = dataclasses.replace(_log(t, 0.1, 2), err=np.zeros((t.size, 2)))
    one = _log(t, 0.1, 1)  # the single joint's figures take one-joint logs
    make = {
        "reaching": lambda: plots.reaching_figure({"PD": log}, [0.0, 0.0], [0.5, 0.5], (0.1, 1.0)),
        "circle": lambda: plots.circle_tracking_figure({"OS-CT": log, "IK": log}, log.ee[:, :2]),
        "side_by_side": lambda: plots.single_joint_figure({"a": one}, ["angle", "torque"], side_by_side=True),
        "stacked": lambda: plots.single_joint_figure({"a": one}, ["angle", "rate", "torque"]),
        "closed_form": lambda: plots.closed_form_figure({"p": {"a": (t, t, t)}, "q": {"b": (t, t, t)}}, "y"),
    }
    with plt.rc_context({"figure.dpi": dpi}):
        fig = make[name]()
        buffer = io.BytesIO()
        fig.savefig(buffer, format="png", bbox_inches="tight", pad_inches=0.1)
    plt.close(fig)
    width = int.from_bytes(buffer.getvalue()[16:20], "big")
    assert plots.TEXT_COLUMN_PX - 40 <= width <= plots.TEXT_COLUMN_PX, width


def test_coinciding_torques_of_two_runs_both_stay_visible():
    """Task 3's two laws give the same torques: the second run's lines used to hide the first's
    completely. Each run is now drawn narrower than the one before, over it."""
    t = np.linspace(0.0, 1.0, 11)
    log = dataclasses.replace(_log(t, 0.1, 2), err=np.zeros((t.size, 2)))
    fig = plots.circle_tracking_figure({"OS-CT": log, "IK": log}, log.ee[:, :2])
    torques = next(ax for ax in fig.axes if ax.get_title() == "joint torques")
    widths = {line.get_label(): line.get_linewidth() for line in torques.get_lines()}
    plt.close(fig)
    for j in (1, 2):
        assert widths[rf"OS-CT $\tau_{j}$"] >= 2 * widths[rf"IK $\tau_{j}$"], widths
    order = [line.get_label() for line in torques.get_lines()]
    assert order.index(r"OS-CT $\tau_1$") < order.index(r"IK $\tau_1$")  # the wide one underneath


def test_a_one_joint_set_point_gives_one_error_curve_and_misuse_is_named():
    """A set point's ``pos`` has shape (N, 1), which minus ``log.q[:, 0]`` (N,) broadcast to N×N:
    the error panel drew 300 curves. Also: one quantity named as a string, and no runs."""
    from labsupport.plants import SingleJoint
    from labsupport.trajectories import set_point

    log = SingleJoint().simulate(lambda t, s: 0.1, 0.3)
    fig = plots.single_joint_figure({"run": log}, ["error"], reference=lambda t: set_point(t, [0.5]))
    (ax,) = fig.axes
    (line,) = ax.lines
    np.testing.assert_allclose(line.get_ydata(), np.degrees(0.5 - log.q[:, 0]))
    plt.close(fig)
    with pytest.raises(ValueError, match="name at least one quantity"):  # matplotlib's gridspec error before
        plots.single_joint_figure({"run": log}, [])
    for panels in ({}, "x"):
        with pytest.raises(ValueError, match="panels must map each panel's title to its curves"):
            plots.closed_form_figure(panels, "y")
    fig = plots.single_joint_figure({"run": log}, "angle")
    assert len(fig.axes) == 1 and fig.axes[0].get_ylabel() == "θ [deg]"
    plt.close(fig)
    with pytest.raises(ValueError, match="runs must map a label to each run's Log"):
        plots.single_joint_figure({}, ["angle"])
    with pytest.raises(ValueError, match="one angle per time"):
        plots.single_joint_figure({"run": log}, ["error"], reference=lambda t: 0.5)
    plt.close("all")


def test_frame_indices_need_a_whole_number_of_samples():
    with pytest.raises(ValueError, match="n_samples must be a whole number"):
        plots.frame_indices(10.5, 0.01, 12)
    assert plots.frame_indices(np.int64(100), 0.01, 10).dtype.kind == "i"


def test_figure_arguments_of_the_wrong_kind_are_named():
    """A level that is not a (label, value) pair, a target with a third coordinate, and a video
    size given as floats or odd numbers: each used to end in an unpacking or type error."""
    from labsupport.kinematics.planar_2r import LAB_ARM

    t = np.linspace(0.0, 1.0, 11)
    with pytest.raises(ValueError, match=r"level must be a pair \(label, value\)"):
        plots.single_joint_figure({"run": _log(t, 0.1, 1)}, ["angle"], level=0.5)
    with pytest.raises(ValueError, match=r"target \(x, y\) must have shape \(2,\)"):
        plots.reaching_figure({"run": _log(t, 0.1, 2)}, [0.0, 0.0], [0.5, 0.5, 0.1], (0.1, 1.0))
    q = np.zeros((3, 2))
    frames = plots.planar_arm_frames([dict(q=q, title="arm")], LAB_ARM, t=t[:3], size=(64.0, 48.0))
    assert frames.shape[1:] == (48, 64, 3)
    with pytest.raises(ValueError, match="two positive even whole numbers"):
        plots.planar_arm_frames([dict(q=q, title="arm")], LAB_ARM, t=t[:3], size=(63, 48))
    plt.close("all")


def test_the_task3_figures_name_a_run_without_a_site_or_reference():
    """Without site= the figures ended in an IndexError; without reference= the error panel drew a
    flat 0 mm while the arm was 57 mm off."""
    from dataclasses import replace

    t = np.linspace(0.0, 1.0, 11)
    run = _log(t, 0.1, 2)
    no_site = replace(run, ee=np.empty((11, 0)))
    with pytest.raises(ValueError, match=r"run 'PD': the log has no end-effector position: pass site="):
        plots.reaching_figure({"PD": no_site}, [0.0, 0.0], [0.5, 0.5], (0.1, 1.0))
    path = np.c_[np.cos(t), np.sin(t)]
    with pytest.raises(ValueError, match=r"run 'OS-CT': the log has no position error: pass site= and reference="):
        plots.circle_tracking_figure({"OS-CT": _log(t, 0.1, 2)}, path)
    with pytest.raises(ValueError, match=r"desired_path must be the circle's points, an \(N, 2\) array"):
        tracked = replace(run, ref=path, err=path - run.ee[:, :2])
        plots.circle_tracking_figure({"OS-CT": tracked}, lambda t: path)
    plt.close("all")


def test_planar_arm_frames_names_a_panel_or_arm_of_the_wrong_kind():
    """A panel without a title was a KeyError, a 1-D ref an IndexError, the arm's lengths as a
    tuple an AttributeError, float frames "slice indices must be integers"."""
    from labsupport.kinematics.planar_2r import LAB_ARM

    q = np.zeros((3, 2))
    cases = [
        (dict(panels=[dict(q=q)], arm=LAB_ARM), r"panel 0 must be a dict with q .* and title"),
        (dict(panels={"q": q, "title": "a"}, arm=LAB_ARM), "panels must be a list of dicts"),
        (
            dict(panels=[dict(q=q, title="a", ref=np.zeros(3))], arm=LAB_ARM),
            r"panel 0 \(a\): ref must have shape \(N, 2\)",
        ),
        (dict(panels=[dict(q=q, title="a", target=[0.5, 0.2, 0.1])], arm=LAB_ARM), r"target must have shape \(2,\)"),
        (dict(panels=[dict(q=q, title="a")], arm=(0.5, 0.4)), "arm must be a Planar2R"),
        (dict(panels=[dict(q=q, title="a")], arm=LAB_ARM, frames=[0.0, 1.0]), "frames must be whole sample indices"),
    ]
    for kwargs, words in cases:
        with pytest.raises(ValueError, match=words):
            plots.planar_arm_frames(**kwargs, size=(64, 48))
    right = [dict(q=q, title="a", path=[[0.5, 0.2], [0.4, 0.2]])]  # a path given as a list is fine
    assert plots.planar_arm_frames(right, LAB_ARM, size=(64, 48)).shape == (3, 48, 64, 3)
    plt.close("all")


def test_planar_arm_frames_names_panels_of_different_lengths():
    from labsupport.kinematics.planar_2r import LAB_ARM

    q = np.zeros((3, 2))
    with pytest.raises(ValueError, match=r"same samples, one row per time; got lengths \[2, 3\]"):
        plots.planar_arm_frames([dict(q=q, title="a"), dict(q=q[:2], title="b")], LAB_ARM)
    with pytest.raises(ValueError, match=r"got lengths \[3, 4\]"):
        plots.planar_arm_frames([dict(q=q, title="a")], LAB_ARM, t=np.arange(4.0))
    with pytest.raises(ValueError, match=r"frames must be sample indices in \[0, 2\]"):
        plots.planar_arm_frames([dict(q=q, title="a")], LAB_ARM, frames=[0, 5])
    plt.close("all")


def test_a_figure_flag_that_is_not_true_or_false_is_named():
    """side_by_side="no" and legend="no" would otherwise act as True."""
    t = np.linspace(0.0, 1.0, 11)
    log = _log(t, 0.1, 1)
    with pytest.raises(ValueError, match="side_by_side must be True or False"):
        plots.single_joint_figure({"a": log}, ["angle"], side_by_side="no")
    fig, ax = plt.subplots()
    with pytest.raises(ValueError, match="legend must be True or False"):
        plots.single_joint_panel(ax, {"a": log}, "angle", legend="no")
    plt.close(fig)


def test_planar_arm_frames_refuses_a_video_that_would_fill_the_memory():
    """By default every sample became a frame: a 10 s run logged every millisecond would have
    drawn 10,000 frames, about 3.5 GB; a size of 20000 x 20000 took 1.2 GB per frame."""
    from labsupport.kinematics.planar_2r import LAB_ARM

    q = np.zeros((plots.MAX_FRAMES + 1, 2))
    with pytest.raises(ValueError, match=rf"{plots.MAX_FRAMES + 1} frames is more than {plots.MAX_FRAMES}"):
        plots.planar_arm_frames([dict(q=q, title="a")], LAB_ARM, size=(64, 48))
    with pytest.raises(ValueError, match=r"size must be at most 1920 x 1080 pixels"):
        plots.planar_arm_frames([dict(q=q[:2], title="a")], LAB_ARM, size=(20000, 20000))
    picked = plots.frame_indices(len(q), 0.002, fps=30)
    video = plots.planar_arm_frames([dict(q=q, title="a")], LAB_ARM, frames=picked, size=(64, 48))
    assert video.shape == (len(picked), 48, 64, 3)
    plt.close("all")


# --- show_law: a law's code under its equation, its docstring left out ---------------------------


def _documented(theta, Kp):
    r"""PD feedback: :math:`\tau = K_p\,\theta`.

    .. math:: \tau = K_p\theta
    """
    # the spring term
    return Kp * theta


def _bare(x):
    return 2 * x


def _one_liner(x):
    """Twice ``x``."""; return 2 * x  # fmt: skip # noqa: E702


class _Holder:
    def method(self, x):
        """Indented, as a method's source is."""
        return x + 1


def test_law_source_leaves_out_the_docstring_and_keeps_the_code():
    assert book.law_source(_documented) == "def _documented(theta, Kp):\n    # the spring term\n    return Kp * theta\n"
    assert book.law_source(_bare) == "def _bare(x):\n    return 2 * x\n"
    assert book.law_source(_Holder.method) == "    def method(self, x):\n        return x + 1\n"
    # a docstring that shares its line with code stays, so no code is lost
    assert "return 2 * x" in book.law_source(_one_liner)


def test_show_law_displays_the_code_as_a_python_block(monkeypatch):
    shown = []
    monkeypatch.setattr(book, "display", shown.append)
    book.show_law(_documented)
    text = shown[0].data
    assert text.startswith("```python\ndef _documented(theta, Kp):") and text.endswith("```")
    assert "math" not in text
    with pytest.raises(ValueError, match="defined in a source file"):
        book.show_law(len)


def test_glue_prints_the_value_where_no_book_can_fill_the_text_in(monkeypatch, capsys):
    """On Colab (no MyST-NB) the Markdown shows {glue:text}`t1_tau_c:.2f` as written, and the value
    was stored nowhere a student could see: glue now prints it by its name. Where MyST-NB is
    present, it records the value (a NumPy scalar as a Python number) and prints nothing."""
    import sys

    monkeypatch.setitem(sys.modules, "myst_nb", None)  # import myst_nb now raises ImportError
    book.glue("t1_tau_c", np.float64(5.0))
    book.glue("t1_third", 1 / 3)
    book.glue("t1_word", "never")
    assert capsys.readouterr().out == "t1_tau_c = 5\nt1_third = 0.333333\nt1_word = never\n"

    recorded = []
    fake = type(sys)("myst_nb")
    fake.glue = lambda name, value, display: recorded.append((name, value, type(value), display))
    monkeypatch.setitem(sys.modules, "myst_nb", fake)
    book.glue("t1_tau_c", np.float64(5.0))
    assert recorded == [("t1_tau_c", 5.0, float, False)] and capsys.readouterr().out == ""
