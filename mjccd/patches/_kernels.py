"""Numba kernels of the patch solver: line contours, IntersectionPeriod, swept boxes, search.

Everything here takes plain float64/int64 arrays and scalars and never raises; the
Python layer in :mod:`mjccd.patches.solver` validates and prepares the arrays.

Storage: every live sub-patch is one row of a pool, ``(N, 7)`` homogeneous control points
``[w x_t0, w y_t0, w z_t0, w, w x_t1, w y_t1, w z_t1]`` plus its parameter region
``(u0, v0, h, o)``; a search node is a pair of pool rows and a time interval. Pool rows
are reference counted and recycled, so memory follows the live queue, not the history.
"""
from collections import namedtuple

import numpy as np
import numba

from mjccd.bernstein import copy_into
from mjccd.sorting import sort_by_key

# compiled on first use and cached; no cfunc wrapper (no kernel is passed around as a first-class function);
# forceinline=False: numba hands a caller's forceinline down to the callees it compiles
_jit = numba.njit(cache=True, nogil=True, error_model="numpy", no_cfunc_wrapper=True, forceinline=False)
# small helpers of hot loops; only ones on scalars or called once per node: array arguments of a helper cost
# reference counting in the loops that call it.  Compiled once and inlined by LLVM (inline="always" copied
# their numba IR into every caller, which multiplied compile time; docs/benchmarks.md, "First use")
_inline = numba.njit(cache=True, nogil=True, error_model="numpy", no_cfunc_wrapper=True, forceinline=True)

INF = np.inf

# status codes returned by the search
NO_CONTACT = 0
CONTACT = 1
MAX_ITERATIONS = 2
MAX_NODES = 3

# primitives with at most this many line pairs skip the contour sweep
PAIRWISE_MAX = 16

# method codes
OURS = 0
TRAD = 1


# ---------------------------------------------------------------------------- contours
@_jit
def _sort_by_slope(a, n, order):
    """Insertion sort of ``order[:n]`` by ascending ``a`` (n is at most a few dozen)."""
    for i in range(n):
        order[i] = i
    sort_by_key(order, n, a)


@_jit
def _upper_contour(a, b, eps, order, n, sign, tl, tu, ca, cb, cx):
    """Max contour over [tl, tu] of the lines ``sign*(a t + b) + eps`` (sort-and-sweep).

    ``order`` sorts ``a`` ascending; with ``sign = -1`` it is walked backwards, so the
    signed slopes are ascending either way. Output: contour line k (slope ``ca[k]``,
    intercept ``cb[k]``) is the maximum on ``[cx[k], cx[k+1]]``; ``cx[0] = tl``,
    ``cx[m] = tu``. Returns m. Lines of equal slope keep the larger intercept; a line is
    dropped when it never rises above the contour inside [tl, tu].
    """
    m = 0
    for kk in range(n):
        idx = order[kk] if sign > 0 else order[n - 1 - kk]
        sa = sign * a[idx]
        sb = sign * b[idx] + eps[idx]
        keep = True
        while m > 0:
            ta = ca[m - 1]
            tb = cb[m - 1]
            if sa == ta:
                if sb <= tb:
                    keep = False
                    break
                m -= 1
                continue
            # sa > ta: the new line overtakes the top one at x
            x = (tb - sb) / (sa - ta)
            if x <= cx[m - 1]:
                m -= 1
                continue
            break
        if not keep:
            continue
        if m == 0:
            ca[0] = sa
            cb[0] = sb
            cx[0] = tl
            m = 1
        else:
            x = (cb[m - 1] - sb) / (sa - ca[m - 1])
            if x >= tu:
                continue
            ca[m] = sa
            cb[m] = sb
            cx[m] = x
            m += 1
    cx[m] = tu
    return m


@_jit
def _negative_interval(ca1, cb1, cx1, m1, ca2, cb2, cx2, m2, tl, tu, out, k):
    """Where the convex sum of two contours is negative, as an open interval.

    Writes ``out[k] = (s, e)``; ``s = -inf`` when already negative at tl and
    ``e = +inf`` when still negative at tu. Returns k + 1, or k when never negative.
    A convex function is negative on at most one interval, found by one merged sweep
    over the breakpoints of both contours.
    """
    i = 0
    j = 0
    x = tl
    g = (ca1[0] + ca2[0]) * x + cb1[0] + cb2[0]
    inside = g < 0.0
    s = -INF
    while True:
        xa = cx1[i + 1]
        xb = cx2[j + 1]
        nx = xa if xa < xb else xb
        sl = ca1[i] + ca2[j]
        ic = cb1[i] + cb2[j]
        gn = sl * nx + ic
        if not inside:
            if gn < 0.0:
                r = -ic / sl
                s = r if r > x else x
                inside = True
        else:
            if gn >= 0.0:
                r = -ic / sl
                e = r if r < nx else nx
                out[k, 0] = s
                out[k, 1] = e
                return k + 1
        if xa <= nx:
            i += 1
        if xb <= nx:
            j += 1
        x = nx
        if i >= m1 or j >= m2:
            break
    if inside:
        out[k, 0] = s
        out[k, 1] = INF
        return k + 1
    return k


