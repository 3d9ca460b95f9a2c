"""Seed §1, §3: a 7-DOF redundant arm (K1207 style) on a rail, carrying the ISEE, in MuJoCo (Physics role).

The seed's robot is a Robotics Research K1207 arm "mounted on a translating platform, and controlled by a
real-time system employing Configuration Control [9]" (§1), carrying the Integrated Sensor End-Effector:
two cameras, strobes, halogen lamps, a parallel-jaw gripper with 11 cm jaws, two IR triangulation proximity
sensors recessed behind the jaw tips, a force/torque sensor (§3, §3.1). This module builds that robot:

- :func:`arm_spec` returns the editable model (``mujoco.MjSpec``) and the obstacle functions
  (:func:`add_obstacle`, with :class:`Wall`, :class:`SteppedSurface`, :class:`CurvedSurface`) add geoms to
  it in front of the tool, so a closed-loop demo can servo to known surfaces.
- :class:`Arm` holds the state and the named read-outs (tool pose, Jacobian, arm angle, rangefinders, F/T)
  and :meth:`Arm.step_velocity` does Cartesian velocity control through :mod:`rsi.control.redundancy`.
- :func:`track_path` measures the tracking figures ``arm_tracking_error_m`` and ``additional_task_error_deg``.

Kinematics (all joints zero: the arm points straight up; alternating roll/pitch like the K1207):
rail (slide, world x) -> s1 roll (z) -> s2 pitch (x) -> 0.55 m upper arm -> e1 roll -> e2 pitch ->
0.50 m forearm -> w1 roll -> w2 pitch -> 0.10 m -> w3 roll -> flange (F/T site) -> ISEE housing 0.06 m ->
jaws 0.11 m -> tool site at the jaw tips. Reach from shoulder to jaw tips: 1.32 m (1.15 m to the flange).
Tool frame: z out of the jaws (the tool axis, along which the proximity sensors look), x the sensors'
baseline; at the home pose z = world +y (toward the truss), x = world +x (along the rail), y = world -z.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from rsi import _validate as v
from rsi.constants import PROXIMITY_SAMPLE_RATE_HZ
from rsi.control.redundancy import (
    JointLimits,
    RedundancySettings,
    arm_angle_jacobian,
    arm_angle_rad,
    orientation_error,
    resolve_joint_rates,
)
from rsi.errors import InputError
from rsi.sim.render import import_mujoco

FloatArray = NDArray[np.float64]

JOINT_NAMES = ("rail", "s1", "s2", "e1", "e2", "w1", "w2", "w3")
UPPER_ARM_M = 0.55
FOREARM_M = 0.50
WRIST_TO_FLANGE_M = 0.10
HOUSING_M = 0.06
JAW_LENGTH_M = 0.11  # seed §3.1: "a parallel jaw gripper which has a length of 11 cm"
JAW_MAX_OPENING_M = 0.08  # each jaw slides 4 cm out from its rest 2 cm off the tool axis
DEFAULT_JAW_OPENING_M = 0.04  # half open: the jaws' posture while the ISEE inspects
RANGEFINDER_RECESS_M = JAW_LENGTH_M  # the sensors sit on the housing face, behind the jaw tips
RANGEFINDER_CUTOFF_M = 0.75  # seed §3: the SA1D sees to about 0.75 m
RANGEFINDER_BASELINE_M = 0.07
STEREO_BASELINE_M = 0.06
RAIL_HALF_TRAVEL_M = 1.0
SHOULDER_HEIGHT_M = 0.975
RAIL_Y_M = -1.8
# Home: upper arm 30 deg forward of vertical, elbow bent 90 deg, wrist pitched so the tool is horizontal;
# well away from the elbow-straight and wrist-straight singularities.
HOME_Q = np.array([0.0, 0.0, -np.pi / 6, 0.0, -np.pi / 2, 0.0, np.pi / 6, 0.0])
ARM_ANGLE_REFERENCE = np.array([0.0, 0.0, 1.0])  # psi = 0: elbow in the vertical plane through S-W, up

# K1207-like ranges; rates a little under the K1207's (a gentle inspection arm)
LIMITS = JointLimits(
    lower=np.concatenate([[-RAIL_HALF_TRAVEL_M], np.radians([-170, -110, -170, -135, -170, -110, -170])]),
    upper=np.concatenate([[RAIL_HALF_TRAVEL_M], np.radians([170, 110, 170, 135, 170, 110, 170])]),
    max_rate=np.array([0.25, 1.0, 1.0, 1.2, 1.2, 1.5, 1.5, 1.5]),
)
MODES = ("kinematic", "servo")
JAW_NAMES = ("jaw_left", "jaw_right")
CAMERAS = ("left", "right")
WORLD_ARM_PREFIX = "arm_"  # names of the arm's elements inside a larger model (rsi.sim.load(arm=True))
# What a host world does not take from the arm's own model: its floor and room light (the truss world is a
# dark room with its own calibrated lights; rsi.sim.scene).
_STANDALONE_ONLY = {"geom": ("floor",), "light": ("room",)}


# --------------------------------------------------------------------------------------- obstacles


@dataclass(frozen=True)
class Wall:
    """A flat wall facing the tool at the home pose.

    Parameters
    ----------
    distance_m : float
        From the home tool tip to the wall along the home tool axis, > 0 m.
    half_width_m : float
        Half extent along the rail (tangential, world x), > 0 m.
    half_height_m : float
        Half extent vertically, > 0 m.
    """

    distance_m: float
    half_width_m: float = 1.5
    half_height_m: float = 0.6

    def __post_init__(self) -> None:
        for name in ("distance_m", "half_width_m", "half_height_m"):
            v.in_range(getattr(self, name), name, low=0.0, low_inclusive=False)

    def surface_distance_m(self, tangential_m: object) -> FloatArray:
        """Distance from the home tool plane to the surface, m, at tangential offsets along world x."""
        t = np.asarray(tangential_m, dtype=np.float64)
        return np.where(np.abs(t) <= self.half_width_m, self.distance_m, np.inf)

    def boxes(self) -> list[tuple[FloatArray, FloatArray]]:
        """(centre offset [x, depth, z], half sizes) of each box, relative to the home tool tip."""
        thickness = 0.02
        return [
            (
                np.array([0.0, self.distance_m + thickness, 0.0]),
                np.array([self.half_width_m, thickness, self.half_height_m]),
            )
        ]


@dataclass(frozen=True)
class SteppedSurface:
    """A wall with rectangular steps toward the tool (protrusions coming into view, seed §3.1 region B).

    Parameters
    ----------
    distance_m : float
        Home tool tip to the base wall, > 0 m.
    steps : sequence of (start_m, end_m, height_m)
        Tangential interval (world x offset from the home tool tip) and height toward the tool, m;
        ``0 < height < distance``, intervals ordered and not overlapping.
    half_width_m, half_height_m : float
        Extent of the base wall.
    """

    distance_m: float
    steps: tuple[tuple[float, float, float], ...] = ((0.10, 0.30, 0.05), (0.30, 0.50, 0.10))
    half_width_m: float = 1.5
    half_height_m: float = 0.6

    def __post_init__(self) -> None:
        Wall(self.distance_m, self.half_width_m, self.half_height_m)
        previous_end = -np.inf
        cleaned = []
        if not isinstance(self.steps, (tuple, list)):
            raise InputError(f"steps must be a tuple of (start_m, end_m, height_m); got {self.steps!r}.")
        for index, step in enumerate(self.steps):
            if not isinstance(step, (tuple, list)) or len(step) != 3:
                raise InputError(f"steps[{index}] must be (start_m, end_m, height_m); got {step!r}.")
            start, end, height = (v.finite_number(x, f"steps[{index}]") for x in step)
            if not previous_end <= start < end:
                raise InputError(
                    f"steps[{index}]={step!r}: intervals must be ordered, non-empty and not overlapping."
                )
            if not 0 < height < self.distance_m:
                raise InputError(f"steps[{index}] height must be in (0, distance_m); got {height!r}.")
            previous_end = end
            cleaned.append((start, end, height))
        object.__setattr__(self, "steps", tuple(cleaned))

    def surface_distance_m(self, tangential_m: object) -> FloatArray:
        """Distance from the home tool plane to the surface, m, at tangential offsets along world x."""
        t = np.asarray(tangential_m, dtype=np.float64)
        result = np.where(np.abs(t) <= self.half_width_m, self.distance_m, np.inf)
        for start, end, height in self.steps:
            result = np.where((t >= start) & (t < end), self.distance_m - height, result)
        return result

    def boxes(self) -> list[tuple[FloatArray, FloatArray]]:
        """(centre offset [x, depth, z], half sizes) of each box, relative to the home tool tip."""
        boxes = Wall(self.distance_m, self.half_width_m, self.half_height_m).boxes()
        for start, end, height in self.steps:
            boxes.append(
                (
                    np.array([(start + end) / 2, self.distance_m - height / 2, 0.0]),
                    np.array([(end - start) / 2, height / 2, self.half_height_m]),
                )
            )
        return boxes


@dataclass(frozen=True)
class CurvedSurface:
    """A vertical cylinder standing in front of a wall: a convex surface curving away from the tool.

    Parameters
    ----------
    distance_m : float
        Home tool tip to the cylinder's nearest point, > 0 m.
    radius_m : float
        Cylinder radius, > 0 m.
    centre_m : float
        Tangential (world x) offset of the cylinder axis from the home tool tip, m.
    wall_distance_m : float
        Home tool tip to the backing wall, > ``distance_m`` (None: ``distance_m + radius_m``).
    """

    distance_m: float
    radius_m: float = 0.3
    centre_m: float = 0.0
    wall_distance_m: float | None = None
    half_height_m: float = 0.6

    def __post_init__(self) -> None:
        v.in_range(self.distance_m, "distance_m", low=0.0, low_inclusive=False)
        v.in_range(self.radius_m, "radius_m", low=0.0, low_inclusive=False)
        v.finite_number(self.centre_m, "centre_m")
        wall = self.distance_m + self.radius_m if self.wall_distance_m is None else self.wall_distance_m
        v.in_range(wall, "wall_distance_m", low=self.distance_m, low_inclusive=False)
        object.__setattr__(self, "wall_distance_m", float(wall))

    def surface_distance_m(self, tangential_m: object) -> FloatArray:
        """Distance from the home tool plane to the surface, m, at tangential offsets along world x."""
        t = np.asarray(tangential_m, dtype=np.float64) - self.centre_m
        inside = np.abs(t) < self.radius_m
        cylinder = self.distance_m + self.radius_m - np.sqrt(np.clip(self.radius_m**2 - t**2, 0.0, None))
        wall = float(self.wall_distance_m) if self.wall_distance_m is not None else np.inf
        return np.where(inside, np.minimum(cylinder, wall), wall)

    def boxes(self) -> list[tuple[FloatArray, FloatArray]]:
        """The backing wall, as for :class:`Wall`."""
        wall = float(self.wall_distance_m) if self.wall_distance_m is not None else 1.0
        return Wall(wall, 1.5, self.half_height_m).boxes()


Obstacle = Wall | SteppedSurface | CurvedSurface


def _home_tool_frame() -> tuple[FloatArray, FloatArray]:
    """Home tool tip (world, m) and home rotation (columns: tool x, y, z in world), from the chain."""
    s = np.array([0.0, RAIL_Y_M, SHOULDER_HEIGHT_M])
    phi1, phi2 = -HOME_Q[2], -(HOME_Q[2] + HOME_Q[4])
    e = s + UPPER_ARM_M * np.array([0.0, np.sin(phi1), np.cos(phi1)])
    w = e + FOREARM_M * np.array([0.0, np.sin(phi2), np.cos(phi2)])
    tip = w + (WRIST_TO_FLANGE_M + HOUSING_M + JAW_LENGTH_M) * np.array([0.0, 1.0, 0.0])
    rotation = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, -1.0, 0.0]])
    return tip, rotation


def add_obstacle(spec: Any, obstacle: Obstacle, *, name: str = "obstacle") -> None:
    """Add an obstacle's geoms to a model spec, placed in front of the tool's home pose.

    Offsets are [tangential (world x), depth (along the home tool axis, world +y), vertical]. The geoms
    collide with the arm (contype 1) and are seen by the rangefinders and cameras.

    Parameters
    ----------
    spec : mujoco.MjSpec
        From :func:`arm_spec`.
    obstacle : Wall, SteppedSurface or CurvedSurface
    name : str
        Prefix of the geom names.
    """
    mujoco: Any = import_mujoco()
    _check_spec(spec)
    if not isinstance(name, str):
        raise InputError(f"name must be a str (the geoms' name prefix); got {name!r}.")
    if not isinstance(obstacle, Wall | SteppedSurface | CurvedSurface):
        raise InputError(
            f"obstacle must be a Wall, SteppedSurface or CurvedSurface; got {type(obstacle).__name__}."
        )
    tip, _ = _home_tool_frame()
    for index, (offset, half) in enumerate(obstacle.boxes()):
        geom = spec.worldbody.add_geom()
        geom.name = f"{name}_{index}"
        geom.type = mujoco.mjtGeom.mjGEOM_BOX
        geom.size = half
        geom.pos = tip + offset
        geom.rgba = [0.62, 0.62, 0.6, 1.0]
        geom.contype, geom.conaffinity = 1, 2
    if isinstance(obstacle, CurvedSurface):
        geom = spec.worldbody.add_geom()
        geom.name = f"{name}_cylinder"
        geom.type = mujoco.mjtGeom.mjGEOM_CYLINDER
        geom.size = [obstacle.radius_m, obstacle.half_height_m, 0.0]
        geom.pos = tip + np.array([obstacle.centre_m, obstacle.distance_m + obstacle.radius_m, 0.0])
        geom.rgba = [0.7, 0.7, 0.68, 1.0]
        geom.contype, geom.conaffinity = 1, 2


# -------------------------------------------------------------------------------------------- MJCF


def _check_model(model: object, data: object) -> None:
    """Raise unless `model` is a mujoco.MjModel and `data` a mujoco.MjData of it (MuJoCo's own errors say
    neither which argument nor how to fix it)."""
    mujoco: Any = import_mujoco()
    if not isinstance(model, mujoco.MjModel):
        raise InputError(f"model must be a mujoco.MjModel; got {type(model).__name__}. Compile a spec first.")
    if not isinstance(data, mujoco.MjData) or data.qpos.size != model.nq:
        raise InputError(
            f"data must be the mujoco.MjData of model; got {type(data).__name__}: mujoco.MjData(model)."
        )


def _check_spec(spec: object) -> None:
    mujoco: Any = import_mujoco()
    if not isinstance(spec, mujoco.MjSpec):
        raise InputError(f"spec must be a mujoco.MjSpec; got {type(spec).__name__}. Start from arm_spec().")


def _fmt(values: Sequence[float] | FloatArray) -> str:
    return " ".join(f"{float(x):.6g}" for x in values)


def arm_mjcf() -> str:
    """The arm, rail and ISEE as MJCF (see the module docstring for the chain and frames)."""
    lo, hi = LIMITS.lower, LIMITS.upper
    rng = [f"{lo[i]:.6f} {hi[i]:.6f}" for i in range(8)]
    half_rf = RANGEFINDER_BASELINE_M / 2
    half_cam = STEREO_BASELINE_M / 2
    # Servo gains: stiff like the K1207's joint servos; armature (reflected rotor inertia) and
    # implicitfast keep the light chain stable at a 2 ms step (ARCHITECTURE: MuJoCo facts).
    return f"""<mujoco model="k1207_isee">
  <compiler angle="radian" autolimits="true"/>
  <option timestep="0.002" integrator="implicitfast"/>
  <visual><global offwidth="1280" offheight="960"/></visual>
  <default>
    <joint armature="0.2" damping="5" limited="true"/>
    <geom contype="2" conaffinity="1" density="1200" rgba="0.85 0.85 0.82 1"/>
    <position kp="4000" kv="120" inheritrange="0"/>
    <site size="0.01" rgba="1 0 0 0.5" group="4"/>
  </default>
  <worldbody>
    <light name="room" pos="0 -1 3" dir="0 0 -1" diffuse="0.5 0.5 0.5"/>
    <geom name="floor" type="plane" size="4 4 0.1" rgba="0.3 0.3 0.32 1" contype="1" conaffinity="2"/>
    <geom name="rail_beam" type="box" pos="0 {RAIL_Y_M} 0.35" size="{RAIL_HALF_TRAVEL_M + 0.2} 0.12 0.05"
          rgba="0.4 0.4 0.45 1" contype="1" conaffinity="0"/>
    <body name="carriage" pos="0 {RAIL_Y_M} 0.45" gravcomp="1">
      <joint name="rail" type="slide" axis="1 0 0" range="{rng[0]}" armature="5" damping="50"/>
      <geom name="carriage" type="box" pos="0 0 0.03" size="0.15 0.15 0.03" rgba="0.3 0.3 0.35 1"/>
      <geom name="column" type="cylinder" pos="0 0 0.25" size="0.08 0.22"/>
      <body name="base" pos="0 0 0.47" gravcomp="1">
        <joint name="s1" axis="0 0 1" range="{rng[1]}"/>
        <geom name="s1_housing" type="cylinder" pos="0 0 0.025" size="0.075 0.03"/>
        <body name="upper_arm" pos="0 0 {SHOULDER_HEIGHT_M - 0.92:.6g}" gravcomp="1">
          <joint name="s2" axis="1 0 0" range="{rng[2]}"/>
          <site name="shoulder" pos="0 0 0"/>
          <geom name="s2_housing" type="cylinder" fromto="-0.07 0 0 0.07 0 0" size="0.065"/>
          <geom name="upper_arm" type="capsule" fromto="0 0 0.07 0 0 {UPPER_ARM_M * 0.55:.6g}" size="0.055"/>
          <body name="upper_arm_roll" pos="0 0 {UPPER_ARM_M * 0.55:.6g}" gravcomp="1">
            <joint name="e1" axis="0 0 1" range="{rng[3]}"/>
            <geom type="capsule" fromto="0 0 0 0 0 {UPPER_ARM_M * 0.45 - 0.06:.6g}" size="0.05"/>
            <body name="forearm" pos="0 0 {UPPER_ARM_M * 0.45:.6g}" gravcomp="1">
              <joint name="e2" axis="1 0 0" range="{rng[4]}"/>
              <site name="elbow" pos="0 0 0"/>
              <geom name="e2_housing" type="cylinder" fromto="-0.06 0 0 0.06 0 0" size="0.055"/>
              <geom name="forearm" type="capsule" fromto="0 0 0.06 0 0 {FOREARM_M * 0.55:.6g}" size="0.045"/>
              <body name="forearm_roll" pos="0 0 {FOREARM_M * 0.55:.6g}" gravcomp="1">
                <joint name="w1" axis="0 0 1" range="{rng[5]}"/>
                <geom type="capsule" fromto="0 0 0 0 0 {FOREARM_M * 0.45 - 0.05:.6g}" size="0.04"/>
                <body name="wrist" pos="0 0 {FOREARM_M * 0.45:.6g}" gravcomp="1">
                  <joint name="w2" axis="1 0 0" range="{rng[6]}"/>
                  <site name="wrist" pos="0 0 0"/>
                  <geom name="w2_housing" type="cylinder" fromto="-0.045 0 0 0.045 0 0" size="0.04"/>
                  <body name="tool_roll" pos="0 0 0.05" gravcomp="1">
                    <joint name="w3" axis="0 0 1" range="{rng[7]}"/>
                    <geom type="cylinder" fromto="0 0 0 0 0 {WRIST_TO_FLANGE_M - 0.05:.6g}" size="0.035"/>
                    <body name="isee" pos="0 0 {WRIST_TO_FLANGE_M - 0.05:.6g}" gravcomp="1">
                      <site name="ft" pos="0 0 0"/>
                      <geom name="ft_sensor" type="cylinder" pos="0 0 0.01" size="0.04 0.01"
                            rgba="0.2 0.2 0.2 1"/>
                      <body name="palm" pos="0 0 {HOUSING_M}">
                        <!-- the housing belongs to the sensors' own body, which a rangefinder ignores, and
                             ends 1 mm behind their faces: a ray must not start on a surface (reads 0) -->
                        <geom name="housing" type="box" pos="0 0 {-0.001 - (HOUSING_M - 0.02) / 2:.6g}"
                              size="0.07 0.06 {(HOUSING_M - 0.02) / 2:.6g}" rgba="0.15 0.15 0.17 1"/>
                        <site name="range_left" pos="{-half_rf} 0 0" zaxis="0 0 1"/>
                        <site name="range_right" pos="{half_rf} 0 0" zaxis="0 0 1"/>
                        <site name="tool" pos="0 0 {JAW_LENGTH_M}"/>
                        <camera name="isee_left" pos="{-half_cam} -0.045 0" xyaxes="1 0 0 0 -1 0" fovy="35"/>
                        <camera name="isee_right" pos="{half_cam} -0.045 0" xyaxes="1 0 0 0 -1 0" fovy="35"/>
                        <light name="halogen_left" pos="-0.06 0.045 0" dir="0 0 1" type="spot" cutoff="30"
                               diffuse="0.4 0.4 0.4" castshadow="false"/>
                        <light name="halogen_right" pos="0.06 0.045 0" dir="0 0 1" type="spot" cutoff="30"
                               diffuse="0.4 0.4 0.4" castshadow="false"/>
                        <body name="jaw_left" pos="0 -0.02 0">
                          <joint name="jaw_left" type="slide" axis="0 -1 0" range="0 {JAW_MAX_OPENING_M / 2}"
                                 armature="0.01"/>
                          <geom name="jaw_left" type="box" pos="0 -0.005 {JAW_LENGTH_M / 2}"
                                size="0.012 0.005 {JAW_LENGTH_M / 2}" rgba="0.6 0.6 0.62 1"/>
                          <light name="strobe_left" pos="0 -0.012 0.02" dir="0 0.2 1" type="spot" cutoff="35"
                                 diffuse="0 0 0" castshadow="false"/>
                        </body>
                        <body name="jaw_right" pos="0 0.02 0">
                          <joint name="jaw_right" type="slide" axis="0 1 0" range="0 {JAW_MAX_OPENING_M / 2}"
                                 armature="0.01"/>
                          <geom name="jaw_right" type="box" pos="0 0.005 {JAW_LENGTH_M / 2}"
                                size="0.012 0.005 {JAW_LENGTH_M / 2}" rgba="0.6 0.6 0.62 1"/>
                          <light name="strobe_right" pos="0 0.012 0.02" dir="0 -0.2 1" type="spot" cutoff="35"
                                 diffuse="0 0 0" castshadow="false"/>
                        </body>
                      </body>
                    </body>
                  </body>
                </body>
              </body>
            </body>
          </body>
        </body>
      </body>
    </body>
  </worldbody>
  <actuator>
    <position name="rail" joint="rail" kp="20000" kv="2000"/>
    {"".join(f'<position name="{j}" joint="{j}"/>' for j in JOINT_NAMES[1:])}
    <position name="jaw_left" joint="jaw_left" kp="200" kv="5"/>
    <position name="jaw_right" joint="jaw_right" kp="200" kv="5"/>
  </actuator>
  <sensor>
    <rangefinder name="range_left" site="range_left" cutoff="{RANGEFINDER_CUTOFF_M}"/>
    <rangefinder name="range_right" site="range_right" cutoff="{RANGEFINDER_CUTOFF_M}"/>
    <force name="ft_force" site="ft"/>
    <torque name="ft_torque" site="ft"/>
  </sensor>
