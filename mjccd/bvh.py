"""BVH motion capture: parse clips, build an MJCF skeleton, convert the motion to ``qpos``.

Conventions.  A BVH joint's frame is its parent's frame moved by
``OFFSET + (position channels)`` and then turned by its rotation channels,
composed in the order they are declared (``Zrotation Yrotation Xrotation``
gives ``Rz @ Ry @ Rx`` acting on column vectors), angles in degrees.

The MJCF skeleton keeps every BVH joint frame as one MuJoCo body (same axes,
lengths times ``scale``); the root body gets a free joint, every other joint
with rotation channels a ball joint, position channels of non-root joints
become slide joints.  Only the root's free joint carries the change from the
BVH world (Y up) to MuJoCo's (Z up): BVH ``(x, y, z)`` maps to MuJoCo
``(z, x, y)``, so a T-pose facing BVH +Z faces MuJoCo +x with its left on +y.
A :class:`Placement` (yaw about +z, then a shift) puts a character in a scene.
"""
import argparse
import contextlib
import math
import numbers
import os
import re
from dataclasses import dataclass, field

import mujoco
import numpy as np

from mjccd import _command, files
from mjccd.errors import InputError, MjccdError
from mjccd.fitting import DEFAULT_TOLERANCE, Shape, ball, cover_loosened, fit_atoms, within_tolerance
from mjccd.quadric import matrix_to_quat, quat_to_matrix
from mjccd._command import PlainHelpFormatter

# CMU ASF length unit: 1/0.45 inch (about 0.0564 m).
CMU_SCALE = 0.0254 / 0.45
# BVH (Y up) -> MuJoCo (Z up): (x, y, z) -> (z, x, y), a 120 degree turn about (1, 1, 1).
Y_UP_TO_Z_UP = np.array([0.5, 0.5, 0.5, 0.5])

_AXES = {"X": np.array([1.0, 0.0, 0.0]), "Y": np.array([0.0, 1.0, 0.0]), "Z": np.array([0.0, 0.0, 1.0])}
_CHANNELS = {"Xposition", "Yposition", "Zposition", "Xrotation", "Yrotation", "Zrotation"}

# Capsule radii (metres) of the limb that starts at a joint, by joint name;
# the first matching pattern wins.  Values follow adult anthropometric girths
# (thigh ~44 cm, calf ~36 cm, upper arm ~30 cm, forearm ~26 cm circumference).
LIMB_RADII = (
    ("thumb", 0.02),
    ("handindex|fingerbase", 0.045),  # the fist: wrist to knuckles
    ("finger|index", 0.012),
    ("toe", 0.025),
    ("foot|ankle", 0.04),
    ("upleg|thigh", 0.07),
    ("leg|shin|knee|calf", 0.055),
    ("hipjoint|pelvis", 0.07),
    ("hips|root", 0.1),
    ("lowerback|spine|chest|back|torso|abdomen", 0.11),
    ("neck", 0.05),
    ("head", 0.095),
    ("shoulder|clavicle|collar", 0.05),
    ("forearm|elbow", 0.035),
    ("arm", 0.045),
    ("hand|wrist", 0.04),
)
DEFAULT_RADIUS = 0.04

# Deepest joint chain accepted: a human skeleton is about 20 deep, and MuJoCo's
# XML reader stops at about 500 nested elements.
MAX_DEPTH = 256
# Accepted metres per file unit (micrometres to kilometres) and seconds per frame.
SCALE_RANGE = (1e-6, 1e3)
FRAME_TIME_RANGE = (1e-6, 3600.0)
# Longest offset or position (metres, once scaled): far beyond any capture
# volume, far below where squared lengths overflow.
MAX_LENGTH = 1e6


class BVHError(InputError):
    """A BVH file that cannot be read; the message names the file and line."""


@dataclass
class Joint:
    """One joint of the hierarchy; ``offset`` in file units, ``channels`` as declared."""

    name: str
    parent: int
    offset: np.ndarray
    channels: tuple = ()
    end_sites: list = field(default_factory=list)
    children: list = field(default_factory=list)


