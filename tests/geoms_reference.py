"""Ground truth for the first contact of two MuJoCo primitive geoms under rigid motion, graded by MuJoCo itself.

    python tests/geoms_reference.py --seed 7 --per-pair 3 -o CASES.json --expected EXPECTED.json
    python tests/geoms_reference.py --seed 11 --total 150 -o tests/data/geoms_heldout_s11.json \\
        --expected tests/data/geoms_heldout_s11_expected.json
    python tests/geoms_reference.py --reproduce CASES.json EXPECTED.json   # recompute a stored set, compare

This file does not import ``mjccd``: it is an independent reference for the geom solver.

Cases (:func:`make_cases`) are random pairs of sphere, capsule, cylinder, box and ellipsoid (the 15 unordered
pairs) and each of the five against a static plane, in the JSON format of ``geoms_public.json``: each body
has a ``"shape"`` (``{"type": "capsule", "radius": r, "half_length": h}`` and so on) and a ``"motion"``,
static or rigid.  Rigid motion: centre ``p(t) = (1-t) p0 + t p1``, quaternion ``q(t) = (1-t) q0 + t q1'``
normalised, ``q1' = ±q1`` with ``q0·q1' >= 0``, ``t`` in [0, 1].  Capsule and cylinder axes are the local z
axis; a plane is the solid half-space z <= 0 of its (static) frame, as MuJoCo collides it.

The answer (:func:`reference`) is read from MuJoCo's own signed distance ``mujoco.mj_geomDistance`` (at
``ccd_tolerance = 1e-12``) along the motion: a 4001-point scan of [0, 1]; every local minimum of the scan
that could hide a contact (or decides a near miss) refined by golden section; the first sign change
bisected to 1e-13.  The contact point is the midpoint of MuJoCo's closest-point segment (``fromto``) there.

MuJoCo's distance is not trusted blindly (:class:`Grader`).  Its GJK path (every pair with a cylinder or an
ellipsoid except sphere-cylinder and the planes, and box-box) returns, at scattered configurations,
distances that are provably wrong (too small by up to 1e-2 for ellipsoids, with closest points off the
surfaces) and signs that are wrong near contact.  So every sign the search uses is proven by the shapes'
own geometry, posed by this file's quaternion arithmetic: a positive distance by a separating plane (the
support functions along MuJoCo's direction, a surface normal at one of its points or a box or cylinder
axis leave a gap), a distance <= 0 by a point inside both shapes (the midpoint of MuJoCo's segment), a
plane pair by the exact half-space distance; a value the geometry contradicts is set aside and taken a
hair (1e-11 of time) away.  The proven bracket of the first crossing must be at most 1e-8 wide; MuJoCo's
own sign change is then bisected inside it.

Ill-posed cases are left out (``reference`` returns None): a start within 1e-9 of contact (or whose sign
is not proven); a first crossing that is nearly tangent (the distance does not go below -1e-7 x size
within 1e-6 of time after it), whose proven bracket is wider than 1e-8, or whose proven sign does not
hold at t* -/+ 1e-7 (and 3 and 10 times that); an approach without contact closer than 1e-4 x size; a
contact point MuJoCo does not hold steady (its points at t* + 1e-9, t* + 1e-8 and t* - 1e-7 within
1e-6 x size, after the motion in between) or whose segment's ends are off the surfaces by more than
1e-9 x size.  "size" is the larger of the two shapes' sizes as ``check_geoms.py`` measures them.

Second references (:func:`crosscheck`): sphere-sphere and sphere-plane have closed forms, solved with
mpmath at 50 digits (first contact within 1e-9, point within 1e-9 x size, near misses' clearance); for
every pair the contact point is checked against both analytic surfaces.  The generator never emits a
case that disagrees (it reports it and draws again).
"""
import argparse
import json
import math
import re
import sys
import time

import mujoco
import numpy as np
from mpmath import mp, mpf

SOLIDS = ("sphere", "capsule", "cylinder", "box", "ellipsoid")
KINDS = ("translate", "rotate", "spin")
PAIRS = ([(SOLIDS[i], SOLIDS[j]) for i in range(len(SOLIDS)) for j in range(i, len(SOLIDS))]
         + [(s, "plane") for s in SOLIDS])
# scenario of the k-th case overall: 6 of 9 collide, 2 pass close by, 1 never comes near
SCENARIOS = ("collide", "collide", "near", "collide", "collide", "far", "collide", "collide", "near")

N_SCAN = 4001               # scan points over [0, 1]
CCD_TOLERANCE = 1e-12       # model.opt.ccd_tolerance for mj_geomDistance's GJK/EPA pairs
DISTMAX = 100.0             # mj_geomDistance's cut-off: far above any distance in these scenes
T_TOL = 1e-13               # width of the bisected crossing bracket
START_EPS = 1e-9            # |distance at t=0| below this: ill-posed start
TANGENT_DT, TANGENT_DEPTH = 1e-6, 1e-7     # within TANGENT_DT after the crossing, below -TANGENT_DEPTH x size
SIGN_WINDOW = 1e-7          # MuJoCo's sign must be right at t* -/+ this (and further out)
CERT_WIDTH = 1e-8           # the crossing's bracket proven by the geometry must be at most this wide
POINT_STEADY = 1e-6         # MuJoCo's contact point at t*+1e-9, t*+1e-8 and t*-1e-7 within this x size
CLEAR_MIN = 1e-4            # closest approach without contact must be at least this x size
NEAR_RANGE = (1e-3, 0.3)    # clearance of the "near" scenario, x size
FAR_MIN = 0.1               # a "far" case clears by at least this x size
CLOSED_FORM_TOL = 1e-9      # sphere-sphere and sphere-plane: MuJoCo's answer against the 50-digit one
SURFACE_TOL = 1e-8          # the contact point within this x size of both analytic surfaces
GOLDEN = (math.sqrt(5.0) - 1.0) / 2.0


# ------------------------------------------------------------------ shapes and motions
def shape_size(shape):
    """The size check_geoms.py scores points with: largest extent from the centre (0 for a plane)."""
    t = shape["type"]
    if t == "plane":
        return 0.0
    if t == "sphere":
        return float(shape["radius"])
    if t in ("capsule", "cylinder"):
        return float(shape["radius"] + shape["half_length"])
    if t == "box":
        return float(np.linalg.norm(shape["half_sizes"]))
    return float(max(shape["radii"]))


def case_size(case):
    return max(shape_size(case["a"]["shape"]), shape_size(case["b"]["shape"]))


def bounding_radius(shape):
    """Radius of the smallest centred ball holding the shape."""
    t = shape["type"]
    if t == "sphere":
        return shape["radius"]
    if t == "capsule":
        return shape["radius"] + shape["half_length"]
    if t == "cylinder":
        return math.hypot(shape["radius"], shape["half_length"])
    if t == "box":
        return float(np.linalg.norm(shape["half_sizes"]))
    return max(shape["radii"])


def inner_radius(shape):
    """Radius of the largest centred ball inside the shape."""
    t = shape["type"]
    if t == "sphere":
        return shape["radius"]
    if t == "capsule":
        return shape["radius"]
    if t == "cylinder":
        return min(shape["radius"], shape["half_length"])
    if t == "box":
        return min(shape["half_sizes"])
    return min(shape["radii"])


