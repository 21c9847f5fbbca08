"""The renderer floor: a validated Scene (cloudmeta.scene) -> a linear image, through the kernels
(cloudmeta.kernels). It imports only downwards.

frame     -- render / render_frame: the estimator table keyed by render.scattering, one RenderResult back
quality   -- the presets and the resolved quadrature settings of a render
estimate  -- the error estimate and error-controlled rendering (docs/error_estimate.md)
pack      -- the scene packed into the kernels' records, once per render
bands     -- bands of rows on threads, the progress bar, tiles
single    -- the single-scattering driver (the deterministic part of every render)
multiple  -- the multiple-scattering driver (the Monte Carlo part)
denoise   -- the optional denoiser of the Monte Carlo part (pyoidn)
"""
from .frame import ESTIMATORS, RenderResult, render, render_frame

__all__ = ["ESTIMATORS", "RenderResult", "render", "render_frame"]
