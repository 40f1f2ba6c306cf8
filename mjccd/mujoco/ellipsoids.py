"""Bounding ellipsoids of MuJoCo bodies: fitted to a model's geoms, the set and its files, its binding to a model.

The fitting maths is :mod:`mjccd.fitting`; this module reads the geoms of a
``mujoco.MjModel`` into its shapes and labels the result by body.
"""
import json
import os
import warnings
import zipfile
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field

import mujoco
import numpy as np
from threadpoolctl import threadpool_limits

from mjccd import _validate
from mjccd.errors import InputError, InputTypeError
from mjccd.fitting import (DEFAULT_TOLERANCE, MAX_ELLIPSOIDS, SURFACE_SAMPLES, VOLUME_SAMPLES, Shape,
                           cover_loosened, cover_report, fit_shapes, within_tolerance)
from mjccd.quadric import matrix_to_quat, quat_to_matrix
from mjccd.mujoco import fit_cache
from mjccd.mujoco.warnings import CoverageWarning

FORMAT_VERSION = 1
BOUND_GROUP = 5  # the geom group mjccd fit writes its bounding ellipsoids to
SUPPORTED = {
    mujoco.mjtGeom.mjGEOM_SPHERE: "sphere",
    mujoco.mjtGeom.mjGEOM_CAPSULE: "capsule",
    mujoco.mjtGeom.mjGEOM_ELLIPSOID: "ellipsoid",
    mujoco.mjtGeom.mjGEOM_CYLINDER: "cylinder",
    mujoco.mjtGeom.mjGEOM_BOX: "box",
    mujoco.mjtGeom.mjGEOM_MESH: "mesh",
}


