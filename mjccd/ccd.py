"""Exact continuous collision detection of two moving ellipsoids (thesis ch. 5).

With ``A(t)`` and ``B(t)`` the polynomial quadric matrices of the two moving
ellipsoids (see :mod:`mjccd.motion`), the CCD function is

    F(u, t) = det((1 - u) A(t) + u B(t)),   (u, t) in [0, 1] x [0, 1],

built exactly in bivariate Bernstein form (degree 4 in u).  F < 0 on the
edges u = 0 and u = 1, and at each time t the pair is separate exactly when
``State(t) = max_u F(u, t)`` is positive (touching when it is zero).  Hence

* first contact: starting from a separate time t with ``u* = argmax F(., t)``,
  F(u*, s) > 0 certifies separation for every s up to the first root of the
  univariate polynomial F(u*, .) — a *Bézier shoot*.  Shooting again from
  that root converges quadratically to the contact time (thesis §5.3.3).
* end of an overlap: the zero set of F is searched in time order by
  subdividing boxes of (u, t); a box is discarded when its Bernstein
  coefficients of F are all negative, or when F is negative on one face and
  F_t has the sign that keeps it negative across the box.  The first box that
  cannot be discarded brackets the exit, which is then refined by bisection
  on State.

``first_contact`` and ``collision_intervals`` are the public entry points;
everything below them runs in numba on plain arrays.
"""
import math
from fractions import Fraction
from typing import NamedTuple

import numba
import numpy as np

from mjccd import _validate, exact, exact_stretch
from mjccd import bernstein as bz
from mjccd.errors import InputTypeError
from mjccd.motion import (EPS, Affine, Motion, Rigid, Static, centre_extent, gamma, pose_side_errors, quadric_affine,
                          quadric_at, rigid_scaled_into, translation_scaled_into)
from mjccd.quadric import STATUS_NAMES, Ellipsoid, det4, quartic_max, quartic_max5, quat_to_matrix, touching_point

# compiled on first use and cached; no cfunc wrapper (no kernel is passed around as a first-class function);
# forceinline=False: numba hands a caller's forceinline down to the callees it compiles.  A literal argument
# (0, 1, True) compiles a kernel once per value: call sites pass np.intp(0), np.bool_(True) instead; arrays are
# copied by loops (bernstein.copy_into), never by a slice assignment from an array (see bernstein's _jit)
_jit = numba.njit(cache=True, nogil=True, no_cfunc_wrapper=True, forceinline=False)
# a kernel with one call site in compiled code is typed inside its caller (numba IR inlining): no library of its
# own, which LLVM would optimise and compile again with all its callees (docs/benchmarks.md, "First use");
# also the two tiny heap helpers, and empty_pencil, which its callers give literal degrees (as a kernel of its
# own it compiled once per literal value)
_inline = numba.njit(cache=True, nogil=True, no_cfunc_wrapper=True, forceinline=False, inline="always")

SHOOT_TOL = 1e-15        # relative width at which a Bézier-clipping root is accepted
THIN = 8.0               # a body whose largest radius exceeds its smallest this many times is thin
SHOOT_CONVERGED = 1e-14  # a shoot that advances less than this has reached where F - E meets zero
SECANT_SPAN = 1e-8       # a Newton step past the contact by less than this is finished by one secant step
SHOOT_BAND = 4.0         # a shoot landing where State is within this many bands of zero is at the contact
EXIT_BOX_TOL = 1e-7      # time width at which the overlap search hands over to bisection
MAX_SHOOTS = 4000
MAX_BOXES = 200000
MAX_MARCH = 2000
CERTIFY_ULPS = 64 * 2.220446049250313e-16  # rounding allowance of the exact quartic maximum
MAX_INTERVALS = 100000
TOUCH_SPAN = 1e-6        # time resolution of a tangential contact (the square root of the rounding band)
PIECE_RATIO = 2.0         # a piece of time on which every motion's positive factor varies at most this much
MAX_PIECE_DEPTH = 10
EXACT_PROBES = 64        # probes end * 2^-k (k = 64 .. 1) that look for the first contact of a pair touching at t = 0
# Two unit quaternions that differ by at most this in every component are one orientation.  MuJoCo's
# integration of a free body that does not turn moves its quaternion by about 2 units in the last place
# of 1 per step (e.g. a ball in flight); the turn such a difference stands for (below 4e-15 rad) moves no
# surface point by more than 4e-15 of its distance from the centre, far below the rounding of the inputs.
SAME_ORIENTATION = 8 * 2.220446049250313e-16
EVAL_ROUNDING = 64 * EPS  # relative rounding of evaluating F's rows at a time and of a quartic's maximum
DOUBLE, DOUBLE_TIGHT, RATIONAL = 0, 1, 2  # precision tiers: constant error bound, coefficient-wise bound, exact
TIME_TOL = 1e-9           # an event is certified when its time is this close to both ends of its proven bracket
# half-width of the bracket around a double estimate that the rational tier tries before bisecting to 2^-60: where it
# holds, the estimate is the answer, proven within 9e-16
NEAR_SPAN = 2.0 ** -50
STRETCH_PIECES = 32      # pieces of time a round may take to prove a stretch separate in rationals
SPURIOUS_PIECES = 64     # pieces of time the proof that a doubtful interval holds no contact may take
STRETCH_ROUNDS = 12      # rounds of that proof, each followed by the double solver from its end
HELD_PROBES = 64          # exact statuses an uncertain bracket's end may take to reach a time the pair is not separate


# ---------------------------------------------------------------- building F


@_jit
def _acc(out, x, y, sign):
    """out += sign * x * y for bivariate polynomials in scaled Bernstein form."""
    mx, nx = x.shape
    my, ny = y.shape
    for i1 in range(mx):
        for i2 in range(my):
            for j1 in range(nx):
                a = sign * x[i1, j1]
                for j2 in range(ny):
                    out[i1 + i2, j1 + j2] += a * y[i2, j2]


@_jit
def _dot3_into(out, x0, x1, x2, y0, y1, y2, sign):
    """out += sign * (x0 y0 + x1 y1 + x2 y2) for bivariate polynomials in scaled form.

    The three products share one pass (three multiply-adds per innermost
    step), which runs about twice as fast as three :func:`_acc` calls.
    """
    mx, nx = x0.shape
    my, ny = y0.shape
    for i1 in range(mx):
        for i2 in range(my):
            o = i1 + i2
            for j1 in range(nx):
                a0 = sign * x0[i1, j1]
                a1 = sign * x1[i1, j1]
                a2 = sign * x2[i1, j1]
                for j2 in range(ny):
                    out[o, j1 + j2] += a0 * y0[i2, j2] + a1 * y1[i2, j2] + a2 * y2[i2, j2]


@_jit
def _minor_into(out, x, y, e, g, sign):
    """out += x y + sign e g for four pencil entries (rows: the A and B sides), in scaled form."""
    for j1 in range(x.shape[1]):
        x0 = x[0, j1]
        x1 = x[1, j1]
        e0 = e[0, j1]
        e1 = e[1, j1]
        for j2 in range(y.shape[1]):
            y0 = y[0, j2]
            y1 = y[1, j2]
            g0 = g[0, j2]
            g1 = g[1, j2]
            out[0, j1 + j2] += x0 * y0 + sign * (e0 * g0)
            out[1, j1 + j2] += x0 * y1 + x1 * y0 + sign * (e0 * g1 + e1 * g0)
            out[2, j1 + j2] += x1 * y1 + sign * (e1 * g1)


@_inline
def empty_pencil(p, q, r):
    """Scaled pencil arrays for quadrics of degrees (p, q, r) in (P, U, s): side 0 is A, side 1 is B.

    ``P[i, j, side]``, ``U[i, side]`` and ``s[side]`` hold scaled Bernstein
    coefficients (times their binomials), so that each entry ``P[i, j]`` read as
    a (2, p + 1) array is (1 - u) A_ij(t) + u B_ij(t) in scaled bivariate form.
    """
    return np.empty((3, 3, 2, p + 1)), np.empty((3, 2, q + 1)), np.empty((2, r + 1))


@_jit
def pencil_side_into(P, U, s, Pp, Up, sp, side):
    """A body's (P, U, s) in Bernstein form, elevated and scaled, into one side of the pencil."""
    p = Pp.shape[3] - 1
    q = Up.shape[2] - 1
    r = sp.shape[1] - 1
    bp = bz.binomial_row(p)
    for i in range(3):
        for j in range(3):
            e = bz.elevate(P[i, j].copy(), p + 1 - P.shape[2])
            for a in range(p + 1):
                Pp[i, j, side, a] = e[a] * bp[a]
    bq = bz.binomial_row(q)
    for i in range(3):
        e = bz.elevate(U[i].copy(), q + 1 - U.shape[1])
        for a in range(q + 1):
            Up[i, side, a] = e[a] * bq[a]
    br = bz.binomial_row(r)
    e = bz.elevate(s.copy(), r + 1 - s.shape[0])
    for a in range(r + 1):
        sp[side, a] = e[a] * br[a]


@_jit
def balance_side(Pp, Up, sp, side):
    """Divide one side of the pencil by |det A(0)|^(1/4): both ends of comparable size.

    A(0) is read off the first coefficients (scaled and plain agree there).
    """
    A0 = np.empty((4, 4))
    for i in range(3):
        for j in range(3):
            A0[i, j] = Pp[i, j, side, 0]
        A0[i, 3] = A0[3, i] = Up[i, side, 0]
    A0[3, 3] = sp[side, 0]
    det = det4(A0)
    scale = abs(det) ** 0.25
    if not np.isfinite(scale) or scale == 0.0:
        scale = 0.0
        for i in range(3):
            for j in range(3):
                for a in range(Pp.shape[3]):
                    scale = max(scale, abs(Pp[i, j, side, a]))
    inv = 1.0 / scale
    for i in range(3):
        for j in range(3):
            for a in range(Pp.shape[3]):
                Pp[i, j, side, a] *= inv
        for a in range(Up.shape[2]):
            Up[i, side, a] *= inv
    for a in range(sp.shape[1]):
        sp[side, a] *= inv
    return inv


@_jit
def pencil_quadric_at(Pp, Up, sp, side, t):
    """The 4x4 quadric matrix of one side of the pencil at time t."""
    A = np.empty((4, 4))
    for i in range(3):
        for j in range(3):
            A[i, j] = bz.evaluate_scaled(Pp[i, j, side], t)
        A[i, 3] = A[3, i] = bz.evaluate_scaled(Up[i, side], t)
    A[3, 3] = bz.evaluate_scaled(sp[side], t)
    return A


# adj(P)[i, j] = P[a, b] P[c, d] - P[e, f] P[g, h] for symmetric P, i <= j: rows (i, j, a, b, c, d, e, f, g, h)
_ADJUGATE_TERMS = ((0, 0, 1, 1, 2, 2, 1, 2, 1, 2), (1, 1, 0, 0, 2, 2, 0, 2, 0, 2), (2, 2, 0, 0, 1, 1, 0, 1, 0, 1),
                   (0, 1, 0, 2, 1, 2, 0, 1, 2, 2), (0, 2, 0, 1, 1, 2, 0, 2, 1, 1), (1, 2, 0, 1, 0, 2, 0, 0, 1, 2))


@_inline
def F_from_pencil(Pp, Up, sp):
    """Bernstein coefficients (5, n+1) of F(u, t) = det((1 - u) A(t) + u B(t)) from the scaled pencil."""
    return _pencil_determinant(Pp, Up, sp, -1.0)


@_inline
def F_abs_from_pencil(Pp, Up, sp):
    """The same computation on |entries| with every difference turned into a sum.

    Its coefficients bound the terms that :func:`F_from_pencil` adds up, so
    gamma_K times them bounds that computation's rounding, K the longest
    chain of rounded operations (:func:`error_bound`).
    """
    return _pencil_determinant(np.abs(Pp), np.abs(Up), np.abs(sp), 1.0)


@_jit
def degree_in_t(Pp, Up, sp):
    """Degree in t of the F that :func:`F_from_pencil` builds from this pencil."""
    p, q, r = Pp.shape[3] - 1, Up.shape[2] - 1, sp.shape[1] - 1
    return max(3 * p + r, 2 * p + 2 * q)


@_jit
def _pencil_determinant(Pp, Up, sp, sign):
    """Bernstein coefficients (5, n+1) of F(u, t) = det((1 - u) A(t) + u B(t)) from the scaled pencil.

    Uses ``det [[P, U], [U^T, s]] = s det P - U^T adj(P) U``, which keeps
    every intermediate at its true degree; in the scaled basis every product
    is a plain convolution, and products that are summed share one pass.
    When side 0 has U = 0 (body A centred at the frame origin at every t, see
    :func:`exact_pair`), U = u U_B and the second term is u^2 U_B^T adj(P) U_B:
    rows 2..4 of F, at a third of the cost.  ``sign`` is -1 for F itself and
    +1 for :func:`F_abs_from_pencil`.
    """
    p = Pp.shape[3] - 1
    q = Up.shape[2] - 1
    r = sp.shape[1] - 1
    C = np.zeros((3, 3, 3, 2 * p + 1))  # adj(P), degree (2, 2p): the upper triangle, read symmetrically
    for i, j, a, b, c, d, e, f, g, h in _ADJUGATE_TERMS:
        _minor_into(C[i, j], Pp[a, b], Pp[c, d], Pp[e, f], Pp[g, h], sign)
    detP = np.zeros((4, 3 * p + 1))
    _dot3_into(detP, Pp[0, 0], Pp[0, 1], Pp[0, 2], C[0, 0], C[0, 1], C[0, 2], 1.0)
    n1 = 3 * p + r
    n2 = 2 * p + 2 * q
    n = max(n1, n2)
    F = np.zeros((5, n1 + 1))
    _acc(F, sp, detP, 1.0)
    F2 = F if n1 == n2 else np.zeros((5, n2 + 1))
    a_centred = True
    for i in range(3):
        for a in range(q + 1):
            if Up[i, 0, a] != 0.0:
                a_centred = False
    # with A centred, U = u U_B: one u-row, and the U term lands in rows 2..4 of F
    u_rows = 1 if a_centred else 2
    U = Up[:, 2 - u_rows:]
    V = np.zeros((3, u_rows + 2, 2 * p + q + 1))  # V_i = sum_j adj(P)_ij U_j
    _dot3_into(V[0], U[0], U[1], U[2], C[0, 0], C[0, 1], C[0, 2], 1.0)
    _dot3_into(V[1], U[0], U[1], U[2], C[0, 1], C[1, 1], C[1, 2], 1.0)
    _dot3_into(V[2], U[0], U[1], U[2], C[0, 2], C[1, 2], C[2, 2], 1.0)
    _dot3_into(F2[4 - 2 * u_rows:], U[0], U[1], U[2], V[0], V[1], V[2], sign)
    F = bz.from_scaled_into(F)
    if n1 == n2:
        return F
    F2 = bz.from_scaled_into(F2)
    if n1 < n:
        F = bz.bivariate_elevate_t(F, n - n1)
    else:
        F2 = bz.bivariate_elevate_t(F2, n - n2)
    return F + F2


