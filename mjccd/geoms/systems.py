"""Contact of two moving shapes as a list of polynomial systems in t (numba kernels).

Every shape pair is reduced to *systems*: a few constraints ``p_j(t) <= 0``
(univariate, or bivariate in (s, t) for a point running on a circle) that hold
exactly when a candidate point, a *witness*, lies in both solids.  Each system is

* *genuine*: when it holds, its witness is a common point of the two solids;
* and the systems together are *complete*: whenever the solids meet, one of
  them holds (in particular at the first contact).

So the first contact of the pair is the first time any system holds, and a
proof that one holds at t is a proof of contact at t.

The reductions (docs/method.md, "MuJoCo's geoms"):

* a sphere is a point and a capsule a segment, *rounded* by their radius: the
  pair touches when the rounded core of one comes within the sum of the radii
  of the other shape, i.e. enters that shape inflated by the radii (the
  inflated solid is a union of convex *pieces*: balls, slabs, cylinders about
  an axis, tori about a circle);
* a point in a piece is a univariate system (its constraints at the point);
* a segment meets a convex piece (linear constraints and at most one quadric)
  exactly when one of these candidates lies in it: an end point, the vertex of
  the quadric along the segment (tangency), or the crossing of one of its
  planes (entering or leaving);
* a box's vertices and edges, a cylinder's rims (a circle: bivariate) and its
  caps and side, an ellipsoid's sections and shadows are the faces, edges and
  vertices of the thesis' composite quadric models (chapter 6), each against
  the other solid.

Constraint slots live in a :mod:`mjccd.geoms.poly` workspace; the systems in
three arrays: ``CON`` (ds, row slots: ds = 0 for a univariate constraint),
``SYS`` (constraint start, count, side, witness degree in s, witness slots)
and ``SYSR`` (the witness's rounding radius).  Side 0: the witness is in A's
frame and A is the solid it meets; side 1: the other way round.
"""
import numpy as np

from mjccd.geoms import frames as fr
from mjccd.geoms import poly as P
from mjccd.geoms.poly import _jit

SPHERE, CAPSULE, CYLINDER, BOX, ELLIPSOID, PLANE = 0, 1, 2, 3, 4, 5
KIND_NAMES = ("sphere", "capsule", "cylinder", "box", "ellipsoid", "plane")

NONE, BALL, AXCYL, ELLIPSOIDAL = 0, 1, 2, 3  # quadric of a piece
QPRM = 7                                      # its parameters: axis, centre (3), radius terms (3)
LIN = 6                                       # a linear constraint a . x <= c1 + c2 + c3
MAXLIN = 6
SYS_FIELDS = 28
WIT = 8                                       # first witness slot column of SYS: 4 coordinates x 5 rows

# ---------------------------------------------------------------- the system store


@_jit
def new_store(max_systems, max_constraints):
    """Empty system arrays: CON, SYS, SYSR, counts N = [constraints, systems, overflow]."""
    return (np.zeros((max_constraints, 6), dtype=np.int64), np.zeros((max_systems, SYS_FIELDS), dtype=np.int64),
            np.zeros(max_systems), np.zeros(3, dtype=np.int64))


@_jit
def _con(CON, N, slot):
    """Append the univariate constraint ``slot <= 0``."""
    if N[0] >= CON.shape[0]:
        N[2] = 1
        return
    CON[N[0], 0] = 0
    CON[N[0], 1] = slot
    N[0] += 1


@_jit
def _bcon(CON, N, rows):
    """Append the bivariate constraint given by its rows (one slot per Bernstein coefficient in s)."""
    if N[0] >= CON.shape[0]:
        N[2] = 1
        return
    CON[N[0], 0] = rows.shape[0] - 1
    for i in range(rows.shape[0]):
        CON[N[0], 1 + i] = rows[i]
    N[0] += 1


