"""cloudmeta.scene.atmosphere (docs/atmosphere.md): the sun's colour against colour-science worked by hand,
the sky's zenith and horizon against the single-scattering formula worked by hand, and the scene keys
``type: sun``, ``background: sky`` and ``ambient: sky``."""
import copy

import numpy as np
import pytest
import yaml

import cloudmeta.scene.atmosphere as atm
from cloudmeta.errors import SceneError
from cloudmeta.scene import DirectionalLight, load_scene
from cloudmeta.scene.colour import DEFAULT_COLOURSPACE, parse_colour
from cloudmeta.scene.lights import SunLight

ELEVATIONS = (5.0, 15.0, 45.0, 90.0)


@pytest.fixture(scope="module")
def cs():
    """colour-science, the ASTM G-173 extraterrestrial spectrum and the default wavelengths, as a user has them."""
    import colour
    from colour.plotting.datasets import SD_ASTMG173_ETR

    wl = colour.SPECTRAL_SHAPE_DEFAULT.wavelengths
    return colour, SD_ASTMG173_ETR, wl


def kasten_young(h):
    return 1.0 / (np.sin(np.radians(h)) + 0.50572 * (h + 6.07995) ** -1.6364)


def hand_xyz(cs, spectrum):
    """XYZ of a spectrum on the default wavelengths, colour-science's way, over Y of the ETR sun."""
    colour, etr, wl = cs
    y0 = colour.sd_to_XYZ(colour.SpectralDistribution(etr[wl], wl))[1]
    return colour.sd_to_XYZ(colour.SpectralDistribution(spectrum, wl)) / y0


def hand_depth(cs, aerosol_depth):
    colour, _, wl = cs
    return colour.phenomena.rayleigh_optical_depth(wl * 1e-7) + aerosol_depth * (wl / 550.0) ** -1.3


def to_xy(xyz):
    xyz = np.asarray(xyz)
    return xyz[..., :2] / xyz.sum(axis=-1, keepdims=True)


def rgb_to_xyz(cs, rgb):
    colour = cs[0]
    return colour.RGB_COLOURSPACES[DEFAULT_COLOURSPACE].matrix_RGB_to_XYZ @ rgb


# ------------------------------------------------------------------------------------------- the sun

@pytest.mark.parametrize("aerosol_depth", [0.0, atm.DEFAULT_AEROSOL_DEPTH, atm.turbidity_to_aerosol_depth(4.0)])
def test_01_sun_colour_is_colour_sciences_by_hand(cs, aerosol_depth):
    colour, etr, wl = cs
    for h in ELEVATIONS:
        xyz = hand_xyz(cs, etr[wl] * np.exp(-kasten_young(h) * hand_depth(cs, aerosol_depth)))
        rgb = atm.sun_rgb(h, aerosol_depth)
        assert np.all(rgb > 0), (h, rgb)  # in the gamut: nothing clipped, so RGB -> xy is the sun's xy
        np.testing.assert_allclose(to_xy(rgb_to_xyz(cs, rgb)), to_xy(xyz), rtol=0, atol=1e-6)
        np.testing.assert_allclose(to_xy(atm.sun_xyz(h, aerosol_depth)), to_xy(xyz), rtol=0, atol=1e-9)
        np.testing.assert_allclose(rgb_to_xyz(cs, rgb)[1], xyz[1], rtol=1e-9)  # the luminance too
        np.testing.assert_allclose(
            rgb, colour.RGB_COLOURSPACES[DEFAULT_COLOURSPACE].matrix_XYZ_to_RGB @ xyz, rtol=1e-9)


def test_02_outside_the_atmosphere_the_sun_has_unit_luminance(cs):
    colour, etr, wl = cs
    xyz = atm.spectra()[1] @ atm.spectra()[3]
    np.testing.assert_allclose(xyz[1], 1.0, rtol=1e-12)
    np.testing.assert_allclose(to_xy(xyz), colour.XYZ_to_xy(colour.sd_to_XYZ(colour.SpectralDistribution(etr[wl], wl))),
                               atol=1e-12)


