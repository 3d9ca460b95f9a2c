"""Thresholds and receiver operating characteristics of the flaw detector (seed §2.4).

The seed characterises detection by plots of the probability of detection ``P_D`` against the
probability of false alarm ``P_F`` (ROC). :func:`theoretical_roc` gives the closed form for a flaw model
and flaw strength, :func:`empirical_roc` measures one from a score map and the ground truth, and
:func:`threshold_for` gives the Neyman-Pearson threshold that :func:`rsi.detection.detect.detect` uses.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import cv2
import numpy as np
from numpy.typing import NDArray
from scipy import optimize, special

from rsi import _validate as v
from rsi._validate import as_image, as_mask, choice, in_range, positive_int
from rsi.detection.flaw_models import flaw_kernel
from rsi.errors import InputError

FloatArray = NDArray[np.float64]

METHODS = ("lrt", "erosion")
POLARITIES = ("both", "dark", "bright")


@dataclass(frozen=True)
class RocCurve:
    """A receiver operating characteristic.

    Attributes
    ----------
    p_false_alarm : ndarray of shape (K,)
        Per-pixel probability of false alarm at each threshold.
    p_detection : ndarray of shape (K,)
        Per-flaw probability of detection at each threshold.
    threshold : ndarray of shape (K,)
        The score threshold of each point.
    label : str
        What the curve describes, for legends.
    """

    p_false_alarm: FloatArray
    p_detection: FloatArray
    threshold: FloatArray
    label: str


def _norm_isf(probability: FloatArray) -> FloatArray:
    """Upper-tail quantile of N(0, 1): ``t`` with ``P(z > t) = probability``."""
    result: FloatArray = -special.ndtri(probability)
    return result


def _lrt_thresholds(p_false_alarm: FloatArray, polarity: str, footprint_px: int) -> FloatArray:
    # seed §2.4 Neyman-Pearson: T ~ N(0, 1) under H0; |T| has both tails, -T or T one.
    tails = 2.0 if polarity == "both" else 1.0
    return _norm_isf(p_false_alarm / tails)


def _erosion_both_pixel_probability(p_false_alarm: float, footprint_px: int) -> float:
    """Per-pixel tail ``p`` with ``P(all z > t) + P(all z < -t) - P(both) = p_false_alarm``.

    With ``p = P(z > t)`` the two events are disjoint while ``t >= 0`` (``p <= 1/2``) and otherwise
    overlap in ``all |z| < -t``, of probability ``(2p - 1)^n``.
    """
    n = footprint_px
    closed = (p_false_alarm / 2.0) ** (1.0 / n)
    if closed <= 0.5:
        return float(closed)
    root = optimize.brentq(lambda p: 2.0 * p**n - (2.0 * p - 1.0) ** n - p_false_alarm, 0.5, 1.0)
    return float(root)


def _erosion_thresholds(p_false_alarm: FloatArray, polarity: str, footprint_px: int) -> FloatArray:
    # seed §2.4 sub-optimal erosion test: every one of the n independent footprint pixels must exceed t_e,
    # so P_F = p^n per polarity and each pixel's tail is p = P_F^(1/n).
    if polarity == "both":
        pixel = np.array([_erosion_both_pixel_probability(float(p), footprint_px) for p in p_false_alarm])
    else:
        pixel = p_false_alarm ** (1.0 / footprint_px)
    return _norm_isf(pixel)


_THRESHOLDS = {"lrt": _lrt_thresholds, "erosion": _erosion_thresholds}


def footprint_size(weights: FloatArray) -> int:
    """Number of pixels in a flaw model's footprint (its non-zero weights), ``n`` of the erosion test."""
    return int(np.count_nonzero(v.as_float_array(weights, "weights")))


def thresholds(p_false_alarm: FloatArray, *, polarity: str, method: str, weights: FloatArray) -> FloatArray:
    """Thresholds of the test; ``p_false_alarm`` may be any values in (0, 1] (checked by the caller)."""
    chosen = _THRESHOLDS[v.choice(method, "method", METHODS)]
    probabilities = v.as_float_array(p_false_alarm, "p_false_alarm")
    return chosen(probabilities, v.choice(polarity, "polarity", POLARITIES), footprint_size(weights))


