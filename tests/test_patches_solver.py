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


@pytest.mark.parametrize("kind,order", [("quad", 1), ("triangle", 2)])
def test_curved_random_cases_ours_and_trad_agree(kind, order):
    rng = np.random.default_rng(21)
    for _ in range(12):
        a, b = table1_case(rng, kind, order)
        ours = first_contact(a, b, delta=1e-4)
        trad = first_contact(a, b, method="trad", delta=1e-4, max_iterations=200_000)
        assert trad is None or trad.status == "converged"
        assert (ours is None) == (trad is None)
        if ours is not None:
            assert abs(ours.toi - trad.toi) < 2e-3
            # no contact before the reported time on a sampled grid of both patches
            uv = np.linspace(0, 1, 9)
            grid = [(u, v) for u in uv for v in uv if kind == "quad" or u + v <= 1]
            for t in np.linspace(0, ours.toi, 5)[:-1]:
                pa = np.array([a.evaluate(u, v, t) for u, v in grid])
                pb = np.array([b.evaluate(u, v, t) for u, v in grid])
                assert np.min(np.linalg.norm(pa[:, None] - pb[None], axis=2)) > 0.0


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