@_jit
def _project(p0, p1, n, ex, ey, ez, a, b):
    for i in range(n):
        bi = p0[i, 0] * ex + p0[i, 1] * ey + p0[i, 2] * ez
        a[i] = p1[i, 0] * ex + p1[i, 1] * ey + p1[i, 2] * ez - bi
        b[i] = bi


@_jit
def _pairwise_gap(a1, b1, s1, n1, a2, b2, s2, n2, tl, tu, out, k):
    """Where ``max(line set 1) + shift < min(line set 2) - shift``, by testing all pairs.

    The same open interval as the contour sweep (written to ``out[k]`` with the same
    conventions), in O(n1 n2): the cheaper route for the few lines of small primitives.
    """
    lo = -INF
    hi = INF
    for i in range(n1):
        for j in range(n2):
            sl = a1[i] - a2[j]
            ic = b1[i] - b2[j] + s1[i] + s2[j]
            if sl > 0.0:
                r = -ic / sl
                if r < hi:
                    hi = r
            elif sl < 0.0:
                r = -ic / sl
                if r > lo:
                    lo = r
            elif ic >= 0.0:
                return k
    if lo >= hi or hi <= tl or lo >= tu:
        return k
    out[k, 0] = lo if lo >= tl else -INF
    out[k, 1] = hi if hi <= tu else INF
    return k + 1


@_jit
def _axis_gaps(pa0, pa1, sa, na, pb0, pb1, sb, nb, ex, ey, ez, tl, tu, ws, out, k):
    """Non-overlap intervals on one axis (A below B, B below A); returns the new count."""
    aa = ws.aa
    ba = ws.ba
    ab = ws.ab
    bb = ws.bb
    _project(pa0, pa1, na, ex, ey, ez, aa, ba)
    _project(pb0, pb1, nb, ex, ey, ez, ab, bb)
    if na * nb <= PAIRWISE_MAX:
        k = _pairwise_gap(aa, ba, sa, na, ab, bb, sb, nb, tl, tu, out, k)
        if k > 0 and out[k - 1, 0] == -INF and out[k - 1, 1] == INF:
            return k
        return _pairwise_gap(ab, bb, sb, nb, aa, ba, sa, na, tl, tu, out, k)
    _sort_by_slope(aa, na, ws.oa)
    _sort_by_slope(ab, nb, ws.ob)
    # A below B: max_A(t) + eps < min_B(t) - eps  <=>  maxA + (-minB) < 0
    m1 = _upper_contour(aa, ba, sa, ws.oa, na, 1.0, tl, tu, ws.c1a, ws.c1b, ws.c1x)
    m2 = _upper_contour(ab, bb, sb, ws.ob, nb, -1.0, tl, tu, ws.c2a, ws.c2b, ws.c2x)
    k = _negative_interval(ws.c1a, ws.c1b, ws.c1x, m1, ws.c2a, ws.c2b, ws.c2x, m2, tl, tu,
                           out, k)
    if k > 0 and out[k - 1, 0] == -INF and out[k - 1, 1] == INF:
        return k
    # B below A
    m1 = _upper_contour(ab, bb, sb, ws.ob, nb, 1.0, tl, tu, ws.c1a, ws.c1b, ws.c1x)
    m2 = _upper_contour(aa, ba, sa, ws.oa, na, -1.0, tl, tu, ws.c2a, ws.c2b, ws.c2x)
    return _negative_interval(ws.c1a, ws.c1b, ws.c1x, m1, ws.c2a, ws.c2b, ws.c2x, m2, tl, tu,
                              out, k)


@_inline
def _escape(out, k, x, end, limit):
    """Move x out of every open interval ``out[:k]`` through their ``end`` (1: upper, pushing x up;
    0: lower, pushing it down), sweep after sweep, until it lies in none or has passed ``limit``."""
    changed = True
    while changed:
        changed = False
        for q in range(k):
            if out[q, 0] < x and x < out[q, 1]:
                x = out[q, end]
                changed = True
        if (x > limit) if end == 1 else (x < limit):
            return x
    return x


@_jit
def _feasible_hull(out, k, tl, tu):
    """Smallest and largest t in [tl, tu] outside every open interval ``out[:k]``."""
    lo = _escape(out, k, tl, 1, tu)
    if lo > tu:
        return INF, -INF
    hi = _escape(out, k, tu, 0, tl)
    if hi < tl:
        return INF, -INF
    return lo, hi