def _unit(q):
    q = [float(x) for x in q]
    n = math.hypot(*q)
    return np.array([x / n for x in q])


def motion_rows(motion):
    """(p0, q0, p1, q1') as float arrays: unit quaternions, q1' signed so that q0·q1' >= 0."""
    if motion["type"] == "static":
        p = np.array(motion["position"], dtype=float)
        q = _unit(motion["quaternion"])
        return p, q, p, q
    if motion["type"] != "rigid":
        raise ValueError(f"motion.type: expected 'static' or 'rigid', got {motion['type']!r}")
    s, e = motion["start"], motion["end"]
    q0, q1 = _unit(s["quaternion"]), _unit(e["quaternion"])
    if float(q0 @ q1) < 0.0:
        q1 = -q1
    return np.array(s["position"], dtype=float), q0, np.array(e["position"], dtype=float), q1


def pose_at(rows, t):
    """Centre and unit quaternion at time t of a motion given by :func:`motion_rows`."""
    p0, q0, p1, q1 = rows
    q = (1.0 - t) * q0 + t * q1
    return (1.0 - t) * p0 + t * p1, q / math.sqrt(float(q @ q))


def quat_mat(q):
    w, x, y, z = q
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
                     [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
                     [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]])


def quat_mul(a, b):
    w1, x1, y1, z1 = a
    w2, x2, y2, z2 = b
    return np.array([w1 * w2 - x1 * x2 - y1 * y2 - z1 * z2, w1 * x2 + x1 * w2 + y1 * z2 - z1 * y2,
                     w1 * y2 - x1 * z2 + y1 * w2 + z1 * x2, w1 * z2 + x1 * y2 - y1 * x2 + z1 * w2])


def axis_angle_quat(axis, angle):
    axis = np.asarray(axis, dtype=float) / np.linalg.norm(axis)
    return np.concatenate([[math.cos(angle / 2)], math.sin(angle / 2) * axis])


def local_sdf(shape, x):
    """Signed distance of the local point x to the shape (exact; first order for an ellipsoid, whose sign is
    exact)."""
    t = shape["type"]
    if t == "plane":
        return float(x[2])
    if t == "sphere":
        return math.sqrt(float(x @ x)) - shape["radius"]
    if t == "capsule":
        z = min(max(x[2], -shape["half_length"]), shape["half_length"])
        return math.sqrt(x[0] * x[0] + x[1] * x[1] + (x[2] - z) ** 2) - shape["radius"]
    if t == "cylinder":
        q0, q1 = math.hypot(x[0], x[1]) - shape["radius"], abs(x[2]) - shape["half_length"]
        return min(max(q0, q1), 0.0) + math.hypot(max(q0, 0.0), max(q1, 0.0))
    if t == "box":
        q = np.abs(x) - shape["_hs"]
        return float(np.linalg.norm(np.maximum(q, 0.0))) + min(float(q.max()), 0.0)
    r = shape["_r"]
    g = math.sqrt(float(np.sum((x / r) ** 2)))          # (|x/r| - 1) over its gradient's length
    if g == 0.0:
        return -float(r.min())
    return (g - 1.0) / float(np.linalg.norm(x / (r * r) / g))


def local_normal(shape, x):
    """Outward unit normal of the shape at (or the direction of steepest ascent of its sdf near) x."""
    t = shape["type"]
    if t == "plane":
        return np.array([0.0, 0.0, 1.0])
    if t == "sphere":
        v = x
    elif t == "capsule":
        v = x - [0.0, 0.0, min(max(x[2], -shape["half_length"]), shape["half_length"])]
    elif t == "cylinder":
        rho = math.hypot(x[0], x[1])
        q0, q1 = rho - shape["radius"], abs(x[2]) - shape["half_length"]
        radial = np.array([x[0], x[1], 0.0]) / rho if rho > 0 else np.array([1.0, 0.0, 0.0])
        axial = np.array([0.0, 0.0, math.copysign(1.0, x[2])])
        if q0 > 0 and q1 > 0:
            v = q0 * radial + q1 * axial
        else:
            v = radial if q0 > q1 else axial
    elif t == "box":
        q = np.abs(x) - shape["_hs"]
        if (q > 0).any():
            v = np.sign(x) * np.maximum(q, 0.0)
        else:
            i = int(np.argmax(q))
            v = np.zeros(3)
            v[i] = math.copysign(1.0, x[i])
    else:
        v = x / (shape["_r"] ** 2)
    n = float(np.linalg.norm(v))
    return v / n if n > 0 else np.array([0.0, 0.0, 1.0])


def local_support(shape, u):
    """max over the shape of u·x (local frame); +inf for a plane unless u points along +z."""
    t = shape["type"]
    if t == "plane":
        return 0.0 if (u[0] == 0.0 and u[1] == 0.0 and u[2] >= 0.0) else math.inf
    if t == "sphere":
        return shape["radius"] * math.sqrt(float(u @ u))
    if t == "capsule":
        return shape["half_length"] * abs(u[2]) + shape["radius"] * math.sqrt(float(u @ u))
    if t == "cylinder":
        return shape["half_length"] * abs(u[2]) + shape["radius"] * math.hypot(u[0], u[1])
    if t == "box":
        return float(shape["_hs"] @ np.abs(u))
    return math.sqrt(float(np.sum((shape["_r"] * u) ** 2)))


def _prepared(shape):
    """The shape with numpy copies of its sizes (keys starting with '_') for the functions above."""
    s = dict(shape)
    if s["type"] == "box":
        s["_hs"] = np.array(s["half_sizes"], dtype=float)
    if s["type"] == "ellipsoid":
        s["_r"] = np.array(s["radii"], dtype=float)
    return s


def world_sdf(body, t, x):
    p, q = pose_at(motion_rows(body["motion"]), t)
    return local_sdf(_prepared(body["shape"]), quat_mat(q).T @ (np.asarray(x, dtype=float) - p))


# ------------------------------------------------------------------ MuJoCo's distance along the motion
def _size_attr(shape):
    t = shape["type"]
    v = {"sphere": lambda: [shape["radius"]], "capsule": lambda: [shape["radius"], shape["half_length"]],
         "cylinder": lambda: [shape["radius"], shape["half_length"]], "box": lambda: shape["half_sizes"],
         "ellipsoid": lambda: shape["radii"], "plane": lambda: [0.0, 0.0, 1.0]}[t]()
    return " ".join(repr(float(x)) for x in v)


