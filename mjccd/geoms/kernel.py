"""The first contact of two moving shapes: one compiled call per pair (numba kernel).

:func:`pair_kernel` builds both frames from their element rows
(:mod:`mjccd.geoms.frames`), the pair's systems (:mod:`mjccd.geoms.systems`),
decides the status at t = 0, scans every system for the first time it holds
(:mod:`mjccd.geoms.scan`) and turns the earliest one's witness into the
contact point, normal and touching elements (:mod:`mjccd.geoms.contact`).
"""
import math

import numpy as np

from mjccd.geoms import contact as ct
from mjccd.geoms import frames as fr
from mjccd.geoms import on_plane as op
from mjccd.geoms import poly as P
from mjccd.geoms import scan as sc
from mjccd.geoms import systems as sy
from mjccd.geoms.poly import jit

TIME_TOL = 1e-9             # a first contact is certified when its proven bracket is this narrow
OUT = 18                    # fields of a pair's answer, see pair_kernel
STATUS, LO, HI, TIME, CERTIFIED, POINT, NORMAL, ELEM_A, ELEM_B, SYSTEMS, WINNER, FAILED, TIER, PROVEN = (
    0, 1, 2, 3, 4, 5, 8, 11, 12, 13, 14, 15, 16, 17)
NOT_HANDLED, OVERFLOW, PARTIAL = 1.0, 2.0, 3.0  # values of out[FAILED]; PARTIAL: the ellipsoid solver adds more


@jit
def _degree(rows):
    """Degree in t of a frame composed of these element rows (forward rotation block)."""
    d = 0
    for k in range(rows.shape[0]):
        kind = int(rows[k, 0])
        if kind == fr.SLIDE:
            d += 1
        elif kind == fr.HINGE:
            d += 2
        else:
            moving = False
            for i in range(7):
                if rows[k, 1 + i] != rows[k, 8 + i]:
                    moving = True
            d += 3 if moving else 0
    return d


@jit
def _transform(W, I, F, t, L, v):
    """L (3, 3), v (3,) of the forward map of frame F at time t: x = L y + v."""
    m = P.value(W, I, F[fr.M0], t)
    for i in range(3):
        for j in range(3):
            L[i, j] = P.value(W, I, F[fr.L0 + 3 * i + j], t) / m
        v[i] = P.value(W, I, F[fr.V0 + i], t) / m


@jit
def _unit(x):
    n = math.sqrt(x[0] * x[0] + x[1] * x[1] + x[2] * x[2])
    return x / n if n > 0.0 else x


@jit
def _witness(W, I, SYS, k, s, t):
    """The winning system's witness at (s, t), in the frame of its side."""
    y = np.empty(3)
    vals = np.zeros(4)
    ds = SYS[k, 3]
    for c in range(4):
        for i in range(ds + 1):
            b = P.BINOMIALS[ds, i] * s ** i * (1.0 - s) ** (ds - i)
            vals[c] += b * P.value(W, I, SYS[k, sy.WIT + 5 * c + i], t)
    for c in range(3):
        y[c] = vals[c] / vals[3]
    return y


@jit
def _contact(W, I, SYS, SYSR, k, s, t, ka, sa, FA, kb, sb, FB, out):
    """Fill out[POINT], out[NORMAL], out[ELEM_A], out[ELEM_B] from system k's witness at (s, t)."""
    side = SYS[k, 2]
    y = _witness(W, I, SYS, k, s, t)
    La, va = np.empty((3, 3)), np.empty(3)
    Lb, vb = np.empty((3, 3)), np.empty(3)
    _transform(W, I, FA, t, La, va)
    _transform(W, I, FB, t, Lb, vb)
    Ls, vs = (La, va) if side == 0 else (Lb, vb)
    ks, ss = (ka, sa) if side == 0 else (kb, sb)
    q = np.empty(3)
    if SYSR[k] > 0.0:  # the witness is a rounded core: the contact is the solid's point nearest to it
        ct.closest_point(ks, ss, y, q)
        n_side = _unit(Ls @ (y - q))
        n = n_side if side == 0 else -n_side
        x = Ls @ q + vs
    else:
        x = Ls @ y + vs
        n = np.zeros(3)
    # each shape's element at the point (in its own frame; the rotation's inverse is its transpose)
    ya = La.T @ (x - va)
    yb = Lb.T @ (x - vb)
    tol = 1e-7
    ca, qa, na = ct.element(ka, sa, ya, tol)
    cb, qb, nb = ct.element(kb, sb, yb, tol)
    if SYSR[k] == 0.0:
        if qa == ct.FACE:
            n = La @ na
        elif qb == ct.FACE:
            n = -(Lb @ nb)
        elif qa == ct.EDGE and qb == ct.EDGE:
            ta, tb = La @ na, Lb @ nb
            n = _unit(np.array([ta[1] * tb[2] - ta[2] * tb[1], ta[2] * tb[0] - ta[0] * tb[2],
                                ta[0] * tb[1] - ta[1] * tb[0]]))
            if (n[0] * (x[0] - va[0]) + n[1] * (x[1] - va[1]) + n[2] * (x[2] - va[2])) < 0.0:
                n = -n
        n = _unit(n)
    for i in range(3):
        out[POINT + i] = x[i]
        out[NORMAL + i] = n[i]
    out[ELEM_A] = ca
    out[ELEM_B] = cb


