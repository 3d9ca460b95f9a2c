"""The reference relit for the inspection's light (seed §2.2-2.3): gain and bias fitted again once the
parallax is out, the strobe's smooth shading across the frame, and the share of its light that rides with
the camera (seed §3: the strobe is on the gripper's jaws).

Used by :mod:`rsi.mission.visual` on each comparison, the whole frame's and one component's pixels alone.
"""

from __future__ import annotations

from dataclasses import replace
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

if TYPE_CHECKING:
    from rsi.imaging.compensation import Compensated
    from rsi.imaging.registration import Registration

FloatArray = NDArray[np.float64]

# Pixels beyond this many robust sigmas of the photometric fit leave it: the registration's own trim (seed
# §2.3, rsi.imaging.register: flaws must not pull the fit)
PHOTOMETRIC_TRIM_SIGMAS = 4.0
# Trimmed refits: the second already settles gain and bias to 1e-3 and 0.1 DN on truss seed 0's frames
_PHOTOMETRIC_REFITS = 3
# Fewer pixels than a flaw kernel's few hundred cannot fit the shading's seven parameters against the trim
PHOTOMETRIC_MIN_PIXELS = 256
# The fit reads every this-many-th row and column: a smooth seven-parameter field over ~60,000 pixels is
# known to ~1e-4 of its gain (3 DN noise on ~100 DN), a hundredth of what the detector's variance carries;
# every pixel cost 12 s of a truss-b demo's 160 (issue 15).
_PHOTOMETRIC_STRIDE = 2
# The strobe's shading moves by at most this fraction of its gain over the compared pixels: truss-b's close
# panel views at space repeatability moved it by 8-15 % across half a frame; a field that departs further
# is a change of the surface (a replacement reflects 0.4-0.8 or 1.2-1.5 times the original, seed §4), and
# the flat gain stands
_MAX_SHADING = 0.25


