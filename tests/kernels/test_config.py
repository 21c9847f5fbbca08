"""The numba configuration module: cache detection (what the CLI uses to announce a first compile)."""
import os

import numba
from numba import njit

from cloudmeta import config


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
