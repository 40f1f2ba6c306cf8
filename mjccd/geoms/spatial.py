"""Elliptic disks moving in space (Choi 2008, chapter 3): the certified first contact.

A :class:`Disk` ``(a, b)`` is the flat elliptic disk ``x²/a² + y²/b² <= 1, z = 0``
of its own frame; its motion is :class:`mjccd.Static`, :class:`mjccd.Rigid` or
:class:`mjccd.Chain`, whose frames :mod:`mjccd.geoms.frames` builds from the
element rows of :func:`mjccd.geoms.solve.motion_rows`.

**Reduction to a line** (thesis §3.1).  When the disks' planes are not
parallel they meet in a line L, and a disk meets the other disk's plane in a
chord of L (possibly empty, or one point).  The disks meet exactly when their
chords do; and two segments of a line meet exactly when an end of one lies in
the other.  The ends of A's chord are the points of A's rim on B's plane, and
such an end lies in B's chord exactly when it lies in the disk B.  So the
disks meet iff *an end of A's chord lies in B* or *an end of B's chord lies
in A*, one pair of systems each way, which replace the thesis' condition
``|c1 - c2| <= r1 + r2`` on the two intervals (the same thing, of a lower
degree once squared).

**The systems** for A's chord (B's the same with the roles swapped), in B's
frame through the relative map ``H = Finv_B F_A`` (``x = (L y + v) / m``, a
polynomial frame): A's rim point ``(a ζ1, b ζ2, 0)`` (ζ on the unit circle)
lies on B's plane where ``λ·ζ = κ``, ``λ = (a L20, b L21)``, ``κ = -v2``: the
two ends ``ζ = (κλ ± λ⊥√S) / |λ|²`` with ``S = |λ|² - κ²`` (real iff S >= 0).
B's quadric at an end, times ``(m |λ|²)² > 0``, is ``E ± F√S`` with
polynomials

    P_x = κ (a L_x0 λ1 + b L_x1 λ2) + v_x |λ|²,   Q_x = b L_x1 λ1 - a L_x0 λ2   (x = 0, 1)
    E = Σ (P_x² + S Q_x²) / r_x² - (m |λ|²)²,      F = 2 Σ P_x Q_x / r_x²,

(r = B's semi-axes), and some end lies in B iff ``E - |F|√S <= 0``, i.e. iff
``E <= 0`` or ``E² - F² S <= 0``.  The two systems are ``{-S <= 0, E <= 0}``
and ``{-S <= 0, E² - F² S <= 0}``: univariate, of degree 26 and 52 in t for
two rigid motions.  **Genuine**: where the planes are not parallel (λ != 0) a
proof that one holds is a proof that a point of A's rim (real: S >= 0) lies
in B.  **Complete**: at any time the disks meet with planes not parallel, an
end of one chord lies in the other disk, and one of the four systems holds.

**Parallel and coplanar planes.**  Parallel planes that are not coplanar give
``λ = 0, S = -κ² < 0``: no system holds (proven wherever κ is not within
rounding of 0).  Where the planes coincide, λ = κ = 0 and every constraint
vanishes: the systems can neither be proven to hold nor to fail there.  The
solver therefore looks at the planes exactly (the frames again in rational
arithmetic, :func:`exact_frame`):

* coplanar at every time: the planar solver (:mod:`mjccd.geoms.planar`, B
  seen from A's frame: an exact rational planar motion) answers;
* parallel at every time: the disks can only meet when B's plane passes
  through A's, at a root of B's height above A's plane; with no root in
  [0, t_max] (Sturm, exactly) there is no contact, and a single rational root
  (a height linear in t, as for two bodies that only translate) is decided by
  the planar status at that instant;
* coplanar at t = 0: the planar solver gives the status at the start, and the
  scan starts from there.

Any other coplanar instant (or planes within rounding of each other, which no
double decides) leaves an undecided band around it: the answer is then
uncertain, with a bracket that holds every possible first contact.

The contact point is the middle of the two chords' overlap at the contact
time; the normal (outward from A) is the normal of the disk whose face is
touched, or for two rims the common perpendicular of their tangents.
"""
import math
import threading
from fractions import Fraction

import numpy as np

