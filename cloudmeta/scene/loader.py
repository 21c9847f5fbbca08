"""Scene files: YAML in, a validated, immutable ``Scene`` out (docs/model.md §9).

Everything is checked here, once, so that the renderer and the kernels never meet a bad value. Every
error is a ``SceneError`` naming the file, the key path (``media[0].balls[12].radius``) and what was
expected; unknown keys are errors, at every level. A half-valid scene is never returned.

The section readers are here; the document layer (safe YAML, typed getters) is cloudmeta.scene.document,
the balls cloudmeta.scene.balls, the numeric domain cloudmeta.scene.feasibility, keyframes
cloudmeta.scene.animation.
"""
from __future__ import annotations

from dataclasses import fields

import numpy as np

from ..errors import InputError
from . import limits as lim
from .animation import naming_frame, resolve_frame
from .balls import read_blob
from .colour import DEFAULT_COLOURSPACE, _is_illuminant as is_illuminant, colourspace_name
from .document import Context, Node, describe, fmt_numbers, frozen_array, is_finite_number, read_yaml
from .feasibility import check_domain
from .model import Camera, Density, Ground, ImageSettings, Medium, OutputSettings, Phase, RenderSettings, Scene, Surface
from .atmosphere import DEFAULT_GROUND_ALBEDO, ground_albedo_of, sky_mean
from .lights import SUN_KEYS, SunLight, read_light, read_sun, unit
from .vocabulary import (APPROXIMATE_METHODS, AUTO_EXPOSURE, DENSITY_MODES, DISPLAYS, GRID_DEPOSITS, OCTAVES,
                         PHASE_PARAMS, QUALITIES, SCATTERING_MODES, SHADOW_MODES, WHITE_BALANCE_WORDS, ShadowMode)

#: an up vector closer than this (sine of the angle) to the view direction is refused
_PARALLEL_SINE = 1e-6


_POSITIVE = dict(check=lambda v: v > 0, expect="a finite number > 0")
_NON_NEGATIVE = dict(check=lambda v: v >= 0, expect="a finite number >= 0")
_NONZERO_VECTOR = dict(check=lambda v: np.any(v != 0), expect="a list of 3 finite numbers, not all 0")


def _int_range(lo, hi):
    return dict(check=lambda v: lo <= v <= hi, expect=f"an integer >= {lo} and <= {hi} (README: Limits)")



def _image(top, width, height, spp):
    n = top.node("image", ("width", "height", "spp"))
    # overrides replace the file's values and are validated the same way
    overrides = {k: v for k, v in dict(width=width, height=height, spp=spp).items() if v is not None}
    n = Node(n.ctx, n.path, dict(n.data, **overrides))
    w = n.integer("width", **_int_range(1, lim.MAX_SIDE))
    h = n.integer("height", **_int_range(1, lim.MAX_SIDE))
    spp = n.integer("spp", 1, **_int_range(1, lim.MAX_SPP))
    if w * h > lim.MAX_PIXELS:
        n.fail("height", f"expected at most {lim.MAX_PIXELS} pixels (README: Limits), got {w} x {h} = {w * h}")
    if w * h * spp > lim.MAX_SAMPLES:
        n.fail("spp", f"expected at most {lim.MAX_SAMPLES} samples in all (README: Limits), "
                      f"got {w} x {h} x {spp} = {w * h * spp}")
    return ImageSettings(w, h, spp)


def _camera(top):
    n = top.node("camera", ("position", "look_at", "up", "fov"))
    position, look_at = n.vector("position"), n.vector("look_at")
    view = look_at - position  # finite: both within +-1e100
    if not np.any(view != 0):
        n.fail("look_at", f"expected a point other than camera.position, got {look_at.tolist()} for both")
    if np.abs(view).max() < lim.LENGTH_RANGE[0]:
        n.fail("look_at", f"expected a point at least {lim.LENGTH_RANGE[0]:g} from camera.position, got "
                          f"{fmt_numbers(look_at)} (the camera is at {fmt_numbers(position)})")
    up = n.vector("up", [0.0, 0.0, 1.0], bounded=False, **_NONZERO_VECTOR)
    sine = np.linalg.norm(np.cross(unit(view), unit(up)))
    if sine < _PARALLEL_SINE:
        n.fail("up", f"expected a vector not parallel to the view direction look_at - position = {view.tolist()}, "
                     f"got {up.tolist()}")
    fov = n.number("fov", 40.0, check=lambda v: lim.MIN_FOV <= v <= lim.MAX_FOV,
                   expect=f"a vertical angle in degrees in (0, 180), from {lim.MIN_FOV:g} to {lim.MAX_FOV:g}")
    return Camera(position, look_at, frozen_array(unit(up)), fov)  # unit: the renderer's cross products stay finite


