"""Chain-motion filters (mjccd.chain_bounds): never a colliding pair rejected, and replay's answers unchanged.

Every pair a filter clears is solved again by the exact solver on the same
:class:`mjccd.Chain` motions and must have no contact; a pair the filters call
overlapping at the start must be overlapping for the exact solver too.  The
chains are random and adversarial: long arms, hinge steps close to the
allowed limit, slides, ball and free joints turning far, thin bodies, bodies
starting just apart.
"""
import pathlib

import numpy as np
import pytest

from mjccd import Ball, Chain, Ellipsoid, Fixed, Free, Hinge, Slide, first_contact, replay
from mjccd import chain_bounds as cb
from mjccd.mujoco import ModelAdapter, State
from mjccd.quadric import static_status_pose

ROOT = pathlib.Path(__file__).resolve().parents[1]
CLEARED = (cb.SPHERE, cb.CACHED_PLANE, cb.NEW_PLANE)


def _unit(v):
    return v / np.linalg.norm(v)


def _quat(rng):
    return _unit(rng.normal(size=4))


class Spec:
    """One random chain: a root pose, up to three joints on links, the ellipsoid; joint values per frame."""

    def __init__(self, rng, frames, long_arm=False, big_steps=False, thin=False, speed=1.0, spin=False):
        self.root = ("free", None) if rng.random() < 0.25 else ("fixed", (rng.normal(size=3) * 0.3, _quat(rng)))
        self.joints = []
        count = rng.integers(1 if spin else 0, 4)
        for n in range(count):
            length = rng.uniform(1.0, 3.0) if long_arm else rng.uniform(0.1, 0.8)
            kind = rng.choice(["hinge", "ball"] if spin and n == count - 1 else ["hinge", "hinge", "slide", "ball"])
            axis = _unit(rng.normal(size=3))
            if kind == "hinge":
                limit = 3.1 if big_steps else 2.5
                a0 = rng.uniform(-limit, limit)
                step = rng.uniform(1.0, 2.0 * limit) if big_steps else rng.uniform(0.0, 0.6) * speed
                values = [a0]
                for _ in range(frames - 1):
                    nxt = values[-1] + rng.choice([-1.0, 1.0]) * step
                    values.append(float(np.clip(nxt, -limit, limit)))
            elif kind == "slide":
                values = list(np.cumsum(rng.normal(size=frames) * (1.0 if big_steps else 0.2 * speed)))
            else:
                q = _quat(rng)
                values = [q]
                for _ in range(frames - 1):
                    turn = _quat(rng) if big_steps else _unit(np.r_[1.0, rng.normal(size=3) * 0.3 * speed])
                    values.append(_qmul(values[-1], turn))
            self.joints.append((rng.normal(size=3) * length / np.sqrt(3), kind, axis, values))
        if self.root[0] == "free":
            self.free = [(rng.normal(size=3) * (0.5 if big_steps else 0.1), _quat(rng)) for _ in range(frames)]
            for f in range(1, frames):
                p, q = self.free[f - 1]
                turn = _quat(rng) if big_steps else _unit(np.r_[1.0, rng.normal(size=3) * 0.2 * speed])
                self.free[f] = (p + rng.normal(size=3) * (0.5 if big_steps else 0.1 * speed), _qmul(q, turn))
        # spin: the last joint turns the ellipsoid about its own centre (all of the sweep from its size)
        self.geom = (np.zeros(3) if spin else rng.normal(size=3) * 0.2, _quat(rng))
        if thin:
            self.radii = np.array([rng.uniform(0.3, 1.0), 1e-3, rng.uniform(1e-3, 0.05)])
        else:
            self.radii = rng.uniform(0.05, 0.4, size=3)
        self.offset = np.zeros(3)

    def chain(self, f):
        """The Chain from frame f to frame f + 1."""
        elements = [Fixed(self.offset)]
        if self.root[0] == "free":
            (p0, q0), (p1, q1) = self.free[f], self.free[f + 1]
            elements.append(Free(p0, q0, p1, q1))
        else:
            elements.append(Fixed(*self.root[1]))
        for link, kind, axis, values in self.joints:
            elements.append(Fixed(link))
            if kind == "hinge":
                elements.append(Hinge(axis, values[f], values[f + 1]))
            elif kind == "slide":
                elements.append(Slide(axis, values[f], values[f + 1]))
            else:
                elements.append(Ball(values[f], values[f + 1]))
        elements.append(Fixed(*self.geom))
        return Chain(elements)


