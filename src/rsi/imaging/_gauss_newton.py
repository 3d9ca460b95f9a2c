"""Inverse-compositional Gauss-Newton registration of one pyramid level, with gain, bias and trimming.

Seed §2.3: the residual sum of squares between the inspection and the transformed reference is minimised by
Gauss-Newton, and "terms involving the Jacobian ... can be pre-computed". The inverse-compositional form
(Baker & Matthews 2004, doi:10.1023/B:VISI.0000011205.11775.fd) makes that true for every warp model: the
steepest-descent images and the Hessian are taken on the reference once per level, and each iteration
costs one resampling of the inspection, one subtraction and one matrix-vector product.

Gain and bias are fitted in the same solve without breaking the fixed Hessian by normalising the warped
inspection instead of scaling the reference: with ``N = (I(W(x)) - bias) / gain`` the linearised residual
``N - T ~= grad(T) dW/dp dp + dgain T + dbias`` has a Jacobian that depends on the reference only.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, replace

import cv2
import numpy as np
from numpy.typing import NDArray

from rsi.imaging._pyramid import Estimate, Level
from rsi.imaging._warps import (
    Image,
    Matrix,
    Region,
    WarpModel,
    corner_motion_px,
    normaliser,
    sample,
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
class _Problem:
    """The reference-side terms of one level, precomputed once (seed §2.3).

    The used pixels are the rows ``row0, row0 + row_step, ...`` and the columns ``col0 .. col1 - 1`` of
    `region`. ``jacobian`` has shape (K, R) over them, R = rows used x columns, with zero columns where a
    pixel is not used (outside the mask or the valid polygon, or trimmed), so ``jacobian @ residual`` sums
    over used pixels only; ``weights`` of shape (R,) is 0 outside the mask or polygon and 1 elsewhere, or
    None when there is neither; ``trimmed`` indexes the pixels trimmed as flaws. ``buffer`` of shape
    (rows used, columns) receives each residual.
    """

    region: Region
    row_step: int
    jacobian: NDArray[np.float32]
    hessian: NDArray[np.float64]
    inverse_hessian: NDArray[np.float64]
    weights: NDArray[np.float32] | None
    trimmed: NDArray[np.intp] | None
    n_used: int
    chosen_at: Matrix
    to_pixels: Matrix
    from_pixels: Matrix
    buffer: Image


def _jacobian(
    level: Level, region: Region, row_step: int, settings: Settings, from_pixels: Matrix
) -> NDArray[np.float32]:
    """Steepest-descent images on the used rows of `region`, shape (K, rows used * columns)."""
    reference, n_params = level.reference, settings.model.n_params
    row0, row1, col0, col1 = region
    rows = slice(row0, row1, row_step)
    jacobian = np.empty(
        (n_params + 2 * settings.photometric, len(range(row0, row1, row_step)), col1 - col0), np.float32
    )
    scale = 0.5 / from_pixels[0, 0]
    # Central differences in normalised units, on the used pixels only; the region keeps off the border.
    right, left = reference[rows, col0 + 1 : col1 + 1], reference[rows, col0 - 1 : col1 - 1]
    gu = np.asarray(cv2.addWeighted(right, scale, left, -scale, 0.0, dst=jacobian[0]), np.float32)
    below = reference[row0 + 1 : row1 + 1 : row_step, col0:col1]
    above = reference[row0 - 1 : row1 - 1 : row_step, col0:col1]
    gv = np.asarray(cv2.addWeighted(below, scale, above, -scale, 0.0, dst=jacobian[1]), np.float32)
    if n_params > 2:
        u = (np.arange(col0, col1) * from_pixels[0, 0] + from_pixels[0, 2]).astype(np.float32)
        v = (np.arange(row0, row1, row_step) * from_pixels[1, 1] + from_pixels[1, 2]).astype(np.float32)
        jacobian[2:n_params] = settings.model.descent(gu, gv, u[None, :], v[:, None])[2:]
    if settings.photometric:
        jacobian[n_params] = reference[rows, col0:col1]
        jacobian[n_params + 1] = 1.0
    return jacobian.reshape(jacobian.shape[0], -1)


def _gram(jacobian: NDArray[np.float32]) -> NDArray[np.float64]:
    # Row-pair dot products run at memory speed; a (K, R) @ (R, K) product is 2-3x slower here.
    size = jacobian.shape[0]
    gram = np.empty((size, size))
    for i in range(size):
        for j in range(i, size):
            gram[i, j] = gram[j, i] = np.dot(jacobian[i], jacobian[j])
    return gram


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


def _row_step(level: Level) -> int:
    # With this many rows the accuracy is limited by interpolation bias, not by noise (seed §2.3): every
    # other row carries the same information at half the cost.
    return _ROW_STEP if level.reference.shape[0] >= _ROW_STEP_MIN_ROWS else 1


def _build(level: Level, matrix: Matrix, settings: Settings) -> _Problem | None:
    """Choose the used pixels for this level and precompute the Jacobian and Hessian; None if degenerate."""
    region, inside = valid_region(matrix, level.reference.shape, level.inspection.shape, _MARGIN_PX)
    row0, row1, col0, col1 = region
    if row1 <= row0 or col1 <= col0:
        return None
    if level.mask is not None:
        user = level.mask[row0:row1, col0:col1]
        inside = user if inside is None else inside & user
    row_step = _row_step(level)
    from_pixels = normaliser(level.reference.shape)
    jacobian = _jacobian(level, region, row_step, settings, from_pixels)
    weights = None
    n_used = jacobian.shape[1]
    if inside is not None:
        weights = np.ascontiguousarray(inside[::row_step], dtype=np.float32).ravel()
        jacobian *= weights
        n_used = int(np.count_nonzero(weights))
    hessian = _gram(jacobian)
    inverse = _inverse(hessian)
    if inverse is None or n_used < _MIN_PIXELS_PER_UNKNOWN * jacobian.shape[0]:
        return None
    return _Problem(
        region=region,
        row_step=row_step,
        jacobian=jacobian,
        hessian=hessian,
        inverse_hessian=inverse,
        weights=weights,
        trimmed=None,
        n_used=n_used,
        chosen_at=matrix,
        to_pixels=np.asarray(np.linalg.inv(from_pixels), dtype=np.float64),
        from_pixels=from_pixels,
        buffer=np.empty((len(range(row0, row1, row_step)), col1 - col0), dtype=np.float32),
    )


def _residual(level: Level, problem: _Problem, estimate: Estimate, photometric: bool) -> Image:
    """Normalised residual ``(I(W(x)) - bias) / gain - T(x)`` over the used pixels, shape (R,)."""
    row0, row1, col0, col1 = problem.region
    template = level.reference[row0 : row1 : problem.row_step, col0:col1]
    warped = sample(level.inspection, estimate.matrix, problem.region, problem.row_step, out=problem.buffer)
    if photometric:
        gain = estimate.gain
        cv2.addWeighted(warped, 1.0 / gain, template, -1.0, -estimate.bias / gain, dst=warped)
    else:
        cv2.subtract(warped, template, dst=warped)
    return warped.ravel()


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
    return problem.to_pixels @ settings.model.step(delta[: settings.model.n_params]) @ problem.from_pixels


def _is_sane(estimate: Estimate) -> bool:
    return bool(np.isfinite(estimate.matrix).all() and np.isfinite(estimate.bias) and estimate.gain > 0)


def _trim(
    problem: _Problem, residual: Image, gradient: NDArray[np.float64]
) -> tuple[_Problem, NDArray[np.float64]] | None:
    """Drop pixels whose residual is an outlier (a flaw, seed §2.4); None if none.

    The Hessian and the gradient ``J^T r`` are downdated by the dropped columns alone, so trimming costs one
    pass over the residual, not a new solve.
    """
    stride = max(1, residual.size // _SIGMA_SAMPLES)
    probe = residual[::stride]
    if problem.weights is not None:
        probe = probe[problem.weights[::stride] > 0]
    if probe.size == 0:
        return None
    centre = float(np.median(probe))
    sigma = _MAD_TO_SIGMA * float(np.median(np.abs(probe - centre)))
    if sigma <= 0:
        return None
    spread = _TRIM_SIGMAS * sigma
    index = np.flatnonzero(cv2.inRange(residual, centre - spread, centre + spread) == 0)
    if problem.weights is not None:
        index = index[problem.weights[index] > 0]
    if index.size == 0:
        return None
    dropped = problem.jacobian[:, index]
    hessian = problem.hessian - np.asarray(dropped @ dropped.T, dtype=np.float64)
    inverse = _inverse(hessian)
    if inverse is None:
        return None
    gradient = gradient - np.asarray(dropped @ residual[index], dtype=np.float64)
    # The level's Jacobian is owned by this solve: zero the trimmed columns in place rather than copy it.
    problem.jacobian[:, index] = 0.0
    trimmed = replace(
        problem, hessian=hessian, inverse_hessian=inverse, trimmed=index, n_used=problem.n_used - index.size
    )
    return trimmed, gradient


def _solve(
    problem: _Problem, gradient: NDArray[np.float64], settings: Settings
) -> tuple[NDArray[np.float64], float]:
    """The Gauss-Newton update ``H^-1 J^T r`` and how far, in pixels, it moves the region's corners."""
    delta = problem.inverse_hessian @ gradient
    return delta, corner_motion_px(np.eye(3), _step_matrix(problem, delta, settings), problem.region)


