"""Invariance properties of the CCD answers, checked through ``mjccd.solve_cases``.

Cases are drawn on a dyadic grid and the transforms are the 24 rotations of the cube,
dyadic translations and power-of-two scalings, so the transformed case describes exactly
the same geometry (no rounding in the input): the answers must agree to the accuracy
target (1e-9 in t, 1e-6 of the size for the contact point).
"""
import copy
import itertools
import math
import os
import sys

from hypothesis import assume, given, settings, strategies as st

import mjccd

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from make_reference import quat_mul, rot_matrix  # noqa: E402  (exact rational quaternion helpers)

TOL_T = 1e-9
TOL_P = 1e-6
SETTINGS = settings(max_examples=30, deadline=None, derandomize=True)


# ------------------------------------------------------------------ exact rotations
def _cube_quats():
    """Integer quaternions q with rot(q)/|q|^2 a signed permutation (the 24 cube rotations)."""
    out, seen = [], set()
    for q in itertools.product([-1, 0, 1], repeat=4):
        nz = sum(1 for v in q if v)
        if nz not in (1, 2, 4):
            continue
        R = tuple(tuple(row) for row in rot_matrix(q))
        if R not in seen:
            seen.add(R)
            out.append([float(v) for v in q])
    return out


CUBE = _cube_quats()
assert len(CUBE) == 24


def _mv(R, v):
    return [sum(R[i][k] * v[k] for k in range(3)) for i in range(3)]


# ------------------------------------------------------------------ transforms of JSON
def transform_motion(m, g, p):
    """Motion followed by x -> R(g) x + p."""
    m = copy.deepcopy(m)
    R = rot_matrix(g)
    pt = lambda v: [a + b for a, b in zip(_mv(R, v), p)]
    k = m['type']
    if k == 'static':
        m['position'], m['quaternion'] = pt(m['position']), quat_mul(g, m['quaternion'])
    elif k in ('rigid', 'affine'):
        for key in ('start', 'end'):
            m[key]['position'] = pt(m[key]['position'])
            m[key]['quaternion'] = quat_mul(g, m[key]['quaternion'])
    elif k == 'linear_affine':
        for key in ('start', 'end'):
            M = m[key]
            cols = [_mv(R, [M[i][j] for i in range(3)]) for j in range(3)] + [pt([M[i][3] for i in range(3)])]
            m[key] = [[cols[j][i] for j in range(4)] for i in range(3)]
    elif k == 'rational':
        rot = m['rotation']
        m['rotation'] = [[_padd(*[[R[i][k_] * c for c in rot[k_][j]] for k_ in range(3)])
                          for j in range(3)] for i in range(3)]
        tr, den = m['translation'], m['translation_denominator']
        m['translation'] = [_padd(*([[R[i][k_] * c for c in tr[k_]] for k_ in range(3)]
                                    + [[p[i] * c for c in den]])) for i in range(3)]
    elif k == 'chain':
        base = m['elements'][0]
        assert base['type'] == 'fixed'
        base['position'], base['quaternion'] = pt(base['position']), quat_mul(g, base['quaternion'])
    return m


def scale_motion(m, s):
    """Motion with every length multiplied by s."""
    m = copy.deepcopy(m)
    k = m['type']
    if k == 'static':
        m['position'] = [s * v for v in m['position']]
    elif k in ('rigid', 'affine'):
        for key in ('start', 'end'):
            m[key]['position'] = [s * v for v in m[key]['position']]
    elif k == 'linear_affine':
        for key in ('start', 'end'):
            for row in m[key]:
                row[3] *= s
    elif k == 'rational':
        m['translation'] = [[s * c for c in poly] for poly in m['translation']]
    elif k == 'chain':
        for el in m['elements']:
            if el['type'] == 'fixed':
                el['position'] = [s * v for v in el['position']]
            elif el['type'] == 'slide':
                el['displacement'] = [s * v for v in el['displacement']]
    return m


