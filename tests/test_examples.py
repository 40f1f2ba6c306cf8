"""The shipped examples run to their end with their own arguments (short versions where they take long)."""
import pathlib
import runpy

import pytest

ROOT = pathlib.Path(__file__).resolve().parents[1]


@pytest.mark.dm_control
@pytest.mark.parametrize("domain, task", [("humanoid_CMU", "stand"), ("humanoid", "walk")])
def test_wrap_suite_env_runs(domain, task, capsys):
    """The dm-control example (it used to crash on an uncertain contact without a point)."""
    main = runpy.run_path(str(ROOT / "examples" / "wrap_suite_env.py"))["main"]
    assert main(["--domain", domain, "--task", task, "--steps", "40"]) == 0
    out = capsys.readouterr().out
    assert "control steps had a predicted limb contact" in out and "geom pairs checked" in out
