"""search_exit's bounded box pool: the same exits as the unbounded search, and honest limits.

Every decision is taken with E, the bound of the errors of F's coefficients: the search runs on
the upper polynomial F + E, so a certified exit is a proven lower bound of the true exit, and the
times before it are proven overlapping (status_at(F, E, t) == -1).
"""
import heapq
from decimal import Decimal, getcontext

import numpy as np
import pytest

import mjccd
from mjccd import bernstein as bz
from mjccd import ccd

ID = [1.0, 0.0, 0.0, 0.0]


def _pair(a, motion_a, b, motion_b):
    """(F, E) of the pair over the whole step: the balanced pencil, F and its tight error bound."""
    length = float(max(a.radii.max(), b.radii.max()))
    pencil, err, _ = ccd.prepare_pair(*motion_a.quadric_bounded_on(a.radii, 0.0, 1.0),
                                      *motion_b.quadric_bounded_on(b.radii, 0.0, 1.0), length)
    F, D, _ = ccd.balanced_F(*pencil, err)
    E = ccd.error_bound_tight(F, *pencil, D)
    return F, E


def _ring(depth, lift=None):
    """A sphere on a link behind six hinges about z (F of degree 96) circling a sphere at the origin.

    The link keeps the two centres 0.8 - depth apart (radii 0.3 + 0.5): a constant penetration
    ``depth`` that the certified march cannot get through, so the box search runs.  With ``lift``
    the second sphere rises along z by that much over the step and the overlap ends.
    """
    a, b = mjccd.Ellipsoid([0.3] * 3), mjccd.Ellipsoid([0.5] * 3)
    chain = mjccd.Chain([mjccd.Hinge([0, 0, 1], -0.4, 0.4) for _ in range(6)] + [mjccd.Fixed([0.8 - depth, 0, 0])])
    mb = mjccd.Static([0, 0, 0]) if lift is None else mjccd.Rigid([0, 0, 0], ID, [0, 0, lift], ID)
    return _pair(a, chain, b, mb)


def _ring_exit(depth, lift):
    """The true exit of the lifted ring, from its double inputs: (0.3 + 0.5)^2 = r^2 + (lift t)^2."""
    getcontext().prec = 60
    reach, r, z = Decimal(0.3) + Decimal(0.5), Decimal(0.8 - depth), Decimal(lift)
    return float((reach * reach - r * r).sqrt() / z)


CASES = {
    "spheres": lambda: _pair(mjccd.Ellipsoid([0.5] * 3), mjccd.Rigid([-1.5, 0, 0], ID, [1.5, 0.1, 0], ID),
                             mjccd.Ellipsoid([0.4] * 3), mjccd.Static([0, 0, 0])),
    "spinning": lambda: _pair(mjccd.Ellipsoid([2, 0.2, 0.2]), mjccd.Chain([mjccd.Hinge([0, 0, 1], -2.0, 2.0)]),
                              mjccd.Ellipsoid([0.3] * 3), mjccd.Static([1.5, 0, 0])),
    "tumbling": lambda: _pair(mjccd.Ellipsoid([0.6, 0.2, 0.3]),
                              mjccd.Rigid([-0.5, 0, 0], ID, [0.6, 0.2, 0.1], [0.5, 0.5, 0.5, 0.5]),
                              mjccd.Ellipsoid([0.4, 0.3, 0.2]), mjccd.Rigid([0, 0, 0], ID, [0, 0.1, 0], [0, 1, 0, 0])),
    "ring_through": lambda: _ring(1e-9),
    "ring_lift": lambda: _ring(1e-9, lift=8e-5),
    "ring_lift_fast": lambda: _ring(1e-9, lift=2e-4),
}


def _first_overlap(F, E):
    for t in np.linspace(0.0, 1.0, 2001):
        if ccd.status_at(F, E, t)[0] == -1:
            return float(t)
    raise AssertionError("the case never overlaps")


