"""``mjccd bench geoms``: speed and accuracy of the exact geom solver on MuJoCo's shape pairs, against python-fcl.

Every pair of sphere, capsule, cylinder, box and ellipsoid (15) and each of
them against a static plane (5): close pairs that reach the exact stage (they
collide within the step or pass close by; the cases that never come near are
left out), with MuJoCo's own signed distance as the reference answer.

The cases: by default a set drawn by ``tests/geoms_reference.py`` (seed 23,
``--per-pair`` close cases per pair, generated in a subprocess from the source
checkout and cached in the user's cache folder, ``~/.cache/mjccd/bench-geoms``,
about a minute on two cores the first time), or any ``--cases`` / ``--expected``
pair of files in the case format; ``--quick`` takes a few cases per pair of
the held-out set ``tests/data/geoms_heldout_s11.json`` (shipped in the package).

What is timed, per case, warm (one untimed call first) and on objects built
beforehand: the bare ``geom_first_contact(a, motion_a, b, motion_b)`` call of
the Python API, and python-fcl's ``fcl.continuousCollide`` on prebuilt
collision objects, end transforms, request and result, interleaved case by
case.  Each call runs ``--repeats`` times and the fastest run is the case's
time; a pair's row gives the median and the max over its cases, in µs, and the
ratio of the medians fcl / mjccd.

Accuracy: mjccd's certified answers, its answers wrong by more than 1e-6 (or a
missed or false contact) against the reference, its worst abs dt and the share
of the cases its kernel solved that needed the double-double tier; fcl's
median and max abs dt and its wrong answers (further than 1e-6, missed or
false contacts), over all cases and over those where no body rotates (there
fcl's motion is exactly mjccd's).

python-fcl: shapes ``Sphere(r)``, ``Capsule(r, 2 h)`` and ``Cylinder(r, 2 h)``
(FCL's axis is local z too, but it takes the full length), ``Box(2 hx, 2 hy,
2 hz)`` (full sizes), ``Ellipsoid(rx, ry, rz)`` and, for MuJoCo's plane,
``Halfspace(n = (0, 0, 1), d = 0)`` at the plane's pose (the solid z <= 0).
Solvers: conservative advancement (``CCDC_CONSERVATIVE_ADVANCEMENT``: GJK
distances and motion bounds; FCL 0.7 has none for ellipsoids and crashes on
half-spaces and planes, so those pairs are not run) and the naive solver
(``CCDC_NAIVE``: the discrete ``collide`` at t = k / N) for each ``--fcl-samples``
N.  Motions: ``CCDM_TRANS`` when neither body rotates (exactly mjccd's rigid
motion); for rotating pairs ``CCDM_SCREW`` by default (the rotation at a
constant rate about one axis, as slerp: the same orientations as mjccd's
quaternion lerp at other times, and the centre on a helix, not a line), since
FCL 0.7's ``CCDM_LINEAR`` (lerp + slerp, the closest by design) builds its
motion with an uninitialised reference point (see :mod:`mjccd.bench.peers`):
``--fcl-motion linear`` runs it anyway, with its self-check in the notes.
"""
import argparse
import hashlib
import importlib.metadata
import json
import math
import os
import platform
import statistics
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from tqdm import tqdm

from mjccd._cache import user_cache_dir
from mjccd.bench import options, peers
from mjccd.bench.report import write_section
from mjccd.cases import motion_from_json
from mjccd.files import write_text
from mjccd.geoms import geom_first_contact
from mjccd.geoms import kernel as kn
from mjccd.geoms.shapes import shape_from_json
from mjccd.geoms.solve import solve_geoms
from mjccd._command import PlainHelpFormatter

SOLIDS = ("sphere", "capsule", "cylinder", "box", "ellipsoid")
PAIRS = ([f"{SOLIDS[i]}-{SOLIDS[j]}" for i in range(len(SOLIDS)) for j in range(i, len(SOLIDS))]
         + [f"{s}-plane" for s in SOLIDS])
