"""The console's camera process: live frames, and the reference / inspection pair taken at hand.

The parent sends :class:`rsi.web.live.LiveState` snapshots over a pipe and gets frames back; rendering runs
here, in its own interpreter, so the teleop loop's 44 Hz ticks never wait for it (see :mod:`rsi.web.live`).
An inspection at hand is taken with the same twin at full quality (shadows, multisampling, the seed's
480x640 video frame, seed §2.1) and compared with the reference by the mission's pair pipeline
(:func:`rsi.mission.inspect_pair`: compensation, registration, detection, seed §2.2-2.4); the live
frames pause while it runs, as a camera busy with a shot would.
"""

from __future__ import annotations

import multiprocessing
import threading
from dataclasses import dataclass
from multiprocessing.connection import Connection
from typing import Any

import cv2
import numpy as np
from numpy.typing import NDArray

from rsi import _validate as v
from rsi.errors import InputError
from rsi.mission.settings import MissionSettings
from rsi.sim.world import SCENES, frame_size
from rsi.web.live import LiveCameras, LiveFrame, LiveState

SHOT_SIZE = (480, 640)  # seed §2.1: the inspection camera's video frame
SHOT_KINDS = ("reference", "inspection")
# The mission's detector settings (rsi.mission.MissionSettings: seed §2.4's uniform 3x3 flaw model, a
# false-alarm rate of 1e-9 per pixel so a 480x640 frame holds ~3e-4 false alarms, 0.3 px of residual
# mis-registration in the noise model); at hand the two shots share the pose, so nothing else is needed.
_MISSION = MissionSettings()
SHOT_DETECTION: dict[str, Any] = {
    "flaw_model": _MISSION.flaw_model,
    "size": _MISSION.flaw_size_px,
    "p_false_alarm": _MISSION.p_false_alarm,
    "polarity": "both",
    "misregistration_std_px": _MISSION.misregistration_std_px,
}


@dataclass(frozen=True)
class Shot:
    """A reference or inspection taken at hand, and the comparison when both exist.

    Attributes
    ----------
    kind : {"reference", "inspection"}
    images : dict of str to bytes
        JPEGs: ``reference``, ``inspection`` and, after an inspection with a reference, ``difference`` and
        ``score`` (the detector's score over its threshold, flaws boxed).
    flaws : list of dict
        ``row``, ``col``, ``bbox``, ``area_px``, ``score``, ``polarity`` (strongest first).
    summary : dict
        ``threshold``, ``registration_xy_px`` (the reference's shift onto the inspection), ``elapsed_s``.
    """

    kind: str
    images: dict[str, bytes]
    flaws: list[dict[str, Any]]
    summary: dict[str, Any]


def _jpeg(image: NDArray[np.uint8]) -> bytes:
    return bytes(cv2.imencode(".jpg", image, [cv2.IMWRITE_JPEG_QUALITY, 90])[1].tobytes())


def _display(image: NDArray[np.floating]) -> NDArray[np.uint8]:
    """A float image stretched to 8 bits between its 0.5 and 99.5 percentiles."""
    finite = np.nan_to_num(image.astype(np.float64))
    low, high = np.percentile(finite, [0.5, 99.5])
    result: NDArray[np.uint8] = np.clip((finite - low) * (255.0 / max(high - low, 1e-9)), 0, 255).astype(
        np.uint8
    )
    return result


