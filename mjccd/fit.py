"""Minimum-volume bounding ellipsoids of MuJoCo bodies or geoms, with a guaranteed containment step.

Each geom is turned into *atoms* in its body frame: points (box corners, mesh
vertices) and possibly flat ellipsoids ``{m + S u : |u| <= 1}`` (spheres,
ellipsoid geoms, the two end spheres of a capsule, the two end disks of a
cylinder).  Every supported geom is the convex hull of its atoms, so a convex
function of position reaches its maximum over the geom on an atom.

The fit is Khachiyan's minimum-volume enclosing ellipsoid of dense samples of
the atoms (closed forms for a lone sphere, ellipsoid, box or cylinder).  The
containment step then bounds ``max |L (x - c)|`` over every atom *exactly from
above* -- for an ellipsoidal atom through the dual of the trust-region problem
-- and grows the ellipsoid by that factor when it exceeds one.  So every point
of the geometry is inside the returned ellipsoid, not only the samples.
"""
import argparse
import contextlib
import os
import sys
import tempfile
from dataclasses import dataclass

import mujoco
import numba
import numpy as np

from mjccd import files
from mjccd.errors import InputError, MjccdError
from mjccd.mujoco.ellipsoids import EllipsoidSet, body_label

SUPPORTED = {
    mujoco.mjtGeom.mjGEOM_SPHERE: "sphere",
    mujoco.mjtGeom.mjGEOM_CAPSULE: "capsule",
    mujoco.mjtGeom.mjGEOM_ELLIPSOID: "ellipsoid",
    mujoco.mjtGeom.mjGEOM_CYLINDER: "cylinder",
    mujoco.mjtGeom.mjGEOM_BOX: "box",
    mujoco.mjtGeom.mjGEOM_MESH: "mesh",
}
VISUAL_GROUP = 5
VISUAL_RGBA = (0.2, 0.6, 1.0, 0.3)
# Names of the geoms written by :func:`write_mjcf`; a model read back drops them (see :func:`_load`).
GEOM_PREFIX = "mjccd_ellipsoid_"


@dataclass(frozen=True)
class Atom:
    """``{centre + shape @ u : |u| <= 1}`` in the body frame; ``shape`` is None for a point set."""

    centre: np.ndarray
    shape: np.ndarray = None


# ---------------------------------------------------------------- geometry of geoms


def _quat_mat(q):
    m = np.empty(9)
    mujoco.mju_quat2Mat(m, np.asarray(q, float))
    return m.reshape(3, 3)


def _mat_quat(R):
    q = np.empty(4)
    mujoco.mju_mat2Quat(q, np.ascontiguousarray(R, float).reshape(9))
    return q / np.linalg.norm(q)


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


def geom_atoms(model, geom_id):
    """Atoms (list of :class:`Atom`) and volume of one geom, in its body's frame."""
    gtype = int(model.geom_type[geom_id])
    size = model.geom_size[geom_id]
    p = model.geom_pos[geom_id].copy()
    R = _quat_mat(model.geom_quat[geom_id])
    if gtype == mujoco.mjtGeom.mjGEOM_SPHERE:
        return [Atom(p, R * size[0])], 4.0 / 3.0 * np.pi * size[0] ** 3
    if gtype == mujoco.mjtGeom.mjGEOM_ELLIPSOID:
        return [Atom(p, R @ np.diag(size))], 4.0 / 3.0 * np.pi * np.prod(size)
    if gtype == mujoco.mjtGeom.mjGEOM_CAPSULE:
        r, h = size[0], size[1]
        atoms = [Atom(p + s * h * R[:, 2], R * r) for s in (-1.0, 1.0)]
        return atoms, np.pi * r * r * 2.0 * h + 4.0 / 3.0 * np.pi * r ** 3
    if gtype == mujoco.mjtGeom.mjGEOM_CYLINDER:
        r, h = size[0], size[1]
        disk = R @ np.diag([r, r, 0.0])
        return [Atom(p + s * h * R[:, 2], disk) for s in (-1.0, 1.0)], np.pi * r * r * 2.0 * h
    if gtype == mujoco.mjtGeom.mjGEOM_BOX:
        signs = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)], float)
        return [Atom(p + (signs * size) @ R.T)], 8.0 * np.prod(size)
    if gtype == mujoco.mjtGeom.mjGEOM_MESH:
        mid = int(model.geom_dataid[geom_id])
        adr, num = model.mesh_vertadr[mid], model.mesh_vertnum[mid]
        verts = model.mesh_vert[adr:adr + num].astype(float)
        fadr, fnum = model.mesh_faceadr[mid], model.mesh_facenum[mid]
        faces = model.mesh_face[fadr:fadr + fnum]
        a, b, c = verts[faces[:, 0]], verts[faces[:, 1]], verts[faces[:, 2]]
        volume = abs(np.einsum("ij,ij->i", a, np.cross(b, c)).sum()) / 6.0
        return [Atom(p + verts @ R.T)], volume
    raise ValueError(f"geom {geom_id}: type {gtype} is not supported")


