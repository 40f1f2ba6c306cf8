"""Warnings of the MuJoCo layer: MuJoCo's own warning texts kept out of the working folder, and
:class:`CoverageWarning`, said when mjccd checks less than MuJoCo would collide.

Left alone, MuJoCo prints a warning and appends it to ``MUJOCO_LOG.TXT`` in
the current folder; a command must neither litter nor lose it.
"""
from contextlib import contextmanager

import mujoco


class CoverageWarning(UserWarning):
    """mjccd checks less than MuJoCo would collide: no pair at all (and why), or a geom it cannot check yet
    (a height field, an SDF, a plane that moves with a mocap body).

    Raised through :func:`warnings.warn`, so the usual filters apply, e.g.
    ``warnings.simplefilter("error", CoverageWarning)`` in a test, or ``"ignore"`` where it is expected.
    """


@contextmanager
def mujoco_warnings(handler=None):
    """Within the block, MuJoCo's warnings go to ``handler(text)``; yields the list of texts when no handler."""
    previous = mujoco.get_mju_user_warning()
    caught = []
    mujoco.set_mju_user_warning(handler or caught.append)
    try:
        yield caught
    finally:
        mujoco.set_mju_user_warning(previous)
