"""The one MuJoCo adapter: chain motions that follow MuJoCo's kinematics with joint references, and the same
contacts from the monitor, the guard's step check, replay and mjccd.testing on the same states."""
import mujoco
import numpy as np
import pytest

from mjccd import replay
from mjccd.mujoco import CCDMonitor, GuardedStepper, ModelAdapter, State, fit_model, geom_ellipsoids
from mjccd.mujoco.monitor import StepCheck
from mjccd.testing import trajectory_contacts

# two characters: an arm on the world whose hinges and slide have non-zero references (one hinge is driven past
# pi from its reference), and a free body with a ball-jointed head flying into it
MODEL = """
<mujoco>
 <option timestep="0.01"/>
 <worldbody>
  <body name="a_arm" pos="0 0 0.5" euler="0 0 10">
   <joint name="a_shoulder" type="hinge" axis="0 1 0" pos="0 0 -0.05" ref="0.7"/>
   <geom name="a_arm_bound" type="ellipsoid" size="0.25 0.06 0.06" pos="0.2 0 0" group="5"/>
   <body name="a_fore" pos="0.4 0 0" quat="0.98 0 0.2 0">
    <joint name="a_reach" type="slide" axis="1 0 0.2" ref="0.1"/>
    <joint name="a_elbow" type="hinge" axis="0 0 1" pos="0.02 0 0" ref="-0.5"/>
    <geom name="a_fore_bound" type="ellipsoid" size="0.2 0.05 0.05" pos="0.15 0 0" group="5"/>
   </body>
  </body>
  <body name="b_torso" pos="1.2 0 0.5">
   <freejoint/>
   <geom name="b_torso_bound" type="ellipsoid" size="0.15 0.1 0.2" group="5"/>
   <body name="b_head" pos="0 0 0.3">
    <joint name="b_neck" type="ball" pos="0 0 -0.05"/>
    <geom name="b_head_bound" type="ellipsoid" size="0.08 0.08 0.1" pos="0 0.02 0" group="5"/>
   </body>
  </body>
 </worldbody>
</mujoco>
"""
FRAMES = 40


def _trajectory(model):
    """(T, nq) qpos: the arm swings (its elbow from 2.9 to 3.6 rad past its reference), the free body flies in."""
    s = np.linspace(0.0, 1.0, FRAMES)
    qpos = np.tile(model.qpos0, (FRAMES, 1))
    qpos[:, 0] = 0.7 + 0.4 * s              # a_shoulder: 0 .. 0.4 from its reference
    qpos[:, 1] = 0.1 + 0.15 * np.sin(3 * s)  # a_reach
    qpos[:, 2] = -0.5 + 2.9 + 0.7 * s        # a_elbow: 2.9 .. 3.6 rad from its reference (beyond pi)
    qpos[:, 3] = 1.2 - 0.9 * s               # b_torso flies in along -x, turning
    qpos[:, 5] = 0.5 - 0.1 * s
    angle = 1.5 * s
    qpos[:, 6:10] = np.stack([np.cos(angle / 2), 0 * s, np.sin(angle / 2) * 0.6, np.sin(angle / 2) * 0.8], axis=1)
    tilt = 0.8 * s
    qpos[:, 10:14] = np.stack([np.cos(tilt / 2), np.sin(tilt / 2), 0 * s, 0 * s], axis=1)
    return qpos


@pytest.fixture(scope="module")
def scene(tmp_path_factory):
    folder = tmp_path_factory.mktemp("adapter")
    model_file = folder / "model.xml"
    model_file.write_text(MODEL)
    model = mujoco.MjModel.from_xml_path(str(model_file))
    qpos = _trajectory(model)
    times = np.arange(FRAMES) * model.opt.timestep
    traj = folder / "traj.npz"
    np.savez(traj, qpos=qpos, time=times)
    none = (np.zeros((0, 3)), np.zeros((0, 4)))
    states = [State(q, *none, float(t)) for q, t in zip(qpos, times)]
    return model, model_file, traj, qpos, times, states


def _geom_frames(model, qpos, geoms):
    """MuJoCo's own world frames [R | p] (3 x 4) of the named geoms at ``qpos``."""
    d = mujoco.MjData(model)
    d.qpos[:] = qpos
    mujoco.mj_kinematics(model, d)
    return [np.hstack([d.geom_xmat[g].reshape(3, 3), d.geom_xpos[g][:, None]])
            for g in (model.geom(name).id for name in geoms)]


