"""First contacts of many geom pairs in one step: conservative filters, then the exact pair solve (numba).

Each geom moves by the rigid lerp of its own pose between the step's two
poses (centre lerp, quaternion lerp the short way), as ellipsoids do in
:class:`mjccd.scene.Scene`: one element row of :mod:`mjccd.geoms.frames`.

Two filters clear a pair without a solve; both are proven, never guesses:

* *moving spheres*: a geom stays inside the sphere of radius ``rho`` (its
  reach from its centre) about its centre, which moves along a straight line;
  when the two centres' lines stay further apart than the sum of the radii,
  the pair cannot touch.  Its cheaper first form, one test per pair on balls
  computed once per geom and step: the whole step's sweep of a geom lies in
  the ball about its centre's path's middle of radius ``rho`` plus half the
  path; two such balls apart by a relative 1e-6 clear the pair (the
  centres' lines are then at least that far apart as well, so the full test
  would clear it too: the answers are the same);
* *distance against displacement*: every point of a geom moves by at most
  ``M = |c1 - c0| + 2 sin(theta / 2) rho`` in the step (theta its turn); a
  geom lies inside a *proxy* capsule (a capsule, a cylinder or a box about
  its longest axis, an ellipsoid of radii a >= b about its a axis with
  radius b and half length a - b); when the proxies lie further apart at the
  step's start than M_A + M_B, the pair cannot touch.  Against a plane the
  proxy's height plays the distance.  Where the whole step does not clear, the
  same test runs on halves of it (the proxies' gap at each half's middle,
  how far their points move from there over the half), halved again down to
  pieces of 1/16 of the step: pairs that come near without touching clear.

A geom certainly reaching below a static plane at the step's start (:func:`below_plane`: its lowest
point along the normal, with a relative margin), or two spheres or capsules whose cores lie closer than
their radii (:func:`cores_overlap`), are overlapping without a solve: bodies resting on a floor or on each
other, every step.

A pair may also be given a *minimum motion*: when ``M_A + M_B`` (how far any
point of one can move relative to the other) stays below it, the pair is
left out as too slow (a guard leaves such pairs to MuJoCo's own contacts).
"""
import math

import numpy as np

from mjccd.geoms import frames as fr
from mjccd.geoms import kernel as kn
from mjccd.geoms import systems as sy
from mjccd.geoms.poly import jit

FILTERED = 4.0  # out[FAILED] of a pair the filters cleared (no solve; separate, no contact)
TOO_SLOW = 5.0  # out[FAILED] of a pair whose relative motion stays below its minimum motion (no solve)
MARGIN = 1e-9   # relative margin of the filters' floating-point tests


@jit
def _rotated(q, vx, vy, vz):
    """(x, y, z) of the vector (vx, vy, vz) rotated by the unit quaternion q [w, x, y, z] (scalars: the filters
    run once per pair and step, and a small array made there costs more than the arithmetic)."""
    w, x, y, z = q[0], q[1], q[2], q[3]
    tx = 2.0 * (y * vz - z * vy)
    ty = 2.0 * (z * vx - x * vz)
    tz = 2.0 * (x * vy - y * vx)
    return vx + w * tx + (y * tz - z * ty), vy + w * ty + (z * tx - x * tz), vz + w * tz + (x * ty - y * tx)


@jit
def geom_poses_into(xpos, xquat, body, local, out):
    """out (G, 7) = the world poses [x, y, z, qw, qx, qy, qz] of geoms fixed in bodies (body poses xpos (B, 3),
    xquat (B, 4); each geom's body index and its local pose (G, 7))."""
    for g in range(body.shape[0]):
        b = body[g]
        q = xquat[b]
        r = _rotated(q, local[g, 0], local[g, 1], local[g, 2])
        for i in range(3):
            out[g, i] = xpos[b, i] + r[i]
        bw, bx, by, bz = local[g, 3], local[g, 4], local[g, 5], local[g, 6]
        w, x, y, z = q[0], q[1], q[2], q[3]
        out[g, 3] = w * bw - x * bx - y * by - z * bz
        out[g, 4] = w * bx + x * bw + y * bz - z * by
        out[g, 5] = w * by - x * bz + y * bw + z * bx
        out[g, 6] = w * bz + x * by - y * bx + z * bw


