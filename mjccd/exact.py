"""Exact static status of two ellipsoids, in rational arithmetic (``fractions.Fraction``).

Every double is a rational number, so the quadric of an ellipsoid placed by
double-precision radii, position and quaternion is an exact rational matrix
(the quaternion is normalised exactly: ``rot(q) / |q|^2`` is orthogonal for
any q, no square root needed).  :func:`static_status_exact` then decides the
sign of ``max_u g(u)``, ``g(u) = det((1 - u) A + u B)`` over [0, 1] (thesis
Thm 4.1) without rounding: it is the referee of the double-precision tests in
:mod:`mjccd.quadric`, which hand it the pairs they cannot decide (code 2).

Pure Python and slow (milliseconds a pair): meant for the rare undecided pair.
"""
from fractions import Fraction

SEPARATE, TOUCHING, OVERLAPPING = 1, 0, -1


def _fr(x):
    """An exact rational: a Fraction or int as is, a float converted exactly."""
    return x if isinstance(x, (Fraction, int)) else Fraction(float(x))


def quadric_from_w_exact(G, h, g, radii):
    """4x4 quadric (lists of Fractions) of ``{x : |D^(1/2) (G x + h)|^2 <= g^2}``, ``D = diag(1/r^2)``.

    That is ``[[P, U], [U^T, s]]`` with ``P = G^T D G``, ``U = G^T D h`` and
    ``s = h^T D h - g^2``: the ellipsoid under the motion whose scaled
    inverse is ``W = [[G, h], [0, g]]`` (see :func:`mjccd.motion.quadric_from_w`).
    """
    G = [[_fr(x) for x in row] for row in G]
    h = [_fr(x) for x in h]
    d = [1 / _fr(r) ** 2 for r in radii]
    Q = [[Fraction(0)] * 4 for _ in range(4)]
    for i in range(3):
        for j in range(3):
            Q[i][j] = sum(d[k] * G[k][i] * G[k][j] for k in range(3))
        Q[i][3] = Q[3][i] = sum(d[k] * G[k][i] * h[k] for k in range(3))
    Q[3][3] = sum(d[k] * h[k] * h[k] for k in range(3)) - _fr(g) ** 2
    return Q


def quadric_exact(radii, position, quaternion):
    """Exact world quadric ``M^-T diag(1/a^2, 1/b^2, 1/c^2, -1) M^-1`` of a posed ellipsoid.

    The pose maps the frame to the world by ``y = R x + p`` with
    ``R = rot(q) / |q|^2``, so ``x = R^T y - R^T p``: ``G = R^T``, ``h = -R^T p``, ``g = 1``.
    """
    w, x, y, z = (_fr(c) for c in quaternion)
    n = w * w + x * x + y * y + z * z
    if n == 0:
        raise ValueError("quaternion: zero quaternion")
    R = [[(w * w + x * x - y * y - z * z) / n, 2 * (x * y - w * z) / n, 2 * (x * z + w * y) / n],
         [2 * (x * y + w * z) / n, (w * w - x * x + y * y - z * z) / n, 2 * (y * z - w * x) / n],
         [2 * (x * z - w * y) / n, 2 * (y * z + w * x) / n, (w * w - x * x - y * y + z * z) / n]]
    p = [_fr(c) for c in position]
    G = [[R[k][i] for k in range(3)] for i in range(3)]
    h = [-sum(G[i][k] * p[k] for k in range(3)) for i in range(3)]
    return quadric_from_w_exact(G, h, 1, radii)


# ---------------------------------------------------------------- polynomials (coefficient lists, lowest first)


def _det(M):
    """Determinant by Laplace expansion along the first row (exact; small matrices only)."""
    if len(M) == 1:
        return M[0][0]
    return sum((-1) ** j * M[0][j] * _det([row[:j] + row[j + 1:] for row in M[1:]])
               for j in range(len(M)) if M[0][j] != 0)


def _trim(p):
    while p and p[-1] == 0:
        p = p[:-1]
    return p


def _value(p, x):
    acc = Fraction(0)
    for c in reversed(p):
        acc = acc * x + c
    return acc


