"""Bernstein-form polynomial algebra on [0, 1] (numba kernels).

Every polynomial in mjccd lives in Bernstein form: a univariate polynomial of
degree ``n`` is the array ``c`` of its ``n + 1`` coefficients,
``p(t) = sum_i c[i] * C(n, i) * t**i * (1 - t)**(n - i)``; a bivariate one of
degree ``(m, n)`` is an ``(m + 1, n + 1)`` array in the basis
``B_i^m(u) * B_j^n(t)``.  The form is numerically stable on [0, 1], its
coefficients bound the polynomial (convex hull property) and subdivision is
exact, which is what makes certified root finding possible.

Products are computed in the *scaled* Bernstein basis (coefficients multiplied
by their binomials), where multiplication is a plain convolution.  All kernels
take and return plain float64 arrays and are compiled lazily with
``cache=True``.
"""
import math

import numba
import numpy as np

# compiled on first use and cached; no cfunc wrapper (no kernel is passed around as a first-class function);
# forceinline=False: numba hands a caller's forceinline down to the callees it compiles.  Arrays are copied by
# loops (copy_into), never by a slice assignment from an array: that makes numba compile a shape-mismatch
# error formatted as a string into the kernel, whose string code LLVM then optimises again in every kernel that
# calls it (about 0.16 s each)
_jit = numba.njit(cache=True, nogil=True, no_cfunc_wrapper=True, forceinline=False)


@_jit
def copy_into(dst, src):
    """``dst[:] = src`` for two 1-D arrays of one length, as a loop (see ``_jit``)."""
    for k in range(src.shape[0]):
        dst[k] = src[k]
    return dst


@_jit
def add_into(dst, src, scale):
    """``dst += scale * src`` for two 1-D arrays of one length, as a loop (see ``_jit``)."""
    for k in range(src.shape[0]):
        dst[k] += scale * src[k]
    return dst


# ---------------------------------------------------------------- binomials

TABLED_DEGREE = 48
# C(n, k) rounded once, for the degrees of every hot loop (rigid, affine and rational pairs); a
# compile-time constant, so evaluation needs no division chain
BINOMIALS = np.array([[float(math.comb(n, k)) for k in range(TABLED_DEGREE + 1)]
                       for n in range(TABLED_DEGREE + 1)])


@_jit
def binomial_row(n):
    """The binomial coefficients C(n, 0..n) as floats."""
    row = np.empty(n + 1)
    if n <= TABLED_DEGREE:
        for k in range(n + 1):
            row[k] = BINOMIALS[n, k]
        return row
    row[0] = 1.0
    for i in range(1, n + 1):
        row[i] = row[i - 1] * (n - i + 1) / i
    return row


@_jit
def binomial(n, k):
    """C(n, k) as a float: exact from the table up to TABLED_DEGREE, else a product of k rounded ratios."""
    if n <= TABLED_DEGREE:
        return BINOMIALS[n, k]
    value = 1.0
    for i in range(1, k + 1):
        value = value * (n - i + 1) / i
    return value


# ---------------------------------------------------------------- univariate


@_jit
def evaluate_row(F, i, t):
    """Value at ``t`` of the Bernstein polynomial in row i of ``F`` (Horner in t/(1-t), O(n), no view)."""
    n = F.shape[1] - 1
    if n == 0:
        return F[i, 0]
    flip = t > 0.5
    s = (1.0 - t) / t if flip else t / (1.0 - t)
    # Horner in s over the coefficients, from the end far from t
    acc = F[i, 0] if flip else F[i, n]
    tabled = n <= TABLED_DEGREE
    binom = 1.0
    for k in range(n - 1, -1, -1):
        binom = BINOMIALS[n, k] if tabled else binom * (k + 1) / (n - k)
        acc = acc * s + binom * (F[i, n - k] if flip else F[i, k])
    return acc * (t if flip else 1.0 - t) ** n


@_jit
def evaluate(c, t):
    """Value of the Bernstein polynomial ``c`` at ``t``."""
    return evaluate_row(c.reshape((1, c.shape[0])), 0, t)


