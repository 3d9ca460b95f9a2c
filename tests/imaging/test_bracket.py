"""The ambient-lit image merged from a bracket of shutters (rsi.imaging.bracket, seed §2 further work)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from rsi.errors import InputError
from rsi.imaging.bracket import MAX_BRACKET, merge_ambient
from rsi.imaging.camera import CameraModel, expose

CAMERA = CameraModel()
SHAPE = (200, 320)
SECONDS = 1e-5


def _scene() -> np.ndarray:
    """Ambient illuminance from a deep shadow (100 lux) to full sun and past it (3e6 lux), along the row."""
    return np.logspace(2, 6.5, SHAPE[1], dtype=np.float32)[None, :].repeat(SHAPE[0], 0)


def _truth_dn(lux: np.ndarray, seconds: float) -> np.ndarray:
    return lux * CAMERA.electrons_per_lux_s * seconds / CAMERA.gain_e_per_dn


def _bracket(lux: np.ndarray, factors: tuple[float, ...], seed: int = 0, **kwargs: object) -> list:
    rng = np.random.default_rng(seed)
    strobe = np.zeros_like(lux)
    return [
        expose(lux, strobe, exposure_s=SECONDS * k, camera=CAMERA, lit_field="none", rng=rng, **kwargs)
        for k in factors
    ]


def test_a_bracket_reads_shadow_and_sun_alike_within_its_stated_noise() -> None:
    lux = _scene()
    merged = merge_ambient(_bracket(lux, (1.0, 16.0, 256.0)))
    assert merged.exposure_s == pytest.approx(256 * SECONDS)
    z = (merged.image - _truth_dn(lux, merged.exposure_s)) / np.sqrt(merged.variance)
    # every column from shadow to sun: unbiased, its variance the camera model's (linear sensor, seed §2.1)
    for part in np.array_split(np.arange(SHAPE[1]), 4):
        usable = merged.valid[:, part]
        assert usable.mean() > 0.8
        column_z = z[:, part][usable]
        assert abs(float(column_z.mean())) < 0.05
        assert float(column_z.std()) == pytest.approx(1.0, abs=0.05)


def test_a_longer_shutter_lowers_the_noise_of_the_shadows_and_the_short_one_keeps_the_sun() -> None:
    lux = _scene()
    short = merge_ambient(_bracket(lux, (1.0,)))
    both = merge_ambient(_bracket(lux, (1.0, 16.0)))
    # in relative terms: shadows read with 16x the signal; the sun the long frame clips keeps the short one
    shadow, sun = slice(0, 40), slice(SHAPE[1] - 40, SHAPE[1])
    relative_short = np.sqrt(short.variance[:, shadow]) / _truth_dn(lux[:, shadow], short.exposure_s)
    relative_both = np.sqrt(both.variance[:, shadow]) / _truth_dn(lux[:, shadow], both.exposure_s)
    assert float(np.median(relative_both)) < 0.3 * float(np.median(relative_short))
    assert both.valid[:, sun].mean() == pytest.approx(short.valid[:, sun].mean())


def test_only_the_rows_the_strobe_did_not_light_enter_the_ambient() -> None:
    lux = _scene()[:, :160]
    rng = np.random.default_rng(1)
    flash = np.full(lux.shape, 30.0, np.float32)  # lux s: far over any ambient reading
    frames = [
        expose(lux, flash, exposure_s=SECONDS, camera=CAMERA, lit_field=field, rng=rng)
        for field in ("odd", "even")
    ]
    merged = merge_ambient(frames)
    z = (merged.image - _truth_dn(lux, SECONDS)) / np.sqrt(merged.variance)
    assert merged.valid.mean() > 0.9
    assert abs(float(z[merged.valid].mean())) < 0.1


def test_a_pixel_every_frame_clipped_is_not_valid() -> None:
    lux = np.full((8, 8), 1e9, np.float32)
    merged = merge_ambient(_bracket(lux, (1.0, 4.0)))
    assert not merged.valid.any()
    assert np.all(np.isinf(merged.variance))


def test_a_defective_pixel_is_never_read() -> None:
    from rsi.imaging.camera import BadPixelMap

    lux = np.full((16, 16), 1e4, np.float32)
    bad = BadPixelMap.random((16, 16), fraction=0.2, rng=3)
    merged = merge_ambient(_bracket(lux, (1.0,), bad_pixels=bad))
    assert not merged.valid[bad.defective].any()
    assert merged.valid[~bad.defective].all()


def test_bad_brackets_are_refused_by_name() -> None:
    frames = _bracket(np.full((8, 8), 1e4, np.float32), (1.0, 2.0))
    with pytest.raises(InputError, match="non-empty sequence"):
        merge_ambient([])
    with pytest.raises(InputError, match=f"over {MAX_BRACKET}"):
        merge_ambient(frames[:1] * (MAX_BRACKET + 1))
    with pytest.raises(InputError, match=r"frames\[1\] must be a Frame"):
        merge_ambient([frames[0], "frame"])  # type: ignore[list-item]
    other = _bracket(np.full((8, 9), 1e4, np.float32), (1.0,))[0]
    with pytest.raises(InputError, match="one camera's frames of one scene"):
        merge_ambient([frames[0], other])
    flash = dataclasses.replace(frames[0], lit_field="both")
    with pytest.raises(InputError, match="none holds the ambient alone"):
        merge_ambient([flash])
