"""Exact first contact of MuJoCo's primitive shapes (mjccd.geoms), against independent answers.

* 150 held-out cases of every shape pair (tests/data/geoms_heldout_s11*.json) and past failures
  (tests/data/geoms_regressions*.json), graded by MuJoCo's own signed distance with each sign proven by the
  shapes' geometry (tests/geoms_reference.py);
* closed forms and a 50-digit brute force (mpmath) of the distance between the shapes along the motion;
* invariance under a far translation, grazes that must never be certified as contacts, errors naming the field.
"""
import json
import math
import pathlib

import mpmath
import numpy as np
import pytest

import mjccd
from mjccd.cases import solve_cases
from mjccd.geoms import Box, Capsule, Cylinder, HalfSpace, Sphere, geom_first_contact
from mjccd.geoms.solve import geom_collision_intervals

DATA = pathlib.Path(__file__).parent / "data"
IDENTITY = [1.0, 0.0, 0.0, 0.0]


def _size(shape):
    kind = shape["type"]
    if kind == "plane":
        return 0.0
    if kind == "sphere":
        return shape["radius"]
    if kind in ("capsule", "cylinder"):
        return shape["radius"] + shape["half_length"]
    if kind == "box":
        return float(np.linalg.norm(shape["half_sizes"]))
    return max(shape["radii"])


@pytest.mark.parametrize("name, count", [("geoms_heldout_s11", 150), ("geoms_regressions", 3)])
def test_reference_cases_right_and_certified(name, count):
    cases = json.loads((DATA / f"{name}.json").read_text())
    expected = {e["id"]: e for e in json.loads((DATA / f"{name}_expected.json").read_text())["results"]}
    results = solve_cases(cases)["results"]
    by_case = {c["id"]: c for c in cases["cases"]}
    assert len(results) == len(expected) == count
    for r in results:
        e, c = expected[r["id"]], by_case[r["id"]]
        assert "error" not in r, r
        assert r["certainty"] == "certified", r["id"]
        assert r["status_at_start"] == e["status_at_start"], r["id"]
        if e["first_contact"] is None:
            assert r["first_contact"] is None, r["id"]
            continue
        assert abs(r["first_contact"] - e["first_contact"]) <= 1e-6, r["id"]
        if e["contact_point"] is not None and e["first_contact"] > 0.0:
            size = max(_size(c["a"]["shape"]), _size(c["b"]["shape"]))
            assert np.linalg.norm(np.subtract(r["contact_point"], e["contact_point"])) <= 1e-5 * size, r["id"]


# ---------------------------------------------------------------- closed forms and a 50-digit brute force


def test_spheres_closed_form():
    # centres 4 apart closing at speed 4 (a from -2 to 2), radii 0.5 each: contact at t = (4 - 1) / 4 / ... = 0.25
    c = geom_first_contact(Sphere(0.5), mjccd.Rigid([-2, 0, 0], IDENTITY, [2, 0, 0], IDENTITY),
                           Sphere(0.5), mjccd.Static([0, 0, 0], IDENTITY))
    assert c.certainty == "certified" and abs(c.time - 0.25) <= 1e-12
    assert np.allclose(c.point, [-0.5, 0, 0], atol=1e-12) and np.allclose(c.normal, [1, 0, 0], atol=1e-12)


@pytest.mark.parametrize("shape, low", [(Sphere(0.3), 0.3), (Capsule(0.2, 0.5), 0.7), (Box([0.1, 0.2, 0.3]), 0.3),
                                        (Cylinder(0.25, 0.4), 0.4)])
def test_falling_onto_a_plane(shape, low):
    """An upright shape falling straight from height 2 to -1 reaches z <= 0 of the floor when its lowest point
    does: at t = (2 - low) / 3."""
    c = geom_first_contact(shape, mjccd.Rigid([0.3, -0.2, 2.0], IDENTITY, [0.3, -0.2, -1.0], IDENTITY),
                           HalfSpace(), mjccd.Static([0, 0, 0], IDENTITY))
    assert c.certainty == "certified" and abs(c.time - (2.0 - low) / 3.0) <= 1e-12
    assert abs(c.point[2]) <= 1e-12 and np.allclose(c.normal, [0, 0, -1], atol=1e-12)
    assert c.elements[1] == "plane"


