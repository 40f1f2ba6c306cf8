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
from mjccd.geoms.poly import jit

# The codes below are numpy integers, not Python ones: numba types a Python int constant passed to a kernel as a
# literal and compiles that kernel again for each value it is passed, a numpy integer once (first use's compile)
SPHERE, CAPSULE, CYLINDER, BOX, ELLIPSOID, PLANE = (np.int64(k) for k in range(6))
KIND_NAMES = ("sphere", "capsule", "cylinder", "box", "ellipsoid", "plane")

NONE, BALL, AXCYL, ELLIPSOIDAL = (np.int64(k) for k in range(4))  # quadric of a piece
QPRM = 7                                      # its parameters: axis, centre (3), radius terms (3)
LIN = 6                                       # a linear constraint a . x <= c1 + c2 + c3
MAXLIN = 6
SYS_FIELDS = 28
WIT = 8                                       # first witness slot column of SYS: 4 coordinates x 5 rows
IN_A, IN_B = np.int64(0), np.int64(1)         # a system's side: its witness in A's frame (A the solid it meets)
Z_AXIS = np.int64(2)                          # a local axis: z, that of capsules and cylinders
MAX_PIECES = np.int64(27)                     # the convex pieces of an inflated solid, at most

# ---------------------------------------------------------------- the system store


def new_store(max_systems, max_constraints):
    """Empty system arrays: CON, SYS, SYSR, counts N = [constraints, systems, overflow]."""
    return (np.zeros((max_constraints, 6), dtype=np.int64), np.zeros((max_systems, SYS_FIELDS), dtype=np.int64),
            np.zeros(max_systems), np.zeros(3, dtype=np.int64))


@jit
def _con(CON, N, slot):
    """Append the univariate constraint ``slot <= 0``."""
    if N[0] >= CON.shape[0]:
        N[2] = 1
        return
    CON[N[0], 0] = 0
    CON[N[0], 1] = slot
    N[0] += 1


@jit
def _bcon(CON, N, rows):
    """Append the bivariate constraint given by its rows (one slot per Bernstein coefficient in s)."""
    if N[0] >= CON.shape[0]:
        N[2] = 1
        return
    CON[N[0], 0] = rows.shape[0] - 1
    for i in range(rows.shape[0]):
        CON[N[0], 1 + i] = rows[i]
    N[0] += 1


@jit
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


@jit
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


@jit
def _positive(W, I, k):
    """True when slot k is proven > 0 on all of [0, 1] (a constraint that can never hold)."""
    e = P.error(W, I, k)
    for i in range(I[k, 0] + 1):
        if not W[k, 0, i] > e:
            return False
    return True


@jit
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


@jit
def _radius_times(W, I, w, prm):
    """(R1 + R2 + R3) w for the radius terms prm[4:7]."""
    acc = -1
    for m in range(3):
        if prm[4 + m] != 0.0:
            term = P.scale(W, I, w, prm[4 + m])
            acc = term if acc < 0 else P.add(W, I, acc, term, 1.0)
    return acc if acc >= 0 else P.const(W, I, 0.0)


@jit
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


@jit
def _tangency(W, I, qk, qp, p0, d):
    """alpha gamma - beta^2 of the quadric along the segment p0 + s d (d of weight 0), written by Lagrange's
    identity as |u x d|^2 - R^2 w^2 |d|^2 (u = p0 - e w, in the quadric's own metric): the same polynomial,
    without the cancellation of two products of squares near a tangency."""
    axis = int(qp[0]) if qk == AXCYL else -1
    u = np.empty(3, dtype=np.int64)
    v = np.empty(3, dtype=np.int64)
    for i in range(3):
        if qk == ELLIPSOIDAL:
            u[i] = P.frac(W, I, p0[i], 1.0, qp[1 + i])
            v[i] = P.frac(W, I, d[i], 1.0, qp[1 + i])
        else:
            u[i] = p0[i] if qp[1 + i] == 0.0 else P.add(W, I, p0[i], p0[3], -qp[1 + i])
            v[i] = d[i]
    if axis >= 0:  # the two coordinates across the axis: a 2-d cross product
        j, k = (axis + 1) % 3, (axis + 2) % 3
        cross2 = P.sq(W, I, P.add(W, I, P.mul(W, I, u[j], v[k]), P.mul(W, I, u[k], v[j]), -1.0))
        d2 = P.add(W, I, P.sq(W, I, v[j]), P.sq(W, I, v[k]), 1.0)
    else:
        cross2 = -1
        for j in range(3):
            k, l = (j + 1) % 3, (j + 2) % 3
            c = P.sq(W, I, P.add(W, I, P.mul(W, I, u[k], v[l]), P.mul(W, I, u[l], v[k]), -1.0))
            cross2 = c if cross2 < 0 else P.add(W, I, cross2, c, 1.0)
        d2 = P.dot3(W, I, v[0], v[1], v[2], v[0], v[1], v[2])
    rw = p0[3] if qk == ELLIPSOIDAL else _radius_times(W, I, p0[3], qp)
    return P.add(W, I, cross2, P.mul(W, I, P.sq(W, I, rw), d2), -1.0)


