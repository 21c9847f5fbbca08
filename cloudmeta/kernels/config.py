"""The one place where numba compile flags are set, and where cloudmeta meets numba's process-wide settings.

``fastmath`` stays off: the engine's promise is 1e-9 relative accuracy, and reassociation would break
the bit-for-bit determinism of renders across thread counts.

Cache, scoped to cloudmeta's kernels
------------------------------------
``cache`` keeps compiled kernels between processes. numba checks only the timestamp of the file that
holds a cached function, not of the functions it calls in other files, so after an edit to, say,
``bernstein.py`` a cached caller would run the old code. The cache therefore lives in a folder named
after a hash of every kernel source: any edit starts a fresh cache. The folder is
``$CLOUDMETA_CACHE_DIR`` or ``~/.cache/cloudmeta``; ``NUMBA_CACHE_DIR``, when set, is respected as it is
(numba's layout in it), and ``CLOUDMETA_NO_CACHE=1`` turns caching off.

The kernels' dispatchers get a cache of their own (``_KernelCache``, installed by wrapping numba's
``Dispatcher.enable_caching`` for the functions defined in ``cloudmeta/kernels`` alone: other numba code in
the process caches where it would without cloudmeta, and ``numba.config.CACHE_DIR`` is left alone; it is
installed here, before any kernel module is imported, since numba makes a function's cache when the
function is decorated). Its one locator (``_KernelCacheLocator``) always answers for a kernel, so that a
kernel is never cached by numba's fallbacks (``__pycache__`` beside the sources, ``~/.cache/numba``),
folders without the source hash. It differs from numba's cache in two faults only:

- a cached entry that cannot be read (truncated, garbage, an index numba cannot unpickle, data it cannot
  rebuild a kernel from) is removed and the kernel compiled again (and saved anew), with one line on
  stderr for the process, instead of numba's traceback;
- a folder that cannot be written (read-only, a file where the folder should be, a full disk) is still
  read, but nothing is saved there: the kernels not found in it compile in memory, with one line on stderr
  for the process, never into another folder.

Reference counts: inlinable in cloudmeta's kernels alone
---------------------------------------------------------
numba counts references to every array a kernel binds, with calls to its runtime's ``NRT_incref`` and
``NRT_decref``, which it marks ``noinline`` so that its reference-count pruning can find them. The hot
loops read borrowed records (kernels.borrow: arrays whose MemInfo is null), so each of those calls only
tests a null pointer; but a call still clobbers the caller's registers, and an inlined helper that takes
the scene's records binds a hundred arrays or more. On the multiple-scattering paths a path that did
nothing at all cost 1.3 us, and a vertex 2-4 us where its work alone took 1.2 us in a harness
(docs/performance.md, "Choices in the kernels that buy speed"). cloudmeta therefore links, into each of its own kernels' modules and ahead
of numba's runtime, a copy of the two functions without ``noinline`` (``_inlinable_refcounts``), so that
LLVM inlines them and the null test becomes one compare and branch; NRT_decref keeps the rest of its body
(the atomic decrement and the destructor) in a function of its own, called only for an owned array, so
that each inlined copy stays small (``_split_slow_path``). Single scattering 1.3x and multiple scattering
1.4-1.6x faster, images bit-identical. Owned arrays are counted as before, with the same atomic
operations; only numba's pruning of counts, which runs after inlining, then finds fewer pairs to remove.

numba's runtime itself is left as it is: every other numba function in the process compiles and runs as it
would without cloudmeta. A kernel is a function of a file in this folder; the copy is linked into the
library numba compiles for the kernel (found by ``numba:compile`` events and the library's name; not into
the libraries of numba's helpers, which later functions share), by wrapping the CPU target's
``post_lowering`` (where numba links its runtime). It relies on four names of
numba's internals (``CPUContext.post_lowering``, ``nrtdynmod._define_atomic_inc_dec``, ``_define_nrt_incref``,
``_define_nrt_decref``): pyproject.toml pins numba to the versions tested, and where one is missing the
counts stay calls (``INLINE_REFCOUNTS`` False; tests/kernels/test_config.py fails). ``CLOUDMETA_NRT_INLINE=0``
leaves the kernels' counts as calls too (and caches the kernels apart).

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
import errno
import hashlib
import os
import sys
import tempfile
import threading
from pathlib import Path

import numba
from numba.core import caching, event
from numba.core import dispatcher as _dispatcher

KERNELS = Path(__file__).resolve().parent


def _kernel_source_hash():
    h = hashlib.sha1(numba.__version__.encode())
    if INLINE_REFCOUNTS:
        h.update(b"inline reference counts")
    for path in sorted(KERNELS.glob("*.py")):
        h.update(path.name.encode())
        h.update(path.read_bytes())
    return h.hexdigest()[:16]


def _cache_folder():
    """The folder of cloudmeta's compiled kernels: ``$NUMBA_CACHE_DIR`` where set, else
    ``$CLOUDMETA_CACHE_DIR`` or ``~/.cache/cloudmeta``, in a subfolder named after the kernel sources."""
    if os.environ.get("NUMBA_CACHE_DIR"):
        return Path(os.environ["NUMBA_CACHE_DIR"])
    base = Path(os.environ.get("CLOUDMETA_CACHE_DIR", Path.home() / ".cache" / "cloudmeta"))
    return base / f"numba-{_kernel_source_hash()}"


def _why(exc):
    """An OSError of making or writing the cache folder, in a few words."""
    if exc.errno == errno.EEXIST:
        return "a file stands where the folder should be"
    if exc.errno == errno.ENOTDIR:
        return "a file stands in its path"
    return (exc.strerror or str(exc) or type(exc).__name__).lower()


def _writable(folder):
    """None where compiled kernels can be saved in ``folder`` (made here if missing), else why not."""
    try:
        folder.mkdir(parents=True, exist_ok=True)
        tempfile.TemporaryFile(dir=folder).close()
    except OSError as exc:
        return _why(exc)
    return None


#: what has been said on stderr in this process (each fault once)
_SAID = set()
#: why compiled kernels are not saved (``cache_problem``), None while they are
_PROBLEM = None


def _say_once(kind, line):
    if kind not in _SAID:
        _SAID.add(kind)
        print(line, file=sys.stderr, flush=True)


def cache_problem():
    """None where the kernels compiled in this process are saved for later ones, else why not, in words:
    caching turned off, or a cache folder that cannot be written (it is still read)."""
    if not CACHE:
        return "caching is off (CLOUDMETA_NO_CACHE is set)"
    return None if _PROBLEM is None else f"{CACHE_FOLDER} is not writable ({_PROBLEM})"


#: what the line on a cache that cannot be written says (``cloudmeta compile`` looks for it)
UNCACHED = "kernels will be compiled on every run"


def say_uncached():
    """Say once per process, on stderr, that the kernels compiled now are not saved (when they are not)."""
    if CACHE and _PROBLEM is not None:
        hint = "NUMBA_CACHE_DIR" if os.environ.get("NUMBA_CACHE_DIR") else "CLOUDMETA_CACHE_DIR"
        _say_once("uncached", f"cloudmeta: {UNCACHED}: {cache_problem()}; "
                              f"set {hint} to a writable folder")


def _cannot_save(exc):
    global _PROBLEM
    if _PROBLEM is None:
        _PROBLEM = _why(exc)
    say_uncached()


def _is_kernel_file(py_file):
    return Path(py_file).resolve().parent == KERNELS


class _KernelCacheLocator(caching._SourceFileBackedLocatorMixin, caching._CacheLocator):
    """numba's locator of a cache folder, for cloudmeta's kernels; it answers for them whether or not the
    folder can be written (saving is then skipped, _KernelCache), so that numba never falls back to a
    folder without the source hash for a kernel."""
    folder = None

    def __init__(self, py_func, py_file):
        self._py_file = py_file
        self._lineno = py_func.__code__.co_firstlineno
        self._cache_path = os.path.join(str(self.folder), self.get_suitable_cache_subpath(py_file))

    def get_cache_path(self):
        return self._cache_path

    @classmethod
    def from_function(cls, py_func, py_file):
        if cls.folder is None or not _is_kernel_file(py_file):
            return None
        return cls(py_func, py_file)


class _KernelCacheImpl(caching.CompileResultCacheImpl):
    _locator_classes = [_KernelCacheLocator]


class _KernelCacheFile(caching.IndexDataCacheFile):
    """numba's index and data files of one function, which can discard what cannot be read."""

    def _load_index(self):
        try:
            return super()._load_index()
        except NotADirectoryError:
            return {}  # a file stands in the cache folder's path: nothing cached

    def save(self, key, data):
        try:
            self._load_index()
        except OSError:
            pass  # saving meets it
        except Exception:  # an index that cannot be read (damaged since it was loaded): started anew
            self.discard(self._index_path)
        super().save(key, data)

    def discard(self, path):
        """Remove a file that could not be read: a data file, or the index with every data file of the
        function (those it listed, and no other file can use them)."""
        doomed = [path]
        if path == self._index_path:
            prefix, suffix = self._data_name_pattern.split("{number:d}")
            try:
                names = os.listdir(self._cache_path)
            except OSError:
                names = []
            doomed += [os.path.join(self._cache_path, name) for name in names if name.startswith(prefix)
                       and name.endswith(suffix) and name[len(prefix):-len(suffix)].isdigit()]
        for doomed_path in doomed:
            try:
                os.remove(doomed_path)
            except OSError:
                pass  # a read-only folder: read and found broken again by the next process


