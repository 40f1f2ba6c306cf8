"""Which pairs to check: MuJoCo's own collision rules (between ellipsoids, and ellipsoids against static
planes), pairs named by the user, every pair between characters, or a character's own non-adjacent parts.

Every MuJoCo-facing path (monitor, guard, replay, testing, wrappers) picks its pairs here.

MuJoCo's rules are those of its collision driver (``mj_collision``, ``mj_broadphase`` and
``filterBodyPair`` in ``engine_collision_driver.c``, MuJoCo 3.12 and later, where a mocap body is the
weld root of its own subtree).  A pair of geoms is collided when

* the two geoms form an explicit ``<pair>`` (collided whatever the rules below say), or
* their bodies are not on one weld body (no joint between them), not both dof-less (static bodies and
  mocap bodies never collide with each other), not a weld parent and child (unless ``filterparent`` is
  disabled; a body welded to the world is never filtered as a parent), the geoms pass the
  contype/conaffinity test (``contype1 & conaffinity2 || contype2 & conaffinity1``), and the body pair is
  not in an ``<exclude>``.

The global switches that turn every contact off (``mjDSBL_CONTACT``, ``mjDSBL_CONSTRAINT``) do not
remove pairs: they stop MuJoCo from resolving contacts, not from being asked where bodies meet, and a
model that lets bodies pass through each other is where continuous detection is wanted most.

Left out: the ``mjcb_contactfilter`` callback (it decides at run time) and sleeping bodies (a run-time
state, ``mjENBL_SLEEP``).  The rules are read when the pairs are chosen: a flag changed later (an
environment that turns contacts on) does not change them.
"""
import warnings
from dataclasses import dataclass

import mujoco
import numpy as np

from mjccd.errors import InputError, InputTypeError
from mjccd.quadric import static_status_code
from mjccd.mujoco.chains import body_path
from mjccd.mujoco.ellipsoids import SUPPORTED, body_label, geom_id, geom_label
from mjccd.mujoco.motions import Kinematics, State
from mjccd.mujoco.warnings import CoverageWarning

PAIR_RULES = ("characters", "self")  # the named rules a ``pairs`` argument may give, besides None and a list

# why MuJoCo does not collide a candidate pair, in the order its collision driver tests them
COLLIDED, WELDED, STATIC, PARENT, BITMASK, EXCLUDED = range(6)
REASONS = {
    WELDED: "on one rigid body (no joint between their bodies)",
    STATIC: "both unable to move (bodies welded to the world, or mocap bodies)",
    PARENT: "on a parent and a child body (MuJoCo's filterparent)",
    BITMASK: "filtered by contype/conaffinity",
    EXCLUDED: "listed in an <exclude>",
}
# geoms no ellipsoid bounds, and what mjccd makes of them
GEOM_KINDS = {int(mujoco.mjtGeom.mjGEOM_PLANE): "plane", int(mujoco.mjtGeom.mjGEOM_HFIELD): "hfield",
              int(mujoco.mjtGeom.mjGEOM_SDF): "sdf"}
_BOUNDABLE = np.array(sorted(int(t) for t in SUPPORTED))
_OTHER_RULES = "pass pairs='characters', pairs='self' or a list of (body, body) pairs to check others"


def _pair_key(a, b):
    return (a, b) if a < b else (b, a)


def excluded_body_pairs(model):
    """Body pairs named in the model's ``<exclude>`` elements, as (low id, high id) tuples."""
    out = set()
    for sig in np.asarray(model.exclude_signature).ravel():
        out.add(_pair_key(int(sig >> 16), int(sig & 0xFFFF)))
    return out


def explicit_geom_pairs(model):
    """Geom pairs named in the model's ``<pair>`` elements, as (low id, high id) tuples."""
    return {_pair_key(int(g1), int(g2)) for g1, g2 in zip(model.pair_geom1, model.pair_geom2)}


