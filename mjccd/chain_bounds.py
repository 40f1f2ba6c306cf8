"""Conservative filters for chain motions: sweep bounds, moving spheres and separating planes.

A chain motion (:class:`mjccd.Chain`) moves a body through a sequence of
fixed transforms and joints: hinges (tan(theta/2) linear in t), slides,
ball joints (quaternion lerp) and free joints (centre and quaternion lerp).
Its exact solve costs milliseconds per pair; this module decides most pairs
in microseconds, and a pair it cannot clear goes to the exact solver.  Like
:mod:`mjccd.filters`, it only ever answers "free over the whole step" or
"don't know".

**Sweep bound.**  Write the world motion as ``x(t) = E_1(t) ... E_n(t) y``.
For a node time t0 and any t,

    x(t) - x(t0) = sum_k A_{k-1}(t) [E_k(t) - E_k(t0)] z_k,   z_k = E_{k+1}(t0) ... E_n(t0) y,

with ``A_{k-1}(t) = E_1(t) ... E_{k-1}(t)`` rigid (it keeps lengths).  Each
term is the displacement of one joint acting on the point as it sits at t0:

* hinge: ``2 sin(|dtheta| / 2) rho <= min(|dtheta|, 2) rho``, rho the distance
  of the point from the joint axis at t0; theta(t) = 2 atan(tau(t)) is
  monotone in t, so |dtheta| over a piece is at most its value at the ends;
* slide: ``|ds|``, at most its value at the piece's ends (linear);
* ball and free rotation (quaternion lerp): ``2 sin(a) |x(t0) - o|``, a the
  angle between the two unit quaternions (at most pi / 2 after the sign
  alignment, growing along the lerp), o the joint's centre; a free joint
  adds ``|dp|`` (linear).

A point of the ellipsoid lies within r_max of the centre c, so rho <= rho(c) +
r_max and ``|x - o| <= |c - o| + r_max``.  Summed, this gives a *sweep*
``s(t0; ta, tb)``: every point of the body at any t in [ta, tb] is within s
of where it is at t0.  The body over the piece therefore lies in its own
t0 pose dilated by s.

**Filters.**  (1) Spheres: the body stays in the ball around c(t0) of radius
``r_max + s``, taken at t0 = 0 and t0 = 1 for the whole step.  (2) Planes:
for a unit normal n, the gap ``n . (c_b - c_a) - h_a(n) - h_b(n)`` (h the
support radius) is a lower bound of the distance of the two t0 poses; if it
exceeds ``s_a + s_b``, the plane between them separates the dilated bodies
over the whole piece.  The normal kept from the last frame is tried first;
otherwise a projected gradient ascent (the gap is concave in n) looks for a
better one.  A piece that cannot be cleared is halved (node at its middle,
sweeps about half as large) down to :data:`MAX_DEPTH`.  A pair whose two
ellipsoids overlap at t = 0 (the certified static test of
:func:`mjccd.quadric.static_status_pose`, with one of them shrunk by the
margins below) is reported as overlapping, as the rigid pipeline does;
everything else goes to the exact solver, and so does every pair of a body
whose hinge angles leave (-pi, pi) (the chain motion refuses those).

(3) Static planes (:func:`plane_outcomes`): the body's lowest point along the
plane's normal, in its t0 pose dilated by its sweep, stays above the plane
(over the whole step, else over each of its halves, as for pairs); or at
t = 0 it lies below the plane by more than its margin (overlapping).

The poses are computed here from the chain's elements in double precision;
a relative margin of :data:`MARGIN` on each body's reach (the sum of its
chain's offsets) covers their rounding and that of the exact solver's own
polynomials, and every gap is certified with a rounding margin.
"""
import numpy as np
import numba

from mjccd.errors import InputError, InputTypeError
from mjccd.quadric import static_status_pose

# compiled on first use and cached; no cfunc wrapper (no kernel is passed around as a first-class function);
# forceinline=False: numba hands a caller's forceinline down to the callees it compiles
_jit = numba.njit(cache=True, nogil=True, no_cfunc_wrapper=True, forceinline=False)
# hot-path helpers: compiled once, then inlined by LLVM into each caller (no call, no reference counting of
# array arguments); inline="always" copied their numba IR into every caller instead, which multiplied
# compile time (docs/benchmarks.md, "First use")
_inline = numba.njit(cache=True, nogil=True, no_cfunc_wrapper=True, forceinline=True)

FIXED, HINGE, SLIDE, BALL, FREE = range(5)  # element kinds of a chain program
JOINT_WIDTH = (0, 1, 1, 4, 7)   # joint values each kind reads: angle, displacement, quaternion, position + quaternion
MARGIN = 1e-9             # relative to a body's reach: pose rounding here and in the exact solver's chain polynomials
ROUNDING = 1e-12          # relative rounding margin of a gap
SPHERE_INFLATE = 1e-9     # relative growth of summed sphere radii
MAX_DEPTH = 6             # halvings of the step for the plane test (pieces of 1/64 of the step)
SEARCH_STEPS = 24         # gradient steps of the normal search at one node
# outcome of a pair in a step
SPHERE, CACHED_PLANE, NEW_PLANE, OVERLAP_T0, EXACT = range(5)
OUTCOME_NAMES = ("sphere", "cached_plane", "new_plane", "overlapping_t0", "exact")
NODE = 12  # a node row: centre (3), quaternion (4), sweep, margin, largest semi-axis, time, hinge out of range


