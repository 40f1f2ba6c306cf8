"""First contact of two of MuJoCo's shapes under exact motions: the Python entry points.

:func:`geom_first_contact` validates the shapes and motions, writes each
motion as element rows in a frame at the first body's start (so bodies far
from the origin keep their accuracy), and calls the compiled
:func:`mjccd.geoms.kernel.pair_kernel`.  Pairs of an ellipsoid with a sphere,
a capsule's end or another ellipsoid go to the ellipsoid solver
(:func:`mjccd.first_contact`), and an ellipsoid against a half-space to
:func:`mjccd.plane_first_contact`; their answers are combined with the
kernel's on the same terms (the earliest first contact, its bracket).
"""
import threading

import numpy as np

from mjccd.ccd import Contact, first_contact, solve_motions
from mjccd.errors import InputError, InputTypeError
from mjccd.geoms import contact as ct
from mjccd.geoms import frames as fr
from mjccd.geoms import kernel as kn
from mjccd.geoms import poly as P
from mjccd.geoms import systems as sy
from mjccd.geoms.shapes import kind_and_size
from mjccd.motion import Ball, Chain, Fixed, Free, Hinge, LinearAffine, Motion, Rational, Rigid, Slide, Static
from mjccd.plane import Plane, plane_first_contact, solve_plane
from mjccd.quadric import Ellipsoid, quat_to_matrix

SLOTS = 16384  # polynomials of one pair query (a box against a box needs about 3,600)
STATUS_NAMES = {1: "separate", 0: "touching", -1: "overlapping"}
_local = threading.local()  # each thread's workspaces: concurrent calls never share one


def workspaces():
    """This thread's double and double-double workspaces and system store (made on first use): the last
    arguments of :func:`mjccd.geoms.kernel.pair_kernel`."""
    ws = getattr(_local, "workspaces", None)
    if ws is None:
        ws = _local.workspaces = (*P.workspace(SLOTS, P.MAX_DEGREE), *P.workspace(SLOTS, P.MAX_DEGREE, True),
                                  *sy.new_store(1024, 8192))
    return ws


def _pose_row(p0, q0, p1, q1):
    row = np.zeros(fr.ELEMENT_FIELDS)
    row[0] = fr.POSE
    row[1:4], row[4:8], row[8:11], row[11:15] = p0, q0, p1, q1
    return row


def _element_rows(element):
    if type(element) is Fixed:
        return _pose_row(element.position, element.quaternion, element.position, element.quaternion)
    if isinstance(element, Free):
        return _pose_row(element.position0, element.quaternion0, element.position1, element.quaternion1)
    if type(element) is Ball:
        zero = np.zeros(3)
        return _pose_row(zero, element.quaternion0, zero, element.quaternion1)
    row = np.zeros(fr.ELEMENT_FIELDS)
    if type(element) is Hinge:
        row[0] = fr.HINGE
        row[1:4] = element.axis
        row[4], row[5] = np.tan(element.angle0 / 2), np.tan(element.angle1 / 2)
        return row
    if type(element) is Slide:
        row[0] = fr.SLIDE
        row[1:4] = element.axis
        row[4], row[5] = element.displacement0, element.displacement1
        return row
    raise InputTypeError(f"not a chain element: {element!r}")


def _two_poses(motion):
    """(p0, q0, p1, q1) of a Static or Rigid motion (validated when it was made); None for any other."""
    kind = type(motion)
    if kind is Rigid:
        return motion.position0, motion.quaternion0, motion.position1, motion.quaternion1
    if kind is Static:
        return motion.position, motion.quaternion, motion.position, motion.quaternion
    return None


