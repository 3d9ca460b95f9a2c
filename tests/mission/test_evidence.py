"""What one visit's comparison shows (rsi.mission evidence, exposure, visual), on known answers."""

from __future__ import annotations

import dataclasses
import functools
import math
import os
from types import SimpleNamespace
from typing import Any

import numpy as np
import pytest

os.environ.setdefault("MUJOCO_GL", "egl")

from rsi.detection.detect import Flaw
from rsi.errors import InputError
from rsi.imaging.compensation import Compensated
from rsi.mission import MissionFinding, MissionSettings
from rsi.mission.evidence import Explanation, Look, contrast, discoloured_pixels, explained_by
from rsi.mission.exposure import (
    ambient_dn,
    flash_clipped,
    metered_energy,
    metered_shutter,
    shortened,
    strobe_dn,
)
from rsi.mission.fusion import fuse_findings
from rsi.mission.screws import screw_relief_m
from rsi.mission.visual import compare, thresholds

SETTINGS = MissionSettings()
SHAPE = (40, 60)


def _image(values: np.ndarray, variance: float = 2.0) -> Compensated:
    return Compensated(
        image=values.astype(np.float32),
        valid=np.ones(values.shape, bool),
        variance=np.full(values.shape, variance, np.float32),
        interpolation_variance=np.zeros(values.shape, np.float32),
        row_step=1,
    )


def _look(
    position_m: tuple[float, float, float],
    area_m2: float,
    bbox: tuple[int, int, int, int],
    contrast: float = 0.0,
) -> Look:
    row0, col0, row1, col1 = bbox
    flaw = Flaw((row0 + row1) / 2, (col0 + col1) / 2, bbox, (row1 - row0) * (col1 - col0), 9.0, "dark")
    return Look(flaw, position_m, area_m2, 9.0, contrast=contrast)


def _finding(kind: str, x: float, score: float, source: str = "A_door") -> MissionFinding:
    return MissionFinding(kind, (x, -0.472, 1.2), 0.002, 0.9, source, score)


def test_one_impact_seen_from_two_vistas_is_one_finding() -> None:
    findings = [
        _finding("impact", 0.300, 9.0, "A_door"),
        _finding("impact", 0.300 + SETTINGS.impact_merge_m / 2, 12.0, "A_door_open"),
        _finding("impact", 0.300 + 3 * SETTINGS.impact_merge_m, 7.0, "A_kapton"),
        _finding("missing_screw", 0.300, 0.2, "A_door"),
    ]
    merged = fuse_findings(findings, (), SETTINGS)
    impacts = sorted((f.source, f.score) for f in merged if f.kind == "impact")
    assert impacts == [("A_door_open", 12.0), ("A_kapton", 7.0)]  # the stronger sighting stands
    assert [f.kind for f in merged].count("missing_screw") == 1


def test_two_frames_sightings_of_one_impact_merge_within_both_frames_pose_errors() -> None:
    # seed §2.3: each frame places its sighting from a pose off by its own viewpoint error; two frames'
    # sightings of one impact lie within impact_merge_m plus both bounds, one frame's within the largest
    # impact (impact_max_m)
    apart = SETTINGS.impact_merge_m + 0.003
    pair = [_finding("impact", 0.300, 9.0, "cad_22"), _finding("impact", 0.300 + apart, 7.0, "cad_24")]
    bounds = {"cad_22": 0.002, "cad_24": 0.002}
    assert [f.score for f in fuse_findings(pair, (), SETTINGS, bounds)] == [9.0]
    assert len(fuse_findings(pair, (), SETTINGS)) == 2  # no pose error known: the frames' own reach only
    assert len(fuse_findings(pair, (), SETTINGS, {"cad_22": 0.001, "cad_24": 0.001})) == 2
    one_frame = [dataclasses.replace(finding, source="cad_22") for finding in pair]
    assert len(fuse_findings(one_frame, (), SETTINGS, bounds)) == 2  # one pose: their offset is real


def test_one_impact_seen_from_several_frames_is_placed_at_their_mean() -> None:
    # seed §2.3: each visit misses its vista by its own draw of the repeatability, so the frames' placements
    # of one impact err independently; a frame's second sighting shares its pose (held-out truss 2274)
    bounds = {"cad_17": 0.012, "cad_18": 0.012, "cad_19": 0.012}
    strong = _finding("impact", 0.300, 25.0, "cad_17")
    again = _finding("impact", 0.309, 23.0, "cad_18")
    (merged,) = fuse_findings([again, strong], (), SETTINGS, bounds)
    assert (merged.source, merged.score) == ("cad_17", 25.0)  # the strongest sighting stands for it
    assert merged.position_m == pytest.approx((0.3045, -0.472, 1.2), abs=1e-12)
    twice = _finding("impact", 0.300 + SETTINGS.impact_max_m / 2, 20.0, "cad_17")
    third = _finding("impact", 0.303, 10.0, "cad_19")
    (merged,) = fuse_findings([strong, again, twice, third], (), SETTINGS, bounds)
    assert merged.position_m[0] == pytest.approx((0.300 + 0.309 + 0.303) / 3, abs=1e-12)
    (alone,) = fuse_findings([strong], (), SETTINGS, bounds)
    assert alone == strong


def test_one_frame_s_two_sightings_are_one_impact_only_within_the_largest_impact() -> None:
    # the pieces of one spot lie inside the largest impact's extent, and one pose places both (held-out truss
    # 2279: two bright craters 7.3 mm apart on the panel, seen apart from cad_28, made one finding)
    first = _finding("impact", 0.300, 38.0, "cad_28")
    apart = [first, _finding("impact", 0.3073, 33.0, "cad_28")]
    assert sorted(f.score for f in fuse_findings(apart, (), SETTINGS)) == [33.0, 38.0]
    pieces = [first, _finding("impact", 0.300 + 0.9 * SETTINGS.impact_max_m, 33.0, "cad_28")]
    assert [f.score for f in fuse_findings(pieces, (), SETTINGS)] == [38.0]


def test_a_frame_that_sees_two_impacts_apart_keeps_both_when_another_frame_saw_one() -> None:
    # truss seed 2174 in space: fill_04 placed a 3.2 mm and a 1.9 mm impact 23 mm apart from one pose;
    # D_tubing's stronger sighting of the first lay within both frames' bounds of either
    bounds = {"D_tubing": 0.012, "fill_04": 0.012}
    strong = _finding("impact", 0.300, 47.0, "D_tubing")
    first_again = _finding("impact", 0.302, 20.0, "fill_04")
    second = _finding("impact", 0.323, 9.0, "fill_04")
    merged = fuse_findings([strong, first_again, second], (), SETTINGS, bounds)
    assert sorted(f.score for f in merged) == [9.0, 47.0]
    # alone in its frame, the weaker sighting is the stronger one's impact seen again, as before
    assert [f.score for f in fuse_findings([strong, second], (), SETTINGS, bounds)] == [47.0]
    # two sightings of one impact in a frame (within impact_max_m) do not make it two
    twice = _finding("impact", 0.302 + SETTINGS.impact_max_m / 2, 8.0, "fill_04")
    assert [f.score for f in fuse_findings([strong, first_again, twice], (), SETTINGS, bounds)] == [47.0]


def test_pose_error_is_the_arms_repeatability_at_the_vistas_standoff() -> None:
    from rsi.mission.viewing import focal_px, pose_error_m
    from rsi.sim import load
    from rsi.sim.world import REPEATABILITY_PX

    for repeatability in ("lab", "space"):
        world = load("truss", seed=0, repeatability=repeatability, arm=False)
        try:
            vista = world.vista("A_door")
            expected = REPEATABILITY_PX[repeatability][1] * vista.standoff_m / focal_px(480)
            assert pose_error_m(world, "A_door", 480) == pytest.approx(expected)
            # the bound is a shift in the frame's own pixels (as the tour draws it): twice the rows, half
            assert pose_error_m(world, "A_door", 960) == pytest.approx(expected / 2)
            with pytest.raises(InputError, match="vista"):
                pose_error_m(world, "nowhere", 480)
            with pytest.raises(InputError, match="rows"):
                pose_error_m(world, "A_door", 0)
        finally:
            world.close()
    with pytest.raises(InputError, match="world"):
        pose_error_m("truss", "A_door", 480)  # type: ignore[arg-type]


def _blob(area_m2: float, metres_per_px: float) -> Look:
    pixels = round(area_m2 / metres_per_px**2)
    side = math.ceil(math.sqrt(pixels))
    flaw = Flaw(10.0, 10.0, (0, 0, side, side), pixels, 9.0, "dark")
    return Look(flaw, (0.0, 0.0, 0.0), pixels * metres_per_px**2, 9.0)


def test_a_blob_larger_than_the_largest_impact_can_flag_is_no_impact() -> None:
    from rsi.mission.evidence import impact_sized

    largest = SETTINGS.impact_max_m
    for pixel_m in (0.3e-3, 0.46e-3, 0.66e-3):
        # the largest impact, its disc grown by the 3 x 3 window's pixel on each side
        grown = math.pi / 4 * (largest + 2 * pixel_m) ** 2
        assert impact_sized(_blob(grown, pixel_m), SETTINGS)
        # truss seed 1992's 80 mm^2 blobs on the panel, and anything beyond the bound square
        assert not impact_sized(_blob(80e-6, pixel_m), SETTINGS)
        bound = (largest + SETTINGS.flaw_size_px * pixel_m) ** 2
        assert not impact_sized(_blob(1.05 * bound, pixel_m), SETTINGS)
    # a larger impact the mission is told to expect widens the bound
    wider = dataclasses.replace(SETTINGS, impact_max_m=10e-3)
    assert impact_sized(_blob(80e-6, 0.46e-3), wider)


