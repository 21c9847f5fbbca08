"""The named records the kernels read: the packed scene, the quadrature rule and the work arrays.

Every record is a ``collections.namedtuple`` of arrays and scalars. numba compiles them in nopython mode
and resolves ``media.threshold[m]`` at compile time, so a record costs nothing at run time, and a new
field shifts no index. They are built once per render by cloudmeta.renderer.pack (the scene) or by the ``alloc_*``
kernels (the work arrays); the kernels never build scene records. Arrays are fresh, writable and
C-contiguous with the dtypes given here, so that numba sees one type per record and compiles once.

Shapes: N balls, M media, S surfaces, L lights, K BVH nodes, P pieces, C = 7 control values (degree 6).
"""
from collections import namedtuple

#: a merged bounding-volume hierarchy over the balls of several blobs (kernels.bvh): node_box (K, 6) =
#: [lo, hi]; a leaf has node_n > 0 and holds items[node_a : node_a + node_n]; an inner node has children
#: node_a, node_b; root (M,) is each blob's root node
BVH = namedtuple("BVH", ["node_box", "node_a", "node_b", "node_n", "items", "root"])

#: one blob as the sweep reads it (kernels.sweep): the balls' centers (N, 3), frames (N, 3, 3) and
#: weights (N,), possibly shared with other blobs, and this blob's kernel, blobbiness and threshold
BlobRecord = namedtuple("BlobRecord", ["centers", "frames", "weights", "kernel", "blobbiness", "threshold"])

#: rays of the public API (kernels.trace): origins (R, 3), unit directions (R, 3), t_max (R,)
Rays = namedtuple("Rays", ["origins", "directions", "t_max"])

#: what kernels.trace.trace_rays writes per ray: tau (R,), n_roots (R,), roots (R, cap), n_seg (R,),
#: segs (R, cap, 2); the counts are true counts, the lists hold the first cap
TraceOut = namedtuple("TraceOut", ["tau", "n_roots", "roots", "n_seg", "segs"])

#: balls binned into a coarse uniform grid of cells (kernels.grid): origin (3,), cell size, dims (3,) cells
#: per axis, start (cells + 1,) offsets into items, the ball indices of each cell in increasing order
CellGrid = namedtuple("CellGrid", ["origin", "size", "dims", "start", "items"])

#: every medium's balls in one set of arrays (docs/model.md §4): centers (N, 3), frames (N, 3, 3),
#: weights (N,), start (M + 1,) ball offsets; per medium kernel, threshold, blobbiness (blinn's b),
#: mode (sweep.DENSITY_*), scale (sigma_t = scale * rho), albedo, phase (M, 4) = kind, g1, g2, w
#: (kernels.optics); bvh a BVH
Media = namedtuple("Media", ["centers", "frames", "weights", "start", "kernel", "threshold", "blobbiness",
                             "mode", "scale", "albedo", "phase", "bvh"])

#: every opaque surface's balls (docs/model.md §6): as Media, with colour (S, 3) linear RGB in place of the
#: density and scattering parameters
Surfaces = namedtuple("Surfaces", ["centers", "frames", "weights", "start", "kernel", "threshold",
                                   "blobbiness", "colour", "bvh"])

#: shadow maps of directional lights (kernels.shadowmap): map_of (L,) the light's map or -1 for exact
#: shadow rays; per map geo (13,) rows, res, base (its first texel); start (texels + 1,) piece offsets;
#: per piece t0, t1, c (P, C) sigma_t, cum the running integral, reach the running max of t1
ShadowMaps = namedtuple("ShadowMaps", ["map_of", "geo", "res", "base", "start", "t0", "t1", "c", "cum",
                                       "reach"])

#: the optical depth towards each directional light on a lattice in the light's frame (kernels.shadowmap,
#: the paths' control variate): map_of (L,) the light's volume or -1; per volume geo (13,) rows (as a map's),
#: res (texels per side), depth_n (samples along the light), base (its first sample); tau (V,) float32, the
#: depth at texel (i, j)'s centre and depth k * geo[12] at base + (i res + j) depth_n + k
LightVolumes = namedtuple("LightVolumes", ["map_of", "geo", "res", "depth_n", "base", "tau"])

