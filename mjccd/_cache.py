"""Where numba keeps mjccd's compiled kernels, keyed so that they are never stale, and a note on stderr while
kernels compile.

*Never stale.*  numba checks a cached kernel against its own source file only, so an edit of a kernel it calls
in another file, or an upgrade that changes one, would run the old compiled code (numba issue #1833).  mjccd's
kernels are therefore cached in a folder named by a key: a hash of ``mjccd/__init__.py`` (the version) and of
every source file of the package that imports numba at module level or decorates a function with a jit
decorator, the files the kernels are compiled from, with :data:`CONSTANT_SOURCES`, whose constants they read.
Any change to those files is a new folder, compiled afresh.  Other files (replay, the command line) leave the
key alone; tests/test_install.py checks that no kernel reads a value from them.

*Where.*  ``mjccd/__pycache__/kernels-KEY`` when the package folder is writable (other keys there, left by
earlier versions of this install, are removed); else ``$XDG_CACHE_HOME/mjccd/kernels-KEY`` (or
``~/.cache/mjccd``); else a folder in the system's temporary folder.  A ``NUMBA_CACHE_DIR`` the user set holds
them instead (``$NUMBA_CACHE_DIR/mjccd/kernels-KEY``).  Nothing else changes: the user's other numba code keeps
numba's own cache rules, and no environment variable is set.

*How.*  Two narrow hooks into ``numba.core.caching`` (numba is capped below its next minor version in
pyproject.toml, and tests/test_install.py fails on another): ``KernelLocator`` goes first in numba's list
of cache locators and answers for mjccd's source files only, and a cache of mjccd's that cannot be read or
written (a corrupt index, a full disk) is removed, with one :class:`KernelCacheWarning`: the kernel is compiled
instead and the folder rebuilt by the next saves, never an error blamed on the user's input.

*Notice.*  Compiling is the slow part of first use (one to two minutes of CPU for the demo's replay on 2 cores,
see docs/benchmarks.md, "First use"): while mjccd's kernels compile (not when they load from the cache)
``mjccd: compiling kernels (first use only)…`` goes to stderr once, with the kernels compiled and the seconds
so far on a terminal, progress lines in a log and the totals of long compiles (:class:`CompileNotice`).  It
listens to numba's compile events, so nothing runs when nothing compiles.
"""
import contextlib
import hashlib
import os
import re
import shutil
import sys
import tempfile
import time
import warnings

PACKAGE_DIR = os.path.dirname(os.path.abspath(__file__))
MESSAGE = "mjccd: compiling kernels (first use only)…"
NOTICE_DELAY = 0.5     # s: a compile shorter than this prints nothing
REDRAW_EVERY = 0.5     # s: terminal progress updates
LOG_EVERY = 30.0       # s: progress lines when stderr is not a terminal
LONG_RUN = 5.0         # s: in a log, a run this long ends with a line of totals
KEY_PREFIX = "kernels-"
# modules without kernels whose constants kernels read (tests/test_install.py finds any other)
CONSTANT_SOURCES = ("_validate.py",)
_KERNEL_FILE = re.compile(rb"^(import numba|from numba)|^\s*@\w*jit", re.M)  # numba imported, or a jit decorator


class KernelCacheWarning(RuntimeWarning):
    """mjccd's kernel cache could not be read or written; the kernels are compiled instead."""


def user_cache_dir(environ=os.environ):
    """``$XDG_CACHE_HOME/mjccd``, or ``~/.cache/mjccd`` when XDG_CACHE_HOME is unset or empty."""
    base = environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
    return os.path.join(base, "mjccd")


def kernel_sources(package_dir=PACKAGE_DIR):
    """The package's files the key covers (paths relative to ``package_dir``, sorted): ``__init__.py``, every
    source file that imports numba at module level or decorates a function with a jit decorator, and
    :data:`CONSTANT_SOURCES`."""
    found = []
    for folder, subfolders, names in os.walk(package_dir):
        subfolders[:] = sorted(d for d in subfolders if d != "__pycache__")
        for name in names:
            if not name.endswith(".py"):
                continue
            path = os.path.join(folder, name)
            rel = os.path.relpath(path, package_dir)
            with open(path, "rb") as fh:
                text = fh.read()
            if rel == "__init__.py" or rel in CONSTANT_SOURCES or _KERNEL_FILE.search(text):
                found.append(rel)
    return sorted(found)


def kernel_key(package_dir=PACKAGE_DIR):
    """The hash of :func:`kernel_sources` (their paths and bytes), 16 hex digits."""
    digest = hashlib.sha256()
    for rel in kernel_sources(package_dir):
        with open(os.path.join(package_dir, rel), "rb") as fh:
            digest.update(rel.replace(os.sep, "/").encode() + b"\0" + fh.read() + b"\0")
    return digest.hexdigest()[:16]


