"""``mjccd bench core``: medians of the exact core, and its peers on the same queries.

Sections (all times are medians over queries of the median of repeated runs):

1. batched static status, µs per pair;
2. rigid/rigid ``first_contact`` in close proximity (the pair's bounding spheres meet
   during the step): the fused kernel used by batched callers, the Python API on built
   objects and with the objects built from lists, and ``collision_intervals``;
3. the thesis' Example 5.1 (rational motions, F of degree 40 in t);
4. a link at the end of a six-hinge chain against a static ellipsoid (F of degree 96);
5. the Python API's own costs: the README's quick start call by call, and
   ``solve_cases`` on a document of close rigid pairs;
6. the headline against python-fcl's C++ ``continuousCollide`` (naive solver, N = 100,
   1000; only the call timed, on prebuilt objects) on the same rotating and
   translation-only pairs, with its wrong answers; then, as context, fcl's discrete
   ``collide`` driven from a Python loop and MuJoCo ``mj_geomDistance`` sampling with
   bisection, all scored against mjccd.
"""
import argparse
import json
import os
import platform
import statistics
import sys
import time

import numpy as np
from tqdm import tqdm

import mjccd
from mjccd.bench import options, peers
from mjccd.bench.report import write_section
from mjccd.ccd import rigid_first_contact
from mjccd.quadric import static_status_batch
from mjccd._command import PlainHelpFormatter

EXAMPLE_CASES = options.packaged("cases.json")  # examples/cases.json in the repository
QUICK = {"queries": 10, "repeats": 2, "static_pairs": 2000}
RANGES = {"queries": (1, 100_000), "repeats": (1, 1000), "static_pairs": (2, 5_000_000), "seed": (0, 2**63 - 1)}


def _median_us(fn, repeats):
    samples = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        samples.append(time.perf_counter() - t0)
    return 1e6 * statistics.median(samples)


def _per_query_median(items, fn, repeats):
    fn(items[0])  # compile / warm up
    return statistics.median(_median_us(lambda it=it: fn(it), repeats) for it in items)


def _median_loop_us(fn, loops, repeats):
    """µs per call of ``fn()``: the median over ``repeats`` runs of ``loops`` calls each (for calls of a
    few µs, which one timer reading per call would distort)."""
    samples = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        for _ in range(loops):
            fn()
        samples.append((time.perf_counter() - t0) / loops)
    return 1e6 * statistics.median(samples)


def bench_static(n_pairs, repeats, rng):
    """µs per pair of the batched static status kernel."""
    ra = rng.uniform(0.2, 1.0, size=(n_pairs, 3))
    rb = rng.uniform(0.2, 1.0, size=(n_pairs, 3))
    pa, pb = rng.normal(size=(n_pairs, 3)), rng.normal(size=(n_pairs, 3))
    qa, qb = rng.normal(size=(n_pairs, 4)), rng.normal(size=(n_pairs, 4))
    qa /= np.linalg.norm(qa, axis=1, keepdims=True)
    qb /= np.linalg.norm(qb, axis=1, keepdims=True)
    out = np.empty(n_pairs, dtype=np.int64)
    static_status_batch(ra[:2], pa[:2], qa[:2], rb[:2], pb[:2], qb[:2], out[:2])
    us = _median_us(lambda: static_status_batch(ra, pa, qa, rb, pb, qb, out), repeats)
    return us / n_pairs, {int(k): int(v) for k, v in zip(*np.unique(out, return_counts=True))}


def spheres_meet(q):
    """True when the bounding spheres of the query's two bodies meet during the step."""
    pa, pb = q.position_a, q.position_b
    d0, v = pa[0] - pb[0], (pa[1] - pa[0]) - (pb[1] - pb[0])
    reach = q.radii_a.max() + q.radii_b.max()
    tt = 0.0 if v @ v == 0 else float(np.clip(-(d0 @ v) / (v @ v), 0.0, 1.0))
    return np.linalg.norm(d0 + tt * v) <= reach


