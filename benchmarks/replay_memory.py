"""Peak memory and speed of ``mjccd replay`` on long boxing trajectories.

Usage: python benchmarks/replay_memory.py [--frames 100000 1000000] [--compressed] [--mode MODE] [--old REV]
[--keep DIR]

The trajectory is the bundled ``data/boxing_traj.npz`` (1,199 frames of two CMU boxers)
played forwards, then backwards, again and again (no jump between the copies), cut to
``--frames`` frames at 120 Hz.  It is written into a temporary .npz piece by piece (stored
members, like ``numpy.savez``; ``--compressed``: deflated, like ``numpy.savez_compressed``), so
the benchmark itself stays small however long the trajectory is.

Each replay runs in a fresh process, ``python -m mjccd replay models/boxing.xml TRAJ --no-render
--rows 0 --out DIR`` (rigid motion; ``--mode``: replay's ``--mode``, geoms by default), after one short replay that compiles (or loads from numba's
cache) the kernels.  Its peak resident set is that child's ``ru_maxrss`` (``os.wait4``); wall
time covers the whole process (start, reading and checking the trajectory, the replay, the
reports); ``frames/s`` is the replay's own (kinematics and CCD, as its summary prints it).

``--old REV`` measures the ``mjccd`` package of that git revision the same way (extracted with
git archive into a temporary folder), for a before/after comparison.  The target: a
1,000,000-frame replay within :data:`TARGET_MB`.
"""
import argparse
import os
import pathlib
import re
import subprocess
import sys
import tarfile
import tempfile
import time
import zipfile

import numpy as np

ROOT = pathlib.Path(__file__).resolve().parent.parent
MODEL = ROOT / "models" / "boxing.xml"
TRAJ = ROOT / "data" / "boxing_traj.npz"
RATE = 120.0           # frames per second of the written trajectory
TARGET_MB = 400.0      # peak RSS allowed for 1,000,000 frames
WRITE_ROWS = 8192      # rows written at a time


def write_tiled(path, frames, compressed=False, source=TRAJ):
    """A .npz of ``frames`` frames: ``source``'s qpos forwards, backwards, forwards, ...; time at :data:`RATE`.

    Written member by member and row block by row block, so memory stays small for any ``frames``.
    """
    with np.load(source) as data:
        clip = np.ascontiguousarray(data["qpos"], dtype=np.float64)
    period = np.concatenate([clip, clip[::-1]])
    kind = zipfile.ZIP_DEFLATED if compressed else zipfile.ZIP_STORED
    with zipfile.ZipFile(path, "w", compression=kind, allowZip64=True) as zf:
        with zf.open("qpos.npy", "w", force_zip64=True) as fh:
            np.lib.format.write_array_header_1_0(
                fh, {"descr": "<f8", "fortran_order": False, "shape": (frames, clip.shape[1])})
            for start in range(0, frames, WRITE_ROWS):
                rows = np.arange(start, min(start + WRITE_ROWS, frames)) % len(period)
                fh.write(period[rows].tobytes())
        with zf.open("time.npy", "w", force_zip64=True) as fh:
            np.lib.format.write_array_header_1_0(fh, {"descr": "<f8", "fortran_order": False, "shape": (frames,)})
            for start in range(0, frames, WRITE_ROWS):
                fh.write((np.arange(start, min(start + WRITE_ROWS, frames)) / RATE).tobytes())
    return path


def run_replay(traj, out, package_root, mode=None):
    """Replay ``traj`` in a child process; (peak RSS in MB, wall seconds, frames/s, first contacts, stdout)."""
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(p for p in (str(package_root), os.environ.get("PYTHONPATH"))
                                                     if p))
    command = [sys.executable, "-m", "mjccd", "replay", str(MODEL), str(traj), "--no-render", "--rows", "0",
               "--out", str(out), "--force", *(["--mode", mode] if mode else [])]
    start = time.perf_counter()
    with tempfile.TemporaryFile("w+") as log:
        proc = subprocess.Popen(command, stdout=log, stderr=subprocess.DEVNULL, env=env, cwd=package_root)
        _, status, usage = os.wait4(proc.pid, 0)
        proc.returncode = os.waitstatus_to_exitcode(status)
        wall = time.perf_counter() - start
        log.seek(0)
        text = log.read()
    if proc.returncode != 0:
        raise SystemExit(f"replay of {traj} failed with exit status {proc.returncode}:\n{text}")
    rate = re.search(r"([0-9]+) frames/s", text)
    contacts = re.search(r"first contacts: ([0-9]+)", text)
    return (usage.ru_maxrss / 1024.0, wall, float(rate.group(1)) if rate else float("nan"),
            int(contacts.group(1)) if contacts else -1, text)