@jit
def proxy(kind, size):
    """(axis, half length, radius, reach) of the capsule about a local axis that holds the shape, and the reach
    of its points from its centre."""
    if kind == sy.SPHERE:
        return 2, 0.0, size[0], size[0]
    if kind == sy.CAPSULE or kind == sy.CYLINDER:
        reach = size[0] + size[1] if kind == sy.CAPSULE else math.hypot(size[0], size[1])
        return 2, size[1], size[0], reach
    if kind == sy.PLANE:
        return 2, 0.0, 0.0, 0.0
    # a box or an ellipsoid: about its longest axis
    a = 0
    for i in range(1, 3):
        if size[i] > size[a]:
            a = i
    j, k = (a + 1) % 3, (a + 2) % 3
    if kind == sy.BOX:
        return a, size[a], math.hypot(size[j], size[k]), math.sqrt(size[0] ** 2 + size[1] ** 2 + size[2] ** 2)
    b = max(size[j], size[k])
    return a, size[a] - b, b, size[a]


@jit
def _gap_at(rx, ry, rz, d0, d1, s, u):
    """|r + s d0 - u d1|: the distance of the segments' points at parameters s and u."""
    dx = rx + s * d0[0] - u * d1[0]
    dy = ry + s * d0[1] - u * d1[1]
    dz = rz + s * d0[2] - u * d1[2]
    return math.sqrt(dx * dx + dy * dy + dz * dz)


@jit
def _segment_distance(p0, d0, p1, d1):
    """Distance between the segments p0 + s d0 and p1 + u d1 (s, u in [-1, 1]; d0, d1 (3,) or 3-tuples)."""
    rx, ry, rz = p0[0] - p1[0], p0[1] - p1[1], p0[2] - p1[2]
    a = d0[0] * d0[0] + d0[1] * d0[1] + d0[2] * d0[2]
    e = d1[0] * d1[0] + d1[1] * d1[1] + d1[2] * d1[2]
    f = d1[0] * rx + d1[1] * ry + d1[2] * rz
    c = d0[0] * rx + d0[1] * ry + d0[2] * rz
    b = d0[0] * d1[0] + d0[1] * d1[1] + d0[2] * d1[2]
    best = 1e300
    # the clamped closed form may miss the optimum on a degenerate configuration: try it and every end
    denom = a * e - b * b
    if denom > 1e-300 * (a * e + 1e-300):
        s = min(max((b * f - c * e) / denom, -1.0), 1.0)
        u = (b * s + f) / e if e > 0.0 else 0.0
        best = min(best, _gap_at(rx, ry, rz, d0, d1, s, min(max(u, -1.0), 1.0)))
    for end in (-1.0, 1.0):
        u = min(max((b * end + f) / e, -1.0), 1.0) if e > 0.0 else 0.0
        best = min(best, _gap_at(rx, ry, rz, d0, d1, end, u))
        s = min(max((b * end - c) / a, -1.0), 1.0) if a > 0.0 else 0.0
        best = min(best, _gap_at(rx, ry, rz, d0, d1, s, end))
    return best


@jit
def _axis(q, axis, half):
    """(x, y, z): the local axis ``axis`` scaled to ``half``, rotated by q."""
    return _rotated(q, half if axis == 0 else 0.0, half if axis == 1 else 0.0, half if axis == 2 else 0.0)


@jit
def _moves(Q0, Q1, g, reach):
    """How far any point of geom g (``reach`` from its centre) can move in the step: M of the module
    docstring."""
    c0, c1 = Q0[g, :3], Q1[g, :3]
    move = math.sqrt((c1[0] - c0[0]) ** 2 + (c1[1] - c0[1]) ** 2 + (c1[2] - c0[2]) ** 2)
    turn = abs(Q0[g, 3] * Q1[g, 3] + Q0[g, 4] * Q1[g, 4] + Q0[g, 5] * Q1[g, 5] + Q0[g, 6] * Q1[g, 6])
    # 2 sin(theta / 2) = 2 sqrt(1 - cos^2(theta / 2)), cos(theta / 2) = |q0 . q1|
    return move + 2.0 * math.sqrt(max(1.0 - min(turn, 1.0) ** 2, 0.0)) * reach