def _samples(atoms):
    """Dense points on the atoms' extreme points, for the fit."""
    pts = []
    sphere, circle = _unit_sphere(200), _unit_circle(72)
    for atom in atoms:
        if atom.shape is None:
            pts.append(np.atleast_2d(atom.centre))
        else:
            flat = np.linalg.matrix_rank(atom.shape, tol=1e-12 * max(np.abs(atom.shape).max(), 1e-300)) < 3
            pts.append(atom.centre + (circle if flat else sphere) @ atom.shape.T)
    return np.vstack(pts)


# ---------------------------------------------------------------- fit and containment


@numba.njit(cache=True, nogil=True)
def _khachiyan_weights(P, tolerance, max_iterations):
    """Weights u of the points P (n, 3) whose moment ellipsoid is the minimum-volume one.

    Khachiyan's multiplicative steps with Todd-Yildirim drop steps; stops
    when every point is within ``1 + tolerance`` of the optimality bound.
    """
    n = P.shape[0]
    d1 = 4.0
    Q = np.ones((4, n))
    Q[:3] = P.T
    u = np.full(n, 1.0 / n)
    M = np.empty(n)
    for _ in range(max_iterations):
        X = (Q * u) @ Q.T
        Xi = np.linalg.inv(X)
        Y = Xi @ Q
        j, k = 0, -1
        for i in range(n):
            M[i] = Q[0, i] * Y[0, i] + Q[1, i] * Y[1, i] + Q[2, i] * Y[2, i] + Q[3, i] * Y[3, i]
            if M[i] > M[j]:
                j = i
            if u[i] > 0.0 and (k < 0 or M[i] < M[k]):
                k = i
        up = M[j] - d1
        down = d1 - M[k]
        if up <= tolerance * d1 and down <= tolerance * d1:
            break
        if up >= down:
            step = up / (d1 * (M[j] - 1.0))
            u *= 1.0 - step
            u[j] += step
        else:
            limit = u[k] / (1.0 - u[k])
            step = limit if M[k] <= 1.0 else min(down / (d1 * (M[k] - 1.0)), limit)
            u *= 1.0 + step
            u[k] = max(u[k] - step, 0.0)
    return u


def mvee(points, *, tolerance=1e-4, max_iterations=100000):
    """Minimum-volume enclosing ellipsoid of points (n, 3): (centre, rotation, radii).

    The result encloses the points only up to ``tolerance``;
    :func:`fit_atoms` grows it until containment of the geometry is proven.
    """
    P = np.ascontiguousarray(points, dtype=float)
    centred = P - P.mean(axis=0)
    if np.linalg.matrix_rank(centred, tol=1e-12 * max(np.abs(centred).max(), 1e-300)) < 3:
        raise ValueError("points: they lie in a plane or a line, no bounding ellipsoid")
    u = _khachiyan_weights(P, tolerance, max_iterations)
    c = P.T @ u
    cov = (P.T * u) @ P - np.outer(c, c)
    evals, evecs = np.linalg.eigh(cov)
    if evals[0] <= 1e-14 * max(evals[-1], 1e-300):
        raise ValueError("points: they lie in a plane or a line, no bounding ellipsoid")
    radii = np.sqrt(3.0 * evals)
    if np.linalg.det(evecs) < 0.0:
        evecs[:, 0] = -evecs[:, 0]
    return c, evecs, radii


