"""The kinds and their parameters, the constants every generated cloud shares, and the checks of
``generate``'s arguments (docs/generate.md, Parameters)."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import InputError
from ..scene.limits import MAX_BALLS

#: the threshold and kernel every generated medium uses (the field's inside is F >= T)
THRESHOLD = 0.5
KERNEL = "wyvill6"
#: weight of the base cutter, relative to T: large, so that its edge is sharp (docs/generate.md)
CUTTER_WEIGHT = 1.0e4 * THRESHOLD
#: level of the special balls in Cloud.levels
CUTTER, EROSION, FADE = -1, -2, -3
#: weight of the base-fade ball, relative to T (docs/generate.md, Flat base)
FADE_WEIGHT = -1.0 * THRESHOLD

@dataclass(frozen=True)
class Parameter:
    """A kind's parameter: default (None: computed from the others), unit and meaning, accepted range."""
    default: object
    unit: str
    doc: str
    lo: float
    hi: float
    integer: bool = False


_COMMON = {
    "levels": Parameter(6, "count", "most levels of the hierarchy: the body, then up to levels - 1 generations "
                                    "of puffs on puffs (fewer where balls runs out first)", 2, 8, True),
    "ratio": Parameter(0.55, "ratio", "radius of a puff / radius of its parent, for every level but the last "
                                     "(the last level's ratio follows from the balls left for it)", 0.2, 0.8),
    "spacing": Parameter(3.2, "ratio", "least distance between the centres of two puffs of a level / their "
                                       "visible radius (blue noise; 2 just touching, smaller overlapping)",
                         0.5, 4.0),
    "push": Parameter(1.7, "ratio", "how far each puff but the last level's stands out of the surface it "
                                    "sits on, in its own visible radii (0: centred on the surface)", -1.0, 2.0),
    "push_first": Parameter(None, "ratio", "how far the first level of puffs (the largest, on the body) stands "
                                          "out of it, in their own visible radii (default: push)", -1.0, 2.0),
    "size_spread": Parameter(4.0, "ratio", "largest / smallest puff of a level: their sizes follow a power law "
                                           "over this range (1: all alike, +-15 %)", 1.0, 30.0),
    "size_power": Parameter(2.0, "exponent", "a of the puff sizes' power law p(x) ~ x^-a within a level (larger: "
                                             "more small puffs, fewer large ones)", 0.0, 4.0),
    "depth_power": Parameter(4.0, "exponent", "Pareto exponent of how many puffs each puff carries on the next "
                                              "level (small: a few puffs carry most of the finer levels, so the "
                                              "depth of the hierarchy varies over the cloud; large: all alike)",
                             1.02, 100.0),
    "base_fade": Parameter(0.15, "ratio", "height of the layer above the base where the density thins towards "
                                         "it / the cloud's height (one wide flat ball of weight -T; 0: none)",
                           0.0, 0.6),
    "body": Parameter(None, "count", "balls of the body, level 0 (default: from the kind's shape)", 1, 4096, True),
    "aspect": Parameter(0.8, "ratio", "extent along y / extent along x", 0.1, 10.0),
    "bias": Parameter(0.6, "ratio", "upward bias of the puffs' directions (0: all directions alike; 1: "
                                    "mostly up)", -1.0, 5.0),
    "fray": Parameter(0.5, "fraction", "part of the last level set loose as thin wisps just outside the "
                                        "surface, at a lower weight", 0.0, 1.0),
    "fray_weight": Parameter(1.0, "weight", "weight of the wisps (1: as dense as a puff; a lone ball of weight "
                                             "<= T = 0.5 is never visible)", 0.55, 4.0),
    "fray_reach": Parameter(4.0, "ratio", "farthest a wisp is set out of the surface, in its own visible radii "
                                          "(from 0.9, most near 0.9: a power law)", 0.9, 10.0),
    "erosion": Parameter(0.08, "fraction", "part of the balls that are small negative balls carving dents "
                                           "between the puffs", 0.0, 0.3),
    "optical_depth": Parameter(60.0, "optical depth", "optical depth of the most opaque of five horizontal "
                                                      "rays along x through the cloud's middle (at 0.2 .. 0.8 "
                                                      "of its height): sets the suggested density.scale",
                               0.01, 1.0e4),
}
_SQUARENESS = ("exponent p of the body's footprint |x/a|^p + |y/b|^p <= 1: 2 an ellipse, larger squarer")
#: the body's shape, for the kinds built on a dome or column
_BODY = {
    "turrets": Parameter(4, "count", "rising bubbles that shape the top: the body's roof is highest over them",
                         1, 64, True),
    "turret_height": Parameter(0.45, "ratio", "how much lower the roof is between the turrets than on them "
                                              "(0: a smooth dome)", 0.0, 0.95),
    "body_radius": Parameter(0.2, "size", "largest visible radius of a ball of the body / size (of the tower's "
                                          "width for tower and cumulonimbus)", 0.02, 1.0),
    "body_cover": Parameter(1.0, "ratio", "how far apart the body's balls are: no ball's centre inside this "
                                          "times another's visible radius", 0.3, 3.0),
}