def photometric_refit(
    aligned: Registration, reference: Compensated, inspection: Compensated
) -> tuple[Registration, Compensated]:
    """`aligned` with its gain and bias fitted again on the reference as predicted in depth, and the
    reference relit by the strobe's smooth change of shading (trimmed least squares, the inspection on the
    reference, outliers beyond 4 robust sigmas out).

    The first registration fitted gain and bias before the parallax was taken out: every surface off the
    median depth was misregistered, and what its trim kept pulled the fit. Two passes' strobe images at one
    flash energy (:func:`rsi.mission.exposure.shortened`) differ by the flash's gain and the compensation's
    zero-mean error (seed §2.2), not by an offset: truss seed 0 under a 300 s sun, CAD plan point cad_03,
    agreed to 0.02 DN at every brightness, yet the first fit gave gain 0.943 and bias +11 DN, and a dark
    tube end of 7.6 DN read 7 DN under its prediction, 16 sigma over 31 mm: a false swapped component
    (refitted: 0.997 and +0.5 DN).

    The strobe rides with the camera (seed §3: on the gripper's jaws), so a viewpoint error moves its beam
    and its glare over the surface: the strobe image's gain changes smoothly across the frame. The gain is
    a quadratic in the frame's coordinates (1, x, y, x^2, xy, y^2): no millimetre flaw bends it, and on
    truss-b's close panel views at space repeatability it took the comparison's robust sigma from 4-4.7 DN
    to 2.3-3.0 DN (a flat gain left 8-15 % across half the frame, read as swapped components). The returned
    registration carries the gain at the fitted pixels' centroid; the reference is multiplied by the field
    over it (and its variance by the square).

    What of the strobe's light rides with the camera stays on the frame's pixels while the scene moves: a
    glossy panel's glare (tens of pixels across) is where it was in the frame, and registering the
    reference by the viewpoint error moves it by that error, a dipole of tens of DN that no gain takes out
    (truss-b seed 2178 in space, cad_25: 18 px off, the comparison's robust sigma 4.5 DN, the frame's
    statistic five times too wide, three impacts of 7-10 sigma read under 3). So the prediction keeps a
    share ``c`` of the reference's own smooth light (:func:`_camera_light`) on the frame's pixels and moves
    the rest with the scene, ``c`` fitted with the gains, between none and all of it. The light multiplies
    the surface's reflectance (an image is reflectance times irradiance), so what stays on the frame is the
    light's ratio, ``r(y) (1 + c (L(A y) / L(y) - 1))``: the cells' dark gaps under a moved hotspot dim by
    its ratio, not by its difference (truss seed 2228 in space, C_panel_east_front, the second pristine
    visit 21 px off: an additive share came out 0.19 and left a dipole of +-10 DN, the frame's statistic
    3.5 times too wide, a 2.5 mm crater read 2.9; the ratio's share came out 0.93 and the robust sigma went
    from 5.0 to 1.9 DN). On views whose smooth light is the scene's own (a plate's edge against the dark)
    ``c`` comes out near 0 (held at 0 below).
    """
    warped, inside = aligned.warp(reference.image, output_shape=inspection.image.shape, photometric=False)
    seen, _ = aligned.warp(
        reference.valid.astype(np.float32), output_shape=inspection.image.shape, photometric=False
    )
    used = inside & (seen > 0.999) & inspection.valid
    lattice = np.zeros_like(used)
    lattice[::_PHOTOMETRIC_STRIDE, ::_PHOTOMETRIC_STRIDE] = True
    used &= lattice
    if int(used.sum()) < PHOTOMETRIC_MIN_PIXELS:
        return aligned, reference
    rows, cols = np.nonzero(used)
    # the gain is read at the fitted pixels' centroid: a component's own pixels (_on_component) may lie in
    # a corner, where a quadratic about the frame's centre extrapolates its constant to any sign
    origin = (float(np.mean(rows)), float(np.mean(cols)))
    shading = _shading_basis(rows, cols, inspection.image.shape, origin)
    before, after = warped[used].astype(np.float64), inspection.image[used].astype(np.float64)
    design = np.column_stack([shading * before[:, None], np.ones(before.size)])
    start = np.zeros(design.shape[1])
    start[0], start[-1] = aligned.gain, aligned.bias
    light, riding, share, rider, fitted = None, np.zeros(before.size), 0.0, 0.0, None
    if _moved(aligned):
        light = _camera_light(reference, _compared_in_reference(aligned, inspection.valid, reference.valid))
        moved, _ = aligned.warp(light, output_shape=inspection.image.shape, photometric=False)
        # the prediction's change if the light stays put on the frame: its ratio over the moved light
        riding = before * (_light_ratio(light[used], moved[used]) - 1.0)
        joint, kept = _trimmed_fit(np.column_stack([design, riding]), after, np.append(start, 0.0))
        if not joint[0] > 0.0:  # no strobe image is dimmer than nothing: a degenerate fit, the first stands
            return aligned, reference
        share = float(np.clip(joint[-1] / joint[0], 0.0, 1.0))
        rider = share * float(joint[0])
        # beyond the physical range the share is held at its end and the rest refitted
        fitted = joint[:-1] if share == joint[-1] / joint[0] else None
    if fitted is None:
        coefficients, kept = _trimmed_fit(design, after - rider * riding, start)
    else:
        coefficients = fitted
    gain, bias = float(coefficients[0]), float(coefficients[-1])
    if not gain > 0.0:
        return aligned, reference
    field = shading @ coefficients[:-1] / gain
    if not np.all(np.abs(field - 1.0) <= _MAX_SHADING):
        flat = np.column_stack([before, np.ones(before.size)])[kept]
        gain, bias = _least_squares(flat, after[kept] - rider * riding[kept])
        return replace(aligned, gain=float(gain), bias=float(bias)), _kept_on_frame(
            reference, aligned, light, share
        )
    relit = _relit(reference, aligned, coefficients[:-1] / gain, origin)
    return replace(aligned, gain=gain, bias=bias), _kept_on_frame(relit, aligned, light, share)


def _moved(aligned: Registration) -> bool:
    """Whether `aligned` moves the scene by a pixel or more: under that, what a light that stayed put
    changes is its gradient times the shift, which the detector's mis-registration model already holds
    (seed §2.3-2.4), and its share cannot be told from the noise."""
    return bool(np.hypot(*aligned.translation_xy) >= 1.0)


# The strobe's smooth light (seed §3: the strobe rides on the jaws) is read from the reference through its
# reflectance: the median over this many pixels takes out what is narrower (the cells' gaps, a panel's grid,
# edges, a crater), the Gaussian of this sigma then smooths the light. Chosen on two views whose pristine
# visit was 18-21 px off (truss seed 2228 C_panel_east_front, truss-b seed 2178 cad_25; both development),
# the light then read over the whole frame: a 12 px Gaussian alone left the cells' gaps in the light and
# the comparisons' robust sigma at 3.2 DN and 1.6-1.7 DN, this one 1.9 DN and 1.6 DN, with a third to a
# fifth of the pixels beyond 4 sigma; a 96 px Gaussian flattened cad_25's glare (2.4 DN).
_REFLECTANCE_MEDIAN_PX = 36
_CAMERA_LIGHT_SIGMA_PX = 48.0
_LIGHT_STEP = 4
# Below this many DN the light is too dim to carry a ratio (a dark frame's corner): it is left as it is
_LIGHT_FLOOR_DN = 1.0


