"""``rsi console``: start the operator console's server (uvicorn) with its token and archive."""

from __future__ import annotations

import ipaddress
import os
import secrets
import tempfile
import warnings
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from rsi import _validate as v
from rsi.errors import InputError
from rsi.sim.world import SCENES

LOOPBACK = "127.0.0.1"
DEFAULT_PORT = 8765
MIN_TOKEN_CHARS = 16


class ExposedConsoleWarning(UserWarning):
    """The console listens beyond this machine: whoever reaches the port with the token drives the arm."""


@dataclass(frozen=True)
class ConsoleSettings:
    """What ``rsi console`` was asked for, validated (every argument named in its error).

    Attributes
    ----------
    host : str
        An IP address to listen on; 127.0.0.1 by default (this machine only).
    port : int
        1..65535 (0 picks a free one).
    archive : Path
        SQLite archive file; missions write to it and the page browses it.
    seed : int
        The live world's seed.
    layout : str
        The mock-up (:data:`rsi.sim.world.SCENES`).
    token : str
        The secret in the start URL; at least 16 URL-safe characters.
    """

    host: str
    port: int
    archive: Path
    seed: int
    layout: str
    token: str

    @property
    def url(self) -> str:
        """The start URL, token included (print it only to the person starting the console)."""
        shown = f"[{self.host}]" if ":" in self.host else self.host
        return f"http://{shown}:{self.port}/?token={self.token}"


def console_settings(
    *,
    host: str = LOOPBACK,
    port: int = DEFAULT_PORT,
    archive: str | os.PathLike[str] | None = None,
    seed: int = 0,
    layout: str = "truss",
    token: str | None = None,
) -> ConsoleSettings:
    """Check the console's options; warn (:class:`ExposedConsoleWarning`) when listening beyond loopback."""
    try:
        if not isinstance(host, str):
            raise ValueError(host)
        address = ipaddress.ip_address(host)
    except ValueError as error:
        raise InputError(f"host must be an IP address such as 127.0.0.1; got {host!r}.") from error
    if isinstance(port, bool) or not isinstance(port, int) or not 0 <= port <= 65535:
        raise InputError(f"port must be an integer in [0, 65535]; got {port!r}.")
    if isinstance(seed, bool) or not isinstance(seed, int) or not 0 <= seed < 2**63:  # the archive's integer
        raise InputError(f"seed must be an integer in [0, 2**63); got {seed!r:.60}.")
    v.choice(layout, "layout", SCENES)
    if token is None:
        token = secrets.token_urlsafe(24)
    elif (
        not isinstance(token, str)
        or len(token) < MIN_TOKEN_CHARS
        or not all(c.isalnum() or c in "-_" for c in token)
    ):
        raise InputError(
            f"token must be at least {MIN_TOKEN_CHARS} characters of letters, digits, '-' or '_'; got "
            f"{_described(token)}. Leave it out for a random one."
        )
    if archive is None:
        path = Path(tempfile.mkdtemp(prefix="rsi-console-")) / "archive.db"
    else:
        path = _archive_path(archive)
        if path.is_dir():
            raise InputError(
                f"archive={str(path)!r} is a folder; give the archive's file, e.g. {path / 'archive.db'}."
            )
    if not address.is_loopback:
        warnings.warn(
            f"host={host!r} listens beyond this machine: anyone who reaches port {port} and learns the token "
            "can drive the arm. Use 127.0.0.1 (and an SSH tunnel) unless the network is yours.",
            ExposedConsoleWarning,
            stacklevel=2,
        )
    return ConsoleSettings(str(address), port, path, seed, layout, token)


def _described(token: object) -> str:
    """What a refused token was, without echoing a secret: its length, or its type."""
    return f"{len(token)} characters" if isinstance(token, str) else f"a {type(token).__name__}"


def _archive_path(archive: object) -> Path:
    if not isinstance(archive, (str, os.PathLike)) or isinstance(archive, bytes):
        raise InputError(f"archive must be a file path (str or Path); got {type(archive).__name__}.")
    path = Path(archive)
    if "\0" in str(path):
        raise InputError("archive must be a file path without NUL characters.")
    return path


def websocket_protocol() -> type:
    """uvicorn's websocket implementation on the `websockets` library's asyncio protocol.

    Measured with 20 viewers of the three live views on a loaded 2-core machine (docs/console.md): this one
    kept every viewer and the controller at the camera's rate (12-13 frames/s), the sans-I/O
    (``websockets-sansio``) and ``wsproto`` ones delivered 7-8 frames/s to each. uvicorn marks it deprecated
    in favour of the sans-I/O one; the warning is silenced here, where it was chosen on purpose.
    """
    from uvicorn.config import UvicornDeprecationWarning

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UvicornDeprecationWarning)
        warnings.simplefilter("ignore", DeprecationWarning)  # websockets.legacy, which it runs on
        from uvicorn.protocols.websockets.websockets_impl import WebSocketProtocol
    return WebSocketProtocol


def uvicorn_options() -> dict[str, Any]:
    """The server options the console runs under (``rsi console`` and the tests alike).

    Per-message deflate is off: every video message is JPEG, which deflate cannot shrink, and uvicorn
    deflates each message once per viewer. With it on, 20 viewers of the 480x640 views held the controller
    at 8 frames/s on this 2-core machine (docs/console.md). The control socket's JSON is a few hundred bytes.
    """
    return {"log_level": "warning", "ws": websocket_protocol(), "ws_per_message_deflate": False}


def check_archive(path: Path) -> None:
    """Open the console's archive once, as its missions and reviews will: a damaged one is refused here,
    before the server starts, and left as it was (the archive's whole check precedes any write)."""
    from rsi.archive import Archive

    with Archive.open(path):
        pass


def serve(settings: ConsoleSettings) -> None:
    """Run the console until interrupted (Ctrl-C).

    Raises ArchiveFileError, before anything starts, for an archive that is damaged or not an rsi archive.
    """
    if not isinstance(settings, ConsoleSettings):
        raise InputError(f"settings must come from console_settings(...); got {type(settings).__name__}.")
    check_archive(settings.archive)
    import uvicorn

    from rsi.web.app import create_app
    from rsi.web.console import Console

    os.environ.setdefault("MUJOCO_GL", "egl")
    console = Console(seed=settings.seed, layout=settings.layout)
    app = create_app(console, token=settings.token, archive_path=settings.archive)
    uvicorn.run(app, host=settings.host, port=settings.port, **uvicorn_options())


__all__ = [
    "DEFAULT_PORT",
    "LOOPBACK",
    "ConsoleSettings",
    "ExposedConsoleWarning",
    "check_archive",
    "console_settings",
    "serve",
    "uvicorn_options",
    "websocket_protocol",
]
