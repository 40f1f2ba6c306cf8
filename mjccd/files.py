"""Outputs that are never half-written and never overwrite something by surprise.

Every file is written under a temporary name in its own folder and renamed
into place only when complete (a rename within a folder is atomic), so an
interrupted run leaves the old file or nothing, never a truncated one.  A
folder of outputs (:class:`OutputFolder`) is written all-or-nothing: its
manifest, which lists the files of the run, is written last, and a failed or
interrupted run removes what it wrote.  Existing files, a command's own
inputs and folders that hold another run's files are refused unless the user
passes ``--force``.
"""
import fnmatch
import json
import os
import tempfile
from contextlib import contextmanager
from pathlib import Path

from mjccd.errors import OutputError

MANIFEST = ".mjccd-manifest.json"


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


class OutputFolder:
    """A folder of one run's outputs, written all-or-nothing.

    ``tool`` names the command (kept in the manifest).  A folder that already
    holds files is refused, unless ``force``: then the files an earlier run of
    this tool wrote there (its manifest's list, and for folders from before
    manifests, names matching ``patterns``) are removed first; anything else
    is left alone.  Use as a context manager; open files with :meth:`open`.
    On an error or an interrupt inside the block, the files written so far
    are removed (and the folder, if this run created it and it is empty);
    otherwise the manifest is written last.
    """

    def __init__(self, path, tool, force=False, patterns=()):
        self.path = Path(path)
        self.tool = tool
        self.force = force
        self.patterns = tuple(patterns)
        self.written = []
        self._created = False
        if self.path.exists() and not self.path.is_dir():
            raise OutputError(f"{path}: exists and is not a folder")
        if self.path.is_dir():
            self._clear_earlier_run()

    def _clear_earlier_run(self):
        names = sorted(os.listdir(self.path))
        if not names:
            return
        if not self.force:
            shown = ", ".join(names[:3]) + (", ..." if len(names) > 3 else "")
            raise OutputError(f"{self.path}: holds files of another run ({len(names)}: {shown}); "
                              "choose an empty folder or pass --force to replace this tool's earlier outputs")
        stale = set(self._manifest_files())
        stale.update(n for n in names if any(fnmatch.fnmatch(n, pat) for pat in self.patterns))
        for name in sorted(stale):
            target = self.path / name
            if target.is_file():
                target.unlink()
        manifest = self.path / MANIFEST
        if manifest.exists():
            manifest.unlink()

    def _manifest_files(self):
        try:
            with open(self.path / MANIFEST, encoding="utf-8") as fh:
                files = json.load(fh).get("files", [])
        except (OSError, ValueError, AttributeError):
            return []
        # only plain names inside this folder: a manifest never removes anything elsewhere
        return [f for f in files if isinstance(f, str) and f == os.path.basename(f) and f not in ("", ".", "..")]

    def __enter__(self):
        if not self.path.exists():
            self.path.mkdir(parents=True)
            self._created = True
        return self

    @contextmanager
    def open(self, name, mode="w", **kwargs):
        """A file of this run, written atomically (see :func:`atomic_open`)."""
        with atomic_open(self.path / name, mode, **kwargs) as fh:
            yield fh
        self.written.append(name)

    def file_path(self, name):
        """Where ``name`` goes (for reading back; write with :meth:`open`)."""
        return self.path / name

    def __exit__(self, exc_type, exc, tb):
        if exc_type is None:
            write_text(self.path / MANIFEST, json.dumps({"tool": self.tool, "files": self.written}, indent=1) + "\n")
            return False
        for name in self.written:
            try:
                (self.path / name).unlink()
            except FileNotFoundError:
                pass
        if self._created:
            try:
                self.path.rmdir()
            except OSError:
                pass
        return False
