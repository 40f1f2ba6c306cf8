"""IntersectionPeriod: line contours and the time interval of overlapping inclusions."""
import numpy as np
import pytest

from mjccd.patches import _kernels as K

RNG = np.random.default_rng(7)
TS = np.linspace(0.0, 1.0, 4001)


def contour_values(ca, cb, cx, m, ts):
    out = np.empty_like(ts)
    for k, t in enumerate(ts):
        seg = min(np.searchsorted(cx[1:m + 1], t, side="left"), m - 1)
        out[k] = ca[seg] * t + cb[seg]
    return out


@pytest.mark.parametrize("n", [1, 2, 5, 16])
@pytest.mark.parametrize("sign", [1.0, -1.0])
def test_upper_contour_is_the_pointwise_maximum(n, sign):
    for _ in range(20):
        a, b = RNG.normal(size=n), RNG.normal(size=n)
        if n > 2:
            a[1] = a[0]  # equal slopes must keep the larger intercept
        eps = np.zeros(n)
        order = np.empty(n, np.int64)
        K._sort_by_slope(a, n, order)
        ca, cb, cx = np.empty(n + 1), np.empty(n + 1), np.empty(n + 1)
        m = K._upper_contour(a, b, eps, order, n, sign, 0.0, 1.0, ca, cb, cx)
        brute = np.max(sign * (np.outer(TS, a) + b), axis=1)
        assert np.allclose(contour_values(ca, cb, cx, m, TS), brute, atol=1e-12)
        assert np.all(np.diff(cx[:m + 1]) > 0)


def test_contour_sweep_and_pairwise_give_the_same_gap():
    for _ in range(300):
        n1, n2 = RNG.integers(1, 17, 2)
        a1, b1 = RNG.normal(size=n1), RNG.normal(size=n1) - 1.0
        a2, b2 = RNG.normal(size=n2), RNG.normal(size=n2) + 1.0
        s1, s2 = np.full(n1, 1e-6), np.full(n2, 1e-6)
        o1, o2 = np.empty(n1, np.int64), np.empty(n2, np.int64)
        K._sort_by_slope(a1, n1, o1)
        K._sort_by_slope(a2, n2, o2)
        c1 = [np.empty(n1 + 1) for _ in range(3)]
        c2 = [np.empty(n2 + 1) for _ in range(3)]
        m1 = K._upper_contour(a1, b1, s1, o1, n1, 1.0, 0.0, 1.0, *c1)
        m2 = K._upper_contour(a2, b2, s2, o2, n2, -1.0, 0.0, 1.0, *c2)
        out1, out2 = np.zeros((2, 2)), np.zeros((2, 2))
        k1 = K._negative_interval(*c1, m1, *c2, m2, 0.0, 1.0, out1, 0)
        k2 = K._pairwise_gap(a1, b1, s1, n1, a2, b2, s2, n2, 0.0, 1.0, out2, 0)
        assert k1 == k2
        if k1:
            assert np.allclose(out1[0], out2[0], atol=1e-9)
        # and both match sampling: the gap is where max(set 1) < min(set 2)
        below = (np.max(np.outer(TS, a1) + b1 + 1e-6, axis=1)
                 < np.min(np.outer(TS, a2) + b2 - 1e-6, axis=1))
        if k1:
            inside = (TS > out1[0, 0]) & (TS < out1[0, 1])
            assert np.array_equal(inside[2:-2], below[2:-2]) or \
                np.abs(TS[inside != below] - out1[0].clip(0, 1)[:, None]).min() < 1e-3
        else:
            assert not below.any()


def box_overlap_at(p0a, p1a, p0b, p1b, axes, t):
    pa = p0a + t * (p1a - p0a)
    pb = p0b + t * (p1b - p0b)
    for e in axes:
        xa, xb = pa @ e, pb @ e
        if xa.max() < xb.min() or xb.max() < xa.min():
            return False
    return True


