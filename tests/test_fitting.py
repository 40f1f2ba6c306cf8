"""The fitting maths (``mjccd.fitting``) and the layering around it: a core without MuJoCo, no import cycles."""
import ast
import pathlib
import subprocess
import sys

import numpy as np
import pytest

import mjccd
from mjccd import bvh
from mjccd.fitting import Shape, ball_max_bound, containment_factor, fit_atoms, fit_shapes, mvee
from mjccd.quadric import matrix_to_quat, quat_to_matrix

PACKAGE = pathlib.Path(mjccd.__file__).resolve().parent
CORE = ("bernstein", "quadric", "motion", "ccd", "filters", "scene", "sorting", "fitting")
CLIPS = PACKAGE.parent / "data" / "mocap"

# ---------------------------------------------------------------- layering


def test_the_core_imports_without_mujoco():
    """Every core module imports while ``import mujoco`` fails; the blocker itself is shown to work."""
    code = "\n".join([
        "import sys",
        "sys.modules['mujoco'] = None  # any import of mujoco now raises ImportError",
        *(f"import mjccd.{name}" for name in CORE),
        "loaded = sorted(m for m in sys.modules if m.startswith(('mjccd.mujoco', 'dm_control')))",
        "assert not loaded, loaded",
        "try:",
        "    import mjccd.fit",
        "except ImportError:",
        "    pass",
        "else:",
        "    raise AssertionError('mjccd.fit imported without mujoco: the blocker does not work')",
    ])
    run = subprocess.run([sys.executable, "-c", code], cwd=PACKAGE.parent, capture_output=True, text=True)
    assert run.returncode == 0, run.stderr


def _modules():
    """``{dotted name: path}`` of mjccd's modules and packages (two levels)."""
    paths = sorted(PACKAGE.glob("*.py")) + sorted(PACKAGE.glob("*/*.py"))
    names = {}
    for path in paths:
        parts = path.relative_to(PACKAGE.parent).with_suffix("").parts
        names[".".join(parts[:-1] if parts[-1] == "__init__" else parts)] = path
    return names


