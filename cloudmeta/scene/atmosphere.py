"""The sun and the sky of a clear atmosphere, through colour-science (docs/atmosphere.md).

A light ``type: sun`` and a ``background: sky`` are given by the sun's elevation and the air's aerosol load;
their colour and strength follow from the atmosphere:

- the extraterrestrial sun E0(lambda) is colour-science's ASTM G-173 extraterrestrial spectrum, scaled to
  luminance Y = 1;
- the Rayleigh optical depth tau_R(lambda) of a sea-level standard atmosphere is colour-science's
  (``colour.phenomena.sd_rayleigh_scattering``, Bodhaine et al. 1999);
- the aerosol optical depth is Angstrom's law tau_A(lambda) = tau_A(550 nm) (lambda / 550 nm)^-1.3, its
  value at 550 nm given as ``aerosol_depth`` or from a ``turbidity`` T through Preetham et al. (1999):
  Angstrom's beta = 0.04608 T - 0.04586 (the depth at 1 um), tau_A(550 nm) = beta 0.55^-1.3;
- the relative air mass m(h) at elevation h is Kasten & Young (1989);
- the sun seen from the ground is E0 exp(-m(h) (tau_R + tau_A)) (``sun_xyz``, ``sun_rgb``);
- the sky is the light of that sun scattered once in a plane-parallel atmosphere, averaged over azimuth,
  above a Lambertian ground (``sky_table``); the formulas are in ``_sky_spectra`` and docs/atmosphere.md.

Spectra become XYZ with the CIE 1931 2 degree observer and XYZ becomes linear RGB of the working colourspace
with colour-science's matrix, without chromatic adaptation, as every colour of cloudmeta.scene.colour.

Start-up: colour-science gives four things on 360-780 nm at 1 nm (colour-science's default wavelengths):
the ASTM spectrum, the Rayleigh optical depth, and the XYZ weights of its spectral integration (the XYZ that
``colour.msds_to_XYZ`` gives each wavelength alone, so that ``spectrum @ weights`` is its ``sd_to_XYZ``).
They are kept in colour.py's store, so a later process computes any sun and sky with numpy alone, in a few
milliseconds, without importing colour-science, and the store does not grow with the suns asked for.
"""
from __future__ import annotations

import functools
import importlib.util
import os
from dataclasses import dataclass

import numpy as np

from .colour import _CMFS, DEFAULT_COLOURSPACE, _colour, _space, _stored

#: Angstrom's wavelength exponent of the aerosol optical depth (Preetham et al. 1999 use 1.3)
ANGSTROM_ALPHA = 1.3
#: the wavelength, nm, at which ``aerosol_depth`` is given
AEROSOL_REFERENCE_NM = 550.0
#: the aerosols' Henyey-Greenstein asymmetry and single-scattering albedo (continental haze)
AEROSOL_G = 0.7
AEROSOL_ALBEDO = 0.9
#: tau_A(550 nm) when a sun names neither ``turbidity`` nor ``aerosol_depth``: a clear sky (about T = 2)
DEFAULT_AEROSOL_DEPTH = 0.1
#: the accepted ``turbidity`` and ``aerosol_depth`` (clear to very hazy; the single-scattering sky is poor
#: well before the upper ends, see docs/atmosphere.md)
TURBIDITY_RANGE = (1.0, 20.0)
AEROSOL_DEPTH_RANGE = (0.0, 5.0)
#: the sun's elevation, degrees: Kasten & Young's air mass holds from the horizon up
ELEVATION_RANGE = (0.0, 90.0)
DEFAULT_GROUND_ALBEDO = 0.1
#: the air between the observer and the ground: a line of sight at depression d crosses GROUND_AIR_PATH / sin d
#: air masses before it meets the ground (an observer 0.1 scale heights up: about 800 m under the 8 km of the
#: Rayleigh atmosphere), at most the horizon's; so the ground fades into the haze towards the horizon
GROUND_AIR_PATH = 0.1
#: the sky table: rows are view elevations -90 .. 90 degrees, 1 degree apart (row i: elevation i - 90)
SKY_ROWS = 181
#: azimuths the sky's phase functions are averaged over (a full circle, 5 degrees apart)
_AZIMUTHS = 72
#: Gauss-Legendre nodes in elevation of the sky's irradiance on the ground
_IRRADIANCE_NODES = 96
_STORE_KEY = "atmosphere:ASTM G-173 ETR, Rayleigh Bodhaine 1999 sea level, " + _CMFS + ", 360-780 nm 1 nm"
_BASIS_KEY = "atmosphere:Mallett-Yuksel 2019 sRGB basis, linear, 360-780 nm 1 nm"


