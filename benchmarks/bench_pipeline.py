"""Time the whole visual-inspection pipeline against the pipeline a user would build from OpenCV.

Per 640x480 interlaced frame (seed §2.1-2.4): intra-frame ambient compensation of the new frame, registration
to the stored (already compensated) reference field, and flaw detection at P_F = 1e-5. Per 1024x1024 pair:
two-frame compensation (flash-lit minus ambient frame), registration and detection. The alternative is what an
engineer would write with OpenCV alone: the same compensated images, cv2.findTransformECC (translation),
warpAffine, absdiff, a hand-tuned threshold at 4 robust sigmas, a 3x3 opening and connected components.
Both are scored against the ground truth too, so speed is never bought with misses.

Run: ``.venv/bin/python benchmarks/bench_pipeline.py [--repeats 15]``. One thread, like the seed's small
space-qualified computer; the budget is one video field, 16.7 ms.
"""

from __future__ import annotations

import os

for _variable in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ[_variable] = "1"

import argparse
import statistics
import time
from collections.abc import Callable
from dataclasses import dataclass

import cv2
import numpy as np
from scipy import ndimage

from rsi.datasets.synthetic import flaw_pattern, textured_surface
from rsi.detection.detect import detect
from rsi.imaging.camera import CameraModel, expose
from rsi.imaging.compensation import Compensated, compensate_interlaced, compensate_two_frames

SUN_LUX = 130_000.0  # seed §2.1
STROBE_LUX_S = 13.0  # seed §2.1: 1.3 lm s over 0.1 m^2
FIELD_BUDGET_MS = 1000.0 / 60.0
P_FALSE_ALARM = 1e-5
SHIFT_XY = (3.4, -2.6)


@dataclass(frozen=True)
class Scene:
    reflectance_ref: np.ndarray
    reflectance_insp: np.ndarray
    ambient_ref: np.ndarray
    ambient_insp: np.ndarray
    truth: np.ndarray


def _scene(shape: tuple[int, int], rng: np.random.Generator) -> Scene:
    pad = 16
    big = (shape[0] + 2 * pad, shape[1] + 2 * pad)
    surface = 0.25 + 0.5 * textured_surface(big, rng=rng)
    window = (slice(pad, pad + shape[0]), slice(pad, pad + shape[1]))
    moved = ndimage.shift(surface, (SHIFT_XY[1], SHIFT_XY[0]), mode="reflect")[window]
    flaws = flaw_pattern(shape, size_px=5, spacing_px=40, strength=0.12, rng=rng)
    shadow = np.where(np.arange(shape[1])[None, :] < shape[1] * 0.6, 1.0, 0.35) * np.ones(shape)
    return Scene(
        reflectance_ref=surface[window],
        reflectance_insp=np.clip(moved + flaws.signal, 0.0, 1.0),
        ambient_ref=SUN_LUX * np.ones(shape),
        ambient_insp=SUN_LUX * 0.8 * ndimage.gaussian_filter(shadow, 3.0),
        truth=flaws.truth_mask,
    )


def _interlaced(scene: Scene, camera: CameraModel, rng: np.random.Generator) -> tuple[Compensated, object]:
    reference = expose(
        scene.ambient_ref * scene.reflectance_ref,
        STROBE_LUX_S * scene.reflectance_ref,
        camera=camera,
        rng=rng,
    )
    inspection = expose(
        scene.ambient_insp * scene.reflectance_insp,
        STROBE_LUX_S * scene.reflectance_insp,
        camera=camera,
        rng=rng,
    )
    return compensate_interlaced(reference), inspection


def _two_frame(scene: Scene, camera: CameraModel, rng: np.random.Generator) -> tuple[Compensated, tuple]:
    def frames(ambient: np.ndarray, reflectance: np.ndarray) -> tuple:
        lit = expose(
            ambient * reflectance, STROBE_LUX_S * reflectance, camera=camera, lit_field="both", rng=rng
        )
        dark = expose(ambient * reflectance, 0.0 * reflectance, camera=camera, lit_field="none", rng=rng)
        return lit, dark

    reference = compensate_two_frames(*frames(scene.ambient_ref, scene.reflectance_ref))
    return reference, frames(scene.ambient_insp, scene.reflectance_insp)


