"""Bibliography labels in the form the pages cite: author and year.

The pages cite with sphinxcontrib-bibtex's author-year style ("Lynch and Park [2017]"), but
pybtex's ``plain`` style labels the reference list by number, so the list read [1]–[6], and the
link back from each entry to where it is cited was read out as "1", "2", "3". The style
``author_year_plain`` is ``plain`` with each entry labelled by its authors' last names and its
year, as the text names it ("Lynch and Park 2017", "Todorov et al. 2012"); two entries that
would share a label get "a", "b" after the year.
"""

from __future__ import annotations

from collections import Counter

from pybtex.plugin import register_plugin
from pybtex.style.formatting.plain import Style as PlainStyle
from pybtex.style.labels import BaseLabelStyle


def _who(entry) -> str:
    """The entry's authors (or editors) as the text names them: one, two, or the first et al."""
    people = entry.persons.get("author") or entry.persons.get("editor") or []
    names = [" ".join(person.last_names) or str(person) for person in people]
    names = [name.strip("{}") for name in names]
    if not names:
        return entry.key
    if len(names) == 1:
        return names[0]
    return f"{names[0]} and {names[1]}" if len(names) == 2 else f"{names[0]} et al."


class AuthorYearLabels(BaseLabelStyle):
    """Labels ``Author Year``, made unique with a letter after the year where two coincide."""

    def format_labels(self, sorted_entries):
        entries = list(sorted_entries)
        labels = [f"{_who(entry)} {entry.fields.get('year', '')}".strip() for entry in entries]
        count, seen = Counter(labels), Counter()
        for label in labels:
            seen[label] += 1
            yield label + (chr(ord("a") + seen[label] - 1) if count[label] > 1 else "")


class AuthorYearPlain(PlainStyle):
    """pybtex's ``plain`` style with :class:`AuthorYearLabels`."""

    default_label_style = AuthorYearLabels


def setup(app):
    register_plugin("pybtex.style.labels", "author_year", AuthorYearLabels)
    register_plugin("pybtex.style.formatting", "author_year_plain", AuthorYearPlain)
    return {"parallel_read_safe": True, "parallel_write_safe": True}
