"""Cheap conservative filters in front of the exact solver: moving spheres and separating planes.

Both filters only ever answer "free over the whole step" or "don't know"; a pair
they cannot clear goes to :mod:`mjccd.ccd`.

* **Moving bounding spheres** (thesis §5.4.1).  Each ellipsoid is enclosed by a
  sphere whose centre moves linearly over the step; the squared distance of two
  such centres minus the squared sum of radii is a quadratic in t, solved in
  closed form.  The entry time it returns is a lower bound of the pair's first
  contact, which orders the exact solves of a frame.
* **Separating-plane witness** (thesis §4.2–4.3).  A plane
  ``n(t) . x + d(t) = 0`` whose coefficients are linear in t separates two
  moving ellipsoids over [0, 1] exactly when, for each ellipsoid with centre
  c(t) and inverse shape matrix ``Q(t)^-1 = T(t) / den(t)``,

      h(t) = -+(n(t) . c(t) + d(t)) > sqrt(n(t)^T Q(t)^-1 n(t)).

  Squared, ``G(t) = h(t)^2 den(t) - n(t)^T T(t) n(t) > 0`` (a polynomial of
  degree 8 in t for rigid and affine motions) together with ``h(0) > 0``: h
  cannot change sign while G stays positive, because at a zero of h,
  G = -n^T T n < 0.  G > 0 is decided on the Bernstein coefficients of G with
  subdivision; a rounding margin keeps the answer conservative, and a case
  that cannot be certified is simply handed on.  For rigid motions T is kept
  factored, ``T = sum_m U_m U_m^T`` with U_m the semi-axis vectors (degree 2),
  so ``n^T T n`` is a sum of three squares of cubics.
* **Plane cache**: the normal that held is kept in the first ellipsoid's frame
  and tried first in the next frame (:mod:`mjccd.scene` drives it).
* **Slabs** (:func:`slabs_clear`, the scene's cheap yes/no test
  :func:`mjccd.scene.may_touch_kernel`): a fixed normal n, the centres' gap
  along n (linear in t) against bounds of both supports that hold over the
  whole step; no polynomial, no subdivision.

For chains and other rational motions, :func:`moving_sphere` bounds the
centre's rational curve by its chord plus the largest Bernstein coefficient of
the deviation over the smallest coefficient of the denominator.
"""
import numba
import numpy as np

from mjccd import bernstein as bz
from mjccd.errors import InputError, InputTypeError
from mjccd.quadric import Ellipsoid

# compiled on first use and cached; no cfunc wrapper (no kernel is passed around as a first-class function);
# forceinline=False: numba hands a caller's forceinline down to the callees it compiles
_jit = numba.njit(cache=True, nogil=True, no_cfunc_wrapper=True, forceinline=False)
# hot-path helpers: compiled once, then inlined by LLVM into each caller (no call, no reference counting of
# array arguments); inline="always" copied their numba IR into every caller instead, which multiplied
# compile time (docs/benchmarks.md, "First use")
_inline = numba.njit(cache=True, nogil=True, no_cfunc_wrapper=True, forceinline=True)

EPS = 2.220446049250313e-16
SPHERE_INFLATE = 1e-9        # relative growth of the summed radii: rounding never hides an entry
PLANE_MARGIN = 1e-11         # relative rounding margin on the Bernstein coefficients of G
PLANE_DEPTH = 8              # subdivision depth of the positivity test
SLAB_MARGIN = 1e-6           # relative clearance a slab must leave: closer pairs the exact solver may call touching
WORK_SHAPE = (PLANE_DEPTH + 4, 10)  # scratch rows of the witness kernels (subdivision stack, n^T T n)
INV_B8 = (1.0, 1 / 8, 1 / 28, 1 / 56, 1 / 70, 1 / 56, 1 / 28, 1 / 8, 1.0)  # scaled -> plain Bernstein, degree 8


# ---------------------------------------------------------------- moving spheres


@_inline
def relative_sweep(ca0, ca1, qa0, qa1, ra, cb0, cb1, qb0, qb1, rb):
    """Bound on how far any point of b moves relative to any point of a over the step.

    |Δc_b - Δc_a| plus, per body, the chord its largest semi-axis ``r`` sweeps:
    2 sin(θ/2) r with cos(θ/2) = |q0 . q1| / (|q0| |q1|).  Holds for the rigid
    lerp (the rotation runs along the arc from q0 to q1) and for the affine
    lerp (|(R1 - R0) y| <= 2 sin(θ/2) |y|), and for any sub-interval of the step.
    """
    dx = (cb1[0] - cb0[0]) - (ca1[0] - ca0[0])
    dy = (cb1[1] - cb0[1]) - (ca1[1] - ca0[1])
    dz = (cb1[2] - cb0[2]) - (ca1[2] - ca0[2])
    return np.sqrt(dx * dx + dy * dy + dz * dz) + _chord(qa0, qa1, ra) + _chord(qb0, qb1, rb)


