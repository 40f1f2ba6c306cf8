"""The exact solver against closed forms, the thesis' example and constructed contacts."""
import json
import os
import subprocess
import sys

import numpy as np
import pytest

import mjccd

ID = [1.0, 0.0, 0.0, 0.0]
rng = np.random.default_rng(11)
HERE = os.path.dirname(os.path.abspath(__file__))


def random_quat():
    q = rng.normal(size=4)
    return q / np.linalg.norm(q)


def sphere_times(c0, c1, cb, r):
    """Closed-form entry and exit times of |c(t) - cb| = r for a linearly moving centre."""
    d0 = np.asarray(c0) - cb
    v = np.asarray(c1) - np.asarray(c0)
    qa, qb, qc = v @ v, 2 * d0 @ v, d0 @ d0 - r * r
    disc = qb * qb - 4 * qa * qc
    if disc < 0:
        return None
    s = np.sqrt(disc)
    return (-qb - s) / (2 * qa), (-qb + s) / (2 * qa)


@pytest.mark.parametrize("seed", range(12))
def test_spheres_closed_form(seed):
    r = np.random.default_rng(seed)
    ra, rb = r.uniform(0.1, 1.0, 2)
    cb = r.normal(size=3)
    c0 = cb + r.normal(size=3) * 3
    c1 = cb + r.normal(size=3) * 3
    a = mjccd.Ellipsoid([ra] * 3)
    b = mjccd.Ellipsoid([rb] * 3)
    ma = mjccd.Rigid(c0, random_quat(), c1, random_quat())  # rotation is irrelevant for a sphere
    mb = mjccd.Static(cb, random_quat())
    times = sphere_times(c0, c1, cb, ra + rb)
    status0 = mjccd.static_status(a, (c0, ID), b, (cb, ID))
    intervals = mjccd.collision_intervals(a, ma, b, mb)
    contact = mjccd.first_contact(a, ma, b, mb)
    if status0 != "separate":
        pytest.skip("random start overlaps")
    if times is None or times[0] > 1 or times[1] < 0:
        assert contact is None and intervals == []
        return
    t_in, t_out = times
    assert contact.time == pytest.approx(t_in, abs=1e-9)
    assert len(intervals) == 1
    assert intervals[0][0] == pytest.approx(t_in, abs=1e-9)
    assert intervals[0][1] == pytest.approx(min(t_out, 1.0), abs=1e-9)
    c_t = np.asarray(c0) + t_in * (np.asarray(c1) - c0)
    expected_point = c_t + ra * (cb - c_t) / np.linalg.norm(cb - c_t)
    assert np.allclose(contact.point, expected_point, atol=1e-7)
    assert np.allclose(contact.normal, (cb - c_t) / np.linalg.norm(cb - c_t), atol=1e-7)


def test_sphere_passes_through_within_one_step():
    a, b = mjccd.Ellipsoid([0.1] * 3), mjccd.Ellipsoid([0.05] * 3)
    ma = mjccd.Rigid([-1, 0.02, 0], ID, [1, 0.02, 0], ID)
    mb = mjccd.Static([0, 0, 0])
    t_in, t_out = sphere_times([-1, 0.02, 0], [1, 0.02, 0], np.zeros(3), 0.15)
    (got_in, got_out), = mjccd.collision_intervals(a, ma, b, mb)
    assert got_in == pytest.approx(t_in, abs=1e-9)
    assert got_out == pytest.approx(t_out, abs=1e-9)


