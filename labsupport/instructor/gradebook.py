"""A Canvas gradebook export, read as Canvas's importer reads it, and written back with one
assignment column filled: the file the Canvas command gives the instructor to import
(:mod:`labsupport.instructor.canvas`).

Canvas's own source (github.com/instructure/canvas-lms) is the reference; the community
guides say the same in fewer words.

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

import csv
import io
import math
import re
from dataclasses import dataclass
from pathlib import Path

from labsupport.instructor.submissions import plain

_ASSIGNMENT_HEADER = re.compile(r"^(?P<title>.*)\s\((?P<id>\d+)\)$")

_COMPUTED_HEADER = re.compile(
    "Current Score|Current Points|Current Grade|Final Score|Final Points|Final Grade|Override Score"
    "|Override Grade|Override Status"
)

_POSTING_CELL = re.compile(r"^\s*(Muted|Manual Posting.*)?\s*$", re.IGNORECASE)


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
            points = float(decimal_point(text))
        except ValueError:
            points = float("nan")
        if not points > 0:  # blank, text, 0 or negative: every score would be scaled to nothing
            raise ValueError(
                f"the Points Possible row says {text!r} under {self.header[column]!r}, not a positive number: "
                "set the assignment's points in Canvas and export the gradebook again"
            )
        return points


def decimal_point(text: str) -> str:
    """``"12,5"`` -> ``"12.5"``, as Canvas's importer reads a decimal comma."""
    return text.replace(",", ".") if "." not in text else text.replace(",", "")


def split_records(text: str) -> list[str]:
    """Cut CSV text into records, each with its line ending; a newline inside quotes stays inside.

    Raises:
        ValueError: a quote is never closed (the record it opens runs to the end: the last one).
    """
    records, start, quoted = [], 0, False
    for i, c in enumerate(text):
        if c == '"':
            quoted = not quoted
        elif c == "\n" and not quoted:
            records.append(text[start : i + 1])
            start = i + 1
    if start < len(text):
        records.append(text[start:])
    if quoted:
        raise ValueError(f'a quote (") opened in row {len(records)} is never closed')
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
        sizes = {len(next(csv.reader(io.StringIO(line), delimiter=sep), [])) for line in lines}
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
    try:
        records = split_records(text[len(bom) :])
    except ValueError as err:
        raise _not_a_gradebook(path, str(err)) from None
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


def names_problem(title: str, problem: str) -> bool:
    """Whether an assignment's title names ``problem``: ``problem1`` in "Problem 1: Reaching", not
    in "Problem 10"."""
    return re.search(re.escape(plain(problem)) + r"(?!\d)", plain(title)) is not None


def column_warning(header: str, problem: str) -> str:
    """A warning when the column chosen (by ``--column``) does not name the Problem, else ""."""
    match = _ASSIGNMENT_HEADER.match(header)
    if names_problem(match["title"] if match else header, problem):
        return ""
    return (
        f"Check first: the column's title does not name {problem}; make sure it is this Problem's assignment "
        "before you import (--column chose it)"
    )


def format_score(value: float) -> str:
    """A score as Canvas shows it: at most two decimals, no trailing zeros (``7.5``, ``15``)."""
    text = f"{value:.2f}".rstrip("0").rstrip(".")
    return "0" if text in ("-0", "") else text


def apportion(parts: list[float], total: float | None = None) -> list[float]:
    """``parts`` rounded to hundredths so that they add up to ``total`` (their sum by default)
    rounded to hundredths: each is rounded down, then those with the largest remainders up, one
    hundredth each, until the sum is reached (Hamilton's method). Rounded one by one, the checks'
    points scaled to a Canvas column could add up to a hundredth more or less than the score.

    >>> apportion([4 / 3, 4 / 3, 4 / 3], 4.0)
    [1.34, 1.33, 1.33]
    """
    cents = [100 * p for p in parts]
    kept = [math.floor(c + 1e-6) for c in cents]  # 1e-6: a 2.0 held as 1.99999... is 2
    target = round(100 * (sum(parts) if total is None else total))
    largest_remainder_first = sorted(range(len(cents)), key=lambda k: kept[k] - cents[k])
    for k in largest_remainder_first[: max(0, target - sum(kept))]:
        kept[k] += 1
    return [k / 100 for k in kept]


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
