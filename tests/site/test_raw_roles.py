"""No built page shows MyST role syntax to a reader.

A role such as ``{glue:text}`name``` only works in running text: inside a ``$$`` math block,
for instance, it reaches the page as raw characters, and MathJax typesets them. Every built page
is searched outside code (where showing the syntax is intended).
"""

from __future__ import annotations

import re

import pytest
from bs4 import BeautifulSoup
from sitetools import require_site, toc_pages

RAW_ROLE = re.compile(r"\{(glue|glue:text|glue:figure|glue:any|glue:md|numref|eq|ref|doc|cite)\}`")


def raw_roles(html: str) -> list[str]:
    soup = BeautifulSoup(html, "html.parser")
    for code in soup.select("pre, code, script, style"):
        code.decompose()
    text = soup.get_text(" ")
    return [text[max(0, m.start() - 40) : m.end() + 40].strip() for m in RAW_ROLE.finditer(text)]


def test_raw_roles_are_found():
    assert raw_roles("<p>$$ x = {glue:text}`a:.1f` $$</p>")
    assert not raw_roles("<p>x = 3.0</p><pre>{glue:text}`a`</pre>")


@pytest.mark.parametrize("page", toc_pages())
def test_no_raw_role_syntax(page):
    html = (require_site() / f"{page}.html").read_text(encoding="utf-8")
    found = raw_roles(html)
    assert not found, f"{page} shows MyST role syntax as text (move the role out of math or code): {found}"
