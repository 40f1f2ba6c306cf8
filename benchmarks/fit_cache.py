"""What fitting costs on first use and in a second process, with the on-disk fit cache.

Usage: python benchmarks/fit_cache.py [--repeat 5]

For each model, in fresh processes (each after ``import mjccd``, with the kernels already compiled or
loaded by a first untimed run): ``fit_model(model)`` (the default 1 cm fit) with an empty cache folder
(cold: the fit itself) and again with the entry the cold run left (warm: a file read), and the
construction of a dm-control wrapper with no arguments, warm.  Medians over
``--repeat`` processes; the wrapper's time (:class:`~mjccd.dm_control.CCDWrapper` of the loaded environment,
its fit read from the cache) includes everything it sets up.  Models: dm-control's humanoid, cheetah, hopper,
humanoid_CMU and dog, and the
Kinova arm of ``models/arm_obstacle.xml`` on its own meshes (``include_visual=True``: the arm's meshes and
the obstacle, not the bounds the file already has).
"""
import argparse
import json
import os
import pathlib
import statistics
import subprocess
import sys
import tempfile

ROOT = pathlib.Path(__file__).resolve().parent.parent
MODELS = ("humanoid", "cheetah", "hopper", "humanoid_CMU", "dog", "kinova")

CHILD = r"""
import json, sys, time, warnings
warnings.simplefilter("ignore")
import mujoco
from mjccd.mujoco import fit_model
name = sys.argv[1]
if name == "kinova":
    env, model, visual = None, mujoco.MjModel.from_xml_path("models/arm_obstacle.xml"), True
else:
    from dm_control import suite
    from mjccd.dm_control import CCDWrapper
    task = {"humanoid": "walk", "cheetah": "run", "hopper": "hop", "humanoid_CMU": "stand", "dog": "walk"}[name]
    env = suite.load(name, task)
    model, visual = env.physics.model.ptr, False
start = time.perf_counter()
ellipsoids = fit_model(model, include_visual=visual)
fit = time.perf_counter() - start
wrapper_s = float("nan")
if env is not None:
    start = time.perf_counter()
    CCDWrapper(env)
    wrapper_s = time.perf_counter() - start
print(json.dumps({"fit_s": fit, "wrapper_s": wrapper_s, "ellipsoids": len(ellipsoids)}))
"""


def child(name, cache):
    env = dict(os.environ, MJCCD_FIT_CACHE=str(cache))
    done = subprocess.run([sys.executable, "-c", CHILD, name], capture_output=True, text=True, env=env, cwd=ROOT,
                          check=True)
    return json.loads(done.stdout.strip().splitlines()[-1])


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=5)
    parser.add_argument("--models", nargs="+", choices=MODELS, default=list(MODELS))
    args = parser.parse_args(argv)
    rows = ["| model | ellipsoids | cold fit [ms] | warm fit [ms] | warm CCDWrapper(env) [ms] |",
            "|---|---:|---:|---:|---:|"]
    with tempfile.TemporaryDirectory() as tmp:
        for name in args.models:
            cold, warm, monitor = [], [], []
            for k in range(args.repeat + 1):
                folder = pathlib.Path(tmp) / f"{name}-{k}"
                first = child(name, folder)       # cold: an empty cache folder
                second = child(name, folder)      # warm: the entry the cold run left
                if k:  # the first pair only compiles or loads the kernels
                    cold.append(first["fit_s"])
                    warm.append(second["fit_s"])
                    monitor.append(second["wrapper_s"])
            row = (f"| {name} | {first['ellipsoids']} | {statistics.median(cold) * 1e3:.1f} | "
                   f"{statistics.median(warm) * 1e3:.1f} | {statistics.median(monitor) * 1e3:.1f} |")
            print(row, flush=True)
            rows.append(row)
    print()
    print("\n".join(rows))
    return 0


if __name__ == "__main__":
    sys.exit(main())
