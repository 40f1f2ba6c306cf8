"""Peak memory of ccd.search_exit run to its limit on a degree-96 F.

Usage: python benchmarks/exit_memory.py [--depth 5e-12] [--old REV]

The pair: a sphere (radius 0.3) on a link behind six hinges about z, circling a fixed sphere
(radius 0.5) at a constant distance 0.8 - depth, so the two overlap by ``depth`` for the whole
step.  F has degree 96 in t; the certified march stalls at once and the box search cannot
certify the overlap before MAX_BOXES pops, so search_exit stops at its limit (certified=False).

Everything is compiled and run once on a small case first, so the growth of the peak resident
set (resource.getrusage ru_maxrss) across the measured call is the search's own memory.  With
``--old REV`` the same is measured, in a fresh process, for the search_exit of that git revision
(e.g. da73734, whose search keeps every box in a typed List).
"""
import argparse
import importlib.util
import os
import pathlib
import resource
import subprocess
import sys
import tempfile
import time

ROOT = pathlib.Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

import mjccd  # noqa: E402
from mjccd import ccd  # noqa: E402

ID = [1.0, 0.0, 0.0, 0.0]
TARGET_MB = 50.0


def ring(depth, lift=None):
    a, b = mjccd.Ellipsoid([0.3] * 3), mjccd.Ellipsoid([0.5] * 3)
    chain = mjccd.Chain([mjccd.Hinge([0, 0, 1], -0.4, 0.4) for _ in range(6)] + [mjccd.Fixed([0.8 - depth, 0, 0])])
    mb = mjccd.Static([0, 0, 0]) if lift is None else mjccd.Rigid([0, 0, 0], ID, [0, 0, lift], ID)
    F, Fabs, _, _ = ccd.prepare_pair(*chain.quadric(a.radii), *mb.quadric(b.radii), 0.5)
    return F, Fabs


def peak_mb():
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0  # kB on Linux


def old_search_exit(rev):
    """search_exit of git revision ``rev``, from its ccd.py loaded as a separate module."""
    source = subprocess.run(["git", "show", f"{rev}:mjccd/ccd.py"], cwd=ROOT, check=True,
                            capture_output=True, text=True).stdout
    path = pathlib.Path(tempfile.mkdtemp()) / "ccd_old.py"
    path.write_text(source)
    spec = importlib.util.spec_from_file_location("ccd_old", path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module.search_exit


def measure(search, depth):
    warm_F, warm_Fabs = ring(1e-9, lift=2e-4)  # compiles everything on a short search
    search(warm_F, warm_Fabs, ccd.NOISE, 0.0, 1.0)
    F, Fabs = ring(depth)
    assert ccd.status_at(F, Fabs, ccd.NOISE, 0.0)[0] == -1, "the pair must overlap at t = 0"
    before = peak_mb()
    start = time.perf_counter()
    result = search(F, Fabs, ccd.NOISE, 0.0, 1.0)
    seconds = time.perf_counter() - start
    after = peak_mb()
    return F.shape[1] - 1, result, seconds, before, after


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--depth", type=float, default=5e-12, help="constant penetration of the pair")
    parser.add_argument("--old", metavar="REV", help="also measure the search_exit of this git revision")
    parser.add_argument("--only-old", metavar="REV", help=argparse.SUPPRESS)  # the child process of --old
    args = parser.parse_args()
    if args.only_old:
        search, label = old_search_exit(args.only_old), f"search_exit at {args.only_old}"
    else:
        search, label = ccd.search_exit, "search_exit (pool)"
    degree, result, seconds, before, after = measure(search, args.depth)
    print(f"{label}: degree {degree}, depth {args.depth:g}, result {result}, {seconds:.2f} s")
    print(f"  peak RSS before {before:.1f} MB, after {after:.1f} MB, growth {after - before:.1f} MB")
    if not args.only_old:
        rows, cols = 5, degree + 1
        cap = ccd._exit_capacity(rows, cols, ccd.MAX_BOXES)
        bound = (cap * rows * cols * 8 + 5 * cap * 8) / 2 ** 20
        print(f"  pool: {cap} slots of {rows}x{cols}, at most {bound:.1f} MB with heap and free list")
        ok = after - before < TARGET_MB
        print(f"  growth {'<' if ok else '>='} {TARGET_MB:.0f} MB target: {'ok' if ok else 'FAILED'}")
    if args.old:
        sys.stdout.flush()
        subprocess.run([sys.executable, __file__, "--depth", str(args.depth), "--only-old", args.old], check=True)
    if not args.only_old and not ok:
        sys.exit(1)


if __name__ == "__main__":
    main()
