"""CCDMonitor: the exact first contact of every MuJoCo step between fitted ellipsoids."""
from dataclasses import dataclass

import mujoco
import numpy as np

from mjccd.ccd import first_contact
from mjccd.errors import InputError, InputTypeError
from mjccd.motion import Static
from mjccd.quadric import Ellipsoid, static_status_code
from mjccd.scene import UNCERTAIN, Scene, step_kernel
from mjccd.mujoco.ellipsoids import EllipsoidSet, body_label
from mjccd.mujoco.motions import (MOTIONS, Kinematics, State, as_state, capture, ellipsoid_poses_into,
                                  motions_between, pairs_may_touch, poses_then_may_touch, sweep_sphere)

STATUS = {1: "separate", 0: "touching", -1: "overlapping"}
KINEMATIC_STATE = (mujoco.mjtState.mjSTATE_QPOS | mujoco.mjtState.mjSTATE_MOCAP_POS
                   | mujoco.mjtState.mjSTATE_MOCAP_QUAT)
# MuJoCo's warnings for a NaN, infinite or huge position, velocity or acceleration: it raises one and (unless
# autoreset is disabled) resets the data inside the step
BAD_STATE_WARNINGS = (mujoco.mjtWarning.mjWARN_BADQPOS, mujoco.mjtWarning.mjWARN_BADQVEL,
                      mujoco.mjtWarning.mjWARN_BADQACC)
BAD_COUNTS = slice(int(BAD_STATE_WARNINGS[0]), int(BAD_STATE_WARNINGS[-1]) + 1)  # adjacent in mjtWarning


def step_count(value, field):
    """A number of steps: an int >= 1 (numpy integers too; bool, float and str refused), named ``field``.

    The one check of ``nstep`` and its kin in the monitor, the guard and the wrappers, so that all
    refuse the same values with the same message.
    """
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, np.integer)):
        raise InputTypeError(f"{field}: expected an integer >= 1, got {value!r}")
    if value < 1:
        raise InputError(f"{field}: expected an integer >= 1, got {value!r}")
    return int(value)


def flag(value, field):
    """A yes/no argument: True or False (numpy bools too); anything else refused, named ``field``.

    ``bool("no")`` is True, so a string or a number is refused rather than read as a flag.
    """
    if not isinstance(value, (bool, np.bool_)):
        raise InputTypeError(f"{field}: expected True or False, got {value!r}")
    return bool(value)


def went_bad(data, counts, counts_before, time_before):
    """True when the MuJoCo step just taken on ``data`` met a bad state (see :attr:`StepReport.unstable`).

    ``counts``: the view ``data.warning.number[BAD_COUNTS]``; ``counts_before``: its bytes and
    ``time_before`` the time, both read just before the step.  A bad position, velocity or
    acceleration raises one of MuJoCo's bad-state warnings; a reset clears the counts and then counts
    its own warning, so a repeated reset can leave them as they were, but it also sets the time back
    to 0, so the step then ends no later than it began.  A state left non-finite (autoreset disabled)
    counts too.
    """
    return (counts.tobytes() != counts_before or data.time <= time_before
            or not (np.isfinite(data.qpos).all() and np.isfinite(data.qvel).all()))


@dataclass(frozen=True, eq=False)
class StepContact:
    """First contact of one pair of bodies within one simulator step.

    Attributes:
        time: simulation time of the contact in seconds.
        fraction: the same instant as a fraction in [0, 1] of the step.
        bodies: the two body names (``#id`` for unnamed bodies).
        body_ids: the two MuJoCo body ids.
        ellipsoids: the two ellipsoid indices in the monitor's :class:`EllipsoidSet`.
        point: (3,) world contact point, None when the pair was not separate at the step start.
        normal: (3,) unit world normal pointing out of ``bodies[0]``, None likewise.
        status_at_start: "separate", "touching" or "overlapping" at the step start.
        certainty: "certified", or "uncertain" when the exact solver hit one of its limits on
            this pair: then the contact is only possible, somewhere in ``bracket``, and ``time``
            and ``fraction`` are the start of that bracket (never read it as "no contact").
        bracket: (lo, hi) simulation times in seconds holding every possible first contact
            when uncertain (lo == hi when the first contact itself is known); None when certified.
    """

    time: float
    fraction: float
    bodies: tuple
    body_ids: tuple
    ellipsoids: tuple
    point: object
    normal: object
    status_at_start: str
    certainty: str = "certified"
    bracket: tuple = None


