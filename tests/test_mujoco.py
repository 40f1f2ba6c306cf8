"""MuJoCo layer: motions between states, pair sets, the step monitor, contacts at known times."""
import re

import mujoco
import numpy as np
import pytest

import mjccd
from mjccd.mujoco import (CCDMonitor, EllipsoidSet, Kinematics, State, capture, default_pairs, fit_model,
                          interpolate_qpos, motions_between)

ARM = """
<mujoco>
 <worldbody>
  <body name="base" pos="0.1 0.2 0.3" quat="0.9 0.1 0.2 0.3"><freejoint/>
   <geom type="box" size="0.1 0.1 0.05"/>
   <body name="upper" pos="0 0 0.1" euler="0.2 0 0">
    <joint name="shoulder" type="hinge" axis="0 1 0" pos="0 0 -0.02" ref="0.3"/>
    <geom type="capsule" fromto="0 0 0 0 0 0.3" size="0.04"/>
    <body name="fore" pos="0 0 0.3">
     <joint name="elbow" type="hinge" axis="1 0.5 0" pos="0.01 0 0"/>
     <joint name="twist" type="hinge" axis="0 0 1"/>
     <geom type="capsule" fromto="0 0 0 0 0 0.25" size="0.03"/>
     <body name="slider" pos="0 0 0.25">
      <joint name="extend" type="slide" axis="0 0.3 1" ref="0.01"/>
      <geom type="box" size="0.02 0.02 0.04"/>
      <body name="hand" pos="0 0 0.05">
       <joint name="wrist" type="ball" pos="0 0 -0.01"/>
       <geom type="ellipsoid" size="0.03 0.05 0.02" pos="0.01 0 0.02"/>
      </body>
     </body>
    </body>
   </body>
  </body>
  <body name="post" pos="1 0 0"><geom type="cylinder" size="0.05 0.5"/></body>
 </worldbody>
 <contact><exclude body1="base" body2="slider"/></contact>
</mujoco>
"""

THROW = """
<mujoco>
 <option gravity="0 0 0" timestep="0.002"><flag contact="disable"/></option>
 <worldbody>
  <body name="left" pos="-0.5 0 0"><freejoint/><geom type="sphere" size="0.1"/></body>
  <body name="right" pos="0.5 0 0"><freejoint/><geom type="ellipsoid" size="0.2 0.1 0.15"/></body>
 </worldbody>
</mujoco>
"""


@pytest.fixture(scope="module")
def arm():
    m = mujoco.MjModel.from_xml_string(ARM)
    return m, fit_model(m, tolerance=None)  # one per body: some overlap at qpos0


def _random_qpos(model, rng, scale=0.8):
    d = mujoco.MjData(model)
    q = model.qpos0.copy()
    for j in range(model.njnt):
        adr = model.jnt_qposadr[j]
        t = model.jnt_type[j]
        if t == mujoco.mjtJoint.mjJNT_FREE:
            q[adr:adr + 3] = rng.normal(size=3) * 0.2
            quat = rng.normal(size=4)
            q[adr + 3:adr + 7] = quat / np.linalg.norm(quat)
        elif t == mujoco.mjtJoint.mjJNT_BALL:
            quat = np.r_[1.0, rng.normal(size=3) * scale * 0.5]
            q[adr:adr + 4] = quat / np.linalg.norm(quat)
        else:
            q[adr] += rng.uniform(-scale, scale)
    d.qpos[:] = q
    return q


def _ellipsoid_frames(model, es, qpos):
    d = mujoco.MjData(model)
    d.qpos[:] = qpos
    mujoco.mj_kinematics(model, d)
    out = []
    for b, p, q in zip(es.body_ids(model), es.positions, es.quaternions):
        R = d.xmat[b].reshape(3, 3)
        Re = np.empty(9)
        mujoco.mju_quat2Mat(Re, q)
        out.append(np.hstack([R @ Re.reshape(3, 3), (d.xpos[b] + R @ p)[:, None]]))
    return out


def test_rigid_motion_matches_mujoco_at_both_ends(arm):
    model, es = arm
    rng = np.random.default_rng(1)
    q0, q1 = _random_qpos(model, rng), _random_qpos(model, rng)
    d0, d1 = mujoco.MjData(model), mujoco.MjData(model)
    d0.qpos[:], d1.qpos[:] = q0, q1
    motions = motions_between(model, es, d0, d1, "rigid")
    for t, q in ((0.0, q0), (1.0, q1)):
        for m, want in zip(motions, _ellipsoid_frames(model, es, q)):
            np.testing.assert_allclose(m.transform(t), want, atol=1e-12)


def test_chain_motion_is_forward_kinematics_of_interpolated_joints(arm):
    model, es = arm
    rng = np.random.default_rng(2)
    for _ in range(3):
        q0, q1 = _random_qpos(model, rng), _random_qpos(model, rng)
        motions = motions_between(model, es, q0, q1, "chain")
        for t in (0.0, 0.25, 0.6, 1.0):
            qt = interpolate_qpos(model, q0, q1, t)
            for m, want in zip(motions, _ellipsoid_frames(model, es, qt)):
                np.testing.assert_allclose(m.transform(t), want, atol=1e-10)
    np.testing.assert_allclose(interpolate_qpos(model, q0, q1, 0.0), q0, atol=1e-14)
    hinges = [model.jnt_qposadr[j] for j in range(model.njnt) if model.jnt_type[j] == mujoco.mjtJoint.mjJNT_HINGE]
    np.testing.assert_allclose(interpolate_qpos(model, q0, q1, 1.0)[hinges], q1[hinges], atol=1e-14)


