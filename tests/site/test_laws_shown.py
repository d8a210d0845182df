"""Every Task page, as built, shows the code of every control law it runs.

A Task notebook runs laws it imports from ``labsupport.controllers``; each of them must be shown
on the page with ``labsupport.book.show_law``, so the built HTML holds a highlighted code block
with that function's ``def``. The code comes from the package itself, so it is compared with
the installed function's source less its docstring (``labsupport.book.law_source``; the page
writes the law's equation in Markdown above the code): page and package cannot disagree on the
code.

Every notebook page also reads without scrolling sideways at common window widths: the laws,
the unfolded code cells and the printouts; and so do the display equations of every page.
"""

from __future__ import annotations

import ast
import importlib
import inspect
import json
import re

import pytest
from bs4 import BeautifulSoup
from sitetools import ROOT, WIDTHS, require_site

from labsupport.book import law_source

TASKS = ["task1_single_joint", "task2_single_joint_mujoco", "task3_planar_2r", "task4_ur5e"]
CONTROLLERS = "labsupport.controllers"


def _code(notebook: str) -> str:
    nb = json.loads((ROOT / "notebooks" / f"{notebook}.ipynb").read_text(encoding="utf-8"))
    cells = ["".join(c["source"]) for c in nb["cells"] if c["cell_type"] == "code"]
    # IPython magics and shell escapes are not Python
    return "\n".join(line for cell in cells for line in cell.splitlines() if not line.lstrip().startswith(("%", "!")))


def laws_run(notebook: str) -> dict[str, object]:
    """The controller functions a notebook uses: ``{name: function}``, from its imports of
    ``labsupport.controllers`` (``from ... import f`` or a module alias used as ``alias.f``)."""
    tree = ast.parse(_code(notebook))
    functions: dict[str, object] = {}
    aliases: dict[str, object] = {}
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom) and node.module and node.module.startswith(CONTROLLERS):
            module = importlib.import_module(node.module)
            for a in node.names:
                obj = getattr(module, a.name, None)
                if obj is None:
                    obj = importlib.import_module(f"{node.module}.{a.name}")
                (aliases if inspect.ismodule(obj) else functions)[a.asname or a.name] = obj
        elif isinstance(node, ast.Import):
            for a in node.names:
                if a.name.startswith(CONTROLLERS) and a.asname:
                    aliases[a.asname] = importlib.import_module(a.name)
    for node in ast.walk(tree):
        if isinstance(node, ast.Attribute) and isinstance(node.value, ast.Name) and node.value.id in aliases:
            obj = getattr(aliases[node.value.id], node.attr, None)
            if inspect.isfunction(obj):
                functions[node.attr] = obj
    return {name: f for name, f in functions.items() if inspect.isfunction(f)}


def shown_code_blocks(notebook: str) -> list[str]:
    html = (require_site() / "notebooks" / f"{notebook}.html").read_text(encoding="utf-8")
    soup = BeautifulSoup(html, "html.parser")
    return [block.get_text() for block in soup.select("main div.highlight pre")]


@pytest.mark.parametrize("notebook", TASKS)
def test_every_law_run_is_shown(notebook):
    laws = laws_run(notebook)
    assert laws, f"{notebook} runs no law from {CONTROLLERS}: the test's parser found nothing"
    blocks = shown_code_blocks(notebook)
    missing = []
    for fn in laws.values():
        source = law_source(fn).strip()
        if not any(source in re.sub(r"\r\n", "\n", b) for b in blocks):
            missing.append(f"{fn.__module__}.{fn.__name__}")
    assert not missing, (
        f"{notebook}: the page runs these laws but does not show their current code "
        f"(use labsupport.book.show_law): {missing}"
    )


#: Every notebook page: the Tasks and the Problems as students get them.
PAGES = TASKS + ["problem1_reaching", "problem2_tracking"]

WIDE_CODE_JS = """() => [...document.querySelectorAll('main div.cell:not(.tag_hide-input) pre')]
  .map(pre => ({head: pre.textContent.split('\\n')[0].slice(0, 60),
                output: pre.closest('div.cell_output') !== null,
                scroll: pre.scrollWidth, width: pre.clientWidth}))"""


@pytest.mark.parametrize("width", WIDTHS)
@pytest.mark.parametrize("notebook", PAGES)
def test_code_reads_without_scrolling_sideways(tab_page, notebook, width):
    """What a reader sees without unfolding anything shows its whole width: the code cells
    that run the lab (the figure cells, plotting and the figure's text alternative, are
    folded away with ``hide-input`` and may be wider), the code of every law the page runs
    (the laws keep to 85 columns; course.css leaves a code block room for 85 from 1024 px
    wide windows up), and what the cells print (course.css wraps printed text at the page's
    width)."""
    blocks = tab_page(f"notebooks/{notebook}", width).evaluate(WIDE_CODE_JS)
    inputs = [b for b in blocks if not b["output"]]
    outputs = [b for b in blocks if b["output"]]
    assert len(inputs) > 5 and len(outputs) > 3, (
        f"{notebook}: found only {len(inputs)} unfolded code cells and {len(outputs)} printouts"
    )
    laws = sorted(laws_run(notebook)) if notebook in TASKS else []
    unchecked = [n for n in laws if not any(b["head"].startswith(f"def {n}(") for b in outputs)]
    assert not unchecked, f"{notebook}: these laws' code is not among the blocks checked: {unchecked}"
    wide = [b for b in blocks if b["scroll"] > b["width"] + 1]
    assert not wide, f"{notebook} at {width} px: code or printout scrolls sideways: {wide}"


WIDE_MATH_JS = """() => {
  const shown = [...document.querySelectorAll('main mjx-container[display="true"]')];
  const listings = [...document.querySelectorAll('main pre')].filter(p => !p.closest('div.cell'));
  const cut = e => e.scrollWidth > e.clientWidth + 1;
  return {count: shown.length,
          cut: shown.filter(cut).map(m => (m.querySelector('mjx-assistive-mml') || m).textContent.slice(0, 60))
               .concat(listings.filter(cut).map(p => p.textContent.slice(0, 60)))};
}"""


#: Equations must also fit a tablet held upright (768 px) and the narrowest window that shows
#: the navigation sidebar (960 px); the code cells need at least 1024 px for 85 columns.
EQUATION_WIDTHS = (768, 960, *WIDTHS)


@pytest.mark.parametrize("width", EQUATION_WIDTHS)
def test_equations_and_listings_read_without_scrolling_sideways(on_every_page, width):
    """No display equation of any page is cut off at the page's edge (MathJax then shows
    a scroll bar inside the equation, and a reader sees half a formula). Long ones are
    broken into lines (``gathered``/``aligned``). The same for the listings of the
    Markdown pages (shell commands, file trees); the notebooks' cells are checked above."""
    found = on_every_page(WIDE_MATH_JS, width)
    equations = sum(f["count"] for f in found.values())
    wide = {page: f["cut"] for page, f in found.items() if f["cut"]}
    assert equations > 50, f"found only {equations} display equations on the site's pages"
    assert not wide, f"at {width} px these display equations or listings scroll sideways: {wide}"
