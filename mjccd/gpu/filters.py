"""Device port of the scene's conservative filters: moving bounding spheres and separating-plane witnesses.

Mirrors :mod:`mjccd.filters` (sphere entry, the rigid inverse-shape factors, the witness of a plane
lerped over the frame and its three variants) and :func:`mjccd.quadric.separating_plane_matrices`
(the static plane between two separate ellipsoids) for one pair of ellipsoids held in local arrays
(index 0 the pair's first ellipsoid, 1 its second).  A filter only ever answers "free over the whole
frame" or "don't know", as on the CPU.
"""
import math

from numba import cuda

from mjccd import filters as fl
from mjccd.gpu.solver import det4, quartic_max5
from mjccd.quadric import TOUCH_ULPS

device = cuda.jit(device=True)

SPHERE_INFLATE = fl.SPHERE_INFLATE
PLANE_MARGIN = fl.PLANE_MARGIN
PLANE_DEPTH = fl.PLANE_DEPTH
WORK_SHAPE = fl.WORK_SHAPE  # scratch rows of the witness (subdivision stack, n^T T n)


@device
def sphere_entry(ca0, ca1, ra, cb0, cb1, rb):
    """filters.sphere_entry: first t in [0, 1] at which the two moving spheres touch (a lower bound of
    the pair's first contact), or -1."""
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
        return -1.0
    disc = b * b - 4.0 * a * c
    if disc < 0.0:
        return -1.0
    t = 2.0 * c / (-b + math.sqrt(disc))
    if t > 1.0:
        return -1.0
    return max(0.0, t * (1.0 - 1e-12))


@device
def support_rigid(radii, q0, q1, U, den, e):
    """filters.support_rigid for body e of the pair: ``radii`` (3,), quaternions (4,) (q1 on q0's side)."""
    a0, a1, a2, a3 = q0[0], q0[1], q0[2], q0[3]
    b0, b1, b2, b3 = q1[0], q1[1], q1[2], q1[3]
    r0, r1, r2 = radii[0], radii[1], radii[2]
    for k in range(3):
        if k == 0:
            w, x, y, z, w2, x2, y2, z2 = a0, a1, a2, a3, a0, a1, a2, a3
        elif k == 1:
            w, x, y, z, w2, x2, y2, z2 = a0, a1, a2, a3, b0, b1, b2, b3
        else:
            w, x, y, z, w2, x2, y2, z2 = b0, b1, b2, b3, b0, b1, b2, b3
        s = 2.0 if k == 1 else 1.0
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


@device
def rotation_into(q, R, r):
    """filters.rotation_into: the rotation matrix of the unit quaternion q (4,) into R[r]."""
    w, x, y, z = q[0], q[1], q[2], q[3]
    R[r, 0, 0] = w * w + x * x - y * y - z * z
    R[r, 0, 1] = 2.0 * (x * y - w * z)
    R[r, 0, 2] = 2.0 * (x * z + w * y)
    R[r, 1, 0] = 2.0 * (x * y + w * z)
    R[r, 1, 1] = w * w - x * x + y * y - z * z
    R[r, 1, 2] = 2.0 * (y * z - w * x)
    R[r, 2, 0] = 2.0 * (x * z - w * y)
    R[r, 2, 1] = 2.0 * (y * z + w * x)
    R[r, 2, 2] = w * w - x * x - y * y + z * z


@device
def support_at(S, den, e, n0, n1, n2, k):
    """filters.support_at (rigid factors): support radius of body e along n at end k (0: t = 0, 4: t = 1)."""
    acc = 0.0
    c = k // 2
    for m in range(3):
        s = n0 * S[e, m, 0, c] + n1 * S[e, m, 1, c] + n2 * S[e, m, 2, c]
        acc += s * s
    return math.sqrt(max(acc, 0.0) / den[e, k])


@device
def _normal_form(S, e, n0, n1, work, row):
    """filters._normal_form (rigid factors): n(t)^T T n(t) into work[row, :7]; returns its rounding scale."""
    for a in range(7):
        work[row, a] = 0.0
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


@device
def _positive8(work, margin):
    """filters._positive8: the degree-8 polynomial in work[0, :9] is certified > margin on [0, 1]."""
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


@device
def _inv_b8(a):
    """filters.INV_B8[a]: 1 / C(8, a)."""
    if a == 0 or a == 8:
        return 1.0
    if a == 1 or a == 7:
        return 1 / 8
    if a == 2 or a == 6:
        return 1 / 28
    if a == 3 or a == 5:
        return 1 / 56
    return 1 / 70


