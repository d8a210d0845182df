"""Grade from Canvas to Canvas: the "Download Submissions" zip in, a gradebook ready to import out.

Usage (from the repository root)::

    .venv/bin/python -m labsupport.instructor.canvas --problem problem1 submissions.zip \\
        --gradebook export.csv [--column "Problem 1 (12345)"] --out OUT

reads the zip that an assignment's *Download Submissions* gives and the CSV that the
Gradebook's *Export* gives, grades each student's notebook with
:func:`labsupport.instructor.batch.run_batch`, and writes

* ``OUT/gradebook_import.csv``: the export's identifying columns (``Student`` to ``Section``)
  and the Problem's column, filled, for the Gradebook's *Import*; the other assignments' columns
  are left out, so a stale export cannot revert grades changed in Canvas since;
* ``OUT/feedback/<canvas prefix>_feedback.txt``: one file per graded student, and
  ``OUT/feedback_upload.zip`` holding them all, for the assignment's *Re-upload Submissions*;
* ``OUT/report.txt``: what was graded and what was not, and why (grades in Canvas that the
  import replaces, files that match no student, students with no submission, unreadable files,
  late work, resubmissions, scaling);
* ``OUT/batch/``: the batch grader's own ``grades.csv`` and feedback, the Problem's rubric
  (``rubric.md``, and ``rubric_canvas.csv`` for the course's *Rubrics → Import Rubric*), and
  the pairs of students who share code (``similarity.html``: :mod:`labsupport.instructor.similarity`).

A regrade into the same ``OUT`` first moves the earlier run's import, report and zip into
``OUT/previous/``, and the earlier batch's results into ``OUT/batch/previous/``
(:func:`keep_previous`).

What Canvas produces, and where each fact comes from
----------------------------------------------------

Canvas's own source (github.com/instructure/canvas-lms) is the reference; the community
guides say the same in fewer words.

*Download Submissions* zip (``lib/content_zipper.rb``: ``get_filename``,
``add_upload_submission``, ``sanitize_user_name``, ``sanitize_file_name``):

* an uploaded file is stored at the top of the zip as
  ``<name>_[LATE_]<user id>_<attachment id>_<file name>``;
* ``<name>`` is the student's sortable name ("Last, First") in lower case with every character
  that is not a letter, digit or underscore removed ("Smith, Bob" gives ``smithbob``);
* ``LATE`` is there when Canvas counts the submission late;
* the second number is the id of the uploaded file (the attachment), not of the submission;
* ``<file name>`` is the file's display name (``/ \\ : * ? " < > |`` replaced by ``_``);
* with anonymous grading the name is left out and the user id becomes ``anon_<anonymous id>``:
  such files cannot be matched to a gradebook row and are reported;
* a text entry is ``<name>_[LATE_]<user id>_text.html``, a URL ``..._link.html``;
* only the files of each student's latest attempt are zipped;
* for a group assignment graded as a group, one member stands for the group and the name is
  the group's name (``representatives`` in ``app/models/assignment.rb``).

Resubmissions (``app/models/attachment.rb``: ``handle_duplicates``,
``make_unique_filename``): a file uploaded into a student's submissions folder that already
holds a file of the same name is renamed ``<stem>-1<ext>``, then ``-2``... up to ``-7``, after
which a random UUID takes the number's place (older versions kept counting); so
``problem1_reaching-2.ipynb`` is the third upload of that name (students notice it too:
https://github.com/IIC1253/IIC1253-2025-1/issues/34). Attachment ids grow with each upload, so
the highest one is a student's latest file.

*Re-upload Submissions* (``infer_comment_context_from_filename`` in ``app/models/assignment.rb``)
splits each file name on ``_``, takes the first two all-digit parts as the user id and the
attachment id, and attaches the file as a comment to that student's submission; the feedback
files are named with the submitted file's own prefix, so Canvas finds them.

Gradebook export (``lib/gradebook_exporter.rb``) and import (``lib/gradebook_importer.rb``):

* columns ``Student`` (or ``LastName``, ``FirstName``), ``ID``, ``SIS User ID`` (optional),
  ``SIS Login ID``, ``Integration ID`` and ``Root Account`` (optional), ``Section``, custom
  columns, one column per assignment titled ``<title> (<assignment id>)``, then read-only totals
  (``Current Score``, ``Unposted Current Score``, ``Final Score``, ``Current Points``, ...);
* an optional row of ``Manual Posting`` markers, then the row whose first cell is
  ``    Points Possible`` (with ``(read only)`` under computed columns), then one row per student;
* the import requires a first row starting ``Student``, ``ID`` (or ``LastName``, ``FirstName``,
  ``ID``) whose student columns end with ``Section``; it finds each student by ``ID`` first,
  then SIS ids, then name; it skips the Points Possible and Manual Posting rows and ignores
  read-only columns; it updates only the columns the file holds; it reads ``;`` or ``,`` as the
  separator and a decimal comma or point;
* it changes only the students the file holds, so a student with no new score (no submission,
  a timed-out or failed grading, an excused cell) is left out of the file and keeps what Canvas
  holds, even a grade entered after the export (never a 0, which would be a grade); the Points
  Possible row is kept as exported, and a score is scaled to the column's points possible
  when the Problem's checks add up to a different maximum.

Community guides: https://community.canvaslms.com/t5/Instructor-Guide/How-do-I-import-grades-in-the-Gradebook/ta-p/807
(importing), and on the export's read-only columns, which the import ignores,
https://ts.vcu.edu/askit/teaching-and-learning/canvas/faculty/grading-faculty/gradebook-action-menu-faculty/.
"""

from __future__ import annotations

import argparse
import csv
import io
import json
import os
import re
import shutil
import tempfile
import unicodedata
import zipfile
import zlib
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path, PurePosixPath

from labsupport.instructor.assign import chosen_spec, load_spec, problem_arguments

#: Largest notebook read from the zip [bytes]: reading one takes that much memory, and no
#: student's notebook comes near it; a bigger file is reported, not graded.
MAX_NOTEBOOK_BYTES = 2**30
#: Above this size [bytes] a notebook is graded without its outputs and attachments, which the
#: grader never reads (it runs the code cells' source): the same grade, in less memory.
STRIP_OUTPUTS_BYTES = 64 * 2**20
#: Largest total the zip may declare once uncompressed [bytes]; a bigger zip is refused.
MAX_ZIP_BYTES = 4 * 2**30
#: Most entries a zip may hold.
MAX_ZIP_ENTRIES = 20_000

