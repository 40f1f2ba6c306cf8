"""Elliptic disks moving in the plane (mjccd.geoms.planar): the thesis' Examples 2.2 and 2.1, and an independent
brute force on random rigid and affine motions.

The brute force knows nothing of the solver's systems: at each time it takes the separation of the two disks
as the largest gap between their support functions over all directions (max over unit n of
min_B n.x - max_A n.x), positive exactly when they are apart (the distance), and finds the first time it
reaches zero on a grid refined by bisection.  Example 2.2's touching point is derived in mpmath from the
thesis' own characteristic polynomial (Lemma 2.5: the kernel of lambda0 A - B at its negative double root).
"""
from fractions import Fraction

import mpmath as mp
import numpy as np
import pytest

from mjccd.errors import InputError, MjccdError
from mjccd.geoms.planar import (CycloidalMotion, Ellipse, PlanarMotion, ellipse_collision_intervals,
                                ellipse_first_contact)

# ---------------------------------------------------------------- the thesis' Example 2.2

ROT = [[4, -16, 0, 32, -16], [0, -16, 48, -32], [0, 16, -48, 32]]  # cos-like, and the two off-diagonal entries
W22 = [4, -16, 32, -32, 16]


def example_2_2(printed=False):
    """M_A and M_B of Example 2.2; M_A's x-translation is -160t^3 + 240t^2 - 160t + 40 (the printed
    -160t^3 - 240t^2 + 160t - 40 has a sign slip: with it the disks never meet)."""
    xa = [-40, 160, -240, -160] if printed else [40, -160, 240, -160]
    ma = [[ROT[0], ROT[1], xa], [ROT[2], ROT[0], [80, -400, 880, -960, 480]], [0, 0, W22]]
    mb = [[ROT[0], ROT[2], [-40, 160, -240, 160]], [ROT[1], ROT[0], [-80, 400, -880, 960, -480]], [0, 0, W22]]
    return Ellipse(5, 10), PlanarMotion(ma), Ellipse(5, 10), PlanarMotion(mb)


def mp_touch_point(ma, mb, ea, eb, t):
    """The touching point at time t from the characteristic polynomial det(lambda A - B) (thesis Lemma 2.5),
    in mpmath: the negative double root lambda0 and the kernel of lambda0 A - B."""
    mp.mp.dps = 40
    t = mp.mpf(t)

    def conic(m, e):
        M = mp.matrix([[sum(mp.mpf(c.numerator) / c.denominator * t ** k for k, c in enumerate(p)) for p in row]
                       for row in m.entries])
        Mi = mp.inverse(M)
        return Mi.T * mp.diag([1 / mp.mpf(e.a) ** 2, 1 / mp.mpf(e.b) ** 2, -1]) * Mi

    A, B = conic(ma, ea), conic(mb, eb)
    f = lambda lam: mp.det(lam * A - B)  # noqa: E731
    roots = mp.polyroots(_cubic(f), maxsteps=200, extraprec=200)
    neg = sorted(r.real for r in roots if abs(r.imag) < 1e-15 and r.real < 0)
    lam0 = 0.5 * (neg[0] + neg[-1])  # a double root: both negative roots coincide
    Q = lam0 * A - B
    x = mp.lu_solve(Q[0:2, 0:2], -Q[0:2, 2])  # the kernel, normalised to weight 1
    return np.array([float(x[0]), float(x[1])]), float(neg[-1] - neg[0])


def _cubic(f):
    """The coefficients (highest first) of the cubic f, from four values."""
    xs = [mp.mpf(k) for k in (-1, 0, 1, 2)]
    V = mp.matrix([[x ** 3, x ** 2, x, 1] for x in xs])
    c = mp.lu_solve(V, mp.matrix([f(x) for x in xs]))
    return [c[i] for i in range(4)]


def test_example_2_2_as_printed_never_touches():
    assert ellipse_first_contact(*example_2_2(printed=True)) is None