@pytest.mark.parametrize("t_star", [1e-12, 1e-9, 1e-6, 1e-3, 0.1, 0.5, 0.9, 1 - 1e-9, 1.0])
def test_known_contact_time_sweep(t_star):
    """Ellipsoids placed so that they touch exactly at t_star while translating."""
    a, b = mjccd.Ellipsoid([0.6, 0.3, 0.2]), mjccd.Ellipsoid([0.2, 0.5, 0.4])
    # along x they touch when the centres are 0.8 apart
    speed = 1.0
    x0 = -(0.8 + speed * t_star)
    ma = mjccd.Rigid([x0, 0, 0], ID, [x0 + speed, 0, 0], ID)
    mb = mjccd.Static([0, 0, 0])
    contact = mjccd.first_contact(a, ma, b, mb)
    assert contact is not None
    assert contact.time == pytest.approx(t_star, abs=1e-9)
    if contact.status_at_start == "separate":
        assert np.allclose(contact.point, [-0.2, 0, 0], atol=1e-6)
    else:  # a gap of 1e-12 at the start is inside the touching band
        assert t_star < 1e-9 and contact.status_at_start == "touching"


def test_thesis_example_5_1():
    with open(os.path.join(HERE, "data", "public_cases.json")) as fh:
        cases = {c["id"]: c for c in json.load(fh)["cases"]}
    result = mjccd.solve_cases({"version": 1, "cases": [cases["pub-thesis-5.1"]]})["results"][0]
    assert result["first_contact"] == pytest.approx(0.5, abs=1e-9)
    assert np.allclose(result["contact_point"], [np.sqrt(2), 0, np.sqrt(2)], atol=1e-6)


def test_start_touching_and_overlapping():
    a, b = mjccd.Ellipsoid([1, 1, 1]), mjccd.Ellipsoid([1, 1, 1])
    touching = mjccd.first_contact(a, mjccd.Rigid([0, 0, 0], ID, [-1, 0, 0], ID), b, mjccd.Static([2, 0, 0]))
    assert touching.time == 0.0 and touching.status_at_start == "touching"
    over = mjccd.first_contact(a, mjccd.Rigid([0, 0, 0], ID, [-5, 0, 0], ID), b, mjccd.Static([1, 0, 0]))
    assert over.time == 0.0 and over.status_at_start == "overlapping" and over.point is None
    (t0, t1), = mjccd.collision_intervals(a, mjccd.Rigid([0, 0, 0], ID, [-5, 0, 0], ID), b, mjccd.Static([1, 0, 0]))
    assert t0 == 0.0 and t1 == pytest.approx(0.2, abs=1e-9)  # centres 2 apart at t = 0.2


@pytest.mark.parametrize("gap, hits", [(1e-6, False), (-1e-8, True)])
def test_near_miss_and_shallow_graze(gap, hits):
    """Sphere sliding past: closest distance ra + rb + gap (in units of the size 1)."""
    a, b = mjccd.Ellipsoid([1, 1, 1]), mjccd.Ellipsoid([1, 1, 1])
    y = 2.0 + gap
    ma = mjccd.Rigid([-3, y, 0], ID, [3, y, 0], ID)
    contact = mjccd.first_contact(a, ma, b, mjccd.Static([0, 0, 0]))
    assert (contact is not None) == hits
    if hits:
        expected = 0.5 - np.sqrt(4 - y * y) / 6
        assert contact.time == pytest.approx(expected, abs=1e-6)


def _hinge_angle(t, a0, a1):
    return 2 * np.arctan((1 - t) * np.tan(a0 / 2) + t * np.tan(a1 / 2))


def test_intervals_of_a_spinning_ellipsoid():
    """A long ellipsoid spinning about z sweeps a sphere once or twice, symmetrically in angle."""
    a, b = mjccd.Ellipsoid([2, 0.2, 0.2]), mjccd.Ellipsoid([0.3] * 3)
    chain = mjccd.Chain([mjccd.Hinge([0, 0, 1], -2.0, 2.0)])
    (t_in, t_out), = mjccd.collision_intervals(a, chain, b, mjccd.Static([1.5, 0, 0]))
    assert _hinge_angle(t_in, -2, 2) == pytest.approx(-_hinge_angle(t_out, -2, 2), abs=1e-8)
    assert -1.0 < _hinge_angle(t_in, -2, 2) < 0.0
    two = mjccd.collision_intervals(a, chain, b, mjccd.Static([0, 1.5, 0]))
    assert len(two) == 2
    angles = [_hinge_angle(t, -2, 2) for iv in two for t in iv]
    assert angles[0] + np.pi / 2 == pytest.approx(-(angles[1] + np.pi / 2), abs=1e-8)
    assert angles[2] - np.pi / 2 == pytest.approx(-(angles[3] - np.pi / 2), abs=1e-8)


