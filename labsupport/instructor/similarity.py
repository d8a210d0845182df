"""Which submissions share code with each other, or with the master's solution: a lead for the
instructor, never a grade.

The batch grader (:mod:`labsupport.instructor.batch`, and so the Canvas command too) writes
two files beside ``grades.csv``:

* ``similarity.csv``: one row per pair of notebooks where either has at least
  :data:`FLAG_SHARE` of its own code in the other, or where the code they share in passages of
  :data:`MIN_PASSAGE` characters or more is as much as :data:`FLAG_SHARE` of a whole answer,
  and that share at least :data:`MIN_SHARED` of a whole answer in all, most shared first: the
  two files (one may be the master's solution), the share of each one's own code found in the
  other, how much code they share (in characters of normalised code, what copydetect calls
  tokens: every name replaced by one letter, spaces and comments dropped), and what they share
  in long passages as a share of a whole answer (over 100 % where they share more code than a
  whole answer holds: answers longer than the master's, or code beyond the answer);
* ``similarity.html``: the same pairs side by side, the shared passages marked, for reading in
  a browser (one self-contained page).

``python -m labsupport.instructor.compare`` (:mod:`labsupport.instructor.compare`) makes the same
report for a folder without grading it.

Each submission is compared with the others, with the master's solution and with the notebooks
of any ``--compare-with FOLDER_OR_ZIP`` (earlier years' submissions, say: references, not graded and
not compared with each other).

A notebook's own code is the source of its code cells (outputs are never read), less the cells
left exactly as handed out, and less every passage of the student notebook as handed out (the
stubs' signatures and docstrings, say), which every submission shares by design, and of the
course's other notebooks (the Tasks: a student may paste from them). Two notebooks
are compared with `copydetect <https://github.com/blingenf/copydetect>`_, which fingerprints
code as MOSS does (winnowed k-grams of its normalised text: every name replaced by one letter,
spaces and comments dropped): renamed variables and dropped comments do not hide a copy, and
passages shorter than 25 characters of that text do not count (a one-line PD law, the same in
every right answer, is about 17).

Measured on Problem 1: independently written right answers share 7 to 37 % of their own code
(its laws are short, its IK a textbook formula); a copy shares 100 %, even with its variables
renamed and its comments dropped. Padding does not hide a copy either: two students who hand in
one answer, each with pages of unrelated code added, share only a small part of their own code,
but as much code as a whole answer, and that lists them. Only passages of :data:`MIN_PASSAGE`
characters or more count toward a whole answer: long notebooks written apart share many short
idioms, which add up to as much. A whole answer is the master's own
code, or, where the checkout lacks the master, the median submission's. Read the marked
passages before concluding anything. The
master's solution is compared too where the checkout holds it (``spec["master"]``): the
masters are in the course repository, so a public repository shows them to anyone who looks.
"""

from __future__ import annotations

import csv
import html
import io
import itertools
import statistics
from dataclasses import dataclass

try:
    from copydetect import CodeFingerprint, compare_files
    from copydetect.defaults import NOISE_THRESHOLD
    from copydetect.utils import find_fingerprint_overlap, get_copied_slices, highlight_overlap
except ImportError as err:  # a checkout whose environment predates the report
    raise ImportError(
        "the batch grader's shared-code report needs copydetect: run `bash .ci/setup` from the repository root "
        "(or `pip install -e '.[instructor]'`)"
    ) from err

from labsupport.instructor import judge
from labsupport.instructor.assign import ROOT
from labsupport.instructor.outputs import clean_text, csv_cell

#: A pair is listed when either notebook has at least this share of its own code in the other.
FLAG_SHARE = 0.6
#: The shortest shared passage that counts toward a whole answer [characters of code with every
#: name replaced by one letter and spaces dropped, as copydetect compares it]: about four lines
#: of a law (``tau = Kp * (q_d - q) - Kd * qdot`` is 13), more than twice the 25 below which
#: copydetect counts nothing. Task 4's notebook shares no code on purpose with Task 1's, 2's or
#: 3's, yet the passages they share (idioms: a plot, a printout) add up to 91 to 105 % of a
#: whole answer of Problem 1, none longer than 53 characters; a copied answer is one passage of
#: hundreds (363 for Problem 1's).
MIN_PASSAGE = 60
#: The least a pair must share to be listed, as a share of a whole answer: a third, more than
#: the PD and computed-torque laws together (31 % of Problem 1's master), less than its inverse
#: kinematics alone (69 %). Below it, a high share of one's own code only means there is little
#: of it: two notebooks that each hold just the textbook PD and computed-torque lines (right
#: answers write them alike) have 73 % of their own code in each other.
MIN_SHARED = 1 / 3
#: The name the master's solution goes by in the reports.
MASTER = "master solution"
#: A notebook with more own code than this [characters] is not compared (fingerprinting this
#: much takes about 2 s): the grader's one bound on the code it reads for the instructor's leads.
MAX_CODE_CHARS = judge.MAX_CODE_CHARS


