"""Many moving ellipsoids, many pairs, one frame at a time: filters then the exact solver, in numba.

A :class:`Scene` holds N ellipsoids and a list of pairs.  ``step(poses_t0,
poses_t1)`` moves every ellipsoid over the frame (rigid: centre lerp and
quaternion lerp; affine: centre and shape matrix lerp) and answers with a
:class:`FrameResult`.  Per pair (all inside one compiled kernel):

0. policy, not a filter: a pair whose relative motion over the frame stays
   below its ``min_motion`` (:meth:`Scene.set_min_motion`) is left out
   (outcome ``too_slow``);
1. moving bounding spheres (:func:`mjccd.filters.sphere_entry`): free, or a
   lower bound of the contact time;
2. the plane cached from the last frame, kept in the first ellipsoid's frame;
3. static status at t = 0 (overlapping pairs collide at t = 0);
4. a new separating plane at t = 0 (thesis Thm 4.5–4.6), then one at t = 1;
5. what is left goes to the exact solver.  When only the first contact is
   wanted, those pairs are solved in order of sphere-entry time with the
   best time so far as ``t_max``; a pair whose spheres meet only after it is
   not solved at all.

**Planes.**  A scene may also hold K static planes (MuJoCo ``plane`` geoms:
floors, walls), each the solid half-space below ``n . x = offset`` (see
:class:`mjccd.plane.Plane`), and Q *plane pairs* (ellipsoid, plane).  Pair
indices run over both kinds: 0 .. P - 1 are the rows of :attr:`Scene.pairs`,
P .. P + Q - 1 the rows of :attr:`Scene.plane_pairs` (``Scene.plane_pair(k)``
maps one back).  A plane pair is filtered by its bounding sphere against the
plane (the centre's signed distance is linear in t, so its smallest value is
at an end of the frame: clear when both ends exceed the largest semi-axis;
in contact at t = 0 when the centre is closer than the support along n),
then solved exactly by :func:`mjccd.plane.plane_pair_kernel`; its contact is
a :class:`PlaneContact`.  It shares the outcome codes, the
counters (a cleared plane pair counts as ``sphere_culled``) and the
earliest-contact bound of the ellipsoid pairs.  A scene without planes runs
exactly as before.

The scene's arrays (its radii and pairs, the plane cache, the per-pair
results of the last frame, the scratch of the kernels) are one
:class:`Workspace`, which the kernels take as one argument, a
:class:`WorkspaceRef`.
"""
import array
import collections
from dataclasses import astuple, dataclass, fields, replace
from typing import NamedTuple

import numba
import numpy as np
from numba.core import cgutils, types
from numba.experimental import structref
from numba.core.typing.typeof import typeof_impl
from numba.extending import intrinsic, overload

from mjccd import _validate
from mjccd._exclusive import Exclusive, exclusive
from mjccd import filters as fl
from mjccd.ccd import TIME_TOL, exact_pair, same_orientation
from mjccd.errors import InputError
from mjccd.plane import PLANE_WORK, RUN_FIELDS, RUNS_AT, TWO_POSE_RUNS, Plane, plane_pair_kernel, plane_rows
from mjccd.quadric import (pencil_point_into, pencil_quartic, quadric_matrix, quartic_max,
                            separating_plane_matrices, static_status_pose)
from mjccd.settle import pair_problem, settle
from mjccd.sorting import sort_by_key

# compiled on first use and cached; no cfunc wrapper (no kernel is passed around as a first-class function);
# forceinline=False: numba hands a caller's forceinline down to the callees it compiles
_jit = numba.njit(cache=True, nogil=True, no_cfunc_wrapper=True, forceinline=False)
# hot-path helpers: compiled once, then inlined by LLVM into each caller (no call, no reference counting of
# array arguments); inline="always" copied their numba IR into every caller instead, which multiplied
# compile time (docs/benchmarks.md, "First use")
_inline = numba.njit(cache=True, nogil=True, no_cfunc_wrapper=True, forceinline=True)

# outcome codes of a pair in one frame
SPHERE, CACHED_PLANE, NEW_PLANE, OVERLAP_T0, EXACT_FREE, EXACT_HIT, PRUNED, UNCERTAIN, TOO_SLOW = range(9)
OUTCOME_NAMES = ("sphere", "cached_plane", "new_plane", "overlapping_t0", "exact_free",
                 "exact_colliding", "pruned_by_bound", "uncertain", "too_slow")
# pairs, sphere, cached plane, new plane, overlapping t0, solved, colliding, pruned, uncertain, too slow
N_COUNTERS = 10


@intrinsic
def _ticks(typingctx):
    """CPU cycle counter (for the optional per-pair timing of benchmarks)."""
    def codegen(context, builder, signature, args):
        import llvmlite.ir as ir
        fnty = ir.FunctionType(ir.IntType(64), [])
        fn = cgutils.get_or_insert_function(builder.module, fnty, "llvm.readcyclecounter")
        return builder.call(fn, [])
    return types.int64(), codegen


@intrinsic
def _borrow(typingctx, arr):
    """A view of ``arr`` that holds no reference (no meminfo), for arrays the kernel's caller keeps alive.

    Numba counts references to every array passed to an inlined helper or
    sliced from another array, with atomic instructions; on the per-pair hot
    path that costs more than the arithmetic.  Views of a borrowed array are
    borrowed too.  Never return one or keep it past the call.
    """
    def codegen(context, builder, signature, args):
        src = context.make_array(signature.args[0])(context, builder, args[0])
        out = context.make_array(signature.return_type)(context, builder)
        context.populate_array(out, data=src.data, shape=src.shape, strides=src.strides, itemsize=src.itemsize,
                               meminfo=None)
        return out._getvalue()
    return arr(arr), codegen


@numba.njit(cache=True, nogil=True, no_cfunc_wrapper=True, forceinline=False)
def read_ticks():
    """The cycle counter, readable from Python (to calibrate :class:`RunResult` ticks)."""
    return _ticks()


# ---------------------------------------------------------------- workspace


class Workspace(NamedTuple):
    """The named arrays of a :class:`Scene`, shared by its Python layer and its compiled kernels.

    N ellipsoids, P pairs, K planes, Q plane pairs.  The per-pair results
    (``outcome`` .. ``ticks``, ``cand``) have P + Q rows: the pairs, then the
    plane pairs.  The kernels write them and the plane cache in place;
    nothing here is reallocated while the scene lives.
    """

    radii: np.ndarray       # (N, 3) semi-axes
    rmax: np.ndarray        # (N,) largest semi-axis (radius of the bounding sphere)
    pairs: np.ndarray       # (P, 2) int64 ellipsoid indices
    min_motion: np.ndarray  # (P,) relative motion over a frame below which a pair is left out (0: never)
    affine: bool            # the motion model: affine (True) or rigid (False)
    plane_cache: bool       # keep each pair's separating plane for the next frame
    cache_n: np.ndarray     # (P, 3) cached plane normal, in the first ellipsoid's frame
    cache_kind: np.ndarray  # (P,) int8 witness variant of the cached plane, 0 when none
    p0: np.ndarray          # (N, 3) positions at the start of the frame
    q0: np.ndarray          # (N, 4) unit quaternions at the start
    p1: np.ndarray          # (N, 3) positions at the end
    q1: np.ndarray          # (N, 4) unit quaternions at the end, as given (any sign)
    outcome: np.ndarray     # (P + Q,) int8 outcome code of the last frame (OUTCOME_NAMES)
    entry: np.ndarray       # (P + Q,) sphere-entry time (-1: the spheres never meet or the pair was left out)
    times: np.ndarray       # (P + Q,) first contact (-1: none found), the bracket's low end when uncertain
    times_hi: np.ndarray    # (P + Q,) the bracket's high end (UNCERTAIN pairs only)
    points: np.ndarray      # (P + Q, 3) touching point of the first contact (world)
    normals: np.ndarray     # (P + Q, 3) unit normal out of the first ellipsoid (world)
    ticks: np.ndarray       # (P + Q,) int64 CPU cycles per pair (timed runs only)
    counters: np.ndarray    # (N_COUNTERS,) int64, in the order of FrameCounters
    q1_aligned: np.ndarray  # (N, 4) scratch: q1 on the side of q0
    S: np.ndarray           # (N, 3, 3, 3 | 5) scratch: inverse shape polynomials (filters.support_*)
    den: np.ndarray         # (N, 5) scratch: their denominators
    R0: np.ndarray          # (N, 3, 3) scratch: rotations at t = 0
    R1: np.ndarray          # (N, 3, 3) scratch: rotations at t = 1
    work: np.ndarray        # filters.WORK_SHAPE scratch of the witness kernels
    scratch: np.ndarray     # (4, 3) scratch: the centres of one pair
    cand: np.ndarray        # (P + Q,) int64 scratch: the pairs left for the exact solver
    ready: np.ndarray       # (N,) bool scratch: per-ellipsoid data prepared in this frame
    aff_scratch: np.ndarray  # (8, 3, 3) scratch of filters.support_affine
    planes: np.ndarray      # (K, 4) [nx, ny, nz, offset], unit normals: the half-spaces n . x <= offset
    plane_pairs: np.ndarray  # (Q, 2) int64 (ellipsoid index, plane index)
    plane_min_motion: np.ndarray  # (Q,) as min_motion, for the plane pairs
    plane_work: np.ndarray  # (mjccd.plane.PLANE_WORK,) scratch of the plane kernels
    plane_touch: np.ndarray  # (2, 3) scratch: point and normal of a plane contact