def motion_rows(motion, field="motion"):
    """The element rows of a motion the geom solvers take: Static, Rigid or Chain."""
    poses = _two_poses(motion)
    if poses is not None:
        return _pose_row(*poses)[None, :]
    if type(motion) is Chain:
        return np.array([_element_rows(e) for e in motion.elements])
    if isinstance(motion, (Rational, LinearAffine)):
        raise InputError(f"{field}: the compiled geom solvers take Static, Rigid and Chain motions; a "
                         f"{type(motion).__name__} motion goes to geom_first_contact and geom_collision_intervals "
                         f"(the composite quadric solver)")
    if isinstance(motion, Motion):
        raise InputError(f"{field}: a {type(motion).__name__} motion does not keep MuJoCo's shapes rigid; "
                         f"the geom solvers take Static, Rigid and Chain motions")
    raise InputTypeError(f"{field}: expected a motion (Static, Rigid, Chain), got {type(motion).__name__}")


def shifted_rows(rows, origin):
    """The rows of the same motion seen from ``origin`` (the root's position shifted; exact for nearby bodies)."""
    if rows[0, 0] == fr.POSE:
        out = rows.copy()
        out[0, 1:4] -= origin
        out[0, 8:11] -= origin
        return out
    lead = _pose_row(-origin, [1.0, 0.0, 0.0, 0.0], -origin, [1.0, 0.0, 0.0, 0.0])
    return np.vstack([lead[None, :], rows])


def _check(shape, motion, field):
    kind, size = kind_and_size(shape, f"{field}.shape")
    rows = motion_rows(motion, f"{field}.motion")
    if kind == sy.PLANE and not (rows.shape[0] == 1 and np.array_equal(rows[0, 1:8], rows[0, 8:15])):
        raise InputError(f"{field}.motion: a plane (HalfSpace) must be static")
    return kind, size, rows


def _ellipsoid_shape(kind, size):
    """The shape as the ellipsoid solver takes it (a sphere is an ellipsoid with equal radii)."""
    return Ellipsoid(size if kind == sy.ELLIPSOID else [size[0]] * 3)


def _end_ball_motion(motion, h):
    """The exact motion of the centre of a capsule's end ball (the capsule's motion, then (0, 0, h))."""
    end = Fixed([0.0, 0.0, h])
    if type(motion) is Static:
        return Chain([Fixed(motion.position, motion.quaternion), end])
    if type(motion) is Rigid:
        return Chain([Free(motion.position0, motion.quaternion0, motion.position1, motion.quaternion1), end])
    return Chain(list(motion.elements) + [end])


def _plane_of(motion):
    """The world plane (outward normal, offset) of a HalfSpace at a static pose."""
    R = quat_to_matrix(np.asarray(motion.quaternion, float))
    n = R[:, 2]
    return Plane(n, float(n @ np.asarray(motion.position, float)))


def _from_contact(contact, names, flip):
    """A Contact of the ellipsoid or plane solver as a geom answer (its normal turned when the shapes were)."""
    if contact is None:
        return None
    normal = None if contact.normal is None else (-np.asarray(contact.normal) if flip else contact.normal)
    return contact._replace(normal=normal, elements=names if contact.time > 0.0 or
                            contact.status_at_start == "separate" else None)


def _other_solver(shape_a, motion_a, shape_b, motion_b, ka, sa, kb, sb, t_max):
    """The contacts the ellipsoid and plane solvers owe for this pair (a list)."""
    flip = ka > kb
    if flip:
        shape_a, motion_a, shape_b, motion_b = shape_b, motion_b, shape_a, motion_a
        ka, sa, kb, sb = kb, sb, ka, sa
    surface = ("surface", "surface")
    if kb == sy.PLANE:  # an ellipsoid above a plane
        c = plane_first_contact(_ellipsoid_shape(ka, sa), motion_a, _plane_of(motion_b), t_max=t_max)
        names = ("surface", "plane")
        return [_from_contact(c, names[::-1] if flip else names, flip)]
    if ka == sy.CAPSULE:  # the capsule's end balls against the ellipsoid
        out = []
        for h, cap in ((sa[1], "cap +z"), (-sa[1], "cap -z")):
            c = first_contact(Ellipsoid([sa[0]] * 3), _end_ball_motion(motion_a, h), _ellipsoid_shape(kb, sb),
                              motion_b, t_max=t_max)
            names = (cap, "surface")
            out.append(_from_contact(c, names[::-1] if flip else names, flip))
        return out
    c = first_contact(_ellipsoid_shape(ka, sa), motion_a, _ellipsoid_shape(kb, sb), motion_b, t_max=t_max)
    return [_from_contact(c, surface, flip)]


