"""The console's API on the real server: the token on every route, no traversal, no cross-origin, the
control lock, hold-to-move with the server's watchdog, the latched e-stop, and 20 viewers at once."""

from __future__ import annotations

import contextlib
import http.client
import json
import re
import subprocess
import sys
import time
import warnings
from pathlib import Path
from typing import Any

import cv2
import httpx
import numpy as np
import pytest
import websockets
from websockets.sync.client import ClientConnection, connect

from rsi.archive import Archive, Finding
from rsi.errors import InputError
from rsi.sim.render import import_mujoco
from rsi.web import ExposedConsoleWarning, console_settings
from rsi.web.app import VIDEO_WINDOW
from rsi.web.console import LIVE_SIZE
from rsi.web.live import CAMERAS

from .conftest import ARTIFACTS, UVICORN_WEBSOCKETS_WARNING, Live

# uvicorn's websockets protocol (rsi.web.server.websocket_protocol) warns on every handshake
pytestmark = pytest.mark.filterwarnings(UVICORN_WEBSOCKETS_WARNING)

STOP_BUDGET_S = 0.2  # issue 16: the arm stops within 200 ms of release, blur, hidden tab or lost socket


def _ws(live: Live, path: str) -> str:
    return live.url.replace("http://", "ws://") + path


def _routes(live: Live) -> list[tuple[str, str]]:
    """Every (method, path) the app serves, path parameters filled in."""
    routes = []
    for route in live.app.app.routes:  # type: ignore[attr-defined]
        path = re.sub(r"\{[^}]+\}", "1", getattr(route, "path", ""))
        for method in sorted(getattr(route, "methods", None) or ()):
            if method != "HEAD":
                routes.append((method, path))
    return routes


def test_every_route_but_healthz_answers_401_without_the_token(live: Live) -> None:
    routes = _routes(live)
    assert len(routes) >= 18 and ("GET", "/api/status") in routes
    static = [("GET", "/static/console.js"), ("GET", "/static/vendor/three.module.min.js")]
    wrong = ({}, {"Authorization": "Bearer wrong-token-wrong-token"}, {"Authorization": live.token})
    for method, path in [*routes, *static]:
        for headers in wrong:
            response = httpx.request(method, live.url + path, headers=headers, timeout=30)
            expected = 200 if path == "/healthz" else 401
            assert response.status_code == expected, (method, path, headers)
    assert httpx.get(live.url + "/static/console.js", params={"token": live.token}).status_code == 200
    assert live.get("/api/status").status_code == 200


def test_every_websocket_answers_401_without_the_token(live: Live) -> None:
    paths = [r.path for r in live.app.app.routes if type(r).__name__ == "APIWebSocketRoute"]  # type: ignore[attr-defined]
    assert sorted(paths) == ["/ws/control", "/ws/state", "/ws/video"]
    for path in paths:
        for query in ("", "?token=wrong-token-wrong-token"):
            with pytest.raises(websockets.exceptions.InvalidStatus) as refused:
                connect(_ws(live, path + query), open_timeout=30).close()
            assert refused.value.response.status_code == 401


def test_no_request_reaches_a_file_outside_the_static_folder_or_the_archive(live: Live) -> None:
    secret = (Path(__file__).resolve().parents[2] / "src" / "rsi" / "web" / "app.py").read_text()[:200]
    host, port = live.url.removeprefix("http://").split(":")
    for raw in (
        "/static/../app.py",
        "/static/%2e%2e/app.py",
        "/static/..%2fapp.py",
        "/static/vendor/../../app.py",
        "/static/%2e%2e/%2e%2e/%2e%2e/pyproject.toml",
        "/api/shoot/image/..%2f..%2fapp.py",
        "/api/archive/findings/1/crop/..%2f..%2fapp.py",
    ):
        connection = http.client.HTTPConnection(host, int(port), timeout=30)
        connection.request("GET", raw + f"?token={live.token}")  # sent as written, not normalised
        response = connection.getresponse()
        body = response.read().decode("utf-8", "replace")
        connection.close()
        assert response.status in (400, 404), raw
        assert secret not in body and "[build-system]" not in body


def test_cross_origin_requests_are_refused_and_no_cors_header_is_sent(live: Live) -> None:
    headers = {"Authorization": f"Bearer {live.token}", "Origin": "http://evil.example"}
    assert httpx.get(live.url + "/api/status", headers=headers).status_code == 403
    preflight = httpx.options(
        live.url + "/api/estop", headers={**headers, "Access-Control-Request-Method": "POST"}
    )
    assert "access-control-allow-origin" not in preflight.headers
    same = live.get("/api/status", headers={"Origin": live.url})
    assert same.status_code == 200 and "access-control-allow-origin" not in same.headers
    with pytest.raises(websockets.exceptions.InvalidStatus) as refused:
        connect(_ws(live, f"/ws/state?token={live.token}"), origin="http://evil.example").close()  # type: ignore[arg-type]
    assert refused.value.response.status_code == 403


