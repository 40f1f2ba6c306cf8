"""Polynomials in t on [0, 1] that carry a proven bound of their rounding (numba kernels for the geom solvers).

A *workspace* is an arena of slots, each holding one univariate polynomial in
Bernstein form:

* ``W[k, 0, :n+1]`` its coefficients, ``W[k, 1, :n+1]`` a proven bound of each
  coefficient's error against the exact result of the same operations on the
  exact inputs;
* in a *double-double* workspace (``W.shape[1] == 3``) ``W[k, 2]`` holds the
  low parts: every operation is then carried in double-double arithmetic;
* ``I[k, 0]`` its degree n; ``I[-1, 0]`` counts the slots in use (slot 0 is
  the scratch of degree elevations) and ``I[-1, 1]`` is set once an
  allocation failed.

The bounds are a *running error analysis* (Wilkinson; Higham 2002, §3.3):
each operation adds to its inputs' propagated bounds the rounding it commits,
bounded from the values it actually computed (``u |result|``, or the sum of
the magnitudes of the terms it added), so a bound follows the values rather
than a worst case of the whole program.  In double-double, each operation's
own rounding is a few u^2 of its operands (Joldes, Muller and Popescu 2017).
Every bound is rounded up by a relative margin of 1e-12, which covers the
rounding of the bounds' own arithmetic.  :func:`error` adds the rounding of
the scanners that restrict and evaluate a polynomial.  Inputs are exact
doubles: positions, quaternions and sizes as the caller gave them.

A *bivariate* polynomial in (s, t), Bernstein in both, is a row of slots: one
univariate polynomial in t per Bernstein coefficient in s (the ``b*``
helpers), so the same arithmetic and bounds serve both.
"""
import math

import numba
import numpy as np

# the geoms kernels' one jit configuration (imported by every geoms module and geoms mode's step): compiled on
# first use and cached; no cfunc wrapper (no kernel is passed around as a first-class function)
jit = numba.njit(cache=True, nogil=True, no_cfunc_wrapper=True, forceinline=False)
# small helpers inlined by LLVM into their callers
_inline = numba.njit(cache=True, nogil=True, no_cfunc_wrapper=True, forceinline=True)

EPS = 2.220446049250313e-16
DD_EPS = 16.0 * EPS * EPS    # the relative error of one double-double operation, bounded generously
UP = 1.0 + 1e-12             # the margin every bound is rounded up by
MAX_DEGREE = 96
# C(n, k) correctly rounded; exact (so free of rounding) up to n = 56, where they stay below 2^53
BINOMIALS = np.array([[float(math.comb(n, k)) for k in range(MAX_DEGREE + 1)] for n in range(MAX_DEGREE + 1)])
EXACT_BINOMIALS = 56


@_inline
def gamma(k):
    """gamma_k = k u / (1 - k u), the relative error bound of k rounded operations."""
    return k * EPS / (1.0 - k * EPS)


@_inline
def _unit(W):
    """The rounding unit of the workspace's arithmetic (u, or a few u^2 in double-double)."""
    return DD_EPS if W.shape[1] == 3 else EPS


def workspace(slots, degree, double_double=False):
    """A fresh workspace of ``slots`` polynomials of degree at most ``degree`` (``degree <= MAX_DEGREE``)."""
    W = np.zeros((slots, 3 if double_double else 2, degree + 1))
    I = np.zeros((slots + 1, 2), dtype=np.int64)
    I[-1, 0] = 1  # slot 0 is the scratch of elevations
    return W, I


@jit
def reset(W, I):
    """Empty the workspace for the next query."""
    I[-1, 0] = 1
    I[-1, 1] = 0


@_inline
def _dd(W):
    return W.shape[1] == 3


# ---------------------------------------------------------------- error-free transformations


@_inline
def two_sum(a, b):
    s = a + b
    z = s - a
    return s, (a - (s - z)) + (b - z)


@_inline
def two_product(a, b):
    p = a * b
    c = 134217729.0 * a  # Dekker's split (2^27 + 1)
    a1 = c - (c - a)
    a2 = a - a1
    c = 134217729.0 * b
    b1 = c - (c - b)
    b2 = b - b1
    return p, a2 * b2 - (((p - a1 * b1) - a2 * b1) - a1 * b2)


@_inline
def dd_add(ah, al, bh, bl):
    s, e = two_sum(ah, bh)
    e += al + bl
    return two_sum(s, e)


@_inline
def dd_mul(ah, al, bh, bl):
    p, e = two_product(ah, bh)
    e += ah * bl + al * bh
    return two_sum(p, e)


