"""DeepPCB matching rules and metrics: hand-made boxes with known answers, a fake tree, and real data."""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest

from rsi.datasets.deeppcb import load_split, read_pair
from rsi.datasets.evaluate import (
    DeepPcbSettings,
    EvaluationResult,
    MatchCounts,
    PcbDetections,
    centre_in_box,
    detect_defects,
    evaluate_pairs,
    group_defects,
    group_detection,
    iou_match,
    leave_one_group_out,
    name_defects,
    name_detection,
    predicted_template,
    register_pair,
)
from rsi.datasets.official import box_iou
from rsi.datasets.pcb_features import FEATURES
from rsi.datasets.pcb_learn import evaluate_deeppcb
from rsi.errors import InputError

REAL_ROOT = Path(__file__).resolve().parents[2].parent / "shared" / "data" / "deeppcb"

KEYS = [
    "pairs",
    "defects",
    "recall",
    "precision",
    "f1",
    "false_alarms_per_image",
    "iou_recall",
    "iou_precision",
    "seconds_per_pair",
    "official_precision",
    "official_recall",
    "official_f",
    "map",
    "per_class",
    "confusion",
    "classes",
]


def test_centre_in_box_known_answer() -> None:
    boxes = [[0, 0, 10, 10], [20, 20, 30, 30], [100, 100, 110, 110]]
    centres = [[10.0, 10.0], [25.0, 21.0], [26.0, 29.0], [50.0, 5.0], [10.5, 5.0]]
    found, false_alarm = centre_in_box(centres, boxes)
    assert found.tolist() == [True, True, False]  # corners inclusive; two centres in one box count once
    assert false_alarm.tolist() == [False, False, False, True, True]


def test_centre_in_box_empty_inputs() -> None:
    found, false_alarm = centre_in_box(np.empty((0, 2)), [[0, 0, 1, 1]])
    assert found.tolist() == [False] and false_alarm.shape == (0,)
    found, false_alarm = centre_in_box([[1.0, 1.0]], [])
    assert found.shape == (0,) and false_alarm.tolist() == [True]


@pytest.mark.parametrize(
    ("centres", "boxes"),
    [([[1.0, 2.0, 3.0]], [[0, 0, 1, 1]]), ([[1.0, 2.0]], [[0, 0, 1]]), ([[np.nan, 2.0]], [[0, 0, 1, 1]])],
)
def test_centre_in_box_rejects_bad_shapes(centres: object, boxes: object) -> None:
    with pytest.raises(InputError, match=r"must be a finite array of shape \(K, [24]\)"):
        centre_in_box(centres, boxes)


def test_box_iou_known_answers() -> None:
    # Inclusive corners: [0, 9] is 10 px. Half-overlap along x: 50 / (100 + 100 - 50) = 1/3.
    iou = box_iou([[0, 0, 9, 9], [0, 0, 9, 9]], [[0, 0, 9, 9], [5, 0, 14, 9], [20, 20, 29, 29]])
    np.testing.assert_allclose(iou, [[1.0, 1 / 3, 0.0], [1.0, 1 / 3, 0.0]])


def test_iou_match_is_one_to_one_and_strict() -> None:
    truth = [[0, 0, 9, 9], [5, 0, 14, 9]]
    detected = [[0, 0, 9, 9], [1, 0, 10, 9]]  # both overlap box 0 best; the second falls to box 1
    found, correct = iou_match(detected, truth)
    assert found.tolist() == [True, True] and correct.tolist() == [True, True]
    found, correct = iou_match([[0, 0, 9, 9]], truth, iou_threshold=0.5)
    assert found.tolist() == [True, False] and correct.tolist() == [True]
    # exactly 1/3 is not > 0.3333...: the rule is strict
    found, _ = iou_match([[5, 0, 14, 9]], [[0, 0, 9, 9]], iou_threshold=1 / 3)
    assert found.tolist() == [False]


def test_iou_match_rejects_bad_threshold() -> None:
    with pytest.raises(InputError, match="iou_threshold must be in"):
        iou_match([[0, 0, 1, 1]], [[0, 0, 1, 1]], iou_threshold=1.0)


