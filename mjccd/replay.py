"""Trajectory replay: move a MuJoCo model's bounding ellipsoids along recorded ``qpos`` and find contacts.

Between two consecutive frames every bounding ellipsoid follows the chosen
motion model (``rigid``: centre and quaternion lerp; ``affine``: centre and
shape-matrix lerp; ``chain``: the joints of its kinematic chain, hinge angles
with tan(theta/2) linear), and every pair is checked exactly over the frame
interval.  The bounding ellipsoids are the model's ellipsoid geoms in geom
group 5 (all ellipsoid geoms when group 5 has none).  By default a pair is
checked when its two ellipsoids hang under different top-level bodies and at
least one of them moves; a model with one character (an imported skeleton)
falls back to that character's self-collisions, every pair of bodies that are
neither one rigid body nor a parent and a child (``--pairs self``), and says
so with a :class:`~mjccd.mujoco.warnings.CoverageWarning`.  Static planes (floors, walls) count
too: by default every ellipsoid that moves is checked against every static plane (``--planes all``;
``mujoco`` keeps the pairs MuJoCo's own rules would collide, ``none`` leaves planes out), so a floor
under the boxers counts even though MuJoCo never collides with it (it is a visual geom there).

Inputs are checked before any work: a bad model or trajectory stops with a
:class:`ReplayError` naming the file and the problem.  The frames run in
chunks; Ctrl-C is acted on between chunks, never inside compiled code.

Memory grows neither with the number of frames nor with the number of contacts: an .npz
trajectory is read :data:`READ_FRAMES` frames at a time (:class:`Trajectory`: one pass that
checks every frame, then one that replays them), and what the replay reports (the first
contacts, the runs of frames each pair spends in contact) goes to temporary files as it is
found (:mod:`mjccd.spool`), from which the reports are written piece by piece.

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
import warnings
import zipfile
import zlib
from contextlib import ExitStack, closing, contextmanager
from dataclasses import dataclass, field, fields
from functools import cached_property

import numpy as np

from mjccd import interrupts, npz_stream
from mjccd.spool import ArraySpool, JsonSpool
from mjccd.errors import InputError, MjccdError, OutputError
from mjccd.files import OutputFolder
from mjccd.mujoco import adapter
from mjccd.mujoco.adapter import ModelAdapter
from mjccd.mujoco.geoms import GeomChecker
from mjccd.mujoco.monitor import check_mode
from mjccd.mujoco.ellipsoids import EllipsoidSet, body_label, geom_ellipsoids, geom_id, geom_label
from mjccd.mujoco.motions import State, as_state
from mjccd.mujoco.pairs import PAIR_RULES, every_plane_pair, pairs_with_reason, plane_pairs
from mjccd.mujoco.warnings import CoverageWarning
from mjccd.scene import FrameCounters
from mjccd._command import PlainHelpFormatter, whole_number

MOTIONS = ("rigid", "affine", "chain")
PLANE_RULES = ("all", "mujoco", "none")  # which static planes each ellipsoid is checked against (replay_planes)
# filter counters, summed over the frames (the fields of mjccd.scene.FrameCounters)
COUNTER_NAMES = tuple(f.name for f in fields(FrameCounters))
OUTPUT_PATTERNS = ("contacts.json", "contacts.csv", "timeline.png", "frame_*.png")  # every file replay writes
# frame intervals per chunk of compiled work (Ctrl-C and the progress bar act between chunks): a few
# milliseconds of scene kernels; chain frames whose pairs pass the filters cost an exact solve (ms) each
CHUNK_FRAMES = {"rigid": 64, "affine": 64, "chain": 16}
READ_FRAMES = 4096  # frames read from a trajectory .npz at a time (5.6 MB of qpos for the boxing scene)
PLOT_BARS = 4000    # a timeline row with more contact runs (or first contacts) is thinned to about this many
NPZ_ARRAYS = ("qpos", "time", "keyframes")  # the arrays a trajectory .npz may hold
RADIUS_RANGE = (1e-6, 1e6)   # metres; semi-axes outside it overflow or lose all precision in the solver
COORDINATE_LIMIT = 1e6   # largest |qpos| value and ellipsoid centre coordinate (metres), for the same reason
TIME_LIMIT = 1e12        # largest |time| in seconds
MIN_QUATERNION_NORM = 1e-12  # shorter joint quaternions are refused (MuJoCo would make them the identity)
# one run of frame intervals a pair spends in contact: intervals first to last, from time start to time end
RUN_DTYPE = np.dtype([("pair", np.int64), ("first", np.int64), ("last", np.int64), ("start", np.float64),
                      ("end", np.float64)])


class ReplayError(InputError):
    """Bad replay input: the message names the file or field and what is wrong."""


# ---------------------------------------------------------------- model and trajectory


def _reason(exc):
    """The first line of an exception's message, or its type when it has none."""
    text = str(exc).strip()
    return text.splitlines()[0] if text else type(exc).__name__


def load_model(model_path):
    """Compile an MJCF file (:func:`mjccd.mujoco.load_model`); errors name the file, as :class:`ReplayError`."""
    try:
        return adapter.load_model(pathlib.Path(model_path))
    except InputError as exc:
        raise ReplayError(str(exc)) from None


def replay_ellipsoids(model, pairs=None, source="model"):
    """``(ellipsoids, pairs)``: the model's bounding ellipsoids (:class:`~mjccd.mujoco.EllipsoidSet`) and the
    (P, 2) pairs to check (see the module docstring).

    ``pairs``: ellipsoid index pairs; ``"characters"`` (:func:`mjccd.mujoco.pairs.character_pairs`);
    ``"self"`` (:func:`mjccd.mujoco.pairs.self_pairs`); or None: ``"characters"``, and when all the
    ellipsoids hang under one top-level body, ``"self"`` instead, said by a
    :class:`~mjccd.mujoco.warnings.CoverageWarning`.  ``source`` (the model file) starts the error messages.
    """
    try:
        ellipsoids = geom_ellipsoids(model, any_group=True)
    except InputError as exc:
        raise ReplayError(f"{source}: {exc}") from None
    if len(ellipsoids) < 2:
        raise ReplayError(f"{source}: needs at least two ellipsoid geoms to check, found {len(ellipsoids)}")
    low, high = RADIUS_RANGE
    bad = np.flatnonzero(~np.all((ellipsoids.radii >= low) & (ellipsoids.radii <= high), axis=1))
    if len(bad):
        raise ReplayError(f"{source}: ellipsoid {ellipsoids.geoms[bad[0]]!r} has semi-axes "
                          f"{ellipsoids.radii[bad[0]].tolist()}; replay supports {low:g} to {high:g} m")
    if pairs is None or isinstance(pairs, str):
        if pairs is not None and pairs not in PAIR_RULES:
            raise ReplayError(f"pairs: expected one of {', '.join(PAIR_RULES)}, or ellipsoid index pairs, "
                              f"got {pairs!r}")
        ids = ellipsoids.body_ids(model)
        chosen, why = pairs_with_reason(model, ellipsoids, pairs or "characters", ids)
        tops = set(model.body_rootid[ids].tolist())
        if pairs is None and not len(chosen) and len(tops) == 1:
            chosen, why = pairs_with_reason(model, ellipsoids, "self", ids)
            if len(chosen):
                top = body_label(model, tops.pop())
                warnings.warn(f"{source}: one character ({top!r}): checking its self-collisions, {len(chosen)} "
                              f"pairs of ellipsoids on bodies neither rigidly joined nor parent and child "
                              f"(--pairs self)", CoverageWarning, stacklevel=2)
        if not len(chosen):
            raise ReplayError(f"{source}: {why}")
        pairs = chosen
    try:
        pairs = adapter.checked_pairs(pairs, len(ellipsoids))
    except InputError as exc:
        raise ReplayError(str(exc)) from None
    return ellipsoids, pairs


def replay_planes(model, ellipsoids, planes="all"):
    """(Q, 2) rows (ellipsoid index, plane geom id) of the static planes to check: ``"all"``
    (:func:`~mjccd.mujoco.pairs.every_plane_pair`: every ellipsoid that moves against every static plane),
    ``"mujoco"`` (:func:`~mjccd.mujoco.pairs.plane_pairs`: MuJoCo's collision rules) or ``"none"``."""
    if planes not in PLANE_RULES:
        raise ReplayError(f"planes: expected one of {', '.join(PLANE_RULES)}, got {planes!r}")
    if planes == "none":
        return np.zeros((0, 2), dtype=np.int64)
    return every_plane_pair(model, ellipsoids) if planes == "all" else plane_pairs(model, ellipsoids)