@dataclass
class Clip:
    """A parsed BVH file: joints in file (depth-first) order and the frames (T, channels)."""

    joints: list
    frames: np.ndarray
    frame_time: float
    source: str = "<bvh>"

    @property
    def n_frames(self):
        return self.frames.shape[0]

    @property
    def n_channels(self):
        return self.frames.shape[1]

    def channel_start(self):
        """First column of each joint's channels in ``frames``."""
        starts, k = [], 0
        for j in self.joints:
            starts.append(k)
            k += len(j.channels)
        return starts

    def joint_index(self, name):
        for i, j in enumerate(self.joints):
            if j.name == name:
                return i
        raise ValueError(f"{self.source}: no joint named {name!r}")


@dataclass(frozen=True)
class Placement:
    """Where a character goes in the world: turn by ``yaw`` (radians, about +z), then shift."""

    shift: tuple = (0.0, 0.0, 0.0)
    yaw: float = 0.0

    def quaternion(self):
        return np.array([math.cos(self.yaw / 2), 0.0, 0.0, math.sin(self.yaw / 2)])


# ---------------------------------------------------------------- parsing


def read_bvh(path):
    """Parse the BVH file at ``path`` into a :class:`Clip`."""
    try:
        with open(path, encoding="utf-8", errors="replace") as fh:
            text = fh.read()
    except OSError as exc:
        raise BVHError(f"{path}: cannot read: {exc.strerror}") from None
    return parse_bvh(text, source=str(path))


def parse_bvh(text, source="<bvh>"):
    """Parse BVH text into a :class:`Clip`; errors name ``source`` and the line."""
    lines = text.splitlines()
    tokens = []  # (token, line number)
    motion_line = None
    for n, line in enumerate(lines, 1):
        if line.strip().upper() == "MOTION":
            motion_line = n
            break
        tokens.extend((tok, n) for tok in line.split())
    if not tokens or tokens[0][0] != "HIERARCHY":
        raise BVHError(f"{source}: line 1: expected 'HIERARCHY' at the start of the file")
    if motion_line is None:
        raise BVHError(f"{source}: no MOTION section (file truncated?)")
    joints = []
    pos = _parse_joint(tokens, 1, -1, joints, source, depth=1)
    if pos != len(tokens):
        tok, n = tokens[pos]
        raise BVHError(f"{source}: line {n}: unexpected {tok!r} after the hierarchy")
    frames, frame_time = _parse_motion(lines, motion_line, sum(len(j.channels) for j in joints), source)
    return Clip(joints, frames, frame_time, source)


def _expect(tokens, pos, want, source):
    if pos >= len(tokens):
        raise BVHError(f"{source}: hierarchy ends early, expected {want!r} (file truncated?)")
    tok, n = tokens[pos]
    if tok != want:
        raise BVHError(f"{source}: line {n}: expected {want!r}, got {tok!r}")
    return pos + 1


def _numbers(tokens, pos, count, what, source):
    if pos + count > len(tokens):
        raise BVHError(f"{source}: hierarchy ends early in {what} (file truncated?)")
    out = []
    for tok, n in tokens[pos:pos + count]:
        try:
            v = float(tok)
        except ValueError:
            raise BVHError(f"{source}: line {n}: {what}: expected a number, got {tok!r}") from None
        if not math.isfinite(v):
            raise BVHError(f"{source}: line {n}: {what}: not finite: {tok!r}")
        out.append(v)
    return out, pos + count


