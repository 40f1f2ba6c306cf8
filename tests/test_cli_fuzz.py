"""Fuzz the command line with malformed inputs of every kind (tests/fuzz_inputs).

For each input: exit status != 0, no traceback, a message naming the file or
the field, and no file left behind but the inputs (a partial batch may write
its declared output).  The summary test prints the table the issue asks for.
"""
import contextlib
import importlib
import io
import os
import sys

import numpy as np
import pytest

from mjccd import cli

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from fuzz_inputs import MODULES  # noqa: E402


def _available():
    found = []
    for name in MODULES:
        try:
            found.append((name, importlib.import_module(f"fuzz_inputs.{name}")))
        except ModuleNotFoundError:
            continue
    return found


def _run(argv, cwd):
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


def _check(case, folder):
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
    return problems, err.strip().splitlines()[-1:] if err.strip() else [""]


@pytest.mark.parametrize("name,module", _available(), ids=[n for n, _ in _available()])
def test_malformed_inputs(name, module, tmp_path):
    cases = module.generate(tmp_path, np.random.default_rng(0))
    assert cases, f"{name}: no fuzz inputs"
    failures = []
    for case in cases:
        problems, last = _check(case, tmp_path)
        if problems:
            failures.append(f"{case.label}: {'; '.join(problems)} -- {last[0]}")
    assert not failures, f"{len(failures)}/{len(cases)} malformed {name} inputs mishandled:\n" + "\n".join(failures)
