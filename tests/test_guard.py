"""Guarded stepping: no tunneling, bit-identical when nothing is predicted, no stale state after rollbacks."""
import collections

import mujoco
import numpy as np
import pytest

from mjccd.mujoco import fit_model
from mjccd.mujoco.guard import GuardedStepper, GuardedWrapper, geom_ellipsoids

WALL_HALF, BALL = 0.01, 0.02
MUJOCO_MAJOR = int(mujoco.__version__.split(".")[0])

# A ball thrown along +x at a 2 cm ellipsoid wall.  The ball carries a motor with a
# filtered activation and the model has sensors, so that act, warm starts and
# sensordata all take part in the state comparisons.
WALL = """
<mujoco>
  <option timestep="{dt!r}"/>
  <worldbody>
    <body name="wall" pos="0 0 1">
      <geom name="wall" type="ellipsoid" size="{half} 1 1" solref="0.001 1"/>
    </body>
    <body name="ball" pos="{x0!r} 0 1">
      <freejoint name="ball"/>
      <geom name="ball" type="sphere" size="{r}" density="1000" solref="0.001 1"/>
      <site name="ball"/>
    </body>
  </worldbody>
  <actuator>
    <general name="push" site="ball" gear="0 0 1 0 0 0" dyntype="filter" dynprm="0.02"/>
  </actuator>
  <sensor>
    <accelerometer site="ball"/>
    <velocimeter site="ball"/>
    <framepos objtype="site" objname="ball"/>
    <actuatorfrc actuator="push"/>
  </sensor>
</mujoco>
"""


def wall_model(dt, x0=-0.5):
    return mujoco.MjModel.from_xml_string(WALL.format(dt=dt, half=WALL_HALF, r=BALL, x0=x0))


def thrown(model, speed, ctrl=0.0):
    data = mujoco.MjData(model)
    data.qvel[0] = speed
    data.ctrl[0] = ctrl
    mujoco.mj_forward(model, data)
    return data


def inside_wall(qpos):
    """Ball centre inside the wall ellipsoid, or beyond its mid-plane."""
    x, y, z = qpos[0], qpos[1], qpos[2] - 1.0
    return x >= 0.0 or (x / WALL_HALF) ** 2 + y ** 2 + z ** 2 <= 1.0


def full_state(model, data):
    """Everything a later step depends on or a user reads back."""
    spec = mujoco.mjtState.mjSTATE_INTEGRATION
    state = np.empty(mujoco.mj_stateSize(model, spec))
    mujoco.mj_getState(model, data, state, spec)
    return np.concatenate([state, data.sensordata, data.qacc, data.act_dot, data.actuator_force])


@pytest.mark.parametrize("dt,speed", [(0.002, 50.0), (0.002, 200.0), (0.005, 200.0), (0.01, 100.0),
                                      (0.01, 200.0)])
def test_guard_stops_tunneling_through_thin_wall(dt, speed):
    model = wall_model(dt)
    steps = int(round(0.1 / dt))
    plain = thrown(model, speed)
    for _ in range(steps):
        mujoco.mj_step(model, plain)
    # dt 2 ms at 50 m/s: a step starts with the ball's centre on the wall's mid-plane. MuJoCo 3.17's contact
    # there lets the ball through; MuJoCo 4.0's sphere-ellipsoid contact has the opposite normal and pushes it
    # back, so plain MuJoCo 4 does not tunnel in this one case (the guard's part below holds on both).
    if not (MUJOCO_MAJOR >= 4 and (dt, speed) == (0.002, 50.0)):
        assert plain.qpos[0] > 1.0, "plain MuJoCo should tunnel in this case"

    data = thrown(model, speed)
    guard = GuardedStepper(model, data, fit_model(model))
    xs = []
    for _ in range(steps):
        report = guard.step()
        xs.append(data.qpos[:3].copy())
        assert not inside_wall(data.qpos), f"ball inside the wall at t = {data.time}"
        assert np.isclose(sum(report.substeps), dt, rtol=0, atol=1e-15)
    assert guard.clamps_total >= 1
    assert model.opt.timestep == dt  # restored
    assert max(x[0] for x in xs) < -BALL + 0.5 * BALL  # bounced back, never more than half a radius deep
    assert data.qvel[0] <= 0.0


def test_no_predicted_contact_is_bit_identical():
    model = wall_model(0.004)
    plain = thrown(model, -3.0, ctrl=0.5)
    guarded = thrown(model, -3.0, ctrl=0.5)
    guard = GuardedStepper(model, guarded, fit_model(model))
    for _ in range(150):
        mujoco.mj_step(model, plain)
        report = guard.step()
        assert report.clamps == () and report.substeps == (0.004,)
    assert np.array_equal(full_state(model, plain), full_state(model, guarded))


def test_rollback_leaves_no_stale_state():
    dt = 0.005
    model = wall_model(dt)
    guarded = thrown(model, 120.0, ctrl=2.0)
    guard = GuardedStepper(model, guarded, fit_model(model))
    replay = thrown(model, 120.0, ctrl=2.0)
    rolled = 0
    for k in range(40):
        ctrl = np.sin(0.3 * k)
        guarded.ctrl[0] = replay.ctrl[0] = ctrl
        report = guard.step()
        rolled += report.rollbacks
        # a plain run that stops at the same instants
        for h in report.substeps:
            model.opt.timestep = h
            mujoco.mj_step(model, replay)
        model.opt.timestep = dt
        assert np.array_equal(full_state(model, guarded), full_state(model, replay)), f"step {k}"
    assert rolled >= 1
    assert guarded.act[0] != 0.0 and np.any(guarded.qacc_warmstart != 0.0)


