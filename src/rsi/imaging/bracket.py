"""Seed §2 further work: several electronic shutter settings merged into one ambient-lit image of high
dynamic range.

Sunlight in orbit makes "images having a large dynamic range with sharp shadows" (seed §1): one shutter
that holds a sunlit face under the top leaves its shadows a few DN, one that lifts the shadows clips the
sunlit faces. The camera is linear (seed §2.1), so every unclipped reading of a pixel measures the same
illuminance, scaled by its exposure time; :func:`merge_ambient` weighs the readings of a bracket by their
inverse noise variance (Granados et al. 2010, "Optimal HDR reconstruction with linear digital cameras"),
the variance taken from the camera's own noise model at the merged level, not at each reading (a weight
drawn from the reading it weighs would bias the mean towards the darker draws).

Only the rows the strobe did not light hold the ambient alone: the unlit field of an interlaced strobe
frame (seed §2.2) enters the bracket with its rows, an ambient-only frame (``lit_field="none"``) whole.
OpenCV's ``createMergeDebevec`` and ``createMergeRobertson`` estimate an unknown camera response and return
no variance; this camera's response is known and linear, and the comparison needs the variance.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from rsi.errors import InputError
from rsi.imaging.camera import Frame, _lit_rows

F32 = NDArray[np.float32]
BoolArray = NDArray[np.bool_]

MAX_BRACKET = 16
"""Most frames one bracket merges: sixteen exposures a stop apart span 2**16, past any scene's range."""


@dataclass(frozen=True)
class AmbientImage:
    """The ambient light alone at every pixel, merged from a bracket of exposures (seed §2 further work).

    Attributes
    ----------
    image : ndarray of shape (M, N), float32
        DN above black that a frame of ``exposure_s`` would read, were it never to clip.
    variance : ndarray of shape (M, N), float32
        Noise variance of `image` in DN^2, from the camera's noise model at the merged level.
    valid : ndarray of shape (M, N), bool
        True where some reading of the pixel was unclipped, not defective and not strobe-lit.
    exposure_s : float
        The bracket's longest exposure, the unit of `image`.
    exposures_s : tuple of float
        Every exposure the bracket merged, in the order given.
    """

    image: F32
    variance: F32
    valid: BoolArray
    exposure_s: float
    exposures_s: tuple[float, ...]


def merge_ambient(frames: Sequence[Frame]) -> AmbientImage:
    """Merge the ambient-lit readings of `frames` (one scene, one camera, any exposures) into one image.

    Parameters
    ----------
    frames : sequence of Frame
        1 to ``MAX_BRACKET`` frames of the same shape from the same camera, taken from the same pose: the
        unlit rows of interlaced strobe frames (``lit_field`` "odd" or "even") and ambient-only frames
        (``"none"``); a whole-flash frame (``"both"``) holds no ambient reading.

    Returns
    -------
    AmbientImage
        Inverse-variance mean of each pixel's usable readings, scaled to the longest exposure.
    """
    _check_frames(frames)
    longest = max(frame.exposure_s for frame in frames)
    camera = frames[0].camera
    values, usable = _readings(frames, longest)
    # the first level: each pixel's longest unclipped reading, the one with the most signal
    first = np.zeros(values[0].shape, np.float32)
    filled = np.zeros(values[0].shape, bool)
    for index in np.argsort([-frame.exposure_s for frame in frames], kind="stable"):
        new = usable[index] & ~filled
        first[new] = values[index][new]
        filled |= new
    level = np.maximum(first, np.float32(0.0))
    weight_sum = np.zeros(first.shape, np.float64)
    weighted = np.zeros(first.shape, np.float64)
    for frame, value, ok in zip(frames, values, usable, strict=True):
        scale = longest / frame.exposure_s
        # the reading's own variance in DN^2 at the level it should read, then scaled to the longest frame
        reading_variance = camera.noise_variance_dn(
            level / np.float32(scale) + np.float32(camera.black_level_dn)
        )
        weight = np.where(ok, 1.0 / (reading_variance.astype(np.float64) * scale * scale), 0.0)
        weight_sum += weight
        weighted += weight * value
    with np.errstate(divide="ignore", invalid="ignore"):
        image = np.where(filled, weighted / weight_sum, 0.0).astype(np.float32)
        variance = np.where(filled, 1.0 / weight_sum, np.inf).astype(np.float32)
    return AmbientImage(image, variance, filled, longest, tuple(frame.exposure_s for frame in frames))


def _check_frames(frames: object) -> None:
    if not isinstance(frames, Sequence) or not frames:
        raise InputError(
            f"frames must be a non-empty sequence of Frame; got {type(frames).__name__}"
            f"{'' if not isinstance(frames, Sequence) else ' of length 0'}. Pass the bracket's frames."
        )
    if len(frames) > MAX_BRACKET:
        raise InputError(
            f"frames holds {len(frames)} frames, over {MAX_BRACKET}: a bracket a stop apart spans 2**16 "
            "within that. Merge fewer exposures."
        )
    for index, frame in enumerate(frames):
        if not isinstance(frame, Frame):
            raise InputError(f"frames[{index}] must be a Frame; got {type(frame).__name__}.")
    first = frames[0]
    for index, frame in enumerate(frames):
        if frame.raw.shape != first.raw.shape or frame.camera != first.camera:
            raise InputError(
                f"frames[{index}] has shape {frame.raw.shape} from {frame.camera}, frames[0] shape "
                f"{first.raw.shape} from {first.camera}: a bracket is one camera's frames of one scene."
            )
    if all(frame.lit_field == "both" for frame in frames):
        raise InputError(
            "frames are all whole-flash frames (lit_field 'both'): none holds the ambient alone. Add an "
            "ambient-only frame (lit_field 'none') or an interlaced strobe frame."
        )


def _readings(frames: Sequence[Frame], longest: float) -> tuple[list[F32], list[BoolArray]]:
    """Each frame's DN above black scaled to the `longest` exposure, and where it is an ambient reading
    that may be used (unlit row, not clipped, not defective)."""
    values, usable = [], []
    for frame in frames:
        camera = frame.camera
        value = (frame.raw.astype(np.float32) - np.float32(camera.black_level_dn)) * np.float32(
            longest / frame.exposure_s
        )
        ok = ~_lit_rows(frame.raw.shape, frame.lit_field) & ~frame.saturated
        if frame.bad_pixels is not None:
            ok &= ~frame.bad_pixels.defective
        values.append(value)
        usable.append(np.broadcast_to(ok, frame.raw.shape))
    return values, usable


__all__ = ["MAX_BRACKET", "AmbientImage", "merge_ambient"]