def geom_row_labels(checker):
    """A short label per checked geom for reports: its body's name, or its geom's when the body holds several."""
    bodies = [checker.labels[int(b)] for b in checker.body]
    return [body if bodies.count(body) == 1 else geom for geom, body in zip(checker.labels_of_rows, bodies)]


def ellipsoid_labels(ellipsoids):
    """A short label per ellipsoid for reports: its body's name, or its geom's (less ``_bound``) when the body
    holds several."""
    bodies = ellipsoids.bodies
    return [body if bodies.count(body) == 1 else geom.removesuffix("_bound")
            for geom, body in zip(ellipsoids.geoms, bodies)]


def load_trajectory(traj, model):
    """``(qpos (T, nq), time (T))`` from an .npz (qpos, time) or a .bvh clip made for this model.

    Refuses, naming the file and the frame, what MuJoCo would silently change
    (a zero joint quaternion) and what the solver cannot use (NaN, infinity,
    values beyond :data:`COORDINATE_LIMIT`, complex numbers); ``time``, when
    given, must increase.  These are whole arrays: :class:`Trajectory` reads
    the same file, with the same checks, a few frames at a time.
    """
    trajectory = Trajectory(traj, model)
    return trajectory.qpos(), trajectory.times()


def load_keyframes(traj, model):
    """The ``keyframes`` (K >= 2, nq) of a trajectory .npz, checked like ``qpos`` (for ``--intervals``)."""
    path = _input_file(traj, "trajectory")
    arrays = read_npz(path, keep=("keyframes",)) if path.suffix.lower() == ".npz" else {}
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


def read_npz(path, keep=None):
    """The arrays of a trajectory .npz by name; a file that is not one, or unknown arrays, raise ReplayError.

    ``keep``: the names of the arrays to return (default: all); the others are read through and
    dropped, so that a damaged one is refused all the same.
    """
    arrays = {}
    with _npz_archive(path) as (npz, names):
        for name in names:
            with npz_stream.Member(npz, name) as member:
                if keep is None or name in keep:
                    arrays[name] = member.read()
                else:
                    member.discard()
    return arrays


@contextmanager
def _npz_archive(path):
    """The open archive (a ``numpy.lib.npyio.NpzFile``) of a trajectory .npz and its sorted array names.

    Refuses a file that is not an .npz, one without ``qpos`` and one with unknown arrays; inside
    the ``with``, what reading the archive raises (a damaged or truncated member, a bad .npy
    header, an object array) becomes a :class:`ReplayError` naming the file.
    """
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
        with npz_stream.open_npz(path) as npz:
            names = sorted(npz.files)
            if "qpos" not in names:
                raise ReplayError(f"{path}: no 'qpos' array (has {names})")
            extra = [n for n in names if n not in NPZ_ARRAYS]
            if extra:
                raise ReplayError(f"{path}: unexpected arrays {extra} (a trajectory holds 'qpos', "
                                  "optionally 'time' and 'keyframes')")
            yield npz, names
    except ReplayError:
        raise
    except zipfile.BadZipFile as exc:
        raise ReplayError(f"{path}: damaged or truncated .npz archive ({_reason(exc)})") from None
    except (OSError, ValueError, EOFError, zlib.error, MemoryError) as exc:
        raise ReplayError(f"{path}: not a readable .npz archive ({_reason(exc)})") from None


class Trajectory:
    """A trajectory file, checked frame by frame when opened, then read :attr:`read_frames` frames at a time.

    Opening an .npz reads every frame once and refuses what :func:`load_trajectory` refuses,
    with the same messages (file, frame, joint) and in the same order, keeping none of the
    frames; :meth:`chunks` then reads them again, in order.  Memory does not grow with the
    number of frames, except for a ``qpos`` stored in Fortran order (read whole, it cannot be
    read by rows) and a .bvh clip (converted whole by :mod:`mjccd.bvh` and kept; ``arrays``: its ``(qpos, time)``
    when the caller has converted it already).
    """

    def __init__(self, traj, model, read_frames=READ_FRAMES, *, arrays=None):
        if not (isinstance(read_frames, (int, np.integer)) and read_frames >= 1):
            raise ReplayError(f"read_frames: expected a positive integer, got {read_frames!r}")
        self.source = traj
        self.model = model
        self.read_frames = int(read_frames)
        self.path = _input_file(traj, "trajectory")
        self.has_time = False   # an .npz with a 'time' array (else time = frame * model.opt.timestep)
        self._arrays = None     # (qpos, time) of a .bvh clip
        suffix = self.path.suffix.lower()
        if suffix == ".bvh":
            from mjccd import bvh

            # ``arrays``: the clip's (qpos, time) when the caller imported it already (mjccd.collection)
            _, qpos, time, _ = bvh.import_bvh(self.path) if arrays is None else (None, *arrays, None)
            qpos = check_qpos(qpos, model, traj)
            if time is None:
                time = self._computed_times(0, qpos.shape[0])
            self._arrays = qpos, _check_time(time, qpos.shape[0], traj)
            self.n_frames = qpos.shape[0]
        elif suffix == ".npz":
            self.n_frames = self._scan()
        else:
            raise ReplayError(f"{traj}: unknown trajectory type {self.path.suffix!r} (expected .npz or .bvh)")

    def _computed_times(self, first, stop):
        return np.arange(first, stop) * self.model.opt.timestep

    def _scan(self):
        """Read and check every array of the .npz; the number of frames.

        Read errors stop at once (members in name order, as :func:`read_npz` reads them); the
        problems of the values are kept until every member has been read, then the first
        ``qpos`` problem, else the first ``time`` problem, is raised.
        """
        qpos_problem = time_problem = None
        frames = 0
        with _npz_archive(self.path) as (npz, names):
            for name in names:  # 'keyframes' < 'qpos' < 'time'
                with npz_stream.Member(npz, name) as member:
                    if name == "qpos":
                        qpos_problem, frames = self._scan_qpos(member)
                    elif name == "time":
                        self.has_time = True
                        if qpos_problem is None:
                            time_problem = self._scan_time(member, frames)
                        else:
                            member.discard()
                    else:
                        member.discard()
        if qpos_problem is None and not self.has_time:
            check = _TimeCheck(self.source)
            for first in range(0, frames, self.read_frames):
                check.rows(self._computed_times(first, min(first + self.read_frames, frames)), first)
            time_problem = check.finish()
        problem = qpos_problem or time_problem
        if problem:
            raise ReplayError(problem)
        return frames

    def _scan_qpos(self, member):
        """(the problem :func:`check_qpos` would report, or None; frames) of the ``qpos`` member."""
        problem = (_member_problem(member, self.source, "qpos")
                   or _qpos_shape_problem(_checked_shape(member), self.model, self.source, "qpos"))
        if problem:
            member.discard()
            return problem, 0
        check = _QposCheck(self.model, self.source)
        first = 0
        for rows in member.rows(self.read_frames):
            check.rows(np.ascontiguousarray(rows, dtype=np.float64), first)
            first += len(rows)
        return check.finish(), member.shape[0]

    def _scan_time(self, member, frames):
        """The problem :func:`_check_time` would report for the ``time`` member, or None."""
        problem = _member_problem(member, self.source, "time")
        if problem is None and _checked_shape(member) != (frames,):
            problem = f"{self.source}: time must have shape ({frames},), got {_checked_shape(member)}"
        if problem:
            member.discard()
            return problem
        check = _TimeCheck(self.source)
        first = 0
        for values in member.rows(self.read_frames):
            check.rows(np.ascontiguousarray(values, dtype=np.float64), first)
            first += len(values)
        return check.finish()

    def _changed(self):
        return ReplayError(f"{self.source}: the trajectory file changed after it was checked; replay it again")

    def chunks(self):
        """``(first, qpos (r, nq), time (r,))``, float64, for frames ``first`` to ``first + r - 1``, in order.

        The frames are checked again as they are read (a file changed since it was opened is
        refused, not replayed).
        """
        step = self.read_frames
        if self._arrays is not None:
            qpos, time = self._arrays
            for first in range(0, self.n_frames, step):
                yield first, qpos[first:first + step], time[first:first + step]
            return
        qpos_check, time_check = _QposCheck(self.model, self.source), _TimeCheck(self.source)
        first = 0
        with _npz_archive(self.path) as (npz, _), ExitStack() as members:
            member = members.enter_context(npz_stream.Member(npz, "qpos"))
            if not member.is_array or tuple(member.shape) != (self.n_frames, self.model.nq):
                raise self._changed()
            times = None
            if self.has_time:
                time_member = members.enter_context(npz_stream.Member(npz, "time"))
                if not time_member.is_array or tuple(time_member.shape) != (self.n_frames,):
                    raise self._changed()
                times = time_member.rows(step)
            for rows in member.rows(step):
                qpos = np.ascontiguousarray(rows, dtype=np.float64)
                if times is None:
                    time = self._computed_times(first, first + len(qpos))
                else:
                    time = next(times, None)
                    if time is None or len(time) != len(qpos):
                        raise self._changed()
                    time = np.ascontiguousarray(time, dtype=np.float64)
                qpos_check.rows(qpos, first)
                time_check.rows(time, first)
                problem = qpos_check.finish() or time_check.finish()
                if problem:
                    raise ReplayError(problem)
                yield first, qpos, time
                first += len(qpos)
        if first != self.n_frames:
            raise self._changed()

    def qpos(self):
        """The whole (T, nq) ``qpos``, read again from the file (a .bvh clip: the converted one)."""
        if self._arrays is not None:
            return self._arrays[0]
        with _npz_archive(self.path) as (npz, _):
            with npz_stream.Member(npz, "qpos") as member:
                values = member.read()
        return check_qpos(values, self.model, self.source)

    def times(self):
        """The whole (T,) frame times, read again from the file or computed from the model's timestep."""
        if self._arrays is not None:
            return self._arrays[1]
        if not self.has_time:
            return self._computed_times(0, self.n_frames)
        with _npz_archive(self.path) as (npz, _):
            with npz_stream.Member(npz, "time") as member:
                values = member.read()
        return _check_time(values, self.n_frames, self.source)


