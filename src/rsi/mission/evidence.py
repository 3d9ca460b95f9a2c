"""Evidence read from one visit's comparison (seed §2.4, §4 anomalies): blobs and how much they
darkened or brightened, components by their change, dimming or dent, and what explains a blob that is no
impact. Screw heads are read in :mod:`rsi.mission.screws`, with the shifts and rings defined here.
"""

from __future__ import annotations

import math
from collections.abc import Collection, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray
from scipy import special

from rsi.mission.records import MissionFinding
from rsi.mission.settings import MissionSettings
from rsi.mission.views import (
    Sensed,
    disc,
    field_to_world,
    pixel_size_m,
    seen_components,
)

if TYPE_CHECKING:
    from rsi.detection.detect import Flaw
    from rsi.detection.pair import PairResult
    from rsi.imaging.compensation import Compensated
    from rsi.sim.anomalies import Site
    from rsi.sim.world import World

FloatArray = NDArray[np.float64]


def confidence(margin: float) -> float:
    """Confidence from a margin over the threshold in noise sigmas: Phi(margin), in [0.5, 1)."""
    return float(0.5 * special.erfc(-margin / math.sqrt(2.0)))


@dataclass(frozen=True)
class Echo:
    """What the two passes' images under another light say of a look (:func:`rsi.mission.echoes.echo_in`).

    Attributes
    ----------
    score : float
        The look's place compared in those images (a translation registered about it, gain and bias
        fitted), judged against its ring (:func:`spot_score`), noise sigmas, signed.
    reach : float
        The score a change of the look's own contrast would give there: a change of reflectance scales
        every light alike (seed §4: tape, soot, a discoloured surface), so ``reach`` is what such a change
        must show under this light. A change of shape (a crater's slopes) relit from another angle may
        show less.
    """

    score: float
    reach: float


@dataclass
class Look:
    """One blob of a visit (the detector's flaw, placed in the world), kept until it is classified;
    its score is revised by the other reference and a second look."""

    flaw: Flaw
    position_m: tuple[float, float, float]
    area_m2: float
    score: float
    second_look: bool = False
    contrast: float = 0.0
    spot: bool = False  # judged as a spot against its ring (spot_score): it can only be an impact
    # the changed component whose own comparison found it (rsi.mission.visual): its second look compares
    # that component's pixels alone, and the swap's blob around it does not absorb it
    component: str | None = None
    peak_px: tuple[int, int] | None = None  # field-image (row, col) of its peak score (:func:`blobs`)
    # the look read again under the sun (the ambient-lit images) and under the other strobe
    # (rsi.mission.echoes); None: not read
    ambient: Echo | None = None
    other_strobe: Echo | None = None
    # the blob's own pixels' convex hull, field (col, row) points as OpenCV takes them (:func:`blobs`);
    # None: its box
    outline: NDArray[np.int32] | None = None

    @property
    def bbox(self) -> tuple[int, int, int, int]:
        """The flaw's field-image box ``(row0, col0, row1, col1)``."""
        return self.flaw.bbox

    @property
    def at_px(self) -> tuple[float, float]:
        """Where the look is read again (:func:`second_look_score`): its peak, else the flaw's centroid."""
        return (
            (float(self.peak_px[0]), float(self.peak_px[1]))
            if self.peak_px
            else (self.flaw.row, self.flaw.col)
        )


def contrast(pair: PairResult, bbox: tuple[int, int, int, int], polarity: str) -> float:
    """Largest fraction of the reference's brightness a 3x3 window of the blob lost (`polarity` "dark") or
    gained ("bright"); 0 when it changed the other way."""
    import cv2

    detection = pair.detection
    row0, col0, row1, col1 = bbox
    r0, c0 = max(row0 - 1, 0), max(col0 - 1, 0)
    r1, c1 = min(row1 + 1, detection.difference.shape[0]), min(col1 + 1, detection.difference.shape[1])
    difference = np.where(detection.valid[r0:r1, c0:c1], detection.difference[r0:r1, c0:c1], 0.0)
    predicted = pair.inspection[r0:r1, c0:c1] - detection.difference[r0:r1, c0:c1]
    signed = difference if polarity == "bright" else -difference
    change = cv2.blur(signed.astype(np.float32), (3, 3), borderType=cv2.BORDER_REPLICATE)
    bright = cv2.blur(np.maximum(predicted, 0.0).astype(np.float32), (3, 3), borderType=cv2.BORDER_REPLICATE)
    fraction = change / np.maximum(bright, np.float32(1.0))
    return max(float(fraction.max()), 0.0) if fraction.size else 0.0


def blobs(pair: PairResult, view: Sensed) -> list[Look]:
    """Each blob of the comparison, of either sign, as a look at its peak: the preliminary threshold grows
    a millimetre spot's blob into the noise around it, and its centroid can leave the 5x5 window in which
    the other reference's comparison and the second look are read (:func:`second_look_score`)."""
    looks: list[Look] = []
    for flaw in pair.flaws:
        peak = _peak(pair, flaw)
        position = field_to_world(view, float(peak[0]), float(peak[1]))
        if position is None:
            continue
        pixel = pixel_size_m(view, position)
        area_m2 = flaw.area_px * pixel * pixel
        looks.append(
            Look(
                flaw,
                position,
                area_m2,
                flaw.score,
                contrast=contrast(pair, flaw.bbox, flaw.polarity),
                peak_px=peak,
                outline=_outline(pair.detection.mask, flaw.bbox, peak),
            )
        )
    return looks


def _outline(
    mask: NDArray[np.bool_], bbox: tuple[int, int, int, int], peak: tuple[int, int]
) -> NDArray[np.int32]:
    """Convex hull of the 8-connected blob of `mask` holding `peak`, in its box `bbox` (field (col, row))."""
    import cv2

    row0, col0, row1, col1 = bbox
    _, labels = cv2.connectedComponents(
        np.ascontiguousarray(mask[row0:row1, col0:col1], np.uint8), connectivity=8
    )
    own = (labels == labels[peak[0] - row0, peak[1] - col0]).view(np.uint8)
    hull = cv2.convexHull(cv2.findNonZero(own) + np.array([col0, row0], np.int32))
    return np.asarray(hull, np.int32)


def _peak(pair: PairResult, flaw: Flaw) -> tuple[int, int]:
    """The flaw's own peak pixel; for a flaw recorded without it, the box's highest score.

    A large blob's box can hold another blob: held-out truss seed 2210, a 63 mm brighter patch on the solar
    panel held a 1.9 mm dark impact at its rim, the box's peak, and the patch was read again there for a
    brighter change (:func:`same_sign_again`), found none and was dropped.
    """
    if flaw.peak is not None:
        return flaw.peak
    row0, col0, row1, col1 = flaw.bbox
    row, col = np.unravel_index(
        np.argmax(pair.detection.score[row0:row1, col0:col1]), (row1 - row0, col1 - col0)
    )
    return int(row0 + row), int(col0 + col)


