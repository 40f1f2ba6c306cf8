"""The two-pose solver's kernel on close rigid pairs, timed so that two checkouts can be compared on a busy machine.

The pairs of ``mjccd bench core`` (200 with meeting bounding spheres, turning up to 0.5 rad, and 200
translation-only ones).  Each query is called 9 times and its fastest call kept; the line gives the
median over the queries, in µs of the thread's CPU time (``time.thread_time``), which time another
tenant takes from a shared core does not count into.  Four figures: the fused first-contact kernel
(``rigid_first_contact``, plain arrays) and ``collision_intervals`` on built objects (every interval:
the all-intervals kernel that ``solve_cases`` runs too, plus the Python layer), for each set.

Compare two checkouts by alternating runs, e.g.::

    for i in 1 2 3 4; do PYTHONPATH=../before python benchmarks/kernel_timing.py before; \
                         python benchmarks/kernel_timing.py after; done
"""
import statistics
import sys
import time

import mjccd
from mjccd.bench import peers
from mjccd.bench.core import built_pair, fused_arguments, spheres_meet
from mjccd.ccd import rigid_first_contact

CALLS = 9
QUERIES = 200


def fastest_median(items, fn):
    """Median over ``items`` of the fastest of CALLS calls of ``fn(item)``, in µs of thread CPU time."""
    fn(items[0])
    best = []
    for item in items:
        fastest = float("inf")
        for _ in range(CALLS):
            t0 = time.thread_time()
            fn(item)
            fastest = min(fastest, time.thread_time() - t0)
        best.append(1e6 * fastest)
    return statistics.median(best)


def main(label):
    figures = []
    for name, angle, seed in (("rotating", 0.5, 0), ("translation", 0.0, 1)):
        queries = [q for q in peers.random_rigid_queries(3 * QUERIES, seed=seed, max_angle=angle)
                   if spheres_meet(q)][:QUERIES]
        figures.append((f"{name} first contact", fastest_median([fused_arguments(q) for q in queries],
                                                                lambda a: rigid_first_contact(*a))))
        figures.append((f"{name} collision_intervals", fastest_median([built_pair(q) for q in queries],
                                                                      lambda p: mjccd.collision_intervals(*p))))
    print(label, " ".join(f"{name}: {us:.2f}" for name, us in figures), flush=True)


if __name__ == "__main__":
    main(sys.argv[1] if len(sys.argv) > 1 else "mjccd")