# ---------------------------------------------------------------- rounding bounds
#
# Every decision of the solver is taken on F with E, a bound of the errors of
# F's Bernstein coefficients, so that it holds for the exact F of the inputs.
# E has two parts: the pencil entries' own construction errors (bounded by the
# builder of each quadric, as a symmetric 4x4 matrix of bounds per side, in
# units of plain Bernstein coefficients) carried through the determinant, and
# the rounding of F_from_pencil itself: a straight-line program of sums and
# products whose error is at most gamma_K times the same program run on
# absolute values (F_abs_from_pencil), K its longest chain of roundings.


_PERMUTATIONS = ((0, 1, 2, 3), (0, 1, 3, 2), (0, 2, 1, 3), (0, 2, 3, 1), (0, 3, 1, 2), (0, 3, 2, 1),
                 (1, 0, 2, 3), (1, 0, 3, 2), (1, 2, 0, 3), (1, 2, 3, 0), (1, 3, 0, 2), (1, 3, 2, 0),
                 (2, 0, 1, 3), (2, 0, 3, 1), (2, 1, 0, 3), (2, 1, 3, 0), (2, 3, 0, 1), (2, 3, 1, 0),
                 (3, 0, 1, 2), (3, 0, 2, 1), (3, 1, 0, 2), (3, 1, 2, 0), (3, 2, 0, 1), (3, 2, 1, 0))


@_jit
def _entry_maxima(Pp, Up, sp):
    """Largest |plain Bernstein coefficient| of each entry of the 4x4 pencil, over both sides."""
    p = Pp.shape[3] - 1
    q = Up.shape[2] - 1
    r = sp.shape[1] - 1
    bp, bq, br = bz.binomial_row(p), bz.binomial_row(q), bz.binomial_row(r)  # the values of bz.binomial
    M = np.zeros((4, 4))
    for side in range(2):  # each maximum kept in a local: twice as fast as updating M in place
        for i in range(3):
            for j in range(i, 3):
                m = M[i, j]
                for a in range(p + 1):
                    m = max(m, abs(Pp[i, j, side, a]) / bp[a])
                M[i, j] = m
            m = M[i, 3]
            for a in range(q + 1):
                m = max(m, abs(Up[i, side, a]) / bq[a])
            M[i, 3] = m
        m = M[3, 3]
        for a in range(r + 1):
            m = max(m, abs(sp[side, a]) / br[a])
        M[3, 3] = m
    # every division (and an untabled binomial's product of 2k roundings) rounded up; the matrix symmetric
    n = max(p, q, r)
    slack = 1.0 + 4.0 * EPS if n <= bz.TABLED_DEGREE else 1.0 + (4.0 * n + 4.0) * EPS
    for i in range(4):
        for j in range(i, 4):
            M[i, j] *= slack
            M[j, i] = M[i, j]
    return M


@_jit
def _chain_length(Pp, Up, sp):
    """K: an upper bound of the number of roundings along any path of F_from_pencil (and of its elevation)."""
    p = Pp.shape[3] - 1
    q = Up.shape[2] - 1
    r = sp.shape[1] - 1
    return 8.0 * (2 * p + 2 * q + r + 10)


@_jit
def entry_errors_balanced(err, inv, M):
    """The entries' error bounds after :func:`balance_side` multiplied side s by inv[s] (one more rounding)."""
    out = np.empty((4, 4))
    for i in range(4):
        for j in range(4):
            out[i, j] = max(err[0, i, j] * inv[0], err[1, i, j] * inv[1]) * (1.0 + 2.0 * EPS) + EPS * M[i, j]
    return out


@_jit
def error_bound_global(F, Pp, Up, sp, D, M):
    """E as one constant: a bound of every coefficient's error from maxima alone (cheap).

    With M the entries' coefficient maxima (:func:`_entry_maxima`) and D their error bounds, every
    coefficient of F_abs is at most perm(M) and the entries' errors move F by
    at most perm(M + D) - perm(M) (each term of the permanent is a product of
    four entries, and Bernstein products are convex combinations).
    """
    perm = 0.0
    delta = 0.0
    for pi in _PERMUTATIONS:
        term = 1.0
        for i in range(4):
            term *= M[i, pi[i]] + D[i, pi[i]]
        perm += term
        for k in range(4):  # prod(M + D) - prod(M) <= sum_k D_k prod_{j != k} (M + D)_j
            part = D[k, pi[k]]
            for i in range(4):
                if i != k:
                    part *= M[i, pi[i]] + D[i, pi[i]]
            delta += part
    K = _chain_length(Pp, Up, sp)
    n = F.shape[1] - 1
    fmax = 0.0
    for i in range(F.shape[0]):
        for j in range(F.shape[1]):
            fmax = max(fmax, abs(F[i, j]))
    value = (delta + gamma(K) * perm) * (1.0 + 64.0 * EPS) + gamma(4 * n + 40) * fmax
    return np.full(F.shape, value)


@_inline
def error_bound_tight(F, Pp, Up, sp, D):
    """E coefficient by coefficient: F_abs of the entries widened by their error bounds, minus F_abs."""
    p = Pp.shape[3] - 1
    q = Up.shape[2] - 1
    r = sp.shape[1] - 1
    bp, bq, br = bz.binomial_row(p), bz.binomial_row(q), bz.binomial_row(r)
    Pw = np.abs(Pp)
    Uw = np.abs(Up)
    sw = np.abs(sp)
    for side in range(2):
        for i in range(3):
            for j in range(3):
                for a in range(p + 1):
                    Pw[i, j, side, a] += D[i, j] * bp[a]
            for a in range(q + 1):
                Uw[i, side, a] += D[i, 3] * bq[a]
        for a in range(r + 1):
            sw[side, a] += D[3, 3] * br[a]
    wide = _pencil_determinant(Pw, Uw, sw, 1.0)
    plain = F_abs_from_pencil(Pp, Up, sp)
    K = _chain_length(Pp, Up, sp)
    n = F.shape[1] - 1
    extra = gamma(4 * n + 40) * np.abs(F).max()
    return (wide - plain) * (1.0 + 4.0 * EPS) + 3.0 * gamma(K) * wide + extra


# ---------------------------------------------------------------- state


@_jit
def _rows_at(F, t):
    """F(., t) as five Bernstein coefficients in u: the five rows evaluated in one Horner pass."""
    n = F.shape[1] - 1
    if t == 0.0 or t == 1.0:
        end = 0 if t == 0.0 else n
        return F[0, end], F[1, end], F[2, end], F[3, end], F[4, end]
    if n > bz.TABLED_DEGREE:
        return (bz.evaluate_row(F, np.intp(0), t), bz.evaluate_row(F, np.intp(1), t),
                bz.evaluate_row(F, np.intp(2), t), bz.evaluate_row(F, np.intp(3), t),
                bz.evaluate_row(F, np.intp(4), t))
    flip = t > 0.5
    s = (1.0 - t) / t if flip else t / (1.0 - t)
    end = 0 if flip else n
    r0, r1, r2, r3, r4 = F[0, end], F[1, end], F[2, end], F[3, end], F[4, end]
    for k in range(n - 1, -1, -1):
        b = bz.BINOMIALS[n, k]
        j = n - k if flip else k
        r0 = r0 * s + b * F[0, j]
        r1 = r1 * s + b * F[1, j]
        r2 = r2 * s + b * F[2, j]
        r3 = r3 * s + b * F[3, j]
        r4 = r4 * s + b * F[4, j]
    w = (t if flip else 1.0 - t) ** n
    return r0 * w, r1 * w, r2 * w, r3 * w, r4 * w


@_jit
def state(F, t):
    """max_u F(u, t) and its argmax (F is quartic in u)."""
    g0, g1, g2, g3, g4 = _rows_at(F, t)
    return quartic_max5(g0, g1, g2, g3, g4)


@_jit
def _quartic_at(g0, g1, g2, g3, g4, u):
    """Value at u of the quartic with Bernstein coefficients g0..g4."""
    v = 1.0 - u
    return (v * v * v * v * g0 + 4.0 * u * v * v * v * g1 + 6.0 * u * u * v * v * g2
            + 4.0 * u * u * u * v * g3 + u * u * u * u * g4)


@_jit
def status_at(F, E, t):
    """:func:`status_with` with E's largest coefficient taken here."""
    return status_with(F, E, E.max(), t)


@_jit
def status_with(F, E, emax, t):
    """(status code, max_u F, argmax) at time t, decided with E, the bound of F's coefficient errors.

    1 (separate) when F - E > 0 at the argmax, so the true State is positive;
    -1 (overlapping) when F + E < 0 for every u; 0 when neither holds: the
    pair touches, or is closer to touching than the rounding can resolve.
    E already holds the rounding of these evaluations (:func:`error_bound_global`); ``emax`` is
    its largest coefficient, which decides most times without evaluating E.
    """
    g0, g1, g2, g3, g4 = _rows_at(F, t)
    gmax, u = quartic_max5(g0, g1, g2, g3, g4)
    if gmax > emax:
        return 1, gmax, u
    if gmax < -emax:
        return -1, gmax, u
    e0, e1, e2, e3, e4 = _rows_at(E, t)
    if gmax > _quartic_at(e0, e1, e2, e3, e4, u):
        return 1, gmax, u
    upper, _ = quartic_max5(g0 + e0, g1 + e1, g2 + e2, g3 + e3, g4 + e4)
    if upper < 0.0:
        return -1, gmax, u
    return 0, gmax, u


# ---------------------------------------------------------------- first contact


@_jit
def shoot_first_contact(F, E, t_start, t_max, u):
    """Earliest contact in [t_start, t_max] by recursive Bézier shoots.

    Requires the pair to be separate at t_start, where State's argmax is ``u``.  Returns (time, u, lower,
    certified): where the shoots stopped (State inside the rounding band),
    the argmax there, and ``lower``, up to which separation is proven: each shoot
    follows F(u*, .) - E(u*, .), a lower bound of the true F(u*, .), so the
    true first contact is at or after ``lower``.  Time -1 when separation is
    proven over the whole interval.  When the shoots run out (MAX_SHOOTS),
    ``certified`` is False and the first contact, if any, lies in [lower, t_max].
    """
    emax = E.max()
    t = t_start
    h = np.empty(F.shape[1])
    uniform = E.min() == emax  # the constant bound: E(u, .) is that constant
    e = h if uniform else np.empty(F.shape[1])
    for _ in range(MAX_SHOOTS):
        if t >= t_max:
            break
        bz.bivariate_at_u_into(F, u, h)
        if uniform:
            h -= E[0, 0]
        else:
            bz.bivariate_at_u_into(E, u, e)
            h -= e
        bz.restrict_into(h, t, t_max)
        if not h[0] > 0.0:  # F - E has come down to zero: the bound can prove no more, the contact is near
            return t, u, t, True
        r = -1.0 if h.min() > 0.0 else bz.first_root(h, SHOOT_TOL)
        if r < 0.0:
            break
        t_new = t + r * (t_max - t)
        code, gmax, u_new = status_with(F, E, emax, t_new)
        # at the band's edge, the shoots no longer advance, or (constant bound) within a few bands of it
        if code != 1 or t_new - t <= SHOOT_CONVERGED or (uniform and gmax <= SHOOT_BAND * emax):
            return t_new, u_new, t_new, True
        t, u = t_new, u_new
    else:
        return t, u, t, False
    # certified separate up to t_max; a touch exactly at t_max still counts
    code, _, u_end = status_with(F, E, emax, t_max)
    if code != 1:
        return t_max, u_end, t_max, True
    return -1.0, 0.0, t_max, True


@_jit
def _state_and_slope(F, t, h):
    """(max_u F(u, t), its argmax u, dF(u, .)/dt at t): ``h`` is a buffer of F's row length."""
    gmax, u = state(F, t)
    bz.bivariate_at_u_into(F, u, h)
    _, slope = bz.value_and_slope(h, t)
    return gmax, u, slope