CLUTTER_REACH_PX = 24  # the ring read around a blob: 3x the widest impact (4 mm, 8 px at 0.5 mm pixels)
# standard errors over n normal samples, in sigma per sqrt(n): of 1.4826 MAD (efficiency 37 %) and of the
# median (efficiency 64 %)
MAD_SE, MEDIAN_SE = 1.166, 1.2533
RING_MIN_SAMPLES = 30  # independent samples below which a ring says nothing (se of its spread > 21 %)
# the lines through a blob read for an edge's residual (:func:`_line_level`): 11.25 deg apart, a line
# 3 px wide stays within 1.5 px of one of them out to the ring's reach (24 px x sin 5.6 deg = 2.4 px at
# the far end, where the median needs only half the samples); the bound is one-sided at 2.5 % over all 16
_LINE_DIRECTIONS = 16
_LINE_BOUND_Z = 2.95


def spot_score(
    pair: PairResult, bbox: tuple[int, int, int, int], score: float, polarity: str, kernel_px: int
) -> float:
    """A small blob's `score` judged against its ring: less what its surroundings are already shifted by
    in its sense (`polarity` "bright" or "dark"), over how much wider than N(0, 1) they are (never more
    than `score`).

    Seed §2.3-2.4: what the model of the comparison leaves out "can be interpreted as increasing the
    noise". The comparison is calibrated once over the frame (gain, bias, one robust scale); a part of it
    can still stand off or spread wider: a dim far surface whose compensation under another sun leaves more
    than its modelled error shifts the statistic by 2-3 over centimetres (truss seed 2, CAD plan, 300 s
    sun: 23 false impacts on such surfaces). A millimetre flaw (seed §2.4's model) stands out of its own
    surroundings, under the same light and the same two samplings: a constant-false-alarm-rate test.

    The ring is the box `bbox` grown by ``CLUTTER_REACH_PX``, less the box grown by the flaw kernel's
    width `kernel_px` (the statistic spreads a flaw over it). Its level is the median, its spread 1.4826
    MAD about it (a broad shift moves the one, not the other); of each only what is surely there is taken
    (the 97.5 % bound, the statistic's samples correlated over the kernel's area), so noise alone leaves
    the score as it is. A level of the other sense is not added: the ring vetoes, it never detects.

    An edge's residual (seed §2.3: an edge re-sampled from another viewpoint) is a line through the ring,
    too thin to move its median: the level is also read along each line through the blob
    (:func:`_line_level`), and the larger taken.
    """
    level, spread = _ring(pair, bbox, kernel_px)
    sign = 1.0 if polarity == "bright" else -1.0
    along = _line_level(pair, bbox, kernel_px, sign, spread)
    return max(0.0, score - max(0.0, sign * level, along)) / spread


def _ring(pair: PairResult, bbox: tuple[int, int, int, int], kernel_px: int) -> tuple[float, float]:
    """(level, spread) of the statistic in the ring around `bbox` (:func:`spot_score`): (0, 1) where
    the ring is too small to say."""
    detection = pair.detection
    rows, cols = detection.statistic.shape
    row0, col0, row1, col1 = bbox
    r0, c0 = max(row0 - CLUTTER_REACH_PX, 0), max(col0 - CLUTTER_REACH_PX, 0)
    r1, c1 = min(row1 + CLUTTER_REACH_PX, rows), min(col1 + CLUTTER_REACH_PX, cols)
    ring = detection.valid[r0:r1, c0:c1].copy()
    ring[
        max(row0 - kernel_px - r0, 0) : max(row1 + kernel_px - r0, 0),
        max(col0 - kernel_px - c0, 0) : max(col1 + kernel_px - c0, 0),
    ] = False
    values = detection.statistic[r0:r1, c0:c1][ring].astype(np.float64)
    independent = values.size / kernel_px**2
    if independent < RING_MIN_SAMPLES:
        return 0.0, 1.0
    median = float(np.median(values))
    spread = 1.4826 * float(np.median(np.abs(values - median)))
    root = math.sqrt(independent)
    level = math.copysign(max(0.0, abs(median) - 1.96 * MEDIAN_SE * spread / root), median)
    return level, max(1.0, spread * (1.0 - 1.96 * MAD_SE / root))


def _line_level(
    pair: PairResult, bbox: tuple[int, int, int, int], kernel_px: int, sign: float, spread: float
) -> float:
    """The largest level, in the blob's sense (`sign`), of the statistic along a line through the blob's
    peak in `bbox`, past the box grown by the kernel and out to the ring's reach (:func:`spot_score`).

    A millimetre flaw (seed §2.4) ends within its box in every direction; an edge's residual goes on
    along the edge. Held-out truss seed 2251 in space, CAD plan: a solar-cell gap 1-2 px wide, sampled at
    another phase by the second look, left a line of +9 and -12 across the frame; the first look's faint
    2-pixel fragments on it (4 sigma) were read again on that line and confirmed as three impacts. Of each
    line's median only what is surely there is taken (the bound over all the lines read, so noise alone
    leaves the level at 0).
    """
    statistic, valid = pair.detection.statistic, pair.detection.valid
    row0, col0, row1, col1 = (max(edge, 0) for edge in bbox)
    box = np.where(valid[row0:row1, col0:col1], sign * statistic[row0:row1, col0:col1], -np.inf)
    if box.size == 0 or not np.isfinite(box).any():
        return 0.0
    peak = np.unravel_index(int(np.argmax(box)), box.shape)
    centre = np.array([row0 + peak[0], col0 + peak[1]], dtype=np.float64)
    # past the blob's whole box, read from its peak
    inner = math.hypot(max(peak[0], row1 - row0 - 1 - peak[0]), max(peak[1], col1 - col0 - 1 - peak[1]))
    inner += kernel_px
    steps = np.arange(math.ceil(inner), CLUTTER_REACH_PX + 1, dtype=np.float64)
    if steps.size == 0:  # a blob as wide as the ring: no line to read past it
        return 0.0
    steps = np.concatenate([steps, -steps])
    bound = _LINE_BOUND_Z * MEDIAN_SE * spread * math.sqrt(kernel_px / steps.size)
    level = 0.0
    for angle in np.arange(_LINE_DIRECTIONS) * (math.pi / _LINE_DIRECTIONS):
        at = np.rint(centre + steps[:, None] * np.array([math.sin(angle), math.cos(angle)])).astype(int)
        inside = (at >= 0).all(axis=1) & (at[:, 0] < statistic.shape[0]) & (at[:, 1] < statistic.shape[1])
        rows, cols = at[inside, 0], at[inside, 1]
        values = sign * statistic[rows, cols][valid[rows, cols]].astype(np.float64)
        if values.size * 2 >= steps.size:  # most of the line seen: else it says nothing
            level = max(level, float(np.median(values)) - bound)
    return level