def test_slide_chain_equals_translation():
    a, b = mjccd.Ellipsoid([0.3, 0.2, 0.2]), mjccd.Ellipsoid([0.25] * 3)
    chain = mjccd.Chain([mjccd.Fixed([-2, 0.1, 0]), mjccd.Slide([2, 0, 0], 0.0, 3.0)])
    rigid = mjccd.Rigid([-2, 0.1, 0], ID, [1, 0.1, 0], ID)
    mb = mjccd.Static([0, 0, 0])
    assert np.allclose(mjccd.collision_intervals(a, chain, b, mb), mjccd.collision_intervals(a, rigid, b, mb), atol=1e-12)
    with pytest.raises(ValueError, match="displacement"):
        mjccd.Slide([1, 0, 0], 0.0, float("nan"))


def test_t_max_bounds_the_search():
    a, b = mjccd.Ellipsoid([0.5] * 3), mjccd.Ellipsoid([0.5] * 3)
    ma = mjccd.Rigid([-3, 0, 0], ID, [0, 0, 0], ID)
    mb = mjccd.Static([0, 0, 0])
    full = mjccd.first_contact(a, ma, b, mb)
    assert full.time == pytest.approx(2 / 3, abs=1e-12)
    assert mjccd.first_contact(a, ma, b, mb, t_max=0.6) is None
    assert mjccd.first_contact(a, ma, b, mb, t_max=0.7).time == pytest.approx(2 / 3, abs=1e-12)


def test_chain_equals_equivalent_rigid_motion():
    """A ball joint behind a fixed offset is the rigid motion of that pose."""
    a, b = mjccd.Ellipsoid([0.5, 0.2, 0.3]), mjccd.Ellipsoid([0.4, 0.4, 0.2])
    q0, q1 = random_quat(), random_quat()
    chain = mjccd.Chain([mjccd.Fixed([0.3, 0.1, 0]), mjccd.Ball(q0, q1)])
    rigid = mjccd.Rigid([0.3, 0.1, 0], q0, [0.3, 0.1, 0], q1)
    mb = mjccd.Rigid([1.5, 0, 0], ID, [0.4, 0.2, 0], ID)
    got = np.array(mjccd.collision_intervals(a, chain, b, mb))
    want = np.array(mjccd.collision_intervals(a, rigid, b, mb))
    assert len(want) >= 1 and got.shape == want.shape
    assert np.allclose(got, want, atol=1e-10)


# ---------------------------------------------------------------- bad input


@pytest.mark.parametrize("make, msg", [
    (lambda: mjccd.Rigid([0, 0, np.nan], ID, [0, 0, 0], ID), "start.position: contains NaN"),
    (lambda: mjccd.Rigid([0, 0, 0], [0, 0, 0, 0], [0, 0, 0], ID), "start.quaternion: zero quaternion"),
    (lambda: mjccd.Static([0, 0], ID), "position: expected shape 3"),
    (lambda: mjccd.LinearAffine(np.eye(3, 4), np.zeros((3, 4))), "becomes singular"),
    (lambda: mjccd.Rational([[[1], [1], [0]], [[0], [1], [0]], [[0], [0], [1]]], [1], [[0], [0], [0]], [1]),
     "rotation: not orthogonal"),
    (lambda: mjccd.Rational([[[1], [0], [0]], [[0], [1], [0]], [[0], [0], [1]]], [1, -2], [[0], [0], [0]], [1]),
     "rotation_denominator: vanishes"),
    (lambda: mjccd.Hinge([0, 0, 1], 0.0, 3.5), "angle"),
    (lambda: mjccd.Hinge([0, 0, 0], 0.0, 1.0), "axis: zero vector"),
    (lambda: mjccd.Chain([]), "at least one element"),
])
def test_bad_motion_input(make, msg):
    with pytest.raises(ValueError, match=msg):
        make()


