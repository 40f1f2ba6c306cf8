"""Elliptic disks moving in the plane (Choi 2008, chapter 2): the certified first contact and every contact.

An elliptic disk is ``Ellipse(a, b)``: ``x²/a² + y²/b² <= 1`` in its own frame.
A *planar motion* is a 3x3 homogeneous matrix ``M(t)`` whose entries are
polynomials in t (power basis, lowest degree first, as the thesis writes M_A
and M_B), ``M = [[L(t), v(t)], [0, 0, w(t)]]``: the point y of the disk is at
``(L y + v) / w`` at time t.  A rigid rational motion has ``L / w`` a rotation
(the thesis' kinematic image, eq. 2.3, gives one: :meth:`PlanarMotion.
from_kinematic_image`); any other nonsingular L is an affine motion, which
deforms the disk into other ellipses.  Entries are taken exactly (floats,
ints and :class:`fractions.Fraction`).

**Refusal rule.**  A motion is accepted when ``w(t)`` and ``det L(t)`` have no
real root in [0, 1], decided exactly (rational arithmetic, Sturm's theorem):
then the map is an invertible affine map at every time of [0, 1].  Every
other matrix (and one whose last row is not ``[0, 0, w]``) is refused with an
:class:`mjccd.errors.InputError` naming the entry.

**Formulation.**  Rather than the thesis' discriminant (whose zeros also mark
internal tangencies and complex touches, and must be sorted afterwards), the
contact is the first time one of these *systems* holds:

1. and 2. *a point of B's boundary lies in A*: B's boundary is the rational
   quadratic ``(a(1 - σ²), 2bσ) / (1 + σ²)`` over two charts (σ = 2s - 1 on
   the half x >= 0, and its mirror image), as
   :func:`mjccd.geoms.systems.circle_rows` writes a circle.  Its points are
   taken into A's frame through the inverse of A's motion by the adjugate,
   ``adj(M_A) M_B = [[w_A adj(L_A) L_B, adj(L_A)(w_A v_B - w_B v_A)], [0, 0,
   det(L_A) w_B]]``, a polynomial homogeneous point (X, Y, Z) of degree 2 in
   s, and A's quadric ``X²/a_A² + Y²/b_A² - Z² <= 0`` is one bivariate
   constraint in (s, t);
3. *A's centre lies in B*: A's centre ``adj(M_B) M_A [0, 0, 1]`` in B's
   quadric, univariate.

Each system is **genuine**: the weight Z = det(L_A) w_B never vanishes (the
refusal rule), so the constraint is A's quadric at the Cartesian point times
Z² > 0, and a proof that it holds at (s, t) is a proof that a point of B (on
its boundary) lies in A, or A's centre in B: a common point.  They are
**complete**: when the disks share a point at time t, either B's boundary
meets A, or it does not, and then A (connected, meeting B, missing B's
boundary) lies inside B's interior, centre included.  So the first contact is
the first time any system holds, and every interval of contact is the union
of the systems' intervals.  From separation the first contact is a touch of
the two boundaries, found by systems 1 and 2.

The systems are built in a :mod:`mjccd.geoms.poly` workspace from the exact
Bernstein coefficients of the inputs (converted in rational arithmetic,
rounded to double or double-double with the bound of that rounding), scanned
by :func:`mjccd.geoms.scan.first_time` and :func:`mjccd.geoms.scan.bfirst_time`,
and rebuilt in double-double when doubles leave the first
contact in a bracket wider than ``TIME_TOL`` (1e-9), as
:func:`mjccd.geoms.kernel.pair_kernel` does.  Both motions are first seen from
A's centre at t = 0 (the shift applied exactly), so a pair far from the origin
loses nothing.  A bracket still wider is *zoomed* into (:func:`_window_scan`):
each system is rebuilt on the bracket's window of time (the motions
reparametrised exactly) and on windows of s that are halved while undecided,
so that its coefficients, and its error bounds, are as small as the constraint
is there.  A graze, which touches without any strict inequality, is finally
tried in rational arithmetic at the simplest dyadic time of a narrow bracket
(:func:`_exact_touch`: the thesis' Example 2.2 touches at t = 1/2).  The
intervals of :func:`ellipse_collision_intervals` come from the systems' runs
(:func:`~mjccd.geoms.scan.ball_runs`, :func:`~mjccd.geoms.scan.all_runs`), each
end left uncertain refined by the same window scans (read backwards for an
end).  The contact point is B's boundary point that goes deepest into A at the
contact time (a 1-d Newton refinement of the scan's witness), the normal A's
outward normal there.

**Trigonometric motions** (the thesis' cycloidal motions, Example 2.1: a
rotation by an angle linear in t and a linear translation,
:class:`CycloidalMotion`) are not rational.  They are answered through proven
rational approximations: on pieces of time, cos and sin of the angle are
replaced by Taylor polynomials whose error is bounded rigorously (interval
arithmetic, mpmath.iv) by η; the true disk then lies in the approximate disk
grown by ``1 + √2 η ρ / ((1 - √2 η) m)`` and contains the approximate disk
shrunk by ``1 / (1 + √2 η ρ / m)`` (ρ, m the largest and smallest semi-axes).
The first contact of the grown pair is a proven lower bound of the true one
and the first contact of the shrunk pair a proven upper bound; the answer is
certified when they agree within TIME_TOL (1.4e-12 apart for Example 2.1).
"""
import heapq
import math
import threading
from fractions import Fraction

import numpy as np

from mjccd import _validate
from mjccd.ccd import Contact
from mjccd.errors import InputError, InputTypeError
from mjccd.geoms import exact as X
from mjccd.geoms import kernel as kn
from mjccd.geoms import poly as P
from mjccd.geoms import scan as sc
from mjccd.geoms import systems as sy
from mjccd.geoms.poly import jit

TIME_TOL = kn.TIME_TOL
STATUS_NAMES = {1: "separate", 0: "touching", -1: "overlapping"}
MAX_MOTION_DEGREE = P.MAX_DEGREE  # degree of the contact polynomials in t, which the workspace bounds
SLOTS = 4096
NM = 7                            # the polynomials of a motion: L00, L01, L10, L11, v0, v1, w
OUTP = kn.OUT + 2                 # the kernel's answer, the witness s, its system's kind
S_BEST, KIND = kn.OUT, kn.OUT + 1
CHART0, CHART1, CENTRE = 0, 1, 2  # kinds of the planar systems
ZOOM_BOXES = 600                  # boxes a window scan examines (a window left undecided is split instead)


# ---------------------------------------------------------------- shapes and motions


def semi_axis(value, field):
    """A semi-axis, checked: a finite length in the accepted range."""
    x = _validate.scalar(value, field)
    lo, hi = _validate.LENGTH_RANGE
    if not lo <= x <= hi:
        raise InputError(f"{field}: a semi-axis must lie in [{lo:g}, {hi:g}], got {x!r}")
    return x


class Ellipse:
    """The elliptic disk ``x²/a² + y²/b² <= 1`` (semi-axes a along the local x axis, b along y)."""

    __slots__ = ("a", "b")

    def __init__(self, a, b):
        self.a = semi_axis(a, "a")
        self.b = semi_axis(b, "b")

    def __repr__(self):
        return f"Ellipse({self.a!r}, {self.b!r})"


