"""BVH import: the real CMU clips, forward kinematics against an independent evaluation, bad files."""
import pathlib

import mujoco
import numpy as np
import pytest

from mjccd import bvh

ROOT = pathlib.Path(__file__).resolve().parents[1]
CLIPS = {
    "cmu_13_18_boxing_first10s.bvh": 1200,
    "cmu_14_03_boxing_first10s.bvh": 1200,
}


def _clip_path(name):
    return ROOT / "data" / "mocap" / name


def _rot(axis, deg):
    """Rotation matrix about a coordinate axis, written out (independent of mjccd.bvh)."""
    c, s = np.cos(np.radians(deg)), np.sin(np.radians(deg))
    if axis == "X":
        return np.array([[1, 0, 0], [0, c, -s], [0, s, c]])
    if axis == "Y":
        return np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]])
    return np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])


def _reference_positions(path, frame):
    """World joint positions (file units, Y up) of one frame, from a minimal reader of our own."""
    tokens = pathlib.Path(path).read_text().split()
    names, parents, offsets, channels = [], [], [], []
    stack, i = [], 0
    while tokens[i] != "MOTION":
        tok = tokens[i]
        if tok in ("ROOT", "JOINT"):
            names.append(tokens[i + 1])
            parents.append(stack[-1] if stack else -1)
            i += 2
        elif tok == "End":
            names.append(None)
            parents.append(stack[-1])
            i += 2
        elif tok == "{":
            stack.append(len(names) - 1)
            i += 1
        elif tok == "}":
            stack.pop()
            i += 1
        elif tok == "OFFSET":
            offsets.append([float(x) for x in tokens[i + 1:i + 4]])
            channels.append([])
            i += 4
        elif tok == "CHANNELS":
            n = int(tokens[i + 1])
            channels[-1] = tokens[i + 2:i + 2 + n]
            i += 2 + n
        else:
            i += 1
    values = pathlib.Path(path).read_text().split("Frame Time:")[1].splitlines()[1 + frame].split()
    values = [float(v) for v in values]
    world_R, world_p, k = [], [], 0
    out = {}
    for j, name in enumerate(names):
        local_p = np.array(offsets[j])
        local_R = np.eye(3)
        for ch in channels[j]:
            v = values[k]
            k += 1
            if ch.endswith("position"):
                local_p = local_p + v * np.eye(3)["XYZ".index(ch[0])]
            else:
                local_R = local_R @ _rot(ch[0], v)
        if parents[j] < 0:
            R, p = local_R, local_p
        else:
            R = world_R[parents[j]] @ local_R
            p = world_p[parents[j]] + world_R[parents[j]] @ local_p
        world_R.append(R)
        world_p.append(p)
        if name is not None:
            out[name] = p
    return out


@pytest.mark.parametrize("name,frames", CLIPS.items())
def test_real_clips_counts(name, frames):
    clip = bvh.read_bvh(_clip_path(name))
    assert clip.n_frames == frames
    assert clip.n_channels == 96
    assert len(clip.joints) == 31
    assert clip.joints[0].channels == ("Xposition", "Yposition", "Zposition", "Zrotation", "Yrotation", "Xrotation")
    assert sum(len(j.end_sites) for j in clip.joints) == 7
    assert clip.frame_time == pytest.approx(1 / 120, rel=1e-4)