@_jit
def _axes(fa, fb, use_obb, axes):
    """Separating axes: 3 world axes, or the 15 OBB axes (near-parallel crosses skipped)."""
    if not use_obb:
        for r in range(3):
            for c in range(3):
                axes[r, c] = 1.0 if r == c else 0.0
        return 3
    n = 0
    for r in range(3):
        for c in range(3):
            axes[n, c] = fa[r, c]
            axes[n + 1, c] = fb[r, c]
        n += 2
    for r in range(3):
        for q in range(3):
            x = fa[r, 1] * fb[q, 2] - fa[r, 2] * fb[q, 1]
            y = fa[r, 2] * fb[q, 0] - fa[r, 0] * fb[q, 2]
            z = fa[r, 0] * fb[q, 1] - fa[r, 1] * fb[q, 0]
            nn = np.sqrt(x * x + y * y + z * z)
            if nn > 1e-9:
                axes[n, 0] = x / nn
                axes[n, 1] = y / nn
                axes[n, 2] = z / nn
                n += 1
    return n


@_jit
def intersection_period(pa0, pa1, sa, fa, na, pb0, pb1, sb, fb, nb, tl, tu, use_obb,
                        time_margin, ws):
    """Time interval [tau_min, tau_max] within [tl, tu] where the two inclusions may meet.

    pa0/pa1: (na, 3) Euclidean control points of A at t = 0 and t = 1 (linear in between);
    sa: (na,) per-line contour shift (the robustness margin); fa: (3, 3) OBB frame rows.
    The candidate interval is widened by ``time_margin`` while testing and the result is
    clipped back to [tl, tu]. Returns ``(inf, -inf)`` when the inclusions never meet.
    """
    el = tl - time_margin
    eu = tu + time_margin
    if use_obb and (na == 1 or nb == 1):
        # a point against a box: the box's own three axes are exact (no cross axes)
        f = fb if na == 1 else fa
        for r in range(3):
            for c in range(3):
                ws.axes[r, c] = f[r, c]
        nax = 3
    else:
        nax = _axes(fa, fb, use_obb, ws.axes)
    k = 0
    for q in range(nax):
        k = _axis_gaps(pa0, pa1, sa, na, pb0, pb1, sb, nb, ws.axes[q, 0], ws.axes[q, 1],
                       ws.axes[q, 2], el, eu, ws, ws.gaps, k)
        if k > 0 and ws.gaps[k - 1, 0] == -INF and ws.gaps[k - 1, 1] == INF:
            return INF, -INF
    lo, hi = _feasible_hull(ws.gaps, k, el, eu)
    if lo > hi:
        return INF, -INF
    if lo < tl:
        lo = tl
    if hi > tu:
        hi = tu
    if lo > hi:
        # feasible only inside the widened margins: keep the nearer endpoint
        if lo > tu:
            lo = tu
        hi = lo
    return lo, hi


@_inline
def _extend(lo, hi, b, a, s, tl, tu):
    """(lo, hi) widened by the range over [tl, tu] of the line ``a t + b`` widened by s."""
    v0 = b + a * tl
    v1 = b + a * tu
    return min(lo, min(v0, v1) - s), max(hi, max(v0, v1) + s)


@_jit
def swept_boxes_overlap(pa0, pa1, sa, fa, na, pb0, pb1, sb, fb, nb, tl, tu, use_obb, ws):
    """Traditional test: do the boxes of the volumes swept over [tl, tu] overlap?"""
    nax = _axes(fa, fb, use_obb, ws.axes)
    for q in range(nax):
        ex = ws.axes[q, 0]
        ey = ws.axes[q, 1]
        ez = ws.axes[q, 2]
        _project(pa0, pa1, na, ex, ey, ez, ws.aa, ws.ba)
        _project(pb0, pb1, nb, ex, ey, ez, ws.ab, ws.bb)
        amin = INF
        amax = -INF
        for i in range(na):
            amin, amax = _extend(amin, amax, ws.ba[i], ws.aa[i], sa[i], tl, tu)
        bmin = INF
        bmax = -INF
        for i in range(nb):
            bmin, bmax = _extend(bmin, bmax, ws.bb[i], ws.ab[i], sb[i], tl, tu)
        if amax < bmin or bmax < amin:
            return False
    return True


# ---------------------------------------------------------------------------- sub-patches
@_jit
def _unit(x, y, z, out, r):
    nn = np.sqrt(x * x + y * y + z * z)
    if nn > 0.0 and np.isfinite(nn):
        out[r, 0] = x / nn
        out[r, 1] = y / nn
        out[r, 2] = z / nn
        return True
    return False


@_jit
def _corner(p0, p1, t, i, c):
    return p0[i, c] + t * (p1[i, c] - p0[i, c])


@_jit
def _directions(p0, p1, t, c0, cu, cv, cw, c):
    """Component c of the u and v parameter directions at time t (Eq. 19-20)."""
    u = 0.0
    v = 0.0
    if cw >= 0:
        o = _corner(p0, p1, t, c0, c)
        pu = _corner(p0, p1, t, cu, c)
        pv = _corner(p0, p1, t, cv, c)
        pw = _corner(p0, p1, t, cw, c)
        u = 0.5 * (pu - o + pw - pv)
        v = 0.5 * (pv - o + pw - pu)
    else:
        if cu >= 0:
            u = _corner(p0, p1, t, cu, c) - _corner(p0, p1, t, c0, c)
        if cv >= 0:
            v = _corner(p0, p1, t, cv, c) - _corner(p0, p1, t, c0, c)
    return u, v


