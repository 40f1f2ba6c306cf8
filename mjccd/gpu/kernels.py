"""CUDA kernels of the batched frame check: poses from bodies, pose split, filters, exact solve, per-world reduction.

Layout: W worlds of the same N ellipsoids and P pairs.  Poses are (W, N, 7) rows
``[x, y, z, qw, qx, qy, qz]``; the per-pair arrays are (W, P).  One thread per
(world, ellipsoid) splits the poses, one per (world, pair) runs the filters and
appends the pairs they cannot clear to a survivor list, one per survivor runs the
exact solve, one per world reduces to the earliest contact.  Outcome codes are
those of :mod:`mjccd.scene`; a time of -1 means no contact.
"""
import math

from numba import cuda, float64

from mjccd.gpu import filters as fl
from mjccd.gpu.solver import quat_to_matrix_into, rigid_pair, same_orientation
from mjccd.scene import CACHED_PLANE, EXACT_FREE, EXACT_HIT, NEW_PLANE, OVERLAP_T0, SPHERE, UNCERTAIN

# per-world status of a first-contact answer
NO_CONTACT, CONTACT, POSSIBLE_CONTACT, BAD_INPUT = 0, 1, 2, 3
STATUS_NAMES = ("none", "contact", "uncertain", "bad_input")
THREADS = 128
WORK_SHAPE = fl.WORK_SHAPE


