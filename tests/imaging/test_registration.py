"""Tests of rsi.imaging.registration (seed §2.3): known answers, invariants, robustness, bad input."""

from __future__ import annotations

import dataclasses
import threading
from concurrent.futures import ThreadPoolExecutor

import numpy as np
import pytest
import scipy.ndimage as ndi
from numpy.typing import NDArray

from rsi.errors import InputError
from rsi.imaging import _gauss_newton, _pyramid, _warps
from rsi.imaging._warps import map_points, sample
from rsi.imaging.registration import MODELS, PreparedReference, Registration, prepare_reference, register

SIDE_PX = 256
SUBPIXEL_PX = 0.02  # stated accuracy on clean synthetic pairs, seed §2.3 residual mis-registration
PAD_PX = 64


def texture(side_px: int = SIDE_PX, seed: int = 1, sigma_px: float = 3.0) -> NDArray[np.float32]:
    """Band-limited random texture in [0, 1]."""
    noise = np.random.default_rng(seed).random((side_px, side_px))
    smooth = ndi.gaussian_filter(noise, sigma_px)
    return ((smooth - smooth.min()) / (smooth.max() - smooth.min())).astype(np.float32)


def warped(reference: NDArray[np.float32], matrix: NDArray[np.float64]) -> NDArray[np.float32]:
    """Inspection whose pixel ``matrix @ x`` shows reference pixel ``x`` (cubic spline, reflect padding)."""
    rows, cols = np.mgrid[0 : reference.shape[0], 0 : reference.shape[1]]
    target = np.column_stack([cols.ravel(), rows.ravel()]).astype(np.float64)
    source = map_points(np.linalg.inv(matrix), target) + PAD_PX
    padded = np.pad(reference.astype(np.float64), PAD_PX, mode="reflect")
    values = ndi.map_coordinates(padded, [source[:, 1], source[:, 0]], order=3)
    return values.reshape(reference.shape).astype(np.float32)


def shifted(reference: NDArray[np.float32], shift_xy: tuple[float, float]) -> NDArray[np.float32]:
    """``scipy.ndimage.shift(reference, (dy, dx))`` on a reflect-padded copy, cropped: no border junk."""
    padded = np.pad(reference.astype(np.float64), PAD_PX, mode="reflect")
    moved = ndi.shift(padded, (shift_xy[1], shift_xy[0]), order=3)
    return moved[PAD_PX:-PAD_PX, PAD_PX:-PAD_PX].astype(np.float32)


def about_centre(angle_rad: float, scale: float, shift_xy: tuple[float, float]) -> NDArray[np.float64]:
    centre = (SIDE_PX - 1) / 2.0
    cos, sin = scale * np.cos(angle_rad), scale * np.sin(angle_rad)
    to_centre = np.array([[1.0, 0.0, -centre], [0.0, 1.0, -centre], [0.0, 0.0, 1.0]])
    back = np.array([[1.0, 0.0, centre + shift_xy[0]], [0.0, 1.0, centre + shift_xy[1]], [0.0, 0.0, 1.0]])
    return back @ np.array([[cos, -sin, 0.0], [sin, cos, 0.0], [0.0, 0.0, 1.0]]) @ to_centre


TRUTHS = {
    "translation": np.array([[1.0, 0.0, 3.3], [0.0, 1.0, -2.6], [0.0, 0.0, 1.0]]),
    "euclidean": about_centre(0.03, 1.0, (2.2, -1.4)),
    "similarity": about_centre(0.02, 1.03, (-1.7, 2.4)),
    "affine": np.array([[1.02, 0.015, 2.1], [-0.01, 0.985, -1.3], [0.0, 0.0, 1.0]]),
    "homography": np.array([[1.01, 0.01, 1.5], [-0.008, 0.995, -2.1], [4e-5, -3e-5, 1.0]]),
}
PROBES_XY = np.array([[24.0, 24.0], [231.0, 24.0], [231.0, 231.0], [24.0, 231.0], [127.5, 127.5]])


def corner_error_px(matrix: NDArray[np.float64], truth: NDArray[np.float64]) -> float:
    return float(np.abs(map_points(matrix, PROBES_XY) - map_points(truth, PROBES_XY)).max())


def test_models_listed_in_the_contract() -> None:
    assert MODELS == ("translation", "euclidean", "similarity", "affine", "homography")


@pytest.mark.parametrize("model", MODELS)
def test_recovers_known_warp_of_every_model(model: str) -> None:
    reference = texture()
    inspection = 1.2 * warped(reference, TRUTHS[model]) + 0.05
    result = register(reference, inspection, model=model)
    assert result.converged and result.reason == "converged"
    assert corner_error_px(result.matrix, TRUTHS[model]) < SUBPIXEL_PX


