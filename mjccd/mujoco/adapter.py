"""The one binding of a MuJoCo model to the CCD core: ellipsoid poses of states, motions, pairs, the checks.

:class:`ModelAdapter` is what the monitor, guarded stepping, replay, :mod:`mjccd.testing` and the
environment wrappers all use to ask "what touches between these two states".  It owns the fitted
:class:`~mjccd.mujoco.EllipsoidSet` bound to the model's bodies, forward kinematics on a private
``MjData`` (:class:`~mjccd.mujoco.Kinematics`), the pairs (:mod:`mjccd.mujoco.pairs`), and the
checker of the motion model:

* ``rigid`` and ``affine``: a :class:`mjccd.scene.Scene` fed the ellipsoid poses at both ends;
* ``chain``: the joints of each ellipsoid's kinematic chain (:class:`~mjccd.mujoco.chains.ChainLayout`),
  pairs decided by the chain filters (:class:`mjccd.chain_bounds.ChainFilter`) and, when they cannot,
  by the exact solver on each ellipsoid's :class:`mjccd.Chain`.

Answers come back as :class:`StepReport` and :class:`StepContact` in simulation time and body names.
"""
import math
import pathlib
import sys
from dataclasses import astuple
from functools import cached_property

import mujoco
import numpy as np

from mjccd import chain_bounds as cb
from mjccd.ccd import first_contact
from mjccd.errors import InputError, InputTypeError
from mjccd.filters import EPS
from mjccd.motion import Affine, Rigid
from mjccd.plane import Plane, plane_first_contact
from mjccd.quadric import Ellipsoid, static_status_code
from mjccd.settle import estimated_touch
from mjccd.scene import OVERLAP_T0, Scene, first_of
from mjccd.mujoco.chains import ChainLayout
from mjccd.mujoco.ellipsoids import EllipsoidSet, body_report_label
from mjccd.mujoco.motions import (MIN_NORM2, MOTIONS, Kinematics, State, as_state, has_zero_quaternion,
                                  nonfinite_error, quaternion_addresses, zero_quaternion_error)
from mjccd.mujoco.reports import (COUNTER_NAMES, UNSTABLE_REPORT, StepContact, StepCounters,  # noqa: F401
                                   StepReport)
from mjccd.mujoco.warnings import mujoco_warnings

STATUS = {1: "separate", 0: "touching", -1: "overlapping"}


def plane_clearance(radii, pose, plane):
    """How far an ellipsoid at ``pose`` ([x, y, z, qw, qx, qy, qz], unit quaternion) lies above ``plane``
    ([n, offset]): the centre's height less the ellipsoid's support along n (negative: it reaches below)."""
    x, y, z, w, qx, qy, qz = pose.tolist()
    nx, ny, nz, offset = plane.tolist()
    ux, uy, uz = -qx, -qy, -qz  # the normal in the ellipsoid's frame: turned by the conjugate quaternion
    tx, ty, tz = 2.0 * (uy * nz - uz * ny), 2.0 * (uz * nx - ux * nz), 2.0 * (ux * ny - uy * nx)
    lx, ly, lz = nx + w * tx + (uy * tz - uz * ty), ny + w * ty + (uz * tx - ux * tz), nz + w * tz + (ux * ty - uy * tx)
    a, b, c = radii.tolist()
    height = nx * x + ny * y + nz * z - offset
    support = math.sqrt((a * lx) ** 2 + (b * ly) ** 2 + (c * lz) ** 2)
    # within rounding of tangent counts as tangent (the exact solver's "touching or undecided" at the start)
    if abs(height - support) <= 64.0 * EPS * (abs(x) + abs(y) + abs(z) + abs(offset) + support):
        return 0.0
    return height - support


