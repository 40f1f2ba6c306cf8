"""Errors and bad states in the MuJoCo layer: no contact invented across a reset, arguments checked alike."""
import re

import mujoco
import numpy as np
import pytest

from mjccd.errors import InputError, InputTypeError
from mjccd.mujoco import CCDMonitor, EllipsoidSet, GuardedStepper, fit_model, interpolate_qpos, load_ellipsoids
from mjccd.scene import Scene

# A ball in front of a thin wall; the tests put it behind the wall, so that MuJoCo's reset to qpos0 jumps
# through the wall.
WALL = """
<mujoco>
  <option timestep="0.005" gravity="0 0 0"/>
  <worldbody>
    <body name="wall" pos="0 0 1"><geom name="wall_geom" type="ellipsoid" size="0.01 1 1"/></body>
    <body name="ball" pos="-0.5 0 1"><freejoint/><geom name="ball_geom" type="sphere" size="0.02"/></body>
  </worldbody>
</mujoco>
"""
ELLIPSOIDS = EllipsoidSet(bodies=("wall", "ball"), radii=[[0.01, 1, 1], [0.02, 0.02, 0.02]],
                          positions=np.zeros((2, 3)), quaternions=[[1, 0, 0, 0]] * 2)


def wall_model(autoreset=True):
    model = mujoco.MjModel.from_xml_string(WALL)
    if not autoreset:
        model.opt.disableflags |= mujoco.mjtDisableBit.mjDSBL_AUTORESET
    return model


def behind_the_wall(model, data, speed=1e200):
    """The ball behind the wall (x = 0.3) at a speed MuJoCo finds bad: it resets the data to qpos0 (x = -0.5)."""
    data.qpos[0] = 0.3
    data.qvel[0] = speed
    mujoco.mj_forward(model, data)


# ------------------------------------------------------------ bad states: reported unstable, nothing checked


def test_monitor_reports_a_reset_step_unstable_not_a_contact():
    model = wall_model()
    data = mujoco.MjData(model)
    seen = []
    monitor = CCDMonitor(model, data, ELLIPSOIDS, on_contact=seen.append)
    for _ in range(2):  # the second reset leaves the warning count as it was: the time tells
        behind_the_wall(model, data)
        assert monitor.step() is None
        assert monitor.last_report.unstable and monitor.last_report.contacts == ()
        assert data.qpos[0] == -0.5  # MuJoCo reset the data
    assert seen == []
    assert monitor.step() is None and not monitor.last_report.unstable  # the next step is an ordinary one


def test_monitor_several_steps_report_the_unstable_one():
    model = wall_model()
    data = mujoco.MjData(model)
    monitor = CCDMonitor(model, data, ELLIPSOIDS)
    behind_the_wall(model, data)
    assert monitor.step(np.int64(3)) is None
    assert monitor.last_report.unstable and data.time == pytest.approx(0.015)  # reset as the first step began


def test_monitor_and_guard_report_a_reset_alike():
    model = wall_model()
    reports = []
    for make in (lambda d: CCDMonitor(model, d, ELLIPSOIDS), lambda d: GuardedStepper(model, d, ELLIPSOIDS)):
        data = mujoco.MjData(model)
        stepper = make(data)
        behind_the_wall(model, data)
        stepper.step()
        reports.append(stepper.last_report)
    monitor_report, guard_report = reports
    assert monitor_report.unstable and guard_report.unstable
    assert monitor_report.first is None and guard_report.clamps == ()


def test_autoreset_off_nan_state_is_unstable_not_an_internal_error():
    model = wall_model(autoreset=False)
    data = mujoco.MjData(model)
    monitor = CCDMonitor(model, data, ELLIPSOIDS)
    data.qfrc_applied[0] = np.nan
    for _ in range(3):
        assert monitor.step() is None
        assert monitor.last_report.unstable
    assert np.isnan(data.qpos[0])


