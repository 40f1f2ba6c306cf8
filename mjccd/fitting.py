"""Bounding ellipsoids of convex shapes, with proven containment; plain numpy and numba, no MuJoCo.

Each shape is turned into *atoms*: points (box corners, mesh vertices) and
possibly flat ellipsoids ``{m + S u : |u| <= 1}`` (balls, ellipsoids, the two
end balls of a capsule, the two end disks of a cylinder).  Every supported
shape is the convex hull of its atoms, so a convex function of position
reaches its maximum over the shape on an atom.

The fit is Khachiyan's minimum-volume enclosing ellipsoid of samples of the
atoms, refined by the points of the atoms farthest outside it (closed forms
for a lone sphere, ellipsoid, box or cylinder).  The containment step then
bounds ``max |L (x - c)|`` over every atom *exactly from above* -- for an
ellipsoidal atom through the dual of the trust-region problem -- and grows
the ellipsoid by that factor when it exceeds one.  So every point of the
shapes is inside the returned ellipsoid, not only the samples.

:func:`cover_shape` covers a shape by several ellipsoids instead, as few as
keep every point of them within a tolerance of the shape (containment still
proven the same way, piece by piece); :func:`cover_report` and
:func:`within_tolerance` measure and prove how far ellipsoids reach past
shapes, with the exact distances of :meth:`Shape.distance`.

Shapes use MuJoCo's geom parametrisation (so :mod:`mjccd.mujoco.ellipsoids`
passes a model's geoms through unchanged), but nothing here needs MuJoCo.
"""
from dataclasses import dataclass

import numba
import numpy as np

from mjccd.errors import InputError

KINDS = ("sphere", "capsule", "ellipsoid", "cylinder", "box", "mesh")
REFINE_ROUNDS = 100  # at most this many times the farthest points of the atoms join the samples
MAX_ITERATIONS = 100000  # Khachiyan steps of one fit to samples


class TooManyEllipsoids(InputError):
    """A cover needs more ellipsoids than allowed at its tolerance (:func:`cover_shape`)."""


@dataclass(frozen=True)
class Atom:
    """``{centre + shape @ u : |u| <= 1}``; ``shape`` is None for a point set (``centre`` (n, 3))."""

    centre: np.ndarray
    shape: np.ndarray = None


def ball(centre, radius):
    """The atom of a ball."""
    return Atom(np.asarray(centre, dtype=float), radius * np.eye(3))


@dataclass(frozen=True)
class Shape:
    """A convex shape placed by ``position`` (3,) and ``rotation`` (3, 3), sized as MuJoCo geoms are.

    ``size``: sphere (r,), capsule and cylinder (r, half length along z),
    ellipsoid and box (three half axes).  A mesh has no size; it is its
    ``vertices`` (n, 3) in its own frame, ``faces`` (m, 3) give its volume;
    :meth:`distance`, :meth:`contains` and :func:`cover_shape` take a mesh
    as its convex hull and need ``faces`` to be the hull's
    (:func:`mjccd.mujoco.ellipsoids.mesh_hull` gives MuJoCo's).
    """

    kind: str
    size: np.ndarray
    position: np.ndarray
    rotation: np.ndarray
    vertices: np.ndarray = None
    faces: np.ndarray = None

    def __post_init__(self):
        if self.kind not in KINDS:
            raise ValueError(f"kind: expected one of {', '.join(KINDS)}, got {self.kind!r}")

    def atoms(self):
        """Atoms whose convex hull is the shape."""
        s, p, R = np.asarray(self.size, dtype=float), np.asarray(self.position, dtype=float), self.rotation
        if self.kind == "sphere":
            return [Atom(p, R * s[0])]
        if self.kind == "ellipsoid":
            return [Atom(p, R * s)]
        if self.kind == "capsule":
            return [Atom(p + end * s[1] * R[:, 2], R * s[0]) for end in (-1.0, 1.0)]
        if self.kind == "cylinder":
            disk = R * np.array([s[0], s[0], 0.0])
            return [Atom(p + end * s[1] * R[:, 2], disk) for end in (-1.0, 1.0)]
        if self.kind == "box":
            signs = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)], float)
            return [Atom(p + (signs * s) @ R.T)]
        return [Atom(p + np.asarray(self.vertices, dtype=float) @ R.T)]

    def volume(self):
        """Volume of the shape (a mesh's from its faces)."""
        s = np.asarray(self.size, dtype=float)
        if self.kind == "sphere":
            return 4.0 / 3.0 * np.pi * s[0] ** 3
        if self.kind == "ellipsoid":
            return 4.0 / 3.0 * np.pi * np.prod(s)
        if self.kind == "capsule":
            return np.pi * s[0] ** 2 * 2.0 * s[1] + 4.0 / 3.0 * np.pi * s[0] ** 3
        if self.kind == "cylinder":
            return np.pi * s[0] ** 2 * 2.0 * s[1]
        if self.kind == "box":
            return 8.0 * np.prod(s)
        v = np.asarray(self.vertices, dtype=float)
        a, b, c = v[self.faces[:, 0]], v[self.faces[:, 1]], v[self.faces[:, 2]]
        return abs(np.einsum("ij,ij->i", a, np.cross(b, c)).sum()) / 6.0

    def support(self, directions):
        """``max_{x in shape} x . n`` for each direction n of ``directions`` (m, 3), any length."""
        n = np.atleast_2d(np.asarray(directions, dtype=float))
        s, p, R = np.asarray(self.size, dtype=float), np.asarray(self.position, dtype=float), self.rotation
        local, base = n @ R, n @ p  # components in the shape's frame
        if self.kind == "sphere":
            return base + s[0] * np.linalg.norm(n, axis=1)
        if self.kind == "ellipsoid":
            return base + np.linalg.norm(local * s[:3], axis=1)
        if self.kind == "capsule":
            return base + s[1] * np.abs(local[:, 2]) + s[0] * np.linalg.norm(n, axis=1)
        if self.kind == "cylinder":
            return base + s[1] * np.abs(local[:, 2]) + s[0] * np.hypot(local[:, 0], local[:, 1])
        if self.kind == "box":
            return base + np.abs(local) @ s[:3]
        return base + np.max(local @ np.asarray(self.vertices, dtype=float).T, axis=1)

    def distance(self, points):
        """Euclidean distance (n,) from each of ``points`` (n, 3) to the solid shape (0 inside).

        Closed forms for sphere, capsule, cylinder and box; an ellipsoid's
        nearest point solves its one-variable secular equation by bisection;
        a mesh is its convex hull (as MuJoCo collides it), so its ``faces``
        must be the faces of that hull: the nearest point lies on a face
        whose plane has the point outside, and the distance is the least
        point-triangle distance over those faces.
        """
        x = np.atleast_2d(np.asarray(points, dtype=float))
        s = np.asarray(self.size, dtype=float)
        local = (x - np.asarray(self.position, dtype=float)) @ self.rotation
        if self.kind == "sphere":
            return np.maximum(np.linalg.norm(local, axis=1) - s[0], 0.0)
        if self.kind == "ellipsoid":
            return _ellipsoid_distance(local, s[:3])
        if self.kind == "capsule":
            axis = np.zeros_like(local)
            axis[:, 2] = np.clip(local[:, 2], -s[1], s[1])
            return np.maximum(np.linalg.norm(local - axis, axis=1) - s[0], 0.0)
        if self.kind == "cylinder":
            radial = np.maximum(np.hypot(local[:, 0], local[:, 1]) - s[0], 0.0)
            return np.hypot(radial, np.maximum(np.abs(local[:, 2]) - s[1], 0.0))
        if self.kind == "box":
            return np.linalg.norm(np.maximum(np.abs(local) - s[:3], 0.0), axis=1)
        a, b, c, normals, offsets = self._hull()
        return _hull_distance(np.ascontiguousarray(local), a, b, c, normals, offsets)

    def contains(self, points):
        """(n,) True where a point of ``points`` (n, 3) lies in the solid shape (a mesh: its convex hull)."""
        if self.kind != "mesh":
            return self.distance(points) == 0.0
        x = np.atleast_2d(np.asarray(points, dtype=float))
        local = (x - np.asarray(self.position, dtype=float)) @ self.rotation
        _, _, _, normals, offsets = self._hull()
        slack = 1e-12 * np.abs(np.asarray(self.vertices, dtype=float)).max()  # points on a face count as inside
        return np.all(local @ normals.T <= offsets + slack, axis=1)

    def _hull(self):
        """Triangles (a, b, c: (m, 3) each) of a mesh's hull faces, outward unit normals and plane offsets."""
        if self.faces is None:
            raise ValueError("faces: a mesh shape needs the faces of its convex hull here")
        hull = _Hull(self.vertices, self.faces)
        return (*hull.planar, hull.normals, hull.offsets)

    def closed_form(self):
        """Minimum-volume ellipsoid (centre, rotation, radii) of a sphere, ellipsoid, box or cylinder, else None."""
        s = np.asarray(self.size, dtype=float)
        if self.kind == "sphere":
            radii = np.full(3, s[0])
        elif self.kind == "ellipsoid":
            radii = s[:3].copy()
        elif self.kind == "box":
            radii = np.sqrt(3.0) * s[:3]
        elif self.kind == "cylinder":  # r sqrt(3/2), h sqrt(3): minimises R^2 H on the rim
            radii = np.array([s[0] * np.sqrt(1.5), s[0] * np.sqrt(1.5), s[1] * np.sqrt(3.0)])
        else:
            return None
        return np.array(self.position, dtype=float), np.array(self.rotation, dtype=float), radii


