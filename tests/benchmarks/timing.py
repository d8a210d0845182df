"""Timing shared by the control-loop benchmarks: alternate the loops, keep each one's best.

On a machine with several cores the scheduler may move a process from one core to another in
the middle of a measurement; a Python-heavy loop (a law written with NumPy and MuJoCo calls)
then runs up to twice as slowly for a while, and bare ``mj_step`` much less so, which biases
their ratio and makes it jump between runs (0.10 one run, 0.115 the next, for the UR5e). So
the process is first pinned to one core; the ratios then repeat to within a few percent.
"""

from __future__ import annotations

import os
import platform
import sys
import time
from collections.abc import Callable

import mujoco
import numpy as np


def versions() -> str:
    """What the ratios depend on besides the machine: the interpreter and the libraries the laws
    call (the same code measures lower on Python 3.12, Colab's, than on 3.11, for one)."""
    return f"{platform.machine()}, Python {sys.version.split()[0]}, MuJoCo {mujoco.__version__}, NumPy {np.__version__}"


def pin_to_one_core() -> int | None:
    """Keep this process on one of the cores it may use (where the OS allows it); return
    that core, or None where pinning is not available."""
    if not hasattr(os, "sched_setaffinity"):
        return None
    core = min(os.sched_getaffinity(0))
    os.sched_setaffinity(0, {core})
    return core


def seconds(fn: Callable[[], object]) -> float:
    """Wall-clock seconds of one call of ``fn``."""
    start = time.perf_counter()
    fn()
    return time.perf_counter() - start


def best_times(loops: dict[str, Callable[[], object]], repeats: int) -> dict[str, float]:
    """Each loop's best time over ``repeats`` rounds, the loops alternating within a round so
    that other load on the machine hits them alike; the process is pinned to one core first."""
    pin_to_one_core()
    times = dict.fromkeys(loops, float("inf"))
    for _ in range(repeats):
        for name, fn in loops.items():
            times[name] = min(times[name], seconds(fn))
    return times


def law_budget_us(target_ratio: float, bare_rate: float, loop_rate: float) -> float:
    r"""Microseconds per step a control law may add to a loop and still reach ``target_ratio``
    of bare ``mj_step``: :math:`1/(r\,f_{\text{bare}}) - 1/f_{\text{loop}}`, with the loop's own
    rate :math:`f_{\text{loop}}` measured with the law replaced by replayed torques."""
    return 1e6 * (1.0 / (target_ratio * bare_rate) - 1.0 / loop_rate)
