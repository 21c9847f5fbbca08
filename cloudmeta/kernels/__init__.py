"""numba kernels: arrays and scalars in, arrays and tuples out. Nothing here knows about YAML, files or colour.

bernstein  -- de Casteljau evaluation and subdivision, degree elevation, exact integrals (one job each)
metaball   -- a ball's chord along a ray, its Bernstein control values, the falloff k(u) at points
clipping   -- all roots of a Bernstein polynomial in [0, 1], in order, by Bézier clipping
sweep      -- one ray through one blob: composite intervals, inside pieces, roots, optical depth
trace      -- batches of rays in parallel, for the public API
"""