def test_a_nan_mocap_pose_is_named_in_the_users_terms():
    # without contacts MuJoCo never looks at a mocap pose: the NaN reaches the check
    model = mujoco.MjModel.from_xml_string("""
<mujoco>
  <option gravity="0 0 0"><flag contact="disable"/></option>
  <worldbody>
    <body name="hand" mocap="true"><geom type="sphere" size="0.1"/></body>
    <body name="ball" pos="1 0 0"><freejoint/><geom type="sphere" size="0.1"/></body>
  </worldbody>
</mujoco>""")
    ellipsoids = EllipsoidSet(bodies=("hand", "ball"), radii=[[0.1] * 3] * 2, positions=np.zeros((2, 3)),
                              quaternions=[[1, 0, 0, 0]] * 2)
    data = mujoco.MjData(model)
    monitor = CCDMonitor(model, data, ellipsoids, pairs=[("hand", "ball")])
    monitor.step()
    data.mocap_pos[0, 1] = np.nan
    with pytest.raises(InputError, match=r"^data before step 1 of 2: mocap_pos\[1\] is NaN or infinite$"):
        monitor.step(2)


def _gym_env(tmp_path, frame_skip=2):
    pytest.importorskip("gymnasium.envs.mujoco")
    from gymnasium import spaces
    from gymnasium.envs.mujoco import MujocoEnv

    path = tmp_path / "wall.xml"
    path.write_text(WALL)

    class Wall(MujocoEnv):
        metadata = {"render_modes": ["human", "rgb_array", "depth_array"]}

        def __init__(self):
            super().__init__(str(path), frame_skip, spaces.Box(-np.inf, np.inf, (7,), np.float64))

        def step(self, action):
            self.do_simulation(action, self.frame_skip)
            return self.data.qpos.copy(), 0.0, False, False, {}

        def reset_model(self):
            behind_the_wall(self.model, self.data)
            return self.data.qpos.copy()

    return Wall()


def test_gymnasium_wrapper_reports_a_reset_unstable(tmp_path):
    from mjccd.mujoco.gym import CCDGymWrapper

    env = CCDGymWrapper(_gym_env(tmp_path), ELLIPSOIDS)
    env.reset(seed=0)
    _, _, _, _, info = env.step(np.zeros(0))
    assert info["ccd"]["unstable"] and env.last_unstable
    assert info["ccd"]["contacts"] == [] and np.isinf(info["ccd"]["contact_time"])
    assert [r.unstable for r in info["ccd"]["reports"]] == [True, False]


def test_gymnasium_wrapper_refuses_a_fractional_frame_count(tmp_path):
    from mjccd.mujoco.gym import CCDGymWrapper

    env = CCDGymWrapper(_gym_env(tmp_path, frame_skip=2.7), ELLIPSOIDS)
    env.reset(seed=0)
    with pytest.raises(InputTypeError, match="n_frames: expected an integer >= 1, got 2.7"):
        env.step(np.zeros(0))


def _dm_env():
    from dm_control import mujoco as dm_mujoco
    from dm_control.rl import control
    from dm_control.suite import base

    class Behind(base.Task):
        def initialize_episode(self, physics):
            behind_the_wall(physics.model.ptr, physics.data.ptr)

        def get_observation(self, physics):
            return {"x": physics.data.qpos[:3].copy()}

        def get_reward(self, physics):
            return 0.0

    physics = dm_mujoco.Physics.from_xml_string(WALL)
    return control.Environment(physics, Behind(random=0), control_timestep=0.01, time_limit=1.0)


@pytest.mark.dm_control
def test_dm_control_wrappers_report_a_reset_unstable_alike():
    from mjccd.dm_control import CCDWrapper
    from mjccd.mujoco import GuardedWrapper

    unstable = []
    for wrap in (CCDWrapper, GuardedWrapper):
        env = _dm_env()
        wrapped = wrap(env, ELLIPSOIDS)
        wrapped.reset()
        with env.physics.suppress_physics_errors():  # as dm-control, a bad state is a PhysicsError otherwise
            ts = wrapped.step(np.zeros(0))
        unstable.append([r.unstable for r in wrapped.last_reports])
        assert wrapped.last_unstable
        if wrap is CCDWrapper:
            assert wrapped.last_contacts == []
            assert np.isinf(ts.observation["ccd/contact_time"])
    assert unstable == [[True, False]] * 2



