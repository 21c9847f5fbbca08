"""numba kernels: arrays, scalars and named records in, arrays and tuples out. Nothing here knows about YAML,
files or colour.

records    -- the named records the kernels read: the packed scene, the quadrature, the work arrays
bernstein  -- de Casteljau evaluation and subdivision, degree elevation, exact integrals (one job each)
metaball   -- a ball's chord along a ray, its Bernstein control values, the falloff k(u) and the field and
              gradient at points
clipping   -- all roots of a Bernstein polynomial in [0, 1], in order, by Bézier clipping
sweep      -- one ray through one blob: composite intervals, inside pieces, roots, optical depth
bvh        -- a bounding-volume hierarchy over the balls' supports: build, ray and point queries
media      -- every medium along one ray: the pieces a camera ray integrates, shadow transmittance
surfaces   -- opaque surfaces along one ray: the first hit, shadow blocking, the normal
shadowmap  -- light-space shadow maps of directional lights: tracing the texels, the lookup
optics     -- phase functions
radiance   -- the camera-ray estimator (single scattering, in stages) and the image loop
trace      -- batches of rays and points in parallel, for the public API
grid       -- the field on a regular grid, with a spatial cull (cloudmeta.inspect)
"""
