"""Flat elliptic disks moving in space (mjccd.geoms.spatial): analytic cases, the coplanar and parallel cases,
and an independent brute force on random rigid and articulated motions.

The brute force knows nothing of the chords the solver works with: at each time it takes the separation of
the two disks as the largest gap between their support functions over all directions (max over unit n of
min_B n.x - max_A n.x; a disk's support is n.c + sqrt((n.a e1)^2 + (n.b e2)^2)), positive exactly when they
are apart, from the motions' own poses (``Motion.transform``), and finds the first time it reaches zero.
"""
import numpy as np
import pytest
from scipy.optimize import minimize

import mjccd
from mjccd.errors import InputError, MjccdError
from mjccd.geoms.spatial import Disk, disk_first_contact

IDENTITY = [1.0, 0.0, 0.0, 0.0]


def about_x(angle):
    return [np.cos(angle / 2), np.sin(angle / 2), 0.0, 0.0]


UPRIGHT = about_x(np.pi / 2)  # the disk's plane turned into the world's xz plane (its local y along world z)
A, B = Disk(2.0, 1.0), Disk(1.0, 0.5)
REST = mjccd.Static([0.0, 0.0, 0.0], IDENTITY)


def test_upright_disk_dropped_on_a_flat_one():
    """B's lowest point (0.5 below its centre) reaches A's plane when its centre is at z = 0.5: t = 5/8."""
    c = disk_first_contact(A, REST, B, mjccd.Rigid([0.5, 0, 3], UPRIGHT, [0.5, 0, -1], UPRIGHT))
    assert c.certainty == "certified" and abs(c.time - 0.625) < 1e-9
    np.testing.assert_allclose(c.point, [0.5, 0.0, 0.0], atol=1e-7)
    np.testing.assert_allclose(c.normal, [0.0, 0.0, 1.0], atol=1e-7)  # A's face, turned towards B


def test_rim_against_rim():
    """B upright at height 0.3 cuts A's plane at x_c +- 0.8; it meets A's rim (x = 2) when x_c = 2.8: t = 0.4."""
    c = disk_first_contact(A, REST, B, mjccd.Rigid([4, 0, 0.3], UPRIGHT, [1, 0, 0.3], UPRIGHT))
    assert c.certainty == "certified" and abs(c.time - 0.4) < 1e-9
    np.testing.assert_allclose(c.point, [2.0, 0.0, 0.0], atol=1e-7)
    assert abs(c.normal[1]) < 1e-9 and c.normal[0] > 0  # perpendicular to A's rim tangent (y), towards B


def test_coplanar_throughout_goes_to_the_planar_solver():
    c = disk_first_contact(A, REST, B, mjccd.Rigid([5, 0, 0], IDENTITY, [-5, 0, 0], IDENTITY))
    assert c.certainty == "certified" and abs(c.time - 0.2) < 1e-9
    np.testing.assert_allclose(c.point, [2.0, 0.0, 0.0], atol=1e-7)
    np.testing.assert_allclose(c.normal, [1.0, 0.0, 0.0], atol=1e-7)
    tilted = about_x(0.7)  # the same in a tilted common plane, far from the origin: still exactly coplanar
    far = np.array([1e5, 2e5, -3e5])
    R = np.array([[1, 0, 0], [0, np.cos(0.7), -np.sin(0.7)], [0, np.sin(0.7), np.cos(0.7)]])
    c = disk_first_contact(A, mjccd.Static(far, tilted), B, mjccd.Rigid(far + R @ [5, 0, 0], tilted,
                                                                          far + R @ [-5, 0, 0], tilted))
    assert c.certainty == "certified" and abs(c.time - 0.2) < 1e-9
    np.testing.assert_allclose(c.point - far, [2.0, 0.0, 0.0], atol=1e-6)
    # off the x axis, R's rounding moves B's path off A's plane (the planes stay parallel: one quaternion):
    # by about 1e-11 far from the origin, where that is proven and the disks never meet; by about 1e-16 at
    # the origin, where nothing decides whether they cross, and the answer says so
    for origin in (far, np.zeros(3)):
        for y, crossing in ((0.3, True), (3.0, False)):
            path = (origin + R @ [5, y, 0], tilted, origin + R @ [-5, y, 0], tilted)
            c = disk_first_contact(A, mjccd.Static(origin, tilted), B, mjccd.Rigid(*path))
            assert c is None or (crossing and c.certainty == "uncertain" and c.bracket[0] <= 0.2 <= c.bracket[1])


