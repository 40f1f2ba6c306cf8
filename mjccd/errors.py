"""The exceptions mjccd raises on purpose: every message names the argument, field or file.

``MjccdError`` is the common base, so a caller can catch everything the
library refuses in one clause; the subclasses are also ``ValueError``,
``TypeError`` or ``OSError``, so code written against the built-in
exceptions keeps working.
"""


class MjccdError(Exception):
    """Base of every error mjccd raises about its inputs or outputs."""


class InputError(MjccdError, ValueError):
    """A value that is not acceptable: out of range, wrong shape, NaN, inconsistent."""


class InputTypeError(MjccdError, TypeError, ValueError):
    """An argument of the wrong kind (a string where a number is expected, ...).

    Also a ValueError, as every input error was before these classes existed.
    """


class OutputError(MjccdError, OSError):
    """An output that would overwrite something it must not, or that cannot be written."""


class ConcurrentUseError(MjccdError, RuntimeError):
    """One object (a Scene, a monitor, a batch) entered from a second thread while the first is still in it.

    Its buffers are shared, so the second call could only give wrong answers: it is refused at once.
    """