class PlanarMotion:
    """A rational planar motion: the 3x3 homogeneous matrix ``[[L(t), v(t)], [0, 0, w(t)]]`` of polynomials.

    ``matrix[i][j]`` is a number or a list of power-basis coefficients
    (lowest degree first).  Refused (InputError) unless the last row is
    ``[0, 0, w]`` with w and det L free of roots on [0, 1] (decided exactly).
    """

    __slots__ = ("entries", "degree")

    def __init__(self, matrix, *, field="matrix"):
        if isinstance(matrix, PlanarMotion):
            self.entries, self.degree = matrix.entries, matrix.degree
            return
        rows = np.asarray(matrix, dtype=object) if not isinstance(matrix, (list, tuple)) else matrix
        if len(rows) != 3 or any(not isinstance(r, (list, tuple, np.ndarray)) or len(r) != 3 for r in rows):
            raise InputError(f"{field}: expected a 3x3 matrix of polynomials")
        e = [[X.poly_of(rows[i][j], f"{field}[{i}][{j}]") for j in range(3)] for i in range(3)]
        for j in range(2):
            if any(e[2][j]):
                raise InputError(f"{field}[2][{j}]: the last row must be [0, 0, w(t)]")
        self.entries = tuple(tuple(tuple(p) for p in row) for row in e)
        self.degree = max(len(p) - 1 for row in e for p in row)
        if not any(e[2][2]) or X.has_root_in_01(e[2][2]):
            raise InputError(f"{field}[2][2]: w(t) vanishes at some t in [0, 1]")
        det = X.add(X.mul(e[0][0], e[1][1]), X.mul(e[0][1], e[1][0]), -1)
        if not any(det) or X.has_root_in_01(det):
            raise InputError(f"{field}: the linear part [[{field}[0][0], {field}[0][1]], [{field}[1][0], "
                             f"{field}[1][1]]] is singular at some t in [0, 1]")

    @classmethod
    def from_kinematic_image(cls, d0, d1, d2, d3):
        """The rigid rational motion of the kinematic image d(t) (thesis eq. 2.3): polynomials d0..d3 (power
        basis), products formed exactly."""
        d = [X.poly_of(x, f"d{i}") for i, x in enumerate((d0, d1, d2, d3))]
        sq2, sq3, c23 = X.mul(d[2], d[2]), X.mul(d[3], d[3]), X.mul(d[2], d[3])
        diag = X.add(sq2, sq3, -1)
        return cls([[diag, X.scale(c23, 2), X.scale(X.add(X.mul(d[0], d[3]), X.mul(d[1], d[2]), -1), 2)],
                    [X.scale(c23, -2), diag, X.scale(X.add(X.mul(d[0], d[2]), X.mul(d[1], d[3])), 2)],
                    [[0], [0], X.add(sq2, sq3)]])

    def translated(self, offset):
        """The same motion followed by the translation ``offset`` (exact)."""
        o = [X.number(x, f"offset[{i}]") for i, x in enumerate(offset)]
        e = [list(r) for r in self.entries]
        for i in range(2):
            e[i][2] = X.add(e[i][2], X.scale(e[2][2], o[i]))
        return PlanarMotion(e)

    def at(self, t):
        """The matrix at time t (floats)."""
        t = Fraction(float(t))
        return np.array([[float(X.value(p, t)) for p in row] for row in self.entries])

    def reparametrized(self, t0, h):
        """The motion on [t0, t0 + h] as a motion in tau = (t - t0) / h (exact)."""
        out = object.__new__(PlanarMotion)
        out.entries = tuple(tuple(tuple(X.taylor_shift(list(p), Fraction(t0), Fraction(h))) for p in row)
                            for row in self.entries)
        out.degree = self.degree
        return out

    def _polys(self, origin=(0, 0)):
        """L00, L01, L10, L11, v0 - o0 w, v1 - o1 w, w."""
        e = self.entries
        w = list(e[2][2])
        return [list(e[0][0]), list(e[0][1]), list(e[1][0]), list(e[1][1]),
                X.add(list(e[0][2]), X.scale(w, Fraction(origin[0])), -1),
                X.add(list(e[1][2]), X.scale(w, Fraction(origin[1])), -1), w]

    def __repr__(self):
        return f"PlanarMotion(degree {self.degree})"


def _unchecked(e):
    """A PlanarMotion of exact entries known to be valid (no Sturm test)."""
    out = object.__new__(PlanarMotion)
    out.entries = tuple(tuple(tuple(p) for p in row) for row in e)
    out.degree = max(len(p) - 1 for row in e for p in row)
    return out


class CycloidalMotion:
    """A rotation by an angle linear in t about the disk's centre, which moves linearly (thesis §2.4):
    ``x = Rot(angle + angular_velocity t) y + position + velocity t``.  With ``unit="pi"`` the angles are
    multiples of pi (so ``angular_velocity=Fraction(10, 9)`` is the thesis' 10π/9 exactly)."""

    __slots__ = ("angle", "angular_velocity", "position", "velocity", "unit")

    def __init__(self, position, velocity, angle=0.0, angular_velocity=0.0, *, unit="rad"):
        if unit not in ("rad", "pi"):
            raise InputError(f"unit: expected 'rad' or 'pi', got {unit!r}")
        self.position = tuple(X.number(x, f"position[{i}]") for i, x in enumerate(_pair(position, "position")))
        self.velocity = tuple(X.number(x, f"velocity[{i}]") for i, x in enumerate(_pair(velocity, "velocity")))
        self.angle = X.number(angle, "angle")
        self.angular_velocity = X.number(angular_velocity, "angular_velocity")
        self.unit = unit

    def _theta(self, t):
        th = float(self.angle) + float(self.angular_velocity) * t
        return th * math.pi if self.unit == "pi" else th

    def at(self, t):
        th = self._theta(float(t))
        c, s = math.cos(th), math.sin(th)
        return np.array([[c, -s, float(self.position[0]) + float(self.velocity[0]) * t],
                         [s, c, float(self.position[1]) + float(self.velocity[1]) * t], [0.0, 0.0, 1.0]])

    def approximation(self, t0, h, degree):
        """(PlanarMotion in tau on [t0, t0 + h], eta): cos and sin of the angle replaced by their Taylor
        polynomials of the given degree about the piece's middle, with coefficients enclosed in interval
        arithmetic (mpmath.iv); eta is a proven bound of both errors on the piece: the coefficients' enclosure
        radii weighted by |tau - 1/2|^k <= 2^-k, plus Lagrange's remainder |gamma|^(n+1) / ((n+1)! 2^(n+1))
        (gamma the angle's change over the piece; every derivative of cos and sin is at most 1)."""
        from mpmath import iv
        prec, iv.prec = iv.prec, 160
        try:
            return self._approximation(iv, Fraction(t0), Fraction(h), degree)
        finally:
            iv.prec = prec

    def _approximation(self, iv, t0, h, degree):

        def ival(x):
            return iv.mpf(x.numerator) / iv.mpf(x.denominator)

        scale = iv.pi if self.unit == "pi" else iv.mpf(1)
        mid = (ival(self.angle) + ival(self.angular_velocity) * (ival(t0) + ival(h) / 2)) * scale
        gam = ival(self.angular_velocity) * ival(h) * scale
        cm, sm = iv.cos(mid), iv.sin(mid)
        derivs = [(cm, sm), (-sm, cm), (-cm, -sm), (sm, -cm)]  # (cos, sin)^(k) at the middle, period 4
        cos_c, sin_c, err = [], [], Fraction(0)
        fact, gk = iv.mpf(1), iv.mpf(1)
        for k in range(degree + 1):
            if k:
                fact *= k
                gk *= gam
            worst = Fraction(0)
            for c, out in ((derivs[k % 4][0] * gk / fact, cos_c), (derivs[k % 4][1] * gk / fact, sin_c)):
                lo, hi = _iv_bounds(c)
                m = (lo + hi) / 2
                out.append(m)
                worst = max(worst, hi - m)
            err += worst / 2 ** k
        _, rem = _iv_bounds(abs(gk * gam) / (fact * (degree + 1)))
        err += rem / 2 ** (degree + 1)
        centred = [Fraction(-1, 2), Fraction(1)]  # tau - 1/2

        def expand(coefs):
            out = [Fraction(0)]
            for c in reversed(coefs):
                out = X.add(X.mul(out, centred), [c])
            return out

        C, S = expand(cos_c), expand(sin_c)
        px = X.trim([self.position[0] + self.velocity[0] * t0, self.velocity[0] * h])
        py = X.trim([self.position[1] + self.velocity[1] * t0, self.velocity[1] * h])
        # C^2 + S^2 >= (1 - sqrt(2) eta)^2 > 0 and w = 1: nonsingular without Sturm's test
        return _unchecked([[C, X.scale(S, -1), px], [S, C, py], [[Fraction(0)], [Fraction(0)], [Fraction(1)]]]), err

    def __repr__(self):
        return (f"CycloidalMotion(position={[float(x) for x in self.position]}, velocity="
                f"{[float(x) for x in self.velocity]}, angle={float(self.angle)}, angular_velocity="
                f"{float(self.angular_velocity)}, unit={self.unit!r})")


