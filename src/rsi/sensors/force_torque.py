"""Seed §3 F: the ISEE's six-axis force/torque sensor, with Gaussian noise, a bias, and taring.

A strain-gauge wrench sensor reads the true wrench plus an offset (gauge drift, the weight of whatever
hangs below it at tare time) plus noise. Taring averages readings taken with no contact and subtracts
that average afterwards. Wrenches are ``(Fx, Fy, Fz, Tx, Ty, Tz)`` in N and N m, in the sensor frame.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from rsi import _validate as v
from rsi.errors import InputError

FloatArray = NDArray[np.float64]

WRENCH_SIZE = 6


def _as_wrenches(wrench: object, name: str) -> FloatArray:
    values = v.as_float_array(wrench, name)
    if values.ndim == 0 or values.shape[-1] != WRENCH_SIZE:
        raise InputError(
            f"{name} must have shape (..., 6) = (Fx, Fy, Fz, Tx, Ty, Tz) in N and N m; got {values.shape}."
        )
    if not np.isfinite(values).all():
        raise InputError(f"{name} contains NaN or inf; pass finite forces (N) and torques (N m).")
    return values


@dataclass(frozen=True)
class ForceTorqueSensor:
    """Settings of a six-axis force/torque sensor.

    Parameters
    ----------
    force_noise_std_n : float
        Standard deviation of each force channel's noise in newtons, >= 0.
    torque_noise_std_n_m : float
        Standard deviation of each torque channel's noise in newton metres, >= 0.
    bias : tuple of 6 floats
        Offset added to every reading, ``(Fx, Fy, Fz)`` in N then ``(Tx, Ty, Tz)`` in N m.
    """

    force_noise_std_n: float = 0.05
    torque_noise_std_n_m: float = 0.002
    bias: tuple[float, float, float, float, float, float] = (1.2, -0.7, 3.4, 0.04, -0.02, 0.01)

    def __post_init__(self) -> None:
        checks: dict[str, object] = {
            "force_noise_std_n": v.in_range(self.force_noise_std_n, "force_noise_std_n", low=0.0),
            "torque_noise_std_n_m": v.in_range(self.torque_noise_std_n_m, "torque_noise_std_n_m", low=0.0),
            "bias": tuple(float(value) for value in _as_wrenches(self.bias, "bias")),
        }
        v.store_checked(self, checks)

    @property
    def noise_std(self) -> FloatArray:
        """Per-channel noise standard deviations, shape (6,) (N, N, N, N m, N m, N m)."""
        return np.repeat([self.force_noise_std_n, self.torque_noise_std_n_m], 3)


def read_wrench(
    true_wrench: object,
    sensor: ForceTorqueSensor | None = None,
    *,
    rng: np.random.Generator | int | None = None,
) -> FloatArray:
    """Raw readings of the sensor: true wrench + bias + Gaussian noise.

    Parameters
    ----------
    true_wrench : array_like of shape (..., 6)
        Wrenches acting on the sensor, ``(Fx, Fy, Fz, Tx, Ty, Tz)`` in N and N m.
    sensor : ForceTorqueSensor, optional
        Sensor settings.
    rng : numpy.random.Generator or int or None
        Noise source; identical seeds give identical readings.

    Returns
    -------
    ndarray of shape (..., 6), float64
    """
    settings = ForceTorqueSensor() if sensor is None else v.instance_of(sensor, "sensor", ForceTorqueSensor)
    wrench = _as_wrenches(true_wrench, "true_wrench")
    noise = settings.noise_std * v.as_rng(rng).standard_normal(wrench.shape)
    return np.asarray(wrench + np.asarray(settings.bias) + noise, dtype=np.float64)


def tare(unloaded_readings: object) -> FloatArray:
    """Estimate the bias from readings taken with no contact: their mean, shape (6,).

    Subtract the result from later readings. The estimate's error per channel is the noise standard
    deviation over ``sqrt(n)``, so average many samples.
    """
    readings = _as_wrenches(unloaded_readings, "unloaded_readings").reshape(-1, WRENCH_SIZE)
    return np.asarray(readings.mean(axis=0), dtype=np.float64)


__all__: list[str] = ["WRENCH_SIZE", "ForceTorqueSensor", "read_wrench", "tare"]
