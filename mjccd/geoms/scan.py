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

import numpy as np

from mjccd.geoms import poly as P
from mjccd.geoms.poly import jit

LEAF = 2.0 ** -46       # narrower undecided pieces are not split further
MAX_PIECES = 2000       # pieces examined per system; past it the rest stays undecided
STACK = 160
EPS = P.EPS
SHRINK = 0.8            # clip again while a clip keeps less than this share of the piece


@jit
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


@jit
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


@jit
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


@jit
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


@jit
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


@jit
def _examine_piece(C, D, errs, a, b, mask, buf, hull):
    """One look at the piece [a, b]: each constraint not yet proven negative on it (bit j of ``mask`` clear)
    restricted to it (into ``buf``).  Returns (undecided, mask, which, alpha, beta, left): undecided -1 when
    some constraint is proven positive on the piece (or the clip leaves nothing), else how many are neither
    proven positive nor negative, the last of them ``which``; ``mask`` gains those proven negative; [alpha,
    beta] the clip (fractions of the restricted piece, whose left end is ``left``) to where each undecided
    constraint's convex hull can reach zero."""
    undecided = 0
    which = -1
    alpha, beta = 0.0, 1.0
    left = 0.0
    for j in range(C.shape[0]):
        if (mask >> j) & 1:
            continue
        row = buf[j, :D[j] + 1]
        left = _restrict_coefficients(C[j], row, a, b)
        if row.min() > errs[j]:
            return -1, mask, which, alpha, beta, left
        if row.max() < -errs[j]:
            mask |= 1 << j
            continue
        undecided += 1
        which = j
        al, be = _sublevel(row, errs[j], hull)
        alpha = max(alpha, al)
        beta = min(beta, be)
    if alpha > beta:
        return -1, mask, which, alpha, beta, left
    return undecided, mask, which, alpha, beta, left


@jit
def _split_piece(C, D, errs, a, b, mask, undecided, which, entering_only, sa, sb, sm, top):
    """Push the parts of the undecided piece [a, b] on the stack (sa, sb, sm; returns its new top): around the
    computed root of its one undecided constraint when that one changes sign across the piece (only from
    positive to not, with ``entering_only``), as the part right of the root's band, the band (FORCED: a leaf
    unless proven either way) and the part left of it; else its two halves."""
    if undecided == 1:
        c = C[which, :D[which] + 1]
        va, _ = _value_slope(c, a)
        vb, _ = _value_slope(c, b)
        if entering_only:
            crossing = va > 0.0 and vb <= 0.0
        else:
            crossing = (va > 0.0) != (vb > 0.0) and va != 0.0 and vb != 0.0
        if crossing:
            r = _root_between(c, a, b) if vb != 0.0 else b
            _, slope = _value_slope(c, r)
            width = 4.0 * EPS * r + 1e-300
            if slope != 0.0:
                width += 1.5 * errs[which] / abs(slope)
            if a < r - width and r + width < b and 2.0 * width < 0.25 * (b - a):
                sa[top], sb[top], sm[top] = r + width, b, mask
                sa[top + 1], sb[top + 1], sm[top + 1] = r - width, r + width, mask | FORCED
                sa[top + 2], sb[top + 2], sm[top + 2] = a, r - width, mask
                return top + 3
    mid = 0.5 * (a + b)
    sa[top], sb[top], sm[top] = mid, b, mask
    sa[top + 1], sb[top + 1], sm[top + 1] = a, mid, mask
    return top + 2


@jit
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
            undecided, mask, which, alpha, beta, left = _examine_piece(C, D, errs, a, b, mask, buf, hull)
            infeasible = undecided < 0
            if infeasible:
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
        top = _split_piece(C, D, errs, a, b, mask, undecided, which, True, sa, sb, sm, top)
    return lo, hi, est, band_end


@jit
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


# ---------------------------------------------------------------- bivariate: a parameter s in [0, 1] besides t

MAX_BOXES = 6000      # boxes examined per bivariate system; past it the rest stays undecided
HEAP = 4096
LEAF_S = 2.0 ** -30   # narrower boxes in s are not split in s