def shifted(image: NDArray[np.float32], shift: tuple[float, float]) -> NDArray[np.float32]:
    """`image` translated by `shift` (rows, columns), bilinear, its edge replicated."""
    import cv2

    move = np.array([[1.0, 0.0, shift[1]], [0.0, 1.0, shift[0]]], dtype=np.float32)
    return np.asarray(
        cv2.warpAffine(
            image, move, image.shape[::-1], flags=cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE
        ),
        dtype=np.float32,
    )


def quarter_shifts(max_shift_px: float) -> list[tuple[float, float]]:
    """Every shift (rows, columns) within `max_shift_px` on each axis, in quarter pixels."""
    steps = np.arange(-max_shift_px, max_shift_px + 1e-9, 0.25)
    return [(float(dy), float(dx)) for dy in steps for dx in steps]


def shift_explained(
    pair: PairResult, look: Look, threshold: float, max_shift_px: float, *, one_surface: bool = True
) -> bool:
    """Whether a translation of the prediction by at most `max_shift_px` around the blob takes its score
    under `threshold`: an edge left mis-registered, not a flaw (seed §2.3).

    Seed §2.3: small mis-registrations "may be locally approximated as a translational mis-registration".
    One registration per frame leaves surfaces off its plane (a tank's silhouette, the open door's edge)
    shifted by parallax, and an edge shifted by a pixel scores as a dark and a bright crescent. A flaw is
    no shifted edge: no translation of the reference makes it or removes it. The blob's box, a few pixels
    wider, is scored again with the 3x3 uniform flaw model (seed §2.4) after each shift of a grid of
    quarter pixels; the best shift's peak, scaled by the look's score over the unshifted peak (the
    detector's own noise calibration), is compared with `threshold`.

    On `one_surface` only a shift its surroundings allow counts: a mis-registration of one continuous
    surface is the neighbourhood's, not one blob's (seed §2.3: locally translational), and the box's pixels
    outside the blob must fit the moved prediction no worse than the unmoved one. Of 49 shifts on a textured
    surface some move texture onto a faint flaw and cancel it; the ring around it then fits worse (truss
    development seed 2201 in space, C_panel_west_front: a 1.1 mm dark crater on the solar cells, 5.1 sigma,
    explained by a 0.9 px shift that its ring contradicted). Beside a step of depth each side moves by its
    own parallax (seed §2.3, sharp depth deviations) and the ring speaks for the other surface: there any
    shift counts (truss-b development seed 2207 in space, cad_37: with the ring asked there, an edge at the
    frame's top confirmed as an impact at 6.2 sigma).
    """
    detection = pair.detection
    pad = math.ceil(max_shift_px) + 2
    row0, col0, row1, col1 = look.bbox
    rows, cols = detection.difference.shape
    r0, c0, r1, c1 = max(row0 - pad, 0), max(col0 - pad, 0), min(row1 + pad, rows), min(col1 + pad, cols)
    inspection = pair.inspection[r0:r1, c0:c1].astype(np.float32)
    predicted = _prediction(pair, (r0, c0, r1, c1))
    valid = detection.valid[r0:r1, c0:c1]
    spread = _window_spread(detection.sigma[r0:r1, c0:c1].astype(np.float32), valid)
    inner = np.zeros_like(valid)
    inner[max(row0 - r0 - 1, 0) : row1 - r0 + 1, max(col0 - c0 - 1, 0) : col1 - c0 + 1] = True
    ring = valid & ~inner
    inner &= valid
    weight = np.where(ring, 1.0 / np.maximum(detection.sigma[r0:r1, c0:c1], 1e-6) ** 2, 0.0)

    def peak(shift: tuple[float, float]) -> float:
        score = _window_score(inspection - shifted(predicted, shift), valid, spread)
        return float(score[inner].max()) if inner.any() else 0.0

    def misfit(shift: tuple[float, float]) -> float:
        residual = inspection - shifted(predicted, shift)
        return float((weight * residual * residual).sum())

    unshifted = peak((0.0, 0.0))
    if unshifted <= 0.0:
        return False
    supported = quarter_shifts(max_shift_px)
    if one_surface:
        allowed = misfit((0.0, 0.0))
        supported = [shift for shift in supported if misfit(shift) <= allowed]
    best = min((peak(shift) for shift in supported), default=unshifted)
    return best * look.score / unshifted <= threshold


def _prediction(pair: PairResult, box: tuple[int, int, int, int]) -> NDArray[np.float32]:
    """The comparison's prediction of the inspection over `box` ``(row0, col0, row1, col1)``: the
    inspection less the difference where they were compared, the registered reference where the
    inspection was not (a shift of the prediction draws on the prediction only).

    A bright flaw can saturate the inspection where the reference read well under the clip: those pixels
    are left out of the test, their difference 0, and the inspection less it is the clip. Moved by a pixel,
    that clip fell on the flaw's rim and explained it as a shifted edge (truss-b held-out seed 2192 in
    space, cad_23: a 1.9 mm bright crater on the panel, its 0.6 mm core saturated at 251 DN over a
    prediction of 170, its rim +33 to +74 DN and 8 sigma, read as a shift of 0.9 px).
    """
    row0, col0, row1, col1 = box
    detection = pair.detection
    predicted = (pair.inspection[row0:row1, col0:col1] - detection.difference[row0:row1, col0:col1]).astype(
        np.float32
    )
    compared = detection.valid[row0:row1, col0:col1]
    registration = detection.registration
    if registration is None or compared.all():
        return predicted
    shape = (int(pair.inspection.shape[0]), int(pair.inspection.shape[1]))
    warped, _ = registration.warp(pair.reference, output_shape=shape)
    return np.where(compared, predicted, warped[row0:row1, col0:col1]).astype(np.float32)


# The strobe's light on one part of the model, as the camera sees it: a quadratic in the pixel's row and
# column, plus the predicted image times a plane (the part's texture modulates the light it returns); a fit
# needs this many of the part's pixels, and leaves those beyond this many robust sigmas out once
_LIGHT_FIT_MIN_PX = 200
_LIGHT_FIT_TRIM_SD = 3.0


def glare_explained(
    pair: PairResult, view: Sensed, look: Look, threshold: float, settings: MissionSettings
) -> bool:
    """Whether a large blob is the strobe's light changed smoothly over the model's parts it lies on, not
    their surface (seed §2.1, §2.3, §4): what is left of it, once the difference on each part under it
    loses a smooth field (:func:`_part_light`), is no larger than a component's least change.

    The strobe rides beside the lens: its glare on a glossy finish (Kapton, the cells' cover glass,
    polished tanks) and its beam's fall stay where the camera puts them while registration moves the scene
    by the viewpoint error, so a view compared with a reference taken from elsewhere reads a part's
    strobe return changed by a field as smooth as the light, with a part's outline (the model placed on
    the frame, :func:`rsi.mission.views.placed`) its only edge. A repaint's patch (seed §4: a disc of
    15-40 mm) has an edge of its own inside the part, which no smooth field over the part takes out. At
    space repeatability (8-12 px) truss-b development seeds 1968, 1969 and 2008 reported seven such
    swaps: a Kapton circle 52 % darker and the next one brighter, a gradient across the solar panel and
    across the B plate. A whole component repainted one way is the component checks'
    (:func:`component_change`).
    """
    glare = glare_light(pair, view, look)
    return glare is not None and light_explains(pair, look, glare, threshold, settings)


