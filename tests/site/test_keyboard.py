"""The launch buttons and the videos work from the keyboard alone (WCAG 2.1: 2.1.1 Keyboard,
2.4.7 Focus Visible).

A reader who cannot use a mouse presses Tab from the top of the page until the focus reaches
the rocket (launch) button, opens it with Enter, moves to "Colab" with the arrow keys, and
gets this notebook's Colab address; on the Task 3 and Task 4 pages, Tab also reaches each
video, and Space plays and pauses it. Every focused control must show where the focus is.
"""

from __future__ import annotations

import pytest
from sitetools import expected_colab_url, is_notebook, require_site, toc_pages

NOTEBOOK_PAGES = [p for p in toc_pages() if is_notebook(p)]
#: The most Tab presses a control may take to reach (the header, the sidebar and the page's
#: own links come first).
MAX_TABS = 150

FOCUSED_JS = r"""
() => {
  const e = document.activeElement;
  if (!e || e === document.body) return null;
  const s = getComputedStyle(e);
  return {tag: e.tagName, label: e.getAttribute('aria-label') || '', href: e.getAttribute('href') || '',
          text: (e.innerText || '').trim().slice(0, 40), expanded: e.getAttribute('aria-expanded'),
          outline: s.outlineStyle !== 'none' && parseFloat(s.outlineWidth) > 0, shadow: s.boxShadow !== 'none',
          paused: e.tagName === 'VIDEO' ? e.paused : null};
}
"""


def tab_until(tab, wanted, limit: int = MAX_TABS):
    """Press Tab until ``wanted(focused)`` holds; ``(presses, focused)``, or ``(None, last)``."""
    focused = None
    for presses in range(1, limit + 1):
        tab.keyboard.press("Tab")
        focused = tab.evaluate(FOCUSED_JS)
        if focused and wanted(focused):
            return presses, focused
    return None, focused


def focus_is_visible(focused: dict) -> bool:
    return focused["outline"] or focused["shadow"]


@pytest.mark.parametrize("page", NOTEBOOK_PAGES)
def test_the_launch_button_opens_colab_from_the_keyboard(tab_page, page):
    require_site()
    tab = tab_page(page)
    presses, rocket = tab_until(tab, lambda f: f["label"] == "Launch interactive content")
    assert presses, f"{page}: {MAX_TABS} Tab presses never reached the launch (rocket) button; last focus {rocket}"
    assert focus_is_visible(rocket), f"{page}: the focused launch button shows no focus indicator"
    tab.keyboard.press("Enter")
    assert tab.evaluate(FOCUSED_JS)["expanded"] == "true", f"{page}: Enter does not open the launch menu"
    tab.keyboard.press("ArrowDown")
    colab = tab.evaluate(FOCUSED_JS)
    assert colab and colab["text"] == "Colab", f"{page}: the arrow key does not reach the Colab item ({colab})"
    assert colab["href"] == expected_colab_url(page)
    assert focus_is_visible(colab), f"{page}: the focused Colab item shows no focus indicator"
    tab.keyboard.press("Escape")
    assert tab.evaluate(FOCUSED_JS)["expanded"] == "false", f"{page}: Escape does not close the launch menu"


VIDEO_PAGES = [p for p in NOTEBOOK_PAGES if p.split("/")[-1].startswith(("task3", "task4"))]


@pytest.mark.parametrize("page", VIDEO_PAGES)
def test_every_video_is_reached_and_played_from_the_keyboard(tab_page, page):
    site = require_site()
    n_videos = (site / f"{page}.html").read_text(encoding="utf-8").count("<video")
    assert n_videos >= 2, f"{page}: expected its videos, found {n_videos}"
    tab = tab_page(page)
    seen: set[str] = set()
    for k in range(n_videos):
        # Tab also walks through a focused video's own controls (inside it), so wait for the next video
        presses, video = tab_until(tab, lambda f: f["tag"] == "VIDEO" and f["label"] not in seen)
        assert presses, f"{page}: Tab never reached video {k + 1} of {n_videos}"
        seen.add(video["label"])
        assert focus_is_visible(video), f"{page}: video {k + 1} shows no focus indicator when focused"
        before = video["paused"]
        tab.keyboard.press("Space")
        tab.wait_for_timeout(300)
        after = tab.evaluate(FOCUSED_JS)
        assert after["tag"] == "VIDEO" and after["paused"] != before, (
            f"{page}: Space on video {k + 1} did not {'play' if before else 'pause'} it"
        )
        tab.keyboard.press("Space")
        tab.wait_for_timeout(300)
        assert tab.evaluate(FOCUSED_JS)["paused"] == before, f"{page}: a second Space did not toggle video {k + 1} back"


