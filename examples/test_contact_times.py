"""Contact times in your own pytest suite: two balls rolled at each other, checked exactly.

Run with ``pytest examples/test_contact_times.py``.  The fixtures come from
``mjccd.pytest_plugin`` (enabled automatically when mjccd is installed).
"""
import mujoco
import numpy as np
import pytest

from mjccd.testing import assert_first_contact, assert_intervals, assert_no_contact

BALLS = """
<mujoco>
  <option gravity="0 0 0" timestep="0.01"><flag contact="disable"/></option>
  <worldbody>
    <body name="red" pos="-1 0 0"><freejoint/><geom type="sphere" size="0.1"/></body>
    <body name="blue" pos="1 0 0"><freejoint/><geom type="sphere" size="0.15"/></body>
    <body name="far" pos="0 5 0"><freejoint/><geom type="box" size="0.1 0.1 0.1"/></body>
  </worldbody>
</mujoco>
"""


def rollout(model, steps=100, speed=2.0):
    """qpos of the balls flying at each other at ``speed`` m/s each."""
    data = mujoco.MjData(model)
    data.qvel[0], data.qvel[6] = speed, -speed
    rows = [data.qpos.copy()]
    for _ in range(steps):
        mujoco.mj_step(model, data)
        rows.append(data.qpos.copy())
    return np.array(rows)


def test_balls_meet_when_the_gap_closes(mjccd_model):
    model = mjccd_model(BALLS)
    qpos = rollout(model)
    gap = 2.0 - 0.1 - 0.15
    assert_first_contact(model, qpos, ("red", "blue"), gap / 4.0, tol=1e-9)


def test_they_overlap_until_they_pass(mjccd_model):
    model = mjccd_model(BALLS)
    qpos = rollout(model)
    # centres pass each other; contact lasts while |2 - 4 t| <= 0.25
    assert_intervals(model, qpos, ("red", "blue"), [(1.75 / 4, 2.25 / 4)], tol=1e-9)


def test_far_box_is_never_touched(mjccd_model):
    model = mjccd_model(BALLS)
    assert_no_contact(model, rollout(model), pairs=[("red", "far"), ("blue", "far")])


def test_a_wrong_expectation_fails_readably(mjccd_model):
    model = mjccd_model(BALLS)
    with pytest.raises(AssertionError, match=r"expected t = 0.4 s .* found t = 0.4375 s \('red'-'blue'"):
        assert_first_contact(model, rollout(model), ("red", "blue"), 0.4, tol=1e-6)
