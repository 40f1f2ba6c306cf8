"""The JSON case format of ``mjccd solve`` (version 1): read, parse, solve, report.

A bad case never stops the others: whatever goes wrong while one case is
parsed or solved becomes its result's ``"error": "<case id>: <field path>:
<what is wrong>"`` (the field is named wherever the input is at fault), and
the batch always completes.  A file that is not a version-1 document at all
raises :class:`~mjccd.errors.InputError` naming the file or the top-level field.

Cases whose two bodies each move between two poses (static, rigid, affine)
and whose numbers pass every check are read by a scalar fast path and solved
together, a chunk at a time, in one compiled call
(:func:`mjccd.ccd.two_pose_batch`); every other case, and each of those whose
answer needs the rational tier, goes through :func:`solve_case` alone.
"""
import json
import math
import re
import reprlib

import numpy as np

from mjccd import _validate, interrupts
from mjccd.ccd import PACKED_HEAD, needs_exact, solve_pair, two_pose_batch
from mjccd.errors import InputError
from mjccd.geoms.shapes import shape_from_json
from mjccd.geoms.solve import geom_collision_intervals, geom_first_contact
from mjccd.motion import (Affine, Ball, Chain, Fixed, Free, Hinge, LinearAffine, Rational, Rigid,
                          Slide, Static)
from mjccd.quadric import STATUS_NAMES, Ellipsoid

FORMAT_VERSION = 1
CHUNK = 256  # two-pose cases per compiled call; Ctrl-C takes effect between chunks

# a message that starts with the argument it is about ("start.quaternion: ...", "rotation[0][1]: ...")
_NAMED = re.compile(r"[A-Za-z_][\w\[\]./]*: ")


class CaseError(InputError):
    """A case that cannot be solved; the message names the field."""


def _describe(value):
    """A JSON value in a few characters, for messages: null, true, 2.5, 'text', a list, an object."""
    if value is None or isinstance(value, bool):
        return json.dumps(value)
    if isinstance(value, (str, int, float)):
        return reprlib.repr(value)
    return "a list" if isinstance(value, list) else "an object"


def printable(text):
    """``text`` on one line: control characters (a newline in a case id) escaped."""
    return text if text.isprintable() else text.encode("unicode_escape").decode("ascii")


def read_cases(path):
    """The JSON document in the file ``path``; InputError naming the file when it is not JSON text."""
    try:
        with open(path, "rb") as fh:
            data = fh.read()
    except IsADirectoryError:
        raise InputError(f"{path}: is a folder, expected a JSON file") from None
    except OSError as exc:
        raise InputError(f"{path}: cannot read: {exc.strerror or exc}") from None
    if data.startswith((b"\xff\xfe", b"\xfe\xff")):
        raise InputError(f"{path}: not UTF-8 text (a UTF-16 or UTF-32 byte-order mark; save it as UTF-8)")
    nul = data.find(b"\x00")
    if nul >= 0:
        raise InputError(f"{path}: not UTF-8 text (NUL byte at offset {nul}: binary or UTF-16)")
    try:
        text = data.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        raise InputError(f"{path}: not UTF-8 text (byte 0x{data[exc.start]:02x} at offset {exc.start})") from None
    if not text.strip():
        raise InputError(f"{path}: empty file, expected a JSON document")
    try:
        return json.loads(text)
    except json.JSONDecodeError as exc:
        raise InputError(f"{path}: not valid JSON: {exc.msg} (line {exc.lineno}, column {exc.colno})") from None
    except RecursionError:
        raise InputError(f"{path}: nested too deeply") from None
    except ValueError as exc:  # an integer of thousands of digits
        raise InputError(f"{path}: not valid JSON: {exc}") from None


def _object(value, field):
    if not isinstance(value, dict):
        raise CaseError(f"{field}: expected an object, got {_describe(value)}")
    return value


def _require(d, key, field):
    if key not in _object(d, field):
        raise CaseError(f"{field}.{key}: missing")
    return d[key]