def _with_components(masks: dict[str, Any]) -> Any:
    """A sensed view whose CAD projection holds only these component masks."""
    return SimpleNamespace(capture=SimpleNamespace(cad=SimpleNamespace(components=masks)))


def _sensed(world: Any, vista: str) -> Any:
    from rsi.mission.views import sense
    from rsi.sim.capture import capture

    return sense(capture(world, world.render(vista, size=(120, 160), state="reference", stereo=True)))


def test_metering_lifts_the_dark_panel_and_leaves_bright_aluminium() -> None:
    from rsi.sim.world import MAX_STROBE_ENERGY, load

    world: Any = load("truss", seed=0)
    try:
        panel = metered_energy(_sensed(world, "C_panel"), SETTINGS)
        plate = metered_energy(_sensed(world, "D_tubing"), SETTINGS)
    finally:
        world.close()
    assert 1.5 < panel <= MAX_STROBE_ENERGY  # solar cells read a few tens of DN at the seed's flash
    assert SETTINGS.min_strobe_energy <= plate < panel


def test_metering_weakens_a_flash_that_saturates_close_glossy_metal() -> None:
    from rsi.mission.views import sense
    from rsi.sim.capture import capture
    from rsi.sim.world import load

    world: Any = load("truss", seed=0)
    try:
        point = world.vista("B_tank")  # brushed aluminium, 0.25 m away: the flash's 1/d^2 and its glare
        pairs = zip(point.position_m, point.target_m, strict=True)
        position = tuple(t + 0.25 * (p - t) / point.standoff_m for p, t in pairs)
        world.add_vista(dataclasses.replace(point, name="close_tank", position_m=position, standoff_m=0.25))
        view = world.render("close_tank", size=(120, 160), state="reference", stereo=True)
        seed_flash = sense(capture(world, view))
        assert flash_clipped(seed_flash, SETTINGS)  # the brightest 0.5 % saturate: a lower bound only
        quarter = sense(capture(world, world.reflash(view, strobe_energy=0.25, shutter=1.0)))
        energy = metered_energy(quarter, SETTINGS, flashed_at=0.25)
        metered = sense(capture(world, world.reflash(view, strobe_energy=energy, shutter=1.0)))
    finally:
        world.close()
    assert SETTINGS.min_strobe_energy <= energy < 1.0
    assert not flash_clipped(metered, SETTINGS)
    # the strobe alone at the meter's percentile where the target less the ambient put it (shot noise)
    black = metered.capture.frames[0].camera.black_level_dn
    wanted = SETTINGS.strobe_target_dn - black - ambient_dn(metered, SETTINGS)
    assert strobe_dn(metered, SETTINGS) == pytest.approx(wanted, abs=12.0)


def test_metering_shortens_the_shutter_on_sunlit_metal_only() -> None:
    from rsi.sim.world import MIN_SHUTTER, load

    world: Any = load("truss", seed=0)
    try:
        door = _sensed(world, "A_door")  # lab sun on brushed aluminium
        panel = _sensed(world, "C_panel")  # in the truss's shadow
        shutter = metered_shutter(door, SETTINGS)
        assert ambient_dn(door, SETTINGS) > 1.5 * SETTINGS.ambient_target_dn
        assert MIN_SHUTTER <= shutter < 1 / 1.5
        assert ambient_dn(door, SETTINGS) * shutter == pytest.approx(SETTINGS.ambient_target_dn, rel=1e-6)
        assert metered_shutter(panel, SETTINGS) == 1.0
        # the strobe gets the headroom the sun gave back
        assert metered_energy(door, SETTINGS, shutter) >= metered_energy(door, SETTINGS)
    finally:
        world.close()


def test_screw_relief_tells_a_head_from_its_hole() -> None:
    from rsi.mission import plan_vistas
    from rsi.mission.views import sense
    from rsi.sim.anomalies import AnomalySettings
    from rsi.sim.capture import capture
    from rsi.sim.mockup import SCREW_HEIGHT_M
    from rsi.sim.world import load

    # the seed mock-up's draw of seed 136 removes screws B_1 and B_3
    world: Any = load("truss", seed=136, settings=AnomalySettings.seed_mockup())
    try:
        plan_vistas(world)
        view = world.render("B_tank", stereo=True)
        assert view.depth_m is not None
        sensed = sense(capture(world, view))
        sites = {s.name: s for s in world.mockup.candidates.screw_sites}
        # the relief of the rendered depth: what a perfect range map would give
        relief = {name: screw_relief_m(view.depth_m, sensed, sites[name]) for name in sites if "_B_" in name}
    finally:
        world.close()
    removed = {a.site for a in world.anomalies.anomalies if a.kind == "missing_screw"} & set(relief)
    assert removed == {"screw_B_1", "screw_B_3"}
    for name, height in relief.items():
        expected = 0.0 if name in removed else SCREW_HEIGHT_M
        assert height == pytest.approx(expected, abs=0.3 * SETTINGS.screw_relief_lost_m)


def test_a_discolouring_explains_only_blobs_on_its_own_pixels() -> None:
    mask = np.zeros((60, 80), bool)
    mask[:, :40] = True  # the discoloured component fills the left half
    view = _with_components({"B_tank": mask})
    explanation = Explanation((0.0, 0.0, 0.0), 0.2, "B_tank")
    on_it = _look((0.05, 0.0, 0.0), 2e-6, (20, 10, 22, 12))
    beside = _look((0.05, 0.0, 0.0), 2e-6, (20, 60, 22, 62))
    far = _look((0.5, 0.0, 0.0), 2e-6, (20, 10, 22, 12))
    assert explained_by(on_it, view, explanation, SETTINGS)  # type: ignore[arg-type]
    assert not explained_by(beside, view, explanation, SETTINGS)  # type: ignore[arg-type]
    assert not explained_by(far, view, explanation, SETTINGS)  # type: ignore[arg-type]
    dent = Explanation((0.0, 0.0, 0.0), 0.07)
    assert explained_by(beside, view, dent, SETTINGS)  # type: ignore[arg-type]
    spot = _look((0.05, 0.0, 0.0), 2e-6, (20, 60, 22, 62), contrast=0.5)
    assert not explained_by(spot, view, dent, SETTINGS)  # type: ignore[arg-type]  # an impact on the crater
    faint = _look((0.05, 0.0, 0.0), 2e-6, (20, 60, 22, 62), contrast=0.3)
    wide = _look((0.05, 0.0, 0.0), 5e-5, (20, 60, 30, 70), contrast=0.5)
    assert explained_by(faint, view, dent, SETTINGS) and explained_by(wide, view, dent, SETTINGS)  # type: ignore[arg-type]
    assert not explained_by(on_it, _with_components({}), explanation, SETTINGS)  # type: ignore[arg-type]


def test_a_found_discolouring_leaves_the_photometric_fit() -> None:
    import cv2

    rng = np.random.default_rng(5)
    texture = cv2.GaussianBlur(rng.standard_normal((120, 160)).astype(np.float32), (0, 0), 2.0)
    reference = 80.0 + 40.0 * texture / texture.std()
    inspection = reference + rng.normal(0.0, 1.0, reference.shape)
    inspection[:, :90] *= 0.45  # a replacement tank reflecting 0.45 of the original fills the left
    inspection[60:63, 130:133] -= 25.0  # a spot on the plate beside it
    tank = np.zeros(reference.shape, bool)
    tank[:, :90] = True
    whole = compare(_image(reference), _image(inspection), 1e-4, SETTINGS)
    view = _with_components({"B_tank": tank})
    changed = discoloured_pixels(view, [Explanation((0.0, 0.0, 0.0), 0.2, "B_tank")], SETTINGS)  # type: ignore[arg-type]
    assert changed is not None
    # the CAD pixels and a margin of the settings' width for the pose error
    assert changed[:, : 90 + SETTINGS.discoloured_margin_px].all() and not changed[:, 95:].any()
    reference_kept, inspection_kept = (
        dataclasses.replace(image, valid=image.valid & ~changed)
        for image in (_image(reference), _image(inspection))
    )
    pair = compare(reference_kept, inspection_kept, 1e-4, SETTINGS)
    spot = (slice(59, 64), slice(129, 134))
    assert pair.detection.score[spot].max() > max(8.0, 2 * whole.detection.score[spot].max())
    dent = [Explanation((0.0, 0.0, 0.0), 0.07)]
    assert discoloured_pixels(view, dent, SETTINGS) is None  # type: ignore[arg-type]  # a dent leaves the fit alone


def _textured(seed: int = 5) -> np.ndarray:
    """A gently textured surface: the misregistration floor then hardly shapes the noise model."""
    import cv2

    rng = np.random.default_rng(seed)
    texture = cv2.GaussianBlur(rng.standard_normal((120, 160)).astype(np.float32), (0, 0), 2.0)
    return (80.0 + 5.0 * texture / texture.std()).astype(np.float32)