DT_TOLERANCE = peers.DT_TOLERANCE  # an answer further than this from the reference is wrong
GENERATOR = "tests/geoms_reference.py"
HELDOUT = ("tests/data/geoms_heldout_s11.json", "tests/data/geoms_heldout_s11_expected.json")
DEFAULT_SEED, DEFAULT_PER_PAIR = 23, 16
QUICK = {"per_pair": 2, "repeats": 2, "fcl_samples": [100]}
RANGES = {"per_pair": (1, 1000), "repeats": (1, 1000), "fcl_samples": (1, 100_000), "seed": (0, 2**32 - 1),
          "jobs": (1, 256)}
CA = "CA"  # the conservative-advancement peer's key; naive peers are keyed by their N
CA_UNSUPPORTED = {"ellipsoid": "no CCD for ellipsoids", "plane": "crashes on half-spaces"}


# ----------------------------------------------------------------------------- cases


def _locate(relative):
    """A data file of the source checkout, or its copy shipped in the package; None when neither exists."""
    for candidate in (options.PACKAGE_DATA / Path(relative).name, options.REPOSITORY / relative):
        if candidate.exists():
            return str(candidate)
    return None


def _generated_per_pair(per_pair):
    """Cases to draw per pair so that at least ``per_pair`` are close: the generator cycles 9 scenarios over
    all slots, one of them "far" (never near), so at most ceil(m / 9) of a pair's m slots are far."""
    return per_pair + per_pair // 8 + 1


def generated_set(seed, per_pair, jobs, log=print):
    """(cases, expected results) drawn by ``tests/geoms_reference.py`` for ``seed``, at least ``per_pair`` close
    cases per pair; from the user's cache when the same generator (file contents, MuJoCo version) made them."""
    script = options.REPOSITORY / GENERATOR
    if not script.exists():
        raise FileNotFoundError(f"{GENERATOR} is not here (mjccd does not run from a source checkout)")
    m = _generated_per_pair(per_pair)
    try:
        mujoco_version = importlib.metadata.version("mujoco")
    except importlib.metadata.PackageNotFoundError:
        mujoco_version = "none"
    key = hashlib.sha256(script.read_bytes() + mujoco_version.encode()).hexdigest()[:12]
    cache = Path(user_cache_dir()) / "bench-geoms" / f"geoms-s{seed}-m{m}-{key}.json"
    if cache.exists():
        with open(cache) as fh:
            doc = json.load(fh)
        log(f"cases: {m} per pair, seed {seed}, from {cache}")
        return doc["cases"], doc["results"]
    log(f"cases: drawing {m} per pair (seed {seed}) with {GENERATOR}, {jobs} processes; cached in {cache} "
        f"(about 0.2 s of CPU per case)")
    with tempfile.TemporaryDirectory() as tmp:
        cases_path, expected_path = os.path.join(tmp, "cases.json"), os.path.join(tmp, "expected.json")
        done = subprocess.run([sys.executable, str(script), "--seed", str(seed), "--per-pair", str(m),
                               "-j", str(jobs), "-o", cases_path, "--expected", expected_path],
                              capture_output=True, text=True)
        if done.returncode != 0 or not os.path.exists(expected_path):
            tail = " | ".join((done.stderr or done.stdout).strip().splitlines()[-3:])
            raise RuntimeError(f"{GENERATOR} failed (exit status {done.returncode}): {tail}")
        with open(cases_path) as fh:
            cases = json.load(fh)["cases"]
        with open(expected_path) as fh:
            results = json.load(fh)["results"]
    try:
        cache.parent.mkdir(parents=True, exist_ok=True)
        write_text(cache, json.dumps({"version": 1, "seed": seed, "per_pair": m, "cases": cases,
                                      "results": results}) + "\n")
    except OSError as exc:
        log(f"cases: not cached ({exc})")
    return cases, results


def _pair_name(case):
    """The case's shape pair, "capsule-box": its types in the order of PAIRS (a plane last)."""
    ta, tb = case["a"]["shape"]["type"], case["b"]["shape"]["type"]
    order = SOLIDS + ("plane",)
    if order.index(ta) > order.index(tb):
        ta, tb = tb, ta
    return f"{ta}-{tb}"


