"""Geoms mode's lean step check: the first contact of each simulator step the monitor takes, in one compiled call.

A monitored step of a small model costs MuJoCo a few tens of microseconds, so what the monitor adds must be
about that: no state copies, no second kinematics of a state already seen, no Python pass over the pairs.
:class:`GeomSteps` keeps the geoms' poses of the last state it saw (the start of the next step), reads the
body poses of the end state (the data's own when the step left them current, else forward kinematics on a
private ``MjData``), and :func:`poses_then_pairs` writes the end poses, tests the state, checks every pair
(:func:`mjccd.geoms.batch.step_pairs`) and tallies the answers (:func:`mjccd.geoms.batch.tally`).  The
answers are those of :meth:`GeomChecker.check_poses <mjccd.mujoco.geoms.GeomChecker.check_poses>` on the same
poses, bit for bit: the same kernels in the same order.
"""
import mujoco
import numpy as np

from mjccd.geoms import batch as gb
from mjccd.geoms import kernel as kn
from mjccd.geoms.poly import jit
from mjccd.geoms.solve import workspaces
from mjccd.mujoco.motions import (KINEMATIC_STATE, MIN_NORM2, STATE_NOT_FINITE, State, finite_state,
                                  has_zero_quaternion, kinematic_state, quaternion_addresses)

POSES_NOT_FINITE = -4  # a geom pose is not finite: nothing checked (the caller names the bad value)
POSES_ONLY = -5  # the poses are written and sound, no pair checked (asked for: every pair's contact is wanted)
ZERO_QUATERNION = -6  # a joint or mocap quaternion of the end state is zero (no rotation): a bad state


@jit
def poses_then_pairs(qpos, qvel, mocap_quat, quaternions, xpos, xquat, body, local, Q0, Q1, check, kinds, sizes,
                     pairs, min_motion, new_only, W, I, Wdd, Idd, CON, SYS, SYSR, N, out, counts):
    """The compiled part of a monitored step in geoms mode: the end poses Q1 (G, 7) from the body poses
    ``xpos``, ``xquat`` (each geom's ``body`` and ``local`` pose), then :data:`STATE_NOT_FINITE` when the sum of
    squares of ``qpos`` and ``qvel`` is not finite, :data:`ZERO_QUATERNION` when a quaternion of ``qpos`` (at
    the addresses ``quaternions``) or of ``mocap_quat`` is (:func:`~mjccd.mujoco.motions.has_zero_quaternion`),
    :data:`POSES_NOT_FINITE` when a pose of Q0 or Q1 is not finite, :data:`POSES_ONLY` without ``check``, else
    every pair's first contact up to the earliest (:func:`mjccd.geoms.batch.step_pairs` into ``out``) and
    :func:`mjccd.geoms.batch.tally`'s answer: the first contact's row, -1 when none, or
    :data:`mjccd.geoms.batch.NEEDS_SOLVER` (``counts``: its tallies)."""
    gb.geom_poses_into(xpos, xquat, body, local, Q1)
    if not finite_state(qpos, qvel):
        return STATE_NOT_FINITE
    if has_zero_quaternion(qpos, mocap_quat, quaternions, MIN_NORM2):
        return ZERO_QUATERNION
    for g in range(Q0.shape[0]):
        for i in range(7):
            if not (np.isfinite(Q0[g, i]) and np.isfinite(Q1[g, i])):
                return POSES_NOT_FINITE
    if not check:
        return POSES_ONLY
    gb.step_pairs(kinds, sizes, Q0, Q1, pairs, min_motion, 1.0, False, new_only, W, I, Wdd, Idd, CON, SYS, SYSR,
                  N, out)
    return gb.tally(out, new_only, counts)