@device
def _side_holds(n0, d0, n1, d1, c0, c1, S, den, e, sign, work):
    """filters._side_holds: body e stays strictly on the side sign (n.x + d) > 0 over [0, 1]."""
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
    hh0 = h0 * h0
    hh1 = 2.0 * h0 * h1
    hh2 = h1 * h1 + 2.0 * h0 * h2
    hh3 = 2.0 * h1 * h2
    hh4 = h2 * h2
    nt = PLANE_DEPTH + 3
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
    for a in range(7):
        v = work[nt, a]
        work[0, a] -= v
        work[0, a + 1] -= 2.0 * v
        work[0, a + 2] -= v
    for a in range(9):
        work[0, a] *= _inv_b8(a)
    margin = PLANE_MARGIN * (habs * habs * dmax + nscale)
    return _positive8(work, margin)


@device
def plane_holds(n0, d0, n1, d1, ca0, ca1, cb0, cb1, S, den, work):
    """filters.plane_holds: the lerped plane keeps body 0 below and body 1 above over [0, 1]."""
    if n0[0] * n1[0] + n0[1] * n1[1] + n0[2] * n1[2] <= 0.0:
        return False
    if not _side_holds(n0, d0, n1, d1, cb0, cb1, S, den, 1, 1.0, work):
        return False
    return _side_holds(n0, d0, n1, d1, ca0, ca1, S, den, 0, -1.0, work)


@device
def gap_offset(n, ca, cb, S, den, k):
    """filters.gap_offset: (ok, d) putting the plane with normal n mid-way between the bodies at end k."""
    lo = n[0] * ca[0] + n[1] * ca[1] + n[2] * ca[2] + support_at(S, den, 0, n[0], n[1], n[2], k)
    hi = n[0] * cb[0] + n[1] * cb[1] + n[2] * cb[2] - support_at(S, den, 1, n[0], n[1], n[2], k)
    if not lo < hi:
        return False, 0.0
    return True, -0.5 * (lo + hi)


@device
def witness(n0, n1, ca0, ca1, cb0, cb1, S, den, work):
    """filters.witness: the plane with normal lerped from n0 to n1, centred in the gap at both ends."""
    ok0, d0 = gap_offset(n0, ca0, cb0, S, den, 0)
    if not ok0:
        return False
    ok1, d1 = gap_offset(n1, ca1, cb1, S, den, 4)
    if not ok1:
        return False
    return plane_holds(n0, d0, n1, d1, ca0, ca1, cb0, cb1, S, den, work)


@device
def _turn_into(R0, R1, e, n, out):
    """filters._turn: R1[e] R0[e]^T n into out."""
    l0 = R0[e, 0, 0] * n[0] + R0[e, 1, 0] * n[1] + R0[e, 2, 0] * n[2]
    l1 = R0[e, 0, 1] * n[0] + R0[e, 1, 1] * n[1] + R0[e, 2, 1] * n[2]
    l2 = R0[e, 0, 2] * n[0] + R0[e, 1, 2] * n[1] + R0[e, 2, 2] * n[2]
    out[0] = R1[e, 0, 0] * l0 + R1[e, 0, 1] * l1 + R1[e, 0, 2] * l2
    out[1] = R1[e, 1, 0] * l0 + R1[e, 1, 1] * l1 + R1[e, 1, 2] * l2
    out[2] = R1[e, 2, 0] * l0 + R1[e, 2, 1] * l1 + R1[e, 2, 2] * l2


@device
def witness_variants(n0, ca0, ca1, cb0, cb1, R0, R1, S, den, work, first, n1):
    """filters.witness_variants: n0 held fixed (1), turning with body 0 (2), turning with body 1 (3),
    variant ``first`` first; returns the variant that held (its normal at t = 1 in n1) or 0."""
    n1[0], n1[1], n1[2] = n0[0], n0[1], n0[2]
    ok0, d0 = gap_offset(n0, ca0, cb0, S, den, 0)
    if not ok0:
        return 0
    for step in range(3):
        v = (first - 1 + step) % 3 + 1
        if v == 1:
            n1[0], n1[1], n1[2] = n0[0], n0[1], n0[2]
        elif v == 2:
            _turn_into(R0, R1, 0, n0, n1)
        else:
            _turn_into(R0, R1, 1, n0, n1)
        ok1, d1 = gap_offset(n1, ca1, cb1, S, den, 4)
        if ok1 and plane_holds(n0, d0, n1, d1, ca0, ca1, cb0, cb1, S, den, work):
            return v
    return 0


