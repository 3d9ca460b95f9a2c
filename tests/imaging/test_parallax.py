"""Registration in depth (rsi.imaging.parallax): known rigid-scene motions recovered, occlusions marked."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from rsi.errors import InputError
from rsi.imaging.compensation import Compensated
from rsi.imaging.parallax import fit_parallax, predict_reference

SHAPE = (240, 320)
SHIFT = (6.0, -4.0)  # px at the median depth, 0.5 m
# px m: the camera moved ~4.7 mm across at f = 760 px (b = f T), and turned by (0.2, -0.2) px (a - b / Z0)
PARALLAX = (2.9, -1.9)


def _texture(seed: int = 0) -> np.ndarray:
    rng = np.random.default_rng(seed)
    noise = rng.normal(0.0, 1.0, (SHAPE[0] + 80, SHAPE[1] + 80)).astype(np.float32)
    return cv2.GaussianBlur(noise, (0, 0), 2.0) * 400 + 100


def _ranges() -> np.ndarray:
    """A plate at 0.5 m with a box 15 cm nearer in the middle (a tank before its base plate)."""
    depth = np.full(SHAPE, 0.5, np.float32)
    depth[80:160, 100:220] = 0.35
    return depth


def _scene(
    shift: tuple[float, float] = SHIFT,
    parallax: tuple[float, float] = PARALLAX,
    depth: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Reference and inspection of a rigid scene: inspection pixel x sees the reference at x - d(x)."""
    depth = _ranges() if depth is None else depth
    big = _texture()
    offset = 1.0 / depth - np.median(1.0 / depth)
    rows, cols = np.indices(SHAPE, dtype=np.float32)

    def seen(x: np.ndarray, y: np.ndarray) -> np.ndarray:
        return np.asarray(cv2.remap(big, x + 40, y + 40, cv2.INTER_LINEAR), np.float32)

    reference = seen(cols, rows)
    moved_x = cols - shift[0] - parallax[0] * offset
    moved_y = rows - shift[1] - parallax[1] * offset
    noise = np.random.default_rng(1).normal(0.0, 1.0, SHAPE).astype(np.float32)
    return reference, seen(moved_x.astype(np.float32), moved_y.astype(np.float32)) + noise, depth


def _compensated(image: np.ndarray) -> Compensated:
    ones = np.ones(image.shape, np.float32)
    return Compensated(image, np.ones(image.shape, bool), ones, np.zeros_like(ones), 1)


def test_the_shift_and_the_parallax_of_a_two_depth_scene_are_recovered() -> None:
    reference, inspection, depth = _scene()
    fit = fit_parallax(reference, inspection, depth, start_xy=(5.0, -3.0))
    assert fit.converged
    np.testing.assert_allclose(fit.shift_xy, SHIFT, atol=0.02)
    np.testing.assert_allclose(fit.parallax_px_m, PARALLAX, atol=0.02)
    # the reference predicted from the inspection viewpoint differs from it by the camera noise alone
    predicted = predict_reference(_compensated(reference), fit, depth)
    residual = (inspection - predicted.reference.image)[predicted.reference.valid]
    assert residual.std() == pytest.approx(1.0, abs=0.05)
    # one translation cannot: the box stays off by its parallax
    one_shift = np.roll(np.roll(reference, 6, axis=1), -4, axis=0)
    assert (inspection - one_shift)[100:140, 120:200].std() > 20.0


def test_a_flaw_does_not_pull_the_fit() -> None:
    reference, inspection, depth = _scene()
    inspection[30:45, 30:45] -= 300.0  # a dark spot on the plate, 15 px across
    fit = fit_parallax(reference, inspection, depth, start_xy=(5.0, -3.0))
    np.testing.assert_allclose(fit.shift_xy, SHIFT, atol=0.05)
    np.testing.assert_allclose(fit.parallax_px_m, PARALLAX, atol=0.05)


