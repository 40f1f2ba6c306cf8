"""Replay reads long trajectories piece by piece: same results and files, same refusals, bounded memory."""
import io
import pathlib
import tracemalloc
import types
import zipfile

import numpy as np
import pytest

from mjccd import files, npz_stream, replay
from mjccd.mujoco import ModelAdapter

ROOT = pathlib.Path(__file__).resolve().parents[1]
MODEL = ROOT / "models" / "boxing.xml"
TRAJ = ROOT / "data" / "boxing_traj.npz"
FRAMES = 30_000   # the long trajectory: the bundled clip forwards and backwards, 12.5 times


def _tiled(frames):
    """(qpos, time) of the bundled boxing clip played forwards, backwards, forwards, ... (no jump), at 120 Hz."""
    with np.load(TRAJ) as d:
        clip = d["qpos"]
    period = np.concatenate([clip, clip[::-1]])
    return period[np.arange(frames) % len(period)], np.arange(frames) / 120.0


def _period():
    """Frame intervals in one forwards-and-backwards period of the tiled clip (the last one does not move)."""
    with np.load(TRAJ) as d:
        return 2 * len(d["qpos"])


@pytest.fixture(scope="module")
def boxing_model():
    return replay.load_model(MODEL)


@pytest.fixture(scope="module")
def long_traj(tmp_path_factory):
    path = tmp_path_factory.mktemp("long") / "long.npz"
    qpos, time = _tiled(FRAMES)
    np.savez(path, qpos=qpos, time=time)
    return path


def _replay(traj, out, **chunks):
    """replay() with its timing clock stopped, so that contacts.json is the same from run to run."""
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(replay, "_time", types.SimpleNamespace(perf_counter=lambda: 0.0))
        result = replay.replay(MODEL, traj, "rigid", out, progress=False, render=False, **chunks)
    files = {name: (out / name).read_bytes() for name in ("contacts.json", "contacts.csv", "timeline.png")}
    return result, files


@pytest.fixture(scope="module")
def small_and_whole(long_traj, tmp_path_factory):
    """The long replay read 1,000 frames at a time in chunks of 37, and read and run as one chunk."""
    small = _replay(long_traj, tmp_path_factory.mktemp("small"), read_frames=1000, chunk_frames=37)
    whole = _replay(long_traj, tmp_path_factory.mktemp("whole"), read_frames=FRAMES, chunk_frames=FRAMES)
    return small, whole


def test_small_chunks_and_one_chunk_agree(small_and_whole):
    (small, small_files), (whole, whole_files) = small_and_whole
    assert small.n_frames == whole.n_frames == FRAMES
    assert len(whole.contacts) > 100
    assert small.contacts == whole.contacts
    # geoms mode: 729 pairs of the two boxers' geoms and each of their 54 geoms against the floor
    assert small.counters == whole.counters and whole.counters["pairs"] == (729 + 54) * (FRAMES - 1)
    assert small.overlaps == whole.overlaps and small.frames_in_contact == whole.frames_in_contact
    assert small.time_range == whole.time_range == (0.0, (FRAMES - 1) / 120.0)
    assert replay.summary(small) == replay.summary(whole)
    for name, data in whole_files.items():
        assert small_files[name] == data, name   # byte for byte


