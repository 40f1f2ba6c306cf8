"""The solver against the high-precision oracle (tests/oracle.py).

The committed answers in tests/data/*_expected.json come from the oracle
(tests/make_reference.py regenerates them); a few cases are re-solved live here so the
oracle itself runs in CI.
"""
import json
import os
import random
import subprocess
import sys

import pytest

import mjccd

HERE = os.path.dirname(os.path.abspath(__file__))
DATA = os.path.join(HERE, 'data')
sys.path.insert(0, HERE)
import oracle  # noqa: E402


def _load(name):
    with open(os.path.join(DATA, name)) as f:
        return json.load(f)


BF_CASES = _load('bruteforce_cases.json')
BF_EXPECTED = {r['id']: r for r in _load('bruteforce_expected.json')['results']}
CASE_IDS = [c['id'] for c in BF_CASES['cases']]


@pytest.fixture(scope='module')
def bf_results():
    out = mjccd.solve_cases(BF_CASES)
    return {r['id']: r for r in out['results']}


def test_reference_data_is_rich():
    cases = BF_CASES['cases']
    exp = list(BF_EXPECTED.values())
    assert len(cases) >= 240
    hit = sum(1 for r in exp if r['intervals'])
    assert 0.35 * len(cases) < hit < 0.8 * len(cases)
    tags = [t for c in cases for t in c['tags']]
    for tag in ('near-miss', 'graze', 'multi-interval', 'start-overlapping', 'start-touching'):
        assert tag in tags, tag
    kinds = {m['motion']['type'] for c in cases for m in (c['a'], c['b'])}
    assert kinds == {'static', 'rigid', 'affine', 'linear_affine', 'rational', 'chain'}


@pytest.mark.parametrize('cid', CASE_IDS)
def test_solver_matches_oracle(bf_results, cid):
    case = next(c for c in BF_CASES['cases'] if c['id'] == cid)
    why = oracle.compare(case, BF_EXPECTED[cid], bf_results.get(cid))
    assert not why, '%s %s: %s' % (cid, case['tags'], '; '.join(why))


def test_cli_public_cases(tmp_path):
    out = tmp_path / 'results.json'
    run = subprocess.run([sys.executable, '-m', 'mjccd', 'solve',
                          os.path.join(DATA, 'public_cases.json'), '-o', str(out)],
                         capture_output=True, text=True, cwd=os.path.dirname(HERE))
    assert run.returncode == 0, run.stderr
    chk = subprocess.run([sys.executable, os.path.join(DATA, 'check.py'), str(out)],
                         capture_output=True, text=True)
    assert chk.returncode == 0, chk.stdout
    assert 'cases: 30/30 ok' in chk.stdout


def test_check_script_rejects_wrong_answers(tmp_path):
    res = _load('public_expected.json')
    res['results'][0]['first_contact'] += 1e-8
    bad = tmp_path / 'bad.json'
    bad.write_text(json.dumps(res))
    chk = subprocess.run([sys.executable, os.path.join(DATA, 'check.py'), str(bad)],
                         capture_output=True, text=True)
    assert chk.returncode == 1
    assert 'cases: 29/30 ok' in chk.stdout


def test_oracle_two_spheres_closed_form():
    # sphere of radius 1/2 moving along x from -2 to 2 past a static sphere of radius 1/4
    # at (0, 1/2, 0): contact when |p(t) - c| = 3/4, i.e. (4t - 2)^2 = 9/16 - 1/4
    case = {'id': 'spheres',
            'a': {'radii': [0.5] * 3, 'motion': {
                'type': 'rigid', 'start': {'position': [-2, 0, 0], 'quaternion': [1, 0, 0, 0]},
                'end': {'position': [2, 0, 0], 'quaternion': [0, 1, 0, 0]}}},
            'b': {'radii': [0.25] * 3, 'motion': {
                'type': 'static', 'position': [0, 0.5, 0], 'quaternion': [1, 0, 0, 0]}}}
    r = oracle.solve_case(case)
    x = (9 / 16 - 1 / 4) ** 0.5
    t0, t1 = (2 - x) / 4, (2 + x) / 4
    assert r['status_at_start'] == 'separate'
    assert abs(r['first_contact'] - t0) < 1e-15
    assert len(r['intervals']) == 1
    assert abs(r['intervals'][0][1] - t1) < 1e-15
    # touch point lies on the centre line, 2/3 of the way from a's centre to b's
    p = [-x + (x) * 2 / 3, 0.5 * 2 / 3, 0.0]
    assert max(abs(u - v) for u, v in zip(r['contact_point'], p)) < 1e-14
    assert oracle.status(case, 0.5) == 'overlapping'
    assert oracle.status(case, 0.0) == 'separate'


LIVE = ['bf-touch-01', 'bf-rational-static-01', 'bf-chain-static-01', 'bf-affine-affine-01']


@pytest.mark.parametrize('cid', LIVE)
def test_oracle_live_reproduces_committed_answer(cid):
    case = next(c for c in BF_CASES['cases'] if c['id'] == cid)
    live = oracle.solve_case(case, check=True)
    assert not oracle.compare(case, BF_EXPECTED[cid], live)
    # and the committed answer is bit-for-bit the oracle's
    assert live['first_contact'] == BF_EXPECTED[cid]['first_contact']


def test_oracle_live_fresh_random_cases():
    import make_reference
    rng = random.Random(7)
    cases = []
    for i, (ka, kb) in enumerate([('rigid', 'static'), ('chain', 'rigid'),
                                  ('linear_affine', 'rational')]):
        c = None
        while c is None:
            c = make_reference.build_case(rng, 'live-%d' % i, ka, kb, 'collide')
        cases.append(c)
    got = {r['id']: r for r in mjccd.solve_cases({'version': 1, 'cases': cases})['results']}
    for c in cases:
        exp = oracle.solve_case(c, check=True)
        assert exp['intervals'], c['id']
        why = oracle.compare(c, exp, got[c['id']])
        assert not why, '%s: %s' % (c['id'], '; '.join(why))
