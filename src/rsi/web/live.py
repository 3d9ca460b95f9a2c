"""Live camera frames for the console: the ISEE's raw interlaced and compensated views and an overview.

Frames are rendered in a *twin* of the console's world (same seed, same model) in a child process, from
the live world's state sent before each frame: a render (tens to hundreds of milliseconds on the CPU)
never holds the lock, nor the interpreter, that the 44 Hz teleop loop needs (measured in one process: the
renders delayed the loop's ticks past the 200 ms stop budget).

The ISEE's light basis (seed §2.1: one image per light group) depends only on the scene's state, so it is
rendered again only when that state changed (the arm, the door or the lamp moved); in between every frame
is a new exposure of the same basis, with new camera noise and the strobe on alternate fields (seed §2.2),
and the compensated view weaves the last odd-lit and even-lit frames
(:func:`rsi.imaging.compensation.compensate_field_pair`).
"""

from __future__ import annotations

import asyncio
import hashlib
import threading
import time
from dataclasses import dataclass, field, replace

import cv2
import numpy as np
from numpy.typing import NDArray

from rsi.errors import InputError
from rsi.imaging.camera import Frame
from rsi.imaging.compensation import compensate_field_pair
from rsi.sim.solar_simulator import LampConfiguration
from rsi.sim.world import View, World, frame_size

CAMERAS = ("raw", "compensated", "overview")  # the order is the camera byte of a video message
JPEG_QUALITY = 80


@dataclass(frozen=True)
class LiveFrame:
    """One encoded frame of one camera.

    Attributes
    ----------
    camera : str
        One of :data:`CAMERAS`.
    seq : int
        Counts this camera's frames from 1.
    rendered_at_s : float
        Wall clock (``time.time()``) when the frame was exposed: the page's frame-age badge starts here.
    render_s : float
        Seconds spent making this frame (render, exposure, compensation, encoding), shared views included.
    jpeg : bytes
    message : bytes
        The binary websocket message (:func:`video_message`), made once here, in the camera process, and
        sent as it is to every viewer.
    """

    camera: str
    seq: int
    rendered_at_s: float
    render_s: float
    jpeg: bytes
    message: bytes = b""


def _jpeg(image: NDArray[np.uint8]) -> bytes:
    ok, data = cv2.imencode(".jpg", image, [cv2.IMWRITE_JPEG_QUALITY, JPEG_QUALITY])
    if not ok:  # pragma: no cover - OpenCV encodes any uint8 image
        raise RuntimeError("JPEG encoding failed")
    return bytes(data.tobytes())


def _display_gain(image: NDArray[np.floating]) -> float:
    """Stretch of the strobe image for display: its 99.5th percentile to white, read on every fourth row
    and column (a display level, not a measurement: a sixteenth of the pixels gives the same level)."""
    return 255.0 / max(float(np.nanpercentile(image[::4, ::4], 99.5)), 1e-6)


def _eight_bit(image: NDArray[np.floating]) -> NDArray[np.uint8]:
    """A float image in DN (0..255) as uint8 for display."""
    result: NDArray[np.uint8] = np.clip(np.nan_to_num(image), 0, 255).astype(np.uint8)
    return result


@dataclass(frozen=True)
class LiveState:
    """What the cameras see of the live world: joint positions (arm, door) and the lamps."""

    qpos: NDArray[np.float64]
    lamp: LampConfiguration
    lamp_on: bool
    halogen_on: bool

    @classmethod
    def of(cls, world: World) -> LiveState:
        """The state of `world` (hold its lock while calling)."""
        return cls(world.data.qpos.copy(), world.lamp, world.lamp_on, world.halogen_on)

    def apply(self, twin: World) -> bytes:
        """Put `twin` in this state; returns a key that changes whenever a camera would see a change."""
        twin.data.qpos[:] = self.qpos
        twin.switch_lamp(self.lamp_on)
        twin.set_halogen(self.halogen_on)
        twin.set_lamp(self.lamp)  # runs the kinematics of the whole twin
        digest = hashlib.blake2b(self.qpos.round(6).tobytes(), digest_size=16)
        digest.update(repr((self.lamp, self.lamp_on, self.halogen_on)).encode())
        return digest.digest()


