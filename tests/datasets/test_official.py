"""DeepPCB's official rule (IoU > 0.33, same class) and its AP, on hand-worked cases."""

from __future__ import annotations

import numpy as np
import pytest

from rsi.datasets.official import OfficialTally, average_precision, pair_official

# Two boxes: an open (1) and a short (2), 10 x 10 px each.
TRUTH = np.array([[0, 0, 9, 9], [20, 20, 29, 29]])
TRUTH_CLASSES = np.array([1, 2])


def test_pairs_need_the_same_class_and_iou_above_a_third() -> None:
    detected = np.array([[0, 0, 9, 9], [20, 20, 29, 29], [21, 21, 30, 30]])
    # The second detection lies on the short but says "open"; the third overlaps it by 81 / 119 = 0.68.
    found, correct = pair_official(TRUTH, TRUTH_CLASSES, detected, [1, 1, 2])
    assert found.tolist() == [True, True]
    assert correct.tolist() == [True, False, True]
    # IoU of a 10 x 10 box shifted by 5 px in x and y: 25 / 175 = 0.14 < 0.33: no pair.
    found, correct = pair_official(TRUTH, TRUTH_CLASSES, [[5, 5, 14, 14]], [1])
    assert found.tolist() == [False, False]
    assert correct.tolist() == [False]


def test_pairing_is_first_come_not_best_iou() -> None:
    # Both detections overlap the box above 0.33; the first in order takes it, the better second is unpaired.
    detected = np.array([[0, 0, 9, 13], [0, 0, 9, 9]])
    found, correct = pair_official(TRUTH[:1], [1], detected, [1, 1])
    assert found.tolist() == [True]
    assert correct.tolist() == [True, False]


def test_average_precision_by_hand() -> None:
    # Two boxes of a class; detections by confidence: miss (0.9), hit (0.8), hit (0.3):
    # precision at the hits 1/2 and 2/3, summed and divided by the 2 boxes: 7/12.
    assert average_precision([0.3, 0.9, 0.8], [True, False, True], 2) == pytest.approx(7 / 12)
    assert average_precision([0.5], [True], 4) == pytest.approx(0.25)
    assert average_precision([], [], 3) == 0.0
    assert average_precision([0.5], [True], 0) == 0.0


def test_tally_gives_the_official_figures_and_the_confusion() -> None:
    tally = OfficialTally()
    detected = np.array([[0, 0, 9, 9], [20, 20, 29, 29], [60, 60, 69, 69]])
    tally.add(TRUTH, TRUTH_CLASSES, detected, [1, 1, 6], [0.9, 0.8, 0.1])
    figures = tally.figures()
    # One of three detections is paired (the open); one of two boxes found.
    assert figures["official_precision"] == pytest.approx(1 / 3)
    assert figures["official_recall"] == pytest.approx(1 / 2)
    assert figures["official_f"] == pytest.approx(2 * (1 / 3) * (1 / 2) / (1 / 3 + 1 / 2))
    per_class = figures["per_class"]
    assert isinstance(per_class, dict)
    assert per_class["open"]["ap"] == pytest.approx(1.0)
    assert per_class["short"]["ap"] == 0.0
    # mAP over the classes with boxes (open, short): (1 + 0) / 2.
    assert figures["map"] == pytest.approx(0.5)
    confusion = np.array(figures["confusion"])
    assert confusion[1, 1] == 1  # the open, called open
    assert confusion[2, 1] == 1  # the short, called open
    assert confusion[0, 6] == 1  # a pin-hole where there is nothing
    assert confusion.sum() == 3


def test_tallies_add_up_to_the_tally_of_all_images() -> None:
    first, second, both = OfficialTally(), OfficialTally(), OfficialTally()
    images = [
        (TRUTH, TRUTH_CLASSES, np.array([[0, 0, 9, 9]]), [1], [0.5]),
        (TRUTH, TRUTH_CLASSES, np.array([[20, 20, 29, 29], [50, 50, 59, 59]]), [2, 3], [0.9, 0.2]),
    ]
    first.add(*images[0])
    second.add(*images[1])
    for image in images:
        both.add(*image)
    assert (first + second).figures() == both.figures()
