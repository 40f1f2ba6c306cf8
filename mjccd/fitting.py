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

Shapes use MuJoCo's geom parametrisation (so :mod:`mjccd.mujoco.ellipsoids`
passes a model's geoms through unchanged), but nothing here needs MuJoCo.
"""
from dataclasses import dataclass

import numba
import numpy as np

KINDS = ("sphere", "capsule", "ellipsoid", "cylinder", "box", "mesh")
REFINE_ROUNDS = 100  # at most this many times the farthest points of the atoms join the samples
MAX_ITERATIONS = 100000  # Khachiyan steps of one fit to samples


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
    ``vertices`` (n, 3) in its own frame, ``faces`` (m, 3) give its volume.
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


@numba.njit(cache=True, nogil=True)
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
    Q[:, :3] = P
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


@numba.njit(cache=True, nogil=True)
def _trust_region(a, B):
    """``(bound, u)``: an upper bound of ``max_{|u| <= 1} |a + B u|^2``, tight up to rounding, and its maximiser.

    Weak duality of the trust-region problem: for every ``lam > lambda_max(H)``,
    ``|a + B u|^2 <= |a|^2 + psi(lam)`` with ``psi(lam) = lam + g^T (lam I - H)^-1 g``,
    ``H = B^T B``, ``g = B^T a``.  ``psi`` is convex and its minimum (where
    ``sum gamma_i^2 / (lam - h_i)^2 = 1``) lies in ``(h_max, h_max + |g|]``;
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
    lo, hi = top, top + gnorm
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
