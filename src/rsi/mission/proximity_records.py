"""The proximity demo's result records (seed §3.1, Figs 3, 6, 7; issue 4): frozen, computed elsewhere.

:func:`rsi.mission.proximity_demo.simulate_proximity_demo` fills them; :mod:`rsi.report.isee` draws them.
They hold no algorithm, so the report reads them without reaching the demo's scenarios.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import asdict, dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from rsi.control.proximity_law import ProximityLaw
from rsi.sim.proximity_loop import LoopTrace

FloatArray = NDArray[np.float64]


@dataclass(frozen=True)
class DemoFigures:
    """The acceptance figures of issue 4 (seed §3, §3.1), from
    :func:`rsi.mission.proximity_demo.simulate_proximity_demo`.

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
        From the start until the distance stays within
        ``rsi.mission.proximity_demo.SETTLE_BAND_M`` of the standoff.
    servo_overshoot_m : float
        How far the servo run went past the standoff toward the wall (0 if never).
    following_error_m : float
        Largest |nearest distance - standoff| while the operator moves the tool sideways over the stepped
        and the curved surface, outside the ``RECOVERY_S`` after a step edge enters a sensor's view.
    contour_rms_error_m : float
        RMS error of the surface profile rebuilt from the arm's poses and the filtered readings.
    command_spike_m_s : float
        Largest one-sample spike of the command along the sensor axis over scenarios a-c: a rise followed
        at once by a fall (the smaller of the two), m/s. The Fig. 4 blend is continuous across the
        standoff, so only the readings' noise through the law's slope is left here.
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
    command_spike_m_s: float
    arm_tracking_error_m: float
    lamp_illumination_error: float

    def to_dict(self) -> dict[str, float]:
        """The figures as a JSON-ready mapping (the ``--json`` line of ``rsi isee proximity-demo``)."""
        return {name: float(value) for name, value in asdict(self).items()}


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
        The proximity the law acted on (:func:`rsi.control.blending.law_distance_m`: the nearer reading
        when avoiding, the servo distance when servoing); NaN where no sensor had a return.
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
        The law the loops ran (:data:`rsi.sim.proximity_loop.ARM_LAW`).
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
        Where that axis puts the wall (:data:`rsi.mission.proximity_demo.SURFACE_Z_M`).
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


@dataclass(frozen=True)
class Check:
    """One acceptance figure against its limit: ``value relation limit`` holds when `passed`."""

    figure: str
    value: float
    relation: str
    limit: float
    passed: bool


__all__: list[str] = [
    "Check",
    "ContourScan",
    "DemoFigures",
    "LawResponse",
    "ProximityDemoResult",
    "Scenario",
    "SurfaceFigures",
]
