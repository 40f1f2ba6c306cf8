"""Scene against the pairwise exact solver: same first contact, same colliding set, cache on or off."""
import json
from pathlib import Path

import numpy as np
import pytest

import mjccd
from mjccd.scene import Scene, non_adjacent_pairs, pairs_between

N = 6


def random_frames(seed, n_frames):
    """A smooth pose sequence (n_frames + 1, N, 7) of ellipsoids crowded into a small box."""
    r = np.random.default_rng(seed)
    radii = r.uniform(0.15, 0.45, (N, 3))
    pos = r.uniform(-0.7, 0.7, (N, 3))
    vel = r.normal(size=(N, 3)) * 0.25
    q = r.normal(size=(N, 4))
    w = r.normal(size=(N, 3)) * 0.4
    poses = np.empty((n_frames + 1, N, 7))
    for f in range(n_frames + 1):
        q = q / np.linalg.norm(q, axis=1, keepdims=True)
        poses[f, :, :3], poses[f, :, 3:] = pos, q
        pos = pos + vel
        vel = np.where(np.abs(pos) > 0.8, -vel, vel)
        dq = np.concatenate([np.ones((N, 1)), 0.5 * w], axis=1)
        q = np.stack([_qmul(a, b) for a, b in zip(dq, q)])
    return radii, poses


def _qmul(a, b):
    w1, v1, w2, v2 = a[0], a[1:], b[0], b[1:]
    return np.concatenate([[w1 * w2 - v1 @ v2], w1 * v2 + w2 * v1 + np.cross(v1, v2)])


def pairwise(radii, pairs, p0, p1, motion):
    """First contact and intervals of every pair by the public pairwise API."""
    cls = mjccd.Rigid if motion == "rigid" else mjccd.Affine
    out = {}
    for k, (i, j) in enumerate(pairs):
        args = (mjccd.Ellipsoid(radii[i]), cls(p0[i, :3], p0[i, 3:], p1[i, :3], p1[i, 3:]),
                mjccd.Ellipsoid(radii[j]), cls(p0[j, :3], p0[j, 3:], p1[j, :3], p1[j, 3:]))
        c = mjccd.first_contact(*args)
        if c is not None:
            out[k] = (c, mjccd.collision_intervals(*args))
    return out


@pytest.mark.parametrize("motion", ["rigid", "affine"])
def test_scene_equals_pairwise_solver(motion):
    radii, poses = random_frames(3 if motion == "rigid" else 4, 6)
    cached = Scene(radii, motion=motion)
    plain = Scene(radii, motion=motion, plane_cache=False)
    every = Scene(radii, motion=motion)
    hits = 0
    for f in range(len(poses) - 1):
        ref = pairwise(radii, cached.pairs, poses[f], poses[f + 1], motion)
        a = cached.step(poses[f], poses[f + 1])
        b = plain.step(poses[f], poses[f + 1])
        full = every.step(poses[f], poses[f + 1], all_pairs=True)
        for res in (a, b, full):
            if not ref:
                assert res.first is None
                continue
            k_ref = min(ref, key=lambda k: (ref[k][0].time, k))
            assert res.first.time == pytest.approx(ref[k_ref][0].time, abs=1e-9)
            assert res.first.pair == k_ref
        assert a.first == b.first or a.first.time == b.first.time
        assert {c.pair for c in full.contacts} == set(ref)
        for c in full.contacts:
            contact, intervals = ref[c.pair]
            assert c.time == pytest.approx(contact.time, abs=1e-9)
            assert np.allclose(c.intervals, intervals, atol=1e-9)
            if contact.point is not None:
                assert np.allclose(c.point, contact.point, atol=1e-6)
                assert np.allclose(c.normal, contact.normal, atol=1e-6)
        assert full.counters.colliding == len(ref)
        hits += len(ref)
    assert hits > 0
    assert cached.step(poses[0], poses[1]).counters.pairs == N * (N - 1) // 2


def test_run_equals_steps_and_cache_changes_nothing():
    radii, poses = random_frames(8, 12)
    steps = Scene(radii)
    firsts = [steps.step(poses[f], poses[f + 1]).first for f in range(12)]
    for cache in (True, False):
        run = Scene(radii, plane_cache=cache).run(poses)
        for f, first in enumerate(firsts):
            if first is None:
                assert run.time[f] == -1.0 and run.pair[f] == -1
            else:
                assert run.time[f] == first.time and run.pair[f] == first.pair
    assert Scene(radii).run(poses).counters[:, 2].sum() > 0  # the cache was used


def test_run_new_contacts_only_equals_steps():
    radii, poses = random_frames(8, 12)
    steps = Scene(radii)
    firsts = [steps.step(poses[f], poses[f + 1], new_contacts_only=True).first for f in range(12)]
    run = Scene(radii).run(poses, new_contacts_only=True)
    assert [-1.0 if c is None else c.time for c in firsts] == run.time.tolist()
    assert any(c is not None and c.time > 0 for c in firsts)
    assert np.any(run.time != Scene(radii).run(poses).time)  # some frame starts overlapping: the option matters


