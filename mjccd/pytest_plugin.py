"""pytest fixtures for contact-time tests: load models and trajectories, fit ellipsoids once per model.

Enabled through the ``pytest11`` entry point; a test asks for ``mjccd_model``,
``mjccd_trajectory`` or ``mjccd_ellipsoids`` and gets a loader.  Relative
paths are resolved against the directory of the requesting test file.
"""
import os

import pytest

from mjccd.mujoco.ellipsoids import fit_model
from mjccd.testing import load_model, load_trajectory


def _resolve(request, path):
    path = os.fspath(path)
    if os.path.isabs(path) or path.lstrip().startswith("<"):
        return path
    return os.path.join(os.path.dirname(str(request.path)), path)


@pytest.fixture(scope="session")
def _mjccd_cache():
    return {}


@pytest.fixture
def mjccd_model(request, _mjccd_cache):
    """``load(path_or_xml) -> MjModel``, cached for the session."""
    def load(source):
        key = ("model", _resolve(request, source))
        if key not in _mjccd_cache:
            _mjccd_cache[key] = load_model(key[1])
        return _mjccd_cache[key]
    return load


@pytest.fixture
def mjccd_trajectory(request, mjccd_model):
    """``load(npz_path, model) -> (qpos (T, nq), times (T,))``; ``model`` may be a path too."""
    def load(path, model):
        return load_trajectory(_resolve(request, path), mjccd_model(model) if not hasattr(model, "nq") else model)
    return load


@pytest.fixture
def mjccd_ellipsoids(_mjccd_cache):
    """``fit(model, per="body") -> EllipsoidSet``, fitted once per model and mode."""
    def fit(model, per="body"):
        key = ("fit", id(model), per)
        if key not in _mjccd_cache:
            _mjccd_cache[key] = (model, fit_model(model, per=per))
        return _mjccd_cache[key][1]
    return fit
