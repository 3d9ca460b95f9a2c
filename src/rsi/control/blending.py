"""Seed §3.1, Fig. 4: blend joystick, trajectory and proximity velocities along the sensor axis.

The block diagram adds three velocity commands before Configuration Control::

    x_dot = x_dot_js (joystick) + x_dot_tg (trajectory generator) + x_dot_ps (proximity law)

all along the proximity sensors' axis, positive toward the surface. Two sensors see the surface
(seed §3.1), and their readings are combined in two different ways, because the two halves of the law
protect against different mistakes:

- Avoidance (the law's negative part) is driven by the **nearer** valid reading. This is the conservative
  choice: a protrusion that comes into view of one sensor from the periphery (the reason for region B)
  must repel the arm even if the other sensor still sees the far surface. It also keeps the non-override
  property of region C: the proximity term is never larger than the avoidance law at the nearer reading.
- Servoing (the positive part, servo mode only) is driven by the **mean** of the valid readings: on a
  tilted surface it estimates the distance at the tool centre between the sensors, and it halves the
  noise variance, so the arm does not hunt. It applies only while the nearer reading is already beyond
  the standoff (the avoidance term is zero); otherwise the more repulsive of the two wins.

Readings beyond the sensors' maximum distance (including ``inf``, no return) are ignored; with no valid
reading the proximity term is zero and the sample is flagged. Readings below the minimum distance are kept:
they are region A, where the law retreats.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from rsi import _validate as v
from rsi.control.proximity_law import MODES, ProximityLaw, as_sensed_distances_m, proximity_velocity
from rsi.errors import InputError

FloatArray = NDArray[np.float64]
BoolArray = NDArray[np.bool_]


@dataclass(frozen=True)
class BlendedCommand:
    """Velocity commands along the sensor axis, m/s, positive toward the surface.

    Attributes
    ----------
    velocity_m_s : ndarray of shape (...)
        The sum sent to the arm: joystick + trajectory + proximity.
    proximity_m_s : ndarray of shape (...)
        The proximity term alone.
    nearest_m : ndarray of shape (...)
        The nearer valid reading in metres (``inf`` where none is valid).
    no_valid_reading : ndarray of shape (...), bool
        True where every sensor was out of range (the proximity term is 0 there).
    """

    velocity_m_s: FloatArray
    proximity_m_s: FloatArray
    nearest_m: FloatArray
    no_valid_reading: BoolArray


def _as_velocity(value: object, name: str, *, limit_m_s: float | None = None) -> FloatArray:
    velocity = v.as_float_array(value, name)
    if not np.isfinite(velocity).all():
        raise InputError(f"{name} contains NaN or inf; pass finite velocities in m/s.")
    if limit_m_s is not None and (np.abs(velocity) > limit_m_s).any():
        raise InputError(
            f"{name} must lie in [-{limit_m_s}, {limit_m_s}] m/s (the law's joystick_speed_m_s); "
            f"got extreme {float(velocity.flat[np.argmax(np.abs(velocity))])!r}."
        )
    return velocity


def proximity_term(
    distances_m: object, law: ProximityLaw | None = None, *, mode: str = "avoidance"
) -> tuple[FloatArray, FloatArray, BoolArray]:
    """The proximity velocity from several sensors' readings (see the module notes).

    Parameters
    ----------
    distances_m : array_like of shape (..., S)
        Sensed distances in metres, one column per sensor (S >= 1); ``inf`` means no return.
    law : ProximityLaw, optional
        The law's breakpoints and speeds.
    mode : {"avoidance", "servo"}

    Returns
    -------
    velocity_m_s, nearest_m, no_valid_reading : ndarrays of shape (...)
    """
    settings = ProximityLaw() if law is None else v.instance_of(law, "law", ProximityLaw)
    v.choice(mode, "mode", MODES)
    readings = as_sensed_distances_m(distances_m, "distances_m")
    if readings.ndim == 0 or readings.shape[-1] == 0:
        raise InputError(
            f"distances_m must have shape (..., sensors) with >= 1 sensor; got {readings.shape}."
        )
    valid = readings <= settings.max_distance_m
    count = valid.sum(axis=-1)
    nearest = np.min(np.where(valid, readings, np.inf), axis=-1)
    mean = np.where(count > 0, np.where(valid, readings, 0.0).sum(axis=-1) / np.maximum(count, 1), np.inf)
    avoid = proximity_velocity(nearest, settings, mode="avoidance").velocity_m_s
    servo = proximity_velocity(mean, settings, mode=mode).velocity_m_s
    velocity = np.where(avoid < 0.0, np.minimum(avoid, servo), servo)
    return velocity, nearest, count == 0


def blend_commands(
    joystick_m_s: object,
    trajectory_m_s: object,
    distances_m: object,
    law: ProximityLaw | None = None,
    *,
    mode: str = "avoidance",
) -> BlendedCommand:
    """Fig. 4's sum of joystick, trajectory and proximity velocities along the sensor axis.

    Parameters
    ----------
    joystick_m_s : array_like of shape (...)
        Joystick command in m/s, within +-``law.joystick_speed_m_s``.
    trajectory_m_s : array_like of shape (...)
        Trajectory generator's velocity in m/s, finite.
    distances_m : array_like of shape (..., S)
        The proximity sensors' readings in metres, one column per sensor.
    law : ProximityLaw, optional
    mode : {"avoidance", "servo"}

    Returns
    -------
    BlendedCommand

    Examples
    --------
    >>> command = blend_commands(0.05, 0.0, [0.15, 0.40])  # full push, one sensor sees a protrusion
    >>> bool(command.velocity_m_s <= 0.0)
    True
    """
    settings = ProximityLaw() if law is None else v.instance_of(law, "law", ProximityLaw)
    joystick = _as_velocity(joystick_m_s, "joystick_m_s", limit_m_s=settings.joystick_speed_m_s)
    trajectory = _as_velocity(trajectory_m_s, "trajectory_m_s")
    proximity, nearest, no_valid = proximity_term(distances_m, settings, mode=mode)
    return BlendedCommand(
        velocity_m_s=np.asarray(joystick + trajectory + proximity, dtype=np.float64),
        proximity_m_s=proximity,
        nearest_m=nearest,
        no_valid_reading=no_valid,
    )


__all__: list[str] = ["BlendedCommand", "blend_commands", "proximity_term"]
