"""The console's HTTP and websocket API (FastAPI) and its one page.

Security (issue 16): every route and websocket needs the token (``Authorization: Bearer T`` or
``?token=T``) except ``GET /healthz``; a request without it gets 401 before any route runs
(:class:`TokenGate`, an ASGI layer under everything, websockets included). No CORS headers are ever sent,
and a request whose ``Origin`` is not this server is refused (403), so another site's page cannot drive the
arm even through a browser that holds the token. Files are served from the package's ``static`` folder
(Starlette refuses paths that leave it) and, from the archive, only as images named by their SHA-256, which
the archive checks; no request names a path on disk.
"""

from __future__ import annotations

import asyncio
import contextlib
import html
import json
import secrets
from collections.abc import AsyncIterator, Awaitable, Callable, MutableMapping
from importlib import resources
from pathlib import Path
from typing import Any

import cv2
import numpy as np
from fastapi import FastAPI, HTTPException, WebSocket, WebSocketDisconnect
from fastapi.exceptions import RequestValidationError
from fastapi.responses import HTMLResponse, JSONResponse, Response
from fastapi.staticfiles import StaticFiles
from pydantic import BaseModel, Field

from rsi.archive import REVIEW_VERDICTS, Archive
from rsi.errors import InputError
from rsi.web.console import Console, new_client_id
from rsi.web.live import CAMERAS, AckWindow, FrameHub
from rsi.web.mission_job import SETTINGS, MissionJob
from rsi.web.scene import moving_poses, scene_geometry

Scope = MutableMapping[str, Any]
Message = MutableMapping[str, Any]
Receive = Callable[[], Awaitable[Message]]
Send = Callable[[Message], Awaitable[None]]
ASGIApp = Callable[[Scope, Receive, Send], Awaitable[None]]

OPEN_PATHS = ("/healthz",)
STATE_HZ = 10.0  # telemetry and poses to every viewer
CONTROL_MESSAGE_LIMIT = 4096  # characters; the largest operator message (a hold) is under 100
CROP_MARGIN_PX = 24
VERDICT_PATTERN = "^(" + "|".join(REVIEW_VERDICTS) + ")$"


def _token_of(scope: Scope) -> str | None:
    """The token a request carries (``Authorization: Bearer T`` or ``?token=T``), or None."""
    for name, value in scope.get("headers", []):
        if name == b"authorization":
            scheme, _, token = value.decode("latin-1").partition(" ")
            if scheme.lower() == "bearer":
                return str(token.strip())
    from urllib.parse import parse_qs

    query = parse_qs(scope.get("query_string", b"").decode("latin-1"))
    values = query.get("token")
    return values[0] if values else None


def _same_origin(scope: Scope) -> bool:
    """True without an Origin header (not a browser's cross-site request) or when it names this server."""
    headers = dict(scope.get("headers", []))
    origin = headers.get(b"origin")
    if origin is None:
        return True
    host = headers.get(b"host", b"").decode("latin-1")
    return origin.decode("latin-1") in (f"http://{host}", f"https://{host}")


def _named_problems(error: RequestValidationError) -> list[dict[str, Any]]:
    """A refused request's problems, each naming its field, without echoing the input: FastAPI's own answer
    carries the input, and a body of NaN or 1e400 cannot be written back as JSON (it was a 500)."""
    return [
        {"loc": [str(part) for part in problem.get("loc", ())], "msg": str(problem.get("msg", ""))}
        for problem in error.errors()
    ]


def _check_token(token: object) -> None:
    if not isinstance(token, str) or not token:
        raise InputError("token must be a non-empty string (the secret every request carries).")


class TokenGate:
    """ASGI layer: 401 for every request without the token but ``GET /healthz``; 403 cross-origin."""

    def __init__(self, app: ASGIApp, token: str) -> None:
        if not callable(app):
            raise InputError(f"app must be an ASGI application; got {type(app).__name__}.")
        _check_token(token)
        self.app = app
        self.token = token

    def _allowed(self, scope: Scope) -> bool:
        given = _token_of(scope)
        return given is not None and secrets.compare_digest(given.encode(), self.token.encode())

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        kind = scope["type"]
        if kind not in ("http", "websocket"):
            await self.app(scope, receive, send)
            return
        if kind == "http" and scope["path"] in OPEN_PATHS and scope["method"] in ("GET", "HEAD"):
            await self.app(scope, receive, send)
            return
        status = 0 if self._allowed(scope) else 401
        if status == 0 and not _same_origin(scope):
            status = 403
        if status == 0:
            await self.app(scope, receive, send)
        elif kind == "http":
            await _plain(send, status)
        else:
            await _deny_websocket(scope, receive, send, status)


