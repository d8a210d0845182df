r"""Rigid-body quantities from MuJoCo, the same calls on MuJoCo 3.x and 4.x.

The equation of motion MuJoCo integrates is

.. math:: M(q)\,\ddot q + h(q,\dot q) = \tau, \qquad h = C(q,\dot q)\,\dot q + g(q)

(``qfrc_bias`` is :math:`h`). Every function here reads what MuJoCo last computed in
``data`` (``mj_forward`` or ``mj_step``); none of them calls ``mj_forward`` itself, so a
controller sees exactly the state the loop hands it.

MuJoCo 4 changed two things the lab's text relies on: ``mj_fullM`` takes ``data`` instead of
the sparse array ``data.qM``, and ``MjData.qM`` is gone. :func:`mass_matrix` is the only call
that depends on it, and :func:`full_m_advice` tells a student whose own call meets the other
MuJoCo what changed; keep the differences in this module.
"""

from __future__ import annotations

import re

import mujoco
import numpy as np

from labsupport import validate

#: The oldest MuJoCo the package admits (``pyproject.toml`` says the same; a test checks): on
#: 3.3.0 and older ``mj_jacDot`` gives a :math:`\dot J\dot q` that disagrees with finite
#: differences, before 3.3.6 the UR5e scene does not compile, and before 3.5.0 the implicit
#: integrators still damp a servo whose force sits at its limit (a force that no longer depends
#: on the velocity), so a run that saturates the UR5e's servos (Task 4's unreachable target)
#: moves differently. The unit tests run on it (``bash .ci/test-oldest``).
OLDEST_MUJOCO = (3, 5, 0)


def _version(text: str) -> tuple[int, ...]:
    """``"3.5.0"`` → ``(3, 5, 0)``; a suffix such as ``.dev0`` or ``rc1`` is ignored."""
    return tuple(int(re.match(r"\d*", part).group() or 0) for part in text.split(".")[:3])


if _version(mujoco.__version__) < OLDEST_MUJOCO:
    _oldest = ".".join(map(str, OLDEST_MUJOCO))
    raise ImportError(
        f"labsupport needs MuJoCo {_oldest} or newer, but this Python has MuJoCo {mujoco.__version__}, "
        "which gives different numbers here (J̇q̇, servos at their force limits) or cannot load the UR5e. Run "
        f"`pip install --upgrade 'mujoco>={_oldest},<5'`, then restart the runtime (Colab: Runtime → Restart session)."
    )

#: True on MuJoCo >= 4, where ``mj_fullM(model, data, dst)`` replaced ``mj_fullM(model, dst, qM)``.
FULLM_TAKES_DATA = not hasattr(mujoco.MjData, "qM")


def full_m_advice(error: str) -> str:
    """What to do about an error from ``mj_fullM`` called as the other MuJoCo wants it (the lab's
    text calls it the MuJoCo 3 way, ``mj_fullM(model, M, data.qM)``), else ``""``; appended to the
    message a student reads when a law of theirs raises."""
    if "attribute 'qM'" in error or ("mj_fullM" in error and "incompatible function arguments" in error):
        return (
            ". mj_fullM changed with MuJoCo 4: it was mj_fullM(model, M, data.qM), it is mj_fullM(model, data, M), "
            "and data.qM is gone (this Python has MuJoCo " + mujoco.__version__ + "); mass_matrix(model, data) from "
            "labsupport.dynamics makes the right call on either"
        )
    return ""


def _made_for(model: mujoco.MjModel, data: mujoco.MjData) -> None:
    """``ValueError`` unless ``data`` was made for ``model``: MuJoCo would read the data of
    another model past its arrays without a word. Cheap when it was (``MjData.model`` is the
    model the data was made with); a copy of the model, or anything else, is checked size by
    size (:func:`labsupport.validate.model_and_data`)."""
    if getattr(data, "model", None) is not model:
        validate.model_and_data(model, data)


