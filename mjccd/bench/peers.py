"""Peer baselines for `mjccd bench core`: python-fcl naive CCD and MuJoCo distance sampling.

Both peers answer the same question as `mjccd.first_contact` for two ellipsoids under a
rigid motion over normalized time t in [0, 1]: the first time the two touch, or None.
Neither is exact; they are sampling methods whose cost and error the table measures.

python-fcl (0.7, FCL 0.7) as found:

* Only the naive solver (`CCDC_NAIVE`: evaluate the discrete `collide` at evenly spaced
  times, return the first colliding one) accepts ellipsoids. Conservative advancement
  prints "collision function between node type 11 and node type 11 is not supported" and
  reports no contact; ray shooting and the polynomial solver print "Invalid continuous
  collision setting/checking" for every shape pair.
* `CCDM_LINEAR` (`InterpMotion`) interpolates the translation linearly and the rotation at
  constant angular velocity about one axis (slerp). mjccd's rigid motion moves along the
  same great circle of orientations but with the quaternion lerp parameterization, so the
  two motions differ when rotations are large (for a relative rotation of angle theta the
  orientation mismatch is of order theta**3 / 16 at mid-step); with rotation held constant
  they coincide exactly.
* `InterpMotion(tf_begin, tf_end)`, the constructor `continuousCollide` uses, leaves its
  reference point uninitialized. The result depends on heap contents: in a process that
  had imported mujoco, 173 of 500 translation-only queries disagreed with the
  translation-only motion. `CCDM_SCREW` with no rotation moves the body |d| times too
  far (its axis is not normalized). `CCDM_TRANS` (`TranslationMotion`) is deterministic
  and correct but keeps the start rotation. The "auto" motion therefore uses `CCDM_TRANS`
  when neither body rotates, and `CCDM_LINEAR` otherwise.
* The naive solver samples t = i / (n - 1), i = 0..n-1, and caps n at ceil(1 / toc_err).
  Here `num_max_iterations = n_samples + 1` and toc_err is set below 1 / n_samples, so the
  fcl peer sees the same grid t = k / n_samples as the MuJoCo peer.
"""

from __future__ import annotations

import dataclasses
import math
import statistics
import time
from typing import Callable, Sequence

import numpy as np

FCL_SKIP_MESSAGE = "skipped: python-fcl not installed (pip install mjccd[bench])"
DT_TOLERANCE = 1e-6
"""A peer's contact time counts as wrong when it is further than this from the reference."""


# ----------------------------------------------------------------------------- queries