def _iterate(
    level: Level, problem: _Problem, estimate: Estimate, settings: Settings
) -> tuple[Estimate, _Problem, Image]:
    """Gauss-Newton steps on one level; returns the estimate, the final problem and the last residual.

    On the finest level, when a step falls below the tolerance, its residual is used to trim flaws (seed
    §2.4: a new flaw must not pull the registration) and the step is recomputed from the trimmed sums, with
    no new resampling; the level ends when a step after trimming is below the tolerance too. Coarse levels
    only have to land the next one inside its basin, which a flaw does not prevent: they do not trim.
    """
    # Coarse levels' accuracy is limited by aliasing anyway: their tolerance grows with the level so that
    # the work goes to full resolution.
    tolerance_px = settings.tolerance_px * _COARSE_TOLERANCE_GROWTH**level.index
    trimmed = level.index > 0
    residual = _residual(level, problem, estimate, settings.photometric)
    for _ in range(settings.max_iterations):
        if settings.deadline is not None and time.perf_counter() > settings.deadline:
            return replace(estimate, reason="deadline"), problem, residual
        gradient = np.asarray(problem.jacobian @ residual, dtype=np.float64)
        delta, moved_px = _solve(problem, gradient, settings)
        if moved_px < tolerance_px and not trimmed:
            trimmed = True
            cleaned = _trim(problem, residual, gradient)
            if cleaned is not None:
                problem, gradient = cleaned
                delta, moved_px = _solve(problem, gradient, settings)
        previous, estimate = estimate, _update(estimate, problem, delta, settings)
        if not _is_sane(estimate):
            return replace(previous, iterations=estimate.iterations, reason="diverged"), problem, residual
        if moved_px < tolerance_px and trimmed:
            return replace(estimate, reason="converged"), problem, residual
        if corner_motion_px(problem.chosen_at, estimate.matrix, problem.region) > _MARGIN_PX / 2:
            # Moved out of the margin the region was chosen with: choose it again before sampling outside.
            rebuilt = _build(level, estimate.matrix, settings)
            if rebuilt is None:
                return replace(estimate, reason="diverged"), problem, residual
            problem, trimmed = rebuilt, level.index > 0
        residual = _residual(level, problem, estimate, settings.photometric)
    return replace(estimate, reason="max_iterations"), problem, residual


