"""Generate the brute-force reference cases and their oracle answers.

    python tests/make_reference.py [-j JOBS]

writes tests/data/bruteforce_cases.json and tests/data/bruteforce_expected.json.  The
cases are random (fixed seed) moving-ellipsoid pairs covering every motion model; about
half collide, some start overlapping or touching, some have several contact intervals,
some are near misses or shallow grazes whose clearance is tuned with the oracle.
"""
import argparse
import json
import math
import multiprocessing
import os
import random
import sys

from mpmath import mp, mpf

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import oracle  # noqa: E402

SEED = 20080521
HERE = os.path.dirname(os.path.abspath(__file__))
DATA = os.path.join(HERE, 'data')

# (kind of a, kind of b, number of cases)
GROUPS = [
    ('rigid', 'rigid', 40), ('rigid', 'static', 31), ('affine', 'affine', 25),
    ('affine', 'static', 6), ('affine', 'rigid', 6), ('linear_affine', 'linear_affine', 20),
    ('linear_affine', 'static', 8), ('linear_affine', 'rigid', 6), ('rational', 'rational', 16),
    ('rational', 'static', 12), ('rational', 'rigid', 8), ('chain', 'static', 20),
    ('chain', 'chain', 16), ('chain', 'rigid', 10), ('chain', 'rational', 6),
    ('chain', 'linear_affine', 6),
]
# scenario mix, cycled through each group
SCENARIOS = ['collide', 'miss', 'near-miss', 'collide', 'graze', 'miss', 'start-overlap',
             'multi', 'miss', 'collide', 'near-miss', 'graze', 'miss', 'multi']
NEAR_MISS_EPS = 1e-3                     # relative clearance of near misses
GRAZE_EPS = [-1e-4, -1e-5, -1e-6]        # relative penetration of shallow grazes


# ------------------------------------------------------------------ random pieces
def unit_quat(rng):
    q = [rng.gauss(0, 1) for _ in range(4)]
    n = math.sqrt(sum(x * x for x in q))
    return [x / n for x in q]


def quat_mul(a, b):
    w1, x1, y1, z1 = a
    w2, x2, y2, z2 = b
    return [w1 * w2 - x1 * x2 - y1 * y2 - z1 * z2, w1 * x2 + x1 * w2 + y1 * z2 - z1 * y2,
            w1 * y2 - x1 * z2 + y1 * w2 + z1 * x2, w1 * z2 + x1 * y2 - y1 * x2 + z1 * w2]


def turn(rng, q, max_angle):
    """q followed by a random rotation of angle up to max_angle."""
    ang = rng.uniform(0, max_angle)
    ax = unit_vec(rng)
    d = [math.cos(ang / 2)] + [math.sin(ang / 2) * v for v in ax]
    return quat_mul(d, q)


def unit_vec(rng):
    v = [rng.gauss(0, 1) for _ in range(3)]
    n = math.sqrt(sum(x * x for x in v))
    return [x / n for x in v]


def radii(rng, elongated=False):
    big = rng.uniform(0.25, 1.0)
    lo = max(0.1, big / (5.0 if elongated else rng.choice([1.5, 3.0, 5.0])))
    r = [big, rng.uniform(lo, big), lo if elongated else rng.uniform(lo, big)]
    rng.shuffle(r)
    return r


def rand_pos(rng, s=0.5):
    return [rng.uniform(-s, s) for _ in range(3)]


def pose(rng, p, q):
    return {'position': p, 'quaternion': q}


def rot_matrix(q):
    w, x, y, z = q
    n = w * w + x * x + y * y + z * z
    return [[(w * w + x * x - y * y - z * z) / n, 2 * (x * y - w * z) / n, 2 * (x * z + w * y) / n],
            [2 * (x * y + w * z) / n, (w * w - x * x + y * y - z * z) / n, 2 * (y * z - w * x) / n],
            [2 * (x * z - w * y) / n, 2 * (y * z + w * x) / n, (w * w - x * x - y * y + z * z) / n]]


def det3(m):
    return (m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1])
            - m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0])
            + m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0]))


# polynomials: power basis, lowest degree first
def padd(a, b):
    n = max(len(a), len(b))
    return [(a[i] if i < len(a) else 0.0) + (b[i] if i < len(b) else 0.0) for i in range(n)]


def pmul(a, b):
    out = [0.0] * (len(a) + len(b) - 1)
    for i, x in enumerate(a):
        for j, y in enumerate(b):
            out[i + j] += x * y
    return out


def pscale(a, s):
    return [s * x for x in a]


def peval(a, t):
    return sum(c * t ** i for i, c in enumerate(a))