from mjccd import _validate
from mjccd.ccd import Contact
from mjccd.errors import InputTypeError
from mjccd.geoms import frames as fr
from mjccd.geoms import exact as X
from mjccd.geoms import kernel as kn
from mjccd.geoms import planar as pl
from mjccd.geoms import poly as P
from mjccd.geoms import systems as sy
from mjccd.geoms.poly import jit
from mjccd.geoms.solve import motion_rows, shifted_rows

TIME_TOL = kn.TIME_TOL
STATUS_NAMES = pl.STATUS_NAMES
SLOTS = 8192


class Disk:
    """The flat elliptic disk ``x²/a² + y²/b² <= 1`` in the plane z = 0 of its frame."""

    __slots__ = ("a", "b")

    def __init__(self, a, b):
        self.a = pl.semi_axis(a, "a")
        self.b = pl.semi_axis(b, "b")

    def __repr__(self):
        return f"Disk({self.a!r}, {self.b!r})"


# ---------------------------------------------------------------- kernels (numba)


@jit
def _rim_in(W, I, CON, SYS, SYSR, N, H, a, b, qa, qb, kinds, kind0):
    """The two systems 'an end of the chord that the other disk's plane cuts from this disk (semi-axes a, b)
    lies in the other disk (semi-axes qa, qb)'; H maps this disk's frame into the other's."""
    l1 = P.scale(W, I, H[fr.L0 + 6], a)
    l2 = P.scale(W, I, H[fr.L0 + 7], b)
    kap = P.scale(W, I, H[fr.V0 + 2], -1.0)
    lam2 = P.add(W, I, P.sq(W, I, l1), P.sq(W, I, l2), 1.0)
    S = P.add(W, I, lam2, P.sq(W, I, kap), -1.0)
    negS = P.scale(W, I, S, -1.0)
    if sy._positive(W, I, negS):
        return
    Pn = np.empty(2, dtype=np.int64)
    Qn = np.empty(2, dtype=np.int64)
    for x in range(2):
        aL = P.scale(W, I, H[fr.L0 + 3 * x], a)
        bL = P.scale(W, I, H[fr.L0 + 3 * x + 1], b)
        px = P.add(W, I, P.mul(W, I, kap, P.add(W, I, P.mul(W, I, aL, l1), P.mul(W, I, bL, l2), 1.0)),
                   P.mul(W, I, H[fr.V0 + x], lam2), 1.0)
        qx = P.add(W, I, P.mul(W, I, bL, l1), P.mul(W, I, aL, l2), -1.0)
        r = qa if x == 0 else qb
        Pn[x] = P.frac(W, I, px, 1.0, r)
        Qn[x] = P.frac(W, I, qx, 1.0, r)
    pp = P.add(W, I, P.sq(W, I, Pn[0]), P.sq(W, I, Pn[1]), 1.0)
    qq = P.add(W, I, P.sq(W, I, Qn[0]), P.sq(W, I, Qn[1]), 1.0)
    E = P.add(W, I, P.add(W, I, pp, P.mul(W, I, S, qq), 1.0), P.sq(W, I, P.mul(W, I, H[fr.M0], lam2)), -1.0)
    F = P.scale(W, I, P.add(W, I, P.mul(W, I, Pn[0], Qn[0]), P.mul(W, I, Pn[1], Qn[1]), 1.0), 2.0)
    G = P.add(W, I, P.sq(W, I, E), P.mul(W, I, P.sq(W, I, F), S), -1.0)
    zero = P.const(W, I, 0.0)
    wit = np.empty(4, dtype=np.int64)
    wit[0], wit[1], wit[2], wit[3] = zero, zero, zero, H[fr.M0]
    for k, c in ((0, E), (1, G)):
        if sy._positive(W, I, c):
            continue
        start = N[0]
        sy._con(CON, N, negS)
        sy._con(CON, N, c)
        sy._close(SYS, SYSR, N, start, 0, wit, 0.0)
        if N[2] == 0:
            kinds[N[1] - 1] = kind0 + k