def _interpolate(ys):
    """Coefficients of the polynomial of degree < len(ys) through (k, ys[k]), k = 0, 1, ... (Newton form)."""
    n = len(ys)
    dd = list(ys)
    for level in range(1, n):  # divided differences on the nodes 0, 1, ..., n-1
        for k in range(n - 1, level - 1, -1):
            dd[k] = (dd[k] - dd[k - 1]) / level
    p = [Fraction(0)]
    for k in range(n - 1, -1, -1):  # p = dd[k] + (x - k) p
        p = [a - k * b for a, b in zip([Fraction(0)] + p, p + [Fraction(0)])]
        p[0] += dd[k]
    return _trim(p)


def _derivative(p):
    return _trim([k * c for k, c in enumerate(p)][1:])


def _divmod(a, b):
    """Quotient and remainder of polynomials (b non-zero)."""
    a = list(a)
    q = [Fraction(0)] * max(len(a) - len(b) + 1, 0)
    while len(a) >= len(b) and a:
        k = len(a) - len(b)
        c = a[-1] / b[-1]
        q[k] = c
        for i, bc in enumerate(b):
            a[i + k] -= c * bc
        a = _trim(a[:-1])
    return q, a


def _gcd(a, b):
    while b:
        a, b = b, _divmod(a, b)[1]
    return [c / a[-1] for c in a]


def _sign_changes(seq, x):
    signs = [s for s in (_value(p, x) for p in seq) if s != 0]
    return sum(1 for s, t in zip(signs, signs[1:]) if (s > 0) != (t > 0))


def _real_roots_between(q, lo, hi):
    """Isolating intervals (a, b), a and b no roots, of the roots of the square-free q in (lo, hi).

    Sturm: the number of roots in (a, b) is V(a) - V(b) for the sign changes
    V of q, q', -rem(q, q'), ...  Intervals are halved until each holds one.
    """
    seq = [q, _derivative(q)]
    while seq[-1] and len(seq[-1]) > 1:
        seq.append([-c for c in _divmod(seq[-2], seq[-1])[1]])
    seq = [p for p in seq if p]
    out, todo = [], [(lo, hi)]
    while todo:
        a, b = todo.pop()
        n = _sign_changes(seq, a) - _sign_changes(seq, b)
        if n == 1:
            out.append((a, b))
        elif n > 1:
            m = (a + b) / 2
            while _value(q, m) == 0:  # split at a point that is no root
                m = (a + m) / 2
            todo += [(m, b), (a, m)]
    return sorted(out)


def static_status_exact(A, B):
    """1 (separate), 0 (touching) or -1 (overlapping) of the quadrics A, B, decided exactly.

    ``A``, ``B``: 4x4 of floats or Fractions (ellipsoids: ``det < 0``).  The
    quartic ``g(u) = det((1 - u) A + u B)`` is built exactly from five values;
    the distinct roots of its square-free part ``g / gcd(g, g')`` in (0, 1) are
    isolated with a Sturm sequence, and g is evaluated at a rational point in
    each gap between them (and at 0 and 1): a positive value means separate;
    else a root means touching (g reaches 0 but never exceeds it); else
    overlapping.
    """
    A = [[_fr(x) for x in row] for row in A]
    B = [[_fr(x) for x in row] for row in B]
    ys = [_det([[(1 - u) * a + u * b for a, b in zip(ra, rb)] for ra, rb in zip(A, B)]) for u in range(5)]
    g = _interpolate(ys)
    if not g:
        raise ValueError("degenerate pencil: det((1-u)A + uB) vanishes identically")
    q = _divmod(g, _gcd(g, _derivative(g)))[0] if len(g) > 1 else g
    zero, one = Fraction(0), Fraction(1)
    if not (ys[0] < 0 and ys[1] < 0):  # g(0) = det A, g(1) = det B
        raise ValueError("not two ellipsoids: det A and det B must be negative")
    roots = _real_roots_between(q, zero, one)
    points = [zero, one] + [b for _, b in roots[:-1]]
    if any(_value(g, x) > 0 for x in points):
        return SEPARATE
    return TOUCHING if roots else OVERLAPPING