class GeomPair:
    """MuJoCo's signed distance between the case's two geoms at time t (geom a, then geom b).

    Solid geoms sit alone in mocap bodies whose poses are set per time, then ``mj_kinematics``; a plane is
    a world geom with its static pose written into ``geom_pos``/``geom_quat``.
    """

    def __init__(self, case, *, ccd_tolerance=CCD_TOLERANCE, ccd_iterations=None):
        xml = ["<mujoco><worldbody>"]
        for k in "ab":
            s = case[k]["shape"]
            if s["type"] not in SOLIDS + ("plane",):
                raise ValueError(f"{k}.shape.type: expected one of {SOLIDS + ('plane',)}, got {s['type']!r}")
            if s["type"] == "plane":
                if case[k]["motion"]["type"] != "static":
                    raise ValueError(f"{k}.motion: a plane must be static")
                rows = motion_rows(case[k]["motion"])
                xml.append(f'<geom name="{k}" type="plane" size="0 0 1" '
                           f'pos="{" ".join(repr(float(x)) for x in rows[0])}" '
                           f'quat="{" ".join(repr(float(x)) for x in rows[1])}"/>')
            else:
                xml.append(f'<body name="{k}" mocap="true"><geom name="{k}" type="{s["type"]}" '
                           f'size="{_size_attr(s)}"/></body>')
        xml.append("</worldbody></mujoco>")
        self.model = m = mujoco.MjModel.from_xml_string("".join(xml))
        m.opt.ccd_tolerance = ccd_tolerance
        if ccd_iterations is not None:
            m.opt.ccd_iterations = ccd_iterations
        self.data = mujoco.MjData(m)
        self.ga, self.gb = (mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_GEOM, k) for k in "ab")
        self.movers = []
        for k in "ab":
            rows = motion_rows(case[k]["motion"])
            g = self.ga if k == "a" else self.gb
            if case[k]["shape"]["type"] == "plane":
                # this file's unit quaternion, not the compiler's renormalised copy; the geom's own frame
                # (mj_kinematics skips geom_pos/geom_quat of a geom compiled in its body's frame)
                m.geom_pos[g] = rows[0]
                m.geom_quat[g] = rows[1]
                if m.geom_sameframe[g] and (rows[0].any() or (rows[1] != [1.0, 0.0, 0.0, 0.0]).any()):
                    m.geom_sameframe[g] = 0
                continue
            mocap = m.body_mocapid[m.geom_bodyid[g]]
            self.data.mocap_pos[mocap], self.data.mocap_quat[mocap] = rows[0], rows[1]
            if case[k]["motion"]["type"] != "static":
                self.movers.append((mocap,) + rows)

    def _pose(self, t):
        d = self.data
        for mocap, p0, q0, p1, q1 in self.movers:
            q = (1.0 - t) * q0 + t * q1
            d.mocap_pos[mocap] = (1.0 - t) * p0 + t * p1
            d.mocap_quat[mocap] = q / math.sqrt(float(q @ q))
        mujoco.mj_kinematics(self.model, d)

    def dist(self, t):
        self._pose(t)
        return mujoco.mj_geomDistance(self.model, self.data, self.ga, self.gb, DISTMAX, None)

    def dist_fromto(self, t):
        """(distance, fromto (6,): the closest point on a, then on b) at time t."""
        self._pose(t)
        ft = np.zeros(6)
        dist = mujoco.mj_geomDistance(self.model, self.data, self.ga, self.gb, DISTMAX, ft)
        return dist, ft


class Grader:
    """MuJoCo's distance with each value's sign proven by the shapes' own geometry.

    A positive distance is proven by a separating plane: along MuJoCo's direction, a surface normal at one
    of its points, the last plane that worked, or (when those fail) a box or cylinder axis or the cross
    product of one body's axis with the other's, the two support functions leave a gap above ``tol``.  A
    distance <= 0 is proven by a point inside both shapes by more than ``tol`` (the midpoint of MuJoCo's
    segment).  For a plane pair the half-space distance is exact.  Without such a proof the sign is 0
    (uncertain: within about ``tol`` of contact, or a plane that is not found).  A MuJoCo value the
    geometry contradicts is a *glitch* (a sign it disproves, a distance below a proven lower bound, closest
    points off their surfaces by more than 1e-9 x size, or a plane pair's distance off the exact one by
    more than 1e-12): callers take such values a hair away (:meth:`robust`), and only a sign that
    MuJoCo and the geometry agree on is used.  Poses come from this file's quaternion arithmetic.
    """

    def __init__(self, case, **kw):
        self.pair = GeomPair(case, **kw)
        self.shapes = [_prepared(case[k]["shape"]) for k in "ab"]
        self.rows = [motion_rows(case[k]["motion"]) for k in "ab"]
        self.size = case_size(case)
        extent = max(float(np.abs(r[i]).max()) for r in self.rows for i in (0, 2)) + 2.0 * self.size
        self.tol = 1e-14 * (1.0 + extent)
        self.surface_tol = 1e-9 * self.size
        kinds = [s["type"] for s in self.shapes]
        self.plane = kinds.index("plane") if "plane" in kinds else None
        straight = {"box": (0, 1, 2), "cylinder": (2,)}
        self.axes = None
        if self.plane is None and any(k in straight for k in kinds):
            self.axes = [straight.get(k, ()) for k in kinds]
        self.normal = None
        self.evaluations = self.glitches = 0
        self.worst_glitch = 0.0

    def frames(self, t):
        out = []
        for rows in self.rows:
            p, q = pose_at(rows, t)
            out.append((quat_mat(q), p))
        return out

    def _support(self, k, frames, u):
        R, c = frames[k]
        return float(u @ c) + local_support(self.shapes[k], R.T @ u)

    def _sdf(self, k, frames, x):
        R, c = frames[k]
        return local_sdf(self.shapes[k], R.T @ (x - c))

    def axis_bound(self, frames):
        """The best lower bound over the shapes' straight directions: box axes, cylinder axes, and the
        cross products of one body's with the other's (exact for box-box, and for a cylinder's side or a
        box's edge against a box edge or another cylinder's side)."""
        dirs = [[frames[k][0][:, i] for i in self.axes[k]] for k in (0, 1)]
        cands = dirs[0] + dirs[1]
        for u in dirs[0]:
            for v in dirs[1]:
                w = np.cross(u, v)
                n = float(np.linalg.norm(w))
                if n > 1e-9:
                    cands.append(w / n)
        best, arg = -math.inf, None
        for n in cands:
            for m in (n, -n):
                g = self._gap(frames, m)
                if g > best:
                    best, arg = g, m
        return best, arg

    def _gap(self, frames, n):
        """min over b of n·b - max over a of n·a: a lower bound on the distance (n unit, from a to b)."""
        return -self._support(1, frames, -n) - self._support(0, frames, n)

    def lower_bound(self, frames, ft):
        p1, p2 = ft[:3], ft[3:]
        cands = []
        v = p2 - p1
        L = float(np.linalg.norm(v))
        if L > 0:
            cands.append(v / L)
        for k, p, sgn in ((0, p1, 1.0), (1, p2, -1.0)):
            R, c = frames[k]
            cands.append(sgn * (R @ local_normal(self.shapes[k], R.T @ (p - c))))
        if self.normal is not None:
            cands.append(self.normal)
        best, arg = -math.inf, None
        for n in cands:
            g = self._gap(frames, n)
            if g > best:
                best, arg = g, n
        return best, arg

    def plane_distance(self, frames):
        """The exact signed distance of the solid to the half-space (plane pairs)."""
        s = 1 - self.plane
        Rp, op = frames[self.plane]
        n = Rp[:, 2]
        R, c = frames[s]
        return float(n @ c) - local_support(self.shapes[s], -(R.T @ n)) - float(n @ op)

    def proven_lower(self, frames, ft):
        """The best lower bound on the distance this file proves from MuJoCo's points and the shapes' axes
        (the exact distance for a plane pair)."""
        if self.plane is not None:
            return self.plane_distance(frames)
        lb, _ = self.lower_bound(frames, ft)
        if self.axes:
            lb = max(lb, self.axis_bound(frames)[0])
        return lb

    def evaluate(self, t):
        """(d, sign, glitch, fromto) at time t: MuJoCo's distance, its certified sign (+1, -1, or 0 when
        uncertain) and whether the geometry contradicts MuJoCo's output."""
        d, ft = self.pair.dist_fromto(t)
        self.evaluations += 1
        frames = self.frames(t)
        sign, glitch, err = 0, False, 0.0
        if self.plane is not None:
            exact = self.plane_distance(frames)
            err = abs(d - exact)
            glitch = err > 1e-12 * (1.0 + abs(exact)) + self.tol
            sign = 1 if (d > 0 and exact > self.tol) else -1 if (d <= 0 and exact < -self.tol) else 0
        elif d > 0:
            off = max(self._sdf(0, frames, ft[:3]), self._sdf(1, frames, ft[3:]))
            lb, n = self.lower_bound(frames, ft)
            if lb <= self.tol and self.axes:
                lb, n = max((lb, n), self.axis_bound(frames), key=lambda x: x[0])
            err = max(off, lb - d)
            glitch = off > self.surface_tol or d < lb - self.tol - 1e-12 * d
            if lb > self.tol:
                sign = 1
                self.normal = n
            else:
                mid = 0.5 * (ft[:3] + ft[3:])
                if self._sdf(0, frames, mid) < -self.tol and self._sdf(1, frames, mid) < -self.tol:
                    glitch, err = True, max(err, d)     # MuJoCo says apart; a common point says not
        else:
            mid = 0.5 * (ft[:3] + ft[3:])
            if self._sdf(0, frames, mid) < -self.tol and self._sdf(1, frames, mid) < -self.tol:
                sign = -1
            else:
                lb, n = self.lower_bound(frames, ft)
                if lb > self.tol:
                    glitch, err = True, lb - d
        if glitch:                   # the value is set aside; a sign the geometry proves stands
            self.glitches += 1
            self.worst_glitch = max(self.worst_glitch, err)
        return d, sign, glitch, ft

    def robust(self, t, lo=0.0, hi=1.0, spread=1e-11):
        """evaluate() at t, or where MuJoCo glitches there, at the nearest of t ± k·spread (k = 1..4, within
        [lo, hi]) where it does not. Returns (d, sign, glitch, fromto, t_used)."""
        first = None
        for k in (0, 1, -1, 2, -2, 3, -3, 4, -4):
            tk = t + k * spread
            if not lo <= tk <= hi:
                continue
            d, s, g, ft = self.evaluate(tk)
            if first is None:
                first = (d, s, g, ft, tk)
            if not g:
                return d, s, g, ft, tk
        return first


