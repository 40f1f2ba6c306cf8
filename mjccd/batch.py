"""Many independent worlds of the same ellipsoids checked at once, in parallel over the worlds (numba ``prange``).

A :class:`BatchScene` holds B worlds of the same N ellipsoids, pairs, planes
and plane pairs as one :class:`mjccd.scene.Scene` (same arguments, same
validation), each world with its own plane cache.  Every method answers for
all B worlds in one compiled call, each world exactly as a
:class:`~mjccd.scene.Scene` of its own would (bit for bit: the same kernel,
:func:`mjccd.scene.step_kernel`, on the same numbers), whatever the other
worlds hold.

Memory: what the worlds share (radii, pairs, planes, ``min_motion``) is held
once; the scratch and per-pair results of :func:`~mjccd.scene.step_kernel` (a
:class:`~mjccd.scene.Workspace`) exist once per thread, not per world; a world
owns only its plane cache (P normals and P bytes), which is copied into the
thread's workspace before its frame and back after it (only the rows that
hold a plane).  The rest of a frame depends on nothing that a world leaves
in the scratch, so a world's answer is the same on any thread and in any
batch.

A world whose poses hold NaN, infinity or a zero quaternion is not solved:
its ``ok`` is False and ``errors`` names it; the other worlds are.
"""
import math
from collections import namedtuple
from dataclasses import astuple
from typing import NamedTuple

import numba
import numpy as np
from numba.typed import List

from mjccd import _validate
from mjccd._exclusive import Exclusive, exclusive
from mjccd.errors import InputError
from mjccd.scene import N_COUNTERS, UNCERTAIN, Scene, field, new_workspace, split_poses, step_kernel, workspace_ref

# as in mjccd.scene: compiled on first use and cached; the parallel kernels loop over the worlds with prange
_inline = numba.njit(cache=True, nogil=True, no_cfunc_wrapper=True, forceinline=True)
_parallel = numba.njit(cache=True, nogil=True, no_cfunc_wrapper=True, parallel=True)

# the Workspace fields every thread shares (read by the kernels, set between calls); the others are one thread's
_SHARED = ("radii", "rmax", "pairs", "min_motion", "affine", "plane_cache", "planes", "plane_pairs",
          "plane_min_motion")

# the poses of a world: split as Scene.step splits them, or not solved (a bad value)
ORDINARY, NON_FINITE, ZERO_QUATERNION = range(3)
_FAULTS = {NON_FINITE: "has a non-finite value", ZERO_QUATERNION: "has a zero quaternion"}


class BatchContacts(NamedTuple):
    """The first contact of each of B worlds (arrays indexed by world).

    ``pair[b]`` is the scene's pair index of world b's first contact: a row of
    ``pairs``, or ``len(pairs) + row`` for a row of ``plane_pairs``; -1 when
    world b has none (or its input was bad).  ``frame[b]``: the frame of
    that contact (0 for :meth:`BatchScene.first_contacts`; the index f of
    frame f -> f + 1 for :meth:`BatchScene.first_contacts_along`), -1 when
    none.  ``time[b]`` in [0, 1] within that frame (-1 when none), the low
    end of the bracket when the contact is uncertain; ``time_hi[b]`` the
    bracket's high end (equal to ``time`` when certain, -1 when none).
    ``point``/``normal`` (B, 3) world frame, zero when none, at t = 0, or
    uncertain without a known touching point (where
    :class:`mjccd.scene.FirstContact` has None).  ``outcome[b]`` int8: the
    scene's outcome code of that pair (``mjccd.scene.OUTCOME_NAMES``;
    ``UNCERTAIN`` marks an uncertain contact), -1 when none.  ``ok[b]`` False
    when world b's input was bad; ``errors`` maps each such world to a
    message naming the world, the field and the ellipsoid (the other worlds
    are solved).
    """

    pair: np.ndarray     # (B,) int64
    frame: np.ndarray    # (B,) int64
    time: np.ndarray     # (B,) float64
    time_hi: np.ndarray  # (B,) float64
    point: np.ndarray    # (B, 3)
    normal: np.ndarray   # (B, 3)
    outcome: np.ndarray  # (B,) int8
    ok: np.ndarray       # (B,) bool
    errors: dict         # world -> message


