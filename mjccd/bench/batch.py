"""``mjccd bench batch``: many worlds at once on the CPU (:class:`mjccd.batch.BatchScene`), against one scene per world.

Workloads, each world with poses of its own:

* **boxing**: two 21-ellipsoid boxers per world, every pair between them
  (441 pairs), rigid motion; synthetic, without MuJoCo (:func:`boxing_worlds`:
  limb sizes of an adult, joints driven by smooth random signals and punches,
  each world its own signals).
* **humanoid**: dm-control's humanoid, one fitted ellipsoid per body and its
  self pairs, poses of MuJoCo runs under random controls (held a few steps),
  each world a stretch of one of a few runs at its own offset; skipped with a
  line saying why where MuJoCo or dm-control does not import.

Per number of worlds B, in pair-frames per second (worlds x frames x pairs
per second, medians of interleaved repeats, the plane cache reset before
each): :meth:`~mjccd.batch.BatchScene.first_contacts` frame by frame with one
thread and with all of numba's threads; the same frames through one
:class:`~mjccd.scene.Scene` per world driven from a Python loop
(``Scene.first_contact``); :meth:`~mjccd.batch.BatchScene.first_contacts_along`
over the whole sequence (frames up to each world's first contact); and the GPU
(:mod:`mjccd.gpu`) where it imports and finds a CUDA device.  One world's
:meth:`Scene.run <mjccd.scene.Scene.run>` over a long sequence is the
single-world reference.
"""
import argparse
import math
import os
import platform
import statistics
import sys
import time

import numba
import numpy as np

from mjccd.batch import BatchScene
from mjccd.bench import options
from mjccd.bench.report import write_section
from mjccd.quadric import matrix_to_quat
from mjccd.scene import Scene, pairs_between
from mjccd._command import PlainHelpFormatter

WORKLOADS = ("boxing", "humanoid")
WORLDS = [1, 4, 16, 64, 256, 1024, 4096]
QUICK = {"worlds": [1, 4, 16], "world_frames": 64, "run_frames": 50, "repeats": 1}
RANGES = {"worlds": (1, 1 << 20), "world_frames": (1, 10**9), "run_frames": (2, 10**7), "repeats": (1, 1000),
          "seed": (0, 2**32 - 1)}
GPU_COMMAND = "pip install 'mjccd[gpu]' && mjccd bench batch"
HOLD = 5  # humanoid: physics steps a random control is held

# ---------------------------------------------------------------- boxing worlds

# name, parent (index; None: the bone before), joint offset in the parent's frame, ellipsoid centre in the
# bone's frame, radii (metres)
_BONES = [
    ("pelvis", -1, (0.0, 0.0, 0.0), (0.0, 0.0, 0.0), (0.11, 0.16, 0.09)),
    ("lower_back", 0, (0.0, 0.0, 0.09), (0.0, 0.0, 0.08), (0.10, 0.14, 0.08)),
    ("chest", 1, (0.0, 0.0, 0.16), (0.0, 0.0, 0.12), (0.11, 0.17, 0.13)),
    ("neck", 2, (0.0, 0.0, 0.25), (0.0, 0.0, 0.05), (0.05, 0.05, 0.06)),
    ("head", 3, (0.0, 0.0, 0.09), (0.01, 0.0, 0.10), (0.09, 0.075, 0.11)),
]
for _s, _side in ((1.0, "l"), (-1.0, "r")):
    _BONES += [
        (f"shoulder_{_side}", 2, (0.0, 0.06 * _s, 0.20), (0.0, 0.07 * _s, 0.0), (0.05, 0.08, 0.05)),
        (f"upper_arm_{_side}", None, (0.0, 0.15 * _s, 0.0), (0.0, 0.0, -0.14), (0.05, 0.05, 0.16)),
        (f"forearm_{_side}", None, (0.0, 0.0, -0.28), (0.0, 0.0, -0.13), (0.045, 0.045, 0.14)),
        (f"fist_{_side}", None, (0.0, 0.0, -0.26), (0.0, 0.0, -0.05), (0.05, 0.045, 0.06)),
        (f"thigh_{_side}", 0, (0.0, 0.09 * _s, -0.05), (0.0, 0.0, -0.21), (0.08, 0.08, 0.23)),
        (f"shin_{_side}", None, (0.0, 0.0, -0.43), (0.0, 0.0, -0.21), (0.055, 0.055, 0.22)),
        (f"foot_{_side}", None, (0.0, 0.0, -0.43), (0.06, 0.0, -0.04), (0.12, 0.05, 0.04)),
        (f"toes_{_side}", None, (0.15, 0.0, -0.05), (0.03, 0.0, 0.0), (0.04, 0.045, 0.025)),
    ]