def test_chain_hinge_beyond_pi_uses_offset_path():
    m = mujoco.MjModel.from_xml_string("""<mujoco><worldbody><body name="wheel">
        <joint type="hinge" axis="0 0 1"/><geom type="box" size="0.3 0.05 0.05" pos="0.2 0 0"/></body>
        </worldbody></mujoco>""")
    es = fit_model(m, tolerance=None)  # one ellipsoid
    q0, q1 = np.array([3.0]), np.array([3.5])
    (motion,) = motions_between(m, es, q0, q1, "chain")
    for t in (0.0, 0.5, 1.0):
        np.testing.assert_allclose(motion.transform(t), _ellipsoid_frames(m, es, interpolate_qpos(m, q0, q1, t))[0],
                                   atol=1e-10)
    with pytest.raises(ValueError, match="hinge turns by"):
        motions_between(m, es, np.array([0.0]), np.array([3.5]), "chain")


def test_default_pairs(arm):
    model, es = arm
    names = es.bodies
    pairs = {(names[i], names[j]) for i, j in default_pairs(model, es, drop_overlapping_at_qpos0=False)}
    assert ("base", "upper") not in pairs and ("upper", "fore") not in pairs  # joined by a joint
    assert ("base", "slider") not in pairs  # <exclude>
    assert ("base", "fore") in pairs and ("upper", "post") in pairs
    dropped = {(names[i], names[j]) for i, j in default_pairs(model, es)}
    assert dropped <= pairs and ("upper", "post") in dropped
    assert ("fore", "hand") not in dropped  # overlapping in the reference pose


def _throw(t_star, speed=7.0):
    """Two free bodies flying at each other that first touch at simulation time t_star."""
    m = mujoco.MjModel.from_xml_string(THROW)
    d = mujoco.MjData(m)
    gap = 1.0 - 0.1 - 0.2
    d.qvel[0] = speed
    d.qvel[6] = -speed
    d.qpos[0] = -0.5 - (2 * speed * t_star - gap) / 2
    d.qpos[7] = 0.5 + (2 * speed * t_star - gap) / 2
    return m, d


@pytest.mark.parametrize("motion", ["rigid", "affine", "chain"])
def test_known_contact_time(motion):
    t_star = 0.0123457
    m, d = _throw(t_star)
    es = fit_model(m)
    seen = []
    monitor = CCDMonitor(m, d, es, motion=motion, on_contact=seen.append)
    contact = None
    while contact is None and d.time < 0.05:
        contact = monitor.step()
    assert contact is not None
    dt = m.opt.timestep
    assert abs(contact.time - t_star) <= 1e-9 * dt
    assert contact.bodies == ("left", "right") and contact.status_at_start == "separate"
    np.testing.assert_allclose(contact.normal, [1, 0, 0], atol=1e-7)
    np.testing.assert_allclose(contact.point[1:], 0.0, atol=1e-7)
    assert seen == [contact]
    # the step after starts overlapping
    nxt = monitor.step()
    assert nxt.fraction == 0.0 and nxt.status_at_start == "overlapping" and nxt.point is None


def test_spinning_ellipsoids_agree_with_the_core():
    m, d = _throw(0.02, speed=5.0)
    d.qvel[3:6] = [0, 0, 40.0]
    d.qvel[9:12] = [30.0, 0, 10.0]
    es = fit_model(m)
    monitor = CCDMonitor(m, d, es)
    for _ in range(40):
        s0 = capture(d)
        mujoco.mj_step(m, d)
        s1 = capture(d)
        found = monitor.check(s0, s1)
        mo = motions_between(m, es, s0, s1, "rigid")
        ref = mjccd.first_contact(mjccd.Ellipsoid(es.radii[0]), mo[0], mjccd.Ellipsoid(es.radii[1]), mo[1])
        if ref is None:
            assert found is None
            continue
        assert found is not None and abs(found.fraction - ref.time) <= 1e-9
        if ref.point is not None:
            np.testing.assert_allclose(found.point, ref.point, atol=1e-9)
            break
    else:
        pytest.fail("no contact in 40 steps")


def test_check_accepts_qpos_and_counts_from_state_t0():
    m, d = _throw(0.0101)
    es = fit_model(m)
    monitor = CCDMonitor(m, d, es)
    q0 = d.qpos.copy()
    q1 = q0.copy()
    q1[0] += 7.0 * 0.02
    q1[7] -= 7.0 * 0.02
    contact = monitor.check(q0, q1)  # one "step" of 0.02 s
    assert contact is not None
    assert contact.fraction == pytest.approx(0.0101 / 0.02, abs=1e-9)
    assert contact.time == pytest.approx(contact.fraction * m.opt.timestep)


