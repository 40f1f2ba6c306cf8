"""Patch CCD solver: times of impact by construction, Ours vs Trad, manifolds, limits."""
import numpy as np
import pytest

from mjccd.patches import Patch, contact_manifold, first_contact
from mjccd.patches.bench import table1_case
from mjccd.patches.ellipsoid import ellipsoid_patches

RNG = np.random.default_rng(3)
SWEEP = [1e-12, 1e-9, 1e-6, 1e-3, 0.25, 0.5, 0.999, 1.0]
# the reported time is the start of a candidate interval: never later than the truth,
# earlier by about (margins + accepted box size) / approach speed
EARLY = 1e-5


def flat_quad(x0, x1, y0, y1, z, degree=1):
    u = np.linspace(x0, x1, degree + 1)
    v = np.linspace(y0, y1, degree + 1)
    return np.array([[[a, b, z] for b in v] for a in u])


def assert_bracket(toi, truth, early=EARLY):
    assert truth - early <= toi <= truth + 1e-12, (toi, truth)


@pytest.mark.parametrize("t_star", SWEEP)
@pytest.mark.parametrize("inclusion", ["obb", "aabb"])
def test_parallel_patch_translating_onto_a_patch(t_star, inclusion):
    ground = Patch.quad(flat_quad(-1, 1, -1, 1, 0.0, degree=2))
    start = flat_quad(-0.3, 0.7, -0.4, 0.6, t_star)
    end = flat_quad(-0.3, 0.7, -0.4, 0.6, t_star - 1.0)  # z(t) = t* - t
    c = first_contact(ground, Patch.quad(start, end), inclusion=inclusion)
    assert c is not None and c.status == "converged"
    assert_bracket(c.toi, t_star)
    assert abs(c.point[2]) < 1e-5
    assert -0.3 - 1e-5 <= c.point[0] <= 0.7 + 1e-5


@pytest.mark.parametrize("t_star", [1e-12, 1e-6, 0.3, 0.75, 1.0])
@pytest.mark.parametrize("tilt", [False, True])
def test_sphere_as_patches_against_a_plane(t_star, tilt):
    r, drop = 0.4, 0.8
    rot = np.eye(3)
    if tilt:  # move the patch poles away from the contact point
        c, s = np.cos(0.7), np.sin(0.7)
        rot = np.array([[1, 0, 0], [0, c, -s], [0, s, c]]) @ np.array(
            [[c, 0, s], [0, 1, 0], [-s, 0, c]])
    centre0 = np.array([0.1, -0.2, r + drop * t_star])
    centre1 = centre0 - [0.0, 0.0, drop]  # lowest point at drop (t* - t)
    sphere = ellipsoid_patches([r] * 3, np.hstack([rot, centre0[:, None]]),
                               np.hstack([rot, centre1[:, None]]))
    plane = Patch.quad(flat_quad(-2, 2, -2, 2, 0.0))
    c = first_contact(sphere, plane)
    assert c is not None
    assert_bracket(c.toi, t_star)
    assert np.allclose(c.point, [0.1, -0.2, 0.0], atol=2e-3)


@pytest.mark.parametrize("gap,expect", [(0.0, 2 / 3), (-1e-3, 2 / 3), (1e-3, None)])
def test_patch_grazing_an_edge(gap, expect):
    # a vertical square slides along -x; its bottom edge sits at z = gap, level with a
    # flat square whose boundary edge x = 1 it reaches at t = 2/3
    ground = Patch.quad(flat_quad(0, 1, 0, 1, 0.0))

    def wall(x):
        return np.array([[[x, 0.2, gap], [x, 0.2, gap + 1]], [[x, 0.8, gap], [x, 0.8, gap + 1]]])
    c = first_contact(ground, Patch.quad(wall(2.0), wall(0.5)))
    if expect is None:
        assert c is None
    else:
        assert c is not None
        assert_bracket(c.toi, expect)
        assert abs(c.point[0] - 1.0) < 1e-5


