"""Where and how two touching shapes touch: closest points, outward normals and element names (numba kernels).

At the first contact the winning system's witness is a point of both solids
(or, for a rounded shape, of its core at the sum of the radii from the other
solid).  These kernels turn it into the contact point on both surfaces and the
unit normal outward from the first shape, and name the element of each shape
that holds the point (face, edge, vertex, rim, ...), in each shape's own frame.
"""
import math

import numpy as np

from mjccd.geoms.poly import jit
from mjccd.geoms.systems import BOX, CAPSULE, CYLINDER, ELLIPSOID, PLANE, SPHERE

FACE, EDGE, VERTEX = 2, 1, 0
ELEMENT_NAMES = {  # (kind, code) -> name; codes from :func:`element`
    (SPHERE, 0): "surface", (ELLIPSOID, 0): "surface", (PLANE, 0): "plane",
    (CAPSULE, 0): "side", (CAPSULE, 1): "cap +z", (CAPSULE, 2): "cap -z",
    (CYLINDER, 0): "side", (CYLINDER, 1): "face +z", (CYLINDER, 2): "face -z", (CYLINDER, 3): "rim +z",
    (CYLINDER, 4): "rim -z",
}


@jit
def closest_point(kind, size, y, out):
    """out = the point of the shape (local frame) closest to the local point y (y itself when inside)."""
    if kind == SPHERE or kind == CAPSULE:
        c = 0.0
        if kind == CAPSULE:
            c = min(max(y[2], -size[1]), size[1])
        d0, d1, d2 = y[0], y[1], y[2] - c
        n = math.sqrt(d0 * d0 + d1 * d1 + d2 * d2)
        s = min(1.0, size[0] / n) if n > 0.0 else 0.0
        out[0], out[1], out[2] = s * d0, s * d1, c + s * d2
    elif kind == BOX:
        for i in range(3):
            out[i] = min(max(y[i], -size[i]), size[i])
    elif kind == CYLINDER:
        rho = math.sqrt(y[0] * y[0] + y[1] * y[1])
        s = min(1.0, size[0] / rho) if rho > 0.0 else 1.0
        out[0], out[1] = s * y[0], s * y[1]
        out[2] = min(max(y[2], -size[1]), size[1])
    elif kind == PLANE:
        out[0], out[1], out[2] = y[0], y[1], min(y[2], 0.0)
    else:
        for i in range(3):
            out[i] = y[i]


@jit
def element(kind, size, y, tol):
    """(code, quality, n (3,)) of the element of the shape holding its surface point y (local): quality
    FACE (n the outward unit normal), EDGE (n the edge's unit tangent) or VERTEX; code numbers the element
    (for a box: 1 + axis + 3 (sign < 0) for a face, 7 + ... see :func:`element_name`)."""
    n = np.zeros(3)
    if kind == SPHERE or kind == ELLIPSOID:
        for i in range(3):
            n[i] = y[i] / (size[i] * size[i]) if kind == ELLIPSOID else y[i]
        m = math.sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2])
        return 0, FACE, n / m if m > 0.0 else n
    if kind == PLANE:
        n[2] = 1.0
        return 0, FACE, n
    if kind == CAPSULE:
        c = min(max(y[2], -size[1]), size[1])
        n[0], n[1], n[2] = y[0], y[1], y[2] - c
        m = math.sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2])
        code = 0 if abs(c) < size[1] else (1 if c > 0.0 else 2)
        return code, FACE, n / m if m > 0.0 else n
    if kind == CYLINDER:
        r, h = size[0], size[1]
        rho = math.sqrt(y[0] * y[0] + y[1] * y[1])
        on_side = abs(rho - r) <= tol * r
        on_cap = abs(abs(y[2]) - h) <= tol * h
        if on_side and on_cap:
            if rho > 0.0:
                n[0], n[1] = -y[1] / rho, y[0] / rho
            return (3 if y[2] > 0.0 else 4), EDGE, n
        if on_cap or (rho < r and abs(y[2]) >= h):
            n[2] = 1.0 if y[2] > 0.0 else -1.0
            return (1 if y[2] > 0.0 else 2), FACE, n
        if rho > 0.0:
            n[0], n[1] = y[0] / rho, y[1] / rho
        return 0, FACE, n
    # box: which coordinates sit on their face
    on = 0
    count = 0
    free = -1
    for i in range(3):
        if abs(abs(y[i]) - size[i]) <= tol * max(size[i], 1e-300) or abs(y[i]) > size[i]:
            on |= 1 << i
            count += 1
        else:
            free = i
    if count == 1:
        for i in range(3):
            if on == 1 << i:
                n[i] = 1.0 if y[i] > 0.0 else -1.0
                return 1 + i + (3 if y[i] < 0.0 else 0), FACE, n
    signs = (1 if y[0] > 0.0 else 0) | (2 if y[1] > 0.0 else 0) | (4 if y[2] > 0.0 else 0)
    if count == 2:
        n[free] = 1.0
        return 7 + 8 * free + signs, EDGE, n
    return 31 + signs, VERTEX, n


def element_name(kind, code):
    """A readable name of an element code of :func:`element`."""
    if kind != BOX:
        return ELEMENT_NAMES.get((kind, code), "surface")
    axes = "xyz"
    if 1 <= code <= 6:
        i = (code - 1) % 3
        return f"face {'-' if code > 3 else '+'}{axes[i]}"
    if 7 <= code < 31:
        free, signs = divmod(code - 7, 8)
        corner = "".join(("+" if signs & (1 << i) else "-") + axes[i] for i in range(3) if i != free)
        return f"edge {corner} (along {axes[free]})"
    signs = code - 31
    return "vertex " + "".join(("+" if signs & (1 << i) else "-") + axes[i] for i in range(3))
