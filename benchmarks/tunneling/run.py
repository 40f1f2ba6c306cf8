"""Tunneling count and cost per simulated second: plain MuJoCo, smaller timesteps, guarded stepping.

Usage: python benchmarks/tunneling/run.py [--runs N] [--boxing-runs N] [--quick] [--mujoco4 PYTHON]
                                          [--out docs/tunneling_benchmarks.md] [--bench docs/benchmarks.md]

Writes the table to ``--out`` and, as its own marked section ("tunneling"), into ``--bench``.  With
``--mujoco4`` (the Python of an environment with MuJoCo >= 4; ``make tunneling`` makes one) the table
gets two peer columns from speculative.py: that MuJoCo's plain stepping and its speculative contacts.
"""
import argparse
import json
import os
import pathlib
import platform
import subprocess
import sys
import time

import mujoco
import numpy as np

HERE = pathlib.Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
from scenarios import CASES, DIVERGED, ROOT, Boxing, Cup, Episodes, Kick, Wall, quick_cases  # noqa: E402

from mjccd.bench.report import write_section  # noqa: E402
from mjccd.mujoco.guard import GuardedStepper  # noqa: E402

MODES = ("plain", "dt/2", "dt/5", "dt/10", "guarded")
DIVISOR = {"plain": 1, "dt/2": 2, "dt/5": 5, "dt/10": 10, "guarded": 1}
PEER_MODES = ("plain", "speculative")  # speculative.py's runs, under MuJoCo >= 4
DEFAULT_MUJOCO4 = ROOT / ".venv-mujoco4" / "bin" / "python"


def simulate(cls, dt, speed, mode, runs):
    """[(tunneled, seconds of CPU per simulated second, clamps, unstable, spin gain, energy, divergent)] of
    ``runs`` runs (seeds 0, 1, ...) on one simulation (see scenarios.Episodes): one model, one data and,
    guarded, one GuardedStepper.  The spin gain (boxing only, else None) is the swung arm's peak angular speed
    over its swing speed; the energy (closed scenarios, else None) the peak mechanical energy over the start
    kinetic energy (scenarios.Run)."""
    sc = cls(dt / DIVISOR[mode], speed=speed)
    guard = None

    def guarded(m, d):
        nonlocal guard
        guard = GuardedStepper(m, d, sc.ellipsoids(), pairs=sc.pairs)
        return guard.step

    episodes = Episodes(sc, guarded if mode == "guarded" else None)
    results = []
    for seed in range(runs):
        before = guard.clamps_total if guard else 0
        run = episodes.run(seed)
        results.append((run.tunneled, run.cost, (guard.clamps_total if guard else 0) - before, run.unstable,
                        sc.spin_gain(), run.energy, run.divergent))
    return results


def cell(tunneled, runs, cost, unstable, note=""):
    """One table cell: runs that tunneled / runs · median cost (· note) (· the unstable runs, if any)."""
    return f"{tunneled}/{runs} · {cost:.3g}" + (f" · {note}" if note else "") \
        + (f" · **{unstable} unstable**" if unstable else "")


def table(runs, cases, boxing_runs=None):
    """Rows of formatted cells, {(scenario, dt, speed, mode): (runs tunneled, median ms per simulated second)},
    for boxing {(scenario, dt, speed, mode): median spin gain} and, for closed scenarios,
    {(scenario, dt, speed, mode): ([energy of each run], divergent runs)}.  Boxing runs ``boxing_runs`` times
    (default ``runs``)."""
    rows, cells, gains, energies = [], {}, {}, {}
    for cls, dt, speeds in cases:
        n = boxing_runs if cls is Boxing and boxing_runs else runs
        simulate(cls, dt, speeds[0], "guarded", 1)  # compile the kernels
        for speed in speeds:
            row = [cls.name, f"{dt * 1e3:.3g}", f"{speed:g}"]
            for mode in MODES:
                res = simulate(cls, dt, speed, mode, n)
                tun = sum(r[0] for r in res)
                cost = np.median([r[1] for r in res]) * 1e3
                cells[cls.name, dt, speed, mode] = (tun, cost)
                if res[0][4] is not None:
                    gains[cls.name, dt, speed, mode] = np.median([r[4] for r in res])
                if res[0][5] is not None:
                    energies[cls.name, dt, speed, mode] = ([r[5] for r in res], sum(r[6] for r in res))
                clamps = np.median([r[2] for r in res])
                note = f"{clamps:g} clamp" + ("" if clamps == 1 else "s") if mode == "guarded" else ""
                row.append(cell(tun, n, cost, sum(r[3] for r in res), note))
            rows.append(row)
            print(" | ".join(row), flush=True)
    return rows, cells, gains, energies


