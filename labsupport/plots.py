r"""The figure layouts the notebooks share, and planar-arm animations as MP4 video.

The figure functions return a pyplot figure, which a notebook's inline backend shows at the
end of the cell; the animation draws on a figure of its own, off pyplot, and returns frames.
Videos are drawn with Matplotlib's Agg canvas frame by frame and encoded by :mod:`mediapy`
(H.264 MP4), a few hundred kilobytes each, instead of frame-by-frame HTML.
"""

from __future__ import annotations

import itertools
from collections.abc import Mapping, Sequence

import matplotlib.pyplot as plt
import numpy as np
from cycler import cycler
from matplotlib import rcParamsDefault
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from labsupport import validate
from labsupport.kinematics.planar_2r import checked_arm, elbow_position, forward_kinematics
from labsupport.metrics import cumulative_effort

#: Successive curves of a panel differ in line style or marker as well as in colour (WCAG 2.1,
#: success criterion 1.4.1: colour is never the only cue), six distinct curves per panel. The
#: figure functions below give each run its line style themselves; this cycle is for a
#: notebook's own plots (:func:`course_style`).
CURVE_CYCLE = (
    cycler(color=rcParamsDefault["axes.prop_cycle"].by_key()["color"][:6])  # Matplotlib's own first six
    + cycler(linestyle=["-", "--", "-.", ":", "-", "--"])
    + cycler(marker=["", "", "", "", "o", "s"])
    + cycler(markevery=[None, None, None, None, 0.1, 0.1])
)


def course_style(rc: Mapping | None = None) -> None:
    """Set Matplotlib's defaults for the course's figures: :data:`CURVE_CYCLE`, then ``rc``
    (more ``rcParams``, e.g. ``{"figure.dpi": 90}``)."""
    plt.rcParams.update({"axes.prop_cycle": CURVE_CYCLE, **(rc or {})})


#: Width of the book's text column in CSS pixels (on a screen 1280 px wide or more). A figure
#: no wider shows at full size, so its labels keep the size Matplotlib gave them; a wider one
#: is scaled down to fit, and its tick labels and legends with it.
TEXT_COLUMN_PX = 752


def column_width() -> float:
    """The width in inches of a figure that fills the text column at Matplotlib's current
    ``figure.dpi``: :data:`TEXT_COLUMN_PX` / dpi, less the 0.1 in that a notebook's inline
    backend pads each side with (9.2 in at 80 dpi, 8.16 in at 90)."""
    return TEXT_COLUMN_PX / plt.rcParams["figure.dpi"] - 0.2


def _figure(height, nrows=1, ncols=1, **kwargs):
    """A pyplot figure ``height`` inches tall that fills the text column, with a 2-D array of axes."""
    figsize = (column_width(), height)
    return plt.subplots(nrows, ncols, figsize=figsize, squeeze=False, layout="constrained", **kwargs)


#: What a single-joint panel can show: its axis label and how to read it from a ``sim.Log``
#: (``reference(t)`` gives the desired motion, for the error, which is desired minus actual,
#: :math:`\theta_d - \theta`, as on the theory page).
SINGLE_JOINT_QUANTITIES = {
    "angle": ("θ [deg]", lambda log, ref: np.degrees(log.q[:, 0])),
    "rate": (r"$\dot\theta$ [deg/s]", lambda log, ref: np.degrees(log.qdot[:, 0])),
    "speed": ("ω [rad/s]", lambda log, ref: log.qdot[:, 0]),
    "torque": ("τ [N·m]", lambda log, ref: log.tau[:, 0]),
    "effort": ("∫τ² dt [N²·m²·s]", lambda log, ref: cumulative_effort(log.t, log.tau[:, 0])),
    "error": (r"$\theta_d - \theta$ [deg]", lambda log, ref: np.degrees(_desired_angle(ref, log.t) - log.q[:, 0])),
}