def _opencv_pipeline(reference: np.ndarray, inspection: np.ndarray) -> np.ndarray:
    warp = np.eye(2, 3, dtype=np.float32)
    criteria = (cv2.TERM_CRITERIA_EPS | cv2.TERM_CRITERIA_COUNT, 50, 1e-3)
    _, warp = cv2.findTransformECC(reference, inspection, warp, cv2.MOTION_TRANSLATION, criteria, None, 5)
    size = (inspection.shape[1], inspection.shape[0])
    warped = cv2.warpAffine(reference, warp, size, flags=cv2.INTER_LINEAR + cv2.WARP_INVERSE_MAP)
    difference = cv2.absdiff(inspection, warped)
    sigma = 1.4826 * float(np.median(np.abs(difference - np.median(difference))))
    mask = (difference > 4.0 * sigma).astype(np.uint8)
    mask = cv2.morphologyEx(mask, cv2.MORPH_OPEN, np.ones((3, 3), np.uint8))
    cv2.connectedComponents(mask)
    return mask.astype(bool)


def _score(found: np.ndarray, truth: np.ndarray) -> tuple[float, int]:
    labels, count = ndimage.label(truth)
    hit = np.unique(labels[found & truth])
    recall = float(np.count_nonzero(hit)) / max(count, 1)
    found_labels, found_count = ndimage.label(found)
    near_truth = ndimage.binary_dilation(truth, iterations=2)
    false = found_count - np.count_nonzero(np.unique(found_labels[found & near_truth]))
    return recall, false


def _median_ms(run: Callable[[], object], repeats: int) -> float:
    run()
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        run()
        times.append((time.perf_counter() - start) * 1000.0)
    return statistics.median(times)


def _case(name: str, shape: tuple[int, int], interlaced: bool, repeats: int) -> list[tuple]:
    rng = np.random.default_rng(11)
    camera = CameraModel()
    scene = _scene(shape, rng)
    if interlaced:
        reference, frame = _interlaced(scene, camera, rng)
        truth = scene.truth[1::2]

        def compensate() -> Compensated:
            return compensate_interlaced(frame)
    else:
        reference, frames = _two_frame(scene, camera, rng)
        truth = scene.truth

        def compensate() -> Compensated:
            return compensate_two_frames(*frames)

    def rsi_run() -> np.ndarray:
        return detect(reference, compensate(), flaw_model="uniform", size=3, p_false_alarm=P_FALSE_ALARM).mask

    def opencv_run() -> np.ndarray:
        return _opencv_pipeline(reference.image, compensate().image)

    rows = []
    for label, run in (
        ("rsi (compensate+register+detect)", rsi_run),
        ("OpenCV ECC+absdiff+threshold", opencv_run),
    ):
        ms = _median_ms(run, repeats)
        recall, false = _score(run(), truth)
        rows.append((name, label, ms, recall, false))
    return rows


def main() -> None:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--repeats", type=int, default=15)
    args = parser.parse_args()
    cv2.setNumThreads(1)
    rows = _case("640x480 interlaced frame", (480, 640), True, args.repeats)
    rows += _case("1024x1024 two-frame pair", (1024, 1024), False, args.repeats)
    print(f"{'case':26} {'pipeline':34} {'ms':>8} {'x rsi':>7} {'recall':>7} {'false':>6}")
    for index, (case, label, ms, recall, false) in enumerate(rows):
        rsi_ms = rows[index - index % 2][2]
        print(f"{case:26} {label:34} {ms:8.2f} {ms / rsi_ms:7.2f} {recall:7.3f} {false:6d}")
    frame_ms = rows[0][2]
    verdict = "meets" if frame_ms <= FIELD_BUDGET_MS else "MISSES"
    print(
        f"\n640x480 frame: {frame_ms:.2f} ms per frame, "
        f"{verdict} the one-field budget of {FIELD_BUDGET_MS:.1f} ms"
    )


if __name__ == "__main__":
    main()
