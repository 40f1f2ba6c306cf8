"""Moving ellipsoids against static planes (mjccd.plane, and planes in mjccd.scene.Scene).

References: closed forms (a falling sphere, a translating ellipsoid against a tilted plane, an ellipsoid
spinning about a fixed centre, for every motion model that can express them), and a brute-force oracle
for the rest: g(t) = n . c(t) - offset - support(t) from the motion's exact rational quadric, evaluated in
mpmath at 40 digits, sampled densely and bisected.  The oracle shares nothing with mjccd.plane.
"""
import math
from fractions import Fraction

import mpmath
import numpy as np
import pytest
from hypothesis import given, settings, strategies as st

import mjccd
from mjccd.errors import InputError, InputTypeError
from mjccd.motion import (Affine, Chain, Fixed, Free, Hinge, LinearAffine, Rational, Rigid, Slide, Static,
                          _WMotion)
from mjccd.plane import (PLANE_WORK, Plane, plane_collision_intervals, plane_first_contact,
                         plane_first_contact_kernel, solve_plane)
from mjccd.scene import OUTCOME_NAMES, SPHERE, TOO_SLOW, PairContact, PlaneContact, Scene

TOL_T = 1e-9
FLOOR = Plane([0.0, 0.0, 1.0], 0.0)


# ------------------------------------------------------------------ oracle (mpmath, independent of mjccd.plane)


def _mp(x):
    x = Fraction(x)
    return mpmath.mpf(x.numerator) / x.denominator


def oracle_g(motion, radii, plane, t):
    """n . c - offset - support along n at the rational time t, from the motion's exact quadric (40 digits)."""
    with mpmath.workdps(40):
        A = motion.exact_quadric_at(np.asarray(radii, float), Fraction(t))
        M = mpmath.matrix([[_mp(A[i][j]) for j in range(4)] for i in range(4)])
        P, U, s = M[0:3, 0:3], M[0:3, 3], M[3, 3]
        Pi = P ** -1
        c = -(Pi * U)
        rho = (U.T * Pi * U)[0] - s
        n = mpmath.matrix([_mp(float(x)) for x in plane.normal])
        return (n.T * c)[0] - _mp(plane.offset) - mpmath.sqrt(rho * (n.T * Pi * n)[0])


def rot_mp(q):
    """rot(q) / |q|^2 in mpmath (exactly the rotation of the double quaternion q, to the working precision)."""
    w, x, y, z = (_mp(float(v)) for v in q)
    nq = w * w + x * x + y * y + z * z
    return mpmath.matrix([[(w * w + x * x - y * y - z * z) / nq, 2 * (x * y - w * z) / nq, 2 * (x * z + w * y) / nq],
                          [2 * (x * y + w * z) / nq, (w * w - x * x + y * y - z * z) / nq, 2 * (y * z - w * x) / nq],
                          [2 * (x * z - w * y) / nq, 2 * (y * z + w * x) / nq, (w * w - x * x - y * y + z * z) / nq]])


def oracle_intervals(motion, radii, plane, samples=200, t_max=1.0):
    """Maximal intervals of [0, t_max] where g <= 0: dense samples, crossings bisected to 1e-13."""
    ts = [t_max * k / samples for k in range(samples + 1)]
    gs = [oracle_g(motion, radii, plane, t) for t in ts]
    out, start = [], (0.0 if gs[0] <= 0 else None)
    for a, b, ga, gb in zip(ts, ts[1:], gs, gs[1:]):
        if (ga > 0) == (gb > 0):
            continue
        lo, hi = a, b
        while hi - lo > 1e-13:
            mid = 0.5 * (lo + hi)
            if (oracle_g(motion, radii, plane, mid) > 0) == (ga > 0):
                lo = mid
            else:
                hi = mid
        if ga > 0:
            start = 0.5 * (lo + hi)
        else:
            out.append((start, 0.5 * (lo + hi)))
            start = None
    if start is not None:
        out.append((start, t_max))
    return out, min(gs)


def assert_intervals(got, ref, tol=TOL_T):
    assert len(got) == len(ref), (got, ref)
    for (a, b), (c, d) in zip(got, ref):
        assert abs(a - c) <= tol and abs(b - d) <= tol, (got, ref)


# ------------------------------------------------------------------ motions that all express one path


def translating(p0, p1, quaternion=(1.0, 0.0, 0.0, 0.0)):
    """Every motion model for a body that translates from p0 to p1 with a fixed orientation."""
    R = mjccd.quadric.quat_to_matrix(np.asarray(quaternion, float))
    p0, p1 = np.asarray(p0, float), np.asarray(p1, float)
    out = {"rigid": Rigid(p0, quaternion, p1, quaternion), "affine": Affine(p0, quaternion, p1, quaternion),
           "linear_affine": LinearAffine(np.hstack([R, p0[:, None]]), np.hstack([R, p1[:, None]]))}
    if quaternion == (1.0, 0.0, 0.0, 0.0):
        out["rational"] = Rational(np.eye(3)[:, :, None].tolist(), [1.0],
                                   [[p0[i], p1[i] - p0[i]] for i in range(3)])
        out["chain"] = Chain([Fixed(p0), Slide(p1 - p0, 0.0, float(np.linalg.norm(p1 - p0)))])
        out["free"] = Free(p0, quaternion, p1, quaternion)
    return out