def turbidity_to_aerosol_depth(turbidity):
    """tau_A(550 nm) of a turbidity T: Angstrom's beta = 0.04608 T - 0.04586 (Preetham et al. 1999, their
    turbidity T: the optical depth of haze and air over that of air alone), the depth at 1 um, times
    (0.55)^-1.3. Never below 0 (T = 1, pure air, gives beta = 0.00022)."""
    beta = 0.04608 * float(turbidity) - 0.04586
    return max(beta, 0.0) * (AEROSOL_REFERENCE_NM / 1000.0) ** -ANGSTROM_ALPHA


def air_mass(elevation_deg):
    """Kasten & Young (1989): the relative optical air mass at the true elevation h (degrees, >= 0),
    m = 1 / (sin h + 0.50572 (h + 6.07995)^-1.6364); 37.92 at the horizon, 0.9997 at the zenith."""
    h = np.asarray(elevation_deg, dtype=np.float64)
    return 1.0 / (np.sin(np.radians(h)) + 0.50572 * (h + 6.07995) ** -1.6364)


def _astm_g173_etr():
    """colour-science's ASTM G-173 extraterrestrial spectrum. It lives in ``colour.plotting.datasets``, whose
    package imports matplotlib; its module needs only colour.algebra and colour.colorimetry, so it is read
    from its file when that is where this colour-science keeps it (no matplotlib), else imported."""
    colour = _colour()
    path = os.path.join(os.path.dirname(colour.__file__), "plotting", "datasets", "astm_g_173.py")
    if os.path.isfile(path):
        spec = importlib.util.spec_from_file_location("_cloudmeta_astm_g_173", path)
        module = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(module)
        return module.SD_ASTMG173_ETR
    from colour.plotting.datasets import SD_ASTMG173_ETR
    return SD_ASTMG173_ETR


def _compute_spectra():
    colour = _colour()
    from colour.colorimetry import reshape_msds

    shape = colour.SPECTRAL_SHAPE_DEFAULT
    wavelengths = shape.wavelengths
    cmfs = reshape_msds(colour.MSDS_CMFS[_CMFS], shape)
    weights = colour.msds_to_XYZ(np.eye(len(wavelengths)), cmfs, colour.sd_ones(shape), method="Integration",
                                 shape=shape)
    return dict(wavelengths=wavelengths.tolist(),
                sun=np.asarray(_astm_g173_etr()[wavelengths], np.float64).tolist(),
                rayleigh=colour.phenomena.sd_rayleigh_scattering(shape).values.tolist(),
                weights=np.ravel(weights).tolist())


@functools.lru_cache(maxsize=1)
def spectra():
    """(wavelengths nm, E0 with Y = 1, tau_R, XYZ weights (n, 3)), read-only float64: colour-science's
    numbers (through the store) on its default wavelengths, 360-780 nm at 1 nm."""
    values = _stored(_STORE_KEY, _compute_spectra)
    wl, sun, rayleigh = (np.array(values[k], np.float64) for k in ("wavelengths", "sun", "rayleigh"))
    weights = np.array(values["weights"], np.float64).reshape(-1, 3)
    sun = sun / (sun @ weights[:, 1])
    for a in (wl, sun, rayleigh, weights):
        a.setflags(write=False)
    return wl, sun, rayleigh, weights


def _compute_basis():
    colour = _colour()
    from colour.algebra import LinearInterpolator
    from colour.recovery import MSDS_BASIS_FUNCTIONS_sRGB_MALLETT2019
    # linear between colour-science's 5 nm samples and constant beyond 380 nm: each stays in [0, 1] and
    # the three sum to 1 (within 1e-5), so a grey stays flat
    basis = MSDS_BASIS_FUNCTIONS_sRGB_MALLETT2019.copy().align(colour.SPECTRAL_SHAPE_DEFAULT,
                                                                 interpolator=LinearInterpolator)
    return np.asarray(basis.values, np.float64).T.tolist()