#: the pieces of the texels of shadow maps while they are traced (kernels.shadowmap.trace_texel_chunk):
#: per piece t0, t1, c (P, C) sigma_t, cum, reach, as in ShadowMaps
MapPieces = namedtuple("MapPieces", ["t0", "t1", "c", "cum", "reach"])

#: the lights (docs/model.md §5): kind (L,) kinds.DIRECTIONAL or POINT; vec (L, 3) the direction towards a
#: directional light, or a point light's position; rgb (L, 3) irradiance or intensity; maps ShadowMaps, or
#: None in a scene with neither shadow maps nor surfaces (kernels.features)
Lights = namedtuple("Lights", ["kind", "vec", "rgb", "maps"])

#: what a camera ray sees: Media, Surfaces (None in a scene with neither surfaces nor shadow maps: the kernels
#: then compile without the surface code, kernels.features), Lights, the background (K, 3) (one row: uniform; more:
#: a sky over elevation, kernels.camera.background_radiance) and the ambient radiance (3,)
#: octaves (N, 3): rows (a^i, b^i, c^i) of the approximate mode's octaves (docs/approximate.md); the single
#: row (1, 1, 1) is single scattering; radiance: the approximate mode's RadianceGrid (method grid), else None
#: (and then its gather is not compiled, kernels.features); view_media: the Media the camera ray sees, the same
#: record as media except in the grid method, where each medium's forward peak f of the phase function leaves
#: the camera ray's extinction (scale (1 - f albedo), albedo / (1 - f albedo): docs/approximate.md, delta split)
SceneRecords = namedtuple("SceneRecords", ["media", "surfaces", "lights", "background", "ambient", "octaves",
                                           "radiance", "view_media"])

#: the approximate mode's grid method (kernels.fluence): a box of cubic cells, origin (3,), cell size, dims (3,)
#: (cell c = i + nx (j + ny k)); coef (cells, 3, M) per cell, colour and medium the light the medium scatters
#: towards the camera (per unit sigma_s; with deposits at collisions, times the cell's mean sigma_s), as a value
#: at the cell's centre; towards (cells, 3) the unit
#: direction from each cell's centre to the camera; peak (M, 2) per medium (cos_c, p_c): the phase function the
#: photons deposit is clamped to p_c where cos theta > cos_c (its forward peak goes to SceneRecords.view_media);
#: filled (cells, M) what coef is per (1, or the cell's mean sigma_s,m with deposits at collisions): the gather
#: interpolates both and divides (kernels.fluence.grid_scattered)
RadianceGrid = namedtuple("RadianceGrid", ["origin", "size", "dims", "coef", "towards", "peak", "filled"])

#: the shared method's cache of the deep orders (renderer.shared, kernels.fluence.cached_light): a box of cubic cells
#: as RadianceGrid's, moments (cells, 3, SH_TERMS) per cell and colour the spherical-harmonic coefficients of the
#: scattered light's (and the environment's) radiance at the cell's centre (kernels.fluence.sh_basis);
#: phase_moments (M, SH_TERMS) per medium (-1)^l times its phase function's Legendre coefficient of each
#: harmonic's degree l; order: the tails trace the orders up to this one and read the cache beyond it (0: none)
FluenceCache = namedtuple("FluenceCache", ["origin", "size", "dims", "moments", "phase_moments", "order"])

#: a delta-tracked flight's deposits at its tentative collisions (kernels.fluence, render.grid.deposit: collisions):
#: the RadianceGrid, its coef (cells, 3, M) and the photon's power rgb (3,)
FlightTally = namedtuple("FlightTally", ["grid", "coef", "rgb"])

#: where the grid method's photons come from (kernels.fluence.emit): per source kind (S,) (kinds.LIGHTS, or
#: fluence.ENVIRONMENT), vec (S, 3) the direction towards a directional light or a point light's position,
#: rgb (S, 3) the power of one photon (times the environment's radiance along it), first (S + 1,) the
#: photons' numbering per source; centre (3,) and radius of the sphere the parallel photons cross; the
#: background table (K, 3) (kernels.camera.background_radiance); footprint (S, R, R) 1 where a directional
#: source's parallel rays through that texel of its disk can meet the media, axes (S, 2, 3) the disk's texel
#: axes (renderer.fluence.sun_footprint; all ones for the other sources)
PhotonSources = namedtuple("PhotonSources", ["kind", "vec", "rgb", "first", "centre", "radius", "background",
                                             "footprint", "axes"])

