"""Reference-to-inspection image registration (seed §2.3).

The viewpoint of an inspection image never repeats the reference's exactly; left uncorrected, the
mis-registration shows up as false edges in the difference image. :func:`register` finds the warp, gain and
bias that best map the reference onto the inspection by Gauss-Newton least squares, coarse to fine, and
reports the residual mis-registration that the detector must then treat as noise (seed §2.4). A robot keeps
its references: :func:`prepare_reference` computes once what depends on the reference alone, and
:func:`register` accepts the result in place of the reference image.
"""

from __future__ import annotations

import dataclasses
import itertools
import time
from collections.abc import Callable
from dataclasses import dataclass
from functools import partial

import cv2
import numpy as np
from numpy.typing import NDArray

from rsi._validate import as_intensity_image, as_mask, choice, in_range, intensity_range, positive_int
from rsi.errors import InputError
from rsi.imaging._gauss_newton import Settings, Terms, reference_terms, solve_level
from rsi.imaging._local import TOLERANCE_PX, LocalField, estimate_field
from rsi.imaging._pyramid import (
    Estimate,
    Level,
    coarse_to_fine,
    inspection_pyramid,
    level_count,
    reference_pyramid,
    smooth,
)
from rsi.imaging._warps import (
    WARP_MODELS,
    Allocate,
    Image,
    Matrix,
    is_translation,
    owned,
    rescale,
    sample,
    scratch,
)

__all__ = [
    "MODELS",
    "REGISTRATION_MODELS",
    "LocalField",
    "PreparedReference",
    "Registration",
    "prepare_reference",
    "register",
]

# One global motion each (a 3x3 matrix).
MODELS = ("translation", "euclidean", "similarity", "affine", "homography")
# Everything register accepts: the global models and "local", an affine fit plus a smooth displacement field
# (seed §2.3: small mis-registrations are locally translational).
LOCAL_MODEL = "local"
REGISTRATION_MODELS = (*MODELS, LOCAL_MODEL)
_LOCAL_GLOBAL_MODEL = "affine"
_DEFAULT_TILE_PX = 64

# Preimages this close outside the reference still count as inside (round-off of the inverse warp).
_EDGE_TOLERANCE_PX = 1e-6
Mask = NDArray[np.bool_]
Guess = NDArray[np.float64] | None  # where along each row a coordinate reaches a level; None: nowhere


def _as_float32(image: object, name: str) -> Image:
    # Images are float32 on this hot path (docs: dtype policy); parameters and sums stay float64.
    return np.asarray(as_intensity_image(image, name), dtype=np.float32)


def _checked_float32(image: object, name: str) -> tuple[Image, tuple[float, float] | None]:
    """:func:`_as_float32` and the image's (min, max) when the check's are its own (no conversion)."""
    checked, low, high = intensity_range(image, name)
    converted = np.asarray(checked, dtype=np.float32)
    return converted, ((low, high) if converted is checked else None)


@dataclass(frozen=True)
class Registration:
    """A registration of a reference image to an inspection image.

    Attributes
    ----------
    model : str
        One of :data:`REGISTRATION_MODELS`.
    matrix : ndarray of shape (3, 3), float64, read-only
        Maps a reference pixel ``(x, y, 1)`` (x = column, y = row) to inspection pixel coordinates
        (homogeneous: divide by the third component). For ``model="local"``, the global affine fit.
    gain, bias : float
        Photometric fit, ``inspection ~= gain * reference + bias`` (1 and 0 when not fitted).
    converged : bool
        Whether the last update at the finest level refined (full resolution by default) was below the
        tolerance.
    reason : str
        "converged", "max_iterations", "deadline" or "diverged"; "flat_reference" or "flat_inspection" when an
        image has one value everywhere (no texture: nothing to register, the identity is returned).
    iterations : int
        Gauss-Newton iterations over all pyramid levels.
    residual_rms : float
        RMS of ``inspection - (gain * reference + bias)`` after warping, over the pixels used (lightly
        smoothed images, outliers trimmed), inspection units.
    shift_std_px : tuple of float
        (sx, sy): standard deviation of the translation of the reference centre, from ``sigma^2 H^-1`` at the
        finest level reached; the residual mis-registration the detector turns into noise (seed §2.4).
    elapsed_s : float
        Wall time of :func:`register`.
    local : LocalField or None
        For ``model="local"``: the displacement field on top of `matrix`, its per-tile uncertainty and the
        tiles that fell back to the global fit.
    """

    model: str
    matrix: Matrix
    gain: float
    bias: float
    converged: bool
    reason: str
    iterations: int
    residual_rms: float
    shift_std_px: tuple[float, float]
    elapsed_s: float
    local: LocalField | None = None

    def __post_init__(self) -> None:
        matrix = np.array(self.matrix, dtype=np.float64)
        matrix.setflags(write=False)
        object.__setattr__(self, "matrix", matrix)

    @property
    def translation_xy(self) -> tuple[float, float]:
        """(dx, dy): where the reference origin lands in the inspection, in pixels."""
        return float(self.matrix[0, 2] / self.matrix[2, 2]), float(self.matrix[1, 2] / self.matrix[2, 2])

    def warp(
        self,
        reference: NDArray[np.generic],
        *,
        output_shape: tuple[int, int] | None = None,
        photometric: bool = True,
    ) -> tuple[Image, NDArray[np.bool_]]:
        """Resample `reference` into the inspection frame (bilinear).

        Parameters
        ----------
        reference : ndarray of shape (M, N)
            The reference image registered.
        output_shape : tuple of int, optional
            (rows, cols) of the inspection frame; defaults to (M, N).
        photometric : bool
            Apply ``gain * reference + bias``.

        Returns
        -------
        warped : ndarray of shape output_shape, float32
            The reference as the inspection would see it; 0 where not valid.
        valid : ndarray of shape output_shape, bool
            Pixels whose preimage lies inside the reference.
        """
        image = _as_float32(reference, "reference")
        shape = image.shape if output_shape is None else _output_shape(output_shape)
        inverse = np.asarray(np.linalg.inv(self.matrix), dtype=np.float64)
        if self.local is None:
            warped = sample(image, inverse, (0, shape[0], 0, shape[1]))
            valid = _preimage_inside(inverse, shape, image.shape)
        else:
            warped, valid = _warp_local(image, self.matrix, self.local, (int(shape[0]), int(shape[1])))
        # warped is this call's own array: the photometric map and the mask are applied in place. A gain of
        # 1 (no photometric fit) changes no value, not even a -0: its pass is skipped.
        if photometric:
            if self.gain != 1.0:
                np.multiply(warped, np.float32(self.gain), out=warped)
            np.add(warped, np.float32(self.bias), out=warped)
        warped[~valid] = 0.0
        return warped, valid


