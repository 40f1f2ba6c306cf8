"""mjccd: exact continuous collision detection for ellipsoid-bounded MuJoCo bodies."""
from mjccd import _cache  # noqa: F401  (first: the kernels' keyed cache before any kernel is defined; compile notice)
from mjccd.cases import solve_cases
from mjccd.ccd import Contact, collision_intervals, first_contact
from mjccd.motion import (Affine, Ball, Chain, Fixed, Free, Hinge, LinearAffine, Motion, Rational,
                          Rigid, Slide, Static)
from mjccd.plane import Plane, plane_collision_intervals, plane_first_contact, solve_plane
from mjccd.quadric import (Ellipsoid, SeparatingPlane, contact_point, separating_plane,
                           static_status, static_status_many)

__all__ = [
    "Affine", "Ball", "Chain", "Contact", "Ellipsoid", "Fixed", "Free", "Hinge", "LinearAffine",
    "Motion", "Rational", "Rigid", "SeparatingPlane", "Slide", "Static", "collision_intervals",
    "contact_point", "first_contact", "separating_plane", "solve_cases", "static_status",
    "static_status_many",
    "Plane", "plane_collision_intervals", "plane_first_contact", "solve_plane",
    "Scene", "FrameResult", "FrameCounters", "PairContact", "PlaneContact", "BatchScene", "BatchContacts",
    "scan",
]
__version__ = "0.1.0"

# many ellipsoids per frame, and many worlds: imported on first use, so that ``import mjccd`` stays quick
_LATER = {"Scene": "mjccd.scene", "FrameResult": "mjccd.scene", "FrameCounters": "mjccd.scene",
          "PairContact": "mjccd.scene", "PlaneContact": "mjccd.scene", "BatchScene": "mjccd.batch",
          "BatchContacts": "mjccd.batch", "scan": "mjccd.collection"}


def __getattr__(name):
    if name not in _LATER:
        raise AttributeError(f"module 'mjccd' has no attribute {name!r}")
    import importlib

    value = getattr(importlib.import_module(_LATER[name]), name)
    globals()[name] = value
    return value
