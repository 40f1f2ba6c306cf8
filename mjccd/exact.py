"""Exact static status of two ellipsoids, in rational arithmetic (``fractions.Fraction``).

Every double is a rational number, so the quadric of an ellipsoid placed by
double-precision radii, position and quaternion is an exact rational matrix
(the quaternion is normalised exactly: ``rot(q) / |q|^2`` is orthogonal for
any q, no square root needed).  :func:`static_status_exact` then decides the
sign of ``max_u g(u)``, ``g(u) = det((1 - u) A + u B)`` over [0, 1] (thesis
Thm 4.1) without rounding: it is the referee of the double-precision tests in
:mod:`mjccd.quadric`, which hand it the pairs they cannot decide (code 2).

The decision is made in integers (positive multiples of A and B, an integer
binary quartic, Bernstein subdivision and, rarely, Sturm's theorem): pure
Python, a fraction of a millisecond a pair, near-touching ones included.
"""
import math
import numbers
from fractions import Fraction

import numpy as np

from mjccd.errors import InputError

SEPARATE, TOUCHING, OVERLAPPING = 1, 0, -1


def _fr(x):
    """An exact rational: a Fraction as is, an integer or a float converted exactly.

    (Integers become Fractions too: an int kept as is would turn the true
    divisions below into float ones.)
    """
    if isinstance(x, Fraction):
        return x
    if isinstance(x, numbers.Integral):
        return Fraction(int(x))
    return Fraction(float(x))


def quadric_from_w_exact(G, h, g, radii):
    """4x4 quadric (lists of Fractions) of ``{x : |D^(1/2) (G x + h)|^2 <= g^2}``, ``D = diag(1/r^2)``.

    That is ``[[P, U], [U^T, s]]`` with ``P = G^T D G``, ``U = G^T D h`` and
    ``s = h^T D h - g^2``: the ellipsoid under the motion whose scaled
    inverse is ``W = [[G, h], [0, g]]`` (see :func:`mjccd.motion.quadric_from_w`).
    """
    G = [[_fr(x) for x in row] for row in G]
    h = [_fr(x) for x in h]
    d = [1 / _fr(r) ** 2 for r in radii]
    Q = [[Fraction(0)] * 4 for _ in range(4)]
    for i in range(3):
        for j in range(3):
            Q[i][j] = sum(d[k] * G[k][i] * G[k][j] for k in range(3))
        Q[i][3] = Q[3][i] = sum(d[k] * G[k][i] * h[k] for k in range(3))
    Q[3][3] = sum(d[k] * h[k] * h[k] for k in range(3)) - _fr(g) ** 2
    return Q


def quadric_exact(radii, position, quaternion):
    """Exact world quadric ``M^-T diag(1/a^2, 1/b^2, 1/c^2, -1) M^-1`` of a posed ellipsoid.

    The pose maps the frame to the world by ``y = R x + p`` with
    ``R = rot(q) / |q|^2``, so ``x = R^T y - R^T p``: ``G = R^T``, ``h = -R^T p``, ``g = 1``.
    """
    w, x, y, z = (_fr(c) for c in quaternion)
    n = w * w + x * x + y * y + z * z
    if n == 0:
        raise InputError("quaternion: zero quaternion")
    R = [[(w * w + x * x - y * y - z * z) / n, 2 * (x * y - w * z) / n, 2 * (x * z + w * y) / n],
         [2 * (x * y + w * z) / n, (w * w - x * x + y * y - z * z) / n, 2 * (y * z - w * x) / n],
         [2 * (x * z - w * y) / n, 2 * (y * z + w * x) / n, (w * w - x * x - y * y + z * z) / n]]
    p = [_fr(c) for c in position]
    G = [[R[k][i] for k in range(3)] for i in range(3)]
    h = [-sum(G[i][k] * p[k] for k in range(3)) for i in range(3)]
    return quadric_from_w_exact(G, h, 1, radii)