# ---------------------------------------------------------------- static separating plane (mjccd.quadric)


@device
def quadric_matrix_into(radii, position, quaternion, R, out):
    """quadric.quadric_matrix into out (4, 4); R (3, 3) scratch."""
    w, x, y, z = quaternion[0], quaternion[1], quaternion[2], quaternion[3]
    n = w * w + x * x + y * y + z * z
    R[0, 0] = (w * w + x * x - y * y - z * z) / n
    R[0, 1] = 2.0 * (x * y - w * z) / n
    R[0, 2] = 2.0 * (x * z + w * y) / n
    R[1, 0] = 2.0 * (x * y + w * z) / n
    R[1, 1] = (w * w - x * x + y * y - z * z) / n
    R[1, 2] = 2.0 * (y * z - w * x) / n
    R[2, 0] = 2.0 * (x * z - w * y) / n
    R[2, 1] = 2.0 * (y * z + w * x) / n
    R[2, 2] = (w * w - x * x - y * y + z * z) / n
    for i in range(3):
        for j in range(3):
            acc = 0.0
            for k in range(3):
                acc += R[i, k] * R[j, k] / (radii[k] * radii[k])
            out[i, j] = acc
    for i in range(3):
        qp = out[i, 0] * position[0] + out[i, 1] * position[1] + out[i, 2] * position[2]
        out[i, 3] = -qp
        out[3, i] = -qp
    out[3, 3] = -(position[0] * out[0, 3] + position[1] * out[1, 3] + position[2] * out[2, 3]) - 1.0


@device
def _mix_into(A, B, u, M):
    for i in range(4):
        for j in range(4):
            M[i, j] = (1.0 - u) * A[i, j] + u * B[i, j]


@device
def _cof(M, i, j):
    r0, r1, r2 = (1 if i == 0 else 0), (2 if i <= 1 else 1), (3 if i <= 2 else 2)
    c0, c1, c2 = (1 if j == 0 else 0), (2 if j <= 1 else 1), (3 if j <= 2 else 2)
    minor = (M[r0, c0] * (M[r1, c1] * M[r2, c2] - M[r1, c2] * M[r2, c1])
             - M[r0, c1] * (M[r1, c0] * M[r2, c2] - M[r1, c2] * M[r2, c0])
             + M[r0, c2] * (M[r1, c0] * M[r2, c1] - M[r1, c1] * M[r2, c0]))
    return minor if (i + j) % 2 == 0 else -minor


@device
def _null_point_into(M, P):
    """quadric.null_vector of M, divided by its last component, into P (4,)."""
    best = 0
    best_diag = abs(_cof(M, 0, 0))
    for i in range(1, 4):
        d = abs(_cof(M, i, i))
        if d > best_diag:
            best, best_diag = i, d
    x3 = _cof(M, best, 3)
    for i in range(4):
        P[i] = _cof(M, best, i) / x3


@device
def _quartic_value(g0, g1, g2, g3, g4, u):
    v = 1.0 - u
    return (g0 * v ** 4 + 4.0 * g1 * u * v ** 3 + 6.0 * g2 * u * u * v * v
            + 4.0 * g3 * u ** 3 * v + g4 * u ** 4)


@device
def _quartic_root(g0, g1, g2, g3, g4, lo, hi, glo):
    """quadric._quartic_root: bisection for the sign change of the quartic on [lo, hi]."""
    for _ in range(200):
        mid = 0.5 * (lo + hi)
        if mid <= lo or mid >= hi:
            break
        gm = _quartic_value(g0, g1, g2, g3, g4, mid)
        if (gm > 0.0) == (glo > 0.0):
            lo, glo = mid, gm
        else:
            hi = mid
    return 0.5 * (lo + hi)


@device
def _form(Q, X, Y):
    """X^T Q Y for 4-vectors."""
    acc = 0.0
    for i in range(4):
        row = Q[i, 0] * Y[0] + Q[i, 1] * Y[1] + Q[i, 2] * Y[2] + Q[i, 3] * Y[3]
        acc += X[i] * row
    return acc


@device
def _segment_hits(Q, P0, D):
    """quadric._segment_hits on P0 + s D: the two parameters where the line meets Q (NaN when it misses)."""
    qa = _form(Q, D, D)
    qb = 2.0 * _form(Q, P0, D)
    qc = _form(Q, P0, P0)
    disc = qb * qb - 4.0 * qa * qc
    if disc < 0.0 or qa == 0.0:
        return math.nan, math.nan
    sq = math.sqrt(disc)
    s1 = (-qb - sq) / (2.0 * qa)
    s2 = (-qb + sq) / (2.0 * qa)
    return min(s1, s2), max(s1, s2)


