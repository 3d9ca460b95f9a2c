"""Seed §2.1-2.2, §4: camera frames of the mock-up from MuJoCo's classic renderer.

The classic renderer is linear (no gamma) but returns uint8 colour, and a pixel saturates at 255. So each
light group is rendered alone (a *basis* image), converted to float32 luminance, scaled to lux by its
calibration, and only then combined, in numpy, by the camera model :func:`rsi.imaging.camera.expose`: an
interlaced frame whose odd field the strobe lights (seed §2.2), with the shutter of seed §2.1, shot and read
noise and 8 bits. The basis images sum to the all-lights render within quantisation (tested).

Quantisation: each group's level puts a white Lambertian surface facing its light at ~0.8-0.9 of 255, while
the camera maps the same surface to ~160 DN (13 lux s on reflectance 1, ``CameraModel`` defaults), so one
basis step is ~0.7 camera DN: its rounding error (0.2 DN rms) stays below the camera's own read and
quantisation noise (0.4 DN rms).

Glare: the classic renderer clamps a pixel's lit colour at 1 before the texture multiplies it, so a basis
image reads 255 times the texel wherever its lights' sum passes 1 (the strobe's specular return on the tanks
and plates at close range), a plateau below the camera model's full well in which a bright impact cannot
brighten: no real sensor flatters like that (seed §2.1: it sees the glare or saturates and says so). Where a
basis image may be clipped it is rendered again with its lights at a quarter (the lit colour is linear in
them: no headlight, no emission) and the pixels that read brighter so are taken from it, up to
:data:`GLARE_RENDERS` times (64 times the level). :data:`CLIP_SUSPECT` is the darkest a clipped pixel can
read: the brushed and grainy textures' darkest texel is 167 of 255; the solar cells' bus bars (63) lie
between fingers and cells of 218 and more, which a clipped patch of cells always holds.

Backend: chosen lazily from ``MUJOCO_GL`` (``egl`` by default, ``osmesa`` if EGL is not installed,
``glfw`` with a display); a missing one fails only when something is rendered, naming what to install.
"""

from __future__ import annotations

import ctypes.util
import importlib
import os
import sys
from dataclasses import dataclass, field
from types import ModuleType
from typing import Any

import numpy as np
from numpy.typing import NDArray

from rsi._validate import as_float_array
from rsi.errors import InputError, RsiError

F32 = NDArray[np.float32]
BoolArray = NDArray[np.bool_]

_BACKENDS = {"egl": "mujoco.egl", "osmesa": "mujoco.osmesa", "glfw": "mujoco.glfw"}
_INSTALL = {
    "egl": "an EGL driver (Debian/Ubuntu: apt-get install libegl1 libgl1; NVIDIA GPUs: the driver's libEGL)",
    "osmesa": "OSMesa for CPU rendering (Debian/Ubuntu: apt-get install libosmesa6)",
    "glfw": "GLFW and a display (pip install glfw; apt-get install libglfw3; set DISPLAY)",
}
GLARE_DIMMING = 4.0
GLARE_RENDERS = 3
CLIP_SUSPECT = 166
_LUMINANCE = np.array([0.299, 0.587, 0.114], dtype=np.float32)  # seed §2.1: luminance only (Rec. 601)
STATES = ("inspection", "reference")


class RenderBackendError(RsiError, RuntimeError):
    """No usable OpenGL backend for MuJoCo's renderer (the message says what to install)."""


def backend_name() -> str:
    """The OpenGL backend for rendering: ``MUJOCO_GL`` if set, else ``egl`` or, lacking EGL, ``osmesa``."""
    requested = os.environ.get("MUJOCO_GL", "").strip().lower()
    if requested:
        return requested
    if ctypes.util.find_library("EGL") is None and ctypes.util.find_library("OSMesa") is not None:
        return "osmesa"
    return "egl"


