"""Per-category results of the certified core on a case file scored against its reference answers.

For every case: whether the answer is within the accuracy definition (|dt| <= 1e-9 on the
first contact and every interval end, same status at start and number of intervals), its
certainty, the precision tier it needed (double precision with the constant bound, with the
coefficient-wise bound, or rational arithmetic) and its solve time.  Prints one row per
category (the first tag of each case).

    python benchmarks/certified_core.py tests/data/adversarial_public.json tests/data/adversarial_expected.json
"""
import argparse
import collections
import json
import time

from mjccd.cases import _body
from mjccd.ccd import DOUBLE, DOUBLE_TIGHT, RATIONAL, solve_motions

TIERS = {DOUBLE: "double", DOUBLE_TIGHT: "double, coefficient-wise bound", RATIONAL: "rational"}


def _ok(solution, expected):
    if {1: "separate", 0: "touching", -1: "overlapping"}[solution.status_at_start] != expected["status_at_start"]:
        return False
    got, want = solution.intervals, expected["intervals"]
    if len(got) != len(want):
        return False
    return all(abs(float(x) - float(y)) <= 1e-9 for (a, b), (c, d) in zip(got, want) for x, y in ((a, c), (b, d)))


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("cases")
    parser.add_argument("expected")
    args = parser.parse_args(argv)
    cases = json.load(open(args.cases))["cases"]
    expected = {r["id"]: r for r in json.load(open(args.expected))["results"]}
    rows = collections.defaultdict(lambda: collections.Counter())
    times = collections.defaultdict(list)
    for case in cases:
        a, ma, _ = _body(case, "a")
        b, mb, _ = _body(case, "b")
        solve_motions(a, ma, b, mb)  # compile / warm up
        start = time.perf_counter()
        solution = solve_motions(a, ma, b, mb)
        elapsed = time.perf_counter() - start
        category = case.get("tags", ["?"])[0]
        row = rows[category]
        row["cases"] += 1
        row["ok"] += _ok(solution, expected[case["id"]])
        row["uncertain"] += not solution.certified
        row[TIERS[solution.precision]] += 1
        times[category].append(elapsed)
    print("| category | cases | ok | uncertain | double | coefficient-wise bound | rational | median ms | max ms |")
    print("| --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: |")
    total = collections.Counter()
    for category, row in rows.items():
        total.update(row)
        t = sorted(times[category])
        print(f"| {category} | {row['cases']} | {row['ok']} | {row['uncertain']} | {row['double']} | "
              f"{row['double, coefficient-wise bound']} | {row['rational']} | {1e3 * t[len(t) // 2]:.2f} | "
              f"{1e3 * t[-1]:.1f} |")
    print(f"| all | {total['cases']} | {total['ok']} | {total['uncertain']} | {total['double']} | "
          f"{total['double, coefficient-wise bound']} | {total['rational']} | | |")


if __name__ == "__main__":
    main()
