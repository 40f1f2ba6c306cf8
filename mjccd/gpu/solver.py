"""Device port of the exact first contact of two rigidly moving ellipsoids (float64, one thread per pair).

Each function mirrors the CPU kernel of the same name (:mod:`mjccd.ccd`, :mod:`mjccd.bernstein`,
:mod:`mjccd.quadric`, :mod:`mjccd.motion`) operation for operation, in the same order, so the device
answers what the CPU answers; where the CPU allocates, the device works in fixed-size
``cuda.local.array`` buffers and views of them.  Only the path of a rigid/rigid pair's first contact
is here: :func:`mjccd.ccd.two_pose_pair` with ``first_only`` (the pencil of degrees (4, 5, 6), or
(0, 1, 2) when neither body turns; F of degree 18 or 2 in t), both precision tiers of
:func:`mjccd.ccd.solve_balanced`, the certified shoots and the entry bracket.  What the CPU settles
beyond double precision (a pair touching at t = 0 within the rounding band, a bracket wider than
TIME_TOL, a search limit) comes back flagged (:func:`rigid_pair`'s ``certified`` False, or
status 0), never guessed.
"""
import math

import numpy as np
from numba import cuda, float64, int64

from mjccd import bernstein as bz
from mjccd import ccd
from mjccd.motion import EPS
from mjccd.quadric import ARGMAX_TOL

device = cuda.jit(device=True)

NMAX = 18                    # largest degree in t of F (rigid pencil: 3 * 4 + 6 = 2 * 4 + 2 * 5)
NCOL = NMAX + 1
BINOM = np.ascontiguousarray(bz.BINOMIALS[:NCOL, :NCOL])
TIME_TOL = ccd.TIME_TOL
SHOOT_TOL = ccd.SHOOT_TOL
SHOOT_CONVERGED = ccd.SHOOT_CONVERGED
SHOOT_BAND = ccd.SHOOT_BAND
SECANT_SPAN = ccd.SECANT_SPAN
TOUCH_SPAN = ccd.TOUCH_SPAN
MAX_SHOOTS = ccd.MAX_SHOOTS
THIN = ccd.THIN
SAME_ORIENTATION = ccd.SAME_ORIENTATION
DOUBLE, DOUBLE_TIGHT = ccd.DOUBLE, ccd.DOUBLE_TIGHT
# first_root's stack depth for SHOOT_TOL, as bernstein.first_root sizes it
ROOT_DEPTH = int(np.ceil(-np.log2(max(SHOOT_TOL, 1e-300)))) + 2
# adj(P)[i, j] = P[a, b] P[c, d] - P[e, f] P[g, h]: ccd._ADJUGATE_TERMS as an array
ADJUGATE = np.array(ccd._ADJUGATE_TERMS, dtype=np.int64)
PERMUTATIONS = np.array(ccd._PERMUTATIONS, dtype=np.int64)
F_SHAPE = (5, NCOL)               # F, E and scratch of F's shape
ROOT_SHAPE = (ROOT_DEPTH, NCOL)   # first_root's stack of pieces


# ---------------------------------------------------------------- quartics, determinants (mjccd.quadric)


@device
def _cubic(d0, d1, d2, d3, u):
    v = 1.0 - u
    return d0 * v * v * v + 3.0 * d1 * u * v * v + 3.0 * d2 * u * u * v + d3 * u * u * u


@device
def _quartic5(g0, g1, g2, g3, g4, u):
    v = 1.0 - u
    uu = u * u
    vv = v * v
    return g0 * vv * vv + 4.0 * g1 * u * vv * v + 6.0 * g2 * uu * vv + 4.0 * g3 * uu * u * v + g4 * uu * uu


@device
def _max_on_piece(g0, g1, g2, g3, g4, lo, hi):
    """quadric._max_on_piece."""
    d0, d1, d2, d3 = g1 - g0, g2 - g1, g3 - g2, g4 - g3
    flo = _cubic(d0, d1, d2, d3, lo)
    fhi = _cubic(d0, d1, d2, d3, hi)
    if not (flo > 0.0 and fhi < 0.0):
        return -math.inf, lo
    e0, e1, e2 = 3.0 * (d1 - d0), 3.0 * (d2 - d1), 3.0 * (d3 - d2)
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
        if abs(nxt - u) <= ARGMAX_TOL:
            break
        u = nxt if lo < nxt < hi else 0.5 * (lo + hi)
    return _quartic5(g0, g1, g2, g3, g4, u), u


@device
def quartic_max5(g0, g1, g2, g3, g4):
    """quadric.quartic_max5: max over u in [0, 1] of a Bernstein quartic, and its argmax."""
    if g0 >= g4:
        best, best_u = g0, 0.0
    else:
        best, best_u = g4, 1.0
    if max(g1, g2, g3) < best:
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
            sq = math.sqrt(disc)
            qq = -0.5 * (b + sq if b >= 0.0 else b - sq)
            r1 = qq / c
            r2 = a / qq if qq != 0.0 else 2.0
    if r1 > r2:
        r1, r2 = r2, r1
    lo = 0.0
    for piece in range(3):
        cut = r1 if piece == 0 else (r2 if piece == 1 else 1.0)
        if cut <= lo or cut > 1.0:
            continue
        val, u = _max_on_piece(g0, g1, g2, g3, g4, lo, cut)
        if val > best:
            best, best_u = val, u
        lo = cut
    return best, best_u


@device
def _laplace(M, i, j, p, q, sign):
    s = M[0, i] * M[1, j] - M[1, i] * M[0, j]
    c = M[2, p] * M[3, q] - M[3, p] * M[2, q]
    return sign * (s * c)


@device
def det4(M):
    """quadric.det4: Laplace expansion along rows 0-1, summed in the same order."""
    det = -0.0
    det += _laplace(M, 0, 1, 2, 3, 1.0)
    det += _laplace(M, 0, 2, 1, 3, -1.0)
    det += _laplace(M, 0, 3, 1, 2, 1.0)
    det += _laplace(M, 1, 2, 0, 3, 1.0)
    det += _laplace(M, 1, 3, 0, 2, -1.0)
    det += _laplace(M, 2, 3, 0, 1, 1.0)
    return det


@device
def _det3(m00, m01, m02, m10, m11, m12, m20, m21, m22):
    return (m00 * (m11 * m22 - m12 * m21) - m01 * (m10 * m22 - m12 * m20)
            + m02 * (m10 * m21 - m11 * m20))