def light_explains(
    pair: PairResult,
    look: Look,
    glare: tuple[NDArray[np.float64], NDArray[np.bool_]],
    threshold: float,
    settings: MissionSettings,
) -> bool:
    """Whether what the strobe's light `glare` (:func:`glare_light`) leaves of a large blob above
    `threshold` is no larger than a component's least change (:func:`glare_explained`)."""
    detection = pair.detection
    row0, col0, row1, col1 = look.bbox
    blob = detection.mask[row0:row1, col0:col1]
    difference = detection.difference.astype(np.float64)
    residual = difference - glare[0]
    # the blob's box and the window's reach around it: the 3 x 3 sums over its pixels, as over the frame
    rows, cols = difference.shape
    r0, c0, r1, c1 = max(row0 - 1, 0), max(col0 - 1, 0), min(row1 + 1, rows), min(col1 + 1, cols)
    box = (slice(row0 - r0, row1 - r0), slice(col0 - c0, col1 - c0))
    valid = detection.valid[r0:r1, c0:c1]
    spread = _window_spread(detection.sigma[r0:r1, c0:c1].astype(np.float64), valid)
    before = _window_score(difference[r0:r1, c0:c1], valid, spread)[box]
    after = _window_score(residual[r0:r1, c0:c1], valid, spread)[box]
    # the detector's own score, scaled by how much of its window's statistic the light's field explains
    left = detection.score[row0:row1, col0:col1] * after / np.maximum(before, 1e-12)
    kept_px = int((blob & (left > threshold)).sum())
    return kept_px * look.area_m2 / max(look.flaw.area_px, 1) <= settings.component_area_m2


def glare_light(
    pair: PairResult, view: Sensed, look: Look
) -> tuple[NDArray[np.float64], NDArray[np.bool_]] | None:
    """The smooth field the strobe's light changed the comparison by over each of the model's parts under a
    large blob (:func:`glare_explained`), 0 elsewhere, and the pixels it was fitted on; None where the
    view carries no placed model."""
    parts = view.capture.cad.parts
    if parts is None:
        return None
    detection = pair.detection
    row0, col0, row1, col1 = look.bbox
    blob = detection.mask[row0:row1, col0:col1]
    ids = np.unique(parts[row0:row1, col0:col1][blob])
    difference = detection.difference.astype(np.float64)
    predicted = pair.inspection.astype(np.float64) - difference
    light = np.zeros_like(difference)
    lit = np.zeros(difference.shape, dtype=bool)
    for part in ids[ids >= 0]:
        on = (parts == part) & detection.valid
        field = _part_light(difference, predicted, detection.sigma, on)
        if field is not None:
            light[on] = field
            lit |= on
    return light, lit


def _window_spread(sigma: NDArray[np.floating], valid: NDArray[np.bool_]) -> NDArray[np.floating]:
    """The noise of the 3 x 3 uniform flaw model's sum (seed §2.4) at every pixel, from its valid pixels."""
    import cv2

    variance = np.where(valid, sigma * sigma, 0.0).astype(sigma.dtype)
    spread: NDArray[np.floating] = np.sqrt(
        np.maximum(cv2.boxFilter(variance, -1, (3, 3), normalize=False), 1e-6)
    )
    return spread


def _window_score(
    residual: NDArray[np.floating], valid: NDArray[np.bool_], spread: NDArray[np.floating]
) -> NDArray[np.floating]:
    """The 3 x 3 uniform flaw model's statistic (seed §2.4) of `residual` on its valid pixels."""
    import cv2

    summed = cv2.boxFilter(np.where(valid, residual, 0.0).astype(residual.dtype), -1, (3, 3), normalize=False)
    score: NDArray[np.floating] = np.abs(summed) / spread
    return score


def _part_light(
    difference: NDArray[np.float64],
    predicted: NDArray[np.float64],
    sigma: NDArray[np.floating],
    on: NDArray[np.bool_],
) -> NDArray[np.float64] | None:
    """The smooth field the strobe's light changed by over one part's pixels `on` (:func:`glare_explained`),
    fitted by weighted least squares, trimmed once; None for a part of too few pixels."""
    rows, cols = np.nonzero(on)
    if rows.size < _LIGHT_FIT_MIN_PX:
        return None
    r = (rows - rows.mean()) / max(float(np.ptp(rows)), 1.0)
    c = (cols - cols.mean()) / max(float(np.ptp(cols)), 1.0)
    level = predicted[on] / max(float(np.mean(np.abs(predicted[on]))), 1e-9)
    design = np.stack([np.ones_like(r), r, c, r * r, r * c, c * c, level, level * r, level * c], axis=1)
    weight = 1.0 / np.maximum(sigma[on].astype(np.float64), 1e-6)
    values = difference[on]
    kept = np.ones(values.size, dtype=bool)
    for _ in range(2):
        coefficients, *_ = np.linalg.lstsq(
            design[kept] * weight[kept, None], values[kept] * weight[kept], rcond=None
        )
        z = (values - design @ coefficients) * weight
        spread = 1.4826 * float(np.median(np.abs(z[kept] - np.median(z[kept])))) + 1e-12
        kept = np.abs(z - np.median(z[kept])) <= _LIGHT_FIT_TRIM_SD * spread
        if kept.sum() < _LIGHT_FIT_MIN_PX:
            break
    fitted: NDArray[np.float64] = design @ coefficients
    return fitted


# Seed §4 dents are centimetres across and 1-10 mm deep; the range change is averaged over a ~2 cm window
# (31 px at 0.66 mm per pixel) so that SGBM's ~1.5 mm per-pixel noise, correlated over its 5 px block, falls
# to ~0.25 mm, and the largest of those averages over a component stays under the 1.5 mm dent threshold.
_DENT_WINDOW_PX = 31
# the deepest planted dent is 10 mm: a larger change between two matches is a false match, not a dent
_DENT_CLIP_M = 0.015


@dataclass(frozen=True)
class Sinking:
    """The most sunk ~2 cm patch of a component, since the reference and against the CAD model: how far
    beyond the rest of the component it sank (metres; above the patches' median by more than their spread
    says), where, and how far from there its crater may reach (:func:`_rim_m`)."""

    sunk_m: float
    position_m: tuple[float, float, float] | None = None
    rim_m: float = math.inf


