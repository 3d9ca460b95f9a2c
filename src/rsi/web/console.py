"""The console's live world: the ISEE on its arm and rail, the mock-up, the solar simulator, the orbit clock.

Three threads share one :class:`rsi.sim.world.World` under one lock:

- the **teleop loop** at 44 Hz (seed §3.1) runs :func:`rsi.web.teleop.teleop_step` on the console's
  :class:`rsi.sim.proximity_loop.ProximityLoop` (the one §3.1 loop, as in the demo and the transits) and
  the server-side watchdog: a held command whose heartbeat (20 Hz from the page) is older than
  :data:`HEARTBEAT_TIMEOUT_S` is dropped and the arm holds, so a frozen tab, a lost socket or a release
  the network ate stops the arm within ``HEARTBEAT_TIMEOUT_S + 1/44 s`` < 200 ms;
- the **camera loop** sends the state to the camera process and publishes the frames it renders
  (:mod:`rsi.web.live`, :mod:`rsi.web.worker`);
- the **housekeeping loop** (2 Hz) moves the sun with the orbit clock and reads the gas sensor.

One operator holds the control lock at a time (the others watch); the e-stop latches until the operator
resets it explicitly.
"""

from __future__ import annotations

import contextlib
import math
import secrets
import threading
import time
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from rsi.errors import InputError
from rsi.sim.world import World, frame_size, load
from rsi.web.live import FrameHub, LiveState
from rsi.web.teleop import (
    STOPPED_SPEED_M_S,
    TELEOP_LAW,
    TELEOP_RATE_HZ,
    TeleopStep,
    teleop_loop,
    teleop_step,
)
from rsi.web.worker import SHOT_KINDS, CameraProcess, Shot

FloatArray = NDArray[np.float64]

HEARTBEAT_HZ = 20.0  # the page sends its held command this often
# three missed heartbeats (a loaded page's timers slip by tens of ms); with one 44 Hz period to act, the stop
# comes at most 0.15 + 0.023 = 0.173 s after the last heartbeat, inside the 200 ms budget
HEARTBEAT_TIMEOUT_S = 0.15
LIVE_SIZE = (480, 640)  # the seed §2.1 frame; one camera tick is ~30 ms of it on one core (docs/console.md)
LIVE_FPS = 15.0  # camera loop's target: >= 10 frames/s with a margin for a loaded machine's jitter
HOUSEKEEPING_HZ = 2.0
TELEMETRY_SECONDS = 30.0
ORBIT_START_S = 400.0  # the mission's reference pass starts here (rsi.mission): the lamp lights the faces
MAX_CLOCK_RATE = 600.0  # ten minutes of orbit per second: a 93-minute orbit in about 9 s
GAS_WINDOW_S = 20.0


@dataclass
class StopEvent:
    """A release and when the arm was seen stopped after it (the stop latency, on the server's clock)."""

    reason: str
    released_at_s: float
    stopped_at_s: float | None = None

    @property
    def latency_s(self) -> float | None:
        return None if self.stopped_at_s is None else self.stopped_at_s - self.released_at_s


@dataclass
class Operator:
    """Who holds the control lock, and the command they hold."""

    client_id: str
    name: str
    command_m_s: FloatArray = field(default_factory=lambda: np.zeros(3))
    held: bool = False
    heartbeat_at_s: float = 0.0


