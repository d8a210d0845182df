"""Small fixes to the HTML the book's theme stack writes: pages load without errors, and every
part of them is reachable by landmark.

* **Scripts added twice.** Some extensions (sphinx-thebe, sphinx-togglebutton) register inline
  configuration scripts while the builder already exists, and Sphinx then emits them twice in
  every page (once with no file name, once with an empty one). A repeated
  ``const THEBE_JS_URL = ...`` is a JavaScript ``SyntaxError`` in the browser console. We drop
  exact repeats from each page's script list.
* **Icons drawn twice.** The theme's stylesheet already draws its Font Awesome icons from web
  fonts (about 0.3 MB); its page template also loads Font Awesome's 1.5 MB JavaScript, which
  redraws the same icons as SVG. After the build we remove that script tag and file: the icons
  stay, and every page is 1.5 MB lighter.
* **Empty colour mode.** The theme writes ``localStorage.mode || "{{ default_mode }}"`` into
  every page; with no default set, a first visit logs "Got invalid theme mode". We default the
  mode to ``auto`` (follow the reader's system setting), which is what the theme falls back to.
* **Bibliography roles.** docutils marks the reference list ``role="list"`` and each entry
  ``role="doc-biblioentry"``, a role that WAI-ARIA 1.2 deprecates and that is not a list item,
  so assistive technology sees a list with no items (axe-core: ``aria-required-children``,
  ``aria-deprecated-role``). Each entry becomes ``role="listitem"``.
* **The course's title outside any landmark.** The sidebar's first item, the course title that
  links to the home page, sat in no landmark, so a screen reader moving by landmarks never met
  it (axe-core: ``region``). It becomes a navigation landmark named "Course home".
* **Numbers in Python's exponent notation.** A number glued into the prose with a format such as
  ``:.1e`` read as Python prints it, ``1.4e-09``. It becomes the formula
  :math:`1.4 \\times 10^{-9}`, typeset (and spoken) like the page's other formulas, in bold
  like every other glued number.
* **A bare redirect at the site's root.** The root ``index.html`` was one ``<meta>`` tag that
  sends the browser on to the first page: no language, no title, no icon (so the browser asked
  the server for ``/favicon.ico``, a 404), and a blank page where a browser does not follow such
  redirects (a reader may turn them off). It becomes a whole page: the book's language and
  title, the course's icon, a viewport for phones, and a link to the first page for that reader.
* **Punctuation alone at the start of a line.** A browser may break a line between an inline
  formula (MathJax draws it as one inline box) and the comma, colon or bracket written against
  it, so a line could begin with a lone ``,`` or end with a lone ``(``. Each inline formula with
  punctuation against it is wrapped, with that punctuation, in a ``span.math-nobreak``, which
  ``course.css`` keeps on one line.
* **The viewport said three times.** Sphinx, the theme and its parent theme each write a
  ``<meta name="viewport">`` into the head, so every page said it three times (two of them
  ``initial-scale=1``, one ``1.0``: the same). The first is kept.
* **Code broken at its hyphens.** Inline code may break where it must, so that a long call
  never widens a phone's page (``course.css``); but a browser also breaks it after any hyphen,
  where it need not, and ``sscbirrt-`` at a line's end reads as a name that ends in a hyphen,
  ``-`` then ``> tau`` as a minus sign. Each word of inline code that holds a hyphen (Sphinx
  writes each word as a ``span.pre``) gets the class ``keep-whole``, which ``course.css`` keeps
  on one line.
* **Toggles named otherwise than they read.** sphinx-togglebutton names each ``<summary>`` that
  shows a hidden code cell "Toggle hidden content" (``aria-label``), which replaces its visible
  text, "Show code cell source", for a screen reader and for voice control, so a page of them
  was a row of identical, unspeakable buttons (WCAG 2.1, 2.5.3 Label in Name). The label goes:
  the summary is named by the text it shows.
"""

from __future__ import annotations

import html as html_text
import re
from pathlib import Path

_BIBLIOENTRY = 'role="doc-biblioentry"'
_TOGGLE_LABEL = '<summary aria-label="Toggle hidden content">'
_TITLE_ITEM = re.compile(
    r'(<div class="sidebar-primary-items__start sidebar-primary__section">\s*<div class="sidebar-primary-item")>'
)
#: An inline formula as Sphinx writes it (its TeX, HTML-escaped, holds no tag), with an opening
#: bracket just before it and closing punctuation just after it.
_INLINE_MATH = re.compile(r'([(\[]?)(<span class="math notranslate nohighlight">[^<]*</span>)([,.;:!?)\]]*)')
#: A glued number written by Python's ``e`` format: mantissa, sign and exponent.
_GLUED_EXPONENT = re.compile(r'<span class="pasted-text">(-?\d+(?:\.\d+)?)e([-+]?)(\d+)</span>')
#: A word of inline code (docutils writes each as a ``span.pre``) that holds a hyphen.
_HYPHENATED_CODE = re.compile(r'<span class="pre">([^<]*-[^<]*)</span>')
#: The redirect Jupyter Book (or sphinx-external-toc) writes as the root ``index.html``.
_REDIRECT = re.compile(r'<meta http-equiv="Refresh" content="0; url=([^"]+)" />')
#: A viewport declaration in a page's head.
_VIEWPORT = re.compile(r'\s*<meta name="viewport"[^>]*>')
_FONTAWESOME_JS = re.compile(r'\s*<script defer src="[^"]*_static/scripts/fontawesome\.js[^"]*"></script>')