def test_touching_at_the_start_reports_zero():
    a = Patch.quad(flat_quad(0, 1, 0, 1, 0.0))
    b = Patch.triangle([[0.5, 0.5, 0.0], [0.5, 0.5, 1.0], [2.0, 0.5, 1.0]],
                       velocities=np.tile([0.0, 0.0, 1.0], (3, 1)))
    for method in ("ours", "trad"):
        c = first_contact(a, b, method=method)
        assert c is not None and c.toi == 0.0


def test_separating_or_distant_patches_report_none():
    a = Patch.quad(flat_quad(0, 1, 0, 1, 0.0))
    b = Patch.quad(flat_quad(0, 1, 0, 1, 0.1), flat_quad(0, 1, 0, 1, 0.5))
    assert first_contact(a, b) is None
    assert first_contact(a, b, method="trad") is None
    far = Patch.quad(flat_quad(5, 6, 0, 1, 0.0), flat_quad(3, 4, 0, 1, 0.0))
    assert first_contact(a, far) is None


def test_t_max_limits_the_query():
    a = Patch.quad(flat_quad(0, 1, 0, 1, 0.0))
    b = Patch.quad(flat_quad(0, 1, 0, 1, 0.5), flat_quad(0, 1, 0, 1, -0.5))
    assert first_contact(a, b, t_max=0.4) is None
    assert_bracket(first_contact(a, b, t_max=0.6).toi, 0.5)


def test_iteration_limit_is_a_status_with_a_lower_bound():
    a = Patch.quad(flat_quad(0, 1, 0, 1, 0.0))
    b = Patch.quad(flat_quad(0.2, 1, 0, 1, 0.5), flat_quad(0.2, 1, 0, 1, -0.5))
    c = first_contact(a, b, max_iterations=3)
    assert c.status == "max_iterations" and c.toi <= 0.5 and np.isnan(c.params[0])


# ----------------------------------------------------------- random Table-1 cases
def triangles_intersect(p, q):
    """Exact-enough test for two triangles (3, 3) in general position."""
    def seg_tri(a, b, tri):
        n = np.cross(tri[1] - tri[0], tri[2] - tri[0])
        da, db = (a - tri[0]) @ n, (b - tri[0]) @ n
        if da * db > 0 or da == db:
            return False
        x = a + (b - a) * (da / (da - db))
        signs = [np.cross(tri[(k + 1) % 3] - tri[k], x - tri[k]) @ n for k in range(3)]
        return all(s >= 0 for s in signs) or all(s <= 0 for s in signs)
    return any(seg_tri(p[i], p[(i + 1) % 3], q) for i in range(3)) or any(
        seg_tri(q[i], q[(i + 1) % 3], p) for i in range(3))


def test_linear_triangles_ours_matches_trad_and_dense_sampling():
    rng = np.random.default_rng(11)
    hits = 0
    for _ in range(30):
        a, b = table1_case(rng, "triangle", 1)
        ours = first_contact(a, b, delta=1e-5)
        trad = first_contact(a, b, method="trad", delta=1e-5)
        assert (ours is None) == (trad is None)
        t_end = 1.0 if ours is None else ours.toi
        for t in np.linspace(0.0, t_end, 100)[:-1] if t_end > 0 else []:
            assert not triangles_intersect(a.control_points(t)[[0, 1, 2]],
                                           b.control_points(t)[[0, 1, 2]])
        if ours is not None:
            hits += 1
            assert abs(ours.toi - trad.toi) < 1e-3
            # at the reported time the two points are (nearly) the same
            pa = a.evaluate(ours.params[0], ours.params[1], ours.toi)
            pb = b.evaluate(ours.params[2], ours.params[3], ours.toi)
            assert np.linalg.norm(pa - pb) < 1e-3
    assert 8 < hits < 30