_BONES = [(n, i - 1 if p is None else p, j, c, r) for i, (n, p, j, c, r) in enumerate(_BONES)]
BONES = len(_BONES)  # 21


def rotations(v):
    """Rotation matrices (..., 3, 3) of rotation vectors v (..., 3) (Rodrigues)."""
    theta = np.linalg.norm(v, axis=-1)[..., None, None]
    k = v / np.maximum(theta[..., 0], 1e-300)
    K = np.zeros(v.shape + (3,))
    K[..., 0, 1], K[..., 0, 2], K[..., 1, 2] = -k[..., 2], k[..., 1], -k[..., 0]
    K[..., 1, 0], K[..., 2, 0], K[..., 2, 1] = k[..., 2], -k[..., 1], k[..., 0]
    return np.eye(3) + np.sin(theta) * K + (1.0 - np.cos(theta)) * K @ K


def _joint(name, side, smooth, punch):
    """Rotation vector (B, F, 3) of bone ``name``'s joint: smooth random swings, arms punching."""
    v = np.zeros(smooth(0.0).shape + (3,))
    if name.startswith("upper_arm"):
        v[..., 1] = -(0.9 + 0.6 * punch + smooth(0.25))  # shoulder flexion: the arm swings forward
        v[..., 0] = side * (0.25 + smooth(0.15) - 0.2 * punch)
        v[..., 2] = smooth(0.2)
    elif name.startswith("forearm"):
        v[..., 1] = -(1.9 - 1.7 * punch + smooth(0.2))  # the elbow opens as the fist goes out
    elif name.startswith("thigh"):
        v[..., 1], v[..., 0] = -0.15 + smooth(0.2), smooth(0.08)
    elif name.startswith("shin"):
        v[..., 1] = 0.3 + smooth(0.2)
    elif name in ("lower_back", "chest"):
        v[..., 1], v[..., 2] = 0.1 + smooth(0.12), smooth(0.3)
    else:
        v[:] = np.stack([smooth(0.1) for _ in range(3)], axis=-1)
    return v


def boxing_worlds(worlds, frames, *, seed=0, fps=60.0):
    """Two 21-ellipsoid boxers facing each other in each world, without MuJoCo.

    Returns poses (worlds, frames + 1, 42, 7), radii (42, 3) and the 441 pairs
    between the boxers.  Each world draws its own joint signals (sums of
    sinusoids of random frequency and phase) and punches; so do both boxers.
    """
    rng = np.random.default_rng(seed)
    ts = rng.uniform(0.0, 100.0, (worlds, 1)) + np.arange(frames + 1) / fps  # (B, F)

    def smooth(amplitude, fmin=0.2, fmax=1.2, n=3):
        f = rng.uniform(fmin, fmax, (n, worlds, 1))
        phase = rng.uniform(0.0, 2.0 * np.pi, (n, worlds, 1))
        return amplitude / n * np.sin(2.0 * np.pi * f * ts + phase).sum(axis=0)

    gap = 1.1 + smooth(0.12, 0.1, 0.5)  # fists reach the other boxer in about a tenth of the frames
    poses = np.empty((worlds, frames + 1, 2 * BONES, 7))
    for c, (x, facing) in enumerate(((-0.5, 0.0), (0.5, np.pi))):
        root = np.stack([x * gap + smooth(0.03), smooth(0.06), 1.0 + smooth(0.02)], axis=-1)
        rot, pos, punches = [], [], {}
        for b, (name, parent, joint, centre, _) in enumerate(_BONES):
            side = 1.0 if name.endswith("_l") else -1.0
            if parent < 0:
                v = np.stack([np.zeros_like(ts), smooth(0.08), facing + smooth(0.25)], axis=-1)
                R, p = rotations(v), root
            else:
                if name.startswith("upper_arm"):
                    rate = rng.uniform(0.4, 0.9, (worlds, 1))
                    phase = rng.uniform(0.0, 2.0 * np.pi, (worlds, 1))
                    punches[name[-1]] = np.maximum(0.0, np.sin(2.0 * np.pi * rate * ts + phase)) ** 4
                R = rot[parent] @ rotations(_joint(name, side, smooth, punches.get(name[-1])))
                p = pos[parent] + rot[parent] @ np.asarray(joint)
            rot.append(R)
            pos.append(p)
            e = c * BONES + b
            poses[:, :, e, :3] = p + R @ np.asarray(centre)
            poses[:, :, e, 3:] = matrix_to_quat(R)
    radii = np.array([bone[4] for bone in _BONES] * 2)
    return poses, radii, pairs_between(range(BONES), range(BONES, 2 * BONES))