@_jit
def frame(p0, p1, t, corners, out):
    """Orthonormal OBB frame (rows) from the parameter directions of the shape at time t.

    Axis 1 follows the u direction (paper Eq. 19-21), axis 2 the normal u x v, axis 3
    completes the frame; degenerate directions (points, segments, collapsed corners) fall
    back to any orthonormal completion. Any fixed frame keeps the test conservative; the
    shape at the start of the tested interval keeps the boxes tight.
    """
    c0 = corners[0]
    cu = corners[1]
    cv = corners[2]
    cw = corners[3]
    ux, vx = _directions(p0, p1, t, c0, cu, cv, cw, 0)
    uy, vy = _directions(p0, p1, t, c0, cu, cv, cw, 1)
    uz, vz = _directions(p0, p1, t, c0, cu, cv, cw, 2)
    if not _unit(ux, uy, uz, out, 0):
        if not _unit(vx, vy, vz, out, 0):
            out[0, 0] = 1.0
            out[0, 1] = 0.0
            out[0, 2] = 0.0
    ax = out[0, 0]
    ay = out[0, 1]
    az = out[0, 2]
    nx = uy * vz - uz * vy
    ny = uz * vx - ux * vz
    nz = ux * vy - uy * vx
    lu = np.sqrt(ux * ux + uy * uy + uz * uz)
    lv = np.sqrt(vx * vx + vy * vy + vz * vz)
    ln = np.sqrt(nx * nx + ny * ny + nz * nz)
    ok = ln > 1e-12 * lu * lv and ln > 0.0
    if ok:
        # remove any component along axis 1 (exactly zero in exact arithmetic)
        d = nx * ax + ny * ay + nz * az
        ok = _unit(nx - d * ax, ny - d * ay, nz - d * az, out, 1)
    if not ok:
        # any unit vector orthogonal to axis 1: cross with the least aligned world axis
        if abs(ax) <= abs(ay) and abs(ax) <= abs(az):
            _unit(0.0, az, -ay, out, 1)
        elif abs(ay) <= abs(az):
            _unit(-az, 0.0, ax, out, 1)
        else:
            _unit(ay, -ax, 0.0, out, 1)
    bx = out[1, 0]
    by = out[1, 1]
    bz = out[1, 2]
    out[2, 0] = ay * bz - az * by
    out[2, 1] = az * bx - ax * bz
    out[2, 2] = ax * by - ay * bx


@_jit
def euclidean(hom, n, margin, p0, p1, shift):
    """Euclidean control points at t = 0, 1 from homogeneous rows; every line shifts by margin."""
    for i in range(n):
        w = hom[i, 3]
        for c in range(3):
            p0[i, c] = hom[i, c] / w
            p1[i, c] = hom[i, 4 + c] / w
        shift[i] = margin