def _poses(motion):
    """((p0, q0), (p1, q1)) of a static or rigid motion of the case format."""
    if motion["type"] == "static":
        pose = (motion["position"], motion["quaternion"])
        return pose, pose
    if motion["type"] != "rigid":
        raise ValueError(f"motion type {motion['type']!r}: the geom bench takes static and rigid motions")
    return ((motion["start"]["position"], motion["start"]["quaternion"]),
            (motion["end"]["position"], motion["end"]["quaternion"]))


def _rotates(motion):
    (_, q0), (_, q1) = _poses(motion)
    return not np.array_equal(peers.quaternion_to_matrix(np.asarray(q0, float)),
                              peers.quaternion_to_matrix(np.asarray(q1, float)))


@dataclass
class BenchCase:
    """One case, built once: mjccd's shapes and motions, its reference answer, and the results filled in."""

    id: str
    pair: str
    doc: dict
    args: tuple                      # (shape_a, motion_a, shape_b, motion_b) for geom_first_contact
    reference: float = None          # first contact (0.0: touching or overlapping at the start; None: never)
    rotates: bool = False
    answer: object = "not run"       # mjccd's first contact time, None, or "error: ..."
    certified: bool = False
    bracket: tuple = None            # an uncertain answer's bracket
    tier: int = None                 # 1: the kernel needed double-double; None: the kernel did not solve it
    us: float = None                 # fastest of the repeats
    fcl: dict = field(default_factory=dict)  # peer key -> (answer, µs)


def select_cases(cases, results, per_pair):
    """The close cases (not tagged "far"), at most ``per_pair`` of each pair, built as :class:`BenchCase`."""
    expected = {r["id"]: r for r in results}
    taken = {p: 0 for p in PAIRS}
    out = []
    for case in cases:
        if "far" in case.get("tags", ()) or case["id"] not in expected:
            continue
        pair = _pair_name(case)
        if taken.get(pair, per_pair) >= per_pair:
            continue
        taken[pair] += 1
        ref = expected[case["id"]]
        t = 0.0 if ref["status_at_start"] != "separate" else ref["first_contact"]
        args = (shape_from_json(case["a"]["shape"], "a.shape"), motion_from_json(case["a"]["motion"], "a.motion"),
                shape_from_json(case["b"]["shape"], "b.shape"), motion_from_json(case["b"]["motion"], "b.motion"))
        out.append(BenchCase(case["id"], pair, case, args, t,
                             _rotates(case["a"]["motion"]) or _rotates(case["b"]["motion"])))
    return out


# ----------------------------------------------------------------------------- python-fcl


def _fcl_geometry(fcl, shape):
    """The fcl geometry of a case-format shape (FCL takes full lengths and sizes; axis local z)."""
    t = shape["type"]
    if t == "sphere":
        return fcl.Sphere(float(shape["radius"]))
    if t == "capsule":
        return fcl.Capsule(float(shape["radius"]), 2.0 * float(shape["half_length"]))
    if t == "cylinder":
        return fcl.Cylinder(float(shape["radius"]), 2.0 * float(shape["half_length"]))
    if t == "box":
        return fcl.Box(*(2.0 * float(x) for x in shape["half_sizes"]))
    if t == "ellipsoid":
        return fcl.Ellipsoid(*map(float, shape["radii"]))
    return fcl.Halfspace(np.array([0.0, 0.0, 1.0]), 0.0)  # MuJoCo's plane: the solid z <= 0 of its frame


def _transform(fcl, position, quaternion):
    q = np.asarray(quaternion, dtype=np.float64)
    return fcl.Transform(q / np.linalg.norm(q), np.asarray(position, dtype=np.float64))


def ca_unsupported(pair):
    """Why fcl's conservative advancement is not run on this pair (None: it is)."""
    for shape, why in CA_UNSUPPORTED.items():
        if shape in pair.split("-"):
            return why
    return None


