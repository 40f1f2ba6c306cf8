"""BatchScene against one Scene per world: the same answers bit for bit, worlds independent, bad worlds named."""
import numba
import numpy as np
import pytest

from mjccd.batch import BatchScene
from mjccd.errors import InputError
from mjccd.plane import Plane
from mjccd.scene import CACHED_PLANE, UNCERTAIN, Scene

N = 5
FLOOR = [Plane((0.0, 0.0, 1.0), -0.55)]


def random_worlds(seed, worlds, frames, box=0.6):
    """Radii (N, 3) and smooth pose sequences (worlds, frames + 1, N, 7) of ellipsoids crowded into a small box."""
    r = np.random.default_rng(seed)
    radii = r.uniform(0.15, 0.45, (N, 3))
    pos = r.uniform(-box, box, (worlds, N, 3))
    vel = r.normal(size=(worlds, N, 3)) * 0.2
    q = r.normal(size=(worlds, N, 4))
    w = r.normal(size=(worlds, N, 4)) * 0.3
    poses = np.empty((worlds, frames + 1, N, 7))
    for f in range(frames + 1):
        poses[:, f, :, :3] = pos
        poses[:, f, :, 3:] = q / np.linalg.norm(q, axis=2, keepdims=True)
        pos = pos + vel
        vel = np.where(np.abs(pos) > box + 0.1, -vel, vel)
        q = q + w
    return radii, poses


def scenes(radii, worlds, **kwargs):
    return [Scene(radii, **kwargs) for _ in range(worlds)]


def assert_same_first(batch, b, first):
    """World b of a BatchContacts equals a Scene's FirstContact (None: no contact), bit for bit."""
    if first is None:
        assert (batch.pair[b], batch.frame[b], batch.time[b], batch.time_hi[b], batch.outcome[b]) == (-1,) * 5
        assert not batch.point[b].any() and not batch.normal[b].any()
        return
    assert batch.pair[b] == first.pair
    assert batch.time[b] == first.time
    assert batch.time_hi[b] == (first.time if first.bracket is None else first.bracket[1])
    assert (batch.outcome[b] == UNCERTAIN) == (first.bracket is not None)
    if first.point is None:
        assert not batch.point[b].any() and not batch.normal[b].any()
    else:
        assert np.array_equal(batch.point[b], first.point) and np.array_equal(batch.normal[b], first.normal)


CASES = [("rigid", None, True), ("affine", None, True), ("rigid", FLOOR, True), ("affine", FLOOR, False)]


@pytest.mark.parametrize("motion, planes, cache", CASES)
def test_first_contacts_equal_one_scene_per_world(motion, planes, cache):
    radii, poses = random_worlds(1, 6, 5)
    kwargs = dict(motion=motion, planes=planes, plane_cache=cache)
    batch = BatchScene(radii, 6, **kwargs)
    singles = scenes(radii, 6, **kwargs)
    hits = 0
    for f in range(5):
        got = batch.first_contacts(poses[:, f], poses[:, f + 1])
        assert got.ok.all() and got.errors == {}
        for b, scene in enumerate(singles):
            first = scene.first_contact(poses[b, f], poses[b, f + 1])
            assert_same_first(got, b, first)
            assert got.frame[b] == (-1 if first is None else 0)
            hits += first is not None
    assert hits > 5


@pytest.mark.parametrize("motion, planes, cache", CASES)
def test_step_gives_every_colliding_pair_of_each_world(motion, planes, cache):
    radii, poses = random_worlds(2, 5, 4)
    kwargs = dict(motion=motion, planes=planes, plane_cache=cache)
    batch = BatchScene(radii, 5, **kwargs)
    singles = scenes(radii, 5, **kwargs)
    for f in range(4):
        for all_pairs, new_only in ((True, False), (False, True), (True, True)):
            got = batch.step(poses[:, f], poses[:, f + 1], all_pairs=all_pairs, new_contacts_only=new_only)
            for b, scene in enumerate(singles):
                res = scene.step(poses[b, f], poses[b, f + 1], all_pairs=all_pairs, new_contacts_only=new_only)
                a = scene.workspace.arrays
                assert np.array_equal(got.outcome[b], a.outcome)
                assert np.array_equal(got.counters[b], a.counters)
                hit = a.times >= 0.0
                assert np.array_equal(got.time[b][hit], a.times[hit]) and (got.time[b][~hit] == -1.0).all()
                if all_pairs:
                    assert set(np.flatnonzero(got.time[b] >= 0.0).tolist()) == {c.pair for c in res.contacts}
                first = res.first
                assert (got.first.pair[b], got.first.time[b]) == ((-1, -1.0) if first is None
                                                                  else (first.pair, first.time))