def _parse_joint(tokens, pos, parent, joints, source, depth):
    """Parse ROOT/JOINT name { OFFSET ... CHANNELS ... children }; returns the next position.

    ``depth`` counts the joints from the root down to this one; beyond
    :data:`MAX_DEPTH` the file is refused (no skeleton is that deep, and the
    model could not be loaded).
    """
    if pos >= len(tokens):
        raise BVHError(f"{source}: hierarchy has no ROOT (file truncated?)")
    kind, n = tokens[pos]
    if kind not in ("ROOT", "JOINT"):
        raise BVHError(f"{source}: line {n}: expected 'ROOT' or 'JOINT', got {kind!r}")
    if (kind == "ROOT") != (parent < 0):
        raise BVHError(f"{source}: line {n}: {kind} {'outside' if kind == 'JOINT' else 'inside'} the root")
    if pos + 1 >= len(tokens):
        raise BVHError(f"{source}: hierarchy ends early after {kind} (file truncated?)")
    name = tokens[pos + 1][0]
    if depth > MAX_DEPTH:
        raise BVHError(f"{source}: line {n}: joint {name!r} is {depth} joints deep; "
                       f"at most {MAX_DEPTH} are accepted")
    if any(j.name == name for j in joints):
        raise BVHError(f"{source}: line {n}: joint name {name!r} used twice")
    pos = _expect(tokens, pos + 2, "{", source)
    pos = _expect(tokens, pos, "OFFSET", source)
    offset, pos = _numbers(tokens, pos, 3, f"OFFSET of {name}", source)
    pos = _expect(tokens, pos, "CHANNELS", source)
    (count,), pos = _numbers(tokens, pos, 1, f"CHANNELS of {name}", source)
    if count != int(count) or not 0 <= count <= 6:
        raise BVHError(f"{source}: line {tokens[pos - 1][1]}: CHANNELS of {name}: bad count {count:g}")
    count = int(count)
    if pos + count > len(tokens):
        raise BVHError(f"{source}: hierarchy ends early in CHANNELS of {name} (file truncated?)")
    channels = tuple(tok for tok, _ in tokens[pos:pos + count])
    for tok, m in tokens[pos:pos + count]:
        if tok not in _CHANNELS:
            raise BVHError(f"{source}: line {m}: CHANNELS of {name}: unknown channel {tok!r}")
    if len(set(channels)) != len(channels):
        raise BVHError(f"{source}: line {n}: CHANNELS of {name}: a channel is repeated")
    pos += count
    me = len(joints)
    joint = Joint(name, parent, np.array(offset), channels)
    joints.append(joint)
    if parent >= 0:
        joints[parent].children.append(me)
    while True:
        if pos >= len(tokens):
            raise BVHError(f"{source}: hierarchy ends inside joint {name} (file truncated?)")
        tok, m = tokens[pos]
        if tok == "}":
            return pos + 1
        if tok == "JOINT":
            pos = _parse_joint(tokens, pos, me, joints, source, depth + 1)
        elif tok == "End":
            pos = _expect(tokens, pos + 1, "Site", source)
            pos = _expect(tokens, pos, "{", source)
            pos = _expect(tokens, pos, "OFFSET", source)
            off, pos = _numbers(tokens, pos, 3, f"End Site OFFSET of {name}", source)
            pos = _expect(tokens, pos, "}", source)
            joint.end_sites.append(np.array(off))
        else:
            raise BVHError(f"{source}: line {m}: expected 'JOINT', 'End Site' or '}}' in {name}, got {tok!r}")


def _parse_motion(lines, motion_line, n_channels, source):
    """Frames: N / Frame Time: dt / N lines of n_channels numbers."""
    rest = [(n, line) for n, line in enumerate(lines[motion_line:], motion_line + 1) if line.strip()]
    if len(rest) < 2:
        raise BVHError(f"{source}: MOTION section lacks 'Frames:' and 'Frame Time:' (file truncated?)")
    m = re.fullmatch(r"\s*Frames:\s*(\d+)\s*", rest[0][1])
    if not m:
        raise BVHError(f"{source}: line {rest[0][0]}: expected 'Frames: <count>', got {rest[0][1].strip()!r}")
    n_frames = int(m.group(1))
    m = re.fullmatch(r"\s*Frame Time:\s*(\S+)\s*", rest[1][1])
    try:
        frame_time = float(m.group(1)) if m else float("nan")
    except ValueError:
        frame_time = float("nan")
    if not (math.isfinite(frame_time) and frame_time > 0):
        raise BVHError(f"{source}: line {rest[1][0]}: expected 'Frame Time: <positive seconds>', "
                       f"got {rest[1][1].strip()!r}")
    low, high = FRAME_TIME_RANGE
    if not low <= frame_time <= high:
        raise BVHError(f"{source}: line {rest[1][0]}: Frame Time: {frame_time:g} s is outside "
                       f"[{low:g}, {high:g}] seconds")
    data = rest[2:]
    if len(data) < n_frames:
        raise BVHError(f"{source}: header says {n_frames} frames but only {len(data)} frame lines "
                       f"follow (file truncated?)")
    if len(data) > n_frames:
        raise BVHError(f"{source}: line {data[n_frames][0]}: header says {n_frames} frames "
                       f"but more frame lines follow")
    if n_frames == 0:
        raise BVHError(f"{source}: the clip has no frames")
    frames = np.empty((n_frames, n_channels))
    for k, (n, line) in enumerate(data):
        parts = line.split()
        if len(parts) != n_channels:
            raise BVHError(f"{source}: line {n}: frame {k} has {len(parts)} values, "
                           f"the hierarchy declares {n_channels} channels (file truncated?)")
        try:
            frames[k] = [float(p) for p in parts]
        except ValueError:
            raise BVHError(f"{source}: line {n}: frame {k}: not a number in {line.strip()[:60]!r}") from None
    if not np.all(np.isfinite(frames)):
        k = int(np.nonzero(~np.all(np.isfinite(frames), axis=1))[0][0])
        raise BVHError(f"{source}: line {data[k][0]}: frame {k} holds NaN or infinity")
    return frames, frame_time


