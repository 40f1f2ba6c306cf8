"""Malformed ``mjccd import-bvh`` inputs: broken BVH files, bad options, unsafe outputs.

Every clip is a small BVH written here (a hips-legs-spine skeleton of three
frames) and then damaged: truncated, deepened, renamed, given bad numbers or
channels; the options get extreme scales and start frames, and outputs that
would overwrite an input or an existing file.
"""
from . import FuzzCase

ROOT_CHANNELS = "6 Xposition Yposition Zposition Zrotation Yrotation Xrotation"
ROTATION = "3 Zrotation Yrotation Xrotation"


def clip_text(*, root="Hips", leg="LeftUpLeg", knee="LeftLeg", spine="Spine", leg_offset="1 0 0",
              leg_channels=ROTATION, frames=3, frame_time="0.0333333", rows=None):
    """A valid BVH clip (4 joints, 15 channels) with any part replaced."""
    n_channels = 6 + 3 + 3 + len(leg_channels.split()) - 1
    rows = rows if rows is not None else [" ".join(f"{0.1 * (k + i):.3f}" for i in range(n_channels))
                                          for k in range(frames)]
    return f"""HIERARCHY
ROOT {root}
{{
  OFFSET 0 0 0
  CHANNELS {ROOT_CHANNELS}
  JOINT {leg}
  {{
    OFFSET {leg_offset}
    CHANNELS {leg_channels}
    JOINT {knee}
    {{
      OFFSET 0 -4 0
      CHANNELS {ROTATION}
      End Site
      {{
        OFFSET 0 -4 0
      }}
    }}
  }}
  JOINT {spine}
  {{
    OFFSET 0 2 0
    CHANNELS {ROTATION}
    End Site
    {{
      OFFSET 0 3 0
    }}
  }}
}}
MOTION
Frames: {frames}
Frame Time: {frame_time}
""" + "\n".join(rows) + "\n"


def chain_text(depth):
    """A valid-looking clip whose joints form one chain ``depth`` joints deep."""
    lines = ["HIERARCHY"]
    for k in range(depth):
        lines += [f"{'ROOT' if k == 0 else 'JOINT'} J{k}", "{", "OFFSET 0 1 0",
                  f"CHANNELS {ROOT_CHANNELS if k == 0 else ROTATION}"]
    lines += ["End Site", "{", "OFFSET 0 1 0", "}"] + ["}"] * depth
    values = " ".join(["0"] * (6 + 3 * (depth - 1)))
    return "\n".join(lines + ["MOTION", "Frames: 1", "Frame Time: 0.01", values]) + "\n"


