"""The bubblewrap sandbox a submission runs in: what it sees, what it may use, how it is started.

One :class:`Layout` is prepared per batch, in a private folder of the grader's, and shared
read-only by every sandbox of the batch:

* ``/opt/python``: the base interpreter (bound at a neutral path, so ``sys.prefix`` names no
  folder of the course checkout), and ``/opt/venv``: a skeleton virtual environment whose
  ``site-packages`` is the grader's own, with every way into the checkout masked (editable
  finders, ``.pth`` files naming it, labsupport's own metadata); the host folders bound there
  are still named by the kernel's mount table and bubblewrap's command line in ``/proc``, as
  paths the sandbox cannot open;
* ``/opt/student/labsupport``: labsupport as a student installs it (the packages the wheel
  lists in ``pyproject.toml``, so no instructor tooling), with the modules of
  :data:`labsupport.grading.rules.FORBIDDEN` replaced by stubs whose every attribute is a
  function raising ``RuntimeError(forbidden_message(name))``;
* ``/opt/runner/labsupport_sandbox.py``: the server that runs the cells
  (:mod:`labsupport.instructor.sandbox`).

Each sandbox then gets its own PID, network, IPC, UTS and user namespaces (no network at all;
when its first process ends, or the grader stops it, the kernel kills every process left in it,
however it detached), a private ``tmpfs`` of capped size as home (its working folder), as
``/tmp`` and as ``/dev/shm``, everything else read-only, and resource limits (address space,
CPU time, file size, core dumps, processes). It sees neither the checkout, nor the
submissions, nor the output folder, nor the grader, nor any other submission.
"""

from __future__ import annotations

import ast
import os
import resource
import shutil
import subprocess
import sys
import sysconfig
import tempfile
from dataclasses import dataclass
from pathlib import Path

from labsupport.grading import rules

try:
    import tomllib
except ImportError:  # Python 3.10
    import tomli as tomllib

#: The repository root (the grader runs from a checkout).
CHECKOUT = Path(__file__).resolve().parents[2]
#: Where the sandbox finds things.
PYTHON_HOME, VENV, STUDENT, RUNNER, HOME = "/opt/python", "/opt/venv", "/opt/student", "/opt/runner", "/home/student"
#: The server's file name inside the sandbox.
SERVER = "labsupport_sandbox.py"


@dataclass(frozen=True)
class Limits:
    """Resource limits of one sandbox (each process in it).

    Attributes:
        memory: address space per process [bytes].
        cpu: CPU time per process, a hard backstop [s] (the scoring limits are the judge's).
        file_size: largest file it may write [bytes].
        processes: processes per user (enforced by the kernel only for a grader not run as root;
            the PID namespace's teardown bounds them in every case).
        scratch: size of each private tmpfs (home, ``/tmp``, ``/dev/shm``) [bytes]; nothing
            else in the sandbox is writable.
    """

    memory: int = 4 << 30
    cpu: int = 900
    file_size: int = 64 << 20
    processes: int = 512
    scratch: int = 256 << 20


#: The limits a batch uses unless told otherwise.
DEFAULT_LIMITS = Limits()


class SandboxUnavailable(RuntimeError):
    """bubblewrap cannot run here; the message says what to do."""


# ---------------------------------------------------------------------------------------------
# the student's labsupport
# ---------------------------------------------------------------------------------------------


def wheel_files(checkout: Path = CHECKOUT) -> dict[str, Path]:
    """What the student's wheel holds: ``{path inside site-packages: source file}``, from the
    ``[tool.setuptools]`` packages, package-dir and package-data of ``pyproject.toml``."""
    config = tomllib.loads((checkout / "pyproject.toml").read_text(encoding="utf-8"))["tool"]["setuptools"]
    package_dir = config.get("package-dir", {})
    package_data = config.get("package-data", {})
    files = {}
    for package in config["packages"]:
        src = checkout / package_dir.get(package, package.replace(".", "/"))
        dst = package.replace(".", "/")
        for p in sorted(src.glob("*.py")):
            files[f"{dst}/{p.name}"] = p
        for pattern in package_data.get(package, []):
            for p in sorted(src.glob(pattern)):
                files[f"{dst}/{p.name}"] = p
    return files


