"""CCDMonitor: the exact first contact of every MuJoCo step between fitted ellipsoids."""
import warnings

import mujoco
import numpy as np

from mjccd._exclusive import Exclusive, exclusive
from mjccd.errors import InputError, InputTypeError
from mjccd.scene import poses_may_touch
from mjccd.mujoco.adapter import (COUNTER_NAMES, UNSTABLE_REPORT, ModelAdapter,  # noqa: F401 (re-exported)
                                  StepContact, StepCounters, StepReport)
from mjccd.mujoco.ellipsoids import EllipsoidSet
from mjccd.mujoco.geoms import GeomChecker
from mjccd.mujoco.geom_steps import POSES_NOT_FINITE, POSES_ONLY, ZERO_QUATERNION, GeomSteps
from mjccd.mujoco.pairs import pairs_with_reason, plane_pairs, warn_uncovered
from mjccd.mujoco.warnings import CoverageWarning
from mjccd.mujoco.motions import (KINEMATIC_STATE, MIN_NORM2, MOTIONS, POSES_NOT_ORDINARY, STATE_NOT_FINITE,
                                  as_state, capture, ellipsoid_poses_into, finite_state, has_zero_quaternion,
                                  kinematic_state, poses_then_first, poses_then_may_touch, quaternion_addresses)

# MuJoCo's warnings for a NaN, infinite or huge position, velocity or acceleration: it raises one and (unless
# autoreset is disabled) resets the data inside the step
BAD_STATE_WARNINGS = (mujoco.mjtWarning.mjWARN_BADQPOS, mujoco.mjtWarning.mjWARN_BADQVEL,
                      mujoco.mjtWarning.mjWARN_BADQACC)
BAD_COUNTS = slice(int(BAD_STATE_WARNINGS[0]), int(BAD_STATE_WARNINGS[-1]) + 1)  # adjacent in mjtWarning
# what every step of a monitor without pairs reports (the pairs' selection warned why there are none)
NO_PAIR_REPORT = StepReport(None, (), 0, 0, 0, False, StepCounters([0] * len(COUNTER_NAMES)))


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
    if counts.tobytes() != counts_before or data.time <= time_before:
        return True
    return not state_finite(data)


def state_finite(data):
    """False when a position or velocity of ``data`` is NaN or infinite (:func:`~mjccd.mujoco.motions.finite_state`,
    the test the compiled step paths make)."""
    return bool(finite_state(data.qpos, data.qvel))


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


def selected_adapter(model, ellipsoids, pairs, motion, planes, stacklevel=2):
    """The :class:`~mjccd.mujoco.ModelAdapter` of a monitor's arguments: ``pairs`` as
    :func:`~mjccd.mujoco.pairs.select_pairs` reads them (None: MuJoCo's collision rules) and, with ``planes``,
    the static planes MuJoCo collides with the ellipsoids' geoms.  Each geom it cannot check is warned about
    once, as is a selection that leaves nothing to check; the warnings name the line ``stacklevel`` frames up
    from the caller's (1: the caller's line, 2: its caller's)."""
    chosen, why = pairs_with_reason(model, ellipsoids, pairs, stacklevel=stacklevel + 1)
    on_planes = plane_pairs(model, ellipsoids) if planes else None
    if planes:
        warn_uncovered(model, ellipsoids, stacklevel=stacklevel + 2)
    if why is not None and (on_planes is None or len(on_planes) == 0):
        warnings.warn(why, CoverageWarning, stacklevel=stacklevel + 1)
    return ModelAdapter(model, ellipsoids, chosen, motion, plane_pairs=on_planes)


MODES = ("geoms", "ellipsoids")


