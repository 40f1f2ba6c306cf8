"""Replay end to end on a short piece of the boxing scene (geoms mode, the default, and ellipsoid mode), and
clear errors on bad input."""
import csv
import json
import pathlib

import mujoco
import numpy as np
import pytest

from mjccd import Ellipsoid, Plane, Rigid, first_contact, plane_first_contact, replay
from mjccd.mujoco import ModelAdapter, State
from mjccd.quadric import matrix_to_quat

ROOT = pathlib.Path(__file__).resolve().parents[1]
MODEL = ROOT / "models" / "boxing.xml"
TRAJ = ROOT / "data" / "boxing_traj.npz"
FIRST, LAST = 136, 150   # frames of the bundled trajectory around the first glove contacts
ELLIPSOIDS, PAIRS = 94, 46 * 48  # the bounds of models/boxing.xml: the default fit within 1 cm


@pytest.fixture(scope="module")
def short_traj(tmp_path_factory):
    path = tmp_path_factory.mktemp("traj") / "short.npz"
    with np.load(TRAJ) as d:
        np.savez(path, qpos=d["qpos"][FIRST:LAST], time=d["time"][FIRST:LAST])
    return path


@pytest.fixture(scope="module")
def result(short_traj, tmp_path_factory):
    """Ellipsoid mode, boxer against boxer only."""
    out = tmp_path_factory.mktemp("out")
    return replay.replay(MODEL, short_traj, "rigid", out, progress=False, render=False, planes="none",
                         mode="ellipsoids"), out


@pytest.fixture(scope="module")
def floor_result(short_traj, tmp_path_factory):
    """The same replay with its default planes: every moving ellipsoid against the floor."""
    out = tmp_path_factory.mktemp("floor")
    return replay.replay(MODEL, short_traj, "rigid", out, progress=False, render=False, mode="ellipsoids"), out


@pytest.fixture(scope="module")
def geoms_result(short_traj, tmp_path_factory):
    """The default: the boxers' own geoms (their visual capsules, spheres and boxes) and the floor."""
    out = tmp_path_factory.mktemp("geoms")
    return replay.replay(MODEL, short_traj, "rigid", out, progress=False, render=False), out


def test_geoms_mode_is_the_default_and_checks_the_real_geoms(geoms_result):
    """Nothing in the boxing model collides, so its real geoms are its visual ones, never the group-5 bounds; in
    this piece the fists' capsules meet (the gloves) and feet land on the floor."""
    res, out = geoms_result
    model = replay.load_model(MODEL)
    assert res.mode == "geoms"
    kinds = {int(model.geom_type[g]) for g in res.geoms.geom_ids}
    assert mujoco.mjtGeom.mjGEOM_ELLIPSOID not in kinds or all(model.geom_group[g] != 5 for g in res.geoms.geom_ids)
    assert not any(model.geom_group[g] == 5 for g in res.geoms.geom_ids)
    on_floor = [c for c in res.contacts if c["bodies"][1] == "world"]
    gloves = [c for c in res.contacts if c["bodies"][1] != "world"]
    assert on_floor and all(c["geoms"][1] == "floor" and c["elements"][1] == "plane" for c in on_floor)
    assert all(("Toe" in c["bodies"][0] or "Foot" in c["bodies"][0]) for c in on_floor)
    fist = ("FingerBase", "HandIndex1", "Thumb")
    assert gloves and all(any(f in b for f in fist) for c in gloves for b in c["bodies"])
    assert all("certainty" not in c for c in res.contacts)
    doc = json.loads((out / "contacts.json").read_text())
    assert doc["mode"] == "geoms" and doc["geoms"] == res.parts and "ellipsoids" not in doc
    assert doc["counters"]["pairs"] == len(res.pairs) * (LAST - FIRST - 1)
    with open(out / "contacts.csv") as fh:
        rows = list(csv.DictReader(fh))
    assert len(rows) == len(res.contacts) and {r["geom_b"] for r in rows} > {"floor"}
    assert "55 geoms" in replay.summary(res)