class BatchStep(NamedTuple):
    """Every pair of each world in one frame (:meth:`BatchScene.step`).

    ``first``: the :class:`BatchContacts` of the frame.  ``outcome`` (B, P + Q)
    int8 the outcome code of every pair (plane pairs last); ``time`` (B, P + Q)
    its first contact (-1: none; the bracket's low end when uncertain) and
    ``time_hi`` the bracket's high end (``time`` when certain); ``counters``
    (B, N_COUNTERS) as :class:`mjccd.scene.FrameCounters`.  Rows of bad
    worlds hold -1 outcomes and times and zero counters.  A pair collides in
    world b when ``time[b, k] >= 0``.
    """

    first: BatchContacts
    outcome: np.ndarray
    time: np.ndarray
    time_hi: np.ndarray
    counters: np.ndarray


# what the kernels fill, per world: the fields of BatchContacts but ok and errors, the state of its poses
# (ORDINARY, NON_FINITE, ZERO_QUATERNION) and where a bad one is (pose set, ellipsoid)
_Firsts = namedtuple("_Firsts", ["status", "fault", "pair", "frame", "time", "time_hi", "point", "normal", "outcome"])
# the per-pair arrays of BatchStep (zero rows when not asked for)
_PerPair = namedtuple("_PerPair", ["outcome", "time", "time_hi", "counters"])


# ---------------------------------------------------------------- kernels


@_inline
def _split(poses, p, q):
    """One world's (N, 7) poses into positions p and unit quaternions q exactly as :meth:`Scene.step
    <mjccd.scene.Scene.step>` splits them: (state, ellipsoid).

    Ordinary poses go through :func:`mjccd.scene.split_poses`.  Otherwise the
    first ellipsoid with a non-finite value (NON_FINITE), then the first with
    a zero quaternion (ZERO_QUATERNION, judged as
    :func:`mjccd._validate.pose_array` judges it: on the quaternion scaled by a
    power of two) is named, and p and q are not usable.  Left is a quaternion
    whose squared norm overflows: then every quaternion of the set is scaled
    by a power of two and normalised, the operations of ``pose_array`` in
    their order (ORDINARY).
    """
    if split_poses(poses, p, q):
        return ORDINARY, -1
    n = poses.shape[0]
    for e in range(n):
        for m in range(7):
            if not np.isfinite(poses[e, m]):
                return NON_FINITE, e
    for e in range(n):
        _, exponent = math.frexp(max(max(abs(poses[e, 3]), abs(poses[e, 4])), max(abs(poses[e, 5]), abs(poses[e, 6]))))
        s = 0.0
        for m in range(4):
            v = math.ldexp(poses[e, 3 + m], -exponent)
            s += v * v
        norm = math.sqrt(s)
        if math.ldexp(norm, exponent) < _validate.MIN_NORM:
            return ZERO_QUATERNION, e
        for m in range(3):
            p[e, m] = poses[e, m]
        for m in range(4):
            q[e, m] = math.ldexp(poses[e, 3 + m], -exponent) / norm
    return ORDINARY, -1


@_inline
def _load_cache(ws, cache_n, cache_kind, b):
    """World b's plane cache into the thread's workspace (the normals of the pairs that have a plane only: a
    normal is read only where its kind is set)."""
    kind, normal = field(ws, "cache_kind"), field(ws, "cache_n")
    for k in range(kind.shape[0]):
        v = cache_kind[b, k]
        kind[k] = v
        if v > 0:
            for m in range(3):
                normal[k, m] = cache_n[b, k, m]


@_inline
def _store_cache(ws, cache_n, cache_kind, b):
    """The thread's plane cache back into world b's."""
    kind, normal = field(ws, "cache_kind"), field(ws, "cache_n")
    for k in range(kind.shape[0]):
        v = kind[k]
        cache_kind[b, k] = v
        if v > 0:
            for m in range(3):
                cache_n[b, k, m] = normal[k, m]


