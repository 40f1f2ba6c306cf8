"""Moving-sphere filter and separating-plane witness: conservative for every motion model, exact in t."""
import numpy as np
import pytest

import mjccd
from mjccd import filters as fl
from mjccd.quadric import quat_to_matrix

rng = np.random.default_rng(5)
ID = np.array([1.0, 0.0, 0.0, 0.0])


def unit(q):
    q = np.asarray(q, float)
    return q / np.linalg.norm(q)


def rand_quat():
    return unit(rng.normal(size=4))


def aligned(q0, q1):
    return q1 if q0 @ q1 >= 0 else -q1


def supports(affine, radii, q0, q1):
    """Inverse shape polynomials of one ellipsoid as arrays of one: T (1, 3, 3, 5) affine, factor U (1, 3, 3, 3) rigid."""
    den = np.empty((1, 5))
    args = (np.asarray(radii, float)[None], np.asarray(q0, float)[None], np.asarray(q1, float)[None])
    if affine:
        S = np.empty((1, 3, 3, 5))
        fl.support_affine(*args, S, den, 0, np.empty((8, 3, 3)))
    else:
        S = np.empty((1, 3, 3, 3))
        fl.support_rigid(*args, S, den, 0)
    return S, den


def witness_free(affine, ra, pa0, qa0, pa1, qa1, rb, pb0, qb0, pb1, qb1):
    """The plane filter as the scene runs it: a plane at t = 0, then the three variants."""
    qa1, qb1 = aligned(qa0, qa1), aligned(qb0, qb1)
    try:
        plane = mjccd.separating_plane(mjccd.Ellipsoid(ra), (pa0, qa0), mjccd.Ellipsoid(rb), (pb0, qb0))
    except ValueError:
        return False
    Sa, dena = supports(affine, ra, qa0, qa1)
    Sb, denb = supports(affine, rb, qb0, qb1)
    R0 = np.stack([quat_to_matrix(qa0), quat_to_matrix(qb0)])
    R1 = np.stack([quat_to_matrix(qa1), quat_to_matrix(qb1)])
    v, _ = fl.witness_variants(plane.normal, pa0, pa1, pb0, pb1, R0, R1, np.concatenate([Sa, Sb]),
                               np.concatenate([dena, denb]), 0, 1, np.empty(fl.WORK_SHAPE), 1)
    return v > 0


# ---------------------------------------------------------------- spheres


@pytest.mark.parametrize("seed", range(3))
def test_sphere_entry_is_a_lower_bound(seed):
    r = np.random.default_rng(seed)
    for _ in range(200):
        ca0, cb0 = r.normal(size=3), r.normal(size=3)
        ca1, cb1 = ca0 + r.normal(size=3), cb0 + r.normal(size=3)
        ra, rb = r.uniform(0.1, 0.8, 2)
        te = fl.sphere_entry(ca0, ca1, ra, cb0, cb1, rb)
        ts = np.linspace(0.0, 1.0, 2001)
        d = np.linalg.norm((cb0 - ca0) + ts[:, None] * ((cb1 - cb0) - (ca1 - ca0)), axis=1) - (ra + rb)
        inside = np.nonzero(d < 0)[0]
        if len(inside):
            assert 0.0 <= te <= ts[inside[0]]
        if te < 0:
            assert d.min() > -1e-12


def test_sphere_entry_closed_form():
    # head-on: centres 3 apart closing at speed 2, radii 0.5 + 0.5 -> touch at t = 1
    assert fl.sphere_entry(np.zeros(3), np.array([1.0, 0, 0]), 0.5, np.array([3.0, 0, 0]),
                           np.array([2.0, 0, 0]), 0.5) == pytest.approx(1.0, abs=1e-8)
    assert fl.sphere_entry(np.zeros(3), np.zeros(3), 0.5, np.array([3.0, 0, 0]), np.array([3.0, 0, 0]), 0.5) == -1.0
    assert fl.sphere_entry(np.zeros(3), np.zeros(3), 1.0, np.array([1.5, 0, 0]), np.array([5.0, 0, 0]), 1.0) == 0.0


def _surface(radii, n=200):
    u = rng.normal(size=(n, 3))
    return radii * (u / np.linalg.norm(u, axis=1, keepdims=True))


def _affine_points(m, radii, t):
    """Surface points of the affine interpolant at t: c + Q(t)^(-1/2) u, |u| = 1."""
    def shape(q):
        R = quat_to_matrix(q)
        return R @ np.diag(1 / radii ** 2) @ R.T
    Q = (1 - t) * shape(m.quaternion0) + t * shape(m.quaternion1)
    w, V = np.linalg.eigh(Q)
    u = rng.normal(size=(200, 3))
    u /= np.linalg.norm(u, axis=1, keepdims=True)
    c = (1 - t) * m.position0 + t * m.position1
    return c + u @ (V @ np.diag(w ** -0.5) @ V.T)