def _qmul(a, b):
    return np.array([a[0] * b[0] - a[1] * b[1] - a[2] * b[2] - a[3] * b[3],
                     a[0] * b[1] + a[1] * b[0] + a[2] * b[3] - a[3] * b[2],
                     a[0] * b[2] - a[1] * b[3] + a[2] * b[0] + a[3] * b[1],
                     a[0] * b[3] + a[1] * b[2] - a[2] * b[1] + a[3] * b[0]])


def _centre_and_quat(chain, t):
    program, q0, q1 = cb.program_from_elements([chain])
    c, q = cb.ChainFilter(program, [[1.0, 1.0, 1.0]], np.zeros((0, 2))).poses(q0, q1, t)
    return c[0], q[0]


def _place(rng, a, b, mode, spread=(0.3, 1.6)):
    """Shift b's chain so that the pair is near contact: at a random time, or just apart at t = 0.

    "near": the centres at a random time of the first step are ``spread`` times the sum of the largest
    semi-axes apart; "just_apart": the two touch at t = 0 but for a relative 1e-9 of their distance.
    """
    ca_chain, cb_chain = a.chain(0), b.chain(0)
    if mode == "just_apart":
        pa, qa = _centre_and_quat(ca_chain, 0.0)
        pb, qb = _centre_and_quat(cb_chain, 0.0)
        u = _unit(rng.normal(size=3))
        lo, hi = 0.0, 2.0 * (a.radii.max() + b.radii.max())

        def separate(s):
            return static_status_pose(a.radii, pa, qa, b.radii, pa + s * u, qb) == 1

        for _ in range(60):  # bisection to the touching distance along u
            mid = 0.5 * (lo + hi)
            lo, hi = (lo, mid) if separate(mid) else (mid, hi)
        b.offset = pa + hi * (1.0 + 1e-9) * u - pb
    else:
        t = rng.uniform(0.0, 1.0)
        pa, _ = _centre_and_quat(ca_chain, t)
        pb, _ = _centre_and_quat(cb_chain, t)
        reach = (a.radii.max() + b.radii.max()) * rng.uniform(*spread)
        b.offset = pa + reach * _unit(rng.normal(size=3)) - pb


def _check_pairs(specs, pairs, frames):
    """Filter every step and solve exactly each pair the filters decided; returns the counts per outcome.

    Pairs left to the exact solver (EXACT) carry no claim and are not solved here (with big steps some
    of them take the solver seconds).
    """
    program, _, _ = cb.program_from_elements([s.chain(0) for s in specs])
    filt = cb.ChainFilter(program, np.array([s.radii for s in specs]), pairs)
    seen = np.zeros(5, dtype=np.int64)
    for f in range(frames - 1):
        chains = [s.chain(f) for s in specs]
        _, q0, q1 = cb.program_from_elements(chains)
        outcome = filt.step(q0, q1).copy()
        for k, (i, j) in enumerate(pairs):
            seen[outcome[k]] += 1
            if outcome[k] == cb.EXACT:
                continue
            c = first_contact(Ellipsoid(specs[i].radii), chains[i], Ellipsoid(specs[j].radii), chains[j])
            if outcome[k] in CLEARED:
                assert c is None, (f, k, cb.OUTCOME_NAMES[outcome[k]], c)
            elif outcome[k] == cb.OVERLAP_T0:
                assert c is not None and c.point is None and c.status_at_start != "separate", (f, k, c)
    return seen