@pytest.mark.parametrize("shift_xy", [(3.7, -2.2), (-0.4, 0.9), (12.5, 7.25)])
def test_sign_convention_follows_scipy_shift(shift_xy: tuple[float, float]) -> None:
    reference = texture()
    result = register(reference, shifted(reference, shift_xy))
    np.testing.assert_allclose(result.translation_xy, shift_xy, atol=SUBPIXEL_PX)


def test_gain_and_bias_recovered() -> None:
    reference = texture(sigma_px=4.0)
    result = register(reference, 0.7 * shifted(reference, (2.5, 1.5)) + 0.2)
    # Bilinear resampling lowers the contrast of a fractional shift by about 1%: the tolerance says so.
    assert result.gain == pytest.approx(0.7, abs=0.015)
    assert result.bias == pytest.approx(0.2, abs=0.01)
    np.testing.assert_allclose(result.translation_xy, (2.5, 1.5), atol=SUBPIXEL_PX)


def test_without_photometric_gain_is_one_and_offset_is_tolerated() -> None:
    reference = texture()
    result = register(reference, shifted(reference, (1.3, -0.7)) + 0.02, photometric=False)
    assert (result.gain, result.bias) == (1.0, 0.0)
    np.testing.assert_allclose(result.translation_xy, (1.3, -0.7), atol=SUBPIXEL_PX)


def test_large_shift_converges_from_phase_correlation() -> None:
    reference = texture(side_px=SIDE_PX, sigma_px=2.0)
    result = register(reference, shifted(reference, (43.4, -41.7)))
    assert result.converged
    np.testing.assert_allclose(result.translation_xy, (43.4, -41.7), atol=SUBPIXEL_PX)


def test_bright_flaw_does_not_pull_the_estimate(monkeypatch: pytest.MonkeyPatch) -> None:
    reference = texture()
    rng = np.random.default_rng(7)
    inspection = shifted(reference, (3.7, -2.2)) + rng.normal(0.0, 2.0 / 255.0, reference.shape).astype(
        np.float32
    )
    inspection[100:120, 140:160] += 0.5
    robust = register(reference, inspection)
    np.testing.assert_allclose(robust.translation_xy, (3.7, -2.2), atol=SUBPIXEL_PX)
    # The flaw is strong enough to matter: without trimming it pulls the estimate past the tolerance.
    monkeypatch.setattr(_gauss_newton, "_TRIM_SIGMAS", np.inf)
    pulled = register(reference, inspection)
    assert np.hypot(*(np.subtract(pulled.translation_xy, (3.7, -2.2)))) > SUBPIXEL_PX


def test_mask_excludes_a_flaw() -> None:
    reference = texture()
    inspection = shifted(reference, (2.0, 1.0))
    inspection[60:110, 60:110] = 1.0
    mask = np.ones(reference.shape, dtype=bool)
    mask[50:115, 50:115] = False
    result = register(reference, inspection, mask=mask)
    np.testing.assert_allclose(result.translation_xy, (2.0, 1.0), atol=SUBPIXEL_PX)


def test_identity_gives_zero_motion() -> None:
    reference = texture()
    result = register(reference, reference)
    np.testing.assert_allclose(result.matrix, np.eye(3), atol=1e-4)
    assert result.gain == pytest.approx(1.0, abs=1e-4)
    assert result.bias == pytest.approx(0.0, abs=1e-4)
    assert result.residual_rms < 1e-4


def test_shift_std_grows_with_noise() -> None:
    reference = texture()
    rng = np.random.default_rng(3)
    clean = shifted(reference, (1.5, 0.5))
    stds = []
    for sigma in (0.005, 0.02):
        noisy = clean + rng.normal(0.0, sigma, clean.shape).astype(np.float32)
        stds.append(register(reference, noisy).shift_std_px)
    assert all(np.isfinite(stds[0])) and stds[0][0] > 0
    assert stds[1][0] > 2.5 * stds[0][0] and stds[1][1] > 2.5 * stds[0][1]


def test_tiny_deadline_is_reported_not_raised() -> None:
    reference = texture()
    result = register(reference, shifted(reference, (3.0, 1.0)), deadline_s=1e-9)
    assert result.reason == "deadline"
    assert not result.converged
    assert np.isfinite(result.residual_rms)


def test_noise_only_pair_is_reported_not_raised() -> None:
    rng = np.random.default_rng(11)
    reference = rng.random((128, 128)).astype(np.float32)
    inspection = rng.random((128, 128)).astype(np.float32)
    for photometric in (True, False):
        result = register(reference, inspection, photometric=photometric, max_iterations=10)
        assert not result.converged
        assert result.reason in ("diverged", "max_iterations")


def test_flat_image_diverges() -> None:
    result = register(np.full((64, 64), 0.5), np.full((64, 64), 0.5))
    assert result.reason == "flat_reference" and not result.converged


def test_image_too_small_for_the_margins_reports_divergence() -> None:
    result = register(np.eye(3), np.eye(3))
    assert result.reason == "diverged"


