"""labsupport installs as a package whose models travel with it."""

import os
import subprocess
import sys
import zipfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def _wheel_names(tmp_path) -> set[str]:
    """File names inside the wheel pip builds from the checkout: what a student installs."""
    subprocess.run(
        [sys.executable, "-m", "pip", "wheel", "-q", "--no-deps", "-w", str(tmp_path), str(ROOT)],
        check=True,
        capture_output=True,
    )
    wheel = next(tmp_path.glob("labsupport-*.whl"))
    return set(zipfile.ZipFile(wheel).namelist())


def test_wheel_ships_every_model(tmp_path):
    names = _wheel_names(tmp_path)
    for xml in (ROOT / "models").glob("*.xml"):
        assert f"labsupport/models/{xml.name}" in names


def test_wheel_holds_no_instructor_tooling_and_no_answers(tmp_path):
    """What Colab installs for a student: no batch grader, no masters, no 3R solutions."""
    names = _wheel_names(tmp_path)
    assert any(n.startswith("labsupport/grading/") for n in names)  # the in-notebook checks ship
    assert not [n for n in names if n.startswith("labsupport/instructor/")]
    assert not [n for n in names if "spatial_3r" in n and n.endswith(".py")]
    assert not [n for n in names if n.endswith(".ipynb")]


def test_models_load_from_any_working_directory(tmp_path):
    code = (
        "import labsupport, mujoco\n"
        "from labsupport.plants import load_model, model_path\n"
        "for p in model_path('single_joint').parent.iterdir():\n"
        "    if p.name.endswith('.xml') and not p.name.startswith('ur5e'):\n"
        "        m, d = load_model(p.name[:-4]); assert m.nv > 0\n"
        "print('ok')\n"
    )
    out = subprocess.run([sys.executable, "-c", code], cwd=tmp_path, capture_output=True, text=True)
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == "ok"


def test_unknown_model_is_named():
    import pytest

    from labsupport.plants import model_path

    with pytest.raises(ValueError, match="no model named 'nope'"):
        model_path("nope")


def test_a_checkout_on_the_path_but_not_installed_is_told_to_install(tmp_path):
    """``labsupport.models`` exists only once the package is installed (``models/`` is mapped
    there); a checkout merely put on ``sys.path`` gets one message saying what to run, both
    from the shipped-model loader and from the UR5e's."""
    import shutil
    import site

    shutil.copytree(ROOT / "labsupport", tmp_path / "labsupport", ignore=shutil.ignore_patterns("__pycache__"))
    code = (
        "import labsupport.plants, labsupport.ur5e\n"
        "print(labsupport.plants.__file__)\n"
        "for load in (lambda: labsupport.plants.load_model('planar_2r'), labsupport.ur5e.load_ur5e):\n"
        "    try:\n"
        "        load()\n"
        "    except ModuleNotFoundError as error:\n"
        "        print(error)\n"
    )
    # -S: no site-packages' .pth files, so an editable install's finder cannot supply the models.
    path = [str(tmp_path), *site.getsitepackages()]
    out = subprocess.run(
        [sys.executable, "-S", "-c", code],
        cwd=tmp_path,
        capture_output=True,
        text=True,
        env={**os.environ, "PYTHONPATH": os.pathsep.join(path)},
    )
    assert out.returncode == 0, out.stderr
    lines = out.stdout.splitlines()
    assert lines[0] == str(tmp_path / "labsupport" / "plants.py")
    assert len(lines) == 3
    for line in lines[1:]:
        assert "labsupport.models" in line and "without being installed" in line
        assert f"imported from {tmp_path}" in line and "pip install -e ." in line


def test_a_checkout_on_the_path_refuses_the_models_of_another_installed_checkout(tmp_path):
    """A second checkout put on PYTHONPATH of a Python where this one is installed (pip install -e)
    imported its own labsupport but this checkout's models: a mass changed in the second
    checkout's models/ moved nothing, and its tests passed. Its models folder now refuses, naming
    both checkouts and the command that installs the second."""
    import shutil

    other = tmp_path / "other"
    shutil.copytree(ROOT / "labsupport", other / "labsupport", ignore=shutil.ignore_patterns("__pycache__"))
    shutil.copytree(ROOT / "models", other / "models")
    shutil.copy(ROOT / "pyproject.toml", other)
    code = "from labsupport.plants import load_model\nload_model('planar_2r')\n"
    env = {**os.environ, "PYTHONPATH": str(other)}
    out = subprocess.run([sys.executable, "-c", code], cwd=tmp_path, capture_output=True, text=True, env=env)
    assert out.returncode != 0
    assert f"labsupport was imported from the checkout {other}" in out.stderr, out.stderr
    assert f"resolve to {ROOT / 'models'}" in out.stderr and "pip install -e ." in out.stderr