@device
def _cofactor(M, i, j):
    r0, r1, r2 = (1 if i == 0 else 0), (2 if i <= 1 else 1), (3 if i <= 2 else 2)
    c0, c1, c2 = (1 if j == 0 else 0), (2 if j <= 1 else 1), (3 if j <= 2 else 2)
    minor = _det3(M[r0, c0], M[r0, c1], M[r0, c2], M[r1, c0], M[r1, c1], M[r1, c2],
                  M[r2, c0], M[r2, c1], M[r2, c2])
    return minor if (i + j) % 2 == 0 else -minor


@device
def touching_point_into(A, B, u, M, p, n):
    """quadric.touching_point into p and n (M: a 4x4 scratch)."""
    for i in range(4):
        for j in range(4):
            M[i, j] = (1.0 - u) * A[i, j] + u * B[i, j]
    best = 0
    best_diag = abs(_cofactor(M, 0, 0))
    for i in range(1, 4):
        d = abs(_cofactor(M, i, i))
        if d > best_diag:
            best, best_diag = i, d
    x3 = _cofactor(M, best, 3)
    for i in range(3):
        p[i] = _cofactor(M, best, i) / x3
    for i in range(3):
        n[i] = A[i, 0] * p[0] + A[i, 1] * p[1] + A[i, 2] * p[2] + A[i, 3]
    norm = math.sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2])
    for i in range(3):
        n[i] /= norm


@device
def quat_to_matrix_into(q, R):
    """quadric.quat_to_matrix into R (3, 3)."""
    w, x, y, z = q[0], q[1], q[2], q[3]
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


# ---------------------------------------------------------------- Bernstein (mjccd.bernstein)


@device
def _keep_left(c, t):
    n = c.shape[0] - 1
    for r in range(1, n + 1):
        for i in range(n, r - 1, -1):
            c[i] = (1.0 - t) * c[i - 1] + t * c[i]


@device
def _keep_right(c, t):
    n = c.shape[0] - 1
    for r in range(1, n + 1):
        for i in range(n - r + 1):
            c[i] = (1.0 - t) * c[i] + t * c[i + 1]


@device
def restrict_into(c, a, b):
    if b < 1.0:
        _keep_left(c, b)
    if a > 0.0:
        _keep_right(c, a / b if b > 0.0 else 0.0)


@device
def evaluate_scaled(c, t):
    n = c.shape[0] - 1
    if t <= 0.5:
        s = t / (1.0 - t)
        acc = c[n]
        for k in range(n - 1, -1, -1):
            acc = acc * s + c[k]
        return acc * (1.0 - t) ** n
    s = (1.0 - t) / t
    acc = c[0]
    for k in range(1, n + 1):
        acc = acc * s + c[k]
    return acc * t ** n


@device
def value_and_slope(c, t):
    """bernstein.value_and_slope (degree at most NMAX: tabled binomials)."""
    n = c.shape[0] - 1
    if n == 0:
        return c[0], 0.0
    flip = t > 0.5
    x = (1.0 - t) / t if flip else t / (1.0 - t)
    acc = c[0] if flip else c[n]
    dacc = (c[0] - c[1]) if flip else (c[n] - c[n - 1])
    for k in range(n - 1, -1, -1):
        binom = BINOM[n, k]
        acc = acc * x + binom * (c[n - k] if flip else c[k])
    for k in range(n - 2, -1, -1):
        binom = BINOM[n - 1, k]
        diff = (c[n - k - 1] - c[n - k]) if flip else (c[k + 1] - c[k])
        dacc = dacc * x + binom * diff
    far = t if flip else 1.0 - t
    slope = n * dacc * far ** (n - 1)
    return acc * far ** n, -slope if flip else slope


@device
def _chain_crossings(c, upper, stack, lo, hi):
    n = c.shape[0] - 1
    top = 0
    for i in range(n + 1):
        while top >= 2:
            a = stack[top - 2]
            b = stack[top - 1]
            cross = (b - a) * (c[i] - c[a]) - (c[b] - c[a]) * (i - a)
            if (cross >= 0.0) if upper else (cross <= 0.0):
                top -= 1
            else:
                break
        stack[top] = i
        top += 1
    for k in range(top):
        p = stack[k]
        if c[p] == 0.0:
            lo = min(lo, float(p))
            hi = max(hi, float(p))
        elif k + 1 < top:
            q = stack[k + 1]
            if c[q] != 0.0 and (c[p] > 0.0) != (c[q] > 0.0):
                x = p + (q - p) * c[p] / (c[p] - c[q])
                lo = min(lo, x)
                hi = max(hi, x)
    return lo, hi


@device
def _hull_crossing(c, stack):
    n = c.shape[0] - 1
    lo, hi = _chain_crossings(c, False, stack, 2.0 * n, -1.0)
    lo, hi = _chain_crossings(c, True, stack, lo, hi)
    if hi < 0.0:
        return 2.0, -1.0
    return lo / n, hi / n


@device
def _newton_first_root(c, tol, left):
    """bernstein._newton_first_root; ``left``: a buffer of c's length."""
    n = c.shape[0] - 1
    x = 0.0
    converged = False
    for _ in range(50):
        v, d = value_and_slope(c, x)
        if v == 0.0:
            converged = True
            break
        if not d != 0.0:
            return -1.0
        step = -v / d
        x += step
        if not 0.0 <= x <= 1.0:
            return -1.0
        if abs(step) <= 0.25 * tol:
            converged = True
            break
    if not converged:
        return -1.0
    lo = max(0.0, x - 0.5 * tol)
    hi = min(1.0, lo + tol)
    positive = c[0] > 0.0
    v_hi, _ = value_and_slope(c, hi)
    if v_hi != 0.0 and (v_hi > 0.0) == positive:
        return -1.0
    for i in range(n + 1):
        left[i] = c[i]
    _keep_left(left, lo)
    for i in range(n + 1):
        if left[i] == 0.0 or (left[i] > 0.0) != positive:
            return -1.0
    return lo


