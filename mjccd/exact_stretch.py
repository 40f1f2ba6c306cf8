"""Separation over a stretch of time, proven in rational arithmetic.

Where the double-precision solver cannot decide a stretch (its rounding
band: a body flattened near a singular ``linear_affine``, a long graze),
the pair is separate at every t of [t0, t1] when, for some u(t) in (0, 1),
``p(t) = det((1 - u(t)) A(t) + u(t) B(t)) > 0`` on the whole stretch: the
exact status is the sign of the largest such determinant over u
(:func:`mjccd.exact.static_status_exact`).  With A(t) and B(t) polynomial
in t of degree d and u(t) linear, p has degree at most 4 (d + 1); its
values at 4 (d + 1) + 1 rational times give its Bernstein coefficients on
[t0, t1] exactly, and when they are all positive so is p.  The stretch is halved where that fails, the
earlier half first, so the proven part always starts at t0.
"""
import math
from fractions import Fraction
from math import comb

import numpy as np

from mjccd.exact import det

U_CANDIDATES = 4        # the best u of the float search compared exactly
MAXIMUM_BITS = 60       # the quartic's maxima in u are located to 2^-60 when the float search fails


def _integers(A, B):
    """(A L, B L, L): both exact quadrics times one positive integer L that clears every denominator."""
    scale = math.lcm(*(Fraction(x).denominator for M in (A, B) for row in M for x in row))
    return ([[int(Fraction(x) * scale) for x in row] for row in A],
            [[int(Fraction(x) * scale) for x in row] for row in B], scale)


def _pencil_det(pair, u):
    """det((1 - u) A + u B), exactly, for ``pair`` = :func:`_integers` (A, B) and the rational u."""
    A, B, scale = pair
    p, q = u.numerator, u.denominator
    return Fraction(det([[(q - p) * A[i][j] + p * B[i][j] for j in range(4)] for i in range(4)]), (scale * q) ** 4)


def _best_u(pair):
    """A u in (0, 1) where det((1 - u) A + u B) is about largest: the witness tried over a piece.

    The determinant is a quartic in u: its Bernstein coefficients from five
    exact values, scaled into floats, locate the maximum on a grid that is
    also fine near both ends (a thin body's witness u can be 1e-6 from one);
    the few best candidates are compared exactly.
    """
    values = [_pencil_det(pair, Fraction(k, 4)) for k in range(5)]
    coefficients = _bernstein_of_values(values)
    scale = max(abs(c) for c in coefficients)
    if scale == 0:
        return Fraction(1, 2)
    c = np.array([float(x / scale) for x in coefficients])
    ends = np.logspace(-15, -1, 60)
    grid = np.unique(np.concatenate([np.linspace(0.0, 1.0, 257)[1:-1], ends, 1.0 - ends]))
    binomials = np.array([1.0, 4.0, 6.0, 4.0, 1.0])
    quartic = sum(c[i] * binomials[i] * grid ** i * (1.0 - grid) ** (4 - i) for i in range(5))
    candidates = [Fraction(float(u)) for u in grid[np.argsort(quartic)[-U_CANDIDATES:]] if 0.0 < u < 1.0]
    best = max((_pencil_det(pair, u), u) for u in candidates or [Fraction(1, 2)])
    if best[0] > 0:
        return best[1]
    # the floats can miss a narrow peak, or their rounding lift a wrong end: the maxima located exactly
    return max([best] + [(_pencil_det(pair, u), u) for u in _maxima(coefficients)])[1]


