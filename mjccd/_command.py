"""One-line failure reports of the commands that write files (``mjccd fit``, ``mjccd import-bvh``)."""
import sys

from mjccd.errors import MjccdError


def failure(command, exc, outputs):
    """Report why ``mjccd <command>`` failed as one line on stderr; returns the exit status, 2.

    Args:
        command: the command's name, as typed after ``mjccd``.
        exc: a refused input or output (:class:`MjccdError`, ValueError: its message names it),
            or an OSError raised while writing ``outputs``.
        outputs: the paths the command was writing.
    """
    if isinstance(exc, (MjccdError, ValueError)):
        print(f"mjccd {command}: {exc}", file=sys.stderr)
    else:
        print(f"mjccd {command}: cannot write {', '.join(outputs)}: {exc.strerror}", file=sys.stderr)
    return 2
