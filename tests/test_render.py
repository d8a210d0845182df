"""Offscreen rendering: real frames through EGL (and OSMesa), and a clear error without OpenGL.

Each case runs in a fresh interpreter, because MuJoCo reads ``MUJOCO_GL`` once, when it is
first imported.
"""

import ctypes.util
import dataclasses
import json
import os
import re
import shutil
import subprocess
import sys
import types
import warnings
from pathlib import Path

import mediapy
import numpy as np
import pytest

from labsupport import gl, plots, render


def ffmpeg_program() -> str | None:
    """The ffmpeg that labsupport can encode video with: the PATH's, else the one that the optional
    package imageio-ffmpeg ships (what a Colab student gets with `%pip install imageio-ffmpeg`)."""
    if on_path := shutil.which("ffmpeg"):
        return on_path
    try:
        import imageio_ffmpeg

        return imageio_ffmpeg.get_ffmpeg_exe()
    except (ImportError, RuntimeError):
        return None


#: The ffmpeg to encode with (.ci/setup installs one; a GPU image may have only imageio-ffmpeg's).
FFMPEG = ffmpeg_program()
needs_ffmpeg = pytest.mark.skipif(FFMPEG is None, reason="no ffmpeg, on the PATH or from imageio-ffmpeg")

SCRIPT = r"""
import json, os, sys
import numpy as np
import labsupport
from labsupport import gl, render, trajectories, ur5e
from labsupport.actuators import servo_actuation
from labsupport.controllers.ur5e import LAB_GAINS, PoseArrays, lab_torque
from labsupport.sim import simulate
model, data = ur5e.load_ur5e()
quat_d = np.array(ur5e.HOME_QUAT)
ref = trajectories.sample(lambda t: trajectories.circle_3d(t, (-0.1, 0.5, 0.6), 0.1, (1, 1, 1), 0.25),
                          model.opt.timestep, 1.0)
site, arrays = model.site(ur5e.SITE).id, PoseArrays.for_model(model)
def controller(model, data):
    return lab_torque(model, data, site, ref.at(data.time).pos, quat_d, LAB_GAINS, arrays)
log = simulate(model, data, controller, 1.0, keyframe=ur5e.HOME, site=ur5e.SITE, reference=ref,
               actuation=servo_actuation(model))
result = {"backend": os.environ.get("MUJOCO_GL"), "choice": gl.last_choice}
try:
    frames = render.render_run(model, log, target_quat=quat_d, fps=5, progress=False)
    np.save(sys.argv[1], frames)
except render.RenderingUnavailable as err:
    result["error"] = str(err)
about = "The UR5e follows the circle for one second."
shown = render.show_run_video(model, log, description=about, fps=5, progress=False) if "error" in result else "skipped"
result["show_returned_none"] = shown is None
print(json.dumps(result))
"""