def test_bad_api_arguments():
    a = mjccd.Ellipsoid([1, 1, 1])
    m = mjccd.Static([0, 0, 0])
    with pytest.raises(ValueError, match="t_max"):
        mjccd.first_contact(a, m, a, mjccd.Static([3, 0, 0]), t_max=1.5)
    with pytest.raises(ValueError, match="motion_b"):
        mjccd.first_contact(a, m, a, "static")
    with pytest.raises(ValueError, match="a: expected an mjccd.Ellipsoid"):
        mjccd.first_contact([1, 1, 1], m, a, m)


def _case(cid, **override):
    case = {"id": cid,
            "a": {"radii": [1, 1, 1], "motion": {"type": "rigid",
                                                 "start": {"position": [-3, 0, 0], "quaternion": ID},
                                                 "end": {"position": [3, 0, 0], "quaternion": ID}}},
            "b": {"radii": [1, 1, 1], "motion": {"type": "static", "position": [0, 0, 0], "quaternion": ID}}}
    for path, value in override.items():
        node = case
        keys = path.split("__")
        for k in keys[:-1]:
            node = node[k]
        node[keys[-1]] = value
    return case


def test_solve_cases_reports_bad_cases_and_solves_the_rest():
    doc = {"version": 1, "cases": [
        _case("good"),
        _case("neg-radius", a__radii=[1, -1, 1]),
        _case("zero-quat", b__motion__quaternion=[0, 0, 0, 0]),
        _case("no-motion", b__motion__type="teleport"),
        {"id": "missing-b", "a": _case("x")["a"]},
    ]}
    results = {r["id"]: r for r in mjccd.solve_cases(doc)["results"]}
    assert results["good"]["first_contact"] == pytest.approx(1 / 6, abs=1e-12)
    assert results["neg-radius"]["error"] == "neg-radius: a.radii: radii must be positive, got [1.0, -1.0, 1.0]"
    assert results["zero-quat"]["error"].startswith("zero-quat: b.motion.quaternion: zero quaternion")
    assert "b.motion.type: unknown motion type 'teleport'" in results["no-motion"]["error"]
    assert results["missing-b"]["error"] == "missing-b: case.b: missing"


def run_cli(*args):
    return subprocess.run([sys.executable, "-m", "mjccd", *args], capture_output=True, text=True)


def test_cli_solve_and_errors(tmp_path):
    good = tmp_path / "cases.json"
    good.write_text(json.dumps({"version": 1, "cases": [_case("good"), _case("bad", a__radii=[1, 1])]}))
    out = tmp_path / "out.json"
    proc = run_cli("solve", str(good), "-o", str(out))
    assert proc.returncode == 1
    assert "Traceback" not in proc.stderr
    assert "bad: a.radii: expected shape 3" in proc.stderr
    results = json.loads(out.read_text())["results"]
    assert results[0]["first_contact"] == pytest.approx(1 / 6, abs=1e-12)
    broken = tmp_path / "broken.json"
    broken.write_text("{not json")
    proc = run_cli("solve", str(broken))
    assert proc.returncode == 2 and "not valid JSON" in proc.stderr and "Traceback" not in proc.stderr
    proc = run_cli("solve", str(tmp_path / "missing.json"))
    assert proc.returncode == 2 and "cannot read" in proc.stderr
    wrong_version = tmp_path / "v2.json"
    wrong_version.write_text(json.dumps({"version": 2, "cases": []}))
    proc = run_cli("solve", str(wrong_version))
    assert proc.returncode == 2 and "version: expected 1" in proc.stderr


