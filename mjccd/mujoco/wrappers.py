"""Environment wrappers: the exact first contact of every control step, over all physics substeps.

The dm-control wrappers (``CCDWrapper`` here, ``GuardedWrapper`` in :mod:`mjccd.mujoco.guard`) need a
dm-control that works with the installed MuJoCo: dm-control 1.0.50 and older install next to MuJoCo 4 (they
declare ``mujoco>=3.17`` without a cap) but cannot build a physics there; 1.0.52 can.
:func:`dm_control_problem` says why not (once per process); the wrappers then raise
:class:`DmControlUnavailableError`.  Nothing else in mjccd needs dm-control: the monitor, the guard's
stepper and the Gymnasium wrapper work on MuJoCo 4.
"""
import collections
import functools
import importlib.metadata
from collections.abc import Mapping

import mujoco
import numpy as np

from mjccd.errors import InputError, InputTypeError
from mjccd.mujoco.ellipsoids import EllipsoidSet, fit_model
from mjccd.mujoco.monitor import CCDMonitor, step_count

try:  # dm_env comes with dm-control, which mjccd leaves out on Python 3.13+ (pyproject.toml)
    import dm_env
    from dm_env import specs
except ImportError:
    dm_env = specs = None

OBSERVATION_KEYS = ("ccd/contact_time", "ccd/contact_pair", "ccd/contact_point", "ccd/contact_normal")
# the ccd/* entries of every step of a CCDWrapper with no pair to check: shared, so read-only
NO_CONTACT = {"ccd/contact_time": np.array(np.inf), "ccd/contact_pair": np.full(2, -1, np.int32),
               "ccd/contact_point": np.zeros(3), "ccd/contact_normal": np.zeros(3)}
for _entry in NO_CONTACT.values():
    _entry.flags.writeable = False


def fitted_or_checked(model, ellipsoids, per):
    """``ellipsoids`` when given (checked), else the bounding ellipsoids fitted to ``model``."""
    if ellipsoids is None:
        return fit_model(model, per=per)
    if not isinstance(ellipsoids, EllipsoidSet):
        raise InputTypeError(f"ellipsoids: expected an EllipsoidSet or None, got {type(ellipsoids).__name__}")
    return ellipsoids


class DmControlUnavailableError(RuntimeError):
    """A dm-control wrapper was used where dm-control does not work (MuJoCo 4 with dm-control 1.0.50 or older) or
    is missing."""


# the smallest dm-control use: a physics from MJCF, one step
_PROBE_XML = '<mujoco><worldbody><body><freejoint/><geom size="0.1"/></body></worldbody></mujoco>'


def _version(distribution):
    try:
        return importlib.metadata.version(distribution)
    except importlib.metadata.PackageNotFoundError:
        return None


@functools.lru_cache(maxsize=None)
def dm_control_problem():
    """None when dm-control works with the installed MuJoCo, else a sentence naming both versions and why.

    Tries the import and a minimal use (a physics built from MJCF and stepped once), once per process.
    """
    mj = f"MuJoCo {mujoco.__version__}"
    version = _version("dm-control")
    if version is None or dm_env is None:
        return (f"dm-control is not installed next to {mj} (mjccd installs it on Python < 3.13 only, where "
                f"its labmaze has wheels: pip install 'mjccd[dm-control]')")
    try:
        from dm_control import mujoco as dm_mujoco
        from dm_control.rl import control  # noqa: F401 (the wrappers' environments)

        dm_mujoco.Physics.from_xml_string(_PROBE_XML).step()
    except Exception as exc:  # noqa: BLE001 - whatever breaks, the wrappers cannot run
        first_line = str(exc).strip().splitlines()[0] if str(exc).strip() else ""
        return f"dm-control {version} does not work with {mj} ({type(exc).__name__}: {first_line})"
    return None


def require_dm_control(user):
    """Raise :class:`DmControlUnavailableError` naming ``user`` and the versions when dm-control does not work."""
    problem = dm_control_problem()
    if problem is None:
        return
    advice = (f"The MuJoCo API (mjccd.mujoco.CCDMonitor, GuardedStepper, mjccd.mujoco.gym.CCDGymWrapper) works "
              f"without dm-control, on MuJoCo {mujoco.__version__} too")
    if _version("dm-control") is not None:
        advice = ("For the dm-control wrappers use a MuJoCo that dm-control supports "
                  "(pip install 'mujoco>=3.17,<4'). " + advice)
    raise DmControlUnavailableError(f"{user} needs dm-control, but {problem}. {advice}")


