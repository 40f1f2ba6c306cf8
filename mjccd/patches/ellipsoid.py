"""An ellipsoid as eight exact rational biquadratic patches, moved by a linear affine map.

The unit-sphere octant is the tensor product of two rational quarter circles (weights
1, 1/sqrt(2), 1): the u circle runs in the equator plane, the v circle from the equator
to the pole. Its 3 x 3 control points and positive weights give the octant exactly; the
eight sign choices give the sphere, scaling by the radii the ellipsoid. The poles are
degenerate corners (one patch edge collapses to a point), which is fine for the solver.

Under the ``linear_affine`` motion ``x = ((1 - t) M0 + t M1) [y; 1]`` every control
point moves on a straight line and the weights do not change, so the moving ellipsoid
is exactly a set of moving rational patches.
"""
import numpy as np

from mjccd.errors import InputError

from .primitives import Patch

_R = np.sqrt(0.5)
# quarter circle from (1, 0) to (0, 1): control points and weights
_ARC = np.array([[1.0, 0.0], [1.0, 1.0], [0.0, 1.0]])
_ARC_W = np.array([1.0, _R, 1.0])


def unit_octant():
    """(3, 3, 3) control points and (3, 3) weights of the octant x, y, z >= 0 of the unit sphere."""
    pts = np.empty((3, 3, 3))
    for i in range(3):
        for j in range(3):
            radial, height = _ARC[j]
            pts[i, j] = (_ARC[i, 0] * radial, _ARC[i, 1] * radial, height)
    return pts, np.outer(_ARC_W, _ARC_W)


def _affine(value, field):
    m = np.array(value, dtype=np.float64)
    if m.shape != (3, 4):
        raise InputError(f"`{field}`: expected a 3x4 matrix [L|v], got shape {m.shape}")
    if not np.all(np.isfinite(m)):
        raise InputError(f"`{field}`: contains NaN or infinity")
    return m


def ellipsoid_patches(radii, start, end=None):
    """Eight moving rational biquadratic patches that are exactly the ellipsoid's surface.

    Args:
        radii: (3,) positive semi-axes (a, b, c) in the ellipsoid's own frame.
        start: (3, 4) matrix [L|v] mapping the own frame to the world at t = 0.
        end: (3, 4) matrix at t = 1 (default: ``start``, a static ellipsoid).

    Returns:
        list of 8 :class:`Patch` of kind ``"quad"``, degree (2, 2).
    """
    r = np.array(radii, dtype=np.float64)
    if r.shape != (3,):
        raise InputError(f"`radii`: expected 3 values, got shape {r.shape}")
    if not np.all(np.isfinite(r)) or np.any(r <= 0.0):
        raise InputError(f"`radii`: must be finite and positive, got {r.tolist()}")
    m0 = _affine(start, "start")
    m1 = m0 if end is None else _affine(end, "end")
    pts, w = unit_octant()
    out = []
    for sx in (1.0, -1.0):
        for sy in (1.0, -1.0):
            for sz in (1.0, -1.0):
                local = pts * (np.array([sx, sy, sz]) * r)
                hom = np.concatenate([local, np.ones((3, 3, 1))], axis=2)
                out.append(Patch.quad(hom @ m0.T, hom @ m1.T, weights=w))
    return out
