"""Geoms mode in the MuJoCo layer (mjccd.mujoco.geoms): which geoms are real, MuJoCo's pair rules on them, meshes,
resting contacts, the guard, and the answers against MuJoCo's own signed distance."""
import pathlib
import warnings

import mujoco
import numpy as np
import pytest

from mjccd.mujoco import CCDMonitor, GuardedStepper, fit_model
from mjccd.mujoco.geoms import GeomChecker, real_geoms
from mjccd.mujoco.motions import capture
from mjccd.mujoco.warnings import CoverageWarning

ROOT = pathlib.Path(__file__).parents[1]

RESTING = """
<mujoco>
  <option timestep="0.002"/>
  <worldbody>
    <geom name="floor" type="plane" size="5 5 0.1"/>
    <body name="ball" pos="0 0 0.1"><freejoint/><geom type="sphere" size="0.1"/></body>
    <body name="crate" pos="1 0 0.2"><freejoint/><geom type="box" size="0.2 0.2 0.2"/></body>
  </worldbody>
</mujoco>
"""


def test_resting_bodies_touch_at_the_step_start_and_are_never_new_contacts():
    """A ball and a crate settled on the floor: every step finds them touching or overlapping at its start (as
    MuJoCo's soft contacts leave them), never a new contact."""
    model = mujoco.MjModel.from_xml_string(RESTING)
    data = mujoco.MjData(model)
    for _ in range(300):  # let MuJoCo settle them
        mujoco.mj_step(model, data)
    monitor = CCDMonitor(model, data, fit_model(model), all_pairs=True)
    assert monitor.mode == "geoms"
    for _ in range(50):
        monitor.step()
        contacts = monitor.last_report.contacts
        assert {c.bodies for c in contacts} == {("ball", "world"), ("crate", "world")}
        assert all(c.status_at_start in ("touching", "overlapping") for c in contacts)
    new_only = CCDMonitor(model, data, fit_model(model), report_overlapping=False)
    for _ in range(50):
        assert new_only.step() is None


@pytest.mark.dm_control
def test_no_pair_is_dropped_because_its_ellipsoids_overlap_at_qpos0():
    """dm-control's cartpole: MuJoCo collides the rails with the cart and the pole; the bounding ellipsoids of those
    bodies overlap in the reference pose, which drops the pairs in ellipsoid mode, never in geoms mode."""
    from dm_control import suite

    physics = suite.load("cartpole", "swingup", task_kwargs={"random": 0}).physics
    model = physics.model.ptr
    checker = GeomChecker(model, fit_model(model))
    names = [checker.labels_of_rows[a] + "/" + checker.labels_of_rows[b] for a, b in checker.pairs]
    assert {"rail1/cart", "rail2/cart", "rail1/pole_1", "rail2/pole_1"} <= set(names)


def test_real_geoms_are_collision_geoms_or_else_visual_geoms_never_the_bounds():
    both = """
    <mujoco><worldbody>
      <body name="a"><freejoint/><geom name="hit" type="capsule" size="0.1 0.2"/>
        <geom name="look" type="sphere" size="0.3" contype="0" conaffinity="0" group="1"/></body>
    </worldbody></mujoco>"""
    model = mujoco.MjModel.from_xml_string(both)
    ids, visual = real_geoms(model)
    assert [model.geom(g).name for g in ids] == ["hit"] and not visual
    shown = both.replace('<geom name="hit" type="capsule" size="0.1 0.2"/>',
                         '<geom name="hit" type="capsule" size="0.1 0.2" contype="0" conaffinity="0"/>')
    shown = shown.replace("</body>", '<geom name="bound" type="ellipsoid" size="0.4 0.4 0.5" group="5" '
                                     'contype="0" conaffinity="0"/></body>')
    model = mujoco.MjModel.from_xml_string(shown)
    ids, visual = real_geoms(model)
    assert [model.geom(g).name for g in ids] == ["hit", "look"] and visual


def test_a_mesh_is_checked_on_its_ellipsoid_with_one_warning_naming_it():
    xml = """
    <mujoco>
      <asset><mesh name="tetra" vertex="0 0 0  0.2 0 0  0 0.2 0  0 0 0.2"/></asset>
      <worldbody>
        <body name="rock" pos="-1 0 0"><freejoint/><geom name="rock_mesh" type="mesh" mesh="tetra"/></body>
        <body name="ball" pos="1 0 0"><freejoint/><geom name="ball" type="sphere" size="0.1"/></body>
      </worldbody>
    </mujoco>"""
    model = mujoco.MjModel.from_xml_string(xml)
    data = mujoco.MjData(model)
    with pytest.warns(CoverageWarning, match="checks meshes on their bounding ellipsoids: rock_mesh$") as said:
        monitor = CCDMonitor(model, data, fit_model(model, tolerance=None), planes=False)
    assert len(said) == 1
    kinds = dict(zip(monitor.geoms.labels_of_rows, monitor.geoms.kinds.tolist()))
    assert kinds == {"rock_mesh": 4, "ball": 0}  # the mesh as its ellipsoid
    data.qvel[0] = 1000.0  # the rock flies 2 m in a step, into the ball
    with warnings.catch_warnings():
        warnings.simplefilter("error", CoverageWarning)
        contact = monitor.step()
    assert contact is not None and contact.geoms == (int(model.geom("rock_mesh").id), int(model.geom("ball").id))