def test_example_2_2_touches_at_one_half():
    ea, ma, eb, mb = example_2_2()
    c = ellipse_first_contact(ea, ma, eb, mb)
    assert c is not None and c.certainty == "certified" and c.status_at_start == "separate"
    assert abs(c.time - 0.5) <= 1e-9
    point, spread = mp_touch_point(ma, mb, ea, eb, 0.5)
    assert spread < 1e-15  # a double root: the disks touch at t = 1/2
    np.testing.assert_allclose(point, [0.0, 0.0], atol=1e-12)
    np.testing.assert_allclose(c.point, point, atol=1e-9)
    np.testing.assert_allclose(c.normal, [0.0, -1.0], atol=1e-9)  # A is the upper disk: outward is down


@pytest.mark.parametrize("k", range(3, 13))
def test_example_2_2_moved_apart(k):
    """The lower disk moved down by d = 10^-k of the disk size (10): no contact, certified, down to 1e-12."""
    ea, ma, eb, mb = example_2_2()
    d = Fraction(10, 10 ** k)
    c = ellipse_first_contact(ea, ma, eb, mb.translated((0, -d)))
    assert c is None or (c.certainty == "uncertain" and c.bracket[0] <= 0.5 <= c.bracket[1])
    assert c is None  # what the solver gives today, for every d


def test_example_2_2_intervals():
    ea, ma, eb, mb = example_2_2(printed=True)
    assert ellipse_collision_intervals(ea, ma, eb, mb) == ([], True)
    ea, ma, eb, mb = example_2_2()
    intervals, certified = ellipse_collision_intervals(ea, ma, eb, mb)
    # a graze at t = 1/2 is not a strict inequality anywhere: an interval around it, honestly uncertain
    assert not certified and len(intervals) == 1 and abs(intervals[0][0] - 0.5) < 1e-5


# ---------------------------------------------------------------- Example 2.1: trigonometric (cycloidal) motions


def test_example_2_1_cycloidal():
    """Thesis: first contact at t = 0.226, point (-47.605, -33.162); touching again (externally) at 0.731."""
    A, B = Ellipse(6, 10), Ellipse(14, 4)
    ma = CycloidalMotion([-80, -38], [115, 55], 0, Fraction(10, 9), unit="pi")
    mb = CycloidalMotion([-60, -57], [76, 97], 0, Fraction(2, 3), unit="pi")
    c = ellipse_first_contact(A, ma, B, mb)
    assert c.certainty == "certified"
    assert abs(c.time - 0.226) < 5e-4
    np.testing.assert_allclose(c.point, [-47.605, -33.162], atol=1e-3)
    # the brute force on the true (trigonometric) motion agrees
    assert abs(separation(ma.at(c.time), A, mb.at(c.time), B)) < 1e-7
    assert separation(ma.at(c.time - 1e-6), A, mb.at(c.time - 1e-6), B) > 0
    assert separation(ma.at(c.time + 1e-6), A, mb.at(c.time + 1e-6), B) < 0
    intervals, certified = ellipse_collision_intervals(A, ma, B, mb)
    assert certified and len(intervals) == 1
    assert abs(intervals[0][0] - c.time) < 1e-9 and abs(intervals[0][1] - 0.731) < 5e-4


def test_cycloidal_no_contact_and_overlap():
    A = Ellipse(1, 2)
    still = CycloidalMotion([0, 0], [0, 0], 0, 0)
    far = CycloidalMotion([10, 0], [0, 0], 0.3, 5.0)  # spins in place, never within reach
    assert ellipse_first_contact(A, still, A, far) is None
    near = CycloidalMotion([1.5, 0], [0, 0], 0.0, 3.0)
    assert ellipse_first_contact(A, still, A, near).status_at_start == "overlapping"


# ---------------------------------------------------------------- the brute force

PHI = np.linspace(0.0, 2.0 * np.pi, 1441)[:-1]


