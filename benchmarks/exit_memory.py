"""Peak memory of ccd.search_exit run to its limit on a degree-96 F.

Usage: python benchmarks/exit_memory.py [--depth 5e-12] [--old REV]

The pair: a sphere (radius 0.3) on a link behind six hinges about z, circling a fixed sphere
(radius 0.5) at a constant distance 0.8 - depth, so the two overlap by ``depth`` for the whole
step.  F has degree 96 in t; the certified march stalls at once and the box search cannot
certify the overlap before MAX_BOXES pops, so search_exit stops at its limit (certified=False).
The search runs on F + E, E the tight bound of F's coefficient errors (error_bound_tight; with
the cheaper error_bound_global, F + E reaches zero at this depth and the search ends early with
a certified lower bound of the exit instead of running to its limit).

Everything is compiled and run once on a small case first, so the growth of the peak resident
set (resource.getrusage ru_maxrss) across the measured call is the search's own memory.  With
``--old REV`` the same is measured, in a fresh process, with the whole mjccd package of that git
revision (extracted with git archive); F is built with the API that revision has: the one of
(F, E) error bounds, or the older (F, Fabs, NOISE) one.  At revision da73734, whose search keeps
every box in a typed List, the growth was 748 MB (measured with this script before the pool).
"""
import argparse
import pathlib
import resource
import subprocess
import sys
import tarfile
import tempfile
import time

ROOT = pathlib.Path(__file__).resolve().parent.parent
ID = [1.0, 0.0, 0.0, 0.0]
TARGET_MB = 50.0


def ring(mjccd, ccd, depth, lift=None):
    """The pair as ``search()``, a call of that revision's search_exit over the step, and its status at t = 0."""
    import numpy as np

    a, b = mjccd.Ellipsoid([0.3] * 3), mjccd.Ellipsoid([0.5] * 3)
    chain = mjccd.Chain([mjccd.Hinge([0, 0, 1], -0.4, 0.4) for _ in range(6)] + [mjccd.Fixed([0.8 - depth, 0, 0])])
    mb = mjccd.Static([0, 0, 0]) if lift is None else mjccd.Rigid([0, 0, 0], ID, [0, 0, lift], ID)
    if hasattr(ccd, "NOISE"):  # the old API: decisions with |F| and a relative noise
        F, Fabs, _, _ = ccd.prepare_pair(*chain.quadric(a.radii), *mb.quadric(b.radii), 0.5)
        return (F, lambda: ccd.search_exit(F, Fabs, ccd.NOISE, 0.0, 1.0),
                ccd.status_at(F, Fabs, ccd.NOISE, 0.0)[0])
    pencil, err, _ = ccd.prepare_pair(*chain.quadric_bounded_on(a.radii, 0.0, 1.0),
                                      *mb.quadric_bounded_on(b.radii, 0.0, 1.0), 0.5)
    F, D, _ = ccd.balanced_F(*pencil, err)
    E = ccd.error_bound_tight(F, *pencil, D)
    return F, lambda: ccd.search_exit(F, E, 0.0, 1.0), ccd.status_at(F, E, 0.0)[0]


def peak_mb():
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0  # kB on Linux


def measure(mjccd, ccd, depth):
    _, warm, _ = ring(mjccd, ccd, 1e-9, lift=2e-4)  # compiles everything on a short search
    warm()
    F, search, status0 = ring(mjccd, ccd, depth)
    assert status0 == -1, "the pair must overlap at t = 0"
    before = peak_mb()
    start = time.perf_counter()
    result = search()
    seconds = time.perf_counter() - start
    after = peak_mb()
    return F.shape[1] - 1, result, seconds, before, after


def run_old(rev, depth):
    """Measure revision ``rev`` in a fresh process on its own copy of the package."""
    with tempfile.TemporaryDirectory() as tmp:
        archive = pathlib.Path(tmp) / "mjccd.tar"
        subprocess.run(["git", "archive", "--format=tar", "-o", str(archive), rev, "mjccd"], cwd=ROOT, check=True)
        with tarfile.open(archive) as tar:
            tar.extractall(tmp)
        subprocess.run([sys.executable, __file__, "--depth", str(depth), "--only-old", rev, "--root", tmp],
                       check=True)


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--depth", type=float, default=5e-12, help="constant penetration of the pair")
    parser.add_argument("--old", metavar="REV", help="also measure the search_exit of this git revision")
    parser.add_argument("--only-old", metavar="REV", help=argparse.SUPPRESS)  # the child process of --old
    parser.add_argument("--root", help=argparse.SUPPRESS)  # where the child finds that revision's package
    args = parser.parse_args()
    sys.path.insert(0, args.root or str(ROOT))
    import mjccd
    from mjccd import ccd

    if args.only_old:
        label = f"search_exit at {args.only_old}"
    else:
        label = "search_exit (pool)"
    degree, result, seconds, before, after = measure(mjccd, ccd, args.depth)
    print(f"{label}: degree {degree}, depth {args.depth:g}, result {result}, {seconds:.2f} s")
    print(f"  peak RSS before {before:.1f} MB, after {after:.1f} MB, growth {after - before:.1f} MB")
    ok = True
    if not args.only_old:
        rows, cols = 5, degree + 1
        cap = ccd._exit_capacity(rows, cols, ccd.MAX_BOXES)
        bound = (cap * rows * cols * 8 + 5 * cap * 8) / 2 ** 20
        print(f"  pool: {cap} slots of {rows}x{cols}, at most {bound:.1f} MB with heap and free list")
        ok = after - before < TARGET_MB
        print(f"  growth {'<' if ok else '>='} {TARGET_MB:.0f} MB target: {'ok' if ok else 'FAILED'}")
    if args.old:
        sys.stdout.flush()
        run_old(args.old, args.depth)
    if not ok:
        sys.exit(1)


if __name__ == "__main__":
    main()