@_inline
def _chord(q0, q1, r):
    """Largest displacement of a point at distance r from the centre under the rotation q0 -> q1."""
    dot = q0[0] * q1[0] + q0[1] * q1[1] + q0[2] * q1[2] + q0[3] * q1[3]
    n0 = q0[0] * q0[0] + q0[1] * q0[1] + q0[2] * q0[2] + q0[3] * q0[3]
    n1 = q1[0] * q1[0] + q1[1] * q1[1] + q1[2] * q1[2] + q1[3] * q1[3]
    cos2 = min(1.0, dot * dot / (n0 * n1))
    return 2.0 * np.sqrt(1.0 - cos2) * r * (1.0 + 1e-12) + 1e-15 * r


@_inline
def sphere_entry(ca0, ca1, ra, cb0, cb1, rb):
    """First t in [0, 1] at which two spheres with linearly moving centres touch, or -1.

    ``d(t) = |c_b(t) - c_a(t)|^2 - (ra + rb)^2`` is a quadratic; the pair is free
    when d > 0 on [0, 1].  The summed radius is inflated by a relative 1e-9, so
    the returned time never exceeds the exact entry time.
    """
    d0x = cb0[0] - ca0[0]
    d0y = cb0[1] - ca0[1]
    d0z = cb0[2] - ca0[2]
    vx = (cb1[0] - ca1[0]) - d0x
    vy = (cb1[1] - ca1[1]) - d0y
    vz = (cb1[2] - ca1[2]) - d0z
    reach = (ra + rb) * (1.0 + SPHERE_INFLATE)
    a = vx * vx + vy * vy + vz * vz
    b = 2.0 * (d0x * vx + d0y * vy + d0z * vz)
    c = d0x * d0x + d0y * d0y + d0z * d0z - reach * reach
    if c <= 0.0:
        return 0.0
    if b >= 0.0 or a == 0.0:
        return -1.0  # distance grows (or stays) from a positive start
    disc = b * b - 4.0 * a * c
    if disc < 0.0:
        return -1.0
    t = 2.0 * c / (-b + np.sqrt(disc))  # smaller root, without cancellation
    if t > 1.0:
        return -1.0
    return max(0.0, t * (1.0 - 1e-12))


# ---------------------------------------------------------------- slabs
#
# Ellipsoids given by positions p (N, 3) and unit quaternions q (N, 4) at t = 0
# and t = 1 (p0, q0, p1, q1), moving as the scene moves them (centres lerped).


@_inline
def _support_unit(radii, q, e, nx, ny, nz):
    """Support value sqrt(sum_k (r_k (R[:, k] . n))^2) of ellipsoid e (centred) with unit quaternion q[e]."""
    w, x, y, z = q[e, 0], q[e, 1], q[e, 2], q[e, 3]
    # columns of the rotation matrix of (w, x, y, z), dotted with n
    c0 = (1.0 - 2.0 * (y * y + z * z)) * nx + 2.0 * (x * y + w * z) * ny + 2.0 * (x * z - w * y) * nz
    c1 = 2.0 * (x * y - w * z) * nx + (1.0 - 2.0 * (x * x + z * z)) * ny + 2.0 * (y * z + w * x) * nz
    c2 = 2.0 * (x * z + w * y) * nx + 2.0 * (y * z - w * x) * ny + (1.0 - 2.0 * (x * x + y * y)) * nz
    a = radii[e, 0] * c0
    b = radii[e, 1] * c1
    c = radii[e, 2] * c2
    return np.sqrt(a * a + b * b + c * c)


@_inline
def _swept_support(affine, radii, rmax, q0, q1, e, nx, ny, nz):
    """Upper bound, over the whole step, of ellipsoid e's support in direction n (about its centre).

    Exact for a constant orientation; for the affine lerp the larger of the two
    ends (the inverse of the lerped quadric is convex in t); else the largest
    semi-axis.
    """
    same = True
    opposite = True
    for m in range(4):
        same = same and q0[e, m] == q1[e, m]
        opposite = opposite and q0[e, m] == -q1[e, m]
    if same or opposite:
        return _support_unit(radii, q0, e, nx, ny, nz)
    if affine:
        return max(_support_unit(radii, q0, e, nx, ny, nz), _support_unit(radii, q1, e, nx, ny, nz))
    return rmax[e]


