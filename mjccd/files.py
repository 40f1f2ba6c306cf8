"""Outputs that are never half-written and never overwrite something by surprise.

Every file is written under a temporary name in its own folder and renamed
into place only when complete (a rename within a folder is atomic), so an
interrupted run leaves the old file or nothing, never a truncated one.  A
folder of outputs (:class:`OutputFolder`) is written all-or-nothing: the run
is staged beside the earlier one and swapped in only when complete, its
manifest (the list of the run's files) written last; a failed or interrupted
run leaves the earlier one in place, and a second run into a folder in use is
refused.  Existing files, a command's own
inputs and folders that hold another run's files are refused unless the user
passes ``--force``.
"""
import fcntl
import fnmatch
import json
import os
import shutil
import tempfile
from contextlib import contextmanager
from pathlib import Path

from mjccd.errors import OutputError

MANIFEST = ".mjccd-manifest.json"
LOCK = ".mjccd.lock"        # the lock file of a folder a run is writing into (OutputFolder)
STAGING = ".mjccd-new-"     # the prefix of a run's staging folder inside it


def _same_file(a, b):
    try:
        return os.path.samefile(a, b)
    except OSError:
        return os.path.realpath(a) == os.path.realpath(b)


def check_output_file(path, inputs=(), force=False):
    """Refuse to write ``path`` over one of ``inputs`` or over an existing file, unless ``force``.

    Also refuses a folder, or a file whose folder does not exist (with the
    path in the message).
    """
    p = Path(path)
    if p.is_dir():
        raise OutputError(f"{path}: is a folder, expected a file name")
    if not p.parent.is_dir():
        raise OutputError(f"{path}: folder {str(p.parent) or '.'} does not exist")
    if force:
        return
    for source in inputs:
        if p.exists() and _same_file(p, source):
            raise OutputError(f"{path}: is an input of this command; write elsewhere or pass --force to replace it")
    if p.exists():
        raise OutputError(f"{path}: exists; pass --force to replace it")


def _new_file_mode():
    """The permissions ``open`` gives a new file: 0o666 less the process's umask."""
    umask = os.umask(0)
    os.umask(umask)
    return 0o666 & ~umask


@contextmanager
def atomic_open(path, mode="w", **kwargs):
    """``open`` for writing, under a temporary name renamed onto ``path`` when the block ends without error.

    On any error or interrupt the temporary file is removed and ``path`` is left as it was.
    """
    p = Path(path)
    fd, tmp = tempfile.mkstemp(prefix=f".{p.name}.", suffix=".part", dir=str(p.parent))
    try:
        os.chmod(tmp, _new_file_mode())  # mkstemp makes it private; an output is made as open() would
        with os.fdopen(fd, mode, **kwargs) as fh:
            yield fh
            fh.flush()
            os.fsync(fh.fileno())
        os.replace(tmp, p)
    except BaseException:
        try:
            os.unlink(tmp)
        except FileNotFoundError:
            pass
        raise


def write_text(path, text):
    """Write ``text`` to ``path`` atomically."""
    with atomic_open(path, "w", encoding="utf-8") as fh:
        fh.write(text)


def lock_folder(path):
    """Lock the folder ``path`` for one run (``fcntl.flock`` on its lock file, made if missing) and return the lock's
    file descriptor; an :class:`~mjccd.errors.OutputError` when another run holds it.  A killed run's lock goes
    with its process."""
    path = Path(path)
    while True:
        fd = os.open(path / LOCK, os.O_RDWR | os.O_CREAT, 0o644)
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            os.close(fd)
            raise OutputError(f"{path}: another run is writing into this folder; wait for it to end or "
                              f"choose another folder") from None
        try:  # the file a finishing run removed is no lock: take the one at the path now
            if os.fstat(fd).st_ino == os.stat(path / LOCK).st_ino:
                return fd
        except FileNotFoundError:
            pass
        os.close(fd)


def unlock_folder(path, fd):
    """Release :func:`lock_folder`'s lock ``fd`` on ``path``, removing the lock file."""
    try:
        os.unlink(Path(path) / LOCK)
    except FileNotFoundError:
        pass
    os.close(fd)