@jit
def _combine(W, I, a, U, b, V):
    """The homogeneous point a U + b V for slots a, b (4 slots each way)."""
    out = np.empty(4, dtype=np.int64)
    for c in range(4):
        out[c] = P.add(W, I, P.mul(W, I, a, U[c]), P.mul(W, I, b, V[c]), 1.0)
    return out


# ---------------------------------------------------------------- pieces


@jit
def new_pieces(n):
    """Arrays of n convex pieces: quadric kind, its parameters, linear constraints and their count."""
    return (np.zeros(n, dtype=np.int64), np.zeros((n, QPRM)), np.zeros((n, MAXLIN, LIN)),
            np.zeros(n, dtype=np.int64), np.zeros(1, dtype=np.int64))


@jit
def _piece(PQ, PP, PL, PN, cnt, qk, axis, e0, e1, e2, R1, R2, R3):
    k = cnt[0]
    cnt[0] += 1
    PQ[k] = qk
    PP[k, 0], PP[k, 1], PP[k, 2], PP[k, 3] = axis, e0, e1, e2
    PP[k, 4], PP[k, 5], PP[k, 6] = R1, R2, R3
    PN[k] = 0
    return k


@jit
def _bound(PL, PN, k, i, sign, c1, c2, c3):
    """Add sign * x_i <= c1 + c2 + c3 to piece k."""
    r = PN[k]
    PN[k] += 1
    for m in range(3):
        PL[k, r, m] = 0.0
    PL[k, r, i] = sign
    PL[k, r, 3], PL[k, r, 4], PL[k, r, 5] = c1, c2, c3


@jit
def solid_pieces(kind, size, R1, R2):
    """The convex pieces whose union is the shape ``kind`` (core for a sphere or capsule) inflated by
    R1 + R2; tori are not pieces (a rounded cylinder's rims are handled apart)."""
    PQ, PP, PL, PN, cnt = new_pieces(MAX_PIECES)
    if kind == SPHERE:
        _piece(PQ, PP, PL, PN, cnt, BALL, 0.0, 0.0, 0.0, 0.0, R1, R2, 0.0)
    elif kind == CAPSULE:
        h = size[1]
        _piece(PQ, PP, PL, PN, cnt, BALL, 0.0, 0.0, 0.0, h, R1, R2, 0.0)
        _piece(PQ, PP, PL, PN, cnt, BALL, 0.0, 0.0, 0.0, -h, R1, R2, 0.0)
        k = _piece(PQ, PP, PL, PN, cnt, AXCYL, 2.0, 0.0, 0.0, 0.0, R1, R2, 0.0)
        _bound(PL, PN, k, Z_AXIS, 1.0, h, 0.0, 0.0)
        _bound(PL, PN, k, Z_AXIS, -1.0, h, 0.0, 0.0)
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
        _bound(PL, PN, k, Z_AXIS, 1.0, h, R1, R2)
        _bound(PL, PN, k, Z_AXIS, -1.0, h, R1, R2)
        if R1 != 0.0 or R2 != 0.0:
            k = _piece(PQ, PP, PL, PN, cnt, AXCYL, 2.0, 0.0, 0.0, 0.0, r, R1, R2)  # grown sideways
            _bound(PL, PN, k, Z_AXIS, 1.0, h, 0.0, 0.0)
            _bound(PL, PN, k, Z_AXIS, -1.0, h, 0.0, 0.0)
    elif kind == PLANE:
        k = _piece(PQ, PP, PL, PN, cnt, NONE, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0)
        _bound(PL, PN, k, Z_AXIS, 1.0, R1, R2, 0.0)
    elif kind == ELLIPSOID:
        k = _piece(PQ, PP, PL, PN, cnt, ELLIPSOIDAL, 0.0, size[0], size[1], size[2], 0.0, 0.0, 0.0)
    return PQ, PP, PL, PN, cnt[0]


# ---------------------------------------------------------------- candidates


@jit
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


@jit
def _may_be_negative(W, I, k):
    """False when slot k is proven > 0 everywhere (so ``k <= 0`` never holds)."""
    return not _positive(W, I, k)


@jit
def segment_in_piece(W, I, CON, SYS, SYSR, N, p0, p1, dv, qk, qp, lins, nlin, side, r_w, ends, crossings):
    """The systems 'the segment [p0, p1] (homogeneous points of one weight; ``dv`` = p1 - p0, 3 slots, as
    mapped from the local direction) meets the piece': its end points (with ``ends``), the vertex of the
    quadric along it, and (with ``crossings``) its crossings of each plane, entering and leaving.  Together
    they hold exactly when the segment meets the piece.  A plane the segment is exactly parallel to (its
    mapped direction has no component across it) gets no crossing: its crossing would be a point at
    infinity that meets 0 <= 0 in every other constraint at the instant the segment lies in that plane, and
    the first touch is always bound by another plane or an end."""
    if ends:
        point_in_piece(W, I, CON, SYS, SYSR, N, p0, qk, qp, lins, nlin, side, r_w)
        point_in_piece(W, I, CON, SYS, SYSR, N, p1, qk, qp, lins, nlin, side, r_w)
    zero = P.const(W, I, 0.0)
    d = np.empty(4, dtype=np.int64)
    for c in range(3):
        d[c] = dv[c]
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
                disc = _tangency(W, I, qk, qp, p0, d)  # alpha gamma - beta^2 <= 0, as a cross product
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
        if P.is_zero(W, I, _lin(W, I, d, lins[k])):
            continue  # parallel to the plane all along
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