# ------------------------------------------------------------------ validation


def test_plane_value_is_validated_and_normalised():
    plane = Plane([0.0, 0.0, 2.0], 1.5)
    assert plane.normal.tolist() == [0.0, 0.0, 1.0] and plane.offset == 1.5
    assert Plane.through([1.0, 2.0, 3.0], [0, 3, 4]).offset == pytest.approx(0.6 * 2 + 0.8 * 3)
    assert Plane([1e300, 0, 0]).normal.tolist() == [1.0, 0.0, 0.0]
    assert plane.signed_distance([0, 0, 4]) == 2.5
    assert Plane([0, 0, 1], 1.5) == Plane([0, 0, 3], 1.5) and hash(Plane([0, 0, 1])) == hash(Plane([0, 0, 1]))
    with pytest.raises(InputError, match=r"^normal: zero vector"):
        Plane([0.0, 0.0, 0.0])
    with pytest.raises(InputError, match=r"^normal: contains NaN or infinity$"):
        Plane([np.nan, 0.0, 1.0])
    with pytest.raises(InputError, match=r"^normal: expected shape 3, got \(2,\)$"):
        Plane([0.0, 1.0])
    with pytest.raises(InputError, match=r"^offset: must be finite, got inf$"):
        Plane([0.0, 0.0, 1.0], np.inf)
    with pytest.raises(InputError, match=r"^offset: expected a number, got 'a'$"):
        Plane([0.0, 0.0, 1.0], "a")
    with pytest.raises(InputError, match=r"^point: contains NaN or infinity$"):
        Plane.through([0, np.nan, 0], [0, 0, 1])


def test_api_arguments_are_validated():
    m = Rigid([0, 0, 2], [1, 0, 0, 0], [0, 0, 0], [1, 0, 0, 0])
    with pytest.raises(InputTypeError, match=r"^motion: expected an mjccd motion, got str$"):
        plane_first_contact([1, 1, 1], "rigid", FLOOR)
    with pytest.raises(InputError, match=r"^radii: radii must be positive, got \[1.0, -1.0, 1.0\]$"):
        plane_first_contact([1, -1, 1], m, FLOOR)
    with pytest.raises(InputError, match=r"^plane: expected shape 4, got \(3,\)$"):
        plane_first_contact([1, 1, 1], m, [0, 0, 1])
    with pytest.raises(InputError, match=r"^plane\.normal: zero vector"):
        plane_first_contact([1, 1, 1], m, [0, 0, 0, 1])
    with pytest.raises(InputError, match=r"^t_max: must lie in \[0, 1\], got 2.0$"):
        plane_first_contact([1, 1, 1], m, FLOOR, t_max=2.0)
    # a row [nx, ny, nz, offset] and an Ellipsoid are accepted as well
    assert plane_first_contact(mjccd.Ellipsoid([0.5, 0.5, 0.5]), m, [0, 0, 2, 0]).time == pytest.approx(0.75)


# ------------------------------------------------------------------ closed forms


@pytest.mark.parametrize("t_star", [1e-12, 1e-9, 1e-6, 1e-3, 0.1, 0.37, 0.5, 0.999999, 1.0])
@pytest.mark.parametrize("kind", ["rigid", "affine", "linear_affine", "rational", "chain", "free"])
def test_falling_sphere_closed_form(kind, t_star):
    """A sphere of radius r falls by v over the step onto the floor z = z0: contact at t = (h0 - z0 - r) / v
    (dyadic r, z0 and v: at t* = 1 the sphere ends exactly on the floor)."""
    r, z0, v = 0.375, -0.25, 1.5
    h0 = z0 + r + v * t_star
    motion = translating([0.2, -0.1, h0], [0.2, -0.1, h0 - v])[kind]
    floor = Plane([0, 0, 1], z0)
    expected = (h0 - z0 - r) / v
    contact = plane_first_contact([r, r, r], motion, floor)
    assert contact.certainty == "certified" and contact.status_at_start == "separate"
    assert abs(contact.time - expected) <= TOL_T
    assert np.allclose(contact.point, [0.2, -0.1, z0], atol=1e-6 * r)
    assert contact.normal.tolist() == [0.0, 0.0, -1.0]
    intervals = plane_collision_intervals([r, r, r], motion, floor)
    assert len(intervals) == 1 and abs(intervals[0][0] - expected) <= TOL_T and intervals[0][1] == 1.0