def test_group_defects_merges_close_pieces_and_drops_small() -> None:
    mask = np.zeros((60, 60), bool)
    mask[10:14, 10:14] = True  # piece A
    mask[10:14, 17:21] = True  # piece B, 3 px gap from A
    mask[40:41, 40:41] = True  # a lone pixel
    apart = group_defects(mask)
    assert len(apart.centres_xy) == 3
    merged = group_defects(mask, merge_gap_px=4, min_area_px=2)
    np.testing.assert_allclose(merged.centres_xy, [[15.0, 11.5]])
    np.testing.assert_array_equal(merged.boxes_xyxy, [[10, 10, 20, 13]])
    grown = group_defects(mask, merge_gap_px=4, min_area_px=2, grow_px=12)
    np.testing.assert_array_equal(grown.boxes_xyxy, [[0, 0, 32, 25]])  # clipped at the image edge


def test_group_defects_empty_mask() -> None:
    found = group_defects(np.zeros((8, 8), bool), merge_gap_px=2)
    assert found.centres_xy.shape == (0, 2) and found.boxes_xyxy.shape == (0, 4)


@pytest.mark.parametrize(("argument", "value"), [("merge_gap_px", -1), ("min_area_px", 0), ("grow_px", 1.5)])
def test_group_defects_rejects_bad_arguments(argument: str, value: object) -> None:
    with pytest.raises(InputError, match=argument):
        group_defects(np.zeros((8, 8), bool), **{argument: value})  # type: ignore[arg-type]


def test_group_defects_rejects_non_2d_mask() -> None:
    with pytest.raises(InputError, match="mask must be 2-D"):
        group_defects(np.zeros((2, 8, 8), bool))


@pytest.mark.parametrize(
    ("field", "value"),
    [
        ("registration_model", "rigid"),
        ("flaw_model", "blob"),
        ("method", "median"),
        ("size", 0),
        ("p_false_alarm", 0.5),
        ("noise_sigma", 0.0),
        ("misregistration_std_px", -1.0),
        ("registration_finest_level", -1),
        ("registration_coarsest_level", 0),  # finer than the finest level (1)
        ("registration_row_step", 0),
        ("registration_photometric", "no"),
        ("registration_presmooth", 1),
        ("registration_field_tolerance_px", 0.0),
        ("merge_gap_px", -2),
        ("min_area_px", 0),
        ("border_px", -1),
        ("box_padding_px", -1),
    ],
)
def test_settings_reject_bad_values(field: str, value: object) -> None:
    with pytest.raises(InputError, match=field):
        DeepPcbSettings(**{field: value})  # type: ignore[arg-type]


def test_settings_are_frozen() -> None:
    with pytest.raises(dataclasses.FrozenInstanceError):
        DeepPcbSettings().size = 5  # type: ignore[misc]


def test_evaluate_pairs_counts_known_detections(tmp_path: Path, tree_writer: Callable[..., Path]) -> None:
    root = tree_writer(
        tmp_path,
        {
            "00041000": (
                np.zeros((8, 8), np.uint8),
                np.zeros((8, 8), np.uint8),
                "0 0 9 9 1\n20 20 29 29 2\n",
            ),
            "00041001": (np.zeros((8, 8), np.uint8), np.zeros((8, 8), np.uint8), "0 0 9 9 3\n"),
        },
    )
    answers = iter(
        [
            PcbDetections(np.array([[5.0, 5.0], [50.0, 50.0]]), np.array([[0, 0, 9, 9], [45, 45, 55, 55]])),
            PcbDetections(np.empty((0, 2)), np.empty((0, 4), np.int64)),
        ]
    )
    seen: list[tuple[str, int, int]] = []
    result = evaluate_pairs(
        load_split(root),
        lambda reference, inspection: next(answers),
        progress=lambda stage, done, total: seen.append((stage, done, total)),
    )
    assert seen == [("group00041/00041/00041000", 1, 2), ("group00041/00041/00041001", 2, 2)]
    assert (result.pairs, result.defects) == (2, 3)
    assert result.recall == pytest.approx(1 / 3) and result.precision == pytest.approx(0.5)
    assert result.f1 == pytest.approx(2 * (1 / 3) * 0.5 / (1 / 3 + 0.5))
    assert result.false_alarms_per_image == pytest.approx(0.5)
    assert result.iou_recall == pytest.approx(1 / 3) and result.iou_precision == pytest.approx(0.5)
    assert list(result.to_dict()) == KEYS