@pytest.mark.parametrize("aerosol_depth", [0.0, 0.1, 0.5])
def test_03_the_sun_reddens_and_dims_as_it_sets(aerosol_depth):
    h = np.arange(0.0, 90.5, 2.5)
    xyz = np.array([atm.sun_xyz(e, aerosol_depth) for e in h])
    assert np.all(np.diff(xyz[:, 1]) > 0)            # brighter as it rises
    assert np.all(np.diff(to_xy(xyz)[:, 0]) < 0)     # x falls as it rises: redder as it sets
    assert xyz[-1, 1] < 1.0


def test_04_more_aerosol_dims_and_reddens_the_sun():
    a, b = atm.sun_xyz(30.0, 0.05), atm.sun_xyz(30.0, 0.4)
    assert b[1] < a[1] and to_xy(b)[0] > to_xy(a)[0]
    assert atm.turbidity_to_aerosol_depth(2.0) == pytest.approx((0.04608 * 2 - 0.04586) * 0.55 ** -1.3)


def test_05_air_mass_kasten_young():
    assert atm.air_mass(90.0) == pytest.approx(0.99971, abs=1e-5)
    assert atm.air_mass(0.0) == pytest.approx(37.92, abs=0.01)
    assert atm.air_mass(30.0) == pytest.approx(1.9942, abs=1e-3)  # close to 1 / sin(30 degrees)


# ------------------------------------------------------------------------------------------- the sky

def hand_sky(cs, view, sun, aerosol_depth, mean_phases):
    """The sky's spectral radiance at view elevation ``view`` of docs/atmosphere.md, worked out by hand:
    mean_phases = (<p_R>, <p_A>) averaged over azimuth."""
    _, etr, wl = cs
    tau_r = cs[0].phenomena.rayleigh_optical_depth(wl * 1e-7)
    tau_a = aerosol_depth * (wl / 550.0) ** -1.3
    tau = tau_r + tau_a
    ms, mv = kasten_young(sun), kasten_young(view)
    with np.errstate(invalid="ignore"):
        path = np.where(abs(mv - ms) > 1e-12, (np.exp(-tau * ms) - np.exp(-tau * mv)) / (tau * (mv - ms)),
                        np.exp(-tau * ms))
    p_r, p_a = mean_phases
    return etr[wl] * (tau_r * p_r + 0.9 * tau_a * p_a) * path * mv


def hg(cos_theta, g=0.7):
    return (1 - g * g) / (4 * np.pi * (1 + g * g - 2 * g * cos_theta) ** 1.5)


@pytest.mark.parametrize("sun,aerosol_depth", [(30.0, 0.0), (30.0, 0.1), (30.0, 0.4), (8.0, 0.1), (65.0, 0.2)])
def test_06_zenith_and_horizon_against_the_formula_by_hand(cs, sun, aerosol_depth):
    xyz = atm.sky_xyz(sun, aerosol_depth)
    # zenith: every azimuth is the same direction, cos theta = sin(sun)
    c = np.sin(np.radians(sun))
    zenith = hand_xyz(cs, hand_sky(cs, 90.0, sun, aerosol_depth, (3 / (16 * np.pi) * (1 + c * c), hg(c))))
    np.testing.assert_allclose(xyz[180], zenith, rtol=1e-9)
    # horizon: cos theta = cos(sun) cos(phi); <1 + cos^2> = 1 + cos^2(sun) / 2 exactly, HG averaged finely
    phi = (np.arange(20000) + 0.5) * 2 * np.pi / 20000
    c = np.cos(np.radians(sun))
    phases = (3 / (16 * np.pi) * (1 + c * c / 2), hg(c * np.cos(phi)).mean())
    np.testing.assert_allclose(xyz[90], hand_xyz(cs, hand_sky(cs, 0.0, sun, aerosol_depth, phases)), rtol=1e-9)


@pytest.mark.parametrize("aerosol_depth", [0.0, 0.1, 0.4])
def test_07_zenith_bluer_than_horizon(aerosol_depth):
    for sun in (5.0, 15.0, 30.0, 45.0, 60.0, 90.0):
        zenith, horizon = atm.sky_table(sun, aerosol_depth)[[180, 90]]
        assert zenith[2] / zenith[0] > horizon[2] / horizon[0], sun     # blue over red
    if aerosol_depth == 0:  # air alone: a deep blue zenith
        assert atm.sky_table(30.0, 0.0)[180, 2] > 2 * atm.sky_table(30.0, 0.0)[180, 0]


