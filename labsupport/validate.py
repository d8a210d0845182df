"""Input checks, written once: the package's public functions validate their arguments with
these, so a bad argument gets a message that names it, says what was expected and what came
instead, rather than a traceback from deep inside NumPy or MuJoCo. The control laws are the
exception: their bodies read like their equations, with no checks; run inside
:func:`labsupport.sim.simulate`, an error of theirs (a shape NumPy cannot broadcast, say) is
explained there, with the law's name and the time.
"""

from __future__ import annotations

import math

import mujoco
import numpy as np

#: What :func:`model_object` looks up: MuJoCo's object type and the model's count of them.
_OBJECTS = {
    "site": (mujoco.mjtObj.mjOBJ_SITE, "nsite"),
    "camera": (mujoco.mjtObj.mjOBJ_CAMERA, "ncam"),
    "keyframe": (mujoco.mjtObj.mjOBJ_KEY, "nkey"),
}


def floats(value) -> np.ndarray | None:
    """``value`` as a float array, or ``None`` where NumPy cannot read it as numbers: an object,
    nested lists of unequal lengths, a Python integer too large for a float. The one place that
    knows what NumPy raises then; callers say what the value should have been. (Text NumPy reads:
    "5" is 5.0; :func:`not_text` refuses it first.) Complex numbers are ``None`` too: NumPy would
    keep their real parts with a mere warning (:func:`real` says why they arise)."""
    if is_complex(value):
        return None
    try:
        return np.asarray(value, dtype=float)
    except (TypeError, ValueError, OverflowError):
        return None


def vector(name: str, value, shape) -> np.ndarray:
    """``value`` as a float array of exactly ``shape``, with finite entries.

    Args:
        name: the argument's name, as the caller knows it (used in the message).
        value: anything ``np.asarray`` turns into numbers.
        shape: the expected shape, e.g. ``(2,)`` or ``(6, 7)``; an ``int`` means ``(n,)``;
            ``None`` takes any shape (one number included).

    Returns:
        A float64 array (the input itself when it already is one of the right shape).

    Raises:
        ValueError: the value is not numeric (nested lists of unequal lengths, a number too
            large for a float), has another shape, or holds NaN or inf.
    """
    if shape is not None:
        shape = (int(shape),) if np.ndim(shape) == 0 else tuple(int(n) for n in shape)
    not_text(name, value)
    real(f"{name} holds", value)
    array = floats(value)
    if array is None:
        expected = "numbers" if shape is None else f"numbers of shape {shape}"
        raise ValueError(f"{name} must be {expected}, got {short(value)}")
    if shape is not None and array.shape != shape:
        raise ValueError(f"{name} must have shape {shape}, got shape {array.shape}: {short(value)}")
    if not np.all(np.isfinite(array)):
        raise ValueError(f"{name} must be finite, got {short(value)}{none_note(value)}")
    return array


def none_note(value) -> str:
    """A remark for a message about a value that is not finite: where it holds ``None``
    (which NumPy reads as NaN), say so, since the user wrote None, not NaN."""
    try:
        holds_none = any(v is None for v in np.asarray(value, dtype=object).ravel())
    except (TypeError, ValueError):
        return ""
    return " (None is not a number: a value never set?)" if holds_none else ""


def number(name: str, value, *, positive: bool = False, nonnegative: bool = False) -> float:
    """``value`` as a finite float, optionally required to be > 0 or >= 0.

    Raises:
        ValueError: the value is not a real number, is NaN or inf, or breaks the sign asked.
    """
    if isinstance(value, (bool, np.bool_)):
        raise ValueError(f"{name} must be a number, got the boolean {value!r}")
    if value is None:
        raise ValueError(f"{name} must be a number, got None (a value never set?)")
    not_text(name, value)
    array = floats(value)
    if array is None or array.size != 1:
        raise ValueError(f"{name} must be a single real number, got {short(value)}")
    result = float(array.reshape(()))
    if not np.isfinite(result):
        raise ValueError(f"{name} must be finite, got {value!r}")
    if positive and not result > 0:
        raise ValueError(f"{name} must be positive, got {value!r}")
    if nonnegative and not result >= 0:
        raise ValueError(f"{name} must be non-negative, got {value!r}")
    return result


def whole(name: str, value, low: int, high: int | None = None) -> int:
    """``value`` as an ``int`` from ``low`` to ``high`` (inclusive; no upper bound for ``None``): a
    whole number such as a count of pixels, or a ``ValueError`` that says what is allowed."""
    allowed = f"a whole number from {low} to {high}" if high is not None else f"a whole number, at least {low}"
    whole_number = not isinstance(value, (bool, np.bool_)) and (
        isinstance(value, (int, np.integer))
        or (isinstance(value, (float, np.floating)) and math.isfinite(value) and float(value).is_integer())
    )
    if not whole_number or value < low or (high is not None and value > high):
        raise ValueError(f"{name} must be {allowed}, got {short(value)}")
    return int(value)


