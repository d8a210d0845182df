"""Text alternatives of the site's figures and videos (WCAG 2.1, success criterion 1.1.1).

axe-core only asks that an ``<img>`` has *an* ``alt``; MyST-NB's default for a notebook's figure
is the image's own file name (``alt="../_images/<hash>.png"``), which passes axe and tells a
screen-reader user nothing. These tests read the built pages (``_build/html``) and ask more:

* every ``<img>`` inside ``<main>`` has an alt that is real text: not missing, not a file name
  or path, not a bare word such as "image"; an empty alt only on an image marked decorative
  (``role="presentation"``/``"none"`` or ``aria-hidden="true"``); a figure (a notebook output,
  anything under ``_images/`` or inline as ``data:image``) at least :data:`MIN_WORDS` words;
* every ``<video>`` has a text alternative of at least :data:`MIN_WORDS` words: its
  ``aria-label`` or ``aria-labelledby``, the ``<figcaption>`` of the ``<figure>`` around it
  (unless ``aria-hidden``, as the course's are: they repeat the name for the eye alone), or its
  fallback content (the browser's stock "does not support the video tag" does not count).

The notebooks give their figures these texts in the cell metadata,
``{"mystnb": {"image": {"alt": "..."}}}``; the source-level tests at the end check that every
cell that draws a figure has one and that the Problems' student notebooks inherit the masters'.
"""

from __future__ import annotations

import ast
import json
import re

import pytest
from bs4 import BeautifulSoup
from sitetools import ROOT, SUMMARY, is_notebook, require_site, toc_pages

#: The fewest words a figure's or a video's text alternative may have.
MIN_WORDS = 5
_IMAGE_FILE = re.compile(r"\.(png|jpe?g|gif|svg|webp|bmp|tiff?)\s*$", re.IGNORECASE)
_GENERIC = {
    "image",
    "img",
    "figure",
    "fig",
    "picture",
    "photo",
    "plot",
    "graph",
    "chart",
    "output",
    "screenshot",
    "video",
    "png",
    "svg",
    "untitled",
}
_BROWSER_FALLBACK = re.compile(r"your browser does not support|this browser does not support", re.IGNORECASE)


# --------------------------------------------------------------------------------------------
# What counts as a real text alternative
# --------------------------------------------------------------------------------------------
def _words(text: str) -> list[str]:
    return re.findall(r"\w+", text)


def alt_problem(alt: str | None, *, figure: bool) -> str | None:
    """Why ``alt`` is not a real text alternative (None if it is); ``figure`` asks for a description."""
    if alt is None:
        return "no alt attribute"
    text = " ".join(alt.split())
    if not text:
        return "an empty alt, but the image is not marked decorative (role=presentation or aria-hidden)"
    if text.startswith("data:") or _IMAGE_FILE.search(text) or ("/" in text and " " not in text):
        return f"the alt is a file name or path ({text[:60]!r}), not a description"
    if text.lower().strip(" .:") in _GENERIC or text.startswith("<Figure size"):
        return f"the alt {text!r} names the kind of thing, not what it shows"
    if figure and len(_words(text)) < MIN_WORDS:
        return f"the alt {text!r} is too short to describe a figure (at least {MIN_WORDS} words)"
    return None


def is_decorative(img) -> bool:
    return img.get("alt") == "" and (img.get("role") in ("presentation", "none") or img.get("aria-hidden") == "true")


def is_figure(img) -> bool:
    """A content figure: a notebook output, a file of the book's ``_images``, or an inline image."""
    src = img.get("src", "")
    if "_images/" in src or src.startswith("data:image"):
        return True
    return img.find_parent(class_=re.compile(r"\bcell_output\b|\boutput\b")) is not None


def video_text(video, soup) -> list[str]:
    """The text alternatives a video offers, best first (each whitespace-normalised)."""
    found = [video.get("aria-label", "")]
    for ref in video.get("aria-labelledby", "").split():
        target = soup.find(id=ref)
        if target is not None:
            found.append(target.get_text(" "))
    figure = video.find_parent("figure")
    caption = figure.find("figcaption") if figure is not None else None
    if caption is not None and caption.get("aria-hidden") != "true":  # a hidden one is for the eye alone
        found.append(caption.get_text(" "))
    fallback = " ".join(
        s for s in video.find_all(string=True, recursive=True) if s.parent.name not in ("source", "track")
    )
    if not _BROWSER_FALLBACK.search(fallback):
        found.append(fallback)
    return [" ".join(text.split()) for text in found if text and text.strip()]


def page_problems(html: str) -> tuple[list[str], int, int]:
    """``(problems, figures checked, videos checked)`` for the ``<main>`` of one page."""
    soup = BeautifulSoup(html, "html.parser")
    main = soup.find("main")
    if main is None:
        return ["the page has no <main> element"], 0, 0
    problems, n_figures = [], 0
    for img in main.find_all("img"):
        if is_decorative(img):
            continue
        figure = is_figure(img)
        n_figures += figure
        why = alt_problem(img.get("alt"), figure=figure)
        if why:
            src = img.get("src", "")
            problems.append(f"<img src={src[:40] + '...' if src.startswith('data:') else src!r}>: {why}")
    videos = main.find_all("video")
    for k, video in enumerate(videos, 1):
        texts = video_text(video, soup)
        if not any(len(_words(t)) >= MIN_WORDS for t in texts):
            problems.append(
                f"video {k} of {len(videos)} has no text alternative of {MIN_WORDS} words or more "
                f"(aria-label, a <figcaption> or fallback text); found {texts!r}"
            )
    return problems, n_figures, len(videos)


