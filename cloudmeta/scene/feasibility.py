"""The numeric domain: a validated scene is refused where the kernels' tolerances would not hold (lengths
relative to the scene's diagonal, optical depths and radiances far from overflow) or where the render
would not fit this machine's memory (docs/model_notes.md "Numeric domain", README "Limits")."""
from __future__ import annotations

import math

import numpy as np

from . import limits as lim
from .document import fmt_numbers
from .vocabulary import MAP_SHADOWS, SHADOW_MAP_RESOLUTION

def _phase_peak(phase):
    """The largest value of the phase function (at cos theta = +-1)."""
    hg = lambda g: (1 + abs(g)) / (4 * math.pi * (1 - abs(g)) ** 2)  # noqa: E731
    if phase.type == "hg":
        return hg(phase.g)
    if phase.type == "double_hg":
        return phase.w * hg(phase.g1) + (1 - phase.w) * hg(phase.g2)
    return 3 / (8 * math.pi) if phase.type == "rayleigh" else 1 / (4 * math.pi)


def check_domain(ctx, scene):
    """Refuse values outside the domain where the kernels' tolerances hold (docs/model_notes.md "Numeric
    domain"): lengths relative to the scene's length L (its diagonal unless geometry lies far away), optical depths and radiances far from overflow,
    and work and memory within the machine's means (README "Limits")."""
    lo, hi = scene.bbox()
    diag = float(np.linalg.norm(hi - lo))
    things = [(f"media[{i}]", m) for i, m in enumerate(scene.media)] + \
             [(f"surfaces[{i}]", s) for i, s in enumerate(scene.surfaces)]
    if not lim.LENGTH_RANGE[0] <= diag <= 2 * lim.LENGTH_RANGE[1]:
        ctx.fail(f"{things[0][0]}.balls", f"the scene's bounding-box diagonal is {diag:g}, outside "
                                         f"[{lim.LENGTH_RANGE[0]:g}, {lim.LENGTH_RANGE[1]:g}] (README: Limits)")
    # tolerances are relative to the scene's length L (Scene.length_scale: the diagonal, unless geometry
    # lies far away); coordinates within MAX_OFFSET x L keep t's rounding (eps |t|) below the root tolerance
    scale = scene.length_scale()
    far = lim.MAX_OFFSET * scale
    # a ball spans at least 1000 root tolerances (1e-6 of L at the default 1e-9)
    min_radius = lim.MIN_RADIUS_TOLERANCES * (scene.render.root_tolerance or 1e-9)
    for path, thing in things:
        blob, locate = thing.blob, ctx.ball_sources[id(thing.blob)]
        bad = np.flatnonzero(np.abs(blob.centers).max(axis=1) > far)
        if len(bad):
            key_path, prefix = locate(int(bad[0]), "center")
            ctx.fail(key_path, f"{prefix}expected a centre within +-{far:.3g} ({lim.MAX_OFFSET:g} x the scene's "
                               f"length {scale:.3g}), got {fmt_numbers(blob.centers[bad[0]])}")
        small = np.flatnonzero(blob.radii.min(axis=1) < min_radius * scale)
        if len(small):
            key_path, prefix = locate(int(small[0]), "radius")
            ctx.fail(key_path, f"{prefix}expected radii of at least {min_radius * scale:.3g} ({min_radius:g} x the "
                               f"scene's length {scale:.3g}: 1000 root tolerances), got {fmt_numbers(blob.radii[small[0]])}")
    for key, point in (("camera.position", scene.camera.position), ("camera.look_at", scene.camera.look_at)) + \
            tuple((f"lights[{i}].{l.KEYS[0]}", l.place()) for i, l in enumerate(scene.lights)
                  if l.place() is not None):
        if np.abs(point).max() > far:
            ctx.fail(key, f"expected a point within +-{far:.3g} ({lim.MAX_OFFSET:g} x the scene's length "
                          f"{scale:.3g}), got {fmt_numbers(point)}")
    for i, m in enumerate(scene.media):
        rho = 1.0 if m.density.mode == "uniform" else float(np.abs(m.blob.weights).sum())
        if m.density.scale * rho * diag > lim.MAX_TAU_BOUND:
            ctx.fail(f"media[{i}].density.scale", f"expected scale x sum |weight| x diagonal <= "
                                                  f"{lim.MAX_TAU_BOUND:g} (a bound on optical depth), got "
                                                  f"{m.density.scale * rho * diag:.3g}")
    for i, light in enumerate(scene.lights):
        if light.place() is not None and light.irradiance_at(diag) > lim.MAX_RADIANCE:
            ctx.fail(f"lights[{i}].{light.KEYS[1]}", f"expected intensity x color / diagonal^2 <= {lim.MAX_RADIANCE:g}, "
                                                     f"got {light.irradiance_at(diag):.3g}")
    # the brightest radiance single scattering and surfaces can make: background + ambient x (1 + colour)
    # + each light's irradiance (a point light's at one diagonal) x the largest phase peak or colour / pi
    peak = max([m.albedo * _phase_peak(m.phase) for m in scene.media] + [s.color.max() / math.pi
                                                                        for s in scene.surfaces])
    colour = max([1.0] + [s.color.max() for s in scene.surfaces])
    irradiance = sum(l.irradiance_at(diag) for l in scene.lights)
    ambient = 0.0 if scene.ambient is None else float(np.max(scene.ambient))
    terms = {"background": float(np.max(scene.background)), "ambient": ambient * (1 + colour),
             "lights": irradiance * peak}
    bound = sum(terms.values())
    if not bound <= lim.MAX_RADIANCE:
        ctx.fail(max(terms, key=terms.get),
                 f"the brightest radiance this scene can make is about {bound:.3g}, above the limit "
                 f"{lim.MAX_RADIANCE:g} (README: Limits)")
    r = scene.render
    if r.max_length is not None and diag / r.max_length > lim.MAX_STEPS_PER_RAY:
        ctx.fail("render.max_length", f"expected at least {diag / lim.MAX_STEPS_PER_RAY:.3g} (the scene's "
                                      f"diagonal {diag:.3g} / {lim.MAX_STEPS_PER_RAY:g} steps), got {r.max_length:g}")
    _check_memory(ctx, scene)


def _check_memory(ctx, scene):
    w, h = scene.image.width, scene.image.height
    balls = sum(len(t.blob) for t in scene.media + scene.surfaces)
    directional = sum(l.casts_map for l in scene.lights)
    res = scene.render.shadow_map or SHADOW_MAP_RESOLUTION
    texels = directional * res * res if scene.render.shadows in MAP_SHADOWS and scene.media else 0
    need, have = lim.render_memory(w, h, balls, texels), lim.physical_memory()
    if have is not None and need > lim.MEMORY_FRACTION * have:
        key = "render.shadow_map" if texels * lim.BYTES_PER_TEXEL > w * h * lim.BYTES_PER_PIXEL else "image"
        ctx.fail(key, f"a render of {w} x {h} pixels, {balls} balls and {texels} shadow-map texels needs about "
                      f"{lim.gib(need)}, more than {lim.MEMORY_FRACTION:g} of this machine's {lim.gib(have)}")