@pytest.mark.parametrize("kind", ["rigid", "affine", "linear_affine"])
@pytest.mark.parametrize("seed", range(4))
def test_translating_ellipsoid_onto_tilted_plane_closed_form(kind, seed):
    """Fixed orientation, straight path, tilted plane: support h = sqrt(sum r_k^2 (R^T n)_k^2) is constant and
    sigma is linear, so the contact is at (sigma0 - h) / (sigma0 - sigma1); the point is c - S n / h."""
    rng = np.random.default_rng(seed)
    radii = rng.uniform(0.1, 1.0, 3)
    q = rng.normal(size=4)
    q = tuple(q / np.linalg.norm(q))
    plane = Plane(rng.normal(size=3), rng.uniform(-1, 1))
    n = plane.normal
    R = mjccd.quadric.quat_to_matrix(np.asarray(q))
    h_float = float(np.sqrt(np.sum((radii * (R.T @ n)) ** 2)))
    side = rng.normal(size=(2, 3))
    side -= np.outer(side @ n, n)  # moves along the plane do not change the distance
    p0 = n * (plane.offset + h_float + rng.uniform(0.2, 1.0)) + side[0]
    p1 = p0 - n * rng.uniform(2.0 * h_float + 1.5, 4.0) + side[1]
    motion = translating(p0, p1, q)[kind]
    with mpmath.workdps(40):  # the closed form on the very doubles of the input
        if kind == "linear_affine":  # the frame map's linear part is R as rounded: S = R diag(r^2) R^T
            Rm = [[_mp(float(x)) for x in row] for row in R]
        else:  # rot(q) / |q|^2 of the motion's own quaternion
            Rm = rot_mp(motion.quaternion0).tolist()
        nm = [_mp(float(v)) for v in n]
        body = [sum(Rm[m][k] * nm[m] for m in range(3)) for k in range(3)]
        h = mpmath.sqrt(sum((_mp(float(radii[k])) * body[k]) ** 2 for k in range(3)))
        s0 = sum(nm[i] * _mp(float(p0[i])) for i in range(3)) - _mp(plane.offset)
        s1 = sum(nm[i] * _mp(float(p1[i])) for i in range(3)) - _mp(plane.offset)
        t_star = float((s0 - h) / (s0 - s1))
        Sn = [sum(Rm[i][k] * _mp(float(radii[k])) ** 2 * body[k] for k in range(3)) for i in range(3)]
        point = [float((1 - t_star) * _mp(float(p0[i])) + t_star * _mp(float(p1[i])) - Sn[i] / h) for i in range(3)]
    contact = plane_first_contact(radii, motion, plane)
    assert contact.certainty == "certified"
    assert abs(contact.time - t_star) <= TOL_T
    assert np.allclose(contact.point, point, atol=1e-6 * radii.max())
    assert abs(plane.signed_distance(contact.point)) <= 1e-6 * radii.max()
    assert np.array_equal(contact.normal, 0.0 - n)


def _spin_time(a, c, height, theta_end):
    """Time at which a body spinning about y from 0 to theta_end (quaternion lerp) first reaches the floor:
    support along z is sqrt(a^2 sin^2(theta) + c^2 cos^2(theta)); it equals the centre's height at
    sin^2(theta*) = (height^2 - c^2) / (a^2 - c^2), and tan(theta/2) = t s / ((1 - t) + t co) for the lerp."""
    with mpmath.workdps(40):
        a, c, height = _mp(a), _mp(c), _mp(height)
        theta = mpmath.asin(mpmath.sqrt((height ** 2 - c ** 2) / (a ** 2 - c ** 2)))
        T = mpmath.tan(theta / 2)
        co, s = mpmath.cos(_mp(theta_end) / 2), mpmath.sin(_mp(theta_end) / 2)
        return T, float(T / (s + T * (1 - co)))


@pytest.mark.parametrize("height", [0.35, 0.5, 0.8, 0.97])
def test_spinning_ellipsoid_about_fixed_centre_closed_form(height):
    """radii (1, 0.5, 0.3): the long axis turns from horizontal towards vertical about a centre at ``height``."""
    a, c, phi = 1.0, 0.3, 2.0
    # the body's x axis starts along x (support 0.3); quaternion lerp from identity to a turn of phi about y
    q1 = (math.cos(phi / 2), 0.0, math.sin(phi / 2), 0.0)
    motion = Rigid([0.1, 0.2, height], [1, 0, 0, 0], [0.1, 0.2, height], q1)
    _, t_star = _spin_time(a, c, height, phi)
    contact = plane_first_contact([a, 0.5, c], motion, FLOOR)
    assert contact.certainty == "certified" and abs(contact.time - t_star) <= TOL_T
    assert abs(contact.point[2]) <= 1e-6
    # the same spin as a hinge (tan(theta/2) linear) and as a rational motion: t* = tan(theta*/2) / tan(phi/2)
    T, _ = _spin_time(a, c, height, phi)
    with mpmath.workdps(40):
        t_hinge = float(T / mpmath.tan(_mp(phi) / 2))
    hinge = Chain([Fixed([0.1, 0.2, height]), Hinge([0, 1, 0], 0.0, phi)])
    tau = math.tan(phi / 2)
    rational = Rational([[[1, 0, -tau * tau], [0], [0, 2 * tau]], [[0], [1, 0, tau * tau], [0]],
                         [[0, -2 * tau], [0], [1, 0, -tau * tau]]], [1, 0, tau * tau], [[0.1], [0.2], [height]])
    for m in (hinge, rational):
        contact = plane_first_contact([a, 0.5, c], m, FLOOR)
        assert contact.certainty == "certified" and abs(contact.time - t_hinge) <= TOL_T, (m, contact)