@_inline
def _slab_clear(affine, radii, rmax, p0, q0, p1, q1, i, j, nx, ny, nz, tol):
    """True when planes normal to the unit vector n separate ellipsoids i and j during the whole step.

    The centre gap along n is linear in t, so its minimum is at an end; it
    must exceed both supports' bounds over the step by more than ``tol``.
    """
    g0 = (p0[j, 0] - p0[i, 0]) * nx + (p0[j, 1] - p0[i, 1]) * ny + (p0[j, 2] - p0[i, 2]) * nz
    g1 = (p1[j, 0] - p1[i, 0]) * nx + (p1[j, 1] - p1[i, 1]) * ny + (p1[j, 2] - p1[i, 2]) * nz
    if g0 < 0.0:
        g0, g1, nx, ny, nz = -g0, -g1, -nx, -ny, -nz
    gap = min(g0, g1)
    if gap <= tol:
        return False
    return gap - _swept_support(affine, radii, rmax, q0, q1, i, nx, ny, nz) \
        - _swept_support(affine, radii, rmax, q0, q1, j, nx, ny, nz) > tol


@_inline
def _thin_axis(radii, q, e):
    """World direction, at unit quaternion q[e], of ellipsoid e's shortest semi-axis."""
    k = 0
    if radii[e, 1] < radii[e, k]:
        k = 1
    if radii[e, 2] < radii[e, k]:
        k = 2
    w, x, y, z = q[e, 0], q[e, 1], q[e, 2], q[e, 3]
    if k == 0:
        return 1.0 - 2.0 * (y * y + z * z), 2.0 * (x * y + w * z), 2.0 * (x * z - w * y)
    if k == 1:
        return 2.0 * (x * y - w * z), 1.0 - 2.0 * (x * x + z * z), 2.0 * (y * z + w * x)
    return 2.0 * (x * z + w * y), 2.0 * (y * z - w * x), 1.0 - 2.0 * (x * x + y * y)


@_inline
def slabs_clear(affine, radii, rmax, p0, q0, p1, q1, i, j):
    """True when a slab keeps ellipsoids i and j apart during the whole step (rigid or ``affine`` lerp).

    Tries the centre line at t = 0 and at t = 1 and each ellipsoid's thinnest
    axis at t = 0.  A slab must leave a clearance of ``SLAB_MARGIN`` times the
    summed largest semi-axes, more than rounding and more than the exact
    solver's own band: a pair cleared here is one the solver finds free.
    """
    tol = SLAB_MARGIN * (rmax[i] + rmax[j])
    d0x, d0y, d0z = p0[j, 0] - p0[i, 0], p0[j, 1] - p0[i, 1], p0[j, 2] - p0[i, 2]
    d1x, d1y, d1z = p1[j, 0] - p1[i, 0], p1[j, 1] - p1[i, 1], p1[j, 2] - p1[i, 2]
    n0 = np.sqrt(d0x * d0x + d0y * d0y + d0z * d0z)
    if n0 > 0.0 and _slab_clear(affine, radii, rmax, p0, q0, p1, q1, i, j, d0x / n0, d0y / n0, d0z / n0, tol):
        return True
    n1 = np.sqrt(d1x * d1x + d1y * d1y + d1z * d1z)
    if n1 > 0.0 and _slab_clear(affine, radii, rmax, p0, q0, p1, q1, i, j, d1x / n1, d1y / n1, d1z / n1, tol):
        return True
    ax, ay, az = _thin_axis(radii, q0, i)
    if _slab_clear(affine, radii, rmax, p0, q0, p1, q1, i, j, ax, ay, az, tol):
        return True
    ax, ay, az = _thin_axis(radii, q0, j)
    return _slab_clear(affine, radii, rmax, p0, q0, p1, q1, i, j, ax, ay, az, tol)


# ---------------------------------------------------------------- inverse shape polynomials