def _reason(exc):
    text = " ".join(str(exc).split())
    if isinstance(exc, EOFError) or "truncated" in text:
        return "truncated"
    text = f"damaged: {type(exc).__name__}: {text}" if text else f"damaged: {type(exc).__name__}"
    return text if len(text) <= 120 else text[:117] + "..."


class _KernelCache(caching.FunctionCache):
    """numba's cache of a kernel's compiled overloads, in the kernel cache folder, with the two faults
    handled (module docstring)."""
    _impl_class = _KernelCacheImpl

    def __init__(self, py_func):
        super().__init__(py_func)
        files = self._cache_file
        self._cache_file = _KernelCacheFile(files._cache_path, self._impl.filename_base, files._source_stamp)
        module = py_func.__module__.rpartition(".")[2]
        self._kernel = f"{module}.{getattr(py_func, '__qualname__', py_func.__name__)}"

    def load_overload(self, sig, target_context):
        cres = super().load_overload(sig, target_context)
        if cres is None and self._enabled:
            say_uncached()  # compiled next, and saved only where the folder can be written
        return cres

    def _load_overload(self, sig, target_context):
        """numba's load (index, data file, rebuild), except that a file that cannot be read or rebuilt
        from is discarded and the load is a miss (numba then compiles the kernel and saves it anew)."""
        if not self._enabled:
            return None
        files = self._cache_file
        key = self._index_key(sig, target_context.codegen())
        path = files._index_path
        try:
            name = files._load_index().get(key)
            if name is None:
                return None
            path = files._data_path(name)
            try:
                data = files._load_data(name)
            except FileNotFoundError:
                return None  # removed since the index was written (numba's rule): a miss
            return self._impl.rebuild(target_context, data)
        except Exception as exc:
            files.discard(path)
            _say_once("unreadable", f"cloudmeta: the cached kernel {self._kernel} in {files._cache_path} could "
                                    f"not be read ({_reason(exc)}); compiling it again")
            return None

    def save_overload(self, sig, data):
        if _PROBLEM is not None:
            return
        try:
            super().save_overload(sig, data)
        except OSError as exc:
            _cannot_save(exc)