def test_earliest_contact_bound_prunes_later_pairs():
    """Pair 0 hits at t = 0.25, pair 1 only later: pair 1 is not solved, its sphere entry is too late."""
    radii = np.full((4, 3), 0.5)
    p0 = np.array([[0, 0, 0, 1, 0, 0, 0], [2, 0, 0, 1, 0, 0, 0],
                   [10, 0, 0, 1, 0, 0, 0], [14, 0, 0, 1, 0, 0, 0]], float)
    p1 = p0.copy()
    p1[1, 0] = -2.0          # closes 4 in the frame: touches when the gap 1 is gone, t = 0.25
    p1[3, 0] = 10.5          # centres 4 apart close by 3.5: touch (distance 1) at t = 6/7
    scene = Scene(radii, pairs=[[0, 1], [2, 3]])
    res = scene.step(p0, p1)
    assert res.first.pair == 0 and res.first.time == pytest.approx(0.25, abs=1e-9)
    assert res.counters.pruned == 1 and res.counters.solved_exactly == 1
    full = scene.step(p0, p1, all_pairs=True)
    assert [c.pair for c in full.contacts] == [0, 1]
    assert full.contacts[1].time == pytest.approx(6 / 7, abs=1e-9)
    assert np.allclose(res.first.point, [0.5 - 0.0, 0, 0], atol=1e-9)
    assert np.allclose(res.first.normal, [1, 0, 0], atol=1e-9)


def test_pairs_that_only_translate_are_solved_without_a_plane():
    """A thin slab and a ball that flies through it in the frame: the ends are separate (the ball is on the
    other side at t = 1), so a turning pair would get a plane search; a translating one goes straight to
    the exact solver, with the closed-form contact time, and one that stops short is solved and found free."""
    radii = np.array([[0.01, 1.0, 1.0], [0.02, 0.02, 0.02]])
    p0 = np.array([[0, 0, 0, 1, 0, 0, 0], [-0.1, 0, 0, 1, 0, 0, 0]], float)
    p1 = p0.copy()
    p1[1, 0] = 0.1
    scene = Scene(radii)
    res = scene.step(p0, p1)
    assert res.counters.new_plane == 0 and res.counters.solved_exactly == 1
    assert res.first.time == pytest.approx(0.07 / 0.2, abs=1e-12)  # gap 0.07 closed at 0.2 per frame
    assert np.allclose(res.first.normal, [-1, 0, 0], atol=1e-9)
    short = p1.copy()
    short[1, 0] = -0.05  # stops 2 cm short of the slab (its face at -0.01, the ball's radius 0.02)
    miss = scene.step(p0, short)
    assert miss.first is None and miss.counters.new_plane == 0 and miss.counters.solved_exactly == 1
    turning = short.copy()
    turning[1, 3:] = [np.cos(0.1), np.sin(0.1), 0, 0]
    assert scene.step(p0, turning).counters.new_plane == 1  # a ball that also turns: cleared by a plane


def test_overlap_at_start_is_time_zero():
    radii = np.full((2, 3), 0.5)
    p = np.array([[0, 0, 0, 1, 0, 0, 0], [0.5, 0, 0, 1, 0, 0, 0]], float)
    res = Scene(radii).step(p, p)
    assert res.first.time == 0.0 and res.first.point is None
    assert res.counters.overlapping_t0 == 1


def test_overlap_after_a_contact_has_no_point():
    """Frame 0: B reaches A at t = 2/3; frame 1: they overlap from the start, so no point or normal is left over."""
    radii = np.full((2, 3), 0.5)
    poses = np.zeros((3, 2, 7))
    poses[:, :, 3] = 1.0
    poses[:, 1, 0] = [2.0, 0.5, 0.5]
    run = Scene(radii).run(poses)
    assert run.time[0] == pytest.approx(2 / 3, abs=1e-9) and np.allclose(run.normal[0], [1, 0, 0], atol=1e-9)
    assert run.time[1] == 0.0 and not run.point[1].any() and not run.normal[1].any()
    scene = Scene(radii)
    assert scene.step(poses[0], poses[1]).first.point is not None
    later = scene.step(poses[1], poses[2])
    assert later.first.time == 0.0 and later.first.point is None and later.first.normal is None


def test_step_reads_poses_of_any_layout():
    """Lists, Fortran-ordered and strided poses give the same frame as C-ordered float64 ones."""
    radii, poses = random_frames(5, 2)
    ref = Scene(radii).step(poses[0], poses[1], all_pairs=True)
    wide = np.zeros((N, 9))
    wide[:, :7] = poses[1]
    for a, b in ((poses[0].tolist(), poses[1]), (np.asfortranarray(poses[0]), wide[:, :7])):
        res = Scene(radii).step(a, b, all_pairs=True)
        assert res.counters == ref.counters
        assert [(c.pair, c.time) for c in res.contacts] == [(c.pair, c.time) for c in ref.contacts]
    assert ref.contacts


def three_pairs():
    """Unit spheres in three pairs over one frame: pair 0 overlaps from the start; pair 1 closes 4 units and
    first touches at t = 0.25; pair 2 closes 3.5 units and touches at 6/7.  Returns (scene, poses_t0, poses_t1)."""
    p0 = np.array([[0, 0, 0, 1, 0, 0, 0], [0.5, 0, 0, 1, 0, 0, 0],
                   [10, 0, 0, 1, 0, 0, 0], [12, 0, 0, 1, 0, 0, 0],
                   [20, 0, 0, 1, 0, 0, 0], [24, 0, 0, 1, 0, 0, 0]], float)
    p1 = p0.copy()
    p1[3, 0] = 8.0
    p1[5, 0] = 20.5
    return Scene(np.full((6, 3), 0.5), pairs=[[0, 1], [2, 3], [4, 5]]), p0, p1