def load_model(source, *, field="model"):
    """An ``MjModel`` from a model, an MJCF path or an MJCF string; errors name the file (or ``field``).

    MuJoCo's compiler warnings go to stderr, each after the file's name.
    """
    if isinstance(source, mujoco.MjModel):
        return source
    if not isinstance(source, (str, pathlib.PurePath)):
        raise InputTypeError(f"{field}: expected an MjModel, an MJCF path or an MJCF string, "
                             f"got {type(source).__name__}")
    text = str(source)
    is_xml = isinstance(source, str) and text.lstrip().startswith("<")
    name = "the MJCF string" if is_xml else text
    if not is_xml:
        path = pathlib.Path(text)
        if path.is_dir():
            raise InputError(f"{text}: is a folder, expected an MJCF model file")
        if not path.is_file():
            raise InputError(f"{text}: model file not found")
    with mujoco_warnings() as warned:
        try:
            model = mujoco.MjModel.from_xml_string(text) if is_xml else mujoco.MjModel.from_xml_path(text)
        except ValueError as exc:
            message = " ".join(line.strip() for line in str(exc).splitlines() if line.strip()) or "cannot compile"
            raise InputError(f"{name}: not a valid MJCF model: {message}") from None
    for message in warned:
        print(f"{name}: MuJoCo warning: {message}", file=sys.stderr)
    return model


def checked_pairs(pairs, n, field="pairs"):
    """(P, 2) int64 ellipsoid index pairs, each two distinct indices in 0..n-1; errors name ``field``."""
    arr = np.asarray(pairs)
    if arr.size == 0:
        return np.empty((0, 2), dtype=np.int64)
    if arr.ndim != 2 or arr.shape[1] != 2 or arr.dtype.kind not in "iu":
        raise InputError(f"{field}: expected P rows of 2 ellipsoid indices, got {arr.tolist()!r:.80}")
    arr = arr.astype(np.int64)
    if arr.min() < 0 or arr.max() >= n or np.any(arr[:, 0] == arr[:, 1]):
        raise InputError(f"{field}: indices must be distinct and within 0..{n - 1}")
    return np.ascontiguousarray(arr)


def motions_between(model, ellipsoids, state0, state1, motion="rigid"):
    """One mjccd motion per ellipsoid from state0 (t = 0) to state1 (t = 1).

    Args:
        model: ``mujoco.MjModel``.
        ellipsoids: :class:`~mjccd.mujoco.EllipsoidSet`.
        state0, state1: ``MjData``, :class:`State` or qpos vectors.
        motion: "rigid" (per-ellipsoid pose lerp), "affine" (centre and shape
            matrix lerp) or "chain" (joint-space interpolation down the tree, see
            :mod:`mjccd.mujoco.chains`).
    """
    checker = ModelAdapter(model, ellipsoids, (), motion)
    return checker.motions(as_state(model, state0, "state_t0"), as_state(model, state1, "state_t1"))


def _report(first, contacts, counts):
    """A :class:`StepReport` of a rigid or affine check: ``counts`` in :class:`mjccd.scene.FrameCounters`' order,
    read by name."""
    counters = StepCounters(counts)
    return StepReport(first, contacts, counters["pairs"], counters["solved_exactly"], counters["uncertain"], False,
                      counters)