def _broken_clips(rng):
    """(label, file content as str or bytes) of every damaged clip."""
    good = clip_text()
    lines = good.splitlines()
    motion = lines.index("MOTION")
    last_frame_start = good.rindex("\n", 0, len(good) - 1) + 1
    row = " ".join(["0.5"] * 15)
    clips = [
        ("empty file", ""),
        ("only whitespace", " \n\t\n\n"),
        ("NUL bytes", b"\x00" * 64),
        ("UTF-16 text", good.encode("utf-16")),
        ("gzip header", b"\x1f\x8b\x08\x00" + bytes(rng.integers(0, 256, 200, dtype="u1"))),
        ("JSON instead of BVH", '{"HIERARCHY": []}\n'),
        ("lower-case hierarchy", good.replace("HIERARCHY", "hierarchy")),
        ("text before HIERARCHY", "# exported\n" + good),
        ("misspelled HIERARCHY", good.replace("HIERARCHY", "HIERARCHIE")),
        ("no MOTION section", "\n".join(lines[:motion]) + "\n"),
        ("MOTION and nothing after", "\n".join(lines[:motion + 1]) + "\n"),
        ("MOTION with Frames only", "\n".join(lines[:motion + 2]) + "\n"),
        ("3000-deep hierarchy", chain_text(3000)),
        ("300-deep hierarchy", chain_text(300)),
        ("257-deep hierarchy", chain_text(257)),
        ("a joint name used twice", clip_text(spine="LeftUpLeg")),
        ("a joint named like the root's free joint", clip_text(leg="Hips_root")),
        ("JOINT instead of ROOT", good.replace("ROOT Hips", "JOINT Hips")),
        ("ROOT inside the root", good.replace("JOINT Spine", "ROOT Spine")),
        ("two roots", good.replace("MOTION", "ROOT Other\n{\nOFFSET 0 0 0\nCHANNELS 0\n}\nMOTION")),
        ("joint without a name", good.replace("JOINT Spine", "JOINT")),
        ("missing opening brace", good.replace("ROOT Hips\n{", "ROOT Hips", 1)),
        ("missing closing brace", good.replace("}\nMOTION", "MOTION")),
        ("extra closing brace", good.replace("}\nMOTION", "}\n}\nMOTION")),
        ("OFFSET with two numbers", clip_text(leg_offset="1 0")),
        ("OFFSET nan", clip_text(leg_offset="nan 0 0")),
        ("OFFSET inf", clip_text(leg_offset="0 inf 0")),
        ("OFFSET 1e999", clip_text(leg_offset="0 0 1e999")),
        ("OFFSET word", clip_text(leg_offset="one 0 0")),
        ("OFFSET 1e300 overflows once scaled", clip_text(leg_offset="1e300 0 0")),
        ("OFFSET 1e200 in two axes", clip_text(leg_offset="1e200 1e200 0")),
        ("missing OFFSET", good.replace("    OFFSET 1 0 0\n", "")),
        ("missing CHANNELS", good.replace(f"CHANNELS {ROOT_CHANNELS}", "")),
        ("CHANNELS 7", good.replace("CHANNELS 6", "CHANNELS 7", 1)),
        ("CHANNELS -1", clip_text(leg_channels="-1")),
        ("CHANNELS 2.5", clip_text(leg_channels="2.5 Zrotation Yrotation")),
        ("CHANNELS three", good.replace("CHANNELS 3", "CHANNELS three", 1)),
        ("CHANNELS 1e9", good.replace("CHANNELS 3", "CHANNELS 1e9", 1)),
        ("CHANNELS count above the names", clip_text(leg_channels="3 Zrotation Yrotation")),
        ("unknown channel Wrotation", clip_text(leg_channels="3 Zrotation Yrotation Wrotation")),
        ("lower-case channel", clip_text(leg_channels="3 zrotation Yrotation Xrotation")),
        ("abbreviated channel", clip_text(leg_channels="3 Zrot Yrot Xrot")),
        ("channel repeated", clip_text(leg_channels="3 Zrotation Zrotation Xrotation")),
        ("End without Site", good.replace("End Site", "End", 1)),
        ("End Site with CHANNELS", good.replace("End Site\n      {\n", "End Site\n{\nCHANNELS 1 Xrotation\n", 1)),
        ("stray word in a joint", good.replace("JOINT Spine", "Bone\nJOINT Spine")),
        ("Frames: -1", good.replace("Frames: 3", "Frames: -1")),
        ("Frames: ten", good.replace("Frames: 3", "Frames: ten")),
        ("Frames: 1.5", good.replace("Frames: 3", "Frames: 1.5")),
        ("Frames without colon", good.replace("Frames: 3", "Frames 3")),
        ("Frames: 0 and no frames", clip_text(frames=0)),
        ("Frames: 10^12", good.replace("Frames: 3", "Frames: 1000000000000")),
        ("more frames than declared", good + row + "\n"),
        ("fewer frames than declared", good.replace("Frames: 3", "Frames: 5")),
        ("Frame Time: 1e308", clip_text(frame_time="1e308")),
        ("Frame Time: 0", clip_text(frame_time="0")),
        ("Frame Time: -0.01", clip_text(frame_time="-0.01")),
        ("Frame Time: nan", clip_text(frame_time="nan")),
        ("Frame Time: inf", clip_text(frame_time="inf")),
        ("Frame Time: 1e-300", clip_text(frame_time="1e-300")),
        ("Frame Time: two hours", clip_text(frame_time="7200")),
        ("Frame Time: fast", clip_text(frame_time="fast")),
        ("Frame Time missing", good.replace("Frame Time: 0.0333333\n", "")),
        ("frame with one value missing", clip_text(rows=[row, row, " ".join(["0.5"] * 14)])),
        ("frame with one value too many", clip_text(rows=[row, row + " 0.5", row])),
        ("frame value abc", clip_text(rows=[row, row.replace("0.5", "abc", 1), row])),
        ("frame value nan", clip_text(rows=[row, row, row.replace("0.5", "nan", 1)])),
        ("frame value inf", clip_text(rows=[row.replace("0.5", "-inf", 1), row, row])),
        ("frame value 1e999", clip_text(rows=[row, row.replace("0.5", "1e999", 1), row])),
        ("frame value with a comma", clip_text(rows=[row, row.replace("0.5", "0,5", 1), row])),
        ("frame value in hex", clip_text(rows=[row, row, row.replace("0.5", "0x1F", 1)])),
        ("root position 1e307 overflows once scaled", clip_text(rows=["1e307 " + row[4:], row, row])),
    ]
    for size in (1, 17, 512, 4096):
        clips.append((f"{size} random bytes", bytes(rng.integers(0, 256, size, dtype="u1"))))
    for cut in sorted(rng.choice(last_frame_start, 30, replace=False)):
        clips.append((f"truncated at byte {cut} of {len(good)}", good[:cut]))
    for n in range(2, motion, 3):
        clips.append((f"truncated after line {n}", "\n".join(lines[:n]) + "\n"))
    return clips


