r"""Offscreen MuJoCo pictures and video: show a state, replay a run, draw the target and
end-effector traces, encode MP4.

Rendering goes through :class:`mujoco.Renderer` on the OpenGL backend that
:mod:`labsupport.gl` chose when :mod:`labsupport` was imported: on Linux EGL (a GPU, or Mesa's
llvmpipe on a CPU-only machine), else OSMesa, else GLFW on a desktop; on macOS and Windows
MuJoCo's own default. If none works, :class:`RenderingUnavailable`
says what to install; :func:`show_picture` and :func:`show_run_video` then print that message
instead of a picture or a video, so a notebook still runs to the end. Inside the batch grader's
sandbox nothing is rendered: a graded notebook's pictures would only spend its time limits.

Videos are rendered *after* the simulation, from the logged joint angles, so rendering
never slows the control loop down and a failed render loses no results.
"""

from __future__ import annotations

import os
import warnings
from html import escape

import IPython.display
import mediapy
import mujoco
import numpy as np

from labsupport import gl, validate
from labsupport.book import PIXEL_DENSITY, show_figure, text_alternative
from labsupport.grading import BATCH_ENV
from labsupport.plots import frame_indices
from labsupport.sim import Log, site_positions

#: Blue target trace and red end-effector trace, as in the lab; their widths in pixels (the
#: red one narrower, drawn over the blue: see :func:`render_run`).
TARGET_RGBA = np.array([0.0, 0.2, 1.0, 1.0], dtype=np.float32)
EE_RGBA = np.array([1.0, 0.0, 0.0, 0.8], dtype=np.float32)
TARGET_WIDTH, EE_WIDTH = 6.0, 3.0
#: The size a picture is shown at by default, width x height [CSS pixels].
PICTURE_SIZE = (480, 360)

INSTALL_HINT = (
    "On Linux, install an OpenGL library that works without a display and restart the kernel: "
    "on Debian/Ubuntu `sudo apt-get install libegl1 libopengl0 libgl1-mesa-dri` (EGL through Mesa) or "
    "`sudo apt-get install libosmesa6` (OSMesa, software only). On Colab choose a GPU runtime "
    "(Runtime > Change runtime type); labsupport sets up NVIDIA's EGL itself. On macOS and "
    "Windows MuJoCo renders through the desktop's OpenGL with MUJOCO_GL unset: update the "
    "graphics driver, or run the notebook in Colab. In every case `import labsupport` before "
    "anything imports mujoco. The simulation results do not need a video."
)

IMPORT_ORDER_HINT = (
    "PyOpenGL was imported before labsupport, and it keeps the platform it took then, which MuJoCo's "
    f"offscreen back ends (EGL, OSMesa) cannot render through: {gl.IMPORT_ORDER_ADVICE}. "
    "The simulation results do not need a video."
)

FFMPEG_HINT = (
    "Encoding the video needs the ffmpeg program, which was not found. From the notebook, "
    "`%pip install imageio-ffmpeg` brings one for any system (labsupport finds it without a kernel "
    "restart); or install ffmpeg itself (`sudo apt-get install ffmpeg`, `brew install ffmpeg`, "
    "`conda install ffmpeg`, `winget install ffmpeg`) and restart the kernel. "
    "The simulation results do not need a video."
)


_ZERO3, _ZERO9 = np.zeros(3), np.zeros(9)


class RenderingUnavailable(RuntimeError):
    """No video can be made here: no OpenGL backend could create an offscreen context, or no
    ffmpeg can encode the frames; the message says what to install."""


def require_ffmpeg() -> None:
    """Make sure mediapy can encode video, else raise :class:`RenderingUnavailable` saying how.

    ffmpeg is looked for where mediapy looks (the PATH, or what ``mediapy.set_ffmpeg`` named),
    then in the optional package ``imageio-ffmpeg``, which mediapy is then pointed at. That
    package is imported here rather than at the top, so that installing it from a running
    notebook is enough.
    """
    if mediapy.video_is_available():
        return
    try:
        import imageio_ffmpeg  # optional, and may be installed after labsupport was imported

        mediapy.set_ffmpeg(imageio_ffmpeg.get_ffmpeg_exe())
    except (ImportError, RuntimeError):
        pass
    if not mediapy.video_is_available():
        raise RenderingUnavailable(FFMPEG_HINT)


