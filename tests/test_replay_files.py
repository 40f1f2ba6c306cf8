"""``mjccd replay --out``: used folders, --force, nothing partial after an error or Ctrl-C."""
import fcntl
import json
import os
import pty
import re
import select
import signal
import struct
import subprocess
import sys
import termios
import time

import numpy as np
import pytest

from mjccd import replay
from mjccd.files import MANIFEST, STAGING, OutputFolder
from mjccd.mujoco import ModelAdapter
from mjccd.mujoco.geoms import GeomChecker

from test_replay import FIRST, LAST, MODEL, ROOT, TRAJ, short_traj  # noqa: F401 (the fixture)

REPORTS = ["contacts.csv", "contacts.json", "timeline.png"]


def _earlier_run(folder):
    """A folder as an earlier replay left it (more frames than this one), plus a file of the user's."""
    folder.mkdir()
    stale = ["contacts.json", "contacts.csv", "timeline.png", "frame_00007.png", "frame_00900.png"]
    for name in stale:
        (folder / name).write_text("from an earlier run\n")
    (folder / "frame_00005.png").write_text("an earlier frame before manifests\n")
    (folder / MANIFEST).write_text(json.dumps({"tool": "replay", "files": stale}) + "\n")
    (folder / "notes.txt").write_text("the user's own file\n")


