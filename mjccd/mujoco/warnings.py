"""MuJoCo's warning texts, kept out of the working folder.

Left alone, MuJoCo prints a warning and appends it to ``MUJOCO_LOG.TXT`` in
the current folder; a command must neither litter nor lose it.
"""
from contextlib import contextmanager

import mujoco


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
