"""Ellipsoids as quadrics, and the static tests between two of them.

An ellipsoid with radii (a, b, c) is ``X^T A X <= 0`` with
``A = diag(1/a^2, 1/b^2, 1/c^2, -1)`` in its own frame and ``X = (x, y, z, 1)``.
Placed by a pose ``M`` (frame -> world) it becomes ``M^-T A M^-1``.

The static status of two ellipsoids follows from the characteristic quartic
``f(lambda) = det(lambda A - B)`` (two distinct negative roots: separate; a
negative double root: touching; none: overlapping).  With ``lambda = (u-1)/u``
the negative half-line becomes u in (0, 1) and, up to a positive factor,
``g(u) = det((1 - u) A + u B)``.  Since ``g(0) = det A < 0`` and
``g(1) = det B < 0``, the pair is separate exactly when ``max_u g(u) > 0``.
That maximum is what every decision below is based on, including the moving
case in :mod:`mjccd.ccd`.

The static status is certified: the numba kernels (:func:`static_status_pose`,
:func:`static_status_batch`, :func:`static_status_matrices`) carry a rigorous
bound of every rounding error and answer 1 (separate) or -1 (overlapping) only
where the sign of ``max g`` is proven; otherwise they answer ``UNDECIDED``
(2): touching, or too close to touching for double precision.  The Python
functions (:func:`static_status`, :func:`static_status_many`,
:func:`static_status_code`) settle those pairs in rational arithmetic
(:mod:`mjccd.exact`), so they are exact for the doubles given and always agree.
"""
from dataclasses import dataclass

import numba
import numpy as np

from mjccd import _validate, exact
from mjccd.errors import InputError

# compiled on first use and cached; no cfunc wrapper (no kernel is passed around as a first-class function);
# forceinline=False: numba hands a caller's forceinline down to the callees it compiles
_jit = numba.njit(cache=True, nogil=True, no_cfunc_wrapper=True, forceinline=False)
# hot-path helpers: compiled once, then inlined by LLVM into each caller (no call, no reference counting of
# array arguments); inline="always" copied their numba IR into every caller instead, which multiplied
# compile time (docs/benchmarks.md, "First use")
_inline = numba.njit(cache=True, nogil=True, no_cfunc_wrapper=True, forceinline=True)

SEPARATE = 1
TOUCHING = 0
OVERLAPPING = -1
STATUS_NAMES = {SEPARATE: "separate", TOUCHING: "touching", OVERLAPPING: "overlapping"}

# The tolerant tests (status_from_max: the moving case in mjccd.ccd, contact_point,
# separating_plane) count |max g| below this many rounding units as touching.  The
# static status itself is certified instead (static_status_pose: code 2 = UNDECIDED).
TOUCH_ULPS = 256.0
# width in u at which the argmax of the quartic is accepted; the maximum itself
# is then exact to second order (g' vanishes there)
ARGMAX_TOL = 1e-14


# ---------------------------------------------------------------- kernels


@_jit
def quat_to_matrix(q):
    """Rotation matrix of the quaternion [w, x, y, z] (normalised here)."""
    w, x, y, z = q[0], q[1], q[2], q[3]
    n = w * w + x * x + y * y + z * z
    R = np.empty((3, 3))
    R[0, 0] = (w * w + x * x - y * y - z * z) / n
    R[0, 1] = 2.0 * (x * y - w * z) / n
    R[0, 2] = 2.0 * (x * z + w * y) / n
    R[1, 0] = 2.0 * (x * y + w * z) / n
    R[1, 1] = (w * w - x * x + y * y - z * z) / n
    R[1, 2] = 2.0 * (y * z - w * x) / n
    R[2, 0] = 2.0 * (x * z - w * y) / n
    R[2, 1] = 2.0 * (y * z + w * x) / n
    R[2, 2] = (w * w - x * x - y * y + z * z) / n
    return R


def matrix_to_quat(R):
    """Unit quaternions [w, x, y, z] (..., 4), w >= 0, of rotation matrices (..., 3, 3).

    The inverse of :func:`quat_to_matrix`, by Shepperd's method: branching on
    the largest of ``1 + trace`` and ``1 + 2 R_ii - trace`` divides by the
    largest quaternion component, so no rotation loses precision (the trace
    alone fails near half turns).
    """
    R = np.asarray(R, dtype=float)
    m00, m11, m22 = R[..., 0, 0], R[..., 1, 1], R[..., 2, 2]
    cand = np.stack([1 + m00 + m11 + m22, 1 + m00 - m11 - m22, 1 - m00 + m11 - m22, 1 - m00 - m11 + m22], -1)
    best = cand.argmax(axis=-1)
    s = 2.0 * np.sqrt(np.maximum(np.take_along_axis(cand, best[..., None], -1)[..., 0], 1e-300))
    d21, d02, d10 = R[..., 2, 1] - R[..., 1, 2], R[..., 0, 2] - R[..., 2, 0], R[..., 1, 0] - R[..., 0, 1]
    s01, s02, s12 = R[..., 0, 1] + R[..., 1, 0], R[..., 0, 2] + R[..., 2, 0], R[..., 1, 2] + R[..., 2, 1]
    branch = [best == 0, best == 1, best == 2]
    q = np.stack([np.select(branch, [s / 4, d21 / s, d02 / s], d10 / s),
                  np.select(branch, [d21 / s, s / 4, s01 / s], s02 / s),
                  np.select(branch, [d02 / s, s01 / s, s / 4], s12 / s),
                  np.select(branch, [d10 / s, s02 / s, s12 / s], s / 4)], -1)
    q *= np.where(q[..., :1] < 0, -1.0, 1.0)
    return q / np.linalg.norm(q, axis=-1, keepdims=True)


@_jit
def quadric_matrix(radii, position, quaternion):
    """World 4x4 matrix ``M^-T diag(1/a^2, 1/b^2, 1/c^2, -1) M^-1`` of a posed ellipsoid."""
    R = quat_to_matrix(quaternion)
    Q = np.zeros((3, 3))
    for i in range(3):
        for j in range(3):
            acc = 0.0
            for k in range(3):
                acc += R[i, k] * R[j, k] / (radii[k] * radii[k])
            Q[i, j] = acc
    out = np.empty((4, 4))
    Qp = Q @ position
    for i in range(3):  # element by element (see bernstein's _jit)
        for j in range(3):
            out[i, j] = Q[i, j]
        out[i, 3] = out[3, i] = -Qp[i]
    out[3, 3] = position @ Qp - 1.0
    return out


@_jit
def _det3(m00, m01, m02, m10, m11, m12, m20, m21, m22):
    return (m00 * (m11 * m22 - m12 * m21) - m01 * (m10 * m22 - m12 * m20)
            + m02 * (m10 * m21 - m11 * m20))


# Laplace expansion of a 4x4 determinant along rows 0-1: term k is sign * s_k * c_k with
# s_k = m[0, i] m[1, j] - m[1, i] m[0, j] and its complementary minor
# c_k = m[2, p] m[3, q] - m[3, p] m[2, q]; rows (i, j, p, q, sign), in the order summed
_LAPLACE = ((0, 1, 2, 3, 1.0), (0, 2, 1, 3, -1.0), (0, 3, 1, 2, 1.0),
            (1, 2, 0, 3, 1.0), (1, 3, 0, 2, -1.0), (2, 3, 0, 1, 1.0))


@_inline
def _det4_rows(r0, r1, r2, r3):
    """det of the 4x4 with rows r0..r3 (4-tuples) by 2x2 minors: s0 c5 - s1 c4 + s2 c3 + s3 c2 - s4 c1 + s5 c0.

    Summed left to right from -0.0 (the exact identity of +), so each rounding is that of the written sum.
    """
    det = -0.0
    for i, j, p, q, sign in _LAPLACE:
        s = r0[i] * r1[j] - r1[i] * r0[j]
        c = r2[p] * r3[q] - r3[p] * r2[q]
        det += sign * (s * c)
    return det


