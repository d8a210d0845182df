"""The version ranges the course admits, as the CI scripts read them.

``.ci/oldest-pins.py`` turns pyproject.toml's lower bounds into the exact pins of `.venv-oldest`
(``.ci/test-oldest``); ``.ci/newest-requirements.py`` lifts requirements.txt's pins for the weekly
workflow. Both are checked against the files they read.
"""

import re
import subprocess
import sys
from pathlib import Path

import yaml

try:
    import tomllib
except ModuleNotFoundError:  # Python 3.10: the instructor extra brings tomli
    import tomli as tomllib
from test_fresh_venv import COLAB_PYTHON

ROOT = Path(__file__).resolve().parents[1]


def run(script: str) -> list[str]:
    out = subprocess.run([sys.executable, str(ROOT / ".ci" / script)], capture_output=True, text=True, check=True)
    return out.stdout.splitlines()


def test_oldest_pins_are_pyprojects_lower_bounds():
    project = tomllib.loads((ROOT / "pyproject.toml").read_text(encoding="utf-8"))["project"]
    declared = project["dependencies"] + [r for extra in project["optional-dependencies"].values() for r in extra]
    pins = run("oldest-pins.py")
    highest = {}  # a package the package and an extra both declare is pinned at the higher bound
    for requirement in declared:
        name, bound = re.match(r"([A-Za-z0-9_.-]+)\s*(?:>=|==)\s*([0-9.]+)", requirement).groups()
        version = tuple(map(int, bound.split(".")))
        if name not in highest or version > highest[name][0]:
            highest[name] = (version, f"{name}=={bound}")
    assert [pin.split(";")[0] for pin in pins] == [pin for _, pin in highest.values()]
    assert "mujoco==3.5.0" in pins
    assert "ipython==8.0" in pins and "ipython==7.34" not in pins


def test_newest_requirements_lift_every_pin_but_the_caps():
    pinned = [
        line.split("==")[0]
        for line in (ROOT / "requirements.txt").read_text(encoding="utf-8").splitlines()
        if line.strip() and not line.startswith("#")
    ]
    lifted = [line for line in run("newest-requirements.py") if line.strip() and not line.startswith("#")]
    assert [re.match(r"[A-Za-z0-9_.-]+", line).group() for line in lifted] == pinned
    assert "jupyter-book<2" in lifted  # the book stays Jupyter Book v1
    assert [line for line in lifted if "==" in line] == [line for line in lifted if line.startswith("ruff==")]
    assert "mujoco" in lifted and "numpy" in lifted  # pyproject's ranges decide (mujoco<5)


def test_weekly_workflow_runs_the_test_command_on_newest_versions_and_checks_links():
    workflow = yaml.safe_load((ROOT / ".github" / "workflows" / "weekly.yml").read_text(encoding="utf-8"))
    triggers = workflow[True]  # YAML 1.1 reads the key `on` as True
    assert triggers["schedule"][0]["cron"].split()[-1] == "1"  # weekly, on Mondays
    steps = {job: " ".join(str(s.get("run", "")) for s in spec["steps"]) for job, spec in workflow["jobs"].items()}
    assert "newest-requirements.py" in steps["newest"]
    assert 'REQUIREMENTS="$PWD/newest.txt" bash .ci/test' in steps["newest"]  # absolute: tests copy the checkout
    assert "requirements.txt" not in steps["newest"]  # the tests read its pins: it stays as committed
    assert workflow["jobs"]["newest"]["container"]["options"] == "--privileged"  # bubblewrap's namespaces
    assert "--builder linkcheck" in steps["links"]
    assert "gh issue create" in steps["report"] and workflow["jobs"]["report"]["if"].startswith("failure()")


def test_every_push_runs_the_readme_test_command():
    """CI's entry point on every push and pull request, in a container where bubblewrap can run."""
    workflow = yaml.safe_load((ROOT / ".github" / "workflows" / "tests.yml").read_text(encoding="utf-8"))
    assert {"push", "pull_request"} <= set(workflow[True])
    job, colab = workflow["jobs"]["test"], workflow["jobs"]["colab-python"]
    assert [s["run"] for s in job["steps"] if s.get("run", "").startswith("bash")] == ["bash .ci/run"]
    assert job["container"]["options"] == colab["container"]["options"] == "--privileged"
    # the unit and notebook tests again on the Python Colab runs, which tests/test_fresh_venv.py names
    assert colab["container"]["image"] == f"python:{COLAB_PYTHON}-bookworm"
    assert [s["run"] for s in colab["steps"] if "run" in s] == [f"PYTHON=python{COLAB_PYTHON} bash .ci/test-unit"]
    run = (ROOT / ".ci" / "run").read_text(encoding="utf-8")
    readme = (ROOT / "README.md").read_text(encoding="utf-8")
    assert "bash .ci/test" in run and "bash .ci/test " in readme
