"""Instructor tooling: generating the Problems from their masters, and batch grading.

This package lives in the course repository only. It is *not* part of what a student installs
(``pyproject.toml`` leaves it out of the wheel that Colab gets), so nothing in it is within a
submission's reach: run it from a checkout of the course repository.

==================  ===================================================================
``assign``          master notebook → student notebook + autograder spec
``isolation``       the bubblewrap sandbox: what a submission sees, its limits
``sandbox``         the server that runs one submission's cells inside it and answers calls
``judge``           grades one submission through a sandbox
``batch``           grades a folder of submissions into a CSV and feedback files
``similarity``      which submissions share code with each other or with a master's solution
``compare``         the same shared-code report for a folder, without grading it
``rubric``          a Problem's grading rubric (points, scoring, each named mistake's credit)
``canvas``          Canvas "Download Submissions" zip + gradebook export → graded gradebook to import
``submissions``     a submissions zip read safely: Canvas's file names, each student's notebook
``gradebook``       a Canvas gradebook export read, and written back with one column filled
``outputs``         what the graders write: texts made safe for a file, earlier runs kept
==================  ===================================================================
"""