def test_start_poses_are_read_off_the_saved_state():
    # without mocap bodies the guard takes the step start's positions from the state it saved for a
    # rollback; with one it reads the kinematic state (positions and mocap poses) itself
    from mjccd.mujoco.guard import STATE_SPEC

    plain_xml = WALL.format(dt=0.004, half=WALL_HALF, r=BALL, x0=-0.5)
    mocap_xml = plain_xml.replace("<worldbody>", '<worldbody><body name="marker" mocap="true" pos="0 2 0"/>')
    for xml, reads_saved in ((plain_xml, True), (mocap_xml, False)):
        model = mujoco.MjModel.from_xml_string(xml)
        data = thrown(model, 150.0)
        guard = GuardedStepper(model, data, fit_model(model), mode="ellipsoids")  # the lean ellipsoid path
        assert (guard._qpos0 is not None) == reads_saved
        for _ in range(20):
            data.mocap_pos[:] += 0.01
            guard.step()
            assert not inside_wall(data.qpos)
        assert guard.clamps_total >= 1
        if reads_saved:
            mujoco.mj_getState(model, data, guard._state0, STATE_SPEC)
            assert guard._qpos0.tobytes() == data.qpos.tobytes()  # no mocap body: the kinematic state is qpos


def test_max_rechecks_zero_only_reports():
    model = wall_model(0.002)
    data = thrown(model, 200.0)
    seen = []
    guard = GuardedStepper(model, data, fit_model(model), max_rechecks=0, on_clamp=seen.append)
    for _ in range(50):
        guard.step()
    assert data.qpos[0] > 0.0 and seen == [] and guard.clamps_total == 0


def test_clamp_reports_contact():
    model = wall_model(0.01)
    data = thrown(model, 100.0)
    seen = []
    guard = GuardedStepper(model, data, fit_model(model), on_clamp=seen.append)
    report = None
    while not seen:
        report = guard.step()
    c = seen[0]
    assert set(c.bodies) == {"wall", "ball"} and c.status_at_start == "separate"
    # first contact when the ball centre is at x = -(half + radius)
    assert report.rollbacks == 1 and len(report.substeps) >= 2
    assert abs(c.point[0] + WALL_HALF) < 1e-6


@pytest.mark.parametrize("max_penetration,clamped", [(0.0, True), (0.25, False)])
def test_slow_contact_is_left_to_mujoco(max_penetration, clamped):
    """A ball approaching at 5 mm per step touches the wall: below a quarter of the pair's thickness (3 cm) it
    is MuJoCo's contact; with max_penetration 0 the guard clamps it."""
    dt = 0.002
    model = wall_model(dt, x0=-(WALL_HALF + BALL) - 0.004)
    data = thrown(model, 2.5)
    guard = GuardedStepper(model, data, fit_model(model), max_penetration=max_penetration)
    for _ in range(5):
        guard.step()
        assert not inside_wall(data.qpos)
    assert (guard.clamps_total > 0) == clamped
    assert data.qvel[0] <= 0.0  # stopped by MuJoCo's contact either way


def test_fast_contact_is_clamped_whatever_max_penetration():
    model = wall_model(0.01)
    data = thrown(model, 100.0)
    guard = GuardedStepper(model, data, fit_model(model), max_penetration=0.9)
    for _ in range(10):
        guard.step()
        assert not inside_wall(data.qpos)
    assert guard.clamps_total >= 1


def test_bad_arguments():
    model = wall_model(0.002)
    data = mujoco.MjData(model)
    ell = fit_model(model)
    with pytest.raises(ValueError, match="max_rechecks: expected a finite integer >= 0, got -1"):
        GuardedStepper(model, data, ell, max_rechecks=-1)
    with pytest.raises(ValueError, match="overshoot"):
        GuardedStepper(model, data, ell, overshoot=2.0)
    with pytest.raises(ValueError, match="contact_step"):
        GuardedStepper(model, data, ell, contact_step=0.0)
    with pytest.raises(ValueError, match="max_penetration: expected a fraction of the pair's thickness below 1"):
        GuardedStepper(model, data, ell, max_penetration=1.0)
    with pytest.raises(ValueError, match="max_penetration: expected a finite number >= 0"):
        GuardedStepper(model, data, ell, max_penetration=float("nan"))
    with pytest.raises(ValueError, match="nstep"):
        GuardedStepper(model, data, ell).step(0)
    with pytest.raises(ValueError, match="pairs"):
        GuardedStepper(model, data, ell, pairs=[("ball", "nowhere")])
    with pytest.raises(ValueError, match="group: the model has no ellipsoid geom in group 5"):
        geom_ellipsoids(model, 5)


def test_geom_ellipsoids_reads_group():
    ell = geom_ellipsoids(wall_model(0.002), 0)
    assert ell.bodies == ("wall",) and np.allclose(ell.radii, [[WALL_HALF, 1, 1]])


