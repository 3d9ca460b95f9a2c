"""MOS gas sensor (seed §3 H, §4 ammonia leaks): power law, inversion, response/recovery, drift, errors."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from rsi.errors import InputError
from rsi.sensors.gas import MosGasSensor, read_gas

QUIET = MosGasSensor(noise_relative=0.0)


def test_power_law_at_known_points() -> None:
    sensor = MosGasSensor(baseline_ohm=40e3, scale_ppm=10.0, exponent=0.5)
    resistance = sensor.resistance_ohm([0.0, 30.0])
    assert resistance.tolist() == pytest.approx([40e3, 40e3 / 2.0])  # (1 + 30/10)^-0.5 = 1/2


@settings(max_examples=60, deadline=None)
@given(concentration_ppm=st.floats(0.0, 1e4), exponent=st.floats(0.2, 1.0))
def test_steady_state_inverts_to_the_concentration(concentration_ppm: float, exponent: float) -> None:
    sensor = MosGasSensor(exponent=exponent)
    recovered = sensor.concentration_ppm(sensor.resistance_ohm(concentration_ppm))
    assert recovered == pytest.approx(concentration_ppm, rel=1e-9, abs=1e-9)


def test_long_exposure_reads_the_concentration() -> None:
    readings = read_gas(np.full(2000, 25.0), QUIET)
    assert readings.estimated_ppm[-1] == pytest.approx(25.0, rel=1e-6)


@pytest.mark.parametrize("direction", ["response", "recovery"])
def test_first_order_step_reaches_63_percent_at_one_time_constant(direction: str) -> None:
    rate_hz = QUIET.sample_rate_hz
    tau_s = {"response": QUIET.response_time_s, "recovery": QUIET.recovery_time_s}[direction]
    soak = int(20 * QUIET.response_time_s * rate_hz)  # long enough to settle at 50 ppm
    after = round(tau_s * rate_hz)
    step = {
        "response": np.r_[np.zeros(1), np.full(after + 1, 50.0)],
        "recovery": np.r_[np.full(soak, 50.0), np.zeros(after + 1)],
    }[direction]
    start = {"response": 1, "recovery": soak}[direction]
    estimated = read_gas(step, QUIET).estimated_ppm
    moved = abs(estimated[start + after] - estimated[start]) / 50.0
    assert moved == pytest.approx(1.0 - np.exp(-1.0), abs=0.005)


def test_recovery_is_slower_than_response() -> None:
    pulse = np.r_[np.full(300, 40.0), np.zeros(300)]
    estimated = read_gas(pulse, QUIET).estimated_ppm
    rise_to_half = int(np.argmax(estimated >= 20.0))
    fall_to_half = int(np.argmax(estimated[300:] <= 20.0))
    assert fall_to_half > 2 * rise_to_half


def test_baseline_drift_fakes_gas_unless_the_baseline_is_updated() -> None:
    sensor = dataclasses.replace(QUIET, drift_per_s=-1e-3)
    readings = read_gas(np.zeros(1000), sensor)
    assert readings.estimated_ppm[-1] > 0.5  # a falling baseline reads as gas
    drifted_ohm = sensor.baseline_ohm * (1.0 + sensor.drift_per_s * readings.time_s[-1])
    corrected = sensor.concentration_ppm(readings.resistance_ohm[-1], baseline_ohm=drifted_ohm)
    assert corrected == pytest.approx(0.0, abs=1e-9)


def test_determinism_by_seed() -> None:
    concentration = np.r_[np.zeros(50), np.full(100, 10.0)]
    first, again, other = (read_gas(concentration, rng=seed).resistance_ohm for seed in (3, 3, 4))
    np.testing.assert_array_equal(first, again)
    assert not np.array_equal(first, other)


@pytest.mark.parametrize(
    ("changes", "fragment"),
    [
        ({"baseline_ohm": 0.0}, "baseline_ohm must be in"),
        ({"scale_ppm": -1.0}, "scale_ppm must be in"),
        ({"exponent": 0.0}, "exponent must be in"),
        ({"response_time_s": -1.0}, "response_time_s must be in"),
        ({"recovery_time_s": 0.0}, "recovery_time_s must be in"),
        ({"drift_per_s": float("nan")}, "drift_per_s must be finite"),
        ({"noise_relative": -0.1}, "noise_relative must be in"),
        ({"sample_rate_hz": 0.0}, "sample_rate_hz must be in"),
    ],
)
def test_gas_sensor_rejects_each_bad_setting_by_name(changes: dict[str, float], fragment: str) -> None:
    with pytest.raises(InputError, match=fragment):
        dataclasses.replace(MosGasSensor(), **changes)


def test_gas_functions_reject_bad_input_by_name() -> None:
    with pytest.raises(InputError, match="concentration_ppm must be finite and >= 0 ppm"):
        read_gas([1.0, -2.0])
    with pytest.raises(InputError, match="concentration_ppm must be finite and >= 0 ppm"):
        read_gas([1.0, float("nan")])
    with pytest.raises(InputError, match="concentration_ppm must be a non-empty 1-D time series"):
        read_gas(np.zeros((2, 3)))
    with pytest.raises(InputError, match="resistance_ohm must be finite and > 0 ohm"):
        MosGasSensor().concentration_ppm([1e3, 0.0])
    with pytest.raises(InputError, match="baseline_ohm must be in"):
        MosGasSensor().resistance_ohm(1.0, baseline_ohm=-5.0)