def _with_statistics(estimate: Estimate, problem: _Problem, residual: Image, level: Level) -> Estimate:
    """Residual RMS and the translation's std from sigma^2 H^-1 (the detector's registration noise, §2.4)."""
    if problem.weights is not None:
        residual *= problem.weights
    if problem.trimmed is not None:
        residual[problem.trimmed] = 0.0
    rss = float(np.dot(residual, residual))
    dof = max(problem.n_used - problem.hessian.shape[0], 1)
    variance = rss / dof * np.diag(problem.inverse_hessian)[:2]
    # Translation parameters are in units of half a side: back to full-resolution pixels. The estimate uses
    # only the rows used (every other one on large levels), so sigma^2 H^-1 over them is its std.
    std_px = np.sqrt(variance) * problem.to_pixels[0, 0] * 2.0**level.index
    rms = np.sqrt(rss / max(problem.n_used, 1)) * estimate.gain
    return replace(estimate, residual_rms=float(rms), shift_std_px=(float(std_px[0]), float(std_px[1])))


def solve_level(level: Level, estimate: Estimate, settings: Settings) -> Estimate:
    """Refine `estimate` (in the level's pixels) on one level, trimming flaws once it has settled.

    Parameters
    ----------
    level : Level
        Smoothed reference and inspection of shape (M, N) and (P, Q), and the level's mask.
    estimate : Estimate
        Start; its matrix is in this level's pixels.
    settings : Settings
        Model, photometric flag, iteration budget, tolerance and deadline.

    Returns
    -------
    Estimate
        With ``reason`` of this level, iterations accumulated, residual RMS and translation std.
    """
    problem = _build(level, estimate.matrix, settings)
    if problem is None:
        return replace(estimate, reason="diverged")
    estimate, problem, residual = _iterate(level, problem, estimate, settings)
    return _with_statistics(estimate, problem, residual, level)