def _run_script(tmp_path, script: str, *args: str, **env) -> dict:
    """Run ``script`` in a fresh interpreter (MuJoCo reads ``MUJOCO_GL`` once, on import) with
    ``env`` added to an environment free of any GL choice; the JSON of its last line."""
    environment = {k: v for k, v in os.environ.items() if k not in ("MUJOCO_GL", "PYOPENGL_PLATFORM")}
    environment.update(env)
    out = subprocess.run(
        [sys.executable, "-c", script, *args],
        env=environment,
        cwd=tmp_path,
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert out.returncode == 0, out.stderr
    return json.loads(out.stdout.strip().splitlines()[-1])


def _render_in_subprocess(tmp_path, **env):
    result = _run_script(tmp_path, SCRIPT, str(tmp_path / "frames.npy"), **env)
    frames = np.load(tmp_path / "frames.npy") if (tmp_path / "frames.npy").exists() else None
    return result, frames


def _assert_real_frames(frames):
    assert frames.shape == (5, 240, 320, 3) and frames.dtype == np.uint8
    for frame in frames:
        assert frame.std() > 10, "a frame is (nearly) uniform"
        assert len(np.unique(frame.reshape(-1, 3), axis=0)) > 100
    # the arm moves: consecutive frames differ, and the first and last clearly
    assert all(np.any(a != b) for a, b in zip(frames[:-1], frames[1:], strict=True))
    assert np.mean(np.abs(frames[0].astype(int) - frames[-1].astype(int))) > 0.5


@pytest.mark.skipif(not gl.egl_works(), reason="EGL cannot open a display on this machine")
def test_egl_renders_frames_that_are_not_blank(tmp_path):
    result, frames = _render_in_subprocess(tmp_path)
    assert result["backend"] == "egl", result
    assert "error" not in result, result
    _assert_real_frames(frames)


@pytest.mark.skipif(not gl.osmesa_works(), reason="OSMesa is not installed")
def test_falls_back_to_osmesa_when_egl_fails(tmp_path):
    # glvnd finds no EGL vendor library: EGL fails, OSMesa takes over
    result, frames = _render_in_subprocess(tmp_path, __EGL_VENDOR_LIBRARY_FILENAMES=str(tmp_path / "none.json"))
    assert result["backend"] == "osmesa", result
    assert "egl did not work" in result["choice"]
    _assert_real_frames(frames)


def test_no_working_backend_gives_a_clear_message(tmp_path):
    # EGL forced, but no EGL vendor library can be found
    result, frames = _render_in_subprocess(
        tmp_path, MUJOCO_GL="egl", __EGL_VENDOR_LIBRARY_FILENAMES=str(tmp_path / "none.json")
    )
    assert frames is None
    message = result["error"]
    assert "MUJOCO_GL=egl" in message and "apt-get install" in message and "libosmesa6" in message
    assert result["show_returned_none"]


def test_no_backend_at_all_is_explained(monkeypatch):
    import mujoco

    model = mujoco.MjModel.from_xml_string("<mujoco><worldbody><geom size='1'/></worldbody></mujoco>")
    monkeypatch.delenv("MUJOCO_GL", raising=False)
    with pytest.raises(render.RenderingUnavailable, match="No OpenGL backend.*apt-get install"):
        render.make_renderer(model)


def unset_env(monkeypatch, *names: str) -> None:
    """Remove environment variables for one test, and remove them again after it even where the
    code under test sets them (``delenv`` alone records nothing for an absent variable, so a
    variable set by the test would leak into every later test of the process)."""
    for name in names:
        monkeypatch.setenv(name, "")
        monkeypatch.delenv(name)


@pytest.fixture
def fresh_backend_choice(monkeypatch):
    """select_backend as on a first import: no MUJOCO_GL, neither mujoco nor PyOpenGL imported
    (restored after)."""
    unset_env(monkeypatch, "MUJOCO_GL", "PYOPENGL_PLATFORM")
    monkeypatch.delitem(sys.modules, "mujoco", raising=False)
    monkeypatch.delitem(sys.modules, "OpenGL.platform", raising=False)  # PyOpenGL's platform: not chosen yet
    monkeypatch.setattr(gl, "last_choice", gl.last_choice)
    monkeypatch.setattr(gl, "user_backend", gl.user_backend)
    return monkeypatch


def test_select_backend_reports_when_nothing_works(fresh_backend_choice):
    fresh_backend_choice.setattr(gl, "on_linux", lambda: True)
    fresh_backend_choice.setattr(gl, "egl_works", lambda: False)
    fresh_backend_choice.setattr(gl, "osmesa_works", lambda: False)
    fresh_backend_choice.setattr(gl, "display_open", lambda: False)
    assert gl.select_backend() is None
    assert "no OpenGL backend works" in gl.last_choice and "no display is open for glfw" in gl.last_choice
    assert "MUJOCO_GL" not in os.environ


def test_a_mujoco_gl_that_mujoco_would_refuse_is_dropped_with_a_warning(fresh_backend_choice):
    """``MUJOCO_GL=bogus`` made ``import labsupport`` fail inside MuJoCo's import ("invalid value
    for environment variable MUJOCO_GL"), simulation and all."""
    fresh_backend_choice.setenv("MUJOCO_GL", "bogus")
    fresh_backend_choice.setattr(gl, "on_linux", lambda: True)
    fresh_backend_choice.setattr(gl, "egl_works", lambda: True)
    with pytest.warns(RuntimeWarning, match="MUJOCO_GL='bogus' is not a value MuJoCo knows"):
        assert gl.select_backend() == "egl"
    assert os.environ["MUJOCO_GL"] == "egl" and gl.user_backend is None
    fresh_backend_choice.delenv("PYOPENGL_PLATFORM")  # a new process: only the user's settings
    fresh_backend_choice.setenv("MUJOCO_GL", " OSMesa ")  # MuJoCo reads it stripped, in lower case
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert gl.select_backend() == " OSMesa " and gl.user_backend == " OSMesa "


def test_an_empty_mujoco_gl_is_no_choice(fresh_backend_choice):
    """``MUJOCO_GL=`` (exported empty) used to count as the user's choice: nothing was chosen, and
    MuJoCo would have tried GLFW, which needs a display. Now the backend is chosen as if unset."""
    fresh_backend_choice.setenv("MUJOCO_GL", " ")
    fresh_backend_choice.setattr(gl, "on_linux", lambda: True)
    fresh_backend_choice.setattr(gl, "egl_works", lambda: True)
    assert gl.select_backend() == "egl" and os.environ["MUJOCO_GL"] == "egl"
    assert gl.last_choice.startswith("MUJOCO_GL=egl (tried first: nothing)")


def test_a_gpu_without_its_egl_library_is_named_with_what_to_do(fresh_backend_choice, tmp_path):
    """A container started without NVIDIA's graphics libraries used to get Mesa's advice only."""
    driver = tmp_path / "version"
    driver.write_text("NVRM version: 550\n")
    fresh_backend_choice.setattr(gl, "on_linux", lambda: True)
    fresh_backend_choice.setattr(gl, "NVIDIA_DRIVER_FILES", (str(driver),))
    fresh_backend_choice.setattr(gl, "NVIDIA_EGL_LIBRARY", "libEGL_nvidia_absent.so.0")
    for works in ("egl_works", "osmesa_works", "display_open"):
        fresh_backend_choice.setattr(gl, works, lambda: False)
    assert gl.select_backend() is None
    assert "no OpenGL backend works" in gl.last_choice
    assert "an NVIDIA GPU is here, but its EGL library" in gl.last_choice
    assert "NVIDIA_DRIVER_CAPABILITIES=all" in gl.last_choice
    fresh_backend_choice.setattr(gl, "NVIDIA_DRIVER_FILES", (str(tmp_path / "absent"),))
    assert gl.select_backend() is None and "NVIDIA" not in gl.last_choice  # no GPU: no such advice


def test_a_gpu_without_the_egl_loader_is_told_to_install_it(fresh_backend_choice, tmp_path):
    """NVIDIA's EGL library present, glvnd's libEGL.so.1 absent (an NVIDIA machine without the
    libegl1 package): no backend works, and the report names the one package that fixes it."""
    unset_env(fresh_backend_choice, "__EGL_VENDOR_LIBRARY_FILENAMES", "__EGL_VENDOR_LIBRARY_DIRS")
    fresh_backend_choice.setattr(gl, "on_linux", lambda: True)
    fresh_backend_choice.setattr(gl, "NVIDIA_DRIVER_FILES", (str(tmp_path / "absent"),))
    fresh_backend_choice.setattr(gl, "GLVND_EGL_VENDOR_DIRS", (str(tmp_path),))
    for works in ("egl_works", "osmesa_works", "display_open"):
        fresh_backend_choice.setattr(gl, works, lambda: False)
    fresh_backend_choice.setattr(gl, "library_loads", lambda name: name == gl.NVIDIA_EGL_LIBRARY)
    assert gl.select_backend() is None
    assert "but not the EGL loader (libEGL.so.1)" in gl.last_choice
    assert "apt-get install libegl1 libopengl0" in gl.last_choice
    fresh_backend_choice.setattr(gl, "library_loads", lambda name: True)  # the loader is there: no such advice
    assert gl.select_backend() is None and "EGL loader" not in gl.last_choice


def only_the_egl_loader_loads(name: str) -> bool:
    """``library_loads`` on a minimal Debian or Ubuntu with ``libegl1`` and no ``libopengl0``."""
    return name == gl.EGL_LOADER


def test_egl_without_an_opengl_library_is_not_chosen_and_the_package_is_named(fresh_backend_choice):
    """Mesa's EGL opened a display, but PyOpenGL found no libOpenGL/libGL beside it: EGL was
    chosen, and ``import labsupport`` then failed inside MuJoCo's import ("'NoneType' object has
    no attribute 'glGetError'"), simulation and all (seen on a minimal Debian with Python 3.14)."""
    fresh_backend_choice.setattr(gl, "on_linux", lambda: True)
    fresh_backend_choice.setattr(gl, "NVIDIA_DRIVER_FILES", ())
    fresh_backend_choice.setattr(gl, "library_loads", only_the_egl_loader_loads)
    fresh_backend_choice.setattr(gl, "osmesa_works", lambda: False)
    fresh_backend_choice.setattr(gl, "display_open", lambda: False)
    assert not gl.opengl_library_loads() and not gl.egl_works()
    assert gl.select_backend() is None and "MUJOCO_GL" not in os.environ
    assert "egl did not work" in gl.last_choice
    assert "an OpenGL library beside it" in gl.last_choice and "apt-get install libegl1 libopengl0" in gl.last_choice
    fresh_backend_choice.setattr(gl, "library_loads", lambda name: name in (gl.EGL_LOADER, "libOpenGL.so.0"))
    assert gl.opengl_library_loads() and not gl.pyopengl_egl_missing()
    fresh_backend_choice.setattr(gl, "egl_works", lambda: False)  # EGL failing for another reason
    assert gl.select_backend() is None and "libopengl0" not in gl.last_choice  # names no such library
    fresh_backend_choice.setattr(gl, "library_loads", lambda name: False)  # no EGL loader either
    assert gl.select_backend() is None and "apt-get install libegl1 libopengl0" in gl.last_choice


def test_a_users_egl_that_pyopengl_cannot_load_is_dropped_with_a_warning(fresh_backend_choice):
    """``MUJOCO_GL=egl`` set by hand where PyOpenGL cannot load EGL (no OpenGL library beside the
    loader, or no loader) made MuJoCo's import fail; labsupport says why and takes the backend
    that works (OSMesa here)."""
    fresh_backend_choice.setenv("MUJOCO_GL", "egl")
    fresh_backend_choice.setattr(gl, "on_linux", lambda: True)
    fresh_backend_choice.setattr(gl, "NVIDIA_DRIVER_FILES", ())
    fresh_backend_choice.setattr(gl, "library_loads", only_the_egl_loader_loads)
    fresh_backend_choice.setattr(gl, "osmesa_works", lambda: True)
    with warnings.catch_warnings(record=True) as said:
        warnings.simplefilter("always")
        assert gl.select_backend() == "osmesa"
    assert len(said) == 1, [str(w.message) for w in said]  # the dropped choice, and no other
    assert re.search(r"MUJOCO_GL='egl' cannot work here: .*apt-get install libegl1 libopengl0", str(said[0].message))
    assert os.environ["MUJOCO_GL"] == "osmesa" and os.environ["PYOPENGL_PLATFORM"] == "osmesa"
    assert gl.user_backend is None
    fresh_backend_choice.setenv("MUJOCO_GL", "egl")  # no EGL loader either: MuJoCo's import fails the same way
    fresh_backend_choice.setattr(gl, "library_loads", lambda name: False)
    with pytest.warns(RuntimeWarning, match=r"MUJOCO_GL='egl' cannot work here: .*EGL loader \(libEGL.so.1\)"):
        assert gl.select_backend() == "osmesa"
    fresh_backend_choice.delenv("PYOPENGL_PLATFORM")  # a new process: only the user's settings
    fresh_backend_choice.setenv("MUJOCO_GL", "egl")  # with an OpenGL library, the user's choice stands
    fresh_backend_choice.setattr(gl, "library_loads", lambda name: True)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert gl.select_backend() == "egl" and gl.user_backend == "egl"


def test_a_pyopengl_platform_the_user_set_comes_first_or_is_made_to_agree(fresh_backend_choice):
    """MuJoCo's EGL and OSMesa modules refuse any other ``PYOPENGL_PLATFORM``. With
    ``PYOPENGL_PLATFORM=osmesa`` set where EGL works, labsupport chose EGL anyway: ``import
    labsupport`` then failed inside MuJoCo 3.5's import, and with MuJoCo 4 every renderer failed
    with advice to install libraries that were there."""
    fresh_backend_choice.setattr(gl, "on_linux", lambda: True)
    fresh_backend_choice.setattr(gl, "egl_works", lambda: True)
    fresh_backend_choice.setattr(gl, "osmesa_works", lambda: True)

    def choose(mujoco_gl: str | None, pyopengl: str) -> str | None:
        if mujoco_gl:
            fresh_backend_choice.setenv("MUJOCO_GL", mujoco_gl)
        else:
            fresh_backend_choice.delenv("MUJOCO_GL", raising=False)
        fresh_backend_choice.setenv("PYOPENGL_PLATFORM", pyopengl)
        return gl.select_backend()

    with warnings.catch_warnings():
        warnings.simplefilter("error")  # an agreeing choice warns of nothing
        assert choose(None, "osmesa") == "osmesa" and os.environ["PYOPENGL_PLATFORM"] == "osmesa"
        assert choose(None, " EGL ") == "egl" and os.environ["PYOPENGL_PLATFORM"] == "egl"
        assert choose("egl", "egl") == "egl" and gl.user_backend == "egl"
    disagrees = r"PYOPENGL_PLATFORM='osmesa' does not match MUJOCO_GL=egl.*Unset PYOPENGL_PLATFORM"
    with pytest.warns(RuntimeWarning, match=disagrees):  # the user's two choices disagree: MUJOCO_GL's stands
        assert choose("egl", "osmesa") == "egl" and gl.user_backend == "egl"
    assert os.environ["PYOPENGL_PLATFORM"] == "egl"
    fresh_backend_choice.setattr(gl, "osmesa_works", lambda: False)  # the platform asked for does not work
    with pytest.warns(RuntimeWarning, match=disagrees):
        assert choose(None, "osmesa") == "egl"
    assert os.environ["PYOPENGL_PLATFORM"] == "egl" and "osmesa did not work" in gl.last_choice
    fresh_backend_choice.setattr(gl, "egl_works", lambda: False)  # glfw is left with PyOpenGL's own default
    fresh_backend_choice.setattr(gl, "display_open", lambda: True)
    assert choose(None, "x11") == "glfw" and os.environ["PYOPENGL_PLATFORM"] == "x11"


@pytest.mark.skipif(not gl.egl_works(), reason="EGL cannot open a display on this machine")
def test_egl_renders_beside_a_pyopengl_platform_set_for_osmesa(tmp_path):
    result, frames = _render_in_subprocess(tmp_path, MUJOCO_GL="egl", PYOPENGL_PLATFORM="osmesa")
    assert result["backend"] == "egl" and "error" not in result, result
    _assert_real_frames(frames)


def test_a_backend_that_a_pyopengl_imported_first_cannot_serve_is_not_chosen(fresh_backend_choice):
    """PyOpenGL fixes its platform when first imported (GLX, without PYOPENGL_PLATFORM). With
    ``import OpenGL.GL`` before ``import labsupport`` and ``MUJOCO_GL=osmesa``, labsupport's import
    failed inside PyOpenGL: "'GLXPlatform' object has no attribute 'OSMesa'"."""

    def loaded(name: str) -> None:  # PyOpenGL imported, with its platform module OpenGL.platform.<name>
        platform_class = type("Platform", (), {"__module__": f"OpenGL.platform.{name}"})
        fresh_backend_choice.setitem(sys.modules, "OpenGL.platform", types.SimpleNamespace(PLATFORM=platform_class()))

    fresh_backend_choice.setattr(gl, "on_linux", lambda: True)
    fresh_backend_choice.setattr(gl, "egl_works", lambda: True)
    fresh_backend_choice.setattr(gl, "osmesa_works", lambda: True)
    fresh_backend_choice.setattr(gl, "display_open", lambda: False)
    loaded("glx")
    refused = r"PyOpenGL was imported before labsupport, with its glx platform, and MuJoCo's {} back end"
    assert re.match(refused.format("osmesa"), gl.pyopengl_refuses("osmesa"))
    assert re.match(refused.format("egl"), gl.pyopengl_refuses("egl")) and gl.pyopengl_refuses("glfw") is None
    fresh_backend_choice.setenv("MUJOCO_GL", "osmesa")
    with pytest.warns(RuntimeWarning, match=r"MUJOCO_GL='osmesa' cannot work in this process: .*restart the kernel"):
        assert gl.select_backend() is None  # and simulation goes on: MuJoCo's import works
    assert "MUJOCO_GL" not in os.environ and gl.user_backend is None
    assert "egl cannot work beside PyOpenGL's glx platform, osmesa cannot" in gl.last_choice
    fresh_backend_choice.setattr(gl, "display_open", lambda: True)
    assert gl.select_backend() == "glfw"  # a desktop: GLX is GLFW's own platform
    loaded("egl")  # imported with PYOPENGL_PLATFORM=egl: EGL serves, OSMesa does not
    fresh_backend_choice.setenv("MUJOCO_GL", "osmesa")
    with pytest.warns(RuntimeWarning, match=r"MUJOCO_GL='osmesa' cannot work in this process: .*its egl platform"):
        assert gl.select_backend() == "egl"
    loaded("osmesa")
    fresh_backend_choice.delenv("MUJOCO_GL")
    fresh_backend_choice.setenv("PYOPENGL_PLATFORM", "osmesa")
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert gl.select_backend() == "osmesa"
    fresh_backend_choice.delenv("PYOPENGL_PLATFORM")  # unset since: EGL, which works, is still refused
    fresh_backend_choice.delenv("MUJOCO_GL")
    assert gl.select_backend() == "osmesa" and "egl cannot work beside PyOpenGL's osmesa platform" in gl.last_choice
    fresh_backend_choice.setitem(sys.modules, "mujoco", types.ModuleType("mujoco"))  # MuJoCo chose already
    fresh_backend_choice.setenv("MUJOCO_GL", "egl")
    assert gl.unusable_choice("egl") is None and gl.select_backend() == "egl"


@pytest.mark.skipif(not gl.egl_works(), reason="EGL cannot open a display on this machine")
def test_pyopengl_imported_first_leaves_the_import_working_and_says_what_to_do(tmp_path):
    first = "import OpenGL.GL\n" + SCRIPT
    result = _run_script(tmp_path, first, str(tmp_path / "frames.npy"), MUJOCO_GL="osmesa", PYOPENGL_PLATFORM="egl")
    assert result["backend"] == "egl" and "error" not in result, result  # PyOpenGL's EGL platform: EGL renders
    _assert_real_frames(np.load(tmp_path / "frames.npy"))
    result = _run_script(tmp_path, first, str(tmp_path / "none.npy"), MUJOCO_GL="osmesa")  # its GLX platform
    assert result["backend"] is None and not (tmp_path / "none.npy").exists(), result
    assert "osmesa cannot work beside PyOpenGL's glx platform" in result["error"]
    assert result["error"].endswith(render.IMPORT_ORDER_HINT) and "apt-get" not in result["error"]  # nothing to install
    assert result["show_returned_none"]


def test_a_vendor_variable_naming_missing_files_is_named(fresh_backend_choice, tmp_path):
    """``__EGL_VENDOR_LIBRARY_FILENAMES`` pointing at a file that is not there hides every EGL
    driver, a GPU's too; the report used to give Mesa's install advice alone."""
    fresh_backend_choice.setenv("__EGL_VENDOR_LIBRARY_FILENAMES", f"{tmp_path / 'none.json'}:{tmp_path / 'gone.json'}")
    fresh_backend_choice.setattr(gl, "on_linux", lambda: True)
    for works in ("egl_works", "osmesa_works", "display_open"):
        fresh_backend_choice.setattr(gl, works, lambda: False)
    assert gl.select_backend() is None
    assert "__EGL_VENDOR_LIBRARY_FILENAMES names files that do not exist" in gl.last_choice
    assert str(tmp_path / "none.json") in gl.last_choice and str(tmp_path / "gone.json") in gl.last_choice
    (tmp_path / "none.json").write_text("{}")
    (tmp_path / "gone.json").write_text("{}")
    assert gl.select_backend() is None and "__EGL_VENDOR_LIBRARY_FILENAMES" not in gl.last_choice


def test_rendering_on_the_cpu_beside_an_unusable_gpu_says_why(monkeypatch, tmp_path):
    """Mesa's EGL renders but the GPU sits idle, or nothing renders: either way the GPU's
    missing EGL library is named, with what to do."""
    import mujoco

    driver = tmp_path / "version"
    driver.write_text("NVRM version: 550\n")
    monkeypatch.setattr(gl, "NVIDIA_DRIVER_FILES", (str(driver),))
    monkeypatch.setattr(gl, "NVIDIA_EGL_LIBRARY", "libEGL_nvidia_absent.so.0")
    monkeypatch.setattr(gl, "on_linux", lambda: True)
    monkeypatch.setenv("MUJOCO_GL", "egl")
    model = mujoco.MjModel.from_xml_string("<mujoco><worldbody><geom size='1'/></worldbody></mujoco>")
    made = object()
    monkeypatch.setattr(mujoco, "Renderer", lambda model, height, width: made)
    with pytest.warns(RuntimeWarning, match="renders in software here, slowly: an NVIDIA GPU is here"):
        assert render.make_renderer(model) is made

    def no_context(model, height, width):
        raise RuntimeError("eglInitialize failed")

    monkeypatch.setattr(mujoco, "Renderer", no_context)
    with pytest.raises(render.RenderingUnavailable, match=r"eglInitialize failed\)\. Also, an NVIDIA GPU is here"):
        render.make_renderer(model)


def test_a_linux_desktop_without_egl_or_osmesa_renders_through_glfw(fresh_backend_choice):
    fresh_backend_choice.setattr(gl, "on_linux", lambda: True)
    fresh_backend_choice.setattr(gl, "egl_works", lambda: False)
    fresh_backend_choice.setattr(gl, "osmesa_works", lambda: False)
    fresh_backend_choice.setenv("DISPLAY", ":0")
    assert gl.select_backend() == "glfw"
    assert os.environ["MUJOCO_GL"] == "glfw" and "PYOPENGL_PLATFORM" not in os.environ


def test_macos_and_windows_keep_mujocos_own_default(fresh_backend_choice):
    """MuJoCo renders offscreen there with MUJOCO_GL unset (CGL on macOS, GLFW on Windows); EGL
    and OSMesa, Linux's, are not even probed."""
    fresh_backend_choice.setattr(gl, "on_linux", lambda: False)
    fresh_backend_choice.setattr(gl, "egl_works", lambda: pytest.fail("EGL probed off Linux"))
    assert gl.select_backend() == "default"
    assert "MUJOCO_GL" not in os.environ and "default backend" in gl.last_choice


def test_off_linux_the_renderer_tries_mujocos_default_and_explains_a_failure(monkeypatch):
    import mujoco

    model = mujoco.MjModel.from_xml_string("<mujoco><worldbody><geom size='1'/></worldbody></mujoco>")
    monkeypatch.delenv("MUJOCO_GL", raising=False)
    monkeypatch.setattr(gl, "on_linux", lambda: False)
    made = object()
    monkeypatch.setattr(mujoco, "Renderer", lambda model, height, width: made)
    assert render.make_renderer(model) is made

    def no_context(model, height, width):
        raise RuntimeError("CGL: no pixel format")

    monkeypatch.setattr(mujoco, "Renderer", no_context)
    with pytest.raises(
        render.RenderingUnavailable, match=r"its default backend \(RuntimeError: CGL.*macOS and Windows"
    ):
        render.make_renderer(model)


def test_renderer_size_is_checked():
    import mujoco

    model = mujoco.MjModel.from_xml_string("<mujoco/>")
    with pytest.raises(ValueError, match="offscreen buffer"):
        render.make_renderer(model, width=4000, height=3000)
    with pytest.raises(ValueError, match=r"^an integer of 401 digits x 240 is larger than") as caught:
        render.make_renderer(model, width=10**400)  # named by its size, not printed digit by digit
    assert len(str(caught.value)) < 300


BIG_FRAME_SCRIPT = r"""
import json
import labsupport
from labsupport import render
from labsupport.plants import load_model
model, data = load_model("planar_2r")
try:
    render.render_picture(model, data, width=800, height=600)
except ValueError as err:
    refused = str(err)
model.vis.global_.offwidth, model.vis.global_.offheight = 800, 600  # as the message says
print(json.dumps([refused, list(render.render_picture(model, data, width=800, height=600).shape)]))
"""


@pytest.mark.skipif(not gl.egl_works(), reason="EGL cannot open a display on this machine")
def test_a_frame_larger_than_the_buffer_is_refused_with_advice_that_works(tmp_path):
    """800 x 600 is past the 2R model's 640 x 480 buffer: refused, with the attributes to set;
    set as the message says, the same picture renders."""
    refused, shape = _run_script(tmp_path, BIG_FRAME_SCRIPT, MUJOCO_GL="egl")
    assert refused == (
        "800 x 600 is larger than the model's offscreen buffer (640x480); pick a smaller size, or enlarge the "
        "buffer before rendering: set model.vis.global_.offwidth and model.vis.global_.offheight (in the model "
        "file, <visual><global offwidth offheight>)"
    )
    assert shape == [600, 800, 3]


@pytest.fixture
def glvnd(tmp_path, monkeypatch):
    """A system vendor folder holding Mesa's file only, NVIDIA's EGL library installed beside
    glvnd's loader and OpenGL library, and no glvnd variable set (all restored after)."""
    folder = tmp_path / "egl_vendor.d"
    folder.mkdir()
    (folder / "50_mesa.json").write_text('{"ICD": {"library_path": "libEGL_mesa.so.0"}}')
    monkeypatch.setattr(gl, "GLVND_EGL_VENDOR_DIRS", (str(tmp_path / "absent"), str(folder)))
    monkeypatch.setattr(
        gl, "library_loads", lambda name: name in (gl.NVIDIA_EGL_LIBRARY, gl.EGL_LOADER, "libOpenGL.so.0")
    )
    unset_env(monkeypatch, "__EGL_VENDOR_LIBRARY_FILENAMES", "__EGL_VENDOR_LIBRARY_DIRS")
    return folder


def test_nvidia_egl_is_listed_first_where_no_vendor_file_names_it(glvnd):
    """Colab's GPU runtime: NVIDIA's library is there, but only Mesa's vendor file."""
    assert gl.list_nvidia_egl() is True
    listed = os.environ["__EGL_VENDOR_LIBRARY_FILENAMES"].split(os.pathsep)
    assert listed == [gl.NVIDIA_EGL_VENDOR_FILE, str(glvnd / "50_mesa.json")]
    vendor = json.loads(open(gl.NVIDIA_EGL_VENDOR_FILE, encoding="utf-8").read())
    assert vendor["ICD"]["library_path"] == gl.NVIDIA_EGL_LIBRARY == "libEGL_nvidia.so.0"
    assert vendor["file_format_version"] == "1.0.0"


def test_nvidia_egl_listing_leaves_every_other_machine_alone(glvnd, monkeypatch):
    (glvnd / "10_nvidia.json").write_text('{"ICD": {"library_path": "libEGL_nvidia.so.0"}}')
    assert gl.list_nvidia_egl() is False  # the system names NVIDIA already
    (glvnd / "10_nvidia.json").unlink()
    monkeypatch.setenv("__EGL_VENDOR_LIBRARY_FILENAMES", "/the/users/own.json")
    assert gl.list_nvidia_egl() is False  # the user's own choice
    assert os.environ["__EGL_VENDOR_LIBRARY_FILENAMES"] == "/the/users/own.json"
    monkeypatch.delenv("__EGL_VENDOR_LIBRARY_FILENAMES")
    monkeypatch.setattr(gl, "library_loads", lambda name: False)
    assert gl.list_nvidia_egl() is False  # no NVIDIA driver
    assert "__EGL_VENDOR_LIBRARY_FILENAMES" not in os.environ


def test_nvidias_library_is_found_on_the_library_path_as_colab_installs_it(tmp_path):
    """Colab puts the driver's libraries in a folder of ``LD_LIBRARY_PATH``, with no unversioned
    ``.so`` and no entry in the loader's cache: what glvnd's ``dlopen`` finds must count.

    The stand-in library has a name of its own, since on a machine with an NVIDIA GPU the real
    ``libEGL_nvidia.so.0`` loads without the folder too."""
    libc = ctypes.util.find_library("c")
    found = subprocess.run(["ldconfig", "-p"], capture_output=True, text=True).stdout
    path = re.search(rf"{re.escape(libc)} \(libc6,x86-64\) => (\S+)", found)
    if path is None:
        pytest.skip("no x86-64 libc in the loader's cache to stand in for NVIDIA's library")
    stand_in = "libEGL_course_stand_in.so.0"  # versioned, as NVIDIA's is, and nowhere else
    shutil.copy(path.group(1), tmp_path / stand_in)
    probe = f"from labsupport import gl; print(gl.library_loads({stand_in!r}))"
    env = dict(os.environ, LD_LIBRARY_PATH=str(tmp_path))
    run = subprocess.run([sys.executable, "-c", probe], env=env, capture_output=True, text=True, timeout=120)
    assert run.stdout.split() == ["True"], run.stderr
    env.pop("LD_LIBRARY_PATH")
    run = subprocess.run([sys.executable, "-c", probe], env=env, capture_output=True, text=True, timeout=120)
    assert run.stdout.split() == ["False"], run.stderr


def test_a_user_choice_of_egl_still_gets_nvidias_egl_listed(glvnd, fresh_backend_choice):
    fresh_backend_choice.setenv("MUJOCO_GL", "egl")
    fresh_backend_choice.setattr(gl, "on_linux", lambda: True)
    assert gl.select_backend() == "egl"
    assert "NVIDIA's EGL listed by labsupport" in gl.last_choice
    assert os.environ["__EGL_VENDOR_LIBRARY_FILENAMES"].startswith(gl.NVIDIA_EGL_VENDOR_FILE)


@pytest.mark.skipif(not gl.egl_works(), reason="EGL cannot open a display on this machine")
def test_a_bad_mujoco_gl_still_simulates_and_renders_and_a_users_failing_one_is_named(tmp_path):
    """A mistyped backend no longer stops the import; a valid one that cannot render here (MuJoCo's
    ``disable``) says to unset it, where the advice used to be only what to install."""
    result, frames = _render_in_subprocess(tmp_path, MUJOCO_GL="bogus")
    assert result["backend"] == "egl", result
    _assert_real_frames(frames)
    (tmp_path / "frames.npy").unlink()
    result, frames = _render_in_subprocess(tmp_path, MUJOCO_GL="disable")
    assert frames is None and result["show_returned_none"], result
    assert gl.USER_BACKEND_ADVICE in result["error"] and "MUJOCO_GL=disable" in result["error"], result


@pytest.mark.skipif(not gl.egl_works(), reason="EGL cannot open a display on this machine")
def test_a_listed_nvidia_library_that_cannot_load_leaves_mesa_rendering(tmp_path):
    """Where the NVIDIA file is listed but its library is missing (no driver), glvnd skips it and
    the system's own vendors still render."""
    system = [str(f) for folder in gl.GLVND_EGL_VENDOR_DIRS for f in sorted(Path(folder).glob("*.json"))]
    result, frames = _render_in_subprocess(
        tmp_path, __EGL_VENDOR_LIBRARY_FILENAMES=os.pathsep.join([gl.NVIDIA_EGL_VENDOR_FILE, *system])
    )
    assert result["backend"] == "egl", result
    _assert_real_frames(frames)


@needs_ffmpeg
def test_video_has_a_text_alternative():
    frames = np.random.default_rng(0).integers(0, 255, (6, 48, 64, 3), dtype=np.uint8)
    html = render.video_html(frames, fps=6, title="a run", description="The arm <moves> round the circle.")
    assert '<video aria-label="The arm &lt;moves&gt; round the circle."' in html
    # the caption shows the same words to the eye; a screen reader reads them once, as the name
    assert '<figcaption aria-hidden="true">The arm &lt;moves&gt; round the circle.</figcaption>' in html
    assert "does not support the video tag" not in html
    assert 'type="video/mp4"' in html and 'width="64" height="48"' in html
    for missing in (None, "", "run.mp4", "the arm moves"):  # a video without one used to be shown
        with pytest.raises(ValueError, match="a video needs a text alternative of at least 5 words"):
            render.video_html(frames, fps=6, description=missing)


@needs_ffmpeg
def test_video_waits_for_the_reader():
    """No video starts by itself (WCAG 2.2.2): it has controls and no autoplay attribute."""
    frames = np.zeros((4, 16, 16, 3), dtype=np.uint8)
    video = re.search(
        r"<video[^>]*>", render.video_html(frames, fps=4, description="A still arm, in four frames.")
    ).group()
    assert " controls" in video and "autoplay" not in video


def test_render_names_the_cameras_and_refuses_a_reference_beyond_3d():
    from labsupport.plants import load_model
    from labsupport.sim import simulate

    model, data = load_model("planar_2r")
    log = simulate(model, data, lambda model, data: np.zeros(2), 0.01, site="end_effector")
    for camera in ("lab", 1, -2, True, 0.0):
        with pytest.raises(ValueError, match=r"camera .* is not in the model; its cameras are \['top'\].*or -1 for"):
            render.render_run(model, log, camera=camera)
    assert render._camera_id(model, np.int64(-1)) == -1 and render._camera_id(model, "top") == 0
    wide = dataclasses.replace(log, ref=np.zeros((len(log.t), 4)))
    with pytest.raises(ValueError, match="at most 3 coordinates"):
        render.render_run(model, wide)
    single, _ = load_model("single_joint")  # a log of another model: NumPy's broadcast error before
    with pytest.raises(ValueError, match="this log does not belong to this model: its rows hold 2 joint positions"):
        render.render_run(single, log)
    with pytest.raises(ValueError, match="fps must be positive"):
        plots.frame_indices(len(log.t), model.opt.timestep, fps=0)
    for kwargs, message in (
        ({"fps": "12"}, "fps must be numbers"),
        ({"trace_step": None}, "trace_step must be a number, got None"),
        ({"target_quat": (1.0, 0.0, 0.0)}, r"target_quat \(w, x, y, z\) must have shape \(4,\)"),
        ({"target_quat": (0.0, 0.0, 0.0, 0.0)}, "target_quat must be a unit quaternion"),
        ({"progress": "no"}, "progress must be True or False"),
    ):
        with pytest.raises(ValueError, match=message):
            render.render_run(model, log, **kwargs)
    with pytest.raises(ValueError, match="log must be the Log that labsupport.sim.simulate returns"):
        render.render_run(model, None)


FLOAT_SIZE_SCRIPT = r"""
import json
import numpy as np
import labsupport
from labsupport import render
from labsupport.plants import load_model
from labsupport.sim import simulate
model, data = load_model("planar_2r")
log = simulate(model, data, lambda model, data: np.zeros(2), 0.5, site="end_effector")
frames = render.render_run(model, log, fps=4, width=64.0, height=48.0, progress=False)
print(json.dumps(list(frames.shape)))
"""


@pytest.mark.skipif(not gl.egl_works(), reason="EGL cannot open a display on this machine")
def test_a_size_given_as_a_float_renders(tmp_path):
    """``make_renderer`` took ``width=64.0`` through ``int()``, but the frames' array did not:
    "'float' object cannot be interpreted as an integer"."""
    assert _run_script(tmp_path, FLOAT_SIZE_SCRIPT, MUJOCO_GL="egl")[1:] == [48, 64, 3]


DEFAULTS_SCRIPT = r"""
import json, sys
import numpy as np
import labsupport
from labsupport import render, trajectories
from labsupport.plants import load_model
from labsupport.sim import simulate
result = {}
for name, q0, reference in (
    ("planar_2r", [0.3, 1.2], lambda t: trajectories.circle_2d(t, (0.5, 0.2), 0.15, 2.0)),
    ("spatial_3r", [0.2, 0.4, 0.6], lambda t: trajectories.circle_3d(t, (0.8, 0.8, 1.2), 0.2, (0, 1, 0), 0.5)),
):
    model, data = load_model(name)
    ref = trajectories.sample(reference, model.opt.timestep, 1.0)
    def hold(model, data, q0=np.array(q0)):  # PD with gravity compensation: the arm swings, the site moves
        return data.qfrc_bias + 40.0 * (q0 - data.qpos) - 5.0 * data.qvel
    log = simulate(model, data, hold, 1.0, site="end_effector", reference=ref)
    for kind, run in ((" with reference", log),
                      (" without reference", simulate(model, data, hold, 1.0, site="end_effector")),
                      (" without site", simulate(model, data, hold, 1.0))):
        frames = render.render_run(model, run, fps=4, progress=False)
        last = frames[-1].astype(int)
        red = (last[..., 0] > 180) & (last[..., 1] < 70) & (last[..., 2] < 70)
        blue = (last[..., 2] > 150) & (last[..., 1] < 80) & (last[..., 0] < 30)  # the trace, not a blue link
        result[name + kind] = {"shape": list(frames.shape), "std": float(last.std()), "red": int(red.sum()),
                               "blue": int(blue.sum()), "site": run.site}
print(json.dumps(result))
"""


@pytest.mark.skipif(not gl.egl_works(), reason="EGL cannot open a display on this machine")
def test_every_arm_renders_with_the_defaults(tmp_path):
    """The 2R (a planar reference) and the 3R render without naming a camera or a site: the
    model's own camera, and the traces of the site the run logged and of its reference, for
    runs with a reference, with a site only, and with neither."""
    result = _run_script(tmp_path, DEFAULTS_SCRIPT)
    assert len(result) == 6
    for name, frame in result.items():
        assert frame["shape"] == [4, 240, 320, 3], name
        assert frame["std"] > 10, f"{name}: a blank frame"
        # the site swings 1 s under PD: its red trace shows if the run logged a site (a few red
        # pixels always: the model's site marker), the reference's blue one if it had one
        assert frame["site"] == (-1 if name.endswith("without site") else 0), name
        assert (frame["red"] > 60) == (frame["site"] == 0), (name, frame)
        assert (frame["blue"] > 20) == name.endswith("with reference"), (name, frame)


@pytest.fixture
def no_ffmpeg(monkeypatch):
    """mediapy finds no ffmpeg and imageio-ffmpeg is not installed (mediapy's choice restored after)."""
    mediapy.set_ffmpeg("no-such-ffmpeg-program")
    monkeypatch.setitem(sys.modules, "imageio_ffmpeg", None)  # import fails
    yield
    mediapy.set_ffmpeg("ffmpeg")


def test_without_ffmpeg_the_videos_say_how_to_get_it_and_the_notebook_goes_on(no_ffmpeg, monkeypatch, capsys):
    frames = np.zeros((4, 48, 64, 3), dtype=np.uint8)
    with pytest.raises(render.RenderingUnavailable, match=r"ffmpeg.*%pip install imageio-ffmpeg"):
        render.video_html(frames, fps=4, description="A still arm, in four frames.")
    shown = []
    monkeypatch.setattr(render.IPython.display, "display", shown.append)
    assert render.show_video(frames, 4, description="A still arm, in four frames.") is None
    monkeypatch.setattr(render, "render_run", lambda *a, **k: pytest.fail("rendered with no way to encode"))
    assert render.show_run_video(None, None, description="The arm reaches its target point.") is None
    printed = capsys.readouterr().out.splitlines()
    assert shown == [] and len(printed) == 2
    assert printed[0].startswith("(No video: Encoding the video needs the ffmpeg program")
    assert printed[0].endswith(") A still arm, in four frames.") and printed[1].endswith(
        ") The arm reaches its target point."
    )


@needs_ffmpeg
def test_the_ffmpeg_of_imageio_ffmpeg_is_used_when_none_is_on_the_path(no_ffmpeg, monkeypatch):
    bundled = FFMPEG  # stands in for the program that imageio-ffmpeg ships
    monkeypatch.setitem(sys.modules, "imageio_ffmpeg", types.SimpleNamespace(get_ffmpeg_exe=lambda: bundled))
    frames = np.random.default_rng(1).integers(0, 255, (4, 48, 64, 3), dtype=np.uint8)
    html = render.video_html(frames, fps=4, description="Random noise, in four small frames.")
    assert 'type="video/mp4"' in html
    assert mediapy.video_is_available()  # mediapy was pointed there: "no-such-ffmpeg-program" is not


@needs_ffmpeg
def test_video_quality_spans_h264s_whole_range():
    """qp 0 (lossless) and 51 (coarsest) both encode, the lossless video the larger; 52 and -1 are refused."""
    frames = np.random.default_rng(2).integers(0, 255, (4, 48, 64, 3), dtype=np.uint8)
    noise = "Random noise, in four small frames."
    sizes = [len(render.video_html(frames, fps=4, description=noise, qp=qp)) for qp in (0, 51)]
    assert sizes[0] > 2 * sizes[1]
    for qp in (52, -1, 2.5):
        with pytest.raises(ValueError, match=rf"qp must be a whole number from 0 to 51, got {qp}"):
            render.video_html(frames, fps=4, description=noise, qp=qp)


PICTURE_SCRIPT = r"""
import json
import labsupport
import mujoco
import numpy as np
from labsupport import render, trajectories
from labsupport.plants import load_model
model, data = load_model("spatial_3r")
data.qpos[:] = [0.4, 0.5, -0.9]
mujoco.mj_forward(model, data)
circle = trajectories.circle_3d(np.linspace(0, 5, 200), (1.0, 0.3, 1.2), 0.3, (0, 0, 1), 0.2).pos
result = {}
for name, path in (("with path", circle), ("without path", None)):
    frame = render.render_picture(model, data, path=path, width=320, height=240)
    red = (frame[..., 0] > 150) & (frame[..., 1] < 60) & (frame[..., 2] < 60)
    blue = (frame[..., 2] > 200) & (frame[..., 1] < 130) & (frame[..., 0] < 30)  # not the link's (51, 153, 230)
    result[name] = {"shape": list(frame.shape), "std": float(frame.std()),
                    "red": np.argwhere(red).tolist(), "blue": int(blue.sum())}
cam = model.camera("oblique").id
result["camera"] = {"pos": data.cam_xpos[cam].tolist(), "mat": data.cam_xmat[cam].tolist(),
                    "fovy": float(model.cam_fovy[cam]), "tip": data.site("end_effector").xpos.tolist()}
print(json.dumps(result))
"""


@pytest.mark.skipif(not gl.egl_works(), reason="EGL cannot open a display on this machine")
def test_a_picture_shows_the_tip_where_the_camera_sees_it_and_the_path_in_blue(tmp_path):
    """The red end-effector ball lies where a pinhole camera of the model's fovy projects the
    site's position (a few pixels of tolerance for the ball's radius); the path's blue trace
    shows only when a path is given."""
    result = _run_script(tmp_path, PICTURE_SCRIPT)
    cam = result.pop("camera")
    rotation = np.array(cam["mat"]).reshape(3, 3)  # camera axes in the world: x right, y up, looking along -z
    x, y, z = rotation.T @ (np.array(cam["tip"]) - np.array(cam["pos"]))
    focal = 120 / np.tan(np.radians(cam["fovy"]) / 2)  # half the 240-pixel height over tan(fovy / 2)
    column, row = 160 + focal * x / -z, 120 - focal * y / -z
    for name, frame in result.items():
        assert frame["shape"] == [240, 320, 3] and frame["std"] > 10, name
        red = np.array(frame["red"])
        near = np.hypot(red[:, 0] - row, red[:, 1] - column) < 6
        assert near.sum() >= 4, (name, (row, column), red.mean(axis=0))
    assert result["with path"]["blue"] > 100 and result["without path"]["blue"] == 0, result


SHARP_PICTURE_SCRIPT = r"""
import base64, io, json, re
import labsupport
import mujoco
import numpy as np
from PIL import Image
from labsupport import book, render, trajectories
from labsupport.plants import load_model
shown = []
book.display = lambda bundle, raw, metadata: shown.append((bundle, metadata))
result = {}
for name in ("spatial_3r", "planar_2r"):  # offscreen buffers of 960 x 720 and MuJoCo's default 640 x 480
    model, data = load_model(name)
    mujoco.mj_forward(model, data)
    render.show_picture(model, data, description=f"The {name} arm at q = 0, seen from its camera.")  # 480 x 360
    bundle, metadata = shown.pop()
    png = Image.open(io.BytesIO(base64.b64decode(bundle["image/png"])))
    img = re.search(r"<img [^>]*>", bundle["text/html"]).group()
    result[name] = {"size": list(png.size), "shown": metadata["image/png"]["width"], "img": img[-60:]}
model, data = load_model("spatial_3r")
data.qpos[:] = [0.4, 0.5, -0.9]
mujoco.mj_forward(model, data)
path = trajectories.circle_3d(np.linspace(0, 5, 200), (1.0, 0.3, 1.2), 0.3, (0, 0, 1), 0.2).pos
one, two = (render.render_picture(model, data, path=path, width=320, height=240, density=d) for d in (1, 2))
blue = lambda f: int(((f[..., 2] > 200) & (f[..., 1] < 130) & (f[..., 0] < 30)).sum())
halved = two.reshape(240, 2, 320, 2, 3).mean(axis=(1, 3))
result["trace"] = {"shapes": [list(one.shape), list(two.shape)], "blue": [blue(one), blue(two)],
                   "difference": float(np.abs(halved - one).mean())}
print(json.dumps(result))
"""


@pytest.mark.skipif(not gl.egl_works(), reason="EGL cannot open a display on this machine")
def test_a_picture_has_twice_the_pixels_where_the_buffer_holds_them(tmp_path):
    """show_picture renders a 480 x 360 picture of the 3R arm (a 960 x 720 buffer) at twice that
    size, as the figures are drawn, and one of the 2R arm (MuJoCo's default 640 x 480) pixel for
    pixel. At
    density 2 the trace is twice as wide (four times the blue pixels), and the frame halved is
    the density-1 frame up to antialiasing."""
    result = _run_script(tmp_path, SHARP_PICTURE_SCRIPT, MUJOCO_GL="egl")
    assert result["spatial_3r"]["size"] == [960, 720] and result["spatial_3r"]["shown"] == 480
    assert result["planar_2r"]["size"] == [480, 360] and result["planar_2r"]["shown"] == 480
    assert all('width="480"' in result[name]["img"] for name in ("spatial_3r", "planar_2r"))
    trace = result["trace"]
    assert trace["shapes"] == [[240, 320, 3], [480, 640, 3]]
    assert 3.0 < trace["blue"][1] / trace["blue"][0] < 5.0, trace
    assert trace["difference"] < 3.0, trace


def test_pictures_and_videos_are_not_made_while_the_batch_grader_runs(monkeypatch, capsys):
    from labsupport.grading import BATCH_ENV
    from labsupport.plants import load_model

    model, data = load_model("spatial_3r")
    monkeypatch.setenv(BATCH_ENV, "1")
    with pytest.raises(render.RenderingUnavailable, match="batch grader"):
        render.render_picture(model, data)
    render.show_picture(model, data, description="The 3R arm standing upright at q = 0.")
    printed = capsys.readouterr().out
    assert printed.startswith("(No picture: pictures and videos are not made while the batch grader")
    assert printed.rstrip().endswith(") The 3R arm standing upright at q = 0.")


def test_a_picture_names_a_bad_path_and_needs_a_description():
    from labsupport.plants import load_model

    model, data = load_model("spatial_3r")
    for path in (np.zeros((5, 2)), [[0.0, 0.0, np.nan]], "circle"):
        with pytest.raises(ValueError, match=r"path must be finite points of shape \(K, 3\)"):
            render.render_picture(model, data, path=path)
    with pytest.raises(ValueError, match="model and data"):
        render.render_picture(data, model)
    with pytest.raises(ValueError, match="camera"):
        render.render_picture(model, data, camera="front")
    with pytest.raises(ValueError):
        render.show_picture(model, data, description="arm")
    import mujoco  # data never evaluated: a black picture before

    with pytest.raises(ValueError, match="holds no kinematics yet.*mj_forward"):
        render.render_picture(model, mujoco.MjData(model))


def test_a_replay_keeps_the_logs_own_clock_and_a_video_needs_frames():
    """render_run timed a log by the model's step: the analytic single joint logged every 10 ms
    and replayed on the 1 ms MuJoCo model showed its first 0.2 s only. video_html of no frames
    ended in a bare StopIteration, and one (H, W, 3) picture became H frames."""
    from dataclasses import replace

    from labsupport.plants import SingleJoint, load_model

    model, _ = load_model("single_joint")
    log = SingleJoint().simulate(lambda t, s: 2 * (1 - s[0]) - 0.5 * s[1], 2.0, dt=0.01)
    dt = render._log_step(log, model.opt.timestep)
    assert dt == pytest.approx(0.01) and model.opt.timestep == pytest.approx(0.001)
    assert len(plots.frame_indices(len(log.t), dt, 10.0)) == 20  # two seconds at 10 frames/s, not 2 frames
    uneven = replace(log, t=log.t**2)
    with pytest.raises(ValueError, match="evenly spaced in time"):
        render.render_run(model, uneven, progress=False)
    for frames in (np.zeros((0, 48, 64, 3), np.uint8), [], np.zeros((48, 64, 3), np.uint8)):
        with pytest.raises(ValueError, match=r"frames must be a video: an \(F, height, width, 3\) array"):
            render.video_html(frames, fps=10, description="the arm turns one full circle")
    with pytest.raises(ValueError, match="fps must be positive"):
        render.video_html(np.zeros((2, 48, 64, 3), np.uint8), fps=0, description="the arm turns one full circle")


def test_frame_indices_pick_the_sample_nearest_each_frame_time():
    """Frame i of a video at f frames/s played at speed s shows the sample nearest t = i s / f;
    ``until`` ends the span; a span shorter than a frame shows its first sample, and a video
    of too many frames is refused."""
    dt, n = 0.002, 2500  # 5 s of 2 ms samples
    frames = plots.frame_indices(n, dt, fps=12)
    assert len(frames) == 60  # 5 s at 12 frames/s
    np.testing.assert_array_equal(frames[:4], [0, 42, 83, 125])  # t = 0, 1/12, 2/12, 3/12 s
    slow = plots.frame_indices(n, dt, fps=12, speed=0.25, until=1.0)
    assert len(slow) == 48  # the first second, four times slower: 4 s of video
    np.testing.assert_array_equal(slow[::4], frames[:12])  # every 4th slow frame is a real-time one
    assert slow[-1] * dt < 1.0 and plots.frame_indices(n, dt, fps=12, until=99.0).tolist() == frames.tolist()
    fast = plots.frame_indices(n, dt, fps=25, speed=2.0)
    np.testing.assert_array_equal(fast, np.arange(0, n, 40)[:62])  # 2 s of run per second of video, 2.5 s
    assert plots.frame_indices(n, dt, fps=12, until=0.05).tolist() == [0] == plots.frame_indices(5, dt, fps=12).tolist()
    with pytest.raises(ValueError, match=r"7200 frames, more than 1800: replay a part of the run \(until=\)"):
        plots.frame_indices(n, dt, fps=60, speed=1 / 24)
    for bad in (dict(speed=0.0), dict(speed=np.nan), dict(until=-1.0), dict(until="1 s")):
        with pytest.raises(ValueError, match=next(iter(bad))):
            plots.frame_indices(n, dt, fps=12, **bad)


SLOW_SCRIPT = r"""
import json
import numpy as np
import labsupport
from labsupport import render
from labsupport.plants import load_model
from labsupport.sim import simulate
model, data = load_model("spatial_3r")
def swing(model, data):  # PD with gravity compensation toward a pose half a radian away
    return data.qfrc_bias + 60.0 * (np.array([0.5, 0.8, -0.2]) - data.qpos) - 8.0 * data.qvel
log = simulate(model, data, swing, 2.0, q0=[0.0, 0.5, -0.5], site="end_effector")
real = render.render_run(model, log, fps=6, progress=False)
slow = render.render_run(model, log, fps=6, speed=0.5, until=1.0, progress=False)
print(json.dumps({"real": len(real), "slow": len(slow),
                  "same": [bool(np.array_equal(slow[2 * i], real[i])) for i in range(6)],
                  "between": float(np.abs(slow[1].astype(int) - real[0].astype(int)).mean())}))
"""


@pytest.mark.skipif(not gl.egl_works(), reason="EGL cannot open a display on this machine")
def test_a_slowed_replay_of_part_of_a_run_shows_the_same_instants_with_frames_between(tmp_path):
    """Half speed over the first second: twice the frames of that second, every other one the
    real-time replay's frame of the same instant, pixel for pixel, the others in between."""
    result = _run_script(tmp_path, SLOW_SCRIPT)
    assert result["real"] == 12 and result["slow"] == 12, result
    assert all(result["same"]), result
    assert result["between"] > 0.05, result  # the arm moved between the two instants


OVER_SCRIPT = r"""
import dataclasses, json
import labsupport  # first: picks the OpenGL backend before MuJoCo loads
import mujoco
import numpy as np
from labsupport import render, trajectories
from labsupport.controllers.operational_space import os_ct_torque
from labsupport.dynamics import site_jacobian
from labsupport.plants import load_model
from labsupport.sim import simulate
model, data = load_model("spatial_3r")
ref = trajectories.sample(lambda t: trajectories.circle_3d(t, (1.0, 0.0, 1.5), 0.3, (0, 0, 1), 0.5),
                          model.opt.timestep, 2.0)
start = ref.at(0.0)
rho, h = np.hypot(*start.pos[:2]), start.pos[2] - 1.0  # the tip's place in the arm's vertical plane
theta = np.arccos((rho**2 + h**2 - 2.0) / 2.0)
q0 = np.array([np.arctan2(start.pos[1], start.pos[0]),
               np.arctan2(rho, h) - np.arctan2(np.sin(theta), 1.0 + np.cos(theta)), theta - np.pi / 2])
data.qpos[:] = q0
mujoco.mj_forward(model, data)
qdot0 = np.linalg.solve(site_jacobian(model, data, "end_effector")[:3], start.vel)  # moving with the circle
def track(model, data):
    r = ref.at(data.time)
    return os_ct_torque(model, data, "end_effector", r.pos, r.vel, r.acc, 64.0, 16.0)
log = simulate(model, data, track, 2.0, q0=q0, qdot0=qdot0, site="end_effector", reference=ref)
bare = dataclasses.replace(log, ref=np.empty((len(log.t), 0)))  # the same run without its reference
last = {name: render.render_run(model, run, fps=4, progress=False, target_body="none")[-1].astype(int)
        for name, run in (("both", log), ("red only", bare))}
red_only, both = last["red only"], last["both"]
core = (red_only[..., 0] - np.maximum(red_only[..., 1], red_only[..., 2])) > 140  # the red trace's pixels
bluish = (both[..., 2] - np.maximum(both[..., 0], both[..., 1])) > 60
print(json.dumps({"gap_mm": float(1e3 * np.abs(log.err).max()), "core": int(core.sum()),
                  "blue_on_core": int(bluish[core].sum()), "blue": int(bluish.sum())}))
"""


@pytest.mark.skipif(not gl.egl_works(), reason="EGL cannot open a display on this machine")
def test_the_red_trace_shows_whole_over_a_reference_it_keeps_to(tmp_path):
    """A 3R run that keeps within a fraction of a millimetre of its circle: the pixels of its red
    trace stay red when the blue reference is drawn too (before, the two flickered where they
    coincide, and about a fifth of the red trace showed blue), and the wider blue band shows
    beside it."""
    result = _run_script(tmp_path, OVER_SCRIPT)
    assert result["gap_mm"] < 0.5 and result["core"] > 100, result
    assert result["blue_on_core"] <= 0.02 * result["core"], result
    assert result["blue"] > 0.5 * result["core"], result


def test_a_density_the_buffer_cannot_hold_names_the_frame_it_asked_for():
    """A 640 x 480 picture of the 2R arm fits its buffer (MuJoCo's default 640 x 480), but not at
    density 2: the message gives the 1280 x 960 frame that asks for, and what to do."""
    import mujoco

    from labsupport.plants import load_model

    model, data = load_model("planar_2r")
    mujoco.mj_forward(model, data)
    with pytest.raises(ValueError) as err:
        render.render_picture(model, data, width=640, height=480, density=2)
    message = str(err.value)
    assert "at density 2 a 640 x 480 picture is a 1280 x 960 frame" in message
    assert "(640x480)" in message and "density=1" in message