@_jit
def _close(SYS, SYSR, N, start, side, wit, r_w):
    """Close the system of the constraints appended since ``start``; its witness: homogeneous point ``wit``
    (4 slots, univariate) in the frame of its side."""
    if N[1] >= SYS.shape[0] or N[2]:
        N[2] = 1
        return
    k = N[1]
    SYS[k, 0], SYS[k, 1], SYS[k, 2], SYS[k, 3] = start, N[0] - start, side, 0
    for c in range(4):
        SYS[k, WIT + 5 * c] = wit[c]
    SYSR[k] = r_w
    N[1] += 1


@_jit
def _bclose(SYS, SYSR, N, start, side, wit, r_w):
    """As :func:`_close` for a bivariate witness ``wit`` (4, ds + 1) of row slots."""
    if N[1] >= SYS.shape[0] or N[2]:
        N[2] = 1
        return
    k = N[1]
    ds = wit.shape[1] - 1
    SYS[k, 0], SYS[k, 1], SYS[k, 2], SYS[k, 3] = start, N[0] - start, side, ds
    for c in range(4):
        for i in range(ds + 1):
            SYS[k, WIT + 5 * c + i] = wit[c, i]
    SYSR[k] = r_w
    N[1] += 1


# ---------------------------------------------------------------- forms on homogeneous points


@_jit
def _positive(W, I, k):
    """True when slot k is proven > 0 on all of [0, 1] (a constraint that can never hold)."""
    e = P.error(W, I, k)
    for i in range(I[k, 0] + 1):
        if not W[k, 0, i] > e:
            return False
    return True


@_jit
def _lin(W, I, pt, row):
    """a . X - (c1 + c2 + c3) Xw for the homogeneous point ``pt`` (4 slots) and the constraint ``row``."""
    acc = -1
    for i in range(3):
        if row[i] != 0.0:
            term = P.scale(W, I, pt[i], row[i])
            acc = term if acc < 0 else P.add(W, I, acc, term, 1.0)
    for m in range(3):
        if row[3 + m] != 0.0:
            acc = P.scale(W, I, pt[3], -row[3 + m]) if acc < 0 else P.add(W, I, acc, pt[3], -row[3 + m])
    return acc if acc >= 0 else P.const(W, I, 0.0)


@_jit
def _radius_times(W, I, w, prm):
    """(R1 + R2 + R3) w for the radius terms prm[4:7]."""
    acc = -1
    for m in range(3):
        if prm[4 + m] != 0.0:
            term = P.scale(W, I, w, prm[4 + m])
            acc = term if acc < 0 else P.add(W, I, acc, term, 1.0)
    return acc if acc >= 0 else P.const(W, I, 0.0)


@_jit
def _bilinear(W, I, qk, prm, U, V):
    """The symmetric bilinear form of the piece's quadric on homogeneous points U, V (4 slots each): ball
    ``(U - e Uw).(V - e Vw) - R^2 Uw Vw``, cylinder about axis prm[0] through e (the other two coordinates),
    ellipsoid with radii prm[1:4] ``sum U_i V_i / r_i^2 - Uw Vw``."""
    acc = -1
    if qk == ELLIPSOIDAL:
        for i in range(3):
            term = P.mul(W, I, P.frac(W, I, U[i], 1.0, prm[1 + i]), P.frac(W, I, V[i], 1.0, prm[1 + i]))
            acc = term if acc < 0 else P.add(W, I, acc, term, 1.0)
        return P.add(W, I, acc, P.mul(W, I, U[3], V[3]), -1.0)
    axis = int(prm[0]) if qk == AXCYL else -1
    for i in range(3):
        if i == axis:
            continue
        du = U[i] if prm[1 + i] == 0.0 else P.add(W, I, U[i], U[3], -prm[1 + i])
        dv = V[i] if prm[1 + i] == 0.0 else P.add(W, I, V[i], V[3], -prm[1 + i])
        term = P.mul(W, I, du, dv)
        acc = term if acc < 0 else P.add(W, I, acc, term, 1.0)
    return P.add(W, I, acc, P.mul(W, I, _radius_times(W, I, U[3], prm), _radius_times(W, I, V[3], prm)), -1.0)