def _import_edges(name, path, modules):
    """``{(imported module, "module:line")}`` for every mjccd import of a module, at module level or in a function.

    Importing ``a.b.c`` first runs the packages ``a`` and ``a.b``, so those
    are edges too, except packages the importer itself lies in (they are
    already running).  ``from package import name`` of a non-module depends
    on the package.  Only mjccd modules are nodes: a deferred import of an
    optional third-party package (matplotlib, tqdm, ...) never enters.
    """
    package = name if path.name == "__init__.py" else name.rpartition(".")[0]
    edges = set()
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, ast.Import):
            targets = [alias.name for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                parent = package.split(".")[:len(package.split(".")) - node.level + 1]
                base = ".".join(parent + ([base] if base else []))
            targets = [f"{base}.{alias.name}" if f"{base}.{alias.name}" in modules else base
                       for alias in node.names]
        else:
            continue
        for target in targets:
            parts = target.split(".")
            if parts[0] != "mjccd":
                continue
            for k in range(1, len(parts) + 1):
                prefix = ".".join(parts[:k])
                running = name.startswith(prefix + ".") and prefix != target
                if prefix in modules and prefix != name and not running:
                    edges.add((prefix, f"{name}:{node.lineno}"))
    return edges


def _cycle(graph):
    """One cycle of ``{node: {(node, where)}}`` as ``[(node, where), ...]``, or None."""
    state, stack = {}, []

    def visit(node):
        state[node] = "open"
        for target, where in sorted(graph[node]):
            stack.append((node, where))
            if state.get(target) == "open":
                start = next(i for i, (n, _) in enumerate(stack) if n == target)
                return stack[start:]
            if target not in state:
                found = visit(target)
                if found:
                    return found
            stack.pop()
        state[node] = "done"
        return None

    for node in sorted(graph):
        if node not in state:
            found = visit(node)
            if found:
                return found
    return None


def test_no_import_cycles_among_mjccd_modules():
    """Module-level and function-level imports together: the core at the bottom, the MuJoCo side above it."""
    modules = _modules()
    graph = {name: _import_edges(name, path, modules) for name, path in modules.items()}
    cycle = _cycle(graph)
    if cycle:
        steps = [f"{where} imports {target}" for (_, where), (target, _) in zip(cycle, cycle[1:] + cycle[:1])]
        pytest.fail("import cycle: " + "; ".join(steps))


def _private_imports(name, path, modules):
    """``["module:line imports other._name", ...]``: names with a leading underscore that a module imports from
    another mjccd module (a private module itself, such as ``mjccd._validate``, may be imported, and its public
    names)."""
    found = []
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if not isinstance(node, ast.ImportFrom) or not (node.module or "").startswith("mjccd"):
            continue
        for alias in node.names:
            private = alias.name.startswith("_") and not alias.name.startswith("__")
            if private and f"{node.module}.{alias.name}" not in modules and node.module != name:
                found.append(f"{name}:{node.lineno} imports {node.module}.{alias.name}")
    return found


def test_no_module_imports_another_modules_private_names():
    """What a module keeps to itself (a leading underscore) no other module imports: shared names are public."""
    modules = _modules()
    modules.update({name: path for name, path in ((".".join(p.relative_to(PACKAGE.parent).with_suffix("").parts), p)
                                                  for p in PACKAGE.rglob("*.py") if "__pycache__" not in p.parts)})
    found = [line for name, path in modules.items() for line in _private_imports(name, path, modules)]
    assert not found, found


def test_the_private_import_check_finds_one(tmp_path):
    path = tmp_path / "user.py"
    path.write_text("from mjccd.ccd import solve_pair, _secret\nfrom mjccd._validate import array\n")
    assert _private_imports("mjccd.user", path, {"mjccd.ccd": None, "mjccd._validate": None}) == [
        "mjccd.user:1 imports mjccd.ccd._secret"]


def test_the_cycle_check_finds_a_cycle():
    graph = {"a": {("b", "a.py:1")}, "b": {("c", "b.py:2")}, "c": {("a", "c.py:3")}, "d": set()}
    assert [node for node, _ in _cycle(graph)] == ["a", "b", "c"]
    assert _cycle({"a": {("b", "a.py:1")}, "b": set()}) is None


def test_a_submodule_import_runs_its_package(tmp_path):
    """``from mjccd.mujoco.ellipsoids import x`` in mjccd/fit.py depends on mjccd/mujoco/__init__.py too."""
    modules = {"mjccd", "mjccd.fit", "mjccd.mujoco", "mjccd.mujoco.ellipsoids"}
    fit = tmp_path / "fit.py"
    fit.write_text("from mjccd.mujoco.ellipsoids import fit_model\n\ndef f():\n    from mjccd import fit\n")
    ellipsoids = tmp_path / "ellipsoids.py"
    ellipsoids.write_text("from mjccd.mujoco import fit_model\n")
    assert _import_edges("mjccd.fit", fit, modules) == {("mjccd.mujoco", "mjccd.fit:1"),
                                                        ("mjccd.mujoco.ellipsoids", "mjccd.fit:1")}
    assert _import_edges("mjccd.mujoco.ellipsoids", ellipsoids, modules) == {("mjccd.mujoco",
                                                                             "mjccd.mujoco.ellipsoids:1")}


# ---------------------------------------------------------------- shapes and their atoms


def _rotation(rng):
    q = rng.normal(size=4)
    return quat_to_matrix(q / np.linalg.norm(q))


def _surface(shape, rng, n=3000):
    """Random points on the surface of a shape (a mesh: its vertices), placed by its pose."""
    u = rng.normal(size=(n, 3))
    u /= np.linalg.norm(u, axis=1)[:, None]
    s = np.asarray(shape.size, dtype=float)
    if shape.kind == "sphere":
        local = s[0] * u
    elif shape.kind == "ellipsoid":
        local = s * u
    elif shape.kind == "capsule":
        caps = s[0] * u + np.where(u[:, 2:] > 0, 1.0, -1.0) * np.array([0.0, 0.0, s[1]])
        ring = s[0] * u[:, :2] / np.linalg.norm(u[:, :2], axis=1)[:, None]
        local = np.vstack([caps, np.c_[ring, rng.uniform(-s[1], s[1], n)]])
    elif shape.kind == "cylinder":
        angle = rng.uniform(0.0, 2.0 * np.pi, n)
        rim = s[0] * np.c_[np.cos(angle), np.sin(angle)]
        local = np.vstack([np.c_[rim * np.sqrt(rng.uniform(0, 1, n))[:, None], rng.choice([-s[1], s[1]], n)],
                           np.c_[rim, rng.uniform(-s[1], s[1], n)], np.c_[rim, np.full(n, s[1])]])
    elif shape.kind == "box":
        local = rng.uniform(-1.0, 1.0, (n, 3))
        face = rng.integers(0, 3, n)
        local[np.arange(n), face] = np.sign(local[np.arange(n), face])
        local *= s
    else:
        local = shape.vertices
    return shape.position + local @ shape.rotation.T


def _radius(centre, rotation, radii, points):
    """``|diag(1/radii) R^T (x - centre)|`` of each point: <= 1 inside the ellipsoid."""
    return np.linalg.norm((points - centre) @ rotation / radii, axis=1)


def _shapes(rng):
    """One shape of every kind at a random pose; the mesh is a tetrahedron with a cut corner."""
    vertices = np.array([[0, 0, 0], [0.3, 0, 0], [0, 0.2, 0], [0, 0, 0.1], [0.3, 0.2, 0.05], [0.1, 0.1, 0.2]], float)
    faces = np.array([[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 4], [1, 4, 5], [2, 5, 4], [1, 5, 3], [2, 3, 5]])
    sizes = {"sphere": [0.13, 0, 0], "capsule": [0.05, 0.2, 0], "ellipsoid": [0.1, 0.2, 0.3],
             "cylinder": [0.1, 0.25, 0], "box": [0.3, 0.1, 0.05], "mesh": [0, 0, 0]}
    return [Shape(kind, np.array(size, float), rng.normal(size=3), _rotation(rng),
                  *((vertices, faces) if kind == "mesh" else ()))
            for kind, size in sizes.items()]


def test_every_kind_alone_and_all_together_are_contained_and_touched():
    rng = np.random.default_rng(7)
    shapes = _shapes(rng)
    for group in [[shape] for shape in shapes] + [shapes, shapes[1:4]]:
        fitted = fit_shapes(group)
        points = np.vstack([_surface(shape, rng) for shape in group])
        reach = _radius(*fitted, points)
        kinds = [shape.kind for shape in group]
        assert reach.max() <= 1.0 + 1e-12, kinds
        assert reach.max() >= 0.97, f"{kinds}: the ellipsoid is far from touching ({reach.max()})"


def test_closed_forms_touch_their_shape():
    rng = np.random.default_rng(2)
    for shape in _shapes(rng):
        exact = shape.closed_form()
        if shape.kind in ("capsule", "mesh"):
            assert exact is None
            continue
        assert containment_factor(*exact, shape.atoms()) == pytest.approx(1.0, abs=1e-12), shape.kind
    box = Shape("box", np.array([0.3, 0.1, 0.05]), np.zeros(3), np.eye(3))
    np.testing.assert_allclose(box.closed_form()[2], np.sqrt(3) * box.size, rtol=1e-15)


def test_cylinder_closed_form_is_minimal_among_axis_aligned():
    """r sqrt(3/2), h sqrt(3): any other axis-aligned ellipsoid that contains the cylinder is bigger."""
    cylinder = Shape("cylinder", np.array([0.1, 0.25, 0.0]), np.zeros(3), np.eye(3))
    centre, rotation, radii = cylinder.closed_form()
    best = np.prod(radii)
    for stretch in np.linspace(0.5, 2.0, 31):
        trial = radii * np.array([1.0, 1.0, stretch])
        grown = trial * containment_factor(centre, rotation, trial, cylinder.atoms())
        assert np.prod(grown) >= best * (1.0 - 1e-12)


def test_volumes_of_the_kinds():
    rng = np.random.default_rng(3)
    shapes = {shape.kind: shape for shape in _shapes(rng)}
    assert shapes["sphere"].volume() == pytest.approx(4 / 3 * np.pi * 0.13 ** 3, rel=1e-14)
    assert shapes["capsule"].volume() == pytest.approx(np.pi * 0.05 ** 2 * 0.4 + 4 / 3 * np.pi * 0.05 ** 3, rel=1e-14)
    assert shapes["box"].volume() == pytest.approx(8 * 0.3 * 0.1 * 0.05, rel=1e-14)
    cube = Shape("mesh", np.zeros(3), np.zeros(3), np.eye(3),
                 vertices=np.array([[x, y, z] for x in (0, 1) for y in (0, 2) for z in (0, 3)], float),
                 faces=np.array([[0, 1, 3], [0, 3, 2], [4, 6, 7], [4, 7, 5], [0, 4, 5], [0, 5, 1],
                                 [2, 3, 7], [2, 7, 6], [0, 2, 6], [0, 6, 4], [1, 5, 7], [1, 7, 3]]))
    assert cube.volume() == pytest.approx(6.0, rel=1e-14)
    with pytest.raises(ValueError, match="kind: expected one of"):
        Shape("plane", np.zeros(3), np.zeros(3), np.eye(3))


# ---------------------------------------------------------------- the fit and the containment bound


def test_mvee_of_box_corners_is_the_circumscribed_ellipsoid():
    corners = np.array([[a, b, c] for a in (-1, 1) for b in (-1, 1) for c in (-1, 1)], float) * [0.3, 0.1, 0.05]
    c, R, r = mvee(corners + [1.0, 2.0, 3.0], tolerance=1e-9)
    np.testing.assert_allclose(np.sort(r), np.sort(np.sqrt(3) * np.array([0.3, 0.1, 0.05])), rtol=1e-6)
    np.testing.assert_allclose(c, [1.0, 2.0, 3.0], atol=1e-9)


def test_mvee_of_points_on_an_ellipsoid_is_that_ellipsoid():
    rng = np.random.default_rng(5)
    R = _rotation(rng)
    radii = np.array([0.4, 1.0, 2.5])
    u = rng.normal(size=(4000, 3))
    u /= np.linalg.norm(u, axis=1)[:, None]
    inside = 0.5 * rng.uniform(-1, 1, (500, 3)) * radii
    points = np.array([1.0, -2.0, 0.5]) + np.vstack([u * radii, inside]) @ R.T
    c, Rf, rf = mvee(points, tolerance=1e-8)
    np.testing.assert_allclose(c, [1.0, -2.0, 0.5], atol=1e-3)
    order = np.argsort(rf)
    np.testing.assert_allclose(rf[order], radii, rtol=2e-3)
    np.testing.assert_allclose(np.abs(Rf[:, order].T @ R), np.eye(3), atol=1e-2)


def test_mvee_refuses_flat_points():
    square = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0], [0.5, 0.5, 0]], float)
    with pytest.raises(ValueError, match="lie in a plane or a line"):
        mvee(square)


