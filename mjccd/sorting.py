"""A small compiled sort shared by the scene (pairs by sphere-entry time) and the patch solver (lines by slope)."""
import numba


@numba.njit(cache=True, nogil=True, no_cfunc_wrapper=True, forceinline=False)
def sort_by_key(order, m, key):
    """Stable insertion sort of the indices ``order[:m]`` by ``key[order[.]]``, ascending (m is small)."""
    for a in range(1, m):
        k = order[a]
        e = key[k]
        b = a - 1
        while b >= 0 and key[order[b]] > e:
            order[b + 1] = order[b]
            b -= 1
        order[b + 1] = k