@_jit
def _combine(W, I, a, U, b, V):
    """The homogeneous point a U + b V for slots a, b (4 slots each way)."""
    out = np.empty(4, dtype=np.int64)
    for c in range(4):
        out[c] = P.add(W, I, P.mul(W, I, a, U[c]), P.mul(W, I, b, V[c]), 1.0)
    return out


# ---------------------------------------------------------------- pieces


@_jit
def new_pieces(n):
    """Arrays of n convex pieces: quadric kind, its parameters, linear constraints and their count."""
    return (np.zeros(n, dtype=np.int64), np.zeros((n, QPRM)), np.zeros((n, MAXLIN, LIN)),
            np.zeros(n, dtype=np.int64), np.zeros(1, dtype=np.int64))


@_jit
def _piece(PQ, PP, PL, PN, cnt, qk, axis, e0, e1, e2, R1, R2, R3):
    k = cnt[0]
    cnt[0] += 1
    PQ[k] = qk
    PP[k, 0], PP[k, 1], PP[k, 2], PP[k, 3] = axis, e0, e1, e2
    PP[k, 4], PP[k, 5], PP[k, 6] = R1, R2, R3
    PN[k] = 0
    return k


@_jit
def _bound(PL, PN, k, i, sign, c1, c2, c3):
    """Add sign * x_i <= c1 + c2 + c3 to piece k."""
    r = PN[k]
    PN[k] += 1
    for m in range(3):
        PL[k, r, m] = 0.0
    PL[k, r, i] = sign
    PL[k, r, 3], PL[k, r, 4], PL[k, r, 5] = c1, c2, c3


@_jit
def solid_pieces(kind, size, R1, R2):
    """The convex pieces whose union is the shape ``kind`` (core for a sphere or capsule) inflated by
    R1 + R2; tori are not pieces (a rounded cylinder's rims are handled apart)."""
    PQ, PP, PL, PN, cnt = new_pieces(27)
    if kind == SPHERE:
        _piece(PQ, PP, PL, PN, cnt, BALL, 0.0, 0.0, 0.0, 0.0, R1, R2, 0.0)
    elif kind == CAPSULE:
        h = size[1]
        _piece(PQ, PP, PL, PN, cnt, BALL, 0.0, 0.0, 0.0, h, R1, R2, 0.0)
        _piece(PQ, PP, PL, PN, cnt, BALL, 0.0, 0.0, 0.0, -h, R1, R2, 0.0)
        k = _piece(PQ, PP, PL, PN, cnt, AXCYL, 2.0, 0.0, 0.0, 0.0, R1, R2, 0.0)
        _bound(PL, PN, k, 2, 1.0, h, 0.0, 0.0)
        _bound(PL, PN, k, 2, -1.0, h, 0.0, 0.0)
    elif kind == BOX:
        for i in range(3):  # a slab: the box grown along axis i
            k = _piece(PQ, PP, PL, PN, cnt, NONE, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0)
            for j in range(3):
                for sgn in (1.0, -1.0):
                    if j == i:
                        _bound(PL, PN, k, j, sgn, size[j], R1, R2)
                    else:
                        _bound(PL, PN, k, j, sgn, size[j], 0.0, 0.0)
            if R1 == 0.0 and R2 == 0.0:
                break
        if R1 != 0.0 or R2 != 0.0:
            for i in range(3):  # edge cylinders along axis i
                j, l = (i + 1) % 3, (i + 2) % 3
                for sj in (1.0, -1.0):
                    for sl in (1.0, -1.0):
                        e = np.zeros(3)
                        e[j], e[l] = sj * size[j], sl * size[l]
                        k = _piece(PQ, PP, PL, PN, cnt, AXCYL, float(i), e[0], e[1], e[2], R1, R2, 0.0)
                        _bound(PL, PN, k, i, 1.0, size[i], 0.0, 0.0)
                        _bound(PL, PN, k, i, -1.0, size[i], 0.0, 0.0)
            for sx in (1.0, -1.0):
                for sy in (1.0, -1.0):
                    for sz in (1.0, -1.0):
                        _piece(PQ, PP, PL, PN, cnt, BALL, 0.0, sx * size[0], sy * size[1], sz * size[2],
                               R1, R2, 0.0)
    elif kind == CYLINDER:
        r, h = size[0], size[1]
        k = _piece(PQ, PP, PL, PN, cnt, AXCYL, 2.0, 0.0, 0.0, 0.0, r, 0.0, 0.0)  # grown along the axis
        _bound(PL, PN, k, 2, 1.0, h, R1, R2)
        _bound(PL, PN, k, 2, -1.0, h, R1, R2)
        if R1 != 0.0 or R2 != 0.0:
            k = _piece(PQ, PP, PL, PN, cnt, AXCYL, 2.0, 0.0, 0.0, 0.0, r, R1, R2)  # grown sideways
            _bound(PL, PN, k, 2, 1.0, h, 0.0, 0.0)
            _bound(PL, PN, k, 2, -1.0, h, 0.0, 0.0)
    elif kind == PLANE:
        k = _piece(PQ, PP, PL, PN, cnt, NONE, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0)
        _bound(PL, PN, k, 2, 1.0, R1, R2, 0.0)
    elif kind == ELLIPSOID:
        k = _piece(PQ, PP, PL, PN, cnt, ELLIPSOIDAL, 0.0, size[0], size[1], size[2], 0.0, 0.0, 0.0)
    return PQ, PP, PL, PN, cnt[0]


