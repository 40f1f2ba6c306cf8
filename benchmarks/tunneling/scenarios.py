"""Tunneling scenarios: a fast ball at a thin wall, balls in a jerked cup, a punch through a head.

Only MuJoCo and NumPy are needed to build and run them (mjccd only for :meth:`Scenario.ellipsoids`), so the
speculative-contacts peer (speculative.py) runs them in an environment with another MuJoCo.
"""
import abc
import pathlib
import time
import xml.etree.ElementTree as ET
from typing import NamedTuple, Optional

import mujoco
import numpy as np

ROOT = pathlib.Path(__file__).resolve().parents[2]

# MuJoCo's warnings for a NaN, infinite or huge position, velocity or acceleration (it then resets the data)
BAD_STATE_WARNINGS = (mujoco.mjtWarning.mjWARN_BADQPOS, mujoco.mjtWarning.mjWARN_BADQVEL,
                      mujoco.mjtWarning.mjWARN_BADQACC)

# Contacts of the guarded geoms use the stiffest time constant MuJoCo allows at the running timestep
# (refsafe raises 0.001 s to 2 x timestep); with the default 0.02 s even a detected contact cannot stop
# a ball at 100 m/s inside a 2 cm wall, whatever the timestep.
STIFF = 'solref="0.001 1"'

WALL_HALF = 0.01
BALL_RADIUS = 0.02

# A run of a closed scenario whose energy rose to this many times its start kinetic energy diverged (nothing
# in it adds energy: any rise is the integration's)
DIVERGED = 10.0


def wall_xml(timestep, speed):
    """(a) A 2 cm ball flying at ``speed`` m/s along +x at an ellipsoid wall 2 cm thick (1 m half-height)."""
    return f"""
<mujoco model="wall">
  <option timestep="{timestep!r}" gravity="0 0 -9.81"/>
  <worldbody>
    <body name="wall" pos="0 0 1">
      <geom name="wall" type="ellipsoid" size="{WALL_HALF} 1 1" {STIFF}/>
    </body>
    <body name="ball" pos="-0.5 0 1">
      <freejoint name="ball"/>
      <geom name="ball" type="sphere" size="{BALL_RADIUS}" density="1000" {STIFF}/>
    </body>
  </worldbody>
  <keyframe><key name="throw" qvel="{speed!r} 0 0 0 0 0"/></keyframe>
</mujoco>"""


class Scenario(abc.ABC):
    """One simulated situation: a model, its start state, the guarded pairs and a tunneling test."""

    name = ""
    duration = 0.0
    # closed: nothing does work on the bodies (no actuators, no applied forces, no prescribed motion), so the
    # mechanical energy (kinetic plus potential) can only fall; Episodes measures its peak
    closed = True

    def __init__(self, timestep, **params):
        self.timestep = timestep
        self.params = params
        self.model = self.build()

    @abc.abstractmethod
    def build(self):
        """The scenario's ``MjModel``."""

    def reset(self, data, rng=None):
        """Put ``data`` into the start state; ``rng`` jitters it (start position, speed) for repeated runs."""
        mujoco.mj_resetDataKeyframe(self.model, data, 0)
        if rng is not None:
            data.qpos[0] += rng.uniform(-0.1, 0.1)
            data.qvel[0] *= rng.uniform(0.9, 1.1)
        mujoco.mj_forward(self.model, data)

    def ellipsoids(self):
        """The guard's :class:`~mjccd.mujoco.EllipsoidSet`: one fitted per body."""
        from mjccd.mujoco import fit_model
        return fit_model(self.model, tolerance=None)

    pairs = None

    def control(self, data):
        """Set controls or mocap before a step (nothing by default)."""

    @abc.abstractmethod
    def tunneled(self, data):
        """True when the current state shows a body gone through the obstacle."""

    def spin_gain(self):
        """How much the contact spun a swung body up (boxing only; None where it does not apply)."""
        return None


class Wall(Scenario):
    """(a) Ball at a thin wall: tunneled when the ball centre is ever beyond the wall's mid-plane."""

    name = "wall"
    duration = 0.1

    def build(self):
        return mujoco.MjModel.from_xml_string(wall_xml(self.timestep, self.params["speed"]))

    def tunneled(self, data):
        return data.qpos[0] > 0.0


