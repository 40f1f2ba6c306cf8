"""Whole motion collections: every clip replayed with exact CCD, its contacts and checks in two Parquet datasets.

- :mod:`~mjccd.collection.clips`: the clips that folders and globs name, and their keys;
- :mod:`~mjccd.collection.checks`: one clip's replay, its contact rows and its flags;
- :mod:`~mjccd.collection.tables`: the Parquet parts, written so that a run resumes;
- :mod:`~mjccd.collection.engines`: this process, a local process pool or Ray;
- :mod:`~mjccd.collection.run`: :func:`scan`, what ``mjccd scan`` runs.
"""
from mjccd.collection.checks import FLAGS, ScanOptions
from mjccd.collection.run import ScanReport, scan
from mjccd.collection.tables import read_tables

__all__ = ["FLAGS", "ScanOptions", "ScanReport", "read_tables", "scan"]
