"""The numba configuration module: cache detection (what the CLI uses to announce a first compile)."""
import os

import numba
from numba import njit

from cloudmeta.kernels import config


def test_is_compiled_looks_for_the_function_in_its_own_cache_folder(tmp_path, monkeypatch):
    monkeypatch.setattr(numba.config, "CACHE_DIR", str(tmp_path))

    def twice(x):
        return 2 * x

    jitted = njit(cache=True)(twice)
    monkeypatch.setattr(config, "CACHE", True)
    assert not config.is_compiled(jitted)
    assert jitted(3) == 6  # compiles and writes the cache
    assert config.is_compiled(jitted)
    monkeypatch.setattr(config, "CACHE", False)
    assert not config.is_compiled(jitted)


def test_threading_layer_is_workqueue_unless_asked_otherwise():
    expected = os.environ.get("NUMBA_THREADING_LAYER") or "workqueue"
    assert numba.config.THREADING_LAYER == expected


# --- reference counts: inlinable in cloudmeta's kernels alone (config._inline_reference_counts) --------------

import subprocess  # noqa: E402
import sys  # noqa: E402

_RUNTIME = """
import os, re, sys
from numba import njit
njit(lambda x: x + 1)(1)  # numba's runtime is built before cloudmeta is imported: the counts inline all the same
from cloudmeta.kernels import config
import numpy as np
from numba.core.runtime import nrt

def churn(n):  # arrays made, bound in branches, passed and dropped: every count must come back to zero
    total = 0.0
    for i in range(n):
        a = np.ones(i % 5 + 1)
        b = a if i % 2 else a[1:]
        total += b.sum() + len(a)
    return total

def compiled(kernel):  # churn as one of cloudmeta's kernels (a function of their folder) or as other code
    config._is_kernel_file = (lambda path: path == "<string>") if kernel else (lambda path: False)
    f = njit(churn)
    before = nrt.rtsys.get_allocation_stats()
    assert f(1000) > 0
    after = nrt.rtsys.get_allocation_stats()
    assert after.alloc - before.alloc == after.free - before.free > 0, (before, after)
    assert after.mi_alloc - before.mi_alloc == after.mi_free - before.mi_free
    ir = f.overloads[f.signatures[0]].library.get_llvm_str()
    return len(re.findall(r"call void @NRT_(?:incref|decref)[(]", ir)), "cloudmeta_NRT_decref_slow" in ir

def runtime_noinline():
    ir = nrt.rtsys._library.get_llvm_str()
    groups = dict(re.findall(r"^attributes (#[0-9]+) = [{] (.*) [}]$", ir, re.M))
    out = []
    for name in ("NRT_incref", "NRT_decref"):
        line = re.search(r"^define .*@" + name + r"[(].*$", ir, re.M).group(0)
        attrs = " ".join(groups.get(g, "") for g in re.findall(r"#[0-9]+", line)) + line
        out.append("noinline" in attrs)
    return out

kernel = compiled(True)
other = compiled(False)
print(config.INLINE_REFCOUNTS, kernel[0], kernel[1], other[0] > 0, other[1], *runtime_noinline())
"""


def _runtime(**env):
    run = subprocess.run([sys.executable, "-c", _RUNTIME], capture_output=True, text=True, check=True,
                         env={**os.environ, "NUMBA_NRT_STATS": "1", "CLOUDMETA_NO_CACHE": "1", **env})
    return run.stdout.split()


def test_reference_counts_inline_in_the_kernels_and_nowhere_else():
    # fails loudly where this numba lacks what config needs (pyproject.toml pins the versions tested): the
    # kernels would run 1.3-1.6x slower with their counts as calls
    inline, kernel_calls, kernel_slow, other_calls, other_slow, incref_noinline, decref_noinline = _runtime()
    assert inline == "True", f"numba {numba.__version__}: cloudmeta's kernels cannot get inlinable reference counts"
    # a kernel: no call of either function left (the decrement's slow path, out of line, frees the arrays)
    assert (kernel_calls, kernel_slow) == ("0", "True")
    # every other function, and numba's runtime itself, exactly as numba makes them
    assert (other_calls, other_slow) == ("True", "False")
    assert (incref_noinline, decref_noinline) == ("True", "True")