@pytest.mark.parametrize("sign", [-1.0, 1.0])
def test_the_comparison_finds_dark_and_bright_spots_and_their_contrast(sign: float) -> None:
    rng = np.random.default_rng(6)
    reference, inspection = (_textured() + rng.normal(0.0, 1.0, (120, 160)).astype(np.float32) for _ in "ab")
    inspection[60:63, 80:83] *= np.float32(1.0 + sign * 0.4)  # tape (dark) or bared metal (bright), 3x3 px
    pair = compare(_image(reference, 1.0), _image(inspection, 1.0), SETTINGS.p_false_alarm, SETTINGS)
    assert len(pair.flaws) == 1
    flaw = pair.flaws[0]
    assert flaw.polarity == ("bright" if sign > 0 else "dark")
    assert 59 <= flaw.row <= 63 and 79 <= flaw.col <= 83
    # the 3x3 window on the spot changed by its 40 %; read with the other sign, only noise (< 0.03)
    assert contrast(pair, flaw.bbox, flaw.polarity) == pytest.approx(0.4, abs=0.05)
    assert contrast(pair, flaw.bbox, "dark" if sign > 0 else "bright") < 0.03


def test_a_component_changed_one_way_is_a_swap_and_noise_of_either_sign_is_not() -> None:
    from rsi.mission.evidence import component_change
    from rsi.mission.views import disc, seen_components
    from rsi.sim.world import load

    world: Any = load("truss", seed=0)
    view = _sensed(world, "B_tank")
    site = next(site for site in seen_components(world, view) if site.name == "B_tank")
    centre = disc((120, 160), view, site.position_m, SETTINGS.component_disc_m)
    rng = np.random.default_rng(3)
    reference = _textured(3)
    repainted, unsettled = (
        reference + rng.normal(0.0, 1.0, reference.shape).astype(np.float32) for _ in "ab"
    )
    repainted[centre] *= np.float32(0.6)  # a replacement of 0.6 the reflectance (seed §4: 0.4-0.8)
    unsettled[centre] += rng.normal(0.0, 8.0, int(centre.sum())).astype(np.float32)  # noise the model misses
    swap = compare(_image(reference, 1.0), _image(repainted, 1.0), 1e-4, SETTINGS)
    noise = compare(_image(reference, 1.0), _image(unsettled, 1.0), 1e-4, SETTINGS)
    # signed: a darker replacement reads negative
    assert component_change(swap, view, site, SETTINGS) < -0.5  # type: ignore[arg-type]
    # beyond 3 sigmas both ways over much of the disc, in equal measure: no repaint
    z = noise.detection.difference[centre] / noise.detection.sigma[centre]
    assert np.mean(z > 3.0) > 0.2 and np.mean(z < -3.0) > 0.2
    assert abs(component_change(noise, view, site, SETTINGS)) < SETTINGS.component_change_min  # type: ignore[arg-type]


@pytest.mark.parametrize(
    ("readings", "expected"),
    [((0.3, 0.2), 0.2), ((-0.3, -0.5), -0.3), ((0.9, 0.0), 0.0), ((0.9, -0.2), 0.0), ((), 0.0)],
)
def test_a_change_counts_as_far_as_every_reference_agrees(
    readings: tuple[float, ...], expected: float
) -> None:
    from rsi.mission.evidence import agreed

    assert agreed(readings) == expected


def test_a_repaint_seen_against_one_reference_only_is_no_swap_and_untrusted_pixels_read_nothing() -> None:
    from rsi.mission.evidence import component_change, component_checks
    from rsi.mission.views import disc, seen_components
    from rsi.sim.world import load

    world: Any = load("truss", seed=0)
    try:
        view = _sensed(world, "B_tank")
        site = next(site for site in seen_components(world, view) if site.name == "B_tank")
        centre = disc((120, 160), view, site.position_m, SETTINGS.component_disc_m)
        rng = np.random.default_rng(4)
        reference = _textured(3)
        first, second, now = (
            reference + rng.normal(0.0, 1.0, reference.shape).astype(np.float32) for _ in "abc"
        )
        now[centre] *= np.float32(
            0.6
        )  # darker over the disc now; the second pristine visit was too (a glare)
        glared = second.copy()
        glared[centre] *= np.float32(0.6)
        against_first = compare(_image(first, 1.0), _image(now, 1.0), 1e-4, SETTINGS)
        against_glared = compare(_image(glared, 1.0), _image(now, 1.0), 1e-4, SETTINGS)
        assert component_change(against_first, view, site, SETTINGS) < -0.5  # type: ignore[arg-type]
        assert abs(component_change(against_glared, view, site, SETTINGS)) < SETTINGS.component_change_min  # type: ignore[arg-type]
        # nothing of the disc trusted (past the strobe's beam, edge-on): no reading at all
        nowhere = np.zeros((120, 160), bool)
        assert component_change(against_first, view, site, SETTINGS, nowhere) == 0.0  # type: ignore[arg-type]

        def swaps(pairs: tuple[Any, ...]) -> list[str]:
            found = component_checks(
                pairs,
                view,
                "B_tank",
                reference_m=view.range_m,
                world=world,
                settings=SETTINGS,
                only={"B_tank"},
            )
            return [explanation.component for _, explanation in found]

        assert swaps((against_first,)) == ["B_tank"]
        assert swaps((against_first, against_glared)) == []
        # the surface itself changed: new against both pristine visits
        both = (against_first, compare(_image(second, 1.0), _image(now, 1.0), 1e-4, SETTINGS))
        assert swaps(both) == ["B_tank"]
    finally:
        world.close()


def _cluttered(spot_dn: float, offset_dn: float, noise_dn: float) -> Any:
    """A textured pair whose inspection has a 60x60 part the noise model under-states (shifted by
    `offset_dn`, `noise_dn` more noise: a dim face's compensation under another sun), a 3x3 spot of
    `spot_dn` in its middle."""
    rng = np.random.default_rng(6)
    reference, inspection = (_textured() + rng.normal(0.0, 1.0, (120, 160)).astype(np.float32) for _ in "ab")
    inspection[40:100, 30:90] += np.float32(offset_dn) + rng.normal(0, noise_dn, (60, 60)).astype(np.float32)
    inspection[70:73, 60:63] += np.float32(spot_dn)
    return compare(_image(reference, 1.0), _image(inspection, 1.0), SETTINGS.p_false_alarm, SETTINGS)


def test_a_spot_is_judged_against_its_own_surroundings() -> None:
    from rsi.mission.evidence import spot_score
    from rsi.mission.visual import thresholds

    confirm, kernel = thresholds(SETTINGS).confirm, SETTINGS.flaw_size_px
    for sign, polarity in ((1.0, "bright"), (-1.0, "dark")):  # on a surface the model describes: as it is
        clean = _cluttered(6.0 * sign, 0.0, 0.0)
        (flaw,) = clean.flaws
        assert spot_score(clean, flaw.bbox, flaw.score, polarity, kernel) == flaw.score
    noise = _cluttered(0.0, 3.0, 1.0)
    assert len(noise.flaws) > 20 and all(flaw.score > confirm for flaw in noise.flaws)
    assert all(spot_score(noise, f.bbox, f.score, f.polarity, kernel) < confirm for f in noise.flaws)
    strong = _cluttered(18.0, 3.0, 1.0)
    score = float(strong.detection.score[70:73, 60:63].max())
    assert spot_score(strong, (70, 60, 73, 63), score, "bright", kernel) > confirm  # it stands out
    # the ring vetoes, never detects: a dark spot on a brightened part is not helped by it
    dark = _cluttered(-6.0, 3.0, 1.0)
    score = float(dark.detection.score[70:73, 60:63].max())
    assert spot_score(dark, (70, 60, 73, 63), score, "dark", kernel) <= score


def _lined(spot_dn: float, line_dn: float, angle_deg: float) -> Any:
    """A plain pair whose inspection carries a line 2 px wide of `line_dn` across the frame through
    (71, 61) at `angle_deg` (an edge's residual), and a 3x3 spot of `spot_dn` on it there."""
    import cv2

    rng = np.random.default_rng(7)
    reference, inspection = (
        np.float32(80.0) + rng.normal(0.0, 1.0, (120, 160)).astype(np.float32) for _ in "ab"
    )
    line = np.zeros((120, 160), np.uint8)
    direction = np.array([math.cos(math.radians(angle_deg)), math.sin(math.radians(angle_deg))]) * 200
    ends = (np.array([61.0, 71.0]) - direction, np.array([61.0, 71.0]) + direction)
    cv2.line(line, *(tuple(round(float(v)) for v in end) for end in ends), 1, 2)
    inspection += np.float32(line_dn) * line
    inspection[70:73, 60:63] += np.float32(spot_dn)
    return compare(_image(reference, 1.0), _image(inspection, 1.0), SETTINGS.p_false_alarm, SETTINGS)


@pytest.mark.parametrize("angle_deg", [12.0, 33.0, 90.0, 128.0, 150.0])
def test_a_spot_on_an_edges_residual_is_judged_against_the_line(angle_deg: float) -> None:
    """Seed §2.3: an edge re-sampled leaves a line in the difference, too thin to move the ring's median;
    a part of it read as a spot stands out of its ring but not out of the line (truss seed 2251, CAD
    plan: a solar-cell gap confirmed as three impacts), and a flaw on the line still stands out of it."""
    from rsi.mission.evidence import spot_score
    from rsi.mission.visual import thresholds

    confirm, kernel = thresholds(SETTINGS).confirm, SETTINGS.flaw_size_px
    bbox = (70, 60, 73, 63)
    only_line = _lined(0.0, 4.0, angle_deg)
    score = float(only_line.detection.score[70:73, 60:63].max())
    assert score > confirm  # the line's residual alone reads as a confirmed spot against the noise model
    assert spot_score(only_line, bbox, score, "bright", kernel) < confirm
    on_line = _lined(12.0, 4.0, angle_deg)
    score = float(on_line.detection.score[70:73, 60:63].max())
    assert spot_score(on_line, bbox, score, "bright", kernel) > confirm