class ModelAdapter:
    """A model, its fitted ellipsoids and the pairs to check, bound to the CCD core for one motion model.

    Args:
        model: ``mujoco.MjModel``.
        ellipsoids: :class:`EllipsoidSet` (its bodies are looked up in the model).
        pairs: (P, 2) ellipsoid index pairs (:func:`mjccd.mujoco.pairs.select_pairs` makes them).
        motion: "rigid", "affine" or "chain".
        plane_pairs: (Q, 2) rows (ellipsoid index, plane geom id) of static planes
            (:func:`mjccd.mujoco.pairs.plane_pairs` makes them); None: none.
        chain_filters: with the chain motion, decide pairs with the chain filters first (False:
            every pair goes to the exact solver; the filters never change an answer).
    """

    def __init__(self, model, ellipsoids, pairs, motion="rigid", *, chain_filters=True, plane_pairs=None):
        if not isinstance(ellipsoids, EllipsoidSet):
            raise InputTypeError(f"ellipsoids: expected an EllipsoidSet, got {type(ellipsoids).__name__}")
        if not isinstance(motion, str) or motion not in MOTIONS:
            raise InputError(f"motion: expected one of {', '.join(MOTIONS)}, got {motion!r}")
        self.model, self.ellipsoids, self.motion = model, ellipsoids, motion
        self.body_ids = ellipsoids.body_ids(model)
        self.pairs = checked_pairs(pairs, len(ellipsoids))
        self.labels = [body_report_label(model, b) for b in range(model.nbody)]
        self.kinematics = Kinematics(model)
        self.radii = ellipsoids.radii
        self.plane_pairs, self.planes, plane_rows = self._static_planes(plane_pairs)
        self.scene = Scene(self.radii, pairs=self.pairs, motion=motion, planes=self.planes if len(plane_rows) else None,
                           plane_pairs=plane_rows if len(plane_rows) else None) \
            if motion != "chain" and (len(self.pairs) or len(plane_rows)) else None
        self._plane_rows = plane_rows
        self.chain_filter = cb.ChainFilter(self.chains.program, self.radii, self.pairs) \
            if motion == "chain" and chain_filters and (len(self.pairs) or len(plane_rows)) else None
        self._cached = None  # (state, poses) of the last end state
        # the scene's per-pair answers and outcome counters of its last check (its own buffers, read after each)
        self._answers = self.scene.workspace.arrays if self.scene is not None else None
        self._counters = self._answers.counters if self.scene is not None else None
        # per pair index (pairs, then plane pairs): (body labels, body ids, ellipsoids, plane geom) of its contacts
        self._contact_parts = [self._parts_of(k) for k in range(len(self.pairs) + len(self.plane_pairs))]

    def _static_planes(self, plane_pairs):
        """``(plane_pairs (Q, 2) (ellipsoid, geom), planes (K, 4) [n, offset], rows (Q, 2) (ellipsoid, plane))``
        of static plane geoms: each plane's world normal (its geom's z axis) and offset, from the model's
        reference pose (a static body never moves)."""
        m = self.model
        rows = np.zeros((0, 2), dtype=np.int64) if plane_pairs is None else np.asarray(plane_pairs, dtype=np.int64)
        if rows.ndim != 2 or rows.shape[1] != 2:
            raise InputError(f"plane_pairs: expected Q rows (ellipsoid index, plane geom id), got shape {rows.shape}")
        for k, (e, g) in enumerate(rows.tolist()):
            if not (0 <= e < len(self.ellipsoids) and 0 <= g < m.ngeom
                    and m.geom_type[g] == mujoco.mjtGeom.mjGEOM_PLANE and m.body_weldid[m.geom_bodyid[g]] == 0):
                raise InputError(f"plane_pairs[{k}]: expected (ellipsoid index, id of a plane geom of a static "
                                 f"body), got {(e, g)}")
        geoms = sorted(set(rows[:, 1].tolist()))
        d = mujoco.MjData(m)
        mujoco.mj_kinematics(m, d)
        planes = np.empty((len(geoms), 4))
        for k, g in enumerate(geoms):
            normal = d.geom_xmat[g].reshape(3, 3)[:, 2]
            planes[k] = (*normal, normal @ d.geom_xpos[g])
        index = {g: k for k, g in enumerate(geoms)}
        scene_rows = np.array([(e, index[g]) for e, g in rows.tolist()], dtype=np.int64).reshape(-1, 2)
        return rows, planes, scene_rows

    def _parts_of(self, k):
        """(body labels, body ids, ellipsoids, plane geom or -1) of pair index k, as its contacts report them."""
        if k < len(self.pairs):
            i, j, g = int(self.pairs[k, 0]), int(self.pairs[k, 1]), -1
            a, b = int(self.body_ids[i]), int(self.body_ids[j])
        else:
            i, g = (int(x) for x in self.plane_pairs[k - len(self.pairs)])
            j, a, b = -1, int(self.body_ids[i]), int(self.model.geom_bodyid[g])
        return (self.labels[a], self.labels[b]), (a, b), (i, j), g

    @cached_property
    def chains(self):
        """The :class:`~mjccd.mujoco.chains.ChainLayout` of the ellipsoids (built on first use)."""
        e = self.ellipsoids
        return ChainLayout(self.model, self.body_ids, e.positions, e.quaternions)

    @cached_property
    def _shapes(self):
        return [Ellipsoid(r) for r in self.radii]

    @cached_property
    def _quaternions(self):
        """The qpos addresses of the model's free and ball joint quaternions (read once)."""
        return quaternion_addresses(self.model)

    def motions(self, s0, s1):
        """One exact motion per ellipsoid from :class:`State` s0 (t = 0) to s1 (t = 1), of the adapter's model."""
        if self.motion == "chain":
            return self.chain_motions(s0, s1)
        e0, e1 = self.poses(s0), self.poses(s1)
        return [self._pose_motion(a, b) for a, b in zip(e0, e1)]

    def _pose_motion(self, pose0, pose1):
        """The scene's motion (rigid or affine) of an ellipsoid from pose0 to pose1 ([x, y, z, qw, qx, qy, qz])."""
        return (Rigid if self.motion == "rigid" else Affine)(pose0[:3], pose0[3:], pose1[:3], pose1[3:])

    def chain_motions(self, s0, s1):
        """The exact chain motion (:class:`mjccd.Chain`) of every ellipsoid from :class:`State` s0 to s1."""
        chains = self.chains
        v0, v1 = chains.values(s0), chains.values(s1)
        chains.check_turns(v0, v1)
        return [chains.motion(e, v0, v1) for e in range(len(self.body_ids))]

    # ------------------------------------------------------------ poses

    def poses(self, state):
        """(N, 7) world poses [x, y, z, qw, qx, qy, qz] of the ellipsoids in ``state`` (a :class:`State`)."""
        c = self._cached
        if c is not None and c[0].time == state.time and np.array_equal(c[0].qpos, state.qpos) \
                and np.array_equal(c[0].mocap_pos, state.mocap_pos) \
                and np.array_equal(c[0].mocap_quat, state.mocap_quat):
            return c[1]
        return self.kinematics.ellipsoid_poses(state, self.body_ids, self.ellipsoids.positions,
                                               self.ellipsoids.quaternions)

    def qpos_poses(self, qpos):
        """(F, N, 7) ellipsoid poses of qpos rows (F, nq), mocap bodies at the model's own poses."""
        mocap = self.model.body_mocapid >= 0
        mpos, mquat = self.model.body_pos[mocap], self.model.body_quat[mocap]
        return np.stack([self.kinematics.ellipsoid_poses(State(q, mpos, mquat), self.body_ids,
                                                         self.ellipsoids.positions, self.ellipsoids.quaternions)
                         for q in qpos]) if len(qpos) else np.empty((0, len(self.body_ids), 7))

    def forget(self):
        """Drop the remembered end state (after a jump: MuJoCo's reset of a bad state)."""
        self._cached = None

    # ------------------------------------------------------------ checks

    def check(self, s0, s1, *, poses=None, all_pairs=False, new_only=False, names=("state_t0", "state_t1")):
        """The :class:`StepReport` of the motion from :class:`State` s0 (t = 0) to s1 (t = 1).

        ``poses``: the ellipsoid poses (N, 7) of both states when the caller has them (:meth:`qpos_poses`);
        ``all_pairs``: every colliding pair in ``contacts`` (else only the first contact);
        ``new_only``: pairs touching or overlapping at the start are left out; ``names``: the two
        states as the caller knows them, for errors.
        """
        if len(self.pairs) == 0 and len(self._plane_rows) == 0:
            return StepReport(None, (), 0, 0, 0, False, StepCounters([0] * len(COUNTER_NAMES)))
        if poses is None:
            poses = (self.poses(s0), self.kinematics.ellipsoid_poses(s1, self.body_ids, self.ellipsoids.positions,
                                                                     self.ellipsoids.quaternions))
        check = self._check_scene if self.scene is not None else self._check_chain
        report = check(s0, s1, poses, names, all_pairs, new_only)
        self._cached = (s1, poses[1])
        return report

    def contact(self, t0, t1, k, fraction, point, normal, poses0, bracket=None, status=None):
        """The :class:`StepContact` of pair ``k`` at ``fraction`` of a step from time ``t0`` to ``t1``.

        ``poses0``: the ellipsoid poses at the step start.  ``bracket``: (lo, hi) step fractions of an
        uncertain answer (None: certified).  ``status``: the status at the step start when the caller
        knows it; else separate when there is a point or an uncertain contact after the start, and the
        static status of the start poses otherwise.
        """
        k = int(k)
        bodies, body_ids, ellipsoids, geom = self._contact_parts[k]
        if status is None:
            if point is None and (bracket is None or bracket[1] == 0.0):
                status = self._start_status(k, poses0)
            else:
                status = "separate"
        seconds = None if bracket is None else (float(self._seconds(t0, t1, bracket[0])),
                                                float(self._seconds(t0, t1, bracket[1])))
        return StepContact(float(self._seconds(t0, t1, fraction)), float(fraction), bodies, body_ids, ellipsoids,
                           None if point is None else np.array(point, float),
                           None if normal is None else np.array(normal, float), status,
                           "certified" if bracket is None else "uncertain", seconds, k, geom)

    def _start_status(self, k, poses0):
        """The static status at the step start of pair ``k``, which is in contact then: "touching" or
        "overlapping" (a pair of ellipsoids whose status comes out separate touches within the solver's
        precision)."""
        if k >= len(self.pairs):
            row = k - len(self.pairs)
            i = int(self.plane_pairs[row, 0])
            plane = self.planes[int(self._plane_rows[row, 1])]
            return "touching" if plane_clearance(self.radii[i], poses0[i], plane) >= 0.0 else "overlapping"
        i, j = int(self.pairs[k, 0]), int(self.pairs[k, 1])
        r = self.radii
        status = STATUS[static_status_code(r[i], poses0[i, :3], poses0[i, 3:], r[j], poses0[j, :3], poses0[j, 3:])]
        return "touching" if status == "separate" else status

    def _seconds(self, t0, t1, fraction):
        """Simulation time at ``fraction`` of a step from ``t0`` to ``t1`` (either None: unknown)."""
        if t0 is not None and t1 is not None and t1 > t0:
            return t0 + fraction * (t1 - t0)
        return (t0 if t0 is not None else 0.0) + fraction * self.model.opt.timestep

    def _pose_error(self, state, poses, name):
        """The :class:`~mjccd.errors.InputError` for ellipsoid poses that are not all finite, in the user's terms.

        ``name`` is the state as the caller knows it ("state_t1", "data after step 2 of 5").
        """
        error = nonfinite_error(state, name)
        if error is not None:
            return error
        k = int(np.flatnonzero(~np.isfinite(poses).all(axis=1))[0])
        return InputError(f"{name}: the pose of ellipsoid {k} (body {self.labels[self.body_ids[k]]!r}) is not "
                          f"finite (largest |qpos| {np.abs(state.qpos).max():.3g})")

    def check_finite(self, states, poses, names):
        """Raise the InputError of :meth:`_pose_error` when some of ``poses`` (one per state) is not finite."""
        for state, p, name in zip(states, poses, names):
            if not np.isfinite(p).all():
                raise self._pose_error(state, p, name) from None

    def _check_scene(self, s0, s1, poses, names, all_pairs, new_only):
        """Rigid and affine motions: the batched :class:`mjccd.scene.Scene` pipeline."""
        p0, p1 = poses
        try:
            return self.check_poses(s0.time, s1.time, p0, p1, all_pairs=all_pairs, new_only=new_only)
        except InputError:  # the scene names its own arguments: name the state instead
            self.check_finite((s0, s1), (p0, p1), names)
            raise

    def check_poses(self, t0, t1, p0, p1, *, all_pairs=False, new_only=False):
        """The :class:`StepReport` of the rigid or affine motion between ellipsoid poses p0 and p1 ((N, 7),
        e.g. :attr:`~mjccd.mujoco.monitor.StepCheck.poses`) of a step from time ``t0`` to ``t1``: what
        :meth:`check` answers for the two states, for callers that hold the poses (the monitor's steps).
        ``all_pairs``, ``new_only`` as in :meth:`check`; a bad pose raises the scene's InputError."""
        scene = self.scene
        if not all_pairs:
            return self.scene_report(t0, t1, scene.first_pair(p0, p1, new_contacts_only=new_only), p0, p1, new_only)
        frame = scene.step(p0, p1, all_pairs=True, new_contacts_only=new_only)  # its uncertain pairs settled
        contacts = [self._converted(t0, t1, c, p0) for c in frame.contacts]
        contacts.sort(key=lambda c: c.fraction)
        return _report(contacts[0] if contacts else None, tuple(contacts), list(astuple(frame.counters)))

    def scene_report(self, t0, t1, best_k, p0, p1, new_only=False):
        """The :class:`StepReport` of the scene's last first-contact check (of a step from time ``t0`` to ``t1``
        from ellipsoid poses ``p0`` to ``p1``), read off its workspace: ``best_k`` is the first pair (-1: none),
        as :meth:`mjccd.scene.Scene.first_pair` and :func:`~mjccd.mujoco.motions.poses_then_first` answer.  A
        first contact the scene could not decide sends the step through every pair (:meth:`check_poses`), its
        uncertain answers to the core's exact tiers."""
        first = None
        if best_k >= 0:
            a = self._answers
            if a.outcome[best_k] == OVERLAP_T0:  # in contact at t = 0: touching or overlapping, by its start poses
                first = self.contact(t0, t1, best_k, 0.0, None, None, p0)
            else:
                first = self._converted(t0, t1, first_of(best_k, a.outcome, a.times, a.times_hi, a.points,
                                                         a.normals), p0)
            if first.certainty != "certified":
                report = self.check_poses(t0, t1, p0, p1, all_pairs=True, new_only=new_only)
                return StepReport(report.first, (), report.pairs_checked, report.pairs_solved, report.pairs_uncertain,
                                  False, report.counters)
        return _report(first, (), self._counters.tolist())

    def _converted(self, t0, t1, hit, p0):
        """The :class:`StepContact` of a scene contact (``FirstContact``, ``PairContact`` or ``PlaneContact``) of
        the scene's last check: a pair in contact at t = 0 (its outcome OVERLAP_T0: overlapping by the scene's
        static test, or touching within rounding by the exact solver) is touching or overlapping by its start
        poses (:meth:`contact`)."""
        return self.contact(t0, t1, hit.pair, hit.time, hit.point, hit.normal, p0, hit.bracket)

    def _check_chain(self, s0, s1, poses, names, all_pairs, new_only):
        """Chain motions: the chain filters, then the exact solver pair by pair."""
        p0 = poses[0]
        self.check_finite((s0, s1), poses, names)
        for state, name in zip((s0, s1), names):  # a chain's turns divide by its quaternions' norms
            if has_zero_quaternion(state.qpos, np.reshape(state.mocap_quat, (-1, 4)), self._quaternions, MIN_NORM2):
                raise zero_quaternion_error(self.model, state, name)
        chains = self.chains
        v0, v1 = chains.values(s0), chains.values(s1)
        chains.check_turns(v0, v1)
        counters = dict.fromkeys(COUNTER_NAMES, 0)
        counters["pairs"] = len(self.pairs)
        contacts = []
        if self.chain_filter is None:
            todo = range(len(self.pairs))
        else:
            outcome = self.chain_filter.step(v0, v1)
            counts = self.chain_filter.counters
            for name, code in (("sphere_culled", cb.SPHERE), ("cached_plane", cb.CACHED_PLANE),
                               ("new_plane", cb.NEW_PLANE)):
                counters[name] = int(counts[code])
            overlap = np.flatnonzero(outcome == cb.OVERLAP_T0)
            counters["overlapping_t0"] = counters["colliding"] = len(overlap)
            if not new_only:  # as the scene: overlapping at t = 0, no solve
                contacts += [self.contact(s0.time, s1.time, k, 0.0, None, None, p0, status="overlapping")
                             for k in overlap.tolist()]
            todo = np.flatnonzero(outcome == cb.EXACT).tolist()
        t_max = 0.0 if contacts and not all_pairs else 1.0
        motions = {}  # built only for the ellipsoids of pairs left to the exact solver
        for k in todo:
            if t_max == 0.0:
                counters["pruned"] += 1
                continue
            i, j = (int(x) for x in self.pairs[k])
            for e in (i, j):
                if e not in motions:
                    motions[e] = chains.motion(e, v0, v1)
            counters["solved_exactly"] += 1
            hit = first_contact(self._shapes[i], motions[i], self._shapes[j], motions[j],
                                t_max=1.0 if all_pairs else t_max)
            if hit is None:
                continue
            certain = hit.certainty == "certified"
            counters["uncertain"] += not certain
            if hit.status_at_start != "separate":
                counters["overlapping_t0"] += 1
                counters["colliding"] += 1
                if new_only:
                    continue
            elif hit.point is not None or certain:
                counters["colliding"] += 1
            bracket = None if certain else hit.bracket
            point, normal = hit.point, hit.normal
            if not certain and point is None:  # an uncertain contact carries an estimated point
                point, normal = estimated_touch(self._shapes[i], motions[i], self._shapes[j], motions[j], hit.time)
            # an uncertain answer keeps the solver's status (the start poses alone may not settle it)
            c = self.contact(s0.time, s1.time, k, hit.time, point, normal, p0, bracket,
                             None if certain else hit.status_at_start)
            contacts.append(c)
            if not all_pairs:
                t_max = min(t_max, c.fraction)
        npairs = len(self.pairs)
        counters["pairs"] += len(self._plane_rows)
        decided = (self.chain_filter.plane_outcomes(self.planes, self._plane_rows) if self.chain_filter is not None
                   else np.full(len(self._plane_rows), cb.EXACT, dtype=np.int8))
        for row, (i, plane) in enumerate(self._plane_rows.tolist()):  # planes: the sweep bounds, else exactly
            if decided[row] == cb.SPHERE:
                counters["sphere_culled"] += 1
                continue
            if t_max == 0.0:
                counters["pruned"] += 1
                continue
            if decided[row] == cb.OVERLAP_T0:  # as the exact solver answers it: overlapping at t = 0
                counters["overlapping_t0"] += 1
                counters["colliding"] += 1
                if not new_only:
                    contacts.append(self.contact(s0.time, s1.time, npairs + row, 0.0, None, None, p0,
                                                 status="overlapping"))
                    t_max = t_max if all_pairs else 0.0
                continue
            if i not in motions:
                motions[i] = chains.motion(i, v0, v1)
            counters["solved_exactly"] += 1
            floor = Plane(self.planes[plane, :3], self.planes[plane, 3])
            hit = plane_first_contact(self._shapes[i], motions[i], floor, t_max=1.0 if all_pairs else t_max)
            if hit is None:
                continue
            certain = hit.certainty == "certified"
            counters["uncertain"] += not certain
            counters["colliding"] += 1
            if hit.status_at_start != "separate":
                counters["overlapping_t0"] += 1
                if new_only:
                    continue
            point, normal = hit.point, hit.normal
            if not certain and point is None:
                point, normal = estimated_touch(self._shapes[i], motions[i], floor, None, hit.time)
            c = self.contact(s0.time, s1.time, npairs + row, hit.time, point, normal, p0,
                             None if certain else hit.bracket,
                             hit.status_at_start if hit.status_at_start != "separate" or not certain else None)
            contacts.append(c)
            if not all_pairs:
                t_max = min(t_max, c.fraction)
        contacts.sort(key=lambda c: c.fraction)
        first = contacts[0] if contacts else None
        return StepReport(first, tuple(contacts) if all_pairs else (), counters["pairs"],
                          counters["solved_exactly"], counters["uncertain"], False,
                          StepCounters([counters[name] for name in COUNTER_NAMES]))
