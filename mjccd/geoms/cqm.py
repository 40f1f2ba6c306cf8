"""Composite quadric models (Choi 2008, chapter 6): first contact of solids bounded by quadric and planar faces,
conic and line edges and vertices, under exact rational motions.

A model lists its boundary elements, as the thesis does: faces (a quadric or a plane, trimmed by inequalities),
edges (a plane cut with a quadric: a conic; or with a second plane: a line) and vertices.  Two models first touch
when a pair of their elements first shares a point.  Each element pair is one of the thesis' subproblems (F-F,
F-E, E-E, F-V); the pairs that cannot hold the first contact of generic motions are left out by its exclusion
rules (a plane face against a plane face, a cylinder or a line edge).  Each subproblem is reduced, exactly over
the rationals, to one polynomial in t whose roots hold every time the two extended elements touch:

* F-F: the discriminant in lambda of ``det(lambda A(t) - B(t))`` (a double root of the pencil);
* F-E and E-E in the edge's plane: two conics touching (the same discriminant in the plane), a conic and a line
  (the line on the dual conic), or the resultant of the two curves' traces on the line where the planes meet;
* F-V: the vertex on the face.

The roots in [0, t_max] are isolated exactly (sympy, rational intervals), then taken in order: at each one the
touching point is computed to 60 digits and tested against both elements' trims.  The first root whose point
lies on both trimmed elements is the first contact.  A test that 60 digits cannot decide (a point on a trim's
edge to 1e-18, a pencil singular at that time with touching sections, a polynomial that vanishes for every t)
makes the answer ``uncertain``, with a bracket from that root to the next proven contact, so that no first
contact is ever certified wrongly.

The status at t = 0 is found with the same solver: the second model approaches its start pose along a world axis
from beyond both bounding balls; an approach free of contact proves them separate.  The contact intervals
(:func:`cqm_collision_intervals`) come from every proven touch and the status between two of them.
"""
import math
from fractions import Fraction
from typing import NamedTuple

import numpy as np

from mjccd.ccd import Contact
from mjccd.errors import InputError, InputTypeError
from mjccd.geoms.exact import number
from mjccd.motion import LinearAffine, Rational, Rigid, Static

DIGITS = 60                # working precision of the touching points
ROOT_DIGITS = 50          # the candidate times are isolated to 1e-50
TIE = 1e-18                # a trim within this (relative) of zero is undecided
# the start status's approach directions: rational unit vectors along no axis and no plane of symmetry
_APPROACHES = tuple(tuple(sign * Fraction(c, 13) for c in v) for v in ((3, 4, 12), (-4, 12, 3), (12, -3, 4))
                    for sign in (1, -1))


def _sympy():
    """sympy and mpmath, imported on first use (``import mjccd`` stays quick)."""
    import mpmath
    import sympy
    return sympy, mpmath


# ---------------------------------------------------------------- surfaces and elements


class Surface(NamedTuple):
    """A quadric ``X^T Q X`` (4x4 symmetric) or a plane ``p . X`` (4,) of homogeneous points X = (x, y, z, 1);
    the solid side, where it trims, is ``<= 0``."""

    form: tuple   # exact Fractions: 4 rows of 4 (quadric) or 4 (plane)
    is_plane: bool


def _fractions(values, shape, field):
    a = np.asarray(values, dtype=object)
    if a.shape != shape:
        raise InputError(f"{field}: expected shape {shape}, got {a.shape}")
    return a


def quadric(matrix, field="matrix"):
    """The quadric surface ``X^T Q X = 0`` of a symmetric 4x4 matrix (its inside ``<= 0``)."""
    if isinstance(matrix, Surface):
        return matrix
    m = _fractions(matrix, (4, 4), field)
    q = tuple(tuple(number(m[i, j], f"{field}[{i}][{j}]") for j in range(4)) for i in range(4))
    if any(q[i][j] != q[j][i] for i in range(4) for j in range(i)):
        raise InputError(f"{field}: a quadric's matrix must be symmetric")
    if not any(q[i][j] for i in range(3) for j in range(3)):
        raise InputError(f"{field}: no quadratic part (a plane is given with plane())")
    return Surface(q, False)


def plane(normal, offset, field="plane"):
    """The plane ``normal . x = offset`` (its inside: ``normal . x <= offset``)."""
    n = _fractions(normal, (3,), f"{field}.normal")
    p = tuple(number(n[i], f"{field}.normal[{i}]") for i in range(3)) + (-number(offset, f"{field}.offset"),)
    if not any(p[:3]):
        raise InputError(f"{field}.normal: must not be zero")
    return Surface(p, True)


def ellipsoid(a, b, c):
    """``x^2/a^2 + y^2/b^2 + z^2/c^2 = 1``."""
    a, b, c = (_positive(v, name) for v, name in ((a, "a"), (b, "b"), (c, "c")))
    return _diagonal(1 / a ** 2, 1 / b ** 2, 1 / c ** 2, -1)


def elliptic_cylinder(a, b):
    """``x^2/a^2 + y^2/b^2 = 1``, its axis along local z (MuJoCo's cylinders)."""
    a, b = _positive(a, "a"), _positive(b, "b")
    return _diagonal(1 / a ** 2, 1 / b ** 2, 0, -1)


def outside(surface):
    """The same surface with its inside turned out: a concave face's trim, a cut-out's wall."""
    s = surface
    if s.is_plane:
        return Surface(tuple(-x for x in s.form), True)
    return Surface(tuple(tuple(-x for x in row) for row in s.form), False)


def _positive(v, field):
    x = number(v, field)
    if x <= 0:
        raise InputError(f"{field}: must be > 0, got {float(x)}")
    return x


def _diagonal(*d):
    return Surface(tuple(tuple(Fraction(d[i]) if i == j else Fraction(0) for j in range(4)) for i in range(4)),
                   False)


def _surface(value, field):
    if isinstance(value, Surface):
        return value
    raise InputTypeError(f"{field}: expected a surface (quadric(), plane(), ellipsoid(), elliptic_cylinder()), "
                         f"got {type(value).__name__}")


class Face(NamedTuple):
    """A boundary face: the part of ``surface`` where every trim is ``<= 0``."""

    surface: Surface
    trims: tuple = ()
    name: str = "face"


class Edge(NamedTuple):
    """A boundary edge: ``plane`` cut with ``surface`` (a quadric: a conic; a plane: a line), where every trim is
    ``<= 0``."""

    plane: Surface
    surface: Surface
    trims: tuple = ()
    name: str = "edge"


class Vertex(NamedTuple):
    """A boundary vertex at a local point."""

    point: tuple
    name: str = "vertex"


class CompositeQuadric:
    """A solid bounded by quadric and planar faces, conic and line edges and vertices (the thesis' CQM).

    ``bound``: the radius of a ball about the local origin that holds the solid (the start status approaches
    from beyond it; each vertex is checked against it).  ``convex``: the solid is convex (MuJoCo's shapes are),
    which lets the start status decide more (see :func:`_status_at`).  Every element is closed: its trims hold
    with equality on its border.
    """

    def __init__(self, faces, edges=(), vertices=(), *, bound, name="model", convex=False):
        self.name = str(name)
        self.convex = bool(convex)
        self.bound = float(_positive(bound, f"{name}.bound"))
        self.faces = tuple(self._face(f, f"{name}.faces[{i}]") for i, f in enumerate(faces))
        self.edges = tuple(self._edge(e, f"{name}.edges[{i}]") for i, e in enumerate(edges))
        self.vertices = tuple(self._vertex(v, f"{name}.vertices[{i}]") for i, v in enumerate(vertices))
        if not self.faces:
            raise InputError(f"{name}.faces: a model needs at least one face")

    @staticmethod
    def _trims(trims, field):
        return tuple(_surface(s, f"{field}.trims[{k}]") for k, s in enumerate(trims))

    def _face(self, f, field):
        if not isinstance(f, Face):
            raise InputTypeError(f"{field}: expected a Face, got {type(f).__name__}")
        return Face(_surface(f.surface, f"{field}.surface"), self._trims(f.trims, field), str(f.name))

    def _edge(self, e, field):
        if not isinstance(e, Edge):
            raise InputTypeError(f"{field}: expected an Edge, got {type(e).__name__}")
        p = _surface(e.plane, f"{field}.plane")
        if not p.is_plane:
            raise InputError(f"{field}.plane: an edge lies in a plane (plane())")
        return Edge(p, _surface(e.surface, f"{field}.surface"), self._trims(e.trims, field), str(e.name))

    def _vertex(self, v, field):
        if not isinstance(v, Vertex):
            raise InputTypeError(f"{field}: expected a Vertex, got {type(v).__name__}")
        p = _fractions(v.point, (3,), f"{field}.point")
        point = tuple(number(p[i], f"{field}.point[{i}]") for i in range(3))
        if math.sqrt(sum(float(x) ** 2 for x in point)) > self.bound:
            raise InputError(f"{field}.point: lies outside the model's bound {self.bound}")
        return Vertex(point, str(v.name))


