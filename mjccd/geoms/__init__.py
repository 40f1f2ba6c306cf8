"""Exact first contact of MuJoCo's own shapes: spheres, capsules, cylinders, boxes, ellipsoids and planes."""
from mjccd.geoms.shapes import Box, Capsule, Cylinder, Ellipsoid, HalfSpace, Sphere, shape_from_json
from mjccd.geoms.solve import geom_collision_intervals, geom_first_contact

__all__ = ["Box", "Capsule", "Cylinder", "Ellipsoid", "HalfSpace", "Sphere", "geom_collision_intervals",
           "geom_first_contact", "shape_from_json"]
