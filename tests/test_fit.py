"""Bounding ellipsoids of a MuJoCo model: containment of every geom point, closed forms, files, MJCF output.

The fitting maths on its own is tested in ``test_fitting.py``.
"""
import json
import pathlib

import mujoco
import numpy as np
import pytest

from mjccd.fit import main, volume_report, write_mjcf
from mjccd.fitting import DEFAULT_TOLERANCE, containment_factor
from mjccd.mujoco import EllipsoidSet, load_ellipsoids
from mjccd.mujoco.ellipsoids import fit_model, fit_report, geom_shape, mesh_hull
from mjccd.mujoco.warnings import CoverageWarning

MODELS = pathlib.Path(__file__).resolve().parents[1] / "models"

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
    return fit_model(model, tolerance=None)  # one ellipsoid per body


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
    es = fit_model(model, tolerance=None, per="geom", bodies=["robot"])
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
    assert main([str(src), "-o", str(out), "--tolerance", "none"]) == 0
    assert "volume ratio" in capsys.readouterr().out
    es = load_ellipsoids(tmp_path / "out.ellipsoids.json")
    assert "robot" in es.bodies and out.exists()
    assert len(es) == len(set(es.bodies))  # one per body: the fit without a tolerance
    assert main([str(tmp_path / "missing.xml"), "-o", str(out)]) == 2
    assert "cannot load" in capsys.readouterr().err
    assert main([str(src), "--bodies", "ghost", "-q"]) == 2
    assert "has no collision geometry" in capsys.readouterr().err