@jit
def _restrict2(c, ds, nt, s0, s1, t0, t1, out, col):
    """out[:ds+1, :nt+1] = the bivariate coefficients c (rows in s, columns in t) on a box containing
    [s0, s1] x [t0, t1] (``col``: scratch of ds + 1); returns the box's real lower corner (s, t)."""
    tl = 0.0
    for i in range(ds + 1):
        tl = _restrict_coefficients(c[i], out[i, :nt + 1], t0, t1)
    sl = 0.0
    cs = col[:ds + 1]
    for k in range(nt + 1):
        for i in range(ds + 1):
            cs[i] = out[i, k]
        sl = _restrict_coefficients(cs, cs, s0, s1)
        for i in range(ds + 1):
            out[i, k] = cs[i]
    return sl, tl


@jit
def _bvalue(c, ds, nt, s, t):
    """Value of the bivariate coefficients at (s, t)."""
    col = np.empty(ds + 1)
    for i in range(ds + 1):
        col[i], _ = _value_slope(c[i, :nt + 1], t)
    v, _ = _value_slope(col, s)
    return v


@jit
def bholds_at(C, DS, DT, errs, s, t):
    """1 when every bivariate constraint is proven < 0 at (s, t), -1 when one is proven > 0, else 0."""
    verdict = 1
    for j in range(C.shape[0]):
        v = _bvalue(C[j], DS[j], DT[j], s, t)
        if v > errs[j]:
            return -1
        if not v < -errs[j]:
            verdict = 0
    return verdict


@jit
def _box_scratch(C, DS, DT):
    """Scratch arrays of the bivariate scans: (buf, scol, env, hull, clip) for :func:`_examine`."""
    ds_max, nt_max = 0, 0
    for j in range(C.shape[0]):
        ds_max = max(ds_max, DS[j])
        nt_max = max(nt_max, DT[j])
    return (np.empty((C.shape[0], ds_max + 1, nt_max + 1)), np.empty(ds_max + 1), np.empty(max(ds_max, nt_max) + 1),
            np.empty(max(ds_max, nt_max) + 1, dtype=np.int64), np.empty(4))


@jit
def _heap():
    """An empty heap of boxes (s0, s1, t0, t1, mask; see :func:`_push`)."""
    return np.empty(HEAP), np.empty(HEAP), np.empty(HEAP), np.empty(HEAP), np.empty(HEAP, dtype=np.int64)


@jit
def _push(hs0, hs1, ht0, ht1, hm, n, s0, s1, t0, t1, mask):
    """Push a box on the binary min-heap keyed by t0; returns the new size (unchanged when full)."""
    if n >= hs0.shape[0]:
        return n
    i = n
    hs0[i], hs1[i], ht0[i], ht1[i], hm[i] = s0, s1, t0, t1, mask
    while i > 0:
        p = (i - 1) // 2
        if ht0[p] <= ht0[i]:
            break
        hs0[p], hs0[i] = hs0[i], hs0[p]
        hs1[p], hs1[i] = hs1[i], hs1[p]
        ht0[p], ht0[i] = ht0[i], ht0[p]
        ht1[p], ht1[i] = ht1[i], ht1[p]
        hm[p], hm[i] = hm[i], hm[p]
        i = p
    return n + 1


@jit
def _pop(hs0, hs1, ht0, ht1, hm, n):
    """Remove the root of the heap (moved into the last place, whose index is returned as the new size)."""
    last = n - 1
    hs0[0], hs0[last] = hs0[last], hs0[0]
    hs1[0], hs1[last] = hs1[last], hs1[0]
    ht0[0], ht0[last] = ht0[last], ht0[0]
    ht1[0], ht1[last] = ht1[last], ht1[0]
    hm[0], hm[last] = hm[last], hm[0]
    i = 0
    while True:
        l, r = 2 * i + 1, 2 * i + 2
        m = i
        if l < last and ht0[l] < ht0[m]:
            m = l
        if r < last and ht0[r] < ht0[m]:
            m = r
        if m == i:
            break
        hs0[m], hs0[i] = hs0[i], hs0[m]
        hs1[m], hs1[i] = hs1[i], hs1[m]
        ht0[m], ht0[i] = ht0[i], ht0[m]
        ht1[m], ht1[i] = ht1[i], ht1[m]
        hm[m], hm[i] = hm[i], hm[m]
        i = m
    return last


