"""``mjccd bench scan``: ``mjccd scan`` over a tiled collection of the bundled CMU clips, and what a per-frame check
misses on the same clips.

*Throughput.*  The collection (:mod:`mjccd.bench.collection`: ``--clips`` clips of ``--frames`` frames, windows
of the two bundled boxing clips played forwards and backwards) is scanned into a fresh folder with one local
worker (in this process), with ``--workers`` local processes, and with Ray on a local Ray of as many CPUs
(when Ray imports).  Each is timed from the call to the tables read back, worker start-up included; clips per
second and frames per second, the median of ``--repeats`` runs.

*What a per-frame check misses.*  On the first ``--miss-clips`` clips, every contact the scan reports (geoms
mode: the skeleton's capsules against each other and the floor) is looked for by a discrete test of the same
geoms: MuJoCo's ``mj_geomDistance`` <= 0 at a frame, on every frame, then on every 3rd frame (as ProtoMotions'
subsampled filter).  A first contact counts as seen when some checked frame of its run of contact (the frames
from the run's first interval to the frame after its last) shows the two geoms touching or overlapping; a
run (a stretch of frame intervals a pair spends in contact: a penetration when it lasts past a frame) likewise.
Pairs of the skeleton that touch in its rest pose (the hips' capsules) overlap by construction and are left out,
as the scan's flags leave them out.
As a check of the continuous answers themselves, every checked pair is also tested on every frame of those
clips: a pair the discrete test finds overlapping at a frame that no run covers would be a contact the scan
missed.
"""
import argparse
import os
import platform
import statistics
import sys
import tempfile
import time
import warnings

import mujoco
import numpy as np

from mjccd.bench import options
from mjccd.bench.collection import collection_frames, tile_collection
from mjccd.bench.report import write_section
from mjccd.collection import scan
from mjccd.collection.checks import RestPose, ScanOptions, replayed
from mjccd.collection.clips import ClipTask
from mjccd.mujoco.warnings import CoverageWarning
from mjccd.mujoco.ellipsoids import geom_id
from mjccd._command import PlainHelpFormatter

QUICK = {"clips": 8, "frames": 240, "repeats": 1, "miss_clips": 4}
RANGES = {"clips": (1, 100000), "frames": (2, 10 ** 7), "repeats": (1, 100), "workers": (1, 4096),
          "miss_clips": (0, 100000)}


def time_engine(folder, runs, **kwargs):
    """Seconds of each of ``runs`` scans of ``folder`` into a fresh output folder, and the tables of the last."""
    seconds, tables = [], None
    for _ in range(runs):
        with tempfile.TemporaryDirectory() as out:
            start = time.perf_counter()
            tables = scan([folder], os.path.join(out, "scan"), progress=False, **kwargs)
            seconds.append(time.perf_counter() - start)
    return seconds, tables