@dataclasses.dataclass(frozen=True)
class RigidQuery:
    """Two ellipsoids, each moving rigidly from its t=0 pose to its t=1 pose.

    Attributes:
        radii_a, radii_b: (3,) semi-axes in the body frame.
        position_a, position_b: (2, 3) world positions, rows t=0 and t=1.
        quaternion_a, quaternion_b: (2, 4) orientations [w, x, y, z], rows t=0 and t=1.
        name: optional label.
    """

    radii_a: np.ndarray
    position_a: np.ndarray
    quaternion_a: np.ndarray
    radii_b: np.ndarray
    position_b: np.ndarray
    quaternion_b: np.ndarray
    name: str = ""

    def __post_init__(self):
        for field, shape in (("radii_a", (3,)), ("position_a", (2, 3)),
                             ("quaternion_a", (2, 4)), ("radii_b", (3,)),
                             ("position_b", (2, 3)), ("quaternion_b", (2, 4))):
            value = np.array(getattr(self, field), dtype=np.float64)
            if value.shape != shape:
                raise ValueError(f"`{field}` must have shape {shape}, got {value.shape}")
            if not np.all(np.isfinite(value)):
                raise ValueError(f"`{field}` must be finite, got {value!r}")
            value.setflags(write=False)
            object.__setattr__(self, field, value)
        for field in ("radii_a", "radii_b"):
            if np.any(getattr(self, field) <= 0):
                raise ValueError(f"`{field}` must be positive, got {getattr(self, field)!r}")
        for field in ("quaternion_a", "quaternion_b"):
            if np.any(np.linalg.norm(getattr(self, field), axis=1) == 0):
                raise ValueError(f"`{field}` must be non-zero, got {getattr(self, field)!r}")

    @property
    def rotates(self) -> bool:
        """True when either body's orientation differs between t=0 and t=1."""
        return not (_same_rotation(*self.quaternion_a) and _same_rotation(*self.quaternion_b))

    def pose_a(self, t: float) -> tuple[np.ndarray, np.ndarray]:
        """(position, unit quaternion) of body a at time t under mjccd's rigid motion."""
        return rigid_pose(self.position_a, self.quaternion_a, t)

    def pose_b(self, t: float) -> tuple[np.ndarray, np.ndarray]:
        """(position, unit quaternion) of body b at time t under mjccd's rigid motion."""
        return rigid_pose(self.position_b, self.quaternion_b, t)

    @classmethod
    def from_case(cls, case: dict) -> "RigidQuery":
        """Build a query from one `mjccd solve` case whose motions are static or rigid."""

        def body(key):
            spec = case[key]
            motion = spec["motion"]
            if motion["type"] == "static":
                p = [motion["position"]] * 2
                q = [motion["quaternion"]] * 2
            elif motion["type"] == "rigid":
                p = [motion["start"]["position"], motion["end"]["position"]]
                q = [motion["start"]["quaternion"], motion["end"]["quaternion"]]
            else:
                raise ValueError(
                    f"{case.get('id', '?')}: {key}.motion.type must be 'static' or 'rigid' "
                    f"for the peers, got {motion['type']!r}")
            return spec["radii"], p, q

        ra, pa, qa = body("a")
        rb, pb, qb = body("b")
        return cls(ra, pa, qa, rb, pb, qb, name=str(case.get("id", "")))


def _same_rotation(q0: np.ndarray, q1: np.ndarray) -> bool:
    """True when two quaternions give exactly the same rotation matrix."""
    return bool(np.array_equal(quaternion_to_matrix(q0), quaternion_to_matrix(q1)))


def quaternion_to_matrix(q: np.ndarray) -> np.ndarray:
    """Rotation matrix of a quaternion [w, x, y, z] of any non-zero length."""
    w, x, y, z = q
    n = w * w + x * x + y * y + z * z
    return np.array([
        [w * w + x * x - y * y - z * z, 2 * (x * y - w * z), 2 * (x * z + w * y)],
        [2 * (x * y + w * z), w * w - x * x + y * y - z * z, 2 * (y * z - w * x)],
        [2 * (x * z - w * y), 2 * (y * z + w * x), w * w - x * x - y * y + z * z],
    ]) / n


def rigid_pose(position: np.ndarray, quaternion: np.ndarray, t):
    """mjccd's rigid motion at time(s) t: lerp position, lerp of sign-aligned quaternions.

    Args:
        position: (2, 3) rows t=0, t=1.
        quaternion: (2, 4) rows t=0, t=1, [w, x, y, z].
        t: scalar or (m,) times.
    Returns:
        (position, unit quaternion): (3,), (4,) for scalar t, else (m, 3), (m, 4).
    """
    q0, q1 = quaternion[0], quaternion[1]
    if np.dot(q0, q1) < 0:
        q1 = -q1
    t = np.asarray(t, dtype=np.float64)[..., None]
    p = (1.0 - t) * position[0] + t * position[1]
    q = (1.0 - t) * q0 + t * q1
    q = q / np.linalg.norm(q, axis=-1, keepdims=True)
    return p, q


