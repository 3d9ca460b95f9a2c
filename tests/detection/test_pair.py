"""The pipeline glue: one pair registered and tested (seed §2.3-2.4), and scoring against known flaws."""

from __future__ import annotations

import numpy as np
import pytest

from rsi.datasets.synthetic import synthetic_pair
from rsi.detection.detect import Flaw
from rsi.detection.pair import inspect_pair, score_flaws
from rsi.errors import InputError

SHIFT_TOLERANCE_PX = 0.05


def flaw_at(bbox: tuple[int, int, int, int]) -> Flaw:
    row0, col0, row1, col1 = bbox
    return Flaw(
        row=(row0 + row1 - 1) / 2, col=(col0 + col1 - 1) / 2, bbox=bbox, area_px=9, score=9.0, polarity="dark"
    )


def test_inspect_pair_finds_seeded_flaws_and_recovers_the_shift() -> None:
    pair = synthetic_pair((192, 224), rng=3)
    result = inspect_pair(pair.reference, pair.inspection, flaw_model="uniform")
    score = score_flaws(result.flaws, pair.centres_rc, valid=result.detection.valid)
    assert score.truth_count > 20
    assert score.recall >= 0.95
    assert score.false_alarms <= 1
    assert result.registration is not None
    np.testing.assert_allclose(result.registration.translation_xy, pair.shift_xy, atol=SHIFT_TOLERANCE_PX)
    assert result.elapsed_s > 0


def test_inspect_pair_rejects_bad_settings_naming_them() -> None:
    image = np.zeros((32, 32))
    with pytest.raises(InputError, match="p_false_alarm"):
        inspect_pair(image, image, p_false_alarm=0.7)
    with pytest.raises(InputError, match="reference"):
        inspect_pair(np.zeros(5), image)


def test_score_counts_found_missed_and_false_flaws() -> None:
    centres = np.array([[10, 10], [30, 30], [50, 50]])
    flaws = (flaw_at((9, 9, 12, 12)), flaw_at((70, 70, 73, 73)), flaw_at((31, 31, 32, 32)))
    score = score_flaws(flaws, centres)
    assert (score.truth_count, score.found_count, score.false_alarms) == (3, 2, 1)
    assert score.is_true == (True, False, True)
    assert score.recall == pytest.approx(2 / 3)
    assert score.precision == pytest.approx(2 / 3)


def test_score_ignores_truth_outside_the_valid_region_and_handles_empty_cases() -> None:
    valid = np.ones((64, 64), bool)
    valid[:, :20] = False
    score = score_flaws((), np.array([[10, 10], [40, 40]]), valid=valid)
    assert (score.truth_count, score.found_count, score.recall, score.precision) == (1, 0, 0.0, 1.0)
    assert score_flaws((), np.empty((0, 2), int)).recall == 1.0