def test_parallel_planes():
    assert disk_first_contact(A, REST, B, mjccd.Rigid([5, 0, 1], IDENTITY, [-5, 0, 1], IDENTITY)) is None
    # passing through A's plane at t = 1/2 (decided exactly): far from A, or across it from below
    assert disk_first_contact(A, REST, B, mjccd.Rigid([5, 0, -1], IDENTITY, [5, 0, 1], IDENTITY)) is None
    c = disk_first_contact(A, REST, B, mjccd.Rigid([0.5, 0.2, -1], IDENTITY, [0.5, 0.2, 1], IDENTITY))
    assert c.certainty == "certified" and c.time == 0.5
    np.testing.assert_allclose(c.normal, [0.0, 0.0, -1.0])
    assert abs(c.point[2]) < 1e-12 and (c.point[0] / 2) ** 2 + c.point[1] ** 2 <= 1.0


def test_start_statuses():
    assert disk_first_contact(A, REST, B, mjccd.Static([0.5, 0, 0.2], UPRIGHT)).status_at_start == "overlapping"
    c = disk_first_contact(A, REST, B, mjccd.Rigid([1, 0, 0], IDENTITY, [0, 0, 3], about_x(1.0)))
    assert c.status_at_start == "overlapping"  # coplanar at the start: the planar solver's status
    c = disk_first_contact(A, REST, B, mjccd.Rigid([0.5, 0, 0.5], UPRIGHT, [0.5, 0, 2], UPRIGHT))
    assert c.status_at_start == "touching" and c.time == 0.0


def test_translation_invariance():
    far = np.array([1e6, -2e6, 3e6])
    c0 = disk_first_contact(A, REST, B, mjccd.Rigid([0.5, 0, 3], UPRIGHT, [0.5, 0, -1], UPRIGHT))
    c1 = disk_first_contact(A, mjccd.Static(far, IDENTITY), B,
                            mjccd.Rigid(far + [0.5, 0, 3], UPRIGHT, far + [0.5, 0, -1], UPRIGHT))
    assert abs(c0.time - c1.time) < 1e-9
    np.testing.assert_allclose(c1.point - far, c0.point, atol=1e-6)


def test_refusals():
    with pytest.raises(InputError, match="a: a semi-axis"):
        Disk(-1.0, 1.0)
    with pytest.raises(MjccdError, match="disk_b"):
        disk_first_contact(A, REST, "disk", REST)
    with pytest.raises(MjccdError, match="motion_b"):
        disk_first_contact(A, REST, B, "still")


# ---------------------------------------------------------------- the brute force


def _fibonacci(n):
    i = np.arange(n) + 0.5
    phi = np.arccos(1.0 - 2.0 * i / n)
    th = np.pi * (1.0 + 5.0 ** 0.5) * i
    return np.stack([np.cos(th) * np.sin(phi), np.sin(th) * np.sin(phi), np.cos(phi)], axis=1)


DIRS = _fibonacci(4000)


def _disk(motion, disk, t):
    T = motion.transform(t)
    return T[:, 3], T[:, 0] * disk.a, T[:, 1] * disk.b


def _gap(n, da, db):
    (ca, ua, wa), (cb, ub, wb) = da, db
    return -(n @ cb) - np.hypot(n @ ub, n @ wb) - (n @ ca) - np.hypot(n @ ua, n @ wa)


def _gap_ab(n, da, db):
    (ca, ua, wa), (cb, ub, wb) = da, db
    return (n @ cb - np.hypot(n @ ub, n @ wb)) - (n @ ca + np.hypot(n @ ua, n @ wa))