# An arm on a ball joint swung at up to 1.2 rad per step into a fixed head placed a little above its plane,
# so that the contact tilts the spin.  Contacts are stiff, as in the tunneling benchmark.
SWING = """
<mujoco>
  <option timestep="{dt!r}" gravity="0 0 0" integrator="implicit"/>
  <worldbody>
    <body name="head" pos="{hx!r} {hy!r} 0.04">
      <geom name="head" type="ellipsoid" size="0.1 0.1 0.12" solref="0.001 1"/>
    </body>
    <body name="arm">
      <joint name="shoulder" type="ball"/>
      <geom name="arm" type="ellipsoid" size="0.3 0.04 0.04" pos="0.3 0 0" mass="1" solref="0.001 1"/>
    </body>
  </worldbody>
</mujoco>
"""


def swing(omega, angle, guarded, dt=1 / 120):
    """(the arm passed the head before MuJoCo saw a contact, MuJoCo reset an unstable run)."""
    model = mujoco.MjModel.from_xml_string(SWING.format(dt=dt, hx=float(0.55 * np.cos(angle)),
                                                        hy=float(0.55 * np.sin(angle))))
    data = mujoco.MjData(model)
    data.qvel[2] = omega
    mujoco.mj_forward(model, data)
    guard = GuardedStepper(model, data, fit_model(model)) if guarded else None
    seen = passed = False
    for _ in range(18):
        if guard is None:
            mujoco.mj_step(model, data)
        else:
            guard.step()
        seen = seen or data.ncon > 0
        centre = data.geom_xpos[model.geom("arm").id]
        passed = passed or (not seen and angle < np.arctan2(centre[1], centre[0]) < angle + 1.5)
    return passed, data.warning[mujoco.mjtWarning.mjWARN_BADQACC].number > 0


def test_guard_stops_a_fast_swing_and_stays_stable():
    """A rotating body (the CCD follows the chord of its arc): never past the head unseen, never diverging.

    With MuJoCo's default Euler integrator this swing can diverge once the contact tilts the spin, plain or
    guarded (explicit gyroscopic forces at ~1 rad per step); the implicit integrator keeps it stable.
    """
    cases = [(omega, np.radians(angle)) for omega in (60.0, 100.0, 140.0) for angle in (50, 60, 70)]
    plain = [swing(omega, angle, False) for omega, angle in cases]
    guarded = [swing(omega, angle, True) for omega, angle in cases]
    assert any(p for p, _ in plain), "plain MuJoCo should let the arm through in some cases"
    assert not any(p for p, _ in guarded)
    assert not any(u for _, u in plain + guarded)


def test_a_step_mujoco_resets_is_kept_and_not_checked():
    # the ball sits beyond the wall; a NaN force makes MuJoCo reset it to its start pose in front of the
    # wall: that jump crosses the wall but is no motion, so the guard keeps the step exactly as plain
    # MuJoCo leaves it
    model = wall_model(0.005)
    datas = []
    for _ in range(2):
        data = thrown(model, 2.0)
        data.qpos[0] = 0.3
        mujoco.mj_forward(model, data)
        data.qfrc_applied[0] = np.nan
        datas.append(data)
    plain, guarded = datas
    guard = GuardedStepper(model, guarded, fit_model(model))
    mujoco.mj_step(model, plain)
    report = guard.step()
    assert report.unstable and report.clamps == () and report.rollbacks == 0 and report.substeps == (0.005,)
    assert guarded.warning[mujoco.mjtWarning.mjWARN_BADQACC].number == 1
    assert guarded.qpos[0] == -0.5
    assert np.array_equal(full_state(model, plain), full_state(model, guarded))
    assert not guard.step().unstable  # the next step is an ordinary one


def test_the_bad_state_counts_are_one_slice_of_the_warnings():
    from mjccd.mujoco.guard import BAD_COUNTS, BAD_STATE_WARNINGS

    assert sorted(int(w) for w in BAD_STATE_WARNINGS) == list(range(BAD_COUNTS.start, BAD_COUNTS.stop))


@pytest.fixture
def poison_short_steps():
    """Installs a control callback that makes the first MuJoCo step shorter than ``dt`` meet a NaN force."""
    poisoned = []

    def poison(model, data, dt):
        if model.opt.timestep < dt and not poisoned:
            poisoned.append(data.time)
            data.qfrc_applied[0] = np.nan

    yield lambda dt: mujoco.set_mjcb_control(lambda model, data: poison(model, data, dt))
    mujoco.set_mjcb_control(None)


def test_a_piece_mujoco_resets_ends_the_step(poison_short_steps):
    # the trial step (5 ms) is sound and finds the wall; the clamp step, shorter, meets a bad acceleration
    model = wall_model(0.005)
    data = thrown(model, 120.0)
    guard = GuardedStepper(model, data, fit_model(model))
    poison_short_steps(0.005)
    reports = [guard.step() for _ in range(20)]
    unstable = [r for r in reports if r.unstable]
    assert len(unstable) == 1
    report = unstable[0]
    assert report.rollbacks == 1 and len(report.clamps) == 1 and len(report.substeps) == 1
    assert 0.0 < report.substeps[0] < 0.005
    assert model.opt.timestep == 0.005
    assert data.warning[mujoco.mjtWarning.mjWARN_BADQACC].number == 1
    assert reports[-1].substeps == (0.005,) and data.qpos[0] == -0.5  # reset, then at rest


