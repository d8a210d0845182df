"""Benchmark: the 2R tracking loop against bare ``mj_step`` on the same model.

Prints the controlled-step rate of :func:`labsupport.sim.simulate` running Task 3.2's
operational-space computed torque (and IK + joint-space CT), logging included, divided by
the rate of bare ``mj_step`` on the same model, both measured in this one run (best of a
few repeats, to damp the noise of a shared machine). The aim is a ratio of at least 0.25.

Run: ``python tests/benchmarks/bench_2r.py``
"""

from __future__ import annotations

import time
from functools import partial

import labsupport  # noqa: F401  (before mujoco)
import mujoco
import numpy as np

from labsupport import gains, sim
from labsupport.controllers.operational_space import make_ik_ct_2r, make_os_ct_2r
from labsupport.kinematics import planar_2r as k2
from labsupport.plants import load_model
from labsupport.trajectories import circle_2d

TARGET_RATIO = 0.25
DURATION = 12.0      # s of simulated time per run (6,000 steps of 2 ms)
REPEATS = 5


def bare_step_rate(model, data, nsteps: int) -> float:
    """Steps per second of ``mj_step`` alone, zero control (best of ``REPEATS``)."""
    best = np.inf
    for _ in range(REPEATS):
        mujoco.mj_resetData(model, data)
        data.qpos[:] = [0.2, 0.3]
        step = mujoco.mj_step
        t0 = time.perf_counter()
        for _ in range(nsteps):
            step(model, data)
        best = min(best, time.perf_counter() - t0)
    return nsteps / best


def controlled_step_rate(model, data, make) -> float:
    """Steps per second of the whole tracking run (controller, clipping off, logging, site
    recomputation and reference evaluation included), best of ``REPEATS``."""
    circle = partial(circle_2d, center=(0.5, 0.2), radius=0.15, period=6.0)
    Kp, Kd = gains.ct_gains(8.0, 1.0)
    q0 = k2.inverse_kinematics(circle(0.0).pos)
    best, nsteps = np.inf, 0
    for _ in range(REPEATS):
        controller = make(model, circle, Kp, Kd)
        t0 = time.perf_counter()
        log = sim.simulate(model, data, controller, DURATION, q0=q0, site="end_effector", reference=circle,
                           log_after_step=True)
        best = min(best, time.perf_counter() - t0)
        nsteps = len(log.t)
    return nsteps / best


def main() -> dict:
    model, data = load_model("planar_2r")
    nsteps = int(round(DURATION / model.opt.timestep))
    bare = bare_step_rate(model, data, nsteps)
    results = {"bare mj_step [steps/s]": bare}
    print(f"2R planar arm, {nsteps} steps of {model.opt.timestep * 1e3:.0f} ms (RK4), best of {REPEATS}")
    print(f"  bare mj_step            : {bare:10.0f} steps/s  ({1e6 / bare:5.1f} us/step)")
    for name, make in (("OS-CT", make_os_ct_2r), ("IK + JS-CT", make_ik_ct_2r)):
        rate = controlled_step_rate(model, data, make)
        ratio = rate / bare
        results[f"{name} ratio"] = ratio
        verdict = "ok" if ratio >= TARGET_RATIO else f"BELOW the target {TARGET_RATIO}"
        print(f"  {name:<10} tracking loop: {rate:10.0f} steps/s  ({1e6 / rate:5.1f} us/step)  "
              f"ratio to bare mj_step = {ratio:.2f}  ({verdict})")
    return results


if __name__ == "__main__":
    main()