@_jit
def subdivide(c, t):
    """Split ``c`` at ``t`` by de Casteljau: coefficients on [0, t] and on [t, 1]."""
    n = c.shape[0] - 1
    work = c.copy()
    left = np.empty(n + 1)
    right = np.empty(n + 1)
    left[0] = work[0]
    right[n] = work[n]
    for r in range(1, n + 1):
        for i in range(n - r + 1):
            work[i] = (1.0 - t) * work[i] + t * work[i + 1]
        left[r] = work[0]
        right[n - r] = work[n - r]
    return left, right


@_jit
def restrict_into(c, a, b):
    """In place: ``c`` reparametrised from [a, b] onto [0, 1]."""
    if b < 1.0:
        _keep_left(c, b)
    if a > 0.0:
        _keep_right(c, a / b if b > 0.0 else 0.0)


@_jit
def restrict(c, a, b):
    """Coefficients of the same polynomial reparametrised from [a, b] onto [0, 1]."""
    out = c.copy()
    restrict_into(out, a, b)
    return out


@_jit
def elevate(c, r):
    """Degree elevation by ``r``: the same polynomial with degree n + r."""
    out = c.copy()
    for _ in range(r):
        n = out.shape[0] - 1
        nxt = np.empty(n + 2)
        nxt[0] = out[0]
        nxt[n + 1] = out[n]
        for i in range(1, n + 1):
            w = i / (n + 1.0)
            nxt[i] = w * out[i - 1] + (1.0 - w) * out[i]
        out = nxt
    return out


@_jit
def derivative(c):
    """Coefficients of dp/dt (degree n - 1)."""
    n = c.shape[0] - 1
    if n == 0:
        return np.zeros(1)
    out = np.empty(n)
    for i in range(n):
        out[i] = n * (c[i + 1] - c[i])
    return out


@_jit
def multiply(a, b):
    """Product of two Bernstein polynomials (degree m + n)."""
    m = a.shape[0] - 1
    n = b.shape[0] - 1
    bm = binomial_row(m)
    bn = binomial_row(n)
    bmn = binomial_row(m + n)
    out = np.zeros(m + n + 1)
    for i in range(m + 1):
        ai = a[i] * bm[i]
        for j in range(n + 1):
            out[i + j] += ai * b[j] * bn[j]
    for k in range(m + n + 1):
        out[k] /= bmn[k]
    return out


@_jit
def add(a, b):
    """Sum of two Bernstein polynomials, elevating the lower degree."""
    m = a.shape[0] - 1
    n = b.shape[0] - 1
    if m < n:
        a = elevate(a, n - m)
    elif n < m:
        b = elevate(b, m - n)
    return a + b


@_jit
def bounds(c):
    """Lower and upper bound of the polynomial on [0, 1] (convex hull property)."""
    return c.min(), c.max()


@_jit
def abs_maxima(P, U, s):
    """Largest |coefficient| of each entry of a 3x3 matrix P (3, 3, n), a vector U (3, m) and a scalar s
    of polynomials: (3, 3), (3,) and a float (bounds of their values on [0, 1])."""
    Pm = np.empty((3, 3))
    Um = np.empty(3)
    for i in range(3):
        for j in range(3):
            Pm[i, j] = np.abs(P[i, j]).max()
        Um[i] = np.abs(U[i]).max()
    return Pm, Um, np.abs(s).max()


@_jit
def adjugate3(M):
    """Adjugate and determinant of a 3x3 matrix of Bernstein polynomials of one degree n (M: (3, 3, n + 1)).

    Returns ``adj`` (3, 3, 2n + 1), ``adj[i, j] = (-1)^(i+j)`` times the minor of M without row j and
    column i, and ``det = M[0, 0] adj[0, 0] + M[0, 1] adj[1, 0] + M[0, 2] adj[2, 0]`` (degree 3n).
    """
    adj = np.empty((3, 3, 2 * M.shape[2] - 1))
    for i in range(3):
        for j in range(3):
            r0, r1 = (1 if j == 0 else 0), (1 if j == 2 else 2)  # the rows other than j, ascending
            c0, c1 = (1 if i == 0 else 0), (1 if i == 2 else 2)
            minor = add(multiply(M[r0, c0], M[r1, c1]), -multiply(M[r0, c1], M[r1, c0]))
            copy_into(adj[i, j], minor if (i + j) % 2 == 0 else -minor)
    det = add(add(multiply(M[0, 0], adj[0, 0]), multiply(M[0, 1], adj[1, 0])), multiply(M[0, 2], adj[2, 0]))
    return adj, det


