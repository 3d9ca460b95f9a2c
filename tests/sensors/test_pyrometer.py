"""Optical pyrometer (seed §3, §4): Planck band radiance, inversion, Kapton vs aluminium, spot, errors."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy import integrate

from rsi.errors import InputError
from rsi.sensors.pyrometer import (
    BOLTZMANN_J_K,
    LIGHT_SPEED_M_S,
    PLANCK_J_S,
    Pyrometer,
    band_radiance_w_m2_sr,
    invert_band_radiance_k,
    read_pyrometer,
)
from rsi.units import fahrenheit_to_kelvin

KAPTON_EMISSIVITY = 0.95  # seed §4: black Kapton glued over the Peltier hot/cold spots
ALUMINIUM_EMISSIVITY = 0.05
ROOM_K = 293.15
HOT_SPOT_K = 350.0
QUIET = Pyrometer(noise_std_k=0.0)


def _planck_w_m3_sr(wavelength_m: float, temperature_k: float) -> float:
    numerator = 2 * PLANCK_J_S * LIGHT_SPEED_M_S**2 / wavelength_m**5
    return float(
        numerator / np.expm1(PLANCK_J_S * LIGHT_SPEED_M_S / (wavelength_m * BOLTZMANN_J_K * temperature_k))
    )


@pytest.mark.parametrize("temperature_k", [200.0, 300.0, 600.0, 1000.0])
def test_band_radiance_matches_adaptive_quadrature(temperature_k: float) -> None:
    reference, _ = integrate.quad(_planck_w_m3_sr, 8e-6, 12e-6, args=(temperature_k,), epsabs=0, epsrel=1e-12)
    assert band_radiance_w_m2_sr(temperature_k) == pytest.approx(reference, rel=1e-10)


def test_band_radiance_is_monotone_in_temperature() -> None:
    temperature = np.linspace(50.0, 2000.0, 5000)
    assert (np.diff(band_radiance_w_m2_sr(temperature)) > 0).all()


def test_inversion_recovers_temperature_across_the_span() -> None:
    temperature = np.linspace(*QUIET.span_k, 300)
    recovered = invert_band_radiance_k(band_radiance_w_m2_sr(temperature), bracket_k=(100.0, 1600.0))
    np.testing.assert_allclose(recovered, temperature, atol=1e-6)


@settings(max_examples=60, deadline=None)
@given(
    temperature_k=st.floats(fahrenheit_to_kelvin(0.0), fahrenheit_to_kelvin(1000.0)),
    emissivity=st.floats(0.05, 1.0),
    seed=st.integers(0, 2**16),
)
def test_matched_emissivity_setting_recovers_temperature(
    temperature_k: float, emissivity: float, seed: int
) -> None:
    pyrometer = Pyrometer(emissivity_setting=emissivity)  # noise 0.1 K: 0.5 K is five sigma
    reading = read_pyrometer(temperature_k, emissivity, pyrometer, background_temperature_k=ROOM_K, rng=seed)
    assert abs(float(reading.temperature_k) - temperature_k) < 0.5


def test_kapton_reads_within_a_kelvin_and_bare_aluminium_is_far_off() -> None:
    # seed §4: one instrument setting (for Kapton) looking at both surfaces of the same hot spot
    kapton, aluminium = read_pyrometer(
        HOT_SPOT_K, [KAPTON_EMISSIVITY, ALUMINIUM_EMISSIVITY], background_temperature_k=ROOM_K, rng=0
    ).temperature_k
    assert abs(kapton - HOT_SPOT_K) < 1.0
    assert abs(aluminium - HOT_SPOT_K) > 40.0  # it reads close to the reflected room


def test_emissivity_and_background_errors_cost_little_on_kapton_and_much_on_aluminium() -> None:
    errors_k = {}
    for name, emissivity in {"kapton": KAPTON_EMISSIVITY, "aluminium": ALUMINIUM_EMISSIVITY}.items():
        # the setting is right but the true emissivity is off by 0.01, and the room is 7 K warmer than set
        pyrometer = dataclasses.replace(QUIET, emissivity_setting=emissivity)
        reading = read_pyrometer(HOT_SPOT_K, emissivity - 0.01, pyrometer, background_temperature_k=300.0)
        errors_k[name] = abs(float(reading.temperature_k) - HOT_SPOT_K)
    assert errors_k["kapton"] < 1.0
    assert errors_k["aluminium"] > 20.0 * errors_k["kapton"]


def test_reading_saturates_at_the_span_ends() -> None:
    # aluminium in orbit reflects cold space: the apparent temperature falls below the span
    reading = read_pyrometer(300.0, ALUMINIUM_EMISSIVITY, QUIET, background_temperature_k=3.0)
    assert bool(reading.saturated)
    assert float(reading.temperature_k) == QUIET.min_temperature_k
    assert not bool(read_pyrometer(300.0, KAPTON_EMISSIVITY, QUIET).saturated)


def test_spot_grows_with_distance_from_the_aperture() -> None:
    pyrometer = Pyrometer()
    spots = pyrometer.spot_diameter_m([0.0, 0.4, 0.8])
    assert spots[0] == pytest.approx(pyrometer.aperture_m)
    assert spots[1] == pytest.approx(pyrometer.aperture_m + 0.4 / 20.0)  # default 20:1 distance to spot
    assert spots[2] - spots[1] == pytest.approx(spots[1] - spots[0])


def test_determinism_by_seed() -> None:
    temperatures = np.linspace(300.0, 700.0, 20)
    first, again, other = (read_pyrometer(temperatures, 0.9, rng=seed).temperature_k for seed in (4, 4, 5))
    np.testing.assert_array_equal(first, again)
    assert not np.array_equal(first, other)


@pytest.mark.parametrize(
    ("changes", "fragment"),
    [
        ({"emissivity_setting": 0.0}, "emissivity_setting must be in"),
        ({"emissivity_setting": 1.2}, "emissivity_setting must be in"),
        ({"reflected_temperature_k": -1.0}, "reflected_temperature_k must be in"),
        ({"min_temperature_k": 0.0}, "min_temperature_k must be in"),
        ({"max_temperature_k": 200.0}, "max_temperature_k must be in"),
        ({"noise_std_k": -0.1}, "noise_std_k must be in"),
        ({"field_of_view_rad": 4.0}, "field_of_view_rad must be in"),
        ({"aperture_m": float("nan")}, "aperture_m must be finite"),
        ({"band_m": (12e-6, 8e-6)}, "band_m must be"),
    ],
)
def test_pyrometer_rejects_each_bad_setting_by_name(changes: dict[str, object], fragment: str) -> None:
    with pytest.raises(InputError, match=fragment):
        dataclasses.replace(Pyrometer(), **changes)  # type: ignore[arg-type]


@pytest.mark.parametrize(
    ("temperature", "emissivity", "fragment"),
    [
        (200.0, 0.9, "surface_temperature_k must lie in the pyrometer's span"),
        (900.0, 0.9, "surface_temperature_k must lie in the pyrometer's span"),
        (float("nan"), 0.9, "surface_temperature_k must be finite and > 0 K"),
        (-5.0, 0.9, "surface_temperature_k must be finite and > 0 K"),
        (300.0, 0.0, r"surface_emissivity must lie in \(0, 1\]"),
        (300.0, 1.5, r"surface_emissivity must lie in \(0, 1\]"),
    ],
)
def test_read_rejects_bad_surfaces(temperature: float, emissivity: float, fragment: str) -> None:
    with pytest.raises(InputError, match=fragment):
        read_pyrometer(temperature, emissivity, rng=0)


def test_other_bad_arguments_are_named() -> None:
    with pytest.raises(InputError, match="background_temperature_k must be in"):
        read_pyrometer(300.0, 0.9, background_temperature_k=0.0)
    with pytest.raises(InputError, match="distance_m must be finite and >= 0 m"):
        Pyrometer().spot_diameter_m(-0.1)
    with pytest.raises(InputError, match="temperature_k must be finite and > 0 K"):
        band_radiance_w_m2_sr([300.0, 0.0])