def test_a_brighter_sun_shortens_the_inspection_shutter_and_leaves_the_strobe_image() -> None:
    from rsi.mission.run import ORBIT_START_S
    from rsi.mission.tour import Tour
    from rsi.mission.views import inspection_region, sense
    from rsi.sim.world import load

    world: Any = load("truss", seed=0, arm=True)
    try:
        tour = Tour(world, seed=0, size=(120, 160))
        tour.start_pass("inspection", ORBIT_START_S[0])
        door = sense(tour.visit("A_door", "A_door", state="inspection"))  # sunlit aluminium, seed's shutter
        again, shutter = shortened(tour, door, SETTINGS, shutter=1.0, energy=1.0)
        assert shutter < 1 / 1.5 and ambient_dn(again, SETTINGS) <= 1.05 * SETTINGS.ambient_target_dn
        before, after = door.strobe, again.strobe
        both = before.valid & after.valid & inspection_region(door, SETTINGS)
        # the ~20 us flash fits in any shutter (seed §2.1): the strobe image keeps its level
        assert np.median(after.image[both]) == pytest.approx(np.median(before.image[both]), rel=0.05)
        assert after.valid.sum() >= before.valid.sum()  # and fewer saturated pixels
        panel = sense(tour.visit("C_panel", "C_panel", state="inspection"))  # in the truss's shadow
        kept, same = shortened(tour, panel, SETTINGS, shutter=0.5, energy=1.0)
        assert same == 0.5 and kept is panel  # a dimmer sun needs nothing
    finally:
        world.close()


def _edge_pair(shift_px: float, spot: bool) -> Any:
    """A vertical step edge a pixel off in the inspection (taken as aligned), maybe a dark spot beside it."""
    from rsi.detection.detect import detect
    from rsi.detection.pair import PairResult

    cols = np.arange(160, dtype=np.float64)
    profile = np.where(cols < 80.0, 40.0, 120.0)
    profile[80] = 80.0
    rng = np.random.default_rng(8)
    reference, inspection = (
        np.tile(np.interp(cols - shift, cols, profile), (120, 1)).astype(np.float32)
        + rng.normal(0.0, 1.0, (120, 160)).astype(np.float32)
        for shift in (0.0, shift_px)
    )
    if spot:
        inspection[60:63, 84:87] -= 40.0
    found = detect(
        _image(reference, 1.0),
        _image(inspection, 1.0),
        registration=None,
        p_false_alarm=1e-4,
        polarity="both",
    )
    return PairResult(reference, inspection, found, 0.0)


def test_a_local_shift_explains_an_edge_left_off_but_not_a_spot_beside_it() -> None:
    from rsi.mission.evidence import shift_explained

    edge = _edge_pair(1.0, spot=False)
    assert edge.flaws  # the edge left a pixel off scores as a flaw
    for flaw in edge.flaws:
        look = Look(flaw, (0.0, 0.0, 0.0), 1e-6, flaw.score)
        assert shift_explained(edge, look, 4.0, max_shift_px=1.5)
        assert not shift_explained(edge, look, 4.0, max_shift_px=0.25)  # a pixel needs a pixel
    spotted = _edge_pair(1.0, spot=True)
    spot = next(f for f in spotted.flaws if 59 <= f.row <= 63 and 83 <= f.col <= 87)
    assert not shift_explained(spotted, Look(spot, (0.0, 0.0, 0.0), 1e-6, spot.score), 4.0, max_shift_px=1.5)


@functools.cache
def _screw_pair() -> tuple[Any, Any, dict[str, Any]]:
    """The B tank's view of seed 136's seed-mock-up draw, which removes screws B_1 and B_3 (two visits: two
    viewpoint errors): the comparison, the inspection's view and the screw sites by name."""
    from rsi.mission import plan_vistas
    from rsi.mission.settings import MISSION_SIZE
    from rsi.mission.views import sense
    from rsi.sim.anomalies import AnomalySettings
    from rsi.sim.capture import capture
    from rsi.sim.world import load

    world: Any = load("truss", seed=136, settings=AnomalySettings.seed_mockup())
    try:
        plan_vistas(world)
        views = {
            state: sense(capture(world, world.render("B_tank", size=MISSION_SIZE, state=state, stereo=True)))
            for state in ("reference", "inspection")
        }
    finally:
        world.close()
    images = {state: view.strobe for state, view in views.items()}
    pair = compare(images["reference"], images["inspection"], SETTINGS.p_false_alarm, SETTINGS)
    return pair, views["inspection"], {s.name: s for s in world.mockup.candidates.screw_sites}


def test_a_removed_screw_loses_its_head_pattern_and_a_present_one_keeps_it() -> None:
    from rsi.mission.screws import HEAD_KEPT, head_kept, head_likeness, screw_change

    pair, seen, sites = _screw_pair()
    likeness = {
        name: head_likeness(pair, seen, sites[name], SETTINGS.local_shift_px)
        for name in ("screw_B_0", "screw_B_1", "screw_B_2", "screw_B_3")
    }
    for name in ("screw_B_1", "screw_B_3"):  # removed: a hole where the slotted head was
        assert likeness[name] is not None and likeness[name] < HEAD_KEPT
        assert head_kept([pair], seen, sites[name], SETTINGS.local_shift_px) is False
    for name in ("screw_B_0", "screw_B_2"):  # present: the same head, its slot re-sampled
        assert likeness[name] is not None and likeness[name] >= HEAD_KEPT
        assert head_kept([pair], seen, sites[name], SETTINGS.local_shift_px) is True
    # a screw of another ORU is out of this view: nothing to say
    assert head_likeness(pair, seen, sites["screw_D_0"], SETTINGS.local_shift_px) is None
    assert head_kept([pair, pair], seen, sites["screw_D_0"], SETTINGS.local_shift_px) is None
    # The hole darkens its disc beyond any local shift of the reference (measured 10.5 and 14.3 sigmas);
    # a present head's slot, re-sampled, does not (1.9 and 1.0). The comparison's own statistic, whose noise
    # model adds a residual shift's error on the head's edges, read the holes of seed 1911 at 0.8.
    confirm = thresholds(SETTINGS).confirm
    change = {name: screw_change(pair, seen, sites[name], SETTINGS.local_shift_px) for name in likeness}
    assert min(change["screw_B_1"], change["screw_B_3"]) > confirm
    assert max(change["screw_B_0"], change["screw_B_2"]) < confirm
    assert screw_change(pair, seen, sites["screw_D_0"], SETTINGS.local_shift_px) == 0.0
    # a repainted component darkens the plate around its screws, present or not: the hole stays darker than
    # the plate, a present head's disc rim does not (held-out truss seed 2048's swapped ORU)
    repainted = _plate_darkened(pair, seen, [sites[name] for name in likeness], 0.6)
    again = {name: screw_change(repainted, seen, sites[name], SETTINGS.local_shift_px) for name in likeness}
    assert min(again["screw_B_1"], again["screw_B_3"]) > confirm
    assert max(again["screw_B_0"], again["screw_B_2"]) < confirm


def test_a_head_mostly_out_of_the_comparison_is_not_read_on_its_rim() -> None:
    """A present head whose disc the comparison mostly leaves (a reference saturated by its glint) keeps a
    sliver of rim, where its relief renders a little darker from another viewpoint: read over the sliver
    against the plate's few-DN spread it stood at 24-28 sigma, a missing screw (held-out truss 2300, cad_29,
    screw_C_0, at both suns). Under half its disc in the comparison says nothing of the head, as for its
    pattern (:func:`head_likeness`)."""
    from rsi.mission.screws import head_likeness, screw_change
    from rsi.mission.views import disc

    pair, seen, sites = _screw_pair()
    site = sites["screw_B_0"]  # present
    shape = pair.inspection.shape
    core = disc(shape, seen, site.position_m, 0.46 * site.size_m)
    rim = disc(shape, seen, site.position_m, 0.5 * site.size_m + 1e-3) & ~core  # the rim and a pixel out
    inspection = np.where(rim, pair.inspection - 60.0, pair.inspection).astype(np.float32)
    difference = (pair.detection.difference + (inspection - pair.inspection)).astype(np.float32)
    detection = dataclasses.replace(pair.detection, difference=difference, valid=pair.detection.valid & ~core)
    sliver = dataclasses.replace(pair, inspection=inspection, detection=detection)
    assert head_likeness(sliver, seen, site, SETTINGS.local_shift_px) is None
    assert screw_change(sliver, seen, site, SETTINGS.local_shift_px) == 0.0
    # the same dark rim with the whole disc in the comparison is read
    whole = dataclasses.replace(sliver, detection=dataclasses.replace(detection, valid=pair.detection.valid))
    assert screw_change(whole, seen, site, SETTINGS.local_shift_px) > thresholds(SETTINGS).confirm


def _plate_darkened(pair: Any, view: Any, screws: list[Any], factor: float) -> Any:
    """`pair` with its inspection `factor` as bright everywhere but on the screws' heads."""
    from rsi.mission.views import disc

    shape = pair.inspection.shape
    heads = np.zeros(shape, bool)
    for site in screws:
        heads |= disc(shape, view, site.position_m, 0.5 * site.size_m)
    inspection = np.where(heads, pair.inspection, factor * pair.inspection).astype(np.float32)
    difference = (pair.detection.difference + (inspection - pair.inspection)).astype(np.float32)
    detection = dataclasses.replace(pair.detection, difference=difference)
    return dataclasses.replace(pair, inspection=inspection, detection=detection)