def generate(folder, rng):
    cases = []
    for k, (label, content) in enumerate(_broken_clips(rng)):
        name = f"clip{k:03d}.bvh"
        mode = "wb" if isinstance(content, bytes) else "w"
        with open(folder / name, mode) as fh:
            fh.write(content)
        cases.append(FuzzCase(label, ["import-bvh", name, "-o", "out.xml", "--traj", "out.npz"], (name,)))

    (folder / "good.bvh").write_text(clip_text())
    (folder / "existing.xml").write_text("<mujoco/>\n")
    (folder / "existing.npz").write_bytes(b"not an npz")
    (folder / "a_folder").mkdir()
    base = ["import-bvh", "good.bvh"]
    for value in ("1e300", "0", "-1", "nan", "inf", "-inf", "1e-300", "1e9", "abc", ""):
        cases.append(FuzzCase(f"--scale {value!r}", base + ["-o", "out.xml", f"--scale={value}"], ("scale",)))
    for value in ("-1", "3", "1000000000", "x", "1.5"):
        cases.append(FuzzCase(f"--start {value!r}", base + ["-o", "out.xml", f"--start={value}"], ("start",)))
    cases += [
        FuzzCase("missing clip", ["import-bvh", "missing.bvh", "-o", "out.xml"], ("missing.bvh",)),
        FuzzCase("clip is a folder", ["import-bvh", "a_folder", "-o", "out.xml"], ("a_folder",)),
        FuzzCase("no -o", base, ("-o",)),
        FuzzCase("unknown option", base + ["-o", "out.xml", "--bogus"], ("--bogus",)),
        FuzzCase("-o into a missing folder", base + ["-o", "nowhere/out.xml"], ("nowhere/out.xml",)),
        FuzzCase("-o is a folder", base + ["-o", "a_folder"], ("a_folder",)),
        FuzzCase("-o is the clip", base + ["-o", "good.bvh"], ("good.bvh",)),
        FuzzCase("--traj is the clip", base + ["-o", "out.xml", "--traj", "good.bvh"], ("good.bvh",)),
        FuzzCase("--traj is -o", base + ["-o", "out.xml", "--traj", "out.xml"], ("--traj",)),
        FuzzCase("-o exists", base + ["-o", "existing.xml"], ("existing.xml",)),
        FuzzCase("--traj exists", base + ["-o", "out.xml", "--traj", "existing.npz"], ("existing.npz",)),
        FuzzCase("--traj into a missing folder", base + ["-o", "out.xml", "--traj", "nowhere/t.npz"],
                 ("nowhere/t.npz",)),
    ]
    return cases
