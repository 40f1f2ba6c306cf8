"""Guarded stepping: roll a MuJoCo step back to the exact first contact so fast bodies cannot tunnel."""
import math
from dataclasses import dataclass

import mujoco
import numba
import numpy as np

from mjccd.errors import InputError, InputTypeError
from mjccd.mujoco.ellipsoids import EllipsoidSet, geom_ellipsoids  # noqa: F401 (re-exported)
from mjccd.mujoco.monitor import (BAD_COUNTS, BAD_STATE_WARNINGS, CCDMonitor, StepCheck,  # noqa: F401 (re-exported)
                                  step_count, went_bad)
from mjccd.mujoco.chains import body_path
from mjccd.mujoco.motions import capture
from mjccd.mujoco.wrappers import DelegatingEnvironment, fitted_or_checked

STATE_SPEC = mujoco.mjtState.mjSTATE_INTEGRATION
UNSTABLE = object()  # a piece of a step in which MuJoCo met a bad state


@dataclass(frozen=True, eq=False)
class GuardReport:
    """What one guarded step did.

    Attributes:
        substeps: lengths in seconds of the MuJoCo steps that were kept; they sum to the timestep.
            One entry when nothing was clamped.
        clamps: the :class:`~mjccd.mujoco.StepContact` that caused each clamp, in order.
        rollbacks: how many trial steps were thrown away and redone with a shorter timestep.
        exhausted: True when ``max_rechecks`` clamps were spent and the rest of the step ran unguarded.
        unstable: True when MuJoCo met a bad position, velocity or acceleration in one of the step's
            MuJoCo steps (its ``mjWARN_BADQPOS``/``QVEL``/``QACC`` warnings) and, unless autoreset is
            disabled, reset the data.  That MuJoCo step is kept as MuJoCo left it and not checked (a jump
            back to the reset pose is no motion), and the step ends there, so ``substeps`` may sum to
            less than the timestep.
    """

    substeps: tuple
    clamps: tuple
    rollbacks: int
    exhausted: bool
    unstable: bool = False


def _positive(value, field, *, integer=False, allow_zero=False):
    """A finite number (an int with ``integer``) > 0, or >= 0 with ``allow_zero``; bool and str refused."""
    kinds = (int, np.integer) if integer else (int, float, np.integer, np.floating)
    kind = "integer" if integer else "number"
    bound = ">= 0" if allow_zero else "> 0"
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, kinds):
        raise InputTypeError(f"{field}: expected a finite {kind} {bound}, got {value!r}")
    if not np.isfinite(value) or value < 0 or (value == 0 and not allow_zero):
        raise InputError(f"{field}: expected a finite {kind} {bound}, got {value!r}")
    return int(value) if integer else float(value)


@numba.njit(cache=True, nogil=True)
def reach_fraction(tau, a):
    """Fraction s of a step at which a shorter MuJoCo step from the same start reaches the contact that the
    CCD found at fraction ``tau`` of the full step.

    The CCD follows the straight interpolation of the step's two poses.  A MuJoCo step of s·dt from the same
    start moves the joints by s·dt·(v0 + s·(v1 − v0)) (semi-implicit Euler: the acceleration comes from the
    start state; v1 is the full step's end velocity), which along the full step's displacement dt·v1 is the
    fraction a·s + (1 − a)·s² with ``a`` = v0·v1 / v1·v1.  Returns the smallest s in [0, 1] at which that
    fraction reaches tau: tau for a pair at constant velocity, √tau for one that starts from rest (a kick),
    less than tau for one that slows down.
    """
    if tau <= 0.0:
        return 0.0
    root = math.sqrt(a * a + 4.0 * (1.0 - a) * tau)
    # the same root in the form without cancellation for each sign of a
    return min(2.0 * tau / (a + root) if a >= 0.0 else (root - a) / (2.0 * (1.0 - a)), 1.0)