@_inline
def dd_mul_d(ah, al, b):
    p, e = two_product(ah, b)
    e += al * b
    return two_sum(p, e)


@_inline
def dd_div_d(ah, al, b):
    q = ah / b
    p, e = two_product(q, b)
    r = ((ah - p) - e + al) / b
    return two_sum(q, r)


# ---------------------------------------------------------------- slots


@_inline
def alloc(W, I, degree):
    """A new slot of the given degree (arrays uninitialised); slot 0 (the scratch) when the arena is full or
    the degree too high, which marks the workspace as failed."""
    k = I[-1, 0]
    ok = (k < W.shape[0]) & (degree < W.shape[2])
    # selects, no branch: numba keeps the reference counting of W and I it adds around array work in a branch,
    # which cost each operation more than its arithmetic
    slot = k if ok else 0
    I[-1, 1] = I[-1, 1] | (0 if ok else 1)
    I[-1, 0] = k + (1 if ok else 0)
    I[slot, 0] = degree if ok else 0
    return slot


@jit
def failed(I):
    """True once an allocation has failed: every polynomial formed since is meaningless."""
    return I[-1, 1] != 0


@_inline
def _coef(W, k, i):
    """Coefficient i of slot k as one double."""
    return W[k, 0, i] + W[k, 2, i] if W.shape[1] == 3 else W[k, 0, i]


@jit
def const(W, I, value):
    """The constant ``value`` (exact)."""
    k = alloc(W, I, 0)
    W[k, 0, 0] = value
    W[k, 1, 0] = 0.0
    if _dd(W):
        W[k, 2, 0] = 0.0
    return k


@jit
def linear(W, I, v0, v1):
    """(1 - t) v0 + t v1 (exact: its Bernstein coefficients are v0, v1)."""
    if v0 == v1:
        return const(W, I, v0)
    k = alloc(W, I, 1)
    W[k, 0, 0], W[k, 0, 1] = v0, v1
    W[k, 1, 0] = W[k, 1, 1] = 0.0
    if _dd(W):
        W[k, 2, 0] = W[k, 2, 1] = 0.0
    return k


@_inline
def _elevate_into(W, a, m, n, dst):
    """Slot a (degree m) elevated to degree n, coefficients and bounds, written into slot dst: each step
    c'_i = (i c_{i-1} + (d + 1 - i) c_i) / (d + 1), four roundings."""
    rows = W.shape[1]
    u4 = 4.0 * _unit(W)
    for r in range(rows):
        for i in range(m + 1):
            W[dst, r, i] = W[a, r, i]
    for d in range(m, n):
        for r in range(rows):
            W[dst, r, d + 1] = W[dst, r, d]
        for i in range(d, 0, -1):
            num0, num1 = float(i), float(d + 1 - i)
            mag = (num0 * abs(_coef(W, dst, i - 1)) + num1 * abs(_coef(W, dst, i))) / (d + 1.0)
            err = (num0 * W[dst, 1, i - 1] + num1 * W[dst, 1, i]) / (d + 1.0)
            if rows == 3:
                h1, l1 = dd_mul_d(W[dst, 0, i - 1], W[dst, 2, i - 1], num0)
                h2, l2 = dd_mul_d(W[dst, 0, i], W[dst, 2, i], num1)
                h, lo = dd_add(h1, l1, h2, l2)
                W[dst, 0, i], W[dst, 2, i] = dd_div_d(h, lo, d + 1.0)
            else:
                W[dst, 0, i] = (num0 * W[dst, 0, i - 1] + num1 * W[dst, 0, i]) / (d + 1.0)
            W[dst, 1, i] = (err + u4 * mag) * UP


@jit
def add(W, I, a, b, sb):
    """a + sb * b (sb an exact double: 1.0, -1.0 or any scale), elevating the lower degree."""
    ma, mb = I[a, 0], I[b, 0]
    n = max(ma, mb)
    k = alloc(W, I, n)
    if ma < n:
        _elevate_into(W, a, ma, n, 0)
        a = 0
    if mb < n:
        _elevate_into(W, b, mb, n, 0)
        b = 0
    asb = abs(sb)
    exact_scale = sb == 1.0 or sb == -1.0
    u = _unit(W)
    if _dd(W):
        for i in range(n + 1):
            bh, bl = dd_mul_d(W[b, 0, i], W[b, 2, i], sb)
            W[k, 0, i], W[k, 2, i] = dd_add(W[a, 0, i], W[a, 2, i], bh, bl)
            mag = abs(_coef(W, a, i)) + asb * abs(_coef(W, b, i))
            W[k, 1, i] = (W[a, 1, i] + asb * W[b, 1, i] + 2.0 * u * mag) * UP
    else:
        for i in range(n + 1):
            sbv = sb * W[b, 0, i]
            c = W[a, 0, i] + sbv
            W[k, 0, i] = c
            err = W[a, 1, i] + asb * W[b, 1, i] + u * abs(c)
            if not exact_scale:
                err += u * abs(sbv)
            W[k, 1, i] = err * UP
    return k


