"""Benchmark rsi.register (translation) against the tools a user would pick instead (seed §2.3).

Images: skimage.data camera, brick, gravel and grass at 512x512 (float32 in [0, 1]) and a 2x2 mosaic of
them at 1024x1024. Each is shifted by known (dx, dy) with a cubic spline on a reflect-padded copy, then
cropped, so no method sees border junk; the inspection is ``1.1 * shifted + 0.03`` plus Gaussian noise of
sigma 2/255 (fixed seed). Every method runs single-threaded, interleaved with the others over the timed
rounds so that machine load hits all alike. Time is the median over the rounds of the CPU time of the calling
thread (``time.thread_time``): for these single-threaded runs it is the wall time of an idle machine, and it
does not count the time other processes hold the shared cores; the wall-clock ratio is printed as well.

rsi is timed twice. "cold" does everything per call, as ECC does. "warm" registers to a reference prepared
once by ``prepare_reference`` outside the timing (a robot's stored reference, seed §2.3: "terms involving the
Jacobian matrix ... can be pre-computed"); the preparation's own time is printed apart. Warm is never cold.

Run: ``.venv/bin/python benchmarks/bench_registration.py`` (``--quick`` for a short run).
"""

from __future__ import annotations

import os

for _variable in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ[_variable] = "1"

import argparse
import time
from collections.abc import Callable

import cv2
import numpy as np
import scipy.ndimage as ndi
from numpy.typing import NDArray
from skimage import data
from skimage.registration import phase_cross_correlation

from rsi.imaging.registration import PreparedReference, prepare_reference, register

Image = NDArray[np.float32]
Method = Callable[[Image, Image], tuple[float, float]]

SHIFTS_XY = ((3.7, -2.2), (9.6, -8.3), (25.3, -31.1), (40.2, 44.7))
TEXTURES = ("camera", "brick", "gravel", "grass")
GAIN, BIAS, NOISE_SIGMA = 1.1, 0.03, 2.0 / 255.0
CAPTURE_ERROR_PX = 0.05
PAD_PX = 64
_ECC_CRITERIA = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 50, 1e-3)  # OpenCV's default


def images() -> dict[str, Image]:
    """The four textures at 512x512 and their 2x2 mosaic at 1024x1024, float32 in [0, 1]."""
    tiles = {name: (getattr(data, name)() / 255.0).astype(np.float32) for name in TEXTURES}
    mosaic = np.block([[tiles["camera"], tiles["brick"]], [tiles["gravel"], tiles["grass"]]])
    return {**tiles, "mosaic1024": mosaic.astype(np.float32)}


def inspection_of(reference: Image, shift_xy: tuple[float, float], rng: np.random.Generator) -> Image:
    """``scipy.ndimage.shift(reference, (dy, dx))`` without border junk, with gain, bias and noise."""
    padded = np.pad(reference.astype(np.float64), PAD_PX, mode="reflect")
    shifted = ndi.shift(padded, (shift_xy[1], shift_xy[0]), order=3, mode="reflect")[
        PAD_PX:-PAD_PX, PAD_PX:-PAD_PX
    ]
    noisy = GAIN * shifted + BIAS + rng.normal(0.0, NOISE_SIGMA, reference.shape)
    return noisy.astype(np.float32)


def _rsi(reference: Image, inspection: Image) -> tuple[float, float]:
    return register(reference, inspection, model="translation").translation_xy


def _rsi_warm(prepared: PreparedReference) -> Method:
    def method(reference: Image, inspection: Image) -> tuple[float, float]:
        return register(prepared, inspection).translation_xy

    return method


def _ecc(reference: Image, inspection: Image) -> tuple[float, float]:
    # ECC's warp maps template (reference) pixels to input (inspection) pixels: rsi's sign already.
    warp = np.eye(2, 3, dtype=np.float32)
    try:
        _, warp = cv2.findTransformECC(
            reference, inspection, warp, cv2.MOTION_TRANSLATION, _ECC_CRITERIA, None, 5
        )
    except cv2.error:
        return float("nan"), float("nan")
    return float(warp[0, 2]), float(warp[1, 2])


def _ecc_multiscale(reference: Image, inspection: Image) -> tuple[float, float]:
    parameters = cv2.ECCParameters()
    parameters.motionType = cv2.MOTION_TRANSLATION
    warp = np.eye(2, 3, dtype=np.float32)
    try:
        _, warp = cv2.findTransformECCMultiScale(reference, inspection, warp, parameters)
    except cv2.error:
        return float("nan"), float("nan")
    return float(warp[0, 2]), float(warp[1, 2])


def _phase_iterative(reference: Image, inspection: Image) -> tuple[float, float]:
    # Copies: OpenCV 5 phase correlation may overwrite its inputs.
    dx, dy = cv2.phaseCorrelateIterative(reference.copy(), inspection.copy())
    return float(dx), float(dy)


def _skimage(reference: Image, inspection: Image) -> tuple[float, float]:
    # skimage returns the shift that registers the moving image back onto the reference: the negative.
    shift_rc, _, _ = phase_cross_correlation(reference, inspection, upsample_factor=20)
    return -float(shift_rc[1]), -float(shift_rc[0])


