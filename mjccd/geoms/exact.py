"""Exact polynomials over the rationals: lists of Fractions in the power basis, lowest degree first.

What the small solvers take exactly before any rounding: their inputs as exact numbers, arithmetic on
motions' entries, exact root tests (Sturm's theorem), and the conversion to Bernstein coefficients
rounded once to double (or double-double) with the bound of that rounding (:func:`packed`).
"""
import math
from fractions import Fraction
from numbers import Integral, Real

import numpy as np

from mjccd.errors import InputError, InputTypeError


def number(x, field):
    """x as an exact Fraction (floats, ints, Fractions; finite)."""
    if isinstance(x, Fraction):
        return x
    if isinstance(x, bool):
        raise InputTypeError(f"{field}: expected a number, got {x!r}")
    if isinstance(x, Integral):
        return Fraction(int(x))
    if isinstance(x, Real):
        f = float(x)
        if not math.isfinite(f):
            raise InputError(f"{field}: must be finite, got {f}")
        return Fraction(f)
    raise InputTypeError(f"{field}: expected a number or a list of coefficients, got {type(x).__name__}")


def trim(p):
    p = list(p)
    while len(p) > 1 and p[-1] == 0:
        p.pop()
    return p


def poly_of(value, field):
    """A polynomial entry: a number or a sequence of power-basis coefficients (lowest first), as Fractions."""
    if isinstance(value, np.ndarray):
        if value.ndim == 0:
            return [number(value.item(), field)]
        if value.ndim != 1:
            raise InputError(f"{field}: expected a number or a 1-d list of coefficients")
        value = value.tolist()
    if isinstance(value, (list, tuple)):
        if not value:
            raise InputError(f"{field}: expected a non-empty list of coefficients")
        return trim([number(c, f"{field}[{i}]") for i, c in enumerate(value)])
    return [number(value, field)]


def add(a, b, sb=1):
    n = max(len(a), len(b))
    return trim([(a[i] if i < len(a) else 0) + sb * (b[i] if i < len(b) else 0) for i in range(n)])


def mul(a, b):
    out = [Fraction(0)] * (len(a) + len(b) - 1)
    for i, x in enumerate(a):
        if x:
            for j, y in enumerate(b):
                out[i + j] += x * y
    return trim(out)


def scale(a, s):
    return trim([s * x for x in a])


def value(p, t):
    acc = Fraction(0)
    for c in reversed(p):
        acc = acc * t + c
    return acc


def derivative(p):
    return trim([i * p[i] for i in range(1, len(p))] or [Fraction(0)])


def remainder(a, b):
    """The remainder of a by b (b nonzero)."""
    a = list(a)
    while len(a) >= len(b) and any(a):
        f = a[-1] / b[-1]
        shift = len(a) - len(b)
        for i, c in enumerate(b):
            a[shift + i] -= f * c
        a.pop()
    return trim(a or [Fraction(0)])


def sign_changes(seq, t):
    signs = [v for v in (value(p, t) for p in seq) if v != 0]
    return sum(1 for x, y in zip(signs, signs[1:]) if (x > 0) != (y > 0))


def has_root_in_01(p):
    """True when the nonzero polynomial p has a real root in [0, 1] (exact: Sturm's theorem; a multiple root is
    counted once, which is all a yes-or-no needs)."""
    p = trim(p)
    if value(p, 0) == 0 or value(p, 1) == 0:
        return True
    if len(p) == 1:
        return False
    seq = [p, derivative(p)]
    while len(seq[-1]) > 1:
        r = remainder(seq[-2], seq[-1])
        if not any(r):
            break
        big = max(abs(c) for c in r)
        seq.append([-c / big for c in r])  # a positive factor keeps the signs; it keeps the numbers small
    return sign_changes(seq, Fraction(0)) - sign_changes(seq, Fraction(1)) > 0


def taylor_shift(p, t0, h):
    """p(t0 + h tau) as a polynomial in tau (exact)."""
    out = [Fraction(0)]
    for c in reversed(p):
        out = add(mul(out, [t0, h]), [c])
    return out


def up(x):
    """The smallest double >= the nonnegative Fraction x."""
    f = float(x)
    if Fraction(f) < x:
        f = math.nextafter(f, math.inf)
    return f


def down(x):
    """The largest double <= x."""
    f = float(x)
    if Fraction(f) > x:
        f = math.nextafter(f, -math.inf)
    return f


def bernstein(p, n):
    """Bernstein coefficients of degree n >= deg p on [0, 1] (exact)."""
    return [sum((Fraction(math.comb(k, i), math.comb(n, i)) * p[i] for i in range(min(k, len(p) - 1) + 1)),
                Fraction(0)) for k in range(n + 1)]


def packed(polys):
    """Polynomials (Fractions, power basis) as kernel input: (4, len, n+1) = hi, lo, error bound of hi, error
    bound of hi + lo, from their exact Bernstein coefficients; and each one's degree."""
    degs = np.array([len(p) - 1 for p in polys], dtype=np.int64)
    n = int(degs.max())
    out = np.zeros((4, len(polys), n + 1))
    for r, p in enumerate(polys):
        for i, x in enumerate(bernstein(p, len(p) - 1)):
            hi = float(x)
            rest = x - Fraction(hi)
            lo = float(rest)
            out[0, r, i], out[1, r, i] = hi, lo
            out[2, r, i] = up(abs(rest))
            out[3, r, i] = up(abs(rest - Fraction(lo)))
    return out, degs
