"""ROC truths (seed §2.4): thresholds, closed forms, P_D = P_F without a flaw, monotonicity."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import stats

from rsi.detection.roc import empirical_roc, theoretical_roc, threshold_for
from rsi.errors import InputError

MODELS = ("single", "uniform", "peak", "kernel")
CROSS = np.array([[0.0, 1.0, 0.0], [1.0, 2.0, 1.0], [0.0, 1.0, 0.0]])


def _kernel(model: str) -> np.ndarray | None:
    return CROSS if model == "kernel" else None


def test_lrt_thresholds_are_normal_quantiles() -> None:
    assert threshold_for(1e-3, polarity="both") == pytest.approx(stats.norm.isf(5e-4))
    assert threshold_for(1e-3, polarity="dark") == pytest.approx(stats.norm.isf(1e-3))


def test_erosion_threshold_gives_requested_rate_over_the_footprint() -> None:
    t = threshold_for(1e-4, polarity="bright", method="erosion", flaw_model="uniform", size=3)
    assert stats.norm.sf(t) ** 9 == pytest.approx(1e-4)
    # Both polarities with n = 25: the per-pixel tail exceeds 1/2 (t < 0) and the events overlap.
    t_both = threshold_for(1e-3, polarity="both", method="erosion", flaw_model="uniform", size=5)
    p = stats.norm.sf(t_both)
    assert t_both < 0
    assert 2 * p**25 - (2 * p - 1) ** 25 == pytest.approx(1e-3)


@pytest.mark.parametrize("method", ["lrt", "erosion"])
@pytest.mark.parametrize("polarity", ["both", "dark", "bright"])
@pytest.mark.parametrize("model", MODELS)
def test_zero_strength_gives_chance_and_curves_are_monotone(model: str, polarity: str, method: str) -> None:
    chance = theoretical_roc(
        model, strength_sigma=0.0, kernel=_kernel(model), method=method, polarity=polarity
    )
    np.testing.assert_allclose(chance.p_detection, chance.p_false_alarm, rtol=1e-6)
    curve = theoretical_roc(
        model, strength_sigma=3.0, kernel=_kernel(model), method=method, polarity=polarity
    )
    assert np.all(np.diff(curve.p_detection) >= -1e-12)
    assert np.all(curve.p_detection >= curve.p_false_alarm - 1e-12)


def test_lrt_closed_form() -> None:
    # Uniform 3x3 matched to itself: mean = s * 9 / 3 = 3 s.
    curve = theoretical_roc("uniform", strength_sigma=1.5, p_false_alarm=np.array([1e-3]), polarity="dark")
    assert curve.p_detection[0] == pytest.approx(stats.norm.cdf(4.5 - stats.norm.isf(1e-3)))
    # A single-pixel detector facing a 3x3 flaw sees only its centre.
    mismatched = theoretical_roc(
        "single",
        strength_sigma=2.0,
        p_false_alarm=np.array([1e-2]),
        true_flaw=np.ones((3, 3)),
        polarity="both",
    )
    t = stats.norm.isf(5e-3)
    assert mismatched.p_detection[0] == pytest.approx(stats.norm.cdf(2 - t) + stats.norm.cdf(-2 - t))


def test_erosion_closed_form_and_suboptimality() -> None:
    pf = np.array([1e-4])
    erosion = theoretical_roc("uniform", strength_sigma=3.0, p_false_alarm=pf, method="erosion")
    t = stats.norm.isf(1e-4 ** (1 / 9))
    assert erosion.p_detection[0] == pytest.approx(stats.norm.cdf(3.0 - t) ** 9)
    lrt = theoretical_roc("uniform", strength_sigma=3.0, p_false_alarm=pf, method="lrt")
    assert lrt.p_detection[0] > erosion.p_detection[0]  # seed §2.4: erosion is the sub-optimal test


@pytest.mark.parametrize(
    ("call", "argument"),
    [
        (lambda: threshold_for(0.0), "p_false_alarm"),
        (lambda: threshold_for(0.5), "p_false_alarm"),
        (lambda: threshold_for(1e-3, polarity="up"), "polarity"),
        (lambda: threshold_for(1e-3, method="max"), "method"),
        (lambda: theoretical_roc("single", strength_sigma=-1.0), "strength_sigma"),
        (
            lambda: theoretical_roc("single", strength_sigma=1.0, p_false_alarm=np.array([0.0])),
            "p_false_alarm",
        ),
        (lambda: theoretical_roc("single", strength_sigma=1.0, true_flaw=np.ones((2, 2))), "true_flaw"),
        (lambda: theoretical_roc("single", strength_sigma=1.0, true_flaw=[1.0]), "true_flaw"),
        (lambda: empirical_roc(np.zeros((8, 8)), np.zeros((8, 8), bool)), "truth_mask"),
        (lambda: empirical_roc(np.zeros((8, 8)), np.ones((4, 4), bool)), "truth_mask"),
        (lambda: empirical_roc(np.full((8, 8), np.nan), np.ones((8, 8), bool)), "score"),
        (lambda: empirical_roc(np.zeros((8, 8)), np.eye(8, dtype=bool), guard_px=-1), "guard_px"),
        (
            lambda: empirical_roc(np.zeros((8, 8)), np.eye(8, dtype=bool), valid=np.zeros((8, 8), bool)),
            "valid",
        ),
    ],
)
def test_bad_arguments_are_named(call: object, argument: str) -> None:
    with pytest.raises(InputError, match=argument):
        call()  # type: ignore[operator]


def test_empirical_roc_on_a_known_score() -> None:
    rng = np.random.default_rng(3)
    score = rng.standard_normal((200, 200))
    truth = np.zeros((200, 200), bool)
    truth[10:200:20, 10:200:20] = True
    score[truth] = 10.0
    score[10, 10] = -10.0  # one missed flaw
    curve = empirical_roc(score, truth, guard_px=1)
    assert curve.p_detection[0] == pytest.approx(99 / 100)
    assert curve.p_false_alarm[0] == 0.0
    assert curve.p_detection[-1] == 1.0
    assert curve.p_false_alarm[-1] > 0.99
