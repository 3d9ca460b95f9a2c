"""Synthetic reference/inspection pairs with known flaws, after the seed's laboratory tests (seed §2.4).

The seed simulated flaws "by a random dot pattern of a given pixel size distributed on the surface of a
test object". Here a textured surface is shifted by a known sub-pixel motion, photometrically scaled, given
a jittered-grid dot pattern of flaws and independent sensor noise, so every stage can be scored.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import cv2
import numpy as np
from numpy.typing import NDArray
from scipy import ndimage

from rsi._validate import as_rng, choice, finite_number, in_range, positive_int
from rsi.detection.flaw_models import flaw_kernel
from rsi.errors import InputError

FloatArray = NDArray[np.float64]

PROFILES = ("uniform", "peak")
_SCALES_PX = (1.5, 4.0, 12.0, 40.0)  # texture octaves: fine grain to large shading
_EDGE_COUNT = 12  # straight edges (panel seams, shadows) that registration can lock on to
_EDGE_BLUR_PX = 0.8  # optics: edges are sharp but band-limited
_SHIFT_MARGIN_PX = 8  # texture beyond the shift that ndimage.shift's spline needs


@dataclass(frozen=True)
class FlawPattern:
    """A random dot pattern of flaws.

    Attributes
    ----------
    signal : ndarray of shape (M, N), float64
        Additive flaw signal (negative for dark flaws).
    truth_mask : ndarray of shape (M, N), bool
        True on flaw pixels.
    centres_rc : ndarray of shape (K, 2), int
        Flaw centre pixels as (row, col).
    size_px : int
        Flaw side in pixels.
    strength : float
        Amplitude of each flaw's strongest pixel.
    """

    signal: FloatArray
    truth_mask: NDArray[np.bool_]
    centres_rc: NDArray[np.intp]
    size_px: int
    strength: float


@dataclass(frozen=True)
class SyntheticPair:
    """A reference/inspection pair with ground truth.

    Attributes
    ----------
    reference, inspection : ndarray of shape (M, N), float64
        ``inspection = gain * shift(surface, (dy, dx)) + bias + flaws + noise``.
    truth_mask : ndarray of shape (M, N), bool
        Flaw pixels, in inspection coordinates.
    centres_rc : ndarray of shape (K, 2), int
        Flaw centres (row, col) in inspection coordinates.
    shift_xy : tuple of float
        ``(dx, dy)`` applied to the reference (``scipy.ndimage.shift(reference, (dy, dx))`` convention).
    gain, bias, noise_sigma : float
        Photometric map and per-image sensor noise std.
    """

    reference: FloatArray
    inspection: FloatArray
    truth_mask: NDArray[np.bool_]
    centres_rc: NDArray[np.intp]
    shift_xy: tuple[float, float]
    gain: float
    bias: float
    noise_sigma: float


# The largest synthetic image: the pixel limit of the image reader (rsi.imaging.io), 2**26 pixels, a
# 64 M-pixel float64 image is 512 MiB and every generator holds a few of them at once.
MAX_SYNTHETIC_PIXELS = 2**26


def _shape(shape: object) -> tuple[int, int]:
    if not isinstance(shape, tuple) or len(shape) != 2:
        raise InputError(f"shape must be a (rows, cols) tuple; got {shape!r}.")
    rows, cols = positive_int(shape[0], "shape[0]", minimum=2), positive_int(shape[1], "shape[1]", minimum=2)
    if rows * cols > MAX_SYNTHETIC_PIXELS:
        raise InputError(
            f"shape={shape!r} asks for {rows * cols} pixels, over the {MAX_SYNTHETIC_PIXELS} a synthetic "
            "image may have; ask for a smaller (rows, cols)."
        )
    return rows, cols


def _shift(shift_xy: object, size: tuple[int, int]) -> tuple[float, float]:
    """A (dx, dy) shift that leaves the two images overlapping (a larger one pads the canvas without end)."""
    if not isinstance(shift_xy, (tuple, list)) or len(shift_xy) != 2:
        raise InputError(f"shift_xy must be a (dx, dy) pair in pixels; got {shift_xy!r:.60}.")
    dx = finite_number(shift_xy[0], "shift_xy[0]")
    dy = finite_number(shift_xy[1], "shift_xy[1]")
    if abs(dx) >= size[1] or abs(dy) >= size[0]:
        raise InputError(
            f"shift_xy={shift_xy!r:.60} moves the image off itself (shape {size}); pass a shift smaller than "
            "the image so that the pair overlaps."
        )
    return dx, dy


def _edges(shape: tuple[int, int], rng: np.random.Generator) -> FloatArray:
    """Sum of random straight steps: half-planes through random points with random normals and heights."""
    rows, cols = np.mgrid[0 : shape[0], 0 : shape[1]].astype(np.float64)
    steps = np.zeros(shape)
    for _ in range(_EDGE_COUNT):
        angle = rng.uniform(0.0, 2.0 * np.pi)
        row0, col0 = rng.uniform(0.0, shape[0]), rng.uniform(0.0, shape[1])
        steps += rng.normal(0.0, 1.0) * ((rows - row0) * np.sin(angle) + (cols - col0) * np.cos(angle) > 0)
    blurred = cv2.GaussianBlur(steps, (0, 0), _EDGE_BLUR_PX, borderType=cv2.BORDER_REFLECT)
    return np.asarray(blurred, dtype=np.float64)


def textured_surface(shape: tuple[int, int], *, rng: np.random.Generator | int | None = None) -> FloatArray:
    """Return a textured surface image with values in [0, 1].

    Parameters
    ----------
    shape : tuple of int
        ``(M, N)``.
    rng : Generator, int or None
        Randomness.

    Returns
    -------
    ndarray of shape (M, N), float64
        Multi-scale smooth noise (octaves of Gaussian-filtered white noise, equal power per octave) plus
        a dozen blurred straight edges, rescaled to [0, 1]: enough detail at every scale for registration.
    """
    size = _shape(shape)
    generator = as_rng(rng)
    texture = np.zeros(size)
    for scale in _SCALES_PX:
        octave = cv2.GaussianBlur(
            generator.standard_normal(size), (0, 0), scale, borderType=cv2.BORDER_REFLECT
        )
        texture += octave / octave.std()
    edges = _edges(size, generator)
    texture += 1.5 * edges / max(float(edges.std()), 1e-12)
    low, high = float(texture.min()), float(texture.max())
    result: FloatArray = np.asarray((texture - low) / (high - low), dtype=np.float64)
    return result


def _jittered_centres(
    shape: tuple[int, int], size_px: int, spacing_px: int, rng: np.random.Generator
) -> NDArray[np.intp]:
    """One centre per grid cell, jittered so flaws stay inside their cell with a one-pixel gap."""
    half = size_px // 2
    low = half + 1
    high = spacing_px - 2 - half  # inclusive
    cells_r, cells_c = shape[0] // spacing_px, shape[1] // spacing_px
    grid_r, grid_c = np.mgrid[0:cells_r, 0:cells_c]
    origins = np.column_stack([grid_r.ravel(), grid_c.ravel()]) * spacing_px
    centres: NDArray[np.intp] = origins + rng.integers(low, high + 1, size=origins.shape)
    return centres


def flaw_pattern(
    shape: tuple[int, int],
    *,
    size_px: int = 3,
    spacing_px: int = 16,
    strength: float = 0.1,
    profile: str = "uniform",
    peak_ratio: float = 2.0,
    polarity: str = "dark",
    rng: np.random.Generator | int | None = None,
) -> FlawPattern:
    """Return a random dot pattern of square flaws on a jittered grid (seed §2.4 laboratory tests).

    Parameters
    ----------
    shape : tuple of int
        ``(M, N)`` of the image.
    size_px : int
        Odd flaw side in pixels.
    spacing_px : int
        Grid cell side; one flaw per whole cell. Must be at least ``size_px + 3`` so flaws never touch.
    strength : float
        Amplitude of the strongest flaw pixel, >= 0.
    profile : {"uniform", "peak"}
        Equal strength over the square, or a centre ``peak_ratio`` times the surround (crater).
    peak_ratio : float
        Centre-to-surround ratio of the ``"peak"`` profile.
    polarity : {"dark", "bright"}
        Sign of the flaws.
    rng : Generator, int or None
        Randomness.

    Returns
    -------
    FlawPattern
    """
    size = _shape(shape)
    side = positive_int(size_px, "size_px")
    if side % 2 == 0:
        raise InputError(f"size_px must be odd so each flaw has a centre pixel; got {side}. Try {side + 1}.")
    spacing = positive_int(spacing_px, "spacing_px")
    if spacing < side + 3:
        raise InputError(
            f"spacing_px must be >= size_px + 3 = {side + 3} so flaws never touch; got {spacing}."
        )
    amplitude = in_range(strength, "strength", low=0.0)
    chosen = choice(profile, "profile", PROFILES)
    sign = {"dark": -1.0, "bright": 1.0}[choice(polarity, "polarity", ("dark", "bright"))]
    shape_w = flaw_kernel(chosen, size=side, peak_ratio=peak_ratio)
    centres = _jittered_centres(size, side, spacing, as_rng(rng))
    signal = np.zeros(size)
    half = side // 2
    for row, col in centres:
        signal[row - half : row + half + 1, col - half : col + half + 1] = sign * amplitude * shape_w
    truth = np.zeros(size, bool)
    for row, col in centres:
        truth[row - half : row + half + 1, col - half : col + half + 1] = True
    return FlawPattern(signal, truth, centres, side, amplitude)


def synthetic_pair(
    shape: tuple[int, int] = (512, 512),
    *,
    shift_xy: tuple[float, float] = (3.7, -2.2),
    gain: float = 1.1,
    bias: float = 0.03,
    noise_sigma: float = 2 / 255,
    flaw_size_px: int = 3,
    flaw_strength: float = 0.15,
    flaw_spacing_px: int = 24,
    profile: str = "uniform",
    rng: np.random.Generator | int | None = None,
) -> SyntheticPair:
    """Return a reference/inspection pair with a known motion, photometric change and flaw pattern.

    Parameters
    ----------
    shape : tuple of int
        ``(M, N)`` of both images.
    shift_xy : tuple of float
        ``(dx, dy)``: ``inspection`` shows ``scipy.ndimage.shift(reference, (dy, dx))``.
    gain, bias : float
        ``inspection ~= gain * reference + bias``.
    noise_sigma : float
        Independent Gaussian sensor noise std added to each image, >= 0.
    flaw_size_px, flaw_strength, flaw_spacing_px, profile
        Dark flaw pattern (see :func:`flaw_pattern`), placed in inspection coordinates.
    rng : Generator, int or None
        Randomness.

    Returns
    -------
    SyntheticPair
    """
    size = _shape(shape)
    dx, dy = _shift(shift_xy, size)
    gain_value = finite_number(gain, "gain")
    bias_value = finite_number(bias, "bias")
    sigma = in_range(noise_sigma, "noise_sigma", low=0.0)
    generator = as_rng(rng)
    # Shift a larger canvas and crop, so the inspection's borders hold real texture, not padding.
    pad = math.ceil(max(abs(dx), abs(dy))) + _SHIFT_MARGIN_PX
    canvas = textured_surface((size[0] + 2 * pad, size[1] + 2 * pad), rng=generator)
    window = (slice(pad, pad + size[0]), slice(pad, pad + size[1]))
    shifted = ndimage.shift(canvas, (dy, dx), mode="reflect")[window]
    flaws = flaw_pattern(
        size,
        size_px=flaw_size_px,
        spacing_px=flaw_spacing_px,
        strength=flaw_strength,
        profile=profile,
        rng=generator,
    )
    reference = canvas[window] + sigma * generator.standard_normal(size)
    inspection = gain_value * shifted + bias_value + flaws.signal + sigma * generator.standard_normal(size)
    return SyntheticPair(
        reference, inspection, flaws.truth_mask, flaws.centres_rc, (dx, dy), gain_value, bias_value, sigma
    )


def pure_noise_pairs(
    shape: tuple[int, int],
    count: int,
    *,
    read_sigma: float,
    shot_variance_per_unit: float = 0.0,
    rng: np.random.Generator | int | None = None,
) -> list[tuple[NDArray[np.float32], NDArray[np.float32]]]:
    """Aligned pairs of one texture with independent noise and no flaw: every detection is a false alarm.

    The calibration set of seed §2.4's P_F analysis. Noise variance per pixel is
    ``read_sigma**2 + shot_variance_per_unit * surface`` (read plus shot noise when the second term is > 0).

    Parameters
    ----------
    shape : tuple of int
        ``(M, N)`` of every image.
    count : int
        Number of pairs, >= 1.
    read_sigma : float
        Signal-independent noise std, >= 0.
    shot_variance_per_unit : float
        Noise variance added per unit of surface intensity, >= 0.
    rng : Generator, int or None
        Randomness (texture and noise).

    Returns
    -------
    list of (reference, inspection) float32 pairs
    """
    size = _shape(shape)
    pairs_wanted = positive_int(count, "count")
    read = in_range(read_sigma, "read_sigma", low=0.0)
    shot = in_range(shot_variance_per_unit, "shot_variance_per_unit", low=0.0)
    generator = as_rng(rng)
    surface = textured_surface(size, rng=generator).astype(np.float32)
    std = np.sqrt(read**2 + shot * surface).astype(np.float32)
    pairs = []
    for _ in range(pairs_wanted):
        noise = generator.standard_normal((2, *size), dtype=np.float32)
        pairs.append((surface + std * noise[0], surface + std * noise[1]))
    return pairs
