"""Image pyramids, the global first estimate and the coarse-to-fine driver of registration (seed §2.3)."""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace

import cv2
import numpy as np
from numpy.typing import NDArray

from rsi.imaging._warps import Allocate, Image, Matrix, owned, rescale, scratch

# The coarsest level keeps at least this many pixels per side: phase correlation there must still see the
# texture, and a shift of up to half this side (times 2**level) is captured. At 128 the benchmark's largest
# shift (40.2, 44.7) px is found within 0.3 coarse pixels on all textures at 512 and 1024, for a quarter of
# the FFT time of 256 (docs/registration.md).
_COARSEST_SIDE_PX = 128
_SMOOTHING_SIZE_PX = 5
_MIN_PHASE_SIDE_PX = 16


@dataclass(frozen=True)
class Level:
    """One pyramid level, pixels ``2**index`` times larger than the input's.

    Attributes
    ----------
    index : int
        0 is the full resolution.
    reference, inspection : ndarray of shape (M, N) and (P, Q), float32
        Lightly smoothed images (bilinear interpolation is then accurate to a few thousandths of a pixel).
    mask : ndarray of shape (M, N), bool, or None
        Reference pixels the user allows, shrunk by the smoothing footprint.
    """

    index: int
    reference: Image
    inspection: Image
    mask: NDArray[np.bool_] | None


@dataclass(frozen=True)
class Estimate:
    """The registration as it stands after some level.

    Attributes
    ----------
    matrix : ndarray of shape (3, 3)
        Reference to inspection warp in pixels of level `level`.
    gain, bias : float
        Photometric model, inspection ~= gain * reference + bias.
    iterations : int
        Gauss-Newton iterations so far, all levels together.
    reason : str
        "converged", "max_iterations", "deadline" or "diverged" (the last two stop the descent).
    residual_rms : float
        RMS of the inspection minus the fitted reference over the pixels used, inspection units.
    shift_std_px : tuple of float
        Standard deviation of the translation (x, y) in full-resolution pixels.
    level : int
        Pyramid level of `matrix`.
    """

    matrix: Matrix
    gain: float = 1.0
    bias: float = 0.0
    iterations: int = 0
    reason: str = "converged"
    residual_rms: float = float("nan")
    shift_std_px: tuple[float, float] = (float("nan"), float("nan"))
    level: int = 0


Solver = Callable[[Level, Estimate], Estimate]
_STOPPING = ("deadline", "diverged")


def level_count(*shapes: tuple[int, int]) -> int:
    """Number of levels so that the coarsest keeps at least ``_COARSEST_SIDE_PX`` pixels per side."""
    side = min(min(shape) for shape in shapes)
    count = 1
    while side // 2 >= _COARSEST_SIDE_PX:
        side //= 2
        count += 1
    return count


def smooth(image: Image, out: Image | None = None) -> Image:
    """5x5 Gaussian, as ECC's gaussFiltSize: it makes bilinear resampling sub-pixel accurate."""
    size = (_SMOOTHING_SIZE_PX, _SMOOTHING_SIZE_PX)
    return np.asarray(cv2.GaussianBlur(image, size, 0.0, dst=out), dtype=np.float32)


def _shrink_mask(mask: NDArray[np.bool_]) -> NDArray[np.bool_]:
    kernel = np.ones((_SMOOTHING_SIZE_PX, _SMOOTHING_SIZE_PX), np.uint8)
    return np.asarray(cv2.erode(mask.astype(np.uint8), kernel), dtype=bool)


