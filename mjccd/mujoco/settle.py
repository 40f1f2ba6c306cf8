"""Uncertain contacts of ellipsoid mode: settled by the core's exact tiers, or given an estimated point.

The compiled scene (:class:`mjccd.scene.Scene`) works in double precision alone.  A pair it cannot decide
(two ellipsoids grazing, or tangent within rounding at the step's start) comes back ``uncertain``.  The core's
:func:`mjccd.first_contact` and :func:`mjccd.plane_first_contact` add the rational tier, so most of these pairs
settle there: they become certified, or certified free.  :func:`settle` asks the core for each uncertain
contact of a step, on the same motion the scene solved.  Whatever stays uncertain keeps the core's bracket,
which holds every possible first contact, and carries an estimated point and normal
(:func:`estimated_touch`).
"""
from fractions import Fraction

import numpy as np

from mjccd.ccd import first_contact
from mjccd.plane import Plane, plane_first_contact
from mjccd.quadric import pencil_quartic, quartic_max, touching_point


def _float_quadric(shape, motion, t):
    """The 4x4 quadric of ``shape`` under ``motion`` at time t, in doubles, scaled by a positive factor (the
    exact matrix divided by its largest entry, so that no entry overflows)."""
    exact = motion.exact_quadric_at(shape.radii, Fraction(t))
    scale = max(abs(Fraction(x)) for row in exact for x in row)
    return np.array([[float(Fraction(x) / scale) for x in row] for row in exact])


def estimated_touch(shape_a, motion_a, other, motion_b, t):
    """(point, normal): where ellipsoid a nearly touches ``other`` (an ellipsoid under ``motion_b``, or a
    :class:`~mjccd.Plane`) at time t, the normal pointing out of a; (None, None) when no finite point comes out.
    The point of the two quadrics' pencil at its extremum (the touching point when they touch), or a's
    support point toward the plane: an estimate, never a proof."""
    A = _float_quadric(shape_a, motion_a, t)
    if isinstance(other, Plane):
        Q, b = A[:3, :3], A[:3, 3]
        centre = -np.linalg.solve(Q, b)
        inverse = np.linalg.inv(Q / (centre @ Q @ centre - A[3, 3]))
        n = np.asarray(other.normal, float)
        reach = inverse @ n / np.sqrt(n @ inverse @ n)
        point, normal = centre - reach, -n / np.linalg.norm(n)
    else:
        B = _float_quadric(other, motion_b, t)
        g, _ = pencil_quartic(A, B)
        _, u = quartic_max(g)
        point, normal = touching_point(A, B, u)
    if not (np.all(np.isfinite(point)) and np.all(np.isfinite(normal))):
        return None, None
    return point, normal


def settle(pair_problem, contacts, new_only, make):
    """``(contacts, settled, dropped)``: ``contacts`` (:class:`~mjccd.mujoco.StepContact`, in step fractions)
    with each uncertain one asked again of the core's exact tiers.

    ``pair_problem(k)`` gives pair k's (shape_a, motion_a, shape_b or Plane, motion_b or None), the motion the
    scene solved; ``new_only``: a pair not separate at the start is left out.  A contact the core certifies is
    replaced by its answer, one it proves free is dropped; one still uncertain takes the core's bracket and
    status and an estimated point (:func:`estimated_touch` at the bracket's start).  ``settled`` counts the
    contacts no longer uncertain (``dropped`` of them left out).  ``make(k, fraction, point, normal, status,
    bracket)`` makes the contact of pair k from an answer (``bracket``: step fractions, None when certified).
    """
    out, settled, dropped = [], 0, 0
    for c in contacts:
        if c.certainty == "certified":
            out.append(c)
            continue
        shape_a, motion_a, other, motion_b = pair_problem(c.pair)
        if isinstance(other, Plane):
            hit = plane_first_contact(shape_a, motion_a, other)
        else:
            hit = first_contact(shape_a, motion_a, other, motion_b)
        certain = hit is None or hit.certainty == "certified"
        settled += certain
        if hit is None or (new_only and hit.status_at_start != "separate"):
            dropped += 1
            continue
        point, normal = hit.point, hit.normal
        if point is None and not (certain and hit.status_at_start != "separate"):
            point, normal = estimated_touch(shape_a, motion_a, other, motion_b, hit.time)
        out.append(make(c.pair, hit.time, point, normal, hit.status_at_start, None if certain else hit.bracket))
    return out, settled, dropped
