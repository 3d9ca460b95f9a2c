"""Seed §2.3-2.4 extra variance: what the noise model must add where the comparison is not pure sensor noise.

Seed §2.4: "errors in mis-registration correction and ambient light compensation can be interpreted as
increasing the noise in the image". Each function here turns one such error into a per-pixel variance (or a
factor on the variance) that the likelihood-ratio test then divides by, so the threshold rises exactly where
the nuisance is and nowhere else:

- :func:`shared_interpolation` - the ambient-interpolation error of seed §2.2, the same in both images
  under the same ambient;
- :func:`shadow_edge_variance` - the interpolation error of a sharp sun-shadow edge that moved between the
  visits (seed §2.2 penumbra);
- :func:`half_pixel_shifted` and :func:`pair_excess` - what two flaw-free visits of one view differ by
  beyond the model (texture aliasing, sub-pixel sampling phase, relief);
- :func:`nuisance_scale` - the larger of the two;
- :func:`parallax_scale` - surfaces off the plane one translation registers (seed §2.3).

Every image is a :class:`rsi.imaging.compensation.Compensated` (image, variance, interpolation variance,
valid mask), shape (M, N).
"""

from __future__ import annotations

from dataclasses import replace
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from rsi import _validate as v
from rsi.errors import InputError

if TYPE_CHECKING:
    from rsi.imaging.compensation import Compensated

Float32Array = NDArray[np.float32]


def _compensated(image: object, name: str) -> Compensated:
    """`image` if it is a Compensated image, else an error naming the argument and the fix."""
    from rsi.imaging.compensation import Compensated

    if not isinstance(image, Compensated):
        raise InputError(
            f"{name} must be an rsi.imaging.compensation.Compensated image (compensate_interlaced or "
            f"compensate_field_pair give one); got {type(image).__name__}."
        )
    return image


_SOBEL_SCALE = 0.125  # 3x3 Sobel weights sum to 8: this scale gives DN per pixel
_FAR_M = 10.0  # a depth beyond this is no surface (the renderer's and the stereo matcher's "no return")


def shared_interpolation(
    reference: Compensated, inspection: Compensated, *, spread_px: int = 2
) -> tuple[Compensated, Compensated]:
    """Both images with the reference's ambient-interpolation variance, dilated by `spread_px`.

    Seed §2.2: under the same ambient the interpolation errors of reference and inspection are the same and
    cancel. The inspection's own estimate would also count a new flaw's sharp edge as interpolation error
    and hide the flaw behind it, so the flaw-free reference's map, dilated by the repeatability, is used
    for both.

    Parameters
    ----------
    reference, inspection : Compensated
        Shape (M, N) each.
    spread_px : int
        Half-width of the square dilation (the visits' pose error in pixels), >= 0.

    Returns
    -------
    (Compensated, Compensated)
        Reference and inspection, each with ``variance = sensor variance + shared interpolation variance``.
    """
    reference, inspection = _compensated(reference, "reference"), _compensated(inspection, "inspection")
    import cv2

    spread_px = v.positive_int(spread_px, "spread_px", minimum=0)
    side = 2 * spread_px + 1
    shared = np.asarray(
        cv2.dilate(reference.interpolation_variance, np.ones((side, side), np.uint8)), dtype=np.float32
    )

    def rebuilt(image: Compensated) -> Compensated:
        sensor = image.variance - image.interpolation_variance
        return replace(image, variance=(sensor + shared).astype(np.float32), interpolation_variance=shared)

    return rebuilt(reference), rebuilt(inspection)


