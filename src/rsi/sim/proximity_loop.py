"""Seed §3.1, Fig. 4: the proximity sensors closing the 44 Hz velocity loop around the arm, written once.

One period of the loop (seed §3.1: the sensors were read through an A/D at 44 Hz on a 68040)::

    MuJoCo rangefinders (true distance, -1 = no return)
      ──► rsi.sensors.ProximityChannel (response curve, noise, 12-bit A/D, low-pass filter, range flag)
      ──► rsi.control.blend_commands (joystick + trajectory + proximity law, Fig. 4)
      ──► velocity along the sensor axis (+ the free motion across it) ──► Configuration Control (the arm)

:class:`ProximityLoop` is the controller, stepped once per sensor sample with the operator's or the trajectory
generator's velocity (the proximity demo's scenarios, the mission's transits, the console's teleop, which
calls :meth:`ProximityLoop.sense` instead while the operator has let go);
:func:`run_closed_loop` drives it for a fixed time from velocity schedules and returns a :class:`LoopTrace`.

Sign convention (as in :mod:`rsi.control`): velocity along the sensor axis is positive toward the surface.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any, Protocol

import numpy as np
from numpy.typing import NDArray

from rsi import _validate as v
from rsi.constants import PROXIMITY_SAMPLE_RATE_HZ
from rsi.control.blending import blend_commands
from rsi.control.proximity_law import MODES, ProximityLaw
from rsi.errors import InputError
from rsi.sensors.proximity import ProximityChannel, ProximitySensor
from rsi.sim.arm import RANGEFINDER_CUTOFF_M

FloatArray = NDArray[np.float64]
BoolArray = NDArray[np.bool_]

RANGE_SITES = ("range_left", "range_right")
"""The arm's two rangefinder sites (seed §3.1: two sensors on the ISEE's face), left and right."""
FRAMES = ("tool", "world")

# The law tuned on the arm. The defaults (Vjs 0.05 m/s, peak 0.03 m/s, region E out to 0.45 m) cannot bring
# the arm from 0.6 m to the standoff within 2 s: at 0.6 m they command nothing (region F), and at 0.03 m/s
# the 0.27 m trip alone takes 9 s. This law therefore uses a faster joystick and servo peak, region E
# reaching out to 0.73 m, and C/D's slope at 6 /s (a quarter of the 22 /s stability bound at 44 Hz, so the
# filter's 39 ms lag adds no overshoot). See docs/proximity-demo.md for the scan that chose these numbers.
ARM_LAW = ProximityLaw(
    joystick_speed_m_s=0.30,
    retreat_speed_m_s=0.80,
    avoidance_speed_m_s=0.60,
    servo_peak_speed_m_s=0.24,
    min_distance_m=0.08,
    avoidance_start_m=0.29,
    hold_distance_m=0.34,
    servo_end_m=0.73,
    max_distance_m=0.75,
    sample_rate_hz=PROXIMITY_SAMPLE_RATE_HZ,  # seed §3.1: the sensors were read through an A/D at 44 Hz
)


class Rig(Protocol):
    """What the loop needs of the arm (:class:`rsi.sim.arm.Arm` has it)."""

    def rangefinder_distances_m(self) -> FloatArray: ...

    def site_position_m(self, name: str) -> FloatArray: ...

    def tool_pose(self) -> tuple[FloatArray, FloatArray]: ...

    def step_velocity(self, twist_or_velocity: object, dt_s: float, *, frame: str = ...) -> Any: ...


@dataclass(frozen=True)
class LoopSample:
    """One period of the loop: what the sensors gave and what was sent (taken before the arm moved).

    Attributes
    ----------
    time_s : float
        Sample time from the loop's start, seconds.
    true_m : ndarray of shape (2,)
        True distances of the two sensors from MuJoCo's rangefinders (``inf``: no return).
    reading_m : ndarray of shape (2,)
        Filtered, linearised readings (rsi.sensors), metres (``inf``: no return).
    out_of_range : ndarray of shape (2,), bool
        The sensors' out-of-range flags.
    origin_m : ndarray of shape (2, 3)
        World positions of the two sensor faces.
    axis : ndarray of shape (3,)
        The sensor axis (unit, world).
    joystick_m_s, trajectory_m_s : float
        Fig. 4's ``x_js`` and ``x_tg`` along the sensor axis.
    proximity_m_s : float
        The proximity law's term ``x_ps``.
    command_m_s : float
        Velocity sent along the sensor axis: the sum (or ``x_js + x_tg`` where the law is not applied).
    """

    time_s: float
    true_m: FloatArray
    reading_m: FloatArray
    out_of_range: BoolArray
    origin_m: FloatArray
    axis: FloatArray
    joystick_m_s: float
    trajectory_m_s: float
    proximity_m_s: float
    command_m_s: float


def _true_distances_m(rig: Rig) -> FloatArray:
    # MuJoCo's rangefinder: negative = no return, clamped at its cutoff; both mean "nothing seen"
    raw = np.asarray(rig.rangefinder_distances_m(), dtype=np.float64)
    return np.where((raw < 0.0) | (raw >= RANGEFINDER_CUTOFF_M), np.inf, raw)


def _check_rig(rig: object) -> None:
    missing = [name for name in _RIG_METHODS if not callable(getattr(rig, name, None))]
    if missing:
        raise InputError(
            f"rig must be an arm (rsi.sim.arm.Arm, or anything with {', '.join(_RIG_METHODS)}); "
            f"got {type(rig).__name__}, which lacks {', '.join(missing)}."
        )


_RIG_METHODS = ("rangefinder_distances_m", "site_position_m", "tool_pose", "step_velocity")


class ProximityLoop:
    """The 44 Hz proximity loop of seed §3.1 (Fig. 4) on an arm, one :meth:`step` per sensor sample.

    Parameters
    ----------
    rig : rsi.sim.arm.Arm
        The arm (anything with its ``rangefinder_distances_m``, ``site_position_m``, ``tool_pose`` and
        ``step_velocity``).
    law : ProximityLaw
        Breakpoints and speeds; its ``sample_rate_hz`` is the loop's rate. May be changed between steps.
    mode : {"avoidance", "servo"}
        May be changed between steps (an operator switching the servo on).
    sensor : ProximitySensor, optional
        Both sensors' settings (default: the seed's SA1D at the law's rate).
    rng : numpy.random.Generator or int or None
        Sensor noise; each sensor gets its own stream, so a seed fixes the run.
    apply_proximity : bool
        False computes ``x_ps`` but does not add it (seed §3.1 measured Figs 6-7 that way).
    """

    def __init__(
        self,
        rig: Rig,
        *,
        law: ProximityLaw = ARM_LAW,
        mode: str = "avoidance",
        sensor: ProximitySensor | None = None,
        rng: np.random.Generator | int | None = None,
        apply_proximity: bool = True,
    ) -> None:
        _check_rig(rig)
        if sensor is not None:
            v.instance_of(sensor, "sensor", ProximitySensor)
        if not isinstance(law, ProximityLaw):  # read below before the law setter checks it
            raise InputError(f"law must be a ProximityLaw; got {type(law).__name__}. Try ARM_LAW.")
        self.sensor = ProximitySensor(sample_rate_hz=law.sample_rate_hz) if sensor is None else sensor
        self.law = law
        self.mode = mode
        self.rig = rig
        self.apply_proximity = bool(apply_proximity)
        self._channels = [ProximityChannel(self.sensor, rng=s) for s in v.as_rng(rng).spawn(len(RANGE_SITES))]
        self.samples = 0

    @property
    def law(self) -> ProximityLaw:
        """The law the next step evaluates."""
        return self._law

    @law.setter
    def law(self, law: ProximityLaw) -> None:
        if not isinstance(law, ProximityLaw):
            raise InputError(f"law must be a ProximityLaw; got {type(law).__name__}. Try ARM_LAW.")
        if law.sample_rate_hz != self.sensor.sample_rate_hz:
            raise InputError(
                f"sensor.sample_rate_hz={self.sensor.sample_rate_hz!r} differs from law.sample_rate_hz="
                f"{law.sample_rate_hz!r}; the loop runs once per sensor sample, so make them equal."
            )
        self._law = law

    @property
    def mode(self) -> str:
        """``"avoidance"`` or ``"servo"`` for the next step."""
        return self._mode

    @mode.setter
    def mode(self, mode: str) -> None:
        self._mode = v.choice(mode, "mode", MODES)

    @property
    def dt_s(self) -> float:
        """The loop's period, seconds."""
        return 1.0 / self._law.sample_rate_hz

    def step(
        self, velocity: object = (0.0, 0.0, 0.0), *, joystick_m_s: float = 0.0, frame: str = "tool"
    ) -> LoopSample:
        """One period: read both sensors, blend, send the command to the arm for one period.

        Parameters
        ----------
        velocity : array_like of shape (3,) or (6,)
            The free motion: the tool tip's linear velocity (m/s), optionally followed by its angular
            velocity (rad/s), in `frame`. Its component along the sensor axis is Fig. 4's trajectory term
            ``x_tg``; the rest (the operator's sideways joystick, the generator's transfer) passes through.
        joystick_m_s : float
            Fig. 4's joystick term ``x_js`` along the sensor axis, within +-``law.joystick_speed_m_s``.
        frame : {"tool", "world"}
            ``"tool"``: z is the sensor axis, x the sensors' baseline.

        Returns
        -------
        LoopSample
            The sample, taken before the arm moved.
        """
        where = v.choice(frame, "frame", FRAMES)
        free = np.asarray(velocity, dtype=np.float64)
        if free.shape not in ((3,), (6,)) or not np.isfinite(free).all():
            raise InputError(
                f"velocity must be 3 (v, m/s) or 6 (v m/s, omega rad/s) finite numbers; got {velocity!r}."
            )
        sensed = self._read_sensors()
        axis = self.rig.tool_pose()[1][:, 2]
        along = float(free[2]) if where == "tool" else float(axis @ free[:3])
        blended = blend_commands(joystick_m_s, along, sensed[1], self._law, mode=self._mode)
        command = float(blended.velocity_m_s) if self.apply_proximity else joystick_m_s + along
        sample = self._sample(
            sensed,
            axis,
            joystick_m_s=joystick_m_s,
            along_m_s=along,
            proximity_m_s=float(blended.proximity_m_s),
            command_m_s=command,
        )
        # seed Fig. 4: the blended command replaces the free motion's part along the sensor axis and goes to
        # Configuration Control as one velocity for one period
        sent = free.copy()
        if where == "tool":
            sent[2] = command
        else:
            sent[:3] = free[:3] + (command - along) * axis
        self.rig.step_velocity(sent, self.dt_s, frame=where)
        self.samples += 1
        return sample

    def sense(self) -> LoopSample:
        """One period with nothing sent: read both sensors through their filters, leave the arm as it is.

        For a loop whose operator let go (the console's hold-to-move): the filters and the sample clock keep
        running at the sensors' rate, so the readings are settled when motion resumes, but the arm is not
        stepped at all -- even a zero velocity step would let redundancy resolution move the joints in the
        null space. Same sensors and noise streams as :meth:`step`.

        Returns
        -------
        LoopSample
            Joystick, trajectory and command zero; ``proximity_m_s`` is the law's term on these readings
            (what it would command, shown to the operator), not sent.
        """
        sensed = self._read_sensors()
        law_term = float(blend_commands(0.0, 0.0, sensed[1], self._law, mode=self._mode).proximity_m_s)
        sample = self._sample(
            sensed,
            self.rig.tool_pose()[1][:, 2],
            joystick_m_s=0.0,
            along_m_s=0.0,
            proximity_m_s=law_term,
            command_m_s=0.0,
        )
        self.samples += 1
        return sample

    def _read_sensors(self) -> tuple[FloatArray, FloatArray, BoolArray]:
        """Both sensors sampled once: true distances, filtered readings, out-of-range flags."""
        true = _true_distances_m(self.rig)
        read = [channel.read(float(d)) for channel, d in zip(self._channels, true, strict=True)]
        return true, np.array([value for value, _ in read]), np.array([flag for _, flag in read])

    def _sample(
        self,
        sensed: tuple[FloatArray, FloatArray, BoolArray],
        axis: FloatArray,
        *,
        joystick_m_s: float,
        along_m_s: float,
        proximity_m_s: float,
        command_m_s: float,
    ) -> LoopSample:
        true, reading, out_of_range = sensed
        return LoopSample(
            time_s=self.samples * self.dt_s,
            true_m=true,
            reading_m=reading,
            out_of_range=out_of_range,
            origin_m=np.array([self.rig.site_position_m(name) for name in RANGE_SITES]),
            axis=axis,
            joystick_m_s=float(joystick_m_s),
            trajectory_m_s=along_m_s,
            proximity_m_s=proximity_m_s,
            command_m_s=command_m_s,
        )