@_inline
def support_rigid(radii, q0, q1, U, den, e):
    """Fill U[e] (3, 3, 3) and den[e] (5,) so that ``Q(t)^-1 = sum_m U_m(t) U_m(t)^T / den(t)`` (rigid motion).

    Ellipsoid e has semi-axes ``radii[e]`` and quaternions ``q0[e]``, ``q1[e]``
    (sign-aligned) at t = 0 and 1.  Scaled Bernstein form (coefficient k times
    C(degree, k)).  With q lerped, ``Q^-1 = rot(q) diag(r^2) rot(q)^T / |q|^4``:
    ``U[e, m, :, k]`` is r_m times column m of rot(q) (degree 2) and
    ``den = |q|^4`` (degree 4).  Keeping the factor instead of the product
    makes ``n^T Q^-1 n`` a sum of three squares.
    """
    a0, a1, a2, a3 = q0[e, 0], q0[e, 1], q0[e, 2], q0[e, 3]
    b0, b1, b2, b3 = q1[e, 0], q1[e, 1], q1[e, 2], q1[e, 3]
    r0, r1, r2 = radii[e, 0], radii[e, 1], radii[e, 2]
    for k in range(3):
        # rot(q(t)) in scaled Bernstein form of degree 2: a product of two lerps
        # [a0, a1] [b0, b1] is [a0 b0, a0 b1 + a1 b0, a1 b1]
        if k == 0:
            w, x, y, z, w2, x2, y2, z2 = a0, a1, a2, a3, a0, a1, a2, a3
        elif k == 1:
            w, x, y, z, w2, x2, y2, z2 = a0, a1, a2, a3, b0, b1, b2, b3
        else:
            w, x, y, z, w2, x2, y2, z2 = b0, b1, b2, b3, b0, b1, b2, b3
        s = 2.0 if k == 1 else 1.0      # the middle coefficient is the symmetrised product
        ww = s * w * w2
        xx = s * x * x2
        yy = s * y * y2
        zz = s * z * z2
        xy = x * y2 + y * x2 if k == 1 else x * y
        xz = x * z2 + z * x2 if k == 1 else x * z
        yz = y * z2 + z * y2 if k == 1 else y * z
        wx = w * x2 + x * w2 if k == 1 else w * x
        wy = w * y2 + y * w2 if k == 1 else w * y
        wz = w * z2 + z * w2 if k == 1 else w * z
        U[e, 0, 0, k] = r0 * (ww + xx - yy - zz)
        U[e, 0, 1, k] = r0 * 2.0 * (xy + wz)
        U[e, 0, 2, k] = r0 * 2.0 * (xz - wy)
        U[e, 1, 0, k] = r1 * 2.0 * (xy - wz)
        U[e, 1, 1, k] = r1 * (ww - xx + yy - zz)
        U[e, 1, 2, k] = r1 * 2.0 * (yz + wx)
        U[e, 2, 0, k] = r2 * 2.0 * (xz + wy)
        U[e, 2, 1, k] = r2 * 2.0 * (yz - wx)
        U[e, 2, 2, k] = r2 * (ww - xx - yy + zz)
    g0 = a0 * a0 + a1 * a1 + a2 * a2 + a3 * a3
    g1 = 2.0 * (a0 * b0 + a1 * b1 + a2 * b2 + a3 * b3)
    g2 = b0 * b0 + b1 * b1 + b2 * b2 + b3 * b3
    den[e, 0] = g0 * g0
    den[e, 1] = 2.0 * g0 * g1
    den[e, 2] = g1 * g1 + 2.0 * g0 * g2
    den[e, 3] = 2.0 * g1 * g2
    den[e, 4] = g2 * g2