def measure(label, package_root, frames_list, folder, compressed, mode=None):
    """Rows of the table for one mjccd package (a warm-up replay first)."""
    warm = write_tiled(folder / "warm.npz", 300, compressed)
    run_replay(warm, folder / "out", package_root, mode)
    rows = []
    for frames in frames_list:
        traj = write_tiled(folder / f"tiled_{frames}.npz", frames, compressed)
        size_mb = traj.stat().st_size / 2 ** 20
        rss, wall, rate, contacts, _ = run_replay(traj, folder / "out", package_root, mode)
        traj.unlink()
        rows.append((label, "deflated" if compressed else "stored", frames, size_mb, rss, wall, rate, frames / wall,
                     contacts))
        print(f"{label}: {frames} frames ({size_mb:.0f} MB file): peak RSS {rss:.0f} MB, wall {wall:.1f} s, "
              f"replay {rate:.0f} frames/s, overall {frames / wall:.0f} frames/s, {contacts} first contacts",
              flush=True)
    return rows


def extract(rev, folder):
    """The mjccd package of git revision ``rev`` under ``folder`` (returned: the folder to put on PYTHONPATH)."""
    folder.mkdir(parents=True, exist_ok=True)
    archive = folder / "mjccd.tar"
    subprocess.run(["git", "archive", "--format=tar", "-o", str(archive), rev, "mjccd"], cwd=ROOT, check=True)
    with tarfile.open(archive) as tar:
        tar.extractall(folder)
    archive.unlink()
    return folder


def markdown(rows):
    lines = ["| package | members | frames | file [MB] | peak RSS [MB] | wall [s] | replay frames/s | "
             "overall frames/s | first contacts |", "|---|---|---:|---:|---:|---:|---:|---:|---:|"]
    for label, members, frames, size, rss, wall, rate, overall, contacts in rows:
        lines.append(f"| {label} | {members} | {frames:,} | {size:.0f} | {rss:.0f} | {wall:.1f} | {rate:.0f} | "
                     f"{overall:.0f} | {contacts:,} |")
    return "\n".join(lines)


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--frames", type=int, nargs="+", default=[100_000, 1_000_000],
                        help="trajectory lengths to replay (default 100000 1000000)")
    parser.add_argument("--compressed", action="store_true", help="write deflated members (savez_compressed)")
    parser.add_argument("--mode", choices=("geoms", "ellipsoids"), help="replay's --mode (default: its default)")
    parser.add_argument("--old", metavar="REV", help="also measure the mjccd package of this git revision")
    parser.add_argument("--keep", metavar="DIR", help="work in this folder (kept) instead of a temporary one")
    args = parser.parse_args(argv)
    if any(f < 2 for f in args.frames):
        parser.error("--frames: every length must be at least 2")
    with tempfile.TemporaryDirectory() as tmp:
        folder = pathlib.Path(args.keep or tmp)
        folder.mkdir(parents=True, exist_ok=True)
        rows = []
        if args.old:
            old_root = extract(args.old, folder / "old")
            rows += measure(f"`{args.old}`", old_root, args.frames, folder, args.compressed, args.mode)
        rows += measure("this tree", ROOT, args.frames, folder, args.compressed, args.mode)
    print()
    print(markdown(rows))
    current = [r for r in rows if r[0] == "this tree" and r[2] >= 1_000_000]
    if current and max(r[4] for r in current) > TARGET_MB:
        print(f"peak RSS above the {TARGET_MB:.0f} MB target for 1,000,000 frames", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