@jit
def _examine(C, DS, DT, errs, s0, s1, t0, t1, mask, buf, scol, env, hull, clip):
    """One look at the box [s0, s1] x [t0, t1]: each constraint not yet proven negative on it (bit j of ``mask``
    clear) restricted to it (into ``buf``).  Returns (undecided, mask): undecided -1 when some constraint is
    proven positive on the box (or the clip below leaves nothing), 0 when every one is proven negative, else
    how many are neither; ``mask`` gains the constraints proven negative.  clip (4,) = the box (t0, t1, s0,
    s1) clipped to where the lower envelopes of every undecided constraint (over s as a polynomial in t, over
    t as one in s) can reach zero."""
    undecided = 0
    a_t, b_t, a_s, b_s = 0.0, 1.0, 0.0, 1.0
    sl, tl = 0.0, 0.0
    for j in range(C.shape[0]):
        if (mask >> j) & 1:
            continue
        ds, nt = DS[j], DT[j]
        box = buf[j]
        sl, tl = _restrict2(C[j], ds, nt, s0, s1, t0, t1, box, scol)
        mn, mx = box[0, 0], box[0, 0]
        for i in range(ds + 1):
            for k in range(nt + 1):
                mn = min(mn, box[i, k])
                mx = max(mx, box[i, k])
        if mn > errs[j]:
            return -1, mask
        if mx < -errs[j]:
            mask |= 1 << j
            continue
        undecided += 1
        for k in range(nt + 1):  # lower envelope over s, as a polynomial in t
            m = box[0, k]
            for i in range(1, ds + 1):
                m = min(m, box[i, k])
            env[k] = m
        al, be = _sublevel(env[:nt + 1], errs[j], hull)
        a_t, b_t = max(a_t, al), min(b_t, be)
        for i in range(ds + 1):  # lower envelope over t, as a polynomial in s
            m = box[i, 0]
            for k in range(1, nt + 1):
                m = min(m, box[i, k])
            env[i] = m
        al, be = _sublevel(env[:ds + 1], errs[j], hull)
        a_s, b_s = max(a_s, al), min(b_s, be)
    if a_t > b_t or a_s > b_s:
        return -1, mask
    wt, ws = t1 - tl, s1 - sl
    # widened by the rounding of the clip's own arithmetic before it is trusted
    nt0 = max(tl + max(a_t - 1e-12, 0.0) * wt, t0)
    nt1 = min(tl + min(b_t + 1e-12, 1.0) * wt, t1)
    ns0 = max(sl + max(a_s - 1e-12, 0.0) * ws, s0)
    ns1 = min(sl + min(b_s + 1e-12, 1.0) * ws, s1)
    clip[0], clip[1], clip[2], clip[3] = _unless_inverted(nt0, nt1, t0, t1, ns0, ns1, s0, s1)
    return undecided, mask


@jit
def _shrunk(clip, s0, s1, t0, t1):
    """Whether the clip keeps less than SHRINK of the box along one side (worth clipping again)."""
    return (clip[1] - clip[0]) < SHRINK * (t1 - t0) or (clip[3] - clip[2]) < SHRINK * (s1 - s0)


@jit
def _halve(hs0, hs1, ht0, ht1, hm, n, s0, s1, t0, t1, mask, DS, DT, buf):
    """Push the two halves of a box: in s when the undecided constraints' coefficients (``buf``) vary more along
    s than along t (the envelope over s is what keeps the box from being clipped away) or the box is a leaf
    wide in time, else in t.  Returns the heap's new size."""
    vs, vt = 0.0, 0.0
    for j in range(DS.shape[0]):
        if (mask >> j) & 1:
            continue
        box = buf[j]
        for k in range(DT[j] + 1):
            lo_, hi_ = box[0, k], box[0, k]
            for i in range(1, DS[j] + 1):
                lo_, hi_ = min(lo_, box[i, k]), max(hi_, box[i, k])
            vs = max(vs, hi_ - lo_)
        for i in range(DS[j] + 1):
            lo_, hi_ = box[i, 0], box[i, 0]
            for k in range(1, DT[j] + 1):
                lo_, hi_ = min(lo_, box[i, k]), max(hi_, box[i, k])
            vt = max(vt, hi_ - lo_)
    if s1 - s0 > LEAF_S and (vs > vt or t1 - t0 <= LEAF):
        smid = 0.5 * (s0 + s1)
        n = _push(hs0, hs1, ht0, ht1, hm, n, s0, smid, t0, t1, mask)
        return _push(hs0, hs1, ht0, ht1, hm, n, smid, s1, t0, t1, mask)
    tm = 0.5 * (t0 + t1)
    n = _push(hs0, hs1, ht0, ht1, hm, n, s0, s1, t0, tm, mask)
    return _push(hs0, hs1, ht0, ht1, hm, n, s0, s1, tm, t1, mask)


