"""``mjccd warmup``: compile (or load from numba's cache) every kernel a user may need, with progress.

numba compiles mjccd's kernels on first use and caches them (see :mod:`mjccd._cache`);
each kind of work compiles its own kernels, so the first query of each kind pays for
them (docs/benchmarks.md, "First use").  ``mjccd warmup`` runs one small query of each
kind up front, one job after the other, and prints one line per job on stderr with the
kernels it compiled and its time.  Once the cache holds them, warmup takes a few seconds.

Jobs (``mjccd warmup JOB ...`` runs some; ``--list`` prints them):

* ``core``: ``first_contact`` and ``collision_intervals`` for every motion model (the fused
  two-pose kernel, the general path by pieces), the static tests, a plane, ``mjccd solve``'s
  batched cases;
* ``scene``: :class:`mjccd.scene.Scene` (moving-sphere filter, separating planes, the exact
  pairs) with rigid and affine motion, per frame and batched, and
  :class:`mjccd.batch.BatchScene` (many worlds in parallel);
* ``replay``: ``mjccd replay`` with rigid, affine and chain motion on the boxing clip the
  package ships (its first 150 frames);
* ``mujoco``: :class:`~mjccd.mujoco.CCDMonitor` (what the dm-control and Gymnasium wrappers
  step) with each motion, and :class:`~mjccd.mujoco.GuardedStepper`;
* ``fit``: bounding ellipsoids of MuJoCo bodies (``fit_model``, ``mjccd fit``);
* ``patches``: patch CCD (:mod:`mjccd.patches`).
"""
import argparse
import contextlib
import io
import os
import sys
import tempfile
import time

import numpy as np

from mjccd import _cache
from mjccd._command import PlainHelpFormatter


