"""Flaw detection by a calibrated likelihood-ratio test on the registered difference image (seed §2.4).

``detect`` registers the reference to the inspection image, forms the difference
``d = inspection - (gain * warped_reference + bias)``, models its per-pixel noise variance
(:mod:`rsi.detection.noise`) and tests, at every pixel, "no flaw" against "a flaw of the model's shape
centred here". With Gaussian noise the log-likelihood ratio is the matched filter

    T = corr(d / var, w) / sqrt(corr(1 / var, w^2)),

which is exactly N(0, 1) without a flaw, so a requested per-pixel false-alarm probability fixes the
threshold (Neyman-Pearson). ``docs/detection.md`` gives the derivation.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import cv2
import numpy as np
from numpy.typing import NDArray

from rsi._validate import (
    MAX_INTENSITY,
    as_image,
    as_mask,
    choice,
    in_range,
    intensity_range,
    positive_int,
    same_shape,
)
from rsi.detection import noise
from rsi.detection.flaw_models import FLAW_MODELS, flaw_kernel
from rsi.detection.roc import METHODS, POLARITIES, thresholds
from rsi.errors import InputError
from rsi.imaging._components import component_stats, nonzero_pixels, occupied, pixel_components
from rsi.imaging._warps import scratch
from rsi.imaging.compensation import Compensated
from rsi.imaging.registration import REGISTRATION_MODELS, Registration, register

Float32Array = NDArray[np.float32]
BoolArray = NDArray[np.bool_]

_VARIANCE_FLOOR = np.float32(1e-20)  # keeps 1/var finite where a noise-free model predicts zero
_VALID_WEIGHT = 0.999  # a warped validity map below this touched an invalid reference pixel


@dataclass(frozen=True)
class Flaw:
    """One detected flaw: an 8-connected component of the detection mask.

    Attributes
    ----------
    row, col : float
        Centroid in inspection-image pixels.
    bbox : tuple of int
        ``(row0, col0, row1, col1)``, half-open.
    area_px : int
        Pixels in the component.
    score : float
        Peak score in the component.
    polarity : {"dark", "bright"}
        Sign of the change at the peak.
    peak : (int, int), optional
        ``(row, col)`` of the peak, one of the component's own pixels (its box may hold another flaw's);
        None for a flaw recorded without it.
    """

    row: float
    col: float
    bbox: tuple[int, int, int, int]
    area_px: int
    score: float
    polarity: str
    peak: tuple[int, int] | None = None


@dataclass(frozen=True)
class Detection:
    """Result of :func:`detect`; all maps have the inspection image's shape (M, N).

    Attributes
    ----------
    score : ndarray of shape (M, N), float32
        Test score: ``|T|`` for ``"both"``, ``-T`` for ``"dark"``, ``T`` for ``"bright"`` (eroded for
        ``method="erosion"``); 0 where invalid.
    statistic : ndarray of shape (M, N), float32
        Signed statistic (positive = brighter than predicted); 0 where invalid.
    mask : ndarray of shape (M, N), bool
        ``(score > threshold) & valid``.
    threshold : float
        Threshold giving the requested per-pixel false-alarm probability.
    flaws : tuple of Flaw
        Connected components of ``mask`` with at least ``min_area_px`` pixels, strongest first.
    difference : ndarray of shape (M, N), float32
        ``d = inspection - (gain * warped_reference + bias)``; 0 where invalid.
    sigma : ndarray of shape (M, N), float32
        Noise standard deviation of ``d`` as the test sees it (the flaw model's interpolation factor
        included; before self-calibration); 0 where invalid.
    valid : ndarray of shape (M, N), bool
        Pixels where the test is defined.
    registration : Registration or None
        The registration used (None: images taken as aligned).
    flaw_model, method, polarity : str
        The settings used.
    p_false_alarm : float
        Requested per-pixel false-alarm probability.
    """

    score: Float32Array
    statistic: Float32Array
    mask: BoolArray
    threshold: float
    flaws: tuple[Flaw, ...]
    difference: Float32Array
    sigma: Float32Array
    valid: BoolArray
    registration: Registration | None
    flaw_model: str
    method: str
    p_false_alarm: float
    polarity: str


@dataclass(frozen=True)
class _Input:
    """One image as the detector needs it: intensities, validity and sensor variance (None = unknown)."""

    image: Float32Array
    valid: BoolArray | None
    variance: Float32Array | float | None
    span: tuple[float, float] | None = None  # (min, max) of `image`, when its check found them


@dataclass(frozen=True)
class _Aligned:
    """The reference brought into the inspection frame."""

    predicted: Float32Array  # gain * warped_reference + bias
    valid: BoolArray
    variance: Float32Array | float | None  # the reference's sensor variance, warped
    gain: float
    bias: float
    fraction_xy: tuple[float, float] | None  # sub-pixel phase of a translation; None: varies


def _unpack(image: object, name: str, noise_sigma: float | None) -> _Input:
    if isinstance(image, Compensated):
        pixels = as_image(image.image, f"{name}.image").astype(np.float32, copy=False)
        valid = as_mask(image.valid, f"{name}.valid", pixels.shape)
        # seed §2.2: ambient interpolation error is extra noise; with a known sensor sigma only it is added.
        extra = image.interpolation_variance if noise_sigma is not None else image.variance
        base = 0.0 if noise_sigma is None else noise_sigma**2
        variance = np.asarray(extra, dtype=np.float32) + np.float32(base)
        return _Input(pixels, valid, variance)
    if not isinstance(image, np.ndarray):
        raise InputError(
            f"{name} must be a numpy array of shape (rows, cols) or a Compensated image; "
            f"got {type(image).__name__}."
        )
    checked, low, high = intensity_range(image, name)
    pixels = checked.astype(np.float32, copy=False)
    # The check's range is the image's own only if it was float32 already (a conversion may round).
    span = (low, high) if pixels is checked else None
    return _Input(pixels, None, None if noise_sigma is None else noise_sigma**2, span)


def _refuse_uninformative(reference: _Input, inspection: _Input) -> None:
    """A constant inspection against a textured reference (a dark or saturated frame) says nothing about
    flaws: every pixel changed, or none can be seen. Reporting "0 flaws" for it would be silently wrong."""
    pixels = inspection.image
    low, high = inspection.span if inspection.span is not None else (pixels.min(), pixels.max())
    if low == high and reference.image.min() != reference.image.max():
        raise InputError(
            f"inspection has one value everywhere ({float(pixels.flat[0]):g}) while the reference is "
            "textured: the pair carries no information about flaws (a dark or saturated frame?). Check the "
            "exposure and the lamp, and retake the inspection."
        )


def _resolve_registration(
    registration: object, reference: _Input, inspection: _Input, model: str
) -> Registration | None:
    if registration is None:
        same_shape(reference.image, inspection.image, ("reference", "inspection"))
        return None
    if isinstance(registration, Registration):
        return registration
    if isinstance(registration, str) and registration == "auto":
        return register(reference.image, inspection.image, model=model)
    raise InputError(
        f"registration must be 'auto', a Registration or None; got {registration!r}. "
        "Pass registration=None if the images are already aligned."
    )


def _warp_optional(
    registration: Registration, values: Float32Array | float | None, shape: tuple[int, int]
) -> Float32Array | float | None:
    if values is None or isinstance(values, float):
        return values
    warped, _ = registration.warp(values, output_shape=shape, photometric=False)
    return np.asarray(warped, dtype=np.float32)


def _align(reference: _Input, inspection: _Input, registration: Registration | None) -> _Aligned:
    shape = (int(inspection.image.shape[0]), int(inspection.image.shape[1]))
    if registration is None:
        valid = np.ones(shape, bool) if reference.valid is None else reference.valid
        return _Aligned(reference.image, valid, reference.variance, 1.0, 0.0, (0.0, 0.0))
    predicted, valid = registration.warp(reference.image, output_shape=shape, photometric=True)
    valid = np.asarray(valid, dtype=bool)
    if reference.valid is not None:
        warped_valid, _ = registration.warp(
            reference.valid.astype(np.float32), output_shape=shape, photometric=False
        )
        valid = valid & (warped_valid > _VALID_WEIGHT)
    fraction = None
    if registration.model == "translation":
        tx, ty = registration.translation_xy
        fraction = (tx % 1.0, ty % 1.0)
    return _Aligned(
        np.asarray(predicted, dtype=np.float32),
        valid,
        _warp_optional(registration, reference.variance, shape),
        float(registration.gain),
        float(registration.bias),
        fraction,
    )


def _factor(weights: NDArray[np.float64], fraction_xy: tuple[float, float] | None) -> float:
    if fraction_xy is None:
        return noise.mean_interpolation_factor(weights)
    return noise.interpolation_factor(weights, fraction_xy)


def _sensor_variances(
    inspection: _Input, aligned: _Aligned, difference: Float32Array, valid: BoolArray
) -> tuple[Float32Array | float, Float32Array | float]:
    """Sensor variance of the inspection and of the warped reference; fitted to ``d`` when unknown."""
    if inspection.variance is not None and aligned.variance is not None:
        return inspection.variance, aligned.variance
    # The variance is read at a local mean of both images: a noisy intensity would couple the variance to
    # the noise in d (a pixel whose reference noise is low also gets a low variance) and fatten the tails.
    mean = np.float32(0.5) * (inspection.image + aligned.predicted)
    intensity = np.asarray(cv2.blur(mean, (3, 3)), dtype=np.float32)
    single = _factor(np.ones((1, 1)), aligned.fraction_xy)
    coefficients = noise.fit_sensor_variance(
        difference, intensity, valid, gain=aligned.gain, bias=aligned.bias, factor=single
    )
    reference_intensity = (intensity - np.float32(aligned.bias)) * np.float32(1.0 / aligned.gain)
    return (
        noise.affine_variance(intensity, coefficients),
        noise.affine_variance(reference_intensity, coefficients),
    )


def _prediction_errors(
    aligned: _Aligned,
    registration: Registration | None,
    shift_floor: float,
    local_std: Float32Array | None = None,
) -> tuple[Float32Array, ...]:
    """Coherent one-sigma errors of the prediction: residual shift and resampling (seed §2.3-2.4).

    `local_std`: a local registration's per-pixel shift std over `aligned` (default: the field's own over
    the whole frame; a box of the frame passes its crop)."""
    if registration is None and shift_floor == 0.0:
        return ()
    if registration is not None and registration.local is not None:
        shape = (int(aligned.predicted.shape[0]), int(aligned.predicted.shape[1]))
        std = registration.local.std(shape) if local_std is None else local_std
        return _local_prediction_errors(aligned, std, shift_floor)
    # Unregistered images are not resampled: no sub-pixel phase, hence no resampling error.
    fraction = (0.0, 0.0) if registration is None else aligned.fraction_xy
    own = (0.0, 0.0) if registration is None else registration.shift_std_px
    shift_std = (max(own[0], shift_floor), max(own[1], shift_floor))
    return noise.systematic_errors(aligned.predicted, fraction, shift_std)


def _local_prediction_errors(
    aligned: _Aligned, std: Float32Array, shift_floor: float
) -> tuple[Float32Array, ...]:
    """As _prediction_errors, with the local field's per-pixel shift std `std` (rows, cols, 2) in place of
    one global value."""
    unit_x, unit_y, curvature = noise.systematic_errors(aligned.predicted, None, (1.0, 1.0))
    floor = np.float32(shift_floor)
    return unit_x * np.maximum(std[..., 0], floor), unit_y * np.maximum(std[..., 1], floor), curvature


def _variances(
    variance: Float32Array | np.floating[Any], valid: BoolArray, invalid: BoolArray
) -> tuple[Float32Array | np.float32, Float32Array]:
    """The floored noise variance of ``d`` and its inverse, 0 where invalid.

    A variance that is one number (a known sensor sigma, no Compensated images) stays one number: a single
    division instead of one per pixel, and no full-size copy; the values are those of the per-pixel path.
    """
    floored = np.maximum(variance, _VARIANCE_FLOOR)
    if np.ndim(floored) == 0:
        level = np.float32(floored)
        return level, np.where(valid, np.float32(1.0) / level, np.float32(0.0))
    per_pixel = np.broadcast_to(floored, valid.shape).astype(np.float32)
    inverse = np.divide(np.float32(1.0), per_pixel, dtype=np.float32)
    inverse[invalid] = 0.0
    return per_pixel, inverse


def _sigma(
    variance: Float32Array | np.float32, errors: tuple[Float32Array, ...], valid: BoolArray
) -> Float32Array:
    """Noise std of ``d`` with the coherent errors' squares added, 0 where invalid (accumulated in place)."""
    if not errors:
        return np.where(valid, np.sqrt(variance), np.float32(0.0)).astype(np.float32, copy=False)
    total = np.multiply(errors[0], errors[0])
    for error in errors[1:]:
        total += error * error
    total += variance
    np.sqrt(total, out=total)
    total[~valid] = 0.0
    return np.asarray(total, dtype=np.float32)


