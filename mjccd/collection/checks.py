"""One clip's scan: its replay (:func:`mjccd.replay.replay_trajectory`), its contact rows and its row of the clips
table with the checks users filter on.

The flags, each with its threshold in :class:`ScanOptions`:

- ``self_penetration``: two bodies of the skeleton stay in contact for at least ``self_overlap_s`` seconds
  (a run of frame intervals in contact, as replay's ``in_contact``; a brief touch between frames is a contact,
  not a penetration).  Pairs that already touch in the model's reference pose (qpos0: an imported skeleton's
  rest pose, where the capsules of the hips meet) overlap by construction and do not count; their contacts
  are still rows of the contacts table.  ``longest_overlap_s`` is the longest such contact.
- ``below_floor``: some frame has a real geom (MuJoCo's own, of a moving body) more than ``floor_depth_m``
  metres below a static plane (a geom's lowest point along the plane's normal, from MuJoCo's kinematics).
- ``jump``: in some frame interval a joint turns by more than ``jump_deg`` degrees (a hinge's angle, a ball's or
  free joint's rotation).
"""
import math
import traceback
import warnings
from dataclasses import asdict, dataclass

import mujoco
import numpy as np

from mjccd import bvh
from mjccd.errors import InputError, MjccdError
from mjccd.mujoco.ellipsoids import geom_id
from mjccd.mujoco.geoms import real_geoms
from mjccd.mujoco.warnings import CoverageWarning
from mjccd.replay import MOTIONS, PLANE_RULES, Trajectory, load_model, replay_trajectory

G = mujoco.mjtGeom
FLAGS = ("self_penetration", "below_floor", "jump")
KINEMATICS_FRAMES = 4096  # frames whose geom poses are held at a time by the floor check


@dataclass(frozen=True)
class ScanOptions:
    """What a scan checks and how.

    Attributes:
        model: the MJCF of the qpos (.npz) clips (None: BVH clips only, each imported to its own skeleton).
        motion, mode, planes: as :func:`mjccd.replay.replay` (None mode: geoms with the rigid motion).
        self_overlap_s: the ``self_penetration`` flag's shortest contact, seconds.
        floor_depth_m: the ``below_floor`` flag's depth, metres.
        jump_deg: the ``jump`` flag's largest turn of a joint in one frame interval, degrees.
        bvh_scale: metres per BVH file unit (:func:`mjccd.bvh.import_bvh`; CMU's by default).
    """

    model: str = None
    motion: str = "rigid"
    mode: str = None
    planes: str = "all"
    self_overlap_s: float = 0.1
    floor_depth_m: float = 0.1
    jump_deg: float = 45.0
    bvh_scale: float = bvh.CMU_SCALE

    def check(self):
        """Refuse a bad option with a :class:`~mjccd.errors.InputError` naming it."""
        if self.motion not in MOTIONS:
            raise InputError(f"motion: expected one of {', '.join(MOTIONS)}, got {self.motion!r}")
        if self.mode not in (None, "geoms", "ellipsoids"):
            raise InputError(f"mode: expected 'geoms' or 'ellipsoids', got {self.mode!r}")
        if self.planes not in PLANE_RULES:
            raise InputError(f"planes: expected one of {', '.join(PLANE_RULES)}, got {self.planes!r}")
        for name in ("self_overlap_s", "floor_depth_m", "jump_deg", "bvh_scale"):
            value = getattr(self, name)
            low = 0.0 if name != "bvh_scale" else math.ulp(0.0)  # a scale must be positive
            if not (isinstance(value, (int, float)) and math.isfinite(value) and value >= low):
                raise InputError(f"{name}: expected a finite number {'>=' if low == 0 else '>'} 0, got {value!r}")
        return self

    def settings(self):
        """The options that change answers, as a dict (the model enters a clip's key by its bytes)."""
        out = asdict(self)
        out.pop("model")
        return out


_MODELS = {}  # path -> compiled model, per worker process (the qpos clips of one scan share their model)


def _model(path):
    if path not in _MODELS:
        _MODELS[path] = load_model(path)
    return _MODELS[path]


def check_clips(tasks, options):
    """``(contacts, clips)``: the rows of a batch of :class:`~mjccd.collection.clips.ClipTask`, each table as a
    dict of columns.  A clip that fails is a clips row with its error; the others are still scanned."""
    contacts = {name: [] for name in CONTACT_COLUMNS}
    clips = {name: [] for name in CLIP_COLUMNS}
    for task in tasks:
        row = {name: None for name in CLIP_COLUMNS}
        row.update(clip=task.path, key=task.key, format=task.format, flags=[])
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", CoverageWarning)  # a skeleton's self pairs, said in the docs
                found = _check_clip(task, options)
        except Exception as exc:  # noqa: BLE001 -- one bad clip is a row with its error, never the end of a scan
            row["error"] = _error_text(exc)
        else:
            row.update(found["clip"])
            for r in found["contacts"]:
                for name in CONTACT_COLUMNS:
                    contacts[name].append(r.get(name))
        for name in CLIP_COLUMNS:
            clips[name].append(row[name])
    return contacts, clips