def ground_albedo_of(value):
    """A ground albedo as the sky functions take it: a float for a grey ground, a tuple of 3 floats for a
    coloured one (linear BT.709 reflectances, each in [0, 1]); one equal in all three is the grey.
    ValueError otherwise."""
    if np.ndim(value) == 0:
        albedo = float(value)
        if not 0.0 <= albedo <= 1.0:
            raise ValueError(f"ground_albedo: expected an albedo in [0, 1], got {value!r}")
        return albedo
    rgb = tuple(float(v) for v in np.asarray(value, np.float64).ravel())
    if np.shape(value) != (3,) or not all(0.0 <= v <= 1.0 for v in rgb):
        raise ValueError(f"ground_albedo: expected an albedo in [0, 1] or [r, g, b] each in [0, 1], got {value!r}")
    return rgb[0] if rgb[0] == rgb[1] == rgb[2] else rgb


def ground_reflectance(albedo):
    """The ground's reflectance on the wavelengths of ``spectra()``: a grey albedo (a number) as it is, flat;
    an RGB albedo (linear BT.709, whatever the working colourspace) as the spectrum of Mallett & Yuksel
    (2019, colour-science's ``RGB_to_sd_Mallett2019``): r, g and b weights of three smooth basis spectra that
    sum to 1, so the spectrum stays in [0, 1] and its colour under D65 is the RGB's."""
    albedo = ground_albedo_of(albedo)
    if isinstance(albedo, float):
        return albedo
    basis = np.array(_stored(_BASIS_KEY, _compute_basis), np.float64)
    return np.asarray(albedo) @ basis


def _check(elevation_deg, aerosol_depth):
    lo, hi = ELEVATION_RANGE
    if not lo <= elevation_deg <= hi:
        raise ValueError(f"the sun's elevation: expected degrees in [{lo:g}, {hi:g}], got {elevation_deg!r}")
    lo, hi = AEROSOL_DEPTH_RANGE
    if not lo <= aerosol_depth <= hi:
        raise ValueError(f"aerosol_depth: expected tau_A(550 nm) in [{lo:g}, {hi:g}], got {aerosol_depth!r}")


def _depths(aerosol_depth):
    """(tau_R, tau_A): the Rayleigh and aerosol optical depths on the wavelengths of ``spectra()``."""
    wl, _, tau_r, _ = spectra()
    tau_a = aerosol_depth * (wl / AEROSOL_REFERENCE_NM) ** -ANGSTROM_ALPHA
    return tau_r, tau_a


def _rgb(xyz, colourspace):
    """Linear RGB of ``colourspace`` of XYZ (..., 3), negative components (out of gamut) clipped to 0, as
    cloudmeta.scene.colour.parse_colour does."""
    matrix = np.array(_space(colourspace)["XYZ_to_RGB"]).reshape(3, 3)
    return np.maximum(np.asarray(xyz) @ matrix.T, 0.0)


def sun_spectrum(elevation_deg, aerosol_depth=DEFAULT_AEROSOL_DEPTH):
    """The sun seen from the ground, E0(lambda) exp(-m (tau_R + tau_A)), E0 with luminance Y = 1, on the
    wavelengths of ``spectra()``."""
    _check(elevation_deg, aerosol_depth)
    _, sun, _, _ = spectra()
    tau_r, tau_a = _depths(aerosol_depth)
    return sun * np.exp(-air_mass(elevation_deg) * (tau_r + tau_a))


def sun_xyz(elevation_deg, aerosol_depth=DEFAULT_AEROSOL_DEPTH):
    """(3,) XYZ of the sun at ``elevation_deg`` seen from the ground; 1 is the luminance it has outside
    the atmosphere."""
    return sun_spectrum(elevation_deg, aerosol_depth) @ spectra()[3]