# ------------------------------------------------------------------ statuses at the start, no contact


def test_statuses_at_start_and_no_contact():
    r = [0.5, 0.5, 0.5]
    up = Rigid([0, 0, 0.5], [1, 0, 0, 0], [0, 0, 2.0], [1, 0, 0, 0])
    down = Rigid([0, 0, 0.5], [1, 0, 0, 0], [0, 0, -2.0], [1, 0, 0, 0])
    cut = Rigid([0, 0, 0.3], [1, 0, 0, 0], [0, 0, 2.0], [1, 0, 0, 0])
    below = Affine([0, 0, -3], [1, 0, 0, 0], [1, 0, -2], [0, 1, 0, 0])
    clear = Rigid([0, 0, 2.0], [1, 0, 0, 0], [0, 0, 0.5 + 1e-6], [0, 1, 0, 0])
    assert plane_first_contact(r, clear, FLOOR) is None
    assert plane_collision_intervals(r, clear, FLOOR) == []
    touch = plane_first_contact(r, up, FLOOR)
    assert touch == mjccd.Contact(0.0, None, None, "touching")
    s = solve_plane(r, up, FLOOR)
    assert s.certified and s.intervals[0, 0] == 0.0 and s.intervals[0, 1] <= 1e-15
    assert plane_first_contact(r, down, FLOOR).status_at_start == "touching"
    assert plane_collision_intervals(r, down, FLOOR) == [(0.0, 1.0)]
    contact = plane_first_contact(r, cut, FLOOR)
    assert contact == mjccd.Contact(0.0, None, None, "overlapping")
    assert_intervals(plane_collision_intervals(r, cut, FLOOR), [(0.0, 0.2 / 1.7)])
    assert plane_first_contact(r, below, FLOOR).status_at_start == "overlapping"  # below the plane: in contact
    assert plane_collision_intervals(r, below, FLOOR) == [(0.0, 1.0)]
    # at rest on the floor, or sliding along it: the exact status holds for the whole step
    for m in (Static([0, 0, 0.5]), Rigid([0, 0, 0.5], [1, 0, 0, 0], [3, 1, 0.5], [1, 0, 0, 0])):
        s = solve_plane(r, m, FLOOR)
        assert s.status_at_start == 0 and s.certified and s.intervals.tolist() == [[0.0, 1.0]]
    assert plane_first_contact(r, Static([0, 0, 0.5 + 2 ** -40]), FLOOR) is None


def test_a_gap_closing_at_once_is_found_after_zero():
    """2^-40 above the floor, falling at speed 1: first contact at 2^-40, not at 0."""
    m = Rigid([0, 0, 0.5 + 2 ** -40], [1, 0, 0, 0], [0, 0, -0.5 + 2 ** -40], [1, 0, 0, 0])
    contact = plane_first_contact([0.5, 0.5, 0.5], m, FLOOR)
    assert contact.status_at_start == "separate" and contact.certainty == "certified"
    assert abs(contact.time - 2 ** -40) <= 1e-12


def test_t_max_bounds_the_search():
    m = Rigid([0, 0, 2], [1, 0, 0, 0], [0, 0, 0], [1, 0, 0, 0])
    assert plane_first_contact([0.5] * 3, m, FLOOR, t_max=0.7) is None
    assert plane_first_contact([0.5] * 3, m, FLOOR, t_max=0.8).time == pytest.approx(0.75, abs=TOL_T)


def test_far_from_the_origin():
    """Positions and offsets of 1e5 (sizes 0.5): the compensated distance keeps the double tier certified."""
    m = Rigid([1e5, -1e5, 1e5 + 2.0], [1, 0, 0, 0], [1e5, -1e5, 1e5], [0.8, 0.6, 0, 0])
    plane = Plane([0, 0, 1], 1e5)
    s = solve_plane([0.5, 0.3, 0.5], m, plane)
    ref = oracle_intervals(m, [0.5, 0.3, 0.5], plane, samples=60)[0]
    assert s.certified and s.precision == 0
    assert_intervals(s.intervals.tolist(), ref)
    assert abs(plane.signed_distance(s.point)) <= 1e-6


# ------------------------------------------------------------------ grazes


