"""Choose MuJoCo's OpenGL backend before MuJoCo is imported.

MuJoCo reads ``MUJOCO_GL`` once, when it is first imported, so the choice has to be made
by the first thing a notebook imports: :mod:`labsupport` calls :func:`select_backend` on
import. The order of preference is EGL (GPU or Mesa's llvmpipe), then OSMesa (software),
then no rendering at all; simulation works in every case.
"""

from __future__ import annotations

import ctypes.util
import os
import sys

#: Where glvnd looks for EGL vendor files; Colab's NVIDIA driver ships none.
NVIDIA_EGL_VENDOR_FILE = "/usr/share/glvnd/egl_vendor.d/10_nvidia.json"
_NVIDIA_EGL_VENDOR_JSON = (
    '{\n  "file_format_version" : "1.0.0",\n'
    '  "ICD" : { "library_path" : "libEGL_nvidia.so.0" }\n}\n'
)


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


def available_backends() -> list[str]:
    """The MuJoCo GL backends whose system libraries can be found, best first."""
    found = []
    if ctypes.util.find_library("EGL"):
        found.append("egl")
    if ctypes.util.find_library("OSMesa"):
        found.append("osmesa")
    return found


def select_backend() -> str | None:
    """Set ``MUJOCO_GL`` (and ``PYOPENGL_PLATFORM``) unless the user already chose.

    Returns the backend in force, or None when none was found (rendering then raises a
    :class:`labsupport.render.RenderingUnavailable` that says what to install).
    """
    if "MUJOCO_GL" in os.environ:
        return os.environ["MUJOCO_GL"]
    if "mujoco" in sys.modules:
        # Too late to choose: MuJoCo has already read the variable.
        return None
    if on_colab():
        install_nvidia_egl_vendor_file()
    backends = available_backends()
    if not backends:
        return None
    os.environ["MUJOCO_GL"] = backends[0]
    os.environ.setdefault("PYOPENGL_PLATFORM", backends[0])
    return backends[0]