def test_a_lone_ellipsoid_atom_fits_to_itself_without_its_closed_form():
    rng = np.random.default_rng(9)
    R = _rotation(rng)
    radii = np.array([0.1, 0.2, 0.3])
    c, Rf, rf = fit_atoms([Shape("ellipsoid", radii, np.ones(3), R).atoms()[0]])
    assert np.prod(rf) == pytest.approx(np.prod(radii), rel=1e-3)
    assert np.prod(rf) >= np.prod(radii) * (1.0 - 1e-12)  # it contains the ellipsoid, so it is no smaller


def test_containment_check_can_fail():
    """The check is not vacuous: a 1% smaller ellipsoid is reported as not containing."""
    capsule = Shape("capsule", np.array([0.05, 0.2, 0.0]), np.zeros(3), _rotation(np.random.default_rng(1)))
    c, R, r = fit_shapes([capsule])
    assert containment_factor(c, R, r, capsule.atoms()) <= 1.0 + 1e-12
    assert containment_factor(c, R, 0.99 * r, capsule.atoms()) > 1.005


def test_trust_region_bound_is_tight_and_above_every_sample():
    rng = np.random.default_rng(3)
    u = rng.normal(size=(20000, 3))
    u /= np.linalg.norm(u, axis=1)[:, None]
    for trial in range(40):
        a = rng.normal(size=3)
        B = rng.normal(size=(3, 3))
        if trial % 3 == 0:
            B[:, 2] = 0.0  # flat atom (a disk)
        if trial % 5 == 0:
            a = np.zeros(3)  # the hard case of the trust-region problem
        sampled = np.max(np.sum((a + u @ B.T) ** 2, axis=1))
        bound = ball_max_bound(a, B)
        assert sampled <= bound + 1e-12
        assert bound <= sampled * 1.01