def _iv_bounds(x):
    """The two ends of an mpmath interval as exact Fractions."""
    out = []
    for sign, man, exp, _ in x._mpi_:
        v = Fraction(int(man)) * Fraction(2) ** int(exp)
        out.append(-v if sign else v)
    return out[0], out[1]


def _pair(v, field):
    if isinstance(v, np.ndarray):
        v = v.tolist()
    if not isinstance(v, (list, tuple)) or len(v) != 2:
        raise InputError(f"{field}: expected 2 numbers")
    return v


def _motion(m, field):
    if isinstance(m, (PlanarMotion, CycloidalMotion)):
        return m
    return PlanarMotion(m, field=field)


def _ellipse(e, field):
    if not isinstance(e, Ellipse):
        raise InputTypeError(f"{field}: expected an Ellipse, got {type(e).__name__}")
    return e


# ---------------------------------------------------------------- kernels (numba)


@jit
def _load(W, I, M, D):
    """Slots holding packed polynomials (see :func:`mjccd.geoms.exact.packed`): hi and its bound in doubles, hi + lo and its
    bound in double-double."""
    out = np.empty(M.shape[1], dtype=np.int64)
    dd = W.shape[1] == 3
    for r in range(M.shape[1]):
        n = D[r]
        k = P.alloc(W, I, n)
        for i in range(n + 1):
            W[k, 0, i] = M[0, r, i]
            if dd:
                W[k, 2, i] = M[1, r, i]
                W[k, 1, i] = M[3, r, i]
            else:
                W[k, 1, i] = M[2, r, i]
        out[r] = k
    return out


@jit
def _relative(W, I, MA, MB):
    """adj(M_A) M_B: B's frame into A's, homogeneous (slots h00, h01, h10, h11, t0, t1, weight):
    [[w_A adj(L_A) L_B, adj(L_A)(w_A v_B - w_B v_A)], [0, 0, det(L_A) w_B]]."""
    wa, wb = MA[6], MB[6]
    adj = np.empty(4, dtype=np.int64)
    adj[0], adj[1], adj[2], adj[3] = MA[3], P.scale(W, I, MA[1], -1.0), P.scale(W, I, MA[2], -1.0), MA[0]
    H = np.empty(NM, dtype=np.int64)
    for i in range(2):
        for j in range(2):
            s = P.add(W, I, P.mul(W, I, adj[2 * i], MB[j]), P.mul(W, I, adj[2 * i + 1], MB[2 + j]), 1.0)
            H[2 * i + j] = P.mul(W, I, wa, s)
    d0 = P.add(W, I, P.mul(W, I, wa, MB[4]), P.mul(W, I, wb, MA[4]), -1.0)
    d1 = P.add(W, I, P.mul(W, I, wa, MB[5]), P.mul(W, I, wb, MA[5]), -1.0)
    for i in range(2):
        H[4 + i] = P.add(W, I, P.mul(W, I, adj[2 * i], d0), P.mul(W, I, adj[2 * i + 1], d1), 1.0)
    det = P.add(W, I, P.mul(W, I, MA[0], MA[3]), P.mul(W, I, MA[1], MA[2]), -1.0)
    H[6] = P.mul(W, I, det, wb)
    return H


@jit
def _window_row(W, I, R, s0, s1):
    """The rows R (3 slots: a quadratic's Bernstein coefficients in s) restricted to [s0, s1] (de Casteljau's
    blossom; the weights are exact for dyadic s0, s1 of up to 26 bits)."""
    if s0 == 0.0 and s1 == 1.0:
        return R
    out = np.empty(3, dtype=np.int64)
    for q in range(3):
        u, v = (s0, s0) if q == 0 else ((s0, s1) if q == 1 else (s1, s1))
        w = ((1.0 - u) * (1.0 - v), u * (1.0 - v) + v * (1.0 - u), u * v)
        acc = -1
        for i in range(3):
            if w[i] != 0.0:
                acc = P.scale(W, I, R[i], w[i]) if acc < 0 else P.add(W, I, acc, R[i], w[i])
        out[q] = acc
    return out


@jit
def _boundary_in(W, I, CON, SYS, SYSR, N, H, ra, rb, qa, qb, kinds, c0, c1, s0, s1):
    """The bivariate systems 'a point of the boundary of the disk (semi-axes ra, rb), mapped by H, lies in the
    disk of semi-axes qa, qb', one per chart c0 <= chart < c1 of the boundary (kinds CHART0, CHART1), each
    restricted to s in [s0, s1]."""
    zero = P.const(W, I, 0.0)
    for chart in range(c0, c1):
        sgn = 1.0 if chart == 0 else -1.0
        X = np.empty(3, dtype=np.int64)
        Y = np.empty(3, dtype=np.int64)
        Z = np.empty(3, dtype=np.int64)
        # Bernstein rows in s: H (0, -rb, 1), the direction H (sgn ra, 0, 0) (weight 0), H (0, rb, 1)
        X[0], X[2] = P.add(W, I, H[4], H[1], -rb), P.add(W, I, H[4], H[1], rb)
        Y[0], Y[2] = P.add(W, I, H[5], H[3], -rb), P.add(W, I, H[5], H[3], rb)
        X[1], Y[1] = P.scale(W, I, H[0], sgn * ra), P.scale(W, I, H[2], sgn * ra)
        Z[0], Z[1], Z[2] = H[6], zero, H[6]
        X, Y, Z = _window_row(W, I, X, s0, s1), _window_row(W, I, Y, s0, s1), _window_row(W, I, Z, s0, s1)
        Xn = np.empty(3, dtype=np.int64)
        Yn = np.empty(3, dtype=np.int64)
        for i in range(3):
            Xn[i] = P.frac(W, I, X[i], 1.0, qa)
            Yn[i] = P.frac(W, I, Y[i], 1.0, qb)
        q = P.badd(W, I, P.badd(W, I, P.bmul(W, I, Xn, Xn), P.bmul(W, I, Yn, Yn), 1.0), P.bmul(W, I, Z, Z), -1.0)
        if sy._bpositive(W, I, q):
            continue
        start = N[0]
        sy._bcon(CON, N, q)
        wit = np.empty((4, 3), dtype=np.int64)
        for i in range(3):
            wit[0, i], wit[1, i], wit[2, i], wit[3, i] = X[i], Y[i], zero, Z[i]
        sy._bclose(SYS, SYSR, N, start, 0, wit, 0.0)
        if N[2] == 0:
            kinds[N[1] - 1] = chart