def _enable_caching(dispatcher):
    """``Dispatcher.enable_caching`` (``cache=True``): a _KernelCache for cloudmeta's kernels, numba's own
    cache for every other function (and for the kernels where NUMBA_CACHE_LOCATOR_CLASSES names the
    locators)."""
    if (_KernelCacheLocator.folder is not None and _is_kernel_file(dispatcher.py_func.__code__.co_filename)
            and not getattr(numba.config, "CACHE_LOCATOR_CLASSES", None)):
        dispatcher._cache = _KernelCache(dispatcher.py_func)
    else:
        _enable_caching.numba(dispatcher)


def _register_cache():
    """Whether the kernels are cached (``cache=True``), and their cache installed where they are."""
    global _PROBLEM
    if os.environ.get("CLOUDMETA_NO_CACHE", ""):
        return False
    folder = _cache_folder()
    _PROBLEM = _writable(folder)
    _KernelCacheLocator.folder = folder
    dispatcher = _dispatcher.Dispatcher
    _enable_caching.numba = getattr(dispatcher.enable_caching, "numba", dispatcher.enable_caching)
    dispatcher.enable_caching = _enable_caching
    return True


def _prefer_workqueue():
    from numba.np.ufunc import parallel
    if os.environ.get("NUMBA_THREADING_LAYER") or numba.config.THREADING_LAYER != "default":
        return
    if getattr(parallel, "_is_initialized", False):
        return
    numba.config.THREADING_LAYER = "workqueue"


