"""Wrap a dm-control suite task and let a controller react to exact predicted contacts.

The humanoid is driven by smooth random torques.  After every control step
the wrapper reports the first new contact between two of its geoms (limbs and
floor, exactly: geoms mode) within that step (time, bodies, point, normal).
When one is reported the controller brakes: it damps its torques for the next
few steps.  A contact the solver could only bracket is ``uncertain`` and
carries its estimate's point when it has one.

    python examples/wrap_suite_env.py [--steps 300] [--domain humanoid_CMU --task stand]
"""
import argparse

import numpy as np
from dm_control import suite

from mjccd.dm_control import CCDWrapper


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--domain", default="humanoid_CMU")
    parser.add_argument("--task", default="stand")
    parser.add_argument("--steps", type=int, default=300)
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args(argv)

    # the three lines that matter: load, wrap, read the ccd/* observations
    env = CCDWrapper(suite.load(args.domain, args.task, task_kwargs={"random": args.seed}),
                     report_overlapping=False)
    timestep = env.reset()

    spec = env.action_spec()
    rng = np.random.default_rng(args.seed)
    action = np.zeros(spec.shape)
    brake = 0
    contacts = 0
    for step in range(args.steps):
        target = rng.uniform(spec.minimum, spec.maximum)
        action = 0.8 * action + 0.2 * target
        if brake:
            action *= 0.2  # react: back off while limbs are about to touch
            brake -= 1
        timestep = env.step(action)
        obs = timestep.observation
        if np.isfinite(obs["ccd/contact_time"]):
            contacts += 1
            brake = 5
            c = env.last_contacts[0]
            if contacts <= 5:
                where = "" if c.point is None else f" at {np.round(c.point, 3)}"
                flag = "" if c.certainty == "certified" else " (uncertain)"
                print(f"step {step:4d}: {c.bodies[0]} touches {c.bodies[1]} in "
                      f"{1e3 * obs['ccd/contact_time']:.3f} ms{where}{flag}")
        if timestep.last():
            timestep = env.reset()
    print(f"{contacts} of {args.steps} control steps had a predicted limb contact "
          f"({len(env.monitor.pairs)} {'geom' if env.monitor.mode == 'geoms' else 'ellipsoid'} pairs checked per "
          f"physics step)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