@_inline
def _write_first(ws, k, f, b, out):
    """Pair k's first contact (the answer of step_kernel; -1: none, or a world not solved) in frame f as world
    b's, as :func:`mjccd.scene.first_of` reads it."""
    if k < 0:
        out.pair[b] = -1
        out.frame[b] = -1
        out.time[b] = -1.0
        out.time_hi[b] = -1.0
        out.outcome[b] = -1
        for m in range(3):
            out.point[b, m] = 0.0
            out.normal[b, m] = 0.0
        return
    times, times_hi, outcome = field(ws, "times"), field(ws, "times_hi"), field(ws, "outcome")
    points, normals = field(ws, "points"), field(ws, "normals")
    t = times[k]
    uncertain = outcome[k] == UNCERTAIN
    touch = not ((t == 0.0 or uncertain) and normals[k, 0] == 0.0 and normals[k, 1] == 0.0 and normals[k, 2] == 0.0)
    out.pair[b] = k
    out.frame[b] = f
    out.time[b] = t
    out.time_hi[b] = times_hi[k] if uncertain else t
    out.outcome[b] = outcome[k]
    for m in range(3):
        out.point[b, m] = points[k, m] if touch else 0.0
        out.normal[b, m] = normals[k, m] if touch else 0.0


@_inline
def _write_pairs(ws, solved, b, per):
    """Every pair's outcome and times, and the counters, of the thread's last frame as world b's (``solved``;
    else no outcome (-1), no times, no counts)."""
    times, times_hi, outcome, counters = field(ws, "times"), field(ws, "times_hi"), field(ws, "outcome"), \
        field(ws, "counters")
    if not solved:
        for k in range(outcome.shape[0]):
            per.outcome[b, k] = -1
            per.time[b, k] = -1.0
            per.time_hi[b, k] = -1.0
        for c in range(counters.shape[0]):
            per.counters[b, c] = 0
        return
    for k in range(outcome.shape[0]):
        per.outcome[b, k] = outcome[k]
        per.time[b, k] = times[k]
        per.time_hi[b, k] = times_hi[k] if outcome[k] == UNCERTAIN else times[k]
    for c in range(counters.shape[0]):
        per.counters[b, c] = counters[c]


@_parallel
def frame_kernel(refs, poses_t0, poses_t1, cache_n, cache_kind, all_pairs, new_only, out, per):
    """One frame of every world, (B, N, 7) poses, in parallel over the worlds.

    ``refs``: one :class:`mjccd.scene.WorkspaceRef` per thread (indexed by
    ``numba.get_thread_id()``).  ``cache_n`` (B, P, 3) and ``cache_kind``
    (B, P) are the worlds' plane caches ((B, 0, ...) without one).  A world
    whose poses :func:`_split` refuses is not solved: ``out.status`` and
    ``out.fault`` (pose set 0 or 1, ellipsoid) say why.  Writes every world's
    fields of ``out`` (:class:`_Firsts`) and, when it has rows, of ``per``
    (:class:`_PerPair`).
    """
    use_cache = cache_kind.shape[1] > 0
    # numba's parfor loses what the loop body itself writes through a tuple's field: take the arrays out first
    status, fault = out.status, out.fault
    for b in numba.prange(poses_t0.shape[0]):
        ws = refs[numba.get_thread_id()]
        p0, q0, p1, q1 = field(ws, "p0"), field(ws, "q0"), field(ws, "p1"), field(ws, "q1")
        state, e = _split(poses_t0[b], p0, q0)
        fault[b, 0] = 0
        if state == ORDINARY:
            state, e = _split(poses_t1[b], p1, q1)
            fault[b, 0] = 1
        fault[b, 1] = e
        status[b] = state
        k = -1
        if state == ORDINARY:
            if use_cache:
                _load_cache(ws, cache_n, cache_kind, b)
            k, _, _, _ = step_kernel(ws, p0, q0, p1, q1, np.empty((0, 2)), np.empty(0, dtype=np.int64), all_pairs,
                                     new_only, np.bool_(False))
            if use_cache:
                _store_cache(ws, cache_n, cache_kind, b)
        _write_first(ws, k, 0, b, out)
        if per.outcome.shape[0] > 0:
            _write_pairs(ws, state == ORDINARY, b, per)


