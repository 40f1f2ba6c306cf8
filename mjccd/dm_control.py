"""dm-control integration: ``CCDWrapper`` adds the exact first contact of each control step to observations.

The wrappers need a dm-control that works with the installed MuJoCo (on MuJoCo 4, dm-control 1.0.52 or
later): ``dm_control_problem()`` says why not, and the wrappers raise ``DmControlUnavailableError`` naming
both versions.
"""
from mjccd.mujoco.wrappers import (OBSERVATION_KEYS, CCDWrapper, DmControlUnavailableError, dm_control_problem,
                                   observation_specs)

__all__ = ["CCDWrapper", "DmControlUnavailableError", "OBSERVATION_KEYS", "dm_control_problem",
           "observation_specs"]
