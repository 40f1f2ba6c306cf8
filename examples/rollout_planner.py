"""A sampling planner that drops every rollout in which the Jaco arm would touch the I-beam.

    python examples/rollout_planner.py                # 64 rollouts of 40 steps per control step
    python examples/rollout_planner.py --rollouts 256 --horizon 12 --iterations 120
    python examples/rollout_planner.py --quick        # a few control steps, for the tests
    python examples/rollout_planner.py --unchecked    # keep colliding rollouts: watch the arm hit the beam

The arm of models/arm_planner.xml (the Kinova Jaco of models/arm_obstacle.xml with joint position servos) starts
with its hand on one side of the I-beam and must bring it to a target on the far side.  Each control step the
planner samples K sequences of joint targets around its current plan, rolls them all out with MuJoCo's own
``mujoco.rollout`` (threaded, persistent pool), asks mjccd for the first contact of every rollout
(:class:`mjccd.mujoco.rollout.RolloutChecker`: exact continuous collision detection of the fitted ellipsoids
over every step, not only at the recorded states), drops the colliding ones, keeps the cheapest of the rest
(distance of the hand to the target along the way) and executes its first targets.  The executed path is
checked again at the end.  MuJoCo itself does not collide these geoms (visual only): without mjccd the arm
would sweep through the beam.
"""
import argparse
import os
import pathlib
import time

import mujoco
import mujoco.rollout
import numpy as np

from mjccd.mujoco import geom_ellipsoids
from mjccd.mujoco.rollout import FULLPHYSICS, RolloutChecker, adapter_for, first_contacts

ROOT = pathlib.Path(__file__).resolve().parents[1]
MODEL = ROOT / "models" / "arm_planner.xml"
START = np.array([-0.8, -0.85, 0.8, 0.4, -0.5, 0.3])    # hand beside the beam, reaching as far out as the beam
GOAL = np.array([0.8, -0.85, 0.8, -0.4, 0.5, -0.3])     # the target: where the hand is in this pose
REACHED = 0.03   # metres from the target
QUICK = {"rollouts": 16, "horizon": 6, "iterations": 4}


def hand_at(model, qpos):
    """World position of the hand body in the joint configuration ``qpos``."""
    data = mujoco.MjData(model)
    data.qpos[:] = qpos
    mujoco.mj_kinematics(model, data)
    return data.xpos[model.body("hand").id].copy()


class Planner:
    """Random shooting around the previous plan: K sequences of ``horizon`` joint-target knots, each held
    ``hold`` steps; the first sample is the previous plan shifted by one knot, the second holds still."""

    def __init__(self, model, target, args):
        self.model, self.target, self.args = model, target, args
        self.rng = np.random.default_rng(args.seed)
        self.nthread = args.threads
        self.datas = [mujoco.MjData(model) for _ in range(max(1, self.nthread))]
        self.plan = None
        self.hand = model.sensor("hand_position").adr[0]

    def samples(self, current):
        """(K, horizon, nu) joint-target knots."""
        k, h, nu = self.args.rollouts, self.args.horizon, self.model.nu
        base = np.tile(current, (h, 1)) if self.plan is None else np.vstack([self.plan[1:], self.plan[-1:]])
        steps = self.rng.normal(scale=self.args.sigma, size=(k, h, nu))
        knots = base + np.cumsum(steps, axis=1)   # smooth: a random walk away from the plan
        knots[0] = base
        knots[1] = current
        lo, hi = self.model.actuator_ctrlrange.T
        return np.clip(knots, lo, hi)

    def costs(self, sensordata, knots):
        """(K,) the hand's mean distance to the target along each rollout, its final distance weighted 4x,
        and a small price on jumps of the targets."""
        hand = sensordata[:, :, self.hand:self.hand + 3]
        dist = np.linalg.norm(hand - self.target, axis=2)
        jumps = np.abs(np.diff(knots, axis=1)).sum(axis=(1, 2))
        return dist.mean(axis=1) + 4.0 * dist[:, -1] + 0.01 * jumps