@jit
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


@jit
def rounded(kind):
    """True for the shapes that are a core (point, segment) rounded by a radius: sphere and capsule."""
    return kind == SPHERE or kind == CAPSULE


@jit
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


@jit
def _box_corner(size, v):
    """Local coordinates of the box vertex number v (bits: sign of x, y, z)."""
    return (size[0] if v & 1 else -size[0]), (size[1] if v & 2 else -size[1]), (size[2] if v & 4 else -size[2])


@jit
def _box_vertices(W, I, size, H):
    out = np.empty((8, 4), dtype=np.int64)
    for v in range(8):
        x, y, z = _box_corner(size, v)
        out[v] = fr.point(W, I, H, x, y, z)
    return out


@jit
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


@jit
def _segment_in_solid(W, I, CON, SYS, SYSR, N, p0, p1, dv, kind, size, R1, R2, side, r_w, ends, crossings):
    PQ, PP, PL, PN, npc = solid_pieces(kind, size, R1, R2)
    for k in range(npc):
        segment_in_piece(W, I, CON, SYS, SYSR, N, p0, p1, dv, PQ[k], PP[k], PL[k], PN[k], side, r_w, ends,
                         crossings)


@jit
def _plane_rims(W, I, CON, SYS, SYSR, N, size, H, side):
    """A cylinder (map H into the plane's frame) against the half-space z <= 0: for each rim, its centre below
    the plane, or its lowest point (C_z <= r |a x e_z| in homogeneous terms, squared).  A rim that never
    tilts (a x e_z identically zero) has its centre as its lowest point: the squared form, whose root would
    be double, is left out."""
    r, h = size[0], size[1]
    U = fr.direction(W, I, H, 0.0, 0.0, 1.0)
    level = P.is_zero(W, I, U[0]) and P.is_zero(W, I, U[1])
    drop = P.add(W, I, P.sq(W, I, P.scale(W, I, U[0], r)), P.sq(W, I, P.scale(W, I, U[1], r)), 1.0)
    for zc in (h, -h):
        C = fr.point(W, I, H, 0.0, 0.0, zc)
        if not _positive(W, I, C[2]):
            start = N[0]
            _con(CON, N, C[2])
            _close(SYS, SYSR, N, start, side, C, 0.0)
        T = P.add(W, I, P.sq(W, I, C[2]), drop, -1.0)
        if not level and not _positive(W, I, T):
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


@jit
def _box_edges_in(W, I, CON, SYS, SYSR, N, vb, H, bsize, kind, size, side):
    """The 12 edges of a box (half sizes ``bsize``, its vertices ``vb`` under the map H into the other
    frame) against the solid ``kind``: tangencies and plane crossings (the vertices themselves are systems
    of their own)."""
    PQ, PP, PL, PN, npc = solid_pieces(kind, size, 0.0, 0.0)
    for bit in (1, 2, 4):
        dv = fr.direction(W, I, H, 2.0 * bsize[0] if bit == 1 else 0.0, 2.0 * bsize[1] if bit == 2 else 0.0,
                          2.0 * bsize[2] if bit == 4 else 0.0)
        for v in range(8):
            if v & bit:
                continue
            for k in range(npc):
                segment_in_piece(W, I, CON, SYS, SYSR, N, vb[v], vb[v | bit], dv, PQ[k], PP[k], PL[k], PN[k],
                                 side, 0.0, np.bool_(False), np.bool_(True))


HANDLED, PARTIAL = 1, 2  # build_pair's answers besides 0 (the pair is the ellipsoid solver's)


@jit
def _rounded_into(W, I, CON, SYS, SYSR, N, ka, sa, FA, kb, sb, FB):
    """B (a sphere or capsule) against A: B's core in A inflated by B's radius (and A's own when rounded)."""
    HAB = fr.relative(W, I, FA, FB)
    pts = _core_points(W, I, kb, sb, HAB)
    ra = sa[0] if rounded(ka) else 0.0
    rb = sb[0]
    _points_in_solid(W, I, CON, SYS, SYSR, N, pts, ka, sa, rb, ra, IN_A, rb)
    # a plane's inflated half-space is convex and a segment's height above it linear along the segment: where
    # some point of the segment lies in it, an end does, so the ends' systems hold first and the segment's
    # (bivariate, far dearer) adds nothing
    if kb == CAPSULE and ka != PLANE:
        dv = fr.direction(W, I, HAB, 0.0, 0.0, 2.0 * sb[1])
        _segment_in_solid(W, I, CON, SYS, SYSR, N, pts[0], pts[1], dv, ka, sa, rb, ra, IN_A, rb, np.bool_(False), np.bool_(True))
        if ka == CYLINDER:
            for zc in (sa[1], -sa[1]):
                segment_in_torus(W, I, CON, SYS, SYSR, N, pts[0], pts[1], sa[0], zc, rb, 0.0, IN_A, rb)
    return HANDLED