# ---------------------------------------------------------------- candidates


@_jit
def point_in_piece(W, I, CON, SYS, SYSR, N, pt, qk, qp, lins, nlin, side, r_w):
    """The system 'the homogeneous point pt lies in the piece'."""
    lv = np.empty(MAXLIN, dtype=np.int64)
    for r in range(nlin):
        lv[r] = _lin(W, I, pt, lins[r])
        if _positive(W, I, lv[r]):
            return
    q = -1
    if qk != NONE:
        q = _bilinear(W, I, qk, qp, pt, pt)
        if _positive(W, I, q):
            return
    start = N[0]
    for r in range(nlin):
        _con(CON, N, lv[r])
    if q >= 0:
        _con(CON, N, q)
    _close(SYS, SYSR, N, start, side, pt, r_w)


@_jit
def _may_be_negative(W, I, k):
    """False when slot k is proven > 0 everywhere (so ``k <= 0`` never holds)."""
    return not _positive(W, I, k)


@_jit
def segment_in_piece(W, I, CON, SYS, SYSR, N, p0, p1, qk, qp, lins, nlin, side, r_w, ends, crossings):
    """The systems 'the segment [p0, p1] (homogeneous points of one weight) meets the piece': its end points
    (with ``ends``), the vertex of the quadric along it, and (with ``crossings``) its crossings of each plane,
    entering and leaving.  Together they hold exactly when the segment meets the piece."""
    if ends:
        point_in_piece(W, I, CON, SYS, SYSR, N, p0, qk, qp, lins, nlin, side, r_w)
        point_in_piece(W, I, CON, SYS, SYSR, N, p1, qk, qp, lins, nlin, side, r_w)
    zero = P.const(W, I, 0.0)
    d = np.empty(4, dtype=np.int64)
    for c in range(3):
        d[c] = P.add(W, I, p1[c], p0[c], -1.0)
    d[3] = zero
    if qk != NONE:
        al = _bilinear(W, I, qk, qp, d, d)
        if not P.is_zero(W, I, al):
            be = _bilinear(W, I, qk, qp, p0, d)
            ga = _bilinear(W, I, qk, qp, p0, p0)
            c1 = P.add(W, I, ga, al, -1.0)                 # q(0) <= alpha: implied, and well conditioned
            c2 = P.add(W, I, P.scale(W, I, be, 2.0), ga, 1.0)  # q(1) <= alpha
            if _may_be_negative(W, I, c1) and _may_be_negative(W, I, c2) and _may_be_negative(W, I, be):
                c3 = P.scale(W, I, P.add(W, I, al, be, 1.0), -1.0)  # -beta <= alpha: the vertex before the end
                disc = P.add(W, I, P.mul(W, I, al, ga), P.sq(W, I, be), -1.0)  # alpha gamma - beta^2 <= 0
                mb = P.scale(W, I, be, -1.0)
                wit = _combine(W, I, al, p0, mb, d)
                lv = np.empty(MAXLIN, dtype=np.int64)
                ok = _may_be_negative(W, I, c3) and _may_be_negative(W, I, disc)
                for r in range(nlin):
                    if not ok:
                        break
                    lv[r] = _lin(W, I, wit, lins[r])
                    ok = _may_be_negative(W, I, lv[r])
                if ok:
                    start = N[0]
                    _con(CON, N, c1)
                    _con(CON, N, c2)
                    _con(CON, N, be)
                    _con(CON, N, c3)
                    _con(CON, N, disc)
                    for r in range(nlin):
                        _con(CON, N, lv[r])
                    _close(SYS, SYSR, N, start, side, wit, r_w)
    if not crossings:
        return
    for k in range(nlin):
        u = _lin(W, I, p0, lins[k])
        v = _lin(W, I, p1, lins[k])
        for sense in (1.0, -1.0):  # entering (u >= 0 >= v), leaving (u <= 0 <= v)
            su = P.scale(W, I, u, -sense)
            sv = P.scale(W, I, v, sense)
            if not (_may_be_negative(W, I, su) and _may_be_negative(W, I, sv)):
                continue
            wit = _combine(W, I, v, p0, P.scale(W, I, u, -1.0), p1)  # weight (v - u) w: negative when entering
            lv = np.empty(MAXLIN, dtype=np.int64)
            ok = True
            for r in range(nlin):
                if r == k:
                    continue
                lv[r] = P.scale(W, I, _lin(W, I, wit, lins[r]), -sense)  # over a weight of sign -sense
                if not _may_be_negative(W, I, lv[r]):
                    ok = False
                    break
            if not ok:
                continue
            q = -1
            if qk != NONE:
                q = _bilinear(W, I, qk, qp, wit, wit)
                if _positive(W, I, q):
                    continue
            start = N[0]
            _con(CON, N, su)
            _con(CON, N, sv)
            for r in range(nlin):
                if r != k:
                    _con(CON, N, lv[r])
            if q >= 0:
                _con(CON, N, q)
            _close(SYS, SYSR, N, start, side, wit, r_w)


