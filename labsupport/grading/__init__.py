"""Checks behind the Problems' in-notebook feedback (the batch grader is instructor tooling: :mod:`labsupport.instructor`).

In a notebook::

    from labsupport.grading import check
    check("p1_ik", globals())      # prints plain-words feedback on ik_3r

``check`` runs the same check functions the batch grader runs; the grader runs them outside
the submission's process (:mod:`labsupport.instructor.judge`), so nothing a notebook does to its
own copy of labsupport or of the grader changes its grade.

Modules:

==================  ===================================================================
``feedback``        results, probes (how a check reaches student code), plain-words errors
``common``          test states, mistake diagnosis, a simulation driven by student code
``problem1``        Problem 1 checks (IK, PD, CT, reach)
``problem2``        Problem 2 checks (start, OS-CT, IK + JS-CT, tracking)
==================  ===================================================================
"""

from __future__ import annotations

import os
from typing import Callable

from labsupport.grading.feedback import (NotImplementedYet, Result, StudentError, as_vector)

#: Set in the batch grader's sandbox: in-notebook checks then stay quiet (the grader runs its own).
BATCH_ENV = "LABSUPPORT_GRADING_BATCH"


def registry() -> dict[str, Callable]:
    """Every check, by name."""
    from labsupport.grading import problem1, problem2

    return {**problem1.CHECKS, **problem2.CHECKS}


def check(name: str, namespace: dict) -> Result | None:
    """Run check ``name`` on the functions and variables of ``namespace`` (pass ``globals()``) and print feedback.

    Never raises because of the student's code: a missing or broken function is reported in words.
    """
    checks = registry()
    if name not in checks:
        raise ValueError(f"no check named {name!r}; the checks are {sorted(checks)}")
    if os.environ.get(BATCH_ENV):
        print(f"[{name}] checked separately by the batch grader")
        return None
    from labsupport.grading.feedback import DirectProbe

    result = checks[name](DirectProbe(namespace))
    print(result)
    return result


def as_controller(fn: Callable, *args) -> Callable:
    """Wrap a student's ``fn(model, data, *args)`` into a controller ``(model, data) -> tau`` for
    :func:`labsupport.sim.simulate` that says plainly when ``fn`` is not implemented or returns a bad torque.

    ``args`` may also be a single function of the time returning the tuple of arguments.
    """
    name = getattr(fn, "__name__", "the controller")
    moving = len(args) == 1 and callable(args[0])

    def controller(model, data):
        extra = args[0](float(data.time)) if moving else args
        return as_vector(name, fn(model, data, *extra), model.nu, "torque")

    return controller


def attempt(label: str, run: Callable):
    """Run ``run()`` (e.g. a simulation) and return its result, or print why it cannot run yet and return None."""
    try:
        return run()
    except NotImplementedYet as err:
        print(f"{label}: skipped, {err}. Fill in the TODO above and run again.")
    except StudentError as err:
        print(f"{label}: skipped, {err}.")
    except Exception as err:  # the student's code may raise anything
        print(f"{label}: skipped, it raised {type(err).__name__}: {err}")
    return None