def _built_by_dm_control(physics):
    """True when ``physics`` is a dm-control ``Physics``: dm-control built it with the installed MuJoCo."""
    if physics is None or dm_env is None:
        return False
    try:
        from dm_control import mujoco as dm_mujoco
    except Exception:  # noqa: BLE001 - whatever breaks the import, the probe names it
        return False
    return isinstance(physics, dm_mujoco.Physics)


class DelegatingEnvironment(dm_env.Environment if dm_env is not None else object):
    """Base of mjccd's dm-control wrappers: holds a dm-control environment and passes everything on."""

    def __init__(self, env):
        physics = getattr(env, "physics", None)
        if not _built_by_dm_control(physics):  # else dm-control evidently works here: no probe
            require_dm_control(type(self).__name__)
        if physics is None or not hasattr(physics, "model") or not hasattr(physics.model, "ptr"):
            raise InputTypeError(f"env: expected a dm-control environment with a `physics`, got {type(env).__name__}")
        self._env = env

    @property
    def physics(self):
        return self._env.physics

    def reset(self):
        return self._env.reset()

    def step(self, action):
        return self._env.step(action)

    def observation_spec(self):
        return self._env.observation_spec()

    def action_spec(self):
        return self._env.action_spec()

    def reward_spec(self):
        return self._env.reward_spec()

    def discount_spec(self):
        return self._env.discount_spec()

    def close(self):
        return self._env.close()

    def __getattr__(self, name):
        if name.startswith("__") or name == "_env":
            raise AttributeError(name)
        return getattr(self._env, name)


class SubstepRecorder:
    """Checks every simulator step of a control step and collects what the monitor reports.

    ``reports`` holds the :class:`~mjccd.mujoco.StepReport` of each step (``unstable`` where MuJoCo
    met a bad state: that step is not checked), ``contacts`` the contacts they report.
    """

    def __init__(self, monitor):
        self.monitor = monitor
        self.contacts = []
        self.reports = []
        self.start_time = 0.0
        self.unstable = False  # True when MuJoCo met a bad state in one of the steps recorded
        self._names = []  # "substep k", made once

    def begin(self, data):
        self.monitor.data = data
        self.contacts = []
        self.reports = []
        self.start_time = float(data.time)
        self.unstable = False

    def substep(self, advance, bodies_current=False):
        """Advance the simulation by one step with ``advance()`` and check that step (``bodies_current``: as
        :meth:`~mjccd.mujoco.CCDMonitor.advance_checked` takes it)."""
        reports, names = self.reports, self._names
        if len(names) == len(reports):
            names.append(f"substep {len(reports) + 1}")
        monitor = self.monitor
        report = monitor.advance_checked(advance, names[len(reports)], bodies_current=bodies_current)
        reports.append(report)
        if report.unstable:
            self.unstable = True
        if monitor.all_pairs:
            self.contacts.extend(report.contacts)
        elif report.first is not None:
            self.contacts.append(report.first)

    def results(self):
        """``(contacts, reports, unstable)`` of the control step: its contacts in time order, each step's
        report, and whether MuJoCo met a bad state."""
        return sorted(self.contacts, key=_time_of), list(self.reports), self.unstable

    def first(self):
        """The earliest contact of the control step, or None."""
        return min(self.contacts, key=_time_of) if self.contacts else None

    def observation(self, model=None):
        """The ``ccd/*`` observation entries for the control step just recorded (fresh arrays)."""
        c = self.first()
        if c is None:
            return {key: value.copy() for key, value in NO_CONTACT.items()}
        return {"ccd/contact_time": np.array(c.time - self.start_time),
                "ccd/contact_pair": np.array(c.body_ids, np.int32),
                "ccd/contact_point": np.zeros(3) if c.point is None else c.point.copy(),
                "ccd/contact_normal": np.zeros(3) if c.normal is None else c.normal.copy()}


def _time_of(contact):
    return contact.time


