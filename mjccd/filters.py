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
  that cannot be certified is simply handed on.
* **Plane cache**: the normal that held is kept in the first ellipsoid's frame
  and tried first in the next frame (:mod:`mjccd.scene` drives it).

For chains and other rational motions, :func:`moving_sphere` bounds the
centre's rational curve by its chord plus the largest Bernstein coefficient of
the deviation over the smallest coefficient of the denominator.
"""
import numba
import numpy as np

from mjccd import bernstein as bz
from mjccd.quadric import Ellipsoid

_jit = numba.njit(cache=True, nogil=True)

EPS = 2.220446049250313e-16
SPHERE_INFLATE = 1e-9        # relative growth of the summed radii: rounding never hides an entry
PLANE_MARGIN = 1e-11         # relative rounding margin on the Bernstein coefficients of G
PLANE_DEPTH = 8              # subdivision depth of the positivity test
WORK_SHAPE = (PLANE_DEPTH + 4, 10)  # scratch rows of the witness kernels
B8 = (1.0, 8.0, 28.0, 56.0, 70.0, 56.0, 28.0, 8.0, 1.0)


# ---------------------------------------------------------------- moving spheres


@_jit
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


# ---------------------------------------------------------------- inverse shape polynomials


@_jit
def _qprod(q0, q1, a, b, k):
    """Scaled Bernstein coefficient k of q_a(t) q_b(t) for the lerp from q0 to q1."""
    if k == 0:
        return q0[a] * q0[b]
    if k == 1:
        return q0[a] * q1[b] + q1[a] * q0[b]
    return q1[a] * q1[b]


@_jit
def support_rigid(radii, q0, q1, T, den, scratch):
    """Fill T (3, 3, 5) and den (5,) so that ``Q(t)^-1 = T(t) / den(t)`` for a rigid motion.

    Scaled Bernstein form (coefficient k times C(4, k)).  With ``R = rot(q)/|q|^2``
    and q lerped, ``Q^-1 = R diag(r^2) R^T = rot diag(r^2) rot^T / |q|^4``.
    ``scratch`` is a (4, 3, 3) work array.
    """
    for i in range(3):
        for j in range(3):
            for k in range(5):
                T[i, j, k] = 0.0
    for k in range(5):
        den[k] = 0.0
    # rot(q(t)) in scaled Bernstein form of degree 2: a product of two lerps
    # [a0, a1] [b0, b1] is [a0 b0, a0 b1 + a1 b0, a1 b1]
    rot = scratch[:3]
    g = scratch[3, 0]
    for k in range(3):
        ww = _qprod(q0, q1, 0, 0, k)
        xx = _qprod(q0, q1, 1, 1, k)
        yy = _qprod(q0, q1, 2, 2, k)
        zz = _qprod(q0, q1, 3, 3, k)
        xy = _qprod(q0, q1, 1, 2, k)
        xz = _qprod(q0, q1, 1, 3, k)
        yz = _qprod(q0, q1, 2, 3, k)
        wx = _qprod(q0, q1, 0, 1, k)
        wy = _qprod(q0, q1, 0, 2, k)
        wz = _qprod(q0, q1, 0, 3, k)
        rot[0, 0, k] = ww + xx - yy - zz
        rot[0, 1, k] = 2.0 * (xy - wz)
        rot[0, 2, k] = 2.0 * (xz + wy)
        rot[1, 0, k] = 2.0 * (xy + wz)
        rot[1, 1, k] = ww - xx + yy - zz
        rot[1, 2, k] = 2.0 * (yz - wx)
        rot[2, 0, k] = 2.0 * (xz - wy)
        rot[2, 1, k] = 2.0 * (yz + wx)
        rot[2, 2, k] = ww - xx - yy + zz
        g[k] = ww + xx + yy + zz
    for i in range(3):
        for j in range(i, 3):
            for m in range(3):
                r2 = radii[m] * radii[m]
                for a in range(3):
                    ra_ = rot[i, m, a] * r2
                    for b in range(3):
                        T[i, j, a + b] += ra_ * rot[j, m, b]
            for k in range(5):
                T[j, i, k] = T[i, j, k]
    for a in range(3):
        for b in range(3):
            den[a + b] += g[a] * g[b]


@_jit
def support_affine(radii, q0, q1, T, den):
    """Fill T (3, 3, 5) and den (5,) with adj Q(t) and det Q(t) for the affine interpolant.

    ``Q(t) = (1 - t) Q0 + t Q1`` is the lerped shape matrix, so
    ``Q^-1 = adj(Q) / det(Q)``; both are elevated to degree 4 (scaled form).
    """
    R0 = _rotation(q0)
    R1 = _rotation(q1)
    Q = np.zeros((3, 3, 2))
    for i in range(3):
        for j in range(3):
            for m in range(3):
                dm = 1.0 / (radii[m] * radii[m])
                Q[i, j, 0] += R0[i, m] * R0[j, m] * dm
                Q[i, j, 1] += R1[i, m] * R1[j, m] * dm
    adj = np.zeros((3, 3, 3))
    for i in range(3):
        for j in range(3):
            i1, i2 = (j + 1) % 3, (j + 2) % 3
            j1, j2 = (i + 1) % 3, (i + 2) % 3
            # adj[i, j] = cofactor of Q[j, i] (Q symmetric): cyclic indices give the sign
            for a in range(2):
                for b in range(2):
                    adj[i, j, a + b] += Q[i1, j1, a] * Q[i2, j2, b] - Q[i1, j2, a] * Q[i2, j1, b]
    det3 = np.zeros(4)
    for j in range(3):
        for a in range(2):
            for b in range(3):
                det3[a + b] += Q[0, j, a] * adj[j, 0, b]
    for i in range(3):
        for j in range(3):
            c0, c1, c2 = adj[i, j, 0], adj[i, j, 1], adj[i, j, 2]
            T[i, j, 0] = c0
            T[i, j, 1] = 2.0 * c0 + c1
            T[i, j, 2] = c0 + 2.0 * c1 + c2
            T[i, j, 3] = c1 + 2.0 * c2
            T[i, j, 4] = c2
    den[0] = det3[0]
    den[1] = det3[0] + det3[1]
    den[2] = det3[1] + det3[2]
    den[3] = det3[2] + det3[3]
    den[4] = det3[3]


@_jit
def _rotation(q):
    """Rotation matrix of a unit quaternion [w, x, y, z]."""
    R = np.empty((3, 3))
    rotation_into(q, R)
    return R


@_jit
def rotation_into(q, R):
    """Write the rotation matrix of a unit quaternion [w, x, y, z] into R (3, 3)."""
    w, x, y, z = q[0], q[1], q[2], q[3]
    R[0, 0] = w * w + x * x - y * y - z * z
    R[0, 1] = 2.0 * (x * y - w * z)
    R[0, 2] = 2.0 * (x * z + w * y)
    R[1, 0] = 2.0 * (x * y + w * z)
    R[1, 1] = w * w - x * x + y * y - z * z
    R[1, 2] = 2.0 * (y * z - w * x)
    R[2, 0] = 2.0 * (x * z - w * y)
    R[2, 1] = 2.0 * (y * z + w * x)
    R[2, 2] = w * w - x * x - y * y + z * z


# ---------------------------------------------------------------- separating-plane witness


@_jit
def support_at(T, den, n, k):
    """Support radius sqrt(n^T Q^-1 n) at the end k = 0 (t = 0) or k = 4 (t = 1)."""
    acc = 0.0
    for i in range(3):
        for j in range(3):
            acc += n[i] * T[i, j, k] * n[j]
    return np.sqrt(max(acc, 0.0) / den[k])


@_jit
def _positive8(c, margin, work):
    """True when the degree-8 Bernstein polynomial c is > margin on [0, 1] (certified).

    Depth-first subdivision on the scratch rows of ``work``; column 9 holds the
    depth of each stacked piece.  Fails as soon as an end value (an exact value
    of the polynomial) is not above the margin, or at depth PLANE_DEPTH.
    """
    for k in range(9):
        work[0, k] = c[k]
    work[0, 9] = 0.0
    top = 1
    while top > 0:
        top -= 1
        cur = work[top]
        if cur[0] <= margin or cur[8] <= margin:
            return False
        lo = cur[1]
        for k in range(2, 8):
            lo = min(lo, cur[k])
        if lo > margin:
            continue
        if cur[9] >= PLANE_DEPTH:
            return False
        # de Casteljau at 1/2: left half back into slot top, right half into slot top + 1
        nxt = work[top + 1]
        for k in range(9):
            nxt[k] = cur[k]
        for r in range(1, 9):
            for k in range(9 - r):
                nxt[k] = 0.5 * (nxt[k] + nxt[k + 1])
            cur[r] = nxt[0]
        cur[9] += 1.0
        nxt[9] = cur[9]
        top += 2
    return True


@_jit
def _side_holds(n0, d0, n1, d1, c0, c1, T, den, sign, work):
    """True when the ellipsoid stays strictly on the side ``sign (n.x + d) > 0`` over [0, 1]."""
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
    G = work[PLANE_DEPTH + 2]
    nTn = work[PLANE_DEPTH + 3]
    for a in range(9):
        G[a] = 0.0
        nTn[a] = 0.0
    for a in range(5):
        da = den[a]
        G[a] += hh0 * da
        G[a + 1] += hh1 * da
        G[a + 2] += hh2 * da
        G[a + 3] += hh3 * da
        G[a + 4] += hh4 * da
    # n^T T n (degree 6, scaled), then elevated to 8 by the factor (1 - t + t)^2
    for i in range(3):
        for j in range(3):
            for a in range(5):
                tij = T[i, j, a]
                nTn[a] += n0[i] * tij * n0[j]
                nTn[a + 1] += (n0[i] * n1[j] + n1[i] * n0[j]) * tij
                nTn[a + 2] += n1[i] * tij * n1[j]
    nmax = 0.0
    dmax = 0.0
    for a in range(7):
        G[a] -= nTn[a]
        G[a + 1] -= 2.0 * nTn[a]
        G[a + 2] -= nTn[a]
    for a in range(9):
        G[a] /= B8[a]
    for a in range(7):
        nmax = max(nmax, abs(nTn[a]))
    for a in range(5):
        dmax = max(dmax, abs(den[a]))
    margin = PLANE_MARGIN * (habs * habs * dmax + nmax)
    return _positive8(G, margin, work)


@_jit
def plane_holds(n0, d0, n1, d1, ca0, ca1, Ta, dena, cb0, cb1, Tb, denb, work):
    """True when the plane lerped from (n0, d0) to (n1, d1) keeps A below and B above over [0, 1].

    ``ca*``/``cb*``: centres at t = 0 and 1; ``T``/``den``: inverse shape
    polynomials from :func:`support_rigid` or :func:`support_affine`.
    Requires ``n0 . n1 > 0`` so that n(t) never vanishes.
    """
    if n0[0] * n1[0] + n0[1] * n1[1] + n0[2] * n1[2] <= 0.0:
        return False
    if not _side_holds(n0, d0, n1, d1, cb0, cb1, Tb, denb, 1.0, work):
        return False
    return _side_holds(n0, d0, n1, d1, ca0, ca1, Ta, dena, -1.0, work)


@_jit
def gap_offset(n, ca, Ta, dena, cb, Tb, denb, k):
    """Offset d putting the plane with normal n mid-way between A and B at end k (0 or 4).

    Returns (ok, d); ok is False when the projections of A and B on n overlap.
    """
    lo = n[0] * ca[0] + n[1] * ca[1] + n[2] * ca[2] + support_at(Ta, dena, n, k)
    hi = n[0] * cb[0] + n[1] * cb[1] + n[2] * cb[2] - support_at(Tb, denb, n, k)
    if not lo < hi:
        return False, 0.0
    return True, -0.5 * (lo + hi)


@_jit
def witness(n0, n1, ca0, ca1, Ta, dena, cb0, cb1, Tb, denb, work):
    """Try the plane with normal lerped from n0 to n1, centred in the gap at both ends."""
    ok0, d0 = gap_offset(n0, ca0, Ta, dena, cb0, Tb, denb, 0)
    if not ok0:
        return False
    ok1, d1 = gap_offset(n1, ca1, Ta, dena, cb1, Tb, denb, 4)
    if not ok1:
        return False
    return plane_holds(n0, d0, n1, d1, ca0, ca1, Ta, dena, cb0, cb1, Tb, denb, work)


@_jit
def witness_variants(n0, ca0, ca1, Ra0, Ra1, Ta, dena, cb0, cb1, Rb0, Rb1, Tb, denb, n1_out, work, first):
    """Try a world normal n0 held fixed (variant 1), turning with A (2) and turning with B (3).

    ``R*0``/``R*1`` are the rotations of the two bodies at t = 0 and 1; variant
    ``first`` is tried first (the one that held last frame).  Returns the
    variant that held (its normal at t = 1 in ``n1_out``), or 0.
    """
    for step in range(3):
        v = (first - 1 + step) % 3 + 1
        if v == 1:
            n1_out[:] = n0
        else:
            R0 = Ra0 if v == 2 else Rb0
            R1 = Ra1 if v == 2 else Rb1
            for i in range(3):  # n1 = R1 R0^T n0
                acc = 0.0
                for j in range(3):
                    loc = R0[0, j] * n0[0] + R0[1, j] * n0[1] + R0[2, j] * n0[2]
                    acc += R1[i, j] * loc
                n1_out[i] = acc
        if witness(n0, n1_out, ca0, ca1, Ta, dena, cb0, cb1, Tb, denb, work):
            return v
    return 0


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
        raise ValueError(f"ellipsoid: expected an mjccd.Ellipsoid, got {type(ellipsoid).__name__}")
    r = float(ellipsoid.radii.max())
    if isinstance(motion, (mo.Rigid, mo.Affine)):
        return motion.position0.copy(), motion.position1.copy(), r
    if isinstance(motion, mo.Static):
        return motion.position.copy(), motion.position.copy(), r
    if isinstance(motion, mo.LinearAffine):
        scale = max(np.linalg.norm(motion.start[:, :3], 2), np.linalg.norm(motion.end[:, :3], 2))
        return motion.start[:, 3].copy(), motion.end[:, 3].copy(), r * float(scale)
    if isinstance(motion, (mo.Chain, mo.Rational)):
        return _rational_centre_sphere(*motion._w, r)
    raise ValueError(f"motion: no bounding sphere for motion kind {getattr(motion, 'kind', type(motion).__name__)!r}")


def _rational_centre_sphere(G, h, g, r):
    """Chord plus deviation bound of the centre ``-adj(G) h / det(G)`` of a W-form rigid motion."""
    adj = [[None] * 3 for _ in range(3)]
    for i in range(3):
        for j in range(3):
            rows = [k for k in range(3) if k != j]
            cols = [k for k in range(3) if k != i]
            m = bz.add(bz.multiply(G[rows[0], cols[0]].copy(), G[rows[1], cols[1]].copy()),
                       -bz.multiply(G[rows[0], cols[1]].copy(), G[rows[1], cols[0]].copy()))
            adj[i][j] = m if (i + j) % 2 == 0 else -m
    det = bz.add(bz.add(bz.multiply(G[0, 0].copy(), adj[0][0]), bz.multiply(G[0, 1].copy(), adj[1][0])),
                 bz.multiply(G[0, 2].copy(), adj[2][0]))
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
