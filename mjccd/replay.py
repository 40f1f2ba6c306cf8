"""Trajectory replay: move a MuJoCo model's bounding ellipsoids along recorded ``qpos`` and find contacts.

Between two consecutive frames every bounding ellipsoid follows the chosen
motion model (``rigid``: centre and quaternion lerp; ``affine``: centre and
shape-matrix lerp; ``chain``: the joints of its kinematic chain, hinge angles
with tan(theta/2) linear), and every pair is checked exactly over the frame
interval.  The bounding ellipsoids are the model's ellipsoid geoms in geom
group 5 (all ellipsoid geoms when group 5 has none).  By default a pair is
checked when its two ellipsoids hang under different top-level bodies and at
least one of them moves.

Inputs are checked before any work: a bad model or trajectory stops with a
:class:`ReplayError` naming the file and the problem.  The frames run in
chunks; Ctrl-C is acted on between chunks, never inside compiled code.

Outputs: a table of first contacts, ``contacts.json``, ``contacts.csv``,
``timeline.png`` and, where an OpenGL backend works, a few rendered frames,
written all-or-nothing into an :class:`mjccd.files.OutputFolder`.
"""
import argparse
import csv
import json
import math
import os
import pathlib
import sys
import time as _time
import zipfile
import zlib
from contextlib import contextmanager
from dataclasses import dataclass, field

import numpy as np

from mjccd import interrupts
from mjccd.errors import InputError, MjccdError, OutputError
from mjccd.files import OutputFolder

MOTIONS = ("rigid", "affine", "chain")
BOUND_GROUP = 5  # the group mjccd.fit writes its ellipsoids to
# filter counters, summed over the frames (the fields of mjccd.scene.FrameCounters)
COUNTER_NAMES = ("pairs", "sphere_culled", "cached_plane", "new_plane", "overlapping_t0", "solved_exactly",
                 "colliding", "pruned", "uncertain")
OUTPUT_PATTERNS = ("contacts.json", "contacts.csv", "timeline.png", "frame_*.png")  # every file replay writes
# frame intervals per chunk of compiled work (Ctrl-C and the progress bar act between chunks): a few
# milliseconds of scene kernels, or one frame of the much slower chain motion
CHUNK_FRAMES = {"rigid": 64, "affine": 64, "chain": 1}
NPZ_ARRAYS = ("qpos", "time", "keyframes")  # the arrays a trajectory .npz may hold
RADIUS_RANGE = (1e-6, 1e6)   # metres; semi-axes outside it overflow or lose all precision in the solver
COORDINATE_LIMIT = 1e6   # largest |qpos| value and ellipsoid centre coordinate (metres), for the same reason
TIME_LIMIT = 1e12        # largest |time| in seconds
MIN_QUATERNION_NORM = 1e-12  # shorter joint quaternions are refused (MuJoCo would make them the identity)


class ReplayError(InputError):
    """Bad replay input: the message names the file or field and what is wrong."""


# ---------------------------------------------------------------- model and trajectory


@dataclass
class Bounds:
    """The bounding ellipsoids of a model and the pairs to check."""

    geom_ids: np.ndarray          # (N,) MuJoCo geom ids
    names: list                   # (N,) geom names
    body_names: list              # (N,) names of the bodies holding them
    labels: list                  # (N,) body name, or geom name when the body holds several
    radii: np.ndarray             # (N, 3)
    pairs: np.ndarray             # (P, 2) indices into the N ellipsoids


def _reason(exc):
    """The first line of an exception's message, or its type when it has none."""
    text = str(exc).strip()
    return text.splitlines()[0] if text else type(exc).__name__


@contextmanager
def _mujoco_warnings():
    """Collect MuJoCo's warnings instead of letting it append them to MUJOCO_LOG.TXT in the working folder."""
    import mujoco

    previous = mujoco.get_mju_user_warning()
    caught = []
    mujoco.set_mju_user_warning(caught.append)
    try:
        yield caught
    finally:
        mujoco.set_mju_user_warning(previous)


def load_model(model_path):
    """Compile an MJCF file; errors name the file, then give MuJoCo's message; its warnings go to stderr."""
    import mujoco

    path = pathlib.Path(model_path)
    if path.is_dir():
        raise ReplayError(f"{model_path}: is a folder, expected an MJCF model file")
    if not path.is_file():
        raise ReplayError(f"{model_path}: model file not found")
    with _mujoco_warnings() as warned:
        try:
            model = mujoco.MjModel.from_xml_path(str(path))
        except ValueError as exc:
            message = " ".join(line.strip() for line in str(exc).splitlines() if line.strip()) or "cannot compile"
            raise ReplayError(f"{model_path}: not a valid MJCF model: {message}") from None
    for message in warned:
        print(f"{model_path}: MuJoCo warning: {message}", file=sys.stderr)
    return model