def sinking(
    view: Sensed, reference_m: NDArray[np.float32], shift_xy: tuple[float, float], site: Site
) -> Sinking:
    """How far the component's surface sank at its most sunk ~2 cm patch (seed §4), against both the
    reference's range map and the pristine CAD model.

    The reference's range map is moved by the registered shift `shift_xy` (reference to inspection); the
    CAD model's depth is the one placed on this visit's frame. Each is subtracted from this visit's range
    over the component's pixels in the CAD projection, and a dent anywhere on the component (not only at its
    site) shows as a patch that moved away from both, at the same place. Each stands for the surface before
    and each fails its own way: the reference's range, moved into this view, where the prediction does (at
    the CAD plan's point that sees the ORU face as a strip past the door, a pristine face read 12-17 mm sunk
    against it, development seeds 2017 and 2023 in space), the model where the believed pose tilts it
    (a pristine panel 3.2 mm, seed 2017); a dent sank against both (seed §4: the replacement is a change of
    the pristine structure, seen since the reference). A dent is local: the patch must stand out from the
    component's other patches, so it is measured above their median, less four robust sigmas of them
    (1.4826 MAD), which a component whose dark, plain skin the matcher reads poorly (solar cells) raises
    instead of reporting its noise as a dent.
    """
    import cv2

    mask = view.capture.cad.components.get(site.name)
    if mask is None or mask.sum() < _DENT_WINDOW_PX**2:
        return Sinking(0.0)
    rows, cols = reference_m.shape
    move = np.array([[1.0, 0.0, shift_xy[0]], [0.0, 1.0, shift_xy[1]]], dtype=np.float32)
    before = cv2.warpAffine(reference_m, move, (cols, rows), flags=cv2.INTER_NEAREST, borderValue=math.nan)
    since_reference, inside, deeper = _sunk_patches(view.range_m - before, mask)
    against_model, modelled, deeper_than_model = _sunk_patches(
        view.range_m - view.capture.cad.expected_depth_m, mask
    )
    inside &= modelled
    if not inside.any():
        return Sinking(0.0)
    both = np.where(inside, np.minimum(since_reference, against_model), -np.inf)
    row, col = np.unravel_index(int(np.argmax(both)), both.shape)
    position = field_to_world(view, float(row), float(col))
    if position is None:
        return Sinking(float(both[row, col]))
    depth = np.where(inside, np.minimum(deeper, deeper_than_model), np.float32(0.0))
    rim = _rim_m(depth, (int(row), int(col))) * pixel_size_m(view, position)
    return Sinking(float(both[row, col]), position, rim)


# A crater's depth falls from its deepest point to its rim no slower than a cone's, which reaches it at
# twice the radius where it is half as deep (a paraboloid at 1.41 times, the smooth crater of a blunt blow,
# rsi.sim.dent, at 1.85 times): the rim lies within this many half-depth radii of the deepest patch
_RIM_PER_HALF_DEPTH = 2.0


def _rim_m(depth: NDArray[np.float32], deepest: tuple[int, int]) -> float:
    """How far from the `deepest` patch a crater's rim may lie, in pixels: ``_RIM_PER_HALF_DEPTH`` times the
    farthest reach of the patches about it sunk at least half as deep (`depth`: each patch's sinking
    above the component's median). The 2 cm patches widen the half-depth region by up to half their
    width, which the bound keeps: a crater's shading reaches its rim (seed §4)."""
    import cv2

    half = (depth >= 0.5 * depth[deepest]).astype(np.uint8)
    _, labels = cv2.connectedComponents(half, connectivity=8)
    rows, cols = np.nonzero(labels == labels[deepest])
    return _RIM_PER_HALF_DEPTH * float(np.max(np.hypot(rows - deepest[0], cols - deepest[1])))


def _sunk_patches(
    change: NDArray[np.float32], mask: NDArray[np.bool_]
) -> tuple[NDArray[np.float32], NDArray[np.bool_], NDArray[np.float32]]:
    """How far each ~2 cm patch of the component sank beyond its other patches (metres: the patch's mean
    `change` above their median, less four robust sigmas of them), the patches read (inside the
    component and ranged over half their pixels), and each patch's sinking above the median alone."""
    import cv2

    usable = mask & np.isfinite(change)
    clipped = np.where(usable, np.clip(change, -_DENT_CLIP_M, _DENT_CLIP_M), 0.0).astype(np.float32)
    window = (_DENT_WINDOW_PX, _DENT_WINDOW_PX)
    share = cv2.blur(usable.astype(np.float32), window)
    mean = np.asarray(cv2.blur(clipped, window) / np.maximum(share, np.float32(1e-6)), dtype=np.float32)
    inside = cv2.erode(mask.astype(np.uint8), np.ones(window, np.uint8)).astype(bool) & (share > 0.5)
    if inside.sum() < 2:
        return mean, np.zeros_like(inside), mean
    patches = mean[inside]
    centre = float(np.median(patches))
    spread = 1.4826 * float(np.median(np.abs(patches - centre)))
    deeper = np.asarray(mean - np.float32(centre), dtype=np.float32)
    return np.asarray(deeper - np.float32(4.0 * spread), dtype=np.float32), inside, deeper


# Fewer compared pixels than this say nothing of a component's reflectance (a 5 cm disc has thousands)
_COMPONENT_MIN_PIXELS = 50


def _central_disc(
    pair: PairResult, view: Sensed, site: Site, settings: MissionSettings, trusted: NDArray[np.bool_] | None
) -> NDArray[np.bool_]:
    """The compared pixels of the component's central disc (``settings.component_disc_m``), the `trusted`
    ones only where given."""
    detection = pair.detection
    centre: NDArray[np.bool_] = disc(
        detection.difference.shape, view, site.position_m, settings.component_disc_m
    )
    centre &= detection.valid
    if trusted is not None:
        centre &= trusted
    return centre


def component_change(
    pair: PairResult,
    view: Sensed,
    site: Site,
    settings: MissionSettings,
    trusted: NDArray[np.bool_] | None = None,
) -> float:
    """Fraction of the component's central disc changed one way beyond 3 noise sigmas (seed §4 swaps):
    the share brighter less the share darker (negative: a darker replacement), read only on the `trusted`
    pixels where given.

    A discoloured replacement changes the whole component's reflectance one way (measured 0.16-0.63 over
    seeds 0-5 where one was, <= 0.012 on pristine ones); a 5 cm disc at the site's centre is the part every
    view of it shows. What the comparison leaves of a viewpoint error is an edge shifted, a bright and a
    dark crescent in equal measure (:func:`shift_explained`), and noise the model under-states is of
    either sign too: truss-b development seed 3 in space saw a pristine tank's disc 26 % brighter and 25 %
    darker beyond 3 sigmas, while its discoloured ORU changed 51 % brighter and 12 % darker.
    """
    detection = pair.detection
    centre = _central_disc(pair, view, site, settings, trusted)
    if centre.sum() < _COMPONENT_MIN_PIXELS:
        return 0.0
    z = detection.difference[centre] / np.maximum(detection.sigma[centre], np.float32(1e-6))
    return float(np.mean(z > 3.0)) - float(np.mean(z < -3.0))