def test_new_contacts_only_skips_pairs_overlapping_at_start():
    """See :func:`three_pairs`: the overlap at the start is left out, pair 1 comes first, pair 2 at 6/7."""
    scene, p0, p1 = three_pairs()
    assert scene.step(p0, p1).first.time == 0.0
    res = scene.step(p0, p1, new_contacts_only=True)
    assert res.first.pair == 1 and res.first.time == pytest.approx(0.25, abs=1e-12)
    assert res.counters.overlapping_t0 == 1 and res.counters.pruned == 1
    full = scene.step(p0, p1, all_pairs=True, new_contacts_only=True)
    assert [c.pair for c in full.contacts] == [1, 2]
    assert full.contacts[1].time == pytest.approx(6 / 7, abs=1e-12)


def test_min_motion_leaves_out_slow_pairs_only():
    """A min_motion of 3.75 leaves out pair 2 (closing 3.5) alone: pair 1 (closing 4) stays the first
    contact and pair 2 no longer reports one."""
    scene, p0, p1 = three_pairs()
    scene.set_min_motion(np.full(3, 3.75))
    full = scene.step(p0, p1, all_pairs=True, new_contacts_only=True)
    assert [c.pair for c in full.contacts] == [1]
    assert full.first.time == pytest.approx(0.25, abs=1e-12)
    scene.set_min_motion(np.zeros(3))
    assert [c.pair for c in scene.step(p0, p1, all_pairs=True, new_contacts_only=True).contacts] == [1, 2]


def test_pair_helpers():
    assert pairs_between([0, 1], [2, 3, 4]).tolist() == [[0, 2], [0, 3], [0, 4], [1, 2], [1, 3], [1, 4]]
    assert non_adjacent_pairs(4, [[0, 1], [2, 1], [2, 3]]).tolist() == [[0, 2], [0, 3], [1, 3]]


def test_bad_input():
    radii = np.full((3, 3), 0.5)
    good = np.zeros((3, 7))
    good[:, 3] = 1.0
    scene = Scene(radii)
    with pytest.raises(ValueError, match=r"radii\[1\]: radii must be positive"):
        Scene([[1, 1, 1], [1, 0, 1]])
    with pytest.raises(ValueError, match=r"pairs\[1\]: index out of range for 3 ellipsoids, got \[0, 3\]"):
        Scene(radii, pairs=[[0, 1], [0, 3]])
    with pytest.raises(ValueError, match=r"pairs\[0\]: an ellipsoid cannot be paired with itself"):
        Scene(radii, pairs=[[2, 2]])
    with pytest.raises(ValueError, match="pairs: expected shape Px2, got \\(3,\\)"):
        Scene(radii, pairs=[0, 1, 2])
    with pytest.raises(ValueError, match="motion: expected 'rigid' or 'affine', got 'chain'"):
        Scene(radii, motion="chain")
    with pytest.raises(ValueError, match=r"poses_t0: expected shape 3x7, got \(3, 6\)"):
        scene.step(good[:, :6], good)
    bad = good.copy()
    bad[1, 0] = np.nan
    with pytest.raises(ValueError, match="poses_t1: contains NaN or infinity"):
        scene.step(good, bad)
    bad = good.copy()
    bad[2, 3:] = 0.0
    with pytest.raises(ValueError, match=r"poses_t1\[2\]: zero quaternion"):
        scene.step(good, bad)
    with pytest.raises(ValueError, match=r"poses\[1\]\[2\]: zero quaternion"):
        scene.run(np.stack([good, bad]))


# ---------------------------------------------------------------- uncertain answers of the exact solver
#
# A real limit of the solver (MAX_SHOOTS, the exit pool) is baked into the compiled kernel and is hard to hit on
# purpose, so these tests run the scene kernel's own Python source (``step_kernel.py_func``: the same lines the
# compiled kernel runs) with a stand-in exact solver that answers "uncertain" for chosen pairs.


def _exact_stand_in(answers):
    """An exact_pair that returns ``answers[x]`` for the pair whose first body starts at x = ``pa0[0]``
    (the real solver for the others)."""
    from mjccd.ccd import exact_pair

    def stand_in(affine, ra, pa0, qa0, pa1, qa1, rb, pb0, qb0, pb1, qb1, t_max, first_only):
        answer = answers.get(float(pa0[0]))
        if answer is None:
            return exact_pair(affine, ra, pa0, qa0, pa1, qa1, rb, pb0, qb0, pb1, qb1, t_max, first_only)
        return answer(t_max, first_only)
    return stand_in


def _limit(lo, hi, status0=1, intervals=(), touch=False):
    """An answer of a solver that hit a limit: bracket [lo, hi], the intervals found before it."""
    def answer(t_max, first_only):
        iv = np.array(intervals, float).reshape(-1, 2)
        point = np.array([0.5, 0.0, 0.0]) if touch else np.zeros(3)
        normal = np.array([1.0, 0.0, 0.0]) if touch else np.zeros(3)
        return status0, iv, point, normal, False, lo, hi
    return answer


@pytest.fixture
def python_kernel(monkeypatch):
    """Scene kernels run as Python; returns a setter for the stand-in solver's answers (see _exact_stand_in)."""
    import mjccd.scene as sc

    monkeypatch.setattr(sc, "_borrow", lambda a: a)
    monkeypatch.setattr(sc, "step_kernel", sc.step_kernel.py_func)
    monkeypatch.setattr(sc, "run_kernel", sc.run_kernel.py_func)

    def answers(table):
        monkeypatch.setattr(sc, "exact_pair", _exact_stand_in(table))
    answers({})
    return answers


