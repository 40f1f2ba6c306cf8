"""Malformed ``mjccd fit`` inputs: MJCF MuJoCo cannot load, models with nothing to fit, bad options, unsafe outputs.

The models start from the repository's ``models/arm_obstacle.xml`` (copied
here, its mesh folder addressed relative to this folder, its obstacle made
colliding so that a fit would succeed) and are then damaged.
"""
import os
import pathlib

from . import FuzzCase

MODELS = pathlib.Path(__file__).resolve().parents[2] / "models"

SMALL_MODELS = {
    "geom size nan": '<mujoco><worldbody><body><freejoint/><geom size="nan"/></body></worldbody></mujoco>',
    "box of size 0": '<mujoco><worldbody><body><freejoint/><geom type="box" size="0 0 0"/></body></worldbody></mujoco>',
    "sphere of radius 1e-300": '<mujoco><worldbody><body><freejoint/><geom size="1e-300"/></body></worldbody></mujoco>',
    "capsule of length 0": '<mujoco><worldbody><body><freejoint/><geom type="capsule" fromto="0 0 0 0 0 0" '
                           'size="0.1"/></body></worldbody></mujoco>',
    "flat mesh": '<mujoco><asset><mesh name="m" vertex="0 0 0 1 0 0 0 1 0 1 1 0"/></asset><worldbody><body>'
                 '<freejoint/><geom type="mesh" mesh="m"/></body></worldbody></mujoco>',
    "only an earlier fit's ellipsoid": '<mujoco><worldbody><body><freejoint/><geom name="mjccd_ellipsoid_0" '
                                       'type="ellipsoid" size="0.1 0.2 0.3"/></body></worldbody></mujoco>',
    "only a plane": '<mujoco><worldbody><geom type="plane" size="1 1 1"/></worldbody></mujoco>',
    "only a height field": '<mujoco><asset><hfield name="h" nrow="2" ncol="2" size="1 1 1 1"/></asset><worldbody>'
                           '<body><geom type="hfield" hfield="h"/></body></worldbody></mujoco>',
    "only visual geoms": '<mujoco><worldbody><body><freejoint/><geom size="0.1" contype="0" conaffinity="0"/>'
                         '</body></worldbody></mujoco>',
    "no worldbody": "<mujoco/>",
    "a URDF robot": '<robot name="r"/>',
    "repeated body name": '<mujoco><worldbody><body name="a"><geom size="1"/></body><body name="a"><geom size="1"/>'
                          '</body></worldbody></mujoco>',
    "unknown element": "<mujoco><worldbody><bogus/></worldbody></mujoco>",
    "unknown attribute": '<mujoco><worldbody><geom size="1" colour="red"/></worldbody></mujoco>',
    "include of a missing file": '<mujoco><include file="missing_part.xml"/></mujoco>',
    "unclosed element": "<mujoco><worldbody>",
    "entity expansion": '<?xml version="1.0"?><!DOCTYPE m [<!ENTITY a "aaaaaaaa"><!ENTITY b "&a;&a;&a;&a;">]>'
                        '<mujoco model="&b;"/>',
}


def good_model(folder):
    """The text of ``models/arm_obstacle.xml`` made to load from ``folder`` and to have something to fit."""
    text = (MODELS / "arm_obstacle.xml").read_text()
    meshes = os.path.relpath(MODELS / "kinova", folder)
    text = text.replace('meshdir="kinova/"', f'meshdir="{meshes}/"')
    return text.replace('<geom type="box" rgba', '<geom type="box" contype="1" conaffinity="1" rgba')


