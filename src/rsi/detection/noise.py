"""Noise model of the difference image ``d = inspection - (gain * warped_reference + bias)`` (seed §2.4).

The seed treats every error source as extra noise on ``d``: sensor noise of both images, the noise
reduction and correlation caused by resampling the reference, residual mis-registration (seed §2.3) and
ambient-light interpolation (seed §2.2). This module holds those pieces; ``docs/detection.md`` derives them.
"""

from __future__ import annotations

import functools
import math
from typing import Any

import cv2
import numpy as np
from numpy.typing import NDArray
from scipy import optimize, signal

from rsi import _validate as v
from rsi.errors import InputError

FloatArray = NDArray[np.float64]
Float32Array = NDArray[np.float32]

MAD_TO_SIGMA = 1.4826  # 1 / Phi^-1(3/4): MAD of N(0, s^2) is s / 1.4826
_ROBUST_SAMPLES = 50_000  # subsample size for robust scales: relative error ~ 1.17 / sqrt(n) ~ 0.5 %
_FIT_SAMPLES = 16_000
_FIT_BINS = 16
_FRACTION_GRID = 8  # fractions averaged for warps whose sub-pixel phase varies over the image


def _pair(value: object, name: str, *, high: float, unknown: bool = False) -> tuple[float, float]:
    """Two numbers in [0, `high`] (an x and a y; NaN where `unknown` allows it), or raise naming `name`."""
    pair = v.as_float_array(value, name)
    known = pair if not unknown else pair[~np.isnan(pair)]
    if pair.shape != (2,) or np.isnan(known).any() or not ((known >= 0.0) & (known <= high)).all():
        also = " or NaN (unknown)" if unknown else ""
        raise InputError(f"{name} must be two numbers (x, y) in [0, {high:g}]{also}; got {value!r:.60}.")
    return float(pair[0]), float(pair[1])


def _weights(weights: object) -> FloatArray:
    """A non-zero, finite 2-D filter scaled to a largest magnitude of 1 (the factors are scale-free)."""
    kernel = v.as_float_array(weights, "weights")
    if kernel.ndim != 2 or kernel.size == 0 or not np.isfinite(kernel).all() or not kernel.any():
        raise InputError(
            f"weights must be a finite, non-zero 2-D flaw model; got shape {kernel.shape}. "
            "Pass rsi.detection.flaw_models.flaw_model(...)."
        )
    return np.asarray(kernel / np.abs(kernel).max(), dtype=np.float64)


def _plane(image: object, name: str) -> NDArray[np.floating[Any]]:
    """A 2-D image (NaN allowed where invalid), float kept without a copy."""
    return v.as_image(image, name, allow_nan=True)


def bilinear_weights(fraction_xy: tuple[float, float]) -> FloatArray:
    """Return the 2x2 bilinear interpolation kernel ``h`` for sub-pixel fractions ``(fx, fy)``.

    Returns
    -------
    ndarray of shape (2, 2)
        ``[[(1-fx)(1-fy), fx(1-fy)], [(1-fx)fy, fx fy]]`` (rows = y).
    """
    fx, fy = _pair(fraction_xy, "fraction_xy", high=1.0)
    return np.outer([1.0 - fy, fy], [1.0 - fx, fx])


def interpolation_factor(weights: FloatArray, fraction_xy: tuple[float, float]) -> float:
    """Variance factor of bilinearly resampled white noise seen through the filter ``weights``.

    Parameters
    ----------
    weights : ndarray of shape (K, L)
        Flaw model (matched filter) ``w``.
    fraction_xy : tuple of float
        Sub-pixel fractions ``(fx, fy)`` of the resampling, in [0, 1).

    Returns
    -------
    float
        ``||w * h||^2 / ||w||^2`` with ``h`` the bilinear kernel: white noise of variance ``v`` becomes, after
        resampling, noise whose ``w``-filtered variance equals that of white noise of variance ``v`` times
        this factor. For one pixel it is ``((1-fx)^2 + fx^2)((1-fy)^2 + fy^2)``.
    """
    kernel = _weights(weights)
    smeared = signal.convolve2d(kernel, bilinear_weights(fraction_xy), mode="full")
    return float(np.sum(smeared**2) / np.sum(kernel**2))


