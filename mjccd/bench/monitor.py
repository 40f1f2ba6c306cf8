"""Cost of CCDMonitor on top of mj_step: two boxers at sparring distance, every cross pair checked.

The scene is ``models/boxing.xml`` (two CMU boxers, bounded by 46 and 48 ellipsoids, the default 1 cm fit) without
gravity, started from a real pose of ``data/boxing_traj.npz`` (the package ships its first
150 frames) with random joint velocities and each boxer's centre of mass at rest, so the
limbs keep moving near each other.  MuJoCo steps it at 2 ms with a little joint damping:
at the model's own 1/120 s the lightest parts spin up until MuJoCo finds a bad
acceleration and resets the simulation.  Each measurement steps a fresh copy of that
state; the medians are over repeats of ``--steps`` steps.  A run in which MuJoCo warns (of
a bad state, after which it resets the simulation) stops the bench with an error instead
of timing the reset pose.  Rigid steps check the boxers' own geoms (geoms mode, the monitor's
default for rigid motion), affine steps their bounding ellipsoids.
"""
import argparse
import os
import platform
import statistics
import sys
import time

import mujoco
import numpy as np
from tqdm import tqdm

from mjccd import replay
from mjccd.bench import options
from mjccd.bench.report import write_section
from mjccd.errors import InputError
from mjccd.mujoco import CCDMonitor, geom_ellipsoids
from mjccd.mujoco.warnings import mujoco_warnings
from mjccd._command import PlainHelpFormatter

TIMESTEP = 0.002     # s, MuJoCo's default
LIMB_DAMPING = 0.02  # N m s / rad on every joint but the boxers' free joints
QUICK = {"steps": 50, "repeats": 1}
RANGES = {"steps": (1, 1_000_000), "repeats": (1, 1000), "frame": (0, 10**9), "speed": (0.0, 100.0),
          "seed": (0, 2**63 - 1)}


def _free_joints(model):
    return [j for j in range(model.njnt) if model.jnt_type[j] == mujoco.mjtJoint.mjJNT_FREE]


def sparring_state(model, qpos, speed, seed):
    """MjData at the pose ``qpos``, limbs moving at random joint velocities of about ``speed`` rad/s.

    Also sets the scene's physics on ``model``: no gravity, :data:`TIMESTEP`
    and :data:`LIMB_DAMPING`.  Each boxer's root gets the linear velocity that
    keeps its centre of mass at rest, so the two stay at sparring distance.
    """
    model.opt.gravity[:] = 0.0
    model.opt.timestep = TIMESTEP
    roots = np.zeros(model.nv, dtype=bool)
    for j in _free_joints(model):
        roots[model.jnt_dofadr[j]:model.jnt_dofadr[j] + 6] = True
    model.dof_damping[~roots] = LIMB_DAMPING
    data = mujoco.MjData(model)
    data.qpos[:] = qpos
    data.qvel[~roots] = np.random.default_rng(seed).normal(scale=speed, size=int(np.sum(~roots)))
    mujoco.mj_forward(model, data)
    mujoco.mj_subtreeVel(model, data)
    for j in _free_joints(model):
        data.qvel[model.jnt_dofadr[j]:model.jnt_dofadr[j] + 3] -= data.subtree_linvel[model.jnt_bodyid[j]]
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


def check_stable(model, data, start_time, steps, run, warned):
    """Raise InputError if MuJoCo warned during ``run`` or reset the simulation (after a bad state it resets
    the data, and the timing would then be of the reset pose); ``warned``: the warning texts collected."""
    raised = [mujoco.mjtWarning(w).name for w in range(len(data.warning)) if data.warning[w].number]
    reset = abs(data.time - (start_time + steps * model.opt.timestep)) > 1e-6 * max(1.0, data.time)
    if raised or reset:
        said = "; ".join(warned) or ", ".join(raised) or "no warning"
        raise InputError(f"the {run} run went wrong: MuJoCo {'reset the simulation' if reset else 'warned'} "
                         f"({said}); try a lower --speed or another --frame or --seed")


def run(model, qpos, ellipsoids, pairs, steps, repeats, speed, seed):
    """Median ms per step of mj_step and CCDMonitor.step (rigid, affine); (pairs, steps with a contact) per motion."""
    start = sparring_state(model, qpos, speed, seed)
    rows = {"mj_step": [], "rigid": [], "affine": []}
    counts = {}
    with mujoco_warnings() as warned:
        for _ in tqdm(range(repeats), desc="bench monitor", unit="repeat", disable=not sys.stderr.isatty()):
            data = mujoco.MjData(model)
            mujoco.mj_copyData(data, model, start)
            rows["mj_step"].append(_per_step_ms(lambda: mujoco.mj_step(model, data), steps))
            check_stable(model, data, start.time, steps, "mj_step", warned)
            for motion in ("rigid", "affine"):
                data = mujoco.MjData(model)
                mujoco.mj_copyData(data, model, start)
                monitor = CCDMonitor(model, data, ellipsoids, pairs=pairs, motion=motion)
                monitor.step()  # compile
                hits = []
                rows[motion].append(_per_step_ms(lambda: hits.append(monitor.step() is not None), steps))
                check_stable(model, data, start.time, steps + 1, f"CCDMonitor.step ({motion})", warned)
                counts[motion] = (monitor.mode, len(monitor.pairs), sum(hits))
    return {k: statistics.median(v) for k, v in rows.items()}, counts


