"""Malformed ``mjccd bench`` arguments: unknown suites, counts out of range, unreadable inputs, unwritable pages.

Every case but one must stop before the benchmark runs (so each answers in well
under a second), with argparse's usage error or a one-line message naming the
option or the file, and must leave no markdown page behind.  The one runs the
monitor's scene so fast that MuJoCo resets it within a few steps: the bench must
stop with an error rather than time the reset pose.
"""
from . import FuzzCase

SUITES = ("core", "scene", "monitor", "patches")
COUNTS = {  # suite -> (option, a value below its range, a value above it)
    "core": [("--queries", "0", "100001"), ("--repeats", "0", "10000"), ("--static-pairs", "1", "1000000000000")],
    "scene": [("--frames", "1", "1000000000"), ("--table3-frames", "0", "100000000"), ("--repeats", "0", "5000"),
              ("--samples", "0", "100000")],
    "monitor": [("--steps", "0", "10000000000"), ("--repeats", "0", "1001"), ("--speed", "-1", "1e308")],
    "patches": [("--cases", "0", "1000000000"), ("--orders", "0", "4"), ("--deltas", "0", "2"),
                ("--trad-max-iterations", "0", "100000000000")],
}


def _range_cases(rng):
    cases = []
    for suite, counts in COUNTS.items():
        for option, low, high in counts:
            cases.append(FuzzCase(f"{suite} {option} {low} (too small)", ["bench", suite, option, low], (option,)))
            cases.append(FuzzCase(f"{suite} {option} {high} (huge)", ["bench", suite, option, high], (option,)))
        option = counts[0][0]
        negative = str(int(rng.integers(-10**6, 0)))
        cases.append(FuzzCase(f"{suite} {option} negative", ["bench", suite, option, negative], (option,)))
        cases.append(FuzzCase(f"{suite} {option} nan", ["bench", suite, option, "nan"], (option,)))
        cases.append(FuzzCase(f"{suite} --seed negative", ["bench", suite, "--seed", "-1"], ("--seed",)))
    return cases


def _markdown_cases(folder):
    (folder / "a_folder").mkdir()
    cases = []
    for suite in SUITES:
        cases += [
            FuzzCase(f"{suite} --markdown in a missing folder", ["bench", suite, "--markdown", "nowhere/bench.md"],
                     ("--markdown", "nowhere")),
            FuzzCase(f"{suite} --markdown pointing at a folder", ["bench", suite, "--markdown", "a_folder"],
                     ("--markdown", "a_folder")),
            FuzzCase(f"{suite} --markdown empty", ["bench", suite, "--markdown", ""], ("--markdown",)),
        ]
    return cases


def _input_cases(folder):
    (folder / "garbage.xml").write_text("<mujoco><worldbody>")
    (folder / "garbage.npz").write_bytes(b"PK\x03\x04 not really a zip archive")
    (folder / "empty.npz").write_bytes(b"")
    (folder / "no_boxers.xml").write_text(
        '<mujoco><worldbody><body><freejoint/><geom type="ellipsoid" size="0.1 0.2 0.3" group="5"/></body>'
        '<body pos="1 0 0"><freejoint/><geom type="ellipsoid" size="0.1 0.2 0.3" group="5"/></body>'
        "</worldbody></mujoco>")
    (folder / "empty_sets").mkdir()
    return [
        FuzzCase("monitor --model missing", ["bench", "monitor", "--model", "missing.xml"], ("missing.xml",)),
        FuzzCase("monitor --model not MJCF", ["bench", "monitor", "--model", "garbage.xml"], ("garbage.xml",)),
        FuzzCase("monitor --model without the two boxers", ["bench", "monitor", "--model", "no_boxers.xml"],
                 ("no_boxers.xml",)),
        FuzzCase("monitor --traj not an npz", ["bench", "monitor", "--traj", "garbage.npz"], ("garbage.npz",)),
        FuzzCase("monitor --traj empty", ["bench", "monitor", "--traj", "empty.npz"], ("empty.npz",)),
        FuzzCase("monitor --traj a folder", ["bench", "monitor", "--traj", "empty_sets"], ("empty_sets",)),
        FuzzCase("monitor --frame past the trajectory", ["bench", "monitor", "--frame", "150"], ("--frame",)),
        FuzzCase("monitor --frame negative", ["bench", "monitor", "--frame", "-1"], ("--frame",)),
        FuzzCase("monitor --speed inf", ["bench", "monitor", "--speed", "inf"], ("--speed",)),
        FuzzCase("monitor --speed that blows MuJoCo up", ["bench", "monitor", "--speed", "30", "--steps", "200",
                                                          "--repeats", "1"], ("--speed",)),
        FuzzCase("monitor --markdown is its --model", ["bench", "monitor", "--model", "garbage.xml", "--markdown",
                                                       "garbage.xml"], ("--markdown",)),
        FuzzCase("scene --traj missing", ["bench", "scene", "--traj", "missing.npz"], ("missing.npz",)),
        FuzzCase("scene --traj not an npz", ["bench", "scene", "--traj", "garbage.npz"], ("garbage.npz",)),
        FuzzCase("scene --model not MJCF", ["bench", "scene", "--model", "garbage.xml", "--traj", "garbage.npz"],
                 ("garbage.xml",)),
        FuzzCase("scene --only unknown part", ["bench", "scene", "--only", "everything"], ("--only",)),
        FuzzCase("patches --data without query files", ["bench", "patches", "--data", "empty_sets"],
                 ("--data", "empty_sets")),
        FuzzCase("patches --data missing", ["bench", "patches", "--table", "3", "--data", "missing_sets"],
                 ("--data", "missing_sets")),
        FuzzCase("patches --kinds unknown", ["bench", "patches", "--kinds", "hexagon"], ("--kinds",)),
        FuzzCase("patches --methods unknown", ["bench", "patches", "--methods", "magic"], ("--methods",)),
        FuzzCase("patches --sets none", ["bench", "patches", "--sets", ","], ("--sets",)),
        FuzzCase("patches --orders not a number", ["bench", "patches", "--orders", "one"], ("--orders",)),
        FuzzCase("patches --deltas nan", ["bench", "patches", "--deltas", "1e-4,nan"], ("--deltas",)),
        FuzzCase("patches --table 2", ["bench", "patches", "--table", "2"], ("--table",)),
        FuzzCase("patches --max-queries negative", ["bench", "patches", "--max-queries", "-5"], ("--max-queries",)),
    ]


def generate(folder, rng):
    return [
        FuzzCase("unknown suite", ["bench", "fast"], ("suite", "fast")),
        FuzzCase("no suite", ["bench"], ("suite",)),
        FuzzCase("core unknown option", ["bench", "core", "--querys", "5"], ("--querys",)),
        FuzzCase("core --queries 1.5", ["bench", "core", "--queries", "1.5"], ("--queries",)),
        FuzzCase("core --quick with a value", ["bench", "core", "--quick", "yes"], ("yes",)),
    ] + _range_cases(rng) + _markdown_cases(folder) + _input_cases(folder)