# ---------------------------------------------------------------- small vector kernels


@_inline
def _qmul(a0, a1, a2, a3, b0, b1, b2, b3):
    """Quaternion product a b ([w, x, y, z])."""
    return (a0 * b0 - a1 * b1 - a2 * b2 - a3 * b3,
            a0 * b1 + a1 * b0 + a2 * b3 - a3 * b2,
            a0 * b2 - a1 * b3 + a2 * b0 + a3 * b1,
            a0 * b3 + a1 * b2 - a2 * b1 + a3 * b0)


@_inline
def _rotate(q0, q1, q2, q3, v0, v1, v2):
    """rot(q) v for a unit quaternion q."""
    # v + 2 w (u x v) + 2 u x (u x v), u the vector part
    c0 = q2 * v2 - q3 * v1
    c1 = q3 * v0 - q1 * v2
    c2 = q1 * v1 - q2 * v0
    return (v0 + 2.0 * (q0 * c0 + q2 * c2 - q3 * c1),
            v1 + 2.0 * (q0 * c1 + q3 * c0 - q1 * c2),
            v2 + 2.0 * (q0 * c2 + q1 * c1 - q2 * c0))


@_inline
def _qmul_unit(a0, a1, a2, a3, b0, b1, b2, b3):
    """The quaternion product a b, normalised."""
    w, x, y, z = _qmul(a0, a1, a2, a3, b0, b1, b2, b3)
    return _unit4(w, x, y, z)


@_inline
def _unit4(a0, a1, a2, a3):
    n = np.sqrt(a0 * a0 + a1 * a1 + a2 * a2 + a3 * a3)
    return a0 / n, a1 / n, a2 / n, a3 / n


@_inline
def _quat_lerp(q0, q1, a, t):
    """Unit quaternion of the lerp from q0[a:a+4] to q1[a:a+4] (both normalised, q1 sign-aligned) at t."""
    u0, u1, u2, u3 = _unit4(q0[a], q0[a + 1], q0[a + 2], q0[a + 3])
    v0, v1, v2, v3 = _unit4(q1[a], q1[a + 1], q1[a + 2], q1[a + 3])
    if u0 * v0 + u1 * v1 + u2 * v2 + u3 * v3 < 0.0:
        v0, v1, v2, v3 = -v0, -v1, -v2, -v3
    if t == 0.0:
        return u0, u1, u2, u3
    if t == 1.0:
        return v0, v1, v2, v3
    s = 1.0 - t
    return _unit4(s * u0 + t * v0, s * u1 + t * v1, s * u2 + t * v2, s * u3 + t * v3)


@_inline
def _sin_between(u, v):
    """sin of the angle between unit 4-vectors u, v with u . v >= 0, without cancellation: |v - (u . v) u|."""
    d = u[0] * v[0] + u[1] * v[1] + u[2] * v[2] + u[3] * v[3]
    w0 = v[0] - d * u[0]
    w1 = v[1] - d * u[1]
    w2 = v[2] - d * u[2]
    w3 = v[3] - d * u[3]
    return min(1.0, np.sqrt(w0 * w0 + w1 * w1 + w2 * w2 + w3 * w3))


@_inline
def _hinge_angle(q0, q1, a, t):
    """theta(t) = 2 atan((1 - t) tan(theta0 / 2) + t tan(theta1 / 2))."""
    if t == 0.0:
        return q0[a]
    if t == 1.0:
        return q1[a]
    return 2.0 * np.arctan((1.0 - t) * np.tan(0.5 * q0[a]) + t * np.tan(0.5 * q1[a]))


# ---------------------------------------------------------------- poses and sweeps


