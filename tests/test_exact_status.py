"""The exact static status (mjccd.exact) and the certified double-precision tests that defer to it."""
import math
from fractions import Fraction
from pathlib import Path

import mpmath
import numpy as np
import pytest

import mjccd
from mjccd import _validate, exact
from mjccd import quadric as Q

ID = (1.0, 0.0, 0.0, 0.0)
NAMES = {1: "separate", 0: "touching", -1: "overlapping"}


def unit(q):
    """q normalised as static_status and static_status_many normalise it (the doubles they decide on)."""
    return _validate.pose_array(np.r_[np.zeros(3), q][None, :], "q")[0, 3:]


def random_pairs(seed, n, thin=False):
    """n pairs (ra, pa, qa, rb, pb, qb) of random shapes and poses; thin: 1000:1 disks and needles."""
    rng = np.random.default_rng(seed)
    out = []
    for _ in range(n):
        if thin:
            ra, rb = (rng.permutation([1.0, 1.0, 1e-3] if rng.random() < 0.5 else [1.0, 1e-3, 1e-3])
                      for _ in range(2))
        else:
            ra, rb = rng.uniform(0.2, 1.0, 3), rng.uniform(0.2, 1.0, 3)
        out.append((ra, rng.normal(size=3), rng.normal(size=4), rb, rng.normal(size=3), rng.normal(size=4)))
    return out


def exact_code(ra, pa, qa, rb, pb, qb):
    """The exact status of the pair as the Python layer sees it (quaternions normalised)."""
    qa, qb = unit(qa), unit(qb)
    return exact.static_status_exact(exact.quadric_exact(ra, pa, qa), exact.quadric_exact(rb, pb, qb))


def pose_code(ra, pa, qa, rb, pb, qb):
    """The batched kernel's code for one pair (tuples in, as static_status_batch passes them)."""
    qa, qb = unit(qa), unit(qb)
    return int(Q.static_status_pose(tuple(map(float, ra)), tuple(map(float, pa)), tuple(map(float, qa)),
                                    tuple(map(float, rb)), tuple(map(float, pb)), tuple(map(float, qb))))


def all_paths(ra, pa, qa, rb, pb, qb):
    """static_status, static_status_many, static_status_code: they must agree (returned as a name).

    The first two normalise the quaternions; the third is given them normalised the same way."""
    single = mjccd.static_status(mjccd.Ellipsoid(ra), (pa, qa), mjccd.Ellipsoid(rb), (pb, qb))
    many = mjccd.static_status_many([ra], [np.r_[pa, qa]], [rb], [np.r_[pb, qb]])
    code = Q.static_status_code(ra, pa, unit(qa), rb, pb, unit(qb))
    assert single == NAMES[int(many[0])] == NAMES[code]
    return single


# ---------------------------------------------------------------- the exact test


def mp_status(A, B):
    """Status from max g on [0, 1] in 50-digit arithmetic (g's critical points by polyroots)."""
    with mpmath.workdps(50):
        A = mpmath.matrix([[mpmath.mpf(float(x)) for x in row] for row in A])
        B = mpmath.matrix([[mpmath.mpf(float(x)) for x in row] for row in B])
        ys = [mpmath.det((1 - u) * A + u * B) for u in range(5)]
        # power coefficients through u = 0..4, then g' and its real roots in (0, 1)
        V = mpmath.matrix([[mpmath.mpf(u) ** k for k in range(5)] for u in range(5)])
        c = mpmath.lu_solve(V, mpmath.matrix(ys))
        g = lambda u: sum(c[k] * u ** k for k in range(5))  # noqa: E731
        crit = mpmath.polyroots([4 * c[4], 3 * c[3], 2 * c[2], c[1]], maxsteps=200, extraprec=200)
        pts = [0, 1] + [mpmath.re(r) for r in crit if abs(mpmath.im(r)) < 1e-30 and 0 < mpmath.re(r) < 1]
        gmax = max(g(u) for u in pts)
        return 1 if gmax > 0 else -1


def test_quadric_exact_matches_the_double_quadric():
    for ra, pa, qa, *_ in random_pairs(1, 5):
        E = np.array([[float(x) for x in row] for row in exact.quadric_exact(ra, pa, qa)])
        assert np.allclose(E, Q.quadric_matrix(ra, pa, qa), rtol=1e-12, atol=1e-12)


def test_quadric_from_w_exact_is_the_posed_quadric():
    """A pose y = R x + p is W = [[R^T, -R^T p], [0, 1]]; a scaled W gives a positive multiple."""
    q = (1.0, 2.0, -0.5, 0.25)
    p = (0.5, -1.0, 2.0)
    r = (1.0, 0.5, 0.25)
    P = exact.quadric_exact(r, p, q)
    w, x, y, z = map(Fraction, q)
    n = w * w + x * x + y * y + z * z
    R = [[(w * w + x * x - y * y - z * z) / n, 2 * (x * y - w * z) / n, 2 * (x * z + w * y) / n],
         [2 * (x * y + w * z) / n, (w * w - x * x + y * y - z * z) / n, 2 * (y * z - w * x) / n],
         [2 * (x * z - w * y) / n, 2 * (y * z + w * x) / n, (w * w - x * x - y * y + z * z) / n]]
    G = [[3 * R[k][i] for k in range(3)] for i in range(3)]  # 3 W: c^2 = 9 times the quadric
    h = [-sum(G[i][k] * Fraction(p[k]) for k in range(3)) for i in range(3)]
    W = exact.quadric_from_w_exact(G, h, 3, r)
    assert all(W[i][j] == 9 * P[i][j] for i in range(4) for j in range(4))