def _ball_max_bound(a, B):
    """Upper bound of ``max_{|u| <= 1} |a + B u|^2``, tight up to rounding.

    Weak duality of the trust-region problem: for every ``lam > lambda_max(H)``,
    ``|a + B u|^2 <= |a|^2 + psi(lam)`` with ``psi(lam) = lam + g^T (lam I - H)^-1 g``,
    ``H = B^T B``, ``g = B^T a``.  ``psi`` is convex and its minimum (where
    ``sum gamma_i^2 / (lam - h_i)^2 = 1``) lies in ``(h_max, h_max + |g|]``;
    bisection keeps the upper end, where the bound is valid, and closes on it.
    """
    H = B.T @ B
    g = B.T @ a
    h, V = np.linalg.eigh(H)
    gamma2 = (V.T @ g) ** 2
    top = float(h[-1])
    base = float(a @ a)
    gnorm = float(np.sqrt(gamma2.sum()))
    if gnorm == 0.0:
        return base + max(top, 0.0)
    lo, hi = top, top + gnorm
    for _ in range(200):
        mid = 0.5 * (lo + hi)
        if not lo < mid < hi:
            break
        if np.sum(gamma2 / (mid - h) ** 2) > 1.0:
            lo = mid
        else:
            hi = mid
    return base + hi + float(np.sum(gamma2 / (hi - h)))


def containment_factor(centre, rotation, radii, atoms):
    """``max |y|`` over all atoms, ``y = diag(1/radii) R^T (x - centre)``: <= 1 means contained."""
    L = (rotation / radii).T
    worst = 0.0
    for atom in atoms:
        if atom.shape is None:
            y = (np.atleast_2d(atom.centre) - centre) @ L.T
            worst = max(worst, float(np.max(np.einsum("ij,ij->i", y, y))))
        else:
            worst = max(worst, _ball_max_bound(L @ (atom.centre - centre), L @ atom.shape))
    return float(np.sqrt(worst))


def _closed_form(model, geom_id):
    """Exact minimum-volume ellipsoid of a lone primitive geom, or None."""
    gtype = int(model.geom_type[geom_id])
    s = model.geom_size[geom_id]
    if gtype == mujoco.mjtGeom.mjGEOM_SPHERE:
        radii = np.full(3, s[0])
    elif gtype == mujoco.mjtGeom.mjGEOM_ELLIPSOID:
        radii = s.copy()
    elif gtype == mujoco.mjtGeom.mjGEOM_BOX:
        radii = np.sqrt(3.0) * s
    elif gtype == mujoco.mjtGeom.mjGEOM_CYLINDER:  # r sqrt(3/2), h sqrt(3): minimises R^2 H on the rim
        radii = np.array([s[0] * np.sqrt(1.5), s[0] * np.sqrt(1.5), s[1] * np.sqrt(3.0)])
    else:
        return None
    return model.geom_pos[geom_id].copy(), _quat_mat(model.geom_quat[geom_id]), radii


def fit_atoms(atoms, *, exact=None):
    """Bounding ellipsoid (centre, rotation, radii) of atoms, grown until containment is proven."""
    c, R, r = exact if exact is not None else mvee(_samples(atoms))
    factor = containment_factor(c, R, r, atoms)
    if factor > 1.0:
        r = r * factor
    return c, R, r


def collision_geoms(model, body_id, *, include_visual=False):
    """Geom ids of a body that take part in collisions (all geoms with ``include_visual``)."""
    start, num = model.body_geomadr[body_id], model.body_geomnum[body_id]
    ids = range(start, start + num) if start >= 0 else range(0)
    return [g for g in ids if include_visual or (model.geom_contype[g] | model.geom_conaffinity[g])]


