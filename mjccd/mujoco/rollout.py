"""First contacts of many rollouts at once: MuJoCo's ``mujoco.rollout`` states (or qpos arrays) checked as a batch.

``mujoco.rollout.rollout(model, data, initial_state, control)`` answers, for each of B rollouts, the full physics
state after each of its T steps (``mjSTATE_FULLPHYSICS``): no body poses.  Here the ellipsoid poses of all
B x (T + 1) states come from MuJoCo's own forward kinematics (``mj_kinematics`` on private ``MjData``, one per
thread, written into preallocated buffers) and the adapter's pose routine
(:func:`~mjccd.mujoco.motions.ellipsoid_poses_into`, run over every state in one compiled call); then one
compiled, parallel call of :class:`mjccd.batch.BatchScene` finds each rollout's first contact, exactly as the
:class:`~mjccd.mujoco.ModelAdapter` finds it checking the steps one by one (same pairs, planes and motion).

In geoms mode (the default of :func:`first_contacts` with the rigid motion) the poses are those of the model's
own geoms (:class:`~mjccd.mujoco.geoms.GeomChecker`, same kinematics), and each rollout's steps are checked in
order by :meth:`GeomChecker.check_poses <mjccd.mujoco.geoms.GeomChecker.check_poses>`, up to its first contact,
exactly as a :class:`~mjccd.mujoco.CCDMonitor` in geoms mode checks them one by one.

The frames of rollout b are ``initial_state[b]`` (when given: the state the rollout started from) followed by
its rows; step f moves frame f to frame f + 1.  After ``mujoco.rollout`` (which records the state after each
step) step f therefore ends at row f.
"""
import re
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field
from time import perf_counter

import mujoco
import numba
import numpy as np

from mjccd.batch import BatchScene
from mjccd.errors import InputError, InputTypeError
from mjccd.scene import UNCERTAIN
from mjccd.mujoco.adapter import ModelAdapter
from mjccd.geoms.batch import geom_poses_into
from mjccd.mujoco.ellipsoids import EllipsoidSet
from mjccd.mujoco.geoms import GeomChecker
from mjccd.mujoco.monitor import check_mode, flag, selected_adapter, selected_geoms, step_count
from mjccd.mujoco.motions import ellipsoid_poses_into

FULLPHYSICS = int(mujoco.mjtState.mjSTATE_FULLPHYSICS)
_TIME = int(mujoco.mjtState.mjSTATE_TIME)
_QPOS = int(mujoco.mjtState.mjSTATE_QPOS)
_MOCAP_POS = int(mujoco.mjtState.mjSTATE_MOCAP_POS)
_MOCAP_QUAT = int(mujoco.mjtState.mjSTATE_MOCAP_QUAT)
_ALL_BITS = (1 << int(mujoco.mjtState.mjNSTATE)) - 1
STATES_PER_THREAD = 512  # the least states a kinematics thread gets (below, one thread does them faster)


def state_layout(model, spec, field="state_spec"):
    """``({component bit: slice}, size)``: where each component of a ``spec`` state vector lies in it.

    ``mj_getState`` writes the components of ``spec`` one after another in the order of their bits, each
    ``mj_stateSize(model, bit)`` long; ``size`` is ``mj_stateSize(model, spec)``.
    """
    if isinstance(spec, (bool, np.bool_)) or not isinstance(spec, (int, np.integer, mujoco.mjtState)):
        raise InputTypeError(f"{field}: expected an mjtState bit mask (an int), got {spec!r}")
    spec = int(spec)
    if spec <= 0 or spec & ~_ALL_BITS:
        raise InputError(f"{field}: expected a mask of mjtState bits within {_ALL_BITS:#x}, got {spec:#x}")
    out, at = {}, 0
    for i in range(int(mujoco.mjtState.mjNSTATE)):
        bit = 1 << i
        if spec & bit:
            n = mujoco.mj_stateSize(model, bit)
            out[bit] = slice(at, at + n)
            at += n
    return out, at


@numba.njit(cache=True, nogil=True, no_cfunc_wrapper=True, forceinline=False)
def _poses_of_states(xpos, xquat, body_ids, positions, quaternions, out):
    """``out[k]`` (N, 7): the ellipsoid poses of body poses ``xpos[k]``, ``xquat[k]`` for every state k, by the
    adapter's own routine (so bit for bit the poses it computes for each state)."""
    for k in range(xpos.shape[0]):
        ellipsoid_poses_into(xpos[k], xquat[k], body_ids, positions, quaternions, out[k])


