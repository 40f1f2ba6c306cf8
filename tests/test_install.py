"""A plain (non-editable) install works: every bench suite runs from the wheel, outside the repository.

The sdist is built from a copy of the working tree's files (as a fresh clone would have
them: no build leftovers such as an old ``mjccd.egg-info``, whose file list setuptools
would reuse) and the wheel from the sdist, so both carry what they must (package data,
LICENSE, NOTICE).  The wheel goes with ``pip --no-deps`` into a fresh virtual environment
that sees this environment's packages through a ``.pth`` file (no second download of
numpy, numba or mujoco); each ``mjccd bench <suite> --quick`` then runs from an empty
folder outside the repository.  The compiled kernels of this checkout are copied to the
installed copy of the same sources, so they load instead of compiling for minutes (a fresh
install compiles them on first use: docs/benchmarks.md, "First use").

The first-use tests at the end check where the compiled kernels go and that they are never
stale (mjccd._cache: keyed on their sources, a callee edited in another file compiles afresh;
a corrupt or unwritable cache compiles with one warning), the compile notice and
``mjccd warmup``.
"""
import io
import os
import shutil
import subprocess
import sys
import sysconfig
import tarfile
import tempfile
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
    """Copy this checkout's compiled kernels to the installed copy when its kernel sources are the same (the same
    key, mjccd._cache): they then load instead of compiling; other sources compile afresh."""
    from mjccd import _cache

    key = _cache.kernel_key()
    if _cache.kernel_key(str(site / "mjccd")) != key:
        return
    ours = ROOT / "mjccd" / "__pycache__" / (_cache.KEY_PREFIX + key)
    if ours.is_dir():
        shutil.copytree(ours, site / "mjccd" / "__pycache__" / ours.name, dirs_exist_ok=True)


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


def _stable_roots(monkeypatch, writable):
    """mjccd._cache's folder choice with ``writable(folder)`` saying which folders can be written."""
    from mjccd import _cache

    monkeypatch.setattr(_cache, "_writable", writable)
    return _cache


def test_kernels_go_to_the_package_then_the_user_then_the_temporary_folder(tmp_path, monkeypatch):
    pkg = str(tmp_path / "site" / "mjccd")
    env = {"XDG_CACHE_HOME": str(tmp_path / "xdg")}
    everywhere = _stable_roots(monkeypatch, lambda folder: True)
    assert everywhere.kernel_cache_root("abc", env, pkg) == os.path.join(pkg, "__pycache__", "kernels-abc")
    read_only = _stable_roots(monkeypatch, lambda folder: not folder.startswith(pkg))
    assert read_only.kernel_cache_root("abc", env, pkg) == str(tmp_path / "xdg" / "mjccd" / "kernels-abc")
    monkeypatch.setenv("HOME", str(tmp_path / "home"))
    assert read_only.kernel_cache_root("abc", {}, pkg) == str(tmp_path / "home" / ".cache" / "mjccd" / "kernels-abc")
    no_home = _stable_roots(monkeypatch, lambda folder: folder.startswith(tempfile.gettempdir()) and
                            not folder.startswith(str(tmp_path)))
    assert no_home.kernel_cache_root("abc", env, pkg).startswith(tempfile.gettempdir())
    nowhere = _stable_roots(monkeypatch, lambda folder: False)
    assert nowhere.kernel_cache_root("abc", env, pkg) is None


def test_a_users_numba_cache_dir_holds_the_kernels_and_is_never_changed(tmp_path, monkeypatch):
    cache = _stable_roots(monkeypatch, lambda folder: True)
    env = {"NUMBA_CACHE_DIR": str(tmp_path / "mine")}
    root = cache.kernel_cache_root("abc", env, str(tmp_path / "mjccd"))
    assert root == str(tmp_path / "mine" / "mjccd" / "kernels-abc") and env == {"NUMBA_CACHE_DIR": str(tmp_path / "mine")}