# ------------------------------------------------------------------ motions
def motion(rng, kind, fast=False):
    """A random motion of the given kind near the origin; fast = large rotations."""
    travel = rng.uniform(0.1, 0.6) if fast else rng.uniform(0.3, 2.0)
    p0 = rand_pos(rng)
    d = unit_vec(rng)
    p1 = [a + travel * b for a, b in zip(p0, d)]
    q0 = unit_quat(rng)
    max_turn = 3.1 if fast else rng.choice([0.3, 1.5, 3.0])
    q1 = turn(rng, q0, max_turn)
    if kind == 'static':
        return {'type': 'static', 'position': p0, 'quaternion': q0}
    if kind in ('rigid', 'affine'):
        return {'type': kind, 'start': pose(rng, p0, q0), 'end': pose(rng, p1, q1)}
    if kind == 'linear_affine':
        return linear_affine(rng, p0, p1, q0, fast)
    if kind == 'rational':
        return rational(rng, p0, p1, fast)
    if kind == 'chain':
        return chain(rng, p0, p1, fast)
    raise ValueError(kind)


def linear_affine(rng, p0, p1, q0, fast):
    while True:
        q1 = turn(rng, q0, 1.6 if fast else 1.0)
        mats = []
        for q, p in ((q0, p0), (q1, p1)):
            R = rot_matrix(q)
            S = [[rng.uniform(0.7, 1.4) if i == j else rng.uniform(-0.2, 0.2) for j in range(3)]
                 for i in range(3)]
            L = [[sum(R[i][k] * S[k][j] for k in range(3)) for j in range(3)] for i in range(3)]
            mats.append([L[i] + [p[i]] for i in range(3)])
        dets = []
        for k in range(201):
            t = k / 200
            L = [[(1 - t) * mats[0][i][j] + t * mats[1][i][j] for j in range(3)] for i in range(3)]
            dets.append(det3(L))
        if min(dets) > 0.2 * max(dets):   # det is a cubic: dense samples bound it
            return {'type': 'linear_affine', 'start': mats[0], 'end': mats[1]}


def rational(rng, p0, p1, fast):
    """Rotation rot(e)/|e|^2 with a polynomial quaternion e(t) (dyadic coefficients)."""
    deg = 2 if fast or rng.random() < 0.5 else 1
    while True:
        e = [[rng.randint(-24, 24) / 16.0 for _ in range(deg + 1)] for _ in range(4)]
        w, x, y, z = e
        den = padd(padd(pmul(w, w), pmul(x, x)), padd(pmul(y, y), pmul(z, z)))
        vals = [peval(den, k / 100) for k in range(101)]
        if min(vals) > 0.15 * max(vals) and min(vals) > 0.2:
            break
    neg = lambda a: pscale(a, -1.0)
    two = lambda a: pscale(a, 2.0)
    rot = [[padd(padd(pmul(w, w), pmul(x, x)), neg(padd(pmul(y, y), pmul(z, z)))),
            two(padd(pmul(x, y), neg(pmul(w, z)))), two(padd(pmul(x, z), pmul(w, y)))],
           [two(padd(pmul(x, y), pmul(w, z))),
            padd(padd(pmul(w, w), pmul(y, y)), neg(padd(pmul(x, x), pmul(z, z)))),
            two(padd(pmul(y, z), neg(pmul(w, x))))],
           [two(padd(pmul(x, z), neg(pmul(w, y)))), two(padd(pmul(y, z), pmul(w, x))),
            padd(padd(pmul(w, w), pmul(z, z)), neg(padd(pmul(x, x), pmul(y, y))))]]
    if rng.random() < 0.5:
        # polynomial translation of degree <= 3 through p0 and p1
        tr = []
        for a, b in zip(p0, p1):
            c2, c3 = rng.uniform(-0.5, 0.5), rng.uniform(-0.5, 0.5)
            tr.append([a, b - a - c2 - c3, c2, c3])
        tden = [1.0]
    else:
        # rational translation sharing the rotation's denominator
        tr = [padd(pscale(den, a), pscale([0.0] + [rng.uniform(-1, 1) for _ in range(len(den) - 1)],
                                          1.0 + abs(b - a))) for a, b in zip(p0, p1)]
        tden = list(den)
    return {'type': 'rational', 'rotation': rot, 'rotation_denominator': den,
            'translation': tr, 'translation_denominator': tden}