def _dtype_problem(dtype, source, field):
    """Why an array of ``dtype`` cannot be used as real numbers (None: it can)."""
    if dtype.kind == "c":
        return f"{source}: {field} holds complex numbers ({dtype}); expected real numbers"
    if dtype.kind not in "fiu":
        return f"{source}: {field} has dtype {dtype}, expected real numbers"
    return None


def _member_problem(member, source, field):
    """What :func:`_real_array` would refuse in an .npz member, known from its header alone (None: nothing)."""
    if not member.is_array:
        return f"{source}: {field} is not a numpy array (got bytes)"
    return _dtype_problem(member.dtype, source, field)


def _checked_shape(member):
    """The shape :func:`_real_array` gives the member's array (it makes a 0-d array 1-d)."""
    return tuple(member.shape) if len(member.shape) else np.ascontiguousarray(np.float64(0.0)).shape


def _real_array(values, source, field):
    """``values`` as float64, refusing complex numbers (their imaginary part would be lost) and non-numbers."""
    if not isinstance(values, np.ndarray):
        raise ReplayError(f"{source}: {field} is not a numpy array (got {type(values).__name__})")
    problem = _dtype_problem(values.dtype, source, field)
    if problem:
        raise ReplayError(problem)
    return np.ascontiguousarray(values, dtype=np.float64)


def _qpos_shape_problem(shape, model, source, field):
    """Why ``qpos`` of this shape does not fit the model (None: it does)."""
    if len(shape) != 2 or shape[1] != model.nq:
        return f"{source}: {field} must have shape (T, {model.nq}) for this model, got {shape}"
    if shape[0] < 2:
        return f"{source}: {field} needs at least 2 frames, got {shape[0]}"
    return None


def check_qpos(values, model, source, field="qpos"):
    """(T >= 2, nq) joint positions as float64; errors name ``source``, ``field``, the frame and the joint."""
    qpos = _real_array(values, source, field)
    problem = _qpos_shape_problem(qpos.shape, model, source, field)
    if problem:
        raise ReplayError(problem)
    return _checked_whole(_QposCheck(model, source, field), qpos)


def _checked_whole(check, values):
    """``values``, all of them fed to a chunk check (:class:`_QposCheck`, :class:`_TimeCheck`) at once; its
    problem raised."""
    check.rows(values, 0)
    problem = check.finish()
    if problem:
        raise ReplayError(problem)
    return values


class _QposCheck:
    """The value checks of :func:`check_qpos`, fed the frames a chunk at a time, in order.

    :meth:`finish` gives the message check_qpos would give for all the frames fed: the first
    value (frame by frame, then joint by joint) that is not finite or beyond
    :data:`COORDINATE_LIMIT`, else the first zero quaternion of the first joint that has one.
    """

    def __init__(self, model, source, field="qpos"):
        import mujoco

        self.source, self.field = source, field
        self.joint_of = _qpos_joints(model)
        kinds = {int(mujoco.mjtJoint.mjJNT_FREE): "free", int(mujoco.mjtJoint.mjJNT_BALL): "ball"}
        self.quaternions = []   # (joint, kind, qpos address of its quaternion, name)
        for j in range(model.njnt):
            kind_name = kinds.get(int(model.jnt_type[j]))
            if kind_name is not None:
                a = model.jnt_qposadr[j] + (3 if kind_name == "free" else 0)
                self.quaternions.append((j, kind_name, a, _joint_name(model, j)))
        self.beyond = None      # message of the first value beyond the limit
        self.zero = {}          # joint -> message of its first zero quaternion

    def rows(self, qpos, first):
        """Check the float64 frames ``qpos`` (r, nq), frame numbers ``first`` to ``first + r - 1``."""
        if self.beyond is not None:
            return
        bad = np.argwhere(~(np.abs(qpos) <= COORDINATE_LIMIT))  # NaN fails too
        if len(bad):
            k, a = bad[0]
            problem = "is not a finite number" if not np.isfinite(qpos[k, a]) else f"is beyond ±{COORDINATE_LIMIT:g}"
            frame = first + k
            self.beyond = (f"{self.source}: {self.field}[{frame}, {a}] = {qpos[k, a]:g} (frame {frame}, joint "
                           f"{self.joint_of[a]!r}) {problem}")
            return
        for j, kind_name, a, name in self.quaternions:
            if j in self.zero:
                continue
            norms = np.linalg.norm(qpos[:, a:a + 4], axis=1)
            zero = np.nonzero(norms < MIN_QUATERNION_NORM)[0]
            if len(zero):
                frame = first + zero[0]
                self.zero[j] = (f"{self.source}: {self.field}[{frame}, {a}:{a + 4}] (frame {frame}): the quaternion "
                                f"of {kind_name} joint {name!r} is zero (norm {norms[zero[0]]:g}); "
                                "MuJoCo would silently make it the identity")

    def finish(self):
        """The message of the problem found so far (None: none)."""
        if self.beyond is not None:
            return self.beyond
        return self.zero[min(self.zero)] if self.zero else None


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
    return _checked_whole(_TimeCheck(source), time)


class _TimeCheck:
    """The value checks of :func:`_check_time`, fed the times a chunk at a time, in order.

    :meth:`finish` gives the message _check_time would give for all the times fed: the first
    time that is not finite or beyond :data:`TIME_LIMIT`, else the first that does not increase.
    """

    def __init__(self, source):
        self.source = source
        self.bad = self.back = None
        self.last = None   # the last time fed

    def rows(self, time, first):
        """Check the float64 times ``time`` (r,) of frames ``first`` to ``first + r - 1``."""
        if self.bad is None:
            bad = np.nonzero(~(np.abs(time) <= TIME_LIMIT))[0]
            if len(bad):
                self.bad = (f"{self.source}: time[{first + bad[0]}] = {time[bad[0]]:g} must be finite and within "
                            f"±{TIME_LIMIT:g} s")
        if self.back is None and len(time):
            steps = np.diff(time if self.last is None else np.concatenate([[self.last], time])) <= 0
            if steps.any():
                k = int(np.nonzero(steps)[0][0]) + first - (self.last is not None)
                self.back = f"{self.source}: time must increase, but time[{k + 1}] <= time[{k}]"
        if len(time):
            self.last = time[-1]

    def finish(self):
        """The message of the problem found so far (None: none)."""
        return self.bad or self.back