# ---------------------------------------------------------------- the rotation helper the fits share


def test_matrix_to_quat_inverts_quat_to_matrix_also_near_half_turns():
    rng = np.random.default_rng(11)
    quats = rng.normal(size=(400, 4))
    quats[:100, 0] = 1e-9 * rng.normal(size=100)  # half turns: the trace branch would lose them
    quats[100:110, 1:] = 0.0  # no turn
    quats /= np.linalg.norm(quats, axis=1)[:, None]
    quats *= np.where(quats[:, :1] < 0, -1.0, 1.0)
    mats = np.array([quat_to_matrix(q) for q in quats])
    back = matrix_to_quat(mats)
    assert back.shape == (400, 4) and np.all(back[:, 0] >= 0.0)
    np.testing.assert_allclose(np.array([quat_to_matrix(q) for q in back]), mats, atol=1e-14)
    np.testing.assert_allclose(np.abs(np.sum(back * quats, axis=1)), 1.0, atol=1e-14)
    np.testing.assert_allclose(matrix_to_quat(mats[7]), back[7], rtol=0, atol=0)


# ---------------------------------------------------------------- a user: bounds of BVH skeleton parts


def test_bvh_parts_are_contained_in_their_ellipsoids():
    """Every capsule of each rigid part of a skeleton (fingers and shoulders frozen: parts of several limbs)."""
    rng = np.random.default_rng(4)
    clip = bvh.read_bvh(CLIPS / "cmu_13_18_boxing_first10s.bvh")
    frozen = frozenset("LHipJoint RHipJoint LeftShoulder RightShoulder LeftFingerBase LeftHandIndex1 LThumb "
                       "RightFingerBase RightHandIndex1 RThumb".split())
    groups = bvh.rigid_groups(clip, bvh.Layout("", bvh.CMU_SCALE, bvh.Placement(), frozen, 1))
    assert any(len(capsules) > 1 for capsules in groups.values())
    for joint, capsules in groups.items():
        radii, centre, quat = bvh.fit_capsules(capsules)
        points = np.vstack([_surface(bvh.capsule_shape(*c), rng, 500) for c in capsules])
        reach = _radius(centre, quat_to_matrix(quat), radii, points)
        assert 0.97 <= reach.max() <= 1.0, clip.joints[joint].name