def chain(rng, p0, p1, fast):
    """Base (fixed or free) followed by 1-3 joints / link offsets."""
    n = rng.choice([2, 3, 3, 4])
    q0 = unit_quat(rng)
    if rng.random() < 0.3:
        els = [{'type': 'free', 'start': pose(rng, p0, q0),
                'end': pose(rng, [(a + b) / 2 for a, b in zip(p0, p1)], turn(rng, q0, 1.0))}]
    else:
        els = [{'type': 'fixed', 'position': p0, 'quaternion': q0}]
    for k in range(1, n):
        last = k == n - 1
        choice = rng.choice(['hinge', 'hinge', 'slide', 'ball', 'fixed'])
        if last and n > 2 and rng.random() < 0.6:
            choice = 'fixed'
        if choice == 'hinge':
            lim = 2.9 if fast else 2.2
            els.append({'type': 'hinge', 'axis': unit_vec(rng),
                        'angle': [rng.uniform(-lim, lim), rng.uniform(-lim, lim)]})
        elif choice == 'slide':
            els.append({'type': 'slide', 'axis': [rng.uniform(-1, 1) for _ in range(3)],
                        'displacement': [rng.uniform(-0.5, 0.5), rng.uniform(-0.5, 1.5)]})
        elif choice == 'ball':
            qa = unit_quat(rng)
            els.append({'type': 'ball', 'start': qa, 'end': turn(rng, qa, 2.5)})
        else:
            off = [rng.uniform(0.2, 0.7) * v for v in unit_vec(rng)]
            els.append({'type': 'fixed', 'position': off, 'quaternion': unit_quat(rng)})
    return {'type': 'chain', 'elements': els}


def shifted(m, v):
    """The motion m followed by a constant translation v."""
    m = json.loads(json.dumps(m))
    k = m['type']
    if k == 'static':
        m['position'] = [a + b for a, b in zip(m['position'], v)]
    elif k in ('rigid', 'affine'):
        for key in ('start', 'end'):
            m[key]['position'] = [a + b for a, b in zip(m[key]['position'], v)]
    elif k == 'linear_affine':
        for key in ('start', 'end'):
            for i in range(3):
                m[key][i][3] += v[i]
    elif k == 'rational':
        m['translation'] = [padd(p, pscale(m['translation_denominator'], s))
                            for p, s in zip(m['translation'], v)]
    elif k == 'chain':
        base = m['elements'][0]
        if base['type'] == 'fixed':
            base['position'] = [a + b for a, b in zip(base['position'], v)]
        else:
            for key in ('start', 'end'):
                base[key]['position'] = [a + b for a, b in zip(base[key]['position'], v)]
    return m


# ------------------------------------------------------------------ arrangement
def centre(body, t):
    with mp.workdps(20):
        return [float(x) for x in oracle.ellipsoid(body, mpf(t))[0]]


def min_measure(case, n=96):
    """Global minimum over t of the Perram-Wertheim measure h (coarse grid + golden search)."""
    with mp.workdps(20):
        hs = [oracle.measure(case, mpf(i) / n) for i in range(n + 1)]
        i = min(range(n + 1), key=lambda k: hs[k])
        lo, hi = mpf(max(0, i - 1)) / n, mpf(min(n, i + 1)) / n
        g = (math.sqrt(5) - 1) / 2
        a, b = lo, hi
        x1, x2 = b - g * (b - a), a + g * (b - a)
        f1, f2 = oracle.measure(case, x1), oracle.measure(case, x2)
        for _ in range(40):
            if f1 < f2:
                b, x2, f2 = x2, x1, f1
                x1 = b - g * (b - a)
                f1 = oracle.measure(case, x1)
            else:
                a, x1, f1 = x1, x2, f2
                x2 = a + g * (b - a)
                f2 = oracle.measure(case, x2)
        return float(min(f1, f2, hs[i])), float(x1)


def tune(case, base_shift, n, target):
    """Shift b by base_shift + s*n with s chosen so that min_t h = target; None if it fails."""
    def g(s):
        c = dict(case, b=dict(case['b'], motion=shifted(case['b']['motion'],
                                                        [a + s * d for a, d in zip(base_shift, n)])))
        return min_measure(c)[0] - target, c
    size = max(case['a']['radii']) + max(case['b']['radii'])
    lo, hi = 0.0, size
    glo, ghi = g(lo)[0], g(hi)[0]
    for _ in range(8):
        if ghi > 0:
            break
        hi *= 2
        ghi = g(hi)[0]
    if not (glo < 0 < ghi):
        return None
    for _ in range(60):
        s = hi - ghi * (hi - lo) / (ghi - glo)
        if not lo < s < hi:
            s = (lo + hi) / 2
        val, c = g(s)
        if abs(val) <= 0.02 * abs(target):
            return c
        if val < 0:
            lo, glo = s, val
        else:
            hi, ghi = s, val
        if hi - lo < 1e-14:
            return None
    return None