_REASONS = {401: b"token required: Authorization: Bearer <token> or ?token=<token>", 403: b"cross-origin"}


async def _plain(send: Send, status: int, prefix: str = "http") -> None:
    body = json.dumps({"detail": _REASONS[status].decode()}).encode()
    headers = [(b"content-type", b"application/json"), (b"content-length", str(len(body)).encode())]
    if status == 401:
        headers.append((b"www-authenticate", b"Bearer"))
    await send({"type": f"{prefix}.response.start", "status": status, "headers": headers})
    await send({"type": f"{prefix}.response.body", "body": body})


async def _deny_websocket(scope: Scope, receive: Receive, send: Send, status: int) -> None:
    await receive()  # websocket.connect
    if "websocket.http.response" in scope.get("extensions", {}):
        await _plain(send, status, prefix="websocket.http")
    else:  # a server without the denial extension can only close the handshake (HTTP 403)
        await send({"type": "websocket.close", "code": 1008})


# ---------------------------------------------------------------------------------------- requests


class SunRequest(BaseModel):
    orbit_time_s: float | None = Field(default=None, ge=0.0, le=1e7)
    clock_rate: float | None = Field(default=None, ge=0.0, le=600.0)


class LampRequest(BaseModel):
    on: bool | None = None
    halogen: bool | None = None


class MissionRequest(BaseModel):
    seed: int = Field(default=0, ge=0, lt=2**31)
    setting: str = Field(default="small", pattern="^(" + "|".join(SETTINGS) + ")$")


class ReviewRequest(BaseModel):
    verdict: str = Field(pattern=VERDICT_PATTERN)
    note: str = Field(default="", max_length=10_000)
    reviewer: str = Field(default="operator", min_length=1, max_length=200)


class EstopRequest(BaseModel):
    reason: str = Field(default="e-stop from the page", max_length=200)


# ---------------------------------------------------------------------------------------- the app


def _page(token: str) -> str:
    template = resources.files("rsi.web").joinpath("static/index.html").read_text(encoding="utf-8")
    nonce = secrets.token_urlsafe(16)
    quoted = html.escape(token, quote=True)
    return template.replace("{{TOKEN}}", quoted).replace("{{NONCE}}", nonce)


def _csp(page: str) -> str:
    start = page.index('nonce="') + len('nonce="')
    nonce = page[start : page.index('"', start)]
    return (
        f"default-src 'self'; script-src 'self' 'nonce-{nonce}'; style-src 'self'; "
        "img-src 'self' blob: data:; "
        "connect-src 'self'; frame-ancestors 'none'; base-uri 'none'; form-action 'none'"
    )