@jit
def _capsules(W, I, CON, SYS, SYSR, N, sa, FA, sb, FB):
    """Capsule against capsule: their segments come within ra + rb exactly when an end of B's comes that near
    A's segment (B's ends in A inflated by rb: its end balls and its cylinder), an end of A's comes that near
    the inside of B's (A's ends in B's inflated cylinder: the end-to-end distances are already B's ends in A's
    balls), or the closest points of the two axis lines, inside both segments, do (:func:`axis_lines`; where
    the axes are parallel an end is among the closest points)."""
    ra, rb = sa[0], sb[0]
    HAB = fr.relative(W, I, FA, FB)
    HBA = fr.relative(W, I, FB, FA)
    _points_in_solid(W, I, CON, SYS, SYSR, N, _core_points(W, I, CAPSULE, sb, HAB), CAPSULE, sa, rb, ra, IN_A, rb)
    PQ, PP, PL, PN, npc = solid_pieces(CAPSULE, sb, ra, rb)
    ends = _core_points(W, I, CAPSULE, sa, HBA)
    for m in range(2):
        for k in range(npc):
            if PQ[k] == AXCYL:
                point_in_piece(W, I, CON, SYS, SYSR, N, ends[m], PQ[k], PP[k], PL[k], PN[k], IN_B, ra)
    axis_lines(W, I, CON, SYS, SYSR, N, HAB, ra, sa[1], rb, sb[1], IN_A)
    return HANDLED


@jit
def _against_ellipsoid(W, I, CON, SYS, SYSR, N, ka, sa, FA, sb, FB):
    """A (capsule, cylinder or box) against the ellipsoid B (radii sb)."""
    HBA = fr.relative(W, I, FB, FA)  # A's frame into the ellipsoid's
    HAB = fr.relative(W, I, FA, FB)
    centre = fr.point(W, I, HAB, 0.0, 0.0, 0.0)  # the ellipsoid's centre in A: containment
    c1 = np.empty((1, 4), dtype=np.int64)
    c1[0] = centre
    if ka == CAPSULE:
        # the capsule's cylinder part; its end balls are the ellipsoid solver's
        piece = np.array([sa[0], sa[1], 0.0])
        lateral_shadow(W, I, CON, SYS, SYSR, N, HBA, sb, sa[0], sa[1], IN_B)
        _points_in_solid(W, I, CON, SYS, SYSR, N, c1, CYLINDER, piece, 0.0, 0.0, IN_A, 0.0)
        return PARTIAL
    if ka == CYLINDER:
        _circles_in_solid(W, I, CON, SYS, SYSR, N, HBA, sa[0], sa[1], ELLIPSOID, sb, IN_B)
        for sign in (1.0, -1.0):
            face_section(W, I, CON, SYS, SYSR, N, HBA, sb, Z_AXIS, sign, sa[1], sa, np.bool_(True), IN_A)
        lateral_shadow(W, I, CON, SYS, SYSR, N, HBA, sb, sa[0], sa[1], IN_B)
    else:  # a box
        vb = _box_vertices(W, I, sa, HBA)
        _points_in_solid(W, I, CON, SYS, SYSR, N, vb, ELLIPSOID, sb, 0.0, 0.0, IN_B, 0.0)
        _box_edges_in(W, I, CON, SYS, SYSR, N, vb, HBA, sa, ELLIPSOID, sb, IN_B)
        for axis in range(3):
            for sign in (1.0, -1.0):
                face_section(W, I, CON, SYS, SYSR, N, HBA, sb, axis, sign, sa[axis], sa, np.bool_(False), IN_A)
    _points_in_solid(W, I, CON, SYS, SYSR, N, c1, ka, sa, 0.0, 0.0, IN_A, 0.0)
    return HANDLED