def fit_shapes(shapes):
    """Bounding ellipsoid (centre, rotation, radii) of the union of shapes (a lone primitive: its closed form)."""
    exact = shapes[0].closed_form() if len(shapes) == 1 else None
    return fit_atoms([a for shape in shapes for a in shape.atoms()], exact=exact)


def fit_atoms(atoms, *, exact=None, tolerance=1e-4):
    """Bounding ellipsoid (centre, rotation, radii) of atoms, with containment proven.

    ``exact``: a known minimum ellipsoid, only checked (and grown if needed).
    Otherwise the minimum-volume ellipsoid of a few samples of the atoms is
    refined: the point of each atom farthest outside it joins the samples,
    until none is outside by more than ``tolerance`` (also Khachiyan's) or
    after :data:`REFINE_ROUNDS` rounds.  The last ellipsoid is then grown by
    its containment factor.
    """
    if exact is None:
        points, weights = _samples(atoms), None
        for _ in range(REFINE_ROUNDS):
            c, R, r, weights = _mvee(points, weights, tolerance)
            far = [p for atom in atoms if atom.shape is not None
                   for p in [_farthest_point(c, R, r * (1.0 + tolerance), atom)] if p is not None]
            if not far:
                break
            points = np.vstack([points, far])
            weights = np.concatenate([weights, np.zeros(len(far))])
    else:
        c, R, r = exact
    return c, R, r * max(containment_factor(c, R, r, atoms), 1.0)


# ---------------------------------------------------------------- distances to shapes


def _ellipsoid_distance(local, radii):
    """Distance (n,) from points (n, 3) in an ellipsoid's frame to the solid ellipsoid.

    The nearest point of a point y outside is ``x_i = a_i^2 y_i / (a_i^2 + tau)``
    with ``tau > 0`` the root of ``sum (a_i y_i / (a_i^2 + tau))^2 = 1``, which
    decreases in tau and is at most 1 at ``tau = max(a) |y|``: bisection.
    """
    a2 = radii * radii
    outside = np.sum(local * local / a2, axis=1) > 1.0
    y = local[outside]
    lo = np.zeros(len(y))
    hi = np.max(radii) * np.linalg.norm(y, axis=1)
    for _ in range(200):
        mid = 0.5 * (lo + hi)
        big = np.sum((radii * y / (a2 + mid[:, None])) ** 2, axis=1) > 1.0
        lo, hi = np.where(big, mid, lo), np.where(big, hi, mid)
        if np.all(hi - lo <= 1e-15 * np.maximum(hi, 1e-300)):
            break
    out = np.zeros(len(local))
    out[outside] = np.linalg.norm(y - a2 * y / (a2 + hi[:, None]), axis=1)
    return out


@numba.njit(cache=True, nogil=True, no_cfunc_wrapper=True, forceinline=False)
def _point_triangle_d2(px, py, pz, a, b, c):
    """Squared distance from p to the triangle abc (Ericson, Real-Time Collision Detection, 5.1.5), in scalars:
    a hull test calls it for many faces of many points, and small arrays made there cost more than the
    arithmetic."""
    abx, aby, abz = b[0] - a[0], b[1] - a[1], b[2] - a[2]
    acx, acy, acz = c[0] - a[0], c[1] - a[1], c[2] - a[2]
    apx, apy, apz = px - a[0], py - a[1], pz - a[2]
    d1, d2 = abx * apx + aby * apy + abz * apz, acx * apx + acy * apy + acz * apz
    if d1 <= 0.0 and d2 <= 0.0:
        qx, qy, qz = a[0], a[1], a[2]
    else:
        bpx, bpy, bpz = px - b[0], py - b[1], pz - b[2]
        d3, d4 = abx * bpx + aby * bpy + abz * bpz, acx * bpx + acy * bpy + acz * bpz
        cpx, cpy, cpz = px - c[0], py - c[1], pz - c[2]
        d5, d6 = abx * cpx + aby * cpy + abz * cpz, acx * cpx + acy * cpy + acz * cpz
        va, vb, vc = d3 * d6 - d5 * d4, d5 * d2 - d1 * d6, d1 * d4 - d3 * d2
        if d3 >= 0.0 and d4 <= d3:
            qx, qy, qz = b[0], b[1], b[2]
        elif vc <= 0.0 and d1 >= 0.0 and d3 <= 0.0:
            s = d1 / (d1 - d3)
            qx, qy, qz = a[0] + s * abx, a[1] + s * aby, a[2] + s * abz
        elif d6 >= 0.0 and d5 <= d6:
            qx, qy, qz = c[0], c[1], c[2]
        elif vb <= 0.0 and d2 >= 0.0 and d6 <= 0.0:
            s = d2 / (d2 - d6)
            qx, qy, qz = a[0] + s * acx, a[1] + s * acy, a[2] + s * acz
        elif va <= 0.0 and d4 - d3 >= 0.0 and d5 - d6 >= 0.0:
            s = (d4 - d3) / ((d4 - d3) + (d5 - d6))
            qx, qy, qz = b[0] + s * (c[0] - b[0]), b[1] + s * (c[1] - b[1]), b[2] + s * (c[2] - b[2])
        else:
            denom = 1.0 / (va + vb + vc)
            v, w = vb * denom, vc * denom
            qx, qy, qz = a[0] + abx * v + acx * w, a[1] + aby * v + acy * w, a[2] + abz * v + acz * w
    ex, ey, ez = px - qx, py - qy, pz - qz
    return ex * ex + ey * ey + ez * ez


@numba.njit(cache=True, nogil=True, no_cfunc_wrapper=True, forceinline=False)
def _hull_distance(points, a, b, c, normals, offsets):
    """Distance (n,) from points to a convex polytope given by its faces (triangles a, b, c; outward planes).

    Inside every plane: 0.  Otherwise the nearest boundary point lies on a
    face whose plane has the point outside (the point minus its nearest
    point is a non-negative mix of the normals of the faces there, and it
    has a positive dot product with one of them), so the least
    point-triangle distance over those faces is the distance.
    """
    out = np.zeros(points.shape[0])
    for k in range(points.shape[0]):
        px, py, pz = points[k, 0], points[k, 1], points[k, 2]
        best = np.inf
        for f in range(a.shape[0]):
            if normals[f, 0] * px + normals[f, 1] * py + normals[f, 2] * pz > offsets[f]:
                best = min(best, _point_triangle_d2(px, py, pz, a[f], b[f], c[f]))
        if best < np.inf:
            out[k] = np.sqrt(best)
    return out


# ---------------------------------------------------------------- samples of the atoms


def _unit_sphere(n):
    """n nearly uniform points on the unit sphere (Fibonacci lattice), plus the 6 axis poles."""
    k = np.arange(n) + 0.5
    z = 1.0 - 2.0 * k / n
    r = np.sqrt(1.0 - z * z)
    phi = k * np.pi * (3.0 - np.sqrt(5.0))
    pts = np.stack([r * np.cos(phi), r * np.sin(phi), z], axis=1)
    return np.vstack([pts, np.eye(3), -np.eye(3)])


def _unit_circle(n):
    a = 2.0 * np.pi * np.arange(n) / n
    return np.stack([np.cos(a), np.sin(a), np.zeros(n)], axis=1)


def _samples(atoms):
    """A few points on each atom (all of a point set), where the fit starts."""
    pts = []
    sphere, circle = _unit_sphere(20), _unit_circle(12)
    for atom in atoms:
        if atom.shape is None:
            pts.append(np.atleast_2d(atom.centre))
        else:
            flat = np.linalg.matrix_rank(atom.shape, tol=1e-12 * max(np.abs(atom.shape).max(), 1e-300)) < 3
            pts.append(atom.centre + (circle if flat else sphere) @ atom.shape.T)
    return np.vstack(pts)