def _phase(n):
    p = n.node("phase", ("type",) + sum(PHASE_PARAMS.values(), ()), {})
    kind = p.choice("type", tuple(PHASE_PARAMS), "isotropic")
    p.only(("type",) + PHASE_PARAMS[kind])
    g = dict(check=lambda v: -1 < v < 1, expect="an asymmetry in (-1, 1)")
    if kind == "hg":
        return Phase(kind, g=p.number("g", **g))
    if kind == "double_hg":
        return Phase(kind, g1=p.number("g1", **g), g2=p.number("g2", **g),
                     w=p.number("w", check=lambda v: 0 <= v <= 1, expect="a weight in [0, 1]"))
    return Phase(kind)



def _named(ctx, items, prefix, build):
    """Build each item of a media / surfaces list; names default to ``{prefix}{i}`` and must be unique."""
    out, seen = [], {}
    for i, (path, raw) in enumerate(items):
        thing = build(path, raw, f"{prefix}{i}")
        if thing.name in seen:
            ctx.fail(f"{path}.name", f"expected a unique name, {thing.name!r} is also {seen[thing.name]}")
        seen[thing.name] = path
        out.append(thing)
    return tuple(out)


_BLOB_KEYS = ("name", "kernel", "threshold", "blobbiness", "balls", "balls_file")


def _medium(ctx, path, raw, default_name):
    n = Node(ctx, path, raw, _BLOB_KEYS + ("density", "albedo", "phase"))
    name = n.string("name", default_name)
    d = n.node("density", ("mode", "scale"), {})
    density = Density(d.choice("mode", DENSITY_MODES, "field"), d.number("scale", 1.0, **_NON_NEGATIVE))
    albedo = n.number("albedo", 1.0, check=lambda v: 0 <= v <= 1, expect="an albedo in [0, 1]")
    return Medium(name, read_blob(n, "medium"), density, albedo, _phase(n))


def _surface(ctx, path, raw, default_name, colourspace):
    n = Node(ctx, path, raw, _BLOB_KEYS + ("color",))
    name = n.string("name", default_name)
    return Surface(name, read_blob(n, "surface"), n.colour("color", colourspace, [1.0, 1.0, 1.0]))


def _render(top, overrides=None):
    n = top.node("render", tuple(f.name for f in fields(RenderSettings)), {})
    if overrides:  # the command line's --quality, --shadows, --shadow-map: validated like the file's values
        n = Node(n.ctx, n.path, dict(n.data, **{k: v for k, v in overrides.items() if v is not None}))
    colourspace = n.string("colourspace", DEFAULT_COLOURSPACE)
    try:
        colourspace = colourspace_name(colourspace)  # canonical spelling
    except InputError:
        n.fail("colourspace", f"expected the name of a colour-science RGB colourspace such as "
                              f"{DEFAULT_COLOURSPACE!r} or 'ACEScg', got {colourspace!r}")
    return RenderSettings(
        quality=n.choice("quality", QUALITIES, "default"),
        tolerance=n.number("tolerance", None, check=lambda v: 0 <= v < 1, expect="a number in [0, 1)"),
        max_tau=n.number("max_tau", None, check=lambda v: v >= lim.MIN_MAX_TAU,
                         expect=f"a finite number > 0, at least {lim.MIN_MAX_TAU:g} (README: Limits)"),
        max_length=n.number("max_length", None, **_POSITIVE),  # against the scene's size in _check_domain
        max_angle=n.number("max_angle", None, check=lambda v: lim.MIN_MAX_ANGLE <= v <= 1.6,
                           expect=f"an angle in (0, 1.6] radians, at least {lim.MIN_MAX_ANGLE:g}"),
        cutoff=n.number("cutoff", None, check=lambda v: 0 <= v < 1, expect="a number in [0, 1)"),
        root_tolerance=n.number("root_tolerance", None,
                                check=lambda v: lim.ROOT_TOLERANCE_RANGE[0] <= v <= lim.ROOT_TOLERANCE_RANGE[1],
                                expect="a finite number > 0, from {:g} to {:g} of the scene's diagonal".format(
                                    *lim.ROOT_TOLERANCE_RANGE)),
        shadows=ShadowMode(n.choice("shadows", SHADOW_MODES, "exact")),
        shadow_map=n.integer("shadow_map", None, **_int_range(2, lim.MAX_SHADOW_MAP)),
        colourspace=colourspace,
        scattering=n.choice("scattering", SCATTERING_MODES, "single"),
        method=n.choice("method", APPROXIMATE_METHODS, "octaves"),
        octaves=_octaves(n),
        grid=_grid(n),
        shared=_shared(n),
        max_order=n.integer("max_order", 64, **_int_range(1, lim.MAX_ORDER)),
        ms_spp=_ms_spp(n),
        track_from=n.integer("track_from", 2, **_int_range(2, lim.MAX_ORDER + 1)),
        error=n.number("error", None, check=lambda v: lim.MIN_ERROR_TARGET <= v <= 0.5,
                       expect=f"a relative RMSE from {lim.MIN_ERROR_TARGET:g} to 0.5 (docs/error_estimate.md)"),
        calibrate=n.flag("calibrate", True))


