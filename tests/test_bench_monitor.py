"""`mjccd bench monitor` runs end to end and writes its own section of a benchmark page."""
import pytest

from mjccd.bench import monitor


def test_monitor_bench_writes_its_section(tmp_path, capsys):
    page = tmp_path / "bench.md"
    page.write_text("# Benchmarks\n\nkept\n")
    assert monitor.main(["--steps", "5", "--repeats", "1", "--markdown", str(page)]) == 0
    text = page.read_text()
    assert "kept" in text and "<!-- bench monitor: begin -->" in text
    assert "| `CCDMonitor.step`, rigid |" in text and "| 2208 |" in text  # boxer against boxer, 46 x 48 bounds
    assert "ms per step" in capsys.readouterr().out


def test_monitor_bench_rejects_bad_options(capsys):
    with pytest.raises(SystemExit):
        monitor.main(["--steps", "0"])
    assert "--steps" in capsys.readouterr().err
