r"""Serve MathJax from the site itself, so equations render without a CDN (offline previews,
the browser tests, readers behind a firewall).

MathJax 3's files come from the pinned PyPI package ``sphinx-mathjax-offline`` (Apache-2.0).
Only the one combined component the pages load (``tex-chtml.js``, about 1.2 MB), its web
fonts and the TeX extensions it loads on demand (``\boldsymbol``, ``\cancel``, ... about 0.5 MB
on disk; a page fetches only those it uses) are copied, not the package's whole 24 MB
distribution.
"""

from __future__ import annotations

import importlib.util
from pathlib import Path

from sphinx.util.fileutil import copy_asset

_FILES = ("tex-chtml.js", "output/chtml/fonts/woff-v2", "input/tex/extensions")


def _mathjax_root() -> Path:
    spec = importlib.util.find_spec("sphinx-mathjax-offline")
    if spec is None or spec.origin is None:
        raise RuntimeError("MathJax not found: pip install sphinx-mathjax-offline (see requirements.txt)")
    return Path(spec.origin).parent / "static" / "mathjax"


def _copy(app, exc):
    if exc is not None or app.builder.format != "html":
        return
    root, dest = _mathjax_root(), Path(app.outdir) / "_static" / "mathjax"
    for rel in _FILES:
        src = root / rel
        target = dest / rel
        if src.is_dir():
            copy_asset(str(src), str(target))
        else:
            target.parent.mkdir(parents=True, exist_ok=True)
            target.write_bytes(src.read_bytes())


def setup(app):
    app.config.mathjax_path = "mathjax/tex-chtml.js"
    app.connect("build-finished", _copy)
    return {"parallel_read_safe": True, "parallel_write_safe": True}