def test_autoreset_off_unstable_steps_are_reported_not_checked():
    model = wall_model(0.005)
    model.opt.disableflags |= mujoco.mjtDisableBit.mjDSBL_AUTORESET
    data = thrown(model, 2.0)
    guard = GuardedStepper(model, data, fit_model(model))
    data.qfrc_applied[0] = np.nan
    reports = [guard.step() for _ in range(3)]
    assert all(r.unstable and r.clamps == () for r in reports)
    assert np.isnan(data.qpos[0])


# ------------------------------------------------------------ dm-control


def _env(speed, control_timestep=0.02):
    from dm_control import mujoco as dm_mujoco
    from dm_control.rl import control
    from dm_control.suite import base

    class Throw(base.Task):
        def initialize_episode(self, physics):
            physics.data.qvel[0] = speed

        def get_observation(self, physics):
            return collections.OrderedDict(x=physics.data.qpos[:3].copy())

        def get_reward(self, physics):
            return 0.0

    physics = dm_mujoco.Physics.from_xml_string(WALL.format(dt=0.004, half=WALL_HALF, r=BALL, x0=-0.5))
    return control.Environment(physics, Throw(random=0), control_timestep=control_timestep, time_limit=1.0)


@pytest.mark.dm_control
def test_dm_control_wrapper_guards_substeps():
    plain, wrapped = _env(150.0), GuardedWrapper(_env(150.0))
    plain.reset()
    wrapped.reset()
    for _ in range(5):
        a = plain.step(np.zeros(1))
        b = wrapped.step(np.zeros(1))
    assert a.observation["x"][0] > 0.0
    assert b.observation["x"][0] < -BALL
    assert any(r.clamps for r in wrapped.last_reports) or wrapped.stepper.clamps_total >= 1
    assert len(wrapped.last_reports) == 5


@pytest.mark.dm_control
def test_dm_control_wrapper_without_contact_is_identical():
    plain, wrapped = _env(-2.0), GuardedWrapper(_env(-2.0))
    plain.reset()
    wrapped.reset()
    for k in range(10):
        a = plain.step(np.array([np.cos(k)]))
        b = wrapped.step(np.array([np.cos(k)]))
        assert np.array_equal(a.observation["x"], b.observation["x"])
    pm, pd = plain.physics.model.ptr, plain.physics.data.ptr
    wm, wd = wrapped.physics.model.ptr, wrapped.physics.data.ptr
    assert np.array_equal(full_state(pm, pd), full_state(wm, wd))


@pytest.mark.dm_control
def test_dm_control_wrapper_raises_physics_error_like_dm_control(poison_short_steps):
    from dm_control.rl.control import PhysicsError

    wrapped = GuardedWrapper(_env(150.0))
    wrapped.reset()
    poison_short_steps(0.004)
    with pytest.raises(PhysicsError, match="BADQACC"):
        for _ in range(5):
            wrapped.step(np.zeros(1))


def test_clamp_goes_to_entry_not_exit():
    # a case where the batched scene check reports the exit instant of the pair;
    # the guard must still clamp at the entry (centre at x = -(half + radius))
    x0, v, dt = -0.4726076625357091, 190.7914685505548, 0.01
    model = wall_model(dt, x0=x0)
    data = thrown(model, v)
    guard = GuardedStepper(model, data, fit_model(model))
    report = guard.step()
    entry = (-(WALL_HALF + BALL) - x0) / (v * dt)
    assert len(report.clamps) == 1 and abs(report.clamps[0].fraction - entry) < 1e-6
    assert data.qvel[0] < 0.0 and not inside_wall(data.qpos)


@pytest.mark.parametrize("a", [-1.0, 0.0, 0.3, 1.0 - 1e-13, 1.0, 1.5, 2.0, 5.0])
def test_reach_fraction_solves_the_sub_step_model(a):
    """A MuJoCo step of s·dt covers a·s + (1 − a)·s² of the full step's displacement: s is that fraction's
    first root, tau at constant velocity, √tau from rest, less than tau when slowing down."""
    from mjccd.mujoco.guard import reach_fraction

    for tau in (0.0, 1e-9, 0.01, 0.2, 0.5, 0.9, 1.0):
        s = reach_fraction(tau, a)
        assert 0.0 <= s <= 1.0
        assert a * s + (1.0 - a) * s * s == pytest.approx(tau, abs=1e-12)
        grid = np.linspace(0.0, s, 1001)[:-1]
        assert np.all(a * grid + (1.0 - a) * grid ** 2 < tau + 1e-12)  # the first root
        if a == 1.0:
            assert s == tau
        elif a == 0.0:
            assert s == pytest.approx(np.sqrt(tau), abs=1e-15)
        elif a > 1.0 and 0.0 < tau < 1.0:
            assert s < tau