@jit
def build_pair(W, I, CON, SYS, SYSR, N, ka, sa, FA, kb, sb, FB):
    """All systems of the pair (shape ka, size sa, frame FA) and (kb, sb, FB).  Returns HANDLED; PARTIAL when
    the ellipsoid solver must add a capsule's end balls against an ellipsoid; 0 for the ellipsoid solver's
    pairs (an ellipsoid with a sphere, an ellipsoid or a plane)."""
    if ka > kb:
        code = build_pair(W, I, CON, SYS, SYSR, N, kb, sb, FB, ka, sa, FA)
        _flip(SYS, N)
        return code
    # now ka <= kb: SPHERE < CAPSULE < CYLINDER < BOX < ELLIPSOID < PLANE
    if ka == SPHERE and kb == ELLIPSOID or ka == ELLIPSOID:
        return 0
    if ka == CAPSULE and kb == CAPSULE:
        return _capsules(W, I, CON, SYS, SYSR, N, sa, FA, sb, FB)
    if rounded(ka):
        if kb == ELLIPSOID:
            return _against_ellipsoid(W, I, CON, SYS, SYSR, N, ka, sa, FA, sb, FB)
        code = _rounded_into(W, I, CON, SYS, SYSR, N, kb, sb, FB, ka, sa, FA)  # A's core into B
        _flip(SYS, N)
        return code
    if kb == PLANE:
        HBA = fr.relative(W, I, FB, FA)  # A into the plane's frame
        if ka == BOX:
            _points_in_solid(W, I, CON, SYS, SYSR, N, _box_vertices(W, I, sa, HBA), PLANE, sb, 0.0, 0.0, IN_B, 0.0)
        else:
            _plane_rims(W, I, CON, SYS, SYSR, N, sa, HBA, IN_B)
        return HANDLED
    if kb == ELLIPSOID:
        return _against_ellipsoid(W, I, CON, SYS, SYSR, N, ka, sa, FA, sb, FB)
    HAB = fr.relative(W, I, FA, FB)
    HBA = fr.relative(W, I, FB, FA)
    if ka == BOX:  # box and box
        vb = _box_vertices(W, I, sb, HAB)
        _points_in_solid(W, I, CON, SYS, SYSR, N, vb, BOX, sa, 0.0, 0.0, IN_A, 0.0)
        _points_in_solid(W, I, CON, SYS, SYSR, N, _box_vertices(W, I, sa, HBA), BOX, sb, 0.0, 0.0, IN_B, 0.0)
        _box_edges_in(W, I, CON, SYS, SYSR, N, vb, HAB, sb, BOX, sa, IN_A)
        return HANDLED
    if kb == BOX:  # cylinder and box
        vb = _box_vertices(W, I, sb, HAB)
        _points_in_solid(W, I, CON, SYS, SYSR, N, vb, CYLINDER, sa, 0.0, 0.0, IN_A, 0.0)
        _box_edges_in(W, I, CON, SYS, SYSR, N, vb, HAB, sb, CYLINDER, sa, IN_A)
        _circles_in_solid(W, I, CON, SYS, SYSR, N, HBA, sa[0], sa[1], BOX, sb, IN_B)
        return HANDLED
    # cylinder and cylinder
    _circles_in_solid(W, I, CON, SYS, SYSR, N, HAB, sb[0], sb[1], CYLINDER, sa, IN_A)
    _circles_in_solid(W, I, CON, SYS, SYSR, N, HBA, sa[0], sa[1], CYLINDER, sb, IN_B)
    axis_lines(W, I, CON, SYS, SYSR, N, HAB, sa[0], sa[1], sb[0], sb[1], IN_A)
    return HANDLED


@jit
def _flip(SYS, N):
    """After building a pair with its shapes swapped: every system's side is turned back to the caller's."""
    for k in range(N[1]):
        SYS[k, 2] = 1 - SYS[k, 2]


# ---------------------------------------------------------------- points on a circle (bivariate in s)


@jit
def circle_rows(W, I, H, zc, r, chart):
    """The circle of radius r about the local z axis at height zc, under the map H: a homogeneous point
    (4, 3) of row slots, degree 2 in s.  Chart 0 covers the half x >= 0 (angle -pi/2..pi/2, by the tangent
    of its half: sigma = 2s - 1), chart 1 the half x <= 0."""
    out = np.empty((4, 3), dtype=np.int64)
    p0 = fr.point(W, I, H, 0.0, -r, zc)
    p2 = fr.point(W, I, H, 0.0, r, zc)
    d = fr.direction(W, I, H, r if chart == 0 else -r, 0.0, 0.0)
    zero = P.const(W, I, 0.0)
    for c in range(4):
        out[c, 0] = p0[c]
        out[c, 2] = p2[c]
        out[c, 1] = d[c] if c < 3 else zero
    return out


@jit
def _blin(W, I, rows, row):
    """A linear constraint on a bivariate homogeneous point: row by row."""
    ds = rows.shape[1] - 1
    out = np.empty(ds + 1, dtype=np.int64)
    pt = np.empty(4, dtype=np.int64)
    for i in range(ds + 1):
        for c in range(4):
            pt[c] = rows[c, i]
        out[i] = _lin(W, I, pt, row)
    return out


@jit
def _bcoord(W, I, rows, c, e):
    """The bivariate coordinate c of the point less e times its weight (row by row)."""
    ds = rows.shape[1] - 1
    out = np.empty(ds + 1, dtype=np.int64)
    for i in range(ds + 1):
        out[i] = rows[c, i] if e == 0.0 else P.add(W, I, rows[c, i], rows[3, i], -e)
    return out