@dataclass(frozen=True)
class EllipsoidSet:
    """Ellipsoids fixed in MuJoCo body frames.

    Attributes:
        bodies: (N,) body names (``#id`` for an unnamed body), one per ellipsoid (several ellipsoids may share a body).
        radii: (N, 3) semi-axes in the ellipsoid's own frame.
        positions: (N, 3) ellipsoid centres in the body frame.
        quaternions: (N, 4) ellipsoid orientations [w, x, y, z] in the body frame.
        geoms: (N,) name of the geom an ellipsoid bounds, or "" when it bounds a whole body.
        volume_ratios: (N,) ellipsoid volume / volume of the geometry it bounds (NaN if unknown).
    """

    bodies: tuple
    radii: np.ndarray
    positions: np.ndarray
    quaternions: np.ndarray
    geoms: tuple = ()
    volume_ratios: np.ndarray = field(default=None)

    def __post_init__(self):
        bodies = tuple(str(b) for b in self.bodies)
        n = len(bodies)
        object.__setattr__(self, "bodies", bodies)
        object.__setattr__(self, "radii", _validate.radii_array(self.radii, "radii"))
        object.__setattr__(self, "positions", _validate.array(self.positions, (n, 3), "positions"))
        quats = _validate.pose_array(np.hstack([np.zeros((n, 3)), _validate.array(
            self.quaternions, (n, 4), "quaternions")]), "quaternions")[:, 3:] if n else np.zeros((0, 4))
        object.__setattr__(self, "quaternions", np.ascontiguousarray(quats))
        if len(self.radii) != n:
            raise InputError(f"radii: expected {n} rows (one per body entry), got {len(self.radii)}")
        geoms = tuple(str(g) for g in self.geoms) if len(self.geoms) else ("",) * n
        if len(geoms) != n:
            raise InputError(f"geoms: expected {n} entries, got {len(geoms)}")
        object.__setattr__(self, "geoms", geoms)
        ratios = (np.full(n, np.nan) if self.volume_ratios is None
                  else np.asarray(self.volume_ratios, dtype=float).reshape(-1))
        if ratios.shape != (n,):
            raise InputError(f"volume_ratios: expected {n} entries, got {ratios.shape[0]}")
        object.__setattr__(self, "volume_ratios", ratios)

    def __len__(self):
        return len(self.bodies)

    def body_ids(self, model):
        """(N,) MuJoCo body ids of the ellipsoids; InputError naming any body the model lacks (and its bodies)."""
        ids = np.empty(len(self), dtype=np.int64)
        for k, name in enumerate(self.bodies):
            if name.startswith("#") and name[1:].isdigit():
                ids[k] = int(name[1:]) if int(name[1:]) < model.nbody else -1
            else:
                ids[k] = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, name)
            if ids[k] < 0:
                labels = [body_label(model, b) for b in range(1, model.nbody)]
                shown = ", ".join(repr(b) for b in labels[:20]) + (", ..." if len(labels) > 20 else "")
                raise InputError(f"ellipsoids.bodies[{k}]: the model has no body {name!r}; its bodies: {shown}")
        return ids

    # ------------------------------------------------------------ files

    def to_dict(self):
        """Plain JSON-ready dictionary (format version 1)."""
        return {"version": FORMAT_VERSION, "ellipsoids": [
            {"body": b, "geom": g or None, "radii": r.tolist(), "position": p.tolist(),
             "quaternion": q.tolist(),
             "volume_ratio": None if not np.isfinite(v) else float(v)}
            for b, g, r, p, q, v in zip(self.bodies, self.geoms, self.radii, self.positions,
                                        self.quaternions, self.volume_ratios)]}

    @classmethod
    def from_dict(cls, doc):
        """Inverse of :meth:`to_dict`; errors name the entry and field."""
        if not isinstance(doc, dict) or not isinstance(doc.get("ellipsoids"), list):
            raise InputError("ellipsoids: expected an object with an 'ellipsoids' list")
        if doc.get("version", FORMAT_VERSION) != FORMAT_VERSION:
            raise InputError(f"version: unsupported ellipsoid file version {doc.get('version')!r}")
        rows = doc["ellipsoids"]
        for k, row in enumerate(rows):
            for key in ("body", "radii", "position", "quaternion"):
                if not isinstance(row, dict) or key not in row:
                    raise InputError(f"ellipsoids[{k}].{key}: missing")
        return cls(bodies=[r["body"] for r in rows],
                   radii=[_validate.radii(r["radii"], f"ellipsoids[{k}].radii") for k, r in enumerate(rows)],
                   positions=[r["position"] for r in rows],
                   quaternions=[r["quaternion"] for r in rows],
                   geoms=[r.get("geom") or "" for r in rows],
                   volume_ratios=[np.nan if r.get("volume_ratio") is None else r["volume_ratio"] for r in rows])

    def save(self, path):
        """Write to ``.json`` or ``.npz`` (chosen by the extension)."""
        path = _file_name(path)
        if path.endswith(".npz"):
            np.savez(path, version=FORMAT_VERSION, bodies=np.array(self.bodies), geoms=np.array(self.geoms),
                     radii=self.radii, positions=self.positions, quaternions=self.quaternions,
                     volume_ratios=self.volume_ratios)
        elif path.endswith(".json"):
            with open(path, "w") as fh:
                json.dump(self.to_dict(), fh, indent=1)
                fh.write("\n")
        else:
            raise InputError(f"path: expected a .json or .npz file name, got {path!r}")

    @classmethod
    def load(cls, path):
        """Read a file written by :meth:`save`; every error is an InputError naming the file."""
        path = _file_name(path)
        if not path.endswith((".npz", ".json")):
            raise InputError(f"path: expected a .json or .npz file name, got {path!r}")
        try:
            return cls._read(path)
        except FileNotFoundError:
            raise InputError(f"{path}: no such ellipsoid file") from None
        except IsADirectoryError:
            raise InputError(f"{path}: is a folder, expected an ellipsoid file") from None
        except OSError as exc:
            raise InputError(f"{path}: cannot read the ellipsoid file: {exc.strerror or exc}") from None
        except json.JSONDecodeError as exc:
            raise InputError(f"{path}: not valid JSON: {exc}") from None
        except UnicodeDecodeError:
            raise InputError(f"{path}: not a text file; expected JSON") from None
        except ValueError as exc:  # the content (InputError from the checks)
            raise InputError(f"{path}: {exc}") from None

    @classmethod
    def _read(cls, path):
        """The set in the ``.json`` or ``.npz`` file ``path`` (the errors of :meth:`load` unwrapped)."""
        if path.endswith(".npz"):
            try:
                archive = np.load(path, allow_pickle=False)
            except (ValueError, zipfile.BadZipFile, EOFError) as exc:
                raise InputError(f"not a readable .npz file ({exc})") from None
            with archive as f:
                missing = [k for k in ("bodies", "radii", "positions", "quaternions") if k not in f]
                if missing:
                    raise InputError(f"missing array {missing[0]!r}")
                return cls(bodies=f["bodies"].tolist(), radii=f["radii"], positions=f["positions"],
                           quaternions=f["quaternions"],
                           geoms=f["geoms"].tolist() if "geoms" in f else (),
                           volume_ratios=f["volume_ratios"] if "volume_ratios" in f else None)
        with open(path, encoding="utf-8") as fh:
            return cls.from_dict(json.load(fh))


