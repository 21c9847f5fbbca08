"""Lights (docs/model.md §5): every light kind's scene keys, dataclass, reader and bounds, in one place.

A kind is a frozen dataclass with ``KIND`` (its name in kernels.kinds.LIGHTS, where its id is) and ``KEYS``
(its scene keys besides ``type`` and ``color``), and three methods the floors above ask instead of testing
the class: ``record()`` the (vector, rgb) that kernels.records.Lights holds for it, ``irradiance_at(d)`` the
largest irradiance it gives at distance d (the numeric domain's bound), and ``place()`` its position or
None. ``casts_map``: whether ``render.shadows: map`` draws it a shadow map (directional lights). Adding a
kind: a class and its reader here, its id in kernels.kinds and its evaluation in kernels.lighting.

A scene's ``type`` names a *reader* (``READERS``): each kind's own, and ``sun``, another way of reading a
directional light: given by its elevation, azimuth and aerosols, its colour and irradiance follow from the
atmosphere (cloudmeta.scene.atmosphere, docs/atmosphere.md). It is a ``SunLight``, a DirectionalLight that
keeps its ``Sun`` for the sky (``background: sky``); the kernels see a directional light.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from . import atmosphere as atm
from . import limits as lim
from ..kernels.kinds import LIGHTS as LIGHT_IDS
from .document import Node, fmt_numbers, frozen_array

_NON_NEGATIVE = dict(check=lambda v: v >= 0, expect="a finite number >= 0")
_NONZERO_VECTOR = dict(check=lambda v: np.any(v != 0), expect="a list of 3 finite numbers, not all 0")


def unit(v):
    """v / |v| without overflow or underflow: scaled by its largest component first."""
    v = np.asarray(v, dtype=np.float64)
    v = v / np.max(np.abs(v))
    return v / np.linalg.norm(v)


@dataclass(frozen=True, eq=False)
class DirectionalLight:
    KIND: ClassVar[str] = "directional"
    KEYS: ClassVar[tuple] = ("direction", "irradiance")
    casts_map: ClassVar[bool] = True
    direction: np.ndarray   #: unit vector towards the light
    irradiance: np.ndarray  #: (3,) irradiance x color

    def record(self):
        return self.direction, self.irradiance

    def irradiance_at(self, distance):
        return float(np.max(self.irradiance))

    def place(self):
        return None

    @classmethod
    def read(cls, n, value):
        """The light of Node ``n``, whose irradiance x color is ``value``."""
        if not np.max(value) <= lim.MAX_RADIANCE:
            n.fail("irradiance", f"expected irradiance x color <= {lim.MAX_RADIANCE:g} (README: Limits), got "
                                 f"{fmt_numbers(value)}")
        return cls(frozen_array(unit(n.vector("direction", bounded=False, **_NONZERO_VECTOR))), frozen_array(value))


@dataclass(frozen=True, eq=False)
class PointLight:
    KIND: ClassVar[str] = "point"
    KEYS: ClassVar[tuple] = ("position", "intensity")
    casts_map: ClassVar[bool] = False
    position: np.ndarray
    intensity: np.ndarray   #: (3,) intensity x color

    def record(self):
        return self.position, self.intensity

    def irradiance_at(self, distance):
        return float(np.max(self.intensity)) / distance ** 2

    def place(self):
        return self.position

    @classmethod
    def read(cls, n, value):
        """The light of Node ``n``, whose intensity x color is ``value``."""
        if not np.all(np.isfinite(value)):
            n.fail("intensity", f"expected intensity x color to be finite, got {fmt_numbers(value)}")
        return cls(n.vector("position"), frozen_array(value))


@dataclass(frozen=True, eq=False)
class SunLight(DirectionalLight):
    """A directional light read from ``type: sun``: its direction, colour and irradiance follow from ``sun``
    (``irradiance`` = sun.irradiance x sun_rgb). KIND stays ``directional``: the kernels need nothing new."""
    sun: atm.Sun = None


#: light type -> its class
LIGHTS = {cls.KIND: cls for cls in (DirectionalLight, PointLight)}
assert tuple(LIGHTS) == tuple(LIGHT_IDS), "every light kind of the kernels has its class here"

#: a sun's keys besides ``type`` (the same in ``background: {sky: {...}}``)
SUN_KEYS = ("elevation", "azimuth", "irradiance", "turbidity", "aerosol_depth")
#: a sun's ``irradiance`` when not given: the extraterrestrial luminance the scenes' suns have
DEFAULT_SUN_IRRADIANCE = 16.0


def read_sun(n):
    """The ``Sun`` of the keys SUN_KEYS of Node ``n`` (its other keys are the caller's to check)."""
    lo, hi = atm.ELEVATION_RANGE
    elevation = n.number("elevation", check=lambda v: lo <= v <= hi,
                         expect=f"the sun's elevation in degrees, from {lo:g} (the horizon) to {hi:g} (the zenith)")
    azimuth = n.number("azimuth", 0.0, check=lambda v: -360 <= v <= 360,
                       expect="a compass azimuth in degrees within +-360 (0: towards +y, north; 90: towards +x, east)")
    irradiance = n.number("irradiance", DEFAULT_SUN_IRRADIANCE, **_NON_NEGATIVE)
    if n.has("turbidity") and n.has("aerosol_depth"):
        n.fail("aerosol_depth", "give turbidity or aerosol_depth, not both (both set the aerosols)")
    if n.has("turbidity"):
        lo, hi = atm.TURBIDITY_RANGE
        turbidity = n.number("turbidity", check=lambda v: lo <= v <= hi,
                             expect=f"a turbidity from {lo:g} (pure air) to {hi:g} (Preetham et al. 1999)")
        aerosol_depth = atm.turbidity_to_aerosol_depth(turbidity)
    else:
        lo, hi = atm.AEROSOL_DEPTH_RANGE
        aerosol_depth = n.number("aerosol_depth", atm.DEFAULT_AEROSOL_DEPTH, check=lambda v: lo <= v <= hi,
                                 expect=f"an aerosol optical depth at 550 nm from {lo:g} to {hi:g}")
    return atm.Sun(elevation, azimuth, aerosol_depth, irradiance)


def _read_sun_light(n, colourspace):
    if n.has("color"):
        n.fail("color", "not allowed on a sun: its colour follows from the atmosphere (elevation, turbidity or "
                        "aerosol_depth; docs/atmosphere.md); use type: directional for a colour of your own")
    n.only(("type",) + SUN_KEYS)
    sun = read_sun(n)
    with np.errstate(over="ignore"):
        value = sun.irradiance * sun.rgb(colourspace)
    if not np.max(value) <= lim.MAX_RADIANCE:
        n.fail("irradiance", f"expected irradiance x the sun's colour <= {lim.MAX_RADIANCE:g} (README: Limits), "
                             f"got {fmt_numbers(value)}")
    return SunLight(frozen_array(unit(sun.direction())), frozen_array(value), sun)


def _reader(cls):
    def read(n, colourspace):
        n.only(("type", "color") + cls.KEYS)
        color = n.colour("color", colourspace, [1.0, 1.0, 1.0])
        with np.errstate(over="ignore"):
            value = n.number(cls.KEYS[1], 1.0, **_NON_NEGATIVE) * color
        return cls.read(n, value)
    return read


#: light type as a scene names it -> the reader of its mapping: each kind's own, and ``sun``
READERS = {**{kind: _reader(cls) for kind, cls in LIGHTS.items()}, "sun": _read_sun_light}
_ALL_KEYS = tuple(dict.fromkeys(("type", "color") + sum((c.KEYS for c in LIGHTS.values()), ()) + SUN_KEYS))


def read_light(ctx, path, raw, colourspace):
    """The light of the mapping ``raw`` at key path ``path``."""
    n = Node(ctx, path, raw, _ALL_KEYS)
    return READERS[n.choice("type", tuple(READERS))](n, colourspace)