</mujoco>"""


def arm_spec(obstacles: Sequence[Obstacle] = ()) -> Any:
    """The arm's model spec (``mujoco.MjSpec``) with the obstacles added; compile it or pass it to Arm."""
    mujoco: Any = import_mujoco()
    if isinstance(obstacles, (str, bytes)) or not isinstance(obstacles, (tuple, list)):
        raise InputError(
            f"obstacles must be a tuple of Wall, SteppedSurface or CurvedSurface; got {obstacles!r}."
        )
    spec = mujoco.MjSpec.from_string(arm_mjcf())
    for index, obstacle in enumerate(obstacles):
        add_obstacle(spec, obstacle, name=f"obstacle{index}")
    return spec


def attach_arm(spec: Any, *, home_tool_tip_m: object, prefix: str = WORLD_ARM_PREFIX) -> None:
    """Put the arm, its rail and the ISEE into another model's spec (an MjSpec attach, no copy of the MJCF).

    The whole arm (rail beam, carriage and chain, actuators, rangefinders, F/T) is translated so that its
    home tool tip lands on `home_tool_tip_m`; the rail stays along world x and the home tool axis along
    world +y. Names get `prefix` (bind with ``Arm.bind(model, data, prefix=prefix)``). The arm's floor
    and room light are left out, and the host takes the arm's integrator (``implicitfast``, needed by the
    light chain under physics: ARCHITECTURE, MuJoCo facts).

    Parameters
    ----------
    spec : mujoco.MjSpec
        The host model, edited in place.
    home_tool_tip_m : (float, float, float)
        World position of the tool tip at :data:`HOME_Q` (rail at mid-travel), m.
    prefix : str
        Prefix of every name the arm brings.
    """
    _check_spec(spec)
    target = v.as_float_array(home_tool_tip_m, "home_tool_tip_m")
    if target.shape != (3,) or not np.all(np.isfinite(target)):
        raise InputError(f"home_tool_tip_m must be 3 finite numbers (x, y, z m); got {home_tool_tip_m!r}.")
    if not isinstance(prefix, str):
        raise InputError(f"prefix must be a str; got {prefix!r}.")
    child = arm_spec()
    spec.option.integrator = child.option.integrator
    spec.option.timestep = child.option.timestep
    frame = spec.worldbody.add_frame()
    frame.pos = target - _home_tool_frame()[0]
    try:
        spec.attach(child, frame=frame, prefix=prefix)
    except ValueError as error:  # MuJoCo refuses a name the host already has ("repeated name ...")
        raise InputError(
            f"prefix={prefix!r} gives the arm a name spec already has ({error}); choose another prefix."
        ) from None
    for kind, names in _STANDALONE_ONLY.items():
        for name in names:
            spec.delete(getattr(spec, kind)(prefix + name))