def fcl_linear_pose(position: np.ndarray, quaternion: np.ndarray, t: float):
    """The pose FCL's `CCDM_LINEAR` motion intends at time t (reference point at the origin).

    Translation is lerped; the rotation turns at constant rate about the axis of
    R1 R0^T, through an angle in [0, pi]. Returns (position (3,), unit quaternion (4,)).
    """
    q0 = quaternion[0] / np.linalg.norm(quaternion[0])
    q1 = quaternion[1] / np.linalg.norm(quaternion[1])
    if np.dot(q0, q1) < 0:
        q1 = -q1
    angle = math.acos(min(1.0, float(np.dot(q0, q1))))
    if angle < 1e-15:
        q = q0
    else:
        q = (math.sin((1 - t) * angle) * q0 + math.sin(t * angle) * q1) / math.sin(angle)
    p = (1.0 - t) * position[0] + t * position[1]
    return p, q / np.linalg.norm(q)


def _random_unit_quaternion(rng: np.random.Generator) -> np.ndarray:
    q = rng.normal(size=4)
    return q / np.linalg.norm(q)


def _turn(q: np.ndarray, axis: np.ndarray, angle: float) -> np.ndarray:
    """q followed by a world-frame rotation of `angle` about unit `axis`."""
    h = 0.5 * angle
    w1, v1 = math.cos(h), math.sin(h) * axis
    w0, v0 = q[0], q[1:]
    return np.concatenate([[w1 * w0 - v1 @ v0], w1 * v0 + w0 * v1 + np.cross(v1, v0)])


def random_rigid_queries(count: int, *, seed: int = 0, max_angle: float = 0.0,
                         radius_range: tuple[float, float] = (0.2, 1.0)) -> list[RigidQuery]:
    """Random pairs that start apart and sweep past each other; about half of them touch.

    Each body turns by an angle drawn from [0, max_angle] (radians) about a random axis.
    `max_angle=0` gives translation-only queries, on which python-fcl's motion and mjccd's
    coincide exactly; a small `max_angle` (say 0.1) keeps the two motions within about
    `max_angle**3 / 16` radians of each other.
    """
    rng = np.random.default_rng(seed)
    queries = []
    for k in range(count):
        ra = rng.uniform(*radius_range, size=3)
        rb = rng.uniform(*radius_range, size=3)
        reach = ra.max() + rb.max()
        u = rng.normal(size=3)
        u /= np.linalg.norm(u)
        side = rng.normal(size=3)
        side -= (side @ u) * u
        side /= np.linalg.norm(side)
        gap = rng.uniform(1.05, 2.0) * reach
        pa0 = rng.uniform(-1.0, 1.0, size=3)
        pb0 = pa0 + gap * u
        pa1 = pa0 + 0.5 * gap * u
        pb1 = pa0 - 0.5 * gap * u + rng.uniform(0.0, 1.2) * reach * side
        quats = []
        for _ in range(2):
            q0 = _random_unit_quaternion(rng)
            axis = rng.normal(size=3)
            axis /= np.linalg.norm(axis)
            q1 = _turn(q0, axis, rng.uniform(0.0, max_angle)) if max_angle > 0 else q0.copy()
            quats.append(np.array([q0, q1]))
        queries.append(RigidQuery(ra, [pa0, pa1], quats[0], rb, [pb0, pb1], quats[1],
                                  name=f"random-{seed}-{k}"))
    return queries


# ----------------------------------------------------------------------------- python-fcl


def fcl_available() -> bool:
    """True when python-fcl can be imported."""
    try:
        import fcl  # noqa: F401
    except ImportError:
        return False
    return True


@dataclasses.dataclass(frozen=True)
class FclSetup:
    """Everything `fcl.continuousCollide` needs, built once so that only the call is timed."""

    object_a: object
    end_a: object
    object_b: object
    end_b: object
    request: object
    motion: str


