"""Ambient-light compensation (seed §2.2): cancellation truths, interpolation errors, noise, validity."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from rsi.errors import InputError
from rsi.imaging.camera import BadPixelMap, CameraModel, Frame, expose
from rsi.imaging.compensation import compensate_field_pair, compensate_interlaced, compensate_two_frames

STROBE_DN = 30.0
SUN_LUX = 130000.0


def _interlaced_dn(ambient_dn: np.ndarray, lit_field: str = "odd") -> np.ndarray:
    """A noise-free raw frame in DN: ambient everywhere plus a flat strobe on the lit field."""
    raw = 4.0 + ambient_dn.astype(np.float64)
    raw[1 if lit_field == "odd" else 0 :: 2] += STROBE_DN
    return raw


def _ambient_rows(profile: np.ndarray, cols: int = 8) -> np.ndarray:
    return np.repeat(profile[:, None], cols, axis=1).astype(np.float64)


@pytest.mark.parametrize("lit_field", ["odd", "even"])
def test_constant_ambient_cancels_exactly(lit_field: str) -> None:
    raw = _interlaced_dn(np.full((40, 8), 120.0), lit_field)
    result = compensate_interlaced(raw, lit_field=lit_field)
    np.testing.assert_array_equal(result.image, STROBE_DN)
    np.testing.assert_array_equal(result.interpolation_variance, 0.0)
    assert result.valid.all()


@pytest.mark.parametrize("lit_field", ["odd", "even"])
def test_linear_vertical_ambient_cancels_except_the_one_neighbour_edge_row(lit_field: str) -> None:
    slope_dn = 0.5
    raw = _interlaced_dn(_ambient_rows(10.0 + slope_dn * np.arange(200)), lit_field)
    result = compensate_interlaced(raw, lit_field=lit_field)
    # the row on the frame edge has one unlit neighbour, one row inwards: off by one row of slope
    edge = 0 if lit_field == "even" else -1
    interior = np.delete(result.image, edge, axis=0)
    np.testing.assert_array_equal(interior, STROBE_DN)
    np.testing.assert_allclose(result.image[edge], STROBE_DN + slope_dn * (-1 if edge == 0 else 1))
    np.testing.assert_array_equal(np.delete(result.interpolation_variance, edge, axis=0), 0.0)


def test_sharp_shadow_edge_gives_interpolation_variance_only_at_the_edge_rows() -> None:
    lit_row, step_dn = 51, 180.0  # rows >= 51 are in shadow; lit row 51 is field row 25
    profile = np.where(np.arange(100) < lit_row, 200.0, 20.0)
    raw = _interlaced_dn(_ambient_rows(profile), "odd")
    result = compensate_interlaced(raw, lit_field="odd")
    error = result.image - STROBE_DN
    flagged = np.flatnonzero(result.interpolation_variance[:, 0] > 0)
    np.testing.assert_array_equal(flagged, [24, 25, 26])
    # the row straddling the edge is off by half the step, and its variance says so (seed §2.2)
    assert abs(error[25, 0]) == pytest.approx(step_dn / 2)
    assert result.interpolation_variance[25, 0] == pytest.approx(error[25, 0] ** 2, rel=0.05)
    np.testing.assert_array_equal(np.delete(error, 25, axis=0), 0.0)


def test_penumbra_wider_than_two_pixels_interpolates_well() -> None:
    """Seed §2.2: a transition over more than a couple of pixels is estimated accurately."""
    rows = np.arange(100)
    sharp = np.where(rows < 51, 200.0, 20.0)
    soft = np.interp(rows, [47, 55], [200.0, 20.0])
    errors = [
        np.abs(
            compensate_interlaced(_interlaced_dn(_ambient_rows(p)), lit_field="odd").image - STROBE_DN
        ).max()
        for p in (sharp, soft)
    ]
    assert errors[1] < 0.15 * errors[0]


def test_compensated_image_matches_the_strobe_only_image_within_its_noise() -> None:
    rng = np.random.default_rng(7)
    shape = (480, 640)
    ambient = SUN_LUX * (0.3 + 0.2 * np.linspace(0, 1, shape[0]))[:, None] * np.ones(shape)
    strobe = 13.0 * rng.uniform(0.2, 0.6, size=shape)
    frame = expose(ambient, strobe, lit_field="odd", rng=rng)
    result = compensate_interlaced(frame)
    camera = frame.camera
    truth = strobe[1::2] * camera.electrons_per_lux_s / camera.gain_e_per_dn
    z = (result.image - truth) / np.sqrt(result.variance)
    assert result.valid.all()
    assert abs(z.mean()) < 0.02
    assert z.std() == pytest.approx(1.0, abs=0.1)


@pytest.mark.parametrize(("method", "power_ratio"), [("interlaced", 1.5), ("two_frames", 2.0)])
def test_noise_power_grows_as_predicted_and_the_variance_map_matches(method: str, power_ratio: float) -> None:
    """Seed §2.2: subtraction nearly doubles the noise power (two frames: x2; mean of two rows: x1.5)."""
    ambient, strobe = np.full((480, 640), 0.4 * SUN_LUX), np.zeros((480, 640))
    if method == "interlaced":
        frame = expose(ambient, strobe, lit_field="odd", rng=11)
        single = frame.raw
        result = compensate_interlaced(frame)
    else:
        lit = expose(ambient, strobe, lit_field="both", rng=11)
        single = lit.raw
        result = compensate_two_frames(lit, expose(ambient, strobe, lit_field="none", rng=12))
    measured = float(result.image.astype(np.float64).var())
    assert measured / float(single.astype(np.float64).var()) == pytest.approx(power_ratio, rel=0.1)
    assert measured == pytest.approx(float(result.variance.mean()), rel=0.1)


def test_two_frame_compensation_recovers_the_strobe_at_full_resolution() -> None:
    ambient, strobe = np.full((200, 300), 0.4 * SUN_LUX), np.full((200, 300), 5.0)
    lit = expose(ambient, strobe, lit_field="both", rng=1)
    result = compensate_two_frames(lit, expose(ambient, strobe, lit_field="none", rng=2))
    camera = lit.camera
    assert result.image.shape == (200, 300)
    assert result.row_step == 1
    assert result.image.mean() == pytest.approx(
        5.0 * camera.electrons_per_lux_s / camera.gain_e_per_dn, abs=0.02
    )
    np.testing.assert_array_equal(result.interpolation_variance, 0.0)


@pytest.mark.parametrize(("rows", "lit_field"), [(40, "odd"), (40, "even"), (41, "odd"), (41, "even")])
def test_outputs_are_float32_at_field_resolution(rows: int, lit_field: str) -> None:
    raw = np.full((rows, 9), 50, dtype=np.uint8)
    result = compensate_interlaced(raw, lit_field=lit_field)
    assert result.row_step == 2
    for array in (result.image, result.variance, result.interpolation_variance):
        assert array.shape == (rows // 2, 9)
        assert array.dtype == np.float32
    assert result.valid.dtype == np.bool_


def test_saturated_lit_and_neighbour_pixels_are_flagged_invalid() -> None:
    raw = _interlaced_dn(np.full((40, 8), 100.0))
    raw[10, 3] = 255.0  # unlit row 10 feeds lit rows 9 and 11 (field rows 4 and 5)
    raw[21, 5] = 255.0  # lit row 21 is field row 10
    result = compensate_interlaced(raw, lit_field="odd")
    invalid = np.argwhere(~result.valid).tolist()
    assert invalid == [[4, 3], [5, 3], [10, 5]]
    lowered = compensate_interlaced(raw, lit_field="odd", saturation_dn=130.0)
    assert not lowered.valid.any()  # every lit row reads 134 DN


def test_frame_saturation_mask_and_bad_pixels_are_honoured() -> None:
    raw = np.full((20, 6), 90, dtype=np.uint8)
    saturated = np.zeros_like(raw, dtype=bool)
    saturated[3, 2] = True
    dead = np.zeros_like(saturated)
    dead[8, 4] = True
    defects = BadPixelMap(hot=np.zeros_like(dead), dead=dead, stuck=np.zeros_like(dead))
    frame = Frame(raw=raw, saturated=saturated, lit_field="odd", exposure_s=1e-4, bad_pixels=defects)
    result = compensate_interlaced(frame)
    assert np.argwhere(~result.valid).tolist() == [[1, 2], [3, 4], [4, 4]]
    clean = compensate_interlaced(frame, bad_pixels=BadPixelMap.random((20, 6), fraction=0.0, rng=0))
    assert np.argwhere(~clean.valid).tolist() == [[1, 2]]


def test_a_saturated_lit_pixel_over_a_read_ambient_is_a_lower_bound() -> None:
    raw = _interlaced_dn(np.full((40, 8), 100.0))
    raw[21, 5] = 255.0  # lit row 21 (field row 10) clipped; its ambient rows 20 and 22 read 104
    raw[10, 3] = 255.0  # unlit row 10: lit rows 9 and 11 lose their ambient
    raw[13, 3] = 255.0  # lit row 13 clipped, its unlit neighbour 12 read
    raw[14, 3] = 255.0  # ... and its unlit neighbour 14 clipped too: nothing to subtract
    defects = np.zeros((40, 8), bool)
    defects[31, 6] = True  # a hot lit pixel reading the top is a defect, no bound
    raw[31, 6] = 255.0
    bad = BadPixelMap(hot=defects, dead=np.zeros_like(defects), stuck=np.zeros_like(defects))
    result = compensate_interlaced(raw, lit_field="odd", bad_pixels=bad)
    assert result.lower_bound is not None
    assert np.argwhere(result.lower_bound).tolist() == [[10, 5]]
    assert result.image[10, 5] == pytest.approx(255.0 - 104.0)
    assert not (result.lower_bound & result.valid).any()


def test_two_frame_lower_bound_needs_the_ambient_frame_read() -> None:
    lit, ambient = np.full((10, 10), 150.0), np.full((10, 10), 60.0)
    lit[2, 2] = lit[7, 1] = 255.0
    ambient[7, 1] = 255.0
    result = compensate_two_frames(lit, ambient)
    assert result.lower_bound is not None
    assert np.argwhere(result.lower_bound).tolist() == [[2, 2]]
    assert result.image[2, 2] == pytest.approx(195.0)


def test_field_pair_lower_bound_is_the_top_less_the_ambient_where_the_strobe_clipped() -> None:
    strobe = np.full((20, 8), 2.0, np.float32)
    strobe[7, 4] = strobe[8, 2] = 400.0  # a bright spot on an odd and on an even row, past the top
    odd, even = _pair(strobe, np.full((20, 8), 8000.0, np.float32))
    woven = compensate_field_pair(odd, even)
    assert woven.lower_bound is not None
    assert np.argwhere(woven.lower_bound).tolist() == [[7, 4], [8, 2]]
    assert not woven.valid[7, 4] and not woven.valid[8, 2]
    top = odd.camera.max_dn
    # the row's ambient was read in the other frame: the bound is the top less about that reading
    assert woven.image[7, 4] == pytest.approx(top - float(even.raw[7, 4]), abs=3.0)
    assert woven.image[8, 2] == pytest.approx(top - float(odd.raw[8, 2]), abs=3.0)


def test_two_frame_validity_uses_both_inputs() -> None:
    lit, ambient = np.full((10, 10), 150.0), np.full((10, 10), 60.0)
    lit[2, 2] = 255.0
    ambient[7, 1] = 255.0
    stuck = np.zeros((10, 10), dtype=bool)
    stuck[5, 5] = True
    defects = BadPixelMap(hot=np.zeros_like(stuck), dead=np.zeros_like(stuck), stuck=stuck)
    result = compensate_two_frames(lit, ambient, bad_pixels=defects)
    assert np.argwhere(~result.valid).tolist() == [[2, 2], [5, 5], [7, 1]]


def test_camera_model_sets_the_noise_level() -> None:
    raw = _interlaced_dn(np.full((20, 4), 100.0))
    quiet = CameraModel(read_noise_e=0.0, full_well_e=1e6)
    noisy = CameraModel(read_noise_e=200.0, full_well_e=1e6)
    quiet_var = compensate_interlaced(raw, lit_field="odd", camera=quiet).variance
    noisy_var = compensate_interlaced(raw, lit_field="odd", camera=noisy).variance
    assert (noisy_var > quiet_var).all()


@pytest.mark.parametrize(
    ("frame", "kwargs", "name"),
    [
        (np.zeros((20, 4)), {}, "lit_field"),
        (np.zeros((20, 4)), {"lit_field": "both"}, "lit_field"),
        ([[0.0] * 4] * 20, {"lit_field": "odd"}, "frame"),
        (np.zeros((5, 4)), {"lit_field": "odd"}, "frame"),
        (np.zeros((20, 4)), {"lit_field": "odd", "saturation_dn": float("nan")}, "saturation_dn"),
        (np.zeros((20, 4)), {"lit_field": "odd", "camera": "sony"}, "camera"),
        (
            np.zeros((20, 4)),
            {"lit_field": "odd", "bad_pixels": BadPixelMap.random((2, 2), rng=0)},
            "bad_pixels",
        ),
    ],
)
def test_interlaced_rejects_bad_input_naming_the_argument(
    frame: object, kwargs: dict[str, object], name: str
) -> None:
    with pytest.raises(InputError, match=name):
        compensate_interlaced(frame, **kwargs)  # type: ignore[arg-type]


def test_interlaced_rejects_whole_frame_flashes() -> None:
    flash = expose(np.zeros((8, 4)), np.zeros((8, 4)), lit_field="both", rng=0)
    with pytest.raises(InputError, match=r"lit_field='both'.*compensate_two_frames"):
        compensate_interlaced(flash)


@pytest.mark.parametrize(
    ("lit_field", "ambient_field", "name"),
    [("odd", "none", "lit"), ("both", "both", "ambient")],
)
def test_two_frames_rejects_frames_lit_the_wrong_way(lit_field: str, ambient_field: str, name: str) -> None:
    zeros = np.zeros((8, 4))
    lit = expose(zeros, zeros, lit_field=lit_field, rng=0)
    ambient = expose(zeros, zeros, lit_field=ambient_field, rng=1)
    with pytest.raises(InputError, match=f"{name} must be a frame with lit_field"):
        compensate_two_frames(lit, ambient)


def test_two_frames_rejects_mismatched_shapes() -> None:
    with pytest.raises(InputError, match="lit and ambient must have the same shape"):
        compensate_two_frames(np.zeros((8, 4)), np.zeros((8, 5)))


@pytest.mark.parametrize(("lit_field", "edge"), [("even", 0), ("odd", -1)])
def test_variance_map_counts_every_subtracted_term(lit_field: str, edge: int) -> None:
    camera = CameraModel()
    raw = _interlaced_dn(np.full((20, 3), 100.0), lit_field)
    result = compensate_interlaced(raw, lit_field=lit_field, camera=camera)
    lit_var, unlit_var = camera.noise_variance_dn(np.array([134.0, 104.0]))
    # mean of two unlit rows: a quarter of each; on the frame edge the one neighbour counts whole
    expected = np.full((10, 3), lit_var + 0.5 * unlit_var, dtype=np.float32)
    expected[edge] = lit_var + unlit_var
    np.testing.assert_allclose(result.variance, expected, rtol=1e-6)
    two = compensate_two_frames(raw, raw, camera=camera)
    np.testing.assert_allclose(two.variance, 2 * camera.noise_variance_dn(raw), rtol=1e-6)


def _pair(strobe: np.ndarray, ambient: np.ndarray, seed: int = 0) -> tuple[Frame, Frame]:
    rng = np.random.default_rng(seed)
    odd = expose(ambient, strobe, exposure_s=1e-3, lit_field="odd", rng=rng)
    even = expose(ambient, strobe, exposure_s=1e-3, lit_field="even", rng=rng)
    return odd, even


def test_field_pair_gives_every_row_its_own_strobe_image() -> None:
    rows, cols = 40, 24
    # a one-row dark line on an even row: intra-frame compensation of the odd field cannot see it
    strobe = np.full((rows, cols), 0.2, np.float32)
    strobe[10] = 0.05
    ambient = np.full((rows, cols), 800.0, np.float32)
    odd, even = _pair(strobe, ambient)
    woven = compensate_field_pair(odd, even)
    assert woven.image.shape == (rows, cols) and woven.row_step == 1 and woven.valid.all()
    line, rest = woven.image[10].mean(), np.delete(woven.image, 10, axis=0).mean()
    assert line < 0.5 * rest  # the strobe-only contrast of the line, 0.05 vs 0.2
    assert compensate_interlaced(odd).image.mean(axis=1).min() > 0.8 * rest


def _shadow_edge_pair(edge_row: int, rows: int = 40, cols: int = 400) -> tuple[Frame, Frame]:
    """Sunlit above `edge_row`, black shadow from it on: a sharp edge along the rows (seed §2.2)."""
    ambient = np.zeros((rows, cols), np.float32)
    ambient[:edge_row] = 8000.0
    return _pair(np.full((rows, cols), 2.0, np.float32), ambient, seed=edge_row)


@pytest.mark.parametrize("edge_row", [20, 21])
def test_field_pair_is_exact_at_a_shadow_edge_along_the_rows(edge_row: int) -> None:
    odd, even = _shadow_edge_pair(edge_row)
    woven = compensate_field_pair(odd, even)
    strobe_dn = np.median(woven.image)
    # the flat strobe everywhere: every row's mean within 1 DN of it (noise / sqrt(400) is ~0.1 DN)
    assert np.abs(woven.image.mean(axis=1) - strobe_dn).max() < 1.0
    # intra-frame interpolation misses by half the edge's ~100 DN contrast on the row beside it
    field = compensate_interlaced(odd if edge_row % 2 else even).image
    assert np.abs(field.mean(axis=1) - strobe_dn).max() > 20.0


@pytest.mark.parametrize("edge_row", [20, 21])
def test_field_pair_variance_predicts_the_error_at_and_away_from_the_edge(edge_row: int) -> None:
    odd, even = _shadow_edge_pair(edge_row, rows=40, cols=4000)
    woven = compensate_field_pair(odd, even)
    error = woven.image - np.median(woven.image[edge_row + 4 :])
    for row in (2, edge_row - 1, edge_row, 30):
        measured, predicted = float(np.mean(error[row] ** 2)), float(np.mean(woven.variance[row]))
        assert 0.8 < measured / predicted < 1.25, (row, measured, predicted)


def test_field_pair_averages_both_ambient_estimates_where_the_ambient_is_smooth() -> None:
    camera = CameraModel()
    odd, even = _pair(np.full((20, 3), 2.0, np.float32), np.full((20, 3), 8000.0, np.float32))
    woven = compensate_field_pair(odd, even)
    lit_var, unlit_var = (
        float(np.median(camera.noise_variance_dn(frame.raw[rows])))
        for frame, rows in ((odd, slice(1, None, 2)), (odd, slice(0, None, 2)))
    )
    # weights 2/3 (mean of two rows, variance u/2) and 1/3 (one row, u): u (4/9 / 2 + 1/9) = u / 3
    np.testing.assert_allclose(np.median(woven.variance[4:16]), lit_var + unlit_var / 3, rtol=0.05)


def test_field_pair_falls_back_on_one_estimate_where_the_other_is_unusable() -> None:
    odd, even = _pair(np.full((20, 8), 2.0, np.float32), np.full((20, 8), 8000.0, np.float32))
    top = np.uint16(odd.camera.max_dn)
    blind = replace(even, raw=even.raw.copy(), saturated=even.saturated.copy())
    blind.raw[11] = top  # row 11 is unlit in the even-lit frame: its ambient reading is lost
    blind.saturated[11] = True
    woven = compensate_field_pair(odd, blind)
    np.testing.assert_array_equal(woven.image[11], compensate_interlaced(odd).image[5])
    assert woven.valid[11].all()
    # a saturated unlit row of the odd-lit frame: its lit rows 9 and 11 take the even-lit frame's reading,
    # and the even-lit frame's row 10 its own interpolation
    deaf = replace(odd, raw=odd.raw.copy(), saturated=odd.saturated.copy())
    deaf.raw[10] = top
    deaf.saturated[10] = True
    woven = compensate_field_pair(deaf, even)
    expected = deaf.raw[9].astype(np.float32) - even.raw[9].astype(np.float32)
    np.testing.assert_allclose(woven.image[9], expected)
    np.testing.assert_array_equal(woven.image[10], compensate_interlaced(even).image[5])
    assert woven.valid[9:12].all()


def test_field_pair_rejects_wrong_fields_shapes_and_types() -> None:
    strobe = np.full((20, 8), 0.2, np.float32)
    ambient = np.zeros((20, 8), np.float32)
    odd, even = _pair(strobe, ambient)
    with pytest.raises(InputError, match="odd_lit must have its strobe in the odd field"):
        compensate_field_pair(even, even)
    with pytest.raises(InputError, match="even_lit must have its strobe in the even field"):
        compensate_field_pair(odd, odd)
    with pytest.raises(InputError, match=r"odd_lit must be an rsi\.imaging\.camera\.Frame"):
        compensate_field_pair(odd.raw, even)  # type: ignore[arg-type]
    small_even = _pair(np.full((18, 8), 0.2, np.float32), np.zeros((18, 8), np.float32))[1]
    with pytest.raises(InputError, match="same shape"):
        compensate_field_pair(odd, small_even)


def test_field_pair_keeps_a_sunlit_flaw_at_full_contrast_and_unhidden() -> None:
    # a 1-pixel spot a quarter as reflective under both the sun and the strobe, on a lit row of each frame
    strobe = np.full((40, 64), 2.0, np.float32)
    ambient = np.full((40, 64), 8000.0, np.float32)
    for row in (21, 22):
        strobe[row, 30], ambient[row, 30] = 0.5, 2000.0
    odd, even = _pair(strobe, ambient, seed=3)
    woven = compensate_field_pair(odd, even)
    level = float(np.median(woven.image))
    # the spot loses three quarters of the strobe's DN; the unlit rows' spot does not leak into its ambient
    np.testing.assert_allclose(woven.image[21:23, 30], 0.25 * level, atol=3.0)
    # and its own variance stays that of its neighbours (no interpolation error claimed over it)
    assert woven.variance[21:23, 30].max() < 1.5 * float(np.median(woven.variance))