def new_workspace(radii, pairs, affine, plane_cache, planes=None, plane_pairs=None):
    """A :class:`Workspace` for (N, 3) ``radii``, (P, 2) int64 ``pairs``, (K, 4) ``planes`` and (Q, 2) int64
    ``plane_pairs`` (all already validated; no planes by default)."""
    planes = np.zeros((0, 4)) if planes is None else np.ascontiguousarray(planes, dtype=np.float64)
    plane_pairs = (np.zeros((0, 2), dtype=np.int64) if plane_pairs is None
                   else np.ascontiguousarray(plane_pairs, dtype=np.int64))
    n, npairs, nall = len(radii), len(pairs), len(pairs) + len(plane_pairs)
    radii = np.ascontiguousarray(radii, dtype=np.float64)
    return Workspace(radii, np.ascontiguousarray(radii.max(axis=1)) if n else np.empty(0),
                     np.ascontiguousarray(pairs, dtype=np.int64), np.zeros(npairs), bool(affine), bool(plane_cache),
                     np.zeros((npairs, 3)), np.zeros(npairs, dtype=np.int8),
                     np.zeros((n, 3)), np.zeros((n, 4)), np.zeros((n, 3)), np.zeros((n, 4)),
                     np.zeros(nall, dtype=np.int8), np.zeros(nall), np.zeros(nall), np.zeros(nall),
                     np.zeros((nall, 3)), np.zeros((nall, 3)), np.zeros(nall, dtype=np.int64),
                     np.zeros(N_COUNTERS, dtype=np.int64),
                     np.zeros((n, 4)), np.zeros((n, 3, 3, 5 if affine else 3)), np.zeros((n, 5)),
                     np.zeros((n, 3, 3)), np.zeros((n, 3, 3)), np.zeros(fl.WORK_SHAPE), np.zeros((4, 3)),
                     np.zeros(nall, dtype=np.int64), np.zeros(n, dtype=np.bool_), np.zeros((8, 3, 3)),
                     planes, plane_pairs, np.zeros(len(plane_pairs)), np.zeros(PLANE_WORK), np.zeros((2, 3)))


@structref.register
class _WorkspaceRefType(types.StructRef):
    """Numba type of :class:`WorkspaceRef`."""

    def preprocess_fields(self, members):
        return tuple((name, types.unliteral(t)) for name, t in members)


class WorkspaceRef(array.array):
    """A :class:`Workspace` as one argument of a compiled kernel: ``ref.arrays`` is the workspace.

    Numba passes a tuple of arrays to compiled code array by array (about
    0.1 µs each for a named tuple); a reference to a compiled structure
    holding the tuple (a numba ``StructRef``) crosses in constant time.  Python
    reads the same arrays through ``arrays``.  Made by :func:`workspace_ref`.

    Why an (empty) ``array.array``: numba's dispatcher types an argument in C
    from a fingerprint of it, cached, when it can compute one; for an object
    with a buffer its fingerprint includes its Python type, so a reference
    costs about as much to pass as one array.  A plain proxy object has no
    fingerprint and is typed by a call back into Python on every call (about
    0.4 µs, a tenth of a guarded MuJoCo step).
    """

    __eq__, __ne__, __hash__ = object.__eq__, object.__ne__, object.__hash__  # an identity, not an empty array

    def __new__(cls, *args):
        return super().__new__(cls, "b")

    def __bool__(self):
        return True

    def __repr__(self):
        planes = f", {len(self.arrays.plane_pairs)} plane pairs" if len(self.arrays.plane_pairs) else ""
        return f"<WorkspaceRef of {len(self.arrays.radii)} ellipsoids, {len(self.arrays.pairs)} pairs{planes}>"

    @classmethod
    def _numba_box_(cls, ty, mi):
        """The object numba gives back for a compiled reference (see :func:`numba.experimental.structref.define_boxing`)."""
        ref = cls()
        ref._type, ref._meminfo = ty, mi
        return ref


structref.define_boxing(_WorkspaceRefType, WorkspaceRef)
_WORKSPACE_REF = _WorkspaceRefType([("arrays", numba.typeof(new_workspace(np.ones((1, 3)), np.zeros((1, 2)),
                                                                          False, True)))])
# every WorkspaceRef has this one type (workspace_ref checks that the arrays fit it): read in C on a cache miss
WorkspaceRef._numba_type_ = _WORKSPACE_REF
typeof_impl.register(WorkspaceRef)(lambda ref, c: _WORKSPACE_REF)  # before the generic typing of buffers


@intrinsic
def _field_of(typingctx, ref, name):
    """``ref.arrays.<name>`` read in place, an array borrowed as :func:`_borrow` makes it."""
    if not isinstance(name, types.StringLiteral):
        return None
    index = Workspace._fields.index(name.literal_value)
    typ = ref.field_dict["arrays"][index]

    def codegen(context, builder, signature, args):
        ref_type = signature.args[0]
        meminfo = cgutils.create_struct_proxy(ref_type)(context, builder, value=args[0]).meminfo
        payload = ref_type.get_data_type()
        data = builder.bitcast(context.nrt.meminfo_data(builder, meminfo),
                               context.data_model_manager[payload].get_value_type().as_pointer())
        value = builder.extract_value(cgutils.create_struct_proxy(payload)(context, builder, ref=data).arrays, index)
        if not isinstance(typ, types.Array):
            return value
        src = context.make_array(typ)(context, builder, value)
        out = context.make_array(typ)(context, builder)
        context.populate_array(out, data=src.data, shape=src.shape, strides=src.strides, itemsize=src.itemsize,
                               meminfo=None)
        return out._getvalue()
    return typ(ref, name), codegen


def field(ref, name):
    """The array (or flag) ``name`` of a :class:`WorkspaceRef`'s workspace: ``ref.arrays.<name>``.

    In compiled code it is read in place, without counting a reference (reading
    ``ref.arrays`` would count one to each of its thirty arrays), so it must
    not outlive the call, as :func:`_borrow`'s views.
    """
    return getattr(ref.arrays, name)


@overload(field, jit_options={"cache": True})
def _field_compiled(ref, name):
    return lambda ref, name: _field_of(ref, name)


@_jit
def _new_ref(arrays):
    ref = structref.new(_WORKSPACE_REF)
    ref.arrays = arrays
    return ref


def workspace_ref(arrays):
    """The :class:`WorkspaceRef` of a :class:`Workspace` (its arrays shared, not copied)."""
    if numba.typeof(arrays) != _WORKSPACE_REF.field_dict["arrays"]:
        raise InputError(f"arrays: expected a Workspace of C-contiguous arrays as new_workspace makes it, "
                         f"got {numba.typeof(arrays)}")
    ref = _new_ref(arrays)
    ref.arrays = arrays
    return ref


# ---------------------------------------------------------------- kernels


@_inline
def _to_world(R, e, v):
    """R[e] v for a 3-tuple v (a normal kept in body e's frame, put into the world)."""
    return (R[e, 0, 0] * v[0] + R[e, 0, 1] * v[1] + R[e, 0, 2] * v[2],
            R[e, 1, 0] * v[0] + R[e, 1, 1] * v[1] + R[e, 1, 2] * v[2],
            R[e, 2, 0] * v[0] + R[e, 2, 1] * v[1] + R[e, 2, 2] * v[2])


@_inline
def _keep(R, e, n, cache_n, k):
    """cache_n[k] = R[e]^T n: the world normal n kept in body e's frame for the next frame."""
    for m in range(3):
        cache_n[k, m] = R[e, 0, m] * n[0] + R[e, 1, m] * n[1] + R[e, 2, m] * n[2]


@_inline
def _prepare(affine, e, radii, q0, q1_raw, q1, S, den, R0, R1, aff_scratch):
    """Per-ellipsoid data of a frame: q1 sign-aligned with q0, inverse shape polynomials, end rotations.

    Done only for ellipsoids with a pair past the sphere filter.
    """
    s = 1.0
    if q0[e, 0] * q1_raw[e, 0] + q0[e, 1] * q1_raw[e, 1] + q0[e, 2] * q1_raw[e, 2] + q0[e, 3] * q1_raw[e, 3] < 0.0:
        s = -1.0
    for m in range(4):
        q1[e, m] = s * q1_raw[e, m]
    if affine:
        fl.support_affine(radii, q0, q1, S, den, e, aff_scratch)
    else:
        fl.support_rigid(radii, q0, q1, S, den, e)
    fl.rotation_into(q0, R0, e, e)
    fl.rotation_into(q1, R1, e, e)


@_inline
def _filter_pair(i, j, radii, p0, q0, p1, q1, S, den, R0, R1, use_cache, cache_n, cache_kind, k, work, scratch):
    """Plane filters of pair k = (i, j), whose moving spheres meet: returns the outcome code.

    ``cache_kind[k]``: 0 no cached plane, else the witness variant to try
    first.  Centres are taken relative to A's at t = 0.
    """
    o0, o1, o2 = p0[i, 0], p0[i, 1], p0[i, 2]
    ca0 = (0.0, 0.0, 0.0)
    ca1 = (p1[i, 0] - o0, p1[i, 1] - o1, p1[i, 2] - o2)
    cb0 = (p0[j, 0] - o0, p0[j, 1] - o1, p0[j, 2] - o2)
    cb1 = (p1[j, 0] - o0, p1[j, 1] - o1, p1[j, 2] - o2)
    if use_cache and cache_kind[k] > 0:
        n0 = _to_world(R0, i, (cache_n[k, 0], cache_n[k, 1], cache_n[k, 2]))
        v, n1 = fl.witness_variants(n0, ca0, ca1, cb0, cb1, R0, R1, S, den, i, j, work, cache_kind[k])
        if v > 0:
            _keep(R1, i, n1, cache_n, k)
            cache_kind[k] = v
            return CACHED_PLANE
    cache_kind[k] = 0
    for m in range(3):
        scratch[0, m] = ca0[m]
        scratch[1, m] = ca1[m]
        scratch[2, m] = cb0[m]
        scratch[3, m] = cb1[m]
    return _new_plane(i, j, radii, p0, q0, p1, q1, S, den, R0, R1, cache_n, cache_kind, k, work, scratch)


