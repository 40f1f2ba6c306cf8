"""How faithful mjccd's contacts are on real MuJoCo models: recall, precision and cost for two fits side by side.

Each environment (dm-control suite and Gymnasium models; Gymnasium's only when installed) runs ``--steps``
MuJoCo steps under random controls, uniform in each actuator's range and held for ``HOLD`` steps, from the
environment's own reset state.  The same steps are checked by :class:`~mjccd.mujoco.CCDMonitor` with every
colliding pair reported (``all_pairs``), once per fit:

* **recall**: every *new* MuJoCo contact (a geom pair with ``dist < 0`` among the contacts of a step's end
  state that was not among those of the state before) between two geoms the ellipsoids cover (or a covered
  geom and a plane mjccd checks) must be an mjccd contact of that step or the step before, or a pair mjccd
  found already touching at that step's start.  Matched by body pair.
* **precision**: of the mjccd contacts of pairs that were separate at the step start, the share at which
  the real geoms of the two bodies are within 1 cm at the contact instant (``mj_geomDistance``, each geom
  moved between the step's two ends as mjccd moves an ellipsoid: centre lerp, quaternion lerp).
* **cost**: a control step of the wrapped environment (:class:`~mjccd.dm_control.CCDWrapper`,
  :class:`~mjccd.mujoco.gym.CCDGymWrapper`) against the plain environment's, both from the same reset
  under the same random actions, median over chunks of ``CHUNK`` control steps; and, for context,
  ``CCDMonitor.step`` against a bare ``mj_step``.

A step in which MuJoCo meets a bad state restarts the episode from the reset state (and is not counted).
"""
import argparse
import os
import platform
import statistics
import sys
import time
import warnings

import mujoco
import numpy as np
from tqdm import tqdm

from mjccd.bench import options
from mjccd.bench.report import write_section
from mjccd.fitting import DEFAULT_TOLERANCE
from mjccd.mujoco import CCDMonitor, fit_model
from mjccd.mujoco.pairs import bounded_geoms, plane_pairs

DM_CONTROL = {"humanoid": ("humanoid", "run"), "humanoid_CMU": ("humanoid_CMU", "run"),
              "walker": ("walker", "walk"), "quadruped": ("quadruped", "walk"),
              "manipulator": ("manipulator", "bring_ball")}
GYMNASIUM = ("Ant-v5", "Humanoid-v5", "HalfCheetah-v5")
ENVS = tuple(DM_CONTROL) + GYMNASIUM
HOLD = 5          # steps a random control is held
CHUNK = 50        # steps per timed chunk
NEAR = 0.01       # m: a contact instant is precise when the real geoms are this close
QUICK = {"steps": 60, "env_steps": 60, "envs": ["walker", "humanoid"]}
RANGES = {"steps": (1, 1_000_000), "env_steps": (1, 1_000_000), "seed": (0, 2**63 - 1)}


# ---------------------------------------------------------------- environments


def make_env(name, seed):
    """A fresh environment after its reset with ``seed``: ``(env, model, data, kind)``; None when its package
    (or its MuJoCo environments) is not installed."""
    if name in DM_CONTROL:
        try:
            from dm_control import suite
        except ImportError:
            return None
        env = suite.load(*DM_CONTROL[name], task_kwargs={"random": seed})
        env.reset()
        return env, env.physics.model.ptr, env.physics.data.ptr, "dm_control"
    try:
        import gymnasium
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            env = gymnasium.make(name)
    except Exception:  # not installed, or without its MuJoCo environments
        return None
    env.reset(seed=seed)
    return env, env.unwrapped.model, env.unwrapped.data, "gymnasium"


def random_actions(env, kind, n, seed):
    """``n`` random actions, uniform in the environment's action bounds."""
    rng = np.random.default_rng(seed)
    if kind == "dm_control":
        spec = env.action_spec()
        lo, hi = spec.minimum, spec.maximum
    else:
        lo, hi = env.action_space.low, env.action_space.high
    return rng.uniform(lo, hi, size=(n, len(lo)))


