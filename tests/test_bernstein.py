"""Bernstein kernels against plain numpy polynomial arithmetic."""
import numpy as np
import pytest

from mjccd import bernstein as bz

rng = np.random.default_rng(7)


def power_eval(p, t):
    return np.polynomial.polynomial.polyval(t, p)


@pytest.mark.parametrize("deg", [0, 1, 3, 8, 24])
def test_from_power_and_evaluate(deg):
    p = rng.normal(size=deg + 1)
    c = bz.from_power(p)
    for t in [0.0, 0.13, 0.5, 0.77, 1.0]:
        assert bz.evaluate(c, t) == pytest.approx(power_eval(p, t), abs=1e-12)


def test_subdivide_restrict_elevate_derivative():
    p = rng.normal(size=7)
    c = bz.from_power(p)
    left, right = bz.subdivide(c, 0.3)
    for s in [0.0, 0.4, 1.0]:
        assert bz.evaluate(left, s) == pytest.approx(power_eval(p, 0.3 * s), abs=1e-12)
        assert bz.evaluate(right, s) == pytest.approx(power_eval(p, 0.3 + 0.7 * s), abs=1e-12)
    mid = bz.restrict(c, 0.2, 0.6)
    assert bz.evaluate(mid, 0.5) == pytest.approx(power_eval(p, 0.4), abs=1e-12)
    up = bz.elevate(c, 3)
    assert len(up) == 10
    assert bz.evaluate(up, 0.71) == pytest.approx(power_eval(p, 0.71), abs=1e-12)
    d = bz.derivative(c)
    dp = np.polynomial.polynomial.polyder(p)
    assert bz.evaluate(d, 0.33) == pytest.approx(power_eval(dp, 0.33), abs=1e-11)


def test_multiply_and_add():
    p, q = rng.normal(size=4), rng.normal(size=6)
    prod = bz.multiply(bz.from_power(p), bz.from_power(q))
    s = bz.add(bz.from_power(p), bz.from_power(q))
    for t in [0.1, 0.6, 0.9]:
        assert bz.evaluate(prod, t) == pytest.approx(power_eval(np.polynomial.polynomial.polymul(p, q), t), abs=1e-12)
        assert bz.evaluate(s, t) == pytest.approx(power_eval(np.polynomial.polynomial.polyadd(p, q), t), abs=1e-12)


def test_bounds_contain_values():
    c = bz.from_power(rng.normal(size=9))
    lo, hi = bz.bounds(c)
    values = [bz.evaluate(c, t) for t in np.linspace(0, 1, 101)]
    assert lo <= min(values) and max(values) <= hi


@pytest.mark.parametrize("roots, tol", [([0.3], 1e-14), ([0.2, 0.7], 1e-14), ([1e-9, 0.5], 1e-14),
                                        ([0.999999], 1e-13),
                                        ([0.25, 0.25 + 1e-7, 0.9], 1e-10)])  # clustered: ill-conditioned
def test_first_root_finds_smallest(roots, tol):
    p = np.array([1.0])
    for r in roots:
        p = np.polynomial.polynomial.polymul(p, [-r, 1.0])
    c = bz.from_power(p)
    found = bz.first_root(c, 1e-15)
    assert found == pytest.approx(min(roots), abs=tol)


def test_first_root_survives_a_root_at_the_clipped_end():
    """Regression: a shallow graze whose first root sits where clipping cuts.

    Clipping narrows onto the root at 4.89e-7 so tightly that the rounded value at the
    new lower end comes out -4e-36; the root must still be reported there, not skipped
    for the second root near 5.5e-3 (the two bound a 1e-5-deep overlap).
    """
    c = np.array([1.1852516765579676e-08, -0.0013465272238574327, 0.026254659040808762,
                  0.08222677472484546, 0.16639811958807552, 0.2789835219354132,
                  0.42057449041876166, 0.5921375792202834, 0.7950207210097262,
                  1.0309675231297692, 1.3021397557375618, 1.611148496339445,
                  1.9610946432928085, 2.35561978177545, 2.798968690762514, 3.296065131639054,
                  3.8526029735152454, 4.475155205690988, 5.171303987047259])
    assert bz.evaluate(c, 1e-7) > 0.0 > bz.evaluate(c, 1e-6)
    assert bz.first_root(c, 1e-15) == pytest.approx(4.8905525e-7, rel=1e-6)


@pytest.mark.parametrize("deg", [1, 2, 7, 18, 60])  # 60: above the tabled binomials
def test_value_and_slope(deg):
    p = rng.normal(size=deg + 1)
    c = bz.from_power(p)
    dp = np.polynomial.polynomial.polyder(p)
    for t in [0.0, 0.2, 0.5, 0.51, 0.9, 1.0]:
        value, slope = bz.value_and_slope(c, t)
        assert value == pytest.approx(power_eval(p, t), abs=1e-9)
        assert slope == pytest.approx(power_eval(dp, t), abs=1e-8)


def test_newton_fast_path_never_returns_a_later_root():
    """The certified Newton root is the first root or nothing (-1, clipping decides), never another root."""
    local = np.random.default_rng(3)
    declined = 0
    for _ in range(500):
        roots = local.uniform(-0.5, 1.5, size=local.integers(2, 6))
        c = bz.from_power(np.polynomial.polynomial.polyfromroots(roots))
        inside = np.sort(roots[(roots >= 0.0) & (roots <= 1.0)])
        fast = bz._newton_first_root(c, 1e-15)
        if fast < 0.0:
            declined += 1
            continue
        assert len(inside) and fast == pytest.approx(inside[0], abs=1e-9)
        assert bz.first_root(c, 1e-15) == fast
    assert 0 < declined < 500  # both branches are exercised


def test_first_root_none():
    c = bz.from_power(np.array([1.0, -1.0, 1.0]))  # 1 - t + t^2 > 0
    assert bz.first_root(c, 1e-15) == -1.0


def test_bivariate_scaled_product():
    F = rng.normal(size=(2, 4))
    G = rng.normal(size=(3, 2))
    H = bz.from_scaled(bz.scaled_multiply(bz.to_scaled(F), bz.to_scaled(G)))
    for u, t in [(0.2, 0.3), (0.9, 0.1)]:
        f = bz.evaluate(bz.bivariate_at_u(F, u), t)
        g = bz.evaluate(bz.bivariate_at_u(G, u), t)
        h = bz.evaluate(bz.bivariate_at_t(H, t), u)
        assert h == pytest.approx(f * g, abs=1e-12)