def make_fcl_objects(query: RigidQuery, n_samples: int, *, motion: str = "auto") -> FclSetup:
    """fcl collision objects at their t=0 poses, t=1 transforms and a naive-solver request.

    Args:
        query: the pair and its motion.
        n_samples: number of intervals; fcl evaluates n_samples + 1 poses t = k / n_samples.
        motion: "auto" (translation-only motion when no body rotates, else linear),
            "linear" or "translation".
    """
    import fcl

    if n_samples < 1:
        raise ValueError(f"`n_samples` must be at least 1, got {n_samples!r}")
    if motion == "auto":
        motion = "linear" if query.rotates else "translation"
    if motion == "linear":
        motion_type = fcl.CCDMotionType.CCDM_LINEAR
    elif motion == "translation":
        motion_type = fcl.CCDMotionType.CCDM_TRANS
    else:
        raise ValueError(f"`motion` must be 'auto', 'linear' or 'translation', got {motion!r}")

    def transform(position, quaternion):
        q = np.asarray(quaternion, dtype=np.float64)
        return fcl.Transform(q / np.linalg.norm(q), np.asarray(position, dtype=np.float64))

    object_a = fcl.CollisionObject(fcl.Ellipsoid(*map(float, query.radii_a)),
                                   transform(query.position_a[0], query.quaternion_a[0]))
    object_b = fcl.CollisionObject(fcl.Ellipsoid(*map(float, query.radii_b)),
                                   transform(query.position_b[0], query.quaternion_b[0]))
    request = fcl.ContinuousCollisionRequest(
        num_max_iterations=n_samples + 1,
        toc_err=0.5 / n_samples,
        ccd_motion_type=motion_type,
        ccd_solver_type=fcl.CCDSolverType.CCDC_NAIVE,
    )
    return FclSetup(object_a, transform(query.position_a[1], query.quaternion_a[1]),
                    object_b, transform(query.position_b[1], query.quaternion_b[1]),
                    request, motion)


def fcl_linear_motion_is_sane() -> bool:
    """Whether fcl's `CCDM_LINEAR` currently agrees with `CCDM_TRANS` on pure translations.

    fcl 0.7 builds its linear motion with an uninitialized reference point, so the answer
    depends on heap contents and can change within one process.
    """
    query = RigidQuery([0.5] * 3, [[-2.0, 0.1, 0.0], [2.0, 0.1, 0.0]], [[1.0, 0, 0, 0]] * 2,
                       [0.5] * 3, [[1.0, 0.0, 0.0], [1.0, 0.0, 0.0]], [[1.0, 0, 0, 0]] * 2)
    expected = fcl_first_contact(query, 100, motion="translation")
    return all(fcl_first_contact(query, 100, motion="linear") == expected for _ in range(3))


def fcl_continuous_collide(setup: FclSetup) -> float | None:
    """Run `fcl.continuousCollide` on a prepared pair; first colliding sample time or None."""
    import fcl

    result = fcl.ContinuousCollisionResult()
    fcl.continuousCollide(setup.object_a, setup.end_a, setup.object_b, setup.end_b,
                          setup.request, result)
    return float(result.time_of_contact) if result.is_collide else None


def fcl_call_times(setups: Sequence[FclSetup], repeats: int) -> list[float]:
    """Median wall time (µs) of each pair's bare `fcl.continuousCollide` call over `repeats` runs.

    Objects, end transforms, request and result are built beforehand, so only the call into
    FCL's C++ is timed: the fastest way python-fcl offers to ask the question. (A reused
    result only accumulates; the answers come from `fcl_continuous_collide`.)
    """
    import fcl

    call = fcl.continuousCollide
    times = []
    for setup in setups:
        args = (setup.object_a, setup.end_a, setup.object_b, setup.end_b, setup.request,
                fcl.ContinuousCollisionResult())
        call(*args)
        samples = []
        for _ in range(repeats):
            start = time.perf_counter()
            call(*args)
            samples.append(time.perf_counter() - start)
        times.append(1e6 * statistics.median(samples))
    return times


