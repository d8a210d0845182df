"""The worked examples in labsupport's docstrings run and print what they say.

Each concept a student meets first (gain design, references, metrics, the 2R arm's kinematics,
MuJoCo's M, h, J and J̇q̇, the single joint's simulation, the one loop, the servo inversion)
carries an example with the lab's numbers, checked here with ``doctest`` against the closed
form it states: a docstring cannot drift from the code.
"""

from __future__ import annotations

import doctest
import importlib

import pytest

#: Modules whose functions carry worked examples, and how many examples each has at least.
MODULES = {
    "labsupport.gains": 5,
    "labsupport.metrics": 3,
    "labsupport.trajectories": 3,
    "labsupport.kinematics.planar_2r": 5,
    "labsupport.dynamics": 10,
    "labsupport.plants": 2,
    "labsupport.sim": 5,
    "labsupport.actuators": 5,
    "labsupport.instructor.gradebook": 1,
}


@pytest.mark.parametrize("name", MODULES)
def test_docstring_examples_hold(name):
    module = importlib.import_module(name)
    result = doctest.testmod(module, optionflags=doctest.NORMALIZE_WHITESPACE)
    assert result.attempted >= MODULES[name], f"{name}: {result.attempted} example lines, expected more"
    assert result.failed == 0, f"{name}: {result.failed} example lines print something else (see the output above)"