def test_evaluate_pairs_rejects_no_pairs() -> None:
    with pytest.raises(InputError, match="pairs is empty"):
        evaluate_pairs((), lambda reference, inspection: PcbDetections(np.empty((0, 2)), np.empty((0, 4))))


def test_evaluate_deeppcb_end_to_end_on_a_fake_tree(defect_tree: Path) -> None:
    root = defect_tree
    result = evaluate_deeppcb(root, "trainval", settings=DeepPcbSettings(), classes="rules")
    assert isinstance(result, EvaluationResult)
    assert (result.pairs, result.defects) == (3, 6)
    assert result.recall == 1.0 and result.false_alarms_per_image == 0.0
    assert result.iou_recall == 1.0 and result.iou_precision == 1.0
    # Each defect is named: every detection lies in the official tally, its class table and confusion.
    assert sum(row["detections"] for row in result.per_class.values()) == 6
    assert np.array(result.confusion)[1:, 1:].sum() == 6
    assert 0.0 <= result.official_f <= 1.0


def test_evaluate_deeppcb_rejects_bad_settings(tmp_path: Path) -> None:
    with pytest.raises(InputError, match="settings must be a DeepPcbSettings"):
        evaluate_deeppcb(tmp_path, "trainval", settings={"size": 3})  # type: ignore[arg-type]


def test_detect_defects_rejects_bad_images() -> None:
    with pytest.raises(InputError, match="reference must be 2-D"):
        detect_defects(np.zeros((4, 4, 3)), np.zeros((4, 4)))


def test_real_trainval_subset_meets_the_target() -> None:
    if not (REAL_ROOT / "PCBData" / "trainval.txt").is_file():
        pytest.skip(f"DeepPCB not found at {REAL_ROOT}: real-data test skipped (see its README.md there)")
    pairs = load_split(REAL_ROOT, "trainval")[::100]  # 10 pairs across all seven groups
    settings = DeepPcbSettings()
    result = evaluate_pairs(
        pairs, lambda reference, inspection: detect_defects(reference, inspection, settings=settings)
    )
    assert result.pairs == 10
    # Full trainval: see docs/deeppcb.md (benchmarks/eval_deeppcb.py).
    assert result.recall >= 0.95
    assert result.false_alarms_per_image <= 0.6  # 10 pairs: a loose bound on a noisy figure
    # The official rule needs the class too: 0.93 on these 10 pairs, 0.953 on all 1,000.
    assert result.official_f >= 0.85


@pytest.mark.parametrize("pair_name", ["20085195", "20085203", "77000016"])
def test_real_boards_where_the_field_once_drifted_keep_every_box(pair_name: str) -> None:
    # On these trainval boards the local field used to run off (to 7-43 px; a coarse level locked onto the
    # neighbouring trace) and a defect's box was lost; the field's trust region (an eighth of a tile)
    # holds it: every box is found by the official IoU rule, as the affine fit finds them. Read with the
    # square's erosion test, whose per-pixel threshold is lower than the disc's: the disc loses one faint
    # 3 px mousebite of 20085203 under the field, not by a drift (docs/deeppcb.md).
    if not (REAL_ROOT / "PCBData" / "trainval.txt").is_file():
        pytest.skip(f"DeepPCB not found at {REAL_ROOT}: real-data test skipped (see its README.md there)")
    (pair,) = [pair for pair in load_split(REAL_ROOT, "trainval") if pair.pair_id.endswith(pair_name)]
    found = detect_defects(*read_pair(pair), settings=DeepPcbSettings(flaw_model="uniform"))
    assert iou_match(found.boxes_xyxy, pair.boxes_xyxy)[0].all()


def _counts(boxes: int, found: int, detections: int, false_alarms: int) -> MatchCounts:
    return MatchCounts(pairs=10, boxes=boxes, found=found, detections=detections, false_alarms=false_alarms)


