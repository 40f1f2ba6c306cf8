"""Input checks shared by the Python layer: every error names the field and the problem."""
import numpy as np

from mjccd.errors import InputError


def array(value, shape, field):
    """A finite float64 array of the given shape (None in ``shape`` = any length)."""
    try:
        arr = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError):
        raise InputError(f"{field}: expected numbers, got {value!r}") from None
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
    except (TypeError, ValueError):
        raise InputError(f"{field}: expected a number, got {value!r}") from None
    if not np.isfinite(x):
        raise InputError(f"{field}: must be finite, got {x}")
    return x


def vector(value, n, field):
    """A finite vector of length n."""
    return array(value, (n,), field)


def radii(value, field):
    """Three finite, strictly positive radii."""
    r = vector(value, 3, field)
    if np.any(r <= 0.0):
        raise InputError(f"{field}: radii must be positive, got {r.tolist()}")
    return r


def radii_array(value, field):
    """(N, 3) finite, strictly positive radii."""
    r = array(value, (None, 3), field)
    bad = np.nonzero(np.any(r <= 0.0, axis=1))[0]
    if len(bad):
        raise InputError(f"{field}[{bad[0]}]: radii must be positive, got {r[bad[0]].tolist()}")
    return r


def quaternion(value, field):
    """A finite, non-zero quaternion [w, x, y, z], returned normalised."""
    q = vector(value, 4, field)
    n = float(np.sqrt(q @ q))
    if n < 1e-12:
        raise InputError(f"{field}: zero quaternion (norm {n:.3g})")
    return q / n


def pose_array(value, field, n=None):
    """(N, 7) rows of position and quaternion [w, x, y, z], quaternions normalised."""
    poses = array(value, (n, 7), field)
    norms = np.sqrt(np.sum(poses[:, 3:] ** 2, axis=1))
    bad = np.nonzero(norms < 1e-12)[0]
    if len(bad):
        raise InputError(f"{field}[{bad[0]}]: zero quaternion")
    out = poses.copy()
    out[:, 3:] /= norms[:, None]
    return out


def polynomial(value, field):
    """Power-basis coefficients (lowest degree first): a non-empty finite 1-D list."""
    try:
        p = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError):
        raise InputError(f"{field}: expected a list of coefficients, got {value!r}") from None
    if p.ndim != 1 or p.size == 0:
        raise InputError(f"{field}: expected a non-empty list of coefficients")
    if not np.all(np.isfinite(p)):
        raise InputError(f"{field}: contains NaN or infinity")
    return p


def time_bound(value, field):
    """A number in [0, 1]."""
    try:
        t = float(value)
    except (TypeError, ValueError):
        raise InputError(f"{field}: expected a number in [0, 1], got {value!r}") from None
    if not (0.0 <= t <= 1.0):
        raise InputError(f"{field}: must lie in [0, 1], got {t}")
    return t