@device
def first_root(c, tol, stack_c, stack_lo, stack_hi, hull, cur):
    """bernstein.first_root with its buffers passed in: stack_c (ROOT_DEPTH, >= n + 1), stack_lo and
    stack_hi (ROOT_DEPTH,), hull (int, >= n + 1), cur (>= n + 1); cur also serves the Newton certificate."""
    n = c.shape[0] - 1
    if n == 0:
        return 0.0 if c[0] == 0.0 else -1.0
    if c[0] == 0.0:
        return 0.0
    cur = cur[:n + 1]
    hull = hull[:n + 1]
    fast = _newton_first_root(c, tol, cur)
    if fast >= 0.0:
        return fast
    for i in range(n + 1):
        stack_c[0, i] = c[i]
    stack_lo[0] = 0.0
    stack_hi[0] = 1.0
    top = 1
    while top > 0:
        top -= 1
        for i in range(n + 1):
            cur[i] = stack_c[top, i]
        lo = stack_lo[top]
        hi = stack_hi[top]
        positive_at_lo = cur[0] > 0.0
        while True:
            cmin = cur[0]
            cmax = cur[0]
            for i in range(1, n + 1):
                cmin = min(cmin, cur[i])
                cmax = max(cmax, cur[i])
            if cmin > 0.0 or cmax < 0.0:
                break
            width = hi - lo
            if width <= tol:
                return lo
            alpha, beta = _hull_crossing(cur, hull)
            if alpha > beta:
                break
            alpha = max(alpha, 0.0)
            beta = min(beta, 1.0)
            if beta - alpha > 0.7:
                mid = lo + 0.5 * width
                for i in range(n + 1):
                    stack_c[top, i] = cur[i]
                _keep_right(stack_c[top, :n + 1], 0.5)
                stack_lo[top] = mid
                stack_hi[top] = hi
                top += 1
                _keep_left(cur, 0.5)
                hi = mid
                continue
            if beta < 1.0:
                _keep_left(cur, beta)
            if alpha > 0.0:
                _keep_right(cur, alpha / beta if beta > 0.0 else 0.0)
            new_lo = lo + alpha * width
            new_hi = lo + beta * width
            lo, hi = new_lo, max(new_hi, new_lo)
            if cur[0] == 0.0 or (cur[0] > 0.0) != positive_at_lo:
                return lo
            if hi - lo <= tol:
                return lo
    return -1.0


@device
def bivariate_at_u_into(F, u, out):
    m = F.shape[0] - 1
    for j in range(F.shape[1]):
        out[j] = 0.0
    w_binom = 1.0
    for i in range(m + 1):
        w = w_binom * u ** i * (1.0 - u) ** (m - i)
        for j in range(F.shape[1]):
            out[j] += w * F[i, j]
        w_binom = w_binom * (m - i) / (i + 1)


# ---------------------------------------------------------------- building F (mjccd.ccd)


@device
def _acc(out, x, y, sign):
    mx, nx = x.shape
    my, ny = y.shape
    for i1 in range(mx):
        for i2 in range(my):
            for j1 in range(nx):
                a = sign * x[i1, j1]
                for j2 in range(ny):
                    out[i1 + i2, j1 + j2] += a * y[i2, j2]


@device
def _dot3_into(out, x0, x1, x2, y0, y1, y2, sign):
    mx, nx = x0.shape
    my, ny = y0.shape
    for i1 in range(mx):
        for i2 in range(my):
            o = i1 + i2
            for j1 in range(nx):
                a0 = sign * x0[i1, j1]
                a1 = sign * x1[i1, j1]
                a2 = sign * x2[i1, j1]
                for j2 in range(ny):
                    out[o, j1 + j2] += a0 * y0[i2, j2] + a1 * y1[i2, j2] + a2 * y2[i2, j2]


@device
def _minor_into(out, x, y, e, g, sign):
    for j1 in range(x.shape[1]):
        x0 = x[0, j1]
        x1 = x[1, j1]
        e0 = e[0, j1]
        e1 = e[1, j1]
        for j2 in range(y.shape[1]):
            y0 = y[0, j2]
            y1 = y[1, j2]
            g0 = g[0, j2]
            g1 = g[1, j2]
            out[0, j1 + j2] += x0 * y0 + sign * (e0 * g0)
            out[1, j1 + j2] += x0 * y1 + x1 * y0 + sign * (e0 * g1 + e1 * g0)
            out[2, j1 + j2] += x1 * y1 + sign * (e1 * g1)


@device
def pencil_determinant(Pp, Up, sp, sign, F, C, detP, V):
    """ccd._pencil_determinant into F (5, n + 1), for pencils with 3p + r = 2p + 2q (both of the rigid path's).

    Pp (3, 3, 2, p + 1), Up (3, 2, q + 1), sp (2, r + 1) are views of the scaled pencil; C
    (3, 3, 3, >= 2p + 1), detP (4, >= 3p + 1) and V (3, 4, >= 2p + q + 1) are scratch.
    """
    p = Pp.shape[3] - 1
    q = Up.shape[2] - 1
    r = sp.shape[1] - 1
    n = 3 * p + r
    for i in range(3):
        for j in range(3):
            for a in range(3):
                for b in range(2 * p + 1):
                    C[i, j, a, b] = 0.0
    for k in range(6):
        i, j, a, b = ADJUGATE[k, 0], ADJUGATE[k, 1], ADJUGATE[k, 2], ADJUGATE[k, 3]
        c, d, e, f = ADJUGATE[k, 4], ADJUGATE[k, 5], ADJUGATE[k, 6], ADJUGATE[k, 7]
        g, h = ADJUGATE[k, 8], ADJUGATE[k, 9]
        _minor_into(C[i, j, :, :2 * p + 1], Pp[a, b], Pp[c, d], Pp[e, f], Pp[g, h], sign)
    w = 2 * p + 1
    for a in range(4):
        for b in range(3 * p + 1):
            detP[a, b] = 0.0
    _dot3_into(detP[:, :3 * p + 1], Pp[0, 0], Pp[0, 1], Pp[0, 2], C[0, 0, :, :w], C[0, 1, :, :w], C[0, 2, :, :w], 1.0)
    for a in range(5):
        for b in range(n + 1):
            F[a, b] = 0.0
    _acc(F, sp, detP[:, :3 * p + 1], 1.0)
    a_centred = True
    for i in range(3):
        for a in range(q + 1):
            if Up[i, 0, a] != 0.0:
                a_centred = False
    u_rows = 1 if a_centred else 2
    U0 = Up[0, 2 - u_rows:]
    U1 = Up[1, 2 - u_rows:]
    U2 = Up[2, 2 - u_rows:]
    vw = 2 * p + q + 1
    for i in range(3):
        for a in range(u_rows + 2):
            for b in range(vw):
                V[i, a, b] = 0.0
    _dot3_into(V[0, :u_rows + 2, :vw], U0, U1, U2, C[0, 0, :, :w], C[0, 1, :, :w], C[0, 2, :, :w], 1.0)
    _dot3_into(V[1, :u_rows + 2, :vw], U0, U1, U2, C[0, 1, :, :w], C[1, 1, :, :w], C[1, 2, :, :w], 1.0)
    _dot3_into(V[2, :u_rows + 2, :vw], U0, U1, U2, C[0, 2, :, :w], C[1, 2, :, :w], C[2, 2, :, :w], 1.0)
    _dot3_into(F[4 - 2 * u_rows:], U0, U1, U2, V[0, :u_rows + 2, :vw], V[1, :u_rows + 2, :vw],
               V[2, :u_rows + 2, :vw], sign)
    for a in range(5):  # bernstein.from_scaled_into
        for b in range(n + 1):
            F[a, b] /= BINOM[4, a] * BINOM[n, b]


