"""MuJoCo's primitive shapes, as the geom solvers take them (MuJoCo's conventions).

Each shape lives in its own frame, which a motion carries:

* :class:`Sphere` (radius), :class:`Capsule` and :class:`Cylinder` (radius and
  half-length, axis along local z), :class:`Box` (half sizes),
  :class:`Ellipsoid` (radii: :class:`mjccd.Ellipsoid` is the same shape) and
  :class:`HalfSpace`, MuJoCo's ``plane``: the solid half-space z <= 0 of its
  frame (static only).

``shape_from_json`` reads the ``"shape"`` object of the case format.
"""
from dataclasses import dataclass

import numpy as np

from mjccd import _validate
from mjccd.errors import InputError, InputTypeError
from mjccd.geoms import systems as sy
from mjccd.quadric import Ellipsoid


def _length(value, field):
    """One positive finite length within the supported range."""
    if isinstance(value, bool):
        raise InputError(f"{field}: expected a number, got {value!r}")
    x = _validate.scalar(value, field)
    if x <= 0.0:
        raise InputError(f"{field}: must be positive, got {x:g}")
    lo, hi = _validate.LENGTH_RANGE
    if not lo <= x <= hi:
        raise InputError(f"{field}: {x:g} is outside the supported range [{lo:g}, {hi:g}]")
    return x


@dataclass(frozen=True)
class Sphere:
    """A ball of the given radius about its frame's origin."""

    radius: float

    def __post_init__(self):
        object.__setattr__(self, "radius", _length(self.radius, "radius"))

    kind = sy.SPHERE

    def size(self):
        return np.array([self.radius, 0.0, 0.0])


@dataclass(frozen=True)
class Capsule:
    """The points within ``radius`` of the segment from (0, 0, -half_length) to (0, 0, half_length)."""

    radius: float
    half_length: float

    def __post_init__(self):
        object.__setattr__(self, "radius", _length(self.radius, "radius"))
        object.__setattr__(self, "half_length", _length(self.half_length, "half_length"))

    kind = sy.CAPSULE

    def size(self):
        return np.array([self.radius, self.half_length, 0.0])


@dataclass(frozen=True)
class Cylinder:
    """x^2 + y^2 <= radius^2, |z| <= half_length."""

    radius: float
    half_length: float

    def __post_init__(self):
        object.__setattr__(self, "radius", _length(self.radius, "radius"))
        object.__setattr__(self, "half_length", _length(self.half_length, "half_length"))

    kind = sy.CYLINDER

    def size(self):
        return np.array([self.radius, self.half_length, 0.0])


@dataclass(frozen=True)
class Box:
    """|x| <= half_sizes[0], |y| <= half_sizes[1], |z| <= half_sizes[2]."""

    half_sizes: tuple

    def __post_init__(self):
        if not isinstance(self.half_sizes, (list, tuple, np.ndarray)) or len(self.half_sizes) != 3:
            raise InputError(f"half_sizes: expected 3 numbers, got {self.half_sizes!r}")
        object.__setattr__(self, "half_sizes", tuple(_length(x, f"half_sizes[{k}]")
                                                     for k, x in enumerate(self.half_sizes)))

    kind = sy.BOX

    def size(self):
        return np.array(self.half_sizes)


@dataclass(frozen=True)
class HalfSpace:
    """MuJoCo's ``plane``: the solid half-space z <= 0 of its frame, which must not move."""

    kind = sy.PLANE

    def size(self):
        return np.zeros(3)


SHAPES = (Sphere, Capsule, Cylinder, Box, Ellipsoid, HalfSpace)


def kind_and_size(shape, field="shape"):
    """(kind code, size (3,)) of a shape object; InputTypeError naming ``field`` for anything else."""
    if isinstance(shape, Ellipsoid):
        return sy.ELLIPSOID, np.asarray(shape.radii, float)
    if isinstance(shape, (Sphere, Capsule, Cylinder, Box, HalfSpace)):
        return shape.kind, shape.size()
    raise InputTypeError(f"{field}: expected a Sphere, Capsule, Cylinder, Box, Ellipsoid or HalfSpace, "
                         f"got {type(shape).__name__}")


def scale_of(shape):
    """The shape's size: its largest extent from its centre (0 for a half-space)."""
    kind, size = kind_and_size(shape)
    if kind == sy.CAPSULE or kind == sy.CYLINDER:
        return float(size[0] + size[1])
    if kind == sy.BOX:
        return float(np.linalg.norm(size))
    return float(size.max())


def shape_from_json(d, field):
    """A shape from its case-format object ``{"type": ..., ...}``; InputError naming the field otherwise."""
    if not isinstance(d, dict):
        raise InputError(f"{field}: expected an object with a 'type'")
    kind = d.get("type")
    keys = {"sphere": ("radius",), "capsule": ("radius", "half_length"), "cylinder": ("radius", "half_length"),
            "box": ("half_sizes",), "ellipsoid": ("radii",), "plane": ()}
    if kind not in keys:
        raise InputError(f"{field}.type: expected one of {', '.join(keys)}, got {kind!r}")
    for key in keys[kind]:
        if key not in d:
            raise InputError(f"{field}.{key}: missing")
    try:
        if kind == "sphere":
            return Sphere(d["radius"])
        if kind in ("capsule", "cylinder"):
            return (Capsule if kind == "capsule" else Cylinder)(d["radius"], d["half_length"])
        if kind == "box":
            return Box(d["half_sizes"])
        if kind == "ellipsoid":
            return Ellipsoid(d["radii"])
        return HalfSpace()
    except (InputError, InputTypeError, ValueError, TypeError) as exc:
        msg = str(exc)
        raise InputError(f"{field}.{msg}" if msg.split(":")[0] in keys[kind] else f"{field}: {msg}") from None
