"""Tunneling count and cost per simulated second: plain MuJoCo, smaller timesteps, guarded stepping.

Usage: python benchmarks/tunneling/run.py [--runs N] [--quick] [--out docs/tunneling_benchmarks.md]
                                          [--bench docs/benchmarks.md]

Writes the table to ``--out`` and, as its own marked section ("tunneling"), into ``--bench``.
"""
import argparse
import os
import pathlib
import platform
import sys
import time

import mujoco
import numpy as np

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent))
from scenarios import ROOT, Boxing, Cup, Wall  # noqa: E402

from mjccd.bench.report import write_section  # noqa: E402
from mjccd.mujoco.guard import BAD_STATE_WARNINGS, GuardedStepper  # noqa: E402

MODES = ("plain", "dt/2", "dt/5", "dt/10", "guarded")
CASES = [
    (Wall, 0.002, (10.0, 50.0, 200.0)),
    (Wall, 0.005, (10.0, 50.0, 200.0)),
    (Wall, 0.010, (10.0, 50.0, 200.0)),
    (Cup, 0.002, (2.0, 10.0, 20.0)),
    (Cup, 0.010, (2.0, 10.0, 20.0)),
    (Boxing, 1 / 120, (5.0, 20.0, 60.0)),
]


def simulate(cls, dt, speed, mode, seed):
    """(tunneled, seconds of CPU per simulated second, clamps, unstable) of one run.

    ``unstable``: MuJoCo met a NaN, infinite or huge position, velocity or acceleration and reset the
    data (its bad-state warnings); the rest of such a run simulates the start pose, so "not tunneled"
    means nothing there.
    """
    div = {"plain": 1, "dt/2": 2, "dt/5": 5, "dt/10": 10, "guarded": 1}[mode]
    sc = cls(dt / div, speed=speed)
    m = sc.model
    d = mujoco.MjData(m)
    sc.reset(d, np.random.default_rng(seed))
    guard = GuardedStepper(m, d, sc.ellipsoids(), pairs=sc.pairs) if mode == "guarded" else None
    steps = int(round(sc.duration / m.opt.timestep))
    tunneled = False
    elapsed = 0.0
    for _ in range(steps):
        t0 = time.perf_counter()  # the controller and the step are timed, the tunneling test is not
        sc.control(d)
        if guard is None:
            mujoco.mj_step(m, d)
        else:
            guard.step()
        elapsed += time.perf_counter() - t0
        tunneled = tunneled or sc.tunneled(d)
    unstable = any(d.warning[int(w)].number > 0 for w in BAD_STATE_WARNINGS)
    return tunneled, elapsed / sc.duration, 0 if guard is None else guard.clamps_total, unstable


def table(runs, cases):
    """Rows of formatted cells, and the raw medians {(scenario, dt, speed, mode): ms per simulated second}."""
    rows, costs = [], {}
    for cls, dt, speeds in cases:
        simulate(cls, dt, speeds[0], "guarded", 0)  # compile and warm the caches
        for speed in speeds:
            row = [cls.name, f"{dt * 1e3:.3g}", f"{speed:g}"]
            for mode in MODES:
                res = [simulate(cls, dt, speed, mode, seed) for seed in range(runs)]
                tun = sum(r[0] for r in res)
                cost = np.median([r[1] for r in res]) * 1e3
                unstable = sum(r[3] for r in res)
                costs[cls.name, dt, speed, mode] = cost
                cell = f"{tun}/{runs} · {cost:.3g}"
                if mode == "guarded":
                    clamps = np.median([r[2] for r in res])
                    cell += f" · {clamps:g} clamp" + ("" if clamps == 1 else "s")
                row.append(cell + (f" · **{unstable} unstable**" if unstable else ""))
            rows.append(row)
            print(" | ".join(row), flush=True)
    return rows, costs