def test_07b_horizon_brighter_than_zenith_in_a_clear_sky():
    """Single scattering: the horizon's long path scatters more than the zenith's short one, until the
    zenith lies in the aerosols' forward peak (the aureole) of a high sun in hazy air."""
    def horizon_over_zenith(sun, aerosol_depth):
        xyz = atm.sky_xyz(sun, aerosol_depth)
        return xyz[90, 1] / xyz[180, 1]

    for sun in (5.0, 30.0, 60.0, 90.0):
        assert horizon_over_zenith(sun, 0.0) > 4, sun      # air alone: several times brighter
    for sun in (30.0, 45.0, 60.0):
        assert horizon_over_zenith(sun, 0.1) > 1, sun      # the default clear sky, a high sun
    for sun in (60.0, 90.0):
        assert horizon_over_zenith(sun, 0.4) < 0.5, sun    # hazy, the sun high: the aureole at the zenith


def test_08_ground_below_the_horizon_is_lambertian(monkeypatch):
    sun, aerosol_depth, albedo = 35.0, 0.15, 0.25
    monkeypatch.setattr(atm, "GROUND_AIR_PATH", 0.0)  # the ground itself, no air in between (test_08b)
    xyz = atm.sky_xyz(sun, aerosol_depth, albedo)
    np.testing.assert_allclose(xyz[:90], xyz[[0] * 90], rtol=1e-14)  # the same below the horizon
    np.testing.assert_array_equal(atm.sky_xyz(sun, aerosol_depth, 0.0)[:90], 0.0)
    np.testing.assert_array_equal(atm.sky_xyz(sun, aerosol_depth, 0.5)[90:], xyz[90:])  # sky: no albedo
    # L = albedo / pi (sin(h) E_sun + integral of L_sky cos(zenith) dOmega), the integral by the trapezoid
    # rule over the table's own 1-degree rows (agrees to its error, ~1e-4)
    e = np.radians(np.arange(0.0, 91.0))
    f = xyz[90:] * (np.sin(e) * np.cos(e))[:, None]
    e_sky = 2 * np.pi * np.radians(1.0) * (f[1:-1].sum(axis=0) + (f[0] + f[-1]) / 2)
    expected = albedo / np.pi * (np.sin(np.radians(sun)) * atm.sun_xyz(sun, aerosol_depth) + e_sky)
    np.testing.assert_allclose(xyz[0], expected, rtol=1e-3)


def test_08b_the_ground_fades_into_the_haze_towards_the_horizon(monkeypatch):
    """Below the horizon the ground is seen through GROUND_AIR_PATH / sin(depression) air masses:
    L = L_ground T + L_air (1 - T), its haze brightest, and the ground least visible, at the horizon."""
    sun, aerosol_depth, albedo = 35.0, 0.1, 0.1
    hazy = atm.sky_xyz(sun, aerosol_depth, albedo)
    monkeypatch.setattr(atm, "GROUND_AIR_PATH", 0.0)
    bare = atm.sky_xyz(sun, aerosol_depth, albedo)
    air = atm.sky_xyz(sun, aerosol_depth, 0.0)  # no ground light: the air's alone
    monkeypatch.undo()
    air_only = atm.sky_xyz(sun, aerosol_depth, 0.0)
    np.testing.assert_array_equal(air[:90], 0.0)
    np.testing.assert_array_equal(hazy[90:], bare[90:])                 # the sky is unchanged
    assert np.all(np.diff(air_only[:90, 1]) > 0)                         # haze grows towards the horizon
    assert np.all(np.diff(hazy[:90, 1]) > 0)
    # looking straight down through 0.1 air masses the ground dominates; one degree down, the haze
    assert abs(hazy[0, 1] - bare[0, 1]) < 0.1 * bare[0, 1]
    assert air_only[89, 1] > 0.5 * hazy[89, 1]
    # the step at the horizon is smaller than the bare ground's: no hard band
    assert abs(hazy[90, 1] - hazy[89, 1]) < 0.5 * abs(hazy[90, 1] - bare[89, 1])
    # at the horizon's air mass the haze is (nearly) the horizon's own sky
    assert atm.ground_air_mass(-1e-9) == pytest.approx(atm.air_mass(0.0))
    assert atm.ground_air_mass(-90.0) == pytest.approx(atm.GROUND_AIR_PATH)