def test_exact_status_agrees_with_mpmath():
    seen = set()
    for pair in random_pairs(2, 12) + random_pairs(3, 4, thin=True):
        A = exact.quadric_exact(*pair[:3])
        B = exact.quadric_exact(*pair[3:])
        code = exact.static_status_exact(A, B)
        assert code == mp_status(A, B)
        seen.add(code)
    assert seen == {1, -1}


@pytest.mark.parametrize("d, expected", [(2.0, 0), (2.0 + 2.0 ** -40, 1), (2.0 - 2.0 ** -40, -1),
                                         (3.0, 1), (1.0, -1)])
def test_dyadic_spheres(d, expected):
    """Unit spheres at distance d: touching exactly at 2 (every number here is dyadic)."""
    r = (1.0, 1.0, 1.0)
    assert exact_code(r, (0.0, 0.0, 0.0), ID, r, (d, 0.0, 0.0), ID) == expected
    assert all_paths(np.array(r), np.zeros(3), np.array(ID), np.array(r), np.array([d, 0, 0]),
                     np.array(ID)) == NAMES[expected]
    if expected != 0:  # the kernels decide every pair that is not touching here
        assert pose_code(r, (0, 0, 0), ID, r, (d, 0, 0), ID) == expected
    else:
        assert pose_code(r, (0, 0, 0), ID, r, (d, 0, 0), ID) == Q.UNDECIDED
    # a rotated pair of spheres: still exact (rot(q) / |q|^2 is orthogonal for any q)
    q = (1.0, 2.0, 3.0, 4.0)
    pb = (0.0, d * 0.75, d)  # |pb| = 1.25 d: radii 1.25 make the same contact
    r2 = (1.25, 1.25, 1.25)
    assert exact_code(r2, (0.0, 0.0, 0.0), q, r2, pb, ID) == expected


def test_touching_ellipsoids_rotated_exactly():
    """(3, 1, 1) at the origin and (1, 2, 1) turned 90 degrees about z (q = (1, 0, 0, 1), not unit)."""
    qz = (1.0, 0.0, 0.0, 1.0)
    for x, expected in [(5.0, 0), (5.0 + 2.0 ** -45, 1), (5.0 - 2.0 ** -45, -1)]:
        args = ((3.0, 1.0, 1.0), (0.0, 0.0, 0.0), ID, (1.0, 2.0, 1.0), (x, 0.0, 0.0), qz)
        assert exact_code(*args) == expected
        assert Q.static_status_code(*args) == expected
        assert pose_code(*args) in (expected, Q.UNDECIDED)
    A = exact.quadric_exact((3.0, 1.0, 1.0), (0, 0, 0), ID)
    B = exact.quadric_exact((1.0, 2.0, 1.0), (4.0, 0, 0), ID)
    assert exact.static_status_exact(A, B) == 0
    assert exact.static_status_exact(A, [[float(x) for x in row] for row in B]) == 0  # dyadic: exact
    # floats are taken exactly: 1/9 rounded down widens A past the contact
    assert exact.static_status_exact([[float(x) for x in row] for row in A], B) == -1
    with pytest.raises(ValueError, match="not two ellipsoids"):
        exact.static_status_exact([[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]], B)


# ---------------------------------------------------------------- thin shapes


def thin_cases():
    """Parallel 1000:1 disks and needles 20 % of their size apart, axis-aligned and turned together."""
    disk, needle = (1.0, 1.0, 1e-3), (1.0, 1e-3, 1e-3)
    cases = [(disk, (0.0, 0.0, 0.2)),  # stacked: 0.2 apart along the thin axis
             (disk, (2.2, 0.0, 0.0)),  # side by side in their plane: gap 0.2
             (disk, (1.5, 0.0, 0.2)),
             (needle, (0.0, 0.2, 0.0)),  # side by side
             (needle, (2.2, 0.0, 0.0)),  # end to end
             (needle, (0.3, 0.1, 0.15))]
    rng = np.random.default_rng(7)
    out = []
    for r, offset in cases:
        for q in (np.array(ID), unit(rng.normal(size=4))):
            R = Q.quat_to_matrix(q)
            pa = rng.normal(size=3)
            out.append((np.array(r), pa, q, np.array(r), pa + R @ np.array(offset), q))
    return out


