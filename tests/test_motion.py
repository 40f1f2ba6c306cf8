"""Motion constructors: cheap checks with the same messages, the poses' row, and W formed on first need."""
import numpy as np
import pytest

import mjccd
from mjccd import motion as mo
from mjccd.errors import InputError

ID = [1.0, 0.0, 0.0, 0.0]


def _eager_rigid_w(p0, q0, p1, q1):
    """W of a rigid motion as the constructor used to form it: the quaternion lerp, then the centre lerp."""
    rot = mo.w_of_rotation(np.ascontiguousarray(np.stack([q0, q1], axis=-1)))
    shift = mo.w_of_translation(np.ascontiguousarray(np.stack([p0, p1], axis=-1)))
    return mo.w_compose(*shift, *rot)


def test_rigid_keeps_its_poses_in_one_row_and_aligns_the_end_quaternion():
    q1 = np.array([0.2, 0.9, 0.1, 0.3])
    m = mjccd.Rigid([1, 2, 3], [0.5, 0.5, 0.5, 0.5], [4, 5, 6], -q1)
    assert m._row.shape == (14,) and m._row.dtype == np.float64
    assert m.position0.tolist() == [1, 2, 3] and m.position1.tolist() == [4, 5, 6]
    assert m.quaternion0.tolist() == [0.5, 0.5, 0.5, 0.5]
    assert m.quaternion0 @ m.quaternion1 >= 0.0  # -q1 turned back to the short way
    assert np.allclose(m.quaternion1, q1 / np.linalg.norm(q1), atol=1e-16)
    assert np.array_equal(mjccd.Rigid([1, 2, 3], [0.5, 0.5, 0.5, 0.5], [4, 5, 6], q1)._row, m._row)
    affine = mjccd.Affine([1, 2, 3], [0.5, 0.5, 0.5, 0.5], [4, 5, 6], -q1)
    assert np.allclose(affine.quaternion1, -q1 / np.linalg.norm(q1), atol=1e-16)  # the affine motion keeps it


def test_w_is_formed_on_first_need_as_before():
    r = np.random.default_rng(4)
    p0, p1 = r.normal(size=3), r.normal(size=3)
    q0, q1 = r.normal(size=4), r.normal(size=4)
    m = mjccd.Rigid(p0, q0, p1, q1)
    assert m._w_cache is None
    G, h, g = m.scaled_inverse_w()
    for got, want in zip((G, h, g), _eager_rigid_w(m.position0, m.quaternion0, m.position1, m.quaternion1)):
        assert np.array_equal(got, want)
    assert m.scaled_inverse_w() is m.scaled_inverse_w()  # formed once
    s = mjccd.Static(p0, q0)
    assert s._w_cache is None
    for got, want in zip(s.scaled_inverse_w(), mo._pose_w(s.position, s.quaternion)):
        assert np.array_equal(got, want)
    radii = np.array([0.3, 0.2, 0.5])
    for t in (0.0, 0.3, 1.0):  # the quadric from W is the rigid quadric (up to the factor |q|^4)
        A = mo.quadric_at(*mo.quadric_from_w(G, h, g, radii), t)
        B = mo.quadric_at(*mo.quadric_rigid(radii, m.position0, m.quaternion0, m.position1, m.quaternion1), t)
        assert np.allclose(A / np.abs(A).max(), B / np.abs(B).max(), atol=1e-13)


@pytest.mark.parametrize("kind", [mjccd.Rigid, mjccd.Affine])
def test_translated_shifts_the_centres_and_forms_w_again(kind):
    m = kind([1e6, 2.0, 3.0], [0.1, 0.7, 0.2, 0.6], [1e6 + 1.0, 2.5, 3.0], [0.3, 0.6, 0.1, 0.7])
    if kind is mjccd.Rigid:
        m.scaled_inverse_w()
    offset = np.array([1e6, 2.0, 3.0])
    local = m.translated(offset)
    assert type(local) is kind
    assert local.position0.tolist() == [0.0, 0.0, 0.0] and local.position1.tolist() == [1.0, 0.5, 0.0]
    assert np.array_equal(local.quaternion0, m.quaternion0) and np.array_equal(local.quaternion1, m.quaternion1)
    assert m.position0[0] == 1e6  # the original is untouched
    if kind is mjccd.Rigid:
        fresh = mjccd.Rigid(local.position0, local.quaternion0, local.position1, local.quaternion1)
        for got, want in zip(local.scaled_inverse_w(), fresh.scaled_inverse_w()):
            assert np.array_equal(got, want)
    static = mjccd.Static([5.0, 6.0, 7.0], [0.0, 1.0, 0.0, 0.0]).translated(np.array([5.0, 6.0, 7.0]))
    assert static.position.tolist() == [0.0, 0.0, 0.0] and static.quaternion.tolist() == [0.0, 1.0, 0.0, 0.0]


