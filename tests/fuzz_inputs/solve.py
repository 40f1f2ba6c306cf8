"""Malformed ``mjccd solve`` inputs: broken files, wrong types at every field of a case, unsafe outputs.

Whole files that are not a version-1 document (wrong encoding, nesting,
truncation, top-level types) must be refused naming the file.  Files of one
good and one bad case, the bad one damaged at one field of the case format
(docs/case-format.md) with null, a string, NaN, 1e300 and the like, must
answer the good case and name the bad case's id and field; with ``-o`` they
write their output (a partial batch).  Outputs point at the input, at an
existing file, at a folder and into a missing folder.
"""
import copy
import json
import math

from . import FuzzCase

IDENTITY = [1.0, 0.0, 0.0, 0.0]


def _pose(position):
    return {"position": position, "quaternion": list(IDENTITY)}


# one valid motion of each kind; a sphere on it meets a static sphere at the origin
MOTIONS = {
    "static": {"type": "static", "position": [0.5, 0.0, 0.0], "quaternion": list(IDENTITY)},
    "rigid": {"type": "rigid", "start": _pose([-3.0, 0.0, 0.0]), "end": _pose([3.0, 0.0, 0.0])},
    "affine": {"type": "affine", "start": _pose([-3.0, 0.0, 0.0]), "end": _pose([3.0, 0.0, 0.0])},
    "linear_affine": {"type": "linear_affine", "start": [[1.0, 0, 0, -3], [0, 1, 0, 0], [0, 0, 1, 0]],
                      "end": [[1.0, 0, 0, 3], [0, 1, 0, 0], [0, 0, 1, 0]]},
    "rational": {"type": "rational", "rotation": [[[1.0], [0.0], [0.0]], [[0.0], [1.0], [0.0]], [[0.0], [0.0], [1.0]]],
                 "rotation_denominator": [1.0], "translation": [[-3.0, 6.0], [0.0], [0.0]],
                 "translation_denominator": [1.0]},
    "chain": {"type": "chain", "elements": [
        {"type": "fixed", "position": [-3.0, 0.0, 0.0], "quaternion": list(IDENTITY)},
        {"type": "slide", "axis": [1.0, 0.0, 0.0], "displacement": [0.0, 6.0]},
        {"type": "hinge", "axis": [0.0, 0.0, 1.0], "angle": [0.0, 0.5]},
        {"type": "ball", "start": list(IDENTITY), "end": [0.0, 1.0, 0.0, 0.0]},
        {"type": "free", "start": _pose([0.0, 0.0, 0.0]), "end": _pose([0.1, 0.0, 0.0])}]},
}

# JSON values no number accepts (WRONG) and no list or object accepts (NOT_A_LIST), and numbers no field accepts
WRONG = {"null": None, "true": True, "a string": "x", "an object": {}}
NOT_A_LIST = {**WRONG, "a number": 3}
NON_FINITE = {"NaN": math.nan, "Infinity": math.inf, "-Infinity": -math.inf, "a 401-digit integer": 10 ** 400}
HUGE = {"1e300": 1e300, "-1e300": -1e300}


def _case(cid, motion="rigid"):
    return {"id": cid, "a": {"radii": [1.0, 1.0, 1.0], "motion": copy.deepcopy(MOTIONS[motion])},
            "b": {"radii": [1.0, 1.0, 1.0], "motion": copy.deepcopy(MOTIONS["static"])}}


def _set(node, path, value):
    for key in path[:-1]:
        node = node[key]
    if value is _DELETE:
        del node[path[-1]]
    else:
        node[path[-1]] = value


_DELETE = object()


def _field_name(path):
    """'a.motion.start.position' for ('a', 'motion', 'start', 'position', 1): the message's field, up to any index."""
    names = []
    for key in path:
        if isinstance(key, int):
            break
        names.append(key)
    return ".".join(names)