@_jit
def from_power(p):
    """Bernstein coefficients (degree len(p) - 1) of ``sum_k p[k] t**k``."""
    n = p.shape[0] - 1
    bn = binomial_row(n)
    out = np.zeros(n + 1)
    for i in range(n + 1):
        acc = 0.0
        bi = binomial_row(i)
        for k in range(i + 1):
            acc += bi[k] / bn[k] * p[k]
        out[i] = acc
    return out


# ---------------------------------------------------------------- root finding


@_jit
def _chain_crossings(c, upper, stack, lo, hi):
    """Widen [lo, hi] by the zero crossings of the lower (or upper) convex hull chain of (i, c[i])."""
    n = c.shape[0] - 1
    top = 0
    for i in range(n + 1):
        while top >= 2:
            a = stack[top - 2]
            b = stack[top - 1]
            cross = (b - a) * (c[i] - c[a]) - (c[b] - c[a]) * (i - a)
            if (cross >= 0.0) if upper else (cross <= 0.0):
                top -= 1
            else:
                break
        stack[top] = i
        top += 1
    for k in range(top):
        p = stack[k]
        if c[p] == 0.0:
            lo = min(lo, p)
            hi = max(hi, p)
        elif k + 1 < top:
            q = stack[k + 1]
            if c[q] != 0.0 and (c[p] > 0.0) != (c[q] > 0.0):
                x = p + (q - p) * c[p] / (c[p] - c[q])
                lo = min(lo, x)
                hi = max(hi, x)
    return lo, hi


@_jit
def _hull_crossing(c, stack):
    """Where the convex hull of the control points (i/n, c[i]) meets zero, in O(n).

    The hull meets the axis in one segment [alpha, beta] whose ends lie on the
    lower or the upper hull chain.  Returns (2, -1) when the hull misses the
    axis.  ``stack`` is scratch of length n + 1.
    """
    n = c.shape[0] - 1
    lo, hi = _chain_crossings(c, np.bool_(False), stack, 2.0 * n, -1.0)
    lo, hi = _chain_crossings(c, np.bool_(True), stack, lo, hi)
    if hi < 0.0:
        return 2.0, -1.0
    return lo / n, hi / n


@_jit
def _keep_left(c, t):
    """In place: ``c`` becomes the coefficients on [0, t] (de Casteljau)."""
    n = c.shape[0] - 1
    for r in range(1, n + 1):
        for i in range(n, r - 1, -1):
            c[i] = (1.0 - t) * c[i - 1] + t * c[i]


@_jit
def _keep_right(c, t):
    """In place: ``c`` becomes the coefficients on [t, 1] (de Casteljau)."""
    n = c.shape[0] - 1
    for r in range(1, n + 1):
        for i in range(n - r + 1):
            c[i] = (1.0 - t) * c[i] + t * c[i + 1]


@_jit
def value_and_slope(c, t):
    """p(t) and p'(t) of the Bernstein polynomial ``c`` in O(n): one Horner pass in x = t/(1-t) (as
    :func:`evaluate_row`) that also carries the derivative in x, for Newton's steps.

    p(t) = (1-t)^n P(x), so p'(t) = (1-t)^(n-1) (P'(x) / (1-t) - n P(x)); for t > 1/2 the same from the
    far end, with x = (1-t)/t and the sign turned.
    """
    n = c.shape[0] - 1
    if n == 0:
        return c[0], 0.0
    flip = t > 0.5
    x = (1.0 - t) / t if flip else t / (1.0 - t)
    # coefficient k of P, read from the far end when flipped
    acc = c[0] if flip else c[n]
    dacc = 0.0
    tabled = n <= TABLED_DEGREE
    binom = 1.0
    for k in range(n - 1, -1, -1):
        binom = BINOMIALS[n, k] if tabled else binom * (k + 1) / (n - k)
        dacc = dacc * x + acc
        acc = acc * x + binom * (c[n - k] if flip else c[k])
    far = t if flip else 1.0 - t
    slope = far ** (n - 1) * (dacc / far - n * acc)
    return acc * far ** n, -slope if flip else slope