def max_speed(case):
    """A bound on |d/dt| of the distance (each body's point speeds, nlerp's angular rate included)."""
    v = 0.0
    for k in "ab":
        p0, q0, p1, q1 = motion_rows(case[k]["motion"])
        if case[k]["shape"]["type"] == "plane":
            continue
        c = float(q0 @ q1)                        # nlerp's angular rate is at most 2 |q1 - q0| / |q(t)| ...
        rate = 2.0 * float(np.linalg.norm(q1 - q0)) / math.sqrt(max(0.5 * (1.0 + c), 1e-24))  # |q|^2 >= (1+c)/2
        v += float(np.linalg.norm(p1 - p0)) + rate * bounding_radius(case[k]["shape"])
    return v


def _golden_min(f, lo, hi, tol=1e-12, stop_at=0.0):
    """Minimise f on [lo, hi] by golden section; stops early at a value <= stop_at. (t, f(t))."""
    a, b = lo, hi
    c, d = b - GOLDEN * (b - a), a + GOLDEN * (b - a)
    fc, fd = f(c), f(d)
    best = min((fc, c), (fd, d))
    while b - a > tol and best[0] > stop_at:
        if fc <= fd:
            b, d, fd = d, c, fc
            c = b - GOLDEN * (b - a)
            fc = f(c)
        else:
            a, c, fc = c, d, fd
            d = a + GOLDEN * (b - a)
            fd = f(d)
        best = min(best, (fc, c), (fd, d))
    return best[1], best[0]


SPLITS = (0.5, 0.45, 0.55, 0.35, 0.65, 0.2, 0.8)


def _bisect(sign, lo, hi):
    """lo with certified sign +1, hi with -1: narrowed to T_TOL, splitting elsewhere than the midpoint
    where the sign there is uncertain, stopping where no split of the bracket is certain."""
    while hi - lo > T_TOL:
        for frac in SPLITS:
            m = lo + frac * (hi - lo)
            if not lo < m < hi:
                continue
            s = sign(m)
            if s:
                break
        else:
            break
        if s > 0:
            lo = m
        else:
            hi = m
    return lo, hi


