"""Time the simulator against the render a MuJoCo user would take instead (issue 3 acceptance).

Rows, each the median of ``--repeats`` runs after one warm-up, in one process:

- **world build**: ``rsi.sim.load("truss", seed=...)`` (mock-up, seeded anomalies, MJCF, textures,
  compile) against compiling the same MJCF, already written, with MuJoCo alone. "fresh process" times the
  first build in a new Python process (after the imports, which are listed apart): ``load`` against
  ``mujoco.MjModel.from_xml_path`` of the MJCF and its textures on disk; "again" a later build in the same
  process against ``MjModel.from_xml_string``. Target (issue 3): <= 2 s.
- **frame**: one interlaced frame, ``World.render(vista, size=(N, N), truth=False)``: a new visit, one basis
  render per light group (solar lamp with its 2048-px shadow map plus room ambient; strobe), float32
  luminance and the camera model ``rsi.imaging.camera.expose`` (seed §2.1-2.2: strobe in the odd field,
  exposure, noise, 8 bits). The alternative is what a user would take: one ``mujoco.Renderer`` RGB render of
  the same scene from the same camera with the same lights all on at once (uint8 colour, no exposure model,
  no noise, clipped where lights add past 1). Target (issue 3): <= 0.3 s at 1024x1024.
- **frame + truth**: ``World.render`` as it is called by default, adding depth and the segmentation the
  flaw masks come from, against ``mujoco.Renderer`` RGB plus its depth and segmentation renders.

One thread: the BLAS/OpenMP pools are pinned to 1 and Mesa's llvmpipe (the CPU OpenGL of ``MUJOCO_GL=egl``
without a GPU) to ``--gl-threads`` (``LP_NUM_THREADS``, default 1); both sides share the driver.

Run: ``MUJOCO_GL=egl .venv/bin/python benchmarks/bench_sim.py [--repeats 7] [--size 1024] [--gl-threads 1]``.
"""

from __future__ import annotations

import argparse
import os
import sys

for _variable in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ[_variable] = "1"


def _arguments() -> argparse.Namespace:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--repeats", type=int, default=7, help="timed runs per row (median), >= 5")
    parser.add_argument("--size", type=int, default=1024, help="frame side in pixels")
    parser.add_argument(
        "--gl-threads", type=int, default=1, help="llvmpipe threads (LP_NUM_THREADS); 0 = driver"
    )
    parser.add_argument("--seed", type=int, default=7)
    parser.add_argument("--vista", default="D_tubing")
    return parser.parse_args()


ARGS = _arguments() if __name__ == "__main__" else None
if ARGS is not None and ARGS.gl_threads > 0:
    os.environ["LP_NUM_THREADS"] = str(ARGS.gl_threads)  # read when Mesa starts, so set before any context
os.environ.setdefault("MUJOCO_GL", "egl")

import statistics
import subprocess
import tempfile
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import mujoco

import rsi.sim
from rsi.sim.scene import LIGHT_GROUPS, scene_mjcf
from rsi.sim.world import World

FRAME_TARGET_S = 0.3
BUILD_TARGET_S = 2.0


def _median_s(run: Callable[[], object], repeats: int, *, before: Callable[[], None] | None = None) -> float:
    if before is not None:
        before()
    run()  # warm-up: contexts, caches
    times = []
    for _ in range(repeats):
        if before is not None:
            before()
        start = time.perf_counter()
        run()
        times.append(time.perf_counter() - start)
    return statistics.median(times)


_COLD_RSI = """
import time
start = time.perf_counter()
import rsi.sim.world
imported = time.perf_counter()
rsi.sim.world.load("truss", seed={seed})
print(imported - start, time.perf_counter() - imported)
"""
_COLD_MUJOCO = """
import time
start = time.perf_counter()
import mujoco
imported = time.perf_counter()
mujoco.MjModel.from_xml_path({path!r})
print(imported - start, time.perf_counter() - imported)
"""


def _cold_s(code: str, repeats: int) -> tuple[float, float]:
    """Median import and build seconds of `code` run in fresh Python processes."""
    runs = []
    for _ in range(repeats):
        result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
        runs.append([float(value) for value in result.stdout.split()])
    return statistics.median(run[0] for run in runs), statistics.median(run[1] for run in runs)