def fit_model(model, *, per="body", bodies=None, include_visual=False):
    """Bounding ellipsoids of a compiled model as an :class:`EllipsoidSet`.

    Args:
        model: ``mujoco.MjModel``.
        per: "body" (one ellipsoid per body) or "geom" (one per geom).
        bodies: body names or ids to fit; default every body with supported collision geometry.
        include_visual: also bound geoms with ``contype = conaffinity = 0``.

    Planes, height fields and SDF geoms are unbounded or implicit: they are
    skipped (and a body that has nothing else is left out).  ``volume_ratios``
    compare with the sum of the geoms' volumes (overlaps counted twice).
    """
    if not isinstance(model, mujoco.MjModel):
        raise ValueError(f"model: expected a mujoco.MjModel, got {type(model).__name__}")
    if per not in ("body", "geom"):
        raise ValueError(f"per: expected 'body' or 'geom', got {per!r}")
    explicit = bodies is not None
    body_ids = _resolve_bodies(model, bodies) if explicit else range(model.nbody)
    out = {"bodies": [], "geoms": [], "radii": [], "positions": [], "quaternions": [], "volume_ratios": []}

    def emit(body_id, geom_name, fitted, volume):
        c, R, r = fitted
        out["bodies"].append(body_label(model, body_id))
        out["geoms"].append(geom_name)
        out["radii"].append(r)
        out["positions"].append(c)
        out["quaternions"].append(_mat_quat(R))
        out["volume_ratios"].append(4.0 / 3.0 * np.pi * np.prod(r) / volume if volume > 0 else np.nan)

    for b in body_ids:
        geoms = collision_geoms(model, b, include_visual=include_visual)
        label = body_label(model, b)
        if not geoms:
            if explicit:
                raise ValueError(f"bodies: body {label!r} has no collision geometry")
            continue
        usable = [g for g in geoms if int(model.geom_type[g]) in SUPPORTED]
        if not usable:
            if explicit:
                kinds = sorted({mujoco.mjtGeom(int(model.geom_type[g])).name for g in geoms})
                raise ValueError(f"bodies: body {label!r} has only unsupported geoms ({', '.join(kinds)})")
            continue
        if per == "geom":
            for g in usable:
                atoms, volume = geom_atoms(model, g)
                name = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_GEOM, g) or f"#{g}"
                emit(b, name, fit_atoms(atoms, exact=_closed_form(model, g)), volume)
        else:
            atoms, volume = [], 0.0
            for g in usable:
                a, v = geom_atoms(model, g)
                atoms += a
                volume += v
            exact = _closed_form(model, usable[0]) if len(usable) == 1 else None
            try:
                emit(b, "", fit_atoms(atoms, exact=exact), volume)
            except ValueError as exc:
                raise ValueError(f"body {label!r}: {exc}") from None
    if not out["bodies"]:
        raise ValueError("model: no body has sphere, capsule, ellipsoid, cylinder, box or mesh "
                         "collision geometry")
    return EllipsoidSet(**out)


def _resolve_bodies(model, bodies):
    ids = []
    for k, b in enumerate(bodies):
        if isinstance(b, (int, np.integer)):
            if not 0 <= int(b) < model.nbody:
                raise ValueError(f"bodies[{k}]: body id {b} out of range [0, {model.nbody})")
            ids.append(int(b))
        else:
            i = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, str(b))
            if i < 0:
                raise ValueError(f"bodies[{k}]: the model has no body named {b!r}")
            ids.append(i)
    return ids


def volume_report(ellipsoids):
    """Plain-text table: body, geom, radii and ellipsoid/geometry volume ratio."""
    lines = [f"{'body':<24} {'geom':<16} {'radii':<30} {'volume ratio':>12}"]
    for b, g, r, v in zip(ellipsoids.bodies, ellipsoids.geoms, ellipsoids.radii, ellipsoids.volume_ratios):
        radii = " ".join(f"{x:.4g}" for x in r)
        lines.append(f"{b:<24} {g or '-':<16} {radii:<30} {v:>12.3f}")
    return "\n".join(lines)


# ---------------------------------------------------------------- MJCF output


