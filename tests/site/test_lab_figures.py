"""The lab's printed figures, as the built book's Task notebooks print them.

Each Task notebook prints the figures that the lab's text prints, to the same precision. These
tests read the notebooks as the book build executed them (``_build/jupyter_execute``), so that
a change anywhere that moves a figure the lab prints is caught, and named: a setting in a
notebook's cell, a law, ``labsupport``, a model. The unit tests pin the same figures from the
laws run with the lab's settings (``tests/test_single_joint.py``, ``tests/test_task2_task3.py``,
``tests/test_ur5e.py``); these check that the pages print them.
"""

from __future__ import annotations

import json

import nbformat
import pytest
from sitetools import SITE

EXECUTED = SITE.parent / "jupyter_execute" / "notebooks"

#: What each notebook prints of the lab's figures, in the course's words, with the lab's values
#: at the lab's precision (white space is compared loosely).
PRINTED = {
    "task1_single_joint": [
        "Max gravity torque: m·g·r = 0.981 N·m",
        "τc = M / b = 0.5 / 0.1 = 5.00 s",
        "ω_ss = τ / b = 1.0 / 0.1 = 10.00 rad/s",
        "ω = 6.321 rad/s (63.2 % of ω_ss)",
        "Kp = τ_max / e0 = 5.0 / 1.571 = 3.183 N·m/rad",
        "Kd = 2√(Kp·M) − b = 2.423 N·m·s/rad",
        "ωn = 2.523 rad/s, ζ = 1.000",
        "peak torque at t = 0: 5.00 N·m",
        "ζ = 0.591, ωn = 3.383 rad/s",
        "Kp = M·ωn² = 5.723 N·m/rad",
        "Kd = 2ζωn·M − b = 1.900 N·m·s/rad",
        "peak torque at t = 0: 8.99 N·m",
        "FB gains: Kp = 4.199 N·m/rad, Kd = 1.900 N·m·s/rad ζ = 0.690, ωn = 2.898 rad/s",
        "FB only : 10.891 deg FF+FB : 2.253 deg Reduction: 79.3 %",
    ],
    "task2_single_joint_mujoco": [
        "Kp = 4.199 N·m/rad, Kd = 1.900 N·m·s/rad (zeta = 0.690, wn = 2.898 rad/s)",
        "matched model (r~ = 0.10 m): 0.0069 deg",
        "mismatched model (r~ = 0.08 m): 2.2551 deg",
    ],
    "task3_planar_2r": [
        "RMS error, OS-CT : ex = 0.224 mm, ey = 0.952 mm",
        "RMS error, IK+JS-CT : ex = 0.224 mm, ey = 0.955 mm",
    ],
    "task4_ur5e": [
        "RMS position error: 39.11 mm",
        "RMS orientation error: 2.996 deg",
    ],
}

#: The lab's figures that a page states in its prose only, by their glue name: the format the
#: page gives them, and the lab's value.
GLUED = {
    "task2_single_joint_mujoco": {"t2_penalty": (".4f", "2.2481")},
}


def loosely(text: str) -> str:
    return " ".join(text.split())


def printed(notebook: str) -> str:
    """Everything the executed ``notebook`` printed, its streams in order, white space collapsed."""
    path = EXECUTED / f"{notebook}.ipynb"
    if not path.is_file():
        pytest.fail(f"{path} is missing: build the book first (bash .ci/build-book)")
    nb = nbformat.read(path, as_version=4)
    streams = [o.get("text", "") for c in nb.cells if c.cell_type == "code" for o in c.get("outputs", [])]
    return loosely("\n".join(s for s in streams if isinstance(s, str)))


@pytest.mark.parametrize("notebook", sorted(PRINTED))
def test_each_task_prints_the_labs_figures_at_the_labs_precision(notebook):
    said = printed(notebook)
    missing = [line for line in PRINTED[notebook] if loosely(line) not in said]
    assert not missing, (
        f"{notebook} no longer prints {missing}, figures the lab prints. Find what moved them (a setting in "
        "the notebook, a law, labsupport); if the change is meant, say on the page why the figure differs "
        "from the lab's, and update this list"
    )


@pytest.mark.parametrize("notebook", sorted(GLUED))
def test_the_labs_figures_in_the_prose_keep_the_labs_values(notebook):
    glued = json.loads((EXECUTED / f"{notebook}.glue.json").read_text(encoding="utf-8"))
    for name, (spec, lab) in GLUED[notebook].items():
        value = float(glued[name]["data"]["text/plain"])
        assert format(value, spec) == lab, f"{notebook}'s {name} is {value:{spec}}, the lab prints {lab}"
