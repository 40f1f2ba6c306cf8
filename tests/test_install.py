"""A plain (non-editable) install works: every bench suite runs from the wheel, outside the repository.

The sdist is built from a copy of the working tree's files (as a fresh clone would have
them: no build leftovers such as an old ``mjccd.egg-info``, whose file list setuptools
would reuse) and the wheel from the sdist, so both carry what they must (package data,
LICENSE, NOTICE).  The wheel goes with ``pip --no-deps`` into a fresh virtual environment
that sees this environment's packages through a ``.pth`` file (no second download of
numpy, numba or mujoco); each ``mjccd bench <suite> --quick`` then runs from an empty
folder outside the repository.  The numba caches of this checkout are copied next to the
installed copies of the same sources, so the kernels load instead of compiling for
minutes (a fresh install compiles them on first use: docs/benchmarks.md, "First use").

The first-use tests at the end check where numba's cache goes (next to the sources, or the
user's cache folder for a read-only install, never over the user's own ``NUMBA_CACHE_DIR``),
the compile notice and ``mjccd warmup``.
"""
import io
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
    assert {"mjccd/bench/data/boxing_traj_first150.npz", "mjccd/bench/data/geoms_heldout_s11.json",
            "mjccd/bench/data/geoms_heldout_s11_expected.json"} <= set(names)
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


# ---------------------------------------------------------------- first use: cache folder, compile notice, warmup


def _package(root):
    """A package folder laid out as mjccd's (a subpackage with kernels), for mjccd._cache's folder choice."""
    pkg = root / "mjccd"
    (pkg / "mujoco").mkdir(parents=True)
    (pkg / "__init__.py").write_text("")
    (pkg / "mujoco" / "__init__.py").write_text("")
    return pkg


def _read_only(monkeypatch, pkg):
    """os.access as on a read-only install: nothing under ``pkg`` is writable (root ignores chmod, so patch it)."""
    from mjccd import _cache

    real = os.access
    monkeypatch.setattr(_cache.os, "access",
                        lambda path, mode: False if Path(path).is_relative_to(pkg) else real(path, mode))


def test_numba_caches_next_to_a_writable_package(tmp_path):
    from mjccd import _cache

    env = {}
    assert _cache.cache_dir(env, str(_package(tmp_path))) is None
    assert _cache.configure(env, str(_package(tmp_path / "again"))) is None and env == {}


def test_read_only_package_caches_in_the_user_cache_folder(tmp_path, monkeypatch):
    from mjccd import _cache

    pkg = _package(tmp_path)
    _read_only(monkeypatch, pkg)
    env = {"XDG_CACHE_HOME": str(tmp_path / "xdg")}
    assert _cache.cache_dir(env, str(pkg)) == str(tmp_path / "xdg" / "mjccd")
    monkeypatch.setenv("HOME", str(tmp_path / "home"))
    assert _cache.cache_dir({}, str(pkg)) == str(tmp_path / "home" / ".cache" / "mjccd")
    assert _cache.cache_dir({"XDG_CACHE_HOME": ""}, str(pkg)) == str(tmp_path / "home" / ".cache" / "mjccd")
    # configure sets NUMBA_CACHE_DIR and makes the folder
    assert _cache.configure(env, str(pkg)) == str(tmp_path / "xdg" / "mjccd")
    assert env["NUMBA_CACHE_DIR"] == str(tmp_path / "xdg" / "mjccd") and (tmp_path / "xdg" / "mjccd").is_dir()


def test_read_only_subpackage_is_enough_to_move_the_cache(tmp_path, monkeypatch):
    from mjccd import _cache

    pkg = _package(tmp_path)
    _read_only(monkeypatch, pkg / "mujoco")
    assert _cache.cache_dir({"XDG_CACHE_HOME": str(tmp_path / "xdg")}, str(pkg)) == str(tmp_path / "xdg" / "mjccd")


def test_a_users_numba_cache_dir_is_never_replaced(tmp_path, monkeypatch):
    from mjccd import _cache

    pkg = _package(tmp_path)
    _read_only(monkeypatch, pkg)
    env = {"NUMBA_CACHE_DIR": str(tmp_path / "mine"), "XDG_CACHE_HOME": str(tmp_path / "xdg")}
    assert _cache.cache_dir(env, str(pkg)) is None
    assert _cache.configure(env, str(pkg)) is None
    assert env["NUMBA_CACHE_DIR"] == str(tmp_path / "mine") and not (tmp_path / "xdg").exists()


