"""How faithful mjccd's contacts are on real MuJoCo models: recall, precision and cost, in geoms mode and in
ellipsoid mode with two fits.

Each environment (dm-control suite and Gymnasium models; Gymnasium's only when installed) runs ``--steps``
MuJoCo steps under random controls, uniform in each actuator's range and held for ``HOLD`` steps, from the
environment's own reset state.  The same steps are checked by :class:`~mjccd.mujoco.CCDMonitor` with every
colliding pair reported (``all_pairs``): in geoms mode (the default: the model's own geoms, the default fit
standing for meshes only) and in ellipsoid mode with the one-per-body fit and the default tolerance's fit.

* **recall**: every *new* MuJoCo contact (a geom pair with ``dist`` below ``-DEPTH``, beyond MuJoCo's own
  collision tolerance, among the contacts of a step's end state that was not among those (``dist < 0``) of the
  state before) must be an mjccd contact of that step or the step before, or a pair mjccd found already
  touching at that step's start.  Geoms mode matches the geom pair and counts every MuJoCo contact (a pair it
  does not check is a miss, and listed as *unchecked*); ellipsoid mode matches the body pair and counts the
  contacts of geoms its ellipsoids cover (or of a covered geom and a plane it checks).
* **precision**: of the mjccd contacts of pairs that were separate at the step start, the share at which the
  real geoms are within 1 mm (and within 1 cm) at the contact instant: the state there is interpolated by
  MuJoCo (``mj_differentiatePos`` between the step's two ends, ``mj_integratePos`` by the contact's fraction,
  ``mj_kinematics``), the distance is MuJoCo's ``mj_geomDistance`` of the two geoms (geoms mode) or the least
  over the two bodies' covered geoms (ellipsoid mode): independent of mjccd's own geometry and motion.
* **cost**: a control step of the wrapped environment (:class:`~mjccd.dm_control.CCDWrapper`,
  :class:`~mjccd.mujoco.gym.CCDGymWrapper`) against the plain environment's, both from the same reset
  under the same random actions, median over chunks of ``CHUNK`` control steps; and, for context,
  ``CCDMonitor.step`` against a bare ``mj_step``.

A step in which MuJoCo meets a bad state restarts the episode from the reset state (and is not counted).
"""
import argparse
import functools
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
from mjccd.mujoco.motions import geom_distance_between
from mjccd.mujoco.pairs import bounded_geoms, plane_pairs
from mjccd._command import PlainHelpFormatter

DM_CONTROL = {"humanoid": ("humanoid", "run"), "humanoid_CMU": ("humanoid_CMU", "run"), "cheetah": ("cheetah", "run"),
              "walker": ("walker", "walk"), "quadruped": ("quadruped", "walk"),
              "manipulator": ("manipulator", "bring_ball"), "hopper": ("hopper", "hop"),
              "acrobot": ("acrobot", "swingup")}
GYMNASIUM = ("Ant-v5", "Humanoid-v5", "HalfCheetah-v5")
ENVS = tuple(DM_CONTROL) + GYMNASIUM
HOLD = 5          # steps a random control is held
CHUNK = 50        # steps per timed chunk
DEPTH = 1e-6      # m: a MuJoCo contact counts when it is deeper than this (beyond MuJoCo's collision tolerance)
NEAR = (1e-3, 1e-2)  # m: a contact instant is precise when the real geoms are this close (both reported)
QUICK = {"steps": 60, "env_steps": 60, "envs": ["walker", "humanoid"]}
RANGES = {"steps": (1, 1_000_000), "env_steps": (1, 1_000_000), "seed": (0, 2**63 - 1)}
ONE_PER_BODY = "one per body"


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