class _Shooter:
    def __init__(self, cameras: LiveCameras) -> None:
        self.cameras = cameras
        self.reference: Any = None

    def shoot(self, state: LiveState, kind: str) -> Shot:
        from rsi.imaging.compensation import compensate_field_pair
        from rsi.mission import inspect_pair

        twin = self.cameras.twin
        state.apply(twin)
        twin.set_fast_rendering(False)
        try:
            view = twin.render_from_tool(size=SHOT_SIZE, state=kind, truth=False)
        finally:
            twin.set_fast_rendering(True)
        compensated = compensate_field_pair(view.frame, twin.next_frame(view, lit_field="even"))
        images = {kind: _jpeg(_display(compensated.image))}
        if kind == "reference":
            self.reference = compensated
            return Shot(kind, images, [], {})
        if self.reference is None:
            return Shot(kind, images, [], {"note": "no reference yet: take one first"})
        pair = inspect_pair(self.reference, compensated, registration_model="translation", **SHOT_DETECTION)
        detection = pair.detection
        images["reference"] = _jpeg(_display(pair.reference))
        images["difference"] = _jpeg(_display(detection.difference))
        over = np.clip(np.nan_to_num(detection.score) / max(detection.threshold, 1e-9) * 128, 0, 255)
        score = cv2.applyColorMap(over.astype(np.uint8), cv2.COLORMAP_INFERNO)
        for flaw in detection.flaws:
            row0, col0, row1, col1 = flaw.bbox
            cv2.rectangle(score, (col0 - 3, row0 - 3), (col1 + 2, row1 + 2), (255, 255, 0), 1)
        images["score"] = _jpeg(score)
        registration = detection.registration
        shift = None if registration is None else [round(float(x), 3) for x in registration.translation_xy]
        flaws = [
            {
                "row": round(f.row, 1),
                "col": round(f.col, 1),
                "bbox": list(f.bbox),
                "area_px": f.area_px,
                "score": round(f.score, 2),
                "polarity": f.polarity,
            }
            for f in detection.flaws
        ]
        summary = {
            "threshold": round(detection.threshold, 3),
            "registration_xy_px": shift,
            "elapsed_s": round(pair.elapsed_s, 3),
        }
        return Shot(kind, images, flaws, summary)


def _serve(connection: Connection, seed: int, layout: str, size: tuple[int, int]) -> None:
    """The child's loop: ``("frame", state)``, ``("shoot", state, kind)``, ``("stop",)``."""
    from rsi.sim.world import load

    cameras = LiveCameras(load(layout, seed=seed, arm=True, grid_meshes=False), size=size)
    shooter = _Shooter(cameras)
    connection.send(("ready",))
    try:
        while True:
            message = connection.recv()
            if message[0] == "stop":
                break
            try:
                if message[0] == "frame":
                    connection.send(("frames", cameras.frames(message[1])))
                else:
                    connection.send(("shot", shooter.shoot(message[1], message[2])))
            except Exception as error:  # report it to the parent, keep serving
                connection.send(("error", f"{type(error).__name__}: {error}"))
    finally:
        cameras.twin.close()
        connection.close()


def _check_camera_options(seed: object, layout: object, size: object, start_timeout_s: object) -> None:
    """The camera process's options, checked here: a child that fails on them only says it closed."""
    if isinstance(seed, bool) or not isinstance(seed, int) or not 0 <= seed < 2**63:
        raise InputError(f"seed must be an integer in [0, 2**63); got {seed!r}.")
    v.choice(layout, "layout", SCENES)
    frame_size(size)
    v.in_range(start_timeout_s, "start_timeout_s", low=0.0, high=3600.0, low_inclusive=False)


class CameraProcess:
    """The parent's handle on the camera process: one request at a time over a pipe."""

    def __init__(
        self, *, seed: int, layout: str, size: tuple[int, int], start_timeout_s: float = 120.0
    ) -> None:
        _check_camera_options(seed, layout, size, start_timeout_s)
        context = multiprocessing.get_context("spawn")  # a clean interpreter: no inherited GL or threads
        self._connection, child = context.Pipe()
        self._process = context.Process(
            target=_serve, args=(child, seed, layout, size), name="rsi-console-cameras", daemon=True
        )
        self._process.start()
        child.close()
        self._lock = threading.Lock()
        self.size = size
        if not self._connection.poll(start_timeout_s):
            self.close()
            raise RuntimeError(f"the console's camera process did not start in {start_timeout_s} s")
        self._connection.recv()

    def _ask(self, message: tuple[Any, ...]) -> Any:
        with self._lock:
            self._connection.send(message)
            reply = self._connection.recv()
        if reply[0] == "error":
            raise RuntimeError(reply[1])
        return reply[1]

    def frames(self, state: LiveState) -> list[LiveFrame]:
        """One new frame of every live camera."""
        frames: list[LiveFrame] = self._ask(("frame", state))
        return frames

    def shoot(self, state: LiveState, kind: str) -> Shot:
        """Take a reference or an inspection at full quality from the pose in `state`."""
        shot: Shot = self._ask(("shoot", state, kind))
        return shot

    def close(self) -> None:
        """Stop the process (it frees its OpenGL contexts)."""
        try:
            with self._lock:
                self._connection.send(("stop",))
        except (OSError, BrokenPipeError):
            pass
        self._process.join(timeout=10.0)
        if self._process.is_alive():
            self._process.terminate()
            self._process.join(timeout=5.0)
        self._connection.close()


__all__ = ["SHOT_KINDS", "SHOT_SIZE", "CameraProcess", "Shot"]