def bounding_ellipsoids(model, pairs=None, source="model"):
    """The model's bounding ellipsoids and the pairs to check (see the module docstring).

    ``source`` (the model file) starts the error messages.
    """
    import mujoco

    ell = model.geom_type == mujoco.mjtGeom.mjGEOM_ELLIPSOID
    ids = np.nonzero(ell & (model.geom_group == BOUND_GROUP))[0]
    if len(ids) == 0:
        ids = np.nonzero(ell)[0]
    if len(ids) < 2:
        raise ReplayError(f"{source}: needs at least two ellipsoid geoms to check, found {len(ids)}")
    names = [model.geom(g).name or f"geom{g}" for g in ids]
    radii = model.geom_size[ids].copy()
    low, high = RADIUS_RANGE
    bad = np.nonzero(~np.all((radii >= low) & (radii <= high), axis=1))[0]  # NaN fails too
    if len(bad):
        raise ReplayError(f"{source}: ellipsoid {names[bad[0]]!r} has semi-axes {radii[bad[0]].tolist()}; "
                          f"replay supports {low:g} to {high:g} m")
    bodies = model.geom_bodyid[ids]
    body_names = [model.body(b).name or f"body{b}" for b in bodies]
    if pairs is None:
        top = model.body_rootid[bodies]
        moving = _moves(model, bodies)
        pairs = [(a, b) for a in range(len(ids)) for b in range(a + 1, len(ids))
                 if top[a] != top[b] and (moving[a] or moving[b])]
        if not pairs:
            raise ReplayError(f"{source}: no pair of ellipsoids under different top-level bodies that moves")
    labels = [body if body_names.count(body) == 1 else name.removesuffix("_bound")
              for name, body in zip(names, body_names)]
    pairs = np.asarray(pairs, dtype=np.int64).reshape(-1, 2)
    if pairs.size and (pairs.min() < 0 or pairs.max() >= len(ids) or np.any(pairs[:, 0] == pairs[:, 1])):
        raise ReplayError(f"pairs: indices must be distinct and within 0..{len(ids) - 1}")
    return Bounds(ids, names, body_names, labels, radii, pairs)


def _moves(model, bodies):
    """Whether each body has a joint on its path to the world."""
    out = []
    for b in bodies:
        moving = False
        while b > 0 and not moving:
            moving = model.body_jntnum[b] > 0
            b = model.body_parentid[b]
        out.append(bool(moving))
    return np.array(out)


def load_trajectory(traj, model):
    """``(qpos (T, nq), time (T))`` from an .npz (qpos, time) or a .bvh clip made for this model.

    Refuses, naming the file and the frame, what MuJoCo would silently change
    (a zero joint quaternion) and what the solver cannot use (NaN, infinity,
    values beyond :data:`COORDINATE_LIMIT`, complex numbers); ``time``, when
    given, must increase.
    """
    path = _input_file(traj, "trajectory")
    suffix = path.suffix.lower()
    if suffix == ".bvh":
        from mjccd import bvh

        _, qpos, time, _ = bvh.import_bvh(path)
    elif suffix == ".npz":
        arrays = read_npz(path)
        qpos, time = arrays["qpos"], arrays.get("time")
    else:
        raise ReplayError(f"{traj}: unknown trajectory type {path.suffix!r} (expected .npz or .bvh)")
    qpos = check_qpos(qpos, model, traj)
    if time is None:
        time = np.arange(qpos.shape[0]) * model.opt.timestep
    return qpos, _check_time(time, qpos.shape[0], traj)


def load_keyframes(traj, model):
    """The ``keyframes`` (K >= 2, nq) of a trajectory .npz, checked like ``qpos`` (for ``--intervals``)."""
    path = _input_file(traj, "trajectory")
    arrays = read_npz(path) if path.suffix.lower() == ".npz" else {}
    if "keyframes" not in arrays:
        raise ReplayError(f"{traj}: --intervals needs an .npz with a 'keyframes' array (K x nq)")
    return check_qpos(arrays["keyframes"], model, traj, "keyframes")


def _input_file(name, what):
    """The path of an existing input file; a folder or a missing file raises ReplayError naming it."""
    path = pathlib.Path(name)
    if path.is_dir():
        raise ReplayError(f"{name}: is a folder, expected a {what} file")
    if not path.is_file():
        raise ReplayError(f"{name}: {what} file not found")
    return path


def read_npz(path):
    """The arrays of a trajectory .npz by name; a file that is not one, or unknown arrays, raise ReplayError."""
    expected = "expected an .npz archive (a zip of .npy arrays) with 'qpos' and 'time'"
    try:
        with open(path, "rb") as fh:
            head = fh.read(6)
    except OSError as exc:
        raise ReplayError(f"{path}: cannot read: {exc.strerror}") from None
    if not head:
        raise ReplayError(f"{path}: empty file, {expected}")
    if head == b"\x93NUMPY":
        raise ReplayError(f"{path}: holds a single .npy array, {expected}")
    if not head.startswith(b"PK"):
        raise ReplayError(f"{path}: not a zip file, {expected}")
    try:
        with np.load(path, allow_pickle=False) as data:
            names = sorted(data.files)
            if "qpos" not in names:
                raise ReplayError(f"{path}: no 'qpos' array (has {names})")
            extra = [n for n in names if n not in NPZ_ARRAYS]
            if extra:
                raise ReplayError(f"{path}: unexpected arrays {extra} (a trajectory holds 'qpos', "
                                  "optionally 'time' and 'keyframes')")
            return {name: data[name] for name in names}
    except ReplayError:
        raise
    except zipfile.BadZipFile as exc:
        raise ReplayError(f"{path}: damaged or truncated .npz archive ({_reason(exc)})") from None
    except (OSError, ValueError, EOFError, zlib.error, MemoryError) as exc:
        raise ReplayError(f"{path}: not a readable .npz archive ({_reason(exc)})") from None


def _real_array(values, source, field):
    """``values`` as float64, refusing complex numbers (their imaginary part would be lost) and non-numbers."""
    if not isinstance(values, np.ndarray):
        raise ReplayError(f"{source}: {field} is not a numpy array (got {type(values).__name__})")
    if values.dtype.kind == "c":
        raise ReplayError(f"{source}: {field} holds complex numbers ({values.dtype}); expected real numbers")
    if values.dtype.kind not in "fiu":
        raise ReplayError(f"{source}: {field} has dtype {values.dtype}, expected real numbers")
    return np.ascontiguousarray(values, dtype=np.float64)