def _rot(q):
    w, x, y, z = q
    return mpmath.matrix([[1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
                          [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
                          [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]])


def _pose(p0, q0, p1, q1, t):
    """Position and rotation of the rigid lerp at t, in 50 digits (the motion's own definition)."""
    t = mpmath.mpf(t)
    s = 1 if sum(a * b for a, b in zip(q0, q1)) >= 0 else -1
    q = [(1 - t) * mpmath.mpf(a) + t * s * mpmath.mpf(b) for a, b in zip(q0, q1)]
    n = mpmath.sqrt(sum(x * x for x in q))
    return mpmath.matrix([(1 - t) * mpmath.mpf(a) + t * mpmath.mpf(b) for a, b in zip(p0, p1)]), \
        _rot([x / n for x in q])


def _segment_distance(a0, a1, b0, b1):
    """Distance between two segments (mpmath), by the closest points over the parameter square's candidates."""
    d1, d2, r = a1 - a0, b1 - b0, a0 - b0
    a, e, f = (d1.T * d1)[0], (d2.T * d2)[0], (d2.T * r)[0]
    c, b = (d1.T * r)[0], (d1.T * d2)[0]

    def clamp(x):
        return min(max(x, mpmath.mpf(0)), mpmath.mpf(1))

    cands = []
    den = a * e - b * b
    if den > 0:
        s = clamp((b * f - c * e) / den)
        cands.append((s, clamp((b * s + f) / e)))
    for end in (mpmath.mpf(0), mpmath.mpf(1)):
        cands += [(end, clamp((b * end + f) / e)), (clamp((b * end - c) / a), end)]
    return min(mpmath.norm(r + s * d1 - u * d2) for s, u in cands)


def _capsule_gap(ca, ma, cb, mb, t):
    pa, Ra = _pose(*ma, t)
    pb, Rb = _pose(*mb, t)
    ea = Ra * mpmath.matrix([0, 0, ca[1]])
    eb = Rb * mpmath.matrix([0, 0, cb[1]])
    return _segment_distance(pa - ea, pa + ea, pb - eb, pb + eb) - ca[0] - cb[0]


def _first_root(gap, n=400):
    """The first t in [0, 1] where gap(t) <= 0: a scan, then bisection to 1e-30."""
    prev = mpmath.mpf(0)
    if gap(prev) <= 0:
        return 0.0
    for k in range(1, n + 1):
        t = mpmath.mpf(k) / n
        if gap(t) <= 0:
            lo, hi = prev, t
            for _ in range(100):
                mid = (lo + hi) / 2
                lo, hi = (lo, mid) if gap(mid) <= 0 else (mid, hi)
            return float(hi)
        prev = t
    return None


@pytest.mark.parametrize("seed", range(6))
def test_capsules_against_a_50_digit_brute_force(seed):
    """Random rotating capsules: the first time their axes come within the sum of the radii, found by a dense
    scan and bisection in 50-digit arithmetic on the motion's own definition."""
    mpmath.mp.dps = 50
    rng = np.random.default_rng(seed)

    def unit(v):
        return list(v / np.linalg.norm(v))

    ca, cb = (0.1 + 0.1 * rng.random(), 0.2 + 0.3 * rng.random()), (0.1 + 0.1 * rng.random(), 0.2 + 0.3 * rng.random())
    qa0 = unit(rng.normal(size=4))
    qa1 = unit(np.array(qa0) + 0.4 * rng.normal(size=4))
    qb = unit(rng.normal(size=4))
    ma = ([-1.2, 0.1 * rng.normal(), 0.1 * rng.normal()], qa0, [0.4, 0.1 * rng.normal(), 0.1 * rng.normal()], qa1)
    mb = ([0.0, 0.0, 0.0], qb, [0.0, 0.0, 0.0], qb)
    c = geom_first_contact(Capsule(*ca), mjccd.Rigid(*ma), Capsule(*cb), mjccd.Rigid(*mb))
    truth = _first_root(lambda t: _capsule_gap(ca, ma, cb, mb, t))
    if truth is None:
        assert c is None
        return
    assert c is not None and c.certainty == "certified"
    assert abs(c.time - truth) <= 1e-9
    # the point lies on both surfaces
    assert abs(float(_capsule_gap(ca, ma, cb, mb, c.time))) <= 1e-9


# ---------------------------------------------------------------- invariances, grazes, errors


@pytest.mark.parametrize("kind", ["capsule-box", "box-box", "cylinder-box", "capsule-capsule"])
def test_far_from_the_origin(kind):
    """Both bodies translated by 1e6 sizes: the same first contact (within the rounding of the moved inputs)."""
    cases = json.loads((DATA / "geoms_heldout_s11.json").read_text())["cases"]
    case = next(c for c in cases if c["id"].startswith(kind + "-") and "translate" in c["id"])
    far = json.loads(json.dumps(case))
    for body in ("a", "b"):
        m = far[body]["motion"]
        for pose in ([m] if m["type"] == "static" else [m["start"], m["end"]]):
            pose["position"] = [x + 1e6 for x in pose["position"]]
    near, moved = solve_cases({"version": 1, "cases": [case, far]})["results"]
    assert near["certainty"] == moved["certainty"] == "certified"
    assert (near["first_contact"] is None) == (moved["first_contact"] is None)
    if near["first_contact"] is not None:
        assert abs(near["first_contact"] - moved["first_contact"]) <= 1e-6


@pytest.mark.parametrize("clearance", [1e-3, 1e-6, 1e-9, 1e-12])
def test_grazes_never_certified_as_contacts(clearance):
    """A sphere passing a box's edge by ``clearance`` (relative to the size): no certified contact; the same
    sphere passing as deep inside it first touches the edge's end vertex, at z + 1 = -r sqrt(2c - c^2):
    certified while the root is simple enough for doubles, else flagged with a bracket that holds it."""
    r = 0.5
    for sign in (1.0, -1.0):
        # the sphere's centre passes the edge (x = 1, y = 1) along z at distance r (1 + sign clearance)
        d = r * (1.0 + sign * clearance) / math.sqrt(2.0)
        start, end = [1.0 + d, 1.0 + d, -3.0], [1.0 + d, 1.0 + d, 3.0]
        c = geom_first_contact(Sphere(r), mjccd.Rigid(start, IDENTITY, end, IDENTITY), Box([1.0, 1.0, 1.0]),
                               mjccd.Static([0, 0, 0], IDENTITY))
        if sign > 0:
            assert c is None or c.certainty == "uncertain", c
            continue
        depth = r * math.sqrt(2.0 * clearance - clearance * clearance)
        exact = (2.0 - depth) / 6.0
        assert c is not None, clearance
        if c.certainty == "certified":
            assert abs(c.time - exact) <= 1e-9
        else:
            assert c.bracket[0] <= exact + 1e-12 and exact - 1e-12 <= c.bracket[1], (c, exact)
        if clearance >= 1e-6:
            assert c.certainty == "certified"


def test_intervals_of_a_pass_through():
    """A sphere passing straight through a box: one interval, from entry to exit."""
    iv, certified = geom_collision_intervals(Sphere(0.5), mjccd.Rigid([-4, 0, 0], IDENTITY, [4, 0, 0], IDENTITY),
                                             Box([1, 1, 1]), mjccd.Static([0, 0, 0], IDENTITY))
    assert certified and len(iv) == 1
    assert abs(iv[0][0] - 2.5 / 8) <= 1e-9 and abs(iv[0][1] - 5.5 / 8) <= 1e-9


def test_bad_shapes_name_the_field_and_the_rest_is_solved():
    good = {"id": "ok", "a": {"shape": {"type": "sphere", "radius": 0.5},
                               "motion": {"type": "rigid", "start": {"position": [-2, 0, 0], "quaternion": IDENTITY},
                                          "end": {"position": [2, 0, 0], "quaternion": IDENTITY}}},
            "b": {"shape": {"type": "box", "half_sizes": [0.5, 0.5, 0.5]},
                  "motion": {"type": "static", "position": [0, 0, 0], "quaternion": IDENTITY}}}
    bad = []
    for k, (where, value) in enumerate([("type", "cone"), ("radius", -1.0), ("half_sizes", [1, 2]),
                                        ("half_length", "long")]):
        case = json.loads(json.dumps(good))
        case["id"] = f"bad{k}"
        shape = {"type": "capsule", "radius": 0.1, "half_length": 0.3}
        shape[where] = value
        if where == "half_sizes":
            shape = {"type": "box", "half_sizes": value}
        case["a"]["shape"] = shape
        bad.append(case)
    plane_moving = json.loads(json.dumps(good))
    plane_moving["id"] = "moving-plane"
    plane_moving["a"]["shape"] = {"type": "plane"}
    results = {r["id"]: r for r in solve_cases({"version": 1, "cases": [*bad, good, plane_moving]})["results"]}
    assert results["ok"]["first_contact"] == pytest.approx(0.25, abs=1e-12)
    assert "a.shape.type" in results["bad0"]["error"]
    assert "a.shape.radius" in results["bad1"]["error"]
    assert "a.shape.half_sizes" in results["bad2"]["error"]
    assert "a.shape.half_length" in results["bad3"]["error"]
    assert "a.motion" in results["moving-plane"]["error"] and "static" in results["moving-plane"]["error"]


def test_elements_name_where_they_touch():
    """A box turned 45 degrees about x (an edge along x points down) falls onto a box turned 45 degrees about y
    (an edge along y points up): edge across edge, at z_a - 0.5 sqrt(2) = sqrt(2)."""
    qa = [math.cos(math.pi / 8), math.sin(math.pi / 8), 0.0, 0.0]
    qb = [math.cos(math.pi / 8), 0.0, math.sin(math.pi / 8), 0.0]
    c = geom_first_contact(Box([0.5, 0.5, 0.5]), mjccd.Rigid([0, 0, 3.0], qa, [0, 0, 0.0], qa),
                           Box([1.0, 1.0, 1.0]), mjccd.Static([0, 0, 0], qb))
    assert c.certainty == "certified"
    assert abs(c.time - (3.0 - 1.5 * math.sqrt(2.0)) / 3.0) <= 1e-12
    assert np.allclose(c.point, [0, 0, math.sqrt(2.0)], atol=1e-9)
    assert c.elements[0].startswith("edge") and "along x" in c.elements[0]
    assert c.elements[1].startswith("edge") and "along y" in c.elements[1]
    # a box landing flat on an edge touches along it: an end vertex of the edge is as good a witness
    c = geom_first_contact(Box([0.5, 0.5, 0.5]), mjccd.Rigid([0, 0, 3.0], qa, [0, 0, 0.0], qa),
                           Box([2.0, 2.0, 1.0]), mjccd.Static([0, 0, 0], IDENTITY))
    assert c.certainty == "certified" and abs(c.time - (2.0 - 0.5 * math.sqrt(2.0)) / 3.0) <= 1e-12
    assert c.elements[0].split()[0] in ("edge", "vertex") and c.elements[1] == "face +z"


# ---------------------------------------------------------------- the scanners and intervals


@pytest.mark.parametrize("offset", [-0.5, 0.5])
def test_a_constraint_within_its_bound_of_zero_is_never_proven_either_way(offset):
    """A bivariate constraint that stays within its error bound of zero everywhere: neither a contact nor its
    absence is proven (the point proof needs the value below minus the bound)."""
    from mjccd.geoms import scan

    err = 1e-12
    C = np.full((1, 3, 4), offset * err)
    lo, hi, _, _, _ = scan.bfirst_time(C, np.array([2]), np.array([3]), np.array([err]), 1.0)
    assert lo == 0.0 and hi < 0.0


@pytest.mark.parametrize("turn", [0.0, 0.3])
def test_intervals_of_a_cylinder_passing_through_another_are_certified(turn):
    """A cylinder (radius 0.2, half length 0.3, turned about x) crosses a wider, taller one (radius 0.5, half
    length 0.5) along x, 0.1 off its axis, all of it within the wide one's height: they touch when the narrow
    one's shadow on the xy plane (its rim's ellipse swept along its axis' shadow) meets the disk of radius 0.5;
    a brute force over that shadow gives both ends."""
    q = [math.cos(turn / 2), math.sin(turn / 2), 0.0, 0.0]
    iv, certified = geom_collision_intervals(Cylinder(0.2, 0.3), mjccd.Rigid([-2, 0.1, 0], q, [2, 0.1, 0], q),
                                             Cylinder(0.5, 0.5), mjccd.Static([0, 0, 0], IDENTITY))
    p, u = np.meshgrid(np.linspace(0.0, 2.0 * np.pi, 4001), np.linspace(-1.0, 1.0, 401))
    x = 0.2 * np.cos(p)
    y = 0.1 + 0.2 * math.cos(turn) * np.sin(p) + 0.3 * math.sin(turn) * u
    reach = np.max(x + np.sqrt(np.maximum(0.25 - y * y, 0.0)))
    t_in, t_out = (2.0 - reach) / 4.0, (2.0 + reach) / 4.0
    assert certified and len(iv) == 1
    assert abs(iv[0][0] - t_in) <= 1e-6 and abs(iv[0][1] - t_out) <= 1e-6


def test_the_contact_point_lies_on_both_surfaces():
    """Random turning pairs of every primitive: each certified first contact's point lies on both shapes'
    surfaces (their exact signed distances, tests/geoms_reference.py).  A circle's witness taken at s = 1/2
    put it up to 0.14 off both rims on about one pair in ten that met rim to rim."""
    from geoms_reference import _prepared, local_sdf
    from mjccd.quadric import quat_to_matrix

    rng = np.random.default_rng(29)
    kinds = {"sphere": lambda r: (Sphere(r[0]), {"type": "sphere", "radius": r[0]}),
             "capsule": lambda r: (Capsule(r[0], r[1]), {"type": "capsule", "radius": r[0], "half_length": r[1]}),
             "cylinder": lambda r: (Cylinder(r[0], r[1]), {"type": "cylinder", "radius": r[0], "half_length": r[1]}),
             "box": lambda r: (Box(r), {"type": "box", "half_sizes": list(r)}),
             "ellipsoid": lambda r: (mjccd.Ellipsoid(r), {"type": "ellipsoid", "radii": list(r)})}

    def unit(v):
        return v / np.linalg.norm(v)

    checked = 0
    for n in range(300):
        names = list(kinds)
        (ga, da), (gb, db) = (kinds[names[rng.integers(5)]](rng.uniform(0.2, 0.6, 3)) for _ in range(2))
        d = unit(rng.normal(size=3))
        ends = [(rng.uniform(-0.2, 0.2, 3), unit(rng.normal(size=4)), rng.uniform(-0.2, 0.2, 3),
                 unit(rng.normal(size=4))),
                (d * 2.5 + rng.uniform(-0.3, 0.3, 3), unit(rng.normal(size=4)), -d * 0.5 + rng.uniform(-0.3, 0.3, 3),
                 unit(rng.normal(size=4)))]
        motions = [mjccd.Rigid(*e) for e in ends]
        c = geom_first_contact(ga, motions[0], gb, motions[1])
        if c is None or c.certainty != "certified" or c.time == 0.0:
            continue
        for shape, m in ((da, motions[0]), (db, motions[1])):
            q = (1 - c.time) * m.quaternion0 + c.time * m.quaternion1
            p = (1 - c.time) * m.position0 + c.time * m.position1
            local = quat_to_matrix(q / np.linalg.norm(q)).T @ (c.point - p)
            assert abs(local_sdf(_prepared(shape), local)) <= 1e-7, (n, shape, c)
        checked += 1
    assert checked >= 200


@pytest.mark.parametrize("slots, degree", [(24, 96), (16384, 3)])
def test_a_workspace_too_small_is_an_overflow_never_an_answer(slots, degree):
    """A capsule against a box in a workspace with too few slots, or too low a degree: the kernel answers
    OVERFLOW (the Python API raises naming the workspace), and a workspace of the usual size afterwards still
    gives the usual answer."""
    from mjccd.geoms import frames as fr
    from mjccd.geoms import kernel as kn
    from mjccd.geoms import poly as P
    from mjccd.geoms import systems as sy

    def rows(p0, p1, q1):
        r = np.zeros((1, fr.ELEMENT_FIELDS))
        r[0, 0] = fr.POSE
        r[0, 1:4], r[0, 4:8], r[0, 8:11], r[0, 11:15] = p0, IDENTITY, p1, q1
        return r

    ra = rows([-1.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.98, 0.0, 0.2, 0.0])
    rb = rows([0.0, 0.0, 0.0], [0.0, 0.0, 0.0], IDENTITY)
    args = (sy.CAPSULE, np.array([0.1, 0.3, 0.0]), ra, sy.BOX, np.array([0.2, 0.2, 0.2]), rb, 1.0)
    small = (*P.workspace(slots, degree), *P.workspace(slots, degree, True), *sy.new_store(1024, 8192))
    out = np.zeros(kn.OUT)
    kn.pair_kernel(*args, *small, out)
    assert out[kn.FAILED] == kn.OVERFLOW
    from mjccd.geoms.solve import workspaces
    kn.pair_kernel(*args, *workspaces(), out)
    assert out[kn.FAILED] == 0.0 and out[kn.CERTIFIED] == 1.0 and 0.0 < out[kn.TIME] < 1.0
