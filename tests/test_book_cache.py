"""The book's build re-executes its notebooks exactly when what they run has changed.

``bash .ci/build-book`` keeps executed notebooks in jupyter-cache, which only knows a notebook's
code cells; ``.ci/source-hash`` covers what those cells run (labsupport/, models/, the pins), and
a change to it empties the cache. The first tests check the hash on a copy of those inputs; the
last runs the README's build command three times on a small copy of the book (the home page and
one notebook that prints a value read from labsupport) and reads jupyter-cache's records.
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


def tracked_copy(dest: Path, *paths: str) -> Path:
    """Copy the repository's tracked files (under ``paths``, or all) into ``dest``."""
    files = subprocess.run(
        ["git", "ls-files", "-z", "--", *paths], cwd=ROOT, capture_output=True, check=True
    ).stdout.split(b"\0")
    for name in filter(None, (f.decode() for f in files)):
        if (ROOT / name).is_file():
            (dest / name).parent.mkdir(parents=True, exist_ok=True)
            shutil.copy2(ROOT / name, dest / name)
    return dest


def source_hash(root: Path) -> str:
    return subprocess.run(["bash", ".ci/source-hash"], cwd=root, capture_output=True, text=True, check=True).stdout


@pytest.fixture()
def inputs(tmp_path):
    inputs = (".ci", "labsupport", "models", "book", "notebooks", "requirements.txt", "pyproject.toml")
    return tracked_copy(tmp_path, *inputs)


@pytest.mark.parametrize(
    "change",
    [
        lambda r: (r / "labsupport" / "plants.py").write_text(
            (r / "labsupport" / "plants.py").read_text() + "\n# a comment\n"
        ),
        lambda r: (r / "models" / "extra_mesh.stl").write_bytes(b"solid x\nendsolid x\n"),
        lambda r: (r / "labsupport" / "data.json").write_text("{}"),
        lambda r: (r / "requirements.txt").write_text((r / "requirements.txt").read_text() + "tqdm==4.70.1\n"),
    ],
    ids=["labsupport code", "a new file under models", "a non-Python file in labsupport", "the pins"],
)
def test_what_the_notebooks_run_changes_the_hash(inputs, change):
    before = source_hash(inputs)
    change(inputs)
    assert source_hash(inputs) != before


@pytest.mark.parametrize(
    "change",
    [
        lambda r: (r / "book" / "intro.md").write_text((r / "book" / "intro.md").read_text() + "\nMore prose.\n"),
        lambda r: (
            (r / "labsupport" / "__pycache__").mkdir(exist_ok=True)
            or (r / "labsupport" / "__pycache__" / "plants.cpython-311.pyc").write_bytes(b"\0" * 16)
        ),
        lambda r: (r / "models" / "MUJOCO_LOG.TXT").write_text("WARNING: ...\n"),
        lambda r: (r / "notebooks" / "task1_single_joint.ipynb").write_text(
            (r / "notebooks" / "task1_single_joint.ipynb").read_text().replace("PI speed", "PI-speed")
        ),
    ],
    ids=["prose", "bytecode from an import", "MuJoCo's log", "a notebook's text"],
)
def test_prose_and_run_time_files_leave_the_hash_alone(inputs, change):
    before = source_hash(inputs)
    change(inputs)
    assert source_hash(inputs) == before


PROBE = {
    "cells": [
        {"cell_type": "markdown", "id": "probe-md", "metadata": {}, "source": ["# Cache probe\n"]},
        {
            "cell_type": "code",
            "execution_count": None,
            "id": "probe-code",
            "metadata": {},
            "outputs": [],
            "source": [
                "import labsupport.plants\n",
                'print("probe value:", getattr(labsupport.plants, "CACHE_PROBE", "original"))\n',
                'print("package at:", labsupport.plants.__file__)',
            ],
        },
    ],
    "metadata": {"kernelspec": {"display_name": "Python 3", "language": "python", "name": "python3"}},
    "nbformat": 4,
    "nbformat_minor": 5,
}


def build(book: Path) -> str:
    env = {**os.environ, "PYTHONPATH": str(book)}  # the kernel imports the copy's labsupport
    run = subprocess.run(["bash", ".ci/build-book"], cwd=book, env=env, capture_output=True, text=True, check=False)
    assert run.returncode == 0, run.stdout[-3000:] + run.stderr[-3000:]
    return (book / "_build" / "html" / "notebooks" / "cache_probe.html").read_text(encoding="utf-8")


def executions(book: Path) -> list[str]:
    """When jupyter-cache stored each executed notebook (a new record per execution)."""
    from jupyter_cache import get_cache

    return sorted(str(r.created) for r in get_cache(book / "_build" / ".jupyter_cache").list_cache_records())


def test_the_build_re_executes_after_a_code_change_and_only_then(tmp_path):
    if not (ROOT / ".venv" / "bin" / "jupyter-book").exists():
        pytest.skip("needs the .venv that .ci/setup creates")
    book = tracked_copy(tmp_path / "book")
    (book / ".venv").symlink_to(ROOT / ".venv")
    (book / "_toc.yml").write_text("format: jb-book\nroot: book/intro\nchapters:\n  - file: notebooks/cache_probe\n")
    (book / "notebooks" / "cache_probe.ipynb").write_text(json.dumps(PROBE))
    (book / "book" / "intro.md").write_text("# Cache test\n\nFirst words.\n")

    page = build(book)
    first = executions(book)
    assert len(first) == 1 and "probe value: original" in page
    assert str(book / "labsupport") in page  # the copy's package ran, not the checkout's

    (book / "book" / "intro.md").write_text("# Cache test\n\nOther words.\n")
    build(book)
    assert executions(book) == first, "a prose-only change re-executed the notebook"
    assert "Other words." in (book / "_build" / "html" / "book" / "intro.html").read_text(encoding="utf-8")

    plants = book / "labsupport" / "plants.py"
    plants.write_text(plants.read_text() + '\nCACHE_PROBE = "changed"\n')
    page = build(book)
    again = executions(book)
    assert len(again) == 1 and again != first, "a change to labsupport did not re-execute the notebook"
    assert "probe value: changed" in page
