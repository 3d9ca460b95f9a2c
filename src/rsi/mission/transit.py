"""Seed §3.1 in the mission: the arm and rail carry the ISEE between vista points, the proximity law
guarding every approach.

A **transit** (:func:`transit`) takes the ISEE from wherever the arm holds it to a vista's viewing pose
(:mod:`rsi.mission.viewing`: the left ISEE camera at the vista's position, looking along its forward with
its up; 0.5 m standoff):

1. *retract* along the tool axis, away from the structure;
2. *transfer*: a straight line (rail and joints) to a point on the viewing axis ``APPROACH_START_M`` short of
   the pose, turning to the viewing orientation on the way;
3. *approach* along the viewing axis: the trajectory generator's feed-forward plus the proximity law in
   servo mode on the IR rangefinders (seed §3.1, Fig. 4), the law's standoff being the range the
   rangefinders will read at the pose (the mock-up's model, ray-cast); its avoidance part stops the arm short
   of any surface nearer than that, whatever the generator commands (region C's non-override property).

During 1 and 2 the law's avoidance part (nearer reading) is added along the tool axis as a guard. All three
run on the one 44 Hz loop of :mod:`rsi.sim.proximity_loop` (the proximity demo's loop), the generator's
twist as its free motion. Every sample is traced: rangefinders (true and filtered), the generator's and the
law's speeds along the axis, their sum, and the arm's clearance from the mock-up (``mj_geomDistance``).

:class:`rsi.mission.tour.Tour` makes a mission's visits for :func:`rsi.mission.run_mission`: the arm's
transits, the frames from the ISEE, and the lamp on the orbit's sun (:mod:`rsi.mission.sun`). See
docs/mission.md.
"""

from __future__ import annotations

import math
import time
from collections import deque
from dataclasses import dataclass, replace
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from rsi import _validate as v
from rsi.constants import PROXIMITY_SAMPLE_RATE_HZ
from rsi.control.proximity_law import ProximityLaw
from rsi.control.redundancy import orientation_error
from rsi.errors import InputError
from rsi.mission.viewing import Reach, ViewingPose, expected_ranges_m, reach, viewing_pose, world_arm
from rsi.sim.arm import RANGEFINDER_CUTOFF_M
from rsi.sim.clearance import ArmClearance
from rsi.sim.mockup import VISTA_STANDOFF_M
from rsi.sim.proximity_loop import ARM_LAW, LoopSample, LoopTrace, ProximityLoop

if TYPE_CHECKING:
    from rsi.sim.world import World

FloatArray = NDArray[np.float64]

RETRACT_M = 0.15
APPROACH_START_M = 0.2  # the rangefinders (0.75 m) still see a surface 0.5 m off from this far back
TRANSFER_SPEED_M_S = 0.25  # the rail's rate limit: a transfer along the truss is the rail's move
TRANSFER_TURN_RAD_S = 0.5
MOVE_GAIN_PER_S = 8.0  # position loops on exact (kinematic) joints: gain * period 0.18, far from 1
APPROACH_GAIN_PER_S = 4.0  # with the law's 6 /s slope: 10 /s, under the 0.5 * 44 /s bound of a 44 Hz loop
MOVE_TOLERANCE_M = 2e-3  # retract and transfer end here; the approach corrects what is left
MOVE_TOLERANCE_RAD = 5e-3
SETTLE_BAND_M = 2e-3
SETTLE_SAMPLES = 11  # a quarter second at 44 Hz
# A move that gains less than this in SETTLE_SAMPLES (2 mm/s, against the 8 /s loop's 16 mm/s at 2 mm off) is
# held: the guard law's avoidance stops the transfer short of a staging point inside its range (the CAD
# plan's 0.2-0.35 m standoffs, 14 mm short, measured on truss-b), and the approach closes the rest along
# the axis. Waiting out PHASE_TIMEOUT_S there took 12 s of every such visit.
STALL_M = 5e-4
SERVO_AGREEMENT_M = 5e-3  # rays this close: the blend's mean (servo) and nearer (avoidance) agree
PHASE_TIMEOUT_S = 12.0  # 1.8 m of rail travel takes 7.2 s
APPROACH_TIMEOUT_S = 6.0
ARRIVAL_TOLERANCE_M = 5e-3  # the servo holds the rangefinders' noise (1.4 mm at 0.5 m): well inside this
ARRIVAL_TOLERANCE_RAD = 2e-3
PHASES = ("retract", "transfer", "approach")
# Approach law: the speeds and region E of the law tuned on the arm (rsi.sim.proximity_loop.ARM_LAW), with
# its 6 /s C/D slope, the standoff moved to the range read at the viewing pose.
_HOLD_BELOW_STANDOFF_M = 0.05
_HOLD_BELOW_NEAREST_M = 0.02
_MIN_SEGMENT_M = 0.015  # keeps every slope of the law under 0.5 * 44 /s
_SENSOR_MIN_M = ProximityLaw().min_distance_m  # seed §3.1: the SA1D's minimum distance (region A|B)