def _damages():
    """(label, motion kind, path in the case, bad value, field the message must name)."""
    out = []

    def add(kind, path, values, field=None):
        for label, value in values.items():
            out.append((f"{kind}: {'.'.join(map(str, path))} = {label}", kind, path, value,
                        field or _field_name(path)))

    vector_bad = {**NOT_A_LIST, **NON_FINITE, "too short": [0.0, 0.0], "nested": [[0.0], [0.0], [0.0]]}
    element_bad = {**WRONG, **NON_FINITE, "a list": [0.0]}
    # the bodies and their radii
    add("rigid", ("a",), {**NOT_A_LIST, "a list": []})
    add("rigid", ("a",), {"missing": _DELETE}, "case.a")
    add("rigid", ("b",), {"missing": _DELETE}, "case.b")
    add("rigid", ("a", "radii"), {**vector_bad, "missing": _DELETE, "four": [1.0, 1.0, 1.0, 1.0],
                                  "zero": [0.0, 1.0, 1.0], "negative": [-1.0, 1.0, 1.0],
                                  "1e300": [1e300] * 3, "1e-300": [1e-300] * 3, "1e13": [1.0, 1e13, 1.0],
                                  "1e-13": [1.0, 1.0, 1e-13]})
    add("rigid", ("b", "radii", 2), {**element_bad, **HUGE, "1e-300": 1e-300})
    add("rigid", ("a", "motion"), {**NOT_A_LIST, "missing": _DELETE, "a list": []})
    add("rigid", ("a", "motion", "type"), {**NOT_A_LIST, "missing": _DELETE, "unknown": "teleport",
                                           "a list": ["rigid"]})
    # poses
    for kind in ("static", "rigid", "affine"):
        base = () if kind == "static" else ("start",)
        if kind != "static":
            add(kind, ("a", "motion", "end"), {**NOT_A_LIST, "missing": _DELETE, "a list": [0.0, 0.0, 0.0]})
        add(kind, ("a", "motion", *base, "position"), {**vector_bad, "missing": _DELETE})
        add(kind, ("a", "motion", *base, "position", 0), {**element_bad, **HUGE, "1e13": 1e13})
        add(kind, ("a", "motion", *base, "quaternion"), {**NOT_A_LIST, "zero": [0.0] * 4, "1e-300": [1e-300, 0, 0, 0],
                                                         "three": [1.0, 0.0, 0.0], "missing": _DELETE})
        add(kind, ("a", "motion", *base, "quaternion", 3), {**element_bad})
    add("static", ("b", "motion", "position", 1), {"1e300": 1e300, "null": None})
    # linear_affine
    add("linear_affine", ("a", "motion", "start"), {**NOT_A_LIST, "3x3": [[1.0, 0, 0]] * 3, "missing": _DELETE})
    add("linear_affine", ("a", "motion", "end", 1, 3), {**element_bad, **HUGE})
    add("linear_affine", ("a", "motion", "end", 0, 0), {"1e300": 1e300}, "a.motion.end")
    add("linear_affine", ("a", "motion", "end"), {"singular": [[0.0] * 4] * 3}, "a.motion.start/end")
    # rational
    add("rational", ("a", "motion", "rotation"), {**NOT_A_LIST, "2x3": [[[1.0], [0.0], [0.0]]] * 2,
                                                  "missing": _DELETE})
    add("rational", ("a", "motion", "rotation", 0, 0), {**NOT_A_LIST, "empty": [], "NaN": [math.nan],
                                                        "1e300": [1e300], "nested": [[1.0]]})
    add("rational", ("a", "motion", "rotation", 0, 1), {"not orthogonal": [1.0]}, "a.motion.rotation")
    add("rational", ("a", "motion", "rotation_denominator"), {**NOT_A_LIST, "vanishing": [1.0, -2.0], "zero": [0.0],
                                                              "missing": _DELETE})
    add("rational", ("a", "motion", "translation"), {**NOT_A_LIST, "two": [[0.0], [0.0]], "missing": _DELETE})
    add("rational", ("a", "motion", "translation", 1), {"1e300": [1e300], "Infinity": [math.inf], "null": None})
    add("rational", ("a", "motion", "translation_denominator"), {"vanishing": [-1.0, 2.0], "a string": "x"})
    # chains
    add("chain", ("a", "motion", "elements"), {**NOT_A_LIST, "empty": [], "missing": _DELETE})
    add("chain", ("a", "motion", "elements", 1), {**NOT_A_LIST, "a list": []}, "a.motion.elements[1]")
    add("chain", ("a", "motion", "elements", 1, "type"), {"unknown": "weld", "null": None, "missing": _DELETE},
        "a.motion.elements[1]")
    add("chain", ("a", "motion", "elements", 0, "position"), {"1e300": [1e300, 0, 0], "NaN": [math.nan, 0, 0],
                                                              "null": None}, "a.motion.elements[0].position")
    add("chain", ("a", "motion", "elements", 0, "quaternion"), {"zero": [0.0] * 4, "a string": "x"},
        "a.motion.elements[0].quaternion")
    add("chain", ("a", "motion", "elements", 1, "axis"), {"zero": [0.0] * 3, "NaN": [math.nan, 0, 0],
                                                          "null": None, "two": [1.0, 0.0]},
        "a.motion.elements[1].axis")
    add("chain", ("a", "motion", "elements", 1, "displacement"), {"1e300": [0.0, 1e300], "NaN": [math.nan, 0.0],
                                                                  "null": None, "three": [0.0, 1.0, 2.0],
                                                                  "null end": [0.0, None]},
        "a.motion.elements[1].displacement")
    add("chain", ("a", "motion", "elements", 2, "axis"), {"zero": [0.0] * 3, "a number": 1},
        "a.motion.elements[2].axis")
    add("chain", ("a", "motion", "elements", 2, "angle"), {**NOT_A_LIST, "null start": [None, 0.5], "one": [0.0],
                                                           "past pi": [0.0, 4.0], "NaN": [0.0, math.nan],
                                                           "1e300": [0.0, 1e300], "missing": _DELETE},
        "a.motion.elements[2].angle")
    add("chain", ("a", "motion", "elements", 3, "start"), {"zero": [0.0] * 4, "null": None},
        "a.motion.elements[3].start")
    add("chain", ("a", "motion", "elements", 3, "end"), {"Infinity": [math.inf, 0, 0, 0]},
        "a.motion.elements[3].end")
    add("chain", ("a", "motion", "elements", 4, "start"), {"null": None, "a list": [0.0] * 7},
        "a.motion.elements[4].start")
    add("chain", ("a", "motion", "elements", 4, "end", "position"), {"1e300": [1e300, 0, 0]},
        "a.motion.elements[4].end.position")
    return out