# ---------------------------------------------------------------- quaternions


def quat_multiply(a, b):
    """Hamilton product of quaternions [w, x, y, z] (broadcast over leading axes)."""
    aw, ax, ay, az = np.moveaxis(np.asarray(a, float), -1, 0)
    bw, bx, by, bz = np.moveaxis(np.asarray(b, float), -1, 0)
    return np.stack([aw * bw - ax * bx - ay * by - az * bz,
                     aw * bx + ax * bw + ay * bz - az * by,
                     aw * by - ax * bz + ay * bw + az * bx,
                     aw * bz + ax * by - ay * bx + az * bw], axis=-1)


def quat_rotate(q, v):
    """Rotate vectors v (..., 3) by unit quaternions q (..., 4)."""
    q = np.asarray(q, float)
    u = q[..., 1:]
    w = q[..., :1]
    t = 2.0 * np.cross(u, v)
    return v + w * t + np.cross(u, t)


def euler_quaternions(angles_deg, axes):
    """Quaternions (T, 4) of rotations composed in the declared order (``"ZYX"`` -> Rz Ry Rx)."""
    q = np.zeros((angles_deg.shape[0], 4))
    q[:, 0] = 1.0
    for k, ax in enumerate(axes):
        half = np.radians(angles_deg[:, k]) / 2.0
        qk = np.zeros_like(q)
        qk[:, 0] = np.cos(half)
        qk[:, 1:] = np.sin(half)[:, None] * _AXES[ax]
        q = quat_multiply(q, qk)
    return q


def _joint_motion(clip, index, frames):
    """Position channels (T, 3) and rotation quaternions (T, 4) of one joint over the given frames."""
    j = clip.joints[index]
    start = clip.channel_start()[index]
    data = clip.frames[frames, start:start + len(j.channels)]
    shift = np.zeros((data.shape[0], 3))
    rot_cols, rot_axes = [], ""
    for k, ch in enumerate(j.channels):
        if ch.endswith("position"):
            shift[:, "XYZ".index(ch[0])] = data[:, k]
        else:
            rot_cols.append(k)
            rot_axes += ch[0]
    return shift, euler_quaternions(data[:, rot_cols], rot_axes)


# ---------------------------------------------------------------- skeleton


@dataclass(frozen=True)
class Layout:
    """How a clip maps onto a model: per joint, its qpos address (or -1 when frozen/absent)."""

    prefix: str
    scale: float
    placement: Placement
    frozen: frozenset
    reference_frame: int

    def moving(self, clip, index):
        """True when joint ``index`` gets MuJoCo joints (has channels and is not frozen)."""
        j = clip.joints[index]
        return bool(j.channels) and (index == 0 or j.name not in self.frozen)


def limb_radius(name):
    """Capsule radius in metres for the limb that starts at a joint named ``name``."""
    low = name.lower()
    for pattern, r in LIMB_RADII:
        if re.search(pattern, low):
            return r
    return DEFAULT_RADIUS


def _fmt(v):
    return " ".join(f"{x:.12g}" for x in np.atleast_1d(v))


def _sanitize(name):
    return re.sub(r"[^A-Za-z0-9_.\-]", "_", name)


def mjcf_names(clip):
    """MJCF body name of each joint: the BVH name with characters MJCF dislikes replaced by ``_``.

    Names that collide once replaced (``L#Hip`` and ``L_Hip``) stay distinct:
    the first keeps the name, later ones get ``_2``, ``_3``, ... (never a
    name another joint already has).
    """
    wanted = [_sanitize(j.name) for j in clip.joints]
    reserved = set(wanted)
    taken, names = set(), []
    for base in wanted:
        name, k = base, 2
        while name in taken or (name != base and name in reserved):
            name, k = f"{base}_{k}", k + 1
        taken.add(name)
        names.append(name)
    return names