def test_bvh_parts_are_bounded_within_the_default_tolerance():
    """``bvh.fit_part`` (the bounds of models/boxing.xml and of BVH imports): every point of a part's capsules lies
    in one of its ellipsoids, and no point of an ellipsoid lies farther than 1 cm from the capsules (sampled)."""
    rng = np.random.default_rng(5)
    clip = bvh.read_bvh(CLIPS / "cmu_13_18_boxing_first10s.bvh")
    frozen = frozenset("LHipJoint RHipJoint LeftShoulder RightShoulder LeftFingerBase LeftHandIndex1 LThumb "
                       "RightFingerBase RightHandIndex1 RThumb".split())
    groups = bvh.rigid_groups(clip, bvh.Layout("", bvh.CMU_SCALE, bvh.Placement(), frozen, 1))
    counts = []
    for joint, capsules in groups.items():
        fitted = bvh.fit_part(capsules)
        assert len(bvh.fit_part(capsules, None)) == 1
        counts.append(len(fitted))
        shapes = [bvh.capsule_shape(*c) for c in capsules]
        points = np.vstack([_surface(shape, rng, 400) for shape in shapes])
        reach = np.min([_radius(c, quat_to_matrix(q), r, points) for r, c, q in fitted], axis=0)
        assert reach.max() <= 1.0, clip.joints[joint].name
        for radii, centre, quat in fitted:
            sphere = rng.normal(size=(400, 3))
            outer = centre + (sphere / np.linalg.norm(sphere, axis=1, keepdims=True) * radii) @ quat_to_matrix(quat).T
            gap = np.min([shape.distance(outer) for shape in shapes], axis=0)
            assert gap.max() <= DEFAULT_TOLERANCE * (1.0 + 1e-6), clip.joints[joint].name
    assert max(counts) > 1 and min(counts) == 1  # long parts take several ellipsoids, short ones one


# ---------------------------------------------------------------- covers to a tolerance

from mjccd.fitting import (DEFAULT_TOLERANCE, _hull_distance, _surface_within, _trust_region,  # noqa: E402
                           cover_report, cover_shape, within_tolerance)

CUBE_FACES = np.array([[0, 2, 1], [1, 2, 3], [4, 5, 6], [5, 7, 6], [0, 1, 4], [1, 5, 4],
                       [2, 6, 3], [3, 6, 7], [0, 4, 2], [2, 4, 6], [1, 3, 5], [3, 7, 5]])
CUBE_SIGNS = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)], float)
OCTAHEDRON = np.vstack([np.eye(3), -np.eye(3)])
OCTAHEDRON_FACES = np.array([[a, b, c] for a in (0, 3) for b in (1, 4) for c in (2, 5)])


def _box_distance(local, half):
    return np.linalg.norm(np.maximum(np.abs(local) - half, 0.0), axis=1)


def _octahedron_distance(local, a):
    """Distance to ``|x| + |y| + |z| <= a``: projection onto the l1 ball (sort-based simplex projection)."""
    y = np.abs(local)
    inside = y.sum(axis=1) <= a
    u = -np.sort(-y, axis=1)
    css = np.cumsum(u, axis=1) - a
    k = np.arange(1, 4)
    rho = np.max(np.where(u - css / k > 0, k, 0), axis=1)
    theta = css[np.arange(len(y)), rho - 1] / rho
    proj = np.maximum(y - theta[:, None], 0.0)
    return np.where(inside, 0.0, np.linalg.norm(y - proj, axis=1))