def _desired_angle(reference, t) -> np.ndarray:
    """The joint angle ``reference(t).pos`` at the times ``t``, shape ``(N,)`` whether the
    reference gives ``(N,)`` or ``(N, 1)`` (a set point of one joint), or a ``ValueError``."""
    try:
        return np.asarray(reference(t).pos, dtype=float).reshape(len(t))
    except (AttributeError, TypeError, ValueError):
        raise ValueError(
            "reference must be a function of the time array t returning a Reference whose pos holds one "
            f"angle per time (shape ({len(t)},)), such as lambda t: versine(t, move); got {validate.short(reference)}"
        ) from None


_LINE_STYLES = ("-", "--", "-.", ":")
#: Line width of a desired curve: a wide grey band under the runs, told apart by its width.
REFERENCE_WIDTH = 5.0
#: Markers that tell runs apart where line styles already tell joints apart.
_RUN_MARKERS = ("", "o", "s", "^")


def _runs(runs) -> Mapping[str, object]:
    """``runs`` if it maps labels to logs, at least one, else a ``ValueError`` saying so."""
    if not isinstance(runs, Mapping) or not runs:
        raise ValueError(f"runs must map a label to each run's Log, e.g. {{'PD': log}}; got {validate.short(runs)}")
    return runs


def _logged(runs, site: bool = False, reference: bool = False) -> Mapping[str, object]:
    """``runs`` (as :func:`_runs` checks it) if every run logged a site's position (``site``) and
    its error to a reference (``reference``), else a ``ValueError`` naming the run and what to pass."""
    for label, run in _runs(runs).items():
        try:
            validate.run_log(run, site=site, reference=reference)
        except ValueError as err:
            raise ValueError(f"run {label!r}: {err}") from None
    return runs


def _joints(runs: Mapping[str, object], count: int, instead: str) -> Mapping[str, object]:
    """``runs`` (checked by :func:`_logged`) if every run's arm has ``count`` joints, else a
    ``ValueError`` naming the run and what to do ``instead`` (the figure would drop joints)."""
    for label, run in runs.items():
        if np.ndim(run.q) != 2 or np.shape(run.q)[1] != count:
            raise ValueError(
                f"run {label!r}: this figure draws a {count}-joint arm's runs, one column of q per joint, but the "
                f"log's q has shape {np.shape(run.q)}: {instead}"
            )
    return runs


def _styled(runs: Mapping[str, object]) -> list[tuple[str, object, str, str]]:
    """``(label, run, line style, colour)`` of each run: its colour is ``C0``, ``C1``, ... by its
    place, so a run keeps its colour in every panel, whatever else a panel draws first (a
    reference band or the workspace's circles would otherwise shift Matplotlib's colour cycle)."""
    return [
        (label, run, style, f"C{i}")
        for i, ((label, run), style) in enumerate(zip(_runs(runs).items(), itertools.cycle(_LINE_STYLES)))
    ]


def _points(ax, x, y, fmt: str, **kwargs) -> None:
    """Markers at every point of ``(x, y)``: the course style's cycle gives some lines a
    ``markevery``, which would leave a single point undrawn (and ``markevery=None`` given to
    ``plot`` does not override a cycle's value)."""
    (line,) = ax.plot(x, y, fmt, **kwargs)
    line.set_markevery(None)


def _one_joint(runs) -> Mapping[str, object]:
    """``runs`` if each is the ``sim.Log`` of a one-joint arm, else a ``ValueError`` naming the run."""
    return _joints(_logged(runs), 1, "plot each joint of a larger arm yourself, e.g. ax.plot(log.t, log.q[:, j])")


def _planar_2r(runs, reference: bool = False) -> Mapping[str, object]:
    """``runs`` if each is a ``sim.Log`` of the planar 2R arm with its site (and, with
    ``reference``, its reference) logged, else a ``ValueError`` naming the run."""
    return _joints(_logged(runs, site=True, reference=reference), 2, "pass the runs of the planar 2R arm")


def _single_joint_options(runs, level, limit) -> tuple:
    """``runs``, ``level`` and ``limit`` of the single-joint plots, checked (see :func:`_one_joint`,
    :func:`_level`, :func:`_limit`)."""
    return _one_joint(runs), None if level is None else _level(level), _limit(limit)