@_jit
def _new_plane(i, j, radii, p0, q0, p1, q1, S, den, R0, R1, cache_n, cache_kind, k, work, scratch):
    """Static tests and a new separating plane for pair k: the outcome code.

    ``scratch[:4]`` holds the centres relative to A's at t = 0 (from :func:`_filter_pair`).
    A pair whose two ellipsoids only translate goes to the exact solver without a plane: its
    solve (F of degree 2 in t) costs less than finding one separating plane.
    """
    ca0, ca1, cb0, cb1 = scratch[0], scratch[1], scratch[2], scratch[3]
    status0 = static_status_pose(radii[i], p0[i], q0[i], radii[j], p0[j], q0[j])
    if status0 == -1:
        return OVERLAP_T0
    if status0 != 1:  # touching or undecided (2): no plane, the exact solver decides from t = 0
        return EXACT_FREE
    if static_status_pose(radii[i], p1[i], q1[i], radii[j], p1[j], q1[j]) != 1:
        return EXACT_FREE  # not certainly separate at t = 1: straight to the exact solver
    if same_orientation(q0[i], q1[i]) and same_orientation(q0[j], q1[j]):
        return EXACT_FREE
    ok, plane, _, _ = separating_plane_matrices(quadric_matrix(radii[i], ca0, q0[i]),
                                                quadric_matrix(radii[j], cb0, q0[j]))
    n0 = (plane[0], plane[1], plane[2])
    if ok:
        v, n1 = fl.witness_variants(n0, ca0, ca1, cb0, cb1, R0, R1, S, den, i, j, work, 1)
        if v > 0:
            _keep(R1, i, n1, cache_n, k)
            cache_kind[k] = v
            return NEW_PLANE
    ok1, plane1, _, _ = separating_plane_matrices(quadric_matrix(radii[i], ca1, q1[i]),
                                                  quadric_matrix(radii[j], cb1, q1[j]))
    if ok1:
        n1 = (plane1[0], plane1[1], plane1[2])
        _keep(R1, i, n1, cache_n, k)
        cache_kind[k] = 1
        if ok and n0[0] * n1[0] + n0[1] * n1[1] + n0[2] * n1[2] > 0.0:
            if fl.witness(n0, n1, ca0, ca1, cb0, cb1, S, den, i, j, work):
                return NEW_PLANE
    return EXACT_FREE


@_inline
def _split_poses(poses, p, q):
    """Positions of (N, 7) poses into p and normalised quaternions into q: True when that is the whole answer.

    False when a row holds NaN, infinity or a zero quaternion, or when a
    quaternion's squared norm overflows (it comes out as a zero row, so the
    unit rows' squares do not sum to N): such poses are left to
    :func:`mjccd._validate.pose_array`, which names the error or scales each
    quaternion before normalising it.
    """
    total = 0.0
    for i in range(poses.shape[0]):
        for m in range(7):
            if not np.isfinite(poses[i, m]):
                return False
        norm = np.sqrt(poses[i, 3] * poses[i, 3] + poses[i, 4] * poses[i, 4] + poses[i, 5] * poses[i, 5]
                       + poses[i, 6] * poses[i, 6])
        if norm < 1e-12:
            return False
        for m in range(3):
            p[i, m] = poses[i, m]
        for m in range(4):
            q[i, m] = poses[i, 3 + m] / norm
            total += q[i, m] * q[i, m]
    return abs(total - poses.shape[0]) < 0.5


@_inline
def _too_slow(p0, q0, p1, q1, rmax, min_motion, i, j, k):
    """Policy: the ellipsoids of pair k = (i, j) move by less than ``min_motion[k]`` relative to each other.

    :func:`mjccd.filters.relative_sweep` bounds how far any point of j moves
    relative to any point of i; ``min_motion[k] = 0`` checks every pair.
    """
    return min_motion[k] > 0.0 and fl.relative_sweep(
        (p0[i, 0], p0[i, 1], p0[i, 2]), (p1[i, 0], p1[i, 1], p1[i, 2]),
        (q0[i, 0], q0[i, 1], q0[i, 2], q0[i, 3]), (q1[i, 0], q1[i, 1], q1[i, 2], q1[i, 3]), rmax[i],
        (p0[j, 0], p0[j, 1], p0[j, 2]), (p1[j, 0], p1[j, 1], p1[j, 2]),
        (q0[j, 0], q0[j, 1], q0[j, 2], q0[j, 3]), (q1[j, 0], q1[j, 1], q1[j, 2], q1[j, 3]), rmax[j]) < min_motion[k]


@_inline
def _sphere_entry(p0, p1, rmax, i, j):
    """:func:`mjccd.filters.sphere_entry` of the bounding spheres of ellipsoids i and j (-1: they never meet)."""
    return fl.sphere_entry((p0[i, 0], p0[i, 1], p0[i, 2]), (p1[i, 0], p1[i, 1], p1[i, 2]), rmax[i],
                           (p0[j, 0], p0[j, 1], p0[j, 2]), (p1[j, 0], p1[j, 1], p1[j, 2]), rmax[j])


@_inline
def _plane_too_slow(p0, q0, p1, q1, rmax, plane_min_motion, e, k2):
    """Policy, as :func:`_too_slow`: ellipsoid e of plane pair k2 moves by less than ``plane_min_motion[k2]``."""
    return plane_min_motion[k2] > 0.0 and fl.relative_sweep(
        (p0[e, 0], p0[e, 1], p0[e, 2]), (p1[e, 0], p1[e, 1], p1[e, 2]),
        (q0[e, 0], q0[e, 1], q0[e, 2], q0[e, 3]), (q1[e, 0], q1[e, 1], q1[e, 2], q1[e, 3]), rmax[e],
        (0.0, 0.0, 0.0), (0.0, 0.0, 0.0), (1.0, 0.0, 0.0, 0.0), (1.0, 0.0, 0.0, 0.0), 0.0) < plane_min_motion[k2]


@_inline
def _plane_entry(p0, q0, p1, planes, radii, rmax, e, pl):
    """(entry, below) of ellipsoid e against plane pl over the frame, by its bounding sphere.

    The centre's signed distance s(t) = n . c(t) - offset is linear in t for
    both motion models (the centre lerps), so the sphere of radius rmax, which
    holds the ellipsoid for both, is clear of the half-space for the whole
    frame when s > rmax at both ends.  Then entry = -1; otherwise entry is the
    time at which the sphere reaches the plane, a lower bound of the
    ellipsoid's first contact (0 when it reaches it at the start).  The
    radius is inflated by a relative 1e-9 and by the rounding of s.
    ``below``: certainly in contact at t = 0, the centre closer to the plane
    than the support along n (``sqrt(sum r_k^2 (R0^T n)_k^2)``, less a
    relative 1e-9 and the rounding of s): e.g. a body resting on a floor.
    """
    n0, n1, n2, d = planes[pl, 0], planes[pl, 1], planes[pl, 2], planes[pl, 3]
    s0 = n0 * p0[e, 0] + n1 * p0[e, 1] + n2 * p0[e, 2] - d
    s1 = n0 * p1[e, 0] + n1 * p1[e, 1] + n2 * p1[e, 2] - d
    size = max(abs(n0 * p0[e, 0]) + abs(n1 * p0[e, 1]) + abs(n2 * p0[e, 2]),
               abs(n0 * p1[e, 0]) + abs(n1 * p1[e, 1]) + abs(n2 * p1[e, 2])) + abs(d)
    margin = 8.0 * fl.EPS * size
    reach = rmax[e] * (1.0 + fl.SPHERE_INFLATE) + margin
    if s0 > reach:
        if s1 > reach:
            return -1.0, False
        return max(0.0, (s0 - reach) / (s0 - s1) * (1.0 - 1e-9)), False
    w, x, y, z = q0[e, 0], q0[e, 1], q0[e, 2], q0[e, 3]
    nq = w * w + x * x + y * y + z * z
    b0 = ((w * w + x * x - y * y - z * z) * n0 + 2.0 * (x * y + w * z) * n1 + 2.0 * (x * z - w * y) * n2) / nq
    b1 = (2.0 * (x * y - w * z) * n0 + (w * w - x * x + y * y - z * z) * n1 + 2.0 * (y * z + w * x) * n2) / nq
    b2 = (2.0 * (x * z + w * y) * n0 + 2.0 * (y * z - w * x) * n1 + (w * w - x * x - y * y + z * z) * n2) / nq
    h = np.sqrt((radii[e, 0] * b0) ** 2 + (radii[e, 1] * b1) ** 2 + (radii[e, 2] * b2) ** 2)
    return 0.0, s0 < h * (1.0 - 1e-9) - margin


@_inline
def _plane_solve(affine, radii, p0, q0, p1, q1_raw, planes, plane_pairs, npairs, k, t_max, first_only,
                 plane_work, touch):
    """The exact plane kernel on plane pair k (its runs in ``plane_work``): (status at start, runs,
    certified, bracket lo, bracket hi, number of runs)."""
    e = plane_pairs[k - npairs, 0]
    runs = plane_work[RUNS_AT:RUNS_AT + TWO_POSE_RUNS * RUN_FIELDS].reshape((TWO_POSE_RUNS, RUN_FIELDS))
    status0, nruns, certified, lo, hi, _ = plane_pair_kernel(
        affine, radii[e], p0[e], q0[e], p1[e], q1_raw[e], planes[plane_pairs[k - npairs, 1]], t_max, first_only,
        plane_work, runs, touch)
    return status0, runs, certified, lo, hi, nruns


@_inline
def _in_contact_at_start(k, times, points, normals, best, best_k):
    """Pair k is in contact at t = 0: its time 0, no point or normal (the arrays carry over between frames); the
    new (best, best_k), the first such pair kept."""
    times[k] = 0.0
    for m in range(3):
        points[k, m] = 0.0
        normals[k, m] = 0.0
    if best > 0.0:
        return 0.0, k
    return best, best_k