# ---------------------------------------------------------------- replay


@dataclass
class ReplayResult:
    """Everything a replay found.

    ``ellipsoids`` (:class:`~mjccd.mujoco.EllipsoidSet`) are the model's bounding ellipsoids,
    ``pairs`` (P, 2) the pairs checked, ``plane_pairs`` (Q, 2) the (ellipsoid, plane geom) pairs checked and
    ``labels`` a short name per ellipsoid.  ``contacts`` are the first contacts (dicts, as in
    ``contacts.json``, in a :class:`~mjccd.spool.JsonSpool`: a list kept on disk).  ``runs`` are the
    runs of frame intervals a pair (an index into ``pairs``, or P + a row of ``plane_pairs``;
    :meth:`names` gives its names) spends in contact (or possibly in contact: an uncertain result),
    as :data:`RUN_DTYPE` records on disk; :attr:`overlaps` gives them by pair.
    ``frames_in_contact`` counts the frame intervals with any pair in contact; ``time_range`` is
    the times of the first and the last frame.

    Nothing per frame is kept: ``time`` (T,) and ``in_contact`` ((T - 1, P + Q) flags, made from
    the runs) are built on first use and kept from then on; ``time`` is read again from the
    trajectory file.
    """

    model: str
    trajectory: str
    motion: str
    n_frames: int
    ellipsoids: EllipsoidSet
    pairs: np.ndarray
    labels: list
    contacts: JsonSpool = field(default_factory=JsonSpool)
    runs: ArraySpool = field(default_factory=lambda: ArraySpool(RUN_DTYPE), repr=False, compare=False)
    frames_in_contact: int = 0
    time_range: tuple = (0.0, 0.0)
    counters: dict = field(default_factory=dict)
    timing: dict = field(default_factory=dict)
    files: list = field(default_factory=list)
    source: Trajectory = field(default=None, repr=False, compare=False)  # where ``time`` is read from
    plane_pairs: np.ndarray = field(default_factory=lambda: np.zeros((0, 2), dtype=np.int64))
    plane_names: dict = field(default_factory=dict)  # plane geom id -> (geom name, body name)
    mode: str = "ellipsoids"
    geoms: object = field(default=None, repr=False, compare=False)  # geoms mode: the GeomChecker
    # the character (top-level body) and the rigid part (the body its body is welded to) of each part's body, by
    # part (geom row or ellipsoid): the timeline's rows and the rendered highlights group by them
    characters: list = field(default_factory=list, repr=False, compare=False)
    rigid_parts: list = field(default_factory=list, repr=False, compare=False)

    @property
    def part_key(self):
        """What a contact's two parts are in contacts.json: "geoms" (geoms mode) or "ellipsoids"."""
        return "geoms" if self.mode == "geoms" else "ellipsoids"

    @property
    def parts(self):
        """The names of the parts checked: geoms (geoms mode) or ellipsoids."""
        return self.geoms.labels_of_rows if self.mode == "geoms" else list(self.ellipsoids.geoms)

    def on_plane(self, p):
        """Whether pair ``p`` is a part against a static plane (the plane second)."""
        if self.mode == "geoms":
            return self.geoms.is_plane(int(self.pairs[p][1]))
        return p >= len(self.pairs)

    def _first_part(self, p):
        return int(self.pairs[p][0]) if self.mode == "geoms" or p < len(self.pairs) else \
            int(self.plane_pairs[p - len(self.pairs)][0])

    def character(self, p):
        """The character (top-level body) of pair ``p``'s first part."""
        return self.characters[self._first_part(p)]

    def group(self, p):
        """``(key, label)`` of what pair ``p`` is shown as (a timeline row, a highlight): a character against a plane
        for a plane pair, else the two rigid parts (each the body its part's body is welded to: a hand for the
        fingers fixed to it)."""
        if self.on_plane(p):
            key = (self.character(p), self.names(p)[0][1])
            return key, f"{key[0]} (any part) / {key[1]}"
        key = tuple(sorted(self.rigid_parts[int(x)] for x in self.pairs[p]))
        return key, f"{key[0]} / {key[1]}"

    @property
    def n_checked(self):
        """P + Q: the pairs of ellipsoids and the (ellipsoid, plane) pairs."""
        return len(self.pairs) + len(self.plane_pairs)

    def names(self, p):
        """``(parts, bodies, labels)`` of pair ``p`` (geoms mode: two geoms; else below P: two ellipsoids, from P
        on: an ellipsoid and a plane, named by its geom and its body), each a list of two names, as contacts.json
        gives them."""
        ell = self.ellipsoids
        if self.mode == "geoms":
            g = self.geoms
            a, b = (int(x) for x in self.pairs[p])
            parts = [g.labels_of_rows[a], g.labels_of_rows[b]]
            bodies = [g.labels[int(g.body[a])], g.labels[int(g.body[b])]]
            return parts, bodies, [self.labels[a], self.labels[b]]
        if p < len(self.pairs):
            i, j = (int(x) for x in self.pairs[p])
            return [ell.geoms[i], ell.geoms[j]], [ell.bodies[i], ell.bodies[j]], [self.labels[i], self.labels[j]]
        i, g = (int(x) for x in self.plane_pairs[p - len(self.pairs)])
        geom, body = self.plane_names[g]
        return [ell.geoms[i], geom], [ell.bodies[i], body], [self.labels[i], geom]

    def pair_runs(self):
        """``(pair, runs)`` of each pair ever in contact, in pair order; ``runs``: its :data:`RUN_DTYPE` records in
        time order."""
        runs = self.runs.array()
        runs = runs[np.argsort(runs["pair"], kind="stable")]
        cuts = np.flatnonzero(np.diff(runs["pair"])) + 1
        for group in np.split(runs, cuts) if len(runs) else ():
            yield int(group["pair"][0]), group

    @property
    def overlaps(self):
        """Pair -> its runs of frame intervals in contact, each ``(first, last, time[first], time[last + 1])``, in
        order (made from :attr:`runs` on each use)."""
        return {p: [(a, b, t0, t1) for _, a, b, t0, t1 in group.tolist()] for p, group in self.pair_runs()}

    @property
    def pairs_in_contact(self):
        """How many pairs were ever in contact."""
        return len(np.unique(self.runs.array()["pair"]))

    @cached_property
    def time(self):
        """The (T,) frame times, read from the trajectory on first use."""
        return self.source.times()

    @cached_property
    def in_contact(self):
        """(T - 1, P + Q) flags: pair p in contact during frame interval k (made on first use)."""
        flags = np.zeros((self.n_frames - 1, self.n_checked), dtype=bool)
        for p, first, last, _, _ in self.runs.array().tolist():
            flags[first:last + 1, p] = True
        return flags