def kicked(model, speed, dt):
    """A ball at rest, pushed along +x by a force that leaves it at ``speed`` after one step of ``dt``."""
    data = thrown(model, 0.0)
    ball = model.body("ball").id
    data.xfrc_applied[ball, 0] = speed / dt * model.body_mass[ball]
    return data


def test_a_kick_from_rest_is_clamped_once_at_the_contact():
    """From rest, a shorter MuJoCo step covers less than its share of the step's path (s² of it): the clamp
    step is √tau long, and it lands a hair past the contact, so one clamp does (the interpolation's tau
    alone would land 1.6 cm short and clamp again and again)."""
    dt, gap = 0.01, 0.02
    model = wall_model(dt, x0=-(WALL_HALF + BALL + gap))
    data = kicked(model, 10.0, dt)
    spec = mujoco.mjtState.mjSTATE_INTEGRATION
    start = np.empty(mujoco.mj_stateSize(model, spec))
    mujoco.mj_getState(model, data, start, spec)
    guard = GuardedStepper(model, data, fit_model(model))
    report = guard.step()
    assert len(report.clamps) == 1 and report.rollbacks == 1
    tau = report.clamps[0].fraction
    assert report.substeps[0] == pytest.approx((np.sqrt(tau) + guard.overshoot) * dt, rel=1e-12)
    replay = mujoco.MjData(model)  # the clamp step alone, from the same start
    mujoco.mj_setState(model, replay, start, spec)
    model.opt.timestep = report.substeps[0]
    mujoco.mj_step(model, replay)
    model.opt.timestep = dt
    depth = replay.qpos[0] + BALL + WALL_HALF
    assert 0.0 < depth < 2e-4  # a hair past the contact, so MuJoCo's contact takes over
    assert not inside_wall(data.qpos)


def test_a_lengthened_clamp_step_that_meets_a_contact_early_is_redone():
    """The safety net of the lengthened clamp step: when it reaches a contact well before its end (here a
    wrong model that runs it to 90 % of the step), it is rolled back and redone to just past that contact."""
    dt, speed, x0 = 0.01, 10.0, -0.06
    model = wall_model(dt, x0=x0)
    data = thrown(model, speed)
    guard = GuardedStepper(model, data, fit_model(model))
    guard._reach = lambda hit: 0.9
    report = guard.step()
    entry = (-(WALL_HALF + BALL) - x0) / (speed * dt)
    assert len(report.clamps) == 1 and report.clamps[0].fraction == pytest.approx(entry, abs=1e-3)
    assert report.rollbacks == 2  # the trial, then the too-long clamp step
    assert report.substeps[0] == pytest.approx((entry + guard.overshoot) * dt, abs=1e-3 * dt)
    assert np.isclose(sum(report.substeps), dt, rtol=0, atol=1e-15)
    assert not inside_wall(data.qpos) and data.qpos[0] < -WALL_HALF - 0.5 * BALL


# ------------------------------------------------------------ the lean step check


BOX = """
<mujoco>
  <option timestep="0.004" gravity="0 0 -9.81"/>
  <worldbody>
    <geom name="floor" type="ellipsoid" size="0.5 0.5 0.01" pos="0 0 0"/>
    <geom name="side" type="ellipsoid" size="0.01 0.5 0.3" pos="0.3 0 0.2"/>
    <body name="a" pos="0 0 0.2"><freejoint/><geom type="ellipsoid" size="0.05 0.03 0.02"/></body>
    <body name="b" pos="0.1 0.05 0.3"><freejoint/><geom type="ellipsoid" size="0.02 0.04 0.06"/></body>
    <body name="c" pos="-0.1 0 0.15"><freejoint/><geom type="sphere" size="0.03"/></body>
  </worldbody>
</mujoco>
"""


@pytest.mark.parametrize("motion", ["rigid", "affine"])
def test_step_check_prefilter_never_hides_a_contact(motion):
    # tumbling ellipsoids on a floor and against a wall: whenever the compiled prefilter clears a
    # step, the monitor's exact check of the same two states finds no new contact either, and
    # otherwise the lean check's contact is the monitor's
    from mjccd.mujoco import CCDMonitor
    from mjccd.mujoco.guard import StepCheck
    from mjccd.mujoco.motions import capture

    model = mujoco.MjModel.from_xml_string(BOX)
    rng = np.random.default_rng(3)
    cleared = hits = 0
    for run in range(3):
        data = mujoco.MjData(model)
        data.qvel[:] = rng.normal(0.0, 2.0, model.nv)
        data.qvel[0::6] += 1.5  # towards the side wall
        mujoco.mj_forward(model, data)
        ell = fit_model(model, per="geom")
        monitor = CCDMonitor(model, data, ell, motion=motion, report_overlapping=False, mode="ellipsoids")
        check = StepCheck(monitor)
        for _ in range(150):
            s0 = capture(data)
            check.begin(data)
            mujoco.mj_step(model, data)
            s1 = capture(data)
            may = check.end_may_touch(data)
            p0, p1 = check.poses
            kinematics = monitor.adapter.kinematics
            assert np.array_equal(p0, kinematics.ellipsoid_poses(s0, monitor.body_ids, ell.positions, ell.quaternions))
            assert np.array_equal(p1, kinematics.ellipsoid_poses(s1, monitor.body_ids, ell.positions, ell.quaternions))
            exact = monitor.check(s0, s1)
            lean = check.first((s0.time, s1.time))
            if not may:
                cleared += 1
                assert exact is None
            if exact is None:
                assert lean is None
            else:
                hits += 1
                assert lean is not None and lean.fraction == exact.fraction and lean.ellipsoids == exact.ellipsoids
                assert lean.time == exact.time
                assert np.array_equal(lean.point, exact.point) and np.array_equal(lean.normal, exact.normal)
    assert cleared > 50 and hits > 3


