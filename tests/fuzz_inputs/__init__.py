"""Malformed inputs for every ``mjccd`` command, as a careless user or an adversary would give them.

Each module here has ``generate(folder, rng)``: it writes its malformed files
into ``folder`` (a fresh temporary folder) and returns a list of
:class:`FuzzCase`.  :func:`check` runs one in-process through ``mjccd.cli.main``
and lists what it broke of the command line's promises: a non-zero exit, a
message that names the file or the field, no traceback, and no file left
behind.  ``tests/test_cli_fuzz.py`` asserts them; ``benchmarks/fuzz_cli.py``
prints the table.
"""
import contextlib
import importlib
import io
import os
from dataclasses import dataclass

MODULES = ("solve", "replay", "import_bvh", "fit", "bench")


@dataclass
class FuzzCase:
    label: str          # what is wrong with the input, for the report
    argv: list          # the mjccd arguments (strings)
    names: tuple        # at least one of these must appear in stderr: the file, the field
    partial: bool = False  # a batch where good cases are answered: exit 1 with the output written
    writes: tuple = ()  # outputs the command may leave (only with ``partial``)


def available():
    """(command name, generator module) for every module present."""
    found = []
    for name in MODULES:
        try:
            found.append((name, importlib.import_module(f"{__name__}.{name}")))
        except ModuleNotFoundError:
            continue
    return found


def _run(argv, cwd):
    from mjccd import cli

    out, err = io.StringIO(), io.StringIO()
    here = os.getcwd()
    os.chdir(cwd)
    try:
        with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
            try:
                code = cli.main(argv)
            except SystemExit as exc:  # argparse
                code = exc.code if isinstance(exc.code, int) else 2
    finally:
        os.chdir(here)
    return code, err.getvalue()


def check(case, folder):
    """(problems, last stderr line) of one case run in ``folder``; problems is empty when all promises hold."""
    before = set(os.listdir(folder))
    code, err = _run(case.argv, folder)
    left = set(os.listdir(folder)) - before - set(os.path.basename(w) for w in case.writes)
    problems = []
    if "Traceback" in err:
        problems.append("traceback")
    if code == 0:
        problems.append("exit 0 (wrong success)")
    if case.partial and any(not os.path.exists(os.path.join(folder, w)) for w in case.writes):
        problems.append("partial batch wrote no output")
    if not any(n in err for n in case.names):
        problems.append(f"message names none of {case.names}")
    if left:
        problems.append(f"left files {sorted(left)}")
    lines = err.strip().splitlines()
    return problems, lines[-1] if lines else ""
