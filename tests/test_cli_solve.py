"""``mjccd solve`` on files a user can trust: bad cases isolated, outputs never clobbered, clean exits.

A batch with a case the solver cannot take still answers the others (with
the answers they get alone) and writes its output; an existing output or the
input itself is replaced only with ``--force``; a closed pipe and Ctrl-C end
the command with one line at most, no traceback and no file left behind.
"""
import contextlib
import io
import json
import os
import pathlib
import signal
import subprocess
import sys
import time

import pytest

import mjccd
from mjccd import cases, cli

EXAMPLES = pathlib.Path(__file__).resolve().parents[1] / "examples" / "cases.json"
GOOD_IDS = ("pub-sphere-01", "pub-rigid-01", "pub-affine-02", "pub-chain-01")


def _examples():
    return {c["id"]: c for c in json.loads(EXAMPLES.read_text())["cases"]}


def _write_doc(path, case_list):
    path.write_text(json.dumps({"version": 1, "cases": case_list}))
    return path


def _solve(*argv, cwd):
    """(exit status, stdout, stderr) of ``mjccd`` run in-process in ``cwd``."""
    out, err = io.StringIO(), io.StringIO()
    here = os.getcwd()
    os.chdir(cwd)
    try:
        with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
            code = cli.main(list(argv))
    finally:
        os.chdir(here)
    return code, out.getvalue(), err.getvalue()


def _with(case, cid, **fields):
    """A copy of ``case`` with another id and some fields of body a or b replaced ('a__radii': ...)."""
    case = json.loads(json.dumps(case))
    case["id"] = cid
    for path, value in fields.items():
        node = case
        keys = path.split("__")
        for key in keys[:-1]:
            node = node[key]
        node[keys[-1]] = value
    return case


def test_a_case_out_of_range_fails_alone_and_the_others_are_written(tmp_path):
    examples = _examples()
    good = [examples[cid] for cid in GOOD_IDS]
    huge = _with(good[0], "huge", a__radii=[1e300, 1e300, 1e300])
    tiny = _with(good[0], "tiny", b__radii=[1e-300, 1.0, 1.0])
    _write_doc(tmp_path / "mixed.json", [good[0], huge, good[1], tiny, good[2], good[3]])
    code, _, err = _solve("solve", "mixed.json", "-o", "out.json", cwd=tmp_path)
    assert code == 1
    assert "Traceback" not in err
    assert "huge: a.radii: 1e+300 is outside the supported range [1e-12, 1e+12]" in err
    assert "tiny: b.radii: 1e-300 is outside the supported range" in err
    results = {r["id"]: r for r in json.loads((tmp_path / "out.json").read_text())["results"]}
    assert set(results) == {*GOOD_IDS, "huge", "tiny"}
    for case in good:
        alone = mjccd.solve_cases({"version": 1, "cases": [case]})["results"][0]
        assert results[case["id"]] == alone


def test_any_failure_of_one_case_becomes_its_error(monkeypatch):
    """Whatever the solver raises on one case (here ZeroDivisionError) is that case's error, naming its id:
    a compiled call over many cases that fails is taken again one case at a time."""
    examples = _examples()
    solve_pair, batch = cases.solve_pair, cases.two_pose_batch

    def fragile(a, motion_a, b, motion_b):
        if a.radii[0] == 0.25:
            raise ZeroDivisionError("division by zero")
        return solve_pair(a, motion_a, b, motion_b)

    def fragile_batch(affine, radii, *args):
        if (radii[:, 0, 0] == 0.25).any():
            raise ZeroDivisionError("division by zero")
        return batch(affine, radii, *args)

    monkeypatch.setattr(cases, "solve_pair", fragile)
    monkeypatch.setattr(cases, "two_pose_batch", fragile_batch)
    doc = {"version": 1, "cases": [examples["pub-sphere-01"], _with(examples["pub-sphere-01"], "fragile",
                                                                     a__radii=[0.25, 0.25, 0.25])]}
    first, broken = mjccd.solve_cases(doc)["results"]
    assert first["first_contact"] is not None
    assert broken == {"id": "fragile", "error": "fragile: cannot be solved: ZeroDivisionError: division by zero"}


@pytest.mark.parametrize("huge", [[1e300, 0.0, 0.0, 0.0], [0.0, 0.0, -1e300, 0.0], [3e307, 3e307, 3e307, 3e307]])
def test_a_huge_quaternion_is_only_a_direction(huge):
    examples = _examples()
    case = examples["pub-affine-02"]
    unit = [x / max(abs(c) for c in huge) for x in huge]
    results = mjccd.solve_cases({"version": 1, "cases": [
        _with(case, "unit", a__motion__start__quaternion=unit, b__motion__quaternion=unit),
        _with(case, "huge", a__motion__start__quaternion=huge, b__motion__quaternion=huge)]})["results"]
    assert "error" not in results[1], results[1]
    assert {**results[1], "id": "unit"} == results[0]