@jit
def _systems_of(W, I, CON, SYS, SYSR, N, ka, sa, rows_a, kb, sb, rows_b):
    """Frames and systems of the pair in the workspace (W, I) and the system store (CON, SYS, SYSR, N), both
    emptied first; returns (FA, FB, C, DS, DT, errs, code) with each constraint's double coefficients C (rows
    in s, columns in t), degrees DS in s and DT in t, error bounds, and build_pair's code (or -1: overflow)."""
    P.reset(W, I)
    N[0] = N[1] = N[2] = 0
    FA = fr.chain_frame(W, I, rows_a)
    FB = fr.chain_frame(W, I, rows_b)
    code = sy.build_pair(W, I, CON, SYS, SYSR, N, ka, sa, FA, kb, sb, FB)
    C, DS, DT, errs = constraints_of(W, I, CON, N)
    if code != 0 and (N[2] or P.failed(I)):
        code = -1
    return FA, FB, C, DS, DT, errs, code


@jit
def constraints_of(W, I, CON, N):
    """The store's constraints as arrays: (C, DS, DT, errs), each constraint's double coefficients C (rows in
    s, columns in t, every row elevated to its degree in t), its degrees in s and t and the bound of their
    error, the rounding of the restriction and evaluation in s included."""
    ncon = N[0]
    ds_max, nt_max = 0, 0
    for c in range(ncon):
        ds_max = max(ds_max, CON[c, 0])
        for i in range(CON[c, 0] + 1):
            nt_max = max(nt_max, I[CON[c, 1 + i], 0])
    C = np.zeros((ncon, ds_max + 1, nt_max + 1))
    DS = np.empty(ncon, dtype=np.int64)
    DT = np.zeros(ncon, dtype=np.int64)
    errs = np.zeros(ncon)
    row = np.empty(nt_max + 1)
    for c in range(ncon):
        DS[c] = CON[c, 0]
        for i in range(DS[c] + 1):
            DT[c] = max(DT[c], I[CON[c, 1 + i], 0])
        for i in range(DS[c] + 1):  # every row elevated to the constraint's degree in t (exactly: in the arena)
            k = CON[c, 1 + i]
            if I[k, 0] < DT[c]:
                k = _elevated(W, I, k, DT[c])
            P.coefficients_into(W, I, k, row)
            for q in range(DT[c] + 1):
                C[c, i, q] = row[q]
            errs[c] = max(errs[c], P.error(W, I, k))
        if DS[c] > 0:  # the restriction and evaluation in s round too
            big = 0.0
            for i in range(DS[c] + 1):
                for q in range(DT[c] + 1):
                    big = max(big, abs(C[c, i, q]))
            errs[c] += P.gamma(10 * DS[c] + 8) * (big + errs[c])
    return C, DS, DT, errs


@jit
def _elevated(W, I, k, n):
    """Slot k elevated to degree n (a sum with a zero of degree n elevates it, with its bounds)."""
    z = P.alloc(W, I, n)
    for q in range(n + 1):
        for r in range(W.shape[1]):
            W[z, r, q] = 0.0
    return P.add(W, I, k, z, 1.0)


