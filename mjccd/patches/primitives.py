"""Moving (rational) Bézier primitives: points, curves, triangular and tensor-product patches.

Every primitive has control points at the start (t = 0) and at the end (t = 1) of the
step; in between each control point moves on a straight line, and the weights of a
rational primitive stay fixed. Because of that, the (Euclidean) control points of any
sub-patch also move linearly, which is what the time-dependent inclusions rely on.

Control-point order:

* ``"quad"`` of degree (n, m): ``points[i, j]`` is the coefficient of
  ``B_i^n(u) B_j^m(v)``; flattened row-major (index ``i * (m + 1) + j``).
* ``"triangle"`` of degree n: index runs over ``i = 0..n`` then ``j = 0..n-i``, and the
  point is the coefficient of ``n!/(i! j! k!) u^i v^j w^k`` with ``k = n - i - j`` and
  ``w = 1 - u - v`` (domain ``u, v >= 0, u + v <= 1``).
* ``"curve"`` of degree n: coefficient of ``B_i^n(u)``.
* ``"point"``: a single moving point (no parameter).
"""
from dataclasses import dataclass
from fractions import Fraction
from functools import lru_cache
from math import factorial

import numpy as np

from mjccd.errors import InputError

KINDS = ("point", "curve", "triangle", "quad")
KIND_CODE = {name: code for code, name in enumerate(KINDS)}


def _finite_array(value, field):
    try:
        arr = np.array(value, dtype=np.float64)
    except (TypeError, ValueError):
        raise InputError(f"`{field}`: expected an array of numbers, got {value!r}") from None
    if not np.all(np.isfinite(arr)):
        raise InputError(f"`{field}`: contains NaN or infinity")
    return arr


def _check_points(value, shape, field):
    arr = _finite_array(value, field)
    if arr.shape != shape:
        raise InputError(f"`{field}`: expected shape {shape}, got {arr.shape}")
    return arr


def _triangle_degree(count, field):
    for n in (1, 2, 3):
        if (n + 1) * (n + 2) // 2 == count:
            return n
    raise InputError(
        f"`{field}`: a triangular patch of degree 1, 2 or 3 has 3, 6 or 10 control points, "
        f"got {count}")


def triangle_indices(n):
    """(i, j, k) exponents of a degree-n triangular patch, in control-point order."""
    return [(i, j, n - i - j) for i in range(n + 1) for j in range(n + 1 - i)]