def fused_arguments(q):
    """Arguments of the fused kernel: radii (2, 3), positions (2, 2, 3), unit quaternions (2, 2, 4), t_max, out."""
    quats = np.array([q.quaternion_a, q.quaternion_b], dtype=float)
    quats /= np.linalg.norm(quats, axis=2, keepdims=True)
    for body in quats:
        if body[0] @ body[1] < 0:
            body[1] *= -1.0
    return (np.array([q.radii_a, q.radii_b], dtype=float), np.array([q.position_a, q.position_b], dtype=float),
            quats, 1.0, np.empty((2, 3)))


def built_pair(q):
    """The query as the Python API takes it: two Ellipsoids and two Rigid motions."""
    a, b = mjccd.Ellipsoid(q.radii_a), mjccd.Ellipsoid(q.radii_b)
    ma = mjccd.Rigid(q.position_a[0], q.quaternion_a[0], q.position_a[1], q.quaternion_a[1])
    mb = mjccd.Rigid(q.position_b[0], q.quaternion_b[0], q.position_b[1], q.quaternion_b[1])
    return a, ma, b, mb


def _lists(q):
    """The query as plain lists, as a user's code would hold it."""
    return (q.radii_a.tolist(), q.position_a.tolist(), q.quaternion_a.tolist(),
            q.radii_b.tolist(), q.position_b.tolist(), q.quaternion_b.tolist())


def _built_and_solved(lists):
    """The quick-start path on one pair: two Ellipsoids and two Rigid motions from lists, then first_contact."""
    ra, pa, qa, rb, pb, qb = lists
    return mjccd.first_contact(mjccd.Ellipsoid(ra), mjccd.Rigid(pa[0], qa[0], pa[1], qa[1]),
                               mjccd.Ellipsoid(rb), mjccd.Rigid(pb[0], qb[0], pb[1], qb[1]))


def _case(q, k):
    """The query as a case of ``mjccd solve`` (docs/case-format.md)."""
    def body(radii, position, quaternion):
        return {"radii": radii.tolist(), "motion": {
            "type": "rigid", "start": {"position": position[0].tolist(), "quaternion": quaternion[0].tolist()},
            "end": {"position": position[1].tolist(), "quaternion": quaternion[1].tolist()}}}
    return {"id": f"pair-{k}", "a": body(q.radii_a, q.position_a, q.quaternion_a),
            "b": body(q.radii_b, q.position_b, q.quaternion_b)}


README_PAIR = ([0.3, 0.2, 0.1], [0.2, 0.2, 0.4],
               ([-1, 0, 0], [1, 0, 0, 0], [1, 0, 0], [0.7071, 0, 0.7071, 0]), ([0, 0.1, 0], [1, 0, 0, 0]))
"""The README's quick start: two ellipsoids, a Rigid and a Static motion."""


def bench_api(queries, repeats):
    """Rows (name, µs, note) of the Python API's own costs: the quick start call by call, and solve_cases."""
    ra, rb, rigid, static = README_PAIR
    a, b = mjccd.Ellipsoid(ra), mjccd.Ellipsoid(rb)
    ma, mb = mjccd.Rigid(*rigid), mjccd.Static(*static)
    mjccd.collision_intervals(a, ma, b, mb)

    def quick_start():
        return mjccd.first_contact(mjccd.Ellipsoid(ra), mjccd.Rigid(*rigid), mjccd.Ellipsoid(rb),
                                   mjccd.Static(*static))

    loops, runs = 200, max(repeats, 5)
    rows = [("`Ellipsoid(radii)`", _median_loop_us(lambda: mjccd.Ellipsoid(ra), loops, runs), "radii from a list"),
            ("`Rigid(p0, q0, p1, q1)`", _median_loop_us(lambda: mjccd.Rigid(*rigid), loops, runs), "poses from lists"),
            ("`Static(p, q)`", _median_loop_us(lambda: mjccd.Static(*static), loops, runs), "pose from lists"),
            ("`first_contact`", _median_loop_us(lambda: mjccd.first_contact(a, ma, b, mb), loops, runs),
             "built objects"),
            ("`collision_intervals`", _median_loop_us(lambda: mjccd.collision_intervals(a, ma, b, mb), loops, runs),
             "built objects"),
            ("quick start: 2 `Ellipsoid` + `Rigid` + `Static` + `first_contact`",
             _median_loop_us(quick_start, loops, runs), "the README's pair")]
    doc = {"version": 1, "cases": [_case(q, k) for k, q in enumerate(queries)]}
    from mjccd.cases import solve_cases
    solve_cases(doc)
    per_case = _median_loop_us(lambda: solve_cases(doc), 1, runs) / len(queries)
    rows.append(("`solve_cases`, per case", per_case,
                 f"a document of the {len(queries)} close rigid pairs: parsed, solved (all intervals), written"))
    return rows