def surface_mesh(patch, n, t):
    """(T, 3, 3) triangles of the patch at time t over a regular n x n parameter grid."""
    if patch.kind == "quad":
        uv = [(i / n, j / n) for i in range(n + 1) for j in range(n + 1)]
        tris = []
        for i in range(n):
            for j in range(n):
                a, b = i * (n + 1) + j, (i + 1) * (n + 1) + j
                tris += [(a, b, b + 1), (a, b + 1, a + 1)]
    else:
        uv, pos = [], {}
        for i in range(n + 1):
            for j in range(n + 1 - i):
                pos[i, j] = len(uv)
                uv.append((i / n, j / n))
        tris = []
        for i in range(n):
            for j in range(n - i):
                tris.append((pos[i, j], pos[i + 1, j], pos[i, j + 1]))
                if i + j + 2 <= n:
                    tris.append((pos[i + 1, j], pos[i + 1, j + 1], pos[i, j + 1]))
    pts = np.array([patch.evaluate(u, v, t) for u, v in uv])
    return pts[np.array(tris)]


def _edges_cross(tri_e, tri_f):
    """Per pair k: does an edge of triangle tri_e[k] cross triangle tri_f[k]? (K, 3, 3) each."""
    p, q, r = (tri_f[:, None, c] for c in range(3))
    a = tri_e
    b = tri_e[:, [1, 2, 0]]
    n = np.cross(q - p, r - p)
    da = np.einsum("kec,kec->ke", a - p, n)
    db = np.einsum("kec,kec->ke", b - p, n)
    cross = da * db < 0
    with np.errstate(invalid="ignore", divide="ignore"):
        x = a + (b - a) * (da / (da - db))[..., None]
    s = [np.einsum("kec,kec->ke", np.cross(v1 - v0, x - v0), n)
         for v0, v1 in ((p, q), (q, r), (r, p))]
    inside = ((s[0] >= 0) & (s[1] >= 0) & (s[2] >= 0)) | ((s[0] <= 0) & (s[1] <= 0) & (s[2] <= 0))
    return bool(np.any(cross & inside))


def meshes_intersect(ma, mb):
    """Do two triangle meshes intersect (an edge of one crosses a triangle of the other)?"""
    lo_a, hi_a = ma.min(axis=1), ma.max(axis=1)
    lo_b, hi_b = mb.min(axis=1), mb.max(axis=1)
    near = np.all((lo_a[:, None] <= hi_b[None]) & (lo_b[None] <= hi_a[:, None]), axis=2)
    i, j = np.nonzero(near)
    if len(i) == 0:
        return False
    return _edges_cross(ma[i], mb[j]) or _edges_cross(mb[j], ma[i])


def sampled_contact_time(a, b, ts, coarse=8, fine=32):
    """First sampled time at which the two surfaces intersect, or None.

    Surface points move linearly in time (the weights are fixed), so the meshes at t are
    interpolated from t = 0 and t = 1. A coarse-mesh hit is confirmed on a fine mesh, so a
    chord-error artefact near a real contact does not count.
    """
    ends = {n: [surface_mesh(p, n, t) for p in (a, b) for t in (0.0, 1.0)]
            for n in (coarse, fine)}

    def hit(n, t):
        a0, a1, b0, b1 = ends[n]
        return meshes_intersect((1 - t) * a0 + t * a1, (1 - t) * b0 + t * b1)
    for t in np.unique(ts):
        if hit(coarse, t) and hit(fine, t):
            return t
    return None


@pytest.mark.parametrize("kind,order", [(k, n) for k in ("triangle", "quad") for n in (1, 2, 3)])
def test_random_table1_cases_ours_trad_and_dense_sampling_agree(kind, order):
    """Table 1 protocol cases: same collide / not and time for Ours and Trad.; no sampled
    intersection of the two surfaces before the reported time, and one shortly after it
    is not required (grazing contacts exist) but the reported parameters must touch."""
    rng = np.random.default_rng(100 + 10 * order + (kind == "quad"))
    hits = 0
    for _ in range(6):
        a, b = table1_case(rng, kind, order)
        ours = first_contact(a, b, delta=1e-4)
        trad = first_contact(a, b, method="trad", delta=1e-4, max_iterations=200_000)
        assert trad is None or trad.status == "converged"
        assert (ours is None) == (trad is None)
        if ours is None:
            assert sampled_contact_time(a, b, np.linspace(0.0, 1.0, 13)) is None
            continue
        hits += 1
        assert ours.status == "converged"
        # both are lower bounds, each earlier than the truth by about delta-sized boxes
        assert abs(ours.toi - trad.toi) < 5e-4, (ours.toi, trad.toi)
        pa = a.evaluate(ours.params[0], ours.params[1], ours.toi)
        pb = b.evaluate(ours.params[2], ours.params[3], ours.toi)
        assert np.linalg.norm(pa - pb) < 1e-3
        ts = np.linspace(0.0, ours.toi, 13)[:-1] if ours.toi > 0 else []  # touching at 0
        assert sampled_contact_time(a, b, ts) is None, ours.toi
    assert hits >= 2