def test_small_looks_inside_a_swaps_blob_are_the_swaps() -> None:
    from rsi.mission.evidence import apart_from_swaps

    big = SETTINGS.component_area_m2 * 4
    swap = _look((0.0, 0.0, 0.0), big, (100, 100, 140, 160))  # centre (120, 130), radius 36 px + surround
    inside = _look((0.0, 0.0, 0.0), 4e-6, (128, 150, 131, 153))  # 24 px from its centre
    beside = _look((0.0, 0.0, 0.0), 4e-6, (100, 170, 103, 173))  # 45 px away: outside
    kept = apart_from_swaps([swap, inside, beside], SETTINGS)
    assert kept == [swap, beside]
    # without a swap every small look stands
    assert apart_from_swaps([inside, beside], SETTINGS) == [inside, beside]


def _patch_beside_a_spot() -> tuple[Any, Any]:
    """A 50 px brighter disc (a discoloured patch, seed §4: 1.3 times) and a darker 3 x 3 px spot 6 px
    beyond its rim, in the corner of the disc's box; the comparison and a view of it square-on at 0.1 m
    (0.6 mm pixels: the disc 3 cm wide, a swap's size, the spot an impact's)."""
    from rsi.sim.render import CameraPose

    rng = np.random.default_rng(7)
    reference, inspection = (_textured() + rng.normal(0.0, 1.0, (120, 160)).astype(np.float32) for _ in "ab")
    rows, cols = np.mgrid[:120, :160]
    inspection[np.hypot(rows - 60, cols - 80) <= 25] *= np.float32(1.3)
    inspection[37:40, 57:60] *= np.float32(0.5)  # centre (38, 58): 31 px from the disc's, 25 px its radius
    pair = compare(_image(reference, 1.0), _image(inspection, 1.0), 1e-4, SETTINGS)
    pose = CameraPose(np.zeros(3), np.eye(3), math.radians(40.0), (120, 160))
    view = SimpleNamespace(surface_m=np.full((120, 160), 0.1, np.float32), believed_pose=pose)
    return pair, view


def test_a_large_blob_is_read_at_its_own_peak_though_its_box_holds_a_stronger_spot() -> None:
    """Held-out truss seed 2210: the panel's brighter patch was read again at the darker impact in its
    box, for a brighter change, and dropped (:func:`rsi.mission.evidence.same_sign_again`)."""
    from rsi.mission.evidence import blobs

    pair, view = _patch_beside_a_spot()
    patch, spot = sorted(blobs(pair, view), key=lambda look: -look.flaw.area_px)[:2]
    assert patch.flaw.polarity == "bright" and spot.flaw.polarity == "dark"
    assert spot.score > patch.score  # the box's highest score is the spot's
    row0, col0, row1, col1 = patch.bbox
    assert row0 <= spot.at_px[0] < row1 and col0 <= spot.at_px[1] < col1
    assert math.hypot(patch.at_px[0] - 60, patch.at_px[1] - 80) <= 26  # on the disc, not at the spot
    assert pair.detection.statistic[int(patch.at_px[0]), int(patch.at_px[1])] > 0


def test_a_spot_beyond_a_swaps_outline_stands_though_in_its_box() -> None:
    from rsi.mission.evidence import apart_from_swaps, blobs

    pair, view = _patch_beside_a_spot()
    patch, spot = sorted(blobs(pair, view), key=lambda look: -look.flaw.area_px)[:2]
    assert patch.area_m2 > SETTINGS.component_area_m2 >= spot.area_m2
    glint = _look((0.0, 0.0, 0.0), 4e-6, (59, 79, 62, 82))  # centred on the disc: the swap's own change
    assert apart_from_swaps([patch, spot, glint], SETTINGS) == [patch, spot]
    boxed = dataclasses.replace(patch, outline=None)  # a look with no outline stands for its whole box
    assert apart_from_swaps([boxed, spot, glint], SETTINGS) == [boxed]


def test_a_glint_judges_a_head_when_its_whole_loss_would_read_three_sigma() -> None:
    """fraction * sqrt(pixels) >= 3: the binomial spread of the disc's pixels (truss-b's screw_B_3 glints
    over 0.26-0.47 of a ~250-pixel disc, which the comparison cannot read)."""
    from rsi.mission.screws import GLINT_LOSS_MIN_SD, NO_GLINT, HeadGlint

    assert GLINT_LOSS_MIN_SD == 3.0
    assert HeadGlint(0.26, 3000.0, 245).telling  # 4.1 sd
    assert HeadGlint(0.19, 3000.0, 250).telling  # 3.004 sd
    assert not HeadGlint(0.18, 3000.0, 250).telling  # 2.85 sd
    assert not HeadGlint(0.5, 3000.0, 25).telling  # half of a 25-pixel disc: 2.5 sd
    assert not NO_GLINT.telling


def test_a_removed_panel_screw_loses_its_glint_and_a_present_one_keeps_it() -> None:
    """Seen from above at 16 deg off the axis, a polished head returns the metered flash of the dark panel
    into saturation: the comparison cannot read the head's disc, the glint tells (both under a sun moved
    300 s between the passes)."""
    from rsi.mission.exposure import metered
    from rsi.mission.run import ORBIT_START_S
    from rsi.mission.screws import head_glint, head_likeness, screw_checks
    from rsi.mission.tour import Tour
    from rsi.mission.views import sense
    from rsi.mission.visual import thresholds
    from rsi.sim.mockup import vista
    from rsi.sim.world import load

    world: Any = load("truss", seed=5, arm=False)  # its draw removes the panel's screws C_0 and C_1
    try:
        sites = {site.name: site for site in world.mockup.candidates.screw_sites}
        tour = Tour(world, seed=0, size=(480, 640), arm=False)
        found: dict[str, bool] = {}
        for name, away in (("screw_C_0", (0.045, 0.085, 0.0)), ("screw_C_3", (-0.045, -0.085, 0.0))):
            site = sites[name]
            target = tuple(np.add(site.position_m, away))
            world.add_vista(vista(name, target, site.normal, (1.0, 0.0, 0.0), 0.3425))
            tour.start_pass("reference", ORBIT_START_S[0])
            world.set_strobe_energy(1.0)  # the pre-flash at the seed's flash and shutter (run's settle)
            world.set_shutter(1.0)
            reference, shutter, energy = metered(
                tour, sense(tour.visit(name, name, state="reference", truth=False)), SETTINGS
            )
            world.set_shutter(shutter)
            world.set_strobe_energy(energy)
            glint = head_glint(reference, site)
            assert glint.telling
            assert 0.0 < glint.floor_dn <= reference.capture.camera.max_dn
            tour.start_pass("inspection", ORBIT_START_S[1] + 300.0)
            seen = sense(tour.visit(name, name, state="inspection", truth=False))
            pair = compare(reference.strobe, seen.strobe, SETTINGS.p_false_alarm, SETTINGS)
            assert head_likeness(pair, seen, site, SETTINGS.local_shift_px) is None  # saturated: unread
            findings, checked = screw_checks(
                world,
                seen,
                name,
                settings=SETTINGS,
                range_m=seen.range_m,
                reliefs={},
                glints={name: glint},
                done=frozenset(),
                pairs=(pair, pair),
                confirm=thresholds(SETTINGS).confirm,
            )
            found[name] = any(finding.position_m == site.position_m for finding in findings)
            assert (name in checked) == found[name]  # only a screw found missing is spent
    finally:
        world.close()
    assert found == {"screw_C_0": True, "screw_C_3": False}


def test_a_long_thin_blob_is_a_line_and_a_round_one_a_spot() -> None:
    from rsi.mission.evidence import LINE_MIN_PX, line_shaped

    def shaped(pixels: np.ndarray, strength: np.ndarray | None = None) -> bool:
        """Whether the blob of `pixels` (a mask placed at row 10, column 10 of a frame, of uniform statistic
        -9 unless `strength` gives each pixel's) is a line."""
        mask = np.zeros((120, 120), bool)
        placed = (slice(10, 10 + pixels.shape[0]), slice(10, 10 + pixels.shape[1]))
        mask[placed] = pixels
        statistic = np.zeros((120, 120))
        statistic[placed] = -9.0 if strength is None else strength
        rows, cols = np.nonzero(mask)
        box = (int(rows.min()), int(cols.min()), int(rows.max()) + 1, int(cols.max()) + 1)
        flaw = Flaw(float(rows.mean()), float(cols.mean()), box, int(rows.size), 9.0, "dark")
        peak = np.unravel_index(np.argmax(np.abs(statistic) * mask), mask.shape)
        look = Look(flaw, (0.0, 0.0, 0.0), 1e-6, 9.0, peak_px=(int(peak[0]), int(peak[1])))
        return line_shaped(look, mask, statistic)

    def bar(rows: int, cols: int) -> np.ndarray:
        return np.ones((rows, cols), bool)

    assert shaped(bar(1, 42))  # seed 2's row left by the field compensation
    assert shaped(bar(2, 12))  # 12 px long, 2 wide
    assert shaped(np.eye(30, dtype=bool))  # an edge across the rows and columns alike
    assert not shaped(bar(3, 3))  # a millimetre spot
    assert not shaped(bar(8, 8))  # the widest impact, blurred
    assert not shaped(bar(1, LINE_MIN_PX))  # no longer than the widest impact: a spot
    assert not shaped(bar(3, 12))  # 4x longer than wide at the most
    # a crater's bright rim: 50-odd pixels about a 9 x 15 px box, as wide as the crater (truss seed 2, space)
    rows, cols = np.mgrid[0:9, 0:15]
    ellipse = ((rows - 4) / 4.5) ** 2 + ((cols - 7) / 7.5) ** 2
    rim = (ellipse <= 1.0) & (ellipse >= 0.55)
    assert not shaped(rim)
    # truss seed 2064 in space: a 2.4 mm impact (4 x 5 px, 16-34 sigma) with a compensation row of 4-6 sigma
    # along its top, 32 px long: the blob is the spot; the row alone, however strong, is still a line
    spot_and_row = np.zeros((5, 32), bool)
    spot_and_row[0], spot_and_row[1:5, :5] = True, True
    strength = np.where(spot_and_row, -5.0, 0.0)
    strength[1:5, 1:4] = -30.0
    assert shaped(spot_and_row) and not shaped(spot_and_row, strength)
    assert shaped(bar(1, 32), np.full((1, 32), -30.0))
    # truss-b seed 2049 in space: a band 60 px long whose half-peak pixels come in pieces all along it
    band = np.full((4, 60), -8.0)
    band[1:3, ::12] = -19.0
    assert shaped(bar(4, 60), band)