def test_leave_one_group_out_never_chooses_on_the_scored_group() -> None:
    # "loose" finds more on a and b but pays 10 false alarms per group, 110 on c: on any two groups
    # "tight" has the better F1, so it is chosen for every fold.
    counts = {
        "loose": {
            "a": _counts(100, 100, 110, 10),
            "b": _counts(100, 100, 110, 10),
            "c": _counts(100, 90, 200, 110),
        },
        "tight": {"a": _counts(100, 95, 95, 0), "b": _counts(100, 95, 95, 0), "c": _counts(100, 99, 99, 0)},
    }
    result = leave_one_group_out(counts)
    # Without a: loose on b + c has F1 0.75, tight 0.985.
    assert result.chosen == {"a": "tight", "b": "tight", "c": "tight"}
    assert result.held_out["c"] == counts["tight"]["c"]
    pooled = result.pooled.result()
    assert pooled.recall == pytest.approx((95 + 95 + 99) / 300)
    assert pooled.precision == 1.0
    assert result.pooled.pairs == 30


def test_leave_one_group_out_picks_per_fold() -> None:
    counts = {
        "x": {"a": _counts(10, 10, 10, 0), "b": _counts(10, 10, 10, 0), "c": _counts(10, 0, 10, 10)},
        "y": {"a": _counts(10, 0, 10, 10), "b": _counts(10, 9, 9, 0), "c": _counts(10, 10, 10, 0)},
    }
    result = leave_one_group_out(counts)
    assert result.chosen == {"a": "y", "b": "x", "c": "x"}
    assert result.pooled.found == 0 + 10 + 0


def test_match_counts_add_and_give_the_figures() -> None:
    total = _counts(10, 9, 12, 2) + _counts(10, 10, 10, 0)
    assert total == MatchCounts(pairs=20, boxes=20, found=19, detections=22, false_alarms=2)
    figures = total.result()
    assert figures.recall == pytest.approx(0.95)
    assert figures.precision == pytest.approx(20 / 22)
    assert figures.false_alarms_per_image == pytest.approx(0.1)


@pytest.mark.parametrize(
    "counts",
    [
        {},
        {"x": {"a": _counts(1, 1, 1, 0)}},
        {"x": {"a": _counts(1, 1, 1, 0), "b": _counts(1, 1, 1, 0)}, "y": {"a": _counts(1, 1, 1, 0)}},
    ],
)
def test_leave_one_group_out_rejects_uneven_counts(counts: dict[str, dict[str, MatchCounts]]) -> None:
    with pytest.raises(InputError, match="counts"):
        leave_one_group_out(counts)


def test_group_defects_reports_each_groups_area_and_peak_score() -> None:
    mask = np.zeros((30, 30), bool)
    mask[2:4, 2:5] = True
    mask[20:25, 20:21] = True
    score = np.zeros((30, 30))
    score[3, 4], score[22, 20] = 7.0, 5.0
    found = group_defects(mask, score=score)
    order = np.argsort(found.centres_xy[:, 0])
    np.testing.assert_array_equal(np.asarray(found.areas_px)[order], [6, 5])
    np.testing.assert_array_equal(np.asarray(found.strengths)[order], [7.0, 5.0])
    with pytest.raises(InputError, match="score"):
        group_defects(mask, score=np.zeros((4, 4)))


def _thin_scratch() -> tuple[np.ndarray, np.ndarray]:
    """Blank board, and the same with a 7 x 7 blob trailing a 1 px line 30 px long (a thin scratch)."""
    reference = np.full((120, 120), 255.0)
    inspection = reference.copy()
    inspection[50:57, 30:37] = 0.0
    inspection[53, 37:67] = 0.0
    return reference, inspection


def test_grow_to_changes_boxes_the_whole_thin_scratch() -> None:
    reference, inspection = _thin_scratch()
    grown = detect_defects(reference, inspection, settings=DeepPcbSettings())
    seeds = detect_defects(reference, inspection, settings=DeepPcbSettings(grow_to_changes=False))
    # The disc's erosion test (a plus) sees the blob and the line's first pixel, where the plus centred on
    # the blob's last column reaches (x 30-37 after the erosion's pixel is undone, +10 padding); the
    # per-pixel extent reaches the line's end at x = 66.
    np.testing.assert_array_equal(seeds.boxes_xyxy, [[20, 40, 47, 66]])
    np.testing.assert_array_equal(grown.boxes_xyxy, [[20, 40, 76, 66]])
    assert grown.features is not None and grown.features.shape == (1, FEATURES)


