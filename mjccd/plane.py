"""Moving ellipsoids against static planes (MuJoCo ``plane`` geoms): exact first contact and contact intervals.

A :class:`Plane` ``n . x = offset`` stands, as in MuJoCo, for the solid
half-space ``n . x <= offset`` below it (n is the outward normal).  A moving
ellipsoid is in contact with it when it touches or enters the half-space:

    g(t) = n . c(t) - offset - h(t) <= 0,     h(t) = sqrt(n^T S(t) n),

c the centre, S the shape matrix (``S = L diag(r^2) L^T`` for the frame map
x = L y + c), h the support along n.  Squaring, with a positive factor k(t)
that makes it polynomial,

    f(t) = k(t) ((n . c - offset)^2 - h^2),                       (1)

which is, up to that factor, ``pi^T adj(A(t)) pi`` for the plane vector
``pi = (n, -offset)`` and the quadric A(t) of :mod:`mjccd.motion`.  f > 0 iff
|n . c - offset| > h, so

* while the body is clear (g > 0), f > 0 and the centre side
  ``sigma = n . c - offset`` is positive; it cannot change sign while f > 0,
  because at sigma = 0, f = -k h^2 < 0.  The first contact from a clear start
  is the first root of f (a tangential graze is a double root);
* the body touches or penetrates exactly where f <= 0 or sigma < 0, so
  the contact intervals are bounded by roots of f and classified by sigma.

f is built in Bernstein form with a proven bound of its coefficients' rounding
(the same straight-line program run on absolute values, times gamma_K), and
[0, 1] is cut into pieces on which f is proven positive (f - E > 0), proven
negative (f + E < 0), or undecided (a rounding band around each root); the
pieces' side is proven on sigma's own Bernstein coefficients.  An event is
certified when its band is at most ``mjccd.ccd.TIME_TOL`` wide; otherwise the
Python layer settles it in rational arithmetic on the exact status at dyadic
times (as :mod:`mjccd.ccd` does for pairs), and reports ``uncertain`` where that
cannot decide (a graze inside the rounding band).

Degrees of f: rigid 6 (``sigma^2 |q|^4 - sum_k r_k^2 (rot(q)^T n)_k^2``),
affine 5 (``sigma^2 det Q - n^T adj(Q) n``), and for the motions given by
their scaled inverse W = [[G, h], [0, g]] (linear_affine, rational, chain)
``a^2 - sum_k b_k^2`` with ``a = -n^T adj(G) h - offset det G`` and
``b_k = g r_k (adj(G)^T n)_k``.

Public: :class:`Plane`, :func:`plane_first_contact`,
:func:`plane_collision_intervals`, :func:`solve_plane`, and the compiled
kernels :func:`plane_first_contact_kernel` and :func:`plane_pair_kernel` for
ellipsoids moving between two poses (what :class:`mjccd.scene.Scene` calls per
(ellipsoid, plane) pair).
"""
import math
from dataclasses import dataclass
from fractions import Fraction

import numba
import numpy as np

from mjccd import _validate
from mjccd import bernstein as bz
from mjccd.ccd import TIME_TOL, Contact, PairSolution, time_pieces
from mjccd.errors import InputError, InputTypeError
from mjccd.motion import EPS, Affine, Motion, Rigid, Static, gamma
from mjccd.quadric import STATUS_NAMES, Ellipsoid

# compiled on first use and cached; no cfunc wrapper (no kernel is passed around as a first-class function);
# forceinline=False: numba hands a caller's forceinline down to the callees it compiles
_jit = numba.njit(cache=True, nogil=True, no_cfunc_wrapper=True, forceinline=False)
# hot-path helpers: compiled once, then inlined by LLVM into each caller (no call, no reference counting of
# array arguments); inline="always" copied their numba IR into every caller instead, which multiplied
# compile time (docs/benchmarks.md, "First use")
_inline = numba.njit(cache=True, nogil=True, no_cfunc_wrapper=True, forceinline=True)

LEAF = 2.0 ** -44           # width below which an undecided piece of time is left undecided
MAX_NODES = 4096            # pieces examined per scan; past it the rest of the scan is left undecided
STACK = 192                 # pending pieces of a scan (a full stack leaves the piece undecided)
RUN_FIELDS = 8              # t_in, t_out, in_lo, in_hi, out_lo, out_hi, proven, gap
TWO_POSE_RUNS = 16          # runs a two-pose scan can hold (f has at most 6 roots; spare for bands)
ROUNDING_DEPTH = 64         # longest chain of roundings of the two-pose builders (about 33, doubled)
RUNS_AT = 6 * 7 + 4 * 2 + 3 * STACK + 176  # the runs of plane_first_contact_kernel, after the scan and builders
PLANE_WORK = RUNS_AT + TWO_POSE_RUNS * RUN_FIELDS  # float64 scratch of the two-pose kernels
EXACT_BITS = 60             # exact bisection stops at 2^-60 of the time
EXACT_SAMPLES = 16
CLEAR, UNDECIDED, CONTACT = 1, 0, -1  # labels of the pieces of a scan


# ---------------------------------------------------------------- the plane


@dataclass(frozen=True, init=False)
class Plane:
    """A static plane ``normal . x = offset`` bounding the solid half-space ``normal . x <= offset``.

    As MuJoCo's ``plane`` geom: infinite, the body is in contact when it
    touches or enters the side opposite to ``normal``.  ``normal`` (3,) is
    normalised here; ``offset`` is the plane's signed distance from the world
    origin along it.  (Note the sign: :class:`mjccd.SeparatingPlane` writes
    ``normal . x + offset = 0``.)

    Args:
        normal: (3,) finite, non-zero; any length.
        offset: finite number.
    """

    normal: np.ndarray
    offset: float

    def __init__(self, normal, offset=0.0):
        v = _validate.direction(normal, 3, "normal")
        n = v / np.sqrt(v @ v)
        d = _validate.scalar(offset, "offset")
        hi = _validate.LENGTH_RANGE[1]
        if abs(d) > hi:
            raise InputError(f"offset: {d:g} is outside the supported range [{-hi:g}, {hi:g}]")
        n.flags.writeable = False
        object.__setattr__(self, "normal", n)
        object.__setattr__(self, "offset", d)

    @classmethod
    def through(cls, point, normal):
        """The plane through ``point`` (3,) with ``normal`` (3,): offset = normal . point (normal normalised first)."""
        p = _validate.coordinates(point, (3,), "point")
        plane = cls(normal, 0.0)
        return cls(plane.normal, float(plane.normal @ p))

    def as_array(self):
        """(4,) float64 ``[nx, ny, nz, offset]``, the row layout :class:`mjccd.scene.Scene` takes."""
        return np.array([*self.normal, self.offset])

    def signed_distance(self, point):
        """``normal . point - offset`` (positive above the plane)."""
        return float(self.normal @ np.asarray(point, float) - self.offset)

    def __eq__(self, other):
        return (isinstance(other, Plane) and bool(np.array_equal(self.normal, other.normal))
                and self.offset == other.offset)

    def __hash__(self):
        return hash((tuple(self.normal.tolist()), self.offset))

    def __repr__(self):
        return f"Plane(normal={self.normal.tolist()}, offset={self.offset!r})"


def plane_rows(planes, field="planes"):
    """(K, 4) float64 rows ``[nx, ny, nz, offset]`` with unit normals, from Planes or rows (validated)."""
    if isinstance(planes, Plane):
        planes = [planes]
    if isinstance(planes, np.ndarray) and planes.dtype != object:
        items = list(_validate.array(planes, (None, 4), field))
    else:
        try:
            items = list(planes)
        except TypeError:
            raise InputError(f"{field}: expected K planes (mjccd.Plane or rows [nx, ny, nz, offset])") from None
    rows = np.empty((len(items), 4))
    for k, item in enumerate(items):
        if isinstance(item, Plane):
            plane = item
        else:
            row = _validate.vector(item, 4, f"{field}[{k}]")
            try:
                plane = Plane(row[:3], row[3])
            except InputError as err:
                raise InputError(f"{field}[{k}].{err}") from None
        rows[k] = plane.as_array()
    return rows


# ---------------------------------------------------------------- flat scratch layout
#
# The kernels work in one float64 array ``w`` at fixed offsets (no views, nothing allocated).  For f with
# N = deg + 1 coefficients and sigma with NS: f, e (bounds of f's errors), lo = f - e, hi = f + e, two
# restriction buffers, sigma, its error bounds, two buffers, then the scan's stack of pieces.


@_inline
def _layout(N, NS):
    """Offsets (F, E, LO, HI, TL, TH, S, SE, TS, TE, SA, end) of the scan's scratch."""
    S = 6 * N
    SA = S + 4 * NS
    return 0, N, 2 * N, 3 * N, 4 * N, 5 * N, S, S + NS, S + 2 * NS, S + 3 * NS, SA, SA + 3 * STACK


def scan_size(N, NS):
    """Floats of scratch a scan of f (N coefficients) and sigma (NS) needs."""
    return 6 * N + 4 * NS + 3 * STACK