def _gap(M, e, phis):
    """(centre . n, |S^T n|) of the disk under the matrix M for directions at angles phis."""
    S = M[:2, :2] * np.array([e.a, e.b]) / M[2, 2]
    n = np.stack([np.cos(phis), np.sin(phis)])
    return M[:2, 2] / M[2, 2] @ n, np.linalg.norm(S.T @ n, axis=0)


def separation(MA, ea, MB, eb):
    """max over unit n of (min over B of n.x - max over A of n.x): > 0 iff the disks are apart."""
    def g(phis):
        ca, ra = _gap(MA, ea, phis)
        cb, rb = _gap(MB, eb, phis)
        return (cb - rb) - (ca + ra)
    v = g(PHI)
    k = int(np.argmax(v))
    lo, hi = PHI[k] - 0.005, PHI[k] + 0.005
    for _ in range(80):  # golden section on the best sample's neighbourhood
        m1, m2 = hi - 0.618 * (hi - lo), lo + 0.618 * (hi - lo)
        if g(np.array([m1]))[0] < g(np.array([m2]))[0]:
            lo = m1
        else:
            hi = m2
    return max(v[k], g(np.array([0.5 * (lo + hi)]))[0])


def _matrices(m, ts):
    """(len(ts), 3, 3) float matrices of a PlanarMotion (its exact coefficients rounded, evaluated in floats)."""
    out = np.zeros((len(ts), 3, 3))
    for i in range(3):
        for j in range(3):
            out[:, i, j] = np.polyval([float(c) for c in reversed(m.entries[i][j])], ts)
    return out


def _coarse_separations(MA, ea, MB, eb):
    """The separation at many times at once, maximised over the sampled directions only (a lower bound of it
    within about 1e-5 of the sizes)."""
    n = np.stack([np.cos(PHI), np.sin(PHI)])

    def parts(M, e):
        S = M[:, :2, :2] * np.array([e.a, e.b])[None, None, :] / M[:, 2, 2][:, None, None]
        c = M[:, :2, 2] / M[:, 2, 2][:, None]
        return c @ n, np.linalg.norm(np.einsum("tij,ik->tjk", S, n), axis=1)

    ca, ra = parts(MA, ea)
    cb, rb = parts(MB, eb)
    return ((cb - rb) - (ca + ra)).max(axis=1)


def brute_first_contact(ma, ea, mb, eb, n=2000):
    """The first time the separation reaches 0 (a grid of n + 1 times, the sampled separation refined where it
    comes near 0, then bisection); None when it stays positive; also the smallest separation seen."""
    ts = np.linspace(0.0, 1.0, n + 1)
    coarse = _coarse_separations(_matrices(ma, ts), ea, _matrices(mb, ts), eb)
    sep = lambda t: separation(ma.at(t), ea, mb.at(t), eb)  # noqa: E731
    first = None
    for k in np.nonzero(coarse <= 1e-3)[0]:
        if sep(ts[k]) <= 0.0:
            first = int(k)
            break
    smin = float(coarse.min())
    if first is None:
        return None, smin
    if first == 0:
        return 0.0, smin
    a, b = ts[first - 1], ts[first]
    for _ in range(45):
        m = 0.5 * (a + b)
        if sep(m) > 0.0:
            a = m
        else:
            b = m
    return b, smin


def _poly(rng, deg, scale):
    return [float(x) for x in rng.normal(0.0, scale, deg + 1)]


def random_rigid(rng):
    while True:
        deg = int(rng.integers(1, 3))
        try:
            return PlanarMotion.from_kinematic_image(_poly(rng, deg, 2.0), _poly(rng, deg, 2.0),
                                                     _poly(rng, deg, 1.0), _poly(rng, deg, 1.0))
        except InputError:
            pass


