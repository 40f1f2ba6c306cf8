"""The command line against malformed inputs: one table row per command (tests/fuzz_inputs).

Usage: python benchmarks/fuzz_cli.py [--seed N]

Counts, per command, the inputs tried, tracebacks, wrong successes (exit 0),
messages that name neither the file nor the field, and runs that left files
behind.  Every count but the first should be 0.
"""
import argparse
import os
import pathlib
import sys
import tempfile

import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "tests"))
import fuzz_inputs  # noqa: E402


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args(argv)
    rows = []
    for name, module in fuzz_inputs.available():
        with tempfile.TemporaryDirectory() as tmp:
            folder = pathlib.Path(tmp)
            cases = module.generate(folder, np.random.default_rng(args.seed))
            counts = {"traceback": 0, "exit 0": 0, "message names": 0, "left files": 0}
            for case in cases:
                problems, _ = fuzz_inputs.check(case, folder)
                for key in counts:
                    counts[key] += any(p.startswith(key) for p in problems)
        rows.append((f"mjccd {name.replace('_', '-')}", len(cases), *counts.values()))
    print("| command | inputs | tracebacks | wrong successes | message names neither file nor field | files left |")
    print("| --- | ---: | ---: | ---: | ---: | ---: |")
    for row in rows:
        print("| " + " | ".join(str(x) for x in row) + " |")
    total = [sum(r[k] for r in rows) for k in range(1, 6)]
    print("| all | " + " | ".join(str(x) for x in total) + " |")
    return 1 if any(total[1:]) else 0


if __name__ == "__main__":
    sys.exit(main())
