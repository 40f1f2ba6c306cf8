"""High-precision reference solver for moving-ellipsoid CCD cases.

Pure Python + mpmath; it does not import mjccd.  Two independent measures are used:

* the static status at a time t from the signs of the roots of the quartic
  f(lam) = det(lam*A(t) - B(t)) (A, B the 4x4 world quadric matrices), and
* the Perram-Wertheim contact function F(t) = max_{lam in [0,1]} min_x
  [(1-lam) qa(x) + lam qb(x)] (qa, qb the quadratic forms equal to 1 on the
  surfaces), which is > 1 exactly when the ellipsoids are separate.

Crossings are located on F(t) - 1 (adaptive scan, extremum search, bisection) and
checked against the quartic.  Usage: ``python tests/oracle.py CASES.json -o OUT.json``.
"""
import argparse
import json
import sys

import mpmath
from mpmath import mp, mpf

DPS = 50                 # working precision (decimal digits)
T_TOL = mpf(10) ** -30   # crossing times are bracketed to this width
W_MIN = mpf(1) / 4096    # finest scan cell
N_GRID = 128             # default initial scan cells (solve_case(..., n_grid=...) overrides)


class OracleError(RuntimeError):
    """Raised when the two measures disagree or a case is malformed."""


# ---------------------------------------------------------------- small algebra
def _vec(v):
    return [mpf(x) for x in v]


def _mv(M, v):
    return [sum(M[i][k] * v[k] for k in range(len(v))) for i in range(len(M))]


def _mm(A, B):
    n, m, p = len(A), len(B), len(B[0])
    return [[sum(A[i][k] * B[k][j] for k in range(m)) for j in range(p)] for i in range(n)]


def _tr(A):
    return [list(r) for r in zip(*A)]


def _dot(a, b):
    return sum(x * y for x, y in zip(a, b))


def _eye3():
    return [[mpf(1) if i == j else mpf(0) for j in range(3)] for i in range(3)]


def _inv3(M):
    (a, b, c), (d, e, f), (g, h, i) = M
    A, B, C = e * i - f * h, f * g - d * i, d * h - e * g
    det = a * A + b * B + c * C
    if det == 0:
        raise OracleError('singular 3x3 matrix')
    adj = [[A, c * h - b * i, b * f - c * e],
           [B, a * i - c * g, c * d - a * f],
           [C, b * g - a * h, a * e - b * d]]
    return [[x / det for x in row] for row in adj]


def _poly(coeffs, t):
    acc = mpf(0)
    for c in reversed(coeffs):
        acc = acc * t + mpf(c)
    return acc


# ---------------------------------------------------------------- rotations
def quat_matrix(q):
    """rot(q)/|q|^2 for q = [w, x, y, z] (any non-zero length)."""
    w, x, y, z = _vec(q)
    n = w * w + x * x + y * y + z * z
    if n == 0:
        raise OracleError('zero quaternion')
    R = [[w * w + x * x - y * y - z * z, 2 * (x * y - w * z), 2 * (x * z + w * y)],
         [2 * (x * y + w * z), w * w - x * x + y * y - z * z, 2 * (y * z - w * x)],
         [2 * (x * z - w * y), 2 * (y * z + w * x), w * w - x * x - y * y + z * z]]
    return [[e / n for e in row] for row in R]


def _quat_lerp(q0, q1, t):
    q0, q1 = _vec(q0), _vec(q1)
    if _dot(q0, q1) < 0:
        q1 = [-x for x in q1]
    return [(1 - t) * a + t * b for a, b in zip(q0, q1)]


def _axis_angle(axis, theta):
    """Rotation about a unit axis by theta (Rodrigues' formula)."""
    n = _vec(axis)
    s = mp.sqrt(_dot(n, n))
    if s == 0:
        raise OracleError('zero axis')
    x, y, z = [v / s for v in n]
    c, si = mp.cos(theta), mp.sin(theta)
    K = [[0, -z, y], [z, 0, -x], [-y, x, 0]]
    nn = [[x * x, x * y, x * z], [y * x, y * y, y * z], [z * x, z * y, z * z]]
    return [[(c if i == j else 0) + si * K[i][j] + (1 - c) * nn[i][j] for j in range(3)]
            for i in range(3)]


