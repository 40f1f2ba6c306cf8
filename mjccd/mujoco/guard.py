"""Guarded stepping: roll a MuJoCo step back to the exact first contact so fast bodies cannot tunnel."""
import math
from typing import NamedTuple

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
# After a clamp, each MuJoCo step taken in contact is at most this many times as long as the one before it
# (or as half the shortest contact time constant, if that is longer), across the end of the guarded step if
# need be, until the pieces are back to the timestep; see GuardedStepper and docs/guarded-stepping.md.
RAMP_GROWTH = 2.0


class GuardReport(NamedTuple):
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
        kinetic_energy: (before, after) the step, in joules (``0.5 qvel' M qvel`` of the whole model), on
            every report (for an unstable step, "after" is what MuJoCo left: the reset state, or the bad one).
        momentum: (before, after) the step, each a (6,) array: the model's linear momentum in kg m/s (world
            frame) and its angular momentum about its centre of mass in kg m^2/s, on every report (from
            MuJoCo's ``subtree_linvel`` and ``subtree_angmom`` of the world body).  Both are computed when
            first read, from copies of the two states the step keeps.
        energy_added: for a split step, how much the mechanical energy (kinetic plus MuJoCo's potential:
            gravity and springs) rose more than the work of actuators, applied forces, gravity compensation
            and fluid forces explains, in joules, counted from the start of the clamped step (for a step
            that goes on with its pieces, from the start of the step before); contacts and damping only
            remove energy, so this is at most rounding in a sound step.  None for a step that is one plain
            ``mj_step``: that step is MuJoCo's own (a soft contact letting go gives back energy its
            penetration took, which is MuJoCo's contact model, not the guard's), and for an unstable one.
        energy_gain: True when ``energy_added`` exceeds ``energy_tolerance`` (see :class:`GuardedStepper`)
            of the kinetic energy involved: the split step added energy, so its state is not to be trusted.
        states: the step's (start, end) states (time, positions, velocities, mocap poses), from which
            ``kinetic_energy`` and ``momentum`` are computed.
    """

    substeps: tuple
    clamps: tuple
    rollbacks: int
    exhausted: bool
    unstable: bool = False
    energy_added: float = None
    energy_gain: bool = False
    states: tuple = None

    @property
    def kinetic_energy(self):
        """(before, after) the step, in joules."""
        return self.states[0].mechanics()[1], self.states[1].mechanics()[1]

    @property
    def momentum(self):
        """(before, after) the step, each (6,): linear momentum (world frame), angular momentum about the
        centre of mass."""
        return self.states[0].mechanics()[2], self.states[1].mechanics()[2]


class _Meter:
    """Energy and momentum of a model's states, computed on a private MjData."""

    def __init__(self, model):
        self.model = model
        self._data = mujoco.MjData(model)

    def mechanics(self, qpos, qvel, mocap):
        """(potential energy, kinetic energy, momentum) in joules and a (6,) array: the linear momentum
        (world frame) and the angular momentum about the centre of mass.  ``mocap``: (positions,
        quaternions) of the mocap bodies, or None."""
        m, e = self.model, self._data
        e.qpos[:] = qpos
        e.qvel[:] = qvel
        if mocap is not None:
            e.mocap_pos[:], e.mocap_quat[:] = mocap
        mujoco.mj_kinematics(m, e)
        mujoco.mj_comPos(m, e)
        if m.ntendon:
            mujoco.mj_tendon(m, e)
        mujoco.mj_makeM(m, e)
        mujoco.mj_energyPos(m, e)
        mujoco.mj_energyVel(m, e)
        mujoco.mj_comVel(m, e)
        mujoco.mj_subtreeVel(m, e)
        momentum = np.concatenate((m.body_subtreemass[0] * e.subtree_linvel[0], e.subtree_angmom[0]))
        return float(e.energy[0]), float(e.energy[1]), momentum