@_jit
def point_in_torus(W, I, CON, SYS, SYSR, N, pt, rc, zc, R1, R2, side, r_w):
    """The systems 'pt lies within R1 + R2 of the circle of radius rc about the z axis at height zc':
    K <= 0, or K^2 <= 4 rc^2 rho^2, with K = rho^2 + (z - zc)^2 + rc^2 - R^2 (homogeneous)."""
    zw = pt[2] if zc == 0.0 else P.add(W, I, pt[2], pt[3], -zc)
    rho2 = P.add(W, I, P.sq(W, I, pt[0]), P.sq(W, I, pt[1]), 1.0)
    rw = P.scale(W, I, pt[3], rc)
    Rw = P.add(W, I, P.scale(W, I, pt[3], R1), P.scale(W, I, pt[3], R2), 1.0)
    K = P.add(W, I, P.add(W, I, rho2, P.sq(W, I, zw), 1.0), P.add(W, I, P.sq(W, I, rw), P.sq(W, I, Rw), -1.0), 1.0)
    if not _positive(W, I, K):
        start = N[0]
        _con(CON, N, K)
        _close(SYS, SYSR, N, start, side, pt, r_w)
    T = P.add(W, I, P.sq(W, I, K), P.mul(W, I, P.scale(W, I, P.sq(W, I, rw), 4.0), rho2), -1.0)
    if not _positive(W, I, T):
        start = N[0]
        _con(CON, N, T)
        _close(SYS, SYSR, N, start, side, pt, r_w)