@_jit
def node_pose(kind, vec, quat, adr, start, q0, q1, e, t, ta, tb, rmax, rec, out, row):
    """Pose of body e at time t and its sweep over [ta, tb] (ta <= t <= tb), into ``out[row]``.

    ``out[row]``: centre (3), unit quaternion (4), sweep, margin, r_max, t, and 1 where a hinge
    angle is outside (-pi, pi) (0 otherwise).
    ``rec`` (M, 8) is scratch, one row per element.  See the module docstring
    for the bound.
    """
    pw0, pw1, pw2 = 0.0, 0.0, 0.0
    qw0, qw1, qw2, qw3 = 1.0, 0.0, 0.0, 0.0
    reach = rmax
    flat = 0.0  # translation terms of the sweep (slides, free joints)
    refused = 0.0  # a hinge angle outside (-pi, pi): the chain motion refuses it, so the filters decide nothing
    for m in range(start[e], start[e + 1]):
        k = kind[m]
        rec[m, 6] = 0.0
        if k == FIXED:
            d0, d1, d2 = _rotate(qw0, qw1, qw2, qw3, vec[m, 0], vec[m, 1], vec[m, 2])
            pw0 += d0
            pw1 += d1
            pw2 += d2
            reach += np.sqrt(vec[m, 0] ** 2 + vec[m, 1] ** 2 + vec[m, 2] ** 2)
            qw0, qw1, qw2, qw3 = _qmul_unit(qw0, qw1, qw2, qw3, quat[m, 0], quat[m, 1], quat[m, 2], quat[m, 3])
        elif k == HINGE:
            a = adr[m]
            if not (abs(q0[a]) < np.pi and abs(q1[a]) < np.pi):
                refused = 1.0
            th = _hinge_angle(q0, q1, a, t)
            dth = max(abs(th - _hinge_angle(q0, q1, a, ta)), abs(th - _hinge_angle(q0, q1, a, tb)))
            ax0, ax1, ax2 = _rotate(qw0, qw1, qw2, qw3, vec[m, 0], vec[m, 1], vec[m, 2])
            rec[m, 0], rec[m, 1], rec[m, 2] = pw0, pw1, pw2
            rec[m, 3], rec[m, 4], rec[m, 5] = ax0, ax1, ax2
            rec[m, 6] = min(dth, 2.0)
            rec[m, 7] = 1.0  # distance from the axis
            c, s = np.cos(0.5 * th), np.sin(0.5 * th)
            qw0, qw1, qw2, qw3 = _qmul_unit(qw0, qw1, qw2, qw3, c, s * vec[m, 0], s * vec[m, 1], s * vec[m, 2])
        elif k == SLIDE:
            a = adr[m]
            s = (1.0 - t) * q0[a] + t * q1[a]
            sa = (1.0 - ta) * q0[a] + ta * q1[a]
            sb = (1.0 - tb) * q0[a] + tb * q1[a]
            flat += max(abs(s - sa), abs(s - sb))
            d0, d1, d2 = _rotate(qw0, qw1, qw2, qw3, s * vec[m, 0], s * vec[m, 1], s * vec[m, 2])
            pw0 += d0
            pw1 += d1
            pw2 += d2
            reach += max(abs(q0[a]), abs(q1[a]))
        else:  # BALL or FREE: a quaternion lerp (after the position lerp of a free joint)
            a = adr[m]
            if k == FREE:
                s = 1.0 - t
                l0 = s * q0[a] + t * q1[a]
                l1 = s * q0[a + 1] + t * q1[a + 1]
                l2 = s * q0[a + 2] + t * q1[a + 2]
                dp = 0.0
                for tt in (ta, tb):
                    ss = 1.0 - tt
                    e0 = ss * q0[a] + tt * q1[a] - l0
                    e1 = ss * q0[a + 1] + tt * q1[a + 1] - l1
                    e2 = ss * q0[a + 2] + tt * q1[a + 2] - l2
                    dp = max(dp, np.sqrt(e0 * e0 + e1 * e1 + e2 * e2))
                flat += dp
                d0, d1, d2 = _rotate(qw0, qw1, qw2, qw3, l0, l1, l2)
                pw0 += d0
                pw1 += d1
                pw2 += d2
                reach += max(np.sqrt(q0[a] ** 2 + q0[a + 1] ** 2 + q0[a + 2] ** 2),
                             np.sqrt(q1[a] ** 2 + q1[a + 1] ** 2 + q1[a + 2] ** 2))
                a += 3
            u = _quat_lerp(q0, q1, a, t)
            sin_a = max(_sin_between(u, _quat_lerp(q0, q1, a, ta)), _sin_between(u, _quat_lerp(q0, q1, a, tb)))
            rec[m, 0], rec[m, 1], rec[m, 2] = pw0, pw1, pw2
            rec[m, 6] = 2.0 * sin_a
            rec[m, 7] = 0.0  # distance from the centre
            qw0, qw1, qw2, qw3 = _qmul_unit(qw0, qw1, qw2, qw3, u[0], u[1], u[2], u[3])
    sweep = flat
    for m in range(start[e], start[e + 1]):
        f = rec[m, 6]
        if f == 0.0:
            continue
        x0, x1, x2 = pw0 - rec[m, 0], pw1 - rec[m, 1], pw2 - rec[m, 2]
        if rec[m, 7] == 1.0:
            along = x0 * rec[m, 3] + x1 * rec[m, 4] + x2 * rec[m, 5]
            x0 -= along * rec[m, 3]
            x1 -= along * rec[m, 4]
            x2 -= along * rec[m, 5]
        sweep += f * (np.sqrt(x0 * x0 + x1 * x1 + x2 * x2) + rmax)
    out[row, 0], out[row, 1], out[row, 2] = pw0, pw1, pw2
    out[row, 3], out[row, 4], out[row, 5], out[row, 6] = qw0, qw1, qw2, qw3
    out[row, 7] = sweep * (1.0 + 1e-9)
    out[row, 8] = MARGIN * (reach + np.sqrt(pw0 * pw0 + pw1 * pw1 + pw2 * pw2))
    out[row, 9] = rmax
    out[row, 10] = t
    out[row, 11] = refused