def _error_text(exc):
    """One line: the message of a refused input, else the exception's type, message and where it was raised."""
    if isinstance(exc, (MjccdError, ValueError, OSError)):
        return " ".join(str(exc).split()) or type(exc).__name__
    where = traceback.extract_tb(exc.__traceback__)[-1]
    return f"{type(exc).__name__}: {exc} ({where.filename.rsplit('/', 1)[-1]}:{where.lineno})"


def replayed(task, options):
    """``(model, trajectory, result)``: one clip's model (a BVH clip's own skeleton, else ``options.model``), its
    opened :class:`~mjccd.replay.Trajectory` and its :class:`~mjccd.replay.ReplayResult`."""
    if task.format == "bvh":
        xml, qpos, time, _ = bvh.import_bvh(task.path, scale=options.bvh_scale, bounds=True)
        model = mujoco.MjModel.from_xml_string(xml)
        trajectory = Trajectory(task.path, model, arrays=(qpos, time))
        source = f"{task.path} (its skeleton)"
    else:
        if options.model is None:
            raise MjccdError(f"{task.path}: a qpos clip needs the model it moves (--model)")
        model = _model(options.model)
        trajectory = Trajectory(task.path, model)
        source = options.model
    result = replay_trajectory(model, trajectory, options.motion, source=source, planes=options.planes,
                               mode=options.mode)
    return model, trajectory, result


def _check_clip(task, options):
    """The contact rows and the clips-row values of one clip (module docstring)."""
    model, trajectory, result = replayed(task, options)
    rows = contact_rows(result, task)
    times = trajectory.times()
    qpos = trajectory.qpos()
    turns = joint_turns(model, qpos)
    longest = 0.0
    rest = RestPose(model)
    for p, runs in result.pair_runs():
        if not result.on_plane(p) and not rest.overlapping(*result.names(p)[0]):
            longest = max(longest, float(np.max(runs["end"] - runs["start"])))
    depth = floor_depth(model, qpos)
    flags = []
    if longest >= options.self_overlap_s and longest > 0.0:
        flags.append("self_penetration")
    if depth > options.floor_depth_m:
        flags.append("below_floor")
    jumps = int(np.count_nonzero(turns > options.jump_deg))
    if jumps:
        flags.append("jump")
    first = [r for r in rows if r["kind"] == "first"]
    clip = {"frames": int(result.n_frames), "duration_s": float(times[-1] - times[0]),
            "self_contacts": sum(not r["floor"] for r in first), "floor_contacts": sum(r["floor"] for r in first),
            "longest_overlap_s": longest, "max_floor_depth_m": depth,
            "max_joint_turn_deg": float(turns.max()) if len(turns) else 0.0, "jump_frames": jumps, "flags": flags}
    return {"contacts": rows, "clip": clip}


CONTACT_COLUMNS = ("clip", "key", "frame", "time", "kind", "floor", "body_a", "body_b", "part_a", "part_b",
                   "px", "py", "pz", "nx", "ny", "nz", "certainty", "last_frame", "end_time")
CLIP_COLUMNS = ("clip", "key", "format", "frames", "duration_s", "self_contacts", "floor_contacts",
                "longest_overlap_s", "max_floor_depth_m", "max_joint_turn_deg", "jump_frames", "flags", "error")


class RestPose:
    """The model in its reference pose (qpos0: a skeleton's rest pose), to tell which pairs overlap by
    construction (two capsules meeting at the hips) from those that penetrate."""

    def __init__(self, model):
        self.model = model
        self.data = mujoco.MjData(model)
        mujoco.mj_kinematics(model, self.data)

    def overlapping(self, a, b):
        """Whether geoms ``a`` and ``b`` (labels) touch or overlap in the reference pose (MuJoCo's distance)."""
        fromto = np.zeros(6)
        return mujoco.mj_geomDistance(self.model, self.data, geom_id(self.model, a), geom_id(self.model, b), 1.0,
                                      fromto) <= 0.0


def _plane_parts(result):
    """The names a static plane has in the result's contacts (its geom's)."""
    if result.mode == "geoms":
        g = result.geoms
        return {g.labels_of_rows[r] for r in range(len(g.labels_of_rows)) if g.is_plane(r)}
    return {geom for geom, _ in result.plane_names.values()}


