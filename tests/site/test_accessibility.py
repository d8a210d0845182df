"""WCAG 2.1 AA on every page of the built site, checked by axe-core in a real Chromium.

axe-core comes with ``axe-playwright-python`` (it ships ``axe.min.js``; nothing is downloaded).
Each page is loaded once in each colour scheme (the site follows the system's light or dark
mode), axe runs with the WCAG 2.0/2.1 A and AA rule tags and the ``region`` best practice, and
every violation is reported with the rule, its impact and the first offending elements, so the
message says what to fix.
Reflow (1.4.10), which axe does not check, is tested on phone-sized windows.
"""

from __future__ import annotations

import re

import pytest
from sitetools import SUMMARY, VIEWPORT, book_config, dump_json, require_site, toc_pages

WCAG_TAGS = ["wcag2a", "wcag2aa", "wcag21a", "wcag21aa"]
#: The WCAG rules, and one best practice beyond them: ``region``, every part of a page in a
#: landmark, so that a screen reader moving by landmarks meets it all (the course title in the
#: sidebar sat in none: book/_ext/site_fixes.py).
AXE_OPTIONS = {
    "runOnly": {"type": "tag", "values": WCAG_TAGS},
    "rules": {"region": {"enabled": True}},
    "resultTypes": ["violations"],
}


@pytest.fixture(scope="module")
def axe():
    from axe_playwright_python.sync_playwright import Axe

    return Axe()


def _describe(violation: dict) -> str:
    nodes = violation.get("nodes", [])
    where = "; ".join(" ".join(n.get("target", [])) for n in nodes[:3])
    more = f" (+{len(nodes) - 3} more)" if len(nodes) > 3 else ""
    return f"{violation['id']} [{violation.get('impact')}]: {violation['help']} at {where}{more}"


#: What the search page has done once it is ready for axe: said how the search went, and shown
#: each result's quote (the quotes, and the words highlighted in them and in the titles, come once
#: each result's page is fetched).
SEARCH_DONE = (
    "() => /Search finished|No page matches/.test(document.querySelector('p.search-summary')?.textContent)"
    " && [...document.querySelectorAll('ul.search > li')].every(li => li.querySelector('p.context'))"
)


def axe_violations(browser, server, axe, url: str, scheme: str, ready: str | None = None) -> list[dict]:
    """axe's WCAG violations on ``url`` (under the site's root) in the colour ``scheme``, once the
    page's formulas are typeset and the JavaScript condition ``ready`` holds, if given."""
    context = browser.new_context(viewport=VIEWPORT, color_scheme=scheme)
    try:
        tab = context.new_page()
        tab.route("**/*", lambda route, request: route.continue_() if request.url.startswith(server) else route.abort())
        tab.goto(f"{server}/{url}", wait_until="load")
        tab.evaluate("async () => { if (window.MathJax?.startup?.promise) await MathJax.startup.promise; }")
        if ready:
            tab.wait_for_function(ready)
        # The theme applies the colour scheme by script after loading, and its buttons fade
        # their colours over 0.15 s: axe must see the end state, not a frame of the fade.
        tab.wait_for_function("scheme => document.documentElement.dataset.theme === scheme", arg=scheme)
        tab.add_style_tag(content="*, *::before, *::after { transition: none !important; }")
        return axe.run(tab, options=AXE_OPTIONS).response["violations"]
    finally:
        context.close()


@pytest.mark.parametrize("scheme", ["light", "dark"])
@pytest.mark.parametrize("page", toc_pages())
def test_page_meets_wcag21_aa(browser, server, axe, page, scheme):
    """In the reader's colour scheme: the site follows the system's light or dark mode."""
    violations = axe_violations(browser, server, axe, f"{page}.html", scheme)
    dump_json(f"axe__{page.replace('/', '__')}__{scheme}.json", violations)
    SUMMARY.append(f"axe WCAG 2.1 AA {page} ({scheme}): {len(violations)} violations")
    assert not violations, f"{page}: " + " | ".join(_describe(v) for v in violations)


@pytest.mark.parametrize("scheme", ["light", "dark"])
@pytest.mark.parametrize("query", ["computed torque", "ur5e", "nonsenseword"])
def test_search_results_meet_wcag21_aa(browser, server, axe, query, scheme):
    """The search page, with its results, is no page of the table of contents. In dark mode a word
    highlighted in a result's title was link blue on olive, 2.1:1 (book/_static/course.css)."""
    violations = axe_violations(browser, server, axe, f"search.html?q={query}", scheme, ready=SEARCH_DONE)
    assert not violations, f"search {query!r} ({scheme}): " + " | ".join(_describe(v) for v in violations)