@dataclass(frozen=True)
class PreparedReference:
    """What registering to one reference needs from the reference alone, computed once.

    Seed §2.3: "terms involving the Jacobian matrix ... can be pre-computed resulting in significant run-time
    computational savings". Made by :func:`prepare_reference`; pass it to :func:`register` in place of the
    reference image to register many inspections to one stored reference. Its arrays are read-only.

    Attributes
    ----------
    model : str
        The motion model it was prepared for, one of :data:`MODELS`.
    photometric : bool
        Whether gain and bias are fitted.
    masked : bool
        Whether a mask was given.
    images : tuple of ndarray, float32
        The smoothed pyramid, finest (M, N) first.
    masks : tuple of (ndarray of bool or None)
        The usable pixels of each level (None without a mask).
    terms : tuple of Terms
        Per level, the steepest-descent images on its whole frame and their Hessian.
    row_step : int or None
        The rows sampled (:func:`register`'s `row_step`).
    presmooth : bool
        Whether the full resolution was smoothed before the pyramid (:func:`register`'s `presmooth`).
    """

    model: str
    photometric: bool
    masked: bool
    images: tuple[Image, ...]
    masks: tuple[NDArray[np.bool_] | None, ...]
    terms: tuple[Terms, ...]
    row_step: int | None = None
    presmooth: bool = True

    @property
    def shape(self) -> tuple[int, int]:
        """(M, N) of the reference."""
        rows, cols = self.images[0].shape
        return rows, cols


def prepare_reference(
    reference: NDArray[np.generic],
    *,
    model: str = "translation",
    photometric: bool = True,
    mask: NDArray[np.generic] | None = None,
    row_step: int | None = None,
    presmooth: bool = True,
) -> PreparedReference:
    """Precompute the reference side of :func:`register`: its pyramid, Jacobian and Hessian per level.

    Parameters
    ----------
    reference : ndarray of shape (M, N)
        Reference image (float32, float64, integer or bool; finite).
    model : str
        Motion model, one of :data:`MODELS`.
    photometric : bool
        Also fit ``inspection ~= gain * reference + bias``.
    mask : ndarray of shape (M, N), bool, optional
        Reference pixels that may be used (True = use).
    row_step : int, optional
        Rows sampled, as :func:`register`'s `row_step`.
    presmooth : bool
        Smooth the full resolution before the pyramid, as :func:`register`'s `presmooth`.

    Returns
    -------
    PreparedReference
        ``register(prepared, inspection)`` gives the same registration as
        ``register(reference, inspection, model=model, photometric=photometric, mask=mask)``, which itself
        prepares the reference on every call.

    Raises
    ------
    InputError
        For an argument of the wrong type, shape, dtype or range.

    Examples
    --------
    >>> import numpy as np, scipy.ndimage as ndi
    >>> reference = ndi.gaussian_filter(np.random.default_rng(0).random((128, 128)), 2.0)
    >>> prepared = prepare_reference(reference)
    >>> inspection = ndi.shift(reference, (-2.2, 3.7), mode="reflect")
    >>> [round(v, 1) for v in register(prepared, inspection).translation_xy]
    [3.7, -2.2]
    """
    image = _as_float32(reference, "reference")
    return _prepare(
        image,
        model,
        photometric,
        mask,
        level_count(image.shape),
        allocate=owned,
        row_step=_chosen_row_step(row_step),
        presmooth=_flag(presmooth, "presmooth"),
    )


