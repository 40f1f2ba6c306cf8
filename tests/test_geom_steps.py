"""The monitor's lean step check in geoms mode (mjccd.mujoco.geom_steps) answers as GeomChecker.check_poses does."""
import mujoco
import numpy as np
import pytest

from mjccd.mujoco import CCDMonitor, fit_model
from mjccd.mujoco.motions import capture

SCENE = """
<mujoco>
  <option timestep="0.004"/>
  <worldbody>
    <geom name="floor" type="plane" size="5 5 0.1"/>
    <body name="mocap" mocap="true" pos="0 0 0.6"><geom type="box" size="0.3 0.3 0.02"/></body>
    {bodies}
  </worldbody>
</mujoco>
"""
SHAPES = ['type="box" size="0.1 0.15 0.05"', 'type="capsule" size="0.05 0.15"', 'type="cylinder" size="0.1 0.05"',
          'type="sphere" size="0.08"', 'type="ellipsoid" size="0.12 0.06 0.09"']


def _model(seed):
    rng = np.random.default_rng(seed)
    bodies = "".join(f'<body name="b{k}" pos="{rng.uniform(-0.3, 0.3):.3f} {rng.uniform(-0.3, 0.3):.3f} '
                     f'{rng.uniform(0.1, 0.5):.3f}"><freejoint/><geom {s}/></body>' for k, s in enumerate(SHAPES))
    return mujoco.MjModel.from_xml_string(SCENE.format(bodies=bodies))


def _fields(c):
    if c is None:
        return None
    return (c.time, c.fraction, c.bodies, c.geoms, c.status_at_start, c.certainty, c.bracket, c.elements,
            None if c.point is None else c.point.tolist(), None if c.normal is None else c.normal.tolist())


@pytest.mark.parametrize("seed, report_overlapping", [(0, True), (1, False), (2, True)])
def test_each_step_answers_as_the_checker_does_on_the_same_states(seed, report_overlapping):
    """Bodies of every shape thrown about under a moving mocap plate, over a floor (resting, new contacts, spheres
    and ellipsoids the ellipsoid solver finishes): each monitored step's first contact and counters are
    GeomChecker.check's on the step's two states, field for field."""
    model = _model(seed)
    data = mujoco.MjData(model)
    rng = np.random.default_rng(seed)
    data.qvel[:] = rng.normal(0.0, 2.0, model.nv)
    monitor = CCDMonitor(model, data, fit_model(model), report_overlapping=report_overlapping)
    checker = monitor.geoms
    statuses = set()
    for k in range(300):
        if k % 40 == 0:  # the mocap plate jumps: a start state the monitor has not seen
            data.mocap_pos[0] = rng.uniform(-0.2, 0.2, 3) + [0.0, 0.0, 0.5]
        s0 = capture(data)
        first = monitor.step()
        s1 = capture(data)
        expected = checker.check(s0, s1, new_only=not report_overlapping)
        assert _fields(first) == _fields(expected.first), k
        assert dict(monitor.last_report.counters) == dict(expected.counters), k
        assert monitor.last_report.pairs_uncertain == expected.pairs_uncertain
        if first is not None:
            statuses.add(first.status_at_start)
    assert ("overlapping" if report_overlapping else "separate") in statuses, statuses


def test_a_zero_quaternion_set_between_steps_is_a_bad_state_not_a_crash():
    """A free joint's quaternion zeroed by the user between steps: the step is taken, reported unstable, and the
    next sound step is checked again."""
    model = _model(3)
    data = mujoco.MjData(model)
    monitor = CCDMonitor(model, data, fit_model(model))
    monitor.step()
    data.qpos[3:7] = 0.0
    monitor.step()
    assert monitor.last_report.unstable
    data.qpos[3:7] = [1.0, 0.0, 0.0, 0.0]
    mujoco.mj_forward(model, data)
    monitor.step()
    assert not monitor.last_report.unstable and monitor.last_report.pairs_checked == len(monitor.pairs)