def check_qpos(values, model, source, field="qpos"):
    """(T >= 2, nq) joint positions as float64; errors name ``source``, ``field``, the frame and the joint."""
    import mujoco

    qpos = _real_array(values, source, field)
    if qpos.ndim != 2 or qpos.shape[1] != model.nq:
        raise ReplayError(f"{source}: {field} must have shape (T, {model.nq}) for this model, got {qpos.shape}")
    if qpos.shape[0] < 2:
        raise ReplayError(f"{source}: {field} needs at least 2 frames, got {qpos.shape[0]}")
    joint_of = _qpos_joints(model)
    bad = np.argwhere(~(np.abs(qpos) <= COORDINATE_LIMIT))  # NaN fails too
    if len(bad):
        k, a = bad[0]
        problem = "is not a finite number" if not np.isfinite(qpos[k, a]) else f"is beyond ±{COORDINATE_LIMIT:g}"
        raise ReplayError(f"{source}: {field}[{k}, {a}] = {qpos[k, a]:g} (frame {k}, joint {joint_of[a]!r}) "
                          f"{problem}")
    quaternion_kinds = {int(mujoco.mjtJoint.mjJNT_FREE): "free", int(mujoco.mjtJoint.mjJNT_BALL): "ball"}
    for j in range(model.njnt):
        kind_name = quaternion_kinds.get(int(model.jnt_type[j]))
        if kind_name is None:
            continue
        a = model.jnt_qposadr[j] + (3 if kind_name == "free" else 0)
        norms = np.linalg.norm(qpos[:, a:a + 4], axis=1)
        zero = np.nonzero(norms < MIN_QUATERNION_NORM)[0]
        if len(zero):
            raise ReplayError(f"{source}: {field}[{zero[0]}, {a}:{a + 4}] (frame {zero[0]}): the quaternion of "
                              f"{kind_name} joint {_joint_name(model, j)!r} is zero (norm {norms[zero[0]]:g}); "
                              "MuJoCo would silently make it the identity")
    return qpos


def _joint_name(model, j):
    return model.joint(j).name or f"joint{j}"


def _qpos_joints(model):
    """The name of the joint each qpos entry belongs to."""
    import mujoco

    width = {int(mujoco.mjtJoint.mjJNT_FREE): 7, int(mujoco.mjtJoint.mjJNT_BALL): 4}
    names = [""] * model.nq
    for j in range(model.njnt):
        a, size = model.jnt_qposadr[j], width.get(int(model.jnt_type[j]), 1)
        names[a:a + size] = [_joint_name(model, j)] * size
    return names


def _check_time(values, n, source):
    """(n,) increasing finite times as float64."""
    time = _real_array(values, source, "time")
    if time.shape != (n,):
        raise ReplayError(f"{source}: time must have shape ({n},), got {time.shape}")
    bad = np.nonzero(~(np.abs(time) <= TIME_LIMIT))[0]
    if len(bad):
        raise ReplayError(f"{source}: time[{bad[0]}] = {time[bad[0]]:g} must be finite and within "
                          f"±{TIME_LIMIT:g} s")
    if np.any(np.diff(time) <= 0):
        k = int(np.nonzero(np.diff(time) <= 0)[0][0])
        raise ReplayError(f"{source}: time must increase, but time[{k + 1}] <= time[{k}]")
    return time


def check_chain_range(qpos, model, geom_ids, source, field="qpos"):
    """Refuse hinge angles outside (-pi, pi) on the chains of ``geom_ids``: the chain motion needs them inside."""
    import mujoco

    from mjccd.mujoco.motions import body_path

    bodies = {b for g in geom_ids for b in body_path(model, model.geom_bodyid[g])}
    for j in range(model.njnt):
        if model.jnt_type[j] != mujoco.mjtJoint.mjJNT_HINGE or model.jnt_bodyid[j] not in bodies:
            continue
        a = model.jnt_qposadr[j]
        out = np.nonzero(np.abs(qpos[:, a]) >= math.pi)[0]
        if len(out):
            raise ReplayError(f"{source}: {field}[{out[0]}, {a}] = {qpos[out[0], a]:g} (frame {out[0]}): hinge "
                              f"{_joint_name(model, j)!r} must stay within (-pi, pi) for the chain motion")


def geom_poses(model, qpos, geom_ids):
    """World positions (T, N, 3) and unit quaternions (T, N, 4) of the geoms at every frame."""
    import mujoco

    data = mujoco.MjData(model)
    T, N = qpos.shape[0], len(geom_ids)
    pos = np.empty((T, N, 3))
    mats = np.empty((T, N, 9))
    for k in range(T):
        data.qpos[:] = qpos[k]
        mujoco.mj_kinematics(model, data)
        pos[k] = data.geom_xpos[geom_ids]
        mats[k] = data.geom_xmat[geom_ids]
    return pos, _mat_to_quat(mats.reshape(T, N, 3, 3))