@jit
def _centre_in(W, I, CON, SYS, SYSR, N, H, qa, qb, kinds):
    """The system 'the centre of the disk mapped by H lies in the disk of semi-axes qa, qb' (kind CENTRE)."""
    x = P.frac(W, I, H[4], 1.0, qa)
    y = P.frac(W, I, H[5], 1.0, qb)
    q = P.add(W, I, P.add(W, I, P.sq(W, I, x), P.sq(W, I, y), 1.0), P.sq(W, I, H[6]), -1.0)
    if sy._positive(W, I, q):
        return
    start = N[0]
    sy._con(CON, N, q)
    wit = np.empty(4, dtype=np.int64)
    wit[0], wit[1], wit[2], wit[3] = H[4], H[5], P.const(W, I, 0.0), H[6]
    sy._close(SYS, SYSR, N, start, 1, wit, 0.0)
    if N[2] == 0:
        kinds[N[1] - 1] = CENTRE


@jit
def _planar_systems(W, I, CON, SYS, SYSR, N, MA, DA, ax_a, MB, DB, ax_b, kinds):
    """The pair's systems in an emptied workspace and store: B's boundary in A (two charts), A's centre in B."""
    P.reset(W, I)
    N[0] = N[1] = N[2] = 0
    A = _load(W, I, MA, DA)
    B = _load(W, I, MB, DB)
    _boundary_in(W, I, CON, SYS, SYSR, N, _relative(W, I, A, B), ax_b[0], ax_b[1], ax_a[0], ax_a[1], kinds,
                 0, 2, 0.0, 1.0)
    _centre_in(W, I, CON, SYS, SYSR, N, _relative(W, I, B, A), ax_b[0], ax_b[1], kinds)


@jit
def _extract(W, I, CON, N):
    """:func:`mjccd.geoms.kernel.constraints_of` and ok, False when the workspace or the store overflowed (then no
    constraint)."""
    ok = N[2] == 0 and not P.failed(I)
    C, DS, DT, errs = kn.constraints_of(W, I, CON, N if ok else np.zeros(3, dtype=np.int64))
    return C, DS, DT, errs, ok


@jit
def _runs(SYS, N, C, DS, DT, errs, t_end, out):
    """Every interval of [0, t_end] in which some system may hold, merged (rows of
    :func:`mjccd.geoms.kernel.merge_runs`); returns (count, certified, status at t = 0)."""
    R = np.empty((N[1] * kn.MAX_RUNS + 1, sc.RUN_FIELDS))
    n = 0
    part = np.empty((kn.MAX_RUNS, sc.RUN_FIELDS))
    for k in range(N[1]):
        s0, cnt = SYS[k, 0], SYS[k, 1]
        if SYS[k, 3] == 0:
            m = sc.all_runs(np.ascontiguousarray(C[s0:s0 + cnt, 0, :]), DT[s0:s0 + cnt], errs[s0:s0 + cnt], t_end,
                            part)
        else:
            m = sc.ball_runs(C[s0:s0 + cnt], DS[s0:s0 + cnt], DT[s0:s0 + cnt], errs[s0:s0 + cnt], t_end, part)
        for q in range(min(m, kn.MAX_RUNS)):
            for f in range(sc.RUN_FIELDS):
                R[n, f] = part[q, f]
            n += 1
    count, certified = kn.merge_runs(R, n, t_end, out)
    return count, certified, kn.status_of_systems(SYS, N, C, DS, DT, errs)



@jit
def planar_kernel(MA, DA, ax_a, MB, DB, ax_b, t_end, W, I, Wdd, Idd, CON, SYS, SYSR, N, kinds, out):
    """First contact over [0, t_end] of the disks (semi-axes ax_a, ax_b) under the packed motions (MA, DA),
    (MB, DB): doubles first, double-double when the bracket is wider than TIME_TOL.  out (OUTP,): the fields
    of :func:`mjccd.geoms.kernel.pair_kernel` (STATUS, LO, HI, TIME, CERTIFIED, SYSTEMS, WINNER, FAILED,
    TIER, PROVEN), then S_BEST (the witness's s) and KIND (the winning system's kind)."""
    for i in range(out.shape[0]):
        out[i] = 0.0
    out[kn.LO] = out[kn.HI] = out[kn.TIME] = -1.0
    out[KIND] = -1.0
    for tier in range(2):
        Wt, It = (W, I) if tier == 0 else (Wdd, Idd)
        _planar_systems(Wt, It, CON, SYS, SYSR, N, MA, DA, ax_a, MB, DB, ax_b, kinds)
        C, DS, DT, errs, ok = _extract(Wt, It, CON, N)
        if not ok:
            out[kn.FAILED] = kn.OVERFLOW
            return
        out[kn.TIER] = tier
        best, s_best = kn.scan_systems(SYS, N, C, DS, DT, errs, t_end, out, np.bool_(True))
        out[S_BEST] = s_best
        out[KIND] = kinds[best] if best >= 0 else -1.0
        if out[kn.CERTIFIED] > 0.0 or tier == 1:
            return


@jit
def planar_runs(MA, DA, ax_a, MB, DB, ax_b, t_end, W, I, Wdd, Idd, CON, SYS, SYSR, N, kinds, out):
    """Every interval of contact (rows of :func:`mjccd.geoms.kernel.merge_runs` in out (MAX_RUNS, 7)); returns
    (count, certified, status at t = 0, ok), doubles first and double-double when not certified."""
    count, certified, status0 = 0, False, 1
    for tier in range(2):
        Wt, It = (W, I) if tier == 0 else (Wdd, Idd)
        _planar_systems(Wt, It, CON, SYS, SYSR, N, MA, DA, ax_a, MB, DB, ax_b, kinds)
        C, DS, DT, errs, ok = _extract(Wt, It, CON, N)
        if not ok:
            return 0, False, 1, False
        count, certified, status0 = _runs(SYS, N, C, DS, DT, errs, t_end, out)
        if certified:
            break
    return count, certified, status0, True