@dataclass(frozen=True)
class Pair:
    """Two notebooks that share code: ``share_a`` of ``a``'s own code is in ``b``, and
    ``share_b`` of ``b``'s in ``a``; ``shared`` counts the characters of normalised code they
    share; what they share in passages of :data:`MIN_PASSAGE` or more is ``share_answer`` of a
    whole answer; ``marked_a`` and ``marked_b`` are each one's code as HTML, shared passages in
    ``<mark>``."""

    a: str
    b: str
    share_a: float
    share_b: float
    shared: int
    share_answer: float
    marked_a: str
    marked_b: str


def own_code(data: bytes, handed_out: frozenset[str] = frozenset()) -> str:
    """The source of a notebook's code cells, one after the other, less the cells that are
    exactly as handed out (``handed_out``: their sources); ``ValueError`` if it is not a notebook
    (:func:`labsupport.instructor.judge.read_cells`). A lone surrogate (``"\\ud800"`` in the
    notebook's JSON), which no UTF-8 page can hold, is kept as that escape."""
    code = "\n\n".join(source for _, source in judge.read_cells(data) if source not in handed_out)
    return code.encode("utf-8", "backslashreplace").decode("utf-8")


def _fingerprint(name: str, code: str, boilerplate) -> CodeFingerprint:
    """copydetect's fingerprint of ``code`` (Python), less the fingerprints in ``boilerplate``."""
    return CodeFingerprint(name, NOISE_THRESHOLD, 1, boilerplate, filter=True, language="python", fp=io.StringIO(code))


def listed_share(share_a: float, share_b: float, share_answer: float) -> float:
    """What lists a pair (at :data:`FLAG_SHARE` or more) and orders the list: the largest of its
    three shares, a share of more than a whole answer (two copies holding the same extra code)
    counting as a whole."""
    return max(share_a, share_b, min(share_answer, 1.0))


def in_long_passages(a: CodeFingerprint, b: CodeFingerprint, shortest: int = MIN_PASSAGE) -> int:
    """How much of ``a``'s code lies in the passages it shares with ``b`` of at least ``shortest``
    characters of normalised code (:data:`MIN_PASSAGE`): what two notebooks share that is no chance
    match of a few idioms."""
    indices, _ = find_fingerprint_overlap(a.hashes, b.hashes, a.hash_idx, b.hash_idx)
    starts, ends = get_copied_slices(indices, a.k)
    lengths = ends - starts
    return int(lengths[lengths >= shortest].sum())


def answer_tokens(prints: dict[str, CodeFingerprint], codes: dict[str, str]) -> int:
    """How much own code (characters of normalised code) a whole answer has: the master's
    (``MASTER`` in ``prints``), else the median of the submissions' (``codes``) that have any;
    at least 1."""
    if MASTER in prints:
        return max(1, int(prints[MASTER].token_coverage))
    sizes = [prints[name].token_coverage for name in codes if prints[name].token_coverage]
    return max(1, int(statistics.median(sizes))) if sizes else 1


def similar_pairs(
    codes: dict[str, str], handed_out: str, references: dict[str, str] | None = None, flag: float = FLAG_SHARE
) -> list[Pair]:
    """Every pair of ``codes`` (name -> own code), and each of them with each of ``references``
    (the master's solution, earlier years' notebooks: compared with the submissions, not with
    each other), where either has at least ``flag`` of its own code in the other, or where they
    share at least ``flag`` of a whole answer (:func:`answer_tokens`) in passages of
    :data:`MIN_PASSAGE` characters or more (:func:`in_long_passages`), which padding cannot hide,
    and where they share at least :data:`MIN_SHARED` of a whole answer in all (``flag`` where
    that is lower: a lower bar lists more); most shared first, a reference always second. Code
    found in ``handed_out`` (the course's notebooks as handed out) is nobody's own."""
    references = references or {}
    boilerplate = sorted(_fingerprint("handed_out", handed_out, None).hashes)
    everyone = {**references, **codes}
    prints = {name: _fingerprint(name, code, boilerplate) for name, code in everyone.items()}
    answer = answer_tokens(prints, codes)
    pairs = []
    for a, b in [*itertools.combinations(codes, 2), *itertools.product(codes, references)]:
        shared, (share_a, share_b), (slices_a, slices_b) = compare_files(prints[a], prints[b])
        if (
            not shared
            or shared < min(MIN_SHARED, flag) * answer
            or listed_share(share_a, share_b, shared / answer) < flag
        ):
            continue  # all that is shared, short passages too, is an upper bound of what counts
        share_answer = in_long_passages(prints[a], prints[b]) / answer
        if listed_share(share_a, share_b, share_answer) < flag:
            continue
        marked_a, _ = highlight_overlap(everyone[a], slices_a, "<mark>", "</mark>", escape_html=True)
        marked_b, _ = highlight_overlap(everyone[b], slices_b, "<mark>", "</mark>", escape_html=True)
        pairs.append(Pair(a, b, float(share_a), float(share_b), int(shared), share_answer, marked_a, marked_b))
    return sorted(pairs, key=lambda p: (-listed_share(p.share_a, p.share_b, p.share_answer), p.a, p.b))