def public_names(source: str) -> list[str]:
    """The names a module's source defines at its top level without a leading ``_`` (what
    ``from module import *`` takes from it)."""
    names = []
    for node in ast.parse(source).body:
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)):
            names.append(node.name)
        elif isinstance(node, (ast.Assign, ast.AnnAssign)):
            targets = node.targets if isinstance(node, ast.Assign) else [node.target]
            names += [t.id for t in targets if isinstance(t, ast.Name)]
    return sorted({name for name in names if not name.startswith("_")})


def stub_source(module: str, submodules: list[str], message_template: str, names: list[str] = ()) -> str:
    """A forbidden module's stand-in: every attribute is a function raising the rule's message;
    ``__all__`` lists the real module's ``names``, so ``from module import *`` takes such a
    function for each (and a call to it gets the rule's reason, not a ``NameError``).

    Each of ``names`` is a function of its own at the top of the stub, with its message written
    out: its source, which ``inspect.getsource`` gives a submission that copies a law's code to
    run it with ``exec``, is then that same refusal, and the copy's call gets the rule's reason
    (a nested function's source is indented, and ``exec`` of it used to raise
    ``IndentationError``)."""
    named = "".join(
        f"\n\ndef {name}(*args, **kwargs):\n"
        f"    raise RuntimeError({message_template.replace('@@NAME@@', f'{module}.{name}')!r})\n"
        for name in sorted(set(names) - set(submodules))
    )
    return f'''"""{module} is not available while a submission is graded (see the grader's notes)."""

import importlib as _importlib

_TEMPLATE = {message_template!r}
_SUBMODULES = {tuple(submodules)!r}
__all__ = {sorted(names)!r}


def __getattr__(name):
    if name.startswith("__"):
        raise AttributeError(name)
    if name in _SUBMODULES:
        return _importlib.import_module(__name__ + "." + name)

    def forbidden(*args, **kwargs):
        raise RuntimeError(_TEMPLATE.replace("@@NAME@@", __name__ + "." + name))

    forbidden.__name__ = forbidden.__qualname__ = name
    return forbidden
{named}'''


def write_student_package(dest: Path, checkout: Path = CHECKOUT) -> list[str]:
    """Write the student's labsupport under ``dest``; returns the modules replaced by stubs."""
    template = rules.forbidden_message("@@NAME@@")
    files = wheel_files(checkout)
    stubbed = []
    for rel, src in files.items():
        target = dest / rel
        target.parent.mkdir(parents=True, exist_ok=True)
        module = rel[:-3].replace("/", ".") if rel.endswith(".py") else None
        if module and module.endswith(".__init__"):
            module = module[: -len(".__init__")]
        if module and rules.is_forbidden_module(module):
            package_dir = rel.rsplit("/", 1)[0]
            subs = (
                sorted(
                    Path(r).stem
                    for r in files
                    if r.endswith(".py") and r.rsplit("/", 1)[0] == package_dir and not r.endswith("__init__.py")
                )
                if rel.endswith("__init__.py")
                else []
            )
            names = public_names(Path(src).read_text(encoding="utf-8"))
            target.write_text(stub_source(module, subs, template, names), encoding="utf-8")
            stubbed.append(module)
        else:
            shutil.copyfile(src, target)
    # the stubs hide the forbidden functions' code: the watch recognises a compiled copy of one
    # by the fingerprints of the real ones (rules.carried_forbidden_code)
    rules.write_forbidden_code(checkout / "labsupport", dest / "labsupport" / "grading" / rules.FORBIDDEN_CODE_FILE)
    return stubbed


# ---------------------------------------------------------------------------------------------
# the interpreter
# ---------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class Layout:
    """A prepared sandbox layout (host paths) and the bubblewrap arguments that mount it."""

    root: Path
    bwrap: str
    mounts: tuple[str, ...]
    env: tuple[tuple[str, str], ...]
    python: str
    limits: Limits
    stubbed: tuple[str, ...]