def _mat_to_quat(R):
    """Unit quaternions [w, x, y, z] (..., 4) of rotation matrices (..., 3, 3)."""
    m00, m11, m22 = R[..., 0, 0], R[..., 1, 1], R[..., 2, 2]
    cand = np.stack([1 + m00 + m11 + m22, 1 + m00 - m11 - m22, 1 - m00 + m11 - m22, 1 - m00 - m11 + m22], -1)
    best = cand.argmax(axis=-1)
    s = 2.0 * np.sqrt(np.maximum(np.take_along_axis(cand, best[..., None], -1)[..., 0], 1e-300))
    d21, d02, d10 = R[..., 2, 1] - R[..., 1, 2], R[..., 0, 2] - R[..., 2, 0], R[..., 1, 0] - R[..., 0, 1]
    s01, s02, s12 = R[..., 0, 1] + R[..., 1, 0], R[..., 0, 2] + R[..., 2, 0], R[..., 1, 2] + R[..., 2, 1]
    q = np.stack([
        np.select([best == 0, best == 1, best == 2], [s / 4, d21 / s, d02 / s], d10 / s),
        np.select([best == 0, best == 1, best == 2], [d21 / s, s / 4, s01 / s], s02 / s),
        np.select([best == 0, best == 1, best == 2], [d02 / s, s01 / s, s / 4], s12 / s),
        np.select([best == 0, best == 1, best == 2], [d10 / s, s02 / s, s12 / s], s / 4)], -1)
    q *= np.where(q[..., :1] < 0, -1.0, 1.0)
    return q / np.linalg.norm(q, axis=-1, keepdims=True)


# ---------------------------------------------------------------- one frame


@dataclass
class FrameContacts:
    """Pair results of one frame interval: arrays over the checked pairs."""

    status: np.ndarray    # (P,) 1 separate, 0 touching, -1 overlapping at the frame start
    toi: np.ndarray       # (P,) first contact in [0, 1], -1 when none
    point: np.ndarray     # (P, 3)
    normal: np.ndarray    # (P, 3)


class FrameChecker:
    """Checks all pairs over one frame interval; the one place the per-frame CCD runs.

    Rigid and affine motions go through :class:`mjccd.scene.Scene` (moving
    spheres, cached and new separating planes, then the exact solver); the
    chain motion builds each ellipsoid's :class:`mjccd.Chain` and solves every
    pair with :func:`mjccd.first_contact`.
    """

    def __init__(self, bounds, motion, model=None):
        self.bounds = bounds
        self.motion = motion
        self.model = model
        self.counters = dict.fromkeys(COUNTER_NAMES, 0)
        if motion != "chain":
            from mjccd.scene import Scene

            self.scene = Scene(bounds.radii, pairs=bounds.pairs, motion=motion)
        P = len(bounds.pairs)
        self._status = np.ones(P, dtype=np.int64)
        self._toi = np.full(P, -1.0)
        self._point = np.zeros((P, 3))
        self._normal = np.zeros((P, 3))

    def step(self, pos0, quat0, pos1, quat1, qpos0=None, qpos1=None):
        """Results for the interval from poses (N, 3)/(N, 4) at its start to those at its end."""
        self._status[:] = 1
        self._toi[:] = -1.0
        if self.motion == "chain":
            self._chain_step(qpos0, qpos1)
        else:
            res = self.scene.step(np.concatenate([pos0, quat0], axis=1), np.concatenate([pos1, quat1], axis=1),
                                  all_pairs=True)
            for c in res.contacts:
                if c.certainty != "certified" and c.point is None and c.bracket[1] > 0.0:
                    self._toi[c.pair] = c.time  # uncertain: a possible contact from the bracket's start
                    self._point[c.pair] = self._normal[c.pair] = 0.0
                elif c.point is None:
                    self._status[c.pair], self._toi[c.pair] = -1, 0.0
                else:
                    self._toi[c.pair] = c.time
                    self._point[c.pair], self._normal[c.pair] = c.point, c.normal
            for name in COUNTER_NAMES:
                self.counters[name] += getattr(res.counters, name)
        return FrameContacts(self._status, self._toi, self._point, self._normal)

    def _chain_step(self, qpos0, qpos1):
        from mjccd import Ellipsoid, first_contact

        radii = self.bounds.radii
        motions = [chain_motion(self.model, g, qpos0, qpos1) for g in self.bounds.geom_ids]
        self.counters["pairs"] += len(self.bounds.pairs)
        for k, (i, j) in enumerate(self.bounds.pairs):
            self.counters["solved_exactly"] += 1
            c = first_contact(Ellipsoid(radii[i]), motions[i], Ellipsoid(radii[j]), motions[j])
            if c is None:
                continue
            if c.certainty != "certified":
                self.counters["uncertain"] += 1
            if c.certainty != "certified" and c.point is None and c.status_at_start == "separate":
                self._toi[k] = c.time  # uncertain: a possible contact from the bracket's start (not colliding)
                self._point[k] = self._normal[k] = 0.0
                continue
            self.counters["colliding"] += 1
            if c.point is None:
                self._status[k], self._toi[k] = -1, 0.0
                self.counters["overlapping_t0"] += 1
            else:
                self._toi[k] = c.time
                self._point[k], self._normal[k] = c.point, c.normal