def test_used_folder_is_refused_without_force(tmp_path, capsys, short_traj):
    out = tmp_path / "out"
    _earlier_run(out)
    before = {p.name: p.read_text() for p in out.iterdir()}
    assert replay.main([str(MODEL), str(short_traj), "--out", str(out), "--no-render"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and str(out) in err[0] and "--force" in err[0]
    assert {p.name: p.read_text() for p in out.iterdir()} == before


def test_force_replaces_the_earlier_run(tmp_path, capsys, short_traj):
    out = tmp_path / "out"
    _earlier_run(out)
    assert replay.main([str(MODEL), str(short_traj), "--out", str(out), "--no-render", "--force"]) == 0
    assert "wrote" in capsys.readouterr().out
    assert sorted(os.listdir(out)) == sorted(REPORTS + [MANIFEST, "notes.txt"])  # no stale frame left
    manifest = json.loads((out / MANIFEST).read_text())
    assert manifest["tool"] == "replay" and sorted(manifest["files"]) == REPORTS
    assert json.loads((out / "contacts.json").read_text())["frames"] == LAST - FIRST
    assert (out / "notes.txt").read_text() == "the user's own file\n"
    # its own earlier run is refused too, and replaced with --force
    assert replay.main([str(MODEL), str(short_traj), "--out", str(out), "--no-render"]) == 2
    assert replay.main([str(MODEL), str(short_traj), "--out", str(out), "--no-render", "--force"]) == 0


def test_failed_write_leaves_nothing(tmp_path, capsys, monkeypatch, short_traj):
    def disk_full(result, target):
        target.write(b"\x89PNG half a plot")
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(replay, "plot_timeline", disk_full)
    out = tmp_path / "out"
    assert replay.main([str(MODEL), str(short_traj), "--out", str(out), "--no-render"]) == 2
    message = capsys.readouterr().err.strip().splitlines()[-1]  # after the progress bar
    assert message == f"mjccd replay: {out}: cannot write: No space left on device"
    assert not out.exists()
    assert os.listdir(tmp_path) == []


@pytest.mark.parametrize("checker, mode", [(GeomChecker, "geoms"), (ModelAdapter, "ellipsoids")])
def test_ctrl_c_stops_between_chunks(tmp_path, monkeypatch, short_traj, checker, mode):
    """A SIGINT inside a chunk lets the chunk finish, then stops the replay before any file is written."""
    stepped = []
    step = checker.check

    def step_and_press_ctrl_c(self, *args, **kwargs):
        stepped.append(1)
        if len(stepped) == 6:
            os.kill(os.getpid(), signal.SIGINT)
        return step(self, *args, **kwargs)

    monkeypatch.setattr(checker, "check", step_and_press_ctrl_c)
    out = tmp_path / "out"
    with pytest.raises(KeyboardInterrupt):
        replay.replay(MODEL, short_traj, "rigid", out, progress=False, render=False, chunk_frames=4, mode=mode)
    assert len(stepped) == 8  # the second chunk (frames 4..7) ran to its end
    assert not out.exists()


def _long_trajectory(path, repeats):
    """The bundled boxing clip played forwards and backwards ``repeats`` times (no jump between the copies)."""
    with np.load(TRAJ) as d:
        qpos = d["qpos"]
    qpos = np.tile(np.concatenate([qpos, qpos[::-1]]), (repeats, 1))
    np.savez(path, qpos=qpos, time=np.arange(len(qpos)) / 120.0)


@pytest.mark.skipif(sys.platform == "win32", reason="SIGINT to a child process")
def test_sigint_ends_cleanly(tmp_path):
    """Ctrl-C while the frames run: 'mjccd: interrupted', exit 130, no traceback, no file written."""
    traj = tmp_path / "long.npz"
    _long_trajectory(traj, 32)  # about 77,000 frames: several seconds of work
    out = tmp_path / "out"
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")]))
    terminal, stderr = pty.openpty()  # the progress bar shows only on a terminal: stderr is one
    fcntl.ioctl(stderr, termios.TIOCSWINSZ, struct.pack("HHHH", 24, 100, 0, 0))  # 100 columns wide
    proc = subprocess.Popen([sys.executable, "-m", "mjccd", "replay", str(MODEL), str(traj), "--out", str(out),
                             "--no-render"], stdout=subprocess.DEVNULL, stderr=stderr, cwd=tmp_path, env=env)
    os.close(stderr)
    text = ""
    try:
        deadline = time.monotonic() + 60
        while not re.search(r"\| *[1-9]\d*/\d+ ", text):  # the progress bar counts frames
            assert proc.poll() is None, text
            assert time.monotonic() < deadline, "no progress within 60 s"
            text += _read_some(terminal)
        proc.send_signal(signal.SIGINT)
        code = proc.wait(timeout=30)
        text += _read_some(terminal)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
        os.close(terminal)
    assert code == 130, text
    assert text.rstrip().endswith("mjccd: interrupted"), text
    assert "Traceback" not in text and "SystemError" not in text
    assert sorted(os.listdir(tmp_path)) == ["long.npz"]  # no output folder, no temporary file


def _read_some(fd):
    """What a pseudo-terminal has to read within a moment ("" when nothing, or when its writer is gone)."""
    if not select.select([fd], [], [], 0.05)[0]:
        return ""
    try:
        return os.read(fd, 65536).decode(errors="replace")
    except OSError:  # the child closed its end
        return ""


def test_an_interrupted_forced_run_leaves_the_earlier_run_in_place(tmp_path, monkeypatch, short_traj):
    """--force replaces the earlier run only once the new one is complete: a Ctrl-C (or a failure) before that
    leaves every earlier file as it was, and no staging folder or lock behind."""
    out = tmp_path / "out"
    _earlier_run(out)
    before = {p.name: p.read_text() for p in out.iterdir()}

    def interrupted(*args, **kwargs):
        raise KeyboardInterrupt

    monkeypatch.setattr(replay, "write_reports", interrupted)
    with pytest.raises(KeyboardInterrupt):
        replay.replay(MODEL, short_traj, "rigid", out, force=True, progress=False, render=False)
    assert {p.name: p.read_text() for p in out.iterdir()} == before


def test_a_second_run_into_a_folder_in_use_is_refused(tmp_path, capsys, short_traj):
    """While one run holds the folder (its lock), another is refused at once, even with --force, and deletes
    nothing; a staging folder a killed run left behind is removed by the next run."""
    out = tmp_path / "out"
    _earlier_run(out)
    before = {p.name: p.read_text() for p in out.iterdir()}
    with pytest.raises(InterruptedError):  # the holder is itself abandoned: it writes nothing either
        with OutputFolder(out, "replay", force=True, patterns=replay.OUTPUT_PATTERNS):
            assert replay.main([str(MODEL), str(short_traj), "--out", str(out), "--no-render", "--force"]) == 2
            err = capsys.readouterr().err
            assert "another run is writing into this folder" in err and str(out) in err
            raise InterruptedError
    assert {p.name: p.read_text() for p in out.iterdir()} == before
    (out / (STAGING + "killed")).mkdir()
    (out / (STAGING + "killed") / "contacts.json").write_text("half")
    assert replay.main([str(MODEL), str(short_traj), "--out", str(out), "--no-render", "--force"]) == 0
    assert sorted(os.listdir(out)) == sorted(REPORTS + [MANIFEST, "notes.txt"])
