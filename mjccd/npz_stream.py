"""Read the arrays of an .npz archive block by block, exactly as ``numpy.load`` reads them whole.

An .npz is a zip of .npy members.  :class:`Member` opens one member, parses its .npy header
with numpy's own functions, and reads the data in the blocks ``numpy.lib.format.read_array``
reads (:data:`BUFFER_SIZE` bytes), so a damaged, truncated or odd member fails with the
exception and message ``numpy.load`` would give; works for stored and deflated members alike.
:meth:`Member.rows` hands the data out a few rows at a time, so memory does not grow with the
array's length (except for a Fortran-ordered array of 2 or more dimensions: read whole).
"""
import numpy as np
from numpy.lib import format as npy_format

try:  # numpy >= 2
    from numpy.lib._format_impl import _check_version, _read_array_header
except ImportError:  # numpy 1.24 - 1.26
    from numpy.lib.format import _check_version, _read_array_header

BUFFER_SIZE = npy_format.BUFFER_SIZE   # bytes numpy reads from a zip member at a time
MAX_HEADER_SIZE = 10000                # numpy.load's default limit on a .npy header


def open_npz(path):
    """``numpy.load(path, allow_pickle=False)``: the archive's directory is read, none of its arrays."""
    return np.load(path, allow_pickle=False)


def member_key(npz, name):
    """The zip member ``npz[name]`` reads: ``name`` itself when the archive has it, else ``name + '.npy'``."""
    listed = npz.zip.namelist()
    return name if name in listed else name + ".npy"


def _read_bytes(fp, size):
    """``size`` bytes, raising numpy's ValueError when the member ends first."""
    data = b""
    while True:
        chunk = fp.read(size - len(data))
        data += chunk
        if len(chunk) == 0 or len(data) == size:
            break
    if len(data) != size:
        raise ValueError(f"EOF: reading array data, expected {size} bytes got {len(data)}")
    return data


class Member:
    """One member of an open ``NpzFile``: its header parsed, its data not read yet.

    ``is_array`` is False for a member that is not a .npy file (``numpy.load`` gives its bytes);
    otherwise ``shape``, ``fortran_order`` and ``dtype`` are the header's.  Opening raises what
    ``numpy.load`` raises on a bad header or an object array.  Use as a context manager.
    """

    def __init__(self, npz, name):
        key = member_key(npz, name)
        self._fp = npz.zip.open(key)
        try:
            magic = self._fp.read(len(npy_format.MAGIC_PREFIX))
            self._fp.seek(0)
            self.is_array = magic == npy_format.MAGIC_PREFIX
            self.shape, self.fortran_order, self.dtype, self.count = None, False, None, 0
            if self.is_array:
                self._header(npz.zip.getinfo(key).file_size)
        except BaseException:
            self._fp.close()
            raise

    def _header(self, member_size):
        fp = self._fp
        version = npy_format.read_magic(fp)
        _check_version(version)
        self.shape, self.fortran_order, self.dtype = _read_array_header(fp, version,
                                                                        max_header_size=MAX_HEADER_SIZE)
        self.count = 1 if len(self.shape) == 0 else int(np.multiply.reduce(self.shape, dtype=np.int64))
        if self.dtype.hasobject:
            raise ValueError("Object arrays cannot be loaded when allow_pickle=False")
        if self.count < 0 or self.count * self.dtype.itemsize > member_size - fp.tell():
            # numpy allocates the whole array before reading: a header claiming more than the member
            # holds fails there (MemoryError, or ValueError for a negative size) where numpy would
            np.ndarray(self.count, dtype=self.dtype)

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()

    def close(self):
        self._fp.close()

    def blocks(self):
        """The data as flat read-only arrays, in numpy's blocks; a non-array member: its bytes in blocks."""
        if not self.is_array:
            while True:
                chunk = self._fp.read(BUFFER_SIZE)
                if not chunk:
                    return
                yield chunk
        itemsize = self.dtype.itemsize
        if itemsize == 0:
            return
        step = BUFFER_SIZE // min(BUFFER_SIZE, itemsize)
        for i in range(0, self.count, step):
            n = min(step, self.count - i)
            yield np.frombuffer(_read_bytes(self._fp, n * itemsize), dtype=self.dtype, count=n)

    def discard(self):
        """Read the data through (so a damaged member fails as ``numpy.load`` would), keeping none of it."""
        for _ in self.blocks():
            pass

    def read(self):
        """The whole array as ``numpy.load`` returns it (a non-array member: its bytes)."""
        if not self.is_array:
            return b"".join(self.blocks())
        array = np.ndarray(self.count, dtype=self.dtype)
        at = 0
        for block in self.blocks():
            array[at:at + len(block)] = block
            at += len(block)
        if self.fortran_order:
            return array.reshape(self.shape[::-1]).transpose()
        return array.reshape(self.shape)

    def rows(self, n):
        """The array ``n`` rows (along its first axis) at a time, each piece a new writable array.

        Needs an array of at least one dimension; a Fortran-ordered one of two or more is read whole first.
        """
        if not self.is_array or len(self.shape) == 0:
            raise ValueError("rows() needs an array of at least one dimension")
        if n < 1:
            raise ValueError(f"rows: expected a positive number of rows, got {n}")
        if self.fortran_order and len(self.shape) > 1:
            whole = self.read()
            for start in range(0, self.shape[0], n):
                yield np.array(whole[start:start + n])
            return
        rest = tuple(self.shape[1:])
        width = int(np.prod(rest, dtype=np.int64))
        left = self.shape[0]
        if width == 0:
            for start in range(0, left, n):
                yield np.empty((min(n, left - start), *rest), dtype=self.dtype)
            return
        piece, filled = None, 0
        for block in self.blocks():
            at = 0
            while at < len(block):
                if piece is None:
                    piece, filled = np.empty(min(n, left) * width, dtype=self.dtype), 0
                take = min(len(piece) - filled, len(block) - at)
                piece[filled:filled + take] = block[at:at + take]
                filled += take
                at += take
                if filled == len(piece):
                    left -= len(piece) // width
                    yield piece.reshape(-1, *rest)
                    piece = None
