"""Simulator states and the exact motions of fitted ellipsoids between two of them."""
from dataclasses import dataclass

import mujoco
import numpy as np

from mjccd import bernstein as bz
from mjccd.motion import Affine, Ball, Chain, Fixed, Free, Hinge, Rigid, Static, w_of_translation

MOTIONS = ("rigid", "affine", "chain")


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
            raise ValueError(f"{field}: expected MjData, State or a qpos vector, got "
                             f"{type(value).__name__}") from None
        if qpos.shape != (model.nq,):
            raise ValueError(f"{field}: expected a qpos vector of length nq = {model.nq}, got shape {qpos.shape}")
        src = mocap_from
        state = State(qpos.copy(), src.mocap_pos.copy() if src is not None else model.body_pos[
            model.body_mocapid >= 0].copy(), src.mocap_quat.copy() if src is not None else
            model.body_quat[model.body_mocapid >= 0].copy(), None)
    for name in ("qpos", "mocap_pos", "mocap_quat"):
        arr = getattr(state, name)
        if not np.all(np.isfinite(arr)):
            bad = int(np.flatnonzero(~np.isfinite(np.ravel(arr)))[0])
            raise ValueError(f"{field}.{name}[{bad}]: is NaN or infinite")
    if state.qpos.shape != (model.nq,):
        raise ValueError(f"{field}.qpos: expected length nq = {model.nq}, got {state.qpos.shape}")
    return state


def quat_mul(a, b):
    """Row-wise quaternion products (..., 4) [w, x, y, z]."""
    aw, ax, ay, az = np.moveaxis(a, -1, 0)
    bw, bx, by, bz_ = np.moveaxis(b, -1, 0)
    return np.stack([aw * bw - ax * bx - ay * by - az * bz_,
                     aw * bx + ax * bw + ay * bz_ - az * by,
                     aw * by - ax * bz_ + ay * bw + az * bx,
                     aw * bz_ + ax * by - ay * bx + az * bw], axis=-1)


def quat_rotate(q, v):
    """Rotate vectors v (..., 3) by unit quaternions q (..., 4)."""
    w = q[..., :1]
    u = q[..., 1:]
    t = 2.0 * np.cross(u, v)
    return v + w * t + np.cross(u, t)


class Kinematics:
    """Forward kinematics of states on a private ``MjData`` (the user's data is never touched)."""

    def __init__(self, model):
        self.model = model
        self.data = mujoco.MjData(model)

    def body_poses(self, state):
        """World (xpos (nbody, 3), xquat (nbody, 4)) of every body in ``state``."""
        d = self.data
        d.qpos[:] = state.qpos
        if self.model.nmocap:
            d.mocap_pos[:] = state.mocap_pos
            d.mocap_quat[:] = state.mocap_quat
        mujoco.mj_kinematics(self.model, d)
        return d.xpos.copy(), d.xquat.copy()

    def ellipsoid_poses(self, state, body_ids, positions, quaternions):
        """(N, 7) world poses [x, y, z, qw, qx, qy, qz] of ellipsoids fixed in bodies."""
        xpos, xquat = self.body_poses(state)
        qb = xquat[body_ids]
        out = np.empty((len(body_ids), 7))
        out[:, :3] = xpos[body_ids] + quat_rotate(qb, positions)
        q = quat_mul(qb, quaternions)
        out[:, 3:] = q / np.linalg.norm(q, axis=1)[:, None]
        return out


# ---------------------------------------------------------------- joint-space interpolation


def _hinge_path(a0, a1):
    """(offset, angle0, angle1): a hinge goes from a0 to a1 as offset + 2 atan(lerp of tan(angle/2))."""
    if abs(a0) < np.pi and abs(a1) < np.pi:
        return 0.0, a0, a1
    if abs(a1 - a0) >= np.pi:
        raise ValueError(f"hinge turns by {a1 - a0:.6g} rad in one step; the chain motion needs less than pi")
    return a0, 0.0, a1 - a0


def _lerp_quat(q0, q1, t):
    q1 = q1 if q0 @ q1 >= 0.0 else -q1
    q = (1.0 - t) * q0 + t * q1
    return q / np.linalg.norm(q)


def interpolate_qpos(model, qpos0, qpos1, t):
    """Joint values at time t along the path that the ``chain`` motion follows exactly.

    Hinges: ``tan(theta/2)`` linear in t (``theta = qpos - qpos0_ref``); slides:
    linear; ball and free joints: quaternion lerp (normalised) and position lerp.
    """
    q0 = np.asarray(qpos0, float)
    q1 = np.asarray(qpos1, float)
    out = (1.0 - t) * q0 + t * q1
    for j in range(model.njnt):
        adr = model.jnt_qposadr[j]
        kind = model.jnt_type[j]
        if kind == mujoco.mjtJoint.mjJNT_HINGE:
            ref = model.qpos0[adr]
            off, a0, a1 = _hinge_path(q0[adr] - ref, q1[adr] - ref)
            tau = (1.0 - t) * np.tan(a0 / 2.0) + t * np.tan(a1 / 2.0)
            out[adr] = ref + off + 2.0 * np.arctan(tau)
        elif kind == mujoco.mjtJoint.mjJNT_BALL:
            out[adr:adr + 4] = _lerp_quat(q0[adr:adr + 4], q1[adr:adr + 4], t)
        elif kind == mujoco.mjtJoint.mjJNT_FREE:
            out[adr + 3:adr + 7] = _lerp_quat(q0[adr + 3:adr + 7], q1[adr + 3:adr + 7], t)
    return out