@device
def rigid_scaled_into(radii, p0, q0, p1, q1, origin0, origin1, length, P, U, s, side, qq, R, d):
    """motion.rigid_scaled_into; qq (4, 4, 3), R (3, 3, 3) and d (3,) are scratch."""
    for i in range(4):
        for j in range(4):
            qq[i, j, 0] = q0[i] * q0[j]
            qq[i, j, 1] = q0[i] * q1[j] + q1[i] * q0[j]
            qq[i, j, 2] = q1[i] * q1[j]
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
    for k in range(3):
        d[k] = (length / radii[k]) ** 2
    c00 = (p0[0] - origin0[0]) / length
    c01 = (p0[1] - origin0[1]) / length
    c02 = (p0[2] - origin0[2]) / length
    c10 = (p1[0] - origin1[0]) / length
    c11 = (p1[1] - origin1[1]) / length
    c12 = (p1[2] - origin1[2]) / length
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
    for i in range(3):
        for a in range(6):
            U[i, side, a] = 0.0
        for j in range(3):
            cj0 = c00 if j == 0 else (c01 if j == 1 else c02)
            cj1 = c10 if j == 0 else (c11 if j == 1 else c12)
            for a in range(5):
                U[i, side, a] -= P[i, j, side, a] * cj0
                U[i, side, a + 1] -= P[i, j, side, a] * cj1
    for a in range(7):
        s[side, a] = 0.0
    for i in range(3):
        ci0 = c00 if i == 0 else (c01 if i == 1 else c02)
        ci1 = c10 if i == 0 else (c11 if i == 1 else c12)
        for a in range(6):
            s[side, a] -= U[i, side, a] * ci0
            s[side, a + 1] -= U[i, side, a] * ci1
    for a in range(3):
        ga = qq[0, 0, a] + qq[1, 1, a] + qq[2, 2, a] + qq[3, 3, a]
        for b in range(3):
            g2 = ga * (qq[0, 0, b] + qq[1, 1, b] + qq[2, 2, b] + qq[3, 3, b])
            s[side, a + b] -= g2
            s[side, a + b + 1] -= 2.0 * g2
            s[side, a + b + 2] -= g2


@device
def translation_scaled_into(radii, p0, q, p1, origin0, origin1, length, P, U, s, side, R, d):
    """motion.translation_scaled_into; R (3, 3, >= 1) and d (3,) are scratch."""
    w, x, y, z = q[0], q[1], q[2], q[3]
    R[0, 0, 0] = w * w + x * x - y * y - z * z
    R[0, 1, 0] = 2.0 * (x * y - w * z)
    R[0, 2, 0] = 2.0 * (x * z + w * y)
    R[1, 0, 0] = 2.0 * (x * y + w * z)
    R[1, 1, 0] = w * w - x * x + y * y - z * z
    R[1, 2, 0] = 2.0 * (y * z - w * x)
    R[2, 0, 0] = 2.0 * (x * z - w * y)
    R[2, 1, 0] = 2.0 * (y * z + w * x)
    R[2, 2, 0] = w * w - x * x - y * y + z * z
    for k in range(3):
        d[k] = (length / radii[k]) ** 2
    for i in range(3):
        for j in range(i, 3):
            P[i, j, side, 0] = (R[i, 0, 0] * d[0] * R[j, 0, 0] + R[i, 1, 0] * d[1] * R[j, 1, 0]
                                + R[i, 2, 0] * d[2] * R[j, 2, 0])
            P[j, i, side, 0] = P[i, j, side, 0]
    c00 = (p0[0] - origin0[0]) / length
    c01 = (p0[1] - origin0[1]) / length
    c02 = (p0[2] - origin0[2]) / length
    c10 = (p1[0] - origin1[0]) / length
    c11 = (p1[1] - origin1[1]) / length
    c12 = (p1[2] - origin1[2]) / length
    for i in range(3):
        U[i, side, 0] = -(P[i, 0, side, 0] * c00 + P[i, 1, side, 0] * c01 + P[i, 2, side, 0] * c02)
        U[i, side, 1] = -(P[i, 0, side, 0] * c10 + P[i, 1, side, 0] * c11 + P[i, 2, side, 0] * c12)
    g = (w * w + x * x + y * y + z * z) ** 2
    s[side, 0] = -(U[0, side, 0] * c00 + U[1, side, 0] * c01 + U[2, side, 0] * c02) - g
    s[side, 1] = -(U[0, side, 0] * c10 + U[1, side, 0] * c11 + U[2, side, 0] * c12
                   + U[0, side, 1] * c00 + U[1, side, 1] * c01 + U[2, side, 1] * c02) - 2.0 * g
    s[side, 2] = -(U[0, side, 1] * c10 + U[1, side, 1] * c11 + U[2, side, 1] * c12) - g


@device
def gamma(k):
    return k * EPS / (1.0 - k * EPS)


@device
def pose_side_errors(radii, length, C, identity, e):
    """motion.pose_side_errors into e (4, 4)."""
    d0 = length / radii[0]
    d1 = length / radii[1]
    d2 = length / radii[2]
    d0, d1, d2 = d0 * d0, d1 * d1, d2 * d2
    if identity:
        for i in range(4):
            for j in range(4):
                e[i, j] = 0.0
        e[0, 0] = 3.0 * EPS * d0
        e[1, 1] = 3.0 * EPS * d1
        e[2, 2] = 3.0 * EPS * d2
        return
    S = d0 + d1 + d2
    for i in range(3):
        for j in range(3):
            e[i, j] = gamma(80) * S
        e[i, 3] = gamma(100) * S * C
        e[3, i] = e[i, 3]
    e[3, 3] = gamma(120) * (S * C * C + 1.0)


