"""Compiled kernels copy arrays by loops, not by slice assignments from arrays.

numba lowers ``a[i:j] = b`` (b an array) with a shape check whose error message is formatted at run time:
string code that LLVM optimises again in every kernel that holds such an assignment or calls one that does.
Removing them (about 60 sites) took the README quick start's first call from a median of 45.4 s to 40.1 s
of CPU (docs/benchmarks.md, "First use").  This lint reads the sources: in a function compiled by numba, a
subscript with a slice is assigned only a number (``a[:] = 0.0``).  A row assignment ``a[i] = b`` cannot be
told from a scalar one without types; ``copy_into`` and friends cover those by convention.
"""
import ast
import pathlib

import pytest

PACKAGE = pathlib.Path(__file__).resolve().parents[1] / "mjccd"
JIT_NAMES = {"_jit", "_inline", "_parallel", "njit", "jit"}


def _compiled(node):
    """True for a function decorated by one of mjccd's numba decorators (``@_jit``, ``@numba.njit(...)``)."""
    for dec in node.decorator_list:
        target = dec.func if isinstance(dec, ast.Call) else dec
        name = target.attr if isinstance(target, ast.Attribute) else getattr(target, "id", "")
        if name in JIT_NAMES:
            return True
    return False


def _number(value):
    if isinstance(value, ast.UnaryOp):
        value = value.operand
    return isinstance(value, ast.Constant) and isinstance(value.value, (int, float))


def _has_slice(index):
    parts = index.elts if isinstance(index, ast.Tuple) else [index]
    return any(isinstance(p, ast.Slice) for p in parts)


def slice_copies(source, filename="<source>"):
    """(line, text) of every slice assignment of a non-number inside a compiled function of ``source``."""
    found = []
    for fn in ast.walk(ast.parse(source, filename)):
        if not isinstance(fn, ast.FunctionDef) or not _compiled(fn):
            continue
        for node in ast.walk(fn):
            if isinstance(node, ast.Assign):
                targets, value = node.targets, node.value
            elif isinstance(node, ast.AugAssign):
                targets, value = [node.target], node.value
            else:
                continue
            for target in targets:
                if isinstance(target, ast.Subscript) and _has_slice(target.slice) and not _number(value):
                    found.append((node.lineno, ast.unparse(node)))
    return found


def test_the_lint_finds_slice_copies_and_passes_number_fills():
    source = (
        "@_jit\n"
        "def f(a, b):\n"
        "    a[:] = 0.0\n"
        "    a[1:3] = -1\n"
        "    a[:] = b\n"
        "    a[:, 0] += b[0]\n"
        "    return a\n"
        "def g(a, b):\n"
        "    a[:] = b\n")
    assert [line for line, _ in slice_copies(source)] == [5, 6]


@pytest.mark.parametrize("path", sorted(PACKAGE.rglob("*.py")), ids=lambda p: str(p.relative_to(PACKAGE)))
def test_compiled_kernels_copy_arrays_by_loops(path):
    assert slice_copies(path.read_text(), str(path)) == []
