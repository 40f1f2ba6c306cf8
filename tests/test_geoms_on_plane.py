"""A sphere or capsule against a static plane by the written-out systems (mjccd.geoms.on_plane).

* the constraints' Bernstein coefficients and error bounds against the same constraint in 60 digits;
* every answer against the general path's (the systems built in the polynomial workspace), grazes included;
* a rotating capsule against a 50-digit brute force of its lowest point's height, and grazes of the plane that
  must never be certified as contacts.
"""
import math
import os
import sys

import mpmath
import numpy as np
import pytest

import mjccd
from mjccd.geoms import Capsule, HalfSpace, Sphere, geom_first_contact
from mjccd.geoms import frames as fr
from mjccd.geoms import kernel as kn
from mjccd.geoms import on_plane as op
from mjccd.geoms import systems as sy
from mjccd.geoms.solve import workspaces

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from make_reference import rot_matrix  # noqa: E402  (the rotation of an unnormalised quaternion, any number type)


def _unit(v):
    return v / np.linalg.norm(v)


def _rows(p0, q0, p1, q1):
    row = np.zeros((1, fr.ELEMENT_FIELDS))
    row[0, 0] = fr.POSE
    row[0, 1:4], row[0, 4:8], row[0, 8:11], row[0, 11:15] = p0, q0, p1, q1
    return row


def _random_pair(rng, kind, graze=False):
    """(kind, size, geom rows, plane rows) of a random geom moving by a rigid lerp near a random plane; with
    ``graze`` its last pose (not turning) has its lowest point at a tiny height above or below the plane."""
    qp = _unit(rng.normal(size=4))
    n = np.array(rot_matrix(qp))[:, 2]
    o = rng.normal(size=3) * 0.5
    size = np.array([rng.uniform(0.01, 0.3), rng.uniform(0.01, 0.5) if kind == sy.CAPSULE else 0.0, 0.0])
    q0 = _unit(rng.normal(size=4))
    q1 = _unit(q0 + rng.normal(size=4) * rng.choice([0.0, 0.05, 0.5]))
    q1 = q1 if q0 @ q1 >= 0 else -q1
    c0 = o + n * rng.uniform(0.0, 1.0) + rng.normal(size=3) * 0.3
    c1 = c0 + rng.normal(size=3) * 0.3 - n * rng.uniform(0.0, 0.8)
    if graze:
        q1 = q0.copy()
        low = size[0] + size[1] * abs(n @ np.array(rot_matrix(q0))[:, 2])
        c1 = c1 + n * (low + rng.choice([0.0, 1e-12, -1e-12, 1e-9, 1e-6]) - n @ (c1 - o))
    return kind, size, _rows(c0 - c0, q0, c1 - c0, q1), _rows(o - c0, qp, o - c0, qp)


def _bernstein(c, t):
    n = len(c) - 1
    return sum(mpmath.binomial(n, i) * c[i] * t ** i * (1 - t) ** (n - i) for i in range(n + 1))