def _ms_spp(render):
    """render.ms_spp: paths per pixel, or ``auto`` (the default: the renderer plans them to the preset's target)."""
    value, given = render._raw("ms_spp", None)
    if given and value == "auto":
        return None
    check = _int_range(1, lim.MAX_SPP)
    return render.integer("ms_spp", None, check=check["check"], expect=check["expect"] + ", or auto")


def _octaves(render):
    """render.octaves: {count, a, b, c} (docs/approximate.md), each defaulting to the fitted OCTAVES."""
    n = render.node("octaves", ("count", "a", "b", "c"), {})
    count, a, b, c = OCTAVES
    fraction = dict(check=lambda v: 0 < v <= 1, expect="a number in (0, 1]")
    return (n.integer("count", count, **_int_range(1, lim.MAX_OCTAVES)), n.number("a", a, **fraction),
            n.number("b", b, **fraction), n.number("c", c, **fraction))


def _grid(render):
    """render.grid: {cells, photons, deposit} (docs/approximate.md), None where absent (the quality preset's and
    flights); cells or photons left out are None too and take the preset's value."""
    if "grid" not in render.data:
        return None
    n = render.node("grid", ("cells", "photons", "deposit"), {})
    return (n.integer("cells", None, **_int_range(2, lim.MAX_GRID_CELLS)),
            n.integer("photons", None, **_int_range(1, lim.MAX_PHOTONS)), n.choice("deposit", GRID_DEPOSITS, "flights"))


def _shared(render):
    """render.shared: {stride, tails, cache} (docs/approximate.md), None where absent; a key left out is None too:
    the quality preset's stride, tails planned to the preset's target, the preset's cache."""
    if "shared" not in render.data:
        return None
    n = render.node("shared", ("stride", "tails", "cache"), {})
    stride = n.integer("stride", None, check=lambda v: 1 <= v <= lim.MAX_SHARED_STRIDE and v & (v - 1) == 0,
                       expect=f"a power of 2 from 1 to {lim.MAX_SHARED_STRIDE}")
    cache = n.integer("cache", None, check=lambda v: v == 0 or 2 <= v <= lim.MAX_ORDER,
                      expect=f"0 (no cache) or an order from 2 to {lim.MAX_ORDER}")
    return stride, n.integer("tails", None, **_int_range(2, lim.MAX_SHARED_TAILS)), cache


EXPOSURE = dict(check=lambda v: abs(v) <= lim.MAX_EXPOSURE,
                expect=f"a finite number of stops within +-{lim.MAX_EXPOSURE:g}")