@jit
def relative_motion(kinds, sizes, Q0, Q1, ga, gb):
    """A bound of how far any point of geom ga moves relative to any point of gb in the step (a plane stays
    put)."""
    m = 0.0
    for g in (ga, gb):
        if kinds[g] != sy.PLANE:
            m += _moves(Q0, Q1, g, proxy(kinds[g], sizes[g])[3])
    return m


@jit
def clear(kinds, sizes, Q0, Q1, ga, gb, scratch):
    """True when geoms ga and gb cannot touch in the step from poses Q0 to Q1 (G, 7), by either filter of the
    module docstring (``scratch``: (SCRATCH_ROWS, 7) floats for the piecewise test)."""
    pa, pb = ga, gb
    if kinds[ga] == sy.PLANE:
        pa, pb = gb, ga
    ax_a, la, ra, reach_a = proxy(kinds[pa], sizes[pa])
    ax_b, lb, rb, reach_b = proxy(kinds[pb], sizes[pb])
    c0, c1 = Q0[pa, :3], Q1[pa, :3]
    move_a = _moves(Q0, Q1, pa, reach_a)
    if kinds[pb] == sy.PLANE:
        n = _rotated(Q0[pb, 3:], 0.0, 0.0, 1.0)
        o = Q0[pb, :3]
        h0 = n[0] * (c0[0] - o[0]) + n[1] * (c0[1] - o[1]) + n[2] * (c0[2] - o[2])
        h1 = n[0] * (c1[0] - o[0]) + n[1] * (c1[1] - o[1]) + n[2] * (c1[2] - o[2])
        if min(h0, h1) > reach_a * (1.0 + MARGIN) + MARGIN * (abs(h0) + abs(h1)):
            return True
        d = _axis(Q0[pa, 3:], ax_a, la)
        low = h0 - abs(n[0] * d[0] + n[1] * d[1] + n[2] * d[2]) - ra
        if low > move_a * (1.0 + MARGIN) + MARGIN * (abs(h0) + la + ra):
            return True
        return _pieces_clear(kinds, sizes, Q0, Q1, pa, pb, scratch)
    e0, e1 = Q0[pb, :3], Q1[pb, :3]
    # moving spheres: the centres' lines
    ux, uy, uz = c0[0] - e0[0], c0[1] - e0[1], c0[2] - e0[2]
    vx, vy, vz = (c1[0] - e1[0]) - ux, (c1[1] - e1[1]) - uy, (c1[2] - e1[2]) - uz
    vv = vx * vx + vy * vy + vz * vz
    t = 0.0
    if vv > 0.0:
        t = min(max(-(ux * vx + uy * vy + uz * vz) / vv, 0.0), 1.0)
    wx, wy, wz = ux + t * vx, uy + t * vy, uz + t * vz
    scale = abs(ux) + abs(uy) + abs(uz) + abs(vx) + abs(vy) + abs(vz)
    if math.sqrt(wx * wx + wy * wy + wz * wz) > (reach_a + reach_b) * (1.0 + MARGIN) + MARGIN * scale:
        return True
    # distance of the proxies at the start against how far their points can move
    move_b = _moves(Q0, Q1, pb, reach_b)
    gap = _segment_distance(c0, _axis(Q0[pa, 3:], ax_a, la), e0, _axis(Q0[pb, 3:], ax_b, lb)) - ra - rb
    if gap > (move_a + move_b) * (1.0 + MARGIN) + MARGIN * (scale + la + lb + ra + rb):
        return True
    return _pieces_clear(kinds, sizes, Q0, Q1, pa, pb, scratch)


SWEEP_MARGIN = 1e-6  # relative margin of the swept balls' test: far above its rounding and MARGIN's


@jit
def swept_balls(kinds, sizes, Q0, Q1, balls):
    """balls (G, 4) = each geom's swept ball of the step (module docstring): centre (3) and radius; a plane's
    radius is infinite (never cleared this way)."""
    for g in range(Q0.shape[0]):
        dx, dy, dz = Q1[g, 0] - Q0[g, 0], Q1[g, 1] - Q0[g, 1], Q1[g, 2] - Q0[g, 2]
        balls[g, 0] = Q0[g, 0] + 0.5 * dx
        balls[g, 1] = Q0[g, 1] + 0.5 * dy
        balls[g, 2] = Q0[g, 2] + 0.5 * dz
        if kinds[g] == sy.PLANE:
            balls[g, 3] = np.inf
        else:
            balls[g, 3] = 0.5 * math.sqrt(dx * dx + dy * dy + dz * dz) + proxy(kinds[g], sizes[g])[3]


