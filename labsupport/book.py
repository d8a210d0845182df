"""Ties between notebooks and the book: what a page shows comes from the package and from
executed outputs, so page, code and results cannot drift apart.

* :func:`glue` stores a value under a name with MyST-NB, so a page's text can cite it with
  ``{glue:text}`name:.3f```. Without MyST-NB (Colab) it does nothing.
* :func:`show_law` displays the source of a control law of :mod:`labsupport` as highlighted
  code, right under the equation it implements.
"""

from __future__ import annotations

import inspect
from collections.abc import Callable
from typing import Any

from IPython.display import Markdown, display


def glue(name: str, value: Any, display: bool = False) -> None:
    """Record ``value`` under ``name`` for the book's ``{glue:...}`` roles; returns nothing, so a
    cell that ends with it shows no stray output.

    NumPy scalars are stored as Python numbers, so format specs such as ``:.3f`` work on them
    (NumPy 2 writes ``np.float64(1.0)`` as their text form otherwise).
    """
    if hasattr(value, "item") and getattr(value, "shape", None) == ():
        value = value.item()
    try:
        from myst_nb import glue as _glue
    except ImportError:  # Colab or a bare kernel: nothing to record into
        return
    _glue(name, value, display=display)


def show_law(fn: Callable) -> None:
    """Display the code of a control law, its source exactly as ``inspect.getsource`` gives it
    (docstring and equation included), as a highlighted Python block in the notebook and on the
    built page.

    The block is Markdown holding a fenced ``python`` code block: Jupyter and Colab highlight
    it, and MyST-NB renders it as the book's ordinary highlighted code block.
    """
    try:
        source = inspect.getsource(fn).rstrip() + "\n"
    except (TypeError, OSError):
        raise ValueError(f"show_law needs a function defined in a source file, got {fn!r}") from None
    fence = "```"
    while fence in source:
        fence += "`"
    display(Markdown(f"{fence}python\n{source}{fence}"))