def test_the_guard_stops_a_fast_ball_at_a_thin_box_wall():
    xml = """
    <mujoco>
      <option gravity="0 0 0" timestep="0.01"/>
      <worldbody>
        <geom name="wall" type="box" size="0.01 1 1" solref="0.001 1"/>
        <body name="ball" pos="-0.5 0 0"><freejoint/><geom type="sphere" size="0.05" solref="0.001 1"/></body>
      </worldbody>
    </mujoco>"""
    model = mujoco.MjModel.from_xml_string(xml)
    data = mujoco.MjData(model)
    data.qvel[0] = 100.0  # 1 m a step: plain MuJoCo tunnels through the 2 cm wall (stiff contacts: solref)
    seen = []
    guard = GuardedStepper(model, data, fit_model(model), on_clamp=seen.append)
    assert guard.monitor.mode == "geoms"
    for _ in range(5):
        guard.step()
        assert data.qpos[0] < 0.0  # never through
    assert seen and seen[0].elements == ("face -x", "surface")
    assert abs(seen[0].point[0] + 0.01) < 1e-9


@pytest.mark.parametrize("seed", [0, 1])
def test_first_contacts_lie_where_mujoco_measures_zero_distance(seed):
    """Random boxes, capsules, cylinders, spheres and ellipsoids thrown at each other: at each reported first
    contact MuJoCo's own mj_geomDistance between the two geoms (the state interpolated by mj_integratePos) is
    zero, and shortly before it the geoms are apart."""
    shapes = ['type="box" size="0.1 0.15 0.05"', 'type="capsule" size="0.05 0.15"', 'type="cylinder" size="0.1 0.05"',
              'type="sphere" size="0.08"', 'type="ellipsoid" size="0.12 0.06 0.09"']
    rng = np.random.default_rng(seed)
    bodies = "".join(f'<body name="b{k}" pos="{rng.uniform(-0.4, 0.4):.3f} {rng.uniform(-0.4, 0.4):.3f} '
                     f'{rng.uniform(0.2, 0.8):.3f}"><freejoint/><geom {s}/></body>' for k, s in enumerate(shapes))
    model = mujoco.MjModel.from_xml_string(f'<mujoco><option gravity="0 0 -9.81" timestep="0.005"/><worldbody>'
                                           f'<geom name="floor" type="plane" size="5 5 0.1"/>{bodies}'
                                           f'</worldbody></mujoco>')
    data = mujoco.MjData(model)
    data.qvel[:] = rng.normal(0.0, 3.0, model.nv)
    monitor = CCDMonitor(model, data, fit_model(model), report_overlapping=False, all_pairs=True)
    probe = mujoco.MjData(model)
    checked = 0
    for _ in range(200):
        s0 = capture(data)
        monitor.step()
        s1 = capture(data)
        for c in monitor.last_report.contacts:
            ga, gb = c.geoms
            assert c.certainty == "certified"
            dist = []
            for f in (c.fraction, c.fraction - 0.05):
                # the geoms' poses at the fraction: the qpos MuJoCo interpolates (the free joints' centres move
                # linearly and turn at a constant rate: within 1e-6 of mjccd's pose lerp over a short step)
                qvel = np.zeros(model.nv)
                mujoco.mj_differentiatePos(model, qvel, 1.0, s0.qpos, s1.qpos)
                probe.qpos[:] = s0.qpos
                mujoco.mj_integratePos(model, probe.qpos, qvel, f)
                mujoco.mj_kinematics(model, probe)
                dist.append(mujoco.mj_geomDistance(model, probe, ga, gb, 0.1, None))
            assert abs(dist[0]) < 1e-4, (c, dist)
            if c.fraction > 0.05:
                assert dist[1] > -1e-6, (c, dist)
            checked += 1
    assert checked >= 3