def test_reference_counts_stay_calls_when_asked():
    inline, kernel_calls, kernel_slow, *_ = _runtime(CLOUDMETA_NRT_INLINE="0")
    assert inline == "False" and kernel_calls != "0" and kernel_slow == "False"


def test_the_cache_folder_depends_on_how_counts_compile(monkeypatch):
    monkeypatch.setattr(config, "INLINE_REFCOUNTS", True)
    inlined = config._kernel_source_hash()
    monkeypatch.setattr(config, "INLINE_REFCOUNTS", False)
    assert config._kernel_source_hash() != inlined


# --- the kernel cache's faults (issue #27): in process, with a small function given the kernels' cache ------

import pickle  # noqa: E402

import numpy as np  # noqa: E402
import pytest  # noqa: E402
from numba.core.caching import FunctionCache, NullCache  # noqa: E402


@pytest.fixture
def kernel_cache(tmp_path, monkeypatch):
    """The kernels' cache (config._KernelCache), in tmp_path, for functions defined in this file too; a
    fresh record of what was said."""
    monkeypatch.delenv("NUMBA_CACHE_DIR", raising=False)
    monkeypatch.setattr(config, "_is_kernel_file", lambda py_file: True)
    monkeypatch.setattr(config._KernelCacheLocator, "folder", tmp_path)
    monkeypatch.setattr(config, "CACHE_FOLDER", tmp_path)
    monkeypatch.setattr(config, "CACHE", True)
    monkeypatch.setattr(config, "_SAID", set())
    monkeypatch.setattr(config, "_PROBLEM", None)
    return tmp_path


def _thrice():
    def thrice(x):
        return 3 * x
    return njit(cache=True)(thrice)  # a new dispatcher each time, as in a new process


def _files(folder, suffix):
    return sorted(folder.rglob(f"*{suffix}"))


def test_the_kernels_have_their_own_cache_and_other_functions_numbas():
    from cloudmeta.kernels.batch import field_at
    if not config.CACHE:  # CLOUDMETA_NO_CACHE: numba's no-cache
        assert type(field_at._cache) is NullCache and config.cache_problem().startswith("caching is off")
        return
    assert type(field_at._cache) is config._KernelCache
    assert field_at._cache.cache_path.startswith(str(config.CACHE_FOLDER))
    other = njit(cache=True)(lambda x: x + 1)
    assert type(other._cache) is FunctionCache


def test_the_locator_answers_for_kernels_alone_even_where_the_folder_cannot_be_written(tmp_path, monkeypatch):
    from cloudmeta.kernels.batch import field_at
    blocker = tmp_path / "file"
    blocker.write_text("not a folder")
    monkeypatch.setattr(config._KernelCacheLocator, "folder", blocker / "numba-x")
    kernel = field_at.py_func
    locator = config._KernelCacheLocator.from_function(kernel, kernel.__code__.co_filename)
    assert locator is not None  # numba's fallbacks (__pycache__, ~/.cache/numba) never see a kernel
    assert locator.get_cache_path().startswith(str(blocker / "numba-x"))
    assert config._KernelCacheLocator.from_function(_files, __file__) is None


def test_writable_says_why_not(tmp_path):
    blocker = tmp_path / "file"
    blocker.write_text("x")
    assert config._writable(tmp_path / "new" / "numba-1") is None
    assert (tmp_path / "new" / "numba-1").is_dir()
    assert config._writable(blocker) == "a file stands where the folder should be"
    assert config._writable(blocker / "numba-1") == "a file stands in its path"


def test_reasons_in_a_few_words():
    assert config._reason(pickle.UnpicklingError("pickle data was truncated")) == "truncated"
    assert config._reason(EOFError("Ran out of input")) == "truncated"
    assert config._reason(pickle.UnpicklingError("invalid load key, '\\x8f'.")) == \
        "damaged: UnpicklingError: invalid load key, '\\x8f'."
    assert config._reason(MemoryError()) == "damaged: MemoryError"
    assert len(config._reason(ValueError("x" * 500))) == 120