@_jit
def support_affine(radii, q0, q1, T, den, e, scratch):
    """Fill T[e] (3, 3, 5) and den[e] (5,) with adj Q(t) and det Q(t) for the affine interpolant.

    ``Q(t) = (1 - t) Q0 + t Q1`` is the lerped shape matrix, so
    ``Q^-1 = adj(Q) / det(Q)``; both are elevated to degree 4 (scaled form).
    Arguments as in :func:`support_rigid`; ``scratch`` is an (8, 3, 3) work array.
    """
    rotation_into(q0, scratch, e, 0)
    rotation_into(q1, scratch, e, 1)
    R0, R1, Q0, Q1 = scratch[0], scratch[1], scratch[2], scratch[3]
    for i in range(3):
        for j in range(3):
            a0 = 0.0
            a1 = 0.0
            for m in range(3):
                dm = 1.0 / (radii[e, m] * radii[e, m])
                a0 += R0[i, m] * R0[j, m] * dm
                a1 += R1[i, m] * R1[j, m] * dm
            Q0[i, j] = a0
            Q1[i, j] = a1
    adj = scratch[4:7]  # adj[c] = coefficient c of adj Q (power basis in (1 - t), t: degree 2)
    for i in range(3):
        for j in range(3):
            i1, i2 = (j + 1) % 3, (j + 2) % 3
            j1, j2 = (i + 1) % 3, (i + 2) % 3
            # adj[i, j] = cofactor of Q[j, i] (Q symmetric): cyclic indices give the sign
            adj[0, i, j] = Q0[i1, j1] * Q0[i2, j2] - Q0[i1, j2] * Q0[i2, j1]
            adj[1, i, j] = (Q0[i1, j1] * Q1[i2, j2] - Q0[i1, j2] * Q1[i2, j1]
                            + Q1[i1, j1] * Q0[i2, j2] - Q1[i1, j2] * Q0[i2, j1])
            adj[2, i, j] = Q1[i1, j1] * Q1[i2, j2] - Q1[i1, j2] * Q1[i2, j1]
    d0 = d1 = d2 = d3 = 0.0
    for j in range(3):
        d0 += Q0[0, j] * adj[0, j, 0]
        d1 += Q0[0, j] * adj[1, j, 0] + Q1[0, j] * adj[0, j, 0]
        d2 += Q0[0, j] * adj[2, j, 0] + Q1[0, j] * adj[1, j, 0]
        d3 += Q1[0, j] * adj[2, j, 0]
    for i in range(3):
        for j in range(3):
            c0, c1, c2 = adj[0, i, j], adj[1, i, j], adj[2, i, j]
            T[e, i, j, 0] = c0
            T[e, i, j, 1] = 2.0 * c0 + c1
            T[e, i, j, 2] = c0 + 2.0 * c1 + c2
            T[e, i, j, 3] = c1 + 2.0 * c2
            T[e, i, j, 4] = c2
    den[e, 0] = d0
    den[e, 1] = d0 + d1
    den[e, 2] = d1 + d2
    den[e, 3] = d2 + d3
    den[e, 4] = d3


@_inline
def rotation_into(q, R, e, r):
    """Write the rotation matrix of the unit quaternion q[e] = [w, x, y, z] into R[r] (3, 3)."""
    w, x, y, z = q[e, 0], q[e, 1], q[e, 2], q[e, 3]
    R[r, 0, 0] = w * w + x * x - y * y - z * z
    R[r, 0, 1] = 2.0 * (x * y - w * z)
    R[r, 0, 2] = 2.0 * (x * z + w * y)
    R[r, 1, 0] = 2.0 * (x * y + w * z)
    R[r, 1, 1] = w * w - x * x + y * y - z * z
    R[r, 1, 2] = 2.0 * (y * z - w * x)
    R[r, 2, 0] = 2.0 * (x * z - w * y)
    R[r, 2, 1] = 2.0 * (y * z + w * x)
    R[r, 2, 2] = w * w - x * x - y * y + z * z


# ---------------------------------------------------------------- separating-plane witness
#
# The kernels work on the arrays of all ellipsoids of a frame and take indices:
# S (N, 3, 3, 3) holds the rigid factors U of :func:`support_rigid`, or
# S (N, 3, 3, 5) the matrices T of :func:`support_affine` (the last axis tells
# them apart), den (N, 5) the denominators, R0/R1 (N, 3, 3) the rotations at
# t = 0 and 1.  Normals and centres are 3-tuples (or length-3 arrays).  Indexing
# whole arrays instead of taking per-ellipsoid views keeps the hot path free of
# reference counting.


@_inline
def support_at(S, den, e, n, k):
    """Support radius sqrt(n^T Q^-1 n) of ellipsoid e at the end k = 0 (t = 0) or k = 4 (t = 1)."""
    acc = 0.0
    if S.shape[3] == 3:
        c = k // 2
        for m in range(3):
            s = n[0] * S[e, m, 0, c] + n[1] * S[e, m, 1, c] + n[2] * S[e, m, 2, c]
            acc += s * s
    else:
        for i in range(3):
            for j in range(3):
                acc += n[i] * S[e, i, j, k] * n[j]
    return np.sqrt(max(acc, 0.0) / den[e, k])


