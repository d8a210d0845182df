"""Ties between notebooks and the book: what a page shows comes from the package and from
executed outputs, so page, code and results cannot drift apart.

* :func:`glue` stores a value under a name with MyST-NB, so a page's text can cite it with
  ``{glue:text}`name:.3f```. Without MyST-NB (Colab), where the text shows that role as it is
  written, it prints ``name = value`` instead, so the number the text cites is on the screen.
* :func:`show_law` displays the source of a control law of :mod:`labsupport` as highlighted
  code (its docstring left out), right under the equation it implements.
* :func:`show_figure` shows a figure with the text alternative the notebook writes for it from
  the values it plots, so picture and words cannot drift apart.
"""

from __future__ import annotations

import ast
import base64
import inspect
import io
import re
import textwrap
from collections.abc import Callable
from html import escape
from typing import Any

import numpy as np
from IPython.display import Markdown, display

from labsupport import validate

#: The fewest words a figure's text alternative may have.
MIN_ALT_WORDS = 5
#: A line at least this wide [pt] (a reference drawn as a band) counts as a style of its own.
WIDE_LINE = 3.0
#: The label of the collapsed description under each figure: its text alternative, for the eye
#: too, and for a screen reader that would move through it word by word.
FIGURE_IN_WORDS = "The figure in words"
#: Pixels of a figure's PNG per pixel it is shown at (CSS pixel): two, so that its labels stay
#: sharp on phones and high-density screens, and when a reader zooms in on them.
PIXEL_DENSITY = 2


def glue(name: str, value: Any, display: bool = False) -> None:
    """Record ``value`` under ``name`` for the book's ``{glue:...}`` roles; returns nothing, so a
    cell that ends with it shows no stray output in the book.

    NumPy scalars are stored as Python numbers, so format specs such as ``:.3f`` work on them
    (NumPy 2 writes ``np.float64(1.0)`` as their text form otherwise).

    Without MyST-NB (Colab, or the package installed on its own) the notebook's Markdown shows
    ``{glue:text}`name:.3f``` as it is written, so the value is printed as ``name = value``
    (numbers to six significant digits): the student finds the number the text cites by its name.
    """
    if hasattr(value, "item") and getattr(value, "shape", None) == ():
        value = value.item()
    try:
        from myst_nb import glue as _glue
    except ImportError:  # Colab or a bare kernel: nothing to record into, so show it
        shown = f"{value:.6g}" if isinstance(value, float) else str(value)
        print(f"{name} = {shown}")
        return
    _glue(name, value, display=display)


def law_source(fn: Callable) -> str:
    """The source of ``fn`` as ``inspect.getsource`` gives it, less its docstring: the code a
    page shows under the law's equation, which the page states in its own Markdown. A
    ``ValueError`` for a function without a source file."""
    try:
        source = inspect.getsource(fn)
    except (TypeError, OSError):
        raise ValueError(f"show_law needs a function defined in a source file, got {fn!r}") from None
    lines = source.splitlines()
    code = textwrap.dedent(source)  # a method's source is indented; the line numbers stay
    node = ast.parse(code).body[0]
    if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)) and ast.get_docstring(node, clean=False) is not None:
        doc, dedented = node.body[0], code.splitlines()
        before = dedented[doc.lineno - 1][: doc.col_offset]
        after = dedented[doc.end_lineno - 1][doc.end_col_offset :]
        if not before.strip() and not after.strip():  # the docstring has lines of its own
            del lines[doc.lineno - 1 : doc.end_lineno]
    return "\n".join(lines).rstrip() + "\n"


def show_law(fn: Callable) -> None:
    """Display the code of a control law, :func:`law_source` (its source less the docstring,
    whose equation the page writes out in Markdown just above), as a highlighted Python block
    in the notebook and on the built page.

    The block is Markdown holding a fenced ``python`` code block: Jupyter and Colab highlight
    it, and MyST-NB renders it as the book's ordinary highlighted code block.
    """
    source = law_source(fn)
    fence = "```"
    while fence in source:
        fence += "`"
    display(Markdown(f"{fence}python\n{source}{fence}"))


#: A number in Python's exponent notation (``f"{x:.1e}"``): mantissa and exponent.
EXPONENT_NUMBER = re.compile(r"(?<![\w.])(-?\d+(?:\.\d+)?)e([-+]?\d+)\b")
_SUPERSCRIPT = str.maketrans("-0123456789", "⁻⁰¹²³⁴⁵⁶⁷⁸⁹")


def power_of_ten(text: str) -> str:
    """``text`` with each number in Python's exponent notation written as a power of ten, the
    way a reader (or a screen reader) says it: ``1.4e-09`` becomes ``1.4 × 10⁻⁹``."""

    def written(found: re.Match) -> str:
        mantissa, exponent = found.groups()
        return f"{mantissa} × 10{str(int(exponent)).translate(_SUPERSCRIPT)}"

    return EXPONENT_NUMBER.sub(written, text)