#: Batch statuses whose scores go into the gradebook; any other status (timed out, grader
#: error, or one this module does not know) leaves the student out of the import, and is reported.
SCORED_STATUSES = ("graded", "unreadable")
#: Longest message or note written into a feedback file, a CSV cell or a report [characters].
MAX_MESSAGE_CHARS = 2000
#: Bidirectional overrides and isolates: they reorder what a reader sees of the text around them.
_BIDI_CONTROLS = frozenset("\u202a\u202b\u202c\u202d\u202e\u2066\u2067\u2068\u2069")
#: How every feedback file either grader writes begins (how a stale one is recognised).
FEEDBACK_HEADER = "Feedback on "
#: General-purpose flag bit 11 of a zip entry: its name is stored in UTF-8.
_UTF8_NAME_FLAG = 0x800

_UPLOAD = re.compile(
    r"^(?:(?P<name>.*?)_)??(?:(?P<late>LATE)_)?(?P<user>\d+|anon_[A-Za-z0-9]+)_(?P<attachment>\d+)_(?P<original>.+)$"
)
_TEXT_OR_URL = re.compile(
    r"^(?:(?P<name>.*?)_)??(?:(?P<late>LATE)_)?(?P<user>\d+|anon_[A-Za-z0-9]+)_(?P<kind>text|link)\.html$"
)
# Canvas's make_unique_filename: "<stem>-<n><ext>", ext as Canvas cuts it ("a.tar.gz" -> "a-1.tar.gz").
# After -7, today's Canvas appends a random UUID instead of a number (older versions kept counting).
_RESUBMISSION = re.compile(
    r"^(?P<stem>.+)-(?P<n>\d+|[0-9a-f]{8}-[0-9a-f]{4}-[0-9a-f]{4}-[0-9a-f]{4}-[0-9a-f]{12})"
    r"(?P<ext>(?:\.[A-Za-z][A-Za-z0-9]*)*(?:\.[A-Za-z0-9]*))$"
)
_ASSIGNMENT_HEADER = re.compile(r"^(?P<title>.*)\s\((?P<id>\d+)\)$")
_COMPUTED_HEADER = re.compile(
    "Current Score|Current Points|Current Grade|Final Score|Final Points|Final Grade|Override Score"
    "|Override Grade|Override Status"
)
_POSTING_CELL = re.compile(r"^\s*(Muted|Manual Posting.*)?\s*$", re.IGNORECASE)


# --- what both graders write (kept here: labsupport.instructor.batch imports this module) ---------


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


def seed_argument(text: str) -> int:
    """``--seed``'s value: a whole number, 0 or more (the test states' generator takes no other)."""
    if not (text.isascii() and text.isdigit()):
        raise argparse.ArgumentTypeError(f"give a whole number, 0 or more (as batch.json records it), not {text!r}")
    return int(text)


def remove_stale_feedback(folder: Path, keep: set[str]) -> None:
    """Delete the feedback files an earlier run left in ``folder`` (a regrade into the same
    ``--out``), so that it matches what was just graded; only ``*.txt`` files a grader wrote (they
    begin with :data:`FEEDBACK_HEADER`) are touched. Names are compared in any case, as a
    case-insensitive file system would."""
    keep = {name.casefold() for name in keep}
    header = FEEDBACK_HEADER.encode()
    for path in folder.iterdir():
        if path.name.casefold() in keep or not path.name.endswith(".txt") or path.is_symlink() or not path.is_file():
            continue
        try:
            with open(path, "rb") as f:
                stale = f.read(len(header)) == header
            if stale:
                path.unlink()
        except OSError:  # not this grader's to remove
            continue


#: The files a batch writes that a regrade into the same folder moves into ``previous/``.
BATCH_RESULTS = ("grades.csv", "batch.json", "similarity.csv", "similarity.html")
#: The same for a Canvas run: the import, the report and the feedback zip.
CANVAS_RESULTS = ("gradebook_import.csv", "report.txt", "feedback_upload.zip")


def keep_previous(folder: Path, names: tuple[str, ...]) -> None:
    """Move the files ``names`` that an earlier run wrote in ``folder`` into ``folder/previous/``,
    replacing what an even earlier run left there: a regrade into the same folder loses nothing,
    and leaves nothing of the earlier run beside its own results."""
    earlier = [folder / name for name in names if (folder / name).is_file()]
    if not earlier:
        return
    previous = folder / "previous"
    previous.mkdir(exist_ok=True)
    for path in earlier:
        os.replace(path, previous / path.name)
    print(f"the earlier run's {', '.join(p.name for p in earlier)} are now in {previous}")


def keep_private() -> None:
    """Make the files and folders this process creates from now on its owner's alone (umask 077):
    the outputs hold students' grades."""
    os.umask(0o077)


# --- the zip -------------------------------------------------------------------------------------


@dataclass(frozen=True)
class SubmissionFile:
    """One file of a "Download Submissions" zip, its name taken apart as Canvas built it."""

    entry: str  #: the entry's name in the zip
    name: str  #: sortable name, lower case, word characters only ("" when anonymous)
    user_id: int | None  #: Canvas user id (None when anonymous)
    anonymous_id: str | None  #: Canvas anonymous id under anonymous grading
    late: bool  #: Canvas marked the submission LATE
    attachment_id: int | None  #: id of the uploaded file (None for text entries and URLs)
    original: str  #: the file's display name, resubmission suffix included
    resubmission: int  #: n of Canvas's "-n" duplicate-name suffix (0 when absent, 8 for its UUID suffix)
    kind: str = "upload"  #: "upload", "text" or "link"

    @property
    def base_name(self) -> str:
        """The display name without the resubmission suffix: ``problem1-2.ipynb`` -> ``problem1.ipynb``."""
        m = _RESUBMISSION.match(self.original)
        return m["stem"] + m["ext"] if m and self.resubmission else self.original

    @property
    def prefix(self) -> str:
        """The entry name up to the attachment id: what Canvas reads back from a re-uploaded file."""
        base = PurePosixPath(self.entry.replace("\\", "/")).name  # a folder in the zip is not part of it
        return base[: len(base) - len(self.original) - 1] if self.kind == "upload" else ""

    @property
    def is_notebook(self) -> bool:
        return self.kind == "upload" and self.original.lower().endswith(".ipynb")


