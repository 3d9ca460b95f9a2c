"""Seed §3.1 and §4.1 in the mission: the arm and rail carry the ISEE between vista points, the proximity
law guarding every approach, and the solar simulator follows the orbit's sun from visit to visit.

A **transit** (:func:`transit`) takes the ISEE from wherever the arm holds it to a vista's viewing pose (the
left ISEE camera at the vista's position, looking along its forward with its up; 0.5 m standoff):

1. *retract* along the tool axis, away from the structure;
2. *transfer*: a straight line (rail and joints) to a point on the viewing axis ``APPROACH_START_M`` short of
   the pose, turning to the viewing orientation on the way;
3. *approach* along the viewing axis: the trajectory generator's feed-forward plus the proximity law in
   servo mode on the IR rangefinders (seed §3.1, Fig. 4), the law's standoff being the range the
   rangefinders will read at the pose (the mock-up's model, ray-cast); its avoidance part stops the arm short
   of any surface nearer than that, whatever the generator commands (region C's non-override property).

During 1 and 2 the law's avoidance part (nearer reading) is added along the tool axis as a guard. Every
sample of the 44 Hz loop is traced: rangefinders (true and filtered), the generator's and the law's speeds
along the axis, their sum, and the arm's clearance from the mock-up (MuJoCo's ``mj_geomDistance``).

The solar simulator (:func:`sun_setting`, :func:`light_by_sun`) is put, at a visit's mission-clock time,
where the orbit's sun direction says (seed §4.1): lit from the sun's direction onto the vista's target, or
the nearest direction its rail can give (recorded), and off in the Earth's shadow.

:class:`Tour` drives both for :func:`rsi.mission.run_mission`. See docs/mission.md.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field, replace
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from rsi import _validate as v
from rsi.control.blending import blend_commands
from rsi.control.proximity_law import ProximityLaw
from rsi.control.redundancy import orientation_error
from rsi.errors import InputError
from rsi.sim import orbit as orbits
from rsi.sim.arm import FOREARM_M, LIMITS, RANGEFINDER_CUTOFF_M, UPPER_ARM_M
from rsi.sim.mockup import VISTA_STANDOFF_M
from rsi.sim.render import import_mujoco
from rsi.sim.scene import CAMERA_FOVY_DEG
from rsi.sim.solar_simulator import LampConfiguration, LampMount, RateLimits, lamp_pose

if TYPE_CHECKING:
    from rsi.sim.arm import Arm
    from rsi.sim.mockup import Vista
    from rsi.sim.world import View, World

FloatArray = NDArray[np.float64]

LOOP_RATE_HZ = 44.0  # seed §3.1: the proximity loop's rate
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
SERVO_AGREEMENT_M = 5e-3  # rays this close: the blend's mean (servo) and nearer (avoidance) agree
PHASE_TIMEOUT_S = 12.0  # 1.8 m of rail travel takes 7.2 s
APPROACH_TIMEOUT_S = 6.0
ARRIVAL_TOLERANCE_M = 5e-3  # the servo holds the rangefinders' noise (1.4 mm at 0.5 m): well inside this
ARRIVAL_TOLERANCE_RAD = 2e-3
REACH_MARGIN_M = 0.02  # the elbow never fully straight: configuration control damps near that singularity
CLEARANCE_CAP_M = 2.0
FRAME_S = 1.0 / 30.0  # seed §2.2: one interlaced frame
NOMINAL_TRANSIT_S = 5.0  # mission-clock time of a visit without the arm (measured arm transits: 2-7 s)
SUN_DIRECTION_TOLERANCE_RAD = 1e-6  # "reachable": the lamp gives the sun's direction exactly
PHASES = ("retract", "transfer", "approach")
STAGES = ("reference", "inspection")
# Approach law: the demo's speeds and 6 /s avoidance slope (rsi.sim.isee_demo.DEMO_LAW, tuned on the arm)
# with the standoff moved to the range read at the viewing pose.
_LAW_SPEEDS = {"joystick": 0.30, "retreat": 0.80, "avoidance": 0.60, "servo_peak": 0.24}
_HOLD_BELOW_STANDOFF_M = 0.05
_HOLD_BELOW_NEAREST_M = 0.02
_SERVO_END_M = 0.73
_MIN_SEGMENT_M = 0.015  # keeps every slope of the law under 0.5 * 44 /s
_SENSOR_MIN_M = ProximityLaw().min_distance_m  # seed §3.1: the SA1D's minimum distance (region A|B)


def _unit(vector: FloatArray) -> FloatArray:
    result: FloatArray = vector / np.linalg.norm(vector)
    return result


def _camera_rotation(forward: FloatArray, up: FloatArray) -> FloatArray:
    """Columns right, up, backward, as :class:`rsi.sim.render.CameraPose` (MuJoCo cameras look along -z)."""
    back = -_unit(forward)
    right = _unit(np.cross(up, back))
    return np.column_stack([right, np.cross(back, right), back])


def _focal_px(rows: int) -> float:
    return rows / 2 / math.tan(math.radians(CAMERA_FOVY_DEG) / 2)


def _arm_of(world: World) -> Arm:
    try:
        return world.arm
    except InputError:
        raise InputError(
            "world has no arm; build it with rsi.sim.load('truss', seed=..., arm=True) to move the ISEE."
        ) from None


def _vista_of(world: World, vista: object) -> Vista:
    if not isinstance(vista, str) or vista not in world.vistas:
        raise InputError(
            f"vista must be one of this world's vistas {sorted(world.vistas)}; got {vista!r}. A mission's "
            "extra views are added by rsi.mission.plan_vistas(world)."
        )
    return world.vista(vista)


# ----------------------------------------------------------------------------------------- the ISEE


@dataclass(frozen=True)
class _Isee:
    """The ISEE's fixed geometry in the tool frame, read from the model (no numbers copied)."""

    camera_m: FloatArray  # left camera, tool frame
    camera_rotation: FloatArray  # tool_R.T @ camera_R
    wrist_m: FloatArray  # wrist site (on the w2 axis), tool frame
    sensors_m: FloatArray  # (2, 3) rangefinder sites, tool frame
    sensor_body: int  # the body a rangefinder ignores
    shoulder_at_rail_zero_m: FloatArray


