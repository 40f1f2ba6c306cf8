"""What the bench suites share on their command lines: ``--quick``, count ranges, ``--markdown`` and input files.

Small inputs ship with the package (``mjccd/bench/data``, see its README);
big ones stay in the source repository and are found there when mjccd runs
from a checkout.  From an installed wheel, a suite that needs one stops at
once with a one-line error naming the file and how to get it.
"""
import os
from pathlib import Path

from mjccd.errors import OutputError
from mjccd.files import check_output_file

PACKAGE_DATA = Path(__file__).resolve().with_name("data")
REPOSITORY = Path(__file__).resolve().parents[2]  # the source checkout, when mjccd runs from one


def packaged(name):
    """Path (str) of an input shipped with the package."""
    return str(PACKAGE_DATA / name)


def shown(path):
    """``path`` as a report shows it: relative to the folder holding the mjccd package (the checkout or
    site-packages) when it lies there, so packaged data shows as the repository file it links to."""
    resolved = Path(path).resolve()
    parent = PACKAGE_DATA.parents[2]
    return str(resolved.relative_to(parent)) if resolved.is_relative_to(parent) else str(path)


def add_quick(parser, quick):
    """Add ``--quick``: the same code paths on small sizes (``quick``: option dest -> value), for smoke tests."""
    sizes = ", ".join(f"--{dest.replace('_', '-')} {_text(value)}" for dest, value in quick.items()
                      if not isinstance(value, str))
    parser.add_argument("--quick", action="store_true",
                        help=f"a run of a few seconds once the kernels are compiled, on small sizes ({sizes}) "
                             "and the packaged data; options given explicitly still apply")


def _text(value):
    return ",".join(map(str, value)) if isinstance(value, (list, tuple)) else str(value)


def parse(parser, argv, quick):
    """Parse ``argv``; with ``--quick``, the options left out take their values from ``quick``."""
    args = parser.parse_args(argv)
    if args.quick:
        parser.set_defaults(**quick)
        args = parser.parse_args(argv)
    return args


def check_ranges(parser, args, ranges):
    """Stop with a usage error unless every value of each option lies in its range.

    ``ranges``: option dest -> (low, high); list options are checked item by
    item and must not be empty.  NaN and infinities fail the test.
    """
    for dest, (low, high) in ranges.items():
        value = getattr(args, dest)
        option = "--" + dest.replace("_", "-")
        values = value if isinstance(value, list) else [value]
        if not values:
            parser.error(f"{option}: expected at least one value")
        for v in values:
            if not low <= v <= high:
                parser.error(f"{option} must be between {low} and {high}, got {v!r}")


def check_markdown(parser, path, inputs=()):
    """Stop with a usage error unless the markdown page ``path`` can be written (checked before a long run).

    The page itself may exist (its section is replaced); a folder, a missing
    folder, or one of the run's ``inputs`` is refused.
    """
    if path is None:
        return
    try:
        check_output_file(path, force=True)
    except OutputError as exc:
        parser.error(f"--markdown: {exc}")
    for source in inputs:
        if os.path.exists(path) and os.path.exists(source) and os.path.samefile(path, source):
            parser.error(f"--markdown: {path} is an input of this run; write the tables elsewhere")


def repository_input(parser, option, path, relative, size):
    """``path`` if the user gave one, else the big input ``relative`` of the source checkout mjccd runs from.

    From an installed wheel the file is not there: stop with a usage error
    that names it, says why (``size``, too big for the package) and how to get it.
    """
    if path is not None:
        return path
    candidate = REPOSITORY / relative
    if not candidate.exists():
        parser.error(f"{option}: {relative} ({size}) is not part of the installed package; pass {option} "
                     f"with its path in a checkout of the mjccd source repository, or run with --quick")
    return str(candidate)


def parse_checked(parser, argv, quick, ranges, inputs=()):
    """``--quick`` added, ``argv`` parsed (:func:`parse`), its ranges and ``--markdown`` checked against ``inputs``
    (:func:`check_ranges`, :func:`check_markdown`): what most suites do before they measure."""
    add_quick(parser, quick)
    args = parse(parser, argv, quick)
    check_ranges(parser, args, ranges)
    check_markdown(parser, args.markdown, inputs)
    return args


def load_average():
    """The 1-minute load average (NaN where the system does not tell): other work on the machine slows what is
    timed."""
    try:
        return os.getloadavg()[0]
    except (AttributeError, OSError):
        return float("nan")