def test_guard_names_are_exported():
    import mjccd.mujoco as mm

    assert mm.GuardedStepper is GuardedStepper and mm.GuardedWrapper is GuardedWrapper
    assert mm.GuardReport.__name__ == "GuardReport" and "GuardedStepper" in mm.__all__



def test_step_check_follow_reuses_the_end_poses():
    from mjccd.mujoco import CCDMonitor
    from mjccd.mujoco.guard import StepCheck

    model = mujoco.MjModel.from_xml_string(BOX)
    data = mujoco.MjData(model)
    data.qvel[:] = 1.0
    mujoco.mj_forward(model, data)
    check = StepCheck(CCDMonitor(model, data, fit_model(model, per="geom"), report_overlapping=False,
                                 mode="ellipsoids"))
    check.begin(data)
    mujoco.mj_step(model, data)
    check.end_may_touch(data)
    end = check.poses[1].copy()
    check.follow()
    assert np.array_equal(check.poses[0], end)
    mujoco.mj_step(model, data)
    check.end_may_touch(data)
    followed = [p.copy() for p in check.poses]
    check.begin(data)  # what a fresh begin of the same state would record
    assert np.array_equal(check.poses[0], followed[1])


# ------------------------------------------------------------ energy after a clamp

# A two-link arm: the upper link turns freely on a ball joint, the forearm hangs on a heavily damped ball
# joint, as the boxing benchmark's elbow and wrist, and its end swings into a thin stop.  With the implicit
# integrator, a contact force that a short step builds up against the damped joint carries into the next step;
# the guard used to follow its short contact step with one long one and so spun the arm up (4 to 170 times
# its energy); plain MuJoCo at dt and dt/10 never gains energy here.
PENDULUM = """
<mujoco>
  <option timestep="{dt!r}" integrator="implicit"/>
  <default><geom type="ellipsoid" solref="0.001 1"/></default>
  <worldbody>
    <body name="upper">
      <joint name="shoulder" type="ball"/>
      <geom size="0.2 0.03 0.03" pos="0.2 0 0" mass="1" contype="0" conaffinity="0"/>
      <body name="fore" pos="0.4 0 0">
        <joint name="elbow" type="ball" damping="1e4"/>
        <geom name="fore" size="0.15 0.03 0.03" pos="0.15 0 0" mass="0.5"/>
      </body>
    </body>
    <body name="stop" pos="0 0.55 0"><geom name="stop" size="0.1 0.01 0.1"/></body>
  </worldbody>
</mujoco>
"""


def mechanical_energy(model, data):
    """Kinetic plus potential energy of ``data`` (computed on a copy)."""
    probe = mujoco.MjData(model)
    probe.qpos[:], probe.qvel[:] = data.qpos, data.qvel
    mujoco.mj_forward(model, probe)
    mujoco.mj_energyPos(model, probe)
    mujoco.mj_energyVel(model, probe)
    return float(probe.energy.sum()), float(probe.energy[1])


def strike(spin, mode, steps=30, dt=1 / 120):
    """Swing the pendulum about z at ``spin`` rad/s (tilted about x by 3 rad/s) into the stop; (peak
    energy over the start's, the reports) under ``mode``: "plain", "dt/10" or "guarded"."""
    k = 10 if mode == "dt/10" else 1
    model = mujoco.MjModel.from_xml_string(PENDULUM.format(dt=dt / k))
    data = mujoco.MjData(model)
    data.qvel[:3] = [3.0, 0.0, spin]
    mujoco.mj_forward(model, data)
    guard = GuardedStepper(model, data, fit_model(model), pairs=[("fore", "stop")]) if mode == "guarded" else None
    start, _ = mechanical_energy(model, data)
    peak, reports = start, []
    for _ in range(steps * k):
        if guard is None:
            mujoco.mj_step(model, data)
        else:
            reports.append(guard.step())
        peak = max(peak, mechanical_energy(model, data)[0])
    return peak / start, reports


@pytest.mark.parametrize("spin", [40.0, 80.0])
def test_a_pendulum_striking_a_stop_gains_no_energy_under_the_guard(spin):
    guarded, reports = strike(spin, "guarded")
    fine, _ = strike(spin, "dt/10")
    assert sum(len(r.clamps) for r in reports) >= 1
    assert fine <= 1.0 + 1e-9
    assert guarded <= fine * 1.05
    split = [r for r in reports if len(r.substeps) > 1]
    assert split and not any(r.energy_gain for r in reports)
    for r in split:  # the clamped step removes most of the swing's energy, and no step adds energy
        assert r.energy_added <= 1e-9 * r.kinetic_energy[0]
    assert split[0].kinetic_energy[1] < 0.5 * split[0].kinetic_energy[0]
    plain = [r for r in reports if len(r.substeps) == 1]
    assert plain and all(r.kinetic_energy is not None and r.energy_added is None and not r.energy_gain
                         for r in plain)


