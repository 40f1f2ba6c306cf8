"""Bounding ellipsoids of a MuJoCo model: containment of every geom point, closed forms, files, MJCF output.

The fitting maths on its own is tested in ``test_fitting.py``.
"""
import json

import mujoco
import numpy as np
import pytest

from mjccd.fit import main, volume_report, write_mjcf
from mjccd.fitting import containment_factor
from mjccd.mujoco import EllipsoidSet, load_ellipsoids
from mjccd.mujoco.ellipsoids import fit_model, geom_shape

SHAPES = """
<mujoco>
 <asset>
  <mesh name="wedge" vertex="0 0 0  0.3 0 0  0 0.2 0  0 0 0.1  0.3 0.2 0.05  0.1 0.1 0.2"/>
 </asset>
 <worldbody>
  <geom name="floor" type="plane" size="5 5 0.1"/>
  <body name="ball" pos="0.5 0 1"><freejoint/><geom name="ball" type="sphere" size="0.13" pos="0.01 0.02 0.03"/></body>
  <body name="cube" pos="0 1 1"><freejoint/><geom type="box" size="0.1 0.1 0.1"/></body>
  <body name="brick" pos="1 1 1"><freejoint/><geom type="box" size="0.3 0.1 0.05" quat="0.9 0.1 0.3 0.2"/></body>
  <body name="pill" pos="2 0 1"><freejoint/><geom type="capsule" size="0.05 0.2" euler="0.3 0.2 0.1"/></body>
  <body name="can" pos="3 0 1"><freejoint/><geom type="cylinder" size="0.1 0.25"/></body>
  <body name="egg" pos="4 0 1"><freejoint/><geom type="ellipsoid" size="0.1 0.2 0.3" euler="0.5 0 0.2"/></body>
  <body name="rock" pos="5 0 1"><freejoint/><geom type="mesh" mesh="wedge"/></body>
  <body name="robot" pos="6 0 1"><freejoint/>
   <geom type="capsule" fromto="0 0 0 0.3 0 0" size="0.04"/>
   <geom type="box" pos="0.35 0 0" size="0.05 0.08 0.02"/>
   <geom type="sphere" pos="0 0 0.1" size="0.06"/>
   <geom type="cylinder" pos="0.1 0.1 0" size="0.03 0.05" euler="1 0 0"/>
  </body>
  <body name="ghost" pos="7 0 1"><freejoint/><geom type="sphere" size="0.1" contype="0" conaffinity="0"/></body>
 </worldbody>
</mujoco>
"""


@pytest.fixture(scope="module")
def model():
    return mujoco.MjModel.from_xml_string(SHAPES)


@pytest.fixture(scope="module")
def fitted(model):
    return fit_model(model)


def _row(es, body):
    return es.bodies.index(body)


def _quat_mat(q):
    m = np.empty(9)
    mujoco.mju_quat2Mat(m, np.asarray(q, float))
    return m.reshape(3, 3)


def _surface_samples(model, geom_id, n=4000, seed=0):
    """Random points on a geom's surface (mesh: its vertices), in the body frame."""
    rng = np.random.default_rng(seed)
    u = rng.normal(size=(n, 3))
    u /= np.linalg.norm(u, axis=1)[:, None]
    t = int(model.geom_type[geom_id])
    s = model.geom_size[geom_id]
    if t == mujoco.mjtGeom.mjGEOM_SPHERE:
        local = s[0] * u
    elif t == mujoco.mjtGeom.mjGEOM_ELLIPSOID:
        local = s * u
    elif t == mujoco.mjtGeom.mjGEOM_CAPSULE:
        local = s[0] * u + np.where(u[:, 2:] > 0, 1.0, -1.0) * np.array([0, 0, s[1]])
        side = rng.uniform(-s[1], s[1], n)
        ring = np.c_[s[0] * u[:, :2] / np.linalg.norm(u[:, :2], axis=1)[:, None], side]
        local = np.vstack([local, ring])
    elif t == mujoco.mjtGeom.mjGEOM_CYLINDER:
        ang = rng.uniform(0, 2 * np.pi, n)
        rad = s[0] * np.sqrt(rng.uniform(0, 1, n))
        h = rng.choice([-s[1], s[1]], n)
        cap = np.c_[rad * np.cos(ang), rad * np.sin(ang), h]
        wall = np.c_[s[0] * np.cos(ang), s[0] * np.sin(ang), rng.uniform(-s[1], s[1], n)]
        local = np.vstack([cap, wall, [[s[0], 0, s[1]], [-s[0], 0, -s[1]]]])
    elif t == mujoco.mjtGeom.mjGEOM_BOX:
        local = rng.uniform(-1, 1, (n, 3))
        k = rng.integers(0, 3, n)
        local[np.arange(n), k] = np.sign(local[np.arange(n), k])
        corners = np.array([[a, b, c] for a in (-1, 1) for b in (-1, 1) for c in (-1, 1)], float)
        local = np.vstack([local, corners]) * s
    elif t == mujoco.mjtGeom.mjGEOM_MESH:
        mid = model.geom_dataid[geom_id]
        local = model.mesh_vert[model.mesh_vertadr[mid]:model.mesh_vertadr[mid] + model.mesh_vertnum[mid]]
    else:
        raise AssertionError(t)
    return model.geom_pos[geom_id] + local @ _quat_mat(model.geom_quat[geom_id]).T