def fcl_setup(fcl, case, peer, rotating_motion):
    """The arguments of ``fcl.continuousCollide`` for one case and peer (CA or a naive N), built once."""
    objects, ends = [], []
    for key in "ab":
        (p0, q0), (p1, q1) = _poses(case.doc[key]["motion"])
        objects.append(fcl.CollisionObject(_fcl_geometry(fcl, case.doc[key]["shape"]), _transform(fcl, p0, q0)))
        ends.append(_transform(fcl, p1, q1))
    if not case.rotates:
        motion = fcl.CCDMotionType.CCDM_TRANS
    elif rotating_motion == "linear":
        motion = fcl.CCDMotionType.CCDM_LINEAR
    else:
        motion = fcl.CCDMotionType.CCDM_SCREW
    if peer == CA:
        request = fcl.ContinuousCollisionRequest(ccd_motion_type=motion,
                                                 ccd_solver_type=fcl.CCDSolverType.CCDC_CONSERVATIVE_ADVANCEMENT)
    else:  # t = k / N, k = 0..N (peers.make_fcl_objects)
        request = fcl.ContinuousCollisionRequest(num_max_iterations=peer + 1, toc_err=0.5 / peer,
                                                 ccd_motion_type=motion,
                                                 ccd_solver_type=fcl.CCDSolverType.CCDC_NAIVE)
    return (objects[0], ends[0], objects[1], ends[1], request, fcl.ContinuousCollisionResult())


def _fcl_answer(fcl, args):
    result = fcl.ContinuousCollisionResult()
    fcl.continuousCollide(*args[:5], result)
    return float(result.time_of_contact) if result.is_collide else None


# ----------------------------------------------------------------------------- the run


def _fastest_us(call, args, repeats):
    best = math.inf
    for _ in range(repeats):
        t0 = time.perf_counter()
        call(*args)
        best = min(best, time.perf_counter() - t0)
    return 1e6 * best


def _mjccd_answer(case):
    """Fill the case's answer, certainty and tier from one (warming) call."""
    try:
        c = geom_first_contact(*case.args)
        out, _ = solve_geoms(*case.args)
    except Exception as exc:  # a failure is a wrong answer of the row, not the end of the run
        case.answer = f"error: {type(exc).__name__}: {exc}"
        return False
    case.answer = None if c is None else float(c.time)
    case.certified = c is None or c.certainty == "certified"
    case.bracket = None if case.certified else tuple(map(float, c.bracket))
    case.tier = int(out[kn.TIER]) if out[kn.FAILED] in (0.0, kn.PARTIAL) else None
    return True


def run(cases, repeats, fcl_samples, rotating_motion="screw", progress=True):
    """Answer and time every case with mjccd and each fcl peer, interleaved case by case; returns the peers
    run (CA first, then the naive Ns), or [] without python-fcl."""
    have_fcl = peers.fcl_available()
    fcl = None
    if have_fcl:
        import fcl
    keys = ([CA] + list(fcl_samples)) if have_fcl else []
    for case in tqdm(cases, desc="bench geoms", unit="case", disable=not (progress and sys.stderr.isatty())):
        if _mjccd_answer(case):
            case.us = _fastest_us(geom_first_contact, case.args, repeats)
        for key in keys:
            if key == CA and ca_unsupported(case.pair):
                continue
            args = fcl_setup(fcl, case, key, rotating_motion)
            answer = _fcl_answer(fcl, args)
            fcl.continuousCollide(*args)  # warm, on the result timed below (a reused result only accumulates)
            case.fcl[key] = (answer, _fastest_us(fcl.continuousCollide, args, repeats))
    return keys


def is_wrong(got, ref):
    """Whether an answer (a time, None, or an error's text) is wrong against the reference (a time or None)."""
    if isinstance(got, str):
        return True
    if got is None or ref is None:
        return (got is None) != (ref is None)
    return abs(got - ref) > DT_TOLERANCE