def test_all_pairs_reports_every_colliding_pair():
    xml = THROW.replace("</worldbody>", '<body name="third" pos="0 0.3 0"><freejoint/>'
                        '<geom type="sphere" size="0.1"/></body></worldbody>')
    m = mujoco.MjModel.from_xml_string(xml)
    d = mujoco.MjData(m)
    es = fit_model(m)
    monitor = CCDMonitor(m, d, es, all_pairs=True)
    q1 = d.qpos.copy()
    q1[0] += 0.8   # left sweeps through right
    q1[15] -= 0.6  # third comes down onto the x axis
    monitor.check(d.qpos.copy(), q1)
    report = monitor.last_report
    got = {c.bodies for c in report.contacts}
    assert ("left", "right") in got and len(got) >= 2
    assert (report.first.bodies, report.first.fraction) == (report.contacts[0].bodies, report.contacts[0].fraction)
    assert all(a.fraction <= b.fraction for a, b in zip(report.contacts, report.contacts[1:]))


def test_explicit_pairs_and_errors(arm):
    model, es = arm
    d = mujoco.MjData(model)
    mon = CCDMonitor(model, d, es, pairs=[("hand", "post"), (1, "post")])
    assert len(mon.pairs) == 2
    with pytest.raises(ValueError, match=r"pairs\[0\]\[1\]: the model has no body named 'moon'"):
        CCDMonitor(model, d, es, pairs=[("hand", "moon")])
    with pytest.raises(ValueError, match=r"pairs\[0\]\[0\]: body 'world' has no ellipsoid"):
        CCDMonitor(model, d, es, pairs=[("world", "post")])
    with pytest.raises(ValueError, match=r"pairs\[0\]: a body cannot be paired with itself"):
        CCDMonitor(model, d, es, pairs=[("post", "post")])
    with pytest.raises(ValueError, match=r"pairs\[0\]: expected a \(body, body\) pair"):
        CCDMonitor(model, d, es, pairs=["hand"])
    with pytest.raises(ValueError, match="motion: expected one of rigid, affine, chain"):
        CCDMonitor(model, d, es, motion="spline")
    with pytest.raises(ValueError, match="ellipsoids: expected an EllipsoidSet"):
        CCDMonitor(model, d, [1, 2, 3])
    q = model.qpos0.copy()
    q[9] = np.nan
    with pytest.raises(ValueError, match=r"state_t1.qpos\[9\]: is NaN or infinite"):
        mon.check(model.qpos0, q)
    with pytest.raises(ValueError, match=r"state_t0: expected a qpos vector of length nq = 15, got shape \(3,\)"):
        mon.check(np.zeros(3), q)
    other = EllipsoidSet(bodies=["elbow_pad"], radii=[[1, 1, 1]], positions=[[0, 0, 0]],
                         quaternions=[[1, 0, 0, 0]])
    with pytest.raises(ValueError, match=r"ellipsoids.bodies\[0\]: the model has no body 'elbow_pad'"):
        CCDMonitor(model, d, other)


def test_kinematics_leaves_user_data_alone(arm):
    model, es = arm
    d = mujoco.MjData(model)
    mujoco.mj_forward(model, d)
    before = d.xpos.copy()
    state = State(_random_qpos(model, np.random.default_rng(5)), d.mocap_pos, d.mocap_quat)
    Kinematics(model).body_poses(state)
    np.testing.assert_array_equal(d.xpos, before)


# ---------------------------------------------------------------- wrappers and test helpers


@pytest.mark.dm_control
def test_dm_control_wrapper_matches_the_monitor():
    from dm_control import suite

    from mjccd.dm_control import OBSERVATION_KEYS, CCDWrapper

    env = CCDWrapper(suite.load("cartpole", "swingup", task_kwargs={"random": 0}),
                     pairs=[("cart", "pole_1")])
    spec = env.observation_spec()
    assert all(k in spec for k in OBSERVATION_KEYS) and "position" in spec
    ts = env.reset()
    assert np.isinf(ts.observation["ccd/contact_time"])
    physics = env.physics
    model = physics.model.ptr
    reference = CCDMonitor(model, mujoco.MjData(model), env.ellipsoids, pairs=[("cart", "pole_1")])
    n_sub = env._env._n_sub_steps
    for k in range(5):
        start = capture(physics.data.ptr)
        start_time = physics.data.time
        qpos_before = physics.data.qpos.copy()
        ts = env.step(np.array([0.5 * (-1) ** k]))
        assert physics.data.time == pytest.approx(start_time + n_sub * model.opt.timestep)
        obs = ts.observation
        for key in OBSERVATION_KEYS:
            assert spec[key].shape == np.shape(obs[key])
        # the cart and pole overlap all along (the pole hangs from the cart): contact at t = 0
        expected = reference.check(start, State(qpos_before, start.mocap_pos, start.mocap_quat, start_time))
        if expected is not None:
            assert obs["ccd/contact_time"] == 0.0
        assert len(env.last_contacts) == n_sub
        first = env.last_contacts[0]
        assert obs["ccd/contact_time"] == pytest.approx(first.time - start_time, abs=1e-15)
        assert tuple(obs["ccd/contact_pair"]) == first.body_ids