@jit
def _unless_inverted(nt0, nt1, t0, t1, ns0, ns1, s0, s1):
    """A clipped box, except along a side where rounding left the clip inverted (on boxes as narrow as the
    rounding of their own ends): there the box keeps its extent, so that nothing is lost and no box is pushed
    back unchanged for ever."""
    if not nt0 <= nt1:
        nt0, nt1 = t0, t1
    if not ns0 <= ns1:
        ns0, ns1 = s0, s1
    return nt0, nt1, ns0, ns1


@jit
def _point_proof(C, DS, DT, errs, s, t0, t1):
    """A time in [t0, t1] at which every constraint is proven < 0 at this s, placed past the root in t of the
    constraint largest at t1's left end (found by Newton on the univariate restriction to this s); -1 when
    none is found."""
    J = C.shape[0]
    nt_max = 0
    for j in range(J):
        nt_max = max(nt_max, DT[j])
    row = np.empty(nt_max + 1)
    worst, which = -1e300, -1
    for j in range(J):
        v = _bvalue(C[j], DS[j], DT[j], s, t0) + errs[j]  # proven < 0 only when v + its bound is
        if v > worst:
            worst, which = v, j
    if worst < 0.0:
        return t0
    # the blocking constraint as a polynomial in t at this s: combine its rows with the Bernstein weights in s
    ds, nt = DS[which], DT[which]
    for k in range(nt + 1):
        acc = 0.0
        for i in range(ds + 1):
            acc += P.BINOMIALS[ds, i] * s ** i * (1.0 - s) ** (ds - i) * C[which, i, k]
        row[k] = acc
    c = row[:nt + 1]
    vb, _ = _value_slope(c, t1)
    if not vb < 0.0:
        return -1.0
    r = _root_between(c, t0, t1)
    _, slope = _value_slope(c, r)
    width = 4.0 * EPS * r + 1e-300
    if slope != 0.0:
        width += 2.0 * errs[which] / abs(slope)
    for _ in range(8):
        t = min(r + width, t1)
        if bholds_at(C, DS, DT, errs, s, t) == 1:
            return t
        width *= 4.0
    return -1.0