def score(answers, references):
    """Counts against the reference: wrong (further than DT_TOLERANCE, missed, false or an error), missed,
    false, and the median and max abs dt over the cases where both found a contact (None: no such case)."""
    wrong = missed = false = 0
    dts = []
    for got, ref in zip(answers, references):
        if isinstance(got, str):
            wrong += 1
        elif got is None and ref is None:
            continue
        elif got is None:
            missed += 1
            wrong += 1
        elif ref is None:
            false += 1
            wrong += 1
        else:
            dts.append(abs(got - ref))
            wrong += dts[-1] > DT_TOLERANCE
    return {"n": len(references), "wrong": wrong, "missed": missed, "false": false,
            "median_dt": statistics.median(dts) if dts else None, "max_dt": max(dts) if dts else None}


def pair_rows(cases, keys):
    """One dict per pair that has cases (in the order of PAIRS), then one for all pairs together ("all")."""
    groups = [(p, [c for c in cases if c.pair == p]) for p in PAIRS]
    groups = [(p, cs) for p, cs in groups if cs] + [("all", list(cases))]
    rows = []
    for pair, cs in groups:
        times = [c.us for c in cs if c.us is not None]
        kernel = [c for c in cs if c.tier is not None]
        row = {"pair": pair, "n": len(cs), "rotating": sum(c.rotates for c in cs),
               "median_us": statistics.median(times) if times else None, "max_us": max(times) if times else None,
               "certified": sum(c.certified for c in cs), "mjccd": score([c.answer for c in cs],
                                                                          [c.reference for c in cs]),
               "kernel": len(kernel), "double_double": sum(c.tier == 1 for c in kernel),
               "errors": [f"{c.id}: {c.answer}" for c in cs if isinstance(c.answer, str)], "peers": {},
               "wrong_cases": [c for c in cs if is_wrong(c.answer, c.reference)]}
        row["uncertain_wrong"] = sum(not c.certified for c in row["wrong_cases"])
        for key in keys:
            run_on = [c for c in cs if key in c.fcl]
            if not run_on:
                row["peers"][key] = None
                continue
            us = [c.fcl[key][1] for c in run_on]
            straight = [c for c in run_on if not c.rotates]
            mine = [c.us for c in run_on if c.us is not None]
            row["peers"][key] = {
                "n": len(run_on), "median_us": statistics.median(us), "max_us": max(us),
                "mjccd_median_us": statistics.median(mine) if mine else None,  # on the same cases
                "score": score([c.fcl[key][0] for c in run_on], [c.reference for c in run_on]),
                "straight": score([c.fcl[key][0] for c in straight], [c.reference for c in straight])}
        rows.append(row)
    return rows


# ----------------------------------------------------------------------------- report


def _us(value):
    return "–" if value is None else (f"{value:.2f}" if value < 10 else f"{value:.1f}")


def _dt(value):
    return "–" if value is None else ("0" if value == 0.0 else f"{value:.1e}")


def _answer_text(case):
    """mjccd's answer to a case, as the notes under the table give it."""
    if isinstance(case.answer, str):
        return case.answer
    if case.answer is None:
        return "none (certified)" if case.certified else "none"
    if case.certified:
        return f"{case.answer:.9f} (certified)"
    lo, hi = case.bracket
    return f"uncertain in [{lo:.9f}, {hi:.9f}]"


def _peer_name(key):
    return "CA" if key == CA else f"naive N={key}"


def _unsupported_cell(pair, key):
    if key == CA and pair != "all":
        return ca_unsupported(pair) or "–"
    return "–"


def _wrong(s, uncertain=0):
    extra = [f"{s[k]} {k}" for k in ("missed", "false") if s[k]]
    if uncertain:
        extra.append(f"{uncertain} uncertain")
    return f"{s['wrong']}/{s['n']}" + (f" ({', '.join(extra)})" if extra else "")