def _chain():
    return mjccd.Chain([mjccd.Fixed([0.2, 0.1, 0.0]), mjccd.Hinge([0, 0, 1], -0.8, 0.9), mjccd.Fixed([0.5, 0, 0]),
                        mjccd.Hinge([0, 1, 0], 0.3, -0.7), mjccd.Fixed([0.4, 0.0, 0.1])])


@pytest.mark.parametrize("kind", ["rigid", "affine", "linear_affine", "chain", "static"])
def test_moving_sphere_encloses_the_ellipsoid(kind):
    radii = np.array([0.3, 0.1, 0.2])
    e = mjccd.Ellipsoid(radii)
    if kind == "rigid":
        m = mjccd.Rigid([0, 0, 0], rand_quat(), [1, 0.5, 0], rand_quat())
    elif kind == "affine":
        m = mjccd.Affine([0, 0, 0], rand_quat(), [1, 0.5, 0], rand_quat())
    elif kind == "linear_affine":
        m = mjccd.LinearAffine(np.hstack([np.eye(3) * 1.3, [[0], [0], [1]]]),
                               np.hstack([quat_to_matrix(rand_quat()) * 0.8, [[1], [0], [0]]]))
    elif kind == "chain":
        m = _chain()
    else:
        m = mjccd.Static([0.3, 0.2, 0.1], rand_quat())
    c0, c1, r = fl.moving_sphere(e, m)
    assert np.isfinite(r)
    for t in np.linspace(0, 1, 41):
        if kind == "affine":
            pts = _affine_points(m, radii, t)
        elif kind == "rigid":
            qt = unit((1 - t) * m.quaternion0 + t * m.quaternion1)
            pts = (1 - t) * m.position0 + t * m.position1 + _surface(radii) @ quat_to_matrix(qt).T
        elif kind == "static":
            pts = m.position + _surface(radii) @ quat_to_matrix(m.quaternion).T
        else:
            M = m.transform(t)
            pts = _surface(radii) @ M[:, :3].T + M[:, 3]
        c = (1 - t) * c0 + t * c1
        assert np.linalg.norm(pts - c, axis=1).max() <= r * (1 + 1e-9)


def test_moving_sphere_rejects_unknown_input():
    with pytest.raises(ValueError, match="ellipsoid: expected an mjccd.Ellipsoid, got list"):
        fl.moving_sphere([1, 1, 1], mjccd.Static([0, 0, 0]))


# ---------------------------------------------------------------- separating plane


@pytest.mark.parametrize("affine", [False, True])
def test_inverse_shape_polynomials(affine):
    """n(t)^T Q(t)^-1 n(t) den(t) from the rigid factor U or the affine T, against Q(t) built directly."""
    radii = np.array([0.3, 0.1, 0.2])
    q0 = rand_quat()
    q1 = aligned(q0, rand_quat())
    S, den = supports(affine, radii, q0, q1)
    n0, n1 = rng.normal(size=3), rng.normal(size=3)
    work = np.zeros(fl.WORK_SHAPE)
    scale = fl._normal_form(S, 0, n0, n1, work, 0)

    def scaled(c, t):
        d = len(c) - 1
        return sum(ck * (1 - t) ** (d - k) * t ** k for k, ck in enumerate(c))

    for t in np.linspace(0.0, 1.0, 7):
        if affine:
            Q = sum(w * quat_to_matrix(q) @ np.diag(radii ** -2.0) @ quat_to_matrix(q).T
                    for w, q in ((1 - t, q0), (t, q1)))
            inv = np.linalg.inv(Q)
        else:
            R = quat_to_matrix(unit((1 - t) * q0 + t * q1))
            inv = R @ np.diag(radii ** 2) @ R.T
        n = (1 - t) * n0 + t * n1
        assert scaled(work[0, :7], t) == pytest.approx(n @ inv @ n * scaled(den[0], t), rel=1e-9)
        assert scale >= np.abs(work[0, :7]).max()
    for k, (n, q) in ((0, (n0, q0)), (4, (n1, q1))):
        R = quat_to_matrix(q)
        assert fl.support_at(S, den, 0, n, k) == pytest.approx(np.sqrt(n @ R @ np.diag(radii ** 2) @ R.T @ n))


def test_witness_sees_a_mid_frame_crossing():
    """A needle turning through a plane between two clear end poses: both ends pass, the frame must not."""
    needle = np.array([1.0, 0.1, 0.1])
    big = np.array([2.0, 2.0, 0.5])
    q0 = ID
    q1 = unit([0.0, 0.0, 1.0, 0.0])     # 180 degrees about y: long axis along x again at t = 1
    for height, expect_free in ((0.6, False), (2.5, True)):
        pb = np.array([0.0, 0.0, height + 0.5])
        free = witness_free(False, big, np.zeros(3), ID, np.zeros(3), ID, needle, pb, q0, pb, q1)
        contact = mjccd.first_contact(mjccd.Ellipsoid(big), mjccd.Static([0, 0, 0]), mjccd.Ellipsoid(needle),
                                      mjccd.Rigid(pb, q0, pb, q1))
        assert (contact is None) == expect_free
        assert free == expect_free