def _runs(case, m=40):
    """Number of runs of negative h on a coarse grid."""
    with mp.workdps(15):
        neg = [oracle.measure(case, mpf(i) / m) < 0 for i in range(m + 1)]
    return sum(1 for i in range(m + 1) if neg[i] and (i == 0 or not neg[i - 1]))


def _multi(case, rng, tc, rsum):
    """Try random offsets of b near a's path for one giving two or more contact intervals."""
    b = case['b']
    for _ in range(24):
        ts = rng.uniform(0, 1)
        v = [x - y + rsum * rng.uniform(0.3, 1.0) * z for x, y, z in
             zip(centre(case['a'], ts), centre(b, ts), unit_vec(rng))]
        c = dict(case, b=dict(b, motion=shifted(b['motion'], v)))
        if _runs(c) >= 2 and quick_intervals(c) >= 2:
            c['tags'] = ['multi']
            return c
    return None


def quick_intervals(case):
    with mp.workdps(20):
        roots, _ = oracle.crossings(case)
        start_in = oracle.status(case, 0) != 'separate'
    return (len(roots) + (1 if start_in else 0) + 1) // 2


def build_case(rng, cid, ka, kb, scenario):
    fast = scenario == 'multi'
    a = {'radii': radii(rng, elongated=fast), 'motion': motion(rng, ka, fast)}
    b = {'radii': radii(rng, elongated=fast), 'motion': motion(rng, kb, fast)}
    case = {'id': cid, 'a': a, 'b': b}
    tc = 0.0 if scenario == 'start-overlap' else rng.uniform(0.15, 0.85)
    ca, cb = centre(a, tc), centre(b, tc)
    n = unit_vec(rng)
    base = [x - y for x, y in zip(ca, cb)]
    rsum = max(a['radii']) + max(b['radii'])
    rmin = min(a['radii']) + min(b['radii'])
    if scenario in ('near-miss', 'graze'):
        if scenario == 'near-miss':
            eps = NEAR_MISS_EPS
        else:
            eps = GRAZE_EPS[rng.randrange(len(GRAZE_EPS))]
        c = tune(case, base, n, 2 * eps + eps * eps)
        if c is None or not 0.03 < min_measure(c)[1] < 0.97:
            return None                      # tuned extremum must be interior
        c['tags'] = [scenario, 'eps=%g' % eps]
        return c
    if scenario == 'collide':
        d = rng.uniform(0.1, 0.9) * rmin
    elif scenario == 'miss':
        d = rng.uniform(1.05, 1.6) * rsum
    elif scenario == 'start-overlap':
        d = rng.uniform(0.0, 0.8) * rmin
    else:  # multi
        d = rng.uniform(0.5, 1.0) * rsum
    case['b'] = dict(b, motion=shifted(b['motion'], [x + d * y for x, y in zip(base, n)]))
    if scenario == 'multi':
        return _multi(case, rng, tc, rsum)
    if scenario == 'miss' and min_measure(case)[0] < 0.05:
        return None                          # keep misses clear of contact
    if scenario == 'collide':
        with mp.workdps(20):
            if oracle.status(case, 0) != 'separate' or oracle.measure(case, tc) > 0:
                return None
    case['tags'] = [scenario] if scenario in ('miss', 'multi', 'start-overlap') else []
    return case