@device
def balance_side(Pp, Up, sp, side, A0):
    """ccd.balance_side (A0: a 4x4 scratch); returns the factor applied."""
    for i in range(3):
        for j in range(3):
            A0[i, j] = Pp[i, j, side, 0]
        A0[i, 3] = Up[i, side, 0]
        A0[3, i] = A0[i, 3]
    A0[3, 3] = sp[side, 0]
    det = det4(A0)
    scale = abs(det) ** 0.25
    if not math.isfinite(scale) or scale == 0.0:
        scale = 0.0
        for i in range(3):
            for j in range(3):
                for a in range(Pp.shape[3]):
                    scale = max(scale, abs(Pp[i, j, side, a]))
    inv = 1.0 / scale
    for i in range(3):
        for j in range(3):
            for a in range(Pp.shape[3]):
                Pp[i, j, side, a] *= inv
        for a in range(Up.shape[2]):
            Up[i, side, a] *= inv
    for a in range(sp.shape[1]):
        sp[side, a] *= inv
    return inv


@device
def entry_maxima_into(Pp, Up, sp, M):
    """ccd._entry_maxima into M (4, 4)."""
    p = Pp.shape[3] - 1
    q = Up.shape[2] - 1
    r = sp.shape[1] - 1
    for i in range(4):
        for j in range(4):
            M[i, j] = 0.0
    for side in range(2):
        for i in range(3):
            for j in range(i, 3):
                for a in range(p + 1):
                    M[i, j] = max(M[i, j], abs(Pp[i, j, side, a]) / BINOM[p, a])
            for a in range(q + 1):
                M[i, 3] = max(M[i, 3], abs(Up[i, side, a]) / BINOM[q, a])
        for a in range(r + 1):
            M[3, 3] = max(M[3, 3], abs(sp[side, a]) / BINOM[r, a])
    slack = 1.0 + 4.0 * EPS
    for i in range(4):
        for j in range(i, 4):
            M[i, j] *= slack
            M[j, i] = M[i, j]


@device
def _chain_length(p, q, r):
    return 8.0 * (2 * p + 2 * q + r + 10)


@device
def _abs_max(F):
    fmax = 0.0
    for i in range(F.shape[0]):
        for j in range(F.shape[1]):
            fmax = max(fmax, abs(F[i, j]))
    return fmax


@device
def error_bound_global(F, p, q, r, D, M):
    """ccd.error_bound_global: the one constant bounding every coefficient's error."""
    perm = 0.0
    delta = 0.0
    for k0 in range(24):
        term = 1.0
        for i in range(4):
            c = PERMUTATIONS[k0, i]
            term *= M[i, c] + D[i, c]
        perm += term
        for k in range(4):
            part = D[k, PERMUTATIONS[k0, k]]
            for i in range(4):
                if i != k:
                    c = PERMUTATIONS[k0, i]
                    part *= M[i, c] + D[i, c]
            delta += part
    K = _chain_length(p, q, r)
    n = F.shape[1] - 1
    fmax = _abs_max(F)
    return (delta + gamma(K) * perm) * (1.0 + 64.0 * EPS) + gamma(4 * n + 40) * fmax


@device
def error_bound_tight(F, Pp, Up, sp, D, E, Pw, Uw, sw, plain, C, detP, V):
    """ccd.error_bound_tight into E; Pw, Uw, sw (the pencil's shapes) and plain (F's shape) are scratch."""
    p = Pp.shape[3] - 1
    q = Up.shape[2] - 1
    r = sp.shape[1] - 1
    for side in range(2):
        for i in range(3):
            for j in range(3):
                for a in range(p + 1):
                    Pw[i, j, side, a] = abs(Pp[i, j, side, a]) + D[i, j] * BINOM[p, a]
            for a in range(q + 1):
                Uw[i, side, a] = abs(Up[i, side, a]) + D[i, 3] * BINOM[q, a]
        for a in range(r + 1):
            sw[side, a] = abs(sp[side, a]) + D[3, 3] * BINOM[r, a]
    pencil_determinant(Pw, Uw, sw, 1.0, E, C, detP, V)  # wide
    for side in range(2):
        for i in range(3):
            for j in range(3):
                for a in range(p + 1):
                    Pw[i, j, side, a] = abs(Pp[i, j, side, a])
            for a in range(q + 1):
                Uw[i, side, a] = abs(Up[i, side, a])
        for a in range(r + 1):
            sw[side, a] = abs(sp[side, a])
    pencil_determinant(Pw, Uw, sw, 1.0, plain, C, detP, V)
    K = _chain_length(p, q, r)
    n = F.shape[1] - 1
    extra = gamma(4 * n + 40) * _abs_max(F)
    g3 = 3.0 * gamma(K)
    for i in range(5):
        for j in range(n + 1):
            wide = E[i, j]
            E[i, j] = (wide - plain[i, j]) * (1.0 + 4.0 * EPS) + g3 * wide + extra


# ---------------------------------------------------------------- state (mjccd.ccd)


@device
def _rows_at(F, t):
    """ccd._rows_at (degree at most NMAX)."""
    n = F.shape[1] - 1
    if t == 0.0 or t == 1.0:
        end = 0 if t == 0.0 else n
        return F[0, end], F[1, end], F[2, end], F[3, end], F[4, end]
    flip = t > 0.5
    s = (1.0 - t) / t if flip else t / (1.0 - t)
    end = 0 if flip else n
    r0, r1, r2, r3, r4 = F[0, end], F[1, end], F[2, end], F[3, end], F[4, end]
    for k in range(n - 1, -1, -1):
        b = BINOM[n, k]
        j = n - k if flip else k
        r0 = r0 * s + b * F[0, j]
        r1 = r1 * s + b * F[1, j]
        r2 = r2 * s + b * F[2, j]
        r3 = r3 * s + b * F[3, j]
        r4 = r4 * s + b * F[4, j]
    w = (t if flip else 1.0 - t) ** n
    return r0 * w, r1 * w, r2 * w, r3 * w, r4 * w


@device
def state(F, t):
    g0, g1, g2, g3, g4 = _rows_at(F, t)
    return quartic_max5(g0, g1, g2, g3, g4)


