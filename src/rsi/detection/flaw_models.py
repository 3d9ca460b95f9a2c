"""Flaw models: the expected shape of a flaw in the difference image (seed §2.4).

A flaw model is a small 2-D array ``w`` of odd sides, centred on the flaw, whose largest absolute value is 1.
A flaw of strength ``s`` adds ``s * w`` (bright) or ``-s * w`` (dark) to the inspection image, so the
strength is the amplitude of the flaw's strongest pixel. The same array is the matched filter of the
likelihood-ratio test (:mod:`rsi.detection.detect`).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np
from numpy.typing import NDArray

from rsi._validate import choice, in_range, positive_int
from rsi.errors import InputError

FloatArray = NDArray[np.float64]

FLAW_MODELS = ("single", "uniform", "disc", "peak", "kernel")


MAX_SIZE_PX = 255
"""Widest flaw window: seed §2.4 flaws span a few pixels, and a window is a (size x size) array, so an
unbounded size is an unbounded allocation (99999 would ask for 74.5 GiB)."""


def _odd_size(size: object) -> int:
    side = positive_int(size, "size", maximum=MAX_SIZE_PX)
    if side % 2 == 0:
        raise InputError(f"size must be odd so the flaw has a centre pixel; got {side}. Try {side + 1}.")
    return side


def _single(size: int, peak_ratio: float, kernel: object) -> FloatArray:
    # seed §2.4: the single-pixel model tests each pixel on its own.
    return np.ones((1, 1))


def _uniform(size: int, peak_ratio: float, kernel: object) -> FloatArray:
    # seed §2.4: every component of the flaw strength vector equal (a spot of paint).
    return np.ones((size, size))


def _disc(size: int, peak_ratio: float, kernel: object) -> FloatArray:
    # seed §2.4 calls the flaws ~1 mm spots: round, not square. The pixels within (size - 1) / 2 of the
    # centre: for size 3 the centre and its four neighbours, which a bite or a pit 3 px across holds
    # whole where the 3x3 square's corners (sqrt 2 px out) fall outside it.
    radius = (size - 1) / 2
    rows, cols = np.mgrid[0:size, 0:size] - radius
    within: NDArray[np.bool_] = np.hypot(rows, cols) <= radius
    return within.astype(np.float64)


def _peak(size: int, peak_ratio: float, kernel: object) -> FloatArray:
    # seed §2.4: a strong centre over a weaker uniform surround, a crude micro-meteoroid crater.
    weights = np.full((size, size), 1.0 / peak_ratio)
    weights[size // 2, size // 2] = 1.0
    return weights


def _user(size: int, peak_ratio: float, kernel: object) -> FloatArray:
    if kernel is None:
        raise InputError("kernel must be given when flaw_model='kernel'; pass a 2-D array with odd sides.")
    if not isinstance(kernel, np.ndarray) or kernel.ndim != 2:
        shape = getattr(kernel, "shape", type(kernel).__name__)
        raise InputError(f"kernel must be a 2-D numpy array with odd sides; got {shape}.")
    if kernel.shape[0] % 2 == 0 or kernel.shape[1] % 2 == 0:
        raise InputError(f"kernel must have odd sides so it has a centre pixel; got shape {kernel.shape}.")
    if not np.issubdtype(kernel.dtype, np.number) or not np.isfinite(kernel).all():
        raise InputError("kernel must hold finite numbers; it contains NaN, inf or a non-numeric dtype.")
    peak = float(np.max(np.abs(kernel)))
    if peak == 0.0:
        raise InputError("kernel must not be all zeros; give the flaw's expected shape.")
    return np.asarray(kernel, dtype=np.float64) / peak


_BUILDERS: dict[str, Callable[[int, float, object], FloatArray]] = {
    "single": _single,
    "uniform": _uniform,
    "disc": _disc,
    "peak": _peak,
    "kernel": _user,
}


def flaw_kernel(
    flaw_model: str, *, size: int = 3, peak_ratio: float = 2.0, kernel: NDArray[Any] | None = None
) -> FloatArray:
    """Return the flaw model's shape, normalised so its largest absolute value is 1.

    Parameters
    ----------
    flaw_model : {"single", "uniform", "disc", "peak", "kernel"}
        ``"single"``: one pixel. ``"uniform"``: a ``size`` x ``size`` square of equal strength.
        ``"disc"``: the pixels of that square within ``(size - 1) / 2`` of its centre, of equal strength
        (for size 3, a plus). ``"peak"``: the same square with the centre ``peak_ratio`` times stronger
        than the uniform surround (crater model). ``"kernel"``: the user's ``kernel``.
    size : int
        Odd side in pixels of the ``"uniform"``, ``"disc"`` and ``"peak"`` windows.
    peak_ratio : float
        Centre-to-surround strength ratio of the ``"peak"`` model, >= 1.
    kernel : ndarray of shape (K, L), optional
        Flaw shape for ``flaw_model="kernel"``: odd sides, finite, not all zero. Only used by that model.

    Returns
    -------
    ndarray of shape (K, L), float64
        The flaw shape ``w`` with ``max(abs(w)) == 1``.

    Examples
    --------
    >>> flaw_kernel("peak", size=3, peak_ratio=2.0)[1]
    array([0.5, 1. , 0.5])
    """
    model = choice(flaw_model, "flaw_model", FLAW_MODELS)
    side = _odd_size(size)
    ratio = in_range(peak_ratio, "peak_ratio", low=1.0)
    if kernel is not None and model != "kernel":
        raise InputError(f"kernel is only used with flaw_model='kernel'; got flaw_model={model!r}.")
    return _BUILDERS[model](side, ratio, kernel)
