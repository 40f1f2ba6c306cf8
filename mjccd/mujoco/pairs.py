"""Which pairs of ellipsoids to check: MuJoCo's own body-pair rules, pairs named by the user, or all pairs
between characters (the replay's default).

Every MuJoCo-facing path (monitor, guard, replay, testing, wrappers) picks its pairs here.
"""
import mujoco
import numpy as np

from mjccd.errors import InputError, InputTypeError
from mjccd.quadric import static_status_code
from mjccd.mujoco.chains import body_path
from mjccd.mujoco.ellipsoids import body_label
from mjccd.mujoco.motions import Kinematics, State


def _pair_key(a, b):
    return (a, b) if a < b else (b, a)


def excluded_body_pairs(model):
    """Body pairs named in the model's ``<exclude>`` elements, as (low id, high id) tuples."""
    out = set()
    for sig in np.asarray(model.exclude_signature).ravel():
        out.add(_pair_key(int(sig >> 16), int(sig & 0xFFFF)))
    return out


def _filtered_by_mujoco(model, a, b):
    """MuJoCo's own body-pair filter: same weld body, or (with filterparent) weld parent and child."""
    weld = model.body_weldid
    wa, wb = weld[a], weld[b]
    if wa == wb:
        return True
    if model.opt.disableflags & mujoco.mjtDisableBit.mjDSBL_FILTERPARENT:
        return False
    pa, pb = weld[model.body_parentid[wa]], weld[model.body_parentid[wb]]
    return wa != 0 and wb != 0 and (wa == pb or wb == pa)


def _can_touch(model, a, b):
    """True when some collision geom of body a and some of body b pass the contype/conaffinity test."""
    def geoms(body):
        start = model.body_geomadr[body]
        return range(start, start + model.body_geomnum[body]) if start >= 0 else range(0)
    for g in geoms(a):
        for h in geoms(b):
            if (model.geom_contype[g] & model.geom_conaffinity[h]) or (model.geom_contype[h] & model.geom_conaffinity[g]):
                return True
    return False


def default_pairs(model, ellipsoids, *, drop_overlapping_at_qpos0=True):
    """(P, 2) ellipsoid index pairs worth checking.

    The pairs of bodies MuJoCo itself would test for contact: different weld
    bodies, not a weld parent and child (unless ``filterparent`` is disabled),
    not listed in ``<exclude>``, and with at least one geom pair passing the
    contype/conaffinity test.  With ``drop_overlapping_at_qpos0`` the pairs
    whose ellipsoids already touch or overlap in the reference pose ``qpos0``
    are dropped too: close neighbours (a hip and the lower back) would
    otherwise report a contact at every step.
    """
    ids = ellipsoids.body_ids(model)
    excluded = excluded_body_pairs(model)
    verdict = {}
    rows = []
    for i in range(len(ids)):
        for j in range(i + 1, len(ids)):
            key = _pair_key(int(ids[i]), int(ids[j]))
            if key not in verdict:
                a, b = key
                verdict[key] = (a != b and not _filtered_by_mujoco(model, a, b) and key not in excluded
                                and _can_touch(model, a, b))
            if verdict[key]:
                rows.append((i, j))
    pairs = np.array(rows, dtype=np.int64).reshape(-1, 2)
    if drop_overlapping_at_qpos0 and len(pairs):
        kin = Kinematics(model)
        state = State(model.qpos0.copy(), model.body_pos[model.body_mocapid >= 0].copy(),
                      model.body_quat[model.body_mocapid >= 0].copy())
        poses = kin.ellipsoid_poses(state, ids, ellipsoids.positions, ellipsoids.quaternions)
        keep = [static_status_code(ellipsoids.radii[i], poses[i, :3], poses[i, 3:],
                                   ellipsoids.radii[j], poses[j, :3], poses[j, 3:]) == 1 for i, j in pairs]
        pairs = pairs[np.asarray(keep, dtype=bool)]
    return pairs


def _names(labels):
    """``'a', 'b', ...`` for an error message (the first 20)."""
    shown = ", ".join(repr(n) for n in labels[:20])
    return shown + (f", ... ({len(labels)} in all)" if len(labels) > 20 else "")


