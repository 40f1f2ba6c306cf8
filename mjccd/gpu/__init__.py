"""Optional GPU path: filters and exact first contacts of rigidly moving ellipsoids for many worlds at once.

Kernels in float64 on an NVIDIA GPU through numba-cuda (``pip install mjccd[gpu]``) on (W, N)
ellipsoid poses, one thread per (world, pair); the answers stay on the device.  numba-cuda rather
than NVIDIA Warp: the rest of mjccd is numba, so each device function is a line-by-line port of the
CPU kernel it mirrors and can be read against it; arrays of Warp, CuPy, PyTorch and numba all expose
``__cuda_array_interface__``, which numba takes without a copy; and numba-cuda's CUDA simulator
(``NUMBA_ENABLE_CUDASIM=1``) runs the same kernels on the CPU, which is how the tests check them on
machines without a GPU.

Importing this package raises :class:`GpuUnavailableError` (an ImportError) when numba-cuda is
missing, or when there is neither a usable CUDA device nor the simulator.  Nothing else in mjccd
imports it.
"""
from mjccd.gpu._available import GpuUnavailableError, require_cuda

require_cuda()

from mjccd.gpu.kernels import BAD_INPUT, CONTACT, NO_CONTACT, POSSIBLE_CONTACT, STATUS_NAMES  # noqa: E402
from mjccd.gpu.scene import GpuContacts, GpuPairs, GpuScene, poses_from_bodies  # noqa: E402

__all__ = ["BAD_INPUT", "CONTACT", "GpuContacts", "GpuPairs", "GpuScene", "GpuUnavailableError", "NO_CONTACT",
           "POSSIBLE_CONTACT", "STATUS_NAMES", "poses_from_bodies"]