#: Files an operating system adds when it zips a folder: never a student's work.
_OS_FILES = (".DS_Store", "Thumbs.db", "desktop.ini")


def is_os_metadata(entry: str) -> bool:
    """Whether a zip entry is a file the operating system added: macOS's ``__MACOSX/`` folder and
    ``._`` copies (AppleDouble resource forks, not notebooks), ``.DS_Store``, Windows'
    ``Thumbs.db``. A re-zipped download holds them; they are skipped, never graded."""
    parts = entry.replace("\\", "/").split("/")
    return "__MACOSX" in parts or parts[-1].startswith("._") or parts[-1] in _OS_FILES


def parse_submission_name(entry: str) -> SubmissionFile | None:
    """Take a zip entry's name apart: ``<name>_[LATE_]<user id>_<attachment id>_<file name>``.

    Returns None when the name is not one Canvas writes (a file added to the zip by hand).
    """
    base = PurePosixPath(entry.replace("\\", "/")).name
    m = _UPLOAD.match(base)
    kind = "upload"
    if m is None:
        m = _TEXT_OR_URL.match(base)
        if m is None:
            return None
        kind = m["kind"]
    user = m["user"]
    anonymous = user.startswith("anon_")
    original = m["original"] if kind == "upload" else base
    suffix = _RESUBMISSION.match(original) if kind == "upload" else None
    return SubmissionFile(
        entry=entry,
        name=m["name"] or "",
        user_id=None if anonymous else int(user),
        anonymous_id=user[len("anon_") :] if anonymous else None,
        late=m["late"] is not None,
        attachment_id=int(m["attachment"]) if kind == "upload" else None,
        original=original,
        resubmission=(int(suffix["n"]) if suffix["n"].isdigit() else 8) if suffix else 0,
        kind=kind,
    )


def entry_name(info: zipfile.ZipInfo) -> str:
    """The entry's name as its writer meant it.

    A name stored without the UTF-8 flag (general-purpose bit 11; Info-ZIP and rubyzip write
    such zips) is read by :mod:`zipfile` as code page 437, which garbles a UTF-8 name
    (``garcíaana`` comes out ``garc├¡aana``); such a name is read as UTF-8 where its bytes are
    UTF-8, and kept as code page 437 otherwise.
    """
    if info.flag_bits & _UTF8_NAME_FLAG:
        return info.filename
    try:
        return info.filename.encode("cp437").decode("utf-8")
    except UnicodeError:
        return info.filename


def safe_zip_entries(zf: zipfile.ZipFile) -> list[zipfile.ZipInfo]:
    """The zip's file entries, named by :func:`entry_name`, after refusing a zip that could write
    outside its folder or explode.

    Refused: more than :data:`MAX_ZIP_ENTRIES` entries, an absolute name, a drive letter, a
    ``..`` part, a NUL byte, a symbolic link, or a declared total over :data:`MAX_ZIP_BYTES`;
    the name checked is the one used. (Renaming an entry is safe: :meth:`zipfile.ZipFile.open`
    compares the file's own header with ``orig_filename``, which stays as read.)
    """
    infos = zf.infolist()
    if len(infos) > MAX_ZIP_ENTRIES:
        raise ValueError(f"the zip holds {len(infos)} entries, more than {MAX_ZIP_ENTRIES}: not a Canvas download")
    for info in infos:
        name = info.filename = entry_name(info)
        parts = name.replace("\\", "/").split("/")
        if name.startswith(("/", "\\")) or re.match(r"^[A-Za-z]:", name) or ".." in parts or "\x00" in name:
            raise ValueError(
                f"the zip holds an entry named {name!r}, which points outside the folder it is unpacked in; "
                "Canvas never writes such names: download the submissions from Canvas again"
            )
        if (info.external_attr >> 16) & 0o170000 == 0o120000:
            raise ValueError(f"the zip holds a symbolic link {name!r}; Canvas never does: download it again")
    total = sum(info.file_size for info in infos)
    if total > MAX_ZIP_BYTES:
        raise ValueError(
            f"the zip would unpack to {total / 2**30:.1f} GiB, more than {MAX_ZIP_BYTES / 2**30:.0f} GiB: refused"
        )
    return [info for info in infos if not info.is_dir()]


def read_notebook_entry(zf: zipfile.ZipFile, info: zipfile.ZipInfo) -> tuple[bytes | None, str | None]:
    """The notebook in the entry, :func:`held` (and ``None``), or ``None`` and why it cannot be
    read: damaged in the zip, or over :data:`MAX_NOTEBOOK_BYTES`."""
    try:
        data = read_member(zf, info)
    except (zipfile.BadZipFile, zlib.error, EOFError) as err:
        return None, f"damaged in the zip ({err})"
    if data is None:
        return None, f"larger than the {MAX_NOTEBOOK_BYTES:,} bytes a notebook may have"
    return held(data), None


def read_member(zf: zipfile.ZipFile, info: zipfile.ZipInfo, limit: int | None = None) -> bytes | None:
    """The entry's bytes, or None when it holds more than ``limit`` bytes (default :data:`MAX_NOTEBOOK_BYTES`).

    Never reads more than ``limit + 1`` bytes, whatever the entry's header says; an entry whose
    content disagrees with its header raises :class:`zipfile.BadZipFile`.
    """
    limit = MAX_NOTEBOOK_BYTES if limit is None else limit
    if info.file_size > limit:
        return None
    with zf.open(info) as f:
        data = f.read(limit + 1)
    return None if len(data) > limit else data


def held(data: bytes) -> bytes:
    """A notebook's bytes as the graders hold them in memory until graded and compared: without
    its outputs (:func:`without_outputs`) when over :data:`STRIP_OUTPUTS_BYTES`, as they are
    otherwise; only the code is read."""
    return without_outputs(data) if len(data) > STRIP_OUTPUTS_BYTES else data