def test_cli_render_draws_the_fit_or_says_why_not(tmp_path, capsys):
    """``--render``: a picture of the written model (in a fresh process: MUJOCO_GL is chosen before mujoco is
    imported), or one line saying OpenGL is missing; it needs -o and never overwrites a file unasked."""
    import subprocess
    import sys

    from matplotlib.image import imread

    src = tmp_path / "shapes.xml"
    src.write_text(SHAPES)
    out, png = tmp_path / "out.xml", tmp_path / "fit.png"
    assert main([str(src), "--render", str(png), "-q"]) == 2
    assert "--render: draws the written model, so it needs -o OUT.xml" in capsys.readouterr().err
    done = subprocess.run([sys.executable, "-m", "mjccd", "fit", str(src), "-o", str(out), "--tolerance", "none",
                           "-q", "--render", str(png)], capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr
    if png.exists():
        picture = imread(png)
        assert picture.shape[:2] == (720, 960) and picture[..., :3].std() > 0.01  # not a blank frame
    else:
        assert "rendering skipped: no OpenGL backend" in done.stderr
    png.write_bytes(b"mine")
    assert main([str(src), "-o", str(tmp_path / "again.xml"), "--render", str(png), "-q"]) == 2
    assert png.read_bytes() == b"mine" and not (tmp_path / "again.xml").exists()


def test_cli_loosens_a_geom_that_needs_too_many_ellipsoids_and_says_so(tmp_path, capsys):
    """The 30 cm wedge has sharp corners: at the default 1 cm it needs more than 64 ellipsoids, so it is covered
    within 2 cm (the least doubling that needs no more), and the command says so; the result is a proven cover."""
    src = tmp_path / "shapes.xml"
    src.write_text(SHAPES)
    out = tmp_path / "out.xml"
    assert main([str(src), "-o", str(out), "--bodies", "rock", "-q"]) == 0
    err = capsys.readouterr().err
    assert ("geom '#7' of body 'rock' needs more than 64 ellipsoids within 0.01 of it; it is covered within 0.02 ("
            in err)
    loose = load_ellipsoids(tmp_path / "out.ellipsoids.json")
    assert 1 <= len(loose) <= 64
    model = mujoco.MjModel.from_xml_string(SHAPES)
    strict = [row.overshoot for row in fit_report(model, loose) if row.body == "rock"][0]
    assert 0.01 < strict <= 0.02 + 1e-9
    assert main([str(src), "-o", str(out), "--bodies", "rock", "-q", "--tolerance", "0.05", "--force"]) == 0
    assert "covered within" not in capsys.readouterr().err
    with pytest.raises(SystemExit):
        main([str(src), "--tolerance", "-1"])
    assert "--tolerance: expected a positive length or 'none', got '-1'" in capsys.readouterr().err


def test_cli_reports_count_overshoot_and_union_volume_per_body(tmp_path, capsys):
    src = tmp_path / "shapes.xml"
    src.write_text(SHAPES)
    out = tmp_path / "out.xml"
    assert main([str(src), "-o", str(out), "--tolerance", "0.05"]) == 0
    text = capsys.readouterr().out
    assert "union volume ratio" in text and "largest overshoot" in text
    es = load_ellipsoids(tmp_path / "out.ellipsoids.json")
    model = mujoco.MjModel.from_xml_string(SHAPES)
    for row in fit_report(model, es, surface_samples=300, volume_samples=4096):
        assert row.ellipsoids == es.bodies.count(row.body)
        assert row.overshoot <= 0.05 * (1 + 1e-9)
        assert f"{row.body:<24} {row.ellipsoids:>10d}" in text
    written = mujoco.MjModel.from_xml_path(str(out))
    assert written.ngeom == model.ngeom + len(es)


# ---------------------------------------------------------------- fits to a tolerance


def _suite(name):
    dm_control = pytest.importorskip("dm_control")
    return pathlib.Path(dm_control.__file__).parent / "suite" / f"{name}.xml"


def _kinova():
    """The Kinova Jaco arm of models/arm_obstacle.xml: its STL meshes and rings, less the fitted bounds and the beam."""
    spec = mujoco.MjSpec.from_file(str(MODELS / "arm_obstacle.xml"))
    for geom in list(spec.geoms):
        if geom.name.endswith("_bound") or geom.parent.name == "obstacle":
            spec.delete(geom)
    return spec.compile()


def _mesh_samples(model, geom_id, rng, n=600):
    """A mesh geom's own vertices, points on its hull's faces and inside, in the body frame."""
    shape = geom_shape(model, geom_id, hull=True)
    v, f = shape.vertices, shape.faces
    on_faces = np.einsum("ij,ijk->ik", rng.dirichlet(np.ones(3), n), v[f[rng.integers(0, len(f), n)]])
    inside = v.mean(axis=0) + (on_faces - v.mean(axis=0)) * rng.uniform(0, 1, (n, 1))
    mesh = int(model.geom_dataid[geom_id])
    start = model.mesh_vertadr[mesh]
    local = np.vstack([model.mesh_vert[start:start + model.mesh_vertnum[mesh]], on_faces, inside])
    return shape.position + local @ shape.rotation.T


def _check_fit(model, es, tolerance, *, include_visual=False, seed=0):
    """Every sampled point of every bounded geom lies in its body's ellipsoids; the measured overshoot is within t."""
    rng = np.random.default_rng(seed)
    for body in dict.fromkeys(es.bodies):
        rows = [k for k, b in enumerate(es.bodies) if b == body]
        b = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, body)
        for g in range(model.body_geomadr[b], model.body_geomadr[b] + model.body_geomnum[b]):
            if int(model.geom_type[g]) in (mujoco.mjtGeom.mjGEOM_PLANE, mujoco.mjtGeom.mjGEOM_HFIELD):
                continue
            if not (include_visual or model.geom_contype[g] | model.geom_conaffinity[g]):
                continue
            mesh = model.geom_type[g] == mujoco.mjtGeom.mjGEOM_MESH
            pts = _mesh_samples(model, g, rng) if mesh else _surface_samples(model, g, n=500, seed=seed)
            if not mesh:  # and inside
                pts = np.vstack([pts, model.geom_pos[g] + (pts - model.geom_pos[g]) * rng.uniform(0, 1, (len(pts), 1))])
            reach = np.min([_mahalanobis(es, k, pts) for k in rows], axis=0)
            assert reach.max() <= 1.0 + 1e-9, (body, g, reach.max())
    report = fit_report(model, es, include_visual=include_visual, surface_samples=300, volume_samples=4096)
    for row in report:
        assert row.overshoot <= tolerance * (1.0 + 1e-9), row
        assert row.volume_ratio >= 1.0 - 0.02, row  # the union holds the geometry (up to the sampling)
    return report