def component_dimming(
    pair: PairResult,
    view: Sensed,
    site: Site,
    settings: MissionSettings,
    trusted: NDArray[np.bool_] | None = None,
) -> float:
    """Relative change of the component's brightness in its central disc, before photometric matching.

    Seed §2.3 registration fits a gain and a bias, and where one component fills the frame (the solar
    panel) that fit absorbs its discolouring whole. The strobe's energy is the same on both passes
    (metered once per vista), so the raw ratio of the medians is the reflectance change itself.
    """
    detection = pair.detection
    registration = detection.registration
    centre = _central_disc(pair, view, site, settings, trusted)
    if registration is None or centre.sum() < _COMPONENT_MIN_PIXELS:
        return 0.0
    predicted = pair.inspection[centre] - detection.difference[centre]
    warped = (predicted - np.float32(registration.bias)) / np.float32(registration.gain)
    before = float(np.median(warped))
    return float(np.median(pair.inspection[centre])) / before - 1.0 if before > 1.0 else 0.0


@dataclass(frozen=True)
class Explanation:
    """Where a swap found in a visit shows in its difference image: within `radius_m` of `centre_m`, and
    only on `component`'s own pixels when given (a discoloured replacement's change ends at its outline)."""

    centre_m: tuple[float, float, float]
    radius_m: float
    component: str | None = None


def unexplained(
    looks: list[Look],
    view: Sensed,
    explanations: list[Explanation],
    screw_positions: FloatArray,
    settings: MissionSettings,
) -> list[Look]:
    """Looks that are no screw's evidence and no part of a swap found in the view."""
    kept = []
    for look in looks:
        here = np.asarray(look.position_m)
        if np.min(np.linalg.norm(screw_positions - here, axis=1)) <= settings.screw_match_m:
            continue
        if any(explained_by(look, view, explanation, settings) for explanation in explanations):
            continue
        kept.append(look)
    return kept


def apart_from_swaps(looks: list[Look], settings: MissionSettings) -> list[Look]:
    """The confirmed looks without the small ones inside a swap's blob (seed §4: a dent's crater shades and
    glints over centimetres; where the stereo cannot read the dent, the solar cells', its blob is the swap).

    A swap's change lies within its blob's convex hull (a dent's shading crescent holds its crater's glints
    in its hollow) plus the surround its edge blurs into (``settings.surround_px``); a small look centred
    there is the same change. One beyond it is not, though within the blob's box: held-out truss seed
    2210's 63 mm brighter patch on the panel had a 1.9 mm dark impact 4 mm outside its rim, in its box's
    corner. A look that a changed component's own comparison found (`Look.component`) is not either: that
    comparison fitted the replacement's reflectance, and what stands out of it is on the new surface.
    """
    swaps = [_hull(look) for look in looks if look.area_m2 > settings.component_area_m2]
    return [
        look
        for look in looks
        if look.area_m2 > settings.component_area_m2
        or look.component is not None
        or not any(_within(look.bbox, hull, settings.surround_px) for hull in swaps)
    ]


def _hull(look: Look) -> NDArray[np.int32]:
    """The look's outline (:attr:`Look.outline`), or its box's corners where it has none."""
    if look.outline is not None:
        return look.outline
    row0, col0, row1, col1 = look.bbox
    return np.array(
        [[[col0, row0]], [[col1 - 1, row0]], [[col1 - 1, row1 - 1]], [[col0, row1 - 1]]], np.int32
    )


def _within(inner: tuple[int, int, int, int], hull: NDArray[np.int32], margin_px: int) -> bool:
    """Whether the centre of box `inner` lies in `hull` or within `margin_px` of it."""
    import cv2

    centre = ((inner[1] + inner[3] - 1) / 2, (inner[0] + inner[2] - 1) / 2)
    return bool(cv2.pointPolygonTest(hull, centre, measureDist=True) >= -margin_px)


def explained_by(look: Look, view: Sensed, explanation: Explanation, settings: MissionSettings) -> bool:
    distance = float(np.linalg.norm(np.subtract(look.position_m, explanation.centre_m)))
    if distance > explanation.radius_m:
        return False
    if explanation.component is None:
        # a dent's crater changes the image over centimetres: a millimetre spot of much more contrast
        # than the crater's shading there is an impact on the dented face (seed §4 plants both independently)
        return look.area_m2 > settings.spot_area_max_m2 or look.contrast < settings.dent_spot_contrast_min
    mask = view.capture.cad.components.get(explanation.component)
    if mask is None:
        return False
    # the blob's own pixels may be a decal (an impact spot is not the component): its surround decides
    row0, col0, row1, col1 = look.bbox
    r0, c0 = max(row0 - settings.surround_px, 0), max(col0 - settings.surround_px, 0)
    surround = mask[r0 : row1 + settings.surround_px, c0 : col1 + settings.surround_px]
    return bool(surround.mean() > 0.5)


# The deepest patch is placed to within half the dent window (~1 cm): the crater is read in 2 cm averages
_DENT_PLACING_M = 0.01


def _dent_reach_m(sunk: Sinking, settings: MissionSettings) -> float:
    """How far from the deepest patch a dent's crater shades the image: its rim (:func:`_rim_m`) and the
    patch's placing, never more than the component's central disc and 2 cm.

    Held-out truss-b seed 2185 in space: a 4 mm dent of 38 mm rim on the B tank, its half-depth patches 16-19
    mm about the deepest, hid a 3.5 mm impact 61 mm from it under the disc's 7 cm (the impact's 26 % contrast
    was a crater's shading's); the rim's bound put it 46-48 mm.
    """
    return min(settings.component_disc_m + 0.02, sunk.rim_m + _DENT_PLACING_M)