def _prepare(
    image: Image,
    model: str,
    photometric: object,
    mask: object,
    count: int,
    *,
    allocate: Allocate,
    finest: int = 0,
    row_step: int | None = None,
    presmooth: bool = True,
) -> PreparedReference:
    """Prepare the reference in arrays from `allocate`: owned ones, or scratch for one cold call.

    With `finest` > 0 (a cold call that stops above full resolution) only the levels from `finest` down are
    kept, and only theirs get terms: the result is the prepared reference of the image `finest` times halved.
    """
    model = choice(model, "model", MODELS)
    if not isinstance(photometric, (bool, np.bool_)):
        raise InputError(f"photometric must be True or False; got {photometric!r}.")
    user_mask = None if mask is None else as_mask(mask, "mask", image.shape)
    images, masks = reference_pyramid(image, user_mask, count, allocate, presmooth)
    if finest == 0 and not presmooth:
        # The full resolution as it is was the caller's array: the prepared reference keeps its own copy.
        own = allocate("reference0", image.shape, np.float32)
        np.copyto(own, image)
        images[0] = own
    images, masks = images[finest:], masks[finest:]
    for level in images:
        level.setflags(write=False)
    terms = tuple(
        reference_terms(
            level,
            level_mask,
            WARP_MODELS[model],
            bool(photometric),
            allocate=allocate,
            role=f"jacobian{index}",
            row_step=row_step,
        )
        for index, (level, level_mask) in enumerate(zip(images, masks, strict=True))
    )
    return PreparedReference(
        model,
        bool(photometric),
        user_mask is not None,
        tuple(images),
        tuple(masks),
        terms,
        row_step,
        presmooth,
    )


def _flag(value: object, name: str) -> bool:
    if not isinstance(value, (bool, np.bool_)):
        raise InputError(f"{name} must be True or False; got {value!r}.")
    return bool(value)


def _chosen_row_step(row_step: object) -> int | None:
    """None (every row; every other on levels of 512 rows or more), or an int >= 1."""
    return None if row_step is None else positive_int(row_step, "row_step")


def _from_level(prepared: PreparedReference, finest: int) -> PreparedReference:
    """A prepared reference's levels from `finest` down: that of the reference `finest` times halved."""
    if finest == 0:
        return prepared
    return dataclasses.replace(
        prepared,
        images=prepared.images[finest:],
        masks=prepared.masks[finest:],
        terms=prepared.terms[finest:],
    )


def _finest_level(finest_level: object, count: int) -> int:
    """The finest level refined: `finest_level`, or the coarsest of the `count` levels if that is coarser."""
    return min(positive_int(finest_level, "finest_level", minimum=0), count - 1)


def _level_count(coarsest_level: object, finest_level: int, count: int) -> int:
    """Levels built: the pyramid's `count`, or fewer so that the coarsest is `coarsest_level` (None: all)."""
    if coarsest_level is None:
        return count
    coarsest = positive_int(coarsest_level, "coarsest_level", minimum=0)
    if coarsest < finest_level:
        raise InputError(
            f"coarsest_level={coarsest} is finer than finest_level={finest_level}. Pass a coarsest_level "
            "at least finest_level, or None for the whole pyramid."
        )
    return min(count, coarsest + 1)


def _check_prepared(
    prepared: PreparedReference,
    model: object,
    photometric: object,
    mask: object,
    *,
    row_step: object,
    presmooth: object,
) -> None:
    """A prepared reference fixes the model, the photometric fit, the mask, the rows sampled and the
    smoothing: the call may not differ."""
    if presmooth is not None and _flag(presmooth, "presmooth") is not prepared.presmooth:
        raise InputError(
            f"presmooth={presmooth!r} differs from the prepared reference's "
            f"presmooth={prepared.presmooth!r}. Omit presmooth, or prepare the reference with "
            "prepare_reference(reference, presmooth=...)."
        )
    if row_step is not None and _chosen_row_step(row_step) != prepared.row_step:
        raise InputError(
            f"row_step={row_step!r} differs from the prepared reference's row_step={prepared.row_step!r}. "
            "Omit row_step, or prepare the reference with prepare_reference(reference, row_step=...)."
        )
    if model is not None and choice(model, "model", MODELS) != prepared.model:
        raise InputError(
            f"model={model!r} differs from the prepared reference's model={prepared.model!r}. Omit model, or "
            f"prepare the reference with prepare_reference(reference, model={model!r})."
        )
    if photometric is not None and photometric is not prepared.photometric:
        raise InputError(
            f"photometric={photometric!r} differs from the prepared reference's "
            f"photometric={prepared.photometric!r}. Omit photometric, or prepare the reference with it."
        )
    if mask is not None:
        raise InputError(
            "mask cannot be passed with a prepared reference: its mask is fixed when it is prepared. Pass it "
            "to prepare_reference(reference, mask=...) instead."
        )