# --------------------------------------------------------------------------------------------- Arm


@dataclass(frozen=True)
class ArmStep:
    """What one :meth:`Arm.step_velocity` did.

    Attributes
    ----------
    joint_velocity : ndarray of shape (8,)
        Commanded rates (rail m/s, joints rad/s).
    rate_scale : float
        Factor in (0, 1] applied for the rate limits.
    damping : float
        Damped-least-squares ``lambda`` (0 away from singularities).
    locked : ndarray of shape (8,), bool
        Joints held at a position limit.
    tool_position_m : ndarray of shape (3,)
        Tool tip after the step, world frame.
    arm_angle_rad : float
        After the step.
    """

    joint_velocity: FloatArray
    rate_scale: float
    damping: float
    locked: NDArray[np.bool_]
    tool_position_m: FloatArray
    arm_angle_rad: float


class Arm:
    """The K1207-style arm on its rail carrying the ISEE (dm_control's Physics role: state and read-outs).

    Parameters
    ----------
    obstacles : sequence of Wall, SteppedSurface, CurvedSurface
        Placed in front of the tool's home pose (see :func:`add_obstacle`).
    mode : {"kinematic", "servo"}
        ``"kinematic"`` (default) integrates the resolved joint rates exactly (``q += dq dt``, then forward
        kinematics): the K1207's high-gain joint servos track rate commands far faster than the 44 Hz
        proximity loop (seed §3.1), so the arm's dynamics are not the subject; it is exact, fast and
        deterministic, and obstacles do not push back (contacts are not simulated). ``"servo"`` drives
        position actuators (targets integrated from the rates, velocity feed-forward) under full
        dynamics with contacts, ``implicitfast`` and joint armature, gravity compensated as the K1207's
        controller does.
    settings : RedundancySettings, optional
        Redundancy-resolution knobs (default: rail weighted 4x, so the joints do most of the work).
    position_gain : float
        Fraction of the task-space error (position, orientation, arm angle) corrected per step, in (0, 1]
        (closed-loop inverse kinematics: 1 is dead-beat, right for ``"kinematic"``).
    """

    def __init__(
        self,
        obstacles: Sequence[Obstacle] = (),
        *,
        mode: str = "kinematic",
        settings: RedundancySettings | None = None,
        position_gain: float | None = None,
    ) -> None:
        self._mujoco: Any = import_mujoco()
        v.choice(mode, "mode", MODES)
        if isinstance(obstacles, (str, bytes)) or not isinstance(obstacles, (tuple, list)):
            raise InputError(
                f"obstacles must be a tuple of Wall, SteppedSurface or CurvedSurface; got {obstacles!r}."
            )
        self.obstacles = tuple(obstacles)
        model = arm_spec(self.obstacles).compile()
        self._bind(
            model,
            self._mujoco.MjData(model),
            prefix="",
            owns_data=True,
            mode=mode,
            settings=settings,
            position_gain=position_gain,
        )

    @classmethod
    def bind(
        cls,
        model: Any,
        data: Any,
        *,
        prefix: str = WORLD_ARM_PREFIX,
        mode: str = "kinematic",
        settings: RedundancySettings | None = None,
        position_gain: float | None = None,
    ) -> Arm:
        """An Arm driving the arm inside a larger model (one built with :func:`attach_arm`).

        The arm's joints, sites, sensors, cameras and actuators are found by their names with `prefix`;
        everything else in `model` and `data` (a truss, a door, mocap bodies) is left alone, and
        :meth:`reset` sets only the arm's own state. The other parameters are those of :class:`Arm`.

        Parameters
        ----------
        model : mujoco.MjModel
        data : mujoco.MjData
            Of `model`; shared, not copied: the arm's steps move the same world.
        prefix : str
            Name prefix the arm was attached with (:data:`WORLD_ARM_PREFIX` in :func:`rsi.sim.load`).

        Returns
        -------
        Arm
            At the home pose.
        """
        arm = cls.__new__(cls)
        arm._mujoco = import_mujoco()
        v.choice(mode, "mode", MODES)
        if not isinstance(prefix, str):
            raise InputError(f"prefix must be a str; got {prefix!r}.")
        _check_model(model, data)
        arm.obstacles = ()
        arm._bind(
            model,
            data,
            prefix=prefix,
            owns_data=False,
            mode=mode,
            settings=settings,
            position_gain=position_gain,
        )
        return arm

    def _bind(
        self,
        model: Any,
        data: Any,
        *,
        prefix: str,
        owns_data: bool,
        mode: str,
        settings: RedundancySettings | None,
        position_gain: float | None,
    ) -> None:
        self.mode = v.choice(mode, "mode", MODES)
        self.model: Any = model
        self.data: Any = data
        self.prefix = prefix
        self._owns_data = owns_data
        self.settings = (
            RedundancySettings(joint_weights=np.array([4.0, 1, 1, 1, 1, 1, 1, 1]))
            if settings is None
            else v.instance_of(settings, "settings", RedundancySettings)
        )
        default_gain = 1.0 if self.mode == "kinematic" else 0.5
        self.position_gain = v.in_range(
            default_gain if position_gain is None else position_gain,
            "position_gain",
            low=0.0,
            high=1.0,
            low_inclusive=False,
        )
        obj = self._mujoco.mjtObj

        def ids(kind: Any, names: Sequence[str]) -> list[int]:
            found = [int(self._mujoco.mj_name2id(model, kind, prefix + name)) for name in names]
            missing = [prefix + name for name, k in zip(names, found, strict=True) if k < 0]
            if missing:
                raise InputError(
                    f"model has no arm element named {missing[0]!r} (prefix={prefix!r}); build it with "
                    "attach_arm(spec, prefix=...) and pass the same prefix."
                )
            return found

        self._joint_ids = ids(obj.mjOBJ_JOINT, JOINT_NAMES)
        self._qpos = np.array([model.jnt_qposadr[j] for j in self._joint_ids])
        self._dof = np.array([model.jnt_dofadr[j] for j in self._joint_ids])
        jaws = ids(obj.mjOBJ_JOINT, JAW_NAMES)
        self._jaw_qpos = np.array([model.jnt_qposadr[j] for j in jaws])
        self._jaw_dof = np.array([model.jnt_dofadr[j] for j in jaws])
        self._ctrl = np.array(ids(obj.mjOBJ_ACTUATOR, (*JOINT_NAMES, *JAW_NAMES)))
        site_names = ("tool", "shoulder", "elbow", "wrist", "ft", "range_left", "range_right")
        self._site = dict(zip(site_names, ids(obj.mjOBJ_SITE, site_names), strict=True))
        self._camera = dict(
            zip(CAMERAS, ids(obj.mjOBJ_CAMERA, tuple(f"isee_{c}" for c in CAMERAS)), strict=True)
        )
        self._range_adr = [
            int(model.sensor_adr[k]) for k in ids(obj.mjOBJ_SENSOR, ("range_left", "range_right"))
        ]
        self._ft_adr = [int(model.sensor_adr[k]) for k in ids(obj.mjOBJ_SENSOR, ("ft_force", "ft_torque"))]
        self.time_s = 0.0
        self.reset(HOME_Q)

    # ------------------------------------------------------------------------------------ state

    @property
    def limits(self) -> JointLimits:
        """Position and rate limits of the 8 joints (rail first)."""
        return LIMITS

    def reset(self, joint_positions: object = None, *, jaw_opening_m: float = DEFAULT_JAW_OPENING_M) -> None:
        """Put the arm at ``joint_positions`` (8: rail m, then 7 joints rad; None: home), at rest.

        Also re-anchors the Cartesian, orientation and arm-angle references of :meth:`step_velocity`.
        """
        q = HOME_Q if joint_positions is None else v.as_float_array(joint_positions, "joint_positions")
        if q.shape != (8,) or not np.all(np.isfinite(q)):
            raise InputError(f"joint_positions must be 8 finite numbers (rail m, 7 joints rad); got {q!r}.")
        if np.any(q < LIMITS.lower) or np.any(q > LIMITS.upper):
            raise InputError(
                f"joint_positions={q} lie outside the limits lower={LIMITS.lower}, upper={LIMITS.upper}."
            )
        opening = v.in_range(jaw_opening_m, "jaw_opening_m", low=0.0, high=JAW_MAX_OPENING_M)
        if self._owns_data:
            self._mujoco.mj_resetData(self.model, self.data)
        else:  # in a shared world only the arm's own state is reset (not the door, lamp or time)
            self.data.qvel[self._dof] = 0.0
            self.data.qvel[self._jaw_dof] = 0.0
        self.data.qpos[self._qpos] = q
        self.data.qpos[self._jaw_qpos] = opening / 2
        self.data.ctrl[self._ctrl[:8]] = q
        self.data.ctrl[self._ctrl[8:]] = opening / 2
        self._target_q = q.copy()
        self._mujoco.mj_forward(self.model, self.data)
        self.time_s = 0.0
        self._ref_position = self.tool_pose()[0]
        self._ref_rotation = self.tool_pose()[1]
        self._ref_arm_angle = self.arm_angle_rad()

    @property
    def jaw_opening_m(self) -> float:
        """The gap between the gripper's jaws, metres (0: closed)."""
        return float(2.0 * self.data.qpos[self._jaw_qpos].mean())

    def set_jaw_opening(self, opening_m: float) -> None:
        """Open the gripper's jaws to `opening_m` in [0, 0.08] m and hold them there (the joints stay put).

        The jaws lie in the ISEE cameras' view (seed §3.1: 11 cm jaws beside the cameras); moving them moves
        what they hide.
        """
        opening = v.in_range(opening_m, "opening_m", low=0.0, high=JAW_MAX_OPENING_M)
        self.data.qpos[self._jaw_qpos] = opening / 2
        self.data.qvel[self._jaw_dof] = 0.0
        self.data.ctrl[self._ctrl[8:]] = opening / 2
        self._mujoco.mj_forward(self.model, self.data)

    @property
    def joint_positions(self) -> FloatArray:
        """Rail (m) and the 7 joints (rad), shape (8,)."""
        result: FloatArray = self.data.qpos[self._qpos].copy()
        return result

    def random_configuration(
        self, rng: np.random.Generator | int | None, *, margin: float = 0.2
    ) -> FloatArray:
        """Joint positions drawn uniformly from the inner ``1 - 2 margin`` of each range (seeded)."""
        gen = v.as_rng(rng)
        margin = v.in_range(margin, "margin", low=0.0, high=0.5, high_inclusive=False)
        span = LIMITS.upper - LIMITS.lower
        result: FloatArray = gen.uniform(LIMITS.lower + margin * span, LIMITS.upper - margin * span)
        return result

    # -------------------------------------------------------------------------------- read-outs

    def tool_pose(self) -> tuple[FloatArray, FloatArray]:
        """Tool tip position (m, world) and rotation (3x3, columns = tool x, y, z in world)."""
        site = self._site["tool"]
        return self.data.site_xpos[site].copy(), self.data.site_xmat[site].reshape(3, 3).copy()

    def camera_pose(self, camera: str = "left") -> tuple[FloatArray, FloatArray]:
        """Position (m, world) and rotation (3x3, columns: image right, image up, backward) of an ISEE camera.

        Parameters
        ----------
        camera : {"left", "right"}
            ``isee_left`` or ``isee_right`` (baseline :data:`STEREO_BASELINE_M`); both look along the tool
            axis.
        """
        index = self._camera[v.choice(camera, "camera", CAMERAS)]
        return self.data.cam_xpos[index].copy(), self.data.cam_xmat[index].reshape(3, 3).copy()

    def camera_name(self, camera: str = "left") -> str:
        """The model's name of an ISEE camera (with this arm's prefix), for a renderer."""
        return f"{self.prefix}isee_{v.choice(camera, 'camera', CAMERAS)}"

    def site_position_m(self, name: str) -> FloatArray:
        """World position of a named site (tool, shoulder, elbow, wrist, ft, range_left, range_right)."""
        if not isinstance(name, str) or name not in self._site:
            raise InputError(f"name must be one of {sorted(self._site)}; got {name!r}.")
        result: FloatArray = self.data.site_xpos[self._site[name]].copy()
        return result

    def _site_jacobian(self, name: str) -> tuple[FloatArray, FloatArray]:
        jacp = np.zeros((3, self.model.nv))
        jacr = np.zeros((3, self.model.nv))
        self._mujoco.mj_jacSite(self.model, self.data, jacp, jacr, self._site[name])
        return jacp[:, self._dof], jacr[:, self._dof]

    def jacobian(self) -> FloatArray:
        """Tool Jacobian (6 x 8, rows [v; omega] in world, columns rail then joints) from ``mj_jacSite``."""
        jacp, jacr = self._site_jacobian("tool")
        return np.vstack([jacp, jacr])

    def arm_angle_rad(self) -> float:
        """The arm angle psi (rad): plane shoulder-elbow-wrist about the shoulder-wrist line, 0 = elbow up."""
        return arm_angle_rad(
            self.site_position_m("shoulder"),
            self.site_position_m("elbow"),
            self.site_position_m("wrist"),
            reference=ARM_ANGLE_REFERENCE,
        )

    def arm_angle_jacobian(self) -> FloatArray:
        """``d psi / dq``, shape (8,): chain rule through the three sites' ``mj_jacSite`` Jacobians."""
        names = ("shoulder", "elbow", "wrist")
        return arm_angle_jacobian(
            *(self.site_position_m(n) for n in names),
            shoulder_jacobian=self._site_jacobian("shoulder")[0],
            elbow_jacobian=self._site_jacobian("elbow")[0],
            wrist_jacobian=self._site_jacobian("wrist")[0],
            reference=ARM_ANGLE_REFERENCE,
        )

    def rangefinder_distances_m(self) -> FloatArray:
        """The two IR rangefinders' readings (left, right), m, exactly as MuJoCo gives them.

        Measured from the sensor face, which is recessed ``RANGEFINDER_RECESS_M`` (0.11 m) behind the jaw
        tips, along the tool axis. ``-0.75`` (negative) means no return; a surface at or beyond the cutoff
        reads ``+0.75`` (MuJoCo clamps to the cutoff), so treat readings ``>= RANGEFINDER_CUTOFF_M`` as out
        of range too.
        """
        return np.array([self.data.sensordata[a] for a in self._range_adr])

    def force_torque(self) -> tuple[FloatArray, FloatArray]:
        """Force (N) and torque (N m) at the F/T site, in the site (flange) frame.

        What the flange carries: the weight of the ISEE below the site and every contact on it. In
        ``"kinematic"`` mode the joints follow their commands exactly, so the reading is quasi-static
        (accelerations zero): MuJoCo's forward pass would otherwise let the unheld arm fall freely under
        its position servos' stale targets, and the flange would read a spring of hundreds of newtons
        that grows with every centimetre driven (seen on the operator console's trace).
        """
        if self.mode == "kinematic":
            self._quasi_static_sensors()
        f, t = self._ft_adr
        return self.data.sensordata[f : f + 3].copy(), self.data.sensordata[t : t + 3].copy()

    def _quasi_static_sensors(self) -> None:
        """The acceleration-stage sensors (the F/T pair) with every joint held: qacc = 0."""
        held = self.data.qacc.copy()
        self.data.qacc[:] = 0.0
        self._mujoco.mj_rnePostConstraint(self.model, self.data)
        self._mujoco.mj_sensorAcc(self.model, self.data)
        self.data.qacc[:] = held

    # ---------------------------------------------------------------------------------- control

    def step_velocity(
        self,
        twist_or_velocity: object,
        dt_s: float,
        *,
        additional_task_rate: float = 0.0,
        frame: str = "world",
    ) -> ArmStep:
        """Cartesian velocity control for one period (seed Fig. 4: the velocity command into Configuration
        Control).

        Parameters
        ----------
        twist_or_velocity : ndarray of shape (6,) or (3,)
            ``[v (m/s), omega (rad/s)]`` of the tool tip, or ``v`` alone (orientation held).
        dt_s : float
            Period, > 0 s (44 Hz: 1/44). In ``"servo"`` mode, a whole number of 2 ms physics steps is run.
        additional_task_rate : float
            Arm-angle rate, rad/s (0 holds the arm angle).
        frame : {"world", "tool"}
            Frame of ``twist_or_velocity`` (``"tool"``: z along the tool axis, toward the surface).

        Returns
        -------
        ArmStep

        Notes
        -----
        Closed-loop (CLIK) form: references for the tool position, orientation and arm angle advance with
        the command, and the resolved task velocity adds ``position_gain / dt`` times the error to them, so
        integration errors do not accumulate. References are held within 2 mm / 0.02 rad of the actual
        pose, so a command blocked by a limit does not wind up.
        """
        command = v.as_float_array(twist_or_velocity, "twist_or_velocity")
        if command.shape not in ((3,), (6,)) or not np.all(np.isfinite(command)):
            raise InputError(
                f"twist_or_velocity must be 3 (v, m/s) or 6 (v m/s, omega rad/s) finite numbers; "
                f"got {command!r}."
            )
        dt = v.in_range(dt_s, "dt_s", low=0.0, high=1.0, low_inclusive=False)
        rate = v.finite_number(additional_task_rate, "additional_task_rate")
        frame = v.choice(frame, "frame", ("world", "tool"))
        twist = np.concatenate([command, np.zeros(3)]) if command.shape == (3,) else command.copy()
        position, rotation = self.tool_pose()
        if frame == "tool":
            twist = np.concatenate([rotation @ twist[:3], rotation @ twist[3:]])

        # seed §1 [9]: the task velocity is the command plus a proportional correction of the error to the
        # references (closed-loop inverse kinematics); gain 1 is dead-beat: x_ref(t + dt) is reached.
        k = self.position_gain / dt
        psi = self.arm_angle_rad()
        task = np.concatenate(
            [
                twist[:3] + k * (self._ref_position - position),
                twist[3:] + k * orientation_error(self._ref_rotation, rotation),
            ]
        )
        psi_error = float(np.angle(np.exp(1j * (self._ref_arm_angle - psi))))
        # the references advance with the command
        self._ref_position = self._ref_position + twist[:3] * dt
        self._ref_rotation = _rotate(twist[3:] * dt) @ self._ref_rotation
        self._ref_arm_angle = self._ref_arm_angle + rate * dt
        q = self.joint_positions
        resolution = resolve_joint_rates(
            self.jacobian(),
            task,
            joint_positions=np.clip(q, LIMITS.lower, LIMITS.upper),
            limits=LIMITS,
            dt_s=dt,
            additional_jacobian=self.arm_angle_jacobian(),
            additional_velocity=rate + k * psi_error,
            settings=self.settings,
        )
        dq = resolution.joint_velocity
        if self.mode == "kinematic":
            self.data.qpos[self._qpos] = np.clip(q + dq * dt, LIMITS.lower, LIMITS.upper)
            self.data.qvel[self._dof] = dq
            self._mujoco.mj_forward(self.model, self.data)
        else:
            self._servo(dq, dt)
        self.time_s += dt
        position, rotation = self.tool_pose()
        psi = self.arm_angle_rad()
        self._ref_position = position + _clip_norm(self._ref_position - position, 0.002)
        self._ref_rotation = (
            _rotate(_clip_norm(orientation_error(self._ref_rotation, rotation), 0.02)) @ rotation
        )
        self._ref_arm_angle = psi + float(np.clip(self._ref_arm_angle - psi, -0.02, 0.02))
        return ArmStep(
            joint_velocity=dq,
            rate_scale=resolution.rate_scale,
            damping=resolution.damping,
            locked=resolution.locked,
            tool_position_m=position,
            arm_angle_rad=psi,
        )

    def _servo(self, dq: FloatArray, dt: float) -> None:
        steps = max(1, round(dt / float(self.model.opt.timestep)))
        joints = self._ctrl[:8]
        gains = self.model.actuator_gainprm[joints, 0]
        kv = -self.model.actuator_biasprm[joints, 2]
        start = self._target_q.copy()
        for index in range(1, steps + 1):
            target = np.clip(start + dq * dt * index / steps, LIMITS.lower, LIMITS.upper)
            # velocity feed-forward: kp (u - q) - kv qdot = kp (target - q) + kv (dq - qdot)
            self.data.ctrl[joints] = target + kv / gains * dq
            self._mujoco.mj_step(self.model, self.data)
        self._target_q = np.clip(start + dq * dt, LIMITS.lower, LIMITS.upper)
        self._mujoco.mj_forward(self.model, self.data)


