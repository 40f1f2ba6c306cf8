"""Motion models, each turned exactly into polynomial quadric matrices over t in [0, 1].

A moving ellipsoid is ``X^T A(t) X <= 0`` with

    A(t) = [[P(t), U(t)], [U(t)^T, s(t)]]      (up to a positive factor)

where P (3x3), U (3) and s are polynomials in t, kept in Bernstein form.  No
motion is sampled or fitted: rational rigid motions are written through the
*scaled inverse* ``W(t) = c(t) M(t)^-1 = [[G, h], [0, g]]`` with polynomial
G, h, g, so that ``c^2 A = W^T diag(D, -1) W`` (``D = diag(1/a^2, 1/b^2, 1/c^2)``);
compositions (chains) multiply the W's.

Degrees in t of (P, U, s): static (0, 0, 0); rigid (4, 5, 6); affine
(1, 2, 3); linear_affine (4, 5, 6); a chain of k rotating joints
(4k, 4k, 4k) at most.
"""
import abc
import math
from fractions import Fraction

import numba
import numpy as np

from mjccd import _validate, exact
from mjccd import bernstein as bz
from mjccd.errors import InputError, InputTypeError
from mjccd.quadric import quat_to_matrix

# compiled on first use and cached; no cfunc wrapper (no kernel is passed around as a first-class function);
# forceinline=False: numba hands a caller's forceinline down to the callees it compiles
_jit = numba.njit(cache=True, nogil=True, no_cfunc_wrapper=True, forceinline=False)
# a one-line helper called with many literal ints (gamma(80), gamma(120), ...) is typed inside its callers: as a
# kernel of its own, numba compiled it once per literal value
_inline = numba.njit(cache=True, nogil=True, no_cfunc_wrapper=True, forceinline=False, inline="always")
EPS = 2.220446049250313e-16
FLATTENING = 1e-12  # a linear_affine L(t) must keep |det L| above this times its size cubed (see _not_flattened)


# ---------------------------------------------------------------- kernels


@_jit
def _quat_rotation_poly(qc):
    """Unnormalised rotation ``rot(q)`` of a Bernstein quaternion ``qc`` (4, k+1) -> (3, 3, 2k+1)."""
    w, x, y, z = qc[0], qc[1], qc[2], qc[3]
    mul = bz.multiply
    ww, xx, yy, zz = mul(w, w), mul(x, x), mul(y, y), mul(z, z)
    xy, xz, yz = mul(x, y), mul(x, z), mul(y, z)
    wx, wy, wz = mul(w, x), mul(w, y), mul(w, z)
    n = ww.shape[0]
    R = np.empty((3, 3, n))
    bz.copy_into(R[0, 0], ww + xx - yy - zz)
    bz.copy_into(R[0, 1], 2.0 * (xy - wz))
    bz.copy_into(R[0, 2], 2.0 * (xz + wy))
    bz.copy_into(R[1, 0], 2.0 * (xy + wz))
    bz.copy_into(R[1, 1], ww - xx + yy - zz)
    bz.copy_into(R[1, 2], 2.0 * (yz - wx))
    bz.copy_into(R[2, 0], 2.0 * (xz - wy))
    bz.copy_into(R[2, 1], 2.0 * (yz + wx))
    bz.copy_into(R[2, 2], ww - xx - yy + zz)
    return R, ww + xx + yy + zz


@_jit
def _matvec_poly(G, h):
    """Polynomial matrix (3, 3, a) times polynomial vector (3, b) -> (3, a + b - 1)."""
    n = G.shape[2] + h.shape[1] - 1
    out = np.zeros((3, n))
    for i in range(3):
        for k in range(3):
            bz.add_into(out[i], bz.multiply(G[i, k].copy(), h[k].copy()), 1.0)
    return out


@_jit
def _matmul_poly(Ga, Gb):
    """Product of two polynomial 3x3 matrices."""
    n = Ga.shape[2] + Gb.shape[2] - 1
    out = np.zeros((3, 3, n))
    for i in range(3):
        for j in range(3):
            for k in range(3):
                bz.add_into(out[i, j], bz.multiply(Ga[i, k].copy(), Gb[k, j].copy()), 1.0)
    return out


@_jit
def w_of_rotation(qc):
    """Scaled inverse W of a pure rotation by the Bernstein quaternion ``qc``."""
    R, norm2 = _quat_rotation_poly(qc)
    n = R.shape[2]
    G = np.empty((3, 3, n))
    for i in range(3):
        for j in range(3):
            bz.copy_into(G[i, j], R[j, i])
    return G, np.zeros((3, 1)), norm2


@_jit
def w_of_translation(pc):
    """Scaled inverse W of a pure translation by the Bernstein vector ``pc`` (3, k+1)."""
    G = np.zeros((3, 3, 1))
    for i in range(3):
        G[i, i, 0] = 1.0
    return G, -pc, np.ones(1)


@_jit
def w_compose(Ga, ha, ga, Gb, hb, gb):
    """W of the composition M_a M_b, given W_a and W_b:  W = W_b W_a."""
    G = _matmul_poly(Gb, Ga)
    h1 = _matvec_poly(Gb, ha)
    h2 = np.empty((3, hb.shape[1] + ga.shape[0] - 1))
    for i in range(3):
        bz.copy_into(h2[i], bz.multiply(hb[i].copy(), ga))
    deg = max(h1.shape[1], h2.shape[1]) - 1
    h = np.empty((3, deg + 1))
    for i in range(3):
        bz.copy_into(h[i], bz.elevate(h1[i].copy(), deg + 1 - h1.shape[1])
                     + bz.elevate(h2[i].copy(), deg + 1 - h2.shape[1]))
    return G, h, bz.multiply(gb, ga)