@numba.njit(cache=True, nogil=True)
def pair_reach(tau, qvel0, qvel1, dofs):
    """:func:`reach_fraction` of a contact at ``tau`` with ``a`` = v0·v1 / v1·v1 over ``dofs`` (the velocities
    at the start and end of the step); ``tau`` itself when those dofs end the step at rest."""
    dot = 0.0
    speed = 0.0
    for k in dofs:
        dot += qvel0[k] * qvel1[k]
        speed += qvel1[k] * qvel1[k]
    if speed == 0.0:
        return tau
    return reach_fraction(tau, dot / speed)


def _moving_dofs(model, body):
    """The dofs whose motion moves ``body``: those of its joints and of its ancestors' joints."""
    return np.flatnonzero(np.isin(model.dof_bodyid, body_path(model, body)))


class GuardedStepper:
    """MuJoCo stepping that never lets a guarded pair of bodies pass through each other within a step.

    Each call takes an ordinary ``mj_step`` first.  When the exact CCD of that
    step finds no new contact (no guarded pair that was separate at the start
    touches during the step), the step is kept as it is, so the result is
    bit-identical to plain stepping.  Otherwise the full physics state (``mjSTATE_INTEGRATION``:
    positions, velocities, activations, warm start, controls, applied forces,
    mocap, time) is restored, MuJoCo advances with a reduced timestep to the
    first such contact (a hair past it, ``overshoot`` of the step, so that
    MuJoCo's own collision detection sees the touching pair and its contact
    model takes over; the reduced timestep allows for the pair's speeding up
    or slowing down within the step, see :func:`reach_fraction`; a step
    lengthened that way is checked too), takes one short step in contact (``contact_step`` of
    the timestep, where the contact removes most of the approach speed) and
    then the rest of the step, every piece checked again.  At most
    ``max_rechecks`` clamps per step; after that the remaining time is one
    unguarded MuJoCo step (reported as ``exhausted``).  A MuJoCo step in
    which MuJoCo meets a bad state (and resets the data) is kept as it is and
    ends the guarded step (reported as ``unstable``).  Everything is
    deterministic.

    Args:
        model, data: the simulation; ``data`` is advanced by :meth:`step`.
        ellipsoids: :class:`EllipsoidSet` bounding the guarded bodies (geoms that are not
            ellipsoids are guarded through their bounding ellipsoids, so contact is caught early).
        pairs: (body, body) names or ids to guard; default: every pair MuJoCo itself collides.
        motion: "rigid", "affine" or "chain" (see :class:`~mjccd.mujoco.CCDMonitor`).
        max_rechecks: clamps allowed per step (>= 0; 0 only reports, never clamps).
        overshoot: how far past the contact instant a clamp goes, as a fraction of the timestep
            (4x further for each repeated clamp of the same pair within one step).
        contact_step: length of the step taken right after a clamp, as a fraction of the timestep.
        max_penetration: how deep one step may carry a pair into each other before the guard steps in,
            as a fraction of the pair's thickness (the sum of the two smallest semi-axes).  A pair whose
            relative motion within a step (any point, centre travel plus rotation sweep) stays below
            that depth cannot pass through, so it is left to MuJoCo's own contacts, as Bullet leaves
            bodies below its CCD motion threshold.  0 guards every new contact.  Rigid and affine
            motions only; a chain guard checks every pair.
        on_clamp: called with each :class:`~mjccd.mujoco.StepContact` that causes a clamp.
    """

    def __init__(self, model, data, ellipsoids, *, pairs=None, motion="rigid", max_rechecks=32,
                 overshoot=1e-3, contact_step=0.05, max_penetration=0.25, on_clamp=None):
        self.monitor = CCDMonitor(model, data, ellipsoids, pairs=pairs, motion=motion,
                                  report_overlapping=False)
        self.max_rechecks = _positive(max_rechecks, "max_rechecks", integer=True, allow_zero=True)
        self.overshoot = _positive(overshoot, "overshoot")
        if self.overshoot >= 1.0:
            raise InputError(f"overshoot: expected a fraction of the timestep below 1, got {overshoot!r}")
        self.contact_step = _positive(contact_step, "contact_step")
        if self.contact_step > 1.0:
            raise InputError(f"contact_step: expected a fraction of the timestep up to 1, got {contact_step!r}")
        self.max_penetration = _positive(max_penetration, "max_penetration", allow_zero=True)
        if self.max_penetration >= 1.0:
            raise InputError(f"max_penetration: expected a fraction of the pair's thickness below 1, "
                             f"got {max_penetration!r}")
        if on_clamp is not None and not callable(on_clamp):
            raise InputTypeError(f"on_clamp: expected a callable or None, got {type(on_clamp).__name__}")
        self.model, self.data, self.on_clamp = model, data, on_clamp
        self.ellipsoids, self.motion = ellipsoids, motion
        self._state0 = np.empty(mujoco.mj_stateSize(model, STATE_SPEC))
        # without mocap bodies the kinematic state is the positions, which follow the time in the full state
        self._qpos0 = self._state0[1:1 + model.nq] if model.nmocap == 0 else None
        self._qvel0 = self._state0[1 + model.nq:1 + model.nq + model.nv]
        self._opt = model.opt
        # rigid and affine motions: the lean compiled check; chain motions: the monitor's general check
        self._fast = StepCheck(self.monitor) if self.monitor.scene is not None else None
        if self._fast is not None:
            thin = np.asarray(ellipsoids.radii, dtype=float).min(axis=1)
            pairs = self.monitor.pairs
            self.monitor.scene.set_min_motion(self.max_penetration * (thin[pairs[:, 0]] + thin[pairs[:, 1]]))
            # the first step's setup, done here: the current poses recorded, so the first step costs what
            # every other step costs
            self._fast.begin(data)
        self._plain_last = GuardReport((float(model.opt.timestep),), (), 0, False)  # an unclamped step's (shared)
        self._pair_dofs = {}  # (body, body) -> the dofs that move either body (filled at clamps)
        self._warnings_of, self._bad_counts = None, None
        self.last_report = None
        self.clamps_total = 0

    @property
    def pairs(self):
        """(P, 2) guarded ellipsoid index pairs."""
        return self.monitor.pairs

    def step(self, nstep=1):
        """Advance ``nstep`` timesteps (an int >= 1), each guarded; the :class:`GuardReport` of the last one."""
        if type(nstep) is int and nstep == 1:
            return self.guarded_step(None)
        for _ in range(step_count(nstep, "nstep")):
            self.guarded_step(None)
        return self.last_report

    # ------------------------------------------------------------ checks

    def _hit(self, d, start):
        """Earliest new contact of the step just taken (from ``start``), or None."""
        fast = self._fast
        if fast is not None:
            if not fast.end_may_touch(d):
                return None
            return fast.first((float(self._state0[0]), float(d.time)))
        return self.monitor.check(start, capture(d))

    # ------------------------------------------------------------ stepping

    def guarded_step(self, full_step, finish=None):
        """One guarded timestep whose first trial is ``full_step()`` (e.g. dm-control's own step).

        ``finish()``, when given, runs after a step that was clamped (dm-control
        uses it to bring the derived quantities up to date with ``mj_step1``).
        ``full_step`` None is ``mujoco.mj_step(model, data)``.
        """
        m, d = self.model, self.data
        state0 = self._state0
        mujoco.mj_getState(m, d, state0, STATE_SPEC)
        counts = self._bad_counts if self._warnings_of is d else self._watch_warnings(d)
        bad = counts.tobytes()
        fast = self._fast
        if fast is not None:  # the lean path: no Python-level state copies, one compiled prefilter call
            fast.begin(d, self._qpos0)
        else:
            start = capture(d)
        if full_step is None:
            mujoco.mj_step(m, d)
        else:
            full_step()
        # _went_bad's warning and time tests, inline on the hot path (MuJoCo's step leaves no non-finite
        # state without a bad-state warning)
        if counts.tobytes() != bad or d.time <= state0[0]:
            return self._unstable_trial(self._opt.timestep)
        if fast is not None:
            if not fast.end_may_touch(d):
                report = self._plain_report(self._opt.timestep)
                self.last_report = report
                return report
            hit = fast.first((float(state0[0]), float(d.time)))
        else:
            hit = self._hit(d, start)
        if hit is None or self.max_rechecks == 0:
            dt = self._opt.timestep
            report = GuardReport((float(dt),), (), 0, True) if hit is not None else self._plain_report(dt)
            self.last_report = report
            return report
        return self._clamped(hit, bad, finish)

    def _watch_warnings(self, d):
        """MuJoCo's bad-state warning counts of ``d`` (a view, fetched once per data)."""
        self._warnings_of, self._bad_counts = d, d.warning.number[BAD_COUNTS]
        return self._bad_counts

    def _went_bad(self, bad):
        """True when the MuJoCo step just taken (from the saved state) met a bad state (see
        :func:`~mjccd.mujoco.monitor.went_bad`).

        ``bad``: the bytes of the bad-state warning counts before it.
        """
        return went_bad(self.data, self._bad_counts, bad, self._state0[0])

    def _unstable_trial(self, dt):
        """The report of a step whose trial MuJoCo found unstable (and reset): kept as it is, unchecked."""
        self.last_report = GuardReport((float(dt),), (), 0, False, unstable=True)
        return self.last_report

    def _plain_report(self, dt):
        """The shared report of an unclamped step of ``dt`` seconds."""
        report = self._plain_last
        if report.substeps[0] != dt:
            report = self._plain_last = GuardReport((float(dt),), (), 0, False)
        return report

    def _clamped(self, hit, bad, finish):
        """The rest of a step whose first trial found ``hit``: roll back, sub-step, check every piece.

        ``bad``: MuJoCo's bad-state warning counts before the step (bytes); a piece that raises one ends
        the step.
        """
        m, d = self.model, self.data
        opt = self._opt
        dt = float(opt.timestep)
        remaining = length = dt
        substeps, clamps = [], []
        exhausted = unstable = False
        rollbacks = 0
        try:
            while True:
                if hit is UNSTABLE:  # the piece just taken (``length`` long) met a bad state
                    substeps.append(length)
                    unstable = True
                    break
                if hit is not None and len(clamps) < self.max_rechecks:
                    # a pair clamped again in the same step: the redone short step landed short of the
                    # contact (the lerp that the CCD follows and a shorter MuJoCo step still differ where
                    # reach_fraction's model does not hold, e.g. turning joints or contact forces), so each
                    # repeat goes 4x further past the contact
                    again = sum(1 for c in clamps if c.ellipsoids == hit.ellipsoids)
                    past = self.overshoot * dt * 4.0 ** again
                    reach = self._reach(hit)  # reads the piece's end velocities: before the rollback
                    h = reach * length + past
                    clamps.append(hit)
                    if h < length:
                        # redo the trial: up to the contact, then a short step in contact
                        mujoco.mj_setState(m, d, self._state0, STATE_SPEC)
                        rollbacks += 1
                        stepped = False
                        if (reach - hit.fraction) * length > past:
                            # speeding up: this step goes further beyond the part of the piece that its
                            # check cleared than a clamp's own overshoot, so it is checked, and redone to
                            # just past a contact it met early
                            early = self._piece(h, False)
                            if early is UNSTABLE:
                                length, hit = h, UNSTABLE
                                continue
                            stepped = early is None or (1.0 - early.fraction) * h <= 2.0 * past
                            if not stepped:
                                if early.ellipsoids != hit.ellipsoids:  # another pair caused this clamp
                                    clamps.append(early)
                                mujoco.mj_setState(m, d, self._state0, STATE_SPEC)
                                rollbacks += 1
                                h = early.fraction * h + past
                        if not stepped:
                            opt.timestep = h
                            mujoco.mj_step(m, d)
                        substeps.append(h)
                        if self._went_bad(bad):
                            unstable = True
                            break
                        remaining -= h
                        length = min(remaining, self.contact_step * dt)
                        hit = self._piece(length, False)
                        continue
                elif hit is not None:
                    exhausted = True
                substeps.append(length)
                if length >= remaining:
                    break
                remaining -= length
                length = remaining
                hit = self._piece(length, True)
        finally:
            opt.timestep = dt
        if rollbacks and finish is not None:
            finish()
        self.clamps_total += len(clamps)
        self.last_report = GuardReport(tuple(substeps), tuple(clamps), rollbacks, exhausted, unstable)
        if self.on_clamp is not None:
            for c in clamps:
                self.on_clamp(c)
        return self.last_report

    def _reach(self, hit):
        """:func:`reach_fraction` of ``hit`` in the piece just taken (from ``_state0`` to the data), from the
        velocities of the joints that move its two bodies."""
        dofs = self._pair_dofs.get(hit.body_ids)
        if dofs is None:
            dofs = self._pair_dofs[hit.body_ids] = np.union1d(*(_moving_dofs(self.model, b) for b in hit.body_ids))
        return pair_reach(hit.fraction, self._qvel0, self.data.qvel, dofs)

    def _piece(self, length, follows):
        """Save the state, take one MuJoCo step of ``length`` seconds, and check it.

        ``follows``: the data is still the end state of the piece checked last (nothing was rolled back
        or stepped since), so the lean check reuses its poses without reading the state again.
        Returns the earliest new contact, None, or ``UNSTABLE`` when MuJoCo found the step unstable.
        """
        m, d, fast = self.model, self.data, self._fast
        mujoco.mj_getState(m, d, self._state0, STATE_SPEC)
        start = None
        if fast is None:
            start = capture(d)
        elif follows:
            fast.follow()
        else:
            fast.begin(d, self._qpos0)
        bad = self._bad_counts.tobytes()
        self._opt.timestep = length
        mujoco.mj_step(m, d)
        if self._went_bad(bad):
            return UNSTABLE
        return self._hit(d, start)


