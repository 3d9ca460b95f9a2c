"""Local registration against the optical-flow tools a user would pick instead, one thread.

Run from the repository root::

    .venv/bin/python benchmarks/bench_local_registration.py

Each pair is a textured surface blurred as by optics (sigma 1.5 px) and an inspection that shows it through
a known smooth displacement field of the given amplitude, plus 1 DN of noise (the warps of
tests/imaging/test_local_registration.py, at 512 x 512). Every method is asked where each inspection
pixel's content lies in the reference; the error is the distance to the truth, RMS and worst, over the frame
less a 24 px border (the warp brings reflected content there). Times are the CPU time of the calling thread
(median of 3 runs), with OpenCV and BLAS held to one thread.

- rsi: ``rsi.register(reference, inspection, model="local")`` (affine fit, then the mesh), cold.
- OpenCV DIS (``DISOpticalFlow``, PRESET_MEDIUM) and Farneback (``calcOpticalFlowFarneback``, its
  documented example settings 0.5, 3, 15, 3, 5, 1.2), on 8-bit images as they require.
- scikit-image ``optical_flow_ilk`` (radius 7) and ``optical_flow_tvl1`` (defaults).
"""

from __future__ import annotations

import os

for _variable in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ[_variable] = "1"

import statistics
import sys
import time
from collections.abc import Callable

import cv2
import numpy as np
from numpy.typing import NDArray
from skimage.registration import optical_flow_ilk, optical_flow_tvl1

from rsi.datasets.synthetic import textured_surface
from rsi.imaging.registration import register

SIZE_PX = 512
BORDER_PX = 24
BLUR_PX = 1.5
NOISE_DN = 1.0
AMPLITUDES_PX = (1.0, 2.0, 3.0)
ROUNDS = 3

FloatArray = NDArray[np.float64]
Preimage = tuple[FloatArray, FloatArray]
Method = Callable[[NDArray[np.float32], NDArray[np.float32]], Preimage]


def pair(amplitude_px: float, seed: int) -> tuple[NDArray[np.float32], NDArray[np.float32], FloatArray]:
    rng = np.random.default_rng(seed)
    texture = (textured_surface((SIZE_PX, SIZE_PX), rng=rng) * 200.0 + 20.0).astype(np.float32)
    reference = np.asarray(cv2.GaussianBlur(texture, (0, 0), BLUR_PX), dtype=np.float32)
    rows, cols = np.mgrid[0:SIZE_PX, 0:SIZE_PX].astype(np.float64)
    phase = 2 * np.pi / SIZE_PX
    ux = amplitude_px * np.sin(0.7 * phase * cols + 0.3) * np.cos(0.5 * phase * rows)
    uy = amplitude_px * np.cos(0.4 * phase * cols) * np.sin(0.8 * phase * rows + 1.0)
    inspection = cv2.remap(
        reference,
        (cols - ux).astype(np.float32),
        (rows - uy).astype(np.float32),
        cv2.INTER_CUBIC,
        borderMode=cv2.BORDER_REFLECT,
    )
    inspection = inspection + rng.normal(0.0, NOISE_DN, inspection.shape).astype(np.float32)
    return reference, np.asarray(inspection, dtype=np.float32), np.stack([ux, uy], axis=-1)


def _grid() -> tuple[FloatArray, FloatArray]:
    rows, cols = np.mgrid[0:SIZE_PX, 0:SIZE_PX].astype(np.float64)
    return cols, rows


def rsi_local(reference: NDArray[np.float32], inspection: NDArray[np.float32]) -> Preimage:
    registration = register(reference, inspection, model="local")
    assert registration.local is not None
    map_x, map_y = registration.local.source_maps(registration.matrix, (SIZE_PX, SIZE_PX))
    return map_x.astype(np.float64), map_y.astype(np.float64)


