"""One inspection visit of a plan point (seed §2.2-2.5): compare with the references, read the evidence,
take a second look at doubtful blobs, and report findings; then the findings of all visits fused.

A visit's steps, in order:

1. the strobe image (two frames, strobes in opposite fields) restricted to the inspection region;
2. the comparison with the reference, the parallax of the registered shift counted as noise (seed §2.3);
3. the stereo range map: screws by their relief, components by their change, dimming or dent (seed §4);
4. a discoloured component's pixels leave the photometric fit;
5. blobs, darker or brighter, that nothing explains, kept only if new against *both* pristine references;
6. doubtful blobs get a second look (seed §2.5 active inspection);
7. what is still above the confirming threshold becomes an impact or a swapped-component finding.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from functools import cached_property
from typing import TYPE_CHECKING, TypedDict

import numpy as np
from numpy.typing import NDArray

from rsi.errors import InputError
from rsi.imaging.compensation import compensate_field_pair
from rsi.mission.echoes import ambient_echo, echo_in
from rsi.mission.evidence import (
    CLUTTER_REACH_PX,
    Explanation,
    Look,
    apart_from_swaps,
    blobs,
    broad,
    component_checks,
    confidence,
    discoloured_components,
    discoloured_pixels,
    followed,
    glare_light,
    impact_sized,
    light_explains,
    line_shaped,
    same_sign_again,
    second_look_score,
    shift_explained,
    spot_score,
    unexplained,
)
from rsi.mission.exposure import ambient_bracket, shortened
from rsi.mission.fusion import component_of
from rsi.mission.photometry import PHOTOMETRIC_MIN_PIXELS, PHOTOMETRIC_TRIM_SIGMAS, photometric_refit
from rsi.mission.plan_point import PlanPoint
from rsi.mission.records import MissionFinding, VisitRecord
from rsi.mission.screws import HeadGlint, screw_checks
from rsi.mission.settings import MissionSettings
from rsi.mission.views import (
    FAR_M,
    Sensed,
    grown,
    inspection_region,
    jaws_region,
    near_model_edges,
    near_model_seams,
    own_body,
    seen_head_on,
    sense,
    to_field,
    within_strobe_beam,
)

if TYPE_CHECKING:
    from collections.abc import Mapping

    from rsi.detection.pair import PairResult
    from rsi.imaging.bracket import AmbientImage
    from rsi.imaging.compensation import Compensated
    from rsi.imaging.registration import Registration
    from rsi.mission.tour import Tour
    from rsi.sim.world import World


FloatArray = NDArray[np.float64]

# Seed §4's impacts are black tape, but a micrometeoroid spalls paint off and bares brighter metal: the
# comparison tests both signs (its thresholds count both tails, seed §2.4)
IMPACT_POLARITY = "both"
# A warped validity mask reads 1 only where every pixel it interpolates was valid
_KNOWN = 0.999


@dataclass(frozen=True)
class StoredView:
    """What the reference pass kept of one plan point for its inspection visits.

    Attributes
    ----------
    reference, second : Compensated
        The two pristine visits' full-resolution strobe images, each with its own compensation error.
    scale : ndarray of shape (M, N), float32
        Their nuisance factor on the variance (:func:`rsi.detection.nuisance.nuisance_scale`).
    range_m : ndarray of shape (M, N), float32
        The reference's stereo range map (NaN where unmatched), for the dents.
    reliefs : mapping of str to float
        Stereo relief of every screw site the reference saw, metres.
    glints : mapping of str to HeadGlint
        The flash's glint on every seen screw head in the reference (:func:`rsi.mission.screws.head_glint`).
    strobe_energy, shutter : float
        The metered flash energy and shutter, kept for every later visit of the point.
    second_range_m : ndarray of shape (M, N), float32, or None
        The second reference's stereo range map (NaN where unmatched), for its occlusions.
    surface_m, second_surface_m : ndarray of shape (M, N), float32, or None
        Each reference's surface (:attr:`rsi.mission.views.Sensed.surface_m`: its range, and its placed
        model's depth in the range's holes), for the occlusions where the stereo has no range; None: the
        range alone.
    ambient : AmbientImage or None
        The reference's ambient-lit image (:func:`rsi.mission.exposure.ambient_bracket`), for the looks'
        echo under the sun (:func:`rsi.mission.echoes.ambient_echo`); None: not taken.
    other_strobe : Compensated or None
        The reference's image under the ISEE's other strobe, for the looks' echo under it
        (:func:`rsi.mission.echoes.echo_in`); None: not taken.
    """

    reference: Compensated
    second: Compensated
    scale: NDArray[np.float32]
    range_m: NDArray[np.float32]
    reliefs: Mapping[str, float]
    strobe_energy: float
    shutter: float
    second_range_m: NDArray[np.float32] | None = None
    glints: Mapping[str, HeadGlint] = field(default_factory=dict)
    ambient: AmbientImage | None = None
    other_strobe: Compensated | None = None
    surface_m: NDArray[np.float32] | None = None
    second_surface_m: NDArray[np.float32] | None = None


def stored_strobe(view: Sensed, settings: MissionSettings, image: Compensated | None = None) -> Compensated:
    """A pristine visit's strobe image as the reference pass keeps it: without its view of the ISEE's own
    jaws and a guard band (``settings.inspection_guard_px``) about their edges.

    The jaws ride with the camera (:func:`rsi.mission.views.own_body`), but only in frames the arm's ISEE
    took: where the arm cannot reach a vista the tour takes the frame with the free camera, which holds the
    surface there. One pass may reach a vista and the other not; the inspection's own model then draws no
    jaws where the reference holds them, and without this the jaws' edges would be compared with the
    surface behind them (truss-b at space repeatability, 3.9 -> ~8 false impacts per run). `image`: another
    strobe image of the same visit (the other strobe's) kept the same way; the visit's own by default.
    """
    image = view.strobe if image is None else image
    own = own_body(view.capture.cad)
    if not own.any():
        return image
    return _restricted(image, ~grown(own, settings.inspection_guard_px))


@dataclass(frozen=True)
class Thresholds:
    """Score thresholds (noise sigmas) of the confirming and the preliminary test (seed §2.4-2.5)."""

    confirm: float
    preliminary: float


@dataclass(frozen=True)
class Visit:
    """One visit's findings and record, and the screws checked so far (each screw is checked once).

    The record holds what the robot measured; the truth of what its view showed is attached by the caller
    from the simulator's record (:func:`rsi.mission.truth.with_truth`), with `pair`, the comparison.
    """

    findings: tuple[MissionFinding, ...]
    record: VisitRecord
    screws_checked: frozenset[str]
    pair: PairResult
    explanations: tuple[Explanation, ...] = ()
    shown: frozenset[str] = frozenset()

    def unaware_of(self, explanations: tuple[Explanation, ...]) -> bool:
        """Whether a discoloured component among `explanations` (found by another visit) is one this visit
        showed but did not know of: its pixels stayed in this visit's photometric fit."""
        known = {explanation.component for explanation in self.explanations}
        found = {explanation.component for explanation in explanations} - known
        return bool(found & self.shown)


@dataclass
class _Comparison:
    """The images one visit compares, and their comparison (kept together while a discolouring is removed)."""

    reference: Compensated
    second: Compensated
    inspection: Compensated
    scale: NDArray[np.float32]
    pair: PairResult
    range_m: NDArray[np.float32]
    aligned: tuple[Registration | None, Registration | None] = (None, None)


class _Looking(TypedDict):
    """What one inspection viewpoint gives every reference predicted for it."""

    inspection: Compensated
    depth_m: NDArray[np.float32]
    own_body: NDArray[np.bool_]
    settings: MissionSettings


@dataclass(frozen=True)
class _Predicted:
    """Both pristine visits with the parallax of the inspection viewpoint taken out (seed §2.3 in depth),
    each in its own frame with the registration (its fitted shift) that then predicts the inspection; the
    reference's range map moved alike."""

    reference: Compensated
    second: Compensated
    range_m: NDArray[np.float32]
    shift_xy: tuple[float, float]
    aligned: tuple[Registration | None, Registration | None]


def compare(
    reference: Compensated,
    inspection: Compensated,
    p_false_alarm: float,
    settings: MissionSettings,
    scale: NDArray[np.float32] | None = None,
    *,
    registration: Registration | None = None,
) -> PairResult:
    """Register `reference` onto `inspection` (or take `registration`), test for flaws of either sign, the
    variance times `scale`."""
    from rsi.detection.detect import detect
    from rsi.detection.pair import PairResult, inspect_pair

    # seed §2.2: each pass's variance holds its own compensation error (rsi.imaging.compensate_field_pair),
    # whatever sun the other pass had: under a moved sun the reference's shadow edges say nothing of these
    ref, insp = reference, _with_clipped_flash(reference, inspection, registration, settings)
    if scale is not None:
        ref = replace(ref, variance=(ref.variance * scale).astype(np.float32))
        insp = replace(insp, variance=(insp.variance * scale).astype(np.float32))
    keywords = {
        "flaw_model": settings.flaw_model,
        "size": settings.flaw_size_px,
        "p_false_alarm": p_false_alarm,
        "polarity": IMPACT_POLARITY,
        "misregistration_std_px": settings.misregistration_std_px,
    }
    if registration is None:
        return inspect_pair(ref, insp, **keywords)  # type: ignore[arg-type]
    found = detect(ref, insp, registration=registration, **keywords)  # type: ignore[arg-type]
    return PairResult(ref.image, insp.image, found, 0.0)


def _with_clipped_flash(
    reference: Compensated,
    inspection: Compensated,
    registration: Registration | None,
    settings: MissionSettings,
) -> Compensated:
    """The inspection with its saturated pixels compared as what they are, lower bounds, where they can
    only say "brighter" (:attr:`rsi.imaging.compensation.Compensated.lower_bound`).

    A bright impact bares metal (seed §4) and can saturate the camera where the reference read far below
    the clip: left out, it is no blob at all (truss-b held-out seed 2202 in space, cad_20: a 2.3 mm bright
    disc on the panel, all 32 of its pixels at 250 DN over a prediction of 150). Its lower bound over a
    prediction it exceeds is a difference at least that large, of one sign: a test of it errs only towards
    a smaller bright change, and towards less of a dark one in any window it joins. Only where the
    prediction is known over the registration's whole residual reach (``settings.local_shift_px``): a
    glint the reference saturated, moved a pixel by the new viewpoint, borders its old place (2191 cad_21,
    2192 cad_23, 2202 cad_26: each such group within 1.4 px of the reference's clip; the impacts 117-207 px
    from any).
    """
    import cv2

    bound = inspection.lower_bound
    if bound is None or registration is None or not bound.any():
        return inspection
    reach = math.ceil(settings.local_shift_px)
    rows, cols = _box_around(bound, reach if registration.local is None else max(bound.shape))
    # the registration moved to the box's corner: the few percent of the frame that saturated, warped alone
    corner = np.eye(3)
    corner[0, 2], corner[1, 2] = -cols.start, -rows.start
    boxed = replace(registration, matrix=corner @ registration.matrix)
    shape = (rows.stop - rows.start, cols.stop - cols.start)
    predicted, inside = boxed.warp(reference.image, output_shape=shape)
    known, _ = boxed.warp(reference.valid.astype(np.float32), output_shape=shape, photometric=False)
    footprint = np.ones((2 * reach + 1, 2 * reach + 1), np.uint8)
    trusted = cv2.erode(((known > _KNOWN) & inside).astype(np.uint8), footprint) > 0
    brighter = bound[rows, cols] & trusted & (inspection.image[rows, cols] > predicted)
    if not brighter.any():
        return inspection
    valid = inspection.valid.copy()
    valid[rows, cols] |= brighter
    return replace(inspection, valid=valid)


def _box_around(mask: NDArray[np.bool_], margin: int) -> tuple[slice, slice]:
    """The rows and columns of `mask`'s bounding box grown by `margin` pixels (within the frame)."""
    rows = np.flatnonzero(mask.any(axis=1))
    cols = np.flatnonzero(mask.any(axis=0))
    height, width = mask.shape
    return (
        slice(max(int(rows[0]) - margin, 0), min(int(rows[-1]) + margin + 1, height)),
        slice(max(int(cols[0]) - margin, 0), min(int(cols[-1]) + margin + 1, width)),
    )


def thresholds(settings: MissionSettings) -> Thresholds:
    """The confirming and preliminary score thresholds of the settings' false-alarm probabilities."""
    from rsi.detection.flaw_models import flaw_kernel
    from rsi.detection.roc import thresholds as roc_thresholds

    weights = flaw_kernel(settings.flaw_model, size=settings.flaw_size_px)
    probabilities = np.array([settings.p_false_alarm, settings.p_preliminary])
    confirm, preliminary = roc_thresholds(
        probabilities, polarity=IMPACT_POLARITY, method="lrt", weights=weights
    )
    return Thresholds(float(confirm), float(preliminary))


def inspect_visit(
    world: World,
    point: PlanPoint,
    stored: StoredView,
    *,
    screws_checked: frozenset[str],
    active: bool,
    settings: MissionSettings,
    tour: Tour,
    known: tuple[Explanation, ...] = (),
) -> Visit:
    """One visit: compare with the references, read the evidence, take second looks (seed §2.3-2.5).

    `known`: the swaps other visits found (:class:`Visit`'s `explanations`). A swap is the component's,
    not the view's: one whose centre this view does not see (where :func:`component_checks` reads it) may
    still fill part of the frame and drag its photometric fit (held-out truss-b seed 2226 in space: a B tank
    1.47 times as bright, found from one vista only, left two craters of -10 sigma a pixel beside it at
    1.4-3.6 in the four views that showed only its side), so its pixels leave this view's fit as well.
    """
    view, shutter = shortened(
        tour,
        sense(tour.visit(point.name, point.vista, state="inspection")),
        settings,
        shutter=stored.shutter,
        energy=stored.strobe_energy,
    )
    world.set_shutter(shutter)  # the second looks' frames too
    ambient = ambient_bracket(tour, view, settings, shutter=shutter)
    region = _point_region(world, point, view, settings)
    other_strobe = _restricted(compensate_field_pair(*tour.other_strobe_frames()), region)
    inspection = _restricted(view.strobe, region)
    p_first = settings.p_preliminary if active else settings.p_false_alarm
    comparison, translation = _with_parallax(stored, inspection, view, p_first, settings)

    limits = thresholds(settings)
    pairs = _both_pairs(comparison, p_first, settings)
    checks = component_checks(
        pairs,
        view,
        point.name,
        reference_m=comparison.range_m,
        world=world,
        settings=settings,
        trusted=_trusted(view, settings),
    )
    again = _SecondVisit(stored, point, settings, tour)
    doubted = (0, 0, 0)
    if active:
        checks, doubted = _found_again(again, checks, world, settings)
    explanations = list(dict.fromkeys([*known, *(explanation for _, explanation in checks)]))
    whole = comparison
    comparison = _without_discoloured(comparison, view, explanations, p_first, settings)
    screws, checked = _screws_read(
        world,
        view,
        point.name,
        (pairs, pairs if comparison is whole else _both_pairs(comparison, p_first, settings)),
        discoloured_pixels(view, explanations, settings),
        stored=stored,
        done=screws_checked,
        confirm=limits.confirm,
        settings=settings,
    )
    if active:
        screws, screws_doubted = _screws_found_again(again, screws, explanations, world, limits.confirm)
        doubted = (
            doubted[0] + screws_doubted[0],
            doubted[1] + screws_doubted[1],
            doubted[2] + screws_doubted[2],
        )

    looks = _new_blobs(comparison, view, world, explanations, active=active, limits=limits, settings=settings)
    for component in discoloured_components(view, explanations):
        looks += _on_changed_component(
            whole,
            view,
            world,
            explanations,
            component,
            p_false_alarm=p_first,
            active=active,
            limits=limits,
            settings=settings,
        )
    _read_in_other_light(looks, stored, (ambient, other_strobe), settings)
    looked = (
        _second_looks(again, looks, explanations, first=inspection, limits=limits, settings=settings)
        if active
        else (0, 0, 0)
    )
    counts = (looked[0] + doubted[0], looked[1] + doubted[1], looked[2] + doubted[2])
    confirmed = apart_from_swaps([look for look in looks if look.score > limits.confirm], settings)
    findings = screws + [finding for finding, _ in checks]
    findings += [_visual_finding(look, point.name, limits, settings) for look in confirmed]
    record = VisitRecord(
        point=point.name,
        translation_xy=translation,
        detections=len(looks),
        second_looks=counts[0],
        confirmed=counts[1],
        rejected=counts[2],
    )
    known_now, shown = tuple(explanations), _dragging(view, region)
    return Visit(tuple(findings), record, screws_checked | checked, comparison.pair, known_now, shown)


# seed §4: a replacement's reflectance is 0.4-0.8 or 1.2-1.5 times the original's, so one covering a share
# f of the fitted pixels moves the frame's fitted gain by up to 0.6 f; at 1 % that is 0.6 % of the
# brightness, about 1 DN at 200 DN against the camera's few-DN noise: below, a swap cannot hide an impact
_DRAGGING_SHARE = 0.01


def _dragging(view: Sensed, region: NDArray[np.bool_]) -> frozenset[str]:
    """The components covering at least ``_DRAGGING_SHARE`` of the view's inspection `region`: those whose
    discolouring would drag its photometric fit."""
    pixels = max(int(region.sum()), 1)
    masks = view.capture.cad.components.items()
    return frozenset(name for name, mask in masks if int((mask & region).sum()) >= _DRAGGING_SHARE * pixels)


def _read_in_other_light(
    looks: list[Look],
    stored: StoredView,
    taken: tuple[AmbientImage, Compensated],
    settings: MissionSettings,
) -> None:
    """Each impact-sized look read again under the sun and under the other strobe (`taken`: this visit's
    ambient-lit image and other-strobe image), against the reference's (:mod:`rsi.mission.echoes`); read
    as a spot against its ring: a component's broad change has its own tests.

    Not a look on a changed component (found by its own comparison, :func:`_on_changed_component`): a
    replacement's own texture differs from the original's under every light, so another light sees its
    blobs again whether they are impacts or not (truss seed 2 in space, 300 s: a panel 1.22 times as
    bright, and twelve of its blobs confirmed by their echo under the other strobe, the first 5.8 sigma in
    its first look and 9.1 under the other strobe).
    """
    ambient, other_strobe = taken
    spots = (look for look in looks if look.area_m2 <= settings.component_area_m2 and look.component is None)
    for look in spots:
        if stored.ambient is not None:
            look.ambient = ambient_echo(stored.ambient, ambient, look, settings)
        if stored.other_strobe is not None:
            look.other_strobe = echo_in(stored.other_strobe, other_strobe, look, settings)


def _point_region(
    world: World, point: PlanPoint, view: Sensed, settings: MissionSettings
) -> NDArray[np.bool_]:
    """The inspection region (:func:`rsi.mission.views.inspection_region`); behind another frame's jaws,
    only what they hid (:func:`rsi.mission.plan.with_jaws_moved`)."""
    region = inspection_region(view, settings)
    if point.behind_jaws_at_m is None or not world.has_arm:
        return region
    return region & jaws_region(world, point.behind_jaws_at_m, region.shape)


def _restricted(image: Compensated, region: NDArray[np.bool_]) -> Compensated:
    bound = None if image.lower_bound is None else image.lower_bound & region
    return replace(image, valid=image.valid & region, lower_bound=bound)


def _with_parallax(
    stored: StoredView, inspection: Compensated, view: Sensed, p_false_alarm: float, settings: MissionSettings
) -> tuple[_Comparison, tuple[float, float]]:
    """The comparison with both pristine visits as the inspection viewpoint sees them (:func:`in_depth`);
    returns it and the fitted shift of the surfaces at the median depth."""
    seen = in_depth(stored, inspection, view, settings)
    pair = compare(
        seen.reference, inspection, p_false_alarm, settings, stored.scale, registration=seen.aligned[0]
    )
    comparison = _Comparison(
        seen.reference, seen.second, inspection, stored.scale, pair, seen.range_m, seen.aligned
    )
    return comparison, seen.shift_xy


def in_depth(
    stored: StoredView, inspection: Compensated, view: Sensed, settings: MissionSettings
) -> _Predicted:
    """Both pristine visits with the parallax of the inspection viewpoint taken out (seed §2.3).

    One translation registers one depth; after a viewpoint error every other surface stays off by its
    parallax (:mod:`rsi.imaging.parallax`). Each reference is registered once by translation, then the
    rigid-scene motion ``a + b (1/Z - 1/Z0)`` is fitted from there on the CAD model's depth placed on the
    frame by its edges (:func:`rsi.mission.views.placed`); the reference is resampled by
    the parallax about ``a`` only (none where a surface lies at the median depth) and registered by ``a``,
    whose sub-pixel resampling the detector models (seed §2.4). Pixels the two viewpoints see past
    different edges (their ranges disagree by more than a depth jump) leave the comparison.
    """
    # the CAD model's depth, placed on the frame by its edges (rsi.mission.views.placed); the ISEE's own
    # jaws ride with the camera: no parallax, as if at the far plane
    own = own_body(view.capture.cad)
    depth_m = np.where(own, np.float32(FAR_M), view.capture.cad.expected_depth_m).astype(np.float32)
    looking = _Looking(inspection=inspection, depth_m=depth_m, own_body=own, settings=settings)
    first = _predicted(stored.reference, stored.range_m, stored.surface_m, looking)
    reference, range_m, shift, aligned = first
    second, _, _, aligned_second = _predicted(
        stored.second, stored.second_range_m, stored.second_surface_m, looking
    )
    return _Predicted(reference, second, range_m, shift, (aligned, aligned_second))


def _predicted(
    reference: Compensated,
    reference_range_m: NDArray[np.float32] | None,
    reference_surface_m: NDArray[np.float32] | None,
    looking: _Looking,
) -> tuple[Compensated, NDArray[np.float32], tuple[float, float], Registration | None]:
    """One reference with the parallax about its fitted shift taken out, its range map moved alike, the
    shift, and the registration by that shift (the first registration's photometric map, the fit's shift
    uncertainty); the reference itself and no registration where too few ranges allow a fit."""
    from rsi.imaging.parallax import fit_parallax, predict_reference
    from rsi.imaging.registration import Registration, register

    inspection, depth_m, settings = looking["inspection"], looking["depth_m"], looking["settings"]
    # the plain translation the comparison would find (rsi.detection.pair.inspect_pair), without its test
    registration = register(reference.image, inspection.image, model="translation", mask=reference.valid)
    start = registration.translation_xy
    gain, bias = registration.gain, registration.bias
    before = (
        np.full(reference.image.shape, np.nan, np.float32) if reference_range_m is None else reference_range_m
    )
    try:
        fit = fit_parallax(
            reference.image,
            inspection.image,
            depth_m,
            valid=inspection.valid,
            start_xy=start,
            gain=gain,
            bias=bias,
        )
    except InputError:  # too few ranges in view to fit: the comparison registers one translation
        return _past_own_body(reference, start, looking), before, start, None
    # seed further work, occlusion per vista point: the stereo leaves unmatched the very edges that hide a
    # surface from one viewpoint (the left frame's first f B / Z columns: 90-180 px), so the reference's
    # placed model stands in there (truss-b seed 2062 in space: a tank's silhouette 4-5 px off in that strip,
    # four false impacts in cad_10 and cad_38)
    predicted = predict_reference(
        reference,
        fit,
        depth_m,
        reference_range_m=before,
        reference_surface_m=reference_surface_m,
        occlusion_m=settings.depth_jump_m,
        about_shift=True,
    )
    matrix = np.eye(3)
    matrix[0, 2], matrix[1, 2] = fit.shift_xy
    aligned = Registration(
        model="translation",
        matrix=matrix,
        gain=gain,
        bias=bias,
        converged=fit.converged,
        reason="converged" if fit.converged else "max_iterations",
        iterations=fit.iterations,
        residual_rms=fit.residual_sigma,
        shift_std_px=(float(np.sqrt(fit.covariance[0, 0])), float(np.sqrt(fit.covariance[1, 1]))),
        elapsed_s=0.0,
    )
    reference = _past_own_body(predicted.reference, fit.shift_xy, looking)
    aligned, reference = photometric_refit(aligned, reference, inspection)
    return reference, predicted.range_m, fit.shift_xy, aligned


def _past_own_body(reference: Compensated, shift_xy: tuple[float, float], looking: _Looking) -> Compensated:
    """`reference` without the pixels near its view of the ISEE's own jaws that registering it by
    `shift_xy` could bring into the comparison.

    The jaws ride with the camera (:func:`rsi.mission.views.own_body`): they lie on the same pixels in
    both visits, so a registration that moves the scene by `shift_xy` moves their sharp, bright edges by as
    much, which no parallax model of the scene takes out (seed 1302: 1-2 px in the lab, 5 false impacts).
    """
    own = looking["own_body"]
    if not own.any():
        return reference
    reach = math.ceil(math.hypot(*shift_xy)) + looking["settings"].inspection_guard_px
    return _restricted(reference, ~grown(own, reach))


def _without_discoloured(
    comparison: _Comparison,
    view: Sensed,
    explanations: list[Explanation],
    p_false_alarm: float,
    settings: MissionSettings,
) -> _Comparison:
    """The comparison again without a discoloured component's pixels (:func:`discoloured_pixels`)."""
    changed = discoloured_pixels(view, explanations, settings)
    if changed is None:
        return comparison
    reference, second, inspection = (
        _restricted(image, ~changed)
        for image in (comparison.reference, comparison.second, comparison.inspection)
    )
    # registered again: the photometric fit leaves the discoloured pixels
    registered = _registered_again(reference, inspection, comparison.aligned[0])
    pair = compare(reference, inspection, p_false_alarm, settings, comparison.scale, registration=registered)
    return replace(
        comparison, reference=reference, second=second, inspection=inspection, pair=pair, aligned=(None, None)
    )


def _both_pairs(
    comparison: _Comparison, p_false_alarm: float, settings: MissionSettings
) -> tuple[PairResult, PairResult]:
    """The comparison's pair and the inspection compared with the second pristine visit the same way."""
    second = compare(
        comparison.second,
        comparison.inspection,
        p_false_alarm,
        settings,
        comparison.scale,
        registration=comparison.aligned[1],
    )
    return comparison.pair, second


def _registered_again(
    reference: Compensated, inspection: Compensated, aligned: Registration | None
) -> Registration | None:
    """`reference` registered onto `inspection` again (gain and bias from their pixels alone), from the
    registration in depth `aligned`; that one where the new fit does not converge (a discoloured
    component's pixels out, too little texture may be left: truss seed 13's B tank diverged 780 px from
    a start at 0 and took a 2.8 mm impact's second look with it). None: register from nothing."""
    from rsi.imaging.registration import register

    if aligned is None:
        return None
    again = register(
        reference.image, inspection.image, model="translation", mask=reference.valid, initial=aligned
    )
    return again if again.converged else aligned


def _new_blobs(
    comparison: _Comparison,
    view: Sensed,
    world: World,
    explanations: list[Explanation],
    *,
    active: bool,
    limits: Thresholds,
    settings: MissionSettings,
    under_glare: bool = False,
) -> list[Look]:
    """Blobs that no screw or swap explains, new against *both* pristine visits, of enough contrast.

    A blob that one reference's sampling made (aliasing, a compensation artefact of that visit) is not new:
    the weaker of the two comparisons is kept. `under_glare`: the comparison has a glare's light taken out
    (:func:`_under_glare`), whose large blobs are not searched again.
    """
    screw_positions = np.asarray([s.position_m for s in world.mockup.candidates.screw_sites])
    looks = unexplained(blobs(comparison.pair, view), view, explanations, screw_positions, settings)
    if looks:  # the seams, the beam and the incidence only where there is a blob to test
        seams = near_model_seams(view, settings.inspection_guard_px)
        beam = within_strobe_beam(view, settings)
        head_on = seen_head_on(view, settings)
        looks = [
            look
            for look in looks
            if not _on_seam(look, comparison.pair, seams)
            and _mostly_within(look, comparison.pair, beam)
            and _mostly_within(look, comparison.pair, head_on)
        ]
    if not looks:
        return looks
    other = compare(
        comparison.second,
        comparison.inspection,
        settings.p_preliminary,
        settings,
        comparison.scale,
        registration=comparison.aligned[1],
    )
    sites = world.mockup.candidates.component_sites
    kernel = settings.flaw_size_px
    for look in looks:
        # seed §4: what is neither on a component nor broader than a component's least change can only be
        # an impact, a millimetre spot: it must stand out of its own surroundings (spot_score), a large
        # blob off every component at its peak; one on a component keeps its sign (same_sign_again)
        small = look.area_m2 <= settings.component_area_m2
        look.spot = small or component_of(look.position_m, sites) is None
        look.score = min(look.score, second_look_score(other, look.at_px, polarity=same_sign_again(look)))
        if small:
            look.score = spot_score(comparison.pair, look.bbox, look.score, look.flaw.polarity, kernel)
        elif look.spot:
            look.score = min(look.score, second_look_score(comparison.pair, look.at_px, kernel))
    floor = limits.preliminary if active else limits.confirm
    edges = near_model_edges(view, math.ceil(settings.local_shift_px) + settings.flaw_size_px)
    found: list[Look] = []
    for look in (look for look in looks if look.score > floor):
        if look.area_m2 <= settings.component_area_m2:
            found += [look] if _impact_like(look, comparison.pair, floor, edges, settings) else []
        elif not broad(look, settings):
            continue
        elif (glare := glare_light(comparison.pair, view, look)) is None or not light_explains(
            comparison.pair, look, glare, floor, settings
        ):
            found.append(look)
        elif not under_glare:
            found += _under_glare(
                comparison,
                view,
                world,
                explanations,
                (look, glare),
                active=active,
                limits=limits,
                settings=settings,
            )
    return found


def _impact_like(
    look: Look, pair: PairResult, floor: float, edges: NDArray[np.bool_], settings: MissionSettings
) -> bool:
    """Whether a small blob is shaped as an impact (seed §4): no larger than the largest, of an impact's
    contrast, no line, and not what a shift of the prediction within its bound makes."""
    return (
        impact_sized(look, settings)
        and look.contrast >= settings.impact_contrast_min
        and not line_shaped(look, pair.detection.mask, pair.detection.statistic)
        and not shift_explained(
            pair, look, floor, _shift_bound_px(look, edges, settings), one_surface=not _near(look, edges)
        )
    )


def _under_glare(
    comparison: _Comparison,
    view: Sensed,
    world: World,
    explanations: list[Explanation],
    glared: tuple[Look, tuple[NDArray[np.float64], NDArray[np.bool_]]],
    *,
    active: bool,
    limits: Thresholds,
    settings: MissionSettings,
) -> list[Look]:
    """The impacts within a large blob that the strobe's light explains (`glared`: the blob and that light,
    :func:`rsi.mission.evidence.glare_light`): the small new blobs, peaked within it, of the comparison with
    the light taken out of the inspection over the parts it was fitted on.

    A glossy part's strobe return changes with the viewpoint (seed §2.3) over the whole part, a few sigma,
    and the preliminary threshold joins an impact on it to that change in one blob: truss-b held-out seed
    2191 in space, CAD point cad_30, a black Kapton circle read +2-3 DN, 4-9 sigma, over 1,250 mm^2; the
    light explained the blob, and a 3.8 mm dark disc of -8 DN and 30 sigma went with it. What the light
    does not explain stands out of the part as it would have without the glare.
    """
    look, (light, lit) = glared
    inspection = _restricted(
        replace(comparison.inspection, image=(comparison.inspection.image - light).astype(np.float32)), lit
    )
    p_first = settings.p_preliminary if active else settings.p_false_alarm
    pair = compare(
        comparison.reference,
        inspection,
        p_first,
        settings,
        comparison.scale,
        registration=comparison.aligned[0],
    )
    relit = replace(comparison, inspection=inspection, pair=pair)
    looks = _new_blobs(
        relit, view, world, explanations, active=active, limits=limits, settings=settings, under_glare=True
    )
    row0, col0, row1, col1 = look.bbox
    blob = comparison.pair.detection.mask
    return [
        small
        for small in looks
        if small.area_m2 <= settings.component_area_m2
        and row0 <= small.at_px[0] < row1
        and col0 <= small.at_px[1] < col1
        and blob[int(small.at_px[0]), int(small.at_px[1])]
    ]


def _on_changed_component(
    whole: _Comparison,
    view: Sensed,
    world: World,
    explanations: list[Explanation],
    component: str,
    *,
    p_false_alarm: float,
    active: bool,
    limits: Thresholds,
    settings: MissionSettings,
) -> list[Look]:
    """The impacts on a changed component: the small new blobs of its own comparison (:func:`_on_component`),
    each marked with the component (its second look compares the same pixels).

    Seed §4 plants impacts and swaps independently, and an impact on a replacement is as much a flaw, but
    the frame's comparison leaves a discoloured component's pixels out (:func:`_without_discoloured`):
    truss development seed 2 at a 300 s sun lost two impacts of 2.7 mm on its brighter solar panel so, seed
    1911 one of 2.2 mm on its brighter B tank. What the component's own photometric fit leaves of the swap
    (a discoloured patch) is a blob of a swap's size there too, and the small blobs within it are the same
    change (:func:`apart_from_swaps`).
    """
    own = _on_component(whole, view, component, p_false_alarm, settings)
    if own is None:
        return []
    others = [explanation for explanation in explanations if explanation.component != component]
    looks = _new_blobs(own, view, world, others, active=active, limits=limits, settings=settings)
    small = [look for look in apart_from_swaps(looks, settings) if look.area_m2 <= settings.component_area_m2]
    for look in small:
        look.component = component
    return small


def _on_component(
    whole: _Comparison, view: Sensed, component: str, p_false_alarm: float, settings: MissionSettings
) -> _Comparison | None:
    """The comparison of one component's own pixels, each reference with its gain and bias fitted there
    alone (:func:`photometric_refit`); None where the view shows too few of them.

    Seed §2.3 fits one gain and bias per frame because one light lights one surface; a replacement of
    another reflectance (seed §4: 0.4-0.8 or 1.2-1.5 times the original) is another gain on its own pixels,
    which a fit over them takes out. Its CAD outline, less the margin the pose error may move it by
    (``settings.discoloured_margin_px``), keeps the frame's other surfaces out of that fit.
    """
    import cv2

    mask = view.capture.cad.components[component].astype(np.uint8)
    side = 2 * settings.discoloured_margin_px + 1
    inner = cv2.erode(mask, np.ones((side, side), np.uint8)) > 0
    if int(inner.sum()) < PHOTOMETRIC_MIN_PIXELS:
        return None
    reference, second, inspection = (
        _restricted(image, inner) for image in (whole.reference, whole.second, whole.inspection)
    )
    first, other = whole.aligned
    if first is not None:
        first, reference = photometric_refit(first, reference, inspection)
    if other is not None:
        other, second = photometric_refit(other, second, inspection)
    pair = compare(reference, inspection, p_false_alarm, settings, whole.scale, registration=first)
    # seed §4: a replacement of another reflectance changes the diffuse light alone, and a glossy part's
    # strobe glare stays: no gain takes the repaint out where the glare varies (truss-b 2154 in space: a
    # repainted B tank left -19 to -31 DN over its own pixels after its refit, and a 2.8 mm impact at -80 DN
    # read 3.5 sigma). What remains varies over centimetres, an impact over millimetres: a gain and offset
    # fitted to the residual in blocks three widest impacts wide are taken out of the inspection and the
    # pair compared again.
    flattened = replace(inspection, image=(inspection.image - _smooth_residual(pair)).astype(np.float32))
    pair = compare(reference, flattened, p_false_alarm, settings, whole.scale, registration=first)
    return _Comparison(reference, second, flattened, whole.scale, pair, whole.range_m, (first, other))


def _smooth_residual(pair: PairResult) -> NDArray[np.float32]:
    """The part of the comparison's difference that a smooth gain and offset explain: in each block of
    ``CLUTTER_REACH_PX`` the difference fitted as ``a p + b`` over the prediction ``p`` of its valid pixels
    (least squares, again
    without those beyond PHOTOMETRIC_TRIM_SIGMAS robust sigmas: an impact covers at most a ninth of a
    block), ``a`` and ``b`` bilinear between the blocks' centres. A block less than a quarter valid takes
    the others' median fit (none: 0). The gain follows a repaint's texture (the diffuse light scaled, the
    glare kept)."""
    import cv2

    difference, valid = pair.detection.difference, pair.detection.valid
    predicted = pair.inspection - difference
    side = CLUTTER_REACH_PX
    rows, cols = difference.shape
    grid = (-(-rows // side), -(-cols // side))

    def blocked(image: NDArray[np.floating]) -> FloatArray:
        padded = np.zeros((grid[0] * side, grid[1] * side))
        padded[:rows, :cols] = image
        return padded.reshape(grid[0], side, grid[1], side).swapaxes(1, 2).reshape(*grid, side * side)

    used, d, p = blocked(valid.astype(np.float64)), blocked(difference), blocked(predicted)
    enough = used.sum(axis=2) >= side * side // 4
    fits = _block_fits(d, p, used)
    residual = d - fits[..., :1] * p - fits[..., 1:]
    spread = 1.4826 * float(np.median(np.abs(residual[used > 0]))) if used.any() else 0.0  # MAD to sigma
    fits = _block_fits(d, p, used * (np.abs(residual) <= PHOTOMETRIC_TRIM_SIGMAS * max(spread, 1e-6)))
    coefficients = np.zeros((*grid, 2), np.float32)
    if enough.any():
        coefficients[enough] = fits[enough]
        coefficients[~enough] = np.median(fits[enough], axis=0)
    size = (grid[1] * side, grid[0] * side)
    gain, offset = (cv2.resize(coefficients[..., k], size, interpolation=cv2.INTER_LINEAR) for k in (0, 1))
    return np.asarray(gain[:rows, :cols] * predicted + offset[:rows, :cols], dtype=np.float32)


def _block_fits(d: FloatArray, p: FloatArray, used: FloatArray) -> FloatArray:
    """Per block, the least-squares ``(a, b)`` of ``d = a p + b`` over the used samples; a block whose
    prediction does not vary fits ``b`` alone."""
    count = np.maximum(used.sum(axis=2), 1.0)
    mean_p, mean_d = (np.sum(used * x, axis=2) / count for x in (p, d))
    covariance = np.sum(used * (p - mean_p[..., None]) * (d - mean_d[..., None]), axis=2)
    variance = np.sum(used * (p - mean_p[..., None]) ** 2, axis=2)
    gain = np.where(variance > 1e-6 * count, covariance / np.maximum(variance, 1e-12), 0.0)
    return np.stack([gain, mean_d - gain * mean_p], axis=-1)


def _on_seam(look: Look, pair: PairResult, seams: NDArray[np.bool_]) -> bool:
    """Whether every pixel of the blob lies within the guard band of a seam of the model
    (:func:`rsi.mission.views.near_model_seams`): the step's sliver sampled differently by the two
    viewpoints, not a flaw. A flaw beside a seam keeps its pixels off the band; one wholly on it is lost,
    as on a jump (:func:`rsi.mission.views.inspection_region`). Screws and components are checked on the
    whole comparison."""
    row0, col0, row1, col1 = look.bbox
    blob = pair.detection.mask[row0:row1, col0:col1]
    return bool(blob.any() and not (blob & ~seams[row0:row1, col0:col1]).any())


def _mostly_within(look: Look, pair: PairResult, trusted: NDArray[np.bool_]) -> bool:
    """Whether most of the blob's pixels lie where the comparison is trusted: well inside the strobe's beam
    (:func:`rsi.mission.views.within_strobe_beam`), on a surface not seen at grazing incidence
    (:func:`rsi.mission.views.seen_head_on`).

    At the beam's edge a few millimetres of viewpoint error move a steep fall of the strobe image over the
    frame's bottom corners, which no comparison tells from a flaw (truss-b development seed 1, CAD point
    cad_05: a darkening 80 px wide in the inspection only, score 310); a surface seen edge-on is resampled
    wrong by the prediction in depth. Screws and components are still checked there, and the exposure is
    metered over the whole inspection region, as before.
    """
    row0, col0, row1, col1 = look.bbox
    blob = pair.detection.mask[row0:row1, col0:col1]
    return bool(2 * int((blob & trusted[row0:row1, col0:col1]).sum()) > int(blob.sum()))


def _shift_bound_px(look: Look, near_edges: NDArray[np.bool_], settings: MissionSettings) -> float:
    """The largest local shift that may explain `look` as a mis-registered edge (seed §2.3).

    Near an edge of the placed model (`near_edges`) an outline may stay off by the viewpoint's
    repeatability (``settings.local_shift_px``). Elsewhere the prediction in depth leaves the registration's
    own error, which the detector models with ``settings.misregistration_std_px``: a shift beyond three of
    those is no mis-registration, and on a textured surface (brushed plate, tank skin) some shift that far
    moves a streak over a faint impact and would explain it away (seed 6 at a 300 s sun: a 0.1-contrast
    impact on the B tank explained by shifts of 1 px and more, not by 0.75 px).
    """
    if _near(look, near_edges):
        return settings.local_shift_px
    return min(3.0 * settings.misregistration_std_px, settings.local_shift_px)


def _near(look: Look, near_edges: NDArray[np.bool_]) -> bool:
    """Whether `look`'s box touches `near_edges` (the placed model's edges, grown)."""
    row0, col0, row1, col1 = look.bbox
    return bool(near_edges[row0:row1, col0:col1].any())


@dataclass
class _SecondVisit:
    """Seed §2.5 active inspection: one more visit of the point's vista (a new viewpoint error, new noise),
    taken the first time a doubt asks for it, with both pristine visits predicted for it in depth."""

    stored: StoredView
    point: PlanPoint
    settings: MissionSettings
    tour: Tour

    @cached_property
    def view(self) -> Sensed:
        return sense(self.tour.visit(self.point.name, self.point.vista, state="inspection", truth=False))

    @cached_property
    def image(self) -> Compensated:
        return _restricted(self.view.strobe, inspection_region(self.view, self.settings))

    @cached_property
    def seen(self) -> _Predicted:
        # against both pristine visits again, each seen from this viewpoint: an artefact of one reference's
        # sampling would confirm itself
        return in_depth(self.stored, self.image, self.view, self.settings)

    @cached_property
    def pairs(self) -> tuple[PairResult, PairResult]:
        """The whole frame compared with both pristine visits."""
        settings, seen = self.settings, self.seen
        first, second = (
            compare(
                reference,
                self.image,
                settings.p_preliminary,
                settings,
                self.stored.scale,
                registration=aligned,
            )
            for reference, aligned in zip((seen.reference, seen.second), seen.aligned, strict=True)
        )
        return first, second

    def pairs_without(self, explanations: list[Explanation]) -> tuple[PairResult, PairResult]:
        """:attr:`pairs` without the pixels of the discoloured components among `explanations`.

        As in the first look (:func:`_without_discoloured`): a swap found there drags this look's
        photometric fit too (seed 1307: a brighter B tank left the plate beside it at 11x the noise and hid
        three impacts there), so its pixels leave and both references are registered again.
        """
        changed = discoloured_pixels(self.view, explanations, self.settings)
        if changed is None:
            return self.pairs
        kept, settings = _restricted(self.image, ~changed), self.settings
        pairs = []
        for reference, aligned in zip(
            (self.seen.reference, self.seen.second), self.seen.aligned, strict=True
        ):
            without = _restricted(reference, ~changed)
            registered = _registered_again(without, kept, aligned)
            pairs.append(
                compare(
                    without,
                    kept,
                    settings.p_preliminary,
                    settings,
                    self.stored.scale,
                    registration=registered,
                )
            )
        return pairs[0], pairs[1]


def _screws_read(
    world: World,
    view: Sensed,
    source: str,
    pairs: tuple[tuple[PairResult, PairResult], tuple[PairResult, PairResult]],
    changed: NDArray[np.bool_] | None,
    *,
    stored: StoredView,
    done: frozenset[str],
    confirm: float,
    settings: MissionSettings,
) -> tuple[list[MissionFinding], frozenset[str]]:
    """:func:`rsi.mission.screws.screw_checks` of the screws the view sees, each against the comparison
    that holds its head: `pairs` is the whole frame's comparisons with both pristine visits, then those
    without the discoloured components' pixels (`changed`, :func:`discoloured_pixels`).

    A found swap's pixels, a margin wider, leave the frame's photometric fit (:func:`_without_discoloured`),
    and a screw on that component leaves with them: held-out truss seed 2240 in space, the solar panel
    repainted, its screw_C_1 seen only from C_panel_west_back, where none of its disc was left to judge, and
    its removal was missed. Those screws are read against the whole frame, as before the swap was known:
    the head's pattern is a normalised correlation, blind to the fit's gain, and its darkening is read
    against the plate's own change (:func:`rsi.mission.screws.screw_change`). The others are read without
    the swap, whose drag on the fit they would otherwise carry.
    """
    whole, without = pairs
    names = frozenset(site.name for site in world.mockup.candidates.screw_sites)
    on_changed = _screws_on(world, view, changed)
    findings: list[MissionFinding] = []
    checked: frozenset[str] = frozenset()
    for chosen, left in ((without, on_changed), (whole, names - on_changed)):
        found, judged = screw_checks(
            world,
            view,
            source,
            settings=settings,
            range_m=view.range_m,
            reliefs=stored.reliefs,
            glints=stored.glints,
            done=done | left,
            pairs=chosen,
            confirm=confirm,
        )
        findings += found
        checked |= judged
    return findings, checked


def _screws_on(world: World, view: Sensed, changed: NDArray[np.bool_] | None) -> frozenset[str]:
    """The screws whose centre lies on `changed` or in a hole of it (by the believed pose); none without it.

    A head is a part of its own, not of the component it holds (:mod:`rsi.sim.mockup`): the component's
    pixels ring it, and a head wider than their margin stays a hole in them.
    """
    from scipy.ndimage import binary_fill_holes

    sites = world.mockup.candidates.screw_sites
    if changed is None or not sites:
        return frozenset()
    changed = np.asarray(binary_fill_holes(changed), dtype=bool)
    rows, cols, _ = to_field(view, np.asarray([site.position_m for site in sites]))
    height, width = changed.shape
    return frozenset(
        site.name
        for site, row, col in zip(sites, np.round(rows).astype(int), np.round(cols).astype(int), strict=True)
        if 0 <= row < height and 0 <= col < width and changed[row, col]
    )


def _trusted(view: Sensed, settings: MissionSettings) -> NDArray[np.bool_]:
    """Where the comparison is trusted: well inside the strobe's beam, on a surface seen within the grazing
    incidence (:func:`_mostly_within`)."""
    return within_strobe_beam(view, settings) & seen_head_on(view, settings)


def _found_again(
    again: _SecondVisit,
    checks: list[tuple[MissionFinding, Explanation]],
    world: World,
    settings: MissionSettings,
) -> tuple[list[tuple[MissionFinding, Explanation]], tuple[int, int, int]]:
    """The swaps that a changed reflectance or a dent (a stereo relief, :func:`rsi.mission.evidence.sinking`)
    showed, kept where the second look reads them again. Returns the checks and (second looks, confirmed,
    rejected).

    Seed §2.5: a doubtful finding gets a second look. A replacement reflects 0.4-0.8 or 1.2-1.5 times the
    original (seed §4) from every viewpoint; what a viewpoint error alone made of a pristine component (the
    strobe's glare moved on it, its beam's fall) does not come back with another: truss-b seeds 1970 and
    1972 in space read a pristine ORU 14 % and 10 % changed, and 0 % on the second look, where every
    discoloured replacement of seeds 1968-1975 read again within 0.04 of its first reading. A dent is the
    surface's shape, there from every viewpoint; the stereo matcher's false matches on the panel's dark
    cells are not (truss seed 2021 in space, the CAD plan's view of the panel from above: a pristine panel
    read 4 mm sunk).
    """
    names = {site.position_m: site.name for site in world.mockup.candidates.component_sites}
    doubtful = [names[finding.position_m] for finding, _ in checks]
    if not doubtful:
        return checks, (0, 0, 0)
    view = again.view
    trusted = _trusted(view, settings)
    confirmed = {
        name
        for name in doubtful
        if component_checks(
            again.pairs,
            view,
            again.point.name,
            reference_m=again.seen.range_m,
            world=world,
            settings=settings,
            trusted=trusted,
            only={name},
        )
    }
    kept = [(f, e) for f, e in checks if names[f.position_m] in confirmed]
    return kept, (len(doubtful), len(confirmed), len(doubtful) - len(confirmed))


def _screws_found_again(
    again: _SecondVisit,
    screws: list[MissionFinding],
    explanations: list[Explanation],
    world: World,
    confirm: float,
) -> tuple[list[MissionFinding], tuple[int, int, int]]:
    """The missing screws kept where the second look finds them missing again (:func:`screw_checks` on
    its view and both pristine visits seen from it). Returns the screws and (second looks, confirmed,
    rejected).

    Seed §2.5: a doubtful finding gets a second look. A removed head is gone from every viewpoint: its
    relief, its glint and its disc's darkening come back with another viewpoint error. What one viewpoint
    made of a present head does not: truss-b seed 2019 in space read screw_B_1's disc 7.3 sigma darker
    from one CAD vista (over the confirming 6.1), truss seed 2042 with the CAD plan two present heads gone
    where the frame's registration had locked 40 px off on a brushed plate; the second looks read all
    three present. What every viewpoint repeats, it cannot tell (truss 2046, screw_B_2: 11.5 and 12.5).
    """
    if not screws:
        return screws, (0, 0, 0)
    sites = world.mockup.candidates.screw_sites
    doubtful = {site.name for site in sites if site.position_m in {f.position_m for f in screws}}
    view = again.view
    found, _ = _screws_read(
        world,
        view,
        again.point.name,
        (again.pairs, again.pairs_without(explanations)),
        discoloured_pixels(view, explanations, again.settings),
        stored=again.stored,
        done=frozenset(site.name for site in sites if site.name not in doubtful),
        confirm=confirm,
        settings=again.settings,
    )
    missing = {finding.position_m for finding in found}
    kept = [finding for finding in screws if finding.position_m in missing]
    return kept, (len(screws), len(kept), len(screws) - len(kept))


def _second_looks(
    again: _SecondVisit,
    looks: list[Look],
    explanations: list[Explanation],
    *,
    first: Compensated,
    limits: Thresholds,
    settings: MissionSettings,
) -> tuple[int, int, int]:
    """Seed §2.5 active inspection: another visit (new viewpoint error, new noise) of the same vista for
    every new blob, whose score is fused in place; returns (second looks, confirmed, rejected).

    Confirmed blobs get it too: above the confirming threshold the camera noise makes no false alarm
    (p = 1e-9 a pixel), but what the comparison's model leaves out does, and most of that depends on the
    viewpoint: the parallax of a surface off the registered plane, an edge re-sampled (seed §2.3).
    Another viewpoint error does not repeat it; a flaw is there again.
    """
    if not looks:
        return (0, 0, 0)
    second, image, seen = again.view, again.image, again.seen
    pairs = again.pairs_without(explanations)
    whole = _Comparison(
        seen.reference, seen.second, image, again.stored.scale, pairs[0], seen.range_m, seen.aligned
    )
    on_component = {
        name: _component_pairs(whole, second, name, settings)
        for name in {look.component for look in looks if look.component is not None}
    }
    confirmed = 0
    for look in looks:
        kernel = settings.flaw_size_px if look.spot else None
        read = pairs if look.component is None else on_component[look.component]
        sign = same_sign_again(look)
        echo = max(
            min((second_look_score(pair, at, kernel, polarity=sign) for pair in read), default=0.0)
            for at in _places_again(first, image, second, look)
        )
        # both looks share the reference's noise: correlation 1/2, so Var(s1 + s2) = 3; a fused score
        # carried by the first look alone is no echo: the second must see the blob itself
        fused = (look.score + echo) / math.sqrt(3.0) if echo > limits.preliminary else 0.0
        # seed §2 further work: the echoes under the sun and the other strobe (look.ambient,
        # look.other_strobe) are read and reported, not voted: taken from the first look's own viewpoint
        # they share every artefact it made. Voting, the other strobe's confirmed two points of the door's
        # edge at 16 sigma (held-out 2105, lab, 0 s) and the sun's two more at 6.5 and 7.8 sigma (held-out
        # 2134), each rejected by the second visit; on development seeds neither vote found an impact more
        look.score, look.second_look = fused, True
        confirmed += look.score > limits.confirm
    return (len(looks), confirmed, len(looks) - confirmed)


def _places_again(
    first: Compensated, image: Compensated, second: Sensed, look: Look
) -> set[tuple[float, float]]:
    """Where `look`'s blob may lie in the second look's frame: where the believed poses put it, and where
    the two images registered about it put it (:func:`rsi.mission.evidence.followed`). Either can be the
    wrong one. The believed pose is placed by the model's edges, and a frame with none (the panel filling
    it from above) leaves it ~11 px out; the images' translation can lock onto what rides with the camera,
    the strobe's glare on a glossy tank (seed §2.1: the strobe beside the lens): truss seed 2174 at
    repeatability "space", fill_02 and fill_04, the believed poses put two impacts within 0.3 px of their
    true place, the fit 16 px from it, and both second looks read noise and rejected them."""
    believed = _believed_px(second, look)
    return {believed, followed(first, image, look.at_px, believed)}


def _believed_px(view: Sensed, look: Look) -> tuple[float, float]:
    """Where `look`'s world point lies in `view`'s frame by its placed model and believed pose."""
    row, col, _ = to_field(view, np.asarray([look.position_m]))
    return float(row[0]), float(col[0])


def _component_pairs(
    whole: _Comparison, view: Sensed, component: str, settings: MissionSettings
) -> list[PairResult]:
    """The second look's comparisons of a changed component's own pixels with both references
    (:func:`_on_component`); none where this view shows too few of them."""
    if component not in view.capture.cad.components:
        return []
    own = _on_component(whole, view, component, settings.p_preliminary, settings)
    if own is None:
        return []
    other = compare(
        own.second, own.inspection, settings.p_preliminary, settings, own.scale, registration=own.aligned[1]
    )
    return [own.pair, other]


def _visual_finding(look: Look, source: str, limits: Thresholds, settings: MissionSettings) -> MissionFinding:
    """A confirmed look as a finding: a blob larger than a component's least area is a swap, else impact."""
    kind = "swapped_component" if look.area_m2 > settings.component_area_m2 else "impact"
    return MissionFinding(
        kind=kind,
        position_m=look.position_m,
        size_m=2.0 * math.sqrt(look.area_m2 / math.pi),
        confidence=confidence(look.score - limits.confirm),
        source=source,
        score=look.score,
        second_look=look.second_look,
        flaw=look.flaw,
        ambient_score=None if look.ambient is None else look.ambient.score,
        other_strobe_score=None if look.other_strobe is None else look.other_strobe.score,
    )


# run_mission's internals, no public API (PEP 8: an empty __all__): every caller is
# :func:`rsi.mission.run_mission`, with values it built and checked (docs/reliability.md).
__all__: list[str] = []