@jit
def scale(W, I, a, s):
    """s * a for an exact double s."""
    n = I[a, 0]
    k = alloc(W, I, n)
    exact = s == 1.0 or s == -1.0
    u = _unit(W)
    for i in range(n + 1):
        if _dd(W):
            W[k, 0, i], W[k, 2, i] = dd_mul_d(W[a, 0, i], W[a, 2, i], s)
        else:
            W[k, 0, i] = s * W[a, 0, i]
        err = abs(s) * W[a, 1, i]
        if not exact:
            err += u * abs(_coef(W, k, i))
        W[k, 1, i] = err * UP
    return k


@jit
def frac(W, I, a, num, den):
    """a * num / den for exact doubles num and den (two roundings)."""
    n = I[a, 0]
    k = alloc(W, I, n)
    u = _unit(W)
    for i in range(n + 1):
        if _dd(W):
            h, lo = dd_mul_d(W[a, 0, i], W[a, 2, i], num)
            W[k, 0, i], W[k, 2, i] = dd_div_d(h, lo, den)
        else:
            W[k, 0, i] = W[a, 0, i] * num / den
        W[k, 1, i] = (W[a, 1, i] * abs(num) / abs(den) + 2.0 * u * abs(_coef(W, k, i))) * (UP + 2.0 * u)
    return k


@jit
def mul(W, I, a, b):
    """a * b (degree m + n), as a convolution in the scaled Bernstein basis: term (i, j) is
    (a_i C(m, i)) (b_j C(n, j)), three roundings (four where a binomial is itself rounded); the terms of one
    coefficient are summed and divided by C(m + n, q)."""
    m, n = I[a, 0], I[b, 0]
    k = alloc(W, I, m + n)
    if k == 0:  # failed (the product's degree may not fit): nothing written, every loop below empty
        m = n = -1
    d = m + n
    dd = _dd(W)
    u = _unit(W)
    cnt = min(m, n) + 1
    per_term = (4.0 if d > EXACT_BINOMIALS else 3.0) * u + cnt * u  # a term's roundings and its share of the sum
    for q in range(d + 1):
        W[k, 0, q] = 0.0
        W[k, 1, q] = 0.0  # first the propagated error and the terms' magnitudes, combined below
        if dd:
            W[k, 2, q] = 0.0
    # the magnitudes of the terms go to the scratch's bound row
    for q in range(d + 1):
        W[0, 1, q] = 0.0
    for i in range(m + 1):
        bi = BINOMIALS[m, i]
        ai = _coef(W, a, i)
        ea = W[a, 1, i]
        for j in range(n + 1):
            bj = BINOMIALS[n, j]
            w = bi * bj
            bv = _coef(W, b, j)
            eb = W[b, 1, j]
            if dd:
                ph, pl = dd_mul(W[a, 0, i], W[a, 2, i], W[b, 0, j], W[b, 2, j])
                ph, pl = dd_mul_d(ph, pl, w)
                W[k, 0, i + j], W[k, 2, i + j] = dd_add(W[k, 0, i + j], W[k, 2, i + j], ph, pl)
            else:
                W[k, 0, i + j] += (W[a, 0, i] * bi) * (W[b, 0, j] * bj)
            W[k, 1, i + j] += w * (abs(ai) * eb + abs(bv) * ea + ea * eb)
            W[0, 1, i + j] += w * abs(ai * bv)
    for q in range(d + 1):
        if dd:
            W[k, 0, q], W[k, 2, q] = dd_div_d(W[k, 0, q], W[k, 2, q], BINOMIALS[d, q])
        else:
            W[k, 0, q] /= BINOMIALS[d, q]
        err = (W[k, 1, q] + per_term * W[0, 1, q]) / BINOMIALS[d, q] + u * abs(_coef(W, k, q))
        W[k, 1, q] = err * (UP + 4.0 * u)
    return k


@jit
def sq(W, I, a):
    """a * a."""
    return mul(W, I, a, a)