@_jit
def _estimated_touch(ri, p0i, q0i, p1i, q1i, rj, p0j, q0j, p1j, q1j, t, point, normal):
    """An estimate of where two ellipsoids touch near time t (an uncertain answer's bracket start), into point
    and normal (zeros when there is none): both posed by the lerp of their poses (q1 of either sign), the
    point of their pencil at the maximum of its quartic, which is the touching point when they touch (thesis
    Theorem 4.4)."""
    for m in range(3):
        point[m] = 0.0
        normal[m] = 0.0
    ci, qi, cj, qj = np.empty(3), np.empty(4), np.empty(3), np.empty(4)
    si = 1.0 if q0i[0] * q1i[0] + q0i[1] * q1i[1] + q0i[2] * q1i[2] + q0i[3] * q1i[3] >= 0.0 else -1.0
    sj = 1.0 if q0j[0] * q1j[0] + q0j[1] * q1j[1] + q0j[2] * q1j[2] + q0j[3] * q1j[3] >= 0.0 else -1.0
    for m in range(3):
        ci[m] = (1.0 - t) * p0i[m] + t * p1i[m]
        cj[m] = (1.0 - t) * p0j[m] + t * p1j[m]
    ni = nj = 0.0
    for m in range(4):
        qi[m] = (1.0 - t) * q0i[m] + t * si * q1i[m]
        qj[m] = (1.0 - t) * q0j[m] + t * sj * q1j[m]
        ni += qi[m] * qi[m]
        nj += qj[m] * qj[m]
    if not (ni > 0.0 and nj > 0.0):
        return
    for m in range(4):
        qi[m] /= np.sqrt(ni)
        qj[m] /= np.sqrt(nj)
    A = quadric_matrix(ri, ci, qi)
    B = quadric_matrix(rj, cj, qj)
    g, _ = pencil_quartic(A, B)
    _, u = quartic_max(g)
    pencil_point_into(A, B, u, point, normal)


@_jit
def _grown(iv, owner, niv):
    """The all-pairs interval list (``iv`` (n, 2) and ``owner`` (n,), the first ``niv`` rows filled) with room for
    more: copies twice as long, element by element (see bernstein's _jit)."""
    bigger = np.empty((2 * niv + 16, 2))
    bigger_o = np.empty(2 * niv + 16, dtype=np.int64)
    for r in range(niv):
        bigger[r, 0] = iv[r, 0]
        bigger[r, 1] = iv[r, 1]
        bigger_o[r] = owner[r]
    return bigger, bigger_o


@_jit
def step_kernel(ws, p0, q0, p1, q1_raw, iv, owner, all_pairs, new_only, timing):
    """One frame over all pairs of the workspace ``ws`` (a :class:`WorkspaceRef`); returns (best pair, rows, iv, owner).

    Poses: (N, 3) positions and (N, 4) unit quaternions at both ends of the
    frame; ``q1_raw`` is sign-aligned here with ``q0``.  Fills the per-pair
    arrays of the workspace and its ``counters``: ``times[k]`` is the first
    contact of pair k (-1 when none found), ``entry[k]`` its sphere-entry
    time.  A pair on which the exact solver hit a limit gets the outcome
    UNCERTAIN: ``times[k]`` and ``times_hi[k]`` are then its bracket (every
    possible first contact lies in it; lo = hi when the first contact itself
    is known and only later intervals are not), and it counts as a possible
    contact at ``times[k]`` (``times_hi`` is written for UNCERTAIN pairs only).
    Plane pairs (the workspace's ``plane_pairs``) are checked after the
    pairs, with the indices P + row, the same outcomes and counters, by
    :func:`_plane_entry` and then :func:`mjccd.plane.plane_pair_kernel`.
    With ``all_pairs`` every pair not cleared by a filter is solved
    over [0, 1] and its intervals are written to ``iv`` (R, 2) (``owner`` (R,)
    gives the pair of each row; both are replaced by larger arrays when full,
    so use the returned ones and their first ``rows`` rows); otherwise only
    the frame's first contact is sought.  A pair whose relative motion over
    the frame stays below ``min_motion[k]`` is left out (outcome TOO_SLOW, a
    policy, not a filter).  With ``new_only`` pairs already touching or
    overlapping at the start are counted but neither solved nor reported, so
    the first contact is the earliest new one.  Nothing is allocated unless a
    pair reaches the exact solver or ``iv`` fills up.
    """
    affine, use_cache = field(ws, "affine"), field(ws, "plane_cache")
    p0, q0, p1, q1_raw = _borrow(p0), _borrow(q0), _borrow(p1), _borrow(q1_raw)
    radii, rmax, pairs, min_motion = field(ws, "radii"), field(ws, "rmax"), field(ws, "pairs"), field(ws, "min_motion")
    cache_n, cache_kind = field(ws, "cache_n"), field(ws, "cache_kind")
    outcome, entry, times, times_hi = field(ws, "outcome"), field(ws, "entry"), field(ws, "times"), field(ws, "times_hi")
    points, normals, ticks, counters = field(ws, "points"), field(ws, "normals"), field(ws, "ticks"), field(ws, "counters")
    q1, S, den, R0, R1 = field(ws, "q1_aligned"), field(ws, "S"), field(ws, "den"), field(ws, "R0"), field(ws, "R1")
    work, scratch, cand = field(ws, "work"), field(ws, "scratch"), field(ws, "cand")
    ready, aff_scratch = field(ws, "ready"), field(ws, "aff_scratch")
    plane_work, plane_touch = field(ws, "plane_work"), field(ws, "plane_touch")
    planes, plane_pairs, plane_min_motion = field(ws, "planes"), field(ws, "plane_pairs"), field(ws, "plane_min_motion")
    n = radii.shape[0]
    npairs = pairs.shape[0]
    nplane = plane_pairs.shape[0]
    for i in range(n):
        ready[i] = False
    for c in range(N_COUNTERS):
        counters[c] = 0
    counters[0] = npairs + nplane
    ncand = 0
    best = 2.0
    best_k = -1
    t_start = 0
    for k in range(npairs):
        if timing:
            t_start = _ticks()
        i = pairs[k, 0]
        j = pairs[k, 1]
        times[k] = -1.0
        te = -1.0
        if _too_slow(p0, q0, p1, q1_raw, rmax, min_motion, i, j, k):
            code = TOO_SLOW
        else:
            te = _sphere_entry(p0, p1, rmax, i, j)
            code = SPHERE
        if te >= 0.0:
            if not ready[i]:
                _prepare(affine, i, radii, q0, q1_raw, q1, S, den, R0, R1, aff_scratch)
                ready[i] = True
            if not ready[j]:
                _prepare(affine, j, radii, q0, q1_raw, q1, S, den, R0, R1, aff_scratch)
                ready[j] = True
            code = _filter_pair(i, j, radii, p0, q0, p1, q1, S, den, R0, R1, use_cache, cache_n, cache_kind, k,
                                work, scratch)
            if code == OVERLAP_T0:
                te = 0.0
        outcome[k] = code
        entry[k] = te
        if code == OVERLAP_T0 and new_only:
            counters[4] += 1
            counters[6] += 1
        elif code == OVERLAP_T0:
            best, best_k = _in_contact_at_start(k, times, points, normals, best, best_k)
            cand[ncand] = k
            ncand += 1
        elif code == EXACT_FREE:
            cand[ncand] = k
            ncand += 1
        if code <= NEW_PLANE:
            counters[1 + code] += 1
        elif code == TOO_SLOW:
            counters[9] += 1
        if timing:
            ticks[k] = _ticks() - t_start
    for k2 in range(nplane):  # plane pairs: the too-slow policy, the sphere against the plane
        k = npairs + k2
        if timing:
            t_start = _ticks()
        e = plane_pairs[k2, 0]
        times[k] = -1.0
        te = -1.0
        if _plane_too_slow(p0, q0, p1, q1_raw, rmax, plane_min_motion, e, k2):
            code = TOO_SLOW
        else:
            te, below = _plane_entry(p0, q0, p1, planes, radii, rmax, e, plane_pairs[k2, 1])
            code = OVERLAP_T0 if below else (EXACT_FREE if te >= 0.0 else SPHERE)
        outcome[k] = code
        entry[k] = te
        if code == OVERLAP_T0 and new_only:
            counters[4] += 1
            counters[6] += 1
        elif code == OVERLAP_T0:
            best, best_k = _in_contact_at_start(k, times, points, normals, best, best_k)
            cand[ncand] = k
            ncand += 1
        elif code == EXACT_FREE:
            cand[ncand] = k
            ncand += 1
        elif code == SPHERE:
            counters[1] += 1
        else:
            counters[9] += 1
        if timing:
            ticks[k] = _ticks() - t_start
    niv = 0
    if ncand > 1:
        sort_by_key(cand, ncand, entry)  # by sphere-entry time
    for idx in range(ncand):
        k = cand[idx]
        if timing:
            t_start = _ticks()
        if k >= npairs:  # a plane pair
            if outcome[k] == OVERLAP_T0:
                counters[4] += 1
                counters[6] += 1
                if not all_pairs:
                    continue
            elif not all_pairs and (best == 0.0 or entry[k] > best):
                outcome[k] = PRUNED
                counters[7] += 1
                continue
            status0, runs, certified, lo, hi, nruns = _plane_solve(
                affine, radii, p0, q0, p1, q1_raw, planes, plane_pairs, npairs, k, 1.0 if all_pairs else min(best, 1.0),
                not all_pairs, plane_work, plane_touch)
            if outcome[k] == OVERLAP_T0:
                if not certified:
                    outcome[k] = UNCERTAIN
                    times_hi[k] = 0.0
                    counters[8] += 1
            else:
                counters[5] += 1
                if status0 != 1:  # touching at the start (or within rounding of it): in contact, never new
                    outcome[k] = OVERLAP_T0
                    counters[4] += 1
                    counters[6] += 1
                    if not new_only:
                        best, best_k = _in_contact_at_start(k, times, points, normals, best, best_k)
                elif nruns > 0 or not certified:
                    # the first contact is known when its run is proven with a narrow entry bracket
                    known = nruns > 0 and runs[0, 6] > 0.0 and max(runs[0, 0] - runs[0, 2],
                                                                     runs[0, 3] - runs[0, 0]) <= TIME_TOL
                    t = runs[0, 0] if known else lo
                    if known:
                        counters[6] += 1
                    if certified:
                        outcome[k] = EXACT_HIT
                    else:
                        outcome[k] = UNCERTAIN
                        times_hi[k] = t if known else hi
                        counters[8] += 1
                    times[k] = t
                    for m in range(3):
                        points[k, m] = plane_touch[0, m]
                        normals[k, m] = plane_touch[1, m]
                    if t < best or (t == best and k < best_k):
                        best, best_k = t, k
            if all_pairs:
                for r in range(nruns):
                    if niv == iv.shape[0]:
                        iv, owner = _grown(iv, owner, niv)
                    iv[niv, 0] = runs[r, 0]
                    iv[niv, 1] = runs[r, 1]
                    owner[niv] = k
                    niv += 1
            if timing:
                ticks[k] += _ticks() - t_start
            continue
        i = pairs[k, 0]
        j = pairs[k, 1]
        if outcome[k] == OVERLAP_T0:
            counters[4] += 1
            counters[6] += 1
            if not all_pairs:
                continue
        elif not all_pairs and (best == 0.0 or entry[k] > best):
            outcome[k] = PRUNED
            counters[7] += 1
            continue
        t_max = 1.0 if all_pairs else min(best, 1.0)
        status0, intervals, point, normal, certified, lo, hi = exact_pair(
            affine, radii[i], p0[i], q0[i], p1[i], q1[i], radii[j], p0[j], q0[j], p1[j], q1[j], t_max, not all_pairs)
        if outcome[k] == OVERLAP_T0:
            if not certified:  # (all pairs only) contact at 0 for sure, later intervals not complete
                outcome[k] = UNCERTAIN
                times_hi[k] = 0.0
                counters[8] += 1
        else:
            counters[5] += 1
            if new_only and status0 != 1:  # touching at t = 0 (the static test could not tell): not new
                outcome[k] = OVERLAP_T0
                counters[4] += 1
                counters[6] += 1
            elif intervals.shape[0] > 0 or not certified:  # an uncertain pair is a possible contact at lo
                t = lo if intervals.shape[0] == 0 else (intervals[0, 0] if status0 == 1 else 0.0)
                # the first contact is known when its proven bracket [lo, hi] is within TIME_TOL of it (an
                # uncertain answer may still have it, its later intervals cut short); else only the bracket is
                known = intervals.shape[0] > 0 and max(t - lo, hi - t) <= TIME_TOL
                if known:  # a first contact found: colliding (an honest count)
                    counters[6] += 1
                if certified:
                    outcome[k] = EXACT_HIT
                else:
                    outcome[k] = UNCERTAIN
                    if not known:
                        t = lo
                    times_hi[k] = t if known else hi
                    counters[8] += 1
                times[k] = t
                if known or certified:
                    for m in range(3):
                        points[k, m] = point[m]
                        normals[k, m] = normal[m]
                else:  # the first contact is only bracketed: where they nearly touch at the bracket's start
                    _estimated_touch(radii[i], p0[i], q0[i], p1[i], q1_raw[i], radii[j], p0[j], q0[j], p1[j],
                                     q1_raw[j], t, points[k], normals[k])
                if t < best or (t == best and k < best_k):
                    best, best_k = t, k
        if all_pairs:
            for r in range(intervals.shape[0]):
                if niv == iv.shape[0]:
                    iv, owner = _grown(iv, owner, niv)
                iv[niv, 0] = intervals[r, 0]
                iv[niv, 1] = intervals[r, 1]
                owner[niv] = k
                niv += 1
        if timing:
            ticks[k] += _ticks() - t_start
    return best_k, niv, iv, owner