def reference_times(queries):
    """mjccd's first contact time of each query (None when the pair stays separate)."""
    out = []
    for q in queries:
        c = mjccd.first_contact(*built_pair(q))
        out.append(None if c is None else c.time)
    return out


def six_hinge_chain():
    """An arm link behind six hinges (rational degree 12: F of degree 96) and an obstacle."""
    elements = []
    axes = [[0, 0, 1], [0, 1, 0], [0, 1, 0], [1, 0, 0], [0, 1, 0], [1, 0, 0]]
    angles = [(-0.4, 0.5), (0.2, -0.3), (-0.5, 0.4), (0.3, 0.6), (-0.2, 0.3), (0.1, -0.4)]
    for axis, (a0, a1) in zip(axes, angles):
        elements.append(mjccd.Hinge(axis, a0, a1))
        elements.append(mjccd.Fixed([0.25, 0.0, 0.0]))
    return (mjccd.Ellipsoid([0.15, 0.05, 0.05]), mjccd.Chain(elements),
            mjccd.Ellipsoid([0.2, 0.2, 0.3]), mjccd.Static([1.2, 0.3, 0.1]))


def _load_case(cid):
    with open(EXAMPLE_CASES) as fh:
        case = next(c for c in json.load(fh)["cases"] if c["id"] == cid)
    from mjccd.cases import motion_from_json
    return (mjccd.Ellipsoid(case["a"]["radii"]), motion_from_json(case["a"]["motion"], "a.motion"),
            mjccd.Ellipsoid(case["b"]["radii"]), motion_from_json(case["b"]["motion"], "b.motion"))