def _level(level) -> tuple[str, float]:
    """``level`` as ``(label, value)``, text then a number, else a ``ValueError`` that gives the order."""
    text, value = level if isinstance(level, (tuple, list)) and len(level) == 2 else (None, None)
    if not isinstance(text, str):
        raise ValueError(
            "level must be a pair (label, value), the label first, such as ('target', theta_d); "
            f"got {validate.short(level)}"
        )
    return text, validate.number("level's value", value)


def _limit(limit) -> float | None:
    """``limit`` as a positive number (an actuator's torque limit), or ``None``; else a ``ValueError``."""
    return None if limit is None else validate.number("limit (the torque limit in N·m)", limit, positive=True)


def single_joint_panel(
    ax,
    runs: Mapping[str, object],
    quantity: str,
    *,
    reference=None,
    level=None,
    limit: float | None = None,
    title: str = "",
    legend: bool = True,
):
    r"""Draw one ``quantity`` of :data:`SINGLE_JOINT_QUANTITIES` for every run on ``ax``.

    Args:
        runs: label -> ``sim.Log`` of a one-joint arm; runs after the first are dashed, dash-dotted...
        reference: ``reference(t) -> Reference`` (radians); drawn as "desired" (a wide grey band)
            on an angle panel; an error panel shows desired minus actual, :math:`\theta_d - \theta`.
        level: ``(label, value)``, a dotted horizontal line named above its left end, in the panel's unit before the
            conversion to degrees (radians for an angle, rad/s for a speed).
        limit: the actuator limit, drawn as red dotted lines at :math:`\pm` ``limit`` on a torque panel.
    """
    if quantity not in SINGLE_JOINT_QUANTITIES:
        raise ValueError(f"unknown quantity {quantity!r}; choose one of {list(SINGLE_JOINT_QUANTITIES)}")
    if quantity == "error" and reference is None:
        raise ValueError("an error panel needs the reference: pass reference=<function of t>")
    ylabel, read = SINGLE_JOINT_QUANTITIES[quantity]
    runs, level, limit = _single_joint_options(runs, level, limit)
    first = next(iter(runs.values()))
    if reference is not None and quantity == "angle":
        desired = np.degrees(_desired_angle(reference, first.t))
        ax.plot(first.t, desired, color="0.6", lw=REFERENCE_WIDTH, alpha=0.6, label="desired")
    for label, log, style, color in _styled(runs):
        ax.plot(log.t, read(log, reference), style, color=color, label=label)
    if level is not None:
        text, value = level
        value = np.degrees(value) if quantity in ("angle", "rate") else value
        ax.axhline(value, color="gray", ls=":")
        # named above the line's left end, where the runs start away from it (as a legend entry
        # it crowded the free response's legend onto a curve; under the line, a step response
        # rising through it crossed the name)
        ax.annotate(
            text,
            (0, value),
            xycoords=("axes fraction", "data"),
            xytext=(3, 2),
            textcoords="offset points",
            ha="left",
            va="bottom",
            fontsize=10,
            color="0.3",
        )
    if limit is not None and quantity == "torque":
        for sign in (-1, 1):
            ax.axhline(sign * limit, color="tab:red", ls=":")
    ax.set(xlabel="time [s]", ylabel=ylabel, title=title)
    ax.grid(True, alpha=0.4)
    if validate.flag("legend", legend):
        ax.legend(fontsize=8)