def test_python_kernel_equals_the_compiled_one(python_kernel):
    """The harness of the uncertain tests: without a stand-in answer the Python kernel gives the compiled result."""
    scene, p0, p1 = three_pairs()
    compiled = three_pairs()[0].step(p0, p1, all_pairs=True)
    python = scene.step(p0, p1, all_pairs=True)

    def rows(res):
        return [(c.pair, c.time, c.intervals, c.certainty, c.bracket, c.point is None) for c in res.contacts]
    assert rows(python) == rows(compiled) and len(rows(compiled)) == 3
    assert python.counters == compiled.counters and python.first.pair == compiled.first.pair
    assert compiled.certainty == "certified" and compiled.counters.uncertain == 0
    assert all(c.certainty == "certified" and c.bracket is None for c in compiled.contacts)


def test_uncertain_first_contact_is_a_possible_contact_at_its_bracket(python_kernel):
    """The kernel's own answer (resolve_uncertain=False).  See three_pairs: pair 1 (which touches at 0.25) hits a limit, bracket [0.2, 0.3]: it is the first
    contact at 0.2, uncertain, with the estimate of its point (where the spheres nearly touch at 0.2: between
    their surfaces at x = 10.5 and 10.7); counted as uncertain, not colliding; pair 2 is pruned by it."""
    python_kernel({10.0: _limit(0.2, 0.3)})
    scene, p0, p1 = three_pairs()
    res = scene.step(p0, p1, new_contacts_only=True, resolve_uncertain=False)
    assert res.certainty == "uncertain"
    first = res.first
    assert (first.pair, first.time, first.certainty, first.bracket) == (1, 0.2, "uncertain", (0.2, 0.3))
    _assert_estimate_between_the_spheres(first)
    c = res.counters
    # colliding: only the pair overlapping at the start (counted, not reported, with new_contacts_only)
    assert (c.solved_exactly, c.uncertain, c.colliding, c.pruned, c.overlapping_t0) == (1, 1, 1, 1, 1)
    # the overlap at the start comes first when it is reported: the uncertain pair is then pruned, not solved
    res = scene.step(p0, p1)
    assert res.first.pair == 0 and res.certainty == "certified" and res.counters.uncertain == 0


def test_uncertain_first_contact_keeps_its_bracket(python_kernel):
    """Pair 1's solver estimates its first contact at 0.25 but proves it only within [0.2, 0.3] (a first-only
    answer that hit a limit): the scene's kernel reports the bracket, not the estimate, and the point estimated at the
    bracket's start."""
    python_kernel({10.0: _limit(0.2, 0.3, intervals=[(0.25, 0.25)], touch=True)})
    scene, p0, p1 = three_pairs()
    res = scene.step(p0, p1, new_contacts_only=True, resolve_uncertain=False)
    first = res.first
    assert (first.pair, first.time, first.certainty, first.bracket) == (1, 0.2, "uncertain", (0.2, 0.3))
    _assert_estimate_between_the_spheres(first)
    assert (res.counters.uncertain, res.counters.colliding) == (1, 1)  # colliding: the overlap at the start only


def _assert_estimate_between_the_spheres(contact, lo=10.5, hi=10.7):
    """An uncertain contact's estimated point: where two spheres of three_pairs nearly touch at the bracket's
    start, between their surfaces at x = lo and hi (pair 1 at t = 0.2: about x = 10 and 11.2), along +x."""
    assert contact.point is not None and lo <= contact.point[0] <= hi and np.allclose(contact.point[1:], 0.0)
    np.testing.assert_allclose(contact.normal, [1.0, 0.0, 0.0], atol=1e-12)


def _two_pose_poses(case):
    """(N=2, 7) poses at t = 0 and t = 1 of a case whose bodies are rigid or static."""
    def pose(m, key):
        p = m if m["type"] == "static" else m[key]
        return p["position"] + p["quaternion"]
    ma, mb = case["a"]["motion"], case["b"]["motion"]
    return np.array([pose(ma, "start"), pose(mb, "start")]), np.array([pose(ma, "end"), pose(mb, "end")])


def _hard_rigid_cases():
    """(id, radii, poses_t0, poses_t1, the oracle's first contact or None) of the shared hard cases whose bodies
    are rigid or static."""
    data = Path(__file__).parent / "data"
    cases = json.loads((data / "adversarial_public.json").read_text())["cases"]
    want = {r["id"]: r for r in json.loads((data / "adversarial_expected.json").read_text())["results"]}
    return [(case["id"], [case["a"]["radii"], case["b"]["radii"]], *_two_pose_poses(case),
             want[case["id"]]["first_contact"]) for case in cases
            if not {case["a"]["motion"]["type"], case["b"]["motion"]["type"]} - {"rigid", "static"}]


def _holds(first, t):
    """A FirstContact (or None) agrees with the oracle's time t: certified within 1e-9, or t in its bracket."""
    if first is None:
        return t is None
    if first.bracket is None:
        return t is not None and abs(first.time - t) <= 1e-9
    lo, hi = first.bracket
    return first.time == lo and (t is None or lo - 1e-12 <= t <= hi + 1e-12)  # a miss may be possible