def _padd(*polys):
    n = max(len(p) for p in polys)
    return [sum(p[i] for p in polys if i < len(p)) for i in range(n)]


# ------------------------------------------------------------------ strategies (dyadic)
def dy(lo, hi, den=32):
    return st.integers(int(lo * den), int(hi * den)).map(lambda k: k / den)


vec = st.lists(dy(-0.75, 0.75), min_size=3, max_size=3)
quat = st.lists(st.integers(-4, 4), min_size=4, max_size=4).filter(any).map(
    lambda q: [v / 4 for v in q])


@st.composite
def radii(draw):
    big = draw(dy(0.25, 1.0))
    r = [big] + [draw(dy(max(0.125, big / 5), big)) for _ in range(2)]
    return draw(st.permutations(r))


@st.composite
def motion(draw):
    kind = draw(st.sampled_from(['static', 'rigid', 'affine', 'linear_affine', 'rational',
                                 'chain']))
    if kind == 'static':
        return {'type': 'static', 'position': draw(vec), 'quaternion': draw(quat)}
    if kind in ('rigid', 'affine'):
        return {'type': kind, 'start': {'position': draw(vec), 'quaternion': draw(quat)},
                'end': {'position': draw(vec), 'quaternion': draw(quat)}}
    if kind == 'linear_affine':
        mats = []
        for _ in range(2):
            R = rot_matrix(draw(quat))
            sc = [draw(dy(0.75, 1.25, 8)) for _ in range(3)]
            pos = draw(vec)
            mats.append([[R[i][j] * sc[j] for j in range(3)] + [pos[i]] for i in range(3)])
        dets = [_det([[(1 - t) * a + t * b for a, b in zip(r0[:3], r1[:3])]
                      for r0, r1 in zip(*mats)]) for t in [k / 64 for k in range(65)]]
        assume(min(dets) > 0.2 * max(dets))
        return {'type': 'linear_affine', 'start': mats[0], 'end': mats[1]}
    if kind == 'rational':
        e = [[draw(st.integers(-8, 8)) / 8 for _ in range(2)] for _ in range(4)]
        den = _padd(*[_pmul(c, c) for c in e])
        assume(min(den[0] + den[1] * t + den[2] * t * t for t in (0, 0.25, 0.5, 0.75, 1)) > 0.25)
        w, x, y, z = e
        neg = lambda p: [-c for c in p]
        two = lambda p: [2 * c for c in p]
        rot = [[_padd(_pmul(w, w), _pmul(x, x), neg(_pmul(y, y)), neg(_pmul(z, z))),
                two(_padd(_pmul(x, y), neg(_pmul(w, z)))), two(_padd(_pmul(x, z), _pmul(w, y)))],
               [two(_padd(_pmul(x, y), _pmul(w, z))),
                _padd(_pmul(w, w), _pmul(y, y), neg(_pmul(x, x)), neg(_pmul(z, z))),
                two(_padd(_pmul(y, z), neg(_pmul(w, x))))],
               [two(_padd(_pmul(x, z), neg(_pmul(w, y)))), two(_padd(_pmul(y, z), _pmul(w, x))),
                _padd(_pmul(w, w), _pmul(z, z), neg(_pmul(x, x)), neg(_pmul(y, y)))]]
        tr = [[a, b - a] for a, b in zip(draw(vec), draw(vec))]
        return {'type': 'rational', 'rotation': rot, 'rotation_denominator': den,
                'translation': tr, 'translation_denominator': [1.0]}
    return {'type': 'chain', 'elements': [
        {'type': 'fixed', 'position': draw(vec), 'quaternion': draw(quat)},
        {'type': 'hinge', 'axis': draw(vec.filter(any)),
         'angle': [draw(dy(-2.5, 2.5, 16)), draw(dy(-2.5, 2.5, 16))]},
        {'type': 'slide', 'axis': draw(vec.filter(any)),
         'displacement': [draw(dy(-0.5, 0.5)), draw(dy(-0.5, 0.5))]},
        {'type': 'fixed', 'position': draw(vec), 'quaternion': draw(quat)}]}


