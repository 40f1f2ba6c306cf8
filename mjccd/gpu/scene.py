"""GpuScene: W worlds of the same ellipsoids and pairs, one frame checked on the GPU; poses from MuJoCo bodies.

The answers are device arrays (numba device arrays; pass them to CuPy, PyTorch or Warp through
``__cuda_array_interface__``).  Inputs may be host numpy arrays or any object with
``__cuda_array_interface__`` (Warp, CuPy, PyTorch, numba), taken without a host copy; float32 inputs
(MuJoCo Warp's ``Data.xpos``/``xquat``) are widened to float64 exactly on the device.
"""
from typing import NamedTuple

import numpy as np
from numba import cuda

from mjccd import _validate
from mjccd.ccd import first_contact
from mjccd.errors import InputError
from mjccd.gpu import kernels as kn
from mjccd.motion import Rigid
from mjccd.quadric import Ellipsoid
from mjccd.scene import EXACT_HIT, OVERLAP_T0, UNCERTAIN, Scene


class GpuContacts(NamedTuple):
    """The first contact of each of W worlds (device arrays indexed by world).

    ``pair`` (W,) int64: the scene's pair index, -1 when none.  ``time`` (W,) in [0, 1], -1 when none;
    for an uncertain answer the low end of the bracket [``time``, ``time_hi``] that holds every
    possible first contact (an uncertain answer is a possible contact at ``time``, never "no contact");
    ``time_hi`` equals ``time`` when certain.  ``point``/``normal`` (W, 3) world frame, zero when
    none, at t = 0 or uncertain.  ``outcome`` (W,) int8: the :mod:`mjccd.scene` outcome code of that
    pair, -1 when none.  ``status`` (W,) int8: :data:`mjccd.gpu.NO_CONTACT`, ``CONTACT``,
    ``POSSIBLE_CONTACT`` (uncertain) or ``BAD_INPUT`` (a pose held NaN, infinity or a zero
    quaternion, or a body index was out of range).  ``resolved`` (W,) bool: the device flagged one
    of the world's pairs and the answer was settled on the CPU by :func:`mjccd.ccd.first_contact`.
    """

    pair: object
    time: object
    time_hi: object
    point: object
    normal: object
    outcome: object
    status: object
    resolved: object

    def copy_to_host(self):
        """The same fields as numpy arrays."""
        return GpuContacts(*(a.copy_to_host() for a in self))


class GpuPairs(NamedTuple):
    """The device's answer for every (world, pair) of the last frame: ``outcome`` (W, P) int8
    (:mod:`mjccd.scene` codes), ``time`` and ``time_hi`` (W, P) as in :class:`GpuContacts`, ``point`` and
    ``normal`` (W, P, 3) for the pairs the exact kernel solved.  Before any CPU re-solve."""

    outcome: object
    time: object
    time_hi: object
    point: object
    normal: object

    def copy_to_host(self):
        """The same fields as numpy arrays."""
        return GpuPairs(*(a.copy_to_host() for a in self))


def _is_device(value):
    return hasattr(value, "__cuda_array_interface__") or hasattr(value, "copy_to_host")


def _device(value, field, shape):
    """``value`` on the device, without a copy when it is there already; a host value checked first.

    ``shape``: the expected shape, None for any length along an axis.
    """
    want = "x".join("?" if s is None else str(s) for s in shape)
    if _is_device(value):
        arr = cuda.as_cuda_array(value) if hasattr(cuda, "as_cuda_array") else value
        if np.dtype(arr.dtype).kind not in "fiu":
            raise InputError(f"{field}: expected numbers, got dtype {arr.dtype}")
    else:
        try:
            arr = np.ascontiguousarray(value, dtype=np.float64)
        except (TypeError, ValueError, OverflowError):
            raise InputError(f"{field}: expected numbers of shape {want}") from None
    if len(arr.shape) != len(shape) or any(s is not None and s != d for s, d in zip(shape, arr.shape)):
        raise InputError(f"{field}: expected shape {want}, got {tuple(arr.shape)}")
    return arr if _is_device(arr) else cuda.to_device(arr)