# ---------------------------------------------------------------- motions
def _lerp(a, b, t):
    return [(1 - t) * mpf(x) + t * mpf(y) for x, y in zip(a, b)]


def _element(el, t):
    """(R, p) of one chain element at time t: x -> R x + p."""
    k = el['type']
    if k == 'fixed':
        return quat_matrix(el['quaternion']), _vec(el['position'])
    if k == 'hinge':
        th0, th1 = mpf(el['angle'][0]), mpf(el['angle'][1])
        u = (1 - t) * mp.tan(th0 / 2) + t * mp.tan(th1 / 2)
        return _axis_angle(el['axis'], 2 * mp.atan(u)), [mpf(0)] * 3
    if k == 'slide':
        n = _vec(el['axis'])
        s0, s1 = el['displacement']
        s = ((1 - t) * mpf(s0) + t * mpf(s1)) / mp.sqrt(_dot(n, n))
        return _eye3(), [s * v for v in n]
    if k == 'ball':
        return quat_matrix(_quat_lerp(el['start'], el['end'], t)), [mpf(0)] * 3
    if k == 'free':
        return _rigid(el, t)
    raise OracleError('unknown chain element %r' % k)


def _rigid(m, t):
    q = _quat_lerp(m['start']['quaternion'], m['end']['quaternion'], t)
    return quat_matrix(q), _lerp(m['start']['position'], m['end']['position'], t)


def frame_map(motion, t):
    """(L, p): the frame->world affine map x = L y + p at time t (not for 'affine')."""
    t = mpf(t)
    k = motion['type']
    if k == 'static':
        return quat_matrix(motion['quaternion']), _vec(motion['position'])
    if k == 'rigid':
        return _rigid(motion, t)
    if k == 'linear_affine':
        M = [[(1 - t) * mpf(a) + t * mpf(b) for a, b in zip(r0, r1)]
             for r0, r1 in zip(motion['start'], motion['end'])]
        return [row[:3] for row in M], [row[3] for row in M]
    if k == 'rational':
        den = _poly(motion['rotation_denominator'], t)
        R = [[_poly(p, t) / den for p in row] for row in motion['rotation']]
        tden = _poly(motion['translation_denominator'], t)
        return R, [_poly(p, t) / tden for p in motion['translation']]
    if k == 'chain':
        L, p = _eye3(), [mpf(0)] * 3
        for el in reversed(motion['elements']):
            R, q = _element(el, t)
            L, p = _mm(R, L), [a + b for a, b in zip(_mv(R, p), q)]
        return L, p
    raise OracleError('unknown motion %r' % k)


def _affine_shape(motion, radii, t):
    """Centre and shape matrix Q(t) of the 'affine' motion (Q lerp)."""
    D = [[mpf(1) / mpf(r) ** 2 if i == j else mpf(0) for j in range(3)] for i, r in
         enumerate(radii)]
    Qs = []
    for key in ('start', 'end'):
        R = quat_matrix(motion[key]['quaternion'])
        Qs.append(_mm(_mm(R, D), _tr(R)))
    Q = [[(1 - t) * a + t * b for a, b in zip(r0, r1)] for r0, r1 in zip(*Qs)]
    return _lerp(motion['start']['position'], motion['end']['position'], t), Q


def ellipsoid(body, t):
    """(centre, Q, Q^{-1}) of a body at time t; the ellipsoid is (x-c)^T Q (x-c) <= 1."""
    t = mpf(t)
    radii = body['radii']
    if body['motion']['type'] == 'affine':
        c, Q = _affine_shape(body['motion'], radii, t)
        return c, Q, _inv3(Q)
    L, p = frame_map(body['motion'], t)
    r2 = [mpf(r) ** 2 for r in radii]
    P = [[sum(L[i][k] * r2[k] * L[j][k] for k in range(3)) for j in range(3)] for i in range(3)]
    return p, _inv3(P), P