def _file_name(path):
    """``path`` as a string (str or os.PathLike; anything else is refused)."""
    try:
        return os.fspath(path)
    except TypeError:
        raise InputTypeError(f"path: expected a file name, got {type(path).__name__}") from None


def body_label(model, body_id):
    """A body's name, or ``#id`` for an unnamed body (how :class:`EllipsoidSet` refers to it)."""
    name = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_BODY, int(body_id))
    return name if name else f"#{int(body_id)}"


def body_report_label(model, body_id):
    """A body's name as reports give it: its name, or for an unnamed body ``#id`` and the name of its first named
    geom, ``#4 (ball)``, so that a contact of an unnamed body says which it is."""
    label = body_label(model, body_id)
    if not label.startswith("#"):
        return label
    start, num = int(model.body_geomadr[body_id]), int(model.body_geomnum[body_id])
    for g in range(start, start + num) if start >= 0 else ():
        name = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_GEOM, g)
        if name:
            return f"{label} ({name})"
    return label


def load_ellipsoids(path):
    """Load an :class:`EllipsoidSet` from a ``.json`` or ``.npz`` file."""
    return EllipsoidSet.load(path)


# ---------------------------------------------------------------- fitting a model


def geom_ellipsoids(model, group=BOUND_GROUP, *, any_group=False):
    """:class:`EllipsoidSet` made of the model's ellipsoid geoms in ``group`` (e.g. fitted bounding geoms).

    Each geom becomes one ellipsoid fixed in its body at the geom's local pose.  With ``any_group``,
    a model without ellipsoid geoms in ``group`` gives all its ellipsoid geoms instead.
    """
    if not isinstance(model, mujoco.MjModel):
        raise InputTypeError(f"model: expected a mujoco.MjModel, got {type(model).__name__}")
    if isinstance(group, (bool, np.bool_)) or not isinstance(group, (int, np.integer)):
        raise InputTypeError(f"group: expected an integer geom group in 0..5, got {group!r}")
    if not 0 <= int(group) < 6:
        raise InputError(f"group: expected an integer geom group in 0..5, got {group!r}")
    ellipsoid = model.geom_type == mujoco.mjtGeom.mjGEOM_ELLIPSOID
    ids = np.flatnonzero(ellipsoid & (model.geom_group == int(group)))
    if len(ids) == 0 and any_group:
        ids = np.flatnonzero(ellipsoid)
    if len(ids) == 0:
        raise InputError(f"group: the model has no ellipsoid geom{'' if any_group else f' in group {int(group)}'}")
    names = [mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_GEOM, int(g)) or f"#{int(g)}" for g in ids]
    low, high = _validate.LENGTH_RANGE
    radii = model.geom_size[ids]
    bad = np.flatnonzero(~np.all((radii >= low) & (radii <= high), axis=1))  # NaN fails too
    if len(bad):
        raise InputError(f"ellipsoid {names[bad[0]]!r} has semi-axes {radii[bad[0]].tolist()}; supported: "
                         f"{low:g} to {high:g} m")
    return EllipsoidSet(bodies=[body_label(model, b) for b in model.geom_bodyid[ids]],
                        radii=model.geom_size[ids].copy(), positions=model.geom_pos[ids].copy(),
                        quaternions=model.geom_quat[ids].copy(), geoms=names)


