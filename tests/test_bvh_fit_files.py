"""Files of ``import-bvh`` and ``fit``: no surprise overwrites, both outputs or neither, models MuJoCo loads."""
import contextlib
import pathlib

import mujoco
import numpy as np
import pytest

from mjccd import cli, files
from mjccd.mujoco import load_ellipsoids

from fuzz_inputs.fit import good_model
from fuzz_inputs.import_bvh import clip_text

MODELS = pathlib.Path(__file__).resolve().parents[1] / "models"


def _run(capsys, *argv):
    """Exit status and stderr of one in-process ``mjccd`` command."""
    code = cli.main([str(a) for a in argv])
    return code, capsys.readouterr().err


def _interrupt_on_second_output(monkeypatch, module):
    """Make ``module``'s second ``files.atomic_open`` of a run raise KeyboardInterrupt (Ctrl-C while writing)."""
    opened = []
    real = files.atomic_open

    @contextlib.contextmanager
    def atomic_open(path, *args, **kwargs):
        opened.append(path)
        if len(opened) == 2:
            raise KeyboardInterrupt
        with real(path, *args, **kwargs) as fh:
            yield fh

    monkeypatch.setattr(module.files, "atomic_open", atomic_open)
    return opened


def _ellipsoid_geoms(model):
    names = (mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_GEOM, g) or "" for g in range(model.ngeom))
    return [n for n in names if n.startswith("mjccd_ellipsoid_")]


# ---------------------------------------------------------------- import-bvh


@pytest.fixture()
def clip(tmp_path):
    path = tmp_path / "walk.bvh"
    path.write_text(clip_text())
    return path


def test_import_bvh_refuses_to_overwrite_without_force(tmp_path, clip, capsys):
    model, traj = tmp_path / "m.xml", tmp_path / "t.npz"
    model.write_text("old model")
    code, err = _run(capsys, "import-bvh", clip, "-o", model, "--traj", traj)
    assert code == 2 and f"{model}: exists; pass --force" in err
    assert model.read_text() == "old model" and not traj.exists()
    code, err = _run(capsys, "import-bvh", clip, "-o", clip)
    assert code == 2 and "is an input of this command" in err
    assert clip.read_text() == clip_text()


def test_import_bvh_force_replaces_both_outputs(tmp_path, clip, capsys):
    model, traj = tmp_path / "m.xml", tmp_path / "t.npz"
    model.write_text("old model")
    traj.write_bytes(b"old trajectory")
    code, _ = _run(capsys, "import-bvh", clip, "-o", model, "--traj", traj, "--force")
    assert code == 0
    nq = mujoco.MjModel.from_xml_path(str(model)).nq
    with np.load(traj) as data:
        assert data["qpos"].shape == (3, nq) and data["time"].shape == (3,)
    assert not traj.with_name("t.npz.npz").exists()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["m.xml", "t.npz", "walk.bvh"]


def test_import_bvh_interrupted_while_writing_leaves_old_files(tmp_path, clip, capsys, monkeypatch):
    from mjccd import bvh

    model, traj = tmp_path / "m.xml", tmp_path / "t.npz"
    model.write_text("old model")
    traj.write_bytes(b"old trajectory")
    opened = _interrupt_on_second_output(monkeypatch, bvh)
    code, _ = _run(capsys, "import-bvh", clip, "-o", model, "--traj", traj, "--force")
    assert code == 130 and opened == [str(model), str(traj)]
    assert model.read_text() == "old model" and traj.read_bytes() == b"old trajectory"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["m.xml", "t.npz", "walk.bvh"]


def test_import_bvh_colliding_names_give_a_model_mujoco_loads(tmp_path, capsys):
    clip = tmp_path / "hash.bvh"
    clip.write_text(clip_text(leg="L#Hip", spine="L_Hip"))
    model, traj = tmp_path / "m.xml", tmp_path / "t.npz"
    code, err = _run(capsys, "import-bvh", clip, "-o", model, "--traj", traj)
    assert code == 0, err
    compiled = mujoco.MjModel.from_xml_path(str(model))
    assert compiled.body("L_Hip").id != compiled.body("L_Hip_2").id
    assert np.load(traj)["qpos"].shape[1] == compiled.nq


def test_import_bvh_rejected_model_writes_nothing(tmp_path, capsys):
    clip = tmp_path / "clash.bvh"
    clip.write_text(clip_text(leg="Hips_root"))  # the root's free joint is called Hips_root too
    model, traj = tmp_path / "m.xml", tmp_path / "t.npz"
    model.write_text("old model")
    code, err = _run(capsys, "import-bvh", clip, "-o", model, "--traj", traj, "--force")
    assert code == 2
    assert f"{clip}: MuJoCo rejects the model" in err and "repeated name 'Hips_root'" in err
    assert model.read_text() == "old model" and not traj.exists()