def _plain_renderer(world: World, size: int, vista: str) -> tuple[Callable[[], object], Callable[[], object]]:
    """A mujoco.Renderer of the same model, camera, geom groups and lights (sun group + strobe, all on)."""
    renderer = mujoco.Renderer(world.model, size, size)
    option = mujoco.MjvOption()
    option.geomgroup[:] = [1, 0, 0, 1, 0, 0]  # the inspection state, as World.render draws it
    point = world.vista(vista)
    names = (*LIGHT_GROUPS["sun"], *LIGHT_GROUPS["strobe"])
    lit = [mujoco.mj_name2id(world.model, mujoco.mjtObj.mjOBJ_LIGHT, name) for name in names]

    def one_light_setup() -> None:
        world.place_camera(point.position_m, point.forward, point.up)
        world.model.light_active[:] = 0
        world.model.light_active[lit] = 1

    def rgb() -> object:
        one_light_setup()
        renderer.update_scene(world.data, camera="isee", scene_option=option)
        return renderer.render()

    def rgb_depth_segmentation() -> object:
        image = rgb()
        renderer.enable_depth_rendering()
        renderer.update_scene(world.data, camera="isee", scene_option=option)
        depth = renderer.render()
        renderer.disable_depth_rendering()
        renderer.enable_segmentation_rendering()
        renderer.update_scene(world.data, camera="isee", scene_option=option)
        segments = renderer.render()
        renderer.disable_segmentation_rendering()
        return image, depth, segments

    return rgb, rgb_depth_segmentation


def _gl_renderer_name() -> str:
    try:
        from OpenGL import GL

        name: Any = GL.glGetString(GL.GL_RENDERER)
        return name.decode() if isinstance(name, bytes) else str(name)
    except Exception:  # PyOpenGL missing or no current context: the name is only informative
        return "unknown"


def main() -> None:
    args = ARGS if ARGS is not None else _arguments()
    if args.repeats < 5:
        sys.exit("--repeats must be >= 5 (medians of at least five runs).")
    size, repeats = args.size, args.repeats
    world = rsi.sim.load("truss", seed=args.seed)
    xml, assets, _ = scene_mjcf(world.mockup, world.anomalies)
    rows: list[tuple[str, str, float, str, float, float | None]] = []

    with tempfile.TemporaryDirectory() as folder:
        for name, data in assets.items():
            (Path(folder) / name).write_bytes(data)
        (Path(folder) / "truss.xml").write_text(xml)
        imports, cold = _cold_s(_COLD_RSI.format(seed=args.seed), repeats)
        imports_mujoco, cold_mujoco = _cold_s(
            _COLD_MUJOCO.format(path=str(Path(folder) / "truss.xml")), repeats
        )
    rows.append(("import", "import rsi.sim.world", imports, "import mujoco", imports_mujoco, None))
    rows.append(("build, fresh", "rsi.sim.load", cold, "MjModel.from_xml_path", cold_mujoco, BUILD_TARGET_S))
    build = _median_s(lambda: rsi.sim.load("truss", seed=args.seed), repeats)
    compile_only = _median_s(lambda: mujoco.MjModel.from_xml_string(xml, assets), repeats)
    rows.append(("build, again", "rsi.sim.load", build, "MjModel.from_xml_string", compile_only, None))

    shape = (size, size)
    frame = _median_s(lambda: world.render(args.vista, size=shape, truth=False), repeats)
    gl_name = _gl_renderer_name()
    plain_rgb, plain_all = _plain_renderer(world, size, args.vista)
    plain = _median_s(plain_rgb, repeats)
    rows.append((f"frame {size}x{size}", "render(truth=False)", frame, "Renderer RGB", plain, FRAME_TARGET_S))
    with_truth = _median_s(lambda: world.render(args.vista, size=shape), repeats)
    plain_truth = _median_s(plain_all, repeats)
    rows.append(("frame + truth", "render()", with_truth, "Renderer RGB+depth+seg", plain_truth, None))

    threads = os.environ.get("LP_NUM_THREADS", "driver default")
    print(
        f"MUJOCO_GL={os.environ['MUJOCO_GL']}, GL renderer {gl_name!r}, llvmpipe threads {threads}, "
        f"BLAS threads 1, {os.cpu_count()} CPUs; median of {repeats} after a warm-up; seed {args.seed}, "
        f"vista {args.vista!r}"
    )
    print(f"{'step':16} {'rsi':22} {'s':>7} {'plain MuJoCo':24} {'s':>7} {'x plain':>8} {'target':>8}")
    for step, ours, ours_s, theirs, theirs_s, target in rows:
        verdict = "" if target is None else (f"<= {target:g} ok" if ours_s <= target else f"MISS {target:g}")
        print(
            f"{step:16} {ours:22} {ours_s:7.3f} {theirs:24} {theirs_s:7.3f} "
            f"{ours_s / theirs_s:8.2f} {verdict:>8}"
        )
    print(
        "x plain > 1 is what rsi costs over one plain render: a basis render per light group (linear, "
        "unclipped sums), float32 luminance and the camera model (exposure, strobe field, noise, 8 bits)."
    )
    world.close()


if __name__ == "__main__":
    main()
