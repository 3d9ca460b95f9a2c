"""Registration in depth: one viewpoint error moves every surface by its own parallax (seed §2.3).

Seed §2.3: in space "larger repeatability problems are to be expected", and one translation registers one
depth only: after a viewpoint error, surfaces nearer or farther than the registered one stay
mis-registered by their parallax, most at "sharp depth deviations". A camera moved across its view by
``T`` metres moves the image of a point at depth ``Z`` by ``f T / Z`` pixels, and a small turn of the
camera moves every pixel alike. So the inspection pixel ``x`` sees what the reference saw at

    x_ref = x - a - b (1 / Z(x) - 1 / Z0)

with ``a`` the shift of the surfaces at depth ``Z0`` and ``b = f T`` (pixels times metres): four numbers,
whatever the scene's depths, given the inspection's range map ``Z`` (the ISEE's stereo, seed §3 D, with the
CAD model's depth where the matcher had no answer).

- :func:`fit_parallax` fits ``(a, b)`` by Gauss-Newton on the image pair itself (seed §2.3), from the
  translation a plain registration found, with robust weights so that a flaw does not pull the fit
  (seed §2.4); its covariance is ``sigma^2 (J^T W J)^-1``.
- :func:`predict_reference` resamples a compensated reference into the inspection frame (image, variance,
  valid mask), marks invalid the pixels the two viewpoints see differently (occlusion: the reference's own
  range at the preimage is not the inspection's range there, it saw an occluder or past one), and adds the
  warp's remaining uncertainty to the variance: the fit's covariance and the range map's noise, each a
  shift ``delta`` of the prediction that changes it by ``delta |grad I|`` (the detector's own
  mis-registration model, seed §2.4).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import cv2
import numpy as np
from numpy.typing import NDArray

from rsi import _validate as v
from rsi.errors import InputError
from rsi.imaging._local import _gradients
from rsi.imaging.compensation import Compensated

F32 = NDArray[np.float32]
FloatArray = NDArray[np.float64]

# Huber weights beyond this many robust sigmas of the residual: a flaw's pixels weigh little (seed §2.4).
_HUBER_SIGMAS = 3.0
_MAD_TO_SIGMA = 1.4826
# A viewpoint error is mostly the camera moved across its view (every surface by f T / Z); an arm's
# orientation repeatability of ~0.004 deg turns the camera by 0.05 px at f = 760 px, which moves every pixel
# alike: the prior on that common part ``r`` (d = r + f T / Z). A looser prior (0.5 px) let the turn take
# up 1-4 px of misfit at depth edges and b miss the simulator's true f T by up to 70 % (truss vistas,
# seed 3, "space" repeatability); at 0.05 px b comes within 0-20 % of it. The prior also settles the fit
# when every surface in view lies at one depth (then r and f T / Z are the same motion).
_TURN_STD_PX = 0.05
# The fit reads every other pixel of every other row: the four parameters need thousands, not 300,000.
_STRIDE = 2
# Points sampled per row of a cv2.remap map.
_ROW = 1024
# Fewer usable pixels than this and the fit is not attempted.
_MIN_PIXELS = 200
MAX_ITERATIONS = 1000  # Gauss-Newton settles in a handful of steps; the bound keeps a bad value finite


@dataclass(frozen=True)
class ParallaxFit:
    """The inspection-to-reference motion of a rigid scene seen from two viewpoints.

    Attributes
    ----------
    shift_xy : (float, float)
        ``a``: (dx, dy) pixels, the motion of the surfaces at the reference inverse depth.
    parallax_px_m : (float, float)
        ``b = f T``: (bx, by) pixels times metres, the motion per unit of inverse depth (1/m) from there.
    inverse_depth_m : float
        ``1 / Z0``, 1/m: the median inverse depth of the pixels fitted.
    covariance : ndarray of shape (4, 4), float64
        Of (ax, ay, bx, by), ``sigma^2 (J^T W J)^-1``.
    residual_sigma : float
        Robust sigma of the residual after the fit, image units.
    iterations : int
        Gauss-Newton steps taken.
    converged : bool
        Whether the last step moved every pixel by less than the tolerance.
    """

    shift_xy: tuple[float, float]
    parallax_px_m: tuple[float, float]
    inverse_depth_m: float
    covariance: FloatArray
    residual_sigma: float
    iterations: int
    converged: bool

    def displacement(self, range_m: NDArray[np.floating]) -> tuple[F32, F32]:
        """(dx, dy) at every pixel of the inspection range map `range_m`: ``x_ref = x - (dx, dy)``."""
        offset = _inverse_depth(range_m) - np.float32(self.inverse_depth_m)
        (ax, ay), (bx, by) = self.shift_xy, self.parallax_px_m
        return (np.float32(ax) + np.float32(bx) * offset, np.float32(ay) + np.float32(by) * offset)

    def source_maps(self, range_m: NDArray[np.floating]) -> tuple[F32, F32]:
        """(map_x, map_y): the reference pixel every inspection pixel sees, for ``cv2.remap``; a pixel
        without a range (NaN) moves as the surfaces at the median depth."""
        dx, dy = self.displacement(_known(range_m, self))
        rows, cols = np.indices(dx.shape, dtype=np.float32)
        return (cols - dx).astype(np.float32), (rows - dy).astype(np.float32)

    def std_px(self, range_m: NDArray[np.floating], range_std_m: NDArray[np.floating] | float) -> F32:
        """One-sigma error of the displacement at every pixel: the fit's covariance along ``(1, u)`` and
        the range map's noise `range_std_m` moved through ``b``: ``|b| sigma_Z / Z^2``."""
        inverse = _inverse_depth(range_m)
        offset = inverse - np.float32(self.inverse_depth_m)
        cov = self.covariance
        fit_var = np.zeros_like(offset)
        for i in (0, 1):  # x, then y: Var(a_i + b_i u)
            fit_var += cov[i, i] + 2 * cov[i, i + 2] * offset + cov[i + 2, i + 2] * offset**2
        depth_var = float(np.hypot(*self.parallax_px_m)) ** 2 * (np.asarray(range_std_m) * inverse**2) ** 2
        return np.asarray(np.sqrt(np.maximum(fit_var, 0.0) + depth_var), dtype=np.float32)