@_jit
def w_translated(G, h, g, offset):
    """W of the same motion in the frame x' = x - offset:  W T(offset), i.e. h' = G offset + h."""
    deg = max(G.shape[2], h.shape[1]) - 1
    hn = np.empty((3, deg + 1))
    for i in range(3):
        acc = bz.elevate(h[i].copy(), deg + 1 - h.shape[1])
        for k in range(3):
            acc = acc + offset[k] * bz.elevate(G[i, k].copy(), deg + 1 - G.shape[2])
        hn[i] = acc
    return G, hn, g


@_jit
def quadric_from_w(G, h, g, radii):
    """(P, U, s) of an ellipsoid with radii under the motion whose scaled inverse is W."""
    d = 1.0 / (radii * radii)
    nG = G.shape[2]
    nP = 2 * nG - 1
    P = np.zeros((3, 3, nP))
    for i in range(3):
        for j in range(i, 3):
            for k in range(3):
                bz.add_into(P[i, j], bz.multiply(G[k, i].copy(), G[k, j].copy()), d[k])
            bz.copy_into(P[j, i], P[i, j])
    nU = nG + h.shape[1] - 1
    U = np.zeros((3, nU))
    for i in range(3):
        for k in range(3):
            bz.add_into(U[i], bz.multiply(G[k, i].copy(), h[k].copy()), d[k])
    hh = np.zeros(2 * h.shape[1] - 1)
    for k in range(3):
        hh += d[k] * bz.multiply(h[k].copy(), h[k].copy())
    s = bz.add(hh, -bz.multiply(g, g))
    return P, U, s


@_jit
def rigid_scaled_into(radii, p0, q0, p1, q1, origin0, origin1, length, P, U, s, side):
    """Scaled Bernstein (P, U, s) of a rigid motion, written into ``P[:, :, side]``, ``U[:, side]``, ``s[side]``.

    The motion is taken in the frame x' = (x - origin(t)) / length, whose
    origin moves from ``origin0`` to ``origin1`` linearly in t (a translation
    and a uniform scaling: taken for both bodies they change no answer, as the
    determinant of a pencil is invariant under a common congruence with
    determinant one).  With
    ``R = rot(q)`` the unnormalised rotation of the quaternion lerp,
    ``|q|^4 A = [[R D R^T, -R D R^T p], [., p^T R D R^T p - |q|^4]]``:
    P = R D R^T (degree 4), U = -P p (degree 5), s = p^T P p - |q|^4
    (degree 6).  Scaled coefficients (times their binomials) make every
    product a plain convolution; nothing is allocated but two small tables.
    """
    # quadratic products of quaternion components (scaled Bernstein, degree 2)
    qq = np.empty((4, 4, 3))
    for i in range(4):
        for j in range(4):
            qq[i, j, 0] = q0[i] * q0[j]
            qq[i, j, 1] = q0[i] * q1[j] + q1[i] * q0[j]
            qq[i, j, 2] = q1[i] * q1[j]
    R = np.empty((3, 3, 3))
    for a in range(3):
        R[0, 0, a] = qq[0, 0, a] + qq[1, 1, a] - qq[2, 2, a] - qq[3, 3, a]
        R[0, 1, a] = 2.0 * (qq[1, 2, a] - qq[0, 3, a])
        R[0, 2, a] = 2.0 * (qq[1, 3, a] + qq[0, 2, a])
        R[1, 0, a] = 2.0 * (qq[1, 2, a] + qq[0, 3, a])
        R[1, 1, a] = qq[0, 0, a] - qq[1, 1, a] + qq[2, 2, a] - qq[3, 3, a]
        R[1, 2, a] = 2.0 * (qq[2, 3, a] - qq[0, 1, a])
        R[2, 0, a] = 2.0 * (qq[1, 3, a] - qq[0, 2, a])
        R[2, 1, a] = 2.0 * (qq[2, 3, a] + qq[0, 1, a])
        R[2, 2, a] = qq[0, 0, a] - qq[1, 1, a] - qq[2, 2, a] + qq[3, 3, a]
    d = ((length / radii[0]) ** 2, (length / radii[1]) ** 2, (length / radii[2]) ** 2)
    c0 = ((p0[0] - origin0[0]) / length, (p0[1] - origin0[1]) / length, (p0[2] - origin0[2]) / length)
    c1 = ((p1[0] - origin1[0]) / length, (p1[1] - origin1[1]) / length, (p1[2] - origin1[2]) / length)
    for i in range(3):
        for j in range(i, 3):
            for a in range(5):
                P[i, j, side, a] = 0.0
            for k in range(3):
                dk = d[k]
                for a in range(3):
                    ra = R[i, k, a] * dk
                    for b in range(3):
                        P[i, j, side, a + b] += ra * R[j, k, b]
    for i in range(3):
        for j in range(i):
            for a in range(5):
                P[i, j, side, a] = P[j, i, side, a]
    for i in range(3):  # U = -P p, p the centre lerp in the new frame
        for a in range(6):
            U[i, side, a] = 0.0
        for j in range(3):
            for a in range(5):
                U[i, side, a] -= P[i, j, side, a] * c0[j]
                U[i, side, a + 1] -= P[i, j, side, a] * c1[j]
    for a in range(7):
        s[side, a] = 0.0
    for i in range(3):  # s = -p . U - |q|^4
        for a in range(6):
            s[side, a] -= U[i, side, a] * c0[i]
            s[side, a + 1] -= U[i, side, a] * c1[i]
    for a in range(3):
        ga = qq[0, 0, a] + qq[1, 1, a] + qq[2, 2, a] + qq[3, 3, a]
        for b in range(3):
            g2 = ga * (qq[0, 0, b] + qq[1, 1, b] + qq[2, 2, b] + qq[3, 3, b])
            # |q|^4 is of degree 4: elevated to 6 by the factor (1 - t + t)^2, scaled [1, 2, 1]
            s[side, a + b] -= g2
            s[side, a + b + 1] -= 2.0 * g2
            s[side, a + b + 2] -= g2


