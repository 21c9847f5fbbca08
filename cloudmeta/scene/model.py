"""The validated scene as frozen dataclasses (docs/model.md §9): what cloudmeta.scene.loader returns and
every floor above reads. Nothing here validates: the loader builds these only from checked values."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .blob import Blob, length_scale
from .colour import DEFAULT_COLOURSPACE
from .vocabulary import OCTAVES, ShadowMode
from .lights import DirectionalLight, PointLight, SunLight  # noqa: F401 (the light classes, part of the schema)


def frozen_array(value):
    arr = np.array(value, dtype=np.float64)
    arr.setflags(write=False)
    return arr


@dataclass(frozen=True)
class ImageSettings:
    width: int
    height: int
    spp: int


@dataclass(frozen=True, eq=False)
class Camera:
    position: np.ndarray
    look_at: np.ndarray
    up: np.ndarray
    fov: float  #: vertical field of view, degrees


@dataclass(frozen=True)
class Density:
    mode: str = "field"     #: field | excess | uniform (docs/model.md §4)
    scale: float = 1.0      #: sigma_t = scale * rho


@dataclass(frozen=True)
class Phase:
    type: str = "isotropic"  #: isotropic | hg | double_hg | rayleigh
    g: float = 0.0           #: hg
    g1: float = 0.0          #: double_hg: w HG(g1) + (1 - w) HG(g2)
    g2: float = 0.0
    w: float = 1.0


@dataclass(frozen=True, eq=False)
class Medium:
    name: str
    blob: Blob
    density: Density
    albedo: float
    phase: Phase


@dataclass(frozen=True, eq=False)
class Surface:
    name: str
    blob: Blob
    color: np.ndarray


@dataclass(frozen=True)
class RenderSettings:
    """``render:`` as the scene gives it (None: the preset's value). What a frame renders with, every key
    resolved against the preset once, is cloudmeta.renderer.quality.FrameSettings."""
    quality: str = "default"
    tolerance: float | None = None  #: quadrature: J's estimated error per step, relative to its largest value
    max_tau: float | None = None
    max_length: float | None = None
    max_angle: float | None = None  #: radians, seen from a point light
    cutoff: float | None = None
    root_tolerance: float | None = None  #: relative to the scene's bounding-box diagonal
    shadows: ShadowMode = ShadowMode.EXACT  #: a str too: replace(render, shadows="map") is read the same
    shadow_map: int | None = None
    colourspace: str = DEFAULT_COLOURSPACE
    scattering: str = "single"  #: single | multiple | approximate (README: multiple scattering)
    method: str = "octaves"     #: approximate: the method (docs/approximate.md)
    octaves: tuple = OCTAVES    #: approximate, octaves: (count, a, b, c)
    grid: tuple | None = None   #: approximate, grid: (cells, photons, deposit), None: the preset's, flights
    shared: tuple | None = None  #: approximate, shared: (stride, tails, cache), None (or a None in it): the preset's
    max_order: int = 64         #: multiple: the highest scattering order
    ms_spp: int | None = None   #: multiple: Monte Carlo paths per pixel; None: planned to the preset's target
    track_from: int = 2         #: multiple: the first vertex reached by a tracked flight (docs/model.md §10.1)
    error: float | None = None  #: a target relative RMSE: the quadrature is refined until the estimate meets it
    calibrate: bool = True      #: single, approximate: the preset's settings calibrated on the pilot (renderer.pilot)


@dataclass(frozen=True)
class OutputSettings:
    path: str | None = None  #: EXR, absolute (resolved against the YAML's folder)
    png: str | None = None
    #: the PNG's picture (cloudmeta.api.display, docs/display.md); None: the display's default (aces: scene
    #: and auto; raw: none and 0 stops)
    exposure: float | str | None = None  #: stops or "auto"
    display: str = "aces"               #: aces | raw
    white_balance: str | None = None    #: scene | none | a CIE illuminant's name


@dataclass(frozen=True, eq=False)
class Ground:
    """The sky's ground placed in the scene, so that the clouds shade it (``background: {sky: {ground_height}}``,
    docs/atmosphere.md): the plane z = ``height``, and what the sun alone gives it as seen from the camera."""
    height: float        #: z of the flat ground, below the camera
    sun: np.ndarray      #: (181, 3) read-only: the sky table's sunlit part of the ground (rows as Scene.sky's)
    direction: np.ndarray  #: (3,) unit vector towards the sun


@dataclass(frozen=True, eq=False)
class Scene:
    path: str
    image: ImageSettings
    camera: Camera
    background: np.ndarray
    ambient: np.ndarray | None
    lights: tuple
    media: tuple
    surfaces: tuple
    render: RenderSettings
    output: OutputSettings
    inputs: tuple = ()  #: absolute paths of the files the scene was read from (the YAML, every balls_file)
    merged_balls: int = 0  #: identical balls (same centre, radii, rotation) merged into one at load
    #: ``background: sky``: (181, 3) read-only linear RGB, the sky's radiance at view elevations -90 .. 90
    #: degrees, 1 degree apart (row i: elevation i - 90, z up), the same at every azimuth; None otherwise.
    #: ``background`` is then its mean over the sphere (docs/atmosphere.md)
    sky: np.ndarray | None = None
    #: ``background: {sky: {ground_height}}``: the ground as a plane that the media shade; None otherwise
    ground: Ground | None = None

    def bbox(self):
        """(lo, hi) of the union of every medium's and surface's balls."""
        boxes = [thing.blob.bbox for thing in self.media + self.surfaces]
        return (np.min([lo for lo, _ in boxes], axis=0), np.max([hi for _, hi in boxes], axis=0))

    def length_scale(self):
        """The length root tolerances and quadrature steps are relative to (cloudmeta.scene.blob.length_scale
        of every ball of the media and surfaces): the bounding-box diagonal, unless geometry lies far away."""
        scale = self.__dict__.get("_length_scale")
        if scale is None:  # once per scene: the load's domain check and every render ask for it
            scale = length_scale(np.concatenate([thing.blob.bounds for thing in self.media + self.surfaces]))
            object.__setattr__(self, "_length_scale", scale)  # a cache, not a field: replace() drops it
        return scale