def chain_motion(model, geom_id, qpos0, qpos1):
    """The exact articulated motion (:class:`mjccd.Chain`) of a geom between two qpos."""
    import mujoco

    from mjccd import Ball, Chain, Fixed, Free, Hinge, Slide
    from mjccd.mujoco.motions import body_path

    elements = []
    for b in reversed(body_path(model, model.geom_bodyid[geom_id])):
        joints = range(model.body_jntadr[b], model.body_jntadr[b] + model.body_jntnum[b])
        if not any(model.jnt_type[j] == mujoco.mjtJoint.mjJNT_FREE for j in joints):
            elements.append(Fixed(model.body_pos[b], model.body_quat[b]))
        for j in joints:
            a = model.jnt_qposadr[j]
            kind = model.jnt_type[j]
            name = model.joint(j).name or f"joint{j}"
            if kind == mujoco.mjtJoint.mjJNT_FREE:
                elements.append(Free(qpos0[a:a + 3], qpos0[a + 3:a + 7], qpos1[a:a + 3], qpos1[a + 3:a + 7]))
                continue
            anchor = model.jnt_pos[j]
            shifted = bool(np.any(anchor != 0.0))
            if shifted:
                elements.append(Fixed(anchor))
            if kind == mujoco.mjtJoint.mjJNT_BALL:
                elements.append(Ball(qpos0[a:a + 4], qpos1[a:a + 4]))
            elif kind == mujoco.mjtJoint.mjJNT_HINGE:
                if max(abs(qpos0[a]), abs(qpos1[a])) >= math.pi:
                    raise ReplayError(f"qpos: hinge {name!r} must stay within (-pi, pi) for the chain motion")
                elements.append(Hinge(model.jnt_axis[j], qpos0[a], qpos1[a]))
            else:
                elements.append(Slide(model.jnt_axis[j], qpos0[a], qpos1[a]))
            if shifted:
                elements.append(Fixed(-anchor))
    elements.append(Fixed(model.geom_pos[geom_id], model.geom_quat[geom_id]))
    return Chain(elements)


# ---------------------------------------------------------------- replay


@dataclass
class ReplayResult:
    """Everything a replay found; ``contacts`` are first contacts, ``in_contact`` (T-1, P) flags."""

    model: str
    trajectory: str
    motion: str
    time: np.ndarray
    bounds: Bounds
    contacts: list = field(default_factory=list)
    in_contact: np.ndarray = None
    counters: dict = field(default_factory=dict)
    timing: dict = field(default_factory=dict)
    files: list = field(default_factory=list)

    @property
    def n_frames(self):
        return len(self.time)


def replay(model_path, traj, motion="rigid", out_dir=None, *, pairs=None, progress=True, render=True,
           max_rendered=4, force=False, chunk_frames=None):
    """Replay a trajectory on a model and find every first contact between bounding ellipsoids.

    Args:
        model_path: MJCF file with bounding ellipsoid geoms (group 5).
        traj: ``.npz`` with ``qpos`` (T, nq) and ``time`` (T), or a ``.bvh`` clip.
        motion: ``"rigid"``, ``"affine"`` or ``"chain"`` between consecutive frames.
        out_dir: where to write contacts.json, contacts.csv, timeline.png and frames (None: nothing);
            a folder holding another run's files is refused unless ``force`` (see :class:`OutputFolder`).
        pairs: (P, 2) ellipsoid index pairs to check instead of the default.
        chunk_frames: frame intervals per chunk of compiled work (Ctrl-C is acted on between chunks);
            None: the motion's :data:`CHUNK_FRAMES`.  The results do not depend on it.
    Returns:
        a :class:`ReplayResult`.
    """
    if motion not in MOTIONS:
        raise ReplayError(f"motion: expected one of {', '.join(MOTIONS)}, got {motion!r}")
    chunk_frames = CHUNK_FRAMES[motion] if chunk_frames is None else chunk_frames
    if not (isinstance(chunk_frames, (int, np.integer)) and chunk_frames >= 1):
        raise ReplayError(f"chunk_frames: expected a positive integer, got {chunk_frames!r}")
    model = load_model(model_path)
    bounds = bounding_ellipsoids(model, pairs, source=str(model_path))
    qpos, time = load_trajectory(traj, model)
    if motion == "chain":
        check_chain_range(qpos, model, bounds.geom_ids, traj)
    folder = None if out_dir is None else output_folder(out_dir, force)
    result = ReplayResult(str(model_path), str(traj), motion, time, bounds)
    _run(model, qpos, bounds, motion, result, progress, chunk_frames)
    if folder is not None:
        try:
            with folder:
                write_reports(result, folder)
                if render:
                    render_frames(model, qpos, result, folder, max_rendered)
        except OutputError:
            raise
        except OSError as exc:
            raise OutputError(f"{exc.filename or out_dir}: cannot write: {exc.strerror or _reason(exc)}") from None
        result.files = [str(folder.file_path(name)) for name in folder.written]
    return result


def output_folder(out_dir, force=False):
    """The :class:`OutputFolder` for ``out_dir``, checked before the replay runs so that a bad ``--out`` costs no time.

    Refuses a file, a folder holding another run's files (unless ``force``:
    then this tool's earlier outputs there are removed now), and a path that
    cannot become a folder.
    """
    folder = OutputFolder(out_dir, "replay", force=force, patterns=OUTPUT_PATTERNS)
    nearest = next(p for p in (folder.path, *folder.path.parents) if p.exists())
    if not nearest.is_dir():
        raise OutputError(f"{out_dir}: cannot create the output folder: {nearest} is a file")
    if not os.access(nearest, os.W_OK | os.X_OK):
        raise OutputError(f"{out_dir}: cannot write into {nearest}: permission denied")
    return folder