@_jit
def det4(M):
    """Determinant of a 4x4 matrix by 2x2 minors."""
    return _det4_rows((M[0, 0], M[0, 1], M[0, 2], M[0, 3]), (M[1, 0], M[1, 1], M[1, 2], M[1, 3]),
                      (M[2, 0], M[2, 1], M[2, 2], M[2, 3]), (M[3, 0], M[3, 1], M[3, 2], M[3, 3]))


@_jit
def pencil_quartic(A, B):
    """Bernstein coefficients in u of ``g(u) = det((1 - u) A + u B)`` and its noise scale.

    The coefficients are recovered exactly from five values of the
    determinant (a quartic is fixed by five samples; the Bernstein
    coefficients follow from the power ones by a fixed linear map).  The
    noise scale bounds the rounding error of one determinant evaluation.
    """
    us = np.array([0.0, 0.25, 0.5, 0.75, 1.0])
    vals = np.empty(5)
    M = np.empty((4, 4))
    for k in range(5):
        u = us[k]
        for i in range(4):
            for j in range(4):
                M[i, j] = (1.0 - u) * A[i, j] + u * B[i, j]
        vals[k] = det4(M)
    # Values at the nodes 0, 1/4, 1/2, 3/4, 1 -> Bernstein coefficients.
    g = np.empty(5)
    g[0] = vals[0]
    g[4] = vals[4]
    g[1] = (-13.0 * vals[0] + 48.0 * vals[1] - 36.0 * vals[2] + 16.0 * vals[3] - 3.0 * vals[4]) / 12.0
    g[3] = (-3.0 * vals[0] + 16.0 * vals[1] - 36.0 * vals[2] + 48.0 * vals[3] - 13.0 * vals[4]) / 12.0
    g[2] = (13.0 * vals[0] - 64.0 * vals[1] + 120.0 * vals[2] - 64.0 * vals[3] + 13.0 * vals[4]) / 18.0
    scale = 1.0
    for i in range(4):
        ra = 0.0
        rb = 0.0
        for j in range(4):
            ra += A[i, j] * A[i, j]
            rb += B[i, j] * B[i, j]
        scale *= np.sqrt(max(ra, rb))
    return g, scale * 2.3e-16 * 64.0


@_jit
def _quartic_value(g, u):
    v = 1.0 - u
    return (g[0] * v ** 4 + 4.0 * g[1] * u * v ** 3 + 6.0 * g[2] * u * u * v * v
            + 4.0 * g[3] * u ** 3 * v + g[4] * u ** 4)


@_jit
def _cubic(d0, d1, d2, d3, u):
    v = 1.0 - u
    return d0 * v * v * v + 3.0 * d1 * u * v * v + 3.0 * d2 * u * u * v + d3 * u * u * u


@_jit
def _quartic5(g0, g1, g2, g3, g4, u):
    v = 1.0 - u
    uu = u * u
    vv = v * v
    return g0 * vv * vv + 4.0 * g1 * u * vv * v + 6.0 * g2 * uu * vv + 4.0 * g3 * uu * u * v + g4 * uu * uu


@_jit
def _max_on_piece(g0, g1, g2, g3, g4, lo, hi):
    """Local maximum of the quartic on [lo, hi] where g' is monotone, or (-inf, lo).

    The root of g' is found by Newton steps kept inside a shrinking bracket
    (a bisection step whenever Newton would leave it).
    """
    d0, d1, d2, d3 = g1 - g0, g2 - g1, g3 - g2, g4 - g3  # g'/4 in Bernstein form
    flo = _cubic(d0, d1, d2, d3, lo)
    fhi = _cubic(d0, d1, d2, d3, hi)
    if not (flo > 0.0 and fhi < 0.0):  # g' must go + to - for a maximum inside
        return -np.inf, lo
    e0, e1, e2 = 3.0 * (d1 - d0), 3.0 * (d2 - d1), 3.0 * (d3 - d2)  # (g'/4)' in Bernstein form
    u = lo - flo * (hi - lo) / (fhi - flo)
    for _ in range(100):
        f = _cubic(d0, d1, d2, d3, u)
        if f == 0.0:
            break
        if f > 0.0:
            lo = u
        else:
            hi = u
        if hi - lo <= ARGMAX_TOL:
            break
        v = 1.0 - u
        df = e0 * v * v + 2.0 * e1 * u * v + e2 * u * u
        nxt = u - f / df if df < 0.0 else 0.5 * (lo + hi)
        if abs(nxt - u) <= ARGMAX_TOL:  # Newton has converged
            break
        u = nxt if lo < nxt < hi else 0.5 * (lo + hi)
    return _quartic5(g0, g1, g2, g3, g4, u), u


@_jit
def quartic_max5(g0, g1, g2, g3, g4):
    """Maximum of a Bernstein quartic over u in [0, 1] and where it is attained (no allocation).

    The critical points are the roots of the cubic g'; the roots of g''
    (a quadratic, solved in closed form) split [0, 1] into pieces on which
    g' is monotone, and each sign change there is located by bisection.
    """
    best, best_u = (g0, 0.0) if g0 >= g4 else (g4, 1.0)
    if max(g1, g2, g3) < best:  # convex hull below the larger end value
        return best, best_u
    e0 = (g2 - g1) - (g1 - g0)
    e1 = (g3 - g2) - (g2 - g1)
    e2 = (g4 - g3) - (g3 - g2)
    a = e0
    b = 2.0 * (e1 - e0)
    c = e0 - 2.0 * e1 + e2
    r1 = 2.0
    r2 = 2.0
    if c == 0.0:
        if b != 0.0:
            r1 = -a / b
    else:
        disc = b * b - 4.0 * a * c
        if disc > 0.0:
            sq = np.sqrt(disc)
            qq = -0.5 * (b + sq if b >= 0.0 else b - sq)
            r1 = qq / c
            r2 = a / qq if qq != 0.0 else 2.0
    if r1 > r2:
        r1, r2 = r2, r1
    lo = 0.0
    for cut in (r1, r2, 1.0):
        if cut <= lo or cut > 1.0:
            continue
        val, u = _max_on_piece(g0, g1, g2, g3, g4, lo, cut)
        if val > best:
            best, best_u = val, u
        lo = cut
    return best, best_u


@_jit
def quartic_max(g):
    """:func:`quartic_max5` for an array of five Bernstein coefficients."""
    return quartic_max5(g[0], g[1], g[2], g[3], g[4])


@_jit
def status_from_max(gmax, noise):
    """Separate / touching / overlapping from max_u g(u) and its rounding noise."""
    if gmax > TOUCH_ULPS * noise:
        return 1
    if gmax < -TOUCH_ULPS * noise:
        return -1
    return 0


# ---------------------------------------------------------------- certified static status
#
# The static tests below return 1 (separate) or -1 (overlapping) only where
# that is proven for the exact quadrics of their inputs (the doubles given,
# taken as exact rationals), and UNDECIDED (2) otherwise: touching pairs, and
# pairs too close to touching for double precision.  Numba kernels cannot
# run rational arithmetic; the Python layer (static_status,
# static_status_many, static_status_code) resolves code 2 with the exact test
# of :mod:`mjccd.exact`, so no answer anywhere is a guess.
#
# Every value carries a bound on its error (running error analysis, Higham,
# "Accuracy and Stability of Numerical Algorithms", §3.3): e >= |x - exact|.
# Round to nearest gives |fl(a) - a| <= U |fl(a)| for each operation, plus at
# most 2^-1075 for a product that underflows; so, from the magnitudes of the
# terms actually combined,
#     x + y:  e = ex + ey + U |fl(x + y)|
#     x * y:  e = |x| ey + |y| ex + ex ey + U |fl(x y)| + _ETA.
# The bounds are computed in floating point from non-negative numbers, each
# operation losing at most a factor (1 - U); no chain here is 4000 operations
# deep, so a computed bound times _SLACK bounds the error.  An overflow makes
# a value or a bound infinite or NaN: every comparison then fails, UNDECIDED.