def peer_records(python, runs, quick, boxing_runs=None):
    """{(scenario, dt, speed, mode): record} of speculative.py, run by ``python`` (an environment with MuJoCo 4)."""
    cmd = [python, str(HERE / "speculative.py"), "--runs", str(runs)] + (["--quick"] if quick else []) \
        + (["--boxing-runs", str(boxing_runs)] if boxing_runs else [])
    proc = subprocess.run(cmd, stdout=subprocess.PIPE, text=True)  # its progress goes to stderr
    if proc.returncode != 0:
        raise SystemExit(f"--mujoco4: `{' '.join(cmd)}` failed with exit code {proc.returncode}")
    records = [json.loads(line) for line in proc.stdout.splitlines() if line.strip()]
    return {(r["scenario"], r["dt"], r["speed"], r["mode"]): r for r in records}


def add_peer(rows, cells, peer):
    """Append the peer's cells to each row; its (tunneled, cost) join ``cells`` as modes "mujoco4 plain" etc."""
    row_keys = list(dict.fromkeys(k[:3] for k in cells))  # (scenario, dt, speed) of each row, in order
    for row, key in zip(rows, row_keys):
        for mode in PEER_MODES:
            r = peer[key + (mode,)]
            cells[key + ("mujoco4 " + mode,)] = (r["tunneled"], r["cost"])
            row.append(cell(r["tunneled"], r["runs"], r["cost"], r["unstable"]))


def peer_summary(cells, runs, boxing_runs=None):
    """Lines comparing speculative contacts with guarded stepping where plain MuJoCo tunnels in most runs
    (``runs`` per cell, ``boxing_runs`` per boxing cell)."""
    keys = [k[:3] for k in cells if k[3] == "plain"
            and cells[k][0] > (boxing_runs if k[0] == "boxing" and boxing_runs else runs) / 2]
    if not keys:
        return []
    stopped = sum(cells[k + ("mujoco4 speculative",)][0] == 0 for k in keys)
    ratios = [cells[k + ("guarded",)][1] / cells[k + ("mujoco4 speculative",)][1] for k in keys]
    return ["", f"Where plain MuJoCo tunnels in most runs ({len(keys)} cells): speculative contacts stop "
                f"tunneling in {stopped}, guarded stepping in "
                f"{sum(cells[k + ('guarded',)][0] == 0 for k in keys)}; guarded stepping costs "
                f"{min(ratios):.2g}-{max(ratios):.2g}x (median {np.median(ratios):.2g}x) what speculative "
                "contacts cost."]


def spin_lines(gains):
    """Lines giving the boxing arm's median spin gain per speed and mode."""
    speeds = sorted({k[:3] for k in gains}, key=lambda k: k[2])
    if not speeds:
        return []
    parts = ["; ".join(f"{speed:g} m/s: " + ", ".join(f"{mode} {gains[(name, dt, speed, mode)]:.2g}"
                                                       for mode in MODES if (name, dt, speed, mode) in gains)
                       for name, dt, speed in speeds)]
    return ["", "Boxing, the swung arm's peak angular speed over its swing speed (median of the runs; above 1 "
                "the contact added energy to the swing): " + parts[0] + ". See guarded-stepping.md, "
                "\"What it does not guarantee\"."]


