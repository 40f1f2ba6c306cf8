"""``mjccd bench patches``: the Table 1 and Table 3 protocols of Chen et al. 2024.

Table 1: random moving patch pairs (triangular and quadrilateral, order 1-3), average
milliseconds per case for Trad./Ours x AABB/OBB x delta, colliding pairs, speed-ups.
Table 3: the vertex-face / edge-edge query sets in ``data/ccd-queries`` with ground
truth: mean and median microseconds per query, false positives and false negatives,
next to ipctk's Tight-Inclusion CCD when that package is installed.  The query sets
(1.8 MB) stay in the source repository; the package ships one small scene of each
(``mjccd/bench/data/ccd-queries``), which ``--quick`` uses.
"""
import argparse
import platform
import os
import re
import sys
import time

import numpy as np

from mjccd.bench import options
from mjccd.files import write_text
from mjccd._command import PlainHelpFormatter

from . import _kernels as K
from . import queries as Q
from .primitives import Patch
from .solver import first_contact

# method variants: (solver method, queue order, OBB frames). "trad" is Alg. 1 exactly as
# written (queue by the lower time end); "trad-depth" is the same with this package's queue
# order; "-step" variants take every OBB frame from the sub-patch's shape at t = 0 (the
# paper's rule) instead of at the start of the interval being refined
VARIANTS = {"trad": ("trad", "time", "interval"), "ours": ("ours", "depth", "interval"),
            "trad-depth": ("trad", "depth", "interval"), "ours-time": ("ours", "time", "interval"),
            "trad-step": ("trad", "time", "step"), "ours-step": ("ours", "depth", "step")}
LABELS = {"trad": "Trad.", "ours": "Ours", "trad-depth": "Trad.-depth", "ours-time": "Ours-time",
          "trad-step": "Trad.-step", "ours-step": "Ours-step"}


def _speedup_pairs(methods):
    """(trad variant, ours variant) pairs that get a speed-up column."""
    trads = [m for m in methods if VARIANTS[m][0] == "trad"]
    ours = [m for m in methods if VARIANTS[m][0] == "ours"]
    out = []
    for t in trads:
        for o in ours:
            if VARIANTS[t][2] == VARIANTS[o][2] or len(ours) == 1:
                out.append((t, o))
    return out


PAPER_T1_OURS_OBB = {  # paper Table 1, "Ours (OBB)" column [ms] for delta 1e-4, 1e-5, 1e-6
    ("triangle", 1): (4.26, 5.51, 6.68), ("triangle", 2): (22.40, 42.67, 90.87),
    ("triangle", 3): (35.98, 66.73, 131.30), ("quad", 1): (5.00, 9.72, 22.13),
    ("quad", 2): (19.30, 32.50, 62.12), ("quad", 3): (27.17, 44.71, 79.40)}


def table1_case(rng, kind, order):
    """One random case of the Table 1 protocol.

    Control points p and velocities v of both patches are uniform in [-1, 1]; a random
    direction d (same distribution) is added to p of patch 1 and v of patch 2 and
    subtracted from p of patch 2 and v of patch 1, which makes collisions likely.
    Time runs over [0, 1].
    """
    n = (order + 1) ** 2 if kind == "quad" else (order + 1) * (order + 2) // 2
    p1, p2, v1, v2 = (rng.uniform(-1.0, 1.0, (n, 3)) for _ in range(4))
    d = rng.uniform(-1.0, 1.0, 3)
    p1 += d
    v2 += d
    p2 -= d
    v1 -= d
    if kind == "quad":
        shape = (order + 1, order + 1, 3)
        return (Patch.quad(p1.reshape(shape), velocities=v1.reshape(shape)),
                Patch.quad(p2.reshape(shape), velocities=v2.reshape(shape)))
    return Patch.triangle(p1, velocities=v1), Patch.triangle(p2, velocities=v2)


def _progress(total, desc, enabled):
    if not enabled:
        return None
    try:
        from tqdm import tqdm
    except ImportError:  # pragma: no cover - tqdm is a dependency
        return None
    return tqdm(total=total, desc=desc, leave=False, file=sys.stderr, disable=not sys.stderr.isatty())


def _fmt(x, digits=2):
    if x is None or (isinstance(x, float) and not np.isfinite(x)):
        return "-"
    if x >= 1000:
        return f"{x:,.0f}"
    return f"{x:.{digits}f}"


