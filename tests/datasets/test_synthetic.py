"""Synthetic flaw patterns and pairs (seed §2.4 laboratory tests): truths, determinism, errors."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import ndimage

from rsi.datasets.synthetic import flaw_pattern, pure_noise_pairs, synthetic_pair, textured_surface
from rsi.errors import InputError
from rsi.imaging.registration import register


def test_surface_is_in_unit_range_and_deterministic() -> None:
    surface = textured_surface((128, 96), rng=1)
    assert surface.shape == (128, 96) and surface.dtype == np.float64
    assert surface.min() == 0.0 and surface.max() == 1.0
    np.testing.assert_array_equal(surface, textured_surface((128, 96), rng=1))
    assert np.std(np.diff(surface, axis=1)) > 0.005  # fine detail for registration


@pytest.mark.parametrize("profile", ["uniform", "peak"])
def test_flaw_pattern_is_a_non_touching_dot_grid(profile: str) -> None:
    pattern = flaw_pattern((160, 128), size_px=3, spacing_px=16, strength=0.2, profile=profile, rng=3)
    assert pattern.centres_rc.shape == (80, 2)
    _, count = ndimage.label(pattern.truth_mask, structure=np.ones((3, 3)))
    assert count == 80  # 8-connected components never merge
    assert np.count_nonzero(pattern.truth_mask) == 80 * 9
    centres = pattern.signal[pattern.centres_rc[:, 0], pattern.centres_rc[:, 1]]
    np.testing.assert_allclose(centres, -0.2)
    assert np.all(pattern.signal[~pattern.truth_mask] == 0.0)
    expected = -0.2 if profile == "uniform" else -0.1
    row, col = pattern.centres_rc[0]
    assert pattern.signal[row - 1, col] == pytest.approx(expected)


def test_pair_follows_the_shift_convention() -> None:
    pair = synthetic_pair((256, 256), shift_xy=(2.3, -1.6), noise_sigma=0.0, flaw_strength=0.0, rng=6)
    found = register(pair.reference, pair.inspection)
    assert found.translation_xy == pytest.approx((2.3, -1.6), abs=0.02)
    assert (found.gain, found.bias) == pytest.approx((pair.gain, pair.bias), abs=0.01)
    again = synthetic_pair((256, 256), shift_xy=(2.3, -1.6), noise_sigma=0.0, flaw_strength=0.0, rng=6)
    np.testing.assert_array_equal(pair.inspection, again.inspection)


def test_pair_noise_and_flaws() -> None:
    pair = synthetic_pair(
        (256, 256), shift_xy=(0.0, 0.0), gain=1.0, bias=0.0, noise_sigma=0.01, flaw_strength=0.3, rng=7
    )
    difference = pair.inspection - pair.reference
    assert np.std(difference[~pair.truth_mask]) == pytest.approx(0.01 * np.sqrt(2), rel=0.05)
    assert np.mean(difference[pair.truth_mask]) == pytest.approx(-0.3, abs=0.01)


@pytest.mark.parametrize(
    ("call", "argument"),
    [
        (lambda: textured_surface((1, 8)), "shape"),
        (lambda: textured_surface([8, 8]), "shape"),  # type: ignore[arg-type]
        (lambda: flaw_pattern((64, 64), size_px=2), "size_px"),
        (lambda: flaw_pattern((64, 64), size_px=5, spacing_px=7), "spacing_px"),
        (lambda: flaw_pattern((64, 64), strength=-0.1), "strength"),
        (lambda: flaw_pattern((64, 64), profile="ring"), "profile"),
        (lambda: flaw_pattern((64, 64), polarity="both"), "polarity"),
        (lambda: flaw_pattern((64, 64), rng="seed"), "rng"),  # type: ignore[arg-type]
        (lambda: synthetic_pair((64, 64), noise_sigma=-1.0), "noise_sigma"),
        (lambda: synthetic_pair((64, 64), shift_xy=(np.nan, 0.0)), "shift_xy"),
        (lambda: synthetic_pair((64, 64), gain=np.inf), "gain"),
        (lambda: synthetic_pair((64, 64), bias=None), "bias"),  # type: ignore[arg-type]
    ],
)
def test_bad_arguments_are_named(call: object, argument: str) -> None:
    with pytest.raises(InputError, match=argument):
        call()  # type: ignore[operator]


def test_pure_noise_pairs_have_the_asked_noise_and_no_flaw() -> None:
    pairs = pure_noise_pairs((256, 256), 3, read_sigma=0.02, rng=4)
    assert len(pairs) == 3
    for reference, inspection in pairs:
        assert reference.dtype == np.float32
        # seed §2.4: the difference of two independent noise fields has twice one field's variance
        assert np.std(inspection - reference) == pytest.approx(0.02 * np.sqrt(2.0), rel=0.02)
    again = pure_noise_pairs((256, 256), 3, read_sigma=0.02, rng=4)
    np.testing.assert_array_equal(pairs[2][1], again[2][1])


@pytest.mark.parametrize(
    ("kwargs", "argument"),
    [
        ({"count": 0}, "count"),
        ({"read_sigma": -0.1}, "read_sigma"),
        ({"shot_variance_per_unit": -1.0}, "shot_variance_per_unit"),
        ({"shape": (1, 5)}, "shape"),
    ],
)
def test_pure_noise_pairs_reject_bad_settings(kwargs: dict[str, object], argument: str) -> None:
    settings: dict[str, object] = {"shape": (8, 8), "count": 1, "read_sigma": 0.01}
    settings.update(kwargs)
    with pytest.raises(InputError, match=argument):
        pure_noise_pairs(**settings)  # type: ignore[arg-type]


def test_a_synthetic_image_is_bounded_in_pixels() -> None:
    from rsi.datasets.synthetic import MAX_SYNTHETIC_PIXELS, textured_surface

    with pytest.raises(InputError, match="over the"):
        textured_surface((MAX_SYNTHETIC_PIXELS // 2, 4))
