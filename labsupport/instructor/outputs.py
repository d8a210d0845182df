"""What the graders write, and how: every text a student's code can reach made safe for a file,
the feedback files recognised, and every earlier run's results kept.

Both graders use it: :mod:`labsupport.instructor.batch` (a folder of notebooks) and
:mod:`labsupport.instructor.canvas` (a Canvas zip and gradebook), and so does the shared-code
report (:mod:`labsupport.instructor.similarity`).
"""

from __future__ import annotations

import os
import re
import unicodedata
from pathlib import Path

#: Longest message or note written into a feedback file, a CSV cell or a report [characters].
MAX_MESSAGE_CHARS = 2000

#: Bidirectional overrides and isolates: they reorder what a reader sees of the text around them.
_BIDI_CONTROLS = frozenset("\u202a\u202b\u202c\u202d\u202e\u2066\u2067\u2068\u2069")

#: How every feedback file either grader writes begins (how an earlier run's is recognised).
FEEDBACK_HEADER = "Feedback on "


def problem_title(problem: str) -> str:
    """How a feedback file names a Problem: ``"problem1"`` (the spec's id) as ``"Problem 1"``."""
    return re.sub(r"^problem(\d+)$", r"Problem \1", problem)


#: The files a batch writes that a regrade into the same folder moves into ``previous/`` (with
#: the feedback files it wrote: :func:`keep_previous`'s ``feedback``); the rubric too, whose
#: points the earlier grades were given in.
BATCH_RESULTS = ("grades.csv", "batch.json", "similarity.csv", "similarity.html", "rubric.md", "rubric_canvas.csv")

#: The same for a Canvas run: the import, the report, the feedback zip, and the rubric scaled to
#: the column's points possible then.
CANVAS_RESULTS = ("gradebook_import.csv", "report.txt", "feedback_upload.zip", "rubric_canvas.csv")


def clean_text(text: str, limit: int = MAX_MESSAGE_CHARS) -> str:
    """``text`` made safe to write into a feedback file, a CSV cell or a report: one line, no
    control characters, at most ``limit`` characters.

    Student code writes into the messages (an exception's text, a printed string): a line break
    would let it add a line of its own ("Score: 10 / 10"), a NUL byte or a terminal escape would
    garble the file or the terminal showing it, and a lone surrogate (``"\\ud800"`` in a
    notebook's JSON) would stop every UTF-8 file it went into from being written, and with it
    the whole class's grades. Tabs and line breaks become spaces; any other control character
    (Unicode category Cc, and the bidirectional overrides) and any surrogate (Cs) becomes a
    visible escape such as ``\\x1b``; a longer text is cut and ends in "…".
    """
    text = str(text)
    shown = "".join(_visible(c) for c in text[:limit])
    if len(text) > limit or len(shown) > limit:
        return shown[: limit - 1] + "…"
    return shown


#: What a spreadsheet reads as the start of a formula when a cell begins with it.
_FORMULA_STARTS = ("=", "+", "-", "@")


def csv_cell(text: str) -> str:
    """``text`` as :func:`clean_text` makes it, and written so that a spreadsheet shows it as text:
    one that begins as a formula does (``=HYPERLINK(...)``, ``+1``, ``@SUM``) gets a leading ``'``.
    For the cells of a grader's CSV that a student's file name fills."""
    text = clean_text(text)
    return "'" + text if text.startswith(_FORMULA_STARTS) else text


def _visible(c: str) -> str:
    """One character as :func:`clean_text` writes it."""
    if c in "\t\n\r\v\f\x1c\x1d\x1e\x85\u2028\u2029":  # every character str.splitlines breaks at, and tab
        return " "
    if unicodedata.category(c) in ("Cc", "Cs") or c in _BIDI_CONTROLS:
        return ascii(c)[1:-1]
    return c


def feedback_files(folder: Path) -> list[Path]:
    """The feedback files a grader wrote in ``folder``: ``*.txt`` files that begin with
    :data:`FEEDBACK_HEADER` (an instructor's own notes there are not among them)."""
    if not folder.is_dir():
        return []
    header = FEEDBACK_HEADER.encode()
    found = []
    for path in sorted(folder.iterdir()):
        if not path.name.endswith(".txt") or path.is_symlink() or not path.is_file():
            continue
        try:
            with open(path, "rb") as f:
                if f.read(len(header)) == header:
                    found.append(path)
        except OSError:  # not this grader's to touch
            continue
    return found


def keep_previous(folder: Path, names: tuple[str, ...], feedback: str | None = None, quiet: bool = False) -> str:
    """Move the files ``names`` that an earlier run wrote in ``folder``, and the feedback files it
    wrote in ``folder/feedback`` (:func:`feedback_files`) when a ``feedback`` folder name is given,
    into ``folder/previous/``, after moving what an even earlier run left there into
    ``previous/previous/`` (and so on): a regrade into the same folder loses nothing of any run,
    and leaves nothing of the earlier run beside its own results. Returns the line that says what
    moved where (``""`` when nothing did), and prints it unless ``quiet``."""
    earlier = [folder / name for name in names if (folder / name).is_file()]
    fed_back = feedback_files(folder / feedback) if feedback else []
    if not earlier and not fed_back:
        return ""
    previous = folder / "previous"
    if previous.is_dir():  # an even earlier run's: one level down
        keep_previous(previous, names, feedback, quiet=True)
    else:
        previous.mkdir()
    for path in earlier:
        os.replace(path, previous / path.name)
    if fed_back:
        (previous / feedback).mkdir(exist_ok=True)
        for path in fed_back:
            os.replace(path, previous / feedback / path.name)
    moved = [p.name for p in earlier] + ([f"{feedback}/ ({counted(len(fed_back), 'file')})"] if fed_back else [])
    older = " (the runs before it: in previous/previous, and so on)" if (previous / "previous").is_dir() else ""
    message = f"the earlier run's {', '.join(moved)} are now in {previous}{older}"
    if not quiet:
        print(message)
    return message


def counted(count: int, noun: str) -> str:
    """``count`` and ``noun``, plural unless ``count`` is 1: ``"1 submission"``, ``"2 submissions"``."""
    return f"{count} {noun}{'' if count == 1 else 's'}"


def keep_private() -> None:
    """Make the files and folders this process creates from now on its owner's alone (umask 077):
    the outputs hold students' grades."""
    os.umask(0o077)
