"""mjccd: exact continuous collision detection for ellipsoid-bounded MuJoCo bodies."""
from mjccd import _cache  # noqa: F401  (first: numba's cache folder before numba loads; compile notice)
from mjccd.cases import solve_cases
from mjccd.ccd import Contact, collision_intervals, first_contact
from mjccd.motion import (Affine, Ball, Chain, Fixed, Free, Hinge, LinearAffine, Motion, Rational,
                          Rigid, Slide, Static)
from mjccd.plane import Plane, plane_collision_intervals, plane_first_contact, solve_plane
from mjccd.quadric import (Ellipsoid, SeparatingPlane, contact_point, separating_plane,
                           static_status, static_status_many)
from mjccd.scene import FrameCounters, FrameResult, PairContact, PlaneContact, Scene
from mjccd.batch import BatchContacts, BatchScene

__all__ = [
    "Affine", "Ball", "Chain", "Contact", "Ellipsoid", "Fixed", "Free", "Hinge", "LinearAffine",
    "Motion", "Rational", "Rigid", "SeparatingPlane", "Slide", "Static", "collision_intervals",
    "contact_point", "first_contact", "separating_plane", "solve_cases", "static_status",
    "static_status_many",
    "Plane", "plane_collision_intervals", "plane_first_contact", "solve_plane",
    "Scene", "FrameResult", "FrameCounters", "PairContact", "PlaneContact", "BatchScene", "BatchContacts",
]
__version__ = "0.1.0"
