"""What passing a Scene's workspace to a compiled kernel costs, three ways: is ``WorkspaceRef`` worth its use of
numba's internals?

``mjccd.scene.WorkspaceRef`` hands the ~35 arrays of a :class:`~mjccd.scene.Workspace` to compiled code as one
numba ``StructRef``.  It subclasses ``array.array`` and sets numba's private ``_type``, ``_meminfo`` and
``_numba_type_`` so that numba's dispatcher types it in C from a cached fingerprint.  The public alternative, a
``structref.StructRefProxy``, is typed by a call back into Python on every call; the plain alternative, the
``Workspace`` named tuple itself, is unboxed array by array.  Each way calls the same trivial kernel (it reads one
number of one array), so the figure is the cost of the call and the argument alone: the median over
``--repeats`` runs of ``--calls`` calls, ns per call.

Run: ``python benchmarks/workspace_ref.py`` (docs/benchmarks.md, "Passing the workspace").
"""
import argparse
import statistics
import time

import numba
import numpy as np
from numba.core import types
from numba.experimental import structref

from mjccd.scene import field, new_workspace, workspace_ref


@structref.register
class _PublicRefType(types.StructRef):
    def preprocess_fields(self, members):
        return tuple((name, types.unliteral(t)) for name, t in members)


class PublicRef(structref.StructRefProxy):
    """The public way: a StructRefProxy, typed through Python on each call."""


structref.define_proxy(PublicRef, _PublicRefType, ["arrays"])


@numba.njit(nogil=True)
def _by_ref(ref):
    return field(ref, "radii")[0, 0]


@numba.njit(nogil=True)
def _by_public(ref):
    return ref.arrays.radii[0, 0]


@numba.njit(nogil=True)
def _by_tuple(arrays):
    return arrays.radii[0, 0]


def per_call(fn, arg, calls, repeats):
    """Median over ``repeats`` of the mean ns per call of ``fn(arg)`` over ``calls`` calls."""
    fn(arg)
    runs = []
    for _ in range(repeats):
        start = time.perf_counter_ns()
        for _ in range(calls):
            fn(arg)
        runs.append((time.perf_counter_ns() - start) / calls)
    return statistics.median(runs)


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--calls", type=int, default=200_000)
    parser.add_argument("--repeats", type=int, default=7)
    args = parser.parse_args(argv)
    radii = np.ones((21, 3))
    pairs = np.array([(i, j) for i in range(21) for j in range(i + 1, 21)], dtype=np.int64)
    arrays = new_workspace(radii, pairs, False, True)
    ways = [("WorkspaceRef (numba internals)", _by_ref, workspace_ref(arrays)),
            ("StructRefProxy (public API)", _by_public, PublicRef(arrays)),
            ("the Workspace named tuple", _by_tuple, arrays)]
    # interleaved: each repeat runs every way once, so a machine that slows down slows them alike
    results = {name: [] for name, _, _ in ways}
    for _ in range(args.repeats):
        for name, fn, arg in ways:
            results[name].append(per_call(fn, arg, args.calls, 1))
    base = statistics.median(results[ways[0][0]])
    print(f"numba {numba.__version__}, {len(arrays)} workspace fields, {args.calls} calls x {args.repeats} repeats")
    print("| way | ns per call | against WorkspaceRef |")
    print("| --- | ---: | ---: |")
    for name, _, _ in ways:
        ns = statistics.median(results[name])
        print(f"| {name} | {ns:.0f} | +{ns - base:.0f} ns |")


if __name__ == "__main__":
    main()