def capped_cylinder(a, b, half_length, *, name="cylinder"):
    """An elliptic cylinder ``x^2/a^2 + y^2/b^2 <= 1``, ``|z| <= half_length``: side, two caps, two rims
    (Example 6.4's bodies; MuJoCo's cylinder when a == b)."""
    side, h = elliptic_cylinder(a, b), _positive(half_length, "half_length")
    top, bottom = plane((0, 0, 1), h), plane((0, 0, -1), h)
    return CompositeQuadric(
        [Face(side, (top, bottom), "side"), Face(bottom, (side,), "face -z"), Face(top, (side,), "face +z")],
        [Edge(bottom, side, (), "rim -z"), Edge(top, side, (), "rim +z")],
        bound=_norm(max(number(a, "a"), number(b, "b")), h), name=name, convex=True)


def ellipsoid_model(a, b, c, *, name="ellipsoid"):
    """An ellipsoid (a sphere when a == b == c): one face."""
    return CompositeQuadric([Face(ellipsoid(a, b, c), (), "surface")],
                            bound=float(max(number(a, "a"), number(b, "b"), number(c, "c"))) * (1 + 1e-9),
                            name=name, convex=True)


def capsule(radius, half_length, *, name="capsule"):
    """MuJoCo's capsule along local z: a cylinder side and two half-spheres, and the two circles where they
    meet."""
    r, h = _positive(radius, "radius"), _positive(half_length, "half_length")
    side = elliptic_cylinder(r, r)
    top, bottom = plane((0, 0, 1), h), plane((0, 0, -1), h)
    ends = [Surface(tuple(tuple(x for x in row) for row in
                          ((1, 0, 0, 0), (0, 1, 0, 0), (0, 0, 1, -z), (0, 0, -z, z * z - r * r))), False)
            for z in (h, -h)]
    return CompositeQuadric(
        [Face(side, (top, bottom), "side"), Face(ends[0], (outside(top),), "cap +z"),
         Face(ends[1], (outside(bottom),), "cap -z")],
        [Edge(top, side, (), "rim +z"), Edge(bottom, side, (), "rim -z")], bound=_norm(r, h + r), name=name,
        convex=True)


def box(hx, hy, hz, *, name="box"):
    """MuJoCo's box of half sizes (hx, hy, hz): six faces, twelve edges and eight vertices."""
    h = [_positive(v, f) for v, f in ((hx, "hx"), (hy, "hy"), (hz, "hz"))]
    faces, edges, vertices = [], [], []
    sides = {}
    for axis in range(3):
        for sign in (1, -1):
            n = [0, 0, 0]
            n[axis] = sign
            sides[axis, sign] = plane(n, h[axis])
    label = "xyz"
    for (axis, sign), p in sides.items():
        trims = tuple(q for (ax, _), q in sides.items() if ax != axis)
        faces.append(Face(p, trims, f"face {'+' if sign > 0 else '-'}{label[axis]}"))
    for a1 in range(3):
        for a2 in range(a1 + 1, 3):
            free = 3 - a1 - a2
            for s1 in (1, -1):
                for s2 in (1, -1):
                    edges.append(Edge(sides[a1, s1], sides[a2, s2], (sides[free, 1], sides[free, -1]),
                                      f"edge {'+' if s1 > 0 else '-'}{label[a1]}{'+' if s2 > 0 else '-'}{label[a2]}"
                                      f" (along {label[free]})"))
    for sx in (1, -1):
        for sy in (1, -1):
            for sz in (1, -1):
                vertices.append(Vertex((sx * h[0], sy * h[1], sz * h[2]), "vertex " + "".join(
                    ("+" if v > 0 else "-") + axis for v, axis in zip((sx, sy, sz), label))))
    return CompositeQuadric(faces, edges, vertices, bound=_norm(*h), name=name, convex=True)


def _norm(*xs):
    """A radius just above the Euclidean norm of the exact numbers xs."""
    return math.sqrt(sum(float(x) ** 2 for x in xs)) * (1 + 1e-9) + 1e-300


# ---------------------------------------------------------------- motions as polynomial matrices


def _rot_poly(sp, q):
    """rot(q) of an unnormalised quaternion [w, x, y, z] (sympy expressions): rot(q) rot(q)^T = |q|^4 I."""
    w, x, y, z = q
    return sp.Matrix([[w * w + x * x - y * y - z * z, 2 * (x * y - w * z), 2 * (x * z + w * y)],
                      [2 * (x * y + w * z), w * w - x * x + y * y - z * z, 2 * (y * z - w * x)],
                      [2 * (x * z - w * y), 2 * (y * z + w * x), w * w - x * x - y * y + z * z]])


def _homogeneous(sp, L, v, w):
    M = sp.zeros(4, 4)
    M[:3, :3] = L
    M[:3, 3] = v
    M[3, 3] = w
    return M.applyfunc(sp.expand)


def motion_matrix(motion, field="motion", turns=True):
    """(M, N): the homogeneous 4x4 polynomial matrix M(t) of local to world (sympy, exact for the motion's
    doubles) and an exact inverse N(t) (N M = c(t) I with c > 0): for a pose lerp ``[[rot(q)^T, -rot(q)^T p],
    [0, |q|^2]]``, of degree 3, since ``rot(q)`` is orthogonal up to ``|q|^4`` exactly; otherwise the
    adjugate.  ``turns=False``: a pose lerp's orientation left out (a ball centred on the origin, which no
    rotation changes), so that its matrices are of degree 1."""
    sp, _ = _sympy()
    t = sp.Symbol("t")
    R = sp.Rational

    def ex(x):
        return R(Fraction(float(x)))

    def poly(coeffs):
        return sum((ex(c) * t ** k for k, c in enumerate(coeffs)), sp.Integer(0))

    if type(motion) in (Static, Rigid):
        if type(motion) is Static:
            q = [ex(c) for c in motion.quaternion]
            p = sp.Matrix([ex(c) for c in motion.position])
        else:
            q = [(1 - t) * ex(a) + t * ex(b) for a, b in zip(motion.quaternion0, motion.quaternion1)]
            p = sp.Matrix([(1 - t) * ex(a) + t * ex(b) for a, b in zip(motion.position0, motion.position1)])
        rot, n2 = _rot_poly(sp, q), sp.expand(sum(c * c for c in q))
        if not turns:
            rot, n2 = sp.eye(3), sp.Integer(1)
        return _homogeneous(sp, rot, p * n2, n2), _homogeneous(sp, rot.T, -rot.T * p, n2)
    if type(motion) is Rational:
        rd, vd = poly(motion.rotation_denominator), poly(motion.translation_denominator)
        L = sp.Matrix(3, 3, lambda i, j: poly(motion.rotation[i][j]) * vd)
        v = sp.Matrix([poly(motion.translation[i]) * rd for i in range(3)])
        M = _homogeneous(sp, L, v, rd * vd)
    elif type(motion) is LinearAffine:
        L = sp.Matrix(3, 3, lambda i, j: (1 - t) * ex(motion.start[i, j]) + t * ex(motion.end[i, j]))
        v = sp.Matrix([(1 - t) * ex(motion.start[i, 3]) + t * ex(motion.end[i, 3]) for i in range(3)])
        M = _homogeneous(sp, L, v, sp.Integer(1))
    else:
        raise InputTypeError(f"{field}: the composite quadric solver takes Static, Rigid, Rational and "
                             f"LinearAffine motions, got {type(motion).__name__}")
    return M, M.adjugate().applyfunc(sp.expand)


# ---------------------------------------------------------------- subproblems


class _Pair:
    """The frames of one pair of models: ``to_a`` maps B's local points into A's frame, ``to_b`` the other way
    (both polynomial in t, each up to a nonzero factor)."""

    def __init__(self, A, B):
        sp, _ = _sympy()
        self.t = sp.Symbol("t")
        self.to_a = (A[1] * B[0]).applyfunc(sp.expand)
        self.to_b = (B[1] * A[0]).applyfunc(sp.expand)


def _matrix(sp, s):
    R = sp.Rational
    if s.is_plane:
        return sp.Matrix([[R(x) for x in s.form]])        # 1x4
    return sp.Matrix([[R(x) for x in row] for row in s.form])


def _in_frame(sp, s, T):
    """Surface s of the other body seen in this frame through T (points here -> points there)."""
    m = _matrix(sp, s)
    return (m * T if s.is_plane else T.T * m * T).applyfunc(sp.expand)