def _interpreter_mounts(root: Path) -> tuple[list[str], list[tuple[str, str]], str]:
    """bwrap arguments for the interpreter and its packages, the variables they need, and the
    interpreter's path inside the sandbox."""
    base = Path(sys.base_prefix).resolve()
    exe = Path(getattr(sys, "_base_executable", sys.executable)).resolve()
    system = str(base).startswith("/usr")
    home = str(base) if system else PYTHON_HOME
    inner_exe = f"{home}/{exe.relative_to(base)}" if exe.is_relative_to(base) else str(exe)
    mounts = [] if system else ["--ro-bind", str(base), PYTHON_HOME]
    env = [] if system else [("LD_LIBRARY_PATH", f"{PYTHON_HOME}/lib")]
    if Path(sys.prefix).resolve() == base:  # not a virtual environment: its site-packages is in the base
        return mounts, env, inner_exe
    version = f"python{sys.version_info.major}.{sys.version_info.minor}"
    skeleton = root / "venv"
    site_in = f"lib/{version}/site-packages"
    (skeleton / "bin").mkdir(parents=True)
    (skeleton / site_in).mkdir(parents=True)
    (skeleton / "bin" / "python").symlink_to(inner_exe)
    (skeleton / "pyvenv.cfg").write_text(
        f"home = {Path(inner_exe).parent}\ninclude-system-site-packages = false\nversion = {sys.version.split()[0]}\n",
        encoding="utf-8",
    )
    mounts += ["--ro-bind", str(skeleton), VENV]
    site = Path(sysconfig.get_paths()["purelib"]).resolve()
    mounts += ["--ro-bind", str(site), f"{VENV}/{site_in}"]
    empty = root / "empty"
    empty.mkdir(exist_ok=True)
    for p in sorted(site.iterdir()):
        inner = f"{VENV}/{site_in}/{p.name}"
        if p.is_dir() and (p.name == "labsupport" or (p.name.startswith("labsupport-") and p.name.endswith("-info"))):
            mounts += ["--ro-bind", str(empty), inner]  # labsupport comes from /opt/student only
        elif p.is_file() and (p.name.startswith("__editable__") or p.suffix in (".pth", ".egg-link")):
            try:
                names_checkout = str(CHECKOUT) in p.read_text(encoding="utf-8", errors="replace")
            except OSError:
                names_checkout = True
            if names_checkout or "labsupport" in p.name:
                mounts += ["--ro-bind", "/dev/null", inner]
    return mounts, env, f"{VENV}/bin/python"


def _system_mounts() -> list[str]:
    mounts = ["--ro-bind", "/usr", "/usr"]
    for name in ("bin", "lib", "lib64", "lib32", "sbin"):
        p = Path("/") / name
        if p.is_symlink():
            mounts += ["--symlink", os.readlink(p), f"/{name}"]
        elif p.is_dir():
            mounts += ["--ro-bind", str(p), f"/{name}"]
    for name in ("ld.so.cache", "ld.so.conf", "ld.so.conf.d", "localtime", "alternatives", "fonts"):
        if (Path("/etc") / name).exists():
            mounts += ["--ro-bind", f"/etc/{name}", f"/etc/{name}"]
    return mounts


def find_bwrap() -> str:
    """Path of bubblewrap, or :class:`SandboxUnavailable` saying what to do."""
    if not sys.platform.startswith("linux"):
        raise SandboxUnavailable(
            f"the batch grader sandboxes each submission with bubblewrap, which needs Linux (this is {sys.platform}). "
            "Grade on a Linux machine (a VM or a container started with user namespaces allowed), or, for "
            "submissions you trust, pass --unsafe-no-sandbox."
        )
    path = shutil.which("bwrap")
    if path is None:
        raise SandboxUnavailable(
            "bubblewrap (bwrap) is not installed: install it (Debian/Ubuntu: sudo apt-get install bubblewrap; "
            "Fedora: sudo dnf install bubblewrap), or run bash .ci/setup, then grade again. For submissions "
            "you trust, --unsafe-no-sandbox grades without isolation."
        )
    return path