def energy_number(value):
    """A peak energy ratio for the table: two decimals, three digits when large."""
    return f"{value:.2f}" if value < 100 else f"{value:.3g}"


def energy_lines(energies):
    """A table of the closed scenarios' peak energy per mode and, for boxing, the guarded runs against the
    `dt/10` runs of the same seeds."""
    keys = list(dict.fromkeys(k[:3] for k in energies))
    if not keys:
        return []
    modes = [mode for mode in MODES if keys[0] + (mode,) in energies]
    lines = ["", "Energy in the closed scenarios (the wall and the boxing swing: nothing does work on the bodies, "
                 "so their mechanical energy can only fall): the peak over a run of the kinetic plus potential energy "
                 "(less the start potential energy) over the start kinetic energy, measured after every step of each "
                 "mode (each step of `dt/k`, each whole guarded step), median (max) of the runs. **k divergent**: in k "
                 f"runs MuJoCo reset the simulation or the energy reached {DIVERGED:g} times the start.", "",
             "| scenario | dt (ms) | speed (m/s) | " + " | ".join(modes) + " |", "|" + "---|" * (3 + len(modes))]
    for name, dt, speed in keys:
        row = [name, f"{dt * 1e3:.3g}", f"{speed:g}"]
        for mode in modes:
            values, divergent = energies[name, dt, speed, mode]
            row.append(f"{energy_number(np.median(values))} ({energy_number(max(values))})"
                       + (f" · **{divergent} divergent**" if divergent else ""))
        lines.append("| " + " | ".join(row) + " |")
    parts = []
    for name, dt, speed in keys:
        if name != "boxing" or (name, dt, speed, "dt/10") not in energies:
            continue
        ratios = np.array(energies[name, dt, speed, "guarded"][0]) / np.array(energies[name, dt, speed, "dt/10"][0])
        parts.append(f"{speed:g} m/s: median {np.median(ratios):.3f}, max "
                     + (f"{ratios.max():.3f}" if ratios.max() < 100 else f"{ratios.max():.3g}"))
    if parts:
        lines += ["", "Boxing, guarded peak energy over the `dt/10` peak energy of the same seed: " + "; ".join(parts)
                  + "."]
    return lines