def _plane_basis(sp, p):
    """A 4x3 exact basis of the homogeneous points on plane p (1x4)."""
    return sp.Matrix.hstack(*p.nullspace())


def _adj_form(sp, C, ell):
    """ell^T adj(C) ell: zero exactly when the line ell touches the conic C (3x3)."""
    return sp.expand((ell.T * C.adjugate() * ell)[0, 0])


def _discriminant(c):
    """The discriminant of ``c[0] x^n + ... + c[n]`` (n <= 4; the c are sympy Polys in t), by its closed form:
    a few products, where the subresultant sequence of big rational coefficients takes minutes."""
    n = len(c) - 1
    if n == 2:
        a, b, cc = c
        return b * b - 4 * a * cc
    if n == 3:
        a, b, cc, d = c
        return b ** 2 * cc ** 2 - 4 * a * cc ** 3 - 4 * b ** 3 * d - 27 * a ** 2 * d ** 2 + 18 * a * b * cc * d
    a, b, cc, d, e = c
    return (256 * a ** 3 * e ** 3 - 192 * a ** 2 * b * d * e ** 2 - 128 * a ** 2 * cc ** 2 * e ** 2
            + 144 * a ** 2 * cc * d ** 2 * e - 27 * a ** 2 * d ** 4 + 144 * a * b ** 2 * cc * e ** 2
            - 6 * a * b ** 2 * d ** 2 * e - 80 * a * b * cc ** 2 * d * e + 18 * a * b * cc * d ** 3
            + 16 * a * cc ** 4 * e - 4 * a * cc ** 3 * d ** 2 - 27 * b ** 4 * e ** 2 + 18 * b ** 3 * cc * d * e
            - 4 * b ** 3 * d ** 3 - 4 * b ** 2 * cc ** 3 * e + b ** 2 * cc ** 2 * d ** 2)


def _polys_of_pencil(sp, A, B, lam, t):
    """The polynomials in t whose roots hold every time the pencil ``det(lam A - B)`` has a new multiple root or
    vanishes: its coefficients' common factor (the times it vanishes), the discriminant of what is left once
    the roots lam = 0 that hold for every t are divided out, and where a root meets lam = 0 or infinity.  The
    second value says whether a root is multiple for every t (two spheres share the circle at infinity): such
    a root is tested where it is met (:meth:`_Solver._pencil`)."""
    f = _pencil_det(sp, A, B, lam, t)
    coeffs = [sp.Poly(x, t) for x in sp.Poly(f.as_expr(), lam).all_coeffs()]
    while len(coeffs) > 1 and coeffs[-1].is_zero:     # a root lam = 0 for every t: B is singular
        coeffs.pop()
    while len(coeffs) > 1 and coeffs[0].is_zero:      # a root at infinity for every t: A is singular
        coeffs.pop(0)
    if len(coeffs) == 1:
        return [coeffs[0]], False
    content = coeffs[0]
    for x in coeffs[1:]:
        content = sp.gcd(content, x)
    out = [content, coeffs[0], coeffs[-1]]
    disc = _discriminant(coeffs) if len(coeffs) >= 3 else None
    if disc is not None:
        out.append(disc)
    repeated = disc is not None and disc.is_zero
    return [p for p in out if p.degree() > 0], repeated

def _det(M):
    """The determinant of a small square matrix of sympy Polys (lists of rows), by cofactors: ring products only,
    far quicker than sympy's matrices of expressions."""
    n = len(M)
    if n == 1:
        return M[0][0]
    out = M[0][0] * 0
    for j in range(n):
        if M[0][j] == 0:
            continue
        term = M[0][j] * _det([[row[c] for c in range(n) if c != j] for row in M[1:]])
        out = out - term if j % 2 else out + term
    return out


def _mp_det(M):
    """det of a small mp matrix by cofactors (mpmath's LU fails on some exactly singular ones)."""
    return _det([[M[i, j] for j in range(M.cols)] for i in range(M.rows)])


def _as_polys(sp, M, *gens):
    return [[sp.Poly(M[i, j], *gens) for j in range(M.cols)] for i in range(M.rows)]


def _pencil_det(sp, A, B, lam, t):
    """det(lam A - B) as a Poly in (lam, t)."""
    a, b = _as_polys(sp, A, lam, t), _as_polys(sp, B, lam, t)
    L = sp.Poly(lam, lam, t)
    return _det([[L * a[i][j] - b[i][j] for j in range(A.cols)] for i in range(A.rows)])


def _matmul(X, Y):
    return [[sum((X[i][k] * Y[k][j] for k in range(1, len(Y))), X[i][0] * Y[0][j]) for j in range(len(Y[0]))]
            for i in range(len(X))]


def _binary_coefficients(c, d, K):
    """The coefficients (s^d first) of the binary form of degree d on the line ``u = K (s, 1)``: ``c K (s, 1)``
    for a line c (1x3), ``(s, 1) K^T c K (s, 1)^T`` for a conic c (3x3); all Poly lists."""
    if d == 1:
        row = _matmul(c, K)[0]
        return [row[0], row[1]]
    Kt = [[K[i][j] for i in range(3)] for j in range(2)]
    G = _matmul(_matmul(Kt, c), K)
    return [G[0][0], G[0][1] + G[1][0], G[1][1]]


def _binary_resultant(f, g):
    """The resultant of two binary forms by their coefficients (highest first; leading ones may vanish, roots at
    infinity counted): the determinant of their Sylvester matrix."""
    m, n = len(f) - 1, len(g) - 1
    zero = f[0] * 0
    S = [[zero] * (m + n) for _ in range(m + n)]
    for r in range(n):
        for k, c in enumerate(f):
            S[r][r + k] = c
    for r in range(m):
        for k, c in enumerate(g):
            S[n + r][r + k] = c
    return _det(S)


class _Subproblem(NamedTuple):
    """One element pair: its polynomials in t, the check of a root t0, and the moving touch where it persists."""

    kind: str             # "F-F", "F-E", "E-F", "E-E", "F-V", "V-F"
    elem_a: object
    elem_b: object
    polys: list           # sympy Polys in t whose roots hold every touch of the extended elements
    check: object         # t0 (mpf) -> list of (verdict, point in A's frame (mp 3-vector) or None)
    persistent: tuple = None   # where a poly vanishes for every t: (touching point X(t) (4x1), in A's frame?)


class _Verdict:
    """A touching point on both trimmed elements (YES), off one of them (NO), or too close to a trim to say."""

    YES, NO, UNDECIDED = 1, 0, -1


def _ruled(s):
    """A plane, or a quadric whose quadratic part is singular (a cylinder or a cone): no generic point contact
    with a plane."""
    if s.is_plane:
        return True
    q = np.array([[float(x) for x in row[:3]] for row in s.form[:3]])
    return abs(np.linalg.det(q)) <= 1e-12 * max(np.abs(q).max(), 1e-300) ** 3


class _Numeric:
    """The polynomial matrices of one pair evaluated at a time t0, to DIGITS digits."""

    def __init__(self, sp, mp, pair):
        self.sp, self.mp, self.pair = sp, mp, pair

    def at(self, expr_matrix, t0):
        t = self.pair.t
        rows, cols = expr_matrix.shape
        return self.mp.matrix([[self.value(expr_matrix[i, j], t, t0) for j in range(cols)] for i in range(rows)])

    def value(self, e, t, t0):
        p = self.sp.Poly(e, t)
        acc = self.mp.mpf(0)
        for c in p.all_coeffs():
            acc = acc * t0 + self.mp.mpf(c.p) / c.q
        return acc


def _trim_verdict(mp, surfaces, x):
    """YES when the point x (mp 3-vector) satisfies every trim, NO when one fails by more than the tie
    tolerance, else UNDECIDED."""
    X = [x[0], x[1], x[2], mp.mpf(1)]
    scale = 1 + sum(v * v for v in X)
    verdict = _Verdict.YES
    for s in surfaces:
        if s.is_plane:
            v = sum(mp.mpf(s.form[i].numerator) / s.form[i].denominator * X[i] for i in range(4))
            tol = TIE * mp.sqrt(scale) * max(abs(float(c)) for c in s.form)
        else:
            v = sum(mp.mpf(s.form[i][j].numerator) / s.form[i][j].denominator * X[i] * X[j]
                    for i in range(4) for j in range(4))
            tol = TIE * scale * max(abs(float(c)) for row in s.form for c in row)
        if v > tol:
            return _Verdict.NO
        if v > -tol:
            verdict = _Verdict.UNDECIDED
    return verdict


def _dehomogenise(mp, X):
    w = X[3]
    size = max(abs(X[0]), abs(X[1]), abs(X[2]), abs(w))
    if size == 0 or abs(w) <= mp.mpf(10) ** (-30) * size:
        return None
    return mp.matrix([X[0] / w, X[1] / w, X[2] / w])


