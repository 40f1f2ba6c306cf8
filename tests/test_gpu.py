"""The GPU path (mjccd.gpu) against the CPU kernels, in numba-cuda's CUDA simulator and, where there is one, on a GPU.

The GPU checks run in a subprocess of this file (``python tests/test_gpu.py sim|device``): the
simulator is chosen by ``NUMBA_ENABLE_CUDASIM=1`` before numba loads, which must not leak into the
other tests of the pytest process.  The subprocess prints one JSON line of findings; the tests below
assert on it.  Cases (2 ellipsoids per world, one pair): random motions, far apart, overlapping at
t = 0, passing close without touching, grazes built to miss or touch by 1e-9 (translating, and
rotating with the threshold found by the CPU solver), and pairs 1e-9 apart at t = 0; then worlds of 5
ellipsoids (10 pairs) over two frames (the plane cache) against :class:`mjccd.scene.Scene`, and
:func:`mjccd.gpu.poses_from_bodies` against numpy.
"""
import json
import os
import subprocess
import sys

import numpy as np
import pytest

TIME_MATCH = 1e-12   # GPU and CPU first contacts agree to this, or the GPU flags the pair uncertain
N_CASES = {"random": 80, "far": 25, "overlap_t0": 25, "near_miss": 25, "graze_translate": 24,
           "graze_rotate": 16, "touch_t0": 10}
GROUP = 8            # worlds per batch (one radii pair each)


# ---------------------------------------------------------------- cases (run inside the subprocess)


def _quat(rng):
    q = rng.normal(size=4)
    return q / np.linalg.norm(q)


def _qmul(a, b):
    w1, v1, w2, v2 = a[0], a[1:], b[0], b[1:]
    return np.concatenate([[w1 * w2 - v1 @ v2], w1 * v2 + w2 * v1 + np.cross(v1, v2)])


def _turn(q, rng, angle):
    """q turned by ``angle`` about a random axis."""
    axis = rng.normal(size=3)
    axis /= np.linalg.norm(axis)
    return _qmul(np.concatenate([[np.cos(angle / 2)], np.sin(angle / 2) * axis]), q)


def _rot(q):
    w, x, y, z = q
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
                     [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
                     [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]])


def _radii(rng):
    r = rng.uniform(0.2, 1.0, 3)
    if rng.random() < 0.2:  # a thin body: the solver works in A's frame
        r[rng.integers(3)] *= 0.08
    return r


def _touching_offset(ra, qa, rb, qb, n):
    """Offset of B's centre from A's at which the two (fixed orientations) touch with unit normal n (from A)."""
    sa = _rot(qa) @ np.diag(ra ** 2) @ _rot(qa).T
    sb = _rot(qb) @ np.diag(rb ** 2) @ _rot(qb).T
    return sa @ n / np.sqrt(n @ sa @ n) + sb @ n / np.sqrt(n @ sb @ n)


def _tangent(n, rng):
    v = np.cross(n, rng.normal(size=3))
    return v / np.linalg.norm(v)


def _pose(p, q):
    return np.concatenate([p, q])