def test_an_unusable_user_cache_folder_leaves_numba_its_own_fallback(tmp_path, monkeypatch):
    from mjccd import _cache

    pkg = _package(tmp_path)
    _read_only(monkeypatch, pkg)
    (tmp_path / "xdg").write_text("a file where the cache folder would go")
    env = {"XDG_CACHE_HOME": str(tmp_path / "xdg")}
    assert _cache.configure(env, str(pkg)) is None and "NUMBA_CACHE_DIR" not in env


@pytest.mark.skipif(not hasattr(os, "geteuid") or os.geteuid() == 0, reason="root writes into read-only folders")
def test_importing_a_read_only_copy_sets_the_user_cache_folder(tmp_path):
    copy = tmp_path / "site"
    shutil.copytree(ROOT / "mjccd", copy / "mjccd", ignore=shutil.ignore_patterns("__pycache__", "*.nb[ic]"))
    for folder in sorted((p for p in copy.rglob("*") if p.is_dir()), reverse=True) + [copy]:
        folder.chmod(0o555)
    try:
        env = {**_clean_env(), "PYTHONPATH": str(copy), "XDG_CACHE_HOME": str(tmp_path / "xdg")}
        env.pop("NUMBA_CACHE_DIR", None)
        out = _run([sys.executable, "-c", "import mjccd, os; print(os.environ.get('NUMBA_CACHE_DIR'))"],
                   cwd=tmp_path, env=env).strip()
    finally:
        for folder in [copy, *copy.rglob("*")]:
            if folder.is_dir():
                folder.chmod(0o755)
    assert out == str(tmp_path / "xdg" / "mjccd")


class _Event:
    """A numba compile event as the listener sees it."""

    def __init__(self, module):
        self.data = {"dispatcher": SimpleNamespace(py_func=SimpleNamespace(__module__=module))}


class _Clock:
    def __init__(self):
        self.now = 0.0

    def __call__(self):
        return self.now


class _Stream(io.StringIO):
    def __init__(self, tty):
        super().__init__()
        self.tty = tty

    def isatty(self):
        return self.tty


def _compile_run(notice, clock, kernels, seconds, module="mjccd.ccd"):
    """An outermost compile of ``kernels`` nested kernels taking ``seconds``, as numba reports it."""
    step = seconds / (2 * kernels)
    for _ in range(kernels):
        notice.on_start(_Event(module))
        clock.now += step
    for _ in range(kernels):
        clock.now += step
        notice.on_end(_Event(module))


def test_compile_notice_in_a_log_one_line_then_the_totals():
    from mjccd import _cache

    clock, stream = _Clock(), _Stream(tty=False)
    notice = _cache.CompileNotice(stream, clock)
    _compile_run(notice, clock, 40, 75.0)
    lines = stream.getvalue().splitlines()
    assert lines[0] == "mjccd: compiling kernels (first use only)…"
    # a progress line every LOG_EVERY (30 s) of a long compile
    assert lines[1:-1] == ["mjccd: compiling kernels… 34 so far, 31 s", "mjccd: compiling kernels… 40 so far, 61 s"]
    assert lines[-1] == "mjccd: compiled 40 kernels in 75.0 s"


def test_compile_notice_on_a_terminal_counts_on_one_line():
    from mjccd import _cache

    clock, stream = _Clock(), _Stream(tty=True)
    notice = _cache.CompileNotice(stream, clock)
    _compile_run(notice, clock, 10, 5.0)
    _compile_run(notice, clock, 4, 2.0)  # a later run gets a line of its own
    _compile_run(notice, clock, 3, 0.1)  # too short to print
    lines = stream.getvalue().split("\n")
    assert len(lines) == 3 and lines[2] == ""
    assert lines[0].startswith("mjccd: compiling kernels (first use only)… 3 kernels, 0 s")
    assert "\r\033[Kmjccd: compiling kernels (first use only)… 9 kernels, 2 s" in lines[0]
    assert lines[0].endswith("\r\033[Kmjccd: compiling kernels (first use only)… 10 kernels in 5.0 s")
    assert lines[1].startswith("mjccd: compiling kernels… ")
    assert lines[1].endswith("\r\033[Kmjccd: compiled 4 kernels in 2.0 s")