def prepare(root: Path, limits: Limits = DEFAULT_LIMITS, checkout: Path = CHECKOUT) -> Layout:
    """Build the read-only layout every sandbox of a batch shares, in the private folder ``root``,
    and check a sandbox really starts (raises :class:`SandboxUnavailable` otherwise)."""
    bwrap = find_bwrap()
    root = Path(root)
    stubbed = write_student_package(root / "student", checkout)
    (root / "runner").mkdir()
    shutil.copyfile(Path(__file__).with_name("sandbox.py"), root / "runner" / SERVER)
    (root / "mpl").mkdir()
    interp, interp_env, python = _interpreter_mounts(root)
    mounts = (
        _system_mounts()
        + interp
        + ["--ro-bind", str(root / "student"), STUDENT, "--ro-bind", str(root / "runner"), RUNNER]
    )
    env = [
        ("PATH", f"{Path(python).parent}:/usr/bin:/bin"),
        ("HOME", HOME),
        ("TMPDIR", "/tmp"),
        ("PYTHONPATH", STUDENT),
        ("PYTHONNOUSERSITE", "1"),
        ("PYTHONDONTWRITEBYTECODE", "1"),
        ("PYTHONHASHSEED", "0"),
        ("MPLBACKEND", "Agg"),
        ("MPLCONFIGDIR", f"{HOME}/.config/matplotlib"),
        ("MUJOCO_GL", "disable"),
        ("OMP_NUM_THREADS", "1"),
        ("OPENBLAS_NUM_THREADS", "1"),
        ("MKL_NUM_THREADS", "1"),
        ("LANG", "C.UTF-8"),
        ("LABSUPPORT_GRADING_BATCH", "1"),
        *interp_env,
    ]
    layout = Layout(root, bwrap, tuple(mounts), tuple(env), python, limits, tuple(stubbed))
    _warm_up(layout)
    return layout


def _warm_up(layout: Layout) -> None:
    """Start one sandbox that compiles the student's labsupport and builds matplotlib's font
    cache (both kept read-only for the batch), so every submission starts faster; a sandbox
    that cannot start raises :class:`SandboxUnavailable` with bubblewrap's own words."""
    code = (
        "import compileall, importlib, pkgutil, labsupport, matplotlib.pyplot\n"
        f"compileall.compile_dir('{STUDENT}', quiet=1)\n"
    )
    writable = {STUDENT: layout.root / "student", f"{HOME}/.config/matplotlib": layout.root / "mpl"}
    cmd = command(layout, [layout.python, "-c", code], writable=writable, warm=False)
    proc = subprocess.run(
        cmd, capture_output=True, text=True, timeout=300, preexec_fn=lambda: apply_limits(layout.limits)
    )
    if proc.returncode != 0:
        words = (proc.stderr.strip().splitlines() or ["no message"])[-1]
        raise SandboxUnavailable(
            f"bubblewrap could not start a sandbox here ({words}). It needs unprivileged user namespaces. Where "
            "the kernel disables them, enable them (sysctl kernel.unprivileged_userns_clone=1, or on Ubuntu 24.04 "
            "kernel.apparmor_restrict_unprivileged_userns=0). Inside a Docker container, Docker's default seccomp "
            "and AppArmor profiles forbid them: grade on the host, or start the container with --security-opt "
            "seccomp=unconfined --security-opt apparmor=unconfined. Inside a chroot the kernel refuses them "
            "whatever its settings: grade outside it. For submissions you trust, --unsafe-no-sandbox grades "
            "without isolation."
        )


