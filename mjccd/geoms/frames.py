"""Rigid motions as homogeneous polynomial matrices in a :mod:`mjccd.geoms.poly` workspace (numba kernels).

A *frame* is an int array of 26 slot ids: the forward map of the body,
``x = (L y + v) / m`` (L 3x3 row-major, then v, then m: ids 0..12), and its
inverse ``y = (G x + h) / g`` (ids 13..25).  Both are exact for the motion as
given, so a point of body B seen from body A is ``Finv_A F_B [y; 1]``
(:func:`relative`), and every polynomial formed from it carries a proven
rounding bound.

Motions are given as *element rows* (``ELEMENT_FIELDS`` floats each), composed
from the world down, as :class:`mjccd.Chain` composes them:

* ``POSE``: [kind, p0 (3), q0 (4), p1 (3), q1 (4)], centre lerp and quaternion
  lerp (q1 on the side of q0); ``p0 == p1`` and ``q0 == q1`` make it static;
* ``HINGE``: [kind, axis (3), tan(angle0 / 2), tan(angle1 / 2), ...]: the
  quaternion (1, tau(t) axis) with tau linear, exactly :class:`mjccd.Hinge`;
* ``SLIDE``: [kind, axis (3), d0, d1, ...].

A rotation by an unnormalised quaternion q is ``rot(q) / |q|^2`` with
``rot(q) rot(q)^T = |q|^4 I`` exactly, so its inverse is the transpose and
costs no extra degree.
"""
import numpy as np

from mjccd.geoms import poly as P
from mjccd.geoms.poly import jit

ELEMENT_FIELDS = 15
POSE, HINGE, SLIDE = 0, 1, 2
FRAME = 26
# block offsets in a frame's rows: numpy integers, so that a kernel passed two of them compiles once (see
# mjccd.geoms.systems)
L0, V0, M0, G0, H0, GW = (np.int64(k) for k in (0, 9, 12, 13, 22, 25))


@jit
def _rotation(W, I, qs, F):
    """F[L0:L0+9] = rot(q) and F[G0:G0+9] = rot(q)^T for the quaternion slots qs (4,); returns |q|^2."""
    w, x, y, z = qs[0], qs[1], qs[2], qs[3]
    ww, xx, yy, zz = P.sq(W, I, w), P.sq(W, I, x), P.sq(W, I, y), P.sq(W, I, z)
    xy, xz, yz = P.mul(W, I, x, y), P.mul(W, I, x, z), P.mul(W, I, y, z)
    wx, wy, wz = P.mul(W, I, w, x), P.mul(W, I, w, y), P.mul(W, I, w, z)
    a = P.add(W, I, ww, xx, 1.0)
    b = P.add(W, I, yy, zz, 1.0)
    c = P.add(W, I, ww, xx, -1.0)
    d = P.add(W, I, yy, zz, -1.0)
    R = np.empty(9, dtype=np.int64)
    R[0] = P.add(W, I, a, b, -1.0)            # ww + xx - yy - zz
    R[4] = P.add(W, I, c, d, 1.0)             # ww - xx + yy - zz
    R[8] = P.add(W, I, c, d, -1.0)            # ww - xx - yy + zz
    R[1] = P.scale(W, I, P.add(W, I, xy, wz, -1.0), 2.0)
    R[3] = P.scale(W, I, P.add(W, I, xy, wz, 1.0), 2.0)
    R[2] = P.scale(W, I, P.add(W, I, xz, wy, 1.0), 2.0)
    R[6] = P.scale(W, I, P.add(W, I, xz, wy, -1.0), 2.0)
    R[5] = P.scale(W, I, P.add(W, I, yz, wx, -1.0), 2.0)
    R[7] = P.scale(W, I, P.add(W, I, yz, wx, 1.0), 2.0)
    for i in range(3):
        for j in range(3):
            F[L0 + 3 * i + j] = R[3 * i + j]
            F[G0 + 3 * i + j] = R[3 * j + i]
    return P.add(W, I, a, b, 1.0)