def random_affine(rng):
    while True:
        L = [[_poly(rng, 1, 0.4) for _ in range(2)] for _ in range(2)]
        L[0][0][0] += 1.0
        L[1][1][0] += 1.0
        w = [1.0 + abs(float(rng.normal())), float(rng.normal(0.0, 0.3))]
        try:
            return PlanarMotion([[L[0][0], L[0][1], _poly(rng, 2, 3.0)], [L[1][0], L[1][1], _poly(rng, 2, 3.0)],
                                 [0, 0, w]])
        except InputError:
            pass


def near_miss(rng, ea, ma, eb, mb):
    """B's motion moved so that the centres pass within about the sum of the sizes at a random time."""
    t = float(rng.uniform(0.25, 0.85))
    ca, cb = ma.at(t)[:2, 2] / ma.at(t)[2, 2], mb.at(t)[:2, 2] / mb.at(t)[2, 2]
    reach = max(ea.a, ea.b) + max(eb.a, eb.b)
    phi = rng.uniform(0.0, 2.0 * np.pi)
    target = ca + float(rng.uniform(0.5, 1.3)) * reach * np.array([np.cos(phi), np.sin(phi)])
    return mb.translated([float(x) for x in target - cb])


def check_against_brute(ea, ma, eb, mb):
    c = ellipse_first_contact(ea, ma, eb, mb)
    tb, smin = brute_first_contact(ma, ea, mb, eb)
    if c is None:
        assert tb is None and smin > -1e-4  # (the sampled separation is a lower bound within about 1e-5)
        return "free"
    if c.status_at_start != "separate":
        assert tb == 0.0 and separation(ma.at(0.0), ea, mb.at(0.0), eb) <= 1e-9
        return c.status_at_start
    if c.certainty != "certified":  # honest: the bracket holds the brute force's answer
        assert tb is None or c.bracket[0] - 1e-9 <= tb
        return "uncertain"
    sep = lambda t: separation(ma.at(t), ea, mb.at(t), eb)  # noqa: E731
    speed = abs(sep(c.time - 1e-6) - sep(c.time + 1e-6)) / 2e-6  # how fast the gap closes
    tol = 1e-9 + 2e-9 * speed  # the distance a time within 1e-9 of the contact leaves
    assert abs(sep(c.time)) < tol
    before = c.time - 1e-5
    assert before <= 0.0 or sep(before) > 0.0
    assert tb is not None and abs(tb - c.time) < 1e-8  # (a graze between grid times would show here)
    # the point lies on both boundaries; the normal is A's outward normal there
    assert abs(_quadric(mb.at(c.time), eb, c.point)) < 1e-9
    assert abs(_quadric(ma.at(c.time), ea, c.point)) < 4.0 * tol / min(ea.a, ea.b)
    g = _gradient(ma.at(c.time), ea, c.point)
    np.testing.assert_allclose(c.normal, g / np.linalg.norm(g), atol=1e-6)
    return "contact"


def _local(M, x):
    y = np.linalg.solve(M, np.array([x[0], x[1], 1.0]))
    return y[:2] / y[2]


def _quadric(M, e, x):
    y = _local(M, x)
    return (y[0] / e.a) ** 2 + (y[1] / e.b) ** 2 - 1.0


def _gradient(M, e, x, h=1e-6):
    return np.array([(_quadric(M, e, x + d) - _quadric(M, e, x - d)) / (2 * h) for d in (np.array([h, 0.0]),
                                                                                        np.array([0.0, h]))])


@pytest.mark.parametrize("seed", range(12))
def test_random_rigid_against_brute_force(seed):
    rng = np.random.default_rng(100 + seed)
    ea = Ellipse(float(rng.uniform(0.3, 2.0)), float(rng.uniform(0.3, 2.0)))
    eb = Ellipse(float(rng.uniform(0.3, 2.0)), float(rng.uniform(0.3, 2.0)))
    ma, mb = random_rigid(rng), random_rigid(rng)
    check_against_brute(ea, ma, eb, near_miss(rng, ea, ma, eb, mb))