def test_program_poses_match_the_chain():
    """The filters' own kinematics give the pose Chain.transform gives, at the ends and inside the step."""
    rng = np.random.default_rng(1)
    for n in range(30):
        spec = Spec(rng, 2, long_arm=n % 2 == 0, big_steps=n % 3 == 0)
        chain = spec.chain(0)
        for t in (0.0, 0.37, 1.0):
            c, q = _centre_and_quat(chain, t)
            T = chain.transform(t)
            np.testing.assert_allclose(c, T[:, 3], atol=1e-12)
            w, x, y, z = q
            R = np.array([[w * w + x * x - y * y - z * z, 2 * (x * y - w * z), 2 * (x * z + w * y)],
                          [2 * (x * y + w * z), w * w - x * x + y * y - z * z, 2 * (y * z - w * x)],
                          [2 * (x * z - w * y), 2 * (y * z + w * x), w * w - x * x - y * y + z * z]])
            np.testing.assert_allclose(R, T[:, :3], atol=1e-12)


def test_sweep_bounds_every_point_of_the_body():
    """Every surface point at any t of a piece stays within the node's sweep of where it is at the node."""
    rng = np.random.default_rng(2)
    worst = 0.0
    for n in range(40):
        spec = Spec(rng, 2, long_arm=n % 2 == 0, big_steps=n % 4 == 1, thin=n % 5 == 2)
        chain = spec.chain(0)
        program, q0, q1 = cb.program_from_elements([chain])
        ta, tb = sorted(rng.uniform(0.0, 1.0, size=2))
        t0 = rng.uniform(ta, tb) if n % 3 else (ta if n % 2 else tb)
        out = np.empty((1, cb.NODE))
        cb.node_pose(program.kind, program.vec, program.quat, program.adr, program.start, q0, q1, 0, t0, ta, tb,
                     float(spec.radii.max()), np.empty((len(program.kind), 8)), out, 0)
        sweep = out[0, 7]
        dirs = rng.normal(size=(200, 3))
        local = spec.radii * dirs / np.linalg.norm(dirs, axis=1, keepdims=True)  # points on the surface
        T0 = chain.transform(t0)
        x0 = local @ T0[:, :3].T + T0[:, 3]
        for t in np.linspace(ta, tb, 17):
            T = chain.transform(t)
            moved = np.linalg.norm(local @ T[:, :3].T + T[:, 3] - x0, axis=1).max()
            assert moved <= sweep + 1e-12, (n, t, moved, sweep)
            worst = max(worst, moved / sweep) if sweep > 0 else worst
    assert worst > 0.3  # the bound is not vacuous: some bodies use a good part of it


@pytest.mark.parametrize("kind", ["random", "adversarial"])
def test_filters_never_reject_a_colliding_pair(kind):
    """A few hundred chain pairs over three steps, each filter verdict checked against the exact solver."""
    rng = np.random.default_rng(3 if kind == "random" else 4)
    specs, pairs = [], []
    modes = ["near", "just_apart"] if kind == "adversarial" else ["near", "near", "far"]
    for n in range(60):
        a = Spec(rng, 4, long_arm=kind == "adversarial" and n % 2 == 0,
                 big_steps=kind == "adversarial" and n % 3 == 0, thin=kind == "adversarial" and n % 4 == 1,
                 spin=kind == "adversarial" and n % 3 == 2)
        b = Spec(rng, 4, long_arm=kind == "adversarial" and n % 2 == 1,
                 big_steps=kind == "adversarial" and n % 5 == 0, thin=kind == "adversarial" and n % 3 == 1)
        mode = modes[n % len(modes)]
        if mode == "far":
            b.offset = _unit(rng.normal(size=3)) * rng.uniform(3.0, 8.0)
        else:
            _place(rng, a, b, mode)
        specs += [a, b]
        pairs.append((2 * n, 2 * n + 1))
    seen = _check_pairs(specs, np.array(pairs), 4)
    assert seen.sum() == 180
    # every stage is exercised, and many pairs are left to the solver (the placements are close calls)
    assert seen[cb.NEW_PLANE] >= 50 and seen[cb.OVERLAP_T0] >= 10 and seen[cb.EXACT] >= 10, seen
    assert seen[cb.SPHERE] >= 5, seen