class _Slide:
    """Slide-joint chain element: translation ``s(t) axis``, s linear from s0 to s1."""

    def __init__(self, axis, s0, s1):
        self.axis = np.asarray(axis, float) / np.linalg.norm(axis)
        self.s0, self.s1 = float(s0), float(s1)

    def w(self):
        return w_of_translation(np.ascontiguousarray(np.stack([self.axis * self.s0, self.axis * self.s1], axis=1)))


def _body_elements(model, body, state0, state1, poses0, poses1):
    """Chain elements from the world down to a body's frame."""
    path = []
    b = body
    while b != 0:
        path.append(b)
        b = model.body_parentid[b]
    elements = []
    for b in reversed(path):
        mocap = model.body_mocapid[b]
        if mocap >= 0:
            elements = [Free(poses0[0][b], poses0[1][b], poses1[0][b], poses1[1][b])]
            continue
        jnts = range(model.body_jntadr[b], model.body_jntadr[b] + model.body_jntnum[b])
        if any(model.jnt_type[j] == mujoco.mjtJoint.mjJNT_FREE for j in jnts):
            adr = model.jnt_qposadr[jnts[0]]
            elements = [Free(state0.qpos[adr:adr + 3], state0.qpos[adr + 3:adr + 7],
                             state1.qpos[adr:adr + 3], state1.qpos[adr + 3:adr + 7])]
            continue
        elements.append(Fixed(model.body_pos[b], model.body_quat[b]))
        for j in jnts:
            adr = model.jnt_qposadr[j]
            kind = model.jnt_type[j]
            anchor = model.jnt_pos[j]
            if kind == mujoco.mjtJoint.mjJNT_SLIDE:
                ref = model.qpos0[adr]
                elements.append(_Slide(model.jnt_axis[j], state0.qpos[adr] - ref, state1.qpos[adr] - ref))
                continue
            if kind == mujoco.mjtJoint.mjJNT_HINGE:
                ref = model.qpos0[adr]
                try:
                    off, a0, a1 = _hinge_path(state0.qpos[adr] - ref, state1.qpos[adr] - ref)
                except ValueError as exc:
                    name = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_JOINT, j) or f"#{j}"
                    raise ValueError(f"joint {name!r}: {exc}") from None
                turn = [Fixed(np.zeros(3), np.r_[np.cos(off / 2), np.sin(off / 2) * model.jnt_axis[j]])] \
                    if off else []
                rot = turn + [Hinge(model.jnt_axis[j], a0, a1)]
            else:
                rot = [Ball(state0.qpos[adr:adr + 4], state1.qpos[adr:adr + 4])]
            elements += [Fixed(anchor)] + rot + [Fixed(-anchor)]
    return elements


def motions_between(model, ellipsoids, state0, state1, motion="rigid", *, body_ids=None, kinematics=None):
    """One mjccd motion per ellipsoid from state0 (t = 0) to state1 (t = 1).

    Args:
        model: ``mujoco.MjModel``.
        ellipsoids: :class:`~mjccd.mujoco.EllipsoidSet`.
        state0, state1: ``MjData``, :class:`State` or qpos vectors.
        motion: "rigid" (per-ellipsoid pose lerp), "affine" (centre and shape
            matrix lerp) or "chain" (joint-space interpolation down the tree).
    """
    if motion not in MOTIONS:
        raise ValueError(f"motion: expected one of {', '.join(MOTIONS)}, got {motion!r}")
    s0 = as_state(model, state0, "state_t0")
    s1 = as_state(model, state1, "state_t1")
    kin = kinematics or Kinematics(model)
    ids = ellipsoids.body_ids(model) if body_ids is None else body_ids
    if motion == "chain":
        poses0, poses1 = kin.body_poses(s0), kin.body_poses(s1)
        out = []
        for b, p, q in zip(ids, ellipsoids.positions, ellipsoids.quaternions):
            elements = _body_elements(model, int(b), s0, s1, poses0, poses1)
            out.append(Chain(elements + [Fixed(p, q)]) if elements else Static(p, q))
        return out
    e0 = kin.ellipsoid_poses(s0, ids, ellipsoids.positions, ellipsoids.quaternions)
    e1 = kin.ellipsoid_poses(s1, ids, ellipsoids.positions, ellipsoids.quaternions)
    cls = Rigid if motion == "rigid" else Affine
    return [cls(a[:3], a[3:], b[:3], b[3:]) for a, b in zip(e0, e1)]


def sweep_sphere(motion):
    """(centre, radius) of a ball holding the centre path of a chain motion, or None if unknown.

    The centre of the moving frame is ``-G^T h / g^2`` (scaled inverse W); with
    positive denominator coefficients this rational Bezier curve stays in the
    convex hull of its control points.
    """
    w = getattr(motion, "_w", None)
    if w is None:
        return None
    G, h, g = w
    num = []
    for i in range(3):
        acc = None
        for k in range(3):
            term = bz.multiply(G[k, i].copy(), h[k].copy())
            acc = term if acc is None else acc + term
        num.append(-acc)
    den = bz.multiply(g.copy(), g.copy())
    deg = max(len(num[0]), len(den)) - 1
    den = bz.elevate(den, deg + 1 - len(den))
    if np.any(den <= 0.0):
        return None
    ctrl = np.stack([bz.elevate(n.copy(), deg + 1 - len(n)) for n in num], axis=1) / den[:, None]
    centre = 0.5 * (ctrl.min(axis=0) + ctrl.max(axis=0))
    return centre, float(np.sqrt(np.max(np.sum((ctrl - centre) ** 2, axis=1))))
