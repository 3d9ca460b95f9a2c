"""Flaw detection (seed §2.4): calibration of P_F, P_D against theory, registration, inputs and errors."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import pytest
from scipy import ndimage, optimize

from rsi.datasets.synthetic import flaw_pattern, pure_noise_pairs, synthetic_pair, textured_surface
from rsi.detection.detect import Detection, detect
from rsi.detection.noise import interpolation_factor
from rsi.detection.roc import theoretical_roc, threshold_for
from rsi.errors import InputError
from rsi.imaging.compensation import Compensated
from rsi.imaging.registration import Registration

CROSS = np.array([[0.0, 1.0, 0.0], [1.0, 2.0, 1.0], [0.0, 1.0, 0.0]])
MODELS = ("single", "uniform", "peak", "kernel")
RATES = (1e-3, 1e-4, 1e-5)
SHAPE = (1024, 1024)
IMAGES = 16  # 16.8 Mpx per case: about 170 expected false alarms at 1e-5
SIGMA = 0.01


def _kernel(model: str) -> np.ndarray | None:
    return CROSS if model == "kernel" else None


@dataclass(frozen=True)
class NoisePairs:
    """Same texture, independent noise, no flaws: every detection is a false alarm."""

    pairs: tuple[tuple[np.ndarray, np.ndarray], ...]
    noise_sigma: float | None


def _noise_pairs(seed: int, shot: bool) -> NoisePairs:
    # Read + shot noise (variance grows with intensity) for the self-calibrated case, which must find it.
    noise = {"read_sigma": 0.003, "shot_variance_per_unit": 4e-4} if shot else {"read_sigma": SIGMA}
    pairs = pure_noise_pairs(SHAPE, IMAGES, rng=seed, **noise)
    return NoisePairs(tuple(pairs), None if shot else SIGMA)


@pytest.fixture(scope="module", params=["known", "estimated"])
def noise_pairs(request: pytest.FixtureRequest) -> NoisePairs:
    return _noise_pairs(11, shot=request.param == "estimated")


def _false_alarm_rates(pairs: NoisePairs, model: str, method: str) -> list[float]:
    counts = np.zeros(len(RATES))
    total = 0
    for reference, inspection in pairs.pairs:
        found = detect(
            reference,
            inspection,
            flaw_model=model,
            kernel=_kernel(model),
            method=method,
            p_false_alarm=RATES[-1],
            noise_sigma=pairs.noise_sigma,
            registration=None,
        )
        assert found.threshold == threshold_for(
            RATES[-1], method=method, flaw_model=model, kernel=_kernel(model)
        )
        score = found.score[found.valid]
        total += score.size
        for index, rate in enumerate(RATES):
            counts[index] += np.count_nonzero(
                score > threshold_for(rate, method=method, flaw_model=model, kernel=_kernel(model))
            )
    return list(counts / total)


@pytest.mark.parametrize("method", ["lrt", "erosion"])
@pytest.mark.parametrize("model", MODELS)
def test_false_alarm_rate_is_calibrated(noise_pairs: NoisePairs, model: str, method: str) -> None:
    measured = _false_alarm_rates(noise_pairs, model, method)
    for requested, rate in zip(RATES, measured, strict=True):
        assert requested / 1.5 < rate < requested * 1.5, (model, method, requested, rate)


def _strength_for(model: str, method: str, true_flaw: np.ndarray | None) -> float:
    """Flaw strength (difference-sigma units) giving P_D = 0.6 at P_F = 1e-3: both P_F values informative."""

    def gap(strength: float) -> float:
        curve = theoretical_roc(
            model,
            strength_sigma=strength,
            p_false_alarm=np.array([1e-3]),
            kernel=_kernel(model),
            true_flaw=true_flaw,
            method=method,
        )
        return float(curve.p_detection[0]) - 0.6

    return float(optimize.brentq(gap, 0.0, 20.0))


# (detector model, true flaw profile, true flaw size): the kernel model meets a mismatched uniform flaw.
PD_CASES = [
    ("single", "uniform", 1),
    ("uniform", "uniform", 3),
    ("peak", "peak", 3),
    ("kernel", "uniform", 3),
]


@pytest.mark.parametrize("method", ["lrt", "erosion"])
@pytest.mark.parametrize(("model", "profile", "size_px"), PD_CASES)
def test_detection_rate_matches_theory(model: str, profile: str, size_px: int, method: str) -> None:
    rng = np.random.default_rng(5)
    true_flaw = np.ones((3, 3)) if model == "kernel" else None
    strength_sigma = _strength_for(model, method, true_flaw)
    difference_sigma = np.sqrt(2.0) * SIGMA  # both images carry sensor noise SIGMA
    surface = textured_surface(SHAPE, rng=rng)
    flaws = flaw_pattern(
        SHAPE,
        size_px=size_px,
        spacing_px=16,
        strength=strength_sigma * difference_sigma,
        profile=profile,
        rng=rng,
    )
    assert len(flaws.centres_rc) == 4096
    reference = surface + SIGMA * rng.standard_normal(SHAPE)
    inspection = surface + flaws.signal + SIGMA * rng.standard_normal(SHAPE)
    found = detect(
        reference,
        inspection,
        flaw_model=model,
        kernel=_kernel(model),
        method=method,
        polarity="dark",
        noise_sigma=SIGMA,
        registration=None,
    )
    centre_scores = found.score[flaws.centres_rc[:, 0], flaws.centres_rc[:, 1]]
    rates = np.array([1e-3, 1e-2])
    theory = theoretical_roc(
        model,
        strength_sigma=strength_sigma,
        p_false_alarm=rates,
        kernel=_kernel(model),
        true_flaw=true_flaw,
        method=method,
        polarity="dark",
    )
    for rate, threshold, expected in zip(rates, theory.threshold, theory.p_detection, strict=True):
        measured = np.mean(centre_scores > threshold)
        assert abs(measured - expected) < 0.03, (model, method, rate, measured, expected)


def _translation(dx: float, dy: float) -> Registration:
    matrix = np.array([[1.0, 0.0, dx], [0.0, 1.0, dy], [0.0, 0.0, 1.0]])
    return Registration(
        model="translation",
        matrix=matrix,
        gain=1.0,
        bias=0.0,
        converged=True,
        reason="converged",
        iterations=0,
        residual_rms=0.0,
        shift_std_px=(0.0, 0.0),
        elapsed_s=0.0,
    )


@pytest.mark.parametrize("model", ["single", "uniform"])
def test_interpolation_factor_keeps_the_statistic_standard(model: str) -> None:
    # A half-pixel bilinear shift averages four reference pixels: their noise drops to 1/4 of its variance.
    rng = np.random.default_rng(2)
    reference = 0.5 + SIGMA * rng.standard_normal((512, 512))
    inspection = 0.5 + SIGMA * rng.standard_normal((512, 512))
    found = detect(
        reference, inspection, flaw_model=model, noise_sigma=SIGMA, registration=_translation(0.5, 0.5)
    )
    assert interpolation_factor(np.ones((1, 1)), (0.5, 0.5)) == pytest.approx(0.25)
    spread = np.std(found.statistic[found.valid])
    assert spread == pytest.approx(1.0, abs=0.03)


def test_registered_pair_finds_the_flaws() -> None:
    pair = synthetic_pair((512, 512), rng=4)
    found = detect(pair.reference, pair.inspection, flaw_model="uniform", p_false_alarm=1e-5)
    assert found.registration is not None
    assert found.registration.translation_xy == pytest.approx(pair.shift_xy, abs=0.05)
    inside = found.valid[pair.centres_rc[:, 0], pair.centres_rc[:, 1]]
    hit = found.mask[pair.centres_rc[:, 0], pair.centres_rc[:, 1]]
    assert np.mean(hit[inside]) > 0.98
    centres = np.array([[flaw.row, flaw.col] for flaw in found.flaws])
    nearest = np.min(
        np.hypot(*(centres[:, None, :] - pair.centres_rc[None, :, :]).transpose(2, 0, 1)), axis=1
    )
    assert np.count_nonzero(nearest > 3) <= 5  # false flaws
    assert all(flaw.polarity == "dark" for flaw in found.flaws if flaw.score > 2 * found.threshold)


def test_compensated_inputs_bring_validity_and_variance() -> None:
    rng = np.random.default_rng(8)
    shape = (512, 512)
    variance = rng.uniform(1.0, 9.0, shape).astype(np.float32)  # DN^2, strongly heteroscedastic
    surface = 100.0 * textured_surface(shape, rng=rng)
    valid = np.ones(shape, bool)
    valid[100:110, :] = False

    def compensated() -> Compensated:
        image = (surface + np.sqrt(variance) * rng.standard_normal(shape)).astype(np.float32)
        return Compensated(
            image=image,
            valid=valid,
            variance=variance,
            interpolation_variance=np.zeros(shape, np.float32),
            row_step=1,
        )

    found = detect(compensated(), compensated(), flaw_model="uniform", p_false_alarm=1e-3, registration=None)
    assert not found.valid[100:110].any()
    rate = np.count_nonzero(found.mask) / np.count_nonzero(found.valid)
    assert 1e-3 / 1.5 < rate < 1e-3 * 1.5


def test_flaw_list_components() -> None:
    reference = np.zeros((64, 64))
    inspection = np.zeros((64, 64))
    inspection[10:13, 20:24] = -1.0  # dark, 12 px
    inspection[40, 40] = 2.0  # bright, strongest, 1 px
    found = detect(reference, inspection, noise_sigma=0.05, registration=None)
    assert [flaw.polarity for flaw in found.flaws] == ["bright", "dark"]
    bright, dark = found.flaws
    assert bright.bbox == (40, 40, 41, 41) and bright.area_px == 1
    assert dark.bbox == (10, 20, 13, 24) and dark.area_px == 12
    assert (dark.row, dark.col) == pytest.approx((11.0, 21.5))
    assert bright.score > dark.score
    larger = detect(reference, inspection, noise_sigma=0.05, registration=None, min_area_px=2)
    assert [flaw.polarity for flaw in larger.flaws] == ["dark"]
    dark_only = detect(reference, inspection, noise_sigma=0.05, registration=None, polarity="dark")
    assert [flaw.polarity for flaw in dark_only.flaws] == ["dark"]
    assert dark_only.statistic[40, 40] > 0 and dark_only.score[40, 40] < 0


def test_each_flaw_peaks_on_its_own_pixels() -> None:
    """A ring's box holds a stronger spot in its hollow: each flaw's peak is one of its own pixels."""
    rows, cols = np.mgrid[:64, :64]
    radius = np.hypot(rows - 32, cols - 32)
    inspection = np.where((radius >= 12) & (radius <= 16), 1.0, 0.0)
    inspection[31:34, 31:34] = -3.0  # darker and stronger, 9 px clear of the ring
    found = detect(np.zeros((64, 64)), inspection, noise_sigma=0.05, registration=None)
    spot, ring = found.flaws
    assert (spot.polarity, ring.polarity) == ("dark", "bright") and spot.score > ring.score
    for flaw in found.flaws:
        assert flaw.peak is not None and found.mask[flaw.peak]
        assert found.score[flaw.peak] == flaw.score
    assert ring.peak is not None and 12 <= math.hypot(ring.peak[0] - 32, ring.peak[1] - 32) <= 16


GOOD = np.zeros((32, 32))


@pytest.mark.parametrize(
    ("kwargs", "argument"),
    [
        ({"reference": np.zeros((32, 31))}, "reference"),
        ({"inspection": np.zeros(32)}, "inspection"),
        ({"inspection": np.full((32, 32), np.nan)}, "inspection"),
        ({"reference": [[0.0, 1.0], [1.0, 0.0]]}, "reference"),
        ({"flaw_model": "crater"}, "flaw_model"),
        ({"method": "dilation"}, "method"),
        ({"polarity": "grey"}, "polarity"),
        ({"p_false_alarm": 0.0}, "p_false_alarm"),
        ({"p_false_alarm": 0.5}, "p_false_alarm"),
        ({"flaw_model": "uniform", "size": 2}, "size"),
        ({"flaw_model": "uniform", "size": 0}, "size"),
        ({"flaw_model": "kernel", "kernel": np.ones((2, 2))}, "kernel"),
        ({"noise_sigma": -1.0}, "noise_sigma"),
        ({"registration": "manual"}, "registration"),
        ({"registration": np.eye(3)}, "registration"),
        ({"registration_model": "elastic"}, "registration_model"),
        ({"min_area_px": 0}, "min_area_px"),
        ({"misregistration_std_px": -0.5}, "misregistration_std_px"),
        ({"misregistration_std_px": float("nan")}, "misregistration_std_px"),
    ],
)
def test_bad_arguments_are_named(kwargs: dict[str, object], argument: str) -> None:
    arguments: dict[str, object] = {
        "reference": GOOD,
        "inspection": GOOD,
        "registration": None,
        "noise_sigma": 0.1,
    }
    arguments.update(kwargs)
    with pytest.raises(InputError, match=argument):
        detect(**arguments)  # type: ignore[arg-type]


def test_misregistration_floor_turns_a_moved_edge_into_noise() -> None:
    # seed §2.3-2.4: an edge moved by a residual shift is a false "flaw" unless the noise model knows the
    # shift's spread; with a floor of the shift's size the edge falls below threshold and a real flaw stays.
    rng = np.random.default_rng(3)
    reference = np.zeros((96, 96))
    reference[:, 48:] = 1.0
    inspection = np.zeros((96, 96))
    inspection[:, 49:] = 1.0  # the edge moved by one pixel
    inspection[20:25, 20:25] -= 0.5  # a real flaw, away from the edge
    reference += 0.01 * rng.standard_normal(reference.shape)
    inspection += 0.01 * rng.standard_normal(inspection.shape)
    common = {"flaw_model": "uniform", "size": 5, "noise_sigma": 0.01, "registration": None}
    naive = detect(reference, inspection, **common)  # type: ignore[arg-type]
    floored = detect(reference, inspection, misregistration_std_px=1.0, **common)  # type: ignore[arg-type]
    assert naive.mask[:, 46:52].any()
    assert not floored.mask[:, 40:60].any()
    assert floored.mask[22, 22]


def _sparse_and_full(**settings: object) -> tuple[Detection, Detection, float]:
    pair = synthetic_pair((256, 256), flaw_spacing_px=40, rng=5)
    inspection = pair.inspection.copy()
    inspection[:6, 100:112] -= 0.3  # a flaw on the image edge: its box meets the frame there
    arguments: dict[str, object] = {"noise_sigma": 2 / 255, "misregistration_std_px": 0.2, **settings}
    full = detect(pair.reference, inspection, **arguments)  # type: ignore[arg-type]
    above = threshold_for(1e-5, polarity="both", method="lrt", flaw_model="single")
    sparse = detect(
        pair.reference, inspection, registration=full.registration, sparse_above=above, **arguments
    )  # type: ignore[arg-type]
    return full, sparse, above


@pytest.mark.parametrize(
    "settings",
    [
        {"flaw_model": "uniform", "method": "erosion"},
        {"flaw_model": "single", "method": "lrt"},
        {"flaw_model": "uniform", "method": "erosion", "size": 5, "registration_model": "affine"},
        # A local field, no floor: each box reads its crop of the field's per-pixel shift std.
        {
            "flaw_model": "uniform",
            "method": "erosion",
            "registration_model": "local",
            "misregistration_std_px": 0.0,
        },
        {"flaw_model": "uniform", "method": "erosion", "size": 5, "p_false_alarm": 1e-9},
        # A threshold below 0 bounds nothing: every pixel may be flagged, the maps are whole.
        {"flaw_model": "uniform", "method": "erosion", "p_false_alarm": 0.3},
    ],
)
def test_sparse_maps_equal_the_whole_frame_where_they_can_matter(settings: dict[str, object]) -> None:
    full, sparse, above = _sparse_and_full(**settings)
    assert full.mask.any() and full.flaws == sparse.flaws
    for name in ("mask", "valid", "difference"):
        np.testing.assert_array_equal(getattr(sparse, name), getattr(full, name))
    computed = np.isfinite(sparse.sigma)
    assert full.mask[~computed].sum() == 0
    for name in ("score", "statistic", "sigma"):
        np.testing.assert_array_equal(getattr(sparse, name)[computed], getattr(full, name)[computed])
    assert not sparse.score[~computed].any() and not sparse.statistic[~computed].any()

    # Beyond the boxes no pixel passes |d| / sigma > above that is connected to a possible flag.
    # As the grouping of docs/deeppcb.md reads it: |d| / sigma, inf sigma giving 0.
    def pixel_z(found: Detection) -> np.ndarray:
        return np.abs(found.difference) / np.maximum(found.sigma, np.float32(1e-6))

    assert np.array_equal(pixel_z(sparse)[computed], pixel_z(full)[computed])
    assert not pixel_z(sparse)[~computed].any()
    # Every pixel beyond `above` connected to a flag through such pixels (the grown extent) was computed.
    extent = (pixel_z(full) > above) & full.valid  # sigma is 0 where invalid
    labels, _ = ndimage.label(extent | full.mask, structure=np.ones((3, 3)))
    assert computed[np.isin(labels, labels[full.mask])].all()
    assert computed.all() == (full.threshold <= 0)  # a 5x5 erosion at 1e-5 and a 3x3 at 0.3 bound nothing


@pytest.mark.parametrize(
    "settings",
    [
        {"noise_sigma": None},  # self-calibrated: the variance is fitted per pixel
        {"flaw_model": "uniform", "method": "lrt"},  # a window test: |T| is not bounded by one |d|
        {"sparse_above": -1.0},
    ],
)
def test_sparse_needs_its_bound(settings: dict[str, object]) -> None:
    pair = synthetic_pair((128, 128), rng=2)
    arguments: dict[str, object] = {
        "noise_sigma": 0.01,
        "flaw_model": "single",
        "sparse_above": 4.0,
        **settings,
    }
    with pytest.raises(InputError, match="sparse_above"):
        detect(pair.reference, pair.inspection, **arguments)  # type: ignore[arg-type]