def test_register_pair_keeps_a_plausible_fit_and_refuses_a_wild_one() -> None:
    rng = np.random.default_rng(3)
    reference = np.where(rng.random((40, 40)) > 0.5, 255.0, 0.0).repeat(4, 0).repeat(4, 1)
    inspection = np.roll(reference, 2, axis=1)
    fit = register_pair(reference, inspection, "affine")
    assert fit.reason != "implausible"
    np.testing.assert_allclose(fit.translation_xy, (2.0, 0.0), atol=0.05)


def test_register_pair_falls_back_to_the_identity_when_no_fit_is_plausible(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    from rsi.imaging import registration

    real = registration.register
    scaled = np.diag([1.3, 1.0, 1.0])  # a 30 % scale: what a sparse board's wrong lock looked like

    def wild(*args: object, **kwargs: object) -> registration.Registration:
        fit = real(*args, **kwargs)  # type: ignore[arg-type]
        return dataclasses.replace(fit, matrix=scaled)

    monkeypatch.setattr(registration, "register", wild)
    reference = np.full((64, 64), 255.0)
    reference[20:40, 10:50] = 0.0
    fit = register_pair(reference, reference.copy(), "affine")
    assert fit.reason == "implausible" and not fit.converged
    np.testing.assert_array_equal(fit.matrix, np.eye(3))


def test_detect_defects_refuses_a_classifier_of_the_wrong_type() -> None:
    with pytest.raises(InputError, match="classifier"):
        detect_defects(np.zeros((8, 8)), np.zeros((8, 8)), classifier="forest")  # type: ignore[arg-type]


def test_predicted_template_is_the_prediction_where_valid_and_the_test_elsewhere() -> None:
    from rsi.detection.detect import detect

    # A shifted board: the warped template leaves invalid columns at one side.
    rng = np.random.default_rng(4)
    reference = np.where(rng.random((40, 40)) > 0.5, 255.0, 0.0).repeat(4, 0).repeat(4, 1).astype(np.float32)
    inspection = np.roll(reference, 3, axis=1)
    detection = detect(
        reference,
        inspection,
        flaw_model="uniform",
        method="erosion",
        noise_sigma=40.0,
        registration_model="affine",
    )
    # The erosion test's validity is narrower than the prediction's: there d is not 0, yet the template is
    # the test's own pixels.
    assert np.any(~detection.valid & (detection.difference != 0))
    expected = np.where(detection.valid, inspection - detection.difference, inspection)
    np.testing.assert_array_equal(predicted_template(detection, inspection), expected)
    with pytest.raises(InputError, match="inspection"):
        predicted_template(detection, inspection[:-1])
    with pytest.raises(InputError, match="detection"):
        predicted_template("detection", inspection)  # type: ignore[arg-type]


def test_name_detection_is_name_defects_on_the_predicted_template() -> None:
    from rsi.detection.detect import detect

    reference, inspection = _thin_scratch()
    settings = DeepPcbSettings()
    detection = detect(
        reference,
        inspection,
        flaw_model="uniform",
        method="erosion",
        noise_sigma=40.0,
        registration=None,
        misregistration_std_px=3.0,
    )
    found = group_detection(detection, settings)
    named = name_detection(found, detection, inspection)
    expected = name_defects(found, predicted_template(detection, inspection), inspection)
    assert named.features is not None and expected.features is not None
    np.testing.assert_array_equal(named.features, expected.features)
    np.testing.assert_array_equal(named.classes, expected.classes)
    with pytest.raises(InputError, match="strengths"):
        name_detection(dataclasses.replace(found, strengths=None), detection, inspection)
    with pytest.raises(InputError, match="inspection"):
        name_detection(found, detection, inspection[:-1])
    with pytest.raises(InputError, match="found"):
        name_detection("found", detection, inspection)  # type: ignore[arg-type]
