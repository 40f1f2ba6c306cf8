"""Ctrl-C around compiled loops.

A SIGINT that arrives while numba code runs sets Python's exception without
the compiled function noticing, which surfaces as ``SystemError: ...
returned a result with an exception set``.  Inside :func:`deferred` a SIGINT
only raises a flag; the caller runs its compiled work in chunks and calls
the yielded ``check`` between them, which raises ``KeyboardInterrupt`` at a
clean point.
"""
import signal
import threading
from contextlib import contextmanager


@contextmanager
def deferred():
    """Yields ``check()``: raises KeyboardInterrupt if Ctrl-C was pressed since the block began."""
    if threading.current_thread() is not threading.main_thread():
        yield lambda: None  # signals only reach the main thread
        return
    pressed = []

    def on_sigint(signum, frame):
        pressed.append(signum)

    def check():
        if pressed:
            raise KeyboardInterrupt

    previous = signal.signal(signal.SIGINT, on_sigint)
    try:
        yield check
    finally:
        signal.signal(signal.SIGINT, previous)
    check()