def _rotate(rotation_vector: FloatArray) -> FloatArray:
    """Rotation matrix of a rotation vector (Rodrigues)."""
    angle = float(np.linalg.norm(rotation_vector))
    if angle < 1e-15:
        return np.eye(3)
    axis = rotation_vector / angle
    skew = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    result: FloatArray = np.eye(3) + np.sin(angle) * skew + (1 - np.cos(angle)) * skew @ skew
    return result


def _clip_norm(vector: FloatArray, limit: float) -> FloatArray:
    norm = float(np.linalg.norm(vector))
    result: FloatArray = vector if norm <= limit else vector * (limit / norm)
    return result


# ------------------------------------------------------------------------------------- tracking


@dataclass(frozen=True)
class TrackingResult:
    """Figures of :func:`track_path`.

    Attributes
    ----------
    path : str
    arm_tracking_error_m : float
        Largest distance between the tool tip and the path point at the control instants, m.
    additional_task_error_deg : float
        Largest deviation of the arm angle from its set value, degrees (edge figure for the JSON report).
    orientation_error_rad : float
        Largest tool orientation error, rad.
    duration_s : float
    max_rate_ratio : float
        Largest ``|dq| / max_rate`` seen (<= 1).
    """

    path: str
    arm_tracking_error_m: float
    additional_task_error_deg: float
    orientation_error_rad: float
    duration_s: float
    max_rate_ratio: float


