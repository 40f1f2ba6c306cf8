"""A plain (non-editable) install works: every bench suite runs from the wheel, outside the repository.

The sdist is built from a copy of the working tree's files (as a fresh clone would have
them: no build leftovers such as an old ``mjccd.egg-info``, whose file list setuptools
would reuse) and the wheel from the sdist, so both carry what they must (package data,
LICENSE, NOTICE).  The wheel goes with ``pip --no-deps`` into a fresh virtual environment
that sees this environment's packages through a ``.pth`` file (no second download of
numpy, numba or mujoco); each ``mjccd bench <suite> --quick`` then runs from an empty
folder outside the repository.  The numba caches of this checkout are copied next to the
installed copies of the same sources, so the kernels load instead of compiling for
minutes (a fresh install compiles them on first use: about 6 minutes for the four suites
on a busy 2-core machine).
"""
import os
import shutil
import subprocess
import sys
import sysconfig
import tarfile
import time
import venv
import zipfile
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest
import setuptools

from mjccd.bench import options

ROOT = Path(__file__).resolve().parents[1]
SUITES = {"core": "## Core (`mjccd bench core`)", "scene": "## Frame pipeline (`mjccd bench scene`)",
          "monitor": "## MuJoCo step monitor (`mjccd bench monitor`)", "patches": "| simulation | EE |"}
WHEEL_LIMIT = 1_000_000  # bytes: big data stays in the repository
SUITE_TIMEOUT = 900      # s: the first suite compiles most kernels


def _run(argv, cwd, env=None, timeout=300):
    done = subprocess.run([str(a) for a in argv], cwd=cwd, env=env, capture_output=True, text=True, timeout=timeout)
    assert done.returncode == 0, f"{' '.join(map(str, argv))} exited {done.returncode}:\n{done.stderr[-3000:]}"
    return done.stdout


def _clean_env():
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "PYTHONHOME", "PYTHONSTARTUP")}
    env["PYTHONNOUSERSITE"] = "1"
    return env


def _copy_checkout(dest):
    """Copy the working tree's files that git tracks or would track (symbolic links as links) to ``dest``."""
    listed = subprocess.run(["git", "ls-files", "-z", "--cached", "--others", "--exclude-standard"], cwd=ROOT,
                            capture_output=True, check=True).stdout.decode().split("\0")
    for name in filter(None, listed):
        source, target = ROOT / name, dest / name
        if not source.is_symlink() and not source.is_file():
            continue  # deleted in the working tree
        target.parent.mkdir(parents=True, exist_ok=True)
        if source.is_symlink():
            target.symlink_to(os.readlink(source))
        else:
            shutil.copy2(source, target)


def _reuse_compiled_kernels(site):
    """Copy this checkout's numba caches next to the installed copies of the same sources, with their times.

    numba keys a cache on the source file's modification time and size: a kernel the repository's
    own runs compiled then loads; a source that differs from the installed one is left to compile.
    """
    for source in (ROOT / "mjccd").rglob("*.py"):
        installed = site / source.relative_to(ROOT)
        caches = list(source.parent.glob(f"__pycache__/{source.stem}.*.nb[ic]"))
        if not caches or not installed.is_file() or installed.read_bytes() != source.read_bytes():
            continue
        stat = source.stat()
        os.utime(installed, ns=(stat.st_atime_ns, stat.st_mtime_ns))
        (installed.parent / "__pycache__").mkdir(exist_ok=True)
        for cache in caches:
            shutil.copy2(cache, installed.parent / "__pycache__" / cache.name)