# ---------------------------------------------------------------- gaps


@_inline
def _support(P, row, radii, e, n0, n1, n2):
    """Support radius h(n) of ellipsoid e posed by P[row], and its support offset (h, x0, x1, x2)."""
    w, x, y, z = P[row, 3], P[row, 4], P[row, 5], P[row, 6]
    # columns of rot(q): the semi-axis directions
    u00, u10, u20 = w * w + x * x - y * y - z * z, 2.0 * (x * y + w * z), 2.0 * (x * z - w * y)
    u01, u11, u21 = 2.0 * (x * y - w * z), w * w - x * x + y * y - z * z, 2.0 * (y * z + w * x)
    u02, u12, u22 = 2.0 * (x * z + w * y), 2.0 * (y * z - w * x), w * w - x * x - y * y + z * z
    a0 = radii[e, 0] * (n0 * u00 + n1 * u10 + n2 * u20)
    a1 = radii[e, 1] * (n0 * u01 + n1 * u11 + n2 * u21)
    a2 = radii[e, 2] * (n0 * u02 + n1 * u12 + n2 * u22)
    h = np.sqrt(a0 * a0 + a1 * a1 + a2 * a2)
    if h == 0.0:
        return 0.0, 0.0, 0.0, 0.0
    b0, b1, b2 = radii[e, 0] * a0 / h, radii[e, 1] * a1 / h, radii[e, 2] * a2 / h
    return (h, b0 * u00 + b1 * u01 + b2 * u02, b0 * u10 + b1 * u11 + b2 * u12,
            b0 * u20 + b1 * u21 + b2 * u22)


@_inline
def _gap(PA, ra, PB, rb, radii, i, j, n0, n1, n2):
    """Gap of the two dilated bodies along n: (certified gap, unit n (3), gradient of the raw gap (3), raw gap).

    The raw gap ``n . (c_b - c_a) - h_a(n) - h_b(n)`` (n made a unit vector
    here) is a lower bound of the distance of the two poses; the certified gap
    subtracts each node's sweep and margin and a rounding margin, so a
    positive one separates the dilated bodies.
    """
    norm = np.sqrt(n0 * n0 + n1 * n1 + n2 * n2)
    n0, n1, n2 = n0 / norm, n1 / norm, n2 / norm
    ha, xa0, xa1, xa2 = _support(PA, ra, radii, i, n0, n1, n2)
    hb, xb0, xb1, xb2 = _support(PB, rb, radii, j, n0, n1, n2)
    d0, d1, d2 = PB[rb, 0] - PA[ra, 0], PB[rb, 1] - PA[ra, 1], PB[rb, 2] - PA[ra, 2]
    raw = n0 * d0 + n1 * d1 + n2 * d2 - ha - hb
    dil = PA[ra, 7] + PA[ra, 8] + PB[rb, 7] + PB[rb, 8]
    scale = (abs(PA[ra, 0]) + abs(PA[ra, 1]) + abs(PA[ra, 2]) + abs(PB[rb, 0]) + abs(PB[rb, 1]) + abs(PB[rb, 2])
             + ha + hb + dil)
    gap = raw - dil - ROUNDING * scale
    return gap, n0, n1, n2, d0 - xa0 - xb0, d1 - xa1 - xb1, d2 - xa2 - xb2, raw


@_jit
def search_normal(PA, ra, PB, rb, radii, i, j, normal, steps):
    """Try ``normal`` (3,) and up to ``steps`` projected gradient steps from it; return the best certified gap.

    The raw gap ``n . (c_b - c_a) - h_a(n) - h_b(n)`` is concave in n and
    positively homogeneous, so its maximum over unit n (the distance of the
    two ellipsoids, when positive) is reached by ascent on the sphere.  Stops
    as soon as the certified gap is positive.  ``normal`` is left holding the
    best unit normal found.
    """
    gap, n0, n1, n2, g0, g1, g2, raw = _gap(PA, ra, PB, rb, radii, i, j, normal[0], normal[1], normal[2])
    normal[0], normal[1], normal[2] = n0, n1, n2
    if gap > 0.0 or steps == 0:
        return gap
    # step length: 1 / (bound on the curvature of h_a + h_b), the largest safe ascent step
    curv = 0.0
    for e in (i, j):
        rmin = min(radii[e, 0], radii[e, 1], radii[e, 2])
        rmx = max(radii[e, 0], radii[e, 1], radii[e, 2])
        curv += rmx * rmx / rmin
    eta = 1.0 / curv
    best = gap
    for _ in range(steps):
        # tangential part of the gradient: the radial part only rescales n
        dot = g0 * n0 + g1 * n1 + g2 * n2
        t0, t1, t2 = g0 - dot * n0, g1 - dot * n1, g2 - dot * n2
        if t0 * t0 + t1 * t1 + t2 * t2 <= 1e-30 * (g0 * g0 + g1 * g1 + g2 * g2):
            break
        ngap, m0, m1, m2, h0, h1, h2, nraw = _gap(PA, ra, PB, rb, radii, i, j, n0 + eta * t0, n1 + eta * t1,
                                                 n2 + eta * t2)
        if nraw > raw:
            n0, n1, n2, g0, g1, g2, raw = m0, m1, m2, h0, h1, h2, nraw
            eta *= 1.5
            if ngap > best:
                best = ngap
                normal[0], normal[1], normal[2] = n0, n1, n2
                if best > 0.0:
                    break
        else:
            eta *= 0.25
    return best