def _correlate(image: Float32Array, weights: NDArray[np.float64], *, own: bool = False) -> Float32Array:
    """Correlate with `weights` (zero outside the image); `own`: `image` is a temporary that may be reused."""
    if weights.shape == (1, 1):
        if own and weights[0, 0] == 1.0:
            return image  # x * 1 is x: the pixel-wise tests' weight costs no pass
        scaled: Float32Array = np.multiply(image, np.float32(weights[0, 0]), out=image if own else None)
        return scaled
    result = cv2.filter2D(image, -1, weights.astype(np.float32), borderType=cv2.BORDER_CONSTANT)
    return np.asarray(result, dtype=np.float32)


def _lrt(
    difference: Float32Array,
    inverse_variance: Float32Array,
    weights: NDArray[np.float64],
    errors: tuple[Float32Array, ...],
) -> Float32Array:
    # seed §2.4: for Gaussian noise the log-likelihood ratio of "flaw s*w here" is linear in d: a weighted
    # sum over the window, normalised to unit variance under H0. Coherent prediction errors add the square
    # of their own weighted sum to that variance.
    # In place where the operands are this function's own temporaries: the same arithmetic in the same
    # order, without a fresh full-size array (and its page faults) per step.
    numerator = _correlate(difference * inverse_variance, weights, own=True)
    denominator = _correlate(inverse_variance, weights * weights)
    for error in errors:
        coherent = _correlate(error * inverse_variance, weights, own=True)
        denominator += np.multiply(coherent, coherent, out=coherent)
    root = np.sqrt(np.maximum(denominator, _VARIANCE_FLOOR, out=denominator), out=denominator)
    return np.asarray(np.divide(numerator, root, out=numerator), dtype=np.float32)