@device
def _quartic_at(g0, g1, g2, g3, g4, u):
    v = 1.0 - u
    return (v * v * v * v * g0 + 4.0 * u * v * v * v * g1 + 6.0 * u * u * v * v * g2
            + 4.0 * u * u * u * v * g3 + u * u * u * u * g4)


@device
def status_with(F, E, emax, t):
    """ccd.status_with: (code, max_u F, argmax) at t, decided with the error bound E."""
    g0, g1, g2, g3, g4 = _rows_at(F, t)
    gmax, u = quartic_max5(g0, g1, g2, g3, g4)
    if gmax > emax:
        return 1, gmax, u
    if gmax < -emax:
        return -1, gmax, u
    e0, e1, e2, e3, e4 = _rows_at(E, t)
    if gmax > _quartic_at(e0, e1, e2, e3, e4, u):
        return 1, gmax, u
    upper, _ = quartic_max5(g0 + e0, g1 + e1, g2 + e2, g3 + e3, g4 + e4)
    if upper < 0.0:
        return -1, gmax, u
    return 0, gmax, u


# ---------------------------------------------------------------- first contact (mjccd.ccd)


@device
def shoot_first_contact(F, E, emax, uniform, t_start, t_max, u, h, e, stack_c, stack_lo, stack_hi, hull, cur):
    """ccd.shoot_first_contact: (time, u, lower, certified); h and e are buffers of F's row length."""
    t = t_start
    exhausted = True
    for _ in range(MAX_SHOOTS):
        if t >= t_max:
            exhausted = False
            break
        bivariate_at_u_into(F, u, h)
        if uniform:
            e00 = E[0, 0]
            for j in range(h.shape[0]):
                h[j] -= e00
        else:
            bivariate_at_u_into(E, u, e)
            for j in range(h.shape[0]):
                h[j] -= e[j]
        restrict_into(h, t, t_max)
        if not h[0] > 0.0:
            return t, u, t, True
        hmin = h[0]
        for j in range(1, h.shape[0]):
            hmin = min(hmin, h[j])
        r = -1.0 if hmin > 0.0 else first_root(h, SHOOT_TOL, stack_c, stack_lo, stack_hi, hull, cur)
        if r < 0.0:
            exhausted = False
            break
        t_new = t + r * (t_max - t)
        code, gmax, u_new = status_with(F, E, emax, t_new)
        if code != 1 or t_new - t <= SHOOT_CONVERGED or (uniform and gmax <= SHOOT_BAND * emax):
            return t_new, u_new, t_new, True
        t, u = t_new, u_new
    if exhausted:
        return t, u, t, False
    code, _, u_end = status_with(F, E, emax, t_max)
    if code != 1:
        return t_max, u_end, t_max, True
    return -1.0, 0.0, t_max, True


@device
def _state_and_slope(F, t, h):
    gmax, u = state(F, t)
    bivariate_at_u_into(F, u, h)
    _, slope = value_and_slope(h, t)
    return gmax, u, slope


@device
def _entry_upper(F, E, emax, t_c, lower, t_max, gmax, slope):
    """ccd._entry_upper: (probe, computed State there)."""
    w = max(t_c - lower, (gmax + 2.0 * emax) / -slope if slope < 0.0 else 0.0, 1e-16)
    t = t_c
    lowest = math.inf
    while t < t_max:
        t = min(t_c + w, t_max)
        code, gmax, _ = status_with(F, E, emax, t)
        if code == -1:
            return t, gmax
        lowest = min(lowest, gmax)
        if code == 1 and (gmax > lowest + 2.0 * emax or w > TOUCH_SPAN):
            return t, gmax
        w *= 2.0
    g_end, _ = state(F, t_max)
    return t_max, g_end


@device
def _bisect_sign(F, lo, hi, rising):
    """ccd._bisect_sign."""
    sign = 1.0 if rising else -1.0
    f_lo = sign * state(F, lo)[0]
    f_hi = sign * state(F, hi)[0]
    side = 0
    for it in range(200):
        width = hi - lo
        if width <= 4.0 * 2.220446049250313e-16 * max(1.0, abs(hi)):
            break
        mid = 0.5 * (lo + hi)
        if it % 4 != 3 and f_hi > f_lo:
            guess = hi - f_hi * width / (f_hi - f_lo)
            if lo < guess < hi:
                mid = guess
        gmax, _ = state(F, mid)
        if (gmax >= 0.0) == rising:
            hi, f_hi = mid, sign * gmax
            if side == 1:
                f_lo *= 0.5
            side = 1
        else:
            lo, f_lo = mid, sign * gmax
            if side == -1:
                f_hi *= 0.5
            side = -1
    return 0.5 * (lo + hi)


@device
def _zero_of_state(F, lo, hi, gmax, slope, h):
    """ccd._zero_of_state."""
    t = lo
    for it in range(8):
        if it > 0:
            g, _, slope = _state_and_slope(F, t, h)
            if g <= 0.0:
                if t - lo <= SECANT_SPAN:
                    return lo + (t - lo) * gmax / (gmax - g)
                hi = t
                break
            lo, gmax = t, g
        if not slope < 0.0:
            break
        step = -gmax / slope
        if not t + step < hi:
            break
        t += step
        if step <= 4.0 * EPS * t:
            return t
    return _bisect_sign(F, lo, hi, False)


@device
def _tighter_upper(F, E, emax, t, upper):
    for _ in range(40):
        if upper - t <= 0.5 * TIME_TOL:
            break
        mid = 0.5 * (t + upper)
        if status_with(F, E, emax, mid)[0] != -1:
            break
        upper = mid
    return upper


@device
def _entry_estimate(F, E, emax, t_c, lower, t_max, h):
    """ccd._entry_estimate: (estimate, upper end of the bracket)."""
    gmax, u, slope = _state_and_slope(F, t_c, h)
    upper, at_upper = _entry_upper(F, E, emax, t_c, lower, t_max, gmax, slope)
    if upper > t_c and gmax > 0.0:
        if at_upper < 0.0:
            t = _zero_of_state(F, t_c, upper, gmax, slope, h)
            return t, _tighter_upper(F, E, emax, t, upper)
        if at_upper == 0.0:
            return upper, upper
    return t_c, upper