@dataclass(frozen=True, eq=False)
class StepReport:
    """Everything one check found: the first contact (or None), all colliding pairs when asked, counts.

    ``pairs_uncertain`` counts the pairs on which the exact solver hit a limit (see
    :attr:`StepContact.certainty`), including those whose bracket starts after the first contact.
    ``unstable`` is True when MuJoCo met a bad position, velocity or acceleration within the step
    (its ``mjWARN_BADQPOS``/``QVEL``/``QACC`` warnings, a state left NaN or infinite) and, unless
    autoreset is disabled, reset the data: the jump back to the reset pose is no motion, so nothing
    is checked across it (no contact, no pair counted), as :class:`~mjccd.mujoco.GuardReport` reports it.
    """

    first: object
    contacts: tuple
    pairs_checked: int
    pairs_solved: int
    pairs_uncertain: int = 0
    unstable: bool = False


UNSTABLE_REPORT = StepReport(None, (), 0, 0, 0, True)  # what a step that met a bad state reports


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


def check_simulation(model, data):
    """Refuse a ``model`` that is no ``MjModel`` or a ``data`` that is no ``MjData`` of that model's sizes."""
    if not isinstance(model, mujoco.MjModel):
        raise InputTypeError(f"model: expected a mujoco.MjModel, got {type(model).__name__}")
    if not isinstance(data, mujoco.MjData):
        raise InputTypeError(f"data: expected a mujoco.MjData, got {type(data).__name__}")
    sizes = (len(data.qpos), len(data.qvel), len(data.xpos), len(data.mocap_pos))
    if sizes != (model.nq, model.nv, model.nbody, model.nmocap):
        raise InputError(f"data: made for another model (nq, nv, nbody, nmocap = {sizes}, the model's "
                         f"{(model.nq, model.nv, model.nbody, model.nmocap)})")