def generate(folder, rng):
    good = good_model(folder)
    (folder / "good.xml").write_text(good)
    (folder / "existing.xml").write_text("<mujoco/>\n")
    (folder / "existing.json").write_text("{}\n")
    (folder / "taken.ellipsoids.json").write_text("{}\n")
    (folder / "a_folder").mkdir()
    out = ["-o", "out.xml", "-q"]
    broken = [
        ("empty file", ""),
        ("only whitespace", " \n\t\n"),
        ("NUL bytes", b"\x00" * 64),
        ("JSON instead of MJCF", '{"mujoco": {}}\n'),
        ("BVH instead of MJCF", "HIERARCHY\nROOT Hips\n{\n}\nMOTION\n"),
        ("UTF-16 text", good.encode("utf-16")),
        ("arm model without its meshes", (MODELS / "arm_obstacle.xml").read_text()),
        ("boxing model: nothing collides", (MODELS / "boxing.xml").read_text()),
        ("mesh folder that does not exist", good.replace('meshdir="', 'meshdir="nowhere/')),
        ("mesh file with garbage", good.replace('file="base.stl"', 'file="../junk.stl"')),
    ]
    (folder / "junk.stl").write_bytes(bytes(rng.integers(0, 256, 300, dtype="u1")))
    broken += list(SMALL_MODELS.items())
    for size in (1, 100, 3000):
        broken.append((f"{size} random bytes", bytes(rng.integers(0, 256, size, dtype="u1"))))
    for cut in sorted(rng.choice(len(good) - 20, 12, replace=False)):
        broken.append((f"truncated at byte {cut} of {len(good)}", good[:cut]))

    cases = []
    for k, (label, content) in enumerate(broken):
        name = f"model{k:03d}.xml"
        mode = "wb" if isinstance(content, bytes) else "w"
        with open(folder / name, mode) as fh:
            fh.write(content)
        cases.append(FuzzCase(label, ["fit", name] + out, (name,)))

    base = ["fit", "good.xml"]
    cases += [
        FuzzCase("missing model", ["fit", "missing.xml"] + out, ("missing.xml",)),
        FuzzCase("model is a folder", ["fit", "a_folder"] + out, ("a_folder",)),
        FuzzCase("--bodies names no body", base + out + ["--bodies", "nope"], ("bodies",)),
        FuzzCase("--bodies the world (only a plane)", base + out + ["--bodies", "world"], ("bodies",)),
        FuzzCase("--bodies a body with visual geoms only", base + out + ["--bodies", "b_base"], ("bodies",)),
        FuzzCase("--bodies an id as text", base + out + ["--bodies", "#99"], ("bodies",)),
        FuzzCase("--per limb", base + out + ["--per", "limb"], ("--per",)),
        FuzzCase("--group 6", base + out + ["--group", "6"], ("--group",)),
        FuzzCase("--group -1", base + out + ["--group=-1"], ("--group",)),
        FuzzCase("--group x", base + out + ["--group", "x"], ("--group",)),
        FuzzCase("unknown option", base + out + ["--bogus"], ("--bogus",)),
        FuzzCase("--ellipsoids .txt", base + out + ["--ellipsoids", "e.txt"], ("--ellipsoids",)),
        FuzzCase("--ellipsoids is -o", ["fit", "good.xml", "-o", "e.json", "--ellipsoids", "e.json"],
                 ("--ellipsoids",)),
        FuzzCase("-o is the model", base + ["-o", "good.xml"], ("good.xml",)),
        FuzzCase("-o exists", base + ["-o", "existing.xml"], ("existing.xml",)),
        FuzzCase("--ellipsoids exists", base + out + ["--ellipsoids", "existing.json"], ("existing.json",)),
        FuzzCase("default ellipsoid file exists", base + ["-o", "taken.xml"], ("taken.ellipsoids.json",)),
        FuzzCase("-o into a missing folder", base + ["-o", "nowhere/out.xml"], ("nowhere/out.xml",)),
        FuzzCase("-o is a folder", base + ["-o", "a_folder"], ("a_folder",)),
        FuzzCase("--ellipsoids into a missing folder", base + out + ["--ellipsoids", "nowhere/e.json"],
                 ("nowhere/e.json",)),
    ]
    return cases
