"""Near-singular ``linear_affine``: how often the solver is uncertain, and whether its brackets hold.

Body A is x = L(t) y + c(t) with L(t) = U [[s1,0,0],[0,s2,b(t-ts)],[0,-b(t-ts),eps]] V^T: flattened to
about eps of its size at ts (the shared hard set's family); B is static, rigid or linear_affine,
placed anywhere along A's path.  Every case is solved with ``mjccd.solve_cases`` and checked
against the independent 60-digit oracle (tests/oracle.py) under the acceptance rule of
tests/test_adversarial.py: ok, uncertain with a bracket holding the oracle's first contact, or
wrong.  Prints one line per eps range.

    python benchmarks/near_singular.py [--cases 100] [--seed 2] [--eps 2 4] [--jobs 2]
"""
import argparse
import collections
import multiprocessing
import os
import sys

import numpy as np

import mjccd

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(HERE, "..", "tests"))
import oracle  # noqa: E402
from test_adversarial import verdict  # noqa: E402


def _rotation(rng):
    """A random proper rotation matrix."""
    q, r = np.linalg.qr(rng.normal(size=(3, 3)))
    q = q * np.sign(np.diag(r))
    if np.linalg.det(q) < 0.0:
        q[:, 0] = -q[:, 0]
    return q


def _pose_json(c, rng):
    q = rng.normal(size=4)
    return {"position": list(map(float, c)), "quaternion": list(map(float, q / np.linalg.norm(q)))}


def cases(n, seed, lo_exp, hi_exp):
    """n cases, eps = 10^-uniform(lo_exp, hi_exp)."""
    rng = np.random.default_rng(seed)
    out = []
    for k in range(n):
        eps = 10.0 ** -rng.uniform(lo_exp, hi_exp)
        U, V = _rotation(rng), _rotation(rng)
        s1, s2, b = rng.uniform(0.7, 1.3, 3)
        ts = 0.5 if rng.random() < 0.5 else rng.uniform(0.2, 0.8)
        c0 = rng.uniform(-0.5, 0.5, 3)
        c1 = c0 + rng.normal(size=3) / np.sqrt(3) * rng.uniform(0.5, 2.5)

        def frame(t):
            D = np.array([[s1, 0, 0], [0, s2, b * (t - ts)], [0, -b * (t - ts), eps]])
            return np.hstack([U @ D @ V.T, ((1 - t) * c0 + t * c1)[:, None]]).tolist()
        ra, rb = rng.uniform(0.1, 0.35, 3), rng.uniform(0.08, 0.25, 3)
        tc = rng.uniform(0.05, 0.95)
        direction = rng.normal(size=3)
        c = (1 - tc) * c0 + tc * c1 + direction / np.linalg.norm(direction) * rng.uniform(0.0, 1.5) * rb.max()
        kind = ("static", "rigid", "linear_affine")[k % 3]
        if kind == "static":
            mb = {"type": "static", **_pose_json(c, rng)}
        elif kind == "rigid":
            v = rng.uniform(-0.2, 0.2, 3)
            mb = {"type": "rigid", "start": _pose_json(c - tc * v, rng), "end": _pose_json(c + (1 - tc) * v, rng)}
        else:
            v = rng.uniform(-0.2, 0.2, 3)
            mb = {"type": "linear_affine",
                  "start": np.hstack([_rotation(rng), (c - tc * v)[:, None]]).tolist(),
                  "end": np.hstack([_rotation(rng), (c + (1 - tc) * v)[:, None]]).tolist()}
        out.append({"id": f"near-singular-{seed}-{k}", "tags": [f"eps={eps:.2g}", kind],
                    "a": {"radii": ra.tolist(), "motion": {"type": "linear_affine", "start": frame(0.0),
                                                           "end": frame(1.0)}},
                    "b": {"radii": rb.tolist(), "motion": mb}})
    return out


def _oracle(case):
    try:
        return oracle.solve_case(case, check=True, n_grid=512)
    except oracle.OracleError as exc:
        return {"oracle_error": str(exc)}


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cases", type=int, default=100)
    parser.add_argument("--seed", type=int, default=2)
    parser.add_argument("--eps", type=float, nargs=2, default=(2.0, 4.0), metavar=("FROM", "TO"),
                        help="eps = 10^-x, x uniform in [FROM, TO]")
    parser.add_argument("--jobs", type=int, default=2, help="oracle processes")
    args = parser.parse_args(argv)
    todo = cases(args.cases, args.seed, *args.eps)
    results = mjccd.solve_cases({"version": 1, "cases": todo})["results"]
    with multiprocessing.get_context("fork").Pool(args.jobs) as pool:
        expected = pool.map(_oracle, todo, chunksize=1)
    count = collections.Counter()
    for case, want, got in zip(todo, expected, results):
        if "oracle_error" in want:
            count["oracle error"] += 1
            continue
        kind, why = verdict(case, want, got)
        count[kind] += 1
        if kind == "wrong":
            print(f"  wrong: {case['id']} {case['tags']}: {'; '.join(why)}")
    print(f"eps 1e-{args.eps[0]:g} .. 1e-{args.eps[1]:g}, {args.cases} cases, seed {args.seed}: "
          f"ok {count['ok']}, uncertain {count['uncertain']}, wrong {count['wrong']}"
          + (f", oracle errors {count['oracle error']}" if count["oracle error"] else ""))


if __name__ == "__main__":
    main()
