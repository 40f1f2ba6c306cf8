"""Exact continuous collision detection of two moving ellipsoids (thesis ch. 5).

With ``A(t)`` and ``B(t)`` the polynomial quadric matrices of the two moving
ellipsoids (see :mod:`mjccd.motion`), the CCD function is

    F(u, t) = det((1 - u) A(t) + u B(t)),   (u, t) in [0, 1] x [0, 1],

built exactly in bivariate Bernstein form (degree 4 in u).  F < 0 on the
edges u = 0 and u = 1, and at each time t the pair is separate exactly when
``State(t) = max_u F(u, t)`` is positive (touching when it is zero).  Hence

* first contact: starting from a separate time t with ``u* = argmax F(., t)``,
  F(u*, s) > 0 certifies separation for every s up to the first root of the
  univariate polynomial F(u*, .) — a *Bézier shoot*.  Shooting again from
  that root converges quadratically to the contact time (thesis §5.3.3).
* end of an overlap: the zero set of F is searched in time order by
  subdividing boxes of (u, t); a box is discarded when its Bernstein
  coefficients of F are all negative, or when F is negative on one face and
  F_t has the sign that keeps it negative across the box.  The first box that
  cannot be discarded brackets the exit, which is then refined by bisection
  on State.

``first_contact`` and ``collision_intervals`` are the public entry points;
everything below them runs in numba on plain arrays.
"""
import heapq
from dataclasses import dataclass

import numba
import numpy as np
from numba.typed import List

from mjccd import _validate
from mjccd import bernstein as bz
from mjccd.motion import Motion, quadric_at
from mjccd.quadric import (STATUS_NAMES, Ellipsoid, det4, quartic_max, status_from_max,
                           touching_point)

_jit = numba.njit(cache=True, nogil=True)

SHOOT_TOL = 1e-15        # relative width at which a Bézier-clipping root is accepted
EXIT_BOX_TOL = 1e-7      # time width at which the overlap search hands over to bisection
MAX_SHOOTS = 4000
MAX_BOXES = 200000
# relative rounding noise of F's coefficients (construction and evaluation)
NOISE = 256 * 2.220446049250313e-16


# ---------------------------------------------------------------- building F


@_jit
def _elevated(c, n):
    """``c`` elevated to degree n, in scaled Bernstein form (times C(n, j))."""
    e = bz.elevate(c.copy(), n + 1 - c.shape[0])
    return e * bz.binomial_row(n)


@_jit
def _pencil_entry(a, b, n):
    """Scaled bivariate form of (1 - u) a(t) + u b(t), degree (1, n)."""
    out = np.empty((2, n + 1))
    out[0] = _elevated(a, n)
    out[1] = _elevated(b, n)
    return out


@_jit
def _mul(x, y):
    return bz.scaled_multiply(x, y)


