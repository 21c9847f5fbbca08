"""The limits of what cloudmeta accepts, in one place (README.md "Limits", docs/model_notes.md "Numeric domain").

Sizes bound the work and memory of a render so that a typo fails in a second with a clear message instead
of running for hours or being killed for memory. The numeric domain keeps every value where the kernels'
tolerances hold (docs/model_notes.md): lengths relative to the scene's bounding-box diagonal L, weights
relative to the threshold, and everything far from the ends of the double and float32 ranges.
"""
from __future__ import annotations

import os

# --- sizes ----------------------------------------------------------------------------------------
MAX_SIDE = 16384               #: image.width, image.height
MAX_PIXELS = 2 ** 26           #: width x height (8192 x 8192)
MAX_SPP = 65536                #: image.spp, render.ms_spp
MAX_ORDER = 10 ** 9            #: render.max_order (nothing is sized by it; albedo-1 furnaces need ~1e5)
MAX_OCTAVES = 64               #: render.octaves.count (each octave is a pow and a phase per node and light)
MAX_GRID_CELLS = 128           #: render.grid.cells, along the longest side (128^3 x 27 doubles: 0.45 GB a copy)
MAX_PHOTONS = 2 ** 32          #: render.grid.photons (the quasi-random index is 32 bits)
MAX_SHARED_STRIDE = 64         #: render.shared.stride, pixels between sample rays (a power of 2)
MAX_SHARED_TAILS = 2 ** 24     #: render.shared.tails, per sample ray
MAX_SAMPLES = 2 ** 32          #: width x height x spp (a 4K image at 512 spp)
MAX_SHADOW_MAP = 8192          #: render.shadow_map, texels per side
MAX_STEPS_PER_RAY = 1e6        #: L / render.max_length
MIN_MAX_TAU = 1e-4             #: render.max_tau
MIN_MAX_ANGLE = 1e-4           #: render.max_angle, radians
ROOT_TOLERANCE_RANGE = (1e-12, 1e-3)  #: render.root_tolerance, relative to L
MAX_EXPOSURE = 64.0            #: |output.exposure| and |--exposure|, stops
MAX_BALLS = 2 ** 22            #: balls of one medium or surface
MAX_SCENE_BYTES = 16 * 2 ** 20   #: a scene's YAML file (larger ball sets belong in a balls_file)
MAX_BALLS_FILE_BYTES = 512 * 2 ** 20  #: one balls_file
MAX_CSV_LINE = 4096            #: characters of one line of a balls_file
MAX_YAML_NODES = 2_000_000     #: YAML nodes of a scene, every alias expanded
MAX_YAML_DEPTH = 64            #: nesting of YAML lists and mappings
MEMORY_FRACTION = 0.75         #: of the machine's physical memory that one render may need

# --- numeric domain -------------------------------------------------------------------------------
LENGTH_RANGE = (1e-100, 1e100)  #: any length or coordinate, and L itself
MAX_OFFSET = 1e6               #: |coordinate| / L (centres, camera, point lights)
MIN_RADIUS_TOLERANCES = 1000   #: radius / (root tolerance x L): 1e-6 of L at the default 1e-9
MAX_WEIGHT = 1e6               #: |weight| / threshold
THRESHOLD_RANGE = (1e-100, 1e100)
MAX_BLOBBINESS = 1000.0        #: b of the blinn kernel (e^-1000 is 0 in double precision already)
MAX_TAU_BOUND = 1e9            #: scale x sum |weight| x L, a bound on any ray's optical depth
MAX_RADIANCE = 1e30            #: any radiance the scene can make (float32 holds 3.4e38)
MIN_FOV = 1e-3                 #: degrees; below, neighbouring pixels' rays round to one direction
MAX_FOV = 179.9

# bytes a render needs per pixel: the float64 RGBA image, the depth buffer, the float32 copy, and the PNG
# and EXR encodings (float64 temporaries of colour-science, float32 channels)
BYTES_PER_PIXEL = 32 + 8 + 16 + 3 * 8 * 3 + 16 + 3
#: per shadow-map texel: 4 pieces of (t0, t1, 7 control values, cum, reach) float64 reserved, and counts
BYTES_PER_TEXEL = 4 * 8 * (2 + 7 + 2) + 16
#: per ball: centre, radii, rotation, frame, bounds, weight, the BVH and the packed copies of the render
BYTES_PER_BALL = 2 * (24 + 24 + 72 + 72 + 48 + 8) + 200


def physical_memory():
    """Bytes of physical memory of this machine, or None where the system does not say."""
    try:
        return os.sysconf("SC_PHYS_PAGES") * os.sysconf("SC_PAGE_SIZE")
    except (ValueError, OSError, AttributeError):
        return None


def render_memory(width, height, n_balls, shadow_texels):
    """An estimate of the bytes a render needs (the image buffers, the balls, the shadow maps)."""
    return (width * height * BYTES_PER_PIXEL + n_balls * BYTES_PER_BALL + shadow_texels * BYTES_PER_TEXEL
            + 64 * 2 ** 20)


def gib(n_bytes):
    return f"{n_bytes / 2 ** 30:.1f} GiB"

#: the smallest target relative RMSE of ``render.error`` (the reference preset's own error is ~1e-7)
MIN_ERROR_TARGET = 1e-6