def similarity_csv(pairs: list[Pair]) -> str:
    """The text of ``similarity.csv``: a row per pair, shares in percent."""
    buf = io.StringIO()
    writer = csv.writer(buf, lineterminator="\n")
    writer.writerow(
        [
            "file",
            "other",
            "file's own code in other [%]",
            "other's own code in file [%]",
            "shared [characters of normalised code]",
            "shared, of a whole answer [%]",
        ]
    )
    for p in pairs:
        shares = (f"{100 * share:.0f}" for share in (p.share_a, p.share_b))
        writer.writerow([csv_cell(p.a), csv_cell(p.b), *shares, p.shared, f"{100 * p.share_answer:.0f}"])
    return buf.getvalue()


_STYLE = """
body { font-family: system-ui, sans-serif; margin: 1.5rem; color: #1a1a1a; background: #fff; }
.pair { display: grid; grid-template-columns: repeat(auto-fit, minmax(min(28rem, 100%), 1fr)); gap: 1rem; }
pre { background: #f6f6f6; padding: .5rem; overflow-x: auto; font-size: .85rem; }
mark { background: #ffd54f; color: #1a1a1a; }
table { border-collapse: collapse; max-width: 100%; }
th, td { border: 1px solid #999; padding: .25rem .5rem; overflow-wrap: anywhere; }
"""


def _text(text: str) -> str:
    """A file name or a reason as the page shows it: as text, on one line, and writable in UTF-8
    (a name may hold what UTF-8 cannot: :func:`labsupport.instructor.outputs.clean_text`)."""
    return html.escape(clean_text(text))


def _side(name: str, share: float, marked: str) -> str:
    """One notebook's half of a pair on the page; its code scrolls sideways, by keyboard too."""
    return (
        f"<div><h3>{_text(name)} ({100 * share:.0f} % of its own code shared)</h3>"
        f"<pre tabindex='0'>{marked}</pre></div>"
    )


def pairs_listed(reports: dict[str, str]) -> int:
    """How many pairs the reports of :func:`similarity_reports` list (the CSV's rows)."""
    return len(reports["similarity.csv"].splitlines()) - 1


def similarity_html(
    pairs: list[Pair], problem: str, compared: int, references: int, left_out: dict[str, str], flag: float = FLAG_SHARE
) -> str:
    """``similarity.html``: a table of the pairs, then each pair's code side by side, the shared
    passages marked; ``compared`` submissions were compared with each other and with
    ``references`` notebooks (the master's solution, earlier years'), and ``left_out`` maps the
    notebooks not compared to why."""
    e = _text
    not_compared = (
        "<p>Not compared: " + "; ".join(f"{e(name)} ({e(why)})" for name, why in sorted(left_out.items())) + ".</p>"
        if left_out
        else ""
    )
    rows = "".join(
        f'<tr><td><a href="#pair-{i}">{e(p.a)}</a></td><td>{e(p.b)}</td>'
        f"<td>{100 * p.share_a:.0f} %</td><td>{100 * p.share_b:.0f} %</td><td>{100 * p.share_answer:.0f} %</td></tr>"
        for i, p in enumerate(pairs, 1)
    )
    table = (
        "<table><caption>Pairs, most shared first</caption><tr><th scope='col'>file</th>"
        "<th scope='col'>other</th><th scope='col'>its own code found in the other</th>"
        "<th scope='col'>the other's found in it</th><th scope='col'>shared code, of a whole answer "
        "(over 100 %: more than a whole answer)</th></tr>"
        f"{rows}</table>"
        if pairs
        else "<p>No pair reaches that share.</p>"
    )
    sections = "".join(
        f'<section id="pair-{i}"><h2>{i}. {e(p.a)} and {e(p.b)}</h2><div class="pair">'
        f"{_side(p.a, p.share_a, p.marked_a)}{_side(p.b, p.share_b, p.marked_b)}</div></section>"
        for i, p in enumerate(pairs, 1)
    )
    return (
        f'<!DOCTYPE html><html lang="en"><head><meta charset="utf-8"><title>Shared code: {e(problem)}</title>'
        f'<meta name="viewport" content="width=device-width, initial-scale=1"><style>{_STYLE}</style></head>'
        f"<body><main><h1>Shared code: {e(problem)}</h1><p>Submissions compared: {compared}, with each other "
        f"and with {references} reference notebook{'' if references == 1 else 's'} (the master's solution "
        "where there is one, and any earlier notebooks given with --compare-with). Listed: the pairs where "
        "either notebook has at least "
        f"{100 * flag:g} % of its own code (what it adds to the notebook as handed out) in the other, or where "
        f"the two share as much code as {100 * flag:g} % of a whole answer (the master's own code, else the median "
        "submission's), counting passages of about four lines or more (shorter ones two long notebooks share by "
        "chance), so that code added around a copy does not hide it (a share of the size of a whole answer, "
        "not of either notebook: where two share more code than a whole answer holds, as answers longer than "
        "the master's or code shared beyond the answer do, it is over 100 %); either way, only where the two "
        "share at "
        f"least {100 * min(MIN_SHARED, flag):.0f} % of a whole answer in all (less, such as the textbook PD and "
        "computed-torque lines alone, is no lead). "
        "Code from the course's notebooks as handed out (the Problem's, the Tasks') is nobody's own. Shared "
        "passages are <mark>marked</mark>; names and comments do not matter. In a trial on Problem 1, "
        "independently written right answers shared 7 to 37 % of their own code, and copies 100 %: read the "
        "marked passages before concluding anything.</p>"
        f"{not_compared}{table}{sections}</main></body></html>\n"
    )