def _isee(world: World) -> _Isee:
    arm = _arm_of(world)
    tip, rotation = arm.tool_pose()
    camera, camera_rotation = arm.camera_pose("left")
    sensors = np.array([arm.site_position_m(name) for name in ("range_left", "range_right")])
    site = world.model.site(f"{arm.prefix}range_left").id
    rail_m = float(arm.joint_positions[0])
    return _Isee(
        camera_m=rotation.T @ (camera - tip),
        camera_rotation=rotation.T @ camera_rotation,
        wrist_m=rotation.T @ (arm.site_position_m("wrist") - tip),
        sensors_m=(sensors - tip) @ rotation,
        sensor_body=int(world.model.site_bodyid[site]),
        shoulder_at_rail_zero_m=arm.site_position_m("shoulder") - rail_m * np.array([1.0, 0.0, 0.0]),
    )


@dataclass(frozen=True)
class ViewingPose:
    """Where the ISEE must be to take a vista's frame.

    Attributes
    ----------
    vista : str
    camera_m : ndarray of shape (3,)
        Left ISEE camera (the frame's camera), world metres: the vista's position plus the visit's offset.
    camera_rotation : ndarray of shape (3, 3)
        Columns image right, image up, backward (the vista's forward and up).
    tool_m : ndarray of shape (3,)
        Tool tip (jaw tips) at that pose.
    tool_rotation : ndarray of shape (3, 3)
        Tool frame (z along the viewing axis).
    offset_m : (float, float)
        Lateral offset from the vista's position along image right and up, metres.
    """

    vista: str
    camera_m: FloatArray
    camera_rotation: FloatArray
    tool_m: FloatArray
    tool_rotation: FloatArray
    offset_m: tuple[float, float]