def _crop(image: Any, bbox: tuple[int, int, int, int] | None) -> bytes:
    """PNG of a stored image around a finding's box, stretched for display."""
    stored = np.asarray(image)
    if stored.dtype == np.uint8 and stored.ndim == 1:  # encoded bytes
        stored = np.asarray(cv2.imdecode(stored, cv2.IMREAD_UNCHANGED))
    array = np.asarray(stored, dtype=np.float64)
    if array.ndim == 3:
        array = array.mean(axis=2)
    if bbox is not None:
        row0, col0, row1, col1 = bbox
        rows, cols = array.shape[:2]
        array = array[
            max(0, row0 - CROP_MARGIN_PX) : min(rows, row1 + CROP_MARGIN_PX),
            max(0, col0 - CROP_MARGIN_PX) : min(cols, col1 + CROP_MARGIN_PX),
        ]
    finite = np.nan_to_num(array)
    low, high = np.percentile(finite, [1, 99]) if finite.size else (0.0, 1.0)
    scaled = np.clip((finite - low) * (255.0 / max(high - low, 1e-9)), 0, 255).astype(np.uint8)
    scale = max(1, 96 // max(1, min(scaled.shape)))
    larger = cv2.resize(scaled, None, fx=scale, fy=scale, interpolation=cv2.INTER_NEAREST)
    return bytes(cv2.imencode(".png", larger)[1].tobytes())


def _finding_json(archive: Archive, finding: Any) -> dict[str, Any]:
    reviews = archive.reviews(finding.finding_id)
    return {
        "id": finding.finding_id,
        "run_id": finding.run_id,
        "vista": finding.vista,
        "kind": finding.kind,
        "confidence": round(finding.confidence, 3),
        "position_m": finding.position_m,
        "bbox": finding.bbox,
        "size_m": finding.size_m,
        "score": finding.score,
        "track_id": finding.track_id,
        "previous_id": finding.previous_id,
        "seen_at": finding.seen_at.isoformat(),
        "images": [
            which for which in ("reference", "inspection") if getattr(finding, f"{which}_sha256") is not None
        ],
        "review": None
        if not reviews
        else {"verdict": reviews[-1].verdict, "note": reviews[-1].note, "reviewer": reviews[-1].reviewer},
    }


def create_app(console: Console, *, token: str, archive_path: Path) -> Any:
    """The console's ASGI application (FastAPI wrapped in :class:`TokenGate`).

    Parameters
    ----------
    console : Console
        Started by the app's lifespan and stopped with it.
    token : str
        The secret every request but ``GET /healthz`` must carry.
    archive_path : Path
        The SQLite archive missions write to and the page browses.
    """
    if not isinstance(console, Console):
        raise InputError(f"console must be an rsi.web.console.Console; got {type(console).__name__}.")
    mission = MissionJob(archive_path)
    _check_token(token)

    @contextlib.asynccontextmanager
    async def lifespan(_: FastAPI) -> AsyncIterator[None]:
        console.hub.bind(asyncio.get_running_loop())
        await asyncio.to_thread(console.start)
        try:
            yield
        finally:
            mission.stop()
            await asyncio.to_thread(console.stop)

    api = FastAPI(title="rsi operator console", lifespan=lifespan, docs_url=None, redoc_url=None)
    static = resources.files("rsi.web").joinpath("static")
    api.mount("/static", StaticFiles(directory=str(static)), name="static")

    @api.middleware("http")
    async def headers(request: Any, call_next: Any) -> Any:
        response = await call_next(request)
        response.headers["X-Content-Type-Options"] = "nosniff"
        response.headers["Cache-Control"] = "no-store"
        response.headers["Referrer-Policy"] = "no-referrer"
        return response

    @api.exception_handler(InputError)
    async def input_error(_: Any, error: InputError) -> JSONResponse:
        return JSONResponse({"detail": str(error)}, status_code=400)

    @api.exception_handler(RequestValidationError)
    async def invalid_request(_: Any, error: RequestValidationError) -> JSONResponse:
        return JSONResponse({"detail": _named_problems(error)}, status_code=422)

    @api.get("/healthz")
    def healthz() -> dict[str, bool]:
        return {"ok": True}

    @api.get("/", response_class=HTMLResponse)
    def page() -> HTMLResponse:
        text = _page(token)
        return HTMLResponse(text, headers={"Content-Security-Policy": _csp(text)})

    _live_routes(api, console, mission, archive_path)
    _archive_routes(api, archive_path)
    _socket_routes(api, console, mission)
    return TokenGate(api, token)


def _live_routes(api: FastAPI, console: Console, mission: MissionJob, archive_path: Path) -> None:
    """Status, scene, e-stop, sun and lamp, the inspection at hand, the mission."""

    @api.get("/api/status")
    def status() -> dict[str, Any]:
        return {**console.status(), "mission": mission.state(), "archive": str(archive_path)}

    @api.get("/api/scene")
    def scene() -> dict[str, Any]:
        with console.lock:
            return scene_geometry(console.world)

    @api.post("/api/estop")
    def estop(request: EstopRequest) -> dict[str, Any]:
        console.estop(request.reason)
        return {"estop": True}

    @api.post("/api/sun")
    def sun(request: SunRequest) -> dict[str, Any]:
        if request.orbit_time_s is not None:
            console.set_orbit_time(request.orbit_time_s)
        if request.clock_rate is not None:
            console.set_clock_rate(request.clock_rate)
        return console.status()["sun"]  # type: ignore[no-any-return]

    @api.post("/api/lamp")
    def lamp(request: LampRequest) -> dict[str, Any]:
        console.set_lamp(on=request.on, halogen=request.halogen)
        return console.status()["sun"]  # type: ignore[no-any-return]

    @api.post("/api/shoot/{kind}")
    def shoot(kind: str) -> dict[str, Any]:
        shot = console.shoot(kind)
        return {
            "kind": shot.kind,
            "flaws": shot.flaws,
            "summary": shot.summary,
            "images": sorted(shot.images),
        }

    @api.get("/api/shoot")
    def last_shot() -> dict[str, Any]:
        """The last shot anyone took (watchers see the operator's), 404 before the first."""
        shot = console.last_shot
        if shot is None:
            raise HTTPException(404, "no shot yet: take a reference or an inspection first")
        return {
            "kind": shot.kind,
            "flaws": shot.flaws,
            "summary": shot.summary,
            "images": sorted(shot.images),
            "seq": console.shot_seq,
        }

    @api.get("/api/shoot/image/{name}")
    def shot_image(name: str) -> Response:
        shot = console.last_shot
        if shot is None or name not in shot.images:
            raise HTTPException(404, f"no {name!r} image: take a reference or an inspection first")
        return Response(shot.images[name], media_type="image/jpeg")

    @api.post("/api/mission")
    def start_mission(request: MissionRequest) -> dict[str, Any]:
        return mission.start(request.seed, request.setting)

    @api.get("/api/mission")
    def mission_state() -> dict[str, Any]:
        return mission.state()


def _archive_routes(api: FastAPI, archive_path: Path) -> None:
    """Runs, findings and their crops, a flaw's sightings, reviews, a run's replay."""

    def archive() -> Archive:
        return Archive.open(archive_path)

    @api.get("/api/archive/runs")
    def runs() -> list[dict[str, Any]]:
        with archive() as store:
            return [
                {
                    "id": run.run_id,
                    "label": run.label,
                    "status": run.status,
                    "seed": run.seed,
                    "started_at": run.started_at.isoformat(),
                    "finished_at": None if run.finished_at is None else run.finished_at.isoformat(),
                    "finding_count": run.finding_count,
                }
                for run in reversed(store.runs())
            ]

    @api.get("/api/archive/runs/{run_id}/findings")
    def run_findings(run_id: int) -> list[dict[str, Any]]:
        with archive() as store:
            return [_finding_json(store, f) for f in store.findings(run_id)]

    @api.get("/api/archive/runs/{run_id}/replay")
    def replay(run_id: int) -> dict[str, Any]:
        """The run's vistas in the order it reported them, with their camera poses and findings."""
        with archive() as store:
            findings = store.findings(run_id)
            steps: dict[str, dict[str, Any]] = {}
            for finding in findings:
                if finding.vista not in steps:
                    vista = store.vista(finding.vista)
                    steps[finding.vista] = {
                        "vista": vista.name,
                        "position_m": vista.position_m,
                        "forward": vista.forward,
                        "target_m": vista.target_m,
                        "findings": [],
                    }
                steps[finding.vista]["findings"].append(_finding_json(store, finding))
            return {"run_id": run_id, "steps": list(steps.values())}

    @api.get("/api/archive/findings/{finding_id}/history")
    def history(finding_id: int) -> list[dict[str, Any]]:
        with archive() as store:
            return [_finding_json(store, f) for f in store.history(finding_id).sightings]

    @api.get("/api/archive/findings/{finding_id}/crop/{which}")
    def crop(finding_id: int, which: str) -> Response:
        if which not in ("reference", "inspection"):
            raise HTTPException(404, "which must be reference or inspection")
        with archive() as store:
            finding = store.finding(finding_id)
            digest = getattr(finding, f"{which}_sha256")
            if digest is None:
                raise HTTPException(404, f"finding {finding_id} has no {which} image")
            image = store.image(digest)
        if isinstance(image, bytes):
            image = np.frombuffer(image, dtype=np.uint8)
        return Response(_crop(image, finding.bbox), media_type="image/png")

    @api.post("/api/archive/findings/{finding_id}/review")
    def review(finding_id: int, request: ReviewRequest) -> dict[str, Any]:
        with archive() as store:
            store.review_finding(finding_id, request.verdict, note=request.note, reviewer=request.reviewer)
            return _finding_json(store, store.finding(finding_id))


# Video messages a viewer may hold unshown: one on screen while the next is on its way (AckWindow)
VIDEO_WINDOW = 2


async def _read_acks(socket: WebSocket, window: AckWindow) -> None:
    """Every message a video viewer sends acknowledges one frame message shown; returns when it leaves."""
    with contextlib.suppress(WebSocketDisconnect, RuntimeError):
        while (await socket.receive())["type"] != "websocket.disconnect":
            window.shown()


async def _send_video(
    socket: WebSocket, hub: FrameHub, wanted: list[str], window: AckWindow, acks: asyncio.Task[None]
) -> None:
    """The newest frames of the `wanted` cameras, one message per tick, while the viewer keeps up."""
    sent: dict[str, int] = {}
    while not acks.done():
        if not await window.room():
            continue
        fresh = [
            frame for name, frame in hub.snapshot().items() if name in wanted and sent.get(name) != frame.seq
        ]
        if not fresh:
            await hub.wait()
            continue
        await socket.send_bytes(b"".join(frame.message for frame in fresh))
        window.sent()
        sent.update((frame.camera, frame.seq) for frame in fresh)


def _socket_routes(api: FastAPI, console: Console, mission: MissionJob) -> None:
    """Video (binary JPEG), state (JSON at 10 Hz) and control (the operator's messages)."""

    @api.websocket("/ws/video")
    async def video(socket: WebSocket) -> None:
        wanted = [
            c for c in (socket.query_params.get("cams") or ",".join(CAMERAS)).split(",") if c in CAMERAS
        ]
        await socket.accept()
        window = AckWindow(VIDEO_WINDOW)
        acks = asyncio.create_task(_read_acks(socket, window))
        console.hub.viewer(joined=True)
        try:
            await _send_video(socket, console.hub, wanted, window, acks)
        except (WebSocketDisconnect, RuntimeError):
            return
        finally:
            console.hub.viewer(joined=False)
            acks.cancel()

    @api.websocket("/ws/state")
    async def state(socket: WebSocket) -> None:
        await socket.accept()
        with console.lock:
            moving = scene_geometry(console.world)["moving"]
        last_t = -1.0
        try:
            while True:
                with console.lock:
                    samples = [s for s in console.telemetry if s["t"] > last_t]
                    poses = moving_poses(console.world, console.last_step, moving)
                if samples:
                    last_t = samples[-1]["t"]
                status_now = console.status()
                status_now["mission"] = mission.state()
                await socket.send_text(json.dumps({"status": status_now, "samples": samples, "poses": poses}))
                await asyncio.sleep(1.0 / STATE_HZ)
        except (WebSocketDisconnect, RuntimeError):
            return

    @api.websocket("/ws/control")
    async def control(socket: WebSocket) -> None:
        """Operator messages: acquire, hold (20 Hz heartbeat), release, estop, reset, leave."""
        await socket.accept()
        client = new_client_id()
        try:
            while True:
                reply = _control_message(console, client, _json_text(await socket.receive()))
                if reply is not None:
                    await socket.send_text(json.dumps(reply))
        except (WebSocketDisconnect, RuntimeError):
            pass
        finally:  # a lost socket stops the arm at once and frees the lock
            console.release(client, "socket closed")
            console.release_control(client, "socket closed")


def _json_text(message: Message) -> Any:
    """The JSON a control message carries, or None (answered as an unknown message, the socket kept open)
    when it is binary, not JSON or too long; a disconnect ends the handler."""
    if message["type"] == "websocket.disconnect":
        raise WebSocketDisconnect(message.get("code", 1000))
    text = message.get("text")
    if not isinstance(text, str) or len(text) > CONTROL_MESSAGE_LIMIT:
        return None
    try:
        return json.loads(text)
    except (json.JSONDecodeError, RecursionError):
        return None


def _control_message(console: Console, client: str, message: Any) -> dict[str, Any] | None:
    """Act on one operator message; the reply, or None for an accepted heartbeat (no 20 Hz of replies)."""
    if not isinstance(message, dict):
        return {
            "type": "error",
            "detail": f"a control message is a JSON object of at most {CONTROL_MESSAGE_LIMIT} characters "
            "with a type (acquire, hold, release, estop, reset, leave)",
        }
    kind = message.get("type")
    reply: dict[str, Any] = {"type": kind}
    if kind == "acquire":
        reply["granted"] = console.acquire(client, str(message.get("name", "operator")))
    elif kind == "hold":
        try:
            reply["accepted"] = console.hold(client, message.get("v"))
        except InputError as error:
            console.release(client, "bad command")
            return {"type": "error", "detail": str(error)}
        if reply["accepted"]:
            return None
    elif kind == "release":
        console.release(client, str(message.get("reason", "release"))[:64])
    elif kind == "estop":
        console.estop(str(message.get("reason", "e-stop"))[:200])
    elif kind == "reset":
        reply["reset"] = console.reset_estop(client)
    elif kind == "leave":
        console.release_control(client)
    else:
        return {"type": "error", "detail": f"unknown message type {kind!r}"}
    return reply


__all__ = ["OPEN_PATHS", "TokenGate", "create_app"]
