"""MuJoCo integration: fitted ellipsoids on bodies, exact motions between steps, the step monitor, guarded stepping."""
from mjccd.mujoco.ellipsoids import EllipsoidSet, body_label, fit_model, load_ellipsoids
from mjccd.mujoco.adapter import ModelAdapter, StepContact, StepReport, load_model, motions_between
from mjccd.mujoco.monitor import CCDMonitor
from mjccd.mujoco.pairs import (character_pairs, default_pairs, excluded_body_pairs, pairs_from_bodies, plane_pairs,
                                select_pairs, self_pairs, uncovered_geoms)
from mjccd.mujoco.motions import MOTIONS, Kinematics, State, capture, interpolate_qpos
from mjccd.mujoco.guard import GuardedStepper, GuardedWrapper, GuardReport, geom_ellipsoids

__all__ = [
    "CCDMonitor", "EllipsoidSet", "GuardReport", "GuardedStepper", "GuardedWrapper", "Kinematics", "MOTIONS",
    "ModelAdapter", "State", "StepContact", "StepReport", "body_label", "capture", "character_pairs",
    "default_pairs", "excluded_body_pairs", "fit_model", "geom_ellipsoids", "interpolate_qpos", "load_ellipsoids",
    "load_model", "motions_between", "pairs_from_bodies", "plane_pairs", "select_pairs", "self_pairs",
    "uncovered_geoms",
]
