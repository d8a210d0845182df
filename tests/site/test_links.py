"""Link checker over the built site: every internal link, image, script and stylesheet that a
page of ``_build/html`` refers to exists, and every ``#fragment`` names an element of its page."""

from __future__ import annotations

from html.parser import HTMLParser
from pathlib import Path
from urllib.parse import unquote, urljoin, urlparse

from sitetools import SUMMARY, require_site

#: (tag, attribute) pairs that point at another file or a place in one.
REFERENCES = {
    ("a", "href"),
    ("link", "href"),
    ("script", "src"),
    ("img", "src"),
    ("source", "src"),
    ("video", "src"),
    ("video", "poster"),
    ("iframe", "src"),
    ("embed", "src"),
}
EXTERNAL_SCHEMES = ("http:", "https:", "mailto:", "data:", "javascript:", "tel:")


class _Refs(HTMLParser):
    """Collects the references and the element ids of one HTML page, and whether it names an icon."""

    def __init__(self):
        super().__init__(convert_charrefs=True)
        self.refs: list[tuple[str, str]] = []
        self.ids: set[str] = set()
        self.icon = False

    def handle_starttag(self, tag, attrs):
        attrs = dict(attrs)
        if attrs.get("id"):
            self.ids.add(attrs["id"])
        if tag == "a" and attrs.get("name"):
            self.ids.add(attrs["name"])
        if tag == "link" and "icon" in (attrs.get("rel") or "").split() and attrs.get("href"):
            self.icon = True
        for name, value in attrs.items():
            if (tag, name) in REFERENCES and value:
                self.refs.append((tag, value.strip()))


def parse(path: Path) -> _Refs:
    parser = _Refs()
    parser.feed(path.read_text(encoding="utf-8", errors="replace"))
    return parser


def site_pages(site: Path) -> list[Path]:
    """The site's own HTML pages (the theme's bundled files under _static excluded)."""
    return sorted(p for p in site.rglob("*.html") if "_static" not in p.relative_to(site).parts)


def broken_links(site: Path) -> tuple[list[str], int]:
    """``(problems, number of references checked)`` over every page of ``site``."""
    ids_cache: dict[Path, set[str]] = {}
    problems, checked = [], 0
    for page in site_pages(site):
        refs = parse(page)
        ids_cache[page] = refs.ids
        base = page.as_uri()
        for tag, ref in refs.refs:
            if ref.lower().startswith(EXTERNAL_SCHEMES) or ref.startswith("{{"):
                continue
            checked += 1
            url = urlparse(urljoin(base, ref))
            target = Path(unquote(url.path))
            if ref.startswith("#") or not url.path:
                target = page
            if target.is_dir():
                target = target / "index.html"
            where = f"{page.relative_to(site)}: <{tag}> {ref}"
            if not target.exists():
                problems.append(f"{where} -> missing {target}")
                continue
            try:
                target.relative_to(site)
            except ValueError:
                problems.append(f"{where} -> points outside the site")
                continue
            if url.fragment and target.suffix == ".html":
                if target not in ids_cache:
                    ids_cache[target] = parse(target).ids
                if unquote(url.fragment) not in ids_cache[target]:
                    problems.append(f"{where} -> no id {url.fragment!r} in {target.relative_to(site)}")
    return problems, checked


def test_internal_links_resolve():
    site = require_site()
    problems, checked = broken_links(site)
    SUMMARY.append(
        f"link checker: {checked} internal references on {len(site_pages(site))} pages, {len(problems)} broken"
    )
    assert checked > 100, "the link checker found almost nothing to check"
    assert not problems, "broken internal links:\n  " + "\n  ".join(problems[:50])


def test_link_checker_catches_a_broken_link(tmp_path):
    """The checker itself: a page with one good and two bad references gets exactly two problems."""
    (tmp_path / "a.html").write_text('<p id="here">x</p><a href="b.html#there">b</a>', encoding="utf-8")
    (tmp_path / "b.html").write_text(
        '<h1 id="there">b</h1><a href="a.html#here">ok</a><a href="a.html#gone">bad</a><img src="missing.png">',
        encoding="utf-8",
    )
    problems, checked = broken_links(tmp_path)
    assert checked == 4
    assert len(problems) == 2
    assert any("gone" in p for p in problems) and any("missing.png" in p for p in problems)


def test_every_page_names_its_icon():
    """Each page names the course's icon, so a browser shows it in the tab and does not ask the
    server for ``/favicon.ico`` (a 404 on every first visit, outside the site on GitHub Pages);
    the link checker above finds the file."""
    site = require_site()
    missing = [str(page.relative_to(site)) for page in site_pages(site) if not parse(page).icon]
    assert not missing, f"pages without <link rel='icon'>: {missing}"


def test_every_page_declares_its_viewport_once():
    """Three ``<meta name="viewport">`` in a head (Sphinx's, the theme's, its parent's) are
    invalid HTML; ``book/_ext/site_fixes.py`` keeps the first, which phones need."""
    site = require_site()
    counts = {
        str(p.relative_to(site)): p.read_text(encoding="utf-8").count('<meta name="viewport"') for p in site_pages(site)
    }
    wrong = {page: n for page, n in counts.items() if n != 1}
    assert not wrong, f"pages whose viewport is declared other than once: {wrong}"