@dataclass(frozen=True)
class LoopTrace:
    """One closed-loop run at the sensors' rate (the :class:`LoopSample` fields stacked over time).

    Attributes
    ----------
    time_s : ndarray of shape (T,)
        Sample times from the start, seconds.
    true_m : ndarray of shape (T, 2)
        True distances of the two sensors from MuJoCo's rangefinders (``inf``: no return).
    reading_m : ndarray of shape (T, 2)
        Filtered, linearised readings (rsi.sensors), metres (``inf``: no return).
    out_of_range : ndarray of shape (T, 2), bool
        The sensors' out-of-range flags.
    command_m_s : ndarray of shape (T,)
        Velocity sent along the sensor axis (positive toward the surface).
    proximity_m_s : ndarray of shape (T,)
        The proximity law's part of it (Fig. 4's ``x_ps``).
    trajectory_m_s : ndarray of shape (T,)
        The free motion's part along the sensor axis (Fig. 4's ``x_tg``).
    origin_m : ndarray of shape (T, 2, 3)
        World positions of the two sensor faces when each sample was taken.
    axis : ndarray of shape (T, 3)
        The sensor axis (unit, world) at each sample.
    """

    time_s: FloatArray
    true_m: FloatArray
    reading_m: FloatArray
    out_of_range: BoolArray
    command_m_s: FloatArray
    proximity_m_s: FloatArray
    trajectory_m_s: FloatArray
    origin_m: FloatArray
    axis: FloatArray

    @classmethod
    def from_samples(cls, samples: Sequence[LoopSample]) -> LoopTrace:
        """Stack the samples of one run, in order."""
        if not samples:
            raise InputError("samples is empty; a trace needs at least one LoopSample.")

        def stacked(name: str, dtype: type = np.float64) -> Any:
            return np.array([getattr(sample, name) for sample in samples], dtype=dtype)

        return cls(
            time_s=stacked("time_s"),
            true_m=stacked("true_m"),
            reading_m=stacked("reading_m"),
            out_of_range=stacked("out_of_range", bool),
            command_m_s=stacked("command_m_s"),
            proximity_m_s=stacked("proximity_m_s"),
            trajectory_m_s=stacked("trajectory_m_s"),
            origin_m=stacked("origin_m"),
            axis=stacked("axis"),
        )

    @property
    def nearest_true_m(self) -> FloatArray:
        """The nearer sensor's true distance at each sample."""
        return np.asarray(self.true_m.min(axis=1), dtype=np.float64)