def sun_rgb(elevation_deg, aerosol_depth=DEFAULT_AEROSOL_DEPTH, colourspace=DEFAULT_COLOURSPACE):
    """(3,) linear RGB in ``colourspace`` of the sun at ``elevation_deg`` (0 .. 90 degrees) through an
    atmosphere whose aerosol optical depth at 550 nm is ``aerosol_depth``, per unit extraterrestrial
    luminance: its colour times its transmittance (docs/atmosphere.md)."""
    return _rgb(sun_xyz(float(elevation_deg), float(aerosol_depth)), colourspace)


def _mean_phases(view_deg, sun_deg):
    """(Rayleigh, aerosol HG) phase functions (1/sr) averaged over the azimuth between the view and the sun,
    at the view elevations ``view_deg`` (n,): (n,), (n,). cos theta = l . v (docs/model.md §4)."""
    e = np.radians(np.asarray(view_deg, np.float64))[:, None]
    s = np.radians(sun_deg)
    phi = np.arange(_AZIMUTHS) * (2.0 * np.pi / _AZIMUTHS)
    cos_theta = np.sin(e) * np.sin(s) + np.cos(e) * np.cos(s) * np.cos(phi)
    rayleigh = 3.0 / (16.0 * np.pi) * (1.0 + cos_theta ** 2)
    g = AEROSOL_G
    hg = (1.0 - g * g) / (4.0 * np.pi * (1.0 + g * g - 2.0 * g * cos_theta) ** 1.5)
    return rayleigh.mean(axis=1), hg.mean(axis=1)


def _sky_spectra(view_deg, sun_deg, aerosol_depth):
    """(n, wavelengths) spectral radiance of the sky at view elevations ``view_deg`` >= 0 (degrees), per unit
    extraterrestrial luminance, averaged over azimuth.

    Single scattering in a plane-parallel atmosphere where air and aerosol are mixed in the same proportion
    at every height (so only optical depths matter, whatever the density profile): seen from the ground
    along a direction of air mass m_v, with the sun at air mass m_s and total optical depth tau,

        L = E0 sum_k omega_k tau_k <p_k> m_v (exp(-tau m_s) - exp(-tau m_v)) / (tau (m_v - m_s))

    (the limit tau m_s exp(-tau m_s) / tau where m_v = m_s), k = Rayleigh (omega = 1) and aerosol
    (omega = AEROSOL_ALBEDO), <p_k> their phase function averaged over azimuth. Air masses are Kasten &
    Young's, so the horizon (m_v = 37.9) stays finite.
    """
    _, sun, _, _ = spectra()
    tau_r, tau_a = _depths(aerosol_depth)
    tau = tau_r + tau_a
    p_r, p_a = _mean_phases(view_deg, sun_deg)
    m_v = air_mass(view_deg)[:, None]
    a = tau * air_mass(sun_deg)             # (wavelengths,)
    b = tau * m_v                           # (n, wavelengths)
    d = np.abs(b - a)
    with np.errstate(invalid="ignore", divide="ignore"):
        ratio = np.where(d > 0, -np.expm1(-d) / d, 1.0)   # (1 - e^-d) / d, 1 at d = 0
    path = np.exp(-np.minimum(a, b)) * ratio              # (e^-a - e^-b) / (b - a)
    scattering = tau_r * p_r[:, None] + AEROSOL_ALBEDO * tau_a * p_a[:, None]
    return sun * scattering * path * m_v


@functools.lru_cache(maxsize=1)
def _gauss_elevations():
    x, w = np.polynomial.legendre.leggauss(_IRRADIANCE_NODES)
    e = (x + 1.0) * (np.pi / 4.0)           # elevations in (0, pi/2)
    return np.degrees(e), w * (np.pi / 4.0) * np.sin(e) * np.cos(e) * 2.0 * np.pi


def ground_air_mass(view_deg):
    """The air masses between the observer and the ground along view elevations ``view_deg`` < 0 (degrees):
    GROUND_AIR_PATH / sin(depression), at most the horizon's air mass (Kasten & Young)."""
    depression = np.radians(-np.asarray(view_deg, np.float64))
    with np.errstate(divide="ignore"):
        return np.minimum(GROUND_AIR_PATH / np.sin(depression), air_mass(0.0))


