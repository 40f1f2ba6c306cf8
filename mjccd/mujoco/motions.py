"""Simulator states and the exact motions of fitted ellipsoids between two of them."""
from dataclasses import dataclass

import mujoco
import numba
import numpy as np

from mjccd import _validate
from mjccd.errors import InputError, InputTypeError
from mjccd.scene import field, poses_may_touch, split_poses, step_kernel
from mjccd.mujoco.chains import hinge_path

MOTIONS = ("rigid", "affine", "chain")
# what poses_then_first answers instead of a pair index (-1: no contact)
STATE_NOT_FINITE = -3   # a position or velocity of the state is NaN or infinite: nothing checked
POSES_NOT_ORDINARY = -2  # a pose is not finite or not ordinary: nothing checked (the scene's own check names it)
# what fixes the body poses of an MjData: its joint positions and mocap poses (mj_getState's layout)
KINEMATIC_STATE = (mujoco.mjtState.mjSTATE_QPOS | mujoco.mjtState.mjSTATE_MOCAP_POS
                   | mujoco.mjtState.mjSTATE_MOCAP_QUAT)
MIN_NORM2 = _validate.MIN_NORM ** 2  # a quaternion whose squared norm is below this is no rotation (a bad state)


@dataclass(frozen=True)
class State:
    """What fixes body poses: joint positions, mocap poses, and the simulation time (or None)."""

    qpos: np.ndarray
    mocap_pos: np.ndarray
    mocap_quat: np.ndarray
    time: float = None


def capture(data):
    """A :class:`State` copied from an ``MjData``."""
    return State(data.qpos.copy(), data.mocap_pos.copy(), data.mocap_quat.copy(), float(data.time))


def nonfinite_error(state, name):
    """The :class:`~mjccd.errors.InputError` naming the first NaN or infinite value of ``state``'s qpos and
    mocap poses in the user's terms (``name``: the state as the caller knows it), or None when all are
    finite.  MuJoCo checks neither mocap poses nor, without contacts, what they do, so a NaN there reaches
    the check."""
    for field in ("qpos", "mocap_pos", "mocap_quat"):
        values = np.ravel(getattr(state, field))
        bad = np.flatnonzero(~np.isfinite(values))
        if len(bad):
            return InputError(f"{name}: {field}[{bad[0]}] is NaN or infinite")
    return None


def quaternion_addresses(model):
    """The qpos addresses of the free and ball joints' quaternions (4 entries each), sorted."""
    jt, adr = model.jnt_type, model.jnt_qposadr
    free = adr[jt == mujoco.mjtJoint.mjJNT_FREE] + 3
    ball = adr[jt == mujoco.mjtJoint.mjJNT_BALL]
    return np.sort(np.concatenate([free, ball])).astype(np.int64)


def zero_quaternion(qpos, mocap_quat, addresses):
    """The first quaternion shorter than ``_validate.MIN_NORM`` (no rotation: a bad state), as
    ("qpos", address) or ("mocap_quat", row); None when there is none."""
    for a in addresses.tolist():
        q = qpos[a:a + 4]
        if q.dot(q) < _validate.MIN_NORM ** 2:
            return "qpos", a
    if len(mocap_quat):
        norms = np.einsum("ij,ij->i", np.reshape(mocap_quat, (-1, 4)), np.reshape(mocap_quat, (-1, 4)))
        small = np.flatnonzero(norms < _validate.MIN_NORM ** 2)
        if len(small):
            return "mocap_quat", int(small[0])
    return None


@numba.njit(cache=True, nogil=True, no_cfunc_wrapper=True, forceinline=False)
def has_zero_quaternion(qpos, mocap_quat, addresses, min_norm2):
    """True when a quaternion of ``qpos`` (at ``addresses``) or a row of ``mocap_quat`` has a squared norm below
    ``min_norm2``: :func:`zero_quaternion`'s test as one compiled call, for the monitor's every step."""
    for a in addresses:
        if qpos[a] * qpos[a] + qpos[a + 1] * qpos[a + 1] + qpos[a + 2] * qpos[a + 2] + qpos[a + 3] * qpos[a + 3] \
                < min_norm2:
            return True
    for r in range(mocap_quat.shape[0]):
        q = mocap_quat[r]
        if q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3] < min_norm2:
            return True
    return False


