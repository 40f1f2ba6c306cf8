"""Uncertain contacts of the compiled scene: its undecided pairs settled by the core's exact tiers (mjccd.settle),
and an estimated point on whatever stays uncertain."""
import warnings

import numpy as np
import pytest

import mjccd
from mjccd.mujoco import CCDMonitor, fit_model
from mjccd.mujoco.motions import capture
from mjccd.settle import estimated_touch


@pytest.mark.dm_control
def test_the_scenes_undecided_pairs_are_settled_as_the_core_answers_them():
    """dm-control's humanoid with one ellipsoid per body under random controls: the compiled scene leaves some
    contacts uncertain (grazing limbs, limbs tangent within rounding at a step's start); the monitor reports each
    of those pairs as the core's first_contact answers it on the same motion, and no contact lacks a point
    unless it was already touching at the step's start."""
    from dm_control import suite

    env = suite.load("humanoid", "run", task_kwargs={"random": 0})
    env.reset()
    model, data = env.physics.model.ptr, env.physics.data.ptr
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        monitor = CCDMonitor(model, data, fit_model(model, tolerance=None), all_pairs=True, mode="ellipsoids")
    adapter = monitor.adapter
    rng = np.random.default_rng(0)
    scene_uncertain = settled = 0
    for step in range(150):
        data.ctrl[:] = rng.uniform(-1.0, 1.0, model.nu) if step % 5 == 0 else data.ctrl
        p0 = adapter.poses(capture(data)).copy()
        monitor.step()
        report = monitor.last_report
        assert not report.unstable
        p1 = adapter.poses(capture(data))
        frame = adapter.scene.step(p0, p1, all_pairs=True, resolve_uncertain=False)  # the kernel's own answers
        undecided = [c.pair for c in frame.contacts if c.bracket is not None]
        scene_uncertain += len(undecided)
        reported = {c.pair: c for c in report.contacts}
        for k in undecided:
            shape_a, motion_a, shape_b, motion_b = adapter.scene.pair_problem(k)
            alone = mjccd.first_contact(shape_a, motion_a, shape_b, motion_b)
            if alone is None:
                assert k not in reported
                continue
            c = reported[k]
            assert (c.fraction, c.status_at_start, c.certainty) == (alone.time, alone.status_at_start,
                                                                     alone.certainty)
            settled += alone.certainty == "certified"
        for c in report.contacts:
            assert c.point is not None or (c.certainty == "certified" and c.status_at_start != "separate"), c
    assert scene_uncertain >= 3 and settled >= 3, (scene_uncertain, settled)


def test_an_estimated_touch_of_two_tangent_spheres_is_their_touching_point():
    """Two unit spheres, the second sliding along x until tangent at t = 0.5: the estimate at 0.5 is the
    touching point (1, 0, 0) with the normal +x out of the first; against the floor z = 0 a sphere at height 2
    estimates its lowest point, the normal pointing down into the plane."""
    ball = mjccd.Ellipsoid([1.0, 1.0, 1.0])
    still = mjccd.Static([0.0, 0.0, 0.0], [1.0, 0.0, 0.0, 0.0])
    moving = mjccd.Rigid([3.0, 0.0, 0.0], [1.0, 0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [1.0, 0.0, 0.0, 0.0])
    point, normal = estimated_touch(ball, still, ball, moving, 0.5)
    np.testing.assert_allclose(point, [1.0, 0.0, 0.0], atol=1e-9)
    np.testing.assert_allclose(normal, [1.0, 0.0, 0.0], atol=1e-9)
    high = mjccd.Static([0.5, -0.25, 2.0], [1.0, 0.0, 0.0, 0.0])
    point, normal = estimated_touch(ball, high, mjccd.Plane([0.0, 0.0, 1.0], 0.0), None, 0.3)
    np.testing.assert_allclose(point, [0.5, -0.25, 1.0], atol=1e-12)
    np.testing.assert_allclose(normal, [0.0, 0.0, -1.0], atol=1e-12)