# ------------------------------------------------------------------------ table 1
def run_table1(args):
    """Average ms per case; returns (markdown lines, raw rows)."""
    configs = [(m, inc) for m in args.methods for inc in args.inclusions]
    lines = []
    header = ["patch", "order", "cases", "CP"]
    for m, inc in configs:
        for d in args.deltas:
            header.append(f"{LABELS[m]} ({inc.upper()}) {d:g}")
    speedups = _speedup_pairs(args.methods)
    for t, o in speedups:
        for inc in args.inclusions:
            for d in args.deltas:
                header.append(f"{LABELS[t]}/{LABELS[o]} {inc.upper()} {d:g}")
    lines.append("| " + " | ".join(header) + " |")
    lines.append("|" + "---|" * len(header))
    raw = []
    for kind in args.kinds:
        for order in args.orders:
            rng = np.random.default_rng(args.seed)
            cases = [table1_case(rng, kind, order) for _ in range(args.cases)]
            first_contact(*cases[0], delta=1e-2)  # compile / load the kernels
            times = {}
            capped = {}
            hits = None
            bar = _progress(len(configs) * len(args.deltas) * len(cases),
                            f"{kind} {order}", args.progress)
            for m, inc in configs:
                for d in args.deltas:
                    ts, cp, cap = [], 0, 0
                    method, queue, frames = VARIANTS[m]
                    limit = args.trad_max_iterations if method == "trad" else 10_000_000
                    nodes = args.trad_max_nodes if method == "trad" else 1 << 21
                    for a, b in cases:
                        t0 = time.perf_counter()
                        c = first_contact(a, b, method=method, inclusion=inc, delta=d,
                                          max_iterations=limit, max_nodes=nodes, queue=queue,
                                          obb_frames=frames)
                        ts.append(time.perf_counter() - t0)
                        cp += c is not None
                        cap += c is not None and c.status != "converged"
                        if bar is not None:
                            bar.update(1)
                    times[m, inc, d] = 1e3 * float(np.mean(ts))
                    capped[m, inc, d] = cap
                    if (hits is None or m == "ours") and method == "ours" and \
                            inc == args.inclusions[-1] and d == args.deltas[-1]:
                        hits = cp
            if bar is not None:
                bar.close()
            row = [kind, str(order), str(len(cases)), str(hits)]
            for m, inc in configs:
                for d in args.deltas:
                    cell = _fmt(times[m, inc, d])
                    if capped[m, inc, d]:
                        cell += f" ({capped[m, inc, d]} capped)"
                    row.append(cell)
            for t, o in speedups:
                for inc in args.inclusions:
                    for d in args.deltas:
                        s = times[t, inc, d] / times[o, inc, d]
                        row.append(("≥" if capped[t, inc, d] else "") + f"{s:.1f}×")
            lines.append("| " + " | ".join(row) + " |")
            raw.append({"kind": kind, "order": order, "cp": hits, "times": times,
                        "capped": capped})
            print(lines[-1], flush=True)
    return lines, raw


# ------------------------------------------------------------------------ table 3
def _time_queries(kind, vertices, variant, inclusion, delta, max_iterations, progress,
                  compiled_loop):
    """Per-query wall time through one compiled call each, plus the batch mean."""
    a, b = Q.query_primitives(kind, vertices)
    ka, ca, sa, kb, cb, sb = Q.query_kernel_args(kind)
    pairs = np.zeros((1, 2), np.int64)
    pts = np.empty((1, 9))
    info = np.zeros(4, np.int64)
    method, queue, frames = VARIANTS[variant]
    m = K.OURS if method == "ours" else K.TRAD
    obb = inclusion == "obb"
    q = len(vertices)
    hit = np.zeros(q, bool)
    per = np.empty(q)
    search = K.search
    bar = _progress(q, f"{kind} {method} {inclusion}", progress)
    for i in range(q):
        ai, bi = a[i], b[i]
        t0 = time.perf_counter()
        search(ka, ca, sa, ai, kb, cb, sb, bi, pairs, m, obb, delta, 1.0,
               Q.DEFAULT_MARGIN, Q.DEFAULT_TIME_MARGIN, max_iterations, 1 << 21, queue == "depth",
               frames == "step", False, 0.0, 0.0, pts, info)
        per[i] = time.perf_counter() - t0
        hit[i] = info[0] != K.NO_CONTACT
        if bar is not None and i % 256 == 0:
            bar.update(min(256, q - i))
    if bar is not None:
        bar.close()
    if not compiled_loop:
        return hit, per, None
    t0 = time.perf_counter()
    toi, _ = Q.batch(kind, vertices, method=method, inclusion=inclusion, delta=delta,
                     queue=queue, obb_frames=frames, max_iterations=max_iterations,
                     compiled_loop=True)
    batch_mean = (time.perf_counter() - t0) / q
    assert np.array_equal(np.isfinite(toi), hit)
    return hit, per, batch_mean