#: What to do about a frame larger than a model's offscreen buffer.
ENLARGE_BUFFER = (
    "enlarge the buffer before rendering: set model.vis.global_.offwidth and model.vis.global_.offheight "
    "(in the model file, <visual><global offwidth offheight>)"
)


def _fits_buffer(model: mujoco.MjModel, width: int, height: int) -> bool:
    """Whether a ``width`` x ``height`` frame fits the model's offscreen buffer
    (``<visual><global offwidth offheight>``)."""
    return width <= model.vis.global_.offwidth and height <= model.vis.global_.offheight


def make_renderer(model: mujoco.MjModel, width: int = 320, height: int = 240) -> mujoco.Renderer:
    """An offscreen :class:`mujoco.Renderer`, or :class:`RenderingUnavailable` with advice.

    Raises:
        ValueError: if the size exceeds the model's offscreen buffer
            (``model.vis.global_.offwidth`` and ``offheight``, ``<global offwidth offheight>`` in
            MJCF); the message says how to enlarge it.
    """
    if os.environ.get(BATCH_ENV):  # a graded notebook's pictures would only spend its time limits
        raise RenderingUnavailable("pictures and videos are not made while the batch grader runs the notebook")
    validate.mujoco_model(model)
    width, height = validate.whole("width", width, 1), validate.whole("height", height, 1)
    if not _fits_buffer(model, width, height):
        raise ValueError(
            f"{validate.short(width)} x {validate.short(height)} is larger than the model's offscreen buffer "
            f"({model.vis.global_.offwidth}x{model.vis.global_.offheight}); "
            f"pick a smaller size, or {ENLARGE_BUFFER}"
        )
    backend = os.environ.get("MUJOCO_GL")
    if not backend and gl.on_linux():  # on Linux, MuJoCo's default (GLFW) needs a display
        blocked = all(gl.pyopengl_refuses(b) for b in gl.PYOPENGL_PLATFORMS)  # installing would not help
        raise RenderingUnavailable(
            f"No OpenGL backend for MuJoCo ({gl.last_choice}). {IMPORT_ORDER_HINT if blocked else INSTALL_HINT}"
        )
    gpu_unused = gl.on_linux() and gl.nvidia_egl_missing()
    try:
        renderer = mujoco.Renderer(model, height=height, width=width)
    except Exception as err:  # EGL/OSMesa/CGL/GLFW/PyOpenGL raise many types; all mean "no context"
        used = f"MUJOCO_GL={backend}" if backend else "its default backend"
        gpu = f" Also, {gl.NVIDIA_EGL_ADVICE}." if gpu_unused else ""
        chosen = f" {gl.USER_BACKEND_ADVICE}." if gl.user_backend else ""
        raise RenderingUnavailable(
            f"MuJoCo could not open an offscreen OpenGL context with {used} "
            f"({type(err).__name__}: {err}).{gpu}{chosen} {INSTALL_HINT}"
        ) from err
    if gpu_unused:  # it renders, but on the CPU
        warnings.warn(f"MuJoCo renders in software here, slowly: {gl.NVIDIA_EGL_ADVICE}", RuntimeWarning, stacklevel=2)
    return renderer


def add_trace(scene: mujoco.MjvScene, points: np.ndarray, width: float, rgba: np.ndarray) -> int:
    """Append line segments ``width`` pixels wide joining consecutive ``points`` (K, 3) to
    ``scene``; returns how many fit. (Lines, not the lab's capsules: a software renderer
    draws hundreds of capsules several times slower than the robot itself.)"""
    added = 0
    for p0, p1 in zip(points[:-1], points[1:], strict=False):
        if scene.ngeom >= scene.maxgeom:
            break
        geom = scene.geoms[scene.ngeom]
        mujoco.mjv_initGeom(geom, mujoco.mjtGeom.mjGEOM_LINE, _ZERO3, _ZERO3, _ZERO9, rgba)
        mujoco.mjv_connector(geom, mujoco.mjtGeom.mjGEOM_LINE, width, p0, p1)
        scene.ngeom += 1
        added += 1
    return added


