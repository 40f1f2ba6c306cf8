"""Input checks: the scalar fast path and the numpy checks give the same values and the same messages."""
import numpy as np
import pytest

from mjccd import _validate
from mjccd.errors import InputError


def _slow(values):
    """The same numbers in a container the fast path does not take (an object array): the numpy checks."""
    return np.array(list(values), dtype=object)


def _outcome(check, *args):
    try:
        return np.asarray(check(*args), dtype=float)
    except InputError as exc:
        return str(exc)


GOOD = [[0.3, -0.2, 0.1, 2.0], [1e300, 0.0, 0.0, 0.0], [3e-300, 1e-310, 0.0, 0.0], [0.7071, 0.0, 0.7071, 0.0],
        [1, 2, 3, 4], [1e12, -1e12, 5.0, 0.5], [5e-13, 5e-13, 0.0, 0.0]]
BAD = [[0.0, 0.0, 0.0, 0.0], [np.nan, 0.0, 0.0, 1.0], [np.inf, 1.0, 0.0, 0.0], [1e-13, 0.0, 0.0, 0.0],
       [2e-13, -1.0, 1e12 + 1, 0.0], [1.7e308, 1.7e308, 1.7e308, 1.7e308], [10 ** 400, 0, 0, 0]]


@pytest.mark.parametrize("values", GOOD + BAD)
@pytest.mark.parametrize("check", [
    lambda v: _validate.quaternion(v, "q"),
    lambda v: _validate.unit_quaternion(v, "q"),
    lambda v: _validate.direction(v, 4, "d", "zero quaternion"),
    lambda v: _validate.vector(v, 4, "v"),
    lambda v: _validate.floats(v, 4, "v"),
    lambda v: _validate.vector(v[:3], 3, "p"),
    lambda v: _validate.radii(v[:3], "r"),
    lambda v: _validate.coordinates(v[:3], (3,), "c"),
])
def test_fast_and_numpy_paths_agree(check, values):
    """A list, a tuple and a float64 array (the fast path) and an object array (numpy's checks): same floats
    to the bit, or the same message."""
    slow = _outcome(check, _slow(values))
    for container in (list, tuple):
        fast = _outcome(check, container(values))
        assert type(fast) is type(slow)
        assert fast == slow if isinstance(slow, str) else np.array_equal(fast, slow)
    if all(isinstance(x, float) for x in values):
        arr = _outcome(check, np.array(values))
        assert arr == slow if isinstance(slow, str) else np.array_equal(arr, slow)


@pytest.mark.parametrize("call, message", [
    (lambda: _validate.quaternion([0, 0, 0, 0], "start.quaternion"),
     "start.quaternion: zero quaternion (norm 0, at least 1e-12 needed)"),
    (lambda: _validate.quaternion([1e-13, 0, 0, 0], "q"), "q: zero quaternion (norm 1e-13, at least 1e-12 needed)"),
    (lambda: _validate.vector([1, 2], 3, "position"), "position: expected shape 3, got (2,)"),
    (lambda: _validate.vector([[1], [2], [3]], 3, "position"), "position: expected shape 3, got (3, 1)"),
    (lambda: _validate.vector([1, np.nan, 3], 3, "position"), "position: contains NaN or infinity"),
    (lambda: _validate.vector([1, "a", 3], 3, "position"), "position: expected numbers, got [1, 'a', 3]"),
    (lambda: _validate.vector([10 ** 400, 0, 0], 3, "position"), "position: a number is too large for a double"),
    (lambda: _validate.radii([1, -1, 1], "radii"), "radii: radii must be positive, got [1.0, -1.0, 1.0]"),
    (lambda: _validate.radii([1, 1e13, 1], "radii"), "radii: 1e+13 is outside the supported range [1e-12, 1e+12]"),
    (lambda: _validate.coordinates([0, -2e12, 0], (3,), "p"),
     "p: -2e+12 is outside the supported range [-1e+12, 1e+12]"),
    (lambda: _validate.direction([0, 0, 0], 3, "axis"), "axis: zero vector (norm 0, at least 1e-12 needed)"),
])
def test_messages_name_the_field(call, message):
    with pytest.raises(InputError) as info:
        call()
    assert str(info.value) == message


def test_a_quaternion_is_normalised_whatever_its_scale():
    """Scaled by any power of two (huge ones too, and tiny ones above MIN_NORM), a quaternion gives the same
    unit floats."""
    q = [0.3, -0.2, 0.1, 0.9]
    unit = _validate.unit_quaternion(q, "q")
    for k in (-35, -1, 0, 30, 600, 1000):
        assert _validate.unit_quaternion([x * 2.0 ** k for x in q], "q") == unit
    assert abs(sum(x * x for x in unit) - 1.0) <= 4e-16


def test_plain_floats_reads_several_inputs_or_hands_them_back():
    assert _validate.plain_floats(([1, 2, 3], (4.0, 5.0), np.array([6.0])), (3, 2, 1)) == [1, 2, 3, 4, 5, 6]
    assert _validate.plain_floats(([1, 2, 3], [4.0, 5.0]), (3, 3)) is None  # a length that does not fit
    assert _validate.plain_floats(([1, 2, np.nan],), (3,)) is None
    assert _validate.plain_floats(([1, "2", 3],), (3,)) is None
    assert _validate.plain_floats((np.ones((3, 1)),), (3,)) is None
    assert _validate.plain_floats((None,), (3,)) is None