def _time_ipctk(kind, vertices):
    import ipctk
    ccd = ipctk.TightInclusionCCD()
    q = len(vertices)
    hit = np.zeros(q, bool)
    per = np.empty(q)
    fn = ccd.point_triangle_ccd if kind == "vf" else ccd.edge_edge_ccd
    rows = [[np.ascontiguousarray(v) for v in query] for query in vertices]
    for i, r in enumerate(rows):
        t0 = time.perf_counter()
        ok, _ = fn(*r)
        per[i] = time.perf_counter() - t0
        hit[i] = ok
    return hit, per


def ipctk_available():
    try:
        import ipctk  # noqa: F401
    except ImportError:
        return False
    return True


def run_table3(args):
    """Per-query µs, FP, FN on the copied VF / EE sets; returns markdown lines."""
    lines = ["| set | kind | queries (pos.) | method | mean µs (per call) | median µs (per call) "
             "| mean µs (compiled loop) | FP | FN |", "|---|---|---|---|---|---|---|---|---|"]
    have_ipctk = ipctk_available() and not args.no_ipctk
    for name in args.sets:
        for kind in ("vf", "ee"):
            vertices, truth = Q.load_dataset(name, kind, root=args.data)
            if args.max_queries and args.max_queries < len(truth):
                pick = np.linspace(0, len(truth) - 1, args.max_queries).round().astype(int)
                vertices, truth = vertices[pick], truth[pick]
            Q.batch(kind, vertices[:4], compiled_loop=args.compiled_loop)
            runs = []
            for m in args.methods:
                for inc in args.inclusions:
                    hit, per, bm = _time_queries(kind, vertices, m, inc, 1e-6,
                                                 args.query_max_iterations, args.progress,
                                                 args.compiled_loop)
                    label = f"{LABELS[m]} ({inc.upper()})"
                    runs.append((label, hit, per, bm))
            if have_ipctk:
                hit, per = _time_ipctk(kind, vertices)
                runs.append(("ipctk Tight-Inclusion", hit, per, None))
            for label, hit, per, bm in runs:
                fp = int(np.sum(hit & ~truth))
                fn = int(np.sum(~hit & truth))
                row = [name, kind.upper(), f"{len(truth)} ({int(truth.sum())})", label,
                       _fmt(1e6 * per.mean()), _fmt(1e6 * np.median(per)),
                       _fmt(None if bm is None else 1e6 * bm), str(fp), str(fn)]
                lines.append("| " + " | ".join(row) + " |")
                print(lines[-1], flush=True)
    return lines


# ------------------------------------------------------------------------ CLI
QUICK = {"cases": 2, "orders": [1], "deltas": [1e-4], "trad_max_iterations": 10_000, "max_queries": 10,
         "query_max_iterations": 10_000, "data": options.packaged("ccd-queries")}
RANGES = {"cases": (1, 100_000), "orders": (1, 3), "deltas": (1e-15, 0.5), "trad_max_iterations": (1, 10**10),
          "trad_max_nodes": (1, 1 << 26), "seed": (0, 2**63 - 1), "max_queries": (0, 10**9),
          "query_max_iterations": (1, 10**10)}
QUERY_SETS = "data/ccd-queries"  # in the repository only: 1.8 MB


def _numbers(kind):
    """A parser of comma-separated numbers of ``kind`` (int or float) for argparse."""
    def parse(text):
        try:
            return [kind(x) for x in text.split(",") if x]
        except ValueError:
            raise argparse.ArgumentTypeError(f"expected comma-separated {kind.__name__}s, got {text!r}") from None
    return parse


def _names(allowed):
    def parse(text):
        items = [x for x in text.split(",") if x]
        for x in items:
            if x not in allowed:
                raise argparse.ArgumentTypeError(f"expected items of {allowed}, got {x!r}")
        return items
    return parse


def machine_line():
    """One line describing the machine the numbers come from."""
    cpu = platform.processor() or platform.machine()
    try:
        with open("/proc/cpuinfo") as fh:
            for line in fh:
                if line.startswith("model name"):
                    cpu = line.split(":", 1)[1].strip()
                    break
    except OSError:
        pass
    return (f"{cpu}, {os.cpu_count()} logical cores, Python {platform.python_version()}, "
            f"numpy {np.__version__}, numba {__import__('numba').__version__}; "
            f"single-threaded queries")


def update_markdown(path, sections):
    """Replace (or append) each block between ``<!-- key start -->`` and ``<!-- key end -->``, in one atomic write.

    ``sections``: (key, body) pairs.
    """
    if os.path.exists(path):
        with open(path, encoding="utf-8") as fh:
            text = fh.read()
    else:
        text = ""
    for key, body in sections:
        start, end = f"<!-- {key} start -->", f"<!-- {key} end -->"
        block = f"{start}\n{body.rstrip()}\n{end}\n"
        pattern = re.compile(re.escape(start) + r".*?" + re.escape(end) + r"\n?", re.S)
        if pattern.search(text):
            text = pattern.sub(lambda _: block, text)
        else:
            text = text.rstrip() + ("\n\n" if text.strip() else "") + block
    write_text(path, text)