@pytest.mark.parametrize("name", ["humanoid", "walker", "quadruped", "manipulator", "cheetah"])
def test_suite_models_fit_to_tolerances(name):
    model = mujoco.MjModel.from_xml_path(str(_suite(name)))
    counts = []
    for tolerance in (0.005, 0.01, 0.02):
        es = fit_model(model, tolerance=tolerance)
        _check_fit(model, es, tolerance)
        counts.append({b: es.bodies.count(b) for b in es.bodies})
    for fine, coarse in zip(counts, counts[1:]):  # never more ellipsoids at a larger tolerance, body by body
        assert all(coarse[b] <= fine[b] for b in fine), (fine, coarse)


def test_humanoid_limbs_at_the_default_tolerance():
    """dm-control's humanoid: within 1 cm with 2-3 ellipsoids a limb, where one per body overshoots by 7-8 cm."""
    model = mujoco.MjModel.from_xml_path(str(_suite("humanoid")))
    tight = {r.body: r for r in fit_report(model, fit_model(model, tolerance=DEFAULT_TOLERANCE),
                                           surface_samples=500, volume_samples=4096)}
    loose = {r.body: r for r in fit_report(model, fit_model(model, tolerance=None), surface_samples=500,
                                           volume_samples=4096)}
    for limb in ("right_thigh", "left_shin", "right_upper_arm", "left_lower_arm"):
        assert tight[limb].overshoot <= DEFAULT_TOLERANCE and tight[limb].ellipsoids <= 3
        assert loose[limb].ellipsoids == 1 and loose[limb].overshoot > 0.07
        assert tight[limb].volume_ratio < loose[limb].volume_ratio
    for foot in ("right_foot", "left_foot"):  # two capsules each
        assert tight[foot].ellipsoids <= 4 and tight[foot].overshoot <= DEFAULT_TOLERANCE


def test_kinova_meshes_fit_to_tolerances():
    """The STL meshes of the Kinova arm (models/kinova), their hulls as MuJoCo collides them, and the rings.

    The long D-shaped link, the wrist, the hand with its insert and a finger; the whole arm at 1 cm
    takes about a minute (140-odd ellipsoids: the hulls' edges are sharp).
    """
    model = _kinova()
    counts = []
    for tolerance in (0.02, 0.03, 0.05):
        es = fit_model(model, tolerance=tolerance, include_visual=True, per="geom",
                       bodies=["b_2", "b_4", "hand", "b_finger_1"])
        _check_fit(model, es, tolerance, include_visual=True)
        counts.append(len(es))
    assert counts == sorted(counts, reverse=True) and counts[0] > counts[-1]


def test_mesh_hull_is_mujocos_and_its_distance_agrees_with_mujoco():
    """The hull of a visual-only mesh (no graph in the model) is MuJoCo's, and distances agree with mj_geomDistance."""
    model = _kinova()
    g = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, "link_4")
    mesh = int(model.geom_dataid[g])
    assert model.mesh_graphadr[mesh] == -1  # a visual mesh: MuJoCo made no hull of its own
    vertices, faces = mesh_hull(model, mesh)
    start = model.mesh_vertadr[mesh]
    every = model.mesh_vert[start:start + model.mesh_vertnum[mesh]].astype(float)
    e1, e2 = vertices[faces[:, 1]] - vertices[faces[:, 0]], vertices[faces[:, 2]] - vertices[faces[:, 0]]
    normals = np.cross(e1, e2)
    offsets = np.einsum("ij,ij->i", normals, vertices[faces[:, 0]])
    assert np.all(every @ normals.T <= offsets + 1e-12)  # outward faces, every vertex inside
    # distances from points around the hull to it, against MuJoCo's own, with a point-sized sphere
    rng = np.random.default_rng(2)
    points = rng.normal(size=(40, 3)) * 0.06
    spec = mujoco.MjSpec()
    spec.add_mesh(name="m", uservert=every.ravel().tolist())
    spec.worldbody.add_geom(type=mujoco.mjtGeom.mjGEOM_MESH, meshname="m")
    probe = spec.worldbody.add_body(name="probe", mocap=True)
    probe.add_geom(type=mujoco.mjtGeom.mjGEOM_SPHERE, size=[1e-9, 0, 0])
    check = spec.compile()  # MuJoCo recentres the vertices and moves the geom frame so the mesh stays put
    data = mujoco.MjData(check)
    shape = geom_shape(model, g, hull=True)
    ours = shape.distance(shape.position + points @ shape.rotation.T)
    theirs = []
    for p in points:
        data.mocap_pos[0] = p
        mujoco.mj_kinematics(check, data)
        theirs.append(max(mujoco.mj_geomDistance(check, data, 0, 1, 1.0, None), 0.0))
    assert np.any(ours == 0.0) and np.any(ours > 0.01)
    np.testing.assert_allclose(ours, theirs, atol=1e-5)


