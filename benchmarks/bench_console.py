"""What one live frame of the operator console costs, and the choices it made (docs/console.md).

For each size (the live 240x320 and the seed's 480x640) and each renderer (full: shadows and 4x
multisampling, as inspection frames are rendered; fast: neither, as the console's live views are), the
median time of one tick of the camera process (rsi.web.live.LiveCameras.frames: the three views' JPEGs):
*static* (nothing moved: a new exposure of the memoised light basis) and *moving* (the arm moved: the ISEE's
two light-group renders and the overview rendered again). The rate column is 1 / time, the most one core
can give.

Run: ``MUJOCO_GL=egl .venv/bin/python benchmarks/bench_console.py [--frames 8]``.
"""

from __future__ import annotations

import argparse
import os
import statistics
import time

os.environ.setdefault("MUJOCO_GL", "egl")

from rsi.sim.world import load
from rsi.web.live import LiveCameras, LiveState


def _tick_s(cameras: LiveCameras, live_world: object, *, moving: bool, frames: int) -> float:
    world = live_world
    times = []
    for _ in range(frames):
        if moving:
            world.arm.step_velocity([0.0, 0.01, 0.0], 1 / 44.0, frame="tool")  # type: ignore[attr-defined]
        state = LiveState.of(world)  # type: ignore[arg-type]
        start = time.perf_counter()
        cameras.frames(state)
        times.append(time.perf_counter() - start)
    return statistics.median(times)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--frames", type=int, default=8)
    frames = parser.parse_args().frames
    print(f"load average {os.getloadavg()[0]:.1f} on {os.cpu_count()} cores")
    print(f"{'size':>9} {'renderer':>8} {'static ms':>10} {'fps':>6} {'moving ms':>10} {'fps':>6}")
    for size in ((240, 320), (480, 640)):
        for fast in (True, False):
            live_world = load("truss", seed=0, arm=True)
            cameras = LiveCameras(load("truss", seed=0, arm=True), size=size)
            cameras.twin.set_fast_rendering(fast)
            cameras.frames(LiveState.of(live_world))  # contexts made, first basis rendered
            static = _tick_s(cameras, live_world, moving=False, frames=frames)
            moving = _tick_s(cameras, live_world, moving=True, frames=frames)
            name = "fast" if fast else "full"
            print(
                f"{size[0]:>4}x{size[1]:<4} {name:>8} {static * 1e3:>10.1f} {1 / static:>6.1f} "
                f"{moving * 1e3:>10.1f} {1 / moving:>6.1f}"
            )
            cameras.twin.close()
            live_world.close()


if __name__ == "__main__":
    main()