# --------------------------------------------------------------------------------------------
# The rules themselves, on small pieces of HTML
# --------------------------------------------------------------------------------------------
def _main(body: str) -> str:
    return f"<html><body><nav><img src='logo.png'></nav><main>{body}</main></body></html>"


@pytest.mark.parametrize(
    "img, why",
    [
        ('<img src="../_images/ab12.png" alt="../_images/ab12.png">', "file name or path"),
        ('<img src="_images/ab12.png" alt="ab12.png">', "file name or path"),
        ('<img src="_images/ab12.png">', "no alt attribute"),
        ('<img src="_images/ab12.png" alt="">', "not marked decorative"),
        ('<img src="_images/ab12.png" alt="Figure">', "names the kind of thing"),
        ('<img src="_images/ab12.png" alt="Speed over time">', "too short"),
        ('<div class="cell_output"><img src="data:image/png;base64,AAAA" width="480"></div>', "no alt attribute"),
    ],
)
def test_rules_reject_what_is_not_a_text_alternative(img, why):
    problems, n_figures, _ = page_problems(_main(img))
    assert n_figures == 1 and len(problems) == 1 and why in problems[0], problems


@pytest.mark.parametrize(
    "body",
    [
        '<img src="_images/ab12.png" alt="Speed in rad/s rising to its steady state within five seconds.">',
        '<img src="_static/rule.png" alt="" role="presentation">',
        '<video aria-label="The arm swings onto the circle and follows it twice."><source src="a.mp4"></video>',
        '<figure><video><source src="a.mp4"></video><figcaption>The arm follows the blue circle twice, '
        "in red.</figcaption></figure>",
        '<video><source src="a.mp4">The arm follows the blue circle twice, in red.</video>',
    ],
)
def test_rules_accept_real_text_alternatives(body):
    assert page_problems(_main(body))[0] == []


def test_rules_reject_a_video_with_the_browsers_stock_fallback_only():
    mediapy_like = (
        '<table><tr><td><div>lab run</div><video controls width="480"><source src="data:video/mp4;'
        'base64,AAAA" type="video/mp4"/>This browser does not support the video tag.</video>'
        "</td></tr></table>"
    )
    problems = page_problems(_main(mediapy_like))[0]
    assert len(problems) == 1 and "no text alternative" in problems[0]


def test_rules_reject_a_video_whose_only_text_is_a_caption_hidden_from_screen_readers():
    hidden = (
        '<figure><video controls><source src="a.mp4"></video><figcaption aria-hidden="true">'
        "The arm follows the blue circle twice, in red.</figcaption></figure>"
    )
    problems = page_problems(_main(hidden))[0]
    assert len(problems) == 1 and "no text alternative" in problems[0]
    named = hidden.replace("<video controls>", '<video controls aria-label="The arm follows the circle twice.">')
    assert page_problems(_main(named))[0] == []


# --------------------------------------------------------------------------------------------
# The built site
# --------------------------------------------------------------------------------------------
@pytest.mark.parametrize("page", toc_pages())
def test_every_figure_and_video_has_a_text_alternative(page):
    html = (require_site() / f"{page}.html").read_text(encoding="utf-8")
    problems, n_figures, n_videos = page_problems(html)
    SUMMARY.append(f"alt text {page}: {n_figures} figures, {n_videos} videos, {len(problems)} problems")
    assert not problems, f"{page}: " + " | ".join(problems)


def test_the_tasks_show_their_figures():
    """The checks above are not vacuous: each Task's page shows figures with real alt text."""
    site = require_site()
    for page in (p for p in toc_pages() if p.startswith("notebooks/task")):
        _, n_figures, _ = page_problems((site / f"{page}.html").read_text(encoding="utf-8"))
        assert n_figures >= 1, f"{page} shows no figure: did the notebook run when the book was built?"


def figures_without_description(html: str) -> tuple[list[str], int]:
    """The notebook figures of a page whose text alternative is not also written under them, in
    a collapsed ``<details>`` of their ``<figure>`` (labsupport.book.show_figure); and how many
    figures there are."""
    main = BeautifulSoup(html, "html.parser").find("main")
    missing, images = [], [img for img in main.find_all("img") if img.get("src", "").startswith("data:image")]
    for k, img in enumerate(images, 1):
        figure = img.find_parent("figure")
        details = figure.find("details") if figure is not None else None
        text = " ".join(details.p.get_text(" ").split()) if details is not None and details.p else None
        if details is None or details.summary is None or details.has_attr("open") or text != img.get("alt"):
            missing.append(f"figure {k} of {len(images)} ({img.get('alt', '')[:50]!r}): found {text!r}")
    return missing, len(images)