@numba.njit(cache=True, nogil=True, no_cfunc_wrapper=True, forceinline=False)
def _geom_poses_of_states(xpos, xquat, body, local, out):
    """``out[k]`` (G, 7): the geom poses of body poses ``xpos[k]``, ``xquat[k]`` for every state k, by the
    geom checker's own routine."""
    for k in range(xpos.shape[0]):
        geom_poses_into(xpos[k], xquat[k], body, local, out[k])


@dataclass(frozen=True, eq=False)
class RolloutContacts:
    """The first contact of each of B rollouts (arrays indexed by rollout; :meth:`contact` gives one readably).

    Attributes:
        step: (B,) int64 the step of the first contact (step f moves frame f to f + 1; see the module), -1 none.
        time: (B,) simulation time of the contact in seconds (the bracket's start when uncertain), NaN none.
        fraction: (B,) the same instant as a fraction in [0, 1] of its step, NaN none.
        pair: (B,) int64 the checker's pair index (ellipsoid mode: a row of ``adapter.pairs``, or ``len(pairs)``
            plus a row of ``adapter.plane_pairs``; geoms mode: a row of ``adapter.pairs``), -1 none.
        ellipsoids: (B, 2) int64 the two ellipsoid indices ((ellipsoid, -1) for a plane), -1 none (and always
            in geoms mode).
        geoms: (B, 2) int64 in geoms mode the two MuJoCo geom ids that touch, -1 none (and always in ellipsoid
            mode).
        point: (B, 3) world contact point; NaN when none, when not separate at the step start, or uncertain
            without a known touching point.
        normal: (B, 3) unit world normal out of the first ellipsoid or geom, NaN likewise.
        adapter: the :class:`~mjccd.mujoco.ModelAdapter` (ellipsoid mode) or
            :class:`~mjccd.mujoco.geoms.GeomChecker` (geoms mode) that checked.
        uncertain: (B,) bool: the exact solver hit a limit; the contact is possible anywhere from ``time`` to
            ``time_hi`` (never read it as "no contact").
        time_hi: (B,) the end of that bracket in seconds (``time`` when certain), NaN none.
        stopped: (B,) int64 the first step over which the state's time did not advance (MuJoCo's rollout met
            a warning, e.g. a bad state it reset, and repeats its last state from there): that step and the
            later ones are not checked; -1 none (or no times in the states).
        ok: (B,) bool: False for a rollout with bad input, which is not answered (``errors`` says why).
        errors: {rollout: message naming the rollout, the array, the row and the field}.
    """

    step: np.ndarray
    time: np.ndarray
    fraction: np.ndarray
    pair: np.ndarray
    ellipsoids: np.ndarray
    point: np.ndarray
    normal: np.ndarray
    uncertain: np.ndarray
    time_hi: np.ndarray
    stopped: np.ndarray
    ok: np.ndarray
    errors: dict
    adapter: object = field(repr=False)
    # ellipsoid mode (None in geoms mode): what the adapter needs to describe a contact
    _start_poses: np.ndarray = field(repr=False)  # (B, N, 7) the poses at the start of each contact step
    _step_times: np.ndarray = field(repr=False)   # (B, 2) start and end time of each contact step
    _fraction_hi: np.ndarray = field(repr=False)  # (B,) the bracket's end as a fraction of the step
    geoms: np.ndarray = None
    _contacts: tuple = field(default=None, repr=False)  # geoms mode: each rollout's StepContact, or None

    def __len__(self):
        return len(self.step)

    @property
    def colliding(self):
        """(B,) bool: a contact (certain or possible) was found."""
        return self.step >= 0

    @property
    def free(self):
        """(B,) bool: answered, and no contact (not even a possible one)."""
        return self.ok & (self.step < 0)

    def _index(self, b):
        if isinstance(b, (bool, np.bool_)) or not isinstance(b, (int, np.integer)) or not -len(self) <= b < len(self):
            raise InputError(f"rollout: expected an index in 0..{len(self) - 1}, got {b!r}")
        return int(b) % len(self)

    def contact(self, b):
        """Rollout b's first contact as a :class:`~mjccd.mujoco.StepContact` (seconds, body names), or None."""
        b = self._index(b)
        if self.step[b] < 0:
            return None
        if self._contacts is not None:
            return self._contacts[b]
        t0, t1 = self._step_times[b].tolist()
        known = not np.isnan(self.point[b, 0])
        bracket = (float(self.fraction[b]), float(self._fraction_hi[b])) if self.uncertain[b] else None
        return self.adapter.contact(t0, t1, int(self.pair[b]), float(self.fraction[b]),
                                    self.point[b] if known else None, self.normal[b] if known else None,
                                    self._start_poses[b], bracket)

    def describe(self, b):
        """One line on rollout b: its first contact (step, time, bodies, point), no contact, or its error."""
        b = self._index(b)
        if not self.ok[b]:
            return f"rollout {b}: not checked: {self.errors[b]}"
        c = self.contact(b)
        if c is None:
            stop = f" (stopped at step {self.stopped[b]})" if self.stopped[b] >= 0 else ""
            return f"rollout {b}: no contact{stop}"
        where = "" if c.point is None else " at [" + ", ".join(f"{x:.4f}" for x in c.point) + "]"
        kind = "possible contact" if c.certainty == "uncertain" else "contact"
        return (f"rollout {b}: {kind} at step {self.step[b]}, t = {c.time:.6f} s, {c.bodies[0]} / {c.bodies[1]} "
                f"({c.status_at_start} at the step start){where}")


