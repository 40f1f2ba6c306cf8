"""Where numba keeps mjccd's compiled kernels, and a note on stderr while kernels compile.

:mod:`mjccd` imports this module before anything that imports numba.  numba caches a
kernel next to its source (``__pycache__``) when it can write there.  An install it
cannot write to (a system or read-only site-packages) gets ``NUMBA_CACHE_DIR`` set to
``$XDG_CACHE_HOME/mjccd`` (or ``~/.cache/mjccd``): the kernels compile once per user, in a
folder named after mjccd (numba's own fallback, a folder under ``~/.cache/numba``, is left
for when that one cannot be made).  A ``NUMBA_CACHE_DIR`` the user set is never replaced.
numba reads ``NUMBA_CACHE_DIR`` for every cached function of the process, so on such an
install the caches of other numba code go to that folder as well (each under a subfolder
named after its source folder).

Compiling is the slow part of first use (one to two minutes of CPU for the demo's replay
on 2 cores, see docs/benchmarks.md, "First use"): while mjccd's kernels compile (not when
they load from the cache) ``mjccd: compiling kernels (first use only)…`` goes to stderr
once, with the kernels compiled and the seconds so far on a terminal, progress lines in a
log and the totals of long compiles (:class:`CompileNotice`).  It listens to numba's
compile events, so nothing runs when nothing compiles.
"""
import contextlib
import os
import sys
import time

PACKAGE_DIR = os.path.dirname(os.path.abspath(__file__))
MESSAGE = "mjccd: compiling kernels (first use only)…"
NOTICE_DELAY = 0.5     # s: a compile shorter than this prints nothing
REDRAW_EVERY = 0.5     # s: terminal progress updates
LOG_EVERY = 30.0       # s: progress lines when stderr is not a terminal
LONG_RUN = 5.0         # s: in a log, a run this long ends with a line of totals


def user_cache_dir(environ=os.environ):
    """``$XDG_CACHE_HOME/mjccd``, or ``~/.cache/mjccd`` when XDG_CACHE_HOME is unset or empty."""
    base = environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
    return os.path.join(base, "mjccd")


def _kernel_folders(package_dir):
    """The package folder and its subpackages: numba writes a ``__pycache__`` into each."""
    folders = [package_dir]
    for name in sorted(os.listdir(package_dir)):
        sub = os.path.join(package_dir, name)
        if os.path.isfile(os.path.join(sub, "__init__.py")):
            folders.append(sub)
    return folders


def _writable(folder):
    """True when a cache can be written into ``folder/__pycache__`` (made if missing)."""
    pycache = os.path.join(folder, "__pycache__")
    if os.path.isdir(pycache):
        return os.access(pycache, os.W_OK | os.X_OK)
    return os.access(folder, os.W_OK | os.X_OK)


def cache_dir(environ=os.environ, package_dir=PACKAGE_DIR):
    """The ``NUMBA_CACHE_DIR`` mjccd needs, or None to leave numba's choice alone.

    None when ``NUMBA_CACHE_DIR`` is set (the user's choice) or when every folder of the
    package is writable (numba's default: next to the sources); else :func:`user_cache_dir`.
    """
    if environ.get("NUMBA_CACHE_DIR"):
        return None
    try:
        folders = _kernel_folders(package_dir)
    except OSError:  # the package folder cannot even be listed
        folders = [package_dir]
    if all(_writable(folder) for folder in folders):
        return None
    return user_cache_dir(environ)


def configure(environ=os.environ, package_dir=PACKAGE_DIR):
    """Set ``NUMBA_CACHE_DIR`` when :func:`cache_dir` asks for it; returns the folder set, or None.

    A folder that cannot be made is left unset: numba then tries its own user-wide cache
    (``~/.cache/numba``), or compiles without caching.
    """
    path = cache_dir(environ, package_dir)
    if path is None:
        return None
    try:
        os.makedirs(path, exist_ok=True)
    except OSError:
        return None
    environ["NUMBA_CACHE_DIR"] = path
    if environ is os.environ and "numba" in sys.modules:  # numba came first and has read its settings
        from numba.core import config

        config.reload_config()
    return path


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


configure()
install_notice()