def quadric(body, t):
    """World 4x4 quadric matrix (mpmath matrix) X^T A X <= 0 of a body at time t."""
    t = mpf(t)
    radii = body['radii']
    if body['motion']['type'] == 'affine':
        c, Q = _affine_shape(body['motion'], radii, t)
        Qm, cm = mpmath.matrix(Q), mpmath.matrix(c)
        Qc = Qm * cm
        A = mpmath.matrix(4, 4)
        for i in range(3):
            for j in range(3):
                A[i, j] = Qm[i, j]
            A[i, 3] = A[3, i] = -Qc[i]
        A[3, 3] = (cm.T * Qc)[0] - 1
        return A
    L, p = frame_map(body['motion'], t)
    M = mpmath.matrix(4, 4)
    for i in range(3):
        for j in range(3):
            M[i, j] = L[i][j]
        M[i, 3] = p[i]
    M[3, 3] = 1
    Mi = mpmath.inverse(M)
    A0 = mpmath.diag([mpf(1) / mpf(r) ** 2 for r in radii] + [mpf(-1)])
    return Mi.T * A0 * Mi


# ---------------------------------------------------------------- static status
def quartic(A, B):
    """Coefficients (highest degree first) of det(lam*A - B), by interpolation at 5 nodes."""
    nodes = [-2, -1, 0, 1, 2]
    vals = [mpmath.det(k * A - B) for k in nodes]
    V = mpmath.matrix([[mpf(k) ** j for j in range(5)] for k in nodes])
    c = mpmath.lu_solve(V, mpmath.matrix(vals))
    return [c[4 - j] for j in range(5)]


def _roots(A, B):
    coeffs = quartic(A, B)
    return mpmath.polyroots(coeffs, maxsteps=400, extraprec=4 * mp.prec)   # highest degree first


def _negative_pair(roots):
    scale = max(abs(r) for r in roots)
    tol = mpf(10) ** -20 * scale
    return scale, [r for r in roots if mpmath.re(r) < 0 and abs(mpmath.im(r)) <= tol]


def status(case, t):
    """'separate' | 'touching' | 'overlapping' from the negative roots of det(lam A - B)."""
    with mp.workdps(2 * DPS):
        A, B = quadric(case['a'], t), quadric(case['b'], t)
        scale, neg = _negative_pair(_roots(A, B))
        if len(neg) != 2:
            return 'overlapping'
        if abs(neg[0] - neg[1]) <= mpf(10) ** -20 * scale:
            return 'touching'
        return 'separate'


def contact_point_quartic(case, t):
    """Null vector of lam0*A - B at the (near) double negative root lam0, dehomogenised."""
    with mp.workdps(2 * DPS):
        A, B = quadric(case['a'], t), quadric(case['b'], t)
        roots = [r for r in _roots(A, B) if mpmath.re(r) < 0]
        if len(roots) < 2:
            raise OracleError('no negative root pair at the contact time')
        best = None
        for i in range(len(roots)):
            for j in range(i + 1, len(roots)):
                d = abs(roots[i] - roots[j])
                if best is None or d < best[0]:
                    best = (d, roots[i], roots[j])
        lam0 = mpmath.re(best[1] + best[2]) / 2
        N = lam0 * A - B
        E, V = mpmath.eigsy(N)
        k = min(range(4), key=lambda i: abs(E[i]))
        X = [V[i, k] for i in range(4)]
        return [X[i] / X[3] for i in range(3)]