def markdown(med, counts, n_ell, args, command):
    base = med["mj_step"]
    lines = ["## MuJoCo step monitor (`mjccd bench monitor`)", "",
             f"Command: `{command}`  ",
             f"Machine: {platform.machine()}, {os.cpu_count()} cores, Python {platform.python_version()}, "
             f"MuJoCo {mujoco.__version__}", "",
             f"`{options.shown(args.model)}` without gravity, {n_ell} ellipsoids, from frame {args.frame} of "
             f"`{options.shown(args.traj)}` with random joint velocities (σ = {args.speed} rad/s) and each boxer's "
             f"centre of mass at rest; time step {TIMESTEP * 1e3:g} ms, joint damping {LIMB_DAMPING:g} N·m·s/rad; "
             f"median over {args.repeats} runs of {args.steps} steps, none of which met a bad state.", "",
             "| stepping | what touches | ms per step | added by mjccd (ms) | pairs | steps with a contact |",
             "| --- | --- | ---: | ---: | ---: | ---: |",
             f"| `mj_step` | | {base:.3f} | | | |"]
    for motion in ("rigid", "affine"):
        mode, pairs, hits = counts[motion]
        lines.append(f"| `CCDMonitor.step`, {motion} | {mode} | {med[motion]:.3f} | {med[motion] - base:.3f} | "
                     f"{pairs} | {hits} |")
    return "\n".join(lines) + "\n"


def _load(parser, args):
    """The model, the start pose, the bounding ellipsoids and the cross pairs; usage errors name the option."""
    try:
        model = replay.load_model(args.model)
        ellipsoids = geom_ellipsoids(model)
    except InputError as exc:
        parser.error(f"--model: {exc}")
    pairs = cross_pairs(ellipsoids)
    if not pairs:
        parser.error(f"--model: {args.model} has no pair of bounding ellipsoids between a boxer 'a_' and a boxer 'b_'")
    try:
        qpos, _ = replay.load_trajectory(args.traj, model)
    except InputError as exc:
        parser.error(f"--traj: {exc}")
    if args.frame >= len(qpos):
        parser.error(f"--frame {args.frame}: {args.traj} has frames 0 to {len(qpos) - 1}")
    return model, qpos[args.frame], ellipsoids, pairs


def main(argv=None):
    parser = argparse.ArgumentParser(formatter_class=PlainHelpFormatter,
                                     prog="mjccd bench monitor", description=__doc__.splitlines()[0])
    parser.add_argument("--model", default=options.packaged("boxing.xml"),
                        help="MJCF model with two boxers (default: models/boxing.xml, shipped with the package)")
    parser.add_argument("--traj", default=options.packaged("boxing_traj_first150.npz"),
                        help="trajectory (.npz) holding the start pose (default: the first 150 frames of "
                             "data/boxing_traj.npz, shipped with the package)")
    parser.add_argument("--steps", type=int, default=2000, help="steps per run (default 2000)")
    parser.add_argument("--repeats", type=int, default=3, help="runs (default 3)")
    parser.add_argument("--frame", type=int, default=135, help="trajectory frame of the start pose")
    parser.add_argument("--speed", type=float, default=1.0, help="joint velocity scale, rad/s")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--markdown", metavar="FILE", help="write the table into this markdown file")
    options.add_quick(parser, QUICK)
    args = options.parse(parser, argv, QUICK)
    options.check_ranges(parser, args, RANGES)
    options.check_markdown(parser, args.markdown, (args.model, args.traj))
    model, qpos, ellipsoids, pairs = _load(parser, args)
    try:
        med, counts = run(model, qpos, ellipsoids, pairs, args.steps, args.repeats, args.speed, args.seed)
    except InputError as exc:
        print(f"mjccd bench monitor: {exc}", file=sys.stderr)
        return 1
    command = "mjccd bench monitor" + ("" if argv is None else " " + " ".join(argv))
    text = markdown(med, counts, len(ellipsoids), args, command)
    print(text)
    if args.markdown:
        write_section(args.markdown, "monitor", text)
        print(f"written to {args.markdown}")
    return 0
