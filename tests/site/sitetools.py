"""Helpers and fixtures for the tests of the built site: pages, a local web server, a browser.

These tests run after the book build (``bash .ci/build-book``) and read ``_build/html``; set
``BOOK_HTML`` to test a site built elsewhere. The browser is Debian's Chromium
(``/usr/bin/chromium``, or ``$CHROMIUM``) driven by Playwright; no browser is ever downloaded.
The site serves MathJax itself (book/_ext/local_mathjax.py), so every page must load with no
request leaving localhost: any such request is refused and reported.

Every page is loaded once; what the browser saw (console messages, requests, images, videos,
MathJax) is recorded in a :class:`PageReport` that the individual tests check.
"""

from __future__ import annotations

import functools
import http.server
import json
import os
import re
import threading
from dataclasses import dataclass, field
from pathlib import Path
from urllib.parse import unquote, urlparse

import pytest
import yaml

ROOT = Path(__file__).resolve().parents[2]
SITE = Path(os.environ.get("BOOK_HTML", ROOT / "_build" / "html")).resolve()
ARTIFACTS = ROOT / "tests" / "artifacts"
CHROMIUM = os.environ.get("CHROMIUM", "/usr/bin/chromium")
CHROMIUM_ARGS = [
    "--headless",
    "--no-sandbox",
    "--disable-gpu",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
    "--no-first-run",
    "--autoplay-policy=no-user-gesture-required",
]
#: Pages whose screenshots are saved under tests/artifacts/screenshots.
SCREENSHOT_PAGES = (
    "book/intro",
    "book/theory",
    "notebooks/task1_single_joint",
    "notebooks/task3_planar_2r",
    "notebooks/task4_ur5e",
)
VIEWPORT = {"width": 1280, "height": 900}
#: Window widths a reader may use: a small laptop, the narrowest window with both sidebars
#: (the theme shows the in-page table of contents from 1200 px), a common laptop, a desktop.
WIDTHS = (1024, 1200, 1280, 1920)


# --------------------------------------------------------------------------------------------
# The book's configuration and pages
# --------------------------------------------------------------------------------------------
def book_config() -> dict:
    return yaml.safe_load((ROOT / "_config.yml").read_text(encoding="utf-8"))


def toc_pages() -> list[str]:
    """Every page of ``_toc.yml`` (document names without suffix), root first."""
    toc = yaml.safe_load((ROOT / "_toc.yml").read_text(encoding="utf-8"))
    pages = [toc["root"]]

    def walk(entries):
        for entry in entries or []:
            if "file" in entry:
                pages.append(entry["file"])
            walk(entry.get("sections"))
            for part in entry.get("parts", []) or []:
                walk(part.get("chapters"))

    for part in toc.get("parts", []) or []:
        walk(part.get("chapters"))
    walk(toc.get("chapters"))
    return [re.sub(r"\.(md|ipynb)$", "", p) for p in pages]


def is_notebook(page: str) -> bool:
    return (ROOT / f"{page}.ipynb").exists()


def expected_colab_url(page: str) -> str:
    """The Colab URL of a notebook page, built from ``_config.yml``'s repository settings."""
    config = book_config()
    repo = config["repository"]
    parts = urlparse(repo["url"].rstrip("/"))
    if parts.netloc != "github.com":
        raise ValueError(f"repository.url must be a github.com URL, got {repo['url']!r}")
    org_repo = parts.path.strip("/")
    colab = config.get("launch_buttons", {}).get("colab_url", "https://colab.research.google.com")
    prefix = (repo.get("path_to_book") or "").strip("/")
    path = f"{prefix}/{page}.ipynb" if prefix else f"{page}.ipynb"
    return f"{colab.rstrip('/')}/github/{org_repo}/blob/{repo.get('branch', 'main')}/{path}"


def require_site() -> Path:
    if not (SITE / "index.html").exists():
        pytest.fail(
            f"no built site at {SITE}: run `bash .ci/build-book` first (tests/site checks the built book)",
            pytrace=False,
        )
    return SITE


# --------------------------------------------------------------------------------------------
# A local web server for the built site
# --------------------------------------------------------------------------------------------
class _QuietHandler(http.server.SimpleHTTPRequestHandler):
    def log_message(self, format, *args):  # noqa: A002 - signature of the base class
        pass


@pytest.fixture(scope="session")
def site() -> Path:
    return require_site()


@pytest.fixture(scope="session")
def server(site):
    handler = functools.partial(_QuietHandler, directory=str(site))
    httpd = http.server.ThreadingHTTPServer(("127.0.0.1", 0), handler)
    thread = threading.Thread(target=httpd.serve_forever, daemon=True)
    thread.start()
    yield f"http://127.0.0.1:{httpd.server_address[1]}"
    httpd.shutdown()
    httpd.server_close()


