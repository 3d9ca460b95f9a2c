"""IR triangulation proximity sensor (seed §3.1): curve, A/D, filter, range flags, determinism, errors."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from rsi.errors import InputError
from rsi.sensors.proximity import (
    LowPassFilter,
    ProximityChannel,
    ProximitySensor,
    as_distances_m,
    read_proximity,
)

SENSOR = ProximitySensor()


def test_response_curve_is_inverse_in_distance_and_linearises_exactly() -> None:
    distance = np.linspace(SENSOR.min_distance_m, SENSOR.max_distance_m, 50)
    volts = SENSOR.voltage_v(distance)
    assert volts[0] == pytest.approx(SENSOR.voltage_at_min_v)
    assert (np.diff(volts) < 0).all()
    # triangulation: V (d + d0) is constant
    np.testing.assert_allclose(volts * (distance + SENSOR.lens_offset_m), volts[0] * (distance[0] + 0.02))
    np.testing.assert_allclose(SENSOR.distance_m(volts), distance, rtol=1e-12)
    assert SENSOR.voltage_v([SENSOR.max_distance_m + 0.01, np.inf]).tolist() == [0.0, 0.0]
    assert SENSOR.distance_m(0.0) == np.inf


def test_readings_are_quantised_to_adc_counts() -> None:
    readings = read_proximity(np.full(100, 0.4), rng=1)
    counts = readings.raw_v / SENSOR.adc_step_v
    np.testing.assert_allclose(counts, np.round(counts), atol=1e-9)


@pytest.mark.parametrize("distance_m", [0.1, 0.3, 0.5, 0.7])
def test_steady_readings_are_accurate_and_filtered_is_quieter(distance_m: float) -> None:
    readings = read_proximity(np.full(440, distance_m), rng=2)
    settled = readings.filtered_m[44:]
    assert abs(settled.mean() - distance_m) < 0.003
    assert settled.std() < readings.raw_m[44:].std() / 2
    assert not readings.out_of_range.any()


def test_out_of_range_flag_beyond_max_and_below_min() -> None:
    truth = np.r_[np.full(88, 0.3), np.full(88, 1.5), np.full(88, 0.02)]
    readings = read_proximity(truth, rng=3)
    assert not readings.out_of_range[:88].any()
    assert readings.out_of_range[130:176].all()  # no return: 0 V, filtered reading runs out
    assert readings.out_of_range[-44:].all()  # too near: clipped at the rail, reads below the minimum
    assert (readings.filtered_m[-44:] < SENSOR.min_distance_m).all()


def test_determinism_by_seed() -> None:
    truth = np.linspace(0.1, 0.9, 200)
    first, again, other = (read_proximity(truth, rng=seed) for seed in (7, 7, 8))
    np.testing.assert_array_equal(first.filtered_m, again.filtered_m)
    np.testing.assert_array_equal(first.out_of_range, again.out_of_range)
    assert not np.array_equal(first.raw_v, other.raw_v)


def test_per_sample_channel_matches_the_batch() -> None:
    truth = np.r_[np.linspace(0.2, 0.6, 60), np.full(10, 2.0)]
    batch = read_proximity(truth, rng=11)
    channel = ProximityChannel(rng=11)
    streamed = [channel.read(float(distance)) for distance in truth]
    np.testing.assert_allclose([reading for reading, _ in streamed], batch.filtered_m, rtol=1e-12)
    assert [flag for _, flag in streamed] == batch.out_of_range.tolist()


def test_filter_update_and_batch_agree_and_constant_passes_without_transient() -> None:
    samples = np.random.default_rng(0).normal(size=64)
    stepwise = LowPassFilter(4.0, 44.0, order=2)
    batch = LowPassFilter(4.0, 44.0, order=2)
    np.testing.assert_allclose([stepwise.update(x) for x in samples], batch.filter(samples), rtol=1e-12)
    constant = LowPassFilter(4.0, 44.0)
    np.testing.assert_allclose(constant.filter(np.full(20, 3.3)), 3.3)
    constant.reset()
    assert constant.update(-1.0) == pytest.approx(-1.0)


@pytest.mark.parametrize("order", [1, 2])
def test_filter_lag_on_a_ramp_is_its_dc_group_delay(order: int) -> None:
    rate_hz, cutoff_hz, slope_m_s = 44.0, 4.0, 0.1
    time_s = np.arange(440) / rate_hz
    smoother = LowPassFilter(cutoff_hz, rate_hz, order=order)
    lag_s = (slope_m_s * time_s - smoother.filter(slope_m_s * time_s))[-1] / slope_m_s
    assert lag_s == pytest.approx(smoother.dc_delay_s, rel=1e-3)
    if order == 1:  # first order: delay ~ 1 / (2 pi fc), up to the bilinear transform's warping
        assert lag_s == pytest.approx(1.0 / (2 * np.pi * cutoff_hz), rel=0.1)


@pytest.mark.parametrize(
    ("changes", "fragment"),
    [
        ({"min_distance_m": 0.0}, "min_distance_m must be in"),
        ({"max_distance_m": 0.05}, "max_distance_m must be in"),
        ({"lens_offset_m": -0.01}, "lens_offset_m must be in"),
        ({"voltage_at_min_v": 6.0}, "voltage_at_min_v must be in"),
        ({"full_scale_v": 0.0}, "full_scale_v must be in"),
        ({"noise_std_v": -0.1}, "noise_std_v must be in"),
        ({"noise_std_v": float("nan")}, "noise_std_v must be finite"),
        ({"adc_bits": 0}, "adc_bits must be an integer"),
        ({"adc_bits": 25}, "adc_bits must be in 1..24"),
        ({"sample_rate_hz": -44.0}, "sample_rate_hz must be in"),
        ({"cutoff_hz": 22.0}, "cutoff_hz must be in"),
        ({"filter_order": 0}, "filter_order must be an integer"),
    ],
)
def test_sensor_rejects_each_bad_setting_by_name(changes: dict[str, object], fragment: str) -> None:
    with pytest.raises(InputError, match=fragment):
        dataclasses.replace(SENSOR, **changes)  # type: ignore[arg-type]


@pytest.mark.parametrize(
    ("truth", "fragment"),
    [
        ([0.3, -0.1], "true_distance_m must be >= 0 m"),
        ([0.3, float("nan")], "true_distance_m contains NaN"),
        (np.zeros((2, 2)), "true_distance_m must be a non-empty 1-D time series"),
        ([], "true_distance_m must be a non-empty 1-D time series"),
    ],
)
def test_read_proximity_rejects_bad_distances(truth: object, fragment: str) -> None:
    with pytest.raises(InputError, match=fragment):
        read_proximity(truth, rng=0)


def test_distance_helper_and_filter_reject_bad_input() -> None:
    with pytest.raises(InputError, match="d contains NaN or inf"):
        as_distances_m([np.inf], "d")
    with pytest.raises(InputError, match="d must be a number or an array of numbers"):
        as_distances_m(["far"], "d")
    with pytest.raises(InputError, match="cutoff_hz must be in"):
        LowPassFilter(30.0, 44.0)
    with pytest.raises(InputError, match="order must be an integer"):
        LowPassFilter(4.0, 44.0, order=0)
    with pytest.raises(InputError, match="samples must be a non-empty 1-D array"):
        LowPassFilter(4.0, 44.0).filter([])
    with pytest.raises(InputError, match="sample must be finite"):
        LowPassFilter(4.0, 44.0).update(float("nan"))
    with pytest.raises(InputError, match="rng must be"):
        read_proximity([0.3], rng="seed")  # type: ignore[arg-type]
