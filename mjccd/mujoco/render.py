"""Offscreen pictures of a model with its bounding ellipsoids shown, or a clear line when OpenGL is missing.

Shared by ``mjccd replay`` (frames at first contacts) and ``mjccd fit --render`` (a fit at a glance).
"""
import sys
import warnings

import mujoco

from mjccd.mujoco.ellipsoids import BOUND_GROUP


def _reason(exc):
    """The first line of an exception's message, or its type when it has none."""
    text = str(exc).strip()
    return text.splitlines()[0] if text else type(exc).__name__


def open_renderer(model, height=480, width=640):
    """A ``mujoco.Renderer``, or None after one line on stderr saying rendering was skipped (no OpenGL).

    mujoco picks its OpenGL platform when imported: ``MUJOCO_GL`` must be set before that (the command line
    does it, :func:`mjccd.cli._choose_gl_backend`).
    """
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            return mujoco.Renderer(model, height, width)
    except Exception as exc:  # no usable OpenGL context on this machine
        print(f"rendering skipped: no OpenGL backend ({_reason(exc)}); set MUJOCO_GL=egl or osmesa",
              file=sys.stderr)
        return None


def scene_option(group=BOUND_GROUP):
    """Visual options that show geom group ``group`` (the bounding ellipsoids) beside the model's own."""
    opt = mujoco.MjvOption()
    opt.geomgroup[group] = 1
    return opt


def whole_model_camera(model, data, azimuth=135.0, elevation=-10.0):
    """A free camera framing every body of ``data`` (its subtree centre, at about the model's extent)."""
    cam = mujoco.MjvCamera()
    cam.lookat[:] = data.subtree_com[0]
    cam.distance = 1.1 * model.stat.extent
    cam.azimuth, cam.elevation = azimuth, elevation
    return cam
