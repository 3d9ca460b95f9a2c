"""Input checks shared by every package: fail early, name the argument, the value and the fix."""

from __future__ import annotations

import math
import os
import warnings
from collections.abc import Iterable, Mapping
from typing import Any, TypeVar

import numpy as np
from numpy.typing import NDArray

from rsi.errors import InputError

FloatArray = NDArray[np.floating[Any]]
T = TypeVar("T")

_MIN_SIDE_PX = 2


def as_image(image: object, name: str, *, allow_nan: bool = False) -> FloatArray:
    """Return `image` as a 2-D float array following the dtype policy.

    float32 and float64 are kept (no copy); bool and integer images become float64. Anything else, NaN or
    inf, fewer or more than two dimensions, or a side under two pixels raises :class:`InputError`.
    """
    if not isinstance(image, np.ndarray):
        raise InputError(
            f"{name} must be a numpy array of shape (rows, cols); got {type(image).__name__}. "
            f"Try np.asarray({name})."
        )
    if image.ndim != 2:
        raise InputError(
            f"{name} must be 2-D (rows, cols); got shape {image.shape}. "
            "Convert colour images to grey (e.g. cv2.cvtColor(img, cv2.COLOR_BGR2GRAY)) first."
        )
    if min(image.shape) < _MIN_SIDE_PX:
        raise InputError(
            f"{name} must be at least {_MIN_SIDE_PX}x{_MIN_SIDE_PX} pixels; got shape {image.shape}. "
            "Pass a non-empty image."
        )
    if image.dtype in (np.float32, np.float64):
        result: FloatArray = image
    elif image.dtype == np.bool_ or np.issubdtype(image.dtype, np.integer):
        result = image.astype(np.float64)
    else:
        raise InputError(
            f"{name} has dtype={image.dtype}, which is not supported. "
            "Try 'float32', 'float64', an unsigned integer or bool image."
        )
    if not allow_nan:
        _finite_range(result, name)
    return result


def _finite_range(image: FloatArray, name: str) -> tuple[float, float]:
    """(min, max) of `image`, or raise if it holds NaN or inf."""
    # min and max propagate NaN and reach +-inf without a full-size temporary (page faults on hot paths).
    low, high = float(image.min()), float(image.max())
    if not (math.isfinite(low) and math.isfinite(high)):
        bad = int(np.count_nonzero(~np.isfinite(image)))
        raise InputError(
            f"{name} contains {bad} NaN or inf pixel(s). Replace them (e.g. np.nan_to_num) "
            "or mark them invalid with a mask."
        )
    return low, high


MAX_INTENSITY = 1e15
"""Largest pixel magnitude registration and detection take: they work in float32 (max 3.4e38) and square
intensities and their sums over the image, so 1e15 keeps every sum finite (any camera reads below 2**32)."""


def as_intensity_image(image: object, name: str) -> FloatArray:
    """:func:`as_image`, and every pixel's magnitude at most :data:`MAX_INTENSITY`."""
    return intensity_range(image, name)[0]


def intensity_range(image: object, name: str) -> tuple[FloatArray, float, float]:
    """:func:`as_intensity_image` and the image's (min, max), found by the same pass (callers that also need
    the range, e.g. to see a constant image, need not read the image again)."""
    result = as_image(image, name, allow_nan=True)
    # One min and one max serve both checks (this runs several times per image on the detection path).
    low, high = _finite_range(result, name)
    peak = max(abs(low), abs(high))
    if peak > MAX_INTENSITY:
        raise InputError(
            f"{name} holds a pixel of magnitude {peak:.3g}, over {MAX_INTENSITY:g}: registration and "
            "detection work in float32 and square intensities: divide both images by one constant."
        )
    return result, low, high


def as_mask(mask: object, name: str, shape: tuple[int, ...]) -> NDArray[np.bool_]:
    """Return `mask` as a bool array of `shape` (True = use this pixel)."""
    if not isinstance(mask, np.ndarray):
        raise InputError(f"{name} must be a numpy bool array of shape {shape}; got {type(mask).__name__}.")
    if mask.shape != shape:
        raise InputError(f"{name} must have shape {shape} (the image's); got {mask.shape}.")
    if mask.dtype != np.bool_:
        if not (np.issubdtype(mask.dtype, np.integer) or np.issubdtype(mask.dtype, np.floating)):
            raise InputError(f"{name} has dtype={mask.dtype}; pass a bool array (True = valid pixel).")
        converted: NDArray[np.bool_] = np.not_equal(mask, 0)
        return converted
    return mask


def same_shape(first: np.ndarray, second: np.ndarray, names: tuple[str, str]) -> None:
    """Raise unless the two arrays have the same shape."""
    if first.shape != second.shape:
        raise InputError(
            f"{names[0]} and {names[1]} must have the same shape; got {first.shape} and {second.shape}. "
            "Crop or resize one to match the other."
        )