def mass_matrix(model: mujoco.MjModel, data: mujoco.MjData, out: np.ndarray | None = None) -> np.ndarray:
    r"""Dense joint-space inertia matrix :math:`M(q)` of shape ``(nv, nv)``.

    Args:
        model, data: the MuJoCo model and the data holding the factorised inertia.
        out: optional preallocated ``(nv, nv)`` float64 array to fill (no allocation).

    Example: the single joint, :math:`M = I_{cm} + m r^2 = 0.49 + 1.0 \cdot 0.1^2` kg·m².

    >>> from labsupport.plants import load_model
    >>> model, data = load_model("single_joint")
    >>> print(mass_matrix(model, data))
    [[0.5]]
    """
    _made_for(model, data)
    try:
        if out is None:
            out = np.zeros((model.nv, model.nv))
        if FULLM_TAKES_DATA:
            mujoco.mj_fullM(model, data, out)
        else:  # MuJoCo 3.x
            mujoco.mj_fullM(model, out, data.qM)
    except (TypeError, AttributeError):
        validate.model_and_data(model, data)  # names a model or data of the wrong kind
        raise _bad_out("mass_matrix", out, (model.nv, model.nv)) from None
    if not out.diagonal().all():  # every joint has inertia: a zero is data never evaluated
        raise ValueError(
            "mass_matrix: the data holds no mass matrix yet (its diagonal has zeros): run "
            "mujoco.mj_forward(model, data) on this data after setting its state (a scratch MjData too)"
        )
    return out


def mass_times(model: mujoco.MjModel, data: mujoco.MjData, v: np.ndarray, out: np.ndarray | None = None) -> np.ndarray:
    r"""The product :math:`M(q)\,v` of the joint-space inertia with a vector ``v`` (nv,).

    MuJoCo's ``mj_mulM`` multiplies by the inertia it holds in sparse form, so the dense
    :math:`M` is never formed: in a control loop this is about half the cost of
    ``mass_matrix(model, data) @ v``, with the same result to rounding.

    Args:
        out: optional preallocated ``(nv,)`` float64 array to fill; a new array otherwise.

    Example: the single joint, :math:`M = 0.5` kg·m², asked for 2 rad/s²: 1 N·m.

    >>> from labsupport.plants import load_model
    >>> model, data = load_model("single_joint")
    >>> print(mass_times(model, data, [2.0]))
    [1.]
    """
    _made_for(model, data)
    try:
        if out is None:
            out = np.empty(model.nv)
        mujoco.mj_mulM(model, data, out, v)
    except (TypeError, AttributeError):
        validate.model_and_data(model, data)
        try:
            validate.vector("v", v, (model.nv,))
        except ValueError as err:
            raise ValueError(f"{err}{_gain_matrix_hint(v)}") from None
        raise _bad_out("mass_times", out, (model.nv,)) from None
    return out


def _gain_matrix_hint(value) -> str:
    """Why a control law's acceleration may have come out as a matrix: its gains were, or its
    reference was a whole ``Reference`` where the law takes its three parts."""
    if np.ndim(value) != 2:
        return ""
    return (
        "; in a control law this is the acceleration, which a gain given as a matrix makes a "
        "matrix too: pass Kp and Kd as numbers (or one number per joint or coordinate); so does "
        f"{validate.REFERENCE_WHOLE}"
    )


def _bad_out(function: str, out, shape: tuple[int, ...]) -> ValueError:
    """The error for an ``out`` array that MuJoCo or NumPy refused to fill."""
    if isinstance(out, np.ndarray):
        got = f"a {out.dtype} array of shape {out.shape}" + ("" if out.flags.c_contiguous else ", not C-contiguous")
    else:
        got = type(out).__name__
    return ValueError(
        f"{function}: out must be a C-contiguous float64 array of shape {shape}, got {got}; "
        "or leave out= away to get a new array"
    )