def test_dm_control_wrappers_name_the_versions_where_dm_control_does_not_work(monkeypatch):
    """On MuJoCo 4 (dm-control 1.0.50 cannot build a physics there) the wrappers refuse, naming the versions."""
    from mjccd.dm_control import CCDWrapper, DmControlUnavailableError
    from mjccd.mujoco import GuardedWrapper, wrappers

    problem = wrappers.dm_control_problem()
    if problem is None:  # dm-control works with this MuJoCo: pretend it does not
        problem = f"dm-control 0.0 does not work with MuJoCo {mujoco.__version__} (AttributeError: x)"
        monkeypatch.setattr(wrappers, "dm_control_problem", lambda: problem)
    assert f"MuJoCo {mujoco.__version__}" in problem and "dm-control" in problem
    for wrap in (CCDWrapper, GuardedWrapper):
        with pytest.raises(DmControlUnavailableError) as info:
            wrap(object())
        message = str(info.value)
        assert message.startswith(f"{wrap.__name__} needs dm-control, but {problem}")
        assert "mujoco>=3.17,<4" in message and "CCDMonitor" in message


# ------------------------------------------------------------ arguments checked alike


@pytest.mark.parametrize("nstep,error", [(-3, InputError), (0, InputError), (2.7, InputTypeError),
                                         ("3", InputTypeError), (True, InputTypeError), (None, InputTypeError)])
def test_nstep_is_checked_alike(nstep, error):
    model = wall_model()
    messages = []
    for stepper in (CCDMonitor(model, mujoco.MjData(model), ELLIPSOIDS),
                    GuardedStepper(model, mujoco.MjData(model), ELLIPSOIDS)):
        with pytest.raises(error, match="^nstep: expected an integer >= 1") as info:
            stepper.step(nstep)
        assert stepper.data.time == 0.0
        messages.append(str(info.value))
    assert messages[0] == messages[1]


@pytest.mark.parametrize("name", ["all_pairs", "report_overlapping"])
def test_flags_are_true_or_false(name):
    model = wall_model()
    with pytest.raises(InputTypeError, match=f"^{name}: expected True or False, got 'no'"):
        CCDMonitor(model, mujoco.MjData(model), ELLIPSOIDS, **{name: "no"})


@pytest.mark.parametrize("name,value,error", [
    ("max_rechecks", "3", InputTypeError), ("max_rechecks", 2.5, InputTypeError), ("overshoot", "0.1", InputTypeError),
    ("contact_step", True, InputTypeError), ("max_penetration", -0.1, InputError)])
def test_guard_thresholds_refused_by_kind(name, value, error):
    model = wall_model()
    with pytest.raises(error, match=f"^{name}: expected a finite"):
        GuardedStepper(model, mujoco.MjData(model), ELLIPSOIDS, **{name: value})


def test_data_of_another_model_is_refused():
    model = wall_model()
    other = mujoco.MjModel.from_xml_string("<mujoco><worldbody><body><joint/><geom size='1'/></body>"
                                           "</worldbody></mujoco>")
    with pytest.raises(InputError, match=r"^data: made for another model"):
        CCDMonitor(model, mujoco.MjData(other), ELLIPSOIDS)


def test_unknown_pair_names_list_the_bodies_with_ellipsoids():
    model = wall_model()
    data = mujoco.MjData(model)
    for make in (CCDMonitor, GuardedStepper):
        with pytest.raises(InputError, match=r"pairs\[0\]\[1\]: the model has no body named 'nope'; "
                                             r"bodies with ellipsoids: 'wall', 'ball'$"):
            make(model, data, ELLIPSOIDS, pairs=[("ball", "nope")])
    with pytest.raises(InputError, match=r"'ball_geom' is a geom of body 'ball'"):
        CCDMonitor(model, data, ELLIPSOIDS, pairs=[("wall", "ball_geom")])
    with pytest.raises(InputError, match=r"pairs\[0\]\[0\]: expected a body name or id, got True"):
        CCDMonitor(model, data, ELLIPSOIDS, pairs=[(True, "ball")])


def test_scene_refuses_pairs_of_names():
    with pytest.raises(InputError, match=r"^pairs: expected ellipsoid indices in 0\.\.1, got \['ball', 'nope'\]"):
        Scene(np.ones((2, 3)), pairs=[("ball", "nope")])