def _graze(eps, affine):
    """(motion, radii, t_graze): g decreases on [0, t_graze] to eps at t_graze.

    Rigid: an ellipsoid (0.2, 0.2, 1) swinging about y through vertical at t = 1/2 (the quaternion lerp is
    symmetric about it) above the floor, its lowest point eps above it there: a double root of f.
    Affine: the lerped shape matrix has no such interior extreme here (its support along z is smallest
    mid-step), so the body turns from lying to standing while it sinks, and ends eps above the floor.
    """
    radii = [0.2, 0.2, 1.0]
    if not affine:
        q0, q1 = (math.cos(-0.3), 0.0, math.sin(-0.3), 0.0), (math.cos(0.3), 0.0, math.sin(0.3), 0.0)
        return Rigid([0.0, 0.0, 1.0 + eps], q0, [0.0, 0.0, 1.0 + eps], q1), radii, 0.5
    q0, q1 = (math.cos(math.pi / 4), 0.0, math.sin(math.pi / 4), 0.0), (math.cos(0.25), 0.0, math.sin(0.25), 0.0)
    q1 = Affine([0, 0, 0], q1, [0, 0, 0], q1).quaternion0  # the quaternion as Affine keeps it
    with mpmath.workdps(40):
        R = rot_mp(q1)
        Q = R * mpmath.diag([1 / _mp(r) ** 2 for r in radii]) * R.T
        end = float(mpmath.sqrt((Q ** -1)[2, 2]))
    return Affine([0.0, 0.0, end + 0.5 + eps], q0, [0.0, 0.0, end + eps], q1), radii, 1.0


@pytest.mark.parametrize("eps", [1e-3, 1e-6, 1e-8, 1e-10, 1e-12, 0.0, -1e-12, -1e-10, -1e-8, -1e-6, -1e-3])
@pytest.mark.parametrize("affine", [False, True])
def test_graze_is_certified_right_or_uncertain(eps, affine):
    """The lowest point comes within eps of the floor.  Never a wrong certified answer; a clearance of 1e-6 is
    free, a penetration of 1e-8 is a contact; an uncertain answer brackets the true first contact."""
    m, radii, t_graze = _graze(eps, affine)
    truth = None  # the true first contact (bisection of g, which decreases on [0, t_graze]), None if clear
    if oracle_g(m, radii, FLOOR, t_graze) <= 0:
        lo, hi = 0.0, t_graze
        while hi - lo > 1e-13:
            mid = 0.5 * (lo + hi)
            lo, hi = (mid, hi) if oracle_g(m, radii, FLOOR, mid) > 0 else (lo, mid)
        truth = hi
    contact = plane_first_contact(radii, m, FLOOR)
    if contact is None:
        assert truth is None
    elif contact.certainty == "certified":
        assert truth is not None and abs(contact.time - truth) <= TOL_T
    else:
        assert truth is None or contact.bracket[0] - TOL_T <= truth <= contact.bracket[1] + TOL_T
    if eps >= 1e-6:
        assert contact is None
    if eps <= -1e-8:
        assert contact is not None
    # the double-precision kernel alone: certified answers are right, the others bracket the contact
    status, time, time_hi, certified = plane_first_contact_kernel(
        affine, np.array(radii), m.position0, m.quaternion0, m.position1, m.quaternion1,
        np.array([0.0, 0.0, 1.0, 0.0]), 1.0, np.empty(PLANE_WORK), np.zeros((2, 3)))
    assert status == 1
    if certified:
        assert (time < 0.0) == (truth is None)
        assert truth is None or abs(time - truth) <= TOL_T
    else:
        assert truth is None or time - TOL_T <= truth <= time_hi + TOL_T


# ------------------------------------------------------------------ every motion model against the oracle


def _case(kind, rng):
    """A random motion of kind towards and through a random plane."""
    plane = Plane(rng.normal(size=3), rng.uniform(-0.5, 0.5))
    n = plane.normal
    start = n * (plane.offset + rng.uniform(1.0, 1.6)) + rng.normal(scale=0.3, size=3)
    end = start - n * rng.uniform(0.5, 2.5) + rng.normal(scale=0.3, size=3)
    q0 = rng.normal(size=4)
    q1 = q0 + rng.normal(scale=0.7, size=4)
    if kind == "rigid":
        return plane, Rigid(start, q0, end, q1)
    if kind == "affine":
        return plane, Affine(start, q0, end, q1)
    if kind == "free":
        return plane, Free(start, q0, end, q1)
    if kind == "static":
        return plane, Static(n * (plane.offset + rng.uniform(0.05, 0.9)), q0)
    if kind == "linear_affine":
        L0 = np.eye(3) + 0.2 * rng.normal(size=(3, 3))
        L1 = np.eye(3) + 0.2 * rng.normal(size=(3, 3))
        return plane, LinearAffine(np.hstack([L0, start[:, None]]), np.hstack([L1, end[:, None]]))
    if kind == "chain":
        axis = rng.normal(size=3)
        return plane, Chain([Fixed(start, q0), Hinge(axis, rng.uniform(-1, 1), rng.uniform(-1, 1)),
                             Slide(end - start, 0.0, float(np.linalg.norm(end - start))), Fixed([0.2, 0.0, 0.1])])
    # rational: a rotation about z by tan(theta/2) = t (degree 2 / 2), a quadratic path
    rot = [[[1, 0, -1], [0, -2], [0]], [[0, 2], [1, 0, -1], [0]], [[0], [0], [1, 0, 1]]]
    mid = 0.5 * (start + end) + rng.normal(scale=0.5, size=3)
    path = [[start[i], 2 * (mid[i] - start[i]), start[i] - 2 * mid[i] + end[i]] for i in range(3)]
    return plane, Rational(rot, [1, 0, 1], path)


