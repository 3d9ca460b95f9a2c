"""Pictures of result records, encoded as PNG bytes: grey and colour-mapped images, flaw overlays, ROC plots.

This module is a view: it renders arrays and records that the algorithms already produced and computes
nothing about the inspection itself. Images are encoded with OpenCV (fast, no figure machinery); only the ROC
plot uses matplotlib, through a bare ``Figure`` on the non-interactive Agg canvas (pyplot is never imported).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from rsi import _validate as v
from rsi._validate import as_image, as_mask
from rsi.errors import InputError

if TYPE_CHECKING:
    from rsi.detection.detect import Flaw
    from rsi.detection.roc import RocCurve

UInt8Array = NDArray[np.uint8]

# Invalid pixels (outside the registered overlap, saturated, bad) are drawn in this mid grey so that they
# read as "no data" rather than as dark or bright surface.
_INVALID_GREY = 96
_INVALID_BGR = (_INVALID_GREY, _INVALID_GREY, _INVALID_GREY)
_BOX_BGR = (0, 0, 255)
_LABEL_BGR = (0, 255, 255)
# Small images are enlarged by a whole factor (nearest neighbour, so pixels stay honest) until the long side
# reaches this many pixels, which keeps the flaw numbers legible.
_OVERLAY_MIN_SIDE_PX = 768
_STRETCH_PERCENTILES = (0.5, 99.5)
_P_FALSE_ALARM_FLOOR = 1e-7  # left end of the ROC plot's P_F axis


def encode_png(image: UInt8Array) -> bytes:
    """Encode an 8-bit grey (M, N) or BGR (M, N, 3) image as PNG bytes.

    Parameters
    ----------
    image : ndarray of uint8, shape (M, N) or (M, N, 3)
        Pixels to encode; colour images are in OpenCV's BGR order.

    Returns
    -------
    bytes
        The PNG file contents.
    """
    _uint8_picture(image, "image")
    import cv2

    ok, buffer = cv2.imencode(".png", np.ascontiguousarray(image))
    if not ok:
        raise InputError(f"could not encode an image of shape {image.shape} as PNG; pass uint8 grey or BGR.")
    return bytes(buffer.tobytes())


def _valid_or_all(valid: object, shape: tuple[int, ...]) -> NDArray[np.bool_]:
    if valid is None:
        return np.ones(shape, dtype=bool)
    return as_mask(valid, "valid", shape)


def to_uint8(image: object, *, valid: object = None) -> UInt8Array:
    """Stretch an image to 8 bits between its 0.5 and 99.5 percentiles over the valid pixels.

    Parameters
    ----------
    image : ndarray of shape (M, N)
        Any real image (DN, reflectance, score).
    valid : ndarray of bool, shape (M, N), optional
        Pixels that carry data; the others are drawn mid grey.

    Returns
    -------
    ndarray of uint8, shape (M, N)
    """
    pixels = as_image(image, "image", allow_nan=True)
    mask = _valid_or_all(valid, pixels.shape) & np.isfinite(pixels)
    low, high = _stretch_limits(pixels, mask)
    scaled = np.clip((np.nan_to_num(pixels) - low) / (high - low), 0.0, 1.0)
    grey: UInt8Array = np.round(scaled * 255.0).astype(np.uint8)
    grey[~mask] = _INVALID_GREY
    return grey


def _stretch_limits(pixels: NDArray[Any], mask: NDArray[np.bool_]) -> tuple[float, float]:
    if not mask.any():
        return 0.0, 1.0
    low, high = (float(v) for v in np.percentile(pixels[mask], _STRETCH_PERCENTILES))
    if high <= low:
        return low, low + 1.0
    return low, high


def grey_png(image: object, *, valid: object = None) -> bytes:
    """Render an image as a contrast-stretched grey PNG (see :func:`to_uint8`)."""
    return encode_png(to_uint8(image, valid=valid))


def colour_png(
    image: object,
    *,
    cmap: str = "magma",
    symmetric: bool = False,
    limit: float | None = None,
    valid: object = None,
) -> bytes:
    """Render an image through a matplotlib colour map as a PNG.

    Parameters
    ----------
    image : ndarray of shape (M, N)
        A difference image (signed) or a score image.
    cmap : str, default "magma"
        Name of a matplotlib colour map ("RdBu_r" suits signed differences).
    symmetric : bool, default False
        Map [-limit, +limit] so that zero sits at the colour map's centre.
    limit : float, optional
        Upper end of the mapped range (and minus the lower one when `symmetric`); by default the 99.5th
        percentile of the valid pixels (of their magnitude when `symmetric`).
    valid : ndarray of bool, shape (M, N), optional
        Pixels that carry data; the others are drawn mid grey.

    Returns
    -------
    bytes
        The PNG file contents.
    """
    pixels = as_image(image, "image", allow_nan=True)
    limit = None if limit is None else v.finite_number(limit, "limit")
    mask = _valid_or_all(valid, pixels.shape) & np.isfinite(pixels)
    low, high = _colour_limits(pixels, mask, symmetric=symmetric, limit=limit)
    index = np.clip((np.nan_to_num(pixels) - low) / (high - low), 0.0, 1.0)
    bgr = _lookup_table(cmap)[np.round(index * 255.0).astype(np.intp)]
    bgr[~mask] = _INVALID_BGR
    return encode_png(bgr)


def _colour_limits(
    pixels: NDArray[Any], mask: NDArray[np.bool_], *, symmetric: bool, limit: float | None
) -> tuple[float, float]:
    values = pixels[mask]
    if limit is None:
        limit = float(np.percentile(np.abs(values) if symmetric else values, 99.5)) if values.size else 1.0
    limit = max(limit, 1e-12)
    if symmetric:
        return -limit, limit
    low = float(values.min()) if values.size else 0.0
    return (low, limit) if limit > low else (low, low + 1.0)


def _lookup_table(cmap: str) -> UInt8Array:
    # matplotlib.colormaps needs no figure machinery and no backend, so pyplot stays unimported here.
    import matplotlib

    if cmap not in matplotlib.colormaps:
        raise InputError(f"cmap={cmap!r} is not a matplotlib colour map. Try 'magma' or 'RdBu_r'.")
    rgba = matplotlib.colormaps[cmap](np.linspace(0.0, 1.0, 256))
    rgb = np.round(rgba[:, :3] * 255.0).astype(np.uint8)
    return np.ascontiguousarray(rgb[:, ::-1])


def mapped_png(
    image: object,
    *,
    low: float,
    high: float,
    cmap: str = "gray",
    valid: object = None,
    scale_rc: tuple[int, int] = (1, 1),
) -> bytes:
    """Render an image through a colour map between fixed limits, enlarged by whole factors, as a PNG.

    Unlike :func:`grey_png` and :func:`colour_png` the limits are given, so that several pictures (a
    reference and its inspection, every finding's score) share one scale and can be compared by eye.

    Parameters
    ----------
    image : ndarray of shape (M, N)
        Any real image.
    low, high : float
        Values mapped to the colour map's ends (``high > low``); values outside are clipped.
    cmap : str, default "gray"
        Name of a matplotlib colour map.
    valid : ndarray of bool, shape (M, N), optional
        Pixels that carry data; the others are drawn mid grey.
    scale_rc : (int, int), default (1, 1)
        Whole enlargement factors along rows and columns (nearest neighbour: pixels stay honest). An
        interlaced field is shown at the frame's aspect with ``(2 * k, k)``.

    Returns
    -------
    bytes
        The PNG file contents.
    """
    pixels = as_image(image, "image", allow_nan=True)
    low, high = v.finite_number(low, "low"), v.finite_number(high, "high")
    if not high > low:
        raise InputError(f"high must exceed low; got low={low!r}, high={high!r}.")
    rows_factor, cols_factor = _scale(scale_rc, pixels.size)
    mask = _valid_or_all(valid, pixels.shape) & np.isfinite(pixels)
    index = np.clip((np.nan_to_num(pixels) - low) / (high - low), 0.0, 1.0)
    bgr = _lookup_table(cmap)[np.round(index * 255.0).astype(np.intp)]
    bgr[~mask] = _INVALID_BGR
    big = np.repeat(np.repeat(bgr, rows_factor, axis=0), cols_factor, axis=1)
    return encode_png(big)


def _enlargement(shape: tuple[int, ...]) -> int:
    return max(1, -(-_OVERLAY_MIN_SIDE_PX // max(shape[:2])))


def overlay_png(image: object, flaws: Sequence[Flaw], *, valid: object = None, pad_px: int = 2) -> bytes:
    """Draw numbered boxes around the flaws on a grey rendering of the inspection image.

    Flaw ``k`` (1-based, in the order given: strongest first) is boxed in red and labelled ``k`` in yellow,
    matching the ``number`` column of flaws.csv / flaws.json.

    Parameters
    ----------
    image : ndarray of shape (M, N)
        The inspection image the flaw coordinates refer to.
    flaws : sequence of Flaw
        Found flaws; each `bbox` is (row0, col0, row1, col1), half-open, in `image` pixels.
    valid : ndarray of bool, shape (M, N), optional
        Pixels that carry data; the others are drawn mid grey.
    pad_px : int, default 2
        Gap between a flaw and its box, in image pixels, so the box does not hide the flaw.

    Returns
    -------
    bytes
        The PNG file contents (enlarged by a whole factor when the image is small).
    """
    flaws = v.records_named(flaws, "flaws", "Flaw")
    import cv2

    grey = to_uint8(image, valid=valid)
    factor = _enlargement(grey.shape)
    big = np.repeat(np.repeat(grey, factor, axis=0), factor, axis=1)
    canvas: UInt8Array = np.ascontiguousarray(cv2.cvtColor(big, cv2.COLOR_GRAY2BGR), dtype=np.uint8)
    for number, flaw in enumerate(flaws, start=1):
        _draw_flaw(canvas, flaw.bbox, number, factor=factor, pad_px=pad_px)
    return encode_png(canvas)


def _draw_flaw(
    canvas: UInt8Array, bbox: tuple[int, int, int, int], number: int, *, factor: int, pad_px: int
) -> None:
    import cv2

    row0, col0, row1, col1 = (int(v) for v in bbox)
    top_left = ((col0 - pad_px) * factor, (row0 - pad_px) * factor)
    bottom_right = ((col1 + pad_px) * factor - 1, (row1 + pad_px) * factor - 1)
    cv2.rectangle(canvas, top_left, bottom_right, _BOX_BGR, 1)
    label_xy = (bottom_right[0] + 2, max(top_left[1] + 8, 10))
    cv2.putText(canvas, str(number), label_xy, cv2.FONT_HERSHEY_SIMPLEX, 0.4, _LABEL_BGR, 1, cv2.LINE_AA)


def roc_png(
    curves: Sequence[RocCurve], *, title: str = "ROC", measured: Sequence[bool] | None = None
) -> bytes:
    """Plot P_D against P_F (log axis) for one or more ROC curves.

    Parameters
    ----------
    curves : sequence of RocCurve
        Curves to draw, each labelled by its `label`; a label containing "measured" is drawn as markers,
        theory as a line (seed §2.4: the ROC is the parametric plot of P_D versus P_F).
    title : str, default "ROC"
        Plot title.
    measured : sequence of bool, optional
        Per curve, whether it is measured (markers) or theory (a line); by default a curve is measured when
        its label contains "measured".

    Returns
    -------
    bytes
        The PNG file contents.
    """
    curves = v.records_named(curves, "curves", "RocCurve")
    _title(title)
    if measured is not None and not isinstance(measured, (list, tuple)):
        raise InputError(
            f"measured must be a list of bools, one per curve, or None; got {type(measured).__name__}."
        )
    # A bare Figure renders through the Agg canvas: no pyplot, so no GUI backend and no global figure state
    # (safe in the web console's threads too).
    from matplotlib.figure import Figure

    figure = Figure(figsize=(6.0, 4.5), dpi=100)
    axes = figure.subplots()
    if measured is None:
        measured = ["measured" in curve.label for curve in curves]
    if len(measured) != len(curves):
        raise InputError(f"measured must hold one flag per curve ({len(curves)}); got {len(measured)}.")
    for curve, is_measured in zip(curves, measured, strict=True):
        _plot_curve(axes, curve, measured=bool(is_measured))
    axes.set(xscale="log", xlabel="P_F (false alarms per pixel)", ylabel="P_D", title=title)
    axes.set_ylim(-0.02, 1.02)
    axes.set_xlim(left=_P_FALSE_ALARM_FLOOR / 2.0)
    axes.grid(True, which="both", alpha=0.3)
    axes.legend(loc="lower right", fontsize="small")
    return figure_png(figure)


def figure_png(figure: Any) -> bytes:
    """Render a matplotlib ``Figure`` (bare, on the Agg canvas) to PNG bytes, trimmed to its contents."""
    v.record_named(figure, "figure", "Figure")
    import io

    buffer = io.BytesIO()
    figure.savefig(buffer, format="png", bbox_inches="tight")
    return buffer.getvalue()


def _plot_curve(axes: Any, curve: RocCurve, *, measured: bool) -> None:
    p_false_alarm = np.asarray(curve.p_false_alarm, dtype=np.float64)
    p_detection = np.asarray(curve.p_detection, dtype=np.float64)
    seen = p_false_alarm > 0.0
    if not measured:
        axes.plot(p_false_alarm[seen], p_detection[seen], "-", label=curve.label)
        return
    (line,) = axes.plot(p_false_alarm[seen], p_detection[seen], "o", markersize=3, label=curve.label)
    if not seen.all():
        # A log axis cannot show P_F = 0 (no background pixel reached the threshold): such points are drawn
        # as left-pointing triangles on the axis floor, i.e. "P_F below anything this image can measure".
        floor = np.full(np.count_nonzero(~seen), _P_FALSE_ALARM_FLOOR)
        axes.plot(floor, p_detection[~seen], "<", color=line.get_color(), label=f"{curve.label}, P_F = 0")


def _uint8_picture(image: object, name: str) -> None:
    """Raise unless `image` is a uint8 grey (M, N) or colour (M, N, 3) picture, as OpenCV encodes."""
    shape: tuple[int, ...] = tuple(getattr(image, "shape", ()))
    fits = len(shape) == 2 or (len(shape) == 3 and shape[2] == 3)
    if not isinstance(image, np.ndarray) or image.dtype != np.uint8 or not fits or min(shape, default=0) < 1:
        raise InputError(
            f"{name} must be a uint8 array of shape (M, N) or (M, N, 3); got "
            f"{type(image).__name__} {getattr(image, 'dtype', '')} {shape}. Convert with to_uint8."
        )


def _title(title: object) -> None:
    if not isinstance(title, str):
        raise InputError(f"title must be a str; got {type(title).__name__} {title!r:.60}.")


_MAX_PICTURE_PX = 2**26
"""Most pixels an enlarged picture may have (64 M, 192 MB in colour): crops are enlarged to ~200 x 200."""


def _scale(scale_rc: object, pixels: int) -> tuple[int, int]:
    """`scale_rc` as two whole factors >= 1 that keep the picture under :data:`_MAX_PICTURE_PX`."""
    given = tuple(scale_rc) if isinstance(scale_rc, (tuple, list)) else ()
    factors = [item for item in given if isinstance(item, (int, np.integer)) and item >= 1]
    if len(given) != 2 or len(factors) != 2 or pixels * int(factors[0]) * int(factors[1]) > _MAX_PICTURE_PX:
        raise InputError(
            f"scale_rc must hold two whole factors >= 1 that keep the picture under {_MAX_PICTURE_PX} "
            f"pixels; got {scale_rc!r:.80}."
        )
    return int(factors[0]), int(factors[1])
