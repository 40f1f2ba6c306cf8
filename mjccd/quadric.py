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
def _cubic_value(d, u):
    v = 1.0 - u
    return d[0] * v ** 3 + 3.0 * d[1] * u * v * v + 3.0 * d[2] * u * u * v + d[3] * u ** 3


@_jit
def _monotone_root(d, lo, hi, flo):
    """Root of the cubic ``d`` (Bernstein) on [lo, hi] where it is monotone and changes sign."""
    for _ in range(100):
        mid = 0.5 * (lo + hi)
        if mid <= lo or mid >= hi:
            break
        fm = _cubic_value(d, mid)
        if fm == 0.0:
            return mid
        if (fm > 0.0) == (flo > 0.0):
            lo, flo = mid, fm
        else:
            hi = mid
        if hi - lo < 1e-15:
            break
    return 0.5 * (lo + hi)


@_jit
def quartic_max(g):
    """Maximum of the Bernstein quartic ``g`` over u in [0, 1] and where it is attained.

    The critical points are the roots of the cubic g'; the roots of g''
    (a quadratic, solved in closed form) split [0, 1] into pieces on which
    g' is monotone, and each sign change there is located by bisection.
    """
    if g.max() < 0.0:  # convex hull below zero: certainly negative everywhere
        best_u = 0.0 if g[0] >= g[4] else 1.0
        return max(g[0], g[4]), best_u
    d = np.empty(4)  # g'/4 in Bernstein form
    for i in range(4):
        d[i] = g[i + 1] - g[i]
    # g''/12 Bernstein coefficients (quadratic) -> power basis a + b u + c u^2
    e0 = d[1] - d[0]
    e1 = d[2] - d[1]
    e2 = d[3] - d[2]
    a = e0
    b = 2.0 * (e1 - e0)
    c = e0 - 2.0 * e1 + e2
    cuts = np.empty(4)
    ncut = 0
    cuts[ncut] = 0.0
    ncut += 1
    if c == 0.0:
        if b != 0.0:
            r = -a / b
            if 0.0 < r < 1.0:
                cuts[ncut] = r
                ncut += 1
    else:
        disc = b * b - 4.0 * a * c
        if disc > 0.0:
            sq = np.sqrt(disc)
            qq = -0.5 * (b + sq if b >= 0.0 else b - sq)
            r1 = qq / c
            r2 = a / qq if qq != 0.0 else r1
            if r1 > r2:
                r1, r2 = r2, r1
            if 0.0 < r1 < 1.0:
                cuts[ncut] = r1
                ncut += 1
            if 0.0 < r2 < 1.0 and r2 != r1:
                cuts[ncut] = r2
                ncut += 1
    cuts[ncut] = 1.0
    ncut += 1
    best = g[0]
    best_u = 0.0
    if g[4] > best:
        best = g[4]
        best_u = 1.0
    for k in range(ncut - 1):
        lo = cuts[k]
        hi = cuts[k + 1]
        flo = _cubic_value(d, lo)
        fhi = _cubic_value(d, hi)
        if flo > 0.0 and fhi < 0.0:  # g' goes + to -: a local maximum
            u = _monotone_root(d, lo, hi, flo)
            val = _quartic_value(g, u)
            if val > best:
                best = val
                best_u = u
    return best, best_u


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
def static_status_batch(radii_a, pos_a, quat_a, radii_b, pos_b, quat_b, out):
    """Status codes of many posed pairs at once (one row per pair)."""
    for k in range(out.shape[0]):
        A = quadric_matrix(radii_a[k], pos_a[k], quat_a[k])
        B = quadric_matrix(radii_b[k], pos_b[k], quat_b[k])
        out[k] = static_status_matrices(A, B)
    return out


@_jit
def null_vector(M):
    """A vector spanning the kernel of a (numerically) rank-3 symmetric 4x4 matrix.

    The adjugate of a rank-3 matrix is rank one, ``adj M = k X X^T``; its
    column with the largest diagonal entry is the best-conditioned multiple
    of X.
    """
    adj = np.empty((4, 4))
    rows = np.empty(3, dtype=np.int64)
    cols = np.empty(3, dtype=np.int64)
    for i in range(4):
        for j in range(4):
            ri = 0
            for r in range(4):
                if r != j:
                    rows[ri] = r
                    ri += 1
            ci = 0
            for c in range(4):
                if c != i:
                    cols[ci] = c
                    ci += 1
            minor = _det3(M[rows[0], cols[0]], M[rows[0], cols[1]], M[rows[0], cols[2]],
                          M[rows[1], cols[0]], M[rows[1], cols[1]], M[rows[1], cols[2]],
                          M[rows[2], cols[0]], M[rows[2], cols[1]], M[rows[2], cols[2]])
            adj[i, j] = minor if (i + j) % 2 == 0 else -minor
    best = 0
    for i in range(1, 4):
        if abs(adj[i, i]) > abs(adj[best, best]):
            best = i
    return adj[:, best].copy()


@_jit
def touching_point(A, B, u):
    """World contact point and unit normal (outward from A) of two touching quadrics.

    ``u`` is the double root of det((1-u)A + uB) in (0, 1); the contact point
    spans the kernel of (1-u)A + uB (the thesis' Theorem 4.4 in u form).
    """
    M = (1.0 - u) * A + u * B
    X = null_vector(M)
    p = X[:3] / X[3]
    Xh = np.empty(4)
    Xh[:3] = p
    Xh[3] = 1.0
    n = (A @ Xh)[:3]
    n = n / np.sqrt(n @ n)
    return p, n


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
