"""What a Problem TODO may use from labsupport, and how a use of the rest is caught.

The Problems ask for code only the student writes: the 3R arm's inverse kinematics and its
control laws, from MuJoCo's own :math:`M`, :math:`h`, :math:`J` and :math:`\\dot J\\dot q`.
labsupport also holds the Tasks' laws and the 2R arm's kinematics; a TODO answered by calling
into them (say, Task 3's generic joint computed torque applied to the 3R arm) scores zero for
that TODO, with :func:`forbidden_message` as the reason.

Two places enforce it:

* the in-notebook check calls the student's function under :func:`call_watched`, which notes
  every Python function the call runs, in its own thread and in threads it starts, and flags
  one defined in a :data:`FORBIDDEN` module, by module name, by source file
  (:func:`forbidden_module_of_file`: so a function imported under another name, loaded from
  its file as another module, or rebuilt from its code object, even one marshalled on another
  installation, is still caught), or by its compiled code (:func:`carried_forbidden_code`: the
  same law compiled under a made-up file name and carried in a pickle);
* the batch grader's sandbox replaces the :data:`FORBIDDEN` modules by stubs whose functions
  raise ``RuntimeError(forbidden_message(name))``, and calls the student's function under the
  same watch; the checks recognise that message (:func:`is_forbidden_message`) and give the
  same zero with the same reason.

The batch grader decides. The in-notebook watch runs in the student's own process, so a
student set on hiding a call can: turn the watch off and on again within the call, run the
borrowed law from a thread started before the call, or ``exec`` a law's source copied out
with ``inspect``. In the sandbox none of these finds a law to run, and the TODO still scores
zero with the same reason: the source ``inspect`` finds there is the stub's, which raises it
(``tests/hostile/copies_law_source.ipynb``).
"""

from __future__ import annotations

import hashlib
import json
import linecache
import os
import sys
import threading
from collections.abc import Callable, Iterator
from functools import cache
from pathlib import Path
from types import CodeType

#: Module prefixes a Problem TODO may not call into: the Tasks' control laws, the arms'
#: kinematics, and the checks' own internals (they evaluate the Problems' formulas).
FORBIDDEN: tuple[str, ...] = (
    "labsupport.controllers",
    "labsupport.kinematics",
    "labsupport.grading.common",
    "labsupport.grading.problem1",
    "labsupport.grading.problem2",
)

#: What a Problem TODO may use from labsupport, as each Problem's box "What you may use from
#: labsupport" lists it (everything of NumPy and MuJoCo is fine too; a test holds the two alike).
ALLOWED: tuple[str, ...] = (
    "labsupport.plants.load_model",
    "labsupport.dynamics.mass_matrix",
    "labsupport.dynamics.mass_times",
    "labsupport.dynamics.bias_forces",
    "labsupport.dynamics.solve_mass",
    "labsupport.dynamics.site_jacobian",
    "labsupport.dynamics.site_jdot_qdot",
    "labsupport.trajectories",
    "labsupport.sim.simulate",
    "labsupport.metrics",
    "labsupport.render.show_picture",
    "labsupport.render.show_run_video",
    "labsupport.grading.check",
    "labsupport.grading.as_controller",
    "labsupport.grading.attempt",
)

#: The words every forbidden-use message carries (the sandbox may shorten the rest).
MARKER = "is off limits in a Problem TODO"


#: Why a function that switched off :func:`call_watched`'s watch scores zero in the notebook.
WATCH_REMOVED = (
    f"switching off the check's watch (sys.setprofile) {MARKER}: the check must see which "
    "functions yours runs. Remove that call. This TODO scores zero."
)


class ForbiddenUse(Exception):
    """A student's function ran a function of a :data:`FORBIDDEN` module (the message is
    :func:`forbidden_message` of its qualified name), or switched off the watch that would see
    it (the message is :data:`WATCH_REMOVED`)."""

    def __init__(self, qualified_name: str, message: str | None = None):
        self.qualified_name = qualified_name
        super().__init__(forbidden_message(qualified_name) if message is None else message)


def forbidden_message(qualified_name: str) -> str:
    """The plain-words reason a TODO that called ``qualified_name`` scores zero (short enough to
    survive the sandbox's 200-character error messages)."""
    return (
        f"{qualified_name} {MARKER}: write it yourself with NumPy and MuJoCo (M, h, J and J̇q̇ "
        "from labsupport.dynamics). This TODO scores zero."
    )


def is_forbidden_message(text: str) -> bool:
    """Whether an error message says a forbidden part of labsupport was called."""
    return MARKER in str(text)


def is_forbidden_module(module: str) -> bool:
    """Whether the module ``module`` (a dotted name) is one a TODO may not call into."""
    return any(module == p or module.startswith(p + ".") for p in FORBIDDEN)