def contact_rows(result, task):
    """The clip's contact rows: a ``first`` row per first contact (time, point, normal) and a ``continuing`` row
    per run of contact that no first contact opens (a pair already touching when the run begins: say, at the
    clip's first frame), with the run's last frame and end time."""
    key = result.part_key
    planes = _plane_parts(result)
    rows, opened = [], set()
    for c in result.contacts:
        a, b = c[key]
        rows.append({"clip": task.path, "key": task.key, "frame": c["frame"], "time": c["time"], "kind": "first",
                     "floor": b in planes, "body_a": c["bodies"][0], "body_b": c["bodies"][1], "part_a": a,
                     "part_b": b, "px": c["point"][0], "py": c["point"][1], "pz": c["point"][2],
                     "nx": c["normal"][0], "ny": c["normal"][1], "nz": c["normal"][2],
                     "certainty": c.get("certainty", "certified"), "last_frame": None, "end_time": None})
        opened.add((c["frame"], a, b))
    for p, runs in result.pair_runs():
        (a, b), bodies, _ = result.names(p)
        for _, first, last, start, end in runs.tolist():
            if (first, a, b) in opened:
                continue
            rows.append({"clip": task.path, "key": task.key, "frame": first, "time": start, "kind": "continuing",
                         "floor": b in planes, "body_a": bodies[0], "body_b": bodies[1], "part_a": a, "part_b": b,
                         "px": None, "py": None, "pz": None, "nx": None, "ny": None,
                         "nz": None, "certainty": None, "last_frame": last, "end_time": end})
    rows.sort(key=lambda r: (r["frame"], r["kind"] != "first", r["time"], r["part_a"], r["part_b"]))
    return rows


def joint_turns(model, qpos):
    """(T - 1,) the largest turn of any joint in each frame interval, degrees: a hinge's angle change, a ball's or
    a free joint's rotation angle (slides do not turn)."""
    turns = np.zeros(max(len(qpos) - 1, 0))
    for j in range(model.njnt):
        kind, adr = int(model.jnt_type[j]), int(model.jnt_qposadr[j])
        if kind == mujoco.mjtJoint.mjJNT_HINGE:
            turn = np.abs(np.diff(qpos[:, adr]))
        elif kind in (mujoco.mjtJoint.mjJNT_BALL, mujoco.mjtJoint.mjJNT_FREE):
            q = qpos[:, adr + (3 if kind == mujoco.mjtJoint.mjJNT_FREE else 0):][:, :4]
            q = q / np.linalg.norm(q, axis=1, keepdims=True)
            cos_half = np.clip(np.abs(np.sum(q[:-1] * q[1:], axis=1)), 0.0, 1.0)
            turn = 2.0 * np.arccos(cos_half)
        else:
            continue
        np.maximum(turns, np.degrees(turn), out=turns)
    return turns


def _support(kind, size, aabb, m):
    """(F,) how far a geom reaches along a direction, ``m`` (F, 3): the direction in the geom's frame."""
    ax = np.abs(m)
    if kind == G.mjGEOM_SPHERE:
        return np.full(len(m), size[0])
    if kind == G.mjGEOM_CAPSULE:
        return size[1] * ax[:, 2] + size[0]
    if kind == G.mjGEOM_CYLINDER:
        return size[1] * ax[:, 2] + size[0] * np.hypot(m[:, 0], m[:, 1])
    if kind == G.mjGEOM_ELLIPSOID:
        return np.linalg.norm(m * size[:3], axis=1)
    if kind == G.mjGEOM_BOX:
        return ax @ size[:3]
    return m @ aabb[:3] + ax @ aabb[3:]  # meshes and the rest: their bounding box


def floor_depth(model, qpos):
    """The deepest any real geom of a moving body reaches below a static plane over the frames, metres (0 when
    none does or the model has no static plane)."""
    real, _ = real_geoms(model)
    static = model.body_weldid[model.geom_bodyid] == 0
    planes = [g for g in range(model.ngeom) if model.geom_type[g] == G.mjGEOM_PLANE and static[g]]
    bodies = [int(g) for g in real.tolist() if not static[g] and model.geom_type[g] != G.mjGEOM_PLANE]
    if not planes or not bodies:
        return 0.0
    data = mujoco.MjData(model)
    mujoco.mj_kinematics(model, data)
    plane_at = [(data.geom_xpos[g].copy(), data.geom_xmat[g].reshape(3, 3)[:, 2].copy()) for g in planes]
    deepest = 0.0
    for first in range(0, len(qpos), KINEMATICS_FRAMES):
        rows = qpos[first:first + KINEMATICS_FRAMES]
        xpos = np.empty((len(rows), len(bodies), 3))
        xmat = np.empty((len(rows), len(bodies), 3, 3))
        for k, q in enumerate(rows):
            data.qpos[:] = q
            mujoco.mj_kinematics(model, data)
            xpos[k] = data.geom_xpos[bodies]
            xmat[k] = data.geom_xmat[bodies].reshape(-1, 3, 3)
        for point, normal in plane_at:
            for i, g in enumerate(bodies):
                m = xmat[:, i].transpose(0, 2, 1) @ normal  # the plane's normal in the geom's frame
                low = (xpos[:, i] - point) @ normal - _support(int(model.geom_type[g]), model.geom_size[g],
                                                              model.geom_aabb[g], m)
                deepest = max(deepest, float(-low.min()))
    return deepest