def _farthest_point(centre, rotation, radii, atom):
    """The point of an ellipsoidal atom farthest outside the ellipsoid, or None when the atom is inside."""
    L = (rotation / radii).T
    bound, u = _trust_region(L @ (atom.centre - centre), np.ascontiguousarray(L @ atom.shape))
    return atom.centre + atom.shape @ u if bound > 1.0 else None


# ---------------------------------------------------------------- minimum-volume ellipsoid of points


@numba.njit(cache=True, nogil=True, no_cfunc_wrapper=True, forceinline=False)
def _khachiyan_weights(P, u, tolerance, max_iterations):
    """Weights u of the points P (n, 3) whose moment ellipsoid is the minimum-volume one, improved in place.

    Khachiyan's multiplicative steps with Todd-Yildirim drop steps, from the
    weights given; stops when every point is within ``1 + tolerance`` of the
    optimality bound.  Each step changes the moment matrix by a rank-one
    term, so its inverse follows by Sherman-Morrison.
    """
    n = P.shape[0]
    d1 = 4.0
    Q = np.ones((n, 4))
    for i in range(n):  # element by element (see mjccd.bernstein's _jit)
        Q[i, 0] = P[i, 0]
        Q[i, 1] = P[i, 1]
        Q[i, 2] = P[i, 2]
    M = np.empty(n)
    v = np.empty(4)
    for iteration in range(max_iterations):
        if iteration % 1000 == 0:  # afresh now and then: the rank-one updates gather rounding errors
            Xi = np.linalg.inv((Q.T * u) @ Q)
        j, k = 0, -1
        for i in range(n):
            m = 0.0
            for a in range(4):
                row = 0.0
                for b in range(4):
                    row += Xi[a, b] * Q[i, b]
                m += Q[i, a] * row
            M[i] = m
            if M[i] > M[j]:
                j = i
            if u[i] > 0.0 and (k < 0 or M[i] < M[k]):
                k = i
        up = M[j] - d1
        down = d1 - M[k]
        if up <= tolerance * d1 and down <= tolerance * d1:
            break
        if up >= down:
            i, step = j, up / (d1 * (M[j] - 1.0))
            u *= 1.0 - step
            u[j] += step
            scale, weight = 1.0 - step, step
        else:
            limit = u[k] / (1.0 - u[k])
            step = limit if M[k] <= 1.0 else min(down / (d1 * (M[k] - 1.0)), limit)
            u *= 1.0 + step
            u[k] = max(u[k] - step, 0.0)
            i, scale, weight = k, 1.0 + step, -step
        # X <- scale X + weight q q^T with q = Q[i]
        for a in range(4):
            v[a] = Xi[a, 0] * Q[i, 0] + Xi[a, 1] * Q[i, 1] + Xi[a, 2] * Q[i, 2] + Xi[a, 3] * Q[i, 3]
        f = weight / (scale + weight * M[i])
        for a in range(4):
            for b in range(4):
                Xi[a, b] = (Xi[a, b] - f * v[a] * v[b]) / scale
    return u


def mvee(points, *, tolerance=1e-4, max_iterations=MAX_ITERATIONS):
    """Minimum-volume enclosing ellipsoid of points (n, 3): (centre, rotation, radii).

    The result encloses the points only up to ``tolerance``;
    :func:`fit_atoms` grows it until containment of the geometry is proven.
    """
    return _mvee(points, None, tolerance, max_iterations)[:3]


def _mvee(points, weights, tolerance, max_iterations=MAX_ITERATIONS):
    """:func:`mvee` from Khachiyan weights (uniform when None), and the weights it ends with."""
    P = np.ascontiguousarray(points, dtype=float)
    centred = P - P.mean(axis=0)
    if np.linalg.matrix_rank(centred, tol=1e-12 * max(np.abs(centred).max(), 1e-300)) < 3:
        raise ValueError("points: they lie in a plane or a line, no bounding ellipsoid")
    u = np.full(len(P), 1.0 / len(P)) if weights is None else np.array(weights, dtype=float)
    u = _khachiyan_weights(P, u, tolerance, max_iterations)
    c = P.T @ u
    cov = (P.T * u) @ P - np.outer(c, c)
    evals, evecs = np.linalg.eigh(cov)
    if evals[0] <= 1e-14 * max(evals[-1], 1e-300):
        raise ValueError("points: they lie in a plane or a line, no bounding ellipsoid")
    radii = np.sqrt(3.0 * evals)
    if np.linalg.det(evecs) < 0.0:
        evecs[:, 0] = -evecs[:, 0]
    return c, evecs, radii, u


# ---------------------------------------------------------------- containment


def ball_max_bound(a, B):
    """Upper bound of ``max_{|u| <= 1} |a + B u|^2``, tight up to rounding (see :func:`_trust_region`)."""
    return _trust_region(np.asarray(a, dtype=float), np.ascontiguousarray(B, dtype=float))[0]


@numba.njit(cache=True, nogil=True, no_cfunc_wrapper=True, forceinline=False)
def _trust_region(a, B):
    """``(bound, u)``: an upper bound of ``max_{|u| <= 1} |a + B u|^2``, tight up to rounding, and its maximiser.

    Weak duality of the trust-region problem: for every ``lam > lambda_max(H)``,
    ``|a + B u|^2 <= |a|^2 + psi(lam)`` with ``psi(lam) = lam + g^T (lam I - H)^-1 g``,
    ``H = B^T B``, ``g = B^T a``.  ``psi`` is convex and its minimum (where
    ``sum gamma_i^2 / (lam - h_i)^2 = 1``) lies in ``(h_max, h_max + |g|]``
    (the upper end raised to ``h_max (1 + 1e-15)`` when ``|g|`` is below rounding);
    bisection keeps the upper end, where the bound is valid, and closes on it.
    The maximiser is ``u = (lam I - H)^-1 g`` there, scaled to ``|u| = 1`` (a
    top eigenvector when ``g = 0``).
    """
    H = B.T @ B
    g = B.T @ a
    h, V = np.linalg.eigh(H)
    gamma = V.T @ g
    gamma2 = gamma * gamma
    top = h[-1]
    base = a @ a
    gnorm = np.sqrt(gamma2.sum())
    if gnorm == 0.0:
        return base + max(top, 0.0), V[:, -1].copy()
    # any lam > h_max gives a valid bound: keep hi above h_max also when |g| is lost next to it in rounding
    lo, hi = top, top + max(gnorm, 1e-15 * abs(top))
    for _ in range(200):
        mid = 0.5 * (lo + hi)
        if not lo < mid < hi:
            break
        if np.sum(gamma2 / (mid - h) ** 2) > 1.0:
            lo = mid
        else:
            hi = mid
    u = V @ (gamma / (hi - h))
    return base + hi + np.sum(gamma2 / (hi - h)), u / np.sqrt(u @ u)


def containment_factor(centre, rotation, radii, atoms):
    """``max |y|`` over all atoms, ``y = diag(1/radii) R^T (x - centre)``: <= 1 means contained."""
    L = (rotation / radii).T
    worst = 0.0
    for atom in atoms:
        if atom.shape is None:
            y = (np.atleast_2d(atom.centre) - centre) @ L.T
            worst = max(worst, float(np.max(np.einsum("ij,ij->i", y, y))))
        else:
            bound, _ = _trust_region(L @ (atom.centre - centre), np.ascontiguousarray(L @ atom.shape))
            worst = max(worst, bound)
    return float(np.sqrt(worst))


# ---------------------------------------------------------------- covers to a tolerance

DEFAULT_TOLERANCE = 0.01
"""Default one-sided overshoot of a cover, in metres (1 cm).

At 1 cm the capsule limbs of dm-control's humanoid (radius 3-6 cm) take two
or three ellipsoids each instead of one that overshoots their ends by 7-8 cm;
half a centimetre costs about one more ellipsoid per limb, and every ellipsoid
adds pairs to check at every step.  Lengths are in the model's unit: 0.01 is
1 cm in a model written in metres."""
MAX_ELLIPSOIDS = 64
"""A shape that needs more ellipsoids than this at the asked tolerance is refused (:func:`cover_shape`)."""
LOOSENINGS = 12
""":func:`cover_loosened` tries a shape that needs too many ellipsoids within 2, 4, ... 4096 times the tolerance."""
_DESIGN = 1.0 - 1e-9  # covers aim at this share of the tolerance: growing to proven containment stays inside it
_STRETCHES = (1.0, 2.0, 4.0)  # how far a mesh piece's ellipsoid may reach along the axes it was cut on
_GROWTHS = (1.0, 1.6, 2.5, 4.0)  # how mesh grid cells may grow from the ends of an axis to its middle
_GRID_CELLS = 16  # nested grids are tried up to this many cells; past it only the bisection
_MESH_DIRECTIONS = 1000  # directions in which candidate ellipsoids of a mesh cell are compared with the hull


