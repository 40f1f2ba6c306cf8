"""Geoms mode: contacts of MuJoCo's own geoms, exact (:mod:`mjccd.geoms`), with their pairs by MuJoCo's rules.

*Which geoms are real.*  A model's collision geoms (a nonzero contype or
conaffinity, or named in a ``<pair>``) when it has any.  In a model where
nothing collides (every geom contype = conaffinity = 0, as the bundled boxing
and arm models, which only show motions) they are its visual geoms: the ones
the bounding ellipsoids were fitted to.  Never the bounds themselves: the
ellipsoids ``mjccd fit`` writes into a model (group 5, visual only) are left
out.

*Shapes.*  Spheres, capsules, cylinders, boxes, ellipsoids and static planes
are solved exactly as they are.  A mesh is checked on the fitted ellipsoids
that bound it (``ellipsoids`` of its body naming it, or the body's own
ellipsoid), with one :class:`~mjccd.mujoco.warnings.CoverageWarning` naming
the meshes; height fields and SDF geoms are not checked (warned about once).

*Motion.*  Each geom moves from its pose at the step start to its pose at the
end by the rigid lerp of its own pose (centre lerp and quaternion lerp), as
each ellipsoid does in ellipsoid mode (:mod:`mjccd.geoms.batch`).

*Pairs.*  With ``pairs=None``, MuJoCo's rules (:func:`mjccd.mujoco.pairs.collision_reasons`) on the real
geoms, each geom pair on its own: nothing is dropped because bounding ellipsoids overlap in the reference
pose.  With ``"characters"``, ``"self"`` or a list of body pairs, the body pairs those name (as for the
ellipsoids, :func:`mjccd.mujoco.pairs.pairs_with_reason`) and every pair of their real geoms, a body standing
for its rigid part: itself and the bodies welded to it (a hand and the finger bodies fixed to it).  Static
planes: by MuJoCo's rules with ``pairs=None``, else every static plane against every geom of a moving body.
"""
import warnings

import mujoco
import numpy as np

from mjccd.geoms import batch as gb
from mjccd.geoms import kernel as kn
from mjccd.geoms import systems as sy
from mjccd.geoms.contact import element_name
from mjccd.geoms.shapes import Box, Capsule, Cylinder, HalfSpace, Sphere
from mjccd.errors import InputError
from mjccd.geoms.solve import geom_collision_intervals, geom_first_contact, workspaces
from mjccd.motion import Rigid, Static
from mjccd.quadric import Ellipsoid
from mjccd.mujoco.chains import body_path
from mjccd.mujoco.ellipsoids import body_report_label, geom_label
from mjccd.mujoco.motions import Kinematics, State, nonfinite_error
from mjccd.mujoco.pairs import COLLIDED, collision_reasons, explicit_geom_pairs, pairs_with_reason
from mjccd.mujoco.reports import COUNTER_NAMES, StepContact, StepCounters, StepReport
from mjccd.mujoco.warnings import CoverageWarning

G = mujoco.mjtGeom
KINDS = {int(G.mjGEOM_SPHERE): sy.SPHERE, int(G.mjGEOM_CAPSULE): sy.CAPSULE, int(G.mjGEOM_CYLINDER): sy.CYLINDER,
         int(G.mjGEOM_BOX): sy.BOX, int(G.mjGEOM_ELLIPSOID): sy.ELLIPSOID, int(G.mjGEOM_PLANE): sy.PLANE}
STATUS = {1: "separate", 0: "touching", -1: "overlapping"}
BOUND_GROUP = 5  # where mjccd fit writes the bounding ellipsoids
TALLY_SLOTS = [COUNTER_NAMES.index(name) for name in gb.TALLIES]  # where each of tally's counts goes
SOLVED_SLOT, UNCERTAIN_SLOT = COUNTER_NAMES.index("solved_exactly"), COUNTER_NAMES.index("uncertain")


def _is_bound(model, g):
    """A fitted bound written into the model: a visual-only ellipsoid in the bounds' group."""
    return (int(model.geom_type[g]) == G.mjGEOM_ELLIPSOID and int(model.geom_group[g]) == BOUND_GROUP
            and not model.geom_contype[g] | model.geom_conaffinity[g])


