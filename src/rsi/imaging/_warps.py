"""Warp models, coordinate frames and resampling for registration (seed §2.3).

A warp is a 3x3 float64 matrix that maps a reference pixel ``(x, y, 1)`` to inspection pixel coordinates.
Each model is a record in :data:`WARP_MODELS`: its parameter count, the steepest-descent images of the
inverse-compositional Jacobian at the identity, and the increment matrix built from a parameter update.
Parameters live in centred, normalised coordinates ``u = (x - cx) / s`` so that the Hessian of a 1024-pixel
image is as well conditioned as that of a 64-pixel one.
"""

from __future__ import annotations

import math
import threading
from collections.abc import Callable
from dataclasses import dataclass
from typing import Protocol, TypeVar

import cv2
import numpy as np
from numpy.typing import NDArray

Matrix = NDArray[np.float64]
Image = NDArray[np.float32]
Region = tuple[int, int, int, int]  # (row0, row1, col0, col1), half-open, in reference pixels

_POLY_SHIFT_BITS = 8
_Scalar = TypeVar("_Scalar", bound=np.generic)
_ALIGNMENT = 64


class _Workspace(threading.local):
    """One thread's reusable buffers, one flat byte buffer per role (grown, never shrunk)."""

    def __init__(self) -> None:
        self.buffers: dict[str, NDArray[np.uint8]] = {}


_WORKSPACE = _Workspace()


def scratch(role: str, shape: tuple[int, ...], dtype: type[_Scalar]) -> NDArray[_Scalar]:
    """An uninitialised array for a temporary of one call that never reaches the caller.

    A cold 1024x1024 registration needs about 20 MB of temporaries (pyramids, the 8 MB Jacobian, residual
    buffers). Freshly allocated, glibc hands such buffers back to the system on free, and every call then
    pays thousands of page faults: on a small flight computer (seed §2.1) they cost as much as the arithmetic
    (docs/registration.md). Each thread therefore keeps one buffer per `role`, reused by its next call: at
    most the temporaries of the largest call so far, per thread, none shared between threads. Two arrays
    alive at once must have different roles, and nothing made here may be returned to the caller.
    """
    size = math.prod(shape) * np.dtype(dtype).itemsize
    buffer = _WORKSPACE.buffers.get(role)
    if buffer is None or buffer.size < size:
        # Cache-line aligned, as OpenCV aligns its own buffers (its vector loads are slower across lines).
        padded = np.empty(size + _ALIGNMENT, dtype=np.uint8)
        start = -padded.ctypes.data % _ALIGNMENT
        buffer = _WORKSPACE.buffers[role] = padded[start : start + size]
    return buffer[:size].view(dtype).reshape(shape)


def owned(role: str, shape: tuple[int, ...], dtype: type[_Scalar]) -> NDArray[_Scalar]:
    """A new, uninitialised array: for what the caller keeps (the :func:`scratch` signature, role unused)."""
    return np.empty(shape, dtype=dtype)


class Allocate(Protocol):
    """:func:`scratch` (temporaries of one call) or :func:`owned` (arrays the caller keeps)."""

    def __call__(self, role: str, shape: tuple[int, ...], dtype: type[_Scalar]) -> NDArray[_Scalar]: ...


def _translation(gu: Image, gv: Image, u: Image, v: Image) -> list[Image]:
    return [gu, gv]


def _euclidean(gu: Image, gv: Image, u: Image, v: Image) -> list[Image]:
    return [gu, gv, u * gv - v * gu]


def _similarity(gu: Image, gv: Image, u: Image, v: Image) -> list[Image]:
    return [gu, gv, u * gu + v * gv, u * gv - v * gu]


def _affine(gu: Image, gv: Image, u: Image, v: Image) -> list[Image]:
    return [gu, gv, u * gu, v * gu, u * gv, v * gv]


def _homography(gu: Image, gv: Image, u: Image, v: Image) -> list[Image]:
    radial = u * gu + v * gv
    return [*_affine(gu, gv, u, v), -u * radial, -v * radial]


def _translation_step(p: NDArray[np.float64]) -> Matrix:
    return np.array([[1.0, 0.0, p[0]], [0.0, 1.0, p[1]], [0.0, 0.0, 1.0]])


def _euclidean_step(p: NDArray[np.float64]) -> Matrix:
    cos, sin = np.cos(p[2]), np.sin(p[2])
    return np.array([[cos, -sin, p[0]], [sin, cos, p[1]], [0.0, 0.0, 1.0]])


def _similarity_step(p: NDArray[np.float64]) -> Matrix:
    return np.array([[1.0 + p[2], -p[3], p[0]], [p[3], 1.0 + p[2], p[1]], [0.0, 0.0, 1.0]])