@_inline
def _mul(w, ia, na, ib, nb, io):
    """w[io : io + na + nb + 1] = product of the Bernstein polynomials of degrees na at ia and nb at ib
    (na + nb <= 48, the tabled binomials: the two-pose builders)."""
    for k in range(na + nb + 1):
        w[io + k] = 0.0
    for i in range(na + 1):
        ai = w[ia + i] * bz.BINOMIALS[na, i]
        for j in range(nb + 1):
            w[io + i + j] += ai * (w[ib + j] * bz.BINOMIALS[nb, j])
    for k in range(na + nb + 1):
        w[io + k] /= bz.BINOMIALS[na + nb, k]


@_inline
def _restrict(w, src, N, a, b, dst):
    """w[dst : dst + N] = the polynomial at src reparametrised from [a, b] onto [0, 1] (de Casteljau, as
    :func:`mjccd.bernstein.restrict_into`)."""
    n = N - 1
    for i in range(N):
        w[dst + i] = w[src + i]
    if b < 1.0:
        for r in range(1, n + 1):
            for i in range(n, r - 1, -1):
                w[dst + i] = (1.0 - b) * w[dst + i - 1] + b * w[dst + i]
    if a > 0.0:
        t = a / b if b > 0.0 else 0.0
        for r in range(1, n + 1):
            for i in range(n - r + 1):
                w[dst + i] = (1.0 - t) * w[dst + i] + t * w[dst + i + 1]


@_jit
def _value_slope(w, off, N, t):
    """p(t) and p'(t) of the Bernstein polynomial at w[off : off + N] (as :func:`mjccd.bernstein.value_and_slope`)."""
    n = N - 1
    if n == 0:
        return w[off], 0.0
    flip = t > 0.5
    x = (1.0 - t) / t if flip else t / (1.0 - t)
    acc = w[off] if flip else w[off + n]
    dacc = (w[off] - w[off + 1]) if flip else (w[off + n] - w[off + n - 1])
    tabled = n <= bz.TABLED_DEGREE
    binom = 1.0
    for k in range(n - 1, -1, -1):
        binom = bz.BINOMIALS[n, k] if tabled else binom * (k + 1) / (n - k)
        acc = acc * x + binom * (w[off + n - k] if flip else w[off + k])
    binom = 1.0
    for k in range(n - 2, -1, -1):
        binom = bz.BINOMIALS[n - 1, k] if tabled else binom * (k + 1) / (n - 1 - k)
        diff = (w[off + n - k - 1] - w[off + n - k]) if flip else (w[off + k + 1] - w[off + k])
        dacc = dacc * x + binom * diff
    far = t if flip else 1.0 - t
    slope = n * dacc * far ** (n - 1)
    return acc * far ** n, -slope if flip else slope


@_jit
def _value(w, off, N, t):
    v, _ = _value_slope(w, off, N, t)
    return v


@_inline
def _max_abs(w, off, N):
    m = 0.0
    for i in range(N):
        m = max(m, abs(w[off + i]))
    return m


# ---------------------------------------------------------------- two-pose builders


@_inline
def _scale_of(radii):
    """The power of two L >= the largest radius (lengths are divided by it exactly)."""
    rmax = max(radii[0], radii[1], radii[2])
    _, e = math.frexp(rmax)
    return math.ldexp(1.0, e)


@_inline
def _two_sum(a, b):
    s = a + b
    z = s - a
    return s, (a - (s - z)) + (b - z)


@_inline
def _two_product(a, b):
    p = a * b
    c = 134217729.0 * a  # Dekker's split (2^27 + 1)
    a1 = c - (c - a)
    a2 = a - a1
    c = 134217729.0 * b
    b1 = c - (c - b)
    b2 = b - b1
    return p, a2 * b2 - (((p - a1 * b1) - a2 * b1) - a1 * b2)


@_inline
def _side_into(p0, p1, plane, L, w, S, SE):
    """w[S : S + 2] = sigma(t) / L = (n . c(t) - offset) / L (degree 1) and w[SE : SE + 2] bounds of its errors.

    Compensated (Ogita, Rump and Oishi's Dot2): the error is u |sigma| plus
    gamma_4^2 times the sum of the terms' magnitudes, so a body and a plane
    far from the origin keep the accuracy of their distance.
    """
    for end in range(2):
        p = p0 if end == 0 else p1
        hi, lo = _two_product(plane[0], p[0])
        for m in range(1, 3):
            h, r = _two_product(plane[m], p[m])
            hi, q = _two_sum(hi, h)
            lo += q + r
        hi, q = _two_sum(hi, -plane[3])
        lo += q
        v = hi + lo
        size = abs(plane[0] * p[0]) + abs(plane[1] * p[1]) + abs(plane[2] * p[2]) + abs(plane[3])
        g4 = gamma(4)
        w[S + end] = v / L
        w[SE + end] = (2.0 * EPS * abs(v) + 2.0 * g4 * g4 * size) / L


@_jit
def _rigid_into(radii, q0, q1, plane, L, w, S, SE, F, E, B, g):
    """w[F : F + 7] = f of a rigid motion, ``sigma^2 |q|^4 - sum_k r_k^2 (rot(q)^T n)_k^2`` in units of L, and
    w[E : E + 7] the bounds of its coefficients' errors: ``g`` (gamma of the rounding depth) times the
    program on absolute values, plus what sigma's own errors (at w[SE]) can change.  w[S : S + 2] must
    hold sigma / L.  Scratch from B on (84 floats)."""
    s = 1.0
    if q0[0] * q1[0] + q0[1] * q1[1] + q0[2] * q1[2] + q0[3] * q1[3] < 0.0:
        s = -1.0  # the lerp takes the short way (as Rigid does)
    VEC, VECA, NRM, NRMA = B, B + 9, B + 18, B + 21  # rot(q)^T n (3 x degree 2), |q|^2, and abs programs
    for i in range(3):
        # coefficient i of the products q_a q_b of the two lerps (Bernstein, degree 2)
        w0, x0, y0, z0 = q0[0], q0[1], q0[2], q0[3]
        w1, x1, y1, z1 = s * q1[0], s * q1[1], s * q1[2], s * q1[3]
        if i == 0:
            ww, xx, yy, zz, wx, wy, wz, xy, xz, yz = (w0 * w0, x0 * x0, y0 * y0, z0 * z0, w0 * x0, w0 * y0, w0 * z0,
                                                      x0 * y0, x0 * z0, y0 * z0)
        elif i == 2:
            ww, xx, yy, zz, wx, wy, wz, xy, xz, yz = (w1 * w1, x1 * x1, y1 * y1, z1 * z1, w1 * x1, w1 * y1, w1 * z1,
                                                      x1 * y1, x1 * z1, y1 * z1)
        else:
            ww, xx, yy, zz = w0 * w1, x0 * x1, y0 * y1, z0 * z1
            wx, wy, wz = (w0 * x1 + x0 * w1) / 2.0, (w0 * y1 + y0 * w1) / 2.0, (w0 * z1 + z0 * w1) / 2.0
            xy, xz, yz = (x0 * y1 + y0 * x1) / 2.0, (x0 * z1 + z0 * x1) / 2.0, (y0 * z1 + z0 * y1) / 2.0
        aw0, ax0, ay0, az0 = abs(w0), abs(x0), abs(y0), abs(z0)
        aw1, ax1, ay1, az1 = abs(w1), abs(x1), abs(y1), abs(z1)
        if i == 0:
            dia = aw0 * aw0 + ax0 * ax0 + ay0 * ay0 + az0 * az0
            axy, axz, ayz, awx, awy, awz = ax0 * ay0, ax0 * az0, ay0 * az0, aw0 * ax0, aw0 * ay0, aw0 * az0
        elif i == 2:
            dia = aw1 * aw1 + ax1 * ax1 + ay1 * ay1 + az1 * az1
            axy, axz, ayz, awx, awy, awz = ax1 * ay1, ax1 * az1, ay1 * az1, aw1 * ax1, aw1 * ay1, aw1 * az1
        else:
            dia = aw0 * aw1 + ax0 * ax1 + ay0 * ay1 + az0 * az1
            axy, axz, ayz = (ax0 * ay1 + ay0 * ax1) / 2.0, (ax0 * az1 + az0 * ax1) / 2.0, (ay0 * az1 + az0 * ay1) / 2.0
            awx, awy, awz = (aw0 * ax1 + ax0 * aw1) / 2.0, (aw0 * ay1 + ay0 * aw1) / 2.0, (aw0 * az1 + az0 * aw1) / 2.0
        r00 = ww + xx - yy - zz
        r11 = ww - xx + yy - zz
        r22 = ww - xx - yy + zz
        r01 = 2.0 * (xy - wz)
        r02 = 2.0 * (xz + wy)
        r10 = 2.0 * (xy + wz)
        r12 = 2.0 * (yz - wx)
        r20 = 2.0 * (xz - wy)
        r21 = 2.0 * (yz + wx)
        n0, n1, n2 = plane[0], plane[1], plane[2]
        w[VEC + i] = r00 * n0 + r10 * n1 + r20 * n2
        w[VEC + 3 + i] = r01 * n0 + r11 * n1 + r21 * n2
        w[VEC + 6 + i] = r02 * n0 + r12 * n1 + r22 * n2
        a01, a02, a12 = 2.0 * (axy + awz), 2.0 * (axz + awy), 2.0 * (ayz + awx)
        m0, m1, m2 = abs(n0), abs(n1), abs(n2)
        w[VECA + i] = dia * m0 + a01 * m1 + a02 * m2
        w[VECA + 3 + i] = a01 * m0 + dia * m1 + a12 * m2
        w[VECA + 6 + i] = a02 * m0 + a12 * m1 + dia * m2
        w[NRM + i] = ww + xx + yy + zz
        w[NRMA + i] = dia
    SQ, SQA, TMP = B + 24, B + 29, B + 34
    for i in range(5):
        w[SQ + i] = 0.0
        w[SQA + i] = 0.0
    for k in range(3):
        rk = radii[k] / L
        r2 = rk * rk
        _mul(w, VEC + 3 * k, 2, VEC + 3 * k, 2, TMP)
        for i in range(5):
            w[SQ + i] += r2 * w[TMP + i]
        _mul(w, VECA + 3 * k, 2, VECA + 3 * k, 2, TMP)
        for i in range(5):
            w[SQA + i] += r2 * w[TMP + i]
    N2, N2A, S2, S2A, ONE, LEFT, LEFTA = B + 39, B + 44, B + 49, B + 52, B + 55, B + 58, B + 65
    SIP, SII, LEFTP = B + 72, B + 74, B + 76
    _mul(w, NRM, 2, NRM, 2, N2)
    _mul(w, NRMA, 2, NRMA, 2, N2A)
    for i in range(3):
        w[ONE + i] = 1.0
    _mul(w, SQ, 4, ONE, 2, F)
    _mul(w, SQA, 4, ONE, 2, E)
    _sigma_term(w, S, SE, N2, N2A, 4, S2, S2A, SIP, SII, LEFT, LEFTA, LEFTP)
    for i in range(7):
        w[F + i] = w[LEFT + i] - w[F + i]
        w[E + i] = g * (w[LEFTA + i] + w[E + i]) + (w[LEFTA + i] - w[LEFTP + i]) * (1.0 + 1e-6)