def _maxima(coefficients):
    """The local maxima in (0, 1) of the quartic with these exact Bernstein coefficients, to 2^-MAXIMUM_BITS.

    Its derivative is monotone between the roots of its second derivative (a
    quadratic: its vertex, then bisection on each side), so each change of the
    derivative's sign from + to - there is one maximum, found by bisection.
    Every sign is taken exactly, on integers: the witness u they give is then
    checked exactly by its determinant, so it need not be exact itself.
    """
    n = len(coefficients) - 1
    power = [sum(coefficients[i] * comb(n, i) * comb(n - i, k - i) * (-1) ** (k - i) for i in range(k + 1))
             for k in range(n + 1)]
    scale = math.lcm(*(Fraction(c).denominator for c in power))
    power = [int(Fraction(c) * scale) for c in power]
    first = [k * power[k] for k in range(1, n + 1)]
    second = [k * first[k] for k in range(1, n)]
    one = 1 << MAXIMUM_BITS

    def sign(poly, m):  # the sign of poly at u = m / 2^bits, times 2^(bits * degree)
        degree = len(poly) - 1
        value = sum(c * m ** j << (MAXIMUM_BITS * (degree - j)) for j, c in enumerate(poly))
        return (value > 0) - (value < 0)

    def root(poly, lo, hi):  # a sign change of poly in [lo, hi], narrowed by bisection
        s_lo = sign(poly, lo)
        while hi - lo > 1:
            mid = (lo + hi) // 2
            if sign(poly, mid) == s_lo:
                lo = mid
            else:
                hi = mid
        return lo

    splits = {0, one}
    if len(second) == 3 and second[2] != 0:
        vertex = Fraction(-second[1], 2 * second[2])
        if 0 < vertex < 1:
            splits.add(math.floor(vertex * one))
    edges = sorted(splits)
    for lo, hi in zip(edges, edges[1:]):
        if sign(second, lo) * sign(second, hi) < 0:
            splits.add(root(second, lo, hi))
    edges = sorted(splits)
    return [Fraction(root(first, lo, hi), one) for lo, hi in zip(edges, edges[1:])
            if sign(first, lo) > 0 and sign(first, hi) < 0]


def _bernstein_of_values(values):
    """Bernstein coefficients on [0, 1] of the polynomial of degree n taking ``values`` at s = k / n.

    Newton's forward differences give the power-basis coefficients in s, and
    those the Bernstein ones: b_i = sum_{j <= i} C(i, j) / C(n, j) a_j.
    """
    n = len(values) - 1
    diffs = list(values)
    newton = [diffs[0]]  # p(s) = sum_k D^k p_0 C(n s, k)
    for k in range(1, n + 1):
        diffs = [diffs[i + 1] - diffs[i] for i in range(len(diffs) - 1)]
        newton.append(diffs[0])
    power = [Fraction(0)] * (n + 1)
    falling = [Fraction(1)]  # coefficients in s of C(n s, k), built up factor by factor
    for k in range(n + 1):
        for j, c in enumerate(falling):
            power[j] += newton[k] * c
        if k < n:  # C(n s, k + 1) = C(n s, k) (n s - k) / (k + 1)
            nxt = [Fraction(0)] * (len(falling) + 1)
            for j, c in enumerate(falling):
                nxt[j + 1] += c * n / (k + 1)
                nxt[j] -= c * k / (k + 1)
            falling = nxt
    return [sum(Fraction(comb(i, j), comb(n, j)) * power[j] for j in range(i + 1)) for i in range(n + 1)]


def positive_through(quadric_a, quadric_b, degree, t0, t1):
    """True when det((1 - u(t)) A(t) + u(t) B(t)) > 0 for all t in [t0, t1], u(t) the lerp of the best u
    at both ends (the witness follows the ridge of the maximum, which moves with t).

    ``quadric_a``, ``quadric_b``: t -> exact 4x4 quadric, polynomial in t of degree ``degree``.
    """
    u0 = _best_u(_integers(quadric_a(t0), quadric_b(t0)))
    u1 = _best_u(_integers(quadric_a(t1), quadric_b(t1)))
    n = 4 * (degree + 1)
    values = []
    for k in range(n + 1):
        s = Fraction(k, n)
        t = t0 + (t1 - t0) * s
        values.append(_pencil_det(_integers(quadric_a(t), quadric_b(t)), u0 + (u1 - u0) * s))
        if values[-1] <= 0:
            return False
    return min(_bernstein_of_values(values)) > 0


def separate_until(quadric_a, quadric_b, degree, t0, t1, finest, budget):
    """(end of the stretch [t0, end] proven separate, the first piece that could not be proven or None).

    Pieces are halved down to the width ``finest``; at most ``budget`` pieces are tried.
    """
    pending = [(Fraction(t0), Fraction(t1))]
    proven = Fraction(t0)
    while pending:
        a, b = pending.pop()
        budget -= 1
        if positive_through(quadric_a, quadric_b, degree, a, b):
            proven = b
            continue
        if b - a <= finest or budget <= 0:
            return proven, (a, b)
        middle = (a + b) / 2
        pending += [(middle, b), (a, middle)]
    return proven, None
