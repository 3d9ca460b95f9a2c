"""Seed §3.1 in the mission: where the ISEE must be for a vista, whether the arm reaches it, what its
rangefinders will read there.

A **viewing pose** (:func:`viewing_pose`) puts the left ISEE camera at a vista's position, looking along its
forward with its up (0.5 m standoff), shifted by a visit's repeatability offset; :func:`reach` says whether
the arm on its rail can get the ISEE there; :func:`expected_ranges_m` ray-casts what the two rangefinders
will read at the pose, the standoff of a transit's approach law (:mod:`rsi.mission.transit`). The ISEE's
geometry is read from the arm's model, no numbers copied. See docs/mission.md.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from rsi import _validate as v
from rsi.errors import InputError
from rsi.sim.arm import FOREARM_M, LIMITS, RANGEFINDER_CUTOFF_M, UPPER_ARM_M
from rsi.sim.clearance import is_arm_geom
from rsi.sim.mockup import Vista
from rsi.sim.render import import_mujoco
from rsi.sim.scene import CAMERA_FOVY_DEG

if TYPE_CHECKING:
    from rsi.sim.arm import Arm
    from rsi.sim.world import World

FloatArray = NDArray[np.float64]

REACH_MARGIN_M = 0.02  # the elbow never fully straight: configuration control damps near that singularity


def _unit(vector: FloatArray) -> FloatArray:
    result: FloatArray = vector / np.linalg.norm(vector)
    return result


def look_rotation(forward: FloatArray, up: FloatArray) -> FloatArray:
    """A camera looking along `forward` with `up` up: columns right, up, backward, as
    :class:`rsi.sim.render.CameraPose` (MuJoCo cameras look along -z).

    Raises InputError unless both are non-zero directions, not parallel.
    """
    back = -v.direction3(forward, "forward")
    across = np.cross(v.direction3(up, "up"), back)
    if np.linalg.norm(across) < 1e-9:
        raise InputError(f"up must not be parallel to forward; got forward={forward!r}, up={up!r}.")
    right = _unit(across)
    return np.column_stack([right, np.cross(back, right), back])


def focal_px(rows: int) -> float:
    """Focal length in pixels of the ISEE camera (``CAMERA_FOVY_DEG``) in a frame of `rows` rows."""
    rows = v.positive_int(rows, "rows", maximum=2**20)  # far past any sensor; keeps rows / 2 a float
    return rows / 2 / math.tan(math.radians(CAMERA_FOVY_DEG) / 2)


def pose_error_m(world: World, vista: str, rows: int) -> float:
    """The most a visit's viewpoint error can move a point it places on the surface of `vista`, metres.

    Seed §2.3: the arm misses a vista by its repeatability, which the believed pose does not hold; the
    bound is the arm's (:data:`rsi.sim.world.REPEATABILITY_PX`, an image shift at the vista's standoff),
    in metres at that standoff for a frame of `rows` rows.
    """
    from rsi.sim.world import REPEATABILITY_PX  # at call time: rsi.sim.world is the heaviest import

    _checked_world(world)
    worst_px = REPEATABILITY_PX[world.repeatability][1]
    return worst_px * world.vista(vista).standoff_m / focal_px(rows)


def _checked_world(world: object) -> None:
    from rsi.sim.world import World  # at call time: rsi.sim.world is the heaviest import of the simulator

    v.instance_of(world, "world", World, none_allowed=False)


def world_arm(world: World) -> Arm:
    """The world's arm, or an InputError that says how to build a world with one."""
    _checked_world(world)
    try:
        return world.arm
    except InputError:
        raise InputError(
            "world has no arm; build it with rsi.sim.load('truss', seed=..., arm=True) to move the ISEE."
        ) from None


def world_vista(world: World, vista: object) -> Vista:
    """The world's vista `vista`, or an InputError listing them (and where a mission's extras come from)."""
    _checked_world(world)
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
    arm = world_arm(world)
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
    return pose_of(world, world_vista(world, vista), offset_m=offset_m)


def pose_of(world: World, point: Vista, *, offset_m: tuple[float, float] = (0.0, 0.0)) -> ViewingPose:
    """:func:`viewing_pose` of a vista `point` the world need not list (a plan generator's candidate)."""
    return _pose(_isee(world), point, offset_m)


def _pose(isee: _Isee, point: Vista, offset_m: tuple[float, float]) -> ViewingPose:
    v.instance_of(point, "point", Vista, none_allowed=False)
    offset = v.as_float_array(offset_m, "offset_m")
    if offset.shape != (2,) or not np.isfinite(offset).all():
        raise InputError(f"offset_m must be two finite numbers (right, up; metres); got {offset_m!r}.")
    rotation = look_rotation(np.asarray(point.forward, float), np.asarray(point.up, float))
    camera = np.asarray(point.position_m, float) + rotation[:, :2] @ offset
    tool_rotation = rotation @ isee.camera_rotation.T
    return ViewingPose(
        vista=point.name,
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
    return reach_pose(world, viewing_pose(world, vista))


def reach_pose(world: World, pose: ViewingPose) -> Reach:
    """:func:`reach` of a viewing pose (of a vista the world need not list)."""
    return _reach(_isee(world), v.instance_of(pose, "pose", ViewingPose, none_allowed=False))


def reach_vistas(world: World, points: Sequence[Vista]) -> list[Reach]:
    """:func:`reach` of many vistas the world need not list (the ISEE's geometry read once)."""
    isee = _isee(world)
    if not isinstance(points, Sequence) or isinstance(points, str):
        raise InputError(f"points must be a list of Vista; got {type(points).__name__}.")
    return [_reach(isee, _pose(isee, point, (0.0, 0.0))) for point in points]


def _reach(isee: _Isee, pose: ViewingPose) -> Reach:
    wrist = pose.tool_m + pose.tool_rotation @ isee.wrist_m
    low, high = float(LIMITS.lower[0]), float(LIMITS.upper[0])
    rail = float(np.clip(wrist[0] - isee.shoulder_at_rail_zero_m[0], low, high))
    shoulder = isee.shoulder_at_rail_zero_m + rail * np.array([1.0, 0.0, 0.0])
    shortfall = float(np.linalg.norm(wrist - shoulder)) - (UPPER_ARM_M + FOREARM_M - REACH_MARGIN_M)
    return Reach(vista=pose.vista, reachable=shortfall <= 0.0, shortfall_m=shortfall, rail_m=rail)


# --------------------------------------------------------------------------------- the rangefinders


def expected_ranges_m(world: World, pose: ViewingPose) -> FloatArray:
    """What the two rangefinders will read at `pose`, from the mock-up's model (``inf``: no return).

    A ray from each sensor site along the viewing axis, as MuJoCo's rangefinder casts it (its own body
    ignored), passing through any part of the arm where the arm is now.
    """
    isee = _isee(world)
    v.instance_of(pose, "pose", ViewingPose, none_allowed=False)
    prefix = world_arm(world).prefix
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
            if not is_arm_geom(world.model, int(geom[0]), prefix):
                ranges[index] = travelled if travelled < RANGEFINDER_CUTOFF_M else np.inf
                break
            # an arm part where the arm is now, not where it will be: look past it
            origin, travelled = origin + (hit + 1e-6) * axis, travelled + 1e-6
    return ranges


__all__ = [
    "REACH_MARGIN_M",
    "Reach",
    "ViewingPose",
    "expected_ranges_m",
    "focal_px",
    "look_rotation",
    "pose_of",
    "reach",
    "reach_pose",
    "reach_vistas",
    "viewing_pose",
    "world_arm",
    "world_vista",
]