@device
def solve_first(F, E, t_max, h, e, stack_c, stack_lo, stack_hi, hull, cur):
    """ccd.solve_intervals with first_only, then ccd.verdict.

    Returns (status at start, found, t_in, u at the first contact, certified, bracket lo, bracket hi):
    ``found`` tells whether there is a first interval (its start t_in).
    """
    emax = E[0, 0]
    emin = E[0, 0]
    for i in range(E.shape[0]):
        for j in range(E.shape[1]):
            emax = max(emax, E[i, j])
            emin = min(emin, E[i, j])
    uniform = emin == emax
    status0, _, u_first = status_with(F, E, emax, 0.0)
    reached = -1.0
    found = False
    t_in = lower = in_hi = 0.0
    if status0 == 1:
        t_in, u_first, lower, certified = shoot_first_contact(F, E, emax, uniform, 0.0, t_max, u_first, h, e,
                                                              stack_c, stack_lo, stack_hi, hull, cur)
        if not certified:
            reached = lower
        elif t_in >= 0.0:
            t_in, in_hi = _entry_estimate(F, E, emax, t_in, lower, t_max, h)
            found = True
    else:
        t_in = lower = 0.0
        if status0 == -1:
            in_hi = 0.0
        else:
            gmax, _, slope = _state_and_slope(F, 0.0, h)
            in_hi, _ = _entry_upper(F, E, emax, 0.0, 0.0, t_max, gmax, slope)
        found = True
    certified = reached < 0.0  # ccd.verdict of the first interval, or of none
    if found:
        if max(t_in - lower, in_hi - t_in) > TIME_TOL:
            certified = False
        return status0, True, t_in, u_first, certified, lower, in_hi
    if reached >= 0.0:
        return status0, False, -1.0, u_first, False, reached, t_max
    return status0, False, -1.0, u_first, certified, -1.0, -1.0


@device
def solve_balanced(Pp, Up, sp, err, t_max, A0, inv, M, D, F, E, Pw, Uw, sw, plain, C, detP, V, h, e,
                   stack_c, stack_lo, stack_hi, hull, cur):
    """ccd.solve_balanced (balance in place, build F, the constant bound, then the coefficient-wise one):
    :func:`solve_first`'s values and the precision tier."""
    inv[0] = balance_side(Pp, Up, sp, 0, A0)
    inv[1] = balance_side(Pp, Up, sp, 1, A0)
    entry_maxima_into(Pp, Up, sp, M)
    for i in range(4):  # ccd.entry_errors_balanced
        for j in range(4):
            D[i, j] = max(err[0, i, j] * inv[0], err[1, i, j] * inv[1]) * (1.0 + 2.0 * EPS) + EPS * M[i, j]
    pencil_determinant(Pp, Up, sp, -1.0, F, C, detP, V)
    p = Pp.shape[3] - 1
    q = Up.shape[2] - 1
    r = sp.shape[1] - 1
    value = error_bound_global(F, p, q, r, D, M)
    for i in range(E.shape[0]):
        for j in range(E.shape[1]):
            E[i, j] = value
    status0, found, t_in, u, certified, lo, hi = solve_first(F, E, t_max, h, e, stack_c, stack_lo, stack_hi,
                                                             hull, cur)
    if certified:
        return status0, found, t_in, u, certified, lo, hi, DOUBLE
    error_bound_tight(F, Pp, Up, sp, D, E, Pw, Uw, sw, plain, C, detP, V)
    status0, found, t_in, u, certified, lo, hi = solve_first(F, E, t_max, h, e, stack_c, stack_lo, stack_hi,
                                                             hull, cur)
    return status0, found, t_in, u, certified, lo, hi, DOUBLE_TIGHT


@device
def same_orientation(q0, q1):
    return (abs(q0[0] - q1[0]) <= SAME_ORIENTATION and abs(q0[1] - q1[1]) <= SAME_ORIENTATION
            and abs(q0[2] - q1[2]) <= SAME_ORIENTATION and abs(q0[3] - q1[3]) <= SAME_ORIENTATION)


@device
def _conj_mul_into(a, b, out):
    out[0] = a[0] * b[0] + a[1] * b[1] + a[2] * b[2] + a[3] * b[3]
    out[1] = a[0] * b[1] - a[1] * b[0] - a[2] * b[3] + a[3] * b[2]
    out[2] = a[0] * b[2] + a[1] * b[3] - a[2] * b[0] - a[3] * b[1]
    out[3] = a[0] * b[3] - a[1] * b[2] + a[2] * b[1] - a[3] * b[0]


@device
def _to_frame(R, p, origin, out):
    d0 = p[0] - origin[0]
    d1 = p[1] - origin[1]
    d2 = p[2] - origin[2]
    out[0] = R[0, 0] * d0 + R[1, 0] * d1 + R[2, 0] * d2
    out[1] = R[0, 1] * d0 + R[1, 1] * d1 + R[2, 1] * d2
    out[2] = R[0, 2] * d0 + R[1, 2] * d1 + R[2, 2] * d2


@device
def _max3(v):
    return max(v[0], v[1], v[2])


@device
def _min3(v):
    return min(v[0], v[1], v[2])