def character_bodies(clip, layout, *, extra=None, indent="    "):
    """MJCF ``<body>`` text of one character (the root's body with everything below it).

    ``extra`` maps a joint name to more MJCF lines placed inside that joint's
    body (for instance bounding ellipsoid geoms).
    """
    extra = extra or {}
    s = layout.scale
    out = []
    ref = [layout.reference_frame]
    names = mjcf_names(clip)

    def body(index, depth):
        j = clip.joints[index]
        pad = indent * depth
        name = layout.prefix + names[index]
        if index == 0:
            pos0, quat0 = root_pose(clip, layout, ref)
            attrs = f'pos="{_fmt(pos0[0])}" quat="{_fmt(quat0[0])}"'
        else:
            shift, quat = _joint_motion(clip, index, ref)
            frozen = not layout.moving(clip, index)
            attrs = f'pos="{_fmt(s * (j.offset + (shift[0] if frozen else 0.0)))}"'
            if frozen and j.channels:
                attrs += f' quat="{_fmt(quat[0])}"'
        out.append(f'{pad}<body name="{name}" {attrs}>')
        if index == 0:
            out.append(f'{pad}{indent}<freejoint name="{name}_root"/>')
        elif layout.moving(clip, index):
            for ch in j.channels:
                if ch.endswith("position"):
                    axis = _AXES[ch[0]]
                    out.append(f'{pad}{indent}<joint name="{name}_{ch[0].lower()}" type="slide" axis="{_fmt(axis)}"/>')
            if any(ch.endswith("rotation") for ch in j.channels):
                out.append(f'{pad}{indent}<joint name="{name}" type="ball"/>')
        r = limb_radius(j.name)
        ends = [clip.joints[c].offset for c in j.children] + list(j.end_sites)
        for k, end in enumerate(ends):
            length = float(np.linalg.norm(end)) * s
            if length < 1e-6:
                continue
            out.append(f'{pad}{indent}<geom name="{name}_limb{k}" type="capsule" size="{r:.4g}" '
                       f'fromto="0 0 0 {_fmt(s * end)}" class="limb"/>')
        for line in extra.get(j.name, ()):
            out.append(f"{pad}{indent}{line}")
        for c in j.children:
            body(c, depth + 1)
        out.append(f"{pad}</body>")

    body(0, 2)
    return "\n".join(out)


def root_pose(clip, layout, frames=None):
    """World position (T, 3) and quaternion (T, 4) of the root body for the given frames."""
    frames = slice(None) if frames is None else frames
    shift, quat = _joint_motion(clip, 0, frames)
    p_bvh = layout.scale * (clip.joints[0].offset + shift)
    qp = layout.placement.quaternion()
    q_world = quat_multiply(qp, Y_UP_TO_Z_UP)
    pos = quat_rotate(np.broadcast_to(q_world, p_bvh.shape[:-1] + (4,)), p_bvh) + np.asarray(layout.placement.shift)
    quat = quat_multiply(q_world, quat)
    return pos, quat / np.linalg.norm(quat, axis=-1, keepdims=True)


def qpos_trajectory(clip, layout, frames=None):
    """``qpos`` rows (T, nq) of one character in the joint order of :func:`character_bodies`."""
    frames = np.arange(clip.n_frames) if frames is None else np.asarray(frames)
    cols = []
    pos, quat = root_pose(clip, layout, frames)
    cols += [pos, quat]

    def walk(index):
        j = clip.joints[index]
        if index != 0 and layout.moving(clip, index):
            shift, q = _joint_motion(clip, index, frames)
            for ch in j.channels:
                if ch.endswith("position"):
                    cols.append(layout.scale * shift[:, ["XYZ".index(ch[0])]])
            if any(ch.endswith("rotation") for ch in j.channels):
                cols.append(q)
        for c in j.children:
            walk(c)

    walk(0)
    return np.concatenate(cols, axis=1)


def _limb_capsules(clip, index, scale):
    """Capsules ``(p0, p1, radius)`` (metres, the joint's own frame) of the limbs starting at a joint."""
    j = clip.joints[index]
    r = limb_radius(j.name)
    ends = [clip.joints[c].offset for c in j.children] + list(j.end_sites)
    return [(np.zeros(3), scale * np.asarray(e, float), r) for e in ends
            if np.linalg.norm(e) * scale >= 1e-6]


