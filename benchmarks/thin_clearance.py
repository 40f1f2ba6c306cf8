"""Thin bodies just clear of, or just into, each other: what the core and a Scene's kernel certify.

The stacked family of ``tests/test_adversarial.py``: 1000:1 needles and disks (needle over needle,
needle over disk, disk edge over face, face over face), one passing over the other with a clearance of
exactly +-``delta`` x size at its closest.  For each sign: how many ``mjccd.first_contact`` certifies
(free for the misses, a contact for the hits), how many it leaves uncertain or gets wrong, and how many
a two-body ``mjccd.scene.Scene``'s compiled kernel (``resolve_uncertain=False``) and the Scene itself
leave uncertain; then the median and largest time of ``first_contact``.

    python benchmarks/thin_clearance.py [--delta 1e-5 1e-6] [--cases 40] [--seed 5]
"""
import argparse
import pathlib
import random
import statistics
import sys
import time

import mjccd
from mjccd.scene import Scene

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[1] / "tests"))
import test_adversarial as family  # noqa: E402  (the generator of the stacked cases)
from test_scene import _two_pose_poses  # noqa: E402

SPECS = [(family.NEEDLE_FLAT, family.NEEDLE_FLAT, True), (family.NEEDLE_UP, family.DISK_FACE, False),
         (family.DISK_FACE, family.DISK_EDGE, False), (family.DISK_FACE, family.DISK_FACE, True)]


def measure(delta, cases, seed):
    """{"miss" | "hit": {verdict: count}} and the first_contact times (s) of ``cases`` stacked pairs."""
    rng = random.Random(seed)
    counts = {"miss": dict.fromkeys(("certified", "uncertain", "wrong", "kernel uncertain", "Scene uncertain"), 0),
              "hit": dict.fromkeys(("certified", "uncertain", "wrong", "kernel uncertain", "Scene uncertain"), 0)}
    times = []
    for n in range(cases):
        ra, rb, a_static = SPECS[n % 4]
        sign = 1 if (n // 4) % 2 else -1
        case = family._stacked(rng, f"c{n}", list(ra), list(rb), sign * delta * max(ra + rb), a_static, [])
        start, end = _two_pose_poses(case)
        motions = [mjccd.Rigid(p0[:3], p0[3:], p1[:3], p1[3:]) for p0, p1 in zip(start, end)]
        t0 = time.perf_counter()
        c = mjccd.first_contact(mjccd.Ellipsoid(ra), motions[0], mjccd.Ellipsoid(rb), motions[1])
        times.append(time.perf_counter() - t0)
        row = counts["miss" if sign > 0 else "hit"]
        if c is not None and c.certainty == "uncertain":
            row["uncertain"] += 1
        elif (c is None) == (sign > 0):
            row["certified"] += 1
        else:
            row["wrong"] += 1
        raw = Scene([ra, rb]).step(start, end, resolve_uncertain=False).first
        row["kernel uncertain"] += raw is not None and raw.bracket is not None
        first = Scene([ra, rb]).step(start, end).first
        row["Scene uncertain"] += first is not None and first.bracket is not None
    return counts, times


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--delta", type=float, nargs="+", default=[1e-5, 1e-6])
    parser.add_argument("--cases", type=int, default=40)
    parser.add_argument("--seed", type=int, default=5)
    args = parser.parse_args(argv)
    print("| clearance | pairs | certified | uncertain | wrong | kernel uncertain | Scene uncertain | median ms "
          "| max ms |")
    print("| --- | --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: |")
    for delta in args.delta:
        counts, times = measure(delta, args.cases, args.seed)
        for kind, sign, plural in (("miss", "+", "misses"), ("hit", "-", "hits")):
            row = counts[kind]
            print(f"| {sign}{delta:g} x size | {sum(row[k] for k in ('certified', 'uncertain', 'wrong'))} {plural} "
                  f"| {row['certified']} | {row['uncertain']} | {row['wrong']} | {row['kernel uncertain']} "
                  f"| {row['Scene uncertain']} | {1e3 * statistics.median(times):.0f} | {1e3 * max(times):.0f} |",
                  flush=True)


if __name__ == "__main__":
    main()
