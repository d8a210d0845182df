"""Page weight: each page with everything it loads stays under 3 MB, the whole site under 30 MB,
and media are light formats (PNG/SVG figures of sensible size, MP4 video).

A page's weight is counted for a first visit (nothing cached): its HTML plus every file the
browser loaded for it (theme scripts, stylesheets, fonts, MathJax, figures, videos) plus the
files it refers to that a browser may load later (lazy images). Two figures are kept per page:

* **transfer** — the bytes a reader downloads: text resources (HTML, CSS, JavaScript, SVG, ...)
  are compressed on the way, as GitHub Pages does (gzip here), while media
  (PNG, MP4, WOFF2) count as they are. This is the page weight the 3 MB limit applies to.
* **raw** — the same files uncompressed, for information; the theme and MathJax alone are about
  3.8 MB of it, on every page.

On top of that, a page's **own content** (its HTML with any embedded video, and the figures
and videos it shows) must stay under 3 MB even uncompressed.
"""

from __future__ import annotations

import functools
import gzip
import re
import struct
from pathlib import Path
from urllib.parse import unquote, urljoin, urlparse

import pytest
from sitetools import SUMMARY, dump_json, require_site, toc_pages
from test_links import parse

MB = 1_000_000
PAGE_LIMIT = 3 * MB
SITE_LIMIT = 30 * MB
#: Suffixes a web server compresses on the way (media formats are compressed already).
COMPRESSIBLE = {
    ".html",
    ".css",
    ".js",
    ".mjs",
    ".svg",
    ".json",
    ".txt",
    ".xml",
    ".map",
    ".ttf",
    ".otf",
    ".eot",
    ".ipynb",
    ".inv",
}
#: Asset references that a browser fetches when it shows the page.
LOADED = {"img", "script", "source", "video"}
CONTENT = {"img", "source", "video"}
PAGES = toc_pages()
WEIGHTS: dict[str, dict] = {}


@functools.cache
def transfer_size(path: Path) -> int:
    """Bytes on the wire: gzip-compressed for text resources, as stored for media."""
    data = path.read_bytes()
    if path.suffix.lower() in COMPRESSIBLE:
        return len(gzip.compress(data, compresslevel=6))
    return len(data)


def referenced_files(site: Path, page: Path, tags=LOADED) -> dict[str, Path]:
    """Local files a page refers to with the given tags (and its stylesheets, for ``script``)."""
    files = {}
    refs = [r for r in parse(page).refs if r[0] in tags]
    if "script" in tags:
        text = page.read_text(encoding="utf-8", errors="replace")
        refs += [("link", s) for s in re.findall(r'<link[^>]*rel="stylesheet"[^>]*href="([^"]+)"', text)]
    for _tag, ref in refs:
        if ref.lower().startswith(("http:", "https:", "data:")):
            continue
        path = Path(unquote(urlparse(urljoin(page.as_uri(), ref)).path))
        if path.is_file():
            files[str(path.relative_to(site))] = path
    return files


def page_weight(site: Path, page: str, loaded_urls) -> dict:
    """Raw and transfer bytes of a page and everything it loads, and of its own content."""
    html = site / f"{page}.html"
    files = referenced_files(site, html)
    for url in loaded_urls:
        parts = urlparse(url)
        if parts.hostname == "127.0.0.1":
            rel = unquote(parts.path).lstrip("/")
            if rel != f"{page}.html" and (site / rel).is_file():
                files[rel] = site / rel
    resources = [html] + [p for p in files.values() if p.is_file()]
    content = [html] + list(referenced_files(site, html, CONTENT).values())
    largest = sorted(((str(k), p.stat().st_size) for k, p in files.items() if p.is_file()), key=lambda kv: -kv[1])[:3]
    return {
        "raw": sum(p.stat().st_size for p in resources),
        "transfer": sum(transfer_size(p) for p in resources),
        "content": sum(p.stat().st_size for p in content),
        "html": html.stat().st_size,
        "files": len(resources),
        "largest": largest,
    }


