"""Benchmark: the 2R tracking loop against bare ``mj_step`` on the same model.

Prints the controlled-step rate of :func:`labsupport.sim.simulate` running Task 3.2's laws,
written as the notebook writes them (a small ``controller(model, data)`` closure that reads the
sampled reference and calls the law), logging included, divided by the rate of bare
``mj_step`` on the same model, all measured in this one run on one core, alternating the loops
and keeping each one's best of a few repeats, so that other load on the machine biases them
alike (``timing.py``). The aim is a ratio of at least 0.35.

Run: ``python tests/benchmarks/bench_2r.py``
"""

from __future__ import annotations

import time
from functools import partial

import mujoco
from timing import best_times, law_budget_us, versions

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


def bare_steps(model, data, nsteps: int) -> None:
    """``nsteps`` plain ``mj_step`` calls, zero control, from a bent posture."""
    mujoco.mj_resetData(model, data)
    data.qpos[:] = [0.2, 0.3]
    step = mujoco.mj_step
    for _ in range(nsteps):
        step(model, data)


def tracking_run(model, data, make) -> sim.Log:
    """One whole tracking run: reference sampling, controller, logging, site recomputation
    and reference evaluation."""
    Kp, Kd = gains.ct_gains(8.0, 1.0)
    q0 = k2.inverse_kinematics(circle(0.0).pos)
    controller = make(model, Kp, Kd)
    return sim.simulate(
        model, data, controller, DURATION, q0=q0, site="end_effector", reference=circle, log_after_step=True
    )


def replay_controller(model, asked: sim.Log):
    """A controller that returns the torques a run asked for, step by step: the loop's own cost
    on the same motion, with (almost) no law."""
    dt, tau = model.opt.timestep, asked.tau

    def controller(model, data):
        return tau[int(data.time / dt + 0.5)]

    return lambda model, Kp, Kd: controller


def controller_call(model, data, make, n: int = 20000) -> float:
    """Seconds per call of the controller alone, at one state."""
    controller = make(model, *gains.ct_gains(8.0, 1.0))
    mujoco.mj_forward(model, data)
    t0 = time.perf_counter()
    for _ in range(n):
        controller(model, data)
    return (time.perf_counter() - t0) / n


def main() -> dict:
    model, data = load_model("planar_2r")
    nsteps = int(round(DURATION / model.opt.timestep))
    makers = {"OS-CT": os_ct_controller, "IK + JS-CT": ik_ct_controller}
    loops = {"bare": lambda: bare_steps(model, data, nsteps)}
    loops.update({name: (lambda make=make: tracking_run(model, data, make)) for name, make in makers.items()})
    replay = replay_controller(model, tracking_run(model, data, os_ct_controller))
    loops["loop alone"] = lambda: tracking_run(model, data, replay)
    times = best_times(loops, REPEATS)
    bare = nsteps / times["bare"]
    results = {"bare mj_step [steps/s]": bare}
    print(f"2R planar arm, {nsteps} steps of {model.opt.timestep * 1e3:.0f} ms (RK4), best of {REPEATS}; {versions()}")
    print(f"  bare mj_step            : {bare:10.0f} steps/s  ({1e6 / bare:5.1f} us/step)")
    for name, make in makers.items():
        rate = nsteps / times[name]
        ratio = rate / bare
        results[f"{name} ratio"] = ratio
        verdict = "ok" if ratio >= TARGET_RATIO else f"BELOW the target {TARGET_RATIO}"
        print(
            f"  {name:<10} tracking loop: {rate:10.0f} steps/s  ({1e6 / rate:5.1f} us/step)  "
            f"ratio to bare mj_step = {ratio:.2f}  ({verdict}); controller alone "
            f"{1e6 * controller_call(model, data, make):.1f} us/call"
        )
    rate = nsteps / times["loop alone"]
    results["loop alone ratio"] = rate / bare
    print(
        f"  loop alone (OS-CT's torques replayed): {rate:10.0f} steps/s  ({1e6 / rate:5.1f} us/step)  "
        f"ratio to bare mj_step = {rate / bare:.2f}: the ceiling for any law in this loop"
    )
    print(
        f"  a law reaching {TARGET_RATIO} may add at most {law_budget_us(TARGET_RATIO, bare, rate):.1f} us "
        "per step to this loop (the controllers' cost in it: their us/step above less the loop's)"
    )
    return results


if __name__ == "__main__":
    main()