def _ground_transmittance(view_deg, aerosol_depth):
    """(n, wavelengths) the air's transmittance between the observer and the ground along view elevations
    ``view_deg`` < 0 (``ground_air_mass``)."""
    tau_r, tau_a = _depths(aerosol_depth)
    return np.exp(-(tau_r + tau_a) * ground_air_mass(view_deg)[:, None])


def _ground_spectra(view_deg, sun_deg, aerosol_depth, ground):
    """(n, wavelengths) the ground of spectral radiance ``ground`` seen along view elevations ``view_deg`` < 0
    through the air below the observer (``ground_air_mass``): L = ground T + L_air (1 - T), T = exp(-tau m_g),
    L_air = E0 exp(-tau m_s) sum_k omega_k tau_k <p_k> / tau, the light of the sun (as it reaches the ground)
    scattered once towards the observer per unit optical path: the sky's formula (``_sky_spectra``) for a
    path low in the air, over which the sun's transmittance is the ground's."""
    _, sun, _, _ = spectra()
    tau_r, tau_a = _depths(aerosol_depth)
    tau = tau_r + tau_a
    p_r, p_a = _mean_phases(view_deg, sun_deg)
    transmittance = _ground_transmittance(view_deg, aerosol_depth)
    with np.errstate(invalid="ignore", divide="ignore"):
        air = sun * np.exp(-tau * air_mass(sun_deg)) * np.where(
            tau > 0, (tau_r * p_r[:, None] + AEROSOL_ALBEDO * tau_a * p_a[:, None]) / tau, 0.0)
    return ground * transmittance + air * (1.0 - transmittance)


def sky_xyz(sun_elevation_deg, aerosol_depth=DEFAULT_AEROSOL_DEPTH, ground_albedo=DEFAULT_GROUND_ALBEDO):
    """(181, 3) XYZ of the sky's radiance at view elevations -90 .. 90 degrees (row i: elevation i - 90),
    per unit extraterrestrial luminance of the sun. Above the horizon, ``_sky_spectra``; below it a
    Lambertian ground of albedo ``ground_albedo`` (grey, or [r, g, b]: ``ground_reflectance``) lit by the sun (sin h E0 exp(-m tau)) and the sky,
    L = albedo / pi (E_sun + E_sky), E_sky = integral over the upper hemisphere of L cos(zenith), seen through
    the air below the observer (``_ground_spectra``): towards the horizon it fades into the haze."""
    s, aerosol_depth = float(sun_elevation_deg), float(aerosol_depth)
    _check(s, aerosol_depth)
    reflectance = ground_reflectance(ground_albedo)
    weights = spectra()[3]
    sky = _sky_spectra(np.arange(0.0, 91.0), s, aerosol_depth)
    nodes, node_weights = _gauss_elevations()
    e_sky = node_weights @ _sky_spectra(nodes, s, aerosol_depth)
    e_sun = np.sin(np.radians(s)) * sun_spectrum(s, aerosol_depth)
    ground = reflectance / np.pi * (e_sun + e_sky)
    out = np.empty((SKY_ROWS, 3))
    out[:90] = _ground_spectra(np.arange(-90.0, 0.0), s, aerosol_depth, ground) @ weights
    out[90:] = sky @ weights
    return out


def ground_sun_xyz(sun_elevation_deg, aerosol_depth=DEFAULT_AEROSOL_DEPTH, ground_albedo=DEFAULT_GROUND_ALBEDO):
    """(181, 3) XYZ, rows as ``sky_xyz``'s: below the horizon the part of the ground's radiance that the sun
    lights directly, albedo / pi sin h E_sun, seen through the air below the observer; 0 above the horizon.
    It is what a cloud's shadow takes from ``sky_xyz``'s ground where the cloud hides the sun entirely
    (docs/atmosphere.md, *The clouds' shadow on the ground*)."""
    s, aerosol_depth = float(sun_elevation_deg), float(aerosol_depth)
    _check(s, aerosol_depth)
    view = np.arange(-90.0, 0.0)
    lit = ground_reflectance(ground_albedo) / np.pi * np.sin(np.radians(s)) * sun_spectrum(s, aerosol_depth)
    out = np.zeros((SKY_ROWS, 3))
    out[:90] = (lit * _ground_transmittance(view, aerosol_depth)) @ spectra()[3]
    return out