def viewing_pose(world: World, vista: str, *, offset_m: tuple[float, float] = (0.0, 0.0)) -> ViewingPose:
    """The tool pose that puts the left ISEE camera on `vista`'s viewpoint, shifted by `offset_m`.

    Raises InputError for a world without the arm, an unknown vista or a non-finite offset.
    """
    point = _vista_of(world, vista)
    isee = _isee(world)
    offset = np.asarray(offset_m, dtype=np.float64)
    if offset.shape != (2,) or not np.isfinite(offset).all():
        raise InputError(f"offset_m must be two finite numbers (right, up; metres); got {offset_m!r}.")
    rotation = _camera_rotation(np.asarray(point.forward, float), np.asarray(point.up, float))
    camera = np.asarray(point.position_m, float) + rotation[:, :2] @ offset
    tool_rotation = rotation @ isee.camera_rotation.T
    return ViewingPose(
        vista=vista,
        camera_m=camera,
        camera_rotation=rotation,
        tool_m=camera - tool_rotation @ isee.camera_m,
        tool_rotation=tool_rotation,
        offset_m=(float(offset[0]), float(offset[1])),
    )


# ------------------------------------------------------------------------------------------- reach


@dataclass(frozen=True)
class Reach:
    """Whether the arm on its rail can put the ISEE at a vista's viewing pose (geometry of the chain).

    Attributes
    ----------
    vista : str
    reachable : bool
        The wrist's goal lies within the arm's reach from some rail position (less ``REACH_MARGIN_M``).
    shortfall_m : float
        Distance from the wrist's goal to the nearest reachable point, metres (negative: inside by that).
    rail_m : float
        Rail position (joint value) from which the shoulder is nearest the wrist's goal.
    """

    vista: str
    reachable: bool
    shortfall_m: float
    rail_m: float


def reach(world: World, vista: str) -> Reach:
    """Can the arm reach `vista`'s viewing pose? Shoulder-to-wrist distance against the two links.

    The wrist site lies on the w2 pitch axis, fixed in the tool frame, so the goal fixes it; the shoulder
    rides the rail along world x. Raises InputError for a world without the arm or an unknown vista.
    """
    pose = viewing_pose(world, vista)
    isee = _isee(world)
    wrist = pose.tool_m + pose.tool_rotation @ isee.wrist_m
    low, high = float(LIMITS.lower[0]), float(LIMITS.upper[0])
    rail = float(np.clip(wrist[0] - isee.shoulder_at_rail_zero_m[0], low, high))
    shoulder = isee.shoulder_at_rail_zero_m + rail * np.array([1.0, 0.0, 0.0])
    shortfall = float(np.linalg.norm(wrist - shoulder)) - (UPPER_ARM_M + FOREARM_M - REACH_MARGIN_M)
    return Reach(vista=vista, reachable=shortfall <= 0.0, shortfall_m=shortfall, rail_m=rail)


# ------------------------------------------------------------------------------------- proximity law


def approach_law(standoff_m: float, nearest_m: float | None = None) -> ProximityLaw:
    """The proximity law of an approach (seed §3.1, Fig. 5) whose servo holds `standoff_m`.

    The demo's speeds, with the hold distance (C|D) 5 cm short of the standoff (or 2 cm short of the
    nearer sensor's expected range, whichever is nearer) and C/D's slope set so the law crosses zero at the
    standoff. Raises InputError when the standoff leaves no room for the law inside the sensors' 0.75 m.
    """
    standoff = v.in_range(standoff_m, "standoff_m", low=0.0, low_inclusive=False)
    nearest = standoff if nearest_m is None else v.finite_number(nearest_m, "nearest_m")
    hold = min(standoff - _HOLD_BELOW_STANDOFF_M, nearest - _HOLD_BELOW_NEAREST_M)
    span = standoff - hold  # region D from the hold distance to the standoff
    slope = _LAW_SPEEDS["joystick"] / span
    avoidance_start = hold - (_LAW_SPEEDS["avoidance"] - _LAW_SPEEDS["joystick"]) / slope
    peak = hold + (_LAW_SPEEDS["joystick"] + _LAW_SPEEDS["servo_peak"]) / slope
    cramped = avoidance_start < _SENSOR_MIN_M + _MIN_SEGMENT_M or peak > _SERVO_END_M - _MIN_SEGMENT_M
    if span < _MIN_SEGMENT_M or cramped:
        raise InputError(
            f"standoff_m={standoff!r} (nearest_m={nearest!r}) leaves no room for the approach law between "
            f"the sensors' {_SENSOR_MIN_M} m and {_SERVO_END_M} m; approach to a standoff of 0.25-0.67 m."
        )
    return ProximityLaw(
        joystick_speed_m_s=_LAW_SPEEDS["joystick"],
        retreat_speed_m_s=_LAW_SPEEDS["retreat"],
        avoidance_speed_m_s=_LAW_SPEEDS["avoidance"],
        servo_peak_speed_m_s=_LAW_SPEEDS["servo_peak"],
        avoidance_start_m=avoidance_start,
        hold_distance_m=hold,
        servo_end_m=_SERVO_END_M,
        max_distance_m=RANGEFINDER_CUTOFF_M,
        sample_rate_hz=LOOP_RATE_HZ,
    )