UNDECIDED = 2
_U = 2.0 ** -53  # unit roundoff of IEEE double
_ETA = 2.0 ** -500  # > the error of an underflowing product; normal, and so is its square (no slow subnormals)
_SLACK = 1.0 + 2.0 ** -40  # > (1 - U)^-4000: the rounding of the bounds themselves
# radii whose squares could under- or overflow, and quaternions far from unit norm, are left UNDECIDED
_RADIUS_MIN, _RADIUS_MAX = 2.0 ** -200, 2.0 ** 200
_QNORM_MIN, _QNORM_MAX = 2.0 ** -100, 2.0 ** 100
# the de Casteljau subdivision of the last resort goes this many halvings deep
SUBDIVIDE_DEPTH = 30
_ZERO16 = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0)


@_inline
def _emul(x, ex, y, ey):
    """x * y and a bound on its error, for x, y within ex, ey of exact values."""
    z = x * y
    return z, abs(x) * ey + abs(y) * ex + ex * ey + _U * abs(z) + _ETA


@_inline
def _eadd(x, ex, y, ey):
    """x + y and a bound on its error."""
    z = x + y
    return z, ex + ey + _U * abs(z)


@_inline
def _ediff(a, ea, b, eb, c, ec, d, ed):
    """a * b - c * d and a bound on its error."""
    p, ep = _emul(a, ea, b, eb)
    q, eq = _emul(c, ec, d, ed)
    return _eadd(p, ep, -q, eq)


@_inline
def _edot3(x, ex, y, ey):
    """x . y for 3-tuples and a bound on its error."""
    s, es = _emul(x[0], ex[0], y[0], ey[0])
    p, ep = _emul(x[1], ex[1], y[1], ey[1])
    s, es = _eadd(s, es, p, ep)
    p, ep = _emul(x[2], ex[2], y[2], ey[2])
    return _eadd(s, es, p, ep)


@_inline
def _eminor(m, e, top, i, j):
    """The 2x2 minor of rows ``top``, ``top + 1`` and columns i, j of :func:`_det4e`'s ``m``, and its bound."""
    a, b = 4 * top, 4 * top + 4
    return _ediff(m[a + i], e[a + i], m[b + j], e[b + j], m[b + i], e[b + i], m[a + j], e[a + j])


@_inline
def _eterms(m, e, k, h):
    """Laplace terms k + h of :data:`_LAPLACE`: ``sign_k s_k c_k + sign_h s_h c_h`` and its error bound."""
    i, j, p, q, sign = _LAPLACE[k]
    s, f = _eminor(m, e, 0, i, j)
    c, g = _eminor(m, e, 2, p, q)
    i, j, p, q, sign_h = _LAPLACE[h]
    s_h, f_h = _eminor(m, e, 0, i, j)
    c_h, g_h = _eminor(m, e, 2, p, q)
    return _ediff(sign * s, f, c, g, -sign_h * s_h, f_h, c_h, g_h)


@_jit
def _det4e(m, e):
    """det of the 4x4 ``m`` (16-tuple, row-major, entries within ``e``) by 2x2 minors, and its error bound.

    The terms of :func:`_det4_rows`, summed as (s0 c5 - s1 c4) + (s2 c3 - s4 c1) + (s3 c2 + s5 c0).
    """
    d, ed = _eterms(m, e, 0, 1)
    p, ep = _eterms(m, e, 2, 4)
    d, ed = _eadd(d, ed, p, ep)
    p, ep = _eterms(m, e, 3, 5)
    return _eadd(d, ed, p, ep)


@_inline
def _kdot3(k, x, ex, y, ey):
    """k (x . y) for an exact k, and its error bound."""
    s, es = _edot3(x, ex, y, ey)
    return _emul(k, 0.0, s, es)


@_inline
def _mix(u, v, a, ea, b, eb):
    """v a + u b (u, v >= 0 exact) and its error bound."""
    x, ex = _emul(v, 0.0, a, ea)
    y, ey = _emul(u, 0.0, b, eb)
    return _eadd(x, ex, y, ey)


@_jit
def _mix_row(u, v, A, eA, B, eB, i):
    """Row i of ``v A + u B`` (16-tuples within eA, eB): its values and their error bounds."""
    x0, f0 = _mix(u, v, A[4 * i], eA[4 * i], B[4 * i], eB[4 * i])
    x1, f1 = _mix(u, v, A[4 * i + 1], eA[4 * i + 1], B[4 * i + 1], eB[4 * i + 1])
    x2, f2 = _mix(u, v, A[4 * i + 2], eA[4 * i + 2], B[4 * i + 2], eB[4 * i + 2])
    x3, f3 = _mix(u, v, A[4 * i + 3], eA[4 * i + 3], B[4 * i + 3], eB[4 * i + 3])
    return (x0, x1, x2, x3), (f0, f1, f2, f3)


@_jit
def _pencil_det_e(u, v, A, eA, B, eB):
    """det(v A + u B) and its error bound: a positive multiple of g(u / (u + v))."""
    m0, e0 = _mix_row(u, v, A, eA, B, eB, 0)
    m1, e1 = _mix_row(u, v, A, eA, B, eB, 1)
    m2, e2 = _mix_row(u, v, A, eA, B, eB, 2)
    m3, e3 = _mix_row(u, v, A, eA, B, eB, 3)
    return _det4e(m0 + m1 + m2 + m3, e0 + e1 + e2 + e3)


@_jit
def _lin5(c, den, v, e):
    """(c . v) / den for five samples v within e, and its error bound (six roundings a term at most)."""
    s = (c[0] * v[0] + c[1] * v[1] + c[2] * v[2] + c[3] * v[3] + c[4] * v[4]) / den
    err = 0.0
    for k in range(5):
        err += abs(c[k]) * (e[k] + 7.0 * _U * abs(v[k]))
    return s, err / den + 8.0 * _ETA


@_jit
def _bernstein(v, e):
    """Bernstein coefficients of a quartic from its values v at u = 0, 1/4, 1/2, 3/4, 1 (within e),
    with error bounds (the map of :func:`pencil_quartic`)."""
    g1, E1 = _lin5((-13.0, 48.0, -36.0, 16.0, -3.0), 12.0, v, e)
    g2, E2 = _lin5((13.0, -64.0, 120.0, -64.0, 13.0), 18.0, v, e)
    g3, E3 = _lin5((-3.0, 16.0, -36.0, 48.0, -13.0), 12.0, v, e)
    return (v[0], g1, g2, g3, v[4]), (e[0], E1, E2, E3, e[4])


@_jit
def _half(a, ea, b, eb):
    """(a + b) / 2 and its error bound."""
    z = (a + b) * 0.5
    return z, (ea + eb) * 0.5 + _U * abs(z) + _ETA


@_jit
def _split(g, E):
    """de Casteljau halves of a Bernstein quartic within E of g: (left, its bounds, right, its bounds)."""
    l0, f0 = _half(g[0], E[0], g[1], E[1])
    l1, f1 = _half(g[1], E[1], g[2], E[2])
    l2, f2 = _half(g[2], E[2], g[3], E[3])
    l3, f3 = _half(g[3], E[3], g[4], E[4])
    m0, h0 = _half(l0, f0, l1, f1)
    m1, h1 = _half(l1, f1, l2, f2)
    m2, h2 = _half(l2, f2, l3, f3)
    n0, k0 = _half(m0, h0, m1, h1)
    n1, k1 = _half(m1, h1, m2, h2)
    p, ep = _half(n0, k0, n1, k1)
    return ((g[0], l0, m0, n0, p), (E[0], f0, h0, k0, ep), (p, n1, m2, l3, g[4]), (ep, k1, h2, f3, E[4]))