def ground_sun_table(sun_elevation_deg, aerosol_depth=DEFAULT_AEROSOL_DEPTH, colourspace=DEFAULT_COLOURSPACE,
                     ground_albedo=DEFAULT_GROUND_ALBEDO):
    """(181, 3) read-only linear RGB of ``ground_sun_xyz``, per unit extraterrestrial luminance, as
    ``sky_table`` gives the sky."""
    return _sky_table(float(sun_elevation_deg), float(aerosol_depth), colourspace, ground_albedo_of(ground_albedo),
                      ground_sun_xyz)


@functools.lru_cache(maxsize=64)
def _sky_table(sun_elevation_deg, aerosol_depth, colourspace, ground_albedo, xyz_of=sky_xyz):
    """Read-only linear RGB of the table ``xyz_of`` (sky_xyz, or ground_sun_xyz) gives, kept per sun and ground."""
    table = _rgb(xyz_of(sun_elevation_deg, aerosol_depth, ground_albedo), colourspace)
    table.setflags(write=False)
    return table


def sky_table(sun_elevation_deg, aerosol_depth=DEFAULT_AEROSOL_DEPTH, colourspace=DEFAULT_COLOURSPACE,
              ground_albedo=DEFAULT_GROUND_ALBEDO):
    """(181, 3) read-only linear RGB in ``colourspace`` of the sky's radiance at view elevations -90 .. 90
    degrees, 1 degree apart (row i: elevation i - 90; z is up), per unit extraterrestrial luminance of a
    sun at ``sun_elevation_deg``: the sun's ``irradiance`` multiplies it. The sky is taken as the same at
    every azimuth (averaged over it). Negative components (out of gamut) are clipped to 0. ``ground_albedo``:
    a number (grey) or [r, g, b] (``ground_reflectance``)."""
    return _sky_table(float(sun_elevation_deg), float(aerosol_depth), colourspace, ground_albedo_of(ground_albedo))


def sky_mean(table):
    """(3,) the mean over the whole sphere (by solid angle) of a sky table: its rows weighted by the cosine
    of their elevation."""
    table = np.asarray(table, np.float64)
    w = np.cos(np.radians(np.arange(table.shape[0]) - (table.shape[0] - 1) / 2.0))
    w = np.maximum(w, 0.0)
    return w @ table / w.sum()


@dataclass(frozen=True)
class Sun:
    """A sun and its atmosphere as a scene gives them (a ``type: sun`` light, ``background: {sky: ...}``)."""
    elevation: float      #: degrees above the horizon, 0 .. 90
    azimuth: float        #: compass degrees: 0 towards +y (north), 90 towards +x (east)
    aerosol_depth: float  #: tau_A at 550 nm
    irradiance: float     #: the extraterrestrial luminance: it scales the sun's colour and its sky

    def direction(self):
        """(3,) the unit vector towards the sun: (sin az cos el, cos az cos el, sin el), z up."""
        el, az = np.radians(self.elevation), np.radians(self.azimuth)
        return np.array([np.sin(az) * np.cos(el), np.cos(az) * np.cos(el), np.sin(el)])

    def rgb(self, colourspace=DEFAULT_COLOURSPACE):
        """(3,) the sun's colour at unit extraterrestrial luminance (``sun_rgb``)."""
        return sun_rgb(self.elevation, self.aerosol_depth, colourspace)

    def sky(self, colourspace=DEFAULT_COLOURSPACE, ground_albedo=DEFAULT_GROUND_ALBEDO):
        """(181, 3) its sky's radiance (``sky_table``) times ``irradiance``: rows are elevations -90 .. 90."""
        with np.errstate(over="ignore"):
            return self.irradiance * sky_table(self.elevation, self.aerosol_depth, colourspace, ground_albedo)

    def ground_sun(self, colourspace=DEFAULT_COLOURSPACE, ground_albedo=DEFAULT_GROUND_ALBEDO):
        """(181, 3) the sunlit part of its sky's ground (``ground_sun_table``) times ``irradiance``."""
        with np.errstate(over="ignore"):
            return self.irradiance * ground_sun_table(self.elevation, self.aerosol_depth, colourspace, ground_albedo)