def test_thin_parallel_shapes_are_separate_everywhere():
    for pair in thin_cases():
        assert all_paths(*pair) == "separate"
        assert exact_code(*pair) == 1
        assert pose_code(*pair) in (1, Q.UNDECIDED)
    # axis-aligned, the double-precision kernel decides them itself
    for pair in thin_cases()[::2]:
        assert pose_code(*pair) == 1


def test_paths_agree_on_thin_and_random_pairs_near_contact():
    """Pairs scaled to just touch along random directions, then moved by tiny relative amounts."""
    rng = np.random.default_rng(11)
    undecided = decided = 0
    rows = []
    for k, (ra, pa, qa, rb, pb, qb) in enumerate(random_pairs(5, 6, thin=True) + random_pairs(6, 4)):
        direction = (pb - pa) / np.linalg.norm(pb - pa)
        lo, hi = 0.0, 4.0  # bisection on the kernel: -1 below the contact distance, 1 above
        for _ in range(60):
            mid = 0.5 * (lo + hi)
            code = pose_code(ra, pa, qa, rb, pa + mid * direction, qb)
            if code == Q.UNDECIDED:
                break
            lo, hi = (lo, mid) if code == 1 else (mid, hi)
        for rel in (0.0, 1e-15, -1e-15, 1e-12, -1e-12, 1e-9, -1e-9, 1e-6, -1e-6):
            pair = (ra, pa, qa, rb, pa + mid * (1.0 + rel) * direction, qb)
            code = pose_code(*pair)
            truth = exact_code(*pair)
            if code == Q.UNDECIDED:
                undecided += 1
            else:
                decided += 1
                assert code == truth, (k, rel)
            rows.append((pair, truth))
    assert undecided > 0 and decided > 0
    # static_status_many on all rows at once against the single-pair paths
    ra = np.array([p[0] for p, _ in rows])
    rb = np.array([p[3] for p, _ in rows])
    pa = np.array([np.r_[p[1], p[2]] for p, _ in rows])
    pb = np.array([np.r_[p[4], p[5]] for p, _ in rows])
    many = mjccd.static_status_many(ra, pa, rb, pb)
    assert [int(c) for c in many] == [t for _, t in rows]
    for (pair, truth), c in list(zip(rows, many))[::7]:
        assert mjccd.static_status(mjccd.Ellipsoid(pair[0]), (pair[1], pair[2]),
                                   mjccd.Ellipsoid(pair[3]), (pair[4], pair[5])) == NAMES[truth]


def test_matrix_kernel_is_certified():
    """static_status_matrices on the (rounded) world matrices: right where it decides, for those matrices."""
    for ra, pa, qa, rb, pb, qb in random_pairs(8, 6) + thin_cases()[:4]:
        A, B = Q.quadric_matrix(ra, pa, qa), Q.quadric_matrix(rb, pb, qb)
        code = int(Q.static_status_matrices(A, B))
        if code != Q.UNDECIDED:
            assert code == exact.static_status_exact(A, B)
    # touching spheres: the kernel must not guess
    A = Q.quadric_matrix(np.ones(3), np.zeros(3), np.array(ID))
    for d, expected in [(2.0, Q.UNDECIDED), (2.0 + 2.0 ** -30, 1), (2.0 - 2.0 ** -30, -1)]:
        B = Q.quadric_matrix(np.ones(3), np.array([d, 0.0, 0.0]), np.array(ID))
        assert Q.static_status_matrices(A, B) == expected


# ---------------------------------------------------------------- the rounding bounds, checked exactly


def scaled_pair_exact(ra, pa, qa, rb, pb, qb):
    """The pair as the pose kernels build it (A's frame scaled by |qa|^2, balanced by ka, kb), exactly."""
    def rot(q):
        w, x, y, z = map(Fraction, q)
        return [[w * w + x * x - y * y - z * z, 2 * (x * y - w * z), 2 * (x * z + w * y)],
                [2 * (x * y + w * z), w * w - x * x + y * y - z * z, 2 * (y * z - w * x)],
                [2 * (x * z - w * y), 2 * (y * z + w * x), w * w - x * x - y * y + z * z]], w * w + x * x + y * y + z * z

    RA, na = rot(qa)
    RB, nb = rot(qb)
    d = [Fraction(pa[i]) - Fraction(pb[i]) for i in range(3)]
    Rp = [[sum(RB[l][k] * RA[l][i] for l in range(3)) for i in range(3)] for k in range(3)]
    t = [sum(RB[l][k] * d[l] for l in range(3)) for k in range(3)]
    c = [sum(RA[l][i] * d[l] for l in range(3)) for i in range(3)]
    eb = [1 / Fraction(r) ** 2 for r in rb]
    ea = [1 / Fraction(r) ** 2 for r in ra]
    ka = Fraction(math.sqrt(float(ra[0]) * float(ra[1]) * float(ra[2])))
    kb = Fraction(math.sqrt(float(rb[0]) * float(rb[1]) * float(rb[2])))
    A = [[0] * 4 for _ in range(4)]
    for i in range(3):
        A[i][i] = ka * na * na * ea[i]
    A[3][3] = -ka
    B = [[0] * 4 for _ in range(4)]
    for i in range(3):
        for j in range(3):
            B[i][j] = kb * sum(eb[k] * Rp[k][i] * Rp[k][j] for k in range(3))
        B[i][3] = B[3][i] = kb * sum(eb[k] * Rp[k][i] * t[k] for k in range(3))
    sb = sum(eb[k] * t[k] * t[k] for k in range(3)) - nb * nb
    sa = sum(ea[i] * c[i] * c[i] for i in range(3)) - na * na
    B[3][3] = kb * sb
    return A, B, sb, sa


