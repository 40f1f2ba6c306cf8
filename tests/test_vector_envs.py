"""Many environments at once: CCDGymWrapper in Gymnasium's AsyncVectorEnv, CCDWrapper pickled and built in a
spawn pool's workers (each subprocess loads the compiled kernels from numba's on-disk cache)."""
import multiprocessing
import pickle

import numpy as np
import pytest


def _plain(contacts):
    """The contacts of a step as plain values (StepContact compares by identity; a pool returns these)."""
    return [(c.time, c.body_ids, c.geoms, c.status_at_start, None if c.point is None else c.point.tolist(),
             None if c.normal is None else c.normal.tolist()) for c in contacts]


def _make_hopper():
    import gymnasium

    from mjccd.mujoco.gym import CCDGymWrapper

    return CCDGymWrapper(gymnasium.make("Hopper-v5"))


def test_async_vector_env_carries_the_contacts_in_info():
    gymnasium = pytest.importorskip("gymnasium")
    pytest.importorskip("gymnasium.envs.mujoco")
    # spawn: the factories go to fresh processes by cloudpickle, as on macOS and Windows (and Python 3.14's default)
    envs = gymnasium.vector.AsyncVectorEnv([_make_hopper] * 2, context="spawn")
    try:
        envs.reset(seed=0)
        envs.action_space.seed(0)
        ended = np.zeros(2, bool)
        hits = np.zeros(2, int)
        for _ in range(30):
            _, _, terminated, truncated, info = envs.step(envs.action_space.sample())
            # an environment that ended the step before is reset by this one (NEXT_STEP autoreset): no ccd entry
            np.testing.assert_array_equal(info["_ccd"], ~ended)
            ccd = info["ccd"]
            assert ccd["contact_time"].shape == (2,) and ccd["contact_pair"].shape == (2, 2)
            assert ccd["contacts"].shape == (2,) and ccd["unstable"].shape == (2,)
            for i in np.flatnonzero(info["_ccd"]):
                found = np.isfinite(ccd["contact_time"][i])
                assert found == bool(ccd["contacts"][i])
                if found:  # the first of the step's contacts, as the wrapper's own info gives it
                    assert tuple(ccd["contact_pair"][i]) == ccd["contacts"][i][0].body_ids
                    hits[i] += 1
            ended = terminated | truncated
        assert (hits > 0).all()  # the hopper's foot on the floor
    finally:
        envs.close()


def _dm_hopper(seed):
    from dm_control import suite

    from mjccd.dm_control import CCDWrapper

    return CCDWrapper(suite.load("hopper", "stand", task_kwargs={"random": seed}))


def _actions(env, seed, n):
    spec = env.action_spec()
    rng = np.random.default_rng(seed)
    return [rng.uniform(spec.minimum, spec.maximum) for _ in range(n)]


@pytest.mark.dm_control
def test_ccd_wrapper_pickles_and_steps_as_the_original():
    env = _dm_hopper(0)
    env.reset()
    actions = _actions(env, 0, 14)
    for action in actions[:4]:
        env.step(action)
    clone = pickle.loads(pickle.dumps(env))
    assert clone.physics is not env.physics
    assert clone.monitor.model is clone.physics.model.ptr and clone.monitor.data is clone.physics.data.ptr
    np.testing.assert_array_equal(clone.monitor.pairs, env.monitor.pairs)
    assert _plain(clone.last_contacts) == _plain(env.last_contacts)
    hits = 0
    for action in actions[4:]:
        mine, theirs = env.step(action), clone.step(action)
        for key, value in mine.observation.items():
            np.testing.assert_array_equal(theirs.observation[key], value, err_msg=key)
        assert _plain(clone.last_contacts) == _plain(env.last_contacts)
        hits += len(env.last_contacts) > 0
    np.testing.assert_array_equal(clone.physics.data.qpos, env.physics.data.qpos)
    assert hits > 0  # the hopper lands on the floor


def _rollout(seed):
    """Build a CCDWrapper here (a pool worker), step it 10 times; each step's contacts as plain values."""
    env = _dm_hopper(seed)
    env.reset()
    out = []
    for action in _actions(env, seed, 10):
        env.step(action)
        out.append(_plain(env.last_contacts))
    return out


@pytest.mark.dm_control
def test_ccd_wrapper_built_in_spawn_pool_workers():
    with multiprocessing.get_context("spawn").Pool(2) as pool:
        answers = pool.map(_rollout, [0, 1])
    assert answers == [_rollout(0), _rollout(1)]
    assert all(any(step) for step in answers)