@jit
def _bquadric(W, I, qk, qp, rows):
    """The piece's quadric at a bivariate homogeneous point (degree twice the point's in s)."""
    acc = np.empty(0, dtype=np.int64)
    first = True
    axis = int(qp[0]) if qk == AXCYL else -1
    for i in range(3):
        if i == axis:
            continue
        if qk == ELLIPSOIDAL:
            u = np.empty(rows.shape[1], dtype=np.int64)
            for k in range(rows.shape[1]):
                u[k] = P.frac(W, I, rows[i, k], 1.0, qp[1 + i])
        else:
            u = _bcoord(W, I, rows, i, qp[1 + i])
        term = P.bmul(W, I, u, u)
        acc = term if first else P.badd(W, I, acc, term, 1.0)
        first = False
    if qk == ELLIPSOIDAL:
        w = rows[3].copy()
    else:
        w = np.empty(rows.shape[1], dtype=np.int64)
        for k in range(rows.shape[1]):
            w[k] = _radius_times(W, I, rows[3, k], qp)
    return P.badd(W, I, acc, P.bmul(W, I, w, w), -1.0)


@jit
def _bpositive(W, I, rows):
    """True when a bivariate polynomial is proven > 0 everywhere (each row's coefficients are)."""
    for i in range(rows.shape[0]):
        if not _positive(W, I, rows[i]):
            return False
    return True


@jit
def curve_in_piece(W, I, CON, SYS, SYSR, N, pt, qk, qp, lins, nlin, side, r_w):
    """The bivariate system 'the point pt (rows in s) lies in the piece'."""
    cons = np.empty((MAXLIN + 1, 5), dtype=np.int64)
    degs = np.empty(MAXLIN + 1, dtype=np.int64)
    m = 0
    for r in range(nlin):
        b = _blin(W, I, pt, lins[r])
        if _bpositive(W, I, b):
            return
        degs[m] = b.shape[0] - 1
        for i in range(b.shape[0]):
            cons[m, i] = b[i]
        m += 1
    if qk != NONE:
        q = _bquadric(W, I, qk, qp, pt)
        if _bpositive(W, I, q):
            return
        degs[m] = q.shape[0] - 1
        for i in range(q.shape[0]):
            cons[m, i] = q[i]
        m += 1
    start = N[0]
    for r in range(m):
        _bcon(CON, N, cons[r, :degs[r] + 1])
    _bclose(SYS, SYSR, N, start, side, pt, r_w)


@jit
def _circles_in_solid(W, I, CON, SYS, SYSR, N, H, r, h, kind, size, side):
    """The two rims (radius r, heights +-h) of a cylinder, mapped by H into the frame of the solid ``kind``,
    against that solid, both charts each."""
    PQ, PP, PL, PN, npc = solid_pieces(kind, size, 0.0, 0.0)
    for zc in (h, -h):
        for chart in range(2):
            rows = circle_rows(W, I, H, zc, r, chart)
            for k in range(npc):
                curve_in_piece(W, I, CON, SYS, SYSR, N, rows, PQ[k], PP[k], PL[k], PN[k], side, 0.0)


@jit
def segment_in_torus(W, I, CON, SYS, SYSR, N, p0, p1, rc, zc, R1, R2, side, r_w):
    """The bivariate systems 'a point of the segment [p0, p1] lies within R1 + R2 of the circle of radius rc
    about the z axis at height zc' (see :func:`point_in_torus`)."""
    rows = np.empty((4, 2), dtype=np.int64)
    for c in range(4):
        rows[c, 0], rows[c, 1] = p0[c], p1[c]
    x, y = rows[0], rows[1]
    z = _bcoord(W, I, rows, Z_AXIS, zc)
    rho2 = P.badd(W, I, P.bmul(W, I, x, x), P.bmul(W, I, y, y), 1.0)
    wr = np.empty(2, dtype=np.int64)
    wR = np.empty(2, dtype=np.int64)
    for k in range(2):
        wr[k] = P.scale(W, I, rows[3, k], rc)
        wR[k] = P.add(W, I, P.scale(W, I, rows[3, k], R1), P.scale(W, I, rows[3, k], R2), 1.0)
    K = P.badd(W, I, P.badd(W, I, rho2, P.bmul(W, I, z, z), 1.0),
               P.badd(W, I, P.bmul(W, I, wr, wr), P.bmul(W, I, wR, wR), -1.0), 1.0)
    if not _bpositive(W, I, K):
        start = N[0]
        _bcon(CON, N, K)
        _bclose(SYS, SYSR, N, start, side, rows, r_w)
    four_r2 = P.bmul(W, I, wr, wr)
    for k in range(four_r2.shape[0]):
        four_r2[k] = P.scale(W, I, four_r2[k], 4.0)
    T = P.badd(W, I, P.bmul(W, I, K, K), P.bmul(W, I, four_r2, rho2), -1.0)
    if not _bpositive(W, I, T):
        start = N[0]
        _bcon(CON, N, T)
        _bclose(SYS, SYSR, N, start, side, rows, r_w)


# ---------------------------------------------------------------- against an ellipsoid: sections and shadows


