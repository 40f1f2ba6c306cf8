"""Fitted ellipsoids kept on disk, so that fitting a model again (a second process, a test run, each worker of a
vector environment) costs a file read, not a fit.

An entry is keyed by what the fit reads of the model (:data:`MODEL_FIELDS`: the geoms, their bodies, the meshes
and the names), the fit's options, the versions of mjccd and MuJoCo and the text of the modules that fit, so that
a changed model, an edit or an upgrade never reads a stale fit.  Entries are ``.npz`` files in :func:`folder`,
written under a temporary name and renamed into place, so a reader sees a whole entry or none; an entry that is
missing or cannot be read is fitted again, and a folder that cannot be written is not used (the fit is returned
all the same).  ``MJCCD_FIT_CACHE`` names another folder, or turns the cache off with ``off``.
"""
import functools
import hashlib
import os
import pathlib
import tempfile
import zipfile

import mujoco
import numpy as np

import mjccd
from mjccd._cache import user_cache_dir

ENVIRONMENT = "MJCCD_FIT_CACHE"
# everything fit_model reads of a model (collision_geoms, geom_shape, the labels, _resolve_bodies)
MODEL_FIELDS = ("body_geomadr", "body_geomnum", "geom_bodyid", "geom_contype", "geom_conaffinity", "geom_type",
                "geom_group", "geom_size", "geom_pos", "geom_quat", "geom_dataid", "mesh_vertadr", "mesh_vertnum",
                "mesh_vert", "mesh_faceadr", "mesh_facenum", "mesh_face", "mesh_graphadr", "mesh_graph",
                "name_bodyadr", "name_geomadr", "names")
SOURCES = ("fitting.py", "mujoco/ellipsoids.py", "mujoco/fit_cache.py", "quadric.py")  # the code that fits


def folder(environ=os.environ):
    """The cache folder (``$MJCCD_FIT_CACHE``, else ``fits`` in mjccd's user cache), or None when turned off."""
    chosen = environ.get(ENVIRONMENT)
    if chosen == "off":
        return None
    return pathlib.Path(chosen or os.path.join(user_cache_dir(environ), "fits"))


@functools.lru_cache(maxsize=None)
def _code_digest():
    """A digest of the versions and of the fitting code's text (read once per process)."""
    digest = hashlib.sha256(f"{mjccd.__version__} {mujoco.__version__} {np.__version__}".encode())
    package = pathlib.Path(mjccd.__file__).parent
    for name in SOURCES:
        digest.update((package / name).read_bytes())
    return digest.digest()


def key(model, options):
    """The entry name of a fit of ``model`` with ``options`` (a dict of plain values)."""
    digest = hashlib.sha256(_code_digest())
    digest.update(repr(sorted(options.items())).encode())
    for name in MODEL_FIELDS:
        value = np.ascontiguousarray(getattr(model, name))
        digest.update(f"{name} {value.dtype.str} {value.shape}".encode())
        digest.update(value.tobytes())
    return digest.hexdigest()


def load(name, environ=os.environ):
    """``(fields, notes)`` stored as ``name``: the :class:`~mjccd.mujoco.EllipsoidSet`'s fields (a dict of its
    arguments) and the fit's warnings; None when none is stored, the cache is off, or the entry cannot be read
    (it is then fitted again and replaced)."""
    where = folder(environ)
    if where is None:
        return None
    try:
        with np.load(where / f"{name}.npz", allow_pickle=False) as entry:
            fields = {"bodies": entry["bodies"].tolist(), "geoms": entry["geoms"].tolist(),
                      **{k: entry[k] for k in ("radii", "positions", "quaternions", "volume_ratios")}}
            return fields, [str(note) for note in entry["notes"].tolist()]
    except (OSError, ValueError, KeyError, EOFError, zipfile.BadZipFile):
        return None


def store(name, ellipsoids, notes=(), environ=os.environ):
    """Keep ``ellipsoids`` and the fit's ``notes`` as ``name``; quietly nothing when the folder cannot be
    written."""
    where = folder(environ)
    if where is None:
        return
    handle, temporary = None, None
    try:
        where.mkdir(parents=True, exist_ok=True)
        handle, temporary = tempfile.mkstemp(prefix=".fit-", suffix=".npz", dir=where)
        os.close(handle)
        with open(temporary, "wb") as fh:
            np.savez(fh, bodies=np.array(ellipsoids.bodies, dtype=str), geoms=np.array(ellipsoids.geoms, dtype=str),
                     radii=ellipsoids.radii, positions=ellipsoids.positions, quaternions=ellipsoids.quaternions,
                     volume_ratios=ellipsoids.volume_ratios, notes=np.array(list(notes), dtype=str))
        os.replace(temporary, where / f"{name}.npz")
        temporary = None
    except OSError:
        pass
    finally:
        if temporary is not None:
            try:
                os.unlink(temporary)
            except OSError:
                pass
