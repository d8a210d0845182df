"""Choose MuJoCo's OpenGL backend before MuJoCo is imported.

MuJoCo reads ``MUJOCO_GL`` once, when it is first imported, so the choice has to be made
by the first thing a notebook imports: :mod:`labsupport` calls :func:`select_backend` on
import. The order of preference is EGL (GPU or Mesa's llvmpipe), then OSMesa (software),
then no rendering at all; simulation works in every case.
"""

from __future__ import annotations

import ctypes.util
import os
import platform
import sys

#: Where glvnd looks for EGL vendor files; Colab's NVIDIA driver ships none.
NVIDIA_EGL_VENDOR_FILE = "/usr/share/glvnd/egl_vendor.d/10_nvidia.json"
_NVIDIA_EGL_VENDOR_JSON = (
    '{\n  "file_format_version" : "1.0.0",\n  "ICD" : { "library_path" : "libEGL_nvidia.so.0" }\n}\n'
)


def on_linux() -> bool:
    """True on Linux, where ``MUJOCO_GL`` must name a backend; elsewhere MuJoCo's default renders."""
    return platform.system() == "Linux"


def display_open() -> bool:
    """True when an X11 or Wayland display is open (a Linux desktop session), so GLFW can render."""
    return bool(os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY"))


def on_colab() -> bool:
    """True when running inside a Google Colab kernel."""
    return "google.colab" in sys.modules


def _has_nvidia_gpu() -> bool:
    return os.path.exists("/dev/nvidia0") or os.path.exists("/proc/driver/nvidia/version")


def install_nvidia_egl_vendor_file(path: str = NVIDIA_EGL_VENDOR_FILE) -> bool:
    """Write the glvnd vendor file that lets EGL find NVIDIA's driver (Colab GPU runtimes).

    Returns True when the file exists afterwards. Does nothing without an NVIDIA GPU.
    """
    if os.path.exists(path):
        return True
    if not _has_nvidia_gpu():
        return False
    try:
        os.makedirs(os.path.dirname(path), exist_ok=True)
        with open(path, "w", encoding="utf-8") as f:
            f.write(_NVIDIA_EGL_VENDOR_JSON)
    except OSError:
        return False
    return True


def egl_works() -> bool:
    """True when EGL can open a headless display the way MuJoCo does (a GPU, or Mesa's llvmpipe).

    Calls ``eglQueryDevicesEXT``, ``eglGetPlatformDisplayEXT`` and ``eglInitialize`` through
    ctypes, so it needs neither MuJoCo nor PyOpenGL and takes a few milliseconds.
    """
    name = ctypes.util.find_library("EGL")
    if not name:
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


def select_backend() -> str | None:
    """Set ``MUJOCO_GL`` (and ``PYOPENGL_PLATFORM``) unless the user already chose.

    On Linux, EGL is taken if it really opens a display (:func:`egl_works`), else OSMesa if it
    really creates a context (:func:`osmesa_works`), else GLFW if a desktop display is open,
    else nothing: simulation still works and rendering raises a
    :class:`labsupport.render.RenderingUnavailable` that says what to install. On macOS and
    Windows nothing is set and MuJoCo's own default is in force (returned as ``"default"``).
    Returns the backend in force, or None.
    """
    global last_choice
    if "MUJOCO_GL" in os.environ:
        last_choice = f"MUJOCO_GL={os.environ['MUJOCO_GL']} was set before labsupport was imported"
        return os.environ["MUJOCO_GL"]
    if "mujoco" in sys.modules:
        last_choice = "mujoco was imported before labsupport, so MUJOCO_GL could not be chosen"
        return None
    if not on_linux():
        last_choice = f"MuJoCo's default backend for {platform.system()} (MUJOCO_GL unset)"
        return "default"
    if on_colab():
        install_nvidia_egl_vendor_file()
    tried = []
    # (backend, whether it works here, PyOpenGL's platform for it, what to report if not)
    for backend, works, pyopengl, failed in (
        ("egl", egl_works, "egl", "egl did not work"),
        ("osmesa", osmesa_works, "osmesa", "osmesa did not work"),
        ("glfw", display_open, None, "no display is open for glfw"),  # PyOpenGL's default: GLX
    ):
        if works():
            os.environ["MUJOCO_GL"] = backend
            if pyopengl:
                os.environ.setdefault("PYOPENGL_PLATFORM", pyopengl)
            last_choice = f"MUJOCO_GL={backend} (tried first: {', '.join(tried) or 'nothing'})"
            return backend
        tried.append(failed)
    last_choice = "no OpenGL backend works: " + ", ".join(tried)
    return None


_EGL_PLATFORM_DEVICE_EXT = 0x313F
_OSMESA_RGBA = 0x1908
