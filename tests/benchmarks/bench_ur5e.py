"""Task 4 speed: UR5e controlled steps per second against bare ``mj_step``, and render rate.

Run ``python tests/benchmarks/bench_ur5e.py``. All rates are measured in the same run,
alternating the loops and keeping each one's best of several repeats, so that other load on
the machine biases them as little as possible.
"""

from __future__ import annotations

import time

import labsupport  # noqa: F401  (chooses the GL backend before mujoco is imported)
import mujoco
import numpy as np

from labsupport import render, ur5e
from labsupport.controllers.ur5e import LabController, OperationalSpaceController

REPEATS = 5


def bare_steps(model, data, n):
    """n plain mj_step calls from the home keyframe, control held constant."""
    mujoco.mj_resetDataKeyframe(model, data, 0)
    for _ in range(n):
        mujoco.mj_step(model, data)


def textbook_loop(model, data, task):
    """The lab's loop as written: lists grown per step, M^-1 formed, Lambda by pinv."""
    sid = model.site("attachment_site").id
    conj = np.empty(4)
    mujoco.mju_negQuat(conj, task.unit_quat())
    kp, kd = np.repeat([100.0, 50.0], 3), 2 * np.sqrt(np.repeat([100.0, 50.0], 3))
    J, Minv, quat, dq, e = np.zeros((6, 6)), np.zeros((6, 6)), np.zeros(4), np.zeros(4), np.zeros(6)
    log = []
    mujoco.mj_resetDataKeyframe(model, data, 0)
    while data.time < task.duration:
        e[:3] = data.site(sid).xpos - task.reference(data.time).pos
        mujoco.mju_mat2Quat(quat, data.site(sid).xmat)
        mujoco.mju_mulQuat(dq, quat, conj)
        mujoco.mju_quat2Vel(e[3:], dq, 1.0)
        mujoco.mj_jacSite(model, data, J[:3], J[3:], sid)
        mujoco.mj_solveM(model, data, Minv, np.eye(6))
        lam = np.linalg.pinv(J @ Minv @ J.T)
        tau = J.T @ lam @ (-kp * e - kd * (J @ data.qvel)) + data.qfrc_bias
        ctrl = data.qpos + 0.2 * data.qvel + tau / model.actuator_gainprm[:, 0]
        data.ctrl = np.clip(ctrl, *model.actuator_ctrlrange.T)
        mujoco.mj_step(model, data)
        log.append((e.copy(), tau.copy()))
    return len(log)


def _best(fn, repeats=REPEATS):
    best = np.inf
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - t0)
    return best


def main() -> dict:
    model, data = ur5e.load_ur5e()
    task = ur5e.CircleTask()
    n = int(round(task.duration / model.opt.timestep))
    osc, lab = OperationalSpaceController(), LabController()

    times = {name: np.inf for name in ("bare", "osc", "lab", "textbook")}
    for _ in range(REPEATS):   # alternate, so that load hits all loops alike
        times["bare"] = min(times["bare"], _best(lambda: bare_steps(model, data, n), 1))
        times["osc"] = min(times["osc"], _best(lambda: ur5e.run(model, data, osc, task), 1))
        times["lab"] = min(times["lab"], _best(lambda: ur5e.run(model, data, lab, task), 1))
    times["textbook"] = _best(lambda: textbook_loop(model, data, task), 2)
    rates = {name: n / t for name, t in times.items()}
    ratios = {name: rates[name] / rates["bare"] for name in ("osc", "lab", "textbook")}

    print(f"UR5e, {n} steps of {model.opt.timestep * 1e3:.0f} ms ({task.duration:.0f} s simulated)")
    print(f"  bare mj_step                      {rates['bare']:9.0f} steps/s")
    for name, label in (("osc", "operational-space controller"), ("lab", "lab's law, in place"),
                        ("textbook", "lab's loop as written")):
        print(f"  {label:33s} {rates[name]:9.0f} steps/s   ratio to bare {ratios[name]:.3f}")

    run = ur5e.run(model, data, osc, task)
    result = {"bare_steps_per_s": rates["bare"], "controlled_steps_per_s": rates["osc"],
              "ratio": ratios["osc"], "ratio_lab_inplace": ratios["lab"],
              "ratio_lab_as_written": ratios["textbook"]}
    try:
        fps = 12
        frames_time = _best(lambda: render.render_run(model, run, fps=fps, progress=False), 2)
        frames = int(task.duration * fps)
        result["render_frames_per_s"] = frames / frames_time
        print(f"  render 320x240 with traces        {frames / frames_time:9.1f} frames/s "
              f"({frames} frames in {frames_time:.1f} s)")
    except render.RenderingUnavailable as err:
        print(f"  render: unavailable ({err})")
    return result


if __name__ == "__main__":
    main()