def _script_key(script) -> tuple:
    attributes = getattr(script, "attributes", {}) or {}
    # An inline script is registered once with filename None and once with "" (the builder's
    # copy), so the two compare unequal in Sphinx; treat both as "inline".
    filename = getattr(script, "filename", str(script)) or ""
    return (str(filename), getattr(script, "priority", 500), tuple(sorted(attributes.items())))


def _power_of_ten(found: re.Match) -> str:
    """``1.4e-09`` as the inline formula :math:`\\mathbf{1.4 \\times 10^{-9}}`."""
    mantissa, sign, exponent = found.groups()
    power = ("-" if sign == "-" else "") + str(int(exponent))
    tex = rf"\mathbf{{{mantissa} \times 10^{{{power}}}}}"  # bold, as glued numbers are
    return f'<span class="math notranslate nohighlight">\\({tex}\\)</span>'


def _math_with_its_punctuation(found: re.Match) -> str:
    """An inline formula and the punctuation against it, in one span that does not break."""
    before, formula, after = found.groups()
    if not before and not after:
        return formula
    return f'<span class="math-nobreak">{before}{formula}{after}</span>'


def _one_viewport(html: str) -> str:
    """``html`` with its first viewport declaration only."""
    first = _VIEWPORT.search(html)
    if first is None:
        return html
    return html[: first.end()] + _VIEWPORT.sub("", html[first.end() :])


def fix_page_context(app, pagename, templatename, context, doctree):
    """``html-page-context`` handler: unique scripts, and a valid default colour mode."""
    scripts = context.get("script_files")
    if isinstance(scripts, list):
        seen, unique = set(), []
        for script in scripts:
            key = _script_key(script)
            if key not in seen:
                seen.add(key)
                unique.append(script)
        scripts[:] = unique
    if not context.get("default_mode"):
        context["default_mode"] = "auto"


def fix_built_pages(app, exc):
    """``build-finished`` handler: remove the redundant Font Awesome script from every page, give
    bibliography entries the list-item role, name each toggle by its text, put the course title
    in a landmark, write glued numbers in exponent notation as powers of ten, keep each inline
    formula on one line with the punctuation against it, keep each hyphenated word of inline
    code whole, and keep one viewport declaration."""
    if exc is not None or app.builder.format != "html":
        return
    out = Path(app.outdir)
    for page in out.rglob("*.html"):
        html = page.read_text(encoding="utf-8")
        lighter = _FONTAWESOME_JS.sub("", html).replace(_BIBLIOENTRY, 'role="listitem"')
        lighter = lighter.replace(_TOGGLE_LABEL, "<summary>")
        lighter = _TITLE_ITEM.sub(r'\1 role="navigation" aria-label="Course home">', lighter, count=1)
        lighter = _GLUED_EXPONENT.sub(_power_of_ten, lighter)
        lighter = _INLINE_MATH.sub(_math_with_its_punctuation, lighter)
        lighter = _HYPHENATED_CODE.sub(r'<span class="pre keep-whole">\1</span>', lighter)
        lighter = _one_viewport(lighter)
        if lighter != html:
            page.write_text(lighter, encoding="utf-8")
    _complete_the_redirect(out / "index.html", app.config)
    for name in ("fontawesome.js", "fontawesome.js.map"):
        (out / "_static" / "scripts" / name).unlink(missing_ok=True)


def _complete_the_redirect(redirect: Path, config) -> None:
    """Make the root redirect page a whole page (WCAG 2.4.2 and 3.1.1): the book's language and
    title, its icon (which Sphinx copies into ``_static``), a viewport, and a link to the first page."""
    found = _REDIRECT.search(redirect.read_text(encoding="utf-8")) if redirect.is_file() else None
    if found is None:
        return
    url, title = found[1], html_text.escape(config.html_title or config.project)
    icon = f'<link rel="icon" href="_static/{Path(config.html_favicon).name}" />\n' if config.html_favicon else ""
    redirect.write_text(
        f'<!DOCTYPE html>\n<html lang="{config.language or "en"}">\n<head>\n<meta charset="utf-8" />\n'
        '<meta name="viewport" content="width=device-width, initial-scale=1" />\n'
        f"<title>{title}</title>\n{icon}{found[0]}\n</head>\n"
        f'<body>\n<main>\n<p>The course starts at <a href="{url}">{title}</a>.</p>\n</main>\n</body>\n</html>\n',
        encoding="utf-8",
    )


def setup(app):
    # Run after the theme has filled the context (its handlers use the default priority 500).
    app.connect("html-page-context", fix_page_context, priority=900)
    app.connect("build-finished", fix_built_pages)
    return {"parallel_read_safe": True, "parallel_write_safe": True}