COLD, WARM = "rsi.register cold", "rsi.register warm"
METHODS: dict[str, Method] = {
    COLD: _rsi,
    WARM: _rsi,  # replaced per reference by _rsi_warm(prepared) in measure()
    "cv2.findTransformECC": _ecc,
    "cv2.findTransformECCMultiScale": _ecc_multiscale,
    "cv2.phaseCorrelateIterative": _phase_iterative,
    "skimage.phase_cross_correlation": _skimage,
}


def _run(method: Method, reference: Image, inspection: Image) -> tuple[tuple[float, float], float, float]:
    cpu_started, wall_started = time.thread_time(), time.perf_counter()
    shift = method(reference, inspection)
    return shift, time.thread_time() - cpu_started, time.perf_counter() - wall_started


def measure(
    reference: Image, inspection: Image, prepared: PreparedReference, rounds: int
) -> dict[str, tuple[tuple[float, float], float, float]]:
    """Per method: estimated (dx, dy), median CPU and wall seconds over `rounds`, methods interleaved."""
    methods = {**METHODS, WARM: _rsi_warm(prepared)}
    cpu: dict[str, list[float]] = {name: [] for name in methods}
    wall: dict[str, list[float]] = {name: [] for name in methods}
    shifts = {name: _run(method, reference, inspection)[0] for name, method in methods.items()}  # warm-up
    for _ in range(rounds):
        for name, method in methods.items():
            _, cpu_s, wall_s = _run(method, reference, inspection)
            cpu[name].append(cpu_s)
            wall[name].append(wall_s)
    return {
        name: (shifts[name], float(np.median(cpu[name])), float(np.median(wall[name]))) for name in methods
    }


def _prepare_time_s(reference: Image, rounds: int) -> float:
    times = []
    for _ in range(rounds):
        started = time.thread_time()
        prepare_reference(reference)
        times.append(time.thread_time() - started)
    return float(np.median(times))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="two images, two shifts, three rounds")
    parser.add_argument("--rounds", type=int, default=7, help="timed rounds per method (default 7)")
    args = parser.parse_args()
    cv2.setNumThreads(1)
    rng = np.random.default_rng(20240605)
    chosen = images()
    shifts = SHIFTS_XY
    rounds = args.rounds
    if args.quick:
        chosen = {name: chosen[name] for name in ("gravel", "mosaic1024")}
        shifts, rounds = (SHIFTS_XY[0], SHIFTS_XY[3]), 3
    errors: dict[str, list[float]] = {name: [] for name in METHODS}
    ratios: dict[tuple[str, int], list[tuple[float, float]]] = {}
    print(
        f"{'image':<11} {'shift (dx, dy)':<15} {'method':<32} {'error px':>9} {'cpu ms':>8} {'wall ms':>8} "
        f"{'x ECC cpu':>9}"
    )
    for image_name, reference in chosen.items():
        prepared = prepare_reference(reference)
        prepare_ms = _prepare_time_s(reference, rounds) * 1e3
        print(f"{image_name:<11} prepare_reference (not in the warm times): {prepare_ms:.2f} ms cpu")
        for shift_xy in shifts:
            inspection = inspection_of(reference, shift_xy, rng)
            results = measure(reference, inspection, prepared, rounds)
            _, ecc_cpu, ecc_wall = results["cv2.findTransformECC"]
            for name, (estimate, cpu_s, wall_s) in results.items():
                error = float(np.hypot(estimate[0] - shift_xy[0], estimate[1] - shift_xy[1]))
                errors[name].append(error)
                ratios.setdefault((name, reference.shape[0]), []).append((ecc_cpu / cpu_s, ecc_wall / wall_s))
                shift_text = f"({shift_xy[0]}, {shift_xy[1]})"
                print(
                    f"{image_name:<11} {shift_text:<15} {name:<32} {error:>9.4f} {cpu_s * 1e3:>8.2f} "
                    f"{wall_s * 1e3:>8.2f} {ecc_cpu / cpu_s:>9.1f}"
                )
    _summary(errors, ratios)


def _summary(
    errors: dict[str, list[float]], ratios: dict[tuple[str, int], list[tuple[float, float]]]
) -> None:
    sides = sorted({side for _, side in ratios})
    print(
        f"\nsummary: median error over all pairs; capture failures = error >= {CAPTURE_ERROR_PX} px or none;"
        "\n'x ECC' = ECC time / method time per image side (worst and median over images and shifts), CPU and"
        " wall clock; rsi warm excludes prepare_reference, rsi cold includes everything"
    )
    header = "".join(
        f" {f'worst x {side}':>11} {f'median x {side}':>12} {f'wall worst {side}':>15}" for side in sides
    )
    print(f"{'method':<32} {'median err px':>13} {'capture fails':>13}{header}")
    for name in METHODS:
        failures = sum(1 for error in errors[name] if not error < CAPTURE_ERROR_PX)
        columns = ""
        for side in sides:
            cpu = [ratio[0] for ratio in ratios[(name, side)]]
            wall = [ratio[1] for ratio in ratios[(name, side)]]
            columns += f" {min(cpu):>11.1f} {float(np.median(cpu)):>12.1f} {min(wall):>15.1f}"
        print(
            f"{name:<32} {np.nanmedian(errors[name]):>13.4f} {failures:>7d}/{len(errors[name]):<5d}{columns}"
        )


if __name__ == "__main__":
    main()