def nearer_camera(scene: mujoco.MjvScene, points: np.ndarray, distance: float) -> np.ndarray:
    """``points`` (K, 3) moved ``distance`` toward the scene's camera, so that a trace drawn
    through them shows in front of one drawn through the same points (instead of the two
    flickering where they coincide). Each point moves along its line of sight, so the picture
    shows it where it was; :func:`render_run` moves the red trace by a thousandth of the
    model's extent."""
    toward = np.asarray(scene.camera[0].pos, dtype=float) - points
    return points + distance * toward / np.linalg.norm(toward, axis=1, keepdims=True)


def render_run(
    model: mujoco.MjModel,
    log: Log,
    *,
    target_quat=None,
    fps: float = 25,
    width: int = 320,
    height: int = 240,
    camera: str | int | None = None,
    trace_step: float = 0.04,
    progress: bool = True,
    target_body: str = "target",
    speed: float = 1.0,
    until: float | None = None,
) -> np.ndarray:
    """Frames (F, height, width, 3) replaying a run's :class:`labsupport.sim.Log`.

    Each frame shows the robot at the logged joint angles and, up to that instant, the traces
    (every ``trace_step`` seconds) of the reference (blue, :data:`TARGET_WIDTH` pixels wide) and
    of the site the run logged (red, :data:`EE_WIDTH` pixels, drawn over the blue one: where the
    site keeps to the reference, a red line runs inside a blue band; see :func:`nearer_camera`).
    A planar reference (``log.ref`` of 2 columns) is drawn in the plane the site moves in: its
    missing coordinates are the site's. A mocap body ``target_body``, if the model has one,
    follows a 3-D reference, held at ``target_quat`` (w, x, y, z) when given. Works for any run
    of :func:`labsupport.sim.simulate`; without ``site=`` there is nothing to trace and only the
    robot is shown.

    ``camera`` is a camera of the model (name or id), by default its first one, or MuJoCo's
    free camera (-1) for a model without cameras. Shadows and reflections are off: software
    OpenGL renders several times faster without them. A progress bar (tqdm) shows while
    ``progress`` is true; in a notebook it is erased when the video is done.

    ``fps`` is the video's frame rate, 25 frames/s by default (Task 3's animations have the
    same; the lab's own videos run at 30). ``speed`` is the playback rate (0.25 shows a quick
    motion four times slower, in four times as many frames) and ``until`` the part of the run
    to replay, in seconds from its start (the whole run by default);
    :func:`labsupport.plots.frame_indices` picks the logged rows.

    Raises:
        ValueError: ``fps`` outside (0, 60], a camera the model does not have, a log of another
            model, a reference of more than 3 columns, a ``speed`` or ``until`` that is not a
            positive number, a log whose rows are not evenly spaced in time, or a video of more
            than :data:`labsupport.plots.MAX_FRAMES` frames.

    The video's clock is the log's own (its rows' spacing), not the model's time step.
    """
    validate.mujoco_model(model)
    validate.run_log(log)
    if not 0 < validate.number("fps", fps) <= 60:
        raise ValueError(f"fps must be in (0, 60], got {fps!r}")
    trace_step = validate.number("trace_step", trace_step, positive=True)
    progress = validate.flag("progress", progress)
    if target_quat is not None:
        target_quat = validate.vector("target_quat (w, x, y, z)", target_quat, (4,))
        if not abs(np.linalg.norm(target_quat) - 1.0) <= 1e-6:
            raise ValueError(f"target_quat must be a unit quaternion (w, x, y, z), got {validate.short(target_quat)}")
    if log.q.shape[1:] != (model.nq,) or log.site >= model.nsite:
        raise ValueError(
            f"this log does not belong to this model: its rows hold {log.q.shape[-1]} joint positions "
            f"(and site {log.site}), the model has nq = {model.nq} (and {model.nsite} sites); "
            "replay a log with the model that produced it"
        )
    camera = _camera_id(model, camera)
    dt = _log_step(log, model.opt.timestep)
    n = len(log.t)
    frame_steps = frame_indices(n, dt, fps, speed, until)
    stride = max(1, int(round(trace_step / dt)))
    trail_idx = np.arange(0, n, stride)
    ee_trail, target_trail = _trails(model, log, trail_idx)

    lift = 1e-3 * model.stat.extent  # the red trace's lead over the blue one, toward the camera
    renderer = make_renderer(model, width, height)
    data = mujoco.MjData(model)
    body = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, target_body)
    mocap = model.body_mocapid[body] if body >= 0 and log.ref.shape[1] == 3 else -1
    if mocap >= 0 and target_quat is not None:
        data.mocap_quat[mocap] = target_quat
    frames = np.empty((len(frame_steps), renderer.height, renderer.width, 3), dtype=np.uint8)
    bar = _progress_bar(len(frame_steps)) if progress else None
    try:
        for i, k in enumerate(frame_steps):
            data.qpos[:] = log.q[k]
            if mocap >= 0:
                data.mocap_pos[mocap] = log.ref[k]
            mujoco.mj_forward(model, data)
            renderer.update_scene(data, camera=camera)
            renderer.scene.flags[mujoco.mjtRndFlag.mjRND_SHADOW] = False
            renderer.scene.flags[mujoco.mjtRndFlag.mjRND_REFLECTION] = False
            upto = int(np.searchsorted(trail_idx, k, side="right"))
            add_trace(renderer.scene, target_trail[:upto], TARGET_WIDTH, TARGET_RGBA)
            add_trace(renderer.scene, nearer_camera(renderer.scene, ee_trail[:upto], lift), EE_WIDTH, EE_RGBA)
            frames[i] = renderer.render()
            if bar is not None:
                bar.update(1)
    finally:
        renderer.close()
        if bar is not None:
            bar.close()
    return frames