def test_cached_normals_are_checked_again():
    """A normal kept from the last step is only used when it still separates the swept bodies."""
    rng = np.random.default_rng(5)
    specs, pairs = [], []
    for n in range(20):
        a, b = Spec(rng, 6, speed=0.2), Spec(rng, 6, speed=0.2)
        _place(rng, a, b, "near", (1.0, 1.5))
        specs += [a, b]
        pairs.append((2 * n, 2 * n + 1))
    seen = _check_pairs(specs, np.array(pairs), 6)
    assert seen[cb.CACHED_PLANE] >= 10 and seen[cb.NEW_PLANE] >= 10, seen


@pytest.mark.parametrize("mover", ["free", "hinge", "slide", "ball"])
def test_tunnelling_steps_are_left_to_the_solver(mover):
    """Apart at both ends of the step, through each other in the middle: no filter may clear it."""
    q = (1.0, 0.0, 0.0, 0.0)
    turn = (np.cos(0.8), 0.0, 0.0, np.sin(0.8))  # 1.6 rad about z
    chains = {"free": Chain([Free((3.0, 0.2, 0.0), q, (-3.0, 0.2, 0.0), q)]),
              "hinge": Chain([Hinge((0.0, 0.0, 1.0), -1.5, 1.5), Fixed((3.0, 0.0, 0.0))]),
              "slide": Chain([Fixed((0.0, 0.3, 0.0)), Slide((1.0, 0.0, 0.0), -4.0, 4.0)]),
              "ball": Chain([Fixed((0.0, 1.2, 0.0)), Ball((np.cos(-0.8), 0.0, 0.0, np.sin(-0.8)), turn)])}
    other = {"free": (0.0, 0.0, 0.0), "hinge": (3.0, 0.0, 0.0), "slide": (0.0, 0.0, 0.0), "ball": (0.6, 1.0, 0.0)}
    moving = chains[mover]
    still = Chain([Fixed(other[mover])])
    radii = np.array([[1.0, 0.05, 0.05] if mover == "ball" else [0.3, 0.2, 0.1], [0.2, 0.2, 0.2]])
    if mover == "hinge":
        still = Chain([Fixed((0.0, 3.0, 0.0))])  # on the arc swept by the hinge's ellipsoid
    program, q0, q1 = cb.program_from_elements([moving, still])
    outcome = cb.ChainFilter(program, radii, [[0, 1]]).step(q0, q1)
    c = first_contact(Ellipsoid(radii[0]), moving, Ellipsoid(radii[1]), still)
    assert c is not None and c.status_at_start == "separate" and 0.0 < c.time < 1.0
    assert outcome[0] == cb.EXACT


def test_program_refuses_inconsistent_arrays():
    with pytest.raises(ValueError, match="inconsistent"):
        cb.ChainProgram([0], np.zeros((1, 3)), np.zeros((1, 4)), [0], [0, 2])
    program, q0, q1 = cb.program_from_elements([Chain([Hinge((0, 0, 1), 0.0, 0.5), Fixed((1.0, 0, 0))])])
    with pytest.raises(ValueError, match="joint value vectors"):
        cb.ChainFilter(program, [[0.1, 0.1, 0.1]], [[0, 0]]).step(q0[:0], q1[:0])


# ---------------------------------------------------------------- replay