@_jit
def _negative(g, E):
    """All five coefficients certainly negative (then so is the quartic: the convex hull property)."""
    return (g[0] < -E[0] * _SLACK and g[1] < -E[1] * _SLACK and g[2] < -E[2] * _SLACK
            and g[3] < -E[3] * _SLACK and g[4] < -E[4] * _SLACK)


@_jit
def _subdivide(g, E):
    """Certified sign of a quartic known by Bernstein coefficients within E of g: 1, -1 or UNDECIDED.

    Halves depth first, left to right: a piece with all coefficients
    certainly negative is negative; an end value certainly positive proves
    separation; the first piece still open at SUBDIVIDE_DEPTH leaves the
    answer UNDECIDED.  The stack of right halves still to look at is the
    only allocation of the static tests (this last resort is rare).
    """
    stack = np.empty((SUBDIVIDE_DEPTH + 1, 10))
    depths = np.empty(SUBDIVIDE_DEPTH + 1, dtype=np.int64)
    top = 0
    depth = 0
    while True:
        if g[0] > E[0] * _SLACK or g[4] > E[4] * _SLACK:
            return 1
        if not _negative(g, E):
            if depth >= SUBDIVIDE_DEPTH:
                return UNDECIDED
            g, E, right, eright = _split(g, E)
            depth += 1
            for i in range(5):
                stack[top, i] = right[i]
                stack[top, 5 + i] = eright[i]
            depths[top] = depth
            top += 1
        elif top == 0:
            return -1
        else:
            top -= 1
            g = (stack[top, 0], stack[top, 1], stack[top, 2], stack[top, 3], stack[top, 4])
            E = (stack[top, 5], stack[top, 6], stack[top, 7], stack[top, 8], stack[top, 9])
            depth = depths[top]


@_jit
def _certified_status(A, eA, B, eB):
    """1 / -1 where proven for the exact quadrics within eA, eB of A, B (16-tuples), else UNDECIDED.

    g(u) = det((1-u)A + uB) is sampled at u = 0, 1/4, ..., 1 with error
    bounds.  A sample certainly positive proves separation; Bernstein
    coefficients (linear in the samples) all certainly negative prove
    overlap.  Otherwise g is evaluated at its argmax (separate if certainly
    positive there), and last the coefficients are subdivided.  A positive
    multiple of g is all that is needed: det(v A + u B) for any v, u >= 0.
    """
    v2, e2 = _pencil_det_e(0.5, 0.5, A, eA, B, eB)
    if v2 > e2 * _SLACK:
        return 1
    v1, e1 = _pencil_det_e(0.25, 0.75, A, eA, B, eB)
    if v1 > e1 * _SLACK:
        return 1
    v3, e3 = _pencil_det_e(0.75, 0.25, A, eA, B, eB)
    if v3 > e3 * _SLACK:
        return 1
    v0, e0 = _pencil_det_e(0.0, 1.0, A, eA, B, eB)
    v4, e4 = _pencil_det_e(1.0, 0.0, A, eA, B, eB)
    if v0 > e0 * _SLACK or v4 > e4 * _SLACK:
        return 1
    v = (v0, v1, v2, v3, v4)
    e = (e0, e1, e2, e3, e4)
    g, E = _bernstein((v0, v1, v2, v3, v4), (e0, e1, e2, e3, e4))
    if _negative(g, E):
        return -1
    _, us = quartic_max5(g[0], g[1], g[2], g[3], g[4])
    if 0.0 < us < 1.0:
        vs, es = _pencil_det_e(us, 1.0 - us, A, eA, B, eB)
        if vs > es * _SLACK:
            return 1
    return _subdivide(g, E)


@_jit
def _tuple16(M):
    """A 4x4 array as a row-major 16-tuple."""
    return (M[0, 0], M[0, 1], M[0, 2], M[0, 3], M[1, 0], M[1, 1], M[1, 2], M[1, 3],
            M[2, 0], M[2, 1], M[2, 2], M[2, 3], M[3, 0], M[3, 1], M[3, 2], M[3, 3])


@_jit
def static_status_matrices(A, B):
    """Status code of two world quadrics (4x4 arrays, taken as exact): 1 separate, -1 overlapping,
    2 (UNDECIDED) touching or too close to touching for double precision (resolve it with
    :func:`mjccd.exact.static_status_exact`)."""
    return _certified_status(_tuple16(A), _ZERO16, _tuple16(B), _ZERO16)


@_jit
def _rot_tuple(q):
    """Rotation matrix of a unit quaternion [w, x, y, z] as a 9-tuple (no allocation).

    For any q it is ``rot(q) = |q|^2 R`` with R orthogonal.
    """
    w, x, y, z = q[0], q[1], q[2], q[3]
    return (w * w + x * x - y * y - z * z, 2.0 * (x * y - w * z), 2.0 * (x * z + w * y),
            2.0 * (x * y + w * z), w * w - x * x + y * y - z * z, 2.0 * (y * z - w * x),
            2.0 * (x * z - w * y), 2.0 * (y * z + w * x), w * w - x * x - y * y + z * z)


@_inline
def _inv_square(r):
    """1 / r^2 for an exact r in [_RADIUS_MIN, _RADIUS_MAX], and its error bound (two roundings: < 3 U)."""
    x = 1.0 / (r * r)
    return x, 3.0 * _U * x


@_inline
def _emul_inv_square(x, ex, r):
    """x / r^2 (r as in :func:`_inv_square`) and its error bound."""
    y, ey = _inv_square(r)
    return _emul(x, ex, y, ey)


@_inline
def _rotate_scale(cb, erb, x, ex, db):
    """``y = rot(qb)^T x`` (cb: the columns of rot(qb), within erb; x within ex) and ``Db y``
    (db: the three (1/r^2, bound) of B's radii): y, its bounds, Db y, its bounds, as 3-tuples."""
    y0, f0 = _edot3(cb[0], erb, x, ex)
    y1, f1 = _edot3(cb[1], erb, x, ex)
    y2, f2 = _edot3(cb[2], erb, x, ex)
    w0, k0 = _emul(db[0][0], db[0][1], y0, f0)
    w1, k1 = _emul(db[1][0], db[1][1], y1, f1)
    w2, k2 = _emul(db[2][0], db[2][1], y2, f2)
    return (y0, y1, y2), (f0, f1, f2), (w0, w1, w2), (k0, k1, k2)