def test_fused_kernel_matches_the_general_path():
    """first_contact of two Rigid motions (the fused kernel) against the general pencil of the motions' quadrics."""
    from mjccd.ccd import rigid_first_contact, solve_pair

    for seed in range(25):
        r = np.random.default_rng(100 + seed)
        ra, rb = r.uniform(0.2, 1.0, 3), r.uniform(0.2, 1.0, 3)
        qs = [q / np.linalg.norm(q) for q in r.normal(size=(4, 4))]
        pa0, pa1 = r.normal(size=3) * 2, r.normal(size=3) * 2
        pb0, pb1 = r.normal(size=3) * 0.3, r.normal(size=3) * 0.3
        a, b = mjccd.Ellipsoid(ra), mjccd.Ellipsoid(rb)
        ma, mb = mjccd.Rigid(pa0, qs[0], pa1, qs[1]), mjccd.Rigid(pb0, qs[2], pb1, qs[3])
        _, want, _, _ = solve_pair(a, ma, b, mb)
        api = mjccd.first_contact(a, ma, b, mb)
        touch = np.empty((2, 3))
        status, t = rigid_first_contact(np.array([ra, rb]), np.array([[pa0, pa1], [pb0, pb1]]),
                                        np.array([[ma.quaternion0, ma.quaternion1], [mb.quaternion0, mb.quaternion1]]),
                                        1.0, touch)
        point, normal = touch
        if want is None:
            assert t == -1.0 and api is None
        else:
            assert t == pytest.approx(want.time, abs=1e-12)
            # the API settles a bracket wider than 1e-9 in rational arithmetic; the fused kernel keeps its estimate
            assert api.time == pytest.approx(t, abs=1e-9) and api.status_at_start == want.status_at_start
            if want.point is not None:
                assert np.allclose(point, want.point, atol=1e-9)
                assert np.allclose(normal, want.normal, atol=1e-9)
                assert np.allclose(api.point, point, atol=1e-9)


def test_translation_pencil_equals_the_rigid_one():
    """A quaternion that does not move: the pencil at degrees (0, 1, 2) is the rigid pencil at (4, 5, 6)."""
    from mjccd.ccd import empty_pencil, pencil_quadric_at
    from mjccd.motion import rigid_scaled_into, translation_scaled_into

    r = np.random.default_rng(8)
    for _ in range(20):
        radii, q = r.uniform(0.1, 2.0, 3), random_quat() * r.uniform(0.9, 1.1)  # not unit: |q|^4 kept
        p0, p1, o0, o1 = r.normal(size=(4, 3))
        low, high = empty_pencil(0, 1, 2), empty_pencil(4, 5, 6)
        translation_scaled_into(radii, p0, q, p1, o0, o1, 1.7, *low, 0)
        rigid_scaled_into(radii, p0, q, p1, q, o0, o1, 1.7, *high, 0)
        for t in (0.0, 0.3, 0.71, 1.0):
            want = pencil_quadric_at(*high, 0, t)
            assert np.allclose(pencil_quadric_at(*low, 0, t), want, rtol=1e-12, atol=1e-12 * abs(want).max())


@pytest.mark.parametrize("affine", [False, True])
def test_pure_translation_matches_the_general_path(affine):
    """Both quaternions fixed: the degree-2 F of the fused kernel against the general degree-18 pencil."""
    from mjccd.ccd import solve_pair

    kind = mjccd.Affine if affine else mjccd.Rigid
    hits = 0
    for seed in range(40):
        r = np.random.default_rng(300 + seed)
        ra, rb = r.uniform(0.1, 1.0, 3), r.uniform(0.1, 1.0, 3)
        qa, qb = random_quat(), random_quat()
        pa0, pb0 = r.normal(size=3) * 2, r.normal(size=3) * 0.3
        pa1, pb1 = -pa0 + r.normal(size=3) * 0.5, pb0 + r.normal(size=3) * 0.3
        a, b = mjccd.Ellipsoid(ra), mjccd.Ellipsoid(rb)
        ma, mb = kind(pa0, qa, pa1, qa), kind(pb0, qb, pb1, qb)
        _, want, _, _ = solve_pair(a, mjccd.Rigid(pa0, qa, pa1, qa), b, mjccd.Rigid(pb0, qb, pb1, qb))
        got = mjccd.first_contact(a, ma, b, mb)
        if want is None:
            assert got is None
            continue
        assert got.status_at_start == want.status_at_start
        assert got.time == pytest.approx(want.time, abs=1e-12)
        if want.point is not None:
            hits += 1
            assert np.allclose(got.point, want.point, atol=1e-9)
            assert np.allclose(got.normal, want.normal, atol=1e-9)
        # a quaternion that moves by a hair takes the general kernel: the answer moves by a hair too
        q_moved = qa + 1e-12
        nearly = mjccd.first_contact(a, kind(pa0, qa, pa1, q_moved / np.linalg.norm(q_moved)), b, mb)
        assert nearly.time == pytest.approx(got.time, abs=1e-9)
    assert hits >= 10


