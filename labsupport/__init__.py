"""labsupport: the small package behind the lab "Control of Robotic Manipulators".

Modules, one idea each:

========================  ===============================================================
``plants``                the analytic single-joint model and the MuJoCo model loaders
``dynamics``              mass matrix, bias forces, Jacobians from MuJoCo (3.x and 4.x)
``kinematics``            forward/inverse kinematics of the 2R arm (the 3R arm's is a Problem)
``trajectories``          set point, versine, sinusoid and circles: position, velocity, acceleration
``gains``                 PD gain design (actuator limit, %OS/settling time, wn/zeta)
``controllers``           the control laws, one function each: PI, PD, feedforward, computed torque, OS-CT
``sim``                   one MuJoCo simulation loop that returns a :class:`~labsupport.sim.Log`
``metrics``               functions of a Log: RMS errors, effort, overshoot, settling time, saturation
``render``                offscreen MuJoCo pictures and video (EGL, OSMesa fallback) with mediapy
``ur5e``                  the Menagerie UR5e with the lab's scene, loaded from any directory
``actuators``             position servos as an actuator mapping: the one servo inversion
``grading``               in-notebook checks of the Problems (batch grading: labsupport.instructor)
``plots``                 the figure layouts the notebooks share
``book``                  glue and show_law: prose numbers and law code come from the package
``gl``                    MuJoCo's OpenGL backend, chosen on import (EGL, GLFW, OSMesa)
``validate``              the one input validator (shapes, finite values, signs)
========================  ===============================================================

Importing the package chooses an OpenGL backend for MuJoCo (``MUJOCO_GL``) before MuJoCo
itself is imported, so import ``labsupport`` first in a notebook. It then refuses, with what to
do, a MuJoCo older than the package admits (:data:`labsupport.dynamics.OLDEST_MUJOCO`).
"""

from labsupport import gl as _gl

_gl.select_backend()

from labsupport import dynamics as _dynamics  # noqa: E402, F401  (after the backend: refuses a too old MuJoCo)

__version__ = "1.0.0"
