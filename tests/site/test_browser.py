"""Every page of the built site, as a reader's browser (headless Chromium) shows it."""

from __future__ import annotations

import json
import re
from pathlib import Path

import pytest
from sitetools import ARTIFACTS, SCREENSHOT_PAGES, WIDTHS, expected_colab_url, is_notebook, require_site, toc_pages

PAGES = toc_pages()
NOTEBOOK_PAGES = [p for p in PAGES if is_notebook(p)]
COLAB = "https://colab.research.google.com/"


def test_toc_lists_every_notebook():
    """Each notebook of notebooks/ is a page of the book (so it gets its launch buttons)."""
    root = Path(__file__).resolve().parents[2]
    on_disk = {f"notebooks/{p.stem}" for p in (root / "notebooks").glob("*.ipynb")}
    assert on_disk <= set(PAGES), f"notebooks missing from _toc.yml: {sorted(on_disk - set(PAGES))}"


@pytest.mark.parametrize("page", PAGES)
def test_page_is_built(page):
    site = require_site()
    assert (site / f"{page}.html").is_file(), f"{page}.html missing from the built site"


@pytest.mark.parametrize("page", PAGES)
def test_no_console_errors(visit, page):
    r = visit(page)
    problems = (
        [f"console: {m}" for m in r.console_errors]
        + [f"uncaught: {m}" for m in r.page_errors]
        + [f"request failed: {m}" for m in r.failed_requests]
        + [f"external request (site must load offline, MathJax excepted): {u}" for u in r.external_requests]
    )
    assert not problems, f"{page}:\n  " + "\n  ".join(problems)


@pytest.mark.parametrize("page", PAGES)
def test_mathjax_rendered(visit, page):
    m = visit(page).math
    if m["nMath"]:
        assert m["hasMathJax"], f"{page} has {m['nMath']} formulas but MathJax did not load"
    assert not m["untypeset"], f"{page}: formulas MathJax left untypeset: {m['untypeset'][:5]}"
    assert not m["merrors"], f"{page}: TeX errors: {m['merrors'][:5]}"
    assert not m["raw"], f"{page}: raw TeX left in the text: {m['raw'][:5]}"
    assert m["nTypeset"] >= m["nMath"]


def test_theory_equations_are_numbered(visit):
    """The theory page's labelled equations render with their numbers (what notebooks cite)."""
    m = visit("book/theory").math
    assert m["nMath"] >= 20 and m["nTypeset"] >= m["nMath"]
    site = require_site()
    html = (site / "book" / "theory.html").read_text(encoding="utf-8")
    for label in ("eq-sj-model", "eq-pd-gains", "eq-ffpd", "eq-js-ct", "eq-os-ct", "eq-task-inertia"):
        assert f'id="equation-{label}"' in html, label


@pytest.mark.parametrize("page", PAGES)
def test_images_loaded(visit, page):
    imgs = visit(page).images
    assert not imgs["bad"], f"{page}: images that did not load: {imgs['bad']}"


@pytest.mark.parametrize("page", PAGES)
def test_videos_play(visit, page):
    for v in visit(page).videos:
        assert v["error"] is None, f"{page}: video {v['src']} failed to load (MediaError {v['error']})"
        assert v["duration"] and v["duration"] > 0 and v["duration"] != float("inf"), (
            f"{page}: video {v['src']} has duration {v['duration']}"
        )
        assert v["played"], f"{page}: video {v['src']} did not play ({v['playError']})"
        assert v["type"] in ("video/mp4", ""), f"{page}: video {v['src']} is {v['type']}, not MP4"


@pytest.mark.parametrize("page", PAGES)
def test_videos_wait_for_the_reader(page):
    """No video starts by itself (WCAG 2.2.2); each has its own controls."""
    html = (require_site() / f"{page}.html").read_text(encoding="utf-8")
    for tag in re.findall(r"<video\b[^>]*>", html):
        assert "autoplay" not in tag and "controls" in tag, f"{page}: {tag[:120]}"


@pytest.mark.parametrize("page", NOTEBOOK_PAGES)
def test_launch_buttons(visit, page):
    """The Colab button opens this notebook from the repository of ``_config.yml``; the
    download button serves the notebook itself."""
    links = visit(page).links
    colab = [link["href"] for link in links if link["href"].startswith(COLAB)]
    assert colab, f"{page}: no Colab launch button"
    assert set(colab) == {expected_colab_url(page)}, f"{page}: Colab links {colab}"
    downloads = [
        link
        for link in links
        if link["href"].endswith(".ipynb") and "download" in (link["title"] + link["cls"]).lower()
    ]
    assert downloads, f"{page}: no .ipynb download button"
    site = require_site()
    for link in downloads:
        target = (site / page).parent / link["href"]
        nb = json.loads(target.resolve().read_text(encoding="utf-8"))
        assert nb["nbformat"] == 4 and nb["cells"], f"{page}: download {link['href']} is not a notebook"