# ---------------------------------------------------------------- shape pairs


@_jit
def rounded(kind):
    """True for the shapes that are a core (point, segment) rounded by a radius: sphere and capsule."""
    return kind == SPHERE or kind == CAPSULE


@_jit
def _core_points(W, I, kind, size, H):
    """The core of a rounded shape under the map H: one point (sphere) or the two ends of the segment."""
    if kind == SPHERE:
        pts = np.empty((1, 4), dtype=np.int64)
        pts[0] = fr.point(W, I, H, 0.0, 0.0, 0.0)
        return pts
    pts = np.empty((2, 4), dtype=np.int64)
    pts[0] = fr.point(W, I, H, 0.0, 0.0, -size[1])
    pts[1] = fr.point(W, I, H, 0.0, 0.0, size[1])
    return pts


@_jit
def _box_corner(size, v):
    """Local coordinates of the box vertex number v (bits: sign of x, y, z)."""
    return (size[0] if v & 1 else -size[0]), (size[1] if v & 2 else -size[1]), (size[2] if v & 4 else -size[2])


@_jit
def _box_vertices(W, I, size, H):
    out = np.empty((8, 4), dtype=np.int64)
    for v in range(8):
        x, y, z = _box_corner(size, v)
        out[v] = fr.point(W, I, H, x, y, z)
    return out


@_jit
def _points_in_solid(W, I, CON, SYS, SYSR, N, pts, kind, size, R1, R2, side, r_w):
    """Each point of ``pts`` against the solid ``kind`` inflated by R1 + R2 (rims of a rounded cylinder
    included)."""
    PQ, PP, PL, PN, npc = solid_pieces(kind, size, R1, R2)
    for m in range(pts.shape[0]):
        for k in range(npc):
            point_in_piece(W, I, CON, SYS, SYSR, N, pts[m], PQ[k], PP[k], PL[k], PN[k], side, r_w)
        if kind == CYLINDER and (R1 != 0.0 or R2 != 0.0):
            for zc in (size[1], -size[1]):
                point_in_torus(W, I, CON, SYS, SYSR, N, pts[m], size[0], zc, R1, R2, side, r_w)


@_jit
def _segment_in_solid(W, I, CON, SYS, SYSR, N, p0, p1, kind, size, R1, R2, side, r_w, ends, crossings):
    PQ, PP, PL, PN, npc = solid_pieces(kind, size, R1, R2)
    for k in range(npc):
        segment_in_piece(W, I, CON, SYS, SYSR, N, p0, p1, PQ[k], PP[k], PL[k], PN[k], side, r_w, ends, crossings)


@_jit
def _plane_rims(W, I, CON, SYS, SYSR, N, size, H, side):
    """A cylinder (map H into the plane's frame) against the half-space z <= 0: for each rim, its centre below
    the plane, or its lowest point (C_z <= r |a x e_z| in homogeneous terms, squared)."""
    r, h = size[0], size[1]
    U = fr.direction(W, I, H, 0.0, 0.0, 1.0)
    drop = P.add(W, I, P.sq(W, I, P.scale(W, I, H[fr.M0], r)), P.sq(W, I, P.scale(W, I, U[2], r)), -1.0)
    for zc in (h, -h):
        C = fr.point(W, I, H, 0.0, 0.0, zc)
        if not _positive(W, I, C[2]):
            start = N[0]
            _con(CON, N, C[2])
            _close(SYS, SYSR, N, start, side, C, 0.0)
        T = P.add(W, I, P.sq(W, I, C[2]), drop, -1.0)
        if not _positive(W, I, T):
            # the lowest point of the rim, exact where C_z = r sqrt(w^2 - U_z^2) (at the touch)
            r2 = r * r
            wit = np.empty(4, dtype=np.int64)
            for c in range(2):
                wit[c] = P.add(W, I, P.mul(W, I, C[c], C[2]), P.mul(W, I, U[2], U[c]), r2)
            wit[2] = T
            wit[3] = P.mul(W, I, H[fr.M0], C[2])
            start = N[0]
            _con(CON, N, T)
            _close(SYS, SYSR, N, start, side, wit, 0.0)