@_jit
def _entry_upper(F, E, t_c, lower, t_max, gmax, slope):
    """The upper end of the bracket of a contact estimated at t_c (proven separate before ``lower``).

    ``gmax`` and ``slope``: State and its slope at t_c (:func:`_state_and_slope`).
    The first probe t_c + w 2^k (w from State's slope at t_c) that is proven overlapping:
    the contact lies in [lower, probe]; or the first proven separate again
    after probes inside the rounding band: the pair stayed inside the band in
    between (a touch, or a miss by less than the rounding), and [lower, probe]
    is where a contact may be.  The shoots stop near the band's edge, so the first probes may still be
    separate.  Returns (probe, computed State there); t_max when no probe is decided (touching to the end).
    """
    emax = E.max()
    # first probe: where State, going down at this slope, would be 2 emax below zero
    w = max(t_c - lower, (gmax + 2.0 * emax) / -slope if slope < 0.0 else 0.0, 1e-16)
    t = t_c
    lowest = np.inf
    while t < t_max:
        t = min(t_c + w, t_max)
        code, gmax, _ = status_with(F, E, emax, t)
        if code == -1:
            return t, gmax
        lowest = min(lowest, gmax)
        # separate again: State has risen by more than its rounding since its lowest probe (a graze), or the
        # probes never went inside the band (the bracket stays wide)
        if code == 1 and (gmax > lowest + 2.0 * emax or w > TOUCH_SPAN):
            return t, gmax
        w *= 2.0
    return t_max, state(F, t_max)[0]


@_jit
def _entry_estimate(F, E, t_c, lower, t_max):
    """(estimate, upper end of the bracket) of a contact where the shoots stopped at t_c: the estimate is
    the zero of the computed State inside [lower, upper] when it changes sign there, else t_c."""
    h = np.empty(F.shape[1])
    gmax, u, slope = _state_and_slope(F, t_c, h)
    upper, at_upper = _entry_upper(F, E, t_c, lower, t_max, gmax, slope)
    if upper > t_c and gmax > 0.0:
        if at_upper < 0.0:
            t = _zero_of_state(F, t_c, upper, gmax, slope, h)
            return t, _tighter_upper(F, E, t, upper)
        if at_upper == 0.0:  # e.g. a touch exactly at t_max
            return upper, upper
    return t_c, upper


@_inline
def _tighter_upper(F, E, t, upper):
    """A proven-overlapping time closer to the estimate t than ``upper`` (which is proven overlapping), when
    the bracket is too wide for TIME_TOL: bisection on the overlapping status down towards t."""
    emax = E.max()
    for _ in range(40):
        if upper - t <= 0.5 * TIME_TOL:
            break
        mid = 0.5 * (t + upper)
        if status_with(F, E, emax, mid)[0] != -1:
            break
        upper = mid
    return upper


@_jit
def _zero_of_state(F, lo, hi, gmax, slope, h):
    """The zero of the computed State in [lo, hi] (State ``gmax`` > 0 at lo, with ``slope``; < 0 at hi).

    Newton's steps on F(u*, .) from lo, which converge quadratically at a
    regular contact; a step that lands past the zero within SECANT_SPAN is
    finished by one secant step between the last two iterates (its error is
    of the order of that width squared); regula falsi when a step leaves the
    bracket.  ``h``: a buffer of F's row length.
    """
    t = lo
    for it in range(8):
        if it > 0:
            g, _, slope = _state_and_slope(F, t, h)
            if g <= 0.0:
                if t - lo <= SECANT_SPAN:
                    return lo + (t - lo) * gmax / (gmax - g)
                hi = t
                break
            lo, gmax = t, g
        if not slope < 0.0:
            break
        step = -gmax / slope
        if not t + step < hi:
            break
        t += step
        if step <= 4.0 * EPS * t:
            return t
    return _bisect_sign(F, lo, hi, np.bool_(False))


# ---------------------------------------------------------------- end of an overlap


@_jit
def _bisect_sign(F, lo, hi, rising):
    """Zero of State between lo and hi (State < 0 at lo when ``rising``, > 0 otherwise).

    Regula falsi with the Illinois modification on State itself, which keeps
    the bracket and converges superlinearly; a plain halving step is taken
    whenever the bracket fails to halve.
    """
    sign = 1.0 if rising else -1.0
    f_lo = sign * state(F, lo)[0]
    f_hi = sign * state(F, hi)[0]
    side = 0
    for it in range(200):
        width = hi - lo
        if width <= 4.0 * 2.220446049250313e-16 * max(1.0, abs(hi)):
            break
        mid = 0.5 * (lo + hi)
        if it % 4 != 3 and f_hi > f_lo:
            guess = hi - f_hi * width / (f_hi - f_lo)
            if lo < guess < hi:
                mid = guess
        gmax, _ = state(F, mid)
        if (gmax >= 0.0) == rising:
            hi, f_hi = mid, sign * gmax
            if side == 1:
                f_lo *= 0.5
            side = 1
        else:
            lo, f_lo = mid, sign * gmax
            if side == -1:
                f_hi *= 0.5
            side = -1
    return 0.5 * (lo + hi)


@_jit
def _third_derivative_bounds(F, out):
    """Per row of ``F``: an upper bound (>= 0) of its third t-derivative on [0, 1], into ``out``.

    The third differences of the coefficients times n (n - 1) (n - 2) are the
    Bernstein coefficients of that derivative, which bound it; each is widened
    by the rounding of the differences.  (Restricted to the march's own
    interval they would be tighter, at the cost of a subdivision per row: on
    close pairs the march is faster without it.)
    """
    rows = F.shape[0]
    n = F.shape[1] - 1
    if n < 3:
        out[:] = 0.0
        return
    scale = n * (n - 1) * (n - 2) * 1.0
    for i in range(rows):
        top = -np.inf
        size = 0.0
        for j in range(n - 2):
            top = max(top, F[i, j + 3] - 3.0 * F[i, j + 2] + 3.0 * F[i, j + 1] - F[i, j])
        for j in range(n + 1):
            size = max(size, abs(F[i, j]))
        out[i] = max((top + 8.0 * gamma(8) * size) * scale, 0.0)


@_jit
def _quartic_model(g, d, c, M3, u, h):
    """At one u: sum_i B_i(u) (g_i + h d_i + h^2 / 2 max(c_i + h M3_i, 0)), the march's bound (see
    :func:`_march_exit`)."""
    v = 1.0 - u
    b0 = v * v * v * v
    b1 = 4.0 * u * v * v * v
    b2 = 6.0 * u * u * v * v
    b3 = 4.0 * u * u * u * v
    b4 = u * u * u * u
    hh = 0.5 * h * h
    return (b0 * (g[0] + h * d[0] + hh * max(c[0] + h * M3[0], 0.0))
            + b1 * (g[1] + h * d[1] + hh * max(c[1] + h * M3[1], 0.0))
            + b2 * (g[2] + h * d[2] + hh * max(c[2] + h * M3[2], 0.0))
            + b3 * (g[3] + h * d[3] + hh * max(c[3] + h * M3[3], 0.0))
            + b4 * (g[4] + h * d[4] + hh * max(c[4] + h * M3[4], 0.0)))


@_jit
def _predicted_step(g, d, c, M3, u, margin, room):
    """The largest step within ``room`` (to about 1 %) that the march's bound proves at the single u: an
    estimate of the step it proves for every u, which :func:`_march_exit` then checks."""
    if _quartic_model(g, d, c, M3, u, room) < -margin:
        return room
    h = room
    for _ in range(80):
        h *= 0.5
        if _quartic_model(g, d, c, M3, u, h) < -margin:
            break
    lo, hi = h, 2.0 * h
    for _ in range(7):
        mid = 0.5 * (lo + hi)
        if _quartic_model(g, d, c, M3, u, mid) < -margin:
            lo = mid
        else:
            hi = mid
    return lo


@_jit
def _march_exit(F, t_start, t_end):
    """Certified march through an overlap of F (an upper bound of the true F, 5 rows in u): returns (exit time
    or 2.0 for none, or -1.0; time reached).

    From a time a with State(a) < 0 it steps by h where, for every u,
        sum_i B_i(u) [g_i + h d_i + h^2 / 2 max(c_i + h M_i, 0)] < 0,
    with g_i, d_i, c_i the value, slope and curvature at a of row i of F (its
    Bernstein coefficient in u, a polynomial in t) and M_i >= 0 an upper
    bound of that row's third derivative (:func:`_third_derivative_bounds`).
    By Taylor's theorem the bracket bounds row i on [a, a + h]; it is convex
    in the step, so with B_i(u) >= 0 its value at h and State(a) < 0 prove
    F < 0 on [a, a + h] for every u.  The maximum over u of that quartic is
    exact (:func:`mjccd.quadric.quartic_max5`), and a margin covers the
    rounding of the rows.  The step tried is the largest the bound allows at
    the u where the last one was tightest (:func:`_predicted_step`), shrunk
    until proven.  Near an exit the steps converge quadratically onto it;
    once it is within EXIT_BOX_TOL, it is the zero of State there
    (:func:`_rising_zero`).  When the steps stall short of a time where
    State >= 0 it returns -1 and the time reached, for the box search to go
    on from there.
    """
    rows = F.shape[0]
    if t_end <= t_start:
        return 2.0, t_end
    Ft = bz.bivariate_derivative_t(F)
    Ftt = bz.bivariate_derivative_t(Ft)
    size = 0.0  # slopes and curvatures at a are rounded relative to their coefficients
    for i in range(rows):
        for j in range(Ft.shape[1]):
            size = max(size, abs(Ft[i, j]))
        for j in range(Ftt.shape[1]):
            size = max(size, abs(Ftt[i, j]))
    M3 = np.empty(rows)
    _third_derivative_bounds(F, M3)
    g = np.empty(rows)
    d = np.empty(rows)
    c = np.empty(rows)
    r = np.empty(rows)
    a = t_start
    u = -1.0
    for _ in range(MAX_MARCH):
        if a >= t_end:
            return 2.0, t_end
        g[0], g[1], g[2], g[3], g[4] = _rows_at(F, a)
        d[0], d[1], d[2], d[3], d[4] = _rows_at(Ft, a)
        c[0], c[1], c[2], c[3], c[4] = _rows_at(Ftt, a)
        margin = 0.0
        for i in range(rows):
            margin = max(margin, abs(g[i]) + abs(d[i]) + abs(c[i]) + M3[i])
        margin = EVAL_ROUNDING * (margin + size)  # rounding of the rows and of the quartic's maximum
        if u < 0.0:
            _, u = quartic_max5(g[0], g[1], g[2], g[3], g[4])
        room = t_end - a
        h = _predicted_step(g, d, c, M3, u, margin, room)
        h = room if h >= room else 0.95 * h
        proven = False
        while h >= 1e-3 * EXIT_BOX_TOL:
            for i in range(rows):
                r[i] = g[i] + h * d[i] + 0.5 * h * h * max(c[i] + h * M3[i], 0.0)
            bmax, u = quartic_max5(r[0], r[1], r[2], r[3], r[4])
            if bmax < -margin:
                proven = True
                break
            h *= 0.7
        # a step shorter than EXIT_BOX_TOL is taken only while State is still negative that far ahead
        if not proven or (h < EXIT_BOX_TOL and state(F, min(a + EXIT_BOX_TOL, t_end))[0] >= 0.0):
            break
        a = t_end if h >= room else a + h
    else:
        return -1.0, a
    tb = min(a + EXIT_BOX_TOL, t_end)
    gmax, _ = state(F, tb)
    if gmax >= 0.0:
        return _rising_zero(F, a, tb), tb
    return -1.0, a


# search_exit's boxes live in a pool of preallocated coefficient slots sized by this budget (bytes); the
# slot of a popped box is recycled, so the search runs in bounded memory whatever the degree of F
EXIT_POOL_BYTES = 32 * 1024 * 1024