@pytest.mark.parametrize("page", PAGES)
def test_colab_links_point_at_notebooks(visit, page):
    """Every Colab link anywhere (e.g. the home page's table) opens an existing notebook."""
    valid = {expected_colab_url(p) for p in NOTEBOOK_PAGES}
    for link in visit(page).links:
        if link["href"].startswith(COLAB):
            assert link["href"] in valid, f"{page}: Colab link {link['href']} opens no notebook"


def test_home_page_opens_every_notebook_in_one_click(visit):
    """A reader goes from the home page to Colab for every task and problem in one click."""
    home = toc_pages()[0]
    hrefs = {link["href"] for link in visit(home).links}
    missing = [p for p in NOTEBOOK_PAGES if expected_colab_url(p) not in hrefs]
    assert not missing, f"home page has no Colab link for {missing}"


def test_install_cell_hidden_on_pages():
    """The install cell's source sits in a collapsed toggle and its output is removed."""
    site = require_site()
    for page in NOTEBOOK_PAGES:
        html = (site / f"{page}.html").read_text(encoding="utf-8")
        i = html.find("find_spec")
        assert i > 0, f"{page}: install cell missing"
        start = html.rfind('<div class="cell ', 0, i)
        tag = html[start : html.find(">", start)]
        assert "tag_hide-input" in tag or "tag_remove-input" in tag, f"{page}: install cell not hidden ({tag})"
        end = html.find('<div class="cell ', i)
        assert "cell_output" not in html[i : end if end > 0 else None], f"{page}: install cell shows output"


def test_screenshots_saved(visit):
    """Screenshots of a few pages are kept under tests/artifacts/screenshots for review."""
    for page in SCREENSHOT_PAGES:
        visit(page)
        shot = ARTIFACTS / "screenshots" / f"{page.replace('/', '__')}.png"
        assert shot.is_file() and shot.stat().st_size > 10_000, shot


VISIBLE_SEARCH_JS = """() => [...document.querySelectorAll('.search-button-field')]
  .filter(e => e.offsetParent !== null && e.getBoundingClientRect().width > 0).length"""


@pytest.mark.parametrize("width", WIDTHS)
def test_one_search_field(tab_page, width):
    """The sidebar holds the search field; the theme must not add a second one in a top bar."""
    visible = tab_page("notebooks/task1_single_joint", width).evaluate(VISIBLE_SEARCH_JS)
    assert visible == 1, f"{visible} search fields visible at {width} px"


@pytest.mark.parametrize(
    ("query", "stem"), [("gravity", "gravit"), ("computed torque", "comput"), ("sinusoid", "sinusoid")]
)
def test_search_results_quote_the_text_around_the_word(tab_page, query, stem):
    """Every result of a search quoted the page's header ("...Colab", "....md"): Sphinx looks for
    the stemmed word ("graviti") as written, in a block that starts with the header's buttons.
    The quotes come from the article now, around the word, with each formula's TeX read as text
    (book/_static/course.js)."""
    tab = tab_page("search")
    tab.goto(f"{tab.url}?q={query}")
    tab.wait_for_function("() => /Search finished/.test(document.querySelector('p.search-summary')?.textContent)")
    # each result's quote comes once its page is fetched, after the status line says "finished"
    tab.wait_for_function(
        "() => [...document.querySelectorAll('ul.search > li')].every(li => li.querySelector('p.context'))"
    )
    quotes = tab.locator("ul.search p.context").all_text_contents()
    assert len(quotes) >= 3, quotes
    for quote in quotes:
        assert stem in quote.lower() and len(quote) > 100, quote
        assert not re.search(r"\\[a-zA-Z(\[]|\$\$|&|\b(aligned|split|bmatrix)\b", quote), f"TeX in the quote: {quote}"
    # for a screen reader: how the search went is a status; the focus is in the page's search field
    assert tab.get_attribute("p.search-summary", "role") == "status"
    assert tab.evaluate(
        "() => document.activeElement.closest('dialog') === null && document.activeElement.name === 'q'"
    )
    assert tab.get_attribute("#pst-search-dialog", "aria-label") == "Search this book"


