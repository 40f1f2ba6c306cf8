"""First contacts of whole rollouts (mjccd.mujoco.rollout): the same answers as the adapter checking each step,
rollout by rollout; states of ``mujoco.rollout`` and their qpos agree; mocap poses from states and controls; bad
rollouts named."""
import pathlib
import subprocess
import sys

import mujoco
import mujoco.rollout
import numpy as np
import pytest

from mjccd.errors import InputError
from mjccd.mujoco import ModelAdapter, State, fit_model
from mjccd.mujoco.geoms import GeomChecker
from mjccd.mujoco.rollout import (FULLPHYSICS, RolloutChecker, adapter_for, checker_for, first_contacts,
                                   state_layout)

pytestmark = pytest.mark.mujoco
ROOT = pathlib.Path(__file__).resolve().parents[1]

# a floor, a hinged two-link arm, two free bodies and a mocap paddle, all colliding by MuJoCo's default rules
MODEL = """
<mujoco>
 <option timestep="0.01" gravity="0 0 -6"/>
 <worldbody>
  <geom name="floor" type="plane" size="3 3 0.1"/>
  <body name="upper" pos="0 0 0.6">
   <joint name="shoulder" type="hinge" axis="0 1 0" damping="0.05"/>
   <geom type="capsule" fromto="0 0 0 0.35 0 0" size="0.05"/>
   <body name="lower" pos="0.35 0 0">
    <joint name="elbow" type="hinge" axis="0 1 0" damping="0.05"/>
    <geom type="capsule" fromto="0 0 0 0.3 0 0" size="0.04"/>
   </body>
  </body>
  <body name="ball" pos="0.5 0.05 0.9"><freejoint/><geom type="sphere" size="0.08"/></body>
  <body name="box" pos="-0.3 0 0.4"><freejoint/><geom type="box" size="0.07 0.05 0.04"/></body>
  <body name="paddle" mocap="true" pos="0.3 0.4 0.5"><geom type="box" size="0.1 0.02 0.1"/></body>
 </worldbody>
 <actuator>
  <motor joint="shoulder" gear="8"/>
  <motor joint="elbow" gear="4"/>
 </actuator>
</mujoco>
"""
B, T = 10, 25
MOCAP = int(mujoco.mjtState.mjSTATE_MOCAP_POS) | int(mujoco.mjtState.mjSTATE_MOCAP_QUAT)
CTRL = int(mujoco.mjtState.mjSTATE_CTRL)


@pytest.fixture(scope="module")
def model():
    return mujoco.MjModel.from_xml_string(MODEL)


@pytest.fixture(scope="module")
def adapters(model):
    ellipsoids = fit_model(model, tolerance=None)  # one per body: the loose paddle reaches the balls
    return {motion: adapter_for(model, ellipsoids, motion=motion) for motion in ("rigid", "affine")}


def _starts(model, seed, nroll=B):
    """(nroll, nstate) FULLPHYSICS start states with random joint velocities."""
    data = mujoco.MjData(model)
    rng = np.random.default_rng(seed)
    out = np.empty((nroll, mujoco.mj_stateSize(model, FULLPHYSICS)))
    for b in range(nroll):
        data.qvel[:] = rng.normal(scale=2.0, size=model.nv)
        data.time = 0.25
        mujoco.mj_forward(model, data)
        mujoco.mj_getState(model, data, out[b], FULLPHYSICS)
    return data, out


def _rollouts(model, seed, nroll=B, nstep=T, control_spec=CTRL):
    """(initial state, states (nroll, nstep, nstate), controls) of random open-loop rollouts by mujoco.rollout."""
    data, state0 = _starts(model, seed, nroll)
    rng = np.random.default_rng(seed + 1)
    ncontrol = mujoco.mj_stateSize(model, control_spec)
    control = rng.normal(scale=1.5, size=(nroll, nstep, ncontrol))
    if control_spec & MOCAP:  # the paddle sweeps through the middle: positions then a unit quaternion
        layout, _ = state_layout(model, control_spec)
        sweep = np.linspace(0.0, 1.0, nstep)[None, :, None] * np.array([0.0, -0.8, 0.0])
        control[:, :, layout[int(mujoco.mjtState.mjSTATE_MOCAP_POS)]] = np.array([0.3, 0.4, 0.5]) + sweep
        quat = rng.normal(size=(nroll, nstep, 4))
        control[:, :, layout[int(mujoco.mjtState.mjSTATE_MOCAP_QUAT)]] = quat / np.linalg.norm(quat, axis=2,
                                                                                                keepdims=True)
    states, _ = mujoco.rollout.rollout(model, data, state0, control, control_spec=control_spec)
    return state0, states, control