def test_geom_contacts_agree_with_the_pairwise_geom_solver(geoms_result, short_traj):
    """Each first contact is the exact answer of mjccd.geoms for the two geoms' pose lerps, the poses from
    MuJoCo's own kinematics."""
    from mjccd.geoms import HalfSpace, geom_first_contact
    from mjccd.motion import Static

    res, _ = geoms_result
    model = replay.load_model(MODEL)
    qpos, _ = replay.load_trajectory(short_traj, model)
    data = mujoco.MjData(model)
    checker = res.geoms
    for c in res.contacts[:4]:
        k = c["frame"]
        a, b = (checker.labels_of_rows.index(n) for n in c["geoms"])
        g = int(checker.geom_ids[a])
        poses = []
        for q in qpos[k:k + 2]:
            data.qpos[:] = q
            mujoco.mj_kinematics(model, data)
            poses.append((data.geom_xpos[g].copy(), matrix_to_quat(data.geom_xmat[g].reshape(3, 3))))
        floor = int(checker.geom_ids[b])
        got = geom_first_contact(checker._shape(a), Rigid(*poses[0], *poses[1]), HalfSpace(),
                                 Static(model.geom_pos[floor], model.geom_quat[floor]))
        assert got is not None and got.certainty == "certified"
        assert abs(got.time - c["toi"]) < 1e-9
        np.testing.assert_allclose(got.point, c["point"], atol=1e-6)


def test_scene_layout():
    model = replay.load_model(MODEL)
    ellipsoids, pairs = replay.replay_ellipsoids(model)
    names = ellipsoids.geoms
    per_boxer = [sum(n.startswith(p) for n in names) for p in ("a_", "b_")]
    assert per_boxer == [46, 48]      # the default fit within 1 cm (models/build_boxing.py), 21 parts each
    assert len(pairs) == 46 * 48      # boxer against boxer only
    assert all(names[i].startswith("a_") and names[j].startswith("b_") for i, j in pairs)


def test_end_to_end(result):
    res, out = result
    assert res.n_frames == LAST - FIRST
    assert len(res.contacts) >= 3
    doc = json.loads((out / "contacts.json").read_text())
    assert doc["frames"] == LAST - FIRST and doc["pairs"] == PAIRS
    assert len(doc["first_contacts"]) == len(res.contacts)
    assert doc["counters"]["pairs"] == PAIRS * (LAST - FIRST - 1)
    assert doc["counters"]["sphere_culled"] > 0.9 * doc["counters"]["pairs"]
    with open(out / "contacts.csv") as fh:
        rows = list(csv.DictReader(fh))
    assert len(rows) == len(res.contacts)
    assert (out / "timeline.png").stat().st_size > 1000
    first = res.contacts[0]
    assert first["frame"] == 145 - FIRST
    assert first["bodies"] == ["a_RightForeArm", "b_LeftHand"]
    assert res.time[first["frame"]] <= first["time"] <= res.time[first["frame"] + 1]
    assert "a_RightForeArm_1 / b_LeftHand" in replay.contact_table(res)  # a body's several bounds are numbered
    assert "sphere_culled" in replay.summary(res)


def test_contact_agrees_with_pairwise_solver(result, short_traj):
    """Each first contact is the pairwise exact answer for the two geoms' rigid motions."""
    res, _ = result
    model = replay.load_model(MODEL)
    qpos, _ = replay.load_trajectory(short_traj, model)
    ell = res.ellipsoids
    data = mujoco.MjData(model)
    for c in res.contacts[:4]:
        k = c["frame"]
        i, j = (ell.geoms.index(n) for n in c["ellipsoids"])
        poses = []
        for q in qpos[k:k + 2]:  # the geoms' poses from MuJoCo's own kinematics
            data.qpos[:] = q
            mujoco.mj_kinematics(model, data)
            poses.append({e: (data.geom_xpos[g].copy(), matrix_to_quat(data.geom_xmat[g].reshape(3, 3)))
                          for e, g in ((i, model.geom(ell.geoms[i]).id), (j, model.geom(ell.geoms[j]).id))})
        got = first_contact(Ellipsoid(ell.radii[i]), Rigid(*poses[0][i], *poses[1][i]),
                            Ellipsoid(ell.radii[j]), Rigid(*poses[0][j], *poses[1][j]))
        assert got is not None and got.point is not None
        assert abs(got.time - c["toi"]) < 1e-9
        np.testing.assert_allclose(got.point, c["point"], atol=1e-6)