def test_rules_find_a_figure_whose_description_is_missing_or_differs():
    text = "Speed rises to 10 rad/s within five seconds."
    img = f'<img src="data:image/png;base64,AAAA" alt="{text}">'
    written = f"<details><summary>The figure in words</summary><p>{text}</p></details>"
    assert figures_without_description(_main(f"<figure>{img}{written}</figure>")) == ([], 1)
    for body in (img, f"<figure>{img}</figure>", f"<figure>{img}{written.replace('10', '12')}</figure>"):
        assert len(figures_without_description(_main(body))[0]) == 1, body


@pytest.mark.parametrize("page", [p for p in toc_pages() if is_notebook(p)])
def test_every_figure_has_its_description_written_under_it(page):
    """A sighted reader can read a figure's text alternative too, and a screen-reader user can
    move through it word by word, which an alt does not allow (WAI's tutorial on complex images)."""
    missing, n = figures_without_description((require_site() / f"{page}.html").read_text(encoding="utf-8"))
    assert not missing, f"{page}: " + " | ".join(missing)
    assert n >= 1 or not page.startswith("notebooks/task"), f"{page} shows no figure"


# --------------------------------------------------------------------------------------------
# The notebooks' sources: every figure is shown with a text alternative computed from its values
# --------------------------------------------------------------------------------------------
_DRAWS_A_FIGURE = re.compile(r"plt\.subplots\(|_figure\(|renderer\.render\(\)")
_SHOWN_WITHOUT_ALT = re.compile(r"plt\.show\(\)|display\(Image\(")


def _notebooks() -> list:
    pages = [ROOT / f"{p}.ipynb" for p in toc_pages() if is_notebook(p)]
    return pages + sorted((ROOT / "notebooks" / "masters").glob("*.ipynb"))


def _cells(path) -> list[dict]:
    return json.loads(path.read_text(encoding="utf-8"))["cells"]


def _python(source: str) -> ast.Module:
    """A code cell as Python (IPython's ``%`` and ``!`` lines left out)."""
    return ast.parse("\n".join(line for line in source.splitlines() if not line.lstrip().startswith(("%", "!"))))


def computed_alts(source: str) -> list[bool]:
    """For each ``show_figure(figure, alt)`` call of a cell: is ``alt`` computed (an f-string with
    a replacement field, or built from names), rather than a fixed text that can drift?"""
    found = []
    for node in ast.walk(_python(source)):
        if isinstance(node, ast.Call) and getattr(node.func, "id", getattr(node.func, "attr", "")) == "show_figure":
            alt = node.args[1] if len(node.args) > 1 else next((k.value for k in node.keywords if k.arg == "alt"), None)
            found.append(alt is not None and any(isinstance(n, (ast.FormattedValue, ast.Name)) for n in ast.walk(alt)))
    return found


def test_computed_alts_are_told_from_fixed_ones():
    assert computed_alts('show_figure(fig, f"Speed rises to {w:.1f} rad/s within five seconds.")') == [True]
    assert computed_alts('show_figure(fig, "Speed rises to 10 rad/s within five seconds.")') == [False]
    assert computed_alts('book.show_figure(fig, alt="The arm swings, " + text)') == [True]
    assert computed_alts("fig, ax = plt.subplots()") == []


@pytest.mark.parametrize("path", _notebooks(), ids=lambda p: p.relative_to(ROOT).as_posix())
def test_every_figure_is_shown_with_an_alt_computed_from_its_values(path):
    problems = []
    for k, cell in enumerate(_cells(path)):
        source = "".join(cell["source"])
        if cell["cell_type"] != "code":
            continue
        where = f"cell {k} ({source.splitlines()[0][:50]!r})" if source else f"cell {k}"
        if cell.get("metadata", {}).get("mystnb", {}).get("image", {}).get("alt"):
            problems.append(f"{where}: a fixed alt in the cell metadata (compute it and pass it to show_figure)")
        if _SHOWN_WITHOUT_ALT.search(source):
            problems.append(f"{where}: shows a figure without its alt (use labsupport.book.show_figure)")
        alts = computed_alts(source)
        if _DRAWS_A_FIGURE.search(source) and not alts:
            problems.append(f"{where}: draws a figure but never calls show_figure(figure, alt)")
        if not all(alts):
            problems.append(f"{where}: show_figure's alt is a fixed text; write it from the plotted values (f-string)")
    assert not problems, f"{path.name}: " + "; ".join(problems)


@pytest.mark.parametrize("name", ["problem1_reaching", "problem2_tracking"])
def test_student_notebooks_show_their_figures_as_the_masters_do(name):
    def code(path):
        return {c["id"]: "".join(c["source"]) for c in _cells(path) if c["cell_type"] == "code"}

    master, student = code(ROOT / "notebooks" / "masters" / f"{name}.ipynb"), code(ROOT / "notebooks" / f"{name}.ipynb")
    figures = {cell_id: source for cell_id, source in master.items() if computed_alts(source)}
    assert figures, f"the master of {name} shows no figure through show_figure"
    assert {cell_id: student.get(cell_id) for cell_id in figures} == figures
