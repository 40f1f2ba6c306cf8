"""Input checks shared by the Python layer: every error names the field and the problem.

Short vectors (positions, quaternions, radii) of plain numbers take a scalar
fast path in Python floats; anything else, and every input that fails a
check, goes through the numpy checks, so an error is the same whichever path
met the input first.
"""
import math
import reprlib

import numpy as np

from mjccd.errors import InputError

LENGTH_RANGE = (1e-12, 1e12)
"""The radii the solver supports, in any unit; coordinates lie within ±LENGTH_RANGE[1].

Measured with :func:`mjccd.first_contact` on cases of every motion kind: a
whole case scaled by 2^k gives the same answer for |k| <= 480 (1e±144) and
fails beyond 2^500, where squared lengths overflow; but the exact fallback
divides 0/0 once the radii of a pair differ by more than about 1e30
(spheres of 1e-32 and 1 fail, 1e-30 and 1 pass).  The core works in a frame
scaled by the largest radius, so what matters is how far apart two lengths
of one pair can be: this range keeps any two within 1e24 of each other.
"""

MIN_NORM = 1e-12
"""A quaternion or axis shorter than this is taken for zero (as in :mod:`mjccd.scene`)."""


_PLAIN = frozenset((float, int, bool, np.float64))
"""Element types whose ``float()`` is what ``np.asarray(..., float64)`` makes of them."""

_SHORT = 4
"""Vectors up to this length take the scalar fast path."""

_FLOAT64 = np.dtype(np.float64)


def _floats(value, n):
    """The n entries of a flat list, tuple or float64 vector of plain numbers, as finite Python floats.

    None when the input is anything else or holds a NaN or infinity (an
    overflowing sum of finite entries too): the numpy checks then decide,
    and name what is wrong.
    """
    kind = type(value)
    if kind is np.ndarray:
        if value.dtype is not _FLOAT64 or value.shape != (n,):
            return None
        return finite_floats(value.tolist())
    if (kind is list or kind is tuple) and len(value) == n:
        return finite_floats(value)
    return None


def finite_floats(xs, types=_PLAIN):
    """The numbers ``xs`` (a list or tuple) as a list of finite Python floats, or None when one is not of
    ``types``, does not fit a double, or is a NaN or infinity (an overflowing sum of finite ones too)."""
    if not types.issuperset(map(type, xs)):
        return None
    try:
        xs = list(map(float, xs))
    except OverflowError:
        return None
    total = sum(xs)
    return xs if total - total == 0.0 else None


def plain_floats(values, lengths):
    """Several short inputs at once (``lengths`` entries each) as one list of finite Python floats, or None.

    For constructors that take a few vectors (a pose, two poses): one pass
    of the checks of :func:`_floats` over all of them; None sends each input
    through its own checks, which name the field.
    """
    try:
        for value, n in zip(values, lengths):
            if len(value) != n:
                return None
        xs = [x for value in values for x in value]
    except TypeError:
        return None
    return finite_floats(xs)


def _shown(value):
    """A short repr for messages (a huge or deeply nested input stays one short line)."""
    return reprlib.repr(value)


def _float64(value, field, expected):
    """``np.asarray(value, float64)``; the error names the field and says what was ``expected``."""
    try:
        return np.asarray(value, dtype=np.float64)
    except OverflowError:
        raise InputError(f"{field}: a number is too large for a double") from None
    except (TypeError, ValueError):
        raise InputError(f"{field}: expected {expected}, got {_shown(value)}") from None