@jit
def status_of_systems(SYS, N, C, DS, DT, errs):
    """The pair's status at t = 0 from its systems: 1 (separate) when each is proven not to hold there, -1
    (overlapping) when one is proven to hold, else 0 (touching: undecided within rounding)."""
    status0 = 1
    for k in range(N[1]):
        s0, cnt = SYS[k, 0], SYS[k, 1]
        if SYS[k, 3] == 0:
            st = sc.status_at_start(np.ascontiguousarray(C[s0:s0 + cnt, 0, :]), errs[s0:s0 + cnt])
        else:
            st = _bstatus_at_start(C[s0:s0 + cnt], DS[s0:s0 + cnt], DT[s0:s0 + cnt], errs[s0:s0 + cnt])
        if st == -1:
            return -1
        if st == 0:
            status0 = 0
    return status0


@jit
def scan_systems(SYS, N, C, DS, DT, errs, t_end, out, decide):
    """Status at t = 0 (with ``decide``; else out[STATUS] = 1 and every system is scanned from 0, the caller
    deciding the start) and first contact over all systems into out (out[PROVEN] = 1 when some time is
    proven to satisfy a system); returns the winning system (-1: none) and the s at which it holds (bivariate
    systems)."""
    out[SYSTEMS] = N[1]
    out[CERTIFIED] = 0.0
    out[PROVEN] = 0.0
    out[STATUS] = 1.0
    if decide:
        status0 = status_of_systems(SYS, N, C, DS, DT, errs)
        out[STATUS] = status0
        if status0 != 1:
            out[LO] = out[HI] = out[TIME] = 0.0
            out[CERTIFIED] = 1.0
            out[PROVEN] = 1.0 if status0 == -1 else 0.0
            return -1, 0.5
    lo, hi, band_end = -1.0, -1.0, -1.0
    best, best_est, best_s = -1, 2.0, 0.5
    for k in range(N[1]):
        s0, cnt = SYS[k, 0], SYS[k, 1]
        limit = hi if hi >= 0.0 else t_end
        if SYS[k, 3] == 0:
            l, h, e, be = sc.first_time(np.ascontiguousarray(C[s0:s0 + cnt, 0, :]), DT[s0:s0 + cnt],
                                        errs[s0:s0 + cnt], limit)
            sv = 0.5
        else:
            l, h, e, be, sv = sc.bfirst_time(C[s0:s0 + cnt], DS[s0:s0 + cnt], DT[s0:s0 + cnt], errs[s0:s0 + cnt],
                                             limit)
        if l < 0.0:
            continue
        lo = l if lo < 0.0 else min(lo, l)
        if h >= 0.0 and (hi < 0.0 or h < hi):
            hi = h
        band_end = max(band_end, be)
        if e < best_est:
            best, best_est, best_s = k, e, sv
    out[LO] = lo
    out[HI] = out[TIME] = -1.0
    if lo < 0.0:  # proven free
        out[CERTIFIED] = 1.0
        return -1, 0.5
    if hi >= 0.0:
        out[HI] = hi
        out[PROVEN] = 1.0
        out[CERTIFIED] = 1.0 if hi - lo <= TIME_TOL else 0.0
    else:
        out[HI] = max(band_end, lo)
    t = min(max(best_est, lo), out[HI])
    out[TIME] = t if out[CERTIFIED] > 0.0 else lo
    out[WINNER] = best
    return best, best_s


@jit
def _bstatus_at_start(C, DS, DT, errs):
    """As :func:`mjccd.geoms.scan.status_at_start` for bivariate constraints at t = 0: whether some s in [0, 1]
    satisfies them all, decided by the univariate scan over s of their values at t = 0."""
    J = C.shape[0]
    ds = 0
    for j in range(J):
        ds = max(ds, DS[j])
    cols = np.zeros((J, ds + 1))
    for j in range(J):
        for i in range(DS[j] + 1):
            cols[j, i] = C[j, i, 0]
    lo, hi, _, _ = sc.first_time(cols, DS, errs, 1.0)
    if lo < 0.0:
        return 1
    return -1 if hi >= 0.0 else 0


@jit
def _clear(out):
    """An answer with nothing found yet."""
    for i in range(OUT):
        out[i] = 0.0
    out[LO] = out[HI] = out[TIME] = -1.0


