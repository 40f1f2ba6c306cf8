"""dm-control integration: ``CCDWrapper`` adds the exact first contact of each control step to observations."""
from mjccd.mujoco.wrappers import OBSERVATION_KEYS, CCDWrapper, observation_specs

__all__ = ["CCDWrapper", "OBSERVATION_KEYS", "observation_specs"]