class _Snapshot:
    """A state (time, positions and velocities as bytes, mocap poses) whose :meth:`_Meter.mechanics` is
    computed when first asked for: a plain guarded step only copies its end state."""

    __slots__ = ("meter", "time", "posvel", "mocap", "_value")

    def __init__(self, meter, time, posvel, mocap):
        self.meter, self.time, self.posvel, self.mocap = meter, time, posvel, mocap
        self._value = None

    def holds(self, time, posvel, mocap):
        """True when this is the state ``time``, ``posvel`` (bytes) and ``mocap`` (as in :meth:`mechanics`)."""
        if time != self.time or posvel != self.posvel:
            return False
        return mocap is None or (np.array_equal(mocap[0], self.mocap[0]) and np.array_equal(mocap[1], self.mocap[1]))

    def mechanics(self):
        if self._value is None:
            nq = self.meter.model.nq
            posvel = np.frombuffer(self.posvel)
            self._value = self.meter.mechanics(posvel[:nq], posvel[nq:], self.mocap)
        return self._value


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


@numba.njit(cache=True, nogil=True, no_cfunc_wrapper=True, forceinline=False)
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


@numba.njit(cache=True, nogil=True, no_cfunc_wrapper=True, forceinline=False)
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


def shortest_contact_time(model):
    """The shortest contact time constant of ``model`` in seconds (``solref[0]`` > 0 of its colliding geoms,
    its explicit pairs and, when enabled, the global override); 0 when it has none (``solref`` given as direct
    stiffness and damping).

    MuJoCo raises a contact's time constant to twice the running timestep, so in a step shorter than half of
    this the contact is not stiffer: such a step's contact force is the one of a step of half this length.
    """
    colliding = (model.geom_contype != 0) | (model.geom_conaffinity != 0)
    times = [model.geom_solref[colliding, 0], model.pair_solref[:, 0]]
    if model.opt.enableflags & mujoco.mjtEnableBit.mjENBL_OVERRIDE:
        times.append(model.opt.o_solref[:1])
    times = np.concatenate(times)
    times = times[times > 0.0]
    return float(times.min()) if len(times) else 0.0


