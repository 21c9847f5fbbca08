"""The one place where numba compile flags are set, and where cloudmeta meets numba's process-wide settings.

``fastmath`` stays off: the engine's promise is 1e-9 relative accuracy, and reassociation would break
the bit-for-bit determinism of renders across thread counts.

Cache, scoped to cloudmeta's kernels
------------------------------------
``cache`` keeps compiled kernels between processes. numba checks only the timestamp of the file that
holds a cached function, not of the functions it calls in other files, so after an edit to, say,
``bernstein.py`` a cached caller would run the old code. The cache therefore lives in a folder named
after a hash of every kernel source: any edit starts a fresh cache. The folder is
``$CLOUDMETA_CACHE_DIR`` or ``~/.cache/cloudmeta``; ``NUMBA_CACHE_DIR``, when set, is respected as it is,
and ``CLOUDMETA_NO_CACHE=1`` turns caching off.

The folder reaches numba through a cache locator (``_KernelCacheLocator``) that answers only for the
functions defined in ``cloudmeta/kernels``: ``numba.config.CACHE_DIR`` is left alone, so other numba code
in the process caches where it would without cloudmeta. (numba picks a function's locator when the
function is decorated, so the locator is registered here, before any kernel module is imported.)

Threading layer: process-wide by nature
---------------------------------------
numba runs one thread pool per process, and its layer is chosen once, when the first parallel kernel
(or ``numba.get_num_threads``) starts the pool; nothing can give cloudmeta a layer of its own. cloudmeta
prefers numba's own ``workqueue``: the public ray API launches one parallel loop per call, and the
OpenMP layer took 7.7 ms per launch on a 2-core machine with another busy process (its sleeping workers
wait for the scheduler), workqueue 0.06 ms. The preference is applied only where it changes nobody's
choice: not when ``NUMBA_THREADING_LAYER`` is set, not when the program set
``numba.config.THREADING_LAYER`` itself before importing cloudmeta, and not when the pool is already
running. (The renderer itself runs bands of rows on Python threads and does not use the pool's layer.)
"""
import hashlib
import os
from pathlib import Path

import numba
from numba.core import caching

KERNELS = Path(__file__).resolve().parent / "kernels"


def _kernel_source_hash():
    h = hashlib.sha1(numba.__version__.encode())
    for path in sorted(KERNELS.glob("*.py")):
        h.update(path.name.encode())
        h.update(path.read_bytes())
    return h.hexdigest()[:16]


def _cache_folder():
    """The folder of cloudmeta's compiled kernels, or None where numba's NUMBA_CACHE_DIR rules; False
    where it cannot be written (then nothing is cached rather than risk a stale cache)."""
    if os.environ.get("NUMBA_CACHE_DIR"):
        return None
    base = Path(os.environ.get("CLOUDMETA_CACHE_DIR", Path.home() / ".cache" / "cloudmeta"))
    folder = base / f"numba-{_kernel_source_hash()}"
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except OSError:
        return False
    return folder


class _KernelCacheLocator(caching.UserProvidedCacheLocator):
    """numba's locator for a user-given cache folder, answering only for cloudmeta's kernels."""
    folder = None

    def __init__(self, py_func, py_file):
        self._py_file = py_file
        self._lineno = py_func.__code__.co_firstlineno
        self._cache_path = os.path.join(str(self.folder), self.get_suitable_cache_subpath(py_file))

    @classmethod
    def from_function(cls, py_func, py_file):
        if cls.folder is None or Path(py_file).resolve().parent != KERNELS:
            return None
        return super(caching.UserProvidedCacheLocator, cls).from_function(py_func, py_file)


def _register_cache():
    if os.environ.get("CLOUDMETA_NO_CACHE", ""):
        return False
    folder = _cache_folder()
    if folder is None:
        return True  # NUMBA_CACHE_DIR: numba's own locator
    if folder is False:
        return False
    _KernelCacheLocator.folder = folder
    if _KernelCacheLocator not in caching.CacheImpl._locator_classes:
        caching.CacheImpl._locator_classes.insert(0, _KernelCacheLocator)
    return True


def _prefer_workqueue():
    from numba.np.ufunc import parallel
    if os.environ.get("NUMBA_THREADING_LAYER") or numba.config.THREADING_LAYER != "default":
        return
    if getattr(parallel, "_is_initialized", False):
        return
    numba.config.THREADING_LAYER = "workqueue"


_prefer_workqueue()
CACHE = _register_cache()
FASTMATH = False

#: flags for serial kernels
NJIT = dict(cache=CACHE, fastmath=FASTMATH, nogil=True, error_model="numpy")
#: flags for the small helpers of hot loops: inlined into their callers at numba's IR level, so that no
#: call boundary (and no reference counting of the arrays passed) remains in the loop
NJIT_INLINE = dict(NJIT, inline="always")
#: flags for the few kernels that loop over rays or points with prange (the public ray API, the grid)
NJIT_PARALLEL = dict(NJIT, parallel=True)
#: options of the @overload helpers that pick an implementation by an argument's type (kernels.features);
#: inlined into their callers, so they compile with them and are cached with them
OVERLOAD = dict(jit_options=dict(fastmath=FASTMATH, error_model="numpy"), inline="always")


def is_compiled(dispatcher):
    """Whether numba's cache already holds the jitted function ``dispatcher`` for this installation (its
    cache folder depends on the source file's path too), so that a run loads it instead of compiling.
    Reads the index path from numba's cache object; False wherever that is not available."""
    if not CACHE:
        return False
    index = getattr(getattr(getattr(dispatcher, "_cache", None), "_cache_file", None), "_index_path", None)
    return index is not None and os.path.exists(index)