#: records.Quadrature.shadow_mode: where a node's shadow transmittance T_l comes from (``render.shadows``,
#: cloudmeta.scene.vocabulary.ShadowMode): exact shadow rays; a directional light's shadow map, always; or its map
#: where the map's own error bound keeps map_tolerance, an exact shadow ray elsewhere (kernels.lighting)
SHADOWS_EXACT = 0
SHADOWS_MAP = 1
SHADOWS_HYBRID = 2
SHADOW_MODES = {"exact": SHADOWS_EXACT, "map": SHADOWS_MAP, "hybrid": SHADOWS_HYBRID}

#: the in-scattering quadrature (cloudmeta.renderer.pack.quadrature): the step rule, 7 Gauss and 15 Kronrod nodes
#: on [0, 1] with their Lagrange bases at a fine Gauss rule (fine_y, fine_w); where the Gauss nodes and
#: the other 8 sit among the 15 (gauss_col, kronrod_col); tail (2, 7) maps J at the Gauss nodes to its two
#: highest Legendre coefficients. Then the render's quality settings (cloudmeta.renderer.quality.FrameSettings):
#: max_tau, max_length, max_angle, cutoff, u_stop = -log(cutoff) (the view optical depth past which
#: nothing is shaded; inf for cutoff 0), tol_t (the root tolerance on t, absolute), tolerance, and
#: light_scale (the frame's scattered-light scale that tolerance is relative to, cloudmeta.renderer.calibrate; 0:
#: relative to each ray's brightest J instead); shadow_mode (SHADOWS_EXACT, SHADOWS_MAP or SHADOWS_HYBRID, int64)
#: and map_tolerance: with SHADOWS_HYBRID, the error of J (r + g + b, weighted by the view transmittance,
#: absolute) that a shadow map's interpolation may make at a node before an exact shadow ray replaces it (0:
#: exact rays only; unread in the other modes); growth: the step limits at view depth u are max_tau and
#: max_length times e^(growth u) (0: equal steps)
Quadrature = namedtuple("Quadrature", ["gauss_x", "gauss_lag", "kronrod_x", "kronrod_lag", "gauss_col",
                                       "kronrod_col", "tail", "fine_y", "fine_w", "max_tau", "max_length",
                                       "max_angle", "cutoff", "u_stop", "tol_t", "tolerance", "light_scale",
                                       "shadow_mode", "map_tolerance", "growth"])

#: a pinhole camera (docs/model.md §8): position, forward, and right / up scaled to the image plane's
#: half-extent at distance 1 (3,) each; the image size, samples per pixel and the jitter seed
Camera = namedtuple("Camera", ["position", "forward", "right", "up", "width", "height", "spp", "seed"])

#: one blob's sweep along a ray (kernels.sweep.alloc_scratch), reused ray after ray: the chords (t0, t1,
#: control values); the sweep's breakpoints, start order and active list; the composite intervals (t0,
#: t1, control values, magnitude); the inside pieces (t0, t1, F); the transitions; the clipping stack
#: (lo, hi, control values); g = F - T on an interval, and its roots (loc, rising)
SweepScratch = namedtuple("SweepScratch", ["chord_t0", "chord_t1", "chord_c", "bp", "order", "act", "iv_t0",
                                           "iv_t1", "iv_c", "iv_mag", "out_t0", "out_t1", "out_c", "roots",
                                           "st_lo", "st_hi", "st_c", "g", "loc", "rising"])

#: the pieces of every medium on one camera ray (kernels.media.alloc_ray_pieces): t0, t1, sigma_t
#: control values, medium; the interval sweep's breakpoints, start order and active list; and the
#: ray's elementary intervals (between consecutive piece ends): el_t0, el_t1, el_u0 the optical depth
#: from the ray's start to el_t0, el_S sigma_t of all media, el_sig (2P, M, C) of each
RayPieces = namedtuple("RayPieces", ["t0", "t1", "c", "medium", "bp", "order", "act", "el_t0", "el_t1", "el_u0",
                                     "el_S", "el_sig"])