def real_geoms(model):
    """``(ids, visual)``: the geoms whose contacts geoms mode reports (module docstring) and whether they are
    visual geoms (a model where nothing collides)."""
    in_pairs = {int(g) for g in np.concatenate([model.pair_geom1, model.pair_geom2])}
    ids = [g for g in range(model.ngeom)
           if (model.geom_contype[g] or model.geom_conaffinity[g] or g in in_pairs) and not _is_bound(model, g)]
    if ids:
        return np.array(ids, dtype=np.int64), False
    return np.array([g for g in range(model.ngeom) if not _is_bound(model, g)], dtype=np.int64), True


def _moving(model, body):
    """True when a joint lies on the body's path to the world."""
    return any(model.body_jntnum[b] > 0 for b in body_path(model, body))


class GeomChecker:
    """The real geoms of a model, their pairs, and the exact first contact of a step between them.

    Args:
        model: ``mujoco.MjModel``.
        ellipsoids: an :class:`~mjccd.mujoco.EllipsoidSet` of the model (its meshes are checked on these), or
            None when it has no mesh to check.
        pairs: None (MuJoCo's rules), ``"characters"``, ``"self"`` or a list of (body, body) (module docstring).
        planes: True (the static planes: by MuJoCo's rules with ``pairs=None`` in a model whose geoms collide,
            else every static plane against every geom of a moving body), ``"all"`` (always the latter),
            ``"mujoco"`` (always MuJoCo's rules) or False.
        stacklevel: where the coverage warnings point (as :func:`warnings.warn`, counted from the caller).
    """

    motion = "rigid"  # each geom moves by the rigid lerp of its pose (module docstring)

    def __init__(self, model, ellipsoids=None, pairs=None, *, planes=True, stacklevel=2):
        self.model = model
        if ellipsoids is not None:
            ellipsoids.body_ids(model)  # every ellipsoid on a body of this model (the error names any other)
        self.labels = [body_report_label(model, b) for b in range(model.nbody)]
        real, self.visual = real_geoms(model)
        rows = []  # (geom id, kind, size (3,), local pose (7,), body)
        meshes, skipped = [], []
        for g in real.tolist():
            t = int(model.geom_type[g])
            b = int(model.geom_bodyid[g])
            if t in KINDS:
                size = model.geom_size[g].copy()
                if t == G.mjGEOM_SPHERE:
                    size[1:] = 0.0
                elif t in (G.mjGEOM_CAPSULE, G.mjGEOM_CYLINDER):
                    size[2] = 0.0
                elif t == G.mjGEOM_PLANE:
                    if model.body_weldid[b] != 0:
                        skipped.append(f"{geom_label(model, g)!r} (a plane on a moving body)")
                        continue
                    size[:] = 0.0
                rows.append((g, KINDS[t], size, np.concatenate([model.geom_pos[g], model.geom_quat[g]]), b))
            elif t == G.mjGEOM_MESH and ellipsoids is not None:
                bound = self._mesh_bounds(model, ellipsoids, g)
                if not bound:
                    skipped.append(f"{geom_label(model, g)!r} (a mesh no ellipsoid bounds)")
                meshes.append(geom_label(model, g))
                rows.extend((g, sy.ELLIPSOID, r, pose, b) for r, pose in bound)
            else:
                skipped.append(f"{geom_label(model, g)!r} ({mujoco.mjtGeom(t).name[7:].lower()})")
        if meshes:
            warnings.warn(f"geoms mode checks meshes on their bounding ellipsoids: {', '.join(meshes[:10])}"
                          + (f" and {len(meshes) - 10} more" if len(meshes) > 10 else ""), CoverageWarning,
                          stacklevel=stacklevel + 1)
        if skipped:
            warnings.warn(f"geoms mode cannot check these geoms: {', '.join(skipped[:10])}"
                          + (f" and {len(skipped) - 10} more" if len(skipped) > 10 else ""), CoverageWarning,
                          stacklevel=stacklevel + 1)
        self.geom_ids = np.array([r[0] for r in rows], dtype=np.int64)
        self.kinds = np.array([r[1] for r in rows], dtype=np.int64)
        self.sizes = np.array([r[2] for r in rows], dtype=float).reshape(-1, 3)
        self.local = np.array([r[3] for r in rows], dtype=float).reshape(-1, 7)
        self.body = np.array([r[4] for r in rows], dtype=np.int64)
        self.labels_of_rows = [geom_label(model, g) for g in self.geom_ids]
        self.pairs, self.reason = self._pairs(ellipsoids, pairs, planes)
        self._pair_labels = self._labels_of_pairs()
        self.min_motion = np.zeros(len(self.pairs))  # see set_min_motion
        self.kinematics = Kinematics(model)

    def thickness(self):
        """(G,) how thick each checked geom is: its smallest radius or half size (a cylinder's smaller of radius
        and half length); a plane is 0 (the half-space adds nothing to a pair's thickness)."""
        thin = self.sizes.copy()
        thin[self.kinds == sy.SPHERE, 1:] = np.inf
        rounded = (self.kinds == sy.CAPSULE)
        thin[rounded, 1:] = np.inf
        thin[self.kinds == sy.CYLINDER, 2] = np.inf
        out = thin.min(axis=1)
        out[self.kinds == sy.PLANE] = 0.0
        return out

    def set_min_motion(self, values):
        """Leave out of each step the pairs whose geoms move less than ``values`` (P,) metres relative to each
        other (counted as ``too_slow``): what cannot carry them far into each other is left to MuJoCo's own
        contacts."""
        values = np.asarray(values, dtype=float)
        if values.shape != (len(self.pairs),) or not np.all(np.isfinite(values)) or np.any(values < 0.0):
            raise InputError(f"min_motion: expected {len(self.pairs)} finite values >= 0, got shape {values.shape}")
        self.min_motion = values

    def is_plane(self, row):
        """Whether geom row ``row`` is a static plane."""
        return bool(self.kinds[row] == sy.PLANE)

    @staticmethod
    def _mesh_bounds(model, ellipsoids, g):
        """The fitted ellipsoids that stand for mesh geom g: (radii, pose in its body) of those naming it, else
        those bounding its whole body."""
        b = int(model.geom_bodyid[g])
        ids = ellipsoids.body_ids(model)
        name = geom_label(model, g)
        own = [k for k in range(len(ellipsoids)) if ids[k] == b and ellipsoids.geoms[k] == name]
        if not own:
            own = [k for k in range(len(ellipsoids)) if ids[k] == b and ellipsoids.geoms[k] == ""]
        return [(ellipsoids.radii[k].copy(), np.concatenate([ellipsoids.positions[k], ellipsoids.quaternions[k]]))
                for k in own]

    def _pairs(self, ellipsoids, pairs, planes):
        """((P, 2) row pairs, why none) of the geoms to check, planes last in each pair."""
        m = self.model
        n = len(self.geom_ids)
        is_plane = self.kinds == sy.PLANE
        solid = np.flatnonzero(~is_plane)
        plane_rows = np.flatnonzero(is_plane) if planes else np.empty(0, dtype=np.int64)
        explicit = explicit_geom_pairs(m)
        by_rules = planes == "mujoco" or (planes is True and pairs is None and not self.visual)
        out = []
        why = None
        if pairs is None and not self.visual:
            iu, ju = np.triu_indices(len(solid), 1)
            a, b = solid[iu], solid[ju]
            ga, gb = self.geom_ids[a], self.geom_ids[b]
            reason = collision_reasons(m, self.body[a], self.body[b], m.geom_contype[ga], m.geom_conaffinity[ga],
                                       m.geom_contype[gb], m.geom_conaffinity[gb])
            keep = (reason == COLLIDED) & (self.body[a] != self.body[b])
            for k in range(len(a)):
                if keep[k] or (min(ga[k], gb[k]), max(ga[k], gb[k])) in explicit:
                    out.append((a[k], b[k]))
            for p in plane_rows.tolist() if by_rules else ():
                gp = self.geom_ids[p]
                bodies = np.full(len(solid), self.body[p])
                reason = collision_reasons(m, self.body[solid], bodies, m.geom_contype[self.geom_ids[solid]],
                                           m.geom_conaffinity[self.geom_ids[solid]], np.full(len(solid),
                                           m.geom_contype[gp]), np.full(len(solid), m.geom_conaffinity[gp]))
                for k, e in enumerate(solid.tolist()):
                    if reason[k] == COLLIDED or (min(gp, self.geom_ids[e]), max(gp, self.geom_ids[e])) in explicit:
                        out.append((e, p))
            if not by_rules:
                for p in plane_rows.tolist():
                    out.extend((e, p) for e in solid.tolist() if _moving(m, int(self.body[e])))
            if not out:
                why = "no pair to check: MuJoCo's rules collide no two of the model's geoms"
        else:
            if ellipsoids is None:
                raise ValueError("ellipsoids: needed to read the body pairs of a pairs argument")
            chosen, why = pairs_with_reason(m, ellipsoids, pairs, drop_overlapping_at_qpos0=False)
            # a moving body stands for its rigid part, the bodies welded to it (a hand and the fingers fixed to
            # it: one bound may cover them all); a static body for itself (every static body is welded to the world)
            part = np.where(m.body_weldid != 0, m.body_weldid, np.arange(m.nbody))
            weld = part[ellipsoids.body_ids(m)]
            groups = {(min(int(weld[i]), int(weld[j])), max(int(weld[i]), int(weld[j]))) for i, j in chosen.tolist()}
            of = part[self.body]
            for a in solid.tolist():
                for b in solid.tolist():
                    if a < b and of[a] != of[b] and (min(of[a], of[b]), max(of[a], of[b])) in groups:
                        out.append((a, b))
            for p in plane_rows.tolist():
                if by_rules:
                    gp = self.geom_ids[p]
                    es = [e for e in solid.tolist() if collision_reasons(
                        m, self.body[e:e + 1], self.body[p:p + 1], m.geom_contype[self.geom_ids[e:e + 1]],
                        m.geom_conaffinity[self.geom_ids[e:e + 1]], m.geom_contype[[gp]],
                        m.geom_conaffinity[[gp]])[0] == COLLIDED]
                else:
                    es = [e for e in solid.tolist() if _moving(m, int(self.body[e]))]
                out.extend((e, p) for e in es)
            if out:
                why = None
        return np.array(out, dtype=np.int64).reshape(-1, 2), why

    # ------------------------------------------------------------ checks

    def geom_poses(self, state):
        """(G, 7) world poses [x, y, z, qw, qx, qy, qz] of the checked geoms in ``state``."""
        xpos, xquat = self.kinematics.body_poses(state)
        out = np.empty((len(self.geom_ids), 7))
        gb.geom_poses_into(xpos, xquat, self.body, self.local, out)
        return out

    def qpos_poses(self, qpos):
        """(F, G, 7) geom poses of qpos rows (F, nq), mocap bodies at the model's own poses."""
        m = self.model
        mocap = m.body_mocapid >= 0
        mpos, mquat = m.body_pos[mocap], m.body_quat[mocap]
        out = np.empty((len(qpos), len(self.geom_ids), 7))
        for k, q in enumerate(qpos):
            out[k] = self.geom_poses(State(q, mpos, mquat))
        return out

    def check(self, s0, s1, *, poses=None, all_pairs=False, new_only=False, names=("state_t0", "state_t1")):
        """The :class:`~mjccd.mujoco.StepReport` of the step from :class:`~mjccd.mujoco.State` s0 to s1 (every
        contact with ``all_pairs``, else the first; ``new_only``: pairs not separate at the start left out;
        ``poses``: the geom poses (G, 7) of both states when the caller has them (:meth:`qpos_poses`);
        ``names``: the two states as the caller knows them, for errors)."""
        q0, q1 = (self.geom_poses(s0), self.geom_poses(s1)) if poses is None else poses
        self.check_finite((s0, s1), (q0, q1), names)
        return self.check_poses(s0.time, s1.time, q0, q1, all_pairs=all_pairs, new_only=new_only)

    def check_finite(self, states, poses, names):
        """Raise an InputError in the user's terms (the state's NaN or infinite value, else the geom) when some
        of ``poses`` (one (G, 7) array per state; ``names``: the states as the caller knows them) is not
        finite."""
        for state, q, name in zip(states, poses, names):
            if not np.isfinite(q).all():
                error = nonfinite_error(state, name)
                if error is not None:
                    raise error
                g = self.geom_ids[np.flatnonzero(~np.isfinite(q).all(axis=1))[0]]
                raise InputError(f"{name}: the pose of geom {geom_label(self.model, g)!r} is not finite "
                                 f"(largest |qpos| {np.abs(state.qpos).max():.3g})")

    def pair_problem(self, k, Q0, Q1):
        """(shape_a, motion_a, shape_b, motion_b) of pair k in the step from geom poses Q0 to Q1: the arguments
        of :func:`mjccd.geoms.geom_first_contact` that answer it with no filter in between."""
        a, b = self.pairs[k]
        return self._shape(a), self._motion(a, Q0, Q1), self._shape(b), self._motion(b, Q0, Q1)

    def pair_intervals(self, k, Q0, Q1):
        """Every (t_in, t_out) fraction of the step in which pair k touches or overlaps (its geoms' poses Q0 and
        Q1 at both ends)."""
        return geom_collision_intervals(*self.pair_problem(k, Q0, Q1))[0]

    def check_poses(self, t0, t1, Q0, Q1, *, all_pairs=False, new_only=False):
        """As :meth:`check`, from the geom poses (G, 7) at both ends of a step from time t0 to t1."""
        npairs = len(self.pairs)
        if npairs == 0:
            return StepReport(None, (), 0, 0, 0, False, StepCounters([0] * len(COUNTER_NAMES)))
        out = np.empty((npairs, kn.OUT))
        gb.step_pairs(self.kinds, self.sizes, Q0, Q1, self.pairs, self.min_motion, 1.0, bool(all_pairs),
                      bool(new_only), *workspaces(), out)
        if all_pairs:
            return self.report_of_rows(t0, t1, Q0, Q1, out, True, new_only)
        tallies = np.empty(len(gb.TALLIES), dtype=np.int64)
        return self.first_report(t0, t1, Q0, Q1, out, gb.tally(out, bool(new_only), tallies), tallies, new_only)

    def first_report(self, t0, t1, Q0, Q1, out, first, tallies, new_only):
        """The first-contact :class:`StepReport` of a step from time t0 to t1 (geom poses Q0, Q1) from
        :func:`~mjccd.geoms.batch.step_pairs`' rows ``out`` and :func:`~mjccd.geoms.batch.tally`'s ``first`` and
        ``tallies``: read off the tallies, or row by row when a pair is left to the ellipsoid solver."""
        if first == gb.NEEDS_SOLVER:
            return self.report_of_rows(t0, t1, Q0, Q1, out, False, new_only)
        return self._tallied_report(t0, t1, out, first, tallies)

    def _tallied_report(self, t0, t1, out, first, tallies):
        """:meth:`first_report` when the kernel answered every row."""
        counts = [0] * len(COUNTER_NAMES)
        counts[0] = len(out)  # pairs
        for slot, value in zip(TALLY_SLOTS, tallies.tolist()):
            counts[slot] = value
        contact = None
        if first >= 0:
            contact = self._contact(t0, t1, first, *self._kernel_contact(first, out[first]))
        return StepReport(contact, (), counts[0], counts[SOLVED_SLOT], counts[UNCERTAIN_SLOT], False,
                          StepCounters(counts))

    def report_of_rows(self, t0, t1, Q0, Q1, out, all_pairs, new_only):
        """The :class:`StepReport` of :func:`~mjccd.geoms.batch.step_pairs`' answers ``out``, row by row (pairs
        the kernel leaves to the ellipsoid solver solved here)."""
        npairs = len(out)
        found = []
        counts = dict.fromkeys(COUNTER_NAMES, 0)
        counts["pairs"] = npairs
        failed = out[:, kn.FAILED]
        solved = np.flatnonzero((failed != gb.FILTERED) & (failed != gb.TOO_SLOW))
        counts["sphere_culled"] = int(np.count_nonzero(failed == gb.FILTERED))
        counts["too_slow"] = int(np.count_nonzero(failed == gb.TOO_SLOW))
        for k in solved.tolist():
            o = out[k]
            failed = o[kn.FAILED]
            counts["solved_exactly"] += 1
            if failed == kn.NOT_HANDLED or failed == kn.PARTIAL:
                c = self._solve_other(k, Q0, Q1)
            else:
                c = self._kernel_contact(k, o)
            if c is None:
                continue
            status, frac, point, normal, certain, bracket, elements = c
            if status != "separate":
                counts["overlapping_t0"] += 1
                if new_only:
                    continue
            counts["colliding"] += 1
            counts["uncertain"] += not certain
            found.append((frac, k, status, point, normal, certain, bracket, elements))
        found.sort(key=lambda f: f[:2])  # by time, then pair: the first of equal ones first
        # a StepContact costs more than the check of a small model's step: only those reported are made
        contacts = [self._contact(t0, t1, k, status, frac, point, normal, certain, bracket, elements)
                    for frac, k, status, point, normal, certain, bracket, elements in found[:None if all_pairs else 1]]
        first = contacts[0] if contacts else None
        return StepReport(first, tuple(contacts) if all_pairs else (), counts["pairs"], counts["solved_exactly"],
                          counts["uncertain"], False, StepCounters([counts[name] for name in COUNTER_NAMES]))

    def _kernel_contact(self, k, o):
        """(status, fraction, point, normal, certain, bracket, elements) of pair k's kernel answer, or None."""
        status = STATUS[int(o[kn.STATUS])]
        if status != "separate":
            return status, 0.0, None, None, True, None, None
        if o[kn.LO] < 0.0:
            return None
        a, b = self.pairs[k]
        elements = (element_name(int(self.kinds[a]), int(o[kn.ELEM_A])),
                    element_name(int(self.kinds[b]), int(o[kn.ELEM_B])))
        point, normal = o[kn.POINT:kn.POINT + 3].copy(), o[kn.NORMAL:kn.NORMAL + 3].copy()
        if o[kn.CERTIFIED] > 0.0:
            return status, float(o[kn.TIME]), point, normal, True, None, elements
        return status, float(o[kn.LO]), point, normal, False, (float(o[kn.LO]), float(o[kn.HI])), elements

    def _shape(self, e):
        kind, size = int(self.kinds[e]), self.sizes[e]
        if kind == sy.SPHERE:
            return Sphere(size[0])
        if kind in (sy.CAPSULE, sy.CYLINDER):
            return (Capsule if kind == sy.CAPSULE else Cylinder)(size[0], size[1])
        if kind == sy.BOX:
            return Box(size)
        if kind == sy.ELLIPSOID:
            return Ellipsoid(size)
        return HalfSpace()

    def _motion(self, e, Q0, Q1):
        """The exact motion of row e: the lerp of its pose (a plane stays put)."""
        if self.kinds[e] == sy.PLANE:
            return Static(Q0[e, :3], Q0[e, 3:])
        return Rigid(Q0[e, :3], Q0[e, 3:], Q1[e, :3], Q1[e, 3:])

    def _solve_other(self, k, Q0, Q1):
        """Pair k through :func:`mjccd.geoms.geom_first_contact` (pairs the ellipsoid solver answers)."""
        c = geom_first_contact(*self.pair_problem(k, Q0, Q1))
        if c is None:
            return None
        if c.status_at_start != "separate":
            return c.status_at_start, 0.0, None, None, True, None, None
        certain = c.certainty == "certified"
        return ("separate", float(c.time), c.point, c.normal, certain, None if certain else c.bracket, c.elements)

    def _contact(self, t0, t1, k, status, frac, point, normal, certain, bracket, elements):
        bodies, body_ids, plane, geoms = self._pair_labels[k]
        dt = (t1 - t0) if t0 is not None and t1 is not None and t1 > t0 else self.model.opt.timestep
        start = t0 if t0 is not None else 0.0
        seconds = None if bracket is None else (start + bracket[0] * dt, start + bracket[1] * dt)
        return StepContact(start + frac * dt, frac, bodies, body_ids, (-1, -1), point, normal, status,
                           "certified" if certain else "uncertain", seconds, k, plane, geoms, elements)

    def _labels_of_pairs(self):
        """Per pair: (body names, body ids, plane geom or -1, geom ids), as its contacts name them."""
        out = []
        for a, b in self.pairs.tolist():
            ga, gb_ = int(self.geom_ids[a]), int(self.geom_ids[b])
            ba, bb = int(self.body[a]), int(self.body[b])
            out.append(((self.labels[ba], self.labels[bb]), (ba, bb), gb_ if self.kinds[b] == sy.PLANE else -1,
                        (ga, gb_)))
        return out