def replay(model_path, traj, motion="rigid", out_dir=None, *, pairs=None, planes="all", progress=True, render=True,
           max_rendered=4, force=False, chunk_frames=None, read_frames=None, mode=None):
    """Replay a trajectory on a model and find every first contact of its geoms (geoms mode, the default with the
    rigid motion) or of their bounding ellipsoids.

    Args:
        model_path: MJCF file with bounding ellipsoid geoms (group 5).
        traj: ``.npz`` with ``qpos`` (T, nq) and ``time`` (T), or a ``.bvh`` clip.
        motion: ``"rigid"``, ``"affine"`` or ``"chain"`` between consecutive frames.
        out_dir: where to write contacts.json, contacts.csv, timeline.png and frames (None: nothing);
            a folder holding another run's files is refused unless ``force`` (see :class:`OutputFolder`).
        pairs: (P, 2) ellipsoid index pairs to check, ``"characters"`` or ``"self"``; None: the default
            (see :func:`replay_ellipsoids`).
        planes: the static planes each ellipsoid is checked against: ``"all"``, ``"mujoco"`` or ``"none"``
            (see :func:`replay_planes`).
        chunk_frames: frame intervals per chunk of compiled work (Ctrl-C is acted on between chunks);
            None: the motion's :data:`CHUNK_FRAMES`.  The results do not depend on it.
        read_frames: frames read from the trajectory file at a time (None: :data:`READ_FRAMES`); the
            results do not depend on it either.
        mode: "geoms": the model's own geoms, exact (:mod:`mjccd.mujoco.geoms`: its collision geoms, or in a
            model where nothing collides its visual geoms, never the bounds), on the body pairs the ellipsoid
            pairs name; "ellipsoids": the bounds; None: geoms with the rigid motion, ellipsoids otherwise.
    Returns:
        a :class:`ReplayResult`.
    """
    chunk_frames, mode = _checked_options(motion, chunk_frames, planes, mode)
    read_frames = READ_FRAMES if read_frames is None else read_frames
    if not (isinstance(read_frames, (int, np.integer)) and read_frames >= 1):  # before the model is loaded
        raise ReplayError(f"read_frames: expected a positive integer, got {read_frames!r}")
    model = load_model(model_path)
    ellipsoids, pairs = replay_ellipsoids(model, pairs, source=str(model_path))
    trajectory = Trajectory(traj, model, read_frames)  # reads and checks every frame, keeps none
    folder = None if out_dir is None else output_folder(out_dir, force)
    checker, result = _prepared(model, str(model_path), trajectory, motion, ellipsoids, pairs, planes, mode)
    highlights = Highlights(max_rendered) if folder is not None and render else None  # what render_frames draws
    if folder is None:
        _run(checker, trajectory, result, progress, chunk_frames, highlights)
        return result
    with folder:  # locked for the whole run; the earlier run's files stay until this one is complete
        _run(checker, trajectory, result, progress, chunk_frames, highlights)
        try:
            write_reports(result, folder)
            if render:
                render_frames(model, highlights.chosen(), folder, bounds=mode != "geoms")
        except OutputError:
            raise
        except OSError as exc:
            raise OutputError(f"{exc.filename or out_dir}: cannot write: {exc.strerror or _reason(exc)}") from None
    result.files = [str(folder.file_path(name)) for name in folder.written]
    return result


def replay_trajectory(model, trajectory, motion="rigid", *, source="model", pairs=None, planes="all", mode=None,
                      chunk_frames=None, progress=False):
    """:func:`replay` of a compiled model and an opened :class:`Trajectory`, with no output folder: what
    :mod:`mjccd.collection` runs on each clip.  ``source`` names the model in messages and in the result."""
    chunk_frames, mode = _checked_options(motion, chunk_frames, planes, mode)
    ellipsoids, pairs = replay_ellipsoids(model, pairs, source=source)
    checker, result = _prepared(model, source, trajectory, motion, ellipsoids, pairs, planes, mode)
    _run(checker, trajectory, result, progress, chunk_frames)
    return result


def _checked_options(motion, chunk_frames, planes, mode):
    """``(chunk_frames, mode)`` with their defaults filled in; a :class:`ReplayError` naming a bad option."""
    if motion not in MOTIONS:
        raise ReplayError(f"motion: expected one of {', '.join(MOTIONS)}, got {motion!r}")
    chunk_frames = CHUNK_FRAMES[motion] if chunk_frames is None else chunk_frames
    if not (isinstance(chunk_frames, (int, np.integer)) and chunk_frames >= 1):
        raise ReplayError(f"chunk_frames: expected a positive integer, got {chunk_frames!r}")
    if planes not in PLANE_RULES:  # before the model is loaded
        raise ReplayError(f"planes: expected one of {', '.join(PLANE_RULES)}, got {planes!r}")
    try:
        return chunk_frames, check_mode(mode, motion)
    except InputError as exc:
        raise ReplayError(str(exc)) from None


def _prepared(model, source, trajectory, motion, ellipsoids, pairs, planes, mode):
    """``(checker, result)``: the geom checker (geoms mode) or the ellipsoids' adapter of ``model``, its
    ``ellipsoids`` and ``pairs`` (:func:`replay_ellipsoids`), and the empty :class:`ReplayResult` the replay of
    ``trajectory`` fills."""
    if mode == "geoms":
        ids = ellipsoids.body_ids(model)
        bodies = sorted({(min(int(ids[i]), int(ids[j])), max(int(ids[i]), int(ids[j]))) for i, j in pairs.tolist()})
        checker = GeomChecker(model, ellipsoids, bodies, planes=False if planes == "none" else planes, stacklevel=3)
        if not len(checker.pairs):
            raise ReplayError(f"{source}: {checker.reason or 'no pair of geoms to check'}")
        result = ReplayResult(source, str(trajectory.source), motion, trajectory.n_frames, ellipsoids, checker.pairs,
                              geom_row_labels(checker), source=trajectory, mode="geoms", geoms=checker,
                              characters=_characters(model, checker.body),
                              rigid_parts=_rigid_parts(model, checker.body))
        return checker, result
    on_planes = replay_planes(model, ellipsoids, planes)
    result = ReplayResult(source, str(trajectory.source), motion, trajectory.n_frames, ellipsoids, pairs,
                          ellipsoid_labels(ellipsoids), source=trajectory, plane_pairs=on_planes,
                          plane_names={g: (geom_label(model, g), body_label(model, model.geom_bodyid[g]))
                                       for g in set(on_planes[:, 1].tolist())},
                          characters=_characters(model, ellipsoids.body_ids(model)),
                          rigid_parts=_rigid_parts(model, ellipsoids.body_ids(model)))
    checker = ModelAdapter(model, ellipsoids, pairs, motion, plane_pairs=on_planes if len(on_planes) else None)
    return checker, result


def _characters(model, body_ids):
    """The name of the top-level body (the character) of each body in ``body_ids``."""
    return [body_label(model, model.body_rootid[int(b)]) for b in body_ids]


def _rigid_parts(model, body_ids):
    """The name of the body each moving body in ``body_ids`` is welded to (itself when it has a joint); a static
    body's own (every static body is welded to the world)."""
    return [body_label(model, model.body_weldid[int(b)] or int(b)) for b in body_ids]


def output_folder(out_dir, force=False):
    """The :class:`OutputFolder` for ``out_dir``, checked before the replay runs so that a bad ``--out`` costs no time.

    Refuses a file, a folder holding another run's files (unless ``force``:
    then this tool's earlier outputs there are replaced once the new run is
    complete), and a path that cannot become a folder.  A second run into a
    folder in use is refused when it starts (the folder's lock).
    """
    folder = OutputFolder(out_dir, "replay", force=force, patterns=OUTPUT_PATTERNS)
    nearest = next(p for p in (folder.path, *folder.path.parents) if p.exists())
    if not nearest.is_dir():
        raise OutputError(f"{out_dir}: cannot create the output folder: {nearest} is a file")
    if not os.access(nearest, os.W_OK | os.X_OK):
        raise OutputError(f"{out_dir}: cannot write into {nearest}: permission denied")
    return folder


def _run(checker, trajectory, result, progress, chunk_frames, highlights=None):
    """Kinematics and the per-frame checks, chunk by chunk of frames read from ``trajectory``; fills ``result``.

    ``checker`` is the :class:`~mjccd.mujoco.ModelAdapter` of the model, its ellipsoids and pairs.
    The chunks run inside :func:`mjccd.interrupts.deferred`: a Ctrl-C raises
    KeyboardInterrupt between two chunks, never inside compiled code.  The
    checker (and its plane caches) carries over from chunk to chunk, so
    the results do not depend on ``chunk_frames`` (nor on how many frames the
    trajectory reads at a time).  ``highlights`` (a :class:`Highlights`) is
    offered every first contact with the qpos rows of its interval's ends: what
    :func:`render_frames` draws.
    """
    model = checker.model
    start = _time.perf_counter()
    if result.mode == "geoms":  # the first compile (or cache load) is not part of the timing
        p = checker.qpos_poses(model.qpos0[None])[0]
        checker.check_poses(0.0, 1.0, p, p, all_pairs=True)
    else:
        warm_up(checker.motion)
        checker.qpos_poses(model.qpos0[None])  # nor is the kinematics kernel's
    t_warm = _time.perf_counter() - start
    mocap = model.body_mocapid >= 0
    mocap_pos, mocap_quat = model.body_pos[mocap].copy(), model.body_quat[mocap].copy()
    counters = dict.fromkeys(COUNTER_NAMES, 0)
    n = trajectory.n_frames - 1
    overlaps = _Overlaps(result.n_checked, result.runs)
    t_first = t_last = None
    t_kin = t_ccd = 0.0
    bar = None
    if progress:
        from tqdm import tqdm

        bar = tqdm(total=n, desc="replay", unit="frame", file=sys.stderr, leave=False,
                   disable=not sys.stderr.isatty())  # a terminal only
    try:
        with interrupts.deferred() as check, closing(_windows(trajectory, chunk_frames)) as windows:
            for first, qpos, time in windows:  # frames first .. stop
                stop = first + len(qpos) - 1
                t_first = time[0] if t_first is None else t_first
                t_last = time[-1]
                start = _time.perf_counter()
                poses = checker.qpos_poses(qpos)
                _check_centres(poses, first, result)
                t_kin += _time.perf_counter() - start
                start = _time.perf_counter()
                flags = np.zeros((stop - first, result.n_checked), dtype=bool)
                states = [State(q, mocap_pos, mocap_quat, float(t)) for q, t in zip(qpos, time)]
                for i in range(stop - first):
                    try:
                        report = checker.check(states[i], states[i + 1], poses=(poses[i], poses[i + 1]),
                                               all_pairs=True)
                    except InputError as exc:
                        raise ReplayError(f"{result.trajectory}: frame {first + i}: {exc}") from None
                    for name, v in report.counters.items():
                        counters[name] += v
                    for p, contact in _record(result, first + i, report, time[i], time[i + 1], flags[i]):
                        if highlights is not None:
                            highlights.offer(result, p, contact, qpos[i], qpos[i + 1])
                overlaps.add(first, flags, time)
                t_ccd += _time.perf_counter() - start
                if bar is not None:
                    bar.update(stop - first)
                check()
    finally:
        if bar is not None:
            bar.close()
    overlaps.close(n, t_last)
    result.frames_in_contact = overlaps.frames
    result.time_range = (float(t_first), float(t_last))
    result.counters = {name: int(v) for name, v in counters.items()}
    result.timing = {"kinematics_s": t_kin, "ccd_s": t_ccd, "intervals": n,
                     "frames_per_s": n / max(t_kin + t_ccd, 1e-12), "warm_up_s": t_warm}