def test_max_iterations_reported() -> None:
    reference = texture()
    result = register(reference, shifted(reference, (3.3, -2.6)), max_iterations=1)
    assert result.reason == "max_iterations" and not result.converged


def test_shapes_may_differ() -> None:
    reference = texture()
    inspection = shifted(reference, (3.5, 2.5))[10:200, 20:230]
    result = register(reference, inspection)
    # Cropping at (row 10, col 20) moves every inspection pixel by (-20, -10).
    np.testing.assert_allclose(result.translation_xy, (3.5 - 20.0, 2.5 - 10.0), atol=SUBPIXEL_PX)


def test_integer_images_are_accepted() -> None:
    reference = (texture() * 255).astype(np.uint8)
    inspection = np.clip(shifted(reference.astype(np.float32), (2.0, -1.0)), 0, 255).astype(np.uint8)
    result = register(reference, inspection)
    np.testing.assert_allclose(result.translation_xy, (2.0, -1.0), atol=0.05)


@pytest.mark.parametrize("as_registration", [False, True])
def test_initial_matrix_or_registration_is_used(as_registration: bool) -> None:
    reference = texture()
    truth = TRUTHS["similarity"]
    inspection = warped(reference, truth)
    start: NDArray[np.float64] | Registration = truth + np.array([[0, 0, 0.4], [0, 0, -0.3], [0, 0, 0]])
    if as_registration:
        start = register(reference, inspection, model="similarity", max_iterations=2)
    result = register(reference, inspection, model="similarity", initial=start)
    assert result.converged
    assert corner_error_px(result.matrix, truth) < SUBPIXEL_PX


def test_result_is_frozen_and_matrix_read_only() -> None:
    reference = texture()
    result = register(reference, reference)
    with pytest.raises(dataclasses.FrozenInstanceError):
        result.gain = 2.0  # type: ignore[misc]
    with pytest.raises(ValueError, match="read-only"):
        result.matrix[0, 2] = 5.0
    assert result.model == "translation" and result.elapsed_s > 0 and result.iterations >= 1


def test_deterministic() -> None:
    reference = texture()
    inspection = shifted(reference, (1.25, 0.75))
    first, second = register(reference, inspection), register(reference, inspection)
    assert np.array_equal(first.matrix, second.matrix)
    fields = ("gain", "bias", "reason", "iterations", "residual_rms", "shift_std_px")
    assert [getattr(first, name) for name in fields] == [getattr(second, name) for name in fields]


def test_warp_valid_mask_is_the_preimage_inside_the_reference() -> None:
    reference = texture()
    shift = np.array([[1.0, 0.0, 3.5], [0.0, 1.0, -2.0], [0.0, 0.0, 1.0]])
    result = Registration("translation", shift, 1.0, 0.0, True, "converged", 1, 0.0, (0.0, 0.0), 0.0)
    warped_reference, valid = result.warp(reference)
    assert warped_reference.dtype == np.float32 and valid.dtype == np.bool_
    # Preimage x - 3.5 must lie in [0, 255]: columns 4..255; y + 2 in [0, 255]: rows 0..253.
    expected = np.zeros_like(valid)
    expected[0:254, 4:256] = True
    assert np.array_equal(valid, expected)
    assert np.all(warped_reference[~valid] == 0.0)


def test_warp_maps_reference_onto_inspection() -> None:
    reference = texture()
    inspection = 1.1 * shifted(reference, (3.5, -2.0)) + 0.03
    warped_reference, valid = register(reference, inspection).warp(reference)
    inner = np.s_[8:-8, 8:-8]
    assert valid[inner].all()
    assert np.abs(warped_reference[inner] - inspection[inner]).max() < 0.01


def test_warp_output_shape_and_no_photometric() -> None:
    reference = texture()
    result = Registration("translation", np.eye(3), 2.0, 1.0, True, "converged", 1, 0.0, (0.0, 0.0), 0.0)
    plain, valid = result.warp(reference, output_shape=(100, 120), photometric=False)
    assert plain.shape == valid.shape == (100, 120) and valid.all()
    np.testing.assert_allclose(plain, reference[:100, :120], atol=1e-6)
    with pytest.raises(InputError, match="output_shape"):
        result.warp(reference, output_shape=(0, 5))
    with pytest.raises(InputError, match="reference"):
        result.warp(np.zeros((4, 4, 3)))


