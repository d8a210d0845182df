"""Benchmark: building the book, cold and after a change to the prose.

1. **Cold build**: the whole book, every notebook executed, from nothing (no ``_build``, no
   execution cache). Target: at most 5 minutes on the 2-core machine.
2. **Prose-only rebuild**: one sentence added to a page of ``book/``, then the same build
   command again. The execution cache must keep every notebook from running again.
   Target: at most 30 s.

Both builds run the command of ``.ci/build-book`` (``jupyter-book build . --builder html -W
--keep-going``) in a temporary copy of the checkout (its tracked and non-ignored files), so the
working tree and its ``_build`` are never touched, and the page is "restored" by construction.

Run: ``.venv/bin/python tests/benchmarks/bench_book.py``
"""

from __future__ import annotations

import os
import re
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
COLD_TARGET_S = 300.0
PROSE_TARGET_S = 30.0
PROSE_PAGE = "book/setup.md"


def copy_checkout(dest: Path) -> None:
    """Copy the files git tracks or would track (nothing ignored: no .venv, no _build)."""
    names = subprocess.run(
        ["git", "-C", str(ROOT), "ls-files", "-z", "--cached", "--others", "--exclude-standard"],
        capture_output=True,
        check=True,
    ).stdout.split(b"\0")
    for name in filter(None, names):
        src = ROOT / os.fsdecode(name)
        if src.is_file():
            target = dest / os.fsdecode(name)
            target.parent.mkdir(parents=True, exist_ok=True)
            shutil.copy2(src, target)


def build(book: Path) -> tuple[float, int, bool]:
    """``(seconds, notebooks executed, succeeded)`` for one build of ``book``."""
    jupyter_book = Path(sys.executable).parent / "jupyter-book"
    env = dict(os.environ, MUJOCO_GL=os.environ.get("MUJOCO_GL", "egl"))
    start = time.perf_counter()
    out = subprocess.run(
        [str(jupyter_book), "build", ".", "--builder", "html", "-W", "--keep-going"],
        cwd=book,
        env=env,
        capture_output=True,
        text=True,
    )
    seconds = time.perf_counter() - start
    log = out.stdout + out.stderr
    executed = len(re.findall(r"Executing notebook", log))
    if out.returncode != 0:
        print(log[-4000:])
    return seconds, executed, out.returncode == 0


def main() -> int:
    print(f"machine: {os.cpu_count()} cores; book: {ROOT.name}")
    with tempfile.TemporaryDirectory(prefix="bench-book-") as tmp:
        book = Path(tmp) / "book"
        copy_checkout(book)
        n_notebooks = len(list((book / "notebooks").glob("*.ipynb")))

        cold, executed, ok_cold = build(book)
        print(
            f"cold build, {executed}/{n_notebooks} notebooks executed: {cold:7.1f} s "
            f"(target <= {COLD_TARGET_S:.0f} s) {'ok' if cold <= COLD_TARGET_S else 'OVER TARGET'}"
            f"{'' if ok_cold else '  [BUILD FAILED]'}"
        )

        page = book / PROSE_PAGE
        page.write_text(
            page.read_text(encoding="utf-8") + "\nThis sentence was added by the build benchmark.\n", encoding="utf-8"
        )
        prose, executed, ok_prose = build(book)
        print(
            f"rebuild after a prose-only change to {PROSE_PAGE}, {executed} notebooks executed: "
            f"{prose:7.1f} s (target <= {PROSE_TARGET_S:.0f} s) "
            f"{'ok' if prose <= PROSE_TARGET_S and executed == 0 else 'OVER TARGET'}"
            f"{'' if ok_prose else '  [BUILD FAILED]'}"
        )
        html = (book / "_build" / "html" / PROSE_PAGE).with_suffix(".html")
        if "added by the build benchmark" not in html.read_text(encoding="utf-8"):
            print("the rebuilt page does not show the change")
            return 1
    return 0 if (ok_cold and ok_prose) else 1


if __name__ == "__main__":
    sys.exit(main())
