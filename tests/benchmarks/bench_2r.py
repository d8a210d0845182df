"""Benchmark: the 2R tracking loop against bare ``mj_step`` on the same model.

Prints the controlled-step rate of :func:`labsupport.sim.simulate` running Task 3.2's laws,
written as the notebook writes them (a small ``controller(model, data)`` closure that reads the
sampled reference and calls the law), logging included, divided by the rate of bare
``mj_step`` on the same model, both measured in this one run (best of a few repeats, to damp
the noise of a shared machine). The aim is a ratio of at least 0.35.

Run: ``python tests/benchmarks/bench_2r.py``
"""

from __future__ import annotations

import time
from functools import partial

import mujoco
import numpy as np

import labsupport  # noqa: F401  (before mujoco)
from labsupport import gains, sim, trajectories
from labsupport.controllers.joint_space import ct_joint_torque
from labsupport.controllers.operational_space import os_ct_torque
from labsupport.kinematics import planar_2r as k2
from labsupport.plants import load_model
from labsupport.trajectories import circle_2d

TARGET_RATIO = 0.35
DURATION = 12.0  # s of simulated time per run (6,000 steps of 2 ms)
REPEATS = 5
circle = partial(circle_2d, center=(0.5, 0.2), radius=0.15, period=6.0)


def os_ct_controller(model, Kp, Kd):
    ref = trajectories.sample(circle, model.opt.timestep, DURATION)
    ee = model.site("end_effector").id

    def controller(model, data):
        x_d, xdot_d, xddot_d = ref.at(data.time)
        return os_ct_torque(model, data, ee, x_d, xdot_d, xddot_d, Kp, Kd)

    return controller


def ik_ct_controller(model, Kp, Kd):
    ref = trajectories.sample(lambda t: k2.joint_reference(circle(t)), model.opt.timestep, DURATION)

    def controller(model, data):
        q_d, qdot_d, qddot_d = ref.at(data.time)
        return ct_joint_torque(model, data, q_d, qdot_d, qddot_d, Kp, Kd)

    return controller


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


def controlled_step_rate(model, data, make) -> tuple[float, dict]:
    """Steps per second of the whole tracking run (reference sampling, controller, logging,
    site recomputation and reference evaluation included), best of ``REPEATS``; and the
    per-step cost of the parts, timed alone at one state."""
    Kp, Kd = gains.ct_gains(8.0, 1.0)
    q0 = k2.inverse_kinematics(circle(0.0).pos)
    best, nsteps = np.inf, 0
    for _ in range(REPEATS):
        t0 = time.perf_counter()
        controller = make(model, Kp, Kd)
        log = sim.simulate(
            model, data, controller, DURATION, q0=q0, site="end_effector", reference=circle, log_after_step=True
        )
        best = min(best, time.perf_counter() - t0)
        nsteps = len(log.t)
    mujoco.mj_forward(model, data)
    n = 20000
    t0 = time.perf_counter()
    for _ in range(n):
        controller(model, data)
    per_call = (time.perf_counter() - t0) / n
    return nsteps / best, {"controller call [us]": 1e6 * per_call}


def main() -> dict:
    model, data = load_model("planar_2r")
    nsteps = int(round(DURATION / model.opt.timestep))
    bare = bare_step_rate(model, data, nsteps)
    results = {"bare mj_step [steps/s]": bare}
    print(f"2R planar arm, {nsteps} steps of {model.opt.timestep * 1e3:.0f} ms (RK4), best of {REPEATS}")
    print(f"  bare mj_step            : {bare:10.0f} steps/s  ({1e6 / bare:5.1f} us/step)")
    for name, make in (("OS-CT", os_ct_controller), ("IK + JS-CT", ik_ct_controller)):
        rate, parts = controlled_step_rate(model, data, make)
        ratio = rate / bare
        results[f"{name} ratio"] = ratio
        verdict = "ok" if ratio >= TARGET_RATIO else f"BELOW the target {TARGET_RATIO}"
        print(
            f"  {name:<10} tracking loop: {rate:10.0f} steps/s  ({1e6 / rate:5.1f} us/step)  "
            f"ratio to bare mj_step = {ratio:.2f}  ({verdict}); controller alone "
            f"{parts['controller call [us]']:.1f} us/call"
        )
    return results


if __name__ == "__main__":
    main()
