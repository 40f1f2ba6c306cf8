"""``mjccd scan``: the command line of :func:`mjccd.collection.scan`."""
import argparse
import sys

from mjccd.collection.checks import ScanOptions
from mjccd.collection.engines import ENGINES
from mjccd.collection.run import ScanReport, scan
from mjccd.collection.tables import CLIPS, CONTACTS
from mjccd.errors import MjccdError
from mjccd.replay import MOTIONS, PLANE_RULES
from mjccd._command import PlainHelpFormatter, whole_number

DEFAULTS = ScanOptions()


def _amount(text):
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number >= 0, got {text!r}") from None
    if not value >= 0 or value == float("inf"):
        raise argparse.ArgumentTypeError(f"expected a finite number >= 0, got {text!r}")
    return value


def build_parser():
    parser = argparse.ArgumentParser(
        prog="mjccd scan", formatter_class=PlainHelpFormatter,
        description="Replay every clip of a collection with exact CCD and write two Parquet datasets into OUT: "
                    f"{CONTACTS} (every first contact between frames, and the contacts already under way when "
                    f"a run of contact begins) and {CLIPS} (one row per clip: counts, the flags "
                    "self_penetration, below_floor and jump, and the error of a clip that could not be scanned). "
                    "A second run into OUT scans only the clips not yet there.")
    parser.add_argument("sources", nargs="+", help="folders, glob patterns (quoted) or files of .bvh or .npz clips")
    parser.add_argument("-o", "--out", required=True, help="the scan's folder (made if missing; resumed if it "
                                                           "holds a scan with the same settings)")
    parser.add_argument("--model", help="MJCF model the .npz qpos clips move (BVH clips each get their own "
                                        "skeleton, as mjccd import-bvh builds it)")
    parser.add_argument("--workers", type=whole_number(1, "workers"),
                        help="processes or Ray CPUs (default: every core)")
    parser.add_argument("--engine", choices=ENGINES, default="pool",
                        help="'pool': local processes (the default); 'ray': Ray tasks (pip install 'mjccd[ray]')")
    parser.add_argument("--address", help="the Ray cluster to run on (ray://HEAD:10001 or HEAD:6379); default: "
                                          "a local Ray of --workers CPUs")
    parser.add_argument("--batch", type=whole_number(1, "clips"),
                        help="clips per part of the tables (default: about four batches per worker, at most 16 clips)")
    parser.add_argument("--motion", choices=MOTIONS, default=DEFAULTS.motion, help="motion between frames")
    parser.add_argument("--mode", choices=("geoms", "ellipsoids"),
                        help="what touches: the model's own geoms (the default with --motion rigid) or its "
                             "bounding ellipsoids")
    parser.add_argument("--planes", choices=PLANE_RULES, default=DEFAULTS.planes,
                        help="static planes to check (as mjccd replay)")
    parser.add_argument("--self-overlap", type=_amount, default=DEFAULTS.self_overlap_s, metavar="SECONDS",
                        help=f"self_penetration: two bodies in contact this long (default {DEFAULTS.self_overlap_s:g} "
                             "s; pairs touching in the rest pose do not count)")
    parser.add_argument("--floor-depth", type=_amount, default=DEFAULTS.floor_depth_m, metavar="METRES",
                        help=f"below_floor: a geom this far below a static plane (default "
                             f"{DEFAULTS.floor_depth_m:g} m)")
    parser.add_argument("--jump-angle", type=_amount, default=DEFAULTS.jump_deg, metavar="DEGREES",
                        help=f"jump: a joint turning more than this in one frame (default {DEFAULTS.jump_deg:g})")
    parser.add_argument("--bvh-scale", type=_amount, default=DEFAULTS.bvh_scale, metavar="METRES",
                        help="metres per BVH file unit (default: CMU's)")
    return parser


def main(argv=None):
    """``mjccd scan SOURCES... -o OUT``; returns the exit status."""
    args = build_parser().parse_args(argv)
    report = ScanReport()
    try:
        contacts, clips = scan(args.sources, args.out, model=args.model, workers=args.workers, engine=args.engine,
                               address=args.address, batch=args.batch, report=report, motion=args.motion,
                               mode=args.mode, planes=args.planes, self_overlap_s=args.self_overlap,
                               floor_depth_m=args.floor_depth, jump_deg=args.jump_angle, bvh_scale=args.bvh_scale)
    except (MjccdError, ValueError) as exc:
        print(f"mjccd scan: {' '.join(str(exc).split())}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print(f"mjccd scan: interrupted after {report.scanned} clips; run the same command again to scan the rest",
              file=sys.stderr)
        return 130
    print(summary(report, contacts, clips, args.out))
    return 0


def summary(report, contacts, clips, out):
    """A few lines: clips found, scanned, skipped; contacts; flags; errors; where the tables are."""
    flags = {}
    for row in clips.column("flags").to_pylist():
        for flag in row or ():
            flags[flag] = flags.get(flag, 0) + 1
    kinds = contacts.column("kind").to_pylist()
    floor = contacts.column("floor").to_pylist()
    first = sum(k == "first" for k in kinds)
    first_floor = sum(k == "first" and f for k, f in zip(kinds, floor))
    errors = sum(e is not None for e in clips.column("error").to_pylist())
    lines = [f"{report.found} clips found: {report.scanned} scanned now, {report.done_before} scanned before"
             + (f", {len(report.repeats)} repeating an earlier clip's bytes (left out)" if report.repeats else ""),
             f"{clips.num_rows} clips in the tables: {first} first contacts ({first - first_floor} self, "
             f"{first_floor} floor), {clips.num_rows - errors} scanned, {errors} failed",
             "flags: " + (", ".join(f"{k} {v}" for k, v in sorted(flags.items())) or "none"),
             f"wrote {out}/{CONTACTS}, {out}/{CLIPS}"]
    return "\n".join(lines)