def rigid_groups(clip, layout):
    """Capsules of each rigidly moving part: ``{joint index: [(p0, p1, r), ...]}`` in that joint's frame.

    A part is a joint that moves (the root, or a joint with MuJoCo joints)
    together with the frozen joints below it, placed at the layout's
    reference frame.
    """
    groups = {}
    ref = [layout.reference_frame]

    def walk(index, owner, R, p):
        if index == 0 or layout.moving(clip, index):
            owner, R, p = index, np.eye(3), np.zeros(3)
        caps = groups.setdefault(owner, [])
        for a, b, r in _limb_capsules(clip, index, layout.scale):
            caps.append((p + R @ a, p + R @ b, r))
        for c in clip.joints[index].children:
            if layout.moving(clip, c):
                walk(c, owner, R, p)
                continue
            shift, q = _joint_motion(clip, c, ref)
            pc = p + R @ (layout.scale * (clip.joints[c].offset + shift[0]))
            walk(c, owner, R @ quat_to_matrix(q[0]), pc)

    walk(0, 0, np.eye(3), np.zeros(3))
    return {k: v for k, v in groups.items() if v}


def fit_capsules(capsules):
    """A bounding ellipsoid ``(radii, centre, quaternion)`` that contains every capsule ``(p0, p1, radius)``.

    A capsule is the convex hull of its two end balls, so the ellipsoid of
    :func:`mjccd.fitting.fit_atoms` (containment proven) bounds it.  A
    skeleton is fitted once, offline: with a tolerance ten times finer than
    the default.  The radii get a margin of 1e-9 for the 12 digits the MJCF
    is written with.
    """
    atoms = [ball(p, r) for p0, p1, r in capsules for p in (p0, p1)]
    centre, rotation, radii = fit_atoms(atoms, tolerance=1e-5)
    return radii * (1.0 + 1e-9), centre, matrix_to_quat(rotation)


def capsule_shape(p0, p1, radius):
    """The capsule from ``p0`` to ``p1`` as a :class:`mjccd.fitting.Shape` (its axis along the local z)."""
    axis = np.asarray(p1, dtype=float) - np.asarray(p0, dtype=float)
    length = float(np.linalg.norm(axis))
    centre = (np.asarray(p0, dtype=float) + np.asarray(p1, dtype=float)) / 2
    if length == 0.0:
        return Shape("sphere", np.array([radius, 0.0, 0.0]), centre, np.eye(3))
    z = axis / length
    x = np.cross(z, [1.0, 0.0, 0.0] if abs(z[0]) < 0.9 else [0.0, 1.0, 0.0])
    x /= np.linalg.norm(x)
    return Shape("capsule", np.array([radius, length / 2, 0.0]), centre, np.c_[x, np.cross(z, x), z])


def fit_part(capsules, tolerance=DEFAULT_TOLERANCE):
    """Bounding ellipsoids ``[(radii, centre, quaternion), ...]`` of one rigid part's capsules ``(p0, p1, r)``.

    As :func:`mjccd.mujoco.fit_model` fits a body: one ellipsoid
    (:func:`fit_capsules`) when it is proven within ``tolerance`` of the
    capsules, else each capsule covered within it
    (:func:`mjccd.fitting.cover_loosened`; containment proven either way).
    ``tolerance=None``: the one ellipsoid, however loose.  The radii get a
    margin of 1e-9 for the 12 digits the MJCF is written with.
    """
    one = fit_capsules(capsules)
    if tolerance is None:
        return [one]
    shapes = [capsule_shape(*c) for c in capsules]
    radii, centre, quat = one
    if within_tolerance(centre, quat_to_matrix(quat), radii, shapes, tolerance):
        return [one]
    return [(r * (1.0 + 1e-9), c, matrix_to_quat(R))
            for shape in shapes for c, R, r in cover_loosened(shape, tolerance)[0]]


_BOUNDS = {}  # hierarchy, layout and tolerance -> bounding_geoms' lines (one skeleton's clips share their bounds)