def _earliest(contacts):
    """One answer from several for the same pair: the worst status at the start, else the earliest first
    contact, uncertain when an uncertain bracket begins before the earliest certified contact."""
    rank = {"overlapping": 0, "touching": 1, "separate": 2}
    status = min((c.status_at_start for c in contacts if c is not None), key=rank.get, default="separate")
    if status != "separate":
        return Contact(0.0, None, None, status)
    found = [c for c in contacts if c is not None]
    if not found:
        return None
    lo = min(c.bracket[0] if c.certainty == "uncertain" else c.time for c in found)
    hi = min(c.bracket[1] if c.certainty == "uncertain" else c.time for c in found)
    first = min(found, key=lambda c: (c.time, c.certainty != "certified"))
    if all(c.certainty == "certified" or c.bracket[0] >= first.time for c in found) and first.certainty == "certified":
        return first
    return first._replace(time=lo, certainty="uncertain", bracket=(lo, hi))


_POSE_KIND = np.array([float(fr.POSE)])


def _pose_rows_from(poses, origin):
    """The one element row of a two-pose motion seen from ``origin``: as ``shifted_rows(motion_rows(m),
    origin)``, bit for bit, in one allocation (the common case of a pair query: no plane, no chain)."""
    p0, q0, p1, q1 = poses
    return np.concatenate((_POSE_KIND, p0 - origin, q0, p1 - origin, q1))[None, :]


def _static_unless_body(kind, motion):
    """True for a body, or a plane under a Static motion (a plane's other motions are checked the long way)."""
    return kind != sy.PLANE or type(motion) is Static


def _rows_and_origin(shape_a, motion_a, shape_b, motion_b):
    """(ka, sa, rows_a, kb, sb, rows_b, origin) of a pair: both motions' element rows seen from ``origin`` (the
    start of the first body that is not a plane), every field validated.  Two Static or Rigid motions (a plane
    Static) take the short way, one row each."""
    ka, sa = kind_and_size(shape_a, "a.shape")
    kb, sb = kind_and_size(shape_b, "b.shape")
    poses_a, poses_b = _two_poses(motion_a), _two_poses(motion_b)
    if poses_a is not None and poses_b is not None and _static_unless_body(ka, motion_a) and \
            _static_unless_body(kb, motion_b) and not ka == kb == sy.PLANE:
        origin = poses_b[0] if ka == sy.PLANE else poses_a[0]
        return ka, sa, _pose_rows_from(poses_a, origin), kb, sb, _pose_rows_from(poses_b, origin), origin
    ka, sa, ra = _check(shape_a, motion_a, "a")
    kb, sb, rb = _check(shape_b, motion_b, "b")
    if ka == sy.PLANE and kb == sy.PLANE:
        raise InputError("b.shape: two planes are not a pair MuJoCo collides")
    origin = ra[0, 1:4].copy() if ka != sy.PLANE else rb[0, 1:4].copy()
    return ka, sa, shifted_rows(ra, origin), kb, sb, shifted_rows(rb, origin), origin


def solve_geoms(shape_a, motion_a, shape_b, motion_b, *, t_max=1.0):
    """The kernel's answer array (see :func:`mjccd.geoms.kernel.pair_kernel`) for a validated pair."""
    ka, sa, rows_a, kb, sb, rows_b, origin = _rows_and_origin(shape_a, motion_a, shape_b, motion_b)
    out = np.empty(kn.OUT)
    kn.pair_kernel(ka, sa, rows_a, kb, sb, rows_b, float(t_max), *workspaces(), out)
    if out[kn.FAILED] == kn.OVERFLOW:
        raise RuntimeError(f"{sy.KIND_NAMES[ka]}-{sy.KIND_NAMES[kb]}: the pair's polynomials outgrew the solver's "
                           f"workspace (a chain too deep for its degree limit {P.MAX_DEGREE})")
    out[kn.POINT:kn.POINT + 3] += origin
    return out, (ka, sa, kb, sb)