def test_08d_the_suns_share_of_the_ground(monkeypatch):
    """ground_sun_xyz: the part of the ground's radiance that the sun lights directly, albedo / pi sin h E_sun,
    seen through the same air as the whole ground; none above the horizon; at most the whole."""
    sun, aerosol_depth, albedo = 35.0, 0.15, 0.25
    share = atm.ground_sun_xyz(sun, aerosol_depth, albedo)
    np.testing.assert_array_equal(share[90:], 0.0)
    whole = atm.sky_xyz(sun, aerosol_depth, albedo)
    assert np.all(share[:90] > 0) and np.all(share[:90] < whole[:90])
    assert 0.5 < share[0, 1] / whole[0, 1] < 1.0 and share[89, 1] / whole[89, 1] < 0.3  # the haze is lit anyway
    # the naive twin: the spectrum through the air's transmittance exp(-tau m_g), then to XYZ
    wl, _, _, weights = atm.spectra()
    tau_r, tau_a = atm._depths(aerosol_depth)
    view = np.arange(-90.0, 0.0)
    seen = np.exp(-np.outer(atm.ground_air_mass(view), tau_r + tau_a))
    lit = albedo / np.pi * np.sin(np.radians(sun)) * atm.sun_spectrum(sun, aerosol_depth)
    np.testing.assert_allclose(share[:90], (seen * lit) @ weights, rtol=1e-13)
    # with no air in between, the bare ground's sun term: albedo / pi sin h times the sun's XYZ
    monkeypatch.setattr(atm, "GROUND_AIR_PATH", 0.0)
    bare = atm.ground_sun_xyz(sun, aerosol_depth, albedo)
    np.testing.assert_allclose(bare[:90], albedo / np.pi * np.sin(np.radians(sun)) * atm.sun_xyz(sun, aerosol_depth)
                               * np.ones((90, 1)), rtol=1e-13)
    monkeypatch.undo()
    np.testing.assert_array_equal(atm.ground_sun_xyz(sun, aerosol_depth, 0.0), 0.0)
    table = atm.ground_sun_table(sun, aerosol_depth)
    assert table.shape == (181, 3) and not table.flags.writeable and np.all(table <= atm.sky_table(sun, aerosol_depth))


def test_08c_a_coloured_ground(monkeypatch):
    """An RGB albedo is a reflectance spectrum (Mallett & Yuksel 2019's basis) whose colour under D65 is that
    RGB; a grey one is the number's flat spectrum, bit for bit; the sky above is unchanged."""
    import colour
    green = (0.08, 0.16, 0.04)
    rho = atm.ground_reflectance(green)
    assert rho.shape == atm.spectra()[0].shape and np.all((rho >= 0) & (rho <= 1))
    d65 = colour.SDS_ILLUMINANTS["D65"].copy().align(colour.SPECTRAL_SHAPE_DEFAULT).values
    weights = atm.spectra()[3]
    xyz = (rho * d65) @ weights / (d65 @ weights)[1]
    rgb = np.asarray(colour.RGB_COLOURSPACES[DEFAULT_COLOURSPACE].matrix_XYZ_to_RGB) @ xyz
    np.testing.assert_allclose(rgb, green, rtol=0.01)
    assert atm.ground_reflectance([0.3, 0.3, 0.3]) == 0.3
    np.testing.assert_array_equal(atm.sky_table(35.0, 0.1, ground_albedo=[0.1, 0.1, 0.1]), atm.sky_table(35.0, 0.1))
    coloured = atm.sky_table(35.0, 0.1, ground_albedo=green)
    np.testing.assert_array_equal(coloured[90:], atm.sky_table(35.0, 0.1)[90:])
    monkeypatch.setattr(atm, "GROUND_AIR_PATH", 0.0)  # the bare ground: about the albedo times a white one's
    bare = atm.sky_xyz(35.0, 0.1, green)
    white = atm.sky_xyz(35.0, 0.1, 1.0)
    to_rgb = np.asarray(colour.RGB_COLOURSPACES[DEFAULT_COLOURSPACE].matrix_XYZ_to_RGB)
    np.testing.assert_allclose(to_rgb @ bare[0] / (to_rgb @ white[0]), green, rtol=0.08)
    assert np.argmax(to_rgb @ bare[0]) == 1  # green
    for bad in ([0.1, 0.2], [0.1, 1.2, 0.0], -0.1, [[0.1, 0.1, 0.1]]):
        with pytest.raises(ValueError, match="ground_albedo"):
            atm.ground_albedo_of(bad)


