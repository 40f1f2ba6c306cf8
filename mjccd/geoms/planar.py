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
by :func:`mjccd.geoms.scan.bfirst_time` and :func:`mjccd.geoms.scan.first_time`
(:func:`~mjccd.geoms.scan.ball_runs` and :func:`~mjccd.geoms.scan.all_runs` for
every interval), and rebuilt in double-double when doubles leave the first
contact in a bracket wider than ``TIME_TOL`` (1e-9), as
:func:`mjccd.geoms.kernel.pair_kernel` does.  Both motions are first seen from
A's centre at t = 0 (the shift applied exactly), so a pair far from the origin
loses nothing.  The contact point is B's boundary point that goes deepest into
A at the contact time (a 1-d Newton refinement of the scan's witness), the
normal A's outward normal there.

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
certified when they agree within TIME_TOL (they do by about 1e-13 here).
"""
import math
import threading
from fractions import Fraction
from numbers import Integral, Real

import numpy as np

from mjccd import _validate
from mjccd.ccd import Contact
from mjccd.errors import InputError, InputTypeError
from mjccd.geoms import kernel as kn
from mjccd.geoms import poly as P
from mjccd.geoms import scan as sc
from mjccd.geoms import systems as sy
from mjccd.geoms.poly import _jit

TIME_TOL = kn.TIME_TOL
STATUS_NAMES = {1: "separate", 0: "touching", -1: "overlapping"}
MAX_MOTION_DEGREE = P.MAX_DEGREE  # degree of the contact polynomials in t, which the workspace bounds
SLOTS = 4096
NM = 7                            # the polynomials of a motion: L00, L01, L10, L11, v0, v1, w
OUTP = kn.OUT + 3                 # the kernel's answer, then the witness s, its system's kind, a spare
S_BEST, KIND = kn.OUT, kn.OUT + 1
CHART0, CHART1, CENTRE = 0, 1, 2  # kinds of the planar systems


# ---------------------------------------------------------------- exact polynomials (lists of Fractions)


def _number(x, field):
    """x as an exact Fraction (floats, ints, Fractions; finite)."""
    if isinstance(x, Fraction):
        return x
    if isinstance(x, bool):
        raise InputTypeError(f"{field}: expected a number, got {x!r}")
    if isinstance(x, Integral):
        return Fraction(int(x))
    if isinstance(x, Real):
        f = float(x)
        if not math.isfinite(f):
            raise InputError(f"{field}: must be finite, got {f}")
        return Fraction(f)
    raise InputTypeError(f"{field}: expected a number or a list of coefficients, got {type(x).__name__}")


def _trim(p):
    p = list(p)
    while len(p) > 1 and p[-1] == 0:
        p.pop()
    return p


def _poly(value, field):
    """A polynomial entry: a number or a sequence of power-basis coefficients (lowest first), as Fractions."""
    if isinstance(value, np.ndarray):
        if value.ndim == 0:
            return [_number(value.item(), field)]
        if value.ndim != 1:
            raise InputError(f"{field}: expected a number or a 1-d list of coefficients")
        value = value.tolist()
    if isinstance(value, (list, tuple)):
        if not value:
            raise InputError(f"{field}: expected a non-empty list of coefficients")
        return _trim([_number(c, f"{field}[{i}]") for i, c in enumerate(value)])
    return [_number(value, field)]


def _padd(a, b, sb=1):
    n = max(len(a), len(b))
    return _trim([(a[i] if i < len(a) else 0) + sb * (b[i] if i < len(b) else 0) for i in range(n)])


def _pmul(a, b):
    out = [Fraction(0)] * (len(a) + len(b) - 1)
    for i, x in enumerate(a):
        if x:
            for j, y in enumerate(b):
                out[i + j] += x * y
    return _trim(out)


def _pscale(a, s):
    return _trim([s * x for x in a])


def _peval(p, t):
    acc = Fraction(0)
    for c in reversed(p):
        acc = acc * t + c
    return acc


def _pderiv(p):
    return _trim([i * p[i] for i in range(1, len(p))] or [Fraction(0)])


def _prem(a, b):
    """The remainder of a by b (b nonzero)."""
    a = list(a)
    while len(a) >= len(b) and any(a):
        f = a[-1] / b[-1]
        shift = len(a) - len(b)
        for i, c in enumerate(b):
            a[shift + i] -= f * c
        a.pop()
    return _trim(a or [Fraction(0)])


def _sign_changes(seq, t):
    signs = [v for v in (_peval(p, t) for p in seq) if v != 0]
    return sum(1 for x, y in zip(signs, signs[1:]) if (x > 0) != (y > 0))


def _vanishes_on_01(p):
    """True when the nonzero polynomial p has a real root in [0, 1] (exact: Sturm's theorem; a multiple root is
    counted once, which is all a yes-or-no needs)."""
    p = _trim(p)
    if _peval(p, 0) == 0 or _peval(p, 1) == 0:
        return True
    if len(p) == 1:
        return False
    seq = [p, _pderiv(p)]
    while len(seq[-1]) > 1:
        r = _prem(seq[-2], seq[-1])
        if not any(r):
            break
        big = max(abs(c) for c in r)
        seq.append([-c / big for c in r])  # a positive factor keeps the signs; it keeps the numbers small
    return _sign_changes(seq, Fraction(0)) - _sign_changes(seq, Fraction(1)) > 0


def _taylor_shift(p, t0, h):
    """p(t0 + h tau) as a polynomial in tau (exact)."""
    out = [Fraction(0)]
    for c in reversed(p):
        out = _padd(_pmul(out, [t0, h]), [c])
    return out


def _up(x):
    """The smallest double >= the nonnegative Fraction x."""
    f = float(x)
    if Fraction(f) < x:
        f = math.nextafter(f, math.inf)
    return f


def _down(x):
    """The largest double <= x."""
    f = float(x)
    if Fraction(f) > x:
        f = math.nextafter(f, -math.inf)
    return f


def _bernstein(p, n):
    """Bernstein coefficients of degree n >= deg p on [0, 1] (exact)."""
    return [sum((Fraction(math.comb(k, i), math.comb(n, i)) * p[i] for i in range(min(k, len(p) - 1) + 1)),
                Fraction(0)) for k in range(n + 1)]


def _packed(polys):
    """Polynomials (Fractions, power basis) as kernel input: (4, len, n+1) = hi, lo, error bound of hi, error
    bound of hi + lo, from their exact Bernstein coefficients; and each one's degree."""
    degs = np.array([len(p) - 1 for p in polys], dtype=np.int64)
    n = int(degs.max())
    out = np.zeros((4, len(polys), n + 1))
    for r, p in enumerate(polys):
        for i, x in enumerate(_bernstein(p, len(p) - 1)):
            hi = float(x)
            rest = x - Fraction(hi)
            lo = float(rest)
            out[0, r, i], out[1, r, i] = hi, lo
            out[2, r, i] = _up(abs(rest))
            out[3, r, i] = _up(abs(rest - Fraction(lo)))
    return out, degs


# ---------------------------------------------------------------- shapes and motions


def _length(value, field):
    x = _validate.scalar(value, field)
    lo, hi = _validate.LENGTH_RANGE
    if not lo <= x <= hi:
        raise InputError(f"{field}: a semi-axis must lie in [{lo:g}, {hi:g}], got {x!r}")
    return x


class Ellipse:
    """The elliptic disk ``x²/a² + y²/b² <= 1`` (semi-axes a along the local x axis, b along y)."""

    __slots__ = ("a", "b")

    def __init__(self, a, b):
        self.a = _length(a, "a")
        self.b = _length(b, "b")

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
        e = [[_poly(rows[i][j], f"{field}[{i}][{j}]") for j in range(3)] for i in range(3)]
        for j in range(2):
            if any(e[2][j]):
                raise InputError(f"{field}[2][{j}]: the last row must be [0, 0, w(t)]")
        self.entries = tuple(tuple(tuple(p) for p in row) for row in e)
        self.degree = max(len(p) - 1 for row in e for p in row)
        if not any(e[2][2]) or _vanishes_on_01(e[2][2]):
            raise InputError(f"{field}[2][2]: w(t) vanishes at some t in [0, 1]")
        det = _padd(_pmul(e[0][0], e[1][1]), _pmul(e[0][1], e[1][0]), -1)
        if not any(det) or _vanishes_on_01(det):
            raise InputError(f"{field}: the linear part [[{field}[0][0], {field}[0][1]], [{field}[1][0], "
                             f"{field}[1][1]]] is singular at some t in [0, 1]")

    @classmethod
    def from_kinematic_image(cls, d0, d1, d2, d3):
        """The rigid rational motion of the kinematic image d(t) (thesis eq. 2.3): polynomials d0..d3 (power
        basis), products formed exactly."""
        d = [_poly(x, f"d{i}") for i, x in enumerate((d0, d1, d2, d3))]
        sq2, sq3, c23 = _pmul(d[2], d[2]), _pmul(d[3], d[3]), _pmul(d[2], d[3])
        diag = _padd(sq2, sq3, -1)
        return cls([[diag, _pscale(c23, 2), _pscale(_padd(_pmul(d[0], d[3]), _pmul(d[1], d[2]), -1), 2)],
                    [_pscale(c23, -2), diag, _pscale(_padd(_pmul(d[0], d[2]), _pmul(d[1], d[3])), 2)],
                    [[0], [0], _padd(sq2, sq3)]])

    def translated(self, offset):
        """The same motion followed by the translation ``offset`` (exact)."""
        o = [_number(x, f"offset[{i}]") for i, x in enumerate(offset)]
        e = [list(r) for r in self.entries]
        for i in range(2):
            e[i][2] = _padd(e[i][2], _pscale(e[2][2], o[i]))
        return PlanarMotion(e)

    def at(self, t):
        """The matrix at time t (floats)."""
        t = Fraction(float(t))
        return np.array([[float(_peval(p, t)) for p in row] for row in self.entries])

    def reparametrized(self, t0, h):
        """The motion on [t0, t0 + h] as a motion in tau = (t - t0) / h (exact)."""
        out = object.__new__(PlanarMotion)
        out.entries = tuple(tuple(tuple(_taylor_shift(list(p), Fraction(t0), Fraction(h))) for p in row)
                            for row in self.entries)
        out.degree = self.degree
        return out

    def _polys(self, origin=(0, 0)):
        """L00, L01, L10, L11, v0 - o0 w, v1 - o1 w, w."""
        e = self.entries
        w = list(e[2][2])
        return [list(e[0][0]), list(e[0][1]), list(e[1][0]), list(e[1][1]),
                _padd(list(e[0][2]), _pscale(w, Fraction(origin[0])), -1),
                _padd(list(e[1][2]), _pscale(w, Fraction(origin[1])), -1), w]

    def __repr__(self):
        return f"PlanarMotion(degree {self.degree})"


class CycloidalMotion:
    """A rotation by an angle linear in t about the disk's centre, which moves linearly (thesis §2.4):
    ``x = Rot(angle + angular_velocity t) y + position + velocity t``.  With ``unit="pi"`` the angles are
    multiples of pi (so ``angular_velocity=Fraction(10, 9)`` is the thesis' 10π/9 exactly)."""

    __slots__ = ("angle", "angular_velocity", "position", "velocity", "unit")

    def __init__(self, position, velocity, angle=0.0, angular_velocity=0.0, *, unit="rad"):
        if unit not in ("rad", "pi"):
            raise InputError(f"unit: expected 'rad' or 'pi', got {unit!r}")
        self.position = tuple(_number(x, f"position[{i}]") for i, x in enumerate(_pair(position, "position")))
        self.velocity = tuple(_number(x, f"velocity[{i}]") for i, x in enumerate(_pair(velocity, "velocity")))
        self.angle = _number(angle, "angle")
        self.angular_velocity = _number(angular_velocity, "angular_velocity")
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
        """(PlanarMotion in tau on [t0, t0 + h], eta): cos and sin of the angle replaced by Taylor polynomials
        about the piece's middle with coefficients enclosed in interval arithmetic; eta is a proven bound of
        both errors on the piece."""
        from mpmath import iv
        iv.prec = 160
        t0, h = Fraction(t0), Fraction(h)

        def ival(x):
            return iv.mpf([str(x.numerator), str(x.numerator)]) / iv.mpf([str(x.denominator), str(x.denominator)])

        scale = iv.pi if self.unit == "pi" else iv.mpf(1)
        mid = (ival(self.angle) + ival(self.angular_velocity) * (ival(t0) + ival(h) / 2)) * scale
        gam = ival(self.angular_velocity) * ival(h) * scale      # the angle's change over the piece
        cm, sm = iv.cos(mid), iv.sin(mid)
        derivs = [(cm, sm), (-sm, cm), (-cm, -sm), (sm, -cm)]  # (cos, sin)^(k) at the middle, period 4
        cos_c, sin_c, err = [], [], Fraction(0)
        fact = iv.mpf(1)
        gk = iv.mpf(1)
        for k in range(degree + 1):
            if k:
                fact *= k
                gk *= gam
            for (dc, ds), out in ((derivs[k % 4], cos_c), (derivs[k % 4], sin_c)):
                pass
            cc = derivs[k % 4][0] * gk / fact
            ss = derivs[k % 4][1] * gk / fact
            for c, out in ((cc, cos_c), (ss, sin_c)):
                m = _mpf_fraction(c.mid)
                rad = max(abs(_mpf_fraction(c.a) - m), abs(_mpf_fraction(c.b) - m))
                out.append(m)
                err = max(err, rad) if False else err
            # each coefficient's enclosure radius, weighted by |tau - 1/2|^k <= 2^-k, adds to the error
            err += max(abs(_mpf_fraction(cc.a) - cos_c[-1]), abs(_mpf_fraction(cc.b) - cos_c[-1]),
                       abs(_mpf_fraction(ss.a) - sin_c[-1]), abs(_mpf_fraction(ss.b) - sin_c[-1])) / 2 ** k
        # Lagrange's remainder: |f^(n+1)| <= |gamma|^(n+1) for f = cos or sin of the angle, |tau - 1/2| <= 1/2
        rem = abs(gk * gam) / (fact * (degree + 1)) / 2 ** (degree + 1)
        err += _mpf_fraction(rem.b)
        centred = [Fraction(-1, 2), Fraction(1)]  # tau - 1/2

        def expand(coefs):
            out = [Fraction(0)]
            for c in reversed(coefs):
                out = _padd(_pmul(out, centred), [c])
            return out

        C, S = expand(cos_c), expand(sin_c)
        px = [self.position[0] + self.velocity[0] * t0, self.velocity[0] * h]
        py = [self.position[1] + self.velocity[1] * t0, self.velocity[1] * h]
        m = PlanarMotion([[C, _pscale(S, -1), px], [S, C, py], [0, 0, 1]])
        return m, err

    def __repr__(self):
        return (f"CycloidalMotion(position={[float(x) for x in self.position]}, velocity="
                f"{[float(x) for x in self.velocity]}, angle={float(self.angle)}, angular_velocity="
                f"{float(self.angular_velocity)}, unit={self.unit!r})")


def _mpf_fraction(x):
    """An mpmath mpf (finite) as an exact Fraction."""
    man, exp = x.man_exp
    return Fraction(int(man)) * (Fraction(2) ** int(exp))


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