@jit
def planar_window(MA, DA, ax_a, MB, DB, ax_b, chart, s0, s1, W, I, CON, SYS, SYSR, N, kinds, res):
    """One system on the (reparametrised) time of the packed motions: chart 0 or 1 of B's boundary restricted
    to s in [s0, s1] in A, or (chart -1) A's centre in B.  res = (lo, hi, estimate, band_end, s, ok) as
    :func:`mjccd.geoms.scan.bfirst_time` (lo = -1: proven never to hold; hi = -1: nowhere proven)."""
    P.reset(W, I)
    N[0] = N[1] = N[2] = 0
    A = _load(W, I, MA, DA)
    B = _load(W, I, MB, DB)
    if chart >= 0:
        _boundary_in(W, I, CON, SYS, SYSR, N, _relative(W, I, A, B), ax_b[0], ax_b[1], ax_a[0], ax_a[1], kinds,
                     chart, chart + 1, s0, s1)
    else:
        _centre_in(W, I, CON, SYS, SYSR, N, _relative(W, I, B, A), ax_b[0], ax_b[1], kinds)
    C, DS, DT, errs, ok = _extract(W, I, CON, N)
    res[0], res[1], res[2], res[3], res[4], res[5] = -1.0, -1.0, -1.0, -1.0, 0.5, 1.0 if ok else 0.0
    if not ok or N[1] == 0:
        return
    st, cnt = SYS[0, 0], SYS[0, 1]
    if SYS[0, 3] == 0:
        l, h, e, be = sc.first_time(np.ascontiguousarray(C[st:st + cnt, 0, :]), DT[st:st + cnt], errs[st:st + cnt],
                                    1.0)
        sv = 0.5
    else:
        l, h, e, be, sv = sc.bfirst_time(C[st:st + cnt], DS[st:st + cnt], DT[st:st + cnt], errs[st:st + cnt], 1.0,
                                         ZOOM_BOXES)
    res[0], res[1], res[2], res[3], res[4] = l, h, e, be, sv


# ---------------------------------------------------------------- the Python layer

_local = threading.local()


def thread_workspaces(local, slots):
    """The calling thread's double and double-double workspaces of ``slots`` polynomials, system store and kinds,
    kept in the ``threading.local`` ``local`` (made on first use): the last arguments of the planar and spatial
    kernels."""
    ws = getattr(local, "workspaces", None)
    if ws is None:
        ws = local.workspaces = (*P.workspace(slots, P.MAX_DEGREE), *P.workspace(slots, P.MAX_DEGREE, True),
                                 *sy.new_store(16, 32), np.zeros(16, dtype=np.int64))
    return ws


def workspaces():
    """This thread's workspaces of the planar kernels (:func:`thread_workspaces`)."""
    return thread_workspaces(_local, SLOTS)


def _deg(p):
    return -10 ** 6 if not any(p) else len(p) - 1


def _contact_degree(pa, pb):
    """Degree in t of the contact polynomials of polynomials pa (of A's motion) and pb (B's), both ways."""
    worst = 0
    for x, y in ((pa, pb), (pb, pa)):
        dl = max(_deg(p) for p in x[:4])
        lin = _deg(x[6]) + dl + max(_deg(p) for p in y[:4])
        tr = dl + max(_deg(x[6]) + max(_deg(p) for p in y[4:6]), _deg(y[6]) + max(_deg(p) for p in x[4:6]))
        wt = 2 * dl + _deg(y[6])
        worst = max(worst, 2 * max(lin, tr, wt))
    return worst


def _prepared(ea, ma, eb, mb):
    """Exact polynomials of both motions seen from A's centre at t = 0 (rounded to a double, the shift
    exact), packed for the kernel; and that origin."""
    e = ma.entries
    w0 = X.value(e[2][2], 0)
    origin = (float(X.value(e[0][2], 0) / w0), float(X.value(e[1][2], 0) / w0))
    pa, pb = ma._polys(origin), mb._polys(origin)
    deg = _contact_degree(pa, pb)
    if deg > MAX_MOTION_DEGREE:
        raise InputError(f"motion_a, motion_b: the contact polynomials would have degree {deg} in t, more than the "
                         f"workspace's {MAX_MOTION_DEGREE} (lower the motions' degrees)")
    MA, DA = X.packed(pa)
    MB, DB = X.packed(pb)
    return (MA, DA, np.array([ea.a, ea.b]), MB, DB, np.array([eb.a, eb.b])), origin, pa, pb


def _solve(ea, ma, eb, mb, t_end):
    """The kernel's answer (OUTP,) for two PlanarMotions, the origin and the shifted polynomials."""
    args, origin, pa, pb = _prepared(ea, ma, eb, mb)
    out = np.empty(OUTP)
    planar_kernel(*args, float(t_end), *workspaces(), out)
    if out[kn.FAILED] == kn.OVERFLOW:
        raise RuntimeError("planar pair: the contact polynomials outgrew the solver's workspace")
    return out, origin, pa, pb


ZOOM_SPLIT = 8      # windows per chart of B's boundary when a bracket is zoomed into
ZOOM_DEPTH = 12     # halvings of a window in s
ZOOM_CALLS = 120    # window scans per round of a zoom
ZOOM_ROUNDS = 4     # rounds of a zoom, each on the bracket the last one left


class _Answer:
    """A pair's first contact: status at t = 0 (1, 0, -1), the bracket [lo, hi] (lo = -1: proven free), whether
    hi is proven, the reported time, B's boundary angle of the witness (or None)."""

    __slots__ = ("status", "lo", "hi", "proven", "time", "theta")

    def __init__(self, status, lo, hi, proven, time, theta):
        self.status, self.lo, self.hi, self.proven, self.time, self.theta = status, lo, hi, proven, time, theta

    @property
    def certified(self):
        return self.status != 1 or self.lo < 0.0 or (self.proven and self.hi - self.lo <= TIME_TOL)


def _theta(chart, s):
    th = 2.0 * math.atan(2.0 * s - 1.0)
    return th if chart == CHART0 else math.pi - th