def test_09_sky_mean_weights_by_solid_angle():
    np.testing.assert_allclose(atm.sky_mean(np.full((181, 3), 0.7)), 0.7, rtol=1e-12)
    half = np.zeros((181, 3))
    half[91:] = 1.0  # the upper hemisphere, the horizon row not counted
    np.testing.assert_allclose(atm.sky_mean(half), 0.5, atol=0.005)
    t = atm.sky_table(30.0)
    assert t.shape == (181, 3) and not t.flags.writeable and np.all(t >= 0)


def test_10_the_store_keeps_colour_sciences_numbers(monkeypatch, tmp_path):
    """A later process reads the spectra back from the store bit for bit, without computing them again."""
    import cloudmeta.scene.colour as cc

    def fresh():
        monkeypatch.setenv("CLOUDMETA_CACHE_DIR", str(tmp_path))
        monkeypatch.delenv("CLOUDMETA_NO_CACHE", raising=False)
        monkeypatch.setattr(cc, "_STORE", None)
        atm.spectra.cache_clear()
        atm._sky_table.cache_clear()

    fresh()
    first = [a.copy() for a in atm.spectra()] + [atm.sky_table(20.0).copy()]
    fresh()
    monkeypatch.setattr(atm, "_compute_spectra", lambda: pytest.fail("computed again, not read from the store"))
    second = list(atm.spectra()) + [atm.sky_table(20.0)]
    for a, b in zip(first, second):
        np.testing.assert_array_equal(a, b)
    atm.spectra.cache_clear()
    atm._sky_table.cache_clear()


# ------------------------------------------------------------------------------------------- the scene keys

BASE = {
    "image": {"width": 8, "height": 6},
    "camera": {"position": [0, -12, 2], "look_at": [0, 0, 2]},
    "background": [0.3, 0.45, 0.8],
    "lights": [{"type": "sun", "elevation": 30, "azimuth": 90}],
    "media": [{"balls": [{"center": [0, 0, 2], "radius": 1.5}]}],
}


def load(tmp_path, **changes):
    data = copy.deepcopy(BASE)
    for key, value in changes.items():
        if value is None:
            data.pop(key, None)
        else:
            data[key] = value
    path = tmp_path / "scene.yaml"
    path.write_text(yaml.safe_dump(data))
    return load_scene(path)


def fails(tmp_path, where, fragment, **changes):
    with pytest.raises(SceneError) as info:
        load(tmp_path, **changes)
    text = str(info.value)
    assert "scene.yaml" in text and f"{where}:" in text and fragment in text, text


def test_11_sun_light_is_a_directional_light(tmp_path):
    s = load(tmp_path)
    sun, = s.lights
    assert isinstance(sun, SunLight) and isinstance(sun, DirectionalLight) and sun.KIND == "directional"
    np.testing.assert_allclose(sun.direction, [np.cos(np.radians(30)), 0, 0.5], atol=1e-15)
    np.testing.assert_allclose(sun.irradiance, 16.0 * atm.sun_rgb(30.0, atm.DEFAULT_AEROSOL_DEPTH), rtol=1e-15)
    assert s.sky is None
    np.testing.assert_array_equal(s.background, [0.3, 0.45, 0.8])

    s = load(tmp_path, lights=[{"type": "sun", "elevation": 60, "turbidity": 3, "irradiance": 2}])
    np.testing.assert_allclose(s.lights[0].direction, [0, 0.5, np.sin(np.radians(60))], atol=1e-15)
    np.testing.assert_allclose(s.lights[0].irradiance, 2 * atm.sun_rgb(60.0, atm.turbidity_to_aerosol_depth(3)))
    s = load(tmp_path, lights=[{"type": "sun", "elevation": 45, "azimuth": 225, "aerosol_depth": 0}])
    np.testing.assert_allclose(s.lights[0].direction, [-0.5, -0.5, np.sqrt(0.5)], atol=1e-15)
    assert s.lights[0].sun.aerosol_depth == 0.0