@pytest.mark.parametrize("page", toc_pages())
def test_every_tab_stop_shows_focus_and_formulas_are_not_tab_stops(tab_page, page):
    """Tab from the top of the page to its end: every control it stops at shows the focus
    (the buttons that open the sidebars included, the only way to the contents on a phone),
    and no formula is a stop (MathJax made every one of them one: 168 on the theory page)."""
    require_site()
    tab = tab_page(page)
    tab.evaluate("async () => { if (window.MathJax?.startup?.promise) await MathJax.startup.promise; }")
    tab.add_style_tag(content="*, *::before, *::after { transition: none !important; }")
    math = tab.evaluate("() => document.querySelectorAll('mjx-container[tabindex]:not([tabindex=\"-1\"])').length")
    assert math == 0, f"{page}: {math} formulas are Tab stops (MathJax's inTabOrder setting, _config.yml)"
    hidden, videos = [], set()
    for _ in range(MAX_TABS):
        tab.keyboard.press("Tab")
        focused = tab.evaluate(FOCUSED_JS)
        if focused is None:  # past the last control
            break
        if focused["tag"] == "VIDEO":  # then the browser's own controls inside it, drawn by the browser
            if focused["label"] in videos:
                continue
            videos.add(focused["label"])
        if not focus_is_visible(focused):
            hidden.append({k: focused[k] for k in ("tag", "label", "text", "href")})
    else:
        pytest.fail(f"{page}: {MAX_TABS} Tab presses did not reach the end of the page")
    assert not hidden, f"{page}: focused controls that show no focus indicator: {hidden}"


@pytest.mark.parametrize("toggle", ["primary-toggle", "secondary-toggle"])
def test_a_phone_menu_closed_with_escape_gives_the_focus_back(tab_page, toggle):
    """At 390 px the contents open in a dialog from the button that toggles the sidebar. Escape
    closed it, but the focus fell to the page's body, so a keyboard reader started again from the
    top of the page (WCAG 2.1, 2.4.3); it now returns to the button (book/_static/course.js)."""
    require_site()
    tab = tab_page(NOTEBOOK_PAGES[0], width=390)
    button = tab.locator(f"button.{toggle}").first
    button.focus()
    tab.keyboard.press("Enter")
    tab.wait_for_timeout(300)
    assert tab.evaluate("() => document.querySelector('dialog[open]') !== null"), (
        f"Enter did not open the {toggle} menu"
    )
    tab.keyboard.press("Escape")
    tab.wait_for_timeout(300)
    assert tab.evaluate("() => document.querySelector('dialog[open]') === null"), "Escape did not close the menu"
    focused = tab.evaluate(FOCUSED_JS)
    assert focused and focused["tag"] == "BUTTON", f"after Escape the focus is on {focused or 'the page body'}"
    assert tab.evaluate(f"() => document.activeElement.classList.contains('{toggle}')")


FIGURE_SIZES_JS = r"""
() => [...document.querySelectorAll('figure.course-figure')].map(f => {
  const img = f.querySelector('img'), b = f.querySelector('button.course-figure-size');
  const frame = f.querySelector('.course-figure-frame');
  return {drawn: Number(img.getAttribute('width')), shown: img.clientWidth,
          button: b ? (b.hidden ? 'hidden' : b.getAttribute('aria-pressed')) : null,
          scrolls: frame ? frame.scrollWidth > frame.clientWidth + 1 : null, tabindex: frame && frame.tabIndex,
          page: document.documentElement.scrollWidth <= window.innerWidth};
})
"""


def test_a_figure_shrunk_on_a_phone_shows_at_full_size_from_the_keyboard(tab_page):
    """At 390 px a figure drawn for a 744 px column is shown half as wide, its tick labels about 3 px
    tall. A "Full size" toggle above each shrunk figure shows it at the size it was drawn, in a
    frame that scrolls sideways while the page does not (book/_static/course.js), and Tab goes on
    from the button into that frame; each button names its figure. At 1280 px, where the figures
    fit, there is no such button."""
    require_site()
    tab = tab_page("notebooks/task1_single_joint", width=390)
    before = tab.evaluate(FIGURE_SIZES_JS)
    assert len(before) >= 6 and all(f["shown"] < f["drawn"] - 1 and f["button"] == "false" for f in before), before
    presses, focused = tab_until(tab, lambda f: f["tag"] == "BUTTON" and f["text"] == "Full size", limit=400)
    assert presses and focus_is_visible(focused), focused
    tab.keyboard.press("Enter")
    after = tab.evaluate(FIGURE_SIZES_JS)
    full = [f for f in after if f["button"] == "true"]
    assert len(full) == 1 and full[0]["shown"] == full[0]["drawn"] and full[0]["scrolls"], after
    assert full[0]["tabindex"] == 0 and all(f["page"] for f in after), after  # the page itself never scrolls sideways
    tab.keyboard.press("Tab")  # from the button into its figure's frame, which scrolls with the arrow keys
    assert tab.evaluate("() => document.activeElement.classList.contains('course-figure-frame')")
    tab.keyboard.press("Shift+Tab")
    names = tab.evaluate("() => [...document.querySelectorAll('button.course-figure-size')].map(b => b.ariaLabel)")
    assert names == [f"Full size, figure {k} of {len(names)}" for k in range(1, len(names) + 1)], names
    tab.keyboard.press("Enter")
    assert tab.evaluate(FIGURE_SIZES_JS) == before
    wide = tab_page("notebooks/task1_single_joint").evaluate(FIGURE_SIZES_JS)
    assert all(f["button"] == "hidden" for f in wide), wide
