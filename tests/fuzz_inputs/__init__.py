"""Malformed inputs for every ``mjccd`` command, as a careless user or an adversary would give them.

Each module here has ``generate(folder, rng)``: it writes its malformed files
into ``folder`` (a fresh temporary folder) and returns a list of
:class:`FuzzCase`.  ``tests/test_cli_fuzz.py`` runs them all in-process and
checks the promises of the command line: a non-zero exit, one message that
names the file or the field, no traceback, and no file left behind.
"""
from dataclasses import dataclass


@dataclass
class FuzzCase:
    label: str          # what is wrong with the input, for the report
    argv: list          # the mjccd arguments (strings)
    names: tuple        # at least one of these must appear in stderr: the file, the field
    partial: bool = False  # a batch where good cases are answered: exit 1 with the output written
    writes: tuple = ()  # outputs the command may leave (only with ``partial``)


MODULES = ("solve", "replay", "import_bvh", "fit", "bench")