def test_the_root_page_is_a_whole_page_for_a_reader_whose_browser_stays_on_it(browser, server, axe):
    """The site's root ``index.html`` sends the browser on to the first page. Where the browser
    does not follow such a redirect (a reader may turn them off), the page itself shows: in the
    book's language, under the course's title, with a link to the first page, and with no WCAG
    violation. It was one bare ``<meta>`` tag: no language, no title, a blank page."""
    root = (require_site() / "index.html").read_text(encoding="utf-8")
    first = f"{toc_pages()[0]}.html"
    refresh = f'<meta http-equiv="Refresh" content="0; url={first}" />'
    assert refresh in root, root
    stays = root.replace(refresh, "")  # as a browser that does not follow the redirect shows it
    context = browser.new_context(viewport=VIEWPORT)
    try:
        tab = context.new_page()
        tab.route(f"{server}/", lambda route: route.fulfill(body=stays, content_type="text/html"))
        tab.goto(f"{server}/", wait_until="load")
        assert tab.title() == book_config()["title"]
        assert tab.get_attribute("html", "lang") == "en"
        assert tab.locator("main a").get_attribute("href") == first
        assert re.fullmatch(r"The course starts at .+\.", tab.inner_text("main"))
        results = axe.run(tab, options=AXE_OPTIONS)
    finally:
        context.close()
    violations = results.response["violations"]
    assert not violations, "index.html: " + " | ".join(_describe(v) for v in violations)


@pytest.mark.parametrize("width", (320, 390))
def test_pages_reflow_on_a_phone(on_every_page, width):
    """WCAG 2.1, 1.4.10 Reflow: at 320 CSS px (and a common phone's 390) no page is wider than
    the window, so text never needs sideways scrolling. Code, equations, tables and videos
    may scroll inside their own boxes (two-dimensional content), but must not widen the page:
    a long inline file path or a heading's anchor did."""
    widths = on_every_page("() => document.documentElement.scrollWidth", width)
    wide = {page: w for page, w in widths.items() if w > width}
    assert not wide, f"pages wider than a {width} px window (px): {wide}"


#: Each video's width and how far its right edge lies past its output box's [px].
VIDEO_FIT_JS = """() => [...document.querySelectorAll('main video')].map(v => {
  const r = v.getBoundingClientRect(), box = v.closest('div.cell_output').getBoundingClientRect();
  return {width: Math.round(r.width), past: Math.round(r.right - box.right)};
})"""


@pytest.mark.parametrize("width", (320, 390))
def test_videos_fit_a_phone(on_every_page, width):
    """A video shrinks to the page's column on a phone: at its pixel size its right side and
    its own controls (sound, full screen) lay outside the column, reached only by scrolling the
    output sideways."""
    videos = on_every_page(VIDEO_FIT_JS, width)
    assert sum(len(v) for v in videos.values()) >= 4, "expected the Task 3 and Task 4 videos"
    cut = {page: v for page, v in videos.items() if any(x["past"] > 1 for x in v)}
    assert not cut, f"videos wider than their column in a {width} px window: {cut}"


#: Each of a page's Previous and Next links: its title, and its share of the column's width.
PREV_NEXT_SHARE_JS = """() => [...document.querySelectorAll('.prev-next-area a')].map(a => ({
  title: a.querySelector('p.prev-next-title').textContent.trim(),
  share: a.getBoundingClientRect().width / a.closest('.prev-next-area').getBoundingClientRect().width,
}))"""


@pytest.mark.parametrize("width", (320, 390))
def test_previous_and_next_links_take_a_line_each_on_a_phone(on_every_page, width):
    """The theme gives Previous and Next 45 % of one line each: at 320 px "Task 2: the single joint
    in MuJoCo" broke into five lines of one or two words. Each takes the column's width there."""
    found = on_every_page(PREV_NEXT_SHARE_JS, width)
    assert sum(len(v) for v in found.values()) >= 10, found
    narrow = {page: [t["title"] for t in links if t["share"] < 0.95] for page, links in found.items()}
    assert not any(narrow.values()), f"Previous/Next links narrower than the column at {width} px: {narrow}"


#: The weight of each video's caption, its written description, beside the weight of the page's
#: body text.
CAPTION_WEIGHT_JS = """() => {
  const body = +getComputedStyle(document.querySelector('main p')).fontWeight;
  return [...document.querySelectorAll('div.cell_output figure figcaption')].map(c => ({
    caption: +getComputedStyle(c).fontWeight, body, align: getComputedStyle(c).textAlign,
    text: c.textContent.slice(0, 40),
  }));
}"""