def _window_scan(ea, ma, eb, mb, origin, t0, h, proven_end):
    """The first time any system holds on the window t = t0 + h tau, tau in [0, 1] (h may be negative: the
    window read backwards), found in tau: each system is rebuilt on the window (the motions reparametrised
    exactly) in double-double, B's boundary cut into windows of s that are halved while they stay undecided,
    so that the coefficients, and with them the error bounds, are as small as the constraint is there.
    ``proven_end``: a contact is already proven at tau = 1.  Returns (lo, end, proven, theta) in tau: no
    system holds before lo (lo = -1: none holds on the window); one is proven to hold at end when
    ``proven``, else every possible first time lies in [lo, end]."""
    MA, DA = X.packed(ma.reparametrized(t0, h)._polys(origin))
    MB, DB = X.packed(mb.reparametrized(t0, h)._polys(origin))
    ax_a, ax_b = np.array([ea.a, ea.b]), np.array([eb.a, eb.b])
    _, _, Wdd, Idd, CON, SYS, SYSR, N, kinds = workspaces()
    res = np.empty(6)
    tol = TIME_TOL / float(abs(h)) if h != 0 else 2.0
    # windows (lower bound, end, chart, s0, s1, depth), the one with the lowest bound first
    queue = [(0.0, 1.0, -1, 0.0, 1.0, 0)] + [(0.0, 1.0, c, k / ZOOM_SPLIT, (k + 1) / ZOOM_SPLIT, 0)
                                             for c in (CHART0, CHART1) for k in range(ZOOM_SPLIT)]
    best = 1.0 if proven_end else None
    theta = None
    leaves = []  # (lower bound, end of the undecided band) of the windows left undecided
    calls = 0
    while queue:
        p_lo, p_end, chart, s0, s1, depth = heapq.heappop(queue)
        if best is not None and p_lo >= best:
            continue
        if calls >= ZOOM_CALLS:
            leaves.append((p_lo, p_end))
            continue
        planar_window(MA, DA, ax_a, MB, DB, ax_b, chart, s0, s1, Wdd, Idd, CON, SYS, SYSR, N, kinds, res)
        calls += 1
        if res[5] == 0.0:
            raise RuntimeError("planar pair: the contact polynomials outgrew the solver's workspace")
        if res[0] < 0.0:
            continue
        w_lo = float(res[0])
        w_end = float(res[1]) if res[1] >= 0.0 else float(max(res[3], res[0]))
        if res[1] >= 0.0 and (best is None or w_end < best):
            best = w_end
            theta = None if chart < 0 else _theta(chart, s0 + (s1 - s0) * res[4])
        if best is not None and w_lo >= best:
            continue
        if (res[1] >= 0.0 and w_end - w_lo <= tol) or chart < 0 or depth >= ZOOM_DEPTH:
            leaves.append((w_lo, w_end))
            continue
        mid = 0.5 * (s0 + s1)
        heapq.heappush(queue, (w_lo, w_end, chart, s0, mid, depth + 1))
        heapq.heappush(queue, (w_lo, w_end, chart, mid, s1, depth + 1))
    los = [l for l, _ in leaves if best is None or l < best]
    if best is not None:
        return min(los + [best]), best, True, theta
    if not los:
        return -1.0, -1.0, False, None
    return min(los), min(1.0, max(e for _, e in leaves)), False, None


def _zoom(ea, ma, eb, mb, origin, lo, hi, proven):
    """Narrow the bracket [lo, hi] of every possible first contact (hi proven or not) by
    :func:`_window_scan`, again on the narrower bracket while it shrinks (at most ZOOM_ROUNDS times);
    returns (lo, hi, proven, theta) in t (lo = -1: no contact in it)."""
    theta = None
    for _ in range(ZOOM_ROUNDS):
        t0, h = Fraction(lo), Fraction(hi) - Fraction(lo)
        w_lo, w_end, w_proven, w_theta = _window_scan(ea, ma, eb, mb, origin, t0, h, proven)
        if w_lo < 0.0:
            return -1.0, -1.0, False, None
        new_lo, new_hi = max(lo, X.down(t0 + h * Fraction(w_lo))), min(hi, X.up(t0 + h * Fraction(w_end)))
        shrunk = new_hi - new_lo < 0.5 * (hi - lo)
        lo, hi, proven = new_lo, new_hi, w_proven
        theta = w_theta if w_theta is not None else theta
        if (proven and hi - lo <= TIME_TOL) or not shrunk:
            break
    return lo, hi, proven, theta


def _last_contact(ea, ma, eb, mb, origin, a, b):
    """Where contact ends in [a, b], contact being proven at a and absent just after b (or b the end of
    time): the window read backwards.  Returns (lo, hi, certified): the end lies in [lo, hi]."""
    t0, h = Fraction(b), Fraction(a) - Fraction(b)
    w_lo, w_end, w_proven, _ = _window_scan(ea, ma, eb, mb, origin, t0, h, True)
    if w_lo < 0.0:
        return a, b, False
    lo, hi = max(a, X.down(t0 + h * Fraction(w_end))), min(b, X.up(t0 + h * Fraction(w_lo)))
    return lo, hi, w_proven and hi - lo <= TIME_TOL


def _simplest_dyadic(lo, hi):
    """The dyadic rational with the fewest bits in [lo, hi] (both doubles)."""
    lo_f, hi_f = Fraction(lo), Fraction(hi)
    for k in range(0, 64):
        m = math.ceil(lo_f * 2 ** k)
        if Fraction(m, 2 ** k) <= hi_f:
            return Fraction(m, 2 ** k)
    return lo_f


def _exact_matrix(m, t):
    e = m.entries
    return [[X.value(p, t) for p in row] for row in e]


def _adj3(M):
    """The adjugate of a 3x3 matrix (exact)."""
    def c(i, j):
        r = [x for x in range(3) if x != i]
        k = [x for x in range(3) if x != j]
        return (-1) ** (i + j) * (M[r[0]][k[0]] * M[r[1]][k[1]] - M[r[0]][k[1]] * M[r[1]][k[0]])
    return [[c(j, i) for j in range(3)] for i in range(3)]


def _mat3(A, B):
    return [[sum(A[i][k] * B[k][j] for k in range(3)) for j in range(3)] for i in range(3)]


def _exact_touch(ea, ma, eb, mb, lo, hi, theta):
    """A rational time in [lo, hi] at which a rational point of B's boundary (or A's centre) is proven, in
    rational arithmetic, to lie in the other disk: a touch that no strict inequality can show, as in the
    thesis' Example 2.2 (disks designed to graze at t = 1/2).  None when the candidates fail."""
    t = _simplest_dyadic(lo, hi)
    A, B = _exact_matrix(ma, t), _exact_matrix(mb, t)
    aa, ab, ba, bb = Fraction(ea.a), Fraction(ea.b), Fraction(eb.a), Fraction(eb.b)
    K = _mat3(_adj3(A), B)
    ss = {Fraction(0), Fraction(1, 2), Fraction(1)}
    charts = (CHART0, CHART1)
    if theta is not None:
        chart = CHART0 if math.cos(theta) >= 0.0 else CHART1
        th = theta if chart == CHART0 else math.pi - theta
        s = 0.5 * (math.tan(0.5 * th) + 1.0)
        if 0.0 <= s <= 1.0:
            ss |= {Fraction(round(s * 2 ** k), 2 ** k) for k in range(1, 40)}
    for chart in charts:
        for s in sorted(ss):
            sig = 2 * s - 1
            y = [(1 - sig * sig) * ba * (1 if chart == CHART0 else -1), 2 * sig * bb, 1 + sig * sig]
            p = [sum(K[i][k] * y[k] for k in range(3)) for i in range(3)]
            if p[0] ** 2 / aa ** 2 + p[1] ** 2 / ab ** 2 - p[2] ** 2 <= 0:
                return t
    c = _mat3(_adj3(B), A)
    if c[0][2] ** 2 / ba ** 2 + c[1][2] ** 2 / bb ** 2 - c[2][2] ** 2 <= 0:
        return t
    return None