def _one_line(exc):
    return " ".join(str(exc).split())


def _load(model_path):
    """``(spec, compiled model)`` of an MJCF file, less the ellipsoid geoms an earlier fit added.

    So fitting a fitted model replaces its ellipsoids: they are neither
    bounded themselves nor added a second time.  Errors name the file.
    """
    try:
        spec = mujoco.MjSpec.from_file(os.fspath(model_path))
    except ValueError as exc:
        raise InputError(f"{model_path}: MuJoCo cannot load it: {_one_line(exc)}") from None
    earlier = [geom for geom in spec.geoms if geom.name.startswith(GEOM_PREFIX)]
    for geom in earlier:
        spec.delete(geom)
    try:
        return spec, spec.compile()
    except ValueError as exc:
        without = f" without its {len(earlier)} {GEOM_PREFIX}* geoms" if earlier else ""
        raise InputError(f"{model_path}: MuJoCo cannot compile it{without}: {_one_line(exc)}") from None


def load_model(model_path):
    """The compiled model of an MJCF file, less the ellipsoids an earlier fit added (see :func:`_load`)."""
    return _load(model_path)[1]


def mjcf_with_ellipsoids(model_path, ellipsoids, output_path, *, group=VISUAL_GROUP, rgba=VISUAL_RGBA):
    """MJCF text of the model with the ellipsoids added as visual-only geoms, to be saved at ``output_path``.

    The geoms have ``contype = conaffinity = 0``, zero density and their own
    ``group`` (hidden or shown with the viewer's group toggles), so the
    simulation is unchanged.  Ellipsoids of an earlier fit are replaced.
    Asset folders are rewritten relative to ``output_path``.
    """
    spec, model = _load(model_path)
    ids = ellipsoids.body_ids(model)
    for k, (bid, r, p, q) in enumerate(zip(ids, ellipsoids.radii, ellipsoids.positions, ellipsoids.quaternions)):
        body = spec.worldbody if bid == 0 else spec.bodies[bid]
        geom = body.add_geom()
        geom.name = f"{GEOM_PREFIX}{k}"
        geom.type = mujoco.mjtGeom.mjGEOM_ELLIPSOID
        geom.size = r
        geom.pos = p
        geom.quat = q
        geom.contype = 0
        geom.conaffinity = 0
        geom.density = 0.0
        geom.group = group
        geom.rgba = rgba
    src_dir = os.path.dirname(os.path.abspath(model_path))
    out_dir = os.path.dirname(os.path.abspath(output_path))
    if src_dir != out_dir:
        for attr in ("meshdir", "texturedir"):
            value = getattr(spec, attr)
            if not os.path.isabs(value or ""):
                setattr(spec, attr, os.path.relpath(os.path.join(src_dir, value or ""), out_dir))
        spec.modelfiledir = out_dir + os.sep  # assets are now found from the output's folder
    try:
        return spec.to_xml()  # compiles the model again, with the ellipsoids
    except ValueError as exc:
        raise InputError(f"{model_path}: MuJoCo cannot compile it with the ellipsoids added: "
                         f"{_one_line(exc)}") from None


def write_mjcf(model_path, ellipsoids, output_path, *, group=VISUAL_GROUP, rgba=VISUAL_RGBA):
    """Write :func:`mjcf_with_ellipsoids` to ``output_path`` (atomically: the old file or the new, never half)."""
    files.write_text(output_path, mjcf_with_ellipsoids(model_path, ellipsoids, output_path, group=group, rgba=rgba))


def _ellipsoid_file_bytes(ellipsoids, name):
    """The bytes :meth:`EllipsoidSet.save` writes for a file called ``name`` (.json or .npz)."""
    with tempfile.TemporaryDirectory() as folder:
        path = os.path.join(folder, os.path.basename(name))
        ellipsoids.save(path)
        with open(path, "rb") as fh:
            return fh.read()


# ---------------------------------------------------------------- command line