@pytest.mark.parametrize("na,nb", [(1, 3), (2, 2), (4, 4), (9, 9), (16, 10)])
@pytest.mark.parametrize("use_obb", [False, True])
def test_period_brackets_every_overlapping_instant(na, nb, use_obb):
    ws = K.make_workspace(max(na, nb))
    hits = 0
    for _ in range(300):
        if hits >= 12:
            break
        # A sweeps across the region where B sits, so the inclusions often meet
        sweep = RNG.normal(size=3)
        sweep *= 3.0 / np.linalg.norm(sweep)
        p0a = RNG.uniform(-1, 1, (na, 3)) - 0.5 * sweep
        p1a = p0a + sweep + 0.2 * RNG.normal(size=(na, 3))
        p0b = RNG.uniform(-1, 1, (nb, 3)) + 0.3 * RNG.normal(size=3)
        p1b = p0b + 0.3 * RNG.normal(size=(nb, 3))
        fa, fb = np.empty((3, 3)), np.empty((3, 3))
        q, _ = np.linalg.qr(RNG.normal(size=(3, 3)))
        fa[:] = q.T
        q, _ = np.linalg.qr(RNG.normal(size=(3, 3)))
        fb[:] = q.T
        zero_a, zero_b = np.zeros(na), np.zeros(nb)
        tl, tu = sorted(RNG.uniform(0, 1, 2))
        lo, hi = K.intersection_period(p0a, p1a, zero_a, fa, na, p0b, p1b, zero_b, fb, nb,
                                       tl, tu, use_obb, 0.0, ws)
        nax = K._axes(fa, fb, use_obb, ws.axes)
        axes = ws.axes[:nax].copy()
        if use_obb and (na == 1 or nb == 1):
            axes = (fb if na == 1 else fa).copy()
        ts = np.linspace(tl, tu, 401)
        ok = np.array([box_overlap_at(p0a, p1a, p0b, p1b, axes, t) for t in ts])
        if ok.any():
            hits += 1
            assert lo <= ts[ok].min() + 1e-12 and ts[ok].max() - 1e-12 <= hi
            # tight: the ends are overlapping instants themselves (up to rounding)
            for end in (lo, hi):
                near = [box_overlap_at(p0a, p1a, p0b, p1b, axes, min(max(end + d, tl), tu))
                        for d in (-1e-9, 0.0, 1e-9)]
                assert any(near)
        else:
            assert lo > hi or hi - lo < 2.0 * (tu - tl) / 400
    assert hits >= 12


def test_margins_only_widen_the_interval():
    ws = K.make_workspace(4)
    for _ in range(100):
        p0a, p1a = RNG.uniform(-1, 1, (4, 3)), RNG.uniform(-1, 1, (4, 3))
        p0b, p1b = RNG.uniform(-1, 1, (4, 3)) + 0.5, RNG.uniform(-1, 1, (4, 3)) - 0.5
        f = np.eye(3)
        lo0, hi0 = K.intersection_period(p0a, p1a, np.zeros(4), f, 4, p0b, p1b, np.zeros(4), f,
                                         4, 0.2, 0.8, False, 0.0, ws)
        lo1, hi1 = K.intersection_period(p0a, p1a, np.full(4, 1e-3), f, 4, p0b, p1b,
                                         np.full(4, 1e-3), f, 4, 0.2, 0.8, False, 1e-6, ws)
        if lo0 <= hi0:
            assert lo1 <= lo0 and hi1 >= hi0
        assert 0.2 <= lo1 or lo1 > hi1


def test_touching_only_at_the_interval_end_is_kept():
    # A point reaches the face of a box exactly at t = tu: the widened interval keeps it
    ws = K.make_workspace(4)
    pa0 = np.array([[0.0, 0.0, 1.0]])
    pa1 = np.array([[0.0, 0.0, -1.0]])  # reaches z = 0 at t = 0.5
    quad = np.array([[-1, -1, 0], [1, -1, 0], [-1, 1, 0], [1, 1, 0]], dtype=float)
    f = np.eye(3)
    lo, hi = K.intersection_period(pa0, pa1, np.zeros(1), f, 1, quad, quad, np.zeros(4), f, 4,
                                   0.0, 0.5, False, 1e-6, ws)
    assert lo == hi == 0.5
    lo, hi = K.intersection_period(pa0, pa1, np.zeros(1), f, 1, quad, quad, np.zeros(4), f, 4,
                                   0.0, 0.5 - 1e-3, False, 1e-6, ws)
    assert lo > hi