@jit
def _homogeneous_direction(d, zero):
    """The direction d (3 slots) as a homogeneous point of weight ``zero`` (the zero slot)."""
    out = np.empty(4, dtype=np.int64)
    for c in range(3):
        out[c] = d[c]
    out[3] = zero
    return out


@jit
def _ellipsoid_form(W, I, rad, U, V):
    """sum U_i V_i / r_i^2 - Uw Vw in the ellipsoid's frame (U, V homogeneous, 4 slots)."""
    return _bilinear(W, I, ELLIPSOIDAL, np.array([0.0, rad[0], rad[1], rad[2], 0.0, 0.0, 0.0]), U, V)


@jit
def face_section(W, I, CON, SYS, SYSR, N, H, rad, axis, sign, h, size, disk, side):
    """The planar face x_axis = sign h of a box (half sizes ``size``) or, with ``disk``, the cap of radius
    size[0] of a cylinder, against the ellipsoid (radii ``rad``) in whose frame H maps the face's shape: the
    section of the ellipsoid by the face's plane is not empty and its centre lies on the face.  The centre
    solves the section's 2x2 system by the adjugate: the constraints are polynomial."""
    a, b = (axis + 1) % 3, (axis + 2) % 3
    e = np.zeros(3)
    e[axis] = sign * h
    C0 = fr.point(W, I, H, e[0], e[1], e[2])
    da, db = np.zeros(3), np.zeros(3)
    da[a], db[b] = 1.0, 1.0
    zero = P.const(W, I, 0.0)
    A = _homogeneous_direction(fr.direction(W, I, H, da[0], da[1], da[2]), zero)
    B = _homogeneous_direction(fr.direction(W, I, H, db[0], db[1], db[2]), zero)
    Muu, Muv, Mvv = _ellipsoid_form(W, I, rad, A, A), _ellipsoid_form(W, I, rad, A, B), _ellipsoid_form(W, I, rad, B, B)
    mu, mv, m11 = _ellipsoid_form(W, I, rad, A, C0), _ellipsoid_form(W, I, rad, B, C0), _ellipsoid_form(W, I, rad, C0, C0)
    det = P.add(W, I, P.mul(W, I, Muu, Mvv), P.sq(W, I, Muv), -1.0)
    # -adj(M2) m: the centre's coordinates times det
    cu = P.add(W, I, P.mul(W, I, Muv, mv), P.mul(W, I, Mvv, mu), -1.0)
    cv = P.add(W, I, P.mul(W, I, Muv, mu), P.mul(W, I, Muu, mv), -1.0)
    # det m11 + (centre . m) <= 0, i.e. the minimum of the section's quadratic, times det^2 ... over det
    nonempty = P.add(W, I, P.mul(W, I, det, m11), P.add(W, I, P.mul(W, I, cu, mu), P.mul(W, I, cv, mv), 1.0), 1.0)
    if _positive(W, I, nonempty):
        return
    cons = np.empty(5, dtype=np.int64)
    m = 0
    cons[m] = nonempty
    m += 1
    if disk:
        r = size[0]
        inside = P.add(W, I, P.add(W, I, P.sq(W, I, cu), P.sq(W, I, cv), 1.0), P.sq(W, I, P.scale(W, I, det, r)), -1.0)
        if _positive(W, I, inside):
            return
        cons[m] = inside
        m += 1
    else:
        for c, half in ((cu, size[a]), (cv, size[b])):
            for sg in (1.0, -1.0):
                k = P.add(W, I, P.scale(W, I, c, sg), det, -half)
                if _positive(W, I, k):
                    return
                cons[m] = k
                m += 1
    start = N[0]
    for r_ in range(m):
        _con(CON, N, cons[r_])
    # the witness: the section's centre in the face's frame, homogeneous with weight det
    wit = np.empty(4, dtype=np.int64)
    coords = np.empty(3, dtype=np.int64)
    coords[a], coords[b], coords[axis] = cu, cv, P.scale(W, I, det, sign * h)
    for c in range(3):
        wit[c] = coords[c]
    wit[3] = det
    _close(SYS, SYSR, N, start, side, wit, 0.0)