@pytest.mark.parametrize("name", CLIPS)
@pytest.mark.parametrize("frame", [0, 1, 613, 1199])
def test_forward_kinematics_matches_bvh(name, frame):
    path = _clip_path(name)
    xml, qpos, _, clip = bvh.import_bvh(path)
    model = mujoco.MjModel.from_xml_string(xml)
    data = mujoco.MjData(model)
    assert qpos.shape == (1200, model.nq)
    data.qpos[:] = qpos[frame]
    mujoco.mj_kinematics(model, data)
    ref = _reference_positions(path, frame)
    C = np.array([[0.0, 0.0, 1.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])  # BVH Y-up -> MuJoCo Z-up
    height = max(p[1] for p in ref.values()) - min(p[1] for p in ref.values())
    for joint_name, p in ref.items():
        got = data.xpos[model.body(joint_name).id]
        want = bvh.CMU_SCALE * (C @ p)
        assert np.abs(got - want).max() <= 1e-9 * height * bvh.CMU_SCALE, joint_name


def test_cmu_units_give_a_human_size():
    xml, qpos, _, _ = bvh.import_bvh(_clip_path("cmu_14_03_boxing_first10s.bvh"))
    model = mujoco.MjModel.from_xml_string(xml)
    data = mujoco.MjData(model)
    data.qpos[:] = qpos[0]
    mujoco.mj_kinematics(model, data)
    z = data.xpos[1:, 2]
    assert 1.2 < z.max() - z.min() < 1.9       # T-pose joints span, metres
    arm = np.linalg.norm(data.xpos[model.body("LeftArm").id] - data.xpos[model.body("LeftHand").id])
    assert 0.4 < arm < 0.7


def test_placement_and_start_frame():
    clip = bvh.read_bvh(_clip_path("cmu_13_18_boxing_first10s.bvh"))
    layout = bvh.Layout("a_", bvh.CMU_SCALE, bvh.Placement((1.0, 2.0, 0.0), np.pi / 2), frozenset(), 0)
    q = bvh.qpos_trajectory(clip, layout, [0])
    base = bvh.qpos_trajectory(clip, bvh.Layout("", bvh.CMU_SCALE, bvh.Placement(), frozenset(), 0), [0])
    x, y, z = base[0, :3]
    np.testing.assert_allclose(q[0, :3], [1.0 - y, 2.0 + x, z], atol=1e-12)
    np.testing.assert_allclose(q[0, 7:], base[0, 7:])
    _, qpos, time, _ = bvh.import_bvh(_clip_path("cmu_13_18_boxing_first10s.bvh"), start=1)
    assert qpos.shape[0] == 1199 and time[0] == 0.0


def test_frozen_joints_leave_qpos():
    clip = bvh.read_bvh(_clip_path("cmu_13_18_boxing_first10s.bvh"))
    frozen = frozenset({"LThumb", "RThumb"})
    layout = bvh.Layout("", bvh.CMU_SCALE, bvh.Placement(), frozen, 0)
    xml = bvh.model_xml([(clip, layout, None)])
    model = mujoco.MjModel.from_xml_string(xml)
    q = bvh.qpos_trajectory(clip, layout, [5])
    assert q.shape == (1, model.nq) == (1, 127 - 8)


def _truncate(tmp_path, text, name="bad.bvh"):
    p = tmp_path / name
    p.write_text(text)
    return p


def test_bad_files(tmp_path):
    good = _clip_path("cmu_13_18_boxing_first10s.bvh").read_text()
    lines = good.splitlines()
    cases = [
        ("\n".join(lines[:-3]) + "\n", "header says 1200 frames but only 1197 frame lines follow"),
        ("\n".join(lines[:40]) + "\n", "no MOTION section"),
        ("\n".join(lines[:-1] + [lines[-1][:40]]) + "\n", "the hierarchy declares 96 channels"),
        (good.replace("CHANNELS 3 Zrotation Yrotation Xrotation", "CHANNELS 3 Zrotation Yrotation Wrotation", 1),
         "unknown channel 'Wrotation'"),
        (good.replace("Frame Time: .0083333", "Frame Time: fast"), "expected 'Frame Time: <positive seconds>'"),
        (good.replace("HIERARCHY", "HIERARCHIE", 1), "expected 'HIERARCHY'"),
        ("", "expected 'HIERARCHY'"),
    ]
    for text, message in cases:
        with pytest.raises(bvh.BVHError, match=message.replace("(", r"\(").replace(")", r"\)")):
            bvh.read_bvh(_truncate(tmp_path, text))
    with pytest.raises(ValueError, match="cannot read"):
        bvh.read_bvh(tmp_path / "missing.bvh")


def test_cli(tmp_path, capsys):
    out = tmp_path / "m.xml"
    traj = tmp_path / "t.npz"
    assert bvh.main([str(_clip_path("cmu_14_03_boxing_first10s.bvh")), "-o", str(out), "--traj", str(traj),
                     "--start", "1"]) == 0
    data = np.load(traj)
    assert data["qpos"].shape == (1199, 127)
    assert mujoco.MjModel.from_xml_path(str(out)).nq == 127
    bad = _truncate(tmp_path, "HIERARCHY\nROOT Hips\n{\n")
    assert bvh.main([str(bad), "-o", str(tmp_path / "bad.xml")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "truncated" in err[0] and "Traceback" not in err[0]


def _chain(depth):
    """A clip whose joints form one chain ``depth`` joints deep."""
    lines = ["HIERARCHY"]
    for k in range(depth):
        lines += [f"{'ROOT' if k == 0 else 'JOINT'} J{k}", "{", "OFFSET 0 1 0",
                  "CHANNELS 3 Zrotation Yrotation Xrotation"]
    lines += ["End Site", "{", "OFFSET 0 1 0", "}"] + ["}"] * depth
    return "\n".join(lines + ["MOTION", "Frames: 1", "Frame Time: 0.01", " ".join(["0"] * (3 * depth))]) + "\n"


def test_depth_limit_names_the_joint(tmp_path):
    clip = bvh.read_bvh(_truncate(tmp_path, _chain(bvh.MAX_DEPTH)))
    assert len(clip.joints) == bvh.MAX_DEPTH
    _, qpos, _, _ = bvh.import_bvh(_truncate(tmp_path, _chain(bvh.MAX_DEPTH), "deepest.bvh"))
    assert qpos.shape == (1, 7 + 4 * (bvh.MAX_DEPTH - 1))
    with pytest.raises(bvh.BVHError, match=rf"deep.bvh: line \d+: joint 'J{bvh.MAX_DEPTH}' is {bvh.MAX_DEPTH + 1} "
                                           "joints deep"):
        bvh.read_bvh(_truncate(tmp_path, _chain(3000), "deep.bvh"))


@pytest.mark.parametrize("frame_time", ["1e308", "7200", "1e-300"])
def test_frame_time_out_of_range(tmp_path, frame_time):
    text = _chain(2).replace("Frame Time: 0.01", f"Frame Time: {frame_time}")
    with pytest.raises(bvh.BVHError, match=r"bad.bvh: line \d+: Frame Time: .* outside \[1e-06, 3600\] seconds"):
        bvh.read_bvh(_truncate(tmp_path, text))


def test_colliding_names_become_distinct():
    joints = [bvh.Joint(name, -1, np.zeros(3)) for name in ("L#Hip", "L_Hip", "L_Hip_2", "L Hip")]
    clip = bvh.Clip(joints, np.zeros((1, 0)), 0.01)
    assert bvh.mjcf_names(clip) == ["L_Hip", "L_Hip_3", "L_Hip_2", "L_Hip_4"]


@pytest.mark.parametrize("scale", [0.0, -1.0, float("nan"), float("inf"), 1e300, 1e-300])
def test_scale_out_of_range(scale):
    with pytest.raises(ValueError, match="scale: metres per file unit must be in"):
        bvh.import_bvh(_clip_path("cmu_13_18_boxing_first10s.bvh"), scale=scale)


def test_lengths_that_overflow_once_scaled(tmp_path):
    text = _chain(2).replace("OFFSET 0 1 0", "OFFSET 0 1e300 0", 1)
    with pytest.raises(bvh.BVHError, match=r"bad.bvh: an offset or position reaches 1e\+300 m at scale 1"):
        bvh.import_bvh(_truncate(tmp_path, text), scale=1.0)