def quadric_exact_integer(radii, position, quaternion):
    """:func:`quadric_exact` times a positive number that makes every entry an integer (rows of ints).

    The decisions in integers (:func:`static_status_exact`,
    :func:`touching_point_exact`) take any positive multiple of a quadric;
    this one is formed in integers throughout, several times faster than in
    Fractions.  With ``den`` the common denominator of the pose's numbers,
    ``N = den^2 |q|^2 R`` (integers), ``P = den p`` and ``r_k = a_k / b_k``,
    the factor is ``|q|^4 den^6 (a_0 a_1 a_2)^2``.
    """
    q = [_fr(c) for c in quaternion]
    p = [_fr(c) for c in position]
    den = math.lcm(*(c.denominator for c in q + p))
    w, x, y, z = (c.numerator * (den // c.denominator) for c in q)
    n = w * w + x * x + y * y + z * z
    if n == 0:
        raise InputError("quaternion: zero quaternion")
    N = [[w * w + x * x - y * y - z * z, 2 * (x * y - w * z), 2 * (x * z + w * y)],
         [2 * (x * y + w * z), w * w - x * x + y * y - z * z, 2 * (y * z - w * x)],
         [2 * (x * z - w * y), 2 * (y * z + w * x), w * w - x * x - y * y + z * z]]  # n R
    P = [c.numerator * (den // c.denominator) for c in p]
    r = [_fr(c) for c in radii]
    a = [c.numerator for c in r]
    b = [c.denominator for c in r]
    e = [(b[k] * a[(k + 1) % 3] * a[(k + 2) % 3]) ** 2 for k in range(3)]  # (a_0 a_1 a_2)^2 / r_k^2
    v = [N[0][k] * P[0] + N[1][k] * P[1] + N[2][k] * P[2] for k in range(3)]  # n den R^T p
    Q = [[0] * 4 for _ in range(4)]
    for i in range(3):
        for j in range(i, 3):
            Q[i][j] = Q[j][i] = den * den * sum(e[k] * N[i][k] * N[j][k] for k in range(3))
        Q[i][3] = Q[3][i] = -den * sum(e[k] * N[i][k] * v[k] for k in range(3))
    Q[3][3] = sum(e[k] * v[k] * v[k] for k in range(3)) - (n * den * a[0] * a[1] * a[2]) ** 2
    return Q


# ---------------------------------------------------------------- determinants


def det(M):
    """Determinant by Laplace expansion along the first row (exact; small matrices only)."""
    if len(M) == 1:
        return M[0][0]
    return sum((-1) ** j * M[0][j] * det([row[:j] + row[j + 1:] for row in M[1:]])
               for j in range(len(M)) if M[0][j] != 0)


# ---------------------------------------------------------------- the static status, in integers


def _integer_matrix(M):
    """A positive integer multiple of the rational 4x4 matrix M (rows of ints), with content 1."""
    num, den = [], []
    for row in M:
        for x in row:
            if isinstance(x, int):
                n, d = x, 1
            elif isinstance(x, Fraction):
                n, d = x.numerator, x.denominator
            elif isinstance(x, numbers.Integral):
                n, d = int(x), 1
            else:
                n, d = float(x).as_integer_ratio()
            num.append(n)
            den.append(d)
    lcm = math.lcm(*den)
    ints = [n * (lcm // d) for n, d in zip(num, den)]
    content = math.gcd(*ints)
    if content > 1:
        ints = [n // content for n in ints]
    return [ints[i:i + 4] for i in range(0, 16, 4)]


def _pencil_form(A, B):
    """Coefficients (c0, ..., c4) of the binary quartic ``det(x A + y B) = sum c_j x^(4-j) y^j`` (A, B 4x4 ints).

    Laplace expansion along the row pairs (0, 1) and (2, 3): each 2x2 minor of
    ``x A + y B`` is a binary quadratic, and the determinant is the signed sum
    of six products of complementary minors.
    """
    def minors(r0, r1):
        a0, a1, b0, b1 = A[r0], A[r1], B[r0], B[r1]
        out = {}
        for i in range(4):
            for j in range(i + 1, 4):
                out[i, j] = (a0[i] * a1[j] - a0[j] * a1[i],
                             a0[i] * b1[j] - a0[j] * b1[i] + b0[i] * a1[j] - b0[j] * a1[i],
                             b0[i] * b1[j] - b0[j] * b1[i])
        return out

    top, bottom = minors(0, 1), minors(2, 3)
    c = [0] * 5
    for (i, j), sign in (((0, 1), 1), ((0, 2), -1), ((0, 3), 1), ((1, 2), 1), ((1, 3), -1), ((2, 3), 1)):
        p, q = top[i, j], bottom[tuple(k for k in range(4) if k != i and k != j)]
        if sign < 0:
            p = (-p[0], -p[1], -p[2])
        c[0] += p[0] * q[0]
        c[1] += p[0] * q[1] + p[1] * q[0]
        c[2] += p[0] * q[2] + p[1] * q[1] + p[2] * q[0]
        c[3] += p[1] * q[2] + p[2] * q[1]
        c[4] += p[2] * q[2]
    return c


def _primitive(p):
    """p divided by the (positive) gcd of its integer coefficients."""
    g = math.gcd(*p)
    return [c // g for c in p] if g > 1 else p


def _positive_remainder(a, b):
    """A positive multiple of the remainder of a by b (integer coefficient lists, lowest first, b[-1] != 0)."""
    a = list(a)
    lb, nb = b[-1], len(b)
    sb = 1 if lb > 0 else -1
    while len(a) >= nb:
        la = a[-1]
        if la:
            g = math.gcd(la, lb)
            m, f = abs(lb) // g, sb * la // g  # a <- m a - f x^k b: m > 0, the top term cancels
            k = len(a) - nb
            if m != 1:
                a = [m * x for x in a]
            for i, bc in enumerate(b):
                a[i + k] -= f * bc
        a.pop()
    while a and a[-1] == 0:
        a.pop()
    return a


def _sign_variations(signs):
    signs = [s for s in signs if s]
    return sum(1 for s, t in zip(signs, signs[1:]) if (s > 0) != (t > 0))


def _distinct_positive_roots(p):
    """Number of distinct roots in (0, inf) of the integer polynomial p (p[0] != 0), and gcd(p, p').

    Sturm's theorem on the sequence p, p', -rem, ... (kept primitive: only
    positive factors are dropped, so the signs are those of the Sturm
    sequence), counted between 0 (the constant terms) and +inf (the leading
    coefficients).  It counts distinct roots also when p is not square-free.
    """
    seq = [_primitive(p), _primitive([k * c for k, c in enumerate(p)][1:])]
    while len(seq[-1]) > 1:
        r = _positive_remainder(seq[-2], seq[-1])
        if not r:
            break
        seq.append(_primitive([-c for c in r]))
    n = _sign_variations([s[0] for s in seq]) - _sign_variations([s[-1] for s in seq])
    return n, seq[-1]


SUBDIVISIONS = 200  # Bernstein halvings tried before Sturm decides


def _bisect_status(c):
    """The status proven by Bernstein subdivision of g (binary form c), or None when undecided.

    On an interval of [0, 1], g's Bernstein coefficients (here integers, up to
    a positive factor) enclose g: the end ones are its values at the ends, and
    g lies between the least and the greatest.  The ends are never positive
    here (negative at 0 and 1, and a positive value at a split point ends the
    search), so an interval whose inner coefficients are all <= 0 has g <= 0
    on it, and is dropped.  The others are halved (de Casteljau, without its
    halvings: the halves are 2^4 times their Bernstein coefficients); the
    value at the split point is exact, and a positive one proves the pair
    separate.  When every interval is dropped, g <= 0 on [0, 1]: touching if g
    was 0 at a split point, else overlapping.  Around a double root of g off
    the split points (touching, or nearly) the halving goes on: None after
    SUBDIVISIONS halvings.
    """
    stack = [(12 * c[0], 3 * c[1], 2 * c[2], 3 * c[3], 12 * c[4])]  # c_j / binom(4, j), times 12
    splits, touched = 0, False
    while stack:
        b0, b1, b2, b3, b4 = stack.pop()
        if b1 <= 0 and b2 <= 0 and b3 <= 0:
            continue
        splits += 1
        if splits > SUBDIVISIONS:
            return None
        l1, m1, n1, r1 = b0 + b1, b1 + b2, b2 + b3, b3 + b4
        l2, m2, r2 = l1 + m1, m1 + n1, n1 + r1
        l3, r3 = l2 + m2, m2 + r2
        mid = l3 + r3  # 16 g at the split point, up to the interval's positive factor
        if mid > 0:
            return SEPARATE
        touched = touched or mid == 0
        stack.append((mid, r3 << 1, r2 << 2, r1 << 3, b4 << 4))
        stack.append((b0 << 4, l1 << 3, l2 << 2, l3 << 1, mid))
    return TOUCHING if touched else OVERLAPPING


def static_status_exact(A, B):
    """1 (separate), 0 (touching) or -1 (overlapping) of the quadrics A, B, decided exactly.

    ``A``, ``B``: 4x4 of floats, ints or Fractions (ellipsoids: ``det < 0``),
    taken exactly.  The status is the sign of the maximum of ``g(u) =
    det((1 - u) A + u B)`` over [0, 1].  Positive factors do not change it:
    ``det((1 - u) a A + u b B)`` is g reparametrised monotonically on [0, 1]
    times a positive factor, so A and B are replaced by integer multiples A',
    B', and all the work is in integers.  The binary quartic ``det(x A' + y
    B') = sum c_j x^(4-j) y^j`` has integer coefficients: g's Bernstein
    coefficients are ``c_j / binom(4, j)`` up to a positive factor, and
    ``c0``, ``c4`` (det A', det B') must be negative.

    Bernstein subdivision (:func:`_bisect_status`) settles separate and
    overlapping pairs, near-touching ones included, and pairs touching at a
    dyadic u.  What it leaves (touching, or all but touching) Sturm decides: ``u = y / (x + y)`` maps g's roots in
    (0, 1) onto the positive roots of ``P(t) = sum c_j t^j``, and their
    number n of distinct ones is a count of sign changes at 0 and +inf.  g < 0
    at both ends, so the roots in (0, 1) have even total multiplicity (at most
    4), and g changes sign (separate) exactly at a root of odd multiplicity:
    n = 0 is overlapping, n = 1 (a double or quadruple root) touching, n >= 3
    (some simple root) separate, and n = 2 touching exactly when both roots
    are double, that is when gcd(P, P') has degree 2 and two distinct roots.
    """
    if len(A) != 4 or len(B) != 4 or any(len(row) != 4 for row in A) or any(len(row) != 4 for row in B):
        raise InputError("A and B must be 4x4")
    c = _pencil_form(_integer_matrix(A), _integer_matrix(B))
    if not any(c):
        raise InputError("degenerate pencil: det((1-u)A + uB) vanishes identically")
    if not (c[0] < 0 and c[4] < 0):  # g(0) = det A, g(1) = det B, times positive factors
        raise InputError("not two ellipsoids: det A and det B must be negative")
    verdict = _bisect_status(c)
    if verdict is not None:
        return verdict
    n, gcd = _distinct_positive_roots(c)
    if n == 0:
        return OVERLAPPING
    if n == 1:
        return TOUCHING
    if n == 2 and len(gcd) == 3 and gcd[1] * gcd[1] != 4 * gcd[0] * gcd[2]:
        return TOUCHING
    return SEPARATE


# ---------------------------------------------------------------- the touching point


def _rounded(x, bits=160):
    """x rounded to a multiple of 2^-bits: keeps Newton's iterates short."""
    return Fraction(round(x * (1 << bits)), 1 << bits)


def touching_point_exact(A, B):
    """Touching point and unit normal (outward from A) of two quadrics that touch, to far below double rounding.

    At a touch the quartic ``g(s) = det((1 - s) A + s B)`` has a double root s* in
    (0, 1), where it is largest; the matrix there is singular and its null vector
    is the point.  s* comes from Newton's method on g' in rationals kept to 160
    bits, started from the critical point (a root of the cubic g', found in
    double precision) where g is largest; the null vector from the cofactors
    of the row with the largest diagonal cofactor.  Returns floats.
    """
    A, B = _integer_matrix(A), _integer_matrix(B)
    # balance the two (a positive factor on either only moves s*): |det A| and |det B| within a factor 16
    shift = (abs(det(A)).bit_length() - abs(det(B)).bit_length()) // 4
    if shift > 0:
        B = [[x << shift for x in row] for row in B]
    elif shift < 0:
        A = [[x << -shift for x in row] for row in A]
    c = _pencil_form(A, B)

    # g in powers of s: (1 - s)^(4-j) s^j expanded; then g' a cubic with integer coefficients
    power = [0] * 5
    for j in range(5):
        for k in range(5 - j):
            power[j + k] += c[j] * math.comb(4 - j, k) * (-1) ** k
    slope = [k * power[k] for k in range(1, 5)]  # g'(s) = sum slope[k] s^k

    def value(p, s):
        acc = Fraction(0)
        for coefficient in reversed(p):
            acc = acc * s + coefficient
        return acc

    scale = max(abs(x) for x in slope) or 1
    candidates = [r.real for r in np.roots([x / scale for x in reversed(slope)])
                  if abs(r.imag) <= 1e-9 and 0.0 < r.real < 1.0]
    s = max((_rounded(Fraction(r)) for r in candidates), key=lambda x: value(power, x), default=Fraction(1, 2))
    curvature_poly = [k * slope[k] for k in range(1, 4)]
    for _ in range(60):  # Newton on g' in rationals, from the best critical point double precision found
        curvature = value(curvature_poly, s)
        if curvature == 0:
            break
        step = value(slope, s) / curvature
        s = _rounded(s - step)
        if abs(step) < Fraction(1, 1 << 140):
            break
    M = [[(1 - s) * a + s * b for a, b in zip(ra, rb)] for ra, rb in zip(A, B)]

    def cofactor(r, j):
        minor = [[M[i][k] for k in range(4) if k != j] for i in range(4) if i != r]
        return (-1) ** (r + j) * det(minor)

    r = max(range(4), key=lambda i: abs(cofactor(i, i)))
    X = [cofactor(r, j) for j in range(4)]
    point = [float(X[i] / X[3]) for i in range(3)]
    p = [X[i] / X[3] for i in range(3)] + [Fraction(1)]
    grad = [sum(A[i][k] * p[k] for k in range(4)) for i in range(3)]
    largest = max(abs(v) for v in grad)  # the integer matrix's scale is arbitrary: divide before the floats
    grad = [float(v / largest) for v in grad]
    norm = math.sqrt(sum(v * v for v in grad))
    return point, [v / norm for v in grad]