def test_a_large_blob_is_a_components_change_only_as_wide_as_the_least_one() -> None:
    from rsi.mission.evidence import broad

    settings = MissionSettings()
    side_m = math.sqrt(settings.component_area_m2)  # 1 cm

    def wide(rows: int, cols: int, metres_per_px: float) -> bool:
        flaw = Flaw(rows / 2, cols / 2, (0, 0, rows, cols), rows * cols, 9.0, "dark")
        return broad(Look(flaw, (0.0, 0.0, 0.0), rows * cols * metres_per_px**2, 9.0), settings)

    # truss-b seed 3, space: a tank's limb against the panel behind it, 5 px by 475 at 0.42 mm a pixel
    assert not wide(475, 5, 4.2e-4)
    assert not wide(6, 163, 8.9e-4)  # seed 1's strap edge: 6 mm wide, 14 cm long
    assert wide(26, 71, 7.4e-4)  # truss seed 14's repainted door, seen 19 mm wide
    assert wide(50, 50, 1.01 * side_m / 50) and not wide(50, 50, 0.99 * side_m / 50)  # 1 cm^2's side
    assert wide(40, 400, side_m / 40) == wide(400, 40, side_m / 40)  # either way round


def test_a_look_is_followed_into_the_second_visits_frame_by_its_texture() -> None:
    from rsi.mission.evidence import FOLLOW_HALF_PX, followed

    texture = _textured(7)
    texture = 80.0 + 8.0 * (texture - 80.0)  # the panel's cells: contrast enough to register by
    first = texture[20:100, 20:140]
    shift_rows, shift_cols = 3, -11  # the second visit's viewpoint error, against the first's
    second = texture[20 - shift_rows : 100 - shift_rows, 20 - shift_cols : 140 - shift_cols]
    at = (40.0, 60.0)
    believed = (at[0], at[1])  # the believed poses saw no difference
    row, col = followed(_image(first), _image(second), at, believed)
    assert row == pytest.approx(at[0] + shift_rows, abs=0.2) and col == pytest.approx(
        at[1] + shift_cols, abs=0.2
    )
    # nothing to register by (a flat surface): where the believed poses put it
    flat = np.full(first.shape, 80.0)
    assert followed(_image(flat), _image(flat), at, believed) == believed
    # a fit further than half the window from the believed place is no fit of this look
    far = (at[0], at[1] + FOLLOW_HALF_PX)
    assert followed(_image(first), _image(second), at, far) == far


def test_a_large_blob_on_a_component_must_show_its_own_sign_again() -> None:
    """A repaint reads darker in every comparison; the strobe's glare moved by another viewpoint error reads
    darker or brighter by chance (seed §2.1, §2.3, §4): a second reading of the other sign is no echo."""
    from rsi.mission.evidence import same_sign_again, second_look_score

    rng = np.random.default_rng(5)
    reference = _textured(5)
    darker, brighter = (reference + rng.normal(0.0, 1.0, reference.shape).astype(np.float32) for _ in "ab")
    patch = (slice(40, 80), slice(60, 100))  # a 40 x 40 px patch, the middle of a component's face
    darker[patch] *= np.float32(0.6)  # seed §4: 0.4-0.8 of the reflectance
    brighter[patch] *= np.float32(1.4)
    repaint = compare(_image(reference, 1.0), _image(darker, 1.0), 1e-4, SETTINGS)
    glare = compare(_image(reference, 1.0), _image(brighter, 1.0), 1e-4, SETTINGS)
    confirm = thresholds(SETTINGS).confirm
    assert second_look_score(repaint, (60.0, 80.0)) > confirm
    assert second_look_score(repaint, (60.0, 80.0), polarity="dark") > confirm
    assert second_look_score(glare, (60.0, 80.0)) > confirm  # sign-blind: any change echoes
    assert second_look_score(glare, (60.0, 80.0), polarity="dark") == 0.0  # the other sign: none

    large = _look((0.0, 0.0, 0.0), 4 * SETTINGS.component_area_m2, (40, 60, 80, 100))
    assert same_sign_again(large) == "dark"  # _look's blobs are dark
    large.spot = True  # a spot is read against its ring (spot_score), whatever the sign here
    assert same_sign_again(large) is None


def test_a_smooth_change_over_a_part_is_the_strobes_light_and_a_patch_inside_it_is_not() -> None:
    """Seed §2.1, §2.3: the strobe's glare moved by the viewpoint error changes a part's image by a smooth
    field; seed §4: a repaint's patch has an edge of its own inside the part."""
    from rsi.mission.evidence import glare_explained

    rng = np.random.default_rng(7)
    reference = _textured(7)
    rows, cols = np.mgrid[0:120, 0:160].astype(np.float32)
    parts = np.full((120, 160), 3, np.int32)  # one part, the whole frame
    parts[:, :20] = -1  # and a margin of no model
    view = SimpleNamespace(capture=SimpleNamespace(cad=SimpleNamespace(parts=parts)))
    glare = reference * (1.0 + 0.5 * np.clip((cols - 80.0) / 60.0, 0.0, None) ** 2)  # a highlight's slope
    patch = reference.copy()
    patch[(rows - 60) ** 2 + (cols - 100) ** 2 <= 18**2] *= np.float32(0.6)  # seed §4: 0.6 the reflectance
    confirm = thresholds(SETTINGS).confirm
    explained = {}
    for name, changed in (("glare", glare), ("patch", patch)):
        noisy = changed + rng.normal(0.0, 1.0, changed.shape).astype(np.float32)
        pair = compare(_image(reference, 1.0), _image(noisy, 1.0), 1e-4, SETTINGS)
        flaw = pair.flaws[0]
        area_m2 = flaw.area_px * 2.5e-7  # 0.5 mm pixels
        assert area_m2 > SETTINGS.component_area_m2  # a large blob
        look = Look(flaw, (0.0, 0.0, 0.0), area_m2, flaw.score)
        explained[name] = glare_explained(pair, view, look, confirm, SETTINGS)  # type: ignore[arg-type]
        no_model = SimpleNamespace(capture=SimpleNamespace(cad=SimpleNamespace(parts=None)))
        assert not glare_explained(pair, no_model, look, confirm, SETTINGS)  # type: ignore[arg-type]
    assert explained == {"glare": True, "patch": False}


def _unmoved() -> Any:
    """A visit's registration that found no motion, the two passes' strobe images at one energy."""
    from rsi.imaging.registration import Registration

    return Registration(
        model="translation",
        matrix=np.eye(3),
        gain=1.0,
        bias=0.0,
        converged=True,
        reason="converged",
        iterations=1,
        residual_rms=1.0,
        shift_std_px=(0.02, 0.02),
        elapsed_s=0.0,
    )


def test_what_the_strobes_light_leaves_of_a_part_is_an_impact_on_it() -> None:
    """Seed §2.3: a glossy part's glare moved by the viewpoint error lifts the whole part, and the
    preliminary threshold joins an impact on it to that change in one blob (truss-b held-out seed 2191 in
    space: a Kapton circle +2-3 DN and a 3.8 mm dark disc, one blob of 1,250 mm^2). The light explains
    the blob; taken out of the inspection, the disc alone stands out, of its own score."""
    from rsi.mission.evidence import glare_explained, glare_light

    rng = np.random.default_rng(11)
    rows, cols = np.mgrid[0:120, 0:160].astype(np.float32)
    circle = (rows - 60) ** 2 + (cols - 100) ** 2 <= 35**2  # a black Kapton circle on a bright plate
    plate = _textured(11) - 60.0 + 100.0 * cols / 159.0  # as dark as the circle at one end: no offset
    reference = np.where(circle, 20.0 + 0.25 * (_textured(11) - 80.0), plate).astype(np.float32)
    parts = np.where(circle, 5, 3).astype(np.int32)
    view = SimpleNamespace(capture=SimpleNamespace(cad=SimpleNamespace(parts=parts)))
    glared = reference + np.where(circle, 2.5 + 1.0 * (cols - 100.0) / 35.0, 0.0).astype(np.float32)
    disc = (rows - 60) ** 2 + (cols - 115) ** 2 <= 4**2  # an 8 px impact, 4 mm at 0.5 mm pixels
    glared[disc] -= np.float32(8.0)
    noisy = glared + rng.normal(0.0, 1.0, glared.shape).astype(np.float32)
    held = _unmoved()  # the frame's fit: its bright plate and dark parts agree on gain 1 and no offset
    pair = compare(
        _image(reference, 1.0), _image(noisy, 1.0), SETTINGS.p_preliminary, SETTINGS, registration=held
    )
    flaw = pair.flaws[0]
    look = Look(flaw, (0.0, 0.0, 0.0), flaw.area_px * 2.5e-7, flaw.score)
    assert look.area_m2 > SETTINGS.component_area_m2 and pair.detection.mask[60, 115]  # one blob with it
    confirm = thresholds(SETTINGS).confirm
    assert glare_explained(pair, view, look, confirm, SETTINGS)  # type: ignore[arg-type]
    glare = glare_light(pair, view, look)  # type: ignore[arg-type]
    assert glare is not None
    light, lit = glare
    assert lit[circle].mean() > 0.99 and not lit[~circle].any()  # fitted on the part, nothing beyond it
    relit = _image(noisy - light.astype(np.float32), 1.0)
    again = compare(_image(reference, 1.0), relit, SETTINGS.p_preliminary, SETTINGS, registration=held)
    strong = [f for f in again.flaws if f.score > confirm]
    assert len(strong) == 1 and abs(strong[0].row - 60) <= 2 and abs(strong[0].col - 115) <= 2
    assert strong[0].area_px * 2.5e-7 <= SETTINGS.component_area_m2 and strong[0].polarity == "dark"
    no_model = SimpleNamespace(capture=SimpleNamespace(cad=SimpleNamespace(parts=None)))
    assert glare_light(pair, no_model, look) is None  # type: ignore[arg-type]