def _frames(model_file, traj_file, first, last):
    """(model, ellipsoids, pairs, states) of a replay's frames first .. last."""
    model = replay.load_model(model_file)
    ellipsoids, pairs = replay.replay_ellipsoids(model)
    with np.load(traj_file) as d:
        qpos = d["qpos"][first:last + 1]
    none = (np.zeros((0, 3)), np.zeros((0, 4)))
    return model, ellipsoids, pairs, [State(q, *none, float(k)) for k, q in enumerate(qpos)]


def _same_answers(model, ellipsoids, pairs, states):
    """Every frame's contacts of all pairs with the chain filters equal those without; the summed counters."""
    filtered = ModelAdapter(model, ellipsoids, pairs, "chain")
    plain = ModelAdapter(model, ellipsoids, pairs, "chain", chain_filters=False)
    totals = [dict.fromkeys(replay.COUNTER_NAMES, 0), dict.fromkeys(replay.COUNTER_NAMES, 0)]
    for s0, s1 in zip(states, states[1:]):
        a, b = (checker.check(s0, s1, all_pairs=True) for checker in (filtered, plain))
        assert [(c.pair, c.fraction, c.status_at_start, c.certainty) for c in a.contacts] == \
            [(c.pair, c.fraction, c.status_at_start, c.certainty) for c in b.contacts]
        for x, y in zip(a.contacts, b.contacts):
            np.testing.assert_array_equal(x.point, y.point)
            np.testing.assert_array_equal(x.normal, y.normal)
        for total, report in zip(totals, (a, b)):
            for name, v in report.counters.items():
                total[name] += v
    return totals


def test_replay_chain_filters_give_the_same_contacts_boxing():
    """Glove contacts of the boxing scene: every frame's answers equal those of solving all its pairs."""
    counters, plain = _same_answers(*_frames(ROOT / "models" / "boxing.xml", ROOT / "data" / "boxing_traj.npz",
                                             143, 148))
    assert counters["colliding"] == plain["colliding"] >= 3
    assert counters["overlapping_t0"] == plain["overlapping_t0"] >= 1
    assert counters["sphere_culled"] > 1500 and counters["cached_plane"] > 10
    assert counters["solved_exactly"] <= 10 and plain["solved_exactly"] == plain["pairs"]  # every pair solved


def test_replay_chain_filters_give_the_same_contacts_arm():
    """Hinge chains (the arm scene): the same answers with and without filters through its contacts."""
    counters, plain = _same_answers(*_frames(ROOT / "models" / "arm_obstacle.xml", ROOT / "data" / "arm_traj.npz",
                                             46, 53))
    assert counters["colliding"] == plain["colliding"] >= 1


def test_chain_program_poses_match_mujoco():
    """The chain layout's program (what the filters read) puts every ellipsoid where MuJoCo's kinematics does."""
    for model_file, traj_file in (("boxing.xml", "boxing_traj.npz"), ("arm_obstacle.xml", "arm_traj.npz")):
        model, ellipsoids, pairs, states = _frames(ROOT / "models" / model_file, ROOT / "data" / traj_file, 10, 12)
        checker = ModelAdapter(model, ellipsoids, pairs, "chain")
        layout = checker.chains
        filt = cb.ChainFilter(layout.program, ellipsoids.radii, pairs)
        v1, v2 = layout.values(states[1]), layout.values(states[2])
        for t, state in ((0.0, states[1]), (1.0, states[2])):
            c, q = filt.poses(v1, v2, t)
            poses = checker.kinematics.ellipsoid_poses(state, checker.body_ids, ellipsoids.positions,
                                                       ellipsoids.quaternions)
            np.testing.assert_allclose(c, poses[:, :3], atol=1e-12)
            sign = np.sign(np.sum(q * poses[:, 3:], axis=1))[:, None]
            np.testing.assert_allclose(q * sign, poses[:, 3:], atol=1e-12)
