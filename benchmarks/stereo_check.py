"""The stereo range map against the rendered depth, per surface (issue 13 simulator check).

For every plan vista of a few seeded worlds, the ISEE's pair is matched (`rsi.imaging.stereo.range_map`, as
the mission does through `rsi.mission.views.sense`) and compared with the renderer's depth, which only this
check and the tests may read. Per surface (the truss frame, each component, the rest): the share of pixels
the matcher left as holes, the share of false matches (more than 3 cm off), and the spread of the others
against the prediction sigma_Z = Z^2 sigma_d / (f B) for a disparity error of 1 px (the median absolute
error of Gaussian errors is 0.674 sigma: a ratio of 0.25 means sigma_d ~ 0.37 px).

Run: ``MUJOCO_GL=egl .venv/bin/python benchmarks/stereo_check.py [--seeds 3] [--size 480 640]``
"""

from __future__ import annotations

import argparse
import os
from collections import defaultdict

import numpy as np

os.environ.setdefault("MUJOCO_GL", "egl")

from rsi.imaging.stereo import range_map
from rsi.mission import plan_vistas
from rsi.sim.capture import capture
from rsi.sim.world import load

FALSE_MATCH_M = 0.03


def _surfaces(view: object) -> dict[str, np.ndarray]:
    truss = view.truss_mask  # type: ignore[attr-defined]
    named = {"truss frame and arm": truss}
    for site, mask in view.component_masks.items():  # type: ignore[attr-defined]
        named[site] = mask & ~truss
    taken = np.logical_or.reduce(list(named.values()))
    named["plates, panel frame, rest"] = ~taken
    return named


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=3)
    parser.add_argument("--size", type=int, nargs=2, default=(480, 640))
    args = parser.parse_args()
    size = (args.size[0], args.size[1])
    totals: dict[str, list[float]] = defaultdict(lambda: [0, 0, 0, 0.0, 0.0, 0])
    for seed in range(args.seeds):
        world = load("truss", seed=seed)
        try:
            for point in plan_vistas(world):
                world.set_door(point.door_angle_rad)
                view = world.render(point.vista, size=size, state="reference", stereo=True)
                taken = capture(world, view)
                raw = range_map(*taken.stereo, taken.rig, depth_limits_m=(0.2, 2.0))
                depth = view.depth_m
                assert depth is not None
                surface = depth < 10.0
                for name, mask in _surfaces(view).items():
                    pixels = mask & surface
                    matched = pixels & np.isfinite(raw)
                    error = np.abs(raw - depth)[matched]
                    good = error < FALSE_MATCH_M
                    sigma = taken.rig.depth_sigma_m(depth[matched][good], 1.0)
                    row = totals[name]
                    row[0] += int(pixels.sum())
                    row[1] += int(pixels.sum() - matched.sum())
                    row[2] += int((~good).sum())
                    if good.any():
                        row[3] += float(np.median(error[good])) * good.sum()
                        row[4] += float(np.median(np.asarray(sigma))) * good.sum()
                        row[5] += int(good.sum())
        finally:
            world.close()
    print(f"seeds 0..{args.seeds - 1}, every plan vista, {size[0]}x{size[1]}, reference state")
    print(
        "| surface | pixels | holes | false matches (> 3 cm) | median abs error mm "
        "| sigma_Z(1 px) mm | ratio |"
    )
    print("| --- | --- | --- | --- | --- | --- | --- |")
    for name, (pixels, holes, false, error, sigma, good) in sorted(totals.items()):
        if not pixels:
            continue
        e, s = (1e3 * error / good, 1e3 * sigma / good) if good else (float("nan"), float("nan"))
        print(
            f"| {name} | {pixels} | {holes / pixels:.2f} | {false / max(pixels - holes, 1):.2f} | "
            f"{e:.2f} | {s:.2f} | {e / s:.2f} |"
        )


if __name__ == "__main__":
    main()