@pytest.mark.parametrize("seed", range(12))
def test_random_affine_against_brute_force(seed):
    rng = np.random.default_rng(200 + seed)
    ea = Ellipse(float(rng.uniform(0.3, 2.0)), float(rng.uniform(0.3, 2.0)))
    eb = Ellipse(float(rng.uniform(0.3, 2.0)), float(rng.uniform(0.3, 2.0)))
    ma, mb = random_affine(rng), random_affine(rng)
    check_against_brute(ea, ma, eb, near_miss(rng, ea, ma, eb, mb))


@pytest.mark.parametrize("seed", range(8))
@pytest.mark.parametrize("kind", ["rigid", "affine"])
def test_random_intervals_against_brute_force(seed, kind):
    """Every interval of contact: the sampled separation is <= 0 inside and > 0 outside (away from the ends),
    and each end (other than 0 and 1) is a zero of the separation."""
    rng = np.random.default_rng((100 if kind == "rigid" else 200) + seed)
    ea = Ellipse(float(rng.uniform(0.3, 2.0)), float(rng.uniform(0.3, 2.0)))
    eb = Ellipse(float(rng.uniform(0.3, 2.0)), float(rng.uniform(0.3, 2.0)))
    gen = random_rigid if kind == "rigid" else random_affine
    ma, mb = gen(rng), gen(rng)
    mb = near_miss(rng, ea, ma, eb, mb)
    intervals, certified = ellipse_collision_intervals(ea, ma, eb, mb)
    assert certified
    ts = np.linspace(0.0, 1.0, 2001)
    sep = _coarse_separations(_matrices(ma, ts), ea, _matrices(mb, ts), eb)
    inside = np.zeros(ts.shape, bool)
    near = np.zeros(ts.shape, bool)
    for a, b in intervals:
        inside |= (ts >= a) & (ts <= b)
        near |= (abs(ts - a) < 1e-3) | (abs(ts - b) < 1e-3)
        for end in (a, b):
            if 0.0 < end < 1.0:
                assert abs(separation(ma.at(end), ea, mb.at(end), eb)) < 1e-8
    assert np.all(sep[inside & ~near] <= 1e-4) and np.all(sep[~inside & ~near] > -1e-4)


def test_random_cases_reach_contacts():
    """The near misses above are not all free or all overlapping."""
    kinds = set()
    for seed in range(12):
        rng = np.random.default_rng(100 + seed)
        ea = Ellipse(float(rng.uniform(0.3, 2.0)), float(rng.uniform(0.3, 2.0)))
        eb = Ellipse(float(rng.uniform(0.3, 2.0)), float(rng.uniform(0.3, 2.0)))
        ma, mb = random_rigid(rng), random_rigid(rng)
        c = ellipse_first_contact(ea, ma, eb, near_miss(rng, ea, ma, eb, mb))
        kinds.add("free" if c is None else c.status_at_start)
    assert {"free", "separate"} <= kinds


# ---------------------------------------------------------------- rotations: an exact distance by Lagrange


def _mp_point_ellipse_distance(p, a, b):
    """Distance from the point p (outside) to the ellipse x^2/a^2 + y^2/b^2 = 1, by the 1-d root of the Lagrange
    condition: the closest point is (a^2 px / (a^2 + mu), b^2 py / (b^2 + mu)) with mu > 0 on the ellipse."""
    px, py = abs(p[0]), abs(p[1])
    f = lambda mu: (a * px / (a ** 2 + mu)) ** 2 + (b * py / (b ** 2 + mu)) ** 2 - 1  # noqa: E731
    lo, hi = mp.mpf(0), mp.mpf(1)
    while f(hi) > 0:
        hi *= 2
    for _ in range(200):  # f decreases in mu > 0: bisection
        mu = 0.5 * (lo + hi)
        lo, hi = (mu, hi) if f(mu) > 0 else (lo, mu)
    q = (a ** 2 * px / (a ** 2 + mu), b ** 2 * py / (b ** 2 + mu))
    return mp.sqrt((px - q[0]) ** 2 + (py - q[1]) ** 2)