@_inline
def _sigma_term(w, S, SE, M, MA, nm, S2, S2A, SIP, SII, LEFT, LEFTA, LEFTP):
    """LEFT = sigma^2 M (M of degree nm at w[M]), LEFTA its absolute program with |sigma| inflated by its
    error bounds, LEFTP the same with |sigma| as computed: LEFTA - LEFTP bounds what sigma's errors change."""
    for i in range(2):
        w[SIP + i] = abs(w[S + i])
        w[SII + i] = abs(w[S + i]) + w[SE + i]
    _mul(w, S, 1, S, 1, S2)
    _mul(w, S2, 2, M, nm, LEFT)
    _mul(w, SII, 1, SII, 1, S2A)
    _mul(w, S2A, 2, MA, nm, LEFTA)
    _mul(w, SIP, 1, SIP, 1, S2A)
    _mul(w, S2A, 2, MA, nm, LEFTP)


@_inline
def _rotation_abs(q, w, R, RA):
    """w[R : R + 9] = rot(q) / |q|^2 row-major, w[RA : RA + 9] the same program on absolute values."""
    qw, qx, qy, qz = q[0], q[1], q[2], q[3]
    aw, ax, ay, az = abs(qw), abs(qx), abs(qy), abs(qz)
    n = qw * qw + qx * qx + qy * qy + qz * qz
    w[R + 0] = (qw * qw + qx * qx - qy * qy - qz * qz) / n
    w[R + 1] = 2.0 * (qx * qy - qw * qz) / n
    w[R + 2] = 2.0 * (qx * qz + qw * qy) / n
    w[R + 3] = 2.0 * (qx * qy + qw * qz) / n
    w[R + 4] = (qw * qw - qx * qx + qy * qy - qz * qz) / n
    w[R + 5] = 2.0 * (qy * qz - qw * qx) / n
    w[R + 6] = 2.0 * (qx * qz - qw * qy) / n
    w[R + 7] = 2.0 * (qy * qz + qw * qx) / n
    w[R + 8] = (qw * qw - qx * qx - qy * qy + qz * qz) / n
    dia = (aw * aw + ax * ax + ay * ay + az * az) / n
    w[RA + 0] = w[RA + 4] = w[RA + 8] = dia
    w[RA + 1] = w[RA + 3] = 2.0 * (ax * ay + aw * az) / n
    w[RA + 2] = w[RA + 6] = 2.0 * (ax * az + aw * ay) / n
    w[RA + 5] = w[RA + 7] = 2.0 * (ay * az + aw * ax) / n


# the adjugate of a symmetric 3x3 Q as six entries (00, 11, 22, 01, 02, 12): adj = Q[a] Q[b] - Q[c] Q[d]
_ADJ_TERMS = ((4, 8, 5, 5), (0, 8, 2, 2), (0, 4, 1, 1), (2, 5, 1, 8), (1, 5, 2, 4), (1, 2, 0, 5))


@_jit
def _affine_into(radii, q0, q1, plane, L, w, S, SE, F, E, B, g):
    """w[F : F + 6] = f of the affine interpolant, ``sigma^2 det Q - n^T adj(Q) n`` with Q the lerp of
    R diag(L^2 / r^2) R^T, and w[E : E + 6] the bounds of its coefficients' errors (as :func:`_rigid_into`).
    Scratch from B on (150 floats)."""
    R, RA, Q, QA, DH = B, B + 9, B + 18, B + 36, B + 54  # Q, QA: 9 entries x 2 coefficients
    for k in range(3):
        rk = radii[k] / L
        w[DH + k] = 1.0 / (rk * rk)
    for end in range(2):
        _rotation_abs(q0 if end == 0 else q1, w, R, RA)
        for i in range(3):
            for j in range(3):
                acc = 0.0
                acca = 0.0
                for k in range(3):
                    acc += w[R + 3 * i + k] * w[R + 3 * j + k] * w[DH + k]
                    acca += w[RA + 3 * i + k] * w[RA + 3 * j + k] * w[DH + k]
                w[Q + 2 * (3 * i + j) + end] = acc
                w[QA + 2 * (3 * i + j) + end] = acca
    ADJ, ADJA, T1, T2 = B + 57, B + 75, B + 93, B + 96  # 6 entries x 3 coefficients
    for k in range(6):
        ia, ib, ic, id_ = _ADJ_TERMS[k]
        _mul(w, Q + 2 * ia, 1, Q + 2 * ib, 1, T1)
        _mul(w, Q + 2 * ic, 1, Q + 2 * id_, 1, T2)
        for i in range(3):
            w[ADJ + 3 * k + i] = w[T1 + i] - w[T2 + i]
        _mul(w, QA + 2 * ia, 1, QA + 2 * ib, 1, T1)
        _mul(w, QA + 2 * ic, 1, QA + 2 * id_, 1, T2)
        for i in range(3):
            w[ADJA + 3 * k + i] = w[T1 + i] + w[T2 + i]
    DET, DETA, T3 = B + 99, B + 103, B + 107
    for i in range(4):
        w[DET + i] = 0.0
        w[DETA + i] = 0.0
    for j in range(3):  # det = Q00 adj00 + Q01 adj01 + Q02 adj02
        idx = 0 if j == 0 else (3 if j == 1 else 4)
        _mul(w, Q + 2 * j, 1, ADJ + 3 * idx, 2, T3)
        for i in range(4):
            w[DET + i] += w[T3 + i]
        _mul(w, QA + 2 * j, 1, ADJA + 3 * idx, 2, T3)
        for i in range(4):
            w[DETA + i] += w[T3 + i]
    NAN, NANA = B + 111, B + 114
    n0, n1, n2 = plane[0], plane[1], plane[2]
    for i in range(3):
        w[NAN + i] = (n0 * n0 * w[ADJ + i] + n1 * n1 * w[ADJ + 3 + i] + n2 * n2 * w[ADJ + 6 + i]
                      + 2.0 * (n0 * n1 * w[ADJ + 9 + i] + n0 * n2 * w[ADJ + 12 + i] + n1 * n2 * w[ADJ + 15 + i]))
        w[NANA + i] = (n0 * n0 * w[ADJA + i] + n1 * n1 * w[ADJA + 3 + i] + n2 * n2 * w[ADJA + 6 + i]
                       + 2.0 * (abs(n0 * n1) * w[ADJA + 9 + i] + abs(n0 * n2) * w[ADJA + 12 + i]
                                + abs(n1 * n2) * w[ADJA + 15 + i]))
    S2, S2A, ONE, LEFT, LEFTA = B + 117, B + 120, B + 123, B + 127, B + 133
    SIP, SII, LEFTP = B + 139, B + 141, B + 143
    for i in range(4):
        w[ONE + i] = 1.0
    _mul(w, NAN, 2, ONE, 3, F)
    _mul(w, NANA, 2, ONE, 3, E)
    _sigma_term(w, S, SE, DET, DETA, 3, S2, S2A, SIP, SII, LEFT, LEFTA, LEFTP)
    for i in range(6):
        w[F + i] = w[LEFT + i] - w[F + i]
        w[E + i] = g * (w[LEFTA + i] + w[E + i]) + (w[LEFTA + i] - w[LEFTP + i]) * (1.0 + 1e-6)


