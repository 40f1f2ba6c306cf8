"""Whether the GPU path can run here: numba-cuda installed, and a CUDA device or the CUDA simulator."""
import importlib

import numpy as np

from mjccd.errors import MjccdError

HOW = ("install it with `pip install mjccd[gpu]` (numba-cuda), run on a machine with an NVIDIA GPU and its "
       "CUDA driver, or set NUMBA_ENABLE_CUDASIM=1 before importing numba to run the kernels in numba-cuda's "
       "CUDA simulator on the CPU (slow; for tests)")


class GpuUnavailableError(MjccdError, ImportError):
    """mjccd.gpu cannot run here: numba-cuda is missing, or there is no CUDA device and no simulator."""


def require_cuda():
    """Raise :class:`GpuUnavailableError` naming what is missing, unless numba-cuda can run kernels here."""
    try:
        importlib.import_module("numba_cuda")
    except ImportError as error:
        raise GpuUnavailableError(f"mjccd.gpu needs the numba-cuda package, which is not installed ({error}); "
                                  + HOW) from None
    if not hasattr(np, "row_stack"):
        # numba-cuda up to 0.30 registers an overload of np.row_stack (an alias of np.vstack that numpy 2.5
        # removed) when it loads its numpy support, and fails without it: the alias puts it back
        np.row_stack = np.vstack
    from numba import cuda

    if cuda.is_available():  # a device, or the simulator (which always is)
        return
    raise GpuUnavailableError("mjccd.gpu found no usable CUDA device (no NVIDIA GPU, no CUDA driver, or the "
                              "driver did not initialise; numba.cuda.detect() tells more); " + HOW)
