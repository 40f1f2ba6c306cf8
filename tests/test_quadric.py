"""Static tests: status, contact point and separating plane of two ellipsoids."""
import numpy as np
import pytest

import mjccd
from mjccd.quadric import quat_to_matrix

ID = [1.0, 0.0, 0.0, 0.0]
rng = np.random.default_rng(3)


def random_quat():
    q = rng.normal(size=4)
    return q / np.linalg.norm(q)


@pytest.mark.parametrize("gap, expected", [(1e-6, "separate"), (0.3, "separate"), (0.0, "touching"),
                                           (-1e-8, "overlapping"), (-0.5, "overlapping")])
def test_status_of_spheres(gap, expected):
    """Spheres of radii 1 and 1/4 at distance 5/4 + gap; (3/4, 1, 0) has length 5/4 exactly in binary."""
    a, b = mjccd.Ellipsoid([1, 1, 1]), mjccd.Ellipsoid([0.25, 0.25, 0.25])
    position = np.array([0.75, 1.0, 0.0]) * (1.0 + gap / 1.25)
    assert mjccd.static_status(a, ([0, 0, 0], random_quat()), b, (position, random_quat())) == expected


def test_status_of_ellipsoids_along_axes():
    a, b = mjccd.Ellipsoid([3, 1, 1]), mjccd.Ellipsoid([1, 2, 1])
    assert mjccd.static_status(a, ([0, 0, 0], ID), b, ([4.001, 0, 0], ID)) == "separate"
    assert mjccd.static_status(a, ([0, 0, 0], ID), b, ([4.0, 0, 0], ID)) == "touching"
    assert mjccd.static_status(a, ([0, 0, 0], ID), b, ([3.999, 0, 0], ID)) == "overlapping"
    # rotate b by 90 degrees about z: its long axis now points along x
    qz = [np.cos(np.pi / 4), 0, 0, np.sin(np.pi / 4)]
    assert mjccd.static_status(a, ([0, 0, 0], ID), b, ([4.5, 0, 0], qz)) == "overlapping"


def test_batch_matches_single():
    K = 200
    ra = rng.uniform(0.2, 1.0, size=(K, 3))
    rb = rng.uniform(0.2, 1.0, size=(K, 3))
    pa = np.hstack([rng.normal(size=(K, 3)), rng.normal(size=(K, 4))])
    pb = np.hstack([rng.normal(size=(K, 3)), rng.normal(size=(K, 4))])
    codes = mjccd.static_status_many(ra, pa, rb, pb)
    names = {1: "separate", 0: "touching", -1: "overlapping"}
    for k in range(K):
        single = mjccd.static_status(mjccd.Ellipsoid(ra[k]), (pa[k, :3], pa[k, 3:]),
                                     mjccd.Ellipsoid(rb[k]), (pb[k, :3], pb[k, 3:]))
        assert names[int(codes[k])] == single
    assert {1, -1} <= set(codes.tolist())


def test_contact_point_of_touching_ellipsoids():
    a, b = mjccd.Ellipsoid([3, 1, 1]), mjccd.Ellipsoid([1, 2, 1])
    p, n = mjccd.contact_point(a, ([0, 0, 0], ID), b, ([4.0, 0, 0], ID))
    assert np.allclose(p, [3, 0, 0], atol=1e-6)
    assert np.allclose(n, [1, 0, 0], atol=1e-6)
    with pytest.raises(ValueError, match="not touching"):
        mjccd.contact_point(a, ([0, 0, 0], ID), b, ([5.0, 0, 0], ID))


def surface_points(radii, pos, quat, n=400):
    v = rng.normal(size=(n, 3))
    v /= np.linalg.norm(v, axis=1, keepdims=True)
    return (quat_to_matrix(np.asarray(quat, float)) @ (v * radii).T).T + pos