def _case(kind, rng, ra, rb):
    """(poses_t0 (2, 7), poses_t1 (2, 7)) of one case of ellipsoids with radii ra and rb."""
    qa0, qb0 = _quat(rng), _quat(rng)
    size = ra.max() + rb.max()
    pa0 = rng.uniform(-1, 1, 3)
    if kind in ("random", "far", "overlap_t0"):
        d = rng.normal(size=3)
        d /= np.linalg.norm(d)
        if kind == "random":
            pb0 = pa0 + d * size * rng.uniform(0.6, 2.0)
            pa1 = pa0 + rng.normal(size=3) * 0.2 * size
            pb1 = pb0 + (pa0 - pb0) * rng.uniform(0.0, 1.5) + rng.normal(size=3) * 0.2 * size
            qa1, qb1 = _turn(qa0, rng, rng.uniform(0, 1.5)), _turn(qb0, rng, rng.uniform(0, 1.5))
        elif kind == "far":
            pb0 = pa0 + d * size * 4.0
            pa1, pb1 = pa0 + rng.normal(size=3) * 0.3 * size, pb0 + rng.normal(size=3) * 0.3 * size
            qa1, qb1 = _turn(qa0, rng, 1.0), _turn(qb0, rng, 1.0)
        else:
            pb0 = pa0 + d * rng.uniform(0, 0.2) * min(ra.min(), rb.min())
            pa1, pb1 = pa0 + rng.normal(size=3) * size, pb0 + rng.normal(size=3) * size
            qa1, qb1 = _turn(qa0, rng, 0.5), _turn(qb0, rng, 0.5)
        return np.array([_pose(pa0, qa0), _pose(pb0, qb0)]), np.array([_pose(pa1, qa1), _pose(pb1, qb1)])
    # B slides past A along a tangent of the set of its touching offsets (normal n), ``gap`` off it
    n = rng.normal(size=3)
    n /= np.linalg.norm(n)
    x = _touching_offset(ra, qa0, rb, qb0, n)
    v = _tangent(n, rng) * 2.0 * size
    qa1, qb1 = qa0, qb0

    def poses(gap):
        return (np.array([_pose(pa0, qa0), _pose(pa0 + x + gap * n - 0.5 * v, qb0)]),
                np.array([_pose(pa0, qa1), _pose(pa0 + x + gap * n + 0.5 * v, qb1)]))
    if kind == "near_miss":  # a clear gap while the bounding spheres overlap
        qa1, qb1 = _turn(qa0, rng, 0.02), _turn(qb0, rng, 0.02)
        return poses(0.05 * size)
    if kind == "graze_translate":  # both keep their orientation: a miss or a touch by 1e-9
        return poses(rng.choice([-1e-9, 1e-9]))
    if kind == "touch_t0":  # 1e-9 apart or into each other at t = 0, then sliding along or moving away
        gap = rng.choice([-1e-9, 1e-9])
        pb0 = pa0 + x + gap * n
        pb1 = pb0 + (v if rng.random() < 0.5 else n * size)
        return np.array([_pose(pa0, qa0), _pose(pb0, qb0)]), np.array([_pose(pa0, qa1), _pose(pb1, qb1)])
    if kind != "graze_rotate":
        raise ValueError(kind)
    # A turns as B slides by: the gap at which a first contact appears, by bisection on the CPU kernel, +-1e-9
    qa1 = _turn(qa0, rng, 0.3)
    radii = np.array([ra, rb])
    lo, hi = -0.2 * size, 0.2 * size  # a contact at lo, none at hi
    if not _cpu_touches(radii, *poses(lo)) or _cpu_touches(radii, *poses(hi)):
        return _case(kind, rng, ra, rb)
    for _ in range(48):
        mid = 0.5 * (lo + hi)
        if _cpu_touches(radii, *poses(mid)):
            lo = mid
        else:
            hi = mid
    return poses(hi + rng.choice([-1e-9, 1e-9]))


def _cpu_touches(radii, poses_t0, poses_t1):
    """Whether the CPU kernel (mjccd.ccd.exact_pair) finds or suspects a contact of the pair (0, 1)."""
    from mjccd.ccd import exact_pair

    q0 = poses_t0[:, 3:] / np.linalg.norm(poses_t0[:, 3:], axis=1, keepdims=True)
    q1 = poses_t1[:, 3:] / np.linalg.norm(poses_t1[:, 3:], axis=1, keepdims=True)
    q1 *= np.where((q0 * q1).sum(axis=1) < 0, -1.0, 1.0)[:, None]
    p0, p1 = np.ascontiguousarray(poses_t0[:, :3]), np.ascontiguousarray(poses_t1[:, :3])
    _, intervals, _, _, certified, _, _ = exact_pair(False, radii[0], p0[0], q0[0], p1[0], q1[0],
                                                     radii[1], p0[1], q0[1], p1[1], q1[1], 1.0, True)
    return len(intervals) > 0 or not certified


def _cpu_first_contact(radii, poses_t0, poses_t1):
    """mjccd.first_contact of the pair (0, 1) moving rigidly between the two poses."""
    import mjccd

    return mjccd.first_contact(
        mjccd.Ellipsoid(radii[0]), mjccd.Rigid(poses_t0[0, :3], poses_t0[0, 3:], poses_t1[0, :3], poses_t1[0, 3:]),
        mjccd.Ellipsoid(radii[1]), mjccd.Rigid(poses_t0[1, :3], poses_t0[1, 3:], poses_t1[1, :3], poses_t1[1, 3:]))


def _groups(rng):
    """(kind, radii (2, 3), poses_t0 (W, 2, 7), poses_t1 (W, 2, 7)): the cases in batches of GROUP worlds."""
    out = []
    for kind, count in N_CASES.items():
        for start in range(0, count, GROUP):
            radii = np.array([_radii(rng), _radii(rng)])
            cases = [_case(kind, rng, *radii) for _ in range(min(GROUP, count - start))]
            out.append((kind, radii, np.array([c[0] for c in cases]), np.array([c[1] for c in cases])))
    return out