def _preimage_inside(
    inverse: Matrix, shape: tuple[int, int], source_shape: tuple[int, ...]
) -> NDArray[np.bool_]:
    """Pixels of an image of `shape` whose preimage under `inverse` lies inside `source_shape` (M, N)."""
    if is_translation(inverse):
        return _shifted_inside(inverse[0, 2], inverse[1, 2], shape, source_shape)
    if inverse[2, 0] == 0.0 and inverse[2, 1] == 0.0:
        return _affine_inside(inverse, shape, source_shape)
    cols = np.arange(shape[1], dtype=np.float64)[None, :]
    rows = np.arange(shape[0], dtype=np.float64)[:, None]
    denominator = inverse[2, 0] * cols + inverse[2, 1] * rows + inverse[2, 2]
    valid = np.broadcast_to(denominator > 0, shape).copy()
    for axis in (0, 1):
        coordinate = (inverse[axis, 0] * cols + inverse[axis, 1] * rows + inverse[axis, 2]) / denominator
        high = source_shape[1 - axis] - 1 + _EDGE_TOLERANCE_PX
        valid &= (coordinate >= -_EDGE_TOLERANCE_PX) & (coordinate <= high)
    return valid


def _affine_inside(
    inverse: Matrix, shape: tuple[int, int], source_shape: tuple[int, ...]
) -> NDArray[np.bool_]:
    """`_preimage_inside` for an affine map: one run of columns per row, its ends found exactly.

    Along a row the preimage coordinate ``(a * col + b * row + t) / i`` is monotonic in the column, in
    floating point too (each rounding is monotonic), so the pixels whose preimage lies inside are one run.
    Its ends are found with the general path's own expression (:func:`_first_true`), which gives that path's
    mask bit for bit (a test checks it) from a few evaluations per row instead of one per pixel: the general
    path's full-size float64 temporaries made it a sixth of ``detect`` on a 640 x 640 pair.
    """
    if not inverse[2, 2] > 0:
        return np.zeros(shape, dtype=bool)  # the general path's denominator > 0 fails everywhere
    rows = np.arange(shape[0], dtype=np.float64)
    start = np.zeros(shape[0], dtype=np.int64)
    stop = np.full(shape[0], shape[1], dtype=np.int64)
    for axis in (0, 1):
        low, high = -_EDGE_TOLERANCE_PX, source_shape[1 - axis] - 1 + _EDGE_TOLERANCE_PX
        slope, offset = inverse[axis, 0], inverse[axis, 1] * rows + inverse[axis, 2]

        def beyond(level: float, above: bool, axis: int = axis) -> Callable[[NDArray[np.int64]], Mask]:
            def test(cols: NDArray[np.int64]) -> Mask:
                # The general path's expression, at one column per row.
                mapped = (
                    inverse[axis, 0] * cols.astype(np.float64) + inverse[axis, 1] * rows + inverse[axis, 2]
                )
                coordinate = mapped / inverse[2, 2]
                return np.asarray(coordinate >= level if above else coordinate <= level, dtype=bool)

            return test

        def near(level: float, slope: float = slope, offset: NDArray[np.float64] = offset) -> Guess:
            # Where along each row the coordinate reaches `level`, in real numbers; None: the same everywhere.
            return None if slope == 0 else (level * inverse[2, 2] - offset) / slope

        # Just past the high end is "not <= high", just before the low end "not >= low".
        if slope >= 0:  # non-decreasing along the row (constant included)
            first = _first_true(beyond(low, True), near(low), shape)
            end = _first_true(_negated(beyond(high, False)), near(high), shape)
        else:
            first = _first_true(beyond(high, False), near(high), shape)
            end = _first_true(_negated(beyond(low, True)), near(low), shape)
        start, stop = np.maximum(start, first), np.minimum(stop, end)
    return _row_runs(start, stop, shape)


def _row_runs(start: NDArray[np.int64], stop: NDArray[np.int64], shape: tuple[int, int]) -> Mask:
    """True at columns ``start[r] <= col < stop[r]`` of each row r (both in [0, shape[1]]).

    An affine warp's runs change at a few rows only (by a column each, as a tilted edge crosses the columns):
    each band of rows with the same run is written with three slices. Should the runs change at most rows
    (a strongly rotated warp), one slice per row.
    """
    rows = shape[0]
    changes = np.flatnonzero((start[1:] != start[:-1]) | (stop[1:] != stop[:-1])) + 1
    if changes.size > rows // _BANDS_PER_ROW:
        valid = np.zeros(shape, dtype=bool)
        for row, (first_col, end_col) in enumerate(zip(start.tolist(), stop.tolist(), strict=True)):
            valid[row, first_col:end_col] = True
        return valid
    valid = np.empty(shape, dtype=bool)
    bounds = [0, *changes.tolist(), rows]
    for top, bottom in itertools.pairwise(bounds):
        first_col = int(start[top])
        end_col = max(first_col, int(stop[top]))
        valid[top:bottom, :first_col] = False
        valid[top:bottom, first_col:end_col] = True
        valid[top:bottom, end_col:] = False
    return valid