def mean_interpolation_factor(weights: FloatArray) -> float:
    """:func:`interpolation_factor` averaged over uniformly distributed sub-pixel fractions.

    Used for warps other than a translation, whose fractions sweep [0, 1) across the image.
    """
    kernel = _weights(weights)
    # A pure function of the kernel, asked for on every detect call with the same few kernels: 64
    # convolutions were 3 ms of a 640 x 640 detection.
    return _mean_factor(kernel.shape, kernel.tobytes())


@functools.lru_cache(maxsize=64)
def _mean_factor(shape: tuple[int, ...], kernel_bytes: bytes) -> float:
    kernel = np.frombuffer(kernel_bytes, dtype=np.float64).reshape(shape)
    fractions = (np.arange(_FRACTION_GRID) + 0.5) / _FRACTION_GRID
    return float(np.mean([interpolation_factor(kernel, (fx, fy)) for fx in fractions for fy in fractions]))


def _median(values: NDArray[Any]) -> float:
    """Median by selection, O(n), instead of a full sort."""
    middle = values.size // 2
    return float(np.partition(values, middle)[middle])


def _subsample(values: NDArray[Any], valid: NDArray[np.bool_], samples: int) -> NDArray[Any]:
    stride = max(1, int(np.sqrt(values.size / samples)))
    picked: NDArray[Any] = values[::stride, ::stride][valid[::stride, ::stride]]
    return picked


def robust_scale(values: NDArray[Any], valid: NDArray[np.bool_]) -> float:
    """Return ``1.4826 * MAD`` of the valid values, from a regular subsample of about 50 000 pixels.

    Returns 0 when fewer than two valid pixels are sampled.
    """
    plane = _plane(values, "values")
    sample = _subsample(plane, v.as_mask(valid, "valid", plane.shape), _ROBUST_SAMPLES)
    if sample.size < 2:
        return 0.0
    return MAD_TO_SIGMA * _median(np.abs(sample - _median(sample)))


def fit_sensor_variance(
    difference: Float32Array,
    predicted: Float32Array,
    valid: NDArray[np.bool_],
    *,
    gain: float,
    bias: float,
    factor: float,
) -> tuple[float, float]:
    """Fit the per-image sensor variance ``v(I) = a + b I`` from the difference image.

    Parameters
    ----------
    difference, predicted : ndarray of shape (M, N), float32
        ``d`` and ``gain * warped_reference + bias``.
    valid : ndarray of shape (M, N), bool
        Pixels where ``d`` is defined.
    gain, bias : float
        Photometric map ``inspection ~ gain * reference + bias``.
    factor : float
        Single-pixel interpolation factor of the reference noise.

    Returns
    -------
    tuple of float
        ``(a, b)``, both >= 0: read noise (intensity units squared) and shot-noise slope.

    Notes
    -----
    Both images come from the same camera, so ``var(d) = v(I_insp) + gain^2 F v(I_ref)`` with
    ``I_insp = predicted`` and ``I_ref = (predicted - bias) / gain``. On quantile bins of ``predicted``
    the robust variance ``(1.4826 MAD)^2`` of ``d`` (insensitive to flaws and edges) is regressed by
    non-negative least squares on ``a (1 + gain^2 F) + b (I_insp + gain^2 F I_ref)``.
    """
    difference_plane, predicted_plane = _plane(difference, "difference"), _plane(predicted, "predicted")
    v.same_shape(difference_plane, predicted_plane, ("difference", "predicted"))
    mask = v.as_mask(valid, "valid", difference_plane.shape)
    gain = v.finite_number(gain, "gain")
    if gain == 0.0:
        raise InputError("gain must be non-zero (inspection ~ gain * reference + bias); got 0.")
    bias = v.finite_number(bias, "bias")
    factor = v.in_range(factor, "factor", low=0.0)
    order_key = _subsample(predicted_plane, mask, _FIT_SAMPLES)
    values = _subsample(difference_plane, mask, _FIT_SAMPLES)
    order = np.argsort(order_key)
    rows = []
    targets = []
    for chunk in np.array_split(order, _FIT_BINS):
        if chunk.size < 8:
            continue
        residual = values[chunk]
        intensity = _median(order_key[chunk])
        reference_intensity = (intensity - bias) / gain
        rows.append([1.0 + gain * gain * factor, intensity + gain * gain * factor * reference_intensity])
        targets.append((MAD_TO_SIGMA * _median(np.abs(residual - _median(residual)))) ** 2)
    if not rows:
        return 0.0, 0.0
    coefficients, _ = optimize.nnls(np.asarray(rows), np.asarray(targets))
    return float(coefficients[0]), float(coefficients[1])