def geom_shape(model, geom_id, *, hull=False):
    """The :class:`~mjccd.fitting.Shape` of a supported geom, in its body's frame.

    A mesh is its vertices and faces, or with ``hull`` the vertices and faces
    of the convex hull MuJoCo collides it by (:func:`mesh_hull`).
    """
    gtype = int(model.geom_type[geom_id])
    if gtype not in SUPPORTED:
        raise ValueError(f"geom {geom_id}: type {gtype} is not supported")
    position, rotation = model.geom_pos[geom_id].copy(), quat_to_matrix(model.geom_quat[geom_id].copy())
    if gtype != mujoco.mjtGeom.mjGEOM_MESH:
        return Shape(SUPPORTED[gtype], model.geom_size[geom_id].copy(), position, rotation)
    mesh = int(model.geom_dataid[geom_id])
    if hull:
        vertices, faces = mesh_hull(model, mesh)
        return Shape("mesh", model.geom_size[geom_id].copy(), position, rotation, vertices=vertices, faces=faces)
    vert, face = model.mesh_vertadr[mesh], model.mesh_faceadr[mesh]
    return Shape("mesh", model.geom_size[geom_id].copy(), position, rotation,
                 vertices=model.mesh_vert[vert:vert + model.mesh_vertnum[mesh]].astype(float),
                 faces=model.mesh_face[face:face + model.mesh_facenum[mesh]])


def mesh_hull(model, mesh_id):
    """``(vertices (k, 3), faces (m, 3))`` of the convex hull of a mesh, in the mesh's frame.

    The hull MuJoCo computes (qhull) and collides the mesh by: the model's own
    convex graph when it has one, else that of a one-geom model compiled
    from the mesh's vertices (MuJoCo builds no hull for a mesh that only
    visual geoms use).  ``faces`` index ``vertices``, outward by the right-hand rule.
    """
    mesh_id = int(mesh_id)
    start, count = model.mesh_vertadr[mesh_id], model.mesh_vertnum[mesh_id]
    vertices = model.mesh_vert[start:start + count].astype(float)
    adr = int(model.mesh_graphadr[mesh_id])
    graph = model.mesh_graph[adr:] if adr >= 0 else _hull_graph(model, mesh_id, vertices)
    nvert, nface = int(graph[0]), int(graph[1])
    first = 2 + 3 * nvert + 3 * nface  # numvert, numface, vert_edgeadr, vert_globalid, edge_localid, face_globalid
    faces = np.asarray(graph[first:first + 3 * nface], dtype=np.int64).reshape(nface, 3)
    used = np.unique(faces)
    return vertices[used], np.searchsorted(used, faces)


def _hull_graph(model, mesh_id, vertices):
    """MuJoCo's convex graph of a mesh with these vertices (vertex order kept), from a one-geom model."""
    spec = mujoco.MjSpec()
    spec.add_mesh(name="hull", uservert=vertices.ravel().tolist())
    spec.worldbody.add_geom(type=mujoco.mjtGeom.mjGEOM_MESH, meshname="hull")
    name = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_MESH, mesh_id) or f"#{mesh_id}"
    try:
        hull = spec.compile()
    except ValueError as exc:
        raise ValueError(f"mesh {name!r}: MuJoCo cannot build its convex hull: {' '.join(str(exc).split())}") from None
    if hull.mesh_vertnum[0] != len(vertices) or hull.mesh_graphadr[0] < 0:
        raise ValueError(f"mesh {name!r}: MuJoCo built no convex hull of its {len(vertices)} vertices")
    return hull.mesh_graph[hull.mesh_graphadr[0]:]


def collision_geoms(model, body_id, *, include_visual=False):
    """Geom ids of a body that take part in collisions (with ``include_visual``, all its geoms but the bounds
    ``mjccd fit`` wrote: visual ellipsoids in group :data:`BOUND_GROUP`)."""
    start, num = model.body_geomadr[body_id], model.body_geomnum[body_id]
    ids = range(start, start + num) if start >= 0 else range(0)
    return [g for g in ids if (model.geom_contype[g] | model.geom_conaffinity[g])
            or (include_visual and not _is_bound(model, g))]


def _is_bound(model, g):
    """Geom g is a fitted bound: a visual ellipsoid in :data:`BOUND_GROUP`."""
    return (model.geom_type[g] == mujoco.mjtGeom.mjGEOM_ELLIPSOID and model.geom_group[g] == BOUND_GROUP
            and not (model.geom_contype[g] | model.geom_conaffinity[g]))


def geom_id(model, label):
    """The id of the geom :func:`geom_label` calls ``label`` (its name, or ``#id``), -1 when the model has none."""
    if label.startswith("#") and label[1:].isdigit():
        return int(label[1:]) if int(label[1:]) < model.ngeom else -1
    return mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, label)


def geom_label(model, geom_id):
    """A geom's name, or ``#id`` for an unnamed geom (as ``fit_model(per="geom")`` names it)."""
    return mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_GEOM, int(geom_id)) or f"#{int(geom_id)}"