def test_importing_mjccd_sets_no_environment_and_hooks_only_its_own_files():
    code = ("import os; before = dict(os.environ); import mjccd, numba\n"
            "from numba.core import caching\n"
            "from mjccd.motion import gamma; gamma(3)\n"
            "first = caching.CacheImpl._locator_classes[0]\n"
            "print(dict(os.environ) == before, getattr(first, 'mjccd_kernels', False),"
            " first.from_function(len, os.__file__) is None, numba.__version__)")
    out = _run([sys.executable, "-c", code], cwd=ROOT, env=_clean_env()).split()
    assert out[:3] == ["True", "True", "True"]
    major, minor = (int(x) for x in out[3].split(".")[:2])
    assert (major, minor) == (0, 68), ("numba changed: check the numba internals mjccd relies on (mjccd._cache's "
                                       "hooks, mjccd.scene.WorkspaceRef), then move pyproject's cap")


def test_the_key_covers_every_file_whose_values_kernels_compile_in():
    """Every compiled function of mjccd, and every module or imported value it reads, comes from a keyed file
    (a constant read from an unkeyed module would be compiled in and go stale when that module changes)."""
    import ast
    import importlib
    import types

    from mjccd import _cache

    keyed = set(_cache.kernel_sources())
    package = Path(_cache.PACKAGE_DIR)

    def names(code):
        found = set(code.co_names)
        for const in code.co_consts:
            if isinstance(const, types.CodeType):
                found |= names(const)
        return found

    def keyed_file(module):
        path = getattr(module, "__file__", None)
        return path is None or not Path(path).is_relative_to(package) or \
            str(Path(path).relative_to(package)) in keyed

    problems = []
    for source in sorted(package.rglob("*.py")):
        rel = str(source.relative_to(package))
        if rel.startswith("gpu" + os.sep) or "__pycache__" in rel or rel == "__main__.py":
            continue  # the GPU modules need a CUDA device or the simulator (tests/test_gpu.py); __main__ runs
        name = "mjccd." + rel[:-3].replace(os.sep, ".").removesuffix(".__init__")
        module = importlib.import_module(name.removesuffix(".__init__"))
        imported = {}
        for node in ast.parse(source.read_text()).body:
            if isinstance(node, ast.ImportFrom) and (node.module or "").startswith("mjccd"):
                for alias in node.names:
                    imported[alias.asname or alias.name] = node.module
        for value in list(vars(module).values()):
            func = getattr(value, "py_func", None)
            if func is None or func.__module__ != module.__name__:
                continue
            if rel not in keyed:
                problems.append(f"{rel}: compiled {func.__name__} in a file the key leaves out")
            for read in names(func.__code__):
                got = vars(module).get(read)
                if isinstance(got, types.ModuleType):
                    if not keyed_file(got):
                        problems.append(f"{rel}: {func.__name__} reads module {got.__name__}")
                elif read in imported and not keyed_file(importlib.import_module(imported[read])) \
                        and not isinstance(got, type) and getattr(got, "py_func", None) is None:
                    problems.append(f"{rel}: {func.__name__} reads {read} of {imported[read]}")
    assert not problems, "\n".join(problems)


def _probe_copy(tmp_path):
    """A copy of the package with two probe kernels: ``motion._probe`` calls ``sorting._probe_value``, in
    another file."""
    site = tmp_path / "site"
    shutil.copytree(ROOT / "mjccd", site / "mjccd", ignore=shutil.ignore_patterns("__pycache__"))
    with open(site / "mjccd" / "sorting.py", "a") as fh:
        fh.write("\n\n@numba.njit(cache=True)\ndef _probe_value():\n    return 1.0\n")
    with open(site / "mjccd" / "motion.py", "a") as fh:
        fh.write("\n\nfrom mjccd import sorting as _sorting\n\n\n"
                 "@numba.njit(cache=True)\ndef _probe():\n    return _sorting._probe_value() + 0.5\n")
    return site