#: the compiles under way in this thread, innermost last: a kernel's library name, None for other functions
_COMPILING = threading.local()


class _KernelCompiles(event.Listener):
    """Follows the compiles under way (``numba:compile`` events), so that the library of a kernel, and of no
    other function, gets the inlinable reference counts: numba names a function's library after its
    qualified name, and the helpers it compiles for a kernel (shared with later functions) have their own."""

    def on_start(self, ev):
        py_func = getattr(ev.data.get("dispatcher"), "py_func", None)
        code = getattr(py_func, "__code__", None)
        kernel = code is not None and _is_kernel_file(code.co_filename)
        stack = getattr(_COMPILING, "stack", None)
        if stack is None:
            stack = _COMPILING.stack = []
        stack.append(py_func.__qualname__ if kernel else None)

    def on_end(self, ev):
        _COMPILING.stack.pop()


class _LinkOnly:
    """An LLVM module that numba links into a library as it links its callees' libraries (what numba's
    ``CPUCodeLibrary.finalize`` reads of one)."""

    def __init__(self, module):
        self._module = module
        self._reload_init = set()

    def _ensure_finalized(self):
        pass

    def _get_module_for_linking(self):
        return self._module


#: the linkable module of the inlinable counts, built at the first kernel compile
_REFCOUNTS = []


def _inlinable_refcounts(context):
    """numba's NRT_incref and NRT_decref (and the atomic helpers they call) defined as numba defines them,
    without ``noinline``, NRT_decref split (``_split_slow_path``); every definition ``linkonce_odr``, as numba
    makes its runtime's when it links it."""
    if not _REFCOUNTS:
        from llvmlite import binding
        from numba.core.runtime import nrtdynmod
        module = context.codegen().create_library("cloudmeta_refcounts").create_ir_module("cloudmeta_refcounts")
        increment = nrtdynmod._define_atomic_inc_dec(module, "add", ordering="monotonic")
        decrement = nrtdynmod._define_atomic_inc_dec(module, "sub", ordering="monotonic")
        nrtdynmod._define_nrt_incref(module, increment)
        nrtdynmod._define_nrt_decref(module, decrement)
        for name in ("NRT_incref", "NRT_decref"):
            module.get_global(name).attributes.discard("noinline")
        _split_slow_path(module, module.get_global("NRT_decref"))
        linkable = binding.parse_assembly(str(module))
        for fn in linkable.functions:
            if not fn.is_declaration:
                fn.linkage = "linkonce_odr"
        linkable.verify()
        _REFCOUNTS.append(_LinkOnly(linkable))
    return _REFCOUNTS[0]


