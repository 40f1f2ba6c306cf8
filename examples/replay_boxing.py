"""Replay the bundled boxing scene and print where the two boxers first touch.

    python examples/replay_boxing.py [OUT_DIR]

Uses models/boxing.xml (two CMU boxers, bounded by 46 and 48 ellipsoids) and
data/boxing_traj.npz (1,199 frames at 120 Hz from CMU clips 13_18 and 14_03).
"""
import os
import pathlib
import sys

if "MUJOCO_GL" not in os.environ and not os.environ.get("DISPLAY"):
    os.environ["MUJOCO_GL"] = "egl"  # headless rendering of the contact frames; chosen before mujoco loads

from mjccd import replay  # noqa: E402

ROOT = pathlib.Path(__file__).resolve().parents[1]


def main(out_dir=None):
    result = replay.replay(ROOT / "models" / "boxing.xml", ROOT / "data" / "boxing_traj.npz",
                           motion="rigid", out_dir=out_dir)
    print(replay.contact_table(result, max_rows=10))
    print(replay.summary(result))
    first = result.contacts[0]
    print(f"first contact: {first['labels'][0]} and {first['labels'][1]} at t = {first['time']:.6f} s, "
          f"point {[round(x, 4) for x in first['point']]}")
    return result


if __name__ == "__main__":
    main(sys.argv[1] if len(sys.argv) > 1 else None)
