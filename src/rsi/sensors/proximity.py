"""Seed §3.1: the infrared triangulation proximity sensor (IDEC/Izumi SA1D), its A/D and its low-pass filter.

Signal chain, per sample at 44 Hz (seed §3.1)::

    true distance d ──► response curve V(d) ──► + Gaussian noise ──► A/D (clip, quantise)
                    ──► digital low-pass filter (on volts) ──► linearisation d = V^-1(v) ──► reading, flag

Response curve. A triangulation sensor images its emitter's spot on a position-sensitive detector; by
similar triangles the spot's offset on the detector, hence the output voltage, falls as the inverse of the
distance. We use::

    V(d) = V_min * (d_min + d_0) / (d + d_0)

where ``V_min`` is the output at the minimum distance ``d_min`` and ``d_0`` (``lens_offset_m``) is the
distance from the receiving lens to the sensor face. Closer than ``d_min`` the curve keeps rising until the
A/D rail clips it; beyond ``d_max`` the spot leaves the detector, no light returns and the output is 0 V,
which linearises to an infinite distance. The reading is linearised with the exact inverse, which is why
the seed's Fig. 3 (filtered readings against arm position) is "fairly linear".

The filter runs on volts, not on linearised metres, so that a "no return" sample (0 V, infinite distance)
pulls the filtered reading smoothly out of range instead of turning the filter state into infinity.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from scipy import signal

from rsi import _validate as v
from rsi.constants import PROXIMITY_SAMPLE_RATE_HZ
from rsi.errors import InputError

FloatArray = NDArray[np.float64]
BoolArray = NDArray[np.bool_]

_MAX_ADC_BITS = 24
MAX_ORDER = 32  # a Butterworth of order 4 is the seed's; designing one of order 80,000 took minutes


def as_distances_m(distance_m: object, name: str, *, allow_inf: bool = False) -> FloatArray:
    """Return `distance_m` as a float64 array of non-negative distances in metres, or raise.

    Parameters
    ----------
    distance_m : array_like
        Distances in metres, any shape.
    name : str
        Argument name used in error messages.
    allow_inf : bool
        Accept ``+inf`` (a sensor's "no return"); NaN is never accepted.
    """
    if not isinstance(allow_inf, bool):
        raise InputError(f"allow_inf must be True or False; got {allow_inf!r}.")
    values = v.as_float_array(distance_m, name)
    if np.isnan(values).any() or (not allow_inf and np.isinf(values).any()):
        kind = "NaN or inf" if not allow_inf else "NaN"
        raise InputError(f"{name} contains {kind}; pass finite distances in metres.")
    if (values < 0).any():
        raise InputError(
            f"{name} must be >= 0 m (a distance from the sensor face); got minimum {values.min()!r}."
        )
    return values


@dataclass(frozen=True)
class ProximitySensor:
    """Settings of one IR triangulation proximity sensor and its acquisition chain (seed §3.1).

    Parameters
    ----------
    min_distance_m : float
        Closest distance the sensor resolves, > 0 m; the seed recessed the sensors behind the 11 cm
        gripper so that a surface at the fingertips is already beyond it.
    max_distance_m : float
        Farthest distance the sensor resolves, > ``min_distance_m`` (seed §3: about 0.75 m).
    lens_offset_m : float
        ``d_0`` in the response curve, >= 0 m: from the receiving lens to the sensor face.
    voltage_at_min_v : float
        Output at ``min_distance_m`` in volts, in (0, ``full_scale_v``].
    full_scale_v : float
        A/D input range is [0, ``full_scale_v``] volts, > 0.
    noise_std_v : float
        Standard deviation of the Gaussian output noise in volts, >= 0.
    adc_bits : int
        A/D resolution in bits, 1..24.
    sample_rate_hz : float
        Sampling rate, > 0 Hz (seed §3.1: 44 Hz on a 68040).
    cutoff_hz : float
        Low-pass cut-off, in (0, ``sample_rate_hz`` / 2) Hz.
    filter_order : int
        Order of the Butterworth low-pass, >= 1 (1 is the classic first-order filter).
    """

    min_distance_m: float = 0.08
    max_distance_m: float = 0.75
    lens_offset_m: float = 0.02
    voltage_at_min_v: float = 4.5
    full_scale_v: float = 5.0
    noise_std_v: float = 0.005
    adc_bits: int = 12
    sample_rate_hz: float = PROXIMITY_SAMPLE_RATE_HZ
    cutoff_hz: float = 4.0
    filter_order: int = 1

    def __post_init__(self) -> None:
        checks: dict[str, float | int] = {
            "min_distance_m": v.in_range(self.min_distance_m, "min_distance_m", low=0.0, low_inclusive=False),
            "lens_offset_m": v.in_range(self.lens_offset_m, "lens_offset_m", low=0.0),
            "full_scale_v": v.in_range(self.full_scale_v, "full_scale_v", low=0.0, low_inclusive=False),
            "noise_std_v": v.in_range(self.noise_std_v, "noise_std_v", low=0.0),
            "adc_bits": v.positive_int(self.adc_bits, "adc_bits"),
            "sample_rate_hz": v.in_range(self.sample_rate_hz, "sample_rate_hz", low=0.0, low_inclusive=False),
            "filter_order": v.positive_int(self.filter_order, "filter_order"),
        }
        checks["max_distance_m"] = v.in_range(
            self.max_distance_m, "max_distance_m", low=float(checks["min_distance_m"]), low_inclusive=False
        )
        checks["voltage_at_min_v"] = v.in_range(
            self.voltage_at_min_v,
            "voltage_at_min_v",
            low=0.0,
            high=float(checks["full_scale_v"]),
            low_inclusive=False,
        )
        checks["cutoff_hz"] = v.in_range(
            self.cutoff_hz,
            "cutoff_hz",
            low=0.0,
            high=float(checks["sample_rate_hz"]) / 2.0,
            low_inclusive=False,
            high_inclusive=False,
        )
        if int(checks["adc_bits"]) > _MAX_ADC_BITS:
            raise InputError(f"adc_bits must be in 1..{_MAX_ADC_BITS}; got {self.adc_bits!r}.")
        v.store_checked(self, checks)

    @property
    def time_step_s(self) -> float:
        """Sampling interval in seconds."""
        return 1.0 / self.sample_rate_hz

    @property
    def adc_step_v(self) -> float:
        """One A/D count in volts."""
        return self.full_scale_v / ((1 << self.adc_bits) - 1)

    def voltage_v(self, distance_m: object) -> FloatArray:
        """Noise-free output voltage at `distance_m`, before the A/D (volts; 0 V beyond the maximum).

        Parameters
        ----------
        distance_m : array_like
            True distances from the sensor face in metres, >= 0; ``inf`` means no surface.

        Returns
        -------
        ndarray of the same shape, float64
            ``V(d)`` (see the module notes); 0 V where ``d > max_distance_m`` (no light returns).
        """
        distance = as_distances_m(distance_m, "distance_m", allow_inf=True)
        scale_v_m = self.voltage_at_min_v * (self.min_distance_m + self.lens_offset_m)
        curve = scale_v_m / (distance + self.lens_offset_m)
        return np.where(distance > self.max_distance_m, 0.0, curve)

    def distance_m(self, voltage_v: object) -> FloatArray:
        """Linearised distance in metres for an output of `voltage_v` volts (the inverse of ``voltage_v``).

        Voltages at or below zero (no return) give ``inf``.
        """
        volts = v.as_float_array(voltage_v, "voltage_v")
        scale_v_m = self.voltage_at_min_v * (self.min_distance_m + self.lens_offset_m)
        with np.errstate(divide="ignore"):
            distance = scale_v_m / volts - self.lens_offset_m
        return np.where(volts > 0.0, distance, np.inf)

    def digitise_v(self, distance_m: object, rng: np.random.Generator | int | None) -> FloatArray:
        """Raw A/D readings in volts: response curve, Gaussian noise, clipping to the range, quantisation."""
        generator = v.as_rng(rng)
        clean = self.voltage_v(distance_m)
        noisy = clean + self.noise_std_v * generator.standard_normal(clean.shape)
        counts = np.round(np.clip(noisy, 0.0, self.full_scale_v) / self.adc_step_v)
        return counts * self.adc_step_v

    def out_of_range(self, reading_m: object) -> BoolArray:
        """True where a reading lies below ``min_distance_m`` or beyond ``max_distance_m``."""
        reading = v.as_float_array(reading_m, "reading_m")
        return (reading < self.min_distance_m) | (reading > self.max_distance_m)


class LowPassFilter:
    """A stateful Butterworth low-pass filter; per-sample ``update`` and batch ``filter`` agree exactly.

    seed §3.1: "the data was digitally low-pass filtered for noise reduction". The state starts at the
    steady state of the first sample, so a constant input passes through without a start-up transient.

    Parameters
    ----------
    cutoff_hz : float
        -3 dB frequency in Hz, in (0, ``sample_rate_hz`` / 2).
    sample_rate_hz : float
        Sampling rate in Hz, > 0.
    order : int
        Butterworth order, >= 1.
    """

    def __init__(self, cutoff_hz: float, sample_rate_hz: float, *, order: int = 1) -> None:
        rate = v.in_range(sample_rate_hz, "sample_rate_hz", low=0.0, low_inclusive=False)
        cutoff = v.in_range(
            cutoff_hz, "cutoff_hz", low=0.0, high=rate / 2.0, low_inclusive=False, high_inclusive=False
        )
        self._sos = signal.butter(
            v.positive_int(order, "order", maximum=MAX_ORDER), cutoff, fs=rate, output="sos"
        )
        self._sample_rate_hz = rate
        self._state: FloatArray | None = None

    def reset(self) -> None:
        """Forget the state; the next sample initialises it again."""
        self._state = None

    def filter(self, samples: object) -> FloatArray:
        """Filter a 1-D run of samples, continuing from the current state."""
        values = np.atleast_1d(v.as_float_array(samples, "samples"))
        if values.ndim != 1 or values.size == 0:
            raise InputError(f"samples must be a non-empty 1-D array; got shape {values.shape}.")
        if self._state is None:
            self._state = signal.sosfilt_zi(self._sos) * values[0]
        filtered, self._state = signal.sosfilt(self._sos, values, zi=self._state)
        return np.asarray(filtered, dtype=np.float64)

    def update(self, sample: float) -> float:
        """Filter one sample and return the filtered value."""
        return float(self.filter(v.finite_number(sample, "sample"))[0])

    @property
    def dc_delay_s(self) -> float:
        """Group delay at 0 Hz in seconds: how far a ramp's filtered reading lags the ramp."""
        b, a = signal.sos2tf(self._sos)
        _, delay_samples = signal.group_delay((b, a), w=[0.0])
        return float(delay_samples[0] / self._sample_rate_hz)


@dataclass(frozen=True)
class ProximityReadings:
    """Readings of one proximity sensor over time (seed §3.1, Fig. 3).

    Attributes
    ----------
    time_s : ndarray of shape (T,)
        Sample times in seconds from the first sample.
    raw_v : ndarray of shape (T,)
        A/D readings in volts (noisy, quantised).
    raw_m : ndarray of shape (T,)
        Unfiltered linearised distances in metres (``inf`` for no return).
    filtered_m : ndarray of shape (T,)
        Low-pass filtered, linearised distances in metres (``inf`` for no return).
    out_of_range : ndarray of shape (T,), bool
        True where ``filtered_m`` is below the sensor's minimum or beyond its maximum distance.
    """

    time_s: FloatArray
    raw_v: FloatArray
    raw_m: FloatArray
    filtered_m: FloatArray
    out_of_range: BoolArray


def read_proximity(
    true_distance_m: object,
    sensor: ProximitySensor | None = None,
    *,
    rng: np.random.Generator | int | None = None,
) -> ProximityReadings:
    """Turn true distances sampled at the sensor's rate into filtered, linearised readings.

    Parameters
    ----------
    true_distance_m : array_like of shape (T,)
        Distance from the sensor face to the surface at each 44 Hz sample, metres, >= 0 (``inf``: none).
    sensor : ProximitySensor, optional
        Sensor settings; the defaults model the seed's SA1D.
    rng : numpy.random.Generator or int or None
        Noise source; identical seeds give identical readings.

    Returns
    -------
    ProximityReadings

    Examples
    --------
    >>> import numpy as np
    >>> readings = read_proximity(np.full(100, 0.3), rng=0)
    >>> bool(abs(readings.filtered_m[-1] - 0.3) < 0.005)
    True
    """
    settings = ProximitySensor() if sensor is None else v.instance_of(sensor, "sensor", ProximitySensor)
    distance = as_distances_m(true_distance_m, "true_distance_m", allow_inf=True)
    if distance.ndim != 1 or distance.size == 0:
        raise InputError(f"true_distance_m must be a non-empty 1-D time series; got shape {distance.shape}.")
    raw_v = settings.digitise_v(distance, rng)
    smoother = LowPassFilter(settings.cutoff_hz, settings.sample_rate_hz, order=settings.filter_order)
    filtered_m = settings.distance_m(smoother.filter(raw_v))
    return ProximityReadings(
        time_s=np.arange(distance.size, dtype=np.float64) * settings.time_step_s,
        raw_v=raw_v,
        raw_m=settings.distance_m(raw_v),
        filtered_m=filtered_m,
        out_of_range=settings.out_of_range(filtered_m),
    )


class ProximityChannel:
    """One sensor read sample by sample, for a closed loop; matches :func:`read_proximity` for one seed.

    Parameters
    ----------
    sensor : ProximitySensor, optional
        Sensor settings.
    rng : numpy.random.Generator or int or None
        Noise source.
    """

    def __init__(
        self, sensor: ProximitySensor | None = None, *, rng: np.random.Generator | int | None = None
    ) -> None:
        self.sensor = (
            ProximitySensor() if sensor is None else v.instance_of(sensor, "sensor", ProximitySensor)
        )
        self._rng = v.as_rng(rng)
        self._filter = LowPassFilter(
            self.sensor.cutoff_hz, self.sensor.sample_rate_hz, order=self.sensor.filter_order
        )

    def read(self, true_distance_m: float) -> tuple[float, bool]:
        """Sample the sensor once; return the filtered reading in metres and its out-of-range flag."""
        raw_v = self.sensor.digitise_v(np.array([true_distance_m]), self._rng)
        reading_m = float(self.sensor.distance_m(self._filter.update(float(raw_v[0]))))
        return reading_m, bool(self.sensor.out_of_range(reading_m))


__all__: list[str] = [
    "LowPassFilter",
    "ProximityChannel",
    "ProximityReadings",
    "ProximitySensor",
    "as_distances_m",
    "read_proximity",
]