def test_compile_notice_is_silent_for_short_compiles_other_code_and_when_muted():
    from mjccd import _cache

    clock, stream = _Clock(), _Stream(tty=False)
    notice = _cache.CompileNotice(stream, clock)
    _compile_run(notice, clock, 3, 0.1)                       # shorter than NOTICE_DELAY
    _compile_run(notice, clock, 5, 60.0, module="userpkg")  # not an mjccd kernel
    with notice.muted():
        _compile_run(notice, clock, 4, 60.0)
    assert stream.getvalue() == "" and notice.total == 7
    _compile_run(notice, clock, 2, 1.0)  # the first to print: the message, no totals for a short run
    _compile_run(notice, clock, 6, 4.0)  # a later short run in a log: nothing
    assert stream.getvalue().splitlines() == ["mjccd: compiling kernels (first use only)…"]
    _compile_run(notice, clock, 12, 12.0)  # a later long run: from LONG_RUN on, then its totals
    assert stream.getvalue().splitlines()[1:] == ["mjccd: compiling kernels… 11 so far, 5 s",
                                                  "mjccd: compiled 12 kernels in 12.0 s"]


def test_compiling_prints_the_notice_and_loading_from_the_cache_does_not(tmp_path):
    code = ("from mjccd import _cache; _cache.NOTICE_DELAY = _cache.LONG_RUN = 0.0\n"
            "from mjccd.motion import gamma; gamma(3)\n")
    env = {**_clean_env(), "NUMBA_CACHE_DIR": str(tmp_path / "cache")}
    first = subprocess.run([sys.executable, "-c", code], cwd=tmp_path, env=env, capture_output=True, text=True,
                           timeout=300)
    again = subprocess.run([sys.executable, "-c", code], cwd=tmp_path, env=env, capture_output=True, text=True,
                           timeout=300)
    assert first.returncode == again.returncode == 0, first.stderr + again.stderr
    assert first.stderr.splitlines()[0] == "mjccd: compiling kernels (first use only)…", first.stderr
    assert first.stderr.splitlines()[-1].startswith("mjccd: compiled 1 kernel in "), first.stderr
    assert again.stderr == ""


def test_warmup_prints_one_line_per_job(monkeypatch):
    from mjccd import _cache, warmup

    notice = _cache.install_notice()

    def compiles_two():
        notice.total += 2  # what numba's compile events add

    def fails():
        raise RuntimeError("no model")

    monkeypatch.setattr(warmup, "JOBS", {"one": ("a job that compiles", compiles_two),
                                         "two": ("a job that loads", lambda: None),
                                         "three": ("a job that fails", fails)})
    stream = io.StringIO()
    results = warmup.run(stream=stream)
    lines = stream.getvalue().splitlines()
    assert lines[0].startswith("mjccd warmup [1/3] one    a job that compiles … 2 kernels compiled, ")
    assert lines[1].startswith("mjccd warmup [2/3] two    a job that loads … cached, ")
    assert lines[2].startswith("mjccd warmup [3/3] three  a job that fails … cached, ")
    assert lines[2].endswith("; failed: RuntimeError: no model")
    assert lines[3].startswith("mjccd warmup: 2 kernels compiled in ") and len(lines) == 4
    assert [r[0] for r in results.values()] == [2, 0, 0] and results["three"][3] == "RuntimeError: no model"


def test_warmup_command_lists_its_jobs_and_refuses_unknown_ones():
    from mjccd import warmup

    done = subprocess.run([sys.executable, "-m", "mjccd", "warmup", "--list"], capture_output=True, text=True,
                          cwd=ROOT, timeout=120)
    assert done.returncode == 0 and [line.split()[0] for line in done.stdout.splitlines()] == list(warmup.JOBS)
    done = subprocess.run([sys.executable, "-m", "mjccd", "warmup", "nonsense"], capture_output=True, text=True,
                          cwd=ROOT, timeout=120)
    assert done.returncode == 2 and "unknown job 'nonsense'" in done.stderr