class RolloutChecker:
    """First contacts of batches of rollouts of one model; keeps its batch scene and buffers.

    Args:
        adapter: a :class:`~mjccd.mujoco.geoms.GeomChecker` (geoms mode: the model's own geoms, checked step by
            step as :meth:`GeomChecker.check_poses <mjccd.mujoco.geoms.GeomChecker.check_poses>` checks one), or
            a :class:`~mjccd.mujoco.ModelAdapter` with the rigid or affine motion (ellipsoid mode: its pairs,
            planes and motion are checked, as :meth:`ModelAdapter.check_poses` checks one step, in one
            compiled batch); :func:`checker_for` makes either.
        nthread: threads for the forward kinematics, each with its own ``MjData`` (MuJoCo releases the GIL
            in ``mj_kinematics``; the copies around it hold it), kept from call to call; a batch of fewer than
            ``STATES_PER_THREAD`` states per thread uses fewer threads, as handing work over costs more there.

    ``timing`` holds the seconds the last :meth:`first_contacts` spent in the kinematics (states to poses)
    and in the batched check.
    """

    def __init__(self, adapter, *, nthread=1):
        if not isinstance(adapter, (ModelAdapter, GeomChecker)):
            raise InputTypeError(f"adapter: expected a GeomChecker or a ModelAdapter, got {type(adapter).__name__}")
        self.mode = "geoms" if isinstance(adapter, GeomChecker) else "ellipsoids"
        if self.mode == "ellipsoids" and adapter.motion not in ("rigid", "affine"):
            raise InputError(f"adapter: rollouts are checked with the rigid or affine motion, the adapter's is "
                             f"{adapter.motion!r}")
        self.adapter, self.model = adapter, adapter.model
        self.nthread = step_count(nthread, "nthread")
        self._datas = [mujoco.MjData(self.model) for _ in range(self.nthread)]
        mocap = self.model.body_mocapid >= 0
        order = np.argsort(self.model.body_mocapid[mocap])
        self._mocap0 = (self.model.body_pos[mocap][order].ravel(), self.model.body_quat[mocap][order].ravel())
        for d in self._datas:
            d.mocap_pos[:] = self._mocap0[0].reshape(-1, 3)
            d.mocap_quat[:] = self._mocap0[1].reshape(-1, 4)
        if self.mode == "geoms":
            self._body_ids = np.ascontiguousarray(adapter.body, dtype=np.int64)
            self._local = np.ascontiguousarray(adapter.local, dtype=float)
        else:
            e = adapter.ellipsoids
            self._body_ids = np.ascontiguousarray(adapter.body_ids, dtype=np.int64)
            self._positions = np.ascontiguousarray(e.positions, dtype=float)
            self._quaternions = np.ascontiguousarray(e.quaternions, dtype=float)
        self._xpos = np.empty((0, self.model.nbody, 3))
        self._xquat = np.empty((0, self.model.nbody, 4))
        self._batch = None
        self._pool = None  # the kinematics threads, started on first use
        self.timing = {"kinematics": 0.0, "check": 0.0}

    # ------------------------------------------------------------ input

    def _frames(self, states, qpos, initial_state, state_spec, control, control_spec, start_time, dt):
        """``(kin (B, F, nq + 7 nmocap), times (B, F), sources)``: the kinematic state [qpos, mocap_pos,
        mocap_quat] and time of every frame; ``sources(b, f)`` names frame f of rollout b for errors."""
        m = self.model
        nq, nm = m.nq, m.nmocap
        if (states is None) == (qpos is None):
            raise InputError("states, qpos: give exactly one of them (the rows of each rollout)")
        if states is not None:
            layout, size = state_layout(m, state_spec)
            if _QPOS not in layout:
                raise InputError(f"state_spec: must include mjSTATE_QPOS, got {int(state_spec):#x}")
            rows, name, what = states, "states", f"nstate = mj_stateSize(model, state_spec) = {size}"
        else:
            layout, size = {_QPOS: slice(0, nq)}, nq
            rows, name, what = qpos, "qpos", f"nq = {nq}"
        rows = _numbers(rows, name)
        if rows.ndim != 3 or rows.shape[2] != size:
            raise InputError(f"{name}: expected shape (B, T, {size}) with {what}, got {rows.shape}")
        nb, nt = rows.shape[:2]
        first = None
        if initial_state is not None:
            first = _numbers(initial_state, "initial_state")
            if first.ndim == 1:
                first = first[None]
            if first.ndim != 2 or first.shape[1] != size or first.shape[0] not in (1, nb):
                raise InputError(f"initial_state: expected shape ({size},) or ({nb}, {size}) as one row of "
                                 f"{name}, got {np.shape(initial_state)}")
        off = 0 if first is None else 1
        nf = nt + off
        kin = np.empty((nb, nf, nq + 7 * nm))
        parts = [(_QPOS, slice(0, nq))]
        if nm:
            parts += [(_MOCAP_POS, slice(nq, nq + 3 * nm)), (_MOCAP_QUAT, slice(nq + 3 * nm, nq + 7 * nm))]
        mocap_controls = self._mocap_controls(control, control_spec, nb, nt) if nm else {}
        for bit, dst in parts:
            if bit in layout:
                kin[:, off:, dst] = rows[:, :, layout[bit]]
                if first is not None:
                    kin[:, 0, dst] = first[:, layout[bit]]
            elif bit in mocap_controls:  # row t is the state after step t, taken with control t
                kin[:, off:, dst] = mocap_controls[bit]
                if first is not None:
                    kin[:, 0, dst] = mocap_controls[bit][:, 0]
            else:  # what MuJoCo's rollout uses when the controls do not set the mocap poses
                kin[:, :, dst] = self._mocap0[0 if bit == _MOCAP_POS else 1]
        if _TIME in layout:
            times = np.empty((nb, nf))
            times[:, off:] = rows[:, :, layout[_TIME].start]
            if first is not None:
                times[:, 0] = first[:, layout[_TIME].start]
        else:
            t0 = _numbers(start_time, "start_time")
            if t0.ndim > 1 or t0.size not in (1, nb) or not np.all(np.isfinite(t0)):
                raise InputError(f"start_time: expected a finite number or {nb} of them, got {start_time!r}")
            step = m.opt.timestep if dt is None else _positive(dt, "dt")
            times = t0.reshape(-1, 1) + step * np.arange(nf)
            times = np.broadcast_to(times, (nb, nf))

        def source(b, f):
            if f < off:
                return "initial_state" if len(first) == 1 else f"initial_state[{b}]"
            return f"{name}[{b}, {f - off}]"
        return np.ascontiguousarray(kin), np.ascontiguousarray(times), source

    def _mocap_controls(self, control, control_spec, nb, nt):
        """{bit: (B, T, 3 or 4 nmocap)} of the mocap components in ``control`` (MuJoCo's rollout sets them
        before each step), broadcast over singleton rollout and step dimensions as ``mujoco.rollout`` does."""
        if control is None:
            return {}
        layout, size = state_layout(self.model, control_spec, "control_spec")
        arr = _numbers(control, "control")
        if arr.ndim != 3 or arr.shape[0] not in (1, nb) or arr.shape[1] not in (1, nt) or arr.shape[2] != size:
            raise InputError(f"control: expected shape ([{nb} or 1], [{nt} or 1], {size}) with ncontrol = "
                             f"mj_stateSize(model, control_spec), got {arr.shape}")
        return {bit: np.broadcast_to(arr[:, :, layout[bit]], (nb, nt, layout[bit].stop - layout[bit].start))
                for bit in (_MOCAP_POS, _MOCAP_QUAT) if bit in layout}

    def _bad_rollouts(self, kin, times, source):
        """{rollout: message} for every rollout with a NaN or infinite position, mocap pose or time."""
        m = self.model
        nq, nm = m.nq, m.nmocap
        bad = ~np.isfinite(kin).all(axis=2) | ~np.isfinite(times)
        errors = {}
        for b in np.flatnonzero(bad.any(axis=1)).tolist():
            f = int(np.flatnonzero(bad[b])[0])
            row = kin[b, f]
            if not np.isfinite(times[b, f]):
                what = "time"
            else:
                i = int(np.flatnonzero(~np.isfinite(row))[0])
                what = (f"qpos[{i}]" if i < nq else f"mocap_pos[{(i - nq) // 3}, {(i - nq) % 3}]"
                        if i < nq + 3 * nm else f"mocap_quat[{(i - nq - 3 * nm) // 4}, {(i - nq - 3 * nm) % 4}]")
            errors[b] = f"rollout {b}: {source(b, f)}: {what} is NaN or infinite"
        return errors

    # ------------------------------------------------------------ kinematics

    def _kinematics(self, kin, out):
        """``out`` (K, N, 7): the ellipsoid poses of the K kinematic states ``kin`` (K, nq + 7 nmocap)."""
        k = len(kin)
        if len(self._xpos) < k:
            self._xpos = np.empty((k, self.model.nbody, 3))
            self._xquat = np.empty((k, self.model.nbody, 4))
        xpos, xquat = self._xpos[:k], self._xquat[:k]
        nthread = min(self.nthread, k // STATES_PER_THREAD)
        if nthread <= 1:
            self._forward(self._datas[0], kin, xpos, xquat)
        else:
            if self._pool is None:
                self._pool = ThreadPoolExecutor(self.nthread, thread_name_prefix="mjccd-kinematics")
            cuts = np.linspace(0, k, nthread + 1).astype(int).tolist()
            jobs = [self._pool.submit(self._forward, d, kin[lo:hi], xpos[lo:hi], xquat[lo:hi])
                    for d, lo, hi in zip(self._datas, cuts[:-1], cuts[1:])]
            for job in jobs:
                job.result()
        if self.mode == "geoms":
            _geom_poses_of_states(xpos, xquat, self._body_ids, self._local, out)
        else:
            _poses_of_states(xpos, xquat, self._body_ids, self._positions, self._quaternions, out)

    def _forward(self, d, kin, xpos, xquat):
        """Body poses (xpos, xquat rows) of the kinematic states ``kin`` by ``mj_kinematics`` on ``d``."""
        m, nq = self.model, self.model.nq
        kinematics = mujoco.mj_kinematics
        dq, dx, dxq = d.qpos, d.xpos, d.xquat
        if m.nmocap == 0:
            for k in range(len(kin)):
                dq[:] = kin[k]
                kinematics(m, d)
                xpos[k] = dx
                xquat[k] = dxq
            return
        nm3 = nq + 3 * m.nmocap
        mp, mq = d.mocap_pos.reshape(-1), d.mocap_quat.reshape(-1)
        for k in range(len(kin)):
            row = kin[k]
            dq[:] = row[:nq]
            mp[:] = row[nq:nm3]
            mq[:] = row[nm3:]
            kinematics(m, d)
            xpos[k] = dx
            xquat[k] = dxq

    def poses(self, states=None, *, qpos=None, initial_state=None, state_spec=FULLPHYSICS, control=None,
              control_spec=int(mujoco.mjtState.mjSTATE_CTRL)):
        """(B, F, N, 7) ellipsoid (in geoms mode, geom) poses of every frame (arguments as in
        :meth:`first_contacts`; a frame with a NaN or infinite position gives NaN or infinite poses)."""
        kin, _, _ = self._frames(states, qpos, initial_state, state_spec, control, control_spec, 0.0, None)
        out = np.empty(kin.shape[:2] + (len(self._body_ids), 7))
        self._kinematics(kin.reshape(-1, kin.shape[2]), out.reshape(-1, len(self._body_ids), 7))
        return out

    # ------------------------------------------------------------ the check

    def _scene(self, worlds):
        """The :class:`~mjccd.batch.BatchScene` of ``worlds`` worlds with the adapter's pairs, planes and
        ``min_motion``, its plane cache empty."""
        if self._batch is None or self._batch[0] != worlds:
            a, s = self.adapter, self.adapter.scene
            npl = len(s.plane_pairs)
            batch = BatchScene(a.radii, worlds, pairs=a.pairs, motion=a.motion, planes=s.planes if npl else None,
                               plane_pairs=s.plane_pairs if npl else None)
            if np.any(s.min_motion):
                batch.set_min_motion(s.min_motion)
            if npl and np.any(s.plane_min_motion):
                batch.set_plane_min_motion(s.plane_min_motion)
            self._batch = (worlds, batch)
        batch = self._batch[1]
        batch.reset_cache()
        return batch

    def first_contacts(self, states=None, *, qpos=None, initial_state=None, state_spec=FULLPHYSICS, control=None,
                       control_spec=int(mujoco.mjtState.mjSTATE_CTRL), start_time=0.0, dt=None,
                       new_contacts_only=False):
        """The first contact of every rollout: :class:`RolloutContacts`.

        Args:
            states: (B, T, nstate) states in the ``state_spec`` layout, e.g. the first output of
                ``mujoco.rollout.rollout`` (``mjSTATE_FULLPHYSICS``, the state after each step).
            qpos: (B, T, nq) joint positions instead of ``states``.
            initial_state: the frame before the rows (one row of ``states`` or ``qpos``, or B of them): the
                rollouts' ``initial_state``; None: the first row starts the first step.
            state_spec: the ``mjtState`` components of each state row.
            control, control_spec: the controls given to ``mujoco.rollout`` (([B or 1], [T or 1], ncontrol)),
                read only for the mocap poses when ``control_spec`` sets them and the states do not hold them
                (row t, the state after step t, takes control t's; the initial state control 0's); else mocap
                bodies stay at the model's poses, as MuJoCo's rollout keeps them.
            start_time: when the states hold no time (qpos, or no ``mjSTATE_TIME``): the time of frame 0, one
                number or one per rollout; frame f is at ``start_time + f * dt``.
            dt: the time between frames then (default ``model.opt.timestep``).
            new_contacts_only: leave out pairs touching or overlapping at the start of a step (as the
                monitor's ``report_overlapping=False``).

        A rollout with a NaN or infinite position, mocap pose or time is not answered (``ok`` False, its
        message in ``errors``); the others are.  Wrong shapes raise :class:`~mjccd.errors.InputError`.
        """
        new_only = flag(new_contacts_only, "new_contacts_only")
        tick = perf_counter()
        kin, times, source = self._frames(states, qpos, initial_state, state_spec, control, control_spec,
                                          start_time, dt)
        nb, nf = kin.shape[:2]
        errors = self._bad_rollouts(kin, times, source)
        n = len(self._body_ids)
        poses = np.empty((nb, nf, n, 7))
        if errors:  # not answered: a harmless copy of the model's reference pose in their place
            reference = np.concatenate([self.model.qpos0, *self._mocap0])
            kin[list(errors)] = reference
        self._kinematics(kin.reshape(-1, kin.shape[2]), poses.reshape(-1, n, 7))
        stopped = np.full(nb, -1, dtype=np.int64)
        if nf > 1:
            still = times[:, 1:] <= times[:, :-1]
            for b in np.flatnonzero(still.any(axis=1)).tolist():
                if b not in errors:
                    f = int(np.argmax(still[b]))
                    stopped[b] = f
                    poses[b, f + 1:] = poses[b, f]  # no motion from there: nothing new can touch
        tock = perf_counter()
        if self.mode == "geoms":
            answer = self._geom_answer(poses, times, stopped, errors, new_only)
            self.timing = {"kinematics": tock - tick, "check": perf_counter() - tock}
            return answer
        found = self._check(poses, new_only)
        self.timing = {"kinematics": tock - tick, "check": perf_counter() - tock}
        if found is not None:  # poses the batch refused though the states were finite: the frame named
            for b in np.flatnonzero(~found.ok).tolist():
                message = found.errors.get(b, "its ellipsoid poses are not finite")
                where = re.match(rf"poses\[{b}\]\[(\d+)\]", message)
                errors.setdefault(b, f"rollout {b}: " + (message if where is None else
                                  f"{source(b, int(where.group(1)))}{message[where.end():]}"))
        return self._answer(found, poses, times, stopped, errors, new_only)

    def _check(self, poses, new_only):
        """The :class:`~mjccd.batch.BatchContacts` of ``poses`` (B, F, N, 7); None when nothing is checked."""
        nb, nf = poses.shape[:2]
        a = self.adapter
        if nb == 0 or nf < 2 or a.scene is None:
            return None
        return self._scene(nb).first_contacts_along(poses, new_contacts_only=new_only)

    def _first_along(self, poses, times, start, stopped, new_only):
        """``(step, StepContact)`` of one rollout's first contact from step ``start`` on, each step checked in
        order as the monitor checks one (the checker's ``check_poses``), up to the step where its time stopped
        (``stopped``, -1: none); None when there is none."""
        last = len(times) - 1 if stopped < 0 else int(stopped)
        for f in range(start, last):
            first = self.adapter.check_poses(float(times[f]), float(times[f + 1]), poses[f], poses[f + 1],
                                             new_only=new_only).first
            if first is not None:
                return f, first
        return None

    def _geom_answer(self, poses, times, stopped, errors, new_only):
        """The :class:`RolloutContacts` of geoms mode: each answered rollout's steps checked in order up to its
        first contact (a rollout whose time stopped, up to the step where it did)."""
        nb = len(poses)
        checker = self.adapter
        found = [None if b in errors else self._first_along(poses[b], times[b], 0, stopped[b], new_only)
                 for b in range(nb)]
        step = np.full(nb, -1, dtype=np.int64)
        pair = np.full(nb, -1, dtype=np.int64)
        geoms = np.full((nb, 2), -1, dtype=np.int64)
        time, time_hi, fraction = np.full(nb, np.nan), np.full(nb, np.nan), np.full(nb, np.nan)
        point, normal = np.full((nb, 3), np.nan), np.full((nb, 3), np.nan)
        uncertain = np.zeros(nb, dtype=bool)
        contacts = [None] * nb
        for b, hit in enumerate(found):
            if hit is None:
                continue
            f, c = hit
            contacts[b] = c
            step[b], pair[b], geoms[b] = f, c.pair, c.geoms
            time[b], fraction[b] = c.time, c.fraction
            uncertain[b] = c.certainty == "uncertain"
            time_hi[b] = c.bracket[1] if uncertain[b] else c.time
            if c.point is not None:
                point[b], normal[b] = c.point, c.normal
        ok = np.array([b not in errors for b in range(nb)], dtype=bool)
        return RolloutContacts(step, time, fraction, pair, np.full((nb, 2), -1, dtype=np.int64), point, normal,
                               uncertain, time_hi, stopped, ok, errors, checker, None, None, None, geoms,
                               tuple(contacts))

    def _answer(self, found, poses, times, stopped, errors, new_only):
        """The :class:`RolloutContacts` of a batch answer; a rollout whose first contact the batch left uncertain
        is checked again from that step on as the monitor checks a step (:meth:`ModelAdapter.check_poses
        <mjccd.mujoco.ModelAdapter.check_poses>`: the undecided pairs asked of the core's exact tiers)."""
        nb = len(poses)
        a = self.adapter
        step = np.full(nb, -1, dtype=np.int64)
        pair = np.full(nb, -1, dtype=np.int64)
        fraction, fraction_hi = np.full(nb, np.nan), np.full(nb, np.nan)
        point, normal = np.full((nb, 3), np.nan), np.full((nb, 3), np.nan)
        uncertain = np.zeros(nb, dtype=bool)
        ok = np.ones(nb, dtype=bool)
        if found is not None:
            hit = (found.frame >= 0) & found.ok
            step[hit], pair[hit] = found.frame[hit], found.pair[hit]
            fraction[hit], fraction_hi[hit] = found.time[hit], found.time_hi[hit]
            uncertain[hit] = found.outcome[hit] == UNCERTAIN
            # as Scene.first_contact: no point at t = 0 or when uncertain, unless the solver gave one
            known = hit & found.normal.any(axis=1) | hit & (found.time > 0.0) & ~uncertain
            point[known], normal[known] = found.point[known], found.normal[known]
        for b in np.flatnonzero(uncertain).tolist():
            step[b], pair[b], fraction[b], fraction_hi[b], uncertain[b] = -1, -1, np.nan, np.nan, False
            point[b] = normal[b] = np.nan
            hit = self._first_along(poses[b], times[b], int(found.frame[b]), stopped[b], new_only)
            if hit is None:
                continue
            f, c = hit
            step[b], pair[b], fraction[b] = f, c.pair, c.fraction
            uncertain[b] = c.certainty == "uncertain"
            t0, t1 = float(times[b, f]), float(times[b, f + 1])
            span = t1 - t0 if t1 > t0 else self.model.opt.timestep
            fraction_hi[b] = (c.bracket[1] - t0) / span if uncertain[b] else c.fraction
            if c.point is not None:
                point[b], normal[b] = c.point, c.normal
        for b in errors:
            ok[b] = False
            step[b] = pair[b] = -1
            fraction[b] = fraction_hi[b] = np.nan
            point[b] = normal[b] = np.nan
            uncertain[b] = False
        rows = np.flatnonzero(step >= 0)
        ellipsoids = np.full((nb, 2), -1, dtype=np.int64)
        npairs = len(a.pairs)
        for b in rows.tolist():
            k = int(pair[b])
            ellipsoids[b] = a.pairs[k] if k < npairs else (a.plane_pairs[k - npairs, 0], -1)
        starts = np.zeros((nb, len(self._body_ids), 7))
        step_times = np.full((nb, 2), np.nan)
        starts[rows] = poses[rows, step[rows]]
        step_times[rows, 0] = times[rows, step[rows]]
        step_times[rows, 1] = times[rows, step[rows] + 1]
        t0, t1 = step_times[:, 0], step_times[:, 1]
        span = np.where(t1 > t0, t1 - t0, self.model.opt.timestep)
        with np.errstate(invalid="ignore"):
            seconds, seconds_hi = t0 + fraction * span, t0 + fraction_hi * span
        return RolloutContacts(step, seconds, fraction, pair, ellipsoids, point, normal, uncertain, seconds_hi,
                               stopped, ok, errors, a, starts, step_times, fraction_hi,
                               np.full((nb, 2), -1, dtype=np.int64))


def adapter_for(model, ellipsoids, *, pairs=None, motion="rigid", planes=True):
    """The :class:`~mjccd.mujoco.ModelAdapter` a :class:`~mjccd.mujoco.CCDMonitor` of these arguments checks
    with: ``pairs`` as :func:`~mjccd.mujoco.pairs.select_pairs` reads them (default MuJoCo's collision rules),
    and with ``planes`` the static planes MuJoCo collides with the ellipsoids' geoms (each geom it cannot check
    warned about once, as is a selection that leaves no pair)."""
    if not isinstance(model, mujoco.MjModel):
        raise InputTypeError(f"model: expected a mujoco.MjModel or a ModelAdapter, got {type(model).__name__}")
    if not isinstance(ellipsoids, EllipsoidSet):
        raise InputTypeError(f"ellipsoids: expected an EllipsoidSet (e.g. mjccd.mujoco.fit_model(model)), "
                             f"got {type(ellipsoids).__name__}")
    return selected_adapter(model, ellipsoids, pairs, motion, flag(planes, "planes"))


def checker_for(model, ellipsoids, *, pairs=None, motion="rigid", planes=True, mode=None):
    """What a :class:`~mjccd.mujoco.CCDMonitor` of these arguments checks with, for a :class:`RolloutChecker`:
    in geoms mode (``mode=None`` with the rigid motion, or ``"geoms"``) a
    :class:`~mjccd.mujoco.geoms.GeomChecker` of the model's own geoms, in ellipsoid mode the
    :class:`~mjccd.mujoco.ModelAdapter` of :func:`adapter_for`."""
    if check_mode(mode, motion) == "ellipsoids":
        return adapter_for(model, ellipsoids, pairs=pairs, motion=motion, planes=planes)
    if not isinstance(model, mujoco.MjModel):
        raise InputTypeError(f"model: expected a mujoco.MjModel, got {type(model).__name__}")
    if ellipsoids is not None and not isinstance(ellipsoids, EllipsoidSet):
        raise InputTypeError(f"ellipsoids: expected an EllipsoidSet (e.g. mjccd.mujoco.fit_model(model)) or None, "
                             f"got {type(ellipsoids).__name__}")
    return selected_geoms(model, ellipsoids, pairs, flag(planes, "planes"), stacklevel=2)


def first_contacts(model_or_adapter, states=None, *, qpos=None, initial_state=None, ellipsoids=None, pairs=None,
                   planes=True, motion="rigid", mode=None, nthread=1, **options):
    """The first contact of every rollout (:class:`RolloutContacts`): :meth:`RolloutChecker.first_contacts`
    once.

    Args:
        model_or_adapter: a :class:`~mjccd.mujoco.geoms.GeomChecker` or :class:`~mjccd.mujoco.ModelAdapter`,
            or an ``MjModel`` with ``ellipsoids`` (:class:`~mjccd.mujoco.EllipsoidSet`), ``pairs``,
            ``planes``, ``motion`` and ``mode`` as for :class:`~mjccd.mujoco.CCDMonitor` (default: the
            model's own geoms, MuJoCo's collision rules, static planes included; :func:`checker_for`).
        states, qpos, initial_state: the rollouts, as in :meth:`RolloutChecker.first_contacts`, whose other
            keyword arguments ``options`` passes on.
        nthread: threads for the kinematics.

    To check batch after batch, keep a :class:`RolloutChecker` (it keeps its compiled scene and buffers).
    """
    if isinstance(model_or_adapter, (ModelAdapter, GeomChecker)):
        if ellipsoids is not None or pairs is not None or mode is not None:
            raise InputError("ellipsoids, pairs, mode: given by the adapter; pass them with a model instead")
        adapter = model_or_adapter
    else:
        adapter = checker_for(model_or_adapter, ellipsoids, pairs=pairs, motion=motion, planes=planes, mode=mode)
    return RolloutChecker(adapter, nthread=nthread).first_contacts(states, qpos=qpos, initial_state=initial_state,
                                                                   **options)


def _numbers(value, field):
    """``value`` as a float64 array; anything that is not numbers is refused naming ``field``."""
    try:
        arr = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError):
        raise InputTypeError(f"{field}: expected an array of numbers, got {type(value).__name__}") from None
    return arr


def _positive(value, field):
    """A finite number > 0."""
    try:
        x = float(value)
    except (TypeError, ValueError):
        raise InputTypeError(f"{field}: expected a number > 0, got {value!r}") from None
    if not np.isfinite(x) or x <= 0.0:
        raise InputError(f"{field}: expected a finite number > 0, got {value!r}")
    return x