@pytest.mark.parametrize("page", PAGES)
def test_page_weight(visit, page):
    site = require_site()
    w = page_weight(site, page, visit(page).loaded)
    WEIGHTS[page] = w
    if len(WEIGHTS) == len(PAGES):
        _summarise()
    assert w["transfer"] <= PAGE_LIMIT, (
        f"{page}: a first visit downloads {w['transfer'] / MB:.2f} MB (limit 3 MB); largest files {w['largest']}"
    )
    assert w["content"] <= PAGE_LIMIT, (
        f"{page}: its own HTML, figures and videos weigh {w['content'] / MB:.2f} MB (limit 3 MB)"
    )


def _summarise():
    SUMMARY.append(
        "page weight, first visit (transfer = downloaded bytes, text compressed; "
        "raw = uncompressed; content = the page's HTML, figures and videos):"
    )
    SUMMARY.append(f"  {'page':38s} {'transfer MB':>11s} {'raw MB':>7s} {'content MB':>10s} {'files':>5s}")
    for page, w in WEIGHTS.items():
        SUMMARY.append(
            f"  {page:38s} {w['transfer'] / MB:11.3f} {w['raw'] / MB:7.3f} {w['content'] / MB:10.3f} {w['files']:5d}"
        )
    dump_json("page_weight.json", WEIGHTS)


def site_size(site: Path) -> int:
    return sum(p.stat().st_size for p in site.rglob("*") if p.is_file())


def test_site_size():
    site = require_site()
    total = site_size(site)
    by_dir: dict[str, int] = {}
    for p in site.rglob("*"):
        if p.is_file():
            top = p.relative_to(site).parts[0] if len(p.relative_to(site).parts) > 1 else "(top)"
            by_dir[top] = by_dir.get(top, 0) + p.stat().st_size
    SUMMARY.append(
        f"whole site: {total / MB:.2f} MB (limit 30 MB); "
        + ", ".join(f"{k} {v / MB:.2f}" for k, v in sorted(by_dir.items(), key=lambda kv: -kv[1]))
    )
    assert total < SITE_LIMIT, f"the site weighs {total / MB:.1f} MB (limit 30 MB)"


def png_size(path: Path) -> tuple[int, int]:
    """(width, height) of a PNG, read from its IHDR chunk."""
    with path.open("rb") as f:
        head = f.read(24)
    if head[:8] != b"\x89PNG\r\n\x1a\n":
        raise ValueError(f"{path} is not a PNG")
    return struct.unpack(">II", head[16:24])


def test_figures_are_light():
    """Figures are PNG (or SVG/JPEG) at a screen resolution, not print-resolution bitmaps."""
    site = require_site()
    images = [p for p in (site / "_images").glob("*") if p.is_file()] if (site / "_images").exists() else []
    heavy = []
    for img in images:
        assert img.suffix.lower() in {".png", ".svg", ".jpg", ".jpeg", ".gif"}, f"unexpected figure {img.name}"
        if img.suffix.lower() == ".png":
            width, height = png_size(img)
            if width > 2400 or height > 2400 or img.stat().st_size > 600_000:
                heavy.append(f"{img.name}: {width}x{height}, {img.stat().st_size / 1e3:.0f} kB")
    assert not heavy, "figures too large (use dpi ~100):\n  " + "\n  ".join(heavy)


def test_png_reader():
    """png_size reads a PNG header written here."""
    import zlib

    def chunk(kind, data):
        return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data))

    raw = b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", 37, 11, 8, 2, 0, 0, 0))
    import tempfile

    with tempfile.TemporaryDirectory() as d:
        p = Path(d) / "x.png"
        p.write_bytes(raw)
        assert png_size(p) == (37, 11)


@pytest.mark.parametrize("page", PAGES)
def test_video_is_mp4_not_frames(page):
    """Animations are MP4 video, not matplotlib's frame-by-frame JavaScript (to_jshtml)."""
    site = require_site()
    html = (site / f"{page}.html").read_text(encoding="utf-8", errors="replace")
    assert '<div class="animation">' not in html and "anim_step_forward" not in html.lower(), (
        f"{page} embeds a frame-by-frame animation; encode MP4 instead"
    )
    for m in re.finditer(r'<(?:video|source)\b[^>]*\bsrc="([^"]{0,40})', html):
        src = m.group(1)
        assert src.startswith("data:video/mp4") or src.split("?")[0].endswith(".mp4"), (
            f"{page}: video source {src!r} is not MP4"
        )
