"""`mjccd bench fidelity` runs end to end: in geoms mode every new MuJoCo contact is recalled, no pair goes
unchecked and the first contacts lie within a millimetre of the real geoms; in ellipsoid mode every new contact
of covered geoms is recalled and the tolerance fit's contacts lie within a centimetre; in both, at most 0.5 % of the
contacts are uncertain, each with a point."""
import pytest

from mjccd.bench import fidelity

pytestmark = pytest.mark.dm_control


def _rows(text):
    """{(env, mode, fit): cells} of the bench's table."""
    rows = {}
    for line in text.splitlines():
        cells = [c.strip() for c in line.strip("|").split("|")]
        if len(cells) == 16 and cells[0] in fidelity.ENVS:
            rows[cells[0], cells[1], cells[2]] = cells
    return rows


def _share(cell):
    value, counts = cell.split(" ", 1)
    return float(value), counts


def test_walker_recall_is_complete_and_geoms_mode_is_precise(tmp_path, capsys):
    page = tmp_path / "bench.md"
    page.write_text("# Benchmarks\n\nkept\n")
    assert fidelity.main(["--envs", "walker", "--steps", "400", "--env-steps", "60", "--markdown", str(page)]) == 0
    rows = _rows(capsys.readouterr().out)
    assert sorted(mode for _, mode, _ in rows) == ["ellipsoids", "ellipsoids", "geoms"]
    for (env, mode, fit), cells in rows.items():
        recall, counts = _share(cells[5])
        assert counts != "(0/0)" and recall == 1.0, (mode, fit, cells[5])
        assert _share(cells[10])[0] <= 0.005 and cells[11] == "0", (mode, fit, cells[10], cells[11])
    geoms = next(cells for (_, mode, _), cells in rows.items() if mode == "geoms")
    assert geoms[6] == "0" and _share(geoms[7])[0] >= 0.99
    tolerance = next(cells for (_, _, fit), cells in rows.items() if fit.startswith("tolerance"))
    assert _share(tolerance[8])[0] >= 0.9
    text = page.read_text()
    assert "kept" in text and "<!-- bench fidelity: begin -->" in text


def test_fidelity_bench_rejects_bad_options(capsys):
    with pytest.raises(SystemExit):
        fidelity.main(["--steps", "0"])
    assert "--steps" in capsys.readouterr().err