@jit
def bfirst_time(C, DS, DT, errs, t_end, max_boxes=MAX_BOXES):
    """The first time in [0, t_end] at which some s in [0, 1] makes every bivariate constraint <= 0, examining at
    most about ``max_boxes`` boxes (the rest stays undecided).

    ``C[j, :DS[j]+1, :DT[j]+1]``: constraint j's coefficients (rows in s,
    columns in t).  Boxes of (s, t) are taken earliest first from a heap;
    each is discarded when a constraint is proven positive on it, and clipped
    in t to where the lower envelope over s of every constraint can reach
    zero, and in s likewise.  When clipping no longer moves the box's start,
    the envelope over s is too loose: the box is halved in s (in t once it is
    narrow in s).  A box with every constraint proven negative, or a point
    proven so (placed past a Newton root along the box's middle s), bounds
    the answer from above.  Returns (lo, hi, t_estimate, band_end,
    s_estimate) as :func:`first_time`, with the s of the point that proved
    contact.
    """
    buf, scol, env, hull, clip = _box_scratch(C, DS, DT)
    hs0, hs1, ht0, ht1, hm = _heap()
    n = _push(hs0, hs1, ht0, ht1, hm, 0, 0.0, 1.0, 0.0, t_end, 0)
    hi, est, band_end, s_est = -1.0, -1.0, -1.0, 0.5
    leaf_lo = -1.0
    boxes = 0
    while n > 0:
        n = _pop(hs0, hs1, ht0, ht1, hm, n)
        s0, s1, t0, t1, mask = hs0[n], hs1[n], ht0[n], ht1[n], hm[n]
        if hi >= 0.0 and t0 >= hi:
            n += 1  # put it back: it bounds what is left
            break
        undecided = 0
        while True:
            boxes += 1
            undecided, mask = _examine(C, DS, DT, errs, s0, s1, t0, t1, mask, buf, scol, env, hull, clip)
            if undecided <= 0:
                break
            shrunk = _shrunk(clip, s0, s1, t0, t1)
            t0, t1, s0, s1 = clip[0], clip[1], clip[2], clip[3]
            if not shrunk or boxes >= max_boxes or (t1 - t0 <= LEAF and s1 - s0 <= LEAF_S):
                break
        if undecided < 0:
            continue
        if hi >= 0.0 and t0 >= hi:
            continue
        sm = 0.5 * (s0 + s1)
        if undecided == 0:
            hi, s_est = t0, sm
            continue
        tp = _point_proof(C, DS, DT, errs, sm, t0, t1)
        if tp >= 0.0 and (hi < 0.0 or tp < hi):
            hi, s_est = tp, sm
            t1 = min(t1, tp)
        if (t1 - t0 <= LEAF and s1 - s0 <= LEAF_S) or boxes >= max_boxes or n + 2 > HEAP:
            if leaf_lo < 0.0 or t0 < leaf_lo:
                leaf_lo = t0
                est = 0.5 * (t0 + t1)
                if hi < 0.0:
                    s_est = sm  # no proof yet: the earliest leaf's s is where the witness is
            band_end = max(band_end, t1)
            continue
        n = _halve(hs0, hs1, ht0, ht1, hm, n, s0, s1, t0, t1, mask, DS, DT, buf)
    # the earliest box left unresolved bounds the answer from below
    lo = leaf_lo
    if n > 0:
        first = ht0[0]
        for q in range(n):
            first = min(first, ht0[q])
        if hi < 0.0 or first < hi:
            lo = first if lo < 0.0 else min(lo, first)
    if hi >= 0.0 and (lo < 0.0 or lo > hi):
        lo = hi
    if lo >= 0.0 and (est < 0.0 or est < lo):
        est = lo if hi < 0.0 else 0.5 * (lo + hi)
    if hi >= 0.0 and est > hi:
        est = 0.5 * (lo + hi)
    return lo, hi, est, band_end, s_est


# ---------------------------------------------------------------- every run of time a system holds

INF, UND, FEAS = 1, 0, -1   # labels of pieces of time: proven not to hold, undecided, proven to hold
RUN_FIELDS = 5              # enter_lo, enter_hi, exit_lo, exit_hi, proven (1: some time inside is proven)
MAX_SEGMENTS = 4096


@jit
def _emit(seg, nseg, a, b, label):
    """Append the piece [a, b] with its label, merging it into the previous one when they agree."""
    if b < a:
        return nseg
    if nseg > 0 and seg[nseg - 1, 2] == label and seg[nseg - 1, 1] >= a:
        seg[nseg - 1, 1] = max(seg[nseg - 1, 1], b)
        return nseg
    if nseg >= seg.shape[0]:
        seg[nseg - 1, 1] = max(seg[nseg - 1, 1], b)  # out of room: the rest is undecided
        seg[nseg - 1, 2] = UND
        return nseg
    seg[nseg, 0], seg[nseg, 1], seg[nseg, 2] = a, b, label
    return nseg + 1


@jit
def runs_of(seg, nseg, t_end, out):
    """Runs of time not proven free (rows of ``out``, RUN_FIELDS each) from labelled pieces in time order;
    returns their number."""
    n = 0
    k = 0
    while k < nseg:
        if seg[k, 2] == INF:
            k += 1
            continue
        enter_lo = seg[k, 0]
        enter_hi, exit_lo = -1.0, -1.0
        end = seg[k, 1]
        while k < nseg and seg[k, 2] != INF:
            if seg[k, 2] == FEAS:
                if enter_hi < 0.0:
                    enter_hi = seg[k, 0]
                exit_lo = seg[k, 1]
            end = seg[k, 1]
            k += 1
        if n < out.shape[0]:
            proven = enter_hi >= 0.0
            out[n, 0] = enter_lo
            out[n, 1] = enter_hi if proven else end
            out[n, 2] = exit_lo if proven else enter_lo
            out[n, 3] = end if k < nseg else t_end
            out[n, 4] = 1.0 if proven else 0.0
            n += 1
    return n


