"""Teleoperation: one step of the seed §3.1 loop with the operator's joystick (Fig. 4), for the console.

THE CONSOLE'S ONE STEP FUNCTION. ARCHITECTURE.md wants the §3.1 closed loop to exist once (proximity demo,
mission transits, console teleop); until the sim layer's unified loop lands, the console's step lives here
and only here, built from the same parts: :func:`rsi.control.blending.blend_commands` (Fig. 4's sum along
the sensor axis), :func:`rsi.control.proximity_law.proximity_velocity` (the regions) and the arm's
Cartesian velocity control (:meth:`rsi.sim.arm.Arm.step_velocity`). Switch :func:`teleop_step` to the
unified loop's controller when it exists.

The operator's command is a velocity in the tool frame: x and y across the view, z along the proximity
sensors' axis (positive toward the surface, the law's sign). Only the axial part meets the law: Fig. 4
blends joystick, trajectory and proximity velocities along the sensor axis, and region C's non-override
(a full joystick push nets a velocity <= 0) holds because the law's avoidance speed exceeds the joystick's
(``ProximityLaw`` refuses any other setting). Sideways motion passes through; a protrusion that comes into
a beam from the side (region B) makes the axial term retreat.

Hold-to-move: with ``held`` False the arm holds still, proximity term included. A deadman that lets the
arm keep creeping under the proximity law after release would be motion the operator did not ask for.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol

import numpy as np
from numpy.typing import NDArray

from rsi.control.blending import blend_commands
from rsi.control.proximity_law import ProximityLaw, proximity_velocity
from rsi.errors import InputError

FloatArray = NDArray[np.float64]

TELEOP_RATE_HZ = 44.0  # seed §3.1: the proximity sensors are read, and the law evaluated, at 44 Hz
# seed §3.1 default law: 5 cm/s joystick, avoidance 8 cm/s (> joystick: region C cannot be overridden)
TELEOP_LAW = ProximityLaw()
STOPPED_SPEED_M_S = 1e-3  # below a millimetre per second the tool counts as stopped


class TeleopArm(Protocol):
    """What the step needs of an arm (:class:`rsi.sim.arm.Arm` has it)."""

    def rangefinder_distances_m(self) -> FloatArray: ...

    def tool_pose(self) -> tuple[FloatArray, FloatArray]: ...

    def step_velocity(self, twist_or_velocity: object, dt_s: float, *, frame: str = ...) -> object: ...


@dataclass(frozen=True)
class TeleopStep:
    """What one step commanded and did (the console shows all three commands, seed Fig. 4).

    Attributes
    ----------
    operator_m_s : ndarray of shape (3,)
        The operator's command, tool frame (z toward the surface), after the speed clamp.
    proximity_m_s : float
        The law's term along the sensor axis.
    commanded_m_s : ndarray of shape (3,)
        What was sent to the arm, tool frame: operator's x, y and the blended z (zero when not held).
    distances_m : ndarray of shape (2,)
        The two rangefinders' readings, ``inf`` where there is no return.
    regions : tuple of str
        Each beam's region A-F of the law, ``"-"`` out of range.
    tool_position_m : ndarray of shape (3,)
        After the step, world frame.
    tool_speed_m_s : float
        How fast the tool tip moved during the step.
    held : bool
        Whether the operator held the deadman.
    """

    operator_m_s: FloatArray
    proximity_m_s: float
    commanded_m_s: FloatArray
    distances_m: FloatArray
    regions: tuple[str, ...]
    tool_position_m: FloatArray
    tool_speed_m_s: float
    held: bool


def sensed_distances_m(raw_m: FloatArray) -> FloatArray:
    """MuJoCo's rangefinder readings as the law takes them: no return (< 0) or the cutoff -> ``inf``."""
    from rsi.sim.arm import RANGEFINDER_CUTOFF_M

    readings = np.asarray(raw_m, dtype=np.float64)
    return np.where((readings < 0) | (readings >= RANGEFINDER_CUTOFF_M), np.inf, readings)


def clamp_operator(command_m_s: object, law: ProximityLaw = TELEOP_LAW) -> FloatArray:
    """The operator's tool-frame velocity, each axis clamped to the joystick's full deflection."""
    command = np.asarray(command_m_s, dtype=np.float64)
    if command.shape != (3,) or not np.isfinite(command).all():
        raise InputError(
            f"command_m_s must be 3 finite velocities in m/s (x, y, z tool); got {command_m_s!r}."
        )
    limit = law.joystick_speed_m_s
    clamped: FloatArray = np.clip(command, -limit, limit)
    return clamped


def teleop_step(
    arm: TeleopArm,
    operator_m_s: object,
    *,
    held: bool,
    dt_s: float = 1.0 / TELEOP_RATE_HZ,
    law: ProximityLaw = TELEOP_LAW,
) -> TeleopStep:
    """One loop period: read the beams, blend (seed Fig. 4), command the arm, report all three commands."""
    operator = clamp_operator(operator_m_s, law)
    distances = sensed_distances_m(arm.rangefinder_distances_m())
    regions = tuple(str(r) for r in proximity_velocity(distances, law).region)
    before = arm.tool_pose()[0]
    blend = blend_commands(operator[2], 0.0, distances, law)
    proximity = float(blend.proximity_m_s)
    if held:
        commanded = np.array([operator[0], operator[1], float(blend.velocity_m_s)])
        arm.step_velocity(commanded, dt_s, frame="tool")
    else:  # not even a zero step: redundancy resolution would still move the joints in the null space
        commanded = np.zeros(3)
    after = arm.tool_pose()[0]
    return TeleopStep(
        operator_m_s=operator,
        proximity_m_s=proximity,
        commanded_m_s=commanded,
        distances_m=distances,
        regions=regions,
        tool_position_m=after,
        tool_speed_m_s=float(np.linalg.norm(after - before) / dt_s),
        held=bool(held),
    )


__all__ = [
    "STOPPED_SPEED_M_S",
    "TELEOP_LAW",
    "TELEOP_RATE_HZ",
    "TeleopStep",
    "clamp_operator",
    "sensed_distances_m",
    "teleop_step",
]