@_jit
def run_kernel(ws, positions, quats, iv, owner, new_only, timing, out):
    """Frames 0..F-1 of a pose sequence in one call, carrying the plane cache; fills ``out`` (``_RunArrays``).

    ``positions`` (F + 1, N, 3) and unit ``quats`` (F + 1, N, 4); first contacts
    only.  ``iv``/``owner`` as in :func:`step_kernel` (not written: no
    intervals are asked for).  Each frame's outcomes, ticks and counters are
    copied from the workspace into row f of ``out``.
    """
    outcome, ticks, counters = field(ws, "outcome"), field(ws, "ticks"), field(ws, "counters")
    times, points, normals = field(ws, "times"), field(ws, "points"), field(ws, "normals")
    positions, quats = _borrow(positions), _borrow(quats)
    best_time, best_pair, best_point, best_normal = (_borrow(out.time), _borrow(out.pair), _borrow(out.point),
                                                     _borrow(out.normal))
    out_counters, out_outcomes, out_ticks, frame_ticks = (_borrow(out.counters), _borrow(out.outcomes),
                                                          _borrow(out.ticks), _borrow(out.frame_ticks))
    t_start = 0
    for f in range(positions.shape[0] - 1):
        if timing:
            t_start = _ticks()
        k, _, _, _ = step_kernel(ws, positions[f], quats[f], positions[f + 1], quats[f + 1], iv, owner,
                                 np.bool_(False), new_only, timing)
        for k2 in range(outcome.shape[0]):
            out_outcomes[f, k2] = outcome[k2]
            if timing:
                out_ticks[f, k2] = ticks[k2]
        for c in range(N_COUNTERS):
            out_counters[f, c] = counters[c]
        best_pair[f] = k
        best_time[f] = times[k] if k >= 0 else -1.0
        if k >= 0:
            for m in range(3):
                best_point[f, m] = points[k, m]
                best_normal[f, m] = normals[k, m]
        if timing:
            frame_ticks[f] = _ticks() - t_start


@_inline
def _may_touch(affine, radii, rmax, pairs, min_motion, p0, q0, p1, q1, planes, plane_pairs, plane_min_motion):
    """The loop of :func:`may_touch_kernel` on (borrowed) arrays."""
    for k2 in range(plane_pairs.shape[0]):
        e = plane_pairs[k2, 0]
        if _plane_too_slow(p0, q0, p1, q1, rmax, plane_min_motion, e, k2):
            continue
        te, below = _plane_entry(p0, q0, p1, planes, radii, rmax, e, plane_pairs[k2, 1])
        if te >= 0.0 and not below:
            return True
    for k in range(pairs.shape[0]):
        i = pairs[k, 0]
        j = pairs[k, 1]
        if _too_slow(p0, q0, p1, q1, rmax, min_motion, i, j, k) or _sphere_entry(p0, p1, rmax, i, j) < 0.0:
            continue
        if fl.slabs_clear(affine, radii, rmax, p0, q0, p1, q1, i, j):
            continue
        if static_status_pose(radii[i], p0[i], q0[i], radii[j], p0[j], q0[j]) == -1:
            continue
        return True
    return False


@_jit
def may_touch_kernel(ws, p0, q0, p1, q1):
    """False only when no pair of the workspace ``ws`` can make a new contact in the frame.

    Poses as :func:`step_kernel` takes them.  Per pair, what :func:`step_kernel`
    decides the same way: the too-slow policy and the moving spheres
    (:func:`mjccd.filters.sphere_entry`); then slabs that hold over the whole
    frame (:func:`mjccd.filters.slabs_clear`); last, a pair certainly
    overlapping at t = 0 (the static test :func:`step_kernel` runs) is no new
    contact.  So :func:`step_kernel` with ``new_only`` finds no contact, not
    even an uncertain one, when this returns False.  Plane pairs: the too-slow
    policy, the sphere against the plane, and a body certainly in contact
    with it at t = 0 (:func:`_plane_entry`; no new contact).  Allocates nothing.
    """
    return _may_touch(field(ws, "affine"), field(ws, "radii"), field(ws, "rmax"), field(ws, "pairs"),
                      field(ws, "min_motion"), _borrow(p0), _borrow(q0), _borrow(p1), _borrow(q1),
                      field(ws, "planes"), field(ws, "plane_pairs"), field(ws, "plane_min_motion"))


@_jit
def poses_may_touch(ws, poses_t0, poses_t1):
    """:func:`may_touch_kernel` of (N, 7) poses, split into the workspace's pose arrays as :meth:`Scene.step` splits them.

    True (nothing cleared) when a pose is not finite or not ordinary (see
    :func:`_split_poses`): the exact check then decides, or names the bad input.
    """
    p0, q0, p1, q1 = field(ws, "p0"), field(ws, "q0"), field(ws, "p1"), field(ws, "q1")
    if not (_split_poses(_borrow(poses_t0), p0, q0) and _split_poses(_borrow(poses_t1), p1, q1)):
        return True
    return _may_touch(field(ws, "affine"), field(ws, "radii"), field(ws, "rmax"), field(ws, "pairs"),
                      field(ws, "min_motion"), p0, q0, p1, q1, field(ws, "planes"), field(ws, "plane_pairs"),
                      field(ws, "plane_min_motion"))


# ---------------------------------------------------------------- Python layer


@dataclass(frozen=True)
class PairContact:
    """Contact of one pair in a frame.

    ``time`` in [0, 1] (0 when the pair is not separate at the start); ``point``
    (world) and ``normal`` (unit, outward from ``bodies[0]``) are None then.
    ``intervals`` lists the maximal non-separation intervals (only when every
    colliding pair was asked for; empty otherwise).

    ``certainty`` is "certified", or "uncertain" when the exact solver hit one
    of its limits on this pair: then ``bracket`` = (lo, hi) holds every
    possible first contact, ``time`` is lo, and point and normal are an
    estimate, where the two nearly touch at lo (the touching point itself when
    the first contact was found: lo == hi; with ``all_pairs`` only, its later
    ``intervals`` are then incomplete), None only where no estimate could be
    formed.  An uncertain pair is a possible contact at lo, never "no contact".
    """

    pair: int
    bodies: tuple
    time: float
    point: object
    normal: object
    intervals: tuple = ()
    certainty: str = "certified"
    bracket: tuple = None


@dataclass(frozen=True)
class PlaneContact:
    """Contact of an ellipsoid with a plane (a plane pair of the scene) in a frame.

    ``pair`` is the scene's pair index, ``len(scene.pairs) + row`` for row
    ``row`` of :attr:`Scene.plane_pairs`; ``ellipsoid`` and ``plane`` index
    the scene's ellipsoids and :attr:`Scene.planes`.  The other fields are
    those of :class:`PairContact`, with the body touching or entering the
    half-space below the plane: ``point`` is the ellipsoid's point deepest
    along -n at the first contact and ``normal`` = -n (outward from the
    ellipsoid, as ``PairContact.normal`` is outward from ``bodies[0]``).
    """

    pair: int
    ellipsoid: int
    plane: int
    time: float
    point: object
    normal: object
    intervals: tuple = ()
    certainty: str = "certified"
    bracket: tuple = None