def fit_model(model, *, tolerance=DEFAULT_TOLERANCE, per="body", bodies=None, include_visual=False,
              max_ellipsoids=MAX_ELLIPSOIDS, cache=True):
    """Bounding ellipsoids of a compiled model as an :class:`EllipsoidSet`.

    Two fits:

    * ``tolerance=t`` (the default: :data:`mjccd.fitting.DEFAULT_TOLERANCE`,
      0.01 m, as ``mjccd fit``): each geom is covered by the fewest
      ellipsoids that keep every point of them within ``t`` of the geom
      (:func:`mjccd.fitting.cover_shape`; a mesh is its convex hull, as
      MuJoCo collides it).  With ``per="body"`` a body's geoms share one
      ellipsoid when that one is proven to stay within ``t`` of them
      (:func:`mjccd.fitting.within_tolerance`), e.g. a finger of two small
      capsules; with ``per="geom"`` every geom gets its own cover.
    * ``tolerance=None``: one ellipsoid per body (``per="body"``) or per geom
      (``per="geom"``), the minimum-volume one with proven containment.
      Fewer, but loose: a box gets ``sqrt(3)`` times its half sizes, a limb
      capsule's ends 7-8 cm more.

    Every point of every bounded geom lies inside the union of the ellipsoids
    in both fits.  Fits are kept on disk (:mod:`mjccd.mujoco.fit_cache`,
    keyed by the model's geometry, the options and the fitting code), so the
    same fit in another process is read back instead of computed.

    Args:
        model: ``mujoco.MjModel``.
        tolerance: the most a point of an ellipsoid may lie from its geometry (model units, > 0), or None.
        per: "body" or "geom" (see above).
        bodies: body names or ids to fit; default every body with supported collision geometry.
        include_visual: also bound geoms with ``contype = conaffinity = 0``.
        max_ellipsoids: with a tolerance, the most ellipsoids for one geom: a geom that needs more is covered
            within twice, four times, ... the tolerance, the least that needs no more, with a CoverageWarning.
        cache: read and keep the fit in the on-disk cache (False: always fit, keep nothing).

    Planes, height fields and SDF geoms are unbounded or implicit: they are
    skipped (and a body that has nothing else is left out).  ``geoms`` names
    the geom an ellipsoid bounds ("" for a whole body); ``volume_ratios``
    compare an ellipsoid with the summed volume of the geometry it bounds
    (its geom for a piece of a cover, so a cover's ratios add up; overlaps
    counted twice); :func:`fit_report` measures the union per body.
    """
    if not isinstance(model, mujoco.MjModel):
        raise ValueError(f"model: expected a mujoco.MjModel, got {type(model).__name__}")
    if per not in ("body", "geom"):
        raise ValueError(f"per: expected 'body' or 'geom', got {per!r}")
    if tolerance is not None:
        valid = isinstance(tolerance, (int, float, np.integer, np.floating)) and not isinstance(tolerance, bool)
        if not valid or not (np.isfinite(tolerance) and tolerance > 0):
            raise ValueError(f"tolerance: expected None or a positive length, got {tolerance!r}")
    explicit = bodies is not None
    body_ids = [int(b) for b in _resolve_bodies(model, bodies)] if explicit else list(range(model.nbody))
    options = {"tolerance": None if tolerance is None else float(tolerance), "per": per, "include_visual":
               bool(include_visual), "max_ellipsoids": int(max_ellipsoids), "bodies": body_ids if explicit else None}
    name = fit_cache.key(model, options) if cache else None
    found = None if name is None else fit_cache.load(name)
    if found is not None:
        try:
            stored = EllipsoidSet(**found[0])
        except InputError:  # a damaged entry: fitted again below, and replaced
            stored = None
        if stored is not None and len(stored):
            for note in found[1]:
                warnings.warn(note, CoverageWarning, stacklevel=2)
            return stored
    fitted, notes = _fit(model, tolerance, per, body_ids, explicit, include_visual, max_ellipsoids)
    for note in notes:
        warnings.warn(note, CoverageWarning, stacklevel=2)
    if fitted is None:
        hint = "" if include_visual else " (include_visual=True also bounds the visual geoms)"
        warnings.warn(f"fit_model: no body has sphere, capsule, ellipsoid, cylinder, box or mesh collision geometry: "
                      f"nothing to bound{hint}", CoverageWarning, stacklevel=2)
        return EllipsoidSet(bodies=(), radii=np.zeros((0, 3)), positions=np.zeros((0, 3)),
                            quaternions=np.zeros((0, 4)))
    if name is not None:
        fit_cache.store(name, fitted, notes)
    # built again from its own arrays, as reading the stored copy builds it (normalising the quaternions once
    # more): a fit and its cached copy are the same to the last bit
    return EllipsoidSet(fitted.bodies, fitted.radii, fitted.positions, fitted.quaternions, fitted.geoms,
                        fitted.volume_ratios)


