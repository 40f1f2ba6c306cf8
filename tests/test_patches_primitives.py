"""Moving Bézier primitives: evaluation, exact subdivision, input checks."""
import numpy as np
import pytest

from mjccd.patches import Patch, subdivision_matrices
from mjccd.patches.ellipsoid import ellipsoid_patches

RNG = np.random.default_rng(12)


def random_patch(kind, degree, rational):
    if kind == "quad":
        shape = (degree[0] + 1, degree[1] + 1)
    elif kind == "triangle":
        n = degree[0]
        shape = ((n + 1) * (n + 2) // 2,)
    else:
        shape = (degree[0] + 1,)
    w = RNG.uniform(0.3, 3.0, shape) if rational else None
    make = {"quad": Patch.quad, "triangle": Patch.triangle, "curve": Patch.curve}[kind]
    return make(RNG.normal(size=shape + (3,)), RNG.normal(size=shape + (3,)), weights=w)


KINDS = [("quad", (n, m)) for n in (1, 2, 3) for m in (1, 2, 3)] + \
        [("triangle", (n,)) for n in (1, 2, 3)] + [("curve", (n,)) for n in (1, 2, 3)]


@pytest.mark.parametrize("kind,degree", KINDS)
@pytest.mark.parametrize("rational", [False, True])
def test_subdivision_reproduces_the_parent(kind, degree, rational):
    parent = random_patch(kind, degree, rational)
    for child, (cu, cv), size, flip in parent.subdivide():
        for _ in range(6):
            s, r = RNG.uniform(0, 1, 2)
            if kind == "triangle" and s + r > 1:
                s, r = 1 - s, 1 - r
            if kind == "curve":
                r = 0.0
            t = RNG.uniform()
            u, v = cu + flip * size * s, cv + flip * size * r
            assert np.allclose(child.evaluate(s, r, t), parent.evaluate(u, v, t), atol=1e-12)


@pytest.mark.parametrize("kind,degree", KINDS)
def test_subdivision_matrices_are_exact_convex_combinations(kind, degree):
    mats = subdivision_matrices(kind, degree)
    assert (mats >= 0).all()
    assert np.array_equal(mats.sum(axis=2), np.ones(mats.shape[:2]))
    scaled = mats * 2.0 ** (3 * max(degree))
    assert np.array_equal(scaled, np.round(scaled))  # dyadic: exact in float64


def test_triangle_children_tile_the_parent():
    tri = random_patch("triangle", (2,), False)
    area = 0.0
    for _, corner, size, flip in tri.subdivide():
        area += 0.5 * size ** 2
        centroid = np.add(corner, flip * size / 3.0)
        assert centroid.min() > 0 and centroid.sum() < 1
    assert area == 0.5


@pytest.mark.parametrize("kind,degree", [("quad", (2, 3)), ("triangle", (3,))])
def test_motion_is_linear_in_time_even_when_rational(kind, degree):
    p = random_patch(kind, degree, True)
    u, v = 0.2, 0.3
    a, b = p.evaluate(u, v, 0.0), p.evaluate(u, v, 1.0)
    for t in (0.25, 0.5, 0.9):
        assert np.allclose(p.evaluate(u, v, t), (1 - t) * a + t * b, atol=1e-12)


def test_corners_and_barycentric_evaluation():
    grid = RNG.normal(size=(3, 4, 3))
    q = Patch.quad(grid)
    assert np.allclose(q.evaluate(0, 0), grid[0, 0])
    assert np.allclose(q.evaluate(1, 0), grid[2, 0])
    assert np.allclose(q.evaluate(0, 1), grid[0, 3])
    assert np.allclose(q.evaluate(1, 1), grid[2, 3])
    # linear triangle, order (w, v, u) vertices: f(u, v) = P_w + u (P_u - P_w) + v (P_v - P_w)
    pts = RNG.normal(size=(3, 3))
    tri = Patch.triangle(pts)
    expect = pts[0] + 0.2 * (pts[2] - pts[0]) + 0.7 * (pts[1] - pts[0])
    assert np.allclose(tri.evaluate(0.2, 0.7), expect)


def test_velocities_equal_end_minus_start():
    p0 = RNG.normal(size=(2, 2, 3))
    vel = RNG.normal(size=(2, 2, 3))
    a = Patch.quad(p0, velocities=vel)
    b = Patch.quad(p0, p0 + vel)
    assert np.array_equal(a.points_t1, b.points_t1)
    assert np.allclose(a.velocities, vel.reshape(4, 3))


def test_ellipsoid_patches_lie_on_the_surface_and_cover_every_octant():
    radii = np.array([0.5, 1.5, 2.0])
    patches = ellipsoid_patches(radii, np.hstack([np.eye(3), np.zeros((3, 1))]))
    assert len(patches) == 8
    signs = set()
    for p in patches:
        assert p.rational and (p.weights > 0).all()
        for u, v in RNG.uniform(0, 1, (25, 2)):
            x = p.evaluate(u, v)
            assert abs(np.sum((x / radii) ** 2) - 1.0) < 1e-13
        signs.add(tuple(np.sign(p.evaluate(0.5, 0.5)).astype(int)))
    assert len(signs) == 8


# ------------------------------------------------------------------- bad input
@pytest.mark.parametrize("w,msg", [(-1.0, "weights must be positive"),
                                   (0.0, "weights must be positive"),
                                   (np.nan, "NaN")])
def test_bad_weights_are_rejected(w, msg):
    weights = np.ones((3, 3))
    weights[1, 1] = w
    with pytest.raises(ValueError, match=msg):
        Patch.quad(np.zeros((3, 3, 3)), weights=weights)


@pytest.mark.parametrize("make,arg,msg", [
    (Patch.quad, np.zeros((5, 2, 3)), r"`quad.points_t0`: expected shape \(n\+1, m\+1, 3\)"),
    (Patch.quad, np.zeros((2, 2)), r"`quad.points_t0`: expected shape"),
    (Patch.triangle, np.zeros((4, 3)), "3, 6 or 10 control points, got 4"),
    (Patch.curve, np.zeros((1, 3)), r"`curve.points_t0`: expected shape \(n\+1, 3\)"),
    (Patch.point, np.zeros(2), r"`point.points_t0`: expected shape \(3,\)"),
    (Patch.quad, np.full((2, 2, 3), np.nan), "`quad.points_t0`: contains NaN or infinity"),
])
def test_bad_shapes_and_nan_are_rejected(make, arg, msg):
    with pytest.raises(ValueError, match=msg):
        make(arg)


def test_mismatched_end_points_and_double_motion_are_rejected():
    with pytest.raises(ValueError, match=r"`quad.points_t1`: expected shape \(2, 2, 3\)"):
        Patch.quad(np.zeros((2, 2, 3)), np.zeros((2, 3, 3)))
    with pytest.raises(ValueError, match="either `points_t1` or `velocities`"):
        Patch.quad(np.zeros((2, 2, 3)), np.zeros((2, 2, 3)), velocities=np.zeros((2, 2, 3)))
    with pytest.raises(ValueError, match=r"`quad.weights`: expected shape \(2, 2\)"):
        Patch.quad(np.zeros((2, 2, 3)), weights=np.ones(4))
    with pytest.raises(ValueError, match="`radii`: must be finite and positive"):
        ellipsoid_patches([1, -1, 1], np.zeros((3, 4)))
    with pytest.raises(ValueError, match=r"`end`: expected a 3x4 matrix"):
        ellipsoid_patches([1, 1, 1], np.zeros((3, 4)), np.zeros((4, 4)))