@pytest.mark.parametrize(
    ("kwargs", "argument"),
    [
        ({"reference": np.zeros((8, 8, 3))}, "reference"),
        ({"reference": np.zeros((1, 8))}, "reference"),
        ({"inspection": np.full((8, 8), np.nan)}, "inspection"),
        ({"inspection": np.zeros((8, 8), dtype=np.complex64)}, "inspection"),
        ({"inspection": [[0.0, 1.0], [1.0, 0.0]]}, "inspection"),
        ({"model": "projective"}, "model"),
        ({"photometric": "yes"}, "photometric"),
        ({"max_iterations": 0}, "max_iterations"),
        ({"max_iterations": 2.5}, "max_iterations"),
        ({"tolerance": 0.0}, "tolerance"),
        ({"tolerance": float("nan")}, "tolerance"),
        ({"deadline_s": -1.0}, "deadline_s"),
        ({"deadline_s": 0.0}, "deadline_s"),
        ({"mask": np.ones((7, 8), dtype=bool)}, "mask"),
        ({"initial": np.eye(2)}, "initial"),
        ({"initial": np.zeros((3, 3))}, "initial"),
        ({"initial": "identity"}, "initial"),
    ],
)
def test_bad_input_names_the_argument(kwargs: dict[str, object], argument: str) -> None:
    arguments: dict[str, object] = {"reference": np.zeros((8, 8)), "inspection": np.zeros((8, 8)), **kwargs}
    with pytest.raises(InputError, match=argument):
        register(**arguments)  # type: ignore[arg-type]


def test_shift_validity_rectangle_equals_mapping_every_pixel() -> None:
    # The fast path for pure shifts must agree with the general per-pixel preimage test.
    from rsi.imaging import registration as module

    rng = np.random.default_rng(5)
    for _ in range(300):
        dx, dy = rng.uniform(-30, 30, 2)
        shape = (int(rng.integers(2, 50)), int(rng.integers(2, 50)))
        source = (int(rng.integers(2, 50)), int(rng.integers(2, 50)))
        shift = np.array([[1.0, 0.0, dx], [0.0, 1.0, dy], [0.0, 0.0, 1.0]])
        not_a_shift = shift.copy()
        not_a_shift[2, 0] = 1e-15  # forces the general per-pixel path
        general = module._preimage_inside(not_a_shift, shape, source)
        np.testing.assert_array_equal(module._preimage_inside(shift, shape, source), general)


def test_affine_validity_runs_equal_mapping_every_pixel() -> None:
    # The affine fast path bisects each row for its run of valid columns; it must give the general
    # per-pixel preimage test's mask bit for bit, mirrored and sheared maps and empty rows included.
    from rsi.imaging import registration as module

    rng = np.random.default_rng(7)
    for trial in range(300):
        affine = np.eye(3)
        affine[:2, :2] += rng.uniform(-0.3, 0.3, (2, 2)) if trial % 3 else rng.uniform(-2.0, 2.0, (2, 2))
        affine[:2, 2] = rng.uniform(-40, 40, 2)
        affine[2, 2] = rng.choice([1.0, 0.5, 1.7, -1.0, 0.0])
        if trial % 5 == 0:
            affine[int(rng.integers(0, 2)), int(rng.integers(0, 2))] = 0.0  # constant along the rows
        shape = (int(rng.integers(1, 60)), int(rng.integers(1, 60)))
        source = (int(rng.integers(1, 60)), int(rng.integers(1, 60)))
        not_affine = affine.copy()
        not_affine[2, 0] = 1e-300  # forces the general per-pixel path (1e-300 * col is lost in rounding)
        with np.errstate(divide="ignore", invalid="ignore"):
            general = module._preimage_inside(not_affine, shape, source)
        np.testing.assert_array_equal(module._preimage_inside(affine, shape, source), general)


def test_row_runs_fill_exactly_the_runs() -> None:
    # Near-identity warps take the filled path (every row's run holds a common middle), others one slice
    # per row: both give each row's columns start <= col < stop, empty runs included.
    from rsi.imaging import registration as module

    rng = np.random.default_rng(8)
    for trial in range(500):
        rows, cols = int(rng.integers(1, 40)), int(rng.integers(1, 40))
        spread = (2, cols)[trial % 2]
        start = rng.integers(0, min(spread, cols) + 1, rows)
        stop = cols - rng.integers(0, min(spread, cols) + 1, rows)
        expected = np.zeros((rows, cols), dtype=bool)
        for row in range(rows):
            expected[row, start[row] : stop[row]] = True
        np.testing.assert_array_equal(module._row_runs(start, stop, (rows, cols)), expected)


def test_near_identity_affine_validity_equals_mapping_every_pixel() -> None:
    # DeepPCB's warps: within 1-3 % of the identity, a few pixels of shift.
    from rsi.imaging import registration as module

    rng = np.random.default_rng(9)
    for _ in range(200):
        affine = np.eye(3)
        affine[:2, :2] += rng.uniform(-0.03, 0.03, (2, 2))
        affine[:2, 2] = rng.uniform(-5, 5, 2)
        shape = (int(rng.integers(1, 80)), int(rng.integers(1, 80)))
        not_affine = affine.copy()
        not_affine[2, 0] = 1e-300
        general = module._preimage_inside(not_affine, shape, shape)
        np.testing.assert_array_equal(module._preimage_inside(affine, shape, shape), general)