# ---------------------------------------------------------------- Perram-Wertheim
def pw_max(ca, Pa, cb, Pb):
    """(F, lam, y) with F = max_lam lam(1-lam) r^T (lam Pa + (1-lam) Pb)^{-1} r, r = cb - ca."""
    r = [b - a for a, b in zip(ca, cb)]
    Dm = [[Pa[i][j] - Pb[i][j] for j in range(3)] for i in range(3)]
    lo, hi, lam = mpf(0), mpf(1), mpf(1) / 2
    eps = mpf(10) ** (-(mp.dps * 2) // 3)
    F = None
    for _ in range(300):
        C = [[lam * Pa[i][j] + (1 - lam) * Pb[i][j] for j in range(3)] for i in range(3)]
        Ci = _inv3(C)
        y = _mv(Ci, r)
        g = _dot(r, y)
        Dy = _mv(Dm, y)
        g1 = -_dot(y, Dy)
        g2 = 2 * _dot(Dy, _mv(Ci, Dy))
        w = lam * (1 - lam)
        F = w * g
        F1 = (1 - 2 * lam) * g + w * g1
        F2 = -2 * g + 2 * (1 - 2 * lam) * g1 + w * g2
        if F1 > 0:
            lo = lam
        else:
            hi = lam
        new = lam - F1 / F2 if F2 < 0 else (lo + hi) / 2
        if not lo < new < hi:
            new = (lo + hi) / 2
        if abs(new - lam) < eps or hi - lo < eps:
            return F, lam, y
        lam = new
    raise OracleError('Perram-Wertheim maximisation did not converge')


def measure(case, t):
    """h(t) = F_PW(t) - 1: positive when separate, zero at touch, negative when overlapping."""
    ca, _, Pa = ellipsoid(case['a'], t)
    cb, _, Pb = ellipsoid(case['b'], t)
    return pw_max(ca, Pa, cb, Pb)[0] - 1


def contact_point_pw(case, t):
    """Minimiser x of (1-lam) qa(x) + lam qb(x) at the optimal lam (touch point when F=1)."""
    ca, Qa, Pa = ellipsoid(case['a'], t)
    cb, Qb, Pb = ellipsoid(case['b'], t)
    _, lam, _ = pw_max(ca, Pa, cb, Pb)
    r = [b - a for a, b in zip(ca, cb)]
    S = [[(1 - lam) * Qa[i][j] + lam * Qb[i][j] for j in range(3)] for i in range(3)]
    u = _mv(_inv3(S), _mv(Qb, r))
    return [a + lam * v for a, v in zip(ca, u)]


# ---------------------------------------------------------------- time search
class _Scan:
    """Cached evaluations of h on [0, 1]."""

    def __init__(self, case, h0_override=None):
        self.case = case
        self.cache = {}
        self.h0 = h0_override

    def __call__(self, t):
        t = mpf(t)
        if t == 0 and self.h0 is not None:
            return self.h0
        v = self.cache.get(t)
        if v is None:
            v = self.cache[t] = measure(self.case, t)
        return v


def _bisect(h, a, b, ha, hb):
    """Root of h in [a, b] with sign(ha) != sign(hb) (Illinois regula falsi)."""
    side = 0
    tol = max(T_TOL, mpf(10) ** (5 - mp.dps))
    while b - a > tol:
        c = (a * hb - b * ha) / (hb - ha)
        if not a < c < b:
            c = (a + b) / 2
        hc = h(c)
        if hc == 0:
            return c
        if (hc > 0) == (hb > 0):
            b, hb = c, hc
            if side == -1:
                ha /= 2
            side = -1
        else:
            a, ha = c, hc
            if side == 1:
                hb /= 2
            side = 1
    return (a + b) / 2


def _extremum(h, a, b, sign):
    """Golden-section search of min (sign=+1) or max (sign=-1) of h on [a, b]."""
    g = (mp.sqrt(5) - 1) / 2
    f = lambda x: sign * h(x)
    x1, x2 = b - g * (b - a), a + g * (b - a)
    f1, f2 = f(x1), f(x2)
    while b - a > mpf(10) ** -14:
        if f1 < f2:
            b, x2, f2 = x2, x1, f1
            x1 = b - g * (b - a)
            f1 = f(x1)
        else:
            a, x1, f1 = x1, x2, f2
            x2 = a + g * (b - a)
            f2 = f(x2)
        if f1 < 0 or f2 < 0:
            break
    return (x1, f1 * sign) if f1 < f2 else (x2, f2 * sign)


def crossings(case, h0_override=None, n_grid=None):
    """Sorted times in (0, 1] where h = F_PW - 1 changes sign, found by scan + refinement.

    ``n_grid`` initial scan cells (default ``N_GRID``); a feature narrower than about
    1/n_grid (e.g. the brief overlap of a 1000:1 needle) needs a dense grid to be seen.
    """
    n_grid = N_GRID if n_grid is None else int(n_grid)
    if n_grid < 2:
        raise OracleError('n_grid must be at least 2, got %r' % n_grid)
    h = _Scan(case, h0_override)
    ts = [mpf(i) / n_grid for i in range(n_grid + 1)]
    hs = [h(t) for t in ts]
    d2 = [abs(hs[i - 1] - 2 * hs[i] + hs[i + 1]) * n_grid ** 2 for i in range(1, n_grid)]
    d2 = [d2[0]] + d2 + [d2[-1]]
    tiny = mpf(10) ** -12
    cells = []           # finest cells that might hold a root
    stack = []
    for i in range(n_grid):
        # local curvature bound: 8x the largest nearby second difference
        K = 8 * max(d2[max(0, i - 2):i + 3]) + tiny
        stack.append((ts[i], ts[i + 1], K))
    while stack:
        a, b, K = stack.pop()
        ha, hb = h(a), h(b)
        w = b - a
        if (ha > 0) == (hb > 0) and min(abs(ha), abs(hb)) > K * w * w / 8:
            continue
        if w <= W_MIN:
            cells.append((a, b))
            continue
        m = (a + b) / 2
        hm = h(m)
        K = max(K, 8 * abs(ha - 2 * hm + hb) / (w / 2) ** 2)
        stack += [(a, m, K), (m, b, K)]
    cells.sort()
    roots = []
    done_ext = set()
    for a, b in cells:
        ha, hb = h(a), h(b)
        if (ha > 0) != (hb > 0):
            roots.append(_bisect(h, a, b, ha, hb))
            continue
        # same sign: look for a dip through zero around this cell
        lo, hi = max(mpf(0), a - (b - a)), min(mpf(1), b + (b - a))
        sign = 1 if ha > 0 else -1
        x, fx = _extremum(h, lo, hi, sign)
        key = mpmath.nstr(x, 12)
        if key in done_ext:
            continue
        done_ext.add(key)
        if (fx > 0) != (ha > 0):
            hl, hr = h(lo), h(hi)
            if (hl > 0) != (fx > 0):
                roots.append(_bisect(h, lo, x, hl, fx))
            if (hr > 0) != (fx > 0):
                roots.append(_bisect(h, x, hi, fx, hr))
    roots.sort()
    out = []
    for r in roots:   # merge duplicates from overlapping refinement windows
        if not out or r - out[-1] > mpf(10) ** -20:
            out.append(r)
    return out, h


def solve_case(case, check=True, n_grid=None):
    """Reference result dict (DESIGN.md format) for one case.

    ``n_grid``: initial scan cells of the crossing search (default ``N_GRID``).
    """
    with mp.workdps(DPS):
        st0 = status(case, 0)
        h0 = None
        if st0 == 'touching':
            h0 = -mpf(10) ** -(DPS - 5)   # exact touch at t=0 counts as "not separate"
        roots, h = crossings(case, h0, n_grid)
        inside = st0 != 'separate'
        if check:
            _check(case, st0, h, n_grid)
        intervals = []
        cur = mpf(0) if inside else None
        for r in roots:
            if cur is None:
                cur = r
            else:
                intervals.append([cur, r])
                cur = None
        if cur is not None:
            intervals.append([cur, mpf(1)])
        first = intervals[0][0] if intervals else None
        point = None
        if first is not None and first > 0:
            point = contact_point_quartic(case, first)
            if check:
                p2 = contact_point_pw(case, first)
                size = max(max(case['a']['radii']), max(case['b']['radii']))
                d = mp.sqrt(sum((x - y) ** 2 for x, y in zip(point, p2)))
                if d > mpf(10) ** -15 * size:
                    raise OracleError('%s: contact points disagree by %s' % (case['id'], d))
        if check:
            for lo, hi in intervals:
                mid = (lo + hi) / 2
                if hi - lo > mpf(10) ** -12 and status(case, mid) == 'separate':
                    raise OracleError('%s: quartic says separate inside %s' % (case['id'], [lo, hi]))
                for e in (lo, hi):
                    if 0 < e < 1:
                        for d in (mpf(10) ** -12, -mpf(10) ** -12):
                            s = status(case, e + d)
                            if (s == 'separate') != (h(e + d) > 0):
                                raise OracleError('%s: measures disagree near %s' % (case['id'], e))
        return {
            'id': case['id'],
            'status_at_start': st0,
            'first_contact': None if first is None else float(first),
            'intervals': [[float(a), float(b)] for a, b in intervals],
            'contact_point': None if point is None else [float(x) for x in point],
        }


def _check(case, st0, h, n_grid=None):
    """The quartic status must agree with the sign of the PW measure on the scan grid.

    Checked at 33 evenly spaced grid points whatever the grid (every 4th point of the
    default grid): the quartic roots are the expensive part.
    """
    n_grid = N_GRID if n_grid is None else int(n_grid)
    step = max(1, n_grid // 32)
    for i in range(0, n_grid + 1, step):
        t = mpf(i) / n_grid
        v = h(t)
        if abs(v) < mpf(10) ** -20:
            continue
        s = st0 if i == 0 else status(case, t)
        if (s == 'separate') != (v > 0):
            raise OracleError('%s: status %s but PW measure %s at t=%s'
                              % (case['id'], s, mpmath.nstr(v, 5), t))


def solve_cases(cases, check=True, n_grid=None):
    """Reference results for a {"version": 1, "cases": [...]} dict."""
    return {'version': 1, 'results': [solve_case(c, check, n_grid) for c in cases['cases']]}


# ---------------------------------------------------------------- scoring
TIME_TOL = 1e-9    # |dt| allowed on first contact and interval endpoints
POINT_TOL = 1e-6   # contact point error allowed, relative to the largest radius


def compare(case, expected, got):
    """Reasons (list of str) why ``got`` does not match ``expected``; empty when it does.

    Same criteria as tests/data/check.py.
    """
    why = []
    if got is None:
        return ['missing result']
    if 'error' in got:
        return ['error: %s' % got['error']]
    if got.get('status_at_start') != expected['status_at_start']:
        why.append('status %s != %s' % (got.get('status_at_start'), expected['status_at_start']))
    fe, fg = expected['first_contact'], got.get('first_contact')
    if (fe is None) != (fg is None):
        why.append('first_contact %s, expected %s' % (fg, fe))
    elif fe is not None and not abs(float(fe) - float(fg)) <= TIME_TOL:
        why.append('first_contact |dt|=%.3g' % abs(float(fe) - float(fg)))
    ie, ig = expected['intervals'], got.get('intervals') or []
    if len(ie) != len(ig):
        why.append('%d intervals, expected %d' % (len(ig), len(ie)))
    else:
        for pe, pg in zip(ie, ig):
            for x, y in zip(pe, pg):
                if not abs(float(x) - float(y)) <= TIME_TOL:
                    why.append('interval endpoint |dt|=%.3g' % abs(float(x) - float(y)))
    pe, pg = expected['contact_point'], got.get('contact_point')
    size = max(max(case['a']['radii']), max(case['b']['radii']))
    if (pe is None) != (pg is None):
        why.append('contact_point %s, expected %s' % (pg, pe))
    elif pe is not None:
        d = sum((float(x) - float(y)) ** 2 for x, y in zip(pe, pg)) ** 0.5
        if len(pg) != 3 or not d <= POINT_TOL * size:
            why.append('contact_point |dp|/size=%.3g' % (d / size))
    return why


def _worker(args):
    case, check, n_grid = args
    return solve_case(case, check, n_grid)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument('cases')
    ap.add_argument('-o', '--output')
    ap.add_argument('-j', '--jobs', type=int, default=1)
    ap.add_argument('--no-check', action='store_true')
    ap.add_argument('--grid', type=int, default=N_GRID,
                    help='initial scan cells (default %(default)s; 2048 for 1000:1 needles)')
    a = ap.parse_args(argv)
    cases = json.load(open(a.cases))['cases']
    args = [(c, not a.no_check, a.grid) for c in cases]
    if a.jobs > 1:
        import multiprocessing
        with multiprocessing.Pool(a.jobs) as pool:
            res = pool.map(_worker, args, chunksize=1)
    else:
        res = [_worker(x) for x in args]
    out = json.dumps({'version': 1, 'results': res}, indent=1)
    if a.output:
        with open(a.output, 'w') as f:
            f.write(out + '\n')
    else:
        sys.stdout.write(out + '\n')


if __name__ == '__main__':
    main()