@pytest.mark.parametrize("damage", ["truncated index", "truncated data", "garbage index", "garbage data",
                                    "empty index"])
def test_an_entry_that_cannot_be_read_is_discarded_and_compiled_again(kernel_cache, capsys, damage):
    assert _thrice()(2) == 6
    index, = _files(kernel_cache, ".nbi")
    data, = _files(kernel_cache, ".nbc")
    target = index if "index" in damage else data
    whole = target.read_bytes()
    if "truncated" in damage:
        target.write_bytes(whole[:len(whole) // 2])
    elif "garbage" in damage:  # 0xff is no pickle opcode
        target.write_bytes(b"\xff" + np.random.default_rng(5).bytes(len(whole) - 1))
    else:
        target.write_bytes(b"")
    damaged = target.read_bytes()
    capsys.readouterr()

    again = _thrice()
    assert again(2) == 6  # loaded? no: compiled again
    assert sum(again.stats.cache_misses.values()) == 1
    err = capsys.readouterr().err.splitlines()
    assert len(err) == 1
    assert err[0].startswith("cloudmeta: the cached kernel test_config._thrice.<locals>.thrice in ")
    reason = ("truncated)" if "truncated" in damage or "empty" in damage else
              "damaged: UnpicklingError: invalid load key, '\\xff'.)")
    assert err[0].endswith(f" in {index.parent} could not be read ({reason}; compiling it again")
    assert _files(kernel_cache, ".nbi") == [index] and _files(kernel_cache, ".nbc") == [data]
    assert target.read_bytes() != damaged  # the new copy

    repaired = _thrice()  # the new copy replaced the broken one
    assert repaired(2) == 6
    assert sum(repaired.stats.cache_hits.values()) == 1 and sum(repaired.stats.cache_misses.values()) == 0
    assert capsys.readouterr().err == ""


def test_a_damaged_index_takes_its_data_files_along(kernel_cache):
    assert _thrice()(2) == 6 and _thrice()(2.5) == 7.5  # two signatures, two data files
    index, = _files(kernel_cache, ".nbi")
    assert len(_files(kernel_cache, ".nbc")) == 2
    stranger = index.parent / "other.fn-1.py311.1.nbc"
    stranger.write_bytes(b"someone else's")
    files = _thrice()._cache._cache_file
    files.discard(str(index))
    assert _files(kernel_cache, ".nbi") == [] and _files(kernel_cache, ".nbc") == [stranger]


def test_a_folder_that_cannot_be_written_is_read_and_not_written(kernel_cache, capsys, monkeypatch):
    assert _thrice()(2) == 6  # cached while the folder could be written
    before = sorted(kernel_cache.rglob("*"))
    capsys.readouterr()
    monkeypatch.setattr(config, "_PROBLEM", "permission denied")
    loaded = _thrice()
    assert loaded(2) == 6 and sum(loaded.stats.cache_hits.values()) == 1
    assert capsys.readouterr().err == ""  # nothing compiled, nothing to say
    assert loaded(2.5) == 7.5 and loaded(3j) == 9j  # two compiles, not saved, said once
    err = capsys.readouterr().err.splitlines()
    assert err == [f"cloudmeta: kernels will be compiled on every run: {kernel_cache} is not writable "
                   "(permission denied); set CLOUDMETA_CACHE_DIR to a writable folder"]
    assert sorted(kernel_cache.rglob("*")) == before


def test_a_save_that_fails_stops_saving_and_says_so_once(kernel_cache, capsys, monkeypatch):
    def full_disk(self, key, data):
        raise OSError(28, "No space left on device")
    monkeypatch.setattr(config._KernelCacheFile, "save", full_disk)
    jitted = _thrice()
    assert jitted(2) == 6 and jitted(2.5) == 7.5
    err = capsys.readouterr().err.splitlines()
    assert len(err) == 1 and "is not writable (no space left on device)" in err[0]
    assert config.cache_problem().endswith("is not writable (no space left on device)")