@_jit
def translation_scaled_into(radii, p0, q, p1, origin0, origin1, length, P, U, s, side):
    """:func:`rigid_scaled_into` for a motion whose quaternion stays ``q``: a pure translation, written at
    its true degrees (P constant, U linear, s quadratic) into a pencil of degrees (0, 1, 2).

    The same polynomials as the rigid motion with ``q1 = q0`` (whose lerped
    rotation is constant), without the common factor that raises their degrees
    to (4, 5, 6): F drops from degree 18 to 2 in t.
    """
    w, x, y, z = q[0], q[1], q[2], q[3]
    R = ((w * w + x * x - y * y - z * z, 2.0 * (x * y - w * z), 2.0 * (x * z + w * y)),
         (2.0 * (x * y + w * z), w * w - x * x + y * y - z * z, 2.0 * (y * z - w * x)),
         (2.0 * (x * z - w * y), 2.0 * (y * z + w * x), w * w - x * x - y * y + z * z))
    d = ((length / radii[0]) ** 2, (length / radii[1]) ** 2, (length / radii[2]) ** 2)
    for i in range(3):
        for j in range(i, 3):
            P[i, j, side, 0] = R[i][0] * d[0] * R[j][0] + R[i][1] * d[1] * R[j][1] + R[i][2] * d[2] * R[j][2]
            P[j, i, side, 0] = P[i, j, side, 0]
    c0 = ((p0[0] - origin0[0]) / length, (p0[1] - origin0[1]) / length, (p0[2] - origin0[2]) / length)
    c1 = ((p1[0] - origin1[0]) / length, (p1[1] - origin1[1]) / length, (p1[2] - origin1[2]) / length)
    for i in range(3):  # U = -P p, p the centre lerp in the new frame
        U[i, side, 0] = -(P[i, 0, side, 0] * c0[0] + P[i, 1, side, 0] * c0[1] + P[i, 2, side, 0] * c0[2])
        U[i, side, 1] = -(P[i, 0, side, 0] * c1[0] + P[i, 1, side, 0] * c1[1] + P[i, 2, side, 0] * c1[2])
    g = (w * w + x * x + y * y + z * z) ** 2  # |q|^4, the factor the rigid motion carries
    s[side, 0] = -(U[0, side, 0] * c0[0] + U[1, side, 0] * c0[1] + U[2, side, 0] * c0[2]) - g
    s[side, 1] = -(U[0, side, 0] * c1[0] + U[1, side, 0] * c1[1] + U[2, side, 0] * c1[2]
                   + U[0, side, 1] * c0[0] + U[1, side, 1] * c0[1] + U[2, side, 1] * c0[2]) - 2.0 * g
    s[side, 2] = -(U[0, side, 1] * c1[0] + U[1, side, 1] * c1[1] + U[2, side, 1] * c1[2]) - g


@_jit
def quadric_rigid(radii, p0, q0, p1, q1):
    """(P, U, s) in Bernstein form of the rigid motion (centre lerp, quaternion lerp); see :func:`rigid_scaled_into`."""
    P = np.empty((3, 3, 1, 5))
    U = np.empty((3, 1, 6))
    s = np.empty((1, 7))
    rigid_scaled_into(radii, p0, q0, p1, q1, np.zeros(3), np.zeros(3), 1.0, P, U, s, np.intp(0))
    b4 = bz.binomial_row(4)
    b5 = bz.binomial_row(5)
    b6 = bz.binomial_row(6)
    return P[:, :, 0] / b4, U[:, 0] / b5, s[0] / b6


@_jit
def quadric_affine(radii, p0, q0, p1, q1):
    """(P, U, s) of the thesis' affine interpolant: centre and shape matrix both lerped."""
    d = 1.0 / (radii * radii)
    R0 = quat_to_matrix(q0)
    R1 = quat_to_matrix(q1)
    P = np.zeros((3, 3, 2))
    for i in range(3):
        for j in range(3):
            for k in range(3):
                P[i, j, 0] += R0[i, k] * R0[j, k] * d[k]
                P[i, j, 1] += R1[i, k] * R1[j, k] * d[k]
    c = np.empty((3, 2))
    for i in range(3):
        c[i, 0] = p0[i]
        c[i, 1] = p1[i]
    Qc = _matvec_poly(P, c)  # degree 2
    U = -Qc
    s = np.zeros(4)
    for i in range(3):
        s += bz.multiply(c[i].copy(), Qc[i].copy())
    s = s - 1.0
    return P, U, s


@_inline
def gamma(k):
    """gamma_k = k u / (1 - k u): the relative error bound of k rounded operations (u the unit roundoff)."""
    return k * EPS / (1.0 - k * EPS)


@_jit
def centre_extent(p0, p1, origin0, origin1, length):
    """C of :func:`pose_side_errors`: the larger |centre - origin|_1 / length at the two ends."""
    c0 = abs(p0[0] - origin0[0]) + abs(p0[1] - origin0[1]) + abs(p0[2] - origin0[2])
    c1 = abs(p1[0] - origin1[0]) + abs(p1[1] - origin1[1]) + abs(p1[2] - origin1[2])
    return max(c0, c1) / length


@_jit
def pose_side_errors(radii, length, C, identity, e):
    """Error bounds (4x4, plain-coefficient units) of a two-pose side built by :func:`rigid_scaled_into`,
    :func:`translation_scaled_into` or :func:`quadric_affine` in the frame scaled by ``length``, into ``e``.

    With d_k = (length / r_k)^2, S = sum d_k and C the largest |centre|_1 at
    the two ends (:func:`centre_extent`): every rotation coefficient is at most |q|^2 <= 1, so P's
    terms add up to at most S, U's to S C and s's to S C^2 + 1; a few dozen
    roundings each.  ``identity``: the side's orientation is exactly the
    identity at both ends and its centre the origin (A in its own frame):
    P = diag(d) (d rounded), U = 0 and s = -1 exactly.
    """
    d0 = length / radii[0]
    d1 = length / radii[1]
    d2 = length / radii[2]
    d0, d1, d2 = d0 * d0, d1 * d1, d2 * d2
    if identity:
        e[:, :] = 0.0
        e[0, 0] = 3.0 * EPS * d0
        e[1, 1] = 3.0 * EPS * d1
        e[2, 2] = 3.0 * EPS * d2
        return e
    S = d0 + d1 + d2
    for i in range(3):
        for j in range(3):
            e[i, j] = gamma(80) * S
        e[i, 3] = e[3, i] = gamma(100) * S * C
    e[3, 3] = gamma(120) * (S * C * C + 1.0)
    return e


