"""Ties between notebooks and the book: numbers shown in prose come from executed outputs.

:func:`glue` stores a value under a name with MyST-NB, so a page's text can cite it with
``{glue:text}`name:.3f``` and prose and results cannot drift apart. Without MyST-NB (Colab)
it does nothing.
"""

from __future__ import annotations

from typing import Any


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