@dataclass(frozen=True, eq=False)
class Patch:
    """A moving primitive whose control points travel linearly from t = 0 to t = 1.

    Attributes:
        kind: ``"point"``, ``"curve"``, ``"triangle"`` or ``"quad"``.
        degree: ``()`` for a point, ``(n,)`` for curves and triangles, ``(n, m)`` for quads.
        points_t0: (N, 3) control points at t = 0, world frame.
        points_t1: (N, 3) control points at t = 1, world frame.
        weights: (N,) positive weights (all ones for a polynomial primitive).
    """

    kind: str
    degree: tuple
    points_t0: np.ndarray
    points_t1: np.ndarray
    weights: np.ndarray

    # ----------------------------------------------------------------- constructors
    @classmethod
    def _build(cls, kind, degree, p0, p1, velocities, weights, shape, field):
        p0 = _check_points(p0, shape, f"{field}.points_t0")
        if p1 is not None and velocities is not None:
            raise InputError(f"`{field}`: give either `points_t1` or `velocities`, not both")
        if p1 is not None:
            p1 = _check_points(p1, shape, f"{field}.points_t1")
        elif velocities is not None:
            p1 = p0 + _check_points(velocities, shape, f"{field}.velocities")
        else:
            p1 = p0.copy()
        count = int(np.prod(shape[:-1]))
        if weights is None:
            w = np.ones(count)
        else:
            w = _finite_array(weights, f"{field}.weights")
            if w.shape != shape[:-1]:
                raise InputError(
                    f"`{field}.weights`: expected shape {shape[:-1]}, got {w.shape}")
            w = w.reshape(count)
            bad = np.nonzero(w <= 0.0)[0]
            if len(bad):
                raise InputError(
                    f"`{field}.weights`: weights must be positive (the convex-hull property "
                    f"needs it), got {w[bad[0]]!r} at index {int(bad[0])}")
        p0 = np.ascontiguousarray(p0.reshape(count, 3))
        p1 = np.ascontiguousarray(p1.reshape(count, 3))
        return cls(kind, degree, p0, p1, np.ascontiguousarray(w))

    @classmethod
    def point(cls, point_t0, point_t1=None, *, velocity=None):
        """A moving point (the vertex of a vertex-face query)."""
        p0 = _check_points(point_t0, (3,), "point.points_t0")[None]
        p1 = None if point_t1 is None else _check_points(point_t1, (3,), "point.points_t1")[None]
        v = None if velocity is None else _check_points(velocity, (3,), "point.velocities")[None]
        return cls._build("point", (), p0, p1, v, None, (1, 3), "point")

    @classmethod
    def curve(cls, points_t0, points_t1=None, *, velocities=None, weights=None):
        """A moving (rational) Bézier curve of degree 1-3; points: (n+1, 3)."""
        arr = _finite_array(points_t0, "curve.points_t0")
        if arr.ndim != 2 or arr.shape[1] != 3 or not 2 <= arr.shape[0] <= 4:
            raise InputError(
                f"`curve.points_t0`: expected shape (n+1, 3) with n in 1..3, got {arr.shape}")
        n = arr.shape[0] - 1
        return cls._build("curve", (n,), arr, points_t1, velocities, weights, (n + 1, 3),
                          "curve")

    @classmethod
    def triangle(cls, points_t0, points_t1=None, *, velocities=None, weights=None):
        """A moving triangular (rational) Bézier patch of degree 1-3; points: (N, 3)."""
        arr = _finite_array(points_t0, "triangle.points_t0")
        if arr.ndim != 2 or arr.shape[1] != 3:
            raise InputError(f"`triangle.points_t0`: expected shape (N, 3), got {arr.shape}")
        n = _triangle_degree(arr.shape[0], "triangle.points_t0")
        return cls._build("triangle", (n,), arr, points_t1, velocities, weights,
                          (arr.shape[0], 3), "triangle")

    @classmethod
    def quad(cls, points_t0, points_t1=None, *, velocities=None, weights=None):
        """A moving tensor-product (rational) Bézier patch; points: (n+1, m+1, 3), n, m in 1..3."""
        arr = _finite_array(points_t0, "quad.points_t0")
        if (arr.ndim != 3 or arr.shape[2] != 3 or not 2 <= arr.shape[0] <= 4
                or not 2 <= arr.shape[1] <= 4):
            raise InputError(
                f"`quad.points_t0`: expected shape (n+1, m+1, 3) with n, m in 1..3, "
                f"got {arr.shape}")
        n, m = arr.shape[0] - 1, arr.shape[1] - 1
        return cls._build("quad", (n, m), arr, points_t1, velocities, weights,
                          (n + 1, m + 1, 3), "quad")

    # ------------------------------------------------------------------- properties
    @property
    def rational(self):
        """True when the weights are not all equal."""
        return bool(np.ptp(self.weights) > 0.0)

    @property
    def velocities(self):
        """(N, 3) control-point displacement over the step."""
        return self.points_t1 - self.points_t0

    def control_points(self, t):
        """(N, 3) Euclidean control points at time t."""
        return (1.0 - t) * self.points_t0 + t * self.points_t1

    def homogeneous(self):
        """(N, 7) rows ``[w p_t0, w, w p_t1]``: the form the solver subdivides."""
        w = self.weights[:, None]
        return np.ascontiguousarray(
            np.hstack([w * self.points_t0, w, w * self.points_t1]))

    # ------------------------------------------------------------------- evaluation
    def basis(self, u, v=0.0):
        """(N,) polynomial basis values at (u, v), in control-point order."""
        if self.kind == "point":
            return np.ones(1)
        if self.kind == "curve":
            return _bernstein(self.degree[0], u)
        if self.kind == "quad":
            n, m = self.degree
            return np.outer(_bernstein(n, u), _bernstein(m, v)).ravel()
        n = self.degree[0]
        w = 1.0 - u - v
        return np.array([factorial(n) / (factorial(i) * factorial(j) * factorial(k))
                         * u ** i * v ** j * w ** k for i, j, k in triangle_indices(n)])

    def evaluate(self, u=0.0, v=0.0, t=0.0):
        """World point S(u, v, t): rational evaluation in homogeneous coordinates."""
        b = self.basis(u, v) * self.weights
        return b @ self.control_points(t) / b.sum()

    def subdivide(self):
        """Children over the halved domain, exact (de Casteljau in homogeneous form).

        Returns a list of ``(child, corner, size, orientation)``: the child covers the
        parameter region described by :func:`child_regions` (quads and curves: squares /
        intervals; triangles: the three corner triangles and the flipped middle one).
        """
        mats = subdivision_matrices(self.kind, self.degree)
        h = self.homogeneous()
        out = []
        for k, mat in enumerate(mats):
            c = mat @ h
            w = c[:, 3]
            child = Patch(self.kind, self.degree, c[:, :3] / w[:, None],
                          c[:, 4:7] / w[:, None], w)
            out.append((child,) + child_regions(self.kind)[k])
        return out