# ---------------------------------------------------------------- the scan of [0, t_end]


@_inline
def _bands(w, N, NS, g):
    """In the scan layout: e = g w[E] (the bounds of f's coefficient errors), lo = f - e, hi = f + e; returns
    the restriction margins of lo, hi and sigma (whose error bounds are at w[SE])."""
    F, E, LO, HI, _, _, S, _, _, _, _, _ = _layout(N, NS)
    for i in range(N):
        w[E + i] = g * w[E + i]
        w[LO + i] = w[F + i] - w[E + i]
        w[HI + i] = w[F + i] + w[E + i]
    gr = gamma(6 * N + 6)
    return gr * _max_abs(w, LO, N), gr * _max_abs(w, HI, N), gamma(6 * NS + 6) * _max_abs(w, S, NS)


@_inline
def _classify(w, N, NS, mlo, mhi, a, b):
    """1: f proven > 0 on [a, b]; -1: proven < 0; 0: nothing can be proven on any part of it; 2: split."""
    _, _, LO, HI, TL, TH, _, _, _, _, _, _ = _layout(N, NS)
    _restrict(w, LO, N, a, b, TL)
    _restrict(w, HI, N, a, b, TH)
    lmin = lmax = w[TL]
    hmin = hmax = w[TH]
    for i in range(1, N):
        lmin = min(lmin, w[TL + i])
        lmax = max(lmax, w[TL + i])
        hmin = min(hmin, w[TH + i])
        hmax = max(hmax, w[TH + i])
    if lmin > mlo:
        return 1
    if hmax < -mhi:
        return -1
    if lmax <= mlo and hmin >= -mhi:
        return 0
    return 2


@_inline
def _side_sign(w, N, NS, ms, a, b, whole):
    """Proven sign of sigma on [a, b] (``whole``) or at its midpoint, else 0."""
    _, _, _, _, _, _, S, SE, TS, TE, _, _ = _layout(N, NS)
    if whole:
        _restrict(w, S, NS, a, b, TS)
        _restrict(w, SE, NS, a, b, TE)
        pos = True
        neg = True
        for i in range(NS):
            slack = w[TE + i] * (1.0 + 1e-9) + ms
            if not w[TS + i] > slack:
                pos = False
            if not w[TS + i] < -slack:
                neg = False
        return 1 if pos else (-1 if neg else 0)
    t = 0.5 * (a + b)
    v = _value(w, S, NS, t)
    err = _value(w, SE, NS, t) * (1.0 + 1e-9) + ms
    if v > err:
        return 1
    if v < -err:
        return -1
    return 0


@_jit
def _root_between(w, F, N, a, b):
    """A zero of the computed f in [a, b] where f(a) and f(b) differ in sign (safeguarded Newton)."""
    positive_at_a = _value(w, F, N, a) > 0.0
    noise = 8.0 * N * EPS * _max_abs(w, F, N)  # below this the computed value is rounding
    lo, hi = a, b
    x = 0.5 * (a + b)
    for _ in range(100):
        v, s = _value_slope(w, F, N, x)
        if abs(v) <= noise:
            return x
        if (v > 0.0) == positive_at_a:
            lo = x
        else:
            hi = x
        nx = x - v / s if s != 0.0 else 0.5 * (lo + hi)
        if not (lo < nx < hi):
            nx = 0.5 * (lo + hi)
        if abs(nx - x) <= 1e-300 + 2e-16 * abs(x) or hi - lo <= 4e-16 * hi:
            return nx
        x = nx
    return x


@_jit
def _lowest(w, F, N, a, b):
    """Where the computed f is smallest on [a, b] (golden section; a graze's estimate)."""
    g = 0.5 * (math.sqrt(5.0) - 1.0)
    lo, hi = a, b
    x1 = hi - g * (hi - lo)
    x2 = lo + g * (hi - lo)
    f1, f2 = _value(w, F, N, x1), _value(w, F, N, x2)
    for _ in range(100):
        if hi - lo <= 4e-16 * max(hi, 1e-300):
            break
        if f1 <= f2:
            hi, x2, f2 = x2, x1, f1
            x1 = hi - g * (hi - lo)
            f1 = _value(w, F, N, x1)
        else:
            lo, x1, f1 = x1, x2, f2
            x2 = lo + g * (hi - lo)
            f2 = _value(w, F, N, x2)
    best = 0.5 * (lo + hi)
    fb = _value(w, F, N, best)
    if _value(w, F, N, a) < fb:
        best = a
        fb = _value(w, F, N, a)
    if _value(w, F, N, b) < fb:
        best = b
    return best


@_jit
def _event(w, F, N, lo, hi):
    """The estimate of an event in the proven bracket [lo, hi]: f's zero when it changes sign there, else the middle."""
    if hi <= lo:
        return lo
    vl, vh = _value(w, F, N, lo), _value(w, F, N, hi)
    if (vl > 0.0 and vh < 0.0) or (vl < 0.0 and vh > 0.0):
        return _root_between(w, F, N, lo, hi)
    return 0.5 * (lo + hi)


@_jit
def _close_run(runs, k, w, N, in_lo, in_hi, last_contact, out_hi, gap, at_start):
    """Row k of ``runs``: a run of time not proven clear, from the end of a clear piece (in_lo) to the start
    of the next (out_hi); in_hi is where contact is first proven (-1: never, an unproven run), last_contact
    where it is last proven.  ``at_start``: the run starts at t = 0 (its entry is 0)."""
    runs[k, 7] = 1.0 if gap else 0.0
    if in_hi < 0.0:  # nothing proven: a possible graze, estimated where f is lowest
        t = 0.0 if at_start else _lowest(w, 0, N, in_lo, out_hi)
        runs[k, 0] = runs[k, 1] = t
        runs[k, 2], runs[k, 3], runs[k, 4], runs[k, 5] = in_lo, out_hi, in_lo, out_hi
        runs[k, 6] = 0.0
        return
    runs[k, 6] = 1.0
    runs[k, 0] = 0.0 if at_start else _event(w, 0, N, in_lo, in_hi)
    runs[k, 1] = out_hi if last_contact >= out_hi else _event(w, 0, N, last_contact, out_hi)
    runs[k, 2], runs[k, 3], runs[k, 4], runs[k, 5] = in_lo, in_hi, last_contact, out_hi