@_jit
def _pose_pair(radii_a, pos_a, quat_a, radii_b, pos_b, quat_b):
    """The pair in A's frame, scaled: A, B as 16-tuples with error bounds, and the two centre tests.

    With ``rot(q) = |q|^2 R`` (unnormalised), ``n = |q|^2``, ``R' = rot(qb)^T rot(qa)``,
    ``t' = rot(qb)^T (pa - pb)``, ``Da``, ``Db`` the diagonals 1/r^2, and A's
    frame coordinates scaled by n_a (a congruence: no sign of g changes), the
    exact quadrics are, up to positive factors ``ka``, ``kb`` (any positive
    doubles; they balance the determinants):
        A = ka diag(n_a^2 Da, -1),   B = kb [[R'^T Db R', R'^T Db t'], [., t'^T Db t' - n_b^2]].
    Every rounding on the way is bounded: rot entries and n are sums of four
    terms of at most four roundings (error <= gamma_4 |q|^2 <= 5 U n).
    Returns A, eA, B, eB, and the values with bounds of ``t'^T Db t' - n_b^2``
    (negative: A's centre inside B) and ``|Da^(1/2) rot(qa)^T (pb - pa)|^2 - n_a^2``
    (negative: B's centre inside A).
    """
    ra = _rot_tuple(quat_a)
    rb = _rot_tuple(quat_b)
    na = quat_a[0] * quat_a[0] + quat_a[1] * quat_a[1] + quat_a[2] * quat_a[2] + quat_a[3] * quat_a[3]
    nb = quat_b[0] * quat_b[0] + quat_b[1] * quat_b[1] + quat_b[2] * quat_b[2] + quat_b[3] * quat_b[3]
    ena = 5.0 * _U * na + _ETA
    enb = 5.0 * _U * nb + _ETA
    era = (ena, ena, ena)
    erb = (enb, enb, enb)
    d, ed0 = _eadd(pos_a[0], 0.0, -pos_b[0], 0.0)
    d1, ed1 = _eadd(pos_a[1], 0.0, -pos_b[1], 0.0)
    d2, ed2 = _eadd(pos_a[2], 0.0, -pos_b[2], 0.0)
    dd = (d, d1, d2)
    edd = (ed0, ed1, ed2)
    # columns of rot(qa), rot(qb)
    ca = ((ra[0], ra[3], ra[6]), (ra[1], ra[4], ra[7]), (ra[2], ra[5], ra[8]))
    cb = ((rb[0], rb[3], rb[6]), (rb[1], rb[4], rb[7]), (rb[2], rb[5], rb[8]))
    # R' = rot(qb)^T rot(qa), entry (k, i) = cb[k] . ca[i], by columns R0, R1, R2; t' = T; Db R' and Db t'
    db = (_inv_square(radii_b[0]), _inv_square(radii_b[1]), _inv_square(radii_b[2]))
    R0, F0, W0, K0 = _rotate_scale(cb, erb, ca[0], era, db)
    R1, F1, W1, K1 = _rotate_scale(cb, erb, ca[1], era, db)
    R2, F2, W2, K2 = _rotate_scale(cb, erb, ca[2], era, db)
    T, G, WT, KT = _rotate_scale(cb, erb, dd, edd, db)
    kb = np.sqrt(radii_b[0] * radii_b[1] * radii_b[2])  # |det B|^(1/4) for unit quaternions
    ka = np.sqrt(radii_a[0] * radii_a[1] * radii_a[2])
    b00, e00 = _kdot3(kb, W0, K0, R0, F0)
    b01, e01 = _kdot3(kb, W0, K0, R1, F1)
    b02, e02 = _kdot3(kb, W0, K0, R2, F2)
    b11, e11 = _kdot3(kb, W1, K1, R1, F1)
    b12, e12 = _kdot3(kb, W1, K1, R2, F2)
    b22, e22 = _kdot3(kb, W2, K2, R2, F2)
    b03, e03 = _kdot3(kb, W0, K0, T, G)
    b13, e13 = _kdot3(kb, W1, K1, T, G)
    b23, e23 = _kdot3(kb, W2, K2, T, G)
    tt, ett = _edot3(WT, KT, T, G)
    nb2, enb2 = _emul(nb, enb, nb, enb)
    sb, esb = _eadd(tt, ett, -nb2, enb2)  # < 0: A's centre inside B
    b33, e33 = _emul(kb, 0.0, sb, esb)
    B = (b00, b01, b02, b03, b01, b11, b12, b13, b02, b12, b22, b23, b03, b13, b23, b33)
    eB = (e00, e01, e02, e03, e01, e11, e12, e13, e02, e12, e22, e23, e03, e13, e23, e33)
    # A = ka diag(n_a^2 Da, -1)
    na2, ena2 = _emul(na, ena, na, ena)
    kna2, ekna2 = _emul(ka, 0.0, na2, ena2)
    a0, ea0 = _emul_inv_square(kna2, ekna2, radii_a[0])
    a1, ea1 = _emul_inv_square(kna2, ekna2, radii_a[1])
    a2, ea2 = _emul_inv_square(kna2, ekna2, radii_a[2])
    A = (a0, 0.0, 0.0, 0.0, 0.0, a1, 0.0, 0.0, 0.0, 0.0, a2, 0.0, 0.0, 0.0, 0.0, -ka)
    eA = (ea0, 0.0, 0.0, 0.0, 0.0, ea1, 0.0, 0.0, 0.0, 0.0, ea2, 0.0, 0.0, 0.0, 0.0, 0.0)
    # B's centre in A: |Da^(1/2) rot(qa)^T d|^2 - n_a^2
    c0, j0 = _edot3(ca[0], era, dd, edd)
    c1, j1 = _edot3(ca[1], era, dd, edd)
    c2, j2 = _edot3(ca[2], era, dd, edd)
    x0, i0 = _emul_inv_square(c0, j0, radii_a[0])
    x1, i1 = _emul_inv_square(c1, j1, radii_a[1])
    x2, i2 = _emul_inv_square(c2, j2, radii_a[2])
    sa, esa = _edot3((x0, x1, x2), (i0, i1, i2), (c0, c1, c2), (j0, j1, j2))
    sa, esa = _eadd(sa, esa, -na2, ena2)
    return A, eA, B, eB, sb, esb, sa, esa


@_jit
def _quick_det(u, a, ea, b, eb):
    """det((1-u) diag(a) + u B) for a symmetric B, in plain arithmetic, and a cheap error bound.

    ``b = (b00, b01, b02, b03, b11, b12, b13, b22, b23, b33)``; ``ea`` bounds
    the errors of ``a`` and ``eb = (e3x3, e_col3, e33)`` those of B's blocks;
    u is a node (0, 1/4, 1/2, 3/4, 1: 1 - u exact).  With r_i and d_i the l1
    norms of row i of the entries M and of their error bounds, the entries'
    errors move the determinant by at most ``prod(r_i + d_i) - prod(r_i)``
    (Hadamard's inequality on each term of the expansion of det(M + D) by
    rows), and its evaluation by 2x2 minors (ten roundings a term) by at
    most ``gamma_10 per(|M|) <= 10.01 U prod(r_i)``.  Forming an entry
    ``v a + u b`` rounds by at most ``3.01 U (|v a| + |u b|)``.
    """
    v = 1.0 - u
    b00, b01, b02, b03, b11, b12, b13, b22, b23, b33 = b
    m00 = v * a[0] + u * b00
    m11 = v * a[1] + u * b11
    m22 = v * a[2] + u * b22
    m33 = v * a[3] + u * b33
    m01 = u * b01
    m02 = u * b02
    m03 = u * b03
    m12 = u * b12
    m13 = u * b13
    m23 = u * b23
    det = _det4_rows((m00, m01, m02, m03), (m01, m11, m12, m13), (m02, m12, m22, m23), (m03, m13, m23, m33))
    r0 = abs(m00) + abs(m01) + abs(m02) + abs(m03)
    r1 = abs(m01) + abs(m11) + abs(m12) + abs(m13)
    r2 = abs(m02) + abs(m12) + abs(m22) + abs(m23)
    r3 = abs(m03) + abs(m13) + abs(m23) + abs(m33)
    w = 3.01 * _U * u
    eb3 = u * (3.0 * eb[0] + eb[1]) + 8.0 * _ETA  # rows 0-2 hold three 3x3-block entries and one of column 3
    d0 = v * (ea[0] + 3.01 * _U * abs(a[0])) + eb3 + w * (abs(b00) + abs(b01) + abs(b02) + abs(b03))
    d1 = v * (ea[1] + 3.01 * _U * abs(a[1])) + eb3 + w * (abs(b01) + abs(b11) + abs(b12) + abs(b13))
    d2 = v * (ea[2] + 3.01 * _U * abs(a[2])) + eb3 + w * (abs(b02) + abs(b12) + abs(b22) + abs(b23))
    d3 = (v * (ea[3] + 3.01 * _U * abs(a[3])) + u * (3.0 * eb[1] + eb[2]) + 8.0 * _ETA
          + w * (abs(b03) + abs(b13) + abs(b23) + abs(b33)))
    moved = (d0 * (r1 + d1) * (r2 + d2) * (r3 + d3) + r0 * d1 * (r2 + d2) * (r3 + d3)
             + r0 * r1 * d2 * (r3 + d3) + r0 * r1 * r2 * d3)
    bound = moved + 10.01 * _U * (r0 * r1 * r2 * r3) + 64.0 * _ETA * (1.0 + r0 * r1) * (1.0 + r2 * r3)
    return det, bound