@pytest.mark.parametrize(
    "matrix",
    [
        np.array([[1.0, 0.0, 3.3], [0.0, 1.0, -2.6], [0.0, 0.0, 1.0]]),  # strided fast path
        np.array([[1.0, 0.0, -7.25], [0.0, 1.0, 1.5], [0.0, 0.0, 1.0]]),  # leaves the image: bordered path
        TRUTHS["affine"],
    ],
)
def test_sampling_every_other_row_equals_every_row(matrix: NDArray[np.float64]) -> None:
    # Large levels use every other row (seed §2.3 accuracy is bias-limited): the rows must be the same.
    image = texture()
    region = (3, 250, 5, 240)
    every_row = sample(image, matrix, region)
    every_other = sample(image, matrix, region, row_step=2)
    assert every_other.shape == every_row[::2].shape and every_other.flags.c_contiguous
    np.testing.assert_allclose(every_other, every_row[::2], atol=1e-6)


def test_large_image_uses_every_other_row_and_stays_accurate() -> None:
    reference = texture(side_px=512, seed=4)
    inspection = 1.1 * shifted(reference, (9.6, -8.3)) + 0.03
    assert _gauss_newton._row_step(_pyramid.reference_pyramid(reference, None, 1)[0][0].shape) == 2
    result = register(reference, inspection)
    assert result.converged
    np.testing.assert_allclose(result.translation_xy, (9.6, -8.3), atol=SUBPIXEL_PX)


PREPARED_CASES = [
    ("translation", TRUTHS["translation"]),
    ("translation", np.array([[1.0, 0.0, -31.4], [0.0, 1.0, 27.9], [0.0, 0.0, 1.0]])),
    ("euclidean", TRUTHS["euclidean"]),
    ("affine", TRUTHS["affine"]),
    ("homography", TRUTHS["homography"]),
]


@pytest.mark.parametrize(("model", "truth"), PREPARED_CASES)
@pytest.mark.parametrize("photometric", [True, False])
def test_prepared_reference_gives_the_cold_answer(
    model: str, truth: NDArray[np.float64], photometric: bool
) -> None:
    # Seed §2.3: the Jacobian terms are precomputed once; registering to them must change nothing.
    reference = texture(sigma_px=2.0)
    inspection = warped(reference, truth)
    if photometric:
        inspection = 1.1 * inspection + 0.03
    cold = register(reference, inspection, model=model, photometric=photometric)
    prepared = prepare_reference(reference, model=model, photometric=photometric)
    for _ in range(2):  # and the prepared reference is not changed by use
        warm = register(prepared, inspection)
        np.testing.assert_allclose(warm.matrix, cold.matrix, atol=1e-6)
        assert (warm.gain, warm.bias, warm.iterations, warm.reason) == (
            cold.gain,
            cold.bias,
            cold.iterations,
            cold.reason,
        )
        assert warm.model == model and warm.residual_rms == pytest.approx(cold.residual_rms, rel=1e-6)
    assert corner_error_px(cold.matrix, truth) < SUBPIXEL_PX


def test_prepared_reference_with_mask_and_flaw_gives_the_cold_answer() -> None:
    reference = texture()
    inspection = shifted(reference, (2.0, 1.0))
    inspection[60:110, 60:110] = 1.0
    inspection[150:160, 180:190] += 0.5  # an unmasked flaw, trimmed
    mask = np.ones(reference.shape, dtype=bool)
    mask[50:115, 50:115] = False
    cold = register(reference, inspection, mask=mask)
    warm = register(prepare_reference(reference, mask=mask), inspection)
    np.testing.assert_allclose(warm.matrix, cold.matrix, atol=1e-6)
    np.testing.assert_allclose(warm.translation_xy, (2.0, 1.0), atol=SUBPIXEL_PX)


def test_prepared_reference_with_a_smaller_inspection() -> None:
    # Fewer levels are needed than were prepared: the coarsest ones are left unused.
    reference = texture(side_px=512, seed=4)
    inspection = shifted(reference, (3.5, 2.5))[10:200, 20:230]
    prepared = prepare_reference(reference)
    warm = register(prepared, inspection)
    np.testing.assert_allclose(warm.matrix, register(reference, inspection).matrix, atol=1e-6)
    np.testing.assert_allclose(warm.translation_xy, (3.5 - 20.0, 2.5 - 10.0), atol=SUBPIXEL_PX)


def test_prepared_reference_is_frozen_and_read_only() -> None:
    prepared = prepare_reference(texture(), model="affine", photometric=False)
    assert (prepared.model, prepared.photometric, prepared.masked, prepared.shape) == (
        "affine",
        False,
        False,
        (SIDE_PX, SIDE_PX),
    )
    with pytest.raises(dataclasses.FrozenInstanceError):
        prepared.model = "translation"  # type: ignore[misc]
    with pytest.raises(ValueError, match="read-only"):
        prepared.images[0][0, 0] = 1.0
    with pytest.raises(ValueError, match="read-only"):
        prepared.terms[0].jacobian[0, 0] = 1.0