def _known(range_m: NDArray[np.floating], fit: ParallaxFit) -> F32:
    depth = np.asarray(range_m, dtype=np.float32)
    with np.errstate(invalid="ignore"):
        known = np.isfinite(depth) & (depth > 0)
    return np.where(known, depth, np.float32(1.0 / fit.inverse_depth_m)).astype(np.float32)


def _inverse_depth(range_m: NDArray[np.floating]) -> F32:
    with np.errstate(divide="ignore", invalid="ignore"):
        return (1.0 / np.asarray(range_m, dtype=np.float32)).astype(np.float32)


def fit_parallax(
    reference: NDArray[np.floating],
    inspection: NDArray[np.floating],
    range_m: NDArray[np.floating],
    *,
    valid: NDArray[np.bool_] | None = None,
    start_xy: tuple[float, float] = (0.0, 0.0),
    gain: float = 1.0,
    bias: float = 0.0,
    max_iterations: int = 20,
    tolerance_px: float = 0.01,
) -> ParallaxFit:
    """Fit the rigid-scene motion ``x_ref = x - a - b (1/Z(x) - 1/Z0)`` by Gauss-Newton (seed §2.3).

    Parameters
    ----------
    reference, inspection : ndarray of shape (M, N)
        The reference and the inspection images, one scale (the photometric map is ``gain`` and ``bias``:
        ``inspection ~= gain * reference + bias``).
    range_m : ndarray of shape (M, N)
        The inspection's range along the view axis, metres; NaN or <= 0 where unknown (not fitted).
    valid : ndarray of shape (M, N), bool, optional
        Inspection pixels that may be used.
    start_xy : (float, float)
        The start of ``a``: the translation a plain registration found.
    gain, bias : float
        The photometric map of that registration.
    max_iterations : int
        Gauss-Newton steps at most.
    tolerance_px : float
        Stop when a step moves every fitted pixel by less than this.

    Returns
    -------
    ParallaxFit

    Raises
    ------
    InputError
        Arrays of different shapes, fewer than 200 usable pixels, or pixels that cannot determine the motion
        (no texture where the range map has depths, or all of them moved out of the reference's frame).
    """
    ref, insp, inverse = _checked_inputs(reference, inspection, range_m, valid)
    start_xy, gain, bias, max_iterations, tolerance_px = _fit_settings(
        start_xy, gain, bias, max_iterations, tolerance_px
    )
    usable = np.isfinite(inverse) & (inverse > 0)
    if valid is not None:
        usable &= np.asarray(valid, dtype=bool)
    usable[1::_STRIDE] = False
    usable[:, 1::_STRIDE] = False
    if int(usable.sum()) < _MIN_PIXELS:
        raise InputError(
            f"fit_parallax needs at least {_MIN_PIXELS} pixels with a range and a valid image; got "
            f"{int(usable.sum())}. Pass a range map with more known depths."
        )
    rows, cols = np.nonzero(usable)
    inverse = inverse[rows, cols].astype(np.float64)
    inverse_depth = float(np.median(inverse))
    grad_x, grad_y = _gradients(ref)
    seen = insp[rows, cols].astype(np.float64)
    # (r, B): d = r + B / Z, started as the registered shift all parallax (B = a Z0) and no turn
    params = np.array([0.0, 0.0, start_xy[0] / inverse_depth, start_xy[1] / inverse_depth])
    turn = np.diag([1.0, 1.0, 0.0, 0.0])
    normal, sigma, converged, iteration = np.eye(4), 1.0, False, 0
    for iteration in range(1, max_iterations + 1):
        at_x = (cols - params[0] - params[2] * inverse).astype(np.float32)
        at_y = (rows - params[1] - params[3] * inverse).astype(np.float32)
        inside = (at_x >= 0) & (at_y >= 0) & (at_x <= ref.shape[1] - 1) & (at_y <= ref.shape[0] - 1)
        residual = seen - (gain * _sample(ref, at_x, at_y) + bias)
        slope_x, slope_y = gain * _sample(grad_x, at_x, at_y), gain * _sample(grad_y, at_x, at_y)
        jacobian = np.stack([slope_x, slope_y, slope_x * inverse, slope_y * inverse], axis=1)
        sigma = _robust_sigma(residual[inside])
        weights = np.where(inside, _huber(residual, sigma), 0.0)
        prior = (sigma / _TURN_STD_PX) ** 2 * turn  # the camera's turn, in image units like the data
        normal = (jacobian * weights[:, None]).T @ jacobian + prior
        try:
            step = -np.linalg.solve(normal, (jacobian * weights[:, None]).T @ residual + prior @ params)
        except np.linalg.LinAlgError:
            raise InputError(
                f"fit_parallax cannot determine the motion: at iteration {iteration} the {rows.size} "
                f"usable pixels gave no gradient in the reference's frame ({int(inside.sum())} inside). "
                "Pass a reference with texture where the range map has depths, or register by translation."
            ) from None
        params += step
        moved = np.hypot(step[0] + step[2] * inverse, step[1] + step[3] * inverse)
        if float(moved.max()) < tolerance_px:
            converged = True
            break
    # (r, B) to (a, b): a = r + B / Z0, b = B
    to_shift = np.eye(4)
    to_shift[0, 2] = to_shift[1, 3] = inverse_depth
    covariance = np.asarray(to_shift @ (sigma**2 * np.linalg.pinv(normal)) @ to_shift.T, dtype=np.float64)
    shift = to_shift @ params
    return ParallaxFit(
        shift_xy=(float(shift[0]), float(shift[1])),
        parallax_px_m=(float(shift[2]), float(shift[3])),
        inverse_depth_m=inverse_depth,
        covariance=covariance,
        residual_sigma=float(sigma),
        iterations=iteration,
        converged=converged,
    )