def _reference(adapter, frames, new_only=False):
    """Each rollout's first contact by the adapter, step by step: (step, StepContact) or (-1, None).

    ``frames``: per rollout, a list of :class:`State` (times set); a step whose time does not advance ends the
    rollout, as MuJoCo's rollout repeats its last state after a warning.
    """
    out = []
    for states in frames:
        found = (-1, None)
        for f in range(len(states) - 1):
            s0, s1 = states[f], states[f + 1]
            if s1.time <= s0.time:
                break
            p0, p1 = adapter.poses(s0), adapter.kinematics.ellipsoid_poses(
                s1, adapter.body_ids, adapter.ellipsoids.positions, adapter.ellipsoids.quaternions)
            first = adapter.check_poses(s0.time, s1.time, p0, p1, new_only=new_only).first
            if first is not None:
                found = (f, first)
                break
        out.append(found)
    return out


def _frames_of(model, state0, states, mocap=None):
    """Per rollout, the :class:`State` frames: the start, then each row (mocap (nroll, nstep + 1, nmocap, 7) or
    the model's own mocap poses)."""
    layout, _ = state_layout(model, FULLPHYSICS)
    qs, ts = layout[int(mujoco.mjtState.mjSTATE_QPOS)], layout[int(mujoco.mjtState.mjSTATE_TIME)].start
    rows = np.concatenate([state0[:, None], states], axis=1)
    ref_pos, ref_quat = model.body_pos[model.body_mocapid >= 0], model.body_quat[model.body_mocapid >= 0]
    return [[State(r[qs].copy(), ref_pos if mocap is None else mocap[b, f, :, :3],
                   ref_quat if mocap is None else mocap[b, f, :, 3:], float(r[ts]))
             for f, r in enumerate(rows[b])] for b in range(len(rows))]


def _assert_same(result, reference, exact=True):
    tol = 0.0 if exact else 1e-12
    assert result.ok.all(), result.errors
    for b, (step, c) in enumerate(reference):
        assert result.step[b] == step, b
        if c is None:
            assert result.pair[b] == -1 and np.isnan(result.time[b]) and result.contact(b) is None
            continue
        mine = result.contact(b)
        assert result.pair[b] == c.pair == mine.pair
        assert tuple(result.ellipsoids[b]) == c.ellipsoids == mine.ellipsoids
        assert mine.bodies == c.bodies and mine.status_at_start == c.status_at_start
        assert abs(result.fraction[b] - c.fraction) <= tol and abs(result.time[b] - c.time) <= max(tol, 1e-12)
        assert abs(mine.time - c.time) <= max(tol, 1e-12)
        if c.point is None:
            assert mine.point is None and np.isnan(result.point[b]).all()
        else:
            assert np.abs(result.point[b] - c.point).max() <= tol and np.abs(result.normal[b] - c.normal).max() <= tol
        assert mine.certainty == c.certainty and result.uncertain[b] == (c.certainty == "uncertain")


@pytest.mark.parametrize("motion", ["rigid", "affine"])
def test_rollouts_match_the_adapter_step_by_step(model, adapters, motion):
    adapter = adapters[motion]
    assert len(adapter.pairs) and len(adapter.plane_pairs)  # ellipsoid pairs and the floor
    hits = 0
    for seed in (3, 11):
        state0, states, _ = _rollouts(model, seed)
        result = RolloutChecker(adapter).first_contacts(states, initial_state=state0)
        reference = _reference(adapter, _frames_of(model, state0, states))
        _assert_same(result, reference)
        hits += sum(step >= 0 for step, _ in reference)
        new = RolloutChecker(adapter).first_contacts(states, initial_state=state0, new_contacts_only=True)
        _assert_same(new, _reference(adapter, _frames_of(model, state0, states), new_only=True))
    assert 0 < hits < 2 * B  # some rollouts touch, some do not


def test_rollouts_are_independent(model, adapters):
    state0, states, _ = _rollouts(model, 5)
    checker = RolloutChecker(adapters["rigid"])
    whole = checker.first_contacts(states, initial_state=state0)
    order = np.random.default_rng(0).permutation(B)
    _, more, _ = _rollouts(model, 21, nroll=4)  # the same start states as _starts(model, 21, 4)
    mixed = np.concatenate([states[order], more])
    _, more0 = _starts(model, 21, 4)
    again = checker.first_contacts(mixed, initial_state=np.concatenate([state0[order], more0]))
    for name in ("step", "time", "fraction", "pair", "ellipsoids", "point", "normal", "uncertain", "time_hi"):
        np.testing.assert_array_equal(getattr(again, name)[:B], getattr(whole, name)[order], err_msg=name)
    alone = checker.first_contacts(states[order[:1]], initial_state=state0[order[0]])
    assert alone.step[0] == whole.step[order[0]] and (alone.time[0] == whole.time[order[0]]
                                                      or np.isnan(whole.time[order[0]]))


