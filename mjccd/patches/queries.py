"""Vertex-face and edge-edge CCD as degenerate patches, and the CCD query-set reader.

A vertex-face query is a moving point against a moving linear triangle (two unknowns on
the face plus time); an edge-edge query is a pair of moving linear segments (one unknown
each plus time). Both run through the same solver as the patches.
"""
import gzip
import json
from fractions import Fraction
from pathlib import Path

import numpy as np

from mjccd.errors import InputError

from . import _kernels as K
from .primitives import KIND_CODE, Patch, corner_indices, subdivision_matrices
from .solver import (DEFAULT_DELTA, DEFAULT_MARGIN, DEFAULT_TIME_MARGIN, METHODS, STATUS,
                     _options, first_contact)

# linear triangle control-point order is (w, v, u) vertices; face (f0, f1, f2) maps to
# f0 at (u, v) = (0, 0), f1 at (1, 0), f2 at (0, 1)
_FACE_ORDER = (0, 2, 1)


def vertex_face(vertex_t0, face_t0, vertex_t1, face_t1, **options):
    """Earliest contact of a moving vertex with a moving triangle, or None.

    Args:
        vertex_t0, vertex_t1: (3,) vertex at the start / end of the step.
        face_t0, face_t1: (3, 3) triangle vertices (rows) at the start / end.
        **options: as :func:`mjccd.patches.first_contact`; ``params`` of the result are
            (0, 0, u, v) with the contact at ``f0 + u (f1 - f0) + v (f2 - f0)``.
    """
    point = Patch.point(vertex_t0, vertex_t1)
    f0 = np.asarray(face_t0, dtype=np.float64)
    f1 = np.asarray(face_t1, dtype=np.float64)
    if f0.shape != (3, 3) or f1.shape != (3, 3):
        raise InputError(f"`face_t0`/`face_t1`: expected shape (3, 3), got "
                         f"{f0.shape} and {f1.shape}")
    tri = Patch.triangle(f0[list(_FACE_ORDER)], f1[list(_FACE_ORDER)])
    return first_contact(point, tri, **options)


def edge_edge(edge_a_t0, edge_b_t0, edge_a_t1, edge_b_t1, **options):
    """Earliest contact of two moving segments, or None.

    Args:
        edge_a_t0, edge_a_t1: (2, 3) end points of edge a at the start / end of the step.
        edge_b_t0, edge_b_t1: (2, 3) end points of edge b.
        **options: as :func:`mjccd.patches.first_contact`; ``params`` are (s, 0, r, 0)
            with the contact at ``a0 + s (a1 - a0)`` and ``b0 + r (b1 - b0)``.
    """
    return first_contact(Patch.curve(edge_a_t0, edge_a_t1), Patch.curve(edge_b_t0, edge_b_t1),
                         **options)


def _homogeneous(points_t0, points_t1):
    n = points_t0.shape[:-1]
    return np.concatenate([points_t0, np.ones(n + (1,)), points_t1], axis=-1)


def query_primitives(kind, vertices):
    """Kernel rows (Q, 1, N, 7) of both sides for (Q, 8, 3) query vertices (file order)."""
    v = np.asarray(vertices, dtype=np.float64)
    if v.ndim != 3 or v.shape[1:] != (8, 3):
        raise InputError(f"`vertices`: expected shape (Q, 8, 3), got {v.shape}")
    if not np.all(np.isfinite(v)):
        raise InputError("`vertices`: contains NaN or infinity")
    if kind == "vf":
        a = _homogeneous(v[:, 0:1], v[:, 4:5])
        face = [1 + k for k in _FACE_ORDER]
        b = _homogeneous(v[:, face], v[:, [4 + k for k in face]])
    elif kind == "ee":
        a = _homogeneous(v[:, 0:2], v[:, 4:6])
        b = _homogeneous(v[:, 2:4], v[:, 6:8])
    else:
        raise InputError(f"`kind`: expected 'vf' or 'ee', got {kind!r}")
    return np.ascontiguousarray(a[:, None]), np.ascontiguousarray(b[:, None])


_SIDES = {"vf": (("point", ()), ("triangle", (1,))), "ee": (("curve", (1,)), ("curve", (1,)))}


def query_kernel_args(kind):
    """(kind code, corners, subdivision matrices) of both sides of a VF / EE query."""
    out = []
    for name, degree in _SIDES[kind]:
        out += [KIND_CODE[name], corner_indices(name, degree),
                np.ascontiguousarray(subdivision_matrices(name, degree))]
    return out