@pytest.mark.parametrize(
    ("kwargs", "argument"),
    [
        ({"reference": np.zeros((8, 8, 3))}, "reference"),
        ({"reference": [[0.0, 1.0], [1.0, 0.0]]}, "reference"),
        ({"model": "projective"}, "model"),
        ({"photometric": 1}, "photometric"),
        ({"mask": np.ones((7, 8), dtype=bool)}, "mask"),
    ],
)
def test_prepare_reference_bad_input_names_the_argument(kwargs: dict[str, object], argument: str) -> None:
    arguments: dict[str, object] = {"reference": np.zeros((8, 8)), **kwargs}
    with pytest.raises(InputError, match=argument):
        prepare_reference(**arguments)  # type: ignore[arg-type]


@pytest.mark.parametrize(
    ("kwargs", "argument"),
    [
        ({"model": "affine"}, "model"),
        ({"model": "projective"}, "model"),
        ({"photometric": False}, "photometric"),
        ({"mask": np.ones((8, 8), dtype=bool)}, "mask"),
        ({"inspection": np.full((8, 8), np.nan)}, "inspection"),
        ({"max_iterations": 0}, "max_iterations"),
    ],
)
def test_prepared_reference_bad_call_names_the_argument(kwargs: dict[str, object], argument: str) -> None:
    arguments: dict[str, object] = {"inspection": np.zeros((8, 8)), **kwargs}
    with pytest.raises(InputError, match=argument):
        register(prepare_reference(np.zeros((8, 8))), **arguments)  # type: ignore[arg-type]


def test_prepared_reference_accepts_its_own_settings_repeated() -> None:
    reference = texture()
    inspection = shifted(reference, (1.5, -0.5))
    prepared = prepare_reference(reference, model="similarity", photometric=False)
    same = register(prepared, inspection, model="similarity", photometric=False)
    np.testing.assert_allclose(same.matrix, register(prepared, inspection).matrix, atol=0.0)


def _outcome(result: Registration) -> tuple[object, ...]:
    return (result.matrix.tobytes(), result.gain, result.bias, result.iterations, result.residual_rms)


def test_consecutive_calls_share_no_memory_with_their_results() -> None:
    # Cold calls and inspection pyramids use this thread's reusable scratch buffers (page faults, seed §2.1):
    # nothing returned may live in them, or the next call would overwrite it.
    reference, other = texture(side_px=512, seed=4), texture(side_px=512, seed=5)
    prepared = prepare_reference(reference)
    kept = [array.copy() for array in (*prepared.images, *(terms.jacobian for terms in prepared.terms))]
    first = register(reference, 1.1 * shifted(reference, (3.5, 2.5)) + 0.03)
    first_outcome = _outcome(first)
    second = register(other, shifted(other, (-7.2, 4.1)))
    warm = register(prepared, shifted(reference, (1.5, -0.5)))
    assert _outcome(first) == first_outcome
    np.testing.assert_allclose(second.translation_xy, (-7.2, 4.1), atol=SUBPIXEL_PX)
    np.testing.assert_allclose(warm.translation_xy, (1.5, -0.5), atol=SUBPIXEL_PX)
    owned = [*prepared.images, *(terms.jacobian for terms in prepared.terms)]
    for before, after in zip(kept, owned, strict=True):
        np.testing.assert_array_equal(after, before)
    buffers = list(_warps._WORKSPACE.buffers.values())
    assert buffers  # the calls above did use the workspace
    for array in (first.matrix, second.matrix, warm.matrix, *owned):
        assert not any(np.shares_memory(array, buffer) for buffer in buffers)
    assert not np.shares_memory(first.matrix, second.matrix)


def test_workspace_keeps_one_buffer_per_role() -> None:
    reference = texture(side_px=512, seed=4)
    for side in (512, 300, 512):
        register(reference[:side, :side], shifted(reference, (2.5, 1.5))[:side, :side])
        roles = set(_warps._WORKSPACE.buffers)
    register(reference, shifted(reference, (2.5, 1.5)))
    assert set(_warps._WORKSPACE.buffers) == roles


def test_two_threads_registering_at_once_get_the_serial_answers() -> None:
    # Each thread has its own scratch buffers: concurrent calls must not see each other's temporaries.
    pairs = []
    for seed, side, shift_xy in ((4, 512, (9.6, -8.3)), (5, 512, (-3.3, 2.7)), (6, 256, (25.3, -31.1))):
        reference = texture(side_px=side, seed=seed)
        inspection = 1.1 * shifted(reference, shift_xy) + 0.03
        inspection[40:50, 60:70] += 0.5  # a flaw: trimming runs too
        pairs.append((reference, inspection))
    # And one stored reference that both threads read at once.
    shared = prepare_reference(pairs[0][0])
    cases: list[tuple[NDArray[np.float32] | PreparedReference, NDArray[np.float32]]] = [
        *pairs,
        (shared, pairs[0][1]),
    ]
    expected = [_outcome(register(reference, inspection)) for reference, inspection in cases]
    start = threading.Barrier(2)

    def work(order: int) -> list[tuple[object, ...]]:
        start.wait()
        chosen = list(range(len(cases)))[:: 1 if order == 0 else -1]
        got = {index: _outcome(register(*cases[index])) for _ in range(3) for index in chosen}
        return [got[index] for index in range(len(cases))]

    with ThreadPoolExecutor(max_workers=2) as pool:
        results = list(pool.map(work, (0, 1)))
    assert results == [expected, expected]