def _near_pair(r, affine):
    """Two ellipsoids placed to graze during the step (contact or a near miss)."""
    ra, rb = r.uniform(0.1, 0.6, 3), r.uniform(0.1, 0.6, 3)
    pa0 = r.normal(size=3) * 0.1
    d = unit(r.normal(size=3))
    gap = ra.max() + rb.max()
    pb0 = pa0 + d * gap * r.uniform(0.9, 1.6)
    pa1 = pa0 + r.normal(size=3) * 0.15
    pb1 = pb0 - d * r.uniform(0.0, 0.5) * gap + r.normal(size=3) * 0.1
    return ra, pa0, rand_quat(), pa1, rand_quat(), rb, pb0, rand_quat(), pb1, rand_quat()


@pytest.mark.parametrize("affine", [False, True])
def test_filters_never_drop_a_colliding_pair(affine):
    r = np.random.default_rng(17 + affine)
    motion = mjccd.Affine if affine else mjccd.Rigid
    hits = frees = 0
    for _ in range(120):
        ra, pa0, qa0, pa1, qa1, rb, pb0, qb0, pb1, qb1 = _near_pair(r, affine)
        c = mjccd.first_contact(mjccd.Ellipsoid(ra), motion(pa0, qa0, pa1, qa1),
                                mjccd.Ellipsoid(rb), motion(pb0, qb0, pb1, qb1))
        te = fl.sphere_entry(pa0, pa1, ra.max(), pb0, pb1, rb.max())
        free = witness_free(affine, ra, pa0, qa0, pa1, qa1, rb, pb0, qb0, pb1, qb1)
        if c is not None:
            hits += 1
            assert 0.0 <= te <= c.time + 1e-12
            assert not free
        frees += free
    assert hits > 10 and frees > 10  # both branches exercised


@pytest.mark.parametrize("eps", [1e-7, -1e-7])
def test_witness_on_a_grazing_pass(eps):
    """Sphere sliding past a box-like ellipsoid at clearance eps: the plane may clear it only when eps > 0."""
    a = np.array([1.0, 1.0, 1.0])
    b = np.array([0.5, 0.5, 0.5])
    pb0 = np.array([-3.0, 0.0, 1.5 + eps])
    pb1 = np.array([3.0, 0.0, 1.5 + eps])
    free = witness_free(False, a, np.zeros(3), ID, np.zeros(3), ID, b, pb0, ID, pb1, ID)
    contact = mjccd.first_contact(mjccd.Ellipsoid(a), mjccd.Static([0, 0, 0]), mjccd.Ellipsoid(b),
                                  mjccd.Rigid(pb0, ID, pb1, ID))
    assert (contact is None) == (eps > 0)
    assert not (free and contact is not None)


@pytest.mark.parametrize("affine", [False, True])
def test_relative_sweep_bounds_every_point(affine):
    """No point of b moves further relative to any point of a than relative_sweep says, between any two times."""
    from mjccd.filters import relative_sweep

    rng = np.random.default_rng(7)
    for _ in range(40):
        radii = rng.uniform(0.1, 1.0, (2, 3))
        c0, c1 = rng.normal(size=(2, 3)), rng.normal(size=(2, 3))
        q0, q1 = rng.normal(size=(2, 4)), rng.normal(size=(2, 4))
        q0 /= np.linalg.norm(q0, axis=1, keepdims=True)
        q1 /= np.linalg.norm(q1, axis=1, keepdims=True)
        q1 *= np.sign(np.sum(q0 * q1, axis=1))[:, None]
        bound = relative_sweep(c0[0], c1[0], q0[0], q1[0], radii[0].max(), c0[1], c1[1], q0[1], q1[1],
                               radii[1].max())

        def point(body, y, t):
            if affine:
                shape = (1 - t) * quat_to_matrix(q0[body]) + t * quat_to_matrix(q1[body])
            else:
                q = (1 - t) * q0[body] + t * q1[body]
                shape = quat_to_matrix(q / np.linalg.norm(q))
            return (1 - t) * c0[body] + t * c1[body] + shape @ (radii[body] * y)

        for _ in range(20):
            ya, yb = rng.normal(size=(2, 3))
            ya /= np.linalg.norm(ya)
            yb /= np.linalg.norm(yb)
            s, t = np.sort(rng.uniform(0, 1, 2))
            moved = (point(1, yb, t) - point(0, ya, t)) - (point(1, yb, s) - point(0, ya, s))
            assert np.linalg.norm(moved) <= bound * (1 + 1e-12)