# ------------------------------------------------------------------------------------- proximity law


def approach_law(standoff_m: float, nearest_m: float | None = None) -> ProximityLaw:
    """The proximity law of an approach (seed §3.1, Fig. 5) whose servo holds `standoff_m`.

    The demo's speeds, with the hold distance (C|D) 5 cm short of the standoff (or 2 cm short of the
    nearer sensor's expected range, whichever is nearer) and C/D's slope set so the law crosses zero at the
    standoff. Raises InputError when the standoff leaves no room for the law inside the sensors' 0.75 m.
    """
    # a standoff beyond the sensors' cutoff is never sensed (and 1e300 - 5 cm is 1e300: no region D at all)
    standoff = v.in_range(standoff_m, "standoff_m", low=0.0, high=RANGEFINDER_CUTOFF_M, low_inclusive=False)
    nearest = standoff if nearest_m is None else v.finite_number(nearest_m, "nearest_m")
    hold = min(standoff - _HOLD_BELOW_STANDOFF_M, nearest - _HOLD_BELOW_NEAREST_M)
    span = standoff - hold  # region D from the hold distance to the standoff
    slope = ARM_LAW.joystick_speed_m_s / span
    avoidance_start = hold - (ARM_LAW.avoidance_speed_m_s - ARM_LAW.joystick_speed_m_s) / slope
    peak = hold + (ARM_LAW.joystick_speed_m_s + ARM_LAW.servo_peak_speed_m_s) / slope
    servo_end = ARM_LAW.servo_end_m
    cramped = avoidance_start < _SENSOR_MIN_M + _MIN_SEGMENT_M or peak > servo_end - _MIN_SEGMENT_M
    if span < _MIN_SEGMENT_M or cramped:
        raise InputError(
            f"standoff_m={standoff!r} (nearest_m={nearest!r}) leaves no room for the approach law between "
            f"the sensors' {_SENSOR_MIN_M} m and {servo_end} m; approach to a standoff of 0.25-0.67 m."
        )
    return ProximityLaw(
        joystick_speed_m_s=ARM_LAW.joystick_speed_m_s,
        retreat_speed_m_s=ARM_LAW.retreat_speed_m_s,
        avoidance_speed_m_s=ARM_LAW.avoidance_speed_m_s,
        servo_peak_speed_m_s=ARM_LAW.servo_peak_speed_m_s,
        avoidance_start_m=avoidance_start,
        hold_distance_m=hold,
        servo_end_m=servo_end,
        max_distance_m=RANGEFINDER_CUTOFF_M,
        sample_rate_hz=PROXIMITY_SAMPLE_RATE_HZ,
    )


GUARD_LAW = approach_law(VISTA_STANDOFF_M)  # avoidance during retract and transfer


# ------------------------------------------------------------------------------------------ transit


