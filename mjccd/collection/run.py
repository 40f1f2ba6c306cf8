"""``mjccd.scan``: every clip of a collection replayed, its contacts and checks written to two Parquet datasets."""
import math
import os
import sys
from dataclasses import dataclass, field

from mjccd.collection.checks import ScanOptions
from mjccd.collection.clips import clip_tasks, file_digest, find_clips, settings_digest
from mjccd.collection.engines import check_engine, run_batches
from mjccd.collection.tables import ScanFolder, read_tables
from mjccd.errors import InputError

MAX_BATCH = 16  # clips per part, at most


@dataclass
class ScanReport:
    """What one run did: clips found, scanned now, done before, repeated (same bytes as an earlier clip), failed."""

    found: int = 0
    scanned: int = 0
    done_before: int = 0
    repeats: list = field(default_factory=list)
    errors: int = 0
    parts: int = 0


def _batches(tasks, workers, batch):
    """The tasks in batches of ``batch`` clips (None: about four batches per worker, at most :data:`MAX_BATCH`)."""
    if batch is None:
        batch = max(1, min(MAX_BATCH, math.ceil(len(tasks) / (4 * workers))))
    if not (isinstance(batch, int) and batch >= 1):
        raise InputError(f"batch: expected a positive number of clips, got {batch!r}")
    return [tasks[i:i + batch] for i in range(0, len(tasks), batch)]


def scan(sources, out, *, model=None, workers=None, engine="pool", address=None, batch=None, progress=True,
         pandas=False, report=None, **options):
    """Scan a collection of clips for contacts between frames; return ``(contacts, clips)``.

    Args:
        sources: folders, glob patterns or files of clips: ``.bvh`` (each imported to its own skeleton, as
            ``mjccd import-bvh`` does) or qpos ``.npz`` trajectories of ``model``.
        out: the scan's folder: ``contacts.parquet`` and ``clips.parquet`` datasets, one part per batch of
            clips.  A run into a folder that holds an earlier scan with the same settings skips the clips it
            already scanned (resume); other settings are refused.
        model: the MJCF of the ``.npz`` clips.
        workers: processes (None: every core).  ``engine``: "pool" (local processes) or "ray" (Ray tasks, on a
            local Ray of ``workers`` CPUs, or on the cluster at ``address``).
        batch: clips per batch (None: about four batches per worker, at most :data:`MAX_BATCH`).
        progress: a progress bar over clips on a terminal's stderr.
        pandas: return pandas frames rather than pyarrow tables.
        report: a :class:`ScanReport` to fill in (what the command line prints).
        **options: the :class:`~mjccd.collection.checks.ScanOptions` (motion, mode, planes, self_overlap_s,
            floor_depth_m, jump_deg, bvh_scale).
    Returns:
        the whole tables of the folder (this run's clips and the earlier runs'), sorted by clip, as
        :func:`~mjccd.collection.tables.read_tables` gives them.
    """
    from mjccd import __version__

    unknown = set(options) - set(ScanOptions.__dataclass_fields__)
    if unknown:
        raise InputError(f"scan: unknown option {sorted(unknown)[0]!r}")
    options = ScanOptions(model=None if model is None else os.fspath(model), **options).check()
    workers = (os.cpu_count() or 1) if workers is None else workers
    if not (isinstance(workers, int) and workers >= 1):
        raise InputError(f"workers: expected a positive integer, got {workers!r}")
    check_engine(engine, address)
    paths = find_clips(sources)
    if options.model is None and any(p.lower().endswith(".npz") for p in paths):
        raise InputError("model: the .npz clips are qpos of a model; name it (--model MODEL.xml)")
    settings = {"version": __version__, "model_sha256": None if model is None else file_digest(options.model),
                **options.settings()}
    tasks, repeats = clip_tasks(paths, settings_digest(settings))
    report = ScanReport() if report is None else report
    report.found, report.repeats = len(paths), repeats
    with ScanFolder(out, settings) as folder:
        done = folder.done_keys()
        todo = [t for t in tasks if t.key not in done]
        report.done_before = len(tasks) - len(todo)
        bar = None
        if progress:
            from tqdm import tqdm

            bar = tqdm(total=len(todo), desc="scan", unit="clip", file=sys.stderr, disable=not sys.stderr.isatty())
        try:
            for batch_tasks, contacts, clips in run_batches(_batches(todo, workers, batch), options, engine=engine,
                                                            workers=workers, address=address):
                folder.write_batch(contacts, clips)
                report.parts += 1
                report.scanned += len(batch_tasks)
                report.errors += sum(e is not None for e in clips["error"])
                if bar is not None:
                    bar.update(len(batch_tasks))
        finally:
            if bar is not None:
                bar.close()
    return read_tables(out, pandas=pandas)
