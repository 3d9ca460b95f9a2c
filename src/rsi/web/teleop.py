"""Teleoperation: one period of the seed §3.1 loop with the operator's joystick (Fig. 4), for the console.

A thin adapter over :class:`rsi.sim.proximity_loop.ProximityLoop`, the one §3.1 closed loop that also runs the
proximity demo and the mission's transits (ARCHITECTURE.md, "The sensor boundary"): the rangefinders are
read through the sensor model (response curve, noise, A/D, low-pass filter) and blended by Fig. 4 there;
this module maps the operator's command onto the loop and reports what the page shows.

The operator's command is a velocity in the tool frame: x and y across the view, z along the proximity
sensors' axis (positive toward the surface, the law's sign). x and y go to the loop as free sideways
motion; z is Fig. 4's joystick term ``x_js``. Only the axial part meets the law, and region C's
non-override (a full joystick push nets a velocity <= 0) holds because the law's avoidance speed exceeds the
joystick's (``ProximityLaw`` refuses any other setting). A protrusion that comes into a beam from the side
(region B) makes the axial term retreat.

Hold-to-move: with ``held`` False the arm holds still, proximity term included. A deadman that lets the
arm keep creeping under the proximity law after release would be motion the operator did not ask for. The
loop then only senses (:meth:`ProximityLoop.sense`), so the filters stay settled for the next push.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from rsi import _validate as v
from rsi.control.proximity_law import ProximityLaw, proximity_velocity
from rsi.errors import InputError
from rsi.sim.proximity_loop import ProximityLoop, Rig

FloatArray = NDArray[np.float64]

# seed §3.1 default law: 5 cm/s joystick, avoidance 8 cm/s (> joystick: region C cannot be overridden)
TELEOP_LAW = ProximityLaw()
TELEOP_RATE_HZ = TELEOP_LAW.sample_rate_hz  # seed §3.1: the sensors are read, and the law evaluated, at 44 Hz
STOPPED_SPEED_M_S = 1e-3  # below a millimetre per second the tool counts as stopped


def teleop_loop(arm: Rig, *, seed: int = 0) -> ProximityLoop:
    """The console's loop on `arm`: :data:`TELEOP_LAW`, avoidance (the operator drives; no servo pull).

    `seed` fixes the sensors' noise, so a console run with a fixed world seed repeats.
    """
    return ProximityLoop(arm, law=TELEOP_LAW, mode="avoidance", rng=seed)


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
        The two proximity sensors' filtered readings (rsi.sensors), ``inf`` where there is no return.
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


def clamp_operator(command_m_s: object, law: ProximityLaw = TELEOP_LAW) -> FloatArray:
    """The operator's tool-frame velocity, each axis clamped to the joystick's full deflection."""
    if not isinstance(law, ProximityLaw):
        raise InputError(f"law must be an rsi.control.ProximityLaw; got {type(law).__name__}.")
    command = v.as_float_array(command_m_s, "command_m_s")
    if command.shape != (3,) or not np.isfinite(command).all():
        raise InputError(
            f"command_m_s must be 3 finite velocities in m/s (x, y, z tool); got {command_m_s!r}."
        )
    limit = law.joystick_speed_m_s
    clamped: FloatArray = np.clip(command, -limit, limit)
    return clamped


def teleop_step(loop: ProximityLoop, operator_m_s: object, *, held: bool) -> TeleopStep:
    """One loop period: the operator's command through the §3.1 loop (seed Fig. 4), or only sensing if let go.

    Parameters
    ----------
    loop : ProximityLoop
        The console's loop on its arm (:func:`teleop_loop`); its law clamps the joystick.
    operator_m_s : array_like of shape (3,)
        Tool-frame velocity, m/s: x, y sideways, z toward the surface.
    held : bool
        The deadman: False steps nothing (the loop only senses).
    """
    if not isinstance(loop, ProximityLoop):
        raise InputError(
            f"loop must be the console's ProximityLoop (teleop_loop); got {type(loop).__name__}."
        )
    if not isinstance(held, (bool, np.bool_)):
        raise InputError(f"held must be True or False (the deadman); got {held!r}.")
    operator = clamp_operator(operator_m_s, loop.law)
    before = loop.rig.tool_pose()[0]
    if held:
        sample = loop.step([operator[0], operator[1], 0.0], joystick_m_s=float(operator[2]))
        commanded = np.array([operator[0], operator[1], sample.command_m_s])
    else:  # not even a zero step: redundancy resolution would still move the joints in the null space
        sample = loop.sense()
        commanded = np.zeros(3)
    after = loop.rig.tool_pose()[0]
    return TeleopStep(
        operator_m_s=operator,
        proximity_m_s=sample.proximity_m_s,
        commanded_m_s=commanded,
        distances_m=sample.reading_m,
        regions=tuple(str(r) for r in proximity_velocity(sample.reading_m, loop.law).region),
        tool_position_m=after,
        tool_speed_m_s=float(np.linalg.norm(after - before) / loop.dt_s),
        held=bool(held),
    )


__all__ = [
    "STOPPED_SPEED_M_S",
    "TELEOP_LAW",
    "TELEOP_RATE_HZ",
    "TeleopStep",
    "clamp_operator",
    "teleop_loop",
    "teleop_step",
]
