"""``solve_cases``: two-pose cases solved a chunk at a time in one compiled call, the others alone, all in order."""
import json
import pathlib

import numpy as np
import pytest

import mjccd
from mjccd import cases

EXAMPLES = pathlib.Path(__file__).resolve().parents[1] / "examples" / "cases.json"


def _pose(r, scale=1.0):
    return {"position": (r.normal(size=3) * scale).tolist(), "quaternion": r.normal(size=4).tolist()}


def _two_pose_case(r, k, kinds):
    def body(kind, centre):
        start, end = _pose(r), _pose(r)
        start["position"] = (np.array(start["position"]) * 0.3 + centre).tolist()
        end["position"] = (np.array(end["position"]) * 0.3 - centre).tolist()
        motion = {"type": kind, **start} if kind == "static" else {"type": kind, "start": start, "end": end}
        return {"radii": r.uniform(0.2, 1.0, 3).tolist(), "motion": motion}
    return {"id": f"c{k}", "a": body(kinds[0], np.array([-1.0, 0, 0])), "b": body(kinds[1], np.array([1.0, 0, 0])),
            "tags": ["ignored"]}


def _document():
    """Two-pose cases of every kind, the examples (rational, linear affine, chain) and bad cases, interleaved."""
    r = np.random.default_rng(2)
    kinds = ["static", "rigid", "affine"]
    docs = [_two_pose_case(r, k, (kinds[k % 3], kinds[(k // 3) % 3])) for k in range(40)]
    docs += json.loads(EXAMPLES.read_text())["cases"]
    bad = json.loads(json.dumps(docs[1]))
    bad["id"] = "bool-radius"
    bad["a"]["radii"][0] = True  # a JSON true is not a number, although Python's bool is an int
    docs.append(bad)
    bad = json.loads(json.dumps(docs[4]))
    bad["id"] = "zero-quaternion"
    bad["b"]["motion"]["start"]["quaternion"] = [0, 0, 0, 0]
    docs.append(bad)
    bad = json.loads(json.dumps(docs[4]))
    bad["id"] = 7
    docs.append(bad)
    huge = json.loads(json.dumps(docs[4]))
    huge["id"] = "huge-quaternion"
    huge["a"]["motion"]["start"]["quaternion"] = [3e307, -3e307, 3e307, 1e307]
    docs.append(huge)
    docs.append(["not", "a", "case"])
    order = np.random.default_rng(5).permutation(len(docs))
    return {"version": 1, "cases": [docs[k] for k in order]}


@pytest.mark.parametrize("chunk", [1, 3, 256])
def test_batched_results_are_the_results_of_each_case_alone(monkeypatch, chunk):
    monkeypatch.setattr(cases, "CHUNK", chunk)
    doc = _document()
    batched = mjccd.solve_cases(doc)["results"]
    alone = [cases._result(case, k) for k, case in enumerate(doc["cases"])]
    assert batched == alone
    by_id = {r["id"]: r for r in batched}
    assert by_id["bool-radius"]["error"] == "bool-radius: a.radii[0]: expected a number, got true"
    assert by_id["zero-quaternion"]["error"].startswith("zero-quaternion: b.motion.start.quaternion: zero quaternion")
    assert by_id["#" + str(next(k for k, c in enumerate(doc["cases"]) if c == ["not", "a", "case"]))]["error"]
    assert "error" not in by_id["huge-quaternion"]
    assert sum(cases._plain_case(c) is not None for c in doc["cases"]) >= 40


def test_the_fast_reader_takes_only_plain_valid_two_pose_cases():
    r = np.random.default_rng(3)
    case = _two_pose_case(r, 0, ("rigid", "static"))
    numbers, affine = cases._plain_case(case)
    a, ma, _ = cases._body(case, "a")
    b, mb, _ = cases._body(case, "b")
    assert list(affine) == [False, False]  # the same floats as the ellipsoids' and the motions'
    assert numbers == a.radii.tolist() + ma._row.tolist() + b.radii.tolist() + mb._row.tolist()
    for path, value in (("a.radii", [1, 1, 2e12]), ("b.motion.position", [0, 0, 1e13]), ("a.radii", [1, 1]),
                        ("b.motion.quaternion", [1e-13, 0, 0, 0]), ("a.motion.type", "chain"),
                        ("a.motion.start", [0, 0, 0]), ("b.motion.position", [0, 0, float("nan")])):
        bad = json.loads(json.dumps(case))
        node = bad
        keys = path.split(".")
        for key in keys[:-1]:
            node = node[key]
        node[keys[-1]] = value
        assert cases._plain_case(bad) is None, path


@pytest.mark.parametrize("scale", [1e-11, 1e-3, 1.0, 3.0, 1e150, 1e307])
@pytest.mark.parametrize("kinds", [("rigid", "static"), ("affine", "rigid"), ("static", "affine")])
def test_the_fast_reader_makes_the_constructors_floats_at_every_quaternion_scale(kinds, scale):
    # the fast reader's unit quaternions are bit for bit those of the motions, also for integer entries and
    # quaternions long enough to overflow a sum of squares
    r = np.random.default_rng(int(scale < 1) + 7 * len(kinds[0]))
    for k in range(20):
        case = _two_pose_case(r, k, kinds)
        for key in ("a", "b"):
            motion = case[key]["motion"]
            for pose in ((motion,) if motion["type"] == "static" else (motion["start"], motion["end"])):
                q = np.array(pose["quaternion"]) * scale
                pose["quaternion"] = [int(round(x)) for x in q] if k % 5 == 0 and scale >= 3.0 else q.tolist()
        numbers, affine = cases._plain_case(case)
        a, ma, _ = cases._body(case, "a")
        b, mb, _ = cases._body(case, "b")
        assert list(affine) == [kinds[0] == "affine", kinds[1] == "affine"]
        assert numbers == a.radii.tolist() + ma._row.tolist() + b.radii.tolist() + mb._row.tolist()


def test_a_failing_batch_is_solved_case_by_case(monkeypatch):
    doc = _document()
    want = mjccd.solve_cases(doc)["results"]

    def broken(*args):
        raise MemoryError("no room")

    monkeypatch.setattr(cases, "two_pose_batch", broken)
    assert mjccd.solve_cases(doc)["results"] == want
