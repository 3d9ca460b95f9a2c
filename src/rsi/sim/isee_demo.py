"""Seed §3.1, Figs 3-7: the proximity sensors closing a 44 Hz loop around the ISEE in MuJoCo.

One loop, run once per sensor sample (seed §3.1: 44 Hz on a 68040)::

    MuJoCo rangefinders (true distance, -1 = no return)
      ──► rsi.sensors.ProximityChannel (response curve, noise, 12-bit A/D, low-pass filter, range flag)
      ──► rsi.control.blend_commands (joystick + trajectory + proximity law, Fig. 4)
      ──► velocity along the sensor axis (+ the operator's tangential joystick) ──► arm / tool

The plant is the 7-DOF arm of :mod:`rsi.sim.arm` (its two rangefinders sit on the ISEE's face, recessed
0.11 m behind the jaw tips, seed §3.1), driven through ``Arm.step_velocity`` in the tool frame: z along the
sensor axis, x along the sensors' baseline (the operator's sideways joystick). The scenarios
(:func:`simulate_proximity_demo`, which returns a :class:`ProximityDemoResult` and writes nothing; the
plots and JSON files are drawn by :func:`rsi.report.isee.write_proximity_report`):

a. full joystick push toward a wall in avoidance mode: the arm must stop in region C (non-override);
b. servo from 0.6 m to the standoff: settle time, settle error, overshoot;
c. tangential joystick motion along a stepped and a curved surface in servo mode: following error;
d. the surface contour reconstructed from the rig's poses and the filtered readings;
e. arm tracking of a Cartesian path with the additional task (from :mod:`rsi.sim.arm`);
f. the regulated halogen lamps under supply and ageing disturbances (:mod:`rsi.sensors.lamps`).

Sign convention (as in :mod:`rsi.control`): velocity along the sensor axis is positive toward the surface.
Fig. 3's arm-position axis is shifted so the wall lies at -0.81 m, as in the seed's experiment.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import asdict, dataclass
from typing import Any, Protocol

import numpy as np
from numpy.typing import NDArray

from rsi import _validate as v
from rsi.control.blending import blend_commands, proximity_term
from rsi.control.proximity_law import ProximityLaw, proximity_velocity
from rsi.errors import InputError
from rsi.sensors.lamps import LampController, simulate_lamp
from rsi.sensors.proximity import LowPassFilter, ProximityChannel, ProximitySensor

FloatArray = NDArray[np.float64]
BoolArray = NDArray[np.bool_]
Progress = Callable[[str, int, int], None]
"""Called as ``progress(stage, completed, total)`` (the CLI's progress bar)."""

SAMPLE_RATE_HZ = 44.0  # seed §3.1: the sensors were read through an A/D at 44 Hz
GRIPPER_LENGTH_M = 0.11  # seed §3.1: sensors recessed behind a parallel-jaw gripper 11 cm long
SURFACE_Z_M = -0.81  # seed Fig. 3: "the environment surface was at about -0.81 m"
TANGENTIAL_SPEED_M_S = 0.05  # the operator's sideways joystick during contour following (scenario c)

# The demo's law. The defaults (Vjs 0.05 m/s, peak 0.03 m/s, region E out to 0.45 m) cannot bring the arm
# from 0.6 m to the standoff within 2 s: at 0.6 m they command nothing (region F), and at 0.03 m/s the
# 0.27 m trip alone takes 9 s. The demo therefore uses a faster joystick and servo peak, region E reaching
# out to 0.73 m, and C/D's slope at 6 /s (a quarter of the 22 /s stability bound at 44 Hz, so the filter's
# 39 ms lag adds no overshoot). See docs/proximity-demo.md for the scan that chose these numbers.
DEMO_LAW = ProximityLaw(
    joystick_speed_m_s=0.30,
    retreat_speed_m_s=0.80,
    avoidance_speed_m_s=0.60,
    servo_peak_speed_m_s=0.24,
    min_distance_m=0.08,
    avoidance_start_m=0.29,
    hold_distance_m=0.34,
    servo_end_m=0.73,
    max_distance_m=0.75,
    sample_rate_hz=SAMPLE_RATE_HZ,
)
SETTLE_BAND_M = 0.005  # issue 4: servo_settle_error_m <= 5 mm; the settle time uses the same band
RECOVERY_S = 1.0  # following error is judged once a surface discontinuity has had this long to recover
DISCONTINUITY_M = 0.005  # a jump of the surface under a sensor ray larger than this in one sample
LAMP_DURATION_S = 3.0
LAMP_SETTLE_S = 0.3  # the lamp loop starts dark; judged after it has settled (rsi.sensors.lamps)
ARM_PATH = "circle"


@dataclass(frozen=True)
class DemoFigures:
    """The acceptance figures of issue 4 (seed §3, §3.1), from :func:`simulate_proximity_demo`.

    Attributes
    ----------
    min_distance_full_push_m : float
        Closest true distance of either sensor to the wall under a full joystick push in avoidance mode.
    avoidance_near_edge_m : float
        Near edge of region C (B|C) of the law used; the push must stay beyond it minus 10 mm.
    push_oscillation_m : float
        Peak-to-peak true distance over the last second of the push (0 for a still arm; sustained
        oscillation would show here).
    servo_settle_error_m : float
        Largest |distance - standoff| over the last second of the servo run from 0.6 m.
    servo_settle_time_s : float
        From the start until the distance stays within ``SETTLE_BAND_M`` of the standoff.
    servo_overshoot_m : float
        How far the servo run went past the standoff toward the wall (0 if never).
    following_error_m : float
        Largest |nearest distance - standoff| while the operator moves the tool sideways over the stepped
        and the curved surface, outside the ``RECOVERY_S`` after a step edge enters a sensor's view.
    contour_rms_error_m : float
        RMS error of the surface profile rebuilt from the arm's poses and the filtered readings.
    arm_tracking_error_m : float
        The arm's largest Cartesian tracking error on a path (:func:`rsi.sim.arm.track_path`).
    lamp_illumination_error : float
        Largest relative illumination error of the regulated lamps after settling.
    """

    min_distance_full_push_m: float
    avoidance_near_edge_m: float
    push_oscillation_m: float
    servo_settle_error_m: float
    servo_settle_time_s: float
    servo_overshoot_m: float
    following_error_m: float
    contour_rms_error_m: float
    arm_tracking_error_m: float
    lamp_illumination_error: float

    def to_dict(self) -> dict[str, float]:
        """The figures as a JSON-ready mapping (the ``--json`` line of ``rsi isee proximity-demo``)."""
        return {name: float(value) for name, value in asdict(self).items()}


@dataclass(frozen=True)
class LoopTrace:
    """One closed-loop run at the sensors' rate.

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
    origin_m: FloatArray
    axis: FloatArray

    @property
    def nearest_true_m(self) -> FloatArray:
        """The nearer sensor's true distance at each sample."""
        return np.asarray(self.true_m.min(axis=1), dtype=np.float64)


class _Rig(Protocol):
    """What the loop needs of the arm (see :class:`rsi.sim.arm.Arm`)."""

    def rangefinder_distances_m(self) -> FloatArray: ...

    def site_position_m(self, name: str) -> FloatArray: ...

    def tool_pose(self) -> tuple[FloatArray, FloatArray]: ...

    def step_velocity(self, twist_or_velocity: object, dt_s: float, *, frame: str = ...) -> Any: ...


_RANGE_SITES = ("range_left", "range_right")


def _true_distances_m(rig: _Rig, cutoff_m: float) -> FloatArray:
    # MuJoCo's rangefinder: negative = no return, clamped at its cutoff; both mean "nothing seen"
    raw = np.asarray(rig.rangefinder_distances_m(), dtype=np.float64)
    return np.where((raw < 0.0) | (raw >= cutoff_m), np.inf, raw)


def _as_schedule(value: float | Callable[[float], float], name: str) -> Callable[[float], float]:
    if callable(value):
        return value
    number = v.finite_number(value, name)
    return lambda _time_s: number


def run_closed_loop(
    rig: _Rig,
    *,
    duration_s: float,
    law: ProximityLaw = DEMO_LAW,
    mode: str = "avoidance",
    joystick_m_s: float | Callable[[float], float] = 0.0,
    trajectory_m_s: float | Callable[[float], float] = 0.0,
    tangential_m_s: float | Callable[[float], float] = 0.0,
    apply_proximity: bool = True,
    sensor: ProximitySensor | None = None,
    rng: np.random.Generator | int | None = None,
) -> LoopTrace:
    """Run the 44 Hz proximity loop of seed §3.1 (Fig. 4) on a rig for `duration_s`.

    Each period: read MuJoCo's rangefinders, pass each through its own :class:`ProximityChannel` (noise,
    A/D, low-pass filter), blend joystick + trajectory + proximity law (:func:`blend_commands`) and send
    the sum along the sensor axis, with the tangential joystick along the sensors' baseline, for one period.

    Parameters
    ----------
    rig : rsi.sim.arm.Arm
        The arm (anything with its ``rangefinder_distances_m``, ``site_position_m``, ``tool_pose`` and
        ``step_velocity``).
    duration_s : float
        Length of the run, > 0 s.
    law : ProximityLaw
        Breakpoints and speeds; its ``sample_rate_hz`` sets the loop rate.
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
        Sensor noise; each sensor gets its own stream, so a seed fixes the run.

    Returns
    -------
    LoopTrace
    """
    duration = v.in_range(duration_s, "duration_s", low=0.0, low_inclusive=False)
    v.choice(mode, "mode", ("avoidance", "servo"))
    tangential = _as_schedule(tangential_m_s, "tangential_m_s")
    joystick = _as_schedule(joystick_m_s, "joystick_m_s")
    trajectory = _as_schedule(trajectory_m_s, "trajectory_m_s")
    settings = ProximitySensor(sample_rate_hz=law.sample_rate_hz) if sensor is None else sensor
    if settings.sample_rate_hz != law.sample_rate_hz:
        raise InputError(
            f"sensor.sample_rate_hz={settings.sample_rate_hz!r} differs from law.sample_rate_hz="
            f"{law.sample_rate_hz!r}; the loop runs once per sensor sample, so make them equal."
        )
    streams = v.as_rng(rng).spawn(len(_RANGE_SITES))
    channels = [ProximityChannel(settings, rng=stream) for stream in streams]
    dt_s = 1.0 / law.sample_rate_hz
    samples = max(1, round(duration * law.sample_rate_hz))
    true_m = np.empty((samples, 2))
    reading_m = np.empty((samples, 2))
    flags = np.empty((samples, 2), dtype=bool)
    command = np.empty(samples)
    proximity = np.empty(samples)
    origin = np.empty((samples, 2, 3))
    axis = np.empty((samples, 3))
    for index in range(samples):
        time_s = index * dt_s
        true_m[index] = _true_distances_m(rig, settings.max_distance_m)
        for sensor_index, channel in enumerate(channels):
            reading_m[index, sensor_index], flags[index, sensor_index] = channel.read(
                true_m[index, sensor_index]
            )
        origin[index] = [rig.site_position_m(name) for name in _RANGE_SITES]
        axis[index] = rig.tool_pose()[1][:, 2]
        blended = blend_commands(joystick(time_s), trajectory(time_s), reading_m[index], law, mode=mode)
        proximity[index] = float(blended.proximity_m_s)
        command[index] = (
            float(blended.velocity_m_s) if apply_proximity else joystick(time_s) + trajectory(time_s)
        )
        # seed Fig. 4: the blended command goes to Configuration Control as a tool-frame velocity
        rig.step_velocity(np.array([tangential(time_s), 0.0, command[index]]), dt_s, frame="tool")
    return LoopTrace(
        time_s=np.arange(samples, dtype=np.float64) * dt_s,
        true_m=true_m,
        reading_m=reading_m,
        out_of_range=flags,
        command_m_s=command,
        proximity_m_s=proximity,
        origin_m=origin,
        axis=axis,
    )


# ------------------------------------------------------------------------------------------ metrics


def settle_figures(
    time_s: FloatArray, distance_m: FloatArray, standoff_m: float, *, band_m: float = SETTLE_BAND_M
) -> tuple[float, float, float]:
    """(settle error, settle time, overshoot) of an approach to `standoff_m` from farther away.

    Parameters
    ----------
    time_s : ndarray of shape (T,)
        Sample times, seconds from the start of the approach.
    distance_m : ndarray of shape (T,)
        True distance to the surface, metres.
    standoff_m : float
        The law's standoff.
    band_m : float
        Settled means within this of the standoff from then on.

    Returns
    -------
    settle_error_m, settle_time_s, overshoot_m : float
        Largest |error| over the last second; time after which the error stays within `band_m` (``inf``
        if it never does); how far the run went past the standoff toward the surface (>= 0).
    """
    error = distance_m - standoff_m
    outside = np.nonzero(np.abs(error) > band_m)[0]
    step_s = float(time_s[1] - time_s[0]) if time_s.size > 1 else 0.0
    if outside.size == 0:
        settle_time = 0.0
    elif outside[-1] == time_s.size - 1:
        settle_time = math.inf
    else:
        settle_time = float(time_s[outside[-1]]) + step_s
    last_second = time_s >= time_s[-1] - 1.0
    return (
        float(np.abs(error[last_second]).max()),
        settle_time,
        float(max(0.0, -float(error.min()))),
    )


def following_error_m(
    error_m: FloatArray, discontinuity: BoolArray, *, samples_to_recover: int
) -> tuple[float, float]:
    """(following error, transient peak) of a contour-following run.

    Parameters
    ----------
    error_m : ndarray of shape (T,)
        Nearest true distance minus the standoff at each sample.
    discontinuity : ndarray of shape (T,), bool
        True where a surface step entered a sensor's ray at that sample.
    samples_to_recover : int
        Samples after each discontinuity left out of the following error (they are the transient).

    Returns
    -------
    following_error_m : float
        Largest |error| outside the recovery windows.
    transient_m : float
        Largest |error| inside them (a step of height h changes the distance by h in one sample).
    """
    recovering = np.zeros(error_m.size, dtype=bool)
    for index in np.nonzero(discontinuity)[0]:
        recovering[index : index + samples_to_recover] = True
    steady = np.abs(error_m[~recovering])
    transient = np.abs(error_m[recovering])
    return (
        float(steady.max()) if steady.size else 0.0,
        float(transient.max()) if transient.size else 0.0,
    )


def _interpolate_rows(time_s: FloatArray, values: FloatArray, at_s: FloatArray) -> FloatArray:
    flat = values.reshape(values.shape[0], -1)
    columns = [np.interp(at_s, time_s, flat[:, column]) for column in range(flat.shape[1])]
    return np.stack(columns, axis=-1).reshape((at_s.size, *values.shape[1:]))


def reconstruct_contour(trace: LoopTrace, *, delay_s: float) -> tuple[FloatArray, FloatArray]:
    """Surface points seen by the sensors: the arm's pose plus the filtered reading along the axis.

    seed §3: the proximity sensors serve "surface contour measuring". A filtered reading describes the
    surface as it was ``delay_s`` earlier (the low-pass filter's lag, seed §3.1), so it is paired with the
    sensor pose of that instant, interpolated between samples.

    Parameters
    ----------
    trace : LoopTrace
    delay_s : float
        The filter's lag, >= 0 s (:attr:`LowPassFilter.dc_delay_s`).

    Returns
    -------
    points_m : ndarray of shape (K, 3)
        World points of the in-range readings whose delayed pose lies inside the run.
    sample_time_s : ndarray of shape (K,)
        The instant each point describes.
    """
    lag = v.in_range(delay_s, "delay_s", low=0.0)
    at_s = trace.time_s - lag
    keep_time = at_s >= trace.time_s[0]
    origin = _interpolate_rows(trace.time_s, trace.origin_m, at_s)
    axis = _interpolate_rows(trace.time_s, trace.axis, at_s)
    axis /= np.linalg.norm(axis, axis=1, keepdims=True)
    valid = keep_time[:, None] & ~trace.out_of_range & np.isfinite(trace.reading_m)
    reading = np.where(valid, trace.reading_m, 0.0)
    points = origin + reading[..., None] * axis[:, None, :]
    times = np.broadcast_to(at_s[:, None], valid.shape)
    return points[valid], times[valid]


# ---------------------------------------------------------------------------------------- scenarios

PUSH_START_M = 0.70  # sensed distance where the full push starts (inside the sensors' 0.75 m)
SERVO_START_M = 0.60  # issue 4: servo from 0.6 m
PUSH_DURATION_S = 3.0
SERVO_DURATION_S = 4.0
SETTLE_BEFORE_SCAN_S = 1.5  # servo at rest before the operator moves sideways
STEPPED_SCAN_M = 0.65  # over both steps up and the step down at 0.5 m (arm.SteppedSurface defaults)
CURVED_SCAN_M = 0.40
CURVED_RADIUS_M = 0.40
SWEEP_SPEED_M_S = 0.05  # seed §3.1: "a simple linear trajectory away from the environmental surface"
SWEEP_NEAR_M = 0.12
SWEEP_FAR_M = 0.78


@dataclass(frozen=True)
class Scenario:
    """One scenario's run: the trace, the arm's home tool frame and the obstacle it met.

    Attributes
    ----------
    name : str
    trace : LoopTrace
    home_tip_m : ndarray of shape (3,)
        Tool tip at the arm's home pose (the obstacles are placed from it).
    home_rotation : ndarray of shape (3, 3)
        Tool frame at home (columns x, y, z in world; z is the sensor axis, x the sensors' baseline).
    obstacle : object
        The :mod:`rsi.sim.arm` obstacle (``surface_distance_m(tangential)`` gives its profile).
    scan_start_s : float
        When the sideways motion started (0 where there is none).
    """

    name: str
    trace: LoopTrace
    home_tip_m: FloatArray
    home_rotation: FloatArray
    obstacle: Any
    scan_start_s: float = 0.0

    def depth_m(self, points_m: FloatArray) -> FloatArray:
        """Depth of world points along the home sensor axis, from the home tool tip."""
        return np.asarray((points_m - self.home_tip_m) @ self.home_rotation[:, 2], dtype=np.float64)

    def tangential_m(self, points_m: FloatArray) -> FloatArray:
        """Offset of world points along the home baseline (the scan direction), from the home tool tip."""
        return np.asarray((points_m - self.home_tip_m) @ self.home_rotation[:, 0], dtype=np.float64)


def _arm(obstacle: Any) -> tuple[Any, FloatArray, FloatArray]:
    from rsi.sim.arm import Arm

    arm = Arm([obstacle])
    tip, rotation = arm.tool_pose()
    return arm, tip, rotation


def _move_along_axis(
    arm: Any, offset_m: float, *, speed_m_s: float = 0.2, rate_hz: float = SAMPLE_RATE_HZ
) -> None:
    """Place the tool `offset_m` along its axis before a scenario (not logged)."""
    steps = math.ceil(abs(offset_m) / speed_m_s * rate_hz)
    for _ in range(steps):
        arm.step_velocity(np.array([0.0, 0.0, offset_m / steps * rate_hz]), 1.0 / rate_hz, frame="tool")


def full_push(law: ProximityLaw = DEMO_LAW, *, rng: np.random.Generator | int | None = None) -> Scenario:
    """Scenario a: a full joystick push (+Vjs) toward a wall in avoidance mode (seed §3.1, region C)."""
    from rsi.sim.arm import Wall

    wall = Wall(SERVO_START_M - GRIPPER_LENGTH_M)
    arm, tip, rotation = _arm(wall)
    _move_along_axis(arm, SERVO_START_M - PUSH_START_M)  # back off to 0.70 m; the arm's reach is limited
    trace = run_closed_loop(
        arm,
        duration_s=PUSH_DURATION_S,
        law=law,
        mode="avoidance",
        joystick_m_s=law.joystick_speed_m_s,
        rng=rng,
    )
    return Scenario("full_push", trace, tip, rotation, wall)


def servo_approach(law: ProximityLaw = DEMO_LAW, *, rng: np.random.Generator | int | None = None) -> Scenario:
    """Scenario b: distance servoing from 0.6 m to the standoff, joystick at rest (seed §3.1, D-E)."""
    from rsi.sim.arm import Wall

    wall = Wall(SERVO_START_M - GRIPPER_LENGTH_M)
    arm, tip, rotation = _arm(wall)
    trace = run_closed_loop(arm, duration_s=SERVO_DURATION_S, law=law, mode="servo", rng=rng)
    return Scenario("servo", trace, tip, rotation, wall)


def follow_surface(
    surface: str,
    law: ProximityLaw = DEMO_LAW,
    *,
    speed_m_s: float = TANGENTIAL_SPEED_M_S,
    rng: np.random.Generator | int | None = None,
) -> Scenario:
    """Scenario c: servo mode while the operator moves the tool sideways over a surface.

    Parameters
    ----------
    surface : {"stepped", "curved"}
        ``"stepped"``: :class:`rsi.sim.arm.SteppedSurface` (steps up of 5 and 10 cm, then down), its base
        at the standoff; ``"curved"``: a 0.4 m radius cylinder whose crest is at the standoff.
    law : ProximityLaw
    speed_m_s : float
        Sideways joystick, > 0 m/s.
    rng : numpy.random.Generator or int or None
    """
    from rsi.sim.arm import CurvedSurface, SteppedSurface

    name = v.choice(surface, "surface", ("stepped", "curved"))
    speed = v.in_range(speed_m_s, "speed_m_s", low=0.0, low_inclusive=False)
    standoff_tip_m = law.standoff_m - GRIPPER_LENGTH_M
    obstacle: Any
    if name == "stepped":
        obstacle, scan_m = SteppedSurface(standoff_tip_m), STEPPED_SCAN_M
    else:
        obstacle = CurvedSurface(standoff_tip_m, radius_m=CURVED_RADIUS_M, centre_m=CURVED_SCAN_M / 2)
        scan_m = CURVED_SCAN_M
    arm, tip, rotation = _arm(obstacle)
    trace = run_closed_loop(
        arm,
        duration_s=SETTLE_BEFORE_SCAN_S + scan_m / speed,
        law=law,
        mode="servo",
        tangential_m_s=lambda time_s: speed if time_s >= SETTLE_BEFORE_SCAN_S else 0.0,
        rng=rng,
    )
    return Scenario(f"follow_{name}", trace, tip, rotation, obstacle, scan_start_s=SETTLE_BEFORE_SCAN_S)


def reading_sweep(law: ProximityLaw = DEMO_LAW, *, rng: np.random.Generator | int | None = None) -> Scenario:
    """Figs 3, 6, 7: a linear trajectory away from a wall with x_ps computed but not applied (seed §3.1)."""
    from rsi.sim.arm import Wall

    forward_m = 0.28  # the arm reaches about 0.31 m forward of home along the tool axis
    wall = Wall(forward_m + SWEEP_NEAR_M - GRIPPER_LENGTH_M)
    arm, tip, rotation = _arm(wall)
    _move_along_axis(arm, forward_m)
    trace = run_closed_loop(
        arm,
        duration_s=(SWEEP_FAR_M - SWEEP_NEAR_M) / SWEEP_SPEED_M_S,
        law=law,
        mode="avoidance",
        trajectory_m_s=-SWEEP_SPEED_M_S,
        apply_proximity=False,
        rng=rng,
    )
    return Scenario("sweep", trace, tip, rotation, wall)


def _discontinuities(scenario: Scenario) -> BoolArray:
    """Samples at which the surface under either sensor ray jumped (a step edge entered the ray)."""
    trace = scenario.trace
    hit = (
        trace.origin_m
        + np.where(np.isfinite(trace.true_m), trace.true_m, 0.0)[..., None] * trace.axis[:, None]
    )
    depth = scenario.depth_m(hit)
    jumps = np.zeros(trace.time_s.size, dtype=bool)
    jumps[1:] = (np.abs(np.diff(depth, axis=0)) > DISCONTINUITY_M).any(axis=1)
    return jumps


@dataclass(frozen=True)
class ContourScan:
    """Scenario d on one surface: the profile rebuilt from poses and readings, and the true one.

    Attributes
    ----------
    name : str
        The scenario's name (``"follow_stepped"``, ``"follow_curved"``).
    tangential_m, depth_m : ndarray of shape (K,)
        Rebuilt points during the scan: offset along the scan and depth from the home tool tip.
    error_m : ndarray of shape (K,)
        Rebuilt minus true depth at each point.
    profile_tangential_m, profile_depth_m : ndarray of shape (P,)
        The true profile sampled over the scanned span.
    """

    name: str
    tangential_m: FloatArray
    depth_m: FloatArray
    error_m: FloatArray
    profile_tangential_m: FloatArray
    profile_depth_m: FloatArray


@dataclass(frozen=True)
class LawResponse:
    """Seed Fig. 6 (avoidance) or 7 (servo): commanded x_ps against the proximity it was computed from.

    Attributes
    ----------
    mode : {"avoidance", "servo"}
    measured_m : ndarray of shape (T,)
        The proximity the law acted on (nearer reading when avoiding, mean of both when servoing); NaN
        where no sensor had a return.
    commanded_m_s : ndarray of shape (T,)
        x_ps at each sample (positive toward the surface).
    law_distance_m, law_velocity_m_s : ndarray of shape (C,)
        The law's own curve.
    breakpoints_m : tuple of float
        The law's region edges.
    """

    mode: str
    measured_m: FloatArray
    commanded_m_s: FloatArray
    law_distance_m: FloatArray
    law_velocity_m_s: FloatArray
    breakpoints_m: tuple[float, ...]


def contour_scan(scenario: Scenario, *, delay_s: float, profile_samples: int = 2000) -> ContourScan:
    """Scenario d on one scan: the profile rebuilt by :func:`reconstruct_contour` against the true one.

    Parameters
    ----------
    scenario : Scenario
        A contour-following run (:func:`follow_surface`); only its scan phase is used.
    delay_s : float
        The filter's lag, >= 0 s (:attr:`LowPassFilter.dc_delay_s`).
    profile_samples : int
        Samples of the true profile over the scanned span (for plotting).

    Returns
    -------
    ContourScan
    """
    points, sample_time = reconstruct_contour(scenario.trace, delay_s=delay_s)
    keep = sample_time >= scenario.scan_start_s
    tangential = scenario.tangential_m(points[keep])
    depth = scenario.depth_m(points[keep])
    truth = np.asarray(scenario.obstacle.surface_distance_m(tangential), dtype=np.float64)
    profile = np.linspace(tangential.min(), tangential.max(), profile_samples)
    return ContourScan(
        name=scenario.name,
        tangential_m=tangential,
        depth_m=depth,
        error_m=depth - truth,
        profile_tangential_m=profile,
        profile_depth_m=np.asarray(scenario.obstacle.surface_distance_m(profile), dtype=np.float64),
    )


def law_response(trace: LoopTrace, law: ProximityLaw, mode: str, *, curve_samples: int = 400) -> LawResponse:
    """Seed Figs 6-7: x_ps computed from a trace's readings against the proximity the law acted on.

    Parameters
    ----------
    trace : LoopTrace
        Usually the open-loop sweep (:func:`reading_sweep`), where x_ps was computed but not applied.
    law : ProximityLaw
    mode : {"avoidance", "servo"}
    curve_samples : int
        Samples of the law's own curve, from 0 to 5 cm past the sensors' maximum distance.

    Returns
    -------
    LawResponse
    """
    v.choice(mode, "mode", ("avoidance", "servo"))
    commanded, nearest, _ = proximity_term(trace.reading_m, law, mode=mode)
    # rsi.control.blending acts on the nearer reading when avoiding and on the mean of the two when servoing
    measured = (
        nearest if mode == "avoidance" else np.where(np.isfinite(nearest), trace.reading_m.mean(1), np.inf)
    )
    curve_m = np.linspace(0.0, law.max_distance_m + 0.05, curve_samples)
    return LawResponse(
        mode=mode,
        measured_m=np.where(np.isfinite(measured), measured, np.nan),
        commanded_m_s=np.asarray(commanded, dtype=np.float64),
        law_distance_m=curve_m,
        law_velocity_m_s=np.asarray(proximity_velocity(curve_m, law, mode=mode).velocity_m_s, np.float64),
        breakpoints_m=tuple(float(edge) for edge in law.breakpoints_m),
    )


# -------------------------------------------------------------------------------------- front door


@dataclass(frozen=True)
class SurfaceFigures:
    """Scenarios c-d on one surface (the ``surfaces`` entries of ``scenarios.json``).

    Attributes
    ----------
    following_error_m : float
        Largest |nearest distance - standoff| during the scan, outside the recovery windows.
    step_transient_m : float
        Largest |nearest distance - standoff| inside them (about the step height).
    closest_m : float
        Closest true distance of either sensor over the run.
    contour_rms_error_m : float
        RMS error of the rebuilt profile.
    contour_points : int
        How many rebuilt points the RMS is over.
    """

    following_error_m: float
    step_transient_m: float
    closest_m: float
    contour_rms_error_m: float
    contour_points: int


@dataclass(frozen=True)
class ProximityDemoResult:
    """Scenarios a-f of issue 4: the acceptance figures and every trace behind them, ready to draw.

    Attributes
    ----------
    seed : int
        Seed of every noise source.
    law : ProximityLaw
        The law the loops ran (:data:`DEMO_LAW`).
    figures : DemoFigures
        The acceptance figures.
    push, servo : Scenario
        Scenarios a (full joystick push, avoidance mode) and b (servo from 0.6 m).
    follows : tuple of Scenario
        Scenario c over the stepped and the curved surface, in that order.
    contours : tuple of ContourScan
        Scenario d on the same two scans, same order.
    surfaces : dict of str to SurfaceFigures
        Per-surface figures of c-d, keyed by the scenario's name.
    sweep : Scenario
        The open-loop linear trajectory away from the wall behind Figs 3, 6 and 7.
    sweep_arm_position_m : ndarray of shape (T,)
        Fig. 3's abscissa: the arm position during the sweep on the seed's axis.
    surface_position_m : float
        Where that axis puts the wall (:data:`SURFACE_Z_M`).
    avoidance_response, servo_response : LawResponse
        Figs 6 and 7.
    lamp_time_s, lamp_error : ndarray of shape (L,)
        Scenario f: time and relative illumination error of the regulated lamps.
    lamp_settle_s : float
        Start of the window the lamp figure is judged over.
    recovery_s, filter_delay_s : float
        The following error's recovery window; the filter lag the contour pairs readings with.
    arm_path : str
        Scenario e's path (:func:`rsi.sim.arm.track_path`).
    additional_task_error_deg : float
        Scenario e: largest error of the additional (arm-angle) task.
    """

    seed: int
    law: ProximityLaw
    figures: DemoFigures
    push: Scenario
    servo: Scenario
    follows: tuple[Scenario, ...]
    contours: tuple[ContourScan, ...]
    surfaces: Mapping[str, SurfaceFigures]
    sweep: Scenario
    sweep_arm_position_m: FloatArray
    surface_position_m: float
    avoidance_response: LawResponse
    servo_response: LawResponse
    lamp_time_s: FloatArray
    lamp_error: FloatArray
    lamp_settle_s: float
    recovery_s: float
    filter_delay_s: float
    arm_path: str
    additional_task_error_deg: float


_STAGES = (
    "a: full joystick push toward a wall (avoidance)",
    "b: servo from 0.6 m to the standoff",
    "c: sideways over a stepped and a curved surface (servo)",
    "Figs 3, 6, 7: linear trajectory away from the wall",
    f"e: arm tracking ({ARM_PATH} path)",
    "f: regulated lamps under supply and ageing disturbances",
)


def simulate_proximity_demo(*, seed: int = 0, progress: Progress | None = None) -> ProximityDemoResult:
    """Run scenarios a-f of issue 4 on the arm and measure the acceptance figures; writes nothing.

    Parameters
    ----------
    seed : int
        Seeds every noise source (sensor noise, lamp supply); the same seed gives the same result.
    progress : callable, optional
        Called as ``progress(stage, completed, total)`` as each stage starts, and once when all are done.

    Returns
    -------
    ProximityDemoResult
        Draw it with :func:`rsi.report.isee.write_proximity_report`.
    """
    if isinstance(seed, bool) or not isinstance(seed, int | np.integer) or seed < 0:
        raise InputError(f"seed must be a non-negative integer; got {seed!r}.")
    from rsi.sim.arm import track_path

    law = DEMO_LAW
    streams = np.random.SeedSequence(int(seed)).spawn(6)
    delay_s = LowPassFilter(4.0, law.sample_rate_hz).dc_delay_s
    recover = round(RECOVERY_S * law.sample_rate_hz)
    stage = iter(enumerate(_STAGES))

    def report() -> None:
        if progress is not None:
            index, name = next(stage, (len(_STAGES), "done"))
            progress(name, index, len(_STAGES))

    report()
    push = full_push(law, rng=np.random.default_rng(streams[0]))
    report()
    servo = servo_approach(law, rng=np.random.default_rng(streams[1]))
    report()
    follows = tuple(
        follow_surface(name, law, rng=np.random.default_rng(streams[2 + index]))
        for index, name in enumerate(("stepped", "curved"))
    )
    report()
    sweep = reading_sweep(law, rng=np.random.default_rng(streams[4]))
    report()
    tracking = track_path(ARM_PATH)
    report()
    lamp = simulate_lamp(LAMP_DURATION_S, rng=np.random.default_rng(streams[5]))
    lamp_error = np.asarray(lamp.relative_error(LampController().setpoint_lux), dtype=np.float64)
    report()

    settle_error, settle_time, overshoot = settle_figures(
        servo.trace.time_s, servo.trace.true_m.mean(axis=1), law.standoff_m
    )
    contours = tuple(contour_scan(scenario, delay_s=delay_s) for scenario in follows)
    surfaces: dict[str, SurfaceFigures] = {}
    for scenario, contour in zip(follows, contours, strict=True):
        scan = scenario.trace.time_s >= scenario.scan_start_s
        steady, transient = following_error_m(
            scenario.trace.nearest_true_m[scan] - law.standoff_m,
            _discontinuities(scenario)[scan],
            samples_to_recover=recover,
        )
        surfaces[scenario.name] = SurfaceFigures(
            following_error_m=steady,
            step_transient_m=transient,
            closest_m=float(scenario.trace.true_m.min()),
            contour_rms_error_m=float(np.sqrt(np.mean(contour.error_m**2))),
            contour_points=int(contour.error_m.size),
        )
    last_second = push.trace.time_s >= push.trace.time_s[-1] - 1.0
    figures = DemoFigures(
        min_distance_full_push_m=float(push.trace.true_m.min()),
        avoidance_near_edge_m=law.avoidance_start_m,
        push_oscillation_m=float(np.ptp(push.trace.nearest_true_m[last_second])),
        servo_settle_error_m=settle_error,
        servo_settle_time_s=settle_time,
        servo_overshoot_m=overshoot,
        following_error_m=max(each.following_error_m for each in surfaces.values()),
        contour_rms_error_m=max(each.contour_rms_error_m for each in surfaces.values()),
        arm_tracking_error_m=float(tracking.arm_tracking_error_m),
        lamp_illumination_error=float(np.abs(lamp_error[lamp.time_s >= LAMP_SETTLE_S]).max()),
    )
    # seed Fig. 3: arm position on an axis where the environment surface is at about -0.81 m
    wall_depth_m = float(sweep.obstacle.distance_m)
    arm_position_m = SURFACE_Z_M + wall_depth_m - sweep.depth_m(sweep.trace.origin_m.mean(axis=1))
    return ProximityDemoResult(
        seed=int(seed),
        law=law,
        figures=figures,
        push=push,
        servo=servo,
        follows=follows,
        contours=contours,
        surfaces=surfaces,
        sweep=sweep,
        sweep_arm_position_m=arm_position_m,
        surface_position_m=SURFACE_Z_M,
        avoidance_response=law_response(sweep.trace, law, "avoidance"),
        servo_response=law_response(sweep.trace, law, "servo"),
        lamp_time_s=np.asarray(lamp.time_s, dtype=np.float64),
        lamp_error=lamp_error,
        lamp_settle_s=LAMP_SETTLE_S,
        recovery_s=RECOVERY_S,
        filter_delay_s=delay_s,
        arm_path=ARM_PATH,
        additional_task_error_deg=float(tracking.additional_task_error_deg),
    )


# ------------------------------------------------------------------------------------------ acceptance

PUSH_MARGIN_M = 0.010  # issue 4: the full push stays beyond region C's near edge minus 10 mm
ACCEPTANCE_LIMITS: Mapping[str, tuple[str, float]] = {
    "servo_settle_error_m": ("<=", 0.005),
    "servo_settle_time_s": ("<=", 2.0),
    "servo_overshoot_m": ("<=", 0.010),
    "following_error_m": ("<=", 0.015),
    "contour_rms_error_m": ("<=", 0.005),
    "arm_tracking_error_m": ("<=", 0.001),
    "lamp_illumination_error": ("<=", 0.01),
}
"""Issue 4's fixed limits; ``min_distance_full_push_m``'s depends on the law (:func:`acceptance`)."""


@dataclass(frozen=True)
class Check:
    """One acceptance figure against its limit: ``value relation limit`` holds when `passed`."""

    figure: str
    value: float
    relation: str
    limit: float
    passed: bool


def acceptance(figures: DemoFigures) -> tuple[Check, ...]:
    """Issue 4's acceptance checks on the demo's figures, in the figures' order.

    The full push must stay beyond region C's near edge minus :data:`PUSH_MARGIN_M`; the others are
    :data:`ACCEPTANCE_LIMITS`. A NaN figure fails.
    """
    limits = {
        "min_distance_full_push_m": (">=", figures.avoidance_near_edge_m - PUSH_MARGIN_M),
        **ACCEPTANCE_LIMITS,
    }
    checks = []
    for name, value in figures.to_dict().items():
        if name in limits:
            relation, limit = limits[name]
            passed = value >= limit if relation == ">=" else value <= limit
            checks.append(Check(name, value, relation, limit, bool(passed)))
    return tuple(checks)


__all__: list[str] = [
    "ACCEPTANCE_LIMITS",
    "DEMO_LAW",
    "Check",
    "ContourScan",
    "DemoFigures",
    "LawResponse",
    "LoopTrace",
    "ProximityDemoResult",
    "Scenario",
    "SurfaceFigures",
    "acceptance",
    "contour_scan",
    "follow_surface",
    "following_error_m",
    "full_push",
    "law_response",
    "reading_sweep",
    "reconstruct_contour",
    "run_closed_loop",
    "servo_approach",
    "settle_figures",
    "simulate_proximity_demo",
]
