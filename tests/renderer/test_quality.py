"""renderer.quality: every render setting of a frame decided once (FrameSettings), from one table of presets."""
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

import cloudmeta as cm
from cloudmeta.kernels import records
from cloudmeta.renderer import pack
from cloudmeta.renderer.quality import PRESETS, FrameSettings, resolve_quality, resolve_settings
from cloudmeta.scene.vocabulary import HYBRID_SHARE, QUALITIES, SHADOW_MAP_RESOLUTION, SHADOW_MODES, ShadowMode

ROOT = Path(__file__).resolve().parents[2]


def cumulus(**render):
    s = cm.load_scene(ROOT / "scenes" / "cumulus.yaml", width=8, height=8)
    return replace(s, render=replace(s.render, **render)) if render else s


def test_one_table_says_what_each_preset_means():
    assert tuple(PRESETS) == QUALITIES
    assert {q: PRESETS[q].target for q in QUALITIES} == {"draft": 3e-3, "default": 1e-3, "fine": 3e-4,
                                                          "reference": None}
    assert {q: PRESETS[q].start for q in QUALITIES} == {"draft": 1.0, "default": 0.0, "fine": -1.0, "reference": None}
    # each preset's tolerance is its target (relative to the pilot's scale)
    assert all(p.quadrature["tolerance"] == p.target for p in PRESETS.values() if p.target is not None)
    assert [PRESETS[q].grid for q in ("draft", "default", "fine")] == [(24, 1 << 21), (40, 1 << 23), (56, 1 << 25)]


def test_the_scene_is_resolved_once_into_one_record():
    s = cumulus(quality="fine", shadows="hybrid", shadow_map=64)
    settings = resolve_settings(s)
    assert isinstance(settings, FrameSettings)
    assert (settings.quality, settings.preset, settings.shadows, settings.shadow_map) == \
        ("fine", PRESETS["fine"], ShadowMode.HYBRID, 64)
    assert settings.target == 3e-4 and settings.error is None and settings.calibrate and settings.grid is None
    assert settings.quadrature == resolve_quality(s.render, s.length_scale())
    assert settings.quadrature.max_length == PRESETS["fine"].quadrature["max_length"] * s.length_scale()
    assert resolve_settings(cumulus()).shadow_map == SHADOW_MAP_RESOLUTION
    # render.error is the target where given, and the quadrature then refines on its own estimate
    with_error = resolve_settings(cumulus(error=2e-3))
    assert with_error.target == 2e-3 and not with_error.calibrate


@pytest.mark.parametrize("render, calibrates", [
    ({}, True), ({"scattering": "approximate"}, True), ({"scattering": "multiple"}, False),
    ({"quality": "reference"}, False), ({"tolerance": 1e-3}, False), ({"cutoff": 1e-4}, False),
    ({"calibrate": False}, False), ({"error": 1e-3}, False), ({"root_tolerance": 1e-8}, True)])
def test_whether_the_pilot_calibrates_is_decided_with_the_settings(render, calibrates):
    assert resolve_settings(cumulus(**render)).calibrate is calibrates


@pytest.mark.parametrize("shadows", SHADOW_MODES)
def test_the_kernels_get_the_shadow_mode_as_an_explicit_id(shadows):
    """records.Quadrature.shadow_mode names the mode; map_tolerance is the hybrid mode's absolute tolerance only."""
    settings = resolve_settings(cumulus(shadows=shadows))
    assert settings.shadows == shadows and settings.shadows.builds_maps is (shadows != "exact")
    quality = replace(settings.quadrature, light_scale=2.0)
    quad = pack.quadrature(quality)
    assert isinstance(quad.shadow_mode, np.int64)
    assert quad.shadow_mode == {"exact": records.SHADOWS_EXACT, "map": records.SHADOWS_MAP,
                                "hybrid": records.SHADOWS_HYBRID}[shadows]
    expected = HYBRID_SHARE * quality.tolerance * 2.0 if shadows == "hybrid" else 0.0
    assert quad.map_tolerance == expected and np.isfinite(quad.map_tolerance)


def test_a_shadow_mode_given_as_a_string_reads_as_the_mode():
    s = cm.load_scene(ROOT / "scenes" / "cumulus.yaml", width=8, height=8, render={"shadows": "map"})
    assert s.render.shadows is ShadowMode.MAP and s.render.shadows == "map"
    assert resolve_settings(cumulus(shadows="hybrid")).shadows is ShadowMode.HYBRID