# ---------------------------------------------------------------- fit


@pytest.fixture()
def arm(tmp_path):
    """``models/arm_obstacle.xml`` with a colliding obstacle, its meshes found from ``tmp_path``."""
    path = tmp_path / "arm.xml"
    path.write_text(good_model(tmp_path))
    return path


def test_fit_refuses_to_overwrite_without_force(tmp_path, arm, capsys):
    out = tmp_path / "out.xml"
    out.write_text("old model")
    code, err = _run(capsys, "fit", arm, "-o", out, "-q")
    assert code == 2 and f"{out}: exists; pass --force" in err
    assert out.read_text() == "old model" and not (tmp_path / "out.ellipsoids.json").exists()
    code, err = _run(capsys, "fit", arm, "-o", arm, "-q")
    assert code == 2 and f"{arm}: is an input of this command" in err
    assert arm.read_text() == good_model(tmp_path)
    code, _ = _run(capsys, "fit", arm, "-o", out, "-q", "--force", "--tolerance", "none")
    assert code == 0
    assert _ellipsoid_geoms(mujoco.MjModel.from_xml_path(str(out))) == ["mjccd_ellipsoid_0"]
    assert load_ellipsoids(tmp_path / "out.ellipsoids.json").bodies == ("obstacle",)


def test_fit_of_its_own_output_replaces_the_ellipsoids(tmp_path, arm, capsys):
    first = tmp_path / "first.ellipsoids.json"
    one = ("--tolerance", "none")  # one ellipsoid per body: the refit replaces exactly that one
    assert _run(capsys, "fit", arm, "-o", arm, "--ellipsoids", first, "--force", "-q", *one)[0] == 0
    again = tmp_path / "again.ellipsoids.json"
    code, err = _run(capsys, "fit", arm, "-o", arm, "--ellipsoids", again, "--force", "-q", *one)
    assert code == 0, err
    assert _ellipsoid_geoms(mujoco.MjModel.from_xml_path(str(arm))) == ["mjccd_ellipsoid_0"]
    np.testing.assert_array_equal(load_ellipsoids(again).radii, load_ellipsoids(first).radii)
    # with --include-visual the earlier ellipsoid is not bounded either: the geoms of the original model only
    original = tmp_path / "original.xml"
    original.write_text(good_model(tmp_path))
    for model, name in ((original, "o.json"), (arm, "a.json")):
        assert _run(capsys, "fit", model, "--ellipsoids", tmp_path / name, "--include-visual", "--per", "geom",
                    "--bodies", "obstacle", "-q", *one)[0] == 0
    refit, fit = load_ellipsoids(tmp_path / "a.json"), load_ellipsoids(tmp_path / "o.json")
    assert refit.geoms == fit.geoms and "mjccd_ellipsoid_0" not in refit.geoms
    np.testing.assert_allclose(refit.radii, fit.radii, rtol=1e-5)  # MjSpec.to_xml keeps 6 digits


def test_fit_interrupted_while_writing_leaves_old_files(tmp_path, arm, capsys, monkeypatch):
    from mjccd import fit

    out, ellipsoids = tmp_path / "out.xml", tmp_path / "out.ellipsoids.json"
    out.write_text("old model")
    ellipsoids.write_text("old ellipsoids")
    opened = _interrupt_on_second_output(monkeypatch, fit)
    code, _ = _run(capsys, "fit", arm, "-o", out, "-q", "--force")
    assert code == 130 and opened == [str(out), str(ellipsoids)]
    assert out.read_text() == "old model" and ellipsoids.read_text() == "old ellipsoids"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["arm.xml", "out.ellipsoids.json", "out.xml"]


def test_fit_output_in_another_folder_finds_the_meshes(tmp_path, capsys):
    out = tmp_path / "sub" / "arm_fit.xml"
    out.parent.mkdir()
    code, err = _run(capsys, "fit", MODELS / "arm_obstacle.xml", "-o", out, "--include-visual",
                     "--bodies", "obstacle", "-q", "--tolerance", "none")
    assert code == 0, err
    assert _ellipsoid_geoms(mujoco.MjModel.from_xml_path(str(out))) == ["mjccd_ellipsoid_0"]


def test_fit_names_a_model_mujoco_cannot_load(tmp_path, capsys):
    bad = tmp_path / "bad.xml"
    bad.write_text("<mujoco><worldbody><bogus/></worldbody></mujoco>")
    code, err = _run(capsys, "fit", bad, "-o", tmp_path / "out.xml")
    assert code == 2 and f"{bad}: MuJoCo cannot load it" in err and "bogus" in err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["bad.xml"]
