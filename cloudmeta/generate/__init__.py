"""Procedural clouds from metaballs, deterministic by seed (docs/generate.md).

``generate(kind, balls=3000, seed=1, size=10.0, **params)`` builds a ``Cloud``: an (N, 10) array of
ellipsoidal metaballs (the balls-file columns ``x,y,z,rx,ry,rz,ax,ay,az,weight``) and the medium settings
that suit it; ``write_scene(cloud, "scene.yaml")`` writes a scene (YAML) and its balls file (CSV) beside it.

Every kind is built the same way, hierarchically, for the ``wyvill6`` kernel and the threshold T = 1/2,
in units of size (everything is scaled at the end):

1. **Body** (level 0): a handful of large balls that fill the kind's envelope (a dome with turrets, a
   tapering column, a deck of cells, a column under an anvil), each as large as the envelope allows
   there, none centred inside another (so that their rounded tops show).
2. **Puffs** (levels 1, 2, ...): every puff of level k + 1 sits on the *surface* F = T of the levels
   0 .. k, on the exposed part of a level-k parent, standing ``push`` of its own visible radius out of it
   (half that on the last level), and no closer than ``spacing`` visible radii to another puff of its
   level (blue noise, placed by octave of size, largest first): puffs on puffs on puffs, a cauliflower.
   Sizes follow a power law: a level's radii are ``ratio`` times its parents' mean times a factor drawn
   from p(x) ~ x^-size_power over a range of ``size_spread``, so the levels overlap in size and the
   sizes spread continuously. How many children a puff carries is drawn from a Pareto law
   (``depth_power``), so the depth of the hierarchy varies over the cloud. Each level gets as many puffs
   as cover the exposed surface of the one below (its area is sampled); the last level takes the balls
   left, its ratio following from their number, so more balls give finer detail, not a crowd. A spot on a
   parent that lies buried under other balls is never used: the detail stays on the surface and the
   interior is a few big balls (a ray meets few balls).
3. **Frayed edges**: a fraction ``fray`` of the last level is set loose outside the surface (from 0.9 to
   ``fray_reach`` of their visible radius, most near the surface) at weight ``fray_weight``: small wisps
   and fragments whose excess density is low, so the edge fades; a fraction ``erosion`` of the balls are
   small negative balls that carve dents between the puffs.
4. **Size and height**: the cloud is scaled so that its visible extent along x is ``size`` exactly, centred
   on x = y = 0, then stretched along z to the height asked for (an affine map of the whole field).
5. **Flat base** at z = 0 (the condensation level): one wide, flat ball of large negative weight (the
   *cutter*) lies under z = 0 and cuts every positive ball there, so that F < T everywhere below z = 0
   and the cloud's underside is flat (within ~1 % of size above z = 0). No positive ball reaches further
   than ``Cloud.depth`` below z = 0, and the cutter overwhelms all of them there. Above it, one more wide,
   flat ball of weight -T centred on z = 0 (the *fade*) lowers F over the lowest ``base_fade`` of the
   cloud's height, so the density thins towards the base.

Only numpy is used, vectorised over the balls of a level: placing puffs reads the field of the levels so
far from a regular grid (each ball added to the grid points of its support), and the exact field
(``Cloud.field``) finds each query's balls through a grid of cells.
Determinism: the same (kind, balls, seed, size, params) give the same array, bit for bit, on one platform
and numpy version (numpy's PCG64 and its normal and uniform draws are platform-independent; only the
last bit of libm's sin and cos could differ between platforms).

The package, by job: ``params`` (the kinds, their parameters, the argument checks), ``field`` (the field
of a set of balls in numpy), ``shapes`` (the kinds' bodies), ``puffs`` (puffs on the exposed surface,
blue-noise spacing), ``cutter`` (the flat base), ``cloud`` (``generate`` and the ``Cloud`` it returns) and
``writer`` (the scene and its balls file).
"""
from .cloud import Cloud, generate
from .field import iso_u
from .params import (CUTTER, CUTTER_WEIGHT, EROSION, FADE, FADE_WEIGHT, KERNEL, KINDS, MIN_BALLS, PARAMETERS,
                     THRESHOLD, Parameter, parse_param)
from .writer import COLUMNS, MARK, check_scene_paths, csv_text, default_scene_settings, scene_text, write_scene

__all__ = ["KINDS", "PARAMETERS", "Parameter", "Cloud", "generate", "write_scene", "check_scene_paths",
           "default_scene_settings", "scene_text", "csv_text", "parse_param", "iso_u", "THRESHOLD", "KERNEL",
           "COLUMNS", "MARK", "CUTTER", "CUTTER_WEIGHT", "EROSION", "FADE", "FADE_WEIGHT", "MIN_BALLS"]
