"""Camera model (seed §2.1): exposure, noise, saturation, fields, defects, determinism, input checks."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from rsi.errors import InputError
from rsi.imaging.camera import BadPixelMap, CameraModel, Frame, expose

SUN_LUX = 130000.0  # seed §2.1: solar illumination at earth orbit
STROBE_LM_S = 1.3  # seed §2.1: laboratory strobe
SCENE_AREA_M2 = 0.1  # seed §2.1: typical inspection scene
SHAPE = (64, 48)


def _flat(value: float, shape: tuple[int, int] = SHAPE) -> np.ndarray:
    return np.full(shape, value)


def test_default_camera_derived_quantities() -> None:
    camera = CameraModel()
    assert camera.max_dn == 255
    assert camera.raw_dtype is np.uint8
    # a full well reads exactly max_dn
    assert camera.black_level_dn + camera.full_well_e / camera.gain_e_per_dn == pytest.approx(255.0)
    assert CameraModel(bits=12).max_dn == 4095
    assert CameraModel(bits=12).raw_dtype is np.uint16


@pytest.mark.parametrize(
    ("field", "value"),
    [
        ("electrons_per_lux_s", 0.0),
        ("electrons_per_lux_s", float("nan")),
        ("full_well_e", -5.0),
        ("read_noise_e", -1.0),
        ("bits", 0),
        ("bits", 17),
        ("bits", 8.0),
        ("black_level_dn", -1.0),
        ("black_level_dn", 255.0),
    ],
)
def test_camera_model_rejects_each_bad_field_by_name(field: str, value: object) -> None:
    with pytest.raises(InputError, match=field):
        CameraModel(**{field: value})  # type: ignore[arg-type]


def test_noise_variance_is_shot_plus_read_plus_quantisation() -> None:
    camera = CameraModel(read_noise_e=30.0)
    gain = camera.gain_e_per_dn
    floor = (30.0 / gain) ** 2 + 1.0 / 12.0
    readings = np.array([[camera.black_level_dn, camera.black_level_dn + 100.0], [0.0, 255.0]])
    variance = camera.noise_variance_dn(readings)
    assert variance.dtype == np.float32
    expected = [[floor, floor + 100.0 / gain], [floor, floor + (255.0 - camera.black_level_dn) / gain]]
    np.testing.assert_allclose(variance, expected, rtol=1e-5)


def test_simulated_noise_matches_the_noise_model() -> None:
    camera = CameraModel()
    frame = expose(_flat(60000.0, (256, 256)), _flat(0.0, (256, 256)), lit_field="none", rng=3)
    raw = frame.raw.astype(np.float64)
    predicted = float(camera.noise_variance_dn(np.array([raw.mean()]))[0])
    assert raw.var() == pytest.approx(predicted, rel=0.05)


def test_seed_exposure_strobe_comparable_to_sun_and_mid_grey_does_not_saturate() -> None:
    """Seed §2.1: at 1/10000 s the sun gives 13 lux s, like the 1.3 lm s strobe over 0.1 m^2."""
    reflectance = 0.5
    ambient_lux_s = SUN_LUX * 1e-4
    strobe_lux_s = STROBE_LM_S / SCENE_AREA_M2
    assert ambient_lux_s == pytest.approx(13.0)
    assert strobe_lux_s == pytest.approx(13.0)
    frame = expose(
        _flat(reflectance * SUN_LUX),
        _flat(reflectance * strobe_lux_s),
        exposure_s=1e-4,
        lit_field="odd",
        rng=0,
    )
    black = frame.camera.black_level_dn
    lit = frame.raw[1::2].mean() - black
    unlit = frame.raw[0::2].mean() - black
    assert not frame.saturated.any()
    assert 0.8 < (lit - unlit) / unlit < 1.25  # strobe comparable to ambient
    assert lit > 0.5 * (frame.camera.max_dn - black)  # sensibly exposed, not dim


def test_field_rate_exposure_without_shutter_saturates() -> None:
    """Seed §2.1: over a whole 1/60 s field the sun gives ~215 lm s on 0.1 m^2, far beyond the strobe."""
    field_lm_s = SUN_LUX * SCENE_AREA_M2 / 60.0
    assert field_lm_s == pytest.approx(215.0, rel=0.01)
    frame = expose(_flat(0.5 * SUN_LUX), _flat(0.0), exposure_s=1.0 / 60.0, lit_field="none", rng=0)
    assert frame.saturated.all()
    assert (frame.raw == 255).all()


@pytest.mark.parametrize(
    ("lit_field", "lit_rows"),
    [("odd", [1, 3]), ("even", [0, 2]), ("both", [0, 1, 2, 3]), ("none", [])],
)
def test_strobe_lights_only_the_named_field(lit_field: str, lit_rows: list[int]) -> None:
    frame = expose(_flat(20000.0, (4, 4000)), _flat(8.0, (4, 4000)), lit_field=lit_field, rng=1)
    means = frame.raw.astype(np.float64).mean(axis=1)
    dark = 4.0 + 20000.0 * 1e-4 * 1000.0 / frame.camera.gain_e_per_dn
    bright = dark + 8.0 * 1000.0 / frame.camera.gain_e_per_dn
    expected = [bright if row in lit_rows else dark for row in range(4)]
    np.testing.assert_allclose(means, expected, atol=0.1)
    assert frame.lit_field == lit_field


def test_identical_seeds_give_identical_frames() -> None:
    ambient, strobe = _flat(50000.0), _flat(5.0)
    first = expose(ambient, strobe, rng=42)
    again = expose(ambient, strobe, rng=np.random.default_rng(42))
    other = expose(ambient, strobe, rng=43)
    np.testing.assert_array_equal(first.raw, again.raw)
    assert not np.array_equal(first.raw, other.raw)


def test_saturation_is_flagged_and_clipped_at_max_dn() -> None:
    ambient = _flat(10000.0)
    ambient[10:20, 5:15] = 1e7
    frame = expose(ambient, _flat(0.0), rng=0)
    assert frame.raw.dtype == np.uint8
    assert frame.saturated[10:20, 5:15].all()
    assert (frame.raw[10:20, 5:15] == 255).all()
    assert not frame.saturated[:10].any()


def test_high_bit_depth_frames_are_uint16() -> None:
    camera = CameraModel(bits=12, black_level_dn=64.0)
    frame = expose(_flat(1e7), _flat(0.0), camera=camera, rng=0)
    assert frame.raw.dtype == np.uint16
    assert (frame.raw == 4095).all()


def test_bad_pixels_imprint_hot_dead_and_stuck() -> None:
    hot, dead, stuck = (np.zeros(SHAPE, dtype=bool) for _ in range(3))
    hot[2, 3], dead[5, 6], stuck[7, 8] = True, True, True
    bad = BadPixelMap(hot=hot, dead=dead, stuck=stuck, stuck_value_dn=77.0)
    frame = expose(_flat(30000.0), _flat(3.0), rng=0, bad_pixels=bad)
    typical = np.median(frame.raw)
    assert frame.raw[2, 3] > typical + 100  # a hot pixel reads high
    assert frame.raw[5, 6] == 0
    assert frame.raw[7, 8] == 77
    assert frame.bad_pixels is bad
    np.testing.assert_array_equal(bad.defective, hot | dead | stuck)


def test_random_bad_pixel_maps_are_disjoint_seeded_and_have_the_asked_fraction() -> None:
    first = BadPixelMap.random((400, 500), fraction=0.01, rng=5)
    again = BadPixelMap.random((400, 500), fraction=0.01, rng=5)
    np.testing.assert_array_equal(first.defective, again.defective)
    assert first.defective.mean() == pytest.approx(0.01, rel=0.1)
    for kind in (first.hot, first.dead, first.stuck):
        assert kind.mean() == pytest.approx(0.01 / 3, rel=0.2)
    assert first.defective.sum() == first.hot.sum() + first.dead.sum() + first.stuck.sum()


@pytest.mark.parametrize(
    ("arguments", "name"),
    [
        ({"hot": [[True]], "dead": np.zeros((2, 2), bool), "stuck": np.zeros((2, 2), bool)}, "hot"),
        (
            {"hot": np.zeros((2, 2), bool), "dead": np.zeros((3, 2), bool), "stuck": np.zeros((2, 2), bool)},
            "dead",
        ),
        (
            {"hot": np.zeros((2, 2), bool), "dead": np.zeros((2, 2), bool), "stuck": np.zeros((2, 2), "U1")},
            "stuck",
        ),
        (
            {
                "hot": np.zeros((2, 2), bool),
                "dead": np.zeros((2, 2), bool),
                "stuck": np.zeros((2, 2), bool),
                "stuck_value_dn": -3.0,
            },
            "stuck_value_dn",
        ),
    ],
)
def test_bad_pixel_map_rejects_bad_fields_by_name(arguments: dict[str, object], name: str) -> None:
    with pytest.raises(InputError, match=name):
        BadPixelMap(**arguments)  # type: ignore[arg-type]


@pytest.mark.parametrize(
    ("shape", "fraction", "name"),
    [((4, 4), 1.5, "fraction"), ((4,), 0.1, "shape"), ((4, 0), 0.1, r"shape\[1\]")],
)
def test_random_bad_pixel_map_rejects_bad_arguments(
    shape: tuple[int, int], fraction: float, name: str
) -> None:
    with pytest.raises(InputError, match=name):
        BadPixelMap.random(shape, fraction=fraction, rng=0)


def _expose_kwargs() -> dict[str, object]:
    return {"ambient_lux": _flat(1000.0), "strobe_lux_s": _flat(1.0)}


@pytest.mark.parametrize(
    ("change", "name"),
    [
        ({"ambient_lux": _flat(-1.0)}, "ambient_lux"),
        ({"strobe_lux_s": _flat(1.0, (3, 3))}, "strobe_lux_s"),
        ({"strobe_lux_s": [[1.0]]}, "strobe_lux_s"),
        ({"exposure_s": 0.0}, "exposure_s"),
        ({"lit_field": "diagonal"}, "lit_field"),
        ({"camera": "sony"}, "camera"),
        ({"bad_pixels": BadPixelMap.random((3, 3), rng=0)}, "bad_pixels"),
        ({"bad_pixels": np.zeros(SHAPE, bool)}, "bad_pixels"),
        ({"rng": "seed"}, "rng"),
    ],
)
def test_expose_rejects_bad_input_naming_the_argument(change: dict[str, object], name: str) -> None:
    arguments = _expose_kwargs() | change
    with pytest.raises(InputError, match=name):
        expose(**arguments)  # type: ignore[arg-type]


def _frame_kwargs() -> dict[str, object]:
    return {
        "raw": np.zeros(SHAPE, np.uint8),
        "saturated": np.zeros(SHAPE, bool),
        "lit_field": "odd",
        "exposure_s": 1e-4,
    }


@pytest.mark.parametrize(
    ("change", "name"),
    [
        ({"raw": np.zeros(SHAPE, np.uint16)}, "raw"),
        ({"raw": np.zeros(SHAPE[0], np.uint8)}, "raw"),
        ({"saturated": np.zeros((2, 2), bool)}, "saturated"),
        ({"lit_field": "top"}, "lit_field"),
        ({"exposure_s": -1.0}, "exposure_s"),
        ({"camera": None}, "camera"),
    ],
)
def test_frame_rejects_bad_fields_by_name(change: dict[str, object], name: str) -> None:
    with pytest.raises(InputError, match=name):
        Frame(**(_frame_kwargs() | change))  # type: ignore[arg-type]


def test_results_are_frozen() -> None:
    frame = expose(_flat(1000.0), _flat(1.0), rng=0)
    with pytest.raises(dataclasses.FrozenInstanceError):
        frame.lit_field = "even"  # type: ignore[misc]
    with pytest.raises(dataclasses.FrozenInstanceError):
        frame.camera.bits = 12  # type: ignore[misc]
