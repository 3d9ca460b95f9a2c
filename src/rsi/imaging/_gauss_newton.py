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
_TRIM_SIGMAS = 3.0
_MAD_TO_SIGMA = 1.4826
_SIGMA_SAMPLES = 1 << 14
_MAX_CONDITION = 1e12
_MIN_PIXELS_PER_UNKNOWN = 8


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

    ``jacobian`` has shape (K, R) over the R pixels of ``region`` with zero columns where a pixel is not
    used (outside the mask or trimmed), so ``jacobian @ residual`` sums only over used pixels.
    """

    region: Region
    template: Image
    jacobian: NDArray[np.float32]
    inverse_hessian: NDArray[np.float64]
    hessian: NDArray[np.float64]
    weights: NDArray[np.float32] | None
    n_used: int
    chosen_at: Matrix
    to_pixels: Matrix
    from_pixels: Matrix


def _descent_images(level: Level, region: Region, settings: Settings, from_pixels: Matrix) -> list[Image]:
    row0, row1, col0, col1 = region
    scale = 1.0 / from_pixels[0, 0]
    # The region keeps a one-pixel border inside the reference, so central differences need no padding.
    patch = level.reference[row0 - 1 : row1 + 1, col0 - 1 : col1 + 1]
    gu = cv2.Sobel(patch, cv2.CV_32F, 1, 0, ksize=1, scale=0.5 * scale)[1:-1, 1:-1]
    gv = cv2.Sobel(patch, cv2.CV_32F, 0, 1, ksize=1, scale=0.5 * scale)[1:-1, 1:-1]
    u = (np.arange(col0, col1) * from_pixels[0, 0] + from_pixels[0, 2]).astype(np.float32)[None, :]
    v = (np.arange(row0, row1) * from_pixels[1, 1] + from_pixels[1, 2]).astype(np.float32)[:, None]
    images = settings.model.descent(gu, gv, u, v)
    if settings.photometric:
        template = level.reference[row0:row1, col0:col1]
        images += [template, np.ones_like(template)]
    return images


def _inverse(hessian: NDArray[np.float64]) -> NDArray[np.float64] | None:
    diagonal = np.diag(hessian)
    if not np.all(diagonal > 0):
        return None
    scale = 1.0 / np.sqrt(diagonal)
    balanced = hessian * np.outer(scale, scale)
    if np.linalg.cond(balanced) > _MAX_CONDITION:
        return None
    return np.asarray(np.linalg.inv(balanced) * np.outer(scale, scale), dtype=np.float64)


def _build(level: Level, matrix: Matrix, settings: Settings) -> _Problem | None:
    """Choose the used pixels for this level and precompute the Jacobian and Hessian; None if degenerate."""
    region, inside = valid_region(matrix, level.reference.shape, level.inspection.shape, _MARGIN_PX)
    row0, row1, col0, col1 = region
    if row1 - row0 < 1 or col1 - col0 < 1:
        return None
    if level.mask is not None:
        user = level.mask[row0:row1, col0:col1]
        inside = user if inside is None else inside & user
    from_pixels = normaliser(level.reference.shape)
    images = _descent_images(level, region, settings, from_pixels)
    jacobian = np.empty((len(images), (row1 - row0) * (col1 - col0)), dtype=np.float32)
    for row, image in zip(jacobian, images, strict=True):
        row.reshape(row1 - row0, col1 - col0)[...] = image
    weights = None if inside is None else inside.ravel().astype(np.float32)
    if weights is not None:
        jacobian *= weights
    n_used = jacobian.shape[1] if weights is None else int(np.count_nonzero(weights))
    hessian = np.asarray(jacobian @ jacobian.T, dtype=np.float64)
    inverse = _inverse(hessian)
    if inverse is None or n_used < _MIN_PIXELS_PER_UNKNOWN * len(images):
        return None
    return _Problem(
        region=region,
        template=np.ascontiguousarray(level.reference[row0:row1, col0:col1]),
        jacobian=jacobian,
        inverse_hessian=inverse,
        hessian=hessian,
        weights=weights,
        n_used=n_used,
        chosen_at=matrix,
        to_pixels=np.linalg.inv(from_pixels),
        from_pixels=from_pixels,
    )


def _residual(level: Level, problem: _Problem, estimate: Estimate, photometric: bool) -> Image:
    """Normalised residual ``(I(W(x)) - bias) / gain - T(x)`` over the region, shape (R,)."""
    warped = sample(level.inspection, estimate.matrix, problem.region)
    if photometric:
        gain = estimate.gain
        cv2.addWeighted(warped, 1.0 / gain, problem.template, -1.0, -estimate.bias / gain, dst=warped)
    else:
        cv2.subtract(warped, problem.template, dst=warped)
    return warped.ravel()


def _update(estimate: Estimate, problem: _Problem, delta: NDArray[np.float64], settings: Settings) -> Estimate:
    """Compose the inverse of the increment into the warp, and the photometric step into gain and bias."""
    n_params = settings.model.n_params
    step = problem.to_pixels @ settings.model.step(delta[:n_params]) @ problem.from_pixels
    matrix = estimate.matrix @ np.linalg.inv(step)
    matrix /= matrix[2, 2]
    gain, bias = estimate.gain, estimate.bias
    if settings.photometric:
        # I(W) = gain (1 + dgain) T + gain dbias + bias, from N ~= (1 + dgain) T + dbias.
        gain, bias = gain * (1.0 + delta[n_params]), bias + gain * delta[n_params + 1]
    return replace(estimate, matrix=matrix, gain=gain, bias=bias, iterations=estimate.iterations + 1)


def _is_sane(estimate: Estimate) -> bool:
    return bool(np.isfinite(estimate.matrix).all() and np.isfinite(estimate.bias) and estimate.gain > 0)


def _iterate(
    level: Level, problem: _Problem, estimate: Estimate, settings: Settings, budget: int
) -> tuple[Estimate, _Problem]:
    """Gauss-Newton steps until the update is below tolerance, the budget or the deadline runs out."""
    identity = np.eye(3)
    for _ in range(budget):
        if settings.deadline is not None and time.perf_counter() > settings.deadline:
            return replace(estimate, reason="deadline"), problem
        residual = _residual(level, problem, estimate, settings.photometric)
        delta = problem.inverse_hessian @ (problem.jacobian @ residual).astype(np.float64)
        previous, estimate = estimate, _update(estimate, problem, delta, settings)
        if not _is_sane(estimate):
            return replace(previous, iterations=estimate.iterations, reason="diverged"), problem
        if corner_motion_px(problem.chosen_at, estimate.matrix, problem.region) > _MARGIN_PX / 2:
            # Moved out of the margin the region was chosen with: choose it again before sampling outside.
            rebuilt = _build(level, estimate.matrix, settings)
            if rebuilt is None:
                return replace(estimate, reason="diverged"), problem
            problem = rebuilt
        step = problem.to_pixels @ settings.model.step(delta[: settings.model.n_params]) @ problem.from_pixels
        moved = corner_motion_px(identity, step, problem.region)
        if moved < settings.tolerance_px:
            return replace(estimate, reason="converged"), problem
    return replace(estimate, reason="max_iterations"), problem


def _trim(problem: _Problem, residual: Image) -> _Problem | None:
    """Drop pixels whose residual is an outlier (a flaw, seed §2.4) and downdate the Hessian; None if none."""
    used = residual if problem.weights is None else residual[problem.weights > 0]
    probe = used[:: max(1, used.size // _SIGMA_SAMPLES)]
    centre = float(np.median(probe))
    sigma = _MAD_TO_SIGMA * float(np.median(np.abs(probe - centre)))
    outlier = np.abs(residual - centre) > _TRIM_SIGMAS * sigma
    if problem.weights is not None:
        outlier &= problem.weights > 0
    index = np.flatnonzero(outlier)
    if sigma <= 0 or index.size == 0:
        return None
    dropped = problem.jacobian[:, index]
    hessian = problem.hessian - np.asarray(dropped @ dropped.T, dtype=np.float64)
    inverse = _inverse(hessian)
    if inverse is None:
        return None
    jacobian = problem.jacobian.copy()
    jacobian[:, index] = 0.0
    weights = np.ones(residual.size, np.float32) if problem.weights is None else problem.weights.copy()
    weights[index] = 0.0
    return replace(
        problem,
        jacobian=jacobian,
        hessian=hessian,
        inverse_hessian=inverse,
        weights=weights,
        n_used=problem.n_used - index.size,
    )


def _with_statistics(estimate: Estimate, problem: _Problem, residual: Image, level: Level) -> Estimate:
    """Residual RMS and the translation's std from sigma^2 H^-1 (the detector's registration noise, §2.4)."""
    weighted = residual if problem.weights is None else residual * problem.weights
    rss = float(np.dot(weighted.astype(np.float64), residual.astype(np.float64)))
    dof = max(problem.n_used - problem.hessian.shape[0], 1)
    variance = rss / dof * np.diag(problem.inverse_hessian)[:2]
    # Translation parameters are in units of half a side: back to full-resolution pixels.
    std_px = np.sqrt(variance) * problem.to_pixels[0, 0] * 2.0**level.index
    rms = np.sqrt(rss / max(problem.n_used, 1)) * (estimate.gain if np.isfinite(estimate.gain) else 1.0)
    return replace(estimate, residual_rms=float(rms), shift_std_px=(float(std_px[0]), float(std_px[1])))


def solve_level(level: Level, estimate: Estimate, settings: Settings) -> Estimate:
    """Refine `estimate` (in the level's pixels) on one level; trim flaws after convergence and refit.

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
    start = estimate.iterations
    estimate, problem = _iterate(level, problem, estimate, settings, settings.max_iterations)
    residual = _residual(level, problem, estimate, settings.photometric)
    if estimate.reason == "converged":
        trimmed = _trim(problem, residual)
        if trimmed is not None:
            budget = settings.max_iterations - (estimate.iterations - start)
            estimate, problem = _iterate(level, trimmed, estimate, settings, budget)
            residual = _residual(level, problem, estimate, settings.photometric)
    return _with_statistics(estimate, problem, residual, level)