def _random_model(rng, bodies=6):
    """MJCF of free bodies with 1-3 random geoms each: capsules, boxes, cylinders, ellipsoids, spheres."""
    xml = ["<mujoco><worldbody>"]
    for b in range(bodies):
        xml.append(f'<body name="b{b}" pos="{b} 0 1"><freejoint/>')
        for _ in range(rng.integers(1, 4)):
            kind = rng.choice(["capsule", "box", "cylinder", "ellipsoid", "sphere"])
            big = rng.uniform(0.02, 0.15)
            small = big / rng.uniform(1.0, 20.0)
            size = {"capsule": [small, big], "cylinder": [small, big], "sphere": [big],
                    "box": [big, small, rng.uniform(small, big)], "ellipsoid": [big, small, rng.uniform(small, big)]}
            pos = " ".join(f"{x:.4f}" for x in rng.normal(size=3) * 0.05)
            euler = " ".join(f"{x:.4f}" for x in rng.uniform(-np.pi, np.pi, 3))
            xml.append(f'<geom type="{kind}" size="{" ".join(f"{x:.5f}" for x in size[kind])}" pos="{pos}" '
                       f'euler="{euler}"/>')
        xml.append("</body>")
    xml.append("</worldbody></mujoco>")
    return mujoco.MjModel.from_xml_string("".join(xml))


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_random_models_fit_to_tolerances(seed):
    rng = np.random.default_rng(seed)
    model = _random_model(rng)
    for per in ("body", "geom"):
        counts = []
        for tolerance in (0.01, 0.02, 0.04):
            es = fit_model(model, tolerance=tolerance, per=per)
            _check_fit(model, es, tolerance, seed=seed)
            counts.append([es.bodies.count(f"b{b}") for b in range(model.nbody - 1)])
        for fine, coarse in zip(counts, counts[1:]):
            assert all(c <= f for f, c in zip(fine, coarse)), counts


def test_tolerance_fit_files_keep_the_format(tmp_path):
    model = mujoco.MjModel.from_xml_path(str(_suite("walker")))
    es = fit_model(model, tolerance=DEFAULT_TOLERANCE)
    path = tmp_path / "walker.json"
    es.save(path)
    doc = json.loads(path.read_text())
    assert doc["version"] == 1
    assert set(doc["ellipsoids"][0]) == {"body", "geom", "radii", "position", "quaternion", "volume_ratio"}
    back = load_ellipsoids(path)
    assert back.bodies == es.bodies and back.geoms == es.geoms
    np.testing.assert_array_equal(back.radii, es.radii)
    # a cover's volume ratios are each ellipsoid over its geom: the pieces of a capsule add up past 1
    torso = [k for k, g in enumerate(es.geoms) if g == "torso"]
    assert len(torso) > 1 and es.volume_ratios[torso].sum() > 1.0 > es.volume_ratios[torso].min()