def _run(model, qpos, bounds, motion, result, progress, chunk_frames):
    """Kinematics and the per-frame checks, chunk by chunk of frames; fills ``result``.

    The chunks run inside :func:`mjccd.interrupts.deferred`: a Ctrl-C raises
    KeyboardInterrupt between two chunks, never inside compiled code.  The
    frame checker (and its plane cache) carries over from chunk to chunk, so
    the results do not depend on ``chunk_frames``.
    """
    warm_up(motion)  # the first compile (or cache load) is not part of the timing
    checker = FrameChecker(bounds, motion, model)
    n = len(result.time) - 1
    in_contact = np.zeros((n, len(bounds.pairs)), dtype=bool)
    t_kin = t_ccd = 0.0
    bar = None
    if progress:
        from tqdm import tqdm

        bar = tqdm(total=n, desc="replay", unit="frame", file=sys.stderr, leave=False)
    try:
        with interrupts.deferred() as check:
            for first in range(0, n, chunk_frames):
                stop = min(first + chunk_frames, n)
                start = _time.perf_counter()
                pos, quat = geom_poses(model, qpos[first:stop + 1], bounds.geom_ids)
                _check_centres(pos, first, bounds, result)
                t_kin += _time.perf_counter() - start
                start = _time.perf_counter()
                for k in range(first, stop):
                    i = k - first
                    fc = checker.step(pos[i], quat[i], pos[i + 1], quat[i + 1], qpos[k], qpos[k + 1])
                    _record(result, k, fc, in_contact)
                t_ccd += _time.perf_counter() - start
                if bar is not None:
                    bar.update(stop - first)
                check()
    finally:
        if bar is not None:
            bar.close()
    result.in_contact = in_contact
    result.counters = {name: int(v) for name, v in checker.counters.items()}
    result.timing = {"kinematics_s": t_kin, "ccd_s": t_ccd, "intervals": n,
                     "frames_per_s": n / max(t_kin + t_ccd, 1e-12)}


def _check_centres(pos, first, bounds, result):
    """Refuse ellipsoid centres beyond :data:`COORDINATE_LIMIT` (say, a huge body offset in the model)."""
    bad = np.argwhere(~np.all(np.abs(pos) <= COORDINATE_LIMIT, axis=2))
    if len(bad):
        k, i = bad[0]
        raise ReplayError(f"{result.trajectory}: frame {first + k}: ellipsoid {bounds.names[i]!r} of {result.model} "
                          f"is at {pos[k, i].tolist()}, beyond ±{COORDINATE_LIMIT:g} m")


def _record(result, k, fc, in_contact):
    """Add frame k's first contacts to ``result`` and its contact flags to ``in_contact``."""
    bounds = result.bounds
    in_contact[k] = (fc.status != 1) | (fc.toi >= 0.0)
    dt = result.time[k + 1] - result.time[k]
    for p in np.nonzero((fc.status == 1) & (fc.toi >= 0.0))[0]:
        i, j = bounds.pairs[p]
        result.contacts.append({
            "frame": int(k), "toi": float(fc.toi[p]), "time": float(result.time[k] + fc.toi[p] * dt),
            "ellipsoids": [bounds.names[i], bounds.names[j]],
            "bodies": [bounds.body_names[i], bounds.body_names[j]],
            "labels": [bounds.labels[i], bounds.labels[j]],
            "point": [float(x) for x in fc.point[p]], "normal": [float(x) for x in fc.normal[p]]})


def warm_up(motion="rigid"):
    """Compile (or load from the cache) the per-frame kernels before timing a replay."""
    if motion == "chain":
        return
    from mjccd.scene import Scene

    poses0 = np.array([[0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0], [3.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0]])
    poses1 = np.array([[0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0], [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0]])
    Scene([[1.0, 0.5, 0.5]] * 2, motion=motion).step(poses0, poses1, all_pairs=True)


def interval_table(model, bounds, qpos0, qpos1, *, repeat=3):
    """All collision intervals of every pair over one chain-motion segment (thesis Table 6 style).

    Each row: the pair, the motion degree (largest degree in t of the two
    motions' scaled inverses), the degree of F in t, the time to build the pair (the
    pair's quadric polynomials and their pencil), the time to build F and solve, and the intervals
    (normalised time).  Times are the best of ``repeat`` runs, after one
    untimed run that compiles.
    """
    from mjccd.ccd import degree_in_t, prepare_pair, solve_balanced

    motions = [chain_motion(model, g, qpos0, qpos1) for g in bounds.geom_ids]
    rows = []
    for i, j in bounds.pairs:
        best_build = best_solve = math.inf
        for _ in range(repeat + 1):
            t0 = _time.perf_counter()
            qa = motions[i].quadric_bounded_on(bounds.radii[i], 0.0, 1.0)
            qb = motions[j].quadric_bounded_on(bounds.radii[j], 0.0, 1.0)
            length = float(max(bounds.radii[i].max(), bounds.radii[j].max()))
            pencil, err, _ = prepare_pair(*qa, *qb, length)
            t1 = _time.perf_counter()
            status0, intervals, _, _, _, _ = solve_balanced(*pencil, err, 1.0, False)
            t2 = _time.perf_counter()
            best_build, best_solve = min(best_build, t1 - t0), min(best_solve, t2 - t1)
        rows.append({"pair": [bounds.labels[i], bounds.labels[j]],
                     "motion_degree": int(max(qa[0].shape[2], qb[0].shape[2]) - 1) // 2,
                     "F_degree_t": int(degree_in_t(*pencil)), "build_ms": best_build * 1e3,
                     "solve_ms": best_solve * 1e3, "status_at_start": int(status0),
                     "intervals": [[float(a), float(b)] for a, b in intervals]})
    return rows


