"""A guard that refuses a second thread's entry into an object whose buffers one call at a time may use.

``with self._exclusive:`` around every method that writes or reads the shared
buffers: the thread inside may enter again (a method calling another), any
other thread gets :class:`mjccd.errors.ConcurrentUseError` at once, naming the
object.  The test is deterministic: it depends on who holds the lock, never on
timing.
"""
import functools
import threading

from mjccd.errors import ConcurrentUseError


class Exclusive:
    """Entry by one thread at a time (re-entry by that thread allowed); ``name`` says what is refused."""

    __slots__ = ("_lock", "_name")

    def __init__(self, name):
        self._lock = threading.RLock()
        self._name = name

    def __enter__(self):
        if not self._lock.acquire(blocking=False):
            raise ConcurrentUseError(f"{self._name}: used from two threads at once (its buffers are shared); "
                                     f"give each thread its own {self._name}")
        return self

    def __exit__(self, *exc):
        self._lock.release()
        return False


def exclusive(method):
    """A method run inside its object's ``_exclusive`` guard (an :class:`Exclusive`)."""
    @functools.wraps(method)
    def guarded(self, *args, **kwargs):
        with self._exclusive:
            return method(self, *args, **kwargs)
    return guarded