def batch(kind, vertices, *, method="ours", inclusion="obb", delta=DEFAULT_DELTA, t_max=1.0,
          margin=DEFAULT_MARGIN, time_margin=DEFAULT_TIME_MARGIN, max_iterations=1_000_000,
          max_nodes=1 << 21, queue="depth", obb_frames="interval", compiled_loop=False):
    """Run many VF (``kind="vf"``) or EE (``"ee"``) queries without building Patch objects.

    Args:
        vertices: (Q, 8, 3) in the query-file vertex order (see :func:`load_queries`).
        compiled_loop: loop over the queries inside one compiled call (fastest, but it
            compiles a second kernel on first use) instead of one call per query.

    Returns:
        (toi, status): (Q,) lower-bound times (inf when no contact) and status strings.
        A query stopped by a limit counts as a (conservative) contact.
    """
    _options(method, inclusion, delta, t_max, margin, time_margin, max_iterations, max_nodes,
             queue, obb_frames)
    a, b = query_primitives(kind, vertices)
    ka, ca, sa, kb, cb, sb = query_kernel_args(kind)
    q = a.shape[0]
    toi = np.empty(q)
    status = np.empty(q, np.int64)
    its = np.empty(q, np.int64)
    args = (METHODS[method], inclusion == "obb", float(delta), float(t_max), float(margin),
            float(time_margin), int(max_iterations), int(max_nodes), queue == "depth",
            obb_frames == "step")
    if compiled_loop:
        K.search_batch(ka, ca, sa, a, kb, cb, sb, b, *args, toi, status, its)
    else:
        pairs = np.zeros((1, 2), np.int64)
        points = np.empty((1, 9))
        info = np.zeros(4, np.int64)
        for i in range(q):
            K.search(ka, ca, sa, a[i], kb, cb, sb, b[i], pairs, *args, False, 0.0, 0.0, points,
                     info)
            status[i] = info[0]
            toi[i] = points[0, 0] if info[0] != K.NO_CONTACT else np.inf
    return toi, np.array([STATUS[int(s)] for s in status])


def _open(path):
    path = Path(path)
    if path.suffix == ".gz":
        return gzip.open(path, "rt")
    return open(path)


def load_queries(csv_path, ground_truth=None):
    """Read a CCD query file (Wang et al. 2021 / Belgrod et al. format; ``.csv`` or ``.csv.gz``).

    Every 8 lines are one query, one vertex per line as exact rationals
    ``xn,xd,yn,yd,zn,zd[,gt]``. Vertex order: VF ``v, f0, f1, f2`` at t0 then at t1;
    EE ``a0, a1, b0, b1`` at t0 then at t1.

    Args:
        csv_path: the query file.
        ground_truth: optional JSON file with one boolean per query; otherwise the 7th
            column is used.

    Returns:
        (vertices, truth): (Q, 8, 3) float64 (rounded to nearest; exact for these data
        sets) and (Q,) bool.
    """
    with _open(csv_path) as fh:
        rows = [line.strip().split(",") for line in fh if line.strip()]
    if len(rows) % 8:
        raise InputError(f"`{csv_path}`: {len(rows)} lines is not a multiple of 8")
    v = np.array([[float(Fraction(int(r[2 * k]), int(r[2 * k + 1]))) for k in range(3)]
                  for r in rows]).reshape(-1, 8, 3)
    if ground_truth is not None:
        with _open(ground_truth) as fh:
            truth = np.array(json.load(fh), dtype=bool)
    else:
        if len(rows[0]) < 7:
            raise InputError(f"`{csv_path}`: no ground-truth column; pass `ground_truth`")
        truth = np.array([int(rows[8 * k][6]) != 0 for k in range(len(rows) // 8)])
    if truth.shape != (v.shape[0],):
        raise InputError(f"`ground_truth`: {truth.shape[0]} values for {v.shape[0]} queries")
    return v, truth


DATA_ROOT = Path(__file__).resolve().parents[2] / "data" / "ccd-queries"


def dataset_files(root=DATA_ROOT):
    """Query files of the copied data sets: {(set, kind): [(csv, ground truth or None)]}."""
    root = Path(root)
    out = {}
    for csv in sorted((root / "handcrafted-wang2021").glob("*/*/*.csv.gz")):
        kind = "vf" if csv.parent.name == "vertex-face" else "ee"
        out.setdefault(("handcrafted", kind), []).append((csv, None))
    for csv in sorted((root / "simulation-scalable-ccd-sample").glob("*/queries/*.csv.gz")):
        stem = csv.name[: -len(".csv.gz")]
        kind = stem[-2:]
        gt = csv.parent.parent / "mma_bool" / f"{stem}_mma_bool.json"
        out.setdefault(("simulation", kind), []).append((csv, gt))
    return out


def load_dataset(name, kind, root=DATA_ROOT):
    """All queries of one copied set (``"handcrafted"`` / ``"simulation"``), kind vf / ee."""
    files = dataset_files(root).get((name, kind))
    if not files:
        raise InputError(f"no query files for set {name!r}, kind {kind!r} under {root}")
    parts = [load_queries(csv, gt) for csv, gt in files]
    return np.concatenate([p[0] for p in parts]), np.concatenate([p[1] for p in parts])