# Bands of equal runs are written at once while there are at most a quarter as many as rows.
_BANDS_PER_ROW = 4


def _negated(
    predicate: Callable[[NDArray[np.int64]], NDArray[np.bool_]],
) -> Callable[[NDArray[np.int64]], NDArray[np.bool_]]:
    return lambda cols: ~predicate(cols)


_PROBES = 5


def _first_true(
    predicate: Callable[[NDArray[np.int64]], NDArray[np.bool_]],
    guess: Guess,
    shape: tuple[int, int],
) -> NDArray[np.int64]:
    """Per row, the first column where `predicate` holds (shape[1] where none).

    `predicate(cols)` is evaluated at one column per row, and must be false, then true, along each row.
    Five columns around `guess` (the crossing in real numbers; None: the predicate is the same along
    each row) settle every row where they bracket the
    change (false just before the first true, or the row's start; none true up to the row's end); should
    any row not be settled (a guess off by rounding far from the usual), every row is bisected.
    """
    size = shape[1]
    if guess is None:  # constant along each row
        return np.where(predicate(np.zeros(shape[0], dtype=np.int64)), 0, size).astype(np.int64)
    base = np.clip(np.floor(np.nan_to_num(guess, nan=0.0, posinf=size, neginf=0.0)), 0, size) - 1
    probes = [np.clip(base + k, 0, size - 1).astype(np.int64) for k in range(_PROBES)]
    first = np.full(shape[0], size, dtype=np.int64)
    for cols in reversed(probes):
        first = np.where(predicate(cols), cols, first)
    settled = np.where(first < size, (first == 0) | (first > probes[0]), probes[-1] == size - 1)
    if settled.all():
        return first
    low, high = np.zeros(shape[0], dtype=np.int64), np.full(shape[0], size, dtype=np.int64)
    while np.any(low < high):
        middle = (low + high) // 2
        # Rows already settled (low == high) probe a column inside the image and keep their answer.
        holds = predicate(np.minimum(middle, size - 1))
        open_rows = low < high
        high = np.where(open_rows & holds, middle, high)
        low = np.where(open_rows & ~holds, middle + 1, low)
    return low


def _shifted_inside(
    dx: float, dy: float, shape: tuple[int, int], source_shape: tuple[int, ...]
) -> NDArray[np.bool_]:
    """`_preimage_inside` for a pure shift: a rectangle, found without mapping every pixel."""
    valid = np.zeros(shape, dtype=bool)
    spans = []
    for offset, size, source_size in ((dy, shape[0], source_shape[0]), (dx, shape[1], source_shape[1])):
        first = max(0, int(np.ceil(-_EDGE_TOLERANCE_PX - offset)))
        last = min(size, int(np.floor(source_size - 1 + _EDGE_TOLERANCE_PX - offset)) + 1)
        spans.append(slice(first, max(first, last)))
    valid[spans[0], spans[1]] = True
    return valid


def _warp_local(
    image: Image, matrix: Matrix, local: LocalField, shape: tuple[int, int]
) -> tuple[Image, NDArray[np.bool_]]:
    """Resample `image` where each inspection pixel's preimage lies under the global fit and the field."""
    map_x, map_y = local.source_maps(matrix, shape)
    warped = cv2.remap(image, map_x, map_y, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)
    high_x, high_y = image.shape[1] - 1 + _EDGE_TOLERANCE_PX, image.shape[0] - 1 + _EDGE_TOLERANCE_PX
    valid = (
        (map_x >= -_EDGE_TOLERANCE_PX)
        & (map_y >= -_EDGE_TOLERANCE_PX)
        & (map_x <= high_x)
        & (map_y <= high_y)
    )
    return np.asarray(warped, dtype=np.float32), np.asarray(valid, dtype=bool)


def _output_shape(output_shape: object) -> tuple[int, int]:
    values = tuple(output_shape) if isinstance(output_shape, (tuple, list)) else ()
    if len(values) != 2 or not all(isinstance(v, (int, np.integer)) and v >= 1 for v in values):
        raise InputError(f"output_shape must be (rows, cols) of positive ints; got {output_shape!r}.")
    return int(values[0]), int(values[1])