Schedule = float | Callable[[float], float]
"""A velocity in m/s, constant or as a function of the loop's time in seconds."""


def _as_schedule(value: Schedule, name: str) -> Callable[[float], float]:
    if callable(value):
        return value
    number = v.finite_number(value, name)
    return lambda _time_s: number


def run_closed_loop(
    rig: Rig,
    *,
    duration_s: float,
    law: ProximityLaw = ARM_LAW,
    mode: str = "avoidance",
    joystick_m_s: Schedule = 0.0,
    trajectory_m_s: Schedule = 0.0,
    tangential_m_s: Schedule = 0.0,
    apply_proximity: bool = True,
    sensor: ProximitySensor | None = None,
    rng: np.random.Generator | int | None = None,
) -> LoopTrace:
    """Run the 44 Hz proximity loop of seed §3.1 (Fig. 4) on a rig for `duration_s`.

    Each period :meth:`ProximityLoop.step` reads the rangefinders, blends joystick + trajectory + law along
    the sensor axis and sends the sum, with the tangential joystick along the sensors' baseline (tool x).

    Parameters
    ----------
    rig : rsi.sim.arm.Arm
    duration_s : float
        Length of the run, > 0 s.
    law : ProximityLaw
        Its ``sample_rate_hz`` sets the loop rate.
    mode : {"avoidance", "servo"}
    joystick_m_s, trajectory_m_s : float or callable of time_s
        Fig. 4's ``x_js`` and ``x_tg`` along the sensor axis, m/s (the joystick within +-Vjs).
    tangential_m_s : float or callable of time_s
        The operator's sideways joystick along the sensors' baseline (tool x), m/s.
    apply_proximity : bool
        False computes ``x_ps`` but does not add it (seed §3.1 measured Figs 6-7 that way).
    sensor : ProximitySensor, optional
        Both sensors' settings (default: the seed's SA1D at the law's rate).
    rng : numpy.random.Generator or int or None
        Sensor noise.

    Returns
    -------
    LoopTrace
    """
    duration = v.in_range(duration_s, "duration_s", low=0.0, low_inclusive=False)
    loop = ProximityLoop(rig, law=law, mode=mode, sensor=sensor, rng=rng, apply_proximity=apply_proximity)
    tangential = _as_schedule(tangential_m_s, "tangential_m_s")
    joystick = _as_schedule(joystick_m_s, "joystick_m_s")
    trajectory = _as_schedule(trajectory_m_s, "trajectory_m_s")
    samples = []
    for index in range(max(1, round(duration * law.sample_rate_hz))):
        time_s = index * loop.dt_s
        free = np.array([tangential(time_s), 0.0, trajectory(time_s)])
        samples.append(loop.step(free, joystick_m_s=joystick(time_s)))
    return LoopTrace.from_samples(samples)


__all__: list[str] = [
    "ARM_LAW",
    "RANGE_SITES",
    "LoopSample",
    "LoopTrace",
    "ProximityLoop",
    "Rig",
    "run_closed_loop",
]