def run(n_queries, repeats, n_static, seed, with_peers):
    rng = np.random.default_rng(seed)
    rows = []
    sections = tqdm(total=6 if with_peers else 5, desc="bench core", unit="section",
                    disable=not sys.stderr.isatty())

    us, counts = bench_static(n_static, repeats, rng)
    rows.append(("static status, batched (per pair)", us, f"{n_static} random pairs; {counts}"))
    sections.update()

    queries = [q for q in peers.random_rigid_queries(3 * n_queries, seed=seed, max_angle=0.5)
               if spheres_meet(q)][:n_queries]
    refs = reference_times(queries)
    hits = sum(r is not None for r in refs)
    fused = _per_query_median([fused_arguments(q) for q in queries], lambda a: rigid_first_contact(*a), repeats)
    built = [built_pair(q) for q in queries]
    api = _per_query_median(built, lambda a: mjccd.first_contact(*a), repeats)
    from_lists = _per_query_median([_lists(q) for q in queries], _built_and_solved, repeats)
    intervals = _per_query_median(built, lambda a: mjccd.collision_intervals(*a), repeats)
    rows.append(("rigid/rigid first_contact, fused kernel", fused,
                 f"{len(queries)} pairs with meeting bounding spheres, {hits} collide"))
    rows.append(("rigid/rigid first_contact, Python API", api, "same pairs, built Ellipsoid and Rigid objects"))
    rows.append(("rigid/rigid first_contact, Python API from lists", from_lists,
                 "same pairs: 2 `Ellipsoid` + 2 `Rigid` built from lists, then `first_contact`"))
    rows.append(("rigid/rigid collision_intervals, Python API", intervals,
                 f"same pairs, every interval: {intervals / api:.2f}× first_contact"))
    sections.update()

    ex = _load_case("pub-thesis-5.1")
    t_ex = mjccd.first_contact(*ex).time
    rows.append(("thesis Example 5.1 (F degree 40)", _per_query_median([ex], lambda a: mjccd.first_contact(*a),
                                                                      max(repeats, 20)),
                 f"first contact t = {t_ex:.15f}"))
    sections.update()

    chain = six_hinge_chain()
    from mjccd.ccd import degree_in_t, prepare_pair
    pencil, _, _ = prepare_pair(*chain[1].quadric_bounded_on(chain[0].radii, 0.0, 1.0),
                                *chain[3].quadric_bounded_on(chain[2].radii, 0.0, 1.0), 1.0)
    degree = degree_in_t(*pencil)
    c = mjccd.first_contact(*chain)
    rows.append((f"six-hinge chain link vs static (F degree {degree})",
                 _per_query_median([chain], lambda a: mjccd.first_contact(*a), max(repeats, 20)),
                 "no contact" if c is None else f"first contact t = {c.time:.12f}"))
    deg6 = _load_case("pub-chain-01")
    rows.append(("degree-6 rational link vs static (F degree 96)",
                 _per_query_median([deg6], lambda a: mjccd.first_contact(*a), max(repeats, 20)),
                 "public case pub-chain-01"))
    sections.update()

    api_rows = bench_api(queries, repeats)
    sections.update()

    peer_rows = []
    if with_peers:
        straight = [q for q in peers.random_rigid_queries(3 * n_queries, seed=seed + 1, max_angle=0.0)
                    if spheres_meet(q)][:n_queries]
        straight_refs = reference_times(straight)
        mj_fused = _per_query_median([fused_arguments(q) for q in straight], lambda a: rigid_first_contact(*a), repeats)
        mj_api = _per_query_median([built_pair(q) for q in straight], lambda a: mjccd.first_contact(*a), repeats)
        peer_rows.append(("translation-only", mj_fused, mj_api, straight,
                          peers.peer_table(straight, straight_refs, (100, 1000), repeats=repeats)))
        peer_rows.append(("rotating (up to 0.5 rad)", fused, api, queries,
                          peers.peer_table(queries, refs, (100, 1000), repeats=repeats)))
        sections.update()
    sections.close()
    return rows, api_rows, peer_rows


def _headline(peer_rows):
    """The ratio table against python-fcl's continuousCollide (naive solver), one row per set of pairs."""
    lines = ["| pairs | mjccd kernel µs | mjccd API µs | fcl N=100 µs | fcl N=1000 µs | N=100 / kernel "
             "| N=1000 / kernel | N=100 / API | N=1000 / API | fcl wrong, N=100 / 1000 | mjccd vs MuJoCo |",
             "| --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | --- |"]
    for title, kernel, api, queries, table in peer_rows:
        by_name = {r["name"]: r for r in table}
        fcl100, fcl1000 = by_name["python-fcl naive, 100 steps"], by_name["python-fcl naive, 1000 steps"]
        mujoco = by_name["MuJoCo mj_geomDistance, 1000 samples + bisection"]
        if fcl100["median_us"] is None:
            cells = ["–"] * 7
        else:
            t100, t1000 = fcl100["median_us"], fcl1000["median_us"]
            cells = [f"{t100:.1f}", f"{t1000:.1f}", f"{t100 / kernel:.1f}×", f"{t1000 / kernel:.1f}×",
                     f"{t100 / api:.1f}×", f"{t1000 / api:.1f}×",
                     f"{fcl100['n_wrong']} / {fcl1000['n_wrong']} of {len(queries)}"]
        agree = f"{mujoco['n_wrong']} disagree (> 1e-6), max abs dt {mujoco['max_dt']:.1e}"
        lines.append(f"| {title}, {len(queries)} | {kernel:.1f} | {api:.1f} | " + " | ".join(cells) + f" | {agree} |")
    return lines