def cover_shape(shape, tolerance, *, max_ellipsoids=MAX_ELLIPSOIDS):
    """Fewest ellipsoids whose union contains ``shape``, none reaching farther than ``tolerance`` from it.

    Returns ``[(centre (3,), rotation (3, 3), radii (3,)), ...]`` in the
    frame ``shape`` is placed in.  Two guarantees, of different kinds:

    * **Containment is proven.**  The shape is cut into convex pieces whose
      union is the shape, each piece the convex hull of atoms (balls, disks,
      points); every ellipsoid is grown by :func:`containment_factor` of its
      piece, an exact upper bound, so every point of the shape lies in some
      ellipsoid.
    * **One-sided overshoot.**  For a convex shape G the farthest point of an
      ellipsoid E from G is ``max_n h_E(n) - h_G(n)`` over unit directions
      (support functions), so ``E`` lies within t of G iff it lies in the
      rounded shape ``G + B(t)``.  Sphere, ellipsoid, capsule, cylinder and
      box covers meet that in closed form; each ellipsoid of a mesh cover is
      proven within t by a branch and bound over its surface with exact
      distances to the hull (:func:`_surface_within`).

    Split rules (t the tolerance):

    * sphere, ellipsoid: the shape itself, one ellipsoid, overshoot 0.
    * capsule (radius r, half length h): spheroids on the axis of equatorial
      radius at most ``R = r + t``; such a spheroid lies in the rounded
      capsule iff its tips stay within ``h + R`` of the centre.  An end
      spheroid holds the end ball and reaches as far down the axis as that
      allows; spheroids in between are as long as their tips allow, placed
      greedily from one end (greedy is optimal for covering an interval).
      One spheroid when it can hold both end balls.
    * cylinder: like a box whose cross-section stays whole (below).
    * box (half sizes A): a grid of cells, each with the smallest axis-aligned
      ellipsoid through its corners whose semi-axes stay below
      ``A_i + t - |c_i|`` (exactly the condition for lying in the rounded
      box).  The corner condition separates by axis, so each axis is cut on
      its own: thin cells at the faces growing geometrically inwards, and
      the grid with the fewest cells wins (slabs are grids with one cut axis).
    * mesh: as MuJoCo collides it, the convex hull of its vertices (its
      ``faces`` must be the hull's).  It is cut into boxes along the axes of
      its minimum-volume ellipsoid: nested grids of up to
      :data:`_GRID_CELLS` cells (slabs first, fewest cells first, even or
      thin at the ends), and an adaptive bisection of the cells that
      overshoot; the fewer cells win.  A cell of the hull is a convex
      polytope whose vertices lie among the hull's vertices in the box, the
      points where hull edges cross box faces and box edges cross hull
      faces, and the box corners inside the hull; an ellipsoid that holds
      those points holds the whole cell -- the solid, not only its faces
      (a union of ellipsoids around the hull's vertices or faces would
      not).  Each cell gets the candidate ellipsoid that overshoots least
      (:func:`_piece_ellipsoid`), accepted only when proven within t.

    After the count is fixed, capsule and cylinder covers are sized for the
    least tolerance that needs no more ellipsoids, and box cells get the
    smallest ellipsoid their caps allow, so covers are no larger than their
    count requires.  The count never grows when the tolerance grows (for a
    mesh, because only the acceptance of a cell depends on the tolerance).

    Args:
        shape: :class:`Shape`; a mesh's ``vertices`` may be only its hull vertices.
        tolerance: the most any point of an ellipsoid may lie from the shape (> 0).
        max_ellipsoids: refuse (InputError) a shape that needs more ellipsoids than this.
    """
    t = float(tolerance) if isinstance(tolerance, (int, float, np.floating, np.integer)) else np.nan
    if not (np.isfinite(t) and t > 0.0) or isinstance(tolerance, bool):
        raise InputError(f"tolerance: expected a positive length, got {tolerance!r}")
    if isinstance(max_ellipsoids, bool) or not isinstance(max_ellipsoids, (int, np.integer)) or max_ellipsoids < 1:
        raise InputError(f"max_ellipsoids: expected a positive integer, got {max_ellipsoids!r}")
    if shape.kind in ("sphere", "ellipsoid"):
        return [_contain(shape.closed_form(), shape.atoms())]
    cover = {"capsule": _capsule_cover, "cylinder": _cylinder_cover, "box": _box_cover,
             "mesh": _mesh_cover}[shape.kind](shape, t * _DESIGN, int(max_ellipsoids))
    if cover is None:
        raise TooManyEllipsoids(f"tolerance: this {shape.kind} needs more than {int(max_ellipsoids)} ellipsoids to "
                                f"stay within {t:g} of it; raise the tolerance or max_ellipsoids")
    return cover


def cover_loosened(shape, tolerance, *, max_ellipsoids=MAX_ELLIPSOIDS):
    """``(cover, used)``: :func:`cover_shape` within ``tolerance``, or, when that needs more than
    ``max_ellipsoids``, within the least of 2, 4, ... 2 ** :data:`LOOSENINGS` times it that needs no more
    (``used``, for the caller to say so).  Raises :class:`TooManyEllipsoids` when none is enough."""
    used = tolerance
    for _ in range(LOOSENINGS + 1):
        try:
            return cover_shape(shape, used, max_ellipsoids=max_ellipsoids), used
        except TooManyEllipsoids:
            used *= 2.0
    raise TooManyEllipsoids(f"needs more than {max_ellipsoids} ellipsoids even within {used / 2:g} of it")


def _contain(ellipsoid, atoms, margin=0.0):
    """The ellipsoid grown by its containment factor of the atoms (and ``1 + margin``)."""
    c, R, r = ellipsoid
    return c, R, r * max(containment_factor(c, R, r, atoms), 1.0) * (1.0 + margin)


def _disk(shape, z, radius):
    R = shape.rotation
    return Atom(np.asarray(shape.position, dtype=float) + z * R[:, 2], R * np.array([radius, radius, 0.0]))


def _axial(shape, z, a, b):
    """A spheroid (a, a, b) centred at ``z`` on the axis of a capsule or cylinder."""
    centre = np.asarray(shape.position, dtype=float) + z * shape.rotation[:, 2]
    return centre, shape.rotation.copy(), np.array([a, a, b])


def _least_tolerance(count_at, t, n):
    """The least tolerance in (0, t] at which ``count_at`` needs at most n ellipsoids (to a part in 1e4)."""
    lo, hi = 0.0, t
    while hi - lo > 1e-4 * t:
        mid = 0.5 * (lo + hi)
        if count_at(mid) <= n:
            hi = mid
        else:
            lo = mid
    return hi


# ---------------------------------------------------------------- capsules


def _capsule_plan(r, h, t, limit):
    """Axial spheroids ``(z, a, b, z_lo, z_hi, ends)`` covering a capsule within t, or None past ``limit``.

    ``[z_lo, z_hi]`` is the stretch of the axis whose disks the spheroid
    holds; ``ends`` says which end balls it holds (+1 top, -1 bottom, 2 both,
    0 none).  Equatorial radius ``a <= R = r + t`` and tips within ``h + R``
    of the centre place a spheroid inside the rounded capsule.  An end
    spheroid centred ``d`` below an end with ``b = d + R`` holds the end ball
    iff ``(a^2 - r^2)(2dR + R^2 - a^2) >= d^2 r^2``; it holds the disks down
    to ``b sqrt(1 - r^2/a^2)`` below its centre.
    """
    R = r + t
    a = r + t * np.linspace(0.0, 1.0, 257)[1:]
    q = a * a - r * r
    d = (R * q + np.sqrt((R * q) ** 2 + r * r * q * (R * R - a * a))) / (r * r)
    whole = d >= h
    if whole.any():
        k = int(np.argmax(whole))  # the thinnest spheroid that holds both end balls
        return [(0.0, a[k], h + R, -h, h, 2)]
    reach = d + (d + R) * np.sqrt(1.0 - r * r / (a * a))
    k = int(np.argmax(reach))
    a_end, d_end, reach = a[k], d[k], reach[k]
    plan = [(h - d_end, a_end, d_end + R, max(h - reach, -h), h, 1)]
    rho = np.sqrt(1.0 - (r / R) ** 2)
    y, stop = h - reach, -h + reach
    while y > stop:
        if len(plan) + 1 >= limit:
            return None
        z = (y - (h + R) * rho) / (1.0 - rho)
        if z < 0.0:
            z = max((y - (h + R) * rho) / (1.0 + rho), -h)
        b = h + R - abs(z)
        low = z - b * rho
        plan.append((z, R, b, max(low, -h), min(y, h), 0))
        y = low
    plan.append((d_end - h, a_end, d_end + R, -h, min(-h + reach, h), -1))
    return plan if len(plan) <= limit else None


