"""Ties between notebooks and the book: what a page shows comes from the package and from
executed outputs, so page, code and results cannot drift apart.

* :func:`glue` stores a value under a name with MyST-NB, so a page's text can cite it with
  ``{glue:text}`name:.3f```. Without MyST-NB (Colab) it does nothing.
* :func:`show_law` displays the source of a control law of :mod:`labsupport` as highlighted
  code, right under the equation it implements.
"""

from __future__ import annotations

import ast
import inspect
import textwrap
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


def law_source(fn: Callable, docstring: bool = False) -> str:
    """The source code of ``fn`` as written in its module, without its docstring unless
    ``docstring=True`` (the page shows the equation just above it)."""
    try:
        source = textwrap.dedent(inspect.getsource(fn))
    except (TypeError, OSError):
        raise ValueError(f"show_law needs a function defined in a source file, got {fn!r}") from None
    if docstring:
        return source.rstrip() + "\n"
    node = ast.parse(source).body[0]
    body = getattr(node, "body", [])
    lines = source.splitlines()
    if (
        body
        and isinstance(body[0], ast.Expr)
        and isinstance(getattr(body[0], "value", None), ast.Constant)
        and isinstance(body[0].value.value, str)
    ):
        del lines[body[0].lineno - 1 : body[0].end_lineno]
    return "\n".join(lines).rstrip() + "\n"


def show_law(fn: Callable, docstring: bool = False) -> None:
    """Display the code of a control law (its source, taken from the function itself) as a
    highlighted Python block in the notebook and on the built page.

    The block is Markdown with a fenced ``python`` code block: Jupyter and Colab highlight it,
    and MyST-NB renders it as the book's ordinary highlighted code block.
    """
    source = law_source(fn, docstring)
    fence = "```"
    while fence in source:
        fence += "`"
    display(Markdown(f"{fence}python\n{source}{fence}"))
