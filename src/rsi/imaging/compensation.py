"""Seed §2.2: ambient-light compensation, subtracting the ambient-lit data from the strobe-lit data.

Three ways, each returning a :class:`Compensated` image that looks as if only the strobe had lit the scene:

- :func:`compensate_interlaced` (intra-frame): only one field of an interlaced frame is strobe-lit; the
  ambient in each lit row is the mean of the unlit rows above and below. Costs half the vertical resolution
  and adds interpolation errors where the ambient bends (sharp shadow edges), reported as variance.
- :func:`compensate_field_pair`: two interlaced frames, the strobe in the odd then the even field. Every
  row is lit in one of them and unlit in the other, so each lit row's ambient is both interpolated and read,
  and the two estimates are weighed by what each may miss: full resolution, exact at shadow edges.
- :func:`compensate_two_frames`: a flash frame minus an ambient-only frame.

The subtraction is valid because the camera is linear (seed §2.1); it nearly doubles the noise power
(seed §2.2), which the result's ``variance`` map states pixel by pixel.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from rsi import _validate as v
from rsi.errors import InputError
from rsi.imaging.camera import (
    DEFAULT_CAMERA,
    BadPixelMap,
    CameraModel,
    Frame,
    _check_bad_pixels,
    _check_camera,
)

F32 = NDArray[np.float32]
BoolArray = NDArray[np.bool_]

_FIELD_PARITY = {"even": 0, "odd": 1}  # first lit row
# Three unlit rows are the fewest that give the ambient's vertical second difference.
_MIN_INTERLACED_ROWS = 6
# A curvature counts as real only beyond 3 noise sigmas: pure noise then adds < 1 % to the variance map.
_NOISE_SIGMAS_SQUARED = np.float32(9.0)
# A noise-free camera (variance 0 everywhere) would divide 0 by 0 in the estimates' weights.
_TINY_VARIANCE = np.float32(1e-12)


@dataclass(frozen=True)
class Compensated:
    """A strobe-only image estimated by ambient-light subtraction (seed §2.2), with its noise.

    Attributes
    ----------
    image : ndarray of shape (K, N), float32
        Strobe-only estimate in DN (black level cancelled). K = M // 2 for an interlaced frame, M otherwise.
    valid : ndarray of shape (K, N), bool
        False where a pixel entering the value was saturated or defective; its ``image`` value is meaningless.
    variance : ndarray of shape (K, N), float32
        Total noise variance in DN^2: sensor noise of every term subtracted plus ``interpolation_variance``.
    interpolation_variance : ndarray of shape (K, N), float32
        Part of ``variance`` due to interpolating the ambient between rows (0 for two-frame compensation).
    row_step : int
        Frame rows per output row: 2 for an intra-frame field image, 1 for two-frame compensation.
    lower_bound : ndarray of shape (K, N), bool, or None
        Of the pixels not ``valid``, those left out only because the strobe-lit reading reached the sensor's
        top while the ambient was read: there ``image`` is the top less the ambient, what the strobe returned
        *at least* (seed §2.1: the camera saturates and says so). None where this is not known.
    """

    image: F32
    valid: BoolArray
    variance: F32
    interpolation_variance: F32
    row_step: int
    lower_bound: BoolArray | None = None


MAX_DN = 1e15
"""Largest DN magnitude compensation accepts: it works in float32 (max 3.4e38) and squares second
differences of DN, so 1e15 keeps every square finite (any real camera reads under 2**32)."""


@dataclass(frozen=True)
class _Sensed:
    """One input frame in float32 DN, which pixels must not be used (of them, those that read the sensor's
    top and are no defect), and its sensor variance (DN^2)."""

    image: F32
    invalid: BoolArray
    variance: F32
    saturated: BoolArray


def _sense(
    data: object,
    name: str,
    camera: CameraModel | None,
    saturation_dn: float | None,
    bad_pixels: BadPixelMap | None,
) -> _Sensed:
    """Read a Frame (its camera, saturation and defects unless overridden) or a 2-D DN array."""
    frame = data if isinstance(data, Frame) else None
    if frame is not None:
        image = frame.raw.astype(np.float32)
        camera = frame.camera if camera is None else camera
        bad_pixels = frame.bad_pixels if bad_pixels is None else bad_pixels
    else:
        values = v.as_image(data, name)
        peak = float(np.max(np.abs(values)))
        if peak > MAX_DN:
            raise InputError(
                f"{name} holds a value of magnitude {peak:.3g} DN, over {MAX_DN:g}: compensation works in "
                "float32 and squares differences of DN, which would overflow. Pass the frame in DN."
            )
        image = values.astype(np.float32, copy=False)
        camera = DEFAULT_CAMERA if camera is None else camera
    _check_camera(camera)
    _check_bad_pixels(bad_pixels, image.shape)
    limit = (
        camera.max_dn if saturation_dn is None else v.in_range(saturation_dn, "saturation_dn", high=MAX_DN)
    )
    saturated = image >= np.float32(limit)
    if frame is not None:
        saturated |= frame.saturated
    invalid = saturated.copy()
    if bad_pixels is not None:
        invalid |= bad_pixels.defective
        saturated &= ~bad_pixels.defective
    return _Sensed(
        image=image, invalid=invalid, variance=camera.noise_variance_dn(image), saturated=saturated
    )


def compensate_two_frames(
    lit: Frame | NDArray[Any],
    ambient: Frame | NDArray[Any],
    *,
    camera: CameraModel | None = None,
    saturation_dn: float | None = None,
    bad_pixels: BadPixelMap | None = None,
) -> Compensated:
    """Subtract an ambient-only frame from a flash-lit frame of the same view (seed §2.2).

    Parameters
    ----------
    lit : Frame or ndarray of shape (M, N)
        Frame lit by ambient and strobe (a Frame must have ``lit_field="both"``), in DN.
    ambient : Frame or ndarray of shape (M, N)
        Frame lit by ambient only (a Frame must have ``lit_field="none"``), in DN.
    camera : CameraModel or None
        Noise model; None takes each Frame's camera, or ``CameraModel()`` for arrays.
    saturation_dn : float or None
        Readings at or above this are saturated; None uses the camera's ``max_dn``.
    bad_pixels : BadPixelMap or None
        Defects to mask; None takes each Frame's map.

    Returns
    -------
    Compensated
        Full-resolution (M, N) result with ``row_step=1`` and zero interpolation variance.
    """
    _require_field(lit, "lit", "both")
    _require_field(ambient, "ambient", "none")
    flash = _sense(lit, "lit", camera, saturation_dn, bad_pixels)
    dark = _sense(ambient, "ambient", camera, saturation_dn, bad_pixels)
    v.same_shape(flash.image, dark.image, ("lit", "ambient"))
    return Compensated(
        image=flash.image - dark.image,
        valid=~(flash.invalid | dark.invalid),
        variance=flash.variance + dark.variance,
        interpolation_variance=np.zeros_like(flash.image),
        row_step=1,
        lower_bound=flash.saturated & ~dark.invalid,
    )


def _require_field(data: object, name: str, expected: str) -> None:
    if isinstance(data, Frame) and data.lit_field != expected:
        raise InputError(
            f"{name} must be a frame with lit_field={expected!r}; got lit_field={data.lit_field!r}. "
            "For one interlaced frame with a strobe-lit field use compensate_interlaced."
        )


def compensate_interlaced(
    frame: Frame | NDArray[Any],
    *,
    lit_field: str | None = None,
    camera: CameraModel | None = None,
    saturation_dn: float | None = None,
    bad_pixels: BadPixelMap | None = None,
) -> Compensated:
    """Intra-frame compensation of an interlaced frame whose one field is strobe-lit (seed §2.2).

    Parameters
    ----------
    frame : Frame or ndarray of shape (M, N)
        The frame in DN, M >= 6. A Frame supplies its lit field, camera and defects; keywords override them.
    lit_field : {"odd", "even"} or None
        The strobe-lit field ("odd" = rows 1, 3, 5...); required for an array.
    camera : CameraModel or None
        Noise model; None takes the Frame's, or ``CameraModel()`` for an array.
    saturation_dn : float or None
        Readings at or above this are saturated; None uses the camera's ``max_dn``.
    bad_pixels : BadPixelMap or None
        Defects to mask; None takes the Frame's map.

    Returns
    -------
    Compensated
        Field image of shape (M // 2, N), ``row_step=2``; row k is frame row 2k + 1 (odd) or 2k (even).

    Notes
    -----
    Lit row r gets the ambient estimate ``(u[r-1] + u[r+1]) / 2``; at the frame edge the one neighbour. Its
    error is about ``-f''/2`` per row^2, i.e. half the second difference ``D`` of the unlit field (step two
    rows): exact in magnitude for a sharp shadow edge, the case the seed worries about, and zero for a linear
    ambient. The interpolation variance is the mean of ``D^2 / 4`` over the second differences centred on
    rows r-1 and r+1 (using rows r-3..r+3), each less nine times its own noise variance and floored at 0, so
    that sensor noise alone hardly adds to it. Edge rows use the first difference instead.
    """
    parity = _FIELD_PARITY[_lit_field(frame, lit_field)]
    rows = _lit_rows(_sense(frame, "frame", camera, saturation_dn, bad_pixels), parity)
    return Compensated(
        image=rows.lit - rows.ambient,
        valid=~(rows.lit_invalid | rows.ambient_invalid),
        variance=rows.lit_variance + rows.ambient_variance + rows.interpolation,
        interpolation_variance=rows.interpolation,
        row_step=2,
        lower_bound=rows.lit_saturated & ~rows.ambient_invalid,
    )


@dataclass(frozen=True)
class _LitRows:
    """One interlaced frame's lit rows and the ambient interpolated for them from its unlit rows (seed §2.2).

    ``ambient_variance`` is the sensor noise of the interpolated ambient, ``interpolation`` the squared error
    the interpolation is expected to make where the ambient bends (:func:`_interpolation_variance`).
    """

    lit: F32
    lit_variance: F32
    lit_invalid: BoolArray
    lit_saturated: BoolArray
    ambient: F32
    ambient_variance: F32
    ambient_invalid: BoolArray
    interpolation: F32


def _lit_rows(sensed: _Sensed, parity: int) -> _LitRows:
    total_rows = sensed.image.shape[0]
    if total_rows < _MIN_INTERLACED_ROWS:
        raise InputError(
            f"frame must have at least {_MIN_INTERLACED_ROWS} rows for intra-frame compensation; "
            f"got shape {sensed.image.shape}. Use compensate_two_frames for tiny images."
        )
    rows = total_rows // 2
    lit = slice(parity, parity + 2 * rows, 2)
    unlit = slice(1 - parity, None, 2)
    edges = (parity == 0, parity == 1 and total_rows % 2 == 0)  # lit rows with one unlit neighbour
    above, below = _neighbours(sensed.image[unlit], parity, rows)
    var_above, var_below = _neighbours(sensed.variance[unlit], parity, rows)
    bad_above, bad_below = _neighbours(sensed.invalid[unlit], parity, rows)
    return _LitRows(
        lit=sensed.image[lit],
        lit_variance=sensed.variance[lit],
        lit_invalid=sensed.invalid[lit],
        lit_saturated=sensed.saturated[lit],
        ambient=np.float32(0.5) * (above + below),
        ambient_variance=_ambient_variance(var_above, var_below, edges),
        ambient_invalid=bad_above | bad_below,
        interpolation=_interpolation_variance(
            sensed.image[unlit], sensed.variance[unlit], parity, rows, edges
        ),
    )


def compensate_field_pair(odd_lit: Frame, even_lit: Frame) -> Compensated:
    """Full-resolution strobe image from two interlaced frames whose strobes light opposite fields.

    Seed §2.2 intra-frame compensation halves the vertical resolution: a ~1 mm flaw that falls on the
    unlit rows is not in the field at all. The next video frame with the strobe on the other field fills
    those rows, each one still compensated within its own frame (no motion between the strobe and its
    ambient), so row r of the result is frame row r.

    Parameters
    ----------
    odd_lit, even_lit : Frame
        Two frames of the same view, of equal shape, the strobe in the odd and in the even field.

    Returns
    -------
    Compensated
        Image of the frames' shape, ``row_step=1`` (odd rows from `odd_lit`, even rows from `even_lit`).

    Raises
    ------
    InputError
        If either is not a Frame, their lit fields are not odd and even, or their shapes differ.
    """
    for frame, name, expected in ((odd_lit, "odd_lit", "odd"), (even_lit, "even_lit", "even")):
        if not isinstance(frame, Frame):
            raise InputError(f"{name} must be an rsi.imaging.camera.Frame; got {type(frame).__name__}.")
        if frame.lit_field != expected:
            raise InputError(
                f"{name} must have its strobe in the {expected} field; got lit_field={frame.lit_field!r}."
            )
    if odd_lit.raw.shape != even_lit.raw.shape:
        raise InputError(
            "odd_lit and even_lit must have the same shape; "
            f"got {odd_lit.raw.shape} and {even_lit.raw.shape}."
        )
    odd, even = (
        _sense(frame, name, None, None, None)
        for frame, name in ((odd_lit, "odd_lit"), (even_lit, "even_lit"))
    )
    rows = odd_lit.raw.shape[0]
    (odd_rows, odd_bound), (even_rows, even_bound) = (
        _with_other_frame(odd, even, parity=1),
        _with_other_frame(even, odd, parity=0),
    )

    def woven(odd_part: NDArray[Any], even_part: NDArray[Any]) -> NDArray[Any]:
        out = np.empty((rows, *odd_part.shape[1:]), dtype=odd_part.dtype)
        out[1::2] = odd_part[: len(range(1, rows, 2))]
        out[0::2] = even_part[: len(range(0, rows, 2))]
        return out

    return Compensated(
        image=woven(odd_rows.image, even_rows.image),
        valid=woven(odd_rows.valid, even_rows.valid),
        variance=woven(odd_rows.variance, even_rows.variance),
        interpolation_variance=woven(odd_rows.interpolation_variance, even_rows.interpolation_variance),
        row_step=1,
        lower_bound=woven(odd_bound, even_bound),
    )


def _with_other_frame(frame: _Sensed, other: _Sensed, *, parity: int) -> tuple[Compensated, BoolArray]:
    """`frame`'s lit rows less their ambient, estimated twice and weighted by what each estimate may miss,
    and where that is a lower bound (:attr:`Compensated.lower_bound`).

    Seed §2.2: the ambient of a lit row is interpolated from the unlit rows around it, which misses where
    the ambient bends (a sun-shadow edge along the rows). The other frame, its strobe in the other field,
    read the very same row under the ambient alone, 1/30 s later: exact while the camera holds still (the
    interlaced fields already assume that for 1/60 s), at the cost of one row's noise instead of the mean of
    two. Their difference measures the interpolation's error at each pixel (less both noises, floored at 0,
    the larger of it and the unlit field's own estimate kept); each estimate is then weighted by the inverse
    of its expected squared error. Where the ambient is smooth the two average (a third of one row's noise
    variance); at a shadow edge the other frame's row takes over; each pass's own edges count, whatever sun
    the other pass had. ``interpolation_variance`` is what remains of the interpolation error.
    """
    rows = _lit_rows(frame, parity)
    count = rows.lit.shape[0]
    row_of = slice(parity, parity + 2 * count, 2)
    twin, twin_variance = other.image[row_of], other.variance[row_of]
    twin_invalid = other.invalid[row_of]
    missed = _excess_square(rows.ambient - twin, rows.ambient_variance + twin_variance)
    error = np.maximum(rows.interpolation, missed)
    interpolated = np.where(rows.ambient_invalid, np.float32(np.inf), rows.ambient_variance + error)
    weight = np.where(
        twin_invalid,
        np.float32(1.0),
        twin_variance / np.maximum(twin_variance + interpolated, _TINY_VARIANCE),
    ).astype(np.float32)
    weight = np.where(rows.ambient_invalid, np.float32(0.0), weight).astype(np.float32)
    ambient = weight * np.where(rows.ambient_invalid, 0.0, rows.ambient) + (1 - weight) * np.where(
        twin_invalid, 0.0, twin
    )
    residual = (weight * weight * np.where(rows.ambient_invalid, 0.0, error)).astype(np.float32)
    noise = weight * weight * np.where(rows.ambient_invalid, 0.0, rows.ambient_variance) + (
        1 - weight
    ) ** 2 * np.where(twin_invalid, 0.0, twin_variance)
    ambient_invalid = rows.ambient_invalid & twin_invalid
    compensated = Compensated(
        image=(rows.lit - ambient).astype(np.float32),
        valid=~(rows.lit_invalid | ambient_invalid),
        variance=(rows.lit_variance + noise + residual).astype(np.float32),
        interpolation_variance=residual,
        row_step=1,
    )
    return compensated, rows.lit_saturated & ~ambient_invalid


def _lit_field(frame: object, lit_field: str | None) -> str:
    if lit_field is None:
        if not isinstance(frame, Frame):
            raise InputError(
                "lit_field is required when frame is an array; pass lit_field='odd' or lit_field='even'."
            )
        lit_field = frame.lit_field
        if lit_field not in _FIELD_PARITY:
            raise InputError(
                f"frame has lit_field={lit_field!r}, but intra-frame compensation needs one strobe-lit field "
                "('odd' or 'even'). Use compensate_two_frames(lit, ambient) for whole-frame flashes."
            )
    return v.choice(lit_field, "lit_field", _FIELD_PARITY)


def _neighbours(field: NDArray[Any], parity: int, rows: int) -> tuple[NDArray[Any], NDArray[Any]]:
    """Rows of the unlit `field` just above and just below each of the first `rows` lit rows.

    Unlit row j is frame row 2j + 1 - parity, so lit row k (frame row 2k + parity) lies between unlit rows
    k + parity - 1 and k + parity. Edge padding makes a lit row on the frame edge get its one neighbour twice.
    """
    padded = _pad_edges(field)
    return padded[parity : parity + rows], padded[parity + 1 : parity + 1 + rows]


def _pad_edges(field: NDArray[Any]) -> NDArray[Any]:
    return np.concatenate([field[:1], field, field[-1:]])


def _ambient_variance(var_above: F32, var_below: F32, edges: tuple[bool, bool]) -> F32:
    """Variance of the ambient estimate: a mean of two independent rows, or one row on the frame edge."""
    variance = np.float32(0.25) * (var_above + var_below)
    if edges[0]:
        variance[0] = var_above[0]
    if edges[1]:
        variance[-1] = var_below[-1]
    return variance


def _excess_square(value: F32, variance: F32) -> F32:
    """value^2 less its expected noise part (three sigmas), floored at 0: a de-noised squared error."""
    excess: F32 = value * value
    excess -= _NOISE_SIGMAS_SQUARED * variance
    np.maximum(excess, 0, out=excess)
    return excess


def _interpolation_variance(
    unlit: F32, unlit_var: F32, parity: int, rows: int, edges: tuple[bool, bool]
) -> F32:
    """Squared interpolation error expected in each lit row, from the unlit field's shape (seed §2.2)."""
    second = unlit[:-2] - 2 * unlit[1:-1] + unlit[2:]
    second_var = unlit_var[:-2] + 4 * unlit_var[1:-1] + unlit_var[2:]
    # error ~ D / 2 for a sharp edge; mean of the squares centred on rows r-1 and r+1 keeps a step's full size
    centred = _pad_edges(_excess_square(second, second_var))
    above, below = _neighbours(centred, parity, rows)
    variance: F32 = np.float32(0.125) * (above + below)
    # a lit row on the frame edge has one neighbour: its error is the slope over one row, ~ first diff. / 2
    if edges[0]:
        variance[0] = 0.25 * _excess_square(unlit[1] - unlit[0], unlit_var[1] + unlit_var[0])
    if edges[1]:
        variance[-1] = 0.25 * _excess_square(unlit[-1] - unlit[-2], unlit_var[-1] + unlit_var[-2])
    return variance
