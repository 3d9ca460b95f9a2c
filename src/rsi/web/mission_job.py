"""A whole mission launched from the console, run in a child process with its progress streamed back.

:func:`rsi.mission.run_mission` runs in its own interpreter (it renders hundreds of frames and would
otherwise starve the teleop loop), writes its run and findings into the console's archive, and reports each
visit, and what each inspection visit found, through a queue; the page polls :meth:`MissionJob.state`.
A visit's findings are provisional: the finished run holds them fused across vistas, with the pyrometer's
and the gas sensor's.
"""

from __future__ import annotations

import multiprocessing
import threading
import time
from pathlib import Path
from typing import Any

from rsi.errors import InputError

PROVISIONAL_LIMIT = 500  # findings a running mission lists (a mission reports a handful a visit)

# "small" is the fast check (a quarter of the pixels, the ISEE teleported to each vista, the lamp where the
# world put it, the hand plan: the points that complete it look for 1 mm pixels that 120x160 frames never
# give, and took the check from ~20 s to ~2 min); "full" is the mission as rsi mission runs it (seed §2.1
# video frames, arm, orbit sun, the default plan).
SETTINGS: dict[str, dict[str, Any]] = {
    "small": {"size": (120, 160), "arm": False, "orbit": False, "plan": "hand"},
    "full": {"size": (480, 640), "arm": True, "orbit": True, "plan": "auto"},
}


def _mission_arguments(setting: str) -> dict[str, Any]:
    """run_mission's keyword arguments for `setting`. A mission under the orbit's sun takes its
    inspection pass under another sun, as `rsi demo` does (seed §2: a station is never inspected under the
    same sun twice)."""
    from rsi.mission import ORBIT_START_S, SUN_OFFSET_S, MissionSettings

    arguments = dict(SETTINGS[setting])
    arguments["settings"] = MissionSettings(plan=arguments.pop("plan"))
    if arguments["orbit"]:
        arguments["orbit_start_s"] = (ORBIT_START_S[0], ORBIT_START_S[1] + SUN_OFFSET_S)
    return arguments


def _run(archive_path: str, seed: int, setting: str, queue: Any) -> None:
    import os

    os.environ.setdefault("MUJOCO_GL", "egl")
    from rsi.archive import Archive
    from rsi.mission import run_mission

    def progress(stage: str, done: int, total: int) -> None:
        queue.put(("progress", stage, done, total))

    def found(vista: str, findings: tuple[Any, ...]) -> None:
        rows = [{"vista": vista, "kind": f.kind, "confidence": round(f.confidence, 3)} for f in findings]
        queue.put(("found", rows))

    try:
        with Archive.open(archive_path) as archive:
            result = run_mission(
                seed, archive=archive, progress=progress, on_visit=found, **_mission_arguments(setting)
            )
        queue.put(("done", result.run_id, len(result.findings), result.timings_s.get("total", 0.0)))
    except Exception as error:  # the page shows why the mission failed
        queue.put(("failed", f"{type(error).__name__}: {error}"))


class MissionJob:
    """At most one mission at a time; its state for the page."""

    def __init__(self, archive_path: Path) -> None:
        if not isinstance(archive_path, (str, Path)) or "\0" in str(archive_path):
            raise InputError(f"archive_path must be the archive's file path; got {archive_path!r}.")
        self.archive_path = Path(archive_path)
        self._lock = threading.Lock()
        self._state: dict[str, Any] = {"status": "idle"}
        self._process: Any = None

    def start(self, seed: int, setting: str) -> dict[str, Any]:
        """Launch a mission; InputError for a bad seed or setting, or while one is running."""
        if isinstance(seed, bool) or not isinstance(seed, int) or not 0 <= seed < 2**31:
            raise InputError(f"seed must be an integer in [0, 2**31); got {seed!r}.")
        if not isinstance(setting, str) or setting not in SETTINGS:
            raise InputError(f"setting={setting!r} is not known. Choose one of {', '.join(SETTINGS)}.")
        with self._lock:
            if self._state["status"] == "running":
                raise InputError("a mission is already running; wait for it to finish.")
            context = multiprocessing.get_context("spawn")
            queue = context.Queue()
            self._process = context.Process(
                target=_run, args=(str(self.archive_path), seed, setting, queue), daemon=True
            )
            self._state = {
                "status": "running",
                "seed": seed,
                "setting": setting,
                "started_at_s": time.time(),
                "stage": "starting",
                "done": 0,
                "total": 0,
                "visits": 0,
                "provisional": [],
                "run_id": None,
            }
            self._process.start()
        threading.Thread(target=self._follow, args=(queue,), name="rsi-console-mission", daemon=True).start()
        return self.state()

    def _follow(self, queue: Any) -> None:
        while True:
            try:
                message = queue.get(timeout=1.0)
            except Exception:  # queue.Empty: check that the child is still there
                if self._process is not None and not self._process.is_alive():
                    with self._lock:
                        if self._state["status"] == "running":
                            self._state.update(status="failed", error="the mission process ended")
                    return
                continue
            with self._lock:
                if message[0] == "progress":
                    _, stage, done, total = message
                    self._state.update(stage=stage, done=done, total=total, visits=self._state["visits"] + 1)
                elif message[0] == "found":
                    listed = self._state["provisional"]
                    listed.extend(message[1][: PROVISIONAL_LIMIT - len(listed)])
                elif message[0] == "done":
                    _, run_id, count, total_s = message
                    self._state.update(
                        status="finished", run_id=run_id, finding_count=count, elapsed_s=round(total_s, 1)
                    )
                    return
                else:
                    self._state.update(status="failed", error=message[1])
                    return

    def state(self) -> dict[str, Any]:
        """Status (idle, running, finished, failed), stage and counts, the run id when finished."""
        with self._lock:
            return {**self._state, "provisional": list(self._state.get("provisional", []))}

    def stop(self) -> None:
        """End a running mission's process (the console is shutting down)."""
        if self._process is not None and self._process.is_alive():
            self._process.terminate()
            self._process.join(timeout=5.0)


__all__ = ["PROVISIONAL_LIMIT", "SETTINGS", "MissionJob"]
