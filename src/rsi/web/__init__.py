"""The operator console (issue 16): a web page to watch, drive and review the inspection robot.

The seed's third subsystem, the graphical user interface that "provides user-friendly interfaces to the
manipulator control and the inspection data". ``rsi console`` starts a FastAPI server over a live
simulated world (:mod:`rsi.web.console`) and serves one page; see docs/console.md. Importing this package
is cheap: the server, the simulator and FastAPI load when used.
"""

from __future__ import annotations

from rsi.web.server import ConsoleSettings, ExposedConsoleWarning, console_settings, serve

__all__ = ["ConsoleSettings", "ExposedConsoleWarning", "console_settings", "serve"]