DESCRIPTION = """\
Fit a bounding ellipsoid to each body (or geom) of a MuJoCo model, report the
volume ratios, and write the model with the ellipsoids added as visual-only
geoms named mjccd_ellipsoid_<k> (-o) and the ellipsoids themselves
(--ellipsoids).  A model that already has geoms named mjccd_ellipsoid_* (the
output of an earlier fit) is refitted: those geoms are dropped before the fit
and replaced, never bounded and never duplicated.  Existing files, and the
model itself, are replaced only with --force; both outputs appear together or
not at all."""


@contextlib.contextmanager
def _warnings_on_stderr(model_path):
    """Send MuJoCo's warnings to stderr, naming the model (not to stdout and a MUJOCO_LOG.TXT in the working folder)."""
    previous = mujoco.get_mju_user_warning()
    mujoco.set_mju_user_warning(lambda text: print(f"mjccd fit: {model_path}: MuJoCo warns: {text}", file=sys.stderr))
    try:
        yield
    finally:
        mujoco.set_mju_user_warning(previous)


def _output_paths(args):
    """The MJCF output and the ellipsoid file to write (each None when not asked for), checked before the fit."""
    if not 0 <= args.group <= 5:
        raise InputError(f"--group: must be in 0..5, got {args.group}")
    target = args.ellipsoids or (os.path.splitext(args.output)[0] + ".ellipsoids.json" if args.output else None)
    if target and not target.endswith((".json", ".npz")):
        raise InputError(f"--ellipsoids: expected a .json or .npz file name, got {target!r}")
    if target and args.output and os.path.realpath(target) == os.path.realpath(args.output):
        raise InputError(f"--ellipsoids: {target} is also the -o model file; give two different names")
    for path in (args.output, target):
        if path:
            files.check_output_file(path, inputs=[args.model], force=args.force)
    return args.output, target


def main(argv=None):
    """``mjccd fit MODEL.xml -o OUT.xml``: fit, report volume ratios, write MJCF and an ellipsoid file."""
    parser = argparse.ArgumentParser(prog="mjccd fit", description=DESCRIPTION)
    parser.add_argument("model", help="MJCF model file")
    parser.add_argument("-o", "--output", help="MJCF file with the ellipsoids added as visual geoms")
    parser.add_argument("--ellipsoids", help="ellipsoid file to write (.json or .npz); "
                        "default: next to --output with extension .ellipsoids.json")
    parser.add_argument("--per", choices=("body", "geom"), default="body")
    parser.add_argument("--bodies", nargs="+", help="only these bodies")
    parser.add_argument("--include-visual", action="store_true", help="also bound non-colliding geoms")
    parser.add_argument("--group", type=int, default=VISUAL_GROUP, help="geom group of the ellipsoids")
    parser.add_argument("--force", action="store_true", help="replace existing output files (even MODEL)")
    parser.add_argument("-q", "--quiet", action="store_true", help="no volume report")
    args = parser.parse_args(argv)
    written = []
    try:
        with _warnings_on_stderr(args.model):
            model = load_model(args.model)
            output, target = _output_paths(args)
            written = [p for p in (output, target) if p]
            try:
                ellipsoids = fit_model(model, per=args.per, bodies=args.bodies, include_visual=args.include_visual)
            except ValueError as exc:
                raise InputError(f"{args.model}: {exc}") from None
            xml = mjcf_with_ellipsoids(args.model, ellipsoids, output, group=args.group) if output else None
        data = _ellipsoid_file_bytes(ellipsoids, target) if target else None
        # both files are renamed into place only once both are complete
        with contextlib.ExitStack() as stack:
            if output:
                stack.enter_context(files.atomic_open(output, "w", encoding="utf-8")).write(xml)
            if target:
                stack.enter_context(files.atomic_open(target, "wb")).write(data)
    except (MjccdError, ValueError) as exc:
        print(f"mjccd fit: {exc}", file=sys.stderr)
        return 2
    except OSError as exc:
        print(f"mjccd fit: cannot write {', '.join(written)}: {exc.strerror}", file=sys.stderr)
        return 2
    if not args.quiet:
        print(volume_report(ellipsoids))
    return 0


if __name__ == "__main__":
    sys.exit(main())