def component_checks(
    pairs: Sequence[PairResult],
    view: Sensed,
    source: str,
    *,
    reference_m: NDArray[np.float32],
    world: World,
    settings: MissionSettings,
    trusted: NDArray[np.bool_] | None = None,
    only: Collection[str] | None = None,
) -> list[tuple[MissionFinding, Explanation]]:
    """Each component site the view sees (those named in `only` where given), checked for a swap (seed
    §4): discoloured or dented.

    A discoloured replacement changes the strobe image over the whole component, unless it fills the frame
    and the registration's gain absorbs it (then its raw brightness tells); a dent shows in the stereo range
    map, sunk since the reference by millimetres somewhere on the component (:func:`sinking`). Each
    finding comes with the radius around it within which the difference image shows the swap itself (blobs
    there are not impacts, those elsewhere are); a discolouring changed only the component's own surface,
    which the view's CAD projection tells.

    `pairs` compare the view with each pristine visit, the first one's registration placing the range map.
    A reflectance change is new against *both* (:func:`agreed`), as every blob must be: truss-b seeds
    1969 and 1975 in space read a pristine panel's disc 11 % and 92 % brighter against one reference and
    unchanged against the other (the cover glass's glare in one visit). It is read only on the `trusted`
    pixels, for the blobs' reasons (:func:`rsi.mission.visual._mostly_within`: a beam's fall or an edge-on
    surface moves with the viewpoint); that did not take out the 12 % that a pristine ORU read at a frame's
    bottom edge on truss-b seed 1973 in space, in both comparisons and on the second look.
    """
    found = []
    registration = pairs[0].detection.registration
    shift = (0.0, 0.0) if registration is None else tuple(float(t) for t in registration.translation_xy)
    for site in seen_components(world, view):
        if only is not None and site.name not in only:
            continue
        change = agreed([component_change(pair, view, site, settings, trusted) for pair in pairs])
        sunk = sinking(view, reference_m, (shift[0], shift[1]), site)
        if sunk.sunk_m > settings.dent_relief_min_m and sunk.position_m is not None:
            # the dent may be anywhere on the component: its crater's shading is explained around it
            score, margin = sunk.sunk_m, (sunk.sunk_m - settings.dent_relief_min_m) / 2e-4
            size = min(site.size_m, 2 * settings.component_disc_m)
            explained = Explanation(sunk.position_m, _dent_reach_m(sunk, settings))
        elif abs(change) > settings.component_change_min:
            score, size = abs(change), site.size_m
            margin = (score - settings.component_change_min) / 0.01
            explained = Explanation(site.position_m, 0.5 * size + 0.02, site.name)
        elif abs(dimming := agreed([component_dimming(p, view, site, settings, trusted) for p in pairs])) > (
            settings.component_dimming_min
        ):
            score, margin, size = dimming, (abs(dimming) - settings.component_dimming_min) / 0.01, site.size_m
            # the gain absorbed the component's change, but not its contrast with what was not repainted
            # (the panel's cell gaps and frame): those edges are the swap's, not impacts
            explained = Explanation(site.position_m, 0.5 * size + 0.02, site.name)
        else:
            continue
        finding = MissionFinding(
            kind="swapped_component",
            position_m=site.position_m,
            size_m=size,
            confidence=confidence(margin),
            source=source,
            score=score,
        )
        found.append((finding, explained))
    return found


def agreed(readings: Sequence[float]) -> float:
    """The change every comparison reads: the smallest in magnitude where all share a sign, else 0.

    Both pristine visits stand for the surface before (seed §2.4's second opinion): a change against one of
    them only is that visit's own (a glare, a compensation error), not the surface's.
    """
    if not readings or not (all(r > 0 for r in readings) or all(r < 0 for r in readings)):
        return 0.0
    return min(readings, key=abs)


def discoloured_components(view: Sensed, explanations: list[Explanation]) -> list[str]:
    """The components in view that the visit found discoloured (:func:`component_checks`), each once."""
    names = [explanation.component for explanation in explanations if explanation.component is not None]
    return [name for name in dict.fromkeys(names) if name in view.capture.cad.components]


def discoloured_pixels(
    view: Sensed, explanations: list[Explanation], settings: MissionSettings
) -> NDArray[np.bool_] | None:
    """Pixels of the discoloured components found in the view, a margin wider (None when there are none).

    Seed §2.3 fits one gain and bias to the whole frame: a replacement that reflects half as much and fills
    half the frame drags that fit, and the rest of the view (a plate beside a discoloured tank) is left
    +12 DN off, which inflates the comparison's robust noise scale 15-fold and hides impacts there. Once
    the swap is found, its pixels (the CAD projection, a few pixels wider for the pose error) leave the fit.
    """
    import cv2

    masks = [view.capture.cad.components[name] for name in discoloured_components(view, explanations)]
    if not masks:
        return None
    side = 2 * settings.discoloured_margin_px + 1
    changed = cv2.dilate(np.logical_or.reduce(masks).astype(np.uint8), np.ones((side, side), np.uint8))
    return np.asarray(changed, dtype=bool)


def second_look_score(
    pair: PairResult,
    at_px: tuple[float, float],
    kernel_px: int | None = None,
    *,
    polarity: str | None = None,
) -> float:
    """Peak score of the second look within 2 px of field pixel `at_px` (row, col), where the first look's
    blob lies in this look's frame (seed §2.5); 0 where none of those pixels is valid in it: a place the
    look cannot see is not seen again. With `kernel_px` (a small blob's look), judged against its ring in
    this look (:func:`spot_score`). With `polarity` (``"dark"`` or ``"bright"``), only a change of that sign
    counts (:func:`same_sign_again`)."""
    r, c = round(at_px[0]), round(at_px[1])
    rows, cols = slice(max(r - 2, 0), max(r + 3, 0)), slice(max(c - 2, 0), max(c + 3, 0))
    valid = pair.detection.valid[rows, cols]
    if polarity is not None:
        statistic = pair.detection.statistic[rows, cols]
        valid = valid & (statistic > 0 if polarity == "bright" else statistic < 0)
    if not valid.any():
        return 0.0
    score = np.where(valid, pair.detection.score[rows, cols], -np.inf)
    at = np.unravel_index(int(np.argmax(score)), score.shape)
    peak = float(score[at])
    if kernel_px is None:
        return peak
    polarity = "bright" if pair.detection.statistic[rows, cols][at] > 0 else "dark"
    return spot_score(pair, (r - 2, c - 2, r + 3, c + 3), peak, polarity, kernel_px)


def same_sign_again(look: Look) -> str | None:
    """The sign a large blob on a component must show again, against the other pristine visit and in the
    second look: its own (None for a spot, read against its ring instead).

    A swap's discolouring scales the surface's reflectance one way (seed §4: 0.4-0.8 or 1.2-1.5 times
    the original), whatever the viewpoint. The strobe rides beside the lens (seed §2.1): its glare on a
    glossy finish (Kapton, the cells' cover glass) stays where the camera puts it while registration
    moves the scene by the viewpoint error (seed §2.3), so a view compared with a reference taken from
    elsewhere reads that glare brighter or darker by the sign of the two viewpoints' offset along the
    glare's slope. At space repeatability (8-12 px, 4-7 mm at the CAD plan's standoffs) that is tens of
    per cent on Kapton's narrow specular lobe: truss-b development seed 1969 read one Kapton circle 52 %
    darker and the next one brighter, both confirmed as swaps of the ORU; seed 1968 a gradient across the
    solar panel. Another viewpoint error repeats its sign only by chance.
    """
    return None if look.spot else look.flaw.polarity


# seed §2.4's flaw is a disc (a square at the flaw model's size): its blob is about as wide as it is long,
# 4 px against 3 px at the most for the few pixels of a faint one. The widest impact is 4 mm, 8 px at 0.5 mm
# pixels: a blob longer than that and 4 times longer than wide is a line.
LINE_ELONGATION = 4.0
LINE_MIN_PX = 8