@_jit
def _child_region(kind, reg, c, out):
    """Region ``(u0, v0, h, o)`` of child c of ``reg``, as in
    :func:`mjccd.patches.primitives.child_regions`: a point keeps its own; curves halve, quads
    quarter; a triangle's children are its corners (c = 0, 1, 2) and the middle one (c = 3,
    orientation flipped)."""
    u0, v0, h, o = reg[0], reg[1], reg[2], reg[3]
    hh = 0.5 * h
    if kind == 0:
        u, v, w, side = u0, v0, h, o
    elif kind == 1:
        u, v, w, side = u0 + c * hh, v0, hh, 1.0
    elif kind == 3:
        u, v, w, side = u0 + (c // 2) * hh, v0 + (c % 2) * hh, hh, 1.0
    else:
        u = u0 + o * hh if c == 1 or c == 3 else u0
        v = v0 + o * hh if c == 2 or c == 3 else v0
        w, side = hh, (-o if c == 3 else o)
    out[0] = u
    out[1] = v
    out[2] = w
    out[3] = side


@_jit
def region_point(kind, reg, out, k):
    """Representative parameters of a region (centre, or centroid for triangles)."""
    if kind == 0:
        out[k] = 0.0
        out[k + 1] = 0.0
    elif kind == 1:
        out[k] = reg[0] + 0.5 * reg[2]
        out[k + 1] = 0.0
    elif kind == 3:
        out[k] = reg[0] + 0.5 * reg[2]
        out[k + 1] = reg[1] + 0.5 * reg[2]
    else:
        out[k] = reg[0] + reg[3] * reg[2] / 3.0
        out[k + 1] = reg[1] + reg[3] * reg[2] / 3.0


@_jit
def _subdivide(mat, hom, n, out):
    for i in range(n):
        for c in range(7):
            acc = 0.0
            for j in range(n):
                acc += mat[i, j] * hom[j, c]
            out[i, c] = acc


# ---------------------------------------------------------------------------- workspace
Workspace = namedtuple("Workspace", "aa ba ab bb oa ob c1a c1b c1x c2a c2b c2x axes gaps")


@_jit
def make_workspace(nmax):
    """Scratch arrays for the inclusion tests of primitives with up to ``nmax`` points."""
    return Workspace(np.empty(nmax), np.empty(nmax), np.empty(nmax), np.empty(nmax),
                     np.empty(nmax, np.int64), np.empty(nmax, np.int64),
                     np.empty(nmax + 1), np.empty(nmax + 1), np.empty(nmax + 1),
                     np.empty(nmax + 1), np.empty(nmax + 1), np.empty(nmax + 1),
                     np.empty((15, 3)), np.empty((32, 2)))


# arrays are copied by loops (copy_into), never by a slice assignment from an array (see mjccd.bernstein's _jit)


@_jit
def _copy_rows_into(dst, src):
    """``dst[:len(src)] = src`` for two 2-D arrays of one width, row by row."""
    for i in range(src.shape[0]):
        copy_into(dst[i], src[i])


@_jit
def _grow3(a, cap):
    b = np.empty((cap, a.shape[1], a.shape[2]))
    for i in range(a.shape[0]):
        _copy_rows_into(b[i], a[i])
    return b


@_jit
def _grow2(a, cap):
    b = np.empty((cap, a.shape[1]), a.dtype)
    _copy_rows_into(b, a)
    return b


@_jit
def _grow1(a, cap):
    return copy_into(np.zeros(cap, a.dtype), a)


# ---------------------------------------------------------------------------- one side
# The sub-patches of one side (A or B) live in a pool: rows ``pool`` (cap, N, 7) of homogeneous
# control points, their regions ``reg`` (cap, 4), reference counts ``ref`` (the queued nodes
# that use a row), and a stack ``free[:nfree]`` of rows to recycle; rows ``top`` on were never used.
@_jit
def _make_pool(roots, kind):
    """A pool holding the primitives ``roots`` (K, N, 7) in rows 0..K-1, each over its whole region:
    (pool, reg, ref, free)."""
    k = roots.shape[0]
    cap = max(64, 2 * k)
    pool = np.empty((cap, roots.shape[1], 7))
    reg = np.empty((cap, 4))
    for i in range(k):
        _copy_rows_into(pool[i], roots[i])
        reg[i, 0] = 0.0
        reg[i, 1] = 0.0
        reg[i, 2] = 1.0 if kind != 0 else 0.0
        reg[i, 3] = 1.0
    return pool, reg, np.zeros(cap, np.int64), np.empty(cap, np.int64)


@_jit
def _grow_pool(pool, reg, ref, free):
    """The pool's arrays at twice the capacity."""
    cap = 2 * pool.shape[0]
    return _grow3(pool, cap), _grow2(reg, cap), _grow1(ref, cap), _grow1(free, cap)


@_inline
def _store(pool, reg, ref, free, nfree, top, hom, region):
    """Copy a sub-patch and its region into a recycled row, else into row ``top`` (the caller grows
    a full pool first: :func:`_grow_pool`); returns (the row, nfree, top)."""
    if nfree > 0:
        nfree -= 1
        j = free[nfree]
    else:
        j = top
        top += 1
    _copy_rows_into(pool[j], hom)
    copy_into(reg[j], region)
    ref[j] = 0
    return j, nfree, top


@_inline
def _release(ref, free, nfree, i):
    """One queued node fewer uses row i; an unused row goes on the free stack. Returns nfree."""
    ref[i] -= 1
    if ref[i] == 0:
        free[nfree] = i
        nfree += 1
    return nfree


@_jit
def _make_children(count, n):
    """Scratch for the ``count`` children of a primitive with n control points: rows, regions,
    Euclidean control points at t = 0 and 1, contour shifts, OBB frames, pool rows."""
    return (np.empty((count, n, 7)), np.empty((count, 4)), np.empty((count, n, 3)),
            np.empty((count, n, 3)), np.empty((count, n)), np.empty((count, 3, 3)),
            np.empty(count, np.int64))


@_inline
def _child(sub, pool, reg, row, kind, corners, n, margin, t_frame, ch, rg, e0, e1, sh, fr, c):
    """Child c of pool row ``row`` (``sub``: the subdivision matrices) into row c of the scratch
    arrays: its control points, region, Euclidean control points and shifts, and OBB frame from its
    shape at t_frame."""
    _subdivide(sub[c], pool[row], n, ch[c])
    _child_region(kind, reg[row], c, rg[c])
    euclidean(ch[c], n, margin, e0[c], e1[c], sh[c])
    frame(e0[c], e1[c], t_frame, corners, fr[c])


# ---------------------------------------------------------------------------- heap
@_jit
def _less(hf, i, j):
    """Order: time bucket of the lower end, then smaller width (deeper first), then time."""
    if hf[i, 3] != hf[j, 3]:
        return hf[i, 3] < hf[j, 3]
    if hf[i, 2] != hf[j, 2]:
        return hf[i, 2] < hf[j, 2]
    return hf[i, 0] < hf[j, 0]


@_jit
def _swap(hf, hi, i, j):
    for c in range(4):
        x = hf[i, c]
        hf[i, c] = hf[j, c]
        hf[j, c] = x
    for c in range(3):
        y = hi[i, c]
        hi[i, c] = hi[j, c]
        hi[j, c] = y


@_jit
def _heap_min_time(hf, nh, t):
    """Smallest lower end among t and the queued nodes: a valid bound on the first contact."""
    for k in range(nh):
        if hf[k, 0] < t:
            t = hf[k, 0]
    return t


@_jit
def _scale(roots):
    """Largest absolute Euclidean coordinate of a set of primitives over the step."""
    m = 0.0
    for k in range(roots.shape[0]):
        for i in range(roots.shape[1]):
            w = roots[k, i, 3]
            for c in range(3):
                m = max(m, abs(roots[k, i, c] / w), abs(roots[k, i, 4 + c] / w))
    return m


@_jit
def _sift_up(hf, hi, k):
    p = (k - 1) // 2
    while k > 0 and _less(hf, k, p):
        _swap(hf, hi, k, p)
        k = p
        p = (k - 1) // 2


@_jit
def _sift_down(hf, hi, n):
    k = 0
    while True:
        c = 2 * k + 1
        if c >= n:
            break
        if c + 1 < n and _less(hf, c + 1, c):
            c += 1
        if _less(hf, c, k):
            _swap(hf, hi, k, c)
            k = c
        else:
            break


@_inline
def _push(hf, hi, nh, lo, up, width, quantum, ia, ib, pair):
    """Queue the node of pool rows (ia, ib) of root pair ``pair`` over [lo, up] (room for it is
    there); returns the new count."""
    hf[nh, 0] = lo
    hf[nh, 1] = up
    hf[nh, 2] = width if quantum > 0.0 else 0.0
    hf[nh, 3] = np.floor(lo / quantum) if quantum > 0.0 else lo
    hi[nh, 0] = ia
    hi[nh, 1] = ib
    hi[nh, 2] = pair
    _sift_up(hf, hi, nh)
    return nh + 1


# ---------------------------------------------------------------------------- search
@_jit
def search(kind_a, corners_a, sub_a, roots_a, kind_b, corners_b, sub_b, roots_b, pairs,
           method, use_obb, delta, t_max, rel, time_margin, max_iterations, max_nodes,
           depth_first_ties, frames_at_step_start, manifold, simultaneity, separation,
           points_out, info_out):
    """Best-first subdivision search for the earliest contact (paper Alg. 2, or Alg. 1).

    roots_a: (Ka, Na, 7) homogeneous rows of the primitives of side A (likewise B);
    pairs: (P, 2) which (a, b) primitives to test. ``method`` is OURS (time-dependent
    inclusions, parameter subdivision only) or TRAD (swept boxes, time bisected too).
    Nodes are popped by the lower end of their time interval (with depth_first_ties,
    ends within delta/16 tie and the smaller node goes first); a node is accepted when
    every parameter width (and for TRAD the time width) is below ``delta``. The reported
    time is the smaller of the accepted node's lower end and every queued lower end, so
    it stays a lower bound of the first contact. Every contour line is shifted outwards
    by ``rel`` times the largest absolute coordinate of all input control points.
    OBB frames come from each sub-patch's shape at t = 0 (``frames_at_step_start``, the
    paper's rule) or at the lower end of the parent's time interval (otherwise).

    Writes rows ``[t, u1, v1, u2, v2, x, y, z, pair]`` to ``points_out`` (one row, or up
    to ``points_out.shape[0]`` distinct points in manifold mode) and
    ``[status, iterations, points, peak queue]`` to ``info_out``. With status
    MAX_ITERATIONS or MAX_NODES, row 0 holds the smallest open lower bound on the time.
    """
    na = roots_a.shape[1]
    nb = roots_b.shape[1]
    ws = make_workspace(max(na, nb))
    # children scratch
    chA, rgA, eA0, eA1, shA, frA, idxA = _make_children(sub_a.shape[0], na)
    chB, rgB, eB0, eB1, shB, frB, idxB = _make_children(sub_b.shape[0], nb)
    # pools
    poolA, regA, refA, freeA = _make_pool(roots_a, kind_a)
    poolB, regB, refB, freeB = _make_pool(roots_b, kind_b)
    nfreeA = 0
    nfreeB = 0
    topA = roots_a.shape[0]
    topB = roots_b.shape[0]
    # heap: floats (t_lo, t_hi, width, bucket), ints (pool a, pool b, root pair). With
    # depth_first_ties, lower ends within one time quantum (delta / 16) count as ties and
    # deeper nodes go first, so nearly simultaneous candidates (face contact) are refined
    # depth-first; otherwise the order is the lower end alone (the papers' queue)
    quantum = 0.0625 * delta if depth_first_ties else 0.0
    margin = rel * max(_scale(roots_a), _scale(roots_b))
    capH = 256
    hf = np.empty((capH, 4))
    hi = np.empty((capH, 3), np.int64)
    nh = 0
    peak = 0
    # roots
    for p in range(pairs.shape[0]):
        ia = pairs[p, 0]
        ib = pairs[p, 1]
        euclidean(poolA[ia], na, margin, eA0[0], eA1[0], shA[0])
        frame(eA0[0], eA1[0], 0.0, corners_a, frA[0])
        euclidean(poolB[ib], nb, margin, eB0[0], eB1[0], shB[0])
        frame(eB0[0], eB1[0], 0.0, corners_b, frB[0])
        if method == OURS:
            lo, up = intersection_period(eA0[0], eA1[0], shA[0], frA[0], na, eB0[0], eB1[0],
                                         shB[0], frB[0], nb, 0.0, t_max, use_obb,
                                         time_margin, ws)
        else:
            lo = 0.0
            up = t_max
            if not swept_boxes_overlap(eA0[0], eA1[0], shA[0], frA[0], na, eB0[0], eB1[0],
                                       shB[0], frB[0], nb, 0.0, t_max, use_obb, ws):
                lo = INF
        if lo <= up:
            if nh == capH:
                capH *= 2
                hf = _grow2(hf, capH)
                hi = _grow2(hi, capH)
            nh = _push(hf, hi, nh, lo, up, max(regA[ia, 2], regB[ib, 2]), quantum, ia, ib, p)
            refA[ia] += 1
            refB[ib] += 1
    for i in range(roots_a.shape[0]):
        if refA[i] == 0:
            freeA[nfreeA] = i
            nfreeA += 1
    for i in range(roots_b.shape[0]):
        if refB[i] == 0:
            freeB[nfreeB] = i
            nfreeB += 1

    status = NO_CONTACT
    iterations = 0
    found = 0
    t_first = INF
    max_points = points_out.shape[0]
    while nh > 0:
        if iterations >= max_iterations:
            status = MAX_ITERATIONS
            break
        # pop
        tl = hf[0, 0]
        tu = hf[0, 1]
        ia = hi[0, 0]
        ib = hi[0, 1]
        pr = hi[0, 2]
        nh -= 1
        if nh > 0:
            for c in range(4):
                hf[0, c] = hf[nh, c]
            for c in range(3):
                hi[0, c] = hi[nh, c]
            _sift_down(hf, hi, nh)
        iterations += 1
        if found > 0 and tl > t_first + simultaneity:
            nh = 0
            break
        width = max(regA[ia, 2], regB[ib, 2])
        if method == TRAD:
            width = max(width, tu - tl)
        if width < delta:
            # accepted: world point = centroid of A's control points at tl
            euclidean(poolA[ia], na, margin, eA0[0], eA1[0], shA[0])
            x = 0.0
            y = 0.0
            z = 0.0
            for i in range(na):
                x += eA0[0, i, 0] + tl * (eA1[0, i, 0] - eA0[0, i, 0])
                y += eA0[0, i, 1] + tl * (eA1[0, i, 1] - eA0[0, i, 1])
                z += eA0[0, i, 2] + tl * (eA1[0, i, 2] - eA0[0, i, 2])
            x /= na
            y /= na
            z /= na
            distinct = True
            for q in range(found):
                dx = points_out[q, 5] - x
                dy = points_out[q, 6] - y
                dz = points_out[q, 7] - z
                if dx * dx + dy * dy + dz * dz < separation * separation:
                    distinct = False
                    break
            if distinct:
                points_out[found, 0] = _heap_min_time(hf, nh, tl) if found == 0 else tl
                region_point(kind_a, regA[ia], points_out[found], 1)
                region_point(kind_b, regB[ib], points_out[found], 3)
                points_out[found, 5] = x
                points_out[found, 6] = y
                points_out[found, 7] = z
                points_out[found, 8] = pr
                if found == 0:
                    t_first = points_out[0, 0]
                found += 1
                status = CONTACT
            if not manifold or found >= max_points:
                nh = 0
                break
            nfreeA = _release(refA, freeA, nfreeA, ia)
            nfreeB = _release(refB, freeB, nfreeB, ib)
            continue
        if found > 0:
            # manifold mode: drop nodes whose A part lies inside a found point's ball
            euclidean(poolA[ia], na, margin, eA0[0], eA1[0], shA[0])
            covered = False
            for q in range(found):
                far = 0.0
                for c in range(3):
                    lo_c = INF
                    up_c = -INF
                    for i in range(na):
                        v0 = eA0[0, i, c] + tl * (eA1[0, i, c] - eA0[0, i, c])
                        v1 = eA0[0, i, c] + tu * (eA1[0, i, c] - eA0[0, i, c])
                        lo_c = min(lo_c, min(v0, v1))
                        up_c = max(up_c, max(v0, v1))
                    d = max(abs(lo_c - points_out[q, 5 + c]), abs(up_c - points_out[q, 5 + c]))
                    far += d * d
                if far <= separation * separation:
                    covered = True
                    break
            if covered:
                nfreeA = _release(refA, freeA, nfreeA, ia)
                nfreeB = _release(refB, freeB, nfreeB, ib)
                continue
        # subdivide both sides
        t_frame = 0.0 if frames_at_step_start else tl
        ca_n = sub_a.shape[0]
        cb_n = sub_b.shape[0]
        for c in range(ca_n):
            _child(sub_a, poolA, regA, ia, kind_a, corners_a, na, margin, t_frame, chA, rgA, eA0,
                   eA1, shA, frA, c)
            idxA[c] = ia if ca_n == 1 else -1
        for c in range(cb_n):
            _child(sub_b, poolB, regB, ib, kind_b, corners_b, nb, margin, t_frame, chB, rgB, eB0,
                   eB1, shB, frB, c)
            idxB[c] = ib if cb_n == 1 else -1
        full = False
        for ca in range(ca_n):
            for cb in range(cb_n):
                for half in range(1 if method == OURS else 2):
                    if method == OURS:
                        lo, up = intersection_period(eA0[ca], eA1[ca], shA[ca], frA[ca], na,
                                                     eB0[cb], eB1[cb], shB[cb], frB[cb], nb,
                                                     tl, tu, use_obb, time_margin, ws)
                    else:
                        tm = 0.5 * (tl + tu)
                        lo = tl if half == 0 else tm
                        up = tm if half == 0 else tu
                        if not swept_boxes_overlap(eA0[ca], eA1[ca], shA[ca], frA[ca], na,
                                                   eB0[cb], eB1[cb], shB[cb], frB[cb], nb,
                                                   lo, up, use_obb, ws):
                            lo = INF
                    if lo > up:
                        continue
                    if nh == capH:
                        if capH >= max_nodes:
                            full = True
                            break
                        capH *= 2
                        hf = _grow2(hf, capH)
                        hi = _grow2(hi, capH)
                    if idxA[ca] < 0:
                        if nfreeA == 0 and topA == poolA.shape[0]:
                            poolA, regA, refA, freeA = _grow_pool(poolA, regA, refA, freeA)
                        idxA[ca], nfreeA, topA = _store(poolA, regA, refA, freeA, nfreeA, topA,
                                                        chA[ca], rgA[ca])
                    if idxB[cb] < 0:
                        if nfreeB == 0 and topB == poolB.shape[0]:
                            poolB, regB, refB, freeB = _grow_pool(poolB, regB, refB, freeB)
                        idxB[cb], nfreeB, topB = _store(poolB, regB, refB, freeB, nfreeB, topB,
                                                        chB[cb], rgB[cb])
                    nh = _push(hf, hi, nh, lo, up, max(rgA[ca, 2], rgB[cb, 2]), quantum, idxA[ca],
                               idxB[cb], pr)
                    refA[idxA[ca]] += 1
                    refB[idxB[cb]] += 1
                if full:
                    break
            if full:
                break
        if nh > peak:
            peak = nh
        nfreeA = _release(refA, freeA, nfreeA, ia)
        nfreeB = _release(refB, freeB, nfreeB, ib)
        if full:
            # put the popped node's bound back as the answer's lower bound
            status = MAX_NODES
            if found == 0:
                points_out[0, 0] = _heap_min_time(hf, nh, tl)
            break
    if status == MAX_ITERATIONS and found == 0:
        points_out[0, 0] = _heap_min_time(hf, nh, INF)
    info_out[0] = status
    info_out[1] = iterations
    info_out[2] = found
    info_out[3] = peak


@_jit
def search_batch(kind_a, corners_a, sub_a, roots_a, kind_b, corners_b, sub_b, roots_b,
                 method, use_obb, delta, t_max, rel, time_margin, max_iterations, max_nodes,
                 depth_first_ties, frames_at_step_start, toi_out, status_out, iterations_out):
    """One single-pair search per query q: roots_a[q] against roots_b[q] (shape (Q, 1, N, 7))."""
    pairs = np.zeros((1, 2), np.int64)
    points = np.empty((1, 9))
    info = np.zeros(4, np.int64)
    for q in range(roots_a.shape[0]):
        search(kind_a, corners_a, sub_a, roots_a[q], kind_b, corners_b, sub_b, roots_b[q],
               pairs, method, use_obb, delta, t_max, rel, time_margin, max_iterations,
               max_nodes, depth_first_ties, frames_at_step_start, False, 0.0, 0.0, points,
               info)
        status_out[q] = info[0]
        iterations_out[q] = info[1]
        toi_out[q] = points[0, 0] if info[0] != NO_CONTACT else INF
