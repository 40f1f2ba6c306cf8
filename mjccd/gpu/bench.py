"""Timing of the GPU path on the boxing workload: pair-frames per second of the full check and of the filters alone.

W worlds each replay the boxing frames (two characters of 21 ellipsoids, 441 pairs) from their own
starting frame, one frame per call, each with its own plane cache, as W environments stepping together
would.  The poses are staged on the device first; a call is timed from its launch to the end of the
device work (``cuda.synchronize``), so the figures are the device's, launch overhead included, without
host copies.  ``filters`` times the pose split and the filters only (spheres, cached and new
separating planes), ``full`` the filters, the exact solve of what they leave and the per-world
reduction, with the answers left on the device (``resolve_uncertain=False``).  Needs numpy, numba
and numba-cuda, not MuJoCo: the poses come from a file (``benchmarks/gpu/boxing_poses.npz``, written
by ``benchmarks/gpu/make_poses.py``).

    python -m mjccd.gpu.bench [--poses FILE] [--worlds 256,1024,4096] [--steps 20] [--check 64] [--json OUT]
"""
import argparse
import json
import statistics
import time

import numpy as np
from numba import cuda

from mjccd.gpu import kernels as kn
from mjccd.gpu.scene import GpuScene
from mjccd._command import PlainHelpFormatter

DEFAULT_POSES = "benchmarks/gpu/boxing_poses.npz"


def load_workload(path):
    """(poses (F + 1, N, 7), radii (N, 3), pairs (P, 2)) from a file written by ``benchmarks/gpu/make_poses.py``."""
    with np.load(path) as data:
        return data["poses"], data["radii"], data["pairs"]


def frame_batches(poses, worlds, steps):
    """(t0, t1) pose batches (W, N, 7) of ``steps`` calls: world w at call s checks frame (7 w + s) mod F."""
    frames = len(poses) - 1
    start = (7 * np.arange(worlds)) % frames
    return [(poses[(start + s) % frames], poses[(start + s) % frames + 1]) for s in range(steps)]


def _timed(run, batches):
    """Seconds of each call (launch to device idle), after one untimed call (compiles, fills the plane cache)."""
    run(*batches[0])
    cuda.synchronize()
    out = []
    for t0, t1 in batches:
        start = time.perf_counter()
        run(t0, t1)
        cuda.synchronize()
        out.append(time.perf_counter() - start)
    return out


def bench_gpu(poses, radii, pairs, worlds=(256, 1024, 4096), steps=20):
    """One row per batch size: median seconds per call and pair-frames per second of the full check and of
    the filters alone, with the mean number of pairs left to the exact solver and of uncertain worlds."""
    rows = []
    npairs = len(pairs)
    for w in worlds:
        batches = [(cuda.to_device(t0), cuda.to_device(t1)) for t0, t1 in frame_batches(poses, w, steps + 1)]
        scene = GpuScene(radii, w, pairs=pairs)
        filt = _timed(scene.filter_frame, batches)
        scene.reset_cache()
        times = _timed(lambda t0, t1: scene.first_contacts(t0, t1, resolve_uncertain=False), batches)
        rows.append({"worlds": w, "pairs": npairs, "steps": steps,
                     "full_s": statistics.median(times), "filters_s": statistics.median(filt),
                     "full_pair_frames_per_s": w * npairs / statistics.median(times),
                     "filters_pair_frames_per_s": w * npairs / statistics.median(filt)})
        rows[-1].update(_counts(scene, batches))
    return rows


def _counts(scene, batches):
    """Mean per call of the pairs the exact kernel solved and of the worlds left uncertain (one more pass)."""
    exact, uncertain, contact = [], [], []
    scene.reset_cache()
    for t0, t1 in batches:
        out = scene.first_contacts(t0, t1, resolve_uncertain=False)
        exact.append(int(scene._count.copy_to_host()[0]))
        status = out.status.copy_to_host()
        uncertain.append(int((status == kn.POSSIBLE_CONTACT).sum()))
        contact.append(int((status == kn.CONTACT).sum()))
    return {"exact_pairs_per_call": statistics.mean(exact), "uncertain_worlds_per_call": statistics.mean(uncertain),
            "contact_worlds_per_call": statistics.mean(contact)}