def test_status_is_the_live_state(live: Live) -> None:
    status = live.get("/api/status").json()
    assert set(status) >= {"arm", "teleop", "sensors", "sun", "video", "mission", "archive"}
    assert len(status["arm"]["joint_positions"]) == 8
    assert all(region in "ABCDEF-" for region in status["sensors"]["regions"])
    assert status["teleop"]["heartbeat_timeout_s"] + 1 / status["teleop"]["rate_hz"] < STOP_BUDGET_S
    assert status["video"]["size"] == list(LIVE_SIZE)


def test_the_3d_scene_shows_every_box_of_the_mockup_a_dented_one_s_mesh_too(live: Live) -> None:
    scene = live.get("/api/scene").json()
    drawn = np.array([sorted(shape["size"]) for shape in scene["shapes"]])
    parts = live.console.world.mockup.parts
    boxes = [sorted(part.size) for part in parts if part.shape == "box"]
    mujoco = import_mujoco()
    model = live.console.world.model
    assert (model.geom_type == mujoco.mjtGeom.mjGEOM_MESH).any()  # seed 0 dents the ORU's fill
    for box in boxes:  # a dented replacement's bounding box is its box within a millimetre
        assert np.abs(drawn - box).max(axis=1).min() < 1e-3, box


def test_the_cameras_render_while_someone_watches_and_idle_when_nobody_does(live: Live) -> None:
    with connect(_ws(live, f"/ws/video?cams=raw&token={live.token}"), open_timeout=30) as socket:
        for _ in range(12):
            socket.recv(timeout=10)
            socket.send("shown")
        video = live.get("/api/status").json()["video"]
        assert video["viewers"] >= 1 and video["fps"] > 0
    deadline = time.monotonic() + 10.0  # the handler notices the close within its 1 s wait, the loop then
    while time.monotonic() < deadline:
        video = live.get("/api/status").json()["video"]
        if video["viewers"] == 0 and video["fps"] == 0:
            break
        time.sleep(0.2)
    assert video["viewers"] == 0 and video["fps"] == 0, video


# ------------------------------------------------------------------------------------- control


def _control(live: Live) -> ClientConnection:
    return connect(_ws(live, f"/ws/control?token={live.token}"), open_timeout=30)


def _ask(socket: ClientConnection, message: dict[str, Any]) -> dict[str, Any]:
    socket.send(json.dumps(message))
    reply: dict[str, Any] = json.loads(socket.recv(timeout=10))
    return reply


def _hold(socket: ClientConnection, velocity_m_s: list[float], seconds: float) -> None:
    """The page's 20 Hz heartbeat for `seconds`."""
    end = time.monotonic() + seconds
    while time.monotonic() < end:
        socket.send(json.dumps({"type": "hold", "v": velocity_m_s}))
        time.sleep(0.05)


def _tool(live: Live) -> np.ndarray:
    return np.array(live.get("/api/status").json()["arm"]["tool_position_m"])


def _last_stop(live: Live, reason: str) -> dict[str, Any]:
    deadline = time.monotonic() + 5
    while time.monotonic() < deadline:
        stop = live.get("/api/status").json()["teleop"]["last_stop"]
        if stop and stop["reason"].startswith(reason) and stop["latency_s"] is not None:
            return dict(stop)
        time.sleep(0.05)
    pytest.fail(f"no stop {reason!r} was recorded")


def test_one_operator_holds_the_lock_and_the_others_watch(live: Live) -> None:
    with _control(live) as first, _control(live) as second:
        assert _ask(first, {"type": "acquire", "name": "ana"})["granted"] is True
        assert _ask(second, {"type": "acquire", "name": "ben"})["granted"] is False
        assert _ask(second, {"type": "hold", "v": [0.0, 0.05, 0.0]})["accepted"] is False
        assert live.get("/api/status").json()["teleop"]["operator"] == "ana"
        assert _ask(first, {"type": "leave"})["type"] == "leave"
        assert _ask(second, {"type": "acquire", "name": "ben"})["granted"] is True