def bound_cases():
    rng = np.random.default_rng(12)
    cases = random_pairs(9, 5) + random_pairs(10, 5, thin=True)
    far = [(ra, pa + 1e3, qa, rb, pb + 1e3, qb) for ra, pa, qa, rb, pb, qb in random_pairs(13, 2)]
    unnormalised = [(ra, pa, 3.0 * qa, rb, pb, 0.5 * qb) for ra, pa, qa, rb, pb, qb in random_pairs(14, 2)]
    tiny = [(ra * 1e-3, pa * 1e-3, qa, rb * 1e-3, pb * 1e-3, qb) for ra, pa, qa, rb, pb, qb in random_pairs(15, 1)]
    return cases + far + unnormalised + tiny + [thin_cases()[k] for k in rng.choice(12, 3, replace=False)]


def exact_det(A, B, u, v):
    return exact.det([[Fraction(v) * a + Fraction(u) * b for a, b in zip(ra, rb)] for ra, rb in zip(A, B)])


def test_error_bounds_hold_exactly():
    """Every value the kernels compare is within its bound of the exact value (quick and tracked paths)."""
    for pair in bound_cases():
        args = tuple(tuple(map(float, x)) for x in pair)
        A, B, sb, sa = scaled_pair_exact(*args)
        # the scaled pair has the status of the posed pair (a congruence and positive factors)
        assert exact.static_status_exact(A, B) == exact_code(*args)
        a, ea, b, eb, qsb, qesb, qsa, qesa = Q._quick_pair(*args)
        tA, teA, tB, teB, tsb, tesb, tsa, tesa = Q._pose_pair(*args)
        assert abs(Fraction(qsb) - sb) <= Fraction(qesb) and abs(Fraction(tsb) - sb) <= Fraction(tesb)
        assert abs(Fraction(qsa) - sa) <= Fraction(qesa) and abs(Fraction(tsa) - sa) <= Fraction(tesa)
        for i in range(4):
            assert abs(Fraction(a[i]) - A[i][i]) <= Fraction(ea[i])
        blocks = [(0, 0, 0), (0, 1, 0), (0, 2, 0), (0, 3, 1), (1, 1, 0), (1, 2, 0), (1, 3, 1), (2, 2, 0),
                  (2, 3, 1), (3, 3, 2)]
        for (i, j, blk), x in zip(blocks, b):
            assert abs(Fraction(x) - B[i][j]) <= Fraction(eb[blk]), (i, j)
        for k in range(16):
            i, j = divmod(k, 4)
            assert abs(Fraction(tA[k]) - A[i][j]) <= Fraction(teA[k])
            assert abs(Fraction(tB[k]) - B[i][j]) <= Fraction(teB[k])
        us = np.random.default_rng(len(str(args))).uniform(0, 1)
        for u in (0.0, 0.25, 0.5, 0.75, 1.0, us):
            v = 1.0 - u
            truth = exact_det(A, B, u, v)
            val, err = Q._quick_det(u, a, ea, b, eb)
            assert abs(Fraction(val) - truth) <= Fraction(err)
            val, err = Q._pencil_det_e(u, v, tA, teA, tB, teB)
            assert abs(Fraction(val) - truth) <= Fraction(err)


def test_undecided_code_is_documented_and_resolved():
    assert Q.UNDECIDED == 2 and Q.UNDECIDED not in Q.STATUS_NAMES
    r = np.ones(3)
    codes = mjccd.static_status_many([r, r], [[0, 0, 0, 1, 0, 0, 0]] * 2, [r, r],
                                     [[2, 0, 0, 1, 0, 0, 0], [0, 0, 2.5, 1, 0, 0, 0]])
    assert codes.tolist() == [0, 1]


# ---------------------------------------------------------------- the integer algorithm against the Fraction one


def _ref_det(M):
    if len(M) == 1:
        return M[0][0]
    return sum((-1) ** j * M[0][j] * _ref_det([row[:j] + row[j + 1:] for row in M[1:]])
               for j in range(len(M)) if M[0][j] != 0)


def _ref_trim(p):
    while p and p[-1] == 0:
        p = p[:-1]
    return p


def _ref_value(p, x):
    acc = Fraction(0)
    for c in reversed(p):
        acc = acc * x + c
    return acc


def _ref_interpolate(ys):
    n = len(ys)
    dd = list(ys)
    for level in range(1, n):
        for k in range(n - 1, level - 1, -1):
            dd[k] = (dd[k] - dd[k - 1]) / level
    p = [Fraction(0)]
    for k in range(n - 1, -1, -1):
        p = [a - k * b for a, b in zip([Fraction(0)] + p, p + [Fraction(0)])]
        p[0] += dd[k]
    return _ref_trim(p)