# --------------------------------------------------------------------------------------------
# The browser and one visit per page
# --------------------------------------------------------------------------------------------
@dataclass
class PageReport:
    """What the browser saw while loading one page."""

    page: str
    console_errors: list[str] = field(default_factory=list)
    page_errors: list[str] = field(default_factory=list)
    failed_requests: list[str] = field(default_factory=list)
    external_requests: list[str] = field(default_factory=list)
    #: URL -> bytes for every local file the page loaded.
    loaded: dict[str, int] = field(default_factory=dict)
    math: dict = field(default_factory=dict)
    images: dict = field(default_factory=dict)
    videos: list[dict] = field(default_factory=list)
    links: list[dict] = field(default_factory=list)


MATH_JS = r"""
async () => {
  if (window.MathJax && MathJax.startup && MathJax.startup.promise) {
    await MathJax.startup.promise;
  }
  const mathEls = [...document.querySelectorAll('.math')];
  const untypeset = mathEls.filter(el => !el.querySelector('mjx-container'))
                           .map(el => el.textContent.trim().slice(0, 80));
  const merrors = [...document.querySelectorAll('mjx-merror')]
                    .map(e => e.getAttribute('data-mjx-error') || e.textContent.slice(0, 80));
  const root = document.querySelector('main') || document.body;
  const walker = document.createTreeWalker(root, NodeFilter.SHOW_TEXT, {
    acceptNode: n => n.parentElement.closest('pre, code, script, style, textarea, mjx-container')
                       ? NodeFilter.FILTER_REJECT : NodeFilter.FILTER_ACCEPT});
  const raw = [];
  while (walker.nextNode()) {
    const t = walker.currentNode.nodeValue;
    // a TeX command (\tilde, \frac, ...) or delimiter left in the text: math MathJax never saw
    if (t.includes('$$') || /\\\(|\\\[|\\[a-zA-Z]{2,}|\$\\/.test(t)) raw.push(t.trim().slice(0, 80));
  }
  return {hasMathJax: !!window.MathJax, nMath: mathEls.length,
          nTypeset: document.querySelectorAll('mjx-container').length,
          untypeset, merrors, raw};
}
"""

IMAGES_JS = r"""
async () => {
  const imgs = [...document.images];
  const bad = [];
  for (const img of imgs) {
    img.loading = 'eager';
    try { await img.decode(); } catch (e) {}
    if (!(img.complete && img.naturalWidth > 0)) bad.push(img.getAttribute('src'));
  }
  return {n: imgs.length, bad, srcs: imgs.map(i => i.currentSrc || i.src)};
}
"""

VIDEOS_JS = r"""
async () => {
  const out = [];
  for (const v of document.querySelectorAll('video')) {
    const src = v.currentSrc || v.src || (v.querySelector('source') || {}).src || '';
    if (v.readyState < 1 && !v.error) {
      await new Promise(res => {
        v.addEventListener('loadedmetadata', res, {once: true});
        v.addEventListener('error', res, {once: true});
        setTimeout(res, 10000);
        v.load();
      });
    }
    let played = false, playError = null;
    if (!v.error) {
      v.muted = true;
      const t0 = v.currentTime;
      try {
        await v.play();
        await new Promise(res => setTimeout(res, 400));
        played = v.currentTime > t0 || v.ended;
      } catch (e) { playError = String(e); }
      v.pause();
    }
    out.push({src: src.startsWith('data:') ? src.slice(0, 30) + '...' : src,
              type: src.startsWith('data:') ? src.slice(5, src.indexOf(';')) :
                    ((v.querySelector('source') || {}).type || ''),
              duration: v.duration, error: v.error ? v.error.code : null,
              played, playError, width: v.videoWidth, height: v.videoHeight});
  }
  return out;
}
"""

LINKS_JS = r"""
() => [...document.querySelectorAll('a[href]')].map(a => ({
  href: a.getAttribute('href'), abs: a.href, text: a.textContent.trim().slice(0, 60),
  title: a.getAttribute('title') || '', cls: a.className || ''}))
"""


def _local_size(site: Path, server: str, url: str) -> int | None:
    if not url.startswith(server):
        return None
    path = unquote(urlparse(url).path).lstrip("/")
    target = site / path
    if target.is_dir():
        target = target / "index.html"
    return target.stat().st_size if target.is_file() else None


