"""The World: determinism, flaws where the truth says, mis-registration per visit, folders (bad input:
test_bad_input.py)."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
from scipy import ndimage

import rsi
from rsi.datasets.rendered import render_vista_to_folder
from rsi.errors import InputError
from rsi.imaging.compensation import compensate_interlaced
from rsi.sim.anomalies import AnomalySettings
from rsi.sim.world import REPEATABILITY_PX, World, load

SMALL = (120, 160)
SEED = 101  # the conftest world's seed and draw (the seed mock-up's): four impacts in the panel view
SETTINGS = AnomalySettings.seed_mockup()


def test_same_seed_same_world_and_frames_different_seed_different_anomalies(world: World) -> None:
    twin = load("truss", seed=SEED, settings=SETTINGS)
    try:
        assert twin.anomalies == world.anomalies
        first, second = twin.render("B_tank", size=SMALL), load_and_render()
        assert np.array_equal(first.frame.raw, second.frame.raw)
        assert first.pose_error_px == second.pose_error_px
    finally:
        twin.close()
    assert load("truss", seed=SEED + 1, settings=SETTINGS).anomalies != world.anomalies


def test_a_frame_without_truth_is_the_same_frame_and_visit(world: World) -> None:
    first, second = load("truss", seed=SEED, settings=SETTINGS), load("truss", seed=SEED, settings=SETTINGS)
    try:
        with_truth = first.render("D_tubing", size=SMALL)
        without = second.render("D_tubing", size=SMALL, truth=False)
    finally:
        first.close()
        second.close()
    assert np.array_equal(with_truth.frame.raw, without.frame.raw)
    assert with_truth.pose_error_px == without.pose_error_px
    assert with_truth.depth_m is not None and without.depth_m is None and without.flaw_masks == {}


def load_and_render() -> object:
    other = load("truss", seed=SEED, settings=SETTINGS)
    try:
        return other.render("B_tank", size=SMALL)
    finally:
        other.close()


def test_every_visible_flaw_is_dark_where_its_mask_says(world: World) -> None:
    view = world.render("C_panel", size=(480, 640))
    assert len(view.flaw_masks) >= 4  # this seed plants four impacts in the panel view
    compensated = compensate_interlaced(view.frame)
    field = compensated.image
    checked = 0
    for index, mask in view.flaw_masks.items():
        rows = mask[1::2][: field.shape[0]]  # the strobe-lit (odd) rows of the frame
        if rows.sum() < 2:
            continue  # below the field's resolution: a spot of < 2 field pixels hides in the noise
        anomaly = world.anomalies.anomalies[index]
        assert anomaly.kind in ("impact", "missing_screw", "swapped_component")
        # the surface around the flaw: a ring 3-8 px out (the panel's cells differ from place to place)
        grown = ndimage.binary_dilation(rows, iterations=8) & ~ndimage.binary_dilation(rows, iterations=3)
        surround = float(np.median(field[grown]))
        # a pixel the flaw covers loses its darkening (seed §4: tape on the surface); a millimetre spot of 2-3
        # field pixels covers none whole, and the 8-bit noise of the dark cells is ~1 DN: a quarter of it
        darkening = getattr(anomaly, "darkening", 0.4)
        assert float(field[rows].min()) < (1.0 - 0.25 * darkening) * surround, (index, anomaly, surround)
        checked += 1
    assert checked >= 3


def test_reference_and_inspection_visits_are_misregistered_by_the_drawn_error(world: World) -> None:
    first = world.render("D_tubing", size=(240, 320), state="reference")
    second = world.render("D_tubing", size=(240, 320), state="reference")
    low, high = REPEATABILITY_PX["lab"]
    for view in (first, second):
        assert low <= float(np.hypot(*view.pose_error_px)) <= high
    result = rsi.register(compensate_interlaced(first.frame).image, compensate_interlaced(second.frame).image)
    dx, dy_field = result.translation_xy
    expected = np.subtract(second.pose_error_px, first.pose_error_px)
    # field images have every other row: vertical shifts halve
    assert abs(dx - expected[0]) < 0.35
    assert abs(2 * dy_field - expected[1]) < 0.5


def test_a_visit_begun_by_name_draws_the_same_whatever_was_rendered_before() -> None:
    """`World.begin_visit`: one visit's viewpoint error and camera noise come from its own stream, so an
    extra frame before it (a second look) changes nothing of it; another name draws another visit."""
    runs = []
    for before in ((), ("A_kapton",), ("A_kapton", "B_tank")):
        twin = load("truss", seed=SEED, settings=SETTINGS)
        try:
            for name in before:
                twin.render(name, size=SMALL, state="reference", truth=False)
            twin.begin_visit("inspection/D_tubing/0")
            runs.append(twin.render("D_tubing", size=SMALL, state="inspection", truth=False))
            twin.begin_visit("inspection/D_tubing/1")
            runs.append(twin.render("D_tubing", size=SMALL, state="inspection", truth=False))
        finally:
            twin.close()
    first, again = runs[0], runs[1]
    for same, other in zip(runs[0::2], runs[1::2], strict=True):
        assert same.pose_error_px == first.pose_error_px
        assert np.array_equal(same.frame.raw, first.frame.raw)
        assert np.array_equal(same.believed_pose.position_m, first.believed_pose.position_m)
        assert other.pose_error_px == again.pose_error_px
    assert first.pose_error_px != again.pose_error_px
    assert not np.array_equal(first.frame.raw, again.frame.raw)


@pytest.mark.parametrize("key", ["", 3, None])
def test_a_visit_needs_a_name(world: World, key: object) -> None:
    with pytest.raises(InputError, match="key must be a non-empty string"):
        world.begin_visit(key)  # type: ignore[arg-type]


def test_stereo_depth_and_readouts(world: World) -> None:
    view = world.render("B_tank", size=SMALL, stereo=True)
    assert view.stereo is not None
    left, right = view.stereo
    assert not np.array_equal(left.raw, right.raw)
    centre = view.depth_m[SMALL[0] // 2, SMALL[1] // 2]
    assert abs(centre - 0.5) < 0.02  # the tank's front at the 0.5 m standoff
    assert abs(world.readouts()["standoff_m"] - 0.5) < 0.02


def test_door_opens_and_fields_delegate(world: World) -> None:
    world.set_door(1.5)
    assert world.readouts()["door_angle_rad"] == 1.5
    world.set_door(0.0)
    spots = world.anomalies.thermal_spots
    assert len(spots) == 2
    temperatures = world.temperature_k([spot.position_m for spot in spots])
    # 30 K at each spot's centre (seed §4 Peltier modules); the other spot's tail adds at most a few mK
    assert np.allclose(np.abs(temperatures - 293.15), 30.0, atol=0.01)
    leak = world.anomalies.gas_leaks[0]
    ahead = np.asarray(leak.position_m) + 0.05 * np.asarray(leak.normal)
    assert world.gas_concentration_ppm([ahead], leak.start_time_s + 60.0)[0] > 0


def test_render_vista_to_folder_writes_frames_depth_and_truth(world: World, tmp_path: Path) -> None:
    paths = render_vista_to_folder(world, "C_panel", tmp_path, size=SMALL)
    assert all(path.exists() for path in paths.values())
    truth = json.loads(paths["truth"].read_text())
    assert truth["seed"] == SEED and truth["anomalies"]["counts"]["impact"] == 5


def test_overview_picture_is_colour_and_marked(world: World) -> None:
    picture = world.overview_picture(size=SMALL)
    assert picture.shape == (*SMALL, 3) and picture.dtype == np.uint8
    assert picture[..., 0].max() == 255  # magenta/red markers


def test_next_frame_is_the_same_visit_with_the_strobe_in_the_other_field(world: World) -> None:
    view = world.render("B_tank", size=SMALL)
    again = world.next_frame(view, lit_field="even")
    assert again.lit_field == "even" and again.exposure_s == view.frame.exposure_s
    # same light and pose: the unlit rows of one are the lit-free rows of the other, up to camera noise
    first_unlit = view.frame.raw[0::2].astype(np.float64)
    second_unlit = again.raw[1::2].astype(np.float64)
    assert abs(first_unlit.mean() - second_unlit.mean()) < 2.0
    assert not np.array_equal(view.frame.raw, again.raw)
    with pytest.raises(InputError, match="view must be a View"):
        world.next_frame(view.frame)  # type: ignore[arg-type]
    with pytest.raises(InputError, match="lit_field"):
        world.next_frame(view, lit_field="both")


def test_truss_mask_marks_the_frame_and_never_a_component(world: World) -> None:
    view = world.render("B_tank", size=SMALL)
    assert view.truss_mask is not None and view.depth_m is not None
    # B_tank looks at its plate with the truss behind it: some struts show, the plate's centre is no strut
    assert 0 < view.truss_mask.mean() < 0.5
    rows, cols = SMALL
    assert not view.truss_mask[rows // 2 - 5 : rows // 2 + 5, cols // 2 - 5 : cols // 2 + 5].any()
    assert world.render("B_tank", size=SMALL, truth=False).truss_mask is None


def test_the_lamp_switched_off_leaves_only_the_isee_lights(world: World) -> None:
    lit = world.render("A_kapton", size=(60, 80), truth=False)
    world.switch_lamp(False)
    try:
        dark = world.render("A_kapton", size=(60, 80), truth=False)
        assert world.readouts()["lamp_intensity_lux"] == 0.0
    finally:
        world.switch_lamp(True)
    # seed §4.1: in the Earth's shadow no sun and no room light; the strobe and the shutter stay
    assert lit.ambient_lux.any() and not dark.ambient_lux.any() and not dark.basis["sun"].any()
    assert dark.frame.exposure_s == lit.frame.exposure_s and dark.strobe_lux_s.any()


def test_shutter_scales_the_ambient_and_keeps_the_flash(world: World) -> None:
    from rsi.sim.world import MIN_SHUTTER

    views = []
    for fraction in (1.0, MIN_SHUTTER):
        world.set_shutter(fraction)
        views.append(world.render("B_tank", size=SMALL))  # lit by the sun and by the strobe
    world.set_shutter(1.0)
    seeds, short = views
    assert math.isclose(MIN_SHUTTER, 0.2)  # the ~20 us flash against the seed's 1/10000 s
    assert short.frame.exposure_s == pytest.approx(MIN_SHUTTER * seeds.frame.exposure_s)
    # the ~20 us flash lies inside either shutter: the same strobe light per render unit
    flash = [float(view.strobe_lux_s.sum() / view.basis["strobe"].sum()) for view in views]
    assert flash[1] == pytest.approx(flash[0], rel=1e-6)
    black = seeds.frame.camera.black_level_dn
    ambient = [float(view.frame.raw[0::2].astype(float).mean()) - black for view in views]  # unlit rows
    assert ambient[1] / ambient[0] == pytest.approx(MIN_SHUTTER, rel=0.15)


def test_component_masks_are_the_swappable_components_without_their_decals(world: World) -> None:
    view = world.render("C_panel", size=(480, 640))  # millimetre spots cover pixel centres only at full size
    panel = view.component_masks["C_panel"]
    assert panel.mean() > 0.5 and set(view.component_masks) <= {"A_oru", "B_tank", "C_panel", "D_tank_0"}
    impacts = [mask for mask in view.flaw_masks.values() if mask.any()]
    assert impacts  # the conftest world's spots lie on the panel; their decals are not panel pixels
    assert all((mask & ~panel).any() for mask in impacts)
    assert not (panel & view.truss_mask).any()


def test_strobe_energy_scales_the_strobe_exposure_and_nothing_else(world: World) -> None:
    strobe, ambient = [], []
    for factor in (1.0, 2.5):
        world.set_strobe_energy(factor)
        view = world.render("B_tank", size=SMALL)  # lit by the sun and by the strobe
        strobe.append(float(view.strobe_lux_s.sum() / view.basis["strobe"].sum()))
        ambient.append(float(view.ambient_lux.sum() / view.basis["sun"].sum()))
    world.set_strobe_energy(1.0)
    assert strobe[1] / strobe[0] == pytest.approx(2.5, rel=1e-5)
    assert ambient[1] == pytest.approx(ambient[0], rel=1e-6)  # the sun's lux per render unit is the flash's


def test_an_ambient_frame_holds_the_sun_alone_scaled_by_its_shutter(world: World) -> None:
    view = world.render("B_tank", size=SMALL, truth=False)  # lit by the sun and by the strobe
    black = view.frame.camera.black_level_dn
    longer = world.ambient_frame(view, exposure_s=4.0 * view.frame.exposure_s)
    assert longer.lit_field == "none"
    # no flash in it: every row reads the ambient, four times the strobe frame's unlit rows (linear, §2.1)
    # where it does not clip
    read = ~longer.saturated[0::2] & ~longer.saturated[1::2]
    unlit = float(view.frame.raw[0::2][read].astype(float).mean()) - black  # the strobe lit the odd rows
    rows = [float(longer.raw[parity::2][read].astype(float).mean()) - black for parity in (0, 1)]
    assert rows[0] / unlit == pytest.approx(4.0, rel=0.1)
    assert rows[1] == pytest.approx(rows[0], rel=0.05)
    with pytest.raises(InputError, match="exposure_s must be in"):
        world.ambient_frame(view, exposure_s=0.0)
    with pytest.raises(InputError, match="view must be a View"):
        world.ambient_frame("view", exposure_s=1e-4)  # type: ignore[arg-type]


def test_the_other_strobe_lights_the_same_view_from_below_the_lens(world: World) -> None:
    from rsi.imaging.compensation import compensate_field_pair

    view = world.render("B_tank", size=SMALL, truth=False)
    upper = compensate_field_pair(view.frame, world.next_frame(view, lit_field="even"))
    frames = world.other_strobe_frames(view)
    assert [frame.lit_field for frame in frames] == ["odd", "even"]
    assert all(frame.exposure_s == view.frame.exposure_s for frame in frames)
    lower = compensate_field_pair(*frames)
    lit = upper.valid & lower.valid & (upper.image > 10.0)
    # the same flash 3 cm on the lens's other side (seed §3 B): as bright overall, brighter towards the
    # frame's bottom, which it is nearer, and dimmer towards its top
    assert float(lower.image[lit].sum() / upper.image[lit].sum()) == pytest.approx(1.0, abs=0.15)
    ratio = np.where(lit, lower.image / np.maximum(upper.image, 1.0), np.nan)
    rows = SMALL[0]
    assert np.nanmedian(ratio[rows * 3 // 4 :]) > np.nanmedian(ratio[: rows // 4])
    with pytest.raises(InputError, match="view must be a View"):
        world.other_strobe_frames("view")  # type: ignore[arg-type]