@jit
def _on_plane(ka, sa, rows_a, kb, sb, rows_b, t_end, out):
    """A sphere or capsule against a static plane by :mod:`mjccd.geoms.on_plane`'s written-out systems, scanned
    as the general ones: True when that certifies the answer (in out), False to take the general path."""
    _clear(out)
    C = np.zeros((2, 1, 4))
    DS = np.zeros(2, dtype=np.int64)
    DT = np.zeros(2, dtype=np.int64)
    errs = np.zeros(2)
    SYS = np.zeros((2, sy.SYS_FIELDS), dtype=np.int64)
    N = np.zeros(3, dtype=np.int64)
    ends = np.zeros(2)
    op.systems(ka, sa, rows_a, kb, sb, rows_b, C, DT, errs, SYS, N, ends)
    best, _ = scan_systems(SYS, N, C, DS, DT, errs, t_end, out, np.bool_(True))
    if out[CERTIFIED] == 0.0:
        return False
    if best >= 0:
        x, n, ca, cb = op.contact(ka, sa, rows_a, kb, sb, rows_b, ends[best], out[TIME])
        for i in range(3):
            out[POINT + i] = x[i]
            out[NORMAL + i] = n[i]
        out[ELEM_A] = ca
        out[ELEM_B] = cb
    return True


@jit
def pair_kernel(ka, sa, rows_a, kb, sb, rows_b, t_end, W, I, Wdd, Idd, CON, SYS, SYSR, N, out):
    """First contact over [0, t_end] of shape ka (size sa (3,), motion rows_a (n, ELEMENT_FIELDS)) and shape kb.

    ``W, I``: a double workspace, ``Wdd, Idd``: a double-double one
    (:func:`mjccd.geoms.poly.workspace`), ``CON, SYS, SYSR, N`` a system
    store (:func:`mjccd.geoms.systems.new_store`), all reused; the pair is solved in doubles and,
    when that leaves its first contact in a bracket wider than TIME_TOL,
    again in double-double.  out (OUT,): [STATUS] 1 separate, 0 touching, -1
    overlapping at t = 0; [LO, HI] the proven bracket of the first contact
    (-1, -1: none); [TIME] its estimate (-1: none; 0 when not separate at the
    start); [CERTIFIED] 1 or 0; [POINT], [NORMAL] (world, outward from shape
    a) and [ELEM_A], [ELEM_B] (element codes) of the contact; [SYSTEMS] how
    many systems the pair has, [WINNER] the one that touches first;
    [FAILED] 0, or NOT_HANDLED (a pair for another solver), OVERFLOW (a
    workspace too small), PARTIAL (the ellipsoid solver adds systems);
    [TIER] 0 when doubles sufficed, 1 when double-double was needed.
    A sphere or capsule against a static plane is first tried by
    :mod:`mjccd.geoms.on_plane` (no workspace), the general path taken
    when that leaves it uncertain.
    """
    if op.applies(ka, sa, rows_a, kb, sb, rows_b) and _on_plane(ka, sa, rows_a, kb, sb, rows_b, t_end, out):
        return
    general_kernel(ka, sa, rows_a, kb, sb, rows_b, t_end, W, I, Wdd, Idd, CON, SYS, SYSR, N, out)


@jit
def general_kernel(ka, sa, rows_a, kb, sb, rows_b, t_end, W, I, Wdd, Idd, CON, SYS, SYSR, N, out):
    """:func:`pair_kernel` by the general path alone: every system built in the workspaces."""
    _clear(out)
    for tier in range(2):
        Wt, It = (W, I) if tier == 0 else (Wdd, Idd)
        FA, FB, C, DS, DT, errs, code = _systems_of(Wt, It, CON, SYS, SYSR, N, ka, sa, rows_a, kb, sb, rows_b)
        if code <= 0:
            out[FAILED] = NOT_HANDLED if code == 0 else OVERFLOW
            return
        out[FAILED] = PARTIAL if code == sy.PARTIAL else 0.0
        out[TIER] = tier
        best, s_best = scan_systems(SYS, N, C, DS, DT, errs, t_end, out, np.bool_(True))
        if out[CERTIFIED] > 0.0 or tier == 1:
            if best >= 0:
                _contact(Wt, It, SYS, SYSR, best, s_best, out[TIME] if out[CERTIFIED] > 0.0 else out[LO],
                         ka, sa, FA, kb, sb, FB, out)
            return