@pytest.mark.dm_control
def test_dm_control_wrapper_reports_a_thrown_ball():
    from dm_control.rl import control

    from mjccd.dm_control import CCDWrapper
    from dm_control import mujoco as dm_mujoco

    class Throw(control.Task):
        def initialize_episode(self, physics):
            physics.data.qvel[0], physics.data.qvel[6] = 7.0, -7.0

        def get_observation(self, physics):
            return {"qpos": physics.data.qpos.copy()}

        def get_reward(self, physics):
            return 0.0

        def action_spec(self, physics):
            from dm_env import specs
            return specs.BoundedArray((0,), float, [], [])

        def before_step(self, action, physics):
            pass

    physics = dm_mujoco.Physics.from_xml_string(THROW)
    env = CCDWrapper(control.Environment(physics, Throw(), n_sub_steps=5, legacy_step=False))
    ts = env.reset()
    m = physics.model.ptr
    t_star = (1.0 - 0.3) / 14.0
    hit = None
    while hit is None:
        start = physics.data.time
        ts = env.step(np.zeros(0))
        if np.isfinite(ts.observation["ccd/contact_time"]):
            hit = start + ts.observation["ccd/contact_time"]
    assert abs(hit - t_star) <= 1e-9 * m.opt.timestep
    np.testing.assert_allclose(ts.observation["ccd/contact_normal"], [1, 0, 0], atol=1e-7)
    assert tuple(ts.observation["ccd/contact_pair"]) == (1, 2)
    assert [(c.certainty, c.bracket) for c in env.last_contacts[:1]] == [("certified", None)]


def test_gymnasium_wrapper_if_installed():
    gymnasium = pytest.importorskip("gymnasium")
    pytest.importorskip("gymnasium.envs.mujoco")
    from mjccd.mujoco.gym import CCDGymWrapper

    env = CCDGymWrapper(gymnasium.make("Ant-v5"), report_overlapping=False)
    env.reset(seed=0)
    _, _, _, _, info = env.step(env.action_space.sample())
    assert set(info["ccd"]) >= {"contact_time", "contact_pair", "contact_point", "contact_normal", "contacts"}


def _balls():
    xml = THROW.replace('size="0.2 0.1 0.15"', 'size="0.2 0.2 0.2"')
    m = mujoco.MjModel.from_xml_string(xml)
    d = mujoco.MjData(m)
    d.qvel[0], d.qvel[6] = 5.0, -5.0
    rows = [d.qpos.copy()]
    for _ in range(80):
        mujoco.mj_step(m, d)
        rows.append(d.qpos.copy())
    return m, np.array(rows)


def test_testing_helpers_pass_and_fail_readably():
    from mjccd.testing import assert_first_contact, assert_intervals, assert_no_contact

    m, qpos = _balls()
    t_in = 0.7 / 10.0
    c = assert_first_contact(m, qpos, ("left", "right"), t_in, tol=1e-9)
    assert c.bodies == ("left", "right")
    assert_intervals(m, qpos, ("left", "right"), [(t_in, 1.3 / 10.0)], tol=1e-9)
    with pytest.raises(AssertionError) as err:
        assert_first_contact(m, qpos, ("left", "right"), 0.05, tol=1e-6)
    msg = str(err.value)
    assert "expected t = 0.05 s" in msg and "found t = 0.07 s ('left'-'right'" in msg and "point [" in msg
    assert "off by +0.02 s" in msg and "checked: the model's own geoms (geoms mode)" in msg
    assert re.search(r"the real geoms are -?[0-9.e+-]+ m apart \(MuJoCo's mj_geomDistance\)", msg)
    with pytest.raises(AssertionError) as err:  # ellipsoid mode: the message says which fit, and how far the geoms are
        assert_first_contact(m, qpos, ("left", "right"), 0.08, tol=1e-6, mode="ellipsoids")
    msg = str(err.value)
    assert "bounding ellipsoids (ellipsoid mode), the default fit, fit_model(model): within 0.01 of the geoms" in msg
    assert re.search(r"at that instant the real geoms are -?[0-9.e+-]+ m apart \(MuJoCo's mj_geomDistance\)", msg)
    with pytest.raises(AssertionError, match=r"found no contact over \[0, 0.01\] s"):
        assert_first_contact(m, qpos[:6], ("left", "right"), 0.05)
    with pytest.raises(AssertionError, match=r"expected no contact, found contacts in \d+ step\(s\):\n  t = 0.07 s"):
        assert_no_contact(m, qpos)
    with pytest.raises(AssertionError, match=r"expected 2 interval\(s\) .* found 1 \[\(0.07, 0.13\)\]"):
        assert_intervals(m, qpos, ("left", "right"), [(0.07, 0.08), (0.09, 0.13)])
    with pytest.raises(AssertionError, match=r"interval 0 expected \(0.07, 0.12\), found \(0.07, 0.13\)"):
        assert_intervals(m, qpos, ("left", "right"), [(0.07, 0.12)])
    with pytest.raises(ValueError, match=r"trajectory: expected qpos of shape \(T >= 2, nq = 14\)"):
        assert_no_contact(m, qpos[:, :3])