def _write(folder, name, data):
    (folder / name).write_bytes(data if isinstance(data, bytes) else data.encode("utf-8"))
    return name


def _damaged_case_inputs(folder):
    """One file per damage: a good case and the damaged one; with -o (a partial batch), --table, or stdout."""
    out = []
    for k, (label, kind, path, value, field) in enumerate(_damages()):
        cid = f"bad-{k}"
        case = _case(cid, kind)
        _set(case, path, value)
        name = _write(folder, f"damaged-{k}.json", json.dumps({"version": 1, "cases": [_case("good"), case]}))
        names = (f"{cid}: {field}",)
        if k % 3 == 0:
            output = f"out-{k}.json"
            out.append(FuzzCase(label, ["solve", name, "-o", output], names, partial=True, writes=(output,)))
        else:
            out.append(FuzzCase(label, ["solve", name] + (["--table"] if k % 3 == 1 else []), names))
    return out


def _case_shape_inputs(folder):
    """Ids and cases of the wrong JSON type: that case's error, the batch still answered."""
    out = []
    for k, (label, value) in enumerate({"null": None, "true": True, "an object": {}, "a number": 3,
                                        "a list": ["x"], "a float": 1.5}.items()):
        case = _case("ignored")
        case["id"] = value
        name = _write(folder, f"id-{k}.json", json.dumps({"version": 1, "cases": [_case("good"), case]}))
        output = f"out-id-{k}.json"
        out.append(FuzzCase(f"id = {label}", ["solve", name, "-o", output, "--table"], ("#1.id",),
                            partial=True, writes=(output,)))
        out.append(FuzzCase(f"id = {label}, table on stdout", ["solve", name, "--table"], ("#1.id",)))
    for k, (label, value) in enumerate({**NOT_A_LIST, "a list": [_case("inner")]}.items()):
        name = _write(folder, f"case-{k}.json", json.dumps({"version": 1, "cases": [_case("good"), value]}))
        out.append(FuzzCase(f"case = {label}", ["solve", name, "--table"], ("#1: case",)))
    return out