@dataclass(frozen=True, eq=False)
class Transit:
    """One move of the ISEE to a vista's viewing pose, sampled by the 44 Hz loop (seed §3.1).

    Attributes
    ----------
    vista, label, stage : str
        The vista, the plan point it serves and the pass (``"reference"``/``"inspection"``, or ``""``).
    reach : Reach
    reached : bool
        The camera ended within ``ARRIVAL_TOLERANCE_M`` / ``_RAD`` of the planned pose. False with an empty
        trace when the pose is out of reach (nothing moved).
    servo : bool
        The approach servoed on the rangefinders (both expected in the law's range); otherwise the generator
        alone drove it, the law's avoidance part still guarding.
    start_clock_s, duration_s, wall_s : float
        Mission clock at the start, simulated duration, and the wall time it took.
    time_s : ndarray of shape (T,)
        From the transit's start.
    phase : ndarray of shape (T,), str
        ``"retract"``, ``"transfer"`` or ``"approach"``.
    range_true_m, range_reading_m : ndarray of shape (T, 2)
        Left and right rangefinders: MuJoCo's true range from the sensor faces and the filtered reading of
        the sensor model (``inf``: no return).
    trajectory_m_s, proximity_m_s, command_m_s : ndarray of shape (T,)
        Along the tool axis, positive toward the surface: the generator's speed, the law's term and their
        sum, commanded (Fig. 4's ``x_tg``, ``x_ps`` and the blend).
    axis_error_m : ndarray of shape (T,)
        Approach: distance still to go along the viewing axis (negative: past the pose); nan elsewhere.
    clearance_m : ndarray of shape (T,)
        Smallest distance between any arm geom and the mock-up, capped at ``CLEARANCE_CAP_M``.
    approach_law : ProximityLaw or None
        The approach's law (None when out of reach); :data:`GUARD_LAW` guards the other phases.
    expected_range_m : ndarray of shape (2,)
        What the rangefinders should read at the pose (the approach law's standoff is their mean).
    pose : ViewingPose or None
        The planned pose (the vista plus this visit's repeatability offset).
    camera_m, camera_rotation : ndarray
        Where the camera ended (position; columns right, up, backward).
    """

    vista: str
    label: str
    stage: str
    reach: Reach
    reached: bool
    servo: bool
    start_clock_s: float
    duration_s: float
    wall_s: float
    time_s: FloatArray
    phase: NDArray[np.str_]
    range_true_m: FloatArray
    range_reading_m: FloatArray
    trajectory_m_s: FloatArray
    proximity_m_s: FloatArray
    command_m_s: FloatArray
    axis_error_m: FloatArray
    clearance_m: FloatArray
    approach_law: ProximityLaw | None
    expected_range_m: FloatArray
    pose: ViewingPose | None
    camera_m: FloatArray
    camera_rotation: FloatArray

    @property
    def name(self) -> str:
        """Which pass and plan point the transit went to, e.g. ``"inspection B_tank"``."""
        return f"{self.stage} {self.label}"

    @property
    def distances_m(self) -> FloatArray:
        """The rangefinders' readings (T, 2), left and right: what the report's proximity trace draws."""
        return self.range_reading_m

    @property
    def min_clearance_m(self) -> float:
        """Smallest clearance over the transit (``inf`` without a trace)."""
        return float(self.clearance_m.min()) if self.clearance_m.size else math.inf

    @property
    def min_range_m(self) -> float:
        """Nearest true rangefinder range over the transit (``inf`` without a trace or a return)."""
        return float(self.range_true_m.min()) if self.range_true_m.size else math.inf

    @property
    def position_error_m(self) -> float:
        """Camera position against the planned pose (nan when out of reach)."""
        if self.pose is None:
            return math.nan
        return float(np.linalg.norm(self.camera_m - self.pose.camera_m))

    @property
    def orientation_error_rad(self) -> float:
        """Camera orientation against the planned pose (nan when out of reach)."""
        if self.pose is None:
            return math.nan
        return float(np.linalg.norm(orientation_error(self.pose.camera_rotation, self.camera_rotation)))


_LOOP_COLUMNS = {
    "time_s": "time_s",
    "range_true_m": "true_m",
    "range_reading_m": "reading_m",
    "trajectory_m_s": "trajectory_m_s",
    "proximity_m_s": "proximity_m_s",
    "command_m_s": "command_m_s",
}
"""Transit trace column -> the :class:`LoopTrace` column it is."""