def test_a_quaternion_moved_by_rounding_is_solved_as_a_translation():
    """A ball in MuJoCo flight: its quaternion drifts by units in the last place each step.  The degree-2
    path takes it, and the answer is the general degree-18 path's for the same drifted motion."""
    from mjccd.ccd import SAME_ORIENTATION, same_orientation, solve_pair

    for seed in range(20):
        r = np.random.default_rng(500 + seed)
        ra, rb = r.uniform(0.1, 1.0, 3), r.uniform(0.1, 1.0, 3)
        qa, qb = random_quat(), random_quat()
        qa1 = qa + r.uniform(-0.5, 0.5, 4) * SAME_ORIENTATION
        moving = mjccd.Rigid(np.zeros(3), qa, np.zeros(3), qa1)
        assert same_orientation(moving.quaternion0, moving.quaternion1)  # after normalisation: the degree-2 path
        assert not np.array_equal(moving.quaternion0, moving.quaternion1)
        pa0, pb0 = np.array([-3.0, 0, 0]) + r.normal(size=3) * 0.1, r.normal(size=3) * 0.1
        pa1, pb1 = np.array([3.0, 0, 0]) + r.normal(size=3) * 0.1, pb0
        a, b = mjccd.Ellipsoid(ra), mjccd.Ellipsoid(rb)
        got = mjccd.first_contact(a, mjccd.Rigid(pa0, qa, pa1, qa1), b, mjccd.Rigid(pb0, qb, pb1, qb))
        _, want, _, _ = solve_pair(a, mjccd.Rigid(pa0, qa, pa1, qa1), b, mjccd.Rigid(pb0, qb, pb1, qb))
        assert got.time == pytest.approx(want.time, abs=1e-12)
        assert np.allclose(got.point, want.point, atol=1e-9) and np.allclose(got.normal, want.normal, atol=1e-9)


def test_rows_at_equals_row_by_row_evaluation():
    from mjccd import bernstein as bz
    from mjccd.ccd import _rows_at

    rng = np.random.default_rng(5)
    for degree in (0, 6, 18, 40, 60):
        F = rng.normal(size=(5, degree + 1))
        for t in (0.0, 1e-9, 0.3, 0.5, 0.73, 1.0 - 1e-9, 1.0):
            got = _rows_at(F, t)
            for i in range(5):
                assert got[i] == pytest.approx(bz.evaluate_row(F, i, t), rel=1e-12, abs=1e-12)


def _far_arm(offset, free):
    """A two-hinge arm rooted at ``offset`` (a Fixed root, or a Free root moving by a dyadic step)."""
    root = (mjccd.Free(offset, [1, 0, 0, 0], offset + [0.0625, 0.0, 0.0], [1, 0, 0, 0]) if free
            else mjccd.Fixed(offset))
    return mjccd.Chain([root, mjccd.Hinge([0, 0, 1], -0.8, 0.9), mjccd.Fixed([0.5, 0, 0]),
                        mjccd.Hinge([0, 1, 0], -0.2, 0.4), mjccd.Fixed([0.375, 0, 0])])