def _kernel_contact(out, ka, kb):
    """The kernel's answer as a Contact (None: proven free of contact)."""
    status = STATUS_NAMES[int(out[kn.STATUS])]
    if out[kn.STATUS] != 1:
        return Contact(0.0, None, None, status)
    if out[kn.LO] < 0.0:
        return None
    elements = (ct.element_name(ka, int(out[kn.ELEM_A])), ct.element_name(kb, int(out[kn.ELEM_B])))
    point, normal = out[kn.POINT:kn.POINT + 3].copy(), out[kn.NORMAL:kn.NORMAL + 3].copy()
    if out[kn.CERTIFIED] > 0.0:
        return Contact(float(out[kn.TIME]), point, normal, status, elements=elements)
    return Contact(float(out[kn.LO]), point, normal, status, "uncertain", (float(out[kn.LO]), float(out[kn.HI])),
                   elements=elements)


def _composite_models(shape_a, shape_b):
    """The two shapes as composite quadric models (:mod:`mjccd.geoms.cqm`), for a pair under a
    :class:`mjccd.Rational` or :class:`mjccd.LinearAffine` motion (exact elimination; seconds, not
    microseconds)."""
    from mjccd.geoms import cqm
    models = []
    for shape, field in ((shape_a, "a"), (shape_b, "b")):
        kind, size = kind_and_size(shape, f"{field}.shape")
        if kind == sy.PLANE:
            raise InputError(f"{field}.shape: a plane (HalfSpace) is not taken beside a Rational or LinearAffine "
                             f"motion (the composite quadric solver needs bounded shapes)")
        models.append({sy.SPHERE: lambda: cqm.ellipsoid_model(size[0], size[0], size[0]),
                       sy.CAPSULE: lambda: cqm.capsule(size[0], size[1]),
                       sy.CYLINDER: lambda: cqm.capped_cylinder(size[0], size[0], size[1]),
                       sy.BOX: lambda: cqm.box(*size),
                       sy.ELLIPSOID: lambda: cqm.ellipsoid_model(*size)}[kind]())
    return models


def _composite(motion_a, motion_b):
    """True for a pair the composite quadric solver takes (a Rational or LinearAffine motion)."""
    return isinstance(motion_a, (Rational, LinearAffine)) or isinstance(motion_b, (Rational, LinearAffine))


def geom_first_contact(shape_a, motion_a, shape_b, motion_b, *, t_max=1.0):
    """First contact of two moving MuJoCo shapes over [0, t_max] as a :class:`mjccd.Contact`, or None.

    ``shape_a``, ``shape_b``: :class:`Sphere`, :class:`Capsule`,
    :class:`Cylinder`, :class:`Box`, :class:`mjccd.Ellipsoid` or
    :class:`HalfSpace`; motions: :class:`mjccd.Static`, :class:`mjccd.Rigid`
    or :class:`mjccd.Chain` (the compiled kernel, microseconds), or
    :class:`mjccd.Rational` and :class:`mjccd.LinearAffine` (the composite
    quadric solver, :mod:`mjccd.geoms.cqm`: exact, seconds; no planes).  The
    contact carries the touching ``elements`` of each shape; an uncertain
    answer carries the bracket that holds every possible first contact.
    """
    if _composite(motion_a, motion_b):
        from mjccd.geoms.cqm import cqm_first_contact
        model_a, model_b = _composite_models(shape_a, shape_b)
        return cqm_first_contact(model_a, motion_a, model_b, motion_b, t_max=t_max)
    out, (ka, sa, kb, sb) = solve_geoms(shape_a, motion_a, shape_b, motion_b, t_max=t_max)
    if out[kn.FAILED] == 0.0:
        return _kernel_contact(out, ka, kb)
    contacts = _other_solver(shape_a, motion_a, shape_b, motion_b, ka, sa, kb, sb, t_max)
    if out[kn.FAILED] == kn.PARTIAL:
        contacts.append(_kernel_contact(out, ka, kb))
    return _earliest(contacts)


