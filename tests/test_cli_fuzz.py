"""Fuzz the command line with malformed inputs of every kind (tests/fuzz_inputs).

For each input: exit status != 0, no traceback, a message naming the file or
the field, and no file left behind but the inputs (a partial batch may write
its declared output).
"""
import os
import sys

import numpy as np
import pytest

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import fuzz_inputs  # noqa: E402

COMMANDS = fuzz_inputs.available()


@pytest.mark.parametrize("name,module", COMMANDS, ids=[n for n, _ in COMMANDS])
def test_malformed_inputs(name, module, tmp_path):
    cases = module.generate(tmp_path, np.random.default_rng(0))
    assert cases, f"{name}: no fuzz inputs"
    failures = []
    for case in cases:
        problems, last = fuzz_inputs.check(case, tmp_path)
        if problems:
            failures.append(f"{case.label}: {'; '.join(problems)} -- {last}")
    assert not failures, f"{len(failures)}/{len(cases)} malformed {name} inputs mishandled:\n" + "\n".join(failures)