@pytest.mark.parametrize("k, r, x", [(1.0, 0.5, 3.0), (0.9, 0.3, 2.5), (0.8, 1.0, 3.5)])
def test_rotating_ellipse_hits_a_circle(k, r, x):
    """A (semi-axes 4, 1) turns about its centre by -2 atan(1 - k t) (the kinematic image d = (0, 0, 1, 1 - k t),
    a rational rotation of degree 2), from across the x axis towards it; B is a circle of radius r at (x, 0).
    The first contact solves dist(R(t)^T (x, 0), A) = r, the distance found in mpmath by the Lagrange
    condition."""
    ea, eb = Ellipse(4.0, 1.0), Ellipse(r, r)
    ma = PlanarMotion.from_kinematic_image([0], [0], [1], [1, -k])
    mb = PlanarMotion([[1, 0, x], [0, 1, 0], [0, 0, 1]])
    c = ellipse_first_contact(ea, ma, eb, mb)
    mp.mp.dps = 40

    def gap(t):
        th = 2 * mp.atan(1 - k * t)  # A turned by -th: B's centre in A's frame is turned by +th
        return _mp_point_ellipse_distance((x * mp.cos(th), x * mp.sin(th)), 4, 1) - r

    assert c is not None and c.certainty == "certified"
    lo, hi = mp.mpf(c.time) - mp.mpf("1e-3"), mp.mpf(c.time) + mp.mpf("1e-3")
    assert gap(lo) > 0 > gap(hi)
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if gap(mid) > 0 else (lo, mid)
    t_exact = 0.5 * (lo + hi)
    assert abs(c.time - float(t_exact)) < 1e-9
    assert all(gap(mp.mpf(s) * c.time / 50) > 0 for s in range(50))  # apart before
    assert abs(np.linalg.norm(c.point - [x, 0.0]) - r) < 1e-8


# ---------------------------------------------------------------- invariance, intervals, validation


@pytest.mark.parametrize("seed", range(4))
def test_translation_invariance(seed):
    rng = np.random.default_rng(300 + seed)
    ea, eb = Ellipse(1.0, 0.6), Ellipse(0.8, 1.3)
    ma, mb = random_rigid(rng), random_rigid(rng)
    mb = near_miss(rng, ea, ma, eb, mb)
    far = (1e6 * 1.3, -2e6 * 1.3)
    c0 = ellipse_first_contact(ea, ma, eb, mb)
    c1 = ellipse_first_contact(ea, ma.translated(far), eb, mb.translated(far))
    assert (c0 is None) == (c1 is None)
    if c0 is not None:
        assert c0.status_at_start == c1.status_at_start and c0.certainty == c1.certainty
        assert abs(c0.time - c1.time) < 1e-9
        if c0.point is not None:
            np.testing.assert_allclose(c1.point - np.array(far), c0.point, atol=1e-6)


def test_translation_intervals():
    """B crosses A along x at speed 10: in contact while |x| <= 3 (semi-axes 2 and 1 along x)."""
    ea, eb = Ellipse(2.0, 1.0), Ellipse(1.0, 0.5)
    ma = PlanarMotion([[1, 0, 0], [0, 1, 0], [0, 0, 1]])
    mb = PlanarMotion([[1, 0, [-5, 10]], [0, 1, 0], [0, 0, 1]])
    intervals, certified = ellipse_collision_intervals(ea, ma, eb, mb)
    assert certified and len(intervals) == 1
    np.testing.assert_allclose(intervals[0], (0.2, 0.8), atol=1e-9)
    c = ellipse_first_contact(ea, ma, eb, mb)
    assert abs(c.time - 0.2) < 1e-9
    np.testing.assert_allclose(c.point, [-2.0, 0.0], atol=1e-7)
    np.testing.assert_allclose(c.normal, [-1.0, 0.0], atol=1e-7)
    assert ellipse_first_contact(ea, ma, eb, mb, t_max=0.1) is None