@jit
def balls_apart(balls, ga, gb):
    """True when the swept balls of geoms ga and gb lie apart by more than SWEEP_MARGIN (relative to their
    radii and their centres' coordinates): the pair cannot touch in the step."""
    dx, dy, dz = balls[ga, 0] - balls[gb, 0], balls[ga, 1] - balls[gb, 1], balls[ga, 2] - balls[gb, 2]
    scale = (abs(balls[ga, 0]) + abs(balls[ga, 1]) + abs(balls[ga, 2]) + abs(balls[gb, 0]) + abs(balls[gb, 1])
             + abs(balls[gb, 2]))
    reach = (balls[ga, 3] + balls[gb, 3]) * (1.0 + SWEEP_MARGIN) + SWEEP_MARGIN * scale
    return dx * dx + dy * dy + dz * dz > reach * reach


@jit
def _lerp_pose(Q0, Q1, g, t, out):
    """out (7,) = geom g's pose at t of its rigid lerp: centre lerp, quaternion lerp the short way, normalised."""
    s = 1.0 if Q0[g, 3] * Q1[g, 3] + Q0[g, 4] * Q1[g, 4] + Q0[g, 5] * Q1[g, 5] + Q0[g, 6] * Q1[g, 6] >= 0.0 \
        else -1.0
    for i in range(3):
        out[i] = (1.0 - t) * Q0[g, i] + t * Q1[g, i]
    nq = 0.0
    for i in range(4):
        out[3 + i] = (1.0 - t) * Q0[g, 3 + i] + t * s * Q1[g, 3 + i]
        nq += out[3 + i] * out[3 + i]
    nq = math.sqrt(nq)
    for i in range(4):
        out[3 + i] /= nq


@jit
def _piece_moves(Q0, Q1, g, reach, lo, mid, hi, P):
    """How far any point of geom g moves from its pose P[1] at ``mid`` over [lo, hi] (P[0], P[2] its poses at
    the ends): the centre's share of its straight path, and ``2 sin(theta / 2) reach`` with theta the larger
    turn from mid to either end (the normalised lerp turns monotonically along one great circle)."""
    move = math.sqrt((Q1[g, 0] - Q0[g, 0]) ** 2 + (Q1[g, 1] - Q0[g, 1]) ** 2 + (Q1[g, 2] - Q0[g, 2]) ** 2)
    move *= max(mid - lo, hi - mid)
    cos = 1.0
    for e in (0, 2):
        c = abs(P[1, 3] * P[e, 3] + P[1, 4] * P[e, 4] + P[1, 5] * P[e, 5] + P[1, 6] * P[e, 6])
        cos = min(cos, c)
    return move + 2.0 * math.sqrt(max(1.0 - min(cos, 1.0) ** 2, 0.0)) * reach


MAX_DEPTH = 4  # halvings of the step for the piecewise test (pieces of 1/16 of the step)
SCRATCH_ROWS = 6 + 2 * MAX_DEPTH + 2  # the piecewise test's poses at a piece's ends and middle, and its stack