def test_scene_brackets_hold_the_oracles_first_contact():
    """The hard rigid cases (needles, disks, grazes) in a two-body Scene: the compiled kernel (no rational tier)
    leaves some uncertain, each holding the oracle's first contact; the Scene asks the core again about those,
    and every one comes back certified as the oracle's."""
    kernel_uncertain = uncertain = 0
    for name, radii, p0, p1, t in _hard_rigid_cases():
        raw = Scene(radii).step(p0, p1, resolve_uncertain=False).first
        assert _holds(raw, t), name
        kernel_uncertain += raw is not None and raw.bracket is not None
        scene = Scene(radii)
        first = scene.step(p0, p1).first
        assert _holds(first, t), name
        uncertain += first is not None and first.bracket is not None
        again = scene.first_contact(p0, p1)
        assert (again is None) == (first is None) and (again is None or again.time == first.time), name
    assert kernel_uncertain >= 2 and uncertain == 0, (kernel_uncertain, uncertain)


def test_an_uncertain_bracket_that_misses_the_truth_is_asked_again(python_kernel):
    """The kernel's stand-in says pair 1 of three_pairs, which first touches at 0.25, touches "somewhere in
    [0.1, 0.2]": a bracket that misses the truth.  Scene asks the core again and reports 0.25, certified, with
    its point, in step (first only and every pair), first_contact and run; resolve_uncertain=False keeps the
    kernel's answer."""
    from mjccd.scene import EXACT_HIT

    python_kernel({10.0: _limit(0.1, 0.2)})
    scene, p0, p1 = three_pairs()
    raw = scene.step(p0, p1, new_contacts_only=True, resolve_uncertain=False)
    assert (raw.first.pair, raw.first.bracket, raw.counters.uncertain) == (1, (0.1, 0.2), 1)
    res = scene.step(p0, p1, new_contacts_only=True)
    assert (res.certainty, res.first.pair, res.first.bracket, res.counters.uncertain) == ("certified", 1, None, 0)
    assert res.first.time == pytest.approx(0.25, abs=1e-12) and res.first.point is not None
    # checked again through every pair: the overlap at the start, pair 1 (now known) and pair 2 collide
    assert (res.counters.colliding, res.counters.pruned) == (3, 0)
    full = scene.step(p0, p1, all_pairs=True, new_contacts_only=True)
    assert [(c.pair, c.certainty) for c in full.contacts] == [(1, "certified"), (2, "certified")]
    assert full.contacts[0].intervals[0][0] == pytest.approx(0.25, abs=1e-12) and full.first.pair == 1
    first = scene.first_contact(p0, p1, new_contacts_only=True)
    assert (first.pair, first.bracket) == (1, None) and first.time == pytest.approx(0.25, abs=1e-12)
    run = scene.run(np.stack([p0, p1, p1]), new_contacts_only=True)
    assert (run.pair[0], run.uncertain[0], run.outcomes[0, 1]) == (1, 0, EXACT_HIT)
    assert run.time[0] == pytest.approx(0.25, abs=1e-12) and run.point[0].any()
    raw_run = scene.run(np.stack([p0, p1, p1]), new_contacts_only=True, resolve_uncertain=False)
    assert (raw_run.pair[0], raw_run.time[0], raw_run.uncertain[0]) == (1, 0.1, 1)


def test_a_settled_pair_touching_at_the_start_is_labelled_overlapping(python_kernel):
    """Pair 2 of three_pairs made to touch exactly at the start; the kernel's stand-in calls it separate then
    and uncertain in [0, 0.1].  Asked again with new contacts only, the core finds it touching at the start:
    not new, so left out, and its outcome is OVERLAP_T0 (in contact at t = 0), not EXACT_FREE."""
    from mjccd.scene import OVERLAP_T0

    python_kernel({20.0: _limit(0.0, 0.1)})
    scene, p0, p1 = three_pairs()
    p0, p1 = p0.copy(), p1.copy()
    p0[5, 0] = 21.0  # unit spheres 1 apart: touching
    raw = scene.step(p0, p1, new_contacts_only=True, resolve_uncertain=False)
    assert (raw.first.pair, raw.first.certainty) == (2, "uncertain")
    result, outcomes = scene.settled_step(p0, p1, new_contacts_only=True)
    assert result.certainty == "certified" and result.first.pair == 1
    assert outcomes[2] == OVERLAP_T0


def test_uncertain_pairs_with_all_pairs(python_kernel):
    """all_pairs: pair 2 (touching at 6/7) hits a limit before its first contact, bracket [0.8, 0.95]; pair 1
    finds its first contact at 0.25 but its later intervals hit a limit (bracket [0.25, 0.25]); pair 0 overlaps
    from the start, its intervals cut short by a limit (bracket [0, 0])."""
    python_kernel({20.0: _limit(0.8, 0.95),
                   10.0: _limit(0.25, 0.25, intervals=[(0.25, 0.5)], touch=True),
                   0.0: _limit(0.0, 0.0, status0=-1, intervals=[(0.0, 0.4)])})
    scene, p0, p1 = three_pairs()
    res = scene.step(p0, p1, all_pairs=True, resolve_uncertain=False)
    assert res.certainty == "uncertain"
    by_pair = {c.pair: c for c in res.contacts}
    assert sorted(by_pair) == [0, 1, 2]
    assert (by_pair[2].time, by_pair[2].bracket) == (0.8, (0.8, 0.95))
    _assert_estimate_between_the_spheres(by_pair[2], 20.5, 20.7)  # about x = 20 and 21.2 at t = 0.8
    assert (by_pair[1].time, by_pair[1].bracket, by_pair[1].intervals) == (0.25, (0.25, 0.25), ((0.25, 0.5),))
    assert np.allclose(by_pair[1].normal, [1, 0, 0])  # the first contact itself is known
    assert (by_pair[0].time, by_pair[0].bracket, by_pair[0].point) == (0.0, (0.0, 0.0), None)
    assert all(c.certainty == "uncertain" for c in res.contacts)
    assert res.first.pair == 0
    c = res.counters
    # colliding: pair 0 (overlapping) and pair 1 (first contact found); pair 2 only possibly
    assert (c.overlapping_t0, c.solved_exactly, c.colliding, c.uncertain) == (1, 2, 2, 3)