#: small per-ray work vectors of the radiance kernels (kernels.raywork.alloc_node_work): light (L, 6) =
#: per light l . v, E_l T_l (r, g, b), T_l and its shadow ray's entries into the media at the current node; pos and
#: l_dir at a node; x, normal and x_off (x lifted off the surface) at a surface hit; node_w the product-integration
#: weights of a step; j_val (4, nodes) J (r, g, b) at the nodes of a step and the entries of their shadow rays
#: (kernels.single.node_topology; -1: unknown); split_u, split_h and split_depth the parts of a step still to do
#: (start, width, halvings deep); count (N_COUNTS,) what the light at the nodes cost so far on this thread
#: (kernels.lighting.COUNT_*). (The entries were a field of their own first: read through the inlined node code,
#: it held garbage, numba 0.68.1, cause not found; as j_val's fourth row they are read right.)
NodeWork = namedtuple("NodeWork", ["light", "pos", "l_dir", "x", "normal", "x_off", "node_w", "j_val",
                                   "split_u", "split_h", "split_depth", "count"])

#: everything one thread's camera rays reuse: SweepScratch (grows), RayPieces (grows), the BVH's
#: candidate list and walk stack, NodeWork
RayWork = namedtuple("RayWork", ["scratch", "pieces", "cand", "stack", "nodes"])

#: what a shadow ray alone reuses (kernels.ground): the BVH's candidate list and walk stack
ShadowWork = namedtuple("ShadowWork", ["cand", "stack"])

#: the in-scattering quadrature's state along one camera ray (kernels.single.step_in_scattering): the
#: cursor of the last node (interval k, its point s_prev, the view optical depth u_prev there), the
#: largest J (r + g + b) met on the ray so far (the scale of the tolerance), and the sweep scratch (which a
#: shadow ray may grow)
StepState = namedtuple("StepState", ["k", "s_prev", "u_prev", "j_max", "scratch"])

#: the key of a path's random numbers (kernels.sampling.sobol4, uniform): the render's seed, the pixel and
#: the path's index in it
PathKey = namedtuple("PathKey", ["seed", "pixel", "path"])

#: a path's four 3-vectors of work (kernels.multiple.ray_paths): the vertex o, the direction d, the
#: sampled next direction d_new, the light scattered at a vertex
PathVectors = namedtuple("PathVectors", ["o", "d", "d_new", "light"])

#: the camera ray's segment, traced once for all the paths that start on it (kernels.multiple): its
#: RayPieces with the elementary intervals, their number n_el and the optical depth u_total of them all
CameraSegment = namedtuple("CameraSegment", ["pieces", "n_el", "u_total"])

#: the multiple-scattering paths (kernels.multiple): the highest scattering order, the vertex from which
#: Russian roulette plays, the paths per pixel, and the first vertex reached by a tracked flight
#: (kernels.tracking; a vertex beyond max_order: every flight exact)
PathSettings = namedtuple("PathSettings", ["max_order", "rr_order", "paths", "track_from"])

#: the majorant grid of the tracked flights (kernels.tracking, docs/model.md §10.1): a box of cubic cells,
#: origin (3,), cell size, dims (3,) cells per axis (cell c = i + nx (j + ny k)); per cell sigma_max and
#: sigma_min, an upper and a lower bound of sigma_t summed over the media at every point of the cell; start
#: (cells + 1,) and items: the balls of every medium (in increasing index) whose padded support box meets
#: the cell; ball_medium (N,) the medium of each ball; inv_r2 (N,) 1 / R^2 of a sphere, 0 for an ellipsoid (a
#: sphere's u skips the frame). Outside the box sigma_t is 0.
MajorantGrid = namedtuple("MajorantGrid", ["origin", "size", "dims", "sigma_max", "sigma_min", "start", "items",
                                           "ball_medium", "inv_r2"])

#: one thread's work for tracked flights (kernels.tracking): sigma (M,) each medium's sigma_t at the last
#: point evaluated, at_vertex (M,) at the path's vertex; x (3,) the point
TrackWork = namedtuple("TrackWork", ["sigma", "at_vertex", "x"])

#: a ray's walk through a grid's cells (kernels.tracking.walk_start), scalars so that they stay in registers
#: (in arrays a flight cost 0.85 us, in scalars 0.61 us): the cell (ix, iy, iz), the step along each axis
#: (sx, sy, sz: -1, 0 or 1), where the ray leaves the cell across each axis' walls (nx, ny, nz) and the
#: distance between those walls along the ray (dx, dy, dz)
Walk = namedtuple("Walk", ["ix", "iy", "iz", "sx", "sy", "sz", "nx", "ny", "nz", "dx", "dy", "dz"])