def test_at_one_depth_the_shift_is_read_as_the_camera_moved_across() -> None:
    flat = np.full(SHAPE, 0.5, np.float32)
    reference, inspection, depth = _scene(parallax=(0.0, 0.0), depth=flat)
    fit = fit_parallax(reference, inspection, depth, start_xy=(5.0, -3.0))
    np.testing.assert_allclose(fit.shift_xy, SHIFT, atol=0.02)
    # no depth spread tells a turn from a move: the prior that an arm turns little reads it as b = a Z0
    np.testing.assert_allclose(fit.parallax_px_m, np.multiply(SHIFT, 0.5), atol=0.05)
    # ... and knows b no better than the prior on the turn (0.05 px, times Z0 = 0.5 m) allows
    assert np.sqrt(fit.covariance[2, 2]) == pytest.approx(0.05 * 0.5, rel=0.2)


def test_the_uncertainty_grows_with_the_range_noise_and_off_the_median_depth() -> None:
    reference, inspection, depth = _scene()
    fit = fit_parallax(reference, inspection, depth, start_xy=(5.0, -3.0))
    quiet = fit.std_px(depth, 0.0)
    noisy = fit.std_px(depth, 0.01)
    assert (noisy > quiet).all()
    # |b| sigma_Z / Z^2 at the box: sqrt(13) * 0.01 / 0.35^2
    expected = np.hypot(*PARALLAX) * 0.01 / 0.35**2
    assert float(noisy[120, 160]) == pytest.approx(np.hypot(float(quiet[120, 160]), expected), rel=0.05)
    # the fit itself is surest at its median depth
    assert float(quiet[10, 10]) < float(quiet[120, 160])


def test_pixels_the_two_viewpoints_see_past_different_edges_leave_the_comparison() -> None:
    reference, inspection, depth = _scene()
    fit = fit_parallax(reference, inspection, depth, start_xy=(5.0, -3.0))
    # the reference's own range map: the box where the reference saw it (x_ref = x - d(x))
    reference_depth = np.full(SHAPE, 0.5, np.float32)
    reference_depth[80 + 4 - 2 : 160 + 4 - 2, 100 - 6 - 3 : 220 - 6 - 3] = 0.35
    predicted = predict_reference(_compensated(reference), fit, depth, reference_range_m=reference_depth)
    occluded = predicted.occluded
    assert occluded.any() and not predicted.reference.valid[occluded].any()
    assert occluded[80:160, 100:220].mean() < 0.2  # only a band along the box's outline
    assert not occluded[:60].any() and not occluded[180:].any()


def test_where_the_stereo_left_the_edge_unranged_the_reference_s_surface_marks_the_occlusion() -> None:
    reference, inspection, depth = _scene()
    fit = fit_parallax(reference, inspection, depth, start_xy=(5.0, -3.0))
    surface = np.full(SHAPE, 0.5, np.float32)
    surface[80 + 4 - 2 : 160 + 4 - 2, 100 - 6 - 3 : 220 - 6 - 3] = 0.35
    # a stereo pair leaves the left frame's first f B / Z columns unmatched: the box's left edge among them
    ranged = surface.copy()
    ranged[:, :140] = np.nan
    compensated = _compensated(reference)
    by_range = predict_reference(compensated, fit, depth, reference_range_m=ranged)
    assert not by_range.occluded[:, :130].any()
    by_surface = predict_reference(
        compensated, fit, depth, reference_range_m=ranged, reference_surface_m=surface
    )
    assert by_surface.occluded[80:160, 90:110].any()  # the left edge's band
    assert not by_surface.reference.valid[by_surface.occluded].any()
    # the same occlusions as a range without holes, and the result still carries the range it was given
    whole = predict_reference(compensated, fit, depth, reference_range_m=surface)
    np.testing.assert_array_equal(by_surface.occluded, whole.occluded)
    assert np.isnan(by_surface.range_m[:, :120]).all()
    with pytest.raises(InputError, match="reference_surface_m must have the reference's shape"):
        predict_reference(compensated, fit, depth, reference_surface_m=surface[:10])