def _checked_inputs(
    reference: NDArray[np.floating],
    inspection: NDArray[np.floating],
    range_m: NDArray[np.floating],
    valid: NDArray[np.bool_] | None,
) -> tuple[F32, F32, F32]:
    ref = v.as_intensity_image(reference, "reference").astype(np.float32)
    insp = v.as_intensity_image(inspection, "inspection").astype(np.float32)
    depth = _range_map(range_m, "range_m", ref.shape)
    if insp.shape != ref.shape:
        raise InputError(
            f"reference and inspection must have one shape; got {ref.shape} and {insp.shape}. Crop one."
        )
    if valid is not None:
        v.as_mask(valid, "valid", ref.shape)
    return ref, insp, _inverse_depth(depth)


def _range_map(range_m: object, name: str, shape: tuple[int, ...]) -> F32:
    """A range map of the image's `shape`, metres (NaN, inf or <= 0: unknown), or an InputError."""
    depth = v.as_float_array(range_m, name)
    if depth.shape != shape:
        raise InputError(f"{name} must have the reference's shape {shape}; got {depth.shape}.")
    return depth.astype(np.float32)


def _fit_settings(
    start_xy: object, gain: object, bias: object, max_iterations: object, tolerance_px: object
) -> tuple[tuple[float, float], float, float, int, float]:
    """fit_parallax's numbers checked: a finite start, photometric map and tolerance, a bounded loop."""
    start = v.as_float_array(start_xy, "start_xy")
    if start.shape != (2,) or not np.isfinite(start).all():
        raise InputError(f"start_xy must be two finite numbers (x, y) in pixels; got {start_xy!r}.")
    return (
        (float(start[0]), float(start[1])),
        v.in_range(gain, "gain", low=-v.MAX_INTENSITY, high=v.MAX_INTENSITY),
        v.in_range(bias, "bias", low=-v.MAX_INTENSITY, high=v.MAX_INTENSITY),
        v.positive_int(max_iterations, "max_iterations", maximum=MAX_ITERATIONS),
        v.positive(tolerance_px, "tolerance_px"),
    )