def zero_quaternion_error(model, state, name):
    """The :class:`~mjccd.errors.InputError` naming a zero joint or mocap quaternion of ``state`` (``name``:
    the state as the caller knows it), or None."""
    bad = zero_quaternion(state.qpos, state.mocap_quat, quaternion_addresses(model))
    if bad is None:
        return None
    where, k = bad
    if where == "qpos":
        free = model.jnt_type == mujoco.mjtJoint.mjJNT_FREE
        joint = int(np.flatnonzero(model.jnt_qposadr + np.where(free, 3, 0) == k)[0])
        body = int(model.jnt_bodyid[joint])
        label = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_JOINT, joint)
        label = repr(label) if label else f"#{joint}"
        owner = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_BODY, body) or f"#{body}"
        return InputError(f"{name}: qpos[{k}:{k + 4}] is a zero quaternion (joint {label} of body {owner!r}): "
                          f"no rotation")
    return InputError(f"{name}: mocap_quat[{k}] is a zero quaternion: no rotation")


def as_state(model, value, field, mocap_from=None):
    """A :class:`State` from an ``MjData``, a ``State`` or a qpos vector; errors name ``field``."""
    if isinstance(value, mujoco.MjData):
        state = capture(value)
    elif isinstance(value, State):
        state = value
    else:
        try:
            qpos = np.asarray(value, dtype=float)
        except (TypeError, ValueError):
            raise InputTypeError(f"{field}: expected MjData, State or a qpos vector, got "
                                 f"{type(value).__name__}") from None
        if qpos.shape != (model.nq,):
            raise InputError(f"{field}: expected a qpos vector of length nq = {model.nq}, got shape {qpos.shape}")
        src = mocap_from
        state = State(qpos.copy(), src.mocap_pos.copy() if src is not None else model.body_pos[
            model.body_mocapid >= 0].copy(), src.mocap_quat.copy() if src is not None else
            model.body_quat[model.body_mocapid >= 0].copy(), None)
    for name in ("qpos", "mocap_pos", "mocap_quat"):
        arr = getattr(state, name)
        if not np.all(np.isfinite(arr)):
            bad = int(np.flatnonzero(~np.isfinite(np.ravel(arr)))[0])
            raise InputError(f"{field}.{name}[{bad}]: is NaN or infinite")
    if state.qpos.shape != (model.nq,):
        raise InputError(f"{field}.qpos: expected length nq = {model.nq}, got {state.qpos.shape}")
    error = zero_quaternion_error(model, state, field)
    if error is not None:
        raise error
    return state


class Kinematics:
    """Forward kinematics of states on a private ``MjData`` (the user's data is never touched)."""

    def __init__(self, model):
        self.model = model
        self.data = mujoco.MjData(model)

    def _forward(self, state):
        """The private MjData with the body poses of ``state``."""
        d = self.data
        d.qpos[:] = state.qpos
        if self.model.nmocap:
            d.mocap_pos[:] = state.mocap_pos
            d.mocap_quat[:] = state.mocap_quat
        mujoco.mj_kinematics(self.model, d)
        return d

    def body_poses(self, state):
        """World (xpos (nbody, 3), xquat (nbody, 4)) of every body in ``state``."""
        d = self._forward(state)
        return d.xpos.copy(), d.xquat.copy()

    def ellipsoid_poses(self, state, body_ids, positions, quaternions):
        """(N, 7) world poses [x, y, z, qw, qx, qy, qz] of ellipsoids fixed in bodies."""
        d = self._forward(state)
        out = np.empty((len(body_ids), 7))
        ellipsoid_poses_into(d.xpos, d.xquat, np.ascontiguousarray(body_ids, dtype=np.int64),
                             np.ascontiguousarray(positions, dtype=float),
                             np.ascontiguousarray(quaternions, dtype=float), out)
        return out


