"""Choose MuJoCo's OpenGL backend before MuJoCo is imported.

MuJoCo reads ``MUJOCO_GL`` once, when it is first imported, so the choice has to be made
by the first thing a notebook imports: :mod:`labsupport` calls :func:`select_backend` on
import. The order of preference is EGL (GPU or Mesa's llvmpipe), then GLFW where a display
is open, then OSMesa (software), then no rendering at all; simulation works in every case.
"""

from __future__ import annotations

import ctypes.util
import json
import os
import platform
import sys
import warnings
from pathlib import Path

#: The folders where glvnd's libEGL reads its vendor files: JSON files that each name one
#: driver's EGL library.
GLVND_EGL_VENDOR_DIRS = ("/etc/glvnd/egl_vendor.d", "/usr/share/glvnd/egl_vendor.d")
#: NVIDIA's EGL library, as glvnd loads it (``dlopen``: the loader's cache and ``LD_LIBRARY_PATH``).
NVIDIA_EGL_LIBRARY = "libEGL_nvidia.so.0"
#: labsupport's own vendor file naming :data:`NVIDIA_EGL_LIBRARY`, for drivers that install none (Colab).
NVIDIA_EGL_VENDOR_FILE = str(Path(__file__).with_name("nvidia_egl_vendor.json"))
#: Files that exist where NVIDIA's kernel driver runs (a GPU is there), inside a container too.
NVIDIA_DRIVER_FILES = ("/proc/driver/nvidia/version", "/dev/nvidiactl")
#: What to do where an NVIDIA GPU is there but its EGL library is not (see :func:`nvidia_egl_missing`).
NVIDIA_EGL_ADVICE = (
    f"an NVIDIA GPU is here, but its EGL library ({NVIDIA_EGL_LIBRARY}) does not load, so MuJoCo cannot render "
    "on it: in a container, start it with NVIDIA_DRIVER_CAPABILITIES=all (or one that includes graphics), "
    "which mounts the driver's OpenGL and EGL libraries; elsewhere, install the driver's OpenGL/EGL package"
)

#: glvnd's EGL loader: the library that MuJoCo's EGL back end opens (through PyOpenGL), and that in
#: turn loads a driver's EGL library (NVIDIA's, or Mesa's).
EGL_LOADER = "libEGL.so.1"
#: What to do where NVIDIA's EGL library is there but the loader is not (see :func:`egl_loader_missing`).
EGL_LOADER_ADVICE = (
    f"NVIDIA's EGL library ({NVIDIA_EGL_LIBRARY}) is here, but not the EGL loader ({EGL_LOADER}) that "
    "opens it: install the loader, and the OpenGL library that PyOpenGL uses beside it (Debian/Ubuntu: "
    "`sudo apt-get install libegl1 libopengl0`), and restart the kernel to render on the GPU"
)

#: The OpenGL libraries that PyOpenGL, through which MuJoCo renders, loads beside EGL: the first of
#: these names that loads as ``lib<name>.so`` or ``lib<name>.so.<0-9>``, as PyOpenGL looks for them.
PYOPENGL_EGL_LIBRARIES = ("OpenGL", "GL", "GLESv2", "GLESv1_CM")
#: What to do where PyOpenGL cannot load EGL (see :func:`pyopengl_egl_missing`).
EGL_LIBRARIES_ADVICE = (
    f"MuJoCo's EGL back end needs the EGL loader ({EGL_LOADER}) and an OpenGL library beside it "
    "(libOpenGL.so.0 or libGL.so.1), and without them MuJoCo's import fails on EGL: install them "
    "(Debian/Ubuntu: `sudo apt-get install libegl1 libopengl0`) and restart the kernel to render through EGL"
)


def on_linux() -> bool:
    """True on Linux, where ``MUJOCO_GL`` must name a backend; elsewhere MuJoCo's default renders."""
    return platform.system() == "Linux"


