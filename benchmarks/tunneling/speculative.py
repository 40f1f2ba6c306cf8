"""Peer: MuJoCo 4's speculative contacts on the tunneling scenarios, run in an environment of their own.

Usage: <python of an environment with mujoco>=4 and numpy> benchmarks/tunneling/speculative.py [--runs N]
       [--boxing-runs N] [--quick]

mjccd runs on the MuJoCo that dm-control supports; MuJoCo 4.0 added speculative contacts
(``<flag speculative="enable"/>``), which make rigid geoms that would pass each other within a step
collide ahead of time.  For every cell of run.py's table this script times plain stepping and
speculative stepping with that MuJoCo (same scenarios, seeds and jitter) and prints one JSON object per
line: scenario, dt, speed, mode ("plain" or "speculative"), tunneled, runs, cost (median ms of CPU per
simulated second), unstable.  ``run.py --mujoco4 PYTHON`` runs it and adds both as peer columns.
"""
import argparse
import json
import pathlib
import sys

import mujoco
import numpy as np

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent))
from scenarios import CASES, Boxing, Episodes, quick_cases  # noqa: E402

SPECULATIVE = getattr(getattr(mujoco, "mjtEnableBit", None), "mjENBL_SPECULATIVE", None)


def simulate(cls, dt, speed, speculative, runs):
    """[scenarios.Run] of ``runs`` runs on one simulation."""
    sc = cls(dt, speed=speed)
    if speculative:
        sc.model.opt.enableflags |= int(SPECULATIVE)
    episodes = Episodes(sc)
    return [episodes.run(seed) for seed in range(runs)]


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=20, help="runs per cell (default 20)")
    ap.add_argument("--boxing-runs", type=int, default=None, help="runs per boxing cell (default: --runs)")
    ap.add_argument("--quick", action="store_true", help="one timestep and speed per scenario")
    args = ap.parse_args(argv)
    if args.runs < 1:
        ap.error(f"--runs: expected a positive count, got {args.runs}")
    if args.boxing_runs is not None and args.boxing_runs < 1:
        ap.error(f"--boxing-runs: expected a positive count, got {args.boxing_runs}")
    if SPECULATIVE is None:
        ap.error(f"this environment has MuJoCo {mujoco.__version__}, which has no speculative contacts "
                 "(they came with MuJoCo 4.0)")
    for cls, dt, speeds in quick_cases() if args.quick else CASES:
        runs = args.boxing_runs if cls is Boxing and args.boxing_runs else args.runs
        simulate(cls, dt, speeds[0], True, 1)  # warm up
        for speed in speeds:
            for mode in ("plain", "speculative"):
                res = simulate(cls, dt, speed, mode == "speculative", runs)
                record = {"scenario": cls.name, "dt": dt, "speed": speed, "mode": mode,
                          "tunneled": int(sum(r.tunneled for r in res)), "runs": runs,
                          "cost": float(np.median([r.cost for r in res]) * 1e3),
                          "unstable": int(sum(r.unstable for r in res)), "mujoco": mujoco.__version__}
                print(json.dumps(record), flush=True)
                print(f"{cls.name} {dt * 1e3:.3g} ms {speed:g} m/s {mode}: {record['tunneled']}/{runs} "
                      f"tunneled, {record['cost']:.3g} ms/s", file=sys.stderr, flush=True)


if __name__ == "__main__":
    main()
