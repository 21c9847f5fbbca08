"""Lights (docs/model.md §5): every light kind's scene keys, dataclass, reader and bounds, in one place.

A kind is a frozen dataclass with ``KIND`` (its name in kernels.kinds.LIGHTS, where its id is) and ``KEYS``
(its scene keys besides ``type`` and ``color``), and three methods the floors above ask instead of testing
the class: ``record()`` the (vector, rgb) that kernels.records.Lights holds for it, ``irradiance_at(d)`` the
largest irradiance it gives at distance d (the numeric domain's bound), and ``place()`` its position or
None. ``casts_map``: whether ``render.shadows: map`` draws it a shadow map (directional lights). Adding a
kind: a class and its reader here, its id in kernels.kinds and its evaluation in kernels.lighting.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import numpy as np

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


#: light type -> its class
LIGHTS = {cls.KIND: cls for cls in (DirectionalLight, PointLight)}
assert tuple(LIGHTS) == tuple(LIGHT_IDS), "every light kind of the kernels has its class here"


def read_light(ctx, path, raw, colourspace):
    """The light of the mapping ``raw`` at key path ``path``."""
    n = Node(ctx, path, raw, ("type", "color") + sum((c.KEYS for c in LIGHTS.values()), ()))
    kind = n.choice("type", tuple(LIGHTS))
    cls = LIGHTS[kind]
    n.only(("type", "color") + cls.KEYS)
    color = n.colour("color", colourspace, [1.0, 1.0, 1.0])
    with np.errstate(over="ignore"):
        value = n.number(cls.KEYS[1], 1.0, **_NON_NEGATIVE) * color
    return cls.read(n, value)