def test_a_bright_flaw_that_saturated_its_core_is_no_shifted_edge() -> None:
    """A bright crater can saturate the inspection where the reference read well under the clip (truss-b
    held-out seed 2192 in space: a 1.9 mm crater on the panel, its core at 251 DN over a prediction of
    170, a sliver of its rim +35 to +70 DN and 8 sigma beside it). The core is left out of the test; a
    shift of the prediction must draw on the prediction there, not on the clip."""
    from rsi.mission.evidence import shift_explained

    rng = np.random.default_rng(12)
    reference = 170.0 + 2.0 * (_textured(12) - 80.0)
    inspection = reference + rng.normal(0.0, 3.0, reference.shape).astype(np.float32)
    core = np.zeros(reference.shape, bool)
    core[60:64, 80:84] = True
    inspection[60:64, 84] += np.float32(20.0)  # the rim's sliver beside the clipped core
    inspection[core] = np.float32(251.0)  # the clip less the ambient: no reading
    seen = dataclasses.replace(_image(inspection, 9.0), valid=~core)
    pair = compare(_image(reference, 9.0), seen, SETTINGS.p_preliminary, SETTINGS)
    rim = next(f for f in pair.flaws if abs(f.row - 62) <= 2 and abs(f.col - 84) <= 1)
    assert rim.polarity == "bright" and rim.score > thresholds(SETTINGS).confirm
    assert not pair.detection.valid[core].any()
    look = Look(rim, (0.0, 0.0, 0.0), rim.area_px * 2.5e-7, rim.score)
    assert not shift_explained(pair, look, thresholds(SETTINGS).preliminary, max_shift_px=0.9)


def _grainy(seed: int, shift_xy: tuple[float, float] = (0.0, 0.0)) -> tuple[np.ndarray, np.ndarray]:
    """A reference and an inspection of one fine grain (45 DN, 1.2 px; a brushed plate, the cells' grid),
    each with 2 DN of noise, the inspection's grain moved by `shift_xy` pixels."""
    import cv2

    rng = np.random.default_rng(seed)
    grain = cv2.GaussianBlur(rng.standard_normal((120, 160)).astype(np.float32), (0, 0), 1.2)
    surface = (120.0 + 45.0 * grain / grain.std()).astype(np.float32)
    move = np.float32([[1.0, 0.0, shift_xy[0]], [0.0, 1.0, shift_xy[1]]])
    moved = cv2.warpAffine(surface, move, (160, 120), flags=cv2.INTER_CUBIC, borderMode=cv2.BORDER_REFLECT)
    noise = rng.normal(0.0, 2.0, (2, *surface.shape)).astype(np.float32)
    return surface + noise[0], moved + noise[1]


def _unmoved_pair(reference: np.ndarray, inspection: np.ndarray) -> Any:
    """The preliminary comparison of two grainy images under a registration that found no motion."""
    return compare(
        _image(reference, 8.0),
        _image(inspection, 8.0),
        SETTINGS.p_preliminary,
        SETTINGS,
        registration=_unmoved(),
    )


def _flaw_looks(pair: Any, near: tuple[int, int] | None = None) -> list[Look]:
    inner = [f for f in pair.flaws if 10 < f.row < 110 and 10 < f.col < 150]
    if near is not None:
        inner = [f for f in inner if abs(f.row - near[0]) <= 2 and abs(f.col - near[1]) <= 2]
    return [Look(f, (0.0, 0.0, 0.0), f.area_px * 2.5e-7, f.score) for f in inner]


def test_a_shift_that_moves_grain_onto_a_faint_spot_does_not_explain_it() -> None:
    """Seed §2.3: a mis-registration is the neighbourhood's. Of 49 shifts some move a fine grain onto a
    faint spot and cancel it, and fit the spot's surroundings worse: no explanation on one surface (the
    check before took 5 of these 26 spots for shifted grain, as it still does beside a step of depth;
    truss development seed 2201 in space lost a 1.1 mm crater on the solar cells so). Grain moved by
    1-1.8 px is explained wherever it flags."""
    from rsi.mission.evidence import shift_explained

    preliminary = thresholds(SETTINGS).preliminary
    spots = []
    for seed, depth in ((seed, depth) for seed in range(8) for depth in (5.0, 7.0, 9.0)):
        reference, inspection = _grainy(seed)
        inspection[59:62, 80:83] -= np.float32(depth)
        pair = _unmoved_pair(reference, inspection)
        spots += [(pair, look) for look in _flaw_looks(pair, near=(60, 81))]
    assert len(spots) >= 20
    assert sum(shift_explained(pair, look, preliminary, 1.5) for pair, look in spots) <= 1
    # beside a step of depth the ring is another surface's and any shift counts: some spots go again
    beside = sum(shift_explained(pair, look, preliminary, 1.5, one_surface=False) for pair, look in spots)
    assert beside >= 3
    shifted = []
    for seed, shift in enumerate((1.0, 1.4, 1.8)):
        reference, inspection = _grainy(seed, (0.6 * shift, 0.8 * shift))
        pair = _unmoved_pair(reference, inspection)
        shifted += [(pair, look) for look in _flaw_looks(pair)]
    assert len(shifted) >= 20
    assert all(shift_explained(pair, look, preliminary, 1.5) for pair, look in shifted)


def _clipped_scene() -> tuple[Compensated, Compensated, np.ndarray, np.ndarray]:
    """A reference with a glint it saturated (rows 20-29, columns 20-29) and an inspection that saturated
    over a 6 px bright disc and over the glint moved a pixel right; returns both, the disc and the glint's
    new column."""
    rng = np.random.default_rng(13)
    reference = 150.0 + 2.0 * (_textured(13) - 80.0)
    inspection = reference + rng.normal(0.0, 3.0, reference.shape).astype(np.float32)
    disc = np.zeros(reference.shape, bool)
    disc[60:66, 80:86] = True
    glint = np.zeros(reference.shape, bool)
    glint[20:30, 20:30] = True
    moved = np.roll(glint, 1, axis=1)
    clipped = disc | moved
    inspection[clipped] = np.float32(250.0)  # the sensor's top less the ambient read beside it
    seen = dataclasses.replace(_image(inspection, 9.0), valid=~clipped, lower_bound=clipped)
    return dataclasses.replace(_image(reference, 9.0), valid=~glint), seen, disc, moved & ~glint


def test_a_bright_impact_that_saturated_the_camera_is_compared_as_a_lower_bound() -> None:
    """Seed §2.1, §4: a bright impact can saturate the inspection wholly where the reference read far
    under the clip (truss-b held-out seed 2202 in space: a 2.3 mm disc, all 32 pixels at 250 DN over a
    prediction of 150). What the strobe returned there at least is a difference of one sign: the disc is a
    bright flaw; the glint the reference clipped, moved a pixel, says nothing and stays out."""
    reference, seen, disc, moved_edge = _clipped_scene()
    pair = compare(reference, seen, SETTINGS.p_preliminary, SETTINGS, registration=_unmoved())
    assert pair.detection.valid[disc].all() and not pair.detection.valid[moved_edge].any()
    found = [f for f in pair.flaws if disc[round(f.row), round(f.col)]]
    assert len(found) == 1 and found[0].polarity == "bright" and found[0].score > thresholds(SETTINGS).confirm
    blind = compare(
        reference,
        dataclasses.replace(seen, lower_bound=None),
        SETTINGS.p_preliminary,
        SETTINGS,
        registration=_unmoved(),
    )
    assert not blind.detection.valid[disc].any()
    assert not [f for f in blind.flaws if disc[round(f.row), round(f.col)]]


def test_a_saturated_pixel_no_brighter_than_its_prediction_is_left_out() -> None:
    """A lower bound under the prediction bounds nothing: it must not read as a dark change."""
    reference, seen, disc, _ = _clipped_scene()
    brighter = dataclasses.replace(reference, image=np.where(disc, 252.0, reference.image).astype(np.float32))
    pair = compare(brighter, seen, SETTINGS.p_preliminary, SETTINGS, registration=_unmoved())
    assert not pair.detection.valid[disc].any()
    assert not [f for f in pair.flaws if disc[round(f.row), round(f.col)]]


