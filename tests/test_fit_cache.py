"""The fit cache: a second fit of the same model reads the first (in this process or another), bit for bit; any
change to what the fit reads, or to its options, fits again; a damaged entry or an unwritable folder costs only a
fit, and ``MJCCD_FIT_CACHE=off`` keeps nothing."""
import os
import subprocess
import sys

import mujoco
import numpy as np
import pytest

from mjccd.mujoco import ellipsoids as ellipsoids_module
from mjccd.mujoco import fit_cache, fit_model

XML = """<mujoco><worldbody>
  <body name="arm"><freejoint/><geom type="capsule" size="0.05 0.3"/>
    <geom type="box" size="0.1 0.1 0.02" pos="0 0 0.4"/></body>
  <body name="ball" pos="1 0 0"><freejoint/><geom type="sphere" size="0.1"/></body>
</worldbody></mujoco>"""


@pytest.fixture
def cache(tmp_path, monkeypatch):
    folder = tmp_path / "fits"
    monkeypatch.setenv("MJCCD_FIT_CACHE", str(folder))
    return folder


def _same(a, b):
    return (a.bodies == b.bodies and a.geoms == b.geoms and all(
        np.array_equal(getattr(a, k), getattr(b, k), equal_nan=True)
        for k in ("radii", "positions", "quaternions", "volume_ratios")))


def _no_fitting(monkeypatch):
    def refuse(*args):
        raise AssertionError("fitted instead of read from the cache")
    monkeypatch.setattr(ellipsoids_module, "_fit", refuse)


def test_a_second_fit_is_read_back_bit_for_bit(cache, monkeypatch):
    model = mujoco.MjModel.from_xml_string(XML)
    first = fit_model(model)
    assert len(list(cache.glob("*.npz"))) == 1 and len(first) > 2
    assert _same(first, fit_model(model, cache=False))  # a cached fit is what fitting gives
    _no_fitting(monkeypatch)
    assert _same(first, fit_model(model))
    assert _same(first, fit_model(mujoco.MjModel.from_xml_string(XML)))  # the same model compiled again


def test_another_process_reads_the_fit(cache):
    model = mujoco.MjModel.from_xml_string(XML)
    fit_model(model)
    code = ("import mujoco, sys; from mjccd.mujoco import ellipsoids as e, fit_model\n"
            "e._fit = lambda *a: sys.exit('fitted again')\n"
            f"print(len(fit_model(mujoco.MjModel.from_xml_string({XML!r}))))")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=dict(os.environ),
                          timeout=300)
    assert done.returncode == 0, done.stderr
    assert int(done.stdout) == len(fit_model(model))


def test_what_the_fit_reads_and_its_options_make_the_key():
    model = mujoco.MjModel.from_xml_string(XML)
    options = {"tolerance": 0.01, "per": "body", "include_visual": False, "max_ellipsoids": 64, "bodies": None}
    key = fit_cache.key(model, options)
    assert key == fit_cache.key(mujoco.MjModel.from_xml_string(XML), dict(options))
    assert key != fit_cache.key(model, dict(options, tolerance=0.02))
    assert key != fit_cache.key(model, dict(options, per="geom"))
    model.opt.timestep = 0.001  # not read by the fit
    model.body_mass[1] = 7.0
    assert fit_cache.key(model, options) == key
    for field, row in (("geom_size", 0), ("geom_pos", 1), ("geom_quat", 1), ("geom_type", 2), ("geom_contype", 0)):
        changed = mujoco.MjModel.from_xml_string(XML)
        getattr(changed, field)[row] += 1
        assert fit_cache.key(changed, options) != key, field


def test_a_changed_model_is_fitted_again(cache):
    model = mujoco.MjModel.from_xml_string(XML)
    before = fit_model(model)
    model.geom_size[0, 1] = 0.5  # a longer capsule
    after = fit_model(model)
    assert not _same(before, after) and _same(after, fit_model(model, cache=False))


def test_a_damaged_entry_is_fitted_again_and_replaced(cache):
    model = mujoco.MjModel.from_xml_string(XML)
    first = fit_model(model)
    (entry,) = cache.glob("*.npz")
    entry.write_bytes(b"not an npz")
    assert _same(first, fit_model(model))
    assert entry.read_bytes()[:2] == b"PK"  # a whole entry again


def test_off_or_unwritable_keeps_nothing_and_still_fits(tmp_path, monkeypatch):
    model = mujoco.MjModel.from_xml_string(XML)
    reference = fit_model(model, cache=False)
    monkeypatch.setenv("MJCCD_FIT_CACHE", "off")
    assert _same(reference, fit_model(model)) and fit_cache.folder() is None
    blocker = tmp_path / "a_file"
    blocker.write_text("")
    monkeypatch.setenv("MJCCD_FIT_CACHE", str(blocker / "fits"))  # cannot be made: under a file
    assert _same(reference, fit_model(model))
    assert blocker.is_file() and not list(tmp_path.glob("**/*.npz"))


def test_cache_false_neither_reads_nor_writes(cache):
    model = mujoco.MjModel.from_xml_string(XML)
    fit_model(model, cache=False)
    assert not cache.exists()
