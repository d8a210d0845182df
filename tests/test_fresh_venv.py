"""Every notebook runs in a brand-new virtual environment, far from this repository.

This is what a student's Colab session does: a Python with nothing of ours installed runs the
install cell, which pip-installs ``labsupport @ <repository>/archive/refs/heads/<branch>.zip``
(GitHub's zip of the branch), and then the notebook. Here the same pip command installs from a
zip of this checkout's HEAD made by ``git archive`` (so only committed files count, exactly as in
GitHub's zip), with no ``git`` on the PATH (a student's machine may have none), into a
virtual environment that does NOT see the system's or the project's site-packages, and each
notebook, the Task 4 video included, is executed from a temporary directory outside the
repository. A missing dependency, a model file not shipped with the package, or a path relative
to the repository would fail here.

The environment is made with Colab's Python (:data:`COLAB_PYTHON`) where this machine has one
(``.ci/find-python``), so the course is tried on the Python its students run, not only on the
one the book is built with; elsewhere with this test's own Python, and a warning says so.

It takes a few minutes (pip reuses its cache), so it carries the ``fresh_venv`` mark:
``pytest -m "not fresh_venv"`` leaves it out of a quick run; CI runs it.
"""

from __future__ import annotations

import importlib.metadata
import json
import os
import shutil
import subprocess
import sys
import warnings
from pathlib import Path

import nbformat
import nbtools
import pytest

pytestmark = pytest.mark.fresh_venv

ROOT = nbtools.ROOT
NOTEBOOKS = sorted((ROOT / "notebooks").glob("*.ipynb"))
#: The Python of Colab's runtime.
COLAB_PYTHON = "3.13"
#: What Colab already provides and the install cell therefore does not install: a kernel and a
#: notebook runner. Pinned to the versions of this project's environment (pip's cache has them).
RUNNER = ["ipykernel", "nbclient", "nbformat"]

RUN_NOTEBOOK = r"""
import json, sys
import nbformat
from nbclient import NotebookClient

src, out, cwd = sys.argv[1:4]
nb = nbformat.read(src, as_version=4)
probe = nbformat.v4.new_code_cell(
    "import sys, json, labsupport\n"
    "from labsupport.plants import model_path\n"
    "print(json.dumps({'prefix': sys.prefix, 'labsupport': labsupport.__file__,\n"
    "                  'model': str(model_path('single_joint'))}))")
nb.cells.append(probe)
NotebookClient(nb, timeout=600, kernel_name="python3",
               resources={"metadata": {"path": cwd}}).execute()
nbformat.write(nb, out)
# The kernel may send one print in several stream messages (its buffer is flushed on a timer,
# which a busy machine can hit mid-line): the probe's facts are its whole stdout.
print("".join(o.get("text", "") for o in nb.cells[-1].outputs if o.get("name") == "stdout"))
"""


def _run(cmd, **kwargs):
    out = subprocess.run(cmd, capture_output=True, text=True, **kwargs)
    assert out.returncode == 0, f"{' '.join(map(str, cmd))} failed:\n{out.stdout[-3000:]}\n{out.stderr[-3000:]}"
    return out


def colab_python() -> str:
    """Colab's Python where this machine has it, else (with a warning) the one running this test."""
    found = subprocess.run(["bash", str(ROOT / ".ci" / "find-python"), COLAB_PYTHON], capture_output=True, text=True)
    if found.returncode == 0:
        return found.stdout.strip()
    here = sys.version.split()[0]
    warnings.warn(f"no Python {COLAB_PYTHON} (Colab's) here: the fresh environment uses {here}", stacklevel=2)
    return getattr(sys, "_base_executable", sys.executable)