class PhysicsSubsteps:
    """A dm-control physics stepped one MuJoCo step at a time, as ``physics.step(1)`` steps it, errors included.

    ``advance()`` takes one step as dm-control's ``Physics.step(1)`` takes it (``legacy_step``:
    ``mj_step2``, or ``mj_step`` with the RK4 integrator, then ``mj_step1``; else ``mj_step``), without
    its ``check_invalid_state`` context around each step: that check runs only when a MuJoCo warning
    count changed in the step (one comparison of the counts' bytes), over that step alone, so a
    ``PhysicsError`` comes right after the step that raised a warning or, where the physics suppresses
    errors, the warning is logged, as ``physics.step(1)`` does.  A physics whose class steps otherwise
    (its own ``step``) is stepped by ``original_step(1)``.  ``bodies_current``: the step leaves the
    data's body poses those of its new positions (the legacy step ends with ``mj_step1``).
    """

    def __init__(self, physics, original_step):
        from dm_control.mujoco import engine

        self.physics, self.model, self.data = physics, physics.model.ptr, physics.data.ptr
        self.legacy, self.integrator = physics.legacy_step, self.model.opt.integrator
        self._counts = self.data.warning.number
        if type(physics).step is not engine.Physics.step:
            self.advance, self.bodies_current = functools.partial(original_step, 1), False
            return
        if not self.legacy:
            self._raw = functools.partial(mujoco.mj_step, self.model, self.data)
        elif self.integrator == mujoco.mjtIntegrator.mjINT_RK4:
            self._raw = self._rk4_legacy_step
        else:
            self._raw = self._legacy_step
        self.advance, self.bodies_current = self._step, self.legacy

    def fits(self, physics):
        """True while this stepper is the one of ``physics`` as it is now (its data, its kind of step)."""
        return (physics is self.physics and physics.data.ptr is self.data and physics.legacy_step == self.legacy
                and self.model.opt.integrator == self.integrator)

    def _legacy_step(self):
        mujoco.mj_step2(self.model, self.data)  # mj_step1 of the state ran at the end of the step before
        mujoco.mj_step1(self.model, self.data)

    def _rk4_legacy_step(self):
        mujoco.mj_step(self.model, self.data)
        mujoco.mj_step1(self.model, self.data)

    def _step(self):
        counts = self._counts
        before = counts.tobytes()
        self._raw()
        if counts.tobytes() != before:
            self._physics_check(before)

    def _physics_check(self, before):
        """dm-control's own ``check_invalid_state`` over the step just taken (``before``: the counts' bytes at
        its start): its context entered now, its snapshot set back to ``before``, then left."""
        physics = self.physics
        check = physics.check_invalid_state()
        check.__enter__()
        np.copyto(physics._warnings_before, np.frombuffer(before, dtype=self._counts.dtype))
        check.__exit__(None, None, None)


def substep_monitor(model, data, ellipsoids, per, **options):
    """``(ellipsoids, monitor, recorder)`` of an environment wrapper: the ellipsoids fitted (or checked), the
    :class:`~mjccd.mujoco.CCDMonitor` with ``options`` and the :class:`SubstepRecorder` of its substeps."""
    ellipsoids = fitted_or_checked(model, ellipsoids, per)
    monitor = CCDMonitor(model, data, ellipsoids, **options)
    return ellipsoids, monitor, SubstepRecorder(monitor)


def observation_specs():
    """Specs of the ``ccd/*`` observation entries."""
    if specs is None:
        raise DmControlUnavailableError(f"observation_specs needs dm_env: {dm_control_problem()}")
    return collections.OrderedDict([
        ("ccd/contact_time", specs.Array((), np.float64, "ccd/contact_time")),
        ("ccd/contact_pair", specs.Array((2,), np.int32, "ccd/contact_pair")),
        ("ccd/contact_point", specs.Array((3,), np.float64, "ccd/contact_point")),
        ("ccd/contact_normal", specs.Array((3,), np.float64, "ccd/contact_normal")),
    ])