@_inline
def _normal_form(S, e, n0, n1, work, row):
    """Write n(t)^T Q^-1(t) den(t) n(t) (degree 6, scaled) into work[row, :7]; return its rounding scale.

    The scale bounds the sum of absolute values of the products behind any
    coefficient, so a margin relative to it covers the rounding.
    """
    for a in range(7):
        work[row, a] = 0.0
    if S.shape[3] == 3:
        # sum of squares of s_m(t) = n(t) . U_m(t) (degree 3): |coefficient| <= 16 |n|^2 |U|^2 (Cauchy-Schwarz)
        su = 0.0
        for m in range(3):
            s0 = n0[0] * S[e, m, 0, 0] + n0[1] * S[e, m, 1, 0] + n0[2] * S[e, m, 2, 0]
            s1 = (n0[0] * S[e, m, 0, 1] + n0[1] * S[e, m, 1, 1] + n0[2] * S[e, m, 2, 1]
                  + n1[0] * S[e, m, 0, 0] + n1[1] * S[e, m, 1, 0] + n1[2] * S[e, m, 2, 0])
            s2 = (n0[0] * S[e, m, 0, 2] + n0[1] * S[e, m, 1, 2] + n0[2] * S[e, m, 2, 2]
                  + n1[0] * S[e, m, 0, 1] + n1[1] * S[e, m, 1, 1] + n1[2] * S[e, m, 2, 1])
            s3 = n1[0] * S[e, m, 0, 2] + n1[1] * S[e, m, 1, 2] + n1[2] * S[e, m, 2, 2]
            work[row, 0] += s0 * s0
            work[row, 1] += 2.0 * s0 * s1
            work[row, 2] += s1 * s1 + 2.0 * s0 * s2
            work[row, 3] += 2.0 * (s0 * s3 + s1 * s2)
            work[row, 4] += s2 * s2 + 2.0 * s1 * s3
            work[row, 5] += 2.0 * s2 * s3
            work[row, 6] += s3 * s3
            for i in range(3):
                for c in range(3):
                    su += S[e, m, i, c] * S[e, m, i, c]
        nn = 0.0
        for i in range(3):
            nn += n0[i] * n0[i] + n1[i] * n1[i]
        return 16.0 * nn * su
    for i in range(3):
        for j in range(3):
            for a in range(5):
                tij = S[e, i, j, a]
                work[row, a] += n0[i] * tij * n0[j]
                work[row, a + 1] += (n0[i] * n1[j] + n1[i] * n0[j]) * tij
                work[row, a + 2] += n1[i] * tij * n1[j]
    nmax = 0.0
    for a in range(7):
        nmax = max(nmax, abs(work[row, a]))
    return nmax


@_inline
def _positive8(work, margin):
    """True when the degree-8 Bernstein polynomial in work[0, :9] is > margin on [0, 1] (certified).

    Depth-first subdivision on the rows of ``work``; column 9 holds the depth
    of each stacked piece.  Fails as soon as an end value (an exact value of
    the polynomial) is not above the margin, or at depth PLANE_DEPTH.
    """
    work[0, 9] = 0.0
    top = 1
    while top > 0:
        top -= 1
        if work[top, 0] <= margin or work[top, 8] <= margin:
            return False
        lo = work[top, 1]
        for k in range(2, 8):
            lo = min(lo, work[top, k])
        if lo > margin:
            continue
        if work[top, 9] >= PLANE_DEPTH:
            return False
        # de Casteljau at 1/2: left half back into row top, right half into row top + 1
        nxt = top + 1
        for k in range(9):
            work[nxt, k] = work[top, k]
        for r in range(1, 9):
            for k in range(9 - r):
                work[nxt, k] = 0.5 * (work[nxt, k] + work[nxt, k + 1])
            work[top, r] = work[nxt, 0]
        work[top, 9] += 1.0
        work[nxt, 9] = work[top, 9]
        top += 2
    return True