KICK_TIME = 0.01  # seconds the kick lasts
KICK_GAP = 0.02   # gap between the resting ball and the wall


class Kick(Wall):
    """(d) The wall's ball at rest 2 cm from the wall, kicked towards it: a force acts for the first 10 ms
    and leaves the ball at ``speed`` m/s.  It starts from rest, so the velocity at the start of the
    first step does not show where the step takes it (speculative contacts extrapolate that velocity).
    Tunneled: the ball centre beyond the wall's mid-plane before MuJoCo saw any ball-wall contact.  (A
    ball that MuJoCo sees touching can still be pushed through by the kick: at 200 m/s its force is
    2000 times the ball's weight, and MuJoCo's soft contact yields to a part of it in every mode.  That
    is the contact model's answer, not a missed contact, so it is not counted.)
    """

    name = "kick"
    duration = 0.1
    closed = False  # the kick does work

    def build(self):
        return mujoco.MjModel.from_xml_string(wall_xml(self.timestep, 0.0))

    def reset(self, data, rng=None):
        m = self.model
        mujoco.mj_resetDataKeyframe(m, data, 0)
        data.qpos[0] = -(WALL_HALF + BALL_RADIUS + KICK_GAP) + (0.0 if rng is None else rng.uniform(-0.005, 0.005))
        speed = self.params["speed"] * (1.0 if rng is None else rng.uniform(0.9, 1.1))
        self._ball = m.body("ball").id
        self._force = speed * m.body_mass[self._ball] / KICK_TIME
        self._touched = False
        mujoco.mj_forward(m, data)

    def control(self, data):
        """The kick: a constant force along +x during the steps that start before KICK_TIME."""
        data.xfrc_applied[self._ball, 0] = self._force if data.time < KICK_TIME - 0.5 * self.timestep else 0.0

    def tunneled(self, data):
        self._touched = self._touched or data.ncon > 0  # the ball and the wall are the only geoms
        return bool(data.qpos[0] > 0.0 and not self._touched)


# The cup: a floor, four thin side walls and a lid, all ellipsoids so the guard is exact.  Each part is a
# disk wider than the cup (semi-axis CUP_SPAN > CUP_HALF * sqrt(2)), so neighbouring parts overlap along
# every edge and corner: the mid-surfaces of the parts close the box, and a ball can leave it only by
# passing through a part.  (An open cup measures balls flying out over the rim, not tunneling.)
CUP_HALF = 0.07      # wall mid-planes at x, y = +-CUP_HALF
CUP_HEIGHT = 0.16    # floor mid-plane at z = 0, lid mid-plane at z = CUP_HEIGHT
CUP_SPAN = 0.12      # in-plane semi-axes of every part
CUP_SKIN = 0.006     # half-thickness of the side walls (floor and lid: 0.008)


def cup_xml(timestep, n_balls=3):
    """(b) Balls resting in a closed thin-walled heavy cup on a slide joint; the cup is jerked sideways."""
    balls = "\n".join(
        f'''    <body name="ball{k}" pos="{-0.02 + 0.02 * k!r} 0 {0.035 + 0.045 * k!r}">
      <freejoint/>
      <geom name="ball{k}" type="sphere" size="0.02" density="1000" {STIFF}/>
    </body>''' for k in range(n_balls))
    h, H, S, w, mid = CUP_HALF, CUP_HEIGHT, CUP_SPAN, CUP_SKIN, CUP_HEIGHT / 2
    return f"""
<mujoco model="cup">
  <option timestep="{timestep!r}"/>
  <worldbody>
    <body name="cup" pos="0 0 0">
      <joint name="cup" type="slide" axis="1 0 0"/>
      <inertial pos="0 0 0" mass="1000" diaginertia="10 10 10"/>
      <geom name="cup_floor" type="ellipsoid" size="{S} {S} 0.008" pos="0 0 0" {STIFF}/>
      <geom name="cup_lid" type="ellipsoid" size="{S} {S} 0.008" pos="0 0 {H}" {STIFF}/>
      <geom name="cup_px" type="ellipsoid" size="{w} {S} {S}" pos="{h} 0 {mid}" {STIFF}/>
      <geom name="cup_nx" type="ellipsoid" size="{w} {S} {S}" pos="{-h} 0 {mid}" {STIFF}/>
      <geom name="cup_py" type="ellipsoid" size="{S} {w} {S}" pos="0 {h} {mid}" {STIFF}/>
      <geom name="cup_ny" type="ellipsoid" size="{S} {w} {S}" pos="0 {-h} {mid}" {STIFF}/>
    </body>
{balls}
  </worldbody>
</mujoco>"""