def array(value, shape, field):
    """A finite float64 array of the given shape (None in ``shape`` = any length)."""
    arr = _float64(value, field, "numbers")
    if arr.ndim != len(shape) or any(s is not None and s != d for s, d in zip(shape, arr.shape)):
        want = "x".join("N" if s is None else str(s) for s in shape) or "scalar"
        raise InputError(f"{field}: expected shape {want}, got {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise InputError(f"{field}: contains NaN or infinity")
    return np.ascontiguousarray(arr)


def scalar(value, field):
    """A finite number."""
    try:
        x = float(value)
    except OverflowError:
        raise InputError(f"{field}: a number is too large for a double") from None
    except (TypeError, ValueError):
        raise InputError(f"{field}: expected a number, got {_shown(value)}") from None
    if not np.isfinite(x):
        raise InputError(f"{field}: must be finite, got {x}")
    return x


def vector(value, n, field):
    """A finite vector of length n."""
    if n <= _SHORT:
        xs = _floats(value, n)
        if xs is not None:
            return np.array(xs)
    return array(value, (n,), field)


def floats(value, n, field):
    """:func:`vector` as a list of n Python floats (the same checks and messages)."""
    xs = _floats(value, n) if n <= _SHORT else None
    return vector(value, n, field).tolist() if xs is None else xs


def _check_lengths(r, field):
    """Radii inside LENGTH_RANGE; the message names the first one outside."""
    lo, hi = LENGTH_RANGE
    outside = r[(r < lo) | (r > hi)]
    if len(outside):
        raise InputError(f"{field}: {outside[0]:g} is outside the supported range [{lo:g}, {hi:g}]")


def radii(value, field):
    """Three strictly positive radii inside LENGTH_RANGE."""
    xs = _floats(value, 3)
    if xs is not None:
        lo, hi = LENGTH_RANGE
        if lo <= xs[0] <= hi and lo <= xs[1] <= hi and lo <= xs[2] <= hi:
            return np.array(xs)
    r = vector(value, 3, field)
    if np.any(r <= 0.0):
        raise InputError(f"{field}: radii must be positive, got {r.tolist()}")
    _check_lengths(r, field)
    return r


def radii_array(value, field):
    """(N, 3) strictly positive radii inside LENGTH_RANGE."""
    r = array(value, (None, 3), field)
    bad = np.nonzero(np.any(r <= 0.0, axis=1))[0]
    if len(bad):
        raise InputError(f"{field}[{bad[0]}]: radii must be positive, got {r[bad[0]].tolist()}")
    outside = np.nonzero(np.any((r < LENGTH_RANGE[0]) | (r > LENGTH_RANGE[1]), axis=1))[0]
    if len(outside):
        _check_lengths(r[outside[0]], f"{field}[{outside[0]}]")
    return r


def coordinates(value, shape, field):
    """A finite array of the given shape whose entries lie within ±LENGTH_RANGE[1] (positions, displacements)."""
    if len(shape) == 1 and shape[0] is not None and shape[0] <= _SHORT:
        xs = _floats(value, shape[0])
        if xs is not None and max(map(abs, xs)) <= LENGTH_RANGE[1]:
            return np.array(xs)
    arr = array(value, shape, field)
    hi = LENGTH_RANGE[1]
    outside = arr[np.abs(arr) > hi]
    if len(outside):
        raise InputError(f"{field}: {outside[0]:g} is outside the supported range [{-hi:g}, {hi:g}]")
    return arr


def direction(value, n, field, zero="zero vector"):
    """A finite vector of length n, not shorter than MIN_NORM, scaled by a power of two to a largest entry in [0.5, 1).

    A direction's length carries no meaning, and scaling by a power of two is
    exact, so normalising the result gives the same bits as normalising the
    input would, without overflow for huge entries (1e300).
    """
    return np.array(_direction(value, n, field, zero))


def _direction(value, n, field, zero):
    """:func:`direction` as a list of Python floats."""
    xs = _floats(value, n) if n <= _SHORT else None
    if xs is None:
        xs = vector(value, n, field).tolist()
    exponent = math.frexp(max(map(abs, xs)))[1]
    v = [math.ldexp(x, -exponent) for x in xs]
    norm = math.ldexp(math.hypot(*v), exponent) if exponent <= 0 else math.inf  # at least 0.5 when exponent > 0
    if norm < MIN_NORM:
        raise InputError(f"{field}: {zero} (norm {norm:.3g}, at least {MIN_NORM:g} needed)")
    return v


def unit_quaternion(value, field):
    """:func:`quaternion` as a list of four Python floats.

    The length is ``math.hypot`` (safe from overflow and underflow, and
    scaled internally by the largest entry's power of two), so the quotients
    are the same whether or not the input was scaled by :func:`direction` first.
    """
    xs = _floats(value, 4)
    if xs is not None:
        norm = math.hypot(*xs)
        if MIN_NORM <= norm < math.inf:
            return [x / norm for x in xs]
    v = _direction(value, 4, field, "zero quaternion")
    norm = math.hypot(*v)
    return [x / norm for x in v]


def quaternion(value, field):
    """A finite, non-zero quaternion [w, x, y, z], returned normalised (a quaternion is only a direction)."""
    return np.array(unit_quaternion(value, field))


def pose_array(value, field, n=None):
    """(N, 7) rows of position and quaternion [w, x, y, z], quaternions normalised as :func:`quaternion` does."""
    poses = array(value, (n, 7), field)
    _, exponents = np.frexp(np.abs(poses[:, 3:]).max(axis=1, initial=0.0))
    quats = np.ldexp(poses[:, 3:], -exponents[:, None])
    norms = np.sqrt(np.sum(quats ** 2, axis=1))
    bad = np.nonzero(np.ldexp(norms, exponents) < MIN_NORM)[0]
    if len(bad):
        raise InputError(f"{field}[{bad[0]}]: zero quaternion")
    out = poses.copy()
    out[:, 3:] = quats / norms[:, None]
    return out


def polynomial(value, field):
    """Power-basis coefficients (lowest degree first): a non-empty finite 1-D list."""
    p = _float64(value, field, "a list of coefficients")
    if p.ndim != 1 or p.size == 0:
        raise InputError(f"{field}: expected a non-empty list of coefficients")
    if not np.all(np.isfinite(p)):
        raise InputError(f"{field}: contains NaN or infinity")
    return p


def time_bound(value, field):
    """A number in [0, 1]."""
    try:
        t = float(value)
    except (TypeError, ValueError, OverflowError):
        raise InputError(f"{field}: expected a number in [0, 1], got {_shown(value)}") from None
    if not (0.0 <= t <= 1.0):
        raise InputError(f"{field}: must lie in [0, 1], got {t}")
    return t