def without_outputs(data: bytes) -> bytes:
    """The notebook without its cells' outputs and attachments, which the grader never reads.

    The cells stay where they are, with their source, so the notebook grades as it is. A file
    that is not a notebook is returned unchanged, for the grader to say why it cannot read it.
    """
    try:
        nb = json.loads(data.decode("utf-8"))
        if not isinstance(nb, dict) or not isinstance(nb.get("cells"), list):
            return data
        for cell in nb["cells"]:
            if isinstance(cell, dict):
                cell.pop("attachments", None)
                if "outputs" in cell:
                    cell["outputs"] = []
        return json.dumps(nb).encode("utf-8")
    except (ValueError, RecursionError):  # not UTF-8, not JSON, or nested too deep
        return data


def notebook_stem(spec: dict) -> str:
    """The student notebook's name without extension, e.g. ``problem1_reaching``."""
    return PurePosixPath(spec.get("student") or spec["problem"]).stem


def _plain(text: str) -> str:
    """Lower case, letters and digits only: the form in which file and column names are compared."""
    return "".join(c for c in unicodedata.normalize("NFKC", text).lower() if c.isalnum())


def choose_notebook(files: list[SubmissionFile], stem: str, problem: str) -> SubmissionFile | None:
    """The file of one student to grade: a notebook named after the Problem, latest upload first.

    Preference: a notebook whose name holds the Problem's notebook name (``problem1_reaching``),
    else one whose name holds the Problem's name (``problem1``), else any notebook; among
    equals, the highest attachment id (the latest upload, whatever Canvas's suffix says).
    """
    notebooks = [f for f in files if f.is_notebook]
    for key in (_plain(stem), _plain(problem), ""):
        named = [f for f in notebooks if key in _plain(f.base_name)]
        if named:
            return max(named, key=lambda f: f.attachment_id or 0)
    return None


# --- the gradebook -------------------------------------------------------------------------------


@dataclass
class Gradebook:
    """A Canvas gradebook export, kept record by record so that a rewrite changes only one column."""

    records: list[str]  #: raw text of each CSV record, its line ending included
    rows: list[list[str]]  #: the parsed cells of each record
    delimiter: str
    bom: str  #: "\ufeff" when the export began with a byte-order mark
    id_column: int  #: index of the ``ID`` column
    name_columns: tuple[int, ...]  #: ``Student``, or ``LastName``, ``FirstName``
    first_assignment_column: int  #: index just after ``Section``
    points_row: int | None  #: index of the Points Possible row
    student_rows: dict[int, int]  #: user id -> row index

    @property
    def header(self) -> list[str]:
        return self.rows[0]

    def assignment_columns(self) -> list[int]:
        """Indices of the assignment columns: titled ``<title> (<id>)``, not read-only, not a total."""
        points = self.rows[self.points_row] if self.points_row is not None else []
        return [
            i
            for i, h in enumerate(self.header)
            if i >= self.first_assignment_column
            and _ASSIGNMENT_HEADER.match(h)
            and not _COMPUTED_HEADER.search(h)
            and "read only" not in (points[i] if i < len(points) else "")
        ]

    def student_name(self, user_id: int) -> str:
        row = self.rows[self.student_rows[user_id]]
        return ", ".join(row[i] for i in self.name_columns if i < len(row) and row[i])

    def cell(self, user_id: int, column: int) -> str:
        row = self.rows[self.student_rows[user_id]]
        return row[column] if column < len(row) else ""

    def points_possible(self, column: int) -> float | None:
        """The column's points possible from the Points Possible row (None without that row)."""
        if self.points_row is None:
            return None
        text = self.rows[self.points_row][column].strip()
        try:
            points = float(_decimal_point(text))
        except ValueError:
            points = float("nan")
        if not points > 0:  # blank, text, 0 or negative: every score would be scaled to nothing
            raise ValueError(
                f"the Points Possible row says {text!r} under {self.header[column]!r}, not a positive number: "
                "set the assignment's points in Canvas and export the gradebook again"
            )
        return points


def _decimal_point(text: str) -> str:
    """``"12,5"`` -> ``"12.5"``, as Canvas's importer reads a decimal comma."""
    return text.replace(",", ".") if "." not in text else text.replace(",", "")


def split_records(text: str) -> list[str]:
    """Cut CSV text into records, each with its line ending; a newline inside quotes stays inside."""
    records, start, quoted = [], 0, False
    for i, c in enumerate(text):
        if c == '"':
            quoted = not quoted
        elif c == "\n" and not quoted:
            records.append(text[start : i + 1])
            start = i + 1
    if start < len(text):
        records.append(text[start:])
    return records


def split_fields(record: str, delimiter: str) -> tuple[list[str], str]:
    """A record's raw field texts (quotes kept) and its line ending."""
    body = record.rstrip("\r\n")
    fields, start, quoted = [], 0, False
    for i, c in enumerate(body):
        if c == '"':
            quoted = not quoted
        elif c == delimiter and not quoted:
            fields.append(body[start:i])
            start = i + 1
    fields.append(body[start:])
    return fields, record[len(body) :]


def detect_delimiter(lines: list[str]) -> str:
    """``;`` or ``,``, decided as Canvas's importer does: the one that splits the first lines into
    the same, larger number of fields."""
    counts = {}
    for sep in (";", ","):
        sizes = {len(next(csv.reader([line], delimiter=sep), [])) for line in lines}
        counts[sep] = sizes.pop() if len(sizes) == 1 else 0
    return ";" if counts[";"] > counts[","] else ","


def _not_a_gradebook(path: Path, why: str) -> ValueError:
    return ValueError(
        f"{path} is not a Canvas gradebook export: {why}. Export it from Canvas: Grades -> Export -> "
        "Export Entire Gradebook, and pass that CSV unchanged"
    )