def format_interval_table(rows):
    """Terminal table of :func:`interval_table` rows with the totals."""
    lines = [f"{'pair':<36} {'motion deg':>10} {'deg F(t)':>8} {'build [ms]':>10} {'solve [ms]':>10}  intervals"]
    for r in rows:
        iv = ", ".join(f"[{a:.9f}, {b:.9f}]" for a, b in r["intervals"]) or "none"
        lines.append(f"{r['pair'][0] + ' / ' + r['pair'][1]:<36} {r['motion_degree']:>10} {r['F_degree_t']:>8} "
                     f"{r['build_ms']:>10.3f} {r['solve_ms']:>10.3f}  {iv}")
    build = sum(r["build_ms"] for r in rows)
    solve = sum(r["solve_ms"] for r in rows)
    lines.append(f"{len(rows)} pairs: build {build:.3f} ms + solve {solve:.3f} ms = {build + solve:.3f} ms")
    return "\n".join(lines)


# ---------------------------------------------------------------- reports


def contact_table(result, max_rows=30):
    """Terminal table of the first contacts: frame, time, pair, point."""
    rows = result.contacts
    if not rows:
        return "no contact"
    lines = [f"{'frame':>6} {'time [s]':>12}  {'pair':<44} point [m]"]
    for c in rows[:max_rows]:
        pair = f"{c['labels'][0]} / {c['labels'][1]}"
        p = "(" + ", ".join(f"{x:+.4f}" for x in c["point"]) + ")"
        lines.append(f"{c['frame']:>6} {c['time']:>12.6f}  {pair:<44} {p}")
    if len(rows) > max_rows:
        lines.append(f"... {len(rows) - max_rows} more first contacts (see contacts.csv)")
    return "\n".join(lines)


def summary(result):
    """A few lines: frames, pairs, contacts, filter counters, timing."""
    c = result.counters
    t = result.timing
    frames_hit = int(result.in_contact.any(axis=1).sum()) if result.in_contact is not None else 0
    pairs_hit = int(result.in_contact.any(axis=0).sum()) if result.in_contact is not None else 0
    lines = [
        f"{result.n_frames} frames ({t['intervals']} intervals), {len(result.bounds.names)} ellipsoids, "
        f"{len(result.bounds.pairs)} pairs, motion {result.motion}",
        f"first contacts: {len(result.contacts)}; frames with contact: {frames_hit}; "
        f"pairs ever in contact: {pairs_hit}",
        "filter: " + ", ".join(f"{k} {v}" for k, v in c.items()),
        f"time: kinematics {t['kinematics_s'] * 1e3:.1f} ms, CCD {t['ccd_s'] * 1e3:.1f} ms, "
        f"{t['frames_per_s']:.0f} frames/s",
    ]
    return "\n".join(lines)


def _overlap_spans(result):
    spans = []
    for p in np.nonzero(result.in_contact.any(axis=0))[0]:
        col = result.in_contact[:, p].astype(np.int8)
        edges = np.diff(np.concatenate([[0], col, [0]]))
        starts, ends = np.nonzero(edges == 1)[0], np.nonzero(edges == -1)[0]
        i, j = result.bounds.pairs[p]
        spans.append({"ellipsoids": [result.bounds.names[i], result.bounds.names[j]],
                      "bodies": [result.bounds.body_names[i], result.bounds.body_names[j]],
                      "labels": [result.bounds.labels[i], result.bounds.labels[j]],
                      "frames": [[int(a), int(b) - 1] for a, b in zip(starts, ends)]})
    return spans


def write_reports(result, folder):
    """contacts.json, contacts.csv and timeline.png in ``folder`` (an :class:`OutputFolder`)."""
    doc = {"version": 1, "model": result.model, "trajectory": result.trajectory, "motion": result.motion,
           "frames": result.n_frames, "ellipsoids": result.bounds.names, "pairs": len(result.bounds.pairs),
           "first_contacts": result.contacts, "in_contact": _overlap_spans(result),
           "counters": result.counters, "timing": result.timing}
    with folder.open("contacts.json", "w", encoding="utf-8") as fh:
        fh.write(json.dumps(doc, indent=1) + "\n")
    with folder.open("contacts.csv", "w", newline="", encoding="utf-8") as fh:
        w = csv.writer(fh)
        w.writerow(["frame", "time", "toi", "ellipsoid_a", "ellipsoid_b", "body_a", "body_b",
                    "px", "py", "pz", "nx", "ny", "nz"])
        for c in result.contacts:
            w.writerow([c["frame"], repr(c["time"]), repr(c["toi"]), *c["ellipsoids"], *c["bodies"],
                        *map(repr, c["point"]), *map(repr, c["normal"])])
    with folder.open("timeline.png", "wb") as fh:
        plot_timeline(result, fh)