def blocks(n, threads=THREADS):
    """Blocks of ``threads`` covering n threads (at least one)."""
    return max(1, (n + threads - 1) // threads)


@cuda.jit(cache=True)
def poses_from_bodies_kernel(xpos, xquat, body, local_pos, local_quat, poses):
    """poses[w, e] = body pose (xpos[w, body[e]], xquat[w, body[e]]) composed with e's local pose; float64."""
    idx = cuda.grid(1)
    n = body.shape[0]
    if idx >= xpos.shape[0] * n:
        return
    w = idx // n
    e = idx - w * n
    b = body[e]
    if b < 0 or b >= xpos.shape[1]:  # no such body: a NaN pose, which makes the world's answer BAD_INPUT
        for m in range(7):
            poses[w, e, m] = math.nan
        return
    R = cuda.local.array((3, 3), float64)
    q = cuda.local.array(4, float64)
    for m in range(4):
        q[m] = float64(xquat[w, b, m])
    quat_to_matrix_into(q, R)
    l0, l1, l2 = float64(local_pos[e, 0]), float64(local_pos[e, 1]), float64(local_pos[e, 2])
    for m in range(3):
        poses[w, e, m] = float64(xpos[w, b, m]) + (R[m, 0] * l0 + R[m, 1] * l1 + R[m, 2] * l2)
    a0, a1, a2, a3 = q[0], q[1], q[2], q[3]
    c0, c1 = float64(local_quat[e, 0]), float64(local_quat[e, 1])
    c2, c3 = float64(local_quat[e, 2]), float64(local_quat[e, 3])
    poses[w, e, 3] = a0 * c0 - a1 * c1 - a2 * c2 - a3 * c3
    poses[w, e, 4] = a0 * c1 + a1 * c0 + a2 * c3 - a3 * c2
    poses[w, e, 5] = a0 * c2 - a1 * c3 + a2 * c0 + a3 * c1
    poses[w, e, 6] = a0 * c3 + a1 * c2 - a2 * c1 + a3 * c0


@cuda.jit(cache=True)
def reset_kernel(bad, count):
    """bad[:] = 0 and count[0] = 0 before a frame."""
    w = cuda.grid(1)
    if w == 0:
        count[0] = 0
    if w < bad.shape[0]:
        bad[w] = 0


@cuda.jit(cache=True)
def split_kernel(poses_t0, poses_t1, p0, q0, p1, q1, bad):
    """Positions and unit quaternions of both ends (as mjccd.scene's pose split), q1 on q0's side.

    ``bad[w]`` is set to 1 when a pose of world w holds NaN, infinity or a zero
    quaternion (norm below 1e-12); that world's answer is BAD_INPUT.
    """
    idx = cuda.grid(1)
    n = poses_t0.shape[1]
    if idx >= poses_t0.shape[0] * n:
        return
    w = idx // n
    e = idx - w * n
    ok = True
    for m in range(7):
        if not (math.isfinite(poses_t0[w, e, m]) and math.isfinite(poses_t1[w, e, m])):
            ok = False
    n0 = math.sqrt(float64(poses_t0[w, e, 3]) * poses_t0[w, e, 3] + float64(poses_t0[w, e, 4]) * poses_t0[w, e, 4]
                   + float64(poses_t0[w, e, 5]) * poses_t0[w, e, 5] + float64(poses_t0[w, e, 6]) * poses_t0[w, e, 6])
    n1 = math.sqrt(float64(poses_t1[w, e, 3]) * poses_t1[w, e, 3] + float64(poses_t1[w, e, 4]) * poses_t1[w, e, 4]
                   + float64(poses_t1[w, e, 5]) * poses_t1[w, e, 5] + float64(poses_t1[w, e, 6]) * poses_t1[w, e, 6])
    if not (ok and 1e-12 <= n0 < math.inf and 1e-12 <= n1 < math.inf):
        bad[w] = 1
        n0 = n1 = 1.0
    for m in range(3):
        p0[w, e, m] = poses_t0[w, e, m]
        p1[w, e, m] = poses_t1[w, e, m]
    dot = 0.0
    for m in range(4):
        q0[w, e, m] = poses_t0[w, e, 3 + m] / n0
        q1[w, e, m] = poses_t1[w, e, 3 + m] / n1
        dot += q0[w, e, m] * q1[w, e, m]
    if dot < 0.0:
        for m in range(4):
            q1[w, e, m] = -q1[w, e, m]


@cuda.jit(cache=True)
def filter_kernel(radii, rmax, pairs, p0, q0, p1, q1, use_cache, cache_n, cache_kind, outcome, times, times_hi,
                  survivors, count):
    """Per (world, pair): moving spheres, the cached plane, new planes at t = 0 and t = 1 (as
    :func:`mjccd.scene._filter_pair`); a pair no filter clears is appended to ``survivors``
    (world * P + pair; ``count[0]`` of them) with outcome EXACT_FREE until the exact kernel decides it."""
    idx = cuda.grid(1)
    npairs = pairs.shape[0]
    if idx >= p0.shape[0] * npairs:
        return
    w = idx // npairs
    k = idx - w * npairs
    i = pairs[k, 0]
    j = pairs[k, 1]
    times[w, k] = -1.0
    times_hi[w, k] = -1.0
    te = fl.sphere_entry(p0[w, i], p1[w, i], rmax[i], p0[w, j], p1[w, j], rmax[j])
    if te < 0.0:
        outcome[w, k] = SPHERE
        return
    if same_orientation(q0[w, i], q1[w, i]) and same_orientation(q0[w, j], q1[w, j]):
        _survive(outcome, survivors, count, w, k, idx)  # translation only: F of degree 2, cheaper than a plane
        return
    S = cuda.local.array((2, 3, 3, 3), float64)
    den = cuda.local.array((2, 5), float64)
    R0 = cuda.local.array((2, 3, 3), float64)
    R1 = cuda.local.array((2, 3, 3), float64)
    work = cuda.local.array(WORK_SHAPE, float64)
    ca0 = cuda.local.array(3, float64)
    ca1 = cuda.local.array(3, float64)
    cb0 = cuda.local.array(3, float64)
    cb1 = cuda.local.array(3, float64)
    n0 = cuda.local.array(3, float64)
    n1 = cuda.local.array(3, float64)
    fl.support_rigid(radii[i], q0[w, i], q1[w, i], S, den, 0)
    fl.support_rigid(radii[j], q0[w, j], q1[w, j], S, den, 1)
    fl.rotation_into(q0[w, i], R0, 0)
    fl.rotation_into(q1[w, i], R1, 0)
    fl.rotation_into(q0[w, j], R0, 1)
    fl.rotation_into(q1[w, j], R1, 1)
    for m in range(3):  # centres relative to A's at t = 0
        o = p0[w, i, m]
        ca0[m] = 0.0
        ca1[m] = p1[w, i, m] - o
        cb0[m] = p0[w, j, m] - o
        cb1[m] = p1[w, j, m] - o
    if use_cache and cache_kind[w, k] > 0:
        for m in range(3):  # the cached normal, kept in A's frame, into the world
            n0[m] = R0[0, m, 0] * cache_n[w, k, 0] + R0[0, m, 1] * cache_n[w, k, 1] + R0[0, m, 2] * cache_n[w, k, 2]
        v = fl.witness_variants(n0, ca0, ca1, cb0, cb1, R0, R1, S, den, work, cache_kind[w, k], n1)
        if v > 0:
            _keep(R1, n1, cache_n, w, k)
            cache_kind[w, k] = v
            outcome[w, k] = CACHED_PLANE
            return
    cache_kind[w, k] = 0
    A = cuda.local.array((4, 4), float64)
    B = cuda.local.array((4, 4), float64)
    M = cuda.local.array((4, 4), float64)
    Pa = cuda.local.array(4, float64)
    Pb = cuda.local.array(4, float64)
    D = cuda.local.array(4, float64)
    plane = cuda.local.array(4, float64)
    Rs = cuda.local.array((3, 3), float64)
    fl.quadric_matrix_into(radii[i], ca0, q0[w, i], Rs, A)
    fl.quadric_matrix_into(radii[j], cb0, q0[w, j], Rs, B)
    ok = fl.separating_normal(A, B, M, Pa, Pb, D, plane)
    for m in range(3):
        n0[m] = plane[m]
    if ok:
        v = fl.witness_variants(n0, ca0, ca1, cb0, cb1, R0, R1, S, den, work, 1, n1)
        if v > 0:
            _keep(R1, n1, cache_n, w, k)
            cache_kind[w, k] = v
            outcome[w, k] = NEW_PLANE
            return
    fl.quadric_matrix_into(radii[i], ca1, q1[w, i], Rs, A)
    fl.quadric_matrix_into(radii[j], cb1, q1[w, j], Rs, B)
    if fl.separating_normal(A, B, M, Pa, Pb, D, plane):
        for m in range(3):
            n1[m] = plane[m]
        _keep(R1, n1, cache_n, w, k)
        cache_kind[w, k] = 1
        if ok and n0[0] * n1[0] + n0[1] * n1[1] + n0[2] * n1[2] > 0.0:
            if fl.witness(n0, n1, ca0, ca1, cb0, cb1, S, den, work):
                outcome[w, k] = NEW_PLANE
                return
    _survive(outcome, survivors, count, w, k, idx)


@cuda.jit(device=True)
def _keep(R1, n, cache_n, w, k):
    """cache_n[w, k] = R1[0]^T n: the world normal kept in A's frame for the next frame."""
    for m in range(3):
        cache_n[w, k, m] = R1[0, 0, m] * n[0] + R1[0, 1, m] * n[1] + R1[0, 2, m] * n[2]


@cuda.jit(device=True)
def _survive(outcome, survivors, count, w, k, idx):
    outcome[w, k] = EXACT_FREE
    slot = cuda.atomic.add(count, 0, 1)
    survivors[slot] = idx


@cuda.jit(cache=True)
def exact_kernel(radii, pairs, p0, q0, p1, q1, survivors, count, outcome, times, times_hi, points, normals):
    """The exact first contact of every survivor (:func:`mjccd.gpu.solver.rigid_pair`), as the scene records it:
    EXACT_HIT (time, point, normal), OVERLAP_T0 (time 0), EXACT_FREE (time -1), or UNCERTAIN with the bracket
    [times, times_hi] that holds every possible first contact (a pair touching at t = 0 within the rounding,
    or one whose bracket is wider than TIME_TOL, or a search limit: what the CPU settles in rational
    arithmetic)."""
    idx = cuda.grid(1)
    if idx >= count[0]:
        return
    npairs = pairs.shape[0]
    s = survivors[idx]
    w = s // npairs
    k = s - w * npairs
    i = pairs[k, 0]
    j = pairs[k, 1]
    point = cuda.local.array(3, float64)
    normal = cuda.local.array(3, float64)
    status0, found, t, certified, lo, hi = rigid_pair(radii[i], p0[w, i], q0[w, i], p1[w, i], q1[w, i],
                                                      radii[j], p0[w, j], q0[w, j], p1[w, j], q1[w, j],
                                                      1.0, point, normal)
    for m in range(3):
        points[w, k, m] = point[m]
        normals[w, k, m] = normal[m]
    if status0 == -1:
        outcome[w, k] = OVERLAP_T0
        times[w, k] = 0.0
    elif status0 == 0:
        outcome[w, k] = UNCERTAIN
        times[w, k] = 0.0
        times_hi[w, k] = hi
    elif found and certified:
        outcome[w, k] = EXACT_HIT
        times[w, k] = t
    elif certified:
        outcome[w, k] = EXACT_FREE
    else:
        outcome[w, k] = UNCERTAIN
        times[w, k] = lo
        times_hi[w, k] = hi


@cuda.jit(cache=True)
def reduce_kernel(outcome, times, times_hi, points, normals, bad, pair, time, time_hi, point, normal, best_outcome,
                  status, resolved):
    """Per world: the earliest contact over its pairs (ties: the lower pair index), as the scene picks it;
    ``resolved`` cleared (the host sets it for the worlds it solves again)."""
    w = cuda.grid(1)
    if w >= times.shape[0]:
        return
    resolved[w] = False
    best = 2.0
    best_k = -1
    if bad[w] == 0:
        for k in range(times.shape[1]):
            t = times[w, k]
            if t >= 0.0 and t < best:
                best, best_k = t, k
    pair[w] = best_k
    for m in range(3):
        point[w, m] = 0.0
        normal[w, m] = 0.0
    if best_k < 0:
        time[w] = -1.0
        time_hi[w] = -1.0
        best_outcome[w] = -1
        status[w] = BAD_INPUT if bad[w] else NO_CONTACT
        return
    code = outcome[w, best_k]
    time[w] = best
    best_outcome[w] = code
    if code == UNCERTAIN:
        time_hi[w] = times_hi[w, best_k]
        status[w] = POSSIBLE_CONTACT
    else:
        time_hi[w] = best
        status[w] = CONTACT
    for m in range(3):
        point[w, m] = points[w, best_k, m]
        normal[w, m] = normals[w, best_k, m]