def touching_cases():
    """Exactly touching at t = 0 (all numbers dyadic), moving into each other."""
    eye = [1.0, 0.0, 0.0, 0.0]
    out = [
        {'a': {'radii': [0.5, 0.5, 0.5], 'motion': {'type': 'static', 'position': [0.0, 0.0, 0.0],
                                                   'quaternion': eye}},
         'b': {'radii': [0.25, 0.25, 0.25],
               'motion': {'type': 'rigid', 'start': {'position': [0.75, 0.0, 0.0], 'quaternion': eye},
                          'end': {'position': [-0.25, 0.875, 0.0], 'quaternion': [0.0, 0.0, 0.0, 1.0]}}}},
        {'a': {'radii': [0.5, 0.25, 1.0], 'motion': {'type': 'static', 'position': [0.0, 0.0, 0.0],
                                                    'quaternion': eye}},
         'b': {'radii': [0.25, 0.5, 0.125],
               'motion': {'type': 'rigid', 'start': {'position': [0.75, 0.0, 0.0], 'quaternion': eye},
                          'end': {'position': [0.5, 0.125, 0.0], 'quaternion': [0.0, 0.0, 0.0, 1.0]}}}},
        {'a': {'radii': [0.5, 0.5, 0.5],
               'motion': {'type': 'affine', 'start': {'position': [0.0, 0.0, 0.0], 'quaternion': eye},
                          'end': {'position': [0.125, 0.0, 0.0], 'quaternion': [1.0, 0.0, 1.0, 0.0]}}},
         'b': {'radii': [0.5, 0.5, 0.5], 'motion': {'type': 'static', 'position': [1.0, 0.0, 0.0],
                                                   'quaternion': eye}}},
        {'a': {'radii': [0.25, 0.5, 0.5],
               'motion': {'type': 'linear_affine', 'start': [[1.0, 0, 0, 0], [0, 1.0, 0, 0], [0, 0, 1.0, 0]],
                          'end': [[1.0, 0, 0, 0.25], [0, 0.5, 0, 0], [0, 0, 1.0, 0.5]]}},
         'b': {'radii': [0.25, 0.25, 0.25], 'motion': {'type': 'static', 'position': [0.5, 0.0, 0.0],
                                                      'quaternion': [0.0, 1.0, 0.0, 0.0]}}},
    ]
    for i, c in enumerate(out):
        c['id'] = 'bf-touch-%02d' % (i + 1)
        c['tags'] = ['start-touching', 'exact-dyadic']
    return out


def kind_tag(case):
    return '%s/%s' % (case['a']['motion']['type'], case['b']['motion']['type'])


def result_tags(case, res):
    tags = list(case.get('tags', []))
    tags.insert(0, kind_tag(case))
    if case['a']['motion']['type'] == 'chain' or case['b']['motion']['type'] == 'chain':
        n = max(len(m['elements']) for m in (case['a']['motion'], case['b']['motion'])
                if m['type'] == 'chain')
        tags.append('chain-%d' % n)
    iv = res['intervals']
    if len(iv) >= 2 and 'multi-interval' not in tags:
        tags.append('multi-interval')
    if not iv:
        tags.append('no-contact')
    if res['status_at_start'] == 'overlapping' and 'start-overlapping' not in tags:
        tags.append('start-overlapping')
    if iv and iv[-1][1] == 1.0:
        tags.append('contact-at-end')
    return [t for t in tags if t not in ('multi', 'start-overlap', 'collide')]


def _solve(case):
    r = oracle.solve_case(case, check=True)
    print('solved', case['id'], file=sys.stderr, flush=True)
    return r


def _build(spec):
    """One case from (id, kind a, kind b, scenario); its own seeded generator."""
    cid, ka, kb, scen = spec
    rng = random.Random('%d-%s' % (SEED, cid))
    for _ in range(12 if scen == 'multi' else 40):
        c = build_case(rng, cid, ka, kb, scen)
        if c is not None:
            print(cid, scen, file=sys.stderr, flush=True)
            return c
    for _ in range(40):
        c = build_case(rng, cid, ka, kb, 'collide')
        if c is not None:
            print(cid, scen, '-> collide', file=sys.stderr, flush=True)
            return c
    raise RuntimeError('cannot build %s' % cid)


def specs():
    out = []
    k = 0
    for ka, kb, count in GROUPS:
        for i in range(count):
            cid = 'bf-%s-%s-%02d' % (ka.replace('_', ''), kb.replace('_', ''), i + 1)
            out.append((cid, ka, kb, SCENARIOS[k % len(SCENARIOS)]))
            k += 1
    return out


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument('-j', '--jobs', type=int, default=os.cpu_count() or 1)
    ap.add_argument('-o', '--outdir', default=DATA)
    a = ap.parse_args(argv)
    with multiprocessing.Pool(a.jobs) as pool:
        cases = touching_cases() + pool.map(_build, specs(), chunksize=1)
        res = pool.map(_solve, cases, chunksize=1)
    for c, r in zip(cases, res):
        c['tags'] = result_tags(c, r)
    os.makedirs(a.outdir, exist_ok=True)
    with open(os.path.join(a.outdir, 'bruteforce_cases.json'), 'w') as f:
        json.dump({'version': 1, 'cases': cases}, f, indent=1)
        f.write('\n')
    with open(os.path.join(a.outdir, 'bruteforce_expected.json'), 'w') as f:
        json.dump({'version': 1, 'results': res}, f, indent=1)
        f.write('\n')
    print('%d cases' % len(cases), file=sys.stderr)
    n_hit = sum(1 for r in res if r['intervals'])
    n_multi = sum(1 for r in res if len(r['intervals']) >= 2)
    print('%d cases, %d collide, %d multi-interval' % (len(cases), n_hit, n_multi))


if __name__ == '__main__':
    main()