@_jit
def _quick_pair(radii_a, pos_a, quat_a, radii_b, pos_b, quat_b):
    """The pair of :func:`_pose_pair` in plain arithmetic, with cheap uniform error bounds.

    Returns ``a`` (A's diagonal), its bounds, B's ten entries ``b`` (as
    :func:`_quick_det` takes them), their bounds (3x3 block, column 3, b33),
    and the two centre tests with their bounds.  Instead of tracking each
    error, the bounds use ``|R'| <= n_a n_b`` (R' is n_a n_b times an
    orthogonal matrix) and the largest |t'|, |c|: loose for thin shapes and
    large offsets, enough for most pairs.  Derivations in the comments.
    """
    ra = _rot_tuple(quat_a)
    rb = _rot_tuple(quat_b)
    na = quat_a[0] * quat_a[0] + quat_a[1] * quat_a[1] + quat_a[2] * quat_a[2] + quat_a[3] * quat_a[3]
    nb = quat_b[0] * quat_b[0] + quat_b[1] * quat_b[1] + quat_b[2] * quat_b[2] + quat_b[3] * quat_b[3]
    # R' = rot(qb)^T rot(qa): |error| <= 3 (2 (n+5Un) 5Un + 25U^2 n^2) + gamma_3 3 n^2 (1+10U)^2 < 40 U na nb
    r0 = rb[0] * ra[0] + rb[3] * ra[3] + rb[6] * ra[6]
    r1 = rb[0] * ra[1] + rb[3] * ra[4] + rb[6] * ra[7]
    r2 = rb[0] * ra[2] + rb[3] * ra[5] + rb[6] * ra[8]
    r3 = rb[1] * ra[0] + rb[4] * ra[3] + rb[7] * ra[6]
    r4 = rb[1] * ra[1] + rb[4] * ra[4] + rb[7] * ra[7]
    r5 = rb[1] * ra[2] + rb[4] * ra[5] + rb[7] * ra[8]
    r6 = rb[2] * ra[0] + rb[5] * ra[3] + rb[8] * ra[6]
    r7 = rb[2] * ra[1] + rb[5] * ra[4] + rb[8] * ra[7]
    r8 = rb[2] * ra[2] + rb[5] * ra[5] + rb[8] * ra[8]
    nn = na * nb * (1.0 + 64.0 * _U)  # >= |R'| + its error
    er = 48.0 * _U * nn + 8.0 * _ETA
    # t' = rot(qb)^T d, c = rot(qa)^T d: |error| <= |d|_1 n (U (1+10U) + 5U + 5U^2 + 3.01U (1+10U)) < 10 U n |d|_1
    dx = pos_a[0] - pos_b[0]
    dy = pos_a[1] - pos_b[1]
    dz = pos_a[2] - pos_b[2]
    d1 = abs(dx) + abs(dy) + abs(dz)
    t0 = rb[0] * dx + rb[3] * dy + rb[6] * dz
    t1 = rb[1] * dx + rb[4] * dy + rb[7] * dz
    t2 = rb[2] * dx + rb[5] * dy + rb[8] * dz
    et = 12.0 * _U * nb * d1 + 8.0 * _ETA
    c0 = ra[0] * dx + ra[3] * dy + ra[6] * dz
    c1 = ra[1] * dx + ra[4] * dy + ra[7] * dz
    c2 = ra[2] * dx + ra[5] * dy + ra[8] * dz
    ec = 12.0 * _U * na * d1 + 8.0 * _ETA
    e0 = 1.0 / (radii_b[0] * radii_b[0])
    e1 = 1.0 / (radii_b[1] * radii_b[1])
    e2 = 1.0 / (radii_b[2] * radii_b[2])
    f0 = 1.0 / (radii_a[0] * radii_a[0])
    f1 = 1.0 / (radii_a[1] * radii_a[1])
    f2 = 1.0 / (radii_a[2] * radii_a[2])
    esum = e0 + e1 + e2
    # centre tests: |error of sum_k e_k x_k^2 - n^2| <= sum e (2|x| ex + ex^2)(1+16U) + 8.01U sum e x^2 + 12U n^2
    # (e: 2 roundings, then 4 more a term and the subtraction; n^2: 11U)
    w0 = e0 * t0
    w1 = e1 * t1
    w2 = e2 * t2
    tt = t0 * w0 + t1 * w1 + t2 * w2
    nb2 = nb * nb
    sb = tt - nb2
    tau = max(abs(t0), abs(t1), abs(t2))
    esb = esum * (2.0 * tau * et + et * et) * (1.0 + 16.0 * _U) + 10.0 * _U * tt + 14.0 * _U * nb2 + 8.0 * _ETA
    na2 = na * na
    cc = f0 * c0 * c0 + f1 * c1 * c1 + f2 * c2 * c2
    sa = cc - na2
    esa = ((f0 + f1 + f2) * (2.0 * max(abs(c0), abs(c1), abs(c2)) * ec + ec * ec) * (1.0 + 16.0 * _U)
           + 10.0 * _U * cc + 14.0 * _U * na2 + 8.0 * _ETA)
    # B in A's frame.  |error| of b_ij (i, j < 3) <= kb sum e ((2 nn er + er^2)(1+8U) + 7.01U nn^2),
    # of b_i3 <= kb sum e ((nn et + tau er + er et)(1+8U) + 7.01U nn tau), of b_33 <= kb esb.
    kb = np.sqrt(radii_b[0] * radii_b[1] * radii_b[2])
    ka = np.sqrt(radii_a[0] * radii_a[1] * radii_a[2])
    b00 = kb * (e0 * r0 * r0 + e1 * r3 * r3 + e2 * r6 * r6)
    b01 = kb * (e0 * r0 * r1 + e1 * r3 * r4 + e2 * r6 * r7)
    b02 = kb * (e0 * r0 * r2 + e1 * r3 * r5 + e2 * r6 * r8)
    b11 = kb * (e0 * r1 * r1 + e1 * r4 * r4 + e2 * r7 * r7)
    b12 = kb * (e0 * r1 * r2 + e1 * r4 * r5 + e2 * r7 * r8)
    b22 = kb * (e0 * r2 * r2 + e1 * r5 * r5 + e2 * r8 * r8)
    b03 = kb * (r0 * w0 + r3 * w1 + r6 * w2)
    b13 = kb * (r1 * w0 + r4 * w1 + r7 * w2)
    b23 = kb * (r2 * w0 + r5 * w1 + r8 * w2)
    b33 = kb * sb
    ep = kb * esum * ((2.0 * nn * er + er * er) * (1.0 + 16.0 * _U) + 8.0 * _U * nn * nn) + 8.0 * _ETA
    eq = kb * esum * ((nn * et + tau * er + er * et) * (1.0 + 16.0 * _U) + 8.0 * _U * nn * tau) + 8.0 * _ETA
    es = kb * esb * (1.0 + 2.0 * _U) + _U * abs(b33) + 8.0 * _ETA
    # A = ka diag(n_a^2 Da, -1): five roundings after n_a's 5U each: < 18U
    kna2 = ka * na2
    a = (kna2 * f0, kna2 * f1, kna2 * f2, -ka)
    ea = (18.0 * _U * a[0] + _ETA, 18.0 * _U * a[1] + _ETA, 18.0 * _U * a[2] + _ETA, 0.0)
    b = (b00, b01, b02, b03, b11, b12, b13, b22, b23, b33)
    return a, ea, b, (ep, eq, es), sb, esb, sa, esa