def handed_out_and_master(spec: dict) -> tuple[frozenset[str], str | None]:
    """The code cells of the student notebook as handed out (their sources), and the master's
    own code (``None`` where this checkout does not hold it), for the Problem of ``spec``;
    ``ValueError`` without the former, since every submission holds it."""
    try:
        handed_out = frozenset(source for _, source in judge.read_cells((ROOT / spec["student"]).read_bytes()))
    except (KeyError, TypeError, OSError, ValueError) as err:
        raise ValueError(
            f"the student notebook of {spec.get('problem')} (the spec's 'student', {spec.get('student')!r}) cannot "
            f"be read ({err}): regenerate the spec with labsupport.instructor.assign"
        ) from None
    master_path = ROOT / spec.get("master", "")
    try:
        master = own_code(master_path.read_bytes(), handed_out) if master_path.is_file() else None
    except ValueError:
        master = None
    return handed_out, master


def course_code(spec: dict) -> str:
    """The code cells of every notebook the course hands out beside the Problem's own (the
    Tasks, the other Problem: the ``.ipynb`` files in the student notebook's folder), one after
    the other. A student may paste from them, so what two notebooks share of it is nobody's own
    code: two students who each explored with code from a different Task share its plotting and
    printing idioms, as much as a whole answer, without sharing an answer."""
    sources = []
    for path in sorted((ROOT / spec["student"]).parent.glob("*.ipynb")):
        try:
            sources += [source for _, source in judge.read_cells(path.read_bytes())]
        except (OSError, ValueError):
            continue
    return "\n\n".join(sources)


def _own_codes(notebooks: dict[str, bytes], handed_out: frozenset[str], left_out: dict[str, str]) -> dict[str, str]:
    """Each notebook's own code (:func:`own_code`), by name; a notebook that cannot be compared
    goes into ``left_out`` instead, with the reason."""
    codes = {}
    for name, data in notebooks.items():
        try:
            code = own_code(data, handed_out)
        except ValueError:
            left_out[name] = "not a notebook the grader can read"
            continue
        if len(code) > MAX_CODE_CHARS:
            left_out[name] = f"{len(code):,} characters of its own code, more than {MAX_CODE_CHARS:,}"
        else:
            codes[name] = code
    return codes


def similarity_reports(
    notebooks: dict[str, bytes], spec: dict, earlier: dict[str, bytes] | None = None, flag: float = FLAG_SHARE
) -> dict[str, str]:
    """The texts of ``similarity.csv`` and ``similarity.html`` (by file name) for ``notebooks``
    (file name -> bytes) of the Problem of ``spec``, compared with each other, with the master's
    solution and with the ``earlier`` notebooks (say, last year's, named by folder and file).
    Files that are not notebooks, or hold more than :data:`MAX_CODE_CHARS` of own code, are left
    out, and the page says so."""
    handed_out, master = handed_out_and_master(spec)
    left_out = {}
    codes = _own_codes(notebooks, handed_out, left_out)
    references = _own_codes(earlier or {}, handed_out, left_out)
    if master is not None:
        references[MASTER] = master
    pairs = similar_pairs(codes, "\n\n".join([*sorted(handed_out), course_code(spec)]), references, flag)
    return {
        "similarity.csv": similarity_csv(pairs),
        "similarity.html": similarity_html(pairs, spec["problem"], len(codes), len(references), left_out, flag),
    }