def test_uncertain_pair_after_the_first_contact_leaves_it_certified(python_kernel):
    """Pair 1 (sphere entry 0.25) is solved first and left uncertain from 0.5 on; pair 2, moved to touch at
    0.4, is solved next under that bound and hits at 0.4: the first contact is certified, the uncertain pair
    only counted."""
    python_kernel({10.0: _limit(0.5, 0.9)})
    scene, p0, p1 = three_pairs()
    p0, p1 = p0.copy(), p1.copy()
    p0[4, 0] = p1[4, 0] = 21.8  # pair 2: a gap of 1.2 closed at 3 per frame
    p1[5, 0] = 21.0
    res = scene.step(p0, p1, new_contacts_only=True)
    assert res.first.pair == 2 and res.first.time == pytest.approx(0.4, abs=1e-12)
    assert res.first.certainty == "certified" and res.certainty == "certified"
    assert res.counters.uncertain == 1 and res.counters.solved_exactly == 2


def test_run_flags_uncertain_frames(python_kernel):
    python_kernel({10.0: _limit(0.2, 0.3)})
    scene, p0, p1 = three_pairs()
    run = scene.run(np.stack([p0, p1, p1]), new_contacts_only=True, resolve_uncertain=False)
    assert run.uncertain.dtype == np.int8 and run.uncertain.tolist() == [1, 0]
    assert run.time[0] == 0.2 and run.pair[0] == 1 and 10.5 <= run.point[0][0] <= 10.7  # the estimate
    # colliding: only the pair overlapping at the start; the uncertain one is counted apart
    assert run.counters.shape == (2, 10) and run.counters[0, 8] == 1 and run.counters[0, 6] == 1


def test_frame_result_from_kernel_arrays():
    """The pure conversion of the kernel's arrays: an UNCERTAIN outcome becomes an uncertain contact."""
    from mjccd.scene import EXACT_HIT, UNCERTAIN, frame_result

    pairs = np.array([[0, 1], [1, 2]])
    outcome = np.array([EXACT_HIT, UNCERTAIN], np.int8)
    times, times_hi = np.array([0.6, 0.1]), np.array([123.0, 0.4])
    points, normals = np.array([[1.0, 2, 3], [0, 0, 0]]), np.array([[0.0, 0, 1], [0, 0, 0]])
    counters = np.array([2, 0, 0, 0, 0, 2, 1, 0, 1, 0])
    res = frame_result(pairs, 1, outcome, times, times_hi, points, normals, counters,
                       (np.array([[0.6, 0.7]]), np.array([0])))
    assert res.certainty == "uncertain" and res.counters.uncertain == 1 and res.counters.colliding == 1
    assert (res.first.pair, res.first.bodies, res.first.time) == (1, (1, 2), 0.1)
    assert (res.first.certainty, res.first.bracket, res.first.point, res.first.normal) == \
        ("uncertain", (0.1, 0.4), None, None)
    hit = res.contacts[0]
    assert (hit.certainty, hit.bracket, hit.intervals) == ("certified", None, ((0.6, 0.7),))
    assert hit.point.tolist() == [1, 2, 3]
    only = frame_result(pairs, 0, outcome, times, times_hi, points, normals, counters)
    assert only.certainty == "certified" and only.contacts == ()


# ---------------------------------------------------------------- the batch API: first_contact, may_touch, min_motion


def _same_first(fc, first):
    """A FirstContact equals the PairContact that step() gives as its first contact (arrays bit for bit)."""
    if first is None:
        return fc is None
    if fc is None or (fc.pair, fc.time, fc.bracket) != (first.pair, first.time, first.bracket):
        return False
    return all((a is None and b is None) or (a is not None and b is not None and np.array_equal(a, b))
               for a, b in ((fc.point, first.point), (fc.normal, first.normal)))


@pytest.mark.parametrize("motion", ["rigid", "affine"])
@pytest.mark.parametrize("new_only", [False, True])
def test_first_contact_equals_step_first(motion, new_only):
    """Frame after frame (the plane cache carried over in both scenes): the lean answer is step()'s first contact,
    and both leave the same plane cache behind."""
    radii, poses = random_frames(11 if motion == "rigid" else 12, 12)
    stepped, lean = Scene(radii, motion=motion), Scene(radii, motion=motion)
    kinds = set()
    for f in range(len(poses) - 1):
        res = stepped.step(poses[f], poses[f + 1], new_contacts_only=new_only)
        fc = lean.first_contact(poses[f], poses[f + 1], new_contacts_only=new_only)
        assert _same_first(fc, res.first), (f, fc, res.first)
        kinds.add("none" if fc is None else ("t0" if fc.point is None else "touch"))
        a, b = stepped.workspace.arrays, lean.workspace.arrays
        assert np.array_equal(a.cache_kind, b.cache_kind) and np.array_equal(a.cache_n, b.cache_n)
    assert "touch" in kinds and (new_only or "t0" in kinds), kinds
    assert stepped.workspace.arrays.cache_kind.any()  # the cache was used