def plot_timeline(result, target):
    """Colliding body pairs over time: bars while in contact, dots at first contacts; PNG into a path or binary file."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    spans = _overlap_spans(result)
    labels = [f"{s['labels'][0]} / {s['labels'][1]}" for s in spans]
    fig, ax = plt.subplots(figsize=(10, max(2.5, 0.25 * len(spans) + 1.2)))
    t = result.time
    for row, s in enumerate(spans):
        ax.broken_barh([(t[a], t[b + 1] - t[a]) for a, b in s["frames"]], (row - 0.35, 0.7),
                       facecolors="tab:blue", alpha=0.5)
        hits = [c["time"] for c in result.contacts if c["ellipsoids"] == s["ellipsoids"]]
        ax.plot(hits, [row] * len(hits), "o", color="tab:red", ms=4)
    ax.set_yticks(range(len(spans)))
    ax.set_yticklabels(labels, fontsize=7)
    ax.set_xlim(t[0], t[-1])
    ax.set_ylim(-1, max(len(spans), 1))
    ax.set_xlabel("time [s]")
    ax.set_title(f"{pathlib.Path(result.model).name}: contacts ({result.motion} motion); red dots: first contacts")
    fig.tight_layout()
    try:
        fig.savefig(target, dpi=110, format="png")
    finally:
        plt.close(fig)


def render_frames(model, qpos, result, folder, count=4):
    """PNG frames at the first few first contacts in ``folder``, colliding ellipsoids in red; none without OpenGL."""
    if not result.contacts or count <= 0:
        return
    if "MUJOCO_GL" not in os.environ and not os.environ.get("DISPLAY"):
        os.environ["MUJOCO_GL"] = "egl"
    try:
        import warnings

        import mujoco

        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            renderer = mujoco.Renderer(model, 480, 640)
    except Exception as exc:  # no usable OpenGL context on this machine
        print(f"rendering skipped: no OpenGL backend ({_reason(exc)}); set MUJOCO_GL=egl or osmesa",
              file=sys.stderr)
        return
    from matplotlib.image import imsave

    data = mujoco.MjData(model)
    opt = mujoco.MjvOption()
    opt.geomgroup[BOUND_GROUP] = 1
    cam = mujoco.MjvCamera()
    picked, seen = [], set()
    for c in result.contacts:
        if c["frame"] not in seen:
            seen.add(c["frame"])
            picked.append(c)
        if len(picked) == count:
            break
    rgba = model.geom_rgba.copy()
    name_to_geom = dict(zip(result.bounds.names, result.bounds.geom_ids))
    try:
        for c in picked:
            k = c["frame"]
            red = {name_to_geom[n] for cc in result.contacts if cc["frame"] == k for n in cc["ellipsoids"]}
            model.geom_rgba[:] = rgba
            for g in red:
                model.geom_rgba[g] = (0.9, 0.1, 0.1, 0.8)
            data.qpos[:] = qpos[k + 1] if c["toi"] > 0.5 else qpos[k]
            mujoco.mj_forward(model, data)
            cam.lookat[:] = c["point"]
            cam.distance, cam.azimuth, cam.elevation = 2.5, 60.0, -15.0
            renderer.update_scene(data, cam, scene_option=opt)
            with folder.open(f"frame_{k:05d}.png", "wb") as fh:
                imsave(fh, renderer.render(), format="png")
    finally:
        model.geom_rgba[:] = rgba
        renderer.close()


# ---------------------------------------------------------------- command line


def _row_count(text):
    """argparse type of ``--rows``: a non-negative integer."""
    try:
        rows = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a whole number of rows, got {text!r}") from None
    if rows < 0:
        raise argparse.ArgumentTypeError(f"expected 0 or more rows, got {rows}")
    return rows


def _folder_name(text):
    """argparse type of ``--out``: a non-empty folder name."""
    if not text.strip():
        raise argparse.ArgumentTypeError("expected a folder name, got an empty string")
    return text


def main(argv=None):
    """``mjccd replay MODEL.xml TRAJ [--motion ...] [--out DIR [--force]]``; returns the exit status."""
    parser = argparse.ArgumentParser(prog="mjccd replay",
                                     description="Replay a trajectory and report the first contacts "
                                                 "between bounding ellipsoids.")
    parser.add_argument("model", help="MJCF model with bounding ellipsoids (geom group 5)")
    parser.add_argument("traj", help=".npz with qpos (T x nq) and time (T), or a .bvh clip")
    parser.add_argument("--motion", choices=MOTIONS, default="rigid", help="motion between frames")
    parser.add_argument("--out", type=_folder_name,
                        help="folder for contacts.json, contacts.csv, timeline.png, frames (written only when "
                             "the replay completes; a folder holding another run needs --force)")
    parser.add_argument("--force", action="store_true",
                        help="write into an --out folder that holds an earlier run, removing that run's files")
    parser.add_argument("--no-render", action="store_true", help="do not render frames")
    parser.add_argument("--rows", type=_row_count, default=30, help="rows of the contact table (default 30)")
    parser.add_argument("--intervals", action="store_true",
                        help="also print every pair's collision intervals over each segment between the "
                             "trajectory's keyframes (npz 'keyframes', chain motion)")
    args = parser.parse_args(argv)
    if not args.no_render and "MUJOCO_GL" not in os.environ and not os.environ.get("DISPLAY"):
        os.environ["MUJOCO_GL"] = "egl"  # must be chosen before mujoco is first imported
    try:
        keys = None
        if args.intervals:  # checked before the replay runs
            model = load_model(args.model)
            bounds = bounding_ellipsoids(model, source=args.model)
            keys = load_keyframes(args.traj, model)
            check_chain_range(keys, model, bounds.geom_ids, args.traj, "keyframes")
        result = replay(args.model, args.traj, args.motion, args.out, render=not args.no_render, force=args.force)
    except (ValueError, MjccdError) as exc:
        print(f"mjccd replay: {exc}", file=sys.stderr)
        return 2
    print(contact_table(result, args.rows))
    print(summary(result))
    if keys is not None:
        for k in range(len(keys) - 1):
            print(f"keyframe segment {k} -> {k + 1}:")
            print(format_interval_table(interval_table(model, result.bounds, keys[k], keys[k + 1])))
    if args.out:
        print("wrote " + ", ".join(result.files))
    return 0