GUARD_LAW = approach_law(VISTA_STANDOFF_M)  # avoidance during retract and transfer


def expected_ranges_m(world: World, pose: ViewingPose) -> FloatArray:
    """What the two rangefinders will read at `pose`, from the mock-up's model (``inf``: no return).

    A ray from each sensor site along the viewing axis, as MuJoCo's rangefinder casts it (its own body
    ignored), passing through any part of the arm where the arm is now.
    """
    isee = _isee(world)
    prefix = _arm_of(world).prefix
    mujoco = import_mujoco()
    axis = pose.tool_rotation[:, 2].copy()
    ranges = np.full(2, np.inf)
    for index, site in enumerate(isee.sensors_m):
        origin = pose.tool_m + pose.tool_rotation @ site
        travelled, geom = 0.0, np.zeros(1, dtype=np.int32)
        for _ in range(8):
            hit = mujoco.mj_ray(world.model, world.data, origin, axis, None, 1, isee.sensor_body, geom)
            if hit < 0:
                break
            travelled += hit
            if not _in_arm(world.model, int(geom[0]), prefix):
                ranges[index] = travelled if travelled < RANGEFINDER_CUTOFF_M else np.inf
                break
            # an arm part where the arm is now, not where it will be: look past it
            origin, travelled = origin + (hit + 1e-6) * axis, travelled + 1e-6
    return ranges


# --------------------------------------------------------------------------------------- clearance


class _Clearance:
    """Smallest distance between the arm's geoms and everything else (MuJoCo's ``mj_geomDistance``).

    Branch and bound on bounding spheres: pairs are measured nearest bound first until the next bound is
    farther than the best distance found, so a step costs a few exact distances, not all ~2000.
    """

    def __init__(self, world: World) -> None:
        model = world.model
        prefix = _arm_of(world).prefix
        arm = [g for g in range(model.ngeom) if _in_arm(model, g, prefix)]
        self._world = world
        self._mujoco = import_mujoco()
        self._arm = np.array(arm)
        self._other = np.array([g for g in range(model.ngeom) if g not in set(arm)])
        self._radius = np.asarray(model.geom_rbound, dtype=np.float64)

    def __call__(self) -> float:
        world = self._world
        centres = np.asarray(world.data.geom_xpos)
        gap = np.linalg.norm(centres[self._arm][:, None, :] - centres[self._other][None, :, :], axis=-1)
        bound = gap - self._radius[self._arm][:, None] - self._radius[self._other][None, :]
        best = CLEARANCE_CAP_M
        for flat in np.argsort(bound, axis=None):
            if bound.flat[flat] >= best:
                break
            i, j = divmod(int(flat), self._other.size)
            distance = self._mujoco.mj_geomDistance(
                world.model, world.data, int(self._arm[i]), int(self._other[j]), best, None
            )
            best = min(best, float(distance))
        return best


def _in_arm(model: Any, geom: int, prefix: str) -> bool:
    body = str(model.body(int(model.geom_bodyid[geom])).name)
    return body.startswith(prefix) or str(model.geom(geom).name).startswith(prefix)


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


_TRACE_FIELDS = (
    "time_s",
    "phase",
    "range_true_m",
    "range_reading_m",
    "trajectory_m_s",
    "proximity_m_s",
    "command_m_s",
    "axis_error_m",
    "clearance_m",
)


@dataclass
class _Trace:
    rows: dict[str, list[Any]] = field(default_factory=lambda: {name: [] for name in _TRACE_FIELDS})