@pytest.mark.parametrize("seed", range(4))
def test_written_out_constraints_lie_within_their_bounds(seed):
    """Each constraint's double coefficients, evaluated in 60 digits, differ from the module docstring's g
    (times 3 for a capsule) evaluated in 60 digits on the same inputs by no more than its bound, at many times;
    inputs of mixed scales, far offsets included."""
    mpmath.mp.dps = 60
    rng = np.random.default_rng(seed)
    for trial in range(40):
        kind = sy.SPHERE if trial % 3 == 0 else sy.CAPSULE
        k, size, rg, rp = _random_pair(rng, kind)
        scale = 10.0 ** rng.integers(-3, 4)
        rg[0, [1, 2, 3, 8, 9, 10]] *= scale
        rp[0, [1, 2, 3, 8, 9, 10]] *= scale
        size[:2] *= scale
        C, DT, errs = np.zeros((2, 1, 4)), np.zeros(2, dtype=np.int64), np.zeros(2)
        SYS, N, ends = np.zeros((2, sy.SYS_FIELDS), dtype=np.int64), np.zeros(3, dtype=np.int64), np.zeros(2)
        op.systems(k, size, rg, sy.PLANE, np.zeros(3), rp, C, DT, errs, SYS, N, ends)
        m = [mpmath.mpf(float(x)) for x in rp[0]]
        qp, o = m[4:8], m[1:4]
        w, x, y, z = qp
        mv = [2 * (x * z + w * y), 2 * (y * z - w * x), w * w - x * x - y * y + z * z]
        p2 = sum(v * v for v in qp)
        g = [mpmath.mpf(float(v)) for v in rg[0]]
        r, h = mpmath.mpf(float(size[0])), mpmath.mpf(float(size[1]))
        for j in range(N[1]):
            for t in [mpmath.mpf(i) / 16 for i in range(17)]:
                c = [(1 - t) * g[1 + i] + t * g[8 + i] for i in range(3)]
                q = [(1 - t) * g[4 + i] + t * g[11 + i] for i in range(4)]
                height = sum(mv[i] * (c[i] - o[i]) for i in range(3)) - r * p2
                if kind == sy.SPHERE:
                    exact = height
                else:
                    q2 = sum(v * v for v in q)
                    R = rot_matrix(q)
                    axis = sum(mv[i] * R[i][2] * q2 for i in range(3))
                    exact = 3 * (q2 * height + mpmath.mpf(float(ends[j])) * axis)
                value = _bernstein([mpmath.mpf(float(v)) for v in C[j, 0, :DT[j] + 1]], t)
                assert abs(value - exact) <= errs[j], (seed, trial, j, float(t))
            assert abs(ends[j]) == (0.0 if kind == sy.SPHERE else size[1])


@pytest.mark.parametrize("seed", range(3))
def test_the_same_answers_as_the_general_path(seed):
    """Random spheres and capsules near random planes, a third of them grazing at the end of the step: the
    same status, the same contact or none, times within 2e-9, the same point, normal and elements; where one
    is uncertain, the other's time lies in its bracket."""
    rng = np.random.default_rng(100 + seed)
    ws = workspaces()
    fast, general = np.zeros(kn.OUT), np.zeros(kn.OUT)
    contacts = 0
    for trial in range(300):
        kind, size, rg, rp = _random_pair(rng, sy.SPHERE if trial % 2 else sy.CAPSULE, graze=trial % 3 == 0)
        plane_first = trial % 4 < 2
        args = ((sy.PLANE, np.zeros(3), rp, kind, size, rg) if plane_first else
                (kind, size, rg, sy.PLANE, np.zeros(3), rp))
        assert op.applies(*args)
        kn.pair_kernel(*args, 1.0, *ws, fast)
        kn.general_kernel(*args, 1.0, *ws, general)
        assert fast[kn.STATUS] == general[kn.STATUS], trial
        assert (fast[kn.LO] < 0.0) == (general[kn.LO] < 0.0), trial
        if fast[kn.STATUS] != 1.0 or fast[kn.LO] < 0.0:
            continue
        contacts += 1
        if fast[kn.CERTIFIED] and general[kn.CERTIFIED]:
            assert abs(fast[kn.TIME] - general[kn.TIME]) <= 2e-9, trial
            assert np.allclose(fast[kn.POINT:kn.POINT + 3], general[kn.POINT:kn.POINT + 3], atol=1e-7), trial
            assert np.allclose(fast[kn.NORMAL:kn.NORMAL + 3], general[kn.NORMAL:kn.NORMAL + 3], atol=1e-7), trial
            assert fast[kn.ELEM_A] == general[kn.ELEM_A] and fast[kn.ELEM_B] == general[kn.ELEM_B], trial
        else:
            assert (general[kn.LO] - 1e-12 <= fast[kn.TIME] <= general[kn.HI] + 1e-12
                    or fast[kn.LO] - 1e-12 <= general[kn.TIME] <= fast[kn.HI] + 1e-12), trial
    assert contacts > 60


def _identity_turned(angle):
    """The quaternion of a turn by ``angle`` about x."""
    return [math.cos(angle / 2), math.sin(angle / 2), 0.0, 0.0]


