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
"""
from dataclasses import dataclass

import numba
import numpy as np

from mjccd import _validate

_jit = numba.njit(cache=True, nogil=True)

SEPARATE = 1
TOUCHING = 0
OVERLAPPING = -1
STATUS_NAMES = {SEPARATE: "separate", TOUCHING: "touching", OVERLAPPING: "overlapping"}

# |max g| below this many rounding units of the determinant counts as touching.
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
    out[:3, :3] = Q
    Qp = Q @ position
    out[:3, 3] = -Qp
    out[3, :3] = -Qp
    out[3, 3] = position @ Qp - 1.0
    return out


@_jit
def _det3(m00, m01, m02, m10, m11, m12, m20, m21, m22):
    return (m00 * (m11 * m22 - m12 * m21) - m01 * (m10 * m22 - m12 * m20)
            + m02 * (m10 * m21 - m11 * m20))


@_jit
def det4(M):
    """Determinant of a 4x4 matrix by 2x2 minors."""
    s0 = M[0, 0] * M[1, 1] - M[1, 0] * M[0, 1]
    s1 = M[0, 0] * M[1, 2] - M[1, 0] * M[0, 2]
    s2 = M[0, 0] * M[1, 3] - M[1, 0] * M[0, 3]
    s3 = M[0, 1] * M[1, 2] - M[1, 1] * M[0, 2]
    s4 = M[0, 1] * M[1, 3] - M[1, 1] * M[0, 3]
    s5 = M[0, 2] * M[1, 3] - M[1, 2] * M[0, 3]
    c5 = M[2, 2] * M[3, 3] - M[3, 2] * M[2, 3]
    c4 = M[2, 1] * M[3, 3] - M[3, 1] * M[2, 3]
    c3 = M[2, 1] * M[3, 2] - M[3, 1] * M[2, 2]
    c2 = M[2, 0] * M[3, 3] - M[3, 0] * M[2, 3]
    c1 = M[2, 0] * M[3, 2] - M[3, 0] * M[2, 2]
    c0 = M[2, 0] * M[3, 1] - M[3, 0] * M[2, 1]
    return s0 * c5 - s1 * c4 + s2 * c3 + s3 * c2 - s4 * c1 + s5 * c0


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


@_jit
def static_status_matrices(A, B):
    """Status code (+1 separate, 0 touching, -1 overlapping) of two world quadrics."""
    g, noise = pencil_quartic(A, B)
    gmax, _ = quartic_max(g)
    return status_from_max(gmax, noise)


@_jit
def _rot_tuple(q):
    """Rotation matrix of a unit quaternion [w, x, y, z] as a 9-tuple (no allocation)."""
    w, x, y, z = q[0], q[1], q[2], q[3]
    return (w * w + x * x - y * y - z * z, 2.0 * (x * y - w * z), 2.0 * (x * z + w * y),
            2.0 * (x * y + w * z), w * w - x * x + y * y - z * z, 2.0 * (y * z - w * x),
            2.0 * (x * z - w * y), 2.0 * (y * z + w * x), w * w - x * x - y * y + z * z)


@_jit
def _pencil_det(u, a0, a1, a2, a3, b00, b01, b02, b03, b11, b12, b13, b22, b23, b33):
    """det((1 - u) diag(a0, a1, a2, a3) + u B) for symmetric B (scalars only)."""
    v = 1.0 - u
    m00 = v * a0 + u * b00
    m11 = v * a1 + u * b11
    m22 = v * a2 + u * b22
    m33 = v * a3 + u * b33
    m01 = u * b01
    m02 = u * b02
    m03 = u * b03
    m12 = u * b12
    m13 = u * b13
    m23 = u * b23
    s0 = m00 * m11 - m01 * m01
    s1 = m00 * m12 - m01 * m02
    s2 = m00 * m13 - m01 * m03
    s3 = m01 * m12 - m11 * m02
    s4 = m01 * m13 - m11 * m03
    s5 = m02 * m13 - m12 * m03
    c5 = m22 * m33 - m23 * m23
    c4 = m12 * m33 - m13 * m23
    c3 = m12 * m23 - m13 * m22
    c2 = m02 * m33 - m03 * m23
    c1 = m02 * m23 - m03 * m22
    c0 = m02 * m13 - m03 * m12
    return s0 * c5 - s1 * c4 + s2 * c3 + s3 * c2 - s4 * c1 + s5 * c0


@_jit
def static_status_pose(radii_a, pos_a, quat_a, radii_b, pos_b, quat_b):
    """Status code of two posed ellipsoids, allocation-free (thesis §4.1 in A's frame).

    B is written in A's canonical frame, both matrices are balanced to
    |det| = 1, and g(u) = det((1-u)A + uB) is sampled at five nodes: a
    positive sample proves separation, all-negative Bernstein coefficients
    prove overlap, and only the remaining pairs need the maximum of g.
    """
    ra = _rot_tuple(quat_a)
    rb = _rot_tuple(quat_b)
    # relative rotation R = Rb^T Ra and translation t = Rb^T (pa - pb)
    r0 = rb[0] * ra[0] + rb[3] * ra[3] + rb[6] * ra[6]
    r1 = rb[0] * ra[1] + rb[3] * ra[4] + rb[6] * ra[7]
    r2 = rb[0] * ra[2] + rb[3] * ra[5] + rb[6] * ra[8]
    r3 = rb[1] * ra[0] + rb[4] * ra[3] + rb[7] * ra[6]
    r4 = rb[1] * ra[1] + rb[4] * ra[4] + rb[7] * ra[7]
    r5 = rb[1] * ra[2] + rb[4] * ra[5] + rb[7] * ra[8]
    r6 = rb[2] * ra[0] + rb[5] * ra[3] + rb[8] * ra[6]
    r7 = rb[2] * ra[1] + rb[5] * ra[4] + rb[8] * ra[7]
    r8 = rb[2] * ra[2] + rb[5] * ra[5] + rb[8] * ra[8]
    dx = pos_a[0] - pos_b[0]
    dy = pos_a[1] - pos_b[1]
    dz = pos_a[2] - pos_b[2]
    t0 = rb[0] * dx + rb[3] * dy + rb[6] * dz
    t1 = rb[1] * dx + rb[4] * dy + rb[7] * dz
    t2 = rb[2] * dx + rb[5] * dy + rb[8] * dz
    e0 = 1.0 / (radii_b[0] * radii_b[0])
    e1 = 1.0 / (radii_b[1] * radii_b[1])
    e2 = 1.0 / (radii_b[2] * radii_b[2])
    ka = (radii_a[0] * radii_a[1] * radii_a[2]) ** 0.5  # |det A|^(1/4) = 1 / sqrt(abc)
    kb = (radii_b[0] * radii_b[1] * radii_b[2]) ** 0.5
    a0 = ka / (radii_a[0] * radii_a[0])
    a1 = ka / (radii_a[1] * radii_a[1])
    a2 = ka / (radii_a[2] * radii_a[2])
    # B in A's frame: Q = R^T E R, Qv = R^T E t, c = t^T E t - 1  (scaled by kb)
    b00 = kb * (e0 * r0 * r0 + e1 * r3 * r3 + e2 * r6 * r6)
    b01 = kb * (e0 * r0 * r1 + e1 * r3 * r4 + e2 * r6 * r7)
    b02 = kb * (e0 * r0 * r2 + e1 * r3 * r5 + e2 * r6 * r8)
    b11 = kb * (e0 * r1 * r1 + e1 * r4 * r4 + e2 * r7 * r7)
    b12 = kb * (e0 * r1 * r2 + e1 * r4 * r5 + e2 * r7 * r8)
    b22 = kb * (e0 * r2 * r2 + e1 * r5 * r5 + e2 * r8 * r8)
    w0 = e0 * t0
    w1 = e1 * t1
    w2 = e2 * t2
    b03 = kb * (r0 * w0 + r3 * w1 + r6 * w2)
    b13 = kb * (r1 * w0 + r4 * w1 + r7 * w2)
    b23 = kb * (r2 * w0 + r5 * w1 + r8 * w2)
    b33 = kb * (t0 * w0 + t1 * w1 + t2 * w2 - 1.0)
    # a centre inside the other ellipsoid (beyond rounding) decides overlap at once
    if t0 * w0 + t1 * w1 + t2 * w2 < 1.0 - 1e-9:
        return -1
    ca0 = -(ra[0] * dx + ra[3] * dy + ra[6] * dz) / radii_a[0]
    ca1 = -(ra[1] * dx + ra[4] * dy + ra[7] * dz) / radii_a[1]
    ca2 = -(ra[2] * dx + ra[5] * dy + ra[8] * dz) / radii_a[2]
    if ca0 * ca0 + ca1 * ca1 + ca2 * ca2 < 1.0 - 1e-9:
        return -1
    ra_ = max(a0, a1, a2, ka)
    rows = (max(ra_, abs(b00) + abs(b01) + abs(b02) + abs(b03))
            * max(ra_, abs(b01) + abs(b11) + abs(b12) + abs(b13))
            * max(ra_, abs(b02) + abs(b12) + abs(b22) + abs(b23))
            * max(ka, abs(b03) + abs(b13) + abs(b23) + abs(b33)))
    noise = rows * 64.0 * 2.220446049250313e-16
    band = TOUCH_ULPS * noise
    # a positive sample proves separation: try the middle first
    v2 = _pencil_det(0.5, a0, a1, a2, -ka, b00, b01, b02, b03, b11, b12, b13, b22, b23, b33)
    if v2 > band:
        return 1
    v1 = _pencil_det(0.25, a0, a1, a2, -ka, b00, b01, b02, b03, b11, b12, b13, b22, b23, b33)
    if v1 > band:
        return 1
    v3 = _pencil_det(0.75, a0, a1, a2, -ka, b00, b01, b02, b03, b11, b12, b13, b22, b23, b33)
    if v3 > band:
        return 1
    v0 = -a0 * a1 * a2 * ka
    v4 = _pencil_det(1.0, a0, a1, a2, -ka, b00, b01, b02, b03, b11, b12, b13, b22, b23, b33)
    g1 = (-13.0 * v0 + 48.0 * v1 - 36.0 * v2 + 16.0 * v3 - 3.0 * v4) / 12.0
    g3 = (-3.0 * v0 + 16.0 * v1 - 36.0 * v2 + 48.0 * v3 - 13.0 * v4) / 12.0
    g2 = (13.0 * v0 - 64.0 * v1 + 120.0 * v2 - 64.0 * v3 + 13.0 * v4) / 18.0
    if max(v0, g1, g2, g3, v4) < -band:
        return -1
    gmax, _ = quartic_max5(v0, g1, g2, g3, v4)
    return status_from_max(gmax, noise)


@_jit
def static_status_batch(radii_a, pos_a, quat_a, radii_b, pos_b, quat_b, out):
    """Status codes of many posed pairs at once (one row per pair; unit quaternions).

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
    best = 0
    best_diag = abs(_cofactor(M, 0, 0))
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
    X = null_vector((1.0 - u) * A + u * B)
    p = X[:3] / X[3]
    n = np.empty(3)
    for i in range(3):
        n[i] = A[i, 0] * p[0] + A[i, 1] * p[1] + A[i, 2] * p[2] + A[i, 3]
    return p, n / np.sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2])


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
    plane[:] = pi
    pa[:] = Ta[:3]
    pb[:] = Tb[:3]
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