class Cup(Scenario):
    """(b) A closed cup jerked along +x at ``speed`` m/s for 30 ms, then back: tunneled when a ball leaves it."""

    name = "cup"
    duration = 0.3
    closed = False  # the cup's motion is prescribed

    def build(self):
        return mujoco.MjModel.from_xml_string(cup_xml(self.timestep))

    def reset(self, data, rng=None):
        mujoco.mj_resetData(self.model, data)
        self._speed = self.params["speed"] * (1.0 if rng is None else rng.uniform(0.9, 1.1))
        if rng is not None:
            data.qpos[1:].reshape(-1, 7)[:, :2] += rng.uniform(-0.01, 0.01, (self.model.nbody - 2, 2))
        mujoco.mj_forward(self.model, data)

    def ellipsoids(self):
        from mjccd.mujoco import fit_model
        return fit_model(self.model, tolerance=None, per="geom")

    def _cup_v(self, t):
        return self._speed if t < 0.03 else (-self._speed * 0.15 if t < 0.23 else 0.0)

    def control(self, data):
        """Prescribe the cup's velocity (it is heavy enough that the balls barely slow it)."""
        data.qvel[0] = self._cup_v(data.time)

    def tunneled(self, data):
        """A ball centre outside the closed cup (beyond a wall's, the floor's or the lid's mid-surface)."""
        balls = data.qpos[1:].reshape(-1, 7)[:, :3] - np.array([data.qpos[0], 0.0, 0.0])
        return bool(np.any(np.abs(balls[:, :2]) > CUP_HALF) or np.any(balls[:, 2] < 0.0)
                    or np.any(balls[:, 2] > CUP_HEIGHT))


BOXING = ROOT / "models" / "boxing.xml"


def boxing_model(timestep):
    """The boxing scene made physical: b's head and a's right arm collide through bounding ellipsoids.

    The bodies are weightless of gravity and held by their joints' damping; a's
    right shoulder, elbow and wrist are free to swing, everything else keeps
    its pose (the limb capsules and the other bounds stay non-colliding).
    """
    from mjccd.fitting import Shape, fit_shapes
    from mjccd.quadric import matrix_to_quat, quat_to_matrix

    tree = ET.parse(BOXING)
    root = tree.getroot()
    option = root.find("option")
    option.set("timestep", repr(timestep))
    option.set("gravity", "0 0 0")
    # The swung arm spins at up to ~1 rad per step.  The default Euler integrator treats the gyroscopic
    # forces explicitly, so once a contact tilts that spin off its axis the run diverges (MuJoCo resets
    # it); the implicit integrator, MuJoCo's remedy for fast rotation, keeps every mode stable.
    option.set("integrator", "implicit")
    colliding = {"b_Head": (1, 2), "a_RightForeArm": (2, 1), "a_RightHand": (2, 1)}  # body: contype, conaffinity
    # one ellipsoid per colliding body, bounding its 1 cm bounds, in their place: the fist's arc through the
    # head's centre then always meets it
    for body in root.iter("body"):
        name = body.get("name", "")
        if name in colliding:
            bounds = [g for g in body.findall("geom") if g.get("class") == "bound"]
            centre, rotation, radii = fit_shapes([Shape(
                "ellipsoid", np.array(g.get("size").split(), float), np.array(g.get("pos").split(), float),
                quat_to_matrix(np.array(g.get("quat").split(), float))) for g in bounds])
            for geom in bounds:
                body.remove(geom)
            ct, ca = colliding[name]
            ET.SubElement(body, "geom", {
                "name": f"{name}_bound", "class": "bound", "size": " ".join(map(repr, radii.tolist())),
                "pos": " ".join(map(repr, centre.tolist())),
                "quat": " ".join(map(repr, matrix_to_quat(rotation).tolist())), "contype": str(ct),
                "conaffinity": str(ca), "solref": "0.001 1", "mass": "0.5" if name.startswith("a_") else "4"})
    for joint in root.iter("joint"):
        joint.set("damping", "0" if joint.get("name", "") == "a_RightArm" else "1e6")
    for parent in root.iter("body"):
        for fj in parent.findall("freejoint"):
            parent.remove(fj)
    model = mujoco.MjModel.from_xml_string(ET.tostring(root, encoding="unicode"))
    # bring b within reach: its head as far from a's right shoulder as a's fist, on the same line as before
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    shoulder = data.xpos[model.body("a_RightArm").id]
    head = data.geom_xpos[model.geom("b_Head_bound").id]
    reach = np.linalg.norm(data.geom_xpos[model.geom("a_RightHand_bound").id] - shoulder)
    gap = head - shoulder
    model.body_pos[model.body("b_Hips").id] -= gap * (1.0 - reach / np.linalg.norm(gap))
    return model