@jit
def _spatial_systems(W, I, CON, SYS, SYSR, N, rows_a, ax_a, rows_b, ax_b, kinds):
    P.reset(W, I)
    N[0] = N[1] = N[2] = 0
    FA = fr.chain_frame(W, I, rows_a)
    FB = fr.chain_frame(W, I, rows_b)
    _rim_in(W, I, CON, SYS, SYSR, N, fr.relative(W, I, FB, FA), ax_a[0], ax_a[1], ax_b[0], ax_b[1], kinds, 0)
    _rim_in(W, I, CON, SYS, SYSR, N, fr.relative(W, I, FA, FB), ax_b[0], ax_b[1], ax_a[0], ax_a[1], kinds, 2)


@jit
def spatial_kernel(rows_a, ax_a, rows_b, ax_b, t_end, decide, W, I, Wdd, Idd, CON, SYS, SYSR, N, kinds, out):
    """First contact over [0, t_end] of two disks (semi-axes ax_a, ax_b) under element rows: doubles, then
    double-double when the bracket is wider than TIME_TOL.  ``decide``: decide the status at t = 0 from the
    systems (False: the caller knows the disks are apart at t = 0).  out as
    :func:`mjccd.geoms.planar.planar_kernel` (KIND: the winning system, 0-1 A's chord, 2-3 B's)."""
    for i in range(out.shape[0]):
        out[i] = 0.0
    out[kn.LO] = out[kn.HI] = out[kn.TIME] = -1.0
    out[pl.KIND] = -1.0
    for tier in range(2):
        Wt, It = (W, I) if tier == 0 else (Wdd, Idd)
        _spatial_systems(Wt, It, CON, SYS, SYSR, N, rows_a, ax_a, rows_b, ax_b, kinds)
        C, DS, DT, errs, ok = pl._extract(Wt, It, CON, N)
        if not ok:
            out[kn.FAILED] = kn.OVERFLOW
            return
        out[kn.TIER] = tier
        best, _ = kn.scan_systems(SYS, N, C, DS, DT, errs, t_end, out, decide)
        out[pl.KIND] = kinds[best] if best >= 0 else -1.0
        if out[kn.CERTIFIED] > 0.0 or tier == 1:
            return


@jit
def spatial_window(HBA, DBA, HAB, DAB, ax_a, ax_b, W, I, CON, SYS, SYSR, N, kinds, out):
    """The four systems from the two relative maps given as packed polynomials (13 each: L row-major, v, m, on
    a window of time reparametrised to [0, 1]), scanned from 0 without a status decision (out as
    :func:`spatial_kernel`)."""
    for i in range(out.shape[0]):
        out[i] = 0.0
    out[kn.LO] = out[kn.HI] = out[kn.TIME] = -1.0
    out[pl.KIND] = -1.0
    P.reset(W, I)
    N[0] = N[1] = N[2] = 0
    _rim_in(W, I, CON, SYS, SYSR, N, pl._load(W, I, HBA, DBA), ax_a[0], ax_a[1], ax_b[0], ax_b[1], kinds, 0)
    _rim_in(W, I, CON, SYS, SYSR, N, pl._load(W, I, HAB, DAB), ax_b[0], ax_b[1], ax_a[0], ax_a[1], kinds, 2)
    C, DS, DT, errs, ok = pl._extract(W, I, CON, N)
    if not ok:
        out[kn.FAILED] = kn.OVERFLOW
        return
    out[kn.TIER] = 1.0
    best, _ = kn.scan_systems(SYS, N, C, DS, DT, errs, 1.0, out, np.bool_(False))
    out[pl.KIND] = kinds[best] if best >= 0 else -1.0


# ---------------------------------------------------------------- exact frames (rational arithmetic)

_ONE, _ZERO = [Fraction(1)], [Fraction(0)]


def _lin(v0, v1):
    return X.trim([Fraction(v0), Fraction(v1) - Fraction(v0)])


def _rot(q):
    """rot(q) (polynomial entries) and |q|² for quaternion polynomials q, as frames._rotation."""
    w, x, y, z = q
    m, a = X.mul, X.add
    ww, xx, yy, zz = m(w, w), m(x, x), m(y, y), m(z, z)
    xy, xz, yz, wx, wy, wz = m(x, y), m(x, z), m(y, z), m(w, x), m(w, y), m(w, z)
    R = [[a(a(ww, xx), a(yy, zz), -1), X.scale(a(xy, wz, -1), 2), X.scale(a(xz, wy), 2)],
         [X.scale(a(xy, wz), 2), a(a(ww, xx, -1), a(yy, zz, -1)), X.scale(a(yz, wx, -1), 2)],
         [X.scale(a(xz, wy, -1), 2), X.scale(a(yz, wx), 2), a(a(ww, xx, -1), a(yy, zz, -1), -1)]]
    return R, a(a(ww, xx), a(yy, zz))