# ---------------------------------------------------------------- a fresh install on other Pythons

FRESH_PYTHONS = ("3.10", "3.13")  # the oldest supported, and the newest, where dm-control is left out
FRESH_CHECK = r'''
import mujoco
import numpy as np

import mjccd
from mjccd.mujoco import CCDMonitor, fit_model
from mjccd.scene import Scene

a, b = mjccd.Ellipsoid([0.3, 0.2, 0.1]), mjccd.Ellipsoid([0.2, 0.2, 0.4])   # the README's quick start
contact = mjccd.first_contact(a, mjccd.Rigid([-1, 0, 0], [1, 0, 0, 0], [1, 0, 0], [0.7071, 0, 0.7071, 0]),
                              b, mjccd.Static([0, 0.1, 0], [1, 0, 0, 0]))
print("quick start", contact.certainty, round(contact.time, 6))
scene = Scene([[0.1, 0.1, 0.1]] * 2)
start = np.array([[0, 0, 0, 1, 0, 0, 0], [1, 0, 0, 1, 0, 0, 0.0]])
end = start.copy()
end[0, 0] = 0.95
print("scene", round(scene.step(start, end).first.time, 6))
model = mujoco.MjModel.from_xml_string('<mujoco><worldbody><geom type="plane" size="1 1 .1"/>'
                                       '<body pos="0 0 .5"><freejoint/><geom size=".1"/></body></worldbody></mujoco>')
data = mujoco.MjData(model)
monitor = CCDMonitor(model, data, fit_model(model))
landed = next(c for c in iter(monitor.step, "never") if c is not None)
print("monitor", landed.bodies, landed.certainty)
'''


def _python(version):
    """An interpreter of ``version`` ("3.13"): on the PATH, or one pyenv installed; None when there is none."""
    candidates = [shutil.which(f"python{version}")]
    pyenv = os.environ.get("PYENV_ROOT") or os.path.expanduser("~/.pyenv")
    candidates += sorted(Path(pyenv, "versions").glob(f"{version}.*/bin/python{version}"), reverse=True)
    for candidate in filter(None, candidates):
        done = subprocess.run([str(candidate), "--version"], capture_output=True, text=True)
        if done.returncode == 0 and done.stdout.startswith(f"Python {version}."):
            return candidate
    return None


@pytest.mark.slow
@pytest.mark.parametrize("version", FRESH_PYTHONS)
def test_the_wheel_runs_on_a_fresh_python(installed, version, tmp_path):
    """pip install of the wheel, with its dependencies from the index, into a fresh environment of another
    Python: the quick start, a Scene.step, a monitored MuJoCo step and ``mjccd replay`` of the bundled clip run
    (Python 3.13 once crashed here: scipy, which the kernels' linear algebra needs, was not declared)."""
    import mujoco

    if mujoco.__version__.startswith("4."):
        pytest.skip("run once, next to MuJoCo 3: the fresh environment installs its own MuJoCo either way")
    interpreter = _python(version)
    if interpreter is None:
        pytest.skip(f"no Python {version} on this machine")
    env_dir = tmp_path / "env"
    _run([interpreter, "-m", "venv", env_dir], cwd=tmp_path, env=_clean_env())
    python, env = env_dir / "bin" / "python", dict(_clean_env(), MJCCD_FIT_CACHE="off")
    _run([python, "-m", "pip", "install", "-q", installed.wheel], cwd=tmp_path, env=env, timeout=900)
    checked = _run([python, "-c", FRESH_CHECK], cwd=tmp_path, env=env, timeout=1200)
    assert "quick start certified 0.27" in checked and "scene 0.842105" in checked, checked
    assert checked.splitlines()[-1].startswith("monitor (") and checked.endswith("certified\n"), checked
    replayed = _run([env_dir / "bin" / "mjccd", "replay", ROOT / "models" / "boxing.xml",
                     ROOT / "data" / "boxing_traj.npz", "--no-render", "--rows", "3"], cwd=tmp_path, env=env,
                    timeout=1200)
    assert "first contacts: 138;" in replayed, replayed
