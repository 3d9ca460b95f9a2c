"""Seed §3 and §4: the metal-oxide-semiconductor (MOS) gas sensor that sniffs the mock-up's ammonia leaks.

Static response. A MOS sensor's resistance falls as a reducing gas is adsorbed; over a wide range the
data sheets of such sensors are straight lines on log-log axes, which we write with a finite clean-air
value as::

    R(C) = R0 * (1 + C / C0) ** (-beta)

``R0`` is the clean-air (baseline) resistance, ``C0`` the concentration scale where the response bends
from linear to a power law, and ``beta`` the log-log slope (0.3-0.8 for tin-oxide sensors). It inverts in
closed form: ``C = C0 * ((R0 / R) ** (1 / beta) - 1)``.

Dynamics. Adsorption is faster than desorption, so the sensor follows a rising concentration with the
response time constant and a falling one with the (longer) recovery time constant::

    dC_s/dt = (C - C_s) / tau,   tau = tau_response if C > C_s else tau_recovery

discretised exactly for a concentration held over each sample. The baseline ``R0`` drifts linearly in
time (ageing, humidity), and the reading carries multiplicative Gaussian noise. Concentrations are in
parts per million by volume (ppm), the unit MOS sensors are specified in.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from rsi import _validate as v
from rsi.errors import InputError

FloatArray = NDArray[np.float64]


def _as_concentrations_ppm(concentration_ppm: object, name: str) -> FloatArray:
    values = v.as_float_array(concentration_ppm, name)
    if not np.isfinite(values).all() or (values < 0).any():
        raise InputError(f"{name} must be finite and >= 0 ppm; got {concentration_ppm!r}.")
    return values


@dataclass(frozen=True)
class MosGasSensor:
    """Settings of a MOS gas sensor (seed §3 H: "changes resistance as a vapor is absorbed").

    Parameters
    ----------
    baseline_ohm : float
        Clean-air resistance ``R0`` in ohms, > 0.
    scale_ppm : float
        Concentration scale ``C0`` in ppm, > 0.
    exponent : float
        Log-log slope ``beta``, > 0.
    response_time_s : float
        Time constant while the concentration rises, > 0 s.
    recovery_time_s : float
        Time constant while it falls, > 0 s (longer than the response for real sensors).
    drift_per_s : float
        Relative baseline drift per second (``R0(t) = R0 * (1 + drift_per_s * t)``), finite.
    noise_relative : float
        Relative standard deviation of the resistance noise, >= 0.
    sample_rate_hz : float
        Sampling rate in Hz, > 0.
    """

    baseline_ohm: float = 50e3
    scale_ppm: float = 5.0
    exponent: float = 0.5
    response_time_s: float = 10.0
    recovery_time_s: float = 40.0
    drift_per_s: float = 0.0
    noise_relative: float = 0.002
    sample_rate_hz: float = 10.0

    def __post_init__(self) -> None:
        checks = {
            name: v.positive(getattr(self, name), name)
            for name in (
                "baseline_ohm",
                "scale_ppm",
                "exponent",
                "response_time_s",
                "recovery_time_s",
                "sample_rate_hz",
            )
        }
        checks["drift_per_s"] = v.finite_number(self.drift_per_s, "drift_per_s")
        checks["noise_relative"] = v.in_range(self.noise_relative, "noise_relative", low=0.0)
        v.store_checked(self, checks)

    def resistance_ohm(self, concentration_ppm: object, *, baseline_ohm: float | None = None) -> FloatArray:
        """Steady-state resistance in ohms at `concentration_ppm` (noise-free)."""
        concentration = _as_concentrations_ppm(concentration_ppm, "concentration_ppm")
        base = self.baseline_ohm if baseline_ohm is None else v.positive(baseline_ohm, "baseline_ohm")
        return np.asarray(base * (1.0 + concentration / self.scale_ppm) ** (-self.exponent), dtype=np.float64)

    def concentration_ppm(self, resistance_ohm: object, *, baseline_ohm: float | None = None) -> FloatArray:
        """Concentration in ppm that gives `resistance_ohm` at steady state (the inverse power law).

        Resistances above the baseline (noise in clean air) read 0 ppm.
        """
        resistance = v.as_float_array(resistance_ohm, "resistance_ohm")
        if not np.isfinite(resistance).all() or (resistance <= 0).any():
            raise InputError(f"resistance_ohm must be finite and > 0 ohm; got {resistance_ohm!r}.")
        base = self.baseline_ohm if baseline_ohm is None else v.positive(baseline_ohm, "baseline_ohm")
        ratio = (base / resistance) ** (1.0 / self.exponent)
        return np.asarray(self.scale_ppm * np.maximum(ratio - 1.0, 0.0), dtype=np.float64)


@dataclass(frozen=True)
class GasReadings:
    """A MOS sensor's output over time.

    Attributes
    ----------
    time_s : ndarray of shape (T,)
        Sample times in seconds.
    sensed_ppm : ndarray of shape (T,)
        The sensor's internal (lagged) concentration ``C_s`` in ppm.
    resistance_ohm : ndarray of shape (T,)
        Measured resistance in ohms (drift and noise included).
    estimated_ppm : ndarray of shape (T,)
        Concentration inverted from ``resistance_ohm`` with the nominal (undrifted) baseline, ppm.
    """

    time_s: FloatArray
    sensed_ppm: FloatArray
    resistance_ohm: FloatArray
    estimated_ppm: FloatArray


def _lagged_ppm(concentration_ppm: FloatArray, sensor: MosGasSensor) -> FloatArray:
    """First-order response with separate rise and recovery time constants (exact for held inputs)."""
    step_s = 1.0 / sensor.sample_rate_hz
    gains = {
        True: -np.expm1(-step_s / sensor.response_time_s),
        False: -np.expm1(-step_s / sensor.recovery_time_s),
    }
    sensed = np.empty_like(concentration_ppm)
    state = 0.0  # the sensor starts in clean air
    for index, target in enumerate(concentration_ppm):
        sensed[index] = state
        state += gains[bool(target > state)] * (target - state)
    return sensed


def read_gas(
    concentration_ppm: object,
    sensor: MosGasSensor | None = None,
    *,
    rng: np.random.Generator | int | None = None,
) -> GasReadings:
    """Resistance readings of a MOS sensor exposed to a concentration time series.

    Parameters
    ----------
    concentration_ppm : array_like of shape (T,)
        Gas concentration at the sensor, ppm, >= 0, held over each sample of ``1 / sample_rate_hz`` s;
        the sensor starts in clean air, so sample 0 reads the baseline.
    sensor : MosGasSensor, optional
        Sensor settings.
    rng : numpy.random.Generator or int or None
        Noise source; identical seeds give identical readings.

    Returns
    -------
    GasReadings
    """
    settings = MosGasSensor() if sensor is None else v.instance_of(sensor, "sensor", MosGasSensor)
    concentration = _as_concentrations_ppm(concentration_ppm, "concentration_ppm")
    if concentration.ndim != 1 or concentration.size == 0:
        raise InputError(f"concentration_ppm must be a non-empty 1-D time series; got {concentration.shape}.")
    time_s = np.arange(concentration.size) / settings.sample_rate_hz
    sensed = _lagged_ppm(concentration, settings)
    baseline_ohm = settings.baseline_ohm * (1.0 + settings.drift_per_s * time_s)
    clean = baseline_ohm * (1.0 + sensed / settings.scale_ppm) ** (-settings.exponent)
    noise = 1.0 + settings.noise_relative * v.as_rng(rng).standard_normal(clean.shape)
    resistance = clean * np.maximum(noise, np.finfo(np.float64).tiny)
    return GasReadings(
        time_s=time_s,
        sensed_ppm=sensed,
        resistance_ohm=resistance,
        estimated_ppm=settings.concentration_ppm(resistance),
    )


__all__: list[str] = ["GasReadings", "MosGasSensor", "read_gas"]