def _transpose(R):
    return [[R[j][i] for j in range(3)] for i in range(3)]


def _matvec(R, v):
    return [X.add(X.add(X.mul(R[i][0], v[0]), X.mul(R[i][1], v[1])), X.mul(R[i][2], v[2]))
            for i in range(3)]


def _matmul(A, B):
    return [[X.add(X.add(X.mul(A[i][0], B[0][j]), X.mul(A[i][1], B[1][j])), X.mul(A[i][2], B[2][j]))
             for j in range(3)] for i in range(3)]


def _element(row):
    """Forward (L, v, m) and inverse (G, h, g) of one element row, exactly as frames._element forms them."""
    kind = int(row[0])
    if kind == fr.SLIDE:
        eye = [[_ONE if i == j else _ZERO for j in range(3)] for i in range(3)]
        d = [_lin(row[1 + i] * row[4], row[1 + i] * row[5]) for i in range(3)]
        return (eye, d, _ONE), (eye, [X.scale(x, -1) for x in d], _ONE)
    if kind == fr.HINGE:
        q = [_ONE] + [_lin(row[1 + i] * row[4], row[1 + i] * row[5]) for i in range(3)]
        R, n2 = _rot(q)
        return (R, [_ZERO] * 3, n2), (_transpose(R), [_ZERO] * 3, n2)
    q = [_lin(row[4 + i], row[11 + i]) for i in range(4)]
    R, n2 = _rot(q)
    p = [_lin(row[1 + i], row[8 + i]) for i in range(3)]
    G = _transpose(R)
    return (R, [X.mul(x, n2) for x in p], n2), (G, [X.scale(x, -1) for x in _matvec(G, p)], n2)


def _compose(f1, f2):
    (L1, v1, m1), (G1, h1, g1) = f1
    (L2, v2, m2), (G2, h2, g2) = f2
    fwd = (_matmul(L1, L2), [X.add(a, X.mul(b, m2)) for a, b in zip(_matvec(L1, v2), v1)], X.mul(m1, m2))
    inv = (_matmul(G2, G1), [X.add(a, X.mul(b, g1)) for a, b in zip(_matvec(G2, h1), h2)], X.mul(g2, g1))
    return fwd, inv


def exact_frame(rows):
    """The frame of element rows in rational arithmetic: ((L, v, m), (G, h, g)) of power-basis Fractions."""
    f = _element(rows[0])
    for row in rows[1:]:
        f = _compose(f, _element(row))
    return f


def _relative(fa, fb):
    """B's frame into A's: (G_A L_B, G_A v_B + h_A m_B, g_A m_B)."""
    (LB, vB, mB), _ = fb
    _, (GA, hA, gA) = fa
    return (_matmul(GA, LB), [X.add(a, X.mul(b, mB)) for a, b in zip(_matvec(GA, vB), hA)], X.mul(gA, mB))


def _flat(rel):
    L, v, m = rel
    return [L[i][j] for i in range(3) for j in range(3)] + list(v) + [m]


ZOOM_ROUNDS = 4


