"""The one place where numba compile flags are set.

``fastmath`` stays off: the engine's promise is 1e-9 relative accuracy, and reassociation would break
the bit-for-bit determinism of renders across thread counts. ``cache`` writes compiled kernels next to
the sources (``__pycache__``) so that a second process starts without compiling.
"""
import os

CACHE = os.environ.get("CLOUDMETA_NO_CACHE", "") == ""
FASTMATH = False

#: flags for serial kernels
NJIT = dict(cache=CACHE, fastmath=FASTMATH, nogil=True, error_model="numpy")
#: flags for the few kernels that loop over rays or pixels with prange
NJIT_PARALLEL = dict(NJIT, parallel=True)