@_parallel
def along_kernel(refs, poses, cache_n, cache_kind, new_only, out):
    """The first frame with a contact of every world over (B, T, N, 7) poses, in parallel over the worlds.

    As :func:`frame_kernel`; frame f runs from pose set f to f + 1, each pose
    set split once, as the world reaches it; a world stops at its first frame
    with a contact, or at a pose set :func:`_split` refuses (``out.fault``:
    that set and the ellipsoid; the world is not solved).
    """
    use_cache = cache_kind.shape[1] > 0
    nsets = poses.shape[1]
    status, fault = out.status, out.fault  # (see frame_kernel)
    for b in numba.prange(poses.shape[0]):
        ws = refs[numba.get_thread_id()]
        pa, qa, pb, qb = field(ws, "p0"), field(ws, "q0"), field(ws, "p1"), field(ws, "q1")
        if use_cache:
            _load_cache(ws, cache_n, cache_kind, b)
        iv, owner = np.empty((0, 2)), np.empty(0, dtype=np.int64)
        state, e = _split(poses[b, 0], pa, qa)
        k, f = -1, 0
        while state == ORDINARY and k < 0 and f < nsets - 1:
            state, e = _split(poses[b, f + 1], pb, qb)
            if state == ORDINARY:
                k, _, _, _ = step_kernel(ws, pa, qa, pb, qb, iv, owner, np.bool_(False), new_only, np.bool_(False))
                if k < 0:
                    pa, qa, pb, qb = pb, qb, pa, qa
                    f += 1
            else:
                f += 1
        if use_cache:
            _store_cache(ws, cache_n, cache_kind, b)
        status[b] = state
        fault[b, 0] = f
        fault[b, 1] = e
        _write_first(ws, k if state == ORDINARY else -1, f, b, out)


# ---------------------------------------------------------------- Python layer


def _firsts(nworlds):
    """:class:`_Firsts` for the kernels to fill (each world's fields are written, solved or not)."""
    return _Firsts(np.empty(nworlds, dtype=np.int8), np.full((nworlds, 2), -1, dtype=np.int64),
                   np.empty(nworlds, dtype=np.int64), np.empty(nworlds, dtype=np.int64), np.empty(nworlds),
                   np.empty(nworlds), np.empty((nworlds, 3)), np.empty((nworlds, 3)), np.empty(nworlds, dtype=np.int8))


def _put_first(out, b, first, outcomes, f):
    """World b's first contact in ``out`` (:class:`_Firsts`) from a settled :class:`~mjccd.scene.FrameResult`'s
    ``first`` (None: none) in frame f, with the pairs' settled outcome codes, as :func:`_write_first` writes the
    kernel's."""
    if first is None:
        out.pair[b], out.frame[b], out.time[b], out.time_hi[b], out.outcome[b] = -1, -1, -1.0, -1.0, -1
        out.point[b] = out.normal[b] = 0.0
        return
    out.pair[b], out.frame[b], out.time[b], out.outcome[b] = first.pair, f, first.time, outcomes[first.pair]
    out.time_hi[b] = first.time if first.bracket is None else first.bracket[1]
    out.point[b] = 0.0 if first.point is None else first.point
    out.normal[b] = 0.0 if first.normal is None else first.normal


def _put_pairs(per, b, result, outcomes):
    """World b's rows of ``per`` (:class:`_PerPair`) from a settled check of every pair."""
    per.outcome[b] = outcomes
    per.time[b] = per.time_hi[b] = -1.0
    for c in result.contacts:
        per.time[b, c.pair] = c.time
        per.time_hi[b, c.pair] = c.time if c.bracket is None else c.bracket[1]
    per.counters[b] = astuple(result.counters)


def _pose_input(value, field_name, shape):
    """A C-contiguous float64 array of ``shape`` (None: any length >= 0); the error names the field and the shape."""
    try:
        arr = np.asarray(value, dtype=np.float64)
    except OverflowError:
        raise InputError(f"{field_name}: a number is too large for a double") from None
    except (TypeError, ValueError):
        arr = None
    if arr is None or arr.ndim != len(shape) or any(s is not None and s != d for s, d in zip(shape, arr.shape)):
        want = "x".join("T" if s is None else str(s) for s in shape)
        raise InputError(f"{field_name}: expected numbers of shape {want}" if arr is None else
                         f"{field_name}: expected shape {want} (worlds, ...), got {arr.shape}")
    return arr if arr.flags.c_contiguous else np.ascontiguousarray(arr)


