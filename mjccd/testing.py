"""Contact-time assertions for users' own test suites, with messages that show expected vs found."""
import os
import zipfile

import mujoco
import numpy as np

from mjccd import _validate
from mjccd.ccd import collision_intervals
from mjccd.errors import InputError, InputTypeError
from mjccd.fitting import DEFAULT_TOLERANCE
from mjccd.quadric import Ellipsoid
from mjccd.mujoco.adapter import ModelAdapter, load_model
from mjccd.mujoco.ellipsoids import EllipsoidSet, body_label, fit_model
from mjccd.mujoco.monitor import check_mode, selected_geoms
from mjccd.mujoco.motions import State, geom_distance_between
from mjccd.mujoco.pairs import select_pairs


def load_trajectory(trajectory, model, times=None):
    """(qpos (T, nq), times (T,)) from an array or an ``.npz`` with ``qpos`` (and optionally ``time``)."""
    if isinstance(trajectory, (str, os.PathLike)):
        path = os.fspath(trajectory)
        if not path.endswith(".npz"):
            raise InputError(f"trajectory: expected an .npz file with a 'qpos' array, got {path!r}")
        if not os.path.isfile(path):
            raise InputError(f"trajectory: no such file {path!r}")
        try:
            with np.load(path, allow_pickle=False) as f:
                arrays = {key: f[key] for key in ("qpos", "time") if key in f}
        except (OSError, ValueError, zipfile.BadZipFile, EOFError) as exc:
            raise InputError(f"trajectory: {path} is not a readable .npz file ({exc})") from None
        if "qpos" not in arrays:
            raise InputError(f"trajectory: {path} has no 'qpos' array")
        qpos = arrays["qpos"]
        if times is None:
            times = arrays.get("time")
    else:
        qpos = trajectory
    try:
        qpos = np.asarray(qpos, dtype=float)
    except (TypeError, ValueError):
        raise InputError(f"trajectory: expected qpos numbers, got {type(qpos).__name__}") from None
    if qpos.ndim != 2 or qpos.shape[1] != model.nq or qpos.shape[0] < 2:
        raise InputError(f"trajectory: expected qpos of shape (T >= 2, nq = {model.nq}), got {qpos.shape}")
    bad = np.argwhere(~np.isfinite(qpos))
    if len(bad):
        raise InputError(f"trajectory[{bad[0][0]}][{bad[0][1]}]: is NaN or infinite")
    if times is None:
        times = np.arange(len(qpos)) * model.opt.timestep
    times = _validate.array(times, (len(qpos),), "times")
    if not np.all(np.diff(times) > 0):
        raise InputError(f"times: expected {len(qpos)} increasing values")
    return qpos, times


def _setup(model, trajectory, ellipsoids, times, pairs, motion, mode):
    """(checker, states): the model's checker (:class:`~mjccd.mujoco.geoms.GeomChecker` in geoms mode, else the
    :class:`~mjccd.mujoco.ModelAdapter` of its ellipsoids) and the trajectory's states."""
    model = load_model(model)
    qpos, times = load_trajectory(trajectory, model, times)
    mode = check_mode(mode, motion)
    if ellipsoids is None:
        ellipsoids = fit_model(model)
    elif not isinstance(ellipsoids, EllipsoidSet):
        raise InputTypeError(f"ellipsoids: expected an EllipsoidSet or None, got {type(ellipsoids).__name__}")
    if mode == "geoms":
        checker = selected_geoms(model, ellipsoids, pairs, True, stacklevel=3)
    else:
        checker = ModelAdapter(model, ellipsoids, select_pairs(model, ellipsoids, pairs), motion)
    return checker, _states(model, qpos, times)


def _states(model, qpos, times):
    mpos = model.body_pos[model.body_mocapid >= 0].copy()
    mquat = model.body_quat[model.body_mocapid >= 0].copy()
    return [State(q, mpos, mquat, float(t)) for q, t in zip(qpos, times)]


def _tolerance(tol):
    """``tol`` as a finite number >= 0 (seconds)."""
    tol = _validate.scalar(tol, "tol")
    if tol < 0.0:
        raise InputError(f"tol: expected a number >= 0 (seconds), got {tol}")
    return tol


def _uncertain(c):
    return getattr(c, "certainty", "certified") != "certified"


def _bracket(c):
    lo, hi = c.bracket
    return f"[{lo:.9g}, {hi:.9g}] s"


def _describe(c):
    where = "" if c.point is None else (f" at point {np.array2string(c.point, precision=6)}"
                                        f" normal {np.array2string(c.normal, precision=6)}")
    if _uncertain(c):
        return (f"uncertain: a contact is possible in {_bracket(c)} ({c.bodies[0]!r}-{c.bodies[1]!r}, "
                f"{c.status_at_start} at step start; the solver hit a limit)" + where)
    return (f"t = {c.time:.9g} s ({c.bodies[0]!r}-{c.bodies[1]!r}, {c.status_at_start} at step start)"
            + where)