def _check_centres(poses, first, result):
    """Refuse ellipsoid centres beyond :data:`COORDINATE_LIMIT` (say, a huge body offset in the model)."""
    bad = np.argwhere(~np.all(np.abs(poses[:, :, :3]) <= COORDINATE_LIMIT, axis=2))
    if len(bad):
        k, i = bad[0]
        raise ReplayError(f"{result.trajectory}: frame {first + k}: {result.part_key[:-1]} {result.parts[i]!r} of "
                          f"{result.model} is at {poses[k, i, :3].tolist()}, beyond ±{COORDINATE_LIMIT:g} m")


def _windows(trajectory, size):
    """``(first, qpos, time)`` of frames ``first`` to ``first + size`` (fewer at the end), from the trajectory's reads.

    Consecutive windows share a frame: the interval from one to the next is in exactly one window.
    """
    qs, ts, have, first = [], [], 0, 0
    with closing(trajectory.chunks()) as chunks:
        for _, qpos, time in chunks:
            qs.append(qpos)
            ts.append(time)
            have += len(qpos)
            if have < size + 1:
                continue
            q, t = (np.concatenate(qs), np.concatenate(ts)) if len(qs) > 1 else (qs[0], ts[0])
            start = 0
            while len(q) - start >= size + 1:
                yield first, q[start:start + size + 1], t[start:start + size + 1]
                start += size
                first += size
            qs, ts, have = [q[start:]], [t[start:]], len(q) - start
    if have >= 2:
        yield first, np.concatenate(qs), np.concatenate(ts)


class _Overlaps:
    """The runs of frame intervals each pair spends in contact, from (intervals, pairs) flags a chunk at a time;
    each run goes to ``runs`` (a :data:`RUN_DTYPE` :class:`~mjccd.spool.ArraySpool`) when it ends."""

    def __init__(self, pairs, runs):
        self.start = np.full(pairs, -1, dtype=np.int64)  # first interval of each pair's open run (-1: none)
        self.start_time = np.zeros(pairs)
        self.runs = runs
        self.frames = 0    # intervals with any pair in contact

    def add(self, first, flags, time):
        """``flags`` (m, P) of intervals ``first`` to ``first + m - 1``; ``time`` (m + 1,) of their end frames."""
        if len(flags) == 0:
            return
        self.frames += int(np.count_nonzero(flags.any(axis=1)))
        before = np.concatenate([(self.start >= 0)[None], flags[:-1]])
        for r, p in zip(*(idx.tolist() for idx in np.nonzero(flags != before))):
            if flags[r, p]:
                self.start[p], self.start_time[p] = first + r, time[r]
            else:
                self.runs.append((p, int(self.start[p]), first + r - 1, float(self.start_time[p]), float(time[r])))
                self.start[p] = -1

    def close(self, intervals, last_time):
        """End the open runs after the last interval (``intervals`` of them; ``last_time``: the last frame's)."""
        for p in np.nonzero(self.start >= 0)[0].tolist():
            self.runs.append((p, int(self.start[p]), intervals - 1, float(self.start_time[p]), float(last_time)))
            self.start[p] = -1


def _record(result, k, report, t0, t1, flags):
    """Add the first contacts of interval k (frame times ``t0`` to ``t1``; ``report``: its
    :class:`~mjccd.mujoco.StepReport` of every pair) to ``result``, its contact flags to ``flags``; returns
    the ``(pair, contact)`` added.

    A pair is in contact when it touches or overlaps at the start, collides, or may collide (an
    uncertain answer); a first contact is a contact of a pair separate at the start (an uncertain one
    at the start of its bracket, with a zero point and normal).  A plane pair's names are its ellipsoid's
    and its plane geom's.
    """
    dt = t1 - t0
    added = []
    for c in sorted(report.contacts, key=lambda c: (c.fraction, c.pair)):  # in time order, then pair order
        flags[c.pair] = True
        if c.status_at_start != "separate":
            continue
        parts, bodies, labels = result.names(c.pair)
        none = (0.0, 0.0, 0.0)
        contact = {"frame": int(k), "toi": float(c.fraction), "time": float(t0 + c.fraction * dt),
                   result.part_key: parts, "bodies": bodies, "labels": labels,
                   "point": [float(x) for x in (none if c.point is None else c.point)],
                   "normal": [float(x) for x in (none if c.normal is None else c.normal)]}
        if c.elements is not None:
            contact["elements"] = list(c.elements)
        if c.certainty != "certified":
            contact["certainty"] = c.certainty
        result.contacts.append(contact)
        added.append((c.pair, contact))
    return added


def warm_up(motion="rigid"):
    """Compile (or load from the cache) the per-frame kernels before timing a replay."""
    if motion == "chain":  # the chain filters and one exact chain solve (a contact)
        from mjccd import Ball, Chain, Ellipsoid, Fixed, Hinge, first_contact
        from mjccd.chain_bounds import ChainFilter, program_from_elements

        chains = [Chain([Hinge((0.0, 0.0, 1.0), 0.0, 0.5), Fixed((2.0, 0.0, 0.0))]),
                  Chain([Fixed((1.5, 1.5, 0.0)), Ball((1.0, 0.0, 0.0, 0.0), (0.9, 0.3, 0.0, 0.0)),
                         Fixed((0.0, -0.5, 0.0))])]
        program, q0, q1 = program_from_elements(chains)
        ChainFilter(program, [[0.5, 0.3, 0.3]] * 2, [[0, 1]]).step(q0, q1)
        first_contact(Ellipsoid([0.5, 0.3, 0.3]), chains[0], Ellipsoid([0.5, 0.3, 0.3]), chains[1])
        return
    from mjccd.scene import Scene

    poses0 = np.array([[0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0], [3.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0]])
    poses1 = np.array([[0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0], [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0]])
    Scene([[1.0, 0.5, 0.5]] * 2, motion=motion).step(poses0, poses1, all_pairs=True)


