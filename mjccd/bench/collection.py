"""A synthetic motion collection from the bundled CMU boxing clips, for ``mjccd bench scan`` and the scan tests.

Each clip is a window of one of the bundled clips (``data/mocap``), its first frame (a T-pose) left out,
*tiled*: played forwards, then backwards, then forwards again ... until it has the frames asked for.  The turns
keep the motion continuous (no pose jumps), so a clean clip raises no ``jump`` flag.  On request the collection
also holds damaged files (cut short, a frame of the wrong length, a number that is not one, an empty file),
which a scan must report as rows with their error, and clips that *jump*: for one frame in the middle the
skeleton snaps to the source clip's T-pose and back.
"""
from pathlib import Path

import numpy as np

from mjccd import files
from mjccd.bench.options import REPOSITORY
from mjccd.errors import InputError

MOCAP = REPOSITORY / "data" / "mocap"  # found where mjccd runs from its source checkout
DAMAGES = ("cut_short", "short_frame", "not_a_number", "empty")


def source_clips(folder=MOCAP):
    """The bundled clips' ``(name, header, frames)``: the BVH text up to ``Frame Time:`` included, and the frame
    lines."""
    out = []
    for path in sorted(Path(folder).glob("*.bvh")):
        lines = path.read_text(encoding="utf-8").splitlines()
        at = next(i for i, line in enumerate(lines) if line.startswith("Frame Time:"))
        header = [line for line in lines[:at + 1] if not line.startswith("Frames:")]
        out.append((path.stem, header, [line for line in lines[at + 1:] if line.strip()]))
    return out


def _bvh_text(header, frames):
    motion = header.index("MOTION")
    return "\n".join(header[:motion + 1] + [f"Frames: {len(frames)}"] + header[motion + 1:] + frames) + "\n"


def _tiled(frames, start, window, length):
    """``length`` frame lines: ``frames[start:start + window]`` forwards, backwards, forwards ... (no repeated
    frame at a turn)."""
    piece = frames[start:start + window]
    out, backwards = list(piece), True
    while len(out) < length:
        out.extend(piece[-2::-1] if backwards else piece[1:])
        backwards = not backwards
    return out[:length]


def _damaged(kind, header, frames):
    if kind == "cut_short":
        return _bvh_text(header, frames)[:len("\n".join(header)) // 2]
    if kind == "short_frame":
        bad = list(frames)
        bad[len(bad) // 2] = " ".join(bad[len(bad) // 2].split()[:-3])
        return _bvh_text(header, bad)
    if kind == "not_a_number":
        bad = list(frames)
        values = bad[1].split()
        values[4] = "abc"
        bad[1] = " ".join(values)
        return _bvh_text(header, bad)
    return ""


def tile_collection(folder, clips, frames, *, damaged=0, jumps=0, seed=0, mocap=MOCAP):
    """Write ``clips`` clean clips of ``frames`` frames, ``damaged`` damaged files and ``jumps`` jumping clips
    into ``folder`` (made if missing), in subfolders by source; returns their paths, sorted.

    Windows start at random frames (``seed``), at least 120 frames (one second) long.  ``mocap``: the folder
    of source clips (the repository's ``data/mocap``).
    """
    rng = np.random.default_rng(seed)
    sources = source_clips(mocap)
    if not sources:
        raise InputError(f"{mocap}: no .bvh clip to tile (the repository's data/mocap)")
    folder = Path(folder)
    paths, used = [], set()
    for k in range(clips + jumps + damaged):
        name, header, lines = sources[k % len(sources)]
        body = lines[1:]  # the leading T-pose left out
        window = int(rng.integers(120, min(len(body), 600)))
        start = int(rng.integers(0, len(body) - window))
        while (name, start) in used:  # every clip its own frames: a scan keeps one of two equal files
            start = int(rng.integers(0, len(body) - window))
        used.add((name, start))
        tiled = _tiled(body, start, window, frames)
        sub = folder / name
        sub.mkdir(parents=True, exist_ok=True)
        if k < clips:
            path, text = sub / f"clip_{k:04d}.bvh", _bvh_text(header, tiled)
        elif k < clips + jumps:
            tiled[len(tiled) // 2] = lines[0]  # the T-pose for one frame
            path, text = sub / f"jump_{k:04d}.bvh", _bvh_text(header, tiled)
        else:
            kind = DAMAGES[(k - clips - jumps) % len(DAMAGES)]
            path, text = sub / f"damaged_{kind}_{k:04d}.bvh", _damaged(kind, header, tiled)
        files.write_text(path, text)
        paths.append(str(path))
    return sorted(paths)


def collection_frames(paths):
    """Frames in the clips of ``paths`` that parse (the ``Frames:`` line of each)."""
    total = 0
    for path in paths:
        with open(path, encoding="utf-8") as fh:
            for line in fh:
                if line.startswith("Frames:"):
                    total += int(line.split()[1])
                    break
    return total