def wrapped(env, kind, ellipsoids):
    """``env`` wrapped by mjccd's wrapper for its kind (first contacts of every physics substep)."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        if kind == "dm_control":
            from mjccd.dm_control import CCDWrapper
            return CCDWrapper(env, ellipsoids)
        from mjccd.mujoco.gym import CCDGymWrapper
        return CCDGymWrapper(env, ellipsoids)


def time_env_steps(name, kind, ellipsoids, steps, seed):
    """Median seconds per control step over chunks of CHUNK control steps: (plain env, wrapped env)."""
    out = []
    for wrap in (False, True):
        env = make_env(name, seed)[0]
        if wrap:
            env = wrapped(env, kind, ellipsoids)
        actions = random_actions(env, kind, steps + 1, seed)
        step = env.step
        step(actions[0])  # compiled and set up before the timed steps
        chunks = []
        for k in range(1, steps - CHUNK + 2, CHUNK):
            begin = time.perf_counter()
            for action in actions[k:k + CHUNK]:
                result = step(action)
                if kind == "gymnasium" and (result[2] or result[3]):
                    env.reset(seed=seed)
            chunks.append((time.perf_counter() - begin) / CHUNK)
        out.append(statistics.median(chunks) if chunks else float("nan"))
    return tuple(out)


def fits(model):
    """{label: EllipsoidSet}: the one-per-body fit and the default tolerance's."""
    return {"one per body": fit_model(model),
            f"tolerance {DEFAULT_TOLERANCE * 100:g} cm": fit_model(model, tolerance=DEFAULT_TOLERANCE)}