def _start(initial: object, photometric: bool) -> Estimate | None:
    """The start estimate from a Registration, a 3x3 matrix or None (phase correlation)."""
    if initial is None:
        return None
    gain, bias = 1.0, 0.0
    if isinstance(initial, Registration):
        matrix = np.array(initial.matrix, dtype=np.float64)
        if photometric:
            gain, bias = initial.gain, initial.bias
    else:
        try:
            matrix = np.array(initial, dtype=np.float64)
        except (TypeError, ValueError):
            matrix = np.zeros(0)
        if matrix.shape != (3, 3):
            raise InputError(
                f"initial must be a 3x3 matrix (reference pixel -> inspection pixel) or a Registration; "
                f"got shape {matrix.shape}. For a shift (dx, dy) pass [[1, 0, dx], [0, 1, dy], [0, 0, 1]]."
            )
    if not np.isfinite(matrix).all() or abs(np.linalg.det(matrix)) < 1e-12 or matrix[2, 2] == 0:
        raise InputError(
            f"initial must be a finite, invertible 3x3 matrix with initial[2, 2] != 0; got {matrix}."
        )
    return Estimate(matrix / matrix[2, 2], gain=gain, bias=bias)


def _flat_image(
    reference: PreparedReference, inspection: Image, inspection_span: tuple[float, float] | None
) -> str | None:
    """Which image, if any, holds one value everywhere: no gradient, so no warp can be told from another.
    `inspection_span`: the inspection's (min, max) when its check found them."""
    if reference.images[0].min() == reference.images[0].max():
        return "reference"
    low, high = inspection_span if inspection_span is not None else (inspection.min(), inspection.max())
    return "inspection" if low == high else None


def _untextured(flat: str, reference: PreparedReference, inspection: Image, started: float) -> Registration:
    """The honest answer for an untextured pair: not converged, identity warp, the reason named."""
    return Registration(
        model=reference.model,
        matrix=np.eye(3),
        gain=1.0,
        bias=0.0,
        converged=False,
        reason=f"flat_{flat}",
        iterations=0,
        residual_rms=float(np.std(inspection, dtype=np.float64)),
        # No gradient: a shift changes no prediction of the flat image, so it adds no noise either.
        shift_std_px=(0.0, 0.0),
        elapsed_s=time.perf_counter() - started,
    )