def test_missing_or_broken_ellipsoid_file_names_the_file(tmp_path):
    missing = tmp_path / "none.json"
    with pytest.raises(InputError, match=f"^{re.escape(str(missing))}: no such ellipsoid file$"):
        load_ellipsoids(missing)
    broken = tmp_path / "broken.npz"
    broken.write_bytes(b"not a zip")
    with pytest.raises(InputError, match=f"^{re.escape(str(broken))}: not a readable .npz file"):
        load_ellipsoids(broken)
    bad = tmp_path / "bad.json"
    bad.write_text('{"ellipsoids": [{"body": "a"}]}')
    with pytest.raises(InputError, match=rf"^{re.escape(str(bad))}: ellipsoids\[0\].radii: missing$"):
        load_ellipsoids(bad)
    folder = tmp_path / "set.json"
    folder.mkdir()
    with pytest.raises(InputError, match=f"^{re.escape(str(folder))}: is a folder"):
        EllipsoidSet.load(folder)


def test_interpolation_time_lies_in_the_step():
    model = wall_model()
    with pytest.raises(InputError, match=r"^t: must lie in \[0, 1\], got 2.0"):
        interpolate_qpos(model, model.qpos0, model.qpos0, 2.0)


def test_testing_helpers_name_a_missing_model_file(tmp_path):
    from mjccd.testing import load_model

    with pytest.raises(InputError, match=r"none\.xml: model file not found$"):
        load_model(tmp_path / "none.xml")


# ------------------------------------------------------------ a quaternion is a direction


def test_scene_takes_a_huge_quaternion_as_its_direction():
    # a long ellipsoid turned 90 degrees about z reaches the small one at y = 1.5; unturned it does not
    radii = [[2.0, 0.1, 0.1], [0.1, 0.1, 0.1]]
    turned = np.array([[0, 0, 0, 1, 0, 0, 1], [0, 1.5, 0, 1, 0, 0, 0]], float)
    huge = turned.copy()
    huge[0, 3:] = [1e300, 0, 0, 1e300]
    unturned = turned.copy()
    unturned[0, 3:] = [1, 0, 0, 0]
    assert Scene(radii).step(unturned, unturned).first is None
    expected = Scene(radii).step(turned, turned).first
    assert expected is not None and expected.time == 0.0
    for poses in (huge, huge.tolist()):  # the compiled fast path and the checked path
        found = Scene(radii).step(poses, poses).first
        assert found is not None and found.time == expected.time
    run = Scene(radii).run(np.stack([huge, huge]))
    assert run.pair[0] == 0 and run.time[0] == 0.0


ZERO_QUAT = """
<mujoco>
  <worldbody>
    <geom name="floor" type="plane" size="5 5 0.1"/>
    <body name="free" pos="0 0 0.5"><freejoint/><geom type="sphere" size="0.1"/></body>
    <body name="arm" pos="0.5 0 0.5"><joint name="shoulder" type="ball"/><geom type="capsule" size="0.05 0.2"/></body>
  </worldbody>
</mujoco>
"""


@pytest.mark.parametrize("motion, mode", [("rigid", "geoms"), ("rigid", "ellipsoids"), ("affine", "ellipsoids"),
                                          ("chain", "ellipsoids")])
def test_a_zero_quaternion_is_a_bad_state_in_every_motion(motion, mode):
    """A zero joint quaternion (no rotation) in a state given to check is an InputError naming the qpos entries
    and the joint; a step from such a state is reported unstable and not checked; never a ZeroDivisionError
    (the chain motion divides by the quaternions' norms)."""
    model = mujoco.MjModel.from_xml_string(ZERO_QUAT)
    data = mujoco.MjData(model)
    monitor = CCDMonitor(model, data, fit_model(model), motion=motion, mode=mode)
    monitor.step()
    for adr, who in ((3, "joint #0 of body 'free'"), (7, "joint 'shoulder' of body 'arm'")):
        bad = data.qpos.copy()
        bad[adr:adr + 4] = 0.0
        with pytest.raises(InputError, match=re.escape(f"state_t1: qpos[{adr}:{adr + 4}] is a zero quaternion "
                                                       f"({who})")):
            monitor.check(data.qpos.copy(), bad)
        data.qpos[adr:adr + 4] = 0.0
        assert monitor.step() is None and monitor.last_report.unstable
        data.qpos[adr:adr + 4] = [1.0, 0.0, 0.0, 0.0]  # a sound state again: checked again
        monitor.step()
        assert not monitor.last_report.unstable