def _reference_exit(F, E, t_start, t_end):
    """The search before the pool, in Python: every box kept, a heapq of (start, index of creation).

    Like search_exit it runs entirely on the upper polynomial F + E.
    """
    upper = F + E
    t_exit, reached = ccd._march_exit(upper, t_start, t_end)
    if t_exit >= 0.0:
        return t_exit, True
    boxes = [bz.bivariate_restrict_t(upper, reached, t_end)]
    ends = [t_end]
    heap = [(reached, 0)]
    count = 0
    while heap:
        t0, idx = heapq.heappop(heap)
        C, t1 = boxes[idx], ends[idx]
        count += 1
        if ccd._exit_box_negative(C):
            continue
        if count > ccd.MAX_BOXES:
            return t0, False
        width = t1 - t0
        column_max = C.max(axis=0)
        r = 0.0
        if column_max[0] < 0.0:
            r = bz.first_root(column_max, 1e-12)
            if r < 0.0:
                continue
        if r > 0.05 and width > ccd.EXIT_BOX_TOL:
            boxes.append(np.array([bz.restrict(C[i].copy(), r, 1.0) for i in range(C.shape[0])]))
            ends.append(t1)
            heapq.heappush(heap, (t0 + r * width, len(boxes) - 1))
            continue
        if width <= ccd.EXIT_BOX_TOL:
            gmax, _ = ccd.state(upper, t1)
            if gmax >= 0.0:
                return ccd._bisect_sign(upper, t0, t1, True), True
            continue
        span_t = (C.max(axis=1) - C.min(axis=1)).max()
        span_u = (C.max(axis=0) - C.min(axis=0)).max()
        a, b = np.empty_like(C), np.empty_like(C)
        if span_t >= span_u:
            ccd._exit_split_t_into(C.copy(), a, b)
            a_end = b_start = 0.5 * (t0 + t1)
        else:
            ccd._exit_split_u_into(C.copy(), a, b)
            a_end, b_start = t1, t0
        boxes += [a, b]
        ends += [a_end, t1]
        heapq.heappush(heap, (t0, len(boxes) - 2))
        heapq.heappush(heap, (b_start, len(boxes) - 1))
    return 2.0, True


def _assert_overlapping_before(F, E, t_start, t):
    """Every sampled time in [t_start, t) is proven overlapping for the true F.

    The search certifies F + E < 0 there, which is status_at's own condition for -1 (overlapping);
    in these cases F + E stays well below the rounding of that evaluation, so nothing weaker
    (0, undecided) is accepted, and above all never 1 (separate).
    """
    for s in np.linspace(t_start, t, 101)[:-1]:
        code = ccd.status_at(F, E, s)[0]
        assert code != 1, f"proven separate at {s} before the search's time {t}"
        assert code == -1, f"not proven overlapping at {s} before the search's time {t}"


@pytest.mark.parametrize("name", sorted(CASES))
def test_pool_gives_the_exits_of_the_unbounded_search(name):
    F, E = CASES[name]()
    t0 = _first_overlap(F, E)
    want = _reference_exit(F, E, t0, 1.0)
    got = ccd.search_exit(F, E, t0, 1.0)
    assert want[1] and got == want  # bit for bit: same boxes, same order, on the same F + E
    # a pool far larger than the default changes nothing either
    t, certified, peak = ccd._search_exit_pool(F, E, t0, 1.0, 10 ** 6, ccd.MAX_BOXES)
    assert (t, certified) == got
    assert peak <= ccd._exit_capacity(F.shape[0], F.shape[1], ccd.MAX_BOXES)
    # the exit of F + E is a lower bound: never after the exit of the computed F itself (E = 0)
    t_plain, certified_plain, _ = ccd._search_exit_pool(F, np.zeros_like(E), t0, 1.0, 10 ** 6, ccd.MAX_BOXES)
    assert certified_plain and got[0] <= t_plain
    if got[0] <= 1.0:
        _assert_overlapping_before(F, E, t0, got[0])