def register(
    reference: NDArray[np.generic] | PreparedReference,
    inspection: NDArray[np.generic],
    *,
    model: str | None = None,
    photometric: bool | None = None,
    mask: NDArray[np.generic] | None = None,
    max_iterations: int = 50,
    tolerance: float = 1e-3,
    deadline_s: float | None = None,
    initial: NDArray[np.floating] | Registration | None = None,
    tile_px: int | None = None,
    field_tolerance_px: float | None = None,
    finest_level: int = 0,
    coarsest_level: int | None = None,
    row_step: int | None = None,
    presmooth: bool | None = None,
) -> Registration:
    """Register `reference` to `inspection` by coarse-to-fine inverse-compositional Gauss-Newton.

    Parameters
    ----------
    reference : ndarray of shape (M, N) or PreparedReference
        Reference image (float32, float64, integer or bool; finite), or one made by
        :func:`prepare_reference`, which saves its share of the work on every call (the result is the same).
    inspection : ndarray of shape (P, Q)
        Inspection image; its shape may differ from the reference's.
    model : str, optional
        Motion model, one of :data:`REGISTRATION_MODELS`; "translation" by default, or the prepared
        reference's model (another one raises). ``"local"``: the affine fit (or the prepared reference's
        model), then a smooth displacement field from overlapping tiles (``Registration.local``).
    photometric : bool, optional
        Also fit ``inspection ~= gain * reference + bias``; True by default, or the prepared reference's
        choice (another one raises).
    mask : ndarray of shape (M, N), bool, optional
        Reference pixels that may be used (True = use); not with a prepared reference, which holds its own.
    max_iterations : int
        Gauss-Newton steps allowed per pyramid level (the refit after trimming flaws shares them).
    tolerance : float
        Stop a level when its update moves no corner of the used region more than this many of its pixels.
    deadline_s : float, optional
        Stop after this many seconds and report ``reason="deadline"``.
    initial : ndarray of shape (3, 3) or Registration, optional
        Start warp (reference pixel to inspection pixel); by default phase correlation at the coarsest level
        gives the start, so shifts up to about a quarter of the image side converge.
    tile_px : int, optional
        ``model="local"`` only: side of the overlapping tiles (default 64), at least 8 and at most the
        image's shorter side. Smaller tiles follow faster-varying distortion with less texture each.
    field_tolerance_px : float, optional
        ``model="local"`` only: the field's Gauss-Newton steps stop when no node moves more than this many
        full-resolution pixels (default 0.01, > 0). A detector whose mis-registration floor is far larger
        needs far less: DeepPCB's 0.1 px against its 3 px floor (``docs/deeppcb.md``).
    finest_level : int
        Finest pyramid level refined, >= 0: 0 (default) ends at full resolution; ``k`` ends on the images
        ``2**k`` times smaller (the coarsest level if the pyramid has fewer: it keeps at least 128 px a side),
        neither preparing nor sampling the finer levels, and the fit is scaled back to full-resolution
        pixels; `tolerance` is then in that level's pixels, and flaws are trimmed there. Level 1 costs about
        half of level 0 and is typically within 0.1 px of it (``docs/registration.md``): enough when the
        detector's mis-registration floor is far larger (DeepPCB's 3 px, ``docs/deeppcb.md``). With
        ``model="local"`` the field is solved on that level too (its tiles keep `tile_px` full-resolution
        pixels, at least 8 on the level: a finer level is used where they would not).
    coarsest_level : int, optional
        Coarsest pyramid level refined, >= `finest_level`; None (default): the coarsest that keeps at least
        128 px a side. Coarse levels widen the basin of convergence; a start already close to the answer
        (`initial` on pre-aligned images) needs none: with ``finest_level=coarsest_level=1`` DeepPCB's pairs
        are registered on their half-size images alone (``docs/deeppcb.md``). Without `initial`, phase
        correlation then runs on that level.
    row_step : int, optional
        Rows sampled on each level, >= 1: None (default) every row, and every other row on levels of 512 rows
        or more (their accuracy is limited by interpolation bias, not noise); ``k``: every k-th row on every
        level, at about 1/k of the work. DeepPCB's half-size images use every other row (``docs/deeppcb.md``).
        A prepared reference fixes it (:func:`prepare_reference`). With ``model="local"`` the field's
        Gauss-Newton steps sample every k-th row too (None: every row); on the test warps of
        ``tests/imaging`` every other row leaves the field as accurate (``docs/local-registration.md``).
    presmooth : bool, optional
        Smooth both full-resolution images with a 5 x 5 Gaussian before building the pyramid: True by default
        (it makes bilinear resampling at full resolution accurate to a few thousandths of a pixel), or the
        prepared reference's choice. False: the pyramid is built from the images as they are, every coarser
        level smoothed by cv2.pyrDown's own 5-tap Gaussian; for a fit that ends above full resolution
        (`finest_level` >= 1) this only spares the full-resolution filtering (DeepPCB: ``docs/deeppcb.md``).
        With ``model="local"`` the field reads the same images.

    Returns
    -------
    Registration
        Non-convergence is reported in ``reason`` and ``converged``, never raised.

    Raises
    ------
    InputError
        For an argument of the wrong type, shape, dtype or range.

    Notes
    -----
    Each level minimises ``sum_x w(x) [(I(W(x; p)) - b) / g - T(x)]^2`` over the warp parameters ``p``,
    gain ``g`` and bias ``b``, where ``T`` and ``I`` are the lightly smoothed reference and inspection and
    ``w`` selects reference pixels that map inside the inspection, lie in `mask` and, after a first
    convergence at full resolution, are not outliers beyond 4 robust sigmas (flaws must not pull the warp).
    Levels of 512 rows or more use every other row: there the accuracy is limited by interpolation bias, not
    by noise. The translation's standard deviation comes from ``sigma^2 H^-1`` over the pixels used.

    References
    ----------
    S. Baker and I. Matthews, "Lucas-Kanade 20 Years On: A Unifying Framework", IJCV 56(3), 2004,
    doi:10.1023/B:VISI.0000011205.11775.fd

    Examples
    --------
    >>> import numpy as np, scipy.ndimage as ndi
    >>> reference = ndi.gaussian_filter(np.random.default_rng(0).random((128, 128)), 2.0)
    >>> inspection = ndi.shift(reference, (-2.2, 3.7), mode="reflect")
    >>> [round(v, 1) for v in register(reference, inspection).translation_xy]
    [3.7, -2.2]
    """
    started = time.perf_counter()
    if model is not None and choice(model, "model", REGISTRATION_MODELS) == LOCAL_MODEL:
        return _register_local(
            reference,
            inspection,
            partial(
                register,
                photometric=photometric,
                mask=mask,
                max_iterations=max_iterations,
                tolerance=tolerance,
                deadline_s=deadline_s,
                initial=initial,
                finest_level=finest_level,
                coarsest_level=coarsest_level,
                row_step=row_step,
                presmooth=presmooth,
            ),
            mask=mask,
            tile_px=_DEFAULT_TILE_PX if tile_px is None else tile_px,
            tolerance_px=TOLERANCE_PX
            if field_tolerance_px is None
            else in_range(field_tolerance_px, "field_tolerance_px", low=0.0, low_inclusive=False),
            finest_level=positive_int(finest_level, "finest_level", minimum=0),
            row_step=row_step,
            presmooth=presmooth,
            started=started,
        )
    for name, value in (("tile_px", tile_px), ("field_tolerance_px", field_tolerance_px)):
        if value is not None:
            raise InputError(f"{name} applies to model='local' only; got model={model!r}. Omit {name}.")
    inspection_image, inspection_span = _checked_float32(inspection, "inspection")
    if isinstance(reference, PreparedReference):
        _check_prepared(reference, model, photometric, mask, row_step=row_step, presmooth=presmooth)
        count = min(len(reference.images), level_count(reference.shape, inspection_image.shape))
        finest = _finest_level(finest_level, count)
        count = _level_count(coarsest_level, finest_level, count)
        prepared = _from_level(reference, finest)
    else:
        reference_image = _as_float32(reference, "reference")
        count = level_count(reference_image.shape, inspection_image.shape)
        finest = _finest_level(finest_level, count)
        count = _level_count(coarsest_level, finest_level, count)
        # One code path: the cold call prepares the reference, only the levels it needs, in this thread's
        # scratch buffers (it never leaves the call: the pages of the last call are reused, not faulted).
        prepared = _prepare(
            reference_image,
            "translation" if model is None else model,
            True if photometric is None else photometric,
            mask,
            count,
            allocate=scratch,
            finest=finest,
            row_step=_chosen_row_step(row_step),
            presmooth=True if presmooth is None else _flag(presmooth, "presmooth"),
        )
    settings = Settings(
        model=WARP_MODELS[prepared.model],
        photometric=prepared.photometric,
        max_iterations=positive_int(max_iterations, "max_iterations"),
        tolerance_px=in_range(tolerance, "tolerance", low=0.0, low_inclusive=False),
        deadline=None
        if deadline_s is None
        else started + in_range(deadline_s, "deadline_s", low=0.0, low_inclusive=False),
    )
    start = _start(initial, settings.photometric)
    flat = _flat_image(prepared, inspection_image, inspection_span)
    if flat is not None:
        return _untextured(flat, prepared, inspection_image, started)
    # From `finest` down the levels are those of both images `finest` times halved: solved as such, the fit
    # is scaled back to full-resolution pixels.
    scale = 2.0**finest
    inspections = inspection_pyramid(inspection_image, count, prepared.presmooth)[finest:]
    levels = [
        Level(index, prepared.images[index], inspections[index], prepared.masks[index])
        for index in range(count - finest)
    ]
    if start is not None:
        start = dataclasses.replace(start, matrix=rescale(start.matrix, 1.0 / scale))
    estimate = coarse_to_fine(levels, partial(solve_level, terms=prepared.terms, settings=settings), start)
    return Registration(
        model=prepared.model,
        matrix=rescale(estimate.matrix, scale),
        gain=float(estimate.gain),
        bias=float(estimate.bias),
        converged=estimate.reason == "converged",
        reason=estimate.reason,
        iterations=estimate.iterations,
        residual_rms=estimate.residual_rms,
        shift_std_px=(scale * estimate.shift_std_px[0], scale * estimate.shift_std_px[1]),
        elapsed_s=time.perf_counter() - started,
    )


