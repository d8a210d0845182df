"""Shared pytest configuration.

Notebooks stored under tests/ (e.g. graded submissions) are data, not notebooks to execute:
nbval only collects the course notebooks passed on the command line (notebooks/).
"""

collect_ignore_glob = ["*.ipynb", "*/*.ipynb", "*/*/*.ipynb", "*/*/*/*.ipynb"]