def mjccd_table(rows):
    """mjccd per pair: time, certified answers, wrong answers, worst abs dt, double-double share."""
    header = ["pair", "cases", "median µs", "max µs", "certified", "wrong", "worst abs dt", "double-double"]
    lines = []
    for r in rows:
        s = r["mjccd"]
        dd = "–" if not r["kernel"] else f"{r['double_double']}/{r['kernel']}"
        lines.append([r["pair"], str(r["n"]), _us(r["median_us"]), _us(r["max_us"]), f"{r['certified']}/{r['n']}",
                      _wrong(s, r["uncertain_wrong"]), _dt(s["max_dt"]), dd])
    return header, lines


def fcl_speed_table(rows, keys):
    """fcl per pair and peer: median and max µs, and the ratio of the medians fcl / mjccd on the same cases."""
    header = ["pair"]
    for key in keys:
        header += [f"{_peer_name(key)} median µs", "max µs", "/ mjccd"]
    lines = []
    for r in rows:
        cells = [r["pair"]]
        for key in keys:
            p = r["peers"][key]
            if p is None:
                cells += [_unsupported_cell(r["pair"], key), "", ""]
                continue
            ratio = "–" if not p["mjccd_median_us"] else f"{p['median_us'] / p['mjccd_median_us']:.2g}×"
            if p["n"] < r["n"]:
                ratio += f" (its {p['n']} cases)"
            cells += [_us(p["median_us"]), _us(p["max_us"]), ratio]
        lines.append(cells)
    return header, lines


def fcl_accuracy_table(rows, keys):
    """fcl per pair and peer: median / max abs dt, wrong answers, and wrong answers where the motions agree."""
    header = ["pair"]
    for key in keys:
        header += [f"{_peer_name(key)} abs dt median / max", "wrong", "translation only: wrong, max abs dt"]
    lines = []
    for r in rows:
        cells = [r["pair"]]
        for key in keys:
            p = r["peers"][key]
            if p is None:
                cells += [_unsupported_cell(r["pair"], key), "", ""]
                continue
            ps, st = p["score"], p["straight"]
            cells += [f"{_dt(ps['median_dt'])} / {_dt(ps['max_dt'])}", _wrong(ps),
                      f"{_wrong(st)}, {_dt(st['max_dt'])}" if st["n"] else "–"]
        lines.append(cells)
    return header, lines


def format_table(header, lines):
    """A markdown table with padded columns (readable as text too); the first column left-aligned."""
    widths = [max(len(row[i]) for row in [header] + lines) for i in range(len(header))]
    out = ["| " + " | ".join(h.ljust(w) for h, w in zip(header, widths)) + " |",
           "| " + " | ".join(("-" * w) if i == 0 else ("-" * (w - 1) + ":") for i, w in enumerate(widths)) + " |"]
    for row in lines:
        out.append("| " + " | ".join(c.ljust(w) if i == 0 else c.rjust(w)
                                     for i, (c, w) in enumerate(zip(row, widths))) + " |")
    return "\n".join(out)


def _versions():
    out = [f"Python {platform.python_version()}", f"numpy {np.__version__}"]
    for dist in ("numba", "python-fcl"):
        try:
            out.append(f"{dist} {importlib.metadata.version(dist)}")
        except importlib.metadata.PackageNotFoundError:
            pass
    return ", ".join(out)