def markdown(rows, costs, runs, command, elapsed):
    head = ["scenario", "dt (ms)", "speed (m/s)"] + list(MODES)
    lines = ["# Tunneling benchmarks", "",
             "Each cell: runs that tunneled / runs · median CPU milliseconds per simulated second "
             "(the controller and the step are timed, the tunneling test is not). "
             "\"k unstable\": in k runs MuJoCo met a NaN, infinite or huge position, velocity or acceleration "
             "and reset the simulation (its bad-state warnings); such a run did not tunnel only because it "
             "restarted.",
             f"{runs} runs per cell with jittered start (position and speed ±10 %). "
             "`dt/k` is plain MuJoCo with the timestep divided by k; `guarded` is "
             "`mjccd.mujoco.guard.GuardedStepper` at the scenario timestep, with the median number of "
             "clamps per run.",
             "Scenarios (`benchmarks/tunneling/scenarios.py`; simulated time per run in brackets): "
             f"`wall` ({Wall.duration:g} s) a 2 cm ball thrown at a 2 cm ellipsoid "
             "wall (tunneled: the ball centre ever beyond the wall's mid-plane); "
             f"`cup` ({Cup.duration:g} s) three balls in a closed "
             "thin-walled cup (floor, four walls and a lid, ellipsoids overlapping at every edge) jerked "
             "sideways for 30 ms (tunneled: a ball centre outside the cup); "
             f"`boxing` ({Boxing.duration:g} s) "
             "a's right arm swung about the shoulder through b's head in models/boxing.xml, arm and head "
             "colliding through their bounding ellipsoids, integrated with MuJoCo's implicit integrator (with the "
             "default Euler the guarded runs at 20 and 60 m/s diverged; see guarded-stepping.md) (tunneled: "
             "the fist past the head's centre before MuJoCo saw any arm-head contact).", "",
             "| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    lines += ["| " + " | ".join(r) + " |" for r in rows]
    ratios = [(dt, speed, costs[name, dt, speed, "guarded"] / costs[name, dt, speed, "plain"])
              for (name, dt, speed, mode) in costs if name == "boxing" and mode == "plain"]
    if ratios:
        dt, speed, ratio = min(ratios, key=lambda r: r[1])
        lines += ["", f"Boxing at the normal speed ({speed:g} m/s): guarded stepping costs "
                      f"{ratio:.2f}x plain stepping."]
    lines += ["", f"Command: `{command}` ({elapsed:.0f} s).", "",
              f"Machine: {platform.processor() or platform.machine()}, {os.cpu_count()} CPUs, "
              f"Python {platform.python_version()}, MuJoCo {mujoco.__version__}, {platform.system()}.", ""]
    return "\n".join(lines)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=10, help="runs per cell (default 10)")
    ap.add_argument("--quick", action="store_true", help="one timestep and speed per scenario")
    ap.add_argument("--out", default=str(ROOT / "docs" / "tunneling_benchmarks.md"),
                    help="markdown file to write ('' for none)")
    ap.add_argument("--bench", default=str(ROOT / "docs" / "benchmarks.md"),
                    help="benchmark report whose 'tunneling' section gets the table ('' for none)")
    args = ap.parse_args(argv)
    if args.runs < 1:
        ap.error(f"--runs: expected a positive count, got {args.runs}")
    cases = [(c, dt, s[-1:]) for c, dt, s in CASES[::2]] if args.quick else CASES
    t0 = time.perf_counter()
    rows, costs = table(args.runs, cases)
    text = markdown(rows, costs, args.runs, "python benchmarks/tunneling/run.py " + " ".join(argv or sys.argv[1:]),
                    time.perf_counter() - t0)
    print(text)
    if args.out:
        pathlib.Path(args.out).write_text(text)
    if args.bench:
        section = text.replace("# Tunneling benchmarks", "## Tunneling: plain, smaller timesteps, guarded stepping", 1)
        section += "\nGuarded stepping: [guarded-stepping.md](guarded-stepping.md); this table also in " \
                   "[tunneling_benchmarks.md](tunneling_benchmarks.md).\n"
        write_section(args.bench, "tunneling", section)


if __name__ == "__main__":
    main()