#: The most time steps one run, or one sampled reference, may hold: 10 million (2.8 hours at
#: 1 ms, a gigabyte or more of log); beyond it a mistyped duration would fill the memory, or, with
#: the lab's timing, count steps for hours before it started.
MAX_STEPS = 10_000_000


def flag(name: str, value) -> bool:
    """``value`` as a bool, or a ``ValueError`` for anything but ``True`` and ``False`` (NumPy's
    included): Python reads any text but ``""`` as true, even ``"no"``, and a number by whether it
    is zero."""
    if not isinstance(value, (bool, np.bool_)):
        raise ValueError(f"{name} must be True or False, got {short(value)}")
    return bool(value)


def steps(duration: float, dt: float) -> int:
    """``round(duration / dt)`` for a positive ``duration`` and time step ``dt`` (checked), or a
    ``ValueError`` past :data:`MAX_STEPS`."""
    duration, dt = number("duration", duration, positive=True), number("dt", dt, positive=True)
    n = duration / dt
    if n > MAX_STEPS:
        raise ValueError(
            f"duration / dt = {duration:g} s / {dt:g} s is {n:.3g} steps, more than the {MAX_STEPS:,} one run may "
            "hold: shorten the duration (it is in seconds) or take a larger time step"
        )
    return int(round(n))


def band(value) -> float:
    """A settling band: a fraction of the step between 0 and 1 (0.02 for 2 %), else a ``ValueError``."""
    value = number("band", value, positive=True)
    if value >= 1:
        raise ValueError(f"band is a fraction of the step, below 1 (0.02 for 2 %), got {value:g}")
    return value


def times(t, increasing: bool = False) -> np.ndarray:
    """``t`` as a float array of finite times [s]: one number, or an array of them; with
    ``increasing``, an array whose times increase from sample to sample."""
    if t is None:
        raise ValueError("t must be a time in seconds (a number or an array of them), got None")
    not_text("t", t)
    values = floats(t)
    if values is None:
        raise ValueError(f"t must be a time in seconds (a number or an array of them), got {short(t)}")
    t = values
    if not np.isfinite(t).all():
        raise ValueError(f"t must be finite, got {short(t)}")
    if increasing and t.ndim == 1 and not np.all(np.diff(t) > 0):
        raise ValueError("the times t must increase from sample to sample")
    return t


def function(name: str, value, expected: str) -> None:
    """``ValueError`` unless ``value`` can be called; ``expected`` says what kind of function
    (``"a function controller(model, data) -> tau"``)."""
    if not callable(value):
        raise ValueError(f"{name} must be {expected}, got {short(value)}")


#: What a reference is, for :func:`function`'s message.
REFERENCE = (
    "a function of time returning a trajectories.Reference (for a fixed target x: "
    "lambda t: trajectories.set_point(t, x))"
)


def is_text(value) -> bool:
    """Whether ``value`` is text, a list or tuple holding text, or a NumPy array of text (NumPy
    would read "5" as 5.0)."""
    if isinstance(value, (str, bytes)):
        return True
    if isinstance(value, (list, tuple)):
        return any(isinstance(v, (str, bytes)) for v in value)
    return isinstance(value, np.ndarray) and value.dtype.kind in "SU"


def is_boolean(value) -> bool:
    """Whether ``value`` is ``True``/``False`` or an array of them (NumPy would read them as 1.0
    and 0.0): what a comparison such as ``q > 0`` gives."""
    if isinstance(value, (bool, np.bool_)):
        return True
    if isinstance(value, (list, tuple)):
        return len(value) > 0 and all(isinstance(v, (bool, np.bool_)) for v in value)
    return isinstance(value, np.ndarray) and value.dtype.kind == "b"


#: Why a boolean is not a number, for the messages that refuse one.
BOOLEAN_NOTE = "True and False are not numbers here (a comparison such as q > 0 gives them)"

#: Why a law's torque may hold three numbers per joint: a ``Reference`` (position, velocity,
#: acceleration) was passed whole where the law takes one of its parts.
REFERENCE_WHOLE = "a Reference passed whole as the desired position: unpack it, as in *ref.at(t)"


def not_text(name: str, value) -> None:
    """``ValueError`` for text, or for ``True``/``False`` values, where numbers belong."""
    if is_text(value):
        raise ValueError(f"{name} must be numbers, not text: got {short(value)}")
    if is_boolean(value):
        raise ValueError(f"{name} must be numbers, got {short(value)}: {BOOLEAN_NOTE}")


