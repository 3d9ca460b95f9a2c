"""One live console for the web tests: the real server (uvicorn) on a free loopback port, in this process."""

from __future__ import annotations

import os
import socket
import threading
import time
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import httpx
import pytest

os.environ.setdefault("MUJOCO_GL", "egl")

TOKEN = "console-test-token-0123456789"
UVICORN_WEBSOCKETS_WARNING = "ignore:remove second argument of ws_handler:DeprecationWarning"
ARTIFACTS = Path(__file__).resolve().parents[2] / "build" / "test-artifacts" / "console"


@dataclass(frozen=True)
class Live:
    url: str
    token: str
    console: object  # rsi.web.console.Console
    archive: Path
    app: object

    def get(self, path: str, headers: dict[str, str] | None = None) -> httpx.Response:
        return httpx.get(
            self.url + path, headers={"Authorization": f"Bearer {self.token}", **(headers or {})}, timeout=60
        )

    def post(self, path: str, body: object = None) -> httpx.Response:
        return httpx.post(
            self.url + path, json=body or {}, headers={"Authorization": f"Bearer {self.token}"}, timeout=120
        )


def _free_port() -> int:
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        return int(probe.getsockname()[1])


@pytest.fixture(scope="session")
def live(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Live]:
    import uvicorn

    from rsi.web.app import create_app
    from rsi.web.console import Console
    from rsi.web.server import uvicorn_options

    archive = tmp_path_factory.mktemp("console") / "archive.db"
    console = Console(seed=0)
    app = create_app(console, token=TOKEN, archive_path=archive)
    port = _free_port()
    server = uvicorn.Server(uvicorn.Config(app, host="127.0.0.1", port=port, **uvicorn_options()))
    thread = threading.Thread(target=server.run, daemon=True)
    thread.start()
    url = f"http://127.0.0.1:{port}"
    deadline = time.monotonic() + 180
    while time.monotonic() < deadline:
        try:
            if httpx.get(url + "/healthz", timeout=2).status_code == 200 and console.hub.snapshot():
                break
        except httpx.HTTPError:
            pass
        time.sleep(0.2)
    else:
        pytest.fail("the console did not start in 180 s")
    yield Live(url, TOKEN, console, archive, app)
    server.should_exit = True
    thread.join(timeout=30)