def _zoom(fa, fb, da, db, lo, hi):
    """Narrow an uncertain bracket [lo, hi]: both relative maps (exact) are reparametrised to the window, so
    that the constraints' coefficients, and the scan's rounding with them, are as small as the constraints
    are there, and scanned again in double-double.  Returns (lo, hi, proven); lo = -1 when the window is
    proven free (so is the whole motion: the bracket held every possible contact)."""
    rba, rab = _flat(_relative(fb, fa)), _flat(_relative(fa, fb))
    ax_a, ax_b = np.array([da.a, da.b]), np.array([db.a, db.b])
    _, _, Wdd, Idd, CON, SYS, SYSR, N, kinds = _workspaces()
    out = np.empty(pl.OUTP)
    proven = False
    for _ in range(ZOOM_ROUNDS):
        t0, h = Fraction(lo), Fraction(hi) - Fraction(lo)
        pba = X.packed([X.taylor_shift(p, t0, h) for p in rba])
        pab = X.packed([X.taylor_shift(p, t0, h) for p in rab])
        spatial_window(*pba, *pab, ax_a, ax_b, Wdd, Idd, CON, SYS, SYSR, N, kinds, out)
        if out[kn.FAILED] == kn.OVERFLOW:
            break
        if out[kn.LO] < 0.0:
            return -1.0, -1.0, False
        new_lo = X.down(t0 + h * Fraction(float(out[kn.LO])))
        new_hi = X.up(t0 + h * Fraction(float(out[kn.HI])))
        lo = max(lo, new_lo)
        if out[kn.PROVEN] > 0.0 or not proven:  # a proven time, or (none yet) the end of the undecided band
            hi = min(hi, new_hi)
        proven = proven or out[kn.PROVEN] > 0.0
        if proven and hi - lo <= TIME_TOL:
            break
    return lo, hi, proven


def _world(f, t):
    """(R (3, 3), c (3,)) of the forward map at time t, in floats."""
    (L, v, m), _ = f
    t = Fraction(float(t))
    mt = X.value(m, t)
    return (np.array([[float(X.value(L[i][j], t) / mt) for j in range(3)] for i in range(3)]),
            np.array([float(X.value(v[i], t) / mt) for i in range(3)]))


# ---------------------------------------------------------------- the Python layer

_local = threading.local()


def _workspaces():
    return pl.thread_workspaces(_local, SLOTS)


def _chord(R, c, a, b, n_o, c_o):
    """The two ends of the chord that the plane (normal n_o through c_o) cuts from the disk (frame R, c;
    semi-axes a, b); both the same point when the plane only touches it."""
    lam = np.array([a * (n_o @ R[:, 0]), b * (n_o @ R[:, 1])])
    kap = n_o @ (c_o - c)
    l2 = lam @ lam
    root = math.sqrt(max(l2 - kap * kap, 0.0))
    perp = np.array([-lam[1], lam[0]])
    ends = []
    for sg in (-1.0, 1.0):
        z = (kap * lam + sg * root * perp) / l2
        ends.append(c + a * z[0] * R[:, 0] + b * z[1] * R[:, 1])
    return ends


def _contact_geometry(fa, da, fb, db, t):
    """(point, normal) of the contact at time t: the middle of the chords' overlap; the touched face's normal,
    or the rims' common perpendicular, turned from A toward B."""
    Ra, ca = _world(fa, t)
    Rb, cb = _world(fb, t)
    na, nb = Ra[:, 2], Rb[:, 2]
    D = np.cross(na, nb)
    if np.linalg.norm(D) < 1e-12:
        return None, None
    D /= np.linalg.norm(D)
    ea = _chord(Ra, ca, da.a, da.b, nb, cb)
    eb = _chord(Rb, cb, db.a, db.b, na, ca)
    fa_, fb_ = sorted(D @ e for e in ea), sorted(D @ e for e in eb)
    lo, hi = max(fa_[0], fb_[0]), min(fa_[1], fb_[1])
    f = 0.5 * (lo + hi)
    base = 0.25 * (ea[0] + ea[1] + eb[0] + eb[1])
    point = base + (f - D @ base) * D
    tol = 1e-7 * max(da.a, da.b, db.a, db.b)
    end_a = min(abs(f - x) for x in fa_) <= tol
    end_b = min(abs(f - x) for x in fb_) <= tol
    if end_a and end_b:  # rim against rim: the common perpendicular of the tangents
        ta = Ra[:, :2] @ _rim_tangent(Ra, ca, da, point)
        tb = Rb[:, :2] @ _rim_tangent(Rb, cb, db, point)
        n = np.cross(ta, tb)
        n = n if np.linalg.norm(n) > 1e-12 else D
        n = n / np.linalg.norm(n)
        return point, n if n @ (cb - ca) >= 0.0 else -n
    if end_a:  # A's rim on B's face
        s = nb @ (ca - point)
        n = -np.sign(s) * nb if abs(s) > tol else np.sign(np.mean(fb_) - np.mean(fa_)) * D
        return point, n
    if end_b:  # B's rim on A's face
        s = na @ (cb - point)
        n = np.sign(s) * na if abs(s) > tol else np.sign(np.mean(fb_) - np.mean(fa_)) * D
        return point, n
    return point, np.sign(np.mean(fb_) - np.mean(fa_)) * D