def fcl_first_contact(query: RigidQuery, n_samples: int, *, motion: str = "auto") -> float | None:
    """python-fcl naive CCD: the first of the times k / n_samples at which the pair collides."""
    return fcl_continuous_collide(make_fcl_objects(query, n_samples, motion=motion))


class FclSampledPair:
    """fcl discrete `collide` driven from Python along mjccd's own rigid motion.

    The control for the fcl rows: the same sample grid as `CCDC_NAIVE`, but on exactly
    mjccd's motion and without fcl's motion classes, at the price of a Python loop.
    """

    def __init__(self, query: RigidQuery):
        import fcl

        self._fcl = fcl
        self.query = query
        self.object_a = fcl.CollisionObject(fcl.Ellipsoid(*map(float, query.radii_a)))
        self.object_b = fcl.CollisionObject(fcl.Ellipsoid(*map(float, query.radii_b)))
        self.request = fcl.CollisionRequest()

    def first_contact(self, n_samples: int) -> tuple[float | None, int]:
        """First of the times k / n_samples at which the pair collides; (toi or None, calls)."""
        if n_samples < 1:
            raise ValueError(f"`n_samples` must be at least 1, got {n_samples!r}")
        fcl, q = self._fcl, self.query
        ts = np.arange(n_samples + 1) / n_samples
        pa, qa = rigid_pose(q.position_a, q.quaternion_a, ts)
        pb, qb = rigid_pose(q.position_b, q.quaternion_b, ts)
        a, b = self.object_a, self.object_b
        for k in range(n_samples + 1):
            a.setTranslation(pa[k])
            a.setQuatRotation(qa[k])
            b.setTranslation(pb[k])
            b.setQuatRotation(qb[k])
            if fcl.collide(a, b, self.request, fcl.CollisionResult()):
                return float(ts[k]), k + 1
        return None, n_samples + 1


# ----------------------------------------------------------------------------- MuJoCo

_MJCF = """<mujoco model="mjccd-peer-pair">
  <option ccd_tolerance="1e-12" ccd_iterations="200"/>
  <worldbody>
    <body name="a" mocap="true"><geom name="a" type="ellipsoid" size="{ra}"/></body>
    <body name="b" mocap="true"><geom name="b" type="ellipsoid" size="{rb}"/></body>
  </worldbody>
</mujoco>"""