def _output(top):
    n = top.node("output", ("path", "png", "exposure", "display", "white_balance"), {})
    exposure = n.data.get("exposure")
    if exposure != AUTO_EXPOSURE:
        exposure = n.number("exposure", None, check=EXPOSURE["check"],
                            expect=f"{AUTO_EXPOSURE} or {EXPOSURE['expect']}")
    white_balance = n.data.get("white_balance")
    if white_balance is not None and not (isinstance(white_balance, str) and (white_balance in WHITE_BALANCE_WORDS
                                                                              or is_illuminant(white_balance))):
        n.fail("white_balance", f"expected {', '.join(WHITE_BALANCE_WORDS)} or a CIE illuminant of "
                                f"colour.SDS_ILLUMINANTS such as D65, D50 or A, got {describe(white_balance)}")
    return OutputSettings(n.path_to("path"), n.path_to("png"), exposure, n.choice("display", DISPLAYS, "aces"),
                          white_balance)



_COLOUR_FORMS = "a colour ([r, g, b], {temperature: K} or {illuminant: NAME})"
_SKY_FORMS = ("sky (the sky of the scene's one sun light), {sky: {ground_albedo, ground_height}} (that sky over "
              "another ground) or {sky: {elevation, azimuth, turbidity or aerosol_depth, irradiance, ground_albedo, "
              "ground_height}}")


def _is_sky(raw):
    """Whether a ``background`` or ``ambient`` value asks for a sky (docs/atmosphere.md), not a colour."""
    return raw == "sky" or (isinstance(raw, dict) and "sky" in raw)


def _sun_of_scene(top, key, lights):
    """The atmosphere.Sun of the scene's one ``type: sun`` light; an error naming ``key`` if it has none or
    several."""
    suns = [light.sun for light in lights if isinstance(light, SunLight)]
    if len(suns) != 1:
        found = "none" if not suns else f"{len(suns)}"
        top.fail(key, f"sky is the sky of the scene's one light of type: sun, found {found}; add one "
                      f"(lights: [{{type: sun, elevation: DEGREES}}]) or give the sky itself: "
                      f"background: {{sky: {{elevation: DEGREES, ...}}}}")
    return suns[0]


def _sky_of_sun(top, key, lights, cs, ground_albedo=DEFAULT_GROUND_ALBEDO):
    """The sky of the scene's one ``type: sun`` light over a ground of ``ground_albedo``."""
    return _sun_of_scene(top, key, lights).sky(cs, ground_albedo)


_GROUND_ALBEDO = "an albedo in [0, 1] (grey) or [r, g, b], each in [0, 1] (linear BT.709)"


def _ground_albedo(s):
    """``ground_albedo`` of the sky node ``s``: a number or [r, g, b] (atmosphere.ground_albedo_of)."""
    raw = s.data.get("ground_albedo")
    if isinstance(raw, list):
        if not (len(raw) == 3 and all(is_finite_number(v) and 0 <= v <= 1 for v in raw)):
            s.fail("ground_albedo", f"expected {_GROUND_ALBEDO}, got {describe(raw)}")
        return ground_albedo_of([float(v) for v in raw])
    return s.number("ground_albedo", DEFAULT_GROUND_ALBEDO, check=lambda v: 0 <= v <= 1, expect=_GROUND_ALBEDO)


#: the keys of ``background: {sky: {...}}`` that place and colour the ground, besides the sun's
_GROUND_KEYS = ("ground_albedo", "ground_height")


def _sky(top, cs, lights, camera):
    """(181, 3) the sky of ``background: sky`` or ``background: {sky: {...}}`` (docs/atmosphere.md), and its
    ground as a model.Ground where ``ground_height`` places it (else None)."""
    raw = top.data.get("background")
    if raw == "sky":
        sun, albedo, s = _sun_of_scene(top, "background", lights), DEFAULT_GROUND_ALBEDO, None
        where = "background"
    else:
        n = top.node("background", ("sky",))
        s = n.node("sky", SUN_KEYS + _GROUND_KEYS)
        albedo = _ground_albedo(s)
        if set(s.data) <= set(_GROUND_KEYS):  # the ground alone: the sky of the scene's one sun over it
            sun, where = _sun_of_scene(top, "background", lights), "background"
        else:
            sun = read_sun(s)
            where = s.key("irradiance")
    sky = sun.sky(cs, albedo)
    if not np.max(sky) <= lim.MAX_RADIANCE:
        top.ctx.fail(where, f"expected the sky's radiance <= {lim.MAX_RADIANCE:g} (README: Limits), its largest is "
                            f"{np.max(sky):.3g}")
    ground = None
    if s is not None and "ground_height" in s.data:
        z = float(camera.position[2])
        height = s.number("ground_height", check=lambda v: abs(v) <= lim.LENGTH_RANGE[1] and v < z,
                          expect=f"a number below the camera's height (its z, {z:g})")
        ground = Ground(height, frozen_array(sun.ground_sun(cs, albedo)),
                        frozen_array(np.asarray(sun.direction(), np.float64)))
    return frozen_array(sky), ground