def poses_from_bodies(xpos, xquat, body, local_pos, local_quat, out=None):
    """Ellipsoid world poses (W, N, 7) from body poses, on the device.

    Args:
        xpos: (W, nbody, 3) body positions (MuJoCo Warp's ``Data.xpos``).
        xquat: (W, nbody, 4) body quaternions [w, x, y, z] (``Data.xquat``).
        body: (N,) the body of each ellipsoid.
        local_pos: (N, 3) each ellipsoid's centre in its body's frame.
        local_quat: (N, 4) each ellipsoid's orientation in its body's frame.
        out: an optional (W, N, 7) float64 device array to write into.
    Returns:
        The (W, N, 7) float64 device array ``[x, y, z, qw, qx, qy, qz]``: centre
        ``xpos + R(xquat) local_pos``, orientation ``xquat * local_quat``.  An
        ellipsoid whose body index is out of range gets a NaN pose (its
        world's answer is then ``BAD_INPUT``).
    """
    xpos = _device(xpos, "xpos", (None, None, 3))
    worlds, nbody = xpos.shape[0], xpos.shape[1]
    xquat = _device(xquat, "xquat", (worlds, nbody, 4))
    if _is_device(body):
        body = cuda.as_cuda_array(body) if hasattr(cuda, "as_cuda_array") else body
        if np.dtype(body.dtype).kind not in "iu" or len(body.shape) != 1:
            raise InputError(f"body: expected (N,) integer body indices, got dtype {body.dtype} shape {body.shape}")
    else:
        body = np.asarray(body)
        if body.ndim != 1 or (body.size and body.dtype.kind not in "iu"):
            raise InputError(f"body: expected (N,) integer body indices, got {body.dtype} of shape {body.shape}")
        bad = np.flatnonzero((body < 0) | (body >= nbody))
        if len(bad):
            raise InputError(f"body[{bad[0]}]: body index {int(body[bad[0]])} out of range for {nbody} bodies")
        body = cuda.to_device(np.ascontiguousarray(body, dtype=np.int64))
    n = body.shape[0]
    local_pos = _device(local_pos, "local_pos", (n, 3))
    local_quat = _device(local_quat, "local_quat", (n, 4))
    if out is None:
        out = cuda.device_array((worlds, n, 7), dtype=np.float64)
    elif tuple(out.shape) != (worlds, n, 7) or np.dtype(out.dtype) != np.float64:
        raise InputError(f"out: expected a ({worlds}, {n}, 7) float64 device array, got {out.dtype} {tuple(out.shape)}")
    kn.poses_from_bodies_kernel[kn.blocks(worlds * n), kn.THREADS](xpos, xquat, body, local_pos, local_quat, out)
    return out


