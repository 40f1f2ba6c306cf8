"""Correctness of the benchmark peers on pairs with a closed-form first contact."""

import math

import numpy as np
import pytest

from mjccd.bench import peers

IDENTITY = [1.0, 0.0, 0.0, 0.0]
needs_fcl = pytest.mark.skipif(not peers.fcl_available(), reason=peers.FCL_SKIP_MESSAGE)


def sphere_query(ra, rb, pa0, pa1, pb0, pb1, qa=(IDENTITY, IDENTITY), qb=(IDENTITY, IDENTITY)):
    return peers.RigidQuery([ra] * 3, [pa0, pa1], qa, [rb] * 3, [pb0, pb1], qb)


def sphere_toi(ra, rb, pa0, pa1, pb0, pb1):
    """Smallest t in [0, 1] with |d0 + t v| = ra + rb, or None."""
    d0 = np.subtract(pb0, pa0)
    v = np.subtract(pb1, pb0) - np.subtract(pa1, pa0)
    a, b, c = v @ v, 2 * d0 @ v, d0 @ d0 - (ra + rb) ** 2
    disc = b * b - 4 * a * c
    if c <= 0:
        return 0.0
    if a == 0 or disc < 0:
        return None
    t = (-b - math.sqrt(disc)) / (2 * a)
    return t if 0 <= t <= 1 else None


SPHERE_CASES = [
    (0.5, 0.7, [-3.0, 0.1, 0.0], [1.0, 0.1, 0.0], [2.0, 0.0, 0.0], [1.5, 0.3, 0.2]),
    (1.0, 0.3, [0.0, 0.0, 0.0], [0.0, 0.0, 0.0], [0.0, 5.0, 0.0], [0.2, -1.0, 0.1]),
    (0.4, 0.4, [1.0, 1.0, 1.0], [-1.0, -1.0, -0.5], [-2.0, -2.0, 2.0], [3.0, 3.0, -2.5]),
    (0.5, 0.5, [0.0, 0.0, 0.0], [4.0, 0.0, 0.0], [0.0, 1.5, 0.0], [4.0, 1.5, 0.0]),  # no hit
]


@pytest.mark.parametrize("case", SPHERE_CASES)
def test_mujoco_sampling_matches_closed_form(case):
    expected = sphere_toi(*case)
    toi, calls = peers.mujoco_sampling_first_contact(sphere_query(*case), 100, tol=1e-10)
    if expected is None:
        assert toi is None and calls == 101
    else:
        assert toi == pytest.approx(expected, abs=1e-8)
        assert toi >= expected - 1e-12
        assert calls > 1


@needs_fcl
@pytest.mark.parametrize("case", SPHERE_CASES)
@pytest.mark.parametrize("n", [100, 1000])
def test_fcl_naive_is_first_sample_after_contact(case, n):
    expected = sphere_toi(*case)
    query = sphere_query(*case)
    assert not query.rotates
    toi = peers.fcl_first_contact(query, n)
    if expected is None:
        assert toi is None
    else:
        assert expected - 1e-9 <= toi <= expected + 1.0 / n + 1e-9


@needs_fcl
def test_fcl_sampled_on_own_motion_matches_naive_grid():
    case = SPHERE_CASES[0]
    expected = sphere_toi(*case)
    toi, calls = peers.FclSampledPair(sphere_query(*case)).first_contact(100)
    assert toi == pytest.approx(math.ceil(expected * 100) / 100, abs=1e-12)
    assert calls == round(toi * 100) + 1


def test_mujoco_sampling_with_rotation_stops_on_the_surface():
    # A rod turning about z sweeps into a sphere that a translation alone would miss.
    half = math.sqrt(0.5)
    query = peers.RigidQuery([2.0, 0.1, 0.1], [[0, 0, 0], [0, 0, 0]],
                             [IDENTITY, [half, 0, 0, half]],
                             [0.3] * 3, [[0, 1.6, 0], [0, 1.6, 0]], [IDENTITY, IDENTITY])
    pair = peers.MujocoDistancePair(query)
    toi, _ = pair.first_contact(50, tol=1e-10)
    assert 0 < toi < 1
    assert pair.distance(toi) <= 0
    assert pair.distance(toi - 1e-9) > 0
    assert all(pair.distance(t) > 0 for t in np.linspace(0, toi - 1e-6, 200))