def pairs_from_bodies(model, ellipsoids, body_pairs, field="pairs"):
    """(P, 2) ellipsoid pairs from a list of (body, body) given by name or id.

    A name or id the model lacks, or a body without an ellipsoid, raises :class:`~mjccd.errors.InputError`
    listing the bodies that carry ellipsoids (and naming the body of a geom given by mistake).
    """
    ids = ellipsoids.body_ids(model)
    with_ellipsoids = [body_label(model, b) for b in dict.fromkeys(ids.tolist())]
    hint = f"; bodies with ellipsoids: {_names(with_ellipsoids)}"
    rows = []
    if isinstance(body_pairs, (str, bytes)):
        raise InputTypeError(f"{field}: expected a list of (body, body) pairs, got {body_pairs!r}")
    try:
        items = list(body_pairs)
    except TypeError:
        raise InputTypeError(f"{field}: expected a list of (body, body) pairs, "
                             f"got {type(body_pairs).__name__}") from None
    for k, pair in enumerate(items):
        if isinstance(pair, str) or not hasattr(pair, "__len__") or len(pair) != 2:
            raise InputError(f"{field}[{k}]: expected a (body, body) pair, got {pair!r}")
        resolved = []
        for side, body in zip((0, 1), pair):
            where = f"{field}[{k}][{side}]"
            if isinstance(body, (int, np.integer)) and not isinstance(body, (bool, np.bool_)):
                bid = int(body)
                if not 0 <= bid < model.nbody:
                    raise InputError(f"{where}: body id {bid} out of range [0, {model.nbody}){hint}")
            elif isinstance(body, str):
                bid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, body)
                if bid < 0:
                    geom = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, body)
                    also = "" if geom < 0 else \
                        f" ({body!r} is a geom of body {body_label(model, model.geom_bodyid[geom])!r})"
                    raise InputError(f"{where}: the model has no body named {body!r}{also}{hint}")
            else:
                raise InputError(f"{where}: expected a body name or id, got {body!r}")
            if not np.any(ids == bid):
                raise InputError(f"{where}: body {body_label(model, bid)!r} has no ellipsoid{hint}")
            resolved.append(bid)
        if resolved[0] == resolved[1]:
            raise InputError(f"{field}[{k}]: a body cannot be paired with itself ({pair[0]!r})")
        for i in np.flatnonzero(ids == resolved[0]):
            for j in np.flatnonzero(ids == resolved[1]):
                rows.append((int(i), int(j)))
    if not rows:
        raise InputError(f"{field}: empty pair list")
    return np.array(rows, dtype=np.int64)


def character_pairs(model, ellipsoids, body_ids=None):
    """(P, 2) pairs of ellipsoids under different top-level bodies (characters) of which at least one moves
    (has a joint on its path to the world).

    The replay's default: two boxers, a robot and its obstacles.  ``body_ids``: the ellipsoids' bodies
    when the caller already has them.
    """
    ids = ellipsoids.body_ids(model) if body_ids is None else np.asarray(body_ids)
    top = model.body_rootid[ids]
    moving = np.array([any(model.body_jntnum[b] > 0 for b in body_path(model, b)) for b in ids], dtype=bool)
    rows = [(a, b) for a in range(len(ids)) for b in range(a + 1, len(ids))
            if top[a] != top[b] and (moving[a] or moving[b])]
    return np.array(rows, dtype=np.int64).reshape(-1, 2)


def select_pairs(model, ellipsoids, pairs, body_ids=None, field="pairs"):
    """The (P, 2) ellipsoid pairs for a ``pairs`` argument: None (:func:`default_pairs`), ``"characters"``
    (:func:`character_pairs`), or a list of (body, body) names or ids (:func:`pairs_from_bodies`)."""
    if pairs is None:
        return default_pairs(model, ellipsoids)
    if isinstance(pairs, str) and pairs == "characters":
        return character_pairs(model, ellipsoids, body_ids)
    return pairs_from_bodies(model, ellipsoids, pairs, field)
