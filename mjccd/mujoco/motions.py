"""Simulator states and the exact motions of fitted ellipsoids between two of them."""
from dataclasses import dataclass

import mujoco
import numba
import numpy as np

from mjccd import _validate
from mjccd import bernstein as bz
from mjccd.errors import InputError, InputTypeError
from mjccd.filters import relative_sweep
from mjccd.motion import Affine, Ball, Chain, Fixed, Free, Hinge, Rigid, Static, w_of_translation
from mjccd.quadric import static_status_pose

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


@numba.njit(cache=True, nogil=True)
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


@numba.njit(cache=True, nogil=True)
def _support(radii, pose, e, nx, ny, nz):
    """Support value sqrt(sum_k (r_k (R[:, k] . n))^2) of ellipsoid e (centred) in direction n."""
    w, x, y, z = pose[e, 3], pose[e, 4], pose[e, 5], pose[e, 6]
    # columns of the rotation matrix of (w, x, y, z), dotted with n
    c0 = (1.0 - 2.0 * (y * y + z * z)) * nx + 2.0 * (x * y + w * z) * ny + 2.0 * (x * z - w * y) * nz
    c1 = 2.0 * (x * y - w * z) * nx + (1.0 - 2.0 * (x * x + z * z)) * ny + 2.0 * (y * z + w * x) * nz
    c2 = 2.0 * (x * z + w * y) * nx + 2.0 * (y * z - w * x) * ny + (1.0 - 2.0 * (x * x + y * y)) * nz
    a = radii[e, 0] * c0
    b = radii[e, 1] * c1
    c = radii[e, 2] * c2
    return np.sqrt(a * a + b * b + c * c)


@numba.njit(cache=True, nogil=True)
def _swept_support(affine, radii, rmax, p0, p1, e, nx, ny, nz):
    """Upper bound, over the whole step, of ellipsoid e's support in direction n (about its centre)."""
    same = True
    for m in range(3, 7):
        if p0[e, m] != p1[e, m]:
            same = False
    if not same:
        same = True
        for m in range(3, 7):
            if p0[e, m] != -p1[e, m]:
                same = False
    if same:  # constant orientation: exact support
        return _support(radii, p0, e, nx, ny, nz)
    if affine:  # the shape matrix is lerped: its support is convex in t
        return max(_support(radii, p0, e, nx, ny, nz), _support(radii, p1, e, nx, ny, nz))
    return rmax[e]


@numba.njit(cache=True, nogil=True)
def _slab_clear(affine, radii, rmax, p0, p1, i, j, nx, ny, nz, tol):
    """True when the plane family normal to n separates ellipsoids i and j during the whole step.

    The centre gap along n is linear in t (centres are lerped), so its minimum is
    at an end; it must exceed both supports' bounds over the step.
    """
    g0 = (p0[j, 0] - p0[i, 0]) * nx + (p0[j, 1] - p0[i, 1]) * ny + (p0[j, 2] - p0[i, 2]) * nz
    g1 = (p1[j, 0] - p1[i, 0]) * nx + (p1[j, 1] - p1[i, 1]) * ny + (p1[j, 2] - p1[i, 2]) * nz
    if g0 < 0.0:
        g0, g1, nx, ny, nz = -g0, -g1, -nx, -ny, -nz
    gap = min(g0, g1)
    if gap <= tol:
        return False
    return gap - _swept_support(affine, radii, rmax, p0, p1, i, nx, ny, nz) \
        - _swept_support(affine, radii, rmax, p0, p1, j, nx, ny, nz) > tol


@numba.njit(cache=True, nogil=True)
def _thin_axis(radii, pose, e):
    """World direction of ellipsoid e's shortest semi-axis."""
    k = 0
    if radii[e, 1] < radii[e, k]:
        k = 1
    if radii[e, 2] < radii[e, k]:
        k = 2
    w, x, y, z = pose[e, 3], pose[e, 4], pose[e, 5], pose[e, 6]
    if k == 0:
        return 1.0 - 2.0 * (y * y + z * z), 2.0 * (x * y + w * z), 2.0 * (x * z - w * y)
    if k == 1:
        return 2.0 * (x * y - w * z), 1.0 - 2.0 * (x * x + z * z), 2.0 * (y * z + w * x)
    return 2.0 * (x * z + w * y), 2.0 * (y * z - w * x), 1.0 - 2.0 * (x * x + y * y)


@numba.njit(cache=True, nogil=True)
def _in_contact_at_start(radii, p0, i, j):
    """Static status of pair (i, j) at t = 0 is touching or overlapping, decided exactly as
    :meth:`mjccd.scene.Scene.step` decides it (same normalisation of the quaternions, same test)."""
    na = np.sqrt(p0[i, 3] ** 2 + p0[i, 4] ** 2 + p0[i, 5] ** 2 + p0[i, 6] ** 2)
    nb = np.sqrt(p0[j, 3] ** 2 + p0[j, 4] ** 2 + p0[j, 5] ** 2 + p0[j, 6] ** 2)
    pa = (p0[i, 0], p0[i, 1], p0[i, 2])  # tuples: nothing allocated
    pb = (p0[j, 0], p0[j, 1], p0[j, 2])
    qa = (p0[i, 3] / na, p0[i, 4] / na, p0[i, 5] / na, p0[i, 6] / na)
    qb = (p0[j, 3] / nb, p0[j, 4] / nb, p0[j, 5] / nb, p0[j, 6] / nb)
    return static_status_pose(radii[i], pa, qa, radii[j], pb, qb) <= 0