def _log_step(log: Log, default: float) -> float:
    """The time between a log's rows [s] (``default`` for a log of one row): a run of another
    time step than the model's (the analytic single joint, a model with a finer step) plays at
    its own pace. Rows unevenly spaced are refused: a video shows them at even intervals."""
    if len(log.t) < 2:
        return default
    steps = np.diff(log.t)
    if not (steps > 0).all() or steps.max() - steps.min() > 1e-6 * steps.max():
        raise ValueError(
            f"the log's rows must be evenly spaced in time to be replayed, got steps from {steps.min():.6g} "
            f"to {steps.max():.6g} s"
        )
    return float(steps.mean())


def render_picture(
    model: mujoco.MjModel,
    data: mujoco.MjData,
    *,
    path=None,
    width: int = PICTURE_SIZE[0],
    height: int = PICTURE_SIZE[1],
    camera: str | int | None = None,
    density: int = 1,
) -> np.ndarray:
    """One frame of the model in the state ``data`` holds, as its last ``mj_forward`` (or
    ``mj_kinematics``) left it, seen from ``camera`` (as in :func:`render_run`), with ``path``,
    points (K, 3) such as a circle to track, drawn as the blue reference trace.

    The frame has ``density`` pixels each way for each of the ``width`` x ``height`` it is meant
    to be shown at, (density·height, density·width, 3), and its trace is as many times as wide,
    so that shown at that size it looks the same, only sharper.
    """
    validate.model_and_data(model, data)
    width, height = validate.whole("width", width, 1), validate.whole("height", height, 1)
    density = validate.whole("density", density, 1)
    if not data.xmat[0].any():  # the world's orientation, the identity once kinematics ran
        raise ValueError(
            "render_picture: the data holds no kinematics yet, so the picture would be black: run "
            "mujoco.mj_forward(model, data) after setting its state"
        )
    camera = _camera_id(model, camera)
    points = None if path is None else _points(path)
    if density > 1 and not _fits_buffer(model, density * width, density * height):
        raise ValueError(
            f"render_picture: at density {density} a {width} x {height} picture is a {density * width} x "
            f"{density * height} frame, larger than the model's offscreen buffer ({model.vis.global_.offwidth}x"
            f"{model.vis.global_.offheight}); pass density=1 (or leave density out in show_picture, which picks "
            f"what fits), a smaller size, or {ENLARGE_BUFFER}"
        )
    renderer = make_renderer(model, density * width, density * height)
    try:
        renderer.update_scene(data, camera=camera)
        if points is not None:
            add_trace(renderer.scene, points, density * TARGET_WIDTH, TARGET_RGBA)
        return renderer.render()
    finally:
        renderer.close()