def test_the_floor_counts_by_default(floor_result, result, short_traj):
    """The boxers' floor is a visual geom MuJoCo never collides, yet replay checks every moving ellipsoid against
    it; each floor contact is the exact answer of the ellipsoid's rigid motion against the plane z <= 0."""
    res, out = floor_result
    model = replay.load_model(MODEL)
    ellipsoids, _ = replay.replay_ellipsoids(model)
    floor = model.geom("floor").id
    assert res.plane_pairs.tolist() == [[i, floor] for i in range(ELLIPSOIDS)]
    assert len(replay.replay_planes(model, ellipsoids, "mujoco")) == 0  # contype 0: not by MuJoCo's rules
    assert len(replay.replay_planes(model, ellipsoids, "none")) == 0
    doc = json.loads((out / "contacts.json").read_text())
    assert doc["pairs"] == PAIRS and doc["plane_pairs"] == ELLIPSOIDS
    assert doc["counters"]["pairs"] == (PAIRS + ELLIPSOIDS) * (LAST - FIRST - 1)
    on_floor = [c for c in res.contacts if c["bodies"][1] == "world"]
    assert on_floor and all(c["ellipsoids"][1] == "floor" and c["labels"][1] == "floor" for c in on_floor)
    assert [c for c in res.contacts if c["bodies"][1] != "world"] == result[0].contacts  # the pairs unchanged
    assert any(s["ellipsoids"][1] == "floor" for s in doc["in_contact"])
    assert f"{ELLIPSOIDS} ellipsoid-plane pairs" in replay.summary(res)
    qpos, _ = replay.load_trajectory(short_traj, model)
    data = mujoco.MjData(model)
    for c in on_floor[:4]:
        k, g = c["frame"], model.geom(c["ellipsoids"][0]).id
        poses = []
        for q in qpos[k:k + 2]:
            data.qpos[:] = q
            mujoco.mj_kinematics(model, data)
            poses.append((data.geom_xpos[g].copy(), matrix_to_quat(data.geom_xmat[g].reshape(3, 3))))
        got = plane_first_contact(Ellipsoid(model.geom_size[g]), Rigid(*poses[0], *poses[1]),
                                  Plane([0.0, 0.0, 1.0], 0.0))
        assert got is not None and abs(got.time - c["toi"]) < 1e-9
        np.testing.assert_allclose(got.point, c["point"], atol=1e-6)


def test_planes_option_is_checked(short_traj):
    with pytest.raises(ValueError, match="planes: expected one of all, mujoco, none, got 'floor'"):
        replay.replay(MODEL, short_traj, planes="floor", progress=False)


def test_affine_motion_runs(short_traj):
    res = replay.replay(MODEL, short_traj, "affine", None, progress=False)
    assert len(res.contacts) >= 1


def test_bad_inputs(tmp_path, short_traj):
    with pytest.raises(ValueError, match="model file not found"):
        replay.replay(tmp_path / "missing.xml", short_traj, progress=False)
    bad_xml = tmp_path / "bad.xml"
    bad_xml.write_text("<mujoco><worldbody><body></mujoco>")
    with pytest.raises(ValueError, match="not a valid MJCF model"):
        replay.replay(bad_xml, short_traj, progress=False)
    narrow = tmp_path / "narrow.npz"
    np.savez(narrow, qpos=np.zeros((5, 10)), time=np.arange(5.0))
    with pytest.raises(ValueError, match=r"qpos must have shape \(T, 174\) for this model, got \(5, 10\)"):
        replay.replay(MODEL, narrow, progress=False)
    noqpos = tmp_path / "noqpos.npz"
    np.savez(noqpos, q=np.zeros((5, 174)))
    with pytest.raises(ValueError, match="no 'qpos' array"):
        replay.replay(MODEL, noqpos, progress=False)
    with np.load(short_traj) as d:
        backwards = tmp_path / "backwards.npz"
        np.savez(backwards, qpos=d["qpos"], time=d["time"][::-1])
    with pytest.raises(ValueError, match="time must increase"):
        replay.replay(MODEL, backwards, progress=False)
    with pytest.raises(ValueError, match="motion: expected one of rigid, affine, chain"):
        replay.replay(MODEL, short_traj, "spline", progress=False)
    clip = ROOT / "data" / "mocap" / "cmu_13_18_boxing_first10s.bvh"
    with pytest.raises(ValueError, match=r"qpos must have shape \(T, 174\) for this model, got \(1200, 127\)"):
        replay.replay(MODEL, clip, progress=False)
    truncated = tmp_path / "cut.bvh"
    truncated.write_text("\n".join(clip.read_text().splitlines()[:-2]))
    with pytest.raises(ValueError, match="file truncated"):
        replay.replay(MODEL, truncated, progress=False)
    with pytest.raises(ValueError, match="unknown trajectory type"):
        replay.replay(MODEL, bad_xml, progress=False)


