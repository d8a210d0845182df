"""Conventions every notebook follows, shared by the tests and by whoever writes a notebook.

* The first code cell is :func:`install_cell_source` with the repository URL of ``_config.yml``,
  tagged ``hide-input`` and ``remove-output``: where labsupport is missing (a fresh Colab
  runtime, a downloaded notebook) it installs it; where it is installed it does nothing.
* Notebooks are committed without outputs; the book build and nbval execute them.
"""

from __future__ import annotations

from pathlib import Path

import nbformat

ROOT = Path(__file__).resolve().parents[1]
INSTALL_CELL_TAGS = ["hide-input", "remove-output"]


def _repository() -> dict:
    """The ``repository`` section of ``_config.yml``, where the URL and branch are set once."""
    import yaml  # the book's tools have it; the tests of the oldest versions, which import this module, need not

    return yaml.safe_load((ROOT / "_config.yml").read_text(encoding="utf-8"))["repository"]


def repository_url() -> str:
    """The repository URL, set once in ``_config.yml``."""
    return _repository()["url"].rstrip("/")


def repository_branch() -> str:
    """The branch the notebooks install from, set once in ``_config.yml`` (``main`` if unset)."""
    return _repository().get("branch", "main")


def archive_url(url: str, branch: str | None = None) -> str:
    """GitHub's zip of the tip of ``branch`` (the configured one by default): pip builds a
    package from it without ``git``."""
    return f"{url}/archive/refs/heads/{branch or repository_branch()}.zip"


def install_cell_source(url: str | None = None, branch: str | None = None) -> str:
    """The exact source of every notebook's first cell."""
    url = url or repository_url()
    return (
        "# Set-up: where labsupport is missing (a fresh Colab runtime, a downloaded notebook),\n"
        "# install it with its models and the packages it needs from the course repository.\n"
        "# Where it is installed already, this cell does nothing.\n"
        "import importlib, importlib.util, subprocess, sys\n"
        'if importlib.util.find_spec("labsupport") is None:\n'
        '    subprocess.run([sys.executable, "-m", "pip", "install", "-q",\n'
        f'                    "labsupport @ {archive_url(url, branch)}"], check=True)\n'
        "    importlib.invalidate_caches()"
    )


def install_cell() -> nbformat.NotebookNode:
    """A fresh install cell, tagged for the book."""
    cell = nbformat.v4.new_code_cell(install_cell_source())
    cell.metadata["tags"] = list(INSTALL_CELL_TAGS)
    return cell


def notebook_paths(include_masters: bool = True) -> list[Path]:
    """Every notebook of the course, students' first, then the Problems' masters."""
    paths = sorted((ROOT / "notebooks").glob("*.ipynb"))
    if include_masters:
        paths += sorted((ROOT / "notebooks" / "masters").glob("*.ipynb"))
    return paths


def save_without_outputs(nb: nbformat.NotebookNode, path: Path) -> None:
    """Write a notebook with outputs and execution counts stripped (how they are committed)."""
    for cell in nb.cells:
        if cell.cell_type == "code":
            cell.outputs = []
            cell.execution_count = None
    nb.metadata.setdefault("kernelspec", {"name": "python3", "display_name": "Python 3", "language": "python"})
    nbformat.write(nb, str(path))


def sync_install_cells() -> list[Path]:
    """Rewrite every notebook's first code cell from ``_config.yml`` (after the repository moved).

    Returns the notebooks that changed. The Problems' student notebooks are generated from the
    masters, so run ``python -m labsupport.instructor.assign`` afterwards.
    """
    changed = []
    for path in notebook_paths():
        nb = nbformat.read(str(path), as_version=4)
        first = next(c for c in nb.cells if c.cell_type == "code")
        if first.source != install_cell_source() or first.metadata.get("tags") != INSTALL_CELL_TAGS:
            first.source = install_cell_source()
            first.metadata["tags"] = list(INSTALL_CELL_TAGS)
            nbformat.write(nb, str(path))
            changed.append(path)
    return changed


if __name__ == "__main__":
    for changed_path in sync_install_cells():
        print(f"updated the install cell of {changed_path.relative_to(ROOT)}")


#: Where Colab installs labsupport: a law compiled there names this file, not this checkout's.
COLAB_SITE_PACKAGES = "/usr/local/lib/python3.13/dist-packages"


def carried_code(fn, site_packages: str = COLAB_SITE_PACKAGES, filename: str | None = None) -> str:
    """``fn``'s code as a student may carry it from their own installation into a notebook:
    marshalled and base64-encoded, every code object in it naming the file that installation
    holds (``site_packages/labsupport/...``), or ``filename`` when given (a made-up one, such as
    ``"<lab notes>"``). It loads only on this Python version, so tests make it when they run
    rather than commit it."""
    import base64
    import marshal

    package = Path(__import__("labsupport").__file__).resolve().parent
    if filename is None:
        filename = f"{site_packages}/labsupport/{Path(fn.__code__.co_filename).resolve().relative_to(package)}"

    def moved(code):
        consts = tuple(moved(c) if hasattr(c, "co_filename") else c for c in code.co_consts)
        return code.replace(co_filename=filename, co_consts=consts)

    return base64.b64encode(marshal.dumps(moved(fn.__code__))).decode()


def settings_of(notebook: str, first_name: str) -> dict:
    """The settings that open the code cell of ``notebooks/<notebook>`` whose source starts with
    ``first_name`` (:func:`labsupport.instructor.assign.cell_settings`). A test compares them with
    the values it pins, so that a setting changed in the notebook is caught there, and not only as
    a number that moved."""
    from labsupport.instructor.assign import cell_settings

    return cell_settings(nbformat.read(ROOT / "notebooks" / notebook, as_version=4), first_name, notebook)