def display_open() -> bool:
    """True when an X11 or Wayland display is open (a Linux desktop session), so GLFW can render."""
    return bool(os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY"))


def _egl_library_of(vendor_file: Path) -> str:
    try:
        return json.loads(vendor_file.read_text(encoding="utf-8"))["ICD"]["library_path"]
    except (OSError, ValueError, KeyError, TypeError):
        return ""


def library_loads(name: str) -> bool:
    """True when the shared library ``name`` loads, found the way ``dlopen`` finds it."""
    try:
        ctypes.CDLL(name)
    except OSError:
        return False
    return True


def nvidia_egl_missing() -> bool:
    """True when NVIDIA's driver runs here (:data:`NVIDIA_DRIVER_FILES`) but its EGL library does
    not load: a container started without the driver's graphics libraries, typically. EGL then
    renders, if at all, through Mesa in software."""
    return any(Path(f).exists() for f in NVIDIA_DRIVER_FILES) and not library_loads(NVIDIA_EGL_LIBRARY)


def egl_loader_missing() -> bool:
    """True when NVIDIA's EGL library loads but glvnd's loader (:data:`EGL_LOADER`) does not: a GPU
    machine or container image with the driver's libraries and without the ``libegl1`` package.
    EGL cannot open at all then, and installing the loader makes it render on the GPU."""
    return not library_loads(EGL_LOADER) and library_loads(NVIDIA_EGL_LIBRARY)


def opengl_library_loads() -> bool:
    """True when PyOpenGL's EGL platform finds an OpenGL library: one of
    :data:`PYOPENGL_EGL_LIBRARIES`, as ``lib<name>.so`` or ``lib<name>.so.<0-9>``."""
    versions = ("", *(f".{n}" for n in range(10)))
    return any(library_loads(f"lib{name}.so{v}") for name in PYOPENGL_EGL_LIBRARIES for v in versions)


def pyopengl_egl_missing() -> bool:
    """True when PyOpenGL cannot load EGL here: no EGL loader (:data:`EGL_LOADER`), or no OpenGL
    library beside it (:func:`opengl_library_loads`), as on a minimal Debian or Ubuntu with
    ``libegl1`` and without ``libopengl0``. Importing MuJoCo with ``MUJOCO_GL=egl`` then fails
    inside PyOpenGL ("'NoneType' object has no attribute 'glGetError'"), simulation and all, even
    where EGL itself opens a display."""
    return not library_loads(EGL_LOADER) or not opengl_library_loads()


def missing_vendor_files() -> list[str]:
    """The files that ``__EGL_VENDOR_LIBRARY_FILENAMES`` names but that do not exist. glvnd reads
    only the files it names, so EGL then finds no driver in them, a GPU's included."""
    named = os.environ.get("__EGL_VENDOR_LIBRARY_FILENAMES", "").split(os.pathsep)
    return [f for f in named if f and not Path(f).is_file()]


def list_nvidia_egl() -> bool:
    """Let EGL find NVIDIA's driver where no glvnd vendor file names it (Colab's GPU runtimes).

    glvnd's libEGL loads only the drivers that the vendor files in
    :data:`GLVND_EGL_VENDOR_DIRS` name. Colab installs NVIDIA's ``libEGL_nvidia.so.0`` (on its
    ``LD_LIBRARY_PATH``) but no vendor file for it, so EGL sees no GPU. Then this sets
    ``__EGL_VENDOR_LIBRARY_FILENAMES`` to labsupport's NVIDIA file followed by the system's own
    files (so Mesa stays a fallback), for this process and the processes it starts; nothing on
    the system is written. Returns True when it set the variable. A machine where NVIDIA's EGL
    library does not load, a system whose vendor files name NVIDIA already, and a glvnd variable
    the user set are all left alone.
    """
    if "__EGL_VENDOR_LIBRARY_FILENAMES" in os.environ or "__EGL_VENDOR_LIBRARY_DIRS" in os.environ:
        return False
    system_files = sorted(
        (f for folder in GLVND_EGL_VENDOR_DIRS for f in Path(folder).glob("*.json")), key=lambda f: f.name
    )
    if any("nvidia" in _egl_library_of(f).lower() for f in system_files):
        return False
    if not library_loads(NVIDIA_EGL_LIBRARY):
        return False
    os.environ["__EGL_VENDOR_LIBRARY_FILENAMES"] = os.pathsep.join(
        [NVIDIA_EGL_VENDOR_FILE, *(str(f) for f in system_files)]
    )
    return True


def egl_works() -> bool:
    """True when EGL can open a headless display the way MuJoCo does (a GPU, or Mesa's llvmpipe),
    with an OpenGL library beside it for PyOpenGL (:func:`opengl_library_loads`).

    Calls ``eglQueryDevicesEXT``, ``eglGetPlatformDisplayEXT`` and ``eglInitialize`` through
    ctypes, so it needs neither MuJoCo nor PyOpenGL and takes a few milliseconds.
    """
    name = ctypes.util.find_library("EGL")
    if not name or not opengl_library_loads():
        return False
    try:
        egl = ctypes.CDLL(name)
        egl.eglGetProcAddress.restype = ctypes.c_void_p
        egl.eglGetProcAddress.argtypes = [ctypes.c_char_p]
        egl.eglInitialize.argtypes = [ctypes.c_void_p, ctypes.POINTER(ctypes.c_int), ctypes.POINTER(ctypes.c_int)]
        egl.eglTerminate.argtypes = [ctypes.c_void_p]
        query_addr = egl.eglGetProcAddress(b"eglQueryDevicesEXT")
        display_addr = egl.eglGetProcAddress(b"eglGetPlatformDisplayEXT")
        if not (query_addr and display_addr):
            return False
        query = ctypes.CFUNCTYPE(
            ctypes.c_uint, ctypes.c_int, ctypes.POINTER(ctypes.c_void_p), ctypes.POINTER(ctypes.c_int)
        )(query_addr)
        get_display = ctypes.CFUNCTYPE(ctypes.c_void_p, ctypes.c_uint, ctypes.c_void_p, ctypes.c_void_p)(display_addr)
        devices, count = (ctypes.c_void_p * 16)(), ctypes.c_int(0)
        if not query(16, devices, ctypes.byref(count)):
            return False
        for i in range(count.value):
            display = get_display(_EGL_PLATFORM_DEVICE_EXT, devices[i], None)
            major, minor = ctypes.c_int(), ctypes.c_int()
            if display and egl.eglInitialize(display, ctypes.byref(major), ctypes.byref(minor)):
                egl.eglTerminate(display)
                return True
    except (OSError, AttributeError, TypeError):
        return False
    return False


def osmesa_works() -> bool:
    """True when OSMesa (software OpenGL) can create a context."""
    name = ctypes.util.find_library("OSMesa")
    if not name:
        return False
    try:
        lib = ctypes.CDLL(name)
        lib.OSMesaCreateContextExt.restype = ctypes.c_void_p
        lib.OSMesaCreateContextExt.argtypes = [ctypes.c_uint, ctypes.c_int, ctypes.c_int, ctypes.c_int, ctypes.c_void_p]
        lib.OSMesaDestroyContext.argtypes = [ctypes.c_void_p]
        context = lib.OSMesaCreateContextExt(_OSMESA_RGBA, 24, 0, 0, None)
        if not context:
            return False
        lib.OSMesaDestroyContext(context)
        return True
    except (OSError, AttributeError, TypeError):
        return False


#: Why the last :func:`select_backend` chose what it chose (shown by rendering errors).
last_choice: str = "select_backend() has not run"
#: The ``MUJOCO_GL`` the user had set before labsupport was imported, if any.
user_backend: str | None = None
#: What to do where the backend the user set does not render.
USER_BACKEND_ADVICE = (
    "MUJOCO_GL was set before labsupport was imported: unset it where it was set and restart the "
    "kernel, and labsupport picks a backend that works here"
)


def mujoco_gl_values() -> tuple[str, ...]:
    """The ``MUJOCO_GL`` values MuJoCo accepts on this system (its import refuses any other)."""
    values = ("disable", "disabled", "off", "false", "0", "enable", "enabled", "on", "true", "1", "glfw")
    extra = {"Linux": ("glx", "egl", "osmesa"), "Windows": ("wgl",), "Darwin": ("cgl",)}
    return values + extra.get(platform.system(), ())


#: The ``MUJOCO_GL`` values whose MuJoCo module requires ``PYOPENGL_PLATFORM`` to be the same
#: value (or unset): MuJoCo's EGL and OSMesa modules refuse any other, at import (MuJoCo 3) or
#: when a renderer is made (MuJoCo 4).
PYOPENGL_PLATFORMS = ("egl", "osmesa")


def match_pyopengl_platform(backend: str) -> None:
    """Set ``PYOPENGL_PLATFORM`` to ``backend`` (``egl`` or ``osmesa``), the only value with which
    MuJoCo renders through it. A different value the user set is replaced, with a warning."""
    users = os.environ.get("PYOPENGL_PLATFORM", "").strip()
    if users and users.lower() != backend:
        warnings.warn(
            f"PYOPENGL_PLATFORM={users!r} does not match MUJOCO_GL={backend}, and MuJoCo renders with "
            f"MUJOCO_GL={backend} only under PYOPENGL_PLATFORM={backend}; labsupport sets that. "
            "Unset PYOPENGL_PLATFORM (or set it to the same value as MUJOCO_GL) to silence this.",
            RuntimeWarning,
            stacklevel=3,
        )
    os.environ["PYOPENGL_PLATFORM"] = backend


#: What to do where PyOpenGL was imported before labsupport with a platform MuJoCo cannot render through.
IMPORT_ORDER_ADVICE = "restart the kernel and import labsupport first, before anything that imports OpenGL"


def pyopengl_platform() -> str | None:
    """The platform PyOpenGL took at its import (``glx``, ``egl``, ``osmesa``, ...), which it keeps
    for the life of the process; None where PyOpenGL is not imported yet."""
    loaded = getattr(sys.modules.get("OpenGL.platform"), "PLATFORM", None)
    return None if loaded is None else type(loaded).__module__.rpartition(".")[2]  # OpenGL.platform.glx: glx


def pyopengl_refuses(backend: str) -> str | None:
    """Why MuJoCo's ``backend`` cannot work in this process, or None. MuJoCo's EGL and OSMesa back
    ends work only through PyOpenGL's platform of the same name (they demand
    ``PYOPENGL_PLATFORM=<backend>``), and PyOpenGL keeps the platform it took at its import
    (:func:`pyopengl_platform`). Imported before labsupport without ``PYOPENGL_PLATFORM``, it takes
    GLX: MuJoCo's import with ``MUJOCO_GL=osmesa`` then fails inside PyOpenGL ("'GLXPlatform'
    object has no attribute 'OSMesa'"), simulation and all, and MuJoCo 3's EGL back end cannot
    open a display."""
    taken = pyopengl_platform()
    if taken is None or backend not in PYOPENGL_PLATFORMS or taken == backend:
        return None
    return (
        f"PyOpenGL was imported before labsupport, with its {taken} platform, and MuJoCo's {backend} back end "
        f"works only with PyOpenGL's {backend} platform"
    )


def unusable_choice(chosen: str) -> str | None:
    """Why MuJoCo's import would fail on the ``MUJOCO_GL`` value ``chosen``, or None: a value it
    does not know, ``egl`` where PyOpenGL cannot load EGL (:func:`pyopengl_egl_missing`), or a
    backend that a PyOpenGL imported earlier cannot serve (:func:`pyopengl_refuses`). Once MuJoCo
    is imported, its choice is made and nothing is unusable."""
    value = chosen.strip().lower()
    if not value or "mujoco" in sys.modules:
        return None
    if value not in mujoco_gl_values():
        return f"is not a value MuJoCo knows (on {platform.system()}: {', '.join(mujoco_gl_values())}): fix or unset it"
    if on_linux() and value == "egl" and pyopengl_egl_missing():
        return f"cannot work here: {EGL_LIBRARIES_ADVICE}"
    if refused := pyopengl_refuses(value):
        return f"cannot work in this process: {refused}: {IMPORT_ORDER_ADVICE}"
    return None


def select_backend() -> str | None:
    """Set ``MUJOCO_GL`` (and ``PYOPENGL_PLATFORM``) unless the user already chose (an empty
    ``MUJOCO_GL`` counts as no choice; one on which MuJoCo's import would fail
    (:func:`unusable_choice`) is dropped with a warning).

    On Linux, EGL is taken if it really opens a display and PyOpenGL has an OpenGL library to
    use with it (:func:`egl_works`), else OSMesa if it
    really creates a context (:func:`osmesa_works`), else GLFW if a desktop display is open,
    else nothing: simulation still works and rendering raises a
    :class:`labsupport.render.RenderingUnavailable` that says what to install. On macOS and
    Windows nothing is set and MuJoCo's own default is in force (returned as ``"default"``).
    On Linux, NVIDIA's EGL is first made visible to glvnd where no vendor file names it
    (:func:`list_nvidia_egl`), also when the user set ``MUJOCO_GL=egl`` beforehand.
    ``PYOPENGL_PLATFORM`` is made to agree with an ``egl`` or ``osmesa`` backend
    (:func:`match_pyopengl_platform`); set by the user to one of them, it puts that backend first.
    Returns the backend in force, or None.
    """
    global last_choice, user_backend
    chosen = os.environ.get("MUJOCO_GL", "")
    if why_dropped := unusable_choice(chosen):  # MuJoCo's import would fail, and every simulation with it
        warnings.warn(
            f"MUJOCO_GL={chosen!r} {why_dropped}; labsupport ignores it and picks a backend itself.",
            RuntimeWarning,
            stacklevel=2,
        )
        del os.environ["MUJOCO_GL"]
    user_backend = None
    notes = " (NVIDIA's EGL listed by labsupport)" if on_linux() and list_nvidia_egl() else ""
    if on_linux() and nvidia_egl_missing():
        notes += f"; {NVIDIA_EGL_ADVICE}"
    elif on_linux() and egl_loader_missing():
        notes += f"; {EGL_LOADER_ADVICE}"
    elif on_linux() and pyopengl_egl_missing():
        notes += f"; {EGL_LIBRARIES_ADVICE}"
    if on_linux() and (gone := missing_vendor_files()):
        notes += (
            f"; __EGL_VENDOR_LIBRARY_FILENAMES names files that do not exist ({', '.join(gone)}): "
            "fix or unset it where it was set, and restart the kernel"
        )
    if os.environ.get("MUJOCO_GL", "").strip():  # empty is no choice: MuJoCo would take GLFW's default
        user_backend = os.environ["MUJOCO_GL"]
        if user_backend.strip().lower() in PYOPENGL_PLATFORMS and "mujoco" not in sys.modules:
            match_pyopengl_platform(user_backend.strip().lower())
        last_choice = f"MUJOCO_GL={user_backend} was set before labsupport was imported{notes}"
        return user_backend
    if "mujoco" in sys.modules:
        last_choice = "mujoco was imported before labsupport, so MUJOCO_GL could not be chosen"
        return None
    if not on_linux():
        last_choice = f"MuJoCo's default backend for {platform.system()} (MUJOCO_GL unset)"
        return "default"
    tried = []
    # (backend, whether it works here, what to report if not); a PYOPENGL_PLATFORM the user set
    # to egl or osmesa puts that backend first
    candidates = [
        ("egl", egl_works, "egl did not work"),
        ("osmesa", osmesa_works, "osmesa did not work"),
        ("glfw", display_open, "no display is open for glfw"),  # PyOpenGL's default: GLX
    ]
    asked = os.environ.get("PYOPENGL_PLATFORM", "").strip().lower()
    candidates.sort(key=lambda candidate: candidate[0] != asked)
    for backend, works, failed in candidates:
        if pyopengl_refuses(backend):
            tried.append(f"{backend} cannot work beside PyOpenGL's {pyopengl_platform()} platform")
            continue
        if works():
            os.environ["MUJOCO_GL"] = backend
            if backend in PYOPENGL_PLATFORMS:
                match_pyopengl_platform(backend)
            last_choice = f"MUJOCO_GL={backend} (tried first: {', '.join(tried) or 'nothing'}){notes}"
            return backend
        tried.append(failed)
    last_choice = "no OpenGL backend works: " + ", ".join(tried) + notes
    return None


_EGL_PLATFORM_DEVICE_EXT = 0x313F
_OSMESA_RGBA = 0x1908
