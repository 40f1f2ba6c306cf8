"""The first time a system of polynomial inequalities holds, certified (numba kernels).

A *system* is a few constraints ``p_j(t) <= 0``, each given by its Bernstein
coefficients (rows of ``C``, degrees ``D``) and a proven bound ``e_j`` of their
error (from :mod:`mjccd.geoms.poly`); it holds at t when all of them do.  :func:`first_time` cuts [0, t_end] into pieces, left first, and labels
each one from the Bernstein coefficients of every constraint restricted to it:

* *infeasible*: some constraint's coefficients all exceed its bound (it is > 0
  on the whole piece);
* *feasible*: every constraint's coefficients stay below minus its bound;
* otherwise the piece is clipped to where the lower convex hull of each
  constraint's control polygon can reach zero (Bézier clipping, quadratic near a
  simple root), split around the computed root of the last undecided
  constraint, or halved; a piece narrower than ``LEAF`` stays *undecided*.

The answer is ``lo`` (no time before it can satisfy the system: every earlier
piece is proven infeasible) and ``hi`` (a time at which the system is proven to
hold, from a feasible piece or one point with every constraint evaluated below
minus its bound), so the first time the system holds lies in [lo, hi].  A
tangential touch (a double root) leaves a band whose width is what the
rounding allows; nothing is ever guessed.
"""
import math

import numpy as np

from mjccd.geoms import poly as P
from mjccd.geoms.poly import _jit

LEAF = 2.0 ** -46       # narrower undecided pieces are not split further
MAX_PIECES = 2000       # pieces examined per system; past it the rest stays undecided
STACK = 160
EPS = P.EPS
SHRINK = 0.8            # clip again while a clip keeps less than this share of the piece


@_jit
def _restrict_coefficients(c, out, a, b):
    """out = the coefficients ``c`` (as many as ``out`` holds) on a piece that contains [a, b]: its left end is
    moved left by the rounding of a / b, so that nothing proven on it misses a sliver of [a, b].  Returns the
    piece's left end."""
    n = out.shape[0] - 1
    for i in range(n + 1):
        out[i] = c[i]
    if b < 1.0:
        for r in range(1, n + 1):
            for i in range(n, r - 1, -1):
                out[i] = (1.0 - b) * out[i - 1] + b * out[i]
    left = 0.0
    if a > 0.0:
        tau = (a * (1.0 - 4.0 * EPS)) / b
        left = tau * b * (1.0 - 2.0 * EPS)
        for r in range(1, n + 1):
            for i in range(n - r + 1):
                out[i] = (1.0 - tau) * out[i] + tau * out[i + 1]
    return left


@_jit
def _sublevel(c, thr, hull):
    """The interval [alpha, beta] of x in [0, 1] where the lower convex hull of the points (i / n, c[i]) is at
    most ``thr``; (2, -1) when it is nowhere.  ``hull``: int scratch of length n + 1."""
    n = c.shape[0] - 1
    if n == 0:
        return (0.0, 1.0) if c[0] <= thr else (2.0, -1.0)
    top = 0
    for i in range(n + 1):
        while top >= 2:
            p, q = hull[top - 2], hull[top - 1]
            if (q - p) * (c[i] - c[p]) - (c[q] - c[p]) * (i - p) <= 0.0:
                top -= 1
            else:
                break
        hull[top] = i
        top += 1
    lo, hi = 2.0, -1.0
    for k in range(top):
        p = hull[k]
        if c[p] <= thr:
            lo = min(lo, float(p))
            hi = max(hi, float(p))
        if k + 1 < top:
            q = hull[k + 1]
            vp, vq = c[p] - thr, c[q] - thr
            if (vp > 0.0) != (vq > 0.0) and vp != vq:
                x = p + (q - p) * vp / (vp - vq)
                lo = min(lo, x)
                hi = max(hi, x)
    if hi < 0.0:
        return 2.0, -1.0
    return lo / n, hi / n


@_jit
def _value_slope(c, t):
    """p(t) and p'(t) of the Bernstein coefficients c (one Horner pass in t / (1 - t))."""
    n = c.shape[0] - 1
    if n == 0:
        return c[0], 0.0
    flip = t > 0.5
    x = (1.0 - t) / t if flip else t / (1.0 - t)
    acc = c[0] if flip else c[n]
    dacc = 0.0
    for k in range(n - 1, -1, -1):
        dacc = dacc * x + acc
        acc = acc * x + P.BINOMIALS[n, k] * (c[n - k] if flip else c[k])
    far = t if flip else 1.0 - t
    slope = far ** (n - 1) * (dacc / far - n * acc)
    return acc * far ** n, -slope if flip else slope


@_jit
def _root_between(c, a, b):
    """A zero of the polynomial c (on [0, 1]) between a and b where its values differ in sign (safeguarded
    Newton)."""
    va, _ = _value_slope(c, a)
    pos = va > 0.0
    lo, hi = a, b
    x = 0.5 * (a + b)
    for _ in range(80):
        v, s = _value_slope(c, x)
        if v == 0.0:
            return x
        if (v > 0.0) == pos:
            lo = x
        else:
            hi = x
        nx = x - v / s if s != 0.0 else 0.5 * (lo + hi)
        if not (lo < nx < hi):
            nx = 0.5 * (lo + hi)
        if abs(nx - x) <= 4.0 * EPS * abs(x) or hi - lo <= 4.0 * EPS * hi:
            return nx
        x = nx
    return x