def _coefficients(value: object) -> tuple[float, float]:
    pair = v.as_float_array(value, "coefficients")
    if pair.shape != (2,) or not np.isfinite(pair).all() or (np.abs(pair) > np.finfo(np.float32).max).any():
        raise InputError(
            f"coefficients must be (a, b) of v(I) = a + b I, two finite float32 numbers; got {value!r:.60}."
        )
    return float(pair[0]), float(pair[1])


def affine_variance(intensity: Float32Array, coefficients: tuple[float, float]) -> Float32Array:
    """Evaluate ``v(I) = a + b I`` (floored at 0 for intensities below zero)."""
    a, b = _coefficients(coefficients)
    levels = intensity if isinstance(intensity, np.ndarray) else v.as_float_array(intensity, "intensity")
    if levels.dtype.kind not in "biuf":
        raise InputError(f"intensity must be an array of numbers; got dtype={levels.dtype}.")
    result: Float32Array = np.maximum(np.float32(a) + np.float32(b) * levels, np.float32(0.0))
    return result


def systematic_errors(
    predicted: Float32Array, fraction_xy: tuple[float, float] | None, shift_std_px: tuple[float, float]
) -> tuple[Float32Array, Float32Array, Float32Array]:
    """Signed one-sigma error maps of the prediction that are coherent over a flaw window.

    Parameters
    ----------
    predicted : ndarray of shape (M, N), float32
        ``gain * warped_reference + bias``.
    fraction_xy : tuple of float or None
        Sub-pixel fractions ``(fx, fy)`` of a translation; None for warps whose fractions vary (their mean
        ``f (1 - f) = 1/6`` is used).
    shift_std_px : tuple of float
        ``(sx, sy)``, the registration's residual translation std (:attr:`Registration.shift_std_px`).

    Returns
    -------
    tuple of three ndarrays of shape (M, N), float32
        ``sx gx`` and ``sy gy``: the change of ``d`` per one-sigma residual shift along x and y
        (seed §2.3-2.4, first-order Taylor expansion; per pixel they add ``sx^2 gx^2 + sy^2 gy^2`` to the
        variance), and
        ``fx (1 - fx) / 2 Ixx + fy (1 - fy) / 2 Iyy``, the leading error of bilinear resampling, which
        misses the image's curvature (largest at edges).

    Notes
    -----
    All three are the same for every pixel of a small window (one shift, one sub-pixel phase), so a window
    sum sees them coherently: the detector adds ``(sum_k w_k e_k / v_k)^2`` to its variance, not
    ``sum_k w_k^2 e_k^2 / v_k^2``.
    """
    # OpenCV's Sobel has no float64-to-float32 path: a float64 prediction is taken as float32 (the detector's)
    plane = np.asarray(_plane(predicted, "predicted"), dtype=np.float32)
    sx, sy = _pair(shift_std_px, "shift_std_px", high=math.inf, unknown=True)
    fractions = None if fraction_xy is None else _pair(fraction_xy, "fraction_xy", high=1.0)
    cx, cy = (1.0 / 6.0, 1.0 / 6.0) if fractions is None else (f * (1.0 - f) for f in fractions)
    # Sobel / 8 is a central difference smoothed across the edge, which keeps sensor noise out of g; the
    # second-derivative Sobel is [1, -2, 1] smoothed by [1, 2, 1] (hence / 4).

    def sobel(dx: int, dy: int, scale: float) -> Float32Array:
        return np.asarray(cv2.Sobel(plane, cv2.CV_32F, dx, dy, ksize=3, scale=scale), dtype=np.float32)

    curvature = sobel(2, 0, 0.125 * cx) + sobel(0, 2, 0.125 * cy)
    return sobel(1, 0, 0.125 * sx), sobel(0, 1, 0.125 * sy), curvature