PATHS = ("line", "circle")
MAX_RATE_HZ = 1000.0  # a joint servo's bandwidth; seed §3.1 runs the proximity loop at 44 Hz
MAX_TRACK_STEPS = 100_000  # ~40 min of path at 44 Hz: far beyond any path of track_path


def _path_point(path: str, s_m: float, start: FloatArray) -> FloatArray:
    if path == "line":
        # 0.3 m diagonal: along the rail, toward the surface and up at once (all joints work)
        direction: FloatArray = np.array([1.0, 0.5, 0.5]) / np.linalg.norm([1.0, 0.5, 0.5])
        return start + s_m * direction
    # circle of radius 0.1 m in the plane normal to the home tool axis (a scan parallel to a surface),
    # starting and ending at the start point
    radius = 0.1
    angle = s_m / radius
    return start + radius * np.array([np.cos(angle) - 1.0, 0.0, np.sin(angle)])


def track_path(
    path: str = "circle",
    *,
    speed_m_s: float = 0.1,
    rate_hz: float = PROXIMITY_SAMPLE_RATE_HZ,
    mode: str = "kinematic",
    arm_angle_set_rad: float | None = None,
) -> TrackingResult:
    """Drive the tool along a named Cartesian path at constant speed, orientation and arm angle held.

    Parameters
    ----------
    path : {"line", "circle"}
        ``"line"``: 0.3 m along (1, 0.5, 0.5)/|.|; ``"circle"``: radius 0.1 m in the world x-z plane (normal
        to the home tool axis).
    speed_m_s : float
        Path speed, > 0 m/s.
    rate_hz : float
        Control rate, > 0 Hz (seed §3.1: 44 Hz).
    mode : {"kinematic", "servo"}
    arm_angle_set_rad : float, optional
        Arm angle to hold (default: the home pose's, 0 rad). The arm first moves there.

    Returns
    -------
    TrackingResult
    """
    name = v.choice(path, "path", PATHS)
    speed = v.in_range(speed_m_s, "speed_m_s", low=0.0, low_inclusive=False)
    hz = v.in_range(rate_hz, "rate_hz", low=0.0, high=MAX_RATE_HZ, low_inclusive=False)
    length = 0.3 if name == "line" else 2 * np.pi * 0.1
    if length / speed * hz > MAX_TRACK_STEPS:  # a slow path at a fast rate is a run of hours
        raise InputError(
            f"speed_m_s={speed_m_s!r} and rate_hz={rate_hz!r} ask for {length / speed * hz:.3g} control "
            f"steps, over {MAX_TRACK_STEPS}: raise speed_m_s or lower rate_hz."
        )
    arm = Arm(mode=mode)
    dt = 1.0 / hz
    if arm_angle_set_rad is not None:
        set_psi = v.finite_number(arm_angle_set_rad, "arm_angle_set_rad")
        # swivel the elbow to the set value, tool held (the additional task alone moves)
        for _ in range(int(hz * 5)):
            error = float(np.angle(np.exp(1j * (set_psi - arm.arm_angle_rad()))))
            if abs(error) < 1e-10:
                break
            arm.step_velocity(np.zeros(6), dt, additional_task_rate=float(np.clip(error / dt, -0.5, 0.5)))
    psi_set = arm.arm_angle_rad()
    arm.reset(arm.joint_positions)
    start, rotation0 = arm.tool_pose()
    steps = int(np.ceil(length / speed * hz))
    worst_position = worst_angle = worst_orientation = worst_rate = 0.0
    for k in range(steps):
        s_now = min(k * dt * speed, length)
        s_next = min((k + 1) * dt * speed, length)
        # feed-forward: the exact chord to the next path point
        velocity = (_path_point(name, s_next, start) - _path_point(name, s_now, start)) / dt
        step = arm.step_velocity(velocity, dt)
        position, rotation = arm.tool_pose()
        worst_position = max(
            worst_position, float(np.linalg.norm(position - _path_point(name, s_next, start)))
        )
        worst_angle = max(worst_angle, abs(float(np.angle(np.exp(1j * (step.arm_angle_rad - psi_set))))))
        worst_orientation = max(
            worst_orientation, float(np.linalg.norm(orientation_error(rotation0, rotation)))
        )
        worst_rate = max(worst_rate, float(np.max(np.abs(step.joint_velocity) / LIMITS.max_rate)))
    return TrackingResult(
        path=name,
        arm_tracking_error_m=worst_position,
        additional_task_error_deg=float(np.degrees(worst_angle)),
        orientation_error_rad=worst_orientation,
        duration_s=steps * dt,
        max_rate_ratio=worst_rate,
    )