def random_controls(model, steps, seed):
    """(steps, nu) controls: uniform in each actuator's range (or [-1, 1] when unlimited), held HOLD steps."""
    rng = np.random.default_rng(seed)
    lo, hi = np.full(model.nu, -1.0), np.full(model.nu, 1.0)
    limited = model.actuator_ctrllimited.astype(bool)
    lo[limited], hi[limited] = model.actuator_ctrlrange[limited].T
    held = rng.uniform(lo, hi, size=(-(-steps // HOLD), model.nu))
    return np.repeat(held, HOLD, axis=0)[:steps]


# ---------------------------------------------------------------- geometry


class Geometry:
    """The model's own geoms at a state, on a private MjData: contacts, poses and distances."""

    def __init__(self, model):
        self.model = model
        self.data = mujoco.MjData(model)

    def at(self, data):
        """Contacts and geom poses of ``data``'s positions: (set of touching geom pairs, geom_xpos, geom quats)."""
        m, e = self.model, self.data
        e.qpos[:], e.mocap_pos[:], e.mocap_quat[:] = data.qpos, data.mocap_pos, data.mocap_quat
        mujoco.mj_fwdPosition(m, e)
        touching = {(min(c.geom1, c.geom2), max(c.geom1, c.geom2)) for c in e.contact[:e.ncon] if c.dist < 0.0}
        quats = np.empty((m.ngeom, 4))
        for g in range(m.ngeom):
            mujoco.mju_mat2Quat(quats[g], e.geom_xmat[g])
        return touching, e.geom_xpos.copy(), quats

    def distance(self, g1, g2, pose0, pose1, fraction):
        """Signed distance of geoms g1 and g2, each moved a ``fraction`` of the way from ``pose0`` to ``pose1``
        ((geom_xpos, quats) pairs) by a centre lerp and a quaternion lerp."""
        e = self.data
        for g in (g1, g2):
            e.geom_xpos[g] = (1.0 - fraction) * pose0[0][g] + fraction * pose1[0][g]
            q0, q1 = pose0[1][g], pose1[1][g]
            q = (1.0 - fraction) * q0 + fraction * (q1 if q0 @ q1 >= 0.0 else -q1)
            mat = np.empty(9)
            mujoco.mju_quat2Mat(mat, q / np.linalg.norm(q))
            e.geom_xmat[g] = mat
        return mujoco.mj_geomDistance(self.model, e, g1, g2, 10.0 * NEAR, None)


def covered(model, ellipsoids):
    """(geom ids the ellipsoids cover or mjccd checks as planes, {body id: its covered geoms})."""
    geoms = set(int(g) for row in bounded_geoms(model, ellipsoids) for g in row)
    geoms |= {int(p) for p in plane_pairs(model, ellipsoids)[:, 1]}
    by_body = {}
    for g in sorted(geoms):
        by_body.setdefault(int(model.geom_bodyid[g]), []).append(g)
    return geoms, by_body


# ---------------------------------------------------------------- one run


class Tally:
    """Counts of one environment and fit."""

    def __init__(self):
        self.new_contacts = self.recalled = 0
        self.first_contacts = self.precise = 0
        self.gaps = []
        self.missed = {}


def check_run(model, start, ellipsoids, controls, tally):
    """Step ``controls`` from ``start`` under a monitor that reports every pair; add recall and precision."""
    data = mujoco.MjData(model)
    mujoco.mj_copyData(data, model, start)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        monitor = CCDMonitor(model, data, ellipsoids, all_pairs=True)
    geometry = Geometry(model)
    cover, by_body = covered(model, ellipsoids)
    touching, *pose0 = geometry.at(data)
    previous_pairs = set()
    for ctrl in controls:
        data.ctrl[:] = ctrl
        monitor.step()
        report = monitor.last_report
        if report.unstable:
            mujoco.mj_copyData(data, model, start)
            touching, *pose0 = geometry.at(data)
            previous_pairs = set()
            continue
        found = {frozenset(c.body_ids) for c in report.contacts}
        overlapping = {frozenset(c.body_ids) for c in report.contacts if c.status_at_start != "separate"}
        now, *pose1 = geometry.at(data)
        for g1, g2 in now - touching:
            if g1 not in cover or g2 not in cover:
                continue
            pair = frozenset((int(model.geom_bodyid[g1]), int(model.geom_bodyid[g2])))
            tally.new_contacts += 1
            if pair in found or pair in previous_pairs or pair in overlapping:
                tally.recalled += 1
            else:
                key = tuple(sorted(mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_GEOM, g) or f"#{g}" for g in (g1, g2)))
                tally.missed[key] = tally.missed.get(key, 0) + 1
        for c in report.contacts:
            if c.status_at_start != "separate":
                continue
            b1, b2 = c.body_ids
            gap = min((geometry.distance(g1, g2, pose0, pose1, c.fraction)
                       for g1 in by_body.get(b1, ()) for g2 in by_body.get(b2, ())), default=np.inf)
            tally.first_contacts += 1
            tally.precise += gap <= NEAR
            tally.gaps.append(gap)
        touching, pose0, previous_pairs = now, pose1, found
    return monitor


def time_steps(model, start, controls, ellipsoids):
    """Median seconds per MuJoCo step over chunks of CHUNK steps: (bare mj_step, CCDMonitor.step)."""
    out = []
    for monitored in (False, True):
        data = mujoco.MjData(model)
        mujoco.mj_copyData(data, model, start)
        if monitored:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                step = CCDMonitor(model, data, ellipsoids).step
            step()  # compiled and set up before the timed steps
        else:
            def step():
                mujoco.mj_step(model, data)
        chunks = []
        for k in range(0, len(controls) - CHUNK + 1, CHUNK):
            begin = time.perf_counter()
            for ctrl in controls[k:k + CHUNK]:
                data.ctrl[:] = ctrl
                step()
            chunks.append((time.perf_counter() - begin) / CHUNK)
        out.append(statistics.median(chunks) if chunks else float("nan"))
    return tuple(out)


def measure(name, steps, env_steps, seed, progress):
    """Rows (dicts) of one environment, one per fit; None when its package is not installed."""
    made = make_env(name, seed)
    if made is None:
        return None
    _env, model, source, kind = made
    start = mujoco.MjData(model)
    mujoco.mj_copyData(start, model, source)
    controls = random_controls(model, steps, seed)
    rows = []
    for label, ellipsoids in fits(model).items():
        tally = Tally()
        monitor = check_run(model, start, ellipsoids, controls, tally)
        bare, monitored = time_steps(model, start, controls, ellipsoids)
        plain_env, wrapped_env = time_env_steps(name, kind, ellipsoids, env_steps, seed)
        rows.append({"env": name, "fit": label, "ellipsoids": len(ellipsoids), "pairs": len(monitor.pairs),
                     "planes": len(plane_pairs(model, ellipsoids)), "tally": tally,
                     "plain_ms": plain_env * 1e3, "wrapped_ms": wrapped_env * 1e3,
                     "bare_ratio": monitored / bare})
        progress.update(1)
    return rows


# ---------------------------------------------------------------- report


def _share(k, n):
    return f"{k / n:.3f} ({k}/{n})" if n else "- (0/0)"


def markdown(rows, skipped, args, command, seconds):
    lines = ["## Fidelity on MuJoCo environments (`mjccd bench fidelity`)", "",
             f"Command: `{command}` ({seconds:.0f} s)  ",
             f"Machine: {platform.machine()}, {os.cpu_count()} cores, Python {platform.python_version()}, "
             f"MuJoCo {mujoco.__version__}", "",
             f"{args.steps} steps per environment under random controls (held {HOLD} steps, seed {args.seed}). "
             f"Recall: new MuJoCo contacts between covered geoms that mjccd reported (that step or the one before, "
             f"or touching at the step start). Precision: mjccd first contacts at which the real geoms are within "
             f"{NEAR * 100:g} cm (`mj_geomDistance`). Cost: {args.env_steps} control steps of the wrapped "
             f"environment over the plain one, medians of {CHUNK}-step chunks; `CCDMonitor.step` over a bare "
             f"`mj_step` for context.", "",
             "| env | fit | ellipsoids | pairs | planes | recall | precision @ 1 cm | median gap (cm) "
             "| plain env (ms/step) | wrapped env (ms/step) | wrapped / plain | monitor / mj_step |",
             "| --- | --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: |"]
    for r in rows:
        t = r["tally"]
        gap = f"{statistics.median(t.gaps) * 100:.2f}" if t.gaps else "-"
        lines.append(f"| {r['env']} | {r['fit']} | {r['ellipsoids']} | {r['pairs']} | {r['planes']} | "
                     f"{_share(t.recalled, t.new_contacts)} | {_share(t.precise, t.first_contacts)} | {gap} | "
                     f"{r['plain_ms']:.3f} | {r['wrapped_ms']:.3f} | {r['wrapped_ms'] / r['plain_ms']:.2f} | "
                     f"{r['bare_ratio']:.2f} |")
    missed = [(r["env"], r["fit"], pair, n) for r in rows for pair, n in r["tally"].missed.items()]
    if missed:
        lines += ["", "Missed new contacts (env, fit, geoms: count): " + "; ".join(
            f"{e}, {f}, {a}-{b}: {n}" for e, f, (a, b), n in sorted(missed, key=lambda x: -x[3])[:20])]
    if skipped:
        lines += ["", "Not installed, not measured: " + ", ".join(skipped) + "."]
    return "\n".join(lines) + "\n"


def main(argv=None):
    parser = argparse.ArgumentParser(prog="mjccd bench fidelity", description=__doc__.splitlines()[0])
    parser.add_argument("--envs", nargs="+", choices=ENVS, default=list(ENVS), metavar="ENV",
                        help=f"environments (default: all of {', '.join(ENVS)})")
    parser.add_argument("--steps", type=int, default=2000, help="MuJoCo steps per environment (default 2000)")
    parser.add_argument("--env-steps", type=int, default=500,
                        help="control steps of each environment timed, plain and wrapped (default 500)")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--markdown", metavar="FILE", help="write the table into this markdown file")
    options.add_quick(parser, QUICK)
    args = options.parse(parser, argv, QUICK)
    options.check_ranges(parser, args, RANGES)
    options.check_markdown(parser, args.markdown, ())
    begin = time.perf_counter()
    rows, skipped = [], []
    with tqdm(total=2 * len(args.envs), desc="environments x fits", file=sys.stderr,
              disable=not sys.stderr.isatty()) as progress:
        for name in args.envs:
            env_rows = measure(name, args.steps, args.env_steps, args.seed, progress)
            if env_rows is None:
                skipped.append(name)
                progress.update(2)
            else:
                rows.extend(env_rows)
    command = "mjccd bench fidelity" + ("" if argv is None else " " + " ".join(argv))
    text = markdown(rows, skipped, args, command, time.perf_counter() - begin)
    print(text)
    if args.markdown:
        write_section(args.markdown, "fidelity", text)
        print(f"written to {args.markdown}")
    return 0