def _key(c):
    """What a contact is, for comparing paths: the pair of bodies, the step fraction, the point."""
    return c.bodies, c.fraction, None if c.point is None else tuple(c.point)


def test_chain_motion_follows_mujoco_with_joint_references(scene):
    """At every frame both ends of the chain motion, and the chain filters' poses, are MuJoCo's kinematics."""
    model, _, _, qpos, _, states = scene
    assert np.count_nonzero(model.qpos0[:3]) == 3  # the hinges and the slide have references
    ellipsoids, pairs = replay.replay_ellipsoids(model)
    checker = ModelAdapter(model, ellipsoids, pairs, "chain")
    layout = checker.chains
    worst = 0.0
    for k in range(FRAMES - 1):
        motions = checker.chain_motions(states[k], states[k + 1])
        v0, v1 = layout.values(states[k]), layout.values(states[k + 1])
        for t, q in ((0.0, qpos[k]), (1.0, qpos[k + 1])):
            want = _geom_frames(model, q, ellipsoids.geoms)
            centres, quats = checker.chain_filter.poses(v0, v1, t)
            for e, (motion, frame) in enumerate(zip(motions, want)):
                worst = max(worst, np.abs(motion.transform(t) - frame).max())
                np.testing.assert_allclose(centres[e], frame[:, 3], atol=1e-12)
                R = np.empty(9)
                mujoco.mju_quat2Mat(R, quats[e])
                np.testing.assert_allclose(R.reshape(3, 3), frame[:, :3], atol=1e-12)
    assert worst < 1e-12, worst


def test_chain_replay_equals_the_monitor_with_joint_references(scene):
    """replay --motion chain on the reference-joint model: every first contact equals the monitor's on the same
    states (all pairs reported, new contacts only)."""
    model, model_file, traj, _, times, states = scene
    result = replay.replay(model_file, traj, "chain", None, progress=False)
    assert len(result.contacts) >= 2
    monitor = CCDMonitor(model, mujoco.MjData(model), geom_ellipsoids(model), pairs="characters", motion="chain",
                         all_pairs=True, report_overlapping=False)
    expected = []
    for k in range(FRAMES - 1):
        monitor.check(states[k], states[k + 1])
        expected += [(k, c.ellipsoids, c.fraction, tuple(c.point) if c.point is not None else (0.0, 0.0, 0.0))
                     for c in sorted(monitor.last_report.contacts, key=lambda c: c.pair)]
    names = list(result.ellipsoids.geoms)
    got = [(c["frame"], tuple(names.index(n) for n in c["ellipsoids"]), c["toi"], tuple(c["point"]))
           for c in result.contacts]
    assert got == expected


@pytest.mark.parametrize("mode", ["geoms", "ellipsoids"])
def test_monitor_guard_replay_and_testing_give_the_same_contacts(scene, mode):
    """One model, one trajectory, rigid motion: the MuJoCo-facing paths find the same contacts (geoms mode, the
    default, and ellipsoid mode, which adds the guard's lean step check)."""
    model, model_file, traj, qpos, times, states = scene
    ellipsoids = geom_ellipsoids(model)
    chosen = None if mode == "geoms" else mode
    new_only = CCDMonitor(model, mujoco.MjData(model), ellipsoids, pairs="characters", all_pairs=True,
                          report_overlapping=False, mode=chosen)
    every = CCDMonitor(model, mujoco.MjData(model), ellipsoids, pairs="characters", mode=chosen)
    assert new_only.mode == every.mode == mode
    per_frame_new, per_frame_first, firsts = [], [], []
    for k in range(FRAMES - 1):
        new_only.check(states[k], states[k + 1])
        per_frame_new.append(sorted((_key(c) for c in new_only.last_report.contacts), key=str))
        per_frame_first.append(new_only.last_report.first)
        firsts.append(every.check(states[k], states[k + 1]))
    assert sum(map(len, per_frame_new)) >= 2 and any(c is not None and c.status_at_start != "separate"
                                                      for c in firsts)

    # replay: every new contact of every frame
    result = replay.replay(model_file, traj, "rigid", None, progress=False, mode=chosen)
    assert result.mode == mode
    by_frame = [[] for _ in range(FRAMES - 1)]
    for c in result.contacts:
        by_frame[c["frame"]].append((tuple(c["bodies"]), c["toi"], tuple(c["point"])))
    assert [sorted(f, key=str) for f in by_frame] == per_frame_new

    if mode == "ellipsoids":  # the guard's step check: the earliest new contact of each step
        check = StepCheck(CCDMonitor(model, mujoco.MjData(model), ellipsoids, pairs="characters",
                                     report_overlapping=False, mode="ellipsoids"))
        data = mujoco.MjData(model)
        for k in range(FRAMES - 1):
            data.qpos[:] = qpos[k]
            check.begin(data)
            data.qpos[:] = qpos[k + 1]
            may = check.end_may_touch(data)
            lean = check.first((times[k], times[k + 1]))
            want = per_frame_first[k]
            assert (lean is None) == (want is None), k
            if want is not None:
                assert may and _key(lean) == _key(want) and lean.time == want.time

    # mjccd.testing: the first contact of each step, contacts at the step start included
    found = trajectory_contacts(model, qpos, pairs="characters", ellipsoids=ellipsoids, times=times, mode=chosen)
    assert [(_key(c), c.time, c.status_at_start) for c in found] == \
        [(_key(c), c.time, c.status_at_start) for c in firsts if c is not None]