def _sample(image: F32, at_x: F32, at_y: F32) -> FloatArray:
    """Bilinear samples of `image` at the points (at_x, at_y), clamped at its edge."""
    count = at_x.size
    # cv2.remap takes maps under 32767 on a side: the points as rows of 1024
    padded = -(-count // _ROW) * _ROW
    map_x = np.zeros(padded, np.float32)
    map_y = np.zeros(padded, np.float32)
    map_x[:count], map_y[:count] = at_x, at_y
    values = cv2.remap(
        image,
        map_x.reshape(-1, _ROW),
        map_y.reshape(-1, _ROW),
        cv2.INTER_LINEAR,
        borderMode=cv2.BORDER_REPLICATE,
    )
    return np.asarray(values, dtype=np.float64).ravel()[:count]


def _robust_sigma(residual: FloatArray) -> float:
    if residual.size == 0:
        return 1.0
    centre = float(np.median(residual))
    return max(_MAD_TO_SIGMA * float(np.median(np.abs(residual - centre))), 1e-6)


def _huber(residual: FloatArray, sigma: float) -> FloatArray:
    size = np.abs(residual) / (_HUBER_SIGMAS * sigma)
    return np.where(size <= 1.0, 1.0, 1.0 / np.maximum(size, 1e-12))


@dataclass(frozen=True)
class Predicted:
    """A reference resampled into the inspection frame by a :class:`ParallaxFit`.

    Attributes
    ----------
    reference : Compensated
        Image, variance and valid mask in the inspection frame; the variance holds the warp's own
        uncertainty (``std_px^2 |grad I|^2``), the mask drops pixels seen past an occluder.
    range_m : ndarray of shape (M, N), float32
        The reference's range map resampled the same way (NaN where it had none).
    std_px : ndarray of shape (M, N), float32
        The displacement's one-sigma error at each inspection pixel.
    occluded : ndarray of shape (M, N), bool
        Pixels where the two viewpoints see different surfaces.
    """

    reference: Compensated
    range_m: F32
    std_px: F32
    occluded: NDArray[np.bool_]


def predict_reference(
    reference: Compensated,
    fit: ParallaxFit,
    range_m: NDArray[np.floating],
    *,
    reference_range_m: NDArray[np.floating] | None = None,
    reference_surface_m: NDArray[np.floating] | None = None,
    range_std_m: NDArray[np.floating] | float = 0.0,
    occlusion_m: float = 0.02,
    about_shift: bool = False,
) -> Predicted:
    """The reference as the inspection viewpoint sees it (seed §2.3), with what it cannot predict marked.

    Parameters
    ----------
    reference : Compensated
        The reference's compensated strobe image (seed §2.2), its variance and valid mask.
    fit : ParallaxFit
        From :func:`fit_parallax` on this pair.
    range_m : ndarray of shape (M, N)
        The inspection's range map (metres; NaN where unknown: those pixels move with ``a`` alone).
    reference_range_m : ndarray of shape (M, N), optional
        The reference's own range map: where it differs from the inspection's by more than `occlusion_m`
        at a pixel's preimage, within the parallax of a step of more than `occlusion_m` in `range_m`, the
        two viewpoints see different surfaces there (an occluding edge); farther from every step the
        disagreement is a false match of the reference's range, and the pixel stays.
    reference_surface_m : ndarray of shape (M, N), optional
        The reference's surface for the occlusion test in place of `reference_range_m` (which the result
        still carries): its range, and where the range has a hole a model's depth. A stereo pair leaves
        the edges it should tell unmatched (the left frame's first ``f B / Z`` columns, 90-180 px, and the
        tank silhouettes' strips), so a range alone marks no occlusion there.
    range_std_m : float or ndarray
        One-sigma noise of `range_m`, metres (into the warp's uncertainty).
    occlusion_m : float
        Range difference that marks an occlusion (larger than the range noise, smaller than the depth
        steps of the scene).
    about_shift : bool
        Return the reference in its own frame with only the parallax about the fit's shift ``a`` taken
        out: translated by ``a`` afterwards (by a registration, :class:`rsi.imaging.Registration`), it is
        the prediction. A detector that models the resampling of a translation's sub-pixel phase (seed
        §2.4, :func:`rsi.detect`) then sees the one resampling it models; where every surface lies at the
        median depth this image is the reference itself, unresampled.

    Returns
    -------
    Predicted
    """
    v.instance_of(reference, "reference", Compensated, none_allowed=False)
    v.instance_of(fit, "fit", ParallaxFit, none_allowed=False)
    shape = reference.image.shape
    range_m = _range_map(range_m, "range_m", shape)
    if reference_range_m is not None:
        reference_range_m = _range_map(reference_range_m, "reference_range_m", shape)
    if reference_surface_m is not None:
        reference_surface_m = _range_map(reference_surface_m, "reference_surface_m", shape)
    range_std = v.as_float_array(range_std_m, "range_std_m")
    if range_std.shape not in ((), shape) or not (np.isfinite(range_std) & (range_std >= 0)).all():
        raise InputError(
            f"range_std_m must be a finite number >= 0 or an array of the image's shape {shape}."
        )
    occlusion_m = v.positive(occlusion_m, "occlusion_m")
    if not isinstance(about_shift, bool):
        raise InputError(f"about_shift must be True or False; got {about_shift!r}.")
    known = _known(range_m, fit)
    seen_m = np.asarray(range_m, dtype=np.float32)
    if about_shift:  # each reference pixel y, with the inspection's depth at y + a
        known, seen_m = _translated(known, fit.shift_xy), _translated(seen_m, fit.shift_xy)
    map_x, map_y = fit.source_maps(known)
    if about_shift:
        map_x, map_y = map_x + np.float32(fit.shift_xy[0]), map_y + np.float32(fit.shift_xy[1])

    def warp(values: NDArray[np.generic], interpolation: int = cv2.INTER_LINEAR) -> F32:
        moved = cv2.remap(
            values.astype(np.float32), map_x, map_y, interpolation, borderMode=cv2.BORDER_REPLICATE
        )
        return np.asarray(moved, dtype=np.float32)

    inside = (map_x >= 0) & (map_y >= 0) & (map_x <= shape[1] - 1) & (map_y <= shape[0] - 1)
    # a pixel whose bilinear neighbours include an invalid reference pixel is invalid
    valid = inside & (warp(reference.valid.astype(np.float32)) > 0.999)
    image = warp(reference.image)
    occluded = np.zeros(shape, dtype=bool)
    before = np.full(shape, np.nan, dtype=np.float32)
    if reference_range_m is not None:
        before = warp(np.asarray(reference_range_m, dtype=np.float32), cv2.INTER_NEAREST)
    surface = before if reference_surface_m is None else warp(reference_surface_m, cv2.INTER_NEAREST)
    if reference_range_m is not None or reference_surface_m is not None:
        with np.errstate(invalid="ignore"):
            occluded = (np.abs(surface - seen_m) > occlusion_m) & _near_steps(known, fit, occlusion_m)
        valid &= ~occluded
    std = fit.std_px(known, range_std_m)
    grad_x, grad_y = _gradients(image)
    variance = warp(reference.variance) + std**2 * (grad_x**2 + grad_y**2)
    predicted = replace(
        reference,
        image=np.where(valid, image, np.float32(0.0)).astype(np.float32),
        valid=valid,
        variance=variance.astype(np.float32),
        interpolation_variance=warp(reference.interpolation_variance),
    )
    return Predicted(predicted, before, std, occluded)


# Pixels beyond the parallax from a depth step: the model's step drawn a pixel or two off, and the range's
# nearest-neighbour sampling across it
_STEP_MARGIN_PX = 2


def _near_steps(depth_m: F32, fit: ParallaxFit, step_m: float) -> NDArray[np.bool_]:
    """Pixels within the parallax about the fit's shift of a step of more than `step_m` in `depth_m`.

    Two viewpoints see different surfaces only next to an occluding edge, no farther from it than the
    edge's parallax between them (seed §2.3): ``|b| |1/Z - 1/Z0|`` at the scene's nearest or farthest
    surface. A range that disagrees anywhere else is the matcher's false match (a glint, a dark texture:
    docs/mission.md), not an occlusion, and its pixel stays in the comparison.
    """
    offset = float(np.abs(_inverse_depth(depth_m) - np.float32(fit.inverse_depth_m)).max())
    reach = math.ceil(float(np.hypot(*fit.parallax_px_m)) * offset) + _STEP_MARGIN_PX
    window = np.ones((2 * reach + 1, 2 * reach + 1), np.uint8)
    spread = cv2.dilate(depth_m, window) - cv2.erode(depth_m, window)
    return np.asarray(spread > step_m, dtype=bool)


def _translated(values: F32, shift_xy: tuple[float, float]) -> F32:
    """`values` read at ``y + shift`` at every pixel ``y`` (nearest: no depth blended across an edge)."""
    move = np.array([[1.0, 0.0, shift_xy[0]], [0.0, 1.0, shift_xy[1]]], dtype=np.float64)
    moved = cv2.warpAffine(
        values,
        move,
        (values.shape[1], values.shape[0]),
        flags=cv2.INTER_NEAREST | cv2.WARP_INVERSE_MAP,
        borderMode=cv2.BORDER_REPLICATE,
    )
    return np.asarray(moved, dtype=np.float32)


__all__ = ["ParallaxFit", "Predicted", "fit_parallax", "predict_reference"]