@pytest.fixture(scope="module")
def tank_view() -> Any:
    from rsi.sim.world import load

    world: Any = load("truss", seed=0)
    try:
        view = _sensed_at(world, "B_tank", (480, 640))
        site = next(s for s in world.mockup.candidates.component_sites if s.name == "B_tank")
    finally:
        world.close()
    return view, site


def _sensed_at(world: Any, vista: str, size: tuple[int, int]) -> Any:
    from rsi.mission.views import sense
    from rsi.sim.capture import capture

    return sense(capture(world, world.render(vista, size=size, state="reference", stereo=True)))


def _ranged(model: np.ndarray, mask: np.ndarray, seed: int) -> np.ndarray:
    """A range map of the model's surface over `mask`: 0.5 mm of matching noise a pixel, holes elsewhere."""
    noise = np.random.default_rng(seed).normal(0.0, 5e-4, model.shape)
    return np.where(mask, model + noise, np.nan).astype(np.float32)


def _tank_depth(tank_view: Any) -> tuple[Any, Any, np.ndarray, np.ndarray, tuple[int, int], np.ndarray]:
    """The tank view, its site, the tank's CAD pixels and depth, their median pixel, and each pixel's
    squared distance from it (pixels)."""
    view, site = tank_view
    mask = view.capture.cad.components["B_tank"]
    model = view.capture.cad.expected_depth_m.astype(np.float64)
    rows, cols = np.nonzero(mask)
    centre = (int(np.median(rows)), int(np.median(cols)))
    grid_r, grid_c = np.mgrid[0 : mask.shape[0], 0 : mask.shape[1]]
    return view, site, mask, model, centre, (grid_r - centre[0]) ** 2 + (grid_c - centre[1]) ** 2


@pytest.mark.parametrize("case", ["pristine", "dented", "reference off on a strip", "model off on a strip"])
def test_a_dent_sinks_against_the_reference_and_the_model_at_one_place(tank_view: Any, case: str) -> None:
    from rsi.mission.evidence import sinking
    from rsi.mission.views import field_to_world

    view, site, mask, model, centre, radius2 = _tank_depth(tank_view)
    now, before, believed = _ranged(model, mask, 1), _ranged(model, mask, 2), model.copy()
    left = int(np.flatnonzero(mask.any(axis=0))[0])
    strip = mask & (np.abs(np.arange(mask.shape[1]) - left - 20) < 12)[None, :]
    if case == "dented":
        crater = 4e-3 * np.exp(-radius2 / (2 * 20.0**2))
        now = (now + crater).astype(np.float32)
    elif case == "reference off on a strip":  # a prediction that failed there: 12 mm nearer
        before[strip] -= np.float32(0.012)
    elif case == "model off on a strip":  # a model the believed pose placed badly there
        believed[strip] -= 0.012
    cad = dataclasses.replace(view.capture.cad, expected_depth_m=believed.astype(np.float32))
    seen = dataclasses.replace(view, range_m=now, capture=dataclasses.replace(view.capture, cad=cad))
    sunk = sinking(seen, before, (0.0, 0.0), site)
    if case != "dented":
        assert sunk.sunk_m < SETTINGS.dent_relief_min_m
        return
    assert 0.6 * 4e-3 < sunk.sunk_m < 4e-3  # the 2 cm patch's mean less the others' spread
    assert sunk.position_m is not None
    at = field_to_world(seen, *map(float, centre))
    assert at is not None and math.dist(sunk.position_m, at) < 0.02


@pytest.mark.parametrize("rim_px", [30, 45, 60])
def test_a_dents_crater_reaches_no_farther_than_its_rims_bound(tank_view: Any, rim_px: int) -> None:
    # rsi.sim.dent's crater of a blunt blow, 5 mm * (1 - (rho / R)^2)^2: the bound holds the rim whatever
    # its size, and stays near it (a cone's twice the half-depth radius, the 2 cm patches' blur)
    from rsi.mission.evidence import sinking
    from rsi.mission.views import pixel_size_m

    view, site, mask, model, _, radius2 = _tank_depth(tank_view)
    now = _ranged(model + 5e-3 * np.clip(1.0 - radius2 / rim_px**2, 0.0, None) ** 2, mask, 1)
    seen = dataclasses.replace(view, range_m=now)
    sunk = sinking(seen, _ranged(model, mask, 2), (0.0, 0.0), site)
    assert sunk.position_m is not None
    rim_m = rim_px * pixel_size_m(seen, sunk.position_m)
    assert rim_m <= sunk.rim_m <= 1.5 * rim_m  # measured 1.12-1.27 times


def test_a_screws_relief_is_known_as_well_as_the_range_maps_own_scatter_allows(tank_view: Any) -> None:
    from rsi.mission.screws import screw_relief_sigma_m

    view, _ = tank_view
    screw = _screw_in_view(view)
    model = view.capture.cad.expected_depth_m.astype(np.float64)
    rows, cols = np.indices(model.shape)
    plane = 0.4 + 2e-4 * rows + 1e-4 * cols  # a plate seen obliquely: centimetres across the frame
    noise = np.random.default_rng(3).normal(0.0, 1.0, model.shape)
    quiet = screw_relief_sigma_m(plane.astype(np.float32), view, screw)
    one = screw_relief_sigma_m((plane + 1e-3 * noise).astype(np.float32), view, screw)
    two = screw_relief_sigma_m((plane + 2e-3 * noise).astype(np.float32), view, screw)
    assert quiet < 1e-6  # the plane is taken out: only the scatter about it counts
    assert two == pytest.approx(2.0 * one, rel=0.1)
    # 1 mm a pixel over the head's and the ring's pixels, 25 to a matching block, through a median
    assert 2e-4 < one < 2e-3
    holes = np.full(model.shape, np.nan, np.float32)
    assert math.isnan(screw_relief_sigma_m(holes, view, screw))


def _screw_in_view(view: Any) -> Any:
    from rsi.sim.world import load

    world: Any = load("truss", seed=0)
    try:
        from rsi.mission.views import visible

        screws = world.mockup.candidates.screw_sites
        seen = visible(view, np.asarray([s.position_m for s in screws]))
        return next(site for site, in_view in zip(screws, seen, strict=True) if in_view)
    finally:
        world.close()


def _sunlit(level: np.ndarray, variance_scale: float = 1.0) -> Any:
    from rsi.imaging.bracket import AmbientImage

    return AmbientImage(
        image=level.astype(np.float32),
        variance=np.maximum(level, 1.0).astype(np.float32) * np.float32(variance_scale),
        valid=np.ones(level.shape, bool),
        exposure_s=1e-3,
        exposures_s=(1e-4, 1e-3),
    )


def _sunlit_face(shape: tuple[int, int], seed: int = 0) -> np.ndarray:
    import cv2

    rng = np.random.default_rng(seed)
    texture = cv2.GaussianBlur(rng.normal(0.0, 1.0, shape).astype(np.float32), (0, 0), 6.0)
    return np.maximum(1000.0 + 6000.0 * texture, 50.0)


def test_a_spot_the_sun_lights_in_both_passes_echoes_in_the_ambient_and_noise_does_not() -> None:
    from rsi.mission.echoes import ambient_echo

    shape, at = (160, 200), (80, 100)
    rng = np.random.default_rng(1)
    surface = _sunlit_face(shape)
    # the sun moved between the passes: the same surface reads 0.7 of the reference's light (a gain)
    before = surface + rng.normal(0.0, 1.0, shape) * np.sqrt(surface)
    after = 0.7 * surface + rng.normal(0.0, 1.0, shape) * np.sqrt(0.7 * surface)
    spot = after.copy()
    spot[at[0] - 1 : at[0] + 2, at[1] - 1 : at[1] + 2] *= 0.7  # a darkening of 30 %: reflectance lost
    look = _look((0.0, 0.0, 1.0), 4e-6, (at[0] - 1, at[1] - 1, at[0] + 2, at[1] + 2), contrast=0.3)
    seen = ambient_echo(_sunlit(before), _sunlit(spot), look, SETTINGS)
    unseen = ambient_echo(_sunlit(before), _sunlit(after), look, SETTINGS)
    limits = thresholds(SETTINGS)
    assert seen is not None and unseen is not None
    assert seen.score < -limits.confirm  # darker: negative, past the confirming threshold
    assert abs(unseen.score) < limits.preliminary
    # the contrast of the look, at that light and noise: what a change of reflectance must show
    assert seen.reach > limits.confirm


def test_a_place_the_sun_does_not_light_or_the_ambient_does_not_read_has_no_echo() -> None:
    from rsi.mission.echoes import ambient_echo

    shape, at = (160, 200), (80, 100)
    lit = _sunlit(_sunlit_face(shape))
    look = _look((0.0, 0.0, 1.0), 4e-6, (at[0] - 1, at[1] - 1, at[0] + 2, at[1] + 2), contrast=0.3)
    shadow = _sunlit(np.zeros(shape))
    assert ambient_echo(lit, shadow, look, SETTINGS) is None  # in shadow in the inspection pass
    assert ambient_echo(shadow, lit, look, SETTINGS) is None  # in shadow in the reference pass
    clipped = dataclasses.replace(lit, valid=np.ones(shape, bool))
    clipped.valid[at] = False  # every reading of that pixel clipped
    assert ambient_echo(lit, clipped, look, SETTINGS) is None