@pytest.mark.parametrize("args, message", [
    (([0, 0, np.nan], ID, [0, 0, 0], ID), "start.position: contains NaN or infinity"),
    (([0, 0, 0], [0, 0, 0, 0], [0, 0, 0], ID), "start.quaternion: zero quaternion (norm 0, at least 1e-12 needed)"),
    (([0, 0, 0], ID, [0, 0], ID), "end.position: expected shape 3, got (2,)"),
    (([0, 0, 0], ID, [0, 0, 0], [1, 0, 0]), "end.quaternion: expected shape 4, got (3,)"),
    (([0, 0, 0], ID, [0, 0, 0], [1, 0, 0, "x"]), "end.quaternion: expected numbers, got [1, 0, 0, 'x']"),
    (([0, 0, 0], ID, [[0], [0], [0]], ID), "end.position: expected shape 3, got (3, 1)"),
])
@pytest.mark.parametrize("kind", [mjccd.Rigid, mjccd.Affine])
def test_two_pose_messages(kind, args, message):
    for convert in (list, np.array) if "numbers" not in message else (list,):
        with pytest.raises(InputError) as info:
            kind(*[convert(a) if not isinstance(a[0], list) else a for a in args])
        assert str(info.value) == message


@pytest.mark.parametrize("args, message", [
    (([0, 0], ID), "position: expected shape 3, got (2,)"),
    (([0, 0, 0], [0, 0, 0, 0]), "quaternion: zero quaternion (norm 0, at least 1e-12 needed)"),
    (([0, np.inf, 0], ID), "position: contains NaN or infinity"),
])
def test_static_messages(args, message):
    with pytest.raises(InputError) as info:
        mjccd.Static(*args)
    assert str(info.value) == message


def test_plain_and_array_inputs_give_the_same_motion():
    r = np.random.default_rng(9)
    p0, p1, q0, q1 = r.normal(size=3), r.normal(size=3), r.normal(size=4), r.normal(size=4)
    a = mjccd.Rigid(p0, q0, p1, q1)
    b = mjccd.Rigid(p0.tolist(), tuple(q0.tolist()), p1.tolist(), q1.tolist())
    c = mjccd.Rigid(p0.astype(np.float32).astype(object), q0, p1, q1 * 2.0 ** 700)  # the field-by-field checks
    assert np.array_equal(a._row, b._row)
    assert np.array_equal(a._row[3:], c._row[3:])
    assert np.array_equal(mjccd.Static(p0, q0)._row, mjccd.Static(list(p0), list(q0))._row)
    assert mjccd.Ellipsoid([1, 2, 3]).radii.tolist() == mjccd.Ellipsoid(np.array([1.0, 2.0, 3.0])).radii.tolist()


def _flattened(ratio, ts, scale, rng):
    """(start, end) 3x4 of x = c L(t) y with L(t) = U [[1,0,0],[0,1,(t-ts)],[0,-(t-ts),r]] V^T: det L is
    smallest at ts, r + (t - ts)^2 there; r is chosen so that it equals ``ratio`` x |L|_F^3 (the larger end)."""
    U = np.linalg.qr(rng.normal(size=(3, 3)))[0]
    V = np.linalg.qr(rng.normal(size=(3, 3)))[0]
    size = max(np.sqrt(3.0 + 2.0 * ts ** 2), np.sqrt(3.0 + 2.0 * (1.0 - ts) ** 2))  # |L|_F at the ends, r ~ 0
    r = ratio * size ** 3

    def end(t):
        L = scale * U @ np.array([[1.0, 0, 0], [0, 1.0, t - ts], [0, -(t - ts), r]]) @ V.T
        return np.hstack([L, rng.normal(size=(3, 1))])
    return end(0.0), end(1.0)


@pytest.mark.parametrize("ts", [0.0, 0.37, 0.5, 1.0])
def test_linear_affine_refusal_depends_only_on_how_flat_it_gets(ts):
    """The documented rule: refused when min |det L(t)| <= 1e-12 |L|_F^3 (or det changes sign), the same at
    any scale, turned any way, with the flattest time at an end or inside."""
    rng = np.random.default_rng(7)
    for scale in (1e-3, 1.0, 1e3):
        start, end = _flattened(0.5 * mo.FLATTENING, ts, scale, rng)
        with pytest.raises(InputError, match="within 1e-12 of singular"):
            mjccd.LinearAffine(start, end)
        start, end = _flattened(2.0 * mo.FLATTENING, ts, scale, rng)
        mjccd.LinearAffine(start, end)
    start, end = _flattened(2.0 * mo.FLATTENING, ts, 1.0, rng)
    end[:, :3] *= -1.0  # det L(1) < 0 < det L(0)
    with pytest.raises(InputError, match="becomes singular between"):
        mjccd.LinearAffine(start, end)