def interval_table(checker, qpos0, qpos1, *, repeat=3):
    """All collision intervals of every pair over one chain-motion segment (thesis Table 6 style).

    Each row: the pair, the motion degree (largest degree in t of the two
    motions' scaled inverses), the degree of F in t, the time to build the pair (the
    pair's quadric polynomials and their pencil), the time to build F and solve, and the intervals
    (normalised time).  Times are the best of ``repeat`` runs, after one
    untimed run that compiles.  ``checker``: the :class:`~mjccd.mujoco.ModelAdapter` of the model's
    ellipsoids and pairs.
    """
    from mjccd.ccd import degree_in_t, prepare_pair, solve_balanced

    model, radii = checker.model, checker.radii
    motions = checker.chain_motions(as_state(model, qpos0, "qpos0"), as_state(model, qpos1, "qpos1"))
    labels = ellipsoid_labels(checker.ellipsoids)
    rows = []
    for i, j in checker.pairs:
        best_build = best_solve = math.inf
        for _ in range(repeat + 1):
            t0 = _time.perf_counter()
            qa = motions[i].quadric_bounded_on(radii[i], 0.0, 1.0)
            qb = motions[j].quadric_bounded_on(radii[j], 0.0, 1.0)
            length = float(max(radii[i].max(), radii[j].max()))
            pencil, err, _ = prepare_pair(*qa, *qb, length)
            t1 = _time.perf_counter()
            status0, intervals, _, _, _, _ = solve_balanced(*pencil, err, 1.0, False)
            t2 = _time.perf_counter()
            best_build, best_solve = min(best_build, t1 - t0), min(best_solve, t2 - t1)
        rows.append({"pair": [labels[i], labels[j]],
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
    frames_hit = result.frames_in_contact
    pairs_hit = result.pairs_in_contact
    planes = f", {len(result.plane_pairs)} ellipsoid-plane pairs" if len(result.plane_pairs) else ""
    what = f"{len(result.parts)} geoms" if result.mode == "geoms" else f"{len(result.ellipsoids)} ellipsoids"
    lines = [
        f"{result.n_frames} frames ({t['intervals']} intervals), {what}, "
        f"{len(result.pairs)} pairs{planes}, motion {result.motion}",
        f"first contacts: {len(result.contacts)}; frames with contact: {frames_hit}; "
        f"pairs ever in contact: {pairs_hit}",
        "filter: " + ", ".join(f"{k} {v}" for k, v in c.items()),
        f"time: kinematics {t['kinematics_s'] * 1e3:.1f} ms, CCD {t['ccd_s'] * 1e3:.1f} ms, "
        f"{t['frames_per_s']:.0f} frames/s (before them, compiling or loading the kernels: "
        f"{t['warm_up_s']:.1f} s)",
    ]
    return "\n".join(lines)


def _overlap_spans(result):
    """The ``in_contact`` entries of contacts.json, one at a time: each pair ever in contact, in pair order, and
    its frame runs."""
    for p, runs in result.pair_runs():
        parts, bodies, labels = result.names(p)
        yield {result.part_key: parts, "bodies": bodies, "labels": labels,
               "frames": ([a, b] for a, b in zip(runs["first"].tolist(), runs["last"].tolist()))}


def write_json(fh, value, depth=0):
    """Write ``value`` as ``json.dump(value, fh, indent=1)`` would, but with any iterable (a generator, a
    :class:`~mjccd.spool.JsonSpool`) written as a list item by item, so that it is never held whole in memory."""
    if isinstance(value, dict):
        entries, opening, closing = ((json.dumps(str(k)) + ": ", v) for k, v in value.items()), "{", "}"
    elif isinstance(value, (str, bytes)) or not hasattr(value, "__iter__"):
        fh.write(json.dumps(value))
        return
    else:
        entries, opening, closing = (("", v) for v in value), "[", "]"
    inner, empty = "\n" + " " * (depth + 1), True
    for prefix, item in entries:
        fh.write((opening if empty else ",") + inner + prefix)
        write_json(fh, item, depth + 1)
        empty = False
    fh.write(opening + closing if empty else "\n" + " " * depth + closing)


def write_reports(result, folder):
    """contacts.json, contacts.csv and timeline.png in ``folder`` (an :class:`OutputFolder`), streamed from the
    result's spools."""
    key = result.part_key
    doc = {"version": 1, "model": result.model, "trajectory": result.trajectory, "motion": result.motion,
           "mode": result.mode, "frames": result.n_frames, key: result.parts, "pairs": len(result.pairs),
           "plane_pairs": len(result.plane_pairs),
           "first_contacts": result.contacts, "in_contact": _overlap_spans(result),
           "counters": result.counters, "timing": result.timing}
    with folder.open("contacts.json", "w", encoding="utf-8") as fh:
        write_json(fh, doc)
        fh.write("\n")
    with folder.open("contacts.csv", "w", newline="", encoding="utf-8") as fh:
        w = csv.writer(fh)
        w.writerow(["frame", "time", "toi", f"{key[:-1]}_a", f"{key[:-1]}_b", "body_a", "body_b",
                    "px", "py", "pz", "nx", "ny", "nz"])
        for c in result.contacts:
            w.writerow([c["frame"], repr(c["time"]), repr(c["toi"]), *c[key], *c["bodies"],
                        *map(repr, c["point"]), *map(repr, c["normal"])])
    with folder.open("timeline.png", "wb") as fh:
        plot_timeline(result, fh)


def plot_timeline(result, target):
    """Colliding body pairs over time: bars while in contact, dots at first contacts; PNG into a path or binary file."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    t0, t1 = result.time_range
    gap = (t1 - t0) / PLOT_BARS
    hits_of = {}
    for c in result.contacts:
        hits_of.setdefault(tuple(c[result.part_key]), _ThinTimes(gap)).add(c["time"])
    rows = {}  # group -> (label, contact runs, first-contact times): a row per pair of rigid parts, per character
    for p, runs in result.pair_runs():  # against a plane
        key, label = result.group(p)
        row = rows.setdefault(key, (label, [], []))
        row[1].extend(_thin_runs(list(zip(runs["start"].tolist(), runs["end"].tolist())), gap))
        parts = tuple(result.names(p)[0])
        row[2].extend(hits_of[parts].kept if parts in hits_of else ())
    labels = []
    fig, ax = plt.subplots(figsize=(10, max(2.5, 0.25 * len(rows) + 1.2)))
    for row, (label, runs, hits) in enumerate(rows.values()):
        labels.append(label)
        bars = _thin_runs(_joined(sorted(runs)), gap)
        ax.broken_barh([(a, b - a) for a, b in bars], (row - 0.35, 0.7), facecolors="tab:blue", alpha=0.5)
        times = _thinned_times(sorted(hits), gap)
        ax.plot(times, [row] * len(times), "o", color="tab:red", ms=4)
    ax.set_yticks(range(len(labels)))
    ax.set_yticklabels(labels, fontsize=7)
    ax.set_xlim(t0, t1)
    ax.set_ylim(-1, max(len(labels), 1))
    ax.set_xlabel("time [s]")
    ax.set_title(f"{pathlib.Path(result.model).name}: contacts ({result.motion} motion); red dots: first contacts")
    fig.tight_layout()
    try:
        fig.savefig(target, dpi=110, format="png")
    finally:
        plt.close(fig)


def _joined(runs):
    """Time runs ``(start, end)`` sorted by start, overlapping ones joined."""
    joined = runs[:1]
    for a, b in runs[1:]:
        if a <= joined[-1][1]:
            joined[-1] = (joined[-1][0], max(b, joined[-1][1]))
        else:
            joined.append((a, b))
    return joined


def _thinned_times(times, gap):
    """Sorted times, thinned as :class:`_ThinTimes` thins them."""
    thin = _ThinTimes(gap)
    for x in times:
        thin.add(x)
    return thin.kept


def _thin_runs(runs, gap):
    """Time runs ``(start, end)`` in order; beyond :data:`PLOT_BARS` of them, those less than ``gap`` apart are joined."""
    if len(runs) <= PLOT_BARS:
        return runs
    joined = [runs[0]]
    for a, b in runs[1:]:
        if a - joined[-1][1] < gap:
            joined[-1] = (joined[-1][0], max(b, joined[-1][1]))
        else:
            joined.append((a, b))
    return joined


class _ThinTimes:
    """Times added in order; beyond :data:`PLOT_BARS` of them, only the first and each one at least ``gap`` after
    the last one kept stay (thinning as it goes, so that a row never holds more than the thinned times)."""

    def __init__(self, gap):
        self.gap, self.seen, self.kept = gap, 0, []

    def add(self, x):
        self.seen += 1
        if self.seen == PLOT_BARS + 1:  # from now on the whole row is thinned: thin what is there
            kept = self.kept[:1]
            for y in self.kept[1:]:
                if y - kept[-1] >= self.gap:
                    kept.append(y)
            self.kept = kept
        if self.seen <= PLOT_BARS or x - self.kept[-1] >= self.gap:
            self.kept.append(x)


class Highlights:
    """The first contacts worth a picture, chosen as they come: the first of each pair of rigid parts meeting
    between characters (or within one), then the first of each character against a plane (a foot strike),
    ``count`` in all, one a frame, with the qpos rows of both ends of their frame interval."""

    def __init__(self, count):
        self.count = count
        self.between, self.on_planes = {}, {}  # group (ReplayResult.group) -> (contact, qpos0, qpos1), first kept
        self.frames = set()  # a picture a frame

    def offer(self, result, p, contact, qpos0, qpos1):
        kept = self.on_planes if result.on_plane(p) else self.between
        key = result.group(p)[0]
        if key not in kept and len(kept) < self.count and contact["frame"] not in self.frames:
            kept[key] = (contact, qpos0.copy(), qpos1.copy())
            self.frames.add(contact["frame"])

    def chosen(self):
        """Up to ``count`` of them, in time order: contacts between bodies first, at least one on a plane."""
        between, on_planes = list(self.between.values()), list(self.on_planes.values())
        floor = min(len(on_planes), max(1, self.count - len(between)))
        picked = between[:self.count - floor] + on_planes[:floor]
        return sorted(picked, key=lambda item: item[0]["time"])


def _framing_camera(model, data):
    """A free camera from the side framing every moving body (both boxers, not the floor's extent)."""
    import mujoco

    moving = [b for b in range(1, model.nbody) if model.body_weldid[b] != 0] or list(range(model.nbody))
    low, high = data.xpos[moving].min(axis=0), data.xpos[moving].max(axis=0)
    cam = mujoco.MjvCamera()
    cam.lookat[:] = 0.5 * (low + high)
    cam.distance = 1.6 * float(np.max(high - low)) + 0.8
    cam.azimuth, cam.elevation = 90.0, -8.0
    return cam


def caption(contact):
    """A frame's caption: frame, time and the pair that touched."""
    a, b = contact["labels"]
    return f"frame {contact['frame']}, t = {contact['time']:.3f} s: {a} / {b} ({contact['toi']:.2f} of the interval)"


def render_frames(model, highlights, folder, bounds=True):
    """A captioned PNG per highlight (:meth:`Highlights.chosen`) in ``folder``, the touching geoms (or
    ellipsoids) in red and the camera framing every character; none without OpenGL (one line says so).
    ``bounds``: show the bounding ellipsoids (geom group 5) too."""
    if not highlights:
        return
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import mujoco

    from mjccd.mujoco.render import open_renderer, scene_option

    renderer = open_renderer(model)
    if renderer is None:
        return
    data = mujoco.MjData(model)
    opt = scene_option() if bounds else mujoco.MjvOption()
    rgba = model.geom_rgba.copy()
    try:
        for contact, qpos0, qpos1 in highlights:
            model.geom_rgba[:] = rgba
            for name in contact.get("geoms", contact.get("ellipsoids", ())):
                g = geom_id(model, name)
                if g >= 0 and model.geom_type[g] != mujoco.mjtGeom.mjGEOM_PLANE:
                    model.geom_rgba[g] = (0.9, 0.1, 0.1, 0.8)
            data.qpos[:] = qpos1 if contact["toi"] > 0.5 else qpos0
            mujoco.mj_forward(model, data)
            renderer.update_scene(data, _framing_camera(model, data), scene_option=opt)
            fig, ax = plt.subplots(figsize=(6.4, 5.1))
            ax.imshow(renderer.render())
            ax.set_axis_off()
            ax.set_title(caption(contact), fontsize=8)
            fig.tight_layout()
            try:
                with folder.open(f"frame_{contact['frame']:05d}.png", "wb") as fh:
                    fig.savefig(fh, dpi=100, format="png")
            finally:
                plt.close(fig)
    finally:
        model.geom_rgba[:] = rgba
        renderer.close()


# ---------------------------------------------------------------- command line


def _folder_name(text):
    """argparse type of ``--out``: a non-empty folder name."""
    if not text.strip():
        raise argparse.ArgumentTypeError("expected a folder name, got an empty string")
    return text


@contextmanager
def _coverage_notes():
    """Within the block each distinct :class:`~mjccd.mujoco.warnings.CoverageWarning` (the pairs chosen) is one
    line ``mjccd replay: TEXT`` on stderr, when it is raised; other warnings show as usual."""
    seen = set()
    with warnings.catch_warnings():
        shown = warnings.showwarning

        def show(message, category, filename, lineno, file=None, line=None):
            if not issubclass(category, CoverageWarning):
                shown(message, category, filename, lineno, file, line)
            elif str(message) not in seen:
                seen.add(str(message))
                print(f"mjccd replay: {message}", file=sys.stderr)

        warnings.showwarning = show
        warnings.simplefilter("always", CoverageWarning)
        yield


def main(argv=None):
    """``mjccd replay MODEL.xml TRAJ [--motion ...] [--pairs ...] [--out DIR [--force]]``; returns the exit status."""
    parser = argparse.ArgumentParser(formatter_class=PlainHelpFormatter,
                                     prog="mjccd replay",
                                     description="Replay a trajectory and report the first contacts "
                                                 "of the model's geoms (or of its bounding ellipsoids).")
    parser.add_argument("model", help="MJCF model with bounding ellipsoids (geom group 5)")
    parser.add_argument("traj", help=".npz with qpos (T x nq) and time (T), or a .bvh clip")
    parser.add_argument("--motion", choices=MOTIONS, default="rigid", help="motion between frames")
    parser.add_argument("--mode", choices=("geoms", "ellipsoids"),
                        help="what touches: 'geoms' (the model's own geoms, exact: its collision geoms, or its "
                             "visual geoms when nothing collides; the default with --motion rigid) or "
                             "'ellipsoids' (the bounding ellipsoids; the default with the other motions)")
    parser.add_argument("--pairs", choices=PAIR_RULES,
                        help="pairs to check: 'characters' (ellipsoids under different top-level bodies, at "
                             "least one moving) or 'self' (within each top-level body, bodies neither rigidly "
                             "joined nor parent and child); default: 'characters', or 'self' when the model "
                             "has one character")
    parser.add_argument("--planes", choices=PLANE_RULES, default="all",
                        help="static planes (floors, walls) to check: 'all' (every moving ellipsoid against every "
                             "static plane, the default), 'mujoco' (the pairs MuJoCo's collision rules give) or "
                             "'none'")
    parser.add_argument("--out", type=_folder_name,
                        help="folder for contacts.json, contacts.csv, timeline.png, frames (written only when "
                             "the replay completes; a folder holding another run needs --force)")
    parser.add_argument("--force", action="store_true",
                        help="write into an --out folder that holds an earlier run, removing that run's files")
    parser.add_argument("--no-render", action="store_true", help="do not render frames")
    parser.add_argument("--rows", type=whole_number(0, "rows"), default=30,
                        help="rows of the contact table (default 30)")
    parser.add_argument("--intervals", action="store_true",
                        help="also print every pair's collision intervals over each segment between the "
                             "trajectory's keyframes (npz 'keyframes', chain motion)")
    args = parser.parse_args(argv)
    try:
        keys = None
        with _coverage_notes():
            if args.intervals:  # checked before the replay runs
                model = load_model(args.model)
                checker = ModelAdapter(model, *replay_ellipsoids(model, args.pairs, source=args.model), "chain")
                keys = load_keyframes(args.traj, model)
                for k in range(len(keys) - 1):
                    try:
                        checker.chain_motions(as_state(model, keys[k], "keyframes"),
                                              as_state(model, keys[k + 1], "keyframes"))
                    except InputError as exc:
                        raise ReplayError(f"{args.traj}: keyframes {k} to {k + 1}: {exc}") from None
            result = replay(args.model, args.traj, args.motion, args.out, pairs=args.pairs, planes=args.planes,
                            render=not args.no_render, force=args.force, mode=args.mode)
    except (ValueError, MjccdError) as exc:
        print(f"mjccd replay: {exc}", file=sys.stderr)
        return 2
    print(contact_table(result, args.rows))
    print(summary(result))
    if keys is not None:
        for k in range(len(keys) - 1):
            print(f"keyframe segment {k} -> {k + 1}:")
            print(format_interval_table(interval_table(checker, keys[k], keys[k + 1])))
    if args.out:
        print("wrote " + ", ".join(result.files))
    return 0