def _compared_in_reference(
    aligned: Registration, compared: NDArray[np.bool_], valid: NDArray[np.bool_]
) -> NDArray[np.bool_]:
    """The reference's `valid` pixels that `aligned` brings onto the inspection's `compared` ones."""
    import cv2

    back = _read_where_inspected(compared.astype(np.float32), aligned, cv2.INTER_NEAREST, cv2.BORDER_CONSTANT)
    return np.asarray(valid & (back > 0.5), dtype=bool)


def _read_where_inspected(
    image: NDArray[np.float32], aligned: Registration, interpolation: int, border: int
) -> NDArray[np.float32]:
    """`image` (on the frame's pixels) read, at each reference pixel y, where `aligned` puts it on the
    inspection's frame: ``image(A y)``."""
    import cv2

    rows, cols = image.shape[:2]
    return np.asarray(
        cv2.warpAffine(
            image,
            aligned.matrix[:2].astype(np.float64),
            (cols, rows),
            flags=interpolation | cv2.WARP_INVERSE_MAP,
            borderMode=border,
        ),
        dtype=np.float32,
    )


def _camera_light(reference: Compensated, surface: NDArray[np.bool_]) -> NDArray[np.float32]:
    """The reference's smooth light over its `surface` pixels (those compared): at a quarter of the
    resolution, the gaps filled from the nearest such pixel, their median over ``_REFLECTANCE_MEDIAN_PX``,
    blurred by ``_CAMERA_LIGHT_SIGMA_PX`` and normalised by the weight (0 where none is near).

    Only the compared surface: what lies beyond it (the dark of space past a panel's edge, a strut) has
    another reflectance, and blurred into the panel's light it made a ratio at its edge (truss-b seed 2237
    in space, held out when it was found, cad_21: the black beyond the panel, 17 px off, read as the
    panel's edge 6-8 sigma brighter, a false swapped component)."""
    import cv2
    from scipy import ndimage

    rows, cols = reference.image.shape
    small = (max(cols // _LIGHT_STEP, 1), max(rows // _LIGHT_STEP, 1))
    weight = cv2.resize(surface.astype(np.float32), small, interpolation=cv2.INTER_AREA)
    total = cv2.resize(reference.image * surface, small, interpolation=cv2.INTER_AREA)
    seen = weight > 0.5
    if not seen.any():
        return np.zeros(reference.image.shape, np.float32)
    level = np.where(seen, total / np.maximum(weight, 1e-3), np.float32(0.0)).astype(np.float32)
    nearest = ndimage.distance_transform_edt(~seen, return_distances=False, return_indices=True)
    filled = level[tuple(nearest)]
    median = ndimage.median_filter(filled, size=max(_REFLECTANCE_MEDIAN_PX // _LIGHT_STEP, 1))
    sigma = _CAMERA_LIGHT_SIGMA_PX / _LIGHT_STEP
    mask = seen.astype(np.float32)
    blurred, norm = (cv2.GaussianBlur(plane, (0, 0), sigma) for plane in (median * mask, mask))
    light = np.where(norm > 1e-3, blurred / np.maximum(norm, 1e-3), np.float32(0.0)).astype(np.float32)
    return np.asarray(cv2.resize(light, (cols, rows), interpolation=cv2.INTER_LINEAR), dtype=np.float32)


def _light_ratio(light: NDArray[np.floating], moved: NDArray[np.floating]) -> FloatArray:
    """``light / moved`` where the moved light is bright enough to divide by, 1 elsewhere."""
    light, moved = np.asarray(light, np.float64), np.asarray(moved, np.float64)
    bright = moved > _LIGHT_FLOOR_DN
    return np.where(bright, light / np.where(bright, moved, 1.0), 1.0)


def _kept_on_frame(
    reference: Compensated, aligned: Registration, light: NDArray[np.float32] | None, share: float
) -> Compensated:
    """`reference` with `share` of its smooth light moved to where `aligned` puts each pixel on the frame,
    so that registering it by `aligned` leaves that share where it was: ``r(y) (1 + c (L(A y) / L(y) - 1))``,
    its variance by the factor's square; `reference` itself where no light was fitted or none rides."""
    import cv2

    if light is None or share == 0.0:
        return reference
    on_frame = _read_where_inspected(light, aligned, cv2.INTER_LINEAR, cv2.BORDER_REPLICATE)
    factor = (1.0 + share * (_light_ratio(on_frame, light) - 1.0)).astype(np.float32)
    return replace(
        reference,
        image=(reference.image * factor).astype(np.float32),
        variance=(reference.variance * factor * factor).astype(np.float32),
    )


def _trimmed_fit(
    design: FloatArray, target: FloatArray, start: FloatArray
) -> tuple[FloatArray, NDArray[np.bool_]]:
    """Least squares of `target` on `design`, refitted without the samples beyond
    ``PHOTOMETRIC_TRIM_SIGMAS`` robust sigmas of the last fit; `start` where too few samples remain."""
    coefficients = start.copy()
    kept = np.ones(target.size, dtype=bool)
    for _ in range(_PHOTOMETRIC_REFITS):
        if int(kept.sum()) < PHOTOMETRIC_MIN_PIXELS:
            break
        coefficients = _least_squares(design[kept], target[kept])
        residual = target - design @ coefficients
        sigma = 1.4826 * float(np.median(np.abs(residual - np.median(residual))))
        kept = np.abs(residual) <= PHOTOMETRIC_TRIM_SIGMAS * max(sigma, 1e-6)
    return coefficients, kept


def _least_squares(design: FloatArray, target: FloatArray) -> FloatArray:
    """Least squares by the normal equations: seven columns over ~10^5 pixels, a fifth of the time of an
    SVD of the whole design (the columns are of one scale, so squaring the condition number costs nothing:
    the coefficients agree with an SVD of the design to 1e-10); the 7 x 7 solve keeps lstsq's rank
    handling."""
    solution, *_ = np.linalg.lstsq(design.T @ design, design.T @ target, rcond=None)
    return np.asarray(solution, dtype=np.float64)


def _shading_basis(
    rows: NDArray[np.intp], cols: NDArray[np.intp], shape: tuple[int, ...], origin: tuple[float, float]
) -> FloatArray:
    """The quadratic shading's terms (1, x, y, x^2, xy, y^2) at pixels, x and y from `origin` (row, col),
    2 across the frame."""
    x, y = _frame_coordinates(rows, cols, shape, origin)
    return np.column_stack([np.ones(x.size), *_shading_terms(x, y)])


def _shading_terms(x: FloatArray, y: FloatArray) -> tuple[FloatArray, ...]:
    """The quadratic shading's terms after the constant: x, y, x^2, xy, y^2."""
    return (x, y, x * x, x * y, y * y)


def _frame_coordinates(
    rows: NDArray[np.number], cols: NDArray[np.number], shape: tuple[int, ...], origin: tuple[float, float]
) -> tuple[FloatArray, FloatArray]:
    """Pixel positions as x and y from `origin` (row, col), 2 across the frame."""
    x = 2.0 * (np.asarray(cols, dtype=np.float64) - origin[1]) / max(shape[1] - 1, 1)
    y = 2.0 * (np.asarray(rows, dtype=np.float64) - origin[0]) / max(shape[0] - 1, 1)
    return x, y


def _relit(
    reference: Compensated, aligned: Registration, shape_coefficients: FloatArray, origin: tuple[float, float]
) -> Compensated:
    """`reference` times the shading field (fitted in the inspection's frame about `origin`, read where
    `aligned` puts each reference pixel), its variance times the field's square."""
    rows, cols = np.indices(reference.image.shape)
    matrix = aligned.matrix
    x, y = _frame_coordinates(
        matrix[1, 0] * cols + matrix[1, 1] * rows + matrix[1, 2],
        matrix[0, 0] * cols + matrix[0, 1] * rows + matrix[0, 2],
        reference.image.shape,
        origin,
    )
    shading = np.full(x.shape, shape_coefficients[0])
    for coefficient, term in zip(shape_coefficients[1:], _shading_terms(x, y), strict=True):
        shading += coefficient * term
    field = shading.astype(np.float32)
    return replace(
        reference,
        image=(reference.image * field).astype(np.float32),
        variance=(reference.variance * field * field).astype(np.float32),
    )


# run_mission's internals, no public API (PEP 8: an empty __all__): every caller is
# :mod:`rsi.mission.visual`, with values it built and checked (docs/reliability.md).
__all__: list[str] = []
