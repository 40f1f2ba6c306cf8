"""Wrapped with no arguments, dm-control's humanoid, cheetah, hopper, acrobot and humanoid_CMU report contacts
where MuJoCo's own geoms meet: every new MuJoCo contact is recalled, and at least 95 % of the first contacts have
the real geoms within 1 cm (by MuJoCo's ``mj_geomDistance``, independent of mjccd), under random controls."""
import warnings

import mujoco
import numpy as np
import pytest

from mjccd.bench import fidelity
from mjccd.mujoco import fit_model

pytestmark = pytest.mark.dm_control
STEPS = 1000


@pytest.mark.parametrize("name", ["humanoid", "cheetah", "hopper", "acrobot", "humanoid_CMU"])
def test_the_default_wrapper_recalls_every_contact_at_the_real_geoms(name):
    from mjccd.dm_control import CCDWrapper

    env, model, data, _ = fidelity.make_env(name, seed=1)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        wrapped = CCDWrapper(env)  # no arguments: what is checked is what the default gives
    mode = wrapped.monitor.mode
    default = fit_model(model)  # the default fit (1 cm), from the fit cache
    assert wrapped.ellipsoids.bodies == default.bodies and np.array_equal(wrapped.ellipsoids.radii, default.radii)
    start = mujoco.MjData(model)
    mujoco.mj_copyData(start, model, data)
    tally = fidelity.Tally()
    fidelity.check_run(model, start, wrapped.ellipsoids, mode, fidelity.random_controls(model, STEPS, 1), tally)
    assert tally.first_contacts > 0
    assert tally.new_contacts > 0 or name == "acrobot"  # MuJoCo's acrobot has contacts disabled: nothing to recall
    assert tally.recalled == tally.new_contacts, tally.missed
    assert tally.precise[1] >= 0.95 * tally.first_contacts, sorted(tally.gaps)[-5:]
