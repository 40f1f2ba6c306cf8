"""Every collision interval of the Jaco arm against the I-beam, like Table 6 of Choi's thesis.

    python examples/arm_intervals.py

The arm (models/arm_obstacle.xml: 10 ellipsoids fitted to the Kinova Jaco's link meshes,
3 on the beam) moves between the keyframes stored in data/arm_traj.npz with every joint's
tan(θ/2) linear in time, so the `chain` motion is exact: each link's ellipsoid moves on a
rational path whose degree grows down the chain (F up to degree 96 in t at the fingers).
"""
import pathlib

import numpy as np

from mjccd import replay
from mjccd.mujoco import ModelAdapter

ROOT = pathlib.Path(__file__).resolve().parents[1]


def main():
    model = replay.load_model(ROOT / "models" / "arm_obstacle.xml")
    checker = ModelAdapter(model, *replay.replay_ellipsoids(model), "chain")
    with np.load(ROOT / "data" / "arm_traj.npz") as data:
        keys = data["keyframes"]
    rows = replay.interval_table(checker, keys[0], keys[1])
    print(replay.format_interval_table(rows))
    hits = [r for r in rows if r["intervals"]]
    print(f"{len(hits)} of {len(rows)} pairs collide; earliest entry "
          f"{min(r['intervals'][0][0] for r in hits):.9f} (normalised time of the segment)")
    return rows


if __name__ == "__main__":
    main()