@jit
def all_runs(C, D, errs, t_end, out):
    """Every run of time in [0, t_end] in which the univariate system may hold, as :func:`runs_of` rows; pieces
    are clipped, split around the roots of a lone undecided constraint (entering or leaving) and halved, as in
    :func:`first_time`, but none is skipped."""
    J = C.shape[0]
    nmax = 0
    for j in range(J):
        nmax = max(nmax, D[j])
    buf = np.empty((J, nmax + 1))
    hull = np.empty(nmax + 1, dtype=np.int64)
    seg = np.empty((MAX_SEGMENTS, 3))
    nseg = 0
    sa = np.empty(STACK)
    sb = np.empty(STACK)
    sm = np.empty(STACK, dtype=np.int64)
    top = 1
    sa[0], sb[0], sm[0] = 0.0, t_end, 0
    pieces = 0
    while top > 0:
        top -= 1
        a, b, mask = sa[top], sb[top], sm[top]
        if mask < 0:  # a part a clip proved free, emitted in its turn
            nseg = _emit(seg, nseg, a, b, INF)
            continue
        forced = (mask & FORCED) != 0
        pieces += 1
        undecided, mask, which, alpha, beta, left = _examine_piece(C, D, errs, a, b, mask, buf, hull)
        if undecided < 0:
            nseg = _emit(seg, nseg, a, b, INF)
            continue
        if undecided == 0:
            nseg = _emit(seg, nseg, a, b, FEAS)
            continue
        if forced or b - a <= LEAF or pieces >= MAX_PIECES or top + 4 > STACK:
            nseg = _emit(seg, nseg, a, b, UND)
            continue
        w = b - left
        na = max(left + max(alpha - 1e-12, 0.0) * w, a)
        nb = min(left + min(beta + 1e-12, 1.0) * w, b)
        if nb - na < SHRINK * (b - a):  # emit the left part now, the right part after the rest
            if na > a:
                nseg = _emit(seg, nseg, a, na, INF)
            if nb < b:
                sa[top], sb[top], sm[top] = nb, b, -1
                top += 1
            sa[top], sb[top], sm[top] = na, nb, mask
            top += 1
            continue
        top = _split_piece(C, D, errs, a, b, mask, undecided, which, False, sa, sb, sm, top)
    return runs_of(seg, nseg, t_end, out)


@jit
def _covered(cov, ncov, t0, t1):
    """True when [t0, t1] lies in one of the intervals cov[:ncov] (times proven to hold)."""
    for q in range(ncov):
        if cov[q, 0] <= t0 and t1 <= cov[q, 1]:
            return True
    return False


@jit
def _cover(cov, ncov, t0, t1):
    """Add [t0, t1] to the intervals proven to hold (merged with those it meets)."""
    for q in range(ncov):
        if cov[q, 0] <= t1 and t0 <= cov[q, 1]:
            cov[q, 0] = min(cov[q, 0], t0)
            cov[q, 1] = max(cov[q, 1], t1)
            return ncov
    if ncov < cov.shape[0]:
        cov[ncov, 0], cov[ncov, 1] = t0, t1
        return ncov + 1
    return ncov


@jit
def _holds_along(C, DS, DT, errs, s, t0, t1):
    """True when every bivariate constraint, taken at this s, is proven < 0 on all of [t0, t1] (its Bernstein
    coefficients in t there below minus its bound)."""
    nt_max = 0
    for j in range(C.shape[0]):
        nt_max = max(nt_max, DT[j])
    row = np.empty(nt_max + 1)
    for j in range(C.shape[0]):
        ds, nt = DS[j], DT[j]
        for k in range(nt + 1):
            acc = 0.0
            for i in range(ds + 1):
                acc += P.BINOMIALS[ds, i] * s ** i * (1.0 - s) ** (ds - i) * C[j, i, k]
            row[k] = acc
        piece = row[:nt + 1]
        _restrict_coefficients(piece, piece, t0, t1)
        if not piece.max() < -errs[j]:
            return False
    return True