# ---------------------------------------------------------------- humanoid worlds


def humanoid_source(seed):
    """``(runs(length, count) -> (count, length + 1, N, 7) poses, radii, pairs)`` of dm-control's humanoid, or
    ``(None, reason)`` when MuJoCo or dm-control is missing or does not work here."""
    try:
        import warnings

        from dm_control import suite

        from mjccd.mujoco import ModelAdapter, fit_model, self_pairs

        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            env = suite.load("humanoid", "run", task_kwargs={"random": seed})
    except Exception as exc:  # not installed, or dm-control that cannot build a physics with this MuJoCo
        return None, f"{type(exc).__name__}: {' '.join(str(exc).split())}"
    physics = env.physics
    model = physics.model.ptr
    ellipsoids = fit_model(model, tolerance=None)  # one per body: the figures in docs/benchmarks.md
    pairs = self_pairs(model, ellipsoids)
    adapter = ModelAdapter(model, ellipsoids, pairs)
    lo, hi = physics.model.actuator_ctrlrange.T

    def runs(length, count):
        """``count`` runs of ``length`` physics steps, each from a reset and under random controls of its own."""
        out = []
        for r in range(count):
            rng = np.random.default_rng([seed, r])
            env.reset()  # the task's own random start
            qpos = [physics.data.qpos.copy()]
            for step in range(length):
                if step % HOLD == 0:
                    physics.data.ctrl[:] = rng.uniform(lo, hi)
                physics.step()
                qpos.append(physics.data.qpos.copy())
            out.append(adapter.qpos_poses(np.array(qpos)))
        return np.stack(out)

    return (runs, ellipsoids.radii, pairs), None


