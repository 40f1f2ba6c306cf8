"""Cost of CCDMonitor on top of mj_step: two boxers at sparring distance, every cross pair checked.

The scene is ``models/boxing.xml`` (two CMU boxers, 21 bounding ellipsoids each) without
gravity, started from a real pose of ``data/boxing_traj.npz`` with random joint velocities,
so the bodies keep moving near each other.  Each measurement steps a fresh copy of that
state; the medians are over repeats of ``--steps`` steps.
"""
import argparse
import os
import pathlib
import platform
import statistics
import time

import mujoco
import numpy as np
from tqdm import tqdm

from mjccd.bench.report import write_section
from mjccd.mujoco import CCDMonitor, geom_ellipsoids

ROOT = pathlib.Path(__file__).resolve().parents[2]


def sparring_state(model, traj, frame, speed, seed):
    """MjData at a recorded pose, gravity off, random joint velocities of about ``speed`` rad/s."""
    model.opt.gravity[:] = 0.0
    data = mujoco.MjData(model)
    with np.load(traj) as d:
        data.qpos[:] = d["qpos"][frame]
    data.qvel[:] = np.random.default_rng(seed).normal(scale=speed, size=model.nv)
    mujoco.mj_forward(model, data)
    return data


def cross_pairs(ellipsoids):
    """Body pairs with one body of each boxer (body names start with ``a_`` and ``b_``)."""
    a = sorted({b for b in ellipsoids.bodies if b.startswith("a_")})
    b = sorted({b for b in ellipsoids.bodies if b.startswith("b_")})
    return [(x, y) for x in a for y in b]


def _per_step_ms(step, n):
    t0 = time.perf_counter()
    for _ in range(n):
        step()
    return (time.perf_counter() - t0) / n * 1e3


def run(model_path, traj, steps, repeats, frame, speed, seed):
    model = mujoco.MjModel.from_xml_path(str(model_path))
    start = sparring_state(model, traj, frame, speed, seed)
    ellipsoids = geom_ellipsoids(model)
    pairs = cross_pairs(ellipsoids)
    rows = {"mj_step": [], "rigid": [], "affine": []}
    counts = {}
    for _ in tqdm(range(repeats), desc="bench monitor", unit="repeat"):
        data = mujoco.MjData(model)
        mujoco.mj_copyData(data, model, start)
        rows["mj_step"].append(_per_step_ms(lambda: mujoco.mj_step(model, data), steps))
        for motion in ("rigid", "affine"):
            data = mujoco.MjData(model)
            mujoco.mj_copyData(data, model, start)
            monitor = CCDMonitor(model, data, ellipsoids, pairs=pairs, motion=motion)
            monitor.step()  # compile
            hits = []
            rows[motion].append(_per_step_ms(lambda: hits.append(monitor.step() is not None), steps))
            counts[motion] = (len(monitor.pairs), sum(hits))
    return {k: statistics.median(v) for k, v in rows.items()}, counts, len(ellipsoids.radii)


def markdown(med, counts, n_ell, args, command):
    base = med["mj_step"]
    lines = ["## MuJoCo step monitor (`mjccd bench monitor`)", "",
             f"Command: `{command}`  ",
             f"Machine: {platform.machine()}, {os.cpu_count()} cores, Python {platform.python_version()}, "
             f"MuJoCo {mujoco.__version__}", "",
             f"`models/boxing.xml` without gravity, {n_ell} ellipsoids, from frame {args.frame} of "
             f"`data/boxing_traj.npz` with random joint velocities (σ = {args.speed} rad/s); "
             f"median over {args.repeats} runs of {args.steps} steps.", "",
             "| stepping | ms per step | added by mjccd (ms) | pairs | steps with a contact |",
             "| --- | ---: | ---: | ---: | ---: |",
             f"| `mj_step` | {base:.3f} | | | |"]
    for motion in ("rigid", "affine"):
        pairs, hits = counts[motion]
        lines.append(f"| `CCDMonitor.step`, {motion} | {med[motion]:.3f} | {med[motion] - base:.3f} | "
                     f"{pairs} | {hits} |")
    return "\n".join(lines) + "\n"


def main(argv=None):
    parser = argparse.ArgumentParser(prog="mjccd bench monitor", description=__doc__.splitlines()[0])
    parser.add_argument("--model", default=str(ROOT / "models" / "boxing.xml"))
    parser.add_argument("--traj", default=str(ROOT / "data" / "boxing_traj.npz"))
    parser.add_argument("--steps", type=int, default=2000, help="steps per run (default 2000)")
    parser.add_argument("--repeats", type=int, default=3, help="runs (default 3)")
    parser.add_argument("--frame", type=int, default=135, help="trajectory frame of the start pose")
    parser.add_argument("--speed", type=float, default=1.0, help="joint velocity scale, rad/s")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--markdown", metavar="FILE", help="write the table into this markdown file")
    args = parser.parse_args(argv)
    if args.steps < 1 or args.repeats < 1 or args.frame < 0 or not args.speed >= 0:
        parser.error("--steps, --repeats must be >= 1, --frame and --speed >= 0")
    for path, field in ((args.model, "--model"), (args.traj, "--traj")):
        if not os.path.exists(path):
            parser.error(f"{field}: no such file: {path}")
    med, counts, n_ell = run(args.model, args.traj, args.steps, args.repeats, args.frame, args.speed, args.seed)
    command = "mjccd bench monitor" + ("" if argv is None else " " + " ".join(argv))
    text = markdown(med, counts, n_ell, args, command)
    print(text)
    if args.markdown:
        write_section(args.markdown, "monitor", text)
        print(f"written to {args.markdown}")
    return 0