def _pmul(a, b):
    out = [0.0] * (len(a) + len(b) - 1)
    for i, u in enumerate(a):
        for j, v in enumerate(b):
            out[i + j] += u * v
    return out


def _det(m):
    return (m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1])
            - m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0])
            + m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0]))


@st.composite
def case(draw):
    return {'id': 'p', 'a': {'radii': draw(radii()), 'motion': draw(motion())},
            'b': {'radii': draw(radii()), 'motion': draw(motion())}}


# ------------------------------------------------------------------ checks
def solve(c):
    r = mjccd.solve_cases({'version': 1, 'cases': [c]})['results'][0]
    assert 'error' not in r, r['error']
    return r


def same_times(r0, r1):
    assert r0['status_at_start'] == r1['status_at_start']
    assert (r0['first_contact'] is None) == (r1['first_contact'] is None)
    if r0['first_contact'] is not None:
        assert abs(r0['first_contact'] - r1['first_contact']) <= TOL_T
    assert len(r0['intervals']) == len(r1['intervals'])
    for a, b in zip(r0['intervals'], r1['intervals']):
        assert abs(a[0] - b[0]) <= TOL_T and abs(a[1] - b[1]) <= TOL_T
    assert (r0['contact_point'] is None) == (r1['contact_point'] is None)


def close_points(p, q, size):
    assert math.dist(p, q) <= TOL_P * size, (p, q)


def size_of(c):
    return max(max(c['a']['radii']), max(c['b']['radii']))


@SETTINGS
@given(case(), st.sampled_from(CUBE), vec)
def test_rigid_transform_invariance(c, g, p):
    r0 = solve(c)
    c1 = copy.deepcopy(c)
    for k in ('a', 'b'):
        c1[k]['motion'] = transform_motion(c[k]['motion'], g, p)
    r1 = solve(c1)
    same_times(r0, r1)
    if r0['contact_point'] is not None:
        q = [u + v for u, v in zip(_mv(rot_matrix(g), r0['contact_point']), p)]
        close_points(q, r1['contact_point'], size_of(c))


@SETTINGS
@given(case())
def test_swap_invariance(c):
    r0 = solve(c)
    r1 = solve(dict(c, a=c['b'], b=c['a']))
    same_times(r0, r1)
    if r0['contact_point'] is not None:
        close_points(r0['contact_point'], r1['contact_point'], size_of(c))


@SETTINGS
@given(case(), st.sampled_from([0.25, 0.5, 2.0, 8.0]))
def test_scale_invariance(c, s):
    r0 = solve(c)
    c1 = copy.deepcopy(c)
    for k in ('a', 'b'):
        c1[k]['radii'] = [s * v for v in c[k]['radii']]
        c1[k]['motion'] = scale_motion(c[k]['motion'], s)
    r1 = solve(c1)
    same_times(r0, r1)
    if r0['contact_point'] is not None:
        close_points([s * v for v in r0['contact_point']], r1['contact_point'], s * size_of(c))


def test_transform_helpers_are_exact():
    # the cube rotations and dyadic data make the transformed JSON exact: applying a
    # rotation and its inverse gives back the original numbers bit for bit
    m = {'type': 'rigid', 'start': {'position': [0.125, -0.5, 0.75], 'quaternion': [0.5, 0.25, 0, -1]},
         'end': {'position': [0.25, 0.5, -0.75], 'quaternion': [1, 0.75, -0.5, 0]}}
    g = [1.0, 1.0, 1.0, 1.0]
    ginv = [1.0, -1.0, -1.0, -1.0]
    back = transform_motion(transform_motion(m, g, [0.0] * 3), ginv, [0.0] * 3)
    assert back['start']['position'] == m['start']['position']
    assert [v / 4 for v in back['end']['quaternion']] == m['end']['quaternion']
