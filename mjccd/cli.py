"""The ``mjccd`` command line: ``solve`` JSON cases, run ``bench`` suites.

Every failure is reported as one line on stderr with a non-zero exit status;
no traceback reaches the user.
"""
import argparse
import functools
import json
import os
import sys

from mjccd import __version__
from mjccd._command import PlainHelpFormatter
from mjccd.errors import MjccdError

EXIT_INTERRUPTED = 130  # 128 + SIGINT, as a shell reports a command ended by Ctrl-C
EXIT_CLOSED_PIPE = 141  # 128 + SIGPIPE, as a shell reports a command ended by a closed pipe


def _refuse(message):
    """Report an unusable input or output of ``solve``; exit status 2."""
    print(f"mjccd solve: {message}", file=sys.stderr)
    return 2


def _cmd_solve(args):
    """Exit 0: all cases solved; 1: some cases failed (the others answered and written); 2: unusable input or output."""
    from mjccd import files
    from mjccd.cases import read_cases, solve_cases

    try:
        if args.output:
            files.check_output_file(args.output, inputs=[args.cases], force=args.force)
        doc = read_cases(args.cases)
    except MjccdError as exc:
        return _refuse(exc)
    try:
        results = solve_cases(doc)
    except MjccdError as exc:
        return _refuse(f"{args.cases}: {exc}")
    text = json.dumps(results, indent=1)
    if args.output:
        try:
            files.write_text(args.output, text + "\n")
        except OSError as exc:
            return _refuse(f"{args.output}: cannot write: {exc.strerror or exc}")
    if args.table:
        print(_table(results["results"]))
    elif not args.output:
        print(text)
    failed = [r for r in results["results"] if "error" in r]
    for r in failed:
        print(f"error: {r['error']}", file=sys.stderr)
    if args.output or failed:
        n = len(results["results"])
        print(f"solved {n - len(failed)}/{n} cases" + (f", {len(failed)} failed" if failed else ""),
              file=sys.stderr)
    return 1 if failed else 0


def _table(results):
    """One line per case: status, first contact, intervals, contact point."""
    from mjccd.cases import printable

    lines = [f"{'case':<18} {'at start':<12} {'first contact':>19}  {'intervals':<9} contact point"]
    for r in results:
        cid = printable(r["id"])
        if "error" in r:
            lines.append(f"{cid:<18} error: {r['error']}")
            continue
        t = "none" if r["first_contact"] is None else f"{r['first_contact']:.15f}"
        p = "" if r["contact_point"] is None else "(" + ", ".join(f"{x:+.6f}" for x in r["contact_point"]) + ")"
        lines.append(f"{cid:<18} {r['status_at_start']:<12} {t:>19}  {len(r['intervals']):<9} {p}")
    return "\n".join(lines)


# Subcommands implemented by their own module's ``main(argv)``; imported only when used.
DELEGATED = {
    "fit": ("mjccd.fit", "fit bounding ellipsoids to a MuJoCo model's bodies"),
    "import-bvh": ("mjccd.bvh", "convert a BVH motion-capture clip to an MJCF skeleton and qpos"),
    "replay": ("mjccd.replay", "replay a trajectory and report every first contact"),
    "scan": ("mjccd.collection.command", "scan a collection of clips into Parquet tables (local processes or Ray)"),
    "warmup": ("mjccd.warmup", "compile every kernel now (numba caches them), one line per job"),
}
# bench suites: (module, what it measures)
BENCH_SUITES = {
    "core": ("mjccd.bench.core", "the exact solver on ellipsoid pairs, against FCL and brute force"),
    "scene": ("mjccd.bench.scene", "the frame pipeline (filters, then exact solves) on boxing workloads"),
    "monitor": ("mjccd.bench.monitor", "CCDMonitor.step against a bare mj_step"),
    "patches": ("mjccd.patches.bench", "Chen et al.'s patch solver on its published query sets"),
    "fidelity": ("mjccd.bench.fidelity", "recall, precision and cost of the wrappers on MuJoCo environments"),
    "batch": ("mjccd.bench.batch", "many worlds at once on the CPU threads"),
    "geoms": ("mjccd.bench.geoms", "the exact geom solver on MuJoCo's shape pairs, graded by mj_geomDistance"),
    "scan": ("mjccd.bench.scan", "mjccd scan over a tiled clip collection; what a per-frame check misses"),
}


