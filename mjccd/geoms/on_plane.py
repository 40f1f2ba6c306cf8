"""A sphere or a capsule against a static plane under a rigid lerp, its systems written out (numba kernels).

This is the pair a walking model meets most: feet and shins against the floor.
The general path (:func:`mjccd.geoms.systems.build_pair`) builds these systems
in a polynomial workspace, both frames and their product included, and that
costs most of the pair's solve.  Here they are written out.

The plane's frame is static (origin o, quaternion p; its normal is m / |p|^2
with m = rot(p) e_z), and the geom moves by a rigid lerp (centre
c(t) = (1 - t) c0 + t c1, quaternion q(t) = (1 - t) q0 + t q1, rotation
rot(q(t)) / |q(t)|^2).  A point y of the geom's core comes within the geom's
radius r of the half-space exactly when

    g(t) = m . rot(q(t)) y + |q(t)|^2 (m . (c(t) - o) - r |p|^2) <= 0,

the point's height above the plane less r, times the positive |p|^2 |q(t)|^2.
This is the general path's constraint for the same point.  For a sphere
(y = 0) the factor |q(t)|^2 is dropped and g is linear.  For each end of a
capsule (y = (0, 0, -h), then (0, 0, h)) g is a cubic.  Its Bernstein
coefficients, times 3, are sums of products of the inputs.  Each is bounded by
gamma_d of the same sum over the inputs' magnitudes (Higham 2002, §3.1), with
d the depth of its rounded operations; :func:`mjccd.geoms.poly.error` adds the
scanners' own rounding.  :func:`mjccd.geoms.kernel.pair_kernel` scans these
systems as it scans the general ones, and takes the general path when they
leave the first contact uncertain.
"""
import numpy as np

from mjccd.geoms import contact as ct
from mjccd.geoms import frames as fr
from mjccd.geoms import poly as P
from mjccd.geoms import systems as sy
from mjccd.geoms.poly import jit
from mjccd.quadric import quat_to_matrix

# A coefficient below takes at most 11 rounded operations on its longest path; the bound uses gamma of twice
# that (and more), which also covers the rounding of the sum of magnitudes it multiplies.
DEPTH = 32
SAFE = 1e-40  # every nonzero input lies in [SAFE, 1 / SAFE]: no product of five inputs under- or overflows
LINEAR, CUBIC = np.int64(1), np.int64(3)  # the constraints' degrees (numpy integers: one compiled _close)


@jit
def _bounded(x):
    a = abs(x)
    return a == 0.0 or SAFE <= a <= 1.0 / SAFE


@jit
def _sides(ka, sa, rows_a, kb, sb, rows_b):
    """(geom kind, size, row, plane row, plane is a): the pair in a fixed order."""
    if ka == sy.PLANE:
        return kb, sb, rows_b[0], rows_a[0], True
    return ka, sa, rows_a[0], rows_b[0], False


@jit
def applies(ka, sa, rows_a, kb, sb, rows_b):
    """True for a sphere or capsule moving by one pose row against a plane whose one pose row is static, with
    nonzero quaternions on one side of each other (the lerp's |q(t)|^2 > 0) and every input bounded
    (:data:`SAFE`)."""
    if (ka == sy.PLANE) == (kb == sy.PLANE) or rows_a.shape[0] != 1 or rows_b.shape[0] != 1:
        return False
    kg, sg, rg, rp, _ = _sides(ka, sa, rows_a, kb, sb, rows_b)
    if not sy.rounded(kg) or rg[0] != fr.POSE or rp[0] != fr.POSE:
        return False
    dot, n0, n1, npl = 0.0, 0.0, 0.0, 0.0
    for i in range(4):
        dot += rg[4 + i] * rg[11 + i]
        n0 += rg[4 + i] * rg[4 + i]
        n1 += rg[11 + i] * rg[11 + i]
        npl += rp[4 + i] * rp[4 + i]
    if dot < 0.0 or n0 == 0.0 or n1 == 0.0 or npl == 0.0:
        return False
    for i in range(1, fr.ELEMENT_FIELDS):
        if not (_bounded(rg[i]) and _bounded(rp[i])):
            return False
        if i < 8 and rp[i] != rp[7 + i]:  # the plane moves
            return False
    return _bounded(sg[0]) and _bounded(sg[1])


@jit
def _form(u, w):
    """The symmetric bilinear form of rot(q) e_z (quaternions [w, x, y, z]): _form(q, q) = rot(q) e_z; and
    the same over magnitudes."""
    v0 = u[1] * w[3] + u[3] * w[1] + u[0] * w[2] + u[2] * w[0]
    v1 = u[2] * w[3] + u[3] * w[2] - u[0] * w[1] - u[1] * w[0]
    v2 = u[0] * w[0] - u[1] * w[1] - u[2] * w[2] + u[3] * w[3]
    a0 = abs(u[1] * w[3]) + abs(u[3] * w[1]) + abs(u[0] * w[2]) + abs(u[2] * w[0])
    a1 = abs(u[2] * w[3]) + abs(u[3] * w[2]) + abs(u[0] * w[1]) + abs(u[1] * w[0])
    a2 = abs(u[0] * w[0]) + abs(u[1] * w[1]) + abs(u[2] * w[2]) + abs(u[3] * w[3])
    return v0, v1, v2, a0, a1, a2