@_jit
def build_F(PA, UA, sA, PB, UB, sB):
    """Bernstein coefficients (5, n+1) of F(u, t) = det((1 - u) A(t) + u B(t)).

    Uses ``det [[P, U], [U^T, s]] = s det P - U^T adj(P) U`` on the pencil,
    which keeps every intermediate at its true degree.
    """
    p = max(PA.shape[2], PB.shape[2]) - 1
    q = max(UA.shape[1], UB.shape[1]) - 1
    r = max(sA.shape[0], sB.shape[0]) - 1
    P00 = _pencil_entry(PA[0, 0], PB[0, 0], p)
    P01 = _pencil_entry(PA[0, 1], PB[0, 1], p)
    P02 = _pencil_entry(PA[0, 2], PB[0, 2], p)
    P11 = _pencil_entry(PA[1, 1], PB[1, 1], p)
    P12 = _pencil_entry(PA[1, 2], PB[1, 2], p)
    P22 = _pencil_entry(PA[2, 2], PB[2, 2], p)
    U0 = _pencil_entry(UA[0], UB[0], q)
    U1 = _pencil_entry(UA[1], UB[1], q)
    U2 = _pencil_entry(UA[2], UB[2], q)
    s = _pencil_entry(sA, sB, r)
    C00 = _mul(P11, P22) - _mul(P12, P12)
    C11 = _mul(P00, P22) - _mul(P02, P02)
    C22 = _mul(P00, P11) - _mul(P01, P01)
    C01 = _mul(P02, P12) - _mul(P01, P22)
    C02 = _mul(P01, P12) - _mul(P02, P11)
    C12 = _mul(P01, P02) - _mul(P00, P12)
    detP = _mul(P00, C00) + _mul(P01, C01) + _mul(P02, C02)
    V0 = _mul(C00, U0) + _mul(C01, U1) + _mul(C02, U2)
    V1 = _mul(C01, U0) + _mul(C11, U1) + _mul(C12, U2)
    V2 = _mul(C02, U0) + _mul(C12, U1) + _mul(C22, U2)
    F1 = bz.from_scaled(_mul(s, detP))
    F2 = bz.from_scaled(_mul(U0, V0) + _mul(U1, V1) + _mul(U2, V2))
    n = max(F1.shape[1], F2.shape[1]) - 1
    if F1.shape[1] <= n:
        F1 = bz.bivariate_elevate_t(F1, n + 1 - F1.shape[1])
    if F2.shape[1] <= n:
        F2 = bz.bivariate_elevate_t(F2, n + 1 - F2.shape[1])
    return F1 - F2


# ---------------------------------------------------------------- state


@_jit
def state(F, t):
    """max_u F(u, t) and its argmax."""
    return quartic_max(bz.bivariate_at_t(F, t))


@_jit
def status_at(F, Fabs, noise, t):
    """(status code, max_u F, argmax) at time t.

    The touching band is the rounding noise of F at (argmax, t): ``noise``
    (relative, from construction and evaluation) times the same Bernstein
    sum taken over |F| (``Fabs`` holds |F| coefficient-wise).
    """
    gmax, u = quartic_max(bz.bivariate_at_t(F, t))
    m = Fabs.shape[0] - 1
    binom = bz.binomial_row(m)
    scale = 0.0
    for i in range(m + 1):
        scale += binom[i] * u ** i * (1.0 - u) ** (m - i) * bz.evaluate(Fabs[i], t)
    return status_from_max(gmax, noise * scale), gmax, u


# ---------------------------------------------------------------- first contact


@_jit
def _polish_contact(F, t, u, t_max):
    """One Newton step of State(t) = 0 from just before the contact (State ~ F(u*, t))."""
    h = bz.bivariate_at_u(F, u)
    value = bz.evaluate(h, t)
    slope = bz.evaluate(bz.derivative(h), t)
    if slope < 0.0 and value > 0.0:
        dt = -value / slope
        if dt < 1e-7:
            return min(t + dt, t_max)
    return t


@_jit
def shoot_first_contact(F, Fabs, noise, t_start, t_max):
    """Earliest contact in [t_start, t_max] by recursive Bézier shoots.

    Requires the pair to be separate at t_start.  Returns (time, u) of the
    contact (State ~ 0 there), or (-1, 0) when separation is certified over
    the whole interval.
    """
    t = t_start
    _, _, u = status_at(F, Fabs, noise, t)
    for _ in range(MAX_SHOOTS):
        if t >= t_max:
            break
        h = bz.bivariate_at_u(F, u)
        if t > 0.0 or t_max < 1.0:
            h = bz.restrict(h, t, t_max)
        r = -1.0 if h.min() > 0.0 else bz.first_root(h, SHOOT_TOL)
        if r < 0.0:
            break
        t_new = t + r * (t_max - t)
        code, _, u_new = status_at(F, Fabs, noise, t_new)
        if code != 1 or t_new <= t:
            return _polish_contact(F, t_new, u_new, t_max), u_new
        t, u = t_new, u_new
    # certified separate up to t_max; a touch exactly at t_max still counts
    code, _, u_end = status_at(F, Fabs, noise, t_max)
    if code != 1:
        return t_max, u_end
    return -1.0, 0.0