def _numbers(value, depth, field):
    """``value``, checked to be lists nested ``depth`` deep of JSON numbers (naming the first item that is not)."""
    if depth == 0:
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise CaseError(f"{field}: expected a number, got {_describe(value)}")
    elif not isinstance(value, list):
        raise CaseError(f"{field}: expected a list, got {_describe(value)}")
    else:
        for k, item in enumerate(value):
            _numbers(item, depth - 1, f"{field}[{k}]")
    return value


def _coordinates(value, shape, field):
    """Numbers of a motion that are not directions or angles (positions, matrices, ...), within the supported range."""
    return _validate.coordinates(_numbers(value, len(shape), field), shape, field)


def _direction(value, n, field, zero="zero vector"):
    """A quaternion or axis, scaled so that the motion's own normalisation cannot overflow."""
    return _validate.direction(_numbers(value, 1, field), n, field, zero)


def _pair(value, field):
    """[start, end] as two finite numbers."""
    if len(_numbers(value, 1, field)) != 2:
        raise CaseError(f"{field}: expected [start, end]")
    return [_validate.scalar(x, f"{field}[{k}]") for k, x in enumerate(value)]


def _polynomial(value, field):
    """Power-basis coefficients, each within the supported range."""
    return _validate.coordinates(_validate.polynomial(_numbers(value, 1, field), field), (None,), field)


def _build(field, make, *args):
    """``make(*args)``; whatever it raises becomes a CaseError naming ``field`` (a constructor names only its own)."""
    try:
        return make(*args)
    except Exception as exc:
        msg = " ".join(str(exc).split())
        if isinstance(exc, ValueError) and _NAMED.match(msg):
            raise CaseError(f"{field}.{msg}") from None
        raise CaseError(f"{field}: {type(exc).__name__}: {msg}" if msg else f"{field}: {type(exc).__name__}") from None


def _pose(d, field):
    return (_coordinates(_require(d, "position", field), (3,), f"{field}.position"),
            _direction(_require(d, "quaternion", field), 4, f"{field}.quaternion", "zero quaternion"))


def _element(d, field):
    kind = _require(d, "type", field)
    if kind == "fixed":
        return _build(field, Fixed, *_pose(d, field))
    if kind == "hinge":
        axis = _direction(_require(d, "axis", field), 3, f"{field}.axis")
        return _build(field, Hinge, axis, *_pair(_require(d, "angle", field), f"{field}.angle"))
    if kind == "slide":
        axis = _direction(_require(d, "axis", field), 3, f"{field}.axis")
        return _build(field, Slide, axis, *_coordinates(_require(d, "displacement", field), (2,),
                                                        f"{field}.displacement"))
    if kind == "ball":
        return _build(field, Ball, *(_direction(_require(d, key, field), 4, f"{field}.{key}", "zero quaternion")
                                     for key in ("start", "end")))
    if kind == "free":
        return _build(field, Free, *_pose(_require(d, "start", field), f"{field}.start"),
                      *_pose(_require(d, "end", field), f"{field}.end"))
    raise CaseError(f"{field}.type: unknown chain element {_describe(kind)}")


def _rational(d, field):
    rotation = _numbers(_require(d, "rotation", field), 3, f"{field}.rotation")
    if len(rotation) != 3 or any(len(row) != 3 for row in rotation):
        raise CaseError(f"{field}.rotation: expected a 3x3 array of polynomials")
    translation = _numbers(_require(d, "translation", field), 2, f"{field}.translation")
    if len(translation) != 3:
        raise CaseError(f"{field}.translation: expected 3 polynomials")
    return _build(field, Rational,
                  [[_polynomial(p, f"{field}.rotation[{i}][{j}]") for j, p in enumerate(row)]
                   for i, row in enumerate(rotation)],
                  _polynomial(_require(d, "rotation_denominator", field), f"{field}.rotation_denominator"),
                  [_polynomial(p, f"{field}.translation[{i}]") for i, p in enumerate(translation)],
                  _polynomial(_require(d, "translation_denominator", field), f"{field}.translation_denominator"))


