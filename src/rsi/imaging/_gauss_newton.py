"""Inverse-compositional Gauss-Newton registration of one pyramid level, with gain, bias and trimming.

Seed §2.3: the residual sum of squares between the inspection and the transformed reference is minimised by
Gauss-Newton, and "terms involving the Jacobian ... can be pre-computed". The inverse-compositional form
(Baker & Matthews 2004, doi:10.1023/B:VISI.0000011205.11775.fd) makes that true for every warp model: the
steepest-descent images and the Hessian are taken on the whole reference level once (:func:`reference_terms`,
reusable across inspections), the Hessian of the pixels a warp leaves usable is that minus the thin strips
outside them, and each iteration costs one resampling of the inspection, one subtraction and one
matrix-vector product.

Gain and bias are fitted in the same solve without breaking the fixed Hessian by normalising the warped
inspection instead of scaling the reference: with ``N = (I(W(x)) - bias) / gain`` the linearised residual
``N - T ~= grad(T) dW/dp dp + dgain T + dbias`` has a Jacobian that depends on the reference only.
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from dataclasses import dataclass, replace

import cv2
import numpy as np
from numpy.typing import NDArray

from rsi.imaging._components import flat_nonzero
from rsi.imaging._pyramid import Estimate, Level
from rsi.imaging._warps import (
    Allocate,
    Image,
    Matrix,
    Region,
    WarpModel,
    corner_motion_px,
    normaliser,
    owned,
    sample,
    scratch,
    valid_region,
)

_MARGIN_PX = 2.0
# A flaw is an outlier of the registration model: trim |residual| beyond this many robust sigmas.
_TRIM_SIGMAS = 4.0
_MAD_TO_SIGMA = 1.4826
_SIGMA_SAMPLES = 1 << 12
_MAX_CONDITION = 1e12
_MIN_PIXELS_PER_UNKNOWN = 8
_COARSE_TOLERANCE_GROWTH = 4.0
# Trim flaws once a step moves less than this many pixels: the pyramid lands the finest level within about
# 0.05 px and one step brings it within a few thousandths, where the misfit at edges is below the noise.
_TRIM_AFTER_STEP_PX = 0.01
# Gauss-Newton with a fixed Hessian converges linearly; with a contraction q = |step k| / |step k-1| the
# motion still to come after step k is about |step k| q / (1 - q). Trusted only for a clear contraction.
_MAX_CONTRACTION = 0.5
_ROW_STEP = 2
_ROW_STEP_MIN_ROWS = 512


@dataclass(frozen=True)
class Settings:
    """What the caller asked for.

    Attributes
    ----------
    model : WarpModel
        Motion model refined.
    photometric : bool
        Fit gain and bias as well.
    max_iterations : int
        Gauss-Newton steps allowed per level (the trimmed refit shares them).
    tolerance_px : float
        Stop when no corner of the region moves more than this, in pixels of the level.
    deadline : float or None
        ``time.perf_counter()`` value at which to stop.
    """

    model: WarpModel
    photometric: bool
    max_iterations: int
    tolerance_px: float
    deadline: float | None


@dataclass(frozen=True)
class Terms:
    """The reference-side terms of one level, computed once per reference (seed §2.3: "terms involving the
    Jacobian matrix ... can be pre-computed").

    Attributes
    ----------
    jacobian : ndarray of shape (K, rows used * N), float32, read-only
        Steepest-descent images on the rows ``0, row_step, 2 row_step, ...`` and every column of the level,
        zero outside the mask and on the image's edge (where central differences are undefined).
    hessian : ndarray of shape (K, K), float64
        ``jacobian @ jacobian.T`` over the whole level; a region's is this minus the strips outside it.
    row_step : int
        1, or 2 on levels with at least 512 rows (their accuracy is limited by interpolation bias, not noise).
    width : int
        N, the level's columns.
    from_pixels, to_pixels : ndarray of shape (3, 3)
        Level pixels to normalised coordinates and back.
    """

    jacobian: NDArray[np.float32]
    hessian: NDArray[np.float64]
    row_step: int
    width: int
    from_pixels: Matrix
    to_pixels: Matrix


@dataclass(frozen=True)
class _Problem:
    """The used pixels of one level for the current warp, and their Hessian.

    The used pixels are the rows ``row0, row0 + row_step, ...`` (row0 a multiple of row_step) and the
    columns ``col0 .. col1 - 1`` of `region`, less `weights` == 0 and the `trimmed` flaws. ``jacobian`` of
    shape (K, R) is the view of the level's Jacobian on the used rows, all N columns: ``jacobian @ residual``
    sums over used pixels only because ``buffer`` of shape (rows used, N), which receives each residual, is
    zero wherever a pixel is not used. ``weights`` of shape (rows used, col1 - col0) is 0 outside the mask or
    the valid polygon and 1 elsewhere, or None when there is neither; ``trimmed`` indexes the flaws in R.
    """

    terms: Terms
    region: Region
    jacobian: NDArray[np.float32]
    hessian: NDArray[np.float64]
    inverse_hessian: NDArray[np.float64]
    weights: NDArray[np.float32] | None
    trimmed: NDArray[np.intp] | None
    n_used: int
    chosen_at: Matrix
    buffer: Image


def _row_step(shape: tuple[int, ...]) -> int:
    # With this many rows the accuracy is limited by interpolation bias, not by noise (seed §2.3): every
    # other row carries the same information at half the cost.
    return _ROW_STEP if shape[0] >= _ROW_STEP_MIN_ROWS else 1


def _zero_edges(planes: Image, last: int) -> None:
    """Zero what lies on the image's edge, where central differences are undefined: no pixel there is used."""
    planes[:, 0] = planes[:, last + 1 :] = planes[:, :, 0] = planes[:, :, -1] = 0.0


def reference_terms(
    reference: Image,
    mask: NDArray[np.bool_] | None,
    model: WarpModel,
    photometric: bool,
    *,
    allocate: Allocate = owned,
    role: str = "jacobian",
    row_step: int | None = None,
) -> Terms:
    """Steepest-descent images and Hessian of one smoothed reference level (`mask` True = usable).

    The Jacobian is a new array, or the `role` :func:`~rsi.imaging._warps.scratch` buffer (`allocate`) for a
    reference used in one call only. `row_step`: every row_step-th row is used (None: :func:`_row_step`).
    """
    rows, cols = reference.shape
    row_step = _row_step(reference.shape) if row_step is None else row_step
    from_pixels, n_params = normaliser((rows, cols)), model.n_params
    shape = (n_params + 2 * photometric, len(range(0, rows, row_step)), cols)
    jacobian = allocate(role, shape, np.float32)
    # Used rows 1 .. last (reference rows row_step .. last * row_step) have both neighbours.
    last = (rows - 2) // row_step
    if last >= 1 and cols >= 3:
        scale, used = 0.5 / from_pixels[0, 0], slice(row_step, last * row_step + 1, row_step)
        # Central differences in normalised units.
        right, left = reference[used, 2:], reference[used, :-2]
        cv2.addWeighted(right, scale, left, -scale, 0.0, dst=jacobian[0, 1 : last + 1, 1:-1])
        below = reference[row_step + 1 : last * row_step + 2 : row_step, 1:-1]
        above = reference[row_step - 1 : last * row_step : row_step, 1:-1]
        cv2.addWeighted(below, scale, above, -scale, 0.0, dst=jacobian[1, 1 : last + 1, 1:-1])
    _zero_edges(jacobian[:2], last)
    if n_params > 2:
        u = (np.arange(cols) * from_pixels[0, 0] + from_pixels[0, 2]).astype(np.float32)
        v = (np.arange(0, rows, row_step) * from_pixels[1, 1] + from_pixels[1, 2]).astype(np.float32)
        planes = model.descent(jacobian[0], jacobian[1], u[None, :], v[:, None])[2:]
        # Plane by plane: assigning the list at once first stacks it into a temporary copy.
        for index, plane in enumerate(planes, start=2):
            jacobian[index] = plane
    if photometric:
        jacobian[n_params] = reference[::row_step]
        jacobian[n_params + 1] = 1.0
        _zero_edges(jacobian[n_params:], last)
    if mask is not None:
        np.multiply(jacobian, mask[::row_step], out=jacobian)
    flat = jacobian.reshape(jacobian.shape[0], -1)
    flat.setflags(write=False)
    return Terms(
        jacobian=flat,
        hessian=_gram(flat),
        row_step=row_step,
        width=cols,
        from_pixels=from_pixels,
        to_pixels=np.asarray(np.linalg.inv(from_pixels), dtype=np.float64),
    )


def _gram(jacobian: NDArray[np.float32]) -> NDArray[np.float64]:
    # Row-pair dot products run at memory speed; a (K, R) @ (R, K) product is 2-3x slower here.
    size = jacobian.shape[0]
    gram = np.empty((size, size))
    for i in range(size):
        for j in range(i, size):
            gram[i, j] = gram[j, i] = np.dot(jacobian[i], jacobian[j])
    return gram


def _outer(columns: NDArray[np.float32]) -> NDArray[np.float64]:
    """``columns @ columns.T`` in float64 for a few pixels (thin strips, dropped pixels)."""
    return _gram(np.ascontiguousarray(columns).reshape(columns.shape[0], -1))


def _inverse(hessian: NDArray[np.float64]) -> NDArray[np.float64] | None:
    """Inverse by Jacobi-balanced inversion; None when singular (a flat image, too few pixels)."""
    diagonal = np.diag(hessian)
    if not np.all(diagonal > 0):
        return None
    scale = 1.0 / np.sqrt(diagonal)
    balanced = hessian * np.outer(scale, scale)
    # A Hessian downdated by trimming can lose positive definiteness to rounding: then it is no Hessian.
    eigenvalues = np.linalg.eigvalsh(balanced)
    if eigenvalues[0] <= 0 or eigenvalues[-1] > _MAX_CONDITION * eigenvalues[0]:
        return None
    return np.asarray(np.linalg.inv(balanced) * np.outer(scale, scale), dtype=np.float64)


def _band_index(box_index: NDArray[np.intp], box_width: int, col0: int, width: int) -> NDArray[np.intp]:
    """Flat indices in a (rows, box_width) box at column col0 -> flat indices in (rows, width)."""
    rows, cols = np.divmod(box_index, box_width)
    return np.asarray(rows * width + (cols + col0), dtype=np.intp)


def _build(level: Level, terms: Terms, matrix: Matrix) -> _Problem | None:
    """Choose the used pixels for this level and their Hessian; None if degenerate.

    The Hessian is the whole level's less the rows above and below the region and the columns beside it
    (thin strips: a few per cent of the pixels), and less the box pixels outside a non-rectangular polygon.
    """
    region, inside = valid_region(matrix, level.reference.shape, level.inspection.shape, _MARGIN_PX)
    row0, row1, col0, col1 = region
    step, width = terms.row_step, terms.width
    first, end = -(-row0 // step), -(-row1 // step)  # used rows first .. end - 1 (level rows times step)
    if end <= first or col1 <= col0:
        return None
    jacobian = terms.jacobian[:, first * width : end * width]
    band = jacobian.reshape(jacobian.shape[0], end - first, width)
    above, below = terms.jacobian[:, : first * width], terms.jacobian[:, end * width :]
    left, right = (np.reshape(side, (side.shape[0], -1)) for side in (band[:, :, :col0], band[:, :, col1:]))
    # One gram of the four strips together: a few per cent of the pixels for usual shifts, few small calls.
    strips = (above, below, left, right)
    columns = scratch("strips", (jacobian.shape[0], sum(strip.shape[1] for strip in strips)), np.float32)
    hessian = terms.hessian - _gram(np.concatenate(strips, axis=1, out=columns))
    used = None
    if inside is not None:
        used = inside[first * step - row0 :: step]
        hessian -= _outer(jacobian[:, _band_index(flat_nonzero(~used), col1 - col0, col0, width)])
    if level.mask is not None:
        # Masked pixels have zero Jacobian columns already: they only leave the statistics and trimming.
        user = level.mask[first * step : row1 : step, col0:col1]
        used = user if used is None else used & user
    weights = None if used is None else used.astype(np.float32)
    n_used = (end - first) * (col1 - col0) if used is None else int(np.count_nonzero(used))
    inverse = _inverse(hessian)
    if inverse is None or n_used < _MIN_PIXELS_PER_UNKNOWN * jacobian.shape[0]:
        return None
    return _Problem(
        terms=terms,
        region=(first * step, row1, col0, col1),
        jacobian=jacobian,
        hessian=hessian,
        inverse_hessian=inverse,
        weights=weights,
        trimmed=None,
        n_used=n_used,
        chosen_at=matrix,
        buffer=_residual_buffer((end - first, width), col0, col1),
    )


def _residual_buffer(shape: tuple[int, int], col0: int, col1: int) -> Image:
    """This thread's residual buffer, zero beside columns col0 .. col1 - 1 (which every residual fills)."""
    buffer = scratch("residual", shape, np.float32)
    buffer[:, :col0] = buffer[:, col1:] = 0.0
    return buffer


def _residual(level: Level, problem: _Problem, estimate: Estimate, photometric: bool) -> Image:
    """Normalised residual ``(I(W(x)) - bias) / gain - T(x)``, zero where unused, shape (R,)."""
    row0, row1, col0, col1 = problem.region
    step = problem.terms.row_step
    template = level.reference[row0:row1:step, col0:col1]
    box = problem.buffer[:, col0:col1]
    warped = sample(level.inspection, estimate.matrix, problem.region, step, out=box)
    if not np.shares_memory(warped, box):
        box[...] = warped
    if photometric:
        gain = estimate.gain
        cv2.addWeighted(box, 1.0 / gain, template, -1.0, -estimate.bias / gain, dst=box)
    else:
        cv2.subtract(box, template, dst=box)
    if problem.weights is not None:
        np.multiply(box, problem.weights, out=box)
    residual = problem.buffer.reshape(-1)
    if problem.trimmed is not None:
        residual[problem.trimmed] = 0.0
    return residual


def _update(
    estimate: Estimate, problem: _Problem, delta: NDArray[np.float64], settings: Settings
) -> Estimate:
    """Compose the inverse of the increment into the warp, and the photometric step into gain and bias."""
    n_params = settings.model.n_params
    matrix = estimate.matrix @ np.linalg.inv(_step_matrix(problem, delta, settings))
    matrix /= matrix[2, 2]
    gain, bias = estimate.gain, estimate.bias
    if settings.photometric:
        # I(W) = gain (1 + dgain) T + gain dbias + bias, from N ~= (1 + dgain) T + dbias.
        gain, bias = gain * (1.0 + delta[n_params]), bias + gain * delta[n_params + 1]
    return replace(estimate, matrix=matrix, gain=gain, bias=bias, iterations=estimate.iterations + 1)


def _step_matrix(problem: _Problem, delta: NDArray[np.float64], settings: Settings) -> Matrix:
    """The increment warp W(dp) in the level's pixels."""
    terms = problem.terms
    return terms.to_pixels @ settings.model.step(delta[: settings.model.n_params]) @ terms.from_pixels


def _is_sane(estimate: Estimate) -> bool:
    return bool(np.isfinite(estimate.matrix).all() and np.isfinite(estimate.bias) and estimate.gain > 0)


def _trim(
    problem: _Problem, residual: Image, gradient: NDArray[np.float64]
) -> tuple[_Problem, NDArray[np.float64]] | None:
    """Drop pixels whose residual is an outlier (a flaw, seed §2.4); None if none.

    The Hessian and the gradient ``J^T r`` are downdated by the dropped columns alone, so trimming costs one
    pass over the residual, not a new solve.
    """
    col0, col1 = problem.region[2:]
    box = problem.buffer[:, col0:col1]
    # About _SIGMA_SAMPLES residuals on a regular grid over the box.
    stride = max(1, int(np.sqrt(box.size / _SIGMA_SAMPLES)))
    probe = box[::stride, ::stride]
    if problem.weights is not None:
        probe = probe[problem.weights[::stride, ::stride] > 0]
    if probe.size == 0:
        return None
    centre = float(np.median(probe))
    sigma = _MAD_TO_SIGMA * float(np.median(np.abs(probe - centre)))
    if sigma <= 0:
        return None
    spread = _TRIM_SIGMAS * sigma
    inside = cv2.inRange(box, centre - spread, centre + spread, dst=scratch("inside", box.shape, np.uint8))
    outliers = np.equal(inside, 0, out=scratch("outliers", box.shape, np.bool_))
    if problem.weights is not None:
        outliers &= problem.weights > 0
    index = _band_index(flat_nonzero(outliers), col1 - col0, col0, problem.terms.width)
    if index.size == 0:
        return None
    dropped = problem.jacobian[:, index]
    hessian = problem.hessian - np.asarray(dropped @ dropped.T, dtype=np.float64)
    inverse = _inverse(hessian)
    if inverse is None:
        return None
    gradient = gradient - np.asarray(dropped @ residual[index], dtype=np.float64)
    trimmed = replace(
        problem, hessian=hessian, inverse_hessian=inverse, trimmed=index, n_used=problem.n_used - index.size
    )
    return trimmed, gradient


def _solve(
    problem: _Problem, gradient: NDArray[np.float64], settings: Settings
) -> tuple[NDArray[np.float64], float]:
    """The Gauss-Newton update ``H^-1 J^T r`` and how far, in pixels, it moves the region's corners."""
    delta = problem.inverse_hessian @ gradient
    if settings.model.n_params == 2:
        # A translation moves every corner alike: no need to map them (this runs every iteration).
        return delta, float(np.hypot(delta[0], delta[1]) * problem.terms.to_pixels[0, 0])
    return delta, corner_motion_px(np.eye(3), _step_matrix(problem, delta, settings), problem.region)


def _iterate(
    level: Level, terms: Terms, problem: _Problem, estimate: Estimate, settings: Settings
) -> tuple[Estimate, _Problem, Image]:
    """Gauss-Newton steps on one level; returns the estimate, the final problem and the last residual.

    On the finest level, once a step falls below ``_TRIM_AFTER_STEP_PX``, its residual is used to trim flaws
    (seed §2.4: a new flaw must not pull the registration) and the step is recomputed from the trimmed sums,
    with no new resampling; the level ends after trimming when a step, or the motion its contraction
    predicts is still to come, is below the tolerance. Coarse levels
    only have to land the next one inside its basin, which a flaw does not prevent: they do not trim.
    """
    # Coarse levels' accuracy is limited by aliasing anyway: their tolerance grows with the level so that
    # the work goes to full resolution.
    tolerance_px = settings.tolerance_px * _COARSE_TOLERANCE_GROWTH**level.index
    trimmed, previous_px = level.index > 0, np.inf
    residual = _residual(level, problem, estimate, settings.photometric)
    for _ in range(settings.max_iterations):
        if settings.deadline is not None and time.perf_counter() > settings.deadline:
            return replace(estimate, reason="deadline"), problem, residual
        gradient = np.asarray(problem.jacobian @ residual, dtype=np.float64)
        delta, moved_px = _solve(problem, gradient, settings)
        if moved_px < _TRIM_AFTER_STEP_PX and not trimmed:
            trimmed = True
            cleaned = _trim(problem, residual, gradient)
            if cleaned is not None:
                problem, gradient = cleaned
                delta, moved_px = _solve(problem, gradient, settings)
        previous, estimate = estimate, _update(estimate, problem, delta, settings)
        if not _is_sane(estimate):
            return replace(previous, iterations=estimate.iterations, reason="diverged"), problem, residual
        contraction = moved_px / previous_px if np.isfinite(previous_px) else 1.0
        to_come_px = np.inf if contraction >= _MAX_CONTRACTION else moved_px * contraction / (1 - contraction)
        if trimmed and min(moved_px, to_come_px) < tolerance_px:
            return replace(estimate, reason="converged"), problem, residual
        previous_px = moved_px
        if corner_motion_px(problem.chosen_at, estimate.matrix, problem.region) > _MARGIN_PX / 2:
            # Moved out of the margin the region was chosen with: choose it again before sampling outside.
            rebuilt = _build(level, terms, estimate.matrix)
            if rebuilt is None:
                return replace(estimate, reason="diverged"), problem, residual
            problem, trimmed = rebuilt, level.index > 0
        residual = _residual(level, problem, estimate, settings.photometric)
    return replace(estimate, reason="max_iterations"), problem, residual


def _with_statistics(estimate: Estimate, problem: _Problem, residual: Image, level: Level) -> Estimate:
    """Residual RMS and the translation's std from sigma^2 H^-1 (the detector's registration noise, §2.4)."""
    if problem.trimmed is not None:
        residual[problem.trimmed] = 0.0
    rss = float(np.dot(residual, residual))
    dof = max(problem.n_used - problem.hessian.shape[0], 1)
    variance = rss / dof * np.diag(problem.inverse_hessian)[:2]
    # Translation parameters are in units of half a side: back to full-resolution pixels. The estimate uses
    # only the rows used (every other one on large levels), so sigma^2 H^-1 over them is its std.
    std_px = np.sqrt(variance) * problem.terms.to_pixels[0, 0] * 2.0**level.index
    rms = np.sqrt(rss / max(problem.n_used, 1)) * estimate.gain
    return replace(estimate, residual_rms=float(rms), shift_std_px=(float(std_px[0]), float(std_px[1])))


def solve_level(level: Level, estimate: Estimate, terms: Sequence[Terms], settings: Settings) -> Estimate:
    """Refine `estimate` (in the level's pixels) on one level, trimming flaws once it has settled.

    Parameters
    ----------
    level : Level
        Smoothed reference and inspection of shape (M, N) and (P, Q), and the level's mask.
    estimate : Estimate
        Start; its matrix is in this level's pixels.
    terms : sequence of Terms
        The reference's precomputed terms per level, finest first (``terms[level.index]`` is used).
    settings : Settings
        Model, photometric flag, iteration budget, tolerance and deadline.

    Returns
    -------
    Estimate
        With ``reason`` of this level, iterations accumulated, residual RMS and translation std.
    """
    level_terms = terms[level.index]
    problem = _build(level, level_terms, estimate.matrix)
    if problem is None:
        return replace(estimate, reason="diverged")
    estimate, problem, residual = _iterate(level, level_terms, problem, estimate, settings)
    return _with_statistics(estimate, problem, residual, level)