def reference_details(case, *, n_scan=N_SCAN, full=True, grader=None):
    """MuJoCo's answer for one case with what it was read from.

    Returns (result, info): result is ``{"id", "status_at_start", "first_contact", "contact_point"}`` or
    None when the case is ill-posed; info holds ``reason`` (why ill-posed, or "ok"), ``d0`` (distance at
    t=0), ``clearance`` (closest approach without contact: over [0, 1], or before the first contact, None
    if there is no dip before it), ``lower_clearance`` (a proven lower bound on it), ``slope`` (mean -d'
    over TANGENT_DT after the crossing), ``bracket`` (width of the crossing's proven bracket),
    ``sign_window`` (the smallest of 1e-10 ... 1e-7 at which the proven sign is right at t* -/+ 1, 3 and
    10 times it), ``point_spread`` (largest distance, x size, of MuJoCo's points at t* + 1e-9, t* + 1e-8 and
    t* - 1e-7 from the contact point, beyond the motion in between), ``evaluations``, ``glitches`` (MuJoCo
    values the geometry contradicts) and ``worst_glitch`` (by how much, in length).
    With ``full=False`` only the scan and the refinement of minima run (for tuning clearances): info then
    carries ``clearance``, ``t_cross`` (None without contact) and ``depth`` (the smallest value with one).
    """
    G = grader if grader is not None else Grader(case)
    size = G.size

    def value(t, lo=0.0, hi=1.0):
        d, s, g, ft, tu = G.robust(t, lo, hi)
        return d, s, g

    def sign(t):
        return G.evaluate(t)[1]

    info = {"reason": "ok", "d0": None, "clearance": None, "lower_clearance": None, "slope": None,
            "bracket": None, "sign_window": None, "point_spread": None}
    out = {"id": case.get("id"), "status_at_start": "separate", "first_contact": None, "contact_point": None}

    def done(reason=None):
        info["evaluations"], info["glitches"], info["worst_glitch"] = G.evaluations, G.glitches, G.worst_glitch
        if reason:
            info["reason"] = reason
            return None, info
        return out, info

    d0, s0, g0, _, _ = G.robust(0.0)
    info["d0"] = d0
    if abs(d0) <= START_EPS:
        return done(f"start distance {d0:.3g} within {START_EPS:g} of contact")
    if s0 == 0:
        return done(f"start distance {d0:.3g} not certain")
    if s0 < 0:
        out.update(status_at_start="overlapping", first_contact=0.0)
        return done()

    ts = np.linspace(0.0, 1.0, n_scan)
    ds = np.empty(n_scan)
    ss = np.zeros(n_scan, dtype=int)
    ds[0], ss[0] = d0, 1
    first, last_pos = n_scan, 0
    for i in range(1, n_scan):
        ds[i], ss[i], _ = value(float(ts[i]))
        if ss[i] < 0 or (ss[i] == 0 and ds[i] <= 0):
            # certified overlap; or uncertain at a value <= 0 (contact within tol, or a glitch MuJoCo keeps)
            first = i
            break
        if ss[i] > 0:
            last_pos = i
    # local minima of the scan before the first crossing that could hide a dip to zero or a close approach
    step = 1.0 / (n_scan - 1)
    reach = 2.0 * max_speed(case) * step + NEAR_RANGE[1] * size
    minima, bracket = [], None

    def f(t):
        return value(t)[0]

    lowest = int(np.argmin(ds[:first]))
    for i in range(1, first):
        right = ds[i + 1] if i + 1 < first else (math.inf if first == n_scan else -math.inf)
        if not (ds[i] <= ds[i - 1] and ds[i] <= right and (ds[i] < reach or i == lowest)):
            continue
        if i + 1 == first and first < n_scan:
            continue                                    # the approach to the crossing itself
        hi = float(ts[i + 1]) if i + 1 < n_scan else 1.0
        tm, dm = _golden_min(f, float(ts[i - 1]), hi)
        d, s, g = value(tm)
        if s < 0:
            j = i - 1
            while ss[j] != 1:                           # the bracket starts at a certified separation
                j -= 1
            bracket = (float(ts[j]), tm)
            break
        if s == 0:
            info["clearance"] = dm
            return done(f"approach to {dm:.3g} at t = {tm:.6f} not certain either way")
        minima.append((dm, tm))
    if bracket is None and first < n_scan:
        bracket = (float(ts[last_pos]), float(ts[first]))
        if ss[first] == 0:
            # walk the bracket's right end forward to a certified overlap
            for t in np.linspace(ts[first], min(1.0, ts[first] + 4 * step), 9)[1:]:
                if G.evaluate(float(t))[1] < 0:
                    bracket = (bracket[0], float(t))
                    break
            else:
                return done(f"no certified overlap after the scan's crossing at t = {ts[first]:.6f}")

    def lower_clear(t):
        """A proven lower bound on the distance at t (exact for a plane pair)."""
        d, ft = G.pair.dist_fromto(t)
        return G.proven_lower(G.frames(t), ft)

    if bracket is None:
        clearance = min([float(ds.min())] + [m for m, _ in minima])
        tmin = min([(float(ds.min()), float(ts[int(np.argmin(ds))]))] + minima)[1]
        info["clearance"], info["t_cross"] = clearance, None
        info["lower_clearance"] = lower_clear(tmin)
        if clearance < CLEAR_MIN * size or info["lower_clearance"] < 0.5 * CLEAR_MIN * size:
            return done(f"closest approach {clearance:.3g} (proven >= {info['lower_clearance']:.3g}) "
                        f"below {CLEAR_MIN:g} x size")
        return done()
    info["t_cross"] = bracket[1]
    if minima:
        info["clearance"] = min(m for m, _ in minima)
        info["lower_clearance"] = lower_clear(min(minima)[1])
    if not full:
        info["depth"] = min(float(ds[first]), f(bracket[1]))
        return done("not bisected (full=False)")
    if minima and min(m for m, _ in minima) < CLEAR_MIN * size:
        return done(f"approach {info['clearance']:.3g} below {CLEAR_MIN:g} x size before the contact")

    # the crossing: first narrowed with certified signs, then MuJoCo's own sign change inside that bracket
    lo_c, hi_c = _bisect(sign, *bracket)
    info["bracket"] = hi_c - lo_c
    if hi_c - lo_c > CERT_WIDTH:
        return done(f"certified crossing bracket [{lo_c!r}, {hi_c!r}] wider than {CERT_WIDTH:g}")
    lo, hi = _bisect(lambda t: 1 if G.pair.dist(t) > 0.0 else -1, lo_c, hi_c)
    t_star = 0.5 * (lo + hi)
    if t_star + TANGENT_DT > 1.0:
        return done(f"first crossing {t_star:.6f} within {TANGENT_DT:g} of t = 1")
    after = []
    for k in range(1, 5):
        d, s, g = value(t_star + TANGENT_DT * k / 4.0)
        after.append(d if s < 0 else 0.0)
    info["slope"] = -min(after) / TANGENT_DT
    if min(after) > -TANGENT_DEPTH * size:
        return done(f"nearly tangent: certified min {min(after):.3g} within {TANGENT_DT:g} after the crossing")
    for w in (1e-10, 1e-9, 1e-8, SIGN_WINDOW):
        if all(sign(t_star - k * w) > 0 and sign(t_star + k * w) < 0 for k in (1, 3, 10)):
            info["sign_window"] = w
            break
    if info["sign_window"] is None:
        return done(f"certified sign not steady within {SIGN_WINDOW:g} of the crossing")

    # contact point: the midpoint of MuJoCo's segment at its crossing (the side with distance <= 0), whose
    # ends lie on their surfaces; it must agree with MuJoCo's points a little deeper and a little before
    def midpoint(t, tol):
        h = max(1e-12, 0.05 * abs(t - t_star))
        for k in (0, 1, -1, 2, -2, 3, -3):
            tk = t + k * h
            d, ft = G.pair.dist_fromto(tk)
            frames = G.frames(tk)
            if max(abs(G._sdf(0, frames, ft[:3])), abs(G._sdf(1, frames, ft[3:]))) <= tol:
                return 0.5 * (ft[:3] + ft[3:])
        return None

    point = midpoint(hi, G.surface_tol)
    if point is None:
        return done("MuJoCo's closest points at the crossing are off the surfaces")
    speed = max_speed(case)
    spread = 0.0
    for t in (hi_c + 1e-9, hi_c + 1e-8, lo_c - 1e-7):
        p = midpoint(t, 10.0 * G.surface_tol)
        if p is None:
            return done(f"MuJoCo's closest points at t = {t!r} are off the surfaces")
        gap = float(np.linalg.norm(p - point)) - 2.0 * speed * abs(t - t_star)
        spread = max(spread, gap / size)
        if gap > POINT_STEADY * size:
            return done(f"contact point not steady: MuJoCo's point at t* {t - t_star:+.0e} is "
                        f"{gap / size:.2g} x size away")
    info["point_spread"] = spread
    out.update(first_contact=t_star, contact_point=point.tolist())
    return done()


def reference(case):
    """MuJoCo's answer for one case (the dict of geoms_expected.json), or None when it is ill-posed."""
    return reference_details(case)[0]


# ------------------------------------------------------------------ second references
def _mp_unit(q):
    q = [mpf(float(x)) for x in q]
    n = mp.sqrt(sum(x * x for x in q))
    return [x / n for x in q]