def _forbidden_use_of(frame) -> str | None:
    """The qualified name of the :data:`FORBIDDEN` function running in ``frame``, recognised by
    its globals' ``__name__``, by its code's source file, or by its compiled code itself
    (:func:`carried_forbidden_code`), else ``None``."""
    module = frame.f_globals.get("__name__", "")
    if not (module.startswith("labsupport.") and is_forbidden_module(module)):
        module = forbidden_module_of_file(frame.f_code.co_filename)
    if module is not None:
        return f"{module}.{_called_name(frame)}"
    return carried_forbidden_code(frame.f_code)


@cache
def forbidden_module_of_file(filename: str) -> str | None:
    """The :data:`FORBIDDEN` module whose source file ``filename`` is, else ``None``: the dotted
    name of its path from the last folder named ``labsupport`` on (links resolved), so a file of
    the package found wherever it is installed, on this machine or on another, is the same
    module. A code object keeps the file it was compiled from: a law's code carried from a
    student's own installation (``marshal.dumps(law.__code__)``) and rebuilt in the notebook
    still names its file there. Cached: the watch asks for every call."""
    if filename.startswith("<"):  # code typed in a cell or built from a string
        return None
    path = os.path.realpath(filename).replace("\\", "/")
    start = path.rfind("/labsupport/")
    stem, ext = os.path.splitext(path[start + 1 :])
    if start < 0 or ext != ".py":
        return None
    module = stem.replace("/", ".").removesuffix(".__init__")
    return module if is_forbidden_module(module) else None


#: The file, beside this module in the batch grader's sandbox, that holds the fingerprints of
#: the :data:`FORBIDDEN` modules' functions (the sandbox's copies of those modules are stubs, so
#: the grader computes them from the real ones: :func:`write_forbidden_code`).
FORBIDDEN_CODE_FILE = "forbidden_code.json"


def code_fingerprint(code: CodeType) -> str:
    """A digest of what ``code`` does: its bytecode, the names it reads and its constants (a
    nested function's code by its own fingerprint), but not its name, its file or its line
    numbers, which a copy can change at will. Bytecode is that of the running Python, as is a
    code object a notebook can load (``marshal`` refuses another version's)."""
    digest = hashlib.sha256(code.co_code)
    digest.update(repr(code.co_names).encode())
    for constant in code.co_consts:
        digest.update(b"\0" + _constant_key(constant).encode())
    return digest.hexdigest()[:32]


def _constant_key(constant) -> str:
    """A constant as :func:`code_fingerprint` reads it: the same in every process (a frozenset's
    order follows the process's string hashing, so its members are sorted)."""
    if isinstance(constant, CodeType):
        return "code " + code_fingerprint(constant)
    if isinstance(constant, frozenset):
        return "frozenset " + repr(sorted(_constant_key(c) for c in constant))
    if isinstance(constant, tuple):
        return "tuple " + repr([_constant_key(c) for c in constant])
    return repr(constant)


def _codes_within(code: CodeType) -> Iterator[CodeType]:
    """``code`` and every code object compiled within it (functions, methods, lambdas)."""
    yield code
    for constant in code.co_consts:
        if isinstance(constant, CodeType):
            yield from _codes_within(constant)


def fingerprints_of_module(source: str, module: str) -> dict[str, str]:
    """``{fingerprint: qualified name}`` of the functions that the module ``module``'s
    ``source`` defines and documents. A function without a docstring, a lambda or a
    comprehension may be the same few instructions as a student's own, so only documented
    functions are recognised: the docstring makes the match a copy."""
    found = {}
    for code in _codes_within(compile(source, module, "exec", dont_inherit=True)):
        documented = bool(code.co_consts) and isinstance(code.co_consts[0], str)
        if not code.co_name.startswith("<") and documented:
            qualname = getattr(code, "co_qualname", code.co_name)  # Python 3.10 has no co_qualname
            found[code_fingerprint(code)] = f"{module}.{qualname}"
    return found


def forbidden_code_of_package(package: Path) -> dict[str, str]:
    """The fingerprints of the :data:`FORBIDDEN` modules' functions, from the sources under
    ``package`` (the folder of ``labsupport``)."""
    found = {}
    for path in sorted(Path(package).rglob("*.py")):
        module = ".".join(("labsupport", *path.relative_to(package).with_suffix("").parts)).removesuffix(".__init__")
        if is_forbidden_module(module):
            found.update(fingerprints_of_module(path.read_text(encoding="utf-8"), module))
    return found


def write_forbidden_code(package: Path, dest: Path) -> None:
    """Write the fingerprints of the real ``package``'s forbidden functions to ``dest`` (a
    :data:`FORBIDDEN_CODE_FILE`), for a copy of the package whose forbidden modules are stubs."""
    Path(dest).write_text(json.dumps(forbidden_code_of_package(package), sort_keys=True), encoding="utf-8")