def test_expected_exits():
    """The constructed exits where they can be written down: the lifted sphere leaves when
    0.8^2 = (0.8 - depth)^2 + (lift t)^2, and the ring without lift never leaves."""
    F, E = CASES["ring_lift"]()
    true_exit = _ring_exit(1e-9, 8e-5)
    assert true_exit == pytest.approx(0.5, abs=1e-6)
    # the computed F alone (E = 0) leaves where the construction says
    t_plain, certified, _ = ccd._search_exit_pool(F, np.zeros_like(E), 0.0, 1.0, 10 ** 6, ccd.MAX_BOXES)
    assert certified and t_plain == pytest.approx(true_exit, abs=1e-5)
    # search_exit, on F + E, gives a proven lower bound of it: no later than the true exit, and where
    # F + E reaches zero, so F itself is still negative there by an amount between E's extremes
    t, certified = ccd.search_exit(F, E, 0.0, 1.0)
    assert certified and t <= true_exit
    assert -E.max() <= ccd.state(F, t)[0] <= -E.min() < 0.0
    assert t == pytest.approx(true_exit, abs=5e-3)
    _assert_overlapping_before(F, E, 0.0, t)
    # the ring overlaps by 1e-9 (F about -2.8e-9 against E about 1e-11): F + E stays negative, so the
    # search proves the overlap through the end of the step
    F, E = CASES["ring_through"]()
    assert ccd.search_exit(F, E, 0.0, 1.0) == (2.0, True)


def test_default_capacity_fits_the_budget():
    for n in (2, 6, 18, 48, 96, 200):
        cap = ccd._exit_capacity(5, n + 1, ccd.MAX_BOXES)
        assert 2 <= cap <= ccd.MAX_BOXES + 2
        assert cap * 5 * (n + 1) * 8 <= ccd.EXIT_POOL_BYTES
    assert ccd._exit_capacity(5, 97, ccd.MAX_BOXES) > 1000
    assert ccd._exit_capacity(5, 3, 100) == 102  # never more slots than can be live


@pytest.mark.parametrize("name", ["spheres", "ring_lift", "ring_lift_fast"])
@pytest.mark.parametrize("capacity, max_pops", [(1, 10 ** 9), (2, 10 ** 9), (8, 10 ** 9), (10 ** 5, 1),
                                                (10 ** 5, 10), (10 ** 5, 300), (10 ** 5, 3000)])
def test_a_limit_returns_a_certified_lower_bound(name, capacity, max_pops):
    F, E = CASES[name]()
    t0 = _first_overlap(F, E)
    exit_time, certified = ccd.search_exit(F, E, t0, 1.0)
    assert certified and exit_time < 1.0
    t, certified, peak = ccd._search_exit_pool(F, E, t0, 1.0, capacity, max_pops)
    assert peak <= max(capacity, 1)
    if certified:  # the limit was not reached: then the answer is the exit itself
        assert t == exit_time
        return
    assert t0 <= t <= exit_time  # the exit of F + E, itself a lower bound of the true exit
    _assert_overlapping_before(F, E, t0, t)


def test_limits_stop_the_ring_that_never_leaves():
    """Without the limits the ring is proven overlapping to the end (2.0, True; test_expected_exits);
    with them the search stops early and says so."""
    F, E = CASES["ring_through"]()
    for capacity, max_pops in [(4, 10 ** 9), (10 ** 5, 50), (10 ** 5, 2000)]:
        t, certified, peak = ccd._search_exit_pool(F, E, 0.0, 1.0, capacity, max_pops)
        assert not certified and 0.0 < t < 1.0 and peak <= capacity
        _assert_overlapping_before(F, E, 0.0, t)


def test_max_boxes_is_reported_uncertified():
    """A penetration of 5e-12 for the whole step (F about -1.4e-11, E about 8.6e-12): F + E is
    negative but too close to zero for the search, which runs into MAX_BOXES.  It used to return the
    popped box's start as if it were the exit; now that start comes back uncertified."""
    F, E = _ring(5e-12)
    assert ccd.status_at(F, E, 0.0)[0] == -1
    t, certified = ccd.search_exit(F, E, 0.0, 1.0)
    assert not certified and 0.0 < t < 1.0
    _assert_overlapping_before(F, E, 0.0, t)