def test_hold_moves_the_arm_and_release_stops_it_within_200_ms(live: Live) -> None:
    with _control(live) as socket:
        assert _ask(socket, {"type": "acquire"})["granted"]
        before = _tool(live)
        _hold(socket, [0.0, 0.05, 0.0], 0.6)
        socket.send(json.dumps({"type": "release", "reason": "pointer up"}))
        stop = _last_stop(live, "pointer up")
        still = _tool(live)
        time.sleep(0.3)
    assert np.linalg.norm(still - before) > 0.015  # 5 cm/s for 0.6 s, across the view
    assert stop["latency_s"] <= STOP_BUDGET_S
    assert np.allclose(_tool(live), still, atol=1e-4)


def test_a_lost_socket_mid_motion_stops_the_arm(live: Live) -> None:
    with _control(live) as socket:
        assert _ask(socket, {"type": "acquire"})["granted"]
        _hold(socket, [0.0, -0.05, 0.0], 0.4)
        socket.close()  # mid-motion: no release was sent
        stop = _last_stop(live, "socket closed")
    assert stop["latency_s"] <= STOP_BUDGET_S
    assert live.get("/api/status").json()["teleop"]["operator"] is None  # the lock is free again


def test_a_silent_page_is_stopped_by_the_server_watchdog(live: Live) -> None:
    with _control(live) as socket:
        assert _ask(socket, {"type": "acquire"})["granted"]
        _hold(socket, [0.0, 0.05, 0.0], 0.3)  # then the heartbeats stop but the socket stays open
        stop = _last_stop(live, "watchdog")
        assert stop["latency_s"] <= STOP_BUDGET_S
        assert live.get("/api/status").json()["arm"]["moving"] is False


def test_the_e_stop_latches_until_the_operator_resets_it(live: Live) -> None:
    with _control(live) as operator, _control(live) as watcher:
        assert _ask(operator, {"type": "acquire"})["granted"]
        assert live.post("/api/estop", {"reason": "test"}).json() == {"estop": True}  # anyone may press it
        before = _tool(live)
        assert _ask(operator, {"type": "hold", "v": [0.0, -0.05, 0.0]})["accepted"] is False
        time.sleep(0.3)
        assert np.allclose(_tool(live), before, atol=1e-5)
        assert live.get("/api/status").json()["teleop"]["estop"] is True
        assert _ask(watcher, {"type": "reset"})["reset"] is False  # only the operator may reset
        assert _ask(operator, {"type": "reset"})["reset"] is True
        latched_at = _tool(live)
        _hold(operator, [0.0, -0.05, 0.0], 0.4)  # moves again only after the reset
        assert _ask(operator, {"type": "release"})["type"] == "release"
        assert np.linalg.norm(_tool(live) - latched_at) > 0.01
        assert _ask(operator, {"type": "leave"})["type"] == "leave"
    assert live.get("/api/status").json()["teleop"]["estop"] is False


def test_bad_control_messages_are_named(live: Live) -> None:
    with _control(live) as socket:
        assert _ask(socket, {"type": "acquire"})["granted"]
        reply = _ask(socket, {"type": "hold", "v": [0.0, "fast", 0.0]})
        assert reply["type"] == "error" and "command_m_s must be 3 finite velocities" in reply["detail"]
        assert _ask(socket, {"type": "jump"}) == {"type": "error", "detail": "unknown message type 'jump'"}


def test_a_message_that_is_not_a_json_object_is_answered_and_the_socket_stays_open(live: Live) -> None:
    with _control(live) as socket:
        for message in (b"\x00\xff", "not json", "[" * 3000, "x" * 5000, "[1, 2]"):
            socket.send(message)
            reply = json.loads(socket.recv(timeout=10))
            assert reply["type"] == "error" and "JSON object" in reply["detail"], message
        assert _ask(socket, {"type": "jump"})["type"] == "error"  # still answering


def test_a_body_json_cannot_write_back_is_refused_by_field_not_a_server_error(live: Live) -> None:
    headers = {"Authorization": f"Bearer {live.token}", "Content-Type": "application/json"}
    for body in (b"NaN", b'{"orbit_time_s": NaN}', b'{"clock_rate": Infinity}', b"1e400"):
        response = httpx.post(live.url + "/api/sun", content=body, headers=headers, timeout=30)
        assert response.status_code == 422, (body, response.status_code)
        assert all("loc" in problem and "msg" in problem for problem in response.json()["detail"])


CLIENTS_SCRIPT = """
import asyncio, json, sys, time
import websockets

async def client(url, seconds):
    arrivals = []
    async with websockets.connect(url) as socket:
        end = time.monotonic() + seconds
        while time.monotonic() < end:
            message = await asyncio.wait_for(socket.recv(), timeout=5)
            arrivals.append((time.monotonic(), message[0], len(message)))
            await socket.send("shown")
    return arrivals

async def main():
    url, count, seconds = sys.argv[1], int(sys.argv[2]), float(sys.argv[3])
    print(json.dumps(await asyncio.gather(*(client(url, seconds) for _ in range(count)))))

asyncio.run(main())
"""