def _pyramid(image: Image, count: int, allocate: Allocate, role: str, presmooth: bool = True) -> list[Image]:
    """`count` levels: `image` smoothed (or `image` itself, without `presmooth`: the caller copies it if it
    keeps it), then cv2.pyrDown of the level above, in arrays from `allocate`."""
    images = [smooth(image, out=allocate(f"{role}0", image.shape, np.float32)) if presmooth else image]
    for index in range(1, count):
        rows, cols = images[-1].shape
        out = allocate(f"{role}{index}", ((rows + 1) // 2, (cols + 1) // 2), np.float32)
        images.append(np.asarray(cv2.pyrDown(images[-1], dst=out), dtype=np.float32))
    return images


def reference_pyramid(
    reference: Image,
    mask: NDArray[np.bool_] | None,
    count: int,
    allocate: Allocate = owned,
    presmooth: bool = True,
) -> tuple[list[Image], list[NDArray[np.bool_] | None]]:
    """Return `count` smoothed levels of the reference and their masks, finest first.

    Only the full resolution is smoothed explicitly; each coarser level is cv2.pyrDown of the smoothed level
    above, whose own 5-tap Gaussian leaves it about as smooth, so four more filter passes are saved. Without
    `presmooth` the full resolution is `reference` itself (pyrDown still smooths every coarser level). The
    levels are new arrays, or :func:`~rsi.imaging._warps.scratch` buffers for a reference used in one call.
    """
    images, masks = (
        _pyramid(reference, count, allocate, "reference", presmooth),
        [None if mask is None else _shrink_mask(mask)],
    )
    for _ in range(1, count):
        previous = masks[-1]
        # A coarse pixel is usable only if every fine pixel under it is.
        masks.append(
            None if previous is None else np.asarray(cv2.pyrDown(previous.astype(np.float32)) > 0.999)
        )
    return images, masks


def inspection_pyramid(inspection: Image, count: int, presmooth: bool = True) -> list[Image]:
    """Return `count` smoothed levels of the inspection, finest first, as :func:`reference_pyramid`.

    They are this thread's :func:`~rsi.imaging._warps.scratch` buffers: valid until its next registration.
    """
    return _pyramid(inspection, count, scratch, "inspection", presmooth)


def _windowed(image: Image, shape: tuple[int, int]) -> Image:
    window = cv2.createHanningWindow(image.shape[::-1], cv2.CV_32F)
    padded = np.zeros(shape, dtype=np.float32)
    padded[: image.shape[0], : image.shape[1]] = (image - image.mean()) * window
    return padded


def phase_shift_xy(reference: Image, inspection: Image) -> tuple[float, float]:
    """Global shift (dx, dy) of `inspection` against `reference` by phase correlation.

    Images of different shapes are windowed separately and zero-padded to a common shape. Any shift up to
    half the image side is found, which is what lets shifts far beyond the Gauss-Newton basin converge.
    """
    if min(*reference.shape, *inspection.shape) < _MIN_PHASE_SIDE_PX:
        return 0.0, 0.0
    shape = (max(reference.shape[0], inspection.shape[0]), max(reference.shape[1], inspection.shape[1]))
    # Fresh arrays: OpenCV 5 phaseCorrelate may overwrite its inputs.
    (dx, dy), _ = cv2.phaseCorrelate(_windowed(reference, shape), _windowed(inspection, shape))
    return float(dx), float(dy)


def coarse_to_fine(levels: Sequence[Level], solver: Solver, start: Estimate | None) -> Estimate:
    """Run `solver` from the coarsest level to the finest, carrying the estimate down.

    Parameters
    ----------
    levels : sequence of Level
        Finest first.
    solver : callable
        ``solver(level, estimate) -> estimate`` refines an estimate given in the level's pixels.
    start : Estimate or None
        Start in full-resolution pixels (level 0); None starts from phase correlation at the coarsest level,
        gain 1 and bias 0.

    Returns
    -------
    Estimate
        In full-resolution pixels (level 0), from the finest level reached: a deadline or a divergence stops
        the descent early.
    """
    top = levels[-1]
    if start is None:
        dx, dy = phase_shift_xy(top.reference, top.inspection)
        estimate = Estimate(np.array([[1.0, 0.0, dx], [0.0, 1.0, dy], [0.0, 0.0, 1.0]]), level=top.index)
    else:
        estimate = start
    for level in reversed(levels):
        factor = 2.0 ** (estimate.level - level.index)
        estimate = solver(
            level, replace(estimate, matrix=rescale(estimate.matrix, factor), level=level.index)
        )
        if estimate.reason in _STOPPING:
            break
    return replace(estimate, matrix=rescale(estimate.matrix, 2.0**estimate.level), level=0)