class GpuScene:
    """W worlds of the same N ellipsoids and P pairs, each frame checked on the GPU in float64.

    Per (world, pair), as :class:`mjccd.scene.Scene` decides a rigid frame: the moving bounding
    spheres, the plane cached from the world's last frame, new separating planes at t = 0 and t = 1
    (each proven over the whole frame by its witness polynomial), then the exact first contact of what
    is left (:mod:`mjccd.gpu.solver`, the CPU solver's double-precision path ported operation for
    operation).  Where the CPU solver would go on in rational arithmetic (a pair touching at t = 0 within
    the rounding, a bracket wider than TIME_TOL, a search limit), the device answers UNCERTAIN with a
    bracket; with ``resolve_uncertain`` those few pairs are then solved on the CPU by
    :func:`mjccd.ccd.first_contact` and the world is marked ``resolved``.

    Args:
        radii: (N, 3) semi-axes.
        worlds: W >= 1.
        pairs: (P, 2) ellipsoid indices; default every pair i < j (validated as :class:`mjccd.scene.Scene`).
        plane_cache: keep each (world, pair)'s separating plane for the next frame, on the device.
    """

    def __init__(self, radii, worlds, *, pairs=None, plane_cache=True):
        if isinstance(worlds, (bool, np.bool_)) or not isinstance(worlds, (int, np.integer)) or worlds < 1:
            raise InputError(f"worlds: expected a number of worlds >= 1, got {worlds!r}")
        checks = Scene(radii, pairs=pairs)  # validates radii and pairs as the CPU scene does
        self.radii = np.array(checks.radii)
        self.pairs = np.array(checks.pairs)
        self.worlds = int(worlds)
        self.plane_cache = bool(plane_cache)
        w, n, p = self.worlds, len(self.radii), len(self.pairs)
        self._radii = cuda.to_device(self.radii)
        self._rmax = cuda.to_device(np.ascontiguousarray(self.radii.max(axis=1)))
        self._pairs = cuda.to_device(np.ascontiguousarray(self.pairs, dtype=np.int64))
        self._cache_n = cuda.to_device(np.zeros((w, p, 3)))
        self._cache_kind = cuda.to_device(np.zeros((w, p), dtype=np.int8))
        self._p0, self._p1 = cuda.device_array((w, n, 3)), cuda.device_array((w, n, 3))
        self._q0, self._q1 = cuda.device_array((w, n, 4)), cuda.device_array((w, n, 4))
        self._bad = cuda.device_array(w, dtype=np.int8)
        self._count = cuda.device_array(1, dtype=np.int32)
        self._survivors = cuda.device_array(max(1, w * p), dtype=np.int64)
        self._per_pair = GpuPairs(cuda.device_array((w, p), dtype=np.int8), cuda.device_array((w, p)),
                                  cuda.device_array((w, p)), cuda.to_device(np.zeros((w, p, 3))),
                                  cuda.to_device(np.zeros((w, p, 3))))
        self._out = GpuContacts(cuda.device_array(w, dtype=np.int64), cuda.device_array(w), cuda.device_array(w),
                                cuda.device_array((w, 3)), cuda.device_array((w, 3)),
                                cuda.device_array(w, dtype=np.int8), cuda.device_array(w, dtype=np.int8),
                                cuda.device_array(w, dtype=np.bool_))

    def reset_cache(self):
        """Forget every world's cached separating planes."""
        self._cache_kind.copy_to_device(np.zeros((self.worlds, len(self.pairs)), dtype=np.int8))

    @property
    def pair_answers(self):
        """:class:`GpuPairs` of the last frame (device arrays that the next frame overwrites)."""
        return self._per_pair

    def filter_frame(self, poses_t0, poses_t1):
        """Only the pose split and the filters of one frame (no exact solve): their outcomes in
        :attr:`pair_answers` (EXACT_FREE marks the pairs left for the exact solver).  For timing the filters."""
        self._filters(poses_t0, poses_t1)

    def first_contacts(self, poses_t0, poses_t1, *, resolve_uncertain=True):
        """The first contact of every world over one frame.

        Args:
            poses_t0, poses_t1: (W, N, 7) poses ``[x, y, z, qw, qx, qy, qz]`` at the start and end of
                the frame, host arrays or device arrays (float32 or float64).
            resolve_uncertain: settle the worlds whose first contact the device left uncertain on the
                CPU (:func:`mjccd.ccd.first_contact` on those pairs; a small device-to-host copy and a
                synchronisation every call).  False: everything stays on the device, without a
                synchronisation, and such worlds keep status POSSIBLE_CONTACT.
        Returns:
            :class:`GpuContacts` of device arrays, valid until the next call.
        """
        self._filters(poses_t0, poses_t1)
        w, p = self.worlds, len(self.pairs)
        a = self._per_pair
        kn.exact_kernel[kn.blocks(w * p), kn.THREADS](self._radii, self._pairs, self._p0, self._q0, self._p1,
                                                       self._q1, self._survivors, self._count, a.outcome, a.time,
                                                       a.time_hi, a.point, a.normal)
        o = self._out
        kn.reduce_kernel[kn.blocks(w), kn.THREADS](a.outcome, a.time, a.time_hi, a.point, a.normal, self._bad,
                                                   o.pair, o.time, o.time_hi, o.point, o.normal, o.outcome, o.status,
                                                   o.resolved)
        if resolve_uncertain:
            self._resolve()
        return o

    def _filters(self, poses_t0, poses_t1):
        w, n, p = self.worlds, len(self.radii), len(self.pairs)
        t0 = self._poses(poses_t0, "poses_t0")
        t1 = self._poses(poses_t1, "poses_t1")
        kn.reset_kernel[kn.blocks(w), kn.THREADS](self._bad, self._count)
        kn.split_kernel[kn.blocks(w * n), kn.THREADS](t0, t1, self._p0, self._q0, self._p1, self._q1, self._bad)
        a = self._per_pair
        kn.filter_kernel[kn.blocks(w * p), kn.THREADS](self._radii, self._rmax, self._pairs, self._p0, self._q0,
                                                        self._p1, self._q1, self.plane_cache, self._cache_n,
                                                        self._cache_kind, a.outcome, a.time, a.time_hi,
                                                        self._survivors, self._count)

    def _poses(self, poses, field):
        shape = (self.worlds, len(self.radii), 7)
        if _is_device(poses):
            return _device(poses, field, shape)
        return cuda.to_device(_host_poses(poses, field, shape))

    def _resolve(self):
        """Worlds whose first contact is uncertain: the uncertain pairs before the earliest certain contact
        solved again by :func:`mjccd.ccd.first_contact`, and the world's answer replaced."""
        o = self._out
        status = o.status.copy_to_host()
        worlds = np.flatnonzero(status == kn.POSSIBLE_CONTACT)
        if len(worlds) == 0:
            return
        host = o.copy_to_host()
        a = self._per_pair
        for w in worlds:
            outcome, times = a.outcome[w].copy_to_host(), a.time[w].copy_to_host()
            times_hi = a.time_hi[w].copy_to_host()
            points, normals = a.point[w].copy_to_host(), a.normal[w].copy_to_host()
            p0, q0 = self._p0[w].copy_to_host(), self._q0[w].copy_to_host()
            p1, q1 = self._p1[w].copy_to_host(), self._q1[w].copy_to_host()
            certain = (times >= 0.0) & (outcome != UNCERTAIN)
            bound = times[certain].min() if certain.any() else 2.0
            for k in np.flatnonzero((outcome == UNCERTAIN) & (times <= bound)):
                i, j = self.pairs[k]
                contact = first_contact(Ellipsoid(self.radii[i]), Rigid(p0[i], q0[i], p1[i], q1[i]),
                                        Ellipsoid(self.radii[j]), Rigid(p0[j], q0[j], p1[j], q1[j]))
                points[k] = normals[k] = 0.0
                if contact is None:
                    outcome[k], times[k] = kn.EXACT_FREE, -1.0
                    continue
                times[k] = contact.time
                if contact.certainty == "uncertain":
                    outcome[k], times_hi[k] = UNCERTAIN, contact.bracket[1]
                    continue
                outcome[k] = EXACT_HIT if contact.status_at_start == "separate" else OVERLAP_T0
                times_hi[k] = contact.time
                if contact.point is not None:
                    points[k], normals[k] = contact.point, contact.normal
            hits = np.flatnonzero(times >= 0.0)
            k = hits[np.argmin(times[hits])] if len(hits) else -1  # argmin: the lowest index among ties
            host.resolved[w] = True
            if k < 0:
                host.pair[w], host.time[w], host.time_hi[w], host.outcome[w] = -1, -1.0, -1.0, -1
                host.point[w] = host.normal[w] = 0.0
                host.status[w] = kn.NO_CONTACT
                continue
            host.pair[w], host.time[w], host.outcome[w] = k, times[k], outcome[k]
            host.time_hi[w] = times_hi[k] if outcome[k] == UNCERTAIN else times[k]
            host.point[w], host.normal[w] = points[k], normals[k]
            host.status[w] = kn.POSSIBLE_CONTACT if outcome[k] == UNCERTAIN else kn.CONTACT
        for device, value in zip(o, host):
            device.copy_to_device(value)


def _host_poses(poses, field, shape):
    """A host pose array checked as the CPU scene checks its poses: (W, N, 7) float64, finite, no zero quaternion."""
    want = "x".join(str(s) for s in shape)
    try:
        arr = np.ascontiguousarray(poses, dtype=np.float64)
    except (TypeError, ValueError):
        raise InputError(f"{field}: expected numbers of shape {want} (worlds, ellipsoids, 7)") from None
    except OverflowError:
        raise InputError(f"{field}: a number is too large for a double") from None
    if arr.shape != shape:
        raise InputError(f"{field}: expected shape {want} (worlds, ellipsoids, 7), got {arr.shape}")
    bad = ~np.isfinite(arr).all(axis=(1, 2)) | (arr[:, :, 3:] == 0.0).all(axis=2).any(axis=1)
    for w in np.flatnonzero(bad)[:1]:
        _validate.pose_array(arr[w], f"{field}[{w}]", shape[1])  # raises, naming the ellipsoid and what is wrong
    return arr