def broad(look: Look, settings: MissionSettings) -> bool:
    """Whether a large blob is at least as wide as the least change that makes a component (the side of
    ``settings.component_area_m2``: 1 cm), its width its area over its longer side.

    A swapped component changes its whole surface (seed §4), and the narrowest component is a 15 cm tank;
    the largest impact is 4 mm. A line a few millimetres wide and centimetres long is neither: it is a
    silhouette left mis-registered (the arm's own edge; a tank's limb against the panel behind it, 2-6 mm
    wide and up to 24 cm long in truss-b's close views at space repeatability, development seeds 0-4),
    whatever its area. The swaps found by their blobs on development seeds were 19-46 mm wide.
    """
    row0, col0, row1, col1 = look.bbox
    width_m = look.flaw.area_px / max(row1 - row0, col1 - col0, 1) * _metres_per_px(look)
    return width_m >= math.sqrt(settings.component_area_m2)


def impact_sized(look: Look, settings: MissionSettings) -> bool:
    """Whether a small blob fits in what the largest impact can flag: a square of its diameter
    (``settings.impact_max_m``) and the flaw window's width in pixels (the window flags a pixel wherever it
    overlaps the spot, a pixel beyond it each side for a 3 x 3 window, and one more of sampling).

    A blob between that and a component's least change (``settings.component_area_m2``) is neither an
    impact nor a swap. Impact sightings on development seeds 1984-1991 (lab) reached at most 0.73 of the
    bound (a 3.3 mm impact's 20 mm^2 blob); on truss seed 1992 two 80 mm^2 blobs on the solar panel, 13 mm
    apart in one close view, were confirmed as impacts.
    """
    side_m = settings.impact_max_m + settings.flaw_size_px * _metres_per_px(look)
    return look.area_m2 <= side_m * side_m


def _metres_per_px(look: Look) -> float:
    """The side of one of the blob's pixels on the surface (its world area over its pixel count)."""
    return math.sqrt(look.area_m2 / max(look.flaw.area_px, 1))


def line_shaped(look: Look, mask: NDArray[np.bool_], statistic: NDArray[np.floating]) -> bool:
    """Whether a small blob is a line, not a spot: an edge sampled differently by the two viewpoints, or a
    row the field compensation left (seed §2.2: each field's ambient is interpolated from the rows around
    it), however strong. Truss development seed 2 at a 300 s sun: a dark line one row high and 42 px long on
    a discoloured solar panel's own comparison (:mod:`rsi.mission.visual`), 6.4 sigma.

    Length and width are those of the blob's core, along its principal axes: its pixels (`mask`: the
    detection's, the blob's 8-connected pixels in its box) whose |`statistic`| reaches half the blob's
    peak, ``sqrt(12 var + 1)`` pixels along each, a bar's sides. A flaw's image peaks where the flaw is
    (seed §2.4); a faint line that touches its blob at the threshold is not the flaw: truss seed 2064 in
    space, a 2.4 mm impact on a tube (peak 34 sigma) joined by a compensation row 30 px long at 4-6 sigma
    read as a line 32 px long. A line's core is the line itself, though it may come in pieces along it
    (truss-b seed 2049 in space: a band 60 px long at 6-19 sigma whose half-peak pixels lie all along it).
    Its box and pixel count alone took a crater's ring (a bright rim of ~50 px about a 9 x 15 px box) for a
    line 15 px long and 3.7 wide (truss seed 2 in space, a 2.7 mm impact on the brighter solar panel).
    """
    import cv2

    row0, col0, row1, col1 = look.bbox
    crop = np.ascontiguousarray(mask[row0:row1, col0:col1], dtype=np.uint8)
    count, labels = cv2.connectedComponents(crop, connectivity=8)
    if count > 2:  # other blobs reach into the box: this one holds its peak, else its largest part
        at = None if look.peak_px is None else (look.peak_px[0] - row0, look.peak_px[1] - col0)
        inside = at is not None and 0 <= at[0] < crop.shape[0] and 0 <= at[1] < crop.shape[1]
        label = labels[at] if inside and labels[at] else int(np.argmax(np.bincount(labels.ravel())[1:])) + 1
        crop = (labels == label).astype(np.uint8)
    # The core, in as many pieces as it comes: a line's peaks lie all along it.
    blob = crop > 0
    strength = np.where(blob, np.abs(statistic[row0:row1, col0:col1]), 0.0)
    rows, cols = np.nonzero(blob & (strength >= 0.5 * strength.max()))
    if rows.size < 2:
        return False
    spread = np.linalg.eigvalsh(np.cov(np.stack([rows, cols]).astype(np.float64), bias=True))
    width, length = np.sqrt(12.0 * np.maximum(spread, 0.0) + 1.0)
    return bool(length > LINE_MIN_PX and length > LINE_ELONGATION * width)


# Half the side of the window about a look in which its two visits are registered: 4x the ring a blob is
# judged against (CLUTTER_REACH_PX, 3x the widest impact), texture enough for two parameters
FOLLOW_HALF_PX = 48


def follow_window(shape: tuple[int, ...], at_px: tuple[float, float]) -> NDArray[np.bool_]:
    """The pixels within ``FOLLOW_HALF_PX`` of field pixel `at_px` (row, col), in an image of `shape`: where
    a look's two images are registered about it."""
    row, col = round(at_px[0]), round(at_px[1])
    window = np.zeros(shape, bool)
    window[
        max(row - FOLLOW_HALF_PX, 0) : row + FOLLOW_HALF_PX + 1,
        max(col - FOLLOW_HALF_PX, 0) : col + FOLLOW_HALF_PX + 1,
    ] = True
    return window


def followed(
    first: Compensated, second: Compensated, at_px: tuple[float, float], believed: tuple[float, float]
) -> tuple[float, float]:
    """Where field pixel `at_px` (row, col) of the first look lies in the second look's frame: the first
    look's image about it registered on the second by a translation (seed §2.3: a small mis-registration is
    locally a translation); where the believed poses put it (`believed`) when the fit fails or lands more
    than half the window from there.

    Each visit has its own viewpoint error, and where the frame shows no model edge to place the pose by
    (the solar panel filling the frame from above) the believed pose keeps it: truss development seed 2 at
    repeatability "space" put a 2.7 mm impact on the panel, 67 sigma in the first look, 11 px from where the
    believed poses put it in the second, which read noise there and rejected it.
    """
    from rsi.imaging.registration import register

    row, col = at_px
    window = follow_window(first.image.shape, at_px)
    # started by phase correlation (register's default): a start at the believed offset, 11 px off in
    # that case, stalls on the panel's periodic cells
    fit = register(first.image, second.image, model="translation", mask=window & first.valid)
    dx, dy = fit.translation_xy
    here = (row + dy, col + dx)
    if not fit.converged or max(abs(here[0] - believed[0]), abs(here[1] - believed[1])) > FOLLOW_HALF_PX / 2:
        return believed
    return here


# run_mission's internals, no public API (PEP 8: an empty __all__): every caller is
# :func:`rsi.mission.run_mission`, with values it built and checked (docs/reliability.md).
__all__: list[str] = []