@dataclass
class _Basis:
    key: bytes = b""
    view: View | None = None
    overview_jpeg: bytes = b""  # the overview changes only with the basis: encoded once per render
    odd: Frame | None = None
    even: Frame | None = None
    renders: int = 0


@dataclass
class FrameHub:
    """The latest frame of each camera, and a way for websocket handlers to wait for the next one.

    The render thread publishes; coroutines on the server's event loop wait. A slow viewer skips to the
    newest frame instead of queueing old ones (frames never pile up in a socket).
    """

    latest: dict[str, LiveFrame] = field(default_factory=dict)
    viewers: int = 0  # video sockets open now: the camera loop renders only for someone
    _loop: asyncio.AbstractEventLoop | None = None
    _event: asyncio.Event | None = None
    _lock: threading.Lock = field(default_factory=threading.Lock)

    def bind(self, loop: asyncio.AbstractEventLoop) -> None:
        """Attach the server's event loop (from its startup)."""
        self._loop = loop
        self._event = asyncio.Event()

    def publish(self, frames: list[LiveFrame]) -> None:
        """From the render thread: store the frames and wake the waiting viewers."""
        with self._lock:
            for frame in frames:
                self.latest[frame.camera] = frame
        loop = self._loop
        if loop is not None and not loop.is_closed():
            loop.call_soon_threadsafe(self._wake)

    def _wake(self) -> None:
        event = self._event
        self._event = asyncio.Event()
        if event is not None:
            event.set()

    async def wait(self, timeout_s: float = 1.0) -> None:
        """Until the next publish (or `timeout_s`, so a handler can notice a closed socket)."""
        event = self._event
        if event is None:
            await asyncio.sleep(timeout_s)
            return
        try:
            await asyncio.wait_for(event.wait(), timeout_s)
        except asyncio.TimeoutError:
            return

    def snapshot(self) -> dict[str, LiveFrame]:
        with self._lock:
            return dict(self.latest)

    def watched(self) -> bool:
        """Whether a viewer is connected, or no frame was made yet (a page that opens sees one at once)."""
        with self._lock:
            return self.viewers > 0 or not self.latest

    def viewer(self, joined: bool) -> None:
        """A video socket opened (`joined`) or closed. The first viewer after a pause drops the frames
        made before it: they show the world as it was when the last viewer left."""
        with self._lock:
            if joined and self.viewers == 0:
                self.latest.clear()
            self.viewers = max(self.viewers + (1 if joined else -1), 0)


class AckWindow:
    """Messages sent to one viewer that its page has not yet shown, and a way to wait for room.

    A socket's send returns once the bytes are in the kernel's buffer, so a page that shows frames more
    slowly than they come (a busy main thread, a starved machine) would queue seconds of them there and
    show every one late, at the full rate: the frame-age badge read 9.5 s in the whole suite's run. The page
    acknowledges each message it has shown; at most `size` stay unacknowledged, and the newest frame is
    sent when there is room, so a slow page skips frames instead of falling behind.
    """

    def __init__(self, size: int) -> None:
        if not isinstance(size, int) or isinstance(size, bool) or size < 1:
            raise InputError(f"size must be a whole number of messages >= 1; got {size!r}.")
        self.size = size
        self.unshown = 0
        self._shown = asyncio.Event()

    def sent(self) -> None:
        self.unshown += 1

    def shown(self) -> None:
        """One acknowledgement (more acknowledgements than messages sent are ignored)."""
        self.unshown = max(self.unshown - 1, 0)
        self._shown.set()

    async def room(self, timeout_s: float = 1.0) -> bool:
        """Wait until fewer than `size` messages are unshown; False after `timeout_s` without room."""
        while self.unshown >= self.size:
            self._shown.clear()
            try:
                await asyncio.wait_for(self._shown.wait(), timeout_s)
            except asyncio.TimeoutError:
                return False
        return True