def _rim_tangent(R, c, d, x):
    """The tangent of the rim (in the disk's own axes) at the rim point nearest x."""
    y = R.T @ (x - c)
    th = math.atan2(y[1] / d.b, y[0] / d.a)
    return np.array([-d.a * math.sin(th), d.b * math.cos(th)])


def _planar_delegate(da, db, fa, fb, rel, t_max, origin):
    """Disks coplanar at every time: B's motion in A's plane (the relative map's upper-left block, exact) and A
    at rest, solved by the planar solver; the answer taken back to the world."""
    L, v, m = rel
    motion_b = pl._unchecked([[L[0][0], L[0][1], v[0]], [L[1][0], L[1][1], v[1]], [_ZERO, _ZERO, m]])
    rest = pl._unchecked([[_ONE, _ZERO, _ZERO], [_ZERO, _ONE, _ZERO], [_ZERO, _ZERO, _ONE]])
    c = pl.ellipse_first_contact(pl.Ellipse(da.a, da.b), rest, pl.Ellipse(db.a, db.b), motion_b, t_max=t_max)
    if c is None or c.point is None:
        return c
    R, ca = _world(fa, c.time)
    point = ca + R[:, :2] @ c.point + origin
    return c._replace(point=point, normal=R[:, :2] @ c.normal)


_UNDECIDED = object()
_REST = None


def _coplanar_status(da, db, rel, t):
    """The planar status ("separate", "touching", "overlapping") of the two disks at a time t (a Fraction) at
    which their planes coincide: B's frame in A's plane is the relative map's upper-left block there."""
    L, v, m = rel
    const = [[X.trim([X.value(p, t)]) for p in row] for row in
             ([L[0][0], L[0][1], v[0]], [L[1][0], L[1][1], v[1]], [_ZERO, _ZERO, m])]
    rest = pl._unchecked([[_ONE, _ZERO, _ZERO], [_ZERO, _ONE, _ZERO], [_ZERO, _ZERO, _ONE]])
    c = pl.ellipse_first_contact(pl.Ellipse(da.a, da.b), rest, pl.Ellipse(db.a, db.b), pl._unchecked(const),
                                 t_max=0.0)
    return "separate" if c is None else c.status_at_start


def _parallel(da, db, fa, rel, t_max, origin):
    """Planes parallel at every time, not always the same: the disks can only meet when B's plane passes
    through A's, at a root of B's height above A's plane (the relative map's v2).  No root in [0, t_max]
    (decided exactly): no contact.  One rational root (v2 of degree 1): the planar status there decides.
    Otherwise _UNDECIDED."""
    L, v, m = rel
    h = v[2]
    if not X.has_root_in_01([c * Fraction(t_max) ** k for k, c in enumerate(h)]):
        return None
    if len(h) != 2:
        return _UNDECIDED
    r = -h[0] / h[1]
    status = _coplanar_status(da, db, rel, r)
    if status == "separate":
        return None
    if r == 0:
        return Contact(0.0, None, None, status)
    t = float(r)
    R, ca = _world(fa, t)
    y = _deepest_in_plane(da, db, rel, r)
    point = ca + R[:, :2] @ y + origin
    side = 1.0 if X.value(h, r / 2) > 0 else -1.0  # B's side of A's plane before it arrives
    return Contact(t, point, side * R[:, 2], "separate")


def _deepest_in_plane(da, db, rel, r):
    """A common point (A's plane coordinates) of the coplanar disks at time r: B's boundary point deepest in A,
    or A's centre when B's boundary stays out of A (A inside B)."""
    L, v, m = rel
    MB = np.array([[float(X.value(p, r)) for p in row] for row in
                   ([L[0][0], L[0][1], v[0]], [L[1][0], L[1][1], v[1]], [_ZERO, _ZERO, m])])
    ea, eb = pl.Ellipse(da.a, da.b), pl.Ellipse(db.a, db.b)
    point, _, th = pl.deepest_point(np.eye(3), ea, MB, eb)
    if (point[0] / da.a) ** 2 + (point[1] / da.b) ** 2 <= 1.0:
        return point
    return np.zeros(2)