@jit
def _pieces_clear(kinds, sizes, Q0, Q1, pa, pb, scratch):
    """The distance-against-displacement test on pieces of the step, halved down to MAX_DEPTH: the proxies'
    gap at each piece's middle against how far their points move over the piece (pb may be a plane: the
    proxy's height above it plays the gap).  True when every piece clears.  ``scratch``: (SCRATCH_ROWS, 7)
    floats to work in."""
    ax_a, la, ra, reach_a = proxy(kinds[pa], sizes[pa])
    ax_b, lb, rb, reach_b = proxy(kinds[pb], sizes[pb])
    plane = kinds[pb] == sy.PLANE
    n = _rotated(Q0[pb, 3:], 0.0, 0.0, 1.0)
    A = scratch[0:3]
    B = scratch[3:6]
    scale = MARGIN * (abs(Q0[pa, 0]) + abs(Q0[pa, 1]) + abs(Q0[pa, 2]) + abs(Q0[pb, 0]) + abs(Q0[pb, 1])
                      + abs(Q0[pb, 2]) + abs(Q1[pa, 0]) + abs(Q1[pa, 1]) + abs(Q1[pa, 2]) + abs(Q1[pb, 0])
                      + abs(Q1[pb, 1]) + abs(Q1[pb, 2]) + la + lb + ra + rb + reach_a + reach_b)
    stack = scratch[6:SCRATCH_ROWS, :3]
    stack[0, 0], stack[0, 1], stack[0, 2] = 0.5, 1.0, 1.0
    stack[1, 0], stack[1, 1], stack[1, 2] = 0.0, 0.5, 1.0
    top = 2
    while top > 0:
        top -= 1
        lo, hi, depth = stack[top, 0], stack[top, 1], stack[top, 2]
        mid = 0.5 * (lo + hi)
        for r, t in ((0, lo), (1, mid), (2, hi)):
            _lerp_pose(Q0, Q1, pa, t, A[r])
            if not plane:
                _lerp_pose(Q0, Q1, pb, t, B[r])
        move = _piece_moves(Q0, Q1, pa, reach_a, lo, mid, hi, A)
        if plane:
            d = _axis(A[1, 3:], ax_a, la)
            gap = (n[0] * (A[1, 0] - Q0[pb, 0]) + n[1] * (A[1, 1] - Q0[pb, 1]) + n[2] * (A[1, 2] - Q0[pb, 2])
                   - abs(n[0] * d[0] + n[1] * d[1] + n[2] * d[2]) - ra)
        else:
            move += _piece_moves(Q0, Q1, pb, reach_b, lo, mid, hi, B)
            gap = (_segment_distance(A[1, :3], _axis(A[1, 3:], ax_a, la), B[1, :3], _axis(B[1, 3:], ax_b, lb))
                   - ra - rb)
        if gap > move * (1.0 + MARGIN) + scale:
            continue
        if gap <= scale or depth >= MAX_DEPTH:  # touching at the node (no halving helps), or no depth left
            return False
        stack[top, 0], stack[top, 1], stack[top, 2] = mid, hi, depth + 1
        stack[top + 1, 0], stack[top + 1, 1], stack[top + 1, 2] = lo, mid, depth + 1
        top += 2
    return True


@jit
def _row(Q0, Q1, g, origin, rows):
    """The element row of geom g's motion (its pose lerp), seen from ``origin``."""
    rows[0, 0] = fr.POSE
    s = 1.0
    if Q0[g, 3] * Q1[g, 3] + Q0[g, 4] * Q1[g, 4] + Q0[g, 5] * Q1[g, 5] + Q0[g, 6] * Q1[g, 6] < 0.0:
        s = -1.0  # the lerp takes the short way, as mjccd.Rigid does
    for i in range(3):
        rows[0, 1 + i] = Q0[g, i] - origin[i]
        rows[0, 8 + i] = Q1[g, i] - origin[i]
    for i in range(4):
        rows[0, 4 + i] = Q0[g, 3 + i]
        rows[0, 11 + i] = s * Q1[g, 3 + i]


@jit
def below_plane(kinds, sizes, Q0, g, p):
    """True when geom g certainly reaches below the plane geom p (the solid z <= 0 of its frame) at the step's
    start by more than a relative MARGIN: its lowest point along the plane's normal n, ``n . (c - o) - h``
    with h the shape's support along -n, computed from the pose as given.  A body resting on a floor under
    MuJoCo's soft contacts sinks in by far more, so its pair needs no solve to be overlapping."""
    w, x, y, z = Q0[p, 3], Q0[p, 4], Q0[p, 5], Q0[p, 6]  # n: the third column of the plane's rotation
    n0, n1, n2 = 2.0 * (x * z + w * y), 2.0 * (y * z - w * x), w * w - x * x - y * y + z * z
    height = n0 * (Q0[g, 0] - Q0[p, 0]) + n1 * (Q0[g, 1] - Q0[p, 1]) + n2 * (Q0[g, 2] - Q0[p, 2])
    # the plane's normal in the geom's frame: the columns of its rotation dotted with n
    w, x, y, z = Q0[g, 3], Q0[g, 4], Q0[g, 5], Q0[g, 6]
    m0 = abs((w * w + x * x - y * y - z * z) * n0 + 2.0 * (x * y + w * z) * n1 + 2.0 * (x * z - w * y) * n2)
    m1 = abs(2.0 * (x * y - w * z) * n0 + (w * w - x * x + y * y - z * z) * n1 + 2.0 * (y * z + w * x) * n2)
    m2 = abs(2.0 * (x * z + w * y) * n0 + 2.0 * (y * z - w * x) * n1 + (w * w - x * x - y * y + z * z) * n2)
    kind, size = kinds[g], sizes[g]
    if kind == sy.SPHERE:
        h = size[0]
    elif kind == sy.CAPSULE:
        h = size[0] + size[1] * m2
    elif kind == sy.CYLINDER:
        h = size[1] * m2 + size[0] * math.sqrt(max(0.0, 1.0 - m2 * m2))
    elif kind == sy.BOX:
        h = size[0] * m0 + size[1] * m1 + size[2] * m2
    elif kind == sy.ELLIPSOID:
        h = math.sqrt((size[0] * m0) ** 2 + (size[1] * m1) ** 2 + (size[2] * m2) ** 2)
    else:
        return False
    scale = abs(Q0[g, 0]) + abs(Q0[g, 1]) + abs(Q0[g, 2]) + abs(Q0[p, 0]) + abs(Q0[p, 1]) + abs(Q0[p, 2]) + h
    return height - h < -MARGIN * scale