@jit
def _element(W, I, row):
    """The frame of one element row."""
    F = np.empty(FRAME, dtype=np.int64)
    kind = int(row[0])
    zero = P.const(W, I, 0.0)
    if kind == SLIDE:
        one = P.const(W, I, 1.0)
        for i in range(3):
            for j in range(3):
                F[L0 + 3 * i + j] = one if i == j else zero
                F[G0 + 3 * i + j] = one if i == j else zero
            d = P.linear(W, I, row[1 + i] * row[4], row[1 + i] * row[5])
            F[V0 + i] = d
            F[H0 + i] = P.scale(W, I, d, -1.0)
        F[M0] = one
        F[GW] = one
        return F
    qs = np.empty(4, dtype=np.int64)
    if kind == HINGE:
        qs[0] = P.const(W, I, 1.0)
        for i in range(3):
            qs[1 + i] = P.linear(W, I, row[1 + i] * row[4], row[1 + i] * row[5])
        n2 = _rotation(W, I, qs, F)
        for i in range(3):
            F[V0 + i] = zero
            F[H0 + i] = zero
        F[M0] = n2
        F[GW] = n2
        return F
    for i in range(4):
        qs[i] = P.linear(W, I, row[4 + i], row[11 + i])
    n2 = _rotation(W, I, qs, F)
    p = np.empty(3, dtype=np.int64)
    for i in range(3):
        p[i] = P.linear(W, I, row[1 + i], row[8 + i])
    for i in range(3):
        F[V0 + i] = P.mul(W, I, p[i], n2)
        # h = -rot(q)^T p
        F[H0 + i] = P.scale(W, I, P.dot3(W, I, F[G0 + 3 * i], F[G0 + 3 * i + 1], F[G0 + 3 * i + 2],
                                         p[0], p[1], p[2]), -1.0)
    F[M0] = n2
    F[GW] = n2
    return F


@jit
def _compose_block(W, I, F1, F2, Lo, Vo, Mo, out):
    """out[Lo:] etc. = the block product [[L1, v1], [0, m1]] [[L2, v2], [0, m2]] of the blocks at Lo, Vo, Mo."""
    for i in range(3):
        for j in range(3):
            out[Lo + 3 * i + j] = P.dot3(W, I, F1[Lo + 3 * i], F1[Lo + 3 * i + 1], F1[Lo + 3 * i + 2],
                                         F2[Lo + j], F2[Lo + 3 + j], F2[Lo + 6 + j])
        lv = P.dot3(W, I, F1[Lo + 3 * i], F1[Lo + 3 * i + 1], F1[Lo + 3 * i + 2], F2[Vo], F2[Vo + 1], F2[Vo + 2])
        out[Vo + i] = P.add(W, I, lv, P.mul(W, I, F1[Vo + i], F2[Mo]), 1.0)
    out[Mo] = P.mul(W, I, F1[Mo], F2[Mo])


@jit
def compose(W, I, F1, F2):
    """The frame of ``x = F1(F2(y))``: forward F1 F2, inverse F2^-1 F1^-1."""
    out = np.empty(FRAME, dtype=np.int64)
    _compose_block(W, I, F1, F2, L0, V0, M0, out)
    _compose_block(W, I, F2, F1, G0, H0, GW, out)
    return out


@jit
def chain_frame(W, I, rows):
    """The frame of the element rows (ELEMENT_FIELDS floats each), the first closest to the world."""
    F = _element(W, I, rows[0])
    for k in range(1, rows.shape[0]):
        F = compose(W, I, F, _element(W, I, rows[k]))
    return F


@jit
def relative(W, I, Fa, Fb):
    """The map from B's frame into A's, ``Finv_A F_B``, as a frame-shaped array whose forward block (ids 0..12)
    is that map (the inverse block is left unset, -1)."""
    out = np.full(FRAME, -1, dtype=np.int64)
    for i in range(3):
        for j in range(3):
            out[L0 + 3 * i + j] = P.dot3(W, I, Fa[G0 + 3 * i], Fa[G0 + 3 * i + 1], Fa[G0 + 3 * i + 2],
                                         Fb[L0 + j], Fb[L0 + 3 + j], Fb[L0 + 6 + j])
        gv = P.dot3(W, I, Fa[G0 + 3 * i], Fa[G0 + 3 * i + 1], Fa[G0 + 3 * i + 2], Fb[V0], Fb[V0 + 1], Fb[V0 + 2])
        out[V0 + i] = P.add(W, I, gv, P.mul(W, I, Fa[H0 + i], Fb[M0]), 1.0)
    out[M0] = P.mul(W, I, Fa[GW], Fb[M0])
    return out


@jit
def point(W, I, H, y0, y1, y2):
    """Homogeneous point (4 slots: X, Y, Z, weight) of the local point y under the forward block of H."""
    out = np.empty(4, dtype=np.int64)
    for i in range(3):
        acc = H[V0 + i]
        for k in range(3):
            yk = y0 if k == 0 else (y1 if k == 1 else y2)
            if yk != 0.0:
                acc = P.add(W, I, acc, H[L0 + 3 * i + k], yk)
        out[i] = acc
    out[3] = H[M0]
    return out


@jit
def direction(W, I, H, d0, d1, d2):
    """The local direction d under the forward block of H (3 slots; over the same weight as :func:`point`)."""
    out = np.empty(3, dtype=np.int64)
    for i in range(3):
        acc = -1
        for k in range(3):
            dk = d0 if k == 0 else (d1 if k == 1 else d2)
            if dk != 0.0:
                term = P.scale(W, I, H[L0 + 3 * i + k], dk)
                acc = term if acc < 0 else P.add(W, I, acc, term, 1.0)
        out[i] = acc if acc >= 0 else P.const(W, I, 0.0)
    return out