def test_tolerance_errors_name_the_argument():
    model = mujoco.MjModel.from_xml_string(SHAPES)
    for bad in (0, -0.01, np.nan, "1cm", True):
        with pytest.raises(ValueError, match="tolerance: expected None or a positive length, got"):
            fit_model(model, tolerance=bad)
    with pytest.warns(CoverageWarning, match="geom '#2' of body 'cube' needs more than 4 ellipsoids within 0.01 of "
                                             "it; it is covered within 0.0"):
        few = fit_model(model, tolerance=0.01, bodies=["cube"], max_ellipsoids=4)
    assert len(few) <= 4
    with pytest.warns(CoverageWarning, match="needs more than 4 ellipsoids"):  # a cached fit warns the same
        fit_model(model, tolerance=0.01, bodies=["cube"], max_ellipsoids=4)


# ---------------------------------------------------------------- MJCF output of models with classes and assets


def test_quadruped_written_with_ellipsoids_compiles_and_keeps_its_masses(tmp_path):
    """Regression: the added geoms took the body's child class, whose fromto clashed with their pos."""
    src = _suite("quadruped")
    out = tmp_path / "quadruped_fit.xml"
    assert main([str(src), "-o", str(out), "-q"]) == 0
    written = mujoco.MjModel.from_xml_path(str(out))
    original = mujoco.MjModel.from_xml_path(str(src))
    es = load_ellipsoids(tmp_path / "quadruped_fit.ellipsoids.json")
    assert written.ngeom == original.ngeom + len(es)
    np.testing.assert_allclose(written.body_mass, original.body_mass, rtol=1e-5)
    added = [g for g in range(written.ngeom)
             if (mujoco.mj_id2name(written, mujoco.mjtObj.mjOBJ_GEOM, g) or "").startswith("mjccd_ellipsoid_")]
    assert len(added) == len(es)
    assert all(written.geom_type[g] == mujoco.mjtGeom.mjGEOM_ELLIPSOID and written.geom_contype[g] == 0
               and written.geom_conaffinity[g] == 0 and written.geom_group[g] == 5 for g in added)
    np.testing.assert_allclose(written.geom_size[added], es.radii, rtol=1e-5)


def test_ellipsoids_take_no_mass_fromto_or_fluid_shape_from_the_defaults(tmp_path):
    src = tmp_path / "classes.xml"
    src.write_text("""<mujoco>
     <default><geom mass="2" fluidshape="ellipsoid"/>
      <default class="limb"><geom type="capsule" fromto="0 0 0 0.3 0 0" size="0.04" material="skin"/></default>
     </default>
     <asset><material name="skin" rgba="1 0 0 1"/></asset>
     <worldbody><body name="arm" childclass="limb"><freejoint/><geom/><geom fromto="0 0 0 0 0.2 0"/></body></worldbody>
    </mujoco>""")
    out = tmp_path / "sub" / "classes_fit.xml"
    out.parent.mkdir()
    assert main([str(src), "-o", str(out), "-q"]) == 0
    before, after = mujoco.MjModel.from_xml_path(str(src)), mujoco.MjModel.from_xml_path(str(out))
    np.testing.assert_allclose(after.body_mass, before.body_mass, rtol=1e-6)
    added = range(before.ngeom, after.ngeom)
    assert len(added) > 0
    assert np.all(after.geom_fluid[added, 0] == 0)  # no fluid forces on the ellipsoids
    assert np.all(after.geom_matid[added] == -1)
    # refitting the written model replaces the ellipsoids and reuses their class
    again = tmp_path / "sub" / "classes_fit2.xml"
    assert main([str(out), "-o", str(again), "-q"]) == 0
    assert mujoco.MjModel.from_xml_path(str(again)).ngeom == after.ngeom


def test_kinova_written_elsewhere_finds_its_stl_meshes(tmp_path):
    """meshdir="kinova/" relative to models/: rewritten relative to an output folder elsewhere on disk."""
    out = tmp_path / "far" / "away" / "arm_fit.xml"
    out.parent.mkdir(parents=True)
    assert main([str(MODELS / "arm_obstacle.xml"), "-o", str(out), "-q", "--include-visual",
                 "--bodies", "b_4", "hand", "--tolerance", "0.05"]) == 0
    written = mujoco.MjModel.from_xml_path(str(out))
    original = mujoco.MjModel.from_xml_path(str(MODELS / "arm_obstacle.xml"))
    assert written.nmesh == original.nmesh
    np.testing.assert_array_equal(written.mesh_vertnum, original.mesh_vertnum)
    np.testing.assert_allclose(written.mesh_vert, original.mesh_vert, atol=1e-6)