def _capsule_cover(shape, t, limit):
    r, h = (float(x) for x in np.asarray(shape.size, dtype=float)[:2])
    plan = _capsule_plan(r, h, t, limit)
    if plan is None:
        return None
    n = len(plan)
    least = _least_tolerance(lambda u: len(_capsule_plan(r, h, u, n) or range(n + 1)), t, n)
    p, axis = np.asarray(shape.position, dtype=float), shape.rotation[:, 2]
    cover = []
    for z, a, b, z_lo, z_hi, ends in _capsule_plan(r, h, least, n):
        top = [ball(p + h * axis, r)] if ends in (1, 2) else [_disk(shape, z_hi, r)]
        bottom = [ball(p - h * axis, r)] if ends in (-1, 2) else [_disk(shape, z_lo, r)]
        cover.append(_contain(_axial(shape, z, a, b), top + bottom))
    return cover


# ---------------------------------------------------------------- boxes and cylinders


def _axis_ratio(A, t, n):
    """Least q such that n cells cover [-A, A] with half widths ``w <= q (A + t - |centre|)``.

    Cells laid greedily from an end grow geometrically: with ``g = (1 + q)/(1 - q)``
    the k-th left boundary is ``t g^k - (A + t)``.  n = 2m cells meet in the
    middle (``t g^m = A + t``); n = 2m + 1 leave a middle cell of half width
    ``q (A + t)`` (``t g^m = (A + t)(1 - q)``).
    """
    m = n // 2
    if n % 2 == 0:
        g = ((A + t) / t) ** (1.0 / m)
        return (g - 1.0) / (g + 1.0)
    lo, hi = 0.0, A / (A + t)
    for _ in range(200):
        mid = 0.5 * (lo + hi)
        if not lo < mid < hi:
            break
        if t * ((1.0 + mid) / (1.0 - mid)) ** m >= (A + t) * (1.0 - mid):
            hi = mid
        else:
            lo = mid
    return hi


def _axis_cells(A, t, n, q):
    """Boundaries (n + 1,) of the n symmetric cells of ratio q covering [-A, A] (see :func:`_axis_ratio`)."""
    m = n // 2
    g = (1.0 + q) / (1.0 - q)
    left = np.minimum(t * g ** np.arange(m + 1) - (A + t), 0.0)
    left[0] = -A
    if n % 2 == 0:
        left[-1] = 0.0
        return np.concatenate([left, -left[-2::-1]])
    left[-1] = min(left[-1], -q * (A + t)) if m else -A
    return np.concatenate([left, -left[::-1]])


def _smallest_radii(half, cap, weight):
    """Semi-axes minimising ``prod alpha^weight`` with ``sum (half/alpha)^2 <= 1`` and ``alpha <= cap``.

    The optimum is ``alpha_k = min(cap_k, half_k sqrt(2 mu / weight_k))`` for
    the ``mu`` that makes the sum 1, found by bisection (None if even the caps
    leave the sum above 1).
    """
    half, cap, weight = (np.asarray(x, dtype=float) for x in (half, cap, weight))
    if np.sum((half / cap) ** 2) > 1.0 + 1e-12:
        return None

    def radii(mu):
        return np.minimum(cap, half * np.sqrt(2.0 * mu / weight))

    lo, hi = weight.sum() / 2.0, max(weight.sum() / 2.0, float(np.max(weight * (cap / half) ** 2)) / 2.0)
    for _ in range(200):
        mid = np.sqrt(lo * hi)
        if not lo < mid < hi:
            break
        if np.sum((half / radii(mid)) ** 2) > 1.0:
            lo = mid
        else:
            hi = mid
    return radii(hi)


def _box_cover(shape, t, limit):
    A = np.asarray(shape.size, dtype=float)[:3]
    ratios = [[_axis_ratio(a, t, n) ** 2 for n in range(1, limit + 1)] for a in A]
    best = None
    for n0 in range(1, limit + 1):
        for n1 in range(1, limit // n0 + 1):
            for n2 in range(1, limit // (n0 * n1) + 1):
                total = ratios[0][n0 - 1] + ratios[1][n1 - 1] + ratios[2][n2 - 1]
                if total <= 1.0:
                    key = (n0 * n1 * n2, total)
                    if best is None or key < best[0]:
                        best = (key, (n0, n1, n2))
                    break  # more cells along axis 2 only add ellipsoids
    if best is None:
        return None
    counts = best[1]
    cells = [_axis_cells(a, t, n, np.sqrt(ratios[i][n - 1])) for i, (a, n) in enumerate(zip(A, counts))]
    p, R = np.asarray(shape.position, dtype=float), shape.rotation
    signs = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)], float)
    cover = []
    for i in range(counts[0]):
        for j in range(counts[1]):
            for k in range(counts[2]):
                lo = np.array([cells[0][i], cells[1][j], cells[2][k]])
                hi = np.array([cells[0][i + 1], cells[1][j + 1], cells[2][k + 1]])
                c, w = 0.5 * (lo + hi), 0.5 * (hi - lo)
                radii = _smallest_radii(w, A + t - np.abs(c), np.ones(3))
                cover.append(_contain((p + R @ c, R.copy(), radii), [Atom(p + (c + signs * w) @ R.T)]))
    return cover


def _cylinder_cover(shape, t, limit):
    r, h = (float(x) for x in np.asarray(shape.size, dtype=float)[:2])
    room = 1.0 - (r / (r + t)) ** 2  # what the rim circle leaves of the corner condition for the axis
    n = next((n for n in range(1, limit + 1) if _axis_ratio(h, t, n) ** 2 <= room), None)
    if n is None:
        return None
    bounds = _axis_cells(h, t, n, _axis_ratio(h, t, n))
    cover = []
    for lo, hi in zip(bounds[:-1], bounds[1:]):
        c, w = 0.5 * (lo + hi), 0.5 * (hi - lo)
        a, b = _smallest_radii([r, w], [r + t, h + t - abs(c)], [2.0, 1.0])
        cover.append(_contain(_axial(shape, c, a, b), [_disk(shape, lo, r), _disk(shape, hi, r)]))
    return cover


# ---------------------------------------------------------------- meshes


def _grids(limit):
    """``((k0, k1, k2), growth)`` of the nested grids to try: at most ``limit`` cells, fewest first.

    k0 >= k1 >= k2 cells along the longest, middle and shortest axis; cells
    even (growth 1) or growing from both ends inwards (:data:`_GROWTHS`),
    which suits hulls with flat ends and sharp rims as thin end cells suit a box.
    """
    grids = [(k0, k1, k2) for k0 in range(1, limit + 1) for k1 in range(1, k0 + 1) for k2 in range(1, k1 + 1)
             if k0 * k1 * k2 <= limit]
    grids.sort(key=lambda g: (g[0] * g[1] * g[2], g[1], g[2]))
    # growing cells only where there are three or more, and never thinner than 1/1000 of the widest
    return [(g, growth) for g in grids for growth in _GROWTHS
            if growth == 1.0 or (max(g) > 2 and growth ** ((max(g) - 1) // 2) <= 1e3)]


class _Hull:
    """A convex polytope as vertices (n, 3) and triangles (m, 3), with its edges and outward face planes."""

    def __init__(self, vertices, faces):
        self.vertices = np.ascontiguousarray(vertices, dtype=float)
        self.faces = np.asarray(faces, dtype=np.int64)
        pairs = np.sort(np.concatenate([self.faces[:, [0, 1]], self.faces[:, [1, 2]], self.faces[:, [2, 0]]]), axis=1)
        self.edges = np.unique(pairs, axis=0)
        a, b, c = (self.vertices[self.faces[:, k]] for k in range(3))
        self.triangles = (a, b, c)
        normals = np.cross(b - a, c - a)
        lengths = np.linalg.norm(normals, axis=1)
        keep = lengths > 0.0
        normals = normals[keep] / lengths[keep, None]
        inward = np.einsum("ij,ij->i", normals, self.vertices.mean(axis=0) - a[keep]) > 0.0
        normals[inward] = -normals[inward]
        self.normals = np.ascontiguousarray(normals)
        self.offsets = np.einsum("ij,ij->i", normals, a[keep])
        self.planar = tuple(np.ascontiguousarray(x[keep]) for x in (a, b, c))
        self.slack = 1e-12 * max(np.abs(self.vertices).max(), 1e-300)

    def distance(self, points):
        """Distance (n,) from points (n, 3) to the solid polytope (:func:`_hull_distance`)."""
        return _hull_distance(np.ascontiguousarray(points, dtype=float), *self.planar, self.normals, self.offsets)

    def cut(self, lo, hi):
        """A superset of the vertices of the polytope cut by the box ``[lo, hi]`` ((k, 3); empty when they miss).

        Each vertex of the cut lies on three planes: three of the polytope
        (one of its vertices), two of it and one of the box (an edge through
        a box face), one of it and two of the box (a box edge through a
        face), or three of the box (a box corner inside the polytope).
        """
        V, tol = self.vertices, self.slack
        a, b, c = self.triangles
        found = [_cut_points(V, self.edges, a, b, c, np.asarray(lo, dtype=float), np.asarray(hi, dtype=float), tol)]
        corners = np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])])
        found.append(corners[np.all(corners @ self.normals.T <= self.offsets + tol, axis=1)])
        return np.vstack(found)