def _core():
    from mjccd import (Affine, Ball, Chain, Ellipsoid, Fixed, Hinge, LinearAffine, Plane, Rational, Rigid, Slide,
                       Static, collision_intervals, contact_point, first_contact, plane_first_contact,
                       separating_plane, solve_cases, static_status, static_status_many)

    a, b = Ellipsoid([0.3, 0.2, 0.1]), Ellipsoid([0.2, 0.2, 0.4])
    still = Static([0.0, 0.1, 0.0])
    turning = Rigid([-1.0, 0.0, 0.0], [1.0, 0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.7071, 0.0, 0.7071, 0.0])
    sliding = Rigid([-1.0, 0.0, 0.0], [1.0, 0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [1.0, 0.0, 0.0, 0.0])
    shearing = Affine([-1.0, 0.0, 0.0], [1.0, 0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.7071, 0.0, 0.7071, 0.0])
    thin = Ellipsoid([1.0, 0.05, 0.05])  # a needle: solved in its own frame
    for motion in (turning, sliding, shearing):
        first_contact(a, motion, b, still)
        collision_intervals(a, motion, b, still)
    first_contact(thin, turning, b, still)
    first_contact(a, Static([0.0, 0.0, 0.0]), b, Static([0.1, 0.0, 0.0]))  # overlapping from the start
    arm = Chain([Fixed([0.0, 0.0, 0.0]), Hinge([0.0, 0.0, 1.0], 0.0, 1.2), Fixed([0.8, 0.0, 0.0]),
                 Ball([1.0, 0.0, 0.0, 0.0], [0.9, 0.3, 0.0, 0.0]), Slide([1.0, 0.0, 0.0], 0.0, 0.1)])
    first_contact(a, arm, b, Static([0.0, 0.9, 0.0]))
    collision_intervals(a, arm, b, Static([0.0, 0.9, 0.0]))
    first_contact(a, LinearAffine(np.hstack([np.eye(3), [[-1.0], [0.0], [0.0]]]),
                                  np.hstack([np.eye(3), [[1.0], [0.0], [0.0]]])), b, still)
    # a turn about z with tan(angle / 2) = t, and a straight translation: polynomials lowest degree first
    turn = [[[1.0, 0.0, -1.0], [0.0, -2.0], [0.0]], [[0.0, 2.0], [1.0, 0.0, -1.0], [0.0]],
            [[0.0], [0.0], [1.0, 0.0, 1.0]]]
    first_contact(a, Rational(turn, [1.0, 0.0, 1.0], [[-1.0, 2.0], [0.0], [0.0]]), b, still)
    pose_a, pose_b = ([0.0, 0.0, 0.0], [1.0, 0.0, 0.0, 0.0]), ([0.5, 0.0, 0.0], [1.0, 0.0, 0.0, 0.0])
    static_status(a, pose_a, b, pose_b)
    static_status_many([[0.3, 0.2, 0.1]] * 2, [[0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0]] * 2, [[0.2, 0.2, 0.4]] * 2,
                       [[0.5, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0], [3.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0]])
    separating_plane(a, pose_a, b, ([3.0, 0.0, 0.0], [1.0, 0.0, 0.0, 0.0]))
    contact_point(a, pose_a, b, ([0.5, 0.0, 0.0], [1.0, 0.0, 0.0, 0.0]))
    plane_first_contact(a, turning, Plane([0.0, 0.0, 1.0], -0.5))
    body = {"radii": [0.3, 0.2, 0.1], "motion": {"type": "rigid",
                                                 "start": {"position": [-1.0, 0.0, 0.0], "quaternion": [1, 0, 0, 0]},
                                                 "end": {"position": [1.0, 0.0, 0.0], "quaternion": [0, 1, 0, 0]}}}
    solve_cases({"version": 1, "cases": [{"id": "warmup", "a": body, "b": {"radii": [0.2, 0.2, 0.4],
                                                                            "motion": {"type": "static", "position": [0, 0.1, 0], "quaternion": [1, 0, 0, 0]}}}]})


def _scene():
    from mjccd.batch import BatchScene
    from mjccd.scene import Scene

    radii = [[0.3, 0.2, 0.1], [0.2, 0.2, 0.4], [0.25, 0.1, 0.1]]
    rng = np.random.default_rng(0)
    poses = np.zeros((6, 3, 7))
    poses[:, :, 3] = 1.0
    poses[:, 1, 0] = np.linspace(1.5, 0.0, 6)  # the second body walks through the first
    poses[:, 2, :3] = [3.0, 0.0, 0.0]
    poses[:, 1, 3:] += rng.normal(scale=0.2, size=(6, 4))
    poses[:, 1, 3:] /= np.linalg.norm(poses[:, 1, 3:], axis=1)[:, None]
    for motion in ("rigid", "affine"):
        scene = Scene(radii, motion=motion)
        for k in range(len(poses) - 1):
            scene.step(poses[k], poses[k + 1])
            scene.step(poses[k], poses[k + 1], all_pairs=True, new_contacts_only=True)
            scene.may_touch(poses[k], poses[k + 1])
        scene.run(poses)
        scene.run(poses, timing=True, new_contacts_only=True)
        worlds = BatchScene(radii, 2, motion=motion)  # many worlds in parallel (mjccd.batch)
        worlds.first_contacts(np.stack([poses[0]] * 2), np.stack([poses[1]] * 2))
        worlds.step(np.stack([poses[0]] * 2), np.stack([poses[1]] * 2), all_pairs=True)
        worlds.first_contacts_along(np.stack([poses] * 2))


def _replay():
    from mjccd import replay
    from mjccd.bench import options

    model, traj = options.packaged("boxing.xml"), options.packaged("boxing_traj_first150.npz")
    with tempfile.TemporaryDirectory(prefix="mjccd-warmup-") as tmp:
        for motion in ("rigid", "affine", "chain"):
            out = os.path.join(tmp, motion)
            with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(io.StringIO()):
                code = replay.main([model, traj, "--motion", motion, "--no-render", "--out", out])
            if code:
                raise RuntimeError(f"mjccd replay --motion {motion} exited {code}")


def _boxers():
    """The packaged two-boxer model, a sparring state, its bounding ellipsoids and cross pairs."""
    from mjccd import replay
    from mjccd.bench import monitor, options
    from mjccd.mujoco import geom_ellipsoids

    model = replay.load_model(options.packaged("boxing.xml"))
    qpos, _ = replay.load_trajectory(options.packaged("boxing_traj_first150.npz"), model)
    ellipsoids = geom_ellipsoids(model)
    return model, monitor.sparring_state(model, qpos[135], 1.0, 0), ellipsoids, monitor.cross_pairs(ellipsoids)


def _mujoco():
    import mujoco

    from mjccd.mujoco import CCDMonitor, GuardedStepper

    model, start, ellipsoids, pairs = _boxers()
    for motion in ("rigid", "affine", "chain"):
        for options in ({}, {"report_overlapping": False, "all_pairs": True}):
            data = mujoco.MjData(model)
            mujoco.mj_copyData(data, model, start)
            CCDMonitor(model, data, ellipsoids, pairs=pairs, motion=motion, **options).step(3)
    for motion in ("rigid", "affine"):
        data = mujoco.MjData(model)
        mujoco.mj_copyData(data, model, start)
        GuardedStepper(model, data, ellipsoids, pairs=pairs, motion=motion).step(3)


# one body of each geom kind fit_model covers (a mesh too), on a free and a hinged body
FIT_MODEL = """<mujoco>
  <asset><mesh name="tetra" vertex="0 0 0  0.1 0 0  0 0.1 0  0 0 0.1"/></asset>
  <worldbody>
    <body name="a" pos="0 0 1"><freejoint/>
      <geom type="capsule" size="0.05 0.2"/><geom type="box" size="0.1 0.05 0.02" pos="0 0 0.3"/>
      <geom type="mesh" mesh="tetra" pos="0 0 0.5"/>
    </body>
    <body name="b" pos="1 0 1"><joint type="hinge"/>
      <geom type="sphere" size="0.1"/><geom type="cylinder" size="0.05 0.1" pos="0 0 0.2"/>
      <geom type="ellipsoid" size="0.1 0.05 0.03" pos="0 0 0.4"/>
    </body>
  </worldbody>
</mujoco>"""


def _fit():
    import mujoco

    from mjccd.mujoco import fit_model

    model = mujoco.MjModel.from_xml_string(FIT_MODEL)
    fit_model(model, cache=False)  # fitted, not read from the fit cache, so that its kernels compile
    fit_model(model, tolerance=None, cache=False)
    fit_model(model, tolerance=None, per="geom", cache=False)


def _patches():
    from mjccd.patches import Patch, contact_manifold, edge_edge, ellipsoid_patches, first_contact, vertex_face

    face = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]
    for method in ("ours", "trad"):
        vertex_face([0.2, 0.2, 1.0], face, [0.2, 0.2, -1.0], face, method=method, max_iterations=20_000)
    edge_edge([[0.0, 0.0, 1.0], [1.0, 0.0, 1.0]], [[0.5, -1.0, 0.0], [0.5, 1.0, 0.0]],
              [[0.0, 0.0, -1.0], [1.0, 0.0, -1.0]], [[0.5, -1.0, 0.0], [0.5, 1.0, 0.0]])
    flat = np.array([[[x, y, 0.0] for x in (-2.0, 0.0, 2.0)] for y in (-2.0, 0.0, 2.0)])
    ground = Patch.quad(flat)
    frame0 = np.hstack([np.eye(3), [[0.0], [0.0], [0.6]]])
    frame1 = np.hstack([np.eye(3), [[0.0], [0.0], [-0.2]]])
    ball = ellipsoid_patches([0.4, 0.4, 0.4], frame0, frame1)
    for inclusion in ("obb", "aabb"):
        first_contact(ball, ground, inclusion=inclusion)
    contact_manifold(ball, ground, simultaneity=1e-3, separation=0.05)


