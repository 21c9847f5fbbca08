"""cloudmeta: clouds and other transparent media from metaballs, rendered exactly (Nishita & Nakamae)."""
from .blob import Blob
from .engine import field, optical_depth, roots, segments
from .errors import CloudmetaError, InputError, SceneError

__all__ = ["Blob", "field", "optical_depth", "roots", "segments", "CloudmetaError", "InputError", "SceneError"]
__version__ = "0.1.0"