def check_pairs(gpu):
    """Batches of worlds of two ellipsoids: the device's answer for the pair against the CPU kernel
    (mjccd.ccd.exact_pair on the same split poses) and the public solver (mjccd.first_contact), and the
    world answers after the CPU re-solve of flagged pairs against the public solver."""
    from mjccd.ccd import exact_pair
    from mjccd.scene import CACHED_PLANE, EXACT_FREE, EXACT_HIT, NEW_PLANE, OVERLAP_T0, SPHERE, UNCERTAIN

    mismatches, flagged, filtered, counts = [], {}, {}, {}
    max_dt = 0.0
    resolved = 0
    for kind, radii, t0, t1 in _groups(np.random.default_rng(20260611)):
        scene = gpu.GpuScene(radii, len(t0))
        contacts = scene.first_contacts(t0, t1).copy_to_host()
        answers = scene.pair_answers.copy_to_host()
        p0, q0 = scene._p0.copy_to_host(), scene._q0.copy_to_host()
        p1, q1 = scene._p1.copy_to_host(), scene._q1.copy_to_host()
        resolved += int(contacts.resolved.sum())
        for w in range(len(t0)):
            counts[kind] = counts.get(kind, 0) + 1
            code, t, t_hi = int(answers.outcome[w, 0]), float(answers.time[w, 0]), float(answers.time_hi[w, 0])
            ref = _cpu_first_contact(radii, t0[w], t1[w])
            ref_t = -1.0 if ref is None else ref.time
            where = f"{kind} case {counts[kind] - 1}"
            # the world's answer, after the CPU re-solve, is the public solver's
            got = float(contacts.time[w])
            if ref is not None and ref.certainty != "certified":
                if contacts.status[w] != gpu.POSSIBLE_CONTACT or not (got <= ref.bracket[1]
                                                                      and ref.bracket[0] <= contacts.time_hi[w]):
                    mismatches.append(f"{where}: world answer {got} (status {contacts.status[w]}) vs uncertain "
                                      f"first_contact {ref.bracket}")
            elif (ref_t < 0) != (got < 0) or abs(ref_t - got) > TIME_MATCH:
                mismatches.append(f"{where}: world answer {got} (status {contacts.status[w]}, resolved "
                                  f"{contacts.resolved[w]}) vs first_contact {ref_t}")
            if code in (SPHERE, NEW_PLANE, CACHED_PLANE):
                filtered[kind] = filtered.get(kind, 0) + 1
                if ref is not None:
                    mismatches.append(f"{where}: cleared by filter {code}, first_contact {ref_t}")
                continue
            status0, intervals, point, normal, certified, lo, hi = exact_pair(
                False, radii[0], p0[w, 0], q0[w, 0], p1[w, 0], q1[w, 0], radii[1], p0[w, 1], q0[w, 1],
                p1[w, 1], q1[w, 1], 1.0, True)
            if code == UNCERTAIN:
                flagged[kind] = flagged.get(kind, 0) + 1
                if ref is not None and ref.certainty == "certified" and not t - 1e-15 <= ref_t <= t_hi + 1e-15:
                    mismatches.append(f"{where}: flagged with bracket [{t}, {t_hi}] without first_contact {ref_t}")
                if status0 == 1 and certified:
                    mismatches.append(f"{where}: flagged where the CPU kernel is certified")
                continue
            # certified on the device: the CPU kernel and the public solver say the same
            if not certified or status0 == 0:
                mismatches.append(f"{where}: device certified (outcome {code}) where the CPU kernel is not")
                continue
            cpu_t = -1.0 if len(intervals) == 0 else (0.0 if status0 != 1 else float(intervals[0, 0]))
            want = {EXACT_HIT: status0 == 1 and cpu_t >= 0, OVERLAP_T0: status0 == -1, EXACT_FREE: cpu_t < 0}[code]
            if not want:
                mismatches.append(f"{where}: outcome {code} at {t} where the CPU kernel has {status0}, {cpu_t}")
                continue
            if ref is not None and ref.certainty != "certified":
                mismatches.append(f"{where}: device certified, public solver uncertain")
            for other in (cpu_t, ref_t):
                if (other < 0) != (t < 0) or abs(other - t) > TIME_MATCH:
                    mismatches.append(f"{where}: device {t!r} vs CPU {other!r}")
            if t >= 0:
                max_dt = max(max_dt, abs(cpu_t - t), abs(ref_t - t))
            if code == EXACT_HIT and (np.abs(answers.point[w, 0] - point).max() > 1e-9 * radii.max()
                                      or np.abs(answers.normal[w, 0] - normal).max() > 1e-9):
                mismatches.append(f"{where}: point/normal {answers.point[w, 0]}, {answers.normal[w, 0]} "
                                  f"vs CPU {point}, {normal}")
    return {"pairs": sum(counts.values()), "counts": counts, "flagged": flagged, "filtered": filtered,
            "resolved_worlds": resolved, "max_dt": max_dt, "mismatches": mismatches[:20],
            "n_mismatches": len(mismatches)}