def check_mode(mode, motion="rigid"):
    """``mode`` checked: "geoms" (MuJoCo's own geoms, exact), "ellipsoids" (the fitted bounds), or None: geoms
    with the rigid motion, ellipsoids with the others (geoms mode moves each geom by the rigid lerp of its
    pose)."""
    if mode is None:
        return "geoms" if motion == "rigid" else "ellipsoids"
    if not isinstance(mode, str) or mode not in MODES:
        raise InputError(f"mode: expected 'geoms', 'ellipsoids' or None, got {mode!r}")
    if mode == "geoms" and motion != "rigid":
        raise InputError(f"mode: geoms mode moves each geom by the rigid lerp of its pose; motion={motion!r} "
                         f"needs mode='ellipsoids'")
    return mode


def selected_geoms(model, ellipsoids, pairs, planes, stacklevel=2):
    """The :class:`~mjccd.mujoco.geoms.GeomChecker` of a monitor's arguments (geoms mode), with the warning of a
    selection that leaves nothing to check (naming the line ``stacklevel`` frames up from the caller's)."""
    checker = GeomChecker(model, ellipsoids, pairs, planes=planes, stacklevel=stacklevel + 1)
    if checker.reason is not None:
        warnings.warn(checker.reason, CoverageWarning, stacklevel=stacklevel + 1)
    return checker