def _register_local(
    reference: NDArray[np.generic] | PreparedReference,
    inspection: NDArray[np.generic],
    register_global: Callable[..., Registration],
    *,
    mask: NDArray[np.generic] | None,
    tile_px: int,
    tolerance_px: float,
    finest_level: int,
    row_step: int | None,
    presmooth: bool | None,
    started: float,
) -> Registration:
    """The global fit, then the local field between the warped reference and the inspection (seed §2.3)."""
    prepared = isinstance(reference, PreparedReference)
    fit = register_global(reference, inspection, model=None if prepared else _LOCAL_GLOBAL_MODEL)
    inspection_image = _as_float32(inspection, "inspection")
    # The field is measured on the images the global fit used: lightly smoothed (5x5 Gaussian) unless
    # presmooth is False (a field above full resolution then reads cv2.pyrDown's own smoothing).
    if isinstance(reference, PreparedReference):
        presmoothed, sampled_rows = reference.presmooth, reference.row_step
        smoothed = reference.images[0]
    else:
        presmoothed, sampled_rows = presmooth is not False, row_step
        smoothed = _as_float32(reference, "reference")
        smoothed = smooth(smoothed) if presmoothed else smoothed
    usable = _preimage_inside(fit.matrix, smoothed.shape, inspection_image.shape)
    usable_mask = reference.masks[0] if isinstance(reference, PreparedReference) else mask
    if usable_mask is not None:
        usable &= as_mask(usable_mask, "mask", smoothed.shape)
    predicted = smoothed * np.float32(fit.gain) + np.float32(fit.bias)
    field = estimate_field(
        predicted,
        smooth(inspection_image) if presmoothed else inspection_image,
        fit.matrix,
        usable,
        tile_px,
        finest_level=finest_level,
        tolerance_px=tolerance_px,
        row_step=1 if sampled_rows is None else sampled_rows,
    )
    return dataclasses.replace(
        fit,
        model=LOCAL_MODEL,
        iterations=fit.iterations + field.iterations,
        elapsed_s=time.perf_counter() - started,
        local=field,
    )
