"""docs/layout.md names every module of the package, and names no module that is gone.

A module is every ``.py`` file under ``mjccd/`` (``__pycache__`` left out), by its dotted name relative to the
package: ``mjccd/geoms/batch.py`` is ``geoms.batch``, ``mjccd/collection/__init__.py`` is ``collection``,
``mjccd/__main__.py`` is ``__main__``; ``mjccd/__init__.py``, the package itself, is ``mjccd``.  Each must appear
in docs/layout.md as a code span of its own (``geoms.batch`` in backquotes): a package's name does not stand for
its modules, and a row may name several (```filters`, `scene`, `chain_bounds```).
"""
import pathlib
import re

ROOT = pathlib.Path(__file__).resolve().parents[1]
PACKAGE = ROOT / "mjccd"
LAYOUT = ROOT / "docs" / "layout.md"
DOTTED = re.compile(r"[A-Za-z_]\w*(?:\.[A-Za-z_]\w*)*")


def _modules():
    """Dotted names of every module of the package, relative to it (``mjccd`` for the package itself)."""
    names = set()
    for path in PACKAGE.rglob("*.py"):
        parts = path.relative_to(PACKAGE).with_suffix("").parts
        if "__pycache__" in parts:
            continue
        if parts[-1] == "__init__":
            parts = parts[:-1]
        names.add(".".join(parts) or "mjccd")
    return names


def _code_spans(text):
    """Every single-backquoted code span of a Markdown text."""
    return set(re.findall(r"(?<!`)`([^`\n]+)`(?!`)", text))


def _first_cells(text):
    """The first cell of every table row (header and separator rows included)."""
    return [line.split("|")[1] for line in text.splitlines() if line.startswith("|")]


def test_the_package_has_modules():
    modules = _modules()
    assert {"mjccd", "ccd", "mujoco", "mujoco.adapter", "geoms.batch"} <= modules, sorted(modules)


def test_layout_names_every_module():
    named = _code_spans(LAYOUT.read_text(encoding="utf-8"))
    missing = sorted(_modules() - named)
    assert not missing, (f"docs/layout.md does not name {len(missing)} module(s) of mjccd, each as a code span of "
                         f"its own dotted name: " + ", ".join(missing))


def test_layout_names_no_missing_module():
    """The first column of the tables names modules that exist (a row left behind by a removed module fails)."""
    modules = _modules()
    stale = sorted({name for cell in _first_cells(LAYOUT.read_text(encoding="utf-8"))
                    for name in _code_spans(cell) if DOTTED.fullmatch(name) and name not in modules})
    assert not stale, "docs/layout.md's tables name modules that mjccd does not have: " + ", ".join(stale)