#: what _colour_or_sky returns where a key asks for a sky: read once the lights are
_SKY = object()


def _colour_or_sky(top, key, cs, default):
    """``key`` read as a colour (docs/model.md §7), or _SKY where it asks for a sky."""
    raw = top.data.get(key)
    if _is_sky(raw):
        return _SKY
    if isinstance(raw, str):
        forms = _SKY_FORMS if key == "background" else "sky (the mean radiance of the scene's sky)"
        top.fail(key, f"expected {_COLOUR_FORMS} or {forms}, got the text {raw!r}")
    return top.colour(key, cs, default)


def _ambient_sky(top, cs, lights, sky):
    """``ambient: sky``: the mean over the sphere of the scene's sky, its background's or else its one sun's
    (the uniform ambient of single scattering, occlusion ignored: docs/atmosphere.md)."""
    if top.data.get("ambient") != "sky":
        top.fail("ambient", f"expected {_COLOUR_FORMS} or sky, got {top.data.get('ambient')!r}")
    return frozen_array(sky_mean(_sky_of_sun(top, "ambient", lights, cs) if sky is None else sky))


def load_scene(path, width=None, height=None, spp=None, render=None, frame=None) -> Scene:
    """Read and validate the YAML scene at ``path``; ``width``, ``height``, ``spp`` override its image settings,
    ``render`` (a dict) its ``render:`` keys, validated like the file's own.

    An animated scene (keyframes, ``animation:``, docs/animation.md) is read at ``frame`` (default 0).
    Raises SceneError (file, key path, what was expected) on the first problem found; a scene outside the
    limits or the numeric domain (cloudmeta.limits, README "Limits") is refused too.
    """
    ctx = Context(path)
    data = read_yaml(ctx)
    if not isinstance(data, dict):
        # the type only: a file that is not a scene (``cloudmeta render /etc/shadow``) must not be quoted
        got = "null" if data is None else {list: "a list", str: "a text"}.get(type(data), type(data).__name__)
        ctx.fail(None, f"expected a mapping of sections (image, camera, media, ...) at the top level, got {got}")
    data, animated = resolve_frame(ctx.file, data, frame)
    with naming_frame((frame or 0) if animated else None):
        return _scene(ctx, data, width, height, spp, render)


def _scene(ctx, data, width, height, spp, render):
    """The Scene of the static YAML document ``data`` (a mapping) of ``ctx``'s file."""
    top = Node(ctx, "", data, ("image", "camera", "background", "ambient", "lights", "media", "surfaces",
                                "render", "output"))
    render = _render(top, render)  # first: colours depend on its colourspace
    cs = render.colourspace
    image = _image(top, width, height, spp)
    camera = _camera(top)
    background = _colour_or_sky(top, "background", cs, [0.0, 0.0, 0.0])
    ambient = _colour_or_sky(top, "ambient", cs, None)
    lights = tuple(read_light(ctx, p, raw, cs) for p, raw in top.items("lights"))
    sky = ground = None
    if background is _SKY:  # a sky: its mean over the sphere where one uniform colour is needed
        sky, ground = _sky(top, cs, lights, camera)
        background = frozen_array(sky_mean(sky))
    if ambient is _SKY:
        ambient = _ambient_sky(top, cs, lights, sky)
    media = _named(ctx, top.items("media"), "medium", lambda p, raw, name: _medium(ctx, p, raw, name))
    surfaces = _named(ctx, top.items("surfaces"), "surface", lambda p, raw, name: _surface(ctx, p, raw, name, cs))
    if not media and not surfaces:
        ctx.fail("media", "a scene needs at least one medium or surface, found none")
    scene = Scene(ctx.file, image, camera, background, ambient, lights, media, surfaces, render, _output(top),
                  tuple(ctx.inputs), ctx.merged_balls, sky=sky, ground=ground)
    check_domain(ctx, scene)
    return scene