def _ref_derivative(p):
    return _ref_trim([k * c for k, c in enumerate(p)][1:])


def _ref_divmod(a, b):
    a = list(a)
    q = [Fraction(0)] * max(len(a) - len(b) + 1, 0)
    while len(a) >= len(b) and a:
        k = len(a) - len(b)
        c = a[-1] / b[-1]
        q[k] = c
        for i, bc in enumerate(b):
            a[i + k] -= c * bc
        a = _ref_trim(a[:-1])
    return q, a


def _ref_gcd(a, b):
    while b:
        a, b = b, _ref_divmod(a, b)[1]
    return [c / a[-1] for c in a]


def _ref_sign_changes(seq, x):
    signs = [s for s in (_ref_value(p, x) for p in seq) if s != 0]
    return sum(1 for s, t in zip(signs, signs[1:]) if (s > 0) != (t > 0))


def _ref_roots_between(q, lo, hi):
    seq = [q, _ref_derivative(q)]
    while seq[-1] and len(seq[-1]) > 1:
        seq.append([-c for c in _ref_divmod(seq[-2], seq[-1])[1]])
    seq = [p for p in seq if p]
    out, todo = [], [(lo, hi)]
    while todo:
        a, b = todo.pop()
        n = _ref_sign_changes(seq, a) - _ref_sign_changes(seq, b)
        if n == 1:
            out.append((a, b))
        elif n > 1:
            m = (a + b) / 2
            while _ref_value(q, m) == 0:
                m = (a + m) / 2
            todo += [(m, b), (a, m)]
    return sorted(out)


def reference_status(A, B):
    """The former static_status_exact (Fractions: g from five determinants, square-free part, Sturm).

    Verbatim but for one fix: it took int entries as they are, and its divided differences then divided ints
    into floats (inexact); here ints become Fractions."""
    fr = lambda x: x if isinstance(x, Fraction) else Fraction(x) if isinstance(x, int) else Fraction(float(x))  # noqa: E731
    A = [[fr(x) for x in row] for row in A]
    B = [[fr(x) for x in row] for row in B]
    ys = [_ref_det([[(1 - u) * a + u * b for a, b in zip(ra, rb)] for ra, rb in zip(A, B)]) for u in range(5)]
    g = _ref_interpolate(ys)
    if not g:
        raise ValueError("degenerate pencil: det((1-u)A + uB) vanishes identically")
    q = _ref_divmod(g, _ref_gcd(g, _ref_derivative(g)))[0] if len(g) > 1 else g
    zero, one = Fraction(0), Fraction(1)
    if not (ys[0] < 0 and ys[1] < 0):
        raise ValueError("not two ellipsoids: det A and det B must be negative")
    roots = _ref_roots_between(q, zero, one)
    points = [zero, one] + [b for _, b in roots[:-1]]
    if any(_ref_value(g, x) > 0 for x in points):
        return 1
    return 0 if roots else -1


def _posed(ra, pa, qa, rb, pb, qb):
    return exact.quadric_exact(ra, pa, qa), exact.quadric_exact(rb, pb, qb)


def near_touching_pairs(seed, n):
    """Pairs at their contact distance along a random direction (bisection on the exact status, 2^-40), moved
    by small relative amounts: thin (1000:1) ones, far ones (1e6 from the origin), unnormalised quaternions."""
    rng = np.random.default_rng(seed)
    out = []
    for k in range(n):
        if k % 3 == 0:
            ra = rng.permutation([1.0, 1.0, 1e-3]) if rng.random() < 0.5 else rng.permutation([1.0, 1e-3, 1e-3])
            rb = rng.permutation([1.0, 1.0, 1e-3]) if rng.random() < 0.5 else rng.permutation([1.0, 1e-3, 1e-3])
        else:
            ra, rb = rng.uniform(0.2, 1.0, 3), rng.uniform(0.2, 1.0, 3)
        qa, qb = rng.normal(size=4) * rng.uniform(0.1, 10.0), rng.normal(size=4) * rng.uniform(0.1, 10.0)
        pa = rng.normal(size=3) + (1e6 if k % 4 == 1 else 0.0)
        d = rng.normal(size=3)
        d /= np.linalg.norm(d)
        A = exact.quadric_exact(ra, pa, qa)
        lo, hi = 0.0, 4.0
        for _ in range(40):
            mid = 0.5 * (lo + hi)
            if exact.static_status_exact(A, exact.quadric_exact(rb, pa + mid * d, qb)) == 1:
                hi = mid
            else:
                lo = mid
        for dist in (lo, hi, hi * (1 + 1e-9), lo * (1 - 1e-9), hi * (1 + 1e-5), lo * (1 - 1e-5)):
            out.append((A, exact.quadric_exact(rb, pa + dist * d, qb)))
    return out