def _document_inputs(folder, rng):
    """Files that are not a version-1 document: refused naming the file, no output written."""
    good = json.dumps({"version": 1, "cases": [_case("good"), _case("other", "chain")]}, indent=1)
    files = {
        "empty": b"",
        "only whitespace": b"  \n\t\n",
        "random bytes": bytes(rng.integers(0, 256, 512, dtype="uint8")),
        "UTF-16 LE with BOM": good.encode("utf-16"),
        "UTF-16 BE with BOM": b"\xfe\xff" + good.encode("utf-16-be"),
        "UTF-16 LE without BOM": good.encode("utf-16-le"),
        "UTF-32": good.encode("utf-32"),
        "Latin-1 id": json.dumps({"version": 1, "cases": [_case("caf\u00e9")]}, ensure_ascii=False).encode("latin-1"),
        "NUL byte": good.encode("utf-8")[:20] + b"\x00" + good.encode("utf-8")[20:],
        "a lone continuation byte": b"\x80" + good.encode("utf-8"),
        "nested lists 100000 deep": b"[" * 100000 + b"]" * 100000,
        "nested objects 100000 deep": b'{"a":' * 100000 + b"1" + b"}" * 100000,
        "radii nested 100000 deep": ('{"version": 1, "cases": [{"id": "deep", "a": {"radii": ' + "[" * 100000
                                     + "]" * 100000 + "}}]}").encode(),
        "trailing garbage": (good + "\n}").encode(),
        "two documents": (good + good).encode(),
        "single quotes": good.replace('"', "'").encode(),
        "a comment": ("// cases\n" + good).encode(),
        "a 5000-digit integer": ('{"version": 1, "cases": [], "n": ' + "7" * 5000 + "}").encode(),
        "a list": b"[]",
        "a number": b"1",
        "a string": b'"cases"',
        "null": b"null",
        "true": b"true",
        "no version": b'{"cases": []}',
        "version 2": b'{"version": 2, "cases": []}',
        "version as a string": b'{"version": "1", "cases": []}',
        "version true": b'{"version": true, "cases": []}',
        "version null": b'{"version": null, "cases": []}',
        "version NaN": b'{"version": NaN, "cases": []}',
        "version 1.5": b'{"version": 1.5, "cases": []}',
        "version a list": b'{"version": [1], "cases": []}',
        "no cases": b'{"version": 1}',
        "cases null": b'{"version": 1, "cases": null}',
        "cases an object": b'{"version": 1, "cases": {"id": "x"}}',
        "cases a string": b'{"version": 1, "cases": "x"}',
        "cases a number": b'{"version": 1, "cases": 3}',
    }
    encoded = good.encode("utf-8")
    for cut in sorted(rng.choice(len(encoded) - 1, 12, replace=False) + 1):
        files[f"truncated at byte {cut}"] = encoded[:cut]
    out = []
    for k, (label, data) in enumerate(files.items()):
        name = _write(folder, f"doc-{k}.json", data)
        argv = ["solve", name] + (["-o", f"never-{k}.json"] if k % 2 else ["--table"])
        out.append(FuzzCase(label, argv, (name,)))
    return out


def _path_inputs(folder):
    """Inputs that are not files, outputs that must not be written."""
    good = _write(folder, "good.json", json.dumps({"version": 1, "cases": [_case("good")]}))
    _write(folder, "exists.json", "{}\n")
    (folder / "a-folder").mkdir()
    (folder / "a-folder.json").mkdir()
    return [
        FuzzCase("missing input", ["solve", "missing.json"], ("missing.json",)),
        FuzzCase("missing input, -o", ["solve", "missing.json", "-o", "never.json"], ("missing.json",)),
        FuzzCase("a folder as input", ["solve", "a-folder.json"], ("a-folder.json",)),
        FuzzCase("-o into a missing folder", ["solve", good, "-o", "no-such-folder/out.json"], ("no-such-folder",)),
        FuzzCase("-o is the input", ["solve", good, "-o", good], (good,)),
        FuzzCase("-o is the input, spelt differently", ["solve", good, "-o", f"./{good}"], (good,)),
        FuzzCase("-o exists", ["solve", good, "-o", "exists.json"], ("exists.json",)),
        FuzzCase("-o is a folder", ["solve", good, "-o", "a-folder"], ("a-folder",)),
        FuzzCase("-o is a folder, --force", ["solve", good, "-o", "a-folder", "--force"], ("a-folder",)),
        FuzzCase("no input named", ["solve"], ("cases",)),
        FuzzCase("an unknown option", ["solve", good, "--bogus"], ("--bogus",)),
        FuzzCase("-o without a value", ["solve", good, "-o"], ("-o",)),
    ]


def generate(folder, rng):
    """The malformed ``solve`` inputs, written into ``folder``."""
    return (_document_inputs(folder, rng) + _path_inputs(folder) + _case_shape_inputs(folder)
            + _damaged_case_inputs(folder))