def _affine_step(p: NDArray[np.float64]) -> Matrix:
    return np.array([[1.0 + p[2], p[3], p[0]], [p[4], 1.0 + p[5], p[1]], [0.0, 0.0, 1.0]])


def _homography_step(p: NDArray[np.float64]) -> Matrix:
    step = _affine_step(p)
    step[2, :2] = p[6:8]
    return step


@dataclass(frozen=True)
class WarpModel:
    """One motion model: the first two parameters are always the translation (u, v) of the centre.

    Attributes
    ----------
    n_params : int
        Number of geometric parameters.
    descent : callable
        ``descent(gu, gv, u, v)`` returns the ``n_params`` steepest-descent images dT/dp at the identity,
        from the template gradients ``gu, gv`` of shape (M, N) in normalised units and the normalised
        coordinates ``u`` of shape (1, N) and ``v`` of shape (M, 1).
    step : callable
        ``step(p)`` returns the 3x3 warp, in normalised coordinates, of a parameter vector of length
        ``n_params``.
    """

    n_params: int
    descent: Callable[[Image, Image, Image, Image], list[Image]]
    step: Callable[[NDArray[np.float64]], Matrix]


WARP_MODELS: dict[str, WarpModel] = {
    "translation": WarpModel(2, _translation, _translation_step),
    "euclidean": WarpModel(3, _euclidean, _euclidean_step),
    "similarity": WarpModel(4, _similarity, _similarity_step),
    "affine": WarpModel(6, _affine, _affine_step),
    "homography": WarpModel(8, _homography, _homography_step),
}


def normaliser(shape: tuple[int, int]) -> Matrix:
    """Map pixel (x, y, 1) of an image of `shape` (M, N) to centred coordinates in units of half a side."""
    rows, cols = shape
    scale = max(rows, cols) / 2.0
    return np.array(
        [
            [1.0 / scale, 0.0, -(cols - 1) / (2.0 * scale)],
            [0.0, 1.0 / scale, -(rows - 1) / (2.0 * scale)],
            [0, 0, 1],
        ]
    )


def rescale(matrix: Matrix, factor: float) -> Matrix:
    """Return `matrix` expressed in pixels `factor` times larger (``x_new = factor * x``; pyrDown halves)."""
    scaling = np.diag([factor, factor, 1.0])
    return scaling @ matrix @ np.diag([1.0 / factor, 1.0 / factor, 1.0])


def is_translation(matrix: Matrix) -> bool:
    """Return whether `matrix` is a pure translation (then a sub-pixel crop is the whole warp)."""
    return bool(np.array_equal(matrix[:2, :2], np.eye(2)) and np.array_equal(matrix[2], [0.0, 0.0, 1.0]))


def map_points(matrix: Matrix, points_xy: NDArray[np.float64]) -> NDArray[np.float64]:
    """Map points of shape (K, 2) in (x, y) through the homogeneous `matrix`; returns shape (K, 2)."""
    mapped = points_xy @ matrix[:2, :2].T + matrix[:2, 2]
    denominator = points_xy @ matrix[2, :2] + matrix[2, 2]
    return np.asarray(mapped / denominator[:, None], dtype=np.float64)


def sample(
    image: Image, matrix: Matrix, region: Region, row_step: int = 1, out: Image | None = None
) -> Image:
    """Resample `image` bilinearly at ``matrix @ (x, y, 1)`` for every reference pixel of `region`.

    Parameters
    ----------
    image : ndarray of shape (P, Q), float32
        Image to read from (the inspection).
    matrix : ndarray of shape (3, 3)
        Reference pixel to `image` pixel map.
    region : tuple of int
        (row0, row1, col0, col1) of the reference pixels to produce.
    row_step : int
        Produce only the rows ``row0, row0 + row_step, ...`` of `region`.
    out : ndarray of shape (rows produced, col1 - col0), float32, optional
        Buffer to write into (saves a page-faulting 4 MB allocation per call at 1024^2).

    Returns
    -------
    ndarray of shape (rows produced, col1 - col0), float32, C-contiguous
    """
    row0, row1, col0, col1 = region
    size_wh = (col1 - col0, len(range(row0, row1, row_step)))
    if is_translation(matrix):
        origin_xy = (col0 + matrix[0, 2], row0 + matrix[1, 2])
        if row_step == 1:
            # A shift is a sub-pixel crop: getRectSubPix is ~9x cheaper than warpAffine at 1024^2.
            centre = (origin_xy[0] + (size_wh[0] - 1) / 2.0, origin_xy[1] + (size_wh[1] - 1) / 2.0)
            return np.asarray(cv2.getRectSubPix(image, size_wh, centre, patch=out), dtype=np.float32)
        rows = _skipped_rows(image, origin_xy, size_wh, row_step, out)
        if rows is not None:
            return rows
    shifted = matrix @ np.array([[1.0, 0.0, col0], [0.0, row_step, row0], [0.0, 0.0, 1.0]])
    flags = cv2.INTER_LINEAR | cv2.WARP_INVERSE_MAP
    if np.array_equal(shifted[2], [0.0, 0.0, 1.0]):
        warped = cv2.warpAffine(
            image, shifted[:2], size_wh, dst=out, flags=flags, borderMode=cv2.BORDER_REPLICATE
        )
    else:
        warped = cv2.warpPerspective(
            image, shifted, size_wh, dst=out, flags=flags, borderMode=cv2.BORDER_REPLICATE
        )
    return np.asarray(warped, dtype=np.float32)