FLOOR = """
<mujoco>
  <compiler angle="radian"/>
  <option gravity="0 0 0" timestep="0.01"/>
  <worldbody>
    <geom name="floor" type="plane" size="5 5 0.1" pos="0 0 -0.25" euler="0.3 0 0"/>
    <body name="ball" pos="0 0 1"><freejoint/><geom type="sphere" size="0.1"/></body>
  </worldbody>
</mujoco>
"""


@pytest.mark.parametrize("motion", ["rigid", "affine", "chain"])
def test_a_ball_falling_onto_a_tilted_floor_touches_at_the_closed_form_time(motion):
    """The floor is a plane geom (tilted 0.3 rad about x, 0.25 m down): the monitor checks it by MuJoCo's
    rules, and the contact comes at the time the ball's lowest point along the floor's normal reaches it."""
    model = mujoco.MjModel.from_xml_string(FLOOR)
    data = mujoco.MjData(model)
    data.qvel[2] = -10.0
    mujoco.mj_forward(model, data)
    normal = np.array([0.0, -np.sin(0.3), np.cos(0.3)])  # the floor's z axis in the world
    height = normal @ (np.array([0.0, 0.0, 1.0]) - np.array([0.0, 0.0, -0.25])) - 0.1
    t_star = height / (10.0 * normal[2])
    monitor = CCDMonitor(model, data, fit_model(model), motion=motion)
    if monitor.mode == "geoms":  # the rigid motion: the ball geom and the floor geom, one pair of the geoms
        assert motion == "rigid" and monitor.pairs.tolist() == [[1, 0]] and len(monitor.plane_pairs) == 0
    else:
        assert len(monitor.pairs) == 0 and monitor.plane_pairs.tolist() == [[0, 0]]
    contact = None
    while contact is None and data.time < 0.5:
        contact = monitor.step()
    assert contact is not None and contact.status_at_start == "separate"
    assert abs(contact.time - t_star) <= 1e-9 * model.opt.timestep
    assert contact.bodies == ("ball", "world") and contact.geom == 0
    if monitor.mode == "geoms":
        assert contact.geoms == (1, 0) and contact.elements == ("surface", "plane")
    else:
        assert contact.ellipsoids == (0, -1)
    assert np.allclose(contact.normal, -normal, atol=1e-9)
    centre = np.array([0.0, 0.0, 1.0 - 10.0 * t_star])
    assert np.allclose(contact.point, centre - 0.1 * normal, atol=1e-9)


def test_planes_can_be_left_out_and_the_guard_lands_a_fast_ball_on_the_floor():
    model = mujoco.MjModel.from_xml_string(FLOOR)
    data = mujoco.MjData(model)
    assert len(CCDMonitor(model, data, fit_model(model), planes=False).plane_pairs) == 0

    data.qvel[2] = -200.0  # 2 m per step: plain MuJoCo would start the contact 1 m below the floor
    mujoco.mj_forward(model, data)
    guard = GuardedStepper(model, data, fit_model(model))
    for _ in range(10):
        guard.step()
    assert guard.clamps_total >= 1
    normal = np.array([0.0, -np.sin(0.3), np.cos(0.3)])
    assert normal @ (data.qpos[:3] - np.array([0.0, 0.0, -0.25])) > 0.0  # the centre stayed above the floor