@jit
def cores_overlap(kinds, sizes, Q0, ga, gb):
    """True when two rounded geoms (spheres, capsules) certainly overlap at the step's start: their cores
    (points, segments) lie closer than the sum of their radii by more than a relative MARGIN."""
    ax_a, la, ra, _ = proxy(kinds[ga], sizes[ga])
    ax_b, lb, rb, _ = proxy(kinds[gb], sizes[gb])
    scale = (abs(Q0[ga, 0]) + abs(Q0[ga, 1]) + abs(Q0[ga, 2]) + abs(Q0[gb, 0]) + abs(Q0[gb, 1]) + abs(Q0[gb, 2])
             + la + lb + ra + rb)
    d = _segment_distance(Q0[ga, :3], _axis(Q0[ga, 3:], ax_a, la), Q0[gb, :3], _axis(Q0[gb, 3:], ax_b, lb))
    return d < ra + rb - MARGIN * scale


@jit
def _overlapping(out, k):
    """out row k of a pair in contact at the step's start, decided without a solve."""
    for f in range(kn.OUT):
        out[k, f] = 0.0
    out[k, kn.STATUS] = -1.0
    out[k, kn.CERTIFIED] = 1.0
    out[k, kn.PROVEN] = 1.0


@jit
def _cleared(out, k, code):
    """out row k of a pair left without a solve: separate, no contact, out[FAILED] = code (the row by index: a
    row view made for each of a step's many cleared pairs costs more than the writes)."""
    for f in range(kn.OUT):
        out[k, f] = 0.0
    out[k, kn.STATUS] = 1.0
    out[k, kn.LO] = out[k, kn.HI] = out[k, kn.TIME] = -1.0
    out[k, kn.CERTIFIED] = 1.0
    out[k, kn.FAILED] = code