@jit
def ball_runs(C, DS, DT, errs, t_end, out):
    """Every run of time in [0, t_end] in which some s in [0, 1] may satisfy the bivariate system, as
    :func:`runs_of` rows.  Boxes as in :func:`bfirst_time`, all of them, except those whose times are already
    proven to hold (by a box where every constraint is negative, or a point proof); the times of the boxes
    left undecided, and those proven, are then swept in order."""
    buf, scol, env, hull, clip = _box_scratch(C, DS, DT)
    hs0, hs1, ht0, ht1, hm = _heap()
    cov = np.empty((256, 2))
    ncov = 0
    und = np.empty((MAX_SEGMENTS, 2))
    nund = 0
    n = _push(hs0, hs1, ht0, ht1, hm, 0, 0.0, 1.0, 0.0, t_end, 0)
    boxes = 0
    while n > 0:
        n = _pop(hs0, hs1, ht0, ht1, hm, n)
        s0, s1, t0, t1, mask = hs0[n], hs1[n], ht0[n], ht1[n], hm[n]
        if _covered(cov, ncov, t0, t1):
            continue
        boxes += 1
        undecided, mask = _examine(C, DS, DT, errs, s0, s1, t0, t1, mask, buf, scol, env, hull, clip)
        if undecided < 0:
            continue
        if undecided == 0:
            ncov = _cover(cov, ncov, t0, t1)
            continue
        sm = 0.5 * (s0 + s1)
        if bholds_at(C, DS, DT, errs, sm, t0) == 1:
            if _holds_along(C, DS, DT, errs, sm, t0, t1):  # the whole time span holds at this s
                ncov = _cover(cov, ncov, t0, t1)
                continue
            ncov = _cover(cov, ncov, t0, t0)
        if _shrunk(clip, s0, s1, t0, t1) and boxes < MAX_BOXES:
            n = _push(hs0, hs1, ht0, ht1, hm, n, clip[2], clip[3], clip[0], clip[1], mask)
            continue
        # only times matter here: a box as narrow in time as a leaf is one, however wide in s
        if t1 - t0 <= LEAF or boxes >= MAX_BOXES or n + 2 > HEAP:
            if nund < und.shape[0]:
                und[nund, 0], und[nund, 1] = t0, t1
                nund += 1
            continue
        n = _halve(hs0, hs1, ht0, ht1, hm, n, s0, s1, t0, t1, mask, DS, DT, buf)
    for q in range(n):  # boxes the limits left unexamined are undecided
        if nund < und.shape[0]:
            und[nund, 0], und[nund, 1] = ht0[q], ht1[q]
            nund += 1
    # sweep: a time is proven to hold when covered, undecided when in an undecided box, else free
    pts = np.empty(2 * (ncov + nund) + 2)
    npt = 0
    pts[npt] = 0.0
    pts[npt + 1] = t_end
    npt += 2
    for q in range(ncov):
        pts[npt], pts[npt + 1] = cov[q, 0], cov[q, 1]
        npt += 2
    for q in range(nund):
        pts[npt], pts[npt + 1] = und[q, 0], und[q, 1]
        npt += 2
    pts = np.sort(pts[:npt])
    seg = np.empty((MAX_SEGMENTS, 3))
    nseg = 0
    for q in range(npt):
        t = pts[q]
        label = INF
        for c in range(ncov):
            if cov[c, 0] <= t <= cov[c, 1]:
                label = FEAS
        if label == INF:
            for c in range(nund):
                if und[c, 0] <= t <= und[c, 1]:
                    label = UND
        nseg = _emit(seg, nseg, t, t, label)
        if q + 1 < npt and pts[q + 1] > t:
            m = 0.5 * (t + pts[q + 1])
            label = INF
            for c in range(ncov):
                if cov[c, 0] <= m <= cov[c, 1]:
                    label = FEAS
            if label == INF:
                for c in range(nund):
                    if und[c, 0] <= m <= und[c, 1]:
                        label = UND
            nseg = _emit(seg, nseg, t, pts[q + 1], label)
    return runs_of(seg, nseg, t_end, out)