@numba.njit(cache=True, nogil=True)
def pairs_may_touch(affine, radii, rmax, p0, p1, pairs, min_motion):
    """False only when no pair can make a new contact during the step (poses p0 -> p1, centres lerped).

    A pair whose relative motion stays below ``min_motion[k]`` is left out, as
    the exact check leaves it out (:func:`mjccd.filters.relative_sweep`).

    Per pair: the swept bounding spheres (radius = largest semi-axis), then
    planes normal to the centre line (at both ends) and to each ellipsoid's
    thinnest axis, with support bounds that hold over the whole step: a pair
    cleared by these has no contact at any t in [0, 1].  Last, a pair already
    touching or overlapping at t = 0 is no new contact (the exact static
    test, as the batched check runs it).  So whatever the exact check of new
    contacts would find, it finds nothing for a cleared pair.
    """
    for k in range(pairs.shape[0]):
        i = pairs[k, 0]
        j = pairs[k, 1]
        if min_motion[k] > 0.0 and relative_sweep(p0[i, :3], p1[i, :3], p0[i, 3:], p1[i, 3:], rmax[i],
                                                  p0[j, :3], p1[j, :3], p0[j, 3:], p1[j, 3:], rmax[j]) < min_motion[k]:
            continue
        scale = rmax[i] + rmax[j]
        tol = 1e-9 * scale
        # swept spheres: |d0 + t v| > reach on [0, 1]
        d0x, d0y, d0z = p0[j, 0] - p0[i, 0], p0[j, 1] - p0[i, 1], p0[j, 2] - p0[i, 2]
        vx, vy, vz = p1[j, 0] - p1[i, 0] - d0x, p1[j, 1] - p1[i, 1] - d0y, p1[j, 2] - p1[i, 2] - d0z
        reach = scale * (1.0 + 1e-9)
        a = vx * vx + vy * vy + vz * vz
        b = 2.0 * (d0x * vx + d0y * vy + d0z * vz)
        c = d0x * d0x + d0y * d0y + d0z * d0z - reach * reach
        if c > 0.0:
            if b >= 0.0 or a == 0.0:
                continue
            tm = -b / (2.0 * a)
            if tm >= 1.0:
                if a + b + c > 0.0:
                    continue
            elif c - b * b / (4.0 * a) > 0.0:
                continue
        # planes
        n0 = np.sqrt(d0x * d0x + d0y * d0y + d0z * d0z)
        if n0 > 0.0 and _slab_clear(affine, radii, rmax, p0, p1, i, j, d0x / n0, d0y / n0, d0z / n0, tol):
            continue
        e1x, e1y, e1z = d0x + vx, d0y + vy, d0z + vz
        n1 = np.sqrt(e1x * e1x + e1y * e1y + e1z * e1z)
        if n1 > 0.0 and _slab_clear(affine, radii, rmax, p0, p1, i, j, e1x / n1, e1y / n1, e1z / n1, tol):
            continue
        ax, ay, az = _thin_axis(radii, p0, i)
        if _slab_clear(affine, radii, rmax, p0, p1, i, j, ax, ay, az, tol):
            continue
        ax, ay, az = _thin_axis(radii, p0, j)
        if _slab_clear(affine, radii, rmax, p0, p1, i, j, ax, ay, az, tol):
            continue
        if _in_contact_at_start(radii, p0, i, j):
            continue
        return True
    return False


# ---------------------------------------------------------------- joint-space interpolation


def _hinge_path(a0, a1):
    """(offset, angle0, angle1): a hinge goes from a0 to a1 as offset + 2 atan(lerp of tan(angle/2))."""
    if abs(a0) < np.pi and abs(a1) < np.pi:
        return 0.0, a0, a1
    if abs(a1 - a0) >= np.pi:
        raise InputError(f"hinge turns by {a1 - a0:.6g} rad in one step; the chain motion needs less than pi")
    return a0, 0.0, a1 - a0


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


def body_path(model, body):
    """The bodies from ``body`` up to (not including) the world: the body, its parent, ... ."""
    path = []
    while body > 0:
        path.append(int(body))
        body = model.body_parentid[body]
    return path


def _body_elements(model, body, state0, state1, poses0, poses1):
    """Chain elements from the world down to a body's frame."""
    elements = []
    for b in reversed(body_path(model, body)):
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
                except InputError as exc:
                    name = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_JOINT, j) or f"#{j}"
                    raise InputError(f"joint {name!r}: {exc}") from None
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
    if not isinstance(motion, str) or motion not in MOTIONS:
        raise InputError(f"motion: expected one of {', '.join(MOTIONS)}, got {motion!r}")
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


@numba.njit(cache=True, nogil=True)
def poses_then_may_touch(xpos, xquat, body_ids, local, radii, rmax, p0, p1, pairs, min_motion, affine):
    """:func:`ellipsoid_poses_into` for the end poses ``p1`` (``local`` = [positions, quaternions]),
    then :func:`pairs_may_touch` from ``p0``: the compiled part of a step check in one call."""
    ellipsoid_poses_into(xpos, xquat, body_ids, local[:, :3], local[:, 3:], p1)
    return pairs_may_touch(affine, radii, rmax, p0, p1, pairs, min_motion)