MAX_RUNS = 64


@jit
def merge_runs(R, n, t_end, out):
    """Merge runs (rows enter_lo, enter_hi, exit_lo, exit_hi, proven) of several systems into the pair's
    intervals of contact: rows (t_in, t_out, in_lo, in_hi, out_lo, out_hi, proven) in ``out``; returns (count,
    certified).  Runs that overlap, or lie within TIME_TOL of each other, are one interval; the interval is
    certified when both its ends' brackets are within TIME_TOL (one that may last to t_end: proven in contact
    up to it) and some run in it is proven."""
    order = np.argsort(R[:n, 0])
    m = 0
    certified = True
    k = 0
    while k < n:
        r = order[k]
        lo_in, lo_out = R[r, 0], R[r, 3]
        hi_in = R[r, 1] if R[r, 4] > 0.0 else 2.0
        hi_out = R[r, 2] if R[r, 4] > 0.0 else -1.0
        proven = R[r, 4] > 0.0
        k += 1
        while k < n and R[order[k], 0] <= lo_out + TIME_TOL:
            q = order[k]
            lo_out = max(lo_out, R[q, 3])
            if R[q, 4] > 0.0:
                hi_in = min(hi_in, R[q, 1])
                hi_out = max(hi_out, R[q, 2])
                proven = True
            k += 1
        if m < out.shape[0]:
            out[m, 2], out[m, 5] = lo_in, lo_out
            out[m, 3] = hi_in if proven else lo_out
            out[m, 4] = hi_out if proven else lo_in
            out[m, 6] = 1.0 if proven else 0.0
            out[m, 0] = 0.5 * (out[m, 2] + out[m, 3])
            out[m, 1] = 0.5 * (out[m, 4] + out[m, 5]) if out[m, 5] < t_end else t_end
            if lo_in == 0.0:
                out[m, 0] = 0.0
            # an interval that may last to t_end is certified only when it is proven to last that long
            if not proven or out[m, 3] - out[m, 2] > TIME_TOL or out[m, 5] - out[m, 4] > TIME_TOL:
                certified = False
            m += 1
        else:
            certified = False
    return m, certified


@jit
def pair_runs(ka, sa, rows_a, kb, sb, rows_b, t_end, W, I, Wdd, Idd, CON, SYS, SYSR, N, out):
    """Every interval of [0, t_end] in which the pair is in contact (touching or overlapping), as rows of
    :func:`merge_runs` in ``out`` (MAX_RUNS, 7).  Returns (count, certified, status at t = 0, code): code as
    :func:`mjccd.geoms.systems.build_pair` (-1: overflow).  Tries doubles, then double-double when the
    intervals are not certified."""
    count, certified, status0, code = 0, False, 1, 0
    for tier in range(2):
        Wt, It = (W, I) if tier == 0 else (Wdd, Idd)
        FA, FB, C, DS, DT, errs, code = _systems_of(Wt, It, CON, SYS, SYSR, N, ka, sa, rows_a, kb, sb, rows_b)
        if code <= 0:
            return 0, False, 1, code
        R = np.empty((N[1] * 8 + 8, sc.RUN_FIELDS))
        n = 0
        part = np.empty((MAX_RUNS, sc.RUN_FIELDS))
        status0 = status_of_systems(SYS, N, C, DS, DT, errs)
        for k in range(N[1]):
            s0, cnt = SYS[k, 0], SYS[k, 1]
            if SYS[k, 3] == 0:
                m = sc.all_runs(np.ascontiguousarray(C[s0:s0 + cnt, 0, :]), DT[s0:s0 + cnt], errs[s0:s0 + cnt],
                                t_end, part)
            else:
                m = sc.ball_runs(C[s0:s0 + cnt], DS[s0:s0 + cnt], DT[s0:s0 + cnt], errs[s0:s0 + cnt], t_end, part)
            for q in range(m):
                if n < R.shape[0]:
                    for f in range(sc.RUN_FIELDS):
                        R[n, f] = part[q, f]
                    n += 1
        count, certified = merge_runs(R, n, t_end, out)
        if certified:
            break
    return count, certified, status0, code