@numba.njit(cache=True, nogil=True, no_cfunc_wrapper=True, forceinline=False)
def _in_box(x, y, z, lo, hi, tol):
    return (lo[0] - tol <= x <= hi[0] + tol) and (lo[1] - tol <= y <= hi[1] + tol) and (lo[2] - tol <= z <= hi[2] + tol)


@numba.njit(cache=True, nogil=True, no_cfunc_wrapper=True, forceinline=False)
def _cut_points(V, edges, a, b, c, lo, hi, tol):
    """The points of :meth:`_Hull.cut` but the box corners, in its order: the vertices in the box, the edges
    through the box's faces, the box's edges through the triangles (a, b, c), each kept within ``tol`` of the
    box.  Compiled: a mesh cover cuts thousands of cells."""
    out = np.empty((V.shape[0] + 6 * edges.shape[0] + 12 * a.shape[0], 3))
    n = 0
    for k in range(V.shape[0]):
        if _in_box(V[k, 0], V[k, 1], V[k, 2], lo, hi, tol):
            for m in range(3):
                out[n, m] = V[k, m]
            n += 1
    x = np.empty(3)
    for axis in range(3):
        for value in (lo[axis], hi[axis]):
            for e in range(edges.shape[0]):
                A, B = V[edges[e, 0]], V[edges[e, 1]]
                da, db = A[axis] - value, B[axis] - value
                if not da * db < 0.0:
                    continue
                f = da / (da - db)
                for m in range(3):
                    x[m] = A[m] + (B[m] - A[m]) * f
                x[axis] = value
                if _in_box(x[0], x[1], x[2], lo, hi, tol):
                    for m in range(3):
                        out[n, m] = x[m]
                    n += 1
    for axis in range(3):
        i, j = (1, 2) if axis == 0 else ((0, 2) if axis == 1 else (0, 1))
        for u in (lo[i], hi[i]):
            for v in (lo[j], hi[j]):
                for f in range(a.shape[0]):
                    det = (b[f, i] - a[f, i]) * (c[f, j] - a[f, j]) - (c[f, i] - a[f, i]) * (b[f, j] - a[f, j])
                    if det == 0.0:  # a face parallel to the box edge meets it only on edges of faces that are not
                        continue
                    s1 = ((u - a[f, i]) * (c[f, j] - a[f, j]) - (c[f, i] - a[f, i]) * (v - a[f, j])) / det
                    s2 = ((b[f, i] - a[f, i]) * (v - a[f, j]) - (u - a[f, i]) * (b[f, j] - a[f, j])) / det
                    if not (s1 >= -1e-12 and s2 >= -1e-12 and s1 + s2 <= 1.0 + 1e-12):
                        continue
                    x[axis] = a[f, axis] + s1 * (b[f, axis] - a[f, axis]) + s2 * (c[f, axis] - a[f, axis])
                    x[i], x[j] = u, v
                    if _in_box(x[0], x[1], x[2], lo, hi, tol):
                        for m in range(3):
                            out[n, m] = x[m]
                        n += 1
    return out[:n]


def _spacing(k, growth):
    """Boundaries (k + 1,) in [0, 1] of k cells that grow by ``growth`` from both ends to the middle (1: even)."""
    m = k // 2
    widths = growth ** np.arange(m, dtype=float)
    cells = np.concatenate([widths, [growth ** m] if k % 2 else [], widths[::-1]])
    bounds = np.concatenate([[0.0], np.cumsum(cells) / cells.sum()])
    bounds[-1] = 1.0
    return bounds


def _nested_cells(hull, counts, growth):
    """Point sets of the cells of a nested grid: each cell cut along its own extent, axis by axis (:func:`_spacing`)."""
    V = hull.vertices
    boxes = [(V.min(axis=0), V.max(axis=0))]
    for axis, k in enumerate(counts):
        if k == 1:
            continue
        cut = []
        for lo, hi in boxes:
            points = hull.cut(lo, hi)
            if len(points) == 0:
                continue
            start, stop = points[:, axis].min(), points[:, axis].max()
            bounds = start + (stop - start) * _spacing(k, growth)
            bounds[-1] = stop
            for j in range(k):
                low, high = lo.copy(), hi.copy()
                low[axis], high[axis] = bounds[j], bounds[j + 1]
                cut.append((low, high))
        boxes = cut
    for lo, hi in boxes:
        piece = hull.cut(lo, hi)
        if len(piece):
            yield piece


def _thick(points):
    """The points, plus copies moved by a hair along any direction they do not span (a flat cell)."""
    centred = points - points.mean(axis=0)
    _, sv, vt = np.linalg.svd(centred, full_matrices=True)
    scale = sv[0] if len(sv) and sv[0] > 0.0 else 1.0
    flat = [vt[k] for k in range(3) if k >= len(sv) or sv[k] <= 1e-9 * scale]
    hair = 1e-9 * max(np.abs(centred).max(), np.abs(points).max(), 1e-300)
    for normal in flat:
        points = np.vstack([points, points + hair * normal, points - hair * normal])
    return points


def _ellipsoid_support(centre, rotation, radii, directions):
    """``h_E(n) = c . n + |diag(radii) R^T n|`` for directions (m, 3)."""
    return directions @ centre + np.linalg.norm((directions @ rotation) * radii, axis=1)


def _support_gap(centre, rotation, radii, vertices, directions, support=None):
    """``h_E(n) - h_V(n)`` for unit directions (m, 3): how far the ellipsoid reaches past the hull of the vertices.

    ``support``: ``h_V`` on ``directions`` when already known.
    """
    if support is None:
        support = np.max(directions @ vertices.T, axis=1)
    return _ellipsoid_support(centre, rotation, radii, directions) - support


def _ascend(f, directions, values, count=4, max_steps=200):
    """Largest value of ``f`` on the unit sphere: local pattern ascent from the ``count`` best ``directions``.

    Steps of 0.05 rad halve down to 1e-5 rad (near a smooth maximum the
    error is quadratic in the angle); on a ridge, where the pattern would
    crawl, ``max_steps`` rounds end it.  Never below the sampled maximum.
    """
    order = np.argsort(values)[::-1][:count]
    n, best = directions[order].copy(), values[order].copy()
    step = np.full(len(n), 0.05)
    rows = np.arange(len(n))
    for _ in range(max_steps):
        if not np.any(step > 1e-5):
            break
        x, y, z = n[:, 0], n[:, 1], n[:, 2]
        use_x = np.abs(x) < 0.9  # tangent basis: e1 = n x (x or y axis), e2 = n x e1
        zero = np.zeros(len(n))
        e1 = np.where(use_x[:, None], np.stack([zero, z, -y], axis=1), np.stack([-z, zero, x], axis=1))
        e1 /= np.sqrt(np.sum(e1 * e1, axis=1))[:, None]
        e2 = np.stack([y * e1[:, 2] - z * e1[:, 1], z * e1[:, 0] - x * e1[:, 2], x * e1[:, 1] - y * e1[:, 0]], axis=1)
        trial = np.concatenate([n + step[:, None] * e for e in (e1, -e1, e2, -e2)])
        trial /= np.sqrt(np.sum(trial * trial, axis=1))[:, None]
        got = f(trial).reshape(4, len(n))
        k = np.argmax(got, axis=0)
        better = got[k, rows] > best
        moved = trial.reshape(4, len(n), 3)[k, rows]
        n[better], best[better] = moved[better], got[k, rows][better]
        step[~better] *= 0.5
    return float(max(best.max(), values.max()))