@pytest.mark.parametrize("seed", range(4))
def test_a_rotating_capsule_against_a_50_digit_brute_force(seed):
    """A capsule falling and turning onto a tilted plane: the first time its lowest point reaches the plane,
    by a dense scan and bisection in 50 digits of n . (c(t) - o) - h |n . a(t)| - r on the motion's own
    definition; the point lies on the plane and on the capsule."""
    mpmath.mp.dps = 50
    rng = np.random.default_rng(seed)
    r, h = 0.05 + 0.1 * rng.random(), 0.1 + 0.3 * rng.random()
    qp = list(_unit(rng.normal(size=4) * 0.2 + np.array([1.0, 0, 0, 0])))
    q0 = list(_unit(rng.normal(size=4)))
    q1 = list(_unit(np.array(q0) + 0.6 * rng.normal(size=4)))
    p0 = [0.1 * rng.normal(), 0.1 * rng.normal(), 1.0]
    p1 = [0.1 * rng.normal(), 0.1 * rng.normal(), -0.2]
    c = geom_first_contact(Capsule(r, h), mjccd.Rigid(p0, q0, p1, q1), HalfSpace(), mjccd.Static([0, 0, 0], qp))
    n = [row[2] for row in rot_matrix([mpmath.mpf(v) for v in qp])]

    def gap(t):
        t = mpmath.mpf(t)
        s = 1 if sum(a * b for a, b in zip(q0, q1)) >= 0 else -1
        q = [(1 - t) * mpmath.mpf(a) + t * s * mpmath.mpf(b) for a, b in zip(q0, q1)]
        axis = [row[2] for row in rot_matrix(q)]
        centre = [(1 - t) * mpmath.mpf(a) + t * mpmath.mpf(b) for a, b in zip(p0, p1)]
        return (sum(n[i] * centre[i] for i in range(3)) - h * abs(sum(n[i] * axis[i] for i in range(3))) - r)

    prev, truth = mpmath.mpf(0), None
    for k in range(1, 401):
        t = mpmath.mpf(k) / 400
        if gap(t) <= 0:
            lo, hi = prev, t
            for _ in range(100):
                mid = (lo + hi) / 2
                lo, hi = (lo, mid) if gap(mid) <= 0 else (mid, hi)
            truth = float(hi)
            break
        prev = t
    assert truth is not None and c is not None and c.certainty == "certified"
    assert abs(c.time - truth) <= 1e-9
    assert abs(float(sum(n[i] * c.point[i] for i in range(3)))) <= 1e-9
    assert np.allclose(c.normal, [-float(v) for v in n], atol=1e-9)
    assert c.elements[1] == "plane"


@pytest.mark.parametrize("clearance", [1e-3, 1e-6, 1e-9, 1e-12])
@pytest.mark.parametrize("shape", ["sphere", "capsule"])
def test_grazes_of_a_plane_never_certified_as_contacts(shape, clearance):
    """A sphere falling straight down and a capsule swinging
    through upright above the floor, their lowest points at ``clearance`` (relative to the size) above it: no
    certified contact; as deep below it: a contact, certified or bracketed around the truth."""
    r, h = 0.2, 0.5
    size = r + (h if shape == "capsule" else 0.0)
    for sign in (1.0, -1.0):
        low = size * (1.0 + sign * clearance)
        if shape == "sphere":
            # straight down to a lowest point of ``low - r`` above the floor at t = 1
            a, motion = Sphere(r), mjccd.Rigid([0.3, 0.1, 2.0], [1, 0, 0, 0], [0.3, 0.1, low], [1, 0, 0, 0])
            exact = (2.0 - size) / (2.0 - low) if sign < 0 else None
        else:
            # swinging from -60 to +60 degrees about x at height ``low``: upright (lowest) at t = 1/2
            a = Capsule(r, h)
            motion = mjccd.Rigid([0, 0, low], _identity_turned(-math.pi / 3), [0.5, 0, low],
                                 _identity_turned(math.pi / 3))
            exact = "somewhere before 1/2" if sign < 0 else None
        c = geom_first_contact(a, motion, HalfSpace(), mjccd.Static([0, 0, 0], [1, 0, 0, 0]))
        if sign > 0:
            assert c is None or c.certainty == "uncertain", (shape, clearance, c)
            continue
        assert c is not None, (shape, clearance)
        if shape == "sphere":
            if c.certainty == "certified":
                assert abs(c.time - exact) <= 1e-9
            else:
                assert c.bracket[0] <= exact + 1e-12 and exact - 1e-12 <= c.bracket[1]
        else:
            assert (c.time if c.certainty == "certified" else c.bracket[0]) <= 0.5
        if clearance >= 1e-6:
            assert c.certainty == "certified", (shape, clearance, c)