def _from_flow_xy(flow: NDArray[np.float32]) -> Preimage:
    # prev = inspection, next = reference: inspection(y) ~ reference(y + flow(y)).
    cols, rows = _grid()
    return cols + flow[..., 0], rows + flow[..., 1]


def _bytes(image: NDArray[np.float32]) -> NDArray[np.uint8]:
    return np.clip(np.rint(image), 0, 255).astype(np.uint8)


def dis(reference: NDArray[np.float32], inspection: NDArray[np.float32]) -> Preimage:
    flow = cv2.DISOpticalFlow_create(cv2.DISOPTICAL_FLOW_PRESET_MEDIUM).calc(
        _bytes(inspection), _bytes(reference), None
    )
    return _from_flow_xy(flow)


def farneback(reference: NDArray[np.float32], inspection: NDArray[np.float32]) -> Preimage:
    flow = cv2.calcOpticalFlowFarneback(_bytes(inspection), _bytes(reference), None, 0.5, 3, 15, 3, 5, 1.2, 0)
    return _from_flow_xy(flow)


def _from_flow_rc(flow: NDArray[np.float32]) -> Preimage:
    # reference_image = inspection, moving = reference: reference(y + flow(y)) ~ inspection(y).
    cols, rows = _grid()
    return cols + flow[1], rows + flow[0]


def ilk(reference: NDArray[np.float32], inspection: NDArray[np.float32]) -> Preimage:
    return _from_flow_rc(optical_flow_ilk(inspection / 255.0, reference / 255.0, radius=7))


def tvl1(reference: NDArray[np.float32], inspection: NDArray[np.float32]) -> Preimage:
    # Its data-attachment weight assumes intensities in [0, 1].
    return _from_flow_rc(optical_flow_tvl1(inspection / 255.0, reference / 255.0))


METHODS: dict[str, Method] = {
    "rsi local": rsi_local,
    "OpenCV DIS": dis,
    "OpenCV Farneback": farneback,
    "skimage ILK": ilk,
    "skimage TV-L1": tvl1,
}


def errors_px(preimage: Preimage, field: FloatArray) -> FloatArray:
    cols, rows = _grid()
    error = np.hypot(preimage[0] - (cols - field[..., 0]), preimage[1] - (rows - field[..., 1]))
    return np.asarray(error[BORDER_PX:-BORDER_PX, BORDER_PX:-BORDER_PX], dtype=np.float64)


def timed(
    method: Callable[[NDArray[np.float32], NDArray[np.float32]], Preimage], *images: NDArray[np.float32]
) -> tuple[Preimage, float]:
    seconds = []
    result: Preimage | None = None
    for _ in range(ROUNDS):
        start = time.thread_time()
        result = method(*images)
        seconds.append(time.thread_time() - start)
    assert result is not None
    return result, statistics.median(seconds)


def main() -> int:
    cv2.setNumThreads(1)
    print(
        f"{SIZE_PX} x {SIZE_PX}, smooth fields, one thread; error over the frame less {BORDER_PX} px, "
        f"CPU ms median of {ROUNDS}\n"
    )
    print("| amplitude px | method | RMS error px | worst px | ms | x rsi time |")
    print("| ---: | --- | ---: | ---: | ---: | ---: |")
    for seed, amplitude in enumerate(AMPLITUDES_PX):
        reference, inspection, field = pair(amplitude, seed)
        rsi_ms = 0.0
        for name, method in METHODS.items():
            preimage, seconds = timed(method, reference, inspection)
            error = errors_px(preimage, field)
            if name == "rsi local":
                rsi_ms = seconds * 1e3
            rms = float(np.sqrt(np.mean(error**2)))
            print(
                f"| {amplitude:g} | {name} | {rms:.3f} | {float(error.max()):.3f} "
                f"| {seconds * 1e3:.0f} | {seconds * 1e3 / rsi_ms:.2f} |",
                flush=True,
            )
    return 0


if __name__ == "__main__":
    sys.exit(main())
