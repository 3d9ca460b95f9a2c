"""Seed §3 A-B: feedback-controlled halogen lamps and the fast strobes on the gripper jaws.

Halogen lamps. "The controlled lights are maintained at a known illumination level by an optical
transistor feedback circuit. This makes the illumination independent of current fluctuations and bulb
age" (seed §3). We model the lamp, its disturbances and the loop at ``sample_rate_hz``::

    E_ss[n]  = E_rated * efficacy(t) * (u[n] * V_supply(t) / V_rated) ** gamma     (halogen: gamma ~ 3.4)
    E[n+1]   = E[n] + (1 - exp(-dt / tau_filament)) * (E_ss[n] - E[n])              (filament heats/cools)
    e[n]     = (E_set - E[n] * (1 + noise)) / E_set                                 (optical transistor)
    u[n]     = clip(Kp * e[n] + I[n], 0, 1);  I[n+1] = I[n] + Kp * dt / Ti * e[n]   (PI; no wind-up)

``u`` is the regulator's duty (fraction of the supply put across the bulb). The supply voltage wanders
(low-pass filtered Gaussian noise plus a slow sag) and the bulb loses efficacy linearly with age (time
compressed so that a run shows it). The integral time is set to the filament time constant so the PI
zero cancels the lamp's pole.

Strobes. Fast pulse strobes (~20 us, seed §2.1) are mounted on the outside faces of the parallel jaws
(seed §3), so opening the gripper moves them sideways and changes the angle at which they light the
scene. Geometry, in the plane of the jaws (camera on the axis, scene centre on the axis at the standoff
in front of the fingertips)::

          strobe ●─── offset_x = jaw_opening / 2 + mount_offset
                 │\\
       setback   │ \\   illumination angle = atan(offset_x / (setback + standoff))
    (to fingertips)  \\
                 │    \\
      fingertips ┴─────●  scene centre, standoff in front of the fingertips
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from rsi import _validate as v
from rsi.constants import STROBE_DURATION_S, STROBE_ENERGY_LM_S
from rsi.errors import InputError

FloatArray = NDArray[np.float64]


_MAX_VOLTAGE_V = 1e4
_LAMP_LIMITS = {
    "rated_illuminance_lux": 1e7,
    "rated_voltage_v": _MAX_VOLTAGE_V,
    "light_exponent": 10.0,
    "filament_time_s": 1e3,
}
_CONTROLLER_LIMITS = {
    "setpoint_lux": 1e7,
    "proportional_gain": 1e6,
    "integral_time_s": 1e6,
    "sample_rate_hz": 1e6,
}
MAX_LAMP_SAMPLES = 10**6
"""Loop steps :func:`simulate_lamp` runs at most (one Python step each: 10**6 is about 10 s)."""


@dataclass(frozen=True)
class HalogenLamp:
    """A halogen lamp on a switching regulator.

    Parameters
    ----------
    rated_illuminance_lux : float
        Illuminance on the scene at rated voltage with a new bulb, > 0 lux.
    rated_voltage_v : float
        Bulb rated voltage, > 0 V.
    supply_voltage_v : float
        Nominal supply voltage, >= ``rated_voltage_v`` (the regulator needs headroom).
    light_exponent : float
        ``gamma``: light output grows as voltage to this power, > 0 (about 3.4 for halogen bulbs).
    filament_time_s : float
        Thermal time constant of the filament, > 0 s.
    """

    rated_illuminance_lux: float = 2000.0
    rated_voltage_v: float = 12.0
    supply_voltage_v: float = 14.0
    light_exponent: float = 3.4
    filament_time_s: float = 0.05

    def __post_init__(self) -> None:
        # Upper bounds far past any lamp (sunlight is ~1.2e5 lux, halogen gamma ~3.4) keep every power and
        # product below the float range.
        checks = {
            name: v.in_range(getattr(self, name), name, low=0.0, high=high, low_inclusive=False)
            for name, high in _LAMP_LIMITS.items()
        }
        checks["supply_voltage_v"] = v.in_range(
            self.supply_voltage_v, "supply_voltage_v", low=checks["rated_voltage_v"], high=_MAX_VOLTAGE_V
        )
        v.store_checked(self, checks)

    def steady_illuminance_lux(
        self, duty: FloatArray, supply_v: FloatArray, efficacy: FloatArray
    ) -> FloatArray:
        """Illuminance the filament settles to at a duty, a supply voltage and a relative efficacy."""
        return np.asarray(
            self.rated_illuminance_lux
            * efficacy
            * (duty * supply_v / self.rated_voltage_v) ** self.light_exponent,
            dtype=np.float64,
        )


@dataclass(frozen=True)
class LampController:
    """The optical-transistor PI loop that holds the illuminance (seed §3).

    Parameters
    ----------
    setpoint_lux : float
        Illuminance to hold, > 0 lux.
    proportional_gain : float
        ``Kp`` on the relative error, > 0 (duty per unit relative error).
    integral_time_s : float
        ``Ti``, > 0 s.
    sample_rate_hz : float
        Loop rate, > 0 Hz.
    sensor_noise_relative : float
        Relative standard deviation of the optical transistor's reading, >= 0.
    """

    setpoint_lux: float = 1500.0
    proportional_gain: float = 4.0
    integral_time_s: float = 0.05
    sample_rate_hz: float = 1000.0
    sensor_noise_relative: float = 0.002

    def __post_init__(self) -> None:
        checks = {
            name: v.in_range(getattr(self, name), name, low=0.0, high=high, low_inclusive=False)
            for name, high in _CONTROLLER_LIMITS.items()
        }
        checks["sensor_noise_relative"] = v.in_range(
            self.sensor_noise_relative, "sensor_noise_relative", low=0.0, high=1.0
        )
        v.store_checked(self, checks)


@dataclass(frozen=True)
class LampDisturbance:
    """What the loop must reject: supply fluctuation and bulb ageing.

    Parameters
    ----------
    supply_noise_relative : float
        Standard deviation of the supply's random wander, relative to nominal, in [0, 0.5).
    supply_correlation_s : float
        Correlation time of that wander, > 0 s.
    supply_sag_per_s : float
        Relative supply sag per second (a discharging battery), >= 0.
    ageing_per_s : float
        Relative efficacy lost per second of run (bulb life compressed into the run), >= 0.
    """

    supply_noise_relative: float = 0.02
    supply_correlation_s: float = 0.5
    supply_sag_per_s: float = 0.02
    ageing_per_s: float = 0.05

    def __post_init__(self) -> None:
        checks = {
            "supply_noise_relative": v.in_range(
                self.supply_noise_relative, "supply_noise_relative", low=0.0, high=0.5, high_inclusive=False
            ),
            "supply_correlation_s": v.positive(self.supply_correlation_s, "supply_correlation_s"),
            "supply_sag_per_s": v.in_range(self.supply_sag_per_s, "supply_sag_per_s", low=0.0),
            "ageing_per_s": v.in_range(self.ageing_per_s, "ageing_per_s", low=0.0),
        }
        v.store_checked(self, checks)


@dataclass(frozen=True)
class LampRun:
    """One simulated run of the lamp loop.

    Attributes
    ----------
    time_s : ndarray of shape (T,)
        Sample times, seconds.
    illuminance_lux : ndarray of shape (T,)
        True illuminance on the scene, lux.
    duty : ndarray of shape (T,)
        Regulator duty commanded, in [0, 1].
    supply_v : ndarray of shape (T,)
        Supply voltage, volts.
    efficacy : ndarray of shape (T,)
        Bulb efficacy relative to new.
    """

    time_s: FloatArray
    illuminance_lux: FloatArray
    duty: FloatArray
    supply_v: FloatArray
    efficacy: FloatArray

    def relative_error(self, setpoint_lux: float) -> FloatArray:
        """``(E - E_set) / E_set`` at each sample."""
        return (self.illuminance_lux - setpoint_lux) / setpoint_lux


def _supply_v(
    lamp: HalogenLamp, disturbance: LampDisturbance, time_s: FloatArray, rng: np.random.Generator
) -> FloatArray:
    """Supply voltage: first-order (Ornstein-Uhlenbeck) wander plus a linear sag."""
    step_s = float(time_s[1] - time_s[0]) if time_s.size > 1 else 1.0
    keep = np.exp(-step_s / disturbance.supply_correlation_s)
    kicks = disturbance.supply_noise_relative * np.sqrt(1.0 - keep**2) * rng.standard_normal(time_s.size)
    wander = np.empty(time_s.size)
    level = disturbance.supply_noise_relative * rng.standard_normal()
    for index, kick in enumerate(kicks):
        wander[index] = level
        level = keep * level + kick
    return lamp.supply_voltage_v * (1.0 + wander - disturbance.supply_sag_per_s * time_s)


def _pi_step(controller: LampController, error: float, integral: float) -> tuple[float, float]:
    """One PI update; the integral freezes while the duty is clipped and the error pushes further out."""
    step_s = 1.0 / controller.sample_rate_hz
    raw = controller.proportional_gain * error + integral
    duty = min(max(raw, 0.0), 1.0)
    if duty == raw or (raw > 1.0) != (error > 0.0):
        integral += controller.proportional_gain * step_s / controller.integral_time_s * error
    return duty, integral


def simulate_lamp(
    duration_s: float,
    lamp: HalogenLamp | None = None,
    controller: LampController | None = None,
    disturbance: LampDisturbance | None = None,
    *,
    closed_loop: bool = True,
    rng: np.random.Generator | int | None = None,
) -> LampRun:
    """Run the lamp with its feedback loop (or open loop, for comparison) under disturbances.

    Parameters
    ----------
    duration_s : float
        Length of the run, > 0 s; ageing must leave the bulb some efficacy at the end.
    lamp, controller, disturbance : optional
        Settings; defaults as documented on each class.
    closed_loop : bool
        False holds the duty that gives the setpoint at nominal supply with a new bulb (no feedback).
    rng : numpy.random.Generator or int or None
        Noise source (supply wander, sensor noise); identical seeds give identical runs.

    Returns
    -------
    LampRun
        Starts dark; with the defaults the loop settles within 0.3 s.
    """
    lamp = HalogenLamp() if lamp is None else v.instance_of(lamp, "lamp", HalogenLamp)
    controller = (
        LampController() if controller is None else v.instance_of(controller, "controller", LampController)
    )
    disturbance = (
        LampDisturbance()
        if disturbance is None
        else v.instance_of(disturbance, "disturbance", LampDisturbance)
    )
    duration = v.positive(duration_s, "duration_s")
    if duration * controller.sample_rate_hz > MAX_LAMP_SAMPLES:
        raise InputError(
            f"duration_s={duration_s!r} at sample_rate_hz={controller.sample_rate_hz!r} is "
            f"{duration * controller.sample_rate_hz:.3g} loop steps, over {MAX_LAMP_SAMPLES}; shorten the "
            "run or lower the rate."
        )
    if disturbance.ageing_per_s * duration >= 1.0:
        raise InputError(
            f"duration_s={duration_s!r} with ageing_per_s={disturbance.ageing_per_s!r} burns the bulb out; "
            "shorten the run or slow the ageing."
        )
    generator = v.as_rng(rng)
    time_s = np.arange(round(duration * controller.sample_rate_hz)) / controller.sample_rate_hz
    supply_v = _supply_v(lamp, disturbance, time_s, generator)
    efficacy = 1.0 - disturbance.ageing_per_s * time_s
    sensor_noise = controller.sensor_noise_relative * generator.standard_normal(time_s.size)
    open_duty = (
        lamp.rated_voltage_v
        / lamp.supply_voltage_v
        * (controller.setpoint_lux / lamp.rated_illuminance_lux) ** (1.0 / lamp.light_exponent)
    )
    lag = -np.expm1(-1.0 / (controller.sample_rate_hz * lamp.filament_time_s))
    illuminance = np.empty(time_s.size)
    duty = np.empty(time_s.size)
    level_lux, integral = 0.0, 0.0
    for index in range(time_s.size):
        illuminance[index] = level_lux
        error = (controller.setpoint_lux - level_lux * (1.0 + sensor_noise[index])) / controller.setpoint_lux
        duty[index], integral = _pi_step(controller, error, integral) if closed_loop else (open_duty, 0.0)
        target = lamp.steady_illuminance_lux(duty[index], supply_v[index], efficacy[index])
        level_lux += lag * (float(target) - level_lux)
    return LampRun(
        time_s=time_s, illuminance_lux=illuminance, duty=duty, supply_v=supply_v, efficacy=efficacy
    )


@dataclass(frozen=True)
class Strobe:
    """A fast pulse strobe on the outside face of a gripper jaw (seed §2.1, §3 B).

    Parameters
    ----------
    pulse_s : float
        Flash duration, > 0 s (seed §2.1: about 20 us).
    luminous_energy_lm_s : float
        Light per flash reaching the scene, > 0 lm s (seed §2.1: 1.3 lm s in the laboratory).
    mount_offset_m : float
        From a jaw's inner face to the strobe's centre, outward, >= 0 m.
    setback_m : float
        Along the camera axis, from the strobe forward to the fingertips, >= 0 m (the 11 cm gripper of
        seed §3.1 by default).
    max_jaw_opening_m : float
        Widest gap between the jaws, > 0 m.
    """

    pulse_s: float = STROBE_DURATION_S
    luminous_energy_lm_s: float = STROBE_ENERGY_LM_S
    mount_offset_m: float = 0.02
    setback_m: float = 0.11
    max_jaw_opening_m: float = 0.08

    def __post_init__(self) -> None:
        checks = {
            "pulse_s": v.positive(self.pulse_s, "pulse_s"),
            "luminous_energy_lm_s": v.positive(self.luminous_energy_lm_s, "luminous_energy_lm_s"),
            "mount_offset_m": v.in_range(self.mount_offset_m, "mount_offset_m", low=0.0),
            "setback_m": v.in_range(self.setback_m, "setback_m", low=0.0),
            "max_jaw_opening_m": v.positive(self.max_jaw_opening_m, "max_jaw_opening_m"),
        }
        v.store_checked(self, checks)

    def luminous_exposure_lux_s(self, exposure_s: float, scene_area_m2: float) -> float:
        """Strobe light per unit area captured by an exposure that starts with the flash (lux s).

        The pulse is taken as rectangular: an exposure at least as long as the pulse captures all of it,
        which is why the strobe is unaffected by a 1/10000 s shutter (seed §2.1).
        """
        exposure = v.positive(exposure_s, "exposure_s")
        area = v.positive(scene_area_m2, "scene_area_m2")
        return self.luminous_energy_lm_s / area * min(1.0, exposure / self.pulse_s)

    def illumination_angle_rad(self, jaw_opening_m: object, standoff_m: object) -> FloatArray:
        """Angle between the strobe-to-scene ray and the camera axis, radians (see the module sketch).

        Parameters
        ----------
        jaw_opening_m : array_like
            Gap between the jaws, in [0, ``max_jaw_opening_m``] metres.
        standoff_m : array_like
            From the fingertips to the scene centre, >= 0 m.
        """
        opening = v.as_float_array(jaw_opening_m, "jaw_opening_m")
        standoff = v.as_float_array(standoff_m, "standoff_m")
        if not np.isfinite(opening).all() or (opening < 0).any() or (opening > self.max_jaw_opening_m).any():
            raise InputError(
                f"jaw_opening_m must lie in [0, {self.max_jaw_opening_m}] m (the gripper's travel); "
                f"got {jaw_opening_m!r}."
            )
        if not np.isfinite(standoff).all() or (standoff < 0).any():
            raise InputError(f"standoff_m must be finite and >= 0 m; got {standoff_m!r}.")
        lateral_m = opening / 2.0 + self.mount_offset_m
        return np.asarray(np.arctan2(lateral_m, self.setback_m + standoff), dtype=np.float64)


__all__: list[str] = [
    "HalogenLamp",
    "LampController",
    "LampDisturbance",
    "LampRun",
    "Strobe",
    "simulate_lamp",
]