@pytest.fixture(scope="session")
def browser():
    if not Path(CHROMIUM).exists():
        pytest.fail(
            f"Chromium not found at {CHROMIUM}: install Debian's `chromium` (bash .ci/setup does), or set $CHROMIUM",
            pytrace=False,
        )
    from playwright.sync_api import sync_playwright

    with sync_playwright() as p:
        b = p.chromium.launch(executable_path=CHROMIUM, args=CHROMIUM_ARGS)
        yield b
        b.close()


@pytest.fixture(scope="session")
def visit(browser, server, site):
    """``visit(page) -> PageReport``; each page is loaded once per session."""
    cache: dict[str, PageReport] = {}
    shots = ARTIFACTS / "screenshots"

    def refuse_external(route, request, report: PageReport):
        report.external_requests.append(request.url)
        return route.abort()

    def _visit(page: str) -> PageReport:
        if page in cache:
            return cache[page]
        report = PageReport(page)
        context = browser.new_context(viewport=VIEWPORT)
        context.route(
            re.compile(r"^https?://(?!127\.0\.0\.1[:/]).*"),
            lambda route, request: refuse_external(route, request, report),
        )
        tab = context.new_page()
        tab.on(
            "console",
            lambda msg: (
                report.console_errors.append(f"{msg.text} @ {msg.location.get('url', '')}")
                if msg.type == "error"
                else None
            ),
        )
        tab.on("pageerror", lambda exc: report.page_errors.append(str(exc)))
        tab.on("requestfailed", lambda req: report.failed_requests.append(f"{req.url} ({req.failure})"))

        def on_response(resp):
            if resp.status >= 400:
                report.failed_requests.append(f"{resp.url} (HTTP {resp.status})")
            size = _local_size(site, server, resp.url)
            if size is not None:
                report.loaded[resp.url.split("?")[0]] = size

        tab.on("response", on_response)
        tab.goto(f"{server}/{page}.html", wait_until="load")
        report.math = tab.evaluate(MATH_JS)
        report.images = tab.evaluate(IMAGES_JS)
        report.videos = tab.evaluate(VIDEOS_JS)
        report.links = tab.evaluate(LINKS_JS)
        tab.wait_for_load_state("networkidle")
        if page in SCREENSHOT_PAGES:
            shots.mkdir(parents=True, exist_ok=True)
            name = page.replace("/", "__")
            tab.evaluate("() => window.scrollTo(0, 0)")
            tab.screenshot(path=str(shots / f"{name}.png"))
            for kind in ("div.math", "img[src*='_images']", "video"):
                el = tab.query_selector(f"main {kind}")
                if el is not None:
                    el.scroll_into_view_if_needed()
                    tab.wait_for_timeout(200)
                    tab.screenshot(path=str(shots / f"{name}__{kind.split('[')[0].replace('.', '_')}.png"))
        context.close()
        cache[page] = report
        return report

    return _visit


# --------------------------------------------------------------------------------------------
# Figures printed at the end of the run (by conftest's terminal-summary hook)
# --------------------------------------------------------------------------------------------
SUMMARY: list[str] = []


def dump_json(name: str, data) -> None:
    ARTIFACTS.mkdir(parents=True, exist_ok=True)
    (ARTIFACTS / name).write_text(json.dumps(data, indent=1, default=str), encoding="utf-8")


@pytest.fixture()
def tab_page(browser, server):
    """``tab_page(page, width=1280)``: a fresh browser tab showing ``page`` in a window
    ``width`` px wide, for tests that interact with it (closed after the test)."""
    contexts = []

    def open_page(page: str, width: int = VIEWPORT["width"]):
        context = browser.new_context(viewport={"width": width, "height": VIEWPORT["height"]})
        contexts.append(context)
        tab = context.new_page()
        tab.goto(f"{server}/{page}.html", wait_until="load")
        return tab

    yield open_page
    for context in contexts:
        context.close()


#: Waits for MathJax to typeset the page (where it has formulas), then runs the function ``js``.
_AFTER_MATHJAX = (
    "async () => {{ if (window.MathJax?.startup?.promise) await MathJax.startup.promise; return ({js})(); }}"
)


@pytest.fixture()
def on_every_page(browser, server):
    """``on_every_page(js, width)``: ``{page: result}`` of the script ``js`` (a JavaScript
    function) run on every page of the book, once typeset, in one window ``width`` px wide."""

    def run(js: str, width: int) -> dict:
        context = browser.new_context(viewport={"width": width, "height": VIEWPORT["height"]})
        try:
            tab = context.new_page()
            results = {}
            for page in toc_pages():
                tab.goto(f"{server}/{page}.html", wait_until="load")
                results[page] = tab.evaluate(_AFTER_MATHJAX.format(js=js))
            return results
        finally:
            context.close()

    return run