def test_the_filters_never_change_an_answer():
    """The boxing clip at 50-frame strides (fast, far-reaching steps): every pair the checker's filters clear has
    no contact when solved on its own, and every other answer is the unfiltered solver's (to rounding: the
    batch and the Python API round the poses each their own way)."""
    from mjccd.geoms import geom_first_contact
    from mjccd.replay import load_model, load_trajectory, replay_ellipsoids

    model = load_model(ROOT / "models" / "boxing.xml")
    qpos, _ = load_trajectory(ROOT / "data" / "boxing_traj.npz", model)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", CoverageWarning)
        checker = GeomChecker(model, replay_ellipsoids(model, None, source="boxing.xml")[0], "characters")
    poses = checker.qpos_poses(qpos[100:1100:50])
    culled = contacts = 0
    for Q0, Q1 in zip(poses[:-1], poses[1:]):
        report = checker.check_poses(0.0, 1.0, Q0, Q1, all_pairs=True)
        culled += report.counters["sphere_culled"]
        found = {c.pair: c for c in report.contacts}
        for k in range(len(checker.pairs)):
            alone = geom_first_contact(*checker.pair_problem(k, Q0, Q1))
            if alone is None:
                assert k not in found, (k, found.get(k))
                continue
            contacts += 1
            c = found[k]
            assert c.status_at_start == alone.status_at_start, (c, alone)
            if alone.status_at_start == "separate":
                assert c.certainty == alone.certainty and abs(c.fraction - alone.time) <= 1e-12, (c, alone)
    assert culled > 1000 and contacts > 20, (culled, contacts)


def test_swept_balls_clear_only_pairs_the_moving_sphere_test_clears():
    """The filters' cheap first test (mjccd.geoms.batch.balls_apart) on random shapes and steps, near and far:
    a pair it clears is cleared by the full filters too, and its centres' paths stay further apart than the
    reaches at every sampled time (so the answers cannot change)."""
    from mjccd.geoms import batch as gb

    rng = np.random.default_rng(7)
    G = 40
    kinds = rng.integers(0, 5, G).astype(np.int64)
    sizes = rng.uniform(0.02, 0.3, (G, 3))
    Q0, Q1 = np.empty((G, 7)), np.empty((G, 7))
    for Q in (Q0, Q1):
        Q[:, :3] = rng.uniform(-1.0, 1.0, (G, 3))
        Q[:, 3:] = rng.normal(size=(G, 4))
        Q[:, 3:] /= np.linalg.norm(Q[:, 3:], axis=1)[:, None]
    Q1[:, :3] = Q0[:, :3] + rng.normal(0.0, 0.2, (G, 3))
    balls = np.empty((G, 4))
    gb.swept_balls(kinds, sizes, Q0, Q1, balls)
    scratch = np.empty((gb.SCRATCH_ROWS, 7))
    apart = 0
    for ga in range(G):
        for gb_ in range(ga + 1, G):
            if not gb.balls_apart(balls, ga, gb_):
                continue
            apart += 1
            assert gb.clear(kinds, sizes, Q0, Q1, ga, gb_, scratch), (ga, gb_)
            reach = gb.proxy(kinds[ga], sizes[ga])[3] + gb.proxy(kinds[gb_], sizes[gb_])[3]
            for t in np.linspace(0.0, 1.0, 11):
                d = (1 - t) * (Q0[ga, :3] - Q0[gb_, :3]) + t * (Q1[ga, :3] - Q1[gb_, :3])
                assert np.linalg.norm(d) > reach, (ga, gb_, t)
    assert 100 < apart < G * (G - 1) // 2


def test_a_ball_tangent_to_the_floor_is_touching_in_either_mode_never_a_new_contact():
    """dm-control's reacher keeps its finger sphere exactly on the floor: with no gravity the ball below stays
    tangent.  Every step reports it touching at the start (one status, certified), in geoms mode and in
    ellipsoid mode with an exact ellipsoid, and never as a new contact (report_overlapping=False: nothing)."""
    from mjccd.mujoco import EllipsoidSet

    model = mujoco.MjModel.from_xml_string(RESTING.replace('<option timestep="0.002"/>',
                                                           '<option timestep="0.002" gravity="0 0 0"/>'))
    exact = EllipsoidSet(bodies=["ball", "crate"], radii=[[0.1, 0.1, 0.1], [0.2, 0.2, 0.2]],
                         positions=np.zeros((2, 3)), quaternions=[[1, 0, 0, 0]] * 2)
    for mode in ("geoms", "ellipsoids"):
        data = mujoco.MjData(model)
        monitor = CCDMonitor(model, data, exact, mode=mode, all_pairs=True)
        seen = set()
        for _ in range(20):
            monitor.step()
            seen |= {(c.status_at_start, c.certainty) for c in monitor.last_report.contacts
                     if c.bodies == ("ball", "world")}
        assert seen == {("touching", "certified")}, (mode, seen)
        quiet = CCDMonitor(model, mujoco.MjData(model), exact, mode=mode, report_overlapping=False)
        assert all(quiet.step() is None for _ in range(20)), mode
