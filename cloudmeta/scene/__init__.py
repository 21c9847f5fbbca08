"""The scene floor: YAML in, a validated, frozen ``Scene`` out. Imports nothing above it (only
cloudmeta.errors and cloudmeta.kernels' numba-free tables, kernels.kinds; kernels.bvh when a BVH is built).

document    -- safe YAML reading and the typed getters (``Node``): every error names file and key path
vocabulary  -- every name of a kind, preset, mode and shared default, defined once
schema      -- the frozen dataclasses of a validated scene
loader      -- load_scene and the section readers
balls       -- inline balls and CSV balls files into one Blob
blob        -- Blob: metaballs of one kernel and threshold, validated and packed (the public API's too)
animation   -- keyframes resolved to one static document per frame
domain      -- the numeric domain and the memory a render needs
colour      -- colours of the scene (colour-science) and the sRGB encoding of previews
limits      -- the numeric limits (README "Limits")
"""
from .loader import load_scene
from .model import (Camera, Density, DirectionalLight, ImageSettings, Medium, OutputSettings, Phase, PointLight,
                     RenderSettings, Scene, Surface)

__all__ = ["load_scene", "Camera", "Density", "DirectionalLight", "ImageSettings", "Medium", "OutputSettings",
           "Phase", "PointLight", "RenderSettings", "Scene", "Surface"]
