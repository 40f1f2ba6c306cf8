"""``mjccd scan`` / :func:`mjccd.scan`: a tiled collection of the bundled CMU clips, damaged files and a jump
included; the same contacts as ``mjccd replay`` clip by clip; the same tables with 1 and 2 workers and on a local
Ray; resume after SIGKILL; refusals."""
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

pa = pytest.importorskip("pyarrow")

from mjccd import bvh, files  # noqa: E402
from mjccd.bench.collection import tile_collection  # noqa: E402
from mjccd.cli import main  # noqa: E402
from mjccd.collection import read_tables, scan  # noqa: E402
from mjccd.collection.tables import CLIPS, CONTACTS  # noqa: E402
from mjccd.errors import InputError, OutputError  # noqa: E402
from mjccd.replay import replay  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def collection(tmp_path_factory):
    """40 clips of 120 frames: 34 clean, 2 that jump, 4 damaged."""
    folder = tmp_path_factory.mktemp("collection") / "clips"
    paths = tile_collection(folder, 34, 120, damaged=4, jumps=2, seed=3)
    return folder, paths


@pytest.fixture(scope="module")
def scanned(collection, tmp_path_factory):
    """The collection scanned in this process (one worker)."""
    out = tmp_path_factory.mktemp("scan") / "one"
    return out, scan([collection[0]], out, workers=1, progress=False)


def test_every_clip_is_a_row_damaged_files_with_their_error(collection, scanned):
    _, paths = collection
    contacts, clips = scanned[1]
    rows = {r["clip"]: r for r in clips.to_pylist()}
    assert sorted(rows) == sorted(paths)
    for path, row in rows.items():
        name = Path(path).name
        if name.startswith("damaged"):
            assert row["error"] and path in row["error"] and row["frames"] is None, row
        else:
            assert row["error"] is None and row["frames"] == 120, row
            assert ("jump" in row["flags"]) == name.startswith("jump"), row
    assert set(contacts.column("clip").to_pylist()) <= {p for p in paths if "damaged" not in p}
    assert contacts.num_rows > 0 and clips.num_rows == 40


def test_flags_follow_their_thresholds(collection, scanned, tmp_path):
    _, clips = scanned[1]
    for row in clips.to_pylist():
        if row["error"] is None:
            assert ("self_penetration" in row["flags"]) == (row["longest_overlap_s"] >= 0.1)
            assert ("below_floor" in row["flags"]) == (row["max_floor_depth_m"] > 0.1)
            assert row["jump_frames"] == 0 or row["max_joint_turn_deg"] > 45.0
    # a lower depth flags the clips whose geoms sink that far
    clip = next(r for r in clips.to_pylist() if r["error"] is None and r["max_floor_depth_m"] > 0.01)
    _, low = scan([clip["clip"]], tmp_path / "low", workers=1, progress=False, floor_depth_m=0.01)
    assert low.to_pylist()[0]["flags"].count("below_floor") == 1


def test_same_contacts_as_replay_clip_by_clip(collection, scanned, tmp_path):
    contacts, _ = scanned[1]
    rows = contacts.to_pylist()
    for path in [p for p in collection[1] if "damaged" not in p]:  # every clip that can be scanned
        xml, _, _, _ = bvh.import_bvh(path, bounds=True)
        model = tmp_path / (Path(path).stem + ".xml")
        model.write_text(xml)
        with pytest.warns(UserWarning, match="self-collisions"):
            result = replay(model, path, progress=False, render=False)
        expected = [(c["frame"], c["time"], c["geoms"], c["bodies"], c["point"], c["normal"]) for c in result.contacts]
        got = [(r["frame"], r["time"], [r["part_a"], r["part_b"]], [r["body_a"], r["body_b"]],
                [r["px"], r["py"], r["pz"]], [r["nx"], r["ny"], r["nz"]])
               for r in rows if r["clip"] == path and r["kind"] == "first"]
        assert sorted(got, key=repr) == sorted(expected, key=repr)
        runs = [r for r in rows if r["clip"] == path and r["kind"] == "continuing"]
        assert all(r["px"] is None and r["last_frame"] >= r["frame"] for r in runs)