class MujocoDistancePair:
    """A two-body MuJoCo model (mocap bodies, one ellipsoid geom each) for one query.

    Construction compiles the model (not timed); `first_contact` is the timed part. The
    GJK/EPA tolerance is tightened from MuJoCo's default 1e-6 so that the signed distance,
    on which the bisection runs, is accurate near zero.
    """

    def __init__(self, query: RigidQuery):
        import mujoco

        self._mujoco = mujoco
        self.query = query
        fmt = lambda r: " ".join(repr(float(x)) for x in r)  # noqa: E731
        self.model = mujoco.MjModel.from_xml_string(
            _MJCF.format(ra=fmt(query.radii_a), rb=fmt(query.radii_b)))
        self.data = mujoco.MjData(self.model)
        self.geom_a = mujoco.mj_name2id(self.model, mujoco.mjtObj.mjOBJ_GEOM, "a")
        self.geom_b = mujoco.mj_name2id(self.model, mujoco.mjtObj.mjOBJ_GEOM, "b")
        self.distmax = 4.0 * float(max(query.radii_a.max(), query.radii_b.max()))
        self._lerp = []
        for position, quaternion in ((query.position_a, query.quaternion_a),
                                     (query.position_b, query.quaternion_b)):
            q0, q1 = quaternion
            if np.dot(q0, q1) < 0:
                q1 = -q1
            self._lerp.append((position[0], position[1] - position[0], q0, q1 - q0))

    def distance(self, t: float) -> float:
        """Signed distance (negative when penetrating) at time t under mjccd's motion."""
        (pa, dpa, qa, dqa), (pb, dpb, qb, dqb) = self._lerp
        qat = qa + t * dqa
        qbt = qb + t * dqb
        return self._distance(pa + t * dpa, qat / math.sqrt(qat @ qat),
                              pb + t * dpb, qbt / math.sqrt(qbt @ qbt))

    def _distance(self, pa, qa, pb, qb) -> float:
        d = self.data
        d.mocap_pos[0] = pa
        d.mocap_quat[0] = qa
        d.mocap_pos[1] = pb
        d.mocap_quat[1] = qb
        self._mujoco.mj_kinematics(self.model, d)
        return self._mujoco.mj_geomDistance(self.model, d, self.geom_a, self.geom_b,
                                            self.distmax, None)

    def first_contact(self, n_samples: int, tol: float = 1e-9) -> tuple[float | None, int]:
        """Sample t = k / n_samples, then bisect the first sign change down to `tol` in t.

        Returns:
            (toi, calls): the earliest time found with distance <= 0 (None when no sample
            touches), and the number of `mj_geomDistance` calls made.
        """
        if n_samples < 1:
            raise ValueError(f"`n_samples` must be at least 1, got {n_samples!r}")
        q = self.query
        ts = np.arange(n_samples + 1) / n_samples
        pa, qa = rigid_pose(q.position_a, q.quaternion_a, ts)
        pb, qb = rigid_pose(q.position_b, q.quaternion_b, ts)
        calls = 0
        hit = -1
        for k in range(n_samples + 1):
            calls += 1
            if self._distance(pa[k], qa[k], pb[k], qb[k]) <= 0.0:
                hit = k
                break
        if hit < 0:
            return None, calls
        if hit == 0:
            return 0.0, calls
        lo, hi = ts[hit - 1], ts[hit]
        while hi - lo > tol:
            mid = 0.5 * (lo + hi)
            calls += 1
            if self.distance(mid) <= 0.0:
                hi = mid
            else:
                lo = mid
        return float(hi), calls


def mujoco_sampling_first_contact(query: RigidQuery, n_samples: int,
                                  tol: float = 1e-9) -> tuple[float | None, int]:
    """MuJoCo `mj_geomDistance` at n_samples + 1 uniform times plus bisection to `tol`.

    Returns (toi or None, number of distance calls).
    """
    return MujocoDistancePair(query).first_contact(n_samples, tol)


# ----------------------------------------------------------------------------- table


def _time_per_query(setups: Sequence, call: Callable, repeats: int) -> tuple[list, list]:
    """Answers of `call(setup)` and the median wall time of each over `repeats` runs (µs)."""
    answers, times = [], []
    for setup in setups:
        samples = []
        answer = None
        for _ in range(repeats):
            start = time.perf_counter()
            answer = call(setup)
            samples.append(time.perf_counter() - start)
        answers.append(answer)
        times.append(1e6 * statistics.median(samples))
    return answers, times


def score(answers: Sequence[float | None], reference_times: Sequence[float | None],
          dt_tolerance: float = DT_TOLERANCE) -> dict:
    """Count missed contacts, false contacts and times further than `dt_tolerance` away."""
    if len(answers) != len(reference_times):
        raise ValueError(f"got {len(answers)} answers for {len(reference_times)} references")
    missed = false = late = 0
    max_dt = 0.0
    for got, ref in zip(answers, reference_times):
        if ref is None and got is None:
            continue
        if got is None:
            missed += 1
        elif ref is None:
            false += 1
        else:
            dt = abs(got - ref)
            max_dt = max(max_dt, dt)
            late += dt > dt_tolerance
    return {"n_wrong": missed + false + int(late), "n_missed": missed, "n_false": false,
            "max_dt": max_dt}