def test_cli_errors_are_one_line(tmp_path, capsys, short_traj):
    assert replay.main([str(tmp_path / "none.xml"), str(short_traj), "--no-render"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err == [f"mjccd replay: {tmp_path / 'none.xml'}: model file not found"]


def test_cli_runs(tmp_path, capsys, short_traj):
    assert replay.main([str(MODEL), str(short_traj), "--out", str(tmp_path), "--no-render"]) == 0
    text = capsys.readouterr().out
    assert "a_LeftToeBase / world" in text and "55 geoms" in text and "frames/s" in text
    assert (tmp_path / "contacts.json").exists()
    assert replay.main([str(MODEL), str(short_traj), "--out", str(tmp_path / "e"), "--no-render", "--mode",
                        "ellipsoids", "--planes", "none"]) == 0
    assert "a_RightForeArm_1 / b_LeftHand" in capsys.readouterr().out


def test_cli_renders_frames_at_floor_contacts_or_says_why_not(tmp_path, short_traj):
    """The command line draws the first contacts, a foot on the floor among them (in a fresh process: MUJOCO_GL is
    chosen before mujoco is imported), or says in one line that OpenGL is missing."""
    import subprocess
    import sys

    done = subprocess.run([sys.executable, "-m", "mjccd", "replay", str(MODEL), str(short_traj), "--out",
                           str(tmp_path), "--rows", "1"], capture_output=True, text=True, timeout=600)
    assert done.returncode == 0, done.stderr
    frames = sorted(tmp_path.glob("frame_*.png"))
    if frames:
        doc = json.loads((tmp_path / "contacts.json").read_text())
        drawn = {int(f.stem[6:]) for f in frames}
        assert drawn <= {c["frame"] + d for c in doc["first_contacts"] for d in (0, 1)}
        assert any(c["geoms"][1] == "floor" and c["frame"] in drawn for c in doc["first_contacts"])
    else:
        assert "rendering skipped: no OpenGL backend" in done.stderr


def test_arm_chain_frames_agree_with_whole_sweep(tmp_path):
    """tan(theta/2)-linear joints: a frame's chain contact lies on the whole sweep's interval."""
    arm = ROOT / "models" / "arm_obstacle.xml"
    with np.load(ROOT / "data" / "arm_traj.npz") as d:
        qpos, time, keys = d["qpos"], d["time"], d["keyframes"]
    piece = tmp_path / "piece.npz"
    np.savez(piece, qpos=qpos[48:53], time=time[48:53])
    res = replay.replay(arm, piece, "chain", None, progress=False)
    first = res.contacts[0]
    assert first["labels"] == ["b_4", "web"]
    model = replay.load_model(arm)
    checker = ModelAdapter(model, res.ellipsoids, res.pairs, "chain")
    rows = {tuple(r["pair"]): r for r in replay.interval_table(checker, keys[0], keys[1], repeat=0)}
    assert len(rows) == 27
    assert rows[("hand", "web")]["F_degree_t"] == 96
    t_in = rows[("b_4", "web")]["intervals"][0][0]
    assert abs(first["time"] - t_in * (time[-1] - time[0])) < 1e-9
    assert rows[("b_1", "web")]["intervals"] == []


def test_arm_sweep_intervals_match_the_static_test():
    """Inside every reported interval the two quadrics overlap; outside they do not."""
    from mjccd.motion import quadric_at
    from mjccd.quadric import static_status_matrices

    model = replay.load_model(ROOT / "models" / "arm_obstacle.xml")
    checker = ModelAdapter(model, *replay.replay_ellipsoids(model), "chain")
    with np.load(ROOT / "data" / "arm_traj.npz") as d:
        keys = d["keyframes"]
    rows = replay.interval_table(checker, keys[0], keys[1], repeat=0)
    motions = checker.motions(*(State(q, np.zeros((0, 3)), np.zeros((0, 4))) for q in keys[:2]))
    checked = 0
    for (i, j), row in zip(checker.pairs, rows):
        qa, qb = motions[i].quadric(checker.radii[i]), motions[j].quadric(checker.radii[j])

        def status(t):
            return static_status_matrices(quadric_at(*qa, t), quadric_at(*qb, t))

        for t_in, t_out in row["intervals"]:
            for t in np.linspace(t_in, t_out, 9)[1:-1]:
                assert status(t) == -1, (row["pair"], t)
            assert status(t_in - 1e-6) != -1 and status(t_out + 1e-6) != -1, row["pair"]
            assert status(t_in - 1e-3) == 1 and status(t_out + 1e-3) == 1, row["pair"]
            checked += 1
    assert checked == 7


@pytest.mark.parametrize("motion, mode", [("rigid", None), ("rigid", "ellipsoids"), ("affine", None)])
def test_chunks_give_the_same_result(short_traj, motion, mode):
    """Chunks of 4 frames (the plane cache carried across) find what one chunk of all frames finds."""
    whole = replay.replay(MODEL, short_traj, motion, None, progress=False, chunk_frames=LAST - FIRST, mode=mode)
    chunked = replay.replay(MODEL, short_traj, motion, None, progress=False, chunk_frames=4, mode=mode)
    assert chunked.contacts == whole.contacts and len(whole.contacts) >= 1
    assert chunked.counters == whole.counters
    assert (whole.counters["cached_plane"] > 0) == (whole.mode == "ellipsoids")
    np.testing.assert_array_equal(chunked.in_contact, whole.in_contact)


def test_chain_chunks_give_the_same_result(tmp_path):
    with np.load(ROOT / "data" / "arm_traj.npz") as d:
        piece = tmp_path / "piece.npz"
        np.savez(piece, qpos=d["qpos"][46:53], time=d["time"][46:53])
    arm = ROOT / "models" / "arm_obstacle.xml"
    whole = replay.replay(arm, piece, "chain", None, progress=False, chunk_frames=6)
    chunked = replay.replay(arm, piece, "chain", None, progress=False, chunk_frames=1)
    assert chunked.contacts == whole.contacts and len(whole.contacts) >= 1
    assert chunked.counters == whole.counters
    np.testing.assert_array_equal(chunked.in_contact, whole.in_contact)


def test_trajectory_refusals_name_frame_and_joint(tmp_path):
    """Values MuJoCo would silently change or drop are refused, not replayed."""
    with np.load(TRAJ) as d:
        qpos, time = d["qpos"][FIRST:FIRST + 4].copy(), d["time"][FIRST:FIRST + 4]
    cases = []
    zero = qpos.copy()
    zero[2, 90:94] = 0.0
    cases.append((zero, r"qpos\[2, 90:94\] \(frame 2\): the quaternion of free joint 'b_Hips_root' is zero"))
    cases.append((qpos + 1e-3j, "qpos holds complex numbers"))
    far = qpos.copy()
    far[1, 0] = 1e300
    cases.append((far, r"qpos\[1, 0\] = 1e\+300 \(frame 1, joint 'a_Hips_root'\) is beyond"))
    for k, (values, message) in enumerate(cases):
        path = tmp_path / f"bad{k}.npz"
        np.savez(path, qpos=values, time=time)
        with pytest.raises(replay.ReplayError, match=f"bad{k}.npz: {message}"):
            replay.replay(MODEL, path, progress=False)
    cut = tmp_path / "cut.npz"
    np.savez(tmp_path / "whole.npz", qpos=qpos, time=time)
    cut.write_bytes((tmp_path / "whole.npz").read_bytes()[:-30])
    with pytest.raises(replay.ReplayError, match="cut.npz: damaged or truncated .npz archive"):
        replay.replay(MODEL, cut, progress=False)


def test_huge_ellipsoid_is_refused_by_name(tmp_path):
    model = tmp_path / "huge.xml"
    model.write_text("<mujoco><worldbody><body name='a'><freejoint/>"
                     "<geom name='big' type='ellipsoid' size='1e300 0.1 0.1'/></body>"
                     "<body name='b' pos='1 0 0'><geom type='ellipsoid' size='0.2 0.1 0.1'/></body>"
                     "</worldbody></mujoco>")
    traj = tmp_path / "t.npz"
    np.savez(traj, qpos=np.tile([0, 0, 0, 1, 0, 0, 0.0], (3, 1)), time=np.arange(3.0))
    with pytest.raises(replay.ReplayError, match=r"huge.xml: ellipsoid 'big' has semi-axes \[1e\+300, 0.1, 0.1\]"):
        replay.replay(model, traj, progress=False)


def test_chain_replay_with_floors_is_the_same_with_and_without_the_plane_filter(tmp_path, monkeypatch):
    """Chain motion, floors on: the sweep-bound plane filter (chain_bounds.plane_outcomes) decides most foot-floor
    pairs without the exact solver; contacts.csv is byte for byte the one every pair solved exactly gives."""
    from mjccd import chain_bounds

    clip = tmp_path / "clip.npz"
    with np.load(TRAJ) as d:
        np.savez(clip, qpos=d["qpos"][:240], time=d["time"][:240])
    fast = replay.replay(MODEL, clip, "chain", tmp_path / "fast", progress=False, render=False, mode="ellipsoids")
    decided = fast.counters["sphere_culled"] + fast.counters["overlapping_t0"]
    monkeypatch.setattr(chain_bounds.ChainFilter, "plane_outcomes",
                        lambda self, planes, rows: np.full(len(rows), chain_bounds.EXACT, dtype=np.int8))
    slow = replay.replay(MODEL, clip, "chain", tmp_path / "slow", progress=False, render=False, mode="ellipsoids")
    assert slow.counters["solved_exactly"] > fast.counters["solved_exactly"] + 1000 and decided
    assert (tmp_path / "fast" / "contacts.csv").read_bytes() == (tmp_path / "slow" / "contacts.csv").read_bytes()
    assert len(fast.contacts) > 10


def test_the_demo_reports_real_contacts_only_and_keeps_the_foot_strikes():
    """``make demo``'s replay: at every first contact's instant the two geoms are within 1 cm by MuJoCo's own
    ``mj_geomDistance`` (the state there interpolated by MuJoCo: ``mj_differentiatePos``/``mj_integratePos``
    between the frames, not by mjccd's motion), and feet still strike the floor; no shin, thigh or hip does."""
    model = mujoco.MjModel.from_xml_path(str(MODEL))
    with np.load(TRAJ) as data:
        qpos = data["qpos"]
    result = replay.replay(MODEL, TRAJ, progress=False, render=False)
    data, velocity, gaps = mujoco.MjData(model), np.zeros(model.nv), []
    for c in result.contacts:
        k = c["frame"]
        mujoco.mj_differentiatePos(model, velocity, 1.0, qpos[k], qpos[k + 1])
        data.qpos[:] = qpos[k]
        mujoco.mj_integratePos(model, data.qpos, velocity, c["toi"])
        mujoco.mj_kinematics(model, data)
        g1, g2 = (mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, name) for name in c["geoms"])
        gaps.append(mujoco.mj_geomDistance(model, data, g1, g2, 0.5, None))
    assert len(gaps) > 100 and max(abs(g) for g in gaps) <= 0.01
    on_floor = [c["bodies"][0] for c in result.contacts if c["bodies"][1] == "world"]
    assert on_floor and all(("Foot" in b or "Toe" in b) for b in on_floor)
    # the fists are capsules on finger bodies welded to the hand that carries the bound: the boxers' body pairs
    # stand for their rigid parts, so gloves meet gloves (they were left out once, silently)
    fists = ("FingerBase", "HandIndex1", "Thumb")
    gloves = [c for c in result.contacts if all(any(f in b for f in fists) for b in c["bodies"])]
    assert gloves and min(c["time"] for c in gloves) == pytest.approx(1.224053, abs=1e-6)