def test_long_replay_repeats_the_clip(small_and_whole, tmp_path):
    """Every frame interval is replayed once: the long run is the first period's run over and over."""
    (small, _), _ = small_and_whole
    qpos, time = _tiled(FRAMES)
    period = _period()
    one = tmp_path / "one.npz"
    np.savez(one, qpos=qpos[:period + 1], time=time[:period + 1])
    ref = replay.replay(MODEL, one, "rigid", None, progress=False)
    repeats = -(-(FRAMES - 1) // period)
    expected = np.tile(ref.in_contact, (repeats, 1))[:FRAMES - 1]
    np.testing.assert_array_equal(small.in_contact, expected)
    shifted = [(c["frame"] % period, c["toi"], c["geoms"], c["point"], c["normal"]) for c in small.contacts]
    tiled = [(c["frame"], c["toi"], c["geoms"], c["point"], c["normal"])
             for k in range(repeats) for c in ref.contacts if k * period + c["frame"] < FRAMES - 1]
    assert shifted == tiled
    for c in small.contacts:
        assert time[c["frame"]] <= c["time"] <= time[c["frame"] + 1]


def test_per_frame_arrays_are_made_on_use(tmp_path):
    qpos, time = _tiled(3000)
    path = tmp_path / "t.npz"
    np.savez(path, qpos=qpos, time=time)
    res = replay.replay(MODEL, path, "rigid", None, progress=False, read_frames=500)
    assert "time" not in vars(res) and "in_contact" not in vars(res)   # nothing per frame kept
    np.testing.assert_array_equal(res.time, time)                      # read back from the file
    flags = res.in_contact
    assert flags.shape == (2999, 729 + 54) and flags.any()
    assert int(flags.any(axis=1).sum()) == res.frames_in_contact
    assert int(flags.any(axis=0).sum()) == len(res.overlaps)
    for p, runs in res.overlaps.items():
        for first, last, t_first, t_end in runs:
            assert flags[first:last + 1, p].all() and t_first == time[first] and t_end == time[last + 1]
            assert first == 0 or not flags[first - 1, p]
            assert last == 2998 or not flags[last + 1, p]


def test_reading_keeps_a_few_frames_in_memory(long_traj, boxing_model):
    """Opening (every frame checked) and reading it through holds about two reads, not the 42 MB of qpos."""
    tracemalloc.start()
    try:
        trajectory = replay.Trajectory(long_traj, boxing_model, read_frames=1000)
        frames = sum(len(qpos) for _, qpos, _ in trajectory.chunks())
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    assert frames == trajectory.n_frames == FRAMES
    whole = FRAMES * boxing_model.nq * 8
    assert peak < whole / 4, f"peak {peak / 2**20:.1f} MB while reading {whole / 2**20:.1f} MB of qpos"


def _refused(path, match, monkeypatch):
    """replay() refuses ``path`` with ``match`` before any frame interval is checked."""
    def no_work(*args, **kwargs):
        raise AssertionError("a frame was replayed before the trajectory was refused")

    monkeypatch.setattr(ModelAdapter, "check", no_work)
    with pytest.raises(replay.ReplayError) as info:
        replay.replay(MODEL, path, progress=False, render=False)
    assert str(info.value) == f"{path}: {match}"
    with pytest.raises(replay.ReplayError) as again:   # the whole-array API says the same
        replay.load_trajectory(path, replay.load_model(MODEL))
    assert str(again.value) == str(info.value)


@pytest.mark.parametrize("save", [np.savez, np.savez_compressed], ids=["stored", "deflated"])
def test_nan_in_a_later_chunk(tmp_path, monkeypatch, save):
    qpos, time = _tiled(32_000)
    qpos[30_000, 50] = np.nan
    save(tmp_path / "nan.npz", qpos=qpos, time=time)
    _refused(tmp_path / "nan.npz", "qpos[30000, 50] = nan (frame 30000, joint 'a_Spine1') is not a finite number",
             monkeypatch)


def test_first_problem_in_check_qpos_order(tmp_path, monkeypatch, boxing_model):
    qpos, time = _tiled(32_000)
    # a zero quaternion before a NaN: the NaN is the one reported (check_qpos's order)
    nan = qpos.copy()
    nan[30_000, 50] = np.nan
    nan[20_000, 7:11] = 0.0
    np.savez(tmp_path / "both.npz", qpos=nan, time=time)
    _refused(tmp_path / "both.npz", "qpos[30000, 50] = nan (frame 30000, joint 'a_Spine1') is not a finite number",
             monkeypatch)
    # two zero quaternions: the first joint that has one, not the first frame
    last = boxing_model.jnt_qposadr[boxing_model.njnt - 1]   # the last ball joint of boxer b
    zero = qpos.copy()
    zero[10_000, last:last + 4] = 0.0
    zero[31_000, 7:11] = 0.0
    np.savez(tmp_path / "zero.npz", qpos=zero, time=time)
    _refused(tmp_path / "zero.npz", "qpos[31000, 7:11] (frame 31000): the quaternion of ball joint 'a_LeftUpLeg' "
             "is zero (norm 0); MuJoCo would silently make it the identity", monkeypatch)


def test_bad_time_in_a_later_chunk(tmp_path, monkeypatch):
    qpos, time = _tiled(32_000)
    step = replay.READ_FRAMES
    repeat = time.copy()
    repeat[2 * step] = repeat[2 * step - 1]   # across the boundary of two reads
    np.savez(tmp_path / "repeat.npz", qpos=qpos, time=repeat)
    _refused(tmp_path / "repeat.npz", f"time must increase, but time[{2 * step}] <= time[{2 * step - 1}]",
             monkeypatch)
    repeat[31_000] = np.inf                   # a time beyond the limit comes first, wherever it is
    np.savez(tmp_path / "inf.npz", qpos=qpos, time=repeat)
    _refused(tmp_path / "inf.npz", "time[31000] = inf must be finite and within ±1e+12 s", monkeypatch)


def test_damaged_member_is_reported_before_bad_values(tmp_path, monkeypatch):
    """As numpy.load read every array first: a damaged 'time' outranks a NaN in 'qpos'."""
    qpos, time = _tiled(32_000)
    qpos[30_000, 50] = np.nan
    buffer = io.BytesIO()
    np.savez(buffer, qpos=qpos, time=time)
    data = bytearray(buffer.getvalue())
    at = zipfile.ZipFile(io.BytesIO(bytes(data))).getinfo("time.npy").header_offset
    names, extra = int.from_bytes(data[at + 26:at + 28], "little"), int.from_bytes(data[at + 28:at + 30], "little")
    data[at + 30 + names + extra + 128 + 8 * 31_000] ^= 0x40   # a stored member: the .npy header is 128 bytes
    (tmp_path / "crc.npz").write_bytes(bytes(data))
    _refused(tmp_path / "crc.npz", "damaged or truncated .npz archive (Bad CRC-32 for file 'time.npy')", monkeypatch)


ARRAYS = {
    "rows": np.arange(3000 * 7, dtype=np.float64).reshape(3000, 7),
    "fortran": np.asfortranarray(np.arange(500 * 3, dtype=np.float32).reshape(500, 3)),
    "bigendian": np.arange(40_000, dtype=">i8"),
    "cube": np.arange(2 * 3 * 4, dtype=np.uint16).reshape(2, 3, 4),
    "scalar": np.float64(2.5),
    "empty": np.zeros((0, 4)),
    "strings": np.array(["a", "bc"]),
}


@pytest.mark.parametrize("save", [np.savez, np.savez_compressed], ids=["stored", "deflated"])
def test_members_read_as_numpy_reads_them(tmp_path, save):
    path = tmp_path / "a.npz"
    save(path, **ARRAYS)
    with np.load(path) as expected, npz_stream.open_npz(path) as npz:
        for name in ARRAYS:
            with npz_stream.Member(npz, name) as member:
                whole = member.read()
            assert whole.dtype == expected[name].dtype and whole.shape == expected[name].shape
            np.testing.assert_array_equal(whole, expected[name])
            if np.ndim(expected[name]) >= 1:
                for n in (1, 333, 10**6):
                    with npz_stream.Member(npz, name) as member:
                        pieces = list(member.rows(n))
                    assert all(len(p) <= n for p in pieces)
                    joined = np.concatenate(pieces) if pieces else np.zeros((0,))
                    np.testing.assert_array_equal(joined.reshape(expected[name].shape), expected[name])


def test_plot_thins_only_long_rows():
    runs = [(float(k), k + 0.5) for k in range(10)]
    assert replay._thin_runs(runs, 1.0) == runs               # few runs: drawn as they are
    many = [(k * 0.1, k * 0.1 + 0.05) for k in range(3 * replay.PLOT_BARS)]
    thinned = replay._thin_runs(many, 0.2)
    assert len(thinned) == 1 and thinned[0] == (0.0, many[-1][1])
    spread = [(k * 1.0, k + 0.5) for k in range(replay.PLOT_BARS + 1)]
    assert replay._thin_runs(spread, 0.4) == spread           # gaps wider than a bar: nothing joined
    times = list(np.arange(3 * replay.PLOT_BARS) * 0.1)
    few, many = replay._ThinTimes(1.0), replay._ThinTimes(0.25)
    for x in times[:10]:
        few.add(x)
    assert few.kept == times[:10]                             # few times: all drawn
    for x in times:
        many.add(x)
    greedy = times[:1]
    for x in times[1:]:
        greedy += [x] if x - greedy[-1] >= 0.25 else []
    assert many.kept == greedy and len(greedy) == replay.PLOT_BARS   # as thinning the whole row at once


def test_rendered_frames_are_highlights_with_their_rows(tmp_path, monkeypatch):
    """render_frames is handed the highlights: the first contact of each body pair between the boxers, then a
    foot strike, each with the qpos rows of its interval (the replay keeps no whole qpos); drawn, each frame
    is captioned with its frame, time and pair."""
    qpos, time = _tiled(3000)
    path = tmp_path / "t.npz"
    np.savez(path, qpos=qpos, time=time)
    handed = {}

    def record(model, highlights, folder, bounds):
        handed["highlights"] = highlights

    monkeypatch.setattr(replay, "render_frames", record)
    result = replay.replay(MODEL, path, "rigid", tmp_path / "out", progress=False, read_frames=700, chunk_frames=50)
    chosen = handed["highlights"]
    assert len(chosen) == 4 and [c["time"] for c, _, _ in chosen] == sorted(c["time"] for c, _, _ in chosen)
    on_floor = [c for c, _, _ in chosen if c["bodies"][1] == "world"]
    between = [frozenset(c["bodies"]) for c, _, _ in chosen if c["bodies"][1] != "world"]
    assert len(on_floor) == 1 and len(set(between)) == len(between) == 3
    firsts = {}
    for c in result.contacts:
        firsts.setdefault(frozenset(c["bodies"]), c)
    assert all(firsts[frozenset(c["bodies"])] == c for c, _, _ in chosen if c["bodies"][1] != "world")
    for c, q0, q1 in chosen:
        np.testing.assert_array_equal(q0, qpos[c["frame"]])
        np.testing.assert_array_equal(q1, qpos[c["frame"] + 1])
    text = replay.caption(chosen[0][0])
    assert text.startswith(f"frame {chosen[0][0]['frame']}, t = ") and " / " in text


def test_frames_are_drawn_with_their_captions(tmp_path, monkeypatch, boxing_model):
    """Without OpenGL here, a stand-in renderer: each highlight becomes one PNG, and the touching geoms are red
    while it is drawn (the model's colours restored after)."""
    from mjccd.mujoco import render

    seen = []

    class Canvas:
        def update_scene(self, data, camera, scene_option):
            seen.append((boxing_model.geom_rgba.copy(), camera.distance))

        def render(self):
            return np.zeros((48, 64, 3), dtype=np.uint8)

        def close(self):
            pass

    monkeypatch.setattr(render, "open_renderer", lambda model: Canvas())
    before = boxing_model.geom_rgba.copy()
    contact = {"frame": 3, "time": 0.025, "toi": 0.2, "geoms": ["a_RightForeArm_limb0", "b_LeftArm_limb0"],
               "labels": ["a_RightForeArm", "b_LeftArm"], "bodies": ["a_RightForeArm", "b_LeftArm"]}
    folder = files.OutputFolder(tmp_path / "frames", "replay", patterns=replay.OUTPUT_PATTERNS)
    with folder:
        replay.render_frames(boxing_model, [(contact, boxing_model.qpos0, boxing_model.qpos0)], folder)
    assert (tmp_path / "frames" / "frame_00003.png").read_bytes()[:4] == b"\x89PNG"
    colours, distance = seen[0]
    red = [g for g in range(boxing_model.ngeom) if tuple(colours[g]) == pytest.approx((0.9, 0.1, 0.1, 0.8))]
    assert sorted(boxing_model.geom(g).name for g in red) == ["a_RightForeArm_limb0", "b_LeftArm_limb0"]
    assert 1.0 < distance < 10.0
    np.testing.assert_array_equal(boxing_model.geom_rgba, before)