def test_video_captions_are_drawn_as_the_body_text(on_every_page):
    """A video's caption is its only written description on the page; the theme drew it at
    its light weight 300, thin and grey beside the body text, and centred its lines."""
    captions = on_every_page(CAPTION_WEIGHT_JS, 1280)
    assert sum(len(c) for c in captions.values()) >= 4, "expected the Task 3 and Task 4 videos' captions"
    light = {page: [c for c in found if c["caption"] < c["body"]] for page, found in captions.items()}
    assert not any(light.values()), f"captions lighter than the body text: {light}"
    centred = {page: [c for c in found if c["align"] not in ("start", "left")] for page, found in captions.items()}
    assert not any(centred.values()), f"captions not aligned as the body text: {centred}"


#: Every formula a reader would have to scroll sideways to read: a displayed one wider than its
#: box, an inline one reaching past its paragraph; each with the start of its TeX.
FORMULA_FIT_JS = """() => [...(window.MathJax?.startup?.document?.math ?? [])].map(item => {
  const box = item.typesetRoot, math = box && box.firstElementChild;
  if (!math) return null;
  // an inline formula is measured with the punctuation kept on its line (span.math-nobreak)
  const r = (item.display ? math : box.closest('span.math-nobreak') || math).getBoundingClientRect();
  const room = (item.display ? box : box.parentElement.closest('p, li, dd, td, div')).getBoundingClientRect();
  return r.right - room.right > 1 || room.left - r.left > 1
    ? {tex: item.math.trim().replace(/\\s+/g, ' ').slice(0, 60), over: Math.round(r.width - room.width)}
    : null;
}).filter(x => x)"""


@pytest.mark.parametrize("width", (320, 390))
def test_formulas_fit_a_phone(on_every_page, width):
    """Every formula reads without scrolling sideways at 320 CSS px (WCAG 2.1, 1.4.10 Reflow).
    MathJax 3 breaks no line itself, so a formula wider than the column showed its start and
    hid the rest behind a scroll bar: long ones are broken into lines in the source, and on a
    phone a numbered one's number goes below it (course.css) to leave it the column's width."""
    cut = {page: f for page, f in on_every_page(FORMULA_FIT_JS, width).items() if f}
    assert not cut, f"formulas wider than the column in a {width} px window (over by px): {cut}"


#: Punctuation written against an inline formula that a line break parted from it: a line
#: starting with the "," or ")" after a formula, or ending with the "(" before one; each with
#: the start of the formula's TeX and the text on the far side of the break.
ORPHAN_PUNCTUATION_JS = """() => [...(window.MathJax?.startup?.document?.math ?? [])].map(item => {
  const box = item.typesetRoot;
  if (item.display || !box || !box.getBoundingClientRect().width) return null;
  const r = box.getBoundingClientRect(), span = box.closest('span.math') || box;
  const tex = item.math.trim().replace(/\\s+/g, ' ').slice(0, 50);
  const char = (node, k) => { const g = document.createRange(); g.setStart(node, k); g.setEnd(node, k + 1);
                              return g.getBoundingClientRect(); };
  const next = span.nextSibling, prev = span.previousSibling;
  // on the formula's line, what follows it starts right of it and what precedes it ends left of it
  if (next?.nodeType === 3 && /^[,.;:!?)\\]]/.test(next.textContent) && char(next, 0).left < r.right - 1)
    return {tex, after: next.textContent.slice(0, 10)};
  if (prev?.nodeType === 3 && /[(\\[]$/.test(prev.textContent)
      && char(prev, prev.textContent.length - 1).right > r.left + 1)
    return {tex, before: prev.textContent.slice(-10)};
  return null;
}).filter(x => x)"""


@pytest.mark.parametrize("width", (320, 390, 1280))
def test_no_punctuation_parted_from_its_formula(on_every_page, width):
    """A browser may break a line between an inline formula and the comma or bracket written
    against it: lines began with a lone "," or ":" and ended with a lone "(" (22 such breaks on
    7 pages at 320, 390, 768 and 1280 px). ``site_fixes.py`` keeps each formula on one line
    with its punctuation."""
    parted = {page: f for page, f in on_every_page(ORPHAN_PUNCTUATION_JS, width).items() if f}
    assert not parted, f"punctuation parted from its formula in a {width} px window: {parted}"