class CCDMonitor:
    """Exact first contacts of every MuJoCo step, one step at a time: of the model's own geoms (geoms mode, the
    default with the rigid motion) or of their fitted ellipsoids.

    Args:
        model, data: the simulation (``data`` is stepped by :meth:`step`).
        ellipsoids: :class:`EllipsoidSet` (e.g. from :func:`mjccd.mujoco.fit_model`): the bounds of ellipsoid
            mode; in geoms mode the meshes are checked on them.
        pairs: None (MuJoCo's rules: on the geoms themselves in geoms mode,
            :func:`~mjccd.mujoco.default_pairs` in ellipsoid mode), ``"characters"``, ``"self"`` or a list of
            (body, body) names or ids (see :func:`mjccd.mujoco.pairs.select_pairs`).
        motion: "rigid", "affine" or "chain" (see :func:`~mjccd.mujoco.motions_between`).
        on_contact: called with each reported :class:`StepContact`.
        all_pairs: report every colliding pair, not only the first contact.
        report_overlapping: when False, pairs already touching or overlapping at
            the start of a step are left out (only new contacts are reported;
            the earliest-contact bound still applies to the new ones).
        planes: also check the ellipsoids against the static ``plane`` geoms (floors, walls: infinite, the
            half-space below each) that MuJoCo's rules collide with their geoms
            (:func:`~mjccd.mujoco.pairs.plane_pairs`); a contact with a plane has ``geom`` set.  Height
            fields, SDF geoms and planes on mocap bodies are not checked yet: each is warned about once
            (:class:`~mjccd.mujoco.warnings.CoverageWarning`, naming the geom).
        mode: "geoms" (each contact is of two geoms, :mod:`mjccd.mujoco.geoms`: contacts name ``geoms`` and
            ``elements``), "ellipsoids", or None: geoms with ``motion="rigid"``, ellipsoids otherwise.

    One thread at a time (it steps one ``MjData`` and keeps the last state seen): a call of :meth:`step`,
    :meth:`advance_checked` or :meth:`check` while another thread is in one raises
    :class:`~mjccd.errors.ConcurrentUseError` at once.
    """

    def __init__(self, model, data, ellipsoids, *, pairs=None, motion="rigid", on_contact=None,
                 all_pairs=False, report_overlapping=True, planes=True, mode=None):
        check_simulation(model, data)
        if not isinstance(ellipsoids, EllipsoidSet):
            raise InputTypeError(f"ellipsoids: expected an EllipsoidSet, got {type(ellipsoids).__name__}")
        if not isinstance(motion, str) or motion not in MOTIONS:
            raise InputError(f"motion: expected one of {', '.join(MOTIONS)}, got {motion!r}")
        mode = check_mode(mode, motion)
        if on_contact is not None and not callable(on_contact):
            raise InputTypeError(f"on_contact: expected a callable or None, got {type(on_contact).__name__}")
        all_pairs, report_overlapping = flag(all_pairs, "all_pairs"), flag(report_overlapping, "report_overlapping")
        planes = flag(planes, "planes")
        self.model, self.data, self.ellipsoids = model, data, ellipsoids
        self.motion, self.on_contact, self.all_pairs = motion, on_contact, all_pairs
        self.report_overlapping, self.mode = report_overlapping, mode
        self.geoms = None
        if mode == "geoms":
            self.geoms = selected_geoms(model, ellipsoids, pairs, planes)
            self.adapter = None
            self.body_ids, self.labels = np.unique(self.geoms.body), self.geoms.labels
            self.pairs, self.plane_pairs = self.geoms.pairs, np.empty((0, 2), dtype=np.int64)
        else:
            self.adapter = selected_adapter(model, ellipsoids, pairs, motion, planes)
            self.body_ids, self.pairs, self.labels = self.adapter.body_ids, self.adapter.pairs, self.adapter.labels
            self.plane_pairs = self.adapter.plane_pairs
        # geoms mode: the poses at both ends of the steps taken (the last end kept as the next start)
        self._geom_steps = None if self.geoms is None else GeomSteps(self.geoms)
        self.last_report = None
        # no pair and no plane: a step is the step alone (see advance_checked)
        self._idle = len(self.pairs) == 0 and len(self.plane_pairs) == 0
        self._poses = None  # the StepCheck that keeps the poses of advance_checked's steps (scene motions)
        # the data whose warning counts _warnings views (MjData arrays: views, fetched once), the bad-state ones
        # (_bad) and where they lie in the bytes of all (_bad_bytes)
        self._watched = self._warnings = self._bad = self._bad_bytes = None
        self._exclusive = Exclusive("CCDMonitor")
        self._quaternions = quaternion_addresses(model)  # a zero one is a bad state (see advance_checked)
        self._any_quaternion = len(self._quaternions) > 0 or model.nmocap > 0
        self._qpos = self._mocap_quat = None  # views of the watched data's (see _watch)

    @property
    def scene(self):
        """The :class:`mjccd.scene.Scene` of rigid and affine motions in ellipsoid mode (None for chains, geoms
        mode or no pairs)."""
        return None if self.adapter is None else self.adapter.scene

    # ------------------------------------------------------------ stepping

    @exclusive
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

    @exclusive
    def advance_checked(self, advance, step_name="the step", *, bodies_current=False):
        """Take one simulator step with ``advance()`` and check it: its :class:`StepReport` (also ``last_report``).

        The monitor's own steps and the wrappers' substeps all go through here.  A step in which
        MuJoCo met a bad state (:func:`went_bad`) is reported unstable and not checked: the jump to the
        reset pose is no motion.  ``step_name`` names the step in errors ("step 2 of 5").
        ``bodies_current``: ``advance()`` leaves the data's body poses (``xpos``, ``xquat``) those of its
        new positions, as dm-control's legacy step does (it ends with ``mj_step1``); the end poses are then
        read off them instead of forward kinematics on a private ``MjData`` (the same kinematics, so the
        same poses bit for bit).
        """
        d = self.data
        if d is not self._watched:
            self._watch(d)
        counts = self._warnings
        counts_before, time_before = counts.tobytes(), d.time
        if self._idle:  # no pair to check: no state copies, no kinematics, only MuJoCo's bad-state test
            advance()
            self.last_report = UNSTABLE_REPORT if went_bad(d, self._bad, counts_before[self._bad_bytes], time_before) \
                else NO_PAIR_REPORT
            return self.last_report
        if self.geoms is not None:
            return self._advance_geoms(d, advance, counts, counts_before, time_before, step_name, bodies_current)
        poses = self._poses
        if poses is None and self.adapter.scene is not None:
            poses = self._poses = StepCheck(self)
        # a start state with no rotation: the step is taken, not checked (a start state the step check has
        # recorded before was tested then: every state it holds has passed this test)
        if (poses is None or not poses.begin(d)) and self._zero_quaternion(d):
            if poses is not None:
                poses.forget_start()
            advance()
            return self._unstable()
        if poses is None:
            s0 = capture(d)
        advance()
        # went_bad's warning and time tests (any warning, then the bad-state ones): the state's own is compiled
        if (counts.tobytes() != counts_before and self._bad.tobytes() != counts_before[self._bad_bytes]) \
                or d.time <= time_before or self._zero_quaternion(d):
            return self._unstable()
        if poses is None:
            if not state_finite(d):
                return self._unstable()
            return self._check(s0, capture(d), self._names(step_name))
        if not self.all_pairs:
            best = poses.end_first(d, bodies_current, not self.report_overlapping)
            if best == STATE_NOT_FINITE:
                return self._unstable()
            if best != POSES_NOT_ORDINARY:
                return self._reported(self.adapter.scene_report(time_before, d.time, best, *poses.poses,
                                                                new_only=not self.report_overlapping))
        else:
            if not state_finite(d):
                return self._unstable()
            poses.end(d, bodies_current)
        try:  # all pairs, or poses the compiled split cannot take: the scene's checked entry
            report = self.adapter.check_poses(time_before, d.time, *poses.poses, all_pairs=self.all_pairs,
                                              new_only=not self.report_overlapping)
        except InputError:  # a pose that is not finite: named in the user's terms
            s1 = capture(d)
            self.adapter.check_finite((s1, s1), poses.poses, self._names(step_name))
            raise
        return self._reported(report)

    def _advance_geoms(self, d, advance, counts, counts_before, time_before, step_name, bodies_current):
        """advance_checked in geoms mode: the geoms' poses at both ends, then their exact check
        (:class:`~mjccd.mujoco.geom_steps.GeomSteps`: one compiled call for the first contact)."""
        steps = self._geom_steps
        if not steps.begin(d) and self._zero_quaternion(d):  # no rotation at the start: taken, not checked
            advance()
            return self._unstable()
        advance()
        if (counts.tobytes() != counts_before and self._bad.tobytes() != counts_before[self._bad_bytes]) \
                or d.time <= time_before:
            return self._unstable()
        new_only = not self.report_overlapping
        answer = steps.end(d, bodies_current, new_only, check=not self.all_pairs)
        if answer == STATE_NOT_FINITE or answer == ZERO_QUATERNION:
            return self._unstable()
        if answer == POSES_NOT_FINITE:  # a NaN mocap pose, say (MuJoCo checks none): named in the user's terms
            states = steps.states(d)
            steps.forget()
            self.geoms.check_finite(states, steps.poses, self._names(step_name))
        if answer == POSES_ONLY:
            return self._reported(self.geoms.check_poses(time_before, d.time, *steps.poses, all_pairs=True,
                                                         new_only=new_only))
        out, tallies = steps.answers
        return self._reported(self.geoms.first_report(time_before, d.time, *steps.poses, out, answer, tallies,
                                                      new_only))

    def _zero_quaternion(self, data):
        """True when a joint or mocap quaternion of the watched ``data`` is zero (no rotation: MuJoCo's
        kinematics would read it as the identity, a chain's turns divide by it)."""
        return self._any_quaternion and \
            has_zero_quaternion(self._qpos, self._mocap_quat, self._quaternions, MIN_NORM2)

    def _watch(self, data):
        """Fetch the views of ``data``'s warning counts (all of them, and the bad-state ones), positions and
        mocap quaternions once per data."""
        self._qpos, self._mocap_quat = data.qpos, data.mocap_quat
        self._warnings = data.warning.number
        self._bad = self._warnings[BAD_COUNTS]
        size = self._warnings.itemsize
        self._bad_bytes = slice(BAD_COUNTS.start * size, BAD_COUNTS.stop * size)
        self._watched = data

    @staticmethod
    def _names(step_name):
        """The data before and after the step ``step_name``, as errors name them."""
        return f"data before {step_name}", f"data after {step_name}"

    def _unstable(self):
        """The report of a step in which MuJoCo met a bad state: nothing checked, the remembered state dropped."""
        if self.adapter is not None:
            self.adapter.forget()
        if self._geom_steps is not None:
            self._geom_steps.forget()
        self.last_report = UNSTABLE_REPORT
        return UNSTABLE_REPORT

    @exclusive
    def check(self, state_t0, state_t1):
        """First contact while moving from state_t0 to state_t1 (``MjData``, :class:`State` or qpos).

        With qpos vectors the mocap poses come from the monitor's data and the
        contact time is counted from state_t0 with the step length ``model.opt.timestep``.
        """
        s0 = as_state(self.model, state_t0, "state_t0", mocap_from=self.data)
        s1 = as_state(self.model, state_t1, "state_t1", mocap_from=self.data)
        return self._check(s0, s1, ("state_t0", "state_t1")).first

    def _check(self, s0, s1, names):
        """The :class:`StepReport` of the motion from state s0 to s1 (``names``: theirs, for errors)."""
        if self.geoms is not None:
            return self._reported(self.geoms.check(s0, s1, all_pairs=self.all_pairs,
                                                   new_only=not self.report_overlapping))
        return self._reported(self.adapter.check(s0, s1, all_pairs=self.all_pairs,
                                                 new_only=not self.report_overlapping, names=names))

    def _reported(self, report):
        """Keep ``report`` as ``last_report`` and pass its contacts to ``on_contact``."""
        self.last_report = report
        if self.on_contact is not None:
            for c in (report.contacts if self.all_pairs else ((report.first,) if report.first else ())):
                self.on_contact(c)
        return report


