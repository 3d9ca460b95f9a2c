"""The console's HTTP routes and its control socket under hostile input, on the real server (issue 17).

1,000 generated requests per route (hostile JSON bodies, non-JSON bytes, hostile path segments): every one
is answered with a client error or a success, never a server error, and the server still answers after. The
control socket gets 1,000 hostile messages on one connection: each is answered, the socket stays open. The
drawn values that would start real work (a mission, a shot) are left out: tests/web runs those for real.
"""

from __future__ import annotations

import json
from collections.abc import Iterator
from typing import Any
from urllib.parse import quote

import httpx
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from rsi.web.mission_job import SETTINGS
from rsi.web.worker import SHOT_KINDS

from .conftest import UVICORN_WEBSOCKETS_WARNING, Live

pytestmark = pytest.mark.filterwarnings(UVICORN_WEBSOCKETS_WARNING)

CASES = 1000
FIELDS = ("reason", "orbit_time_s", "clock_rate", "on", "halogen", "seed", "setting", "verdict", "note")
FIELDS += ("reviewer", "type", "v", "name")

_LEAVES = st.one_of(
    st.none(),
    st.booleans(),
    st.integers(min_value=-(2**70), max_value=2**70),
    st.sampled_from([10**400, -(10**400), 2**63, -1, 0, 1e308, -0.0, 5e-324]),
    st.floats(allow_nan=False, allow_infinity=False),
    st.text(max_size=20),
    st.sampled_from(["", "x" * 20000, "../../etc/passwd", "confirmed", "small", "full", "<script>"]),
)
JSON_VALUES = st.recursive(
    _LEAVES,
    lambda children: st.one_of(
        st.lists(children, max_size=4),
        st.dictionaries(st.one_of(st.sampled_from(FIELDS), st.text(max_size=6)), children, max_size=5),
    ),
    max_leaves=12,
)
BODIES = st.one_of(
    JSON_VALUES.map(lambda value: json.dumps(value).encode()),
    st.binary(max_size=64),
    st.sampled_from([b"", b"NaN", b"1e400", b'{"orbit_time_s": NaN}', b'{"seed": Infinity}', b"[" * 5000]),
)
SEGMENTS = st.one_of(
    st.text(max_size=30).filter(lambda s: s not in ("", ".", "..")).map(lambda s: quote(s, safe="")),
    st.sampled_from(
        ["%2e%2e", "..%2f..%2fetc", "-1", "0", "1", "2", str(2**63), "9" * 40, "1e3", "%00", "raw"]
    ),
)
ROUTES = (
    ("POST", "/api/estop"),
    ("POST", "/api/sun"),
    ("POST", "/api/lamp"),
    ("POST", "/api/mission"),
    ("POST", "/api/shoot/{}"),
    ("GET", "/api/shoot/image/{}"),
    ("GET", "/api/archive/runs/{}/findings"),
    ("GET", "/api/archive/runs/{}/replay"),
    ("GET", "/api/archive/findings/{}/history"),
    ("GET", "/api/archive/findings/{}/crop/{}"),
    ("POST", "/api/archive/findings/{}/review"),
)


STARTS_WORK = ("/api/mission", "/api/shoot/{}")


def _starts_work(path: str, body: bytes) -> bool:
    """Whether a drawn request would launch a mission or take a shot (left to the functional tests)."""
    if path.startswith("/api/shoot/") and not path.startswith("/api/shoot/image/"):
        return path.rsplit("/", 1)[1] in SHOT_KINDS
    if path != "/api/mission":
        return False
    try:
        request = json.loads(body)
    except (ValueError, RecursionError):
        return False
    if not isinstance(request, dict):
        return False
    seed, setting = request.get("seed", 0), request.get("setting", "small")
    return isinstance(setting, str) and setting in SETTINGS and isinstance(seed, (int, float))


@pytest.fixture
def restored(live: Live) -> Iterator[None]:
    """Leave the live console as it was: no e-stop, the same orbit time and clock rate, the same lamps."""
    console: Any = live.console
    before = (console.orbit_time_s, console.clock_rate, console.world.lamp_on, console.world.halogen_on)
    yield
    console.acquire("hostile-restore", "restore")
    console.reset_estop("hostile-restore")
    console.release_control("hostile-restore")
    console.set_clock_rate(before[1])
    console.set_orbit_time(before[0])
    console.set_lamp(on=before[2], halogen=before[3])


@pytest.fixture
def client(live: Live, restored: None) -> Iterator[httpx.Client]:
    headers = {"Authorization": f"Bearer {live.token}", "Content-Type": "application/json"}
    with httpx.Client(base_url=live.url, headers=headers, timeout=30) as session:
        yield session


@pytest.mark.parametrize(("method", "template"), ROUTES, ids=[template for _, template in ROUTES])
def test_a_route_answers_hostile_requests_without_a_server_error(
    client: httpx.Client, method: str, template: str
) -> None:
    answered: list[int] = []

    # the routes that can start work draw twice the cases: the ones left out (below) are not sent, and CASES
    # are sent; the others draw CASES (a draw after the last case sent costs ~2.5 ms and tests nothing)
    drawn = 2 * CASES if template in STARTS_WORK else CASES

    @settings(max_examples=drawn, deadline=None, database=None, suppress_health_check=list(HealthCheck))
    @given(st.lists(SEGMENTS, min_size=2, max_size=2), BODIES)
    def check(segments: list[str], body: bytes) -> None:
        path = template.format(*segments[: template.count("{}")])
        if len(answered) >= CASES or _starts_work(path, body):
            return
        response = client.request(method, path, content=body)
        answered.append(response.status_code)
        assert response.status_code < 500, f"{method} {path} {body[:80]!r}: {response.status_code}"

    check()
    assert len(answered) == CASES
    assert client.get("/healthz").status_code == 200


MESSAGES = st.one_of(
    JSON_VALUES.map(json.dumps),
    st.fixed_dictionaries(
        {"type": st.sampled_from(["hold", "release", "estop", "reset", "leave", "jump", None, 3])},
        optional={"v": JSON_VALUES, "name": JSON_VALUES, "reason": JSON_VALUES},
    ).map(json.dumps),
    st.text(max_size=40),
    st.binary(max_size=40),
    st.sampled_from(["NaN", "[" * 3000, "x" * 5000, '{"type": "hold", "v": [NaN, 0, 0]}']),
)


def test_the_control_socket_answers_every_hostile_message_and_stays_open(live: Live, restored: None) -> None:
    """Never "acquire": without the control lock no hold is accepted, so every message gets one reply."""
    from websockets.sync.client import connect

    url = live.url.replace("http://", "ws://") + f"/ws/control?token={live.token}"
    replies: list[dict[str, Any]] = []
    with connect(url, max_size=2**20) as socket:

        @settings(max_examples=CASES, deadline=None, database=None, suppress_health_check=list(HealthCheck))
        @given(MESSAGES)
        def check(message: str | bytes) -> None:
            socket.send(message)
            reply = json.loads(socket.recv(timeout=10))
            assert isinstance(reply, dict) and "type" in reply, reply
            replies.append(reply)

        check()
        socket.send(json.dumps({"type": "jump"}))
        assert json.loads(socket.recv(timeout=10))["type"] == "error"  # still open, still answering
    assert len(replies) >= CASES
