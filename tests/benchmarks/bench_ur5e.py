"""Task 4 speed: the UR5e laws in the one loop against bare ``mj_step``, and the render rate.

Run ``python tests/benchmarks/bench_ur5e.py``. All rates are measured in the same run, on
one core, alternating the loops and keeping each one's best of several repeats, so that other
load on the machine biases them as little as possible (``timing.py``). The controllers are the
Task 4 page's: a closure that reads the sampled circle at ``data.time`` and calls the law, run
by :func:`labsupport.sim.simulate` with the servos as its actuation. The aim is a ratio of at
least 0.2 for the tracking law.
"""

from __future__ import annotations

import labsupport  # noqa: F401  (chooses the GL backend before mujoco is imported)

# isort: split
import mujoco
import numpy as np
from timing import best_times, law_budget_us, seconds, versions

from labsupport import render, trajectories, ur5e
from labsupport.actuators import Servo, implicit_damping, servo_actuation
from labsupport.controllers.ur5e import LAB_GAINS, PoseArrays, lab_torque, tracking_torque
from labsupport.sim import simulate

REPEATS = 5
TARGET_RATIO = 0.2  # the tracking law against bare mj_step
DURATION = 8.0
QUAT_D = np.array(ur5e.HOME_QUAT)


def bare_steps(model, data, n):
    """n plain mj_step calls from the home keyframe, control held constant."""
    mujoco.mj_resetDataKeyframe(model, data, model.key(ur5e.HOME).id)
    for _ in range(n):
        mujoco.mj_step(model, data)


def controllers(model, reference):
    """The page's two controllers, ``controller(model, data) -> tau``."""
    site, arrays = model.site(ur5e.SITE).id, PoseArrays.for_model(model)
    inertia = implicit_damping(Servo.from_model(model), model.opt.timestep)

    def lab(model, data):
        return lab_torque(model, data, site, reference.at(data.time).pos, QUAT_D, LAB_GAINS, arrays)

    def tracking(model, data):
        ref = reference.at(data.time)
        return tracking_torque(model, data, site, ref.pos, ref.vel, ref.acc, QUAT_D, LAB_GAINS, inertia, arrays)

    return lab, tracking


def main() -> dict:
    model, data = ur5e.load_ur5e()
    dt = model.opt.timestep
    n = int(round(DURATION / dt))
    reference = trajectories.sample(
        lambda t: trajectories.circle_3d(t, (-0.1, 0.5, 0.6), 0.1, (1, 1, 1), 0.25), dt, DURATION
    )
    lab, tracking = controllers(model, reference)
    actuation = servo_actuation(model)

    def run(controller, **stepping):
        return simulate(
            model, data, controller, DURATION, keyframe=ur5e.HOME, site=ur5e.SITE, actuation=actuation, **stepping
        )

    # The loop and the servos alone, on the same motion: replay the torques the tracking law
    # asked for (under a zero torque the arm falls under gravity, a different motion that
    # MuJoCo steps more slowly).
    asked = run(tracking, split_step=True).tau

    def replay(model, data):
        return asked[int(data.time / dt + 0.5)]

    loops = {
        "bare": lambda: bare_steps(model, data, n),
        "tracking": lambda: run(tracking, split_step=True),
        "lab": lambda: run(lab, lab_timing=True),
        "loop": lambda: run(replay, split_step=True),
    }
    times = best_times(loops, REPEATS)
    rates = {name: n / t for name, t in times.items()}
    ratios = {name: rates[name] / rates["bare"] for name in loops}

    print(f"UR5e, {n} steps of {dt * 1e3:.0f} ms ({DURATION:.0f} s simulated); {versions()}")
    print(f"  bare mj_step                          {rates['bare']:9.0f} steps/s  {1e6 / rates['bare']:6.1f} us/step")
    for name, label in (
        ("tracking", "tracking law (split step)"),
        ("lab", "lab's law (lab timing)"),
        ("loop", "loop and servos, replayed torque"),
    ):
        print(
            f"  {label:37s} {rates[name]:9.0f} steps/s  {1e6 / rates[name]:6.1f} us/step   "
            f"ratio to bare {ratios[name]:.3f}"
        )
    verdict = "meets" if ratios["tracking"] >= TARGET_RATIO else "BELOW"
    law_us = 1e6 / rates["tracking"] - 1e6 / rates["loop"]
    print(
        f"  tracking law: {verdict} the target {TARGET_RATIO}; it adds {law_us:.1f} us per step to the loop, "
        f"a law reaching the target may add at most {law_budget_us(TARGET_RATIO, rates['bare'], rates['loop']):.1f} us"
    )

    result = {
        "bare_steps_per_s": rates["bare"],
        "controlled_steps_per_s": rates["tracking"],
        "ratio": ratios["tracking"],
        "ratio_lab": ratios["lab"],
        "ratio_loop_only": ratios["loop"],
    }
    log = simulate(
        model,
        data,
        tracking,
        DURATION,
        keyframe=ur5e.HOME,
        site=ur5e.SITE,
        reference=reference,
        actuation=actuation,
        split_step=True,
    )
    try:
        fps = 12
        frames_time = min(seconds(lambda: render.render_run(model, log, fps=fps, progress=False)) for _ in range(2))
        frames = int(DURATION * fps)
        result["render_frames_per_s"] = frames / frames_time
        result["renderer"] = gl_renderer(model)
        print(
            f"  render 320x240 with traces            {frames / frames_time:9.1f} frames/s "
            f"({frames} frames in {frames_time:.1f} s) on {result['renderer']}"
        )
    except render.RenderingUnavailable as err:
        print(f"  render: unavailable ({err})")
    return result


def gl_renderer(model) -> str:
    """The OpenGL renderer that MuJoCo's offscreen context runs on: a GPU's name, or Mesa's
    llvmpipe in software. The frame rate means little without it."""
    from OpenGL import GL  # here, not on top: after labsupport has chosen PyOpenGL's platform

    renderer = render.make_renderer(model, 16, 16)
    try:
        return GL.glGetString(GL.GL_RENDERER).decode()
    finally:
        renderer.close()


if __name__ == "__main__":
    main()