def _fit(model, tolerance, per, body_ids, explicit, include_visual, max_ellipsoids):
    """``(ellipsoids, notes)``: the fit of :func:`fit_model` (its arguments checked; None when there is nothing to
    bound) and the warnings it owes (geoms covered within a looser tolerance)."""
    notes = []
    out = {"bodies": [], "geoms": [], "radii": [], "positions": [], "quaternions": [], "volume_ratios": []}

    def emit(body_id, geom_name, ellipsoids, volume):
        for c, R, r in ellipsoids:
            out["bodies"].append(body_label(model, body_id))
            out["geoms"].append(geom_name)
            out["radii"].append(r)
            out["positions"].append(c)
            out["quaternions"].append(matrix_to_quat(R))
            out["volume_ratios"].append(4.0 / 3.0 * np.pi * np.prod(r) / volume if volume > 0 else np.nan)

    def body_fit(b):
        """``(emitted, notes)`` of body b: the arguments of each ``emit`` and the notes, in order."""
        emitted, body_notes = [], []
        geoms = collision_geoms(model, b, include_visual=include_visual)
        label = body_label(model, b)
        if not geoms:
            if explicit:
                raise ValueError(f"bodies: body {label!r} has no collision geometry")
            return emitted, body_notes
        usable = [g for g in geoms if int(model.geom_type[g]) in SUPPORTED]
        if not usable:
            if explicit:
                kinds = sorted({mujoco.mjtGeom(int(model.geom_type[g])).name for g in geoms})
                raise ValueError(f"bodies: body {label!r} has only unsupported geoms ({', '.join(kinds)})")
            return emitted, body_notes
        keep = lambda *args: emitted.append(args)  # noqa: E731
        try:
            if tolerance is not None:
                _cover_body(model, b, usable, tolerance, per, max_ellipsoids, keep, body_notes)
            elif per == "geom":
                for g in usable:
                    shape = geom_shape(model, g)
                    keep(b, geom_label(model, g), [fit_shapes([shape])], shape.volume())
            else:
                shapes = [geom_shape(model, g) for g in usable]
                keep(b, "", [fit_shapes(shapes)], sum(shape.volume() for shape in shapes))
        except ValueError as exc:
            raise ValueError(f"body {label!r}: {exc}") from None
        return emitted, body_notes

    # Bodies are fitted on all cores (the covers' kernels release the GIL), their results taken in body order:
    # the same ellipsoids, notes and first error as one after the other.  BLAS runs one thread meanwhile: its
    # threads spin on the fit's many small products and took more time than they saved (Kinova's meshes:
    # 8.8 s with them, 6.8 s without, 3.9 s on two cores).
    workers = min(len(body_ids), len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else
                  (os.cpu_count() or 1))
    with threadpool_limits(limits=1, user_api="blas"):
        if tolerance is None or workers < 2:
            results = [body_fit(b) for b in body_ids]
        else:
            with ThreadPoolExecutor(workers, thread_name_prefix="mjccd-fit") as pool:
                results = list(pool.map(body_fit, body_ids))
    for emitted, body_notes in results:
        for args in emitted:
            emit(*args)
        notes.extend(body_notes)
    return (EllipsoidSet(**out) if out["bodies"] else None), notes