@_jit
def holds_at(C, D, errs, t):
    """1 when every constraint is proven < 0 at t, -1 when one is proven > 0, else 0."""
    verdict = 1
    for j in range(C.shape[0]):
        v, _ = _value_slope(C[j, :D[j] + 1], t)
        if v > errs[j]:
            return -1
        if not v < -errs[j]:
            verdict = 0
    return verdict


FORCED = 1 << 62        # a piece marked so is a band around a computed root: a leaf unless proven either way


@_jit
def first_time(C, D, errs, t_end):
    """The first time in [0, t_end] at which every constraint (coefficients C, degrees D, bounds errs) is <= 0.

    Returns (lo, hi, estimate, band_end): every time before lo is proven not
    to satisfy the system; at hi it is proven to (hi = -1: nowhere proven);
    estimate: the middle of the first undecided band (the computed root of
    the constraint that closes it); band_end: the end of the last undecided
    piece before hi (the latest the first time can be when hi = -1).  lo = -1:
    the system is proven never to hold on [0, t_end].
    """
    J = C.shape[0]
    nmax = 0
    for j in range(J):
        nmax = max(nmax, D[j])
    buf = np.empty((J, nmax + 1))
    hull = np.empty(nmax + 1, dtype=np.int64)
    sa = np.empty(STACK)
    sb = np.empty(STACK)
    sm = np.empty(STACK, dtype=np.int64)
    top = 1
    sa[0], sb[0], sm[0] = 0.0, t_end, 0
    lo, hi, est, band_end = -1.0, -1.0, -1.0, -1.0
    pieces = 0
    while top > 0:
        top -= 1
        a, b, mask = sa[top], sb[top], sm[top]
        forced = (mask & FORCED) != 0
        if hi >= 0.0 and a >= hi:
            continue
        while True:  # clip [a, b] until it stops shrinking
            pieces += 1
            infeasible = False
            undecided = 0
            which = -1
            alpha, beta = 0.0, 1.0
            left = 0.0
            for j in range(J):
                if (mask >> j) & 1:
                    continue
                row = buf[j, :D[j] + 1]
                left = _restrict_coefficients(C[j], row, a, b)
                mn = row.min()
                mx = row.max()
                if mn > errs[j]:
                    infeasible = True
                    break
                if mx < -errs[j]:
                    mask |= 1 << j
                    continue
                undecided += 1
                which = j
                al, be = _sublevel(row, errs[j], hull)
                alpha = max(alpha, al)
                beta = min(beta, be)
            if infeasible or alpha > beta:
                infeasible = True
                break
            if undecided == 0 or forced:
                break
            w = b - left
            # widen the clip by the rounding of its own arithmetic before it is trusted
            na = max(left + max(alpha - 1e-12, 0.0) * w, a)
            nb = min(left + min(beta + 1e-12, 1.0) * w, b)
            if nb - na < SHRINK * (b - a) and pieces < MAX_PIECES:
                a, b = na, nb
                if b - a <= LEAF:
                    break
                continue
            break
        if infeasible:
            continue
        if undecided == 0 or holds_at(C, D, errs, a) == 1:  # the system holds at a
            if lo < 0.0:
                lo = a
                est = a
            hi = a
            break
        if forced or b - a <= LEAF or pieces >= MAX_PIECES or top + 3 > STACK:  # an undecided leaf
            if lo < 0.0:
                lo = a
                est = 0.5 * (a + b)
            band_end = b
            if holds_at(C, D, errs, b) == 1:
                hi = b
                break
            continue
        split = False
        if undecided == 1:
            c = C[which, :D[which] + 1]
            va, _ = _value_slope(c, a)
            vb, _ = _value_slope(c, b)
            if va > 0.0 and vb <= 0.0:
                r = _root_between(c, a, b) if vb < 0.0 else b
                _, slope = _value_slope(c, r)
                width = 4.0 * EPS * r + 1e-300
                if slope != 0.0:
                    width += 1.5 * errs[which] / abs(slope)
                if a < r - width and r + width < b and 2.0 * width < 0.25 * (b - a):
                    # right of the band, the band itself (a leaf unless proven), left of the band
                    sa[top], sb[top], sm[top] = r + width, b, mask
                    sa[top + 1], sb[top + 1], sm[top + 1] = r - width, r + width, mask | FORCED
                    sa[top + 2], sb[top + 2], sm[top + 2] = a, r - width, mask
                    top += 3
                    split = True
        if not split:
            mid = 0.5 * (a + b)
            sa[top], sb[top], sm[top] = mid, b, mask
            sa[top + 1], sb[top + 1], sm[top + 1] = a, mid, mask
            top += 2
    return lo, hi, est, band_end


@_jit
def status_at_start(C, errs):
    """1: some constraint is proven > 0 at t = 0 (the system does not hold); -1: all are proven < 0; 0:
    undecided (a touch within rounding)."""
    verdict = -1
    for j in range(C.shape[0]):
        v = C[j, 0]
        if v > errs[j]:
            return 1
        if not v < -errs[j]:
            verdict = 0
    return verdict
