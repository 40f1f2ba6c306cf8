"""Cost of checking MuJoCo rollouts with mjccd against the cost of the rollouts themselves (Kinova arm and I-beam).

    python benchmarks/rollout/run.py                              # K = 16, 64, 256 rollouts of 40 steps
    python benchmarks/rollout/run.py --markdown docs/benchmarks.md   # also write the 'rollout' section

For each K: K random sequences of joint targets for the servos of models/arm_planner.xml (random walks from the
start pose of examples/rollout_planner.py, drifting across the beam, so that some rollouts touch it), rolled
out by ``mujoco.rollout.Rollout`` (persistent thread pool, one MjData per thread), then checked by
:class:`mjccd.mujoco.rollout.RolloutChecker`: the kinematics (states to ellipsoid poses) and the batched exact
CCD (:class:`mjccd.batch.BatchScene`) timed apart.  Medians over the repeats, per rollout.
"""
import argparse
import os
import pathlib
import platform
import statistics
import sys
import time

import mujoco
import mujoco.rollout
import numba
import numpy as np

from mjccd.files import write_text
from mjccd.mujoco import geom_ellipsoids
from mjccd.mujoco.rollout import FULLPHYSICS, RolloutChecker, adapter_for

ROOT = pathlib.Path(__file__).resolve().parents[2]
MODEL = ROOT / "models" / "arm_planner.xml"
START = np.array([-0.8, -0.85, 0.8, 0.4, -0.5, 0.3])   # examples/rollout_planner.py's start and goal poses
GOAL = np.array([0.8, -0.85, 0.8, -0.4, 0.5, -0.3])
BEGIN, END = "<!-- rollout: begin -->", "<!-- rollout: end -->"


def measure(model, checker, pool, datas, state0, k, steps, repeats, rng):
    """Medians per rollout in ms: (MuJoCo rollout, kinematics, CCD), and the share of colliding rollouts."""
    rows = {"rollout": [], "kinematics": [], "check": []}
    colliding = []
    drift = np.linspace(0.0, 1.0, steps)[None, :, None] * (GOAL - START) * rng.uniform(0.2, 1.0, (k, 1, 1))
    for _ in range(repeats + 1):  # the first round loads the compiled kernels and is not counted
        control = START + drift + np.cumsum(rng.normal(scale=0.03, size=(k, steps, model.nu)), axis=1)
        tick = time.perf_counter()
        states, _ = pool.rollout(model, datas, state0, control)
        elapsed = time.perf_counter() - tick
        found = checker.first_contacts(states, initial_state=state0)
        rows["rollout"].append(elapsed)
        for name in ("kinematics", "check"):
            rows[name].append(checker.timing[name])
        colliding.append(found.colliding.mean())
        assert found.ok.all(), found.errors
    return {name: 1e3 * statistics.median(v[1:]) / k for name, v in rows.items()}, statistics.mean(colliding[1:])


def markdown(results, args, command, npairs, nell):
    lines = ["## Checking MuJoCo rollouts (`benchmarks/rollout/run.py`)", "",
             f"Command: `{command}`  ",
             f"Machine: {platform.machine()}, {os.cpu_count()} cores, Python {platform.python_version()}, "
             f"MuJoCo {mujoco.__version__}, numba {numba.__version__}", "",
             f"`models/arm_planner.xml` (the Jaco arm of `models/arm_obstacle.xml` with joint position servos, "
             f"timestep {args.timestep * 1e3:g} ms): K rollouts of {args.steps} steps from one state, random walks "
             f"of the servo targets drifting across the I-beam; {nell} ellipsoids, {npairs} arm/beam pairs, "
             f"rigid motion, every step of every rollout checked up to its first contact. "
             f"`mujoco.rollout.Rollout` with {args.threads} threads; mjccd: `RolloutChecker.first_contacts`: "
             f"the kinematics column reads and checks the {args.steps + 1} states of each rollout and runs "
             f"`mj_kinematics` and the adapter's pose routine on each (up to {args.threads} threads), the CCD "
             f"column is `BatchScene.first_contacts_along` on {numba.get_num_threads()} numba threads. Median of "
             f"{args.repeats} runs, ms per rollout, on a machine shared with other jobs (±20 %).", "",
             "| K | MuJoCo rollout | mjccd kinematics | mjccd CCD | mjccd total | mjccd / rollout | colliding |",
             "| ---: | ---: | ---: | ---: | ---: | ---: | ---: |"]
    for k, (med, hit) in results.items():
        total = med["kinematics"] + med["check"]
        lines.append(f"| {k} | {med['rollout']:.3f} | {med['kinematics']:.3f} | {med['check']:.3f} | {total:.3f} | "
                     f"{total / med['rollout']:.2f} | {100 * hit:.0f} % |")
    lines += ["", "A rollout's CCD stops at its first contact, so colliding rollouts cost less to check than "
                  "free ones."]
    return "\n".join(lines) + "\n"


def write_section(path, text):
    """Replace the text between the rollout markers of ``path`` (or append the section)."""
    block = f"{BEGIN}\n{text.rstrip()}\n{END}\n"
    old = pathlib.Path(path).read_text(encoding="utf-8") if os.path.exists(path) else "# Benchmarks\n"
    if BEGIN in old and END in old:
        new = old[:old.index(BEGIN)] + block + old[old.index(END) + len(END) + 1:]
    else:
        new = old.rstrip("\n") + "\n\n" + block
    write_text(path, new)


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rollouts", type=int, nargs="+", default=[16, 64, 256], help="values of K")
    parser.add_argument("--steps", type=int, default=40, help="steps per rollout (default 40)")
    parser.add_argument("--repeats", type=int, default=7, help="timed runs per K (default 7)")
    parser.add_argument("--threads", type=int, default=os.cpu_count() or 1,
                        help="threads for MuJoCo's rollout and for the kinematics of the check")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--markdown", metavar="FILE", help="write the table between the rollout markers of FILE")
    args = parser.parse_args(argv)
    for name in ("steps", "repeats", "threads"):
        if getattr(args, name) < 1:
            parser.error(f"--{name}: expected an integer >= 1, got {getattr(args, name)}")
    if min(args.rollouts) < 1:
        parser.error(f"--rollouts: expected integers >= 1, got {args.rollouts}")
    model = mujoco.MjModel.from_xml_path(str(MODEL))
    args.timestep = model.opt.timestep
    adapter = adapter_for(model, geom_ellipsoids(model), pairs="characters", planes=False)
    checker = RolloutChecker(adapter, nthread=args.threads)
    data = mujoco.MjData(model)
    data.qpos[:] = START
    data.ctrl[:] = START
    mujoco.mj_forward(model, data)
    state0 = np.empty(mujoco.mj_stateSize(model, FULLPHYSICS))
    mujoco.mj_getState(model, data, state0, FULLPHYSICS)
    datas = [mujoco.MjData(model) for _ in range(args.threads)]
    rng = np.random.default_rng(args.seed)
    results = {}
    with mujoco.rollout.Rollout(nthread=args.threads) as pool:
        for k in args.rollouts:
            results[k] = measure(model, checker, pool, datas, state0, k, args.steps, args.repeats, rng)
    command = " ".join(["python benchmarks/rollout/run.py", *(sys.argv[1:] if argv is None else argv)])
    text = markdown(results, args, command, len(adapter.pairs), len(adapter.ellipsoids))
    print(text)
    if args.markdown:
        write_section(args.markdown, text)
        print(f"written to {args.markdown}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
