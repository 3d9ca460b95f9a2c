"""Seed §3.1, Fig. 4: blend joystick, trajectory and proximity velocities along the sensor axis.

The block diagram adds three velocity commands before Configuration Control::

    x_dot = x_dot_js (joystick) + x_dot_tg (trajectory generator) + x_dot_ps (proximity law)

all along the proximity sensors' axis, positive toward the surface. Two sensors see the surface
(seed §3.1), and their readings are combined in two different ways, because the two halves of the law
protect against different mistakes:

- Avoidance (the law's negative part) is driven by the **nearer** valid reading. This is the conservative
  choice: a protrusion that comes into view of one sensor from the periphery (the reason for region B)
  must repel the arm even if the other sensor still sees the far surface. It also keeps the non-override
  property of region C: while the nearer reading is inside the standoff, the proximity term is the
  avoidance law at that reading, in either mode.
- Servoing (servo mode only) is driven by a **servo distance** that slides with the nearer reading from
  the nearer reading itself to the **mean** of the valid readings::

      d_servo = nearest + w (mean - nearest),   w = clip((nearest - standoff) / (peak - standoff), 0, 1)

  At and inside the standoff (w = 0) the law acts on the nearer reading, exactly as avoidance does, so
  regions A-C and the repulsive part of D are unchanged. From the servo peak on (w = 1) it acts on the
  mean, which on a tilted surface estimates the distance at the tool centre and halves the noise
  variance. In between, the weight rises along the law's own rising segment (D, standoff to peak), so the
  command moves continuously as the nearer reading crosses the standoff. (Switching from min(avoidance,
  servo at the mean) to servo at the mean there, as this module did before, jumped by the servo law's
  value at the mean: one-sample spikes of up to +0.24 m/s in the proximity demo when a step edge entered
  one sensor's view; docs/proximity-demo.md.)

For readings within range that each change by at most ``delta`` per sample, the command changes by at most
``s_max (1 + g / (peak - standoff)) delta`` per sample, ``s_max`` being the law's steepest slope and ``g``
the larger of the two samples' ``mean - nearest`` (tests/control/test_blending.py checks it).

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


def law_distance_m(
    distances_m: object, law: ProximityLaw | None = None, *, mode: str = "avoidance"
) -> tuple[FloatArray, FloatArray, BoolArray]:
    """The one distance the law acts on, from several sensors' readings (see the module notes).

    Parameters
    ----------
    distances_m : array_like of shape (..., S)
        Sensed distances in metres, one column per sensor (S >= 1); ``inf`` means no return.
    law : ProximityLaw, optional
        The law's breakpoints and speeds (its standoff and servo peak place the servo distance's ramp).
    mode : {"avoidance", "servo"}
        Avoidance acts on the nearer valid reading; servoing on the servo distance.

    Returns
    -------
    distance_m, nearest_m, no_valid_reading : ndarrays of shape (...)
        ``inf`` where no reading is valid.

    Examples
    --------
    >>> law = ProximityLaw()  # standoff 0.333 m, servo peak 0.413 m
    >>> [round(float(law_distance_m([d, d + 0.04], law, mode="servo")[0]), 3) for d in (0.30, 0.373, 0.50)]
    [0.3, 0.383, 0.52]
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
    if mode == "avoidance":
        return nearest, nearest, count == 0
    seen = count > 0
    mean = np.where(valid, readings, 0.0).sum(axis=-1) / np.maximum(count, 1)
    base = np.where(seen, nearest, 0.0)
    ramp_m = settings.peak_distance_m - settings.standoff_m  # D's rising half: the law's own segment
    weight = np.clip((base - settings.standoff_m) / ramp_m, 0.0, 1.0)
    servo = np.where(seen, base + weight * (mean - base), np.inf)
    return servo, nearest, ~seen


def proximity_term(
    distances_m: object, law: ProximityLaw | None = None, *, mode: str = "avoidance"
) -> tuple[FloatArray, FloatArray, BoolArray]:
    """The proximity velocity from several sensors' readings: the law at :func:`law_distance_m`.

    Takes the arguments of :func:`law_distance_m` and returns ``velocity_m_s, nearest_m, no_valid_reading``,
    ndarrays of shape (...): the law's velocity in m/s, the nearer valid reading and the no-return flag.
    """
    settings = ProximityLaw() if law is None else law
    distance, nearest, no_valid = law_distance_m(distances_m, settings, mode=mode)
    return proximity_velocity(distance, settings, mode=mode).velocity_m_s, nearest, no_valid


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
    try:
        np.broadcast_shapes(joystick.shape, trajectory.shape, proximity.shape)
    except ValueError:
        raise InputError(
            f"joystick_m_s, trajectory_m_s and distances_m must describe the same samples; got shapes "
            f"{joystick.shape}, {trajectory.shape} and {proximity.shape} (distances_m without its last axis)."
        ) from None
    return BlendedCommand(
        velocity_m_s=np.asarray(joystick + trajectory + proximity, dtype=np.float64),
        proximity_m_s=proximity,
        nearest_m=nearest,
        no_valid_reading=no_valid,
    )


__all__: list[str] = ["BlendedCommand", "blend_commands", "law_distance_m", "proximity_term"]