# ---------------------------------------------------------------- end of an overlap


@_jit
def _split_t(C):
    left = np.empty_like(C)
    right = np.empty_like(C)
    for i in range(C.shape[0]):
        a, b = bz.subdivide(C[i].copy(), 0.5)
        left[i] = a
        right[i] = b
    return left, right


@_jit
def _split_u(C):
    low = np.empty_like(C)
    high = np.empty_like(C)
    for j in range(C.shape[1]):
        a, b = bz.subdivide(C[:, j].copy(), 0.5)
        low[:, j] = a
        high[:, j] = b
    return low, high


@_jit
def _certified_negative(C):
    """True when F < 0 on the box: all coefficients negative, or monotone in t from a negative face."""
    if C.max() < 0.0:
        return True
    m = C.shape[0]
    n = C.shape[1] - 1
    decreasing = True
    increasing = True
    for i in range(m):
        for j in range(n):
            d = C[i, j + 1] - C[i, j]
            if d > 0.0:
                decreasing = False
            if d < 0.0:
                increasing = False
    if decreasing and C[:, 0].max() < 0.0:
        return True
    if increasing and C[:, n].max() < 0.0:
        return True
    return False


@_jit
def _bisect_sign(F, lo, hi, rising):
    """Zero of State between lo and hi (State < 0 at lo when ``rising``, > 0 otherwise)."""
    for _ in range(100):
        mid = 0.5 * (lo + hi)
        if mid <= lo or mid >= hi:
            break
        gmax, _ = state(F, mid)
        if (gmax >= 0.0) == rising:
            hi = mid
        else:
            lo = mid
    return 0.5 * (lo + hi)


@_jit
def search_exit(F, Fabs, noise, t_start, t_end):
    """First time in [t_start, t_end] at which the pair is separate again, or 2.0.

    Requires the pair to overlap at t_start.  Boxes of (u, t) are taken in
    order of their start time, so everything before the popped box is
    certified negative.
    """
    Cr = bz.bivariate_restrict_t(F, t_start, t_end)
    boxes = List()
    boxes.append(Cr)
    ends = List()
    ends.append(t_end)
    heap = [(t_start, 0)]
    count = 0
    while len(heap) > 0:
        t0, idx = heapq.heappop(heap)
        C = boxes[idx]
        t1 = ends[idx]
        count += 1
        if _certified_negative(C):
            continue
        if count > MAX_BOXES:
            return t0
        width = t1 - t0
        if width <= EXIT_BOX_TOL:
            code, gmax, _ = status_at(F, Fabs, noise, t1)
            if gmax >= 0.0:
                return _bisect_sign(F, t0, t1, True)
            continue
        span_t = 0.0
        span_u = 0.0
        for i in range(C.shape[0]):
            span_t = max(span_t, C[i].max() - C[i].min())
        for j in range(C.shape[1]):
            span_u = max(span_u, C[:, j].max() - C[:, j].min())
        if span_t >= span_u:
            a, b = _split_t(C)
            tm = 0.5 * (t0 + t1)
            boxes.append(a)
            ends.append(tm)
            heapq.heappush(heap, (t0, len(boxes) - 1))
            boxes.append(b)
            ends.append(t1)
            heapq.heappush(heap, (tm, len(boxes) - 1))
        else:
            a, b = _split_u(C)
            boxes.append(a)
            ends.append(t1)
            heapq.heappush(heap, (t0, len(boxes) - 1))
            boxes.append(b)
            ends.append(t1)
            heapq.heappush(heap, (t0, len(boxes) - 1))
    return 2.0