class LiveCameras:
    """Makes the three live views from a twin world kept in step with the live one.

    Parameters
    ----------
    twin : World
        A world of the same seed with the arm (its own OpenGL contexts); switched to fast rendering.
    sync : callable
        ``sync(twin) -> bytes``: copy the live state into the twin (under the live world's lock) and return
        a key that changes whenever anything a camera sees changed.
    size : (int, int)
        Rows and columns of the live frames.
    """

    def __init__(self, twin: World, *, size: tuple[int, int]) -> None:
        if not isinstance(twin, World) or twin.arm is None:
            raise InputError(f"twin must be a World loaded with arm=True; got {type(twin).__name__}.")
        size = frame_size(size)
        self.twin = twin
        self.twin.set_fast_rendering(True)
        self.size = size
        self._basis = _Basis()
        self._seq = 0
        self._odd_next = False

    def frames(self, state: LiveState) -> list[LiveFrame]:
        """One new frame of every camera, of the live world in `state`."""
        start = time.perf_counter()
        key = state.apply(self.twin)
        basis = self._basis
        if key != basis.key or basis.view is None:
            overview_rgb, _ = self.twin.overview(size=self.size)
            overview_jpeg = _jpeg(np.ascontiguousarray(overview_rgb[..., ::-1]))  # RGB -> OpenCV's BGR
            view = self.twin.render_from_tool(size=self.size, truth=False)  # odd-lit, seed §2.2
            self._basis = basis = _Basis(key, view, overview_jpeg, odd=view.frame, renders=basis.renders + 1)
            frame = view.frame
            self._odd_next = False
        else:
            lit = "odd" if self._odd_next else "even"
            frame = self.twin.next_frame(basis.view, lit_field=lit)
            self._odd_next = not self._odd_next
            if lit == "odd":
                basis.odd = frame
            else:
                basis.even = frame
        exposed_at = time.time()
        raw = _jpeg(frame.raw)
        if basis.odd is not None and basis.even is not None:
            woven = compensate_field_pair(basis.odd, basis.even).image
            compensated = _jpeg(_eight_bit(woven * _display_gain(woven)))
        else:
            compensated = raw
        overview = basis.overview_jpeg
        self._seq += 1
        spent = time.perf_counter() - start
        frames = [
            LiveFrame(name, self._seq, exposed_at, spent, data)
            for name, data in zip(CAMERAS, (raw, compensated, overview), strict=True)
        ]
        return [replace(frame, message=video_message(frame)) for frame in frames]

    @property
    def basis_renders(self) -> int:
        """How many times the light basis was rendered (the rest of the frames reused it)."""
        return self._basis.renders


def video_message(frame: LiveFrame) -> bytes:
    """One camera's chunk of a binary websocket message: camera index (uint8), seq (uint32), exposure time
    in ms (float64), JPEG length (uint32), then the JPEG.

    Little-endian. A message holds the chunks of one tick's frames that the viewer asked for, so a tick is
    one send per viewer; the page walks the chunks with a DataView and shows each JPEG as a blob (no base64).
    """
    if not isinstance(frame, LiveFrame):
        raise InputError(f"frame must be a LiveFrame; got {type(frame).__name__}.")
    header = np.zeros(
        1, dtype=[("camera", "u1"), ("seq", "<u4"), ("rendered_at_ms", "<f8"), ("jpeg_bytes", "<u4")]
    )
    header["camera"] = CAMERAS.index(frame.camera)
    header["seq"] = frame.seq
    header["rendered_at_ms"] = frame.rendered_at_s * 1000.0
    header["jpeg_bytes"] = len(frame.jpeg)
    return header.tobytes() + frame.jpeg


HEADER_BYTES = 17

__all__ = ["CAMERAS", "HEADER_BYTES", "AckWindow", "FrameHub", "LiveCameras", "LiveFrame", "video_message"]
