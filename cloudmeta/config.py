"""The one place where numba compile flags are set.

``fastmath`` stays off: the engine's promise is 1e-9 relative accuracy, and reassociation would break
the bit-for-bit determinism of renders across thread counts.

``cache`` keeps compiled kernels between processes. numba checks only the timestamp of the file that
holds a cached function, not of the functions it calls in other files, so after an edit to, say,
``bernstein.py`` a cached caller would run the old code. The cache therefore lives in a folder named
after a hash of every kernel source: any edit starts a fresh cache. The folder is
``$CLOUDMETA_CACHE_DIR`` or ``~/.cache/cloudmeta``; ``NUMBA_CACHE_DIR``, when set, is respected as it is,
and ``CLOUDMETA_NO_CACHE=1`` turns caching off.

The threading layer is numba's own ``workqueue`` unless ``NUMBA_THREADING_LAYER`` says otherwise: the
renderer launches one parallel loop per band of rows, and the OpenMP layer took 7.7 ms per launch on a
2-core machine with another busy process (its sleeping workers wait for the scheduler), workqueue 0.06 ms.
"""
import hashlib
import os
from pathlib import Path

import numba


def _kernel_source_hash():
    h = hashlib.sha1(numba.__version__.encode())
    for path in sorted((Path(__file__).parent / "kernels").glob("*.py")):
        h.update(path.name.encode())
        h.update(path.read_bytes())
    return h.hexdigest()[:16]


def _set_cache_dir():
    if os.environ.get("NUMBA_CACHE_DIR"):
        return True
    base = Path(os.environ.get("CLOUDMETA_CACHE_DIR", Path.home() / ".cache" / "cloudmeta"))
    folder = base / f"numba-{_kernel_source_hash()}"
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except OSError:
        return False  # nowhere to write: compile every time rather than risk a stale cache
    numba.config.CACHE_DIR = str(folder)
    return True


if not os.environ.get("NUMBA_THREADING_LAYER"):
    numba.config.THREADING_LAYER = "workqueue"

CACHE = os.environ.get("CLOUDMETA_NO_CACHE", "") == "" and _set_cache_dir()
FASTMATH = False

#: flags for serial kernels
NJIT = dict(cache=CACHE, fastmath=FASTMATH, nogil=True, error_model="numpy")
#: flags for the small helpers of hot loops: inlined into their callers at numba's IR level, so that no
#: call boundary (and no reference counting of the arrays passed) remains in the loop
NJIT_INLINE = dict(NJIT, inline="always")
#: flags for the few kernels that loop over rays or pixels with prange
NJIT_PARALLEL = dict(NJIT, parallel=True)


def is_compiled(dispatcher):
    """Whether numba's cache already holds the jitted function ``dispatcher`` for this installation (its
    cache folder depends on the source file's path too), so that a run loads it instead of compiling.
    Reads the index path from numba's cache object; False wherever that is not available."""
    if not CACHE:
        return False
    index = getattr(getattr(getattr(dispatcher, "_cache", None), "_cache_file", None), "_index_path", None)
    return index is not None and os.path.exists(index)