class CCDMonitor:
    """Exact first contacts between fitted ellipsoids, one MuJoCo step at a time.

    Args:
        model, data: the simulation (``data`` is stepped by :meth:`step`).
        ellipsoids: :class:`EllipsoidSet` (e.g. from :func:`mjccd.fit.fit_model`).
        pairs: list of (body, body) names or ids; default :func:`default_pairs`.
        motion: "rigid", "affine" or "chain" (see :func:`motions_between`).
        on_contact: called with each reported :class:`StepContact`.
        all_pairs: report every colliding pair, not only the first contact.
        report_overlapping: when False, pairs already touching or overlapping at
            the start of a step are left out (only new contacts are reported;
            the earliest-contact bound still applies to the new ones).
    """

    def __init__(self, model, data, ellipsoids, *, pairs=None, motion="rigid", on_contact=None,
                 all_pairs=False, report_overlapping=True):
        check_simulation(model, data)
        if not isinstance(ellipsoids, EllipsoidSet):
            raise InputTypeError(f"ellipsoids: expected an EllipsoidSet, got {type(ellipsoids).__name__}")
        if not isinstance(motion, str) or motion not in MOTIONS:
            raise InputError(f"motion: expected one of {', '.join(MOTIONS)}, got {motion!r}")
        if on_contact is not None and not callable(on_contact):
            raise InputTypeError(f"on_contact: expected a callable or None, got {type(on_contact).__name__}")
        all_pairs, report_overlapping = flag(all_pairs, "all_pairs"), flag(report_overlapping, "report_overlapping")
        self.model, self.data, self.ellipsoids = model, data, ellipsoids
        self.motion, self.on_contact, self.all_pairs = motion, on_contact, all_pairs
        self.report_overlapping = report_overlapping
        self.body_ids = ellipsoids.body_ids(model)
        self.pairs = default_pairs(model, ellipsoids) if pairs is None else pairs_from_bodies(
            model, ellipsoids, pairs)
        self.labels = [body_label(model, b) for b in range(model.nbody)]
        self._kin = Kinematics(model)
        self._scene = Scene(ellipsoids.radii, pairs=self.pairs, motion=motion) \
            if motion != "chain" and len(self.pairs) else None
        self._cached = None  # (state, poses) of the last end state
        self.last_report = None

    # ------------------------------------------------------------ stepping

    def step(self, nstep=1):
        """Run ``mj_step`` ``nstep`` times (an int >= 1), checking each step; the earliest :class:`StepContact` or None.

        A step in which MuJoCo meets a bad state is not checked (see :attr:`StepReport.unstable`);
        ``last_report`` says so.
        """
        n = step_count(nstep, "nstep")
        first = None
        reports = []
        for k in range(n):
            report = self.advance_checked(lambda: mujoco.mj_step(self.model, self.data),
                                          f"step {k + 1} of {n}" if n > 1 else "the step")
            reports.append(report)
            if first is None and report.first is not None:
                first = report.first
        if len(reports) > 1:
            self.last_report = StepReport(first, tuple(c for r in reports for c in r.contacts),
                                          sum(r.pairs_checked for r in reports),
                                          sum(r.pairs_solved for r in reports),
                                          sum(r.pairs_uncertain for r in reports),
                                          any(r.unstable for r in reports))
        return first

    def advance_checked(self, advance, step_name="the step"):
        """Take one simulator step with ``advance()`` and check it: its :class:`StepReport` (also ``last_report``).

        The monitor's own steps and the wrappers' substeps all go through here.  A step in which
        MuJoCo met a bad state (:func:`went_bad`) is reported unstable and not checked: the jump to the
        reset pose is no motion.  ``step_name`` names the step in errors ("step 2 of 5").
        """
        d = self.data
        counts = d.warning.number[BAD_COUNTS]
        counts_before, time_before = counts.tobytes(), d.time
        s0 = capture(d)
        advance()
        if went_bad(d, counts, counts_before, time_before):
            self._cached = None
            self.last_report = UNSTABLE_REPORT
            return UNSTABLE_REPORT
        return self._check(s0, capture(d), (f"data before {step_name}", f"data after {step_name}"))

    def check(self, state_t0, state_t1):
        """First contact while moving from state_t0 to state_t1 (``MjData``, :class:`State` or qpos).

        With qpos vectors the mocap poses come from the monitor's data and the
        contact time is counted from state_t0 with the step length ``model.opt.timestep``.
        """
        s0 = as_state(self.model, state_t0, "state_t0", mocap_from=self.data)
        s1 = as_state(self.model, state_t1, "state_t1", mocap_from=self.data)
        return self._check(s0, s1, ("state_t0", "state_t1")).first

    # ------------------------------------------------------------ internals

    def _poses(self, state):
        c = self._cached
        if c is not None and c[0].time == state.time and np.array_equal(c[0].qpos, state.qpos) \
                and np.array_equal(c[0].mocap_pos, state.mocap_pos) \
                and np.array_equal(c[0].mocap_quat, state.mocap_quat):
            return c[1]
        return self._kin.ellipsoid_poses(state, self.body_ids, self.ellipsoids.positions,
                                         self.ellipsoids.quaternions)

    def _pose_error(self, state, poses, name):
        """The :class:`~mjccd.errors.InputError` for ellipsoid poses that are not all finite, in the user's terms.

        ``name`` is the state as the caller knows it ("state_t1", "data after step 2 of 5").  MuJoCo
        checks neither mocap poses nor, without contacts, what they do, so a NaN there reaches the check.
        """
        for field in ("qpos", "mocap_pos", "mocap_quat"):
            values = np.ravel(getattr(state, field))
            bad = np.flatnonzero(~np.isfinite(values))
            if len(bad):
                return InputError(f"{name}: {field}[{bad[0]}] is NaN or infinite")
        k = int(np.flatnonzero(~np.isfinite(poses).all(axis=1))[0])
        return InputError(f"{name}: the pose of ellipsoid {k} (body {self.labels[self.body_ids[k]]!r}) is not "
                          f"finite (largest |qpos| {np.abs(state.qpos).max():.3g})")

    def _check(self, s0, s1, names):
        """The :class:`StepReport` of the motion from state s0 to s1 (``names``: theirs, for errors)."""
        if len(self.pairs) == 0:
            report = StepReport(None, (), 0, 0)
        elif self._scene is not None:
            report = self._check_scene(s0, s1, names)
        else:
            report = self._check_chain(s0, s1, names)
        self.last_report = report
        if self.on_contact is not None:
            for c in (report.contacts if self.all_pairs else ((report.first,) if report.first else ())):
                self.on_contact(c)
        return report

    def _seconds(self, t0, t1, fraction):
        """Simulation time at ``fraction`` of a step from ``t0`` to ``t1`` (either None: unknown)."""
        if t0 is not None and t1 is not None and t1 > t0:
            return t0 + fraction * (t1 - t0)
        return (t0 if t0 is not None else 0.0) + fraction * self.model.opt.timestep

    def _contact(self, t0, t1, i, j, fraction, point, normal, poses0, bracket=None, status=None):
        """The :class:`StepContact` of ellipsoids i, j at ``fraction`` of a step from time ``t0`` to ``t1``.

        ``bracket``: (lo, hi) step fractions of an uncertain answer (None: certified).  ``status``: the
        status at the step start when the caller knows it; else separate when there is a point or an
        uncertain contact after the start, and the static status of the start poses otherwise.
        """
        if status is None:
            if point is None and (bracket is None or bracket[1] == 0.0):
                r = self.ellipsoids.radii
                status = STATUS[static_status_code(r[i], poses0[i, :3], poses0[i, 3:],
                                                   r[j], poses0[j, :3], poses0[j, 3:])]
                status = "touching" if status == "separate" else status
            else:
                status = "separate"
        a, b = int(self.body_ids[i]), int(self.body_ids[j])
        seconds = None if bracket is None else (float(self._seconds(t0, t1, bracket[0])),
                                                float(self._seconds(t0, t1, bracket[1])))
        return StepContact(float(self._seconds(t0, t1, fraction)), float(fraction),
                           (self.labels[a], self.labels[b]), (a, b), (int(i), int(j)),
                           None if point is None else np.array(point, float),
                           None if normal is None else np.array(normal, float), status,
                           "certified" if bracket is None else "uncertain", seconds)

    def _check_scene(self, s0, s1, names):
        """Rigid and affine motions: the batched :class:`mjccd.scene.Scene` pipeline."""
        p0 = self._poses(s0)
        p1 = self._kin.ellipsoid_poses(s1, self.body_ids, self.ellipsoids.positions, self.ellipsoids.quaternions)
        try:
            frame = self._scene.step(p0, p1, all_pairs=self.all_pairs,
                                     new_contacts_only=not self.report_overlapping)
        except InputError:  # the scene names its own arguments: name the state instead
            for state, poses, name in zip((s0, s1), (p0, p1), names):
                if not np.isfinite(poses).all():
                    raise self._pose_error(state, poses, name) from None
            raise
        self._cached = (s1, p1)

        def convert(pc):
            i, j = self.pairs[pc.pair]
            return self._contact(s0.time, s1.time, i, j, pc.time, pc.point, pc.normal, p0, pc.bracket)

        first = None if frame.first is None else convert(frame.first)
        contacts = tuple(sorted((convert(c) for c in frame.contacts), key=lambda c: c.fraction))
        return StepReport(first, contacts, frame.counters.pairs, frame.counters.solved_exactly,
                          frame.counters.uncertain)

    def _check_chain(self, s0, s1, names):
        """Chain motions: swept-ball prefilter, then the exact solver pair by pair."""
        p0 = self._poses(s0)
        for state, poses, name in zip((s0, s1), (p0, self._poses(s1)), names):
            if not np.isfinite(poses).all():
                raise self._pose_error(state, poses, name)
        motions = motions_between(self.model, self.ellipsoids, s0, s1, "chain", body_ids=self.body_ids,
                                  kinematics=self._kin)
        self._cached = None
        radii = self.ellipsoids.radii
        rmax = radii.max(axis=1)
        balls = [sweep_sphere(m) if not isinstance(m, Static) else (m.position, 0.0) for m in motions]
        shapes = [Ellipsoid(r) for r in radii]
        t_max, first, contacts, solved, uncertain = 1.0, None, [], 0, 0
        for i, j in self.pairs:
            bi, bj = balls[i], balls[j]
            if bi is not None and bj is not None:
                gap = np.linalg.norm(bi[0] - bj[0]) - bi[1] - bj[1] - rmax[i] - rmax[j]
                if gap > 1e-9 * (rmax[i] + rmax[j]):
                    continue
            solved += 1
            hit = first_contact(shapes[i], motions[i], shapes[j], motions[j],
                                t_max=1.0 if self.all_pairs else t_max)
            if hit is not None and hit.certainty != "certified":
                uncertain += 1
            if hit is None or (hit.status_at_start != "separate" and not self.report_overlapping):
                continue
            bracket = None if hit.certainty == "certified" else hit.bracket
            # an uncertain answer keeps the solver's status (the start poses alone may not settle it)
            c = self._contact(s0.time, s1.time, i, j, hit.time, hit.point, hit.normal, p0, bracket,
                              None if bracket is None else hit.status_at_start)
            contacts.append(c)
            if first is None or c.fraction < first.fraction:
                first, t_max = c, c.fraction
        contacts.sort(key=lambda c: c.fraction)
        return StepReport(first, tuple(contacts) if self.all_pairs else (), len(self.pairs), solved, uncertain)