def _mahalanobis(es, k, pts):
    R = _quat_mat(es.quaternions[k])
    y = (pts - es.positions[k]) @ R / es.radii[k]
    return np.sqrt(np.sum(y * y, axis=1))


def test_every_surface_point_and_mesh_vertex_is_inside(model, fitted):
    for body in ("ball", "cube", "brick", "pill", "can", "egg", "rock", "robot"):
        b = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, body)
        pts = np.vstack([_surface_samples(model, g) for g in range(model.body_geomadr[b],
                                                                     model.body_geomadr[b] + model.body_geomnum[b])])
        r = _mahalanobis(fitted, _row(fitted, body), pts)
        assert r.max() <= 1.0 + 1e-12, body
        assert r.max() >= 0.97, f"{body}: ellipsoid is far from touching its geometry ({r.max()})"


def test_per_geom_fit_contains_each_geom(model):
    es = fit_model(model, per="geom", bodies=["robot"])
    assert len(es) == 4
    b = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, "robot")
    for k, g in enumerate(range(model.body_geomadr[b], model.body_geomadr[b] + 4)):
        assert _mahalanobis(es, k, _surface_samples(model, g)).max() <= 1.0 + 1e-12


def test_sphere_fits_to_itself(model, fitted):
    k = _row(fitted, "ball")
    np.testing.assert_allclose(fitted.radii[k], [0.13] * 3, rtol=1e-12)
    np.testing.assert_allclose(fitted.positions[k], [0.01, 0.02, 0.03], atol=1e-14)
    assert fitted.volume_ratios[k] == pytest.approx(1.0, rel=1e-12)


def test_box_fits_to_circumscribed_ellipsoid(model, fitted):
    np.testing.assert_allclose(fitted.radii[_row(fitted, "cube")], np.sqrt(3) * 0.1 * np.ones(3), rtol=1e-12)
    k = _row(fitted, "brick")
    np.testing.assert_allclose(fitted.radii[k], np.sqrt(3) * np.array([0.3, 0.1, 0.05]), rtol=1e-12)
    assert fitted.volume_ratios[_row(fitted, "cube")] == pytest.approx(np.pi * np.sqrt(3) / 2, rel=1e-12)


def test_containment_check_can_fail(model, fitted):
    """The check is not vacuous: a 1% smaller ellipsoid is reported as not containing."""
    b = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, "pill")
    atoms = geom_shape(model, model.body_geomadr[b]).atoms()
    k = _row(fitted, "pill")
    R = _quat_mat(fitted.quaternions[k])
    assert containment_factor(fitted.positions[k], R, fitted.radii[k], atoms) <= 1.0 + 1e-12
    assert containment_factor(fitted.positions[k], R, 0.99 * fitted.radii[k], atoms) > 1.005


def test_volume_report_lists_every_body(fitted):
    text = volume_report(fitted)
    for body in fitted.bodies:
        assert body in text
    assert "1.000" in text  # the sphere


def test_skips_planes_and_visual_geoms(fitted):
    assert "world" not in fitted.bodies
    assert "ghost" not in fitted.bodies


