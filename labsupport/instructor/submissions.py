"""Submissions in a zip: the file names of Canvas's *Download Submissions* taken apart, the zip
read without trusting it, and each student's one notebook for a Problem chosen.

The Canvas command grades from such a zip (:mod:`labsupport.instructor.canvas`); the batch and
compare commands read one for the shared-code report (``--compare-with``, :func:`zip_notebooks`).

Canvas's own source (github.com/instructure/canvas-lms) is the reference for what follows.

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
"""

from __future__ import annotations

import json
import re
import unicodedata
import zipfile
import zlib
from dataclasses import dataclass
from pathlib import Path, PurePosixPath

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
    ``..`` part, a NUL byte, a symbolic link, two entries of one name (which of them to grade
    would be a guess), or a declared total over :data:`MAX_ZIP_BYTES`; the name checked is the
    one used. (Renaming an entry is safe: :meth:`zipfile.ZipFile.open`
    compares the file's own header with ``orig_filename``, which stays as read.)
    """
    infos = zf.infolist()
    if len(infos) > MAX_ZIP_ENTRIES:
        raise ValueError(f"the zip holds {len(infos)} entries, more than {MAX_ZIP_ENTRIES}: not a Canvas download")
    seen = set()
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
        if name in seen:
            raise ValueError(
                f"the zip holds two entries named {name!r}, so which one to grade is a guess; Canvas never "
                "writes that: download the submissions from Canvas again, or rename one and zip them again"
            )
        seen.add(name)
    total = sum(info.file_size for info in infos)
    if total > MAX_ZIP_BYTES:
        raise ValueError(
            f"the zip would unpack to {total / 2**30:.1f} GiB, more than {MAX_ZIP_BYTES / 2**30:.0f} GiB: refused"
        )
    return [info for info in infos if not info.is_dir()]


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


def plain(text: str) -> str:
    """Lower case, letters and digits only: the form in which file and column names are compared."""
    return "".join(c for c in unicodedata.normalize("NFKC", text).lower() if c.isalnum())


def choose_notebook(files: list[SubmissionFile], stem: str, problem: str) -> SubmissionFile | None:
    """The file of one student to grade: a notebook named after the Problem, latest upload first.

    Preference: a notebook whose name holds the Problem's notebook name (``problem1_reaching``),
    else one whose name holds the Problem's name (``problem1``), else any notebook; among
    equals, the highest attachment id (the latest upload, whatever Canvas's suffix says).
    """
    notebooks = [f for f in files if f.is_notebook]
    for key in (plain(stem), plain(problem), ""):
        named = [f for f in notebooks if key in plain(f.base_name)]
        if named:
            return max(named, key=lambda f: f.attachment_id or 0)
    return None


def other_problem(file_name: str, problem: str) -> str | None:
    """The Problem a file is named after (``problem2`` in ``problem2_tracking.ipynb``) when it is
    not ``problem``; None when the name names none, or this one."""
    named, own = re.search(r"problem(\d+)", plain(file_name)), re.search(r"problem(\d+)", plain(problem))
    return f"problem{named[1]}" if named and own and named[1] != own[1] else None


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
            other = pick and other_problem(pick.base_name, spec["problem"])
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
