"""numba kernels: arrays, scalars and named records in, arrays and tuples out. Nothing here knows about YAML,
files or colour, and nothing here imports from the floors above (cloudmeta.scene, cloudmeta.renderer).

config     -- numba's flags (the one place) and the kernel cache scoped to these modules' sources
kinds      -- every integer id a kernel switches on (falloffs, density modes, phases, lights), with its name
records    -- the named records the kernels read: the packed scene, the quadrature, the work arrays, states
bernstein  -- de Casteljau evaluation and subdivision, degree elevation, exact integrals (one job each)
metaball   -- a ball's chord along a ray, its Bernstein control values, the falloff k(u) and the field and
              gradient at points
clipping   -- all roots of a Bernstein polynomial in [0, 1], in order, by Bézier clipping
density    -- rho(F) of each density mode, its mean and integral (affine in F: stated and relied on there)
sweep      -- one ray through one blob: composite intervals, inside pieces, roots, optical depth
shadow     -- the fused optical depth of shadow rays (no pieces written)
bvh        -- a bounding-volume hierarchy over the balls' supports: build, ray and point queries
media      -- every medium along one ray: the pieces a camera ray integrates, shadow transmittance
surfaces   -- opaque surfaces along one ray: the first hit, shadow blocking, the normal
shadowmap  -- light-space shadow maps of directional lights: tracing the texels, the lookup
features   -- what a scene lacks (surfaces, maps) compiled to its trivial case
optics     -- phase functions
sampling   -- random numbers keyed by (seed, pixel, path, vertex, dimension), phase sampling, free flights
lighting   -- the light reaching a point, every light kind: l . v and E_l T_l, point-light angular cuts
camera     -- camera rays of a pixel's samples, jitter
raywork    -- one thread's work arrays and the elementary intervals of a ray (shared by the estimators)
single     -- the single-scattering estimator (in stages) and its image loop
multiple   -- the multiple-scattering estimator (paths) and its image loop: a sibling of single, sharing
              camera, raywork and lighting, importing nothing from single
trace      -- batches of rays and points in parallel, for the public API
grid       -- the field on a regular grid, with a spatial cull (cloudmeta.api.viewer)

The kernel cache (config) hashes every module of this folder: keep it flat.
"""