@_jit
def w_quadric_errors(G, h, g, radii):
    """Error bounds (4x4, plain-coefficient units) of :func:`quadric_from_w` on these W polynomials.

    P = G^T D G, U = G^T D h, s = h^T D h - g^2 with Bernstein products: each
    entry's terms add up to at most the same sums over the coefficients'
    maxima, and each product and sum rounds a bounded number of times (the W
    coefficients are the motion's definition; restricting them to a piece
    perturbs them by gamma_2n, covered here too).
    """
    n = max(G.shape[2], h.shape[1], g.shape[0])
    rho = gamma(6 * n + 40)
    d = 1.0 / (radii * radii)
    Gm, hm, gm = bz.abs_maxima(G, h, g)
    e = np.empty((4, 4))
    for i in range(3):
        for j in range(3):
            e[i, j] = rho * (d[0] * Gm[0, i] * Gm[0, j] + d[1] * Gm[1, i] * Gm[1, j] + d[2] * Gm[2, i] * Gm[2, j])
        e[i, 3] = e[3, i] = rho * (d[0] * Gm[0, i] * hm[0] + d[1] * Gm[1, i] * hm[1] + d[2] * Gm[2, i] * hm[2])
    e[3, 3] = rho * (d[0] * hm[0] ** 2 + d[1] * hm[1] ** 2 + d[2] * hm[2] ** 2 + gm * gm)
    return e


@_jit
def quadric_at(P, U, s, t):
    """The 4x4 quadric matrix at time t (up to the motion's positive factor)."""
    A = np.empty((4, 4))
    for i in range(3):
        for j in range(3):
            A[i, j] = bz.evaluate(P[i, j], t)
        A[i, 3] = bz.evaluate(U[i], t)
        A[3, i] = A[i, 3]
    A[3, 3] = bz.evaluate(s, t)
    return A


# ---------------------------------------------------------------- helpers


