"""What a Problem TODO may use from labsupport, and how a use of the rest is caught.

The Problems ask for code only the student writes: the 3R arm's inverse kinematics and its
control laws, from MuJoCo's own :math:`M`, :math:`h`, :math:`J` and :math:`\\dot J\\dot q`.
labsupport also holds the Tasks' laws and the 2R arm's kinematics; a TODO answered by calling
into them (say, Task 3's generic joint computed torque applied to the 3R arm) scores zero for
that TODO, with :func:`forbidden_message` as the reason.

Two places enforce it:

* the in-notebook check calls the student's function under :func:`call_watched`, which notes
  every Python function the call runs and flags one defined in a :data:`FORBIDDEN` module
  (however it was imported or renamed);
* the batch grader's sandbox replaces the :data:`FORBIDDEN` modules by stubs whose functions
  raise ``RuntimeError(forbidden_message(name))``; the checks recognise that message
  (:func:`is_forbidden_message`) and give the same zero with the same reason.
"""

from __future__ import annotations

import sys
from collections.abc import Callable

#: Module prefixes a Problem TODO may not call into: the Tasks' control laws, the arms'
#: kinematics, and the checks' own internals (they evaluate the Problems' formulas).
FORBIDDEN: tuple[str, ...] = (
    "labsupport.controllers",
    "labsupport.kinematics",
    "labsupport.grading.common",
    "labsupport.grading.problem1",
    "labsupport.grading.problem2",
)

#: What a Problem may use from labsupport (everything else of NumPy and MuJoCo is fine too).
ALLOWED: tuple[str, ...] = (
    "labsupport.plants.load_model",
    "labsupport.dynamics.mass_matrix",
    "labsupport.dynamics.bias_forces",
    "labsupport.dynamics.solve_mass",
    "labsupport.dynamics.site_jacobian",
    "labsupport.dynamics.site_jdot_qdot",
    "labsupport.trajectories",
    "labsupport.sim.simulate",
    "labsupport.metrics",
    "labsupport.plots",
    "labsupport.book.glue",
    "labsupport.grading.check",
    "labsupport.grading.as_controller",
    "labsupport.grading.attempt",
)

#: The words every forbidden-use message carries (the sandbox may shorten the rest).
MARKER = "is off limits in a Problem TODO"


class ForbiddenUse(Exception):
    """A student's function ran a function of a :data:`FORBIDDEN` module; the message is
    :func:`forbidden_message` of its qualified name."""

    def __init__(self, qualified_name: str):
        self.qualified_name = qualified_name
        super().__init__(forbidden_message(qualified_name))


def forbidden_message(qualified_name: str) -> str:
    """The plain-words reason a TODO that called ``qualified_name`` scores zero (short enough to
    survive the sandbox's 200-character error messages)."""
    return (
        f"{qualified_name} {MARKER}: write it yourself from MuJoCo's M, h, J and J̇q̇ "
        "(labsupport.dynamics). This TODO scores zero."
    )


def is_forbidden_message(text: str) -> bool:
    """Whether an error message says a forbidden part of labsupport was called."""
    return MARKER in str(text)


def is_forbidden_module(module: str) -> bool:
    """Whether the module ``module`` (a dotted name) is one a TODO may not call into."""
    return any(module == p or module.startswith(p + ".") for p in FORBIDDEN)


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

    Returns:
        ``(value, used)``: what ``fn`` returned, and the qualified name of the first function
        of a :data:`FORBIDDEN` module it ran (directly or through any chain of calls), or
        ``None``. A profiler already installed (a debugger, a coverage tool) keeps running.

    Raises:
        ForbiddenUse: ``fn`` raised after running a forbidden function (the forbidden use is
            the reason that counts). Any other exception of ``fn`` passes through.
    """
    used: list[str] = []
    previous = sys.getprofile()

    def watch(frame, event, arg):
        if event == "call" and not used:
            module = frame.f_globals.get("__name__", "")
            if module.startswith("labsupport.") and is_forbidden_module(module):
                used.append(f"{module}.{_called_name(frame)}")
        if previous is not None:
            previous(frame, event, arg)

    sys.setprofile(watch)
    try:
        value = fn(*args, **kwargs)
    except Exception:
        if used:
            raise ForbiddenUse(used[0]) from None
        raise
    finally:
        sys.setprofile(previous)
    return value, (used[0] if used else None)