def test_separating_plane_separates():
    for _ in range(30):
        ra, rb = rng.uniform(0.3, 1.5, 3), rng.uniform(0.3, 1.5, 3)
        qa, qb = random_quat(), random_quat()
        pa = np.zeros(3)
        direction = rng.normal(size=3)
        direction /= np.linalg.norm(direction)
        pb = direction * (ra.max() + rb.max() + rng.uniform(0.05, 1.0))
        a, b = mjccd.Ellipsoid(ra), mjccd.Ellipsoid(rb)
        plane = mjccd.separating_plane(a, (pa, qa), b, (pb, qb))
        assert np.linalg.norm(plane.normal) == pytest.approx(1.0)
        assert np.all(surface_points(ra, pa, qa) @ plane.normal + plane.offset < 0)
        assert np.all(surface_points(rb, pb, qb) @ plane.normal + plane.offset > 0)


def test_separating_plane_of_spheres_touches_closest_points():
    a, b = mjccd.Ellipsoid([1, 1, 1]), mjccd.Ellipsoid([2, 2, 2])
    plane = mjccd.separating_plane(a, ([0, 0, 0], ID), b, ([5, 0, 0], ID))
    assert np.allclose(plane.point_a, [1, 0, 0], atol=1e-9)
    assert np.allclose(plane.point_b, [3, 0, 0], atol=1e-9)
    assert np.allclose(plane.normal, [1, 0, 0], atol=1e-9)
    with pytest.raises(ValueError, match="not separate"):
        mjccd.separating_plane(a, ([0, 0, 0], ID), b, ([2, 0, 0], ID))


@pytest.mark.parametrize("radii, msg", [([1, 0, 1], "positive"), ([1, -2, 1], "positive"),
                                        ([1, np.nan, 1], "NaN"), ([1, 1], "shape")])
def test_bad_radii(radii, msg):
    with pytest.raises(ValueError, match=msg):
        mjccd.Ellipsoid(radii)


def test_bad_batch_input():
    with pytest.raises(ValueError, match="poses_a"):
        mjccd.static_status_many(np.ones((2, 3)), np.zeros((2, 6)), np.ones((2, 3)), np.zeros((2, 7)))
    poses = np.zeros((2, 7))
    poses[:, 3] = 1.0
    bad = poses.copy()
    bad[1, 3] = 0.0
    with pytest.raises(ValueError, match=r"poses_b\[1\]: zero quaternion"):
        mjccd.static_status_many(np.ones((2, 3)), poses, np.ones((2, 3)), bad)


def test_quartic_max_against_dense_sampling():
    """Maximum and argmax of random Bernstein quartics, including nearly flat ones, against a fine grid."""
    from mjccd.quadric import quartic_max5

    rng = np.random.default_rng(3)
    u = np.linspace(0.0, 1.0, 200001)
    basis = np.stack([(1 - u) ** 4, 4 * u * (1 - u) ** 3, 6 * u ** 2 * (1 - u) ** 2, 4 * u ** 3 * (1 - u), u ** 4])
    for k in range(300):
        g = rng.normal(size=5) * (1e-6 if k % 10 == 0 else 1.0)
        values = g @ basis
        best, at = quartic_max5(*g)
        assert best >= values.max() - 1e-12 * np.abs(g).max()
        assert abs((g @ np.array([(1 - at) ** 4, 4 * at * (1 - at) ** 3, 6 * at ** 2 * (1 - at) ** 2,
                                   4 * at ** 3 * (1 - at), at ** 4])) - best) <= 1e-14 * np.abs(g).max()


def test_null_vector_spans_the_kernel():
    from mjccd.quadric import null_vector

    rng = np.random.default_rng(4)
    for _ in range(50):
        V, _ = np.linalg.qr(rng.normal(size=(4, 4)))
        M = V @ np.diag([*rng.uniform(0.5, 2.0, 3) * rng.choice([-1, 1], 3), 0.0]) @ V.T
        X = null_vector(M)
        assert abs(abs(X @ V[:, 3]) / np.linalg.norm(X) - 1.0) < 1e-12
