"""`mjccd bench fidelity` runs end to end: every new MuJoCo contact of covered geoms is recalled, and the
tolerance fit's contacts lie within a centimetre of the real geoms."""
import pytest

from mjccd.bench import fidelity

pytestmark = pytest.mark.dm_control


def _rows(text):
    """{(env, fit): cells} of the bench's table."""
    rows = {}
    for line in text.splitlines():
        cells = [c.strip() for c in line.strip("|").split("|")]
        if len(cells) == 12 and cells[0] in fidelity.ENVS:
            rows[cells[0], cells[1]] = cells
    return rows


def test_walker_recall_is_complete_and_its_floor_is_checked(tmp_path, capsys):
    page = tmp_path / "bench.md"
    page.write_text("# Benchmarks\n\nkept\n")
    assert fidelity.main(["--envs", "walker", "--steps", "400", "--env-steps", "60", "--markdown", str(page)]) == 0
    rows = _rows(capsys.readouterr().out)
    assert len(rows) == 2
    for (env, fit), cells in rows.items():
        recalled, counts = cells[5].split(" ", 1)
        assert int(cells[4]) > 0  # the floor: plane pairs
        assert counts != "(0/0)" and float(recalled) == 1.0, (fit, cells[5])
    tolerance = next(cells for (env, fit), cells in rows.items() if fit.startswith("tolerance"))
    assert float(tolerance[6].split(" ", 1)[0]) >= 0.9
    text = page.read_text()
    assert "kept" in text and "<!-- bench fidelity: begin -->" in text


def test_fidelity_bench_rejects_bad_options(capsys):
    with pytest.raises(SystemExit):
        fidelity.main(["--steps", "0"])
    assert "--steps" in capsys.readouterr().err