@numba.njit(cache=True, nogil=True, no_cfunc_wrapper=True, forceinline=False)
def ellipsoid_poses_into(xpos, xquat, body_ids, positions, quaternions, out):
    """Fill ``out`` (N, 7) with the world poses of ellipsoids fixed in bodies (body poses xpos, xquat).

    The one routine every path of the monitor and the guard uses, so equal
    body poses give bit-identical ellipsoid poses.
    """
    for e in range(body_ids.shape[0]):
        b = body_ids[e]
        w, x, y, z = xquat[b, 0], xquat[b, 1], xquat[b, 2], xquat[b, 3]
        vx, vy, vz = positions[e, 0], positions[e, 1], positions[e, 2]
        tx = 2.0 * (y * vz - z * vy)
        ty = 2.0 * (z * vx - x * vz)
        tz = 2.0 * (x * vy - y * vx)
        out[e, 0] = xpos[b, 0] + (vx + w * tx + (y * tz - z * ty))
        out[e, 1] = xpos[b, 1] + (vy + w * ty + (z * tx - x * tz))
        out[e, 2] = xpos[b, 2] + (vz + w * tz + (x * ty - y * tx))
        bw, bx, by, bz_ = quaternions[e, 0], quaternions[e, 1], quaternions[e, 2], quaternions[e, 3]
        qw = w * bw - x * bx - y * by - z * bz_
        qx = w * bx + x * bw + y * bz_ - z * by
        qy = w * by - x * bz_ + y * bw + z * bx
        qz = w * bz_ + x * by - y * bx + z * bw
        n = np.sqrt(qw * qw + qx * qx + qy * qy + qz * qz)
        out[e, 3] = qw / n
        out[e, 4] = qx / n
        out[e, 5] = qy / n
        out[e, 6] = qz / n


# ---------------------------------------------------------------- joint-space interpolation


def _lerp_quat(q0, q1, t):
    q1 = q1 if q0 @ q1 >= 0.0 else -q1
    q = (1.0 - t) * q0 + t * q1
    return q / np.linalg.norm(q)


def interpolate_qpos(model, qpos0, qpos1, t):
    """Joint values at time t along the path that the ``chain`` motion follows exactly.

    Hinges: ``tan(theta/2)`` linear in t (``theta = qpos - qpos0_ref``); slides:
    linear; ball and free joints: quaternion lerp (normalised) and position lerp.
    ``t`` lies in [0, 1].
    """
    q0 = _validate.vector(qpos0, model.nq, "qpos0")
    q1 = _validate.vector(qpos1, model.nq, "qpos1")
    t = _validate.time_bound(t, "t")
    out = (1.0 - t) * q0 + t * q1
    for j in range(model.njnt):
        adr = model.jnt_qposadr[j]
        kind = model.jnt_type[j]
        if kind == mujoco.mjtJoint.mjJNT_HINGE:
            ref = model.qpos0[adr]
            off, a0, a1 = hinge_path(q0[adr] - ref, q1[adr] - ref)
            tau = (1.0 - t) * np.tan(a0 / 2.0) + t * np.tan(a1 / 2.0)
            out[adr] = ref + off + 2.0 * np.arctan(tau)
        elif kind == mujoco.mjtJoint.mjJNT_BALL:
            out[adr:adr + 4] = _lerp_quat(q0[adr:adr + 4], q1[adr:adr + 4], t)
        elif kind == mujoco.mjtJoint.mjJNT_FREE:
            out[adr + 3:adr + 7] = _lerp_quat(q0[adr + 3:adr + 7], q1[adr + 3:adr + 7], t)
    return out