def peer_table(queries: Sequence[RigidQuery], reference_times: Sequence[float | None],
               n_list: Sequence[int] = (100, 1000), *, repeats: int = 5,
               tol: float = 1e-9, fcl_motion: str = "auto") -> list[dict]:
    """Time the peers and count their wrong answers against `reference_times`.

    Setup (model compilation, fcl objects) is excluded from the timings; for python-fcl's
    naive solver only the `continuousCollide` call is timed (`fcl_call_times`). Each query
    is run `repeats` times; its time is the median of those runs; `median_us` and `mean_us`
    are taken over queries.

    Returns:
        One dict per peer and sample count with keys name, n_samples, median_us, mean_us,
        n_wrong, n_missed, n_false, max_dt, calls_mean (distance or collide calls per
        query) and note ("" or why the row has no numbers).
    """
    queries = list(queries)
    reference_times = list(reference_times)
    if len(queries) != len(reference_times):
        raise ValueError(f"got {len(reference_times)} reference times for {len(queries)} queries")
    rows = []
    have_fcl = fcl_available()
    rotating = sum(q.rotates for q in queries)
    for n in n_list:
        name = f"python-fcl naive, {n} steps"
        if not have_fcl:
            rows.append(_empty_row(name, n, FCL_SKIP_MESSAGE))
        else:
            setups = [make_fcl_objects(q, n, motion=fcl_motion) for q in queries]
            answers = [fcl_continuous_collide(setup) for setup in setups]
            times = fcl_call_times(setups, repeats)
            calls = [n + 1 if a is None else round(a * n) + 1 for a in answers]
            note = ""
            if rotating and fcl_motion != "translation":
                sane = "passed" if fcl_linear_motion_is_sane() else "FAILED"
                note = (f"{rotating} rotating queries on fcl's slerp motion, not mjccd's; "
                        f"fcl linear-motion self-check {sane}")
            rows.append(_row(name, n, answers, times, calls, reference_times, note))

        name = f"python-fcl collide on mjccd motion, {n} steps"
        if not have_fcl:
            rows.append(_empty_row(name, n, FCL_SKIP_MESSAGE))
        else:
            pairs = [FclSampledPair(q) for q in queries]
            results, times = _time_per_query(pairs, lambda p: p.first_contact(n), repeats)
            rows.append(_row(name, n, [r[0] for r in results], times,
                             [r[1] for r in results], reference_times, "Python loop"))

        name = f"MuJoCo mj_geomDistance, {n} samples + bisection"
        pairs = [MujocoDistancePair(q) for q in queries]
        results, times = _time_per_query(pairs, lambda p: p.first_contact(n, tol), repeats)
        answers = [r[0] for r in results]
        calls = [r[1] for r in results]
        rows.append(_row(name, n, answers, times, calls, reference_times, ""))
    return rows


def _row(name, n, answers, times, calls, reference_times, note) -> dict:
    row = {"name": name, "n_samples": n,
           "median_us": statistics.median(times), "mean_us": statistics.fmean(times)}
    row.update(score(answers, reference_times))
    row["calls_mean"] = statistics.fmean(calls)
    row["note"] = note
    return row


def _empty_row(name, n, note) -> dict:
    return {"name": name, "n_samples": n, "median_us": None, "mean_us": None,
            "n_wrong": None, "n_missed": None, "n_false": None, "max_dt": None,
            "calls_mean": None, "note": note}


def markdown_table(rows: Sequence[dict]) -> str:
    """The rows of `peer_table` as a markdown table."""
    def cell(value, fmt):
        return "–" if value is None else format(value, fmt)

    lines = ["| peer | median µs | mean µs | wrong | missed | false | max abs dt | calls | note |",
             "| --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: | --- |"]
    for r in rows:
        lines.append(
            f"| {r['name']} | {cell(r['median_us'], '.1f')} | {cell(r['mean_us'], '.1f')} | "
            f"{cell(r['n_wrong'], 'd')} | {cell(r['n_missed'], 'd')} | "
            f"{cell(r['n_false'], 'd')} | {cell(r['max_dt'], '.2e')} | "
            f"{cell(r['calls_mean'], '.1f')} | {r['note']} |")
    return "\n".join(lines)