@pytest.mark.parametrize("light,where,fragment", [
    ({"color": [1, 1, 1]}, "lights[0].color", "atmosphere"),
    ({"elevation": -3}, "lights[0].elevation", "0 (the horizon)"),
    ({"elevation": None}, "lights[0].elevation", "missing required key"),
    ({"turbidity": 3, "aerosol_depth": 0.1}, "lights[0].aerosol_depth", "not both"),
    ({"turbidity": 0.5}, "lights[0].turbidity", "turbidity"),
    ({"aerosol_depth": -0.1}, "lights[0].aerosol_depth", "550 nm"),
    ({"irradiance": -1}, "lights[0].irradiance", ">= 0"),
    ({"direction": [0, 0, 1]}, "lights[0].direction", "unknown key"),
    ({"azimuth": 400}, "lights[0].azimuth", "compass"),
])
def test_12_bad_suns(tmp_path, light, where, fragment):
    raw = {"type": "sun", "elevation": 30}
    raw.update(light)
    raw = {k: v for k, v in raw.items() if v is not None}
    fails(tmp_path, where, fragment, lights=[raw])


def test_13_background_sky_is_the_suns(tmp_path):
    s = load(tmp_path, background="sky")
    np.testing.assert_allclose(s.sky, 16.0 * atm.sky_table(30.0, atm.DEFAULT_AEROSOL_DEPTH), rtol=1e-15)
    assert s.sky.shape == (181, 3) and not s.sky.flags.writeable
    np.testing.assert_allclose(s.background, atm.sky_mean(s.sky), rtol=1e-15)
    assert s.ambient is None


def test_14_explicit_sky_without_a_sun(tmp_path):
    sky = {"sky": {"elevation": 20, "turbidity": 4, "irradiance": 10, "ground_albedo": 0.3}}
    s = load(tmp_path, background=sky, lights=None)
    np.testing.assert_allclose(s.sky, 10 * atm.sky_table(20.0, atm.turbidity_to_aerosol_depth(4), DEFAULT_COLOURSPACE,
                                                         0.3), rtol=1e-15)
    assert s.lights == ()


def test_14b_a_coloured_ground_in_the_scene(tmp_path):
    brown = [0.2, 0.12, 0.06]
    s = load(tmp_path, background={"sky": {"ground_albedo": brown}})  # the sun's sky over that ground
    np.testing.assert_allclose(s.sky, 16.0 * atm.sky_table(30.0, atm.DEFAULT_AEROSOL_DEPTH, ground_albedo=brown),
                               rtol=1e-15)
    assert s.sky[0, 0] > s.sky[0, 1] > s.sky[0, 2]  # brown, looking down
    np.testing.assert_allclose(s.background, atm.sky_mean(s.sky), rtol=1e-15)
    s = load(tmp_path, background={"sky": {"elevation": 20, "ground_albedo": [0.05, 0.1, 0.03]}}, lights=None)
    np.testing.assert_allclose(s.sky, 16.0 * atm.sky_table(20.0, atm.DEFAULT_AEROSOL_DEPTH,
                                                           ground_albedo=(0.05, 0.1, 0.03)), rtol=1e-15)
    s = load(tmp_path, background={"sky": {"ground_albedo": 0.1}})
    np.testing.assert_array_equal(s.sky, load(tmp_path, background="sky").sky)


def test_14c_a_ground_placed_in_the_scene(tmp_path):
    """ground_height places the sky's ground at z = height (the clouds shade it: renderer.ground); the sky itself
    is unchanged, and without the key the scene has no ground."""
    assert load(tmp_path, background="sky").ground is None
    assert load(tmp_path, background={"sky": {"ground_albedo": 0.3}}).ground is None
    s = load(tmp_path, background={"sky": {"ground_height": -0.5, "ground_albedo": 0.3}})
    np.testing.assert_array_equal(s.sky, load(tmp_path, background={"sky": {"ground_albedo": 0.3}}).sky)
    assert s.ground.height == -0.5
    np.testing.assert_allclose(s.ground.direction, s.lights[0].direction, atol=1e-15)
    np.testing.assert_allclose(s.ground.sun, 16.0 * atm.ground_sun_table(30.0, ground_albedo=0.3), rtol=1e-15)
    assert not s.ground.sun.flags.writeable
    s = load(tmp_path, background={"sky": {"elevation": 20, "azimuth": 180, "ground_height": 1.0}}, lights=None)
    np.testing.assert_allclose(s.ground.direction, [0.0, -np.cos(np.radians(20)), np.sin(np.radians(20))], atol=1e-15)