#: Words of inline code broken over two lines although, with room to spare for the punctuation
#: written against them, they fit the column whole: each with its width and the column's [px].
CODE_BROKEN_JS = """() => [...document.querySelectorAll('main code.literal span.pre')].map(word => {
  if (word.getClientRects().length < 2) return null;
  const room = word.closest('p, li, td, th, dd, dt, figcaption, div').clientWidth;
  word.style.whiteSpace = 'nowrap';
  const whole = word.getBoundingClientRect().width;
  word.style.whiteSpace = '';
  return whole + 40 <= room ? {word: word.textContent, whole: Math.round(whole), room} : null;
}).filter(x => x)"""


@pytest.mark.parametrize("width", (320, 390, 1280))
def test_no_code_word_broken_where_it_fits(on_every_page, width):
    """Inline code may break where it must (course.css), but the browser also broke it after a
    hyphen where nothing forced it: ``sscbirrt-`` / ``assets`` on the credits page at 320 px,
    ``imageio-`` / ``ffmpeg`` on the set-up page at 390 px, and ``-`` / ``> tau`` in Task 4.
    ``site_fixes.py`` keeps each hyphenated word whole."""
    broken = {page: f for page, f in on_every_page(CODE_BROKEN_JS, width).items() if f}
    assert not broken, f"words of inline code broken although they fit a {width} px window: {broken}"


#: Each table's width and the room its scrolling box gives it [px].
TABLE_FIT_JS = """() => [...document.querySelectorAll('main table')].map(t => ({
  head: (t.querySelector('th') || t).textContent.trim().slice(0, 30),
  width: t.scrollWidth,
  room: (t.closest('.pst-scrollable-table-container') || t.parentElement).clientWidth,
}))"""


@pytest.mark.parametrize("width", (320, 390))
def test_tables_fit_a_phone(on_every_page, width):
    """The home page's map of the lab and Task 4's summary fit the column on a phone: at 320 px
    the map hid its last column, the Colab links, behind a scroll bar (course.css halves the
    cells' padding there, and the Colab links sit beside each part's name)."""
    tables = on_every_page(TABLE_FIT_JS, width)
    assert sum(len(t) for t in tables.values()) >= 2, "expected the home page's and Task 4's tables"
    wide = {page: [t for t in ts if t["width"] > t["room"] + 1] for page, ts in tables.items()}
    wide = {page: ts for page, ts in wide.items() if ts}
    assert not wide, f"tables wider than the column in a {width} px window: {wide}"


@pytest.mark.parametrize("page", toc_pages())
def test_every_toggle_is_named_by_the_text_it_shows(page):
    """WCAG 2.1, 2.5.3 Label in Name: sphinx-togglebutton labelled each "Show code cell source"
    summary "Toggle hidden content", so a screen reader announced, and voice control answered
    to, a name the reader never sees (book/_ext/site_fixes.py takes the label off)."""
    from bs4 import BeautifulSoup

    main = BeautifulSoup((require_site() / f"{page}.html").read_text(encoding="utf-8"), "html.parser").find("main")
    labelled = [
        f"{summary['aria-label']!r} on {' '.join(summary.get_text(' ').split())!r}"
        for summary in main.find_all("summary")
        if summary.has_attr("aria-label")
        and " ".join(summary["aria-label"].split()).lower() not in summary.get_text(" ").lower()
    ]
    assert not labelled, f"{page}: summaries named otherwise than they read: {labelled}"


def test_the_reference_list_is_labelled_as_the_pages_cite():
    """The pages cite by author and year ("Lynch and Park [2017]"), but the reference list was
    labelled [1]–[6], and the links back to where each entry is cited were read out as "1", "2"
    (book/_ext/author_year_labels.py labels it by author and year)."""
    from bs4 import BeautifulSoup

    soup = BeautifulSoup((require_site() / "book/references.html").read_text(encoding="utf-8"), "html.parser")
    entries = soup.select("div.citation")
    labels = [" ".join(entry.select_one("span.label").get_text("").split()) for entry in entries]
    assert len(labels) >= 6 and len(set(labels)) == len(labels), labels
    assert "[Lynch and Park 2017]" in labels and "[Khatib 1987]" in labels, labels
    assert all(re.fullmatch(r"\[[A-Z][\w .-]* \d{4}[a-z]?\]", label) for label in labels), labels
    links = [" ".join(a.get_text(" ").split()) for a in soup.select('a[role="doc-backlink"]')]
    assert links and all(re.search(r"[A-Za-z]{3,}", text) for text in links), f"back-links read out as {links}"