@pytest.fixture(scope="module")
def installed(tmp_path_factory):
    """The sdist, the wheel, and a fresh environment (python, bin folder, site-packages) with the wheel installed."""
    assert int(setuptools.__version__.split(".")[0]) >= 77, \
        f"setuptools {setuptools.__version__} is too old to build mjccd: pip install -e '.[test]'"
    tmp = tmp_path_factory.mktemp("install")
    checkout, dist = tmp / "checkout", tmp / "dist"
    _copy_checkout(checkout)
    sdist = dist / _run([sys.executable, "-c", "import sys; from setuptools import build_meta; "
                         "print(build_meta.build_sdist(sys.argv[1]))", dist], cwd=checkout).split()[-1]
    _run([sys.executable, "-m", "pip", "wheel", "--no-deps", "--no-build-isolation", "--no-index",
          "--check-build-dependencies", "-q", "-w", dist, sdist], cwd=tmp)
    wheel = next(dist.glob("mjccd-*.whl"))
    env_dir = tmp / "env"
    venv.EnvBuilder(with_pip=False).create(env_dir)
    bin_dir = env_dir / "bin"
    python = bin_dir / "python"
    site = Path(_run([python, "-c", "import sysconfig; print(sysconfig.get_paths()['purelib'])"], cwd=tmp,
                     env=_clean_env()).strip())
    ours = sysconfig.get_paths()
    (site / "outer-environment.pth").write_text("\n".join(sorted({ours["purelib"], ours["platlib"]})) + "\n")
    _run([python, "-m", "pip", "install", "--no-deps", "--no-build-isolation", "--no-index", "--ignore-installed",
          "-q", wheel], cwd=tmp, env=_clean_env())
    _reuse_compiled_kernels(site)
    return SimpleNamespace(sdist=sdist, wheel=wheel, python=python, bin=bin_dir, site=site)


@pytest.mark.slow
def test_wheel_and_sdist_carry_licences_and_small_data(installed):
    sdist, wheel = installed.sdist, installed.wheel
    with zipfile.ZipFile(wheel) as whl:
        names = whl.namelist()
    assert {"mjccd-0.1.0.dist-info/licenses/LICENSE", "mjccd-0.1.0.dist-info/licenses/NOTICE"} <= set(names)
    assert "mjccd/bench/data/boxing_traj_first150.npz" in names
    assert wheel.stat().st_size < WHEEL_LIMIT, f"{wheel.name}: {wheel.stat().st_size} bytes"
    with tarfile.open(sdist) as tar:
        members = {m.name.split("/", 1)[1] for m in tar.getmembers() if "/" in m.name}
    assert {"LICENSE", "NOTICE", "mjccd/bench/data/cases.json", "mjccd/bench/data/boxing.xml"} <= members


@pytest.mark.slow
def test_import_comes_from_the_fresh_environment(installed, tmp_path):
    where = Path(_run([installed.python, "-c", "import mjccd; print(mjccd.__file__)"], cwd=tmp_path,
                      env=_clean_env()).strip())
    assert where.resolve().is_relative_to(installed.site.resolve()), where
    assert not where.resolve().is_relative_to(ROOT), where


@pytest.mark.slow
@pytest.mark.parametrize("suite", SUITES)
def test_bench_suite_runs_from_the_wheel(installed, suite, tmp_path):
    t0 = time.perf_counter()
    out = _run([installed.bin / "mjccd", "bench", suite, "--quick"], cwd=tmp_path, env=_clean_env(),
               timeout=SUITE_TIMEOUT)
    print(f"mjccd bench {suite} --quick: {time.perf_counter() - t0:.1f} s")
    assert SUITES[suite] in out
    assert not list(tmp_path.iterdir()), "a bench left files in the working folder"


@pytest.mark.slow
@pytest.mark.parametrize("argv, missing", [(["scene", "--only", "boxing"], "data/boxing_traj.npz"),
                                           (["patches", "--table", "3"], "data/ccd-queries")])
def test_data_left_out_of_the_wheel_is_asked_for_by_name(installed, argv, missing, tmp_path):
    done = subprocess.run([installed.bin / "mjccd", "bench", *argv], cwd=tmp_path, env=_clean_env(),
                          capture_output=True, text=True, timeout=120)
    last = done.stderr.strip().splitlines()[-1]
    assert done.returncode == 2 and missing in last and "--quick" in last, done.stderr


def test_packaged_trajectory_is_the_head_of_the_repository_one():
    full = ROOT / "data" / "boxing_traj.npz"
    with np.load(options.packaged("boxing_traj_first150.npz")) as head, np.load(full) as whole:
        assert sorted(head.files) == sorted(whole.files)
        for name in head.files:
            np.testing.assert_array_equal(head[name], whole[name][:150])
