"""cloudmeta: clouds and other transparent media from metaballs, rendered exactly (Nishita & Nakamae).

The public API:

- ``Blob``: metaballs with one kernel and threshold; ``roots``, ``segments``, ``optical_depth``,
  ``first_hit``: the exact ray engine, vectorised over rays; ``field``, ``gradient``, ``normal`` at points.
- ``load_scene``, ``render``, ``write_exr``, ``read_exr``, ``write_png``: YAML scene to image.
- ``render_frames``: a sequence of frames (keyframed scenes), whole or in tiles, here or on a Dask cluster.
"""
from .blob import Blob
from .cluster import render_frames
from .engine import field, first_hit, gradient, normal, optical_depth, roots, segments
from .errors import CloudmetaError, InputError, SceneError
from .io import read_exr, write_exr, write_png
from .render import render
from .scene import load_scene

__all__ = ["Blob", "field", "first_hit", "gradient", "normal", "optical_depth", "roots", "segments", "load_scene",
           "render", "render_frames", "write_exr", "read_exr", "write_png", "CloudmetaError", "InputError",
           "SceneError"]
__version__ = "0.1.0"