def _aligned_ellipsoid(piece, centre, directions, support):
    """Semi-axes (3,) of the axis-aligned ellipsoid centred at ``centre`` through the piece that overshoots least.

    For a fixed centre and axes, ``max_n c . n + |diag(a) n| - h(n)`` is convex
    in the semi-axes ``a`` and grows with each of them, so the best ellipsoid
    touches the piece: ``a = exp(theta) s(theta)`` with ``s`` the least scale
    that holds every point.  A pattern search over ``theta`` (only the shape
    matters) from the piece's half widths finds it.
    """
    reach = np.abs(piece - centre)
    base = directions @ centre - support
    scale = max(reach.max(), 1e-300)
    theta = np.log(np.maximum(reach.max(axis=0), 1e-3 * scale))
    return _pattern_search(reach, base, np.ascontiguousarray(directions, dtype=float), theta)


@numba.njit(cache=True, nogil=True, no_cfunc_wrapper=True, forceinline=False)
def _scaled_radii(reach, theta):
    """``exp(theta)`` scaled to the least ellipsoid of that shape holding every point of ``reach`` (n, 3)."""
    a = np.exp(theta)
    worst = 0.0
    for k in range(reach.shape[0]):
        x, y, z = reach[k, 0] / a[0], reach[k, 1] / a[1], reach[k, 2] / a[2]
        worst = max(worst, x * x + y * y + z * z)
    return a * np.sqrt(worst)


@numba.njit(cache=True, nogil=True, no_cfunc_wrapper=True, forceinline=False)
def _overshoot(reach, base, directions, theta):
    """The largest excess ``base + |diag(radii) n|`` over ``directions`` of the ellipsoid :func:`_scaled_radii`."""
    r = _scaled_radii(reach, theta)
    out = -np.inf
    for k in range(directions.shape[0]):
        x, y, z = directions[k, 0] * r[0], directions[k, 1] * r[1], directions[k, 2] * r[2]
        out = max(out, base[k] + np.sqrt(x * x + y * y + z * z))
    return out


@numba.njit(cache=True, nogil=True, no_cfunc_wrapper=True, forceinline=False)
def _pattern_search(reach, base, directions, theta):
    """:func:`_aligned_ellipsoid`'s search: from ``theta``, steps of +-step along each log semi-axis, the best
    taken, the step halved when none is better, down to 1e-2; the semi-axes of the end."""
    theta = theta.copy()
    best, step = _overshoot(reach, base, directions, theta), 0.5
    trial = np.empty(3)
    while step > 1e-2:
        best_k, best_value = -1, np.inf
        for k in range(6):
            for i in range(3):
                trial[i] = theta[i]
            trial[k % 3] += step if k < 3 else -step
            value = _overshoot(reach, base, directions, trial)
            if value < best_value:
                best_k, best_value = k, value
        if best_value < best:
            theta[best_k % 3] += step if best_k < 3 else -step
            best = best_value
        else:
            step *= 0.5
    return _scaled_radii(reach, theta)


def _piece_ellipsoid(piece, cut_axes, hull, directions, support, tolerance):
    """``(within, sampled, (centre, rotation, radii))``: the candidate ellipsoid of a mesh cell that overshoots least.

    Candidates, none depending on the tolerance:

    * the axis-aligned ellipsoid centred on the cell's box that overshoots
      least (:func:`_aligned_ellipsoid`): the fit for prism-like cells with
      sharp edges, as for a box geom;
    * the cell's minimum-volume ellipsoid, squeezed along the axes the cell
      was cut on by each of :data:`_STRETCHES` before the fit and stretched
      back after: it then reaches past the cut planes into the rest of the
      hull instead of bulging sideways.

    Each candidate is grown to contain the cell's points (proven, plus a
    relative 1e-9 for the rounding of the cut).  The one whose support
    function exceeds the hull's least on ``directions`` wins; ``sampled`` is
    that excess, a lower bound of its overshoot that does not depend on the
    tolerance.  ``within`` is True when :func:`_surface_within` proves that
    no point of it lies farther than ``tolerance`` from the hull (sampling
    alone cannot: the excess peaks on ridges between the vertices' normal
    cones, where sampling misses by an amount linear in the spacing).
    """
    vertices = hull.vertices
    mid = 0.5 * (piece.min(axis=0) + piece.max(axis=0))
    points = _thick(piece)
    candidates = [(mid.copy(), np.eye(3), _aligned_ellipsoid(piece, mid, directions, support))]
    for stretch in (_STRETCHES if cut_axes else (1.0,)):
        s = np.ones(3)
        s[list(cut_axes)] = stretch
        try:
            c, R, r = mvee((points - mid) / s, max_iterations=2000)  # any fit is grown to containment after
        except ValueError:  # a sliver too thin to fit: the aligned candidate covers it
            continue
        U, radii, _ = np.linalg.svd(s[:, None] * (R * r))
        if np.linalg.det(U) < 0.0:
            U[:, 2] = -U[:, 2]
        candidates.append((mid + s * c, U, radii))
    best = None
    for candidate in candidates:
        c, R, r = _contain(candidate, [Atom(piece)], margin=1e-9)
        sampled = float(np.max(_support_gap(c, R, r, vertices, directions, support)))
        if best is None or sampled < best[0]:
            best = (sampled, (c, R, r))
    sampled, ellipsoid = best
    within = sampled <= tolerance and _surface_within(*ellipsoid, hull.distance, tolerance)
    return within, sampled, ellipsoid


def _surface_within(centre, rotation, radii, distance, tolerance, *, max_evaluations=50000):
    """True when it is proven that no point of the ellipsoid lies farther than ``tolerance`` from a convex set.

    For a convex set the distance is convex, so its largest value on the
    solid ellipsoid is on the surface.  The surface is the image of the
    unit sphere, which is the radial projection of the faces of the cube
    ``[-1, 1]^3``; the projection of points outside the unit ball onto it
    does not expand distances, so a square of half side h on a cube face
    maps into a patch within ``h sqrt(2)`` of the image of its centre, and
    the distance (1-Lipschitz) there is at most the distance at the centre
    plus ``max(radii) h sqrt(2)``.  Squares are quartered until every bound
    is within the tolerance (True) or a point beyond it is found (False);
    False too when ``max_evaluations`` points did not settle it.
    ``distance`` maps points (n, 3) to distances (n,).
    """
    M, lipschitz = rotation * radii, float(np.max(radii)) * np.sqrt(2.0)
    half = 0.25
    ticks = -1.0 + half * (2 * np.arange(4) + 1)
    a, b = (x.ravel() for x in np.meshgrid(ticks, ticks, indexing="ij"))
    squares = np.concatenate([np.stack([np.full(16, f), a, b], axis=1) for f in range(6)])
    quarters = np.array([[0, -1, -1], [0, -1, 1], [0, 1, -1], [0, 1, 1]], float)
    evaluations = 0
    while len(squares):
        face = squares[:, 0].astype(np.int64)
        cube = np.zeros((len(squares), 3))
        rows = np.arange(len(squares))
        axis, sign = face % 3, np.where(face < 3, 1.0, -1.0)
        cube[rows, axis] = sign
        cube[rows, (axis + 1) % 3] = squares[:, 1]
        cube[rows, (axis + 2) % 3] = squares[:, 2]
        u = cube / np.linalg.norm(cube, axis=1)[:, None]
        d = distance(centre + u @ M.T)
        evaluations += len(squares)
        if d.max() > tolerance:
            return False
        open_ = squares[d + lipschitz * half > tolerance]
        if not len(open_):
            return True
        if evaluations + 4 * len(open_) > max_evaluations:
            return False
        half *= 0.5
        squares = (open_[:, None, :] + half * quarters[None]).reshape(-1, 3)
    return True


