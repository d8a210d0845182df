"""labsupport installs as a package whose models travel with it."""

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