def text_alternative(alt, what: str = "a figure") -> str:
    """``alt`` with its white space collapsed and its numbers in exponent notation written as
    powers of ten (:func:`power_of_ten`), or a ``ValueError`` when it cannot be a text
    alternative (WCAG 2.1, 1.1.1): fewer than :data:`MIN_ALT_WORDS` words, or a file name."""
    text = power_of_ten(" ".join(alt.split())) if isinstance(alt, str) else ""
    if len(re.findall(r"\w+", text)) < MIN_ALT_WORDS or re.search(r"\.(png|jpe?g|svg|mp4)$", text, re.IGNORECASE):
        raise ValueError(
            f"{what} needs a text alternative of at least {MIN_ALT_WORDS} words that says what it shows, got {alt!r}"
        )
    return text


def show_figure(figure, alt: str, *, density: int = 1) -> None:
    """Show ``figure`` (a Matplotlib figure, or an RGB image array such as a rendered frame) with
    ``alt``, its text alternative (WCAG 2.1, success criterion 1.1.1), which is also written
    under it, collapsed (:data:`FIGURE_IN_WORDS`): a sighted reader can read it too, and a
    screen-reader user who opens it can move through it word by word, which an ``alt`` does
    not allow.

    Write ``alt`` in the notebook from the values the figure plots (an f-string), saying what the
    axes are, what each curve does and its key numbers. The output is one ``<figure>``: an
    ``<img>`` holding the PNG and ``alt``, and the collapsed description. So the built page,
    Jupyter and Colab all carry them (with the PNG itself and ``alt`` as plain text for front
    ends without HTML). A Matplotlib figure is drawn as the inline
    backend draws it, with :data:`PIXEL_DENSITY` times the pixels each way, and shown at the
    inline backend's size; it is closed once shown, so the inline backend does not show it again.
    An image array is shown with ``density`` of its pixels to each CSS pixel each way: 1 for a
    frame shown pixel for pixel, :data:`PIXEL_DENSITY` for a picture rendered at twice the size
    it is shown at (:func:`labsupport.render.show_picture`).

    Raises:
        ValueError: ``alt`` is shorter than :data:`MIN_ALT_WORDS` words or is a file name; or two
            labelled curves of one panel differ by colour alone (success criterion 1.4.1): give
            them different line styles or markers (:data:`labsupport.plots.CURVE_CYCLE` does).
    """
    text = text_alternative(alt)
    if isinstance(figure, np.ndarray):
        import mediapy

        png = mediapy.compress_image(figure)
        density = validate.whole("density", density, 1)
    else:
        import matplotlib.pyplot as plt

        if not isinstance(figure, plt.Figure):
            raise ValueError(
                f"show_figure shows a Matplotlib figure (fig from plt.subplots()) or an RGB image array, "
                f"got {type(figure).__name__}"
            )
        _refuse_colour_only_curves(figure)
        buffer = io.BytesIO()
        # as the inline backend draws it, at PIXEL_DENSITY times as many pixels each way
        figure.savefig(buffer, format="png", bbox_inches="tight", dpi=PIXEL_DENSITY * figure.dpi)
        plt.close(figure)
        png = buffer.getvalue()
        density = PIXEL_DENSITY
    data = base64.b64encode(png).decode("ascii")
    width = round(int.from_bytes(png[16:20], "big") / density)  # the PNG header's width, in CSS pixels
    html = (
        f'<figure class="course-figure" style="margin: 0; padding: 0; max-width: {width}px">'
        f'<img src="data:image/png;base64,{data}" alt="{escape(text)}" width="{width}" '
        'style="max-width: 100%; height: auto">'
        f"<details><summary>{FIGURE_IN_WORDS}</summary><p>{escape(text)}</p></details></figure>"
    )
    display(
        {"text/html": html, "image/png": data, "text/plain": text}, raw=True, metadata={"image/png": {"width": width}}
    )


def _refuse_colour_only_curves(figure) -> None:
    """``ValueError`` if two labelled curves of one panel share line style, marker and width class."""
    for ax in figure.axes:
        seen: dict[tuple[str, str, bool], str] = {}
        for line in ax.get_lines():
            label = str(line.get_label())
            if label.startswith("_"):
                continue  # unlabelled: a guide line or markers that repeat a labelled curve
            marker = str(line.get_marker())
            wide = line.get_linewidth() >= WIDE_LINE  # a wide band is a style of its own
            key = (str(line.get_linestyle()), "" if marker in ("None", "", " ") else marker, wide)
            if key in seen and seen[key] != label:
                raise ValueError(
                    f"in the panel {ax.get_title() or ax.get_ylabel()!r}, the curves {seen[key]!r} and {label!r} "
                    "differ by colour alone: give them different line styles or markers"
                )
            seen[key] = label