# ---------------------------------------------------------------- a step over all pairs


@_jit
def workspace(n_bodies, n_elements):
    """Scratch arrays of :func:`filter_step` (allocated once per filter)."""
    return (np.empty((n_bodies, NODE)), np.empty((n_bodies, NODE)), np.empty((max(n_elements, 1), 8)),
            np.empty((2, NODE)), np.empty((2 * MAX_DEPTH + 2, 3)), np.empty(3), np.empty((2, 3)))


@_jit
def filter_step(kind, vec, quat, adr, start, q0, q1, radii, rmax, pairs, cache_n, cache_ok, outcome, counters, ws):
    """Decide every pair of one step: ``outcome[k]`` is one of SPHERE ... EXACT; ``counters`` (5,) per outcome.

    ``cache_n`` (P, 3) / ``cache_ok`` (P,) hold each pair's normal from the
    last step and whether it has one; both are updated.
    """
    P0, P1, rec, PN, stack, normal, shrunk = ws
    n = start.shape[0] - 1
    for e in range(n):
        node_pose(kind, vec, quat, adr, start, q0, q1, e, 0.0, 0.0, 1.0, rmax[e], rec, P0, e)
        node_pose(kind, vec, quat, adr, start, q0, q1, e, 1.0, 0.0, 1.0, rmax[e], rec, P1, e)
    for c in range(5):
        counters[c] = 0
    for k in range(pairs.shape[0]):
        i, j = pairs[k, 0], pairs[k, 1]
        if P0[i, 11] != 0.0 or P0[j, 11] != 0.0:
            code = EXACT
        else:
            code = _sphere(P0, P1, i, j)
            if code != SPHERE:
                code = _planes(kind, vec, quat, adr, start, q0, q1, radii, rmax, P0, P1, rec, PN, stack, normal,
                               i, j, cache_n, cache_ok, k)
            if code == EXACT and _overlap(radii, P0, i, j, shrunk):
                code = OVERLAP_T0
        outcome[k] = code
        counters[code] += 1


@_inline
def _above(P, row, radii, e, n0, n1, n2, d):
    """How far the lowest point along n of body e posed by ``P[row]``, dilated by its sweep and margin, lies
    above the plane n . x = d, less a rounding margin (> 0: above it)."""
    low = n0 * P[row, 0] + n1 * P[row, 1] + n2 * P[row, 2] - _support(P, row, radii, e, n0, n1, n2)[0]
    rounding = ROUNDING * (abs(P[row, 0]) + abs(P[row, 1]) + abs(P[row, 2]) + abs(d) + P[row, 9] + P[row, 7]
                           + P[row, 8])
    return low - P[row, 7] - P[row, 8] - d - rounding