def _clients(url: str, count: int, seconds: float) -> subprocess.Popen[str]:
    """`count` video clients in another process (as other browsers are), for `seconds`."""
    command = [sys.executable, "-c", CLIENTS_SCRIPT, url, str(count), str(seconds)]
    return subprocess.Popen(command, stdout=subprocess.PIPE, text=True)


def test_twenty_viewers_while_the_controller_still_gets_10_fps(live: Live) -> None:
    """A bounded load test on loopback: 20 viewers of the three views for 9 s; the controller, in its own
    process, counts its frames of the ISEE view over 5 s while all of them are connected."""
    url = _ws(live, f"/ws/video?token={live.token}")
    rates = []
    for _ in range(2):  # a capability: a second bounded run where the shared 2 cores stalled the first
        viewers = _clients(url, 20, 9.0)
        time.sleep(2.0)  # every viewer connected
        controller = _clients(url.replace("/ws/video?", "/ws/video?cams=raw&"), 1, 5.0)
        (arrivals,) = json.loads(controller.communicate(timeout=60)[0])
        watched = json.loads(viewers.communicate(timeout=60)[0])
        times = [t for t, _, _ in arrivals]
        rates.append((len(times) - 1) / (times[-1] - times[0]))
        if rates[-1] >= 10.0:
            break
    fps = rates[-1]
    ARTIFACTS.mkdir(parents=True, exist_ok=True)
    viewer_rates = [len(a) / 9.0 for a in watched]
    record = {"controller_fps": rates, "viewer_ticks_per_s_min": min(viewer_rates)}
    (ARTIFACTS / "console-twenty-viewers.json").write_text(json.dumps(record, indent=1))
    assert fps >= 10.0, f"controller got {rates} frames/s with 20 viewers"
    assert all(camera == CAMERAS.index("raw") for _, camera, _ in arrivals)  # only the view it asked for
    assert len(watched) == 20 and min(len(a) for a in watched) >= 9 * 5  # each viewer >= 5 ticks/s too


def _frame_age_ms(message: bytes) -> float:
    """Now minus the exposure time in the message's first chunk (rsi.web.live.video_message)."""
    (exposed_ms,) = np.frombuffer(message[5:13], dtype="<f8")
    return time.time() * 1000.0 - float(exposed_ms)


def test_a_viewer_slower_than_the_camera_gets_fresh_frames_not_a_growing_queue(live: Live) -> None:
    """A page that shows ~3 frames/s of a 15 frames/s camera: every frame it shows is about one of its
    own periods old; without the acknowledgement window they queued in the socket and aged by 0.27 s
    per frame shown (the browser test's badge read 9.5 s in the whole suite's run)."""
    ages = []
    with connect(_ws(live, f"/ws/video?cams=raw&token={live.token}"), open_timeout=30) as socket:
        for _ in range(16):
            ages.append(_frame_age_ms(socket.recv(timeout=10)))  # type: ignore[arg-type]
            time.sleep(0.3)
            socket.send("shown")
    assert max(ages[-6:]) < 1000.0, ages


def test_a_viewer_that_acknowledges_nothing_is_sent_at_most_the_window(live: Live) -> None:
    with connect(_ws(live, f"/ws/video?cams=raw&token={live.token}"), open_timeout=30) as socket:
        got = [socket.recv(timeout=10) for _ in range(VIDEO_WINDOW)]  # a loaded machine's slow frames too
        with contextlib.suppress(TimeoutError):
            for _ in range(VIDEO_WINDOW + 4):  # bounded: a server that never waits fails here, not hangs
                got.append(socket.recv(timeout=2.0))
        assert len(got) == VIDEO_WINDOW
        socket.send("shown")
        assert _frame_age_ms(socket.recv(timeout=10)) < 1000.0  # the newest frame, not the next queued


# ------------------------------------------------------------------------------------- inspection at hand


def test_a_reference_and_an_inspection_at_the_same_pose_register_with_no_shift(live: Live) -> None:
    assert live.post("/api/shoot/reference").json()["images"] == ["reference"]
    shot = live.post("/api/shoot/inspection").json()
    assert shot["images"] == ["difference", "inspection", "reference", "score"]
    shift = shot["summary"]["registration_xy_px"]
    assert np.hypot(*shift) < 0.5  # the camera did not move between the two: no visit error at hand
    for name in shot["images"]:
        image = cv2.imdecode(np.frombuffer(live.get(f"/api/shoot/image/{name}").content, np.uint8), 1)
        assert image.shape[:2] == (480, 640)
    assert live.post("/api/shoot/sideways").status_code == 400