def single_joint_figure(
    runs: Mapping[str, object],
    quantities: Sequence[str],
    *,
    titles: Sequence[str] = (),
    side_by_side: bool = False,
    reference=None,
    level=None,
    limit: float | None = None,
    suptitle: str = "",
):
    """Runs of a one-joint arm compared panel by panel, one panel per quantity (``"angle"``,
    ``"rate"``, ``"speed"``, ``"torque"``, ``"effort"``, ``"error"``), stacked over a shared time
    axis or side by side. ``reference``, ``level`` and ``limit`` are as in
    :func:`single_joint_panel` (``level`` goes on the first panel); ``titles`` name the panels in
    order; the legend is on every side-by-side panel, on the top one when stacked.
    """
    quantities = [quantities] if isinstance(quantities, str) else list(quantities)  # one panel by name
    titles = [titles] if isinstance(titles, str) else list(titles)  # one title, not one letter a panel
    n = len(quantities)
    if not n:
        raise ValueError(f"name at least one quantity to plot, from {list(SINGLE_JOINT_QUANTITIES)}")
    side_by_side = validate.flag("side_by_side", side_by_side)
    # checked before the figure is made, which would otherwise stay open, empty, under the error
    runs, level, limit = _single_joint_options(runs, level, limit)
    shape, height = ((1, n), 3.4) if side_by_side else ((n, 1), 1.1 + 1.8 * n)
    fig, axes = _figure(height, *shape, sharex=not side_by_side)
    axes = axes.ravel()
    for i, (ax, quantity) in enumerate(zip(axes, quantities, strict=True)):
        single_joint_panel(
            ax,
            runs,
            quantity,
            reference=reference,
            level=level if i == 0 else None,
            limit=limit,
            title=titles[i] if i < len(titles) else "",
            legend=side_by_side or i == 0,
        )
        if not side_by_side and i < n - 1:
            ax.set_xlabel("")  # the shared time axis is labelled once, at the bottom
    if suptitle:
        fig.suptitle(suptitle)
    return fig


#: How many simulated samples :func:`closed_form_figure` marks on each curve: few enough that
#: the closed form's line style shows between the (hollow) markers.
SIMULATION_MARKS = 13


def _curves(title, curves) -> dict[str, tuple[np.ndarray, np.ndarray, np.ndarray]]:
    """The curves of the panel ``title`` of :func:`closed_form_figure`, each as three float arrays
    of one length, or a ``ValueError`` naming the panel and the curve."""
    if not isinstance(curves, Mapping) or not curves:
        raise ValueError(
            f"panel {title!r} must map each curve's label to (t, closed_form, simulated), got {validate.short(curves)}"
        )
    checked = {}
    for label, curve in curves.items():
        arrays = [validate.floats(a) for a in curve] if isinstance(curve, (tuple, list)) else []
        shapes = [None if a is None else a.shape for a in arrays]
        n = shapes[0][0] if shapes and shapes[0] else 0
        if not n or shapes != [(n,)] * 3:
            raise ValueError(
                f"panel {title!r}, curve {label!r}: each curve is (t, closed_form, simulated), three 1-D arrays of "
                "equal lengths, such as (log.t, closed, log.qdot[:, 0]); got "
                + (f"arrays of shapes {shapes}" if shapes else validate.short(curve))
            )
        checked[label] = tuple(arrays)
    return checked


def closed_form_figure(panels: Mapping[str, Mapping[str, tuple]], ylabel: str):
    """Simulations (hollow circles at :data:`SIMULATION_MARKS` evenly spread samples) on top of
    their closed forms (lines), one panel per title; each panel maps a label to
    ``(t, closed_form, simulated)``; the panels share the y axis, with room above the highest
    curve for the legends, which name the markers too."""
    if not isinstance(panels, Mapping) or not panels:
        raise ValueError(f"panels must map each panel's title to its curves, got {validate.short(panels)}")
    panels = {title: _curves(title, curves) for title, curves in panels.items()}
    fig, axes = _figure(3.6, 1, len(panels), sharey=True)
    for ax, (title, curves) in zip(axes[0], panels.items(), strict=True):
        for label, (t, closed_form, simulated), style, color in _styled(curves):
            ax.plot(t, closed_form, style, color=color, label=label)
            marks = np.unique(np.linspace(0, len(t) - 1, SIMULATION_MARKS).round().astype(int))
            _points(ax, t[marks], simulated[marks], "o", ms=5, color=color, mfc="none")
        _points(ax, [], [], "o", ms=5, color="0.3", mfc="none", label="simulated (circles)")
        ax.set(title=title, xlabel="time [s]")
        ax.grid(True, alpha=0.4)
    bottom, top = axes[0, 0].get_ylim()
    axes[0, 0].set_ylim(bottom, top + 0.35 * (top - bottom))  # shared: every panel
    for ax in axes[0]:
        ax.legend(fontsize=8, loc="upper left")
    axes[0, 0].set_ylabel(ylabel)
    return fig


