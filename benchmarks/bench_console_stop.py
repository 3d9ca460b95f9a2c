"""How soon the console's arm stops: after an explicit release, and after the heartbeats go silent.

Holds a 5 cm/s sideways command with the page's 20 Hz heartbeat for 0.4 s, then either releases (the page's
pointer-up) or just stops sending (a frozen page: the server's watchdog), eight times each, and prints the
stop latency the console measured on its own clock (release, or last heartbeat, to the first 44 Hz tick
with the tool still). The budget is 200 ms (issue 16); docs/console.md has the figures.

Run: ``MUJOCO_GL=egl .venv/bin/python benchmarks/bench_console_stop.py``.
"""

from __future__ import annotations

import os
import statistics
import time

os.environ.setdefault("MUJOCO_GL", "egl")

from rsi.web.console import Console

HOLD_S = 0.4
REPEATS = 8


def _hold(console: Console, sign: float) -> None:
    end = time.monotonic() + HOLD_S
    while time.monotonic() < end:
        console.hold("bench", [0.0, sign * 0.05, 0.0])
        time.sleep(0.05)


def main() -> None:
    console = Console(seed=0)
    console.start()
    time.sleep(3.0)
    console.acquire("bench", "bench")
    latencies: dict[str, list[float]] = {"release": [], "watchdog": []}
    for repeat in range(REPEATS):
        for kind, values in latencies.items():
            _hold(console, 1.0 if repeat % 2 == 0 else -1.0)
            if kind == "release":
                console.release("bench", "pointer up")
            time.sleep(0.4)
            latency = console.stops[-1].latency_s
            assert latency is not None
            values.append(latency)
    console.stop()
    print(f"load average {os.getloadavg()[0]:.1f} on {os.cpu_count()} cores; teleop priority raised: "
          f"{console.teleop_priority_raised}")  # fmt: skip
    for kind, values in latencies.items():
        print(f"{kind:>9}: median {statistics.median(values) * 1e3:5.0f} ms, max {max(values) * 1e3:5.0f} ms")


if __name__ == "__main__":
    main()