def _choose_gl_backend():
    """``MUJOCO_GL=egl`` for headless pictures (``fit --render``, replay's frames): set before mujoco is imported,
    since it picks its OpenGL platform then; only with no display, no backend chosen and libEGL installed."""
    if "MUJOCO_GL" in os.environ or os.environ.get("DISPLAY"):
        return
    import ctypes.util

    if ctypes.util.find_library("EGL"):
        os.environ["MUJOCO_GL"] = "egl"


def _delegate(module_name, argv):
    import importlib

    if module_name in ("mjccd.fit", "mjccd.replay"):
        _choose_gl_backend()
    return importlib.import_module(module_name).main(argv)


def _cmd_bench(args):
    return _delegate(BENCH_SUITES[args.suite][0], args.rest)


def build_parser():
    parser = argparse.ArgumentParser(formatter_class=PlainHelpFormatter,
                                     prog="mjccd",
                                     description=__doc__.splitlines()[0])
    parser.add_argument("--version", action="version", version=f"mjccd {__version__}")
    sub = parser.add_subparsers(dest="command", required=True)
    solve = sub.add_parser("solve", help="solve CCD cases given as JSON (format version 1)",
                           formatter_class=PlainHelpFormatter)
    solve.add_argument("cases", help="input JSON: {\"version\": 1, \"cases\": [...]}")
    solve.add_argument("-o", "--output", help="write results here instead of stdout (refused if it exists)")
    solve.add_argument("--force", action="store_true", help="replace an existing --output (even the input)")
    solve.add_argument("--table", action="store_true", help="print a readable table instead of JSON")
    solve.set_defaults(func=_cmd_solve)
    for name, (_, text) in DELEGATED.items():
        sub.add_parser(name, help=text, add_help=False)  # listed here, parsed by its module
    suites = "\n".join(f"  {name:<9} {text}" for name, (_, text) in BENCH_SUITES.items())
    bench = sub.add_parser("bench", help="measure speed and accuracy against peers",
                           formatter_class=argparse.RawDescriptionHelpFormatter,
                           description=f"suites:\n{suites}\n\nmjccd bench suite --help: the suite's options")
    bench.add_argument("suite", choices=list(BENCH_SUITES), metavar="suite", help="one of: " + ", ".join(BENCH_SUITES))
    bench.add_argument("rest", nargs=argparse.REMAINDER, help="options of the suite (--help)")
    bench.set_defaults(func=_cmd_bench)
    return parser


def _run(argv):
    """The command's exit status; an error that escapes it is reported as one line."""
    if argv and argv[0] in DELEGATED:
        command = argv[0]
        run = functools.partial(_delegate, DELEGATED[command][0], argv[1:])
    else:
        args = build_parser().parse_args(argv)
        command, run = args.command, functools.partial(args.func, args)
    try:
        return run()
    except BrokenPipeError:  # not an error of the command: main ends it quietly
        raise
    except MjccdError as exc:  # refused input or output: the message names it
        print(f"mjccd {command}: {' '.join(str(exc).split())}", file=sys.stderr)
        return 2
    except Exception as exc:  # last line of defence: one line, never a traceback
        print(f"mjccd {command}: {type(exc).__name__}: {' '.join(str(exc).split())}", file=sys.stderr)
        return 1


def _drop_stdout():
    """Point stdout at the null device, so that Python's flush at exit finds no closed pipe."""
    try:
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
    except (OSError, ValueError):  # stdout is not a file (captured in-process)
        pass


def main(argv=None):
    """Run one ``mjccd`` command; returns its exit status.

    Ctrl-C ends any command with one line, ``mjccd: interrupted``, and exit
    status 130.  A reader that closes stdout early (``mjccd solve x.json |
    head -c 10``) ends the command quietly, following Python's recipe for
    SIGPIPE: stdout is pointed at the null device and the status is 141
    (128 + SIGPIPE, what a shell reports for a command a closed pipe ends,
    so ``set -o pipefail`` scripts can tell it from an error).
    """
    argv = sys.argv[1:] if argv is None else list(argv)
    try:
        code = _run(argv)
        sys.stdout.flush()  # a closed pipe shows here, not at exit
        return code
    except BrokenPipeError:
        _drop_stdout()
        return EXIT_CLOSED_PIPE
    except KeyboardInterrupt:
        print("mjccd: interrupted", file=sys.stderr)
        return EXIT_INTERRUPTED
