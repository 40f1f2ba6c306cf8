"""Build ``models/boxing.xml`` and ``data/boxing_traj.npz`` from the two CMU boxing clips.

Two boxers face each other: subject 13 at -x facing +x, subject 14 at +x
facing -x, their mean hip positions ``--distance`` metres apart.  Each is a
BVH skeleton (see :mod:`mjccd.bvh`) bounded by one fitted ellipsoid per rigid
part (21 per boxer).  Frame 0 of each clip (the converter's T-pose) is left
out; finger, thumb, hip-joint and shoulder joints are fixed (CMU did not
capture fingers; the other channels are constant zero in both clips).

    python models/build_boxing.py [--distance 1.0]
"""
import argparse
import math
import pathlib

import numpy as np

from mjccd import bvh

ROOT = pathlib.Path(__file__).resolve().parents[1]
CLIPS = (("a_", "cmu_13_18_boxing_first10s.bvh", -1.0), ("b_", "cmu_14_03_boxing_first10s.bvh", 1.0))
FROZEN = frozenset("LHipJoint RHipJoint LeftShoulder RightShoulder LeftFingerBase LeftHandIndex1 LThumb "
                   "RightFingerBase RightHandIndex1 RThumb".split())
START = 1


def build(distance, model_path, traj_path):
    characters, qpos, n = [], [], None
    for prefix, name, side in CLIPS:
        clip = bvh.read_bvh(ROOT / "data" / "mocap" / name)
        frames = np.arange(START, clip.n_frames)
        heading, centre = bvh.facing(clip, frames)
        centre = centre * bvh.CMU_SCALE
        want = 0.0 if side < 0 else math.pi          # face the other boxer
        yaw = want - heading
        c, s = math.cos(yaw), math.sin(yaw)
        turned = np.array([c * centre[0] - s * centre[1], s * centre[0] + c * centre[1]])
        shift = (side * distance / 2 - turned[0], -turned[1], 0.0)
        layout = bvh.Layout(prefix, bvh.CMU_SCALE, bvh.Placement(shift, yaw), FROZEN, START)
        characters.append((clip, layout, bvh.bounding_geoms(clip, layout)))
        qpos.append(bvh.qpos_trajectory(clip, layout, frames))
        n = len(frames) if n is None else min(n, len(frames))
        dt = clip.frame_time
    xml = bvh.model_xml(characters, model_name="boxing")
    model_path.write_text(xml)
    q = np.concatenate([x[:n] for x in qpos], axis=1)
    np.savez_compressed(traj_path, qpos=q, time=np.arange(n) * dt)
    return q.shape


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--distance", type=float, default=1.0, help="metres between the boxers' mean hips")
    parser.add_argument("--model", default=str(ROOT / "models" / "boxing.xml"))
    parser.add_argument("--traj", default=str(ROOT / "data" / "boxing_traj.npz"))
    args = parser.parse_args()
    shape = build(args.distance, pathlib.Path(args.model), pathlib.Path(args.traj))
    print(f"{args.model}, {args.traj}: {shape[0]} frames, nq={shape[1]}")


if __name__ == "__main__":
    main()
