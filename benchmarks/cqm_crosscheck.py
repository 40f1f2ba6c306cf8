"""MuJoCo's primitives as composite quadric models (mjccd.geoms.cqm) against the compiled geom kernel.

Two independent methods on the same random pairs: the composite quadric solver (exact elimination to one
polynomial in t per element pair, candidate roots isolated over the rationals, touching points tested at 60
digits) and ``mjccd.geoms.geom_first_contact`` (certified scans of polynomial systems).  Pairs as in
tests/test_cqm.py: sizes 0.2-0.6, B closing on A from 2.5 along a random direction, both turning (a quaternion
lerp) unless ``--translate``.  Per shape pair: cases, agreements (both free, or both certified within 1e-9 in
time and 1e-7 in point), disagreements, the composite solver's uncertain answers and its median and largest
time per case.

    python benchmarks/cqm_crosscheck.py [--cases 3] [--seed 11] [--translate]
"""
import argparse
import pathlib
import statistics
import sys
import time

import numpy as np

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[1] / "tests"))
from test_cqm import PRIMITIVES, _random_pair  # noqa: E402  (the pairs of the tests)

from mjccd.geoms import cqm, geom_first_contact  # noqa: E402

KINDS = list(PRIMITIVES)
PAIRS = [(a, b) for i, a in enumerate(KINDS) for b in KINDS[i:]]


def _agree(g, c):
    if g is None or c is None:
        return g is None and c is None
    if g.certainty != "certified" or c.certainty != "certified" or abs(g.time - c.time) > 1e-9:
        return False
    return g.point is None or c.point is None or float(np.abs(g.point - c.point).max()) <= 1e-7


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cases", type=int, default=3, help="random pairs per shape pair")
    parser.add_argument("--seed", type=int, default=11)
    parser.add_argument("--translate", action="store_true", help="no turning: each body keeps its orientation")
    args = parser.parse_args(argv)
    print("| pair | cases | agree | disagree | cqm uncertain | cqm median s | cqm max s |")
    print("| --- | ---: | ---: | ---: | ---: | ---: | ---: |")
    for p, (kind_a, kind_b) in enumerate(PAIRS):
        agree = disagree = uncertain = 0
        times = []
        for k in range(args.cases):
            (ga, ca, ma), (gb, cb, mb) = _random_pair(kind_a, kind_b, args.seed + 1000 * p + k, not args.translate)
            g = geom_first_contact(ga, ma, gb, mb)
            start = time.perf_counter()
            c = cqm.cqm_first_contact(ca, ma, cb, mb)
            times.append(time.perf_counter() - start)
            uncertain += c is not None and c.certainty == "uncertain"
            if _agree(g, c):
                agree += 1
            else:
                disagree += 1
                print(f"  {kind_a}-{kind_b} case {k}: geom {g}, cqm {c}", file=sys.stderr)
            print(f"  {kind_a}-{kind_b} {k + 1}/{args.cases}", file=sys.stderr)
        print(f"| {kind_a}-{kind_b} | {args.cases} | {agree} | {disagree} | {uncertain} | "
              f"{statistics.median(times):.1f} | {max(times):.1f} |", flush=True)


if __name__ == "__main__":
    main()