def _workspace(ax, reach_min: float, reach_max: float):
    phi = np.linspace(0, 2 * np.pi, 200)
    for radius in (reach_min, reach_max):
        ax.plot(radius * np.cos(phi), radius * np.sin(phi), "k--", lw=0.8, alpha=0.25)


def _reach(reach) -> tuple[float, float]:
    """``reach`` as the workspace's radii ``(reach_min, reach_max)``, smallest first, else a ``ValueError``."""
    what = "reach is the workspace's inner and outer radius in m, smallest first: pass (arm.reach_min, arm.reach_max)"
    try:
        low, high = validate.vector("reach", reach, (2,))
    except ValueError as err:
        raise ValueError(f"{err}; {what}") from None
    if not 0 <= low <= high:
        raise ValueError(f"{what}; got {validate.short(reach)}")
    return low, high


def reaching_figure(runs: Mapping[str, object], q_d, target, reach: tuple[float, float]):
    r"""Task 3.1's six panels for several runs (``sim.Log`` with ``ee``), three rows of two
    that fit a page's text column at full size: the two joint errors
    :math:`q_{d,j} - q_j` (desired minus actual) in degrees, the two joint torques, then the
    end-effector path and the distance to the target in millimetres.
    """
    runs = _planar_2r(runs)
    q_d = validate.vector("q_d (the desired joint angles [q1, q2] in rad)", q_d, (2,))
    target = validate.vector("target (x, y)", target, (2,))
    reach = _reach(reach)
    fig, axes = _figure(10.0, 3, 2)
    for j in range(2):
        ax = axes[0, j]
        for label, log, style, color in _styled(runs):
            ax.plot(log.t, np.degrees(q_d[j] - log.q[:, j]), style, color=color, lw=1.4, label=label)
        ax.axhline(0.0, color="k", lw=0.8, ls="--")
        ax.set(xlabel="time [s]", ylabel=f"$q_{{d,{j + 1}}} - q_{j + 1}$ [deg]", title=f"joint {j + 1} error")
        ax = axes[1, j]
        for label, log, style, color in _styled(runs):
            ax.plot(log.t, log.tau[:, j], style, color=color, lw=1.4, label=label)
        ax.set(xlabel="time [s]", ylabel=rf"$\tau_{j + 1}$ [N·m]", title=f"joint {j + 1} torque")
    ax = axes[2, 0]
    _workspace(ax, *reach)
    first = next(iter(runs.values()))
    for label, log, style, color in _styled(runs):
        ax.plot(log.ee[:, 0], log.ee[:, 1], style, color=color, lw=1.4, label=label)
    _points(ax, *first.ee[0, :2], "go", ms=7, label="start")
    _points(ax, *target, "r*", ms=12, label="target")
    ax.set_aspect("equal")
    ax.set(xlabel="x [m]", ylabel="y [m]", title="end-effector path")
    # below the panel: inside, any place would hide part of a workspace circle
    ax.legend(fontsize=8, loc="upper center", bbox_to_anchor=(0.5, -0.2), ncol=2)
    ax = axes[2, 1]
    for label, log, style, color in _styled(runs):
        distance = 1000 * np.linalg.norm(log.ee[:, :2] - target, axis=1)
        ax.semilogy(log.t, distance, style, color=color, lw=1.4, label=label)
    ax.set(xlabel="time [s]", ylabel="distance [mm]", title="distance to the target")
    for ax in axes.flat:
        ax.grid(True, alpha=0.4)
        if ax is not axes[2, 0]:
            ax.legend(fontsize=9)
    return fig


