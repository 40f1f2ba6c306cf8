"""Chain motions of fitted ellipsoids: each ellipsoid's joints from the world down, read once from the model.

A :class:`ChainLayout` holds, for every ellipsoid, the elements that place it
in the world, as one :class:`mjccd.chain_bounds.ChainProgram`.  Its joints
read a *joint value vector* (:meth:`ChainLayout.values`): ``qpos`` with every
hinge and slide measured from its reference (``qpos - qpos0``, as MuJoCo's
kinematics measures it), then each mocap body's position and quaternion.  The
exact motions (:meth:`ChainLayout.motion`) and the chain filters both read this
one description, so they describe the same motion, and at t = 0 and t = 1 it is
MuJoCo's forward kinematics:

* a body's frame is its parent's moved by ``body_pos``, ``body_quat``, then by
  each of its joints in order, a hinge about its anchor (``jnt_pos``), a slide
  along its axis, a ball about its anchor;
* a free joint or a mocap body sets the body's world pose outright.

In between, hinges follow tan(theta/2) linear in t, slides are linear, ball
and free rotations are quaternion lerps (see :class:`mjccd.Chain`).
"""
import mujoco
import numpy as np

from mjccd import chain_bounds as cb
from mjccd.errors import InputError
from mjccd.motion import Ball, Chain, Fixed, Free, Hinge, Slide, Static

_KINDS = {int(mujoco.mjtJoint.mjJNT_HINGE): cb.HINGE, int(mujoco.mjtJoint.mjJNT_SLIDE): cb.SLIDE,
          int(mujoco.mjtJoint.mjJNT_BALL): cb.BALL, int(mujoco.mjtJoint.mjJNT_FREE): cb.FREE}
_IDENTITY = (1.0, 0.0, 0.0, 0.0)
_ORIGIN = (0.0, 0.0, 0.0)


def body_path(model, body):
    """The bodies from ``body`` up to (not including) the world: the body, its parent, ... ."""
    path = []
    while body > 0:
        path.append(int(body))
        body = model.body_parentid[body]
    return path


def hinge_path(a0, a1):
    """(offset, angle0, angle1): a hinge goes from a0 to a1 as offset + 2 atan(lerp of tan(angle/2)).

    Angles inside (-pi, pi) need no offset; otherwise the turn is taken about a0, which needs
    ``|a1 - a0| < pi``.
    """
    if abs(a0) < np.pi and abs(a1) < np.pi:
        return 0.0, a0, a1
    if abs(a1 - a0) >= np.pi:
        raise InputError(f"hinge turns by {a1 - a0:.6g} rad in one step; the chain motion needs less than pi")
    return a0, 0.0, a1 - a0


def _body_elements(model, body):
    """(kind, vec, quat, adr) rows from the world down to the frame of ``body`` (value addresses as in
    :meth:`ChainLayout.values`)."""
    rows = []
    for b in reversed(body_path(model, body)):
        mocap = int(model.body_mocapid[b])
        if mocap >= 0:
            rows = [(cb.FREE, _ORIGIN, _IDENTITY, model.nq + 7 * mocap)]
            continue
        joints = range(model.body_jntadr[b], model.body_jntadr[b] + model.body_jntnum[b])
        if any(model.jnt_type[j] == mujoco.mjtJoint.mjJNT_FREE for j in joints):
            rows = [(cb.FREE, _ORIGIN, _IDENTITY, int(model.jnt_qposadr[joints[0]]))]
            continue
        rows.append((cb.FIXED, model.body_pos[b], model.body_quat[b], 0))
        for j in joints:
            kind = _KINDS[int(model.jnt_type[j])]
            adr = int(model.jnt_qposadr[j])
            if kind == cb.SLIDE:
                rows.append((cb.SLIDE, model.jnt_axis[j], _IDENTITY, adr))
                continue
            anchor = model.jnt_pos[j]
            rows += [(cb.FIXED, anchor, _IDENTITY, 0), (kind, model.jnt_axis[j], _IDENTITY, adr),
                     (cb.FIXED, -anchor, _IDENTITY, 0)]
    return rows


class ChainLayout:
    """The chains of ellipsoids fixed in bodies (``body_ids``, local ``positions`` and ``quaternions``).

    Attributes:
        program: the :class:`mjccd.chain_bounds.ChainProgram` of all the chains (the filters' input).
    """

    def __init__(self, model, body_ids, positions, quaternions):
        self.model = model
        build = cb.ProgramBuilder()
        for b, p, q in zip(body_ids, positions, quaternions):
            for kind, vec, quat, adr in _body_elements(model, int(b)):
                if kind == cb.FIXED:
                    build.fixed(vec, quat)
                else:
                    build.joint(kind, adr, vec)
            build.fixed(p, q)
            build.end()
        self.program = build.program()
        hinge = model.jnt_type == mujoco.mjtJoint.mjJNT_HINGE
        measured = hinge | (model.jnt_type == mujoco.mjtJoint.mjJNT_SLIDE)
        self._measured = model.jnt_qposadr[measured].astype(np.int64)  # values taken from their reference
        self._hinges = model.jnt_qposadr[hinge].astype(np.int64)
        self._hinge_ids = np.flatnonzero(hinge)

    def values(self, state):
        """The joint value vector of ``state`` (anything with ``qpos``, ``mocap_pos``, ``mocap_quat``)."""
        m = self.model
        v = np.empty(m.nq + 7 * m.nmocap)
        v[:m.nq] = state.qpos
        v[self._measured] -= m.qpos0[self._measured]
        if m.nmocap:
            mocap = v[m.nq:].reshape(m.nmocap, 7)
            mocap[:, :3] = state.mocap_pos
            mocap[:, 3:] = state.mocap_quat
        return v

    def check_turns(self, v0, v1):
        """Refuse a step that the chain motion cannot follow (see :func:`hinge_path`); the error names the joint."""
        for j, a in zip(self._hinge_ids, self._hinges):
            try:
                hinge_path(v0[a], v1[a])
            except InputError as exc:
                name = mujoco.mj_id2name(self.model, mujoco.mjtObj.mjOBJ_JOINT, int(j)) or f"#{j}"
                raise InputError(f"joint {name!r}: {exc}") from None

    def motion(self, e, v0, v1):
        """The exact motion of ellipsoid ``e`` from joint values ``v0`` (t = 0) to ``v1`` (t = 1)."""
        p = self.program
        elements = []
        for m in range(p.start[e], p.start[e + 1]):
            kind, vec, a = p.kind[m], p.vec[m], p.adr[m]
            if kind == cb.FIXED:
                elements.append(Fixed(vec, p.quat[m]))
            elif kind == cb.HINGE:
                off, a0, a1 = hinge_path(v0[a], v1[a])
                if off:
                    elements.append(Fixed(_ORIGIN, np.r_[np.cos(off / 2), np.sin(off / 2) * vec]))
                elements.append(Hinge(vec, a0, a1))
            elif kind == cb.SLIDE:
                elements.append(Slide(vec, v0[a], v1[a]))
            elif kind == cb.BALL:
                elements.append(Ball(v0[a:a + 4], v1[a:a + 4]))
            else:
                elements.append(Free(v0[a:a + 3], v0[a + 3:a + 7], v1[a:a + 3], v1[a + 3:a + 7]))
        if len(elements) == 1 and isinstance(elements[0], Fixed):  # an ellipsoid of the world body
            return Static(elements[0].position, elements[0].quaternion)
        return Chain(elements)