@device
def separating_normal(A, B, M, Pa, Pb, D, plane):
    """quadric.separating_plane_matrices, the plane's unit normal only (into plane[:3]): True when found.

    A and B (4, 4) are the two quadrics; M (4, 4), Pa, Pb, D (4,) are scratch.
    """
    _mix_into(A, B, 0.0, M)  # quadric.pencil_quartic: five samples of det((1 - u) A + u B)
    v0 = det4(M)
    _mix_into(A, B, 0.25, M)
    v1 = det4(M)
    _mix_into(A, B, 0.5, M)
    v2 = det4(M)
    _mix_into(A, B, 0.75, M)
    v3 = det4(M)
    _mix_into(A, B, 1.0, M)
    v4 = det4(M)
    g0 = v0
    g4 = v4
    g1 = (-13.0 * v0 + 48.0 * v1 - 36.0 * v2 + 16.0 * v3 - 3.0 * v4) / 12.0
    g3 = (-3.0 * v0 + 16.0 * v1 - 36.0 * v2 + 48.0 * v3 - 13.0 * v4) / 12.0
    g2 = (13.0 * v0 - 64.0 * v1 + 120.0 * v2 - 64.0 * v3 + 13.0 * v4) / 18.0
    scale = 1.0
    for i in range(4):
        ra = 0.0
        rb = 0.0
        for j in range(4):
            ra += A[i, j] * A[i, j]
            rb += B[i, j] * B[i, j]
        scale *= math.sqrt(max(ra, rb))
    noise = scale * 2.3e-16 * 64.0
    gmax, umax = quartic_max5(g0, g1, g2, g3, g4)
    if not gmax > TOUCH_ULPS * noise:  # quadric.status_from_max: not separate
        return False
    u_lo = _quartic_root(g0, g1, g2, g3, g4, 0.0, umax, g0)
    u_hi = _quartic_root(g0, g1, g2, g3, g4, umax, 1.0, gmax)
    _mix_into(A, B, u_lo, M)
    _null_point_into(M, Pb)  # u near 0 weights A: its kernel point lies inside B
    _mix_into(A, B, u_hi, M)
    _null_point_into(M, Pa)
    if _form(A, Pa, Pa) > 0.0:  # labels the other way round
        for i in range(4):
            Pa[i], Pb[i] = Pb[i], Pa[i]
    for i in range(4):
        D[i] = Pb[i] - Pa[i]
    _, s_exit_a = _segment_hits(A, Pa, D)
    s_enter_b, _ = _segment_hits(B, Pa, D)
    if not (s_exit_a < s_enter_b):
        return False
    # Ta, Tb: the tangent points along the line; S their midpoint (into M's rows 0-2 as scratch)
    for i in range(4):
        M[0, i] = Pa[i] + s_exit_a * D[i]
        M[1, i] = Pa[i] + s_enter_b * D[i]
    for i in range(4):
        M[2, i] = 0.5 * (M[0, i] + M[1, i])
    pa_s = 0.0
    pb_s = 0.0
    for i in range(4):  # pi_a = A Ta and pi_b = B Tb, each dotted with S
        pa_i = A[i, 0] * M[0, 0] + A[i, 1] * M[0, 1] + A[i, 2] * M[0, 2] + A[i, 3] * M[0, 3]
        pb_i = B[i, 0] * M[1, 0] + B[i, 1] * M[1, 1] + B[i, 2] * M[1, 2] + B[i, 3] * M[1, 3]
        pa_s += pa_i * M[2, i]
        pb_s += pb_i * M[2, i]
    norm2 = 0.0
    for i in range(4):
        pa_i = A[i, 0] * M[0, 0] + A[i, 1] * M[0, 1] + A[i, 2] * M[0, 2] + A[i, 3] * M[0, 3]
        pb_i = B[i, 0] * M[1, 0] + B[i, 1] * M[1, 1] + B[i, 2] * M[1, 2] + B[i, 3] * M[1, 3]
        plane[i] = pb_s * pa_i - pa_s * pb_i
        if i < 3:
            norm2 += plane[i] * plane[i]
    norm = math.sqrt(norm2)
    if norm == 0.0:
        return False
    side = 0.0
    for i in range(4):
        plane[i] /= norm
        side += plane[i] * Pa[i]
    if side > 0.0:  # A's inner point must be on the negative side
        for i in range(4):
            plane[i] = -plane[i]
    return True