@_jit
def scan(w, N, NS, g, t_end, first_only, runs):
    """Cut [0, t_end] into pieces on which the body is proven clear, proven in contact, or undecided, and
    collect the runs of pieces not proven clear.

    ``w`` in the layout of :func:`_layout` (scratch of :func:`scan_size`
    floats): f (N Bernstein coefficients, see (1)) at F, at E the bounds of
    its coefficients' errors divided by ``g`` (the two-pose builders leave
    their absolute-value program there, g = gamma_K), sigma (NS
    coefficients) at S and the bounds of its errors at SE.  Writes
    ``runs`` rows [t_in, t_out, in_lo, in_hi, out_lo, out_hi, proven, gap]:
    the estimates of the run's ends and their proven brackets; ``proven`` 0
    for a run in which no contact is proven (a possible graze); ``gap`` 1
    when an undecided stretch wider than TIME_TOL lies between two contacts.
    Returns (status at start: 1 separate, 0 touching or undecided,
    -1 overlapping; number of runs; reached: -1, or the time from which a
    limit stopped the scan).  With ``first_only`` it stops at the first
    proven contact (its run then ends where it starts).
    """
    mlo, mhi, ms = _bands(w, N, NS, g)
    _, _, _, _, _, _, _, _, _, _, SA, _ = _layout(N, NS)
    SB, SF = SA + STACK, SA + 2 * STACK
    top = 1
    w[SA], w[SB], w[SF] = 0.0, t_end, 0.0
    nodes = 0
    status0 = 2
    nruns = 0
    reached = -1.0
    in_run = False
    in_lo = in_hi = last_contact = 0.0
    gap_from = -1.0
    gap = False
    last_clear = 0.0
    while top > 0:
        top -= 1
        a, b, forced = w[SA + top], w[SB + top], w[SF + top]
        nodes += 1
        if forced > 0.0 or nodes > MAX_NODES:
            code = 0
        else:
            code = _classify(w, N, NS, mlo, mhi, a, b)
            if code == 2 and (b - a <= LEAF or top + 3 > STACK):
                code = 0
        if code == 2:
            va, vb = _value(w, 0, N, a), _value(w, 0, N, b)
            split = False
            if (va > 0.0 and vb < 0.0) or (va < 0.0 and vb > 0.0):
                # split around the computed f's zero: a band as wide as the rounding allows, proven pieces beside it
                r = _root_between(w, 0, N, a, b)
                _, slope = _value_slope(w, 0, N, r)
                width = 4.0 * LEAF
                if slope != 0.0:
                    width += 2.0 * (_value(w, N, N, r) + max(mlo, mhi)) / abs(slope)
                if a + width < r - width and r + width < b - width and 2.0 * width <= 0.25 * (b - a):
                    w[SA + top], w[SB + top], w[SF + top] = r + width, b, 0.0
                    w[SA + top + 1], w[SB + top + 1], w[SF + top + 1] = r - width, r + width, 1.0
                    w[SA + top + 2], w[SB + top + 2], w[SF + top + 2] = a, r - width, 0.0
                    top += 3
                    split = True
            if not split:
                mid = 0.5 * (a + b)
                w[SA + top], w[SB + top], w[SF + top] = mid, b, 0.0
                w[SA + top + 1], w[SB + top + 1], w[SF + top + 1] = a, mid, 0.0
                top += 2
            continue
        # a leaf: its label
        if code == 1:
            sgn = _side_sign(w, N, NS, ms, a, b, False)
            label = CLEAR if sgn > 0 else (CONTACT if sgn < 0 else UNDECIDED)
        elif code == -1:
            label = CONTACT
        else:
            label = CONTACT if _side_sign(w, N, NS, ms, a, b, True) < 0 else UNDECIDED
        if status0 == 2:
            status0 = 1 if label == CLEAR else (-1 if label == CONTACT else 0)
        if label == CLEAR:
            if in_run:
                if nruns == runs.shape[0]:
                    reached = in_lo
                    break
                _close_run(runs, nruns, w, N, in_lo, in_hi, last_contact, a, gap, nruns == 0 and status0 != 1)
                nruns += 1
                in_run = False
            last_clear = b
        elif label == CONTACT:
            if not in_run:
                in_run, in_lo, in_hi, gap, gap_from = True, (0.0 if a == 0.0 else last_clear), a, False, -1.0
            elif in_hi < 0.0:
                in_hi = a
            elif gap_from >= 0.0 and a - gap_from > TIME_TOL:
                gap = True  # an undecided stretch between two contacts: a possible separation
            gap_from = -1.0
            last_contact = b
            if first_only:
                break
        else:
            if not in_run:
                in_run, in_lo, in_hi, gap, gap_from = True, (0.0 if a == 0.0 else last_clear), -1.0, False, a
            elif gap_from < 0.0:
                gap_from = a
    if status0 == 2:
        status0 = 0
    if in_run and reached < 0.0:
        at_start = nruns == 0 and status0 != 1
        if nruns == runs.shape[0]:
            reached = in_lo
        elif first_only and in_hi >= 0.0:
            _close_run(runs, nruns, w, N, in_lo, in_hi, in_hi, in_hi, gap, at_start)
            runs[nruns, 1] = runs[nruns, 0]
            runs[nruns, 4] = runs[nruns, 5] = runs[nruns, 0]
            nruns += 1
        else:  # the run goes on to t_end: it ends there when its last piece is a contact
            _close_run(runs, nruns, w, N, in_lo, in_hi, t_end if gap_from < 0.0 else last_contact, t_end, gap,
                       at_start)
            nruns += 1
    return status0, nruns, reached


@_jit
def verdict(runs, nruns, reached, t_max, first_only):
    """(certified, lo, hi) of a scan: certified when no limit was hit, every run is a proven contact without an
    undecided gap, and every reported time lies within TIME_TOL of both ends of its bracket.  [lo, hi] holds
    every possible first contact ([-1, -1]: none)."""
    certified = reached < 0.0
    first_proven = -1
    for k in range(nruns):
        if runs[k, 6] > 0.0 and first_proven < 0:
            first_proven = k
        if runs[k, 6] == 0.0 or runs[k, 7] > 0.0:
            certified = False
        for end in range(1 if first_only else 2):
            t = runs[k, end]
            if max(t - runs[k, 2 + 2 * end], runs[k, 3 + 2 * end] - t) > TIME_TOL:
                certified = False
    if nruns == 0:
        if reached >= 0.0:
            return False, reached, t_max
        return certified, -1.0, -1.0
    if first_proven >= 0:
        hi = runs[first_proven, 3]
    else:
        hi = runs[nruns - 1, 5] if reached < 0.0 else t_max
    return certified, runs[0, 2], hi


# ---------------------------------------------------------------- two-pose kernels


@_jit
def _support_point(affine, radii, p0, q0, p1, q1, plane, t, w, B, touch):
    """touch[0] = the point of the ellipsoid deepest along -n at time t (world): c - S n / sqrt(n^T S n);
    touch[1] = -n.  Scratch from B on (40 floats)."""
    R, RA, M = B, B + 9, B + 18
    if affine:  # S = Q^-1, Q = lerp of R diag(1/r^2) R^T: solve Q x = n by the adjugate
        for i in range(9):
            w[M + i] = 0.0
        for end in range(2):
            _rotation_abs(q0 if end == 0 else q1, w, R, RA)
            wgt = 1.0 - t if end == 0 else t
            for i in range(3):
                for j in range(3):
                    acc = 0.0
                    for k in range(3):
                        acc += w[R + 3 * i + k] * w[R + 3 * j + k] / (radii[k] * radii[k])
                    w[M + 3 * i + j] += wgt * acc
        a00, a01, a02 = w[M + 4] * w[M + 8] - w[M + 5] * w[M + 7], w[M + 2] * w[M + 7] - w[M + 1] * w[M + 8], \
            w[M + 1] * w[M + 5] - w[M + 2] * w[M + 4]
        a11, a12 = w[M + 0] * w[M + 8] - w[M + 2] * w[M + 6], w[M + 2] * w[M + 3] - w[M + 0] * w[M + 5]
        a22 = w[M + 0] * w[M + 4] - w[M + 1] * w[M + 3]
        det = w[M + 0] * a00 + w[M + 1] * (w[M + 5] * w[M + 6] - w[M + 3] * w[M + 8]) + w[M + 2] * (
            w[M + 3] * w[M + 7] - w[M + 4] * w[M + 6])
        sx = (a00 * plane[0] + a01 * plane[1] + a02 * plane[2]) / det
        sy = (a01 * plane[0] + a11 * plane[1] + a12 * plane[2]) / det
        sz = (a02 * plane[0] + a12 * plane[1] + a22 * plane[2]) / det
    else:
        s = 1.0
        if q0[0] * q1[0] + q0[1] * q1[1] + q0[2] * q1[2] + q0[3] * q1[3] < 0.0:
            s = -1.0
        Q = M + 9
        for m in range(4):
            w[Q + m] = (1.0 - t) * q0[m] + t * s * q1[m]
        _rotation_abs(w[Q:Q + 4], w, R, RA)
        for k in range(3):  # radii^2 times the body-frame components of n
            w[M + k] = radii[k] * radii[k] * (w[R + k] * plane[0] + w[R + 3 + k] * plane[1] + w[R + 6 + k] * plane[2])
        sx = w[R + 0] * w[M] + w[R + 1] * w[M + 1] + w[R + 2] * w[M + 2]
        sy = w[R + 3] * w[M] + w[R + 4] * w[M + 1] + w[R + 5] * w[M + 2]
        sz = w[R + 6] * w[M] + w[R + 7] * w[M + 1] + w[R + 8] * w[M + 2]
    h = math.sqrt(max(plane[0] * sx + plane[1] * sy + plane[2] * sz, 0.0))
    for i, sv in enumerate((sx, sy, sz)):
        c = (1.0 - t) * p0[i] + t * p1[i]
        touch[0, i] = c - (sv / h if h > 0.0 else 0.0)
        touch[1, i] = 0.0 - plane[i]