def test_worlds_are_independent_of_the_batch():
    """Answers do not change when worlds are added, removed or permuted, nor with the number of threads."""
    radii, poses = random_worlds(3, 7, 4)
    full = BatchScene(radii, 7, planes=FLOOR)
    order = np.array([5, 2, 6, 0])
    part = BatchScene(radii, 4, planes=FLOOR)
    threads = numba.get_num_threads()
    try:
        for f in range(4):
            numba.set_num_threads(1 + f % threads)
            a = full.step(poses[:, f], poses[:, f + 1])
            numba.set_num_threads(threads)
            b = part.step(poses[order, f], poses[order, f + 1])
            for name in ("pair", "time", "time_hi", "point", "normal", "outcome"):
                assert np.array_equal(getattr(a.first, name)[order], getattr(b.first, name)), name
            assert np.array_equal(a.outcome[order], b.outcome)
            assert np.array_equal(a.time[order], b.time)
    finally:
        numba.set_num_threads(threads)


def frame_loop(scene, seq, new_only=False):
    """(frame, FirstContact) of the first frame of a pose sequence with a contact, frame by frame; (-1, None)."""
    for f in range(len(seq) - 1):
        first = scene.first_contact(seq[f], seq[f + 1], new_contacts_only=new_only)
        if first is not None:
            return f, first
    return -1, None


def assert_same_along(got, b, frame, first):
    assert got.frame[b] == frame
    assert_same_first(got._replace(frame=np.where(got.frame >= 0, 0, -1)), b, first)


@pytest.mark.parametrize("motion, planes", [("rigid", [Plane((0.0, 0.0, 1.0), -1.5)]), ("affine", None)])
@pytest.mark.parametrize("new_only", [False, True])
def test_first_contacts_along_equals_a_frame_loop(motion, planes, new_only):
    radii, poses = random_worlds(5, 6, 7, box=1.2)  # first contacts in frames 0 to 6, or none
    batch = BatchScene(radii, 6, motion=motion, planes=planes)
    got = batch.first_contacts_along(poses, new_contacts_only=new_only)
    assert got.ok.all()
    for b in range(6):
        assert_same_along(got, b, *frame_loop(Scene(radii, motion=motion, planes=planes), poses[b], new_only))
    assert (got.frame > 0).any() and len(set(got.frame.tolist())) >= 3


def test_bad_poses_fail_only_their_world():
    radii, poses = random_worlds(5, 4, 1)
    p0, p1 = poses[:, 0].copy(), poses[:, 1].copy()
    p1[2, 3, 1] = np.nan
    p0[0, 4, 3:] = 0.0
    batch = BatchScene(radii, 4)
    got = batch.first_contacts(p0, p1)
    assert got.ok.tolist() == [False, True, False, True]
    assert got.errors == {0: "poses_t0[0]: ellipsoid 4 has a zero quaternion",
                          2: "poses_t1[2]: ellipsoid 3 has a non-finite value"}
    for b in (0, 2):
        assert (got.pair[b], got.time[b], got.frame[b]) == (-1, -1.0, -1)
    for b in (1, 3):
        assert_same_first(got, b, Scene(radii).first_contact(p0[b], p1[b]))
    seq = np.repeat(poses[:, :1], 3, axis=1)  # standing still: no new contact in any frame
    seq[1, 2, 0, 6] = np.inf
    along = batch.first_contacts_along(seq, new_contacts_only=True)
    assert along.errors == {1: "poses[1][2]: ellipsoid 0 has a non-finite value"}
    assert along.ok.tolist() == [True, False, True, True] and (along.frame == -1).all()
    assert Scene(radii).first_contact(seq[1, 0], seq[1, 1]) is not None  # overlapping from the start
    assert batch.first_contacts_along(seq).ok[1]  # its contact in frame 0 ends it: set 2 is never read


def test_huge_quaternions_are_normalised_as_scene_does():
    radii, poses = random_worlds(6, 3, 2)
    poses[1, :, :, 3:] *= 1e200  # their squared norms overflow: normalised in Python, as Scene.step does
    batch = BatchScene(radii, 3)
    for f in range(2):
        got = batch.first_contacts(poses[:, f], poses[:, f + 1])
        assert got.ok.all()
        for b in range(3):
            assert_same_first(got, b, Scene(radii).first_contact(poses[b, f], poses[b, f + 1]))
    along = BatchScene(radii, 3).first_contacts_along(poses)
    for b in range(3):
        assert_same_along(along, b, *frame_loop(Scene(radii), poses[b]))


def test_wrong_shapes_name_the_field():
    radii, poses = random_worlds(7, 3, 1)
    batch = BatchScene(radii, 3)
    with pytest.raises(InputError, match=r"^poses_t1: expected shape 3x5x7 \(worlds, \.\.\.\), got \(2, 5, 7\)$"):
        batch.first_contacts(poses[:, 0], poses[:2, 1])
    with pytest.raises(InputError, match=r"^poses_t0: expected shape 3x5x7"):
        batch.step(poses[:, 0, :4], poses[:, 1])
    with pytest.raises(InputError, match=r"^poses: expected shape 3xTx5x7"):
        batch.first_contacts_along(poses[:, :, :, :6])
    with pytest.raises(InputError, match=r"^poses: expected at least 2 pose sets per world"):
        batch.first_contacts_along(poses[:, :1])
    with pytest.raises(InputError, match=r"^poses_t0: expected numbers of shape 3x5x7$"):
        batch.first_contacts("poses", poses[:, 1])
    with pytest.raises(InputError, match=r"^worlds: expected a number of worlds >= 1, got 0$"):
        BatchScene(radii, 0)
    with pytest.raises(InputError, match=r"^pairs\[0\]: index out of range for 5 ellipsoids"):
        BatchScene(radii, 2, pairs=[[0, 7]])
    with pytest.raises(InputError, match=r"^worlds: expected world indices in 0..2"):
        batch.reset_cache([3])