def test_uncertain_first_contact_equals_step_first(python_kernel):
    """See three_pairs: pair 1 hits a limit, bracket [0.2, 0.3]: first_contact gives the same uncertain answer."""
    python_kernel({10.0: _limit(0.2, 0.3)})
    scene, p0, p1 = three_pairs()
    fc = scene.first_contact(p0, p1, new_contacts_only=True, resolve_uncertain=False)
    assert (fc.pair, fc.time, fc.bracket) == (1, 0.2, (0.2, 0.3))
    _assert_estimate_between_the_spheres(fc)
    assert _same_first(fc, scene.step(p0, p1, new_contacts_only=True, resolve_uncertain=False).first)


def _new_contacts_exact(radii, pairs, p0, p1, motion):
    """Pairs with a new contact (separate at the start, a contact or an uncertain answer later) by the pairwise
    exact solver, no filter in front."""
    cls = mjccd.Rigid if motion == "rigid" else mjccd.Affine
    out = []
    for k, (i, j) in enumerate(pairs):
        c = mjccd.first_contact(mjccd.Ellipsoid(radii[i]), cls(p0[i, :3], p0[i, 3:], p1[i, :3], p1[i, 3:]),
                                mjccd.Ellipsoid(radii[j]), cls(p0[j, :3], p0[j, 3:], p1[j, :3], p1[j, 3:]))
        if c is not None and c.status_at_start == "separate":
            out.append(k)
    return out


@pytest.mark.parametrize("motion", ["rigid", "affine"])
def test_may_touch_false_means_no_new_contact(motion):
    """Random frames, crowded and spread out: may_touch False only where neither the exact solver on every
    pair nor first_contact(new_contacts_only=True) finds a new contact; it does clear frames, and it does not
    clear frames with one."""
    seen = {True: 0, False: 0}
    for seed, spread in ((21, 1.0), (22, 3.0), (23, 6.0)):
        radii, poses = random_frames(seed, 8)
        poses[:, :, :3] *= spread
        scene = Scene(radii, motion=motion)
        for f in range(len(poses) - 1):
            may = scene.may_touch(poses[f], poses[f + 1])
            assert may is True or may is False
            seen[may] += 1
            if not may:
                assert _new_contacts_exact(radii, scene.pairs, poses[f], poses[f + 1], motion) == [], (seed, f)
                assert scene.first_contact(poses[f], poses[f + 1], new_contacts_only=True) is None
            elif scene.first_contact(poses[f], poses[f + 1], new_contacts_only=True) is not None:
                seen["hit"] = seen.get("hit", 0) + 1
    assert seen[True] > 0 and seen[False] > 0 and seen.get("hit", 0) > 0, seen


def _grazing(gap, motion, turn, y0=-0.8):
    """A flat ellipsoid at the origin and a ball sliding past its face from y = ``y0`` to 0.8, closest at ``gap``
    (times the radii sum; negative: overlapping) at y = 0; with ``turn`` the flat one also turns a little."""
    radii = np.array([[0.2, 1.0, 0.7], [0.3, 0.3, 0.3]])
    x = 0.2 + 0.3 + gap * 1.3
    p0 = np.array([[0, 0, 0, 1, 0, 0, 0], [x, y0, 0, 1, 0, 0, 0]], float)
    p1 = p0.copy()
    p1[1, 1] = 0.8
    if turn:
        p1[0, 3:] = [np.cos(turn / 2), 0, 0, np.sin(turn / 2)]
    return Scene(radii, motion=motion), radii, p0, p1


@pytest.mark.parametrize("motion", ["rigid", "affine"])
def test_may_touch_near_grazing(motion):
    """Gaps from 1e-3 down to 1e-12 of the size, either side of zero, with and without a turn: may_touch is
    False only when the exact solver finds no new contact.  Clear gaps are cleared (for a turning rigid body
    only by its largest semi-axis: not here), grazes within the slab margin and contacts are not, and a ball
    overlapping the face at the start and sliding off is no new contact."""
    cleared = []
    for gap in (1e-3, 1e-5, 1e-7, 1e-9, 1e-12, 0.0, -1e-12, -1e-9, -1e-5):
        for turn in (0.0, 1e-6, 0.05):
            scene, radii, p0, p1 = _grazing(gap, motion, turn)
            if not scene.may_touch(p0, p1):
                cleared.append((gap, turn))
                assert _new_contacts_exact(radii, scene.pairs, p0, p1, motion) == [], (gap, turn)
                assert scene.first_contact(p0, p1, new_contacts_only=True) is None
            elif gap == -1e-5 and turn == 0.0:
                assert _new_contacts_exact(radii, scene.pairs, p0, p1, motion) == [0]
    assert {(1e-3, 0.0), (1e-5, 0.0)} <= set(cleared) and all(gap > 1e-9 for gap, _ in cleared), cleared
    assert ((1e-5, 1e-6) in cleared) == (motion == "affine"), cleared
    scene, radii, p0, p1 = _grazing(-1e-3, motion, 0.0, y0=0.0)  # overlapping at the start, then sliding off
    assert not scene.may_touch(p0, p1) and _new_contacts_exact(radii, scene.pairs, p0, p1, motion) == []
    assert scene.first_contact(p0, p1).time == 0.0