@jit
def step_pairs(kinds, sizes, Q0, Q1, pairs, min_motion, t_max, all_pairs, new_only, W, I, Wdd, Idd, CON, SYS, SYSR,
               N, out):
    """Every geom pair's answer for one step into ``out`` (P, kernel.OUT): pairs the filters clear get
    out[FAILED] = FILTERED, pairs that move less than ``min_motion`` (P,) relative to each other TOO_SLOW;
    the others :func:`mjccd.geoms.kernel.pair_kernel`'s answer (world point), over
    [0, t_max] and, unless ``all_pairs``, only up to the earliest first contact found so far.  With
    ``new_only`` pairs not separate at the start do not count as contacts.  Returns the index of the earliest
    contact (-1: none); pairs the kernel leaves to the ellipsoid solver (out[FAILED] NOT_HANDLED or PARTIAL)
    are the caller's to finish.

    kinds (G,), sizes (G, 3): the geoms' shapes; Q0, Q1 (G, 7): their world poses [x, y, z, qw, qx, qy, qz]
    at both ends (unit quaternions); pairs (P, 2) geom rows.
    """
    rows_a = np.zeros((1, fr.ELEMENT_FIELDS))
    rows_b = np.zeros((1, fr.ELEMENT_FIELDS))
    scratch = np.empty((SCRATCH_ROWS, 7))
    balls = np.empty((Q0.shape[0], 4))
    swept_balls(kinds, sizes, Q0, Q1, balls)
    best, best_t = -1, t_max
    for k in range(pairs.shape[0]):
        ga, gb = pairs[k, 0], pairs[k, 1]
        if balls_apart(balls, ga, gb) or clear(kinds, sizes, Q0, Q1, ga, gb, scratch):
            _cleared(out, k, FILTERED)
            continue
        if min_motion[k] > 0.0 and relative_motion(kinds, sizes, Q0, Q1, ga, gb) < min_motion[k]:
            _cleared(out, k, TOO_SLOW)
            continue
        if kinds[ga] == sy.PLANE or kinds[gb] == sy.PLANE:
            g, p = (gb, ga) if kinds[ga] == sy.PLANE else (ga, gb)
            sunk = below_plane(kinds, sizes, Q0, g, p)  # resting on a floor
        else:
            sunk = sy.rounded(kinds[ga]) and sy.rounded(kinds[gb]) and cores_overlap(kinds, sizes, Q0, ga, gb)
        if sunk:  # overlapping at the start, no solve
            _overlapping(out, k)
            if new_only:
                continue
            if best < 0 or 0.0 < best_t:
                best, best_t = k, 0.0
            continue
        o = out[k]
        origin = (Q0[ga, :3] if kinds[ga] != sy.PLANE else Q0[gb, :3]).copy()
        _row(Q0, Q1, ga, origin, rows_a)
        _row(Q0, Q1, gb, origin, rows_b)
        kn.pair_kernel(kinds[ga], sizes[ga], rows_a, kinds[gb], sizes[gb], rows_b, t_max if all_pairs else best_t,
                       W, I, Wdd, Idd, CON, SYS, SYSR, N, o)
        for i in range(3):
            o[kn.POINT + i] += origin[i]
        if o[kn.FAILED] == kn.NOT_HANDLED or o[kn.FAILED] == kn.OVERFLOW:
            continue
        if o[kn.STATUS] != 1.0:
            if new_only:
                continue
            t = 0.0
        else:
            if o[kn.LO] < 0.0:
                continue
            t = o[kn.TIME]
        if best < 0 or t < best_t:
            best, best_t = k, t
    return best


# tally's counts, in this order, and what it answers when a pair is left to the ellipsoid solver
TALLIES = ("sphere_culled", "too_slow", "solved_exactly", "overlapping_t0", "colliding", "uncertain")
NEEDS_SOLVER = -2


@jit
def tally(out, new_only, counts):
    """The first contact and the counts of :func:`step_pairs`' answers ``out`` (P, kernel.OUT), read as
    :meth:`mjccd.mujoco.geoms.GeomChecker.check_poses` reads each row: counts (6,) = :data:`TALLIES`; returns
    the row of the first contact (earliest time, then lowest row; a pair not separate at the start at time 0,
    an uncertain one at its bracket's start), -1 when none, or :data:`NEEDS_SOLVER` when a row is not the
    kernel's own answer (left to the ellipsoid solver, or a workspace overflow): the caller then reads every
    row itself.

    One pass over the rows in compiled code: a small model's step is cheaper than reading its rows in
    Python."""
    for i in range(counts.shape[0]):
        counts[i] = 0
    best, best_t = -1, 0.0
    for k in range(out.shape[0]):  # rows by index: a row view each costs more than the reads
        failed = out[k, kn.FAILED]
        if failed == FILTERED:
            counts[0] += 1
            continue
        if failed == TOO_SLOW:
            counts[1] += 1
            continue
        if failed == kn.NOT_HANDLED or failed == kn.PARTIAL or failed == kn.OVERFLOW:
            return NEEDS_SOLVER
        counts[2] += 1
        if out[k, kn.STATUS] != 1.0:
            counts[3] += 1
            if new_only:
                continue
            t = 0.0
        elif out[k, kn.LO] < 0.0:
            continue
        else:
            certain = out[k, kn.CERTIFIED] > 0.0
            if not certain:
                counts[5] += 1
            t = out[k, kn.TIME] if certain else out[k, kn.LO]
        counts[4] += 1
        if best < 0 or t < best_t:
            best, best_t = k, t
    return best