@dataclass(frozen=True)
class FrameCounters:
    """How the pairs of a frame were decided.

    ``colliding`` counts the pairs found colliding; when only the first contact
    is sought, pairs whose spheres meet after it are ``pruned`` instead of
    solved, so it is a lower bound then.  ``uncertain`` counts the pairs on
    which the exact solver hit a limit (outcome "uncertain"): each is a
    possible contact within its bracket and is not counted as colliding unless
    its first contact was found (with ``all_pairs``, when only a later interval
    was left open).  ``too_slow`` counts the pairs left out because their
    relative motion stayed below their ``min_motion`` (a policy of the caller,
    :meth:`Scene.set_min_motion`; the filters, ``sphere_culled`` to
    ``new_plane``, only clear pairs that cannot touch).  It comes last so that
    the indices of the others stay those of earlier versions.
    """

    pairs: int
    sphere_culled: int
    cached_plane: int
    new_plane: int
    overlapping_t0: int
    solved_exactly: int
    colliding: int
    pruned: int
    uncertain: int
    too_slow: int

    @classmethod
    def from_array(cls, c):
        return cls(*np.asarray(c, dtype=np.int64).tolist())


@dataclass(frozen=True)
class FrameResult:
    """Result of :meth:`Scene.step`: the first contact (or None), all contacts when asked, counters.

    ``certainty`` is "uncertain" when a reported contact is (the first one, or
    with ``all_pairs`` any of ``contacts``; see :class:`PairContact`), else
    "certified".  ``counters.uncertain`` also counts uncertain pairs that
    cannot change the answer (their bracket starts at or after the first
    contact).  What the compiled kernel leaves uncertain is asked again of
    the core's exact tiers (:mod:`mjccd.settle`) unless the caller said
    ``resolve_uncertain=False``; the counters then count what is left.
    """

    first: object
    contacts: tuple
    counters: FrameCounters
    certainty: str


@dataclass(frozen=True)
class RunResult:
    """Result of :meth:`Scene.run` over F frames (arrays indexed by frame).

    ``time[f]`` is the first contact of frame f (-1 when none), ``pair[f]`` its
    pair index (-1), ``point``/``normal`` (F, 3) zero when none or at t = 0;
    ``uncertain`` (F,) int8 is 1 where that first contact is uncertain (then
    ``time[f]`` is the low end of its bracket and point and normal are zero;
    :meth:`Scene.step` gives the bracket); ``counters`` (F, N_COUNTERS) in the order of
    :class:`FrameCounters`; ``outcomes``
    (F, P + Q) the outcome code of every pair, plane pairs last (see
    ``OUTCOME_NAMES``); ``ticks`` (F, P + Q) CPU cycles per pair and
    ``frame_ticks`` (F,) per frame when timing was asked for (zero otherwise).
    """

    time: np.ndarray
    pair: np.ndarray
    point: np.ndarray
    normal: np.ndarray
    counters: np.ndarray
    outcomes: np.ndarray
    ticks: np.ndarray
    frame_ticks: np.ndarray
    uncertain: np.ndarray


# what run_kernel fills: the arrays of a RunResult but ``uncertain`` (set from them afterwards)
_RunArrays = collections.namedtuple("_RunArrays", [f.name for f in fields(RunResult) if f.name != "uncertain"])


class FirstContact(NamedTuple):
    """The answer of :meth:`Scene.first_contact`: the fields of :class:`PairContact` that a first contact needs.

    ``pair`` indexes :attr:`Scene.pairs`, or, from ``len(Scene.pairs)`` on,
    :attr:`Scene.plane_pairs` (see :meth:`Scene.plane_pair`); ``time`` in [0, 1]; ``point`` and
    ``normal`` (3,) copies, None exactly when :class:`PairContact` has None;
    ``bracket`` (lo, hi) when the answer is uncertain (then ``time`` is lo),
    else None.
    """

    pair: int
    time: float
    point: object
    normal: object
    bracket: tuple


def first_of(k, outcome, times, times_hi, points, normals):
    """The :class:`FirstContact` of pair k from the per-pair arrays :func:`step_kernel` filled."""
    t = float(times[k])
    uncertain = int(outcome[k]) == UNCERTAIN
    no_touch = (t == 0.0 or uncertain) and not normals[k].any()
    return FirstContact(int(k), t, None if no_touch else points[k].copy(), None if no_touch else normals[k].copy(),
                        (t, float(times_hi[k])) if uncertain else None)


def pair_contact(pairs, k, outcome, times, times_hi, points, normals, intervals=()):
    """The :class:`PairContact` of pair k from the per-pair arrays :func:`step_kernel` filled."""
    k, t, point, normal, bracket = first_of(k, outcome, times, times_hi, points, normals)
    return PairContact(k, (int(pairs[k, 0]), int(pairs[k, 1])), t, point, normal, intervals,
                       "certified" if bracket is None else "uncertain", bracket)


def plane_contact(pairs, plane_pairs, k, outcome, times, times_hi, points, normals, intervals=()):
    """The :class:`PlaneContact` of pair k (>= len(pairs), a plane pair) from the per-pair arrays."""
    k, t, point, normal, bracket = first_of(k, outcome, times, times_hi, points, normals)
    row = plane_pairs[k - len(pairs)]
    return PlaneContact(k, int(row[0]), int(row[1]), t, point, normal, intervals,
                        "certified" if bracket is None else "uncertain", bracket)


def _contact_of(pairs, plane_pairs, k, outcome, times, times_hi, points, normals, intervals=()):
    """:func:`pair_contact` or, for a plane pair, :func:`plane_contact`."""
    if plane_pairs is None or k < len(pairs):
        return pair_contact(pairs, k, outcome, times, times_hi, points, normals, intervals)
    return plane_contact(pairs, plane_pairs, k, outcome, times, times_hi, points, normals, intervals)


def frame_result(pairs, best_k, outcome, times, times_hi, points, normals, counters, rows=None, plane_pairs=None):
    """The :class:`FrameResult` of one :func:`step_kernel` call (a pure function of its arrays).

    ``best_k`` is the kernel's first pair (-1: none); ``rows`` (all pairs
    asked) the intervals of each pair as ``(iv, owner)``, the kernel's first
    ``rows`` rows; None when only the first contact was sought.  Pairs from
    ``len(pairs)`` on are rows of ``plane_pairs`` and give :class:`PlaneContact`.
    """
    first = None if best_k < 0 else _contact_of(pairs, plane_pairs, best_k, outcome, times, times_hi, points, normals)
    contacts = ()
    if rows is not None:
        by_pair = {}
        for (a, b), k in zip(*rows):
            by_pair.setdefault(int(k), []).append((float(a), float(b)))
        contacts = tuple(_contact_of(pairs, plane_pairs, k, outcome, times, times_hi, points, normals,
                                     tuple(by_pair.get(k, ())))
                         for k in np.nonzero(times >= 0.0)[0].tolist())
    uncertain = any(c is not None and c.certainty == "uncertain" for c in (first,) + contacts)
    return FrameResult(first, contacts, FrameCounters.from_array(counters),
                       "uncertain" if uncertain else "certified")


def _plane_arguments(planes, plane_pairs, n):
    """Validated (K, 4) plane rows and (Q, 2) int64 plane pairs (both None when there are no planes)."""
    if planes is None or (not isinstance(planes, Plane) and len(planes) == 0):
        if plane_pairs is not None and len(np.asarray(plane_pairs).reshape(-1)):
            raise InputError("plane_pairs: given without planes")
        return None, None
    rows = plane_rows(planes, "planes")
    k = len(rows)
    if plane_pairs is None:
        return rows, np.stack([np.repeat(np.arange(n), k), np.tile(np.arange(k), n)], axis=1).astype(np.int64)
    try:
        arr = np.asarray(plane_pairs)
    except ValueError:  # ragged rows
        raise InputError("plane_pairs: expected Q rows (ellipsoid index, plane index)") from None
    if arr.ndim != 2 or arr.shape[1] != 2:
        raise InputError(f"plane_pairs: expected shape Qx2, got {arr.shape}")
    if arr.size and (arr.dtype.kind not in "iuf" or not np.all(np.isfinite(arr)) or np.any(arr != np.round(arr))):
        raise InputError(f"plane_pairs: expected integer (ellipsoid, plane) indices, got {arr[0].tolist()!r}")
    arr = arr.astype(np.int64)
    for col, count, what in ((0, n, "ellipsoids"), (1, k, "planes")):
        bad = np.flatnonzero((arr[:, col] < 0) | (arr[:, col] >= count))
        if len(bad):
            raise InputError(f"plane_pairs[{bad[0]}]: {what[:-1]} index out of range for {count} {what}, "
                             f"got {arr[bad[0]].tolist()}")
    return rows, arr


def all_pairs(n):
    """All pairs (i, j), i < j, of n ellipsoids: (n (n - 1) / 2, 2)."""
    i, j = np.triu_indices(int(n), 1)
    return np.stack([i, j], axis=1).astype(np.int64)


def pairs_between(group_a, group_b):
    """Every pair with one ellipsoid from each group (thesis: two characters, 20 x 20 pairs)."""
    a = np.asarray(group_a, dtype=np.int64).ravel()
    b = np.asarray(group_b, dtype=np.int64).ravel()
    return np.stack([np.repeat(a, len(b)), np.tile(b, len(a))], axis=1)


def non_adjacent_pairs(n, edges):
    """All pairs of n ellipsoids except the adjacent ones listed in ``edges`` (self-collision)."""
    adjacent = {(min(int(a), int(b)), max(int(a), int(b))) for a, b in np.asarray(edges).reshape(-1, 2)}
    return np.array([p for p in all_pairs(n).tolist() if tuple(p) not in adjacent], dtype=np.int64).reshape(-1, 2)