def test_too_slow_outcome_and_counter():
    """min_motion 3.75 (see three_pairs: pair 0 does not move, pair 1 closes 4, pair 2 closes 3.5), and a fourth
    pair far away: pairs 0 and 2 are too slow (pair 0 overlapping, pair 2 touching later), pair 3 too: policy
    before filters, whatever the spheres say; with min_motion 3 only pair 0 and the far pair are slow (the far
    one closing 3.5 is culled by its spheres instead)."""
    scene, p0, p1 = three_pairs()
    far0 = np.array([[40, 0, 0, 1, 0, 0, 0], [50, 0, 0, 1, 0, 0, 0]], float)
    far1 = far0.copy()
    far1[1, 0] = 46.5
    p0, p1 = np.concatenate([p0, far0]), np.concatenate([p1, far1])
    scene = Scene(np.full((8, 3), 0.5), pairs=[[0, 1], [2, 3], [4, 5], [6, 7]])
    arrays = scene.workspace.arrays
    from mjccd.scene import EXACT_HIT, OUTCOME_NAMES, SPHERE, TOO_SLOW

    assert OUTCOME_NAMES[TOO_SLOW] == "too_slow" and TOO_SLOW == 8
    scene.set_min_motion(np.full(4, 3.75))
    res = scene.step(p0, p1)
    assert arrays.outcome.tolist() == [TOO_SLOW, EXACT_HIT, TOO_SLOW, TOO_SLOW]
    assert (res.counters.too_slow, res.counters.sphere_culled, res.counters.overlapping_t0) == (3, 0, 0)
    assert res.first.pair == 1 and arrays.entry[[0, 2, 3]].tolist() == [-1.0, -1.0, -1.0]
    scene.set_min_motion([3.0, 3.0, 3.0, 3.0])
    res = scene.step(p0, p1)
    assert arrays.outcome[[0, 3]].tolist() == [TOO_SLOW, SPHERE]
    assert (res.counters.too_slow, res.counters.sphere_culled) == (1, 1)
    run = scene.run(np.stack([p0, p1]))
    assert run.counters[0, 9] == 1 and run.counters[0, 1] == 1 and run.outcomes[0, 0] == TOO_SLOW
    scene.set_min_motion(np.zeros(4))
    res = scene.step(p0, p1)
    assert res.counters.too_slow == 0 and res.first.pair == 0 and res.first.time == 0.0


def test_set_min_motion_refuses_bad_values():
    scene, _, _ = three_pairs()
    with pytest.raises(ValueError, match=r"^min_motion: expected shape 3, got \(2,\)$"):
        scene.set_min_motion([1.0, 2.0])
    with pytest.raises(ValueError, match=r"^min_motion: contains NaN or infinity$"):
        scene.set_min_motion([0.0, np.nan, 1.0])
    with pytest.raises(ValueError, match=r"^min_motion: contains NaN or infinity$"):
        scene.set_min_motion([0.0, 1.0, np.inf])
    with pytest.raises(ValueError, match=r"^min_motion\[1\]: expected a distance >= 0, got -0.5$"):
        scene.set_min_motion([0.0, -0.5, 1.0])
    with pytest.raises(ValueError, match=r"^min_motion: expected numbers, got 'fast'$"):
        scene.set_min_motion("fast")
    with pytest.raises(mjccd.errors.InputError):
        scene.set_min_motion(2.0)  # one number for every pair: not (P,)
    assert scene.min_motion.tolist() == [0.0, 0.0, 0.0]  # nothing was set
    with pytest.raises(ValueError, match="read-only"):
        scene.min_motion[0] = 1.0
    scene.set_min_motion(np.array([1, 2, 3]))  # integers are distances too
    assert scene.min_motion.tolist() == [1.0, 2.0, 3.0]


@pytest.mark.parametrize("aspect", [20.0, 100.0])
def test_scene_agrees_with_first_contact_on_thin_pairs(aspect):
    """Random close pairs with one thin body (given first or second): a two-body Scene, which has no rational
    tier, gives first_contact's time within 1e-9 when it certifies, and a bracket holding it when it cannot."""
    from mjccd.bench import peers

    rng = np.random.default_rng(int(aspect))
    uncertain = 0
    for q in peers.random_rigid_queries(40, seed=int(aspect) + 1, max_angle=0.5):
        radii = [np.array(q.radii_a, float), np.array(q.radii_b, float)]
        radii[int(rng.integers(2))][rng.integers(3)] /= aspect
        start = np.array([np.r_[q.position_a[0], q.quaternion_a[0]], np.r_[q.position_b[0], q.quaternion_b[0]]])
        end = np.array([np.r_[q.position_a[1], q.quaternion_a[1]], np.r_[q.position_b[1], q.quaternion_b[1]]])
        first = Scene(radii).step(start, end).first
        api = mjccd.first_contact(mjccd.Ellipsoid(radii[0]), mjccd.Rigid(start[0, :3], start[0, 3:], end[0, :3],
                                                                        end[0, 3:]),
                                  mjccd.Ellipsoid(radii[1]), mjccd.Rigid(start[1, :3], start[1, 3:], end[1, :3],
                                                                        end[1, 3:]))
        assert api is None or api.certainty == "certified"
        if first is None:
            assert api is None
        elif first.bracket is None:
            assert api is not None and abs(first.time - api.time) <= 1e-9
        else:
            uncertain += 1
            assert first.time == first.bracket[0]
            assert api is None or first.bracket[0] - 1e-12 <= api.time <= first.bracket[1] + 1e-12
    assert uncertain < 30