def _us(value):
    return f"{value:.3f}" if value < 1 else f"{value:.1f}"


def markdown(rows, api_rows, peer_rows, command):
    lines = ["## Core (`mjccd bench core`)", "",
             f"Command: `{command}`  ",
             f"Machine: {platform.machine()}, {os.cpu_count()} cores, Python {platform.python_version()}, "
             f"numpy {np.__version__}", "",
             "| query | median µs | notes |", "| --- | ---: | --- |"]
    for name, us, note in rows:
        lines.append(f"| {name} | {_us(us)} | {note} |")
    lines += ["", "### Python API", "",
              "What the Python layer adds to the kernel: validation (scalar checks on Python floats), the",
              "motions' rows, one compiled call per query (or per chunk of cases).", "",
              "| call | median µs | notes |", "| --- | ---: | --- |"]
    for name, us, note in api_rows:
        lines.append(f"| {name} | {_us(us)} | {note} |")
    if peer_rows:
        lines += ["", "### Headline: python-fcl `continuousCollide` (C++, naive solver) on the same close pairs", "",
                  "Only the `fcl.continuousCollide` call is timed, on prebuilt objects, end transforms, request and",
                  "result: fcl's fastest path from Python.  mjccd's fused kernel (plain arrays, what batched callers",
                  "run) and its Python API (`first_contact` on built objects) in the same run.  Wrong: further than",
                  "1e-6 from mjccd's exact first contact, misses and false contacts included; fcl answers with a",
                  "sample time k / N, and on rotating pairs interpolates the rotation by slerp, not by mjccd's",
                  "quaternion lerp.  Last column: mjccd against MuJoCo's GJK distance sampled 1000 times and",
                  "bisected to 1e-9, an independent check.", ""]
        lines += _headline(peer_rows)
    for title, kernel, _, queries, table in peer_rows:
        lines += ["", f"### Peers on the same {len(queries)} rigid queries, {title}", "",
                  f"mjccd (fused kernel, exact): {kernel:.1f} µs median per query.  Context rows: fcl's discrete",
                  "`collide` driven from a Python loop along mjccd's own motion, and MuJoCo sampling.", "",
                  peers.markdown_table(table), "",
                  "| peer | ratio peer / mjccd kernel (median) |", "| --- | ---: |"]
        for r in table:
            if r["median_us"] is not None:
                lines.append(f"| {r['name']} | {r['median_us'] / kernel:.1f}× |")
    return "\n".join(lines) + "\n"


def main(argv=None):
    parser = argparse.ArgumentParser(formatter_class=PlainHelpFormatter,
                                     prog="mjccd bench core", description=__doc__.splitlines()[0])
    parser.add_argument("--queries", type=int, default=200, help="rigid queries per set (default 200)")
    parser.add_argument("--repeats", type=int, default=7, help="runs per query (default 7)")
    parser.add_argument("--static-pairs", type=int, default=200000, help="pairs in the batched static test")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--no-peers", action="store_true", help="skip python-fcl and MuJoCo sampling")
    parser.add_argument("--markdown", metavar="FILE", help="write the tables into this markdown file")
    options.add_quick(parser, QUICK)
    args = options.parse(parser, argv, QUICK)
    options.check_ranges(parser, args, RANGES)
    options.check_markdown(parser, args.markdown)
    rows, api_rows, peer_rows = run(args.queries, args.repeats, args.static_pairs, args.seed, not args.no_peers)
    command = "mjccd bench core" + ("" if argv is None else " " + " ".join(argv))
    text = markdown(rows, api_rows, peer_rows, command)
    print(text)
    if args.markdown:
        write_section(args.markdown, "core", text)
        print(f"written to {args.markdown}")
    return 0
