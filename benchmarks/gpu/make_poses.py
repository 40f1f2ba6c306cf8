"""Writes benchmarks/gpu/boxing_poses.npz: 161 consecutive frames of the CMU boxing replay's ellipsoid poses.

The GPU benchmark (``python -m mjccd.gpu.bench``) runs where MuJoCo may be missing, so it reads the
poses that MuJoCo's kinematics gives the replay's 2 x 21 fitted ellipsoids (``models/boxing.xml`` with
``data/boxing_traj.npz``, as ``mjccd bench scene`` builds them) from this file: frames 139..299, the
160-frame window of the replay with the most pairs past the moving-sphere filter (about 18 of 441 per
frame; 7.6 over the whole replay).  Run from the repository root: ``python benchmarks/gpu/make_poses.py``.
"""
import numpy as np

from mjccd.bench.scene import real_boxing_workload

FIRST, FRAMES = 139, 160


def main():
    poses, radii, pairs = real_boxing_workload("models/boxing.xml", "data/boxing_traj.npz")
    np.savez_compressed("benchmarks/gpu/boxing_poses.npz", poses=poses[FIRST:FIRST + FRAMES + 1], radii=radii,
                        pairs=pairs, first_frame=FIRST)


if __name__ == "__main__":
    main()