def import_mujoco() -> ModuleType:
    """Import MuJoCo without letting its import-time ``MUJOCO_GL`` check break physics-only use.

    MuJoCo validates ``MUJOCO_GL`` when imported; an unusable value would stop the world from even being
    built. We import it with our chosen backend (or rendering disabled when the value is unknown) and
    restore the variable, so that a bad backend fails only when a frame is rendered.
    """
    if "mujoco" in sys.modules:
        return sys.modules["mujoco"]
    original = os.environ.get("MUJOCO_GL")
    name = backend_name()
    os.environ["MUJOCO_GL"] = name if name in _BACKENDS else "disable"
    try:
        return importlib.import_module("mujoco")
    finally:
        if original is None:
            del os.environ["MUJOCO_GL"]
        else:
            os.environ["MUJOCO_GL"] = original


def _gl_context(width: int, height: int) -> Any:
    """An OpenGL context from the backend of :func:`backend_name`, or a clear RenderBackendError."""
    name = backend_name()
    if name not in _BACKENDS:
        choices = "; ".join(f"MUJOCO_GL={key} needs {hint}" for key, hint in _INSTALL.items())
        raise RenderBackendError(
            f"MUJOCO_GL={name!r} is not a rendering backend rsi can use. Set one of: {choices}."
        )
    try:
        module = importlib.import_module(_BACKENDS[name])
        return module.GLContext(width, height)
    except Exception as error:  # backends fail with ImportError, OSError, AttributeError or GL errors
        raise RenderBackendError(
            f"MUJOCO_GL={name!r}: the OpenGL backend could not start ({type(error).__name__}: {error}). "
            f"Install {_INSTALL[name]}, or choose another backend with MUJOCO_GL=egl|osmesa|glfw."
        ) from error


def _check_size(model: object, height: object, width: object) -> None:
    """Raise unless `model` is an MjModel and the image fits its offscreen buffer (MuJoCo would abort)."""
    mujoco = import_mujoco()
    if not isinstance(model, mujoco.MjModel):
        raise InputError(f"model must be a mujoco.MjModel; got {type(model).__name__}.")
    limits = {"height": model.vis.global_.offheight, "width": model.vis.global_.offwidth}
    for name, side in (("height", height), ("width", width)):
        if isinstance(side, bool) or not isinstance(side, (int, np.integer)) or not 1 <= side <= limits[name]:
            raise InputError(
                f"{name} must be an integer in [1, {limits[name]}] (the model's offscreen buffer); got "
                f"{str(side)[:40]}."
            )


def _check_lights(lights: object, count: int) -> None:
    """Raise unless `lights` is a tuple of the model's light ids."""
    if not isinstance(lights, tuple) or not all(
        isinstance(light, (int, np.integer)) and not isinstance(light, bool) and 0 <= light < count
        for light in lights
    ):
        raise InputError(f"lights must be a tuple of light ids in [0, {count}); got {str(lights)[:80]}.")


