"""Uncertain answers of the compiled scenes, asked again of the core's exact tiers; an estimate for the rest.

The compiled scenes (:class:`mjccd.scene.Scene`, :class:`mjccd.batch.BatchScene`) work in double precision
alone.  A pair they cannot decide (two ellipsoids grazing, or tangent within rounding at the frame's start)
comes back ``uncertain`` with the double solver's bracket, whose high end may be where rounding stopped
deciding rather than a proven event, so a later first contact could lie past it.
:func:`mjccd.first_contact` and :func:`mjccd.plane_first_contact` add the rational tier and reach their
brackets to a proven event.  The scenes ask them again about each such pair, on the motion the kernel solved
(:func:`ask_again`): it comes back certified, certified free, or still uncertain with the core's bracket,
which holds every possible first contact, and an estimated point and normal (:func:`estimated_touch`).
"""
from fractions import Fraction
from typing import NamedTuple

import numpy as np

from mjccd.ccd import collision_intervals, first_contact
from mjccd.motion import Affine, Rigid
from mjccd.plane import Plane, plane_collision_intervals, plane_first_contact
from mjccd.quadric import Ellipsoid, pencil_quartic, quartic_max, touching_point


class Answer(NamedTuple):
    """The core's answer about one pair of a frame (:func:`ask_again`).

    ``time`` in [0, 1], the bracket's low end when uncertain; ``point`` and
    ``normal`` (world, the normal outward from the first body), an estimate
    when uncertain, None when the pair is not separate at the start or no
    estimate could be formed; ``status_at_start`` "separate", "touching" or
    "overlapping"; ``bracket`` (lo, hi) when uncertain, else None;
    ``intervals`` the collision intervals when asked for, else ().
    """

    time: float
    point: object
    normal: object
    status_at_start: str
    bracket: tuple
    intervals: tuple


def pair_problem(motion, radii, pairs, planes, plane_pairs, p0, q0, p1, q1, k):
    """(shape_a, motion_a, shape_b or :class:`~mjccd.Plane`, motion_b or None): what the core solves for pair
    k of a scene (a plane pair: k past the ``pairs``) whose kernel moved its ellipsoids from positions p0 and
    unit quaternions q0 to p1, q1 (``motion`` "rigid" or "affine")."""
    kind = Rigid if motion == "rigid" else Affine
    npairs = len(pairs)
    if k < npairs:
        i, j = int(pairs[k, 0]), int(pairs[k, 1])
        return (Ellipsoid(radii[i]), kind(p0[i], q0[i], p1[i], q1[i]),
                Ellipsoid(radii[j]), kind(p0[j], q0[j], p1[j], q1[j]))
    e, row = (int(x) for x in plane_pairs[k - npairs])
    return (Ellipsoid(radii[e]), kind(p0[e], q0[e], p1[e], q1[e]), Plane(planes[row, :3], planes[row, 3]), None)


def ask_again(problem, *, intervals=False):
    """The core's :class:`Answer` about one pair (``problem`` as :func:`pair_problem` gives it), or None when it
    is certified free.  ``intervals``: also its collision intervals."""
    shape_a, motion_a, other, motion_b = problem
    if isinstance(other, Plane):
        hit = plane_first_contact(shape_a, motion_a, other)
    else:
        hit = first_contact(shape_a, motion_a, other, motion_b)
    if hit is None:
        return None
    certain = hit.certainty == "certified"
    point, normal = hit.point, hit.normal
    if point is None and not (certain and hit.status_at_start != "separate"):
        point, normal = estimated_touch(shape_a, motion_a, other, motion_b, hit.time)
    spans = ()
    if intervals:
        spans = tuple(plane_collision_intervals(shape_a, motion_a, other) if isinstance(other, Plane)
                      else collision_intervals(shape_a, motion_a, other, motion_b))
    return Answer(hit.time, point, normal, hit.status_at_start, None if certain else hit.bracket, spans)


def settle(problem_of, contacts, new_only, make, *, intervals=False, not_new=None):
    """``(contacts, tally)``: ``contacts`` (anything with ``pair``, ``certainty`` and ``bracket``) with each
    uncertain one asked again (:func:`ask_again`).

    ``problem_of(k)`` gives pair k's problem; ``new_only``: a pair not separate at the start is left out.  A
    contact the core certifies is replaced by its answer, one it proves free is left out; one still uncertain
    takes the core's bracket and estimate.  ``make(k, answer)`` makes the contact of pair k.  ``tally`` counts,
    for the caller's counters, the contacts ``settled`` (no longer uncertain, those left out included),
    ``not_new`` (left out by ``new_only``) and ``found`` (a first contact now known whose uncertain answer had
    only bracketed it).  ``not_new``: a list that gets the pairs left out by ``new_only``, for callers that
    label each pair.
    """
    out, tally = [], dict.fromkeys(("settled", "not_new", "found"), 0)
    for c in contacts:
        if c.certainty == "certified":
            out.append(c)
            continue
        answer = ask_again(problem_of(c.pair), intervals=intervals)
        bracketed = c.bracket is not None and c.bracket[0] != c.bracket[1]  # its first contact was not known
        certain = answer is None or answer.bracket is None
        tally["settled"] += certain
        if answer is None:  # proven free
            continue
        tally["found"] += bracketed and (certain or answer.bracket[0] == answer.bracket[1])
        if new_only and answer.status_at_start != "separate":
            tally["not_new"] += 1
            if not_new is not None:
                not_new.append(c.pair)
            continue
        out.append(make(c.pair, answer))
    return out, tally


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