def test_start_statuses():
    ea = Ellipse(1.0, 1.0)
    rest = PlanarMotion([[1, 0, 0], [0, 1, 0], [0, 0, 1]])
    assert ellipse_first_contact(ea, rest, ea, [[1, 0, 1], [0, 1, 0], [0, 0, 1]]).status_at_start == "overlapping"
    assert ellipse_first_contact(ea, rest, ea, [[1, 0, 2], [0, 1, 0], [0, 0, 1]]).status_at_start == "touching"
    inside = ellipse_first_contact(Ellipse(3, 3), rest, Ellipse(0.5, 0.5), [[1, 0, 0.2], [0, 1, 0], [0, 0, 1]])
    assert inside.status_at_start == "overlapping"  # B wholly inside A: its boundary is in A


def test_affine_scaling_disk():
    """An affine motion: A, a unit circle, grows to radius 1 + 3t about the origin and meets the unit circle at
    (4, 0) when 1 + 3t = 3: t = 2/3, at (3, 0)."""
    ea = Ellipse(1.0, 1.0)
    grow = PlanarMotion([[[1, 3], 0, 0], [0, [1, 3], 0], [0, 0, 1]])
    mb = PlanarMotion([[1, 0, 4], [0, 1, 0], [0, 0, 1]])
    c = ellipse_first_contact(ea, grow, ea, mb)
    assert abs(c.time - 2.0 / 3.0) < 1e-9
    np.testing.assert_allclose(c.point, [3.0, 0.0], atol=1e-7)


@pytest.mark.parametrize("matrix, message", [
    ([[1, 0, 0], [0, 1, 0]], "motion_a: expected a 3x3 matrix"),
    ([[1, 0, "x"], [0, 1, 0], [0, 0, 1]], "motion_a[0][2]"),
    ([[1, 0, float("nan")], [0, 1, 0], [0, 0, 1]], "motion_a[0][2]: must be finite"),
    ([[1, 0, 0], [0, 1, 0], [0, 1, 1]], "motion_a[2][1]: the last row must be [0, 0, w(t)]"),
    ([[1, 0, 0], [0, 1, 0], [0, 0, [1, -2]]], "motion_a[2][2]: w(t) vanishes"),
    ([[[1, -2], 0, 0], [0, 1, 0], [0, 0, 1]], "motion_a: the linear part"),
    ([[[-1, 2], 0, 0], [0, [1, -2], 0], [0, 0, 1]], None),  # det (2t - 1)(1 - 2t) <= 0 vanishes at 1/2
])
def test_refusals(matrix, message):
    with pytest.raises(MjccdError) as err:
        ellipse_first_contact(Ellipse(1, 1), matrix, Ellipse(1, 1), [[1, 0, 5], [0, 1, 0], [0, 0, 1]])
    if message is not None:
        assert message in str(err.value)


def test_refusal_is_exact():
    """The rule is exact: w with its root 2^-52 past t = 1 is accepted, with its root at 1 refused."""
    ok = PlanarMotion([[1, 0, 0], [0, 1, 0], [0, 0, [1.0000000000000002, -1]]])  # root at 1 + 2^-52
    assert ok.degree == 1
    with pytest.raises(InputError):
        PlanarMotion([[1, 0, 0], [0, 1, 0], [0, 0, [1, -1]]])  # root at exactly 1
    with pytest.raises(InputError, match="a: a semi-axis"):
        Ellipse(0.0, 1.0)
    steep = PlanarMotion([[1, 0, [0] * 50 + [1]], [0, 1, 0], [0, 0, 1]])  # accepted, but too steep to solve
    with pytest.raises(InputError, match="degree 100 in t"):
        ellipse_first_contact(Ellipse(1, 1), steep, Ellipse(1, 1), [[1, 0, 5], [0, 1, 0], [0, 0, 1]])