class StepCheck:
    """The lean per-step check behind guarded stepping (rigid and affine motions).

    ``begin(data)`` before a step and ``end_may_touch(data)`` after it record the
    ellipsoid poses at both ends (forward kinematics on private ``MjData``,
    poses written into preallocated arrays by one compiled call; the poses of
    a state seen at the last ``end_may_touch`` or ``begin`` are reused).  ``may_touch()``
    is a conservative compiled test (swept spheres, then separating slabs);
    only when it cannot clear every pair does ``first()`` run the exact
    batched check, :meth:`mjccd.scene.Scene.step`, on the same poses: so the
    answer is the same as :meth:`CCDMonitor.check` of the two states.
    """

    def __init__(self, monitor):
        if monitor._scene is None:
            raise InputError("monitor: the step check needs a rigid or affine motion and at least one pair")
        m = monitor.model
        self.monitor, self.model = monitor, m
        n = len(monitor.ellipsoids.radii)
        size = mujoco.mj_stateSize(m, KINEMATIC_STATE)
        self._key = np.empty(size)
        # without mocap bodies the kinematic state is the joint positions: copied as an array, not through
        # mj_getState / mj_setState
        self._qpos_only = m.nmocap == 0
        # slot: [private data, key bytes of its state (None: empty), poses, the private data's qpos]
        self._slots = [[kd, None, np.empty((n, 7)), kd.qpos] for kd in (mujoco.MjData(m), mujoco.MjData(m))]
        for slot in self._slots:  # touch each private data's memory once, here rather than in a first step
            mujoco.mj_kinematics(m, slot[0])
        # the body poses of each private data (MjData arrays are views of its own memory: fetched once)
        self._xposes = [(slot[0].xpos, slot[0].xquat) for slot in self._slots]
        self._start = self._end = 0
        self.body_ids = np.ascontiguousarray(monitor.body_ids, dtype=np.int64)
        self.positions = np.ascontiguousarray(monitor.ellipsoids.positions, dtype=float)
        self.quaternions = np.ascontiguousarray(monitor.ellipsoids.quaternions, dtype=float)
        self._local = np.ascontiguousarray(np.hstack([self.positions, self.quaternions]))
        self.radii = np.ascontiguousarray(monitor.ellipsoids.radii, dtype=float)
        self.rmax = np.ascontiguousarray(self.radii.max(axis=1))
        self.pairs = np.ascontiguousarray(monitor.pairs, dtype=np.int64)
        self._pair_list = [(int(i), int(j)) for i, j in self.pairs]  # the same as Python ints, for results
        self.affine = monitor.motion == "affine"
        self.min_motion = monitor._scene.min_motion  # shared with the exact check: one setting for both

    def _state_of(self, data):
        """The kinematic state of ``data`` (``KINEMATIC_STATE`` layout; a view of its qpos when that is all)."""
        if self._qpos_only:
            return data.qpos
        mujoco.mj_getState(self.model, data, self._key, KINEMATIC_STATE)
        return self._key

    def _fill(self, idx, kb, state):
        """Private data ``idx`` set to the kinematic ``state`` (whose bytes are ``kb``), kinematics run."""
        slot = self._slots[idx]
        kd = slot[0]
        if self._qpos_only:
            slot[3][:] = state
        else:
            mujoco.mj_setState(self.model, kd, state, KINEMATIC_STATE)
        mujoco.mj_kinematics(self.model, kd)
        slot[1] = kb
        return kd

    def follow(self):
        """Record the state seen at the last ``end_may_touch`` as the start of the next step, without reading it.

        Only valid when the data has not changed since that ``end_may_touch`` (the guard's next piece of a step).
        """
        self._start = self._end

    def begin(self, data, state=None):
        """Record the state at the start of a step.

        ``state``: the kinematic state (``KINEMATIC_STATE`` layout) when the caller already holds it
        (the guard reads it off its saved full state), else it is read from ``data``.
        """
        if state is None:
            state = self._state_of(data)
        kb = state.tobytes()
        slots = self._slots
        if slots[self._end][1] == kb:
            self._start = self._end
        elif slots[self._start][1] != kb:
            idx = 1 - self._end
            kd = self._fill(idx, kb, state)
            ellipsoid_poses_into(kd.xpos, kd.xquat, self.body_ids, self.positions, self.quaternions, slots[idx][2])
            self._start = idx

    def end_may_touch(self, data):
        """Record the state at the end of the step begun last, then :meth:`may_touch` (one compiled call
        when the end state is new)."""
        state = self._state_of(data)
        kb = state.tobytes()
        slots = self._slots
        start = self._start
        if slots[start][1] == kb:
            self._end = start
            return self.may_touch()
        idx = 1 - start
        self._fill(idx, kb, state)
        self._end = idx
        xpos, xquat = self._xposes[idx]
        return poses_then_may_touch(xpos, xquat, self.body_ids, self._local, self.radii, self.rmax,
                                    slots[start][2], slots[idx][2], self.pairs, self.min_motion, self.affine)

    @property
    def poses(self):
        """(start, end) (N, 7) ellipsoid poses of the last step (internal buffers: copy to keep)."""
        return self._slots[self._start][2], self._slots[self._end][2]

    def may_touch(self):
        """False when no pair can touch during the step (cheap and conservative)."""
        p0, p1 = self.poses
        return pairs_may_touch(self.affine, self.radii, self.rmax, p0, p1, self.pairs, self.min_motion)

    def first(self, times=None):
        """Earliest new contact (:class:`StepContact` or None) of the step: the exact batched check.

        ``times`` (start time, end time) gives the contact its simulation time.
        """
        mon = self.monitor
        p0, p1 = self.poses
        k, time, point, normal, bracket = self._first_new(mon._scene, p0, p1)
        if k < 0:
            return None
        i, j = self._pair_list[k]
        t0, t1 = (None, None) if times is None else times
        return mon._contact(t0, t1, i, j, time, point, normal, p0, bracket)

    @staticmethod
    def _first_new(scene, p0, p1):
        """:meth:`Scene.step` ``(p0, p1, new_contacts_only=True)``'s first contact as (pair, time, point, normal,
        bracket).

        The same compiled kernel on the same buffers and plane cache, without the result objects
        (pair -1 when there is none; point and normal are views of the scene's buffers; bracket
        (lo, hi) when the answer is uncertain, else None).
        """
        q0_p, q0, q1_p, q1, outcome, entry, times, times_hi, points, normals, ticks, counters, iv, owner, ws = \
            scene._buffers
        scene._poses(p0, "poses_t0", q0_p, q0)
        scene._poses(p1, "poses_t1", q1_p, q1)
        k, _, _, _ = step_kernel(scene.motion == "affine", scene.radii, q0_p, q0, q1_p, q1, scene.pairs,
                                 scene.min_motion, scene.plane_cache, scene._cache_n, scene._cache_kind, False, True, False, outcome,
                                 entry, times, times_hi, points, normals, ticks, counters, iv, owner, ws)
        if k < 0:
            return -1, None, None, None, None
        t = float(times[k])
        uncertain = outcome[k] == UNCERTAIN
        bracket = (t, float(times_hi[k])) if uncertain else None
        if (t == 0.0 or uncertain) and not normals[k].any():  # as Scene: no point or normal without a touch
            return int(k), t, None, None, bracket
        return int(k), t, points[k], normals[k], bracket