@pytest.mark.parametrize("free", [False, True])
def test_chains_far_from_the_origin_give_the_same_answer(free):
    """A chain and its partner shifted by up to 2^40 (about 1e12) times their size: every input stays exact
    (dyadic), so the answer must not move.  Before the chain was composed again from its shifted root, the
    far copies drifted by 1e-6 at 1e10 and were still reported certified."""
    a, b = mjccd.Ellipsoid([0.1875, 0.0625, 0.0625]), mjccd.Ellipsoid([0.125, 0.125, 0.125])
    answers = []
    for k in (0, 20, 33, 40):
        offset = 2.0 ** k * np.array([1.0, -0.25, 0.125])
        partner = mjccd.Rigid(offset + [0.4375, 0.65625, 0.0], [1, 0, 0, 0],
                              offset + [0.4375, 0.59375, 0.0], [1, 0, 0, 0])
        contact = mjccd.first_contact(a, _far_arm(offset, free), b, partner)
        assert contact is not None and contact.certainty == "certified"
        answers.append(contact.time)
    assert max(answers) - min(answers) <= 1e-12, answers


def _close_pair(r, kinds=("rigid", "rigid")):
    """Two ellipsoids crossing each other's path within one step (the bench's close pairs)."""
    def motion(kind, p0, p1):
        q0, q1 = r.normal(size=4), r.normal(size=4)
        if kind == "static":
            return mjccd.Static(p0, q0)
        return (mjccd.Rigid if kind == "rigid" else mjccd.Affine)(p0, q0, p1, q1)
    side = r.normal(size=3) * 0.3
    a = mjccd.Ellipsoid(r.uniform(0.2, 1.0, 3))
    b = mjccd.Ellipsoid(r.uniform(0.2, 1.0, 3))
    return a, motion(kinds[0], [-1.5, 0, 0] + side, [1.5, 0, 0] - side), b, motion(kinds[1], r.normal(size=3) * 0.2,
                                                                                  r.normal(size=3) * 0.2)


def test_interval_ends_are_where_the_exact_status_changes():
    """The end of each overlap of turning pairs (the certified march, then Newton's steps on State) lies within
    TIME_TOL of where the status decided in rational arithmetic changes back to separate."""
    from mjccd.ccd import TIME_TOL, _ExactPair

    checked = 0
    for seed in range(60):
        a, ma, b, mb = _close_pair(np.random.default_rng(400 + seed))
        pair = _ExactPair(a, ma, b, mb)
        for t_in, t_out in mjccd.collision_intervals(a, ma, b, mb):
            if t_out >= 1.0 or t_out - t_in < 1e-6:
                continue
            found = pair.separation_change(t_out - 1e-7, t_out + 1e-7, False)
            assert found is not None and abs(found[0] - t_out) <= TIME_TOL, (seed, t_out, found)
            checked += 1
        if checked >= 6:
            break
    assert checked >= 6


@pytest.mark.parametrize("kinds", [("rigid", "rigid"), ("rigid", "static"), ("affine", "rigid"), ("static", "affine")])
def test_api_answers_read_off_the_kernel_are_the_pair_solution(kinds):
    """first_contact and collision_intervals read the fused kernel's answer straight off its array; the same
    answer as the PairSolution every other caller gets (overlapping starts and misses included)."""
    from mjccd.ccd import _contact, solve_motions

    for seed in range(12):
        a, ma, b, mb = _close_pair(np.random.default_rng(500 + seed), kinds)
        want = _contact(solve_motions(a, ma, b, mb, 1.0, True))
        got = mjccd.first_contact(a, ma, b, mb)
        if want is None:
            assert got is None
        else:
            assert (got.time, got.status_at_start, got.certainty, got.bracket) == \
                (want.time, want.status_at_start, want.certainty, want.bracket)
            for x, y in ((got.point, want.point), (got.normal, want.normal)):
                assert (x is None and y is None) or np.array_equal(x, y)
        assert mjccd.collision_intervals(a, ma, b, mb) == \
            [(float(x), float(y)) for x, y in solve_motions(a, ma, b, mb).intervals]