def test_errors_name_the_body(model):
    with pytest.raises(ValueError, match="bodies: body 'ghost' has no collision geometry"):
        fit_model(model, bodies=["ghost"])
    with pytest.raises(ValueError, match="bodies: body 'world' has only unsupported geoms"):
        fit_model(model, bodies=[0])
    with pytest.raises(ValueError, match=r"bodies\[0\]: the model has no body named 'nope'"):
        fit_model(model, bodies=["nope"])
    with pytest.raises(ValueError, match="per: expected 'body' or 'geom'"):
        fit_model(model, per="limb")
    with pytest.raises(ValueError, match="model: expected a mujoco.MjModel"):
        fit_model("model.xml")
    es = fit_model(model, bodies=["ghost"], include_visual=True)
    assert es.bodies == ("ghost",)


@pytest.mark.parametrize("ext", ["json", "npz"])
def test_file_round_trip(tmp_path, fitted, ext):
    path = tmp_path / f"set.{ext}"
    fitted.save(path)
    back = load_ellipsoids(path)
    assert back.bodies == fitted.bodies
    np.testing.assert_array_equal(back.radii, fitted.radii)
    np.testing.assert_allclose(back.quaternions, fitted.quaternions, rtol=0, atol=1e-15)
    np.testing.assert_array_equal(back.volume_ratios, fitted.volume_ratios)


def test_bad_ellipsoid_file(tmp_path):
    path = tmp_path / "bad.json"
    path.write_text(json.dumps({"version": 1, "ellipsoids": [{"body": "a", "radii": [1, -1, 1],
                                                              "position": [0, 0, 0], "quaternion": [1, 0, 0, 0]}]}))
    with pytest.raises(ValueError, match=r"ellipsoids\[0\].radii: radii must be positive"):
        EllipsoidSet.load(path)
    with pytest.raises(ValueError, match="path: expected a .json or .npz"):
        EllipsoidSet.load(tmp_path / "x.txt")


def test_mjcf_output_is_visual_only(tmp_path, model, fitted):
    src = tmp_path / "shapes.xml"
    src.write_text(SHAPES)
    out = tmp_path / "sub" / "shapes_fit.xml"
    out.parent.mkdir()
    write_mjcf(src, fitted, out)
    m2 = mujoco.MjModel.from_xml_path(str(out))
    assert m2.ngeom == model.ngeom + len(fitted)
    added = range(model.ngeom, m2.ngeom)
    names = {mujoco.mj_id2name(m2, mujoco.mjtObj.mjOBJ_GEOM, g) for g in range(m2.ngeom)}
    assert {f"mjccd_ellipsoid_{k}" for k in range(len(fitted))} <= names
    for g in range(m2.ngeom):
        if (mujoco.mj_id2name(m2, mujoco.mjtObj.mjOBJ_GEOM, g) or "").startswith("mjccd_"):
            assert m2.geom_contype[g] == 0 and m2.geom_conaffinity[g] == 0 and m2.geom_group[g] == 5
            assert m2.geom_type[g] == mujoco.mjtGeom.mjGEOM_ELLIPSOID
    assert len(added) == len(fitted)
    np.testing.assert_allclose(m2.body_mass, model.body_mass, rtol=1e-12)
    # the ellipsoids read back from the MJCF are the fitted ones
    refit = fit_model(m2, bodies=["ball"], per="geom", include_visual=True)
    assert np.allclose(refit.radii[-1], fitted.radii[_row(fitted, "ball")])


def test_cli_main(tmp_path, capsys):
    src = tmp_path / "shapes.xml"
    src.write_text(SHAPES)
    out = tmp_path / "out.xml"
    assert main([str(src), "-o", str(out)]) == 0
    assert "volume ratio" in capsys.readouterr().out
    es = load_ellipsoids(tmp_path / "out.ellipsoids.json")
    assert "robot" in es.bodies and out.exists()
    assert main([str(tmp_path / "missing.xml"), "-o", str(out)]) == 2
    assert "cannot load" in capsys.readouterr().err
    assert main([str(src), "--bodies", "ghost", "-q"]) == 2
    assert "has no collision geometry" in capsys.readouterr().err