def read_gradebook(path: Path) -> Gradebook:
    """Read a Canvas gradebook export (CSV), checking its header as Canvas's importer does."""
    path = Path(path)
    raw = path.read_bytes()
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError:
        raise _not_a_gradebook(path, "it is not UTF-8 text (re-saved by a spreadsheet?)") from None
    bom = "\ufeff" if text.startswith("\ufeff") else ""
    records = split_records(text[len(bom) :])
    if not records:
        raise _not_a_gradebook(path, "it is empty")
    delimiter = detect_delimiter([r.rstrip("\r\n") for r in records[:3]])
    rows = [next(csv.reader(io.StringIO(r), delimiter=delimiter), []) for r in records]
    header = [h.strip() for h in rows[0]]
    if len(header) > 4 and "LastName" in header[0] and "FirstName" in header[1] and "ID" in header[2]:
        name_columns, id_column = (0, 1), 2
    elif len(header) > 3 and "Student" in header[0] and "ID" in header[1]:
        name_columns, id_column = (0,), 1
    else:
        raise _not_a_gradebook(path, f"its first row should begin with Student, ID, but begins with {header[:3]}")
    if "Section" not in header:
        raise _not_a_gradebook(path, "its first row has no Section column")
    points_row, students = None, {}
    for r, row in enumerate(rows[1:], start=1):
        first = row[0] if row else ""
        if "Points Possible" in first:
            if points_row is not None:  # which one would Canvas read? neither guess is safe
                raise _not_a_gradebook(path, f"rows {points_row + 1} and {r + 1} both say Points Possible")
            points_row = r
        elif all(_POSTING_CELL.match(c) for c in row if c):
            continue  # the Manual Posting row, or a blank line
        else:
            cell = row[id_column].strip() if id_column < len(row) else ""
            if not cell.isdigit():
                raise _not_a_gradebook(path, f"row {r + 1} has {cell!r} in the ID column, not a Canvas user id")
            students[int(cell)] = r
    return Gradebook(
        records, rows, delimiter, bom, id_column, name_columns, header.index("Section") + 1, points_row, students
    )


def choose_column(gradebook: Gradebook, problem: str, column: str | None = None) -> int:
    """The index of the Problem's assignment column.

    ``column`` may be the full header (``"Problem 1 (12345)"``), the assignment id or the title;
    without it, the one assignment column whose title names the Problem (``problem1``).
    """
    candidates = gradebook.assignment_columns()
    header = gradebook.header
    listing = "; ".join(repr(header[i]) for i in candidates) or "none"
    if column is not None:
        for test in (
            lambda h: h == column,
            lambda h: _ASSIGNMENT_HEADER.match(h)["id"] == column,
            lambda h: _ASSIGNMENT_HEADER.match(h)["title"] == column,
        ):
            hits = [i for i in candidates if test(header[i])]
            if len(hits) == 1:
                return hits[0]
            if hits:
                several = "; ".join(repr(header[i]) for i in hits)
                raise ValueError(
                    f"{len(hits)} assignment columns match --column {column!r}: {several}; give the one you mean "
                    "by its assignment id, the number in parentheses"
                )
        raise ValueError(f"the gradebook has no assignment column {column!r}; its assignment columns are: {listing}")
    hits = [i for i in candidates if names_problem(_ASSIGNMENT_HEADER.match(header[i])["title"], problem)]
    if len(hits) != 1:
        found = "no assignment column" if not hits else "several assignment columns"
        named = listing if not hits else "; ".join(repr(header[i]) for i in hits)
        raise ValueError(f"{found} of the gradebook names {problem!r}: give --column, one of: {named}")
    return hits[0]


def format_score(value: float) -> str:
    """A score as Canvas shows it: at most two decimals, no trailing zeros (``7.5``, ``15``)."""
    text = f"{value:.2f}".rstrip("0").rstrip(".")
    return "0" if text in ("-0", "") else text


def scaled_score(total: float, maximum: float, points_possible: float | None) -> float:
    """The score in the column's points: ``total / maximum * points_possible`` (unscaled without it)."""
    if points_possible is None or abs(points_possible - maximum) < 1e-9:
        return total
    return total / maximum * points_possible


def fill_column(gradebook: Gradebook, column: int, scores: dict[int, str]) -> str:
    """The import's text: the records of the export cut to its identifying fields (``Student``
    to ``Section``) and ``column``, with ``scores`` (user id -> cell text) written into it.

    Canvas's import updates only the columns and the students the file holds. The export's
    other assignments, and the students with no score in ``scores``, are left out: their cells
    would put back what Canvas held when the export was made, over any grade changed since.
    The other records are kept (the header, the Manual Posting and Points Possible rows), and
    each kept field's raw text and quotes, the separator, the byte-order mark and the line
    endings are the export's.
    """
    user_of_row = {row: user for user, row in gradebook.student_rows.items()}
    out = [gradebook.bom]
    for r, record in enumerate(gradebook.records):
        fields, ending = split_fields(record, gradebook.delimiter)
        if fields == [""]:  # a blank line
            out.append(record)
            continue
        fields += [""] * (column + 1 - len(fields))
        user = user_of_row.get(r)
        if user is not None and user not in scores:
            continue  # no new score: Canvas keeps what it holds
        cell = fields[column] if user is None else scores[user]  # the header and other rows keep theirs
        out.append(gradebook.delimiter.join([*fields[: gradebook.first_assignment_column], cell]) + ending)
    return "".join(out)


# --- grading and the report ----------------------------------------------------------------------


@dataclass
class CanvasResult:
    """What one Canvas round trip did; every list is also written to the report."""

    column: str = ""
    points_possible: float | None = None
    maximum: float = 0.0
    scores: dict[int, str] = field(default_factory=dict)  #: user id -> cell written
    replaced: list[str] = field(default_factory=list)  #: grades already in Canvas that a score replaces
    feedback: dict[int, Path] = field(default_factory=dict)  #: user id -> feedback file
    unmatched: list[str] = field(default_factory=list)  #: files matching no student, and why
    missing: list[str] = field(default_factory=list)  #: gradebook students with nothing graded
    late: list[str] = field(default_factory=list)
    resubmissions: list[str] = field(default_factory=list)
    not_graded: list[str] = field(default_factory=list)  #: files of known students left aside
    not_scored: list[str] = field(default_factory=list)  #: graded files whose status gave no score
    unreadable: list[str] = field(default_factory=list)  #: files the grader could not read (scored 0), and why
    notes: list[str] = field(default_factory=list)
    warning: str = ""  #: what to check before importing (a column that does not name the Problem)


GradeFn = Callable[[Path, Path, Path], list[dict]]