def _desired_path(desired_path) -> np.ndarray:
    """``desired_path`` as an ``(N, 2)`` float array of finite points, else a ``ValueError`` (one of
    shape ``(2, N)`` would draw a "circle" of two points: it says to transpose it)."""
    path = validate.floats(desired_path)
    if path is None or path.ndim != 2 or path.shape[1] != 2:
        transposed = path is not None and path.ndim == 2 and path.shape[0] == 2
        raise ValueError(
            "desired_path must be the circle's points, an (N, 2) array such as reference(t).pos, got "
            + (f"shape {path.shape}: transpose it (desired_path.T)" if transposed else validate.short(desired_path))
        )
    return validate.vector("desired_path", desired_path, path.shape)


def circle_tracking_figure(runs: Mapping[str, object], desired_path):
    r"""Task 3.2's three panels for several runs (``sim.Log`` with ``ee`` and ``err``), sized to
    the text column: on the left the path against the desired circle; on the right, stacked,
    the norm of the Cartesian error in millimetres and the joint torques.
    """
    runs = _planar_2r(runs, reference=True)
    desired_path = _desired_path(desired_path)
    fig, axes = plt.subplot_mosaic(
        [["path", "error"], ["path", "torques"]], figsize=(column_width(), 6.0), layout="constrained"
    )
    ax = axes["path"]
    ax.plot(desired_path[:, 0], desired_path[:, 1], color="0.6", lw=REFERENCE_WIDTH, alpha=0.6, label="desired")
    for label, log, style, color in _styled(runs):
        ax.plot(log.ee[:, 0], log.ee[:, 1], style, color=color, lw=1.2, alpha=0.8, label=label)
    ax.set_aspect("equal")
    ax.set(xlabel="x [m]", ylabel="y [m]", title="end-effector path")
    ax = axes["error"]
    for label, log, style, color in _styled(runs):
        ax.plot(log.t, 1000 * np.linalg.norm(log.err, axis=1), style, color=color, lw=1.2, label=label)
    ax.set(xlabel="time [s]", ylabel=r"$|x_d - x|$ [mm]", title="Cartesian error")
    ax = axes["torques"]
    # each run narrower than the one before, drawn over it: where their torques coincide (as the
    # lab's two laws' do), the earlier run still shows as a band around the later one
    for (i, (label, log)), marker in zip(enumerate(runs.items()), itertools.cycle(_RUN_MARKERS)):
        for j, style in enumerate(("-", "--")):
            ax.plot(
                log.t,
                log.tau[:, j],
                style,
                color=f"C{i}",
                marker=marker,
                markevery=0.1,
                lw=max(3.0 - 2.0 * i, 1.0),
                label=rf"{label} $\tau_{j + 1}$",
            )
    ax.set(xlabel="time [s]", ylabel=r"$\tau$ [N·m]", title="joint torques")
    for ax in axes.values():
        ax.grid(True, alpha=0.4)
        ax.legend(fontsize=8)
    return fig


# ---------------------------------------------------------------------------------------
# Planar-arm animation
# ---------------------------------------------------------------------------------------


#: The most frames one video may have: 2.5 minutes at 12 frames/s, about 0.9 GB of frames at
#: 480x360 (the frames are held in memory until they are encoded).
MAX_FRAMES = 1800
#: The largest video frame :func:`planar_arm_frames` draws (Full HD), in pixels.
MAX_VIDEO_SIZE = (1920, 1080)