def disk_first_contact(disk_a, motion_a, disk_b, motion_b, *, t_max=1.0):
    """First time in [0, t_max] at which two moving flat elliptic disks touch, as a :class:`mjccd.Contact`, or
    None when they are proven apart over [0, t_max].

    ``disk_a``, ``disk_b``: :class:`Disk`; motions: :class:`mjccd.Static`,
    :class:`mjccd.Rigid` or :class:`mjccd.Chain`.  The point is a 3-vector in
    world coordinates, the normal outward from A (see the module's notes).
    ``status_at_start``: "separate", "touching" or "overlapping" (the disks
    cross).  An uncertain answer carries a ``bracket`` holding every possible
    first contact (point and normal None); disks whose planes coincide at an
    isolated time may be answered so.
    """
    for name, d in (("disk_a", disk_a), ("disk_b", disk_b)):
        if not isinstance(d, Disk):
            raise InputTypeError(f"{name}: expected a Disk, got {type(d).__name__}")
    rows_a = motion_rows(motion_a, "motion_a")
    rows_b = motion_rows(motion_b, "motion_b")
    t_max = _validate.time_bound(t_max, "t_max")
    origin = rows_a[0, 1:4].copy()
    rows_a, rows_b = shifted_rows(rows_a, origin), shifted_rows(rows_b, origin)
    fa, fb = exact_frame(rows_a), exact_frame(rows_b)
    rel = _relative(fa, fb)
    L, v, _ = rel
    if not any(L[2][0]) and not any(L[2][1]):  # the planes are parallel at every time
        if not any(v[2]):
            return _planar_delegate(disk_a, disk_b, fa, fb, rel, t_max, origin)
        answer = _parallel(disk_a, disk_b, fa, rel, t_max, origin)
        if answer is not _UNDECIDED:
            return answer
    decide = True
    if all(X.value(p, 0) == 0 for p in (L[2][0], L[2][1], v[2])):  # coplanar at the start: the planar status
        status = _coplanar_status(disk_a, disk_b, rel, Fraction(0))
        if status != "separate":
            return Contact(0.0, None, None, status)
        decide = False
    out = np.empty(pl.OUTP)
    spatial_kernel(rows_a, np.array([disk_a.a, disk_a.b]), rows_b, np.array([disk_b.a, disk_b.b]), float(t_max),
                   decide, *_workspaces(), out)
    if out[kn.FAILED] == kn.OVERFLOW:
        raise RuntimeError("disk pair: the contact polynomials outgrew the solver's workspace (a chain too deep "
                           f"for its degree limit {P.MAX_DEGREE})")
    status = int(out[kn.STATUS])
    if status == 0:  # undecided at the start (a touch, or planes within rounding of each other): the first
        # time proven in contact, scanning from 0, bounds every possible first contact
        spatial_kernel(rows_a, np.array([disk_a.a, disk_a.b]), rows_b, np.array([disk_b.a, disk_b.b]),
                       float(t_max), False, *_workspaces(), out)
        hi = float(out[kn.HI]) if out[kn.PROVEN] > 0.0 else t_max
        return Contact(0.0, None, None, "touching", "uncertain", (0.0, hi))
    if status == -1:
        return Contact(0.0, None, None, "overlapping")
    if out[kn.LO] < 0.0:
        return None
    lo, hi = float(out[kn.LO]), float(out[kn.HI])
    t = float(out[kn.TIME])
    if out[kn.CERTIFIED] == 0.0:
        lo, hi, proven = _zoom(fa, fb, disk_a, disk_b, lo, hi)
        if lo < 0.0:
            return None
        if not proven or hi - lo > TIME_TOL:
            return Contact(lo, None, None, "separate", "uncertain", (lo, hi))
        t = 0.5 * (lo + hi)
    point, normal = _contact_geometry(fa, disk_a, fb, disk_b, t)
    return Contact(t, None if point is None else point + origin, normal, "separate")