def _test_distance(shape, points):
    """Distance to a shape, written here independently of :meth:`Shape.distance` (meshes: a box or an octahedron)."""
    local = (points - shape.position) @ shape.rotation
    s = shape.size
    if shape.kind == "sphere":
        return np.maximum(np.linalg.norm(local, axis=1) - s[0], 0.0)
    if shape.kind == "capsule":
        z = np.clip(local[:, 2], -s[1], s[1])
        return np.maximum(np.linalg.norm(local - np.c_[np.zeros((len(z), 2)), z], axis=1) - s[0], 0.0)
    if shape.kind == "cylinder":
        return np.hypot(np.maximum(np.hypot(local[:, 0], local[:, 1]) - s[0], 0.0),
                        np.maximum(np.abs(local[:, 2]) - s[1], 0.0))
    if shape.kind == "box":
        return _box_distance(local, s)
    if shape.kind == "ellipsoid":  # an upper bound: the way out along the ray from the centre
        return np.maximum(np.linalg.norm(local / s, axis=1) - 1.0, 0.0) * s.max()
    if len(shape.vertices) == 8:
        return _box_distance(local, np.abs(shape.vertices).max(axis=0))
    return _octahedron_distance(local, np.abs(shape.vertices).max())


def _solid(shape, rng, n=2000):
    """Points on the surface (a mesh: its vertices and points on its faces) and inside the shape, placed."""
    if shape.kind == "mesh":
        v, f = shape.vertices, shape.faces
        w = rng.dirichlet(np.ones(3), n)
        tri = f[rng.integers(0, len(f), n)]
        on_faces = np.einsum("ij,ijk->ik", w, v[tri])
        local = np.vstack([v, on_faces, on_faces * rng.uniform(0, 1, (n, 1))])
        return shape.position + local @ shape.rotation.T
    surface = _surface(shape, rng, n)
    centre = np.asarray(shape.position)
    return np.vstack([surface, centre + (surface - centre) * rng.uniform(0, 1, (len(surface), 1))])


def _union_reach(cover, points):
    """The least ``|diag(1/radii) R^T (x - centre)|`` over the cover's ellipsoids, per point: <= 1 inside the union."""
    return np.min([_radius(c, R, r, points) for c, R, r in cover], axis=0)


def _overshoot(cover, shape, rng, n=3000):
    """Largest test-side distance to the shape over random points on the cover's surfaces."""
    u = rng.normal(size=(n, 3))
    u /= np.linalg.norm(u, axis=1)[:, None]
    return max(float(_test_distance(shape, c + u @ (R * r).T).max()) for c, R, r in cover)


def _random_shape(rng, kind):
    """A shape of the kind with a random size (1-20 cm), aspect ratio up to 20:1 and pose."""
    big = rng.uniform(0.02, 0.2)
    small = big / rng.uniform(1.0, 20.0)
    sizes = {"sphere": [big, 0, 0], "capsule": [small, big, 0], "cylinder": [small, big, 0],
             "ellipsoid": [big, small, rng.uniform(small, big)], "box": [big, small, rng.uniform(small, big)]}
    if rng.uniform() < 0.5 and kind in ("capsule", "cylinder"):
        sizes[kind] = [big, small, 0]  # a disk or a flat pill
    return Shape(kind, np.array(sizes[kind]), rng.normal(size=3) * 0.1, _rotation(rng))


@pytest.mark.parametrize("kind", ["sphere", "ellipsoid", "capsule", "cylinder", "box"])
def test_random_covers_contain_the_shape_and_stay_within_the_tolerance(kind):
    """Every sampled surface and inside point is in the union; no sampled ellipsoid point is farther than t."""
    rng = np.random.default_rng(["sphere", "ellipsoid", "capsule", "cylinder", "box"].index(kind))
    for _ in range(8):
        shape = _random_shape(rng, kind)
        points = _solid(shape, rng)
        counts = []
        for t in (0.005, 0.01, 0.02):
            cover = cover_shape(shape, t)
            assert _union_reach(cover, points).max() <= 1.0 + 1e-12, (shape, t)
            assert _overshoot(cover, shape, rng) <= t * (1.0 + 1e-9), (shape, t)
            counts.append(len(cover))
        assert counts == sorted(counts, reverse=True), (shape, counts)


def test_spheres_and_ellipsoids_are_their_own_cover():
    rng = np.random.default_rng(5)
    for kind in ("sphere", "ellipsoid"):
        shape = _random_shape(rng, kind)
        ((c, R, r),) = cover_shape(shape, 1e-4)
        assert _overshoot([(c, R, r)], shape, rng) <= 1e-12
        np.testing.assert_allclose(np.sort(r), np.sort(shape.size if kind == "ellipsoid" else shape.size[:1].repeat(3)),
                                   rtol=1e-12)


def test_capsule_takes_one_spheroid_exactly_when_it_can_hold_both_end_balls():
    """A spheroid of equatorial radius R = r + t, tips at h + R, holds both end balls iff h <= 2R(R^2 - r^2)/r^2."""
    r, t = 0.05, 0.01
    R = r + t
    limit = 2.0 * R * (R * R - r * r) / (r * r)
    for h, count in ((0.98 * limit, 1), (1.02 * limit, 2)):
        cover = cover_shape(Shape("capsule", np.array([r, h, 0.0]), np.zeros(3), np.eye(3)), t / (1.0 - 1e-9))
        assert len(cover) == count


