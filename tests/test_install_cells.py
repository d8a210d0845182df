"""Every notebook starts with the same install cell, built from the repository URL of
``_config.yml``: it installs labsupport where it is missing (Colab), does nothing where it is
installed, and is hidden on the page."""

from __future__ import annotations

import subprocess
import sys
from unittest import mock

import nbformat
import nbtools
import pytest
import yaml

NOTEBOOKS = nbtools.notebook_paths()


def first_code_cell(path):
    nb = nbformat.read(str(path), as_version=4)
    cells = [c for c in nb.cells if c.cell_type == "code"]
    assert cells, f"{path.name} has no code cell"
    return nb, cells[0]


def test_there_are_notebooks():
    assert len(nbtools.notebook_paths(include_masters=False)) >= 6


@pytest.mark.parametrize("path", NOTEBOOKS, ids=lambda p: p.name)
def test_install_cell_matches_config(path):
    nb, cell = first_code_cell(path)
    assert nb.cells[0].cell_type == "markdown" and nb.cells[0].source.lstrip().startswith("#"), (
        f"{path.name}: the first cell must be the markdown title"
    )
    assert cell.source == nbtools.install_cell_source(), (
        f"{path.name}: first code cell differs from nbtools.install_cell_source(); regenerate it"
    )


@pytest.mark.parametrize("path", NOTEBOOKS, ids=lambda p: p.name)
def test_install_cell_is_hidden(path):
    _, cell = first_code_cell(path)
    tags = set(cell.metadata.get("tags", []))
    assert set(nbtools.INSTALL_CELL_TAGS) <= tags, f"{path.name}: install cell tags {sorted(tags)}"
    assert tags & {"hide-input", "remove-input", "remove-cell"}, f"{path.name}: source shown"
    assert tags & {"remove-output", "hide-output", "remove-cell"}, f"{path.name}: output shown"


def test_install_cell_uses_the_configured_repository():
    config = yaml.safe_load((nbtools.ROOT / "_config.yml").read_text(encoding="utf-8"))
    url = config["repository"]["url"].rstrip("/")
    branch = config["repository"].get("branch", "main")
    source = nbtools.install_cell_source()
    assert f"labsupport @ {url}/archive/refs/heads/{branch}.zip" in source
    # One place: changing the URL in _config.yml changes the cell.
    other = nbtools.install_cell_source("https://github.com/someone/else")
    assert "https://github.com/someone/else/archive/refs/heads/main.zip" in other and url not in other


def _run_install_cell(installed: bool) -> list:
    """Execute the install cell with ``subprocess.run`` recorded instead of run, and with
    labsupport found or not found by the import system."""
    import importlib.util

    calls = []

    def fake_run(args, **kwargs):
        calls.append((args, kwargs))
        return subprocess.CompletedProcess(args, 0)

    real_find_spec = importlib.util.find_spec

    def fake_find_spec(name, *args, **kwargs):
        if name == "labsupport":
            return real_find_spec(name) if installed else None
        return real_find_spec(name, *args, **kwargs)

    with mock.patch.object(subprocess, "run", fake_run), mock.patch.object(importlib.util, "find_spec", fake_find_spec):
        exec(compile(nbtools.install_cell_source(), "<install cell>", "exec"), {})
    return calls


def test_install_cell_does_nothing_where_labsupport_is_installed():
    assert _run_install_cell(installed=True) == []


def test_install_cell_installs_labsupport_where_it_is_missing():
    """A fresh Colab runtime (or a downloaded notebook in a bare environment)."""
    calls = _run_install_cell(installed=False)
    assert len(calls) == 1
    args, kwargs = calls[0]
    assert args[:4] == [sys.executable, "-m", "pip", "install"]
    spec = args[-1]
    assert spec == f"labsupport @ {nbtools.repository_url()}/archive/refs/heads/main.zip"
    assert kwargs.get("check") is True, "a failed install must stop the notebook"


def test_the_colab_links_of_the_readme_and_the_home_page_open_the_configured_repository():
    """Moving the repository meant editing the Colab links of README.md and book/intro.md by hand,
    and no test read the README's: every Colab link there must open a notebook of the repository
    and branch that _config.yml names, and one that exists."""
    import re

    owner_repo = nbtools.repository_url().removeprefix("https://github.com/")
    prefix = f"https://colab.research.google.com/github/{owner_repo}/blob/{nbtools.repository_branch()}/"
    for page in ("README.md", "book/intro.md"):
        links = re.findall(
            r"https://colab\.research\.google\.com/github/[^\s)`>\]]+", (nbtools.ROOT / page).read_text()
        )
        assert links, f"{page} has no Colab link"
        for link in links:
            assert link.startswith(prefix), f"{page}: {link} does not open {prefix}… (_config.yml's repository)"
            assert (nbtools.ROOT / link.removeprefix(prefix)).is_file(), f"{page}: {link} opens no notebook of ours"