@_jit
def _newton_first_root(c, tol):
    """Fast path of :func:`first_root`: a Newton root from 0, accepted only with a certificate.

    The certificate: the coefficients of ``c`` restricted to [0, lo] all have
    the sign of c[0] (no root before lo), and c changes sign within ``tol``
    after lo.  Returns lo, or -1 when Newton or the certificate fails (a root
    that is not the first, a double root, rounding), for clipping to decide.
    """
    n = c.shape[0] - 1
    x = 0.0
    converged = False
    for _ in range(50):
        v, d = value_and_slope(c, x)
        if v == 0.0:
            converged = True
            break
        if not d != 0.0:
            return -1.0
        step = -v / d
        x += step
        if not 0.0 <= x <= 1.0:
            return -1.0
        if abs(step) <= 0.25 * tol:
            converged = True
            break
    if not converged:
        return -1.0
    lo = max(0.0, x - 0.5 * tol)
    hi = min(1.0, lo + tol)
    positive = c[0] > 0.0
    v_hi, _ = value_and_slope(c, hi)
    if v_hi != 0.0 and (v_hi > 0.0) == positive:
        return -1.0
    left = c.copy()
    _keep_left(left, lo)
    for i in range(n + 1):
        if left[i] == 0.0 or (left[i] > 0.0) != positive:
            return -1.0
    return lo


@_jit
def first_root(c, tol):
    """Smallest root of the Bernstein polynomial ``c`` in [0, 1], or -1.

    A certified Newton root is tried first (:func:`_newton_first_root`).
    Otherwise Bézier clipping: the part of the interval where the convex hull
    of the control polygon stays off zero is discarded; when clipping stalls
    the interval is halved and the left half searched first.  The returned
    value is the lower end of the first interval of width <= ``tol`` that
    could not be excluded, so the polynomial has no root before it (up to
    rounding).  All work happens in place in a few buffers allocated once per call.
    """
    n = c.shape[0] - 1
    if n == 0:
        return 0.0 if c[0] == 0.0 else -1.0
    if c[0] == 0.0:
        return 0.0
    fast = _newton_first_root(c, tol)
    if fast >= 0.0:
        return fast
    # every pending right half is at most half as wide as the one before it
    max_depth = int(np.ceil(-np.log2(max(tol, 1e-300)))) + 2
    stack_c = np.empty((max_depth, n + 1))
    stack_lo = np.empty(max_depth)
    stack_hi = np.empty(max_depth)
    hull = np.empty(n + 1, dtype=np.int64)
    cur = np.empty(n + 1)
    copy_into(stack_c[0], c)
    stack_lo[0] = 0.0
    stack_hi[0] = 1.0
    top = 1
    while top > 0:
        top -= 1
        copy_into(cur, stack_c[top])
        lo = stack_lo[top]
        hi = stack_hi[top]
        positive_at_lo = cur[0] > 0.0
        while True:
            cmin = cur.min()
            cmax = cur.max()
            if cmin > 0.0 or cmax < 0.0:
                break  # no root on [lo, hi]
            width = hi - lo
            if width <= tol:
                return lo
            alpha, beta = _hull_crossing(cur, hull)
            if alpha > beta:
                break
            alpha = max(alpha, 0.0)
            beta = min(beta, 1.0)
            if beta - alpha > 0.7:
                # clipping does not shrink enough: bisect, left half first
                mid = lo + 0.5 * width
                copy_into(stack_c[top], cur)
                _keep_right(stack_c[top], 0.5)
                stack_lo[top] = mid
                stack_hi[top] = hi
                top += 1
                _keep_left(cur, 0.5)
                hi = mid
                continue
            if beta < 1.0:
                _keep_left(cur, beta)
            if alpha > 0.0:
                _keep_right(cur, alpha / beta if beta > 0.0 else 0.0)
            new_lo = lo + alpha * width
            new_hi = lo + beta * width
            lo, hi = new_lo, max(new_hi, new_lo)
            # Clipping never passes a root, so the value at the new lower end keeps
            # its sign; when rounding flips it (or zeroes it) the root is right here.
            if cur[0] == 0.0 or (cur[0] > 0.0) != positive_at_lo:
                return lo
            if hi - lo <= tol:
                return lo
    return -1.0


# ---------------------------------------------------------------- bivariate