@_jit
def _quick_status(radii_a, pos_a, quat_a, radii_b, pos_b, quat_b):
    """The clear cases at the cost of plain arithmetic: 1, -1, or UNDECIDED (then :func:`_pose_pair`).

    A centre certainly inside the other ellipsoid, g certainly positive at
    u = 1/2, 1/4 or 3/4, all Bernstein coefficients certainly negative, and
    last g at its argmax and the subdivision, all with :func:`_quick_pair`'s bounds.
    """
    a, ea, b, eb, sb, esb, sa, esa = _quick_pair(radii_a, pos_a, quat_a, radii_b, pos_b, quat_b)
    if sb < -esb * _SLACK or sa < -esa * _SLACK:
        return -1  # a centre inside the other ellipsoid
    v2, x2 = _quick_det(0.5, a, ea, b, eb)
    if v2 > x2 * _SLACK:
        return 1
    v1, x1 = _quick_det(0.25, a, ea, b, eb)
    if v1 > x1 * _SLACK:
        return 1
    v3, x3 = _quick_det(0.75, a, ea, b, eb)
    if v3 > x3 * _SLACK:
        return 1
    v0, x0 = _quick_det(0.0, a, ea, b, eb)
    v4, x4 = _quick_det(1.0, a, ea, b, eb)
    g, E = _bernstein((v0, v1, v2, v3, v4), (x0, x1, x2, x3, x4))
    if _negative(g, E):
        return -1
    _, us = quartic_max5(g[0], g[1], g[2], g[3], g[4])
    if 0.0 < us < 1.0:
        vs, xs = _quick_det(us, a, ea, b, eb)
        if vs > xs * _SLACK:
            return 1
    return _subdivide(g, E)


@_jit
def static_status_pose(radii_a, pos_a, quat_a, radii_b, pos_b, quat_b):
    """Status code of two posed ellipsoids: 1 separate, -1 overlapping, 2 (UNDECIDED).

    Certified for the exact quadrics of the inputs (quaternions of any norm,
    normalised exactly as ``rot(q) / |q|^2``): 1 and -1 are never wrong, and
    2 stands for touching or too close to touching for double precision
    (resolve it with :func:`static_status_code` or :mod:`mjccd.exact`).  B is
    written in A's frame (thesis §4.1).  Most pairs are settled by
    :func:`_quick_status` at the cost of plain arithmetic; the others are
    computed again with every error tracked (:func:`_pose_pair`): a centre
    certainly inside the other ellipsoid proves overlap, else
    :func:`_certified_status` decides.
    """
    for k in range(3):
        if not (_RADIUS_MIN <= radii_a[k] <= _RADIUS_MAX and _RADIUS_MIN <= radii_b[k] <= _RADIUS_MAX):
            return UNDECIDED
    for q in (quat_a, quat_b):
        if not (_QNORM_MIN <= q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3] <= _QNORM_MAX):
            return UNDECIDED
    code = _quick_status(radii_a, pos_a, quat_a, radii_b, pos_b, quat_b)
    if code != UNDECIDED:
        return code
    A, eA, B, eB, sb, esb, sa, esa = _pose_pair(radii_a, pos_a, quat_a, radii_b, pos_b, quat_b)
    if sb < -esb * _SLACK or sa < -esa * _SLACK:
        return -1
    return _certified_status(A, eA, B, eB)


@_jit
def static_status_batch(radii_a, pos_a, quat_a, radii_b, pos_b, quat_b, out):
    """Status codes of many posed pairs at once (one row per pair): :func:`static_status_pose`'s
    1, -1 or 2 (UNDECIDED; :func:`static_status_many` resolves it exactly).

    Rows go in as tuples of scalars: a row view would cost an atomic reference
    count update each, about as much as the test itself.
    """
    for k in range(out.shape[0]):
        out[k] = static_status_pose((radii_a[k, 0], radii_a[k, 1], radii_a[k, 2]),
                                    (pos_a[k, 0], pos_a[k, 1], pos_a[k, 2]),
                                    (quat_a[k, 0], quat_a[k, 1], quat_a[k, 2], quat_a[k, 3]),
                                    (radii_b[k, 0], radii_b[k, 1], radii_b[k, 2]),
                                    (pos_b[k, 0], pos_b[k, 1], pos_b[k, 2]),
                                    (quat_b[k, 0], quat_b[k, 1], quat_b[k, 2], quat_b[k, 3]))
    return out


@_jit
def _cofactor(M, i, j):
    """(-1)^(i+j) times the minor of the 4x4 ``M`` without row i and column j."""
    r0, r1, r2 = (1 if i == 0 else 0), (2 if i <= 1 else 1), (3 if i <= 2 else 2)
    c0, c1, c2 = (1 if j == 0 else 0), (2 if j <= 1 else 1), (3 if j <= 2 else 2)
    minor = _det3(M[r0, c0], M[r0, c1], M[r0, c2], M[r1, c0], M[r1, c1], M[r1, c2],
                  M[r2, c0], M[r2, c1], M[r2, c2])
    return minor if (i + j) % 2 == 0 else -minor


@_jit
def null_vector(M):
    """A vector spanning the kernel of a (numerically) rank-3 symmetric 4x4 matrix.

    The adjugate of a rank-3 matrix is rank one, ``adj M = k X X^T``; its
    column with the largest diagonal entry is the best-conditioned multiple
    of X.  Only the diagonal and that column are computed.
    """
    best = np.intp(0)
    best_diag = abs(_cofactor(M, np.intp(0), np.intp(0)))
    for i in range(1, 4):
        d = abs(_cofactor(M, i, i))
        if d > best_diag:
            best, best_diag = i, d
    X = np.empty(4)
    for i in range(4):
        X[i] = _cofactor(M, best, i)  # adj(M)[i, best]
    return X


@_jit
def touching_point(A, B, u):
    """World contact point and unit normal (outward from A) of two touching quadrics.

    ``u`` is the double root of det((1-u)A + uB) in (0, 1); the contact point
    spans the kernel of (1-u)A + uB (the thesis' Theorem 4.4 in u form).
    """
    p = np.full(3, np.nan)
    n = np.full(3, np.nan)
    pencil_point_into(A, B, u, p, n)
    return p, n


@_jit
def pencil_point_into(A, B, u, p, n):
    """p, n = the point spanning the kernel of (1-u)A + uB and the unit normal of A there (outward); False,
    p and n left as they were, where that point lies at infinity or A's normal vanishes there."""
    M = np.empty((4, 4))
    for i in range(4):
        for j in range(4):
            M[i, j] = (1.0 - u) * A[i, j] + u * B[i, j]
    X = null_vector(M)
    if not (np.isfinite(X[3]) and X[3] != 0.0):
        return False
    q = np.empty(3)
    g = np.empty(3)
    for i in range(3):
        q[i] = X[i] / X[3]
    for i in range(3):
        g[i] = A[i, 0] * q[0] + A[i, 1] * q[1] + A[i, 2] * q[2] + A[i, 3]
    norm = np.sqrt(g[0] * g[0] + g[1] * g[1] + g[2] * g[2])
    if not (np.isfinite(norm) and norm > 0.0 and np.isfinite(q[0] + q[1] + q[2])):
        return False
    for i in range(3):
        p[i] = q[i]
        n[i] = g[i] / norm
    return True


@_jit
def _quartic_root(g, lo, hi, glo):
    """Root of the quartic ``g`` on [lo, hi] with a sign change (bisection)."""
    for _ in range(200):
        mid = 0.5 * (lo + hi)
        if mid <= lo or mid >= hi:
            break
        gm = _quartic_value(g, mid)
        if (gm > 0.0) == (glo > 0.0):
            lo, glo = mid, gm
        else:
            hi = mid
    return 0.5 * (lo + hi)


@_jit
def _segment_hits(Q, P0, P1):
    """Parameters s where P0 + s (P1 - P0) meets the quadric Q (NaN when it does not)."""
    D = P1 - P0
    qa = D @ Q @ D
    qb = 2.0 * (P0 @ Q @ D)
    qc = P0 @ Q @ P0
    disc = qb * qb - 4.0 * qa * qc
    if disc < 0.0 or qa == 0.0:
        return np.nan, np.nan
    sq = np.sqrt(disc)
    s1 = (-qb - sq) / (2.0 * qa)
    s2 = (-qb + sq) / (2.0 * qa)
    return min(s1, s2), max(s1, s2)