def exactly_touching_pairs():
    """Ellipsoids touching exactly at the tip of an axis (dyadic radii), the configuration turned by rational
    rotations (integer quaternions) and moved far away, each with the contact moved 2^-40 either way."""
    out = []
    configs = [((1.0, 1.0, 1.0), (1.0, 1.0, 1.0)), ((3.0, 1.0, 1.0), (1.0, 2.0, 1.0)),
               ((0.5, 0.25, 2.0), (0.75, 1.5, 0.125)), ((1.0, 1.0, 2.0 ** -10), (1.0, 2.0 ** -10, 2.0 ** -10))]
    quats = [(1, 0, 0, 0), (1, 2, 3, 4), (3, -1, 0, 2)]
    for (ra, rb) in configs:
        for q in quats:
            w, x, y, z = map(Fraction, q)
            n = w * w + x * x + y * y + z * z
            R = [[(w * w + x * x - y * y - z * z) / n, 2 * (x * y - w * z) / n, 2 * (x * z + w * y) / n],
                 [2 * (x * y + w * z) / n, (w * w - x * x + y * y - z * z) / n, 2 * (y * z - w * x) / n],
                 [2 * (x * z - w * y) / n, 2 * (y * z + w * x) / n, (w * w - x * x - y * y + z * z) / n]]
            for origin in ((0, 0, 0), (2.0 ** 20, -(2.0 ** 20), 3.0 * 2 ** 19)):
                pa = [Fraction(o) for o in origin]
                for shift, expected in ((0, 0), (Fraction(1, 2 ** 40), 1), (-Fraction(1, 2 ** 40), -1)):
                    local = Fraction(ra[0]) + Fraction(rb[0]) + shift
                    pb = [pa[i] + R[i][0] * local for i in range(3)]
                    out.append(((ra, pa, q, rb, pb, q), expected))
    return out


def _algebraic_cases():
    """Matrix pencils (not ellipsoids, det < 0 at both ends) with chosen root structures of g."""
    def block(p, q, r):  # det = -(p^2 + q^2) r^2
        return [[p, q, 0, 0], [q, -p, 0, 0], [0, 0, r, 0], [0, 0, 0, r]]
    return [
        (block(1, 2, 3), block(-3, -6, -1), 0),  # g = -5 (1 - 4u)^2 (3 - 4u)^2: two double roots in (0, 1)
        (block(1, 2, 3), block(-3, -6, 3), 0),  # r constant: one double root
        (block(1, 2, 3), block(-3, -5, -1), 0),  # p, q roots apart: p^2 + q^2 > 0, r^2's double root at 3/4
        (block(1, 2, 3), block(-3, -5, 5), -1),  # and r without root: g < 0
        (block(1, 2, 3), block(-3, -6, 5), 0),  # the double root of p^2 + q^2 only, r's root outside (0, 1)
        ([[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, -3]],  # g = -(1 - 4u)^3 (3 - 4u): triple + simple root
         [[-3, 0, 0, 0], [0, -3, 0, 0], [0, 0, -3, 0], [0, 0, 0, 1]], 1),
        ([[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, -1]],  # g = -(1 - 2u)^4: a quadruple root
         [[-1, 0, 0, 0], [0, -1, 0, 0], [0, 0, -1, 0], [0, 0, 0, 1]], 0),
        ([[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, -1]],  # roots 1/2 (triple) and 1/4: separate
         [[-1, 0, 0, 0], [0, -1, 0, 0], [0, 0, -1, 0], [0, 0, 0, 3]], 1),
        ([[2, 0, 0, 0], [0, 2, 0, 0], [0, 0, 2, 0], [0, 0, 0, -2]],  # g = -(2 - u)^4: no root in [0, 1]
         [[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, -1]], -1),
    ]


def _status_pairs():
    """(A, B) pairs: random, thin, near-touching and exactly touching."""
    pairs = [_posed(*p) for p in random_pairs(21, 40) + random_pairs(22, 30, thin=True)]
    far = [(ra, pa + 1e6, 7.0 * qa, rb, pb + 1e6, 0.01 * qb) for ra, pa, qa, rb, pb, qb in random_pairs(23, 20)]
    pairs += [_posed(*p) for p in far]
    pairs += near_touching_pairs(24, 24)
    pairs += [_posed(*p) for p, _ in exactly_touching_pairs()]
    return pairs


def test_integer_status_matches_the_fraction_algorithm():
    seen = {}
    for A, B in _status_pairs():
        code = exact.static_status_exact(A, B)
        assert code == reference_status(A, B)
        seen[code] = seen.get(code, 0) + 1
    assert set(seen) == {-1, 0, 1} and min(seen.values()) >= 10, seen


def test_exactly_touching_pairs_and_their_neighbours():
    for pair, expected in exactly_touching_pairs():
        assert exact.static_status_exact(*_posed(*pair)) == expected, pair


