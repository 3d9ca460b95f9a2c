"""Seed §4.1 in the mission: the solar simulator's lamp follows the orbit's sun from visit to visit.

At a visit's mission-clock time the lamp is put where the orbit's sun direction says (:func:`sun_setting`,
:func:`light_by_sun`): lit from the sun's direction onto the vista's target, or the nearest direction its
rail can give (recorded), and off in the Earth's shadow. :class:`rsi.mission.transit.Tour` calls it for each
visit of :func:`rsi.mission.run_mission`. See docs/mission.md.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from rsi import _validate as v
from rsi.errors import InputError
from rsi.sim import orbit as orbits
from rsi.sim.solar_simulator import LampConfiguration, LampMount, RateLimits, lamp_pose

if TYPE_CHECKING:
    from rsi.sim.world import World

FloatArray = NDArray[np.float64]

SUN_DIRECTION_TOLERANCE_RAD = 1e-6  # "reachable": the lamp gives the sun's direction exactly


def lab_world_from_lvlh(mount: LampMount | None = None) -> FloatArray:
    """Where the station's LVLH axes lie in the lab: :data:`rsi.sim.orbit.DEFAULT_WORLD_FROM_LVLH` turned
    about the rail so the orbit plane passes through the lamp's rail and the ORU faces' mid-line.

    Seed §4.1: the lamp's rail only gives light directions in the plane through the rail and the spot, so a
    beta = 0 sun (in the orbit plane) is reproduced exactly on ORU A's face (y = -0.472 m, z = 1.2 m) and
    within a fraction of a degree on B and D; the panel on top lies in another plane.
    """
    from rsi.sim.mockup import A_FACE_Y_M, BAY_M, TRUSS_Z0_M

    rail = v.instance_or_default(mount, "mount", LampMount)
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
    time_s = v.in_range(time_s, "time_s", low=0.0)
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
    _check_world(world)
    if not isinstance(setting, SunSetting):
        raise InputError(f"setting must be a SunSetting from sun_setting(...); got {type(setting).__name__}.")
    world.set_lamp(setting.lamp)
    world.switch_lamp(setting.sunlit)


def _check_world(world: object) -> None:
    from rsi.sim.world import World

    v.instance_of(world, "world", World, none_allowed=False)


def lamp_light_direction(world: World, spot_world_m: object) -> FloatArray:
    """Unit vector from a spot toward the world's lamp as it stands (to check a setting independently)."""
    _check_world(world)
    spot = np.array(v.vector3(spot_world_m, "spot_world_m"))
    toward: FloatArray = np.asarray(lamp_pose(world.lamp).position_world_m) - spot
    return toward / np.linalg.norm(toward)


def lamp_move_s(
    first: LampConfiguration, second: LampConfiguration, rates: RateLimits | None = None
) -> float:
    """Time the lamp needs between two configurations at its joint rate limits (seed §4.1)."""
    for name, configuration in (("first", first), ("second", second)):
        v.instance_of(configuration, name, LampConfiguration, none_allowed=False)
    limits = v.instance_or_default(rates, "rates", RateLimits)
    joints = np.array(
        [[c.theta_rad, c.phi_rad, c.lambda_m, c.gamma_m] for c in (first, second)], dtype=np.float64
    )
    return float(np.max(np.abs(joints[1] - joints[0]) / limits.as_array()))


def pass_starts(start_s: object) -> tuple[float, float]:
    """Validated orbit times at which the reference and the inspection pass begin (two numbers >= 0 s)."""
    if not isinstance(start_s, tuple) or len(start_s) != 2:
        raise InputError(
            f"orbit_start_s must be a (reference, inspection) tuple of times in seconds; got {start_s!r}. "
            "Try orbit_start_s=(400.0, 5953.6): the inspection one orbit after the reference."
        )
    first, second = (v.in_range(value, "orbit_start_s", low=0.0) for value in start_s)
    return (first, second)


__all__ = [
    "SUN_DIRECTION_TOLERANCE_RAD",
    "SunSetting",
    "lab_world_from_lvlh",
    "lamp_light_direction",
    "lamp_move_s",
    "light_by_sun",
    "pass_starts",
    "sun_setting",
]