@_jit
def plane_pair_kernel(affine, radii, p0, q0, p1, q1, plane, t_max, first_only, work, runs, touch):
    """Exact contact of an ellipsoid moving between two poses with a static plane (the half-space below it).

    ``affine`` picks the motion (False: rigid, centre and quaternion lerp;
    True: centre and shape-matrix lerp); ``radii`` (3,), ``p0``/``p1`` (3,),
    unit ``q0``/``q1`` (4,) [w, x, y, z] (q1 of either sign), ``plane`` (4,)
    [nx, ny, nz, offset] with a unit normal; over [0, t_max].  ``work``:
    (PLANE_WORK,) scratch; ``runs``: (R, RUN_FIELDS) output rows (see
    :func:`scan`); ``touch`` (2, 3): the point and normal of the first
    contact (t > 0), or of the bracket's start when the answer is uncertain
    (an estimate), zero when there is none.  Returns (status at start,
    number of runs, certified, bracket lo, bracket hi, reached); see
    :func:`verdict`.  Allocates nothing.
    """
    N = 6 if affine else 7
    F, E, _, _, _, _, S, SE, _, _, _, end = _layout(N, 2)
    L = _scale_of(radii)
    _side_into(p0, p1, plane, L, work, S, SE)
    g = gamma(2 * ROUNDING_DEPTH + 2)
    if affine:
        _affine_into(radii, q0, q1, plane, L, work, S, SE, F, E, end, g)
    else:
        _rigid_into(radii, q0, q1, plane, L, work, S, SE, F, E, end, g)
    for m in range(3):
        touch[0, m] = 0.0
        touch[1, m] = 0.0
    status0, nruns, reached = scan(work, N, 2, 1.0, t_max, first_only, runs)
    certified, blo, bhi = verdict(runs, nruns, reached, t_max, first_only)
    if status0 == 1 and nruns > 0 and runs[0, 6] > 0.0 and runs[0, 3] - runs[0, 2] <= 2.0 * TIME_TOL:
        _support_point(affine, radii, p0, q0, p1, q1, plane, runs[0, 0], work, end, touch)
    elif status0 == 1 and not certified and 0.0 <= blo <= t_max:  # only bracketed: the estimate at its start
        _support_point(affine, radii, p0, q0, p1, q1, plane, blo, work, end, touch)
    return status0, nruns, certified, blo, bhi, reached


@_jit
def plane_first_contact_kernel(affine, radii, p0, q0, p1, q1, plane, t_max, work, touch):
    """First contact of an ellipsoid moving between two poses with a static plane, for batched callers.

    Arguments as :func:`plane_pair_kernel`; ``work`` (PLANE_WORK,) also
    holds the runs.  Returns (status at start: 1 separate, 0 touching or
    undecided, -1 overlapping; time: the first contact, -1 when none is
    possible in [0, t_max], 0 when not separate at the start, the bracket's
    low end when uncertain; time_hi: the bracket's high end (= time when
    certified); certified).  ``touch`` (2, 3) gets the contact point (on the
    ellipsoid, deepest along -n) and the normal -n (outward from the
    ellipsoid, as :class:`mjccd.Contact`), zero when there is none.
    """
    runs = work[RUNS_AT:RUNS_AT + TWO_POSE_RUNS * RUN_FIELDS].reshape((TWO_POSE_RUNS, RUN_FIELDS))
    status0, nruns, certified, blo, bhi, _ = plane_pair_kernel(affine, radii, p0, q0, p1, q1, plane, t_max, True,
                                                               work, runs, touch)
    if status0 != 1:
        return status0, 0.0, (0.0 if certified else bhi), certified
    if certified:
        if nruns == 0:
            return status0, -1.0, -1.0, True
        return status0, runs[0, 0], runs[0, 0], True
    return status0, blo, bhi, False


# ---------------------------------------------------------------- motions given by W (Python layer, numba helpers)


@_jit
def _w_plane_poly(G, h, g, rs, n, dh, Ga, ha, ga):
    """f = a^2 - sum_k b_k^2 and a = -n^T adj(G) h - dh det G with b_k = g rs_k (adj(G)^T n)_k, and both programs
    on absolute values (``Ga``, ``ha``, ``ga``: the inputs' absolute values, possibly inflated by their errors)."""
    adj, det = bz.adjugate3(G)
    # absolute program of the adjugate and determinant
    m = G.shape[2]
    adja = np.empty((3, 3, 2 * m - 1))
    for i in range(3):
        for j in range(3):
            r0, r1 = (1 if j == 0 else 0), (1 if j == 2 else 2)
            c0, c1 = (1 if i == 0 else 0), (1 if i == 2 else 2)
            bz.copy_into(adja[i, j], bz.multiply(Ga[r0, c0].copy(), Ga[r1, c1].copy())
                         + bz.multiply(Ga[r0, c1].copy(), Ga[r1, c0].copy()))
    deta = bz.add(bz.add(bz.multiply(Ga[0, 0].copy(), adja[0, 0].copy()),
                         bz.multiply(Ga[0, 1].copy(), adja[1, 0].copy())),
                  bz.multiply(Ga[0, 2].copy(), adja[2, 0].copy()))
    a = -dh * det
    aa = abs(dh) * deta
    for i in range(3):
        for j in range(3):
            prod = bz.multiply(adj[i, j].copy(), h[j].copy())
            proda = bz.multiply(adja[i, j].copy(), ha[j].copy())
            a = bz.add(a, -n[i] * prod)
            aa = bz.add(aa, abs(n[i]) * proda)
    f = bz.multiply(a.copy(), a.copy())
    fa = bz.multiply(aa.copy(), aa.copy())
    for k in range(3):
        col = n[0] * adj[0, k] + n[1] * adj[1, k] + n[2] * adj[2, k]
        cola = abs(n[0]) * adja[0, k] + abs(n[1]) * adja[1, k] + abs(n[2]) * adja[2, k]
        b = rs[k] * bz.multiply(g.copy(), col)
        ba = rs[k] * bz.multiply(ga.copy(), cola)
        f = bz.add(f, -bz.multiply(b.copy(), b.copy()))
        fa = bz.add(fa, bz.multiply(ba.copy(), ba.copy()))
    return f, fa, a, aa


def _restrict_rows(c, t0, t1):
    flat = np.ascontiguousarray(c).reshape(-1, c.shape[-1])
    out = np.empty_like(flat)
    for k in range(flat.shape[0]):
        out[k] = bz.restrict(flat[k].copy(), t0, t1)
    return out.reshape(c.shape)


def _w_piece(W, radii, n, d_local, t0, t1):
    """(f, e, side, side_err) of a W motion on [t0, t1], in units of L (a power of two): e and side_err bound the
    errors of the coefficients (the restriction of W to the piece included)."""
    G, h, g = W
    L = float(_scale_of(radii))
    rs = radii / L
    whole = t0 == 0.0 and t1 == 1.0
    if not whole:
        G, h, g = _restrict_rows(G, t0, t1), _restrict_rows(h, t0, t1), bz.restrict(g.copy(), t0, t1)
    h = np.ascontiguousarray(h / L)
    G, g = np.ascontiguousarray(G), np.ascontiguousarray(g)
    dh = d_local / L
    Ga, ha, ga = np.abs(G), np.abs(h), np.abs(g)
    f, fa, a, aa = _w_plane_poly(G, h, g, rs, n, dh, Ga, ha, ga)
    deg = max(G.shape[2], h.shape[1], g.shape[0]) - 1
    depth = 8 * (f.shape[0] + deg) + 64
    extra_f = np.zeros_like(f)
    extra_a = np.zeros_like(a)
    if not whole:  # the restricted W carries the rounding of the restriction: inflate the inputs by it
        rho = gamma(2 * deg + 4)
        _, fi, _, ai = _w_plane_poly(G, h, g, rs, n, dh, Ga + rho * np.abs(G).max(), ha + rho * np.abs(h).max(),
                                     ga + rho * np.abs(g).max())
        extra_f, extra_a = fi - fa, ai - aa
        fa, aa = fi, ai
    e = gamma(2 * depth) * fa + extra_f * (1.0 + 1e-9)
    side_err = gamma(2 * depth) * aa + extra_a * (1.0 + 1e-9)
    return f, e, a, side_err


def _scan_python(f, e, side, side_err, t_end, first_only):
    """:func:`scan` of f (with its error bounds e) and sigma (with side_err), in scratch sized for them."""
    N, NS = len(f), len(side)
    w = np.empty(scan_size(N, NS))
    w[0:N], w[N:2 * N] = f, e
    w[6 * N:6 * N + NS], w[6 * N + NS:6 * N + 2 * NS] = side, side_err
    runs = np.empty((N + 16, RUN_FIELDS))
    status0, nruns, reached = scan(w, N, NS, 1.0, t_end, first_only, runs)
    return int(status0), runs[:nruns].copy(), float(reached)


# ---------------------------------------------------------------- exact status (rational arithmetic)


def _exact_parts(A, n, d):
    """(D, Y, Z, sigma_D, rho_D, nY) of the quadric A = [[P, U], [U^T, s]] (Fractions, up to a factor > 0) and the
    plane n . x = d: D = det P > 0, Y = adj(P) n, Z = adj(P) U, and

        sigma_D = D (n . c - d) = -n . Z - d D,   rho_D = D rho = U . Z - s D,   nY = D n^T P^-1 n,

    with c = -P^-1 U the centre and rho = U^T P^-1 U - s; the squared support along n is rho n^T P^-1 n.
    """
    P = [[A[i][j] for j in range(3)] for i in range(3)]
    U = [A[i][3] for i in range(3)]
    s = A[3][3]
    adj = [[P[(j + 1) % 3][(i + 1) % 3] * P[(j + 2) % 3][(i + 2) % 3]
            - P[(j + 1) % 3][(i + 2) % 3] * P[(j + 2) % 3][(i + 1) % 3] for j in range(3)] for i in range(3)]
    D = sum(P[0][k] * adj[k][0] for k in range(3))
    Y = [sum(adj[i][k] * n[k] for k in range(3)) for i in range(3)]
    Z = [sum(adj[i][k] * U[k] for k in range(3)) for i in range(3)]
    sigma_D = -sum(n[i] * Z[i] for i in range(3)) - d * D
    rho_D = sum(U[i] * Z[i] for i in range(3)) - s * D
    return D, Y, Z, sigma_D, rho_D, sum(n[i] * Y[i] for i in range(3))