def test_box_corner_condition_decides_the_grid():
    """An axis-aligned ellipsoid within t of a box has semi-axes <= A + t: one holds the box iff sum (A/(A+t))^2 <= 1.

    With cells, the corner cell decides, axis by axis: a cube of half side
    0.1 at t = 0.05 fails 1 x 1 x 1 (3 (0.1/0.15)^2 = 1.33) and 1 x 1 x 2
    (2 (0.1/0.15)^2 + (0.05/0.1)^2 = 1.14) and passes 1 x 2 x 2 (0.94).
    """
    for half, t, count in (([0.0198, 0.01, 0.035], 0.02, 1), ([0.0198, 0.01, 0.035], 0.01, 3),
                           ([0.1, 0.1, 0.1], 0.1, 1), ([0.1, 0.1, 0.1], 0.05, 4)):
        shape = Shape("box", np.array(half), np.zeros(3), np.eye(3))
        cover = cover_shape(shape, t)
        assert len(cover) == count, (half, t, len(cover))
        assert (np.sum((np.array(half) / (np.array(half) + t)) ** 2) <= 1.0) == (count == 1)


def test_cover_of_a_cube_at_its_circumscribed_sphere_overshoots_by_the_closed_form():
    """A cube of half side a fits one sphere of radius a sqrt(3) once t >= a (sqrt(3) - 1), its overshoot."""
    a = 0.1
    cube = Shape("box", np.full(3, a), np.zeros(3), np.eye(3))
    cover = cover_shape(cube, a * (np.sqrt(3.0) - 1.0) * (1.0 + 1e-6))
    assert len(cover) == 1
    np.testing.assert_allclose(cover[0][2], np.full(3, a * np.sqrt(3.0)), rtol=1e-6)
    overshoot, ratio = cover_report(cover, [cube], volume_samples=2 ** 14)
    assert overshoot == pytest.approx(a * (np.sqrt(3.0) - 1.0), rel=1e-9)
    assert ratio == pytest.approx(np.pi * np.sqrt(3.0) / 2.0, rel=0.02)


@pytest.mark.parametrize("mesh", ["box", "octahedron"])
def test_mesh_covers_contain_the_hull_and_stay_within_the_tolerance(mesh):
    """Hull vertices, points on every face and inside are covered; sampled overshoot within t; count monotone."""
    rng = np.random.default_rng(8)
    if mesh == "box":
        vertices, faces, tolerances = CUBE_SIGNS * np.array([0.12, 0.03, 0.05]), CUBE_FACES, (0.01, 0.02, 0.04)
    else:  # sharp corners: 40 ellipsoids at 2 cm, more than 64 at 1.5 cm
        vertices, faces, tolerances = 0.1 * OCTAHEDRON, OCTAHEDRON_FACES, (0.03, 0.04, 0.05)
    shape = Shape("mesh", np.zeros(3), rng.normal(size=3) * 0.1, _rotation(rng), vertices=vertices, faces=faces)
    points = _solid(shape, rng)
    counts = []
    for t in tolerances:
        cover = cover_shape(shape, t)
        assert _union_reach(cover, points).max() <= 1.0 + 1e-9
        assert _overshoot(cover, shape, rng) <= t * (1.0 + 1e-9)
        counts.append(len(cover))
    assert counts == sorted(counts, reverse=True) and counts[0] > counts[-1]


def test_box_mesh_needs_no_more_than_a_few_more_ellipsoids_than_the_box():
    box = Shape("box", np.array([0.0198, 0.01, 0.035]), np.zeros(3), np.eye(3))
    mesh = Shape("mesh", np.zeros(3), np.zeros(3), np.eye(3), vertices=CUBE_SIGNS * box.size, faces=CUBE_FACES)
    for t in (0.01, 0.02):
        assert len(cover_shape(box, t)) <= len(cover_shape(mesh, t)) <= len(cover_shape(box, t)) + 2


