"""Gymnasium wrapper (extra ``mjccd[gymnasium]``): the first contact of each step in ``info``."""
import gymnasium

from mjccd.mujoco.monitor import CCDMonitor
from mjccd.mujoco.wrappers import SubstepRecorder, fitted_or_checked, _model_and_data


class CCDGymWrapper(gymnasium.Wrapper):
    """Adds ``info["ccd"]`` to every step of a Gymnasium MuJoCo environment.

    ``info["ccd"]`` holds ``contact_time`` (seconds from the start of the step
    to the first contact, +inf when none), ``contact_pair`` (body ids, -1 when
    none), ``contact_point``, ``contact_normal`` and ``contacts`` (the
    :class:`~mjccd.mujoco.StepContact` list).  Every one of the ``frame_skip``
    MuJoCo steps is checked by wrapping the environment's ``do_simulation``.
    Arguments as in :class:`mjccd.dm_control.CCDWrapper`.
    """

    def __init__(self, env, ellipsoids=None, *, pairs=None, motion="rigid", on_contact=None,
                 all_pairs=False, report_overlapping=True, per="body"):
        super().__init__(env)
        base, model, data = _model_and_data(env)
        if not callable(getattr(base, "do_simulation", None)):
            raise ValueError(f"env: {type(base).__name__} has no do_simulation(ctrl, n_frames) to hook")
        self.ellipsoids = fitted_or_checked(model, ellipsoids, per)
        self.monitor = CCDMonitor(model, data, self.ellipsoids, pairs=pairs, motion=motion,
                                  on_contact=on_contact, all_pairs=all_pairs,
                                  report_overlapping=report_overlapping)
        self._recorder = SubstepRecorder(self.monitor)
        self.last_contacts = []

    def step(self, action):
        base, model, data = _model_and_data(self.env)
        recorder = self._recorder
        recorder.begin(data)
        original = base.do_simulation

        def checked(ctrl, n_frames):
            for _ in range(int(n_frames)):
                recorder.substep(lambda: original(ctrl, 1), data)

        base.do_simulation = checked
        try:
            obs, reward, terminated, truncated, info = self.env.step(action)
        finally:
            del base.do_simulation
        self.last_contacts = sorted(recorder.contacts, key=lambda c: c.time)
        ccd = {key.split("/", 1)[1]: value for key, value in recorder.observation(model).items()}
        ccd["contacts"] = list(self.last_contacts)
        info = dict(info)
        info["ccd"] = ccd
        return obs, reward, terminated, truncated, info