@pytest.mark.parametrize("subdivisions", [exact.SUBDIVISIONS, 0, 3])
def test_root_structures_and_the_sturm_path(monkeypatch, subdivisions):
    """The Sturm fallback (no subdivision, or few) decides as the subdivision does, on every kind of pair."""
    monkeypatch.setattr(exact, "SUBDIVISIONS", subdivisions)
    for A, B, expected in _algebraic_cases():
        assert reference_status(A, B) == expected
        assert exact.static_status_exact(A, B) == expected, (A, B)
        F = [[Fraction(x, 3) for x in row] for row in A]  # other positive factors and types: the same
        assert exact.static_status_exact(F, [[float(7 * x) for x in row] for row in B]) == expected
        assert exact.static_status_exact(np.array(A, float), np.array(B, np.int64)) == expected
    pairs = _status_pairs()[::4]
    for A, B in pairs:
        assert exact.static_status_exact(A, B) == reference_status(A, B)


def test_integer_form_is_the_pencil_determinant():
    """The binary quartic's coefficients against g's values, and the integer scaling (content 1)."""
    rng = np.random.default_rng(31)
    for _ in range(5):
        A = [[Fraction(int(rng.integers(-50, 50)), int(rng.integers(1, 30))) for _ in range(4)] for _ in range(4)]
        B = [[Fraction(int(rng.integers(-50, 50)), int(rng.integers(1, 30))) for _ in range(4)] for _ in range(4)]
        IA, IB = exact._integer_matrix(A), exact._integer_matrix(B)
        assert math.gcd(*[x for row in IA for x in row]) == 1
        ratio = {IA[i][j] / A[i][j] for i in range(4) for j in range(4) if A[i][j]}
        assert len(ratio) == 1 and ratio.pop() > 0
        c = exact._pencil_form(IA, IB)
        for x, y in [(1, 0), (0, 1), (1, 1), (2, -3), (5, 7)]:
            M = [[x * a + y * b for a, b in zip(ra, rb)] for ra, rb in zip(IA, IB)]
            assert sum(c[j] * x ** (4 - j) * y ** j for j in range(5)) == exact.det(M)


def test_errors_are_kept():
    I4 = [[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]]
    Z = [[0] * 4 for _ in range(4)]
    S = [[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, -1]]
    with pytest.raises(ValueError, match="degenerate pencil"):
        exact.static_status_exact(Z, Z)
    with pytest.raises(ValueError, match="not two ellipsoids"):
        exact.static_status_exact(I4, S)
    with pytest.raises(ValueError, match="not two ellipsoids"):
        exact.static_status_exact(S, I4)


def test_small_integer_pencils_with_repeated_roots(monkeypatch):
    """Diagonal and 2x2-block integer pencils: g a product of small linear and quadratic factors, often with
    double, triple and quadruple roots in (0, 1); subdivision and the Sturm path against the reference."""
    rng = np.random.default_rng(41)
    cases = []
    while len(cases) < 300:
        a, b = rng.integers(-3, 4, 4).tolist(), rng.integers(-3, 4, 4).tolist()
        A = [[a[i] if i == j else 0 for j in range(4)] for i in range(4)]
        B = [[b[i] if i == j else 0 for j in range(4)] for i in range(4)]
        if rng.random() < 0.5:  # a block [[p, q], [q, -p]]: the factor -(p^2 + q^2)
            A[0][1] = A[1][0] = int(rng.integers(-3, 4))
            B[0][1] = B[1][0] = int(rng.integers(-3, 4))
            A[1][1], B[1][1] = -A[0][0], -B[0][0]
        if exact.det(A) < 0 and exact.det(B) < 0:
            cases.append((A, B, reference_status(A, B)))
    assert {e for *_, e in cases} == {-1, 0, 1}
    for subdivisions in (exact.SUBDIVISIONS, 0):
        monkeypatch.setattr(exact, "SUBDIVISIONS", subdivisions)
        for A, B, expected in cases:
            assert exact.static_status_exact(A, B) == expected, (A, B)


def test_integer_quadric_is_a_positive_multiple_of_the_rational_one():
    """exact.quadric_exact_integer against exact.quadric_exact on float and rational poses (far, tiny, thin):
    the same matrix up to a positive factor, entry for entry."""
    from fractions import Fraction

    from mjccd import exact

    rng = np.random.default_rng(0)
    for k in range(200):
        r = rng.uniform(0.001, 3.0, 3)
        p = rng.normal(size=3) * 10.0 ** rng.integers(-3, 7)
        q = rng.normal(size=4)
        if k % 3 == 0:  # a pose at a dyadic time between two float poses, as the rational tier forms it
            t = Fraction(int(rng.integers(1, 2 ** 20)), 2 ** 20)
            p = [Fraction(float(x)) * (1 - t) + Fraction(float(y)) * t for x, y in zip(p, rng.normal(size=3))]
            q = [Fraction(float(x)) * (1 - t) + Fraction(float(y)) * t for x, y in zip(q, rng.normal(size=4))]
        assert (exact._integer_matrix(exact.quadric_exact_integer(r, p, q))
                == exact._integer_matrix(exact.quadric_exact(r, p, q))), k


# ---------------------------------------------------------------- stretches proven separate (mjccd.exact_stretch)