class CCDWrapper(DelegatingEnvironment):
    """Wraps a dm-control environment and adds the first contact of each control step.

    Every physics substep of a control step is checked.  The observation gains
    ``ccd/contact_time`` (seconds from the start of the control step to the
    first contact, +inf when none), ``ccd/contact_pair`` (the two MuJoCo body
    ids, -1 when none), ``ccd/contact_point`` and ``ccd/contact_normal``
    (world frame, normal out of the first body; zeros when none or when the
    pair already overlapped at the start of a substep).  ``last_contacts``
    holds the :class:`~mjccd.mujoco.StepContact` objects of the last step,
    ``last_reports`` the :class:`~mjccd.mujoco.StepReport` of each of its
    substeps and ``last_unstable`` whether MuJoCo met a bad state in one of
    them (that substep is not checked; see :attr:`~mjccd.mujoco.StepReport.unstable`).
    As with dm-control's own stepping, such a substep raises ``PhysicsError``
    unless the physics suppresses errors.  Each substep is one MuJoCo step
    taken as ``physics.step(1)`` takes it, its warnings checked as that checks
    them (:class:`PhysicsSubsteps`): a control step leaves the physics bit for
    bit as the plain environment's does (unless a warning stops it).  With no
    pair to check (warned once, when the pairs are chosen) a step is the
    environment's own step, the no-contact entries (shared read-only arrays)
    added to the observation it returns: no substep is hooked, no state
    copied, no kinematics run; ``last_reports`` stays empty and
    ``last_unstable`` False.

    Args:
        env: a ``dm_control.rl.control.Environment`` (e.g. from ``suite.load``).
        ellipsoids: :class:`EllipsoidSet`; default: ``fit_model(model, per=per)`` (1 cm, read from the fit cache).
        pairs, motion, on_contact, all_pairs, report_overlapping, planes, mode: as in
            :class:`~mjccd.mujoco.CCDMonitor` (by default the model's own geoms, exact).
    """

    def __init__(self, env, ellipsoids=None, *, pairs=None, motion="rigid", on_contact=None,
                 all_pairs=False, report_overlapping=True, per="body", planes=True, mode=None):
        super().__init__(env)
        if not isinstance(env.observation_spec(), Mapping):
            raise InputError("env: its observation_spec is not a mapping; the ccd/* entries cannot be added")
        physics = env.physics
        model = physics.model.ptr
        self.ellipsoids, self.monitor, self._recorder = substep_monitor(
            model, physics.data.ptr, ellipsoids, per, pairs=pairs, motion=motion, on_contact=on_contact,
            all_pairs=all_pairs, report_overlapping=report_overlapping, planes=planes, mode=mode)
        self.last_contacts, self.last_reports, self.last_unstable = [], [], False
        self._idle = len(self.monitor.pairs) == 0 and len(self.monitor.plane_pairs) == 0  # (warned why)
        self._substeps = None  # the PhysicsSubsteps of the physics last stepped
        self._options = dict(pairs=pairs, motion=motion, on_contact=on_contact, all_pairs=all_pairs,
                             report_overlapping=report_overlapping, per=per, planes=planes, mode=mode)

    def __getstate__(self):
        """What rebuilds the wrapper: the environment (a dm-control one pickles its whole physics), the
        ellipsoids, the options and the last step's results; the monitor (a lock, views of the physics' data)
        is not pickled but built anew on the unpickled physics."""
        return {"env": self._env, "ellipsoids": self.ellipsoids, "options": self._options,
                "last": (self.last_contacts, self.last_reports, self.last_unstable)}

    def __setstate__(self, state):
        self.__init__(state["env"], state["ellipsoids"], **state["options"])
        self.last_contacts, self.last_reports, self.last_unstable = state["last"]

    def _with_ccd(self, timestep, recorded):
        entries = self._recorder.observation() if recorded else SubstepRecorder(self.monitor).observation()
        if isinstance(timestep.observation, dict):  # made afresh for this step (dm-control's tasks): in place
            timestep.observation.update(entries)
            return timestep
        obs = collections.OrderedDict(timestep.observation)
        obs.update(entries)
        return timestep._replace(observation=obs)

    def reset(self):
        self.last_contacts, self.last_reports, self.last_unstable = [], [], False
        return self._with_ccd(self._env.reset(), False)

    def step(self, action):
        if self._idle:  # nothing to check: the environment's step, its observation given the no-contact entries
            timestep = self._env.step(action)
            if isinstance(timestep.observation, dict):  # made afresh for this step (dm-control's tasks): in place
                timestep.observation.update(NO_CONTACT)
                return timestep
            return self._with_ccd(timestep, False)
        physics = self._env.physics
        if physics.model.ptr is not self.monitor.model:
            raise InputError("env: the physics model was reloaded; wrap the environment again")
        recorder = self._recorder
        hooked = vars(physics).get("step")
        if hooked is not None:  # another wrapper's hook of this physics' step: each substep through it
            advance, bodies_current = functools.partial(hooked, 1), False
        else:
            substeps = self._substeps
            if substeps is None or not substeps.fits(physics):
                substeps = self._substeps = PhysicsSubsteps(physics, physics.step)
            advance, bodies_current = substeps.advance, substeps.bodies_current
        recorder.begin(physics.data.ptr)

        def checked_step(nstep=1):
            for _ in range(step_count(nstep, "nstep")):
                recorder.substep(advance, bodies_current)

        physics.step = checked_step
        try:
            timestep = self._env.step(action)
        finally:
            if hooked is None:
                del physics.step
            else:  # the other wrapper's hook, as it was
                physics.step = hooked
        self.last_contacts, self.last_reports, self.last_unstable = recorder.results()
        return self._with_ccd(timestep, True)

    def observation_spec(self):
        spec = collections.OrderedDict(self._env.observation_spec())
        spec.update(observation_specs())
        return spec


def model_and_data(env):
    """(MjModel, MjData) of a Gymnasium MuJoCo environment."""
    base = getattr(env, "unwrapped", env)
    model, data = getattr(base, "model", None), getattr(base, "data", None)
    if not isinstance(model, mujoco.MjModel) or not isinstance(data, mujoco.MjData):
        raise InputTypeError(f"env: expected a Gymnasium MuJoCo environment with `model` and `data`, "
                             f"got {type(base).__name__}")
    return base, model, data