def motion_from_json(d, field):
    """A motion object from its JSON description (docs/case-format.md); CaseError naming the field otherwise."""
    kind = _require(d, "type", field)
    if kind == "static":
        return _build(field, Static, *_pose(d, field))
    if kind in ("rigid", "affine"):
        start = _pose(_require(d, "start", field), f"{field}.start")
        end = _pose(_require(d, "end", field), f"{field}.end")
        return _build(field, Rigid if kind == "rigid" else Affine, *start, *end)
    if kind == "linear_affine":
        return _build(field, LinearAffine, *(_coordinates(_require(d, key, field), (3, 4), f"{field}.{key}")
                                             for key in ("start", "end")))
    if kind == "rational":
        return _rational(d, field)
    if kind == "chain":
        elements = _require(d, "elements", field)
        if not isinstance(elements, list):
            raise CaseError(f"{field}.elements: expected a list, got {_describe(elements)}")
        if not elements:
            raise CaseError(f"{field}.elements: a chain needs at least one element")
        return _build(field, Chain, [_element(e, f"{field}.elements[{k}]") for k, e in enumerate(elements)])
    raise CaseError(f"{field}.type: unknown motion type {_describe(kind)}")


def _body(case, key):
    """(shape, motion, is a MuJoCo shape) of body ``key``: ``"radii"`` for an ellipsoid, or a ``"shape"``."""
    body = _require(case, key, "case")
    if "shape" in _object(body, key):
        if "radii" in body:
            raise CaseError(f"{key}: give either 'radii' or 'shape', not both")
        shape = shape_from_json(body["shape"], f"{key}.shape")
        return shape, motion_from_json(_require(body, "motion", key), f"{key}.motion"), True
    radii = _validate.radii(_numbers(_require(body, "radii", key), 1, f"{key}.radii"), f"{key}.radii")
    return Ellipsoid(radii), motion_from_json(_require(body, "motion", key), f"{key}.motion"), False


def _geom_result(a, ma, b, mb):
    """Result dict of a case with a MuJoCo shape (:mod:`mjccd.geoms`)."""
    contact = geom_first_contact(a, ma, b, mb)
    intervals, intervals_certified = geom_collision_intervals(a, ma, b, mb)
    status = "separate" if contact is None else contact.status_at_start
    point = None if contact is None or contact.point is None or contact.time == 0.0 else \
        [float(x) for x in contact.point]
    # the first contact and the intervals are certified apart: an interval's end can stay in a bracket wider than
    # 1e-9 (where the overlap shrinks to a point at a rim, docs/method.md) while the first contact is proven
    certain = contact is None or contact.certainty == "certified"
    if contact is None and not intervals_certified and intervals:
        certain = False  # nothing proven, but an interval may hold a graze: every possible first contact is in it
    result = {"status_at_start": status,
              "first_contact": None if contact is None else float(contact.time),
              "intervals": [[t0, t1] for t0, t1 in intervals],
              "contact_point": point,
              "certainty": "certified" if certain else "uncertain",
              "intervals_certainty": "certified" if intervals_certified else "uncertain"}
    if contact is not None and contact.elements is not None and contact.time > 0.0:
        result["elements"] = list(contact.elements)
    if not certain:
        if contact is None:  # a possible graze somewhere in the intervals
            lo = intervals[0][0] if intervals else 0.0
            result["first_contact"] = lo
            result["first_contact_bracket"] = [lo, intervals[-1][1] if intervals else 1.0]
        else:
            result["first_contact_bracket"] = [float(x) for x in (contact.bracket or (contact.time, contact.time))]
    return result


def solve_case(case):
    """Result dict of one case (raises InputError naming the field for bad input)."""
    a, ma, shaped_a = _body(case, "a")
    b, mb, shaped_b = _body(case, "b")
    if shaped_a or shaped_b:
        return _geom_result(a, ma, b, mb)
    status, contact, intervals, certified = solve_pair(a, ma, b, mb)
    point = None
    if contact is not None and contact.point is not None:
        point = [float(x) for x in contact.point]
    result = {"status_at_start": status,
              "first_contact": None if contact is None else float(contact.time),
              "intervals": [[t0, t1] for t0, t1 in intervals],
              "contact_point": point,
              "certainty": "certified" if certified else "uncertain"}
    if not certified:  # the first contact's own bracket; a proven first contact with a later end left open: its time
        result["first_contact_bracket"] = [float(x) for x in (contact.bracket or (contact.time, contact.time))]
    return result


