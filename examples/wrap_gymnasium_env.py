"""A Gymnasium MuJoCo environment with the exact first contact of every step in ``info["ccd"]``.

    python examples/wrap_gymnasium_env.py [--env Ant-v5] [--steps 300] [--seed 0]

``CCDGymWrapper`` checks every physics frame of a step (``frame_skip`` of them) on the model's own
geoms and puts the earliest new contact in ``info["ccd"]``: its time, the two bodies, the point and
the normal (``report_overlapping=False``: feet resting on the floor are not reported again and again,
only contacts that begin within the step).  Random actions here; any policy works the same way.
"""
import argparse
import math
import sys

import gymnasium

from mjccd.mujoco.gym import CCDGymWrapper


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--env", default="Ant-v5", help="a Gymnasium MuJoCo environment (default Ant-v5)")
    parser.add_argument("--steps", type=int, default=300)
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args(argv)
    env = CCDGymWrapper(gymnasium.make(args.env), report_overlapping=False)
    env.action_space.seed(args.seed)
    env.reset(seed=args.seed)
    touched = 0
    for step in range(args.steps):
        _, _, terminated, truncated, info = env.step(env.action_space.sample())
        ccd = info["ccd"]
        if math.isfinite(ccd["contact_time"]):
            touched += 1
            first = ccd["contacts"][0]
            if touched <= 5:
                print(f"step {step}: {first.bodies[0]} / {first.bodies[1]} touch at t = {first.time:.5f} s, "
                      f"point {[round(float(x), 3) for x in first.point]}")
        if terminated or truncated:
            env.reset()
    print(f"{touched} of {args.steps} steps had a new contact")
    env.close()
    return 0


if __name__ == "__main__":
    sys.exit(main())