def test_distances_to_shapes_against_independent_formulas():
    rng = np.random.default_rng(12)
    points = rng.normal(size=(500, 3)) * 0.2
    for kind in ("sphere", "capsule", "cylinder", "box"):
        shape = _random_shape(rng, kind)
        np.testing.assert_allclose(shape.distance(points), _test_distance(shape, points), atol=1e-14)
    for vertices, faces in ((CUBE_SIGNS * [0.1, 0.05, 0.02], CUBE_FACES), (0.1 * OCTAHEDRON, OCTAHEDRON_FACES)):
        mesh = Shape("mesh", np.zeros(3), rng.normal(size=3) * 0.05, _rotation(rng), vertices=vertices, faces=faces)
        np.testing.assert_allclose(mesh.distance(points), _test_distance(mesh, points), atol=1e-12)
        assert np.array_equal(mesh.contains(points), _test_distance(mesh, points) == 0.0)
    # an ellipsoid: the distance is attained on the surface, and no surface sample is nearer
    shape = Shape("ellipsoid", np.array([0.1, 0.03, 0.06]), np.zeros(3), _rotation(rng))
    u = rng.normal(size=(50000, 3))
    u /= np.linalg.norm(u, axis=1)[:, None]
    surface = u * shape.size @ shape.rotation.T
    far = points[shape.distance(points) > 0][:40]
    brute = np.min(np.linalg.norm(far[:, None, :] - surface[None], axis=2), axis=1)
    d = shape.distance(far)
    assert np.all(d <= brute + 1e-12) and np.all(d >= brute - 2e-3 * brute.max())
    assert np.all(shape.distance(0.5 * surface[:100]) == 0.0)


def test_hull_distance_is_zero_inside_and_matches_the_box():
    vertices = CUBE_SIGNS * np.array([0.2, 0.1, 0.05])
    mesh = Shape("mesh", np.zeros(3), np.zeros(3), np.eye(3), vertices=vertices, faces=CUBE_FACES)
    a, b, c, normals, offsets = mesh._hull()
    grid = np.stack(np.meshgrid(*[np.linspace(-0.4, 0.4, 17)] * 3, indexing="ij"), axis=-1).reshape(-1, 3)
    np.testing.assert_allclose(_hull_distance(grid, a, b, c, normals, offsets),
                               _box_distance(grid, np.array([0.2, 0.1, 0.05])), atol=1e-15)


def test_proofs_of_closeness_agree_with_samples():
    """``within_tolerance`` and ``_surface_within`` prove what samples show and refuse what they refute."""
    rng = np.random.default_rng(3)
    cube = Shape("box", np.full(3, 0.1), np.zeros(3), np.eye(3))
    exact = 0.1 * (np.sqrt(3.0) - 1.0)  # the circumscribed sphere's overshoot
    sphere = (np.zeros(3), np.eye(3), np.full(3, 0.1 * np.sqrt(3.0)))
    for proof in (lambda t: within_tolerance(*sphere, [cube], t),
                  lambda t: _surface_within(*sphere, cube.distance, t)):
        assert proof(exact * 1.01)
        assert not proof(exact * 0.99)
    # two balls side by side: their common ellipsoid reaches farthest between them, inside
    balls = [Shape("sphere", np.array([0.05, 0, 0]), np.array([x, 0.0, 0.0]), np.eye(3)) for x in (-0.1, 0.1)]
    c, R, r = fit_shapes(balls)
    u = rng.normal(size=(20000, 3))
    u /= np.linalg.norm(u, axis=1)[:, None]
    inside = c + (u * rng.uniform(0, 1, (len(u), 1)) ** (1 / 3)) @ (R * r).T
    worst = float(np.min([b.distance(inside) for b in balls], axis=0).max())
    assert not within_tolerance(c, R, r, balls, 0.9 * worst)
    assert within_tolerance(c, R, r, balls, 1.3 * worst)


def test_trust_region_bound_survives_a_gradient_below_rounding():
    """Regression: a disk whose offset lies along its flat axis up to 1e-19 gave NaN (h_max + |g| == h_max)."""
    a = np.array([0.0, -1.3e-19, 0.21])
    B = np.array([[0.909, 0.0, 0.0], [0.0, 0.909, 0.0], [0.0, -1.3e-20, 0.0]])
    bound, u = _trust_region(a, B)
    assert np.isfinite(bound) and np.all(np.isfinite(u))
    assert bound == pytest.approx(a @ a + 0.909 ** 2, rel=1e-12)


def test_cover_errors_name_the_argument():
    capsule = Shape("capsule", np.array([0.05, 0.2, 0.0]), np.zeros(3), np.eye(3))
    for bad in (0.0, -0.01, np.nan, np.inf, True, "0.01"):
        with pytest.raises(ValueError, match="tolerance: expected a positive length, got"):
            cover_shape(capsule, bad)
    with pytest.raises(ValueError, match="max_ellipsoids: expected a positive integer, got 0"):
        cover_shape(capsule, 0.01, max_ellipsoids=0)
    with pytest.raises(ValueError, match="tolerance: this box needs more than 64 ellipsoids to stay within 0.001 "):
        cover_shape(Shape("box", np.full(3, 0.1), np.zeros(3), np.eye(3)), 0.001)
    assert DEFAULT_TOLERANCE == 0.01