def check_worlds(gpu):
    """Worlds of 5 ellipsoids (10 pairs) over two frames against one CPU Scene per world (plane cache on)."""
    from mjccd.scene import CACHED_PLANE, Scene

    rng = np.random.default_rng(7)
    W, N, frames = 6, 5, 3
    radii = rng.uniform(0.15, 0.45, (N, 3))
    poses = np.empty((frames + 1, W, N, 7))
    for w in range(W):
        pos = rng.uniform(-0.6, 0.6, (N, 3))
        vel = rng.normal(size=(N, 3)) * 0.15
        q = np.array([_quat(rng) for _ in range(N)])
        for f in range(frames + 1):
            poses[f, w, :, :3], poses[f, w, :, 3:] = pos, q
            pos = pos + vel
            q = np.array([_turn(qq, rng, 0.05) for qq in q])
    scene = gpu.GpuScene(radii, W)
    cpu = [Scene(radii) for _ in range(W)]
    mismatches, cached = [], 0
    for f in range(frames):
        got = scene.first_contacts(poses[f], poses[f + 1]).copy_to_host()
        cached += int((scene.pair_answers.outcome.copy_to_host() == CACHED_PLANE).sum())
        for w in range(W):
            ref = cpu[w].first_contact(poses[f, w], poses[f + 1, w])
            if ref is None:
                if got.pair[w] != -1:
                    mismatches.append(f"frame {f} world {w}: {got.pair[w]} at {got.time[w]}, CPU none")
                continue
            uncertain = ref.bracket is not None or got.status[w] != gpu.CONTACT
            same_time = abs(got.time[w] - ref.time) <= TIME_MATCH
            if not uncertain and not (same_time and (got.pair[w] == ref.pair or ref.time == got.time[w])):
                mismatches.append(f"frame {f} world {w}: pair {got.pair[w]} at {got.time[w]!r}, "
                                  f"CPU pair {ref.pair} at {ref.time!r}")
            if not uncertain and ref.point is not None and np.abs(got.point[w] - ref.point).max() > 1e-9:
                mismatches.append(f"frame {f} world {w}: point {got.point[w]} vs CPU {ref.point}")
    return {"worlds": W, "frames": frames, "cached_plane_pairs": cached, "mismatches": mismatches}


def check_poses_from_bodies(gpu):
    """poses_from_bodies against numpy, float64 and float32 (MuJoCo Warp's) body poses."""
    rng = np.random.default_rng(3)
    W, nbody, N = 4, 5, 7
    xpos = rng.normal(size=(W, nbody, 3))
    xquat = rng.normal(size=(W, nbody, 4))
    xquat /= np.linalg.norm(xquat, axis=2, keepdims=True)
    body = rng.integers(0, nbody, N)
    local_pos = rng.normal(size=(N, 3)) * 0.1
    local_quat = np.array([_quat(rng) for _ in range(N)])
    errors = {}
    for dtype in (np.float64, np.float32):
        xp, xq = xpos.astype(dtype), xquat.astype(dtype)
        got = gpu.poses_from_bodies(xp, xq, body, local_pos, local_quat).copy_to_host()
        want = np.empty((W, N, 7))
        for w in range(W):
            for e in range(N):
                qb = xq[w, body[e]].astype(np.float64)
                qb /= np.linalg.norm(qb)  # the kernel's rotation is that of the normalised quaternion
                want[w, e, :3] = xp[w, body[e]].astype(np.float64) + _rot(qb) @ local_pos[e]
                want[w, e, 3:] = _qmul(xq[w, body[e]].astype(np.float64), local_quat[e])
        errors[np.dtype(dtype).name] = float(np.abs(got - want).max())
    return {"max_error": errors}