def _skipped_rows(
    image: Image, origin_xy: tuple[float, float], size_wh: tuple[int, int], row_step: int, out: Image | None
) -> Image | None:
    """Bilinear crop at `origin_xy` of every `row_step`-th row, as two weighted sums of strided views.

    None when the samples would leave the image (the caller then takes the general, bordered path).
    """
    (width, height), (x0, y0) = size_wh, origin_xy
    col, row = int(np.floor(x0)), int(np.floor(y0))
    fx, fy = x0 - col, y0 - row
    last_row = row + 1 + row_step * (height - 1)
    if col < 0 or row < 0 or col + width >= image.shape[1] or last_row >= image.shape[0]:
        return None
    columns = slice(col, col + width + 1)
    upper = image[row:last_row:row_step, columns]
    lower = image[row + 1 : last_row + 1 : row_step, columns]
    vertical = cv2.addWeighted(upper, 1.0 - fy, lower, fy, 0.0, dst=scratch("rows", upper.shape, np.float32))
    return np.asarray(
        cv2.addWeighted(vertical[:, :width], 1.0 - fx, vertical[:, 1:], fx, 0.0, dst=out), dtype=np.float32
    )


def valid_region(
    matrix: Matrix, reference_shape: tuple[int, int], inspection_shape: tuple[int, int], margin_px: float
) -> tuple[Region, NDArray[np.bool_] | None]:
    """Reference pixels at least `margin_px` inside both images once mapped into the inspection.

    Returns
    -------
    region : tuple of int
        Bounding box (row0, row1, col0, col1), half-open; empty (row1 <= row0) when nothing is valid.
    inside : ndarray of shape (row1 - row0, col1 - col0), bool, or None
        Which pixels of the box are valid; None when all are (pure translations give a rectangle).
    """
    rows, cols = inspection_shape
    low, high_x, high_y = margin_px, cols - 1 - margin_px, rows - 1 - margin_px
    border = int(np.ceil(margin_px))
    ref_box = (border, reference_shape[0] - border, border, reference_shape[1] - border)
    if is_translation(matrix):
        tx, ty = matrix[0, 2], matrix[1, 2]
        box = (
            max(ref_box[0], int(np.ceil(low - ty))),
            min(ref_box[1], int(np.floor(high_y - ty)) + 1),
            max(ref_box[2], int(np.ceil(low - tx))),
            min(ref_box[3], int(np.floor(high_x - tx)) + 1),
        )
        return box, None
    corners = np.array([[low, low], [high_x, low], [high_x, high_y], [low, high_y]])
    polygon = map_points(np.asarray(np.linalg.inv(matrix), dtype=np.float64), corners)
    canvas = np.zeros(reference_shape, dtype=np.uint8)
    scale = float(1 << _POLY_SHIFT_BITS)
    # The rasterised edge may be off by a pixel: shrink by one more pixel than asked.
    cv2.fillPoly(canvas, [np.round(polygon * scale).astype(np.int32)], (1,), cv2.LINE_8, _POLY_SHIFT_BITS)
    canvas = np.asarray(cv2.erode(canvas, np.ones((3, 3), np.uint8)), dtype=np.uint8)
    canvas[: ref_box[0]] = 0
    canvas[ref_box[1] :] = 0
    canvas[:, : ref_box[2]] = 0
    canvas[:, ref_box[3] :] = 0
    col0, row0, width, height = cv2.boundingRect(canvas)
    inside = canvas[row0 : row0 + height, col0 : col0 + width].astype(bool)
    return (row0, row0 + height, col0, col0 + width), (None if inside.all() else inside)


def corner_motion_px(before: Matrix, after: Matrix, region: Region) -> float:
    """Largest distance, in pixels, that a corner of `region` moves between two warps."""
    row0, row1, col0, col1 = region
    corners = np.array(
        [[col0, row0], [col1 - 1, row0], [col1 - 1, row1 - 1], [col0, row1 - 1]], dtype=np.float64
    )
    moved = map_points(after, corners) - map_points(before, corners)
    return float(np.sqrt((moved**2).sum(axis=1)).max())