def _padded_zeros(like, line=64):
    """Zeros shaped as ``like``, on cache lines of their own: two threads' scratch never shares a line (each
    would invalidate the other's copy at every write)."""
    buf = np.zeros(like.nbytes + 3 * line, dtype=np.uint8)
    start = line + (-buf.ctypes.data) % line
    return buf[start:start + like.nbytes].view(like.dtype).reshape(like.shape)


def _read_only(arr):
    view = arr.view()
    view.flags.writeable = False
    return view


class BatchScene:
    """B independent worlds of the same ellipsoids, pairs and planes, checked in parallel.

    Each world answers as a :class:`mjccd.scene.Scene` of its own would, bit
    for bit, and carries its own plane cache from call to call.  One call at
    a time per batch (as for a scene: a call while another thread is in one raises
    :class:`~mjccd.errors.ConcurrentUseError`).  The threads are numba's
    (``numba.set_num_threads``; at most one per world is used).  Each call
    ends when every thread is done: where other processes keep the cores
    busy, a thread can wait for one for a scheduler tick (milliseconds, with
    numba's default OpenMP layer), so a loaded machine may run a batch
    faster on one thread (or with ``OMP_WAIT_POLICY=passive`` set before
    the first call, which costs some speed on idle cores).  For one world a
    :class:`~mjccd.scene.Scene` costs less per call.

    Args:
        radii: (N, 3) semi-axes, as :class:`mjccd.scene.Scene`.
        worlds: B >= 1, the number of worlds.
        pairs, motion, plane_cache, planes, plane_pairs: as :class:`mjccd.scene.Scene`
            (validated by it).
    """

    def __init__(self, radii, worlds, *, pairs=None, motion="rigid", plane_cache=True, planes=None,
                 plane_pairs=None):
        if isinstance(worlds, (bool, np.bool_)) or not isinstance(worlds, (int, np.integer)) or worlds < 1:
            raise InputError(f"worlds: expected a number of worlds >= 1, got {worlds!r}")
        # one scene checks the arguments (and later min_motion) exactly as Scene does; its arrays are not used
        self._checks = Scene(radii, pairs=pairs, motion=motion, plane_cache=plane_cache, planes=planes,
                             plane_pairs=plane_pairs)
        c = self._checks
        self.worlds, self.motion, self.plane_cache = int(worlds), motion, bool(plane_cache)
        shared = new_workspace(c.radii, c.pairs, motion == "affine", plane_cache, np.array(c.planes),
                               np.array(c.plane_pairs))
        self._shared = shared
        self._threads = [shared._replace(**{name: _padded_zeros(getattr(shared, name))
                                            for name in shared._fields if name not in _SHARED})
                         for _ in range(numba.config.NUMBA_NUM_THREADS)]
        self._refs = List([workspace_ref(ws) for ws in self._threads])
        npairs = len(c.pairs) if self.plane_cache else 0
        self._cache_n = np.zeros((self.worlds, npairs, 3))
        self._cache_kind = np.zeros((self.worlds, npairs), dtype=np.int8)
        self._none = _PerPair(np.zeros((0, 0), dtype=np.int8), np.zeros((0, 0)), np.zeros((0, 0)),
                              np.zeros((0, N_COUNTERS), dtype=np.int64))
        self._exclusive = Exclusive("BatchScene")

    @property
    def radii(self):
        """(N, 3) read-only semi-axes."""
        return _read_only(self._shared.radii)

    @property
    def pairs(self):
        """(P, 2) read-only pairs (ellipsoid indices)."""
        return _read_only(self._shared.pairs)

    @property
    def planes(self):
        """(K, 4) read-only planes, as :attr:`mjccd.scene.Scene.planes`."""
        return self._checks.planes

    @property
    def plane_pairs(self):
        """(Q, 2) read-only plane pairs, as :attr:`mjccd.scene.Scene.plane_pairs` (pair index P + row)."""
        return self._checks.plane_pairs

    def plane_pair(self, k):
        """(ellipsoid, plane) of pair index k when it is a plane pair, else None (as :meth:`Scene.plane_pair
        <mjccd.scene.Scene.plane_pair>`)."""
        return self._checks.plane_pair(k)

    @property
    def min_motion(self):
        """(P,) read-only: :attr:`mjccd.scene.Scene.min_motion`, the same for every world."""
        return self._checks.min_motion

    @property
    def plane_min_motion(self):
        """(Q,) read-only: :attr:`mjccd.scene.Scene.plane_min_motion`, the same for every world."""
        return self._checks.plane_min_motion

    @exclusive
    def set_min_motion(self, values):
        """As :meth:`mjccd.scene.Scene.set_min_motion`, for every world."""
        self._checks.set_min_motion(values)
        self._shared.min_motion[:] = self._checks.min_motion

    @exclusive
    def set_plane_min_motion(self, values):
        """As :meth:`mjccd.scene.Scene.set_plane_min_motion`, for every world."""
        self._checks.set_plane_min_motion(values)
        self._shared.plane_min_motion[:] = self._checks.plane_min_motion

    @exclusive
    def reset_cache(self, worlds=None):
        """Forget the cached separating planes of the given worlds (indices; None: every world)."""
        if worlds is None:
            rows = slice(None)
        else:
            arr = np.asarray(worlds).reshape(-1)
            if arr.size and (arr.dtype.kind not in "iu" or arr.min() < 0 or arr.max() >= self.worlds):
                raise InputError(f"worlds: expected world indices in 0..{self.worlds - 1}, got {worlds!r}")
            rows = arr.astype(np.int64)
        self._cache_n[rows] = 0.0
        self._cache_kind[rows] = 0

    # ------------------------------------------------------------ checks

    def _parallel(self, kernel, *args):
        """Run ``kernel``: on at most one thread per world (a thread without a world would only wait)."""
        threads = numba.get_num_threads()
        if self.worlds >= threads:
            kernel(*args)
            return
        numba.set_num_threads(self.worlds)
        try:
            kernel(*args)
        finally:
            numba.set_num_threads(threads)

    def _contacts(self, out, names):
        """The :class:`BatchContacts` of the kernels' ``out``; ``names(s)`` is the field of pose set s."""
        ok = out.status == ORDINARY
        errors = {}
        if not ok.all():
            for b in np.flatnonzero(~ok).tolist():
                s, e = out.fault[b]
                errors[b] = f"{names(b, int(s))}: ellipsoid {int(e)} {_FAULTS[int(out.status[b])]}"
        return BatchContacts(out.pair, out.frame, out.time, out.time_hi, out.point, out.normal, out.outcome, ok,
                             errors)

    def _frame(self, poses_t0, poses_t1, all_pairs, new_only, per_pair, resolve):
        shape = (self.worlds, len(self.radii), 7)
        p0 = _pose_input(poses_t0, "poses_t0", shape)
        p1 = _pose_input(poses_t1, "poses_t1", shape)
        out = _firsts(self.worlds)
        nall = len(self.pairs) + len(self.plane_pairs)
        per = _PerPair(np.empty((self.worlds, nall), dtype=np.int8), np.empty((self.worlds, nall)),
                       np.empty((self.worlds, nall)), np.empty((self.worlds, N_COUNTERS), dtype=np.int64)) \
            if per_pair else self._none
        self._parallel(frame_kernel, self._refs, p0, p1, self._cache_n, self._cache_kind, all_pairs, new_only, out,
                       per)
        if resolve:
            undecided = out.outcome == UNCERTAIN
            if per_pair and all_pairs:
                undecided |= (per.outcome == UNCERTAIN).any(axis=1)
            for b in np.flatnonzero(undecided & (out.status == ORDINARY)).tolist():
                result, outcomes = self._checks.settled_step(p0[b], p1[b], new_contacts_only=new_only)
                _put_first(out, b, result.first, outcomes, 0)
                if per_pair:
                    _put_pairs(per, b, result, outcomes)
        return self._contacts(out, lambda b, s: f"{('poses_t0', 'poses_t1')[s]}[{b}]"), per

    # ------------------------------------------------------------ checks of the worlds

    @exclusive
    def first_contacts(self, poses_t0, poses_t1, *, new_contacts_only=False, resolve_uncertain=True):
        """The first contact of one frame in every world: :class:`BatchContacts` (``frame`` 0, or -1 when none).

        Args:
            poses_t0, poses_t1: (B, N, 7) rows ``[x, y, z, w, qx, qy, qz]`` at the
                start and end of the frame, world b's in ``[b]``.
            new_contacts_only, resolve_uncertain: as :meth:`mjccd.scene.Scene.step`
                (a world whose first contact the kernel leaves uncertain is
                checked again as its own scene would, :meth:`Scene.settled_step
                <mjccd.scene.Scene.settled_step>`, after the parallel call).
        World b's answer is ``Scene.first_contact`` of its poses (and it
        carries its plane cache on the same way).  A wrong shape raises
        :class:`~mjccd.errors.InputError`; a bad value only fails its world.
        """
        first, _ = self._frame(poses_t0, poses_t1, False, bool(new_contacts_only), False, bool(resolve_uncertain))
        return first

    @exclusive
    def step(self, poses_t0, poses_t1, *, all_pairs=True, new_contacts_only=False, resolve_uncertain=True):
        """One frame in every world with every pair's outcome: a :class:`BatchStep`.

        With ``all_pairs`` every pair not cleared by a filter is solved over
        [0, 1], so ``time[b, k] >= 0`` marks every colliding pair of world b
        (``Scene.step(..., all_pairs=True).contacts``); otherwise only the
        first contact is sought and pairs whose spheres meet after it are
        ``pruned``, as in :meth:`mjccd.scene.Scene.step`.  Arguments as in
        :meth:`first_contacts`; a world with an uncertain pair (``all_pairs``)
        or an uncertain first contact is checked again, and its rows are then
        those of every pair, settled.
        """
        first, per = self._frame(poses_t0, poses_t1, bool(all_pairs), bool(new_contacts_only), True,
                                 bool(resolve_uncertain))
        return BatchStep(first, *per)

    @exclusive
    def first_contacts_along(self, poses, *, new_contacts_only=False, resolve_uncertain=True):
        """The first frame with a contact in each world, over a pose sequence: :class:`BatchContacts`.

        Args:
            poses: (B, T, N, 7), T >= 2 pose sets per world; frame f runs from
                ``poses[:, f]`` to ``poses[:, f + 1]``.
            new_contacts_only, resolve_uncertain: as :meth:`first_contacts`; when
                a world's uncertain first contact proves free, it goes on from
                the next frame.
        Returns ``frame[b]`` the first frame of world b with a contact and that
        frame's first contact (as :meth:`first_contacts` of that frame).  The
        plane cache carries from frame to frame (and into later calls) up to
        and including that frame.  Pose sets are checked as a world reaches
        them, so those after its first contact are never read; a bad one
        before it (``errors[b]`` names it: ``poses[b][s]``) leaves the world
        unsolved.
        """
        n = len(self.radii)
        arr = _pose_input(poses, "poses", (self.worlds, None, n, 7))
        if arr.shape[1] < 2:
            raise InputError(f"poses: expected at least 2 pose sets per world ({self.worlds}xTx{n}x7), "
                             f"got {arr.shape[1]}")
        out = _firsts(self.worlds)
        new_only = bool(new_contacts_only)
        self._parallel(along_kernel, self._refs, arr, self._cache_n, self._cache_kind, new_only, out)
        if resolve_uncertain:
            for b in np.flatnonzero((out.outcome == UNCERTAIN) & (out.status == ORDINARY)).tolist():
                self._settle_along(arr, out, b, new_only)
        return self._contacts(out, lambda b, s: f"poses[{b}][{s}]")

    def _settle_along(self, arr, out, b, new_only):
        """World b's uncertain first contact along ``arr`` settled (:meth:`Scene.settled_step
        <mjccd.scene.Scene.settled_step>`); while it proves free, the world goes on from the next frame (the
        along kernel on that world alone, with its own plane cache)."""
        while True:
            f = int(out.frame[b])
            result, outcomes = self._checks.settled_step(arr[b, f], arr[b, f + 1], new_contacts_only=new_only)
            _put_first(out, b, result.first, outcomes, f)
            if result.first is not None or f + 2 >= arr.shape[1]:
                return
            rest = _firsts(1)
            along_kernel(self._refs, np.ascontiguousarray(arr[b:b + 1, f + 1:]), self._cache_n[b:b + 1],
                         self._cache_kind[b:b + 1], new_only, rest)
            for name in rest._fields:
                getattr(out, name)[b] = getattr(rest, name)[0]
            out.fault[b, 0] += f + 1
            if rest.pair[0] >= 0:
                out.frame[b] += f + 1
            if rest.status[0] != ORDINARY or rest.outcome[0] != UNCERTAIN:
                return