def grade_canvas(
    submissions_zip: Path,
    gradebook_path: Path,
    spec_path: Path,
    out: Path,
    column: str | None = None,
    jobs: int | None = None,
    grade: GradeFn | None = None,
    seed: int | None = None,
    compare_with: list[Path] | None = None,
) -> CanvasResult:
    """Grade a Canvas zip into a copy of a Canvas gradebook export; writes OUT as the module says.

    ``grade(folder, spec_path, out)`` grades a folder of notebooks and returns the batch rows
    (``file``, ``status``, ``scores``, ``messages``, ``notes``); by default it is
    :func:`labsupport.instructor.batch.run_batch` with ``jobs`` and ``seed`` (a fresh secret
    one if None; ``OUT/batch/batch.json`` records it, so ``--seed`` reproduces every grade) and
    ``compare_with`` (folders of earlier notebooks for the shared-code report).
    """
    spec_path, out = Path(spec_path), Path(out)
    spec = load_spec(spec_path)
    if out.exists() and not out.is_dir():
        raise ValueError(f"--out {out} is a file: give --out a folder (it is created if missing)")
    gradebook = read_gradebook(Path(gradebook_path))
    col = choose_column(gradebook, spec["problem"], column)
    result = CanvasResult(
        column=gradebook.header[col],
        points_possible=gradebook.points_possible(col),
        maximum=sum(float(c["points"]) for c in spec["checks"]),
        warning=column_warning(gradebook.header[col], spec["problem"]),
    )
    if result.points_possible is None:
        result.notes.append("the export has no Points Possible row: scores are written unscaled")
    elif abs(result.points_possible - result.maximum) > 1e-9:
        result.notes.append(
            f"the Problem's checks add up to {result.maximum:g} points and the column to "
            f"{result.points_possible:g}: every score is scaled by "
            f"{result.points_possible:g}/{result.maximum:g}"
        )
    chosen = _select_submissions(Path(submissions_zip), gradebook, spec, result)
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as err:
        raise ValueError(
            f"cannot write the output folder {out} ({err.strerror}): give --out a folder you can write to"
        ) from None
    keep_previous(out, CANVAS_RESULTS)
    rows = _grade(Path(submissions_zip), chosen, spec_path, out, result, grade or _run_batch(jobs, seed, compare_with))
    _record_scores(gradebook, col, spec, chosen, rows, out, result)
    remove_stale_feedback(out / "feedback", {path.name for path in result.feedback.values()})
    (out / "gradebook_import.csv").write_bytes(fill_column(gradebook, col, result.scores).encode("utf-8"))
    _write_feedback_zip(out, result)
    (out / "report.txt").write_text(report_text(gradebook, spec, result), encoding="utf-8")
    return result


def _run_batch(jobs: int | None, seed: int | None = None, compare_with: list[Path] | None = None) -> GradeFn:
    def grade(folder: Path, spec_path: Path, out: Path) -> list[dict]:
        # Imported here: the batch grader is heavy and this module's reading and writing of Canvas
        # files must work (and be tested) without it.
        from labsupport.instructor.batch import run_batch

        return run_batch(folder, spec_path, out, jobs=jobs, seed=seed, compare_with=compare_with)

    return grade


def is_zip(path: Path) -> bool:
    """Whether ``path`` is a file named as a zip (``.zip`` in any case)."""
    return path.is_file() and path.suffix.lower() == ".zip"


def open_zip(zip_path: Path) -> zipfile.ZipFile:
    """The zip at ``zip_path``, open; ``ValueError`` saying what to do when it cannot be read."""
    try:
        return zipfile.ZipFile(zip_path)
    except (zipfile.BadZipFile, OSError, UnicodeDecodeError) as err:  # the last: a name flagged UTF-8 that is not
        raise ValueError(
            f"{zip_path} is not a readable zip ({err}): download the submissions from Canvas again"
        ) from None


def zip_notebooks(zip_path: Path, spec: dict) -> tuple[dict[str, bytes], list[str]]:
    """The notebooks of a zip to compare for shared code, by entry name, and what was left out, why.

    From a Canvas "Download Submissions" zip, each student's one notebook for the Problem of
    ``spec``, chosen as for grading (:func:`choose_notebook`); an entry not named as Canvas names
    uploads (a zip of notebooks made by hand) is a notebook of its own. ``ValueError`` for a zip
    that cannot be read or is refused (:func:`safe_zip_entries`).
    """
    notebooks, left_out = {}, []
    with open_zip(zip_path) as zf:
        entries = [info for info in safe_zip_entries(zf) if not is_os_metadata(info.filename)]
        by_student: dict[int | str, list[SubmissionFile]] = {}
        chosen = []
        for info in entries:
            f = parse_submission_name(info.filename)
            if f is None:
                if info.filename.lower().endswith(".ipynb"):
                    chosen.append(info.filename)
            else:
                by_student.setdefault(f.user_id or f.anonymous_id, []).append(f)
        for files in by_student.values():
            pick = choose_notebook(files, notebook_stem(spec), spec["problem"])
            other = pick and _other_problem(pick.base_name, spec["problem"])
            left_out += [
                f"{f.entry} ({other}'s notebook)" if f is pick else f"{f.entry} (the student's other notebook)"
                for f in files
                if f.is_notebook and (f is not pick or other)
            ]
            if pick and not other:
                chosen.append(pick.entry)
        infos = {info.filename: info for info in entries}
        for entry in sorted(chosen):
            data, why = read_notebook_entry(zf, infos[entry])
            if why:
                left_out.append(f"{entry} ({why})")
            else:
                notebooks[entry] = data
    return notebooks, left_out


