"""Each check of the console's public functions, one bad value each: refused at once, naming the argument.

Found by tests/hostile/test_hostile_web.py (bare AttributeError, TypeError and a camera process that only
said its pipe closed); each is checked at the function's entry, before anything is built or started.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from rsi.errors import InputError
from rsi.web.app import TokenGate, create_app
from rsi.web.console import Console
from rsi.web.live import AckWindow, LiveCameras, LiveFrame, video_message
from rsi.web.mission_job import MissionJob
from rsi.web.scene import moving_poses, scene_geometry
from rsi.web.server import console_settings, serve
from rsi.web.teleop import clamp_operator, teleop_step
from rsi.web.worker import CameraProcess

FRAME = LiveFrame("raw", 1, 0.0, 0.01, b"\xff\xd8")


async def _asgi(scope: object, receive: object, send: object) -> None:
    return None


CASES: list[tuple[Callable[[], Any], str]] = [
    (lambda: console_settings(host=127), "host"),
    (lambda: console_settings(token=12345678901234567890), "token"),
    (lambda: console_settings(archive=b"archive.db"), "archive"),
    (lambda: console_settings(archive="a\0b.db"), "archive"),
    (lambda: clamp_operator("fast"), "command_m_s"),
    (lambda: clamp_operator(np.zeros(3), law="TELEOP"), "law"),
    (lambda: teleop_step("loop", np.zeros(3), held=True), "loop"),
    (lambda: video_message(b"jpeg"), "frame"),
    (lambda: AckWindow(0), "size"),
    (lambda: AckWindow(True), "size"),
    (lambda: scene_geometry("world"), "world"),
    (lambda: moving_poses(None, None, [1]), "world"),
    (lambda: MissionJob(b"x.db"), "archive_path"),
    (lambda: MissionJob(Path("x.db")).start(0, np.array(["small"])), "setting"),
    (lambda: LiveCameras("twin", size=(480, 640)), "twin"),
    (lambda: CameraProcess(seed=-1, layout="truss", size=(480, 640)), "seed"),
    (lambda: CameraProcess(seed=0, layout="moon", size=(480, 640)), "layout"),
    (lambda: CameraProcess(seed=0, layout="truss", size=(480, 640, 3)), "size"),
    (lambda: CameraProcess(seed=0, layout="truss", size=(480, 640), start_timeout_s=-1.0), "start_timeout_s"),
    (lambda: serve("127.0.0.1:8765"), "settings"),
    (lambda: TokenGate("app", "t" * 24), "app"),
    (lambda: TokenGate(_asgi, ""), "token"),
    (lambda: create_app("console", token="t" * 24, archive_path=Path("a.db")), "console"),
    (lambda: Console(live_size=(480,)), "size"),
    (lambda: Console(clock=3.0), "clock"),
]


@pytest.mark.parametrize(("call", "argument"), CASES, ids=[argument for _, argument in CASES])
def test_a_bad_argument_is_refused_by_name(call: Callable[[], Any], argument: str) -> None:
    with pytest.raises(InputError, match=argument):
        call()


def test_moving_poses_and_teleop_step_check_their_step_bodies_and_deadman() -> None:
    import rsi.sim

    world = rsi.sim.load("truss", seed=0, arm=True)
    try:
        with pytest.raises(InputError, match="step"):
            moving_poses(world, "step", [1])  # type: ignore[arg-type]
        with pytest.raises(InputError, match="bodies"):
            moving_poses(world, None, [world.model.nbody])
        with pytest.raises(InputError, match="held"):
            from rsi.web.teleop import teleop_loop

            teleop_step(teleop_loop(world.arm), np.zeros(3), held="yes")  # type: ignore[arg-type]
    finally:
        world.close()
