"""The numba configuration module: cache detection (what the CLI uses to announce a first compile)."""
import numba

from cloudmeta import config


def test_is_compiled_looks_for_the_function_in_the_cache(tmp_path, monkeypatch):
    monkeypatch.setattr(config, "CACHE", True)
    monkeypatch.setattr(numba.config, "CACHE_DIR", str(tmp_path))
    assert not config.is_compiled("radiance", "render_pixels")
    (tmp_path / "kernels_abc").mkdir()
    (tmp_path / "kernels_abc" / "radiance.render_pixels-506.py311.nbi").write_bytes(b"")
    assert config.is_compiled("radiance", "render_pixels")
    assert not config.is_compiled("radiance", "ray_radiance")
    monkeypatch.setattr(config, "CACHE", False)
    assert not config.is_compiled("radiance", "render_pixels")


def test_threading_layer_is_workqueue_unless_asked_otherwise():
    import os
    if not os.environ.get("NUMBA_THREADING_LAYER"):
        assert numba.config.THREADING_LAYER == "workqueue"