@_jit
def plane_outcomes(kind, vec, quat, adr, start, q0, q1, radii, rmax, rows, planes, ws, outcome):
    """``outcome[r]`` for each plane pair r (rows (Q, 2): ellipsoid, plane; planes (K, 4): unit normal n and
    offset d, the solid n . x <= d) over the step of joint values q0 to q1, after :func:`filter_step` filled
    the node poses of ``ws``:

    * SPHERE: the body stays above the plane over the whole step: in a node's pose dilated by its sweep and
      margin, its lowest point along n is above d by more than a rounding margin, for the whole step from
      t0 = 0 or 1, else for each piece of it halved down to :data:`MAX_DEPTH` (node at the piece's middle);
    * OVERLAP_T0: at t = 0 its lowest point lies below d by more than its margin and a rounding margin (the
      exact pose then overlaps the solid);
    * EXACT: neither (the exact solver decides).
    """
    P0, P1, rec, PN, stack, _, _ = ws
    for r in range(rows.shape[0]):
        e, k = rows[r, 0], rows[r, 1]
        n0, n1, n2, d = planes[k, 0], planes[k, 1], planes[k, 2], planes[k, 3]
        outcome[r] = EXACT
        if P0[e, 11] != 0.0 or P1[e, 11] != 0.0:
            continue
        if _above(P0, e, radii, e, n0, n1, n2, d) > 0.0 or _above(P1, e, radii, e, n0, n1, n2, d) > 0.0:
            outcome[r] = SPHERE
            continue
        # undilated at t = 0: below the plane by more than the margin is an overlap
        if _above(P0, e, radii, e, n0, n1, n2, d) + P0[e, 7] + 2.0 * P0[e, 8] < -2.0 * ROUNDING * (
                abs(P0[e, 0]) + abs(P0[e, 1]) + abs(P0[e, 2]) + abs(d) + P0[e, 9] + P0[e, 7] + P0[e, 8]):
            outcome[r] = OVERLAP_T0
            continue
        stack[0, 0], stack[0, 1], stack[0, 2] = 0.5, 1.0, 1.0
        stack[1, 0], stack[1, 1], stack[1, 2] = 0.0, 0.5, 1.0
        top = 2
        clear = True
        while top > 0:
            top -= 1
            lo, hi, depth = stack[top, 0], stack[top, 1], stack[top, 2]
            mid = 0.5 * (lo + hi)
            node_pose(kind, vec, quat, adr, start, q0, q1, e, mid, lo, hi, rmax[e], rec, PN, 0)
            gap = _above(PN, 0, radii, e, n0, n1, n2, d)
            if gap > 0.0:
                continue
            # the node's own pose may touch the plane (no halving helps), or no depth left
            if gap + PN[0, 7] + PN[0, 8] <= 0.0 or depth >= MAX_DEPTH or PN[0, 11] != 0.0:
                clear = False
                break
            stack[top, 0], stack[top, 1], stack[top, 2] = mid, hi, depth + 1
            stack[top + 1, 0], stack[top + 1, 1], stack[top + 1, 2] = lo, mid, depth + 1
            top += 2
        if clear:
            outcome[r] = SPHERE


@_inline
def _overlap(radii, P0, i, j, shrunk):
    """True when the two overlap at t = 0 even with A shrunk by the poses' margins.

    :func:`mjccd.quadric.static_status_pose` certifies the overlap of the
    poses computed here.  A is scaled about its centre by ``1 - m / r_min``
    (m the two margins): a ball of radius m around any point of the scaled A
    lies in A (A contains its centre's ball of radius r_min).  A point p in
    both the scaled A and B then has B's true position of it within m of p,
    inside A's true pose (every point of A is within its margin of where it
    is here), so the exact chain poses overlap too.
    """
    scale = 1.0 - (P0[i, 8] + P0[j, 8]) / min(radii[i, 0], radii[i, 1], radii[i, 2])
    if not scale > 0.5:
        return False
    for m in range(3):
        shrunk[0, m] = radii[i, m] * scale
        shrunk[1, m] = radii[j, m]
    return static_status_pose(shrunk[0], P0[i, 0:3], P0[i, 3:7], shrunk[1], P0[j, 0:3], P0[j, 3:7]) == -1


@_inline
def _sphere(P0, P1, i, j):
    """SPHERE when the bodies' sweep spheres around their t = 0 or t = 1 centres are apart, else EXACT."""
    for P in (P0, P1):
        d0, d1, d2 = P[j, 0] - P[i, 0], P[j, 1] - P[i, 1], P[j, 2] - P[i, 2]
        reach = (P[i, 9] + P[i, 7] + P[i, 8] + P[j, 9] + P[j, 7] + P[j, 8]) * (1.0 + SPHERE_INFLATE)
        if d0 * d0 + d1 * d1 + d2 * d2 > reach * reach:
            return SPHERE
    return EXACT


@_jit
def _planes(kind, vec, quat, adr, start, q0, q1, radii, rmax, P0, P1, rec, PN, stack, normal, i, j,
            cache_n, cache_ok, k):
    """Plane test of pair k = (i, j) over the step, halving it where needed: CACHED_PLANE, NEW_PLANE or EXACT."""
    if cache_ok[k]:
        normal[0], normal[1], normal[2] = cache_n[k, 0], cache_n[k, 1], cache_n[k, 2]
        for P in (P0, P1):
            if search_normal(P, i, P, j, radii, i, j, normal, 0) > 0.0:
                cache_n[k, 0], cache_n[k, 1], cache_n[k, 2] = normal[0], normal[1], normal[2]
                return CACHED_PLANE
    else:
        normal[0], normal[1], normal[2] = P0[j, 0] - P0[i, 0], P0[j, 1] - P0[i, 1], P0[j, 2] - P0[i, 2]
        if normal[0] == 0.0 and normal[1] == 0.0 and normal[2] == 0.0:
            normal[0] = 1.0
    cache_ok[k] = False
    # the whole step from either end, then halves with their middles as nodes
    for P in (P0, P1):
        if search_normal(P, i, P, j, radii, i, j, normal, SEARCH_STEPS) > 0.0:
            cache_n[k, 0], cache_n[k, 1], cache_n[k, 2] = normal[0], normal[1], normal[2]
            cache_ok[k] = True
            return NEW_PLANE
    stack[0, 0], stack[0, 1], stack[0, 2] = 0.5, 1.0, 1.0  # (lo, hi, depth); the left half is popped first
    stack[1, 0], stack[1, 1], stack[1, 2] = 0.0, 0.5, 1.0
    top = 2
    while top > 0:
        top -= 1
        lo, hi, depth = stack[top, 0], stack[top, 1], stack[top, 2]
        mid = 0.5 * (lo + hi)
        node_pose(kind, vec, quat, adr, start, q0, q1, i, mid, lo, hi, rmax[i], rec, PN, 0)
        node_pose(kind, vec, quat, adr, start, q0, q1, j, mid, lo, hi, rmax[j], rec, PN, 1)
        gap = search_normal(PN, 0, PN, 1, radii, i, j, normal, SEARCH_STEPS)
        if gap > 0.0:
            continue
        # raw distance bound of the two poses at the node: no halving helps when they may touch there
        if gap + PN[0, 7] + PN[0, 8] + PN[1, 7] + PN[1, 8] <= 0.0 or depth >= MAX_DEPTH:
            return EXACT
        stack[top, 0], stack[top, 1], stack[top, 2] = mid, hi, depth + 1
        stack[top + 1, 0], stack[top + 1, 1], stack[top + 1, 2] = lo, mid, depth + 1
        top += 2
    cache_n[k, 0], cache_n[k, 1], cache_n[k, 2] = normal[0], normal[1], normal[2]
    cache_ok[k] = True
    return NEW_PLANE