@_jit
def bivariate_at_u_into(F, u, out):
    """In ``out``: the univariate polynomial in t, F(u, .) for fixed u (coefficients in t)."""
    m = F.shape[0] - 1
    out[:] = 0.0
    w_binom = 1.0
    for i in range(m + 1):
        w = w_binom * u ** i * (1.0 - u) ** (m - i)
        for j in range(F.shape[1]):
            out[j] += w * F[i, j]
        w_binom = w_binom * (m - i) / (i + 1)
    return out


@_jit
def bivariate_at_u(F, u):
    """Univariate polynomial in t: F(u, .) for fixed u (coefficients in t)."""
    return bivariate_at_u_into(F, u, np.empty(F.shape[1]))


@_jit
def bivariate_at_t(F, t):
    """Univariate polynomial in u: F(., t) for fixed t (coefficients in u)."""
    m = F.shape[0] - 1
    out = np.empty(m + 1)
    for i in range(m + 1):
        out[i] = evaluate_row(F, i, t)
    return out


@_jit
def bivariate_restrict_t(F, a, b):
    """F reparametrised in t from [a, b] onto [0, 1]."""
    out = np.empty_like(F)
    for i in range(F.shape[0]):
        out[i] = restrict(F[i].copy(), a, b)
    return out


@_jit
def bivariate_derivative_t(F):
    """dF/dt in bivariate Bernstein form (degree (m, n - 1))."""
    m = F.shape[0] - 1
    n = F.shape[1] - 1
    out = np.empty((m + 1, max(n, 1)))
    if n == 0:
        out[:, 0] = 0.0
        return out
    for i in range(m + 1):
        for j in range(n):
            out[i, j] = n * (F[i, j + 1] - F[i, j])
    return out


@_jit
def _binomial_grid(m, n):
    """C(m, i) C(n, j) for the coefficients of a bivariate polynomial of degree (m, n)."""
    bm = binomial_row(m)
    bn = binomial_row(n)
    out = np.empty((m + 1, n + 1))
    for i in range(m + 1):
        for j in range(n + 1):
            out[i, j] = bm[i] * bn[j]
    return out


@_jit
def from_scaled_into(S):
    """In place: a bivariate polynomial in scaled form back to plain Bernstein coefficients (returns ``S``)."""
    m = S.shape[0] - 1
    n = S.shape[1] - 1
    if max(m, n) > TABLED_DEGREE:
        bm = binomial_row(m)
        bn = binomial_row(n)
        for i in range(m + 1):
            for j in range(n + 1):
                S[i, j] /= bm[i] * bn[j]
        return S
    for i in range(m + 1):
        for j in range(n + 1):
            S[i, j] /= BINOMIALS[m, i] * BINOMIALS[n, j]
    return S


@_jit
def evaluate_scaled(c, t):
    """Value at ``t`` of a univariate polynomial given by scaled Bernstein coefficients."""
    n = c.shape[0] - 1
    if t <= 0.5:
        s = t / (1.0 - t)
        acc = c[n]
        for k in range(n - 1, -1, -1):
            acc = acc * s + c[k]
        return acc * (1.0 - t) ** n
    s = (1.0 - t) / t
    acc = c[0]
    for k in range(1, n + 1):
        acc = acc * s + c[k]
    return acc * t ** n


@_jit
def to_scaled(F):
    """Bivariate coefficients times C(m, i) C(n, j): products become convolutions."""
    return F * _binomial_grid(F.shape[0] - 1, F.shape[1] - 1)


@_jit
def from_scaled(S):
    """Inverse of :func:`to_scaled`."""
    return from_scaled_into(S.copy())


@_jit
def scaled_multiply(A, B):
    """Product of two bivariate polynomials given in scaled Bernstein form."""
    ma, na = A.shape[0], A.shape[1]
    mb, nb = B.shape[0], B.shape[1]
    out = np.zeros((ma + mb - 1, na + nb - 1))
    for i1 in range(ma):
        for i2 in range(mb):
            for j1 in range(na):
                a = A[i1, j1]
                if a == 0.0:
                    continue
                for j2 in range(nb):
                    out[i1 + i2, j1 + j2] += a * B[i2, j2]
    return out


@_jit
def bivariate_elevate_t(F, r):
    """Elevate the t-degree of a bivariate polynomial by ``r``."""
    out = np.empty((F.shape[0], F.shape[1] + r))
    for i in range(F.shape[0]):
        copy_into(out[i], elevate(F[i].copy(), r))
    return out