def threshold_for(
    p_false_alarm: float,
    *,
    polarity: str = "both",
    method: str = "lrt",
    flaw_model: str = "single",
    size: int = 3,
    peak_ratio: float = 2.0,
    kernel: NDArray[Any] | None = None,
) -> float:
    """Return the score threshold that gives a per-pixel false-alarm probability.

    Parameters
    ----------
    p_false_alarm : float
        Requested per-pixel probability of false alarm, in (0, 0.5).
    polarity : {"both", "dark", "bright"}
        Which sign of change counts as a flaw; ``"both"`` splits ``p_false_alarm`` over two tails.
    method : {"lrt", "erosion"}
        Likelihood-ratio (matched filter) test, or the seed's sub-optimal erosion test.
    flaw_model, size, peak_ratio, kernel
        The flaw model (see :func:`rsi.detection.flaw_models.flaw_kernel`); only the erosion test's
        footprint size depends on it.

    Returns
    -------
    float
        Threshold ``t`` on the detector's score: a pixel is a flaw where ``score > t``.

    Notes
    -----
    LRT: ``t = Phi^-1(1 - P_F/2)`` for ``"both"`` and ``Phi^-1(1 - P_F)`` for one polarity. Erosion over a
    footprint of ``n`` independent pixels: ``t = Phi^-1(1 - P_F^(1/n))`` for one polarity, and for
    ``"both"`` the ``p`` solving ``2 p^n - max(2p - 1, 0)^n = P_F``.

    Examples
    --------
    >>> round(threshold_for(0.05, polarity="both"), 3)
    1.96
    """
    probability = in_range(
        p_false_alarm, "p_false_alarm", low=0.0, high=0.5, low_inclusive=False, high_inclusive=False
    )
    chosen_polarity = choice(polarity, "polarity", POLARITIES)
    chosen_method = choice(method, "method", METHODS)
    weights = flaw_kernel(flaw_model, size=size, peak_ratio=peak_ratio, kernel=kernel)
    return float(
        thresholds(np.array([probability]), polarity=chosen_polarity, method=chosen_method, weights=weights)[
            0
        ]
    )


def _centred_pair(weights: FloatArray, flaw: FloatArray) -> tuple[FloatArray, FloatArray]:
    """Zero-pad two odd-sided arrays to a common shape with their centres aligned."""
    rows = max(weights.shape[0], flaw.shape[0])
    cols = max(weights.shape[1], flaw.shape[1])

    def pad(array: FloatArray) -> FloatArray:
        dr = (rows - array.shape[0]) // 2
        dc = (cols - array.shape[1]) // 2
        return np.pad(array, ((dr, dr), (dc, dc)))

    return pad(weights), pad(flaw)


def _lrt_detection(
    t: FloatArray, weights: FloatArray, flaw: FloatArray, strength: float, polarity: str
) -> FloatArray:
    # The matched-filter statistic at the flaw centre is N(mean, 1) with mean = s <w, f> / ||w||.
    mean = strength * float(np.sum(weights * flaw)) / float(np.linalg.norm(weights))
    upper: FloatArray = special.ndtr(mean - t)
    if polarity == "both":
        upper = upper + special.ndtr(-mean - t)
    return upper


def _erosion_detection(
    t: FloatArray, weights: FloatArray, flaw: FloatArray, strength: float, polarity: str
) -> FloatArray:
    # Each footprint pixel's z is N(s f_i, 1), independent: the eroded score exceeds t iff all of them do.
    means = strength * flaw[weights != 0][:, None]
    upper: FloatArray = np.prod(special.ndtr(means - t), axis=0)
    if polarity == "both":
        lower = np.prod(special.ndtr(-means - t), axis=0)
        overlap = np.prod(np.clip(special.ndtr(-t - means) - special.ndtr(t - means), 0.0, None), axis=0)
        upper = upper + lower - overlap
    return upper


_DETECTION = {"lrt": _lrt_detection, "erosion": _erosion_detection}


def _true_flaw(true_flaw: object, weights: FloatArray) -> FloatArray:
    if true_flaw is None:
        return weights
    shape = getattr(true_flaw, "shape", type(true_flaw).__name__)
    if (
        not isinstance(true_flaw, np.ndarray)
        or true_flaw.ndim != 2
        or not np.issubdtype(true_flaw.dtype, np.number)
    ):
        raise InputError(f"true_flaw must be a 2-D numeric numpy array with odd sides; got {shape}.")
    if true_flaw.shape[0] % 2 == 0 or true_flaw.shape[1] % 2 == 0 or not np.isfinite(true_flaw).all():
        raise InputError(f"true_flaw must be finite with odd sides (centred on the flaw); got shape {shape}.")
    return np.asarray(true_flaw, dtype=np.float64)