def bias_forces(data: mujoco.MjData) -> np.ndarray:
    r"""Bias forces :math:`h(q,\dot q) = C(q,\dot q)\dot q + g(q)` (``qfrc_bias``), a copy.

    Example: the single joint held horizontal, at rest: gravity's torque
    :math:`m g r = 1.0 \cdot 9.81 \cdot 0.1` N·m.

    >>> from labsupport.plants import load_model
    >>> model, data = load_model("single_joint")
    >>> print(bias_forces(data))
    [0.981]
    """
    if not isinstance(data, mujoco.MjData):
        raise ValueError(f"bias_forces takes the data (a mujoco.MjData), got {type(data).__name__}")
    return data.qfrc_bias.copy()


def solve_mass(model: mujoco.MjModel, data: mujoco.MjData, rhs: np.ndarray) -> np.ndarray:
    r""":math:`x = M(q)^{-1} y` using MuJoCo's sparse factorisation (no explicit inverse).

    ``rhs`` is ``(nv,)`` or ``(k, nv)`` (one right-hand side per row). With ``J`` as ``rhs``
    the rows of the result are those of :math:`J M^{-1}` (:math:`M` is symmetric).
    """
    _made_for(model, data)
    y = validate.floats(rhs)
    if y is None:
        raise ValueError(f"solve_mass: rhs must be numbers, got {validate.short(rhs)}")
    y = np.ascontiguousarray(y)  # MuJoCo reads rows
    x = np.empty_like(y)
    try:
        if y.ndim == 1:  # MuJoCo solves for rows
            mujoco.mj_solveM(model, data, x[None], y[None])
        else:
            mujoco.mj_solveM(model, data, x, y)
    except TypeError:
        validate.model_and_data(model, data)
        raise ValueError(f"solve_mass: rhs must have shape ({model.nv},) or (k, {model.nv}), got {y.shape}") from None
    return x


#: What a law is told whose arrays do not fit the site Jacobian: its six rows.
SITE_JACOBIAN_ROWS = (
    'site_jacobian(model, data, "end_effector") has 6 rows, translation then rotation: the position '
    "task takes rows 0–2, [:3], and so does site_jdot_qdot"
)
#: Why a site Jacobian may be singular where the arm is not: its rotation rows were taken.
ANGULAR_ROWS = (
    "the position task takes the site Jacobian's rows 0–2, [:3]; rows 3–5, the rotation's, can be "
    "singular everywhere (on the 3R arm, whose two pitch axes are parallel)"
)


def site_jacobian(
    model: mujoco.MjModel, data: mujoco.MjData, site: int | str, out: np.ndarray | None = None
) -> np.ndarray:
    r"""Geometric Jacobian of a site, shape ``(6, nv)``: rows 0–2 linear, rows 3–5 angular.

    .. math:: \begin{bmatrix} v \\ \omega \end{bmatrix} = J(q)\,\dot q

    Example: the single joint's tip, 0.2 m from the hinge: held horizontal, it rises at
    0.2 m/s per rad/s.

    >>> from labsupport.plants import load_model
    >>> model, data = load_model("single_joint")
    >>> J = site_jacobian(model, data, "tip")
    >>> print(J.shape, f"{J[2, 0]:.3f}")
    (6, 1) 0.200
    """
    _made_for(model, data)
    sid = site_id(model, site)
    if out is None:
        out = np.empty((6, model.nv))  # mj_jacSite fills every entry
    try:
        mujoco.mj_jacSite(model, data, out[:3], out[3:], sid)
    except TypeError:
        validate.model_and_data(model, data)
        raise _bad_out("site_jacobian", out, (6, model.nv)) from None
    return out