def _lrt_scores(
    statistic: Float32Array, valid: BoolArray, weights: NDArray[np.float64]
) -> tuple[Float32Array, Float32Array, BoolArray]:
    return statistic, -statistic, valid


def _erosion_scores(
    statistic: Float32Array, valid: BoolArray, weights: NDArray[np.float64]
) -> tuple[Float32Array, Float32Array, BoolArray]:
    # seed §2.4 sub-optimal test: a flaw needs every footprint pixel beyond t_e, i.e. the grey erosion
    # (minimum over the footprint) of z beyond t_e. Pixels whose footprint leaves the valid area are invalid.
    footprint = (weights != 0).astype(np.uint8)
    bright = np.asarray(cv2.erode(statistic, footprint), dtype=np.float32)
    dark = np.asarray(cv2.erode(-statistic, footprint), dtype=np.float32)
    eroded_valid = cv2.erode(valid.astype(np.uint8), footprint, borderType=cv2.BORDER_CONSTANT, borderValue=0)
    return bright, dark, np.asarray(eroded_valid, dtype=bool)


_METHOD_SCORES: dict[
    str,
    Callable[[Float32Array, BoolArray, NDArray[np.float64]], tuple[Float32Array, Float32Array, BoolArray]],
] = {
    "lrt": _lrt_scores,
    "erosion": _erosion_scores,
}