def run(args):
    model = mujoco.MjModel.from_xml_path(str(MODEL))
    # the model's fitted ellipsoids (group 5); MuJoCo's rules collide nothing here (visual geoms only), so
    # the pairs are those between the arm and the beam
    adapter = adapter_for(model, geom_ellipsoids(model), pairs="characters", planes=False)
    checker = RolloutChecker(adapter, nthread=args.threads)
    target = hand_at(model, GOAL)
    data = mujoco.MjData(model)
    data.qpos[:] = START
    data.ctrl[:] = START
    mujoco.mj_forward(model, data)
    planner = Planner(model, target, args)
    nstate = mujoco.mj_stateSize(model, FULLPHYSICS)
    state0 = np.empty(nstate)
    executed, times = [data.qpos.copy()], [data.time]
    dropped = total = stalls = 0
    t_rollout = t_kin = t_check = 0.0
    steps = args.horizon * args.hold
    print(f"{len(adapter.ellipsoids)} ellipsoids, {len(adapter.pairs)} arm/beam pairs; {args.rollouts} rollouts of "
          f"{steps} steps ({steps * model.opt.timestep:.2f} s) per control step; target "
          f"[{', '.join(f'{x:.3f}' for x in target)}]")
    with mujoco.rollout.Rollout(nthread=args.threads) as pool:
        for it in range(args.iterations):
            mujoco.mj_getState(model, data, state0, FULLPHYSICS)
            knots = planner.samples(data.ctrl.copy())
            control = np.repeat(knots, args.hold, axis=1)
            tick = time.perf_counter()
            states, sensordata = pool.rollout(model, planner.datas, state0, control)
            tock = time.perf_counter()
            found = checker.first_contacts(states, initial_state=state0)
            t_rollout += tock - tick
            t_kin += checker.timing["kinematics"]
            t_check += checker.timing["check"]
            free = found.free
            total += len(free)
            dropped += int((~free).sum())
            if args.unchecked:
                free = np.ones_like(free)
            cost = planner.costs(sensordata, knots)
            if free.any():
                best = int(np.flatnonzero(free)[np.argmin(cost[free])])
                planner.plan = knots[best]
            else:  # every sample touches: hold still (a fresh plan next time)
                stalls += 1
                best, planner.plan = 1, None
            for _ in range(args.hold):
                data.ctrl[:] = knots[best, 0]
                mujoco.mj_step(model, data)
                executed.append(data.qpos.copy())
                times.append(data.time)
            distance = float(np.linalg.norm(data.xpos[model.body("hand").id] - target))
            if it % args.every == 0 or distance < REACHED:
                print(f"step {it:3d}  t = {data.time:5.2f} s  hand {distance:.3f} m from the target  "
                      f"{int(found.free.sum()):3d}/{len(free)} rollouts free" + ("" if free.any() else "  (holding)"))
            if distance < REACHED:
                break
    # the executed path, checked once more as one rollout of qpos rows
    path = first_contacts(adapter, qpos=np.array(executed)[None], start_time=times[0])
    n = total or 1
    print(f"\n{it + 1} control steps, {total} rollouts of {steps} steps: {dropped} rollouts "
          f"{'colliding (kept: --unchecked)' if args.unchecked else 'dropped as colliding'} "
          f"({100.0 * dropped / n:.0f} %), {stalls} steps with every rollout colliding")
    reached = distance < REACHED
    print(f"hand {distance:.3f} m from the target: {'reached' if reached else 'not reached'}")
    print("executed path: " + ("no contact" if path.free[0] else path.describe(0)))
    print(f"time per rollout ({steps} steps): MuJoCo rollout {1e3 * t_rollout / n:.3f} ms, mjccd check "
          f"{1e3 * (t_kin + t_check) / n:.3f} ms (kinematics {1e3 * t_kin / n:.3f} ms, batched CCD "
          f"{1e3 * t_check / n:.3f} ms); threads: {args.threads}")
    return reached and bool(path.free[0])


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rollouts", type=int, default=64, help="rollouts sampled per control step (default 64)")
    parser.add_argument("--horizon", type=int, default=8, help="knots per rollout (default 8)")
    parser.add_argument("--hold", type=int, default=5, help="simulator steps per knot (default 5: 50 ms)")
    parser.add_argument("--iterations", type=int, default=80, help="most control steps (default 80)")
    parser.add_argument("--sigma", type=float, default=0.06, help="random-walk step of the targets, rad")
    parser.add_argument("--threads", type=int, default=os.cpu_count() or 1,
                        help="threads for MuJoCo's rollout and for the kinematics of the check")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--every", type=int, default=5, help="print every this many control steps")
    parser.add_argument("--quick", action="store_true", help=f"a short run: {QUICK}")
    parser.add_argument("--unchecked", action="store_true",
                        help="keep the colliding rollouts (they are still counted): the plain sampling planner")
    args = parser.parse_args(argv)
    if args.quick:
        for name, value in QUICK.items():
            setattr(args, name, value)
        args.every = 1
    for name in ("rollouts", "horizon", "hold", "iterations", "threads", "every"):
        if getattr(args, name) < 1:
            parser.error(f"--{name}: expected an integer >= 1, got {getattr(args, name)}")
    if args.rollouts < 2:
        parser.error("--rollouts: expected at least 2 (the previous plan and holding still are two)")
    return 0 if run(args) or args.quick or args.unchecked else 1


if __name__ == "__main__":
    raise SystemExit(main())