def main(mode):
    """Run the checks under the simulator (``sim``) or on the GPU (``device``) and print one JSON line."""
    try:
        import mjccd.gpu as gpu
    except ImportError as error:
        print(json.dumps({"skip": str(error)}))
        return
    out = {"mode": mode, "pairs": check_pairs(gpu), "worlds": check_worlds(gpu),
           "bodies": check_poses_from_bodies(gpu)}
    print(json.dumps(out))


# ---------------------------------------------------------------- tests (the pytest process)


def _run(mode, timeout):
    env = dict(os.environ)
    env.pop("NUMBA_ENABLE_CUDASIM", None)
    if mode == "sim":
        env["NUMBA_ENABLE_CUDASIM"] = "1"
    proc = subprocess.run([sys.executable, os.path.abspath(__file__), mode], env=env, capture_output=True,
                          text=True, timeout=timeout)
    assert proc.returncode == 0, proc.stderr[-4000:]
    return json.loads(proc.stdout.strip().splitlines()[-1])


@pytest.fixture(scope="module")
def simulator():
    return _run("sim", 900)


@pytest.fixture(scope="module")
def device():
    found = _run("device", 900)
    if "skip" in found:
        pytest.skip(f"no GPU: {found['skip']}")
    return found


def _assert_pairs(found):
    p = found["pairs"]
    print(f"\n{found['mode']}: {p['pairs']} pairs, flagged uncertain {sum(p['flagged'].values())} "
          f"({p['flagged']}), cleared by filters {p['filtered']}, resolved on the CPU {p['resolved_worlds']}, "
          f"largest |dt| of certified contacts {p['max_dt']:.2e}")
    assert p["pairs"] >= 200
    assert p["counts"] == N_CASES
    assert p["n_mismatches"] == 0, p["mismatches"]
    assert p["max_dt"] <= TIME_MATCH


def _assert_worlds(found):
    w = found["worlds"]
    assert w["mismatches"] == []
    assert w["cached_plane_pairs"] > 0  # the second and third frames reuse planes
    assert max(found["bodies"]["max_error"].values()) < 1e-12


def test_simulator_pairs_match_cpu(simulator):
    _assert_pairs(simulator)


def test_simulator_worlds_match_scene(simulator):
    _assert_worlds(simulator)


def test_device_pairs_match_cpu(device):
    _assert_pairs(device)


def test_device_worlds_match_scene(device):
    _assert_worlds(device)


def _import_gpu(env_extra, prelude):
    env = dict(os.environ)
    env.pop("NUMBA_ENABLE_CUDASIM", None)
    env.update(env_extra)
    code = prelude + "\ntry:\n    import mjccd.gpu\nexcept ImportError as e:\n" \
        "    print(type(e).__name__ + ': ' + str(e))\nelse:\n    print('imported')\n"
    proc = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr[-2000:]
    return proc.stdout.strip().splitlines()[-1]


def test_import_error_names_numba_cuda():
    # numba-cuda hidden: the import fails with the package to install
    out = _import_gpu({}, "import sys\nsys.modules['numba_cuda'] = None")
    assert out.startswith("GpuUnavailableError: mjccd.gpu needs the numba-cuda package")
    assert "pip install mjccd[gpu]" in out and "NUMBA_ENABLE_CUDASIM=1" in out


def test_import_error_without_device():
    out = _import_gpu({}, "")
    if out == "imported":
        pytest.skip("a CUDA device is present")
    assert out.startswith("GpuUnavailableError: mjccd.gpu found no usable CUDA device")
    assert "CUDA driver" in out and "NUMBA_ENABLE_CUDASIM=1" in out and "pip install mjccd[gpu]" in out


def test_simulator_imports():
    assert _import_gpu({"NUMBA_ENABLE_CUDASIM": "1"}, "") == "imported"


def test_core_does_not_import_gpu():
    # every other module of mjccd that imports here: none of them loads mjccd.gpu
    code = ("import importlib, pathlib, sys, mjccd\n"
            "root = pathlib.Path(mjccd.__file__).parent\n"
            "for path in sorted(root.rglob('*.py')):\n"
            "    parts = path.relative_to(root).with_suffix('').parts\n"
            "    if parts[0] in ('gpu', '__main__') or parts[-1] == '__init__' and len(parts) > 1:\n"
            "        continue\n"
            "    try:\n        importlib.import_module('.'.join(('mjccd',) + parts))\n"
            "    except ImportError:\n        pass\n"
            "print(sorted(n for n in sys.modules if n.startswith('mjccd.gpu')))")
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert proc.stdout.strip().splitlines()[-1] == "[]"


if __name__ == "__main__":
    main(sys.argv[1])