def test_plane_clearance_is_the_centre_height_less_the_support():
    from mjccd.mujoco.adapter import plane_clearance
    from mjccd.quadric import quat_to_matrix

    rng = np.random.default_rng(1)
    for _ in range(50):
        q = rng.normal(size=4)
        q /= np.linalg.norm(q)
        pose, radii = np.r_[rng.normal(size=3), q], rng.uniform(0.1, 1.0, 3)
        normal = rng.normal(size=3)
        normal /= np.linalg.norm(normal)
        support = np.sqrt(np.sum((radii * (quat_to_matrix(q).T @ normal)) ** 2))
        assert plane_clearance(radii, pose, np.r_[normal, 0.3]) == pytest.approx(normal @ pose[:3] - 0.3 - support,
                                                                                  abs=1e-12)


# a heap of free bodies over a floor: random states leave many pairs overlapping and many bodies below the floor
HEAP = """
<mujoco>
 <worldbody>
  <geom name="floor" type="plane" size="5 5 0.1"/>
""" + "".join(f"""  <body name="b{k}" pos="0 0 1"><freejoint/>
   <geom type="ellipsoid" size="{0.1 + 0.02 * k} {0.06 + 0.01 * k} 0.05"/></body>
""" for k in range(6)) + """ </worldbody>
</mujoco>
"""


def _heap_states(adapter, n, seed):
    """n random (poses t0, poses t1) of HEAP's ellipsoids: bodies near one another and the floor, moving a little."""
    rng = np.random.default_rng(seed)
    nb = adapter.model.nbody - 1
    for _ in range(n):
        q = np.zeros(7 * nb)
        for b in range(nb):
            q[7 * b:7 * b + 3] = rng.uniform([-0.3, -0.3, -0.05], [0.3, 0.3, 0.3])
            quat = rng.normal(size=4)
            q[7 * b + 3:7 * b + 7] = quat / np.linalg.norm(quat)
        q1 = q.copy()
        q1[0::7] += rng.uniform(-0.05, 0.05, nb)
        none = (np.empty((0, 3)), np.empty((0, 4)))
        yield adapter.poses(State(q, *none, 0.0)), adapter.poses(State(q1, *none, 0.01))


def test_start_status_from_the_scene_outcome_equals_the_static_status_recomputed():
    """A contact at t = 0 that the scene's outcome proves (OVERLAP_T0) reports the static status of the start
    poses recomputed from scratch: the same on random states, pairs of ellipsoids and plane pairs alike."""
    from mjccd.mujoco.pairs import plane_pairs
    from mjccd.scene import all_pairs

    model = mujoco.MjModel.from_xml_string(HEAP)
    ellipsoids = fit_model(model)
    adapter = ModelAdapter(model, ellipsoids, all_pairs(len(ellipsoids)), "rigid",
                           plane_pairs=plane_pairs(model, ellipsoids))
    seen = {"pair": 0, "plane": 0}
    for p0, p1 in _heap_states(adapter, 60, 3):
        report = adapter.check_poses(0.0, 0.01, p0, p1, all_pairs=True)
        first = adapter.check_poses(0.0, 0.01, p0, p1).first
        for c in report.contacts + (() if first is None else (first,)):
            if c.fraction == 0.0 and c.point is None and c.certainty == "certified":
                recomputed = adapter.contact(0.0, 0.01, c.pair, 0.0, None, None, p0)
                assert c.status_at_start == recomputed.status_at_start == "overlapping"
                seen["plane" if c.geom >= 0 else "pair"] += 1
    assert seen["pair"] > 20 and seen["plane"] > 20


def test_step_counters_are_a_read_only_mapping_equal_to_the_dict():
    from mjccd.mujoco.adapter import COUNTER_NAMES, StepCounters

    counts = list(range(len(COUNTER_NAMES)))
    counters = StepCounters(counts)
    assert counters == dict(zip(COUNTER_NAMES, counts)) and dict(zip(COUNTER_NAMES, counts)) == counters
    assert list(counters) == list(COUNTER_NAMES) and counters["uncertain"] == 8 and len(counters) == 10
    assert repr(counters) == repr(dict(zip(COUNTER_NAMES, counts)))
    with pytest.raises(KeyError):
        counters["nothing"]
    with pytest.raises(TypeError):
        counters["pairs"] = 1