@jit
def _close(C, DT, errs, SYS, N, coef, mag, n, side):
    """Append the system of the one constraint with Bernstein coefficients coef[:n+1] (magnitudes mag), unless
    it is proven positive on all of [0, 1]; returns whether it was."""
    e, big = 0.0, 0.0
    for i in range(n + 1):
        e = max(e, P.gamma(DEPTH) * mag[i] * P.UP)
        big = max(big, abs(coef[i]))
    err = P.scanned_bound(e, big, n)
    positive = True
    for i in range(n + 1):
        if not coef[i] > err:
            positive = False
    if positive:
        return False
    k = N[1]
    for i in range(n + 1):
        C[k, 0, i] = coef[i]
    DT[k] = n
    errs[k] = err
    SYS[k, 0], SYS[k, 1], SYS[k, 2], SYS[k, 3] = k, 1, side, 0
    N[0] += 1
    N[1] += 1
    return True


@jit
def systems(ka, sa, rows_a, kb, sb, rows_b, C, DT, errs, SYS, N, ends):
    """The pair's systems (one constraint each, the module docstring's g) into C (2, 1, 4), DT (2,), errs (2,),
    SYS (2, SYS_FIELDS) and N (3,) as :func:`mjccd.geoms.kernel.scan_systems` reads them, in the general
    path's order; ends[k]: the local z of system k's core point.  A system that can never hold is left out, as
    the general path leaves it out.  For pairs :func:`applies` accepts."""
    kg, sg, rg, rp, plane_a = _sides(ka, sa, rows_a, kb, sb, rows_b)
    side = sy.IN_A if plane_a else sy.IN_B  # each witness is in the plane's frame
    N[0] = N[1] = N[2] = 0
    p = rp[4:8]
    w, x, y, z = p[0], p[1], p[2], p[3]
    m0, m1, m2 = 2.0 * (x * z + w * y), 2.0 * (y * z - w * x), w * w - x * x - y * y + z * z
    a0, a1 = 2.0 * (abs(x * z) + abs(w * y)), 2.0 * (abs(y * z) + abs(w * x))
    p2 = w * w + x * x + y * y + z * z  # also the magnitude of m2
    r = sg[0]
    H = np.empty(2)
    Hm = np.empty(2)
    for e in range(2):
        d0, d1, d2 = rg[1 + 7 * e] - rp[1], rg[2 + 7 * e] - rp[2], rg[3 + 7 * e] - rp[3]
        H[e] = m0 * d0 + m1 * d1 + m2 * d2 - r * p2
        Hm[e] = a0 * abs(d0) + a1 * abs(d1) + p2 * abs(d2) + r * p2
    coef = np.empty(4)
    mag = np.empty(4)
    if kg == sy.SPHERE:
        for e in range(2):
            coef[e], mag[e] = H[e], Hm[e]
        ends[0] = 0.0
        _close(C, DT, errs, SYS, N, coef, mag, LINEAR, side)
        return
    q0, q1 = rg[4:8], rg[11:15]
    Q0, Q1, Q2 = 0.0, 0.0, 0.0
    Qm1 = 0.0
    for i in range(4):
        Q0 += q0[i] * q0[i]
        Q1 += q0[i] * q1[i]
        Q2 += q1[i] * q1[i]
        Qm1 += abs(q0[i]) * abs(q1[i])
    A = np.empty(3)
    Am = np.empty(3)
    for k in range(3):
        v0, v1, v2, b0, b1, b2 = _form(q0 if k < 2 else q1, q0 if k == 0 else q1)
        A[k] = m0 * v0 + m1 * v1 + m2 * v2
        Am[k] = a0 * b0 + a1 * b1 + p2 * b2
    h = sg[1]
    for sign in (-1.0, 1.0):
        coef[0] = 3.0 * (Q0 * H[0]) + sign * (h * (3.0 * A[0]))
        coef[1] = (2.0 * (Q1 * H[0]) + Q0 * H[1]) + sign * (h * (A[0] + 2.0 * A[1]))
        coef[2] = (Q2 * H[0] + 2.0 * (Q1 * H[1])) + sign * (h * (2.0 * A[1] + A[2]))
        coef[3] = 3.0 * (Q2 * H[1]) + sign * (h * (3.0 * A[2]))
        mag[0] = 3.0 * (Q0 * Hm[0]) + h * (3.0 * Am[0])
        mag[1] = (2.0 * (Qm1 * Hm[0]) + Q0 * Hm[1]) + h * (Am[0] + 2.0 * Am[1])
        mag[2] = (Q2 * Hm[0] + 2.0 * (Qm1 * Hm[1])) + h * (2.0 * Am[1] + Am[2])
        mag[3] = 3.0 * (Q2 * Hm[1]) + h * (3.0 * Am[2])
        k = N[1]
        if _close(C, DT, errs, SYS, N, coef, mag, CUBIC, side):
            ends[k] = sign * h


@jit
def contact(ka, sa, rows_a, kb, sb, rows_b, end, t):
    """(point (3,), normal (3,) outward from shape a, element code of a, of b) when the core point at local z
    ``end`` touches at time t: the point's foot on the plane, as the general path's witness gives it."""
    kg, sg, rg, rp, plane_a = _sides(ka, sa, rows_a, kb, sb, rows_b)
    q = np.empty(4)
    c = np.empty(3)
    for i in range(4):
        q[i] = (1.0 - t) * rg[4 + i] + t * rg[11 + i]
    for i in range(3):
        c[i] = (1.0 - t) * rg[1 + i] + t * rg[8 + i]
    Rg = quat_to_matrix(q)
    Rp = quat_to_matrix(rp[4:8])
    o = rp[1:4]
    core = c + Rg[:, 2] * end
    y = Rp.T @ (core - o)  # in the plane's frame
    foot = y.copy()
    foot[2] = min(y[2], 0.0)
    x = Rp @ foot + o
    d = Rp @ (y - foot)
    n = np.sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2])
    normal = d / n if n > 0.0 else d
    if not plane_a:
        normal = -normal
    code_g = ct.element(kg, sg, Rg.T @ (x - c), 1e-7)[0]
    return x, normal, (0 if plane_a else code_g), (code_g if plane_a else 0)