def _exact_bernstein(c, t):
    """Value of the Bernstein polynomial ``c`` (doubles) at the rational t, exactly.

    de Casteljau in integers: the coefficients over one common denominator,
    t = num / den, each level multiplied through by den; one Fraction at the end.
    """
    t = Fraction(t)
    num, den = t.numerator, t.denominator
    coefficients = [Fraction(float(x)) for x in c]
    scale = math.lcm(*(f.denominator for f in coefficients))
    work = [f.numerator * (scale // f.denominator) for f in coefficients]
    n = len(work) - 1
    for r in range(1, n + 1):
        for i in range(n - r + 1):
            work[i] = (den - num) * work[i] + num * work[i + 1]
    return Fraction(work[0], scale * den ** n)


def _restrict_all(c, t0, t1):
    """Every Bernstein polynomial along the last axis of ``c`` reparametrised from [t0, t1] onto [0, 1]."""
    flat = c.reshape(-1, c.shape[-1])
    out = np.empty_like(flat)
    for k in range(flat.shape[0]):
        out[k] = bz.restrict(flat[k].copy(), t0, t1)
    return out.reshape(c.shape)


def _linear_bernstein(v0, v1):
    """Bernstein coefficients (..., 2) of the lerp from v0 to v1."""
    out = np.empty(np.shape(v0) + (2,))
    out[..., 0] = v0
    out[..., 1] = v1
    return out


def _aligned(q0, q1):
    """q1 or -q1, whichever makes the lerp from q0 take the short way."""
    return q1 if float(q0 @ q1) >= 0.0 else -q1


def _pose_w(position, quaternion):
    """Constant W of a fixed pose (rotation then translation)."""
    R = quat_to_matrix(quaternion)
    G = np.ascontiguousarray(R.T[:, :, None])
    h = np.ascontiguousarray((-R.T @ position)[:, None])
    return G, h, np.ones(1)


def _keeps_sign(c, tol, depth=0):
    """True when the Bernstein polynomial c stays beyond +-tol on its interval (subdivision)."""
    if c.min() > tol or c.max() < -tol:
        return True
    if depth >= 40 or abs(c[0]) <= tol or abs(c[-1]) <= tol or (c[0] > 0.0) != (c[-1] > 0.0):
        return False
    left, right = bz.subdivide(c, 0.5)
    return _keeps_sign(left, tol, depth + 1) and _keeps_sign(right, tol, depth + 1)


def _nonvanishing(poly_power, field, bernstein=False):
    """Reject a polynomial (power basis, or Bernstein) that vanishes or nearly so on [0, 1]."""
    c = np.asarray(poly_power, float) if bernstein else bz.from_power(np.asarray(poly_power, float))
    if not _keeps_sign(c, 1e-12 * np.abs(c).max()):
        ts = np.linspace(0.0, 1.0, 1001)
        vals = np.abs([bz.evaluate(c, t) for t in ts])
        raise InputError(f"{field}: vanishes on [0, 1] (near t = {ts[int(np.argmin(vals))]:.6g})")


def _not_flattened(det, size):
    """Refuse a linear part L(t) that comes within FLATTENING of singular on [0, 1].

    The rule: det L(t) keeps one sign, and its smallest magnitude on [0, 1]
    (at an end or where its derivative vanishes: a cubic, ``det`` in
    Bernstein form) is more than FLATTENING * size^3, ``size`` the larger
    Frobenius norm of L at the ends (the largest over [0, 1]: the norm is
    convex along a lerp).  Since det L <= s_min s_max^2 <= s_min size^2, a body
    that passes is never flattened below FLATTENING of its size.
    """
    d0, d1, d2 = 3.0 * np.diff(det)  # the derivative, a quadratic in Bernstein form
    roots = np.roots([d0 - 2.0 * d1 + d2, 2.0 * (d1 - d0), d0])
    times = [0.0, 1.0] + [float(r.real) for r in roots if abs(r.imag) <= 1e-12 * abs(r) and 0.0 < r.real < 1.0]
    ordered = sorted((t, bz.evaluate(det, t)) for t in times)
    for (ta, va), (tb, vb) in zip(ordered, ordered[1:]):
        if va * vb <= 0.0:
            raise InputError(f"start/end: the linear part L(t) becomes singular between t = {ta:.6g} and {tb:.6g}")
    t, value = min(ordered, key=lambda pair: abs(pair[1]))
    if abs(value) <= FLATTENING * size ** 3:
        raise InputError(f"start/end: the linear part L(t) is within {FLATTENING:g} of singular at t = {t:.6g} "
                         f"(det L = {value:.3g}, |L| up to {size:.3g})")


def _pose_from_json(d, field):
    if not isinstance(d, dict):
        raise InputError(f"{field}: expected an object with position and quaternion")
    for key in ("position", "quaternion"):
        if key not in d:
            raise InputError(f"{field}.{key}: missing")
    return (_validate.vector(d["position"], 3, f"{field}.position"),
            _validate.quaternion(d["quaternion"], f"{field}.quaternion"))


# ---------------------------------------------------------------- motion models


class Motion(abc.ABC):
    """Base class: a motion of an ellipsoid's frame over normalised time t in [0, 1]."""

    kind = "motion"

    @abc.abstractmethod
    def quadric(self, radii):
        """(P, U, s) Bernstein arrays of the ellipsoid with these radii under this motion."""

    @abc.abstractmethod
    def anchor(self):
        """A point on the body's path at t = 0: the origin of a pair's local frame."""

    @abc.abstractmethod
    def translated(self, offset):
        """The same motion seen from a frame whose origin is the world point ``offset``.

        The offset is subtracted from the motion's own inputs, before any
        product is formed, so that a body far from the world origin loses no
        precision to the distance.
        """

    def scaled_inverse_w(self):
        """(G, h, g): the scaled inverse ``W(t) = c(t) M(t)^-1 = [[G, h], [0, g]]`` of this motion, or None.

        Bernstein arrays, G (3, 3, n), h (3, n), g (n,) (see :func:`quadric_from_w`): the motion's own,
        to read, never to write.  None for a motion not given by one (:class:`Affine`).
        """
        return None

    def factor(self):
        """Bernstein coefficients of the positive factor that scales this motion's quadric, or None.

        A rational motion's polynomial quadric is the true one times g(t)^2;
        where g varies by orders of magnitude over [0, 1] the solver builds
        the pair on shorter pieces of time (see :func:`mjccd.ccd.time_pieces`).
        """
        return None

    @abc.abstractmethod
    def exact_quadric_at(self, radii, t):
        """The 4x4 quadric at the rational time t (Fractions or integers), exact for this motion's doubles (up to a
        factor > 0)."""

    @abc.abstractmethod
    def quadric_bounded_on(self, radii, t0, t1):
        """(P, U, s, err) over [t0, t1]: :meth:`quadric_on` and a 4x4 bound of its coefficients' rounding errors."""

    def quadric_on(self, radii, t0, t1):
        """(P, U, s) of this motion over [t0, t1], reparametrised onto [0, 1]."""
        P, U, s = self.quadric(radii)
        if t0 == 0.0 and t1 == 1.0:
            return P, U, s
        return (_restrict_all(P, t0, t1), _restrict_all(U, t0, t1), bz.restrict(s.copy(), t0, t1))


class _WMotion(Motion):
    """A motion given by its scaled inverse W(t) = c(t) M(t)^-1.

    Given to the constructor, or (:class:`Static`, :class:`Rigid`) formed by
    the subclass's ``_scaled_inverse`` on first need: the two-pose solver
    never needs it.
    """

    _w_cache = None

    def __init__(self, G, h, g):
        self._w_cache = (np.ascontiguousarray(G), np.ascontiguousarray(h), np.ascontiguousarray(g))

    @property
    def _w(self):
        """(G, h, g) Bernstein arrays of W."""
        if self._w_cache is None:
            self._w_cache = self._scaled_inverse()
        return self._w_cache

    def quadric(self, radii):
        return quadric_from_w(*self._w, np.asarray(radii, float))

    def quadric_on(self, radii, t0, t1):
        """The scaled inverse is restricted to [t0, t1] before the quadric's products are formed."""
        if t0 == 0.0 and t1 == 1.0:
            return self.quadric(radii)
        G, h, g = self._w
        return quadric_from_w(_restrict_all(G, t0, t1), _restrict_all(h, t0, t1), bz.restrict(g.copy(), t0, t1),
                              np.asarray(radii, float))

    def factor(self):
        return self._w[2]

    def scaled_inverse_w(self):
        return self._w

    def quadric_bounded_on(self, radii, t0, t1):
        G, h, g = self._w
        if not (t0 == 0.0 and t1 == 1.0):
            G, h, g = _restrict_all(G, t0, t1), _restrict_all(h, t0, t1), bz.restrict(g.copy(), t0, t1)
        radii = np.asarray(radii, float)
        return (*quadric_from_w(G, h, g, radii), w_quadric_errors(G, h, g, radii))

    def exact_quadric_at(self, radii, t):
        return self.polynomial_quadric_at(radii, t)

    def polynomial_quadric_at(self, radii, t):
        """The quadric of W at the rational t, exactly: the value of a polynomial in t of degree
        :meth:`quadric_degree` (a subclass's :meth:`exact_quadric_at` may scale it by other factors)."""
        G, h, g = self._w
        return exact.quadric_from_w_exact([[_exact_bernstein(G[i, j], t) for j in range(3)] for i in range(3)],
                                          [_exact_bernstein(h[i], t) for i in range(3)],
                                          _exact_bernstein(g, t), radii)

    def quadric_degree(self):
        """Degree in t of :meth:`polynomial_quadric_at`'s entries (products of two entries of W)."""
        G, h, g = self._w
        return 2 * (max(G.shape[2], h.shape[1], g.shape[0]) - 1)

    def anchor(self):
        G, h, _ = self._w
        return np.linalg.solve(G[:, :, 0], -h[:, 0])

    def translated(self, offset):
        G, h, g = self._w
        return _WMotion(*w_translated(G, h, g, np.asarray(offset, float)))

    def transform(self, t):
        """World 3x4 matrix [L | v] of the frame at time t."""
        G, h, g = self._w
        Gt = np.array([[bz.evaluate(G[i, j], t) for j in range(3)] for i in range(3)])
        ht = np.array([bz.evaluate(h[i], t) for i in range(3)])
        gt = bz.evaluate(g, t)
        L = np.linalg.inv(Gt / gt)
        return np.hstack([L, (-L @ (ht / gt))[:, None]])


def _pose_row(position0, quaternion0, position1, quaternion1, align):
    """Validated poses as one float64 row ``[p0, q0, p1, q1]`` (14,), the quaternions unit; with ``align``,
    q1 is replaced by -q1 where that makes the lerp from q0 take the short way."""
    xs = _validate.plain_floats((position0, quaternion0, position1, quaternion1), (3, 4, 3, 4))
    n0 = n1 = 0.0
    if xs is not None:
        n0 = math.hypot(xs[3], xs[4], xs[5], xs[6])
        n1 = math.hypot(xs[10], xs[11], xs[12], xs[13])
    if _validate.MIN_NORM <= n0 < math.inf and _validate.MIN_NORM <= n1 < math.inf:
        p0, q0 = xs[0:3], [xs[3] / n0, xs[4] / n0, xs[5] / n0, xs[6] / n0]
        p1, q1 = xs[7:10], [xs[10] / n1, xs[11] / n1, xs[12] / n1, xs[13] / n1]
    else:  # the checks one field at a time, which name what is wrong
        p0 = _validate.floats(position0, 3, "start.position")
        q0 = _validate.unit_quaternion(quaternion0, "start.quaternion")
        p1 = _validate.floats(position1, 3, "end.position")
        q1 = _validate.unit_quaternion(quaternion1, "end.quaternion")
    if align and q0[0] * q1[0] + q0[1] * q1[1] + q0[2] * q1[2] + q0[3] * q1[3] < 0.0:
        q1 = [-q1[0], -q1[1], -q1[2], -q1[3]]
    return np.array(p0 + q0 + p1 + q1)


def _shifted(motion, offset):
    """A copy of a validated two-pose motion (``_row``) whose centres are shifted by -offset (no re-validation)."""
    moved = object.__new__(type(motion))
    moved.__dict__.update(motion.__dict__)
    moved.__dict__.pop("_w_cache", None)  # formed again from the shifted centres: no cancellation in W
    row = motion._row.copy()
    row[0:3] -= offset
    row[7:10] -= offset
    moved._row = row
    return moved


class Static(_WMotion):
    """A fixed pose."""

    kind = "static"

    def __init__(self, position, quaternion=(1.0, 0.0, 0.0, 0.0)):
        xs = _validate.plain_floats((position, quaternion), (3, 4))
        norm = 0.0 if xs is None else math.hypot(xs[3], xs[4], xs[5], xs[6])
        if _validate.MIN_NORM <= norm < math.inf:
            p, q = xs[0:3], [xs[3] / norm, xs[4] / norm, xs[5] / norm, xs[6] / norm]
        else:  # the checks one field at a time, which name what is wrong
            p = _validate.floats(position, 3, "position")
            q = _validate.unit_quaternion(quaternion, "quaternion")
        self._row = np.array(p + q + p + q)  # the two-pose row of a motion that stays put

    @property
    def position(self):
        """(3,) world position."""
        return self._row[0:3]

    @property
    def quaternion(self):
        """(4,) unit quaternion [w, x, y, z]."""
        return self._row[3:7]

    def _scaled_inverse(self):
        return _pose_w(self.position, self.quaternion)

    def anchor(self):
        return self.position

    def exact_quadric_at(self, radii, t):
        return exact.quadric_exact_integer(radii, self.position, self.quaternion)

    def translated(self, offset):
        return _shifted(self, offset)


class _TwoPoses:
    """The motions that interpolate two poses (centre lerp): validated poses in ``_row`` = [p0, q0, p1, q1]."""

    @property
    def position0(self):
        """(3,) centre at t = 0."""
        return self._row[0:3]

    @property
    def quaternion0(self):
        """(4,) unit quaternion at t = 0."""
        return self._row[3:7]

    @property
    def position1(self):
        """(3,) centre at t = 1."""
        return self._row[7:10]

    @property
    def quaternion1(self):
        """(4,) unit quaternion at t = 1 (for :class:`Rigid`, on the side of quaternion0)."""
        return self._row[10:14]

    def anchor(self):
        return self.position0

    def translated(self, offset):
        return _shifted(self, offset)

    def factor(self):
        return None

    quadric_on = Motion.quadric_on

    def quadric_bounded_on(self, radii, t0, t1):
        """The centre lerp in this frame (unit 1): :func:`pose_side_errors`, plus the restriction's rounding."""
        radii = np.asarray(radii, float)
        C = centre_extent(self.position0, self.position1, np.zeros(3), np.zeros(3), 1.0)
        err = pose_side_errors(radii, 1.0, C, False, np.empty((4, 4)))
        return (*self.quadric_on(radii, t0, t1), 1.25 * err)  # restriction: gamma_12 more than gamma_80 and up

    def _exact_pose_at(self, t):
        """Centre and (unnormalised) quaternion lerps at the rational time t, exactly."""
        lerp = [(1 - t) * Fraction(float(x)) + t * Fraction(float(y)) for x, y in zip(self.position0, self.position1)]
        return lerp, [(1 - t) * Fraction(float(x)) + t * Fraction(float(y))
                      for x, y in zip(self.quaternion0, self.quaternion1)]


class Rigid(_TwoPoses, _WMotion):
    """Centre lerp and quaternion lerp: ``R(t) = rot(q(t)) / |q(t)|^2``, rational of degree 2."""

    kind = "rigid"

    def __init__(self, position0, quaternion0, position1, quaternion1):
        self._row = _pose_row(position0, quaternion0, position1, quaternion1, True)

    def _scaled_inverse(self):
        """W of the quaternion lerp followed by the centre lerp, formed from this motion's own poses."""
        rot = w_of_rotation(_linear_bernstein(self.quaternion0, self.quaternion1))
        shift = w_of_translation(_linear_bernstein(self.position0, self.position1))
        return w_compose(*shift, *rot)

    def quadric(self, radii):
        return quadric_rigid(np.asarray(radii, float), self.position0, self.quaternion0,
                             self.position1, self.quaternion1)

    def exact_quadric_at(self, radii, t):
        return exact.quadric_exact_integer(radii, *self._exact_pose_at(t))


class Affine(_TwoPoses, Motion):
    """The thesis' affine interpolant: centre and shape matrix ``Q = R D R^T`` both lerped."""

    kind = "affine"

    def __init__(self, position0, quaternion0, position1, quaternion1):
        self._row = _pose_row(position0, quaternion0, position1, quaternion1, False)

    def quadric(self, radii):
        return quadric_affine(np.asarray(radii, float), self.position0, self.quaternion0,
                              self.position1, self.quaternion1)

    def exact_quadric_at(self, radii, t):
        """Shape matrices and centres lerped, exactly: [[Q, -Q c], [-c^T Q, c^T Q c - 1]]."""
        zero = (0.0, 0.0, 0.0)
        Q0 = exact.quadric_exact(radii, zero, self.quaternion0)
        Q1 = exact.quadric_exact(radii, zero, self.quaternion1)
        c, _ = self._exact_pose_at(t)
        Q = [[(1 - t) * Q0[i][j] + t * Q1[i][j] for j in range(3)] for i in range(3)]
        Qc = [sum(Q[i][k] * c[k] for k in range(3)) for i in range(3)]
        out = [row + [-Qc[i]] for i, row in enumerate(Q)]
        return out + [[-x for x in Qc] + [sum(c[i] * Qc[i] for i in range(3)) - 1]]



class LinearAffine(_WMotion):
    """``x = ((1 - t) M0 + t M1) [y; 1]`` with 3x4 matrices: every point moves on a line.

    Refused (InputError) when det L(t) of the linear part changes sign on
    [0, 1] or comes within 1e-12 of singular: min |det L(t)| <= 1e-12 *
    max(|L0|_F, |L1|_F)^3, a body flattened below 1e-12 of its size.
    """

    kind = "linear_affine"

    def __init__(self, start, end):
        self.start = _validate.array(start, (3, 4), "start")
        self.end = _validate.array(end, (3, 4), "end")
        adj, det = bz.adjugate3(_linear_bernstein(self.start[:, :3], self.end[:, :3]))  # of L(t): (3, 3, 2)
        _not_flattened(det, max(np.linalg.norm(self.start[:, :3]), np.linalg.norm(self.end[:, :3])))
        super().__init__(adj, self._h(adj, np.zeros(3)), det)

    def _h(self, adj, offset):
        """-adj(L) (v - offset), the translation lerp v shifted before it is multiplied."""
        return -_matvec_poly(adj, _linear_bernstein(self.start[:, 3] - offset, self.end[:, 3] - offset))

    def anchor(self):
        return self.start[:, 3]

    def translated(self, offset):
        adj, _, det = self._w
        return _WMotion(adj, self._h(adj, offset), det)



class Rational(_WMotion):
    """A rational rigid motion ``x = R(t) y + V(t)`` (thesis §5.1).

    ``R = rotation(t) / rotation_denominator(t)``, ``V = translation(t) /
    translation_denominator(t)``; all polynomials in power basis, lowest
    degree first.  R must be a rotation for every t (checked exactly as a
    polynomial identity ``rotation rotation^T = denominator^2 I``).
    """

    kind = "rational"

    def __init__(self, rotation, rotation_denominator, translation, translation_denominator=(1.0,)):
        if not isinstance(rotation, (list, tuple, np.ndarray)) or len(rotation) != 3 \
                or any(not isinstance(r, (list, tuple, np.ndarray)) or len(r) != 3 for r in rotation):
            raise InputError("rotation: expected a 3x3 array of polynomials")
        rot = [[_validate.polynomial(rotation[i][j], f"rotation[{i}][{j}]") for j in range(3)] for i in range(3)]
        rd = _validate.polynomial(rotation_denominator, "rotation_denominator")
        if not isinstance(translation, (list, tuple, np.ndarray)) or len(translation) != 3:
            raise InputError("translation: expected 3 polynomials")
        tr = [_validate.polynomial(translation[i], f"translation[{i}]") for i in range(3)]
        vd = _validate.polynomial(translation_denominator, "translation_denominator")
        _nonvanishing(rd, "rotation_denominator")
        _nonvanishing(vd, "translation_denominator")
        self._check_rotation(rot, rd)
        deg_r = max(len(p) for row in rot for p in row) - 1
        deg_r = max(deg_r, len(rd) - 1)
        deg_v = max(max(len(p) for p in tr) - 1, len(vd) - 1)

        def bern(p, deg):
            return bz.from_power(np.pad(p, (0, deg + 1 - len(p))))

        Rn = np.array([[bern(rot[i][j], deg_r) for j in range(3)] for i in range(3)])
        Vn = np.array([bern(tr[i], deg_v) for i in range(3)])
        rdb, vdb = bern(rd, deg_r), bern(vd, deg_v)
        G = np.empty((3, 3, deg_r + deg_v + 1))
        for i in range(3):
            for j in range(3):
                G[i, j] = bz.multiply(Rn[j, i].copy(), vdb)
        self._RnT = np.ascontiguousarray(np.transpose(Rn, (1, 0, 2)))
        self._Vn, self._vdb = Vn, vdb
        super().__init__(G, -_matvec_poly(self._RnT, Vn), bz.multiply(rdb, vdb))
        self.rotation, self.rotation_denominator = rot, rd
        self.translation, self.translation_denominator = tr, vd

    def anchor(self):
        return self._Vn[:, 0] / self._vdb[0]

    def translated(self, offset):
        """V - offset = (Vn - offset vd) / vd: the offset leaves the numerators before the rotation multiplies them."""
        G, _, g = self._w
        return _WMotion(G, -_matvec_poly(self._RnT, self._Vn - offset[:, None] * self._vdb[None, :]), g)

    @staticmethod
    def _check_rotation(rot, rd):
        P = np.polynomial.polynomial
        rd2 = P.polymul(rd, rd)
        scale = max(np.abs(rd2).max(), 1e-300)
        for i in range(3):
            for j in range(3):
                acc = np.zeros(1)
                for k in range(3):
                    acc = P.polyadd(acc, P.polymul(rot[i][k], rot[j][k]))
                if i == j:
                    acc = P.polysub(acc, rd2)
                if not (np.isfinite(acc).all() and np.isfinite(scale)):
                    raise InputError(f"rotation: row {i} . row {j} overflows (coefficients too large)")
                if np.abs(acc).max() > 1e-9 * scale:
                    raise InputError(f"rotation: not orthogonal (row {i} . row {j} differs from "
                                     f"{'the denominator squared' if i == j else '0'} by "
                                     f"{np.abs(acc).max():.3g})")
        R0 = np.array([[P.polyval(0.0, rot[i][j]) for j in range(3)] for i in range(3)]) / P.polyval(0.0, rd)
        if np.linalg.det(R0) < 0.0:
            raise InputError("rotation: is a reflection (determinant -1), not a rotation")



# ---------------------------------------------------------------- chains


class Fixed:
    """Constant transform x -> R(q) x + p inside a chain."""

    def __init__(self, position, quaternion=(1.0, 0.0, 0.0, 0.0)):
        self.position = _validate.vector(position, 3, "position")
        self.quaternion = _validate.quaternion(quaternion, "quaternion")

    def w(self):
        return _pose_w(self.position, self.quaternion)


def _unit_axis(axis):
    """The validated joint axis, normalised (scaled first, so that huge entries do not overflow)."""
    axis = _validate.direction(axis, 3, "axis")
    return axis / np.sqrt(axis @ axis)


class Hinge:
    """Rotation about ``axis`` (through the frame origin) with tan(theta/2) linear in t."""

    def __init__(self, axis, angle0, angle1):
        self.axis = _unit_axis(axis)
        for name, a in (("angle[0]", angle0), ("angle[1]", angle1)):
            if not np.isfinite(a) or abs(a) >= np.pi:
                raise InputError(f"{name}: hinge angle must be finite with |angle| < pi, got {a}")
        self.angle0, self.angle1 = float(angle0), float(angle1)

    def w(self):
        tau = _linear_bernstein(np.tan(self.angle0 / 2), np.tan(self.angle1 / 2))
        qc = np.empty((4, 2))
        qc[0] = 1.0
        qc[1:] = self.axis[:, None] * tau[None, :]
        return w_of_rotation(qc)


class Slide:
    """Translation ``s(t) * axis`` with s linear in t."""

    def __init__(self, axis, displacement0, displacement1):
        self.axis = _unit_axis(axis)
        self.displacement0 = _validate.scalar(displacement0, "displacement[0]")
        self.displacement1 = _validate.scalar(displacement1, "displacement[1]")

    def w(self):
        return w_of_translation(_linear_bernstein(self.axis * self.displacement0, self.axis * self.displacement1))


class Ball:
    """Free rotation with quaternion lerp (as in :class:`Rigid`)."""

    def __init__(self, quaternion0, quaternion1):
        self.quaternion0 = _validate.quaternion(quaternion0, "start")
        self.quaternion1 = _aligned(self.quaternion0, _validate.quaternion(quaternion1, "end"))

    def w(self):
        return w_of_rotation(_linear_bernstein(self.quaternion0, self.quaternion1))


class Free(Rigid):
    """A free joint inside a chain: the same interpolation as :class:`Rigid`."""

    def w(self):
        return self._w


class Chain(_WMotion):
    """Articulated composition ``x = E1(E2(...En(y)))``: the first element is closest to the world.

    Elements are :class:`Fixed`, :class:`Hinge`, :class:`Slide`, :class:`Ball`
    and :class:`Free`.  The result is exact; its degree grows with the
    number of moving joints (each rotating joint adds 2 to the rational
    degree of the rotation).
    """

    kind = "chain"

    def __init__(self, elements):
        elements = list(elements)
        if not elements:
            raise InputError("elements: a chain needs at least one element")
        W = None
        for k, el in enumerate(elements):
            if not hasattr(el, "w"):
                raise InputTypeError(f"elements[{k}]: not a chain element: {el!r}")
            Wk = el.w()
            W = Wk if W is None else w_compose(*W, *Wk)
        self.elements = elements
        super().__init__(*W)

    def translated(self, offset):
        """The chain seen from ``offset``, composed again with the offset taken off its root's own position.

        A root :class:`Fixed` or :class:`Free` (a MuJoCo body's offset or free
        joint) is shifted before the composition multiplies it, so a chain far
        from the world origin loses nothing to the distance; a chain whose
        first element is a joint at the world origin gets a leading shift.
        """
        offset = np.asarray(offset, float)
        first = self.elements[0]
        if type(first) is Fixed:
            root = [Fixed(first.position - offset, first.quaternion)]
        elif type(first) is Free:
            root = [Free(first.position0 - offset, first.quaternion0, first.position1 - offset, first.quaternion1)]
        else:
            root = [Fixed(-offset), first]
        return Chain(root + self.elements[1:])