# ---------------------------------------------------------------- uncertain answers of the exact solver
#
# A real limit of the solver is hard to hit on purpose, so the solver is replaced: for chain motions the
# first_contact the monitor calls, for rigid ones the exact_pair of the scene kernel, whose own Python source
# (step_kernel.py_func, the lines the compiled kernel runs) is then run.


def _widened(real):
    """first_contact as if the solver hit a limit around every new contact: bracket t -/+ 1/4 of the step."""
    from mjccd.ccd import Contact

    def fake(a, motion_a, b, motion_b, *, t_max=1.0):
        c = real(a, motion_a, b, motion_b, t_max=t_max)
        if c is None or c.status_at_start != "separate":
            return c
        lo, hi = max(0.0, c.time - 0.25), min(1.0, c.time + 0.25)
        return Contact(lo, None, None, c.status_at_start, "uncertain", (lo, hi))
    return fake


@pytest.fixture
def limited_scene(monkeypatch):
    """Scene kernels run as Python with an exact solver that hits a limit on every pair: bracket [0.3, 0.8]."""
    import mjccd.scene as sc

    def limit(affine, ra, pa0, qa0, pa1, qa1, rb, pb0, qb0, pb1, qb1, t_max, first_only):
        return 1, np.empty((0, 2)), np.zeros(3), np.zeros(3), False, 0.3, 0.8
    import mjccd.mujoco.monitor as mon
    import mjccd.mujoco.motions as mo

    # the guard's compiled step check, compiled (or loaded) before the kernels it calls are replaced
    m, d = _throw(0.0011)
    check = mon.StepCheck(CCDMonitor(m, d, fit_model(m), mode="ellipsoids"))
    check.begin(d)
    mujoco.mj_step(m, d)
    check.end_may_touch(d)
    monkeypatch.setattr(sc, "_borrow", lambda a: a)
    monkeypatch.setattr(sc, "exact_pair", limit)
    kernel = sc.step_kernel.py_func
    monkeypatch.setattr(sc, "step_kernel", kernel)
    # the monitor's one compiled call around the kernel, as Python calling it
    monkeypatch.setattr(mo, "step_kernel", kernel)
    monkeypatch.setattr(mon, "poses_then_first", mo.poses_then_first.py_func)


def test_monitor_certified_contacts_say_so():
    m, d = _throw(0.0011)
    monitor = CCDMonitor(m, d, fit_model(m))
    c = monitor.step()
    assert (c.certainty, c.bracket, c.status_at_start) == ("certified", None, "separate")
    assert c.fraction == pytest.approx(0.55, abs=1e-9) and monitor.last_report.pairs_uncertain == 0


def test_monitor_settles_what_the_scene_leaves_uncertain(limited_scene):
    """The scene's stand-in solver says "somewhere in [0.3, 0.8]"; the core's exact tiers, asked again, find the
    contact at 0.55 of the step, certified, in the monitor and in the guard's lean step check alike."""
    from mjccd.mujoco.monitor import StepCheck

    m, d = _throw(0.0011)
    monitor = CCDMonitor(m, d, fit_model(m), mode="ellipsoids")
    c = monitor.step()
    assert (c.certainty, c.status_at_start, c.bracket) == ("certified", "separate", None)
    assert c.fraction == pytest.approx(0.55, abs=1e-9) and monitor.last_report.pairs_uncertain == 0
    m, d = _throw(0.0011)
    check = StepCheck(CCDMonitor(m, d, fit_model(m), mode="ellipsoids"))
    check.begin(d)
    mujoco.mj_step(m, d)
    check.end_may_touch(d)
    assert check.first((0.0, float(d.time))).fraction == c.fraction


def test_monitor_reports_uncertain_scene_answers(limited_scene, monkeypatch):
    import mjccd.settle as settle
    from mjccd.ccd import Contact
    from mjccd.mujoco.monitor import StepCheck

    # contact at 0.55 of the first step; the stand-in solvers, the scene's and the core's, say "somewhere in
    # [0.3, 0.8]"
    monkeypatch.setattr(settle, "first_contact", lambda *args, **kwargs: Contact(0.3, None, None, "separate",
                                                                                 "uncertain", (0.3, 0.8)))
    m, d = _throw(0.0011)
    monitor = CCDMonitor(m, d, fit_model(m), mode="ellipsoids")
    c = monitor.step()
    assert (c.certainty, c.status_at_start) == ("uncertain", "separate")
    # the point is an estimate: where the two bodies, flying at each other along x, nearly touch at 0.3
    assert c.point is not None and abs(c.point[1]) < 1e-9 and abs(abs(c.normal[0]) - 1.0) < 1e-9
    assert c.fraction == 0.3 and c.bracket == pytest.approx((0.0006, 0.0016), abs=1e-15)
    assert c.time == c.bracket[0]
    assert monitor.last_report.pairs_uncertain == 1 and monitor.last_report.first is c
    # the guard's lean step check reads the same kernel arrays
    m, d = _throw(0.0011)
    check = StepCheck(CCDMonitor(m, d, fit_model(m), mode="ellipsoids"))
    check.begin(d)
    mujoco.mj_step(m, d)
    check.end_may_touch(d)
    c = check.first((0.0, float(d.time)))
    assert (c.certainty, c.fraction) == ("uncertain", 0.3) and c.point is not None
    assert c.bracket == pytest.approx((0.0006, 0.0016), abs=1e-15)


