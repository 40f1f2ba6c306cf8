"""`mjccd bench batch` runs end to end on a tiny size and writes its own section; its boxing worlds are sound."""
import numpy as np
import pytest

from mjccd.bench import batch
from mjccd.scene import Scene


def test_boxing_worlds_differ_and_touch_sometimes():
    poses, radii, pairs = batch.boxing_worlds(3, 300)
    assert poses.shape == (3, 301, 42, 7) and radii.shape == (42, 3) and pairs.shape == (441, 2)
    assert np.allclose(np.linalg.norm(poses[..., 3:], axis=-1), 1.0)
    assert not np.allclose(poses[0], poses[1])
    assert np.abs(np.diff(poses[..., :3], axis=1)).max() < 0.1  # smooth: a few cm per frame at 60 fps
    for world in poses:
        run = Scene(radii, pairs=pairs).run(world)
        assert 0 < int((run.pair >= 0).sum()) < 150  # the boxers meet in some frames, not in most


def test_batch_bench_writes_its_section(tmp_path, capsys):
    page = tmp_path / "bench.md"
    page.write_text("# Benchmarks\n\nkept\n")
    argv = ["--quick", "--worlds", "1", "3", "--world-frames", "3", "--run-frames", "3", "--workloads", "boxing",
            "--markdown", str(page)]
    assert batch.main(argv) == 0
    text = page.read_text()
    assert "kept" in text and "<!-- bench batch: begin -->" in text and "<!-- bench batch: end -->" in text
    assert "### boxing: 42 ellipsoids, 441 pairs per world" in text
    rows = [line for line in text.splitlines() if line.startswith("| 1 | 3 |") or line.startswith("| 3 | 1 |")]
    assert len(rows) == 2
    assert "Single world, `Scene.run` over 3 frames" in text
    assert "pair-frames per second" in capsys.readouterr().out.lower()


def test_batch_bench_rejects_bad_options(capsys):
    with pytest.raises(SystemExit):
        batch.main(["--worlds", "0"])
    assert "--worlds" in capsys.readouterr().err