@pytest.mark.parametrize("kind", ["rigid", "affine", "free", "static", "linear_affine", "chain", "rational"])
def test_every_motion_model_against_the_oracle(kind):
    rng = np.random.default_rng(sum(map(ord, kind)))
    for _ in range(4):
        plane, motion = _case(kind, rng)
        radii = rng.uniform(0.15, 0.6, 3)
        solution = solve_plane(radii, motion, plane)
        ref, _ = oracle_intervals(motion, radii, plane, samples=120)
        first = plane_first_contact(radii, motion, plane)
        if solution.certified:
            assert_intervals(solution.intervals.tolist(), ref)
            if ref:
                assert first.certainty == "certified" and abs(first.time - ref[0][0]) <= TOL_T
                if ref[0][0] > 0.0:
                    assert abs(plane.signed_distance(first.point)) <= 1e-6 * radii.max()
            else:
                assert first is None
        else:  # an uncertain answer brackets the true first contact
            lo, hi = first.bracket
            assert ref and lo - TOL_T <= ref[0][0] <= hi + TOL_T


def test_the_general_path_agrees_with_the_two_pose_kernels():
    """A rigid motion given only by its scaled inverse W (the path of linear_affine, rational and chains)
    gives the intervals the rigid kernel gives."""
    rng = np.random.default_rng(7)
    for _ in range(6):
        plane, motion = _case("rigid", rng)
        radii = rng.uniform(0.15, 0.6, 3)
        a = solve_plane(radii, motion, plane)
        b = solve_plane(radii, _WMotion(*motion.scaled_inverse_w()), plane)
        assert a.certified and b.certified
        assert_intervals(b.intervals.tolist(), a.intervals.tolist())


def test_kernel_agrees_with_the_python_layer():
    rng = np.random.default_rng(3)
    work, touch = np.empty(PLANE_WORK), np.zeros((2, 3))
    for k in range(40):
        plane, motion = _case("affine" if k % 2 else "rigid", rng)
        radii = rng.uniform(0.15, 0.6, 3)
        status, time, time_hi, certified = plane_first_contact_kernel(
            k % 2 == 1, radii, motion.position0, motion.quaternion0, motion.position1, motion.quaternion1,
            plane.as_array(), 1.0, work, touch)
        contact = plane_first_contact(radii, motion, plane)
        if not certified or status == 0:  # the Python layer settles a touching start exactly
            continue
        if time < 0.0:
            assert contact is None
        else:
            assert contact.time == time and (status != 1 or np.array_equal(contact.point, touch[0]))
            assert {1: "separate", 0: "touching", -1: "overlapping"}[status] == contact.status_at_start


# ------------------------------------------------------------------ invariance


def _cube_rotation(index):
    """The 24 rotations of the cube as integer quaternions (rot(q)/|q|^2 is a signed permutation: exact)."""
    import itertools

    seen, out = set(), []
    for q in itertools.product([-1, 0, 1], repeat=4):
        if sum(1 for v in q if v) not in (1, 2, 4):
            continue
        R = np.rint(mjccd.quadric.quat_to_matrix(np.array(q, float))).astype(int)
        key = R.tobytes()
        if key not in seen:
            seen.add(key)
            out.append(np.array(q, float))
    return out[index]


def _qmul(a, b):
    w1, x1, y1, z1 = a
    w2, x2, y2, z2 = b
    return np.array([w1 * w2 - x1 * x2 - y1 * y2 - z1 * z2, w1 * x2 + x1 * w2 + y1 * z2 - z1 * y2,
                     w1 * y2 - x1 * z2 + y1 * w2 + z1 * x2, w1 * z2 + x1 * y2 - y1 * x2 + z1 * w2])


@settings(max_examples=25, deadline=None, derandomize=True)
@given(seed=st.integers(0, 10 ** 6), rot=st.integers(0, 23), shift=st.tuples(*[st.integers(-64, 64)] * 3),
       affine=st.booleans())
