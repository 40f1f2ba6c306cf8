"""The shipped examples run to their end with their own arguments (short versions where they take long)."""
import pathlib
import runpy

import pytest

ROOT = pathlib.Path(__file__).resolve().parents[1]


@pytest.mark.dm_control
@pytest.mark.parametrize("domain, task", [("humanoid_CMU", "stand"), ("humanoid", "walk")])
def test_wrap_suite_env_runs(domain, task, capsys):
    """The dm-control example (it used to crash on an uncertain contact without a point)."""
    main = runpy.run_path(str(ROOT / "examples" / "wrap_suite_env.py"))["main"]
    assert main(["--domain", domain, "--task", task, "--steps", "40"]) == 0
    out = capsys.readouterr().out
    assert "control steps had a predicted limb contact" in out and "geom pairs checked" in out


def _main(name):
    return runpy.run_path(str(ROOT / "examples" / name))["main"]


def test_wrap_gymnasium_env_runs(capsys):
    """The Gymnasium example: an Ant's feet strike the floor within 200 random steps."""
    assert _main("wrap_gymnasium_env.py")(["--steps", "200"]) == 0
    out = capsys.readouterr().out
    assert "/ world touch at t = " in out and "steps had a new contact" in out


def test_arm_intervals_runs(capsys):
    rows = _main("arm_intervals.py")()
    assert rows and "pairs collide; earliest entry" in capsys.readouterr().out


def test_replay_boxing_runs(tmp_path, capsys):
    _main("replay_boxing.py")(tmp_path / "out")
    assert "first contact: " in capsys.readouterr().out
    assert (tmp_path / "out" / "contacts.json").is_file() and (tmp_path / "out" / "timeline.png").is_file()


def test_plot_example_2_2_runs(tmp_path, capsys):
    _main("plot_example_2_2.py")(tmp_path / "example.png")
    assert (tmp_path / "example.png").read_bytes()[:4] == b"\x89PNG"
    assert "first contact at t = 0.5" in capsys.readouterr().out


def test_scan_collection_runs(tmp_path, capsys):
    """The collection example: a damaged file is named, the two jumping clips are flagged, the plot is written,
    and a second run scans nothing again."""
    assert _main("scan_collection.py")([str(tmp_path), "--clips", "6", "--workers", "1"]) == 0
    out = capsys.readouterr().out
    assert "6 clips in" in out and "could not be scanned" in out and out.count(": jump") == 2
    assert (tmp_path / "contacts_per_clip.png").read_bytes()[:4] == b"\x89PNG"
    parts = sorted((tmp_path / "scan" / "clips.parquet").iterdir())
    assert _main("scan_collection.py")([str(tmp_path), "--clips", "6", "--workers", "1"]) == 0
    assert sorted((tmp_path / "scan" / "clips.parquet").iterdir()) == parts