@device
def rigid_pair(ra, pa0, qa0, pa1, qa1, rb, pb0, qb0, pb1, qb1, t_max, point, normal):
    """ccd.two_pose_pair for two rigid motions, first contact only.

    Inputs are (3,) / (4,) arrays (unit quaternions, q1 on the side of q0); ``point`` and ``normal``
    (3,) receive the touch of a first contact at t > 0 (zero otherwise).  Returns (status at start,
    found, time, certified, bracket lo, bracket hi), as :func:`solve_first`.
    """
    f8 = float64
    Pp = cuda.local.array((3, 3, 2, 5), f8)
    Up = cuda.local.array((3, 2, 6), f8)
    sp = cuda.local.array((2, 7), f8)
    err = cuda.local.array((2, 4, 4), f8)
    A0 = cuda.local.array((4, 4), f8)
    A1 = cuda.local.array((4, 4), f8)
    inv = cuda.local.array(2, f8)
    M = cuda.local.array((4, 4), f8)
    D = cuda.local.array((4, 4), f8)
    F = cuda.local.array(F_SHAPE, f8)
    E = cuda.local.array(F_SHAPE, f8)
    plain = cuda.local.array(F_SHAPE, f8)
    Pw = cuda.local.array((3, 3, 2, 5), f8)
    Uw = cuda.local.array((3, 2, 6), f8)
    sw = cuda.local.array((2, 7), f8)
    C = cuda.local.array((3, 3, 3, 9), f8)
    detP = cuda.local.array((4, 13), f8)
    V = cuda.local.array((3, 4, 15), f8)
    h = cuda.local.array(NCOL, f8)
    e = cuda.local.array(NCOL, f8)
    stack_c = cuda.local.array(ROOT_SHAPE, f8)
    stack_lo = cuda.local.array(ROOT_DEPTH, f8)
    stack_hi = cuda.local.array(ROOT_DEPTH, f8)
    hull = cuda.local.array(NCOL, int64)
    cur = cuda.local.array(NCOL, f8)
    qq = cuda.local.array((4, 4, 3), f8)
    R = cuda.local.array((3, 3, 3), f8)
    d = cuda.local.array(3, f8)
    frame = cuda.local.array((3, 3), f8)
    # the poses, in A's frame at t = 0 when a body is thin (ccd._in_frame_of)
    a0 = cuda.local.array(3, f8)
    a1 = cuda.local.array(3, f8)
    b0 = cuda.local.array(3, f8)
    b1 = cuda.local.array(3, f8)
    qa0f = cuda.local.array(4, f8)
    qa1f = cuda.local.array(4, f8)
    qb0f = cuda.local.array(4, f8)
    qb1f = cuda.local.array(4, f8)
    pt = cuda.local.array(3, f8)
    nm = cuda.local.array(3, f8)

    # ccd.thinner: the thinner body is taken as A, its normal turned at the end
    swapped = _max3(rb) > THIN * _min3(rb) and _max3(rb) / _min3(rb) > _max3(ra) / _min3(ra)
    if swapped:
        ra, pa0, qa0, pa1, qa1, rb, pb0, qb0, pb1, qb1 = rb, pb0, qb0, pb1, qb1, ra, pa0, qa0, pa1, qa1
    length = max(_max3(ra), _max3(rb))
    translating = same_orientation(qa0, qa1) and same_orientation(qb0, qb1)
    framed = _max3(ra) > THIN * _min3(ra) or _max3(rb) > THIN * _min3(rb)
    if framed:
        quat_to_matrix_into(qa0, frame)
        _to_frame(frame, pa0, pa0, a0)
        _to_frame(frame, pa1, pa0, a1)
        _to_frame(frame, pb0, pa0, b0)
        _to_frame(frame, pb1, pa0, b1)
        qa0f[0], qa0f[1], qa0f[2], qa0f[3] = 1.0, 0.0, 0.0, 0.0
        if translating:
            qa1f[0], qa1f[1], qa1f[2], qa1f[3] = 1.0, 0.0, 0.0, 0.0
        else:
            _conj_mul_into(qa0, qa1, qa1f)
        _conj_mul_into(qa0, qb0, qb0f)
        _conj_mul_into(qa0, qb1, qb1f)
    else:
        for m in range(3):
            a0[m], a1[m], b0[m], b1[m] = pa0[m], pa1[m], pb0[m], pb1[m]
        for m in range(4):
            qa0f[m], qa1f[m], qb0f[m], qb1f[m] = qa0[m], qa1[m], qb0[m], qb1[m]
    if translating:  # pencil of degrees (0, 1, 2): F of degree 2
        p, q, r = 0, 1, 2
        translation_scaled_into(ra, a0, qa0f, a1, a0, a1, length, Pp, Up, sp, 0, R, d)
        translation_scaled_into(rb, b0, qb0f, b1, a0, a1, length, Pp, Up, sp, 1, R, d)
    else:
        p, q, r = 4, 5, 6
        rigid_scaled_into(ra, a0, qa0f, a1, qa1f, a0, a1, length, Pp, Up, sp, 0, qq, R, d)
        rigid_scaled_into(rb, b0, qb0f, b1, qb1f, a0, a1, length, Pp, Up, sp, 1, qq, R, d)
    extent = max(abs(b0[0] - a0[0]) + abs(b0[1] - a0[1]) + abs(b0[2] - a0[2]),
                 abs(b1[0] - a1[0]) + abs(b1[1] - a1[1]) + abs(b1[2] - a1[2])) / length  # motion.centre_extent
    pose_side_errors(ra, length, 0.0, translating and framed, err[0])
    pose_side_errors(rb, length, extent, False, err[1])
    n = 3 * p + r
    Ppv = Pp[:, :, :, :p + 1]
    Upv = Up[:, :, :q + 1]
    spv = sp[:, :r + 1]
    status0, found, t_in, u, certified, lo, hi, _ = solve_balanced(
        Ppv, Upv, spv, err, t_max, A0, inv, M, D, F[:, :n + 1], E[:, :n + 1], Pw[:, :, :, :p + 1],
        Uw[:, :, :q + 1], sw[:, :r + 1], plain[:, :n + 1], C, detP, V, h[:n + 1], e[:n + 1],
        stack_c, stack_lo, stack_hi, hull, cur)
    for m in range(3):
        point[m] = 0.0
        normal[m] = 0.0
    if status0 == 1 and found:
        t = t_in
        pencil_quadric_into(Ppv, Upv, spv, 0, t, A0)
        pencil_quadric_into(Ppv, Upv, spv, 1, t, A1)
        touching_point_into(A0, A1, u, M, pt, nm)
        for m in range(3):
            point[m] = (1.0 - t) * a0[m] + t * a1[m] + length * pt[m]
        if framed:
            quat_to_matrix_into(qa0, frame)
            l0, l1, l2 = point[0], point[1], point[2]
            for m in range(3):
                point[m] = pa0[m] + frame[m, 0] * l0 + frame[m, 1] * l1 + frame[m, 2] * l2
                normal[m] = frame[m, 0] * nm[0] + frame[m, 1] * nm[1] + frame[m, 2] * nm[2]
        else:
            for m in range(3):
                normal[m] = nm[m]
        if swapped:
            for m in range(3):
                normal[m] = -normal[m]
    return status0, found, t_in, certified, lo, hi


@device
def pencil_quadric_into(Pp, Up, sp, side, t, A):
    """ccd.pencil_quadric_at into A (4, 4)."""
    for i in range(3):
        for j in range(3):
            A[i, j] = evaluate_scaled(Pp[i, j, side], t)
        A[i, 3] = evaluate_scaled(Up[i, side], t)
        A[3, i] = A[i, 3]
    A[3, 3] = evaluate_scaled(sp[side], t)