def test_a_false_match_of_the_reference_range_away_from_every_edge_is_no_occlusion() -> None:
    reference, inspection, depth = _scene()
    fit = fit_parallax(reference, inspection, depth, start_xy=(5.0, -3.0))
    reference_depth = np.full(SHAPE, 0.5, np.float32)
    reference_depth[80 + 4 - 2 : 160 + 4 - 2, 100 - 6 - 3 : 220 - 6 - 3] = 0.35
    # the matcher's false match on a glinting screw head in the plate, 40 cm off, far from the box
    reference_depth[20:30, 30:40] = 0.9
    predicted = predict_reference(_compensated(reference), fit, depth, reference_range_m=reference_depth)
    assert not predicted.occluded[10:40, 20:50].any()
    assert predicted.reference.valid[25:30, 35:40].all()
    assert predicted.occluded[75:165, 90:230].any()  # the box's outline still is one


@pytest.mark.parametrize(
    ("call", "message"),
    [
        (lambda r, d: fit_parallax(r, r[:, :-1], d), "one shape"),
        (lambda r, d: fit_parallax(r, r, np.full(SHAPE, np.nan)), "at least 200 pixels"),
        (lambda r, d: fit_parallax(r, r, d, valid=np.zeros(SHAPE, bool)), "at least 200 pixels"),
        # no texture: no gradient to fit a motion by (truss-b seed 1963 in space, a second reference with
        # its jaws left out, crashed the mission with numpy's LinAlgError before)
        (lambda r, d: fit_parallax(np.full(SHAPE, 80.0), np.full(SHAPE, 80.0), d), "cannot determine"),
        # every usable pixel carried out of the reference's frame by the starting shift
        (lambda r, d: fit_parallax(r, r, d, start_xy=(1e4, 0.0)), "cannot determine"),
    ],
)
def test_bad_input_is_refused_by_name(call: object, message: str) -> None:
    reference, _, depth = _scene()
    with pytest.raises(InputError, match=message):
        call(reference, depth)  # type: ignore[operator]


def test_predict_refuses_a_range_map_of_another_shape() -> None:
    reference, inspection, depth = _scene()
    fit = fit_parallax(reference, inspection, depth, start_xy=(5.0, -3.0))
    with pytest.raises(InputError, match="range_m must have the reference's shape"):
        predict_reference(_compensated(reference), fit, depth[:, :-1])


def test_about_its_shift_a_flat_scene_is_the_reference_itself_and_a_deep_one_predicts_after_the_shift() -> (
    None
):
    from rsi.imaging.registration import Registration

    flat = np.full(SHAPE, 0.5, np.float32)
    reference, inspection, _ = _scene(parallax=(3.0, -2.0), depth=flat)  # b = a Z0: a camera moved across
    fit = fit_parallax(reference, inspection, flat, start_xy=(5.0, -3.0))
    same = predict_reference(_compensated(reference), fit, flat, about_shift=True)
    # nothing to take out at one depth: no resampling, so none the detector would not model
    np.testing.assert_allclose(same.reference.image[2:-2, 2:-2], reference[2:-2, 2:-2], atol=0.05)

    reference, inspection, depth = _scene()
    fit = fit_parallax(reference, inspection, depth, start_xy=(5.0, -3.0))
    about = predict_reference(_compensated(reference), fit, depth, about_shift=True)
    matrix = np.eye(3)
    matrix[0, 2], matrix[1, 2] = fit.shift_xy
    shift = Registration("translation", matrix, 1.0, 0.0, True, "converged", 0, 0.0, (0.0, 0.0), 0.0)
    predicted, inside = shift.warp(about.reference.image)
    valid = inside & (shift.warp(about.reference.valid.astype(np.float32), photometric=False)[0] > 0.999)
    residual = (inspection - predicted)[valid]
    assert residual.std() == pytest.approx(1.0, abs=0.1)  # the camera noise, and the box predicted too