def finite_number(value: object, name: str) -> float:
    """Return `value` as a finite float or raise (a Python int beyond the float range included)."""
    if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)):
        raise InputError(f"{name} must be a number; got {_shown(value)}.")
    try:
        number = float(value)
    except OverflowError:  # an int beyond 1.8e308 has no float
        number = math.inf
    if not math.isfinite(number):
        raise InputError(f"{name} must be finite (a float within +-1.8e308); got {_shown(value)}.")
    return number


def _shown(value: object) -> str:
    """`value` for a message, cut to 80 characters (a 10**400 or a 1 MB string must not flood the line)."""
    # repr of an int over 4300 digits raises (Python's int-to-str limit): give its size instead.
    if isinstance(value, int) and abs(value) >= 10**30:
        return f"an integer of {value.bit_length()} bits"
    text = repr(value)
    return text if len(text) <= 80 else text[:77] + "..."


def in_range(
    value: object,
    name: str,
    *,
    low: float | None = None,
    high: float | None = None,
    low_inclusive: bool = True,
    high_inclusive: bool = True,
) -> float:
    """Return `value` as a float if it lies in the given interval, else raise naming the interval."""
    number = finite_number(value, name)
    too_low = low is not None and (number < low if low_inclusive else number <= low)
    too_high = high is not None and (number > high if high_inclusive else number >= high)
    if too_low or too_high:
        left = "[" if low_inclusive else "("
        right = "]" if high_inclusive else ")"
        interval = f"{left}{'-inf' if low is None else low}, {'inf' if high is None else high}{right}"
        raise InputError(f"{name} must be in {interval}; got {_shown(value)}.")
    return number


def positive_int(value: object, name: str, *, minimum: int = 1, maximum: int | None = None) -> int:
    """Return `value` as an int in [`minimum`, `maximum`] or raise naming the range."""
    bounds = f">= {minimum}" if maximum is None else f"in [{minimum}, {maximum}]"
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)):
        raise InputError(f"{name} must be an integer {bounds}; got {_shown(value)}.")
    if value < minimum or (maximum is not None and value > maximum):
        raise InputError(f"{name} must be an integer {bounds}; got {_shown(value)}.")
    return int(value)


def choice(value: object, name: str, options: Iterable[str]) -> str:
    """Return `value` if it is one of `options`, else raise listing them."""
    allowed = tuple(options)
    if not isinstance(value, str) or value not in allowed:
        listed = ", ".join(repr(option) for option in allowed)
        raise InputError(f"{name}={_shown(value)} is not known. Choose one of {listed}.")
    return value


def as_rng(rng: np.random.Generator | int | None, name: str = "rng") -> np.random.Generator:
    """Return a Generator from a Generator, a seed (an integer >= 0) or None (fresh entropy)."""
    if rng is None or isinstance(rng, np.random.Generator):
        return np.random.default_rng(rng)
    if isinstance(rng, (int, np.integer)) and not isinstance(rng, bool):
        if rng < 0:
            raise InputError(f"{name} seed must be an integer >= 0; got {_shown(rng)}.")
        return np.random.default_rng(int(rng))
    raise InputError(f"{name} must be a numpy Generator, an int seed >= 0 or None; got {_shown(rng)}.")


def positive(value: object, name: str) -> float:
    """Return `value` as a float > 0 or raise naming it."""
    return in_range(value, name, low=0.0, low_inclusive=False)


def store_checked(instance: object, checked: Mapping[str, object]) -> None:
    """Write checked (converted) field values onto a frozen dataclass from its ``__post_init__``."""
    for name, value in checked.items():
        object.__setattr__(instance, name, value)


def as_float_array(value: object, name: str) -> NDArray[np.float64]:
    """Return `value` (a number or an array of numbers, any shape) as a float64 array, or raise naming it.

    Text, bytes, paths, mappings, complex and object arrays, ragged lists and ints beyond the float range
    are refused here, so no numpy conversion error ever reaches the caller. NaN and inf are kept: the
    caller knows whether its quantity may be infinite.
    """
    refused = isinstance(value, (str, bytes, os.PathLike, Mapping)) or (
        isinstance(value, np.ndarray) and value.dtype.kind not in "biuf"
    )
    if isinstance(value, np.ndarray) and not refused:  # the hot path (control loops): nothing can warn
        return np.asarray(value, dtype=np.float64)
    if isinstance(value, (float, np.floating)) or (isinstance(value, int) and abs(value) < 2**1000):
        return np.asarray(value, dtype=np.float64)
    if not refused:
        try:
            with warnings.catch_warnings():
                warnings.simplefilter(
                    "error"
                )  # a complex value is refused, not silently cut to its real part
                return np.asarray(value, dtype=np.float64)
        except (TypeError, ValueError, OverflowError, Warning):
            pass
    raise InputError(f"{name} must be a number or an array of numbers (float64); got {_shown(value)}.")