def bounding_geoms(clip, layout, tolerance=DEFAULT_TOLERANCE):
    """MJCF lines of each rigid part's bounding ellipsoids (:func:`fit_part`), keyed by the joint whose body
    holds them: ``NAME_bound`` for a part's one ellipsoid, ``NAME_1_bound``, ``NAME_2_bound``, ... for several.

    With no frozen joint the parts depend only on the hierarchy (names, offsets, end sites, channels) and the
    layout, so the fits are kept for the next clip of the same skeleton in this process.
    """
    key = None
    if not layout.frozen:
        key = (layout, tolerance, tuple((j.name, j.parent, tuple(j.offset.tolist()), tuple(j.channels),
                                         tuple(tuple(e.tolist()) for e in j.end_sites)) for j in clip.joints))
        if key in _BOUNDS:
            return _BOUNDS[key]
    extra = {}
    names = mjcf_names(clip)
    for index, caps in rigid_groups(clip, layout).items():
        fitted = fit_part(caps, tolerance)
        base = layout.prefix + names[index]
        extra[clip.joints[index].name] = [
            f'<geom name="{base if len(fitted) == 1 else f"{base}_{k + 1}"}_bound" class="bound" '
            f'size="{_fmt(radii)}" pos="{_fmt(centre)}" quat="{_fmt(quat)}"/>'
            for k, (radii, centre, quat) in enumerate(fitted)]
    if key is not None:
        _BOUNDS[key] = extra
    return extra


def facing(clip, frames):
    """Mean heading (radians about MuJoCo +z) and mean root position (3,) over the frames, no placement."""
    layout = Layout("", 1.0, Placement(), frozenset(), 0)
    pos, quat = root_pose(clip, layout, frames)
    fwd = quat_rotate(quat, np.broadcast_to(np.array([0.0, 0.0, 1.0]), pos.shape))  # BVH +Z = forward
    heading = math.atan2(fwd[:, 1].mean(), fwd[:, 0].mean())
    return heading, pos.mean(axis=0)


def model_xml(characters, *, model_name="bvh", floor=True, extra_worldbody=()):
    """A whole MJCF document from ``[(clip, layout, extra), ...]``."""
    parts = [f'<mujoco model="{_sanitize(model_name)}">',
             '  <compiler angle="radian" inertiafromgeom="true" boundmass="1e-4" boundinertia="1e-8"/>',
             '  <option timestep="0.0083333"/>',
             "  <default>",
             '    <default class="limb">',
             '      <geom contype="0" conaffinity="0" group="1" density="1000" rgba="0.75 0.6 0.5 1"/>',
             "    </default>",
             '    <default class="bound">',
             '      <geom type="ellipsoid" contype="0" conaffinity="0" group="5" mass="0" rgba="0.3 0.5 0.9 0.35"/>',
             "    </default>",
             "  </default>",
             "  <visual>",
             '    <global offwidth="960" offheight="720"/>',
             "  </visual>",
             "  <worldbody>",
             '    <light pos="0 0 4" dir="0 0 -1" directional="true"/>']
    if floor:
        parts.append('    <geom name="floor" type="plane" size="5 5 0.1" rgba="0.85 0.85 0.85 1" contype="0" conaffinity="0"/>')
    parts.extend("    " + line for line in extra_worldbody)
    for clip, layout, extra in characters:
        parts.append(character_bodies(clip, layout, extra=extra))
    parts += ["  </worldbody>", "</mujoco>", ""]
    return "\n".join(parts)


def import_bvh(path, *, scale=CMU_SCALE, prefix="", start=0, frozen=(), bounds=False):
    """Read a BVH file; return ``(xml, qpos (T, nq), time (T), clip)`` for one character.

    ``bounds``: give each rigid part its bounding ellipsoids (:func:`bounding_geoms`, the default fit within
    1 cm, in the bounds' group), as replay needs to choose the pairs of a model.

    The model is compiled by MuJoCo before it is returned (see
    :func:`check_model`), so a clip that cannot become a working model is
    refused here, naming ``path``, rather than when the model is loaded.
    """
    low, high = SCALE_RANGE
    if not (isinstance(scale, numbers.Real) and low <= scale <= high):  # NaN fails too
        raise InputError(f"scale: metres per file unit must be in [{low:g}, {high:g}], got {scale!r}")
    clip = read_bvh(path)
    if not 0 <= start < clip.n_frames:
        raise BVHError(f"{path}: start: frame {start} outside the clip's {clip.n_frames} frames")
    length = scale * _longest(clip)
    if length > MAX_LENGTH:
        raise BVHError(f"{path}: an offset or position reaches {length:.3g} m at scale {scale:g}; "
                       f"at most {MAX_LENGTH:g} m is accepted")
    layout = Layout(prefix, float(scale), Placement(), frozenset(frozen), start)
    name = os.path.splitext(os.path.basename(str(path)))[0]
    xml = model_xml([(clip, layout, bounding_geoms(clip, layout) if bounds else None)], model_name=name)
    frames = np.arange(start, clip.n_frames)
    qpos = qpos_trajectory(clip, layout, frames)
    time = (frames - start) * clip.frame_time
    check_model(xml, qpos, str(path))
    return xml, qpos, time, clip