#: The arrays of a run's log (``labsupport.sim.Log``), which functions of a log read.
LOG_FIELDS = ("t", "q", "qdot", "tau", "ctrl", "ee", "ee_rot", "ref", "err", "site")


def is_run_log(value) -> bool:
    """Whether ``value`` has the arrays of a ``labsupport.sim.Log``."""
    return all(hasattr(value, name) for name in LOG_FIELDS)


def run_log(log, site: bool = False, reference: bool = False):
    """``log`` if it has the arrays of a ``labsupport.sim.Log`` (with a site's position, and a
    reference's error, when asked for), else a ``ValueError`` that says what to pass."""
    if not is_run_log(log):
        raise ValueError(f"log must be the Log that labsupport.sim.simulate returns, got {type(log).__name__}")
    if site and np.shape(log.ee)[1:] != (3,):
        raise ValueError("the log has no end-effector position: pass site= to simulate to record one")
    if reference and np.shape(log.err)[1:] in ((), (0,)):
        raise ValueError("the log has no position error: pass site= and reference= to simulate to record one")
    return log


def mujoco_model(model) -> None:
    """``ValueError`` unless ``model`` is a ``mujoco.MjModel``; a ``mujoco.MjData`` in its place
    is named as model and data swapped."""
    if not isinstance(model, mujoco.MjModel):
        swapped = ": model and data are swapped" if isinstance(model, mujoco.MjData) else ""
        raise ValueError(f"model must be a mujoco.MjModel, got {type(model).__name__}{swapped}")


def model_and_data(model, data) -> None:
    """``ValueError`` unless ``model`` is a ``mujoco.MjModel`` and ``data`` a ``mujoco.MjData``
    made for it (sizes checked: a data of another model would be read past its arrays or
    broadcast into the wrong shapes)."""
    mujoco_model(model)
    if not isinstance(data, mujoco.MjData):
        raise ValueError(f"data must be a mujoco.MjData (made with mujoco.MjData(model)), got {type(data).__name__}")
    sizes = {"nq": data.qpos.size, "nv": data.qvel.size, "nu": data.ctrl.size, "nbody": len(data.xpos)}
    wrong = [f"{k} = {v} (the model's {getattr(model, k)})" for k, v in sizes.items() if v != getattr(model, k)]
    if wrong:
        raise ValueError(f"data was made for another model: its {', '.join(wrong)}; make it with mujoco.MjData(model)")


def complex_message(returned: str) -> str:
    """The explanation for a function that ``returned`` (say, "pd_torque returned") complex numbers."""
    return (
        f"{returned} complex numbers, but angles and torques are real. In Python a power of a negative "
        "number, such as (1 - c**2)**0.5 with |c| > 1, is complex: check that the argument of each "
        "square root (or arccos) stays in its range"
    )


def is_complex(value) -> bool:
    """Whether ``value`` holds complex numbers (False for anything NumPy cannot read)."""
    try:
        return bool(np.iscomplexobj(value))
    except Exception:  # a value returned by a student's or user's function may be anything
        return False


def real(returned: str, value) -> None:
    """``ValueError`` (see :func:`complex_message`) if ``value``, which ``returned`` names, holds
    complex numbers; NumPy would otherwise drop their imaginary parts with a mere warning."""
    if is_complex(value):
        raise ValueError(f"{complex_message(returned)} (got {short(value)})")


def short(value) -> str:
    """``value`` for an error message: 4 digits, long arrays elided, an integer of more than 30
    digits by its number of digits, 200 characters at most."""
    try:
        if isinstance(value, int) and abs(value) >= 10**30:
            return f"an integer of {len(str(abs(value)))} digits"
        with np.printoptions(precision=4, threshold=12, edgeitems=3):
            text = repr(value) if not isinstance(value, np.ndarray) else np.array2string(value)
    except ValueError:  # an integer of more digits than Python will print
        text = "a number too large to print"
    return text if len(text) <= 200 else text[:197] + "..."


def model_object(model: mujoco.MjModel, kind: str, value) -> int:
    """The id of the model's ``kind`` (``"site"``, ``"camera"`` or ``"keyframe"``) given by name
    or by id, or a ``ValueError`` that lists the model's ones (an id out of range would make
    MuJoCo read past its arrays)."""
    mujoco_model(model)
    obj, count = _OBJECTS[kind][0], getattr(model, _OBJECTS[kind][1])
    if isinstance(value, str):
        found = mujoco.mj_name2id(model, obj, value)
        if found >= 0:
            return found
    elif isinstance(value, (int, np.integer)) and not isinstance(value, bool) and 0 <= value < count:
        return int(value)
    names = [mujoco.mj_id2name(model, obj, i) or "" for i in range(count)]
    ids = f", by name or by id from 0 to {count - 1}" if count else ""
    raise ValueError(f"{kind} {value!r} is not in the model; its {kind}s are {names}{ids}")