def theoretical_roc(
    flaw_model: str,
    *,
    strength_sigma: float,
    p_false_alarm: NDArray[Any] | None = None,
    size: int = 3,
    peak_ratio: float = 2.0,
    kernel: NDArray[Any] | None = None,
    true_flaw: NDArray[Any] | None = None,
    method: str = "lrt",
    polarity: str = "dark",
) -> RocCurve:
    """Return the detector's ROC for a flaw of known strength in Gaussian noise.

    Parameters
    ----------
    flaw_model, size, peak_ratio, kernel
        The flaw model the detector assumes (see :func:`rsi.detection.flaw_models.flaw_kernel`).
    strength_sigma : float
        Flaw strength (amplitude of its strongest pixel) in units of the difference noise sigma, >= 0.
    p_false_alarm : ndarray of shape (K,), optional
        Per-pixel false-alarm probabilities in (0, 1]; default 100 values log-spaced over [1e-7, 1].
    true_flaw : ndarray of shape (P, Q), optional
        The real flaw's shape (odd sides, centred, in strength units); default the model's own shape.
    method : {"lrt", "erosion"}
        Detection test.
    polarity : {"both", "dark", "bright"}
        Detector polarity; the flaw is taken to have the matching sign (dark for ``"both"``; symmetric).

    Returns
    -------
    RocCurve
        ``P_D`` of the score at the flaw centre, at each ``P_F``.

    Notes
    -----
    LRT: the score at the centre is ``N(m, 1)`` with ``m = s <w, f> / ||w||``, so
    ``P_D = Phi(m - t)`` (``+ Phi(-m - t)`` for ``"both"``). Erosion: ``P_D = prod_i Phi(s f_i - t_e)``
    over the footprint (``"both"`` adds the other polarity's product less the overlap).
    At ``s = 0`` both give ``P_D = P_F``.
    """
    weights = flaw_kernel(flaw_model, size=size, peak_ratio=peak_ratio, kernel=kernel)
    strength = in_range(strength_sigma, "strength_sigma", low=0.0)
    chosen_method = choice(method, "method", METHODS)
    chosen_polarity = choice(polarity, "polarity", POLARITIES)
    if p_false_alarm is None:
        probabilities = np.logspace(-7.0, 0.0, 100)
    else:
        probabilities = np.atleast_1d(np.asarray(p_false_alarm, dtype=np.float64))
        if probabilities.ndim != 1 or not np.all((probabilities > 0) & (probabilities <= 1)):
            raise InputError("p_false_alarm must be a 1-D array of probabilities in (0, 1].")
    padded_weights, padded_flaw = _centred_pair(weights, _true_flaw(true_flaw, weights))
    t = thresholds(probabilities, polarity=chosen_polarity, method=chosen_method, weights=weights)
    detection = _DETECTION[chosen_method](t, padded_weights, padded_flaw, strength, chosen_polarity)
    label = f"{flaw_model} {chosen_method} {chosen_polarity} s={strength:g} sigma"
    return RocCurve(probabilities, np.clip(detection, 0.0, 1.0), t, label)


def _flaw_centres(truth: NDArray[np.bool_]) -> NDArray[np.intp]:
    count, _, _, centroids = cv2.connectedComponentsWithStats(truth.astype(np.uint8), connectivity=8)
    if count < 2:
        raise InputError("truth_mask marks no flaw; pass a bool mask that is True on the flaws.")
    # cv2 centroids are (x, y); the centre pixel is the rounded centroid as (row, col).
    return np.rint(centroids[1:, ::-1]).astype(np.intp)


def empirical_roc(
    score: NDArray[Any],
    truth_mask: NDArray[Any],
    *,
    valid: NDArray[Any] | None = None,
    guard_px: int = 2,
    label: str = "empirical",
) -> RocCurve:
    """Measure a ROC from a score map and the true flaws.

    Parameters
    ----------
    score : ndarray of shape (M, N)
        Detector score (higher = more flaw-like), e.g. ``Detection.score``.
    truth_mask : ndarray of shape (M, N), bool
        True on flaw pixels; each 8-connected component is one flaw.
    valid : ndarray of shape (M, N), bool, optional
        Pixels where the score is defined; default all.
    guard_px : int
        Pixels within this Chebyshev distance of a flaw count neither as flaw nor as background.
    label : str
        Curve label.

    Returns
    -------
    RocCurve
        At each distinct flaw score ``t`` (descending): ``P_D`` = fraction of flaws whose centre pixel
        scores ``>= t``, ``P_F`` = fraction of background pixels scoring ``>= t``.
    """
    values = as_image(score, "score")
    truth = as_mask(truth_mask, "truth_mask", values.shape)
    usable = np.ones(values.shape, bool) if valid is None else as_mask(valid, "valid", values.shape)
    guard = positive_int(guard_px, "guard_px", minimum=0)
    centres = _flaw_centres(truth)
    keep = usable[centres[:, 0], centres[:, 1]]
    flaw_scores = np.sort(values[centres[keep, 0], centres[keep, 1]])[::-1]
    if flaw_scores.size == 0:
        raise InputError("valid excludes every flaw centre in truth_mask; no detection rate can be measured.")
    footprint = np.ones((2 * guard + 1, 2 * guard + 1), np.uint8)
    near = cv2.dilate(truth.astype(np.uint8), footprint).astype(bool)
    background = np.sort(values[usable & ~near])
    count_at_least = background.size - np.searchsorted(background, flaw_scores, side="left")
    ascending = flaw_scores[::-1]
    detected = (ascending.size - np.searchsorted(ascending, flaw_scores, side="left")) / ascending.size
    return RocCurve(count_at_least / max(background.size, 1), detected, flaw_scores.astype(np.float64), label)


__all__ = [
    "METHODS",
    "POLARITIES",
    "RocCurve",
    "empirical_roc",
    "footprint_size",
    "theoretical_roc",
    "threshold_for",
    "thresholds",
]