def test_paper_frames_at_the_step_start_give_the_same_answers():
    """obb_frames="step" (frames from the shape at t = 0, the paper's rule) is just another
    conservative axis choice: same collide / not and times as the default."""
    rng = np.random.default_rng(8)
    for kind, order in (("quad", 1), ("triangle", 2)):
        for _ in range(6):
            a, b = table1_case(rng, kind, order)
            ref = first_contact(a, b, delta=1e-5)
            step = first_contact(a, b, delta=1e-5, obb_frames="step")
            assert (ref is None) == (step is None)
            if ref is not None:
                assert abs(ref.toi - step.toi) < 1e-4


# ----------------------------------------------------------------- manifold mode
def test_face_contact_manifold_spreads_points_over_the_overlap():
    a = Patch.quad(flat_quad(0, 1, 0, 1, 0.0))
    b = Patch.quad(flat_quad(0.25, 1.25, 0, 1, 0.5), flat_quad(0.25, 1.25, 0, 1, -0.5))
    points, stats = contact_manifold(a, b, simultaneity=1e-3, separation=0.2)
    assert stats.status in ("no_contact", "converged")
    assert len(points) >= 8
    xyz = np.array([p.point for p in points])
    d = np.linalg.norm(xyz[:, None] - xyz[None], axis=2) + np.eye(len(xyz)) * 9
    assert d.min() >= 0.2 - 1e-3
    assert all(0.5 - EARLY <= p.toi <= 0.5 + 1e-3 for p in points)
    assert (xyz[:, 0] >= 0.25 - 1e-3).all() and (xyz[:, 0] <= 1 + 1e-3).all()


def test_point_contact_manifold_has_one_point():
    sphere = ellipsoid_patches([0.3] * 3, np.hstack([np.eye(3), [[0.05], [0.02], [1.0]]]),
                               np.hstack([np.eye(3), [[0.05], [0.02], [0.0]]]))
    plane = Patch.quad(flat_quad(-1, 1, -1, 1, 0.0))
    points, _ = contact_manifold(sphere, plane, simultaneity=1e-3, separation=0.05)
    assert len(points) == 1
    assert_bracket(points[0].toi, 0.7)


# ----------------------------------------------------------------- options
@pytest.mark.parametrize("kw,msg", [
    ({"method": "fast"}, "`method`: expected one of"),
    ({"inclusion": "sphere"}, "`inclusion`: expected 'obb' or 'aabb'"),
    ({"delta": 0.0}, "`delta`: expected a positive number"),
    ({"delta": float("nan")}, "`delta`: expected a positive number"),
    ({"t_max": 2.0}, "`t_max`: the motion is defined on"),
    ({"margin": -1.0}, "`margin`: expected a non-negative number"),
    ({"max_iterations": 0}, "`max_iterations`: expected a positive integer"),
    ({"obb_frames": "end"}, "`obb_frames`: expected 'interval' or 'step'"),
    ({"queue": "lifo"}, "`queue`: expected 'depth' or 'time'"),
])
def test_bad_options_are_rejected(kw, msg):
    a = Patch.quad(flat_quad(0, 1, 0, 1, 0.0))
    with pytest.raises(ValueError, match=msg):
        first_contact(a, a, **kw)


def test_bad_sets_are_rejected():
    a = Patch.quad(flat_quad(0, 1, 0, 1, 0.0))
    t = Patch.triangle(np.eye(3))
    with pytest.raises(ValueError, match=r"`b\[1\]`: all primitives of one side"):
        first_contact(a, [a, t])
    with pytest.raises(ValueError, match=r"`a\[0\]`: expected a Patch"):
        first_contact([np.zeros(3)], a)
