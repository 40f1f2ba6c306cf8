"""Thin bodies: what a 20:1 or 100:1 ellipsoid costs the exact solver, given first or second.

Random close rigid pairs (``mjccd.bench.peers.random_rigid_queries``, turning up to 0.5 rad), one
body flattened along a random axis.  For each set: the median, mean and largest time of
``mjccd.first_contact`` (after one untimed call), the share of pairs that needed the rational tier,
the share a two-body ``mjccd.scene.Scene``'s compiled kernel (no rational tier) leaves uncertain, and the
share still uncertain once the Scene has asked the core again (its default, ``mjccd.settle``).
Prints a markdown table; the numbers depend on the machine, the ratios between rows much less.

    python benchmarks/thin_bodies.py [--pairs 200] [--seed 9]
"""
import argparse
import statistics
import time

import numpy as np

import mjccd
from mjccd.bench import peers
from mjccd.ccd import RATIONAL, solve_motions
from mjccd.scene import Scene


def measure(aspect, thin, pairs, seed):
    """(median µs, mean µs, max ms, share through the rational tier, shares uncertain in a Scene's kernel and
    in the Scene)."""
    rng = np.random.default_rng(seed)
    times, rational, kernel, uncertain = [], 0, 0, 0
    queries = peers.random_rigid_queries(pairs, seed=seed, max_angle=0.5)
    for q in queries:
        radii = [np.array(q.radii_a, float), np.array(q.radii_b, float)]
        radii[thin][rng.integers(3)] /= aspect
        poses = [(q.position_a, q.quaternion_a), (q.position_b, q.quaternion_b)]
        motions = [mjccd.Rigid(p[0], r[0], p[1], r[1]) for p, r in poses]
        a, b = mjccd.Ellipsoid(radii[0]), mjccd.Ellipsoid(radii[1])
        mjccd.first_contact(a, motions[0], b, motions[1])
        t0 = time.perf_counter()
        mjccd.first_contact(a, motions[0], b, motions[1])
        times.append(time.perf_counter() - t0)
        rational += solve_motions(a, motions[0], b, motions[1], first_only=True).precision == RATIONAL
        start = np.array([np.r_[p[0], r[0]] for p, r in poses])
        end = np.array([np.r_[p[1], r[1]] for p, r in poses])
        kernel += Scene(radii).step(start, end, resolve_uncertain=False).certainty == "uncertain"
        uncertain += Scene(radii).step(start, end).certainty == "uncertain"
    n = len(queries)
    return (1e6 * statistics.median(times), 1e6 * statistics.mean(times), 1e3 * max(times), rational / n,
            kernel / n, uncertain / n)


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--pairs", type=int, default=200)
    parser.add_argument("--seed", type=int, default=9)
    args = parser.parse_args(argv)
    print("| thin body | aspect | median µs | mean µs | max ms | rational tier | Scene kernel uncertain "
          "| Scene uncertain |")
    print("| --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: |")
    for aspect in (20, 100):
        for thin, name in ((0, "first"), (1, "second")):
            median, mean, worst, rational, kernel, uncertain = measure(aspect, thin, args.pairs, args.seed)
            print(f"| {name} | {aspect}:1 | {median:.1f} | {mean:.1f} | {worst:.1f} | {100 * rational:.0f} % "
                  f"| {100 * kernel:.0f} % | {100 * uncertain:.0f} % |", flush=True)


if __name__ == "__main__":
    main()