def test_two_workers_give_the_same_tables(collection, scanned, tmp_path):
    two = scan([collection[0]], tmp_path / "two", workers=2, progress=False)
    assert two[0].equals(scanned[1][0]) and two[1].equals(scanned[1][1])


def test_ray_gives_the_same_tables(collection, scanned, tmp_path):
    pytest.importorskip("ray")
    on_ray = scan([collection[0]], tmp_path / "ray", workers=2, engine="ray", progress=False)
    assert on_ray[0].equals(scanned[1][0]) and on_ray[1].equals(scanned[1][1])


def test_a_second_run_scans_nothing_again(collection, scanned):
    out, (contacts, clips) = scanned
    before = sorted(os.listdir(out / CLIPS))
    from mjccd.collection import ScanReport

    report = ScanReport()
    again = scan([collection[0]], out, workers=1, progress=False, report=report)
    assert report.scanned == 0 and report.done_before == 40 and sorted(os.listdir(out / CLIPS)) == before
    assert again[0].equals(contacts) and again[1].equals(clips)


def test_resume_after_sigkill_loses_and_repeats_nothing(collection, scanned, tmp_path):
    out = tmp_path / "killed"
    command = [sys.executable, "-m", "mjccd", "scan", str(collection[0]), "-o", str(out), "--workers", "1",
               "--batch", "1"]
    proc = subprocess.Popen(command, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, cwd=ROOT)
    try:
        deadline = time.monotonic() + 300
        while time.monotonic() < deadline and proc.poll() is None:
            if (out / CLIPS).is_dir() and len([n for n in os.listdir(out / CLIPS) if not n.startswith(".")]) >= 3:
                break
            time.sleep(0.005)
        proc.send_signal(signal.SIGKILL)
    finally:
        proc.wait()
    done = [n for n in os.listdir(out / CLIPS) if not n.startswith(".")]
    assert 3 <= len(done) < 40
    assert subprocess.run(command, capture_output=True, cwd=ROOT).returncode == 0
    contacts, clips = read_tables(out)
    assert clips.num_rows == 40 and len(set(clips.column("key").to_pylist())) == 40
    assert contacts.equals(scanned[1][0]) and clips.equals(scanned[1][1])


def test_unfinished_parts_are_dropped_when_a_run_starts(collection, scanned, tmp_path):
    out = tmp_path / "orphan"
    scan([collection[1][0]], out, workers=1, progress=False)
    stray = out / CONTACTS / "part-orphan.parquet"
    stray.write_bytes((out / CONTACTS / os.listdir(out / CONTACTS)[0]).read_bytes())
    (out / CLIPS / ".part-x.parquet.tmp.part").write_bytes(b"half")
    contacts, clips = read_tables(out)
    assert clips.num_rows == 1  # the reader skips it already
    scan([collection[1][0]], out, workers=1, progress=False)
    assert not stray.exists() and not (out / CLIPS / ".part-x.parquet.tmp.part").exists()


def test_two_runs_at_once_and_other_settings_are_refused(collection, tmp_path):
    out = tmp_path / "busy"
    out.mkdir()
    lock = files.lock_folder(out)
    try:
        with pytest.raises(OutputError, match="another run"):
            scan([collection[1][0]], out, workers=1, progress=False)
    finally:
        files.unlock_folder(out, lock)
    scan([collection[1][0]], out, workers=1, progress=False)
    with pytest.raises(OutputError, match="jump_deg"):
        scan([collection[1][0]], out, workers=1, progress=False, jump_deg=10.0)