def frame_indices(n_samples: int, dt: float, fps: float, speed: float = 1.0, until: float | None = None) -> np.ndarray:
    r"""Which samples (spaced ``dt`` seconds, the first at :math:`t = 0`) a video at ``fps`` frames
    per second shows when it plays them at ``speed`` times real time (0.25: four times slower),
    up to ``until`` seconds into the samples (all of them by default): frame :math:`i` shows the
    sample nearest :math:`t_i = i\,s/f`. The video lasts the span divided by :math:`s`, and at
    least one frame (the first sample).

    Raises:
        ValueError: no samples, a non-positive ``fps``, ``dt``, ``speed`` or ``until``, or a
            video of more than :data:`MAX_FRAMES` frames.
    """
    if isinstance(n_samples, bool) or not isinstance(n_samples, (int, np.integer)):
        raise ValueError(f"n_samples must be a whole number of samples, got {n_samples!r}")
    if n_samples <= 0:
        raise ValueError("there are no samples to animate")
    fps = validate.number("fps", fps, positive=True)
    dt = validate.number("dt", dt, positive=True)
    speed = validate.number("speed", speed, positive=True)
    span = n_samples * dt if until is None else min(n_samples * dt, validate.number("until", until, positive=True))
    count = max(1, int(span * fps / speed + 1e-9))  # the tolerance: 5 s at 12 frames/s is 60 frames
    if count > MAX_FRAMES:
        raise ValueError(
            f"{span:g} s played at speed {speed:g} and {fps:g} frames/s is {count} frames, more than "
            f"{MAX_FRAMES}: replay a part of the run (until=), play it faster (speed=) or lower fps"
        )
    return np.minimum(np.rint(np.arange(count) * speed / (fps * dt)).astype(int), n_samples - 1)


def _arm_panels(panels) -> list[dict]:
    """The panels of :func:`planar_arm_frames` with their arrays as float arrays, or a
    ``ValueError`` naming the panel and the entry that is missing or of the wrong shape."""
    if isinstance(panels, Mapping) or not isinstance(panels, Sequence) or not panels:
        raise ValueError(
            "panels must be a list of dicts, one per panel, such as [dict(q=log.q, title='PD')]; got "
            f"{validate.short(panels)}"
        )
    checked = []
    for i, panel in enumerate(panels):
        if not isinstance(panel, Mapping) or "q" not in panel or "title" not in panel:
            raise ValueError(
                f"panel {i} must be a dict with q ((N, 2) joint angles) and title, got {validate.short(panel)}"
            )
        panel = dict(panel)
        for key, shape in (("q", "(N, 2)"), ("ref", "(N, 2)"), ("path", "(M, 2)"), ("target", "(2,)")):
            if key not in panel:
                continue
            value = validate.floats(panel[key])
            if value is None or value.shape[-1:] != (2,) or value.ndim != (1 if key == "target" else 2):
                raise ValueError(
                    f"panel {i} ({panel['title']}): {key} must have shape {shape}, got {validate.short(panel[key])}"
                )
            panel[key] = value
        checked.append(panel)
    return checked