def test_an_id_that_is_not_a_string_is_that_case_error_and_the_table_prints(tmp_path):
    examples = _examples()
    _write_doc(tmp_path / "ids.json", [examples["pub-sphere-01"], _with(examples["pub-rigid-01"], None),
                                       _with(examples["pub-rigid-01"], ["a", "list"])])
    code, out, err = _solve("solve", "ids.json", "--table", cwd=tmp_path)
    assert code == 1 and "Traceback" not in err
    assert "#1.id: expected a string, got null" in err and "#2.id: expected a string, got a list" in err
    assert out.splitlines()[1].startswith("pub-sphere-01") and out.splitlines()[2].startswith("#1 ")


def test_an_existing_output_is_replaced_only_with_force(tmp_path):
    _write_doc(tmp_path / "in.json", [_examples()["pub-sphere-01"]])
    (tmp_path / "out.json").write_text("keep me\n")
    code, _, err = _solve("solve", "in.json", "-o", "out.json", cwd=tmp_path)
    assert code == 2
    assert "out.json" in err and "--force" in err and "Traceback" not in err
    assert (tmp_path / "out.json").read_text() == "keep me\n"
    code, _, err = _solve("solve", "in.json", "-o", "out.json", "--force", cwd=tmp_path)
    assert code == 0, err
    assert json.loads((tmp_path / "out.json").read_text())["results"][0]["id"] == "pub-sphere-01"
    assert sorted(os.listdir(tmp_path)) == ["in.json", "out.json"]


def test_the_input_is_never_its_own_output_without_force(tmp_path):
    original = _write_doc(tmp_path / "in.json", [_examples()["pub-sphere-01"]]).read_text()
    code, _, err = _solve("solve", "in.json", "-o", "in.json", cwd=tmp_path)
    assert code == 2
    assert "in.json: is an input of this command" in err and "--force" in err
    assert (tmp_path / "in.json").read_text() == original
    code, _, err = _solve("solve", "in.json", "-o", "in.json", "--force", cwd=tmp_path)
    assert code == 0, err
    assert "results" in json.loads((tmp_path / "in.json").read_text())
    assert os.listdir(tmp_path) == ["in.json"]


def test_a_file_that_is_not_utf8_names_the_file(tmp_path):
    doc = json.dumps({"version": 1, "cases": [_examples()["pub-sphere-01"]]})
    (tmp_path / "utf16.json").write_bytes(doc.encode("utf-16"))
    code, _, err = _solve("solve", "utf16.json", cwd=tmp_path)
    assert code == 2 and err.startswith("mjccd solve: utf16.json: not UTF-8 text")
    (tmp_path / "bom.json").write_bytes(doc.encode("utf-8-sig"))  # a UTF-8 byte-order mark is UTF-8 still
    code, out, err = _solve("solve", "bom.json", cwd=tmp_path)
    assert code == 0, err
    assert json.loads(out)["results"][0]["id"] == "pub-sphere-01"


def test_a_closed_pipe_ends_quietly(tmp_path):
    """``mjccd solve big.json | head -c 10``: more output than a pipe holds, its reader gone after 10 bytes."""
    sphere = _examples()["pub-sphere-01"]
    _write_doc(tmp_path / "big.json", [_with(sphere, f"case-{k}") for k in range(1500)])
    proc = subprocess.Popen([sys.executable, "-m", "mjccd", "solve", "big.json"], cwd=tmp_path,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    head = proc.stdout.read(10)
    proc.stdout.close()
    err = proc.stderr.read().decode()
    code = proc.wait(timeout=60)
    assert head == b'{\n "versio'
    assert code == cli.EXIT_CLOSED_PIPE
    assert "Traceback" not in err and "BrokenPipe" not in err and "Broken pipe" not in err, err


def test_ctrl_c_leaves_no_output_and_no_temporary_file(tmp_path):
    """SIGINT in the middle of a long batch: exit 130, one line, nothing written."""
    chain = _examples()["pub-chain-01"]
    _write_doc(tmp_path / "many.json", [_with(chain, f"chain-{k}") for k in range(3000)])
    start = time.monotonic()
    subprocess.run([sys.executable, "-c", "import mjccd.cli, mjccd.cases, mjccd.files"], check=True)
    started = time.monotonic() - start  # interpreter and imports: the SIGINT must come later, inside the batch
    proc = subprocess.Popen([sys.executable, "-m", "mjccd", "solve", "many.json", "-o", "out.json"], cwd=tmp_path,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    time.sleep(max(1.0, 3 * started))
    assert proc.poll() is None, "the batch ended before it could be interrupted"
    proc.send_signal(signal.SIGINT)
    out, err = proc.communicate(timeout=60)
    assert proc.returncode == 130, err
    assert err.strip() == "mjccd: interrupted"
    assert os.listdir(tmp_path) == ["many.json"]