def check_against_cpu(poses, radii, pairs, worlds, steps):
    """The first contacts of ``worlds`` worlds over ``steps`` calls against one CPU Scene per world:
    (worlds checked, mismatches (messages), uncertain answers, largest |dt|)."""
    from mjccd.scene import Scene

    scene = GpuScene(radii, worlds, pairs=pairs)
    cpu = [Scene(radii, pairs=pairs) for _ in range(worlds)]
    mismatches, uncertain, max_dt = [], 0, 0.0
    for s, (t0, t1) in enumerate(frame_batches(poses, worlds, steps)):
        got = scene.first_contacts(t0, t1).copy_to_host()
        for w in range(worlds):
            ref = cpu[w].first_contact(t0[w], t1[w])
            if ref is None:
                if got.pair[w] >= 0:
                    mismatches.append(f"call {s} world {w}: GPU pair {got.pair[w]} at {got.time[w]}, CPU none")
                continue
            if ref.bracket is not None or got.status[w] != kn.CONTACT:
                uncertain += 1
                continue
            dt = abs(float(got.time[w]) - ref.time)
            max_dt = max(max_dt, dt)
            if dt > 1e-12 or (got.pair[w] != ref.pair and got.time[w] != ref.time):
                mismatches.append(f"call {s} world {w}: GPU pair {got.pair[w]} at {got.time[w]!r}, "
                                  f"CPU pair {ref.pair} at {ref.time!r}")
    return {"worlds": worlds, "calls": steps, "mismatches": mismatches[:10], "n_mismatches": len(mismatches),
            "uncertain": uncertain, "max_dt": max_dt}


def main(argv=None):
    """Command line: time the batch sizes, optionally check worlds against the CPU scene, print and write JSON."""
    parser = argparse.ArgumentParser(formatter_class=PlainHelpFormatter,
                                     prog="python -m mjccd.gpu.bench", description=__doc__.split("\n")[0])
    parser.add_argument("--poses", default=DEFAULT_POSES, help="pose file (default: %(default)s)")
    parser.add_argument("--worlds", default="256,1024,4096", help="batch sizes W, comma-separated")
    parser.add_argument("--steps", type=int, default=20, help="timed calls per batch size")
    parser.add_argument("--check", type=int, default=0, help="also check this many worlds against the CPU scene")
    parser.add_argument("--json", help="write the results here")
    args = parser.parse_args(argv)
    poses, radii, pairs = load_workload(args.poses)
    name = getattr(cuda.get_current_device(), "name", "CUDA simulator")
    name = name.decode() if isinstance(name, bytes) else str(name)
    result = {"device": name, "poses": args.poses, "frames": len(poses) - 1, "ellipsoids": len(radii),
              "rows": bench_gpu(poses, radii, pairs, [int(w) for w in args.worlds.split(",")], args.steps)}
    print(f"{name}: {len(radii)} ellipsoids, {len(pairs)} pairs, {len(poses) - 1} frames; median of {args.steps} calls")
    print(f"{'worlds':>7} {'full ms':>9} {'pair-frames/s':>14} {'filters ms':>11} {'pair-frames/s':>14} "
          f"{'exact/call':>10} {'uncertain/call':>14}")
    for r in result["rows"]:
        print(f"{r['worlds']:>7} {1e3 * r['full_s']:>9.3f} {r['full_pair_frames_per_s']:>14.3e} "
              f"{1e3 * r['filters_s']:>11.3f} {r['filters_pair_frames_per_s']:>14.3e} "
              f"{r['exact_pairs_per_call']:>10.1f} {r['uncertain_worlds_per_call']:>14.2f}")
    if args.check:
        result["check"] = check_against_cpu(poses, radii, pairs, args.check, 3)
        c = result["check"]
        print(f"check against the CPU scene: {c['worlds']} worlds x {c['calls']} calls, {c['n_mismatches']} "
              f"mismatches, {c['uncertain']} uncertain, largest |dt| {c['max_dt']:.2e}")
    if args.json:
        with open(args.json, "w") as f:
            json.dump(result, f, indent=1)
    return result


if __name__ == "__main__":
    main()