def _writable(folder):
    """True when ``folder`` exists (or can be made) and a file can be created in it."""
    try:
        os.makedirs(folder, exist_ok=True)
        tempfile.TemporaryFile(dir=folder).close()
        return True
    except OSError:
        return False


def kernel_cache_root(key, environ=os.environ, package_dir=PACKAGE_DIR):
    """The folder of the kernels compiled from the sources of ``key`` (module docstring), made if missing."""
    name = KEY_PREFIX + key
    if environ.get("NUMBA_CACHE_DIR"):
        candidates = [os.path.join(environ["NUMBA_CACHE_DIR"], "mjccd", name)]
    else:
        candidates = [os.path.join(package_dir, "__pycache__", name), os.path.join(user_cache_dir(environ), name)]
    candidates.append(os.path.join(tempfile.gettempdir(), f"mjccd-{_user()}", name))
    for root in candidates:
        if _writable(root):
            return root
    return None


def _user():
    try:
        return str(os.getuid())
    except AttributeError:  # no uid (Windows)
        return os.environ.get("USERNAME", "user")


def remove_other_keys(root):
    """Remove the kernel folders of other keys beside ``root`` when it lies in the package's own ``__pycache__``
    (left by earlier versions of this install; a shared user cache may serve other installs and is left)."""
    parent = os.path.dirname(root)
    if os.path.dirname(parent) != PACKAGE_DIR:
        return
    for name in os.listdir(parent):
        if name.startswith(KEY_PREFIX) and os.path.join(parent, name) != root:
            shutil.rmtree(os.path.join(parent, name), ignore_errors=True)


_ROOT = []   # [root folder or None] once the first kernel asked for it
_WARNED = []


def _kernel_root():
    if not _ROOT:
        root = kernel_cache_root(kernel_key())
        if root is not None:
            remove_other_keys(root)
        _ROOT.append(root)
    return _ROOT[0]


def _inside_package(path):
    try:
        return os.path.commonpath([os.path.abspath(path), PACKAGE_DIR]) == PACKAGE_DIR
    except ValueError:  # another drive
        return False


def install_hooks():
    """Put ``KernelLocator`` first among numba's cache locators and guard mjccd's caches (module docstring);
    once per process."""
    from numba.core import caching

    if any(getattr(cls, "mjccd_kernels", False) for cls in caching.CacheImpl._locator_classes):
        return

    class KernelLocator(caching._CacheLocator):
        """mjccd's kernels in the folder of their key, a subfolder per package folder."""

        mjccd_kernels = True

        def __init__(self, py_func, py_file, root):
            self._lineno = py_func.__code__.co_firstlineno
            rel = os.path.relpath(os.path.dirname(os.path.abspath(py_file)), PACKAGE_DIR)
            self._cache_path = os.path.join(root, "mjccd" if rel == "." else "mjccd." + rel.replace(os.sep, "."))

        def get_cache_path(self):
            return self._cache_path

        def get_source_stamp(self):
            return os.path.basename(os.path.dirname(self._cache_path))  # the key: one folder, one stamp

        def get_disambiguator(self):
            return str(self._lineno)

        @classmethod
        def from_function(cls, py_func, py_file):
            if not _inside_package(py_file):
                return None
            root = _kernel_root()
            return None if root is None else cls(py_func, py_file, root)

    unguarded = caching.Cache._guard_against_spurious_io_errors

    @contextlib.contextmanager
    def guarded(self):
        if not getattr(getattr(self._impl, "locator", None), "mjccd_kernels", False):
            with unguarded(self):
                yield
            return
        try:
            yield
        except Exception as exc:  # noqa: BLE001 -- an unusable cache file is a compile, never a failure
            shutil.rmtree(self._cache_path, ignore_errors=True)  # rebuilt by the next saves
            if not _WARNED:
                _WARNED.append(exc)
                warnings.warn(f"mjccd: the kernel cache in {self._cache_path} cannot be used "
                              f"({type(exc).__name__}: {exc}); compiling the kernels instead and rebuilding it",
                              KernelCacheWarning, stacklevel=2)

    caching.CacheImpl._locator_classes.insert(0, KernelLocator)
    caching.Cache._guard_against_spurious_io_errors = guarded