def bounded_geoms(model, ellipsoids, body_ids=None):
    """The geoms each ellipsoid stands for in MuJoCo's rules: a list of N int arrays of geom ids.

    An ellipsoid whose ``geoms`` entry names a geom of its own body that takes part in collisions (a nonzero
    contype or conaffinity, or named in a ``<pair>``) stands for that geom alone, as ``fit_model(per="geom")``
    makes them.  Otherwise (an empty entry: the whole body; or a visual-only geom, such as the bounding
    ellipsoids ``mjccd fit`` writes, which ``geom_ellipsoids`` reads back) it stands for every geom of its
    body that an ellipsoid can bound: planes, height fields and SDFs are not in it.
    """
    ids = ellipsoids.body_ids(model) if body_ids is None else np.asarray(body_ids)
    in_pairs = {int(g) for g in np.concatenate([model.pair_geom1, model.pair_geom2])}
    out = []
    for name, body in zip(ellipsoids.geoms, ids):
        g = geom_id(model, name) if name else -1
        if g >= 0 and model.geom_bodyid[g] == body and (
                model.geom_contype[g] or model.geom_conaffinity[g] or g in in_pairs):
            out.append(np.array([g], dtype=np.int64))
            continue
        start, num = model.body_geomadr[body], model.body_geomnum[body]
        geoms = np.arange(start, start + num, dtype=np.int64) if start >= 0 else np.empty(0, np.int64)
        out.append(geoms[np.isin(model.geom_type[geoms], _BOUNDABLE)])
    return out


def collision_reasons(model, b1, b2, contype1, conaffinity1, contype2, conaffinity2):
    """Reason codes (:data:`COLLIDED` or why not) of candidate geom pairs on bodies b1, b2 (arrays) with the
    contype/conaffinity masks given, by MuJoCo's rules (module docstring), less the explicit ``<pair>``
    elements (the caller adds those)."""
    m = model
    weld, dof = m.body_weldid, m.body_dofnum
    w1, w2 = weld[b1], weld[b2]
    reason = np.full(len(b1), COLLIDED, dtype=np.int8)

    def mark(mask, code):
        reason[(reason == COLLIDED) & mask] = code

    mark(w1 == w2, WELDED)
    mark((dof[w1] == 0) & (dof[w2] == 0), STATIC)
    if not m.opt.disableflags & mujoco.mjtDisableBit.mjDSBL_FILTERPARENT:
        parent = weld[m.body_parentid]  # the weld body of each body's parent
        mark((w1 != 0) & (w2 != 0) & ((w1 == parent[w2]) | (w2 == parent[w1])), PARENT)
    mark(((contype1 & conaffinity2) | (contype2 & conaffinity1)) == 0, BITMASK)
    if m.nexclude:
        signature = (np.minimum(b1, b2).astype(np.int64) << 16) + np.maximum(b1, b2)
        mark(np.isin(signature, np.asarray(m.exclude_signature, dtype=np.int64)), EXCLUDED)
    return reason