def trajectory_contacts(model, trajectory, *, pairs=None, ellipsoids=None, motion="rigid", times=None, mode=None):
    """First contact of every step of a qpos trajectory: a list of ``StepContact`` (steps without one skipped).

    A step whose answer is uncertain is listed too (``certainty == "uncertain"``, ``bracket`` in seconds).
    ``mode``: "geoms" (the model's own geoms, the default with the rigid motion) or "ellipsoids" (their
    fitted bounds), as in :class:`~mjccd.mujoco.CCDMonitor`.
    """
    checker, states = _setup(model, trajectory, ellipsoids, times, pairs, motion, mode)
    return [c for _, c in _step_contacts(checker, states)]


def _step_contacts(checker, states):
    """``(k, first contact of step k)`` of every step that has one."""
    for k, (s0, s1) in enumerate(zip(states, states[1:])):
        c = checker.check(s0, s1, names=(f"trajectory[{k}]", f"trajectory[{k + 1}]")).first
        if c is not None:
            yield k, c


def _what_was_checked(checker, ellipsoids):
    """How the contact was computed, in words, for a failure message."""
    if not isinstance(checker, ModelAdapter):
        return "the model's own geoms (geoms mode)"
    fit = ("the caller's ellipsoids" if ellipsoids is not None else
           f"the default fit, fit_model(model): within {DEFAULT_TOLERANCE:g} of the geoms")
    return f"bounding ellipsoids (ellipsoid mode), {fit}: a contact of the bounds, possibly before the geoms touch"


def _real_distance(model, state0, state1, fraction, bodies):
    """The least distance between the two bodies' geoms at ``fraction`` of the step, by MuJoCo
    (``mj_differentiatePos``/``mj_integratePos`` between the step's qpos, ``mj_geomDistance``), or None when a body
    has no geom."""
    data = mujoco.MjData(model)
    data.mocap_pos[:], data.mocap_quat[:] = state0.mocap_pos, state0.mocap_quat
    geoms = [[g for g in range(model.ngeom) if model.geom_bodyid[g] == b] for b in bodies]
    gap = geom_distance_between(model, data, [(g1, g2) for g1 in geoms[0] for g2 in geoms[1]], state0.qpos,
                                state1.qpos, fraction)
    return None if gap == np.inf else gap


def assert_first_contact(model, trajectory, pair, time, *, tol=1e-6, ellipsoids=None, motion="rigid", times=None,
                         mode=None):
    """Assert that the bodies of ``pair`` first touch at ``time`` seconds (within ``tol``) along the trajectory.

    An uncertain answer (the exact solver hit a limit: the first contact is only known to lie
    in a bracket [lo, hi]) passes only when ``time`` lies in that bracket (widened by ``tol``);
    otherwise it fails, naming the bracket.  Returns the found ``StepContact``.

    Args:
        model: ``MjModel``, MJCF path or MJCF string.
        trajectory: (T, nq) qpos rows, or an ``.npz`` with ``qpos`` (and ``time``).
        pair: (body, body) names or ids.
        time: expected simulation time of the first contact (``times[0]`` is the start).
        times: (T,) times of the rows; default ``k * model.opt.timestep``.
        mode: as in :func:`trajectory_contacts` (by default the model's own geoms).
    """
    time, tol = _validate.scalar(time, "time"), _tolerance(tol)
    checker, states = _setup(model, trajectory, ellipsoids, times, [pair], motion, mode)
    found = next(_step_contacts(checker, states), None)
    head = f"first contact of {pair[0]!r} and {pair[1]!r}: expected t = {time:.9g} s (tol {tol:g})"
    checked = f"checked: {_what_was_checked(checker, ellipsoids)}"
    if found is None:
        raise AssertionError(f"{head}, found no contact over [{states[0].time:.9g}, {states[-1].time:.9g}] s; "
                             f"{checked}")
    k, c = found
    if _uncertain(c):
        lo, hi = c.bracket
        if not lo - tol <= time <= hi + tol:
            raise AssertionError(f"{head}, found {_describe(c)}; {time:.9g} s is outside that bracket; {checked}")
        return c
    if abs(c.time - time) > tol:
        gap = _real_distance(checker.model, states[k], states[k + 1], c.fraction, c.body_ids)
        real = "" if gap is None else (f"; at that instant the real geoms are {gap:.3g} m apart (MuJoCo's "
                                       f"mj_geomDistance)")
        raise AssertionError(f"{head}, found {_describe(c)}; off by {c.time - time:+.3g} s; {checked}{real}")
    return c


