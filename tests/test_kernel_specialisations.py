"""The solver's kernels compile once per argument type, never once per literal value.

A kernel called from compiled code with a constant (``gamma(80)``, ``empty_pencil(4, 5, 6)``, a ``False``
flag, a module constant such as ``MAX_BOXES``) is typed with that literal, so numba compiles it again for
every value: the README's first ``first_contact`` compiled 93 kernels where 79 do.  Call sites pass
``np.intp(0)`` or ``np.bool_(False)``, and the one-line helpers that take literals are typed inside their
callers (docs/benchmarks.md, "First use").

The geom solver's kernels take the shape codes, a system's side, a local axis and a frame's block offsets as
numpy integers (``mjccd.geoms.systems``, ``mjccd.geoms.frames``), and its flags as ``np.bool_``, for the same
reason: passed as Python constants they compiled 175 kernels for the first geoms-mode step where 143 do.

Each check compiles its solver in a fresh process with an empty numba cache: a kernel loaded from
the cache carries its callees inside, so their dispatchers would never show what they compiled.
"""
import os
import subprocess
import sys
import tempfile
import textwrap

LITERALS = textwrap.dedent("""
    import gc
    from numba.core import types
    from numba.core.registry import CPUDispatcher


    def literal_signatures(modules):
        dispatchers = [d for d in gc.get_objects() if isinstance(d, CPUDispatcher) and d.py_func.__module__ in modules]
        assert sum(len(d.signatures) for d in dispatchers) > 40, "the solver's kernels did not compile here"
        for d in dispatchers:
            for sig in d.signatures:
                if any(isinstance(t, types.Literal) for t in sig):
                    print(f"{d.py_func.__module__}.{d.py_func.__name__}{sig}")
""")

TWO_POSE = textwrap.dedent("""
    import mjccd

    a, b = mjccd.Ellipsoid([0.3, 0.2, 0.1]), mjccd.Ellipsoid([0.2, 0.2, 0.4])
    still = mjccd.Static([0, 0.1, 0], [1, 0, 0, 0])
    for motion in (mjccd.Rigid([-1, 0, 0], [1, 0, 0, 0], [1, 0, 0], [0.7071, 0, 0.7071, 0]),   # rotating
                   mjccd.Rigid([-1, 0, 0], [1, 0, 0, 0], [1, 0, 0], [1, 0, 0, 0]),             # translating
                   mjccd.Affine([-1, 0, 0], [1, 0, 0, 0], [1, 0, 0], [0.7071, 0, 0.7071, 0])):  # affine
        assert mjccd.first_contact(a, motion, b, still) is not None
        assert len(mjccd.collision_intervals(a, motion, b, still)) == 1
    literal_signatures(("mjccd.ccd", "mjccd.bernstein", "mjccd.quadric", "mjccd.motion"))
""")

# one pair solve compiles every shape pair's systems (the shapes are a runtime code)
GEOMS = textwrap.dedent("""
    import mjccd
    from mjccd.geoms import Box, Capsule, geom_first_contact

    moving = mjccd.Rigid([-1, 0, 0], [1, 0, 0, 0], [1, 0, 0], [0.7071, 0, 0.7071, 0])
    still = mjccd.Static([0, 0.1, 0], [1, 0, 0, 0])
    assert geom_first_contact(Capsule(0.1, 0.3), moving, Box([0.2, 0.1, 0.3]), still) is not None
    literal_signatures(("mjccd.geoms.systems", "mjccd.geoms.frames", "mjccd.geoms.kernel", "mjccd.geoms.on_plane"))
""")


def literal_specialisations(script):
    """The kernels that ``script`` (in a fresh process, an empty numba cache) compiled for a literal argument."""
    with tempfile.TemporaryDirectory() as cache:
        env = dict(os.environ, NUMBA_CACHE_DIR=cache)
        done = subprocess.run([sys.executable, "-c", LITERALS + script], env=env, capture_output=True, text=True,
                              timeout=900)
    assert done.returncode == 0, done.stderr[-3000:]
    return done.stdout.split("\n")[:-1]


def test_two_pose_solver_compiles_no_literal_specialisation():
    assert literal_specialisations(TWO_POSE) == []


def test_geom_solver_compiles_no_literal_specialisation():
    assert literal_specialisations(GEOMS) == []
