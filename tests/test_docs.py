"""Every Python snippet of README.md and docs/ runs: a file's ```python blocks in order in one namespace (a later
block may use an earlier one's names), in a scratch folder that sees the repository's models/ and data/.

A block may be left out only for what this suite cannot have, said right above its fence as
``<!-- not run: REASON -->`` with REASON one of :data:`ALLOWED`; a block that only shows a signature is fenced
as ``text``, not ``python``.
"""
import pathlib
import re
import subprocess
import sys
import warnings

import matplotlib
import pytest

ROOT = pathlib.Path(__file__).resolve().parents[1]
DOCS = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]
BLOCK = re.compile(r"(?:<!-- not run: (?P<reason>[^>]*?) -->\n)?```python\n(?P<code>.*?)```", re.S)
ALLOWED = ("needs an NVIDIA GPU",)


def _blocks(path):
    return [(m.group("reason"), m.group("code"), path.read_text()[:m.start()].count("\n") + 1)
            for m in BLOCK.finditer(path.read_text())]


@pytest.mark.dm_control  # some snippets wrap dm-control environments
@pytest.mark.parametrize("path", [p for p in DOCS if any(r is None for r, _, _ in _blocks(p))],
                         ids=lambda p: p.name)
def test_every_snippet_runs(path, tmp_path, monkeypatch, capsys):
    for name in ("models", "data"):
        (tmp_path / name).symlink_to(ROOT / name)
    monkeypatch.chdir(tmp_path)
    matplotlib.use("Agg")
    namespace = {"__name__": "__snippet__"}
    for reason, code, line in _blocks(path):
        if reason is None:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                exec(compile(code, f"{path.name}:{line}", "exec"), namespace)


def test_no_python_fence_hides_from_the_runner():
    """A ```python fence the pattern misses (say, with trailing spaces) would silently go unrun, and a block is
    left out only for what CI cannot have."""
    for path in DOCS:
        text = path.read_text()
        for reason, _, line in _blocks(path):
            assert reason is None or reason in ALLOWED, f"{path.name}:{line}: not run for {reason!r}"
        assert text.count("```python") == len(_blocks(path)), path.name
        assert "```py\n" not in text and "```Python" not in text, path.name


def test_the_site_and_its_api_reference_build_strictly(tmp_path):
    """``make docs``: mkdocs with the reference from the docstrings (mkdocstrings); any warning (a page missing
    from the nav, a broken reference, an object that does not import) fails the build."""
    done = subprocess.run([sys.executable, "-m", "mkdocs", "build", "--strict", "--site-dir", str(tmp_path / "site")],
                          cwd=ROOT, capture_output=True, text=True, timeout=600)
    assert done.returncode == 0, done.stderr[-3000:]
    reference = (tmp_path / "site" / "api" / "mujoco" / "index.html").read_text()
    assert "CCDMonitor" in reference and "fit_model" in reference
    index = (tmp_path / "site" / "index.html").read_text()
    assert 'href="mujoco/"' in index  # the first screen links the page on wrapped environments