def miss_counts(path):
    """The per-frame check against the scan's continuous answer on one clip (module docstring): counts by kind."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", CoverageWarning)
        model, trajectory, result = replayed(ClipTask(path, "bvh", ""), ScanOptions())
    qpos = trajectory.qpos()
    data = mujoco.MjData(model)
    fromto = np.zeros(6)
    pairs = [tuple(geom_id(model, name) for name in result.names(p)[0]) for p in range(len(result.pairs))]
    touching = np.zeros((len(qpos), len(pairs)), dtype=bool)  # every checked pair on every frame
    for k, q in enumerate(qpos):
        data.qpos[:] = q
        mujoco.mj_kinematics(model, data)
        for p, (a, b) in enumerate(pairs):
            touching[k, p] = mujoco.mj_geomDistance(model, data, a, b, 0.01, fromto) <= 0.0
    counts = dict.fromkeys(("contacts", "contacts_every", "contacts_third", "runs", "runs_every", "runs_third",
                            "discrete_only"), 0)
    covered = np.zeros_like(touching)
    contact_pairs = {}
    for c in result.contacts:
        contact_pairs.setdefault(tuple(c["geoms"]), []).append(c["frame"])
    rest = RestPose(model)
    for p, runs in result.pair_runs():
        names = tuple(result.names(p)[0])
        structural = not result.on_plane(p) and rest.overlapping(*names)
        for _, first, last, _, _ in runs.tolist():
            frames = np.arange(first, last + 2)
            covered[frames, p] = True
            if structural:
                continue  # overlapping by construction (the hips' capsules), as the scan's flags leave them out
            seen_every = bool(touching[frames, p].any())
            seen_third = bool(touching[frames[frames % 3 == 0], p].any())
            n = sum(first <= f <= last for f in contact_pairs.get(names, ()))
            kind = "floor" if result.on_plane(p) else "self"
            for key, value in (("runs", 1), ("contacts", n)):
                counts[key] += value
                counts[f"{key}_every"] += value * seen_every
                counts[f"{key}_third"] += value * seen_third
            counts[f"{kind}_runs"] = counts.get(f"{kind}_runs", 0) + 1
    counts["discrete_only"] = int(np.count_nonzero(touching & ~covered))
    counts["frames"] = len(qpos)
    return counts


def markdown(rows, miss, args, command, seconds, load, frames):
    lines = ["## Motion collections (`mjccd bench scan`)", "",
             f"Command: `{command}` ({seconds:.0f} s)  ",
             f"Machine: {platform.machine()}, {os.cpu_count()} cores, Python {platform.python_version()}; load "
             f"average {load[0]:.1f} at the start, {load[1]:.1f} at the end", "",
             f"Collection: {args.clips} tiled clips of {args.frames} frames ({frames} frames, 120 per second) "
             "from the two bundled CMU boxing clips (`mjccd.bench.collection`), each imported to its own "
             "skeleton; geoms mode (the skeleton's capsules, self pairs and the floor), rigid motion. Times from "
             f"the call of `mjccd.scan` to its tables, worker start-up included; median of {args.repeats}.", "",
             "| engine | workers | seconds | clips/s | frames/s | against 1 worker |",
             "| --- | ---: | ---: | ---: | ---: | ---: |"]
    base = rows[0][2]
    for engine, workers, secs in rows:
        lines.append(f"| {engine} | {workers} | {secs:.1f} | {args.clips / secs:.1f} | {frames / secs:.0f} | "
                     f"{base / secs:.2f}× |")
    if miss is not None:
        c = miss
        lines += ["", f"What a per-frame check misses, on the first {args.miss_clips} clips ({c['frames']} frames): "
                      "the scan's continuous answers looked for by MuJoCo's `mj_geomDistance` on the same geoms "
                      "(module docstring of `mjccd.bench.scan`).", "",
                  "| | continuous (mjccd) | seen per frame | seen every 3rd frame | only continuous, per frame "
                  "| only continuous, every 3rd |", "| --- | ---: | ---: | ---: | ---: | ---: |"]
        for key, label in (("contacts", "first contacts"), ("runs", "runs of contact (penetrations)")):
            lines.append(f"| {label} | {c[key]} | {c[key + '_every']} | {c[key + '_third']} | "
                         f"{c[key] - c[key + '_every']} | {c[key] - c[key + '_third']} |")
        lines += ["", f"Runs: {c.get('self_runs', 0)} between the skeleton's own bodies, {c.get('floor_runs', 0)} "
                      f"against the floor. Frames where a checked pair overlaps that no continuous run covers "
                      f"(a contact the scan would have missed): {c['discrete_only']}."]
    return "\n".join(lines) + "\n"


def main(argv=None):
    parser = argparse.ArgumentParser(formatter_class=PlainHelpFormatter, prog="mjccd bench scan",
                                     description=__doc__.splitlines()[0])
    parser.add_argument("--clips", type=int, default=200, help="clips in the collection (default 200)")
    parser.add_argument("--frames", type=int, default=1200, help="frames per clip (default 1200)")
    parser.add_argument("--workers", type=int, default=2, help="local processes and Ray CPUs (default 2)")
    parser.add_argument("--repeats", type=int, default=3, help="timed runs of each engine (default 3)")
    parser.add_argument("--miss-clips", type=int, default=20,
                        help="clips of the per-frame comparison (default 20; 0 leaves it out)")
    parser.add_argument("--no-ray", action="store_true", help="leave Ray out")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--markdown", metavar="FILE", help="write the tables into this markdown file")
    args = options.parse_checked(parser, argv, QUICK, RANGES)
    begin, load = time.perf_counter(), [options.load_average()]
    with tempfile.TemporaryDirectory() as work:
        folder = os.path.join(work, "clips")
        paths = tile_collection(folder, args.clips, args.frames, seed=args.seed)
        frames = collection_frames(paths)
        scan([paths[0]], os.path.join(work, "warm"), workers=1, progress=False)  # compile or load the kernels
        plans = [("this process", 1, {"workers": 1}), ("process pool", args.workers, {"workers": args.workers})]
        try:
            import ray  # noqa: F401
        except ImportError:
            args.no_ray = True
        if not args.no_ray:
            plans.append(("Ray, local", args.workers, {"workers": args.workers, "engine": "ray"}))
        rows, reference = [], None
        for name, workers, kwargs in plans:
            print(f"scanning with {name} ({workers} workers)", file=sys.stderr)
            secs, tables = time_engine(folder, args.repeats, **kwargs)
            if reference is None:
                reference = tables
            elif not (tables[0].equals(reference[0]) and tables[1].equals(reference[1])):
                raise SystemExit(f"mjccd bench scan: {name} gave other tables than one worker")
            rows.append((name, workers, statistics.median(secs)))
        miss = None
        if args.miss_clips:
            print(f"per-frame check on {min(args.miss_clips, len(paths))} clips", file=sys.stderr)
            miss = {}
            for path in paths[:args.miss_clips]:
                for key, value in miss_counts(path).items():
                    miss[key] = miss.get(key, 0) + value
    load.append(options.load_average())
    command = "mjccd bench scan" + ("" if argv is None else " " + " ".join(argv))
    text = markdown(rows, miss, args, command, time.perf_counter() - begin, load, frames)
    print(text)
    if args.markdown:
        write_section(args.markdown, "scan", text)
        print(f"written to {args.markdown}")
    return 0