class CompileNotice:
    """Reports mjccd's kernel compiles on stderr; a numba ``numba:compile`` event listener.

    A *run* is an outermost compile of an mjccd kernel with every compile nested in it (the
    kernels it calls).  The first run of the process that lasts ``NOTICE_DELAY`` prints
    :data:`MESSAGE`.  On a terminal each run that lasts that long keeps one line up to date
    with the kernels compiled and the seconds so far and ends it with its totals.  Elsewhere
    (logs, CI) :data:`MESSAGE` is printed once, and a later run prints only once it has lasted
    ``LONG_RUN``; a run that printed adds a progress line every ``LOG_EVERY`` seconds and, when
    it lasted ``LONG_RUN`` or more, a line with its totals.
    """

    def __init__(self, stream=None, clock=time.perf_counter):
        self._stream = stream  # None: sys.stderr at the time of writing (pytest swaps it)
        self._clock = clock
        self.depth = 0
        self.kernels = 0       # compiled in the current run
        self.total = 0         # compiled in this process
        self._start = self._shown = 0.0
        self._announced = False  # MESSAGE printed (once per process)
        self._open = False       # the current run has printed (on a terminal: its line is open)
        self._first = True       # the current run is the first to print
        self.quiet = False       # counts without printing (see :meth:`muted`)

    @staticmethod
    def _ours(event):
        dispatcher = (event.data or {}).get("dispatcher")
        module = getattr(getattr(dispatcher, "py_func", None), "__module__", "") or ""
        return module == "mjccd" or module.startswith("mjccd.")

    def _write(self, text):
        stream = self._stream or sys.stderr
        try:
            stream.write(text)
            stream.flush()
        except (OSError, ValueError):  # a closed or broken stderr: compiling goes on silently
            pass

    def _tty(self):
        stream = self._stream or sys.stderr
        try:
            return stream.isatty()
        except (AttributeError, OSError, ValueError):
            return False

    @contextlib.contextmanager
    def muted(self):
        """Count compiles without printing inside the block (``mjccd warmup`` prints its own lines)."""
        quiet, self.quiet = self.quiet, True
        try:
            yield self
        finally:
            self.quiet = quiet

    def _head(self):
        return MESSAGE if self._first else "mjccd: compiling kernels…"

    def _progress(self, now):
        elapsed = now - self._start
        if self.quiet or elapsed < NOTICE_DELAY:
            return
        tty = self._tty()
        if not self._open:
            if not tty and self._announced:
                if elapsed < LONG_RUN:
                    return  # a later run in a log: silent unless it runs long
                self._write(f"mjccd: compiling kernels… {self.kernels} so far, {elapsed:.0f} s\n")
            else:
                self._write(f"{self._head()} {self.kernels} kernels, {elapsed:.0f} s" if tty else MESSAGE + "\n")
            self._announced = self._open = True
            self._shown = now
        elif tty and now - self._shown >= REDRAW_EVERY:
            self._shown = now
            self._write(f"\r\033[K{self._head()} {self.kernels} kernels, {elapsed:.0f} s")
        elif not tty and now - self._shown >= LOG_EVERY:
            self._shown = now
            self._write(f"mjccd: compiling kernels… {self.kernels} so far, {elapsed:.0f} s\n")

    def on_start(self, event):
        if not self._ours(event):
            return
        now = self._clock()
        if self.depth == 0:
            self._start, self.kernels, self._open = now, 0, False
            self._first = not self._announced
        self.depth += 1
        self.kernels += 1
        self.total += 1
        self._progress(now)

    def on_end(self, event):
        if not self._ours(event):
            return
        now = self._clock()
        self.depth = max(self.depth - 1, 0)
        self._progress(now)
        if self.depth or not self._open:
            return
        elapsed = now - self._start
        kernels = f"{self.kernels} kernel{'s' if self.kernels != 1 else ''}"
        if self._tty():
            head = MESSAGE if self._first else "mjccd: compiled"
            self._write(f"\r\033[K{head} {kernels} in {elapsed:.1f} s\n")
        elif elapsed >= LONG_RUN:
            self._write(f"mjccd: compiled {kernels} in {elapsed:.1f} s\n")


_NOTICE = None


def install_notice():
    """Register the one :class:`CompileNotice` of the process with numba (once); returns it."""
    global _NOTICE
    if _NOTICE is None:
        from numba.core import event

        class _Listener(CompileNotice, event.Listener):
            def on_start(self, ev):
                try:
                    CompileNotice.on_start(self, ev)
                except Exception:  # a report must never stop a compile
                    pass

            def on_end(self, ev):
                try:
                    CompileNotice.on_end(self, ev)
                except Exception:
                    pass

        _NOTICE = _Listener()
        event.register("numba:compile", _NOTICE)
    return _NOTICE


install_hooks()
install_notice()