@_jit
def _exit_capacity(rows, cols, max_pops):
    """Box slots of search_exit's pool: EXIT_POOL_BYTES of coefficients, and no more than can be live.

    Each pop adds at most one live box (a split replaces one box by two), so
    after ``max_pops`` pops at most ``max_pops + 1`` are live.
    """
    return max(2, min(EXIT_POOL_BYTES // (8 * rows * cols), max_pops + 2))


@_inline
def _exit_heap_before(ht, hq, k, t, seq):
    """Entry k of search_exit's heap comes before (t, seq): the order of heapq on (t, index of creation)."""
    return ht[k] < t or (ht[k] == t and hq[k] < seq)


@_inline
def _exit_heap_put(ht, hq, hs, k, t, seq, slot):
    """Entry k of search_exit's heap := (t, seq, slot)."""
    ht[k] = t
    hq[k] = seq
    hs[k] = slot


@_jit
def _exit_heap_push(ht, hq, hs, nh, t, seq, slot):
    """Push (start time t, creation number seq, pool slot) on search_exit's heap of nh entries; returns nh + 1.

    The order is (t, seq), as heapq orders the tuples (t, index of creation).
    """
    k = nh
    while k > 0:
        p = (k - 1) >> 1
        if _exit_heap_before(ht, hq, p, t, seq):
            break
        _exit_heap_put(ht, hq, hs, k, ht[p], hq[p], hs[p])
        k = p
    _exit_heap_put(ht, hq, hs, k, t, seq, slot)
    return nh + 1


@_jit
def _exit_heap_pop(ht, hq, hs, nh):
    """Drop the root of search_exit's heap of nh entries (read it first); returns nh - 1."""
    nh -= 1
    t = ht[nh]
    seq = hq[nh]
    slot = hs[nh]
    k = 0
    while True:
        c = 2 * k + 1
        if c >= nh:
            break
        if c + 1 < nh and _exit_heap_before(ht, hq, c + 1, ht[c], hq[c]):
            c += 1
        if not _exit_heap_before(ht, hq, c, t, seq):
            break
        _exit_heap_put(ht, hq, hs, k, ht[c], hq[c], hs[c])
        k = c
    _exit_heap_put(ht, hq, hs, k, t, seq, slot)
    return nh


@_jit
def _exit_box_negative(C):
    """True when F < 0 on the box of coefficients C (quartic in u by degree n in t).

    F(u, t) <= sum_i (max_j C[i, j]) B_i(u) for every t in the box, and the
    maximum over u of that quartic is taken exactly, so no split in u is
    needed where F is negative at every time but close to zero at one u.
    """
    cmax = C.max()
    if cmax < 0.0:
        return True
    r0 = C[0].max()
    r1 = C[1].max()
    r2 = C[2].max()
    r3 = C[3].max()
    r4 = C[4].max()
    gmax, _ = quartic_max5(r0, r1, r2, r3, r4)
    return gmax < -CERTIFY_ULPS * max(cmax, -C.min())


@_jit
def _exit_split_t_into(work, low, high):
    """De Casteljau at t = 1/2 on every row of ``work`` (destroyed): [t0, tm] into low, [tm, t1] into high."""
    n = work.shape[1] - 1
    for k in range(work.shape[0]):
        w = work[k]
        lo = low[k]
        hi = high[k]
        lo[0] = w[0]
        hi[n] = w[n]
        for r in range(1, n + 1):
            for i in range(n - r + 1):
                w[i] = 0.5 * w[i] + 0.5 * w[i + 1]
            lo[r] = w[0]
            hi[n - r] = w[n - r]


@_jit
def _exit_split_u_into(work, low, high):
    """The box ``work`` (destroyed) halved in u into low and high: de Casteljau at u = 1/2 on all columns."""
    m = work.shape[0] - 1
    bz.copy_into(low[0], work[0])
    bz.copy_into(high[m], work[m])
    for r in range(1, m + 1):
        for i in range(m - r + 1):
            for j in range(work.shape[1]):
                work[i, j] = 0.5 * (work[i, j] + work[i + 1, j])
        bz.copy_into(low[r], work[0])
        bz.copy_into(high[m - r], work[m - r])


@_jit
def _exit_box_search(F, t_start, t_end, capacity, max_pops):
    """The box search of :func:`search_exit` from t_start in a pool of ``capacity`` boxes.

    Returns (t, certified, peak number of live boxes); (t, certified) as
    search_exit.  Boxes are slots of one preallocated (capacity, 5, n + 1)
    array with their end times; the heap holds (start time, creation number,
    slot) of the live ones, so it never holds more than ``capacity``
    entries.  A discarded box's slot goes to a free list, a clipped box stays
    in its slot, and a split box keeps its first half in its slot and puts the
    second in a free one.  The search stops uncertified when the ``max_pops``-th
    pop is not discarded or a split finds no free slot; the popped box has the
    earliest start of all live boxes, so every time before it is certified.
    """
    rows, cols = F.shape
    capacity = max(capacity, 1)
    pool = np.empty((capacity, rows, cols))
    ends = np.empty(capacity)
    free = np.empty(capacity, np.int64)
    ht = np.empty(capacity)
    hq = np.empty(capacity, np.int64)
    hs = np.empty(capacity, np.int64)
    work = np.empty((rows, cols))
    upper = np.empty(cols)
    for i in range(rows):
        bz.copy_into(pool[0, i], F[i])
        bz.restrict_into(pool[0, i], t_start, t_end)
    ends[0] = t_end
    top = 1  # slots below top have been used; those free since are in free[:nfree]
    nfree = 0
    seq = np.intp(0)
    nh = _exit_heap_push(ht, hq, hs, np.intp(0), t_start, seq, np.intp(0))
    peak = 1
    count = 0
    while nh > 0:
        t0 = ht[0]
        s = hs[0]
        nh = _exit_heap_pop(ht, hq, hs, nh)
        C = pool[s]
        t1 = ends[s]
        count += 1
        if _exit_box_negative(C):
            free[nfree] = s
            nfree += 1
            continue
        if count > max_pops:
            return t0, False, peak
        width = t1 - t0
        # Bézier clipping in t: F(u, t) <= sum_j max_i C[i, j] B_j(t), so when that
        # column-wise upper bound starts negative, F < 0 up to its first root.
        for j in range(cols):
            c = C[0, j]
            for i in range(1, rows):
                c = max(c, C[i, j])
            upper[j] = c
        r = 0.0
        if upper[0] < 0.0:
            r = bz.first_root(upper, 1e-12)
            if r < 0.0:  # the bound never reaches zero: F < 0 on the whole box
                free[nfree] = s
                nfree += 1
                continue
        if r > 0.05 and width > EXIT_BOX_TOL:  # the clipped box stays in its slot
            for i in range(rows):
                bz.restrict_into(C[i], r, 1.0)
            seq += 1
            nh = _exit_heap_push(ht, hq, hs, nh, t0 + r * width, seq, s)
            continue
        if width <= EXIT_BOX_TOL:
            gmax, _ = state(F, t1)
            if gmax >= 0.0:
                return _bisect_sign(F, t0, t1, np.bool_(True)), True, peak
            free[nfree] = s
            nfree += 1
            continue
        if nfree > 0:
            nfree -= 1
            b = free[nfree]
        elif top < capacity:
            b = top
            top += 1
        else:  # pool full
            return t0, False, peak
        span_t = 0.0
        span_u = 0.0
        for i in range(rows):
            span_t = max(span_t, C[i].max() - C[i].min())
        for j in range(cols):
            lo = hi = C[0, j]
            for i in range(1, rows):
                lo = min(lo, C[i, j])
                hi = max(hi, C[i, j])
            span_u = max(span_u, hi - lo)
        for i in range(rows):
            bz.copy_into(work[i], C[i])
        if span_t >= span_u:  # halve the wider direction: t (first half ends at tm) or u
            _exit_split_t_into(work, C, pool[b])
            a_end = b_start = 0.5 * (t0 + t1)
        else:
            _exit_split_u_into(work, C, pool[b])
            a_end, b_start = t1, t0
        ends[s] = a_end
        ends[b] = t1
        seq += 1
        nh = _exit_heap_push(ht, hq, hs, nh, t0, seq, s)
        seq += 1
        nh = _exit_heap_push(ht, hq, hs, nh, b_start, seq, b)
        peak = max(peak, nh)
    return 2.0, True, peak


@_inline
def _search_exit_pool(F, E, t_start, t_end, capacity, max_pops):
    """:func:`search_exit` with the pool's capacity and the pop limit as arguments: (t, certified, peak live boxes).

    Both searches run on F + E, an upper bound of the true F: the time they
    return is a lower bound of the true exit.
    """
    upper = F + E
    t_exit, reached = _march_exit(upper, t_start, t_end)
    if t_exit >= 0.0:
        return t_exit, True, 0
    return _exit_box_search(upper, reached, t_end, capacity, max_pops)


@_inline
def search_exit(F, E, t_start, t_end):
    """End of the overlap that holds at t_start, within [t_start, t_end]: (t, certified).

    Requires the pair to overlap at t_start.  The certified march
    (:func:`_march_exit`) goes first; where it stalls, a box search takes
    over: boxes of (u, t) are taken in order of their start time, so
    everything before the popped box is certified negative.  The boxes live
    in a recycled pool of at most EXIT_POOL_BYTES (:func:`_exit_box_search`).

    The search runs on F + E, so every discarded box is overlapping for the
    true F, and the returned time is a lower bound of the true exit.
    certified True: t is that time, or 2.0 when the pair overlaps through t_end.  certified False: a limit (the pool
    full, or MAX_BOXES pops) stopped the search; the pair is certified
    overlapping on [t_start, t) and the exit, if any, lies in [t, t_end].
    """
    rows, cols = F.shape
    max_pops = np.intp(MAX_BOXES)  # a module constant would be passed as a literal: a specialisation of its own
    t, certified, _ = _search_exit_pool(F, E, t_start, t_end, _exit_capacity(rows, cols, max_pops), max_pops)
    return t, certified


@_inline
def _step_off(F, E, t, t_end, first):
    """Status just after a contact instant t: the first decided probe t + first * 2^k.

    Returns (probe, status code, last undecided probe).  A pair whose State
    stays inside the rounding band is touching (no clearance or penetration
    a double can show), so the probes go on doubling past the tangential
    resolution (1e-6) until one is decided or t_end is reached (code 0): a
    stretch of touching, e.g. two bodies that touch for the whole step.
    ``first``: the first offset, 1e-13 unless the band is known to reach further.
    """
    emax = E.max()
    eps = first
    last = t
    while True:
        tp = min(t + eps, t_end)
        code, _, _ = status_with(F, E, emax, tp)
        if code != 0 or tp >= t_end:
            return tp, code, last
        last = tp
        eps *= 2.0


@_jit
def _probe_after_exit(F, E, emax, t, t_end):
    """:func:`_step_off` after an overlap's end t: (probe, status code, last undecided probe).

    State rises through the rounding band there; Newton's steps on State
    minus the bound at the argmax (where :func:`status_with` decides
    separate) put a probe just past the band's end, so the exit's bracket is
    about as narrow as the band; probes doubling from 1e-13 overshoot it by up
    to twice.  Where those steps do not land on a decided probe, the doubling
    probes take over from the last one.
    """
    h = np.empty(F.shape[1])
    x = t
    for _ in range(4):
        gmax, u, slope = _state_and_slope(F, x, h)
        e0, e1, e2, e3, e4 = _rows_at(E, x)
        bound = _quartic_at(e0, e1, e2, e3, e4, u)
        if not slope > 0.0:
            break
        probe = min(x + 1.05 * max(bound - gmax, 0.0) / slope + 4.0 * EPS * max(1.0, abs(x)), t_end)
        code, _, _ = status_with(F, E, emax, probe)
        if code != 0 or probe >= t_end:
            return probe, code, x
        x = probe
    return _step_off(F, E, t, t_end, max(1e-13, x - t))


@_jit
def _rising_zero(F, lo, hi):
    """The zero of State in [lo, hi] where it rises (State(lo) < 0 <= State(hi)), to a few units in the last place.

    Newton's steps on State (its slope is F_t at the argmax, see
    :func:`_state_and_slope`), kept inside the bracket that each value
    narrows: a step that leaves it is replaced by its midpoint.  They
    converge quadratically at a regular exit, where halving would take some
    forty evaluations.
    """
    h = np.empty(F.shape[1])
    t = lo
    gmax, _, slope = _state_and_slope(F, t, h)
    for _ in range(100):
        if hi - lo <= 4.0 * EPS * max(1.0, abs(hi)):
            return 0.5 * (lo + hi)
        step = -gmax / slope if slope > 0.0 else np.inf
        if abs(step) <= 2.0 * EPS * max(1.0, abs(t)):
            return t
        nxt = t + step
        if not lo < nxt < hi:
            nxt = 0.5 * (lo + hi)
        t = nxt
        gmax, _, slope = _state_and_slope(F, t, h)
        if gmax >= 0.0:
            hi = t
        else:
            lo = t
    return t


@_inline
def _end_of_touch(F, E, lo, hi):
    """Last touching time between ``lo`` (touching) and ``hi`` (separate): bisection on the decided status."""
    emax = E.max()
    for _ in range(60):
        if hi - lo <= 4.0 * 2.220446049250313e-16 * max(1.0, hi):
            break
        mid = 0.5 * (lo + hi)
        code, _, _ = status_with(F, E, emax, mid)
        if code == 1:
            hi = mid
        else:
            lo = mid
    return lo


@_inline
def _leave_contact(F, E, t_in, in_hi, t_max):
    """From a contact instant t_in: (t_out, out_lo, out_hi, t_sep, limited).

    t_out is the estimate of the end of the non-separate stretch (overlaps
    that follow each other without a separate probe between them are one
    stretch) and [out_lo, out_hi] a proven bracket of it; t_sep is a
    separate time right after it, where the next shoot starts (t_max when
    the stretch reaches it).  ``limited``: the overlap search hit its limit,
    and out_lo is only the time up to which the overlap is proven.
    ``in_hi``: the upper end of the entry's bracket; where the pair is proven
    overlapping there, the search for the end starts from it.
    """
    emax = E.max()
    t_out = t_in
    lower = t_in
    if in_hi > t_in and status_with(F, E, emax, in_hi)[0] == -1:
        probe, code, last = in_hi, -1, t_in
    else:
        probe, code, last = _step_off(F, E, t_out, t_max, 1e-13)
    while True:
        if code == 1:
            if last - t_out > TOUCH_SPAN:  # touching for longer than a graze: up to somewhere in (last, probe)
                t_out = _end_of_touch(F, E, last, probe)
            elif state(F, t_out)[0] < 0.0:  # the zero of the computed State before the separate probe
                t_out = _rising_zero(F, t_out, probe)
            return t_out, lower, probe, probe, False
        if code == 0:  # inside the rounding band up to t_max: the end lies anywhere after the last proven overlap
            return t_max, lower, t_max, t_max, False
        t_exit, certified = search_exit(F, E, probe, t_max)
        if not certified:
            return t_exit, t_exit, t_max, t_max, True
        if t_exit >= t_max:
            return t_max, t_max, t_max, t_max, False
        t_out = lower = t_exit
        probe, code, last = _probe_after_exit(F, E, emax, t_out, t_max)


@_jit
def solve_intervals(F, E, t_max, first_only):
    """All maximal non-separation intervals in [0, t_max] (just the first with ``first_only``).

    ``E`` bounds the errors of F's coefficients (:func:`error_bound`), so
    every decision is proven for the true F.  Returns (status_at_start,
    intervals (k, 2), bounds (k, 4), u at the first contact, reached):
    intervals hold the estimates (zeros of the computed State), bounds the
    proven brackets [in_lo, in_hi, out_lo, out_hi] of each start and end.
    ``reached`` is -1, or, when a limit of the search (shoots, boxes,
    intervals) stopped it, the time up to which the answer is complete.
    """
    emax = E.max()
    out = np.empty((64, 2))
    bounds = np.empty((64, 4))
    k = 0
    status0, _, u_first = status_with(F, E, emax, 0.0)
    if status0 == 1:
        t_in, u_first, lower, certified = shoot_first_contact(F, E, 0.0, t_max, u_first)
        if not certified:
            return status0, out[:0], bounds[:0], u_first, lower
        if t_in < 0.0:
            return status0, out[:0], bounds[:0], u_first, -1.0
        t_in, in_hi = _entry_estimate(F, E, t_in, lower, t_max)
    else:  # not provably separate at the start: a contact at 0, or (code 0) inside the rounding band
        t_in = lower = 0.0
        if status0 == -1:
            in_hi = 0.0
        else:
            gmax, _, slope = _state_and_slope(F, 0.0, np.empty(F.shape[1]))
            in_hi = _entry_upper(F, E, 0.0, 0.0, t_max, gmax, slope)[0]
    for _ in range(MAX_INTERVALS):
        if first_only:  # no end of the interval is looked for: its bracket is the estimate itself
            out[0, 0] = out[0, 1] = t_in
            bounds[0, 0] = lower
            bounds[0, 1] = in_hi
            bounds[0, 2] = bounds[0, 3] = t_in
            return status0, out[:1], bounds[:1], u_first, -1.0
        t_out, out_lo, out_hi, t_sep, limited = _leave_contact(F, E, t_in, in_hi, t_max)
        if k > 0 and t_in - out[k - 1, 1] <= 1e-12:  # touching the previous one: merge
            out[k - 1, 1] = t_out
            bounds[k - 1, 2] = out_lo
            bounds[k - 1, 3] = out_hi
        else:
            if k == out.shape[0]:
                bigger = np.empty((2 * k, 2))
                wider = np.empty((2 * k, 4))
                for i in range(k):
                    bz.copy_into(bigger[i], out[i])
                    bz.copy_into(wider[i], bounds[i])
                out = bigger
                bounds = wider
            out[k, 0] = t_in
            out[k, 1] = t_out
            bounds[k, 0] = lower
            bounds[k, 1] = in_hi
            bounds[k, 2] = out_lo
            bounds[k, 3] = out_hi
            k += 1
        if limited:
            return status0, out[:k], bounds[:k], u_first, out_lo
        if t_sep >= t_max:
            return status0, out[:k], bounds[:k], u_first, -1.0
        t_in, _, lower, certified = shoot_first_contact(F, E, t_sep, t_max, state(F, t_sep)[1])
        if not certified:
            return status0, out[:k], bounds[:k], u_first, lower
        if t_in < 0.0:
            return status0, out[:k], bounds[:k], u_first, -1.0
        t_in, in_hi = _entry_estimate(F, E, t_in, lower, t_max)
    return status0, out[:k], bounds[:k], u_first, t_in


@_jit
def verdict(intervals, bounds, reached, t_max):
    """(certified, lo, hi) of a solve: certified when no limit was hit and every reported time is within
    TIME_TOL of both ends of its proven bracket; [lo, hi] holds every possible first contact ([-1, -1]: none)."""
    certified = reached < 0.0
    for k in range(bounds.shape[0]):  # every reported time within TIME_TOL of every time its bracket allows
        for end in range(2):
            t = intervals[k, end]
            if max(t - bounds[k, 2 * end], bounds[k, 2 * end + 1] - t) > TIME_TOL:
                certified = False
    if intervals.shape[0] > 0:
        return certified, bounds[0, 0], bounds[0, 1]
    if reached >= 0.0:
        return False, reached, t_max
    return certified, -1.0, -1.0


# ---------------------------------------------------------------- Python layer


@_jit
def _centre(P, U, s, t):
    """Centre of the moving ellipsoid at time t: where the gradient of X^T A X vanishes.  It only places the
    pencil's frame (any origin gives the same answers): for a body flattened to within rounding of a plane
    (a near-singular linear part) the least-squares point stands in."""
    A = quadric_at(P, U, s, t)
    M, g = A[:3, :3].copy(), A[:3, 3].copy()
    if np.linalg.det(M) != 0.0:
        centre = -np.linalg.solve(M, g)
        if np.isfinite(centre).all():
            return centre
    return -np.linalg.lstsq(M, g)[0]


@_jit
def _reframe(P, U, s, origin, length):
    """Quadric polynomials in the frame x_old = length * x_new + origin.

    A rigid change of frame, a uniform scaling and a positive factor on each
    quadric (:func:`balance_side`) change no answer, but they balance the
    pencil: both matrices get entries of order one and |det A(0)| = 1, which
    keeps the rounding of F relative to its values rather than to a far-away
    origin or the units.
    """
    p = P.shape[2] - 1
    q = max(p, U.shape[1] - 1)
    r = max(q, s.shape[0] - 1)
    Pn = P * length * length
    Un = np.empty((3, q + 1))
    for i in range(3):
        acc = bz.elevate(U[i].copy(), q - U.shape[1] + 1)
        for j in range(3):
            acc = acc + origin[j] * bz.elevate(P[i, j].copy(), q - p)
        bz.copy_into(Un[i], acc * length)
    quad = np.zeros(q + 1)
    for i in range(3):
        quad += origin[i] * (Un[i] / length + bz.elevate(U[i].copy(), q - U.shape[1] + 1))
    sn = bz.elevate(s.copy(), r - s.shape[0] + 1) + bz.elevate(quad, r - q)
    return Pn, Un, sn


@_jit
def _reframed_errors(P, U, s, err, origin, length):
    """Error bounds (4x4) of :func:`_reframe`'s output, elevated and scaled into a pencil, from those of its input.

    P' = P L^2, U' = L (U + P o), s' = s + o . (U' / L + U): each error is
    carried through with the magnitudes of the computed coefficients (the
    true ones are at most those plus their bounds), and every step adds its
    own rounding.
    """
    n = max(P.shape[2], U.shape[1], s.shape[0]) + 2
    g = gamma(4 * n + 20)
    Pm, Um, sm = bz.abs_maxima(P, U, s)
    o = np.abs(origin)
    out = np.empty((4, 4))
    for i in range(3):
        for j in range(3):
            out[i, j] = err[i, j] * length * length * (1.0 + g) + g * (Pm[i, j] + err[i, j]) * length * length
    es = err[3, 3] + g * sm
    for i in range(3):
        eu = err[i, 3]
        mu = Um[i]
        for j in range(3):
            eu += o[j] * err[i, j]
            mu += o[j] * (Pm[i, j] + err[i, j])
        out[i, 3] = out[3, i] = length * (eu + g * (mu + err[i, 3]))
        es += o[i] * (2.0 * eu + g * 2.0 * (mu + err[i, 3]))
    out[3, 3] = es * (1.0 + g)
    return out


@_jit
def prepare_pair(PA, UA, sA, errA, PB, UB, sB, errB, length):
    """The pencil of both bodies in a common frame, with the bounds of its entries' errors.

    Returns (pencil (Pp, Up, sp), err (2, 4, 4), the frame's origin); the
    frame is centred between the bodies and scaled by ``length``.  Feed it to
    :func:`solve_balanced`, which balances the pencil in place.
    """
    origin = 0.25 * (_centre(PA, UA, sA, 0.0) + _centre(PA, UA, sA, 1.0)
                     + _centre(PB, UB, sB, 0.0) + _centre(PB, UB, sB, 1.0))
    p = max(PA.shape[2], PB.shape[2]) - 1
    q = max(p, UA.shape[1] - 1, UB.shape[1] - 1)
    Pp, Up, sp = empty_pencil(p, q, max(q, sA.shape[0] - 1, sB.shape[0] - 1))
    pencil_side_into(*_reframe(PA, UA, sA, origin, length), Pp, Up, sp, 0)
    pencil_side_into(*_reframe(PB, UB, sB, origin, length), Pp, Up, sp, 1)
    err = np.empty((2, 4, 4))
    err_a = _reframed_errors(PA, UA, sA, errA, origin, length)
    err_b = _reframed_errors(PB, UB, sB, errB, origin, length)
    for i in range(4):
        bz.copy_into(err[0, i], err_a[i])
        bz.copy_into(err[1, i], err_b[i])
    return (Pp, Up, sp), err, origin


@_jit
def thinner(rx, ry):
    """True when the body of radii ``rx`` is thin (THIN) and thinner than the body of radii ``ry``."""
    return rx.max() > THIN * rx.min() and rx.max() / rx.min() > ry.max() / ry.min()


@_jit
def same_orientation(q0, q1):
    """True when two unit quaternions are one orientation up to rounding (see SAME_ORIENTATION)."""
    return (abs(q0[0] - q1[0]) <= SAME_ORIENTATION and abs(q0[1] - q1[1]) <= SAME_ORIENTATION
            and abs(q0[2] - q1[2]) <= SAME_ORIENTATION and abs(q0[3] - q1[3]) <= SAME_ORIENTATION)


@_jit
def _conj_mul(a, b):
    """The quaternion conj(a) b: b's orientation in the frame of a (a unit)."""
    return np.array([a[0] * b[0] + a[1] * b[1] + a[2] * b[2] + a[3] * b[3],
                     a[0] * b[1] - a[1] * b[0] - a[2] * b[3] + a[3] * b[2],
                     a[0] * b[2] + a[1] * b[3] - a[2] * b[0] - a[3] * b[1],
                     a[0] * b[3] - a[1] * b[2] + a[2] * b[1] - a[3] * b[0]])


@_jit
def _in_frame_of(qa0, qa1, pa0, pa1, qb0, qb1, pb0, pb1, translating):
    """Both two-pose motions in the frame of A at t = 0: origin A's start, axes A's axes.

    A's start orientation becomes exactly the identity (and stays so when
    nothing turns), so A's quadric is diagonal: a thin body's small
    curvatures are not lost to the rounding of its large ones.  Rotating
    and translating both bodies changes no answer.
    """
    R = quat_to_matrix(qa0)
    ident = np.array([1.0, 0.0, 0.0, 0.0])
    out = []
    for p in (pa0, pa1, pb0, pb1):
        d = p - pa0
        out.append(np.array([R[0, 0] * d[0] + R[1, 0] * d[1] + R[2, 0] * d[2],
                             R[0, 1] * d[0] + R[1, 1] * d[1] + R[2, 1] * d[2],
                             R[0, 2] * d[0] + R[1, 2] * d[1] + R[2, 2] * d[2]]))
    qa1n = ident if translating else _conj_mul(qa0, qa1)
    return ident, qa1n, out[0], out[1], _conj_mul(qa0, qb0), _conj_mul(qa0, qb1), out[2], out[3]


@_inline
def two_pose_pair(affine_a, affine_b, ra, pa0, qa0, pa1, qa1, rb, pb0, qb0, pb1, qb1, t_max, first_only):
    """Exact CCD of two ellipsoids that each move between two poses.

    Typed inside each compiled entry that calls it (:func:`two_pose_rows`
    for the Python API, the scene's frame kernel and :func:`rigid_first_contact`
    through :func:`exact_pair`), so that each compiles the solver once, not
    once in a library of its own and again inside its caller.

    Returns (status at start, intervals (k, 2), bounds (k, 4), point,
    normal, reached, precision tier, certified, bracket_lo, bracket_hi); see
    :func:`solve_intervals` and :func:`verdict`.  ``affine_a`` and
    ``affine_b`` pick each body's motion model between its poses (rigid:
    centre and quaternion lerp; affine: centre and shape matrix lerp; a
    static body is either with equal poses).  Quaternions must be unit and
    ``q1`` already on the side of ``q0``.  Both quadrics are taken in a
    common balanced frame that moves with A's centre (unit = the largest
    semi-axis): positions are subtracted before any product, so far-away
    bodies lose nothing, and A's U = 0 there makes F cheaper
    (:func:`F_from_pencil`).  point/normal are zero when there is no external
    touch at t > 0.
    """
    # the thinner body is taken as A: in A's frame (below) A's quadric is diagonal, which keeps A's small
    # curvatures clear of the rounding of its large ones, but not B's (a thin B needed the rational tier far
    # more often); the answer is the same with the normal turned, as it points out of A
    swapped = thinner(rb, ra)
    if swapped:
        affine_a, affine_b = affine_b, affine_a
        ra, pa0, qa0, pa1, qa1, rb, pb0, qb0, pb1, qb1 = rb, pb0, qb0, pb1, qb1, ra, pa0, qa0, pa1, qa1
    length = max(ra.max(), rb.max())
    translating = same_orientation(qa0, qa1) and same_orientation(qb0, qb1)
    # thin bodies are taken in A's frame (A's quadric diagonal); for the others it buys nothing
    framed = ra.max() > THIN * ra.min() or rb.max() > THIN * rb.min()
    frame_quaternion, origin = qa0, pa0  # A's frame at t = 0, where the answer goes back to
    if framed:
        qa0, qa1, pa0, pa1, qb0, qb1, pb0, pb1 = _in_frame_of(qa0, qa1, pa0, pa1, qb0, qb1, pb0, pb1, translating)
    zero = np.zeros(3)
    if translating:  # both only translate (orientation q0): F of degree 2
        Pp, Up, sp = empty_pencil(0, 1, 2)
        translation_scaled_into(ra, pa0, qa0, pa1, pa0, pa1, length, Pp, Up, sp, np.intp(0))
        translation_scaled_into(rb, pb0, qb0, pb1, pa0, pa1, length, Pp, Up, sp, np.intp(1))
    elif affine_a and affine_b:
        Pp, Up, sp = empty_pencil(1, 2, 3)
        pencil_side_into(*quadric_affine(ra / length, zero, qa0, zero, qa1), Pp, Up, sp, 0)
        pencil_side_into(*quadric_affine(rb / length, (pb0 - pa0) / length, qb0, (pb1 - pa1) / length, qb1),
                         Pp, Up, sp, 1)
    else:
        Pp, Up, sp = empty_pencil(4, 5, 6)
        if affine_a:
            pencil_side_into(*quadric_affine(ra / length, zero, qa0, zero, qa1), Pp, Up, sp, 0)
        else:
            rigid_scaled_into(ra, pa0, qa0, pa1, qa1, pa0, pa1, length, Pp, Up, sp, np.intp(0))
        if affine_b:
            pencil_side_into(*quadric_affine(rb / length, (pb0 - pa0) / length, qb0, (pb1 - pa1) / length, qb1),
                             Pp, Up, sp, 1)
        else:
            rigid_scaled_into(rb, pb0, qb0, pb1, qb1, pa0, pa1, length, Pp, Up, sp, np.intp(1))
    err = np.empty((2, 4, 4))
    pose_side_errors(ra, length, 0.0, translating and framed, err[0])
    pose_side_errors(rb, length, centre_extent(pb0, pb1, pa0, pa1, length), np.bool_(False), err[1])
    status0, intervals, bounds, u, reached, tier = solve_balanced(Pp, Up, sp, err, t_max, first_only)
    point = np.zeros(3)
    normal = np.zeros(3)
    if status0 == 1 and intervals.shape[0] > 0:
        t = intervals[0, 0]
        p, n = touching_point(pencil_quadric_at(Pp, Up, sp, np.intp(0), t),
                              pencil_quadric_at(Pp, Up, sp, np.intp(1), t), u)
        for m in range(3):
            point[m] = (1.0 - t) * pa0[m] + t * pa1[m] + length * p[m]
        if framed:  # back from A's frame at t = 0
            frame = quat_to_matrix(frame_quaternion)
            local = point.copy()
            for m in range(3):
                point[m] = origin[m] + frame[m, 0] * local[0] + frame[m, 1] * local[1] + frame[m, 2] * local[2]
                normal[m] = frame[m, 0] * n[0] + frame[m, 1] * n[1] + frame[m, 2] * n[2]
        else:
            bz.copy_into(normal, n)
        if swapped:  # out of the caller's A
            for m in range(3):
                normal[m] = -normal[m]
    certified, lo, hi = verdict(intervals, bounds, reached, t_max)
    return status0, intervals, bounds, point, normal, reached, tier, certified, lo, hi


PACKED_HEAD = 13  # [status0, k, reached, tier, certified, lo, hi, point (3), normal (3)] before the intervals


@_jit
def pack_solution(out, status0, intervals, bounds, point, normal, reached, tier, certified, lo, hi):
    """:func:`two_pose_pair`'s answer written into ``out`` (PACKED_HEAD + 6 k floats): the head, then the k
    intervals (2 each) and their bounds (4 each)."""
    k = intervals.shape[0]
    out[0] = status0
    out[1] = k
    out[2] = reached
    out[3] = tier
    out[4] = 1.0 if certified else 0.0
    out[5] = lo
    out[6] = hi
    for m in range(3):
        out[7 + m] = point[m]
        out[10 + m] = normal[m]
    for i in range(k):
        out[PACKED_HEAD + 2 * i] = intervals[i, 0]
        out[PACKED_HEAD + 2 * i + 1] = intervals[i, 1]
        for j in range(4):
            out[PACKED_HEAD + 2 * k + 4 * i + j] = bounds[i, j]


@_jit
def two_pose_rows(affine_a, affine_b, ra, row_a, rb, row_b, t_max, first_only):
    """:func:`two_pose_pair` on the motions' rows ``[p0, q0, p1, q1]`` (14,), answered in one flat array
    (:func:`pack_solution`): one call and one array across the boundary, for the Python API."""
    status0, intervals, bounds, point, normal, reached, tier, certified, lo, hi = two_pose_pair(
        affine_a, affine_b, ra, row_a[0:3], row_a[3:7], row_a[7:10], row_a[10:14],
        rb, row_b[0:3], row_b[3:7], row_b[7:10], row_b[10:14], t_max, first_only)
    out = np.empty(PACKED_HEAD + 6 * intervals.shape[0])
    pack_solution(out, status0, intervals, bounds, point, normal, reached, tier, certified, lo, hi)
    return out


@_jit
def two_pose_batch(affine, radii, rows, t_max, first_only, starts):
    """:func:`two_pose_rows` for K pairs in one call: ``affine`` (K, 2) bool, ``radii`` (K, 2, 3), ``rows``
    (K, 2, 14) (body a, then b).  Returns one flat array holding each pair's packed answer
    (:func:`pack_solution`); pair k's starts at ``starts[k]`` and ends at ``starts[k + 1]``."""
    K = radii.shape[0]
    buf = np.empty(K * (PACKED_HEAD + 6))  # one interval each; doubled when a pair has more
    pos = 0
    for k in range(K):
        out = two_pose_rows(affine[k, 0], affine[k, 1], radii[k, 0], rows[k, 0], radii[k, 1], rows[k, 1],
                            t_max, first_only)
        need = out.shape[0]
        if pos + need > buf.shape[0]:
            buf = bz.copy_into(np.empty(max(2 * buf.shape[0], pos + need)), buf[:pos])
        bz.copy_into(buf[pos:pos + need], out)
        starts[k] = pos
        pos += need
    starts[K] = pos
    return buf[:pos]


@_inline
def balanced_F(Pp, Up, sp, err):
    """Balance the pencil in place and build F: (F, D, M), D the 4x4 bounds of the balanced entries' errors
    (``err`` (2, 4, 4): each side's before balancing) and M their coefficient maxima, for
    :func:`error_bound_global` or :func:`error_bound_tight`."""
    inv = np.empty(2)
    inv[0] = balance_side(Pp, Up, sp, np.intp(0))
    inv[1] = balance_side(Pp, Up, sp, np.intp(1))
    M = _entry_maxima(Pp, Up, sp)
    D = entry_errors_balanced(err, inv, M)
    return F_from_pencil(Pp, Up, sp), D, M


@_inline
def solve_balanced(Pp, Up, sp, err, t_max, first_only):
    """Balance the pencil, build F and solve it: first with the cheap constant error bound, again with the
    coefficient-wise one when that leaves a bracket wider than TIME_TOL.  See :func:`solve_intervals`.

    ``err`` (2, 4, 4): bounds of each side's entry errors before balancing.
    Returns :func:`solve_intervals`'s values and the precision tier used.
    """
    F, D, M = balanced_F(Pp, Up, sp, err)
    E = error_bound_global(F, Pp, Up, sp, D, M)
    status0, intervals, bounds, u, reached = solve_intervals(F, E, t_max, first_only)
    certified, _, _ = verdict(intervals, bounds, reached, t_max)
    if certified:
        return status0, intervals, bounds, u, reached, DOUBLE
    E = error_bound_tight(F, Pp, Up, sp, D)
    status0, intervals, bounds, u, reached = solve_intervals(F, E, t_max, first_only)
    return status0, intervals, bounds, u, reached, DOUBLE_TIGHT


@_inline
def exact_pair(affine, ra, pa0, qa0, pa1, qa1, rb, pb0, qb0, pb1, qb1, t_max, first_only):
    """:func:`two_pose_pair` with one motion model for both bodies (``affine``), as a scene uses it:
    (status at start, intervals, point, normal, certified, bracket_lo, bracket_hi), see :func:`verdict`."""
    status0, intervals, _, point, normal, _, _, certified, lo, hi = two_pose_pair(
        affine, affine, ra, pa0, qa0, pa1, qa1, rb, pb0, qb0, pb1, qb1, t_max, first_only)
    return status0, intervals, point, normal, certified, lo, hi


@_jit
def rigid_first_contact(radii, positions, quaternions, t_max, touch):
    """Fused kernel for two rigid motions: (status at start, first contact time or -1).

    Body a then b: ``radii`` (2, 3), ``positions`` (2, 2, 3) and ``quaternions``
    (2, 2, 4) at t = 0 then t = 1 (unit, q1 on the side of q0).  The touch
    point and normal go to ``touch`` (2, 3), zero when there is none.  Plain
    arrays in, scalars out: what a batched caller would loop over; see
    :func:`exact_pair`.
    """
    status0, intervals, point, normal, certified, lo, _ = exact_pair(
        False, radii[0], positions[0, 0], quaternions[0, 0], positions[0, 1], quaternions[0, 1],
        radii[1], positions[1, 0], quaternions[1, 0], positions[1, 1], quaternions[1, 1], t_max, True)
    touch[0] = point
    touch[1] = normal
    if status0 != 1:
        return status0, 0.0
    if intervals.shape[0] == 0:
        return status0, (-1.0 if certified else lo)  # an uncertain query is a possible contact at lo
    return status0, intervals[0, 0]


def _check_pair(a, motion_a, b, motion_b):
    for name, e in (("a", a), ("b", b)):
        if not isinstance(e, Ellipsoid):
            raise InputTypeError(f"{name}: expected an mjccd.Ellipsoid, got {type(e).__name__}")
    for name, m in (("motion_a", motion_a), ("motion_b", motion_b)):
        if not isinstance(m, Motion):
            raise InputTypeError(f"{name}: expected an mjccd motion, got {type(m).__name__}")


_TWO_POSE = frozenset((Static, Rigid, Affine))


def _two_poses(a, motion_a, b, motion_b):
    """True for two ellipsoids that each move between two poses (Static, Rigid, Affine): the fused kernel's pairs."""
    return (type(a) is Ellipsoid and type(b) is Ellipsoid
            and type(motion_a) in _TWO_POSE and type(motion_b) in _TWO_POSE)


def _two_pose_call(a, motion_a, b, motion_b, t_max, first_only):
    """:func:`two_pose_rows` on the pair: its flat answer (see :func:`pack_solution`)."""
    return two_pose_rows(type(motion_a) is Affine, type(motion_b) is Affine, a.radii, motion_a._row,
                         b.radii, motion_b._row, t_max, first_only)


def needs_exact(status0, certified):
    """True when a double-precision answer goes on to the rational tier (see :func:`solve_motions`):
    touching at the start, or uncertain (its bracket is refined, or made to hold, in rational arithmetic)."""
    return status0 == 0 or not certified


def _unpacked(out):
    """The :class:`PairSolution` of :func:`two_pose_rows`'s flat answer (views of it, no copies)."""
    status0, k, reached, tier, certified, lo, hi = out[:7].tolist()
    k = int(k)
    touch = status0 == 1 and k > 0
    return PairSolution(int(status0), out[PACKED_HEAD:PACKED_HEAD + 2 * k].reshape(k, 2),
                        out[7:10] if touch else None, out[10:13] if touch else None, certified != 0.0, (lo, hi),
                        out[PACKED_HEAD + 2 * k:].reshape(k, 4), reached, int(tier))


def time_pieces(factors, t_max):
    """Edges of the pieces of [0, t_max] on which every positive factor varies by at most PIECE_RATIO.

    A rational motion's quadric carries g(t)^2 (a hinge sweeping close to
    ±180°, a near-singular linear_affine).  Where g swings by orders of
    magnitude, coefficients built over [0, 1] carry rounding from the large
    end into the small one; built over a piece (the motion's own low-degree
    polynomials restricted first), they keep the rounding of the piece.
    Pieces halve, down to 2^-MAX_PIECE_DEPTH.
    """
    def even(t0, t1):
        for g in factors:
            c = bz.restrict(g.copy(), t0, t1)
            if c[0] < 0.0:  # W and -W are the same motion: the factor has one sign on [0, 1]
                c = -c
            lo = c.min()
            if not lo > 0.0 or c.max() > PIECE_RATIO * lo:
                return False
        return True

    edges = [0.0]
    pending = [(0.0, 1.0, 0)]
    while pending and edges[-1] < t_max:
        t0, t1, depth = pending.pop()
        if depth < MAX_PIECE_DEPTH and not even(t0, t1):
            mid = 0.5 * (t0 + t1)
            pending += [(mid, t1, depth + 1), (t0, mid, depth + 1)]
        else:
            edges.append(min(t1, t_max))
    return edges


class PairSolution(NamedTuple):
    """Everything the solver knows about one pair over [0, t_max] (see :func:`solve_motions`).

    A named tuple: built once per query, so its construction is kept cheap.
    """

    status_at_start: int
    intervals: np.ndarray      # (k, 2) maximal non-separate intervals, normalised time
    point: object              # world touch point of the first contact (t > 0), or None
    normal: object             # unit normal there, outward from the first body, or None
    certified: bool            # False: a limit was hit or a bracket stayed wide; the first contact lies in ``bracket``
    bracket: tuple             # (lo, hi) holding every possible first contact; (-1, -1) for none
    bounds: np.ndarray = None  # (k, 4) proven brackets [in_lo, in_hi, out_lo, out_hi] of the intervals' ends
    reached: float = -1.0      # when a search limit stopped the solve: the time up to which it is complete
    precision: int = 0         # DOUBLE, DOUBLE_TIGHT or RATIONAL: the most careful tier the answer needed


def _turned(quadric, R):
    """(P, U, s, err) of a quadric in the frame x = R x': R^T P R, R^T U, s, with err grown by the rounding."""
    P, U, s, err = quadric
    Pm, Um, _ = bz.abs_maxima(P, U, s)
    aR = np.abs(R)
    out = np.empty((4, 4))
    out[:3, :3] = aR.T @ (err[:3, :3] + gamma(12) * Pm) @ aR
    out[:3, 3] = out[3, :3] = aR.T @ (err[:3, 3] + gamma(6) * Um)
    out[3, 3] = err[3, 3]
    turned_P = np.ascontiguousarray(np.einsum("ki,kjm->ijm", R, np.einsum("klm,lj->kjm", P, R)))
    return turned_P, np.ascontiguousarray(np.einsum("ki,km->im", R, U)), s, out


def _solved_piece(quadric_a, quadric_b, length, first_only):
    """(balanced pencil, its frame's origin, :func:`solve_balanced`'s values) of a piece's two quadrics."""
    pencil, err, frame_origin = prepare_pair(*quadric_a, *quadric_b, length)
    return pencil, frame_origin, solve_balanced(*pencil, err, 1.0, first_only)


def _turned_to_thinner(quadric_a, quadric_b):
    """(R, A, B): both bounded quadrics turned to the principal axes of the thinner body halfway through the
    piece when one is thin (above THIN:1; else R is None), as the two-pose kernel turns the frame to A's axes
    (docs/method.md): the large curvatures of a body flattened near a singular linear part then sit apart
    from its small ones instead of swamping them.  Any invertible R keeps every status and time; the
    rounding of the turn joins the error bounds."""
    def middle(P):  # P at t = 1/2: the Bernstein coefficients weighted by C(n, i) / 2^n
        n = P.shape[2] - 1
        M = P @ (np.array([math.comb(n, i) for i in range(n + 1)]) / 2.0 ** n)
        return 0.5 * (M + M.T)

    def roundness(M):
        values = np.linalg.eigvalsh(M)
        return abs(values[0]) / max(abs(values[2]), 1e-300)
    middle_a, middle_b = middle(quadric_a[0]), middle(quadric_b[0])
    roundness_a, roundness_b = roundness(middle_a), roundness(middle_b)
    if min(roundness_a, roundness_b) > 1.0 / (THIN * THIN):  # neither is thin: the turn buys nothing
        return None, quadric_a, quadric_b
    R = np.linalg.eigh(middle_a if roundness_a <= roundness_b else middle_b)[1]
    return R, _turned(quadric_a, R), _turned(quadric_b, R)


def _solve_pieces(a, motion_a, b, motion_b, t_max, first_only, t_start=0.0):
    """The general path: both motions in a local frame at A's start, built and solved piece by piece
    (over [t_start, t_max]: the status at start is then the status at t_start)."""
    origin = np.asarray(motion_a.anchor(), float)
    local_a, local_b = motion_a.translated(origin), motion_b.translated(origin)
    length = float(max(a.radii.max(), b.radii.max()))
    factors = [f for f in (local_a.factor(), local_b.factor()) if f is not None]
    edges = time_pieces(factors, t_max)
    if t_start > 0.0:
        edges = [t_start] + [t for t in edges if t > t_start]
    at_end = None
    intervals = []
    status0 = None
    point = normal = None
    certified, bracket = True, (-1.0, -1.0)
    all_bounds = []
    reached = -1.0
    precision = DOUBLE
    for t0, t1 in zip(edges[:-1], edges[1:]):
        quadric_a = local_a.quadric_bounded_on(a.radii, t0, t1)
        quadric_b = local_b.quadric_bounded_on(b.radii, t0, t1)
        turn, (pencil, frame_origin, solved) = np.eye(3), _solved_piece(quadric_a, quadric_b, length,
                                                                        first_only and not intervals)
        if solved[0] == 0 or not verdict(solved[1], solved[2], solved[4], 1.0)[0]:
            turned, turned_a, turned_b = _turned_to_thinner(quadric_a, quadric_b)
            if turned is not None:  # undecided as given: again in the thinner body's axes
                turn, (pencil, frame_origin, solved) = turned, _solved_piece(turned_a, turned_b, length,
                                                                             first_only and not intervals)
        code, piece, bounds, u, piece_reached, tier = solved
        precision = max(precision, int(tier))
        if status0 is None:
            status0 = int(code)
        width = t1 - t0
        if at_end is not None and code != 1:  # the touch the piece before found at its end, not refuted here
            if not intervals:
                point, normal = at_end[2]
            intervals.append(at_end[0])
            all_bounds.append(at_end[1])
        at_end = None
        for (s_in, s_out), box in zip(piece, bounds):
            t_in, t_out = t0 + s_in * width, t0 + s_out * width
            box = t0 + box * width
            if intervals and t_in - intervals[-1][1] <= 1e-12:
                intervals[-1][1] = t_out
                all_bounds[-1][2:] = box[2:]
                continue
            if code == 0 and s_in == 0.0 and t0 > edges[0]:
                # a later piece starting inside the rounding band: the piece before proved the pair separate up
                # to t0, this one cannot tell; what it calls a contact may be anywhere in the piece, or none
                box[1] = max(box[1], t1)
                box[3] = max(box[3], t1)
            touch = (point, normal)
            if not intervals and status0 == 1:
                p, n = touching_point(pencil_quadric_at(*pencil, 0, s_in), pencil_quadric_at(*pencil, 1, s_in), u)
                touch = (origin + turn @ (frame_origin + length * p), turn @ n / np.linalg.norm(turn @ n))
            if s_in == 1.0 and t1 < edges[-1]:
                # inside the rounding band just at the piece's end: a touch only if the next piece, which
                # starts there, cannot prove the pair separate
                at_end = ([t_in, t_out], box, touch)
                continue
            point, normal = touch
            intervals.append([t_in, t_out])
            all_bounds.append(box)
        if piece_reached >= 0.0:
            reached = t0 + piece_reached * width
            break
        if first_only and intervals:
            break
    if first_only and intervals:
        intervals = intervals[:1]
        intervals[0][1] = intervals[0][0]
        all_bounds = all_bounds[:1]
    intervals = np.array(intervals, float).reshape(-1, 2)
    all_bounds = np.array(all_bounds, float).reshape(-1, 4)
    certified, lo, hi = verdict(intervals, all_bounds, reached, t_max)
    return PairSolution(status0, intervals, point, normal, bool(certified), (float(lo), float(hi)), all_bounds,
                        reached, precision)


class _ExactPair:
    """The pair in A's local frame, for decisions in rational arithmetic (:mod:`mjccd.exact`)."""

    def __init__(self, a, motion_a, b, motion_b):
        self.a, self.b = a, b
        self.motion_a, self.motion_b = motion_a, motion_b
        self._polynomial = None
        self.origin = np.asarray(motion_a.anchor(), float)
        self.local_a, self.local_b = motion_a.translated(self.origin), motion_b.translated(self.origin)

    def status(self, t):
        """Exact status (1, 0, -1) at the rational time t."""
        return exact.static_status_exact(self.local_a.exact_quadric_at(self.a.radii, t),
                                         self.local_b.exact_quadric_at(self.b.radii, t))

    def separation_change(self, lo, hi, separate_at_lo):
        """Where the exact status changes to or from separate in (lo, hi], by bisection on dyadic times:
        (the time as a float, the end of the final bracket that is not separate, as a Fraction), or None
        when the exact status at lo and hi does not differ as expected."""
        lo, hi = Fraction(lo), Fraction(hi)
        if (self.status(lo) == 1) != separate_at_lo or (self.status(hi) == 1) == separate_at_lo:
            return None
        while hi - lo > Fraction(2) ** -60 * max(hi, Fraction(2) ** -1000):
            mid = (lo + hi) / 2
            if (self.status(mid) == 1) == separate_at_lo:
                lo = mid
            else:
                hi = mid
        return (float(hi), hi) if separate_at_lo else (float(lo), lo)

    def change_near(self, t, lo, hi, separate_at_lo):
        """(t, the end of a bracket around t that is not separate, as a Fraction, the bracket's ends) when the
        exact status taken NEAR_SPAN either side of the double estimate t (inside [lo, hi]) changes there as
        expected: the event lies within NEAR_SPAN of t.  None otherwise."""
        a, b = Fraction(max(lo, t - NEAR_SPAN)), Fraction(min(hi, t + NEAR_SPAN))
        if (self.status(a) == 1) == separate_at_lo and (self.status(b) == 1) != separate_at_lo:
            return t, (b if separate_at_lo else a), float(a), float(b)
        return None

    def first_not_separate(self, lo, hi, *estimates, samples=16):
        """The earliest of the estimates and of ``samples`` even times in (lo, hi) at which the pair is not
        separate (exactly), or None."""
        times = sorted({float(t) for t in estimates if lo < t <= hi}
                       | {lo + (hi - lo) * k / samples for k in range(1, samples + 1)})
        for t in times:
            if self.status(Fraction(t)) != 1:
                return t
        return None

    def polynomial(self):
        """(A(t), B(t), degree): the exact quadrics as polynomials in t (evaluations cached), for
        :mod:`mjccd.exact_stretch`; None when a motion has no scaled inverse (the affine interpolant)."""
        if not all(hasattr(m, "polynomial_quadric_at") for m in (self.local_a, self.local_b)):
            return None
        if self._polynomial is None:
            self._polynomial = self._polynomial_quadrics()
        return self._polynomial

    def _polynomial_quadrics(self):
        """(A(t), B(t), degree), each evaluation kept."""
        cache = {}

        def quadrics(t):
            if t not in cache:
                cache[t] = (self.local_a.polynomial_quadric_at(self.a.radii, t),
                            self.local_b.polynomial_quadric_at(self.b.radii, t))
            return cache[t]
        degree = max(self.local_a.quadric_degree(), self.local_b.quadric_degree())
        return (lambda t: quadrics(t)[0]), (lambda t: quadrics(t)[1]), degree

    def touch(self, t):
        """World touch point and unit normal of the pair at time t, in rational arithmetic."""
        tf = Fraction(t)
        point, normal = exact.touching_point_exact(self.local_a.exact_quadric_at(self.a.radii, tf),
                                                   self.local_b.exact_quadric_at(self.b.radii, tf))
        return self.origin + np.array(point), np.array(normal)


def _settled_event(pair, t, lo, hi, separate_at_lo, interval, inside, t_max):
    """(time, boundary, bracket lo, bracket hi) of the event estimated at t in the double bracket [lo, hi], in
    rational arithmetic, or None when the exact status does not confirm it.

    The estimate confirmed by two exact statuses (:meth:`_ExactPair.change_near`), or else bisection to the
    last bit (the bracket is then the time itself): for an entry (``separate_at_lo``) that finds the pair
    separate again at hi (a graze in the band), from a time inside ``interval`` that is not separate; for an
    exit whose lower end is not inside, from ``inside``, a time the pair is not separate.  An exit the double
    left inside the rounding band up to ``t_max`` holds when the pair is not separate at t_max.
    """
    if lo < t < hi:
        near = pair.change_near(t, lo, hi, separate_at_lo)
        if near is not None:
            return near
    if not separate_at_lo and t == hi == t_max and pair.status(Fraction(hi)) != 1:
        return t, Fraction(hi), t, t  # not separate at the end of the window: the interval reaches it
    found = pair.separation_change(lo, hi, separate_at_lo)
    if found is None and separate_at_lo:
        probe = pair.first_not_separate(lo, hi, interval[0], interval[1])
        found = None if probe is None else pair.separation_change(lo, probe, True)
    if found is None and not separate_at_lo:
        found = pair.separation_change(inside, hi, False)
    return None if found is None else (found[0], found[1], found[0], found[0])


def _refine_exactly(pair, solution, t_max):
    """Events whose proven bracket is wider than TIME_TOL, settled by bisection on the exact status.

    Double precision proved the pair separate before each start bracket and
    overlapping (or touching) at its end, and the reverse around each end.
    The exact status just either side of the double estimate confirms it
    within 2^-50 (:meth:`_ExactPair.change_near`: two exact statuses); where
    it does not, the exact status at dyadic times inside the bracket finds
    where it changes, to 2^-60.  An event whose ends the exact
    status does not confirm (a graze inside the rounding band that may be a
    miss) stays uncertain.
    """
    intervals = solution.intervals.copy()
    bounds = solution.bounds.copy()
    certified = True
    first_refined = False  # the first contact's time settled here: its point is taken there, exactly
    for k in range(len(intervals)):
        # a time the pair is not separate inside interval k: the entry's proven-overlap end, refined below
        inside = Fraction(0) if k == 0 and solution.status_at_start != 1 else Fraction(float(bounds[k, 1]))
        for end, (lo, hi), separate_at_lo in ((0, bounds[k, 0:2], True), (1, bounds[k, 2:4], False)):
            t = intervals[k, end]
            if max(t - lo, hi - t) <= TIME_TOL or (end == 0 and k == 0 and solution.status_at_start != 1):
                continue
            found = _settled_event(pair, t, lo, hi, separate_at_lo, intervals[k], inside, t_max)
            if found is None:
                certified = False
                continue
            intervals[k, end], boundary, bounds[k, 2 * end], bounds[k, 2 * end + 1] = found
            if end == 0:
                inside = boundary
                first_refined = first_refined or k == 0
    point, normal = solution.point, solution.normal
    if first_refined and solution.status_at_start == 1:
        point, normal = pair.touch(float(intervals[0, 0]))
    lo, hi = (bounds[0, 0], bounds[0, 1]) if len(intervals) else solution.bracket
    return solution._replace(intervals=intervals, bounds=bounds, point=point, normal=normal, certified=certified,
                   bracket=(float(lo), float(hi)), precision=RATIONAL)


def _settle_touching_start(pair, solution, first_only):
    """A pair the double status calls touching at t = 0 (inside its rounding band), settled in rational arithmetic.

    Touching or overlapping: the double answer stands.  Separate (e.g. a gap
    of 1e-12 that closes at once): the first contact is where the exact
    status first leaves "separate" inside the double's first interval,
    bracketed by probes end * 2^-k and bisected on dyadic times.
    """
    code = pair.status(Fraction(0))
    solution = solution._replace(precision=RATIONAL)
    if code != 1:
        return solution._replace(status_at_start=code)
    end = Fraction(float(solution.intervals[0, 1])) if len(solution.intervals) else Fraction(0)
    end = max(end, Fraction(TOUCH_SPAN))
    lo = hi = None
    for k in range(EXACT_PROBES, 0, -1):
        probe = end / 2 ** k
        if pair.status(probe) != 1:
            hi = probe
            break
        lo = probe
    found = None if hi is None else pair.separation_change(lo or Fraction(0), hi, True)
    if found is None:  # no contact the exact status can find near t = 0: the double's first interval is not confirmed
        return solution._replace(status_at_start=1, intervals=solution.intervals[1:], certified=False,
                       bracket=(0.0, float(end)), point=None, normal=None)
    t = found[0]
    intervals = solution.intervals.copy()
    bounds = solution.bounds.copy()
    intervals[0, 0] = bounds[0, 0] = bounds[0, 1] = t
    if first_only:
        intervals[0, 1] = bounds[0, 2] = bounds[0, 3] = t
    certified, _, _ = verdict(intervals, bounds, solution.reached, 1.0)
    point, normal = pair.touch(t)
    return solution._replace(status_at_start=1, intervals=intervals, bounds=bounds, point=point, normal=normal,
                   bracket=(t, t), certified=bool(certified))


def _held_bracket(pair, solution, t_max):
    """An uncertain ``solution`` whose bracket reaches a time at which the pair is exactly not separate.

    The double solver proves the pair separate up to the bracket's low end;
    its high end is where the probes of the entry left the rounding band,
    which may be "separate again" rather than a proven overlap: the bodies
    may have missed there and touch later, or never.  Then the bracket
    reaches to the first later time of the double's intervals (entries,
    middles, ends; outside them the pair is proven separate) at which the
    exact status is not separate; failing that, to the end of the last
    interval (no contact is then possible after it), or to ``t_max`` when a
    search limit left the rest unsolved.  Every possible first contact lies
    inside the bracket.
    """
    lo, hi = solution.bracket
    if hi - lo <= TIME_TOL or pair.status(Fraction(hi)) != 1:  # settled, or a proven end
        return solution
    full = _unsettled(pair.a, pair.motion_a, pair.b, pair.motion_b, t_max, False)
    times = sorted({t for row, box in zip(full.intervals.tolist(), full.bounds.tolist())
                    for t in (box[1], row[0], 0.5 * (row[0] + row[1]), row[1]) if hi < t <= t_max})
    for t in times[:HELD_PROBES]:
        if pair.status(Fraction(t)) != 1:
            return solution._replace(bracket=(lo, t))
    if full.reached < 0.0 and len(times) <= HELD_PROBES:
        end = max([hi] + [box[3] for box in full.bounds.tolist()])
        return solution._replace(bracket=(lo, min(end, t_max)))
    return solution._replace(bracket=(lo, t_max))


def _float_below(x):
    """The largest float <= the Fraction x."""
    f = float(x)
    return f if Fraction(f) <= x else float(np.nextafter(f, -np.inf))


def _settled_stretch(pair, solution, first_only, t_max):
    """An uncertain first contact whose bracket [lo, hi] stayed wide, settled by proving the pair separate
    over its start in rational arithmetic (:mod:`mjccd.exact_stretch`), in rounds.

    Each round proves what it can from the low end; then the double solver
    is run again from the proven end (:func:`_solve_pieces` with
    ``t_start``), where it may decide what it could not from further back.
    All of [lo, hi] proven: no contact (``hi`` is the end of the last
    interval that may hold one, or t_max).  A first contact found, by the
    double solver's certified answer from the proven end or, at a piece
    narrower than TIME_TOL whose end is exactly not separate, by bisection
    on the exact status: the double's intervals before it are dropped.
    Else the proven part narrows the bracket from below.
    """
    lo, hi = solution.bracket
    poly = None if hi - lo <= TIME_TOL else pair.polynomial()
    if poly is None:
        return solution
    start = Fraction(lo)
    for _ in range(STRETCH_ROUNDS):
        proven, failed = exact_stretch.separate_until(*poly, start, hi, Fraction(TIME_TOL) / 2, STRETCH_PIECES)
        if failed is None:
            return _settled_stretch_none(solution)
        piece_start, piece_end = failed
        if piece_end - piece_start <= TIME_TOL and pair.status(piece_end) != 1:
            found = pair.separation_change(piece_start, piece_end, True)
            if found is not None:
                return _with_first_contact(pair, solution, found[0], (piece_start, piece_end), first_only)
        start = proven
        window = _solve_pieces(pair.a, pair.motion_a, pair.b, pair.motion_b, t_max, True, _float_below(start))
        if window.status_at_start == 1 and not window.certified and window.reached < 0.0:
            window = _refine_exactly(pair, window, t_max)
        if window.status_at_start == 1 and window.certified:
            if not len(window.intervals):
                return _settled_stretch_none(solution)
            return _with_first_contact(pair, solution, float(window.intervals[0, 0]), window.bounds[0, :2],
                                       first_only)
    return _separate_before(solution._replace(bracket=(_float_below(start), hi), precision=RATIONAL),
                            _float_below(start))


def _separate_before(solution, start):
    """``solution`` with its intervals cut to what follows ``start``, before which the pair is proven
    separate: an interval that ends before it goes, one that spans it starts there (its brackets too), so
    that no interval claims a possible contact outside the first contact's bracket."""
    keep = [k for k in range(len(solution.intervals)) if solution.bounds[k, 3] >= start]
    intervals, bounds = solution.intervals[keep].copy(), solution.bounds[keep].copy()
    if len(keep):
        intervals[0] = np.maximum(intervals[0], start)
        bounds[0] = np.maximum(bounds[0], start)
    return solution._replace(intervals=intervals, bounds=bounds)


def _spurious_dropped(pair, solution):
    """``solution`` without the intervals the exact stretch proof shows separate throughout.

    An interval whose start or end the double solver left in a wide bracket
    may be a stretch of its rounding band rather than a contact: where the
    pair is proven separate over the whole bracket of it (entry's low end to
    exit's high end), it is dropped.  The first interval of a pair not
    separate at the start is a contact at t = 0 and stays.
    """
    poly = pair.polynomial()
    if poly is None:
        return solution
    keep = []
    for k, box in enumerate(solution.bounds.tolist()):
        open_ends = max(solution.intervals[k, 0] - box[0], box[1] - solution.intervals[k, 0],
                        solution.intervals[k, 1] - box[2], box[3] - solution.intervals[k, 1]) > TIME_TOL
        if open_ends and not (k == 0 and solution.status_at_start != 1):
            _, failed = exact_stretch.separate_until(*poly, box[0], box[3], Fraction(TIME_TOL) / 2, SPURIOUS_PIECES)
            if failed is None:
                continue
        keep.append(k)
    if len(keep) == len(solution.intervals):
        return solution
    intervals, bounds = solution.intervals[keep], solution.bounds[keep]
    certified, lo, hi = verdict(intervals, bounds, solution.reached, 1.0)
    if solution.status_at_start != 1:
        lo = hi = 0.0
    first_gone = solution.status_at_start == 1 and keep[:1] != [0]
    point, normal = solution.point, solution.normal
    if first_gone:
        point, normal = pair.touch(float(intervals[0, 0])) if len(intervals) and certified else (None, None)
    return solution._replace(intervals=intervals, bounds=bounds, point=point, normal=normal,
                             certified=bool(certified), bracket=(float(lo), float(hi)), precision=RATIONAL)


def _settled_stretch_none(solution):
    """``solution`` proven free of contact after all."""
    return solution._replace(intervals=np.empty((0, 2)), bounds=np.empty((0, 4)), point=None, normal=None,
                             certified=True, bracket=(-1.0, -1.0), reached=-1.0, precision=RATIONAL)


def _with_first_contact(pair, solution, t, entry, first_only):
    """``solution`` with its first contact proven at t, inside the proven bracket ``entry`` (lo, hi)."""
    entry = [_float_below(Fraction(entry[0])), float(entry[1])]
    if first_only:
        intervals, bounds = np.array([[t, t]]), np.array([entry + [t, t]])
    else:  # the double's intervals hold every possible contact: t lies in one of them
        keep = [k for k in range(len(solution.intervals)) if solution.bounds[k, 3] >= t]
        if not keep or solution.bounds[keep[0], 0] > t:
            return solution._replace(bracket=(entry[0], solution.bracket[1]), precision=RATIONAL)
        intervals, bounds = solution.intervals[keep].copy(), solution.bounds[keep].copy()
        intervals[0, 0] = t
        intervals[0, 1] = max(intervals[0, 1], t)
        bounds[0, :2] = entry
    certified, lo, hi = verdict(intervals, bounds, solution.reached, 1.0)
    point, normal = pair.touch(t)
    return solution._replace(intervals=intervals, bounds=bounds, point=point, normal=normal,
                             certified=bool(certified), bracket=(float(lo), float(hi)), precision=RATIONAL)


def _unsettled(a, motion_a, b, motion_b, t_max, first_only):
    """The double-precision :class:`PairSolution` of a pair, before the rational tier."""
    if _two_poses(a, motion_a, b, motion_b):
        return _unpacked(_two_pose_call(a, motion_a, b, motion_b, float(t_max), first_only))
    _check_pair(a, motion_a, b, motion_b)
    return _solve_pieces(a, motion_a, b, motion_b, t_max, first_only)


def solve_motions(a, motion_a, b, motion_b, t_max=1.0, first_only=False):
    """The one path that answers a pair: a :class:`PairSolution` over [0, t_max].

    Two bodies that each move between two poses (Static, Rigid, Affine) go to
    the fused kernel :func:`two_pose_pair`; every other pair is built in a
    local frame and over pieces of time (:func:`time_pieces`).
    """
    solution = _unsettled(a, motion_a, b, motion_b, t_max, first_only)
    return _settled(a, motion_a, b, motion_b, solution, first_only, t_max)


def _settled(a, motion_a, b, motion_b, solution, first_only, t_max):
    """The double-precision ``solution`` with what it left open settled in rational arithmetic (one
    :class:`_ExactPair` for every step, so its exact quadrics are formed once)."""
    pair = _ExactPair(a, motion_a, b, motion_b)
    if solution.status_at_start == 0:
        solution = _settle_touching_start(pair, solution, first_only)
    if not solution.certified and solution.reached < 0.0:
        solution = _refine_exactly(pair, solution, t_max)
    if not solution.certified and not first_only and solution.reached < 0.0:
        solution = _spurious_dropped(pair, solution)
    if not solution.certified and solution.status_at_start == 1:
        solution = _held_bracket(pair, solution, t_max)
        solution = _settled_stretch(pair, solution, first_only, t_max)
        if not solution.certified and not first_only and solution.reached < 0.0:
            solution = _spurious_dropped(pair, solution)
    return solution


class Contact(NamedTuple):
    """First contact of two moving bodies (a named tuple, as dm_env's TimeStep).

    ``time`` is normalised to [0, 1]; ``point`` (world) and ``normal`` (unit,
    outward from the first body) describe the touch; they are None when
    the pair already touches or overlaps at the start (``time == 0``) or when
    the answer is uncertain.  ``certainty`` is "certified", or "uncertain"
    when a limit of the search was reached: then ``bracket`` = (lo, hi) holds
    every possible first contact and ``time`` is lo, so an uncertain answer
    never reads as "no contact".  The geom solvers (:mod:`mjccd.geoms`) also
    name the two ``elements`` that touch.
    """

    time: float
    point: object
    normal: object
    status_at_start: str
    certainty: str = "certified"
    bracket: tuple = None
    elements: tuple = None     # geom solvers: the names of the two touching elements ("face +x", "rim -z", ...)


def _contact(solution):
    """The first contact of a :class:`PairSolution` as a :class:`Contact`, or None when certified free."""
    status = STATUS_NAMES[solution.status_at_start]
    if solution.status_at_start != 1:
        return Contact(0.0, None, None, status)
    if len(solution.intervals):
        if solution.certified:
            return Contact(float(solution.intervals[0, 0]), solution.point, solution.normal, status)
        lo, hi = solution.bracket  # a possible contact at lo, the low end of the bracket
        return Contact(lo, solution.point, solution.normal, status, "uncertain", (lo, hi))
    if solution.certified:
        return None
    lo, hi = solution.bracket
    return Contact(lo, None, None, status, "uncertain", (lo, hi))


def first_contact(a, motion_a, b, motion_b, *, t_max=1.0):
    """First time in [0, t_max] at which two moving ellipsoids touch, as a :class:`Contact`.

    Returns None when they are certified separate over [0, t_max].  ``t_max``
    is the running bound when many pairs are solved for the earliest contact.
    """
    if type(t_max) is not float or not 0.0 <= t_max <= 1.0:
        t_max = _validate.time_bound(t_max, "t_max")
    if not _two_poses(a, motion_a, b, motion_b):
        return _contact(solve_motions(a, motion_a, b, motion_b, t_max, True))
    out = _two_pose_call(a, motion_a, b, motion_b, t_max, True)
    status0, k, _, _, certified = out[:5].tolist()
    if needs_exact(status0, certified):
        return _contact(_settled(a, motion_a, b, motion_b, _unpacked(out), True, t_max))
    if status0 != 1:
        return Contact(0.0, None, None, STATUS_NAMES[int(status0)])
    return Contact(float(out[PACKED_HEAD]), out[7:10], out[10:13], "separate") if k > 0 else None


def collision_intervals(a, motion_a, b, motion_b):
    """Maximal time intervals [t_in, t_out] within [0, 1] where the two are not separate."""
    if not _two_poses(a, motion_a, b, motion_b):
        return [(float(x), float(y)) for x, y in solve_motions(a, motion_a, b, motion_b).intervals]
    out = _two_pose_call(a, motion_a, b, motion_b, 1.0, False)
    status0, k, _, _, certified = out[:5].tolist()
    if needs_exact(status0, certified):
        out = _settled(a, motion_a, b, motion_b, _unpacked(out), False, 1.0).intervals.ravel()
        return list(zip(out[0::2].tolist(), out[1::2].tolist()))
    times = out[PACKED_HEAD:PACKED_HEAD + 2 * int(k)].tolist()
    return list(zip(times[0::2], times[1::2]))


def solve_pair(a, motion_a, b, motion_b):
    """Status at start, first contact (a :class:`Contact` or None), all intervals, and whether the whole
    answer is certified (a first contact may be, while a later interval's end is only bracketed), in one pass."""
    solution = solve_motions(a, motion_a, b, motion_b)
    return (STATUS_NAMES[solution.status_at_start], _contact(solution),
            [(float(x), float(y)) for x, y in solution.intervals], solution.certified)
