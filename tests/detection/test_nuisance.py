"""Seed §2.3-2.4 extra-variance models (rsi.detection.nuisance), on synthetic inputs with known answers."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from rsi.detection.nuisance import (
    half_pixel_shifted,
    nuisance_scale,
    pair_excess,
    parallax_scale,
    shadow_edge_variance,
    shared_interpolation,
)
from rsi.errors import InputError
from rsi.imaging.compensation import Compensated

SHAPE = (40, 60)


def _image(values: np.ndarray, variance: float = 2.0) -> Compensated:
    return Compensated(
        image=values.astype(np.float32),
        valid=np.ones(values.shape, bool),
        variance=np.full(values.shape, variance, np.float32),
        interpolation_variance=np.zeros(values.shape, np.float32),
        row_step=1,
    )


def _ramp(slope: float) -> np.ndarray:
    return np.tile(np.arange(SHAPE[1], dtype=np.float32) * slope, (SHAPE[0], 1))


def test_half_pixel_shift_moves_a_ramp_by_half_its_slope() -> None:
    shifted = half_pixel_shifted(_image(_ramp(4.0)))
    inner = (slice(2, -2), slice(2, -2))
    np.testing.assert_allclose(shifted.image[inner], _ramp(4.0)[inner] - 2.0, atol=1e-3)
    assert shifted.valid[inner].all()


def test_half_pixel_shift_spreads_an_invalid_pixel_to_its_neighbours() -> None:
    image = _image(_ramp(1.0))
    valid = image.valid.copy()
    valid[20, 30] = False
    shifted = half_pixel_shifted(dataclasses.replace(image, valid=valid))
    # the image moves +0.5 px: output (r, c) reads (r - 0.5, c - 0.5), so four outputs touch the hole
    assert np.argwhere(~shifted.valid).tolist() == [[20, 30], [20, 31], [21, 30], [21, 31]]


def test_parallax_scale_is_one_on_the_registered_plane_and_grows_off_it() -> None:
    ramp = _image(_ramp(3.0))
    np.testing.assert_allclose(parallax_scale(ramp, np.full(SHAPE, 0.5, np.float32), 2.0), 1.0)
    stepped = np.full(SHAPE, 0.5, np.float32)
    stepped[:, 40:] = 0.4  # a part 10 cm proud of the plate: 2 px * (0.5 / 0.4 - 1) = 0.5 px of parallax
    scale = parallax_scale(ramp, stepped, 2.0)
    # first order: 1 + (0.5 px * 3 DN/px)^2 / 2 DN^2
    assert scale[20, 55] == pytest.approx(1.0 + (0.5 * 3.0) ** 2 / 2.0, rel=1e-3)
    assert scale[20, 5] == pytest.approx(1.0)
    np.testing.assert_allclose(parallax_scale(ramp, stepped, 0.0), 1.0)  # no viewpoint error, no parallax


def test_parallax_scale_refuses_a_range_map_of_another_view() -> None:
    with pytest.raises(InputError, match="depth_m"):
        parallax_scale(_image(_ramp(1.0)), np.ones((10, 10)), 1.0)
    with pytest.raises(InputError, match="shift_px"):
        parallax_scale(_image(_ramp(1.0)), np.ones(SHAPE), -1.0)


def test_shadow_edges_add_variance_along_the_edge_only() -> None:
    raw = np.full(SHAPE, 8, np.uint8)
    raw[:, 30:] = 120  # a vertical sun-shadow edge in the ambient (every row, lit or not)
    image = _image(np.full(SHAPE, 50.0))
    edged = shadow_edge_variance(image, raw, lit_field="odd", edge_dn_px=10.0, jag_px=0.5)
    extra = edged.interpolation_variance
    assert extra[:, :25].max() == 0.0 and extra[:, 35:].max() == 0.0
    # Sobel/8 across a 112 DN step peaks at 56 DN/px beside it: (0.5 px * 56)^2
    assert extra[:, 29:31].max() == pytest.approx((0.5 * 112 / 2) ** 2, rel=1e-3)
    np.testing.assert_allclose(edged.variance - image.variance, extra)
    checker = (8 + (np.indices(SHAPE).sum(axis=0) % 2) * 6).astype(np.uint8)
    # a checkerboard texture of 6 DN (gradient below the 10 DN/px edge) is no shadow edge
    quiet = shadow_edge_variance(image, checker, lit_field="even", edge_dn_px=10.0, jag_px=0.5)
    assert quiet.interpolation_variance.max() == 0.0


@pytest.mark.parametrize(
    ("keywords", "message"),
    [
        ({"lit_field": "both", "edge_dn_px": 10.0, "jag_px": 0.5}, "lit_field"),
        ({"lit_field": "odd", "edge_dn_px": 0.0, "jag_px": 0.5}, "edge_dn_px"),
        ({"lit_field": "odd", "edge_dn_px": 10.0, "jag_px": -1.0}, "jag_px"),
    ],
)
def test_shadow_edge_settings_are_checked_by_name(keywords: dict[str, object], message: str) -> None:
    with pytest.raises(InputError, match=message):
        shadow_edge_variance(_image(np.ones(SHAPE)), np.ones(SHAPE), **keywords)  # type: ignore[arg-type]


def test_shared_interpolation_gives_both_images_the_references_dilated_map() -> None:
    reference = _image(np.ones(SHAPE), variance=3.0)
    spike = np.zeros(SHAPE, np.float32)
    spike[10, 10] = 4.0
    reference = dataclasses.replace(
        reference, variance=reference.variance + spike, interpolation_variance=spike
    )
    inspection = dataclasses.replace(
        _image(np.ones(SHAPE), variance=5.0), interpolation_variance=np.full(SHAPE, 1.0, np.float32)
    )
    ref, insp = shared_interpolation(reference, inspection, spread_px=2)
    expected = np.zeros(SHAPE, np.float32)
    expected[8:13, 8:13] = 4.0  # a 5x5 dilation of the spike
    np.testing.assert_array_equal(ref.interpolation_variance, expected)
    np.testing.assert_array_equal(insp.interpolation_variance, expected)
    np.testing.assert_allclose(ref.variance, 3.0 + expected)  # sensor part kept
    np.testing.assert_allclose(insp.variance, 4.0 + expected)  # its own interpolation part replaced
    with pytest.raises(InputError, match="spread_px"):
        shared_interpolation(reference, inspection, spread_px=-1)


def _visits(noisy_patch_sigma: float) -> tuple[Compensated, Compensated]:
    """Two flaw-free visits of a texture, unit noise as declared, and `noisy_patch_sigma` in one patch."""
    import cv2

    rng = np.random.default_rng(3)
    texture = cv2.GaussianBlur(rng.standard_normal((96, 128)).astype(np.float32), (0, 0), 3.0)
    base = 100.0 + 30.0 * texture / texture.std()
    sigma = np.ones(base.shape)
    sigma[30:70, 40:90] = noisy_patch_sigma
    return tuple(  # type: ignore[return-value]
        _image(base + sigma * rng.standard_normal(base.shape), variance=1.0) for _ in range(2)
    )


def test_pair_excess_is_one_where_the_noise_model_holds() -> None:
    first, second = _visits(noisy_patch_sigma=1.0)
    scale = pair_excess(first, second, misregistration_std_px=0.0)
    assert scale.min() >= 1.0
    assert float(np.median(scale[10:-10, 10:-10])) < 1.6  # max over a 9x9 spread of 9x9 means of chi2(1)


def test_pair_excess_measures_noise_the_model_understates() -> None:
    # in the patch the visits' noise is 3x what the variance says: z^2 averages ~9 there (seed §2.4: the
    # extra noise raises the test's threshold exactly there), and the rest of the view stays near 1
    first, second = _visits(noisy_patch_sigma=3.0)
    scale = pair_excess(first, second, misregistration_std_px=0.0)
    assert 6.0 < float(np.median(scale[40:60, 55:75])) < 14.0
    assert float(np.median(scale[5:20, 5:30])) < 1.6
    both = nuisance_scale(first, second, misregistration_std_px=0.0)
    assert np.all(both >= scale)  # the larger of the pair's and the half-pixel phase's excess
