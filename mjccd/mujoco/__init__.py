"""MuJoCo integration: fitted ellipsoids on bodies, exact motions between steps, the step monitor."""
from mjccd.mujoco.ellipsoids import EllipsoidSet, body_label, load_ellipsoids
from mjccd.mujoco.monitor import (CCDMonitor, StepContact, StepReport, default_pairs, excluded_body_pairs,
                                  pairs_from_bodies)
from mjccd.mujoco.motions import (MOTIONS, Kinematics, State, capture, interpolate_qpos,
                                  motions_between)

__all__ = [
    "CCDMonitor", "EllipsoidSet", "Kinematics", "MOTIONS", "State", "StepContact", "StepReport",
    "body_label", "capture", "default_pairs", "excluded_body_pairs", "interpolate_qpos",
    "load_ellipsoids", "motions_between", "pairs_from_bodies",
]