def separation(da, db):
    """max over unit n of the gap (the distance when positive; <= 0 when the disks meet)."""
    v = _gap_ab(DIRS, da, db)
    k = int(np.argmax(v))
    f = lambda x: -_gap_ab(x / np.linalg.norm(x), da, db)  # noqa: E731
    r = minimize(f, DIRS[k], method="Nelder-Mead", options={"xatol": 1e-12, "fatol": 1e-14, "maxiter": 3000})
    return max(float(v[k]), -float(r.fun))


def brute_first_contact(ma, da, mb, db, n=400):
    """The first time the separation reaches 0: sampled directions at n + 1 times (a lower bound of the
    separation), refined where that comes near 0, then bisection."""
    ts = np.linspace(0.0, 1.0, n + 1)
    parts = [(_disk(ma, da, t), _disk(mb, db, t)) for t in ts]
    coarse = np.array([_gap_ab(DIRS, p, q).max() for p, q in parts])
    sep = lambda t: separation(_disk(ma, da, t), _disk(mb, db, t))  # noqa: E731
    first = next((int(k) for k in np.nonzero(coarse <= 0.05)[0] if sep(ts[k]) <= 0.0), None)
    if first is None:
        return None, float(coarse.min())
    if first == 0:
        return 0.0, float(coarse.min())
    a, b = ts[first - 1], ts[first]
    for _ in range(45):
        m = 0.5 * (a + b)
        a, b = (m, b) if sep(m) > 0.0 else (a, m)
    return b, float(coarse.min())


def _q(rng):
    x = rng.normal(size=4)
    return x / np.linalg.norm(x)


def random_case(rng, kind):
    da = Disk(*rng.uniform(0.4, 2.0, 2))
    db = Disk(*rng.uniform(0.4, 2.0, 2))
    pa0, pa1 = rng.normal(0.0, 1.5, 3), rng.normal(0.0, 1.5, 3)
    ma = mjccd.Static(pa0, _q(rng)) if kind == "static" else mjccd.Rigid(pa0, _q(rng), pa1, _q(rng))
    # B's centre passes A's at a random time, within about the sum of the sizes
    t = rng.uniform(0.25, 0.8)
    ca = pa0 if kind == "static" else (1 - t) * pa0 + t * pa1
    d = rng.normal(size=3)
    target = ca + rng.uniform(0.3, 1.2) * (max(da.a, da.b) + max(db.a, db.b)) * d / np.linalg.norm(d)
    v = rng.normal(0.0, 3.0, 3)
    pb0 = target - t * v
    if kind == "chain":
        mb = mjccd.Chain([mjccd.Free(pb0, _q(rng), pb0 + v, _q(rng)), mjccd.Hinge(rng.normal(size=3), -0.8, 1.2)])
    else:
        mb = mjccd.Rigid(pb0, _q(rng), pb0 + v, _q(rng))
    return da, ma, db, mb


@pytest.mark.parametrize("seed", range(12))
def test_random_against_brute_force(seed):
    rng = np.random.default_rng(400 + seed)
    da, ma, db, mb = random_case(rng, ("static", "rigid", "chain")[seed % 3])
    c = disk_first_contact(da, ma, db, mb)
    tb, smin = brute_first_contact(ma, da, mb, db)
    if c is None:
        assert tb is None and smin > -0.05
        return
    if c.status_at_start != "separate":
        assert tb == 0.0
        return
    if c.certainty != "certified":
        assert tb is None or c.bracket[0] - 1e-9 <= tb
        return
    assert tb is not None and abs(tb - c.time) < 1e-7
    assert abs(separation(_disk(ma, da, c.time), _disk(mb, db, c.time))) < 1e-8
    # the point lies on both disks: in each plane, and inside each ellipse
    for m, d in ((ma, da), (mb, db)):
        T = m.transform(c.time)
        y = T[:, :3].T @ (c.point - T[:, 3])
        assert abs(y[2]) < 1e-7 and (y[0] / d.a) ** 2 + (y[1] / d.b) ** 2 <= 1.0 + 1e-7


def test_random_cases_reach_contacts():
    found = set()
    for seed in range(12):
        rng = np.random.default_rng(400 + seed)
        c = disk_first_contact(*random_case(rng, ("static", "rigid", "chain")[seed % 3]))
        found.add("free" if c is None else c.status_at_start + ("" if c.certainty == "certified" else "?"))
    assert "separate" in found