def _other_intervals(shape_a, motion_a, shape_b, motion_b, ka, sa, kb, sb):
    """(intervals, certified) the ellipsoid and plane solvers owe for this pair: lists of (t_in, t_out)."""
    if ka > kb:
        shape_a, motion_a, shape_b, motion_b = shape_b, motion_b, shape_a, motion_a
        ka, sa, kb, sb = kb, sb, ka, sa
    if kb == sy.PLANE:
        sol = solve_plane(_ellipsoid_shape(ka, sa), motion_a, _plane_of(motion_b))
        return [tuple(map(float, iv)) for iv in sol.intervals], bool(sol.certified)
    if ka == sy.CAPSULE:
        out, ok = [], True
        for h in (sa[1], -sa[1]):
            sol = solve_motions(Ellipsoid([sa[0]] * 3), _end_ball_motion(motion_a, h), _ellipsoid_shape(kb, sb),
                                motion_b)
            out += [tuple(map(float, iv)) for iv in sol.intervals]
            ok = ok and bool(sol.certified)
        return out, ok
    sol = solve_motions(_ellipsoid_shape(ka, sa), motion_a, _ellipsoid_shape(kb, sb), motion_b)
    return [tuple(map(float, iv)) for iv in sol.intervals], bool(sol.certified)


def _union(intervals):
    """The union of closed intervals, as a sorted list of disjoint ones (touching within 1e-9 joined)."""
    out = []
    for lo, hi in sorted(intervals):
        if out and lo <= out[-1][1] + kn.TIME_TOL:
            out[-1] = (out[-1][0], max(out[-1][1], hi))
        else:
            out.append((lo, hi))
    return out


def geom_collision_intervals(shape_a, motion_a, shape_b, motion_b):
    """Every interval of normalised time in [0, 1] in which the two shapes touch or overlap.

    Returns (intervals, certified): a list of (t_in, t_out) and whether
    every end is proven within 1e-9 (otherwise an interval may be a graze
    that does not happen, or ends may be wider apart).  Motions as
    :func:`geom_first_contact` takes them: a Rational or LinearAffine one
    goes to :func:`mjccd.geoms.cqm.cqm_collision_intervals` (seconds).
    """
    if _composite(motion_a, motion_b):
        from mjccd.geoms.cqm import cqm_collision_intervals
        model_a, model_b = _composite_models(shape_a, shape_b)
        return cqm_collision_intervals(model_a, motion_a, model_b, motion_b)
    ka, sa, rows_a, kb, sb, rows_b, _ = _rows_and_origin(shape_a, motion_a, shape_b, motion_b)
    out = np.empty((kn.MAX_RUNS, 7))
    count, certified, _, code = kn.pair_runs(ka, sa, rows_a, kb, sb, rows_b, 1.0, *workspaces(), out)
    if code < 0:
        raise RuntimeError(f"{sy.KIND_NAMES[ka]}-{sy.KIND_NAMES[kb]}: the pair's polynomials outgrew the solver's "
                           f"workspace")
    intervals = [(float(out[k, 0]), float(out[k, 1])) for k in range(count)]
    if code != sy.HANDLED:
        other, ok = _other_intervals(shape_a, motion_a, shape_b, motion_b, ka, sa, kb, sb)
        intervals = _union(intervals + other) if code == sy.PARTIAL else _union(other)
        certified = (certified or code == 0) and ok
    return intervals, bool(certified)