class _Rules:
    """MuJoCo's collision rules applied to one model's ellipsoids (see the module docstring)."""

    def __init__(self, model, ellipsoids, body_ids=None):
        self.model = model
        self.ids = ellipsoids.body_ids(model) if body_ids is None else np.asarray(body_ids, dtype=np.int64)
        self.geoms = bounded_geoms(model, ellipsoids, self.ids)
        # one geom pair passes the contype/conaffinity test exactly when the ORs over the geoms do
        self.contype = np.array([np.bitwise_or.reduce(model.geom_contype[g]) if len(g) else 0
                                 for g in self.geoms], dtype=np.int64)
        self.conaffinity = np.array([np.bitwise_or.reduce(model.geom_conaffinity[g]) if len(g) else 0
                                     for g in self.geoms], dtype=np.int64)
        self.owners = {}  # geom id -> the ellipsoids standing for it
        for k, g in enumerate(self.geoms):
            for h in g.tolist():
                self.owners.setdefault(h, []).append(k)

    def reasons(self, b1, b2, contype1, conaffinity1, contype2, conaffinity2):
        """Reason codes (:data:`COLLIDED` or why not) of candidate pairs of bodies b1, b2 with the geom masks
        given, less the explicit ``<pair>`` elements (the caller adds those)."""
        return collision_reasons(self.model, b1, b2, contype1, conaffinity1, contype2, conaffinity2)

    def ellipsoid_pairs(self):
        """``(pairs (C, 2), reasons (C,))`` over every two ellipsoids i < j."""
        n = len(self.ids)
        iu, ju = np.triu_indices(n, 1)
        pairs = np.stack([iu, ju], axis=1).astype(np.int64).reshape(-1, 2)
        reason = self.reasons(self.ids[iu], self.ids[ju], self.contype[iu], self.conaffinity[iu],
                              self.contype[ju], self.conaffinity[ju])
        for g1, g2 in explicit_geom_pairs(self.model):
            for i in self.owners.get(g1, ()):
                for j in self.owners.get(g2, ()):
                    if i != j:
                        a, b = _pair_key(i, j)
                        reason[a * n - a * (a + 1) // 2 + b - a - 1] = COLLIDED  # (a, b)'s row in triu order
        return pairs, reason

    def against_geom(self, geom):
        """Reason codes (N,) of the pairs of one geom with each ellipsoid."""
        m, n = self.model, len(self.ids)
        reason = self.reasons(np.full(n, m.geom_bodyid[geom]), self.ids,
                              np.full(n, m.geom_contype[geom]), np.full(n, m.geom_conaffinity[geom]),
                              self.contype, self.conaffinity)
        for g1, g2 in explicit_geom_pairs(m):
            if geom in (g1, g2):
                for i in self.owners.get(g2 if g1 == geom else g1, ()):
                    reason[i] = COLLIDED
        return reason


def _static_poses(model, ellipsoids, ids):
    """(N, 7) world poses of the ellipsoids in the reference pose ``qpos0`` (mocap bodies at their model pose)."""
    mocap = model.body_mocapid >= 0
    state = State(model.qpos0.copy(), model.body_pos[mocap].copy(), model.body_quat[mocap].copy())
    return Kinematics(model).ellipsoid_poses(state, ids, ellipsoids.positions, ellipsoids.quaternions)


def _default(model, ellipsoids, body_ids=None, drop_overlapping_at_qpos0=True, stacklevel=2):
    """``(pairs, why)``: :func:`default_pairs` and, when there are none, a sentence saying why (else None).
    The warning naming dropped pairs points ``stacklevel`` frames up from the caller's line (1: that line)."""
    rules = _Rules(model, ellipsoids, body_ids)
    candidates, reason = rules.ellipsoid_pairs()
    pairs = candidates[reason == COLLIDED]
    collided = len(pairs)
    if drop_overlapping_at_qpos0 and len(pairs):
        poses = _static_poses(model, ellipsoids, rules.ids)
        keep = np.array([static_status_code(ellipsoids.radii[i], poses[i, :3], poses[i, 3:],
                                            ellipsoids.radii[j], poses[j, :3], poses[j, 3:]) == 1 for i, j in pairs],
                        dtype=bool)
        if len(pairs) and not keep.all() and keep.any():  # never silently (none left: the reason below says so)
            names = sorted({tuple(sorted((body_label(model, rules.ids[i]), body_label(model, rules.ids[j]))))
                            for i, j in pairs[~keep].tolist()})
            shown = ", ".join(f"{a}-{b}" for a, b in names[:10]) + (f" and {len(names) - 10} more"
                                                                     if len(names) > 10 else "")
            warnings.warn(f"ellipsoid mode leaves out {len(names)} body pair(s) MuJoCo collides whose ellipsoids "
                          f"already touch or overlap in qpos0 (drop_overlapping_at_qpos0): {shown}; geoms mode "
                          f"(the default with the rigid motion) checks their real geoms", CoverageWarning,
                          stacklevel=stacklevel + 1)
        pairs = pairs[keep]
    if len(pairs):
        return pairs, None
    bodies = list(dict.fromkeys(rules.ids.tolist()))
    if not bodies:
        return pairs, "no pair to check: the ellipsoid set is empty (nothing to bound)"
    if len(bodies) < 2:
        return pairs, f"no pair to check: every ellipsoid is on body {body_label(model, bodies[0])!r}"
    if collided:
        which = "the one pair MuJoCo would collide already touches or overlaps" if collided == 1 else \
            f"the {collided} pairs MuJoCo would collide all touch or overlap already"
        return pairs, (f"no pair to check: {which} in the reference pose qpos0 (drop_overlapping_at_qpos0); "
                       f"{_OTHER_RULES}")
    i, j = candidates.T
    if not np.any((rules.contype[i] & rules.conaffinity[j]) | (rules.contype[j] & rules.conaffinity[i])):
        # whatever else filters them: no two of the geoms could ever touch in MuJoCo
        return pairs, f"no pair to check: every body pair is filtered by contype/conaffinity; {_OTHER_RULES}"
    codes, counts = np.unique(reason, return_counts=True)
    if len(codes) == 1:
        return pairs, f"no pair to check: every pair of ellipsoids is {REASONS[int(codes[0])]}; {_OTHER_RULES}"
    parts = ", ".join(f"{c} are {REASONS[int(code)]}" for code, c in zip(codes, counts))
    return pairs, f"no pair to check: of the {len(reason)} pairs of ellipsoids, {parts}; {_OTHER_RULES}"


def default_pairs(model, ellipsoids, *, drop_overlapping_at_qpos0=True):
    """(P, 2) ellipsoid index pairs worth checking: the pairs MuJoCo itself would collide.

    MuJoCo's rules (module docstring) applied to the geoms each ellipsoid stands for
    (:func:`bounded_geoms`): one geom when the ellipsoid bounds one collision geom, else every geom of
    its body.  A pair is kept when some geom of one and some geom of the other would be collided.
    With ``drop_overlapping_at_qpos0`` the pairs whose ellipsoids already touch or overlap in the
    reference pose ``qpos0`` are dropped too: close neighbours (a hip and the lower back) would
    otherwise report a contact at every step; a :class:`~mjccd.mujoco.warnings.CoverageWarning` names
    them.  Planes are :func:`plane_pairs`.
    """
    return _default(model, ellipsoids, drop_overlapping_at_qpos0=drop_overlapping_at_qpos0, stacklevel=2)[0]


def _static_plane(model, geom):
    return model.geom_type[geom] == mujoco.mjtGeom.mjGEOM_PLANE and model.body_weldid[model.geom_bodyid[geom]] == 0


def plane_pairs(model, ellipsoids):
    """(Q, 2) int64 rows (ellipsoid index, plane geom id): the static planes MuJoCo would collide with the
    geoms each ellipsoid stands for, by the rules of :func:`default_pairs`.

    Static: the plane's body is welded to the world (floors, walls).  MuJoCo allows planes on dof-less
    bodies only, so the others hang from a mocap body: they move, and are not here but in
    :func:`uncovered_geoms`.  Bodies that cannot move never meet a static plane.
    """
    rules = _Rules(model, ellipsoids)
    rows = []
    for p in range(model.ngeom):
        if _static_plane(model, p):
            rows.extend((int(i), p) for i in np.flatnonzero(rules.against_geom(p) == COLLIDED))
    rows.sort()
    return np.array(rows, dtype=np.int64).reshape(-1, 2)


def every_plane_pair(model, ellipsoids, body_ids=None):
    """(Q, 2) int64 rows (ellipsoid index, plane geom id): every static plane against every ellipsoid on a body
    that moves (a joint on its path to the world), contype/conaffinity and ``<exclude>`` not consulted.

    The explicit request beside :func:`plane_pairs`, as :func:`character_pairs` is beside
    :func:`default_pairs`: a replayed character's floor is often a visual geom that MuJoCo never collides.
    """
    ids = ellipsoids.body_ids(model) if body_ids is None else np.asarray(body_ids, dtype=np.int64)
    moving = [i for i, b in enumerate(ids.tolist()) if any(model.body_jntnum[a] > 0 for a in body_path(model, b))]
    rows = [(i, p) for i in moving for p in range(model.ngeom) if _static_plane(model, p)]
    return np.array(rows, dtype=np.int64).reshape(-1, 2)


@dataclass(frozen=True)
class UncoveredGeom:
    """A geom MuJoCo would collide with some of the ellipsoids' geoms, which mjccd cannot check yet.

    Attributes:
        geom: its id; name: its name (``#id`` when unnamed); kind: "hfield", "sdf" or "plane" (a plane
            that moves with a mocap body); body: its body's name.
        ellipsoids: the indices of the ellipsoids whose geoms MuJoCo would collide with it.
        message: one sentence naming the geom, for a warning.
    """

    geom: int
    name: str
    kind: str
    body: str
    ellipsoids: tuple
    message: str


def uncovered_geoms(model, ellipsoids):
    """The geoms MuJoCo would collide with the ellipsoids' geoms that mjccd does not check yet, as a tuple of
    :class:`UncoveredGeom`: height fields, SDF geoms, and planes that move (with a mocap body).

    A geom MuJoCo collides with none of the ellipsoids' geoms (contype/conaffinity, ``<exclude>``, ...) is
    not listed.  :func:`warn_uncovered` warns about each.
    """
    rules = _Rules(model, ellipsoids)
    out = []
    for g in range(model.ngeom):
        kind = GEOM_KINDS.get(int(model.geom_type[g]))
        if kind is None or (kind == "plane" and _static_plane(model, g)):
            continue
        hits = tuple(int(i) for i in np.flatnonzero(rules.against_geom(g) == COLLIDED))
        if not hits:
            continue
        name, body = geom_label(model, g), body_label(model, model.geom_bodyid[g])
        mover = body_label(model, model.body_weldid[model.geom_bodyid[g]])
        what = {"hfield": "height fields are not checked by mjccd yet",
                "sdf": "SDF geoms are not checked by mjccd yet",
                "plane": f"planes that move with a mocap body ({mover!r}) are not checked by mjccd yet, planes "
                         f"welded to the world are"}[kind]
        bodies = list(dict.fromkeys(ellipsoids.bodies[i] for i in hits))
        shown = ", ".join(repr(b) for b in bodies[:5]) + (f", ... ({len(bodies)} in all)" if len(bodies) > 5 else "")
        out.append(UncoveredGeom(g, name, kind, body, hits,
                                 f"geom {name!r} ({kind}): {what}; MuJoCo collides it with {shown}"))
    return tuple(out)


def warn_uncovered(model, ellipsoids, *, stacklevel=2):
    """Warn (:class:`~mjccd.mujoco.warnings.CoverageWarning`, one per geom) about each of
    :func:`uncovered_geoms`; returns them.  ``stacklevel`` as in :func:`warnings.warn` called here: 2 names
    the line that called this function, 3 its caller."""
    found = uncovered_geoms(model, ellipsoids)
    for item in found:
        warnings.warn(item.message, CoverageWarning, stacklevel=stacklevel)
    return found


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


def self_pairs(model, ellipsoids, body_ids=None):
    """(P, 2) pairs of ellipsoids under one top-level body (a character's self-collisions) whose bodies are
    not adjacent: neither one rigid body (the same weld body) nor a parent and a child (weld bodies, as in
    MuJoCo's filterparent, here also below a body welded to the world).

    Contype/conaffinity, ``<exclude>`` and the disable flags are not consulted: this is the explicit request
    for every non-adjacent pair.  ``body_ids``: the ellipsoids' bodies when the caller already has them.
    """
    ids = ellipsoids.body_ids(model) if body_ids is None else np.asarray(body_ids, dtype=np.int64)
    iu, ju = np.triu_indices(len(ids), 1)
    b1, b2 = ids[iu], ids[ju]
    weld = model.body_weldid
    parent = weld[model.body_parentid]  # the weld body of each body's parent
    w1, w2 = weld[b1], weld[b2]
    keep = ((model.body_rootid[b1] == model.body_rootid[b2]) & (w1 != w2)
            & (w1 != parent[w2]) & (w2 != parent[w1]))
    return np.stack([iu[keep], ju[keep]], axis=1).astype(np.int64).reshape(-1, 2)


def _tops(model, ids):
    """The top-level bodies (characters) holding ellipsoids, in order of first appearance."""
    return list(dict.fromkeys(int(t) for t in model.body_rootid[ids]))


def pairs_with_reason(model, ellipsoids, pairs, body_ids=None, field="pairs", *, drop_overlapping_at_qpos0=True,
                      stacklevel=2):
    """``(pairs (P, 2), reason)``: the ellipsoid pairs :func:`select_pairs` picks for ``pairs`` and, when there
    are none, one sentence saying why (``reason`` is None otherwise).  Nothing is warned but the pairs
    :func:`default_pairs` drops because their ellipsoids overlap in qpos0 (with ``drop_overlapping_at_qpos0``;
    the warning points ``stacklevel`` frames up from the caller's line)."""
    if pairs is None:
        return _default(model, ellipsoids, body_ids, drop_overlapping_at_qpos0, stacklevel + 1)
    if isinstance(pairs, str):
        if pairs not in PAIR_RULES:
            raise InputError(f"{field}: expected None, 'characters', 'self' or a list of (body, body) pairs, "
                             f"got {pairs!r}")
        ids = ellipsoids.body_ids(model) if body_ids is None else np.asarray(body_ids, dtype=np.int64)
        tops = _tops(model, ids)
        if pairs == "characters":
            chosen = character_pairs(model, ellipsoids, ids)
            if len(chosen):
                return chosen, None
            if len(tops) == 1:
                return chosen, (f"no pair to check: every ellipsoid is under one top-level body "
                                f"({body_label(model, tops[0])!r}); use pairs='self' for self-collision")
            return chosen, (f"no pair to check: no ellipsoid under the {len(tops)} top-level bodies moves "
                            f"(none has a joint on its way to the world)")
        chosen = self_pairs(model, ellipsoids, ids)
        if len(chosen):
            return chosen, None
        return chosen, ("no pair to check: no two ellipsoids under one top-level body are on bodies that are "
                        "neither one rigid body nor a parent and a child")
    return pairs_from_bodies(model, ellipsoids, pairs, field), None


def select_pairs(model, ellipsoids, pairs, body_ids=None, field="pairs"):
    """The (P, 2) ellipsoid pairs for a ``pairs`` argument: None (:func:`default_pairs`, MuJoCo's rules),
    ``"characters"`` (:func:`character_pairs`), ``"self"`` (:func:`self_pairs`), or a list of (body, body)
    names or ids (:func:`pairs_from_bodies`).

    When a rule leaves no pair, a :class:`~mjccd.mujoco.warnings.CoverageWarning` says why (e.g. "no pair
    to check: every body pair is filtered by contype/conaffinity; ...").
    """
    chosen, reason = pairs_with_reason(model, ellipsoids, pairs, body_ids, field, stacklevel=2)
    if reason is not None:
        warnings.warn(reason, CoverageWarning, stacklevel=2)
    return chosen