def _select_submissions(
    zip_path: Path, gradebook: Gradebook, spec: dict, result: CanvasResult
) -> dict[int, SubmissionFile]:
    """For each student of the gradebook with a notebook in the zip, the one file to grade."""
    with open_zip(zip_path) as zf:
        entries = safe_zip_entries(zf)
    by_user: dict[int, list[SubmissionFile]] = {}
    kept = [info for info in entries if not is_os_metadata(info.filename)]
    if len(kept) < len(entries):
        result.notes.append(
            f"{len(entries) - len(kept)} files the operating system added to the zip (__MACOSX/, ._ copies, "
            ".DS_Store) skipped"
        )
    for info in kept:
        f = parse_submission_name(info.filename)
        if f is None:
            result.unmatched.append(f"{info.filename}: not named as Canvas names submissions")
        elif f.user_id is None:
            result.unmatched.append(
                f"{info.filename}: anonymous grading hides the student; "
                "grade it by hand or download the zip after the names are shown"
            )
        elif f.user_id not in gradebook.student_rows:
            result.unmatched.append(f"{info.filename}: no student with ID {f.user_id} in the gradebook")
        else:
            by_user.setdefault(f.user_id, []).append(f)
    chosen = {}
    stem = notebook_stem(spec)
    for user, files in by_user.items():
        pick = choose_notebook(files, stem, spec["problem"])
        who = gradebook.student_name(user)
        for f in files:
            if f is not pick:
                why = "a notebook" if f.is_notebook else "not a notebook"
                result.not_graded.append(f"{who}: {f.entry} ({why}; not the file graded for {spec['problem']})")
        if pick is None:
            result.missing.append(f"{who} (ID {user}): no notebook in the zip; left out of the import")
            continue
        other = _other_problem(pick.base_name, spec["problem"])
        if other:
            result.missing.append(
                f"{who} (ID {user}): {pick.original} is {other}'s notebook, not {stem}.ipynb; left out of the "
                f"import (grade that zip with --problem {other}, or this one by hand)"
            )
            continue
        chosen[user] = pick
        if pick.late:
            result.late.append(f"{who}: {pick.entry}")
        if pick.resubmission:
            result.resubmissions.append(f"{who}: {pick.original} (Canvas's name for a re-upload of {pick.base_name})")
        if _plain(stem) not in _plain(pick.base_name):
            result.notes.append(f"{who}: graded {pick.original}, whose name differs from {stem}.ipynb")
        if pick.name and unicodedata.normalize("NFC", pick.name) != _zip_name(gradebook.student_name(user)):
            result.notes.append(
                f"{who}: the file is named after {pick.name!r}, not this student (a group "
                "submission?); the grade is written for this student only"
            )
    for user in gradebook.student_rows:
        if user not in by_user:
            result.missing.append(
                f"{gradebook.student_name(user)} (ID {user}): nothing in the zip; left out of the import"
            )
    return chosen


def _other_problem(file_name: str, problem: str) -> str | None:
    """The Problem a file is named after (``problem2`` in ``problem2_tracking.ipynb``) when it is
    not ``problem``; None when the name names none, or this one."""
    named, own = re.search(r"problem(\d+)", _plain(file_name)), re.search(r"problem(\d+)", _plain(problem))
    return f"problem{named[1]}" if named and own and named[1] != own[1] else None


def _zip_name(sortable_name: str) -> str:
    """The name part Canvas gives a student's files: lower case, word characters only."""
    name = unicodedata.normalize("NFC", sortable_name.removeprefix('="').removesuffix('"').lower())
    return re.sub(r"\W", "", re.sub(r"_(\d+)_", r"\1", name))


def _grade(
    zip_path: Path, chosen: dict[int, SubmissionFile], spec_path: Path, out: Path, result: CanvasResult, grade: GradeFn
) -> dict[int, dict]:
    """Unpack the chosen notebooks into a private folder, grade them, and key the rows by user id.
    With none to grade, an earlier batch's results in ``OUT/batch`` are moved into its
    ``previous/`` and its feedback removed, so that none of it stands beside this run's import."""
    if not chosen:
        _retire_batch(out / "batch")
        return {}
    folder = Path(tempfile.mkdtemp(prefix="canvas-submissions-"))  # mode 0700: private
    try:
        files = {}
        with zipfile.ZipFile(zip_path) as zf:
            infos = {info.filename: info for info in safe_zip_entries(zf)}
            for user, f in sorted(chosen.items()):
                data, why = read_notebook_entry(zf, infos[f.entry])
                if why:
                    result.not_scored.append(f"{f.entry}: {why}, not graded")
                    continue
                name = f"{f.name or 'student'}_{user}.ipynb"
                (folder / name).write_bytes(data)
                files[name] = user
        if files:
            rows = grade(folder, spec_path, out / "batch")
        else:
            rows = []
            _retire_batch(out / "batch")
    finally:
        shutil.rmtree(folder, ignore_errors=True)
    by_user = {}
    for row in rows:
        user = files.get(row.get("file"))
        if user is None:
            result.notes.append(f"the grader returned a row for {row.get('file')!r}, which it was not given")
        else:
            by_user[user] = row
    for user in files.values():
        if user not in by_user:
            result.not_scored.append(f"{chosen[user].entry}: the grader returned no row for it; left out of the import")
    return by_user


def _retire_batch(folder: Path) -> None:
    """Move an earlier batch's results in ``folder`` into ``folder/previous/`` and remove its
    feedback files (a run with nothing to grade writes no batch of its own)."""
    if folder.is_dir():
        keep_previous(folder, BATCH_RESULTS)
        if (folder / "feedback").is_dir():
            remove_stale_feedback(folder / "feedback", set())


def _record_scores(
    gradebook: Gradebook,
    col: int,
    spec: dict,
    chosen: dict[int, SubmissionFile],
    rows: dict[int, dict],
    out: Path,
    result: CanvasResult,
) -> None:
    """Turn each graded row into its cell and its feedback file; say which cells were left alone."""
    (out / "feedback").mkdir(parents=True, exist_ok=True)
    for user, row in sorted(rows.items()):
        f, who = chosen[user], gradebook.student_name(user)
        total = sum(float(row["scores"].get(c["name"], 0.0)) for c in spec["checks"])
        score = format_score(scaled_score(total, result.maximum, result.points_possible))
        previous = gradebook.cell(user, col).strip()
        if previous.upper() in ("EX", "N/A"):  # excused: no grade, and no feedback that says one
            result.not_scored.append(
                f"{who}: {f.entry}: the cell says {previous} in Canvas and is left so, out of the import and "
                f"without feedback (score {score})"
            )
            continue
        path = out / "feedback" / f"{f.prefix}_feedback.txt"
        path.write_text(feedback_text(who, f, spec, row, total, score, result), encoding="utf-8")
        result.feedback[user] = path
        if row.get("status") not in SCORED_STATUSES:
            reason = "; ".join(row.get("notes", [])[:1])
            result.not_scored.append(
                f"{who}: {f.original}: {row.get('status')} ({reason}); left out of the import: grade again or by hand"
            )
            continue
        if row.get("status") == "unreadable":
            reason = "; ".join(row.get("notes", [])[:1]) or "no reason given"
            result.unreadable.append(f"{who}: {f.original}: {reason}")
        if previous and previous not in ("-", score) and _decimal_point(previous) != score:
            result.replaced.append(f"{who}: replaces the grade {previous} already in Canvas with {score}")
        result.scores[user] = score


