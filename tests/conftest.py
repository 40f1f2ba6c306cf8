"""Markers of the suite and the dm-control check made once per session.

``dm_control`` marks a test that builds a dm-control environment.  dm-control 1.0.50 and older install
next to MuJoCo 4 (they declare ``mujoco>=3.17`` without a cap) but cannot build a physics there, so such
tests skip with the reason, naming both versions, wherever the import and a minimal use (a physics from
MJCF, stepped once) fail (``make test-mujoco4`` installs dm-control 1.0.52, which runs).  ``mujoco`` marks
the files that cover the MuJoCo layer (core, monitor, guard, replay, testing helpers): ``pytest -m mujoco``
runs them alone (``make test-mujoco4 PYTEST4="-m mujoco"``).
"""
import os
import shutil
import tempfile

import pytest

_FIT_CACHE = None  # the session's own fit cache folder (mjccd.mujoco.fit_cache), so that the user's is untouched

# The MuJoCo-facing subset (pytest -m mujoco): every test file that loads a MuJoCo model or calls MuJoCo
# (add a new one here), and examples/ (this hook sees the whole session's items).  The files left out
# (solver, quadrics, patches, filters, fitting kernels, JSON cases, the command line's fuzzing) never
# import mujoco, so a second MuJoCo would not change them; test_install.py (a wheel built and installed,
# every bench suite run from it: minutes) checks packaging, and the bench suites' MuJoCo parts run here
# through test_bench_monitor.py and test_bench_peers.py.
MUJOCO_FILES = {
    "test_mujoco.py", "test_mujoco_errors.py", "test_guard.py", "test_replay.py", "test_replay_files.py",
    "test_replay_stream.py", "test_chain_filters.py", "test_scene.py", "test_fit.py", "test_bvh.py",
    "test_bvh_fit_files.py", "test_tunneling_benchmark.py", "test_bench_monitor.py", "test_bench_peers.py",
    "test_adapter.py", "test_pairs.py", "test_bench_fidelity.py", "test_rollout.py", "test_geoms_mode.py",
    "test_fit_cache.py", "test_default_fidelity.py", "test_spool.py", "test_docs.py", "test_geom_steps.py", "test_settle.py",
    "test_scan.py", "test_vector_envs.py",
}


def pytest_configure(config):
    global _FIT_CACHE
    _FIT_CACHE = tempfile.mkdtemp(prefix="mjccd-test-fits-")
    os.environ["MJCCD_FIT_CACHE"] = _FIT_CACHE  # subprocesses of the tests inherit it
    config.addinivalue_line("markers", "dm_control: builds a dm-control environment; skipped where dm-control "
                                       "does not work with the installed MuJoCo (MuJoCo 4 with dm-control 1.0.50 "
                                       "or older)")
    config.addinivalue_line("markers", "mujoco: the MuJoCo-facing files (fit, monitor, guard, replay, scene, "
                                       "testing, examples), set in tests/conftest.py")


def pytest_unconfigure(config):
    if _FIT_CACHE is not None:
        shutil.rmtree(_FIT_CACHE, ignore_errors=True)


def pytest_collection_modifyitems(config, items):
    problem = None
    for item in items:
        if item.path.name in MUJOCO_FILES or item.path.parent.name == "examples":
            item.add_marker(pytest.mark.mujoco)
        if item.get_closest_marker("dm_control") is None:
            continue
        if problem is None:  # once per session, and only when a dm-control test was collected
            from mjccd.dm_control import dm_control_problem

            problem = dm_control_problem() or ""
        if problem:
            item.add_marker(pytest.mark.skip(reason=problem))