def markdown(rows, keys, info):
    """The section of docs/benchmarks.md: method, command, machine, the tables and notes."""
    lines = ["## MuJoCo shape pairs (`mjccd bench geoms`)", "",
             f"Command: `{info['command']}` ({info['seconds']:.0f} s)  ",
             f"Machine: {platform.machine()}, {os.cpu_count()} cores shared with other jobs, {_versions()}; "
             f"load average {info['load'][0]:.1f} at the start, {info['load'][1]:.1f} at the end", "",
             f"Cases: {info['source']}; {rows[-1]['n']} close pairs ({rows[-1]['rotating']} with a rotating body), "
             "the cases that never come near left out. Reference: MuJoCo's own signed distance "
             "(`mj_geomDistance`, each sign proven by the shapes' geometry, `tests/geoms_reference.py`).", "",
             "Per case, warm, on shapes and motions built beforehand, only the call timed: "
             "`mjccd.geoms.geom_first_contact` through the Python API and python-fcl's `fcl.continuousCollide` "
             f"(prebuilt objects, end transforms, request and result), interleaved case by case; each call runs "
             f"{info['repeats']} times and the fastest run is the case's time. A row gives the median and the max "
             "over the pair's cases in µs. Figures are medians on a shared "
             f"{os.cpu_count()}-core machine and move between runs; compare them within a run.", "",
             "### mjccd", "",
             "Wrong: further than 1e-6 from the reference, a missed or a false contact (an error counts too); "
             "an uncertain answer is its bracket's low end. Double-double: the cases whose first contact needed "
             "the kernel's double-double tier, of those the kernel solved (–: the pair goes to the ellipsoid or "
             "plane solver).", "", format_table(*mjccd_table(rows))]
    wrong = [c for r in rows[:-1] for c in r["wrong_cases"]]
    if wrong:
        lines += ["", "mjccd's wrong answers: " + "; ".join(
            f"`{c.id}` {_answer_text(c)} against {'none' if c.reference is None else f'{c.reference:.9f}'}"
            for c in wrong[:12]) + ("; …" if len(wrong) > 12 else "") + "."]
    errors = [e for r in rows[:-1] for e in r["errors"]]
    if errors:
        lines += ["", "Errors: " + "; ".join(errors) + "."]
    slow = sorted((r for r in rows[:-1] if r["median_us"] is not None), key=lambda r: -r["median_us"])[:3]
    if slow:
        lines += ["", "Slowest pairs (median): " + ", ".join(f"{r['pair']} {_us(r['median_us'])} µs"
                                                             for r in slow) + "."]
    lines += ["", "### python-fcl `continuousCollide`", ""]
    if not keys:
        lines.append(f"Not measured: {peers.FCL_SKIP_MESSAGE}.")
        return "\n".join(lines) + "\n"
    motion = ("`CCDM_LINEAR` (lerp + slerp, as asked with `--fcl-motion linear`)" if info["rotating_motion"] ==
              "linear" else "`CCDM_SCREW` (the orientations of a slerp, the centre on a helix; FCL 0.7's "
              "`CCDM_LINEAR`, lerp + slerp, leaves its reference point uninitialised, see `mjccd/bench/peers.py`)")
    lines += ["Shapes: `Sphere`, `Capsule(r, 2h)` and `Cylinder(r, 2h)` (axis local z as in MuJoCo, but the full "
              "length), `Box` (full sizes), `Ellipsoid`, and `Halfspace((0, 0, 1), 0)` at the plane's pose for "
              "MuJoCo's plane. CA: conservative advancement (GJK distances and motion bounds), which FCL 0.7 "
              "does not offer for ellipsoids (it prints \"not supported\" and reports no contact) and which "
              "crashes the process (segmentation fault) on half-spaces and planes, so those pairs are not run; "
              "naive N: the discrete `collide` at t = k / N. Motions: `CCDM_TRANS` when neither body rotates "
              f"(exactly mjccd's rigid motion), else {motion}. On rotating pairs fcl's motion is not mjccd's, so "
              "its dt there mixes the two motions' difference with its solver's error; 'translation only' "
              "counts the cases where the motions agree exactly. Ratios: fcl's median over mjccd's on the same "
              "cases (below 1: fcl is faster).", ""]
    if info.get("linear_check") is not None:
        lines += [f"fcl `CCDM_LINEAR` self-check (translation-only queries against `CCDM_TRANS`): "
                  f"{'passed' if info['linear_check'] else 'FAILED'}.", ""]
    lines += [format_table(*fcl_speed_table(rows, keys)), "",
              "Accuracy against the same reference (abs dt over the cases where both found a contact; wrong as "
              "for mjccd).", "", format_table(*fcl_accuracy_table(rows, keys))]
    return "\n".join(lines) + "\n"