class StepCheck:
    """The lean per-step check behind guarded stepping (rigid and affine motions).

    ``begin(data)`` before a step and ``end_may_touch(data)`` after it record the
    ellipsoid poses at both ends (forward kinematics on private ``MjData``,
    poses written into preallocated arrays by one compiled call; the poses of
    a state seen at the last ``end_may_touch`` or ``begin`` are reused).  ``may_touch()``
    is the scene's conservative compiled test (:meth:`mjccd.scene.Scene.may_touch`);
    only when it cannot clear every pair does ``first()`` run the exact
    batched check, :meth:`mjccd.scene.Scene.first_contact`, on the same poses: so the
    answer is the same as :meth:`CCDMonitor.check` of the two states.  Both use the
    monitor's scene, its plane cache and its ``min_motion``.
    """

    def __init__(self, monitor):
        if monitor.scene is None:
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
        self.scene = monitor.scene
        self._workspace = self.scene.workspace
        self._no_intervals = (np.empty((0, 2)), np.empty(0, dtype=np.int64))  # (a first-contact check writes none)
        self._views_of, self._views = None, None  # a data and its (qpos, qvel, xpos, xquat): fetched once per data

    def _views_for(self, data):
        """(qpos, qvel, xpos, xquat) of ``data`` (MjData arrays are views of its memory: fetched once per data)."""
        if data is not self._views_of:
            self._views = (data.qpos, data.qvel, data.xpos, data.xquat)
            self._views_of = data
        return self._views

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
        """Record the state at the start of a step: True when it is a state recorded before (its poses kept).

        ``state``: the kinematic state (``KINEMATIC_STATE`` layout) when the caller already holds it
        (the guard reads it off its saved full state), else it is read from ``data``.
        """
        if state is None:
            state = kinematic_state(self.model, data, self._key, self._qpos_only)
        kb = state.tobytes()
        slots = self._slots
        if slots[self._end][1] == kb:
            self._start = self._end
        elif slots[self._start][1] != kb:
            idx = 1 - self._end
            kd = self._fill(idx, kb, state)
            ellipsoid_poses_into(kd.xpos, kd.xquat, self.body_ids, self.positions, self.quaternions, slots[idx][2])
            self._start = idx
            return False
        return True

    def forget_start(self):
        """Drop the state recorded by the last ``begin`` (a bad one, not to be taken as a known state)."""
        self._slots[self._start][1] = None

    def _record_end(self, data, bodies_current=False):
        """Record the state of ``data`` as the end of the step begun last: the index of the slot whose poses
        are still to be computed, or None when it is the start state (poses known).  The body poses to
        compute them from are those of the slot's private data after its kinematics, or with
        ``bodies_current`` (``data``'s own are those of its state) ``data``'s."""
        state = kinematic_state(self.model, data, self._key, self._qpos_only)
        kb = state.tobytes()
        start = self._start
        if self._slots[start][1] == kb:
            self._end = start
            return None
        idx = 1 - start
        if bodies_current:
            self._slots[idx][1] = kb
        else:
            self._fill(idx, kb, state)
        self._end = idx
        return idx

    def end(self, data, bodies_current=False):
        """Record the state at the end of the step begun last (its poses: :attr:`poses`); ``bodies_current``:
        the body poses of ``data`` are those of its state (read instead of computed)."""
        idx = self._record_end(data, bodies_current)
        if idx is not None:
            xpos, xquat = self._views_for(data)[2:] if bodies_current else self._xposes[idx]
            ellipsoid_poses_into(xpos, xquat, self.body_ids, self.positions, self.quaternions, self._slots[idx][2])

    def end_first(self, data, bodies_current=False, new_only=False):
        """Record the state at the end of the step begun last, then the scene's first-contact check of the step
        (:meth:`mjccd.scene.Scene.first_pair` with ``new_contacts_only=new_only``), all compiled parts in one call
        (:func:`~mjccd.mujoco.motions.poses_then_first`): the first pair's index (-1: none; the answer in the
        scene's workspace), ``STATE_NOT_FINITE`` when a position or velocity of ``data`` is NaN or infinite, or
        ``POSES_NOT_ORDINARY`` (the scene's checked entry then names the bad pose).  ``bodies_current`` as in
        :meth:`end`."""
        qpos, qvel, xpos, xquat = self._views_for(data)
        idx = self._record_end(data, bodies_current)
        if idx is not None and not bodies_current:
            xpos, xquat = self._xposes[idx]
        slots = self._slots
        iv, owner = self._no_intervals
        return poses_then_first(qpos, qvel, xpos, xquat, self.body_ids, self._local, slots[self._start][2],
                                slots[self._end][2], idx is not None, self._workspace, iv, owner, new_only)

    def end_may_touch(self, data):
        """Record the state at the end of the step begun last, then :meth:`may_touch` (one compiled call
        when the end state is new)."""
        idx = self._record_end(data)
        if idx is None:
            return self.may_touch()
        xpos, xquat = self._xposes[idx]
        return poses_then_may_touch(xpos, xquat, self.body_ids, self._local, self._slots[self._start][2],
                                    self._slots[idx][2], self._workspace)

    @property
    def poses(self):
        """(start, end) (N, 7) ellipsoid poses of the last step (internal buffers: copy to keep)."""
        return self._slots[self._start][2], self._slots[self._end][2]

    def may_touch(self):
        """False when no pair can touch during the step (cheap and conservative): :meth:`Scene.may_touch` of the
        recorded poses, as one compiled call."""
        p0, p1 = self.poses
        return poses_may_touch(self._workspace, p0, p1)

    def first(self, times=None):
        """Earliest new contact (:class:`StepContact` or None) of the step: the exact batched check.

        ``times`` (start time, end time) gives the contact its simulation time.
        """
        p0, p1 = self.poses
        hit = self.scene.first_contact(p0, p1, new_contacts_only=True)
        if hit is None:
            return None
        t0, t1 = (None, None) if times is None else times
        adapter = self.monitor.adapter
        if hit.bracket is not None:  # undecided by the scene: every pair, the undecided asked of the core
            return adapter.check_poses(t0, t1, p0, p1, all_pairs=True, new_only=True).first
        return adapter.contact(t0, t1, hit.pair, hit.time, hit.point, hit.normal, p0, hit.bracket)