class GeomSteps:
    """The geom poses at both ends of the monitor's steps, kept from one step to the next (module docstring).

    ``begin(data)`` before a step records its start (the poses of the last end reused when the state is the
    same), ``end(data, bodies_current, new_only)`` after it runs the check; ``poses`` are the two (G, 7) arrays
    of the last step (internal buffers).
    """

    def __init__(self, checker):
        m = checker.model
        self.checker, self.model = checker, m
        n = len(checker.geom_ids)
        self._qpos_only = m.nmocap == 0  # the kinematic state is then qpos alone: no mj_getState
        self._key = np.empty(mujoco.mj_stateSize(m, KINEMATIC_STATE))
        self._private = mujoco.MjData(m)
        self._private_views = (self._private.qpos, self._private.xpos, self._private.xquat)
        self._keys = [None, None]  # the state bytes whose poses each slot holds
        self._slots = [np.empty((n, 7)), np.empty((n, 7))]
        self._start = self._end = 0
        self._out = np.empty((len(checker.pairs), kn.OUT))
        self._counts = np.empty(len(gb.TALLIES), dtype=np.int64)
        self._quaternions = quaternion_addresses(m)  # the qpos addresses of the free and ball joints' quaternions
        self._views_of, self._views = None, None

    def _views_for(self, data):
        """(qpos, qvel, mocap_quat, xpos, xquat) of ``data`` (MjData arrays are views of its memory: fetched once
        per data)."""
        if data is not self._views_of:
            self._views = (data.qpos, data.qvel, data.mocap_quat, data.xpos, data.xquat)
            self._views_of = data
        return self._views

    def _body_poses(self, state):
        """The private data's body poses after its kinematics in the kinematic ``state``."""
        qpos, xpos, xquat = self._private_views
        if self._qpos_only:
            qpos[:] = state
        else:
            mujoco.mj_setState(self.model, self._private, state, KINEMATIC_STATE)
        mujoco.mj_kinematics(self.model, self._private)
        return xpos, xquat

    def begin(self, data):
        """Record the state of ``data`` as the start of a step (its geom poses computed unless last seen): True
        when it is the end state of the last step checked (already tested there)."""
        state = kinematic_state(self.model, data, self._key, self._qpos_only)
        kb = state.tobytes()
        if self._keys[self._end] == kb:
            self._start = self._end
            return True
        if self._keys[self._start] == kb:
            return False
        idx = 1 - self._end
        xpos, xquat = self._body_poses(state)
        c = self.checker
        gb.geom_poses_into(xpos, xquat, c.body, c.local, self._slots[idx])
        self._keys[idx] = kb
        self._start = idx
        return False

    def end(self, data, bodies_current=False, new_only=False, check=True):
        """Record the state of ``data`` as the end of the step begun last and check the step (its first contact;
        without ``check`` only the end poses): the answer of :func:`poses_then_pairs` (the rows and tallies in
        :attr:`answers`).  ``bodies_current``: ``data``'s body poses are those of its state (read instead of
        computed)."""
        qpos, qvel, mocap_quat, xpos, xquat = self._views_for(data)
        state = kinematic_state(self.model, data, self._key, self._qpos_only)
        kb = state.tobytes()
        if not bodies_current:
            xpos, xquat = self._body_poses(state)
        idx = 1 - self._start
        self._keys[idx] = None  # until its poses are written
        c = self.checker
        answer = poses_then_pairs(qpos, qvel, mocap_quat, self._quaternions, xpos, xquat, c.body, c.local,
                                  self._slots[self._start], self._slots[idx], check, c.kinds, c.sizes, c.pairs,
                                  c.min_motion, new_only, *workspaces(), self._out, self._counts)
        self._keys[idx] = kb
        self._end = idx
        return answer

    def forget(self):
        """Drop the poses kept (after a bad state or a reset of the data)."""
        self._keys = [None, None]

    @property
    def poses(self):
        """(start, end) (G, 7) geom poses of the last step (internal buffers: copy to keep)."""
        return self._slots[self._start], self._slots[self._end]

    @property
    def answers(self):
        """(out, counts): the rows and tallies of the last :meth:`end` (internal buffers)."""
        return self._out, self._counts

    def states(self, data):
        """(start, end) :class:`~mjccd.mujoco.State` of the last step (the start from its recorded bytes, the end
        from ``data``): what an error about a bad value names."""
        nq, nm = self.model.nq, self.model.nmocap
        key = np.frombuffer(self._keys[self._start], dtype=float)
        start = State(key[:nq].copy(), key[nq:nq + 3 * nm].reshape(nm, 3).copy(),
                      key[nq + 3 * nm:].reshape(nm, 4).copy())
        end = State(data.qpos.copy(), data.mocap_pos.copy(), data.mocap_quat.copy(), float(data.time))
        return start, end