def test_qpos_clips_of_a_model(tmp_path):
    model = ROOT / "models" / "boxing.xml"
    with np.load(ROOT / "data" / "boxing_traj.npz") as data:
        qpos, time_ = data["qpos"], data["time"]
    for k in range(2):
        np.savez(tmp_path / f"part{k}.npz", qpos=qpos[200 * k:200 * k + 150], time=time_[200 * k:200 * k + 150])
    (tmp_path / "broken.npz").write_bytes(b"not a zip file")
    contacts, clips = scan([str(tmp_path / "*.npz")], tmp_path / "out", model=model, workers=1, progress=False)
    rows = {Path(r["clip"]).name: r for r in clips.to_pylist()}
    assert "npz" in rows["broken.npz"]["error"] and rows["part0.npz"]["frames"] == 150
    expected = replay(model, tmp_path / "part1.npz", progress=False, render=False).contacts
    got = [r for r in contacts.to_pylist() if r["clip"].endswith("part1.npz") and r["kind"] == "first"]
    assert [(r["frame"], r["time"], [r["body_a"], r["body_b"]]) for r in got] == \
        [(c["frame"], c["time"], c["bodies"]) for c in expected]


def test_bad_sources_and_options_are_refused(tmp_path, collection, capsys):
    with pytest.raises(InputError, match="no such file"):
        scan([tmp_path / "missing"], tmp_path / "o", progress=False)
    (tmp_path / "a.npz").write_bytes(b"x")
    with pytest.raises(InputError, match="--model"):
        scan([tmp_path / "a.npz"], tmp_path / "o", progress=False)
    with pytest.raises(InputError, match="engine"):
        scan([collection[1][0]], tmp_path / "o", engine="spark", progress=False)
    with pytest.raises(InputError, match="jump_deg"):
        scan([collection[1][0]], tmp_path / "o", jump_deg=float("nan"), progress=False)
    assert main(["scan", str(tmp_path / "missing"), "-o", str(tmp_path / "o")]) == 2
    assert "no such file or folder" in capsys.readouterr().err


def test_command_line_summary(collection, tmp_path, capsys):
    assert main(["scan", collection[1][0], collection[1][-1], "-o", str(tmp_path / "cli"), "--workers", "1"]) == 0
    out = capsys.readouterr().out
    assert "2 clips found: 2 scanned now" in out and "clips.parquet" in out


def test_a_clip_with_the_bytes_of_another_is_scanned_once(collection, tmp_path):
    from mjccd.collection import ScanReport

    copy = tmp_path / "copy.bvh"
    copy.write_bytes(Path(collection[1][0]).read_bytes())
    report = ScanReport()
    _, clips = scan([collection[1][0], copy], tmp_path / "o", workers=1, progress=False, report=report)
    assert clips.num_rows == 1 and report.repeats == [str(copy)]


def test_ray_missing_is_named(collection, tmp_path, monkeypatch):
    monkeypatch.setitem(sys.modules, "ray", None)  # import ray raises ImportError
    with pytest.raises(InputError, match=r"mjccd\[ray\]"):
        scan([collection[1][0]], tmp_path / "o", engine="ray", workers=1, progress=False)
    assert not (tmp_path / "o").exists()  # refused before the folder is made


def test_a_per_frame_check_finds_nothing_the_scan_missed(collection):
    """MuJoCo's own distance on every frame of every checked pair: no overlap outside the scan's runs."""
    from mjccd.bench.scan import miss_counts

    for path in [p for p in collection[1] if "clip_" in p][:2]:
        counts = miss_counts(path)
        assert counts["discrete_only"] == 0 and counts["frames"] == 120
        assert counts["contacts_every"] <= counts["contacts"] and counts["runs_third"] <= counts["runs_every"]


def test_bench_scan_quick_writes_its_section(tmp_path, capsys):
    from mjccd.bench.scan import main as bench

    target = tmp_path / "bench.md"
    assert bench(["--quick", "--clips", "3", "--frames", "130", "--miss-clips", "1", "--no-ray",
                  "--markdown", str(target)]) == 0
    text = target.read_text()
    assert "<!-- bench scan: begin -->" in text and "| process pool | 2 |" in text and "only continuous" in text


def test_tables_as_pandas(scanned):
    pytest.importorskip("pandas")
    contacts, clips = read_tables(scanned[0], pandas=True)
    assert len(clips) == 40 and list(contacts.columns) == scanned[1][0].column_names
    assert contacts["px"].isna().sum() == sum(r["kind"] == "continuing" for r in scanned[1][0].to_pylist())