def _mesh_cover(shape, t, limit):
    """Cover of a mesh's hull: the fewer cells of :func:`_grid_cover` and :func:`_bisection_cover`.

    Both counts never grow with the tolerance, so neither does the smaller.
    """
    if shape.faces is None:
        raise InputError("faces: a mesh needs the faces of its convex hull to be covered")
    V = np.asarray(shape.position, dtype=float) + np.asarray(shape.vertices, dtype=float) @ shape.rotation.T
    centre, rotation, radii = mvee(V)
    axes = rotation[:, np.argsort(-radii)]
    if np.linalg.det(axes) < 0.0:
        axes[:, 2] = -axes[:, 2]
    P = (V - centre) @ axes  # along the axes of the minimum-volume ellipsoid, longest first
    hull = _Hull(P, shape.faces)
    directions = _unit_sphere(_MESH_DIRECTIONS)
    support = np.max(directions @ P.T, axis=1)
    grid = _grid_cover(hull, directions, support, t, min(limit, _GRID_CELLS))
    bisection = _bisection_cover(hull, directions, support, t, limit if grid is None else len(grid) - 1)
    best = bisection or grid  # the bisection only returns a cover with fewer cells than the grid's
    return None if best is None else [(centre + axes @ c, axes @ R, r) for c, R, r in best]


def _grid_cover(hull, directions, support, t, limit):
    """The first nested grid of :func:`_grids` whose every cell's ellipsoid stays within t, or None."""
    for counts, growth in _grids(limit):
        cut_axes = tuple(k for k in range(3) if counts[k] > 1)
        cover = []
        for piece in _nested_cells(hull, counts, growth):
            within, _, ellipsoid = _piece_ellipsoid(piece, cut_axes, hull, directions, support, t)
            if not within:
                break
            cover.append(ellipsoid)
        else:
            return cover
    return None


def _bisection_cover(hull, directions, support, t, limit):
    """Cells halved until each one's ellipsoid stays within t (None past ``limit`` cells).

    A cell that overshoots is cut in two at the middle of its extent along
    the one of its two longest axes whose halves overshoot least, judged on
    the sampled overshoots, which do not depend on t.  So the cells at a
    larger tolerance are a subtree of those at a smaller one, and the count
    never grows with t.  It adapts where the grids cannot: sharp corners and
    edges slanted to the axes get small cells, the rest stays whole.
    """
    V = hull.vertices
    whole = (V.min(axis=0), V.max(axis=0))

    def cell(lo, hi):
        piece = hull.cut(lo, hi)
        if not len(piece):
            return None
        cut_axes = tuple(k for k in range(3) if lo[k] > whole[0][k] or hi[k] < whole[1][k])
        within, sampled, ellipsoid = _piece_ellipsoid(piece, cut_axes, hull, directions, support, t)
        return within, sampled, ellipsoid, lo, hi, piece

    done, todo = [], [cell(*whole)]
    while todo:
        within, _, ellipsoid, lo, hi, piece = todo.pop()
        if within:
            done.append(ellipsoid)
            continue
        if len(done) + len(todo) + 2 > limit:
            return None
        best = None
        for axis in np.argsort(piece.max(axis=0) - piece.min(axis=0))[::-1][:2]:  # the two longest extents
            middle = 0.5 * (piece[:, axis].min() + piece[:, axis].max())
            low_hi, high_lo = hi.copy(), lo.copy()
            low_hi[axis], high_lo[axis] = middle, middle
            halves = [h for h in (cell(lo, low_hi), cell(high_lo, hi)) if h is not None]
            worst = max(h[1] for h in halves)
            if best is None or worst < best[0]:
                best = (worst, halves)
        todo.extend(best[1])
    return done


# ---------------------------------------------------------------- how far a set of ellipsoids reaches


SURFACE_SAMPLES = 2000
"""Points sampled on each ellipsoid's surface by :func:`cover_report` (then refined by local ascent)."""
VOLUME_SAMPLES = 2 ** 15
"""Halton points in the box around a body's ellipsoids with which :func:`cover_report` measures volumes."""


def _halton(n, bases=(2, 3, 5)):
    """The first n points (after the origin) of the Halton sequence in the unit cube, (n, len(bases))."""
    out = np.zeros((n, len(bases)))
    index = np.arange(1, n + 1)
    for k, base in enumerate(bases):
        i, f = index.copy(), 1.0
        while np.any(i > 0):
            f /= base
            out[:, k] += f * (i % base)
            i //= base
    return out


def _union_distance(points, shapes):
    """Distance (n,) from each point to the union of the shapes."""
    return np.min([shape.distance(points) for shape in shapes], axis=0)


def cover_report(ellipsoids, shapes, *, surface_samples=SURFACE_SAMPLES, volume_samples=VOLUME_SAMPLES):
    """``(overshoot, volume_ratio)`` of ellipsoids bounding the union of ``shapes``, both measured.

    ``overshoot``: the largest distance from a point of the ellipsoids to the
    union of the shapes (:meth:`Shape.distance`, exact per point), over
    ``surface_samples`` Fibonacci points on each ellipsoid's surface refined
    by local ascent from its best few, and over the Halton points below that
    fall inside the ellipsoids (an ellipsoid around several shapes may reach
    farthest inside, between them).  Sampled, so a lower bound, refined to
    about 1e-7 of the ellipsoid's size.

    ``volume_ratio``: volume of the union of the ellipsoids over volume of
    the union of the shapes (overlaps counted once), both from the same
    ``volume_samples`` Halton points in the box around the ellipsoids.

    Args:
        ellipsoids: [(centre (3,), rotation (3, 3), radii (3,)), ...].
        shapes: [:class:`Shape`, ...] in the same frame.
    """
    sphere = _unit_sphere(surface_samples)
    overshoot = 0.0
    lows, highs = [], []
    for c, R, r in ellipsoids:
        M = R * r

        def reach(u, c=c, M=M):
            return _union_distance(c + u @ M.T, shapes)

        overshoot = max(overshoot, _ascend(reach, sphere, reach(sphere)))
        half = np.sqrt(np.sum(M * M, axis=1))
        lows.append(c - half)
        highs.append(c + half)
    lo, hi = np.min(lows, axis=0), np.max(highs, axis=0)
    points = lo + _halton(volume_samples) * (hi - lo)
    inside = np.zeros(len(points), dtype=bool)
    for c, R, r in ellipsoids:
        inside |= np.sum(((points - c) @ R / r) ** 2, axis=1) <= 1.0
    if inside.any():
        overshoot = max(overshoot, float(_union_distance(points[inside], shapes).max()))
    solid = np.zeros(len(points), dtype=bool)
    for shape in shapes:
        solid |= shape.contains(points)
    ratio = inside.sum() / solid.sum() if solid.any() else np.nan
    return overshoot, float(ratio)


def within_tolerance(centre, rotation, radii, shapes, tolerance, *, max_evaluations=200000):
    """True when it is proven that no point of the solid ellipsoid lies farther than ``tolerance`` from the shapes.

    Branch and bound over the ellipsoid ``{centre + rotation diag(radii) u : |u| <= 1}``:
    a cube of ``u`` with half side s meets the ball in points within
    ``s sqrt(3)`` of the projection of its centre onto the ball (projection
    onto a convex set does not expand distances), so the distance to the
    union of the shapes (1-Lipschitz) is at most the distance at that point
    plus ``max(radii) s sqrt(3)``.  Cubes are halved until every bound is
    within the tolerance (True) or a point is found beyond it (False); False
    too when ``max_evaluations`` points did not settle it.  A quick first
    test compares support functions with the hull of the shapes, a lower
    bound of the distance to their union.
    """
    directions = _unit_sphere(400)
    hull = np.max([shape.support(directions) for shape in shapes], axis=0)
    if np.max(_ellipsoid_support(centre, rotation, radii, directions) - hull) > tolerance:
        return False
    M, lipschitz = rotation * radii, float(np.max(radii)) * np.sqrt(3.0)
    half = 0.25
    ticks = -1.0 + half * (2 * np.arange(4) + 1)
    cells = np.stack(np.meshgrid(ticks, ticks, ticks, indexing="ij"), axis=-1).reshape(-1, 3)
    children = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)], float)
    evaluations = 0
    while len(cells):
        cells = cells[np.sum(np.maximum(np.abs(cells) - half, 0.0) ** 2, axis=1) <= 1.0]
        u = cells / np.maximum(np.linalg.norm(cells, axis=1), 1.0)[:, None]
        d = _union_distance(centre + u @ M.T, shapes)
        evaluations += len(cells)
        if d.max() > tolerance:
            return False
        open_ = cells[d + lipschitz * half > tolerance]
        if evaluations + 8 * len(open_) > max_evaluations:
            return not len(open_)
        half *= 0.5
        cells = (open_[:, None, :] + half * children[None]).reshape(-1, 3)
    return True