def command(layout: Layout, argv: list[str], writable: dict[str, Path] | None = None, warm: bool = True) -> list[str]:
    """The bubblewrap command line that runs ``argv`` in a fresh sandbox of ``layout``."""
    cmd = [
        layout.bwrap,
        "--unshare-all",
        "--unshare-user",
        "--uid",
        "1000",
        "--gid",
        "1000",
        "--hostname",
        "sandbox",
        "--die-with-parent",
        "--new-session",
        "--cap-drop",
        "ALL",
        *layout.mounts,
        "--proc",
        "/proc",
        "--dev",
        "/dev",
        "--size",
        str(layout.limits.scratch),
        "--tmpfs",
        "/dev/shm",
        "--size",
        str(layout.limits.scratch),
        "--tmpfs",
        "/tmp",
        "--size",
        str(layout.limits.scratch),
        "--tmpfs",
        HOME,
        # Colab's working folder: a notebook from Colab that changes into /content or writes
        # there runs on, its files landing in the scratch home.
        "--symlink",
        HOME,
        "/content",
    ]
    for inner, host in (writable or {}).items():
        cmd += ["--bind", str(host), inner]
    if warm:
        cmd += ["--dir", f"{HOME}/.config/matplotlib"]
        for p in sorted((layout.root / "mpl").glob("*.json")):
            cmd += ["--ro-bind", str(p), f"{HOME}/.config/matplotlib/{p.name}"]
    # The root and /dev are tmpfs mounts bubblewrap makes without a size limit: read-only, so
    # that the only memory a submission can fill with files is its capped scratch space.
    cmd += ["--remount-ro", "/dev", "--remount-ro", "/", "--chdir", HOME, "--clearenv"]
    for k, v in layout.env:
        if not (k == "PYTHONDONTWRITEBYTECODE" and not warm):  # the warm-up run writes the bytecode
            cmd += ["--setenv", k, v]
    return cmd + list(argv)


def server_command(layout: Layout) -> list[str]:
    """The command that starts the cell server in a fresh sandbox."""
    return command(layout, [layout.python, f"{RUNNER}/{SERVER}"])


def apply_limits(limits: Limits) -> None:
    """Resource limits for the sandbox's processes (run in the child before bubblewrap starts).

    The address-space limit holds per process, and the process limit only for a grader not run
    as root, so a submission's processes together may still ask for more memory than the machine
    has. They are then the first the kernel's out-of-memory killer stops (``oom_score_adj`` 1000,
    inherited by all of them), never the grader or the rest of the machine."""
    try:
        with open("/proc/self/oom_score_adj", "w") as f:
            f.write("1000")
    except OSError:
        pass  # no /proc: the limits below still hold
    for which, value in (
        (resource.RLIMIT_AS, limits.memory),
        (resource.RLIMIT_CPU, limits.cpu),
        (resource.RLIMIT_FSIZE, limits.file_size),
        (resource.RLIMIT_CORE, 0),
        (resource.RLIMIT_NPROC, limits.processes),
    ):
        try:
            resource.setrlimit(which, (value, value))
        except (ValueError, OSError):
            pass  # e.g. RLIMIT_NPROC below what this user already runs: the PID namespace still bounds them


def unsafe_command(root: Path) -> tuple[list[str], dict[str, str], Path]:
    """Without a sandbox (trusted use only): the server on this interpreter, with the student's
    labsupport first on the path, in a scratch folder of its own."""
    scratch = Path(tempfile.mkdtemp(prefix="row-", dir=root))
    (scratch / "tmp").mkdir()
    env = {k: v for k, v in os.environ.items() if k in ("PATH", "LANG", "LC_ALL", "SYSTEMROOT")}
    env.update(
        PYTHONPATH=str(root / "student"),
        PYTHONNOUSERSITE="1",
        PYTHONDONTWRITEBYTECODE="1",
        HOME=str(scratch),
        TMPDIR=str(scratch / "tmp"),
        MPLBACKEND="Agg",
        MUJOCO_GL="disable",
        OMP_NUM_THREADS="1",
        OPENBLAS_NUM_THREADS="1",
        LABSUPPORT_GRADING_BATCH="1",
    )
    return [sys.executable, "-s", str(root / "runner" / SERVER)], env, scratch


def prepare_unsafe(root: Path, checkout: Path = CHECKOUT) -> Path:
    """The student's labsupport and the server for :func:`unsafe_command`."""
    write_student_package(Path(root) / "student", checkout)
    (Path(root) / "runner").mkdir()
    shutil.copyfile(Path(__file__).with_name("sandbox.py"), Path(root) / "runner" / SERVER)
    return Path(root)