class Console:
    """The live world and its loops (see the module notes).

    Parameters
    ----------
    seed : int
        The world's seed (anomalies, noise), >= 0.
    layout : {"truss"}
        The mock-up (:data:`rsi.sim.world.SCENES`).
    live_size : (int, int)
        Rows and columns of the live views.
    clock : callable
        Monotonic seconds (``time.monotonic``).
    """

    def __init__(
        self,
        *,
        seed: int = 0,
        layout: str = "truss",
        live_size: tuple[int, int] = LIVE_SIZE,
        clock: Callable[[], float] = time.monotonic,
    ) -> None:
        live_size = frame_size(live_size)
        if not callable(clock):
            raise InputError(f"clock must be a callable giving monotonic seconds; got {clock!r}.")
        self.seed = seed
        self.layout = layout
        # the operator's live video draws MuJoCo's boxes at the fast renderer's four quads (docs/console.md)
        self.world: World = load(layout, seed=seed, arm=True, grid_meshes=False)
        self.loop = teleop_loop(self.world.arm, seed=seed)
        self.lock = threading.RLock()
        self.clock = clock
        self.hub = FrameHub()
        self.live_size = live_size
        self.cameras: CameraProcess | None = None
        self.last_shot: Shot | None = None
        self.shot_seq = 0
        self.operator: Operator | None = None
        self.estop_latched = False
        self.estop_reason = ""
        self.last_step: TeleopStep | None = None
        self.stops: deque[StopEvent] = deque(maxlen=50)
        self.telemetry: deque[dict[str, Any]] = deque(maxlen=int(TELEMETRY_SECONDS * TELEOP_RATE_HZ))
        self.orbit_time_s = ORBIT_START_S
        self.clock_rate = 0.0
        self.sun: dict[str, Any] = {}
        self.gas_ppm = 0.0
        self._gas_samples: deque[float] = deque(maxlen=int(GAS_WINDOW_S * HOUSEKEEPING_HZ))
        self.pyrometer_k = float("nan")
        self.render_fps = 0.0
        self.render_ms = 0.0
        self.loop_overrun_s = 0.0
        self.teleop_priority_raised = False
        self._sample = 0
        self._state_version = 0
        self._running = threading.Event()
        self._threads: list[threading.Thread] = []
        self.set_orbit_time(ORBIT_START_S)

    # ------------------------------------------------------------------ lifecycle

    def start(self) -> None:
        """Start the camera process and the teleop, camera and housekeeping loops (daemon threads)."""
        self.cameras = CameraProcess(seed=self.seed, layout=self.layout, size=self.live_size)
        self._running.set()
        for name, target in (
            ("teleop", self._teleop_loop),
            ("cameras", self._camera_loop),
            ("housekeeping", self._housekeeping_loop),
        ):
            thread = threading.Thread(target=target, name=f"rsi-console-{name}", daemon=True)
            thread.start()
            self._threads.append(thread)

    def stop(self) -> None:
        """Stop the loops and free the worlds' OpenGL contexts."""
        self._running.clear()
        for thread in self._threads:
            thread.join(timeout=5.0)
        self._threads.clear()
        if self.cameras is not None:
            self.cameras.close()
            self.cameras = None
        self.world.close()

    # ------------------------------------------------------------------ control lock

    def acquire(self, client_id: str, name: str) -> bool:
        """Take the control lock if nobody holds it (or `client_id` already does)."""
        with self.lock:
            if self.operator is not None and self.operator.client_id != client_id:
                return False
            if self.operator is None:
                self.operator = Operator(client_id, name[:64] or "operator")
            return True

    def release_control(self, client_id: str, reason: str = "released control") -> None:
        """Give the lock back (the arm stops first)."""
        with self.lock:
            if self.operator is not None and self.operator.client_id == client_id:
                self._release(reason)
                self.operator = None

    def hold(self, client_id: str, command_m_s: object) -> bool:
        """A heartbeat from the operator's page: hold `command_m_s` (tool frame, m/s). False if refused."""
        try:
            command = np.asarray(command_m_s, dtype=np.float64)
        except (TypeError, ValueError):
            command = np.full(1, np.nan)
        if command.shape != (3,) or not np.isfinite(command).all():
            raise InputError(f"command_m_s must be 3 finite velocities (m/s); got {command_m_s!r}.")
        with self.lock:
            operator = self.operator
            if operator is None or operator.client_id != client_id or self.estop_latched:
                return False
            operator.command_m_s = command
            operator.held = True
            operator.heartbeat_at_s = self.clock()
            return True

    def release(self, client_id: str, reason: str) -> None:
        """The operator let go (pointer up, key up, window blur, hidden tab, socket closed)."""
        with self.lock:
            if self.operator is not None and self.operator.client_id == client_id:
                self._release(reason)

    def _release(self, reason: str, at_s: float | None = None) -> None:
        operator = self.operator
        if operator is None or not operator.held:
            return
        operator.held = False
        operator.command_m_s = np.zeros(3)
        self.stops.append(StopEvent(reason, self.clock() if at_s is None else at_s))

    def estop(self, reason: str = "e-stop") -> None:
        """Latch the e-stop: the arm holds and no command moves it until :meth:`reset_estop`."""
        with self.lock:
            self.estop_latched = True
            self.estop_reason = reason[:200]
            self._release("e-stop")

    def reset_estop(self, client_id: str) -> bool:
        """Unlatch the e-stop; only the operator holding the control lock may (False otherwise)."""
        with self.lock:
            if self.operator is None or self.operator.client_id != client_id:
                return False
            self.estop_latched = False
            self.estop_reason = ""
            return True

    # ------------------------------------------------------------------ loops

    def _teleop_loop(self) -> None:
        self.teleop_priority_raised = _raise_priority()
        period = 1.0 / TELEOP_RATE_HZ
        next_at = self.clock()
        while self._running.is_set():
            self.tick()
            next_at += period
            delay = next_at - self.clock()
            if delay > 0:
                time.sleep(delay)
            else:  # late (a loaded machine): do not try to catch up with a burst of steps
                self.loop_overrun_s = max(self.loop_overrun_s, -delay)
                next_at = self.clock()

    def tick(self) -> TeleopStep:
        """One 44 Hz period: watchdog, blend, step, telemetry (the teleop loop calls it)."""
        with self.lock:
            now = self.clock()
            operator = self.operator
            if operator is not None and operator.held and now - operator.heartbeat_at_s > HEARTBEAT_TIMEOUT_S:
                self._release("watchdog: heartbeat lost", at_s=operator.heartbeat_at_s)
            held = operator is not None and operator.held and not self.estop_latched
            command = operator.command_m_s if operator is not None and held else np.zeros(3)
            step = teleop_step(self.loop, command, held=held)
            self.last_step = step
            if step.tool_speed_m_s > STOPPED_SPEED_M_S:
                self._state_version += 1
            elif self.stops and self.stops[-1].stopped_at_s is None:
                self.stops[-1].stopped_at_s = self.clock()
            self._record(step, now)
            return step

    def _record(self, step: TeleopStep, now: float) -> None:
        self._sample += 1
        if self._sample % 4 == 0:  # the pyrometer at 11 Hz: enough for a trace, cheap
            self.pyrometer_k = self._pyrometer_k(step)
        force, torque = self.world.arm.force_torque()
        self.telemetry.append(
            {
                "t": round(now, 4),
                "moving": step.tool_speed_m_s > STOPPED_SPEED_M_S,
                "d": [None if math.isinf(d) else round(float(d), 4) for d in step.distances_m],
                "regions": list(step.regions),
                "op": round(float(step.operator_m_s[2]), 4),
                "prox": round(step.proximity_m_s, 4),
                "cmd": round(float(step.commanded_m_s[2]), 4),
                "pyro_k": None if math.isnan(self.pyrometer_k) else round(self.pyrometer_k, 2),
                "gas_ppm": round(self.gas_ppm, 3),
                "f": [round(float(x), 3) for x in force],
                "tq": [round(float(x), 4) for x in torque],
            }
        )

    def _pyrometer_k(self, step: TeleopStep) -> float:
        """The pyrometer's reading of the spot on the view axis (seed §3), emissivity set for Kapton."""
        from rsi.sensors.pyrometer import read_pyrometer

        finite = step.distances_m[np.isfinite(step.distances_m)]
        if finite.size == 0:
            return float("nan")
        position, rotation = self.world.arm.tool_pose()
        from rsi.sim.arm import RANGEFINDER_RECESS_M

        spot = position + rotation[:, 2] * (float(finite.mean()) - RANGEFINDER_RECESS_M)
        truth_k = self.world.temperature_k(spot[None, :])
        return float(read_pyrometer(truth_k, 0.95, rng=self._sample).temperature_k[0])

    def _camera_loop(self) -> None:
        period = 1.0 / LIVE_FPS
        times: deque[float] = deque(maxlen=24)
        while self._running.is_set() and self.cameras is not None:
            started = time.perf_counter()
            if not self.hub.watched():  # nobody looks: a render would only take the CPU from the rest
                self.render_fps = 0.0
                times.clear()
                time.sleep(period)
                continue
            with self.lock:
                state = LiveState.of(self.world)
            try:
                frames = self.cameras.frames(state)
            except (RuntimeError, OSError, EOFError):  # a failed frame must not end the live view
                time.sleep(period)
                continue
            self.hub.publish(frames)
            self.render_ms = frames[0].render_s * 1000
            times.append(time.perf_counter())
            if len(times) > 1:
                self.render_fps = (len(times) - 1) / (times[-1] - times[0])
            time.sleep(max(0.0, period - (time.perf_counter() - started)))

    def shoot(self, kind: str) -> Shot:
        """Take a reference or an inspection at the arm's current pose (``rsi.web.worker``)."""
        if kind not in SHOT_KINDS:
            raise InputError(f"kind={kind!r} is not known. Choose one of {', '.join(SHOT_KINDS)}.")
        if self.cameras is None:
            raise InputError("the console is not running; start() it before taking a shot.")
        with self.lock:
            state = LiveState.of(self.world)
        self.last_shot = self.cameras.shoot(state, kind)
        self.shot_seq += 1
        return self.last_shot

    def _housekeeping_loop(self) -> None:
        period = 1.0 / HOUSEKEEPING_HZ
        while self._running.is_set():
            started = self.clock()
            with contextlib.suppress(InputError):
                if self.clock_rate > 0:
                    self.set_orbit_time(self.orbit_time_s + self.clock_rate * period)
            self._read_gas()
            time.sleep(max(0.0, period - (self.clock() - started)))

    def _read_gas(self) -> None:
        """The MOS sensor at the ISEE (seed §3), its lag and noise applied over a trailing window."""
        from rsi.sensors.gas import MosGasSensor, read_gas

        with self.lock:
            position = self.world.arm.tool_pose()[0]
            ppm = float(self.world.gas_concentration_ppm(position[None, :], [self.orbit_time_s])[0])
        self._gas_samples.append(ppm)
        sensor = MosGasSensor(sample_rate_hz=HOUSEKEEPING_HZ)
        readings = read_gas(np.asarray(self._gas_samples), sensor, rng=self._sample)
        self.gas_ppm = max(0.0, float(readings.estimated_ppm[-1]))

    # ------------------------------------------------------------------ sun and lamp

    def set_orbit_time(self, time_s: float) -> None:
        """Put the orbit clock at `time_s` (s after orbit noon); the lamp lights as its sun (seed §4.1)."""
        from rsi.web._sun import sun_at

        if isinstance(time_s, bool) or not isinstance(time_s, (int, float)) or not math.isfinite(time_s):
            raise InputError(f"time_s must be a finite number of seconds >= 0; got {time_s!r}.")
        if time_s < 0:
            raise InputError(f"time_s must be >= 0 s after orbit noon; got {time_s!r}.")
        with self.lock:
            self.sun = sun_at(self.world, float(time_s))
            self.orbit_time_s = float(time_s)

    def set_clock_rate(self, rate: float) -> None:
        """Run the orbit clock at `rate` times real time, in [0, MAX_CLOCK_RATE] (0 pauses it)."""
        if isinstance(rate, bool) or not isinstance(rate, (int, float)) or not 0 <= rate <= MAX_CLOCK_RATE:
            raise InputError(f"rate must be a number in [0, {MAX_CLOCK_RATE}]; got {rate!r}.")
        self.clock_rate = float(rate)

    def set_lamp(self, *, on: bool | None = None, halogen: bool | None = None) -> None:
        """Switch the solar-simulator lamp and the ISEE's halogen lamps (seed §3, §4.1)."""
        with self.lock:
            if on is not None:
                self.world.switch_lamp(on)
            if halogen is not None:
                self.world.set_halogen(halogen)

    # ------------------------------------------------------------------ read-outs

    def status(self) -> dict[str, Any]:
        """The live state as JSON-ready values (``GET /api/status``)."""
        with self.lock:
            arm = self.world.arm
            position, rotation = arm.tool_pose()
            step = self.last_step
            operator = self.operator
            stop = self.stops[-1] if self.stops else None
            task = self.world.lamp_task
            return {
                "server_time_s": time.time(),
                "seed": self.seed,
                "arm": {
                    "joint_positions": [round(float(q), 5) for q in arm.joint_positions],
                    "tool_position_m": [round(float(x), 5) for x in position],
                    "tool_axis": [round(float(x), 5) for x in rotation[:, 2]],
                    "tool_speed_m_s": None if step is None else round(step.tool_speed_m_s, 5),
                    "moving": step is not None and step.tool_speed_m_s > STOPPED_SPEED_M_S,
                },
                "teleop": {
                    "rate_hz": TELEOP_RATE_HZ,
                    "heartbeat_hz": HEARTBEAT_HZ,
                    "heartbeat_timeout_s": HEARTBEAT_TIMEOUT_S,
                    "joystick_speed_m_s": TELEOP_LAW.joystick_speed_m_s,
                    "operator": None if operator is None else operator.name,
                    "held": bool(operator is not None and operator.held),
                    "operator_m_s": None if step is None else [round(float(x), 4) for x in step.operator_m_s],
                    "proximity_m_s": None if step is None else round(step.proximity_m_s, 4),
                    "commanded_m_s": None
                    if step is None
                    else [round(float(x), 4) for x in step.commanded_m_s],
                    "estop": self.estop_latched,
                    "estop_reason": self.estop_reason,
                    "last_stop": None
                    if stop is None
                    else {"reason": stop.reason, "latency_s": stop.latency_s},
                    "loop_overrun_s": round(self.loop_overrun_s, 4),
                    "priority_raised": self.teleop_priority_raised,
                },
                "sensors": {
                    "proximity_m": None
                    if step is None
                    else [None if math.isinf(d) else round(float(d), 4) for d in step.distances_m],
                    "regions": None if step is None else list(step.regions),
                    "pyrometer_k": None if math.isnan(self.pyrometer_k) else round(self.pyrometer_k, 2),
                    "gas_ppm": round(self.gas_ppm, 3),
                    "force_n": [round(float(x), 3) for x in arm.force_torque()[0]],
                    "torque_n_m": [round(float(x), 4) for x in arm.force_torque()[1]],
                },
                "sun": {
                    **self.sun,
                    "orbit_time_s": round(self.orbit_time_s, 2),
                    "clock_rate": self.clock_rate,
                    "lamp_on": self.world.lamp_on,
                    "halogen_on": self.world.halogen_on,
                    "spot_m": [round(float(x), 4) for x in task.spot_world_m],
                    "beam_angle_rad": round(task.beam_angle_rad, 5),
                    "intensity_lux": round(task.intensity_lux, 1),
                },
                "inspection": {
                    "seq": self.shot_seq,
                    "kind": None if self.last_shot is None else self.last_shot.kind,
                },
                "video": {
                    "size": list(self.live_size),
                    "fps": round(self.render_fps, 2),  # 0 while nobody watches: the cameras idle
                    "viewers": self.hub.viewers,
                    "frame_ms": round(self.render_ms, 1),
                },
            }


TELEOP_NICE = -10  # the 44 Hz loop (and its watchdog) before the renders and the page on a busy machine


def _raise_priority() -> bool:
    """Give the calling thread a higher CPU priority (Linux: nice per thread); False where not permitted.

    The stop budget (200 ms) is spent by the watchdog's timeout and one loop period; on a machine whose
    cores are busy (a browser drawing the 3D view, the camera process rendering) an ordinary thread can wait
    longer than that for a core.
    """
    import os

    try:
        os.setpriority(os.PRIO_PROCESS, threading.get_native_id(), TELEOP_NICE)
    except (OSError, AttributeError):
        return False
    return True


def new_client_id() -> str:
    """An unguessable id for one page's control socket."""
    return secrets.token_urlsafe(12)


__all__ = ["HEARTBEAT_HZ", "HEARTBEAT_TIMEOUT_S", "LIVE_SIZE", "Console", "StopEvent", "new_client_id"]