# The filter the statistic (and its noise model) uses: the LRT sees d through w, erosion pixel by pixel.
_TEST_WEIGHTS: dict[str, Callable[[NDArray[np.float64]], NDArray[np.float64]]] = {
    "lrt": lambda weights: weights,
    "erosion": lambda weights: np.ones((1, 1)),
}

_POLARITY_SCORE: dict[str, Callable[[Float32Array, Float32Array], Float32Array]] = {
    "both": np.maximum,
    "dark": lambda bright, dark: dark,
    "bright": lambda bright, dark: bright,
}


def _signed(bright: Float32Array, dark: Float32Array, valid: BoolArray) -> Float32Array:
    """``bright`` where it is the larger score, else ``-dark``; 0 where invalid (one new array, not four)."""
    signed = np.negative(dark)
    np.copyto(signed, bright, where=bright >= dark)
    signed[~valid] = 0.0
    return np.asarray(signed, dtype=np.float32)


def _peaks(owner: NDArray[np.int32], values: Float32Array) -> dict[int, int]:
    """Per component, the index (into its pixels, row-major) of its highest-scoring pixel; ties: the first."""
    order = np.argsort(-values, kind="stable")
    found, first = np.unique(owner[order], return_index=True)
    return dict(zip(found.tolist(), order[first].tolist(), strict=True))