def _answer(ea, ma, eb, mb, t_end):
    """The first contact of two PlanarMotions over [0, t_end]: the kernel's scan, then (when it leaves an
    uncertain bracket) the zoom and an exact touch at a simple rational time."""
    out, origin, pa, pb = _solve(ea, ma, eb, mb, t_end)
    status = int(out[kn.STATUS])
    if status != 1:
        return _Answer(status, 0.0, 0.0, status == -1, 0.0, None), origin, pa, pb
    lo, hi, proven = float(out[kn.LO]), float(out[kn.HI]), out[kn.PROVEN] > 0.0
    ans = _Answer(1, lo, hi, proven, float(out[kn.TIME]), _theta_of(out))
    if ans.certified:
        return ans, origin, pa, pb
    lo, hi, proven, theta = _zoom(ea, ma, eb, mb, origin, lo, hi, proven)
    ans = _Answer(1, lo, hi, proven, lo, theta if theta is not None else ans.theta)
    if lo >= 0.0 and not ans.certified:
        t = _exact_touch(ea, ma, eb, mb, lo, hi, ans.theta)
        if t is not None:
            ans.hi, ans.proven, ans.time = X.up(t), True, float(t)
            return ans, origin, pa, pb
    if ans.certified and lo >= 0.0:
        ans.time = 0.5 * (lo + hi)
    return ans, origin, pa, pb


def _intervals(ea, ma, eb, mb):
    """(intervals, certified, status at t = 0): the runs of the systems (all_runs, ball_runs) merged, then each
    end left uncertain refined by window scans (forwards for a start, backwards for an end)."""
    args, origin, _, _ = _prepared(ea, ma, eb, mb)
    out = np.empty((kn.MAX_RUNS, 7))
    count, certified, status0, ok = planar_runs(*args, 1.0, *workspaces(), out)
    if not ok:
        raise RuntimeError("planar pair: the contact polynomials outgrew the solver's workspace")
    intervals, all_ok = [], count < kn.MAX_RUNS
    for k in range(count):
        _, _, in_lo, in_hi, out_lo, out_hi, proven = (float(x) for x in out[k])
        proven = proven > 0.0
        if proven and in_hi - in_lo <= TIME_TOL:
            e_lo, e_hi, e_ok = in_lo, in_hi, True
        else:  # the first contact in the run
            e_lo, e_hi, e_proven, _ = _zoom(ea, ma, eb, mb, origin, in_lo, in_hi if proven else out_hi, proven)
            if e_lo < 0.0:
                continue  # no contact in the run at all
            e_ok = e_proven and e_hi - e_lo <= TIME_TOL
            if not e_proven:
                intervals.append((e_lo, out_hi))
                all_ok = False
                continue
            out_lo = max(out_lo, e_hi) if proven else e_hi
        if out_hi >= 1.0 and out_lo >= 1.0 - TIME_TOL:
            x_lo, x_hi, x_ok = 1.0, 1.0, True
        elif out_hi - out_lo <= TIME_TOL and out_hi < 1.0:
            x_lo, x_hi, x_ok = out_lo, out_hi, True
        else:  # the last contact in the run, read backwards from its latest possible end
            x_lo, x_hi, x_ok = _last_contact(ea, ma, eb, mb, origin, out_lo, out_hi)
        all_ok = all_ok and e_ok and x_ok
        intervals.append((0.0 if e_lo == 0.0 else 0.5 * (e_lo + e_hi), 1.0 if x_hi >= 1.0 else 0.5 * (x_lo + x_hi)))
    return _union(intervals), bool(all_ok), int(status0)


def _matrix(polys, t):
    """The 3x3 float matrix of the 7 exact polynomials at time t."""
    t = Fraction(float(t))
    v = [float(X.value(p, t)) for p in polys]
    return np.array([[v[0], v[1], v[4]], [v[2], v[3], v[5]], [0.0, 0.0, v[6]]])


def deepest_point(MA, ea, MB, eb, theta=None):
    """B's boundary point that goes deepest into A (or comes nearest, in A's quadric) for the matrices MA, MB
    at one time: (world point (2,), A's outward unit normal there (2,), B's boundary angle).  Newton on the
    angle from ``theta`` and from the best of 256 samples."""
    K = np.linalg.solve(MA, MB)
    D = np.array([1.0 / ea.a ** 2, 1.0 / ea.b ** 2, -1.0])
    c0, c1, c2 = K[:, 2], K[:, 0] * eb.a, K[:, 1] * eb.b

    def f(th):
        p = c0 + c1 * np.cos(th) + c2 * np.sin(th)
        return p @ (D * p)

    ths = np.linspace(0.0, 2.0 * np.pi, 256, endpoint=False)
    ps = c0[:, None] + c1[:, None] * np.cos(ths) + c2[:, None] * np.sin(ths)
    vals = np.einsum("ik,i,ik->k", ps, D, ps)
    starts = [float(ths[int(np.argmin(vals))])] + ([] if theta is None else [float(theta)])
    best, best_v = None, np.inf
    for th in starts:
        for _ in range(60):
            c, s = np.cos(th), np.sin(th)
            p = c0 + c1 * c + c2 * s
            dp = -c1 * s + c2 * c
            d2p = -c1 * c - c2 * s
            g = 2.0 * (dp @ (D * p))
            hss = 2.0 * (dp @ (D * dp) + p @ (D * d2p))
            step = -g / hss if hss > 0.0 else -0.1 * np.sign(g)
            th = th + float(np.clip(step, -0.5, 0.5))
            if abs(step) < 1e-15:
                break
        v = f(th)
        if v < best_v:
            best, best_v = th, v
    y = MB @ np.array([eb.a * np.cos(best), eb.b * np.sin(best), 1.0])
    point = y[:2] / y[2]
    ya = np.linalg.solve(MA, y)
    ya = ya[:2] / ya[2]
    g = np.array([ya[0] / ea.a ** 2, ya[1] / ea.b ** 2])
    n = np.linalg.inv(MA[:2, :2] / MA[2, 2]).T @ g
    return point, n / np.linalg.norm(n), best


def _theta_of(out):
    """B's boundary angle of the winning chart's witness s (None for the centre system)."""
    kind = int(out[KIND])
    if kind not in (CHART0, CHART1):
        return None
    th = 2.0 * math.atan(2.0 * out[S_BEST] - 1.0)
    return th if kind == CHART0 else math.pi - th


def _contact(ans, ea, eb, pa, pb, origin):
    if ans.status != 1:
        return Contact(0.0, None, None, STATUS_NAMES[ans.status])
    if ans.lo < 0.0:
        return None
    if ans.certified:
        t = ans.time
        point, normal, _ = deepest_point(_matrix(pa, t), ea, _matrix(pb, t), eb, ans.theta)
        return Contact(t, point + np.array(origin), normal, "separate")
    return Contact(ans.lo, None, None, "separate", "uncertain", (ans.lo, ans.hi))


def ellipse_first_contact(ellipse_a, motion_a, ellipse_b, motion_b, *, t_max=1.0):
    """First time in [0, t_max] at which two moving elliptic disks touch, as a :class:`mjccd.Contact`, or None
    when they are proven apart over [0, t_max].

    ``ellipse_a``, ``ellipse_b``: :class:`Ellipse`; motions: :class:`PlanarMotion`
    (or its 3x3 matrix of polynomials) or :class:`CycloidalMotion`.  The
    contact's point is a 2-vector in world coordinates and its normal is
    outward from A.  ``status_at_start`` is "separate", "touching" or
    "overlapping" (then time 0 and no point).  An uncertain answer
    (``certainty == "uncertain"``) carries a ``bracket`` that holds every
    possible first contact (its point and normal are None).
    """
    ea, eb = _ellipse(ellipse_a, "ellipse_a"), _ellipse(ellipse_b, "ellipse_b")
    ma, mb = _motion(motion_a, "motion_a"), _motion(motion_b, "motion_b")
    t_max = _validate.time_bound(t_max, "t_max")
    if isinstance(ma, CycloidalMotion) or isinstance(mb, CycloidalMotion):
        return _cycloidal_first_contact(ea, ma, eb, mb, t_max)
    ans, origin, pa, pb = _answer(ea, ma, eb, mb, t_max)
    return _contact(ans, ea, eb, pa, pb, origin)