@_jit
def _box_edges_in(W, I, CON, SYS, SYSR, N, vb, kind, size, side):
    """The 12 edges of a box (its vertices ``vb`` in the other frame) against the solid ``kind``: tangencies
    and plane crossings (the vertices themselves are systems of their own)."""
    PQ, PP, PL, PN, npc = solid_pieces(kind, size, 0.0, 0.0)
    for v in range(8):
        for bit in (1, 2, 4):
            if v & bit:
                continue
            for k in range(npc):
                segment_in_piece(W, I, CON, SYS, SYSR, N, vb[v], vb[v | bit], PQ[k], PP[k], PL[k], PN[k], side,
                                 0.0, False, True)


@_jit
def build_pair(W, I, CON, SYS, SYSR, N, ka, sa, FA, kb, sb, FB):
    """All systems of the pair (shape ka, size sa, frame FA) and (kb, sb, FB); returns False for a pair this
    builder does not handle (ellipsoid pairs with a sphere, a capsule's end or another ellipsoid)."""
    HAB = fr.relative(W, I, FA, FB)  # B's frame into A's
    if rounded(kb) and (kb == SPHERE or not rounded(ka) or ka == CAPSULE):
        # B's core into A: A inflated by B's radius (and A's own, when A is rounded)
        if ka == ELLIPSOID:
            return False
        pts = _core_points(W, I, kb, sb, HAB)
        ra = sa[0] if rounded(ka) else 0.0
        if kb == SPHERE:
            _points_in_solid(W, I, CON, SYS, SYSR, N, pts, ka, sa, sb[0], ra, 0, sb[0])
        else:
            _points_in_solid(W, I, CON, SYS, SYSR, N, pts, ka, sa, sb[0], ra, 0, sb[0])
            _segment_in_solid(W, I, CON, SYS, SYSR, N, pts[0], pts[1], ka, sa, sb[0], ra, 0, sb[0], False, True)
            if ka == CYLINDER:
                return False  # segment against the rims' tori: bivariate (not yet)
        return True
    if rounded(ka):
        return build_pair(W, I, CON, SYS, SYSR, N, kb, sb, FB, ka, sa, FA) and _flip(SYS, N)
    if ka == PLANE or kb == PLANE:
        if ka != PLANE:
            return build_pair(W, I, CON, SYS, SYSR, N, kb, sb, FB, ka, sa, FA) and _flip(SYS, N)
        if kb == BOX:
            _points_in_solid(W, I, CON, SYS, SYSR, N, _box_vertices(W, I, sb, HAB), PLANE, sa, 0.0, 0.0, 0, 0.0)
            return True
        if kb == CYLINDER:
            _plane_rims(W, I, CON, SYS, SYSR, N, sb, HAB, 0)
            return True
        return False
    if ka == BOX and kb == BOX:
        HBA = fr.relative(W, I, FB, FA)
        vb = _box_vertices(W, I, sb, HAB)
        _points_in_solid(W, I, CON, SYS, SYSR, N, vb, BOX, sa, 0.0, 0.0, 0, 0.0)
        _points_in_solid(W, I, CON, SYS, SYSR, N, _box_vertices(W, I, sa, HBA), BOX, sb, 0.0, 0.0, 1, 0.0)
        _box_edges_in(W, I, CON, SYS, SYSR, N, vb, BOX, sa, 0)
        return True
    return False


@_jit
def _flip(SYS, N):
    """After building a pair with its shapes swapped: every system's side is turned back to the caller's."""
    for k in range(N[1]):
        SYS[k, 2] = 1 - SYS[k, 2]
    return True