@pytest.mark.parametrize("changes,where,fragment", [
    (dict(background={"sky": {"ground_height": 2.0}}), "background.sky.ground_height", "below the camera's height"),
    (dict(background={"sky": {"ground_height": 5}}), "background.sky.ground_height", "(its z, 2)"),
    (dict(background={"sky": {"ground_height": "low"}}), "background.sky.ground_height", "a number below"),
    (dict(background={"sky": {"elevation": 30, "ground_height": [0]}}), "background.sky.ground_height", "below"),
    (dict(background={"sky": {"ground_albedo": [0.1, 1.5, 0.1]}}), "background.sky.ground_albedo", "[r, g, b]"),
    (dict(background={"sky": {"ground_albedo": [0.1, 0.1]}}), "background.sky.ground_albedo", "[r, g, b]"),
    (dict(background={"sky": {"ground_albedo": "green"}}), "background.sky.ground_albedo", "[r, g, b]"),
    (dict(background={"sky": {"ground_albedo": 0.2}}, lights=None), "background", "found none"),
    (dict(background="sky", lights=None), "background", "found none"),
    (dict(background="sky", lights=[{"type": "sun", "elevation": 30}, {"type": "sun", "elevation": 40}]),
     "background", "found 2"),
    (dict(background="skye"), "background", "sky"),
    (dict(background={"sky": {"elevation": 30}, "colour": 1}), "background.colour", "unknown key"),
    (dict(background={"sky": {"elevation": 30, "color": [1, 1, 1]}}), "background.sky.color", "unknown key"),
    (dict(background={"sky": {"azimuth": 30}}), "background.sky.elevation", "missing required key"),
    (dict(background={"sky": {"elevation": 30, "ground_albedo": 2}}), "background.sky.ground_albedo", "[0, 1]"),
    (dict(background={"sky": "clear"}), "background.sky", "mapping"),
    (dict(ambient="sky", lights=None), "ambient", "found none"),
    (dict(ambient={"sky": {"elevation": 30}}), "ambient", "sky"),
])
def test_15_bad_skies(tmp_path, changes, where, fragment):
    fails(tmp_path, where, fragment, **changes)


def test_16_ambient_sky_is_the_skys_mean(tmp_path):
    s = load(tmp_path, background="sky", ambient="sky")
    np.testing.assert_array_equal(s.ambient, atm.sky_mean(s.sky))
    s = load(tmp_path, ambient="sky")  # no sky in the background: the sun's own
    assert s.sky is None
    np.testing.assert_allclose(s.ambient, atm.sky_mean(16.0 * atm.sky_table(30.0)), rtol=1e-15)
    s = load(tmp_path, background={"sky": {"elevation": 10, "ground_albedo": 0.5}}, ambient="sky")
    np.testing.assert_array_equal(s.ambient, atm.sky_mean(s.sky))


def test_17_plain_backgrounds_are_unchanged(tmp_path):
    s = load(tmp_path, ambient=[0.05, 0.07, 0.1])
    np.testing.assert_array_equal(s.background, np.array([0.3, 0.45, 0.8]))
    np.testing.assert_array_equal(s.ambient, np.array([0.05, 0.07, 0.1]))
    assert s.sky is None
    s = load(tmp_path, background={"temperature": 6500}, ambient={"illuminant": "D65"})
    np.testing.assert_array_equal(s.background, parse_colour({"temperature": 6500}, "b"))
    np.testing.assert_array_equal(s.ambient, parse_colour({"illuminant": "D65"}, "a"))
    s = load(tmp_path, background=None, ambient=None)
    np.testing.assert_array_equal(s.background, [0.0, 0.0, 0.0])
    assert s.ambient is None and s.sky is None