def ellipse_collision_intervals(ellipse_a, motion_a, ellipse_b, motion_b):
    """Every interval of [0, 1] in which the two disks touch or overlap: (list of (t_in, t_out), certified).

    Certified: every end is proven within 1e-9.  Otherwise every time of
    contact still lies in the intervals returned, but an interval may be a
    graze that does not happen, or its ends may be wider apart.
    """
    ea, eb = _ellipse(ellipse_a, "ellipse_a"), _ellipse(ellipse_b, "ellipse_b")
    ma, mb = _motion(motion_a, "motion_a"), _motion(motion_b, "motion_b")
    if isinstance(ma, CycloidalMotion) or isinstance(mb, CycloidalMotion):
        return _cycloidal_intervals(ea, ma, eb, mb)
    intervals, certified, _ = _intervals(ea, ma, eb, mb)
    return intervals, certified


# ---------------------------------------------------------------- trigonometric (cycloidal) motions

SQRT2_UP = Fraction(141421357, 100000000)  # above sqrt(2)
CYCLOIDAL_DEGREE = 14                      # Taylor degree on a piece where the angle turns by at most 1 rad


def _pieces_for(m, t_max):
    if not isinstance(m, CycloidalMotion):
        return 1
    turn = abs(float(m.angular_velocity)) * (math.pi if m.unit == "pi" else 1.0) * t_max
    return max(1, math.ceil(turn * (1.0 + 1e-9)))


def _piece_motion(m, t0, h):
    """(exact PlanarMotion in tau on [t0, t0 + h], proven bound of its rotation entries' error)."""
    if isinstance(m, CycloidalMotion):
        return m.approximation(t0, h, CYCLOIDAL_DEGREE)
    return m.reparametrized(t0, h), Fraction(0)


def _scaled(e, eta, grow):
    """The disk grown so that it holds the true one (``grow``), or shrunk so that the true one holds it, when
    the rotation of its approximate motion is within eta of the true one in each entry: a point y moves by at
    most sqrt(2) eta rho (rho, m the largest and smallest semi-axes)."""
    if eta == 0:
        return e
    rho, m = Fraction(max(e.a, e.b)), Fraction(min(e.a, e.b))
    eps = SQRT2_UP * eta * rho
    if grow:
        g = 1 + eps / ((1 - SQRT2_UP * eta) * m)
        return Ellipse(X.up(Fraction(e.a) * g), X.up(Fraction(e.b) * g))
    h = 1 / (1 + eps / m)
    return Ellipse(X.down(Fraction(e.a) * h), X.down(Fraction(e.b) * h))


class _Pieces:
    """The pieces of [0, t_max] on which trigonometric motions are replaced by proven approximations, each
    with its grown and shrunk pair (made on first use)."""

    def __init__(self, ea, ma, eb, mb, t_max):
        self.ea, self.ma, self.eb, self.mb = ea, ma, eb, mb
        self.n = max(_pieces_for(ma, t_max), _pieces_for(mb, t_max))
        self.h = Fraction(t_max) / self.n
        self.eta = Fraction(0)
        self._made = {}

    def __getitem__(self, k):
        if k not in self._made:
            t0 = self.h * k
            pa, eta_a = _piece_motion(self.ma, t0, self.h)
            pb, eta_b = _piece_motion(self.mb, t0, self.h)
            self.eta = max(self.eta, eta_a, eta_b)
            self._made[k] = (t0, (_scaled(self.ea, eta_a, True), pa, _scaled(self.eb, eta_b, True), pb),
                             (_scaled(self.ea, eta_a, False), pa, _scaled(self.eb, eta_b, False), pb))
        return self._made[k]

    def time(self, t0, tau, up):
        x = t0 + self.h * Fraction(float(tau))
        return X.up(x) if up else X.down(x)


def _cycloidal_first_contact(ea, ma, eb, mb, t_max):
    """The first contact under trigonometric motions, bracketed by the grown pairs (which hold the true disks:
    a lower bound) and the shrunk pairs (which the true disks hold: an upper bound), piece by piece."""
    pcs = _Pieces(ea, ma, eb, mb, t_max)
    lo, k, g = None, 0, None
    for k in range(pcs.n):
        t0, grown, _ = pcs[k]
        g = _answer(*grown, 1.0)[0]
        if g.status != 1:
            lo = pcs.time(t0, 0.0, False)
        elif g.lo >= 0.0:
            lo = pcs.time(t0, g.lo, False)
        if lo is not None:
            break
    if lo is None:
        return None
    hi = None
    for j in range(k, pcs.n):
        t0, _, shrunk = pcs[j]
        s = _answer(*shrunk, 1.0)[0]
        if s.status == -1:
            hi = pcs.time(t0, 0.0, True)
        elif s.status == 1 and s.lo >= 0.0 and s.proven:
            hi = pcs.time(t0, s.hi, True)
        if hi is not None:
            break
    if k == 0 and g.status != 1:  # the grown disks meet at the start
        if hi == 0.0:
            return Contact(0.0, None, None, "overlapping")
        return Contact(0.0, None, None, "touching", "uncertain", (0.0, t_max if hi is None else hi))
    if hi is None or hi - lo > TIME_TOL:
        return Contact(lo, None, None, "separate", "uncertain", (lo, t_max if hi is None else hi))
    t = 0.5 * (lo + hi)
    point, normal, _ = deepest_point(ma.at(t), ea, mb.at(t), eb)
    return Contact(t, point, normal, "separate")


def _union(intervals):
    out = []
    for lo, hi in sorted(intervals):
        if out and lo <= out[-1][1] + TIME_TOL:
            out[-1] = (out[-1][0], max(out[-1][1], hi))
        else:
            out.append((lo, hi))
    return out


def _cycloidal_intervals(ea, ma, eb, mb):
    pcs = _Pieces(ea, ma, eb, mb, 1.0)
    grown_iv, shrunk_iv, certified = [], [], True
    for k in range(pcs.n):
        t0, grown, shrunk = pcs[k]
        for pair, acc in ((grown, grown_iv), (shrunk, shrunk_iv)):
            iv, ok, _ = _intervals(*pair)
            certified = certified and ok
            acc += [(pcs.time(t0, a, False), pcs.time(t0, b, True)) for a, b in iv]
    grown_iv, shrunk_iv = _union(grown_iv), _union(shrunk_iv)
    if certified and len(grown_iv) == len(shrunk_iv) and all(
            abs(g[0] - s[0]) <= TIME_TOL and abs(g[1] - s[1]) <= TIME_TOL for g, s in zip(grown_iv, shrunk_iv)):
        return [(0.5 * (g[0] + s[0]), 0.5 * (g[1] + s[1])) for g, s in zip(grown_iv, shrunk_iv)], True
    return grown_iv, False
