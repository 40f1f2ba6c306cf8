"""The ``mjccd`` command line: ``solve`` JSON cases, run ``bench`` suites.

Every failure is reported as one line on stderr with a non-zero exit status;
no traceback reaches the user.
"""
import argparse
import json
import sys


def _cmd_solve(args):
    from mjccd.cases import solve_cases

    try:
        with open(args.cases) as fh:
            doc = json.load(fh)
    except OSError as exc:
        print(f"mjccd solve: cannot read {args.cases}: {exc.strerror}", file=sys.stderr)
        return 2
    except json.JSONDecodeError as exc:
        print(f"mjccd solve: {args.cases} is not valid JSON: {exc}", file=sys.stderr)
        return 2
    try:
        results = solve_cases(doc)
    except ValueError as exc:
        print(f"mjccd solve: {args.cases}: {exc}", file=sys.stderr)
        return 2
    text = json.dumps(results, indent=1)
    if args.output:
        with open(args.output, "w") as fh:
            fh.write(text + "\n")
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
    lines = [f"{'case':<18} {'at start':<12} {'first contact':>19}  {'intervals':<9} contact point"]
    for r in results:
        if "error" in r:
            lines.append(f"{r['id']:<18} error: {r['error']}")
            continue
        t = "none" if r["first_contact"] is None else f"{r['first_contact']:.15f}"
        p = "" if r["contact_point"] is None else "(" + ", ".join(f"{x:+.6f}" for x in r["contact_point"]) + ")"
        lines.append(f"{r['id']:<18} {r['status_at_start']:<12} {t:>19}  {len(r['intervals']):<9} {p}")
    return "\n".join(lines)


# Subcommands implemented by their own module's ``main(argv)``; imported only when used.
DELEGATED = {
    "fit": ("mjccd.fit", "fit bounding ellipsoids to a MuJoCo model's bodies"),
    "import-bvh": ("mjccd.bvh", "convert a BVH motion-capture clip to an MJCF skeleton and qpos"),
    "replay": ("mjccd.replay", "replay a trajectory and report every first contact"),
}
BENCH_SUITES = {"core": "mjccd.bench.core", "scene": "mjccd.bench.scene", "monitor": "mjccd.bench.monitor",
                "patches": "mjccd.patches.bench"}


def _delegate(module_name, argv):
    import importlib

    return importlib.import_module(module_name).main(argv)


def _cmd_bench(args):
    return _delegate(BENCH_SUITES[args.suite], args.rest)


def build_parser():
    parser = argparse.ArgumentParser(prog="mjccd", description=__doc__.splitlines()[0])
    sub = parser.add_subparsers(dest="command", required=True)
    solve = sub.add_parser("solve", help="solve CCD cases given as JSON (format version 1)")
    solve.add_argument("cases", help="input JSON: {\"version\": 1, \"cases\": [...]}")
    solve.add_argument("-o", "--output", help="write results here instead of stdout")
    solve.add_argument("--table", action="store_true", help="print a readable table instead of JSON")
    solve.set_defaults(func=_cmd_solve)
    for name, (_, text) in DELEGATED.items():
        sub.add_parser(name, help=text, add_help=False)  # listed here, parsed by its module
    bench = sub.add_parser("bench", help="measure speed and accuracy against peers")
    bench.add_argument("suite", choices=sorted(BENCH_SUITES))
    bench.add_argument("rest", nargs=argparse.REMAINDER, help="options of the suite (--help)")
    bench.set_defaults(func=_cmd_bench)
    return parser


def main(argv=None):
    argv = sys.argv[1:] if argv is None else list(argv)
    if argv and argv[0] in DELEGATED:
        command = argv[0]
        try:
            return _delegate(DELEGATED[command][0], argv[1:])
        except KeyboardInterrupt:
            print("mjccd: interrupted", file=sys.stderr)
            return 130
        except Exception as exc:  # one line, never a traceback
            print(f"mjccd {command}: {type(exc).__name__}: {exc}", file=sys.stderr)
            return 1
    args = build_parser().parse_args(argv)
    try:
        return args.func(args)
    except KeyboardInterrupt:
        print("mjccd: interrupted", file=sys.stderr)
        return 130
    except Exception as exc:  # last line of defence: one line, never a traceback
        print(f"mjccd {args.command}: {type(exc).__name__}: {exc}", file=sys.stderr)
        return 1
