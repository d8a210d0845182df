"""No built page shows MyST role syntax, or a number in Python's exponent notation, to a reader.

A role such as ``{glue:text}`name``` only works in running text: inside a ``$$`` math block,
for instance, it reaches the page as raw characters, and MathJax typesets them. A number glued
with a format such as ``:.1e`` reads ``1.4e-09``; the site writes it as a power of ten
(``book/_ext/site_fixes.py``), and a figure's text alternative as ``1.4 × 10⁻⁹``
(``labsupport.book.power_of_ten``). Every built page is searched outside code and printed output
(where such text is intended), its figures' and videos' text alternatives included.
"""

from __future__ import annotations

import re

import pytest
from bs4 import BeautifulSoup
from sitetools import require_site, toc_pages

RAW_ROLE = re.compile(r"\{(glue|glue:text|glue:figure|glue:any|glue:md|numref|eq|ref|doc|cite)\}`")


EXPONENT = re.compile(r"(?<![\w.])-?\d+(?:\.\d+)?e[-+]?\d+\b")


#: What is left out of the search: code and printed output (where such text is intended).
CODE = "pre, code, script, style"


def _text(html: str, left_out: str) -> str:
    """The page's text without the elements ``left_out`` (a CSS selector) matches."""
    soup = BeautifulSoup(html, "html.parser")
    for element in soup.select(left_out):
        element.decompose()
    return soup.get_text(" ")


def _around(text: str, pattern: re.Pattern) -> list[str]:
    return [text[max(0, m.start() - 40) : m.end() + 40].strip() for m in pattern.finditer(text)]


def raw_roles(html: str) -> list[str]:
    """Role syntax outside code; inside a formula too, where MathJax would typeset it."""
    return _around(_text(html, CODE), RAW_ROLE)


def _text_alternatives(html: str) -> str:
    """The text alternatives of the page's figures and videos (``alt`` and ``aria-label``)."""
    soup = BeautifulSoup(html, "html.parser")
    return " ".join(e.get("alt") or e.get("aria-label") for e in soup.select("[alt], [aria-label]"))


def exponent_numbers(html: str) -> list[str]:
    """Numbers in exponent notation in the prose (code and formulas' TeX left out) and in the
    text alternatives of figures and videos, which a screen reader reads out."""
    return _around(_text(html, f"{CODE}, span.math, div.math") + " " + _text_alternatives(html), EXPONENT)


def test_raw_roles_are_found():
    assert raw_roles("<p>$$ x = {glue:text}`a:.1f` $$</p>")
    assert raw_roles('<div class="math notranslate nohighlight">\\[x = {glue:text}`a:.1f`\\]</div>')
    assert not raw_roles("<p>x = 3.0</p><pre>{glue:text}`a`</pre>")


def test_exponent_numbers_are_found():
    found = exponent_numbers("<p>within <span>1.4e-09</span> mm, and 4e-13 deg</p>")
    assert len(found) == 2 and "1.4e-09" in found[0] and "4e-13" in found[1]
    assert not exponent_numbers("<p>the constant <code>1e6</code>, <span class='math'>1e-9</span></p><pre>2e-09</pre>")
    assert not exponent_numbers("<p>time step 2e, see Eq. 3e-ish, sensor e-3, file v1.2e</p>")
    assert exponent_numbers('<img src="a.png" alt="the error ends at 1.4e-09 mm">')
    assert exponent_numbers('<video aria-label="a floor of 1e-04 degrees"></video>')
    assert not exponent_numbers('<img src="a.png" alt="the error ends at 1.4 × 10⁻⁹ mm">')


@pytest.mark.parametrize("page", toc_pages())
def test_no_raw_role_syntax(page):
    html = (require_site() / f"{page}.html").read_text(encoding="utf-8")
    found = raw_roles(html)
    assert not found, f"{page} shows MyST role syntax as text (move the role out of math or code): {found}"


@pytest.mark.parametrize("page", toc_pages())
def test_no_number_in_exponent_notation(page):
    html = (require_site() / f"{page}.html").read_text(encoding="utf-8")
    found = exponent_numbers(html)
    assert not found, f"{page} writes numbers in Python's exponent notation in its prose: {found}"