def wrapped(env, kind, ellipsoids, mode):
    """``env`` wrapped by mjccd's wrapper for its kind (first contacts of every physics substep)."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        if kind == "dm_control":
            from mjccd.dm_control import CCDWrapper
            return CCDWrapper(env, ellipsoids, mode=mode)
        from mjccd.mujoco.gym import CCDGymWrapper
        return CCDGymWrapper(env, ellipsoids, mode=mode)


def time_env_steps(name, kind, ellipsoids, mode, steps, seed):
    """Median seconds per control step over chunks of CHUNK control steps: (plain env, wrapped env).

    The two environments take their chunks in turn, so that a machine speeding up or slowing down during the
    run weighs on both alike."""
    runs = []
    for wrap in (False, True):
        env = make_env(name, seed)[0]
        if wrap:
            env = wrapped(env, kind, ellipsoids, mode)
        actions = random_actions(env, kind, steps + 1, seed)
        env.step(actions[0])  # compiled and set up before the timed steps
        runs.append((env, actions, []))
    for k in range(1, steps - CHUNK + 2, CHUNK):
        for env, actions, chunks in runs:
            step = env.step
            begin = time.perf_counter()
            for action in actions[k:k + CHUNK]:
                result = step(action)
                if kind == "gymnasium" and (result[2] or result[3]):
                    env.reset(seed=seed)
            chunks.append((time.perf_counter() - begin) / CHUNK)
    return tuple(statistics.median(chunks) if chunks else float("nan") for _, _, chunks in runs)


def setups(model):
    """[(mode, fit label, EllipsoidSet)]: geoms mode with the default fit (standing for meshes only), then
    ellipsoid mode with the one-per-body fit and the default fit (the default tolerance's)."""
    fitted = fit_model(model)
    tight = f"tolerance {DEFAULT_TOLERANCE * 100:g} cm"
    return [("geoms", tight, fitted), ("ellipsoids", ONE_PER_BODY, fit_model(model, tolerance=None)),
            ("ellipsoids", tight, fitted)]


def random_controls(model, steps, seed):
    """(steps, nu) controls: uniform in each actuator's range (or [-1, 1] when unlimited), held HOLD steps."""
    rng = np.random.default_rng(seed)
    lo, hi = np.full(model.nu, -1.0), np.full(model.nu, 1.0)
    limited = model.actuator_ctrllimited.astype(bool)
    lo[limited], hi[limited] = model.actuator_ctrlrange[limited].T
    held = rng.uniform(lo, hi, size=(-(-steps // HOLD), model.nu))
    return np.repeat(held, HOLD, axis=0)[:steps]


# ---------------------------------------------------------------- geometry


def _pair(g1, g2):
    return (min(int(g1), int(g2)), max(int(g1), int(g2)))


class Geometry:
    """The model's own geoms at a state, on a private MjData: MuJoCo's contacts and distances."""

    def __init__(self, model):
        self.model = model
        self.data = mujoco.MjData(model)

    def contacts(self, data):
        """MuJoCo's contacts at ``data``'s positions: {geom pair: dist} of those with dist < 0."""
        m, e = self.model, self.data
        e.qpos[:], e.mocap_pos[:], e.mocap_quat[:] = data.qpos, data.mocap_pos, data.mocap_quat
        mujoco.mj_fwdPosition(m, e)
        out = {}
        for c in e.contact[:e.ncon]:
            if c.dist < 0.0:
                key = _pair(c.geom1, c.geom2)
                out[key] = min(out.get(key, 0.0), float(c.dist))
        return out

    def distance(self, pairs, qpos0, qpos1, fraction):
        """Least signed distance (mj_geomDistance) of the geom ``pairs`` at the state a ``fraction`` of the way
        from qpos0 to qpos1 as MuJoCo interpolates it (mj_differentiatePos, mj_integratePos)."""
        return geom_distance_between(self.model, self.data, pairs, qpos0, qpos1, fraction, 10.0 * NEAR[-1])


def covered(model, ellipsoids):
    """(geom ids the ellipsoids cover or ellipsoid mode checks as planes, {body id: its covered geoms})."""
    geoms = set(int(g) for row in bounded_geoms(model, ellipsoids) for g in row)
    geoms |= {int(p) for p in plane_pairs(model, ellipsoids)[:, 1]}
    by_body = {}
    for g in sorted(geoms):
        by_body.setdefault(int(model.geom_bodyid[g]), []).append(g)
    return geoms, by_body


# ---------------------------------------------------------------- one run


class Tally:
    """Counts of one environment and setup."""

    def __init__(self):
        self.new_contacts = self.recalled = 0
        self.first_contacts = 0
        self.precise = [0] * len(NEAR)
        self.gaps = []
        self.missed = {}
        self.unchecked = {}
        self.contacts = self.uncertain = self.pointless = 0  # contacts reported; uncertain ones; uncertain, no point


def _name(model, g):
    return mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_GEOM, g) or f"#{g}"


def check_run(model, start, ellipsoids, mode, controls, tally):
    """Step ``controls`` from ``start`` under a monitor (``mode``) that reports every pair; add recall and
    precision to ``tally``; returns the monitor."""
    data = mujoco.MjData(model)
    mujoco.mj_copyData(data, model, start)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        monitor = CCDMonitor(model, data, ellipsoids, all_pairs=True, mode=mode)
    geometry = Geometry(model)
    if mode == "geoms":
        ids = monitor.geoms.geom_ids
        checked = {_pair(ids[a], ids[b]) for a, b in monitor.geoms.pairs}
    else:
        cover, by_body = covered(model, ellipsoids)
    touching = geometry.contacts(data)
    previous = set()
    for ctrl in controls:
        data.ctrl[:] = ctrl
        qpos0 = data.qpos.copy()
        monitor.step()
        report = monitor.last_report
        if report.unstable:
            mujoco.mj_copyData(data, model, start)
            touching, previous = geometry.contacts(data), set()
            continue
        if mode == "geoms":
            found = {_pair(*c.geoms) for c in report.contacts}
            started = {_pair(*c.geoms) for c in report.contacts if c.status_at_start != "separate"}
        else:
            found = {frozenset(c.body_ids) for c in report.contacts}
            started = {frozenset(c.body_ids) for c in report.contacts if c.status_at_start != "separate"}
        now = geometry.contacts(data)
        for (g1, g2), dist in now.items():
            if dist >= -DEPTH or (g1, g2) in touching:
                continue
            if mode == "geoms":
                key = (g1, g2)
                if key not in checked:
                    names = (_name(model, g1), _name(model, g2))
                    tally.unchecked[names] = tally.unchecked.get(names, 0) + 1
            else:
                if g1 not in cover or g2 not in cover:
                    continue
                key = frozenset((int(model.geom_bodyid[g1]), int(model.geom_bodyid[g2])))
            tally.new_contacts += 1
            if key in found or key in previous or key in started:
                tally.recalled += 1
            else:
                names = (_name(model, g1), _name(model, g2))
                tally.missed[names] = tally.missed.get(names, 0) + 1
        for c in report.contacts:
            tally.contacts += 1
            if c.certainty != "certified":
                tally.uncertain += 1
                tally.pointless += c.point is None or c.normal is None
            if c.status_at_start != "separate":
                continue
            if mode == "geoms":
                pairs = [c.geoms]
            else:
                b1, b2 = c.body_ids
                pairs = [(g1, g2) for g1 in by_body.get(b1, ()) for g2 in by_body.get(b2, ())]
            gap = geometry.distance(pairs, qpos0, data.qpos, c.fraction)
            tally.first_contacts += 1
            for k, near in enumerate(NEAR):
                tally.precise[k] += abs(gap) <= near
            tally.gaps.append(gap)
        touching, previous = now, found
    return monitor


def time_steps(model, start, controls, ellipsoids, mode):
    """Median seconds per MuJoCo step over chunks of CHUNK steps: (bare mj_step, CCDMonitor.step), the two
    taking their chunks in turn."""
    runs = []
    for monitored in (False, True):
        data = mujoco.MjData(model)
        mujoco.mj_copyData(data, model, start)
        if monitored:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                step = CCDMonitor(model, data, ellipsoids, mode=mode).step
            step()  # compiled and set up before the timed steps
        else:
            step = functools.partial(mujoco.mj_step, model, data)
        runs.append((data, step, []))
    for k in range(0, len(controls) - CHUNK + 1, CHUNK):
        for data, step, chunks in runs:
            begin = time.perf_counter()
            for ctrl in controls[k:k + CHUNK]:
                data.ctrl[:] = ctrl
                step()
            chunks.append((time.perf_counter() - begin) / CHUNK)
    return tuple(statistics.median(chunks) if chunks else float("nan") for _, _, chunks in runs)


def measure(name, steps, env_steps, seed, progress):
    """Rows (dicts) of one environment, one per setup; None when its package is not installed."""
    made = make_env(name, seed)
    if made is None:
        return None
    _env, model, source, kind = made
    start = mujoco.MjData(model)
    mujoco.mj_copyData(start, model, source)
    controls = random_controls(model, steps, seed)
    rows = []
    for mode, label, ellipsoids in setups(model):
        tally = Tally()
        monitor = check_run(model, start, ellipsoids, mode, controls, tally)
        bare, monitored = time_steps(model, start, controls, ellipsoids, mode)
        plain_env, wrapped_env = time_env_steps(name, kind, ellipsoids, mode, env_steps, seed)
        if mode == "geoms":
            parts, pairs = len(monitor.geoms.geom_ids), len(monitor.pairs)
        else:
            parts, pairs = len(ellipsoids), len(monitor.pairs) + len(monitor.plane_pairs)
        rows.append({"env": name, "mode": mode, "fit": label, "parts": parts, "pairs": pairs, "tally": tally,
                     "plain_ms": plain_env * 1e3, "wrapped_ms": wrapped_env * 1e3, "bare_ratio": monitored / bare})
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
             f"Geoms mode (the default) checks the model's own geoms; ellipsoid mode their fitted bounds. "
             f"Recall: new MuJoCo contacts deeper than {DEPTH:g} m that mjccd reported (that step or the one "
             f"before, or touching at the step start); geoms mode matches geom pairs and counts every MuJoCo "
             f"contact, a pair it does not check (unchecked) as a miss; ellipsoid mode matches body pairs and "
             f"counts the geoms its ellipsoids cover. Precision: mjccd first contacts at which the real geoms are "
             f"within 1 mm (1 cm), by MuJoCo's `mj_geomDistance` at the state MuJoCo interpolates "
             f"(`mj_differentiatePos`, `mj_integratePos`) at the contact's fraction of the step. Cost: "
             f"{args.env_steps} control steps of the wrapped environment over the plain one, medians of {CHUNK}-step "
             f"chunks, the two taking their chunks in turn; `CCDMonitor.step` over a bare `mj_step` (likewise) "
             f"for context. Uncertain: the share of all contacts "
             f"reported (every pair, every step) that are `uncertain`, and how many of those lack a point or "
             f"normal.", "",
             "| env | mode | fit | geoms / ellipsoids | pairs | recall | unchecked | precision @ 1 mm "
             "| precision @ 1 cm | median gap (mm) | uncertain | uncertain without point | plain env (ms/step) "
             "| wrapped env (ms/step) | wrapped / plain | monitor / mj_step |",
             "| --- | --- | --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: "
             "| ---: |"]
    for r in rows:
        t = r["tally"]
        gap = f"{statistics.median(t.gaps) * 1e3:.2f}" if t.gaps else "-"
        unchecked = str(sum(t.unchecked.values())) if r["mode"] == "geoms" else "-"
        lines.append(f"| {r['env']} | {r['mode']} | {r['fit']} | {r['parts']} | {r['pairs']} | "
                     f"{_share(t.recalled, t.new_contacts)} | {unchecked} | {_share(t.precise[0], t.first_contacts)} | "
                     f"{_share(t.precise[1], t.first_contacts)} | {gap} | {_share(t.uncertain, t.contacts)} | "
                     f"{t.pointless} | {r['plain_ms']:.3f} | {r['wrapped_ms']:.3f} | "
                     f"{r['wrapped_ms'] / r['plain_ms']:.2f} | {r['bare_ratio']:.2f} |")
    for what, key in (("Missed new contacts", "missed"), ("MuJoCo contacts of pairs geoms mode does not check",
                                                           "unchecked")):
        listed = [(r["env"], r["mode"], r["fit"], pair, n) for r in rows for pair, n in getattr(r["tally"], key).items()]
        if listed:
            lines += ["", f"{what} (env, mode, fit, geoms: count): " + "; ".join(
                f"{e}, {m}, {f}, {a}-{b}: {n}" for e, m, f, (a, b), n in sorted(listed, key=lambda x: -x[4])[:20])]
    if skipped:
        lines += ["", "Not installed, not measured: " + ", ".join(skipped) + "."]
    return "\n".join(lines) + "\n"


def main(argv=None):
    parser = argparse.ArgumentParser(formatter_class=PlainHelpFormatter,
                                     prog="mjccd bench fidelity", description=__doc__.splitlines()[0])
    parser.add_argument("--envs", nargs="+", choices=ENVS, default=list(ENVS), metavar="ENV",
                        help=f"environments (default: all of {', '.join(ENVS)})")
    parser.add_argument("--steps", type=int, default=1000, help="MuJoCo steps per environment (default 1000)")
    parser.add_argument("--env-steps", type=int, default=500,
                        help="control steps of each environment timed, plain and wrapped (default 500)")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--markdown", metavar="FILE", help="write the table into this markdown file")
    args = options.parse_checked(parser, argv, QUICK, RANGES)
    begin = time.perf_counter()
    rows, skipped = [], []
    per_env = 3  # setups per environment (see setups)
    with tqdm(total=per_env * len(args.envs), desc="environments x setups", file=sys.stderr,
              disable=not sys.stderr.isatty()) as progress:
        for name in args.envs:
            env_rows = measure(name, args.steps, args.env_steps, args.seed, progress)
            if env_rows is None:
                skipped.append(name)
                progress.update(per_env)
            else:
                rows.extend(env_rows)
    command = "mjccd bench fidelity" + ("" if argv is None else " " + " ".join(argv))
    text = markdown(rows, skipped, args, command, time.perf_counter() - begin)
    print(text)
    if args.markdown:
        write_section(args.markdown, "fidelity", text)
        print(f"written to {args.markdown}")
    return 0