def shadow_edge_variance(
    image: Compensated,
    raw_frame: NDArray[np.generic],
    *,
    lit_field: str,
    edge_dn_px: float,
    jag_px: float,
) -> Compensated:
    """`image` with the compensation error of a sharp ambient edge seen at another visit added.

    Seed §2.2 interpolates each lit row's ambient from the unlit rows around it. Along a sharp sun-shadow
    edge that is exact only while the edge runs straight across the rows; the next visit sees the edge a
    fraction of a pixel elsewhere, jagged by the shadow's sampling, and its interpolation misses by up to
    the edge's contrast. The frame's own unlit rows show where such edges are: where their gradient exceeds
    `edge_dn_px`, the gradient times `jag_px` is the one-sigma error added to both the variance and the
    interpolation variance.

    Parameters
    ----------
    image : Compensated
        Full-resolution compensated image, shape (M, N).
    raw_frame : ndarray of shape (M, N)
        The interlaced frame it came from (digital numbers).
    lit_field : {"odd", "even"}
        Which field the strobe lit; the other holds the ambient alone.
    edge_dn_px : float
        Ambient gradient (DN per pixel) above which an edge counts as a sharp shadow edge, > 0.
    jag_px : float
        Sampling jitter of the edge between visits, pixels, >= 0.

    Returns
    -------
    Compensated
    """
    image = _compensated(image, "image")
    import cv2

    v.choice(lit_field, "lit_field", ("odd", "even"))
    edge_dn_px = v.positive(edge_dn_px, "edge_dn_px")
    jag_px = v.in_range(jag_px, "jag_px", low=0.0)
    raw = v.as_image(raw_frame, "raw_frame").astype(np.float32)
    if raw.shape != image.image.shape:
        raise InputError(
            f"raw_frame has shape {raw.shape} but the image is {image.image.shape}; give the frame the "
            "full-resolution image was compensated from."
        )
    unlit = raw[0::2] if lit_field == "odd" else raw[1::2]
    gx = cv2.Sobel(unlit, cv2.CV_32F, 1, 0, ksize=3, scale=_SOBEL_SCALE)
    gy = cv2.Sobel(unlit, cv2.CV_32F, 0, 1, ksize=3, scale=_SOBEL_SCALE / 2)  # field rows: two frame rows
    gradient = np.sqrt(gx * gx + gy * gy)
    edge = np.where(gradient > edge_dn_px, gradient * np.float32(jag_px), np.float32(0.0))
    extra = np.repeat(edge * edge, 2, axis=0)[: image.image.shape[0]]
    interpolation = (image.interpolation_variance + extra).astype(np.float32)
    return replace(image, variance=image.variance + extra, interpolation_variance=interpolation)


def half_pixel_shifted(image: Compensated) -> Compensated:
    """`image` resampled half a pixel along both axes: the sub-pixel phase no second visit may have had.

    A feature thinner than a pixel (a door gap, a grid line) renders differently at each sampling phase and
    no interpolation predicts it; two flaw-free visits show that only where their phases happened to differ.
    Pixels whose bilinear footprint touched an invalid pixel become invalid.
    """
    image = _compensated(image, "image")
    import cv2

    shape = (image.image.shape[1], image.image.shape[0])
    matrix = np.array([[1.0, 0.0, 0.5], [0.0, 1.0, 0.5]], dtype=np.float32)

    def moved(values: Float32Array) -> Float32Array:
        warped = cv2.warpAffine(
            values, matrix, shape, flags=cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE
        )
        return np.asarray(warped, dtype=np.float32)

    valid = moved(image.valid.astype(np.float32)) > 0.999
    return replace(
        image,
        image=moved(image.image),
        variance=moved(image.variance),
        interpolation_variance=moved(image.interpolation_variance),
        valid=valid,
    )


def pair_excess(
    first: Compensated,
    second: Compensated,
    *,
    flaw_model: str = "uniform",
    size: int = 3,
    misregistration_std_px: float = 0.3,
    window_px: int = 9,
    spread_px: int = 9,
) -> Float32Array:
    """Per-pixel factor by which the noise model under-states what two flaw-free visits differ by.

    Seed §2.3-2.4: mis-registration and compensation errors "can be interpreted as increasing the noise".
    Two visits of the same view before any flaw (independent pose errors and camera noise) contain no flaw,
    so their calibrated likelihood-ratio statistic z should be N(0, 1). Where texture aliasing, parallax,
    relief or fine lines make it wider, the local mean of z^2 over a `window_px` box, then its maximum over
    `spread_px` (the next visit's pose error differs), is that excess; floored at 1 it multiplies both
    images' variance before an inspection is tested.

    Parameters
    ----------
    first, second : Compensated
        Two flaw-free visits of one view, shape (M, N). The factor lies in `first`'s frame.
    flaw_model, size, misregistration_std_px
        As in :func:`rsi.detection.detect.detect` (the test the factor will scale).
    window_px, spread_px : int
        Sides of the averaging box and of the dilation, >= 1.

    Returns
    -------
    ndarray of shape (M, N), float32
        The factor, >= 1 everywhere.

    Examples
    --------
    >>> import numpy as np
    >>> from rsi.imaging.compensation import Compensated
    >>> rng = np.random.default_rng(0)
    >>> base = rng.uniform(50, 200, (64, 64)).astype(np.float32)
    >>> def visit(seed):
    ...     noise = np.random.default_rng(seed).normal(0, 1, base.shape).astype(np.float32)
    ...     ones = np.ones_like(base)
    ...     return Compensated(base + noise, ones, np.zeros_like(base), np.ones(base.shape, bool))
    >>> bool(pair_excess(visit(1), visit(2)).min() >= 1.0)
    True
    """
    first, second = _compensated(first, "first"), _compensated(second, "second")
    import cv2

    from rsi.detection.detect import detect
    from rsi.imaging.registration import register

    window_px = v.positive_int(window_px, "window_px")
    spread_px = v.positive_int(spread_px, "spread_px")
    first_shared, second_shared = shared_interpolation(first, second)
    # `second` predicts `first`: the statistic lies in the first visit's frame, where it is used
    registration = register(
        second_shared.image, first_shared.image, model="translation", mask=second_shared.valid
    )
    detection = detect(
        second_shared,
        first_shared,
        flaw_model=flaw_model,
        size=size,
        polarity="both",
        registration=registration,
        misregistration_std_px=misregistration_std_px,
    )
    statistic = np.where(detection.valid, detection.statistic, np.float32(0.0))
    energy = cv2.blur((statistic * statistic).astype(np.float32), (window_px, window_px))
    scale = np.asarray(cv2.dilate(energy, np.ones((spread_px, spread_px), np.uint8)), dtype=np.float32)
    return np.maximum(scale, np.float32(1.0))