def _points(path) -> np.ndarray:
    """``path`` as finite points of shape (K, 3), or a ``ValueError`` that says so."""
    points = validate.floats(path)
    if points is None:
        points = np.empty(0)
    if points.ndim != 2 or points.shape[1] != 3 or not np.isfinite(points).all():
        raise ValueError(f"path must be finite points of shape (K, 3), got {validate.short(path)}")
    return points


def show_picture(
    model: mujoco.MjModel,
    data: mujoco.MjData,
    *,
    description: str,
    width: int = PICTURE_SIZE[0],
    height: int = PICTURE_SIZE[1],
    density: int | None = None,
    **options,
) -> None:
    """Render ``data``'s state (see :func:`render_picture`, which takes the same ``options``) and
    show it ``width`` x ``height`` with its text alternative ``description``
    (:func:`labsupport.book.show_figure`); without a working OpenGL backend print why, and the
    description, instead. By default (``density=None``) the picture is rendered with
    :data:`labsupport.book.PIXEL_DENSITY` times the pixels each way where the model's offscreen
    buffer holds them, as the figures are drawn, so that it stays sharp on high-density screens,
    and pixel for pixel where it does not."""
    description = text_alternative(description, "a picture")
    if density is None:
        validate.mujoco_model(model)
        width, height = validate.whole("width", width, 1), validate.whole("height", height, 1)
        density = PIXEL_DENSITY if _fits_buffer(model, PIXEL_DENSITY * width, PIXEL_DENSITY * height) else 1
    try:
        image = render_picture(model, data, width=width, height=height, density=density, **options)
    except RenderingUnavailable as err:
        _not_shown("picture", err, description)
        return
    show_figure(image, description, density=density)


def _camera_id(model: mujoco.MjModel, camera: str | int | None) -> int:
    """The id of ``camera`` (a name or an id; -1 is MuJoCo's free camera), or by default the
    model's first camera; ``ValueError`` naming the model's cameras for one it lacks."""
    if camera is None:
        return 0 if model.ncam else -1
    if isinstance(camera, (int, np.integer)) and not isinstance(camera, bool) and camera == -1:
        return -1
    try:
        return validate.model_object(model, "camera", camera)
    except ValueError as err:
        raise ValueError(f"{err}, or -1 for MuJoCo's free camera") from None