def _result(case, k):
    """The result of the k-th case, or its error: nothing raised while parsing or solving it escapes."""
    cid = f"#{k}"
    if isinstance(case, dict) and "id" in case:
        if not isinstance(case["id"], str):
            return {"id": cid, "error": f"{cid}.id: expected a string, got {_describe(case['id'])}"}
        cid = case["id"]
    try:
        return {"id": cid, **solve_case(case)}
    except InputError as exc:
        error = str(exc)
    except Exception as exc:  # the solver's own failure on this input: this case's error, never the batch's
        error = f"cannot be solved: {type(exc).__name__}: {exc}"
    return {"id": cid, "error": f"{printable(cid)}: {' '.join(error.split())}"}


def _case_list(doc):
    """The ``cases`` of a version-1 document; InputError naming the top-level field otherwise."""
    if not isinstance(doc, dict):
        raise InputError(f"document: expected an object with 'version' and 'cases', got {_describe(doc)}")
    if "version" not in doc:
        raise InputError(f"version: missing (expected {FORMAT_VERSION})")
    version = doc["version"]
    if isinstance(version, bool) or version != FORMAT_VERSION:
        raise InputError(f"version: expected {FORMAT_VERSION}, got {_describe(version)}")
    if "cases" not in doc:
        raise InputError("cases: missing")
    if not isinstance(doc["cases"], list):
        raise InputError(f"cases: expected a list, got {_describe(doc['cases'])}")
    return doc["cases"]


# ---------------------------------------------------------------- the two-pose fast path

_NUMBER = frozenset((int, float))  # what json.loads makes of a number (bool, its subclass, is not one)


def _plain_unit(q):
    """The unit quaternion the motion makes of ``q`` (four finite floats): its quotients by ``math.hypot``, as
    :func:`mjccd._validate.unit_quaternion` takes them; None for a zero quaternion, or one whose length
    overflows (:func:`solve_case` then reads it).
    """
    norm = math.hypot(q[0], q[1], q[2], q[3])
    if not _validate.MIN_NORM <= norm < math.inf:
        return None
    return [q[0] / norm, q[1] / norm, q[2] / norm, q[3] / norm]


def _plain_body(case, key):
    """(affine?, [radii, p0, q0, p1, q1] (17 floats)) of body ``key`` when it moves between two poses and every
    number passes its check; None otherwise (the case then goes through :func:`solve_case`, which names what is
    wrong).

    One pass over all the body's numbers: lists of JSON numbers (a bool is not one) of the right lengths,
    finite, radii and positions within LENGTH_RANGE, quaternions not zero.
    """
    body = case.get(key)
    if type(body) is not dict:
        return None
    motion, xs = body.get("motion"), body.get("radii")
    if type(motion) is not dict or type(xs) is not list or len(xs) != 3:
        return None
    kind = motion.get("type")
    if kind == "static":
        start = end = motion
    elif kind == "rigid" or kind == "affine":
        start, end = motion.get("start"), motion.get("end")
        if type(end) is not dict:
            return None
    else:
        return None
    if type(start) is not dict:
        return None
    p0, q0, p1, q1 = start.get("position"), start.get("quaternion"), end.get("position"), end.get("quaternion")
    if (type(p0) is not list or type(q0) is not list or type(p1) is not list or type(q1) is not list
            or len(p0) != 3 or len(q0) != 4 or len(p1) != 3 or len(q1) != 4):
        return None
    xs = _validate.finite_floats(xs + p0 + q0 + p1 + q1, _NUMBER)  # radii, then each pose's position and quaternion
    lo, hi = _validate.LENGTH_RANGE
    if (xs is None or not (lo <= xs[0] <= hi and lo <= xs[1] <= hi and lo <= xs[2] <= hi)
            or max(abs(xs[3]), abs(xs[4]), abs(xs[5]), abs(xs[10]), abs(xs[11]), abs(xs[12])) > hi):
        return None
    q0 = _plain_unit(xs[6:10])
    q1 = q0 if kind == "static" else _plain_unit(xs[13:17])
    if q0 is None or q1 is None:
        return None
    if kind == "rigid" and q0[0] * q1[0] + q0[1] * q1[1] + q0[2] * q1[2] + q0[3] * q1[3] < 0.0:
        q1 = [-q1[0], -q1[1], -q1[2], -q1[3]]  # as Rigid aligns them
    return kind == "affine", xs[0:6] + q0 + xs[10:13] + q1