def humanoid_worlds(source, worlds, frames, runs=8):
    """Poses (worlds, frames + 1, N, 7): world b is run b % runs from step b // runs on."""
    count = min(runs, worlds)
    sequences = source(frames + -(-worlds // count), count)
    return np.stack([sequences[b % count, b // count:b // count + frames + 1] for b in range(worlds)])


# ---------------------------------------------------------------- timings


def _warm_then_time(reset, step, frames):
    """Seconds of ``step(f)`` over frames 1 .. T of ``frames`` (T + 2 pose sets), after the cache is reset and
    warmed by frame 0 (as after a frame of a long run)."""
    reset()
    step(0)
    begin = time.perf_counter()
    for f in range(1, len(frames) - 1):
        step(f)
    return time.perf_counter() - begin


def gpu_seconds(radii, pairs, poses, repeats):
    """Median seconds of :class:`mjccd.gpu.GpuScene` ``first_contacts`` frame by frame over (B, T + 1, N, 7) poses
    (all on the device beforehand), and None; ``(None, why)`` when it was not measured."""
    try:
        from mjccd import gpu
    except ImportError as exc:
        return None, " ".join(str(exc).split())
    if numba.config.ENABLE_CUDASIM:
        return None, "the CUDA simulator runs here, not a GPU"
    from numba import cuda

    frames = np.ascontiguousarray(poses.transpose(1, 0, 2, 3))
    scene = gpu.GpuScene(radii, poses.shape[0], pairs=pairs)
    on_device = cuda.to_device(frames)
    scene.first_contacts(on_device[0], on_device[1])  # compiled before the timed runs

    def step(f):
        scene.first_contacts(on_device[f], on_device[f + 1])
        if f == len(frames) - 2:
            cuda.synchronize()
    return statistics.median(_warm_then_time(scene.reset_cache, step, frames) for _ in range(repeats)), None


def measure(radii, pairs, poses, repeats, threads):
    """Median seconds over frames 1 .. T of (B, T + 2, N, 7) ``poses`` (frame 0 warms the plane cache): batched
    with 1 and ``threads`` threads, one Scene per world in a Python loop, and along the sequence from frame 1
    on (with the number of frames it checked)."""
    worlds = poses.shape[0]
    frames = np.ascontiguousarray(poses.transpose(1, 0, 2, 3))  # (T + 2, B, N, 7): one frame's poses contiguous
    batch = BatchScene(radii, worlds, pairs=pairs)
    scenes = [Scene(radii, pairs=pairs) for _ in range(worlds)]
    batch.first_contacts(frames[0], frames[1])  # compiled before the timed runs
    batch.first_contacts_along(poses[:, :2])
    scenes[0].first_contact(frames[0, 0], frames[1, 0])

    def batched(f):
        batch.first_contacts(frames[f], frames[f + 1])

    def reset_scenes():
        for scene in scenes:
            scene.reset_cache()

    def loop(f):
        for b, scene in enumerate(scenes):
            scene.first_contact(frames[f, b], frames[f + 1, b])

    along = []

    def sequence():
        batch.reset_cache()
        batched(0)
        begin = time.perf_counter()
        along.append(batch.first_contacts_along(poses[:, 1:]))
        return time.perf_counter() - begin

    times = {"one": [], "all": [], "loop": [], "along": []}
    try:
        for _ in range(repeats):
            numba.set_num_threads(1)
            times["one"].append(_warm_then_time(batch.reset_cache, batched, frames))
            numba.set_num_threads(threads)
            times["all"].append(_warm_then_time(batch.reset_cache, batched, frames))
            times["along"].append(sequence())
            times["loop"].append(_warm_then_time(reset_scenes, loop, frames))
    finally:
        numba.set_num_threads(threads)
    out = {k: statistics.median(v) for k, v in times.items()}
    first = along[-1]
    out["along_frames"] = int(np.where(first.frame >= 0, first.frame + 1, poses.shape[1] - 2).sum())
    return out


def run_seconds(radii, pairs, poses, repeats):
    """Median seconds of one world's ``Scene.run`` over (T + 1, N, 7) poses, from a cold cache each time."""
    scene = Scene(radii, pairs=pairs)
    scene.run(poses[:3])

    def run():
        scene.reset_cache()
        begin = time.perf_counter()
        scene.run(poses)
        return time.perf_counter() - begin
    return statistics.median(run() for _ in range(repeats))


def bench_workload(name, make, radii, pairs, args, threads, progress):
    """Rows of one workload, one per number of worlds, and its Scene.run reference."""
    npairs = len(pairs)
    rows = []
    for worlds in args.worlds:
        frames = max(1, math.ceil(args.world_frames / worlds))
        poses = make(worlds, frames + 1)  # and one frame before them that warms the plane cache
        t = measure(radii, pairs, poses, args.repeats, threads)
        pf = worlds * frames * npairs
        gpu, why = gpu_seconds(radii, pairs, poses, args.repeats)
        rows.append({"worlds": worlds, "frames": frames, "one": pf / t["one"], "all": pf / t["all"],
                     "loop": pf / t["loop"], "along": t["along_frames"] * npairs / t["along"],
                     "gpu": None if gpu is None else pf / gpu, "gpu_why": why})
        progress.update(1)
    run = make(1, args.run_frames)[0]
    run_fps = args.run_frames / run_seconds(radii, pairs, run, args.repeats)
    progress.update(1)
    return {"name": name, "ellipsoids": len(radii), "pairs": npairs, "rows": rows, "run_fps": run_fps}


# ---------------------------------------------------------------- report


def _rate(x):
    return f"{x / 1e6:.2f} M"


def markdown(results, skipped, args, command, threads, seconds, load):
    lines = ["## Many worlds on the CPU (`mjccd bench batch`)", "",
             f"Command: `{command}` ({seconds:.0f} s)  ",
             f"Machine: {platform.machine()}, {os.cpu_count()} cores, {threads} numba threads "
             f"({numba.threading_layer()} layer), Python {platform.python_version()}, numpy {np.__version__}, "
             f"numba {numba.__version__}; load average {load[0]:.1f} at the start, {load[1]:.1f} at the end", "",
             "Pair-frames per second (worlds × frames × pairs / s; M = 10⁶), medians of "
             f"{args.repeats} interleaved repeats, each after a reset plane cache and one untimed frame that warms it; "
             f"about {args.world_frames} "
             "world-frames per measurement (frames per world = that / worlds). Batched: "
             "`BatchScene.first_contacts` frame by frame, parallel over the worlds; loop: one `Scene` per world, "
             "`Scene.first_contact` per world per frame from Python; along: `BatchScene.first_contacts_along` "
             "over each world's whole sequence, counting the frames up to each world's first contact; GPU: "
             "`mjccd.gpu.GpuScene.first_contacts`, poses already on the device.", ""]
    for r in results:
        run_pf = r["run_fps"] * r["pairs"]
        lines += [f"### {r['name']}: {r['ellipsoids']} ellipsoids, {r['pairs']} pairs per world", "",
                  f"| worlds | frames per world | batched, 1 thread | batched, {threads} threads | speed-up "
                  f"| loop of Scenes | batched ({threads} threads) / loop | along ({threads} threads) | GPU |",
                  "| ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: |"]
        for row in r["rows"]:
            gpu = "not measured" if row["gpu"] is None else _rate(row["gpu"])
            lines.append(f"| {row['worlds']} | {row['frames']} | {_rate(row['one'])} | {_rate(row['all'])} | "
                         f"{row['all'] / row['one']:.2f}× | {_rate(row['loop'])} | {row['all'] / row['loop']:.1f}× | "
                         f"{_rate(row['along'])} | {gpu} |")
        best = max(r["rows"], key=lambda row: row["worlds"])
        lines += ["", f"Single world, `Scene.run` over {args.run_frames} frames: {r['run_fps']:.0f} frames/s = "
                      f"{_rate(run_pf)} pair-frames/s. Batched with 1 thread at {best['worlds']} worlds: "
                      f"{best['one'] / run_pf:.2f}× that per core; with {threads} threads "
                      f"{best['all'] / best['one']:.2f}× its 1-thread rate.", ""]
    why = {row["gpu_why"].split(";")[0] for r in results for row in r["rows"] if row["gpu"] is None}
    if why:
        lines += [f"GPU not measured ({'; '.join(sorted(why))}); to measure it, on a machine with an NVIDIA GPU: "
                  f"`{GPU_COMMAND}`.", ""]
    for name, reason in skipped:
        lines += [f"{name}: not measured ({reason}).", ""]
    lines += ["Notes:", "",
              "- Every world answers exactly as its own `Scene` does (tests/test_batch.py); the worlds share the "
              "ellipsoids and pairs, the scratch of the frame kernel is one per thread, and a world owns only its "
              "plane cache (P normals and P bytes: 45 MB for 4096 worlds of 441 pairs).",
              "- A parallel call ends when every thread is done: when another process holds a core, the waiting "
              "thread gets one only at a scheduler tick, and a call costs milliseconds (rows far below the "
              "1-thread rate in a run with load above 1). Compare rows of a run on idle cores.",
              "- One world per call costs about 15 µs more than `Scene.first_contact` (input checks, result arrays, "
              "the parallel launch); with few worlds, frame-by-frame calls are dominated by that.",
              "- Along: one call per world sequence; it stops each world at its first contact, so few frames are "
              "checked when contacts come early (humanoids on the floor, boxers in reach)."]
    return "\n".join(lines).rstrip() + "\n"


def main(argv=None):
    parser = argparse.ArgumentParser(formatter_class=PlainHelpFormatter,
                                     prog="mjccd bench batch", description=__doc__.splitlines()[0])
    parser.add_argument("--worlds", type=int, nargs="+", default=WORLDS, metavar="B",
                        help=f"numbers of worlds (default {' '.join(map(str, WORLDS))})")
    parser.add_argument("--world-frames", type=int, default=16384,
                        help="world-frames per measurement: each world gets this / worlds frames (default 16384)")
    parser.add_argument("--run-frames", type=int, default=2000,
                        help="frames of the single-world Scene.run reference (default 2000)")
    parser.add_argument("--workloads", nargs="+", choices=WORKLOADS, default=list(WORKLOADS), metavar="NAME",
                        help=f"workloads (default: {' '.join(WORKLOADS)})")
    parser.add_argument("--repeats", type=int, default=3, help="timed repeats of each measurement (default 3)")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--markdown", metavar="FILE", help="write the tables into this markdown file")
    args = options.parse_checked(parser, argv, QUICK, RANGES)
    from tqdm import tqdm

    begin, load = time.perf_counter(), [options.load_average()]
    threads = numba.get_num_threads()
    results, skipped, plans = [], [], []
    if "boxing" in args.workloads:
        _, radii, pairs = boxing_worlds(1, 1)
        plans.append(("boxing", lambda b, f: boxing_worlds(b, f, seed=args.seed)[0], radii, pairs))
    if "humanoid" in args.workloads:
        made, reason = humanoid_source(args.seed)
        if made is None:
            skipped.append(("humanoid", f"dm-control's humanoid did not load: {reason}"))
        else:
            source, radii, pairs = made
            plans.append(("humanoid", lambda b, f: humanoid_worlds(source, b, f), radii, pairs))
    with tqdm(total=len(plans) * (len(args.worlds) + 1), desc="workloads x worlds", file=sys.stderr,
              disable=not sys.stderr.isatty()) as progress:
        for name, make, radii, pairs in plans:
            results.append(bench_workload(name, make, radii, pairs, args, threads, progress))
    command = "mjccd bench batch" + ("" if argv is None else " " + " ".join(argv))
    load.append(options.load_average())
    text = markdown(results, skipped, args, command, threads, time.perf_counter() - begin, load)
    print(text)
    if args.markdown:
        write_section(args.markdown, "batch", text)
        print(f"written to {args.markdown}")
    return 0