def test_rigid_pose_is_mjccd_quaternion_lerp():
    q0 = np.array([1.0, 0.0, 0.0, 0.0])
    q1 = -np.array([math.cos(0.6), 0.0, 0.0, math.sin(0.6)])  # sign flipped on purpose
    p, q = peers.rigid_pose(np.zeros((2, 3)), np.array([q0, q1]), 0.5)
    lerp = 0.5 * q0 - 0.5 * q1
    np.testing.assert_allclose(q, lerp / np.linalg.norm(lerp))
    ps, qs = peers.rigid_pose(np.zeros((2, 3)), np.array([q0, q1]), np.array([0.0, 1.0]))
    np.testing.assert_allclose(qs[0], q0)
    np.testing.assert_allclose(qs[1], -q1)


def test_fcl_linear_pose_turns_at_constant_rate_on_the_same_great_circle():
    angle = 2.0
    q1 = [math.cos(angle / 2), 0.0, math.sin(angle / 2), 0.0]
    quats = np.array([IDENTITY, q1])
    _, q = peers.fcl_linear_pose(np.zeros((2, 3)), quats, 0.25)
    np.testing.assert_allclose(q, [math.cos(angle / 8), 0, math.sin(angle / 8), 0], atol=1e-15)
    _, q_mj = peers.rigid_pose(np.zeros((2, 3)), quats, 0.25)
    assert abs(q_mj[0] * q[2] - q_mj[2] * q[0]) > 1e-3  # same axis, different angle


def test_from_case_reads_static_and_rigid_bodies():
    case = {"id": "c1",
            "a": {"radii": [1, 2, 3], "motion": {"type": "static", "position": [1, 0, 0],
                                                 "quaternion": IDENTITY}},
            "b": {"radii": [1, 1, 1], "motion": {
                "type": "rigid",
                "start": {"position": [0, 0, 0], "quaternion": IDENTITY},
                "end": {"position": [1, 1, 1], "quaternion": [0, 1, 0, 0]}}}}
    query = peers.RigidQuery.from_case(case)
    assert query.name == "c1" and query.rotates
    np.testing.assert_array_equal(query.position_a, [[1, 0, 0], [1, 0, 0]])
    case["b"]["motion"]["type"] = "affine"
    with pytest.raises(ValueError, match=r"c1: b.motion.type must be 'static' or 'rigid'"):
        peers.RigidQuery.from_case(case)


def test_score_counts_each_kind_of_wrong_answer():
    result = peers.score([None, 0.5, 0.3, 0.2 + 1e-7, None], [0.1, None, 0.31, 0.2, None])
    assert result == {"n_wrong": 3, "n_missed": 1, "n_false": 1,
                      "max_dt": pytest.approx(0.01)}


def test_peer_table_rows_on_random_translations():
    queries = peers.random_rigid_queries(4, seed=3)
    pairs = [peers.MujocoDistancePair(q) for q in queries]
    reference = [p.first_contact(2000, tol=1e-12)[0] for p in pairs]
    rows = peers.peer_table(queries, reference, n_list=(50,), repeats=1)
    by_name = {r["name"]: r for r in rows}
    mj = by_name["MuJoCo mj_geomDistance, 50 samples + bisection"]
    assert mj["n_false"] == 0 and mj["median_us"] > 0
    assert mj["max_dt"] < 1e-6 or mj["n_missed"] > 0
    fcl_row = by_name["python-fcl naive, 50 steps"]
    if peers.fcl_available():
        assert fcl_row["n_false"] == 0 and fcl_row["max_dt"] <= 1 / 50 + 1e-9
    else:
        assert fcl_row["note"] == peers.FCL_SKIP_MESSAGE and fcl_row["median_us"] is None
    assert "| peer |" in peers.markdown_table(rows)