def _load(parser, args):
    """(cases, results, description of the source) from the options."""
    if args.cases or args.quick:
        if args.cases:
            cases_path, expected_path = args.cases, args.expected
        else:
            cases_path, expected_path = (_locate(p) for p in HELDOUT)
            if cases_path is None or expected_path is None:
                parser.error(f"--quick: {HELDOUT[0]} is not part of the installed package; pass --cases and "
                             f"--expected with their paths in a checkout of the mjccd source repository")
        try:
            with open(cases_path) as fh:
                cases = json.load(fh)["cases"]
            with open(expected_path) as fh:
                results = json.load(fh)["results"]
        except (OSError, ValueError, KeyError, TypeError) as exc:
            parser.error(f"--cases/--expected: cannot read {cases_path} and {expected_path}: {exc}")
        return cases, results, (f"`{options.shown(cases_path)}`, up to {args.per_pair} close cases per pair")
    try:
        cases, results = generated_set(args.seed, args.per_pair, args.jobs, log=lambda s: print(s, file=sys.stderr))
    except FileNotFoundError as exc:
        parser.error(f"{exc}; pass --cases and --expected, or run with --quick")
    return cases, results, (f"drawn by `{GENERATOR} --seed {args.seed} --per-pair "
                            f"{_generated_per_pair(args.per_pair)}`, the first {args.per_pair} close cases of "
                            "each pair")


def main(argv=None):
    parser = argparse.ArgumentParser(formatter_class=PlainHelpFormatter,
                                     prog="mjccd bench geoms", description=__doc__.splitlines()[0])
    parser.add_argument("--cases", help="cases in the case format (default: a set drawn by " + GENERATOR + ")")
    parser.add_argument("--expected", help="their reference answers (with --cases)")
    parser.add_argument("--seed", type=int, default=DEFAULT_SEED, help=f"seed of the drawn set (default "
                                                                       f"{DEFAULT_SEED})")
    parser.add_argument("--per-pair", type=int, default=DEFAULT_PER_PAIR,
                        help=f"close cases per shape pair (default {DEFAULT_PER_PAIR})")
    parser.add_argument("--repeats", type=int, default=7, help="runs of each call; the fastest counts (default 7)")
    parser.add_argument("--fcl-samples", type=int, nargs="+", default=[100, 1000],
                        help="N of fcl's naive solver, t = k / N (default 100 1000)")
    parser.add_argument("--fcl-motion", choices=("screw", "linear"), default="screw",
                        help="fcl's motion for rotating pairs (default screw; translation-only pairs: CCDM_TRANS)")
    parser.add_argument("--jobs", type=int, default=min(os.cpu_count() or 1, 8),
                        help="processes drawing the case set (default: the cores, at most 8)")
    parser.add_argument("--markdown", metavar="FILE", help="write the tables into this markdown file")
    options.add_quick(parser, QUICK)
    args = options.parse(parser, argv, QUICK)
    options.check_ranges(parser, args, RANGES)
    if (args.cases is None) != (args.expected is None):
        parser.error("--cases and --expected go together")
    options.check_markdown(parser, args.markdown, [p for p in (args.cases, args.expected) if p])
    t0, load0 = time.perf_counter(), os.getloadavg()[0]
    cases, results, source = _load(parser, args)
    chosen = select_cases(cases, results, args.per_pair)
    keys = run(chosen, args.repeats, args.fcl_samples, args.fcl_motion)
    rows = pair_rows(chosen, keys)
    linear_check = None
    if keys and args.fcl_motion == "linear":
        linear_check = peers.fcl_linear_motion_is_sane()
    command = "mjccd bench geoms" + ("" if argv is None else " " + " ".join(argv))
    info = {"command": command, "seconds": time.perf_counter() - t0, "load": (load0, os.getloadavg()[0]),
            "source": source, "repeats": args.repeats, "rotating_motion": args.fcl_motion,
            "linear_check": linear_check}
    text = markdown(rows, keys, info)
    print(text)
    if args.markdown:
        write_section(args.markdown, "geoms", text)
        print(f"written to {args.markdown}")
    return 0