def test_cache_and_min_motion_per_world():
    radii, poses = random_worlds(8, 3, 3)
    batch = BatchScene(radii, 3)
    singles = scenes(radii, 3)
    slow = np.full(len(batch.pairs), 0.05)
    batch.set_min_motion(slow)
    for s in singles:
        s.set_min_motion(slow)
    cached = 0
    for f in range(3):
        if f == 2:
            batch.reset_cache([1])
            singles[1].reset_cache()
        got = batch.step(poses[:, f], poses[:, f + 1], all_pairs=False)
        for b, scene in enumerate(singles):
            scene.step(poses[b, f], poses[b, f + 1])
            assert np.array_equal(got.outcome[b], scene.workspace.arrays.outcome)
        cached += int((got.outcome == CACHED_PLANE).sum())
    assert cached > 0
    assert np.array_equal(batch.min_motion, slow)
    with pytest.raises(InputError, match=r"^min_motion\[0\]: expected a distance >= 0"):
        batch.set_min_motion(-slow)


def test_worlds_the_kernel_leaves_uncertain_are_asked_again():
    """The hard rigid cases of the shared set, each in a batch of two worlds (the case, and the case with its end
    poses at both ends of a first frame): every world answers as a Scene of its own, which asks the core again
    about what its kernel leaves uncertain; first_contacts_along finds the same contact in frame 1."""
    from test_scene import _hard_rigid_cases, _holds

    for name, radii, p0, p1, t in _hard_rigid_cases():
        batch = BatchScene(radii, 2)
        got = batch.first_contacts(np.stack([p0, p0]), np.stack([p1, p1]))
        first = Scene(radii).first_contact(p0, p1)
        assert _holds(first, t), name
        for b in range(2):
            assert_same_first(got, b, first)
        step = batch.step(np.stack([p0, p0]), np.stack([p1, p1]))
        assert_same_first(step.first, 0, first)
        assert not (step.outcome == UNCERTAIN).any() or first is not None and first.bracket is not None, name
        raw = batch.first_contacts(np.stack([p0, p0]), np.stack([p1, p1]), resolve_uncertain=False)
        assert_same_first(raw, 0, Scene(radii).first_contact(p0, p1, resolve_uncertain=False))
        still = np.stack([p0, p0, p1])  # frame 0 does not move (the pair is separate or in contact at t = 0)
        along = BatchScene(radii, 1).first_contacts_along(still[None])
        if first is not None and first.time > 0.0:
            assert along.frame[0] == 1, name
            assert_same_first(along, 0, first)


def _clear_thin_pair():
    """(radii, poses_t0, poses_t1): a 1000:1 disk passing 1e-5 of its size clear of another, edge over face (the
    stacked family of tests/test_adversarial.py, whose fourth case of this seed it is)."""
    import random

    import test_adversarial as ta
    from test_scene import _two_pose_poses

    rng = random.Random(5)
    for n in range(4):
        delta = [1e-5, 1e-4, 1e-3][n % 3] * (1 if (n // 3) % 2 else -1)
        ra, rb = [(ta.DISK_FACE, ta.DISK_FACE), (ta.NEEDLE_UP, ta.DISK_FACE), (ta.NEEDLE_FLAT, ta.NEEDLE_FLAT),
                  (ta.DISK_EDGE, ta.DISK_FACE)][n % 4]
        case = ta._stacked(rng, f"c{n}", list(ra), list(rb), delta, n % 5 < 2, [])
    return [ra, rb], *_two_pose_poses(case)


def test_a_possible_contact_proven_free_goes_on_to_the_next_frame():
    """The kernel calls the clear pair a possible contact; the core proves it free.  Along two frames (the pass,
    then b moved onto a), each world's first contact is then in frame 1, as a frame loop of Scenes says."""
    radii, p0, p1 = _clear_thin_pair()
    raw = Scene(radii).step(p0, p1, resolve_uncertain=False).first
    assert raw is not None and raw.bracket is not None  # the kernel's "possible contact"
    assert Scene(radii).step(p0, p1).first is None and Scene(radii).first_contact(p0, p1) is None
    onto = p1.copy()
    onto[1, :3] = p1[0, :3]  # b's centre moved to a's: they overlap at the end of frame 1
    seq = np.stack([p0, p1, onto])
    along = BatchScene(radii, 2).first_contacts_along(np.stack([seq, seq]))
    want = frame_loop(Scene(radii), seq)
    assert want[0] == 1
    for b in range(2):
        assert_same_along(along, b, *want)
    first = BatchScene(radii, 1).first_contacts(p0[None], p1[None])
    assert first.pair[0] == -1 and first.outcome[0] == -1