@_jit
def separating_plane_matrices(A, B):
    """A plane separating two separate quadrics (thesis Thm 4.5-4.6).

    Returns (ok, plane, point_a, point_b): ``plane = (n, d)`` with unit n and
    A on the side ``n.x + d < 0``; point_a / point_b are the tangent points
    of the two tangent planes through the polar line V0V1 along the line
    V3V2 (good approximations of the closest points; exact for spheres).
    """
    plane = np.zeros(4)
    pa = np.zeros(3)
    pb = np.zeros(3)
    g, noise = pencil_quartic(A, B)
    gmax, umax = quartic_max(g)
    if status_from_max(gmax, noise) != 1:
        return False, plane, pa, pb
    # the two roots of g in (0, 1) <-> the two negative eigenvalues
    u_lo = _quartic_root(g, 0.0, umax, g[0])
    u_hi = _quartic_root(g, umax, 1.0, gmax)
    # u close to 0 weights A: its kernel point lies inside B, and vice versa.
    V_inside_b = null_vector((1.0 - u_lo) * A + u_lo * B)
    V_inside_a = null_vector((1.0 - u_hi) * A + u_hi * B)
    Pa = V_inside_a / V_inside_a[3]
    Pb = V_inside_b / V_inside_b[3]
    if Pa @ A @ Pa > 0.0:  # labels the other way round
        Pa, Pb = Pb, Pa
    _, s_exit_a = _segment_hits(A, Pa, Pb)
    s_enter_b, _ = _segment_hits(B, Pa, Pb)
    if not (s_exit_a < s_enter_b):
        return False, plane, pa, pb
    D = Pb - Pa
    Ta = Pa + s_exit_a * D
    Tb = Pa + s_enter_b * D
    S = 0.5 * (Ta + Tb)
    pi_a = A @ Ta
    pi_b = B @ Tb
    pi = (pi_b @ S) * pi_a - (pi_a @ S) * pi_b
    norm = np.sqrt(pi[0] ** 2 + pi[1] ** 2 + pi[2] ** 2)
    if norm == 0.0:
        return False, plane, pa, pb
    pi = pi / norm
    if pi @ Pa > 0.0:  # A's inner point must be on the negative side
        pi = -pi
    for i in range(3):  # element by element (see bernstein's _jit)
        plane[i] = pi[i]
        pa[i] = Ta[i]
        pb[i] = Tb[i]
    plane[3] = pi[3]
    return True, plane, pa, pb


# ---------------------------------------------------------------- Python layer


@dataclass(frozen=True)
class Ellipsoid:
    """An ellipsoid ``x^2/a^2 + y^2/b^2 + z^2/c^2 <= 1`` in its own frame."""

    radii: np.ndarray

    def __init__(self, radii):
        object.__setattr__(self, "radii", _validate.radii(radii, "radii"))

    def matrix(self, position=(0.0, 0.0, 0.0), quaternion=(1.0, 0.0, 0.0, 0.0)):
        """World 4x4 quadric matrix of this ellipsoid at a pose."""
        p = _validate.vector(position, 3, "position")
        q = _validate.quaternion(quaternion, "quaternion")
        return quadric_matrix(self.radii, p, q)


@dataclass(frozen=True)
class SeparatingPlane:
    """A plane ``normal . x + offset = 0`` with ellipsoid a on its negative side."""

    normal: np.ndarray
    offset: float
    point_a: np.ndarray
    point_b: np.ndarray


def static_status_code(radii_a, pos_a, quat_a, radii_b, pos_b, quat_b):
    """Status code (+1 separate, 0 touching, -1 overlapping) of two posed ellipsoids, never UNDECIDED.

    :func:`static_status_pose` first; the pairs it leaves UNDECIDED are
    decided in rational arithmetic (:func:`mjccd.exact.static_status_exact`)
    on the same doubles, so the answer is exact for the inputs as given.
    """
    ra, pa, qa, rb, pb, qb = (np.asarray(x, dtype=np.float64) for x in (radii_a, pos_a, quat_a, radii_b, pos_b, quat_b))
    code = int(static_status_pose(ra, pa, qa, rb, pb, qb))
    return code if code != UNDECIDED else _exact_code(ra, pa, qa, rb, pb, qb)


def _exact_code(ra, pa, qa, rb, pb, qb):
    """Exact status of a posed pair (pure Python: for the rare UNDECIDED pair only)."""
    return exact.static_status_exact(exact.quadric_exact_integer(ra, pa, qa), exact.quadric_exact_integer(rb, pb, qb))


def _pose(pose):
    """(position, quaternion) checked, the quaternion normalised exactly as static_status_many does it."""
    position, quaternion = pose
    p = _validate.vector(position, 3, "position")
    _validate.quaternion(quaternion, "quaternion")  # its checks and messages
    row = _validate.pose_array(np.r_[p, _validate.vector(quaternion, 4, "quaternion")][None, :], "pose")[0]
    return row[:3], row[3:]


def static_status(a, pose_a, b, pose_b):
    """'separate', 'touching' or 'overlapping' for two posed ellipsoids, exact for the doubles given.

    ``pose_*`` is ``(position, quaternion)`` with the quaternion ``[w, x, y, z]``
    (normalised as :func:`static_status_many` normalises it, so the two agree).
    """
    (pa, qa), (pb, qb) = _pose(pose_a), _pose(pose_b)
    return STATUS_NAMES[static_status_code(a.radii, pa, qa, b.radii, pb, qb)]


def static_status_many(radii_a, poses_a, radii_b, poses_b):
    """Status codes (+1 separate, 0 touching, -1 overlapping) for K pairs, exact for the doubles given.

    ``radii_*`` are (K, 3); ``poses_*`` are (K, 7) rows of position and
    quaternion ``[w, x, y, z]``.  The batched kernel decides almost every
    pair; the few it leaves UNDECIDED are decided exactly, as in
    :func:`static_status`, so both always agree.
    """
    ra = _validate.radii_array(radii_a, "radii_a")
    rb = _validate.radii_array(radii_b, "radii_b")
    pa = _validate.pose_array(poses_a, "poses_a", len(ra))
    pb = _validate.pose_array(poses_b, "poses_b", len(rb))
    if len(ra) != len(rb):
        raise InputError(f"radii_b: expected {len(ra)} rows like radii_a, got {len(rb)}")
    out = np.empty(len(ra), dtype=np.int64)
    static_status_batch(ra, np.ascontiguousarray(pa[:, :3]), np.ascontiguousarray(pa[:, 3:]),
                        rb, np.ascontiguousarray(pb[:, :3]), np.ascontiguousarray(pb[:, 3:]), out)
    for k in np.nonzero(out == UNDECIDED)[0]:
        out[k] = _exact_code(ra[k], pa[k, :3], pa[k, 3:], rb[k], pb[k, :3], pb[k, 3:])
    return out


def contact_point(a, pose_a, b, pose_b):
    """Contact point and unit normal (outward from a) of two touching ellipsoids.

    Raises ValueError when the two are not touching.
    """
    A = a.matrix(*pose_a)
    B = b.matrix(*pose_b)
    g, noise = pencil_quartic(A, B)
    gmax, u = quartic_max(g)
    if status_from_max(gmax, noise) != 0:
        raise InputError("ellipsoids are not touching: status is "
                         + STATUS_NAMES[int(status_from_max(gmax, noise))])
    p, n = touching_point(A, B, u)
    return p, n


def separating_plane(a, pose_a, b, pose_b):
    """A :class:`SeparatingPlane` of two separate ellipsoids (ValueError otherwise)."""
    A = a.matrix(*pose_a)
    B = b.matrix(*pose_b)
    ok, plane, pa, pb = separating_plane_matrices(A, B)
    if not ok:
        raise InputError("ellipsoids are not separate: no separating plane")
    return SeparatingPlane(plane[:3].copy(), float(plane[3]), pa, pb)
