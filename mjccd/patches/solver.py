"""Public patch CCD: earliest contact, contact manifolds, and the traditional baseline.

``first_contact`` runs the time-dependent inclusion method of Chen et al. 2024 (Alg. 2):
only the parameters are subdivided and each candidate's time interval comes from
IntersectionPeriod. ``method="trad"`` runs the traditional inclusion method (Alg. 1:
swept boxes, time bisected as a fifth dimension) for comparison.
"""
from dataclasses import dataclass
import math

import numpy as np

from mjccd.errors import InputError, InputTypeError

from . import _kernels as K
from .primitives import KIND_CODE, Patch, corner_indices, subdivision_matrices

METHODS = {"ours": K.OURS, "trad": K.TRAD}
INCLUSIONS = ("obb", "aabb")
QUEUES = ("depth", "time")
OBB_FRAMES = ("interval", "step")
STATUS = {K.NO_CONTACT: "no_contact", K.CONTACT: "converged",
          K.MAX_ITERATIONS: "max_iterations", K.MAX_NODES: "max_nodes"}

DEFAULT_DELTA = 1e-6
DEFAULT_MARGIN = 1e-6
DEFAULT_TIME_MARGIN = 1e-6


@dataclass(frozen=True)
class PatchContact:
    """Earliest contact found by the patch solver.

    Attributes:
        toi: time of impact in [0, t_max]; a lower bound on the true first contact
            (the start of the accepted candidate's time interval).
        params: (u1, v1, u2, v2) at the accepted sub-patches (centre, or centroid for
            triangles); unused parameters are 0.
        point: (3,) world point S_a(u1, v1, toi).
        pair: (i, j) indices of the primitives in the two input sets.
        status: ``"converged"``, or ``"max_iterations"`` / ``"max_nodes"`` when the search
            stopped early; ``toi`` is then only the lower bound reached so far and
            ``params``/``point`` are NaN.
        iterations: nodes popped from the queue.
    """

    toi: float
    params: tuple
    point: np.ndarray
    pair: tuple
    status: str
    iterations: int


@dataclass(frozen=True)
class SearchStats:
    """Bookkeeping of one search: status, nodes popped and the largest queue size."""

    status: str
    iterations: int
    peak_queue: int


def _as_set(value, field):
    items = [value] if isinstance(value, Patch) else list(value)
    if not items:
        raise InputTypeError(f"`{field}`: expected a Patch or a non-empty list of patches")
    for k, p in enumerate(items):
        if not isinstance(p, Patch):
            raise InputTypeError(f"`{field}[{k}]`: expected a Patch, got {type(p).__name__}")
        if (p.kind, p.degree) != (items[0].kind, items[0].degree):
            raise InputError(
                f"`{field}[{k}]`: all primitives of one side must share kind and degree, "
                f"got {p.kind}{p.degree} after {items[0].kind}{items[0].degree}")
    return items


class _Side:
    """Kernel-ready arrays for one side: kind code, corners, subdivision matrices, roots."""

    def __init__(self, items):
        first = items[0]
        self.items = items
        self.kind = KIND_CODE[first.kind]
        self.corners = corner_indices(first.kind, first.degree)
        self.sub = np.ascontiguousarray(subdivision_matrices(first.kind, first.degree))
        self.roots = np.ascontiguousarray(np.stack([p.homogeneous() for p in items]))


def _options(method, inclusion, delta, t_max, margin, time_margin, max_iterations,
             max_nodes, queue="depth", obb_frames="interval"):
    if obb_frames not in OBB_FRAMES:
        raise InputError(f"`obb_frames`: expected 'interval' or 'step', got {obb_frames!r}")
    if queue not in QUEUES:
        raise InputError(f"`queue`: expected 'depth' or 'time', got {queue!r}")
    if method not in METHODS:
        raise InputError(f"`method`: expected one of {sorted(METHODS)}, got {method!r}")
    if inclusion not in INCLUSIONS:
        raise InputError(f"`inclusion`: expected 'obb' or 'aabb', got {inclusion!r}")
    for name, val in (("delta", delta), ("t_max", t_max)):
        if not (isinstance(val, (int, float)) and math.isfinite(val) and val > 0):
            raise InputError(f"`{name}`: expected a positive number, got {val!r}")
    if t_max > 1.0:
        raise InputError(f"`t_max`: the motion is defined on [0, 1], got {t_max!r}")
    for name, val in (("margin", margin), ("time_margin", time_margin)):
        if not (isinstance(val, (int, float)) and math.isfinite(val) and val >= 0):
            raise InputError(f"`{name}`: expected a non-negative number, got {val!r}")
    for name, val in (("max_iterations", max_iterations), ("max_nodes", max_nodes)):
        if not (isinstance(val, (int, np.integer)) and val > 0):
            raise InputError(f"`{name}`: expected a positive integer, got {val!r}")