def _defaults(**values):
    """Common parameters with other defaults, for one kind."""
    return {name: Parameter(value, _COMMON[name].unit, _COMMON[name].doc, _COMMON[name].lo, _COMMON[name].hi,
                            _COMMON[name].integer) for name, value in values.items()}


#: a tall column of puffs as loose as the cumulus's reads as a foam: its puffs stay closer together
_COLUMN = _defaults(push=1.2, spacing=2.6, fray=0.35, erosion=0.04)
#: per kind: its own parameters and its defaults of the common ones (units: "size" is a multiple of size)
PARAMETERS = {
    "cumulus": {
        **_COMMON,
        # the largest puffs sit on the body, the finer ones stand out of them: rounded masses with a rough,
        # frayed outline (a perimeter dimension of ~1.3), where puffs all standing out as far read as a foam;
        # a narrower spread of sizes within a level keeps the small puffs' detail from being swallowed; the
        # core is denser with the first puffs on the body, so the same density takes a higher optical depth
        # along its most opaque ray (at 60 the cloud would be half as dense as before, misty)
        **_defaults(push=2.0, size_spread=2.0, optical_depth=120.0),
        "push_first": Parameter(1.0, "ratio", _COMMON["push_first"].doc, -1.0, 2.0),
        "height_ratio": Parameter(0.55, "size", "visible height of the cloud / size: ~0.3 humilis, ~0.6 "
                                                "mediocris, ~1 congestus", 0.1, 4.0),
        "squareness": Parameter(2.4, "exponent", _SQUARENESS, 1.5, 8.0),
        **_BODY,
    },
    "stratocumulus": {
        **_COMMON,
        "levels": Parameter(3, "count", _COMMON["levels"].doc, 2, 8, True),
        "aspect": Parameter(0.6, "ratio", _COMMON["aspect"].doc, 0.1, 10.0),
        "bias": Parameter(1.2, "ratio", _COMMON["bias"].doc, -1.0, 5.0),
        "optical_depth": Parameter(80.0, "optical depth", _COMMON["optical_depth"].doc, 0.01, 1.0e4),
        # a deck's cells are lumps, not cauliflowers: its puffs stay close to the surface, and it is too thin
        # for a fade layer
        **_defaults(push=0.8, spacing=2.2, fray=0.25, fray_weight=0.75, fray_reach=0.9, base_fade=0.0, erosion=0.02),
        "thickness": Parameter(0.12, "size", "thickness of the deck (its visible height) / size", 0.01, 1.0),
        "cells": Parameter(9, "count", "cells along x (along y: cells x aspect)", 1, 64, True),
        "coverage": Parameter(0.85, "fraction", "part of the cells present (the rest are the gaps, chosen by "
                                               "a smooth random field)", 0.05, 1.0),
        "flatness": Parameter(0.55, "ratio", "vertical / horizontal radius of the puffs", 0.1, 1.0),
    },
    "tower": {
        **_COMMON,
        **_COLUMN,
        "height_ratio": Parameter(1.6, "size", "visible height of the tower / size (its width)", 0.3, 6.0),
        "squareness": Parameter(2.6, "exponent", _SQUARENESS, 1.5, 8.0),
        "lean": Parameter(0.12, "ratio", "horizontal shift of the top along x / height (wind shear)", -1.0, 1.0),
        "taper": Parameter(0.3, "ratio", "how much narrower the column is at the top than at the base", 0.0, 0.9),
        **_BODY,
    },
    "cumulonimbus": {
        **_COMMON,
        **_COLUMN,
        "height_ratio": Parameter(1.0, "size", "visible height (the anvil's top) / size (the anvil's width)",
                                  0.3, 6.0),
        "squareness": Parameter(2.6, "exponent", _SQUARENESS, 1.5, 8.0),
        "lean": Parameter(0.08, "ratio", "horizontal shift of the top along x / height (wind shear)", -1.0, 1.0),
        "taper": Parameter(0.1, "ratio", "how much narrower the column is at the top than at the base", 0.0, 0.9),
        **_BODY,
        "tower_width": Parameter(0.45, "size", "width of the tower below the anvil / size", 0.1, 1.0),
        "anvil_thickness": Parameter(0.1, "size", "thickness of the anvil / size", 0.02, 1.0),
    },
}
KINDS = tuple(PARAMETERS)
#: the fewest balls a generated cloud may have (body, cutter)
MIN_BALLS = 8