def exact_plane_status(A, n, d):
    """Exact status of the ellipsoid ``X^T A X <= 0`` (4x4 Fractions, up to a positive factor) against the
    half-space ``n . x <= d`` (n, d Fractions): 1 clear of it, 0 touching its plane from above, -1 in contact
    otherwise (cutting the plane, or below it).

    (n . c - d)^2 against the squared support, both times D^2 > 0:
    ``sigma_D^2`` against ``rho_D nY`` (see :func:`_exact_parts`); no division.
    """
    _, _, _, sigma_D, rho_D, nY = _exact_parts(A, n, d)
    if sigma_D <= 0:
        return -1
    lhs = sigma_D * sigma_D
    rhs = rho_D * nY
    return 1 if lhs > rhs else (0 if lhs == rhs else -1)


def exact_support_point(A, n):
    """The point of the ellipsoid ``X^T A X <= 0`` deepest along -n, c - sqrt(rho / n^T P^-1 n) P^-1 n, from the
    exact quadric (Fractions or integers, up to a positive factor), rounded once per term: accurate far from the
    origin too.  Each term is formed from quantities the factor does not change (rho / n^T P^-1 n alone grows
    with its square)."""
    nf = [Fraction(float(x)) for x in n]
    D, Y, Z, _, rho_D, nY = _exact_parts(A, nf, Fraction(0))
    ratio = max(Fraction(rho_D) / nY, Fraction(0))
    offsets = [math.sqrt(float(ratio * (Fraction(Y[i]) / D) ** 2)) for i in range(3)]
    return np.array([float(Fraction(-Z[i]) / D) - (offsets[i] if Y[i] * D >= 0 else -offsets[i]) for i in range(3)])


def _simplest_dyadic(lo, hi):
    """The dyadic rational m / 2^k in (lo, hi] with the smallest k (constructed tangencies lie at such times)."""
    for k in range(0, 64):
        m = math.floor(lo * 2.0 ** k) + 1
        t = m / 2.0 ** k
        if lo < t <= hi:
            return t
    return hi


class _ExactPlane:
    """A moving ellipsoid and a plane, for decisions in rational arithmetic at dyadic times."""

    def __init__(self, radii, motion, n, d):
        self.radii, self.motion = radii, motion
        self.n = [Fraction(float(x)) for x in n]
        self.d = Fraction(float(d))
        self.nf = np.asarray(n, float)

    def status(self, t):
        return exact_plane_status(self.motion.exact_quadric_at(self.radii, Fraction(t)), self.n, self.d)

    def change(self, lo, hi, clear_at_lo):
        """Bisection on dyadic times for where the status changes to (``clear_at_lo``) or from clear in (lo, hi]:
        (time as a float, the final bracket as floats), or None when the ends do not differ as expected."""
        lo, hi = Fraction(lo), Fraction(hi)
        if (self.status(lo) == 1) != clear_at_lo or (self.status(hi) == 1) == clear_at_lo:
            return None
        while hi - lo > Fraction(2) ** -EXACT_BITS * max(hi, Fraction(2) ** -1000):
            mid = (lo + hi) / 2
            if (self.status(mid) == 1) == clear_at_lo:
                lo = mid
            else:
                hi = mid
        return (float(hi) if clear_at_lo else float(lo)), (float(lo), float(hi))

    def first_contact_in(self, lo, hi, *estimates):
        """The earliest of the estimates, of times lo + (hi - lo) 2^-k and of even samples in (lo, hi] at which
        the body is not clear (exactly), or None."""
        times = {float(t) for t in estimates if lo < t <= hi} | {_simplest_dyadic(lo, hi)}
        times |= {lo + (hi - lo) * k / EXACT_SAMPLES for k in range(1, EXACT_SAMPLES + 1)}
        times |= {lo + (hi - lo) * 2.0 ** -k for k in range(1, 64)}
        for t in sorted(t for t in times if lo < t <= hi):
            if self.status(t) != 1:
                return t
        return None

    def point(self, t):
        return exact_support_point(self.motion.exact_quadric_at(self.radii, Fraction(t)), self.nf)


# ---------------------------------------------------------------- Python layer


def _radii_of(ellipsoid):
    if isinstance(ellipsoid, Ellipsoid):
        return ellipsoid.radii
    return Ellipsoid(ellipsoid).radii


def _plane_of(plane):
    if isinstance(plane, Plane):
        return plane
    row = _validate.vector(plane, 4, "plane")
    try:
        return Plane(row[:3], row[3])
    except InputError as err:
        raise InputError(f"plane.{err}") from None


def _motion_of(motion):
    if not isinstance(motion, Motion):
        raise InputTypeError(f"motion: expected an mjccd motion, got {type(motion).__name__}")
    return motion


def _two_pose(motion):
    """(affine?, p0, q0, p1, q1) of a Static, Rigid or Affine motion, else None."""
    if type(motion) is Static:
        return False, motion.position, motion.quaternion, motion.position, motion.quaternion
    if type(motion) in (Rigid, Affine):
        return type(motion) is Affine, motion.position0, motion.quaternion0, motion.position1, motion.quaternion1
    return None


def _keeps_its_height(pose, plane):
    """True when a two-pose motion keeps its orientation exactly and its centre moves exactly parallel to the
    plane (a body at rest, or sliding along it): its status then holds for the whole step."""
    _, p0, q0, p1, q1 = pose
    if not (np.array_equal(q0, q1) or np.array_equal(q0, -q1)):
        return False
    n = [Fraction(float(x)) for x in plane.normal]
    return sum(n[i] * (Fraction(float(p1[i])) - Fraction(float(p0[i]))) for i in range(3)) == 0


def _solve_two_pose(radii, pose, plane, t_max, first_only):
    affine, p0, q0, p1, q1 = pose
    runs = np.empty((TWO_POSE_RUNS, RUN_FIELDS))
    touch = np.zeros((2, 3))
    status0, nruns, _, _, _, reached = plane_pair_kernel(affine, radii, p0, q0, p1, q1, plane.as_array(), t_max,
                                                        first_only, np.empty(PLANE_WORK), runs, touch)
    point = touch[0].copy() if touch[1].any() else None
    return int(status0), runs[:nruns].copy(), float(reached), point


def _solve_w(radii, motion, plane, t_max, first_only):
    """The W path: the motion in a local frame at its anchor, f built and scanned piece by piece."""
    W = motion.scaled_inverse_w()
    if W is None:
        raise InputTypeError(f"motion: {type(motion).__name__} is not supported against planes "
                             "(it gives neither two poses nor a scaled inverse)")
    origin = np.asarray(motion.anchor(), float)
    local = motion.translated(origin)
    d_local = plane.offset - float(plane.normal @ origin)
    W = local.scaled_inverse_w()
    det0 = _exact_det3(W[0][:, :, 0])
    if det0 == 0:
        raise InputError("motion: its linear part is singular at t = 0")
    sign = 1.0 if det0 > 0 else -1.0
    status0 = None
    rows = []
    reached = -1.0
    edges = time_pieces([W[2]], t_max)  # pieces of [0, t_max] on which g varies at most 2x
    for t0, t1 in zip(edges[:-1], edges[1:]):
        f, e, a, a_err = _w_piece(W, radii, plane.normal, d_local, t0, t1)
        code, runs, piece_reached = _scan_python(f, e, sign * a, a_err, 1.0,
                                                 first_only and not any(r[6] > 0.0 for r in rows))
        if status0 is None:
            status0 = code
        width = t1 - t0
        for run in runs:
            run = run.copy()
            run[:6] = t0 + run[:6] * width
            if rows and rows[-1][5] >= t0 - 1e-15 and run[2] <= t0 + 1e-15:  # a run across the piece edge
                last = rows[-1]
                if last[6] == 0.0 and run[6] > 0.0:
                    last[0], last[3] = run[0], run[3]
                last[1], last[4], last[5] = run[1], run[4], run[5]
                last[6] = max(last[6], run[6])
                last[7] = max(last[7], run[7])
                continue
            rows.append(run)
        if piece_reached >= 0.0:
            reached = t0 + piece_reached * width
            break
        if first_only and any(r[6] > 0.0 for r in rows):
            break
    runs = np.array(rows, float).reshape(-1, RUN_FIELDS)
    if first_only and len(runs):
        k = next((i for i in range(len(runs)) if runs[i, 6] > 0.0), len(runs) - 1)
        runs = runs[:k + 1]
        runs[k, 1] = runs[k, 0]
        runs[k, 4] = runs[k, 5] = runs[k, 0]
    return status0, runs, reached, local, d_local, origin