def _run(a, b, *, method, inclusion, delta, t_max, margin, time_margin, max_iterations,
         max_nodes, queue, obb_frames, pairs, manifold, simultaneity, separation, max_points):
    _options(method, inclusion, delta, t_max, margin, time_margin, max_iterations, max_nodes,
             queue, obb_frames)
    sa, sb = _Side(_as_set(a, "a")), _Side(_as_set(b, "b"))
    if pairs is None:
        pairs = np.array([(i, j) for i in range(len(sa.items)) for j in range(len(sb.items))],
                         dtype=np.int64)
    else:
        pairs = np.asarray(pairs, dtype=np.int64).reshape(-1, 2)
        if (pairs < 0).any() or (pairs[:, 0] >= len(sa.items)).any() or (
                pairs[:, 1] >= len(sb.items)).any():
            raise InputError("`pairs`: index out of range")
    points = np.full((max_points, 9), np.nan)
    info = np.zeros(4, dtype=np.int64)
    K.search(sa.kind, sa.corners, sa.sub, sa.roots, sb.kind, sb.corners, sb.sub, sb.roots,
             np.ascontiguousarray(pairs), METHODS[method], inclusion == "obb", float(delta),
             float(t_max), float(margin), float(time_margin), int(max_iterations),
             int(max_nodes), queue == "depth", obb_frames == "step", manifold,
             float(simultaneity), float(separation), points, info)
    return sa, sb, pairs, points, info


def _contact(sa, sb, pairs, row, status, iterations):
    if status != "converged":
        nan = float("nan")
        return PatchContact(float(row[0]), (nan,) * 4, np.full(3, np.nan), (-1, -1), status,
                            iterations)
    i, j = pairs[int(row[8])]
    pa = sa.items[i]
    toi = float(row[0])
    params = tuple(float(x) for x in row[1:5])
    point = pa.evaluate(params[0], params[1], toi)
    return PatchContact(toi, params, point, (int(i), int(j)), status, iterations)


def first_contact(a, b, *, method="ours", inclusion="obb", delta=DEFAULT_DELTA, t_max=1.0,
                  margin=DEFAULT_MARGIN, time_margin=DEFAULT_TIME_MARGIN,
                  max_iterations=10_000_000, max_nodes=1 << 21, queue="depth",
                  obb_frames="interval", pairs=None):
    """Earliest contact between two moving primitives (or two sets of them), or None.

    Args:
        a, b: a :class:`Patch` or a list of patches of one kind and degree each.
        method: ``"ours"`` (time-dependent inclusions) or ``"trad"`` (swept boxes, Alg. 1).
        inclusion: ``"obb"`` (15 separating axes) or ``"aabb"`` (3 world axes).
        delta: acceptance width in parameter space (and in time for ``"trad"``).
        t_max: end of the queried time range, in (0, 1].
        margin: relative shift of every contour line (times the largest coordinate of its
            control point) that widens the inclusions against rounding.
        time_margin: widening of each candidate time interval while it is tested.
        max_iterations, max_nodes: search limits; reaching one is reported in ``status``.
        queue: ``"depth"`` (default): candidates whose lower time ends lie within delta/16
            are ties and the smaller one goes first; ``"time"``: the lower end alone, as
            written in the paper's Alg. 1 and 2 (face contacts then grow the queue).
        obb_frames: where a sub-patch's OBB axes come from: ``"interval"`` (default): its
            shape at the lower end of the time interval being refined; ``"step"``: its
            shape at t = 0, kept for the whole step (the paper's rule, Eq. 19-21). Both
            are conservative; they differ only in how tight the boxes are.
        pairs: optional (P, 2) list of (i, j) primitive pairs to test (default: all).

    Returns:
        :class:`PatchContact`, or None when no contact happens in [0, t_max].
    """
    sa, sb, pairs, points, info = _run(
        a, b, method=method, inclusion=inclusion, delta=delta, t_max=t_max, margin=margin,
        time_margin=time_margin, max_iterations=max_iterations, max_nodes=max_nodes,
        queue=queue, obb_frames=obb_frames, pairs=pairs, manifold=False, simultaneity=0.0,
        separation=0.0, max_points=1)
    status = STATUS[int(info[0])]
    if status == "no_contact":
        return None
    return _contact(sa, sb, pairs, points[0], status, int(info[1]))


def contact_manifold(a, b, *, simultaneity, separation, max_points=256, method="ours",
                     inclusion="obb", delta=DEFAULT_DELTA, t_max=1.0, margin=DEFAULT_MARGIN,
                     time_margin=DEFAULT_TIME_MARGIN, max_iterations=10_000_000,
                     max_nodes=1 << 21, queue="depth", obb_frames="interval", pairs=None):
    """All distinct contact points within ``simultaneity`` of the earliest contact time.

    Points are at least ``separation`` apart (world distance between the side-A points);
    the search continues after the first accepted candidate, skips candidates whose A part
    lies inside the ball around a point already found, and stops once the queue holds only
    candidates later than ``toi + simultaneity`` (paper §5.3).

    Returns:
        (list of :class:`PatchContact` in discovery order, :class:`SearchStats`).
    """
    for name, val in (("simultaneity", simultaneity), ("separation", separation)):
        if not (isinstance(val, (int, float)) and math.isfinite(val) and val >= 0):
            raise InputError(f"`{name}`: expected a non-negative number, got {val!r}")
    if not (isinstance(max_points, (int, np.integer)) and max_points > 0):
        raise InputError(f"`max_points`: expected a positive integer, got {max_points!r}")
    sa, sb, pairs, points, info = _run(
        a, b, method=method, inclusion=inclusion, delta=delta, t_max=t_max, margin=margin,
        time_margin=time_margin, max_iterations=max_iterations, max_nodes=max_nodes,
        queue=queue, obb_frames=obb_frames, pairs=pairs, manifold=True,
        simultaneity=simultaneity, separation=separation, max_points=int(max_points))
    stats = SearchStats(STATUS[int(info[0])], int(info[1]), int(info[3]))
    found = int(info[2])
    contacts = [_contact(sa, sb, pairs, points[k], "converged", int(info[1]))
                for k in range(found)]
    return contacts, stats