class _Mover:
    """The phases of one transit on the proximity loop (seed §3.1, Fig. 4), traced with the clearance."""

    def __init__(self, world: World, rng: np.random.Generator) -> None:
        self.arm = world_arm(world)
        self.loop = ProximityLoop(self.arm, law=GUARD_LAW, rng=rng)
        self.clearance = ArmClearance(world)
        self.samples: list[LoopSample] = []
        self.phases: list[str] = []
        self.axis_errors_m: list[float] = []
        self.clearances_m: list[float] = []

    def step(
        self, phase: str, twist: tuple[FloatArray, FloatArray], *, axis_error_m: float = math.nan
    ) -> None:
        """One period: the generator's world twist is the loop's free motion; its part along the tool axis
        is Fig. 4's ``x_tg``, to which the law's ``x_ps`` is added (seed §3.1)."""
        self.clearances_m.append(self.clearance())  # where the arm is while the sensors are read
        self.samples.append(self.loop.step(np.concatenate(twist), frame="world"))
        self.phases.append(phase)
        self.axis_errors_m.append(axis_error_m)

    def trace(self) -> dict[str, Any]:
        """The :class:`Transit` columns: the loop's samples stacked by :class:`LoopTrace` (one stacking for
        the demo and the transits), then the transit's own phase, axis error and clearance."""
        if self.samples:
            loop = LoopTrace.from_samples(self.samples)
            stacked = {name: getattr(loop, column) for name, column in _LOOP_COLUMNS.items()}
        else:  # out of reach: nothing moved
            stacked = {name: np.empty((0, 2) if name.startswith("range_") else 0) for name in _LOOP_COLUMNS}
        return stacked | {
            "phase": np.asarray(self.phases, dtype=np.str_),
            "axis_error_m": np.asarray(self.axis_errors_m, dtype=np.float64),
            "clearance_m": np.asarray(self.clearances_m, dtype=np.float64),
        }

    def move_to(self, phase: str, tip_m: FloatArray, rotation: FloatArray) -> bool:
        """Straight line and turn to a tool pose at capped speeds, the guard law on; True when there, False
        when the guard holds the arm off it (:data:`STALL_M`) or the phase times out."""
        self.loop.law, self.loop.mode = GUARD_LAW, "avoidance"
        recent: deque[float] = deque(maxlen=SETTLE_SAMPLES)
        for _ in range(round(PHASE_TIMEOUT_S * PROXIMITY_SAMPLE_RATE_HZ)):
            position, current = self.arm.tool_pose()
            error, turn = tip_m - position, orientation_error(rotation, current)
            distance, turned = float(np.linalg.norm(error)), float(np.linalg.norm(turn))
            if distance < MOVE_TOLERANCE_M and turned < MOVE_TOLERANCE_RAD:
                return True
            recent.append(distance)
            if (
                turned < MOVE_TOLERANCE_RAD
                and len(recent) == recent.maxlen
                and recent[0] - distance < STALL_M
            ):
                return False
            twist = (
                _capped(MOVE_GAIN_PER_S * error, TRANSFER_SPEED_M_S),
                _capped(MOVE_GAIN_PER_S * turn, TRANSFER_TURN_RAD_S),
            )
            self.step(phase, twist)
        return False

    def visit(self, pose: ViewingPose, law: ProximityLaw, mode: str) -> None:
        """The three phases: retract along the tool axis, transfer to the approach start, approach."""
        tip, rotation = self.arm.tool_pose()
        self.move_to("retract", tip - RETRACT_M * rotation[:, 2], rotation)
        staging = pose.tool_m - APPROACH_START_M * pose.tool_rotation[:, 2]
        self.move_to("transfer", staging, pose.tool_rotation)
        self.approach(pose, law, mode)

    def approach(self, pose: ViewingPose, law: ProximityLaw, mode: str) -> None:
        """Along the viewing axis: feed-forward plus the law on the rangefinders, until settled."""
        self.loop.law, self.loop.mode = law, mode
        axis = pose.tool_rotation[:, 2]
        limit = law.joystick_speed_m_s
        settled = 0
        for _ in range(round(APPROACH_TIMEOUT_S * PROXIMITY_SAMPLE_RATE_HZ)):
            position, current = self.arm.tool_pose()
            error = pose.tool_m - position
            to_go = float(axis @ error)
            lateral = error - to_go * axis
            # Fig. 4's trajectory term: within +-Vjs, so region C still wins (non-override, seed §3.1)
            feed = float(np.clip(APPROACH_GAIN_PER_S * to_go, -limit, limit))
            turn = orientation_error(pose.tool_rotation, current)
            twist = (
                MOVE_GAIN_PER_S * lateral + feed * axis,
                _capped(MOVE_GAIN_PER_S * turn, TRANSFER_TURN_RAD_S),
            )
            self.step("approach", twist, axis_error_m=to_go)
            calm = abs(to_go) < SETTLE_BAND_M and float(np.linalg.norm(lateral)) < SETTLE_BAND_M
            settled = settled + 1 if calm else 0
            if settled >= SETTLE_SAMPLES:
                return