def test_a_thin_second_body_is_solved_as_the_first():
    """A 20:1 body given second is taken as the solver's A (whose frame keeps its small curvatures): the answer
    is that of the bodies swapped, with the normal turned, and double precision settles nearly all of these
    pairs (when the thin body stayed B, 84 % of them went on to the rational tier)."""
    from mjccd.bench import peers
    from mjccd.ccd import PACKED_HEAD, _two_pose_call

    rng = np.random.default_rng(5)
    solved = rational = 0
    for q in peers.random_rigid_queries(40, seed=9, max_angle=0.5):
        rb = np.array(q.radii_b, float)
        rb[rng.integers(3)] *= 0.05
        a, b = mjccd.Ellipsoid(q.radii_a), mjccd.Ellipsoid(rb)
        ma = mjccd.Rigid(q.position_a[0], q.quaternion_a[0], q.position_a[1], q.quaternion_a[1])
        mb = mjccd.Rigid(q.position_b[0], q.quaternion_b[0], q.position_b[1], q.quaternion_b[1])
        ab = _two_pose_call(a, ma, b, mb, 1.0, np.bool_(True))
        ba = _two_pose_call(b, mb, a, ma, 1.0, np.bool_(True))
        rational += ab[4] != 1.0  # not certified in double precision: the rational tier's
        assert np.array_equal(ab[:7], ba[:7]) and np.array_equal(ab[PACKED_HEAD:], ba[PACKED_HEAD:])
        assert np.array_equal(ab[7:10], ba[7:10]) and np.array_equal(ab[10:13], -ba[10:13])  # point, normal
        solved += ab[1] > 0
    assert solved >= 10 and rational <= 4


def test_rational_tier_confirms_the_double_estimate_as_bisection_would(monkeypatch):
    """100:1 bodies whose double bracket stays wider than 1e-9: the rational tier's two exact statuses
    either side of the double estimate give the first contact that bisection on the exact status gives
    (within the 2^-50 they prove), and it is certified."""
    from mjccd.bench import peers
    from mjccd.ccd import RATIONAL, _ExactPair, solve_motions

    rng = np.random.default_rng(5)
    pairs = []
    for q in peers.random_rigid_queries(12, seed=9, max_angle=0.5):
        ra = np.array(q.radii_a, float)
        ra[rng.integers(3)] *= 0.01
        pairs.append((mjccd.Ellipsoid(ra), mjccd.Rigid(q.position_a[0], q.quaternion_a[0], q.position_a[1],
                                                       q.quaternion_a[1]),
                      mjccd.Ellipsoid(q.radii_b), mjccd.Rigid(q.position_b[0], q.quaternion_b[0], q.position_b[1],
                                                              q.quaternion_b[1])))
    near = [solve_motions(*p, first_only=True) for p in pairs]
    monkeypatch.setattr(_ExactPair, "change_near", lambda self, t, lo, hi, separate_at_lo: None)
    bisected = [solve_motions(*p, first_only=True) for p in pairs]
    refined = 0
    for x, y in zip(near, bisected):
        assert x.certified and y.certified and len(x.intervals) == len(y.intervals)
        if x.precision == RATIONAL and len(x.intervals):
            refined += 1
            assert abs(x.intervals[0, 0] - y.intervals[0, 0]) <= 2.0 ** -49
            assert x.bounds[0, 1] - x.bounds[0, 0] <= 2.0 ** -49
    assert refined >= 3


def test_an_interval_before_the_proven_separation_is_cut_to_it():
    """The rational tier proved the pair separate up to 0.5; the double solver's intervals said [0.2, 0.3]
    and [0.45, 0.6]: the first goes, the second starts at 0.5 (its brackets too), so no interval claims a
    possible contact outside the first contact's bracket [0.5, 0.6]."""
    from mjccd.ccd import PairSolution, _separate_before

    solution = PairSolution(1, np.array([[0.2, 0.3], [0.45, 0.6]]), None, None, False, (0.5, 0.6),
                            np.array([[0.19, 0.21, 0.29, 0.31], [0.44, 0.46, 0.59, 0.61]]))
    cut = _separate_before(solution, 0.5)
    assert cut.intervals.tolist() == [[0.5, 0.6]]
    assert cut.bounds.tolist() == [[0.5, 0.5, 0.59, 0.61]]
    assert (cut.bracket, cut.certified) == ((0.5, 0.6), False)