def test_states_and_their_qpos_give_the_same_contacts(model, adapters):
    adapter = adapters["rigid"]
    state0, states, _ = _rollouts(model, 7)
    layout, _ = state_layout(model, FULLPHYSICS)
    qs = layout[int(mujoco.mjtState.mjSTATE_QPOS)]
    from_states = first_contacts(adapter, states, initial_state=state0)
    from_qpos = first_contacts(adapter, qpos=states[:, :, qs], initial_state=state0[:, qs], start_time=state0[:, 0])
    assert from_states.colliding.any()
    for name in ("step", "pair", "ellipsoids", "fraction", "point", "normal", "uncertain"):
        np.testing.assert_array_equal(getattr(from_qpos, name), getattr(from_states, name), err_msg=name)
    np.testing.assert_allclose(from_qpos.time, from_states.time, rtol=0, atol=1e-12)
    # without an initial state the first row starts the first step: step f ends at row f + 1
    rows = first_contacts(adapter, qpos=states[:, :, qs], start_time=state0[0, 0] + model.opt.timestep)
    reference = _reference(adapter, [f[1:] for f in _frames_of(model, state0, states)])
    assert rows.step.tolist() == [step for step, _ in reference]


def test_a_model_and_its_ellipsoids_check_as_the_monitor_does(model, adapters):
    state0, states, _ = _rollouts(model, 3)
    by_model = first_contacts(model, states, initial_state=state0, ellipsoids=adapters["rigid"].ellipsoids,
                              mode="ellipsoids")
    by_adapter = first_contacts(adapters["rigid"], states, initial_state=state0)
    np.testing.assert_array_equal(by_model.step, by_adapter.step)
    np.testing.assert_array_equal(by_model.time, by_adapter.time)
    without_floor = first_contacts(model, states, initial_state=state0, ellipsoids=adapters["rigid"].ellipsoids,
                                   planes=False, mode="ellipsoids")
    assert not (without_floor.pair >= len(adapters["rigid"].pairs)).any()


def test_geoms_mode_is_the_default_and_checks_as_a_geoms_monitor_does(model):
    """A model alone is checked on its own geoms, each rollout's steps exactly as a geoms-mode checker checks
    them one by one; a floor contact is the capsule's or ball's own, not an ellipsoid's."""
    checker = checker_for(model, None)
    assert isinstance(checker, GeomChecker)
    hits = 0
    for seed in (3, 11):
        state0, states, _ = _rollouts(model, seed)
        result = first_contacts(model, states, initial_state=state0)
        assert (result.ellipsoids == -1).all() and result.ok.all()
        for b, frames in enumerate(_frames_of(model, state0, states)):
            step, ref = -1, None
            for f in range(len(frames) - 1):
                s0, s1 = frames[f], frames[f + 1]
                first = checker.check_poses(s0.time, s1.time, checker.geom_poses(s0), checker.geom_poses(s1)).first
                if first is not None:
                    step, ref = f, first
                    break
            assert result.step[b] == step, b
            if ref is None:
                assert result.contact(b) is None and (result.geoms[b] == -1).all()
                continue
            hits += 1
            mine = result.contact(b)
            assert (mine.time, mine.pair, mine.geoms, mine.elements) == (ref.time, ref.pair, ref.geoms, ref.elements)
            assert result.time[b] == ref.time and tuple(result.geoms[b]) == ref.geoms
            assert result.uncertain[b] == (ref.certainty == "uncertain")
            if ref.point is not None:
                np.testing.assert_array_equal(result.point[b], ref.point)
            assert result.describe(b).startswith(f"rollout {b}: ")
    assert 0 < hits < 2 * B
    with pytest.raises(InputError, match="mode"):
        first_contacts(checker, states, initial_state=state0, mode="geoms")