def test_rigid_change_of_frame_gives_the_same_time(seed, rot, shift, affine):
    rng = np.random.default_rng(seed)
    plane, motion = _case("affine" if affine else "rigid", rng)
    radii = rng.uniform(0.15, 0.6, 3)
    g = _cube_rotation(rot)
    R = np.rint(mjccd.quadric.quat_to_matrix(g))
    s = np.array(shift, float) / 8.0
    moved_plane = Plane(R @ plane.normal, plane.offset + float((R @ plane.normal) @ s))
    cls = Affine if affine else Rigid
    moved = cls(R @ motion.position0 + s, _qmul(g, motion.quaternion0), R @ motion.position1 + s,
                _qmul(g, motion.quaternion1))
    a = plane_first_contact(radii, motion, plane)
    b = plane_first_contact(radii, moved, moved_plane)
    assert (a is None) == (b is None)
    if a is not None and a.certainty == b.certainty == "certified":
        assert a.status_at_start == b.status_at_start and abs(a.time - b.time) <= TOL_T
        if a.point is not None:
            assert np.allclose(R @ a.point + s, b.point, atol=1e-6 * radii.max())


# ------------------------------------------------------------------ scenes with planes


def _scene_case(rng, n, motion):
    radii = rng.uniform(0.1, 0.4, (n, 3))
    p0 = np.hstack([rng.uniform(-2, 2, (n, 2)), rng.uniform(0.0, 1.5, (n, 1))])
    q0 = rng.normal(size=(n, 4))
    q0 /= np.linalg.norm(q0, axis=1)[:, None]
    p1 = p0 + rng.normal(scale=0.4, size=(n, 3)) - [0, 0, 0.3]
    q1 = q0 + rng.normal(scale=0.3, size=(n, 4))
    q1 /= np.linalg.norm(q1, axis=1)[:, None]
    planes = [Plane([0, 0, 1], 0.0), Plane([-1, 0.2, 0.1], -1.8), Plane([0.3, 1, 0], -1.5)]
    scene = Scene(radii, motion=motion, planes=planes)
    return scene, radii, np.hstack([p0, q0]), np.hstack([p1, q1]), planes


@pytest.mark.parametrize("motion", ["rigid", "affine"])
def test_scene_plane_pairs_match_direct_calls(motion):
    rng = np.random.default_rng(11)
    cls = Affine if motion == "affine" else Rigid
    seen_contact = 0
    for _ in range(4):
        scene, radii, a, b, planes = _scene_case(rng, 6, motion)
        full = scene.step(a, b, all_pairs=True)
        by_pair = {c.pair: c for c in full.contacts}
        npairs = len(scene.pairs)
        assert len(scene.plane_pairs) == 6 * 3 and full.counters.pairs == npairs + 18
        for row, (e, p) in enumerate(scene.plane_pairs.tolist()):
            k = npairs + row
            assert scene.plane_pair(k) == (e, p)
            m = cls(a[e, :3], a[e, 3:], b[e, :3], b[e, 3:])
            direct = solve_plane(radii[e], m, planes[p])
            got = by_pair.get(k)
            if not len(direct.intervals):
                assert got is None or got.certainty == "uncertain"
                continue
            seen_contact += 1
            assert isinstance(got, PlaneContact) and (got.ellipsoid, got.plane) == (e, p)
            if got.certainty == "certified" and direct.certified:
                assert_intervals(list(got.intervals), direct.intervals.tolist(), tol=TOL_T)
        # the frame's first contact is the earliest over pairs and plane pairs
        first = scene.step(a, b)
        times = [c.time for c in full.contacts]
        if times:
            assert first.first is not None and abs(first.first.time - min(times)) <= TOL_T
            fc = scene.first_contact(a, b)
            assert fc.pair == first.first.pair and fc.time == first.first.time
            assert isinstance(first.first, PlaneContact if fc.pair >= npairs else PairContact)
    assert seen_contact > 0


def test_scene_filter_never_drops_a_plane_contact():
    """Bodies whose lowest point ends 1e-3 .. 1e-12 of their size below (or above) the plane: the filter may
    only clear pairs that are free, and may_touch must say maybe for every new contact."""
    rng = np.random.default_rng(5)
    for motion, cls in (("rigid", Rigid), ("affine", Affine)):
        for _ in range(6):
            n = 8
            radii = rng.uniform(0.1, 0.4, (n, 3))
            q0 = rng.normal(size=(n, 4))
            q0 /= np.linalg.norm(q0, axis=1)[:, None]
            q1 = q0 + rng.normal(scale=0.2, size=(n, 4))
            q1 /= np.linalg.norm(q1, axis=1)[:, None]
            normal = rng.normal(size=3)
            plane = Plane(normal, rng.uniform(-1, 1))
            nrm = plane.normal
            depth = 10.0 ** -rng.uniform(3, 12, n) * rng.choice([-1.0, 1.0], n)
            p1 = rng.normal(size=(n, 3))
            for e in range(n):
                R1 = mjccd.quadric.quat_to_matrix(q1[e])
                h = np.sqrt(np.sum((radii[e] * (R1.T @ nrm)) ** 2))
                p1[e] += nrm * (plane.offset - nrm @ p1[e] + h + depth[e] * radii[e].max())
            p0 = p1 + nrm[None, :] * rng.uniform(0.05, 1.0, (n, 1)) + rng.normal(scale=0.05, size=(n, 3))
            a, b = np.hstack([p0, q0]), np.hstack([p1, q1])
            scene = Scene(radii, motion=motion, pairs=np.zeros((0, 2)), planes=[plane])
            scene.step(a, b, all_pairs=True)
            outcome = scene.workspace.arrays.outcome.copy()
            maybe = scene.may_touch(a, b)
            for e in range(n):
                direct = plane_first_contact(radii[e], cls(a[e, :3], a[e, 3:], b[e, :3], b[e, 3:]), plane)
                if direct is not None:
                    assert outcome[e] not in (SPHERE, TOO_SLOW), (e, OUTCOME_NAMES[outcome[e]], direct)
                    if direct.status_at_start == "separate":
                        assert maybe


