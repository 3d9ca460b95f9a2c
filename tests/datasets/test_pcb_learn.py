"""The learned defect classes: features of hand-drawn defects, labels by pairing, a fitted classifier."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any

import cv2
import numpy as np
import pytest

from rsi.datasets.deeppcb import DEFECT_TYPES, DeepPcbPair
from rsi.datasets.evaluate import PcbDetections
from rsi.datasets.pcb_classes import classify_defects
from rsi.datasets.pcb_features import (
    FEATURE_NAMES,
    FEATURES,
    defect_features,
    fit_classifier,
    opened_count,
    rule_classes,
)
from rsi.datasets.pcb_learn import evaluate_deeppcb, train_classifier, training_labels
from rsi.errors import InputError

Drawn = Callable[[str], tuple[np.ndarray, np.ndarray]]


def _features(drawn_defect: Drawn, kind: str) -> np.ndarray:
    template, test = drawn_defect(kind)
    box = np.array([[8, 8, 31, 31]])
    return defect_features(template, test, box, np.array([6.0]), np.array([30.0]))


def test_features_have_one_row_per_box(drawn_defect: Drawn) -> None:
    rows = _features(drawn_defect, "open")
    assert rows.shape == (1, FEATURES) and np.isfinite(rows).all()
    empty = defect_features(*drawn_defect("open"), np.empty((0, 4)), np.empty(0), np.empty(0))
    assert empty.shape == (0, FEATURES)


def test_the_features_hold_the_rules_naming_of_each_box(drawn_defect: Drawn) -> None:
    # name_defects reads the rules' classes from the features instead of naming every box twice: they must
    # be classify_defects' own, for every class and for boxes of several sizes (clipped at the border).
    boxes = np.array([[8, 8, 31, 31], [0, 0, 39, 39], [15, 10, 25, 20], [30, 2, 39, 12]])
    for name in DEFECT_TYPES.values():
        template, test = drawn_defect(name)
        features = defect_features(template, test, boxes, np.ones(len(boxes)), np.ones(len(boxes)))
        classes, confidences = rule_classes(features)
        expected_classes, expected_confidences = classify_defects(template, test, boxes)
        np.testing.assert_array_equal(classes, expected_classes)
        np.testing.assert_array_equal(confidences, expected_confidences)
    with pytest.raises(InputError, match="features"):
        rule_classes(np.zeros((1, 3)))


def test_a_crack_touching_at_pixel_corners_splits_the_trace_in_the_tight_counts() -> None:
    # A trace (copper dark) cut by a one-pixel diagonal crack of board: its two sides still touch at pixel
    # corners, so the 8-connected rules see one piece and a mousebite; 4-connected copper sees the open.
    template = np.full((40, 40), 255.0)
    template[15:25] = 0.0
    test = template.copy()
    for row in range(15, 25):
        test[row, row + 5] = 255.0
    box = np.array([[10, 10, 29, 29]])
    features = defect_features(template, test, box, np.array([6.0]), np.array([10.0]))
    classes, _ = rule_classes(features)
    assert DEFECT_TYPES[int(classes[0])] == "mousebite"
    tight = [
        f"box_tight_{kind}_{when}" for kind in ("pieces", "holes") for when in ("before", "after", "change")
    ]
    np.testing.assert_array_equal(_columns(features, tight), [1.0, 2.0, 1.0, 0.0, 0.0, 0.0])


def _columns(features: np.ndarray, names: list[str]) -> np.ndarray:
    return features[0, [FEATURE_NAMES.index(name) for name in names]]


def _trace_box_features(test_drawn: Callable[[np.ndarray], None]) -> np.ndarray:
    """The features of the box over the middle of a 20 px horizontal trace (copper dark) on a 40 px board,
    against a copy of it changed by `test_drawn`."""
    template = np.full((40, 40), 255.0)
    template[10:30] = 0.0
    test = template.copy()
    test_drawn(test)
    box = np.array([[10, 10, 29, 29]])
    return defect_features(template, test, box, np.array([6.0]), np.array([40.0]))


def test_an_open_reaches_the_window_s_edge_and_a_scratch_loop_does_not() -> None:
    # Both split copper into two pieces; only the open's two pieces run on out of the window (a trace cut
    # across), the loop's island stays inside it (a scratch closed on itself inside a pad).
    def cut(test: np.ndarray) -> None:
        test[10:30, 19:21] = 255.0

    def looped(test: np.ndarray) -> None:
        test[14:26, 14:26] = 255.0
        test[16:24, 16:24] = 0.0

    reaching = [
        f"box_{prefix}reaching_{when}" for prefix in ("", "tight_") for when in ("before", "after", "change")
    ]
    pieces = ["box_pieces_before", "box_pieces_after", "box_pieces_change"]
    for drawn, reached in ((cut, [1.0, 2.0, 1.0]), (looped, [1.0, 1.0, 0.0])):
        features = _trace_box_features(drawn)
        np.testing.assert_array_equal(_columns(features, pieces), [1.0, 2.0, 1.0])
        np.testing.assert_array_equal(_columns(features, reaching), reached * 2)


def test_a_cut_leaving_a_one_pixel_sliver_splits_the_copper_s_bulk_and_a_bite_does_not() -> None:
    # A 20 px trace (copper dark) cut across but for a one-pixel sliver along its lower edge: the piece counts
    # (both connectivities) still see one trace and the rules a mousebite; without its slivers the copper's
    # bulk is two pieces, both running on out of the window. A bite 8 px deep leaves the bulk whole.
    def cut(test: np.ndarray) -> None:
        test[10:29, 19:21] = 255.0

    def bitten(test: np.ndarray) -> None:
        test[10:18, 17:23] = 255.0

    bulk = [f"box_bulk_reaching_{when}" for when in ("before", "after", "change")]
    pieces = ["box_pieces_change", "box_tight_pieces_change"]
    for drawn, reached in ((cut, [1.0, 2.0, 1.0]), (bitten, [1.0, 1.0, 0.0])):
        features = _trace_box_features(drawn)
        assert DEFECT_TYPES[int(rule_classes(features)[0][0])] == "mousebite"
        np.testing.assert_array_equal(_columns(features, pieces), [0.0, 0.0])
        np.testing.assert_array_equal(_columns(features, bulk), reached)


def test_the_feature_names_are_one_per_column_and_unique() -> None:
    assert len(FEATURE_NAMES) == FEATURES == len(set(FEATURE_NAMES))


def test_a_classifier_learns_the_six_hand_drawn_classes(drawn_defect: Drawn) -> None:
    rng = np.random.default_rng(0)
    kinds = list(DEFECT_TYPES.items())
    table = np.concatenate([_features(drawn_defect, name) for _, name in kinds])
    # Repeat each class with jittered sizes so that the boosting has several rows per class.
    features = np.repeat(table, 10, axis=0) * rng.uniform(0.95, 1.05, (10 * len(kinds), FEATURES))
    labels = np.repeat([cls for cls, _ in kinds], 10)
    classifier = fit_classifier(features, labels)
    classes, confidences = classifier.predict(table)
    np.testing.assert_array_equal(classes, [cls for cls, _ in kinds])
    assert np.all((confidences > 0.5) & (confidences <= 1.0))
    assert classifier.predict(np.empty((0, FEATURES)))[0].shape == (0,)


def test_training_labels_pair_each_detection_with_its_box() -> None:
    pair = DeepPcbPair(
        "g/1",
        Path("t.jpg"),
        Path("i.jpg"),
        Path("a.txt"),
        np.array([[0, 0, 20, 20], [50, 50, 70, 70]]),
        np.array([3, 5]),
    )
    found = PcbDetections(
        np.zeros((3, 2)), np.array([[52, 52, 72, 72], [1, 1, 21, 21], [200, 200, 220, 220]])
    )
    np.testing.assert_array_equal(training_labels(pair, found), [5, 3, 0])


@pytest.mark.parametrize(
    ("features", "labels", "message"),
    [
        (np.zeros((2, FEATURES)), [1], "one class 0-6 per row"),
        (np.zeros((2, FEATURES)), [1, 9], "one class 0-6 per row"),
        (np.zeros((2, FEATURES)), [0, 0], "name no defect"),
        (np.zeros((2, 3)), [1, 2], "shape"),
    ],
)
def test_fit_classifier_refuses_bad_training_data(features: object, labels: object, message: str) -> None:
    with pytest.raises(InputError, match=message):
        fit_classifier(features, labels)


def test_train_classifier_refuses_what_is_not_a_list_of_pairs() -> None:
    for pairs in ("trainval", []):
        with pytest.raises(InputError, match="pairs must be a non-empty list of DeepPcbPair"):
            train_classifier(pairs)  # type: ignore[arg-type]


def test_the_opened_count_skips_only_openings_that_are_empty() -> None:
    # opened_count skips the opening when too few pixels are set for any to survive the erosion (a corner's
    # worth): the same counts as OpenCV's opening on random windows of every shape, one pixel thin included.
    rng = np.random.default_rng(14)
    square = np.ones((3, 3), np.uint8)
    for trial in range(3000):
        shape = (int(rng.integers(1, 9)), int(rng.integers(1, 9)))
        change = np.zeros(shape, np.uint8)
        spots = rng.integers(0, change.size, int(rng.integers(0, 6)))
        change.flat[spots] = 1
        if trial % 3 == 0:
            change[: int(rng.integers(1, 3)), : int(rng.integers(1, 3))] = 1  # a block in the corner
        expected = float(np.count_nonzero(cv2.morphologyEx(change, cv2.MORPH_OPEN, square)))
        assert opened_count(change, int(np.count_nonzero(change))) == expected


@pytest.mark.parametrize(
    ("change", "count", "named"),
    [
        (np.zeros((4, 4), np.float32), 0, "change"),
        (np.zeros(4, np.uint8), 0, "change"),
        ([[0, 1]], 1, "change"),
        (np.zeros((4, 4), np.uint8), -1, "count"),
        (np.zeros((4, 4), np.uint8), 2.5, "count"),
        (np.zeros((4, 4), np.uint8), True, "count"),
    ],
)
def test_the_opened_count_refuses_what_is_no_window_or_no_count(change: Any, count: Any, named: str) -> None:
    with pytest.raises(InputError, match=named):
        opened_count(change, count)


def test_learned_classes_name_every_split_with_a_classifier_that_never_saw_it(two_group_tree: Path) -> None:
    rules = evaluate_deeppcb(two_group_tree, "trainval", classes="rules")
    cross_fitted = evaluate_deeppcb(two_group_tree, "trainval")
    assert cross_fitted.classes == "learned (fitted on the other board groups)" and rules.classes == "rules"
    # The classifier names the detector's detections: the class-agnostic figures cannot move.
    assert (cross_fitted.recall, cross_fitted.iou_recall) == (rules.recall, rules.iou_recall) == (1.0, 1.0)
    assert cross_fitted.official_f == 1.0
    stages: list[str] = []
    test = evaluate_deeppcb(two_group_tree, "test", progress=lambda stage, done, total: stages.append(stage))
    assert test.classes == "learned (fitted on trainval)" and (test.pairs, test.official_f) == (2, 1.0)
    assert [stage.split()[0] for stage in stages] == ["training"] * 40 + ["scoring"] * 2


def test_learned_classes_need_two_groups_two_classes_and_a_callable_progress(
    defect_tree: Path, two_group_tree: Path
) -> None:
    with pytest.raises(InputError, match="holds only"):
        evaluate_deeppcb(defect_tree, "trainval")  # one board group: nothing to cross-fit on
    with pytest.raises(InputError, match="one class only"):
        fit_classifier(np.zeros((2, FEATURES)), [5, 5])
    with pytest.raises(InputError, match="progress must be a function"):
        evaluate_deeppcb(two_group_tree, "trainval", progress="bar")  # type: ignore[arg-type]
    with pytest.raises(InputError, match=r"classes='deep' is not known"):
        evaluate_deeppcb(two_group_tree, "trainval", classes="deep")