def _probe(site, extra=""):
    env = {**_clean_env(), "PYTHONPATH": str(site)}
    env.pop("NUMBA_CACHE_DIR", None)
    code = extra + "import mjccd.motion as m; print(m._probe())"
    done = subprocess.run([sys.executable, "-W", "always::RuntimeWarning", "-c", code], cwd=site, env=env,
                          capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr
    return float(done.stdout.split()[-1]), done.stderr


def test_a_callee_edited_in_another_file_is_compiled_afresh(tmp_path):
    site = _probe_copy(tmp_path)
    assert _probe(site)[0] == 1.5
    caches = list((site / "mjccd" / "__pycache__").glob("kernels-*"))
    assert len(caches) == 1 and list(caches[0].rglob("motion._probe-*.nbi"))
    assert _probe(site)[0] == 1.5  # loaded from the cache
    sorting = site / "mjccd" / "sorting.py"
    sorting.write_text(sorting.read_text().replace("    return 1.0\n", "    return 2.0\n"))
    assert _probe(site)[0] == 2.5  # numba's own cache would load motion._probe's old code: 1.5
    assert [p.name for p in (site / "mjccd" / "__pycache__").glob("kernels-*")] != [caches[0].name]
    assert len(list((site / "mjccd" / "__pycache__").glob("kernels-*"))) == 1  # the old key's folder is gone


def test_an_upgrade_changes_the_key_and_an_unkeyed_edit_does_not(tmp_path):
    from mjccd import _cache

    copy = tmp_path / "mjccd"
    shutil.copytree(ROOT / "mjccd", copy, ignore=shutil.ignore_patterns("__pycache__"))
    key = _cache.kernel_key(str(copy))
    assert key == _cache.kernel_key() and "replay.py" not in _cache.kernel_sources(str(copy))
    (copy / "replay.py").write_text((copy / "replay.py").read_text() + "\n# an edit of replay, no kernel\n")
    assert _cache.kernel_key(str(copy)) == key
    init = copy / "__init__.py"
    init.write_text(init.read_text().replace('__version__ = "', '__version__ = "9'))  # the next wheel
    assert _cache.kernel_key(str(copy)) != key


def test_a_corrupt_or_unwritable_cache_compiles_with_one_warning(tmp_path):
    site = _probe_copy(tmp_path)
    assert _probe(site)[0] == 1.5
    for index in (site / "mjccd" / "__pycache__").rglob("*.nbi"):
        index.write_bytes(b"not a pickle")
    value, err = _probe(site)
    assert value == 1.5 and err.count("KernelCacheWarning") == 1 and "compiling the kernels instead" in err
    assert _probe(site) == (1.5, "")  # rebuilt: loads again, no warning
    full = ("import errno, numba.core.caching as c\n"
            "def _full(*args): raise OSError(errno.ENOSPC, 'No space left on device')\n"
            "c.IndexDataCacheFile.save = _full\n")
    shutil.rmtree(next((site / "mjccd" / "__pycache__").glob("kernels-*")))
    value, err = _probe(site, full)
    assert value == 1.5 and err.count("KernelCacheWarning") == 1 and "No space left" in err


@pytest.mark.skipif(not hasattr(os, "geteuid") or os.geteuid() == 0, reason="root writes into read-only folders")
def test_a_read_only_install_with_no_writable_home_imports_and_runs(tmp_path):
    copy = tmp_path / "site"
    shutil.copytree(ROOT / "mjccd", copy / "mjccd", ignore=shutil.ignore_patterns("__pycache__"))
    for folder in sorted((p for p in copy.rglob("*") if p.is_dir()), reverse=True) + [copy]:
        folder.chmod(0o555)
    try:
        env = {**_clean_env(), "PYTHONPATH": str(copy), "HOME": str(copy), "XDG_CACHE_HOME": str(copy / "x")}
        env.pop("NUMBA_CACHE_DIR", None)
        out = _run([sys.executable, "-c", "import mjccd; from mjccd.motion import gamma; print(gamma(3) > 0)"],
                   cwd=tmp_path, env=env).strip()
    finally:
        for folder in [copy, *copy.rglob("*")]:
            if folder.is_dir():
                folder.chmod(0o755)
    assert out.splitlines()[-1] == "True"


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
