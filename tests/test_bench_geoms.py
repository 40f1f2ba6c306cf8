"""`mjccd bench geoms` runs end to end on the held-out cases (a row per shape pair) and scores answers soundly."""
import numpy as np
import pytest

from mjccd.bench import geoms, peers

needs_fcl = pytest.mark.skipif(not peers.fcl_available(), reason=peers.FCL_SKIP_MESSAGE)


def _rows(text, heading):
    """The table rows (first cell) of the section under ``heading``, up to the next heading."""
    part = text.split(heading, 1)[1].split("\n###", 1)[0]
    return [line.split("|")[1].strip() for line in part.splitlines() if line.startswith("| ")][2:]


@pytest.mark.slow  # compiles the geom kernels when numba's cache is cold (a minute or two); a second after
def test_geoms_bench_quick_writes_a_row_per_pair(tmp_path, capsys):
    page = tmp_path / "bench.md"
    page.write_text("# Benchmarks\n\nkept\n")
    assert geoms.main(["--quick", "--per-pair", "1", "--repeats", "1", "--markdown", str(page)]) == 0
    text = page.read_text()
    assert "kept" in text and "<!-- bench geoms: begin -->" in text and "<!-- bench geoms: end -->" in text
    assert "## MuJoCo shape pairs (`mjccd bench geoms`)" in capsys.readouterr().out
    assert len(geoms.PAIRS) == 20
    assert _rows(text, "### mjccd") == geoms.PAIRS + ["all"]
    if peers.fcl_available():
        section = text.split("### python-fcl `continuousCollide`", 1)[1]
        tables = [t for t in section.split("\n\n") if t.startswith("| pair")]
        assert len(tables) == 2
        for table in tables:
            rows = [line for line in table.splitlines() if line.startswith("| ")][2:]
            assert [line.split("|")[1].strip() for line in rows] == geoms.PAIRS + ["all"]
        assert "no CCD for ellipsoids" in section and "crashes on half-spaces" in section


def test_geoms_bench_rejects_bad_options(capsys):
    with pytest.raises(SystemExit):
        geoms.main(["--per-pair", "0"])
    assert "--per-pair" in capsys.readouterr().err
    with pytest.raises(SystemExit):
        geoms.main(["--cases", "x.json"])
    assert "--cases and --expected go together" in capsys.readouterr().err


def test_score_counts_missed_false_and_late_answers():
    s = geoms.score([0.5, None, 0.3, 0.2 + 2e-6, None, "error: x"], [0.5, 0.4, None, 0.2, None, 0.1])
    assert (s["n"], s["wrong"], s["missed"], s["false"]) == (6, 4, 1, 1)
    assert s["max_dt"] == pytest.approx(2e-6) and s["median_dt"] == pytest.approx(1e-6)
    assert not geoms.is_wrong(None, None) and geoms.is_wrong(0.1, None) and not geoms.is_wrong(0.3, 0.3 + 1e-7)


def test_conservative_advancement_is_never_run_where_fcl_cannot():
    """FCL 0.7's conservative advancement has no ellipsoid and crashes the process on half-spaces."""
    skipped = {p for p in geoms.PAIRS if geoms.ca_unsupported(p)}
    assert skipped == {p for p in geoms.PAIRS if "ellipsoid" in p or "plane" in p}


@needs_fcl
def test_fcl_shapes_follow_mujoco_conventions():
    """Capsule and cylinder: axis local z, half-length h is FCL's full length 2h; box: half sizes; plane: z <= 0."""
    import fcl

    def distance(shape, position):
        a = fcl.CollisionObject(geoms._fcl_geometry(fcl, shape), fcl.Transform())
        b = fcl.CollisionObject(fcl.Sphere(0.1), fcl.Transform(np.asarray(position, float)))
        return fcl.distance(a, b, fcl.DistanceRequest(), fcl.DistanceResult())

    assert distance({"type": "capsule", "radius": 0.2, "half_length": 0.5}, [0, 0, 1.0]) == pytest.approx(0.2)
    assert distance({"type": "cylinder", "radius": 0.2, "half_length": 0.5}, [0, 0, 1.0]) == pytest.approx(0.4)
    assert distance({"type": "box", "half_sizes": [0.3, 0.4, 0.5]}, [0, 1.0, 0]) == pytest.approx(0.5)

    def collides(position):
        a = fcl.CollisionObject(geoms._fcl_geometry(fcl, {"type": "plane"}), fcl.Transform())
        b = fcl.CollisionObject(fcl.Sphere(0.1), fcl.Transform(np.asarray(position, float)))
        return fcl.collide(a, b, fcl.CollisionRequest(), fcl.CollisionResult()) > 0

    assert collides([0, 0, -3.0]) and collides([0, 0, 0.05]) and not collides([0, 0, 0.2])