JOBS = {
    "core": ("exact solver: every motion model, static tests", _core),
    "scene": ("Scene: filters and exact pairs, rigid and affine", _scene),
    "replay": ("mjccd replay: rigid, affine, chain", _replay),
    "mujoco": ("CCDMonitor (dm-control, Gymnasium wrappers), GuardedStepper", _mujoco),
    "fit": ("bounding ellipsoids of MuJoCo bodies", _fit),
    "patches": ("patch CCD", _patches),
}


def run(jobs=None, stream=None):
    """Run ``jobs`` (names of :data:`JOBS`, default all) in order, one line each on ``stream`` (stderr).

    Returns ``{job: (kernels compiled, seconds, CPU seconds, error or None)}``; a job that fails
    says why on its line and the others still run.  The compile notice of :mod:`mjccd._cache`
    stays quiet meanwhile: these lines say the same.
    """
    stream = stream or sys.stderr
    names = list(JOBS) if not jobs else list(jobs)
    unknown = [n for n in names if n not in JOBS]
    if unknown:
        raise ValueError(f"unknown warmup job {unknown[0]!r}; jobs: {', '.join(JOBS)}")
    notice = _cache.install_notice()
    results = {}
    width = max(len(n) for n in names)
    cpu0, t0 = time.process_time(), time.perf_counter()
    for i, name in enumerate(names, 1):
        text, job = JOBS[name]
        stream.write(f"mjccd warmup [{i}/{len(names)}] {name:<{width}}  {text} …")
        stream.flush()
        before, cpu, start = notice.total, time.process_time(), time.perf_counter()
        error = None
        with notice.muted():
            try:
                job()
            except Exception as exc:  # the other jobs still compile what they need
                error = f"{type(exc).__name__}: {' '.join(str(exc).split())}"
        kernels = notice.total - before
        results[name] = (kernels, time.perf_counter() - start, time.process_time() - cpu, error)
        done = f"{kernels} kernels compiled" if kernels else "cached"
        stream.write(f" {done}, {results[name][1]:.1f} s (CPU {results[name][2]:.1f} s)"
                     + (f"; failed: {error}" if error else "") + "\n")
        stream.flush()
    total = sum(r[0] for r in results.values())
    stream.write(f"mjccd warmup: {total} kernels compiled in {time.perf_counter() - t0:.1f} s "
                 f"(CPU {time.process_time() - cpu0:.1f} s); numba's cache keeps them for later runs\n")
    stream.flush()
    return results


def main(argv=None):
    parser = argparse.ArgumentParser(formatter_class=PlainHelpFormatter,
                                     prog="mjccd warmup", description=__doc__.splitlines()[0])
    parser.add_argument("jobs", nargs="*", metavar="JOB", help=f"jobs to run (default: all): {', '.join(JOBS)}")
    parser.add_argument("--list", action="store_true", help="list the jobs and exit")
    args = parser.parse_args(argv)
    if args.list:
        for name, (text, _) in JOBS.items():
            print(f"{name:<8} {text}")
        return 0
    unknown = [n for n in args.jobs if n not in JOBS]
    if unknown:
        parser.error(f"unknown job {unknown[0]!r}; jobs: {', '.join(JOBS)}")
    results = run(args.jobs)
    return 1 if any(r[3] for r in results.values()) else 0