def site_jdot_qdot(
    model: mujoco.MjModel, data: mujoco.MjData, site: int | str, out: np.ndarray | None = None
) -> np.ndarray:
    r"""The velocity-product acceleration :math:`\dot J(q,\dot q)\,\dot q` of a site, shape ``(6,)``.

    With it, :math:`\ddot x = J\ddot q + \dot J\dot q`. Uses ``mj_jacDot`` at the site's
    current position.

    Args:
        out: optional preallocated ``(6,)`` float64 array to fill; a new array otherwise.

    Example: the single joint's tip turning at 2 rad/s: the centripetal acceleration
    :math:`-r\dot\theta^2 = -0.2 \cdot 2^2` m/s², toward the hinge (along :math:`-x` when
    horizontal).

    >>> import mujoco
    >>> from labsupport.plants import load_model
    >>> model, data = load_model("single_joint")
    >>> data.qvel[:] = 2.0
    >>> mujoco.mj_forward(model, data)
    >>> print(f"{site_jdot_qdot(model, data, 'tip')[0]:.3f} m/s²")
    -0.800 m/s²
    """
    _made_for(model, data)
    sid = site_id(model, site)
    jdot = np.empty((6, model.nv))
    try:
        mujoco.mj_jacDot(model, data, jdot[:3], jdot[3:], data.site_xpos[sid], model.site_bodyid[sid])
    except (TypeError, AttributeError):
        validate.model_and_data(model, data)
        raise
    try:
        return jdot.dot(data.qvel, out=out)
    except (TypeError, ValueError):
        raise _bad_out("site_jdot_qdot", out, (6,)) from None


#: Where a task Jacobian stops counting as regular [m² per rad²]: below it the arm is stretched
#: out or folded. :func:`jacobian_solve` compares it with the smallest pivot of the Cholesky
#: factorisation of :math:`J J^\top`, :func:`task_space_inertia` with the square of :math:`J`'s
#: smallest singular value :math:`\sigma^2`. No pivot is below :math:`\sigma^2`, so near a
#: singularity the first refuses a little later than the second.
SINGULAR_PIVOT = 1e-10


def jacobian_solve(
    J: np.ndarray, rhs: np.ndarray, min_pivot: float = SINGULAR_PIVOT, out: np.ndarray | None = None
) -> np.ndarray:
    r""":math:`x = J^{-1} y` for a square task Jacobian, or a ``ValueError`` at a singular configuration.

    Computed as :math:`x = J^\top (J J^\top)^{-1} y` (equal to :math:`J^{-1}y` when :math:`J` is
    square and invertible) with MuJoCo's Cholesky factorisation of :math:`J J^\top`, whose rank
    tells a singular :math:`J` apart: a pivot below ``min_pivot`` means the arm is stretched
    out or folded, where no joint motion produces some task motion. A :math:`J` with NaN or inf
    entries is named as such where MuJoCo's factorisation reports them as rank loss (MuJoCo 4);
    MuJoCo 3 returns NaN instead, on which the loop then stops. The check is not made up
    front: in the control loop it would cost more than all the rest of this function's checks.
    ``out`` is an optional preallocated ``(nv,)`` result.
    """
    try:  # validate.floats's conversion, inline: this runs at every control step
        J = np.ascontiguousarray(J, dtype=float)
        rhs = np.ascontiguousarray(rhs, dtype=float)
    except (TypeError, ValueError, OverflowError):
        raise ValueError(
            f"jacobian_solve: J and rhs must be numbers, got J = {validate.short(J)} and rhs = {validate.short(rhs)}"
        ) from None
    d, nv = J.shape if J.ndim == 2 else (-1, -1)
    if rhs.shape != (d,) or d > nv:
        more = (
            f": a task of {d} coordinates for {nv} joints has no inverse, so give the target as many "
            "coordinates as the arm has joints, (x, y) for the planar arm"
            if d > nv
            else _gain_matrix_hint(rhs)
        )
        raise ValueError(
            f"jacobian_solve needs a (d, nv) Jacobian with d <= nv and a (d,) right-hand side, "
            f"got J of shape {J.shape} and rhs of shape {rhs.shape}{more}"
        )
    JJt = J.dot(J.T)
    try:
        rank = mujoco.mju_cholFactor(JJt, min_pivot)  # J J^T = L L^T, in place
    except TypeError:
        rank = -1
    if rank < 0 or not min_pivot > 0:  # a pivot of 0 or less would let a singular J through
        raise ValueError(f"jacobian_solve: min_pivot must be a positive number, got {validate.short(min_pivot)}")
    if rank < d:
        if not np.isfinite(J).all():
            raise ValueError(f"the Jacobian has entries that are not finite (NaN or inf): {J.tolist()}")
        _refuse_zero_jacobian(J)
        raise ValueError(
            "the Jacobian is singular at this configuration (the arm is stretched out or "
            "folded, or two of its joint axes line up, as a six-axis wrist's do at q5 = 0): no "
            "joint acceleration gives the task acceleration asked for; keep the target inside "
            "the workspace, away from its boundary, and the wrist away from such poses"
        )
    z = np.empty(d)
    mujoco.mju_cholSolve(z, JJt, rhs)  # z = (J J^T)^-1 y
    try:
        return J.T.dot(z, out=out)  # x = J^T z
    except (TypeError, ValueError):
        raise _bad_out("jacobian_solve", out, (nv,)) from None