def static_status(a, pose_a, b, pose_b):
    """'separate', 'touching' or 'overlapping' for two posed ellipsoids.

    ``pose_*`` is ``(position, quaternion)`` with the quaternion ``[w, x, y, z]``.
    """
    A = a.matrix(*pose_a)
    B = b.matrix(*pose_b)
    return STATUS_NAMES[int(static_status_matrices(A, B))]


def static_status_many(radii_a, poses_a, radii_b, poses_b):
    """Status codes (+1 separate, 0 touching, -1 overlapping) for K pairs.

    ``radii_*`` are (K, 3); ``poses_*`` are (K, 7) rows of position and
    quaternion ``[w, x, y, z]``.
    """
    ra = _validate.radii_array(radii_a, "radii_a")
    rb = _validate.radii_array(radii_b, "radii_b")
    pa = _validate.pose_array(poses_a, "poses_a", len(ra))
    pb = _validate.pose_array(poses_b, "poses_b", len(rb))
    if len(ra) != len(rb):
        raise ValueError(f"radii_b: expected {len(ra)} rows like radii_a, got {len(rb)}")
    out = np.empty(len(ra), dtype=np.int64)
    return static_status_batch(ra, np.ascontiguousarray(pa[:, :3]), np.ascontiguousarray(pa[:, 3:]),
                               rb, np.ascontiguousarray(pb[:, :3]), np.ascontiguousarray(pb[:, 3:]), out)


def contact_point(a, pose_a, b, pose_b):
    """Contact point and unit normal (outward from a) of two touching ellipsoids.

    Raises ValueError when the two are not touching.
    """
    A = a.matrix(*pose_a)
    B = b.matrix(*pose_b)
    g, noise = pencil_quartic(A, B)
    gmax, u = quartic_max(g)
    if status_from_max(gmax, noise) != 0:
        raise ValueError("ellipsoids are not touching: status is "
                         + STATUS_NAMES[int(status_from_max(gmax, noise))])
    p, n = touching_point(A, B, u)
    return p, n


def separating_plane(a, pose_a, b, pose_b):
    """A :class:`SeparatingPlane` of two separate ellipsoids (ValueError otherwise)."""
    A = a.matrix(*pose_a)
    B = b.matrix(*pose_b)
    ok, plane, pa, pb = separating_plane_matrices(A, B)
    if not ok:
        raise ValueError("ellipsoids are not separate: no separating plane")
    return SeparatingPlane(plane[:3].copy(), float(plane[3]), pa, pb)