def _bernstein(n, x):
    return np.array([factorial(n) / (factorial(i) * factorial(n - i)) * x ** i * (1 - x) ** (n - i)
                     for i in range(n + 1)])


def child_regions(kind):
    """Per child: (corner offset in units of the parent size, size factor, orientation flip).

    A region is ``(u0, v0, h, o)``; a triangle region has vertices ``(u0, v0)``,
    ``(u0 + o h, v0)``, ``(u0, v0 + o h)``; a quad region is ``[u0, u0+h] x [v0, v0+h]``.
    """
    if kind == "point":
        return [((0.0, 0.0), 1.0, 1)]
    if kind == "curve":
        return [((0.0, 0.0), 0.5, 1), ((0.5, 0.0), 0.5, 1)]
    if kind == "quad":
        return [((0.5 * iu, 0.5 * iv), 0.5, 1) for iu in (0, 1) for iv in (0, 1)]
    return [((0.0, 0.0), 0.5, 1), ((0.5, 0.0), 0.5, 1), ((0.0, 0.5), 0.5, 1),
            ((0.5, 0.5), 0.5, -1)]


def _blossom_curve(n, args):
    """Coefficients (over the n+1 control points) of the curve blossom at ``args``."""
    rows = [[Fraction(int(i == j)) for j in range(n + 1)] for i in range(n + 1)]
    for x in args:
        rows = [[(1 - x) * a + x * b for a, b in zip(rows[i], rows[i + 1])]
                for i in range(len(rows) - 1)]
    return rows[0]


def _blossom_triangle(n, args):
    """Coefficients of the triangle blossom at barycentric ``args`` (each (u, v, w))."""
    idx = triangle_indices(n)
    pos = {ijk: r for r, ijk in enumerate(idx)}
    size = len(idx)
    level = {ijk: [Fraction(int(pos[ijk] == c)) for c in range(size)] for ijk in idx}
    deg = n
    for (lu, lv, lw) in args:
        deg -= 1
        nxt = {}
        for i in range(deg + 1):
            for j in range(deg + 1 - i):
                k = deg - i - j
                a, b, c = level[(i + 1, j, k)], level[(i, j + 1, k)], level[(i, j, k + 1)]
                nxt[(i, j, k)] = [lu * x + lv * y + lw * z for x, y, z in zip(a, b, c)]
        level = nxt
    return level[(0, 0, 0)]


@lru_cache(maxsize=None)
def _subdivision_matrices(kind, degree):
    half = Fraction(1, 2)
    if kind == "point":
        return np.ones((1, 1, 1))
    if kind in ("curve", "quad"):
        def halves(n):
            out = []
            for lo in (Fraction(0), half):
                hi = lo + half
                out.append([_blossom_curve(n, [lo] * (n - r) + [hi] * r) for r in range(n + 1)])
            return [np.array(m, dtype=np.float64) for m in out]
        if kind == "curve":
            return np.array(halves(degree[0]))
        hu, hv = halves(degree[0]), halves(degree[1])
        return np.array([np.kron(hu[iu], hv[iv]) for iu in (0, 1) for iv in (0, 1)])
    n = degree[0]
    mats = []
    for (cu, cv), size, flip in child_regions("triangle"):
        corner = (Fraction(cu), Fraction(cv))
        s = Fraction(size) * flip

        def bary(du, dv):
            u, v = corner[0] + s * du, corner[1] + s * dv
            return (u, v, 1 - u - v)
        pu, pv, pw = bary(1, 0), bary(0, 1), bary(0, 0)
        mats.append([_blossom_triangle(n, [pu] * i + [pv] * j + [pw] * k)
                     for i, j, k in triangle_indices(n)])
    return np.array(mats, dtype=np.float64)


def subdivision_matrices(kind, degree):
    """(C, N, N) exact midpoint-subdivision matrices: child k control points = M[k] @ parent.

    Entries are dyadic rationals computed with exact fractions (blossoming), so the
    float64 matrices are exact; rows are non-negative and sum to one.
    """
    mats = _subdivision_matrices(kind, tuple(degree))
    mats.setflags(write=False)
    return mats


def corner_indices(kind, degree):
    """Control-point indices ``[origin, u-end, v-end, uv-end]`` (-1 where absent) for OBB axes."""
    if kind == "point":
        return np.array([0, -1, -1, -1], dtype=np.int64)
    if kind == "curve":
        return np.array([0, degree[0], -1, -1], dtype=np.int64)
    if kind == "quad":
        n, m = degree
        return np.array([0, n * (m + 1), m, n * (m + 1) + m], dtype=np.int64)
    idx = triangle_indices(degree[0])
    n = degree[0]
    return np.array([idx.index((0, 0, n)), idx.index((n, 0, 0)), idx.index((0, n, 0)), -1],
                    dtype=np.int64)
