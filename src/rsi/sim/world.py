"""Seed §4: the World, a seeded mock-up with its anomalies, lamp, end-effector camera and frames.

dm_control's Physics role: state (lamp, door, halogen lamps, time), named read-outs, rendering. Randomness
comes from one seed split into independent streams (anomalies, viewpoint errors, camera noise), so the same
seed and the same calls give the same frames bit for bit.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from typing import TYPE_CHECKING, Any

import cv2
import numpy as np
from numpy.typing import NDArray

from rsi import _validate as v
from rsi._seeds import SeedLike, keyed, seed_number, seed_sequence
from rsi.errors import InputError
from rsi.imaging.camera import DEFAULT_CAMERA, CameraModel, Frame, expose
from rsi.sim import fields
from rsi.sim.anomalies import AnomalySet, AnomalySettings, seed_anomalies
from rsi.sim.arm import RANGEFINDER_RECESS_M, WORLD_ARM_PREFIX, Arm
from rsi.sim.mockup import (
    A_FACE_Y_M,
    BAY_M,
    BAYS,
    LAYOUT_NAMES,
    TRUSS_Z0_M,
    VISTA_STANDOFF_M,
    Mockup,
    Vista,
    mockup,
)
from rsi.sim.orbit import (
    FLASH_S,
    LAB_SUN_FRACTION,
    ORBIT_EXPOSURE_S,
    SCENE_AREA_M2,
    STROBE_LM_S,
    SUN_ILLUMINANCE_LUX,
    compensating_exposure,
)
from rsi.sim.render import STATES, CadView, CameraPose, SceneRenderer, import_mujoco
from rsi.sim.scene import (
    CAMERA_FOVY_DEG,
    HALOGEN_LEVEL,
    LIGHT_GROUPS,
    MAX_RENDER_PX,
    REFERENCE_DISTANCE_M,
    STROBE_LEVEL,
    SUN_LEVEL,
    SceneIndex,
    build_model,
)
from rsi.sim.solar_simulator import (
    LampConfiguration,
    LampTask,
    forward_kinematics,
    inverse_kinematics,
    lamp_pose,
)

F32 = NDArray[np.float32]
BoolArray = NDArray[np.bool_]

if TYPE_CHECKING:
    from rsi.sensors.gas import GasReadings, MosGasSensor
    from rsi.sensors.pyrometer import Pyrometer, PyrometerReading
    from rsi.sim.anomalies import Site

SCENES = LAYOUT_NAMES  # the mock-up's layouts (rsi.sim.mockup.LAYOUTS): "truss", "truss-b"
# Seed §2.3 viewpoint repeatability, as the image shift it causes at the vista's standoff: the lab arm
# returns within 1-2 px; in orbit arm flexibility and thermal expansion give about 10 px.
REPEATABILITY_PX: dict[str, tuple[float, float]] = {"lab": (1.0, 2.0), "space": (8.0, 12.0)}
LAB_LAMP_LUX = LAB_SUN_FRACTION * SUN_ILLUMINANCE_LUX  # seed §4.1: 1.5 % of sunlight, 1950 lux
MAX_STROBE_ENERGY = 8.0  # a xenon strobe's discharge spans about three stops
MAX_EXPOSURE_S = 1.0  # 10**4 seed shutters (seed §2.1: 1/10000 s); any scene saturates long before
MIN_SHUTTER = FLASH_S / ORBIT_EXPOSURE_S  # 0.2: a shorter shutter would cut the flash itself
STROBE_LUX_S = STROBE_LM_S / SCENE_AREA_M2  # seed §2.1: 1.3 lm s over 0.1 m^2 at the inspection standoff
HALOGEN_LUX = 1500.0  # end-effector lamps' regulated illuminance at the standoff (rsi.sensors.LampController)
# seed §2.2: a continuous light's basis image lights the strobe-lit and the unlit field alike, so its 8-bit
# rounding cancels in the compensated image; rendered at half its level it clips (and takes the renderer's
# dimmer second render, rsi.sim.render) only on a glint past twice the lamp's full light
AMBIENT_RENDER_LEVEL = 0.5
DEFAULT_SIZE = (480, 640)  # the seed's video frame
# Issue 4: the arm on its rail in the same world, rail along the truss (x) and centred on it. At home the
# ISEE's cameras and rangefinders (on the housing face, RANGEFINDER_RECESS_M behind the jaw tips) stand the
# vistas' 0.5 m off the front-most face (ORU A, as far forward on every layout). ARM_HOME_TOOL_TIP_M is the
# seed layout's ("truss": looking at the B tank, whose front is as far forward); arm_home_tool_tip_m(mockup)
# gives any layout's (issue 15: the rail follows the truss).
ARM_HOME_TOOL_TIP_M = (
    BAY_M * BAYS / 2,
    A_FACE_Y_M - (VISTA_STANDOFF_M - RANGEFINDER_RECESS_M),
    TRUSS_Z0_M + BAY_M / 2,
)
_LAMP_AIM_Y_M = -0.47  # the lamp's first spot: on the ORUs' front faces
TOOL_VIEW = "tool"  # View.vista of a frame from the arm's ISEE camera
_TRUTH_DEPTH_TOLERANCE_M = 5e-3
# What the joint encoders leave unknown of a commanded camera pose: a 17-bit absolute encoder resolves
# 2 pi / 2**17 = 48 urad per joint, and six joints over the arm's ~1 m reach put ~0.1 mm and ~0.1 mrad at the
# camera. Flexure and thermal growth (seed §2.3) are outside the encoders and stay in the visit's error.
ENCODER_POSITION_SIGMA_M = 1e-4
# how far the pyrometer's laser-sighted spot misses its aim: the arm's repeatability at the tool
_PYROMETER_MISS_M = {"lab": (0.0, 1e-3), "space": (2e-3, 6e-3)}
ENCODER_ANGLE_SIGMA_RAD = 1e-4
_MARKER_COLOURS = {
    "hot_spot": (255, 64, 32),
    "cold_spot": (64, 160, 255),
    "gas_leak": (64, 255, 64),
    "missing_screw": (255, 200, 0),
    "impact": (255, 0, 255),
    "swapped_component": (255, 128, 0),
}


@dataclass(frozen=True)
class View:
    """One visit of a vista point: the camera frame, its light basis, depth and ground truth.

    Attributes
    ----------
    vista : str
        Vista name.
    state : {"inspection", "reference"}
        Whether the anomalies were present ("reference" is the pristine mock-up, seed §2.3).
    frame : Frame
        Interlaced 8-bit frame, strobe in ``frame.lit_field`` (seed §2.1-2.2).
    basis : dict of str to ndarray of shape (M, N), float32
        Luminance of each light group alone, in render units 0..255 (see :mod:`rsi.sim.render`).
    ambient_lux : ndarray of shape (M, N), float32
        Reflectance-weighted ambient illuminance given to the camera model.
    strobe_lux_s : ndarray of shape (M, N), float32
        Reflectance-weighted strobe exposure given to the camera model.
    depth_m : ndarray of shape (M, N), float32, or None
        Distance along the viewing axis (the far plane where nothing is hit); None from ``truth=False``.
    flaw_masks : dict of int to ndarray of shape (M, N), bool
        Index into ``World.anomalies.anomalies`` -> pixels showing that anomaly; only visible ones (empty
        for the reference state and from ``truth=False``).
    pose : CameraPose
        The camera actually used (the vista plus this visit's error).
    pose_error_px : (float, float)
        Image shift (x = col, y = row) of the vista's target plane caused by this visit's pose error.
    stereo : tuple of Frame or None
        Left and right frames (baseline :data:`rsi.sim.scene.STEREO_BASELINE_M`) when asked for.
    truss_mask : ndarray of shape (M, N), bool, or None
        Pixels showing the truss frame (longerons, battens, nodes, diagonals) or the robot's own arm rather
        than a component: what a robot's CAD model and its joint angles, projected with the known pose,
        tell it is not the inspected surface. None from ``truth=False``.
    component_masks : dict of str to ndarray of shape (M, N), bool
        Pixels of each swappable component in view (``Mockup.components``, its replacement included), from
        the same CAD projection; decals on it (impact spots) are not its pixels. Empty from ``truth=False``.
    believed_pose : CameraPose
        The pose the robot believes it took the frame from: the commanded pose read through its joint
        encoders (:data:`ENCODER_POSITION_SIGMA_M`, :data:`ENCODER_ANGLE_SIGMA_RAD`). The flexure and
        thermal part of the visit's error (``repeatability``) is not in it (seed §2.3): registration must
        find it.
    carried : bool
        Whether the arm's ISEE took the frame (:meth:`World.render_from_tool`): its own housing and jaws
        are then in the frame wherever its camera looks. False for the free camera of :meth:`World.render`
        (the arm's fallback where it cannot reach a vista), which carries no body.
    """

    vista: str
    state: str
    frame: Frame
    basis: dict[str, F32]
    ambient_lux: F32
    strobe_lux_s: F32
    depth_m: F32 | None
    flaw_masks: dict[int, BoolArray]
    pose: CameraPose
    pose_error_px: tuple[float, float]
    stereo: tuple[Frame, Frame] | None = field(default=None)
    truss_mask: BoolArray | None = field(default=None, repr=False)
    component_masks: dict[str, BoolArray] = field(default_factory=dict, repr=False)
    believed_pose: CameraPose | None = field(default=None, repr=False)
    carried: bool = field(default=False)

    @property
    def flaw_mask(self) -> BoolArray:
        """Union of every visible anomaly's mask."""
        union = np.zeros(self.frame.raw.shape, dtype=bool)
        for mask in self.flaw_masks.values():
            union |= mask
        return union


def _rotation(forward: NDArray[np.float64], up: NDArray[np.float64]) -> NDArray[np.float64]:
    """Camera rotation: columns right, up, backward (MuJoCo cameras look along -z)."""
    back = -forward / np.linalg.norm(forward)
    right = np.cross(up, back)
    right /= np.linalg.norm(right)
    return np.column_stack([right, np.cross(back, right), back])


class World:
    """A seeded truss mock-up: state, read-outs, frames and fields (seed §4).

    Build it with :func:`load`. Rendering starts an OpenGL context on first use (see :mod:`rsi.sim.render`).
    ``grid_meshes=False`` builds a world for rays, reach or live video (:func:`load`).
    """

    def __init__(
        self,
        mockup: Mockup,
        anomalies: AnomalySet,
        *,
        seed: SeedLike,
        repeatability: str = "lab",
        camera: CameraModel = DEFAULT_CAMERA,
        arm: bool = False,
        grid_meshes: bool = True,
    ) -> None:
        self._mujoco: Any = import_mujoco()
        _check_build(repeatability, camera, arm)
        v.instance_of(mockup, "mockup", Mockup, none_allowed=False)
        v.instance_of(anomalies, "anomalies", AnomalySet, none_allowed=False)
        self.mockup = mockup
        self.anomalies = anomalies
        self.repeatability = v.choice(repeatability, "repeatability", REPEATABILITY_PX)
        self.camera = camera
        self.seed = seed_number(seed)
        # the world's own streams, spawned once from its seed: viewpoint errors and camera noise
        self._streams = seed_sequence(seed)
        self._start_streams(self._streams)
        model, index = build_model(
            mockup,
            anomalies,
            arm_home_tool_tip_m=arm_home_tool_tip_m(mockup) if arm else None,
            grid_meshes=grid_meshes,
        )
        self.model: Any = model
        self.index: SceneIndex = index
        self.data: Any = self._mujoco.MjData(model)
        self._arm = Arm.bind(model, self.data, prefix=WORLD_ARM_PREFIX) if arm else None
        self.time_s = 0.0
        self.halogen_on = False
        self.strobe_energy = 1.0
        self.shutter = 1.0
        self.lamp_on = True
        self._renderers: dict[tuple[tuple[int, int], bool], SceneRenderer] = {}
        self.fast_rendering = False
        self._lights = {
            group: [self._id("light", name) for name in names] for group, names in LIGHT_GROUPS.items()
        }
        # the frame the components hang on (seed §4): longerons, battens, nodes, diagonals
        self._truss_geoms = [
            self._id("geom", part.name) for part in mockup.parts if part.component == "truss"
        ] + self._arm_geoms()
        self._component_geoms = self._swappable_geoms()
        middle, _, height = mockup.centre_m
        centre = (middle, _LAMP_AIM_Y_M, height)  # front of the truss's middle
        # seed §4.1: the pan range (theta 90-180 deg) puts the lamp on the +x side of its spot
        self.lamp = inverse_kinematics(centre, intensity_lux=LAB_LAMP_LUX, rail_m=2.0)
        self.set_lamp(self.lamp)

    def _swappable_geoms(self) -> dict[str, list[int]]:
        """Geoms of each swappable component: its parts, their replacements and a dent's facet."""
        swaps = {
            index: anomaly.site
            for index, anomaly in enumerate(self.anomalies.anomalies)
            if anomaly.kind == "swapped_component"
        }
        geoms: dict[str, list[int]] = {}
        for site, parts in self.mockup.components.items():
            names = [*parts, *(f"{part}_swapped" for part in parts)]
            names += [
                name
                for index, replacement in self.index.flaw_geoms.items()
                if swaps.get(index) == site
                for name in replacement
            ]
            geoms[site] = sorted({self._id("geom", name) for name in names} - {-1})
        return geoms

    def _arm_geoms(self) -> list[int]:
        """Geoms of the robot's own arm and rail (bodies named with the arm's prefix), if it is loaded."""
        from rsi.sim.arm import WORLD_ARM_PREFIX

        model = self.model
        bodies = {
            body
            for body in range(model.nbody)
            if (self._mujoco.mj_id2name(model, self._mujoco.mjtObj.mjOBJ_BODY, body) or "").startswith(
                WORLD_ARM_PREFIX
            )
        }
        return [geom for geom in range(model.ngeom) if int(model.geom_bodyid[geom]) in bodies]

    # ------------------------------------------------------------------------------------------ state

    def _id(self, kind: str, name: str) -> int:
        obj = getattr(self._mujoco.mjtObj, f"mjOBJ_{kind.upper()}")
        return int(self._mujoco.mj_name2id(self.model, obj, name))

    @property
    def has_arm(self) -> bool:
        """Whether this world holds the arm (``load(..., arm=True)``)."""
        return self._arm is not None

    @property
    def arm(self) -> Arm:
        """The K1207-style arm on its rail carrying the ISEE, in this world's model and data (issue 4).

        The same :class:`rsi.sim.arm.Arm` as standalone (``reset``, ``tool_pose``, ``jacobian``,
        ``rangefinder_distances_m``, ``step_velocity``, ...), kinematic mode; its rangefinders see the
        mock-up. Only in a world from ``load(..., arm=True)``.
        """
        if self._arm is None:
            raise InputError(
                "this world has no arm; build it with rsi.sim.load(layout, seed=..., arm=True), the layout "
                f"one of {', '.join(SCENES)}."
            )
        return self._arm

    @property
    def vistas(self) -> tuple[str, ...]:
        """Names of the vista points."""
        return tuple(self.mockup.vistas)

    def add_vista(self, point: Vista) -> None:
        """Add a vista point to this world (a mission's plan may need views the mock-up does not list).

        Raises InputError for a non-Vista or a name already taken (the mock-up's vistas are fixed).
        """
        if not isinstance(point, Vista):
            raise InputError(f"point must be an rsi.sim.mockup.Vista; got {type(point).__name__}.")
        if point.name in self.mockup.vistas:
            raise InputError(f"vista {point.name!r} already exists in this world; choose another name.")
        self.mockup = replace(self.mockup, vistas={**self.mockup.vistas, point.name: point})

    def vista(self, name: str) -> Vista:
        """The vista point called `name` (InputError listing the names otherwise)."""
        return self.mockup.vistas[v.choice(name, "vista", self.mockup.vistas)]

    @property
    def lamp_task(self) -> LampTask:
        """Spot centre, beam half-angle and intensity the lamp now gives (seed §4.1 forward kinematics)."""
        return forward_kinematics(self.lamp)

    def set_lamp(self, configuration: LampConfiguration) -> None:
        """Pose the solar-simulator lamp by its kinematics and set its beam (seed §4.1).

        Parameters
        ----------
        configuration : LampConfiguration
            ``(rho, theta, phi, lambda, gamma)``; the lamp body follows :func:`lamp_pose`, the spot light's
            cutoff is the beam half-angle and its level the intensity at the spot centre.
        """
        task = forward_kinematics(configuration)
        pose = lamp_pose(configuration)
        head = pose.rotation_world_from_head
        beam, pan = head[:, 0], head[:, 1]
        # the light shines along the body's -z: body axes (o, o x n, -n) with n the beam axis
        rotation = np.column_stack([pan, np.cross(pan, beam), -beam])
        body = self._id("body", "solar_lamp")
        mocap = int(self.model.body_mocapid[body])
        self.data.mocap_pos[mocap] = pose.position_world_m
        self._mujoco.mju_mat2Quat(self.data.mocap_quat[mocap], rotation.ravel())
        light = self._id("light", "solar_lamp")
        self.model.light_cutoff[light] = math.degrees(task.beam_angle_rad)
        # 1/rho^2 fall-off, with the level SUN_LEVEL at the spot centre
        self.model.light_attenuation[light] = (0.0, 0.0, 1.0 / configuration.rho_m**2)
        self.lamp = configuration
        # the renderer reads the light's world pose from data, which only kinematics updates from the mocap
        self._mujoco.mj_forward(self.model, self.data)

    def aim_lamp(
        self, spot_world_m: object, *, light_from: object, intensity_lux: float = LAB_LAMP_LUX
    ) -> None:
        """Point the lamp at a spot, light arriving from `light_from`, at `intensity_lux` (seed §4.1 IK)."""
        self.set_lamp(inverse_kinematics(spot_world_m, intensity_lux=intensity_lux, light_from=light_from))

    def switch_lamp(self, on: bool) -> None:
        """Switch the solar-simulator lamp (seed §4.1: off while the orbit is in the Earth's shadow).

        Off, frames get neither the lamp nor the room light it scatters, only the ISEE's own lights; the
        shutter keeps the lamp's compensating exposure (seed §2.1).
        """
        if not isinstance(on, bool):
            raise InputError(f"on must be True or False; got {on!r}.")
        self.lamp_on = on

    def set_door(self, angle_rad: float) -> None:
        """Open the electrical ORU's door by `angle_rad` in [0, 1.92] (0 = closed): shows connectors and cold
        plate. It swings out towards the robot (-y) about its hinge, on whichever edge the layout put it."""
        door = self.mockup.door
        angle = v.in_range(angle_rad, "angle_rad", low=0.0, high=door.max_angle_rad)
        self.data.qpos[self.model.jnt_qposadr[self._id("joint", door.joint)]] = angle
        self._mujoco.mj_forward(self.model, self.data)  # the door's geoms follow qpos only after kinematics

    @property
    def door_angle_rad(self) -> float:
        """Opening angle of the electrical ORU's door."""
        return float(self.data.qpos[self.model.jnt_qposadr[self._id("joint", self.mockup.door.joint)]])

    def set_strobe_energy(self, factor: float) -> None:
        """Flash energy of the ISEE strobe as a multiple of the seed's 1.3 lm s (seed §2.1), in [0.1, 8].

        A xenon strobe's energy is set by its discharge; dark surfaces (solar cells, Kapton) take more so
        that their strobe image rises above the camera's read noise and quantisation.
        """
        self.strobe_energy = v.in_range(factor, "factor", low=0.1, high=MAX_STROBE_ENERGY)

    def set_shutter(self, fraction: float) -> None:
        """Electronic shutter as a fraction of the seed's 1/10000 s, in [MIN_SHUTTER, 1] (seed §2.1).

        The ~20 us flash fits in any shutter down to its own length, so a shorter shutter takes the same
        strobe light and less sunlight: a sunlit surface that saturates the frame at the seed's shutter
        (strobe plus ambient beyond the top DN) is measured again. The lab keeps the orbit's ratio: the
        fraction scales the lamp's compensating exposure (:func:`rsi.sim.orbit.compensating_exposure`).
        """
        self.shutter = v.in_range(fraction, "fraction", low=MIN_SHUTTER, high=1.0)

    def set_halogen(self, on: bool) -> None:
        """Switch the end-effector halogen lamps (seed §3); they add to the ambient term of every frame."""
        if not isinstance(on, bool):
            raise InputError(f"on must be True or False; got {on!r}.")
        self.halogen_on = on

    def place_camera(self, position_m: object, forward: object, up: object = (0.0, 0.0, 1.0)) -> None:
        """Move the end-effector camera (with its strobe and lamps) and update the read-outs."""
        position = np.array(v.vector3(position_m, "position_m"))
        look, top = v.direction3(forward, "forward"), v.direction3(up, "up")
        if np.linalg.norm(np.cross(look, top)) < 1e-9:  # no image 'right' from two parallel directions
            raise InputError(f"up={up!r} is parallel to forward={forward!r}; give an up across the view.")
        rotation = _rotation(look, top)
        mocap = int(self.model.body_mocapid[self._id("body", "isee")])
        self.data.mocap_pos[mocap] = position
        self._mujoco.mju_mat2Quat(self.data.mocap_quat[mocap], rotation.ravel())
        self._mujoco.mj_forward(self.model, self.data)

    def readouts(self) -> dict[str, float]:
        """Named read-outs.

        ``standoff_m`` (rangefinder along the view axis, -1 = no return), ``door_angle_rad``,
        ``lamp_intensity_lux`` and ``time_s``.
        """
        self._mujoco.mj_forward(self.model, self.data)
        return {
            "standoff_m": float(self.data.sensor("isee_range").data[0]),
            "door_angle_rad": self.door_angle_rad,
            "lamp_intensity_lux": self.lamp_task.intensity_lux if self.lamp_on else 0.0,
            "time_s": self.time_s,
        }

    # ------------------------------------------------------------------------------------------ fields

    def temperature_k(self, points_m: object) -> NDArray[np.float64]:
        """Surface temperature at world points (seed §4: ambient plus the active Peltier spots)."""
        return fields.surface_temperature_k(points_m, self.anomalies)

    def gas_concentration_ppm(self, points_m: object, time_s: object) -> NDArray[np.float64]:
        """Ammonia concentration at world points and times from the active leaks (seed §4)."""
        return fields.gas_concentration_ppm(points_m, time_s, self.anomalies)

    def read_pyrometer(
        self, site: Site, *, standoff_m: float, pyrometer: Pyrometer, rng: np.random.Generator
    ) -> PyrometerReading:
        """The ISEE pyrometer aimed at `site` from `standoff_m` (seed §3-4): one reading of its spot.

        The laser-sighted spot misses the site by the arm's repeatability (drawn here: the robot does not
        know it), and the optics average the radiance over the spot: one reading of its mean temperature
        and emissivity, through the instrument's model (:func:`rsi.sensors.pyrometer.read_pyrometer`).
        """
        from rsi.sensors.pyrometer import Pyrometer, read_pyrometer
        from rsi.sim.anomalies import Site

        v.instance_of(site, "site", Site, none_allowed=False)
        v.instance_of(pyrometer, "pyrometer", Pyrometer, none_allowed=False)
        v.instance_of(rng, "rng", np.random.Generator, none_allowed=False)
        standoff = v.in_range(standoff_m, "standoff_m", low=0.0)
        low, high = _PYROMETER_MISS_M[self.repeatability]
        normal = np.asarray(site.normal)
        u = np.cross(normal, (0.0, 0.0, 1.0))
        u = u / np.linalg.norm(u) if np.linalg.norm(u) > 1e-9 else np.array([1.0, 0.0, 0.0])
        w = np.cross(normal, u)
        miss, angle = rng.uniform(low, high), rng.uniform(0.0, 2 * math.pi)
        centre = np.asarray(site.position_m) + miss * (math.cos(angle) * u + math.sin(angle) * w)
        radius = 0.5 * float(pyrometer.spot_diameter_m(standoff))
        radii, angles = np.meshgrid(np.linspace(0.0, radius, 4), np.linspace(0, 2 * math.pi, 8))
        points = centre + radii.reshape(-1, 1) * (
            np.cos(angles).reshape(-1, 1) * u + np.sin(angles).reshape(-1, 1) * w
        )
        temperature = float(np.mean(self.temperature_k(points)))
        kapton = self.mockup.candidates.peltier_sites
        eps = float(np.mean(fields.emissivity(points, site.surface, kapton_sites=kapton)))
        return read_pyrometer(temperature, eps, pyrometer, rng=rng)

    def read_gas(
        self, points_m: object, time_s: object, *, sensor: MosGasSensor, rng: np.random.Generator
    ) -> GasReadings:
        """The ISEE's MOS gas sensor sampled at world points and times (seed §3 H), through its model."""
        from rsi.sensors.gas import read_gas

        return read_gas(self.gas_concentration_ppm(points_m, time_s), sensor, rng=rng)

    # ------------------------------------------------------------------------------------------ frames

    def set_fast_rendering(self, on: bool) -> None:
        """Render live video (no shadow map, no multisampling; :class:`rsi.sim.render.SceneRenderer`).

        For a live view (the operator console) only: the lamp's shadows go, so frames for inspection keep
        the default (False).
        """
        if not isinstance(on, bool):
            raise InputError(f"on must be True or False; got {on!r}.")
        self.fast_rendering = on

    def _renderer(self, shape: tuple[int, int]) -> SceneRenderer:
        key = (shape, self.fast_rendering)
        if key not in self._renderers:
            self._renderers[key] = SceneRenderer(self.model, *shape, fast=self.fast_rendering)
        return self._renderers[key]

    def basis(
        self, camera: str = "isee", *, size: tuple[int, int] = DEFAULT_SIZE, state: str = "inspection"
    ) -> dict[str, F32]:
        """Luminance of each light group alone (float32 render units: 255 is a lit colour of 1, glare reads
        past it) from the current camera pose."""
        renderer = self._renderer(frame_size(size))
        return {
            group: renderer.luminance(
                self.data, camera, state=state, lights=tuple(ids), level=self._render_level(group)
            )
            for group, ids in self._lights.items()
        }

    def begin_visit(self, key: str) -> None:
        """Draw the next frames' viewpoint error, encoder noise and camera noise from the stream of the
        visit named `key` (:func:`rsi._seeds.keyed` under the world's seed): the same visit gets the same
        draws whatever was rendered before it. Without it, every frame draws on from the one before."""
        self._start_streams(keyed(self._streams, key))

    def _start_streams(self, root: np.random.SeedSequence) -> None:
        poses, noise, encoders = root.spawn(3)
        self._pose_rng = np.random.default_rng(poses)
        self._noise_rng = np.random.default_rng(noise)
        self._encoder_rng = np.random.default_rng(encoders)

    def render_all_lights(self, camera: str = "isee", *, size: tuple[int, int] = DEFAULT_SIZE) -> F32:
        """Luminance with every light group on at once (to check that the basis images add up)."""
        ids = tuple(i for group in self._lights.values() for i in group)
        return self._renderer(frame_size(size)).luminance(self.data, camera, state="inspection", lights=ids)

    def render(
        self,
        vista: str,
        *,
        size: tuple[int, int] = DEFAULT_SIZE,
        state: str = "inspection",
        stereo: bool = False,
        lit_field: str = "odd",
        exposure_s: float | None = None,
        truth: bool = True,
    ) -> View:
        """Visit a vista point and take a frame (seed §2.1-2.3).

        Each call is a new visit: the camera pose misses the vista by an error drawn from this world's
        generator (``repeatability``: "lab" 1-2 px, "space" ~10 px of image shift), so a reference and an
        inspection frame of the same vista are mis-registered as on a real arm.

        Parameters
        ----------
        vista : str
            One of :attr:`vistas`.
        size : (int, int)
            (rows, cols) of the frame, each 16..2048.
        state : {"inspection", "reference"}
            With the anomalies, or the pristine mock-up the references are taken of.
        stereo : bool
            Also take left and right frames with the stereo baseline.
        lit_field : {"odd", "even"}
            Field the strobe lights (seed §2.2).
        exposure_s : float or None
            Shutter; None keeps the orbit's ambient-to-strobe ratio under the lamp's intensity
            (seed §2.1, :func:`rsi.sim.orbit.compensating_exposure`).
        truth : bool
            Also render depth and the segmentation the flaw masks come from: one extra pass, two when the
            anomalies removed pristine geoms (~0.05 s each at 1024x1024 on the CPU). False gives the frame
            alone (``depth_m`` None, ``flaw_masks`` empty) and draws the same visit and noise.

        Returns
        -------
        View
        """
        point = self.vista(vista)
        shape, settings = self._shot_settings(size, state, lit_field, exposure_s, truth)
        forward, up = np.asarray(point.forward), np.asarray(point.up)
        rotation = _rotation(forward, up)
        fovy = math.radians(CAMERA_FOVY_DEG)
        focal = shape[0] / 2 / math.tan(fovy / 2)
        low, high = REPEATABILITY_PX[self.repeatability]
        magnitude, angle = self._pose_rng.uniform(low, high), self._pose_rng.uniform(0.0, 2 * math.pi)
        # a lateral camera offset t shifts the target plane by -t * f / standoff in the image
        offset_px = np.array([math.cos(angle), math.sin(angle)]) * magnitude
        offset_m = offset_px * point.standoff_m / focal
        position = np.asarray(point.position_m) + offset_m[0] * rotation[:, 0] + offset_m[1] * rotation[:, 1]
        self.place_camera(position, forward, up)
        pose = CameraPose(position, rotation, fovy, shape)
        view = self._view(
            vista,
            pose,
            ("isee", "isee", "isee_right"),
            (float(-offset_px[0]), float(offset_px[1])),
            stereo=stereo,
            truth=truth,
            **settings,
        )
        commanded = CameraPose(np.asarray(point.position_m, dtype=np.float64), rotation, fovy, shape)
        return replace(view, believed_pose=self._through_encoders(commanded))

    def render_from_tool(
        self,
        *,
        size: tuple[int, int] = DEFAULT_SIZE,
        state: str = "inspection",
        stereo: bool = False,
        lit_field: str = "odd",
        exposure_s: float | None = None,
        truth: bool = True,
        unsensed_offset_m: tuple[float, float] = (0.0, 0.0),
    ) -> View:
        """Take a frame with the arm's ISEE cameras from where the arm now holds them (issue 4).

        The same pipeline as :meth:`render` (light basis, camera model, depth and truth); the frame is the
        left ISEE camera's (the stereo pair is left and right). The ISEE's calibrated strobe and halogen
        lamps and its view-axis rangefinder (``readouts()["standoff_m"]``) move with it. No visit error
        is drawn: the pose is the arm's (``pose_error_px`` is (0, 0), ``vista`` is ``"tool"``). The
        rangefinder rays are not drawn (seed §2: the frame is what the camera sees). Needs
        ``load(..., arm=True)``; parameters as for :meth:`render`, and `unsensed_offset_m`: the part of the
        camera's (right, up) position that the joint encoders do not see (the flexure and thermal error of
        seed §2.3), left out of ``believed_pose``.

        Returns
        -------
        View
        """
        arm = self.arm
        shape, settings = self._shot_settings(size, state, lit_field, exposure_s, truth)
        offset = v.as_float_array(unsensed_offset_m, "unsensed_offset_m")
        if offset.shape != (2,) or not np.isfinite(offset).all():
            raise InputError(
                "unsensed_offset_m must be two finite numbers (right, up) in metres; "
                f"got {unsensed_offset_m!r}."
            )
        left, rotation = arm.camera_pose("left")
        forward, up = -rotation[:, 2], rotation[:, 1]
        # the ISEE's calibrated lamps, strobe and view-axis rangefinder ride the camera body, placed on the
        # left camera (midway between the cameras it would sit on the gripper's jaw and range 0)
        self.place_camera(left, forward, up)
        pose = CameraPose(left, _rotation(forward, up), math.radians(CAMERA_FOVY_DEG), shape)
        cameras = (arm.camera_name("left"), arm.camera_name("left"), arm.camera_name("right"))
        view = self._view(TOOL_VIEW, pose, cameras, (0.0, 0.0), stereo=stereo, truth=truth, **settings)
        sensed = replace(pose, position_m=pose.position_m - pose.rotation[:, :2] @ offset)
        return replace(view, believed_pose=self._through_encoders(sensed), carried=True)

    def _through_encoders(self, pose: CameraPose) -> CameraPose:
        """`pose` as the joint encoders report it: their quantisation and noise added."""
        position = pose.position_m + self._encoder_rng.normal(0.0, ENCODER_POSITION_SIGMA_M, 3)
        turn, _ = cv2.Rodrigues(self._encoder_rng.normal(0.0, ENCODER_ANGLE_SIGMA_RAD, 3))
        return replace(pose, position_m=position, rotation=turn @ pose.rotation)

    def cad_projection(self, pose: CameraPose, *, own_body: bool = True) -> CadView:
        """The robot's CAD model of the mock-up seen from `pose`: what it expects, not what is there.

        The pristine mock-up (no anomaly: the robot does not know them) with the door and the arm where
        they were commanded, rendered from `pose` (normally a view's ``believed_pose``): its depth, the
        truss frame and arm pixels, and each swappable component's pixels. The camera is put back after.
        `own_body`: the ISEE's housing and jaws where its own camera sees them, for a frame the arm's ISEE
        took (``View.carried``); False for the free camera, whose frame holds no body of its own.
        """
        if not isinstance(pose, CameraPose):
            raise InputError(
                f"pose must be a CameraPose (a View's believed_pose); got {type(pose).__name__}."
            )
        if not isinstance(own_body, bool):
            raise InputError(
                f"own_body must be True or False (whether the arm's ISEE took the frame); got {own_body!r}."
            )
        mocap = int(self.model.body_mocapid[self._id("body", "isee")])
        kept = self.data.mocap_pos[mocap].copy(), self.data.mocap_quat[mocap].copy()
        self.place_camera(pose.position_m, -pose.rotation[:, 2], pose.rotation[:, 1])
        try:
            depth, segments = self._renderer(pose.shape).depth_and_segments(
                self.data, "isee", state="reference"
            )
        finally:
            self.data.mocap_pos[mocap], self.data.mocap_quat[mocap] = kept
            self._mujoco.mj_forward(self.model, self.data)
        if self._arm is not None and own_body:
            depth, segments = self._with_own_body(depth, segments, pose.shape)
        components = {
            site: mask
            for site, ids in self._component_geoms.items()
            if (mask := np.isin(segments, ids)).any()
        }
        return CadView(depth, np.isin(segments, self._truss_geoms), components, segments)

    def _with_own_body(
        self, depth: F32, segments: NDArray[np.int32], shape: tuple[int, int]
    ) -> tuple[F32, NDArray[np.int32]]:
        """The model's maps with the ISEE's own body (housing, jaws) where its own camera sees it.

        The jaws are rigid with the camera (seed §3.1): they lie on the same pixels whatever the pose, as
        the robot's calibration knows them. Drawn from the believed pose they would lie off by the pose
        error's parallax at a few centimetres (tens of pixels); the surface they hide there is unknown to
        the model (the far plane: no surface).
        """
        own_ids = self._own_geoms()
        misdrawn = np.isin(segments, own_ids)
        own_depth, own_segments = self._renderer(shape).depth_and_segments(
            self.data, self.arm.camera_name("left"), state="reference"
        )
        own = np.isin(own_segments, own_ids)
        far = np.float32(self.model.vis.map.zfar * self.model.stat.extent)  # where the renderer hits nothing
        depth = np.where(own, own_depth, np.where(misdrawn, far, depth))
        segments = np.where(own, own_segments, np.where(misdrawn, -1, segments))
        return depth.astype(np.float32), segments.astype(np.int32)

    def own_body_footprint(
        self, size: object = (480, 640), *, jaw_opening_m: float | None = None
    ) -> BoolArray:
        """Pixels of the arm's ISEE camera frame that its own housing and jaws hide, at a jaw opening.

        Rigid with the camera whatever the arm's pose (seed §3.1: the cameras and the 11 cm jaws share the
        ISEE), so a calibration the robot knows; only the opening moves the jaws across the frame (0.04 m:
        the right-hand middle rows, 0: the bottom right, 0.08 m: the top right). `jaw_opening_m` None: the
        jaws as they are. The arm's jaws are put back after.
        """
        from rsi.sim.arm import JAW_MAX_OPENING_M

        arm = self.arm
        shape = frame_size(size)
        kept = arm.jaw_opening_m
        if jaw_opening_m is not None:
            arm.set_jaw_opening(v.in_range(jaw_opening_m, "jaw_opening_m", low=0.0, high=JAW_MAX_OPENING_M))
        try:
            _, segments = self._renderer(shape).depth_and_segments(
                self.data, arm.camera_name("left"), state="reference"
            )
        finally:
            arm.set_jaw_opening(kept)
        footprint: BoolArray = np.isin(segments, self._own_geoms())
        return footprint

    def _own_geoms(self) -> list[int]:
        """Geoms of the arm's ISEE body and everything it carries (palm, jaws)."""
        from rsi.sim.arm import WORLD_ARM_PREFIX

        model = self.model
        isee = self._id("body", f"{WORLD_ARM_PREFIX}isee")

        def carried(body: int) -> bool:
            while body > 0:
                if body == isee:
                    return True
                body = int(model.body_parentid[body])
            return False

        return [geom for geom in range(model.ngeom) if carried(int(model.geom_bodyid[geom]))]

    def next_frame(self, view: View, *, lit_field: str = "even") -> Frame:
        """The visit's next video frame: same pose and light, new camera noise, the strobe in `lit_field`.

        Seed §2.2: with the strobe on the other field the two frames together give a full-resolution
        compensated image (:func:`rsi.imaging.compensation.compensate_field_pair`).
        """
        if not isinstance(view, View):
            raise InputError(f"view must be a View from World.render; got {type(view).__name__}.")
        field_name = v.choice(lit_field, "lit_field", ("odd", "even"))
        return expose(
            view.ambient_lux,
            view.strobe_lux_s,
            exposure_s=view.frame.exposure_s,
            camera=self.camera,
            lit_field=field_name,
            rng=self._noise_rng,
        )

    def reflash(self, view: View, *, strobe_energy: float, shutter: float) -> View:
        """The visit's frame taken again from the same pose: the strobe at `strobe_energy` times the seed's
        flash and the shutter at `shutter` times the seed's (seed §2.1); truth and stereo pair kept."""
        if not isinstance(view, View):
            raise InputError(f"view must be a View from World.render; got {type(view).__name__}.")
        energy = v.in_range(
            strobe_energy, "strobe_energy", low=0.0, high=MAX_STROBE_ENERGY, low_inclusive=False
        )
        fraction = v.in_range(shutter, "shutter", low=MIN_SHUTTER, high=1.0)
        energy_now, shutter_now = self.strobe_energy, self.shutter
        flashed = replace(
            view,
            strobe_lux_s=(view.strobe_lux_s * np.float32(energy / energy_now)).astype(np.float32),
            frame=replace(view.frame, exposure_s=view.frame.exposure_s * fraction / shutter_now),
        )
        return replace(flashed, frame=self.next_frame(flashed, lit_field=view.frame.lit_field))

    def other_strobe_frames(self, view: View) -> tuple[Frame, Frame]:
        """The visit's two frames again with the ISEE's other strobe (seed §3 B), below the lens, in the odd
        and then the even field: same pose, shutter and flash energy, new noise (seed §2.5: "selection of
        different illuminator/camera combinations to get more data").

        Taken where the camera now stands: call it before the camera moves on from `view`'s visit.
        """
        if not isinstance(view, View):
            raise InputError(f"view must be a View from World.render; got {type(view).__name__}.")
        camera = self.arm.camera_name("left") if view.carried else "isee"
        basis = self._renderer(view.frame.raw.shape).luminance(
            self.data,
            camera,
            state=view.state,
            lights=tuple(self._lights["other_strobe"]),
            level=self._render_level("other_strobe"),
        )
        strobe = self._strobe_lux_s(basis)
        return tuple(  # type: ignore[return-value]
            expose(
                view.ambient_lux,
                strobe,
                exposure_s=view.frame.exposure_s,
                camera=self.camera,
                lit_field=field_name,
                rng=self._noise_rng,
            )
            for field_name in ("odd", "even")
        )

    def ambient_frame(self, view: View, *, exposure_s: float) -> Frame:
        """The visit's ambient alone over `exposure_s` seconds: a frame from the same pose with no flash
        (seed §2 further work: several shutter settings for the ambient-lit image's dynamic range).

        The camera's electronic shutter runs from the flash's own ~20 us (``MIN_SHUTTER`` of the seed's)
        to one video field; without a flash no shorter bound applies, and :data:`MAX_EXPOSURE_S` bounds
        the longer.
        """
        if not isinstance(view, View):
            raise InputError(f"view must be a View from World.render; got {type(view).__name__}.")
        seconds = v.in_range(exposure_s, "exposure_s", low=0.0, high=MAX_EXPOSURE_S, low_inclusive=False)
        return expose(
            view.ambient_lux,
            np.zeros_like(view.ambient_lux),
            exposure_s=seconds,
            camera=self.camera,
            lit_field="none",
            rng=self._noise_rng,
        )

    def _shot_settings(
        self, size: object, state: str, lit_field: str, exposure_s: float | None, truth: object
    ) -> tuple[tuple[int, int], dict[str, Any]]:
        """Validated frame size and the settings of :meth:`_frame` (render units, lamp intensity, shutter)."""
        shape = frame_size(size)
        v.choice(state, "state", STATES)
        v.choice(lit_field, "lit_field", ("odd", "even"))
        if not isinstance(truth, bool):
            raise InputError(f"truth must be True or False; got {truth!r}.")
        intensity = self.lamp_task.intensity_lux
        seconds = (
            compensating_exposure(intensity).lab_exposure_s * self.shutter
            if exposure_s is None
            else v.in_range(exposure_s, "exposure_s", low=0.0, high=MAX_EXPOSURE_S, low_inclusive=False)
        )
        settings: dict[str, Any] = {
            "state": state,
            "lit_field": lit_field,
            "seconds": seconds,
            "intensity": intensity,
        }
        return shape, settings

    def _view(
        self,
        vista: str,
        pose: CameraPose,
        cameras: tuple[str, str, str],
        pose_error_px: tuple[float, float],
        *,
        stereo: bool,
        truth: bool,
        **settings: Any,
    ) -> View:
        """Frame, basis, depth and truth from `cameras` (main, left, right) at `pose`: the shared driver."""
        shape = pose.shape
        main, left, right = cameras
        frame, basis, ambient, strobe = self._frame(main, shape, **settings)
        state = settings["state"]
        depth: F32 | None = None
        masks: dict[int, BoolArray] = {}
        truss: BoolArray | None = None
        components: dict[str, BoolArray] = {}
        if truth:
            depth, segments = self._renderer(shape).depth_and_segments(self.data, main, state=state)
            truss = np.isin(segments, self._truss_geoms)
            components = {
                site: mask
                for site, ids in self._component_geoms.items()
                if (mask := np.isin(segments, ids)).any()
            }
            if state == "inspection":
                masks = self._truth(pose, depth, segments, state, camera=main)
        pair = None
        if stereo:
            # the main camera is the pair's left one: its frame is the left frame
            first = frame if left == main else self._frame(left, shape, **settings)[0]
            pair = (first, self._frame(right, shape, **settings)[0])
        return View(
            vista,
            state,
            frame,
            basis,
            ambient,
            strobe,
            depth,
            masks,
            pose,
            pose_error_px,
            pair,
            truss,
            components,
        )

    def _frame(
        self,
        camera: str,
        shape: tuple[int, int],
        *,
        state: str,
        lit_field: str,
        seconds: float,
        intensity: float,
    ) -> tuple[Frame, dict[str, F32], F32, F32]:
        renderer = self._renderer(shape)
        groups = ("sun", "strobe", "lamps") if self.halogen_on else ("sun", "strobe")
        basis = {
            g: renderer.luminance(
                self.data, camera, state=state, lights=tuple(self._lights[g]), level=self._render_level(g)
            )
            for g in groups
            if g != "sun" or self.lamp_on
        }
        if not self.lamp_on:  # the sun group is the lamp and the room light it scatters: both dark
            basis["sun"] = np.zeros(shape, dtype=np.float32)
        # render units -> lux: 255 * level is a white surface facing the light at its calibration point
        ambient = basis["sun"] * np.float32(intensity / (255 * SUN_LEVEL))
        at_reference = 1.0 / REFERENCE_DISTANCE_M**2
        if self.halogen_on:
            ambient = ambient + basis["lamps"] * np.float32(
                HALOGEN_LUX / (255 * 2 * HALOGEN_LEVEL * at_reference)
            )
        strobe = self._strobe_lux_s(basis["strobe"])
        frame = expose(
            ambient, strobe, exposure_s=seconds, camera=self.camera, lit_field=lit_field, rng=self._noise_rng
        )
        return frame, basis, ambient, strobe

    def _render_level(self, group: str) -> float:
        """The level a light group is rendered at: a strobe at the flash it fires (so a weakened flash is
        rendered with the 8 bits its camera spends on it, and its glare clips less), the continuous lights
        at :data:`AMBIENT_RENDER_LEVEL`."""
        return min(1.0, self.strobe_energy) if group in ("strobe", "other_strobe") else AMBIENT_RENDER_LEVEL

    def _strobe_lux_s(self, luminance: F32) -> F32:
        """A strobe's exposure in lux s from its luminance render: the flash at this world's energy, its
        render level calibrated at the reference distance (seed §2.1: 1.3 lm s over 0.1 m^2)."""
        return luminance * np.float32(
            self.strobe_energy * STROBE_LUX_S / (255 * STROBE_LEVEL * (1.0 / REFERENCE_DISTANCE_M**2))
        )

    def _truth(
        self, pose: CameraPose, depth: F32, segments: NDArray[np.int32], state: str, *, camera: str = "isee"
    ) -> dict[int, BoolArray]:
        """Pixels of each anomaly: its geoms in the frame, and where it replaced pristine geoms (seed §4)."""
        masks: dict[int, BoolArray] = {}
        renderer = self._renderer(pose.shape)
        pristine = None
        if self.index.pristine_geoms:
            pristine = renderer.depth_and_segments(self.data, camera, state="reference")[1]
        for index, names in self.index.flaw_geoms.items():
            ids = [self._id("geom", name) for name in names]
            mask = np.isin(segments, ids)
            if pristine is not None and index in self.index.pristine_geoms:
                mask |= np.isin(pristine, [self._id("geom", n) for n in self.index.pristine_geoms[index]])
            # a flaw smaller than a pixel still marks the pixel its centre falls in, if nothing hides it
            anomaly = self.anomalies.anomalies[index]
            xy, along = pose.project(np.asarray([anomaly.position_m]))
            col, row = (round(c) for c in xy[0])
            if (
                0 <= row < pose.shape[0]
                and 0 <= col < pose.shape[1]
                and abs(depth[row, col] - along[0]) < _TRUTH_DEPTH_TOLERANCE_M
            ):
                mask[row, col] = True
            if mask.any():
                masks[index] = mask
        return masks

    def overview(self, *, size: tuple[int, int] = DEFAULT_SIZE) -> tuple[NDArray[np.uint8], CameraPose]:
        """Colour picture (RGB uint8) of the whole mock-up from the overview vista, and the camera it used.

        Unmarked, in the inspection state (anomalies present), lit by the sun lamp and a lit room for people
        to see the whole mock-up by; the pose projects world points (findings, truth) into the picture.
        """
        shape = frame_size(size)
        point = self.vista("overview")
        self.place_camera(point.position_m, point.forward, point.up)
        renderer = self._renderer(shape)
        ids = tuple(self._lights["sun"])
        room = self._id("light", "room")
        saved = self.model.light_ambient[room].copy()
        self.model.light_ambient[room] = 0.25
        try:
            image = renderer.rgb(self.data, "isee", state="inspection", lights=ids)
        finally:
            self.model.light_ambient[room] = saved
        pose = CameraPose(
            np.asarray(point.position_m),
            _rotation(np.asarray(point.forward), np.asarray(point.up)),
            math.radians(CAMERA_FOVY_DEG),
            shape,
        )
        return np.ascontiguousarray(image), pose

    def overview_picture(self, *, size: tuple[int, int] = DEFAULT_SIZE) -> NDArray[np.uint8]:
        """Colour picture (RGB uint8) of the whole mock-up from the overview vista, anomalies marked.

        Markers: circles coloured by kind (hot spot red, cold spot blue, leak green, missing screw yellow,
        impact magenta, swapped component orange) with the anomaly's index.
        """
        picture, pose = self.overview(size=size)
        shape = pose.shape
        radius = max(4, shape[0] // 60)
        for k, anomaly in enumerate(self.anomalies.anomalies):
            xy, _ = pose.project(np.asarray([anomaly.position_m]))
            centre = (round(xy[0, 0]), round(xy[0, 1]))
            colour = _MARKER_COLOURS[anomaly.kind]
            cv2.circle(picture, centre, radius, colour, 2, cv2.LINE_AA)
            cv2.putText(
                picture,
                str(k),
                (centre[0] + radius, centre[1] - radius),
                cv2.FONT_HERSHEY_SIMPLEX,
                0.4,
                colour,
                1,
                cv2.LINE_AA,
            )
        return picture

    def close(self) -> None:
        """Free every renderer's OpenGL context."""
        for renderer in self._renderers.values():
            renderer.close()
        self._renderers.clear()


def _check_build(repeatability: object, camera: object, arm: object) -> None:
    v.choice(repeatability, "repeatability", REPEATABILITY_PX)
    v.instance_of(camera, "camera", CameraModel, none_allowed=False)
    if not isinstance(arm, bool):
        raise InputError(f"arm must be True or False; got {arm!r}.")


def frame_size(size: object) -> tuple[int, int]:
    """`size` checked as a frame's (rows, cols): a tuple of two integers, each 16..MAX_RENDER_PX."""
    if not isinstance(size, tuple) or len(size) != 2:
        raise InputError(f"size must be a (rows, cols) tuple; got {size!r}. Try size=(480, 640).")
    rows, cols = (v.positive_int(side, "size", minimum=16) for side in size)
    if max(rows, cols) > MAX_RENDER_PX:
        raise InputError(f"size must be at most {MAX_RENDER_PX} pixels a side; got {size!r}.")
    return (rows, cols)


def arm_home_tool_tip_m(mockup: Mockup) -> tuple[float, float, float]:
    """Where the arm's home tool tip stands in front of `mockup`: mid-truss, its rail centred on the truss
    (:data:`ARM_HOME_TOOL_TIP_M` on the seed layout), the vistas' standoff off the front-most face."""
    v.instance_of(mockup, "mockup", Mockup, none_allowed=False)
    return (mockup.length_m / 2, ARM_HOME_TOOL_TIP_M[1], ARM_HOME_TOOL_TIP_M[2])


def load(
    scene: str = "truss",
    *,
    seed: SeedLike,
    repeatability: str = "lab",
    settings: AnomalySettings | None = None,
    camera: CameraModel = DEFAULT_CAMERA,
    arm: bool = False,
    grid_meshes: bool = True,
) -> World:
    """Build a seeded world (seed §4): the mock-up with anomalies drawn from `seed`.

    Parameters
    ----------
    scene : {"truss", "truss-b"}
        The mock-up's layout (:data:`SCENES`, :data:`rsi.sim.mockup.LAYOUTS`): the seed's, or issue 15's
        second arrangement of the same kinds of component on four bays.
    seed : int or numpy.random.SeedSequence
        Seed of every random choice, >= 0, or a sequence spawned for this world: one child stream draws the
        anomalies, the other the viewpoint errors and camera noise.
    repeatability : {"lab", "space"}
        Viewpoint repeatability of each vista visit (seed §2.3).
    settings : AnomalySettings, optional
        Anomaly counts and ranges (defaults of :class:`rsi.sim.anomalies.AnomalySettings`).
    camera : CameraModel
        The inspection camera (seed §2.1).
    arm : bool
        Also put the K1207-style arm on its rail, carrying the ISEE, in the same MuJoCo world (issue 4):
        rail along the truss, centred on it (x = 0.9 +- 1 m on "truss", 1.2 +- 1 m on "truss-b"), home tool
        tip at :func:`arm_home_tool_tip_m` (:data:`ARM_HOME_TOOL_TIP_M` on "truss"). Reach it as
        :attr:`World.arm`; frames from its camera with :meth:`World.render_from_tool`. False (default)
        builds exactly the model, and the frames, of a world without it.
    grid_meshes : bool
        Draw the large boxes as grid meshes, lit at every centimetre (default: the inspection's frames,
        :func:`rsi.sim.scene.scene_mjcf`). False keeps MuJoCo's boxes: a world for rays, reach and the
        operator's live video (the console), where the meshes' triangles only cost time.

    Returns
    -------
    World
    """
    v.choice(scene, "scene", SCENES)
    _check_build(repeatability, camera, arm)  # before the anomalies are drawn and the model is built
    # one stream draws the anomalies, the other is the world's (poses, noise): spawned, never re-derived
    anomaly_stream, world_stream = seed_sequence(seed).spawn(2)
    built = mockup(scene)
    anomalies = seed_anomalies(built.candidates, rng=np.random.default_rng(anomaly_stream), settings=settings)
    # a spawned child keeps its parent's entropy: world.seed is the user's integer
    return World(
        built,
        anomalies,
        seed=world_stream,
        repeatability=repeatability,
        camera=camera,
        arm=arm,
        grid_meshes=grid_meshes,
    )