def test_every_notebook_runs_in_a_fresh_venv(tmp_path):
    assert shutil.which("git"), "git is needed to make the zip of this checkout that pip installs"
    assert len(NOTEBOOKS) == 6, [nb.name for nb in NOTEBOOKS]
    venv = tmp_path / "venv"
    work = tmp_path / "student"
    work.mkdir()
    _run([colab_python(), "-m", "venv", str(venv)])  # no --system-site-packages: nothing leaks in
    py = venv / "bin" / "python"

    env = {k: v for k, v in os.environ.items() if k not in {"PYTHONPATH", "VIRTUAL_ENV", "PYTHONHOME", "PYTHONSTARTUP"}}
    env["MUJOCO_GL"] = env.get("MUJOCO_GL", "egl")
    env["PIP_DISABLE_PIP_VERSION_CHECK"] = "1"

    # Colab's pip is recent; the pip that `venv` bundles may be older.
    _run([str(py), "-m", "pip", "install", "-q", "--upgrade", "pip"], cwd=work, env=env, timeout=600)
    # The install cell's command, with a zip of this checkout in place of GitHub's zip of the
    # branch: the same files under one top folder, as GitHub writes it.
    cell = nbtools.install_cell_source()
    assert '"-m", "pip", "install", "-q",' in cell
    assert f'"labsupport @ {nbtools.archive_url(nbtools.repository_url())}"' in cell
    top = f"{nbtools.repository_url().rsplit('/', 1)[-1]}-{nbtools.repository_branch()}"
    archive = tmp_path / f"{top}.zip"
    _run(["git", "-C", str(ROOT), "archive", "--format=zip", f"--prefix={top}/", "-o", str(archive), "HEAD"])
    without_git = dict(env, PATH=str(venv / "bin"))
    _run(
        [str(py), "-m", "pip", "install", "-q", f"labsupport @ {archive.as_uri()}"],
        cwd=work,
        env=without_git,
        timeout=900,
    )
    runner = [f"{name}=={importlib.metadata.version(name)}" for name in RUNNER]
    _run([str(py), "-m", "pip", "install", "-q", *runner], cwd=work, env=env, timeout=900)

    # Nothing of the project's own environment is visible in the new one.
    probe = _run(
        [
            str(py),
            "-c",
            "import sys; print(sys.prefix); import importlib.util as u; print(u.find_spec('jupyter_book') is None)",
        ],
        cwd=work,
        env=env,
    )
    prefix, no_book = probe.stdout.split()
    assert Path(prefix) == venv and no_book == "True"

    for notebook in NOTEBOOKS:
        executed = work / notebook.name
        out = _run([str(py), "-c", RUN_NOTEBOOK, notebook, executed, work], cwd=work, env=env, timeout=900)
        printed = out.stdout.strip().splitlines()
        assert printed, f"{notebook.name}: the probe cell printed nothing:\n{out.stderr[-3000:]}"
        _check_run(notebook.name, json.loads(printed[-1]), venv, executed)


def _check_run(name: str, facts: dict, venv: Path, executed: Path) -> None:
    """The notebook ran in the fresh environment, on its own install, every cell without error."""
    assert Path(facts["prefix"]) == venv, f"{name} ran in another Python"
    assert Path(facts["labsupport"]).is_relative_to(venv), (
        f"{name}: labsupport came from {facts['labsupport']}, not from the fresh install"
    )
    assert Path(facts["model"]).is_relative_to(venv) and Path(facts["model"]).is_file()
    nb = nbformat.read(str(executed), as_version=4)
    code = [c for c in nb.cells if c.cell_type == "code"]
    outputs = [o for c in code for o in c.get("outputs", [])]
    errors = [o for o in outputs if o.get("output_type") == "error"]
    assert not errors, f"{name} raised: {errors[0].get('ename')}: {errors[0].get('evalue')}"
    assert all(c.get("execution_count") for c in code), f"not every cell of {name} ran"
    if name == "task4_ur5e.ipynb":  # its two videos, rendered offscreen in the fresh environment
        html = [o["data"]["text/html"] for o in outputs if "text/html" in o.get("data", {})]
        assert sum("<video" in h for h in html) == 2, "Task 4 did not show its two videos"