def build_parser():
    p = argparse.ArgumentParser(
        formatter_class=PlainHelpFormatter, prog="mjccd bench patches",
        description="Chen et al. 2024 Table 1 (random patches) and Table 3 (VF/EE query "
                    "sets) protocols for the patch solver.")
    p.add_argument("--table", choices=["1", "3", "all"], default="all")
    p.add_argument("--cases", type=int, default=1000, help="Table 1 cases per primitive")
    p.add_argument("--kinds", type=_names(["triangle", "quad"]), default=["triangle", "quad"])
    p.add_argument("--orders", type=_numbers(int), default=[1, 2, 3], help="patch orders, 1 to 3")
    p.add_argument("--deltas", type=_numbers(float), default=[1e-4, 1e-5, 1e-6])
    p.add_argument("--methods", type=_names(list(VARIANTS)), default=["trad", "ours"],
                   help="trad: Alg. 1 with the queue ordered by the lower time end (as in the "
                        "paper); ours: Alg. 2 with this package's queue order; trad-depth / "
                        "ours-time: the other queue order; trad-step / ours-step: OBB frames "
                        "from the shape at t = 0 (the paper's rule)")
    p.add_argument("--inclusions", type=_names(["aabb", "obb"]), default=["aabb", "obb"])
    p.add_argument("--trad-max-iterations", type=int, default=1_000_000,
                   help="Trad. cases stopped at this many iterations count as capped "
                        "(their time is then a lower bound)")
    p.add_argument("--trad-max-nodes", type=int, default=1 << 21,
                   help="Trad. queue size limit (a case stopped by it also counts as capped)")
    p.add_argument("--seed", type=int, default=2024)
    p.add_argument("--sets", type=_names(["handcrafted", "simulation"]),
                   default=["handcrafted", "simulation"])
    p.add_argument("--data", help=f"root of the copied query sets (default: {QUERY_SETS} of the source "
                                  "repository; with --quick one small scene of each set, shipped with the package)")
    p.add_argument("--max-queries", type=int, default=0,
                   help="Table 3: an evenly spaced subset of N queries per set and kind")
    p.add_argument("--query-max-iterations", type=int, default=1_000_000,
                   help="Table 3: iteration limit per query (a stopped query counts as a "
                        "collision, i.e. conservatively)")
    p.add_argument("--compiled-loop", action="store_true",
                   help="Table 3: also time all queries inside one compiled loop (mean)")
    p.add_argument("--no-ipctk", action="store_true", help="skip ipctk even if installed")
    p.add_argument("--markdown", help="write / update the tables in this markdown file")
    p.add_argument("--label", default="", type=lambda x: f"-{x}" if x else "",
                   help="suffix of the markdown section name, to keep several runs")
    p.add_argument("--no-progress", dest="progress", action="store_false")
    options.add_quick(p, QUICK)
    return p


def _check_query_sets(parser, args):
    """Stop with a usage error unless ``args.data`` holds every set and kind Table 3 will read."""
    args.data = options.repository_input(parser, "--data", args.data, QUERY_SETS, "1.8 MB")
    if not os.path.isdir(args.data):
        parser.error(f"--data: no such folder: {args.data}")
    found = Q.dataset_files(args.data)
    for name in args.sets:
        for kind in ("vf", "ee"):
            if (name, kind) not in found:
                parser.error(f"--data: no {name} {kind.upper()} query files under {args.data}")


def main(argv):
    """Entry point of ``mjccd bench patches``; returns the exit status."""
    parser = build_parser()
    args = options.parse(parser, argv, QUICK)
    options.check_ranges(parser, args, RANGES)
    for dest in ("kinds", "methods", "inclusions", "sets"):
        if not getattr(args, dest):
            parser.error(f"--{dest}: expected at least one value")
    if args.table in ("3", "all"):
        _check_query_sets(parser, args)
    options.check_markdown(parser, args.markdown)
    command = "mjccd bench patches " + " ".join(argv)
    print(f"# machine: {machine_line()}")
    sections = []
    if args.table in ("1", "all"):
        lines, _ = run_table1(args)
        sections.append(("mjccd-bench-patches-table1" + args.label, lines))
    if args.table in ("3", "all"):
        sections.append(("mjccd-bench-patches-table3" + args.label, run_table3(args)))
    if args.markdown:
        header = f"Command: `{command}`  \nMachine: {machine_line()}\n\n"
        update_markdown(args.markdown, [(key, header + "\n".join(lines) + "\n") for key, lines in sections])
    return 0


if __name__ == "__main__":  # pragma: no cover
    raise SystemExit(main(sys.argv[1:]))