def test_formulas_in_search_quotes_read_as_text(tab_page):
    """Accents were dropped (h(θ, θ̇) read h(θ, θ)) and environments' names and & signs left in."""
    tab = tab_page("search")
    said = tab.evaluate(
        "() => [texAsText('\\\\(\\\\tau = M\\\\ddot\\\\theta + h(\\\\theta,\\\\dot{\\\\theta})\\\\)'), "
        "texAsText('\\\\begin{aligned} x &= \\\\frac{\\\\pi}{4} \\\\end{aligned}'), "
        "texAsText('designed for \\\\(\\\\zeta = 1\\\\). Critical \\\\(\\\\theta\\\\), and')]"
    )
    assert said == ["τ = M θ̈ + h(θ, θ̇)", "x = π/4", "designed for ζ = 1. Critical θ, and"], said


def test_a_heading_in_a_search_quote_is_set_off_from_the_text_after_it(tab_page):
    """A section's quote read "1.2 PD position control The arm ...", the heading run into the text."""
    tab = tab_page("search")
    said = tab.evaluate(
        '() => Search.makeSearchSummary(\'<article><h2>PD control<a class="headerlink">#</a></h2>'
        "<p>The arm settles.</p></article>', ['arm'], '').textContent"
    )
    assert said == "PD control — The arm settles.", said


def test_a_search_that_finds_nothing_says_so_without_categories(tab_page):
    tab = tab_page("search")
    tab.goto(f"{tab.url}?q=nonsenseword")
    tab.wait_for_function("() => /No page matches/.test(document.querySelector('p.search-summary')?.textContent)")
    assert "categories" not in tab.inner_text("#search-results")


#: The headings whose theme anchor ("#", hidden until hover or focus) sits below their text, on
#: a line of its own: the reader sees an empty line under the heading.
LONE_ANCHORS_JS = """() => {
  const bottom = (node) => {
    const range = document.createRange();
    range.selectNodeContents(node);
    return Math.max(0, ...[...range.getClientRects()].map((r) => r.bottom));
  };
  const lone = [];
  for (const h of document.querySelectorAll("main h1, main h2, main h3, main h4")) {
    const anchor = h.querySelector("a.headerlink");
    if (!anchor) continue;
    const text = Math.max(...[...h.childNodes].filter((n) => n !== anchor).map(bottom));
    if (anchor.getBoundingClientRect().top >= text - 2) lone.push(h.textContent.replace(anchor.textContent, "").trim());
  }
  return lone;
}"""


@pytest.mark.parametrize("width", WIDTHS)
def test_no_empty_line_under_a_heading(on_every_page, width):
    """A heading that fills its line keeps its hidden anchor at the end of that line; an anchor
    pushed onto a line of its own leaves a gap under the heading (the phones' rule in
    course.css must stay on phones)."""
    found = on_every_page(LONE_ANCHORS_JS, width)
    lone = {page: headings for page, headings in found.items() if headings}
    assert not lone, f"at {width} px these headings have an empty line under them: {lone}"


#: ``[natural width, width drawn for, shown width, start of the alt text]`` of every figure a
#: notebook cell shows; "drawn for" is the ``width`` the image asks for, in CSS pixels.
FIGURE_SCALE_JS = r"""async () => {
  const out = [];
  for (const img of document.querySelectorAll('.cell_output img')) {
    img.loading = 'eager';
    try { await img.decode(); } catch (e) {}
    const asked = Number(img.getAttribute('width')) || img.naturalWidth;
    out.push([img.naturalWidth, asked, img.getBoundingClientRect().width, (img.alt || '').slice(0, 50)]);
  }
  return out;
}"""


def test_figures_show_at_their_own_size(on_every_page):
    """On a screen 1280 px wide every figure fits the text column as drawn, so its tick labels
    and legends keep the size Matplotlib gave them (labsupport.plots.column_width); the circle
    figure of Task 3 and the two-panel figures of Tasks 1, 2 and 4 used to be shrunk to 78-85 %.
    Each Matplotlib figure carries twice the pixels it is shown with (labsupport.book.PIXEL_DENSITY),
    so it stays sharp on a phone's screen and when zoomed in, and so does each rendered picture of a
    model whose offscreen buffer holds it (labsupport.render.show_picture); anything else is shown
    pixel for pixel."""
    shown = on_every_page(FIGURE_SCALE_JS, 1280)
    assert sum(len(figures) for figures in shown.values()) >= 18, shown  # 20 today: 17 plots, 3 pictures
    shrunk = {
        page: [f"{alt}...: drawn for {a} px, shown at {w:.0f} px" for n, a, w, alt in figures if w < a - 1]
        for page, figures in shown.items()
    }
    assert not any(shrunk.values()), {page: found for page, found in shrunk.items() if found}
    dense = [n / a for figures in shown.values() for n, a, w, alt in figures]
    assert sum(abs(d - 2) < 0.01 for d in dense) >= 18 and all(abs(d - 2) < 0.01 or d == 1 for d in dense), dense