@dataclass(frozen=True)
class CameraPose:
    """Where a frame was taken from: a pinhole camera looking along `forward`.

    Attributes
    ----------
    position_m : ndarray of shape (3,)
        Camera centre in the world frame.
    rotation : ndarray of shape (3, 3)
        Columns: image right, image up and backward (minus the viewing direction) in the world frame.
    fovy_rad : float
        Vertical field of view.
    shape : (int, int)
        (rows, cols) of the image.
    """

    position_m: NDArray[np.float64]
    rotation: NDArray[np.float64]
    fovy_rad: float
    shape: tuple[int, int]

    @property
    def focal_px(self) -> float:
        """Focal length in pixels (square pixels)."""
        return self.shape[0] / 2 / float(np.tan(self.fovy_rad / 2))

    def project(self, points_m: NDArray[np.float64]) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Pixel coordinates (x = col, y = row; pixel centres at integers) and depth of world points.

        Parameters
        ----------
        points_m : ndarray of shape (K, 3)

        Returns
        -------
        xy : ndarray of shape (K, 2)
        depth_m : ndarray of shape (K,)
            Distance along the viewing direction (negative behind the camera).
        """
        points = as_float_array(points_m, "points_m")
        if points.ndim != 2 or points.shape[1] != 3:
            raise InputError(f"points_m must have shape (K, 3); got shape {points.shape}.")
        local = (points - self.position_m) @ self.rotation
        depth = -local[:, 2]
        with np.errstate(divide="ignore", invalid="ignore"):
            x = (self.shape[1] - 1) / 2 + self.focal_px * local[:, 0] / depth
            y = (self.shape[0] - 1) / 2 - self.focal_px * local[:, 1] / depth
        return np.stack([x, y], axis=1), depth


# Slices and stacks of the live renderer's round shapes (MuJoCo draws 28 x 16): one 480x640 frame of the
# ISEE camera took 31.6 ms at 28 x 16 and 25.0 ms at 16 x 8 (bench in docs/console.md); 16 slices keep a
# tube's outline within 2 % of its radius (1 - cos(pi / 16)).
FAST_TESSELLATION = (16, 8)
# Quads along a box face's side in live video: MuJoCo's default. The inspection frames' fine quads
# (rsi.sim.scene.BOX_QUAD_M) make the strobe's light true per point; the operator's video shows no strobe
FAST_BOX_QUADS = 4


@dataclass(frozen=True)
class CadView:
    """The robot's CAD model seen from a pose (:meth:`rsi.sim.world.World.cad_projection`).

    Attributes
    ----------
    expected_depth_m : ndarray of shape (M, N), float32
        Depth of the pristine model along the view axis (the far plane, >= 10 m, where nothing is).
    truss : ndarray of shape (M, N), bool
        Pixels of the truss frame and the robot's own arm: not inspected surface.
    components : dict of str to ndarray of shape (M, N), bool
        Pixels of each swappable component the model puts in view.
    parts : ndarray of shape (M, N), int32, or None
        The model's part (one surface of one finish) in each pixel, as an id; -1 where none. None: not
        drawn.
    """

    expected_depth_m: F32
    truss: BoolArray
    components: dict[str, BoolArray] = field(default_factory=dict)
    parts: NDArray[np.int32] | None = None


class SceneRenderer:
    """Offscreen classic-renderer of one model at one image size (owns its OpenGL context).

    Parameters
    ----------
    model : mujoco.MjModel
    height, width : int
        Image size in pixels, at most the model's offscreen buffer (2048).
    show_rangefinders : bool
        Draw the rangefinders' rays (MuJoCo's default). False (default): camera images show only the scene.
    fast : bool
        Live video (the operator console): no shadow map, no multisampling, the round shapes (the
        truss's tubes, the tanks) drawn with :data:`FAST_TESSELLATION` facets and box faces with
        :data:`FAST_BOX_QUADS` quads a side. On the CPU renderer the
        lamp's 2048-px shadow map and 4x multisampling are most of a frame's cost, and the facets most of
        the rest (docs/console.md has the timings); frames for inspection keep all three (False, the
        default).
    """

    def __init__(
        self, model: Any, height: int, width: int, *, show_rangefinders: bool = False, fast: bool = False
    ) -> None:
        mujoco = import_mujoco()
        _check_size(model, height, width)
        for name, flag in (("show_rangefinders", show_rangefinders), ("fast", fast)):
            if not isinstance(flag, bool):
                raise InputError(f"{name} must be True or False; got {flag!r}.")
        self._mujoco = mujoco
        self._model = model
        self._context = _gl_context(width, height)
        self._context.make_current()
        quality = model.vis.quality
        kept = (quality.offsamples, quality.numslices, quality.numstacks, quality.numquads)
        if fast:  # the context reads multisampling and tessellation from the model when it is made
            quality.offsamples, quality.numslices, quality.numstacks = 0, *FAST_TESSELLATION
            quality.numquads = FAST_BOX_QUADS
        try:
            self._mjr = mujoco.MjrContext(model, mujoco.mjtFontScale.mjFONTSCALE_100.value)
        finally:
            quality.offsamples, quality.numslices, quality.numstacks, quality.numquads = kept
        mujoco.mjr_setBuffer(mujoco.mjtFramebuffer.mjFB_OFFSCREEN.value, self._mjr)
        self._mjr.readDepthMap = mujoco.mjtDepthMap.mjDEPTH_ZEROFAR
        self._scene = mujoco.MjvScene(model, maxgeom=4000)
        self._option = mujoco.MjvOption()
        # rangefinder rays would otherwise be drawn into the camera images (ARCHITECTURE: MuJoCo facts)
        self._option.flags[mujoco.mjtVisFlag.mjVIS_RANGEFINDER] = bool(show_rangefinders)
        self._scene.flags[mujoco.mjtRndFlag.mjRND_SHADOW] = not fast
        self._camera = mujoco.MjvCamera()
        self._camera.type = mujoco.mjtCamera.mjCAMERA_FIXED
        self._rect = mujoco.MjrRect(0, 0, width, height)
        self.shape = (height, width)

    def _update(self, data: Any, camera: str, state: str, lights: tuple[int, ...] | None) -> None:
        mujoco = self._mujoco
        if not isinstance(data, mujoco.MjData) or data.qpos.size != self._model.nq:
            raise InputError(
                f"data must be the mujoco.MjData of the renderer's model; got {type(data).__name__}."
            )
        if not isinstance(state, str) or state not in STATES:
            raise InputError(f"state={state!r} is not known. Choose one of {', '.join(map(repr, STATES))}.")
        if lights is not None:
            _check_lights(lights, self._model.nlight)
        camera_id = -1
        if isinstance(camera, str):
            camera_id = mujoco.mj_name2id(self._model, mujoco.mjtObj.mjOBJ_CAMERA, camera)
        if camera_id < 0:  # MuJoCo would abort the whole process on an out-of-range camera id
            names = ", ".join(repr(self._model.camera(k).name) for k in range(self._model.ncam))
            raise InputError(f"camera={camera!r} is not a camera of the scene. Choose one of {names}.")
        self._camera.fixedcamid = camera_id
        anomalous = state == "inspection"
        self._option.geomgroup[:] = [1, 0, 0, int(anomalous), int(not anomalous), 0]
        if lights is not None:
            self._model.light_active[:] = 0
            self._model.light_active[list(lights)] = 1
        self._context.make_current()
        mujoco.mjv_updateScene(
            self._model, data, self._option, None, self._camera, mujoco.mjtCatBit.mjCAT_ALL, self._scene
        )

    def rgb(
        self, data: Any, camera: str, *, state: str = "inspection", lights: tuple[int, ...] | None = None
    ) -> NDArray[np.uint8]:
        """uint8 colour image of shape (M, N, 3) lit by the light ids `lights` (None: the model's own)."""
        self._update(data, camera, state, lights)
        return self._read_colour()

    def luminance(
        self, data: Any, camera: str, *, state: str, lights: tuple[int, ...], level: float = 1.0
    ) -> F32:
        """float32 luminance lit by `lights` only (seed §2.1: luminance signal), in render units: 255 is a
        lit colour of 1, and glare goes past it (the module docstring: rendered again dimmer where clipped).

        `level` in (0, 1] renders the lights that much dimmer to begin with (the result is in the same
        units): a flash fired weaker than the seed's spends the render's 8 bits where its camera does.
        """
        if isinstance(level, bool) or not isinstance(level, (int, float)) or not 0.0 < level <= 1.0:
            raise InputError(f"level must be a number in (0, 1]; got {str(level)[:40]}.")
        self._update(data, camera, state, lights)
        scale = float(level)
        if scale < 1.0:
            self._dim_lights(scale)
        colour = self._read_colour()
        linear = colour.astype(np.float32) / np.float32(scale)
        for _ in range(GLARE_RENDERS):
            if int(colour.max(initial=0)) < CLIP_SUSPECT:
                break
            scale /= GLARE_DIMMING
            self._dim_lights(1.0 / GLARE_DIMMING)
            colour = self._read_colour()
            dimmer = colour.astype(np.float32) / np.float32(scale)
            # each render quantises the lit colour and then its product with the texel to 8 bits: up to a
            # unit of its own level apart (measured: 5 render units at a quarter, never more)
            clipped = np.any(dimmer - linear > 1.0 / scale + 1.0 / (scale * GLARE_DIMMING) + 1.0, axis=2)
            linear[clipped] = dimmer[clipped]
            colour = np.where(clipped[..., None], colour, 0).astype(np.uint8)
        return np.asarray(linear @ _LUMINANCE)

    def _read_colour(self) -> NDArray[np.uint8]:
        buffer = np.empty((*self.shape, 3), dtype=np.uint8)
        self._mujoco.mjr_render(self._rect, self._scene, self._mjr)
        self._mujoco.mjr_readPixels(buffer, None, self._rect, self._mjr)
        return np.ascontiguousarray(buffer[::-1])

    def _dim_lights(self, factor: float) -> None:
        """Scale every light of the updated scene (the model is untouched: the next update restores it)."""
        for k in range(self._scene.nlight):
            light = self._scene.lights[k]
            light.ambient[:] = np.asarray(light.ambient) * factor
            light.diffuse[:] = np.asarray(light.diffuse) * factor
            light.specular[:] = np.asarray(light.specular) * factor

    def depth_and_segments(self, data: Any, camera: str, *, state: str) -> tuple[F32, NDArray[np.int32]]:
        """Depth along the view axis in metres and the geom id seen in each pixel (-1: background)."""
        mujoco = self._mujoco
        self._update(data, camera, state, None)
        flags = self._scene.flags
        flags[mujoco.mjtRndFlag.mjRND_SEGMENT] = True
        flags[mujoco.mjtRndFlag.mjRND_IDCOLOR] = True
        colour = np.empty((*self.shape, 3), dtype=np.uint8)
        depth = np.empty(self.shape, dtype=np.float32)
        try:
            mujoco.mjr_render(self._rect, self._scene, self._mjr)
            mujoco.mjr_readPixels(colour, depth, self._rect, self._mjr)
        finally:
            flags[mujoco.mjtRndFlag.mjRND_SEGMENT] = False
            flags[mujoco.mjtRndFlag.mjRND_IDCOLOR] = False
        code = colour[::-1].astype(np.int64) @ np.array([1, 256, 65536])
        lookup = np.full(self._scene.ngeom + 2, -1, dtype=np.int32)
        for k in range(self._scene.ngeom):
            geom = self._scene.geoms[k]
            if geom.segid >= 0 and geom.objtype == mujoco.mjtObj.mjOBJ_GEOM:
                lookup[geom.segid + 1] = geom.objid
        segments = lookup[np.clip(code, 0, lookup.size - 1)]
        return self._metric_depth(depth[::-1]), segments

    def _metric_depth(self, buffer: F32) -> F32:
        # reversed-Z perspective depth of the classic renderer back to metres (as mujoco.Renderer does)
        extent = self._model.stat.extent
        near = np.float32(self._model.vis.map.znear * extent)
        far = np.float32(self._model.vis.map.zfar * extent)
        c_coef = np.float32(-0.5) * (-(far + near) / (far - near)) - np.float32(0.5)
        d_coef = np.float32(-0.5) * (-(np.float32(2) * far * near) / (far - near))
        return np.asarray(d_coef / (buffer.astype(np.float64) + c_coef), dtype=np.float32)

    def close(self) -> None:
        """Free the OpenGL resources."""
        self._context.make_current()
        self._mjr.free()
        self._context.free()