@cache
def forbidden_code() -> dict[str, str]:
    """The fingerprints of the :data:`FORBIDDEN` functions: the :data:`FORBIDDEN_CODE_FILE` beside
    this module where the grader wrote one, else computed from this installation's sources."""
    here = Path(__file__).resolve().parent
    shipped = here / FORBIDDEN_CODE_FILE
    if shipped.is_file():
        return json.loads(shipped.read_text(encoding="utf-8"))
    return forbidden_code_of_package(here.parent)


#: What :func:`carried_forbidden_code` found for each code object it was asked about, by ``id``
#: (the code object is kept, so its ``id`` is not reused).
_CARRIED: dict[int, tuple[CodeType, str | None]] = {}


def carried_forbidden_code(code: CodeType) -> str | None:
    """The qualified name of the :data:`FORBIDDEN` function that ``code`` is a compiled copy of,
    whatever name and file the copy claims, unless it was written in one of the notebook's cells
    (:func:`_written_in_a_cell`); else ``None``. This catches a law carried into the notebook
    compiled (pickled, marshalled, rebuilt from bytes) under a made-up file name, or written to a
    file from data and imported, which neither the module rule nor the file rule sees; a law
    whose text is pasted into a cell is the notebook's own code, graded as such. Cached per code
    object: the watch asks for every call."""
    seen = _CARRIED.get(id(code))
    if seen is None or seen[0] is not code:
        name = forbidden_code().get(code_fingerprint(code))
        if name is not None and _written_in_a_cell(code):
            name = None
        seen = _CARRIED[id(code)] = (code, name)
    return seen[1]


def _written_in_a_cell(code: CodeType) -> bool:
    """Whether ``code`` was compiled from the text of a notebook cell: IPython keeps each cell's
    text in ``linecache`` under the name its code carries, a name that is no file on disk (a
    file's text, written by the notebook from data it decoded, is not a cell's), and that text
    compiles to code with the same fingerprint."""
    entry = linecache.cache.get(code.co_filename)
    if not (isinstance(entry, tuple) and len(entry) == 4) or os.path.exists(code.co_filename):
        return False
    try:
        compiled = compile("".join(entry[2]), code.co_filename, "exec", dont_inherit=True)
    except (SyntaxError, ValueError, TypeError, RecursionError, MemoryError):
        return False
    fingerprint = code_fingerprint(code)
    return any(code_fingerprint(c) == fingerprint for c in _codes_within(compiled))


def _called_name(frame) -> str:
    """The name a student wrote for the function running in ``frame``: its qualified name, or
    for a class's ``__init__`` (a dataclass's is generated code, named
    ``__create_fn__.<locals>.__init__``) the class itself, or the module's class that a
    student's subclass derives from."""
    code = frame.f_code
    if code.co_name in ("__init__", "__post_init__") and "self" in frame.f_locals:
        module = frame.f_globals.get("__name__")
        for cls in type(frame.f_locals["self"]).__mro__:
            if cls.__module__ == module:
                return cls.__qualname__
    return getattr(code, "co_qualname", code.co_name)


def call_watched(fn: Callable, *args, **kwargs):
    """Call ``fn(*args, **kwargs)``, watching which Python functions it runs.

    The watch is a profile function (``sys.setprofile``) in the calling thread and in every
    thread started during the call (``threading.setprofile``).

    Returns:
        ``(value, used)``: what ``fn`` returned, and the qualified name of the first function
        of a :data:`FORBIDDEN` module it ran (directly or through any chain of calls), or
        ``None``. A profiler already installed (a debugger, a coverage tool) keeps running.

    Raises:
        ForbiddenUse: ``fn`` raised after running a forbidden function (the forbidden use is
            the reason that counts), or ``fn`` switched the watch off. Any other exception of
            ``fn`` passes through.
    """
    used: list[str] = []
    previous, previous_threads = sys.getprofile(), threading.getprofile()

    def watch(frame, event, arg):
        # a module's own top-level code (importing it inside the call) is not a use, nor is its
        # __getattr__ (PEP 562), which an import asks for names such as __path__: the call
        # into it that follows is, and is named by the function called
        if event == "call" and not used and _called_name(frame) not in ("<module>", "__getattr__"):
            name = _forbidden_use_of(frame)
            if name is not None:
                used.append(name)
        if previous is not None:
            previous(frame, event, arg)

    threading.setprofile(watch)
    sys.setprofile(watch)
    try:
        value = fn(*args, **kwargs)
    except Exception:
        if used:
            raise ForbiddenUse(used[0]) from None
        raise
    finally:
        removed = sys.getprofile() is not watch
        sys.setprofile(previous)
        threading.setprofile(previous_threads)
    if removed and not used:
        raise ForbiddenUse("sys.setprofile", WATCH_REMOVED)
    return value, (used[0] if used else None)
