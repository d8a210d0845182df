"""The notebooks read without scrolling sideways: every line of a code cell the page
shows unfolded keeps to 85 columns, the width a code block of the built site shows from
1024 px wide windows up (the laws keep to the same width, ``labsupport/controllers/ruff.toml``).
That holds for the Tasks, the Problems as students get them, and the Problems' masters (an
instructor reads them beside the students' pages).

Cells tagged ``hide-input`` (the set-up cell, and the figure cells: plotting and each
figure's text alternative) are folded on the page and may be wider.
"""

from __future__ import annotations

import json
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
NOTEBOOKS = sorted((ROOT / "notebooks").glob("*.ipynb")) + sorted((ROOT / "notebooks" / "masters").glob("*.ipynb"))
WIDTH = 85


def folded(cell) -> bool:
    """The page folds the cell's code away (its output stays)."""
    return "hide-input" in cell["metadata"].get("tags", [])


@pytest.mark.parametrize("path", NOTEBOOKS, ids=lambda p: p.relative_to(ROOT / "notebooks").as_posix())
def test_shown_code_keeps_to_85_columns(path):
    assert len(NOTEBOOKS) == 8
    cells = json.loads(path.read_text(encoding="utf-8"))["cells"]
    shown = [c for c in cells if c["cell_type"] == "code" and not folded(c)]
    assert len(shown) > 5
    wide = [
        (index, line)
        for index, cell in enumerate(shown)
        for line in "".join(cell["source"]).splitlines()
        if len(line) > WIDTH
    ]
    assert not wide, f"{path.name}: shown code lines wider than {WIDTH} columns: {wide}"


@pytest.mark.parametrize("path", NOTEBOOKS, ids=lambda p: p.relative_to(ROOT / "notebooks").as_posix())
def test_every_figure_cell_is_folded(path):
    """A cell that draws a Matplotlib figure with its text alternative is folded, so the page
    reads like the lab: the runs and their numbers, then the figure."""
    cells = json.loads(path.read_text(encoding="utf-8"))["cells"]
    drawing = [c for c in cells if c["cell_type"] == "code" and "show_figure(fig" in "".join(c["source"])]
    assert drawing
    unfolded = ["".join(c["source"]).splitlines()[0] for c in drawing if not folded(c)]
    assert not unfolded, f"{path.name}: figure cells shown unfolded: {unfolded}"