def markdown(rows, cells, runs, command, elapsed, peer_version=None, gains=None, energies=None, boxing_runs=None):
    head = ["scenario", "dt (ms)", "speed (m/s)"] + list(MODES)
    peer_text = []
    if peer_version:
        head += [f"MuJoCo {peer_version} plain", f"MuJoCo {peer_version} speculative"]
        peer_text = [f"Peer columns: the same runs under MuJoCo {peer_version} in an environment of its own "
                     "(`benchmarks/tunneling/speculative.py`, run by this command after the other columns), "
                     "plain and with speculative contacts (`<flag speculative=\"enable\"/>`, MuJoCo >= 4.0; "
                     "dm-control does not run on it yet). A speculative contact is a contact MuJoCo sees, so "
                     "the boxing test counts it as seen."]
    lines = ["# Tunneling benchmarks", "",
             "Each cell: runs that tunneled / runs · median CPU milliseconds per simulated second "
             "(the controller and the step are timed, the tunneling test is not). "
             "\"k unstable\": in k runs MuJoCo met a NaN, infinite or huge position, velocity or acceleration "
             "and reset the simulation (its bad-state warnings); such a run did not tunnel only because it "
             "restarted.",
             f"{runs} runs per cell ({boxing_runs or runs} for boxing) with jittered start (position and speed "
             "±10 %), on one simulation per cell "
             "(model, data and guard built once; each run resets the data, as an episode does). "
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
             "colliding through one ellipsoid per body (bounding that body's bounds), integrated with MuJoCo's "
             "implicit integrator (with the "
             "default Euler the guarded runs at 60 m/s diverge; see guarded-stepping.md) (tunneled: "
             "the fist past the head's centre before MuJoCo saw any arm-head contact); "
             f"`kick` ({Kick.duration:g} s) the wall's ball at rest 2 cm from the wall, kicked towards it by a "
             "force that acts for the first 10 ms and leaves it at the given speed (tunneled: the ball centre "
             "beyond the wall's mid-plane before MuJoCo saw any ball-wall contact; at 200 m/s the kick, 2000 times "
             "the ball's weight, pushes a ball MuJoCo sees touching through its soft contact in every mode, which "
             "is not counted).",
             *peer_text, "", "| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    lines += ["| " + " | ".join(r) + " |" for r in rows]
    ratios = [(dt, speed, cells[name, dt, speed, "guarded"][1] / cells[name, dt, speed, "plain"][1])
              for (name, dt, speed, mode) in cells if name == "boxing" and mode == "plain"]
    if ratios:
        dt, speed, ratio = min(ratios, key=lambda r: r[1])
        lines += ["", f"Boxing at the normal speed ({speed:g} m/s): guarded stepping costs "
                      f"{ratio:.2f}x plain stepping."]
    lines += spin_lines(gains or {})
    lines += energy_lines(energies or {})
    if peer_version:
        lines += peer_summary(cells, runs, boxing_runs)
    lines += ["", f"Command: `{command}` ({elapsed:.0f} s).", "",
              f"Machine: {platform.processor() or platform.machine()}, {os.cpu_count()} CPUs, "
              f"Python {platform.python_version()}, MuJoCo {mujoco.__version__}, {platform.system()}.", ""]
    return "\n".join(lines)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=20, help="runs per cell (default 20)")
    ap.add_argument("--boxing-runs", type=int, default=100, help="runs per boxing cell (default 100)")
    ap.add_argument("--quick", action="store_true", help="one timestep and speed per scenario")
    default_peer = os.environ.get("MJCCD_MUJOCO4_PYTHON") or (
        str(DEFAULT_MUJOCO4) if DEFAULT_MUJOCO4.exists() else "")
    ap.add_argument("--mujoco4", default=default_peer, metavar="PYTHON",
                    help="Python of an environment with MuJoCo >= 4 for the speculative-contacts peer columns "
                         "(default: $MJCCD_MUJOCO4_PYTHON, else .venv-mujoco4/bin/python if present; '' for none)")
    ap.add_argument("--out", default=str(ROOT / "docs" / "tunneling_benchmarks.md"),
                    help="markdown file to write ('' for none)")
    ap.add_argument("--bench", default=str(ROOT / "docs" / "benchmarks.md"),
                    help="benchmark report whose 'tunneling' section gets the table ('' for none)")
    args = ap.parse_args(argv)
    if args.runs < 1:
        ap.error(f"--runs: expected a positive count, got {args.runs}")
    if args.boxing_runs < 1:
        ap.error(f"--boxing-runs: expected a positive count, got {args.boxing_runs}")
    cases = quick_cases() if args.quick else CASES
    if args.mujoco4 and not pathlib.Path(args.mujoco4).exists():
        ap.error(f"--mujoco4: no Python at {args.mujoco4} (make tunneling sets one up in .venv-mujoco4)")
    t0 = time.perf_counter()
    rows, cells, gains, energies = table(args.runs, cases, args.boxing_runs)
    peer_version = None
    if args.mujoco4:
        peer = peer_records(args.mujoco4, args.runs, args.quick, args.boxing_runs)
        add_peer(rows, cells, peer)
        peer_version = next(iter(peer.values()))["mujoco"]
    text = markdown(rows, cells, args.runs, "python benchmarks/tunneling/run.py " + " ".join(argv or sys.argv[1:]),
                    time.perf_counter() - t0, peer_version, gains, energies, args.boxing_runs)
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