def test_mocap_poses_come_from_the_controls_or_the_states(model, adapters):
    adapter = adapters["rigid"]
    spec = CTRL | MOCAP
    state0, states, control = _rollouts(model, 13, control_spec=spec)
    layout, _ = state_layout(model, spec)
    mpos = control[:, :, layout[int(mujoco.mjtState.mjSTATE_MOCAP_POS)]]
    mquat = control[:, :, layout[int(mujoco.mjtState.mjSTATE_MOCAP_QUAT)]]
    mocap = np.concatenate([mpos, mquat], axis=2).reshape(B, T, 1, 7)
    mocap = np.concatenate([mocap[:, :1], mocap], axis=1)  # frame 0 takes control 0's poses
    reference = _reference(adapter, _frames_of(model, state0, states, mocap))
    paddle = adapter.ellipsoids.bodies.index("paddle")
    assert any(c is not None and paddle in c.ellipsoids for _, c in reference)
    result = first_contacts(adapter, states, initial_state=state0, control=control, control_spec=spec)
    _assert_same(result, reference)
    rows_only = first_contacts(adapter, states, control=control, control_spec=spec)  # row t after control t
    _assert_same(rows_only, _reference(adapter, [f[1:] for f in _frames_of(model, state0, states, mocap)]))
    # the same poses written into the states themselves (mjSTATE_MOCAP_POS | QUAT in the state layout)
    full = FULLPHYSICS | MOCAP
    flayout, size = state_layout(model, full)
    rows = np.zeros((B, T + 1, size))
    src, _ = state_layout(model, FULLPHYSICS)
    both = np.concatenate([state0[:, None], states], axis=1)
    for bit, where in src.items():
        rows[:, :, flayout[bit]] = both[:, :, where]
    rows[:, :, flayout[int(mujoco.mjtState.mjSTATE_MOCAP_POS)]] = mocap[:, :, 0, :3]
    rows[:, :, flayout[int(mujoco.mjtState.mjSTATE_MOCAP_QUAT)]] = mocap[:, :, 0, 3:]
    _assert_same(first_contacts(adapter, rows, state_spec=full), reference)
    # without the controls the paddle stays where the model puts it
    still = first_contacts(adapter, states, initial_state=state0)
    _assert_same(still, _reference(adapter, _frames_of(model, state0, states)))


def test_state_layout_is_mj_getState_s(model):
    data, _ = _starts(model, 1, 1)
    data.mocap_pos[:] = [[1.0, 2.0, 3.0]]
    for spec in (FULLPHYSICS, FULLPHYSICS | MOCAP, CTRL | MOCAP, int(mujoco.mjtState.mjSTATE_QPOS)):
        layout, size = state_layout(model, spec)
        assert size == mujoco.mj_stateSize(model, spec)
        state = np.empty(size)
        mujoco.mj_getState(model, data, state, spec)
        for bit, where in layout.items():
            part = np.empty(mujoco.mj_stateSize(model, bit))
            mujoco.mj_getState(model, data, part, bit)
            np.testing.assert_array_equal(state[where], part)


def test_a_stopped_rollout_is_checked_up_to_its_stop(model, adapters):
    adapter = adapters["rigid"]
    state0, states, _ = _rollouts(model, 3)
    reference = _reference(adapter, _frames_of(model, state0, states))
    late = max(range(B), key=lambda b: reference[b][0])
    stop = reference[late][0]
    assert stop > 2
    cut = states.copy()
    cut[late, stop - 1:] = state0[late]  # MuJoCo reset the data in step stop - 1 and repeats that state
    cut[late, stop - 1:, 0] = 0.0
    result = first_contacts(adapter, cut, initial_state=state0)
    assert result.stopped[late] == stop - 1 and result.step[late] == -1
    assert (np.delete(result.stopped, late) == -1).all()
    _assert_same(result, [r if b != late else (-1, None) for b, r in enumerate(reference)])


def test_threads_give_the_same_poses(model, adapters):
    state0, states, _ = _rollouts(model, 9)
    one = RolloutChecker(adapters["rigid"]).poses(states, initial_state=state0)
    two = RolloutChecker(adapters["rigid"], nthread=3).poses(states, initial_state=state0)
    np.testing.assert_array_equal(one, two)
    frames = _frames_of(model, state0, states)
    for b, f in ((0, 0), (4, 7), (B - 1, T)):
        np.testing.assert_array_equal(one[b, f], adapters["rigid"].poses(frames[b][f]))