HALF_RESOLUTION_PX = 0.1  # finest_level=1: the half-size images' fit, scaled back (docs/registration.md)


@pytest.mark.parametrize("model", ["translation", "affine", "homography"])
def test_finest_level_one_recovers_a_known_warp_at_half_resolution(model: str) -> None:
    reference = texture()
    inspection = 1.2 * warped(reference, TRUTHS[model]) + 0.05
    full = register(reference, inspection, model=model)
    half = register(reference, inspection, model=model, finest_level=1)
    assert half.converged and half.model == model
    assert corner_error_px(half.matrix, TRUTHS[model]) < HALF_RESOLUTION_PX
    # Bilinear resampling of this texture's 1.5 px blobs at half size loses a few per cent of contrast.
    assert half.gain == pytest.approx(1.2, abs=0.06)
    # In full-resolution pixels: a quarter of the samples, each twice as large, and a larger resampling
    # residual give a std several times the full-resolution one (8x here), never a smaller one.
    assert all(2 * f < h < 20 * f for f, h in zip(full.shift_std_px, half.shift_std_px, strict=True))


def test_finest_level_zero_is_the_default_bit_for_bit() -> None:
    reference = texture()
    inspection = warped(reference, TRUTHS["affine"])
    default = register(reference, inspection, model="affine")
    explicit = register(reference, inspection, model="affine", finest_level=0)
    np.testing.assert_array_equal(explicit.matrix, default.matrix)
    assert (explicit.gain, explicit.iterations, explicit.shift_std_px) == (
        default.gain,
        default.iterations,
        default.shift_std_px,
    )


def test_finest_level_beyond_the_pyramid_refines_the_coarsest_level() -> None:
    reference = texture()  # 256 px: levels 0 and 1 only
    inspection = shifted(reference, (3.7, -2.2))
    coarsest = register(reference, inspection, finest_level=1)
    beyond = register(reference, inspection, finest_level=5)
    np.testing.assert_array_equal(beyond.matrix, coarsest.matrix)
    small = texture(side_px=100)  # one level: full resolution whatever is asked
    np.testing.assert_array_equal(
        register(small, shifted(small, (1.5, 0.5)), finest_level=1).matrix,
        register(small, shifted(small, (1.5, 0.5))).matrix,
    )


@pytest.mark.parametrize("model", ["translation", "affine"])
def test_a_single_level_from_a_close_start_recovers_a_known_warp(model: str) -> None:
    # coarsest_level = finest_level = 1: no quarter-size level before the half-size one; from the identity
    # (pre-aligned images) the fit is as good as the two-level one.
    reference = texture()
    inspection = warped(reference, TRUTHS[model])
    two_levels = register(reference, inspection, model=model, finest_level=1, initial=np.eye(3))
    one_level = register(
        reference, inspection, model=model, finest_level=1, coarsest_level=1, initial=np.eye(3)
    )
    assert one_level.converged
    assert corner_error_px(one_level.matrix, TRUTHS[model]) < HALF_RESOLUTION_PX
    assert corner_error_px(one_level.matrix, two_levels.matrix) < HALF_RESOLUTION_PX / 2


def test_coarsest_level_none_or_beyond_the_pyramid_is_the_whole_pyramid_bit_for_bit() -> None:
    reference = texture()  # 256 px: levels 0 and 1 only
    inspection = warped(reference, TRUTHS["affine"])
    default = register(reference, inspection, model="affine")
    for coarsest in (None, 1, 7):
        explicit = register(reference, inspection, model="affine", coarsest_level=coarsest)
        np.testing.assert_array_equal(explicit.matrix, default.matrix)
        assert explicit.iterations == default.iterations


def test_coarsest_level_finer_than_the_finest_is_refused() -> None:
    reference = texture()
    with pytest.raises(InputError, match="coarsest_level=0 is finer than finest_level=1"):
        register(reference, reference, finest_level=1, coarsest_level=0)
    with pytest.raises(InputError, match="coarsest_level"):
        register(reference, reference, coarsest_level=-1)


def test_finest_level_one_trims_a_flaw_there() -> None:
    reference = texture()
    inspection = shifted(reference, (3.7, -2.2))
    inspection[100:120, 140:160] += 0.5
    half = register(reference, inspection, finest_level=1)
    np.testing.assert_allclose(half.translation_xy, (3.7, -2.2), atol=HALF_RESOLUTION_PX / 2)


