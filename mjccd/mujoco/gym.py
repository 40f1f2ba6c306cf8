"""Gymnasium wrapper (extra ``mjccd[gymnasium]``): the first contact of each step in ``info``."""
import functools

import gymnasium
import mujoco

from mjccd.errors import InputTypeError
from mjccd.mujoco.monitor import step_count
from mjccd.mujoco.wrappers import NO_CONTACT, model_and_data, substep_monitor


class CCDGymWrapper(gymnasium.Wrapper):
    """Adds ``info["ccd"]`` to every step of a Gymnasium MuJoCo environment.

    ``info["ccd"]`` holds ``contact_time`` (seconds from the start of the step
    to the first contact, +inf when none), ``contact_pair`` (body ids, -1 when
    none), ``contact_point``, ``contact_normal``, ``contacts`` (the
    :class:`~mjccd.mujoco.StepContact` list), ``reports`` (the
    :class:`~mjccd.mujoco.StepReport` of each MuJoCo step) and ``unstable``
    (True when MuJoCo met a bad state in one of them: that step is not
    checked; see :attr:`~mjccd.mujoco.StepReport.unstable`).  Every one of the
    ``frame_skip`` MuJoCo steps is checked by wrapping the environment's
    ``do_simulation``: the first step is ``do_simulation(ctrl, 1)``; where the
    environment steps as Gymnasium's ``MujocoEnv`` does, the others are
    ``mj_step`` alone and ``mj_rnePostConstraint`` runs once after the last (the
    same states as the plain environment's), else each is ``do_simulation(ctrl, 1)``.
    ``last_contacts``, ``last_reports`` and ``last_unstable``
    keep the same of the last step.  Arguments as in :class:`mjccd.dm_control.CCDWrapper`.
    """

    def __init__(self, env, ellipsoids=None, *, pairs=None, motion="rigid", on_contact=None,
                 all_pairs=False, report_overlapping=True, per="body", planes=True, mode=None):
        super().__init__(env)
        base, model, data = model_and_data(env)
        if not callable(getattr(base, "do_simulation", None)):
            raise InputTypeError(f"env: {type(base).__name__} has no do_simulation(ctrl, n_frames) to hook")
        self.ellipsoids, self.monitor, self._recorder = substep_monitor(
            model, data, ellipsoids, per, pairs=pairs, motion=motion, on_contact=on_contact, all_pairs=all_pairs,
            report_overlapping=report_overlapping, planes=planes, mode=mode)
        self.last_contacts, self.last_reports, self.last_unstable = [], [], False
        self._idle = len(self.monitor.pairs) == 0 and len(self.monitor.plane_pairs) == 0  # (warned why)
        self._own_stepping = _steps_as_mujoco_env(base)

    def step(self, action):
        if self._idle:  # nothing to check: the environment's own step, with the no-contact entries
            obs, reward, terminated, truncated, info = self.env.step(action)
            info = dict(info)
            info["ccd"] = {key.split("/", 1)[1]: value for key, value in NO_CONTACT.items()}
            info["ccd"].update(contacts=[], reports=[], unstable=False)
            return obs, reward, terminated, truncated, info
        base, model, data = model_and_data(self.env)
        recorder = self._recorder
        recorder.begin(data)
        original = base.do_simulation
        hooked = vars(base).get("do_simulation")  # another wrapper's hook: each step through it
        own = self._own_stepping and hooked is None

        def checked(ctrl, n_frames):
            n = step_count(n_frames, "n_frames")
            recorder.substep(functools.partial(original, ctrl, 1))  # the environment's check of ctrl, its step
            if n == 1:
                return
            # Gymnasium's own stepping (ctrl set, mj_step, then mj_rnePostConstraint's derived forces): the ctrl
            # is set and the next steps are mj_step alone, the forces of the last state computed once at the end
            advance = functools.partial(mujoco.mj_step, model, data) if own else functools.partial(original, ctrl, 1)
            for _ in range(n - 1):
                recorder.substep(advance)
            if own:
                mujoco.mj_rnePostConstraint(model, data)

        base.do_simulation = checked
        try:
            obs, reward, terminated, truncated, info = self.env.step(action)
        finally:
            if hooked is None:
                del base.do_simulation
            else:  # the other wrapper's hook, as it was
                base.do_simulation = hooked
        self.last_contacts, self.last_reports, self.last_unstable = recorder.results()
        ccd = {key[4:]: value for key, value in recorder.observation().items()}  # "ccd/..." less "ccd/"
        ccd["contacts"] = list(self.last_contacts)
        ccd["reports"] = list(self.last_reports)
        ccd["unstable"] = self.last_unstable
        info = dict(info)
        info["ccd"] = ccd
        return obs, reward, terminated, truncated, info


def _steps_as_mujoco_env(base):
    """True when ``base`` steps as Gymnasium's ``MujocoEnv`` does (its own ``do_simulation`` and
    ``_step_mujoco_simulation``: ctrl set, ``mj_step``, ``mj_rnePostConstraint``)."""
    from gymnasium.envs.mujoco.mujoco_env import MujocoEnv  # (imports its renderer: loaded with the environment)

    cls = type(base)
    return (cls.do_simulation is MujocoEnv.do_simulation
            and getattr(cls, "_step_mujoco_simulation", None) is MujocoEnv._step_mujoco_simulation)