def _flaws(
    mask: BoolArray, score: Float32Array, statistic: Float32Array, min_area_px: int
) -> tuple[Flaw, ...]:
    # Labelled on the box holding the mask's pixels (a few flaws on a large image), its empty rows cut, with
    # the whole frame's labels; the statistics come from the pixels.
    top, left, bottom, right = occupied(mask.view(np.uint8))
    count, rows, cols, owner = pixel_components(
        np.ascontiguousarray(mask.view(np.uint8)[top:bottom, left:right]), 8
    )
    rows, cols = rows + top, cols + left
    stats, centroids = component_stats(count, rows, cols, owner)
    peaks = _peaks(owner, score[rows, cols])
    found = []
    for label in range(1, count):
        x, y, width, height, area = (int(value) for value in stats[label])
        if area < min_area_px:
            continue
        peak = (rows[peaks[label]], cols[peaks[label]])
        found.append(
            Flaw(
                row=float(centroids[label, 1]),
                col=float(centroids[label, 0]),
                bbox=(y, x, y + height, x + width),
                area_px=area,
                score=float(score[peak]),
                polarity="bright" if statistic[peak] > 0 else "dark",
                peak=(int(peak[0]), int(peak[1])),
            )
        )
    return tuple(sorted(found, key=lambda flaw: -flaw.score))


@dataclass(frozen=True)
class _Test:
    """What the test needs beyond the images: the settings and the noise model of ``d``."""

    variance: Float32Array | np.floating[Any]  # sensor variance of d (factor included)
    test_weights: NDArray[np.float64]
    weights: NDArray[np.float64]
    registration: Registration | None
    shift_floor: float
    method: str
    polarity: str
    calibrate: bool  # self-calibration: rescale the statistic by its robust scale over the frame


def _test_maps(
    aligned: _Aligned,
    difference: Float32Array,
    valid: BoolArray,
    test: _Test,
    errors: tuple[Float32Array, ...] | None = None,
) -> tuple[Float32Array, Float32Array, BoolArray, Float32Array]:
    """Score, signed statistic, the test's validity and sigma of the images given (a whole frame or a box);
    `errors`: the prediction errors on them, if already computed."""
    variance, inverse_variance = _variances(test.variance, valid, ~valid)
    if errors is None:
        errors = _prediction_errors(aligned, test.registration, test.shift_floor)
    statistic = _lrt(difference, inverse_variance, test.test_weights, errors)
    if test.calibrate:
        # Self-calibration: under H0 the statistic is N(0, 1); its robust scale absorbs noise-model error.
        scale = noise.robust_scale(statistic, valid)
        if scale > 0.0:
            statistic = (statistic * np.float32(1.0 / scale)).astype(np.float32, copy=False)
    bright, dark, valid = _METHOD_SCORES[test.method](statistic, valid, test.weights)
    score = np.where(valid, _POLARITY_SCORE[test.polarity](bright, dark), np.float32(0.0))
    return score, _signed(bright, dark, valid), valid, _sigma(variance, errors, valid)


# seed §2.4: sigma^2 = v + coherent errors >= v, so |z| <= |d| / sqrt(v); a relative margin covers the
# float32 rounding of z's few operations (each within 2^-24), so no pixel the test flags is skipped.
_SPARSE_MARGIN = 1.0 - 1e-5


# OpenCV's filters run a row in SIMD blocks and finish it in scalar code, whose rounding (no fused
# multiply-add) can differ in the last bit: a box starting and ending on a multiple of 16 columns (or at the
# frame's edge) puts every pixel in the same kind of block as on the whole frame.
_SIMD_COLUMNS = 16


def _compare(image: Float32Array, bound: float, operation: int, role: str) -> NDArray[np.uint8]:
    """255 where ``image <operation> bound``, else 0: one pass, straight to uint8, into this thread's
    `role` buffer (:func:`~rsi.imaging._warps.scratch`: a temporary of this call only)."""
    out = scratch(role, image.shape, np.uint8)
    # cv2.compare takes a float as a scalar (its stubs list arrays only).
    return np.asarray(cv2.compare(image, bound, operation, dst=out), dtype=np.uint8)  # type: ignore[call-overload]


_UNFILLED, _FILLED = 255, 128  # a joined pixel before and after its component is boxed