@_inline
def _side_holds(n0, d0, n1, d1, c0, c1, S, den, e, sign, work):
    """True when ellipsoid e stays strictly on the side ``sign (n.x + d) > 0`` over [0, 1]."""
    # h(t) = sign (n(t) . c(t) + d(t)), scaled Bernstein degree 2
    h0 = sign * (n0[0] * c0[0] + n0[1] * c0[1] + n0[2] * c0[2] + d0)
    h1 = sign * (n0[0] * c1[0] + n0[1] * c1[1] + n0[2] * c1[2]
                 + n1[0] * c0[0] + n1[1] * c0[1] + n1[2] * c0[2] + d0 + d1)
    h2 = sign * (n1[0] * c1[0] + n1[1] * c1[1] + n1[2] * c1[2] + d1)
    if h0 <= 0.0:
        return False
    habs = max(abs(n0[0] * c0[0]) + abs(n0[1] * c0[1]) + abs(n0[2] * c0[2]) + abs(d0),
               abs(n1[0] * c1[0]) + abs(n1[1] * c1[1]) + abs(n1[2] * c1[2]) + abs(d1),
               0.5 * (abs(n0[0] * c1[0]) + abs(n0[1] * c1[1]) + abs(n0[2] * c1[2])
                      + abs(n1[0] * c0[0]) + abs(n1[1] * c0[1]) + abs(n1[2] * c0[2])
                      + abs(d0) + abs(d1)))
    # h^2 (degree 4, scaled)
    hh0 = h0 * h0
    hh1 = 2.0 * h0 * h1
    hh2 = h1 * h1 + 2.0 * h0 * h2
    hh3 = 2.0 * h1 * h2
    hh4 = h2 * h2
    nt = PLANE_DEPTH + 3  # row of n^T T n; G goes to row 0, where the positivity test starts
    nscale = _normal_form(S, e, n0, n1, work, nt)
    for a in range(9):
        work[0, a] = 0.0
    dmax = 0.0
    for a in range(5):
        da = den[e, a]
        dmax = max(dmax, abs(da))
        work[0, a] += hh0 * da
        work[0, a + 1] += hh1 * da
        work[0, a + 2] += hh2 * da
        work[0, a + 3] += hh3 * da
        work[0, a + 4] += hh4 * da
    # minus n^T T n elevated from degree 6 to 8 by the factor (1 - t + t)^2, then to plain Bernstein
    for a in range(7):
        v = work[nt, a]
        work[0, a] -= v
        work[0, a + 1] -= 2.0 * v
        work[0, a + 2] -= v
    for a in range(9):
        work[0, a] *= INV_B8[a]
    margin = PLANE_MARGIN * (habs * habs * dmax + nscale)
    return _positive8(work, margin)


@_inline
def plane_holds(n0, d0, n1, d1, ca0, ca1, cb0, cb1, S, den, ia, ib, work):
    """True when the plane lerped from (n0, d0) to (n1, d1) keeps A = ia below and B = ib above over [0, 1].

    ``ca*``/``cb*``: centres at t = 0 and 1.  Requires ``n0 . n1 > 0`` so
    that n(t) never vanishes.
    """
    if n0[0] * n1[0] + n0[1] * n1[1] + n0[2] * n1[2] <= 0.0:
        return False
    if not _side_holds(n0, d0, n1, d1, cb0, cb1, S, den, ib, 1.0, work):
        return False
    return _side_holds(n0, d0, n1, d1, ca0, ca1, S, den, ia, -1.0, work)


@_inline
def gap_offset(n, ca, cb, S, den, ia, ib, k):
    """Offset d putting the plane with normal n mid-way between A and B at end k (0 or 4).

    Returns (ok, d); ok is False when the projections of A and B on n overlap.
    """
    lo = n[0] * ca[0] + n[1] * ca[1] + n[2] * ca[2] + support_at(S, den, ia, n, k)
    hi = n[0] * cb[0] + n[1] * cb[1] + n[2] * cb[2] - support_at(S, den, ib, n, k)
    if not lo < hi:
        return False, 0.0
    return True, -0.5 * (lo + hi)


@_inline
def witness(n0, n1, ca0, ca1, cb0, cb1, S, den, ia, ib, work):
    """Try the plane with normal lerped from n0 to n1, centred in the gap at both ends."""
    ok0, d0 = gap_offset(n0, ca0, cb0, S, den, ia, ib, 0)
    if not ok0:
        return False
    ok1, d1 = gap_offset(n1, ca1, cb1, S, den, ia, ib, 4)
    if not ok1:
        return False
    return plane_holds(n0, d0, n1, d1, ca0, ca1, cb0, cb1, S, den, ia, ib, work)


@_inline
def _turn(R0, R1, e, n):
    """R1[e] R0[e]^T n: the normal n carried along by body e turning from R0[e] to R1[e]."""
    l0 = R0[e, 0, 0] * n[0] + R0[e, 1, 0] * n[1] + R0[e, 2, 0] * n[2]
    l1 = R0[e, 0, 1] * n[0] + R0[e, 1, 1] * n[1] + R0[e, 2, 1] * n[2]
    l2 = R0[e, 0, 2] * n[0] + R0[e, 1, 2] * n[1] + R0[e, 2, 2] * n[2]
    return (R1[e, 0, 0] * l0 + R1[e, 0, 1] * l1 + R1[e, 0, 2] * l2,
            R1[e, 1, 0] * l0 + R1[e, 1, 1] * l1 + R1[e, 1, 2] * l2,
            R1[e, 2, 0] * l0 + R1[e, 2, 1] * l1 + R1[e, 2, 2] * l2)


