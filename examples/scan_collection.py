"""Scan a small motion collection and show which clips to look at first.

    python examples/scan_collection.py [OUT_DIR] [--clips N] [--workers W]

Tiles the two bundled CMU boxing clips into N clips of 240 frames (two of them jump to the T-pose for one frame,
one file is damaged), scans them with ``mjccd.scan`` on W local processes, prints the flagged and failed clips
and the earliest self contacts, and plots the first contacts per clip into OUT_DIR/contacts_per_clip.png.
Run it again with the same OUT_DIR: every clip is already in the tables, so nothing is scanned twice.
"""
import argparse
import pathlib
import tempfile

import matplotlib
import pyarrow.compute as pc

import mjccd
from mjccd.bench.collection import tile_collection

matplotlib.use("Agg")  # a file, no window
import matplotlib.pyplot as plt  # noqa: E402


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("out", nargs="?", help="where the clips, the tables and the plot go (default: a new "
                                                "temporary folder)")
    parser.add_argument("--clips", type=int, default=12)
    parser.add_argument("--workers", type=int, default=2)
    args = parser.parse_args(argv)
    out = pathlib.Path(args.out or tempfile.mkdtemp(prefix="mjccd-scan-"))
    clips_dir = out / "clips"
    if not clips_dir.exists():
        tile_collection(clips_dir, args.clips - 3, 240, jumps=2, damaged=1, seed=1)
    contacts, clips = mjccd.scan([clips_dir], out / "scan", workers=args.workers)
    rows = clips.to_pylist()
    print(f"{len(rows)} clips in {out / 'scan'}")
    for row in rows:
        name = pathlib.Path(row["clip"]).name
        if row["error"]:
            print(f"  {name}: could not be scanned: {row['error']}")
        elif row["flags"]:
            print(f"  {name}: {', '.join(row['flags'])} (longest self contact {row['longest_overlap_s']:.3f} s, "
                  f"largest turn {row['max_joint_turn_deg']:.0f} deg in a frame)")
    self_first = contacts.filter(pc.and_(pc.equal(contacts["kind"], "first"), pc.invert(contacts["floor"])))
    earliest = self_first.sort_by([("time", "ascending")]).slice(0, 3).to_pylist()
    for c in earliest:
        print(f"  self contact at t = {c['time']:.4f} s in {pathlib.Path(c['clip']).name}: {c['body_a']} / "
              f"{c['body_b']} at ({c['px']:+.3f}, {c['py']:+.3f}, {c['pz']:+.3f})")
    scanned = [r for r in rows if r["error"] is None]
    names = [pathlib.Path(r["clip"]).stem for r in scanned]
    fig, ax = plt.subplots(figsize=(8, 3.2))
    ax.bar(names, [r["floor_contacts"] for r in scanned], label="floor")
    ax.bar(names, [r["self_contacts"] for r in scanned], bottom=[r["floor_contacts"] for r in scanned],
           label="self")
    ax.set_ylabel("first contacts")
    ax.set_title("First contacts between frames, per clip (mjccd scan)")
    ax.tick_params(axis="x", labelrotation=60, labelsize=7)
    ax.legend()
    fig.tight_layout()
    fig.savefig(out / "contacts_per_clip.png", dpi=120)
    plt.close(fig)
    print(f"plot: {out / 'contacts_per_clip.png'}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