def assert_no_contact(model, trajectory, *, pairs=None, ellipsoids=None, motion="rigid", times=None, show=5,
                      mode=None):
    """Assert that no pair (default: :func:`~mjccd.mujoco.default_pairs`) touches along the trajectory.

    An uncertain answer (the exact solver hit a limit and could not certify the pair free) fails
    too: a contact is possible within its bracket, and the message names it.  ``show``: how many
    steps the message lists.
    """
    if isinstance(show, (bool, np.bool_)) or not isinstance(show, (int, np.integer)):
        raise InputTypeError(f"show: expected an integer >= 0, got {show!r}")
    if show < 0:
        raise InputError(f"show: expected an integer >= 0, got {show!r}")
    found = trajectory_contacts(model, trajectory, pairs=pairs, ellipsoids=ellipsoids, motion=motion, times=times,
                                mode=mode)
    if found:
        lines = "\n".join("  " + _describe(c) for c in found[:show])
        more = f"\n  ... and {len(found) - show} more" if len(found) > show else ""
        unsure = sum(_uncertain(c) for c in found)
        if unsure == len(found):
            head = f"expected no contact, could not certify it: uncertain answers in {len(found)} step(s)"
        elif unsure:
            head = f"expected no contact, found contacts in {len(found)} step(s) ({unsure} uncertain)"
        else:
            head = f"expected no contact, found contacts in {len(found)} step(s)"
        raise AssertionError(f"{head}:\n{lines}{more}")


def contact_intervals(model, trajectory, pair, *, ellipsoids=None, motion="rigid", times=None, mode=None):
    """Maximal time intervals [t_in, t_out] (seconds) in which the two bodies (their geoms, or their ellipsoids
    in ellipsoid mode) are not separate."""
    checker, states = _setup(model, trajectory, ellipsoids, times, [pair], motion, mode)
    out = []
    for s0, s1 in zip(states, states[1:]):
        span = s1.time - s0.time
        for a, b in _step_intervals(checker, s0, s1):
                lo, hi = s0.time + a * span, s0.time + b * span
                if out and lo <= out[-1][1] + 1e-12 * max(1.0, abs(lo)):
                    out[-1] = (out[-1][0], max(out[-1][1], hi))
                else:
                    out.append((lo, hi))
    out.sort()
    merged = []
    for lo, hi in out:
        if merged and lo <= merged[-1][1]:
            merged[-1] = (merged[-1][0], max(merged[-1][1], hi))
        else:
            merged.append((lo, hi))
    return merged


def _step_intervals(checker, s0, s1):
    """Every (t_in, t_out) fraction of the step from s0 to s1 in which one of the checker's pairs touches."""
    if isinstance(checker, ModelAdapter):
        shapes = [Ellipsoid(r) for r in checker.radii]
        motions = checker.motions(s0, s1)
        return [iv for i, j in checker.pairs for iv in collision_intervals(shapes[i], motions[i], shapes[j],
                                                                           motions[j])]
    q0, q1 = checker.geom_poses(s0), checker.geom_poses(s1)
    return [iv for k in range(len(checker.pairs)) for iv in checker.pair_intervals(k, q0, q1)]


def assert_intervals(model, trajectory, pair, intervals, *, tol=1e-6, ellipsoids=None, motion="rigid", times=None,
                     mode=None):
    """Assert the contact intervals (seconds) of a body pair along the trajectory, endpoint by endpoint."""
    tol = _tolerance(tol)
    found = contact_intervals(model, trajectory, pair, ellipsoids=ellipsoids, motion=motion, times=times, mode=mode)
    expected = [(float(a), float(b)) for a, b in intervals]

    def fmt(rows):
        return "[" + ", ".join(f"({a:.9g}, {b:.9g})" for a, b in rows) + "]"

    head = f"contact intervals of {pair[0]!r} and {pair[1]!r} (tol {tol:g} s)"
    if len(found) != len(expected):
        raise AssertionError(f"{head}: expected {len(expected)} interval(s) {fmt(expected)}, "
                             f"found {len(found)} {fmt(found)}")
    for k, ((ea, eb), (fa, fb)) in enumerate(zip(expected, found)):
        if abs(ea - fa) > tol or abs(eb - fb) > tol:
            raise AssertionError(f"{head}: interval {k} expected ({ea:.9g}, {eb:.9g}), found ({fa:.9g}, {fb:.9g})"
                                 f"\n  expected {fmt(expected)}\n  found    {fmt(found)}")
    return found


__all__ = ["assert_first_contact", "assert_intervals", "assert_no_contact", "contact_intervals", "load_model",
           "load_trajectory", "trajectory_contacts", "body_label"]