def _plain_case(case):
    """(numbers, affine (2,)) of a case for :func:`mjccd.ccd.two_pose_batch`, or None: the numbers are body a's
    radii and row [p0, q0, p1, q1], then body b's (17 each)."""
    if type(case) is not dict or type(case.get("id", "")) is not str:
        return None
    a = _plain_body(case, "a")
    b = None if a is None else _plain_body(case, "b")
    if b is None:
        return None
    return a[1] + b[1], (a[0], b[0])


def _packed_result(cid, out):
    """The result of a case from its packed answer (a list, see :func:`mjccd.ccd.pack_solution`), as
    :func:`solve_case` writes it; None when the answer needs the rational tier (every uncertain one does)."""
    status0, k, _, _, certified = out[:5]
    if needs_exact(status0, certified):
        return None
    k = int(k)
    times = out[PACKED_HEAD:PACKED_HEAD + 2 * k]
    result = {"id": cid, "status_at_start": STATUS_NAMES[int(status0)], "first_contact": 0.0,
              "intervals": [[times[2 * i], times[2 * i + 1]] for i in range(k)], "contact_point": None,
              "certainty": "certified"}
    if status0 != 1:  # not separate at the start: the first contact is t = 0, whatever came later
        return result
    if k:
        result["first_contact"] = times[0]
        result["contact_point"] = out[7:10]
    else:
        result["first_contact"] = None
    return result


def _solve_two_pose(cases, plain):
    """Results of the two-pose cases ``cases`` [(k, case), ...] with their :func:`_plain_case` lists, in one
    compiled call; each one the batch cannot answer (rational tier) is solved alone."""
    numbers = np.array([p[0] for p in plain]).reshape(-1, 2, 17)
    radii = np.ascontiguousarray(numbers[:, :, :3])
    rows = np.ascontiguousarray(numbers[:, :, 3:])
    affine = np.array([p[1] for p in plain], dtype=np.bool_)
    starts = np.empty(len(plain) + 1, dtype=np.int64)
    packed = two_pose_batch(affine, radii, rows, 1.0, False, starts).tolist()
    results = []
    for (k, case), s0, s1 in zip(cases, starts[:-1].tolist(), starts[1:].tolist()):
        cid = case["id"] if "id" in case else f"#{k}"
        results.append(_packed_result(cid, packed[s0:s1]) or _result(case, k))
    return results


def _fill(results, batch, plain):
    """The results of a chunk of two-pose cases into ``results``: one compiled call, or, should that call
    fail, each case alone, so that a failure is the failing case's error."""
    try:
        solved = _solve_two_pose(batch, plain)
    except Exception:  # whatever it is, solving the cases alone tells whose it is
        solved = [_result(case, k) for k, case in batch]
    for (k, _), result in zip(batch, solved):
        results[k] = result


def solve_cases(doc):
    """Solve a ``{"version": 1, "cases": [...]}`` document; returns the results document.

    Raises InputError when ``doc`` is not such a document; a case that
    cannot be solved becomes its result's error.  Ctrl-C takes effect
    between cases and chunks of cases (:func:`mjccd.interrupts.deferred`),
    never inside compiled code.
    """
    cases = _case_list(doc)
    results = [None] * len(cases)
    batch, plain = [], []
    with interrupts.deferred() as check:
        for k, case in enumerate(cases):
            lists = _plain_case(case)
            if lists is None:
                check()
                results[k] = _result(case, k)
                continue
            batch.append((k, case))
            plain.append(lists)
            if len(batch) == CHUNK:
                check()
                _fill(results, batch, plain)
                batch, plain = [], []
        if batch:
            check()
            _fill(results, batch, plain)
    return {"version": FORMAT_VERSION, "results": results}