def _capped(vector: FloatArray, limit: float) -> FloatArray:
    norm = float(np.linalg.norm(vector))
    result: FloatArray = vector if norm <= limit else vector * (limit / norm)
    return result


def _law_for(expected_m: FloatArray) -> tuple[ProximityLaw, bool]:
    """The approach law and whether it servos on the rangefinders.

    The blend avoids on the nearer reading and servos on the mean (rsi.control.blending), so a law can
    hold the pose only where both rays expect the same range. Where they differ (a tube before a plate),
    the law's zero goes 5 mm short of the nearer expected range and only its avoidance part acts, the
    feed-forward placing the arm; with no expected return the guard law does that.
    """
    finite = expected_m[np.isfinite(expected_m)]
    try:
        if finite.size == 2 and float(np.ptp(finite)) <= SERVO_AGREEMENT_M:
            return approach_law(float(finite.mean()), float(finite.min())), True
        if finite.size:
            return approach_law(float(finite.min()) - SERVO_AGREEMENT_M), False
    except InputError:
        pass
    return GUARD_LAW, False


def transit(
    world: World,
    vista: str,
    *,
    offset_m: tuple[float, float] = (0.0, 0.0),
    rng: np.random.Generator | int | None = None,
    label: str = "",
    stage: str = "",
    clock_s: float = 0.0,
    law: ProximityLaw | None = None,
) -> Transit:
    """Move the ISEE from where the arm holds it to `vista`'s viewing pose (see the module notes).

    Parameters
    ----------
    world : World
        From ``rsi.sim.load(..., arm=True)``; its arm moves (kinematic mode), nothing else changes.
    vista : str
        One of ``world.vistas``.
    offset_m : (float, float)
        Lateral offset of the planned camera position (image right, up), metres: a visit's repeatability.
    rng : numpy.random.Generator or int or None
        The rangefinders' noise.
    label, stage : str
        Recorded as given (the plan point and the pass).
    clock_s : float
        Mission clock at the start, >= 0 s.
    law : ProximityLaw, optional
        The approach's law, servoing on the rangefinders. Default: :func:`approach_law` at the ranges the
        mock-up's model says the rangefinders will read at the pose (servo only where both agree). A law
        whose standoff is farther than the surface really is makes the arm stop short (seed §3.1, C).

    Returns
    -------
    Transit
        Out of reach: nothing moves, ``reached`` is False and the trace is empty.

    Raises
    ------
    InputError
        A world without the arm, an unknown vista, a bad offset, clock or law.
    """
    start = v.in_range(clock_s, "clock_s", low=0.0)
    if law is not None and not isinstance(law, ProximityLaw):
        raise InputError(
            f"law must be None or a ProximityLaw; got {type(law).__name__}. Try approach_law(0.5)."
        )
    noise = v.as_rng(rng)
    pose = viewing_pose(world, vista, offset_m=offset_m)
    where = reach(world, vista)
    expected = expected_ranges_m(world, pose) if where.reachable else np.full(2, np.inf)
    law, servo = _law_for(expected) if law is None else (law, True)
    mover = _Mover(world, noise)
    began = time.perf_counter()
    if where.reachable:
        mover.visit(pose, law, "servo" if servo else "avoidance")
    camera, camera_rotation = mover.arm.camera_pose("left")
    arrays = mover.trace()
    result = Transit(
        vista=vista,
        label=str(label),
        stage=str(stage),
        reach=where,
        reached=False,
        servo=servo,
        start_clock_s=start,
        duration_s=mover.loop.samples * mover.loop.dt_s,
        wall_s=time.perf_counter() - began,
        approach_law=law if where.reachable else None,
        expected_range_m=expected,
        pose=pose if where.reachable else None,
        camera_m=camera,
        camera_rotation=camera_rotation,
        **arrays,
    )
    arrived = result.position_error_m < ARRIVAL_TOLERANCE_M
    arrived = arrived and result.orientation_error_rad < ARRIVAL_TOLERANCE_RAD
    return replace(result, reached=bool(where.reachable and arrived))


__all__ = [
    "ARRIVAL_TOLERANCE_M",
    "ARRIVAL_TOLERANCE_RAD",
    "GUARD_LAW",
    "Transit",
    "approach_law",
    "transit",
]