@_inline
def witness_variants(n0, ca0, ca1, cb0, cb1, R0, R1, S, den, ia, ib, work, first):
    """Try a world normal n0 held fixed (variant 1), turning with A (2) and turning with B (3).

    Variant ``first`` is tried first (the one that held last frame).  Returns
    (the variant that held or 0, its normal at t = 1 as a 3-tuple).
    """
    n1 = (n0[0], n0[1], n0[2])
    ok0, d0 = gap_offset(n0, ca0, cb0, S, den, ia, ib, 0)  # the same for every variant
    if not ok0:
        return 0, n1
    for step in range(3):
        v = (first - 1 + step) % 3 + 1
        if v == 1:
            n1 = (n0[0], n0[1], n0[2])
        elif v == 2:
            n1 = _turn(R0, R1, ia, n0)
        else:
            n1 = _turn(R0, R1, ib, n0)
        ok1, d1 = gap_offset(n1, ca1, cb1, S, den, ia, ib, 4)
        if ok1 and plane_holds(n0, d0, n1, d1, ca0, ca1, cb0, cb1, S, den, ia, ib, work):
            return v, n1
    return 0, n1


# ---------------------------------------------------------------- Python layer


def moving_sphere(ellipsoid, motion):
    """A sphere with linearly moving centre that encloses the ellipsoid for all t in [0, 1].

    Returns (centre_0, centre_1, radius).  Exact centres for static, rigid and
    affine motions (radius = largest semi-axis: the affine interpolant's
    shape matrix is a convex combination, so its smallest eigenvalue never
    drops below 1 / r_max^2).  Linear-affine motions scale the radius by the
    largest singular value of the linear part at either end.  Rational and
    chain motions (rigid, centre on a rational curve N(t) / D(t)) take the
    chord from c(0) to c(1) and add ``max_k |E_k| / min_k D_k`` with E the
    Bernstein coefficients of ``N - D * chord``; the radius is infinite when
    D's coefficients do not all share a sign.
    """
    from mjccd import motion as mo

    if not isinstance(ellipsoid, Ellipsoid):
        raise InputTypeError(f"ellipsoid: expected an mjccd.Ellipsoid, got {type(ellipsoid).__name__}")
    r = float(ellipsoid.radii.max())
    if isinstance(motion, (mo.Rigid, mo.Affine)):
        return motion.position0.copy(), motion.position1.copy(), r
    if isinstance(motion, mo.Static):
        return motion.position.copy(), motion.position.copy(), r
    if isinstance(motion, mo.LinearAffine):
        scale = max(np.linalg.norm(motion.start[:, :3], 2), np.linalg.norm(motion.end[:, :3], 2))
        return motion.start[:, 3].copy(), motion.end[:, 3].copy(), r * float(scale)
    if isinstance(motion, (mo.Chain, mo.Rational)):
        return _rational_centre_sphere(*motion.scaled_inverse_w(), r)
    raise InputError(f"motion: no bounding sphere for motion kind {getattr(motion, 'kind', type(motion).__name__)!r}")


def _rational_centre_sphere(G, h, g, r):
    """Chord plus deviation bound of the centre ``-adj(G) h / det(G)`` of a W-form rigid motion."""
    adj, det = bz.adjugate3(G)
    num = []
    for i in range(3):
        acc = np.zeros(1)
        for k in range(3):
            acc = bz.add(acc, -bz.multiply(adj[i][k], h[k].copy()))
        num.append(acc)
    deg = max(max(len(c) for c in num), len(det)) - 1
    num = [bz.elevate(c, deg + 1 - len(c)) for c in num]
    det = bz.elevate(det, deg + 1 - len(det))
    if det.min() <= 0.0 and det.max() >= 0.0:
        c = np.array([n[0] / det[0] for n in num])
        return c, np.array([n[-1] / det[-1] for n in num]), np.inf
    if det[0] < 0.0:
        det = -det
        num = [-c for c in num]
    c0 = np.array([n[0] / det[0] for n in num])
    c1 = np.array([n[-1] / det[-1] for n in num])
    # E(t) = N(t) - D(t) ((1 - t) c0 + t c1): D times a linear polynomial, degree deg + 1
    dev = 0.0
    chord = np.stack([c0, c1], axis=1)
    for k in range(deg + 2):
        e = np.empty(3)
        for i in range(3):
            e[i] = (bz.elevate(num[i], 1)[k] - bz.multiply(det, chord[i].copy())[k])
        dev = max(dev, float(np.linalg.norm(e)))
    bound = dev / det.min()
    return c0, c1, r + bound * (1.0 + 1e-9) + 1e-12 * (np.abs(c0).max() + np.abs(c1).max() + r)
