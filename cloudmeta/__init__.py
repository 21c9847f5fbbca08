"""cloudmeta: clouds and other transparent media from metaballs, rendered exactly (Nishita & Nakamae).

The public API:

- ``Blob``: metaballs with one kernel and threshold; ``roots``, ``segments``, ``optical_depth``,
  ``first_hit``: the exact ray engine, vectorised over rays; ``field``, ``gradient``, ``normal`` at points.
- ``load_scene``, ``render``, ``write_exr``, ``read_exr``, ``write_png``: YAML scene to image.
- ``render_frames``: a sequence of frames (keyframed scenes), whole or in tiles, here or on a Dask cluster.

The names are imported on first use (PEP 562): a process loads only the modules its work needs (the
scene loader, the EXR writer and colour-science, the vectorised engine, each when first asked for).
``render`` is imported here (cloudmeta.renderer): what every render needs anyway (numba and the
kernels' dispatchers; no compiled code is loaded until the first call). ``generate`` and ``write_scene``
are imported here too (numpy only, light): ``cloudmeta.generate`` names both a function and a package, and
importing the package sets this module's attribute to the package, so the function is bound here after it,
once, and ``cloudmeta.generate(...)`` is always the function.

The package stands on three floors that import only downwards: ``scene`` (YAML -> Scene), ``renderer``
(Scene -> image) and ``kernels`` (numba), with ``errors`` below them all; the modules here (the API, the
command line, clusters, io, inspection, the ray engine) stand on top.
"""
import importlib

from .generate import generate, write_scene
from .renderer import render

#: public name -> the submodule that defines it
_EXPORTS = {
    "Blob": "scene.blob",
    "field": "api.rays", "first_hit": "api.rays", "gradient": "api.rays", "normal": "api.rays",
    "optical_depth": "api.rays", "roots": "api.rays", "segments": "api.rays",
    "CloudmetaError": "errors", "InputError": "errors", "SceneError": "errors", "OutputError": "errors",
    "read_exr": "api.io", "write_exr": "api.io", "write_png": "api.io",
    "load_scene": "scene", "render_frame": "renderer", "RenderResult": "renderer",
    "render_frames": "api.cluster",
    "fit_volume": "fit",
}

__all__ = ["Blob", "field", "first_hit", "gradient", "normal", "optical_depth", "roots", "segments", "load_scene",
           "render", "render_frame", "RenderResult", "render_frames", "write_exr", "read_exr", "write_png", "CloudmetaError", "InputError",
           "SceneError", "OutputError", "generate", "write_scene", "fit_volume"]
__version__ = "0.1.0"


def __getattr__(name):
    module = _EXPORTS.get(name)
    if module is None:
        raise AttributeError(f"module 'cloudmeta' has no attribute {name!r}")
    value = getattr(importlib.import_module(f".{module}", __name__), name)
    globals()[name] = value  # later lookups skip this hook
    return value


def __dir__():
    return sorted(set(globals()) | set(__all__))