def planar_arm_frames(
    panels: Sequence[Mapping],
    arm,
    t=None,
    frames: np.ndarray | None = None,
    size: tuple[int, int] = (720, 360),
    limits=None,
) -> np.ndarray:
    r"""RGB frames of one or more 2R arms side by side, drawn with Matplotlib.

    Args:
        panels: one dict per panel with ``q`` ((N, 2) joint angles) and ``title``, and
            optionally ``color``, ``target`` (a fixed point), ``ref`` ((N, 2) moving
            reference point) and ``path`` ((M, 2) a fixed curve, e.g. the desired circle).
            The trail of the end effector is drawn behind the arm.
        arm: :class:`labsupport.kinematics.planar_2r.Planar2R`.
        t: (N,) times, printed in the top left corner.
        frames: sample indices to draw (all by default, see :func:`frame_indices`), at most
            :data:`MAX_FRAMES`.
        size: (width, height) of the video in pixels (even numbers, for H.264), at most
            :data:`MAX_VIDEO_SIZE`.
        limits: ((xmin, xmax), (ymin, ymax)); the whole workspace by default.

    Returns:
        ``(F, height, width, 3)`` uint8 array, for :func:`mediapy.show_video`.
    """
    panels = _arm_panels(panels)
    checked_arm(arm)
    width, height = validate.vector("size (width, height)", size, (2,))
    if not (width == int(width) and height == int(height) and width > 0 and height > 0) or width % 2 or height % 2:
        raise ValueError(f"size must be two positive even whole numbers of pixels (H.264), got {size}")
    width, height = int(width), int(height)
    if width > MAX_VIDEO_SIZE[0] or height > MAX_VIDEO_SIZE[1]:
        raise ValueError(f"size must be at most {MAX_VIDEO_SIZE[0]} x {MAX_VIDEO_SIZE[1]} pixels, got {size}")
    dpi = width / 6  # six inches wide at any size: the titles and the clock keep their share of the picture
    fig = Figure(figsize=(width / dpi, height / dpi), dpi=dpi)
    canvas = FigureCanvasAgg(fig)
    axes = fig.subplots(1, len(panels), squeeze=False)[0]
    fig.subplots_adjust(left=0.02, right=0.98, bottom=0.02, top=0.9, wspace=0.05)
    lengths = {len(panel["q"]) for panel in panels} | {len(panel["ref"]) for panel in panels if "ref" in panel}
    if t is not None:
        lengths.add(len(t))
    if len(lengths) != 1:
        raise ValueError(
            "every panel's q (and ref), and t, must hold the same samples, one row per time; "
            f"got lengths {sorted(lengths)}"
        )
    (n,) = lengths
    frames = np.arange(n) if frames is None else np.asarray(frames)
    if frames.dtype.kind not in "iu" and frames.size:
        raise ValueError(f"frames must be whole sample indices (see frame_indices), got {validate.short(frames)}")
    if frames.size and not (frames.min() >= 0 and frames.max() < n):
        raise ValueError(f"frames must be sample indices in [0, {n - 1}], got {frames.min()} to {frames.max()}")
    if frames.size > MAX_FRAMES:  # each frame is a full picture in memory
        raise ValueError(
            f"{frames.size} frames is more than {MAX_FRAMES}: pick the samples to draw with "
            "frames=frame_indices(n_samples, dt, fps, speed, until)"
        )
    reach = arm.l1 + arm.l2 + 0.05
    (x0, x1), (y0, y1) = limits if limits is not None else ((-reach, reach), (-reach, reach))

    artists = []
    for i, (ax, panel) in enumerate(zip(axes, panels, strict=True)):
        color = panel.get("color", f"C{i}")
        ax.set_xlim(x0, x1)
        ax.set_ylim(y0, y1)
        ax.set_aspect("equal")
        ax.set_xticks([])
        ax.set_yticks([])
        ax.set_title(panel["title"], fontsize=9)
        _workspace(ax, abs(arm.l1 - arm.l2), arm.l1 + arm.l2)
        if "path" in panel:
            ax.plot(panel["path"][:, 0], panel["path"][:, 1], "k--", lw=0.8, alpha=0.5)
        if "target" in panel:
            _points(ax, *panel["target"], "r*", ms=10)
        q = np.asarray(panel["q"], dtype=float)
        ee, elbow = forward_kinematics(q, arm), elbow_position(q, arm)
        (trail,) = ax.plot([], [], "-", color=color, lw=1, alpha=0.6)
        (links,) = ax.plot([], [], "o-", color=color, lw=3, ms=4)
        (ref,) = ax.plot([], [], "r*", ms=8)
        for line in (links, ref):  # every joint, and the one moving target point, drawn
            line.set_markevery(None)
        # top left, outside the reach: a video player's controls cover the bottom while paused
        clock = ax.text(0.03, 0.97, "", transform=ax.transAxes, fontsize=8, va="top")
        artists.append((ee, elbow, panel.get("ref"), trail, links, ref, clock))

    out = np.empty((len(frames), height, width, 3), dtype=np.uint8)
    for f, k in enumerate(frames):
        for ee, elbow, moving_ref, trail, links, ref, clock in artists:
            trail.set_data(ee[: k + 1, 0], ee[: k + 1, 1])
            links.set_data([0.0, elbow[k, 0], ee[k, 0]], [0.0, elbow[k, 1], ee[k, 1]])
            if moving_ref is not None:
                ref.set_data([moving_ref[k, 0]], [moving_ref[k, 1]])
            if t is not None:
                clock.set_text(f"t = {t[k]:.2f} s")
        canvas.draw()
        out[f] = np.asarray(canvas.buffer_rgba())[..., :3]
    return out
