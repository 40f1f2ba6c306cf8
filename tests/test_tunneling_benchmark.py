"""The tunneling benchmark's scripts: scenarios that run without mjccd, the MuJoCo 4 peer, clear errors."""
import json
import pathlib
import subprocess
import sys

import mujoco
import pytest

HERE = pathlib.Path(__file__).resolve().parents[1] / "benchmarks" / "tunneling"
HAS_SPECULATIVE = hasattr(mujoco.mjtEnableBit, "mjENBL_SPECULATIVE")

# a Python in which importing mjccd fails, as in the peer's environment (MuJoCo and NumPy only)
WITHOUT_MJCCD = """
import sys
class NoMjccd:
    def find_spec(self, name, path=None, target=None):
        if name == "mjccd" or name.startswith("mjccd."):
            raise ImportError("mjccd is not installed here")
sys.meta_path.insert(0, NoMjccd())
"""


def _python(code, *args):
    return subprocess.run([sys.executable, "-c", WITHOUT_MJCCD + code, *args], capture_output=True, text=True,
                          cwd=HERE, timeout=300)


def test_scenarios_build_and_run_without_mjccd():
    proc = _python(f"""
sys.path.insert(0, {str(HERE)!r})
from scenarios import Episodes, Wall
tunneled, cost, unstable = Episodes(Wall(0.01, speed=200.0)).run(0)
print(tunneled, cost > 0, unstable)
""")
    assert proc.returncode == 0, proc.stderr
    # plain MuJoCo at 10 ms lets a 200 m/s ball through the 2 cm wall; nothing diverges
    assert proc.stdout.split() == ["True", "True", "False"]


def test_speculative_peer_runs_or_says_it_needs_mujoco_4():
    proc = _python(f"import runpy; sys.argv = ['speculative.py', '--quick', '--runs', '1']; "
                   f"runpy.run_path({str(HERE / 'speculative.py')!r}, run_name='__main__')")
    if not HAS_SPECULATIVE:
        assert proc.returncode == 2
        assert f"MuJoCo {mujoco.__version__}" in proc.stderr and "MuJoCo 4.0" in proc.stderr
        assert "Traceback" not in proc.stderr
        return
    assert proc.returncode == 0, proc.stderr
    records = [json.loads(line) for line in proc.stdout.splitlines()]
    assert {r["mode"] for r in records} == {"plain", "speculative"}
    assert all(r["runs"] == 1 and r["cost"] > 0 for r in records)


def test_run_rejects_a_missing_peer_python(tmp_path):
    proc = subprocess.run([sys.executable, str(HERE / "run.py"), "--mujoco4", str(tmp_path / "nowhere"),
                           "--quick", "--out", "", "--bench", ""], capture_output=True, text=True, timeout=300)
    assert proc.returncode == 2
    assert "--mujoco4: no Python at" in proc.stderr and "Traceback" not in proc.stderr


@pytest.mark.skipif(not HAS_SPECULATIVE, reason="speculative contacts need MuJoCo >= 4")
def test_speculative_contacts_stop_the_wall_ball():
    sys.path.insert(0, str(HERE))
    from speculative import simulate
    from scenarios import Wall
    assert simulate(Wall, 0.01, 200.0, False, 1)[0][0]
    assert not simulate(Wall, 0.01, 200.0, True, 1)[0][0]


def test_a_kick_from_rest_tunnels_plain_mujoco_but_not_the_guard():
    """The kick scenario: from rest through the wall within one step; the guard sees the contact."""
    sys.path.insert(0, str(HERE))
    from scenarios import Episodes, Kick

    from mjccd.mujoco.guard import GuardedStepper

    assert Episodes(Kick(0.01, speed=50.0)).run(0)[0]
    sc = Kick(0.01, speed=50.0)
    guarded = Episodes(sc, lambda m, d: GuardedStepper(m, d, sc.ellipsoids()).step)
    for seed in range(3):  # one simulation, reset between runs: no state of a run leaks into the next
        tunneled, _, unstable = guarded.run(seed)
        assert not tunneled and not unstable


def test_the_boxing_spin_gain_is_one_for_a_free_swing_and_is_reported():
    """The arm's peak angular speed over its swing speed: 1 while nothing touches it (the first steps of a
    swing, before the fist reaches the head), larger once a contact has spun it up; run.py reports it."""
    sys.path.insert(0, str(HERE))
    import numpy as np
    import run
    from scenarios import Boxing

    sc = Boxing(1 / 120, speed=5.0)
    data = mujoco.MjData(sc.model)
    sc.reset(data, np.random.default_rng(0))
    for _ in range(2):  # 2 steps at 5 m/s: the fist is still on its way
        mujoco.mj_step(sc.model, data)
        assert not sc.tunneled(data)
    assert sc.spin_gain() == pytest.approx(1.0, abs=0.02)
    data.qvel[sc._dof:sc._dof + 3] *= 3.0
    sc.tunneled(data)
    assert sc.spin_gain() == pytest.approx(3.0, rel=0.02)
    lines = run.spin_lines({("boxing", 1 / 120, 5.0, "plain"): 1.0, ("boxing", 1 / 120, 5.0, "guarded"): 3.4})
    assert "5 m/s: plain 1, guarded 3.4" in lines[-1]
