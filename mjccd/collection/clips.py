"""The clips of a collection: found from folders, globs and files, each keyed by what its answers depend on.

A clip's key is a hash of its bytes, the model's bytes (qpos clips), the scan's options and mjccd's version,
so a re-run recognises the clips it has already scanned, wherever the files have moved, and scans again
whatever changed.
"""
import glob
import hashlib
import json
import os
from dataclasses import dataclass
from pathlib import Path

from mjccd.errors import InputError

CLIP_SUFFIXES = (".bvh", ".npz")
_HASH_BLOCK = 1 << 20


@dataclass(frozen=True)
class ClipTask:
    """One clip to scan: its path (as found), its format ("bvh" or "npz") and its key."""

    path: str
    format: str
    key: str


def file_digest(path):
    """The SHA-256 of a file's bytes, hex; an :class:`~mjccd.errors.InputError` naming an unreadable file."""
    digest = hashlib.sha256()
    try:
        with open(path, "rb") as fh:
            for block in iter(lambda: fh.read(_HASH_BLOCK), b""):
                digest.update(block)
    except OSError as exc:
        raise InputError(f"{path}: cannot read: {exc.strerror or exc}") from None
    return digest.hexdigest()


def find_clips(sources):
    """The clip files ``sources`` name, sorted, each once: a folder gives its .bvh and .npz files (and those of
    its subfolders), a pattern with ``*``, ``?`` or ``[`` the clip files it matches, a file itself.

    A source that names nothing, or a file that is not a clip, raises an :class:`~mjccd.errors.InputError`
    naming it.
    """
    if isinstance(sources, (str, os.PathLike)):
        sources = [sources]
    found = set()
    for source in sources:
        text = str(source)
        if any(c in text for c in "*?["):
            matches = [Path(p) for p in glob.glob(text, recursive=True)]
            clips = [p for p in matches if p.is_file() and p.suffix.lower() in CLIP_SUFFIXES]
            if not clips:
                raise InputError(f"{text}: the pattern matches no .bvh or .npz clip")
        elif os.path.isdir(text):
            clips = [p for p in Path(text).rglob("*") if p.is_file() and p.suffix.lower() in CLIP_SUFFIXES]
            if not clips:
                raise InputError(f"{text}: the folder holds no .bvh or .npz clip")
        elif os.path.isfile(text):
            if Path(text).suffix.lower() not in CLIP_SUFFIXES:
                raise InputError(f"{text}: not a clip (expected a .bvh or .npz file)")
            clips = [Path(text)]
        else:
            raise InputError(f"{text}: no such file or folder")
        found.update(str(p) for p in clips)
    return sorted(found)


def settings_digest(settings):
    """The hash of what every clip's answers depend on besides its own bytes: the scan's settings (options,
    model digest, version), as its folder's ``scan.json`` records them."""
    return hashlib.sha256(json.dumps(settings, sort_keys=True).encode()).hexdigest()


def clip_tasks(paths, common):
    """``(tasks, repeats)``: a :class:`ClipTask` per path, keyed by its bytes and ``common`` (the
    :func:`settings_digest`), and the paths left out because an earlier one has the same bytes."""
    tasks, seen, repeats = [], set(), []
    for path in paths:
        key = hashlib.sha256((file_digest(path) + common).encode()).hexdigest()[:32]
        if key in seen:
            repeats.append(path)
            continue
        seen.add(key)
        tasks.append(ClipTask(path, Path(path).suffix.lower()[1:], key))
    return tasks, repeats