class Boxing(Scenario):
    """(c) a's right arm swung about the shoulder at ``speed`` (fist m/s) through b's head."""

    name = "boxing"
    duration = 0.15

    def build(self):
        return boxing_model(self.timestep)

    def reset(self, data, rng=None):
        m = self.model
        mujoco.mj_resetData(m, data)
        mujoco.mj_forward(m, data)
        self._aim(data, 1.0 if rng is None else rng.uniform(0.9, 1.1))

    def _aim(self, data, jitter):
        """Turn a's right shoulder so the fist heads for b's head, with the requested fist speed."""
        m = self.model
        jnt = m.joint("a_RightArm")
        dof = m.jnt_dofadr[jnt.id]
        body = m.jnt_bodyid[jnt.id]
        hand = m.body("a_RightHand").id
        head = m.body("b_Head").id
        shoulder = data.xpos[body]
        arm = data.xpos[hand] - shoulder
        target = data.geom_xpos[m.geom("b_Head_bound").id] - shoulder
        axis = np.cross(arm, target)
        axis /= np.linalg.norm(axis)
        omega = jitter * self.params["speed"] / np.linalg.norm(arm)
        # angular velocity of a ball joint is expressed in the child body's frame
        R = data.xmat[body].reshape(3, 3)
        data.qvel[dof:dof + 3] = R.T @ (axis * omega)
        self._axis_world, self._shoulder = axis, shoulder.copy()
        self._touched = False
        self._dof, self._swing, self._peak = dof, omega, omega
        mujoco.mj_forward(m, data)

    def ellipsoids(self):
        from mjccd.mujoco.guard import geom_ellipsoids
        return geom_ellipsoids(self.model, 5)

    pairs = (("a_RightForeArm", "b_Head"), ("a_RightHand", "b_Head"))

    def spin_gain(self):
        """The arm's peak angular speed so far (seen by :meth:`tunneled`, once per step) over its swing speed:
        above 1 the contact has added energy to the swing."""
        return self._peak / self._swing

    def tunneled(self, data):
        """The fist swung past the head's centre before MuJoCo ever saw the arm touch the head."""
        m = self.model
        self._peak = max(self._peak, float(np.linalg.norm(data.qvel[self._dof:self._dof + 3])))
        head = m.geom("b_Head_bound").id
        for c in data.contact[:data.ncon]:
            if head in (c.geom1, c.geom2):
                self._touched = True
        head_c = data.geom_xpos[head] - self._shoulder
        fist = data.geom_xpos[m.geom("a_RightHand_bound").id] - self._shoulder
        past = np.cross(head_c, fist) @ self._axis_world > 0.0 and fist @ head_c > 0.0
        return bool(past and not self._touched)