def closed_form(case):
    """Sphere-sphere and sphere-plane at 50 digits: (first contact, contact point, clearance) or None.

    The first contact is None without one in [0, 1] (then the clearance is the closest approach); a case
    overlapping at the start gives first contact 0 and no point.
    """
    ta, tb = case["a"]["shape"]["type"], case["b"]["shape"]["type"]
    if ta != "sphere" or tb not in ("sphere", "plane"):
        return None
    with mp.workdps(50):
        def centre(body):
            m = body["motion"]
            if m["type"] == "static":
                p = [mpf(float(x)) for x in m["position"]]
                return p, p
            return ([mpf(float(x)) for x in m["start"]["position"]],
                    [mpf(float(x)) for x in m["end"]["position"]])

        a0, a1 = centre(case["a"])
        ra = mpf(float(case["a"]["shape"]["radius"]))
        if tb == "sphere":
            b0, b1 = centre(case["b"])
            r = ra + mpf(float(case["b"]["shape"]["radius"]))
            u = [a0[k] - b0[k] for k in range(3)]                       # relative centre (1-t) u + t v
            v = [a1[k] - b1[k] for k in range(3)]
            w = [v[k] - u[k] for k in range(3)]
            A = sum(x * x for x in w)
            B = sum(u[k] * w[k] for k in range(3))
            C = sum(x * x for x in u) - r * r
            rel = lambda t: [u[k] + t * w[k] for k in range(3)]
            if C < 0:
                return 0.0, None, float(mp.sqrt(C + r * r) - r)
            disc = B * B - A * C
            t = None
            if A > 0 and disc >= 0:
                t = (-B - mp.sqrt(disc)) / A
                if not 0 <= t <= 1:
                    t = None
            if t is None:
                tm = min(max(-B / A, mpf(0)), mpf(1)) if A > 0 else mpf(0)
                return None, None, float(mp.sqrt(sum(x * x for x in rel(tm))) - r)
            ca = [(1 - t) * a0[k] + t * a1[k] for k in range(3)]
            d = rel(t)
            n = mp.sqrt(sum(x * x for x in d))
            point = [ca[k] - ra * d[k] / n for k in range(3)]            # from a's centre towards b's
            return float(t), [float(x) for x in point], None
        pm = case["b"]["motion"]
        w, x, y, z = _mp_unit(pm["quaternion"])
        n = [2 * (x * z + w * y), 2 * (y * z - w * x), 1 - 2 * (x * x + y * y)]
        o = [mpf(float(c)) for c in pm["position"]]
        h0 = sum(n[k] * (a0[k] - o[k]) for k in range(3)) - ra
        h1 = sum(n[k] * (a1[k] - o[k]) for k in range(3)) - ra
        if h0 < 0:
            return 0.0, None, float(h0)
        if h1 > 0:
            return None, None, float(min(h0, h1))
        t = h0 / (h0 - h1)
        point = [(1 - t) * a0[k] + t * a1[k] - ra * n[k] for k in range(3)]
        return float(t), [float(c) for c in point], None


def crosscheck(case, result, info=None):
    """Problems found by the second references (a list of strings; empty when all agree).

    Adds ``surface`` (the contact point's largest |signed distance| to the two analytic surfaces, x size)
    to ``info`` when given.
    """
    problems = []
    size = case_size(case)
    cf = closed_form(case)
    if cf is not None:
        t, point, clear = cf
        if (t is None) != (result["first_contact"] is None):
            problems.append(f"closed form says first contact {t}, MuJoCo {result['first_contact']}")
        elif t is not None and abs(t - result["first_contact"]) > CLOSED_FORM_TOL:
            problems.append(f"first contact: closed form {t!r}, MuJoCo {result['first_contact']!r} "
                            f"(|dt| {abs(t - result['first_contact']):.2e})")
        elif point is not None and result["contact_point"] is not None and \
                np.linalg.norm(np.subtract(point, result["contact_point"])) > CLOSED_FORM_TOL * size:
            problems.append(f"contact point off the closed form's by "
                            f"{np.linalg.norm(np.subtract(point, result['contact_point'])):.2e}")
        elif t is None and info is not None and info.get("clearance") is not None and \
                abs(clear - info["clearance"]) > CLOSED_FORM_TOL * max(1.0, size):
            problems.append(f"clearance: closed form {clear!r}, MuJoCo {info['clearance']!r}")
    if result["contact_point"] is not None:
        t = result["first_contact"]
        worst = max(abs(world_sdf(case[k], t, result["contact_point"])) for k in "ab") / size
        if info is not None:
            info["surface"] = worst
        if worst > SURFACE_TOL:
            problems.append(f"contact point {worst:.2e} x size off a surface")
    return problems


# ------------------------------------------------------------------ random cases
def _loguniform(rng, lo, hi):
    return float(math.exp(rng.uniform(math.log(lo), math.log(hi))))


def _random_quat(rng):
    q = rng.normal(size=4)
    return q / np.linalg.norm(q)


def _random_unit(rng):
    v = rng.normal(size=3)
    return v / np.linalg.norm(v)


def random_shape(rng, kind):
    """Sizes from 0.03 to 0.6, aspect ratios up to 8:1."""
    if kind == "sphere":
        return {"type": "sphere", "radius": _loguniform(rng, 0.03, 0.6)}
    big = _loguniform(rng, 0.06, 0.6)
    ratio = lambda: _loguniform(rng, 1.0, min(8.0, big / 0.03))
    if kind in ("capsule", "cylinder"):
        r, h = big / ratio(), big
        if rng.uniform() < (0.3 if kind == "cylinder" else 0.15):
            r, h = big, big / ratio()                                   # disk, or a ball-like capsule
        return {"type": kind, "radius": r, "half_length": h}
    dims = [big, big / ratio(), big / ratio()]
    rng.shuffle(dims)
    return {"type": kind, ("half_sizes" if kind == "box" else "radii"): [float(x) for x in dims]}


def _rigid(p0, q0, p1, q1):
    return {"type": "rigid", "start": {"position": [float(x) for x in p0], "quaternion": [float(x) for x in q0]},
            "end": {"position": [float(x) for x in p1], "quaternion": [float(x) for x in q1]}}


def _static(p, q):
    return {"type": "static", "position": [float(x) for x in p], "quaternion": [float(x) for x in q]}


def _turn(rng, kind):
    """Rotation angle of body a for a motion kind."""
    return {"translate": 0.0, "rotate": rng.uniform(0.3, 1.2), "spin": rng.uniform(1.2, 2.6)}[kind]