def _refuse_zero_jacobian(J: np.ndarray) -> None:
    """``ValueError`` for a Jacobian of zeros only: not a singular arm, but data whose state was
    set without its kinematics being computed."""
    if not J.any():
        raise ValueError(
            "the Jacobian is all zeros: its data holds no kinematics yet. Run mujoco.mj_forward(model, data) "
            "after setting the state (on a scratch MjData: mujoco.mj_kinematics, then mujoco.mj_comPos)"
        )


def task_space_inertia(model: mujoco.MjModel, data: mujoco.MjData, jac: np.ndarray, damping: float = 0.0) -> np.ndarray:
    r"""Operational-space (task-space) inertia :math:`\Lambda = (J M^{-1} J^\top + \lambda I)^{-1}`.

    ``damping`` (:math:`\lambda \ge 0`) keeps :math:`\Lambda` bounded near singular
    configurations; with :math:`\lambda = 0` and a square invertible :math:`J`,
    :math:`J^\top \Lambda = M J^{-1}`.
    """
    damping = validate.number("damping", damping, nonnegative=True)
    validate.mujoco_model(model)
    jac = validate.vector("task_space_inertia: jac", jac, None)
    if jac.ndim != 2 or jac.shape[1] != model.nv:  # one row is (1, nv): a 1-D J would be read as rows
        raise ValueError(
            f"task_space_inertia: jac must be a Jacobian of shape (k, {model.nv}), one row per task "
            f"coordinate, got shape {jac.shape}"
        )
    minv_jt = solve_mass(model, data, jac).T  # M^{-1} J^T, shape (nv, k)
    lam_inv = jac @ minv_jt
    if damping:
        lam_inv = lam_inv + damping * np.eye(lam_inv.shape[0])
    if not damping and (
        jac.shape[0] > jac.shape[1] or np.linalg.svd(jac, compute_uv=False).min() ** 2 < SINGULAR_PIVOT
    ):
        _refuse_zero_jacobian(jac)
        raise ValueError(
            "task_space_inertia: J has lost rank, so J M⁻¹ Jᵀ is singular and Λ does not exist here (the arm "
            "is stretched out or folded, or J has more rows than joints); pass damping > 0 for a bounded Λ"
        )
    try:
        return np.linalg.solve(lam_inv, np.eye(lam_inv.shape[0]))
    except np.linalg.LinAlgError:  # J has full rank, so M⁻¹ is what vanished
        raise ValueError(
            "task_space_inertia: J M⁻¹ Jᵀ is singular although J has full rank, so the data holds no mass "
            "matrix yet: run mujoco.mj_forward(model, data) (or a step) after setting the state"
        ) from None


def site_id(model: mujoco.MjModel, site: int | str) -> int:
    """The id of a site given by name, or already by id; ``ValueError`` naming the model's sites
    for a name it does not have or an id out of its range (MuJoCo itself would read past its
    arrays)."""
    try:
        if type(site) is int and 0 <= site < model.nsite:  # the laws' case, every step: first and cheap
            return site
    except AttributeError:  # not a model (say, model and data swapped): model_object says so
        pass
    return validate.model_object(model, "site", site)