def test_bernstein_of_values_is_exact():
    from mjccd.exact_stretch import _bernstein_of_values
    rng = np.random.default_rng(5)
    for n in (1, 2, 7, 24):
        power = [Fraction(int(x), int(d)) for x, d in zip(rng.integers(-9, 10, n + 1), rng.integers(1, 6, n + 1))]
        p = lambda s: sum(c * s ** j for j, c in enumerate(power))  # noqa: E731
        b = _bernstein_of_values([p(Fraction(k, n)) for k in range(n + 1)])
        s = Fraction(3, 7)
        assert sum(b[i] * math.comb(n, i) * s ** i * (1 - s) ** (n - i) for i in range(n + 1)) == p(s)


def _sphere_pair(gap_end):
    """Unit sphere static at 0 and a unit sphere moving along x from centre 3 to 2 + gap_end: the exact
    quadrics of their W forms (polynomial in t) and the degree."""
    from mjccd.ccd import _ExactPair
    a, b = mjccd.Ellipsoid([1.0, 1.0, 1.0]), mjccd.Ellipsoid([1.0, 1.0, 1.0])
    moving = mjccd.Rigid([3.0, 0.0, 0.0], [1.0, 0, 0, 0], [2.0 + gap_end, 0.0, 0.0], [1.0, 0, 0, 0])
    return _ExactPair(a, mjccd.Static([0.0, 0.0, 0.0], [1.0, 0, 0, 0]), b, moving).polynomial()


def test_a_stretch_is_proven_separate_exactly_up_to_the_contact():
    """Unit spheres: clear by 1/4 at the end, [0, 1] is proven at once; touching at t = 1, [0, 1/2] is
    and [0, 1] is not, and halving proves all but the finest piece before 1; meeting at t = 1/2, nothing
    past 1/2 is ever proven."""
    from mjccd.exact_stretch import positive_through, separate_until
    A, B, degree = _sphere_pair(0.25)   # clear by 1/4 at t = 1
    assert positive_through(A, B, degree, Fraction(0), Fraction(1))
    A, B, degree = _sphere_pair(0.0)    # touching at t = 1
    assert positive_through(A, B, degree, Fraction(0), Fraction(1, 2))
    assert not positive_through(A, B, degree, Fraction(0), Fraction(1))
    proven, failed = separate_until(A, B, degree, 0.0, 1.0, Fraction(1, 2 ** 20), 200)
    assert failed is not None and failed[1] == 1 and Fraction(1) - proven <= Fraction(1, 2 ** 20)
    A, B, degree = _sphere_pair(-1.0)   # centre distance 3 - 2 t: touching at t = 1/2
    proven, failed = separate_until(A, B, degree, 0.0, 1.0, Fraction(1, 2 ** 10), 200)
    assert proven <= Fraction(1, 2) and failed is not None


def test_the_witness_is_the_quartics_maximum_where_the_float_search_misses_it():
    """A quartic in u with a narrow positive peak at u = 1/1000 and a flat negative rest (as det((1 - u) A + u B)
    is for a 1000:1 disk just clear of another): the float grid's candidates all lie where it is negative, and
    the exact search finds the peak to 2^-60."""
    from mjccd.exact_stretch import _bernstein_of_values, _maxima

    peak = Fraction(1, 1000)
    q = lambda u: Fraction(1, 10 ** 12) - (u - peak) ** 2 * (1 + u) ** 2  # noqa: E731 (a peak of 1e-12)
    coefficients = _bernstein_of_values([q(Fraction(k, 4)) for k in range(5)])
    maxima = _maxima(coefficients)
    assert len(maxima) == 1 and abs(maxima[0] - peak) < Fraction(1, 2 ** 50) and q(maxima[0]) > 0


def test_thin_disks_just_clear_of_each_other_are_proven_free():
    """1000:1 needles over disks and disks edge over face, passing 1e-6 of their size clear of each other (the
    stacked family of tests/test_adversarial.py): the rational stretch proof certifies every one free.  Before
    the exact search for the witness u, the float search picked a u near 1 where the determinant is negative,
    and these came back as possible contacts with brackets like [0.39, 1.0]."""
    import random
    import sys

    sys.path.insert(0, str(Path(__file__).parent))
    import test_adversarial as ta

    rng = random.Random(5)
    for n, (ra, rb, a_static) in enumerate([(ta.NEEDLE_UP, ta.DISK_FACE, False), (ta.DISK_FACE, ta.DISK_EDGE, False)]
                                           * 2):
        case = ta._stacked(rng, f"clear-{n}", list(ra), list(rb), 1e-6 * max(ra + rb), a_static, [])
        motions = []
        for m in (case["a"]["motion"], case["b"]["motion"]):
            motions.append(mjccd.Rigid(m["start"]["position"], m["start"]["quaternion"], m["end"]["position"],
                                       m["end"]["quaternion"]))
        assert mjccd.first_contact(mjccd.Ellipsoid(ra), motions[0], mjccd.Ellipsoid(rb), motions[1]) is None, n