def test_sun_and_lamp_controls_move_the_lamp(live: Live) -> None:
    noon = live.post("/api/sun", {"orbit_time_s": 400.0}).json()
    later = live.post("/api/sun", {"orbit_time_s": 1000.0}).json()
    assert noon["sun_world"] != later["sun_world"] and noon["spot_m"] == later["spot_m"]
    assert live.post("/api/lamp", {"on": False}).json()["lamp_on"] is False
    assert live.post("/api/lamp", {"on": True}).json()["lamp_on"] is True
    assert live.post("/api/sun", {"clock_rate": 1e6}).status_code == 422
    assert live.post("/api/sun", {"orbit_time_s": 400.0}).status_code == 200


# ------------------------------------------------------------------------------------- archive


def test_archive_runs_findings_crops_history_and_a_review(live: Live) -> None:
    image = np.tile(np.linspace(0, 1, 64, dtype=np.float32), (48, 1))
    with Archive.open(live.archive) as store:
        store.add_vista("A_door")
        digest = store.store_image(image)
        ids = []
        for _ in range(2):  # the same flaw seen in two runs: one track
            run = store.start_run(seed=7, label="api test")
            store.add_findings(
                run,
                [Finding("A_door", "impact", 0.8, position_m=(0.1, 0.2, 1.0), bbox=(10, 10, 14, 14),
                         size_m=0.004, reference_sha256=digest, inspection_sha256=digest)],
            )  # fmt: skip
            store.finish_run(run)
            ids.append(store.findings(run)[0].finding_id)
    runs = live.get("/api/archive/runs").json()
    assert runs[0]["label"] == "api test" and runs[0]["finding_count"] == 1
    findings = live.get(f"/api/archive/runs/{runs[0]['id']}/findings").json()
    assert findings[0]["id"] == ids[1] and findings[0]["review"] is None
    assert findings[0]["images"] == ["reference", "inspection"]
    png = live.get(f"/api/archive/findings/{ids[1]}/crop/inspection").content
    crop = cv2.imdecode(np.frombuffer(png, np.uint8), 0)
    assert crop is not None and crop.shape[0] >= 38  # the box and its margin, clipped to the image
    history = live.get(f"/api/archive/findings/{ids[1]}/history").json()
    assert [s["id"] for s in history] == ids
    verdict = {"verdict": "rejected", "note": "glint"}
    reviewed = live.post(f"/api/archive/findings/{ids[1]}/review", verdict).json()
    assert reviewed["review"] == {"verdict": "rejected", "note": "glint", "reviewer": "operator"}
    with Archive.open(live.archive) as store:
        assert store.reviews(ids[1])[-1].verdict == "rejected"
    assert live.post(f"/api/archive/findings/{ids[1]}/review", {"verdict": "maybe"}).status_code == 422
    assert live.get("/api/archive/findings/99999/history").status_code == 400
    replay = live.get(f"/api/archive/runs/{runs[0]['id']}/replay").json()
    assert [step["vista"] for step in replay["steps"]] == ["A_door"]


# ------------------------------------------------------------------------------------- settings


def test_console_settings_name_the_bad_argument(tmp_path: Path) -> None:
    settings = console_settings(archive=tmp_path / "a.db", token="a" * 20)
    assert settings.url == f"http://127.0.0.1:8765/?token={'a' * 20}"
    assert len(console_settings().token) >= 16  # a random one when none is given
    with pytest.raises(InputError, match=r"host must be an IP address such as 127.0.0.1; got 'localhost'"):
        console_settings(host="localhost")
    with pytest.raises(InputError, match=r"port must be an integer in \[0, 65535\]; got 70000"):
        console_settings(port=70000)
    with pytest.raises(InputError, match=r"seed must be an integer in \[0, 2\*\*63\); got -1"):
        console_settings(seed=-1)
    with pytest.raises(InputError, match=r"layout"):
        console_settings(layout="station")
    with pytest.raises(InputError, match=r"token must be at least 16 characters"):
        console_settings(token="short")
    with pytest.raises(InputError, match=r"is a folder; give the archive's file"):
        console_settings(archive=tmp_path)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        console_settings(host="127.0.0.1")  # loopback: no warning
    with pytest.warns(ExposedConsoleWarning, match=r"listens beyond this machine"):
        console_settings(host="0.0.0.0")