@jit
def dot3(W, I, x0, x1, x2, y0, y1, y2):
    """x0 y0 + x1 y1 + x2 y2."""
    return add(W, I, add(W, I, mul(W, I, x0, y0), mul(W, I, x1, y1), 1.0), mul(W, I, x2, y2), 1.0)


@jit
def coefficients_into(W, I, k, out):
    """out[:n+1] = slot k's coefficients as doubles (hi + lo rounded once in a double-double workspace)."""
    n = I[k, 0]
    for i in range(n + 1):
        out[i] = _coef(W, k, i)


@jit
def error(W, I, k):
    """A bound of |computed - exact| of slot k (as its double coefficients) at every t in [0, 1], also after the
    scanners restrict it to a piece or evaluate it: the largest bound of a coefficient (plus, in double-double,
    the rounding of each coefficient to one double) and the scanners' own rounding (10 a degree) of
    coefficients no larger than these."""
    n = I[k, 0]
    e = 0.0
    c = 0.0
    for i in range(n + 1):
        e = max(e, W[k, 1, i])
        c = max(c, abs(_coef(W, k, i)))
    if _dd(W):
        e += EPS * c
    return scanned_bound(e, c, n)


@jit
def scanned_bound(e, c, n):
    """The bound of a polynomial of degree n whose coefficients are off by at most e and no larger than c,
    after the scanners restrict it to a piece or evaluate it (their own rounding: 10 a degree)."""
    return (e + gamma(10 * n + 8) * (c + e)) * (1.0 + 1e-9)


@jit
def is_zero(W, I, k):
    """True when slot k is exactly the zero polynomial (every coefficient and bound 0)."""
    for i in range(I[k, 0] + 1):
        if W[k, 1, i] != 0.0 or W[k, 0, i] != 0.0:
            return False
    return True


@jit
def value(W, I, k, t):
    """Value of slot k at t (Horner in t / (1 - t), as :func:`mjccd.bernstein.evaluate_row`)."""
    n = I[k, 0]
    if n == 0:
        return _coef(W, k, 0)
    flip = t > 0.5
    s = (1.0 - t) / t if flip else t / (1.0 - t)
    acc = _coef(W, k, 0 if flip else n)
    for j in range(n - 1, -1, -1):
        acc = acc * s + BINOMIALS[n, j] * _coef(W, k, n - j if flip else j)
    return acc * (t if flip else 1.0 - t) ** n


# ---------------------------------------------------------------- bivariate: rows of slots


@jit
def bmul(W, I, a, b):
    """Product of two bivariate polynomials given as row arrays (degree in s: len - 1 each), in the scaled
    Bernstein basis: each product of rows times C(m, i) C(n, j) (an exact integer), the sums divided by
    C(m + n, q)."""
    m, n = a.shape[0] - 1, b.shape[0] - 1
    d = m + n
    out = np.full(d + 1, -1, dtype=np.int64)
    for i in range(m + 1):
        for j in range(n + 1):
            term = scale(W, I, mul(W, I, a[i], b[j]), BINOMIALS[m, i] * BINOMIALS[n, j])
            out[i + j] = term if out[i + j] < 0 else add(W, I, out[i + j], term, 1.0)
    for q in range(d + 1):
        out[q] = frac(W, I, out[q], 1.0, BINOMIALS[d, q])
    return out


@jit
def belevate(W, I, a, d):
    """A bivariate polynomial elevated to degree d in s."""
    out = a.copy()
    for n in range(a.shape[0] - 1, d):
        nxt = np.empty(n + 2, dtype=np.int64)
        nxt[0] = out[0]
        nxt[n + 1] = out[n]
        for i in range(1, n + 1):
            nxt[i] = add(W, I, frac(W, I, out[i - 1], float(i), n + 1.0),
                         frac(W, I, out[i], float(n + 1 - i), n + 1.0), 1.0)
        out = nxt
    return out


@jit
def badd(W, I, a, b, sb):
    """a + sb * b for bivariate polynomials (row arrays), elevating in s to the higher degree."""
    d = max(a.shape[0], b.shape[0]) - 1
    ea = belevate(W, I, a, d)
    eb = belevate(W, I, b, d)
    out = np.empty(d + 1, dtype=np.int64)
    for i in range(d + 1):
        out[i] = add(W, I, ea[i], eb[i], sb)
    return out


@jit
def bscale_t(W, I, a, p):
    """The bivariate ``a`` times the univariate polynomial (slot) ``p`` in t."""
    out = np.empty(a.shape[0], dtype=np.int64)
    for i in range(a.shape[0]):
        out[i] = mul(W, I, a[i], p)
    return out