def nuisance_scale(
    first: Compensated,
    second: Compensated,
    *,
    flaw_model: str = "uniform",
    size: int = 3,
    misregistration_std_px: float = 0.3,
    window_px: int = 9,
    spread_px: int = 9,
) -> Float32Array:
    """The larger of two flaw-free visits' excess and `first`'s own half-pixel sampling-phase excess.

    Two visits reveal a sampling-phase artefact only where their phases happened to differ; the half-pixel
    shift of :func:`half_pixel_shifted` is the largest phase change a later visit can bring. Keywords as in
    :func:`pair_excess`; shape (M, N), float32, >= 1.
    """
    first, second = _compensated(first, "first"), _compensated(second, "second")
    keywords = {
        "flaw_model": flaw_model,
        "size": size,
        "misregistration_std_px": misregistration_std_px,
        "window_px": window_px,
        "spread_px": spread_px,
    }
    return np.maximum(
        pair_excess(first, second, **keywords),  # type: ignore[arg-type]
        pair_excess(first, half_pixel_shifted(first), **keywords),  # type: ignore[arg-type]
    )


def parallax_scale(
    reference: Compensated, depth_m: NDArray[np.floating], shift_px: float, *, spread_px: int = 9
) -> Float32Array:
    """Variance factor for surfaces off the plane one translation registers (seed §2.3, parallax).

    A viewpoint error that shifts the image by `shift_px` at the median depth z0 shifts a surface at depth
    z by ``shift_px * z0 / z``: it stays mis-registered by ``delta = shift_px |z0 / z - 1|``, which to first
    order changes the difference by ``delta |grad I|`` (the detector's own mis-registration model). The
    extra variance ``delta^2 |grad I|^2``, dilated by `spread_px`, over the reference's variance plus one is
    the factor.

    Parameters
    ----------
    reference : Compensated
        Shape (M, N).
    depth_m : ndarray of shape (M, N)
        Range of each pixel, metres (>= 10 m: no surface).
    shift_px : float
        Magnitude of the registered translation, pixels, >= 0.
    spread_px : int
        Side of the dilation, >= 1.

    Returns
    -------
    ndarray of shape (M, N), float32
        1 where the surface lies at the median depth (or nothing is seen), more elsewhere.
    """
    reference = _compensated(reference, "reference")
    import cv2

    depth = v.as_image(depth_m, "depth_m", allow_nan=True).astype(np.float32)
    if depth.shape != reference.image.shape:
        raise InputError(
            f"depth_m has shape {depth.shape} but the reference is {reference.image.shape}; "
            "give the range map of the same view."
        )
    shift_px = v.in_range(shift_px, "shift_px", low=0.0)
    spread_px = v.positive_int(spread_px, "spread_px")
    surface = depth < _FAR_M
    seen = surface & reference.valid
    if not seen.any():
        return np.ones(depth.shape, np.float32)
    z0 = float(np.median(depth[seen]))
    delta = np.where(surface, shift_px * np.abs(z0 / np.maximum(depth, 1e-3) - 1.0), 0.0).astype(np.float32)
    gx = cv2.Sobel(reference.image, cv2.CV_32F, 1, 0, ksize=3, scale=_SOBEL_SCALE)
    gy = cv2.Sobel(reference.image, cv2.CV_32F, 0, 1, ksize=3, scale=_SOBEL_SCALE)
    extra = delta * delta * (gx * gx + gy * gy)
    extra = np.asarray(cv2.dilate(extra, np.ones((spread_px, spread_px), np.uint8)), dtype=np.float32)
    return (1.0 + extra / np.maximum(reference.variance, np.float32(1e-6))).astype(np.float32)


__all__ = [
    "half_pixel_shifted",
    "nuisance_scale",
    "pair_excess",
    "parallax_scale",
    "shadow_edge_variance",
    "shared_interpolation",
]
