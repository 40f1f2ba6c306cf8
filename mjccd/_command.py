"""What the commands share: one-line failure reports of those that write files (``mjccd fit``, ``mjccd
import-bvh``), and help text in plain words (the docstrings it is made from use reStructuredText markup)."""
import argparse
import re
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


_ROLE = re.compile(r":[a-z]+:`(~?)([^`]+)`")


def plain(text):
    """``text`` without reStructuredText markup: ``code`` and `code` become code, :class:`~a.b.C` becomes C."""
    text = _ROLE.sub(lambda m: m.group(2).rsplit(".", 1)[-1] if m.group(1) else m.group(2), text)
    return re.sub(r"``([^`]*)``", r"\1", text).replace("`", "")


class PlainHelpFormatter(argparse.HelpFormatter):
    """argparse's help with the docstrings' markup taken out (:func:`plain`)."""

    def format_help(self):
        return plain(super().format_help())


def whole_number(low, noun):
    """An argparse type: a whole number of ``noun`` (a plural: "rows", "workers"), ``low`` or more."""
    def parse(text):
        try:
            value = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"expected a whole number of {noun}, got {text!r}") from None
        if value < low:
            raise argparse.ArgumentTypeError(f"expected {low} or more {noun}, got {value}")
        return value
    return parse