def test_scene_new_contacts_only_policy_and_run():
    radii = np.array([[0.5, 0.5, 0.5], [0.2, 0.3, 0.4]])
    scene = Scene(radii, planes=np.array([[0, 0, 2.0, 0.0]]))  # normal of any length
    assert scene.planes.tolist() == [[0.0, 0.0, 1.0, 0.0]] and scene.plane_pairs.tolist() == [[0, 0], [1, 0]]
    resting = [0, 0, 0.49, 1, 0, 0, 0]  # slightly into the floor: in contact at the start, not new
    a = np.array([resting, [3, 0, 2.0, 1, 0, 0, 0]])
    b = np.array([resting, [3, 0, 0.0, 0.8, 0.6, 0, 0]])
    assert scene.step(a, b).first.time == 0.0
    new = scene.step(a, b, new_contacts_only=True)
    assert isinstance(new.first, PlaneContact) and new.first.ellipsoid == 1 and new.first.time > 0.0
    assert scene.may_touch(a, b)
    run = scene.run(np.stack([a, b, b]))
    assert run.outcomes.shape == (2, 3) and run.pair[0] == 1 and run.time[0] == 0.0
    scene.set_plane_min_motion([0.0, 10.0])  # the falling body moves less than 10: left out
    assert scene.step(a, b, new_contacts_only=True).first is None
    assert scene.workspace.arrays.outcome[2] == TOO_SLOW and not scene.may_touch(a, b)
    assert scene.plane_min_motion.tolist() == [0.0, 10.0]
    with pytest.raises(InputError, match=r"^plane_min_motion\[0\]: expected a distance >= 0, got -1.0$"):
        scene.set_plane_min_motion([-1.0, 0.0])
    assert scene.plane_pair(0) is None
    with pytest.raises(InputError, match=r"^k: pair index out of range for 1 pairs and 2 plane pairs, got 3$"):
        scene.plane_pair(3)


def test_scene_plane_arguments_are_validated():
    radii = np.ones((2, 3))
    with pytest.raises(InputError, match=r"^planes\[1\]\.normal: zero vector"):
        Scene(radii, planes=[[0, 0, 1, 0], [0, 0, 0, 1]])
    with pytest.raises(InputError, match=r"^planes: expected shape Nx4, got \(3,\)$"):
        Scene(radii, planes=np.array([0.0, 0.0, 1.0]))
    with pytest.raises(InputError, match=r"^plane_pairs\[1\]: plane index out of range for 1 planes, got \[0, 1\]$"):
        Scene(radii, planes=[FLOOR], plane_pairs=[[0, 0], [0, 1]])
    with pytest.raises(InputError, match=r"^plane_pairs\[0\]: ellipsoid index out of range for 2 ellipsoids"):
        Scene(radii, planes=[FLOOR], plane_pairs=[[2, 0]])
    with pytest.raises(InputError, match=r"^plane_pairs: given without planes$"):
        Scene(radii, plane_pairs=[[0, 0]])
    scene = Scene(radii, planes=[FLOOR], plane_pairs=[[1, 0]])
    assert scene.plane_pairs.tolist() == [[1, 0]]
    assert "1 plane pairs" in repr(scene.workspace)


def test_scene_without_planes_is_unchanged():
    """No planes: no plane pairs, the workspace's per-pair arrays have P rows and the results are PairContacts."""
    rng = np.random.default_rng(2)
    radii = rng.uniform(0.2, 0.5, (5, 3))
    a = np.hstack([rng.uniform(-1, 1, (5, 3)), np.tile([1.0, 0, 0, 0], (5, 1))])
    b = a.copy()
    b[:, :3] = -a[:, :3]
    plain, empty = Scene(radii), Scene(radii, planes=[])
    for scene in (plain, empty):
        assert scene.plane_pairs.shape == (0, 2) and len(scene.workspace.arrays.outcome) == len(scene.pairs)
    r1, r2 = plain.step(a, b, all_pairs=True), empty.step(a, b, all_pairs=True)
    assert repr(r1) == repr(r2)
    assert all(isinstance(c, PairContact) for c in r1.contacts) and r1.contacts
    assert repr(plain.workspace) == "<WorkspaceRef of 5 ellipsoids, 10 pairs>"