def _post_lowering(self, mod, library):
    """numba's ``post_lowering`` (which links its runtime into the library), with the inlinable counts linked
    first into a kernel's library: the first definition linked is the one a module keeps."""
    stack = getattr(_COMPILING, "stack", None)
    if stack and stack[-1] is not None and getattr(library, "name", None) == stack[-1]:
        linking = getattr(library, "_linking_libraries", None)
        if isinstance(linking, list):
            linking.insert(0, _inlinable_refcounts(self))
        else:
            library.add_linking_library(_inlinable_refcounts(self))
    return _post_lowering.numba(self, mod, library)


def _inline_reference_counts():
    """Whether cloudmeta's kernels get inlinable reference counts (module docstring): installs the
    ``numba:compile`` listener and the wrapped ``post_lowering``, unless CLOUDMETA_NRT_INLINE=0 or this numba
    lacks what they need (then the counts stay calls, and the kernels slower)."""
    if os.environ.get("CLOUDMETA_NRT_INLINE", "1").strip() == "0":
        return False
    from numba.core.cpu import CPUContext
    from numba.core.runtime import nrtdynmod
    needed = ("_define_atomic_inc_dec", "_define_nrt_incref", "_define_nrt_decref")
    if not all(callable(getattr(nrtdynmod, name, None)) for name in needed):
        return False
    if not callable(getattr(CPUContext, "post_lowering", None)):
        return False
    if getattr(CPUContext.post_lowering, "numba", None) is None:  # not wrapped already (module imported twice)
        _post_lowering.numba = CPUContext.post_lowering
        CPUContext.post_lowering = _post_lowering
        event.register("numba:compile", _KernelCompiles())
    return True


def _split_slow_path(module, fn):
    """NRT_decref as a null test that LLVM inlines, and a call to the rest of numba's body (the atomic
    decrement and the destructor) kept out of line: every inlined copy is a compare and a call, not the whole
    body (the compile time that inlining adds). Where llvmlite's IR objects lack what this needs (checked
    before anything moves), fn stays whole."""
    from llvmlite import ir
    instructions = [instruction for block in fn.blocks for instruction in block.instructions]
    if len(fn.args) != 1 or not all(hasattr(instruction, "replace_usage") for instruction in instructions):
        return
    slow = ir.Function(module, fn.function_type, "cloudmeta_NRT_decref_slow")
    slow.attributes.add("noinline")
    for instruction in instructions:
        instruction.replace_usage(fn.args[0], slow.args[0])
    for block in fn.blocks:
        block.parent = slow
    slow.blocks = fn.blocks
    fn.blocks = []
    builder = ir.IRBuilder(fn.append_basic_block())
    ptr = fn.args[0]
    is_null = builder.icmp_unsigned("==", ptr, ir.Constant(ptr.type, None))
    with builder.if_then(is_null, likely=False):
        builder.ret_void()
    builder.call(slow, [ptr])
    builder.ret_void()


_prefer_workqueue()
#: whether cloudmeta's kernels get inlinable reference counts (module docstring)
INLINE_REFCOUNTS = _inline_reference_counts()
CACHE = _register_cache()
#: the folder of the compiled kernels (None where caching is off)
CACHE_FOLDER = _KernelCacheLocator.folder
FASTMATH = False

#: flags for serial kernels. no_cfunc_wrapper: numba otherwise compiles a C-callable wrapper of every function
#: (for first-class function values, which the kernels never are), beside the Python wrapper: for a kernel that
#: takes the scene's records, LLVM spent about a third as long on it as on the kernel itself
NJIT = dict(cache=CACHE, fastmath=FASTMATH, nogil=True, error_model="numpy", no_cfunc_wrapper=True)
#: flags for the small helpers of hot loops: inlined into their callers at numba's IR level, so that no
#: call boundary remains in the loop (the arrays they bind are still reference-counted where the helper
#: branches: the loops read borrowed records, kernels.borrow)
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