class GuardedWrapper(DelegatingEnvironment):
    """A dm-control environment whose physics substeps are guarded (see :class:`GuardedStepper`).

    Args:
        env: a ``dm_control.rl.control.Environment``.
        ellipsoids: :class:`EllipsoidSet`; default: fitted per body (or per geom with ``per="geom"``).
        pairs, motion, max_rechecks, overshoot, contact_step, max_penetration, on_clamp: as in
            :class:`GuardedStepper`.

    ``last_reports`` holds the :class:`GuardReport` of every substep of the last control step and
    ``last_unstable`` whether MuJoCo met a bad state in one of them (as in
    :class:`~mjccd.dm_control.CCDWrapper`).  As with dm-control's own stepping, a MuJoCo warning raised
    in any piece of a guarded step raises ``PhysicsError`` (unless the physics suppresses errors).
    """

    def __init__(self, env, ellipsoids=None, *, pairs=None, motion="rigid", max_rechecks=32, overshoot=1e-3,
                 contact_step=0.05, max_penetration=0.25, on_clamp=None, per="body"):
        super().__init__(env)
        physics = env.physics
        model = physics.model.ptr
        ellipsoids = fitted_or_checked(model, ellipsoids, per)
        self.stepper = GuardedStepper(model, physics.data.ptr, ellipsoids, pairs=pairs, motion=motion,
                                      max_rechecks=max_rechecks, overshoot=overshoot,
                                      contact_step=contact_step, max_penetration=max_penetration,
                                      on_clamp=on_clamp)
        self.last_reports = []
        self.last_unstable = False

    def reset(self):
        self.last_reports = []
        self.last_unstable = False
        return self._env.reset()

    def step(self, action):
        physics = self._env.physics
        stepper = self.stepper
        if physics.model.ptr is not stepper.model:
            raise InputError("env: the physics model was reloaded; wrap the environment again")
        stepper.data = stepper.monitor.data = physics.data.ptr
        original = physics.step
        reports = []

        def finish():
            mujoco.mj_step1(stepper.model, stepper.data)

        def guarded(nstep=1):
            for _ in range(step_count(nstep, "nstep")):
                # as dm-control's own step: a MuJoCo warning raised in any piece of a step is a PhysicsError
                # (one context per step: the trial's own check shares the physics' warning snapshot)
                with physics.check_invalid_state():
                    reports.append(stepper.guarded_step(lambda: original(1), finish))

        physics.step = guarded
        try:
            timestep = self._env.step(action)
        finally:
            del physics.step
        self.last_reports = reports
        self.last_unstable = any(r.unstable for r in reports)
        return timestep