def _trails(model: mujoco.MjModel, log: Log, idx: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The points (K, 3) of the logged site's trace and of the reference's at the rows ``idx``.

    The site's come from forward kinematics of the logged joint angles (so they match the
    drawn robot whatever step the loop logged the site at). A reference with fewer than 3
    columns takes the site's remaining coordinates; either trace is empty without a site.
    """
    d = log.ref.shape[1]
    if d > 3:
        raise ValueError(f"the log's reference must be positions of at most 3 coordinates, got shape {log.ref.shape}")
    if log.site < 0:
        return np.empty((0, 3)), np.empty((0, 3))
    ee_trail = site_positions(model, log.q[idx], log.site)
    if not d:
        return ee_trail, np.empty((0, 3))
    target_trail = ee_trail.copy()
    target_trail[:, :d] = log.ref[idx]
    return ee_trail, target_trail


def _progress_bar(total: int):
    """A tqdm bar: text in a terminal; in a notebook, a bar that is erased when done.

    In a Jupyter kernel tqdm writes to a display that is updated in place and emptied at the
    end, so an executed notebook keeps only an empty HTML output (which shows as nothing,
    and which the book's stylesheet hides), never a progress line.
    """
    from tqdm import tqdm

    try:
        from IPython import get_ipython
        from IPython.display import HTML, display

        in_kernel = get_ipython() is not None and hasattr(get_ipython(), "kernel")
    except ImportError:
        in_kernel = False
    if not in_kernel:
        return tqdm(total=total, desc="rendering", unit="frame", leave=False)

    class _DisplayFile:
        """File-like target for tqdm that shows the last line in an updatable display."""

        def __init__(self):
            self.handle = display(HTML(""), display_id=True)

        def write(self, text):
            line = text.strip("\r\n ")
            if line:
                self.handle.update(HTML(f"<pre style='margin:0'>{line}</pre>"))

        def flush(self):
            pass

        def clear(self):
            self.handle.update(HTML(""))

    out = _DisplayFile()
    bar = tqdm(
        total=total, desc="rendering", unit="frame", leave=False, file=out, ascii=False, mininterval=0.5, ncols=80
    )
    close = bar.close

    def close_and_clear():
        close()
        out.clear()

    bar.close = close_and_clear
    return bar


def video_html(
    frames: np.ndarray, fps: float, title: str | None = None, description: str | None = None, qp: int = 30
) -> str:
    """HTML showing ``frames`` as an H.264 MP4 (mediapy); ``qp`` trades size for quality.

    The video waits for the reader: it starts from its controls (or Space once focused), so
    nothing on the page moves unasked (WCAG 2.1, 2.2.2), and loops once started.
    ``description`` is the video's text alternative, required as a figure's is
    (:func:`labsupport.book.text_alternative`): its accessible name (``aria-label``), the
    caption under it, and what a browser that cannot play it shows instead. The caption is
    hidden from screen readers (``aria-hidden``), which read the name already: they read the
    description once, not twice in a row.
    """
    text = escape(text_alternative(description, "a video"))
    try:
        frames = np.asarray(frames)
    except ValueError:  # nested lists of unequal lengths
        frames = np.empty(0)
    if frames.ndim != 4 or len(frames) == 0 or frames.shape[-1] != 3:
        raise ValueError(
            "frames must be a video: an (F, height, width, 3) array of F >= 1 RGB frames (render_run makes "
            f"one), got shape {frames.shape}; for a single picture use show_picture"
        )
    if frames.dtype.kind not in "uf" or (frames.dtype.kind == "u" and frames.itemsize > 2):
        raise ValueError(
            f"frames must be 8-bit colours (uint8, 0 to 255, as render_run makes them) or floats from 0 to 1, got "
            f"{frames.dtype}: convert with np.clip(frames, 0, 255).astype(np.uint8)"
        )
    if frames.dtype.kind == "f" and not np.isfinite(frames).all():
        raise ValueError("frames must be finite: the video holds NaN or infinite colours")
    if frames.dtype.kind == "f" and not 0.0 <= frames.min() <= frames.max() <= 1.0:
        raise ValueError(
            f"float frames hold colours from 0 to 1, got {frames.min():.4g} to {frames.max():.4g} (the video "
            "would show them clipped, white or black): divide colours of 0 to 255 by 255, or pass them as uint8"
        )
    fps = validate.number("fps", fps, positive=True)
    qp = validate.whole("qp", qp, 0, 51)  # H.264's range: 0 is lossless, 51 the coarsest
    require_ffmpeg()
    data = mediapy.compress_video(frames, fps=fps, qp=qp)
    html = mediapy.html_from_compressed_video(data, frames.shape[2], frames.shape[1], title=title, autoplay=False)
    html = html.replace("<video ", f'<video aria-label="{text}" ', 1)
    html = html.replace("This browser does not support the video tag.", text, 1)
    return f'<figure>{html}<figcaption aria-hidden="true">{text}</figcaption></figure>'


def show_video(
    frames: np.ndarray, fps: float, title: str | None = None, description: str | None = None, qp: int = 30
) -> None:
    """Show frames inline as an MP4 video with its text alternative (see :func:`video_html`);
    without ffmpeg print why, and the text alternative, instead."""
    try:
        html = video_html(frames, fps, title, description, qp)
    except RenderingUnavailable as err:
        _not_shown("video", err, description)
        return
    IPython.display.display(IPython.display.HTML(html))


def show_run_video(
    model: mujoco.MjModel,
    log: Log,
    *,
    description: str,
    title: str | None = None,
    fps: float = 25,
    **options,
) -> np.ndarray | None:
    """Render ``log`` (see :func:`render_run`, which takes the same ``options``) and show it with
    its text alternative ``description`` (checked before the rendering starts); without a
    working OpenGL backend or ffmpeg (looked for first) print why, and the description, and
    return None."""
    description = text_alternative(description, "a video")
    try:
        require_ffmpeg()
        frames = render_run(model, log, fps=fps, **options)
    except RenderingUnavailable as err:
        _not_shown("video", err, description)
        return None
    show_video(frames, fps, title, description)
    return frames


def _not_shown(what: str, err: RenderingUnavailable, description: str) -> None:
    print(f"(No {what}: {err}) {description}")