def kinetic_energy_and_momentum(model, data):
    """0.5 qvel' M qvel from the dense mass matrix, and the linear momentum summed over bodies (each body's
    mass times the velocity of its centre of mass), on a copy: independent of the guard's own route."""
    probe = mujoco.MjData(model)
    probe.qpos[:], probe.qvel[:] = data.qpos, data.qvel
    mujoco.mj_forward(model, probe)
    M = np.zeros((model.nv, model.nv))
    mujoco.mj_fullM(model, probe, M)
    linear = np.zeros(3)
    for b in range(1, model.nbody):
        jac = np.zeros((3, model.nv))
        mujoco.mj_jac(model, probe, jac, None, probe.xipos[b], b)
        linear += model.body_mass[b] * (jac @ probe.qvel)
    return 0.5 * probe.qvel @ M @ probe.qvel, linear


@pytest.mark.parametrize("speed", [20.0, 200.0])
def test_every_report_gives_kinetic_energy_and_momentum_at_both_ends(speed):
    """Plain, clamped and unclamped steps alike: the report's values equal an independent computation at
    the step's start and end, and one step's end is the next one's start."""
    model = wall_model(0.002)
    data = thrown(model, speed)
    guard = GuardedStepper(model, data, fit_model(model))
    before = kinetic_energy_and_momentum(model, data)
    last = None
    kinds = set()
    for _ in range(60):
        report = guard.step()
        after = kinetic_energy_and_momentum(model, data)
        kinds.add("clamped" if report.clamps else "split" if len(report.substeps) > 1 else "plain")
        for end, (energy, linear) in enumerate((before, after)):
            assert report.kinetic_energy[end] == pytest.approx(energy, rel=1e-9, abs=1e-12)
            assert report.momentum[end].shape == (6,)
            assert np.allclose(report.momentum[end][:3], linear, rtol=1e-9, atol=1e-12)
        if last is not None:
            assert report.kinetic_energy[0] == last.kinetic_energy[1]
            assert np.array_equal(report.momentum[0], last.momentum[1])
        before, last = after, report
    assert {"plain", "clamped"} <= kinds


def test_a_state_changed_between_steps_is_measured_again():
    model = wall_model(0.002)
    data = thrown(model, 5.0)
    guard = GuardedStepper(model, data, fit_model(model))
    guard.step()
    data.qvel[:] = 0.0
    data.qvel[0] = 1.0  # the user changes the state between steps
    report = guard.step()
    mass = model.body("ball").mass[0]
    assert report.kinetic_energy[0] == pytest.approx(0.5 * mass * 1.0, rel=1e-9)
    assert report.momentum[0][0] == pytest.approx(mass * 1.0, rel=1e-9)


def test_a_step_that_adds_energy_is_flagged(monkeypatch):
    """Without the ramp of growing pieces (one short contact step, then the rest of the step at once, as
    the guard used to step) the pendulum's clamped step spins the arm up: the report says so."""
    import mjccd.mujoco.guard as guard_module

    monkeypatch.setattr(guard_module, "RAMP_GROWTH", float("inf"))
    model = mujoco.MjModel.from_xml_string(PENDULUM.format(dt=1 / 120))
    data = mujoco.MjData(model)
    data.qvel[:3] = [3.0, 0.0, 80.0]
    mujoco.mj_forward(model, data)
    guard = GuardedStepper(model, data, fit_model(model), pairs=[("fore", "stop")], contact_step=0.05)
    guard._contact_half = 0.0  # the first piece in contact: contact_step, as before
    reports = [guard.step() for _ in range(4)]
    flagged = [r for r in reports if r.energy_gain]
    assert flagged and flagged[0].clamps
    before, after = flagged[0].kinetic_energy
    assert after > 2.0 * before and flagged[0].energy_added > 0.5 * after


def test_a_free_ball_bouncing_on_a_wall_gains_no_energy():
    """No damped joint carries a contact force from one step into the next: after the clamp the rest of
    the step is one piece, and the mechanical energy (kinetic plus gravity) only falls."""
    for dt, speed in ((0.002, 200.0), (0.01, 50.0)):
        model = wall_model(dt)
        data = thrown(model, speed)
        guard = GuardedStepper(model, data, fit_model(model))
        start, _ = mechanical_energy(model, data)
        for _ in range(int(round(0.1 / dt))):
            report = guard.step()
            assert mechanical_energy(model, data)[0] <= start * (1.0 + 1e-9)
            assert not report.energy_gain
            if report.clamps:
                assert len(report.substeps) == 3  # the clamp, a piece in contact, the rest
                assert report.kinetic_energy[1] < report.kinetic_energy[0]
        assert guard.clamps_total >= 1 and data.qvel[0] <= 0.0