def geom_distance_between(model, data, geom_pairs, qpos0, qpos1, fraction, distmax=10.0):
    """The least ``mj_geomDistance`` over ``geom_pairs`` at the state ``fraction`` of the way from qpos0 to qpos1
    as MuJoCo interpolates it (``mj_differentiatePos``, ``mj_integratePos``), on ``data`` (a private MjData whose
    mocap poses the caller set); inf without pairs.  Independent of mjccd's motions: a check of its contacts."""
    velocity = np.zeros(model.nv)
    mujoco.mj_differentiatePos(model, velocity, 1.0, qpos0, qpos1)
    data.qpos[:] = qpos0
    mujoco.mj_integratePos(model, data.qpos, velocity, fraction)
    mujoco.mj_kinematics(model, data)
    return min((mujoco.mj_geomDistance(model, data, g1, g2, distmax, None) for g1, g2 in geom_pairs), default=np.inf)


@numba.njit(cache=True, nogil=True, no_cfunc_wrapper=True, forceinline=False)
def finite_state(qpos, qvel):
    """False when the sum of squares of ``qpos`` and ``qvel`` is not finite: a NaN or infinite position or
    velocity.  One sum for all: MuJoCo warns of any value above 1e10, so a sound state cannot overflow it.  The
    one test of a state's finiteness, in the compiled step calls and in :func:`mjccd.mujoco.monitor.state_finite`."""
    total = 0.0
    for v in qpos:
        total += v * v
    for v in qvel:
        total += v * v
    return np.isfinite(total)


def kinematic_state(model, data, out, qpos_only):
    """The state of ``data`` that fixes its body poses, in ``KINEMATIC_STATE``'s layout: a view of its qpos when
    ``qpos_only`` (the model has no mocap body), else written into ``out`` by ``mj_getState``."""
    if qpos_only:
        return data.qpos
    mujoco.mj_getState(model, data, out, KINEMATIC_STATE)
    return out


@numba.njit(cache=True, nogil=True, no_cfunc_wrapper=True, forceinline=False)
def poses_then_may_touch(xpos, xquat, body_ids, local, p0, p1, workspace):
    """:func:`ellipsoid_poses_into` for the end poses ``p1`` (``local`` = [positions, quaternions]),
    then :func:`mjccd.scene.poses_may_touch` of a scene's ``workspace`` (:attr:`mjccd.scene.Scene.workspace`)
    from ``p0``: the compiled part of a step check in one call."""
    ellipsoid_poses_into(xpos, xquat, body_ids, local[:, :3], local[:, 3:], p1)
    return poses_may_touch(workspace, p0, p1)


@numba.njit(cache=True, nogil=True, no_cfunc_wrapper=True, forceinline=False)
def poses_then_first(qpos, qvel, xpos, xquat, body_ids, local, p0, p1, fill, ws, iv, owner, new_only):
    """The compiled part of a monitored step in one call: the end poses, the state's test, the scene's check.

    With ``fill``, :func:`ellipsoid_poses_into` writes the end poses ``p1`` from the body poses ``xpos``,
    ``xquat`` (``local`` = [positions, quaternions]).  Then :data:`STATE_NOT_FINITE` when the sum of squares
    of ``qpos`` and ``qvel`` is not finite (as :func:`mjccd.mujoco.monitor.went_bad` tests it), else the poses
    ``p0``, ``p1`` split into the workspace ``ws`` as :meth:`mjccd.scene.Scene.first_pair` splits them
    (:data:`POSES_NOT_ORDINARY` when that cannot be done) and :func:`mjccd.scene.step_kernel`'s first contact
    (``iv``, ``owner``: its interval buffers, not written): the first pair's index, -1 when none, the
    answer in the workspace's arrays.
    """
    if fill:
        ellipsoid_poses_into(xpos, xquat, body_ids, local[:, :3], local[:, 3:], p1)
    if not finite_state(qpos, qvel):
        return STATE_NOT_FINITE
    s0, r0, s1, r1 = field(ws, "p0"), field(ws, "q0"), field(ws, "p1"), field(ws, "q1")
    if not (split_poses(p0, s0, r0) and split_poses(p1, s1, r1)):
        return POSES_NOT_ORDINARY
    best_k, _, _, _ = step_kernel(ws, s0, r0, s1, r1, iv, owner, np.bool_(False), new_only, np.bool_(False))
    return best_k