def _sparse_boxes(
    difference: Float32Array, footprint: NDArray[np.uint8], level: float, above: float
) -> list[tuple[int, int, int, int]]:
    """Boxes (left, top, width, height) covering what may be flagged (every footprint pixel's |d| beyond
    `level`), the footprint each reads, and the pixels with |d| beyond `above` 8-connected to them."""

    # Every map here is a temporary of this call: this thread's scratch buffers, whose pages stay mapped
    # from one pair to the next (a fresh full-frame array costs its page faults, as much as its pass).
    shape = difference.shape

    def buffer(role: str) -> NDArray[np.uint8]:
        return scratch(f"sparse {role}", shape, np.uint8)

    bright = cv2.erode(_compare(difference, level, cv2.CMP_GT, "sparse >"), footprint, dst=buffer("bright"))
    dark = cv2.erode(_compare(difference, -level, cv2.CMP_LT, "sparse <"), footprint, dst=buffer("dark"))
    flagged = cv2.bitwise_or(bright, dark, dst=buffer("flagged"))
    # The components of the strong pixels, the flagged ones and what their erosion reads (the dilation by
    # the reflected footprint) that hold a flagged pixel.
    reflected = np.ascontiguousarray(footprint[::-1, ::-1])
    read = cv2.bitwise_or(flagged, cv2.dilate(flagged, reflected, dst=buffer("dilated")), dst=buffer("read"))
    strong = cv2.bitwise_or(
        _compare(difference, above, cv2.CMP_GT, "sparse >"),
        _compare(difference, -above, cv2.CMP_LT, "sparse <"),
        dst=buffer("strong"),
    )
    joined = np.asarray(cv2.bitwise_or(strong, read, dst=buffer("joined")), np.uint8)
    # Only the components holding a flagged pixel are boxed: each is flood-filled from the first flagged
    # pixel found in it (a few defects), which returns its box, instead of labelling every component.
    rows, cols = nonzero_pixels(np.asarray(flagged, np.uint8))
    boxes = []
    for row, col in zip(rows.tolist(), cols.tolist(), strict=True):
        if joined[row, col] == _UNFILLED:
            _, _, _, (left, top, width, height) = cv2.floodFill(joined, None, (col, row), _FILLED, flags=8)
            boxes.append((int(left), int(top), int(width), int(height)))
    return boxes


def _check_sparse(test: _Test, sparse_above: float) -> None:
    """The bound |T| <= |d| / sqrt(v) needs one known variance and a pixel-wise test (the mis-registration
    terms, global or local, only add to sigma^2)."""
    if np.ndim(test.variance) != 0 or test.test_weights.shape != (1, 1):
        raise InputError(
            f"sparse_above={sparse_above!r} needs a known noise_sigma on plain arrays (not Compensated "
            "images) and a pixel-wise test (method='erosion', or flaw_model='single'). Pass "
            "sparse_above=None for whole-frame maps."
        )