@pytest.mark.parametrize("model", ["translation", "affine"])
def test_prepared_reference_at_finest_level_one_gives_the_cold_answer(model: str) -> None:
    # The cold call prepares only the levels it refines; a prepared reference holds them all.
    reference = texture(sigma_px=2.0)
    inspection = warped(reference, TRUTHS[model])
    cold = register(reference, inspection, model=model, finest_level=1)
    warm = register(prepare_reference(reference, model=model), inspection, finest_level=1)
    np.testing.assert_allclose(warm.matrix, cold.matrix, atol=1e-6)
    assert (warm.iterations, warm.reason) == (cold.iterations, cold.reason)


@pytest.mark.parametrize("value", [-1, 0.5, "1"])
def test_finest_level_must_be_a_non_negative_int(value: object) -> None:
    with pytest.raises(InputError, match="finest_level"):
        register(texture(), texture(), finest_level=value)  # type: ignore[arg-type]


@pytest.mark.parametrize("model", ["translation", "affine"])
def test_every_other_row_recovers_a_known_warp(model: str) -> None:
    # row_step=2 on a 256-row level (every row by default): half the samples, the same answer within the
    # half-resolution tolerance.
    reference = texture()
    inspection = warped(reference, TRUTHS[model])
    every_row = register(reference, inspection, model=model)
    every_other = register(reference, inspection, model=model, row_step=2)
    assert every_other.converged
    assert corner_error_px(every_other.matrix, TRUTHS[model]) < HALF_RESOLUTION_PX
    assert not np.array_equal(every_other.matrix, every_row.matrix)  # fewer rows: another (close) answer


def test_a_prepared_reference_keeps_its_row_step() -> None:
    reference = texture(sigma_px=2.0)
    inspection = warped(reference, TRUTHS["affine"])
    prepared = prepare_reference(reference, model="affine", row_step=2)
    cold = register(reference, inspection, model="affine", row_step=2)
    warm = register(prepared, inspection)
    np.testing.assert_allclose(warm.matrix, cold.matrix, atol=1e-6)
    assert warm.iterations == cold.iterations
    np.testing.assert_array_equal(register(prepared, inspection, row_step=2).matrix, warm.matrix)
    with pytest.raises(InputError, match="row_step=3 differs from the prepared reference's row_step=2"):
        register(prepared, inspection, row_step=3)
    with pytest.raises(InputError, match="row_step=1 differs"):
        register(prepare_reference(reference, model="affine"), inspection, row_step=1)


@pytest.mark.parametrize("value", [0, -2, 1.5, "2"])
def test_row_step_must_be_a_positive_int(value: object) -> None:
    with pytest.raises(InputError, match="row_step"):
        register(texture(), texture(), row_step=value)  # type: ignore[arg-type]
    with pytest.raises(InputError, match="row_step"):
        prepare_reference(texture(), row_step=value)  # type: ignore[arg-type]


@pytest.mark.parametrize("model", ["translation", "affine"])
def test_without_presmoothing_a_half_size_fit_recovers_a_known_warp(model: str) -> None:
    # presmooth=False: the half-size level is cv2.pyrDown of the raw image, smoothed by its own Gaussian.
    reference = texture()
    inspection = warped(reference, TRUTHS[model])
    raw = register(reference, inspection, model=model, finest_level=1, presmooth=False)
    assert raw.converged
    assert corner_error_px(raw.matrix, TRUTHS[model]) < HALF_RESOLUTION_PX
    smoothed = register(reference, inspection, model=model, finest_level=1)
    assert not np.array_equal(raw.matrix, smoothed.matrix)  # other images, a close answer


def test_a_prepared_reference_keeps_its_presmoothing() -> None:
    reference = texture(sigma_px=2.0)
    inspection = warped(reference, TRUTHS["affine"])
    prepared = prepare_reference(reference, model="affine", presmooth=False)
    cold = register(reference, inspection, model="affine", presmooth=False)
    warm = register(prepared, inspection)
    np.testing.assert_allclose(warm.matrix, cold.matrix, atol=1e-6)
    assert warm.iterations == cold.iterations
    with pytest.raises(InputError, match="presmooth=True differs from the prepared reference's"):
        register(prepared, inspection, presmooth=True)
    with pytest.raises(InputError, match="presmooth"):
        register(reference, inspection, presmooth="no")  # type: ignore[arg-type]
    with pytest.raises(InputError, match="presmooth"):
        prepare_reference(reference, presmooth=1)  # type: ignore[arg-type]


def test_the_caller_s_images_stay_writable_without_presmoothing() -> None:
    reference, inspection = texture(), shifted(texture(), (1.5, 0.5))
    register(reference, inspection, presmooth=False)
    prepare_reference(reference, presmooth=False)
    assert reference.flags.writeable and inspection.flags.writeable