@jit
def lateral_shadow(W, I, CON, SYS, SYSR, N, H, rad, r, h, side):
    """The side of a cylinder (radius r, |z| <= h; H maps its frame into the ellipsoid's) against the
    ellipsoid: a line of the side (through a point of the circle of radius r, parallel to the axis) meets
    the ellipsoid in a chord whose middle lies within |z| <= h.  Per chart of the circle: the chord's
    discriminant beta^2 - alpha gamma >= 0 and beta^2 <= h^2 w^2 alpha^2, with alpha the axis's quadratic
    form, beta its pairing with the circle's point, gamma the point's form (w the point's weight)."""
    zero = P.const(W, I, 0.0)
    D = _homogeneous_direction(fr.direction(W, I, H, 0.0, 0.0, 1.0), zero)
    alpha = _ellipsoid_form(W, I, rad, D, D)
    # the same circle's points in its own frame carry the weights (their third coordinate is 0)
    for chart in range(2):
        rows = circle_rows(W, I, H, 0.0, r, chart)
        ds = 2
        beta = np.empty(ds + 1, dtype=np.int64)
        pt = np.empty(4, dtype=np.int64)
        for i in range(ds + 1):
            for c in range(4):
                pt[c] = rows[c, i]
            beta[i] = _ellipsoid_form(W, I, rad, D, pt)
        gamma = _bquadric(W, I, ELLIPSOIDAL, np.array([0.0, rad[0], rad[1], rad[2], 0.0, 0.0, 0.0]), rows)
        b2 = P.bmul(W, I, beta, beta)
        disc = P.badd(W, I, P.bscale_t(W, I, gamma, alpha), b2, -1.0)  # alpha gamma - beta^2 <= 0
        if _bpositive(W, I, disc):
            continue
        # h alpha w(s), w the circle point's own weight (rows 1, 0, 1): the chord's middle within the side
        hw = np.empty(ds + 1, dtype=np.int64)
        ha = P.scale(W, I, alpha, h)
        hw[0], hw[1], hw[2] = ha, zero, ha
        within = P.badd(W, I, b2, P.bmul(W, I, hw, hw), -1.0)
        if _bpositive(W, I, within):
            continue
        start = N[0]
        _bcon(CON, N, disc)
        _bcon(CON, N, within)
        # witness in the ellipsoid's frame: (alpha point - beta axis) / (alpha w)
        wit = np.empty((4, ds + 1), dtype=np.int64)
        for i in range(ds + 1):
            for c in range(4):
                t = P.mul(W, I, alpha, rows[c, i])
                wit[c, i] = t if c == 3 else P.add(W, I, t, P.mul(W, I, beta[i], D[c]), -1.0)
        _bclose(SYS, SYSR, N, start, side, wit, 0.0)


@jit
def axis_lines(W, I, CON, SYS, SYSR, N, H, ra, ha, rb, hb, side):
    """Side against side of two cylinders (radii ra, rb, half lengths ha, hb; H maps B's frame into A's): the
    closest points of their axis lines lie within both lengths, at most ra + rb apart.  With n = e_z x D (D
    B's axis, |D| = w, the map's weight), P B's centre: (P.n)^2 <= (ra+rb)^2 w^2 |n|^2,
    (|D|^2 P_z - D_z D.P)^2 <= ha^2 w^2 |n|^4 and (D_z P_z - D.P)^2 <= hb^2 |n|^4.  Parallel axes (n = 0)
    touch side to side only where their rims do too."""
    P0 = fr.point(W, I, H, 0.0, 0.0, 0.0)
    D = fr.direction(W, I, H, 0.0, 0.0, 1.0)
    w = H[fr.M0]
    nx, ny = P.scale(W, I, D[1], -1.0), D[0]
    n2 = P.add(W, I, P.sq(W, I, D[0]), P.sq(W, I, D[1]), 1.0)
    if P.is_zero(W, I, n2):
        return
    pn = P.add(W, I, P.mul(W, I, P0[0], nx), P.mul(W, I, P0[1], ny), 1.0)
    rw = P.add(W, I, P.scale(W, I, w, ra), P.scale(W, I, w, rb), 1.0)
    dist = P.add(W, I, P.sq(W, I, pn), P.mul(W, I, P.sq(W, I, rw), n2), -1.0)
    if _positive(W, I, dist):
        return
    dp = P.dot3(W, I, D[0], D[1], D[2], P0[0], P0[1], P0[2])
    D2 = P.add(W, I, n2, P.sq(W, I, D[2]), 1.0)
    sa = P.add(W, I, P.mul(W, I, D2, P0[2]), P.mul(W, I, D[2], dp), -1.0)    # s_A w |n|^2
    zb = P.add(W, I, P.mul(W, I, D[2], P0[2]), dp, -1.0)                    # z_B |n|^2
    n4 = P.sq(W, I, n2)
    ca = P.add(W, I, P.sq(W, I, sa), P.mul(W, I, P.sq(W, I, P.scale(W, I, w, ha)), n4), -1.0)
    cb = P.add(W, I, P.sq(W, I, zb), P.mul(W, I, P.sq(W, I, P.const(W, I, hb)), n4), -1.0)
    if _positive(W, I, ca) or _positive(W, I, cb):
        return
    start = N[0]
    _con(CON, N, dist)
    _con(CON, N, ca)
    _con(CON, N, cb)
    # witness: the point of A's side toward B, at A's closest point: (0, 0, s_A) + ra (P.n) n / ((ra+rb) w |n|^2)
    frac_a = ra / (ra + rb)
    wit = np.empty(4, dtype=np.int64)
    k = P.scale(W, I, pn, frac_a)
    wit[0] = P.mul(W, I, k, nx)
    wit[1] = P.mul(W, I, k, ny)
    wit[2] = sa
    wit[3] = P.mul(W, I, w, n2)
    _close(SYS, SYSR, N, start, side, wit, 0.0)