@_jit
def _step_off(F, Fabs, noise, t, t_end):
    """Status just after a contact instant t: the first probe t + 1e-13 * 2^k that is decided.

    Returns (probe, status code); code 0 when still undecided at 1e-6 or at t_end.
    """
    eps = 1e-13
    while eps < 1e-6:
        tp = t + eps
        if tp > t_end:
            break
        code, _, _ = status_at(F, Fabs, noise, tp)
        if code != 0:
            return tp, code
        eps *= 2.0
    return min(t + eps, t_end), 0


@_jit
def solve_intervals(F, Fabs, noise, t_max, first_only):
    """All maximal non-separation intervals in [0, t_max] (just the first with ``first_only``).

    Returns (status_at_start, intervals (k, 2), u at the first contact).
    """
    out = np.empty((64, 2))
    k = 0
    status0, _, u_first = status_at(F, Fabs, noise, 0.0)
    if status0 == 1:
        t_in, u_first = shoot_first_contact(F, Fabs, noise, 0.0, t_max)
        if t_in < 0.0:
            return status0, out[:0], u_first
    else:
        t_in = 0.0
    while True:
        if first_only:
            out[0, 0] = t_in
            out[0, 1] = t_in
            k = 1
            break
        # leave the contact instant: is it an overlap, or only a touch?
        probe, code = _step_off(F, Fabs, noise, t_in, t_max)
        if code == -1:
            t_out = min(search_exit(F, Fabs, noise, probe, t_max), t_max)
        elif code == 1:
            gmax, _ = state(F, t_in)
            t_out = t_in if gmax >= 0.0 else _bisect_sign(F, t_in, probe, True)
        else:
            t_out = probe
        if k == out.shape[0]:
            bigger = np.empty((2 * k, 2))
            bigger[:k] = out
            out = bigger
        out[k, 0] = t_in
        out[k, 1] = t_out
        k += 1
        if t_out >= t_max:
            break
        t, code = _step_off(F, Fabs, noise, t_out, t_max)
        if t >= t_max:
            break
        if code == -1:  # overlapping again right away: same interval continues
            t_in = out[k - 1, 0]
            k -= 1
            t_out2 = min(search_exit(F, Fabs, noise, t, t_max), t_max)
            out[k, 1] = t_out2
            k += 1
            if t_out2 >= t_max:
                break
            continue
        t_in, _ = shoot_first_contact(F, Fabs, noise, t, t_max)
        if t_in < 0.0:
            break
    return status0, out[:k], u_first


# ---------------------------------------------------------------- Python layer


@dataclass(frozen=True)
class Contact:
    """First contact of two moving ellipsoids.

    ``time`` is normalised to [0, 1]; ``point`` (world) and ``normal`` (unit,
    outward from the first ellipsoid) describe the touch; they are None when
    the pair already touches or overlaps at the start (``time == 0``).
    """

    time: float
    point: object
    normal: object
    status_at_start: str


def _centre(quadric, t):
    """Centre of the moving ellipsoid at time t: the point where the gradient of X^T A X vanishes."""
    A = quadric_at(*quadric, t)
    return -np.linalg.solve(A[:3, :3], A[:3, 3])