def carries_contact_force(model):
    """True when a contact force can carry from one MuJoCo step into the next through damped velocities.

    Where MuJoCo integrates velocity-dependent forces implicitly (joint damping under the Euler integrator,
    and under the implicit ones also tendon damping, actuators and fluid forces), its constraint solver
    still sees those forces explicitly: a dof that a step's contact pushed against its damping carries a
    damping force as large as that push into the next step, which the contact there counters and the
    integrator then mostly cancels, so the rest of the contact force drives the undamped dofs.  The push
    scales with the contact force of the step before; a step much longer than that one applies it for
    longer and adds energy (the guard's ramp of pieces, see :class:`GuardedStepper`).  Without such forces
    (RK4, no damping) nothing carries over.
    """
    integrator = model.opt.integrator
    if integrator == mujoco.mjtIntegrator.mjINT_RK4:
        return False
    damped = bool(np.any(model.dof_damping > 0.0))
    if integrator == mujoco.mjtIntegrator.mjINT_EULER:
        return damped and not model.opt.disableflags & mujoco.mjtDisableBit.mjDSBL_EULERDAMP
    fluid = model.opt.density > 0.0 or model.opt.viscosity > 0.0
    return damped or bool(np.any(model.tendon_damping > 0.0)) or model.nu > 0 or fluid


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
    the timestep, or half the model's shortest contact time constant if that is
    longer: the stiffest contact MuJoCo gives, which removes most of the approach
    speed) and then the rest of the step, every piece checked again.  Where damped
    joints carry a contact force from one MuJoCo step into the next
    (:func:`carries_contact_force`), the pieces after it grow instead, each in
    contact at most ``RAMP_GROWTH`` (2) times the one before, into the next
    step if need be: a long step right after a short one in contact adds energy
    (docs/guarded-stepping.md).  At most
    ``max_rechecks`` clamps per step; after that the remaining time is one
    unguarded MuJoCo step (reported as ``exhausted``).  A MuJoCo step in
    which MuJoCo meets a bad state (and resets the data) is kept as it is and
    ends the guarded step (reported as ``unstable``).  Every step reports its
    kinetic energy and momentum before and after; a split step also flags energy it
    added (:class:`GuardReport`).  Everything is deterministic.

    Args:
        model, data: the simulation; ``data`` is advanced by :meth:`step`.
        ellipsoids: :class:`EllipsoidSet` bounding the guarded bodies (geoms that are not
            ellipsoids are guarded through their bounding ellipsoids, so contact is caught early).
        pairs: (body, body) names or ids to guard; default: every pair MuJoCo itself collides.
        motion: "rigid", "affine" or "chain" (see :class:`~mjccd.mujoco.CCDMonitor`).
        max_rechecks: clamps allowed per step (>= 0; 0 only reports, never clamps).
        overshoot: how far past the contact instant a clamp goes, as a fraction of the timestep
            (4x further for each repeated clamp of the same pair within one step).
        contact_step: length of the step taken right after a clamp, as a fraction of the timestep (at
            least half the model's shortest contact time constant, :func:`shortest_contact_time`).
        max_penetration: how deep one step may carry a pair into each other before the guard steps in,
            as a fraction of the pair's thickness (the sum of the two smallest semi-axes, in geoms mode of the
            two geoms' smallest radii or half sizes; against a plane, the other's alone).  A pair whose
            relative motion within a step (any point, centre travel plus rotation sweep) stays below
            that depth cannot pass through, so it is left to MuJoCo's own contacts, as Bullet leaves
            bodies below its CCD motion threshold.  0 guards every new contact.  Rigid and affine
            motions only; a chain guard checks every pair.
        on_clamp: called with each :class:`~mjccd.mujoco.StepContact` that causes a clamp.
        energy_tolerance: a split step whose mechanical energy rose by more than this fraction of the
            kinetic energy involved, beyond the work of actuators and applied forces, is reported with
            ``energy_gain`` (see :class:`GuardReport`).
        mode: what is guarded, as in :class:`~mjccd.mujoco.CCDMonitor`: the geoms themselves (the default with
            the rigid motion) or their ellipsoids.
    """

    def __init__(self, model, data, ellipsoids, *, pairs=None, motion="rigid", max_rechecks=32,
                 overshoot=1e-3, contact_step=0.05, max_penetration=0.25, on_clamp=None, energy_tolerance=0.05,
                 mode=None):
        self.monitor = CCDMonitor(model, data, ellipsoids, pairs=pairs, motion=motion,
                                  report_overlapping=False, mode=mode)
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
        self.energy_tolerance = _positive(energy_tolerance, "energy_tolerance", allow_zero=True)
        self.model, self.data, self.on_clamp = model, data, on_clamp
        self.ellipsoids, self.motion = ellipsoids, motion
        self._state0 = np.empty(mujoco.mj_stateSize(model, STATE_SPEC))
        # without mocap bodies the kinematic state is the positions, which follow the time in the full state
        self._qpos0 = self._state0[1:1 + model.nq] if model.nmocap == 0 else None
        self._qvel0 = self._state0[1 + model.nq:1 + model.nq + model.nv]
        self._posvel0 = self._state0[1:1 + model.nq + model.nv]
        self._opt = model.opt
        # rigid and affine motions: the lean compiled check; chain motions: the monitor's general check
        self._fast = StepCheck(self.monitor) if self.monitor.scene is not None else None
        if self._fast is not None:
            thin = np.asarray(ellipsoids.radii, dtype=float).min(axis=1)
            pairs = self.monitor.pairs
            self.monitor.scene.set_min_motion(self.max_penetration * (thin[pairs[:, 0]] + thin[pairs[:, 1]]))
            on_planes = self.monitor.plane_pairs  # a plane is as thick as the half-space: the ellipsoid's own
            if len(on_planes):
                self.monitor.scene.set_plane_min_motion(self.max_penetration * thin[on_planes[:, 0]])
            # the first step's setup, done here: the current poses recorded, so the first step costs what
            # every other step costs
            self._fast.begin(data)
        elif self.monitor.geoms is not None:
            geoms = self.monitor.geoms
            thin = geoms.thickness()
            geoms.set_min_motion(self.max_penetration * (thin[geoms.pairs[:, 0]] + thin[geoms.pairs[:, 1]]))
        self._pair_dofs = {}  # (body, body) -> the dofs that move either body (filled at clamps)
        # pieces in contact: none shorter, for their growth, than half the shortest contact time constant
        self._contact_half = 0.5 * shortest_contact_time(model)
        self._carries = carries_contact_force(model)  # pieces in contact grow only where this holds
        # forces whose work a split step's energy report counts, other than applied ones (checked per piece)
        self._forced = model.nu > 0 or model.ngravcomp > 0 or model.opt.density > 0.0 or model.opt.viscosity > 0.0
        # the last piece of a split step that ended in contact with pieces still short of the timestep, and
        # the time it ended at: the next step goes on growing them (see _clamped)
        self._ramp, self._ramp_time = None, None
        self._meter = _Meter(model)
        self._mocap = model.nmocap > 0
        self._plain_substeps = (float(model.opt.timestep),)  # shared by the reports of unclamped steps
        self._views_of, self._views = None, None
        self._last_end = None  # the _Snapshot of the last step's end: the next step's start, if unchanged
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
        if self._ramp is not None:  # the step before ended a clamp's pieces in contact: go on growing them
            last, self._ramp = self._ramp, None
            if d.time == self._ramp_time:  # (not after a reset or a jump in time)
                return self._ramped(*last, finish)
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
            report = self._plain_report(dt, exhausted=hit is not None)
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
        self.last_report = self._plain_report(dt, unstable=True)
        return self.last_report

    def _plain_report(self, dt, *, exhausted=False, unstable=False):
        """The report of a step that is one MuJoCo step of ``dt`` seconds from the saved state, with the
        states at both ends (the hot path of :meth:`_saved_snapshot` and :meth:`_end_snapshot`)."""
        substeps = self._plain_substeps
        if substeps[0] != dt:
            substeps = self._plain_substeps = (float(dt),)
        last, d = self._last_end, self.data
        if self._mocap or last is None or last.time != self._state0[0] or last.posvel != self._posvel0.tobytes():
            return GuardReport(substeps, (), 0, exhausted, unstable,
                               states=(self._saved_snapshot(), self._end_snapshot()))
        qpos, qvel = self._views if self._views_of is d else self._watch_views(d)
        end = self._last_end = _Snapshot(self._meter, d.time, qpos.tobytes() + qvel.tobytes(), None)
        return GuardReport(substeps, (), 0, exhausted, unstable, None, False, (last, end))

    def _watch_views(self, d):
        """(qpos, qvel) of ``d`` (views, fetched once per data)."""
        self._views_of, self._views = d, (d.qpos, d.qvel)
        return self._views

    def _clamped(self, hit, bad, finish, first=None, since=None):
        """The rest of a step whose first trial found ``hit``: roll back, sub-step, check every piece.

        ``bad``: MuJoCo's bad-state warning counts before the step (bytes); a piece that raises one ends
        the step.  ``first``: a step that goes on with the pieces of the step before (no trial, ``hit``
        None): the length of its first piece; ``since``: (mechanical energy, kinetic energy) at the start of
        the step that was clamped and the work of external forces since then (see :meth:`_energy_report`).

        After a clamp the step goes on in pieces that grow (:meth:`_grow`): the first one in contact is
        ``contact_step`` of the timestep, or half the shortest contact time constant if that is longer (a
        contact as stiff as MuJoCo allows it); each one after it in contact is at most ``RAMP_GROWTH``
        times as long as the one before.  While the contact lasts, the pieces keep growing into the next
        step until they are back to the timestep (``_ramp``).
        """
        m, d = self.model, self.data
        opt = self._opt
        dt = float(opt.timestep)
        remaining = length = dt
        substeps, clamps = [], []
        exhausted = unstable = False
        rollbacks = 0
        # the step's start: the state saved for the trial, or the data (a step going on with its pieces)
        start = self._saved_snapshot() if first is None else self._snapshot(d.time, d.qpos.tobytes() + d.qvel.tobytes())
        # the energy since the start of the clamped step, and the work of actuators, applied forces, gravity
        # compensation and fluid forces in the pieces kept since
        if since is None:
            energy0 = start.mechanics()
            base, work = (energy0[0] + energy0[1], energy0[1]), 0.0
        else:
            base, work = since
        # controls and applied forces stay as they are through the step: without them (and without forces
        # that do work of their own) no work is counted
        forced = self._forced or d.xfrc_applied.any() or d.qfrc_applied.any()
        moved = np.zeros(m.nv) if forced else None  # the pieces' generalized displacement (mean velocity)
        try:
            if first is not None:
                length = first
                hit = self._piece(length, False)
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
                        self._displace(moved, h)
                        remaining -= h
                        length = min(remaining, max(self.contact_step * dt, self._contact_half))
                        hit = self._piece(length, False)
                        continue
                elif hit is not None:
                    exhausted = True
                substeps.append(length)
                self._displace(moved, length)
                if length >= remaining:
                    break
                remaining -= length
                # in contact where damped velocities carry the contact force: grow the pieces (a long step
                # right after short ones in contact adds energy); else the rest at once
                length = self._grow(length, remaining) if d.ncon and self._carries else remaining
                hit = self._piece(length, True)
        finally:
            opt.timestep = dt
        last = substeps[-1]
        if moved is not None:
            work += self._work(moved)
        if not unstable and d.ncon and self._carries and RAMP_GROWTH * max(last, self._contact_half) < dt:
            self._ramp, self._ramp_time = (last, (base, work)), d.time
        if (rollbacks or first is not None) and finish is not None:
            finish()
        self.clamps_total += len(clamps)
        end = self._end_snapshot()
        energy = {} if unstable else self._energy_report(end.mechanics(), base, work)
        self.last_report = GuardReport(tuple(substeps), tuple(clamps), rollbacks, exhausted, unstable, **energy,
                                       states=(start, end))
        if self.on_clamp is not None:
            for c in clamps:
                self.on_clamp(c)
        return self.last_report

    def _ramped(self, last, since, finish):
        """A step that goes on growing the pieces of the step before, which ended in contact with a piece
        ``last`` seconds long; ``since``: as in :meth:`_clamped`."""
        d = self.data
        counts = self._bad_counts if self._warnings_of is d else self._watch_warnings(d)
        return self._clamped(None, counts.tobytes(), finish, first=self._grow(last, float(self._opt.timestep)),
                             since=since)

    def _grow(self, last, remaining):
        """The length of the piece after one of ``last`` seconds in contact, ``remaining`` seconds before
        the end of the step: ``RAMP_GROWTH`` times ``last`` (or half the shortest contact time constant, if
        longer: a shorter step's contact is no stiffer), the rest of the step if that is no longer, and half
        of it if the piece after would otherwise be the shorter (a short piece in contact stiffens it)."""
        base = max(last, self._contact_half)
        h = RAMP_GROWTH * base
        if remaining <= h:
            return remaining
        if remaining < h + base:
            return 0.5 * remaining
        return h

    # ------------------------------------------------------------ energy

    def _snapshot(self, time, posvel):
        """The :class:`_Snapshot` of a state of the data at ``time`` with positions and velocities
        ``posvel`` (bytes): the last step's end when it is that state."""
        d = self.data
        mocap = (d.mocap_pos.copy(), d.mocap_quat.copy()) if self.model.nmocap else None
        last = self._last_end
        if last is not None and last.holds(time, posvel, mocap):
            return last
        return _Snapshot(self._meter, float(time), posvel, mocap)

    def _saved_snapshot(self):
        """The snapshot of the state saved at the step's start (``_state0``)."""
        return self._snapshot(self._state0[0], self._posvel0.tobytes())

    def _end_snapshot(self):
        """The snapshot of the data, which holds a step's end; kept for the next step's start."""
        d = self.data
        mocap = (d.mocap_pos.copy(), d.mocap_quat.copy()) if self.model.nmocap else None
        self._last_end = _Snapshot(self._meter, d.time, d.qpos.tobytes() + d.qvel.tobytes(), mocap)
        return self._last_end

    def _displace(self, moved, h):
        """Add to ``moved`` (None: nothing to count) the generalized displacement of the MuJoCo step of ``h``
        seconds just taken from the saved state: ``h`` times its mean velocity."""
        if moved is not None:
            moved += (0.5 * h) * (self._qvel0 + self.data.qvel)

    def _work(self, moved):
        """Work in joules of actuators, applied forces (``qfrc_applied``, ``xfrc_applied``), gravity
        compensation and fluid forces over the generalized displacement ``moved``, at their values in the
        last MuJoCo step taken (exact for constant forces under semi-implicit Euler at constant mass; an
        estimate where they change within the step)."""
        m, d = self.model, self.data
        qfrc = d.qfrc_actuator + d.qfrc_applied + d.qfrc_fluid
        if m.ngravcomp:
            qfrc += d.qfrc_gravcomp * (m.jnt_actgravcomp[m.dof_jntid] == 0)  # else in qfrc_actuator
        xfrc = d.xfrc_applied
        for b in np.flatnonzero(xfrc.any(axis=1)):
            mujoco.mj_applyFT(m, d, xfrc[b, :3], xfrc[b, 3:], d.xipos[b], int(b), qfrc)
        return float(qfrc @ moved)

    def _energy_report(self, energy1, base, work):
        """The energy fields of the report of a split step that ended with ``energy1`` (potential, kinetic,
        momentum).

        ``base``: (mechanical, kinetic) energy at the start of the step that was clamped (this one, or the
        one whose pieces this step goes on growing), ``work``: of external forces since then.  The energy
        added is counted from there: a soft contact gives back, as it lets go, some of the energy its
        penetration took, so a step of the ramp may end with more energy than it started with, never more
        than the clamped step started with.
        """
        added = energy1[0] + energy1[1] - base[0] - work
        scale = max(base[1], energy1[1]) + abs(work)
        return {"energy_added": added, "energy_gain": bool(added > self.energy_tolerance * scale and added > 0.0)}

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
        ellipsoids: :class:`EllipsoidSet`; default: ``fit_model(model, per=per)`` (1 cm, read from the fit cache).
        pairs, motion, max_rechecks, overshoot, contact_step, max_penetration, on_clamp, mode: as in
            :class:`GuardedStepper`.

    ``last_reports`` holds the :class:`GuardReport` of every substep of the last control step and
    ``last_unstable`` whether MuJoCo met a bad state in one of them (as in
    :class:`~mjccd.dm_control.CCDWrapper`).  As with dm-control's own stepping, a MuJoCo warning raised
    in any piece of a guarded step raises ``PhysicsError`` (unless the physics suppresses errors).
    """

    def __init__(self, env, ellipsoids=None, *, pairs=None, motion="rigid", max_rechecks=32, overshoot=1e-3,
                 contact_step=0.05, max_penetration=0.25, on_clamp=None, per="body", mode=None):
        super().__init__(env)
        physics = env.physics
        model = physics.model.ptr
        ellipsoids = fitted_or_checked(model, ellipsoids, per)
        self.stepper = GuardedStepper(model, physics.data.ptr, ellipsoids, pairs=pairs, motion=motion,
                                      max_rechecks=max_rechecks, overshoot=overshoot,
                                      contact_step=contact_step, max_penetration=max_penetration,
                                      on_clamp=on_clamp, mode=mode)
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