def _longest(clip):
    """Largest absolute offset, end-site offset or position-channel value of a clip, in file units."""
    values = [np.abs(j.offset).max() for j in clip.joints]
    values += [np.abs(e).max() for j in clip.joints for e in j.end_sites]
    starts = clip.channel_start()
    for j, first in zip(clip.joints, starts):
        for k, ch in enumerate(j.channels):
            if ch.endswith("position"):
                values.append(np.abs(clip.frames[:, first + k]).max())
    return float(max(values))


def check_model(xml, qpos, source):
    """Refuse, with a :class:`BVHError` naming ``source``, a model MuJoCo rejects or a qpos that does not fit it.

    Names the BVH file allows can still collide in MJCF (a joint called
    ``Hips_root`` beside the root's free joint); compiling is the one
    complete check.
    """
    try:
        model = mujoco.MjModel.from_xml_string(xml)
    except ValueError as exc:
        reason = " ".join(str(exc).split())
        raise BVHError(f"{source}: MuJoCo rejects the model built from this clip: {reason}") from None
    if qpos.shape[1] != model.nq:
        raise BVHError(f"{source}: the motion has {qpos.shape[1]} qpos values per frame, the model nq={model.nq}")


# ---------------------------------------------------------------- command line


def main(argv=None):
    """``mjccd import-bvh CLIP.bvh -o MODEL.xml [--traj TRAJ.npz]``; returns the exit status."""
    parser = argparse.ArgumentParser(formatter_class=PlainHelpFormatter,
                                     prog="mjccd import-bvh",
                                     description="Build an MJCF skeleton and a qpos trajectory from a BVH clip. "
                                                 "Bodies keep the joint names, with characters other than letters, "
                                                 "digits, '_', '.' and '-' replaced by '_' (and _2, _3, ... added "
                                                 "where two names would then collide).  The model is compiled by "
                                                 "MuJoCo before anything is written; both outputs appear together "
                                                 "or not at all.")
    parser.add_argument("clip", help="BVH file")
    parser.add_argument("-o", "--output", required=True, help="MJCF model to write")
    parser.add_argument("--traj", help="write the motion here as .npz (qpos T x nq, time T)")
    parser.add_argument("--scale", type=float, default=CMU_SCALE,
                        help=f"metres per file unit, {SCALE_RANGE[0]:g} to {SCALE_RANGE[1]:g} "
                             f"(default: CMU, {CMU_SCALE:.6f})")
    parser.add_argument("--start", type=int, default=0,
                        help="first frame to keep (1 drops a leading T-pose frame)")
    parser.add_argument("--force", action="store_true", help="replace existing output files")
    args = parser.parse_args(argv)
    outputs = [args.output] + ([args.traj] if args.traj else [])
    try:
        if args.traj and os.path.realpath(args.traj) == os.path.realpath(args.output):
            raise InputError(f"--traj: {args.traj} is also the -o model file; give two different names")
        xml, qpos, time, clip = import_bvh(args.clip, scale=args.scale, start=args.start)
        for path in outputs:
            files.check_output_file(path, inputs=[args.clip], force=args.force)
        # both files are renamed into place only once both are complete
        with contextlib.ExitStack() as stack:
            model_file = stack.enter_context(files.atomic_open(args.output, "w", encoding="utf-8"))
            model_file.write(xml)
            if args.traj:
                traj_file = stack.enter_context(files.atomic_open(args.traj, "wb"))
                np.savez_compressed(traj_file, qpos=qpos, time=time)
    except (MjccdError, ValueError, OSError) as exc:
        return _command.failure("import-bvh", exc, outputs)
    msg = f"{args.output}: {len(clip.joints)} joints, nq={qpos.shape[1]}"
    if args.traj:
        msg += f"; {args.traj}: {qpos.shape[0]} frames at {1.0 / clip.frame_time:.4g} Hz"
    print(msg)
    return 0