def _cover_body(model, body_id, geoms, tolerance, per, max_ellipsoids, emit, notes):
    """Emit a body's ellipsoids to a tolerance: one for all its geoms when that is proven close enough, else covers.

    A geom that needs more than ``max_ellipsoids`` is covered within the least of twice, four times, ... the
    tolerance that needs no more, and a line saying so goes to ``notes``.
    """
    shapes = [geom_shape(model, g, hull=True) for g in geoms]
    if per == "body" and len(shapes) > 1:
        whole = fit_shapes(shapes)
        if within_tolerance(*whole, shapes, tolerance):
            emit(body_id, "", [whole], sum(shape.volume() for shape in shapes))
            return
    for g, shape in zip(geoms, shapes):
        try:
            cover, used = cover_loosened(shape, tolerance, max_ellipsoids=max_ellipsoids)
        except ValueError as exc:
            raise ValueError(f"geom {geom_label(model, g)!r}: {exc}") from None
        if used != tolerance:
            notes.append(f"fit_model: geom {geom_label(model, g)!r} of body {body_label(model, body_id)!r} needs more "
                         f"than {max_ellipsoids} ellipsoids within {tolerance:g} of it; it is covered within {used:g} "
                         f"({len(cover)} ellipsoids; raise max_ellipsoids for a tighter cover)")
        emit(body_id, geom_label(model, g), cover, shape.volume())


@dataclass(frozen=True)
class BodyReport:
    """How tightly a body's ellipsoids bound its geometry (:func:`fit_report`).

    Attributes:
        body: body label, as in :attr:`EllipsoidSet.bodies`.
        ellipsoids: how many ellipsoids the body has.
        overshoot: the farthest a point of them lies from the body's geometry (model units), measured.
        volume_ratio: volume of their union over volume of the geometry's union (overlaps counted once).
    """

    body: str
    ellipsoids: int
    overshoot: float
    volume_ratio: float


def fit_report(model, ellipsoids, *, include_visual=False, surface_samples=SURFACE_SAMPLES,
               volume_samples=VOLUME_SAMPLES):
    """Per body: ellipsoid count, measured overshoot and union volume ratio, as a tuple of :class:`BodyReport`.

    A body's geometry is the union of its supported geoms that take part in
    collisions (all of them with ``include_visual``) and of any geom an
    ellipsoid names, unless that geom is itself a bound (a visual-only
    ellipsoid in group :data:`BOUND_GROUP`, as :func:`geom_ellipsoids`
    reads); a mesh is its convex hull.  The measurements are
    :func:`mjccd.fitting.cover_report`'s: the overshoot is the largest exact
    distance (closed forms; for a mesh, the distance to its hull's faces)
    from ``surface_samples`` points on each ellipsoid's surface, refined by
    local ascent, and from the Halton points inside them, to the geometry;
    the volume ratio counts ``volume_samples`` Halton points in the box
    around the body's ellipsoids.  Bodies come in the order of the set.
    """
    if not isinstance(ellipsoids, EllipsoidSet):
        raise InputTypeError(f"ellipsoids: expected an EllipsoidSet, got {type(ellipsoids).__name__}")
    ids = ellipsoids.body_ids(model)
    geom_ids = {geom_label(model, g): g for g in range(model.ngeom)}
    reports = []
    for label in dict.fromkeys(ellipsoids.bodies):
        rows = [k for k, b in enumerate(ellipsoids.bodies) if b == label]
        b = int(ids[rows[0]])
        geoms = [g for g in collision_geoms(model, b, include_visual=include_visual)
                 if int(model.geom_type[g]) in SUPPORTED]
        for k in rows:
            g = geom_ids.get(ellipsoids.geoms[k])
            if g is not None and int(model.geom_bodyid[g]) == b and g not in geoms and not _is_bound(model, g):
                geoms.append(g)
        if not geoms:
            raise InputError(f"ellipsoids: body {label!r} has no supported geometry to compare its ellipsoids with")
        shapes = [geom_shape(model, g, hull=True) for g in geoms]
        bounds = [(ellipsoids.positions[k], quat_to_matrix(ellipsoids.quaternions[k]), ellipsoids.radii[k])
                  for k in rows]
        overshoot, ratio = cover_report(bounds, shapes, surface_samples=surface_samples,
                                        volume_samples=volume_samples)
        reports.append(BodyReport(label, len(rows), overshoot, ratio))
    return tuple(reports)


def _is_bound(model, geom_id):
    """Whether a geom looks like a fitted bound: a visual-only ellipsoid in :data:`BOUND_GROUP`."""
    return (int(model.geom_type[geom_id]) == mujoco.mjtGeom.mjGEOM_ELLIPSOID
            and int(model.geom_group[geom_id]) == BOUND_GROUP
            and not model.geom_contype[geom_id] | model.geom_conaffinity[geom_id])


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
