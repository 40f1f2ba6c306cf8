"""The two Parquet datasets of a scan, written a part at a time so that an interrupted scan resumes.

A scan's folder holds ``contacts.parquet/`` and ``clips.parquet/``, each a folder of parts: one part per batch
of clips, ``part-<hash of the batch's clip keys>.parquet`` in both.  A part is written under a hidden temporary
name and renamed into place when complete (Parquet readers skip hidden files), the contacts part first: a batch
is done once its clips part is there.  A contacts part with no clips part (a run killed between the two
renames) is removed when the next run starts, and its clips are scanned again.  ``scan.json`` records the
options and the version the folder was scanned with; a run with others is refused.  The folder is locked while a
run writes into it.
"""
import hashlib
import json
import os
from pathlib import Path

from mjccd import files
from mjccd.collection.checks import CLIP_COLUMNS, CONTACT_COLUMNS
from mjccd.errors import InputError, OutputError

CONTACTS, CLIPS = "contacts.parquet", "clips.parquet"
SETTINGS = "scan.json"
# the order the tables come back in (read_tables)
CONTACT_ORDER = [("clip", "ascending"), ("frame", "ascending"), ("kind", "descending"), ("time", "ascending"),
                 ("part_a", "ascending"), ("part_b", "ascending")]
CLIP_ORDER = [("clip", "ascending")]


def _pyarrow():
    try:
        import pyarrow
        import pyarrow.parquet
    except ImportError:
        raise InputError("scan writes Parquet tables with pyarrow, which is not installed: "
                         "pip install 'mjccd[scan]'") from None
    return pyarrow


def schemas():
    """``(contacts, clips)`` pyarrow schemas of the two tables (the columns the docs list)."""
    pa = _pyarrow()
    text, real, whole, flag = pa.string(), pa.float64(), pa.int64(), pa.bool_()
    contact_types = {"clip": text, "key": text, "frame": whole, "time": real, "kind": text, "floor": flag,
                     "body_a": text, "body_b": text, "part_a": text, "part_b": text, "px": real, "py": real,
                     "pz": real, "nx": real, "ny": real, "nz": real, "certainty": text, "last_frame": whole,
                     "end_time": real}
    clip_types = {"clip": text, "key": text, "format": text, "frames": whole, "duration_s": real,
                  "self_contacts": whole, "floor_contacts": whole, "longest_overlap_s": real,
                  "max_floor_depth_m": real, "max_joint_turn_deg": real, "jump_frames": whole,
                  "flags": pa.list_(text), "error": text}
    return (pa.schema([(n, contact_types[n]) for n in CONTACT_COLUMNS]),
            pa.schema([(n, clip_types[n]) for n in CLIP_COLUMNS]))


class ScanFolder:
    """A scan's output folder, locked while a run writes into it (``with ScanFolder(path, settings) as folder``).

    ``settings``: what the scan's answers depend on (options, model digest, version), compared with the
    folder's ``scan.json``.
    """

    def __init__(self, path, settings):
        self.path = Path(path)
        self.settings = settings
        self._lock = None

    def __enter__(self):
        _pyarrow()
        if self.path.exists() and not self.path.is_dir():
            raise OutputError(f"{self.path}: not a folder; scan writes a folder of Parquet datasets")
        try:
            for sub in (self.path / CONTACTS, self.path / CLIPS):
                sub.mkdir(parents=True, exist_ok=True)
            self._lock = files.lock_folder(self.path)
            self._check_settings()
            self._drop_unfinished()
        except BaseException as exc:
            self._release()
            if isinstance(exc, OSError) and not isinstance(exc, OutputError):
                raise OutputError(f"{exc.filename or self.path}: cannot write: {exc.strerror or exc}") from None
            raise
        return self

    def __exit__(self, *exc):
        self._release()
        return False

    def _release(self):
        if self._lock is not None:
            files.unlock_folder(self.path, self._lock)
            self._lock = None

    def _check_settings(self):
        path = self.path / SETTINGS
        if not path.exists():
            files.write_text(path, json.dumps(self.settings, indent=1, sort_keys=True) + "\n")
            return
        try:
            earlier = json.loads(path.read_text(encoding="utf-8"))
        except (OSError, ValueError) as exc:
            raise OutputError(f"{path}: unreadable ({exc}); scan into another folder") from None
        if earlier != json.loads(json.dumps(self.settings)):
            changed = sorted(k for k in set(earlier) | set(self.settings) if earlier.get(k) != self.settings.get(k))
            raise OutputError(f"{self.path}: holds a scan made with other settings ({', '.join(changed)} differ; "
                              f"see {SETTINGS}); scan into another folder")

    def _drop_unfinished(self):
        """Remove the temporary files and the contacts parts without a clips part that killed runs left."""
        done = set(os.listdir(self.path / CLIPS))
        for sub in (CONTACTS, CLIPS):
            for name in os.listdir(self.path / sub):
                if name.startswith(".") or (sub == CONTACTS and name not in done):
                    os.unlink(self.path / sub / name)

    def done_keys(self):
        """The keys of the clips already scanned into this folder."""
        pq = _pyarrow().parquet
        keys = set()
        for name in os.listdir(self.path / CLIPS):
            if not name.startswith("."):
                keys.update(pq.read_table(self.path / CLIPS / name, columns=["key"])["key"].to_pylist())
        return keys

    def write_batch(self, contacts, clips):
        """Write one batch's rows (dicts of columns) as a part of each table, the clips part last."""
        pa = _pyarrow()
        contact_schema, clip_schema = schemas()
        name = "part-" + hashlib.sha256("".join(clips["key"]).encode()).hexdigest()[:24] + ".parquet"
        for sub, rows, schema in ((CONTACTS, contacts, contact_schema), (CLIPS, clips, clip_schema)):
            table = pa.Table.from_pydict(rows, schema=schema)
            with files.atomic_open(self.path / sub / name, "wb") as fh:
                pa.parquet.write_table(table, fh)


def read_tables(folder, *, pandas=False):
    """``(contacts, clips)`` of a scan's folder, sorted by clip (then frame): pyarrow tables, or pandas frames."""
    pa = _pyarrow()
    if pandas:
        try:
            import pandas  # noqa: F401
        except ImportError:
            raise InputError("pandas=True needs pandas, which is not installed: pip install pandas") from None
    folder = Path(folder)
    out = []
    contact_schema, clip_schema = schemas()
    for sub, schema, order in ((CONTACTS, contact_schema, CONTACT_ORDER), (CLIPS, clip_schema, CLIP_ORDER)):
        path = folder / sub
        if not path.is_dir():
            raise InputError(f"{path}: no such dataset; is {folder} a scan's folder?")
        parts = sorted(p for p in os.listdir(path) if not p.startswith("."))
        if sub == CONTACTS:  # only the batches that are done (a clips part)
            parts = [p for p in parts if (folder / CLIPS / p).exists()]
        tables = [pa.parquet.read_table(path / p, schema=schema) for p in parts]
        table = pa.concat_tables(tables) if tables else schema.empty_table()
        table = table.sort_by(order)
        out.append(table.to_pandas() if pandas else table)
    return tuple(out)