def test_assets_and_includes_are_found_from_another_folder(tmp_path):
    """assetdir (meshdir and texturedir both), a texture file and an included file in a subfolder."""
    source = tmp_path / "src"
    (source / "assets").mkdir(parents=True)
    (source / "parts").mkdir()
    (source / "assets" / "wrist.stl").write_bytes((MODELS / "kinova" / "wrist.stl").read_bytes())
    (source / "assets" / "check.png").write_bytes(_png(4, 4))
    (source / "parts" / "wrist.xml").write_text(
        '<mujoco><worldbody><body name="wrist" pos="0 0 1"><freejoint/>'
        '<geom type="mesh" mesh="wrist" material="checker"/></body></worldbody></mujoco>')
    (source / "model.xml").write_text(
        '<mujoco><compiler assetdir="assets"/><asset><mesh name="wrist" file="wrist.stl"/>'
        '<texture name="check" type="2d" file="check.png"/><material name="checker" texture="check"/></asset>'
        '<include file="parts/wrist.xml"/></mujoco>')
    out = tmp_path / "elsewhere" / "deeper" / "model_fit.xml"
    out.parent.mkdir(parents=True)
    assert main([str(source / "model.xml"), "-o", str(out), "-q", "--tolerance", "0.03"]) == 0
    written = mujoco.MjModel.from_xml_path(str(out))
    assert written.nmesh == 1 and written.ntex == 1
    es = load_ellipsoids(out.with_suffix(".ellipsoids.json"))
    assert written.ngeom == 1 + len(es)


def _png(width, height):
    """A small grey PNG, written without an imaging library."""
    import struct
    import zlib

    def chunk(kind, data):
        return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data) & 0xFFFFFFFF)

    rows = b"".join(b"\x00" + b"\x80\x80\x80" * width for _ in range(height))
    return (b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", width, height, 8, 2, 0, 0, 0))
            + chunk(b"IDAT", zlib.compress(rows)) + chunk(b"IEND", b""))


NOTHING_COLLIDES = """
<mujoco>
  <worldbody>
    <geom name="floor" type="plane" size="5 5 0.1" contype="0" conaffinity="0"/>
    <body name="link"><freejoint/><geom type="capsule" size="0.1 0.5" contype="0" conaffinity="0"/></body>
  </worldbody>
</mujoco>
"""


def test_nothing_to_bound_warns_and_gives_an_empty_set_the_monitor_takes(tmp_path, capsys):
    """As Gymnasium's Swimmer: no collision geometry.  fit_model warns (pointing at include_visual) and returns an
    empty set, which a monitor takes (no pair, its own warning); the command refuses and writes nothing."""
    from mjccd.mujoco import CCDMonitor
    from mjccd.mujoco.warnings import CoverageWarning

    model = mujoco.MjModel.from_xml_string(NOTHING_COLLIDES)
    with pytest.warns(CoverageWarning, match="nothing to bound .include_visual=True"):
        empty = fit_model(model)
    assert len(empty) == 0 and empty.radii.shape == (0, 3)
    assert len(fit_model(model, tolerance=None, include_visual=True)) == 1
    with pytest.warns(CoverageWarning, match="no pair to check: the ellipsoid set is empty"):
        monitor = CCDMonitor(model, mujoco.MjData(model), empty, mode="ellipsoids")
    assert monitor.step() is None
    src, out = tmp_path / "nothing.xml", tmp_path / "out.xml"
    src.write_text(NOTHING_COLLIDES)
    assert main([str(src), "-o", str(out)]) == 2
    assert "nothing to bound (--include-visual bounds the visual geoms)" in capsys.readouterr().err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["nothing.xml"]
