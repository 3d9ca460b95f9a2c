"""Seed §3 and §4: the 8-12 um optical pyrometer, its emissivity setting, and why the seed used black Kapton.

Measurement model (an opaque grey surface in a room, seen through the instrument's band)::

    L_seen = eps_true * L(T_surface) + (1 - eps_true) * L(T_background)          (emitted + reflected)
    L_seen = eps_set  * L(T_read)    + (1 - eps_set)  * L(T_reflected_setting)   (what the instrument assumes)

where ``L(T)`` is Planck's spectral radiance integrated over 8-12 um (band radiance, W m^-2 sr^-1). The
instrument solves the second line for ``T_read`` by root finding. With ``eps_set = eps_true`` and the
reflected-temperature setting equal to the background, ``T_read = T_surface`` exactly.

Why black Kapton (seed §4): bare aluminium has emissivity ~0.05, so 95 % of what the pyrometer sees is the
reflected room; a hot spot 60 K above the room changes the signal by a few per cent, and any error in the
assumed emissivity or background turns into tens of kelvin. Black Kapton (emissivity ~0.95) makes the
surface's own emission dominate, and the same emissivity uncertainty costs well under a kelvin.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from scipy import optimize, special

from rsi import _validate as v
from rsi.constants import ROOM_TEMPERATURE_K
from rsi.errors import InputError
from rsi.units import fahrenheit_to_kelvin

FloatArray = NDArray[np.float64]
BoolArray = NDArray[np.bool_]

PLANCK_J_S = 6.62607015e-34
LIGHT_SPEED_M_S = 299792458.0
BOLTZMANN_J_K = 1.380649e-23
_C1_W_M2_SR = 2.0 * PLANCK_J_S * LIGHT_SPEED_M_S**2  # first radiation constant for radiance
_C2_M_K = PLANCK_J_S * LIGHT_SPEED_M_S / BOLTZMANN_J_K  # second radiation constant

BAND_M = (8e-6, 12e-6)  # seed §3: 8-12 micron
# Gauss-Legendre on a smooth integrand over a 4 um band: 24 nodes integrate it to ~1e-14 relative.
_NODES, _WEIGHTS = special.roots_legendre(24)
_NEWTON_STEPS = 50


def _band_nodes_m(band_m: tuple[float, float]) -> tuple[FloatArray, FloatArray]:
    low, high = band_m
    half = (high - low) / 2.0
    return low + half * (_NODES + 1.0), half * _WEIGHTS


def _as_temperatures_k(temperature_k: object, name: str) -> FloatArray:
    values = v.as_float_array(temperature_k, name)
    if not np.isfinite(values).all() or (values <= 0).any():
        raise InputError(f"{name} must be finite and > 0 K; got {temperature_k!r}.")
    return values


def band_radiance_w_m2_sr(temperature_k: object, *, band_m: tuple[float, float] = BAND_M) -> FloatArray:
    """Blackbody radiance integrated over a wavelength band (W m^-2 sr^-1).

    Parameters
    ----------
    temperature_k : array_like
        Temperatures in kelvin, > 0.
    band_m : (float, float)
        Band edges in metres (default 8-12 um, seed §3).

    Returns
    -------
    ndarray of the shape of `temperature_k`

    Notes
    -----
    ``L(T) = integral_band c1 / lambda^5 / (exp(c2 / (lambda T)) - 1) d lambda`` with
    ``c1 = 2 h c^2`` and ``c2 = h c / k``, by 24-point Gauss-Legendre quadrature (scipy.special).
    """
    temperature = _as_temperatures_k(temperature_k, "temperature_k")
    wavelength_m, weight_m = _band_nodes_m(v.increasing_pair(band_m, "band_m", unit="m"))
    spectral = _C1_W_M2_SR / wavelength_m**5 / np.expm1(_C2_M_K / (wavelength_m * temperature[..., None]))
    return np.asarray(spectral @ weight_m, dtype=np.float64)


def _band_radiance_slope(temperature_k: FloatArray, band_m: tuple[float, float]) -> FloatArray:
    """dL/dT of the band radiance, W m^-2 sr^-1 K^-1 (for Newton's method)."""
    wavelength_m, weight_m = _band_nodes_m(band_m)
    x = _C2_M_K / (wavelength_m * temperature_k[..., None])
    spectral = _C1_W_M2_SR / wavelength_m**5 * np.exp(x) / np.expm1(x) ** 2 * x / temperature_k[..., None]
    return np.asarray(spectral @ weight_m, dtype=np.float64)


def invert_band_radiance_k(
    radiance_w_m2_sr: object, *, band_m: tuple[float, float] = BAND_M, bracket_k: tuple[float, float]
) -> FloatArray:
    """Temperature whose band radiance equals `radiance_w_m2_sr`, by Newton root finding (kelvin).

    Radiances are first clipped to the radiances of `bracket_k`, so the answer always lies in the bracket
    (the band radiance is strictly increasing in temperature).
    """
    low_k, high_k = v.increasing_pair(bracket_k, "bracket_k", unit="K")
    band_m = v.increasing_pair(band_m, "band_m", unit="m")
    limits = band_radiance_w_m2_sr(np.array([low_k, high_k]), band_m=band_m)
    radiance = v.as_float_array(radiance_w_m2_sr, "radiance_w_m2_sr")
    if np.isnan(radiance).any():
        raise InputError("radiance_w_m2_sr contains NaN; pass radiances in W m^-2 sr^-1.")
    target = np.clip(radiance, limits[0], limits[1])
    start = np.full(target.shape, high_k)  # L is convex in T: Newton from above never overshoots below
    root: FloatArray = optimize.newton(
        lambda t: band_radiance_w_m2_sr(t, band_m=band_m) - target,
        start,
        fprime=lambda t: _band_radiance_slope(np.asarray(t), band_m),
        maxiter=_NEWTON_STEPS,
        tol=1e-9,
    )
    return np.asarray(np.clip(root, low_k, high_k), dtype=np.float64)


@dataclass(frozen=True)
class Pyrometer:
    """Settings of the ISEE's optical pyrometer (seed §3: 8-12 um, 0-1000 degF, laser sighted).

    Parameters
    ----------
    emissivity_setting : float
        Emissivity the instrument assumes, in (0, 1].
    reflected_temperature_k : float
        Background temperature the instrument assumes for the reflected part, > 0 K.
    min_temperature_k, max_temperature_k : float
        Span in kelvin (seed §3: 0-1000 degF = 255.37-810.93 K); readings saturate at its ends.
    noise_std_k : float
        Standard deviation of the reading noise in kelvin, >= 0.
    field_of_view_rad : float
        Full cone angle of the optics, in (0, pi) rad (default: a 20:1 distance-to-spot ratio).
    aperture_m : float
        Diameter of the spot at the lens, >= 0 m.
    band_m : (float, float)
        Spectral band in metres, 0 < low < high.
    """

    emissivity_setting: float = 0.95
    reflected_temperature_k: float = ROOM_TEMPERATURE_K
    min_temperature_k: float = fahrenheit_to_kelvin(0.0)
    max_temperature_k: float = fahrenheit_to_kelvin(1000.0)
    noise_std_k: float = 0.1
    field_of_view_rad: float = 2.0 * float(np.arctan(1.0 / 40.0))
    aperture_m: float = 0.01
    band_m: tuple[float, float] = BAND_M

    def __post_init__(self) -> None:
        checks: dict[str, object] = {
            "emissivity_setting": v.in_range(
                self.emissivity_setting, "emissivity_setting", low=0.0, high=1.0, low_inclusive=False
            ),
            "reflected_temperature_k": v.in_range(
                self.reflected_temperature_k, "reflected_temperature_k", low=0.0, low_inclusive=False
            ),
            "min_temperature_k": v.in_range(
                self.min_temperature_k, "min_temperature_k", low=0.0, low_inclusive=False
            ),
            "noise_std_k": v.in_range(self.noise_std_k, "noise_std_k", low=0.0),
            "field_of_view_rad": v.in_range(
                self.field_of_view_rad,
                "field_of_view_rad",
                low=0.0,
                high=float(np.pi),
                low_inclusive=False,
                high_inclusive=False,
            ),
            "aperture_m": v.in_range(self.aperture_m, "aperture_m", low=0.0),
        }
        checks["max_temperature_k"] = v.in_range(
            self.max_temperature_k,
            "max_temperature_k",
            low=float(checks["min_temperature_k"]),  # type: ignore[arg-type]
            low_inclusive=False,
        )
        checks["band_m"] = v.increasing_pair(self.band_m, "band_m", unit="m")
        v.store_checked(self, checks)

    @property
    def span_k(self) -> tuple[float, float]:
        """(lowest, highest) temperature the instrument reports, kelvin."""
        return (self.min_temperature_k, self.max_temperature_k)

    def spot_diameter_m(self, distance_m: object) -> FloatArray:
        """Diameter of the measured spot at `distance_m` metres from the lens (metres).

        ``aperture + 2 d tan(fov / 2)``: the cone of the optics widens from the lens aperture.
        """
        distance = v.as_float_array(distance_m, "distance_m")
        if not np.isfinite(distance).all() or (distance < 0).any():
            raise InputError(f"distance_m must be finite and >= 0 m; got {distance_m!r}.")
        return np.asarray(self.aperture_m + 2.0 * distance * np.tan(self.field_of_view_rad / 2.0))


@dataclass(frozen=True)
class PyrometerReading:
    """What the pyrometer reports.

    Attributes
    ----------
    temperature_k : ndarray
        Reported temperature in kelvin, clipped to the span.
    saturated : ndarray of bool
        True where the apparent temperature fell outside the span (the reading sits at a span end).
    radiance_w_m2_sr : ndarray
        Band radiance reaching the instrument (emitted + reflected), W m^-2 sr^-1.
    """

    temperature_k: FloatArray
    saturated: BoolArray
    radiance_w_m2_sr: FloatArray


def read_pyrometer(
    surface_temperature_k: object,
    surface_emissivity: object,
    pyrometer: Pyrometer | None = None,
    *,
    background_temperature_k: float = ROOM_TEMPERATURE_K,
    rng: np.random.Generator | int | None = None,
) -> PyrometerReading:
    """Pyrometer reading of grey surfaces at known temperatures and emissivities.

    Parameters
    ----------
    surface_temperature_k : array_like
        True surface temperatures in kelvin, inside the instrument's span (seed §3: 0-1000 degF).
    surface_emissivity : array_like
        True emissivities in (0, 1], broadcastable to `surface_temperature_k` (aluminium ~0.05, black
        Kapton ~0.95, seed §4).
    pyrometer : Pyrometer, optional
        Instrument settings (emissivity setting 0.95 by default: set for Kapton).
    background_temperature_k : float
        Temperature of the surroundings the surface reflects, > 0 K (a laboratory room by default).
    rng : numpy.random.Generator or int or None
        Noise source; identical seeds give identical readings.

    Returns
    -------
    PyrometerReading

    Examples
    --------
    >>> reading = read_pyrometer(350.0, 0.95, rng=0)
    >>> bool(abs(float(reading.temperature_k) - 350.0) < 0.5)
    True
    """
    settings = Pyrometer() if pyrometer is None else v.instance_of(pyrometer, "pyrometer", Pyrometer)
    temperature = _as_temperatures_k(surface_temperature_k, "surface_temperature_k")
    low_k, high_k = settings.span_k
    if (temperature < low_k).any() or (temperature > high_k).any():
        raise InputError(
            f"surface_temperature_k must lie in the pyrometer's span [{low_k:.2f}, {high_k:.2f}] K "
            f"(0-1000 degF, seed §3); got {surface_temperature_k!r}. Widen the span or convert units "
            "(rsi.units.fahrenheit_to_kelvin)."
        )
    emissivity = v.as_float_array(surface_emissivity, "surface_emissivity")
    if not np.isfinite(emissivity).all() or (emissivity <= 0).any() or (emissivity > 1).any():
        raise InputError(f"surface_emissivity must lie in (0, 1]; got {surface_emissivity!r}.")
    try:
        np.broadcast_shapes(emissivity.shape, temperature.shape)
    except ValueError:
        raise InputError(
            f"surface_emissivity (shape {emissivity.shape}) must broadcast to surface_temperature_k (shape "
            f"{temperature.shape}); pass one emissivity, or one per temperature."
        ) from None
    background = v.in_range(
        background_temperature_k, "background_temperature_k", low=0.0, low_inclusive=False
    )
    band = settings.band_m
    seen = emissivity * band_radiance_w_m2_sr(temperature, band_m=band) + (1.0 - emissivity) * float(
        band_radiance_w_m2_sr(background, band_m=band)
    )
    reflected = float(band_radiance_w_m2_sr(settings.reflected_temperature_k, band_m=band))
    emitted = (seen - (1.0 - settings.emissivity_setting) * reflected) / settings.emissivity_setting
    apparent = invert_band_radiance_k(emitted, band_m=band, bracket_k=(low_k / 2.0, high_k * 2.0))
    noisy = apparent + settings.noise_std_k * v.as_rng(rng).standard_normal(apparent.shape)
    return PyrometerReading(
        temperature_k=np.clip(noisy, low_k, high_k),
        saturated=(noisy < low_k) | (noisy > high_k),
        radiance_w_m2_sr=np.asarray(seen, dtype=np.float64),
    )


__all__: list[str] = [
    "BAND_M",
    "Pyrometer",
    "PyrometerReading",
    "band_radiance_w_m2_sr",
    "invert_band_radiance_k",
    "read_pyrometer",
]
