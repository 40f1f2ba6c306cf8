"""Shared objects across threads: a Scene, a BatchScene or a CCDMonitor entered by a second thread while the first
is inside refuses at once (ConcurrentUseError naming it), never answers wrongly; separate objects run in parallel,
and a GeomChecker (per-thread workspaces) is shared safely.

The refusal tests hold the first thread inside deterministically: its pose input is an object whose conversion to
an array (done inside the call) waits until the second thread has tried."""
import threading

import mujoco
import numpy as np
import pytest

from mjccd.batch import BatchScene
from mjccd.errors import ConcurrentUseError
from mjccd.mujoco import CCDMonitor, fit_model
from mjccd.mujoco.geoms import GeomChecker
from mjccd.mujoco.motions import capture
from mjccd.scene import Scene

RADII = [[0.3, 0.2, 0.1], [0.25, 0.25, 0.15]]
START = np.array([[0.0, 0, 0, 1, 0, 0, 0], [2.0, 0, 0, 1, 0, 0, 0]])
END = np.array([[0.0, 0, 0, 1, 0, 0, 0], [0.0, 0.1, 0, 1, 0, 0, 0]])

BALLS = """
<mujoco>
  <worldbody>
    <geom name="floor" type="plane" size="5 5 0.1"/>
    <body name="a" pos="0 0 0.5"><freejoint/><geom type="sphere" size="0.1"/></body>
    <body name="b" pos="0.5 0 0.5"><freejoint/><geom type="capsule" size="0.05 0.2"/></body>
  </worldbody>
</mujoco>
"""


class _Held:
    """Poses whose conversion to an array (inside the call) signals ``inside`` and waits for ``go``."""

    def __init__(self, poses):
        self.poses, self.inside, self.go = poses, threading.Event(), threading.Event()

    def __array__(self, dtype=None, copy=None):
        self.inside.set()
        assert self.go.wait(10.0)
        return self.poses if dtype is None else self.poses.astype(dtype)


def _refused_while_held(call_held, call_other, poses=START):
    """Run ``call_held`` (given held ``poses``) in a thread until it is inside, then ``call_other`` here: it must
    raise; the held call then finishes; returns its answer."""
    held = _Held(poses.copy())
    answer = {}
    worker = threading.Thread(target=lambda: answer.setdefault("value", call_held(held)))
    worker.start()
    assert held.inside.wait(10.0)
    try:
        with pytest.raises(ConcurrentUseError, match="two threads"):
            call_other()
    finally:
        held.go.set()
        worker.join(300.0)
    return answer["value"]


def test_a_scene_refuses_a_second_thread_and_the_first_is_answered_rightly():
    scene = Scene(RADII)
    expected = Scene(RADII).first_contact(START, END)  # compiled before the threads meet
    got = _refused_while_held(lambda held: scene.first_contact(held, END), lambda: scene.step(START, END))
    assert got.time == expected.time and got.pair == expected.pair
    assert scene.first_contact(START, END).time == expected.time  # usable again afterwards


def test_a_batch_scene_refuses_a_second_thread():
    batch = BatchScene(RADII, 2)
    both = np.stack([START, START])
    ends = np.stack([END, END])
    expected = batch.first_contacts(both, ends).time  # compiled before the threads meet
    got = _refused_while_held(lambda held: batch.first_contacts(held, ends), lambda: batch.first_contacts(both, ends),
                              both)
    np.testing.assert_array_equal(got.time, expected)


@pytest.mark.parametrize("mode", ["geoms", "ellipsoids"])
def test_a_monitor_refuses_a_second_thread(mode):
    model = mujoco.MjModel.from_xml_string(BALLS)
    data = mujoco.MjData(model)
    monitor = CCDMonitor(model, data, fit_model(model), mode=mode)
    monitor.step()  # compiled before the threads meet
    inside, go = threading.Event(), threading.Event()

    def held_step():
        inside.set()
        assert go.wait(10.0)
        mujoco.mj_step(model, data)

    worker = threading.Thread(target=lambda: monitor.advance_checked(held_step))
    worker.start()
    assert inside.wait(10.0)
    try:
        with pytest.raises(ConcurrentUseError, match="CCDMonitor"):
            monitor.check(data.qpos.copy(), data.qpos.copy())
    finally:
        go.set()
        worker.join(300.0)
    assert monitor.last_report is not None


def test_two_threads_hammering_one_scene_get_right_answers_or_a_refusal():
    """1,000 calls from each of two threads released together by a barrier: each call either gives the
    single-threaded answer or raises ConcurrentUseError; never a wrong time, pair or a time of -1."""
    scene = Scene(RADII)
    expected = Scene(RADII).first_contact(START, END)
    barrier = threading.Barrier(2)
    outcomes = [[0, 0, 0], [0, 0, 0]]  # right, refused, wrong

    def hammer(k):
        barrier.wait()
        for _ in range(1000):
            try:
                c = scene.first_contact(START, END)
            except ConcurrentUseError:
                outcomes[k][1] += 1
                continue
            outcomes[k][0 if (c.time, c.pair) == (expected.time, expected.pair) else 2] += 1

    threads = [threading.Thread(target=hammer, args=(k,)) for k in range(2)]
    for t in threads:
        t.start()
    for t in threads:
        t.join(60.0)
    assert outcomes[0][2] == outcomes[1][2] == 0, outcomes
    assert sum(o[0] + o[1] for o in outcomes) == 2000


def test_separate_scenes_and_one_geom_checker_work_from_many_threads():
    model = mujoco.MjModel.from_xml_string(BALLS)
    checker = GeomChecker(model)
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    q0 = checker.geom_poses(capture(data))
    data.qpos[2] = -0.2  # the ball falls through the floor's plane during the step
    q1 = checker.geom_poses(capture(data))
    expected = checker.check_poses(0.0, 1.0, q0, q1).first
    barrier = threading.Barrier(4)
    answers = []

    def work():
        scene = Scene(RADII)
        barrier.wait()
        for _ in range(50):
            c = checker.check_poses(0.0, 1.0, q0, q1).first
            s = scene.first_contact(START, END)
            answers.append((c.time, c.pair, s.time))

    threads = [threading.Thread(target=work) for _ in range(4)]
    for t in threads:
        t.start()
    for t in threads:
        t.join(60.0)
    reference = Scene(RADII).first_contact(START, END).time
    assert len(answers) == 200 and set(answers) == {(expected.time, expected.pair, reference)}