def feedback_text(
    who: str, f: SubmissionFile, spec: dict, row: dict, total: float, score: str, result: CanvasResult
) -> str:
    """One student's feedback: the score in Canvas's points, then each check's points and message."""
    lines = [
        f"{FEEDBACK_HEADER}{spec['problem']} for {clean_text(who)}",
        f"File graded: {clean_text(f.original)}" + ("  (late)" if f.late else ""),
        "",
    ]
    if row.get("status") in SCORED_STATUSES:
        out_of = result.points_possible if result.points_possible is not None else result.maximum
        lines.append(f"Score: {score} / {format_score(out_of)}")
        if score != format_score(total):
            lines.append(f"  ({format_score(total)} of the checks' {format_score(result.maximum)} points, scaled)")
    else:
        lines.append(f"Not scored: {row.get('status')}; your instructor will grade it again.")
    lines.append("")
    for c in spec["checks"]:
        got = row["scores"].get(c["name"])
        shown = "-" if got is None else format_score(float(got))
        message = clean_text(row.get("messages", {}).get(c["name"], "not graded"))
        lines.append(f"- {c['name']} ({shown} / {format_score(float(c['points']))}): {message}")
    notes = [n for n in row.get("notes", []) if not any(n.startswith(c["name"] + ":") for c in spec["checks"])]
    if notes:
        lines += ["", "Notes:"] + [f"- {clean_text(n)}" for n in notes]
    return "\n".join(lines) + "\n"


def _write_feedback_zip(out: Path, result: CanvasResult) -> None:
    """``OUT/feedback_upload.zip``: the feedback files, for the assignment's Re-upload Submissions."""
    with zipfile.ZipFile(out / "feedback_upload.zip", "w", zipfile.ZIP_DEFLATED) as zf:
        for path in sorted(result.feedback.values()):
            zf.write(path, path.name)


def names_problem(title: str, problem: str) -> bool:
    """Whether an assignment's title names ``problem``: ``problem1`` in "Problem 1: Reaching", not
    in "Problem 10"."""
    return re.search(re.escape(_plain(problem)) + r"(?!\d)", _plain(title)) is not None


def column_warning(header: str, problem: str) -> str:
    """A warning when the column chosen (by ``--column``) does not name the Problem, else ""."""
    match = _ASSIGNMENT_HEADER.match(header)
    if names_problem(match["title"] if match else header, problem):
        return ""
    return (
        f"Check first: the column's title does not name {problem}; make sure it is this Problem's assignment "
        "before you import (--column chose it)"
    )


def report_text(gradebook: Gradebook, spec: dict, result: CanvasResult) -> str:
    """The plain-text report: the column written, then each list of what needs a look, the
    grades in Canvas that the import replaces first."""
    out_of = format_score(result.points_possible) if result.points_possible is not None else "?"
    lines = [
        f"Canvas grading report: {spec['problem']}",
        f"Column: {result.column} (points possible {out_of})",
        f"Students in the gradebook: {len(gradebook.student_rows)}; scores written: {len(result.scores)}",
        "",
    ]
    if result.warning:
        lines[2:2] = [result.warning]
    sections = [
        ("Grades already in Canvas that this import replaces", result.replaced),
        ("Files that match no student of the gradebook (not graded)", result.unmatched),
        ("Students with nothing graded (left out of the import: Canvas keeps what it holds)", result.missing),
        ("Graded but not scored (left out of the import: Canvas keeps what it holds)", result.not_scored),
        ("Unreadable files (scored 0: ask the student for a notebook that opens, then grade again)", result.unreadable),
        ("Late submissions (graded; any late penalty is yours to apply)", result.late),
        ("Resubmissions graded (Canvas renames a re-uploaded file name-1, name-2, ...)", result.resubmissions),
        ("Other files of students, not graded", result.not_graded),
        ("Notes", result.notes),
    ]
    for title, items in sections:
        lines.append(f"{title}: {len(items) if items else 'none'}")
        lines += [f"  - {clean_text(item)}" for item in items]
        lines.append("")
    lines += [
        "Next, in Canvas: Grades -> Import -> gradebook_import.csv; then, on the assignment's page,",
        "Re-upload Submissions -> feedback_upload.zip attaches each student's feedback file as a comment.",
    ]
    return "\n".join(lines) + "\n"


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(
        description="Grade a Canvas 'Download Submissions' zip into a Canvas gradebook export, ready to import."
    )
    parser.add_argument("submissions", type=Path, help="the zip that Canvas's Download Submissions gives")
    problem_arguments(parser)
    parser.add_argument("--gradebook", type=Path, required=True, help="the CSV that Canvas's Grades -> Export gives")
    parser.add_argument("--column", help='the assignment column to fill, e.g. "Problem 1 (12345)" or 12345')
    parser.add_argument(
        "--out", type=Path, required=True, help="folder for gradebook_import.csv, feedback/, report.txt"
    )
    parser.add_argument("--jobs", type=int, default=None, help="submissions graded at once (default: CPU count)")
    parser.add_argument(
        "--seed",
        type=seed_argument,
        default=None,
        help="seed of the test states (default: a fresh secret one; OUT/batch/batch.json records it)",
    )
    from labsupport.instructor.batch import check_compare_with, compare_with_argument  # heavy: the grader

    compare_with_argument(parser)
    args = parser.parse_args(argv)
    check_compare_with(parser, args.compare_with, Path(args.submissions))
    spec = chosen_spec(parser, args)
    if args.jobs is not None and args.jobs < 1:
        parser.error(f"--jobs must be at least 1, got {args.jobs}")
    for path, what in ((args.submissions, "submissions zip"), (args.gradebook, "gradebook")):
        if not Path(path).is_file():
            parser.error(f"no {what} at {path}")
    try:
        result = grade_canvas(
            args.submissions,
            args.gradebook,
            spec,
            args.out,
            args.column,
            args.jobs,
            seed=args.seed,
            compare_with=args.compare_with,
        )
    except ValueError as err:
        parser.error(str(err))
    if result.warning:
        print(result.warning)
    print(
        f"{len(result.scores)} scores written to {args.out / 'gradebook_import.csv'} "
        f"({result.column}); {len(result.unmatched)} unmatched files, {len(result.missing)} students "
        f"with nothing graded: see {args.out / 'report.txt'}"
    )


if __name__ == "__main__":
    keep_private()
    main()