# ---------------------------------------------------------------- Python layer


class ChainProgram:
    """The elements of N chains as flat arrays (the input of the kernels).

    ``kind`` (M,) element kinds (FIXED ... FREE); ``vec`` (M, 3) a fixed
    element's offset or a joint's unit axis; ``quat`` (M, 4) a fixed element's
    unit quaternion; ``adr`` (M,) where a joint's values start in the joint
    value vector (a hinge's angle, a slide's displacement, a ball's quaternion,
    a free joint's position and quaternion, as in MuJoCo's qpos); ``start``
    (N + 1,) chain e's elements are ``start[e]:start[e + 1]``, the first
    closest to the world.
    """

    def __init__(self, kind, vec, quat, adr, start):
        self.kind = np.ascontiguousarray(kind, dtype=np.int64)
        self.vec = np.ascontiguousarray(vec, dtype=np.float64).reshape(-1, 3)
        self.quat = np.ascontiguousarray(quat, dtype=np.float64).reshape(-1, 4)
        self.adr = np.ascontiguousarray(adr, dtype=np.int64)
        self.start = np.ascontiguousarray(start, dtype=np.int64)
        m = len(self.kind)
        if not (self.vec.shape[0] == self.quat.shape[0] == self.adr.shape[0] == m and self.start.ndim == 1
                and len(self.start) >= 2 and self.start[0] == 0 and self.start[-1] == m
                and np.all(np.diff(self.start) >= 0)):
            raise InputError("chain program: inconsistent element arrays")
        if m and (self.kind.min() < FIXED or self.kind.max() > FREE):
            raise InputError("chain program: unknown element kind")

    def __len__(self):
        return len(self.start) - 1

    def width(self):
        """Length a joint value vector needs."""
        widths = np.array(JOINT_WIDTH)[self.kind]
        return int(max((self.adr + widths).max(initial=0), 0))


class ProgramBuilder:
    """Collects chains element by element (:meth:`fixed`, :meth:`hinge`, ...; :meth:`end` closes a chain)."""

    def __init__(self):
        self.kind, self.vec, self.quat, self.adr, self.start = [], [], [], [], [0]

    def _add(self, kind, vec=(0.0, 0.0, 0.0), quat=(1.0, 0.0, 0.0, 0.0), adr=0):
        self.kind.append(kind)
        self.vec.append(np.asarray(vec, dtype=np.float64))
        self.quat.append(np.asarray(quat, dtype=np.float64))
        self.adr.append(int(adr))

    def fixed(self, position, quaternion=(1.0, 0.0, 0.0, 0.0)):
        q = np.asarray(quaternion, dtype=np.float64)
        self._add(FIXED, position, q / np.sqrt(q @ q))

    def joint(self, kind, adr, axis=(0.0, 0.0, 1.0)):
        """A hinge or slide about/along ``axis`` (normalised here), or a ball or free joint, reading at ``adr``."""
        axis = np.asarray(axis, dtype=np.float64)
        if kind in (HINGE, SLIDE):
            axis = axis / np.sqrt(axis @ axis)
        self._add(kind, axis, adr=adr)

    def end(self):
        self.start.append(len(self.kind))

    def program(self):
        return ChainProgram(self.kind, np.array(self.vec).reshape(-1, 3), np.array(self.quat).reshape(-1, 4),
                            self.adr, self.start)


