"""Six-axis force/torque sensor (seed §3 F): noise, bias, tare, determinism, errors."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from rsi.errors import InputError
from rsi.sensors.force_torque import ForceTorqueSensor, read_wrench, tare

SENSOR = ForceTorqueSensor()
CONTACT = np.array([0.5, -0.2, 12.0, 0.01, 0.03, -0.002])  # N, N, N, N m, N m, N m


def test_readings_carry_the_bias_and_the_stated_noise() -> None:
    readings = read_wrench(np.tile(CONTACT, (20000, 1)), SENSOR, rng=0)
    assert (np.abs(readings.mean(axis=0) - CONTACT - SENSOR.bias) < 4 * SENSOR.noise_std / 141).all()
    np.testing.assert_allclose(readings.std(axis=0), SENSOR.noise_std, rtol=0.03)


def test_tare_removes_the_bias() -> None:
    unloaded = read_wrench(np.zeros((400, 6)), SENSOR, rng=1)
    loaded = read_wrench(np.tile(CONTACT, (400, 1)), SENSOR, rng=2)
    tared = loaded - tare(unloaded)
    # error of the difference of two 400-sample means: sqrt(2) sigma / 20 per channel; allow 5 of those
    assert (np.abs(tared.mean(axis=0) - CONTACT) < 5 * np.sqrt(2) * SENSOR.noise_std / 20).all()
    assert np.abs(loaded.mean(axis=0) - CONTACT)[2] > 3.0  # without the tare, Fz is off by the bias


def test_determinism_by_seed() -> None:
    first, again, other = (read_wrench(CONTACT, rng=seed) for seed in (5, 5, 6))
    np.testing.assert_array_equal(first, again)
    assert not np.array_equal(first, other)


@pytest.mark.parametrize(
    ("changes", "fragment"),
    [
        ({"force_noise_std_n": -1.0}, "force_noise_std_n must be in"),
        ({"torque_noise_std_n_m": float("nan")}, "torque_noise_std_n_m must be finite"),
        ({"bias": (1.0, 2.0)}, r"bias must have shape \(..., 6\)"),
        ({"bias": (0.0, 0.0, float("inf"), 0.0, 0.0, 0.0)}, "bias contains NaN or inf"),
    ],
)
def test_sensor_rejects_each_bad_setting_by_name(changes: dict[str, object], fragment: str) -> None:
    with pytest.raises(InputError, match=fragment):
        dataclasses.replace(SENSOR, **changes)  # type: ignore[arg-type]


def test_functions_reject_bad_wrenches_by_name() -> None:
    with pytest.raises(InputError, match=r"true_wrench must have shape \(..., 6\)"):
        read_wrench(np.zeros(5))
    with pytest.raises(InputError, match="true_wrench contains NaN or inf"):
        read_wrench([0, 0, float("nan"), 0, 0, 0])
    with pytest.raises(InputError, match=r"unloaded_readings must have shape \(..., 6\)"):
        tare(3.0)
