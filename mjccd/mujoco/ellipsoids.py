"""Bounding ellipsoids of MuJoCo bodies: fitted to a model's geoms, the set and its files, its binding to a model.

The fitting maths is :mod:`mjccd.fitting`; this module reads the geoms of a
``mujoco.MjModel`` into its shapes and labels the result by body.
"""
import json
import os
import zipfile
from dataclasses import dataclass, field

import mujoco
import numpy as np

from mjccd import _validate
from mjccd.errors import InputError, InputTypeError
from mjccd.fitting import Shape, fit_shapes
from mjccd.quadric import matrix_to_quat, quat_to_matrix

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
        if n == 0:
            raise InputError("bodies: an ellipsoid set needs at least one ellipsoid")
        object.__setattr__(self, "bodies", bodies)
        object.__setattr__(self, "radii", _validate.radii_array(self.radii, "radii"))
        object.__setattr__(self, "positions", _validate.array(self.positions, (n, 3), "positions"))
        quats = _validate.pose_array(np.hstack([np.zeros((n, 3)), _validate.array(
            self.quaternions, (n, 4), "quaternions")]), "quaternions")[:, 3:]
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


def geom_shape(model, geom_id):
    """The :class:`~mjccd.fitting.Shape` of a supported geom, in its body's frame."""
    gtype = int(model.geom_type[geom_id])
    if gtype not in SUPPORTED:
        raise ValueError(f"geom {geom_id}: type {gtype} is not supported")
    position, rotation = model.geom_pos[geom_id].copy(), quat_to_matrix(model.geom_quat[geom_id].copy())
    if gtype != mujoco.mjtGeom.mjGEOM_MESH:
        return Shape(SUPPORTED[gtype], model.geom_size[geom_id].copy(), position, rotation)
    mesh = int(model.geom_dataid[geom_id])
    vert, face = model.mesh_vertadr[mesh], model.mesh_faceadr[mesh]
    return Shape("mesh", model.geom_size[geom_id].copy(), position, rotation,
                 vertices=model.mesh_vert[vert:vert + model.mesh_vertnum[mesh]].astype(float),
                 faces=model.mesh_face[face:face + model.mesh_facenum[mesh]])


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

    def emit(body_id, geom_name, shapes):
        c, R, r = fit_shapes(shapes)
        volume = sum(shape.volume() for shape in shapes)
        out["bodies"].append(body_label(model, body_id))
        out["geoms"].append(geom_name)
        out["radii"].append(r)
        out["positions"].append(c)
        out["quaternions"].append(matrix_to_quat(R))
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
                name = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_GEOM, g) or f"#{g}"
                emit(b, name, [geom_shape(model, g)])
        else:
            try:
                emit(b, "", [geom_shape(model, g) for g in usable])
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
