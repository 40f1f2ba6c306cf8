"""Append-only records kept in unnamed temporary files, so that a long run's results do not live in memory.

A replay of a million frames finds about a hundred thousand first contacts and as many runs of
frames in contact.  :class:`JsonSpool` keeps the contacts (JSON-able dicts, one JSON line each)
and :class:`ArraySpool` the runs (fixed-width numpy records) on disk; both read back in order as
often as needed.  Floats survive exactly (JSON writes ``repr``).  The files vanish when the spool
is collected.
"""
import itertools
import json
import tempfile

import numpy as np

BLOCK = 1 << 16        # bytes read at a time when a JSON spool is read back
BUFFERED = 4096        # array records gathered in memory before they are written


class JsonSpool:
    """A read-only sequence of JSON-able dicts (or lists), appended one at a time and stored on disk.

    It reads like a list: ``len``, iteration, indexing and slicing (each reads the file from the start), and
    it equals a list with the same items.  Pickling copies the items.
    """

    def __init__(self, items=()):
        self._file = tempfile.TemporaryFile()
        self._count = 0
        for item in items:
            self.append(item)

    def append(self, item):
        self._file.seek(0, 2)  # a read may have moved the position
        self._file.write(json.dumps(item, allow_nan=True).encode("utf-8") + b"\n")
        self._count += 1

    def __len__(self):
        return self._count

    def __iter__(self):
        self._file.flush()
        position, rest, left = 0, b"", self._count
        while left:
            self._file.seek(position)
            block = self._file.read(BLOCK)
            if not block:
                raise OSError(f"spool file shorter than its {self._count} items")
            position += len(block)
            lines = (rest + block).split(b"\n")
            rest = lines.pop()
            for line in lines[:left]:
                yield json.loads(line)
            left -= min(left, len(lines))

    def __getitem__(self, index):
        if isinstance(index, slice):
            start, stop, step = index.indices(self._count)
            return list(itertools.islice(self, start, stop, step)) if step > 0 else list(self)[index]
        k = index + self._count if index < 0 else index
        if not 0 <= k < self._count:
            raise IndexError("spool index out of range")
        return next(itertools.islice(self, k, None))

    def __eq__(self, other):
        try:
            return len(self) == len(other) and all(a == b for a, b in zip(self, other))
        except TypeError:
            return NotImplemented

    __hash__ = None

    def __repr__(self):
        return f"JsonSpool({self._count} items)"

    def __reduce__(self):
        return JsonSpool, (list(self),)


class ArraySpool:
    """Numpy records of one dtype, appended one at a time and stored on disk; :meth:`array` reads them all."""

    def __init__(self, dtype):
        self.dtype = np.dtype(dtype)
        self._file = tempfile.TemporaryFile()
        self._pending = []
        self._written = 0

    def append(self, record):
        """Add one record (a tuple of the dtype's fields)."""
        self._pending.append(record)
        if len(self._pending) >= BUFFERED:
            self._write()

    def _write(self):
        if self._pending:
            self._file.seek(0, 2)
            self._file.write(np.array(self._pending, dtype=self.dtype).tobytes())
            self._written += len(self._pending)
            self._pending = []

    def __len__(self):
        return self._written + len(self._pending)

    def array(self):
        """Every record so far, in order, as one (N,) structured array."""
        self._write()
        self._file.flush()
        self._file.seek(0)
        return np.fromfile(self._file, dtype=self.dtype)

    def __reduce__(self):
        return _array_spool, (self.dtype, self.array())


def _array_spool(dtype, records):
    """An :class:`ArraySpool` holding ``records`` (what unpickling calls)."""
    spool = ArraySpool(dtype)
    for record in records.tolist():
        spool.append(record)
    return spool