def test_the_pieces_grow_into_the_next_step_while_in_contact():
    """A clamp late in a step on the damped pendulum: the pieces in contact at most double, and the next
    step goes on with them (no trial, no clamp) until they are back to the timestep; a plain run that
    takes the same lengths reaches the same states bit for bit."""
    from mjccd.mujoco.guard import RAMP_GROWTH

    dt = 1 / 120
    model = mujoco.MjModel.from_xml_string(PENDULUM.format(dt=dt))
    data, replay = mujoco.MjData(model), mujoco.MjData(model)
    for d in (data, replay):
        d.qvel[:3] = [0.0, 0.0, 15.0]  # the clamp comes at 0.81 of a step
        mujoco.mj_forward(model, d)
    guard = GuardedStepper(model, data, fit_model(model), pairs=[("fore", "stop")])
    carried = 0
    half = 0.5 * 0.001  # half the contacts' time constant
    for _ in range(30):
        report = guard.step()
        for h in report.substeps:
            model.opt.timestep = h
            mujoco.mj_step(model, replay)
        model.opt.timestep = dt
        assert np.array_equal(full_state(model, data), full_state(model, replay))
        assert np.isclose(sum(report.substeps), dt, rtol=0, atol=1e-15)
        if len(report.substeps) > 1 and not report.clamps:
            carried += 1
            assert report.rollbacks == 0 and report.kinetic_energy is not None
        pieces = report.substeps[1:] if report.clamps else report.substeps
        for a, b in zip(pieces, pieces[1:]):
            assert b <= RAMP_GROWTH * max(a, half) * (1 + 1e-12) or b == pieces[-1]
    assert guard.clamps_total >= 1 and carried >= 1


def test_a_reset_ends_the_ramp_and_runs_repeat_exactly():
    """The same start gives the same guarded trajectory twice, on one guard (reset in between, as an
    episode) and on a fresh one."""
    dt = 1 / 120
    model = mujoco.MjModel.from_xml_string(PENDULUM.format(dt=dt))

    def trajectory(guard, data):
        """Up to the first clamped step, which leaves pieces to grow in the next."""
        mujoco.mj_resetData(model, data)
        data.qvel[:3] = [0.0, 0.0, 15.0]
        mujoco.mj_forward(model, data)
        out = []
        for _ in range(30):
            report = guard.step()
            out.append((report.substeps, data.qpos.tobytes(), data.qvel.tobytes()))
            if report.clamps:
                break
        return out, guard._ramp

    data = mujoco.MjData(model)
    guard = GuardedStepper(model, data, fit_model(model), pairs=[("fore", "stop")])
    first, ramp = trajectory(guard, data)
    assert ramp is not None  # the run ends with pieces still growing: the reset must drop them
    again, _ = trajectory(guard, data)
    data2 = mujoco.MjData(model)
    fresh, _ = trajectory(GuardedStepper(model, data2, fit_model(model), pairs=[("fore", "stop")]), data2)
    assert first == again == fresh
    assert any(len(s) > 1 for s, _, _ in first)


def test_contact_time_and_carrying():
    from mjccd.mujoco.guard import carries_contact_force, shortest_contact_time

    pendulum = mujoco.MjModel.from_xml_string(PENDULUM.format(dt=0.01))
    assert shortest_contact_time(pendulum) == 0.001 and carries_contact_force(pendulum)
    ball = wall_model(0.01)
    assert shortest_contact_time(ball) == 0.001
    undamped = PENDULUM.format(dt=0.01).replace(' damping="1e4"', "")
    assert not carries_contact_force(mujoco.MjModel.from_xml_string(undamped))
    ball.opt.enableflags |= mujoco.mjtEnableBit.mjENBL_OVERRIDE
    ball.opt.o_solref[0] = 0.0005
    assert shortest_contact_time(ball) == 0.0005
    damped_euler = mujoco.MjModel.from_xml_string(PENDULUM.format(dt=0.01).replace(' integrator="implicit"', ""))
    assert carries_contact_force(damped_euler)
    damped_euler.opt.disableflags |= mujoco.mjtDisableBit.mjDSBL_EULERDAMP
    assert not carries_contact_force(damped_euler)
    damped_euler.opt.integrator = mujoco.mjtIntegrator.mjINT_RK4
    assert not carries_contact_force(damped_euler)


def test_energy_tolerance_is_checked():
    model = wall_model(0.002)
    with pytest.raises(ValueError, match="energy_tolerance: expected a finite number >= 0, got -0.1"):
        GuardedStepper(model, mujoco.MjData(model), fit_model(model), energy_tolerance=-0.1)


def test_a_moved_mocap_body_is_a_changed_state():
    """The mocap poses are part of the state a report measures: moving one between steps starts the next
    report from a state measured again; leaving it starts it from the last report's end."""
    xml = WALL.format(dt=0.002, half=WALL_HALF, r=BALL, x0=-0.5).replace(
        "<worldbody>", '<worldbody><body name="marker" mocap="true" pos="0 2 0">'
                       '<geom type="sphere" size="0.1" contype="0" conaffinity="0"/></body>')
    model = mujoco.MjModel.from_xml_string(xml)
    data = thrown(model, 5.0)
    guard = GuardedStepper(model, data, fit_model(model))
    first = guard.step()
    same = guard.step()
    assert same.states[0] is first.states[1]
    data.mocap_pos[0, 2] += 1.0
    moved = guard.step()
    assert moved.states[0] is not same.states[1]
    assert moved.kinetic_energy[0] == pytest.approx(same.kinetic_energy[1], rel=1e-12)