def instance_of(value: object, name: str, kind: type[T], *, none_allowed: bool = True) -> T:
    """Return `value` if it is a `kind`, else raise naming the argument and how to build one.

    `none_allowed` says whether the message offers None (the caller's defaults) as a fix.
    """
    if not isinstance(value, kind):
        defaults = " (or None for the defaults)" if none_allowed else ""
        raise InputError(
            f"{name} must be a {kind.__name__}{defaults}; got {type(value).__name__}. "
            f"Build one with {kind.__name__}(...)."
        )
    return value


def vector3(value: object, name: str) -> tuple[float, float, float]:
    """Return `value` as three finite floats (x, y, z) or raise naming it."""
    array = as_float_array(value, name)
    if array.shape != (3,) or not np.isfinite(array).all():
        raise InputError(f"{name} must be three finite numbers (x, y, z); got {_shown(value)}.")
    return (float(array[0]), float(array[1]), float(array[2]))


def direction3(value: object, name: str) -> NDArray[np.float64]:
    """Return `value` as a unit 3-vector (normalised here) or raise naming it when it is not a direction."""
    vector = np.array(vector3(value, name))
    scale = float(np.max(np.abs(vector)))  # scaled first: the norm of (1e308, 1e308, 0) overflows
    if scale < 1e-12:
        raise InputError(f"{name} must be a non-zero direction; got {_shown(value)}.")
    unit = vector / scale
    return np.asarray(unit / np.linalg.norm(unit), dtype=np.float64)


def instance_or_default(value: object, name: str, kind: type[T]) -> T:
    """Return `kind()` (the documented defaults) for None, else `value` if it is a `kind`, else raise."""
    return kind() if value is None else instance_of(value, name, kind)


def increasing_pair(value: object, name: str, *, low: float = 0.0, unit: str = "") -> tuple[float, float]:
    """Return `value` as (first, second), finite floats with `low` < first < second, or raise naming it."""
    if isinstance(value, (str, bytes)) or not isinstance(value, (tuple, list, np.ndarray)) or len(value) != 2:
        raise InputError(
            f"{name} must be a pair (low, high){' in ' + unit if unit else ''}; got {_shown(value)}."
        )
    first, second = (finite_number(item, f"{name}[{index}]") for index, item in enumerate(value))
    if not low < first < second:
        raise InputError(
            f"{name} must be (low, high) with {low:g} < low < high{' ' + unit if unit else ''}; got "
            f"{_shown(value)}."
        )
    return first, second


def _is_named(value: object, kind: str) -> bool:
    return any(cls.__name__ == kind for cls in type(value).__mro__)


def record_named(value: object, name: str, kind: str) -> None:
    """Raise unless `value` is a `kind` (a class of that name, or a subclass of one).

    Checked by class name: the report layer draws records of the layers below and may not import them
    (pyproject.toml's import contracts), and sim.clearance would import its own caller, sim.world.
    """
    if not _is_named(value, kind):
        raise InputError(
            f"{name} must be a {kind}; got {type(value).__name__} {_shown(value)}. "
            f"Pass the {kind} that rsi returned."
        )


def records_named(value: object, name: str, kind: str) -> list[Any]:
    """Return `value` as a list after checking it is a list or tuple of `kind` records, or raise naming it."""
    if not isinstance(value, (list, tuple)):
        raise InputError(f"{name} must be a list of {kind}; got {type(value).__name__} {_shown(value)}.")
    for index, item in enumerate(value):
        record_named(item, f"{name}[{index}]", kind)
    return list(value)


def size3(value: object, name: str) -> tuple[float, float, float]:
    """Return `value` as three finite half sizes > 0 (metres) or raise naming it."""
    sizes = vector3(value, name)
    if min(sizes) <= 0.0:
        raise InputError(f"{name} must be three half sizes > 0 m; got {_shown(value)}.")
    return sizes


def as_table(values: object, name: str, columns: int) -> FloatArray:
    """`values` as a finite float64 table of shape (K, `columns`); an empty input is (0, `columns`)."""
    table = as_float_array(values, name)
    if table.size == 0:
        return table.reshape(0, columns)
    if table.ndim != 2 or table.shape[1] != columns or not np.isfinite(table).all():
        raise InputError(
            f"{name} must be a finite array of shape (K, {columns}); got shape {table.shape}. "
            f"Pass one row per item, e.g. np.empty((0, {columns})) for none."
        )
    return table