class _Loop:
    """The 44 Hz loop of one transit: sensors, blend, arm step and trace (seed §3.1, Fig. 4)."""

    def __init__(self, world: World, rng: np.random.Generator) -> None:
        from rsi.sensors.proximity import ProximityChannel, ProximitySensor

        self.world = world
        self.arm = _arm_of(world)
        sensor = ProximitySensor(sample_rate_hz=LOOP_RATE_HZ)
        self.channels = [ProximityChannel(sensor, rng=stream) for stream in rng.spawn(2)]
        self.clearance = _Clearance(world)
        self.trace = _Trace()
        self.dt_s = 1.0 / LOOP_RATE_HZ

    @property
    def samples(self) -> int:
        return len(self.trace.rows["time_s"])

    def step(
        self,
        phase: str,
        twist: tuple[FloatArray, FloatArray],
        *,
        law: ProximityLaw,
        mode: str,
        axis_error_m: float = math.nan,
    ) -> float:
        """One period: read, blend along the tool axis, step the arm; returns the axis command.

        `twist` is the generator's (linear m/s, angular rad/s) in the world; its component along the tool
        axis is Fig. 4's ``x_tg``, to which the law's ``x_ps`` is added (seed §3.1).
        """
        linear_m_s, angular_rad_s = twist
        raw = self.arm.rangefinder_distances_m()
        # MuJoCo's rangefinder: negative = no return, clamped at its cutoff; both mean "nothing seen"
        true = np.where((raw < 0.0) | (raw >= RANGEFINDER_CUTOFF_M), np.inf, raw)
        reading = np.array([c.read(float(d))[0] for c, d in zip(self.channels, true, strict=True)])
        axis = self.arm.tool_pose()[1][:, 2]
        along = float(axis @ linear_m_s)
        blended = blend_commands(0.0, along, reading, law, mode=mode)
        command = float(blended.velocity_m_s)
        linear = linear_m_s + (command - along) * axis
        rows = self.trace.rows
        for name, value in zip(
            _TRACE_FIELDS,
            (
                self.samples * self.dt_s,
                phase,
                true,
                reading,
                along,
                float(blended.proximity_m_s),
                command,
                axis_error_m,
                self.clearance(),
            ),
            strict=True,
        ):
            rows[name].append(value)
        self.arm.step_velocity(np.concatenate([linear, angular_rad_s]), self.dt_s)
        return command

    def move_to(self, phase: str, tip_m: FloatArray, rotation: FloatArray) -> bool:
        """Straight line and turn to a tool pose at capped speeds, the guard law on; True when there."""
        for _ in range(round(PHASE_TIMEOUT_S * LOOP_RATE_HZ)):
            position, current = self.arm.tool_pose()
            error, turn = tip_m - position, orientation_error(rotation, current)
            if np.linalg.norm(error) < MOVE_TOLERANCE_M and np.linalg.norm(turn) < MOVE_TOLERANCE_RAD:
                return True
            twist = (
                _capped(MOVE_GAIN_PER_S * error, TRANSFER_SPEED_M_S),
                _capped(MOVE_GAIN_PER_S * turn, TRANSFER_TURN_RAD_S),
            )
            self.step(phase, twist, law=GUARD_LAW, mode="avoidance")
        return False

    def approach(self, pose: ViewingPose, law: ProximityLaw, mode: str) -> None:
        """Along the viewing axis: feed-forward plus the law on the rangefinders, until settled."""
        axis = pose.tool_rotation[:, 2]
        limit = law.joystick_speed_m_s
        settled = 0
        for _ in range(round(APPROACH_TIMEOUT_S * LOOP_RATE_HZ)):
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
            self.step("approach", twist, law=law, mode=mode, axis_error_m=to_go)
            calm = abs(to_go) < SETTLE_BAND_M and float(np.linalg.norm(lateral)) < SETTLE_BAND_M
            settled = settled + 1 if calm else 0
            if settled >= SETTLE_SAMPLES:
                return

    def arrays(self) -> dict[str, Any]:
        rows = self.trace.rows
        arrays: dict[str, Any] = {
            name: np.asarray(rows[name], dtype=np.float64) for name in _TRACE_FIELDS if name != "phase"
        }
        arrays["phase"] = np.asarray(rows["phase"], dtype=np.str_)
        for name in ("range_true_m", "range_reading_m"):
            arrays[name] = arrays[name].reshape(-1, 2)
        return arrays


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
    pose = viewing_pose(world, vista, offset_m=offset_m)
    where = reach(world, vista)
    expected = expected_ranges_m(world, pose) if where.reachable else np.full(2, np.inf)
    law, servo = _law_for(expected) if law is None else (law, True)
    loop = _Loop(world, v.as_rng(rng))
    began = time.perf_counter()
    if where.reachable:
        tip, rotation = loop.arm.tool_pose()
        loop.move_to("retract", tip - RETRACT_M * rotation[:, 2], rotation)
        staging = pose.tool_m - APPROACH_START_M * pose.tool_rotation[:, 2]
        loop.move_to("transfer", staging, pose.tool_rotation)
        loop.approach(pose, law, "servo" if servo else "avoidance")
    camera, camera_rotation = loop.arm.camera_pose("left")
    arrays = loop.arrays()
    result = Transit(
        vista=vista,
        label=str(label),
        stage=str(stage),
        reach=where,
        reached=False,
        servo=servo,
        start_clock_s=start,
        duration_s=loop.samples * loop.dt_s,
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


# ---------------------------------------------------------------------------------------------- sun


def lab_world_from_lvlh(mount: LampMount | None = None) -> FloatArray:
    """Where the station's LVLH axes lie in the lab: :data:`rsi.sim.orbit.DEFAULT_WORLD_FROM_LVLH` turned
    about the rail so the orbit plane passes through the lamp's rail and the ORU faces' mid-line.

    Seed §4.1: the lamp's rail only gives light directions in the plane through the rail and the spot, so a
    beta = 0 sun (in the orbit plane) is reproduced exactly on ORU A's face (y = -0.472 m, z = 1.2 m) and
    within a fraction of a degree on B and D; the panel on top lies in another plane.
    """
    from rsi.sim.mockup import A_FACE_Y_M, BAY_M, TRUSS_Z0_M

    rail = LampMount() if mount is None else mount
    origin = np.asarray(rail.rail_origin_world_m)
    face = np.array([0.0, A_FACE_Y_M, TRUSS_Z0_M + BAY_M / 2])
    toward = origin - face
    tilt = math.atan2(toward[2], -toward[1])  # the rail's elevation seen from the faces (negative: below)
    turn = np.array(
        [[1.0, 0.0, 0.0], [0.0, math.cos(tilt), -math.sin(tilt)], [0.0, math.sin(tilt), math.cos(tilt)]]
    )
    # zenith (-z LVLH) maps to -y by default; turning by -tilt about x brings it onto the rail's direction
    result: FloatArray = turn.T @ orbits.DEFAULT_WORLD_FROM_LVLH
    return result


@dataclass(frozen=True)
class SunSetting:
    """The solar simulator at one visit (seed §4.1).

    Attributes
    ----------
    label, stage : str
        Plan point and pass.
    time_s : float
        Mission clock (orbit time from the orbit's start), seconds.
    orbit_angle_rad : float
        From orbit noon.
    sun_world : (float, float, float)
        Unit vector toward the sun, lab world.
    sunlit : bool
        False in the Earth's shadow: the lamp is off.
    spot_m : (float, float, float)
        The lamp's spot (the vista's target).
    light_world : (float, float, float)
        Unit vector from the spot toward the lamp as set.
    direction_error_rad : float
        Angle between ``light_world`` and ``sun_world``.
    reachable : bool
        ``direction_error_rad <= SUN_DIRECTION_TOLERANCE_RAD``; otherwise the lamp is at the nearest
        direction its rail and joint ranges give.
    lamp : LampConfiguration
    intensity_lux : float
        At the spot centre (0 in shadow).
    focus_clipped : bool
        The focus could not hold the lab's 1.5 % of sunlight at this distance.
    lamp_move_s : float
        Time the lamp needs, at its joint rate limits, from the previous setting (0 for the first).
    """

    label: str
    stage: str
    time_s: float
    orbit_angle_rad: float
    sun_world: tuple[float, float, float]
    sunlit: bool
    spot_m: tuple[float, float, float]
    light_world: tuple[float, float, float]
    direction_error_rad: float
    reachable: bool
    lamp: LampConfiguration
    intensity_lux: float
    focus_clipped: bool
    lamp_move_s: float = 0.0


def _triple(values: FloatArray) -> tuple[float, float, float]:
    return (float(values[0]), float(values[1]), float(values[2]))


def sun_setting(
    spot_world_m: object,
    time_s: float,
    *,
    orbit: orbits.Orbit | None = None,
    world_from_lvlh: object = None,
    label: str = "",
    stage: str = "",
) -> SunSetting:
    """Where the lamp goes to light `spot_world_m` as the orbit's sun does at `time_s` (seed §4.1).

    :func:`rsi.sim.orbit.sun_path` at one instant: the rail position closest in angle to the sun, the head
    pointed at the spot, the focus holding 1.5 % of sunlight. `world_from_lvlh` defaults to
    :func:`lab_world_from_lvlh`. Raises InputError for a bad time (negative, NaN), spot or orbit.
    """
    if isinstance(time_s, bool) or not isinstance(time_s, (int, float, np.floating, np.integer)):
        raise InputError(f"time_s must be a number of seconds >= 0; got {time_s!r}.")
    rotation = lab_world_from_lvlh() if world_from_lvlh is None else world_from_lvlh
    path = orbits.sun_path(
        orbit,
        [float(time_s)],
        spot_world_m=spot_world_m,
        world_from_lvlh=rotation,
        direction_tolerance_rad=SUN_DIRECTION_TOLERANCE_RAD,
    )
    return SunSetting(
        label=str(label),
        stage=str(stage),
        time_s=float(path.time_s[0]),
        orbit_angle_rad=float(path.orbit_angle_rad[0]),
        sun_world=_triple(path.sun_world[0]),
        sunlit=bool(path.sunlit[0]),
        spot_m=_triple(np.asarray(spot_world_m, dtype=np.float64)),
        light_world=_triple(path.light_world[0]),
        direction_error_rad=float(path.direction_error_rad[0]),
        reachable=not bool(path.direction_unreachable[0]),
        lamp=path.trajectory.configuration(0),
        intensity_lux=float(path.intensity_lux[0]),
        focus_clipped=bool(path.focus_clipped[0]),
    )


def light_by_sun(world: World, setting: SunSetting) -> None:
    """Pose the world's lamp as `setting` says and switch it off in the Earth's shadow."""
    if not isinstance(setting, SunSetting):
        raise InputError(f"setting must be a SunSetting from sun_setting(...); got {type(setting).__name__}.")
    world.set_lamp(setting.lamp)
    world.switch_lamp(setting.sunlit)


def lamp_light_direction(world: World, spot_world_m: object) -> FloatArray:
    """Unit vector from a spot toward the world's lamp as it stands (to check a setting independently)."""
    spot = np.asarray(spot_world_m, dtype=np.float64)
    return _unit(np.asarray(lamp_pose(world.lamp).position_world_m) - spot)


def lamp_move_s(
    first: LampConfiguration, second: LampConfiguration, rates: RateLimits | None = None
) -> float:
    """Time the lamp needs between two configurations at its joint rate limits (seed §4.1)."""
    limits = RateLimits() if rates is None else rates
    joints = np.array(
        [[c.theta_rad, c.phi_rad, c.lambda_m, c.gamma_m] for c in (first, second)], dtype=np.float64
    )
    return float(np.max(np.abs(joints[1] - joints[0]) / limits.as_array()))


# --------------------------------------------------------------------------------------------- tour


def pass_starts(start_s: object) -> tuple[float, float]:
    """Validated orbit times at which the reference and the inspection pass begin (two numbers >= 0 s)."""
    if not isinstance(start_s, tuple) or len(start_s) != 2:
        raise InputError(
            f"orbit_start_s must be a (reference, inspection) tuple of times in seconds; got {start_s!r}. "
            "Try orbit_start_s=(400.0, 5953.6): the inspection one orbit after the reference."
        )
    first, second = (v.in_range(value, "orbit_start_s", low=0.0) for value in start_s)
    return (first, second)


class Tour:
    """A mission's visits: the arm's transits, the frames from the ISEE, the lamp on the orbit's sun.

    Parameters
    ----------
    world : World
        The mission's world (with the arm when `arm`).
    seed : int
        Seeds the visits' repeatability draws and the rangefinders' noise (the world's own streams are not
        touched, so ``arm=False, orbit=False`` visits are exactly ``World.render``'s).
    size : (int, int)
        Frame size; the repeatability error is drawn in pixels of it, as ``World.render`` draws it.
    arm : bool
        Move the arm to each reachable vista and take the frame from the ISEE; otherwise (and for vistas out
        of reach) ``World.render`` teleports the free camera.
    orbit : bool
        Light each visit by the orbit's sun at the visit's mission-clock time.
    """

    def __init__(
        self, world: World, *, seed: int, size: tuple[int, int], arm: bool = True, orbit: bool = True
    ) -> None:
        for name, flag in (("arm", arm), ("orbit", orbit)):
            if not isinstance(flag, bool):
                raise InputError(f"{name} must be True or False; got {flag!r}.")
        if arm:
            _arm_of(world)
        self.world = world
        self.size = size
        self.arm = arm
        self.orbit = orbit
        draws, noise = np.random.SeedSequence([int(seed), 21]).spawn(2)
        self._draws = np.random.default_rng(draws)
        self._noise = np.random.default_rng(noise)
        self.clock_s = 0.0
        self.stage = ""
        self.transits: list[Transit] = []
        self.suns: list[SunSetting] = []

    def start_pass(self, stage: str, start_s: float) -> None:
        """Set the mission clock to a pass's start (seed §2.2: the passes may see different suns)."""
        self.stage = v.choice(stage, "stage", STAGES)
        self.clock_s = v.in_range(start_s, "start_s", low=0.0)

    def visit(self, label: str, vista: str, *, state: str, truth: bool = True) -> View:
        """Go to `vista` (plan point `label`), light it, take the frame; the clock advances."""
        from rsi.sim.world import REPEATABILITY_PX

        _vista_of(self.world, vista)
        if not self.arm:
            self.clock_s += NOMINAL_TRANSIT_S if self.orbit else 0.0
            self._light(label, vista)
            self.clock_s += FRAME_S
            return self.world.render(vista, size=self.size, state=state, truth=truth)
        low, high = REPEATABILITY_PX[self.world.repeatability]
        magnitude, angle = self._draws.uniform(low, high), self._draws.uniform(0.0, 2 * math.pi)
        # seed §2.3: the arm misses the vista by its repeatability; World.render's draw, as a goal offset
        offset_px = magnitude * np.array([math.cos(angle), math.sin(angle)])
        offset_m = offset_px * self.world.vista(vista).standoff_m / _focal_px(self.size[0])
        moved = transit(
            self.world,
            vista,
            offset_m=(float(offset_m[0]), float(offset_m[1])),
            rng=self._noise.spawn(1)[0],
            label=label,
            stage=self.stage,
            clock_s=self.clock_s,
        )
        self.transits.append(moved)
        self.clock_s += moved.duration_s if moved.time_s.size else NOMINAL_TRANSIT_S
        self._light(label, vista)
        self.clock_s += FRAME_S
        if not moved.reached:  # documented fallback: the free camera, as without the arm
            return self.world.render(vista, size=self.size, state=state, truth=truth)
        view = self.world.render_from_tool(size=self.size, state=state, truth=truth)
        return replace(view, vista=vista, pose_error_px=self._pose_error_px(vista, moved.camera_m))

    def _pose_error_px(self, vista: str, camera_m: FloatArray) -> tuple[float, float]:
        """Image shift of the target plane caused by the camera's lateral miss, as ``World.render`` gives."""
        point = self.world.vista(vista)
        rotation = _camera_rotation(np.asarray(point.forward, float), np.asarray(point.up, float))
        miss = rotation[:, :2].T @ (camera_m - np.asarray(point.position_m, float))
        shift = miss * _focal_px(self.size[0]) / point.standoff_m
        return (float(-shift[0]), float(shift[1]))

    def _light(self, label: str, vista: str) -> None:
        if not self.orbit:
            return
        target = self.world.vista(vista).target_m
        setting = sun_setting(target, self.clock_s, label=label, stage=self.stage)
        if self.suns:
            setting = replace(setting, lamp_move_s=lamp_move_s(self.suns[-1].lamp, setting.lamp))
        light_by_sun(self.world, setting)
        self.suns.append(setting)


__all__ = [
    "GUARD_LAW",
    "Reach",
    "SunSetting",
    "Tour",
    "Transit",
    "ViewingPose",
    "approach_law",
    "expected_ranges_m",
    "lab_world_from_lvlh",
    "lamp_light_direction",
    "lamp_move_s",
    "light_by_sun",
    "pass_starts",
    "reach",
    "sun_setting",
    "transit",
    "viewing_pose",
]