def _reframe(quadric, origin, length):
    """Quadric polynomials in the frame x_old = length * x_new + origin, scaled to unit size.

    A rigid change of frame, a uniform scaling and a positive factor on each
    quadric change no answer, but they balance the pencil: both matrices
    get entries of order one, which keeps the rounding of F relative to its
    values rather than to the far-away origin or the units.
    """
    P, U, s = quadric
    p = P.shape[2] - 1
    q = max(p, U.shape[1] - 1)
    r = max(q, s.shape[0] - 1)

    def up(c, n):
        return bz.elevate(np.ascontiguousarray(c), n + 1 - c.shape[-1])

    Pq = np.array([[up(P[i, j], q) for j in range(3)] for i in range(3)])
    Uq = np.array([up(U[i], q) for i in range(3)])
    Po = np.einsum("ijk,j->ik", Pq, origin)
    Pn = np.ascontiguousarray(P * length ** 2)
    Un = (Po + Uq) * length
    sn = up(s, r) + up(np.einsum("i,ik->k", origin, Po) + 2.0 * np.einsum("i,ik->k", origin, Uq), r)
    # balance: |det A(0)| = 1, so that F(0, t) and F(1, t) are of comparable size
    scale = abs(det4(quadric_at(Pn, Un, sn, 0.0))) ** 0.25
    if not np.isfinite(scale) or scale == 0.0:
        scale = max(np.abs(Pn).max(), np.abs(Un).max(), np.abs(sn).max())
    return Pn / scale, Un / scale, sn / scale


class _Pair:
    """The CCD function of one pair, built once and queried."""

    def __init__(self, a, motion_a, b, motion_b):
        for name, e in (("a", a), ("b", b)):
            if not isinstance(e, Ellipsoid):
                raise ValueError(f"{name}: expected an mjccd.Ellipsoid, got {type(e).__name__}")
        for name, m in (("motion_a", motion_a), ("motion_b", motion_b)):
            if not isinstance(m, Motion):
                raise ValueError(f"{name}: expected an mjccd motion, got {type(m).__name__}")
        qa = motion_a.quadric(a.radii)
        qb = motion_b.quadric(b.radii)
        self.origin = 0.25 * sum(_centre(q, t) for q in (qa, qb) for t in (0.0, 1.0))
        self.length = float(max(a.radii.max(), b.radii.max()))
        self.qa = _reframe(qa, self.origin, self.length)
        self.qb = _reframe(qb, self.origin, self.length)
        self.F = build_F(*self.qa, *self.qb)
        self.Fabs = np.abs(self.F)

    def solve(self, t_max, first_only):
        return solve_intervals(self.F, self.Fabs, NOISE, t_max, first_only)

    def touch(self, t, u):
        A = quadric_at(*self.qa, t)
        B = quadric_at(*self.qb, t)
        point, normal = touching_point(A, B, u)
        return self.origin + self.length * point, normal


def first_contact(a, motion_a, b, motion_b, *, t_max=1.0):
    """First time in [0, t_max] at which two moving ellipsoids touch, as a :class:`Contact`.

    Returns None when they stay separate over [0, t_max].  ``t_max`` is the
    running bound when many pairs are solved for the earliest contact.
    """
    t_max = _validate.time_bound(t_max, "t_max")
    pair = _Pair(a, motion_a, b, motion_b)
    status0, intervals, u = pair.solve(t_max, True)
    if status0 != 1:
        return Contact(0.0, None, None, STATUS_NAMES[int(status0)])
    if len(intervals) == 0:
        return None
    t = float(intervals[0, 0])
    point, normal = pair.touch(t, u)
    return Contact(t, point, normal, "separate")


def collision_intervals(a, motion_a, b, motion_b):
    """Maximal time intervals [t_in, t_out] within [0, 1] where the two are not separate."""
    pair = _Pair(a, motion_a, b, motion_b)
    _, intervals, _ = pair.solve(1.0, False)
    return [(float(x), float(y)) for x, y in intervals]


def solve_pair(a, motion_a, b, motion_b):
    """Status at start, first contact (time, point, normal) and all intervals in one pass."""
    pair = _Pair(a, motion_a, b, motion_b)
    status0, intervals, u = pair.solve(1.0, False)
    contact = None
    if status0 == 1 and len(intervals):
        t = float(intervals[0, 0])
        point, normal = pair.touch(t, u)
        contact = Contact(t, point, normal, "separate")
    elif status0 != 1:
        contact = Contact(0.0, None, None, STATUS_NAMES[int(status0)])
    return STATUS_NAMES[int(status0)], contact, [(float(x), float(y)) for x, y in intervals]
