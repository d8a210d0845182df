"""Fixtures of the site tests (defined in sitetools.py) and the summary of the figures."""

from sitetools import ARTIFACTS, SUMMARY, browser, on_every_page, server, site, tab_page, visit  # noqa: F401  (fixtures)


def pytest_terminal_summary(terminalreporter):
    if SUMMARY:
        terminalreporter.section("site figures")
        for line in SUMMARY:
            terminalreporter.write_line(line)
        ARTIFACTS.mkdir(parents=True, exist_ok=True)
        (ARTIFACTS / "site_figures.txt").write_text("\n".join(SUMMARY) + "\n", encoding="utf-8")