def _null_vector(mp, M):
    """The null vector of a nearly singular square mp matrix, and whether the null space is one-dimensional."""
    _, S, V = mp.svd_r(M)
    n = M.rows
    big = max(S[0], mp.mpf(10) ** (-DIGITS))
    second = S[n - 2] / big if n > 1 else mp.mpf(1)
    return V[n - 1, :].T, second > mp.mpf(10) ** (-12)


def _null_points(mp, M, form):
    """The real points X with ``M X = 0`` and ``X^T form X = 0``: M's null vector, or where M's null space is a
    line, that line's real points on the quadric (or conic) ``form``."""
    _, S, V = mp.svd_r(M)
    n = M.rows
    big = max(S[0], mp.mpf(10) ** (-DIGITS))
    null = [k for k in range(n) if S[k] <= mp.mpf(10) ** (-12) * big]
    if len(null) <= 1:
        return [V[n - 1, :].T]
    if len(null) > 2:
        raise _Undecided
    X1, X2 = V[null[0], :].T, V[null[1], :].T
    a, b, c = (X1.T * form * X1)[0], (X1.T * form * X2)[0], (X2.T * form * X2)[0]
    size = abs(a) + abs(b) + abs(c)
    disc = b * b - a * c
    if disc < -mp.mpf(10) ** (-DIGITS // 3) * size ** 2:
        return []
    if disc <= mp.mpf(10) ** (-DIGITS // 3) * size ** 2:
        raise _Undecided            # the line touches the form: a double point, not decided here
    r = mp.sqrt(disc)
    if abs(a) >= abs(c):            # X = s X1 + X2, a s^2 + 2 b s + c = 0
        return [((-b + r) / a) * X1 + X2, ((-b - r) / a) * X1 + X2]
    return [X1 + ((-b + r) / c) * X2, X1 + ((-b - r) / c) * X2]


def _double_roots(mp, coeffs):
    """The real double roots of the polynomial with these mp coefficients (highest first), to ~DIGITS/2
    digits."""
    size = max(abs(c) for c in coeffs)
    while coeffs and abs(coeffs[0]) <= mp.mpf(10) ** (-DIGITS + 15) * size:   # zero but for the rounding
        coeffs = coeffs[1:]
    if len(coeffs) < 3:
        return []
    deriv = [c * (len(coeffs) - 1 - k) for k, c in enumerate(coeffs[:-1])]
    out = []
    for r in _roots(mp, deriv):
        if abs(mp.im(r)) > mp.mpf(10) ** (-20) * (1 + abs(r)):
            continue
        r = mp.re(r)
        value = mp.polyval(coeffs, r)
        size = sum(abs(c) * max(1, abs(r)) ** (len(coeffs) - 1 - k) for k, c in enumerate(coeffs))
        if abs(value) <= mp.mpf(10) ** (-DIGITS // 2 - 5) * size:
            out.append(r)
    return out


def _roots(mp, coeffs):
    """Every complex root of a polynomial (mp coefficients, highest first, the first nonzero)."""
    try:
        return mp.polyroots(coeffs, maxsteps=2000, extraprec=4 * DIGITS)
    except mp.NoConvergence:
        raise _Undecided from None


class _Undecided(Exception):
    """A numerical step that did not converge at the working precision: the candidate stays undecided."""


class _Solver:
    """The subproblems of one pair of models and their candidate times."""

    def __init__(self, a, b, MA, MB):
        self.sp, self.mp = _sympy()
        self.a, self.b = a, b
        self.pair = _Pair(MA, MB)
        self.MA, self.MB = MA[0], MB[0]
        self.num = _Numeric(self.sp, self.mp, self.pair)
        self.lam = self.sp.Symbol("lam")

    # each builder returns a _Subproblem: its polynomials in t, and the check of a root t0

    def subproblems(self):
        a, b = self.a, self.b
        for fa in a.faces:
            for fb in b.faces:
                if (fa.surface.is_plane and _ruled(fb.surface)) or (fb.surface.is_plane and _ruled(fa.surface)):
                    continue
                if fa.surface.is_plane or fb.surface.is_plane:
                    yield self._plane_quadric(fa, fb)
                else:
                    yield self._face_face(fa, fb)
        for side, (x, y) in (("F-E", (a, b)), ("E-F", (b, a))):
            for f in x.faces:
                for e in y.edges:
                    if f.surface.is_plane and e.surface.is_plane:
                        continue
                    yield self._face_edge(f, e, side == "E-F", side)
        for ea in a.edges:
            for eb in b.edges:
                yield self._edge_edge(ea, eb)
        for side, (x, y) in (("F-V", (a, b)), ("V-F", (b, a))):
            for f in x.faces:
                for v in y.vertices:
                    yield self._face_vertex(f, v, side == "V-F", side)

    def _pencil(self, A, B):
        """The candidate polynomials of the pencil ``lam A - B(t)`` (:func:`_polys_of_pencil`); None (undecided
        throughout) when a root multiple for every t gives a real finite point at t = 1/2."""
        sp, mp, lam, t = self.sp, self.mp, self.lam, self.pair.t
        polys, repeated = _polys_of_pencil(sp, A, B, lam, t)
        if not repeated:
            return polys
        # the square-free part's discriminant (a root meeting a repeated one included)
        f = _pencil_det(sp, A, B, lam, t)
        rep = sp.gcd(f, f.diff(lam))
        free = sp.Poly(sp.quo(f.as_expr(), rep.as_expr()), lam, t)
        coeffs = [sp.Poly(x, t) for x in sp.Poly(free.as_expr(), lam).all_coeffs()]
        polys = [p for p in polys if not p.is_zero]
        if len(coeffs) >= 3:
            polys.append(_discriminant(coeffs))
        with mp.workdps(DIGITS):
            half = mp.mpf(1) / 2
            An, Bn = self.num.at(A, half), self.num.at(B, half)
            coeffs = self._pencil_coeffs(An, Bn)
            try:
                for l0 in _double_roots(mp, coeffs):
                    if any(_dehomogenise(mp, X) is not None for X in _null_points(mp, l0 * An - Bn, An)):
                        return None
            except _Undecided:
                return None
        return [p for p in polys if p.degree() > 0 or p.is_zero]

    def _plane_quadric(self, fa, fb):
        """A plane face against a quadric face, in the quadric's frame: the plane touches the quadric where it
        lies on the dual quadric, ``p adj(Q) p^T = 0``, at the point ``adj(Q) p^T``."""
        sp, t = self.sp, self.pair.t
        flipped = fa.surface.is_plane           # the quadric is B's
        quad, flat = (fb, fa) if flipped else (fa, fb)
        Q = _matrix(sp, quad.surface)
        p = _in_frame(sp, flat.surface, self.pair.to_a if flipped else self.pair.to_b)
        X = (Q.adjugate() * p.T).applyfunc(sp.expand)
        polys = [sp.Poly(sp.expand((p * X)[0, 0]), t)]

        def check(t0):
            return [self._verify(self.num.at(X, t0), fa.trims, fb.trims, not flipped)]
        return _Subproblem("F-F", fa, fb, polys, check, (X, not flipped))

    def _face_face(self, fa, fb):
        sp, mp, t, lam = self.sp, self.mp, self.pair.t, self.lam
        A = _matrix(sp, fa.surface)
        B = _in_frame(sp, fb.surface, self.pair.to_b)
        polys = self._pencil(A, B)

        def check(t0):
            An, Bn = self.num.at(A, t0), self.num.at(B, t0)
            f = self._pencil_coeffs(An, Bn)
            if max(abs(c) for c in f) <= mp.mpf(10) ** (-DIGITS // 2) * (1 + mp.mnorm(Bn, 1)) ** 4:
                return [self._singular_pencil(An, Bn)]
            out = []
            for l0 in _double_roots(mp, f):
                for X in _null_points(mp, l0 * An - Bn, An):
                    out.append(self._verify(X, fa.trims, fb.trims, True))
            return out
        return _Subproblem("F-F", fa, fb, polys, check)

    def _singular_pencil(self, An, Bn):
        """Two quadrics whose pencil vanishes at t0, such as cylinders with parallel axes: where both share one
        null vector (the common axis), their sections across it decide (two ellipses apart, or undecided)."""
        mp = self.mp
        d, single = _null_vector(mp, An)
        if not single or mp.norm(Bn * d) > mp.mpf(10) ** (-DIGITS // 2) * mp.mnorm(Bn, 1):
            return (_Verdict.UNDECIDED, None)
        _, _, V = mp.svd_r(An)
        P = mp.matrix([[V[k, i] for k in range(3)] for i in range(4)])   # the other three right singular vectors
        return (_Verdict.NO, None) if self._ellipses_apart(P.T * An * P, P.T * Bn * P) else \
            (_Verdict.UNDECIDED, None)

    def _ellipses_apart(self, C1, C2):
        """Two ellipses (3x3, inside <= 0) are apart when det(lam C1 - C2) has two distinct negative roots
        (thesis, chapter 2), decided with a margin far above the working precision."""
        mp = self.mp
        f3 = self._pencil_coeffs(C1, C2)
        roots = _roots(mp, f3)
        real = sorted(mp.re(r) for r in roots if abs(mp.im(r)) <= mp.mpf(10) ** (-20) * (1 + abs(r)))
        negative = [r for r in real if r < 0]
        return len(negative) >= 2 and negative[1] - negative[0] > mp.mpf(10) ** (-15) * (1 + abs(negative[0]))

    def _pencil_coeffs(self, An, Bn):
        """Coefficients (highest first) of det(lam An - Bn) (n x n, so of degree n), from its values at n + 1
        points."""
        mp = self.mp
        n = An.rows
        xs = [mp.mpf(k - n // 2) for k in range(n + 1)]
        ys = [_mp_det(x * An - Bn) for x in xs]
        V = mp.matrix([[x ** (n - k) for k in range(n + 1)] for x in xs])
        c = mp.lu_solve(V, mp.matrix(ys))
        return [c[k] for k in range(n + 1)]

    def _verify(self, X, trims_a, trims_b, in_a):
        """The verdict of a touching point X (homogeneous, in A's frame when in_a, else in B's)."""
        mp = self.mp
        x = _dehomogenise(mp, X)
        if x is None:
            return (_Verdict.NO, None)
        other = self._other_point(X, in_a)
        if other is None:
            return (_Verdict.NO, None)
        xa, xb = (x, other) if in_a else (other, x)
        va, vb = _trim_verdict(mp, trims_a, xa), _trim_verdict(mp, trims_b, xb)
        if _Verdict.NO in (va, vb):
            return (_Verdict.NO, None)
        return (min(va, vb), xa)

    def _other_point(self, X, in_a):
        """X (homogeneous, in one model's frame at the current time) in the other model's frame."""
        T = self._current[1] if in_a else self._current[0]
        Y = T * X
        return _dehomogenise(self.mp, Y)

    def _face_edge(self, f, e, flipped, kind):
        """Face f of one model against edge e of the other, in the edge's frame (B's unless flipped)."""
        sp, mp, t, lam = self.sp, self.mp, self.pair.t, self.lam
        P = _plane_basis(sp, _matrix(sp, e.plane))
        F = _in_frame(sp, f.surface, self.pair.to_b if flipped else self.pair.to_a)   # the face, in the edge's frame
        if e.surface.is_plane:      # a line edge: the face's section (a conic) touches the line
            ell = (_matrix(sp, e.surface) * P).T
            C = (P.T * F * P).applyfunc(sp.expand)
            polys = [sp.Poly(_adj_form(sp, C, ell), t)]
            moving = P * C.adjugate() * ell

            def point(t0):
                Cn, ln = self.num.at(C, t0), self.num.at(ell, t0)
                u = self._adjugate(Cn) * ln
                if mp.norm(u) > mp.mpf(10) ** (-DIGITS // 2) * mp.mnorm(Cn, 1) ** 2 * mp.norm(ln):
                    return [u]
                # the section is a double line (the edge's plane tangent to a cylinder along a ruling): the edge
                # meets it where the two lines cross
                _, S, V = mp.svd_r(Cn)
                if S[1] > mp.mpf(10) ** (-DIGITS // 2) * S[0]:
                    raise _Undecided
                m = V[0, :]
                return [mp.matrix([m[1] * ln[2] - m[2] * ln[1], m[2] * ln[0] - m[0] * ln[2],
                                   m[0] * ln[1] - m[1] * ln[0]])]
        elif f.surface.is_plane:    # a conic edge against a plane face: the face's trace line touches the conic
            E = (P.T * _matrix(sp, e.surface) * P).applyfunc(sp.expand)
            m = (F * P).T.applyfunc(sp.expand)
            polys = [sp.Poly(_adj_form(sp, E, m), t)]
            moving = P * E.adjugate() * m

            def point(t0):
                En, mn = self.num.at(E, t0), self.num.at(m, t0)
                if mp.norm(mn) <= mp.mpf(10) ** (-DIGITS // 2) * mp.mnorm(self.num.at(F, t0), 1) * \
                        mp.mnorm(self.num.at(P, t0), 1):
                    return self._coplanar_face(f, En, P, t0, flipped)
                return [self._adjugate(En) * mn]
        else:                       # two conics in the edge's plane touch
            E = (P.T * _matrix(sp, e.surface) * P).applyfunc(sp.expand)
            C = (P.T * F * P).applyfunc(sp.expand)
            polys = self._pencil(E, C)
            moving = None

            def point(t0):
                En, Cn = self.num.at(E, t0), self.num.at(C, t0)
                f3 = self._pencil_coeffs(En, Cn)
                out = []
                for l0 in _double_roots(mp, f3):
                    out += _null_points(mp, l0 * En - Cn, En)
                return out

        def check(t0):
            Pn = self.num.at(P, t0)
            out = []
            for u in point(t0):
                if mp.norm(u) <= mp.mpf(10) ** (-DIGITS // 2) * (1 + mp.mnorm(Pn, 1)):
                    raise _Undecided   # the section or the edge degenerates to a point or less
                X = Pn * u     # in the edge's frame
                face_trims, edge_trims = f.trims, e.trims
                ta, tb = (face_trims, edge_trims) if not flipped else (edge_trims, face_trims)
                out.append(self._verify(X, ta, tb, flipped))
            return out
        persistent = None if moving is None else (moving.applyfunc(sp.expand), flipped)
        return _Subproblem(kind, f if not flipped else e, e if not flipped else f, polys, check, persistent)

    def _coplanar_face(self, f, En, P, t0, flipped):
        """A plane face in the plane of a conic edge at t0: no touching point when the edge's ellipse is apart
        from the ellipse a quadric trim leaves of the face (thesis, chapter 2), or lies wholly beyond a plane
        trim; else undecided."""
        mp = self.mp
        T = self._current[1] if flipped else self._current[0]     # the edge's frame -> the face's frame
        Pn = self.num.at(P, t0)
        TP = T * Pn
        for g in f.trims:
            if g.is_plane:
                trim = mp.matrix([[mp.mpf(x.numerator) / x.denominator for x in g.form]])
                if self._beside_line(En, trim * TP, TP[3, :]) > 0:
                    return []
                continue
            G = mp.matrix([[mp.mpf(x.numerator) / x.denominator for x in row] for row in g.form])
            if self._ellipses_apart(Pn.T * T.T * G * T * Pn, En):
                return []
        raise _Undecided

    def _beside_line(self, E, ell, weight):
        """Which side of the line ``ell . u = 0`` the ellipse ``u^T E u <= 0`` lies on, in a plane's homogeneous
        coordinates u whose point has the weight ``weight . u`` (rows of 3, mp): +1 wholly where ell . u > 0
        (at weight 1), -1 wholly where it is < 0, 0 when the line meets it, it is no real ellipse, or the
        working precision cannot tell."""
        mp = self.mp
        j = max(range(3), key=lambda i: abs(weight[i]))
        if weight[j] == 0:
            return 0
        Q = mp.zeros(3, 3)             # columns: two directions of weight 0, then a point of weight 1
        for col, i in enumerate(i for i in range(3) if i != j):
            Q[i, col], Q[j, col] = 1, -weight[i] / weight[j]
        Q[j, 2] = 1 / weight[j]
        Ea, la = Q.T * E * Q, ell * Q
        if Ea[0, 0] < 0:
            Ea = -Ea
        det = Ea[0, 0] * Ea[1, 1] - Ea[0, 1] ** 2
        scale = mp.mnorm(Ea, 1)
        tiny = mp.mpf(10) ** (-DIGITS // 3)
        if not (Ea[0, 0] > tiny * scale and det > tiny * scale ** 2):
            return 0
        inv = mp.matrix([[Ea[1, 1], -Ea[0, 1]], [-Ea[0, 1], Ea[0, 0]]]) / det
        b = mp.matrix([Ea[0, 2], Ea[1, 2]])
        c = -(inv * b)
        k = (c.T * mp.matrix([[Ea[0, 0], Ea[0, 1]], [Ea[0, 1], Ea[1, 1]]]) * c)[0] - Ea[2, 2]
        if not k > tiny * scale * (1 + mp.norm(c) ** 2):
            return 0
        g = mp.matrix([la[0], la[1]])
        centre = la[0] * c[0] + la[1] * c[1] + la[2]
        half = mp.sqrt(k * (g.T * inv * g)[0])
        margin = tiny * (abs(centre) + half + mp.norm(la))
        if centre - half > margin:
            return 1
        if centre + half < -margin:
            return -1
        return 0

    def _adjugate(self, M):
        """adj(M) of a 3x3 mp matrix, by cofactors (exact for a singular M)."""
        out = self.mp.matrix(3, 3)
        for i in range(3):
            for j in range(3):
                r0, r1 = [r for r in range(3) if r != j]
                c0, c1 = [c for c in range(3) if c != i]
                out[i, j] = (-1) ** (i + j) * (M[r0, c0] * M[r1, c1] - M[r0, c1] * M[r1, c0])
        return out


    def _edge_edge(self, ea, eb):
        """Edge ea of A against edge eb of B, in B's frame: the two curves' traces on the line where their planes
        meet have a common point."""
        sp, mp, t = self.sp, self.mp, self.pair.t
        P = _plane_basis(sp, _matrix(sp, eb.plane))
        pa = _in_frame(sp, ea.plane, self.pair.to_a)          # A's plane in B's frame (1x4)
        m = (pa * P).T.applyfunc(sp.expand)                   # its trace line in B's plane coordinates

        def trace(surface, frame_map):
            if surface.is_plane:
                return _in_frame(sp, surface, frame_map) * P, 1
            return (P.T * _in_frame(sp, surface, frame_map) * P), 2

        ca, da = trace(ea.surface, self.pair.to_a)
        own = _matrix(sp, eb.surface)
        cb, db = (own * P, 1) if eb.surface.is_plane else (P.T * own * P, 2)

        def bases(mv):
            m1, m2, m3 = mv[0], mv[1], mv[2]
            return [sp.Matrix([[m3, 0], [0, m3], [-m1, -m2]]), sp.Matrix([[-m2, -m3], [m1, 0], [0, m1]]),
                    sp.Matrix([[m2, 0], [-m1, -m3], [0, m2]])]

        # the first basis of the line that does not vanish for every t; its pivot's roots are extra candidates
        polys = None
        cap, cbp = _as_polys(sp, ca, t), _as_polys(sp, cb, t)
        for k, K in zip((2, 0, 1), bases(m)):
            if sp.expand(m[k]) == 0:
                continue
            Kp = _as_polys(sp, K, t)
            r = _binary_resultant(_binary_coefficients(cap, da, Kp), _binary_coefficients(cbp, db, Kp))
            polys = [r] if not r.is_zero else None
            break

        def check(t0):
            mn = self.num.at(m, t0)
            size = max(abs(mn[k]) for k in range(3))
            scale = 1 + mp.mnorm(self.num.at(pa, t0), 1) * mp.mnorm(self.num.at(P, t0), 1)
            if size <= mp.mpf(10) ** (-DIGITS // 2) * scale:
                return self._coplanar(ea, eb, ca, da, cb, db, P, t0)
            k = max(range(3), key=lambda i: abs(mn[i]))
            K = bases(m)[(1, 2, 0)[k]]    # the basis whose pivot is the largest component of m
            Kn = self.num.at(K, t0)
            can, cbn = self.num.at(ca, t0), self.num.at(cb, t0)
            out = []
            for s0 in self._form_roots(can, da, Kn):
                if s0 is None:
                    continue
                u = Kn * mp.matrix([s0[0], s0[1]])
                vb = self._form_value(cbn, db, u)
                scale_b = mp.mnorm(cbn, 1) * mp.norm(u) ** db
                if abs(vb) > mp.mpf(10) ** (-DIGITS // 3) * (scale_b + mp.mpf(10) ** (-DIGITS)):
                    continue
                X = self.num.at(P, t0) * u
                out.append(self._verify(X, ea.trims, eb.trims, False))
            return out
        return _Subproblem("E-E", ea, eb, polys, check)

    def _form_value(self, c, d, u):
        mp = self.mp
        if d == 1:
            return sum(c[0, i] * u[i] for i in range(3))
        return sum(c[i, j] * u[i] * u[j] for i in range(3) for j in range(3))

    def _form_roots(self, c, d, K):
        """The real roots (as homogeneous pairs) of the binary form u = K (s0, s1) on the conic or line c."""
        mp = self.mp
        if d == 1:
            a = sum(c[0, i] * K[i, 0] for i in range(3))
            b = sum(c[0, i] * K[i, 1] for i in range(3))
            return [(-b, a)] if (a != 0 or b != 0) else [None]
        G = K.T * c * K
        a, b, cc = G[0, 0], 2 * G[0, 1], G[1, 1]
        disc = b * b - 4 * a * cc
        size = abs(b) ** 2 + abs(4 * a * cc) + mp.mpf(10) ** (-2 * DIGITS)
        if disc < -mp.mpf(10) ** (-DIGITS // 2) * size:
            return []
        r = mp.sqrt(max(disc, 0))
        if abs(a) >= abs(cc):
            return [(-b + r, 2 * a), (-b - r, 2 * a)] if a != 0 else [None]
        return [(2 * cc, -b - r), (2 * cc, -b + r)]

    def _coplanar(self, ea, eb, ca, da, cb, db, P, t0):
        """Both edges in one plane at t0: two ellipses there are apart when their pencil has two distinct
        negative roots (thesis, chapter 2), a line and an ellipse when the line misses it; anything else stays
        undecided."""
        if da == 1 and db == 1:
            return [(_Verdict.UNDECIDED, None)]
        if da == 1 or db == 1:       # a line and an ellipse: apart when the line misses it
            line, conic = (ca, cb) if da == 1 else (cb, ca)
            weight = self.num.at(P, t0)[3, :]
            if self._beside_line(self.num.at(conic, t0), self.num.at(line, t0), weight) != 0:
                return [(_Verdict.NO, None)]
            return [(_Verdict.UNDECIDED, None)]
        if self._ellipses_apart(self.num.at(ca, t0), self.num.at(cb, t0)):
            return [(_Verdict.NO, None)]
        return [(_Verdict.UNDECIDED, None)]

    def _face_vertex(self, f, v, flipped, kind):
        """A vertex of one model on a face of the other, in the face's frame."""
        sp = self.sp
        into = self.pair.to_a if not flipped else self.pair.to_b
        Xv = (into * sp.Matrix([sp.Rational(c) for c in v.point] + [1])).applyfunc(sp.expand)
        m = _matrix(sp, f.surface)
        expr = (m * Xv)[0, 0] if f.surface.is_plane else (Xv.T * m * Xv)[0, 0]
        polys = [sp.Poly(sp.expand(expr), self.pair.t)]

        def check(t0):
            X = self.num.at(Xv, t0)
            trims_a, trims_b = (f.trims, ()) if not flipped else ((), f.trims)
            return [self._verify(X, trims_a, trims_b, not flipped)]
        return _Subproblem(kind, f if not flipped else v, v if not flipped else f, polys, check, (Xv, not flipped))

    # ------------------------------------------------------------ the search

    def _persistent(self, sub, t_max):
        """A subproblem whose extended elements touch for every t, at a point X(t) that moves polynomially: the
        first time X(t) lies on both trimmed elements, as a candidate (lo, hi, None, ((verdict, point, sub),
        t0)); None when it never does.  Without such a point (two quadrics or two edges touching throughout)
        the subproblem stays undecided from t = 0."""
        sp, mp, t = self.sp, self.mp, self.pair.t
        if sub.persistent is None:
            return (sp.Integer(0), sp.Integer(0), None, ((_Verdict.UNDECIDED, None, sub), mp.mpf(0)))
        X, in_a = sub.persistent
        Xa = X if in_a else (self.pair.to_a * X).applyfunc(sp.expand)
        Xb = (self.pair.to_b * X).applyfunc(sp.expand) if in_a else X
        trims_a, trims_b = _element_trims(sub.elem_a), _element_trims(sub.elem_b)
        signs = [_trim_sign(sp, g, Xa) for g in trims_a] + [_trim_sign(sp, g, Xb) for g in trims_b]
        signs = [sp.Poly(h, t) for h in signs if h != 0]
        times = [(mp.mpf(0), None)]
        for h in signs:
            q = h.sqf_part()
            for (lo, hi), _ in q.intervals(inf=0, sup=sp.Rational(Fraction(t_max)), eps=1e-9):
                times.append((refine_root(q, lo, hi), h))
        with mp.workdps(DIGITS):
            for t0, own in sorted(times, key=lambda c: c[0]):
                Xn = self.num.at(Xa, t0)
                x = _dehomogenise(mp, Xn)
                if x is None:
                    continue
                worst = _Verdict.YES
                for h in signs:
                    if h is own:       # t0 is this polynomial's own root: exactly 0, on the trim's border
                        continue
                    value = self.num.value(h.as_expr(), t, t0)
                    size = sum(abs(c) for c in h.all_coeffs())
                    if value > TIE * size:
                        worst = _Verdict.NO
                        break
                    if value > -TIE * size:
                        worst = _Verdict.UNDECIDED
                if worst != _Verdict.NO:
                    time = sp.Rational(Fraction(float(t0)))
                    return (time, time, None, ((worst, x, sub), t0))
        return None

    def _candidates(self, t_max):
        """(candidates, throughout): every subproblem root in [0, t_max] as (lo, hi, square-free poly, subproblem)
        sorted by its isolating interval (a persistent touch as (time, time, None, (verdict, t0))), and whether
        some subproblem is undecided for every t."""
        sp = self.sp
        candidates, throughout = [], False
        for sub in self.subproblems():
            if sub.polys is None:
                throughout = True
                continue
            for p in sub.polys:
                if p.is_zero:
                    found = self._persistent(sub, t_max)
                    if found is not None:
                        candidates.append(found)
                    continue
                q = p.sqf_part()
                for (lo, hi), _ in q.intervals(inf=0, sup=sp.Rational(Fraction(t_max)), eps=1e-9):
                    candidates.append((lo, hi, q, sub))
        candidates.sort(key=lambda c: c[0])
        return candidates, throughout

    def _verdicts(self, lo, hi, q, sub):
        """(verdicts, t0, sub) of one candidate: its time t0 to 1e-50 and the [(verdict, point)] of the touching
        points there (at the working precision)."""
        if q is None:         # a persistent touch, already tested: sub holds its verdict and time
            verdicts, t0 = sub
            return [verdicts[:2]], t0, verdicts[2]
        t0 = refine_root(q, lo, hi)
        self._current = (self.num.at(self.pair.to_a, t0), self.num.at(self.pair.to_b, t0))
        try:
            return sub.check(t0), t0, sub
        except _Undecided:
            return [(_Verdict.UNDECIDED, None)], t0, sub

    def first(self, t_max):
        """(time, point in A's frame or None, (name_a, name_b), certainty, bracket) of the first contact over
        [0, t_max], or None."""
        mp = self.mp
        candidates, throughout = self._candidates(t_max)
        undecided, undecided_at = (0.0, mp.mpf(0)) if throughout else (None, mp.mpf(0))
        with mp.workdps(DIGITS):
            for lo, hi, q, sub in candidates:
                if undecided is not None and mp.mpf(lo.p) / lo.q > undecided_at:
                    break     # strictly after an undecided candidate: the bracket's end is all it can give
                verdicts, t0, sub = self._verdicts(lo, hi, q, sub)
                if any(v == _Verdict.YES for v, _ in verdicts):
                    x = next(p for v, p in verdicts if v == _Verdict.YES)
                    time = float(t0)
                    names = (sub.elem_a.name, sub.elem_b.name)
                    point, normal = self._touch(sub, x, t0)
                    if undecided is not None and t0 - undecided_at > mp.mpf(10) ** (-ROOT_DIGITS + 5):
                        return (undecided, point, normal, names, "uncertain", (undecided, time))
                    return (time, point, normal, names, "certified", None)
                if any(v == _Verdict.UNDECIDED for v, _ in verdicts) and undecided is None:
                    undecided, undecided_at = float(mp.mpf(lo.p) / lo.q), t0
        if undecided is not None:
            return (undecided, None, None, None, "uncertain", (undecided, float(t_max)))
        return None

    def events(self, t_max):
        """(touches, undecided, throughout): every time in [0, t_max] at which two elements are proven to touch,
        the times whose test 60 digits left undecided (both sorted, mp numbers), and whether a subproblem is
        undecided for every t.  Whenever the two solids start or stop meeting, they touch: so every end of
        their contact intervals is among these times."""
        mp = self.mp
        candidates, throughout = self._candidates(t_max)
        touches, undecided = [], []
        with mp.workdps(DIGITS):
            for lo, hi, q, sub in candidates:
                verdicts, t0, _ = self._verdicts(lo, hi, q, sub)
                if any(v == _Verdict.YES for v, _ in verdicts):
                    touches.append(t0)
                elif any(v == _Verdict.UNDECIDED for v, _ in verdicts):
                    undecided.append(t0)
        return sorted(touches), sorted(undecided), throughout

    def _touch(self, sub, x, t0):
        """The world point of the touch (x: in A's frame) and the unit normal outward from A, from the face that
        touches (A's, else B's turned round); None for two edges or an edge and a vertex."""
        mp = self.mp
        X = mp.matrix([x[0], x[1], x[2], 1])
        W = self.num.at(self.MA, t0) * X
        point = np.array([float(W[i] / W[3]) for i in range(3)])
        for element, frame, motion, sign in ((sub.elem_a, X, self.MA, 1), (sub.elem_b, None, self.MB, -1)):
            if not isinstance(element, Face):
                continue
            if frame is None:
                frame = self.num.at(self.pair.to_b, t0) * X
                frame = frame / frame[3]
            g = element.surface
            if g.is_plane:
                grad = [mp.mpf(g.form[i].numerator) / g.form[i].denominator for i in range(3)]
            else:
                grad = [2 * sum(mp.mpf(g.form[i][j].numerator) / g.form[i][j].denominator * frame[j]
                                for j in range(4)) for i in range(3)]
            M = self.num.at(motion, t0)
            L = np.array([[float(M[i, j] / M[3, 3]) for j in range(3)] for i in range(3)])
            n = np.linalg.solve(L.T, np.array([float(v) for v in grad]))
            return point, sign * n / np.linalg.norm(n)
        return point, None


def _certified_sign(iv, coeffs, x):
    """The sign of the polynomial (exact rationals, highest first) at the mp point x, proven with interval
    arithmetic; 0 when the rounding cannot decide it."""
    acc = iv.mpf(0)
    X = iv.mpf(x)
    for c in coeffs:
        acc = acc * X + iv.mpf(c.p) / c.q
    if acc.a > 0:
        return 1
    if acc.b < 0:
        return -1
    return 0


def refine_root(q, lo, hi):
    """The simple root of the square-free Poly q in its isolating interval [lo, hi] (sympy Rationals) to 1e-50:
    Newton's steps at high precision, then a sign change proven with interval arithmetic on each side (else
    bisection on proven signs).  sympy's own refinement, exact, takes seconds on degree-150 polynomials."""
    _, mp = _sympy()
    from mpmath import iv
    if lo == hi:
        return mp.mpf(lo.p) / lo.q
    coeffs = q.all_coeffs()
    dps = ROOT_DIGITS + 30
    saved, iv.dps = iv.dps, dps
    try:
        with mp.workdps(dps):
            return _newton_then_bisect(mp, iv, coeffs, lo, hi)
    finally:
        iv.dps = saved


def _newton_then_bisect(mp, iv, coeffs, lo, hi):
    """refine_root's search, at the working precision set."""
    a, b = mp.mpf(lo.p) / lo.q, mp.mpf(hi.p) / hi.q
    mcoeffs = [mp.mpf(c.p) / c.q for c in coeffs]
    sa = _certified_sign(iv, coeffs, a) or mp.sign(mp.polyval(mcoeffs, a))
    dcoeffs = [c * (len(mcoeffs) - 1 - k) for k, c in enumerate(mcoeffs[:-1])]
    x = (a + b) / 2
    for _ in range(100):
        d = mp.polyval(dcoeffs, x)
        if d == 0:
            break
        step = mp.polyval(mcoeffs, x) / d
        x -= step
        if not a < x < b:
            x = (a + b) / 2
            break
        if abs(step) < mp.mpf(10) ** (-ROOT_DIGITS - 10):
            break
    delta = mp.mpf(10) ** (-ROOT_DIGITS - 2)
    left, right = _certified_sign(iv, coeffs, x - delta), _certified_sign(iv, coeffs, x + delta)
    if left and right and left != right and a <= x - delta and x + delta <= b:
        return x
    while b - a > mp.mpf(10) ** (-ROOT_DIGITS):     # bisection on proven signs
        m = (a + b) / 2
        sm = _certified_sign(iv, coeffs, m)
        if sm == 0:
            return m     # within the rounding of a root: closer than any width asked for
        if sm == sa:
            a = m
        else:
            b = m
    return (a + b) / 2


def _element_trims(element):
    return getattr(element, "trims", ())


def _trim_sign(sp, g, X):
    """A polynomial in t with the sign of trim g at the moving homogeneous point X(t) (where X's weight is not
    zero): ``X^T G X`` for a quadric, ``(p . X) w`` for a plane."""
    m = _matrix(sp, g)
    if g.is_plane:
        return sp.expand((m * X)[0, 0] * X[3])
    return sp.expand((X.T * m * X)[0, 0])


def _world_bound(sp, M, bound, tau):
    """The centre and a radius of a world ball holding a model of this local bound, at t = tau."""
    M0 = np.array(M.subs(sp.Symbol("t"), tau).evalf(30).tolist(), dtype=float)
    L, v = M0[:3, :3] / M0[3, 3], M0[:3, 3] / M0[3, 3]
    return v, bound * np.linalg.norm(L, 2) * (1 + 1e-9) + 1e-9


def _status_at(a, b, MA, MB, tau=0):
    """The two models' status at the exact time ``tau`` (a sympy Rational): "separate" when B can approach its
    pose there in a straight line, from beyond both bounding balls, without touching A (proven); "touching"
    when an approach touches only at its end; "overlapping" when every approach meets A before its end (a body
    shut in another's cavity without touching it would read so).  Two convex models that are apart have a
    separating plane, and of two opposite approaches one comes from its side and is free: so where both of a
    pair of opposite approaches are proven to meet A, they are not apart, whatever another approach left
    undecided.  None when an approach is undecided and nothing else decides."""
    sp, _ = _sympy()
    t = sp.Symbol("t")
    A0 = (MA[0].subs(t, tau), MA[1].subs(t, tau))
    B0, B0_inverse = MB[0].subs(t, tau), MB[1].subs(t, tau)
    ca, ra = _world_bound(sp, MA[0], a.bound, tau)
    cb, rb = _world_bound(sp, MB[0], b.bound, tau)
    reach = sp.Rational(Fraction(float(np.linalg.norm(ca - cb)) + ra + rb + 1.0))
    touching = undecided = False
    meets = []                  # per approach: proven to meet A
    for direction in _APPROACHES:
        shift, back = sp.eye(4), sp.eye(4)
        for i in range(3):
            shift[i, 3] = reach * sp.Rational(direction[i]) * (1 - t)
            back[i, 3] = -shift[i, 3]
        approach = ((shift * B0).applyfunc(sp.expand), (B0_inverse * back).applyfunc(sp.expand))
        found = _Solver(a, b, A0, approach).first(1.0)
        if found is None:
            return "separate"
        meets.append(found[4] == "certified")
        if found[4] != "certified":
            undecided = True
        elif found[0] == 1.0:
            touching = True
    if undecided and a.convex and b.convex and any(meets[k] and meets[k + 1] for k in range(0, len(meets), 2)):
        undecided = False       # opposite approaches (_APPROACHES lists each with its opposite next)
    if touching:
        return "touching"
    return None if undecided else "overlapping"


def _is_ball(model):
    """A model no rotation about its origin changes: one face, a sphere centred there."""
    if len(model.faces) != 1 or model.edges or model.vertices or model.faces[0].trims:
        return False
    s = model.faces[0].surface
    if s.is_plane:
        return False
    q = s.form
    return q[0][0] == q[1][1] == q[2][2] > 0 and all(q[i][j] == 0 for i in range(4) for j in range(4)
                                                      if i != j)


def _motion_matrices(model_a, motion_a, model_b, motion_b):
    """The two motions' matrices (:func:`motion_matrix`) for two checked models."""
    for m, field in ((model_a, "model_a"), (model_b, "model_b")):
        if not isinstance(m, CompositeQuadric):
            raise InputTypeError(f"{field}: expected a CompositeQuadric, got {type(m).__name__}")
    return (motion_matrix(motion_a, "motion_a", not _is_ball(model_a)),
            motion_matrix(motion_b, "motion_b", not _is_ball(model_b)))


def cqm_first_contact(model_a, motion_a, model_b, motion_b, *, t_max=1.0):
    """First time in [0, t_max] at which two moving composite quadric models touch, as a :class:`mjccd.Contact`
    (None: proven free of contact).

    Motions: :class:`mjccd.Static`, :class:`mjccd.Rigid`, :class:`mjccd.Rational` and
    :class:`mjccd.LinearAffine`, taken exactly.  The contact names the two touching ``elements``; its point is
    in the world; its normal is None (an edge or vertex contact has no single one).  ``uncertain``: a test that
    60 digits could not decide came first, and ``bracket`` holds every possible first contact.
    """
    MA, MB = _motion_matrices(model_a, motion_a, model_b, motion_b)
    t_max = float(t_max)
    if not 0.0 < t_max <= 1.0:
        raise InputError(f"t_max: must be in (0, 1], got {t_max}")
    status = _status_at(model_a, model_b, MA, MB)
    if status not in ("separate", None):
        return Contact(0.0, None, None, status)
    found = _Solver(model_a, model_b, MA, MB).first(t_max)
    if status is None:   # not proven apart at the start: a first contact may be there already
        end = t_max if found is None else found[5][1] if found[5] else found[0]
        return Contact(0.0, None, None, "overlapping", "uncertain", (0.0, end))
    if found is None:
        return None
    time, point, normal, names, certainty, bracket = found
    return Contact(time, point, normal, "separate", certainty, bracket, elements=names)


_STRETCH_POINTS = (Fraction(1, 2), Fraction(1, 3), Fraction(2, 3), Fraction(1, 5))


def _stretch_status(a, b, MA, MB, lo, hi):
    """The status of the two models all through the open stretch (lo, hi) (mp numbers) between two times at
    which they may touch: it does not change there, so the first decided status at one of a few exact times
    inside it (None when none is)."""
    sp, mp = _sympy()
    for f in _STRETCH_POINTS:
        status = _status_at(a, b, MA, MB, sp.Rational(mp.nstr(lo + (hi - lo) * f.numerator / f.denominator, 55,
                                                                strip_zeros=False)))
        if status is not None:
            return status
    return None


def cqm_collision_intervals(model_a, motion_a, model_b, motion_b):
    """Every interval of [0, 1] in which two moving composite quadric models touch or overlap.

    Returns (intervals, certified): a sorted list of disjoint (t_in, t_out), a touch that does not last an
    interval of zero width, and whether every end is proven (within 1e-9).  The ends are among the times at
    which two elements touch (:meth:`_Solver.events`); between two such times the status does not change, so
    it is decided once, at an exact time between them, by the approaches of the start status.  A time or a
    status that 60 digits leave undecided makes the answer uncertain: its stretch is then counted as touching,
    so that the intervals hold every possible contact.
    """
    MA, MB = _motion_matrices(model_a, motion_a, model_b, motion_b)
    sp, mp = _sympy()
    touches, undecided, throughout = _Solver(model_a, model_b, MA, MB).events(1.0)
    if throughout:
        return [(0.0, 1.0)], False
    certified = True
    same = mp.mpf(10) ** (-ROOT_DIGITS + 5)     # times closer than the roots' accuracy are one
    with mp.workdps(DIGITS):
        cuts = []                                 # [time, touched there, proven]
        for x, proven in sorted([(x, True) for x in touches] + [(x, False) for x in undecided]):
            if cuts and x - cuts[-1][0] <= same:
                cuts[-1][2] = cuts[-1][2] or proven
            else:
                cuts.append([x, True, proven])
        for end in (mp.mpf(0), mp.mpf(1)):        # an end that is no proven touch: its own status (exact there)
            near = [c for c in cuts if abs(c[0] - end) <= same]
            if near and near[0][2]:
                continue
            status = _status_at(model_a, model_b, MA, MB, sp.Integer(int(end)))
            if near and status is None:
                continue                          # still an undecided touch
            for c in near:
                cuts.remove(c)
            cuts.append([end, status != "separate", status is not None])
        cuts.sort(key=lambda c: c[0])
        members = []                              # each cut, then the stretch to the next, in time order
        for k, (x, touched, proven) in enumerate(cuts):
            members.append((float(x), float(x), touched, proven))
            if k + 1 < len(cuts):
                status = _stretch_status(model_a, model_b, MA, MB, x, cuts[k + 1][0])
                members.append((float(x), float(cuts[k + 1][0]), status != "separate", status is not None))
        # a time whose touch is unproven matters only where it would stand alone: beside a stretch in contact it
        # is that stretch's end (or inside it) either way
        for k, (lo, hi, touched, proven) in enumerate(members):
            if proven:
                continue
            if lo == hi and any(members[j][2] and members[j][3] for j in (k - 1, k + 1) if 0 <= j < len(members)):
                continue
            certified = False
    intervals = []
    for lo, hi, touched, _ in members:
        if not touched:
            continue
        if intervals and lo <= intervals[-1][1]:
            intervals[-1] = (intervals[-1][0], max(intervals[-1][1], hi))
        else:
            intervals.append((lo, hi))
    return intervals, certified