def test_bad_rollouts_are_named_and_the_others_answered(model, adapters):
    adapter = adapters["rigid"]
    state0, states, _ = _rollouts(model, 3)
    layout, _ = state_layout(model, FULLPHYSICS)
    qs = layout[int(mujoco.mjtState.mjSTATE_QPOS)]
    good = first_contacts(adapter, states, initial_state=state0)
    bad = states.copy()
    bad[2, 6, qs.start + 4] = np.nan
    bad[5, 0, 0] = np.inf
    result = first_contacts(adapter, bad, initial_state=state0)
    assert result.errors == {2: "rollout 2: states[2, 6]: qpos[4] is NaN or infinite",
                             5: "rollout 5: states[5, 0]: time is NaN or infinite"}
    assert result.ok.tolist() == [b not in (2, 5) for b in range(B)]
    assert result.step[2] == result.step[5] == -1 and not result.free[2]
    keep = [b for b in range(B) if b not in (2, 5)]
    np.testing.assert_array_equal(result.step[keep], good.step[keep])
    np.testing.assert_array_equal(result.time[keep], good.time[keep])
    assert result.describe(2) == "rollout 2: not checked: rollout 2: states[2, 6]: qpos[4] is NaN or infinite"
    start = state0[:, qs].copy()
    start[3, 1] = np.nan
    by_qpos = first_contacts(adapter, qpos=states[:, :, qs], initial_state=start)
    assert by_qpos.errors == {3: "rollout 3: initial_state[3]: qpos[1] is NaN or infinite"}


@pytest.mark.parametrize("call, message", [
    (lambda a, s, s0: first_contacts(a, qpos=np.zeros((2, 3, 5))),
     "qpos: expected shape (B, T, 16) with nq = 16, got (2, 3, 5)"),
    (lambda a, s, s0: first_contacts(a, s[:, :, :-1], initial_state=s0),
     "states: expected shape (B, T, 31) with nstate = mj_stateSize(model, state_spec) = 31, got (10, 25, 30)"),
    (lambda a, s, s0: first_contacts(a, s, initial_state=s0[0, :-2]),
     "initial_state: expected shape (31,) or (10, 31) as one row of states, got (29,)"),
    (lambda a, s, s0: first_contacts(a),
     "states, qpos: give exactly one of them (the rows of each rollout)"),
    (lambda a, s, s0: first_contacts(a, s, state_spec=int(mujoco.mjtState.mjSTATE_TIME)),
     "state_spec: must include mjSTATE_QPOS, got 0x1"),
    (lambda a, s, s0: first_contacts(a, qpos=s[:, :, 1:17], dt=0.0),
     "dt: expected a finite number > 0, got 0.0"),
])
def test_wrong_shapes_are_refused_naming_the_argument(model, adapters, call, message):
    state0, states, _ = _rollouts(model, 3)
    with pytest.raises(InputError) as err:
        call(adapters["rigid"], states, state0)
    assert str(err.value) == message


def test_chain_adapters_are_refused(model, adapters):
    chain = ModelAdapter(model, adapters["rigid"].ellipsoids, adapters["rigid"].pairs, "chain")
    with pytest.raises(InputError, match="rigid or affine motion, the adapter's is 'chain'"):
        RolloutChecker(chain)


def test_the_planner_example_runs_short():
    proc = subprocess.run([sys.executable, str(ROOT / "examples" / "rollout_planner.py"), "--quick"],
                          capture_output=True, text=True, timeout=600, cwd=ROOT)
    assert proc.returncode == 0, proc.stderr
    out = proc.stdout
    assert "rollouts dropped as colliding" in out and "per rollout" in out
    assert "executed path: no contact" in out, out


def test_poses_that_come_out_bad_name_the_frame(model, adapters, monkeypatch):
    state0, states, _ = _rollouts(model, 3)
    checker = RolloutChecker(adapters["rigid"])
    kinematics = checker._kinematics

    def broken(kin, out):  # as if MuJoCo's kinematics overflowed in frame 4 of rollout 6 (row 3 of its states)
        kinematics(kin, out)
        out[6 * (T + 1) + 4, 2, 0] = np.inf

    monkeypatch.setattr(checker, "_kinematics", broken)
    result = checker.first_contacts(states, initial_state=state0)
    assert result.errors == {6: "rollout 6: states[6, 3]: ellipsoid 2 has a non-finite value"}
    assert result.ok.sum() == B - 1 and result.step[6] == -1


def test_the_benchmark_writes_only_its_section(tmp_path):
    page = tmp_path / "benchmarks.md"
    page.write_text("# Benchmarks\n\nbefore\n\n<!-- rollout: begin -->\nold table\n<!-- rollout: end -->\n\nafter\n")
    proc = subprocess.run([sys.executable, str(ROOT / "benchmarks" / "rollout" / "run.py"), "--rollouts", "3",
                           "--steps", "4", "--repeats", "1", "--markdown", str(page)],
                          capture_output=True, text=True, timeout=600, cwd=ROOT)
    assert proc.returncode == 0, proc.stderr
    text = page.read_text()
    assert text.startswith("# Benchmarks\n\nbefore\n\n<!-- rollout: begin -->\n## Checking MuJoCo rollouts")
    assert text.endswith("<!-- rollout: end -->\n\nafter\n") and "old table" not in text
    assert "| 3 | " in text