class OutputFolder:
    """A folder of one run's outputs, written all-or-nothing and swapped in only when complete.

    ``tool`` names the command (kept in the manifest).  A folder that already
    holds files is refused (when this object is made, before any work),
    unless ``force``: then the files an earlier run of this tool wrote there
    (its manifest's list, and for folders from before manifests, names
    matching ``patterns``) are replaced; anything else is left alone.

    Use as a context manager around the whole run.  On entry the folder is
    made if missing and *locked* (``fcntl.flock`` on a lock file in it,
    released by the system even when the process is killed): a second run
    into the same folder is refused at once.  The run's files go to a hidden
    staging folder inside it (:meth:`open`); only when the block ends without
    error are they moved into place (each by an atomic rename, over the
    earlier file of the same name), the earlier run's other files removed
    and the manifest written last.  On an error or an interrupt the staging
    folder is removed and the earlier run's files stay as they were (and the
    folder, if this run made it, goes).  A staging folder left by a killed
    run is removed by the next run into the folder.
    """

    def __init__(self, path, tool, force=False, patterns=()):
        self.path = Path(path)
        self.tool = tool
        self.force = force
        self.patterns = tuple(patterns)
        self.written = []
        self._created = False
        self._lock = None
        self._staging = None
        if self.path.exists() and not self.path.is_dir():
            raise OutputError(f"{path}: exists and is not a folder")
        if self.path.is_dir():
            self._check_earlier_run()

    def _names(self):
        """The folder's entries, its lock and staging folders left out."""
        return sorted(n for n in os.listdir(self.path) if n != LOCK and not n.startswith(STAGING))

    def _check_earlier_run(self):
        names = self._names()
        if names and not self.force:
            shown = ", ".join(names[:3]) + (", ..." if len(names) > 3 else "")
            raise OutputError(f"{self.path}: holds files of another run ({len(names)}: {shown}); "
                              "choose an empty folder or pass --force to replace this tool's earlier outputs")

    def _earlier_files(self):
        """The names of the earlier run's files: its manifest's list and the names matching ``patterns``."""
        stale = set(self._manifest_files())
        stale.update(n for n in self._names() if any(fnmatch.fnmatch(n, pat) for pat in self.patterns))
        return stale

    def _manifest_files(self):
        try:
            with open(self.path / MANIFEST, encoding="utf-8") as fh:
                files = json.load(fh).get("files", [])
        except (OSError, ValueError, AttributeError):
            return []
        # only plain names inside this folder: a manifest never removes anything elsewhere
        return [f for f in files if isinstance(f, str) and f == os.path.basename(f) and f not in ("", ".", "..")]

    def __enter__(self):
        try:
            if not self.path.exists():
                self.path.mkdir(parents=True)
                self._created = True
            self._lock = lock_folder(self.path)
            self._check_earlier_run()  # again, under the lock: a run may have ended since
            for name in os.listdir(self.path):  # staging folders of killed runs (none can be alive now)
                if name.startswith(STAGING):
                    shutil.rmtree(self.path / name, ignore_errors=True)
            self._staging = Path(tempfile.mkdtemp(prefix=STAGING, dir=self.path))
        except BaseException as exc:
            self._release()
            if isinstance(exc, OSError) and not isinstance(exc, OutputError):
                raise _cannot_write(self.path, exc) from None
            raise
        return self

    @contextmanager
    def open(self, name, mode="w", **kwargs):
        """A file of this run, written atomically into the staging folder (see :func:`atomic_open`)."""
        with atomic_open(self._staging / name, mode, **kwargs) as fh:
            yield fh
        if name not in self.written:  # written again: the last one stands
            self.written.append(name)

    def file_path(self, name):
        """Where ``name`` is: in the staging folder while the run writes, in the folder once it is done."""
        return (self._staging if self._staging is not None else self.path) / name

    def _swap_in(self):
        """Move the staged files over the earlier run's, remove the rest of its files, write the manifest."""
        stale = self._earlier_files() - set(self.written)
        for name in self.written:
            os.replace(self._staging / name, self.path / name)
        for name in sorted(stale):
            target = self.path / name
            if target.is_file():
                target.unlink()
        write_text(self.path / MANIFEST, json.dumps({"tool": self.tool, "files": self.written}, indent=1) + "\n")

    def _release(self):
        """Remove the staging folder, the lock (and the folder when this run made it and it is empty)."""
        if self._staging is not None:
            shutil.rmtree(self._staging, ignore_errors=True)
            self._staging = None
        if self._lock is not None:
            unlock_folder(self.path, self._lock)
            self._lock = None
        if self._created:
            try:
                self.path.rmdir()
            except OSError:
                pass

    def __exit__(self, exc_type, exc, tb):
        try:
            if exc_type is None:
                self._swap_in()
                self._created = False  # it holds the run now
            else:
                self.written = []
        except OSError as exc:
            raise _cannot_write(self.path, exc) from None
        finally:
            self._release()
        return False


def _cannot_write(path, exc):
    """The OutputError of an OSError met writing into the folder ``path``."""
    return OutputError(f"{exc.filename or path}: cannot write: {exc.strerror or exc}")