class Scene:
    """N ellipsoids and the pairs to check, stepped frame by frame.

    Args:
        radii: (N, 3) semi-axes of each ellipsoid in its own frame.
        pairs: (P, 2) ellipsoid indices; default all pairs i < j (see
            :func:`pairs_between`, :func:`non_adjacent_pairs`).
        motion: "rigid" (centre and quaternion lerp) or "affine" (centre and
            shape matrix lerp, thesis §5.2).
        plane_cache: keep each pair's separating plane for the next frame.
        planes: static planes, each the solid half-space below it (MuJoCo's
            ``plane`` geoms): a sequence of :class:`mjccd.plane.Plane`, or (K, 4)
            rows ``[nx, ny, nz, offset]`` for ``n . x = offset`` (normals of any
            length, normalised here).  None or empty: no planes.
        plane_pairs: (Q, 2) rows (ellipsoid index, plane index) to check; default
            every ellipsoid against every plane.  Their pair indices are
            ``len(pairs) + row`` (see :meth:`plane_pair`), their contacts
            :class:`PlaneContact`.

    One thread at a time: the scene's buffers (poses, answers, plane cache)
    are shared, so a call while another thread is in one raises
    :class:`~mjccd.errors.ConcurrentUseError` at once (a scene per thread
    runs in parallel).
    """

    def __init__(self, radii, *, pairs=None, motion="rigid", plane_cache=True, planes=None, plane_pairs=None):
        self.radii = _validate.radii_array(radii, "radii")
        n = len(self.radii)
        if not isinstance(motion, str) or motion not in ("rigid", "affine"):
            raise InputError(f"motion: expected 'rigid' or 'affine', got {motion!r}")
        self.motion = motion
        if pairs is None:
            pairs = all_pairs(n)
        try:
            arr = np.asarray(pairs)
        except ValueError:  # ragged rows
            raise InputError(f"pairs: expected P rows of 2 ellipsoid indices in 0..{n - 1}") from None
        if arr.ndim != 2 or arr.shape[1] != 2:
            raise InputError(f"pairs: expected shape Px2, got {arr.shape}")
        if arr.size and arr.dtype.kind not in "iuf":  # names, objects or bools: only indices are meant
            raise InputError(f"pairs: expected ellipsoid indices in 0..{n - 1}, got {arr[0].tolist()!r} "
                             "(pairs of body names: mjccd.mujoco.CCDMonitor)")
        if arr.size and not np.issubdtype(arr.dtype, np.integer):
            if not np.all(np.isfinite(arr)) or np.any(arr != np.round(arr)):
                raise InputError("pairs: expected integer ellipsoid indices")
        arr = arr.astype(np.int64)
        bad = np.nonzero((arr < 0).any(axis=1) | (arr >= n).any(axis=1))[0]
        if len(bad):
            raise InputError(f"pairs[{bad[0]}]: index out of range for {n} ellipsoids, got {arr[bad[0]].tolist()}")
        same = np.nonzero(arr[:, 0] == arr[:, 1])[0]
        if len(same):
            raise InputError(f"pairs[{same[0]}]: an ellipsoid cannot be paired with itself, "
                             f"got {arr[same[0]].tolist()}")
        rows, links = _plane_arguments(planes, plane_pairs, n)
        self._arrays = new_workspace(self.radii, arr, motion == "affine", plane_cache, rows, links)
        self._ref = workspace_ref(self._arrays)
        self.radii, self.pairs, self.plane_cache = self._arrays.radii, self._arrays.pairs, self._arrays.plane_cache
        self._iv, self._owner = np.empty((0, 2)), np.empty(0, dtype=np.int64)  # intervals (all pairs), grown as needed
        self._plane_rows = self._arrays.plane_pairs if len(self._arrays.plane_pairs) else None  # for frame_result
        self._exclusive = Exclusive("Scene")

    @property
    def planes(self):
        """(K, 4) read-only: the planes ``[nx, ny, nz, offset]`` (unit normals), each the half-space n . x <= offset."""
        view = self._arrays.planes.view()
        view.flags.writeable = False
        return view

    @property
    def plane_pairs(self):
        """(Q, 2) read-only: the plane pairs (ellipsoid index, plane index); pair index ``len(pairs) + row``."""
        view = self._arrays.plane_pairs.view()
        view.flags.writeable = False
        return view

    def plane_pair(self, k):
        """(ellipsoid, plane) of pair index k when it is a plane pair, None when it is a pair of :attr:`pairs`."""
        k = int(k)
        npairs = len(self._arrays.pairs)
        if not 0 <= k < npairs + len(self._arrays.plane_pairs):
            raise InputError(f"k: pair index out of range for {npairs} pairs and "
                             f"{len(self._arrays.plane_pairs)} plane pairs, got {k}")
        if k < npairs:
            return None
        row = self._arrays.plane_pairs[k - npairs]
        return int(row[0]), int(row[1])

    @property
    def plane_min_motion(self):
        """(Q,) read-only: per plane pair, the motion over a frame below which it is left out (see
        :meth:`set_plane_min_motion`)."""
        view = self._arrays.plane_min_motion.view()
        view.flags.writeable = False
        return view

    @exclusive
    def set_plane_min_motion(self, values):
        """Leave out the plane pairs whose ellipsoid moves too little to matter: :meth:`set_min_motion` for planes.

        Plane pair k is not checked in a frame when how far any point of its
        ellipsoid moves (the centre's displacement plus the chord its largest
        semi-axis sweeps, :func:`mjccd.filters.relative_sweep` against a fixed
        point) stays below ``values[k]``; outcome ``too_slow``.

        Args:
            values: (Q,) finite numbers >= 0, one per plane pair (0: always checked).
        """
        arr = _validate.array(values, (len(self._arrays.plane_pairs),), "plane_min_motion")
        bad = np.flatnonzero(arr < 0.0)
        if len(bad):
            raise InputError(f"plane_min_motion[{bad[0]}]: expected a distance >= 0, got {float(arr[bad[0]])!r}")
        self._arrays.plane_min_motion[:] = arr

    @property
    def workspace(self):
        """The scene's :class:`WorkspaceRef`, for compiled callers (e.g. :func:`poses_may_touch` inside another kernel).

        Its ``arrays`` are the scene's own buffers, written by every check:
        read them, never write them (the plane cache and ``min_motion`` change
        through :meth:`reset_cache` and :meth:`set_min_motion`).
        """
        return self._ref

    @property
    def min_motion(self):
        """(P,) read-only: per pair, the relative motion over a frame below which the pair is left out.

        Zero (the default) checks every pair; see :meth:`set_min_motion`.
        """
        view = self._arrays.min_motion.view()
        view.flags.writeable = False
        return view

    @exclusive
    def set_min_motion(self, values):
        """Leave out the pairs that move too little to matter: a policy, not a filter.

        A pair whose relative motion over a frame (how far any point of one
        ellipsoid moves relative to any point of the other,
        :func:`mjccd.filters.relative_sweep`) stays below ``values[k]`` is not
        checked: its outcome is ``too_slow`` and it counts in
        ``FrameCounters.too_slow``, whether or not it touches.  The guard sets
        this so that slow pairs are left to MuJoCo's own contacts.

        Args:
            values: (P,) finite numbers >= 0, one per pair (0: always checked).
        """
        arr = _validate.array(values, (len(self.pairs),), "min_motion")
        bad = np.flatnonzero(arr < 0.0)
        if len(bad):
            raise InputError(f"min_motion[{bad[0]}]: expected a distance >= 0, got {float(arr[bad[0]])!r}")
        self._arrays.min_motion[:] = arr

    @exclusive
    def reset_cache(self):
        """Forget every cached separating plane."""
        self._arrays.cache_n[:] = 0.0
        self._arrays.cache_kind[:] = 0

    def _poses(self, poses, field, p, q):
        """Positions into p and normalised quaternions into q; a bad input raises naming ``field``.

        The compiled split takes ordinary poses; every other input (lists, other
        layouts, NaN, a zero quaternion, a quaternion whose squared norm
        overflows, see :func:`_split_poses`) goes to
        :func:`mjccd._validate.pose_array`, which raises or scales each quaternion
        before normalising it.
        """
        if (isinstance(poses, np.ndarray) and poses.dtype == np.float64 and poses.shape == p.shape[:1] + (7,)
                and poses.flags.c_contiguous and _split_poses(poses, p, q)):
            return
        checked = _validate.pose_array(poses, field, len(p))  # raises, or converts other input
        p[:] = checked[:, :3]
        q[:] = checked[:, 3:]

    def _frame(self, poses_t0, poses_t1, all_pairs, new_contacts_only):
        """Split the poses into the workspace and run :func:`step_kernel`: (best pair, rows)."""
        a = self._arrays
        self._poses(poses_t0, "poses_t0", a.p0, a.q0)
        self._poses(poses_t1, "poses_t1", a.p1, a.q1)
        best_k, niv, self._iv, self._owner = step_kernel(self._ref, a.p0, a.q0, a.p1, a.q1, self._iv, self._owner,
                                                         all_pairs, new_contacts_only, False)
        return best_k, niv

    @exclusive
    def step(self, poses_t0, poses_t1, *, all_pairs=False, new_contacts_only=False, resolve_uncertain=True):
        """Check one frame.

        Args:
            poses_t0, poses_t1: (N, 7) rows ``[x, y, z, w, qx, qy, qz]`` at the
                start and end of the frame (world frame).
            all_pairs: also return every colliding pair with its first contact
                and intervals (slower: no earliest-contact bound).
            new_contacts_only: leave out pairs already touching or overlapping at
                the start (they are still counted); the first contact is then the
                earliest new one, found with the earliest-contact bound.
            resolve_uncertain: ask what the compiled kernel (double precision
                only) leaves uncertain again of the core's exact tiers
                (:mod:`mjccd.settle`): each such pair comes back certified,
                certified free, or uncertain with a bracket that holds every
                possible first contact.  An uncertain first contact sends the
                frame through every pair first, since a later one may then come
                first.  False: the kernel's own answers (its brackets end where
                rounding stopped deciding).
        Returns:
            :class:`FrameResult`.
        """
        all_pairs, new_only = bool(all_pairs), bool(new_contacts_only)
        result = self._result(*self._frame(poses_t0, poses_t1, all_pairs, new_only), all_pairs)
        if result.certainty == "uncertain" and resolve_uncertain:
            if not all_pairs:
                return self._settled_first(poses_t0, poses_t1, new_only)
            result = self._settled(result, new_only, True)
        return result

    def _settled_first(self, poses_t0, poses_t1, new_only):
        """The first-contact :class:`FrameResult` of a frame whose first contact the kernel left uncertain: which
        contact comes first is known only once every pair is, so every pair is checked and settled."""
        return self._settled(self._result(*self._frame(poses_t0, poses_t1, True, new_only), True), new_only, False)

    def _result(self, best_k, niv, all_pairs):
        """The :class:`FrameResult` of the kernel's last frame, read off the workspace."""
        a = self._arrays
        return frame_result(a.pairs, best_k, a.outcome, a.times, a.times_hi, a.points, a.normals, a.counters,
                            (self._iv[:niv], self._owner[:niv]) if all_pairs else None, self._plane_rows)

    def pair_problem(self, k):
        """(shape_a, motion_a, shape_b or :class:`~mjccd.Plane`, motion_b or None): what the core solves for pair
        k (a plane pair from ``len(pairs)`` on) over the last frame checked, the motion the kernel solved."""
        a = self._arrays
        return pair_problem(self.motion, a.radii, a.pairs, a.planes, a.plane_pairs, a.p0, a.q0, a.p1, a.q1, int(k))

    def _settled(self, result, new_only, all_pairs, not_new=None):
        """``result`` (every pair's contacts) with its uncertain contacts asked again of the core; the first
        contact is the earliest of what is left (lowest pair index on a tie, as the kernel chooses).
        ``not_new``: as in :func:`mjccd.settle.settle`."""
        contacts, tally = settle(self.pair_problem, result.contacts, new_only, self._contact_of, intervals=all_pairs,
                                 not_new=not_new)
        c = result.counters
        counters = replace(c, uncertain=c.uncertain - tally["settled"], colliding=c.colliding + tally["found"],
                           overlapping_t0=c.overlapping_t0 + tally["not_new"])
        first = min(contacts, key=lambda x: (x.time, x.pair), default=None)
        if all_pairs:
            certain = all(x.certainty == "certified" for x in contacts)
        else:
            first = first if first is None else replace(first, intervals=())
            contacts = ()
            certain = first is None or first.certainty == "certified"
        return FrameResult(first, tuple(contacts), counters, "certified" if certain else "uncertain")

    def _contact_of(self, k, answer):
        """The :class:`PairContact` or :class:`PlaneContact` of pair k from the core's answer."""
        pairs = self._arrays.pairs
        certainty = "certified" if answer.bracket is None else "uncertain"
        if k < len(pairs):
            return PairContact(k, (int(pairs[k, 0]), int(pairs[k, 1])), answer.time, answer.point, answer.normal,
                               answer.intervals, certainty, answer.bracket)
        e, row = (int(x) for x in self._arrays.plane_pairs[k - len(pairs)])
        return PlaneContact(k, e, row, answer.time, answer.point, answer.normal, answer.intervals, certainty,
                            answer.bracket)

    @exclusive
    def first_contact(self, poses_t0, poses_t1, *, new_contacts_only=False, resolve_uncertain=True):
        """The first contact of one frame, without the result objects of :meth:`step`: None or a :class:`FirstContact`.

        The same compiled kernel on the same buffers and plane cache as
        :meth:`step`, so it equals ``step(poses_t0, poses_t1,
        new_contacts_only=...).first`` (and carries the plane cache on the same
        way); for callers that check every simulator step (the guard).
        Arguments as in :meth:`step`.
        """
        best_k = self.first_pair(poses_t0, poses_t1, new_contacts_only=new_contacts_only)
        if best_k < 0:
            return None
        a = self._arrays
        first = first_of(best_k, a.outcome, a.times, a.times_hi, a.points, a.normals)
        if first.bracket is None or not resolve_uncertain:
            return first
        c = self._settled_first(poses_t0, poses_t1, bool(new_contacts_only)).first
        return None if c is None else FirstContact(c.pair, c.time, c.point, c.normal, c.bracket)

    @exclusive
    def first_pair(self, poses_t0, poses_t1, *, new_contacts_only=False):
        """The pair index of the first contact of one frame (-1: none), for callers that read the rest of the
        answer from :attr:`workspace` (``outcome``, ``times``, ``points``, ... of every pair, ``counters``).

        The check of :meth:`first_contact`, which is :func:`first_of` of this index: the compiled kernel's own
        answer (an uncertain one, outcome ``UNCERTAIN``, is not asked again; :meth:`step` asks).  Arguments as in
        :meth:`step`.
        """
        best_k, _ = self._frame(poses_t0, poses_t1, False, bool(new_contacts_only))
        return int(best_k)

    @exclusive
    def may_touch(self, poses_t0, poses_t1):
        """A cheap conservative test: False only when :meth:`first_contact` ``(..., new_contacts_only=True)`` of
        the same poses certainly finds nothing (not even an uncertain contact).

        Per pair: the too-slow policy and the moving spheres, as :meth:`step`
        decides them; slabs between the two ellipsoids that hold over the whole
        frame (:func:`mjccd.filters.slabs_clear`); a pair overlapping at the
        start (the static test of :meth:`step`).  No exact solve, nothing
        allocated; the plane cache is not touched.  Compiled callers use
        :func:`poses_may_touch` with :attr:`workspace`.  Arguments as in :meth:`step`.
        """
        a = self._arrays
        self._poses(poses_t0, "poses_t0", a.p0, a.q0)
        self._poses(poses_t1, "poses_t1", a.p1, a.q1)
        return bool(may_touch_kernel(self._ref, a.p0, a.q0, a.p1, a.q1))

    @exclusive
    def run(self, poses, *, timing=False, new_contacts_only=False, resolve_uncertain=True):
        """Check F frames of a pose sequence (F + 1, N, 7) in one compiled call; see :class:`RunResult`.

        The plane cache carries from frame to frame (and into later calls).
        ``timing`` records CPU cycles per pair (for benchmarks);
        ``new_contacts_only`` and ``resolve_uncertain`` as in :meth:`step`: a frame whose first contact the
        kernel leaves uncertain is checked again through every pair and settled, and its row of the result
        (first contact, counters, outcomes) is that check's.
        """
        arr = _validate.array(poses, (None, len(self.radii), 7), "poses")
        if arr.shape[0] < 2:
            raise InputError(f"poses: expected at least 2 pose sets (F + 1, N, 7), got {arr.shape[0]}")
        # quaternions scaled by a power of two (exact) before normalising, as _validate.pose_array does
        _, exponents = np.frexp(np.abs(arr[:, :, 3:]).max(axis=2))
        quats = np.ldexp(arr[:, :, 3:], -exponents[:, :, None])
        norms = np.sqrt(np.sum(quats ** 2, axis=2))
        bad = np.argwhere(np.ldexp(norms, exponents) < _validate.MIN_NORM)
        if len(bad):
            raise InputError(f"poses[{bad[0][0]}][{bad[0][1]}]: zero quaternion")
        positions = np.ascontiguousarray(arr[:, :, :3])
        quats = np.ascontiguousarray(quats / norms[:, :, None])
        nf = arr.shape[0] - 1
        npairs = len(self.pairs) + len(self._arrays.plane_pairs)
        out = _RunArrays(np.empty(nf), np.empty(nf, dtype=np.int64), np.zeros((nf, 3)), np.zeros((nf, 3)),
                         np.empty((nf, N_COUNTERS), dtype=np.int64), np.empty((nf, npairs), dtype=np.int8),
                         np.zeros((nf, npairs), dtype=np.int64), np.zeros(nf, dtype=np.int64))
        run_kernel(self._ref, positions, quats, self._iv, self._owner, bool(new_contacts_only), bool(timing), out)
        uncertain = np.zeros(nf, dtype=np.int8)
        hit = np.flatnonzero(out.pair >= 0)
        uncertain[hit] = out.outcomes[hit, out.pair[hit]] == UNCERTAIN
        if resolve_uncertain and uncertain.any():
            self._settle_frames(arr, out, uncertain, bool(new_contacts_only))
        return RunResult(*out, uncertain)

    @exclusive
    def settled_step(self, poses_t0, poses_t1, *, new_contacts_only=False):
        """``(result, outcomes)``: :meth:`step` through every pair with its uncertain contacts settled (a
        :class:`FrameResult`), and the outcome code of every pair after that ((P + Q,) int8: a settled pair is
        ``EXACT_HIT``, ``OVERLAP_T0`` at t = 0 (also one ``new_contacts_only`` leaves out), ``EXACT_FREE``, or
        still ``UNCERTAIN``).  How :meth:`run`'s
        frames and :class:`~mjccd.batch.BatchScene`'s worlds with an uncertain answer are checked again; the
        plane cache is left as it was."""
        a = self._arrays
        new_only = bool(new_contacts_only)
        cache = a.cache_n.copy(), a.cache_kind.copy()
        try:
            result = self._result(*self._frame(poses_t0, poses_t1, True, new_only), True)
        finally:
            a.cache_n[:], a.cache_kind[:] = cache
        outcomes = a.outcome.copy()
        if result.certainty == "uncertain":
            not_new = []
            result = self._settled(result, new_only, True, not_new)
            answered = {c.pair: c for c in result.contacts}
            not_new = set(not_new)
            for k in np.flatnonzero(outcomes == UNCERTAIN).tolist():
                c = answered.get(k)
                outcomes[k] = (OVERLAP_T0 if k in not_new else EXACT_FREE if c is None
                               else UNCERTAIN if c.certainty == "uncertain" else OVERLAP_T0 if c.time == 0.0
                               else EXACT_HIT)
        return result, outcomes

    def _settle_frames(self, poses, out, uncertain, new_only):
        """Each frame f of :meth:`run` whose first contact is uncertain, checked again (:meth:`settled_step`),
        written into row f of ``out`` and ``uncertain``."""
        for f in np.flatnonzero(uncertain).tolist():
            result, out.outcomes[f] = self.settled_step(poses[f], poses[f + 1], new_contacts_only=new_only)
            out.counters[f] = astuple(result.counters)
            first = result.first
            out.pair[f] = -1 if first is None else first.pair
            out.time[f] = -1.0 if first is None else first.time
            touch = first is not None and first.certainty == "certified" and first.point is not None
            out.point[f] = first.point if touch else 0.0
            out.normal[f] = first.normal if touch else 0.0
            uncertain[f] = first is not None and first.certainty == "uncertain"


split_poses = _split_poses
"""Public name of :func:`_split_poses`, for kernels that split poses as :meth:`Scene.step` does (:mod:`mjccd.batch`)."""