def _check_params(kind, params):
    spec = PARAMETERS[kind]
    out = {}
    for name, value in params.items():
        if name not in spec:
            raise InputError(f"{name}: not a parameter of {kind}; expected one of {', '.join(sorted(spec))}")
        par = spec[name]
        if value is None and par.default is None:
            out[name] = None
            continue
        if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, float, np.integer, np.floating)):
            raise InputError(f"{name}: expected a number, got {value!r}"[:200])
        if par.integer and float(value) != int(value):
            raise InputError(f"{name}: expected an integer, got {value!r}")
        if not (par.lo <= float(value) <= par.hi):  # nan fails too
            raise InputError(f"{name}: expected a number from {par.lo:g} to {par.hi:g}, got {value!r}")
        out[name] = int(value) if par.integer else float(value)
    return {name: out.get(name, par.default) for name, par in spec.items()}


def _check_args(kind, balls, seed, size):
    if not isinstance(kind, str) or kind not in PARAMETERS:
        raise InputError(f"kind: expected one of {', '.join(KINDS)}, got {kind!r}"[:200])
    if isinstance(balls, (bool, np.bool_)) or not isinstance(balls, (int, np.integer)) \
            or not MIN_BALLS <= balls <= MAX_BALLS:
        raise InputError(f"balls: expected an integer from {MIN_BALLS} to {MAX_BALLS}, got {balls!r}"[:200])
    if isinstance(seed, (bool, np.bool_)) or not isinstance(seed, (int, np.integer)) or not 0 <= seed < 2 ** 63:
        raise InputError(f"seed: expected an integer from 0 to 2**63 - 1, got {seed!r}"[:200])
    if isinstance(size, (bool, np.bool_)) or not isinstance(size, (int, float, np.integer, np.floating)) \
            or not 1e-30 <= float(size) <= 1e30:
        raise InputError(f"size: expected a number from 1e-30 to 1e30 (scene units), got {size!r}"[:200])
    return int(balls), int(seed), float(size)


def parse_param(text, label="param"):
    """NAME=VALUE -> (name, int or float), or InputError naming ``label``."""
    name, sep, value = str(text).partition("=")
    name, value = name.strip(), value.strip()
    if not sep or not name or not value:
        raise InputError(f"{label} {text}: expected NAME=VALUE, e.g. height_ratio=1.0")
    try:
        number = int(value)
    except ValueError:
        try:
            number = float(value)
        except ValueError:
            raise InputError(f"{label} {text}: expected a number after '=', got {value!r}"[:200]) from None
    return name, number