def test_chain_monitor_reports_uncertain_answers(monkeypatch):
    import mjccd.mujoco.adapter as adapter

    monkeypatch.setattr(adapter, "first_contact", _widened(adapter.first_contact))
    m, d = _throw(0.0011)
    seen = []
    monitor = CCDMonitor(m, d, fit_model(m), motion="chain", on_contact=seen.append)
    c = monitor.step()
    assert (c.certainty, c.status_at_start) == ("uncertain", "separate")
    # an estimated point: where the two bodies, flying at each other along x, nearly touch at 0.3
    assert c.point is not None and abs(c.point[1]) < 1e-9 and abs(abs(c.normal[0]) - 1.0) < 1e-9
    assert c.fraction == pytest.approx(0.3, abs=1e-9)
    assert c.bracket == pytest.approx((0.0006, 0.0016), abs=1e-12) and c.time == c.bracket[0]
    assert monitor.last_report.pairs_uncertain == 1 and seen == [c]


def test_testing_helpers_with_uncertain_answers(monkeypatch):
    """An uncertain answer passes assert_first_contact only when the expected time is in its bracket, and never
    passes assert_no_contact; both messages name the bracket."""
    import mjccd.mujoco.adapter as adapter
    from mjccd.testing import assert_first_contact, assert_no_contact

    monkeypatch.setattr(adapter, "first_contact", _widened(adapter.first_contact))
    m, qpos = _balls()
    rows = qpos[::3]  # steps of 6 ms: the contact at 0.07 s lies at 2/3 of the step [0.066, 0.072]
    times = np.arange(len(rows)) * 0.006
    kw = dict(motion="chain", times=times)
    c = assert_first_contact(m, rows, ("left", "right"), 0.07, tol=1e-9, **kw)
    assert c.certainty == "uncertain" and c.bracket == pytest.approx((0.0685, 0.0715), abs=1e-12)
    assert_first_contact(m, rows, ("left", "right"), 0.0686, tol=1e-9, **kw)  # anywhere in the bracket
    with pytest.raises(AssertionError, match=r"expected t = 0.068 s \(tol 1e-06\), found uncertain: a contact is "
                                             r"possible in \[0.0685, 0.0715\] s \('left'-'right'.*outside that bracket"):
        assert_first_contact(m, rows, ("left", "right"), 0.068, **kw)
    with pytest.raises(AssertionError, match=r"expected no contact, could not certify it: uncertain answers in 1 "
                                             r"step\(s\):\n  uncertain: a contact is possible in \[0.0685, 0.0715\] s"):
        assert_no_contact(m, rows[:13], motion="chain", times=times[:13])
    with pytest.raises(AssertionError, match=r"expected no contact, found contacts in \d+ step\(s\) \(1 uncertain\)"):
        assert_no_contact(m, rows, **kw)


# ---------------------------------------------------------------- the wrappers' substeps


def _walker(**environment_kwargs):
    from dm_control import suite

    env = suite.load("walker", "walk", task_kwargs={"random": 0}, environment_kwargs=environment_kwargs)
    env.reset()
    return env


def _dm_state(physics):
    d = physics.data.ptr
    return b"".join(a.tobytes() for a in (d.qpos, d.qvel, d.act, d.qacc_warmstart, d.xpos, d.xquat, d.sensordata,
                                          np.array(d.time), d.warning.number))


def _substep_hook(physics, states):
    """Hook ``physics.step`` to take one ``physics.step(1)`` at a time (the per-substep check dm-control's own
    step gives), keeping the state after each in ``states``."""
    original = physics.step

    def one_at_a_time(nstep=1):
        for _ in range(nstep):
            original(1)
            states.append(capture(physics.data.ptr))
    physics.step = one_at_a_time


@pytest.mark.dm_control
@pytest.mark.parametrize("kind", ["legacy", "legacy RK4", "mj_step"])
def test_dm_control_wrapper_steps_the_physics_bit_for_bit_as_the_plain_environment(kind):
    """The wrapped environment's physics (positions, velocities, warm start, body poses, sensors, time) equals
    the plain environment's after every control step, bit for bit, for each kind of dm-control step; its
    observation too, the ccd/* entries added."""
    from mjccd.dm_control import OBSERVATION_KEYS, CCDWrapper

    kwargs = {} if kind != "mj_step" else {"legacy_step": False}
    plain, inner = _walker(**kwargs), _walker(**kwargs)
    if kind == "legacy RK4":
        for env in (plain, inner):
            env.physics.model.opt.integrator = mujoco.mjtIntegrator.mjINT_RK4
    wrapped = CCDWrapper(inner)
    assert wrapped._substeps is None
    actions = np.random.default_rng(0).uniform(-1, 1, (40, 6))
    contacts = 0
    for action in actions:
        a, b = plain.step(action), wrapped.step(action)
        assert _dm_state(plain.physics) == _dm_state(inner.physics)
        assert set(b.observation) == set(a.observation) | set(OBSERVATION_KEYS)
        for key, value in a.observation.items():
            assert np.asarray(value).tobytes() == np.asarray(b.observation[key]).tobytes()
        assert len(wrapped.last_reports) == 10
        contacts += len(wrapped.last_contacts)
    assert wrapped._substeps.bodies_current == (kind != "mj_step") and contacts > 0