def _draw(rng, ta, tb, kind):
    """One random pair of shapes ``ta``, ``tb`` and a motion of kind ``kind`` for body a.

    Body a passes by body b (static, or drifting by up to 0.15 of its bounding radius and turning a little),
    or dips towards the static plane (tilted in half the draws), with its whole path shifted by s along a
    fixed direction (across its path; the plane's normal): s = 0 is the drawn aim, s_hit (through b's
    centre, or ending with a's centre below the plane) should hit, s_far surely clears.
    Returns (make(s) -> {"a", "b"}, s_hit, s_far, size).
    """
    sa = random_shape(rng, ta)
    qa0 = _random_quat(rng)
    angle = _turn(rng, kind)
    qa1 = quat_mul(axis_angle_quat(_random_unit(rng), angle), qa0) if angle else qa0
    Ra = bounding_radius(sa)
    origin = rng.uniform(-0.5, 0.5, size=3)
    if tb == "plane":
        tilt = rng.uniform() < 0.5
        qp = _random_quat(rng) if tilt else np.array([1.0, 0.0, 0.0, 0.0])
        op = origin if tilt else np.zeros(3)
        n = quat_mat(qp)[:, 2]
        along = _random_unit(rng)
        along -= (along @ n) * n
        along /= np.linalg.norm(along)
        h0 = Ra * rng.uniform(1.05, 2.5)
        h1 = -Ra * rng.uniform(0.0, 1.0) if kind == "translate" else -Ra * rng.uniform(-0.3, 1.0)
        travel = Ra * rng.uniform(0.0, 3.0)
        base0 = op + h0 * n
        base1 = op + h1 * n + travel * along
        b = {"shape": {"type": "plane"}, "motion": _static(op, qp)}

        def make(s):
            return {"a": {"shape": sa, "motion": _rigid(base0 + s * n, qa0, base1 + s * n, qa1)}, "b": b}
        return make, -Ra, Ra - h1 + 0.2 * Ra, shape_size(sa)

    sb = random_shape(rng, tb)
    Rb = bounding_radius(sb)
    R = Ra + Rb
    qb0 = _random_quat(rng)
    if rng.uniform() < 0.45:
        b = {"shape": sb, "motion": _static(origin, qb0)}
        drift = 0.0
    else:
        turn_b = rng.uniform(0.0, {"translate": 0.3, "rotate": 0.6, "spin": 1.0}[kind])
        drift = rng.uniform(0.0, 0.15) * Rb
        qb1 = quat_mul(axis_angle_quat(_random_unit(rng), turn_b), qb0)
        b = {"shape": sb, "motion": _rigid(origin, qb0, origin + drift * _random_unit(rng), qb1)}
    u = _random_unit(rng)
    w = _random_unit(rng)
    w -= (w @ u) * u
    w /= np.linalg.norm(w)
    if kind == "spin":
        d0, d1 = R * rng.uniform(1.05, 1.8), R * rng.uniform(-0.6, 0.8)
    else:
        d0, d1 = R * rng.uniform(1.05, 2.5), R * rng.uniform(-0.3, 1.5)
    # aim: through the inner balls (sure to hit) or anywhere within the bounding balls (may graze or miss)
    if rng.uniform() < 0.5:
        aim = rng.uniform(0.0, 0.9) * (inner_radius(sa) + inner_radius(sb))
    else:
        aim = rng.uniform(0.0, 0.8) * R

    def make(s):
        off = (aim + s) * w
        return {"a": {"shape": sa, "motion": _rigid(origin + d0 * u + off, qa0, origin - d1 * u + off, qa1)},
                "b": b}
    return make, -aim, R + drift + 0.1 * R, max(shape_size(sa), shape_size(sb))


def _tune_near(make, s_hit, s_far, target, size, n_scan):
    """Shift s in [s_hit, s_far] whose clearance is within a factor 2 of target (Illinois on the clearance);
    None when it does not get there in 40 scans."""
    def clear(s):
        case = make(s)
        _, info = reference_details(case, n_scan=n_scan, full=False)
        if info.get("t_cross") is not None:
            return min(info["depth"], -1e-6 * size)
        return info["clearance"] if info["clearance"] is not None else math.nan

    lo, hi = s_hit, s_far
    flo, fhi = clear(lo) - target, clear(hi) - target
    if not (flo < 0 < fhi):                             # (a nan from an uncertain scan fails this too)
        return None
    side = 0
    for _ in range(40):
        s = (lo * fhi - hi * flo) / (fhi - flo)
        c = clear(s)
        if math.isnan(c):
            return None
        if 0.5 * target <= c <= 2.0 * target:
            return s
        fs = c - target
        if fs < 0:
            lo, flo = s, fs
            if side == -1:
                fhi *= 0.5
            side = -1
        else:
            hi, fhi = s, fs
            if side == 1:
                flo *= 0.5
            side = 1
    return None


def _one_case(seed, pair_index, slot, scenario, kind, n_scan=N_SCAN, max_tries=200):
    """The slot's case, its answer and details: the first random draw (of a stream fixed by seed, pair
    and slot) whose MuJoCo answer is well-posed, fits the scenario and agrees with the second references.
    Returns (case, result, info, rejected draws by reason, disagreements [(attempt, problems)])."""
    ta, tb = PAIRS[pair_index]
    rng = np.random.default_rng([seed, pair_index, slot])
    rejected, disagreements = {}, []
    for attempt in range(max_tries):
        make, s_hit, s_far, size = _draw(rng, ta, tb, kind)
        if scenario == "collide":
            s = 0.0
        elif scenario == "far":
            s = s_far + rng.uniform(0.2, 1.0) * size
        else:
            target = _loguniform(rng, NEAR_RANGE[0] * 1.5, NEAR_RANGE[1] / 1.5) * size
            s = _tune_near(make, s_hit, s_far, target, size, 1001)
            if s is None:
                rejected["near: no shift"] = rejected.get("near: no shift", 0) + 1
                continue
        case = {"id": f"{ta}-{tb}-{kind}-s{seed}-{slot}", "tags": [f"{ta}-{tb}", kind, scenario]}
        case.update(make(s))
        result, info = reference_details(case, n_scan=n_scan)
        why = info["reason"]
        if result is not None:
            t, clear = result["first_contact"], info["clearance"]
            if result["status_at_start"] != "separate" or info["d0"] < 1e-3 * size:
                why = "start too close"
            elif scenario == "collide" and t is None:
                why = "collide: missed"
            elif scenario != "collide" and t is not None:
                why = f"{scenario}: hit"
            elif scenario == "near" and not NEAR_RANGE[0] * size <= clear <= NEAR_RANGE[1] * size:
                why = "near: clearance out of range"
            elif scenario == "far" and clear < FAR_MIN * size:
                why = "far: too close"
            else:
                problems = crosscheck(case, result, info)
                if not problems:
                    info["attempts"] = attempt + 1
                    return case, result, info, rejected, disagreements
                # a disagreement with a second reference is reported, never emitted: the slot draws again
                disagreements.append((attempt, problems))
                why = "disagrees with a second reference"
        key = re.sub(r"[-+]?\d[\d.e+-]*", "#", why)          # reasons counted without their numbers
        rejected[key] = rejected.get(key, 0) + 1
    raise RuntimeError(f"{ta}-{tb} {kind} {scenario} slot {slot}: no well-posed case in {max_tries} draws "
                       f"({rejected})")


