"""The JSON case format of ``mjccd solve`` (version 1): parse, solve, report.

A bad case never stops the others: its result carries ``"error": "<case id>:
<field path>: <what is wrong>"``.
"""
import numpy as np

from mjccd.ccd import solve_pair
from mjccd.errors import InputError
from mjccd.motion import (Affine, Ball, Chain, Fixed, Free, Hinge, LinearAffine, Rational, Rigid,
                          Slide, Static)
from mjccd.quadric import Ellipsoid

FORMAT_VERSION = 1


class CaseError(InputError):
    """A case that cannot be solved; the message names the field."""


def _require(d, key, field):
    if not isinstance(d, dict):
        raise CaseError(f"{field}: expected an object")
    if key not in d:
        raise CaseError(f"{field}.{key}: missing")
    return d[key]


def _pose(d, field):
    return _require(d, "position", field), _require(d, "quaternion", field)


def _element(d, field):
    kind = _require(d, "type", field)
    if kind == "fixed":
        return Fixed(*_pose(d, field))
    if kind == "hinge":
        angle = _require(d, "angle", field)
        if not isinstance(angle, (list, tuple)) or len(angle) != 2:
            raise CaseError(f"{field}.angle: expected [start, end]")
        return Hinge(_require(d, "axis", field), float(angle[0]), float(angle[1]))
    if kind == "slide":
        s = _require(d, "displacement", field)
        if not isinstance(s, (list, tuple)) or len(s) != 2:
            raise CaseError(f"{field}.displacement: expected [start, end]")
        return Slide(_require(d, "axis", field), s[0], s[1])
    if kind == "ball":
        return Ball(_require(d, "start", field), _require(d, "end", field))
    if kind == "free":
        return Free(*_pose(_require(d, "start", field), f"{field}.start"),
                    *_pose(_require(d, "end", field), f"{field}.end"))
    raise CaseError(f"{field}.type: unknown chain element {kind!r}")


def motion_from_json(d, field):
    """A motion object from its JSON description (DESIGN.md, plus ``chain``)."""
    kind = _require(d, "type", field)
    try:
        if kind == "static":
            return Static(*_pose(d, field))
        if kind in ("rigid", "affine"):
            start = _pose(_require(d, "start", field), f"{field}.start")
            end = _pose(_require(d, "end", field), f"{field}.end")
            return (Rigid if kind == "rigid" else Affine)(*start, *end)
        if kind == "linear_affine":
            return LinearAffine(_require(d, "start", field), _require(d, "end", field))
        if kind == "rational":
            return Rational(_require(d, "rotation", field), _require(d, "rotation_denominator", field),
                            _require(d, "translation", field), _require(d, "translation_denominator", field))
        if kind == "chain":
            elements = _require(d, "elements", field)
            if not isinstance(elements, list) or not elements:
                raise CaseError(f"{field}.elements: expected a non-empty list")
            return Chain([_element(e, f"{field}.elements[{k}]") for k, e in enumerate(elements)])
    except CaseError:
        raise
    except ValueError as exc:
        msg = str(exc)
        raise CaseError(msg if msg.startswith(field) else f"{field}.{msg}") from None
    raise CaseError(f"{field}.type: unknown motion type {kind!r}")


def _body(case, key):
    body = _require(case, key, "case")
    try:
        ellipsoid = Ellipsoid(_require(body, "radii", key))
    except CaseError:
        raise
    except ValueError as exc:
        raise CaseError(f"{key}.{exc}") from None
    return ellipsoid, motion_from_json(_require(body, "motion", key), f"{key}.motion")


def solve_case(case):
    """Result dict of one case (raises CaseError for bad input)."""
    a, ma = _body(case, "a")
    b, mb = _body(case, "b")
    status, contact, intervals = solve_pair(a, ma, b, mb)
    point = None
    if contact is not None and contact.point is not None:
        point = [float(x) for x in contact.point]
    result = {"status_at_start": status,
              "first_contact": None if contact is None else float(contact.time),
              "intervals": [[t0, t1] for t0, t1 in intervals],
              "contact_point": point,
              "certainty": "certified" if contact is None else contact.certainty}
    if result["certainty"] == "uncertain":
        result["first_contact_bracket"] = [float(x) for x in contact.bracket]
    return result


def solve_cases(doc):
    """Solve a ``{"version": 1, "cases": [...]}`` document; returns the results document."""
    if not isinstance(doc, dict):
        raise ValueError("document: expected an object with 'version' and 'cases'")
    if doc.get("version") != FORMAT_VERSION:
        raise ValueError(f"version: expected {FORMAT_VERSION}, got {doc.get('version')!r}")
    cases = doc.get("cases")
    if not isinstance(cases, list):
        raise ValueError("cases: expected a list")
    results = []
    for k, case in enumerate(cases):
        cid = case.get("id", f"#{k}") if isinstance(case, dict) else f"#{k}"
        try:
            result = {"id": cid, **solve_case(case)}
        except CaseError as exc:
            result = {"id": cid, "error": f"{cid}: {exc}"}
        results.append(result)
    return {"version": FORMAT_VERSION, "results": results}