@pytest.mark.dm_control
def test_dm_control_wrapper_reports_what_the_monitor_finds_between_the_substep_states():
    """The wrapper's contacts (end poses read off dm-control's own kinematics, the check in one compiled call)
    are what the adapter finds between the states of the same substeps, taken one physics.step(1) at a time."""
    from dm_control import suite

    from mjccd.dm_control import CCDWrapper

    def humanoid():
        env = suite.load("humanoid", "run", task_kwargs={"random": 1})
        env.reset()
        return env

    for mode in ("geoms", "ellipsoids"):
        reference, inner = humanoid(), humanoid()
        wrapped = CCDWrapper(inner, mode=None if mode == "geoms" else mode)
        assert wrapped.monitor.mode == mode
        checker = wrapped.monitor.geoms if mode == "geoms" else wrapped.monitor.adapter
        states = [capture(reference.physics.data.ptr)]
        _substep_hook(reference.physics, states)
        spec = reference.action_spec()
        found = 0
        for action in np.random.default_rng(1).uniform(spec.minimum, spec.maximum, (12, len(spec.minimum))):
            reference.step(action)
            wrapped.step(action)
            expected = [checker.check(s0, s1).first for s0, s1 in zip(states[-6:-1], states[-5:])]
            got = [r.first for r in wrapped.last_reports]
            assert len(got) == 5
            for e, g in zip(expected, got):
                assert (e is None) == (g is None)
                if e is not None:
                    found += 1
                    assert (g.time, g.fraction, g.bodies, g.ellipsoids, g.status_at_start, g.certainty, g.pair,
                            g.geom, g.geoms, g.elements) == (e.time, e.fraction, e.bodies, e.ellipsoids,
                                                             e.status_at_start, e.certainty, e.pair, e.geom,
                                                             e.geoms, e.elements)
                    for x, y in ((g.point, e.point), (g.normal, e.normal)):
                        assert (x is None and y is None) or x.tobytes() == y.tobytes()
            assert wrapped.last_contacts == [r.first for r in wrapped.last_reports if r.first is not None]
            assert _dm_state(reference.physics) == _dm_state(inner.physics)
        assert found > (10 if mode == "geoms" else 20), mode  # the real geoms touch less often


@pytest.mark.dm_control
@pytest.mark.parametrize("how", ["class", "instance"])
def test_dm_control_wrapper_steps_a_physics_with_its_own_step_through_it(how):
    """A physics class with its own ``step``, or a physics whose ``step`` another wrapper hooked, is stepped by
    it, one timestep at a time."""
    from mjccd.dm_control import CCDWrapper

    plain, inner = _walker(), _walker()
    calls = []
    if how == "class":
        class Counting(type(inner.physics)):
            def step(self, nstep=1):
                calls.append(nstep)
                super().step(nstep)

        inner.physics.__class__ = Counting
    else:
        original = inner.physics.step

        def counting(nstep=1):
            calls.append(nstep)
            original(nstep)
        inner.physics.step = counting
    wrapped = CCDWrapper(inner)
    for action in np.random.default_rng(0).uniform(-1, 1, (5, 6)):
        plain.step(action)
        wrapped.step(action)
        assert _dm_state(plain.physics) == _dm_state(inner.physics)
        assert len(wrapped.last_reports) == 10
    assert calls == [1] * 50  # and the physics keeps its step (the hook left as it was)
    assert vars(inner.physics).get("step") is (counting if how == "instance" else None)


MOCAP = """
<mujoco>
 <worldbody>
  <body name="hand" mocap="true" pos="0 0 1"><geom type="ellipsoid" size="0.1 0.05 0.03"/></body>
  <body name="ball" pos="0.3 0 1"><freejoint/><geom type="sphere" size="0.05"/></body>
 </worldbody>
</mujoco>
"""


@pytest.mark.parametrize("xml", [ARM, MOCAP], ids=["arm", "mocap"])
def test_step_check_reads_current_body_poses_as_its_own_kinematics_computes_them(xml):
    """StepCheck.end with ``bodies_current`` (the data's own body poses after mj_step1) records the same poses, bit
    for bit, as forward kinematics on its private data."""
    from mjccd.mujoco.monitor import StepCheck

    m = mujoco.MjModel.from_xml_string(xml)
    d = mujoco.MjData(m)
    ellipsoids = fit_model(m)
    own, read = (StepCheck(CCDMonitor(m, d, ellipsoids, pairs="characters", mode="ellipsoids")) for _ in range(2))
    rng = np.random.default_rng(0)
    d.qvel[:] = rng.normal(size=m.nv)
    mujoco.mj_step1(m, d)
    for _ in range(20):
        own.begin(d)
        read.begin(d)
        d.mocap_pos[:] += rng.normal(scale=0.01, size=d.mocap_pos.shape)
        mujoco.mj_step2(m, d)
        mujoco.mj_step1(m, d)
        own.end(d)
        read.end(d, bodies_current=True)
        assert own.poses[1].tobytes() == read.poses[1].tobytes()
        assert own.poses[0].tobytes() == read.poses[0].tobytes()
        assert own.poses[1].tobytes() != own.poses[0].tobytes()