def program_from_elements(chains):
    """(:class:`ChainProgram`, q0, q1) of lists of :class:`mjccd.Chain` elements (or Chains).

    Each joint gets its own values in q0 / q1; the result describes exactly
    the motions ``Chain(elements)`` (used by the tests; replay builds its
    program from the MuJoCo model).
    """
    from mjccd import motion as mo

    build = ProgramBuilder()
    v0, v1 = [], []
    for c, chain in enumerate(chains):
        elements = chain.elements if isinstance(chain, mo.Chain) else chain
        for el in elements:
            adr = len(v0)
            if isinstance(el, mo.Fixed):
                build.fixed(el.position, el.quaternion)
            elif isinstance(el, mo.Hinge):
                build.joint(HINGE, adr, el.axis)
                v0.append(el.angle0)
                v1.append(el.angle1)
            elif isinstance(el, mo.Slide):
                build.joint(SLIDE, adr, el.axis)
                v0.append(el.displacement0)
                v1.append(el.displacement1)
            elif isinstance(el, mo.Ball):
                build.joint(BALL, adr)
                v0.extend(el.quaternion0)
                v1.extend(el.quaternion1)
            elif isinstance(el, mo.Free):
                build.joint(FREE, adr)
                v0.extend([*el.position0, *el.quaternion0])
                v1.extend([*el.position1, *el.quaternion1])
            else:
                raise InputTypeError(f"chains[{c}]: not a chain element: {el!r}")
        build.end()
    return build.program(), np.array(v0, dtype=np.float64), np.array(v1, dtype=np.float64)


class ChainFilter:
    """Sweep spheres and separating planes for N chain-moving ellipsoids and a list of pairs.

    ``step(q0, q1)`` decides every pair over one step (joint values q0 at
    t = 0, q1 at t = 1, as addressed by the program) and returns the outcome
    codes (P,) int8: SPHERE, CACHED_PLANE and NEW_PLANE are certified free,
    OVERLAP_T0 overlaps at t = 0, EXACT needs the exact solver.  Each pair's
    normal is kept for the next step.
    """

    def __init__(self, program, radii, pairs):
        self.program = program
        self.radii = np.ascontiguousarray(radii, dtype=np.float64).reshape(-1, 3)
        if len(self.radii) != len(program):
            raise InputError(f"radii: expected {len(program)} rows, one per chain, got {len(self.radii)}")
        self.rmax = np.ascontiguousarray(self.radii.max(axis=1))
        self.pairs = np.ascontiguousarray(pairs, dtype=np.int64).reshape(-1, 2)
        if self.pairs.size and (self.pairs.min() < 0 or self.pairs.max() >= len(program)):
            raise InputError(f"pairs: indices must be within 0..{len(program) - 1}")
        P = len(self.pairs)
        self.outcome = np.empty(P, dtype=np.int8)
        self.counters = np.zeros(5, dtype=np.int64)
        self.reset_cache()
        self._ws = workspace(len(program), len(program.kind))
        self._width = program.width()
        self._q = None  # the joint values of the last step (plane_outcomes reads them)

    def reset_cache(self):
        self.cache_n = np.zeros((len(self.pairs), 3))
        self.cache_ok = np.zeros(len(self.pairs), dtype=np.bool_)

    def step(self, q0, q1):
        q0 = np.ascontiguousarray(q0, dtype=np.float64)
        q1 = np.ascontiguousarray(q1, dtype=np.float64)
        if q0.shape != q1.shape or q0.ndim != 1 or len(q0) < self._width:
            raise InputError(f"q0, q1: expected joint value vectors of length >= {self._width}")
        p = self.program
        filter_step(p.kind, p.vec, p.quat, p.adr, p.start, q0, q1, self.radii, self.rmax, self.pairs,
                    self.cache_n, self.cache_ok, self.outcome, self.counters, self._ws)
        self._q = (q0, q1)
        return self.outcome

    def plane_outcomes(self, planes, rows):
        """(Q,) int8 outcomes SPHERE (free), OVERLAP_T0 or EXACT of the plane pairs ``rows`` (Q, 2: ellipsoid,
        plane row of ``planes`` (K, 4), unit normals) over the step of the last :meth:`step`
        (:func:`plane_outcomes`)."""
        outcome = np.full(len(rows), EXACT, dtype=np.int8)
        if len(rows):
            p = self.program
            plane_outcomes(p.kind, p.vec, p.quat, p.adr, p.start, self._q[0], self._q[1], self.radii, self.rmax,
                           np.ascontiguousarray(rows, dtype=np.int64), np.ascontiguousarray(planes, dtype=np.float64),
                           self._ws, outcome)
        return outcome

    def poses(self, q0, q1, t):
        """(N, 3) centres and (N, 4) unit quaternions at time t (for checks against the chain's own pose)."""
        p = self.program
        out = np.empty((len(p), NODE))
        rec = np.empty((max(len(p.kind), 1), 8))
        q0 = np.ascontiguousarray(q0, dtype=np.float64)
        q1 = np.ascontiguousarray(q1, dtype=np.float64)
        for e in range(len(p)):
            node_pose(p.kind, p.vec, p.quat, p.adr, p.start, q0, q1, e, float(t), float(t), float(t),
                      self.rmax[e], rec, out, e)
        return out[:, :3].copy(), out[:, 3:7].copy()