def _sparse_maps(
    aligned: _Aligned,
    difference: Float32Array,
    valid: BoolArray,
    test: _Test,
    levels: tuple[float, float],
) -> tuple[Float32Array, Float32Array, BoolArray, Float32Array]:
    """`_test_maps` on boxes around the region where the maps can matter; elsewhere 0 (sigma inf).

    `levels` are the test's threshold and ``sparse_above``, statistic units. Each box is computed with a halo
    of 1 + the footprint's radius: the Sobel passes and the erosion read no farther, so inside the box the
    same operations give the whole frame's values (tested bit for bit).
    """
    footprint = (test.weights != 0).astype(np.uint8)
    if test.method != "erosion":
        footprint = np.ones((1, 1), np.uint8)
    deviation = float(np.sqrt(np.maximum(test.variance, _VARIANCE_FLOOR)))
    # A threshold at or below 0 bounds nothing: every pixel may be flagged.
    bound = -np.inf if levels[0] <= 0.0 else levels[0] * deviation * _SPARSE_MARGIN
    boxes = _sparse_boxes(difference, footprint, bound, max(levels[1], 0.0) * deviation * _SPARSE_MARGIN)
    valid_out = valid
    if test.method == "erosion":
        eroded = cv2.erode(valid.view(np.uint8), footprint, borderType=cv2.BORDER_CONSTANT, borderValue=0)
        valid_out = np.asarray(eroded, dtype=bool)
    score = np.zeros(difference.shape, np.float32)
    signed = np.zeros(difference.shape, np.float32)
    sigma = np.full(difference.shape, np.inf, np.float32)
    halo = 1 + max(footprint.shape) // 2
    rows, cols = difference.shape
    local = test.registration.local if test.registration is not None else None
    for left, top, width, height in boxes:
        row0, row1 = max(0, top - halo), min(rows, top + height + halo)
        tight0, tight1 = max(0, left - halo), min(cols, left + width + halo)
        # OpenCV's Sobel rounds as on the whole frame only on whole blocks of columns: the prediction errors
        # are computed on those, the rest (elementwise and erosions, exact anywhere) on the box and its halo.
        col0 = tight0 - tight0 % _SIMD_COLUMNS
        col1 = min(cols, -(-tight1 // _SIMD_COLUMNS) * _SIMD_COLUMNS)
        blocks = dataclasses.replace(aligned, predicted=aligned.predicted[row0:row1, col0:col1])
        errors = tuple(
            error[:, tight0 - col0 : tight1 - col0]
            for error in _prediction_errors(
                blocks,
                test.registration,
                test.shift_floor,
                None if local is None else local.std((rows, cols), (slice(row0, row1), slice(col0, col1))),
            )
        )
        crop = (slice(row0, row1), slice(tight0, tight1))
        maps = _test_maps(
            dataclasses.replace(aligned, predicted=aligned.predicted[crop]),
            difference[crop],
            valid[crop],
            test,
            errors,
        )
        inner = (slice(top - row0, top - row0 + height), slice(left - tight0, left - tight0 + width))
        box = (slice(top, top + height), slice(left, left + width))
        score[box], signed[box], sigma[box] = maps[0][inner], maps[1][inner], maps[3][inner]
    return score, signed, valid_out, sigma


def detect(
    reference: NDArray[Any] | Compensated,
    inspection: NDArray[Any] | Compensated,
    *,
    flaw_model: str = "single",
    size: int = 3,
    peak_ratio: float = 2.0,
    kernel: NDArray[Any] | None = None,
    method: str = "lrt",
    p_false_alarm: float = 1e-5,
    polarity: str = "both",
    noise_sigma: float | None = None,
    registration: str | Registration | None = "auto",
    registration_model: str = "translation",
    min_area_px: int = 1,
    misregistration_std_px: float = 0.0,
    sparse_above: float | None = None,
) -> Detection:
    """Detect flaws in an inspection image by comparison with a reference image (seed §2.4).

    Parameters
    ----------
    reference, inspection : ndarray of shape (M, N) or Compensated
        Images (float32 used internally). A :class:`Compensated` image brings its validity and noise
        variance. Without registration they must have the same shape.
    flaw_model : {"single", "uniform", "disc", "peak", "kernel"}
        Expected flaw shape; see :func:`rsi.detection.flaw_models.flaw_kernel` for ``size``,
        ``peak_ratio`` and ``kernel``.
    method : {"lrt", "erosion"}
        Likelihood-ratio test (matched filter), or the seed's sub-optimal morphological-erosion test.
    p_false_alarm : float
        Requested per-pixel false-alarm probability, in (0, 0.5).
    polarity : {"both", "dark", "bright"}
        Which changes count as flaws.
    noise_sigma : float, optional
        Known sensor noise std of each image (intensity units), > 0. None: fit a read + shot noise model
        to ``d`` and rescale the statistic by its robust scale (self-calibrated test).
    registration : "auto", Registration or None
        ``"auto"`` registers with ``registration_model``; a Registration is used as given; None takes the
        images as aligned.
    registration_model : str
        Model for ``registration="auto"``, one of :data:`rsi.imaging.registration.REGISTRATION_MODELS`.
        ``"local"`` follows local distortion with a smooth field and brings its per-pixel uncertainty.
    min_area_px : int
        Components of the mask smaller than this are not reported as flaws.
    misregistration_std_px : float
        Floor, >= 0, on the residual shift std the noise model uses (seed §2.3-2.4). The registration's own
        ``shift_std_px`` is the statistical precision of one global fit; local distortion (thermal
        expansion, flexible structures, etching of a printed board) moves edges further, and this floor
        turns it into noise at edges instead of false alarms. Also applies with ``registration=None``.
        With a local registration (``model="local"``) the per-pixel std of its field is used instead of
        the global ``shift_std_px``, and the floor applies to it.
    sparse_above : float, optional
        None (default): every map is computed on the whole frame. A value ``s >= 0``: the maps are computed
        only where they can matter, in boxes around (a) every pixel the test could flag and the footprint it
        reads, and (b) the pixels where ``|d| / sigma`` could exceed ``s`` that are 8-connected to (a);
        elsewhere `score` and `statistic` are 0 and `sigma` is inf (``|d| / sigma`` is 0 there, as the
        statistic). `mask`, `flaws`, `difference` and `valid`
        are those of the whole-frame computation, and so is every map inside the boxes, bit for bit;
        ``|difference| / sigma > s2`` for any ``s2 >= s`` holds exactly where it holds on the whole frame,
        among pixels connected to (a) (seed §2.4: ``sigma^2 = v + coherent errors >= v``, so
        ``|T| <= |d| / sqrt(v)`` bounds the statistic from the difference alone). Needs a known
        `noise_sigma` on plain arrays and a pixel-wise test (``method="erosion"``, or
        ``flaw_model="single"``); a local registration's per-pixel shift std is read in each box. On a
        640 x 640 DeepPCB pair the boxes cover about 1 % of the frame (``docs/deeppcb.md``).

    Returns
    -------
    Detection
        Score maps, mask, threshold and the list of flaws.

    Notes
    -----
    Noise variance of ``d`` at a pixel: ``v_insp + gain^2 F v_ref + sx^2 gx^2 + sy^2 gy^2`` with ``F`` the
    bilinear-resampling factor for the flaw model (:func:`rsi.detection.noise.interpolation_factor`),
    ``(sx, sy)`` the registration's ``shift_std_px`` and ``g`` the gradient of the predicted image.
    """
    chosen_model = choice(flaw_model, "flaw_model", FLAW_MODELS)
    chosen_method = choice(method, "method", METHODS)
    chosen_polarity = choice(polarity, "polarity", POLARITIES)
    probability = in_range(
        p_false_alarm, "p_false_alarm", low=0.0, high=0.5, low_inclusive=False, high_inclusive=False
    )
    sigma_known = (
        None
        if noise_sigma is None
        else in_range(noise_sigma, "noise_sigma", low=0.0, high=MAX_INTENSITY, low_inclusive=False)
    )
    choice(registration_model, "registration_model", REGISTRATION_MODELS)
    min_area = positive_int(min_area_px, "min_area_px")
    shift_floor = in_range(misregistration_std_px, "misregistration_std_px", low=0.0)
    if sparse_above is not None:
        in_range(sparse_above, "sparse_above", low=0.0)
    weights = flaw_kernel(chosen_model, size=size, peak_ratio=peak_ratio, kernel=kernel)

    reference_in = _unpack(reference, "reference", sigma_known)
    inspection_in = _unpack(inspection, "inspection", sigma_known)
    _refuse_uninformative(reference_in, inspection_in)
    used_registration = _resolve_registration(registration, reference_in, inspection_in, registration_model)
    aligned = _align(reference_in, inspection_in, used_registration)
    valid = aligned.valid if inspection_in.valid is None else aligned.valid & inspection_in.valid

    invalid = ~valid
    difference = inspection_in.image - aligned.predicted
    difference[invalid] = 0.0
    variance_inspection, variance_reference = _sensor_variances(inspection_in, aligned, difference, valid)
    test_weights = _TEST_WEIGHTS[chosen_method](weights)
    factor = _factor(test_weights, aligned.fraction_xy)
    test = _Test(
        variance=variance_inspection + np.float32(aligned.gain**2 * factor) * variance_reference,
        test_weights=test_weights,
        weights=weights,
        registration=used_registration,
        shift_floor=shift_floor,
        method=chosen_method,
        polarity=chosen_polarity,
        calibrate=sigma_known is None,
    )
    threshold = float(
        thresholds(np.array([probability]), polarity=chosen_polarity, method=chosen_method, weights=weights)[
            0
        ]
    )
    if sparse_above is None:
        score, signed, valid, sigma = _test_maps(aligned, difference, valid, test)
    else:
        _check_sparse(test, sparse_above)
        score, signed, valid, sigma = _sparse_maps(
            aligned, difference, valid, test, (threshold, float(sparse_above))
        )
    mask = (score > threshold) & valid
    return Detection(
        score=score,
        statistic=signed,
        mask=mask,
        threshold=threshold,
        flaws=_flaws(mask, score, signed, min_area),
        difference=difference,
        sigma=sigma,
        valid=valid,
        registration=used_registration,
        flaw_model=chosen_model,
        method=chosen_method,
        p_false_alarm=probability,
        polarity=chosen_polarity,
    )