@pytest.mark.dm_control
def test_dm_control_wrapper_raises_a_physics_error_right_after_the_substep_that_warned():
    """A NaN action: the PhysicsError of dm-control's own check, after the first substep, as when the physics is
    stepped one physics.step(1) at a time; the state then is the same, and the next steps go on alike."""
    from dm_control.rl.control import PhysicsError

    from mjccd.dm_control import CCDWrapper

    reference, inner = _walker(), _walker()
    _substep_hook(reference.physics, [])
    wrapped = CCDWrapper(inner)
    nan = np.full(6, np.nan)
    for env in (reference, wrapped):
        env.step(np.zeros(6))
        with pytest.raises(PhysicsError) as raised:
            env.step(nan)
        assert str(raised.value) == "Physics state is invalid. Warning(s) raised: mjWARN_BADCTRL"
    timestep = inner.physics.model.opt.timestep  # one control step of 10 substeps, then the substep that warned
    assert inner.physics.data.time == pytest.approx(11 * timestep) and len(wrapped.last_reports) == 10
    assert _dm_state(reference.physics) == _dm_state(inner.physics)
    for env in (reference, wrapped):
        env.step(np.full(6, 0.5))
    assert _dm_state(reference.physics) == _dm_state(inner.physics)


@pytest.mark.dm_control
def test_dm_control_wrapper_logs_each_warning_substep_where_the_physics_suppresses_errors(monkeypatch):
    """Errors suppressed: dm-control's warning is logged once per substep that raised one, the same lines as one
    physics.step(1) at a time logs, and the step runs to its end (each substep checked: not unstable)."""
    from dm_control.mujoco import engine

    from mjccd.dm_control import CCDWrapper

    logged = []
    monkeypatch.setattr(engine.logging, "warn", logged.append)
    reference, inner = _walker(), _walker()
    _substep_hook(reference.physics, [])
    wrapped = CCDWrapper(inner)
    nan = np.full(6, np.nan)
    lines = []
    for env in (reference, wrapped):
        with env.physics.suppress_physics_errors():
            for action in (np.zeros(6), nan, np.zeros(6), nan):
                env.step(action)
        lines.append(list(logged))
        logged.clear()
    assert lines[0] == lines[1] == ["Physics state is invalid. Warning(s) raised: mjWARN_BADCTRL"] * 20
    assert _dm_state(reference.physics) == _dm_state(inner.physics)
    assert len(wrapped.last_reports) == 10 and not wrapped.last_unstable


def _cheetah_class():
    pytest.importorskip("gymnasium")
    try:
        from gymnasium.envs.mujoco import half_cheetah_v5
    except Exception as exc:  # gymnasium without its MuJoCo environments
        pytest.skip(f"HalfCheetah-v5: {exc}")
    return half_cheetah_v5.HalfCheetahEnv


def _gym_state(env):
    d = env.unwrapped.data
    return b"".join(a.tobytes() for a in (d.qpos, d.qvel, d.qacc_warmstart, d.cacc, d.cfrc_int, d.cfrc_ext,
                                          np.array(d.time)))


@pytest.mark.parametrize("how", ["own", "class", "instance"])
def test_gymnasium_wrapper_steps_the_simulation_bit_for_bit_as_the_plain_environment(how):
    """Wrapped or not, the same states after every step (positions, velocities, derived forces, time), the same
    observations and rewards; an environment with its own stepping (its class's, or another wrapper's hook of its
    do_simulation) is stepped through it, a step at a time, and keeps its hook."""
    from mjccd.mujoco.gym import CCDGymWrapper

    cheetah = _cheetah_class()
    calls = []

    class Counting(cheetah):
        def _step_mujoco_simulation(self, ctrl, n_frames):
            calls.append(n_frames)
            super()._step_mujoco_simulation(ctrl, n_frames)

    make = Counting if how == "class" else cheetah
    plain, inner = make(), make()
    for env in (plain, inner):
        env.reset(seed=0)
    if how == "instance":
        original = inner.do_simulation

        def hook(ctrl, n_frames):
            calls.append(n_frames)
            original(ctrl, n_frames)
        inner.do_simulation = hook
    wrapped = CCDGymWrapper(inner)
    assert wrapped._own_stepping is (how != "class")
    contacts = 0
    for action in np.random.default_rng(0).uniform(-1, 1, (30, 6)):
        a, b = plain.step(action), wrapped.step(action)
        assert a[0].tobytes() == b[0].tobytes() and a[1:4] == b[1:4]
        assert _gym_state(plain) == _gym_state(inner)
        assert len(b[4]["ccd"]["reports"]) == 5
        contacts += len(b[4]["ccd"]["contacts"])
    assert contacts > 0
    assert calls == {"own": [], "class": [5, 1, 1, 1, 1, 1] * 30, "instance": [1] * 150}[how]
    assert vars(inner).get("do_simulation") is (hook if how == "instance" else None)