# (scenario, timestep, speeds) of the benchmark table
CASES = [
    (Wall, 0.002, (10.0, 50.0, 200.0)),
    (Wall, 0.005, (10.0, 50.0, 200.0)),
    (Wall, 0.010, (10.0, 50.0, 200.0)),
    (Cup, 0.002, (2.0, 10.0, 20.0)),
    (Cup, 0.010, (2.0, 10.0, 20.0)),
    (Boxing, 1 / 120, (5.0, 20.0, 60.0)),
    (Kick, 0.010, (10.0, 50.0, 200.0)),
]


def quick_cases():
    """One timestep and the fastest speed per scenario (``--quick``)."""
    return [(c, dt, s[-1:]) for c, dt, s in CASES[::2]]


class Energy:
    """Mechanical energy (kinetic plus potential: gravity and springs) of a model's states, on a private
    ``MjData`` so that the simulation's own data is not touched."""

    def __init__(self, model):
        self.model = model
        self.data = mujoco.MjData(model)

    def __call__(self, data):
        """(kinetic, potential) energy of ``data``'s positions and velocities, in joules."""
        m, e = self.model, self.data
        e.qpos[:] = data.qpos
        e.qvel[:] = data.qvel
        e.mocap_pos[:] = data.mocap_pos
        e.mocap_quat[:] = data.mocap_quat
        mujoco.mj_kinematics(m, e)
        mujoco.mj_comPos(m, e)
        mujoco.mj_tendon(m, e)
        mujoco.mj_makeM(m, e)
        mujoco.mj_energyPos(m, e)
        mujoco.mj_energyVel(m, e)
        return float(e.energy[1]), float(e.energy[0])


class Run(NamedTuple):
    """One run of :meth:`Episodes.run`."""

    tunneled: bool
    cost: float  # CPU seconds per simulated second (the controller and the step)
    unstable: bool  # MuJoCo met a bad state and reset the data
    energy: Optional[float]  # closed scenarios: the peak of (kinetic + potential - start potential) / start kinetic

    @property
    def divergent(self):
        """MuJoCo reset the run, or its energy rose to ``DIVERGED`` times the start kinetic energy."""
        return self.unstable or (self.energy is not None and not self.energy < DIVERGED)


class Episodes:
    """Repeated runs of one scenario on one simulation, built once as a user builds it.

    The model, one ``MjData`` and the step function are made here; each :meth:`run` resets the data (an
    episode, as dm-control's ``reset`` does) and times the steps.  Compiling a model per run would also
    flush the CPU caches inside the timed steps, charging every mode for the compiler's memory traffic.

    ``make_step(model, data)``, when given, returns the function that takes one step; otherwise each step
    is ``mujoco.mj_step``.
    """

    def __init__(self, scenario, make_step=None):
        self.scenario = scenario
        self.data = mujoco.MjData(scenario.model)
        self.step = None if make_step is None else make_step(scenario.model, self.data)
        self.energy = Energy(scenario.model) if scenario.closed else None

    def run(self, seed):
        """The :class:`Run` of one jittered run from the start state.

        The controller and the step are timed; the tunneling test and, in closed scenarios, the energy
        (after every step: each step of ``dt/k``, each whole guarded step) are not.  ``unstable``: MuJoCo met
        a bad state and reset the data (its bad-state warnings), so the rest of the run simulated the start
        pose and "not tunneled" means nothing.
        """
        sc, step, energy = self.scenario, self.step, self.energy
        m, d = sc.model, self.data
        sc.reset(d, np.random.default_rng(seed))  # mj_resetData also clears the warning counts
        tunneled = False
        elapsed = 0.0
        peak = None
        if energy is not None:
            kinetic0, potential0 = energy(d)
            peak = 1.0
        for _ in range(int(round(sc.duration / m.opt.timestep))):
            t0 = time.perf_counter()
            sc.control(d)
            if step is None:
                mujoco.mj_step(m, d)
            else:
                step()
            elapsed += time.perf_counter() - t0
            tunneled = tunneled or sc.tunneled(d)
            if energy is not None:
                kinetic, potential = energy(d)
                rise = (kinetic + potential - potential0) / kinetic0
                peak = max(peak, rise) if rise == rise else float("inf")  # NaN: diverged
        unstable = any(d.warning[int(w)].number > 0 for w in BAD_STATE_WARNINGS)
        return Run(tunneled, elapsed / sc.duration, unstable, peak)