def _exact_det3(M):
    F = [[Fraction(float(x)) for x in row] for row in M]
    return (F[0][0] * (F[1][1] * F[2][2] - F[1][2] * F[2][1]) - F[0][1] * (F[1][0] * F[2][2] - F[1][2] * F[2][0])
            + F[0][2] * (F[1][0] * F[2][1] - F[1][1] * F[2][0]))


def _certify(runs, reached, t_max, first_only):
    certified, lo, hi = verdict(runs, len(runs), reached, t_max, first_only)
    return bool(certified), (float(lo), float(hi))


def _refine(exact, status0, runs, first_only):
    """Events whose proven bracket is wider than TIME_TOL, runs not proven, and an undecided start, settled on the
    exact status at dyadic times.  Returns (status at start, runs); runs that stay unproven keep their flags."""
    runs = runs.copy()
    settle_start = False  # undecided at t = 0 but exactly clear: the first run's entry is searched from 0
    if status0 == 0:
        status0 = exact.status(0.0)
        settle_start = status0 == 1
        if status0 != 1 and len(runs):
            runs[0, 0], runs[0, 2], runs[0, 3] = 0.0, 0.0, 0.0
            runs[0, 6] = 1.0
            if first_only:
                runs[0, 1] = runs[0, 4] = runs[0, 5] = 0.0
    for k in range(len(runs)):
        at_start = k == 0 and status0 != 1
        if runs[k, 6] == 0.0:  # nothing proven: look for a time the body is not clear
            probe = exact.first_contact_in(runs[k, 2], runs[k, 5], runs[k, 0])
            if probe is None:
                continue
            runs[k, 6] = 1.0
            runs[k, 3] = probe
            if not first_only:
                runs[k, 4] = probe
        wide = max(runs[k, 0] - runs[k, 2], runs[k, 3] - runs[k, 0]) > TIME_TOL
        if not at_start and (wide or (k == 0 and settle_start)):
            found = exact.change(runs[k, 2], runs[k, 3], True)
            if found is not None:
                runs[k, 0], (runs[k, 2], runs[k, 3]) = found[0], found[1]
        if first_only:
            runs[k, 1] = runs[k, 0]
            runs[k, 4] = runs[k, 5] = runs[k, 0]
            if runs[k, 6] > 0.0:
                return status0, runs[:k + 1]
            continue
        if max(runs[k, 1] - runs[k, 4], runs[k, 5] - runs[k, 1]) > TIME_TOL:
            lo = max(runs[k, 4], runs[k, 3])
            found = exact.change(lo, runs[k, 5], False)
            if found is None and exact.status(runs[k, 5]) != 1:
                runs[k, 1] = runs[k, 5]  # in contact at the end of the scan: no exit before it is proven
                continue
            if found is not None:
                runs[k, 1], (runs[k, 4], runs[k, 5]) = found[0], found[1]
    return status0, runs


def solve_plane(ellipsoid, motion, plane, *, t_max=1.0, first_only=False):
    """Everything known about a moving ellipsoid against a static plane over [0, t_max], as a
    :class:`mjccd.ccd.PairSolution`.

    ``status_at_start`` 1 (clear of the half-space), 0 (touching the plane from
    above), -1 (in contact: cutting the plane or below it); ``intervals``
    (k, 2) the maximal times in [0, t_max] at which the body touches or
    penetrates the half-space; ``point`` the point of first contact (the
    ellipsoid's deepest point along -n, world) and ``normal`` = -n (unit,
    outward from the ellipsoid, as for pairs), None when the body is not
    clear at t = 0 or when the first contact is not certified; ``certified``
    False when double precision and the rational tier could not decide (then
    ``bracket`` holds every possible first contact); ``bounds`` (k, 4) the
    proven brackets [in_lo, in_hi, out_lo, out_hi]; ``precision`` 0 (double)
    or 2 (rational).  ``first_only``: stop at the first contact (its interval
    is then [t, t]).

    Args:
        ellipsoid: an :class:`mjccd.Ellipsoid` or its radii (3,).
        motion: any :class:`mjccd.Motion` (Static, Rigid, Affine,
            LinearAffine, Rational, Chain).
        plane: a :class:`Plane` or a row [nx, ny, nz, offset].
    """
    radii = _radii_of(ellipsoid)
    motion = _motion_of(motion)
    plane = _plane_of(plane)
    t_max = _validate.time_bound(t_max, "t_max")
    pose = _two_pose(motion)
    point = None
    if pose is not None and _keeps_its_height(pose, plane):
        status0 = _ExactPlane(radii, motion, plane.normal, plane.offset).status(0.0)
        runs = np.array([[0.0, 0.0 if first_only else t_max, 0.0, 0.0, 0.0 if first_only else t_max,
                          0.0 if first_only else t_max, 1.0, 0.0]]) if status0 != 1 else np.empty((0, RUN_FIELDS))
        return PairSolution(int(status0), np.ascontiguousarray(runs[:, :2]), None, None, True,
                            (0.0, 0.0) if len(runs) else (-1.0, -1.0), np.ascontiguousarray(runs[:, 2:6]), -1.0, 2)
    if pose is not None:
        status0, runs, reached, point = _solve_two_pose(radii, pose, plane, t_max, first_only)
        local, d_local, origin = motion, plane.offset, np.zeros(3)
    else:
        status0, runs, reached, local, d_local, origin = _solve_w(radii, motion, plane, t_max, first_only)
    certified, bracket = _certify(runs, reached, t_max, first_only)
    precision = 0
    first_time = runs[0, 0] if len(runs) else None
    if (status0 == 0 or not certified) and reached < 0.0:
        exact = _ExactPlane(radii, local, plane.normal, d_local)
        status0, runs = _refine(exact, status0, runs, first_only)
        certified, bracket = _certify(runs, reached, t_max, first_only)
        precision = 2
        if len(runs) and runs[0, 0] != first_time:
            point = None
    touch = status0 == 1 and len(runs) > 0 and runs[0, 6] > 0.0 and runs[0, 3] - runs[0, 2] <= 2.0 * TIME_TOL
    if touch and point is None and pose is None:  # the frame map at t, in the local frame (small coordinates)
        frame = local.transform(float(runs[0, 0]))
        L, centre = frame[:, :3], frame[:, 3]
        Sn = L @ (radii ** 2 * (L.T @ plane.normal))
        point = origin + centre - Sn / math.sqrt(float(plane.normal @ Sn))
    if touch and point is None:
        point = origin + exact_support_point(local.exact_quadric_at(radii, Fraction(float(runs[0, 0]))),
                                             plane.normal)
    if not touch:
        point = None
    normal = (0.0 - plane.normal) if point is not None else None
    return PairSolution(int(status0), np.ascontiguousarray(runs[:, :2]), point, normal, certified, bracket,
                        np.ascontiguousarray(runs[:, 2:6]), float(reached), precision)


def _contact(solution):
    """A :class:`mjccd.Contact` of a plane solution (None when certified clear), as for pairs; an uncertain
    answer has ``time`` = the bracket's low end."""
    status = STATUS_NAMES[solution.status_at_start]
    if solution.status_at_start != 1:
        if solution.certified or len(solution.intervals) == 0 or solution.bounds[0, 1] == 0.0:
            return Contact(0.0, None, None, status)
        return Contact(0.0, None, None, status, "uncertain", (0.0, float(solution.bracket[1])))
    if solution.certified:
        if len(solution.intervals) == 0:
            return None
        return Contact(float(solution.intervals[0, 0]), solution.point, solution.normal, status)
    lo, hi = solution.bracket
    return Contact(lo, solution.point if lo == hi else None, solution.normal if lo == hi else None, status,
                   "uncertain", (lo, hi))


def plane_first_contact(ellipsoid, motion, plane, *, t_max=1.0):
    """First time in [0, t_max] at which a moving ellipsoid touches or enters the half-space below a static plane.

    Returns a :class:`mjccd.Contact` (``time``, ``point`` on the ellipsoid,
    ``normal`` = -plane normal, outward from the ellipsoid; ``status_at_start``
    "separate", "touching" or "overlapping"; ``certainty``, and ``bracket``
    when uncertain, as for pairs), or None when the body is certified clear
    of the half-space over [0, t_max].  An uncertain answer is a possible
    contact at ``time`` (the bracket's low end), never "no contact".
    """
    return _contact(solve_plane(ellipsoid, motion, plane, t_max=t_max, first_only=True))


def plane_collision_intervals(ellipsoid, motion, plane):
    """Maximal time intervals [t_in, t_out] within [0, 1] where the ellipsoid touches or penetrates the half-space.

    As :func:`mjccd.collision_intervals`: the estimates only; :func:`solve_plane`
    gives their proven brackets and whether the answer is certified (a graze
    the rounding cannot resolve is listed as a possible contact [t, t]).
    """
    return [(float(x), float(y)) for x, y in solve_plane(ellipsoid, motion, plane).intervals]