def _slots(per_pair, kinds, total=None, pairs=None):
    """(pair index into PAIRS, slot, scenario, motion kind) for each case to make."""
    pairs = list(range(len(PAIRS))) if pairs is None else list(pairs)
    counts = {p: per_pair for p in pairs}
    if total is not None:
        counts = {p: total // len(pairs) + (i < total % len(pairs)) for i, p in enumerate(pairs)}
    out, k = [], 0
    for p in pairs:
        for slot in range(counts[p]):
            out.append((p, slot, SCENARIOS[k % len(SCENARIOS)], kinds[slot % len(kinds)]))
            k += 1
    return out


def _run_slot(args):
    seed, p, slot, scenario, kind = args
    t0 = time.perf_counter()
    case, result, info, rejected, problems = _one_case(seed, p, slot, scenario, kind)
    return case, result, info, rejected, problems, time.perf_counter() - t0


def generate(seed, per_pair=3, kinds=KINDS, *, total=None, pairs=None, jobs=1, log=None):
    """Cases and answers: ``per_pair`` cases for each shape pair (or ``total`` spread round-robin over the
    pairs), motion kinds cycled within a pair, scenarios cycled over all (6 of 9 collide).

    Returns (cases, results, records): records hold per case its pair, scenario, details, rejected draws
    and ``problems``: the disagreements with a second reference met on the way (such a draw is not emitted;
    its slot draws again).
    """
    work = [(seed,) + s for s in _slots(per_pair, tuple(kinds), total, pairs)]
    if jobs > 1:
        import multiprocessing
        with multiprocessing.Pool(jobs) as pool:
            done = pool.map(_run_slot, work, chunksize=1)
    else:
        done = [_run_slot(w) for w in work]
    cases, results, records = [], [], []
    for (s, p, slot, scenario, kind), (case, result, info, rejected, problems, dt) in zip(work, done):
        records.append({"pair": "-".join(PAIRS[p]), "id": case["id"], "scenario": scenario, "kind": kind,
                        "size": case_size(case),
                        "info": info, "rejected": rejected, "problems": problems, "seconds": dt})
        for attempt, why in problems:
            if log:
                log(f"DISAGREEMENT {case['id']} (draw {attempt + 1}, not emitted): {'; '.join(why)}")
        cases.append(case)
        results.append(result)
    return cases, results, records


def make_cases(seed, per_pair=3, kinds=KINDS, *, total=None, pairs=None):
    """The cases only (see :func:`generate`); deterministic for a seed."""
    return generate(seed, per_pair, kinds, total=total, pairs=pairs)[0]


# ------------------------------------------------------------------ command line
def _dump(path, obj):
    with open(path, "w") as fh:
        json.dump(obj, fh, indent=1)
        fh.write("\n")


def reproduce(cases_path, expected_path, *, log=print):
    """Recompute the answers of a stored set and compare: (agree, total, list of disagreements)."""
    cases = {c["id"]: c for c in json.load(open(cases_path))["cases"]}
    bad, n = [], 0
    for e in json.load(open(expected_path))["results"]:
        n += 1
        case = cases[e["id"]]
        size = case_size(case)
        result, info = reference_details(case)
        if result is None:
            bad.append((e["id"], f"ill-posed here: {info['reason']}"))
            continue
        why = []
        if result["status_at_start"] != e["status_at_start"]:
            why.append("status")
        t, te = result["first_contact"], e["first_contact"]
        if (t is None) != (te is None):
            why.append(f"first contact {t} vs {te}")
        elif t is not None and abs(t - te) > 1e-6:
            why.append(f"dt {abs(t - te):.2e}")
        if e.get("contact_point") is not None and te not in (None, 0.0):
            p = result["contact_point"]
            if p is None or np.linalg.norm(np.subtract(p, e["contact_point"])) > 1e-5 * size:
                why.append("point")
        problems = crosscheck(case, result, info)
        if why or problems:
            bad.append((e["id"], ", ".join(why + problems)))
        elif log:
            dt = 0.0 if t is None else abs(t - te)
            dp = (0.0 if e.get("contact_point") is None or result["contact_point"] is None
                  else float(np.linalg.norm(np.subtract(result["contact_point"], e["contact_point"]))) / size)
            log(f"  {e['id']:38s} ok  |dt| {dt:.1e}  |dp|/size {dp:.1e}")
    return n - len(bad), n, bad


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--seed", type=int, default=7)
    ap.add_argument("--per-pair", type=int, default=3, help="cases per shape pair (kinds cycled)")
    ap.add_argument("--total", type=int, help="this many cases spread round-robin over the 20 pairs "
                                              "(overrides --per-pair)")
    ap.add_argument("--kinds", default=",".join(KINDS), help="motion kinds, comma separated")
    ap.add_argument("-o", "--output", help="cases file to write")
    ap.add_argument("--expected", help="answers file to write")
    ap.add_argument("-j", "--jobs", type=int, default=1, help="worker processes")
    ap.add_argument("-v", "--verbose", action="store_true", help="with --reproduce: a line per case")
    ap.add_argument("--reproduce", nargs=2, metavar=("CASES", "EXPECTED"),
                    help="recompute a stored set's answers and compare (no generation)")
    args = ap.parse_args(argv)
    t0 = time.perf_counter()
    if args.reproduce:
        agree, n, bad = reproduce(*args.reproduce, log=print if args.verbose else None)
        for i, why in bad:
            print(f"  {i}: {why}")
        print(f"reproduced {agree}/{n} ({time.perf_counter() - t0:.1f} s)")
        return 0 if agree == n else 1
    kinds = tuple(k for k in args.kinds.split(",") if k)
    for k in kinds:
        if k not in KINDS:
            ap.error(f"--kinds: expected some of {','.join(KINDS)}, got {k!r}")
    cases, results, records = generate(args.seed, args.per_pair, kinds, total=args.total, jobs=args.jobs,
                                       log=print)
    problems = [r for r in records if r["problems"]]
    for pair in dict.fromkeys(r["pair"] for r in records):
        rs = [r for r in records if r["pair"] == pair]
        hits = [r for r in rs if r["scenario"] == "collide"]
        worst = lambda key, scale=False: max([r["info"][key] / (r["size"] if scale else 1.0) for r in hits]
                                             or [0.0])
        clears = [r["info"]["clearance"] / r["size"] for r in rs if r["scenario"] != "collide"]
        rej = sum(sum(r["rejected"].values()) for r in rs)
        glitches = sum(r["info"]["glitches"] for r in rs)
        evals = sum(r["info"]["evaluations"] for r in rs)
        print(f"{pair:20s} {len(rs):2d} cases: {len(hits)} collide, "
              f"{sum(r['scenario'] == 'near' for r in rs)} near, {sum(r['scenario'] == 'far' for r in rs)} far; "
              f"{rej:2d} draws set aside; proven bracket <= {worst('bracket'):.0e}, point off surfaces <= "
              f"{worst('surface'):.0e}, point spread <= {worst('point_spread'):.0e} (x size); clearances/size "
              + (f"{min(clears):.0e}..{max(clears):.0e}" if clears else "-")
              + f"; MuJoCo glitches {glitches}/{evals} (worst {max(r['info']['worst_glitch'] for r in rs):.0e})"
              + f"; {sum(r['seconds'] for r in rs):.1f} s")
    reasons = {}
    for r in records:
        for k, v in r["rejected"].items():
            reasons[k] = reasons.get(k, 0) + v
    if reasons:
        print("draws set aside: " + ", ".join(f"{k} {v}" for k, v in sorted(reasons.items(), key=lambda x: -x[1])))
    if args.output:
        _dump(args.output, {"version": 1, "cases": cases})
    if args.expected:
        _dump(args.expected, {"version": 1, "results": results})
    print(f"{len(cases)} cases ({sum(r['first_contact'] is not None for r in results)} collide), "
          f"{sum(len(r['problems']) for r in problems)} disagreements with a second reference (not emitted); "
          f"{time.perf_counter() - t0:.1f} s")
    return 1 if problems else 0


if __name__ == "__main__":
    sys.exit(main())
