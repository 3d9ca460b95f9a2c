"""Topology features of DeepPCB detections, and the small classical classifier that names them from those
(issue 12, item 3).

The topology rules of :mod:`rsi.datasets.pcb_classes` decide on one window with hard cut-offs; the boundary
between an open and a mousebite (does the bite cut the trace inside the window?) and between a removal
and a pin-hole depends on the window's size and on slivers. Here the same quantities, measured at three
window sizes, with the copper around the change and the trace width at it, feed scikit-learn's
histogram gradient boosting (default settings, nothing tuned). The probability of the predicted class
ranks the detections for average precision. Training it on a split's detections, and the figures of a
split named by it, are :mod:`rsi.datasets.pcb_learn`'s.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import cv2
import numpy as np
from numpy.typing import NDArray

from rsi._validate import as_float_array, as_image, same_shape
from rsi.datasets.pcb_classes import (
    COPPER_BELOW_DN,
    _boxes_inside,
    _class_of_change,
    _copper_counts,
    _core_px,
    _piece_counts,
)
from rsi.errors import InputError
from rsi.imaging._components import labelled

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]

_SQUARE = np.ones((3, 3), np.uint8)
# Windows around each box: shrunk by 7 px (the defect alone, DeepPCB pads by 10), the box, grown by 10 px.
_WINDOW_GROWTH_PX = (-7, 0, 10)
_MIN_WINDOW_PX = 2
_WINDOW_NAMES = ("shrunk", "box", "grown")
_CHANGE_COLUMNS = (
    "added_px",
    "removed_px",
    "added_opened_px",
    "removed_opened_px",
    "pieces_before",
    "pieces_after",
    "holes_before",
    "holes_after",
    "pieces_change",
    "holes_change",
    "copper_share",
)
_SURROUNDING_COLUMNS = (
    "added_touching_copper_share",
    "added_copper_contacts",
    "removed_touching_board_share",
    "removed_board_contacts",
    "removed_copper_width_px",
    "added_board_width_px",
    "rule_class",
    "rule_core_px",
)
_TIGHT_COLUMNS = tuple(
    f"tight_{kind}_{when}" for kind in ("pieces", "holes") for when in ("before", "after", "change")
)
_REACHING_COLUMNS = tuple(
    f"{prefix}reaching_{when}" for prefix in ("", "tight_") for when in ("before", "after", "change")
)
_BULK_COLUMNS = tuple(f"bulk_reaching_{when}" for when in ("before", "after", "change"))
# The columns of defect_features, in order: the box, each window's change (the box window's followed by its
# surroundings and the topology rules' naming of it, classify_window), then each window's counts with the
# connectivities swapped (_tight_features), its pieces reaching the window's edge (_reaching_features) and
# those of its copper without its slivers (_bulk_features).
FEATURE_NAMES: tuple[str, ...] = (
    "box_width_px",
    "box_height_px",
    "strength",
    "area_px",
    *(f"shrunk_{column}" for column in _CHANGE_COLUMNS),
    *(f"box_{column}" for column in _CHANGE_COLUMNS + _SURROUNDING_COLUMNS),
    *(f"grown_{column}" for column in _CHANGE_COLUMNS),
    *(f"{window}_{column}" for window in _WINDOW_NAMES for column in _TIGHT_COLUMNS),
    *(f"{window}_{column}" for window in _WINDOW_NAMES for column in _REACHING_COLUMNS),
    *(f"{window}_{column}" for window in _WINDOW_NAMES for column in _BULK_COLUMNS),
)
FEATURES = len(FEATURE_NAMES)  # columns of defect_features
_RULE_COLUMN = FEATURE_NAMES.index("box_rule_class")
# Columns the classifier learns from: all but the box's width and height (the first two). An absolute box
# size is the board's more than the class's (group 44000's scratch strands merge into long boxes): with them
# the boosting extrapolated, and a small change of the detector collapsed 44000's leave-one-group-out fold
# (official F 0.945 -> 0.57); without them no collapse on five detector variants (docs/deeppcb.md).
_LEARNED_COLUMNS = np.arange(2, FEATURES)


def _window_features(
    before: NDArray[np.uint8],
    after: NDArray[np.uint8],
    changes: tuple[NDArray[np.uint8], NDArray[np.uint8]],
    pieces: tuple[tuple[int, int], tuple[int, int]],
) -> list[float]:
    """Changed copper (raw and after a 3x3 opening) and the (pieces, holes) before and after; `changes` are
    the copper added and removed."""
    added, removed = changes
    counts = (int(np.count_nonzero(added)), int(np.count_nonzero(removed)))
    (pieces_before, holes_before), (pieces_after, holes_after) = pieces
    # The windows are 0/1: sums are counts (and the mean the count over the size, as numpy divides it).
    return [
        float(counts[0]),
        float(counts[1]),
        opened_count(added, counts[0]),
        opened_count(removed, counts[1]),
        pieces_before,
        pieces_after,
        holes_before,
        holes_after,
        pieces_after - pieces_before,
        holes_after - holes_before,
        np.count_nonzero(before) / before.size,
    ]


def opened_count(change: NDArray[np.uint8], count: int) -> float:
    """Pixels of the 3 x 3 opening of a 0/1 window holding `count` set pixels.

    OpenCV's erosion reads only the pixels inside the window, and every pixel has at least a corner's
    worth of them (2 x 2, fewer on a window one pixel thin), all of which must be set for it to survive:
    with fewer set pixels than that the opening is empty, and is not computed (a third of a DeepPCB pair's
    openings: the slivers on a defect's other side).
    """
    if not isinstance(change, np.ndarray) or change.ndim != 2 or change.dtype != np.uint8:
        raise InputError(
            f"change must be a 2-D uint8 array of 0 and 1; got {type(change).__name__} "
            f"{getattr(change, 'dtype', '')} with shape {getattr(change, 'shape', None)}."
        )
    if isinstance(count, bool) or not isinstance(count, (int, np.integer)) or count < 0:
        raise InputError(f"count must be a non-negative int (the window's set pixels); got {count!r}.")
    corner = min(change.shape[0], 2) * min(change.shape[1], 2)
    if count < corner:
        return 0.0
    return float(np.count_nonzero(cv2.morphologyEx(change, cv2.MORPH_OPEN, _SQUARE)))


_Counts = tuple[int, int, int]  # (copper pieces, holes, copper pieces reaching the window's edge)


def _tight_features(before: _Counts, after: _Counts) -> list[float]:
    """Copper pieces and holes before and after with 4-connected copper and 8-connected board, and their
    changes: a crack that leaves the two sides of an open touching at a pixel corner, or a pin-hole whose
    wall binarisation broke at a corner, shows here and not in :func:`_window_features`' counts.

    Leave-one-group-out over trainval's seven board groups (each fold's classifier fitted on the other
    six, one cached detector pass): pin-holes named mousebites 11 -> 0, opens named mousebites 16 -> 14,
    official F 0.984 -> 0.988, mAP 0.983 -> 0.986 (docs/deeppcb.md).
    """
    (pieces_before, holes_before, _), (pieces_after, holes_after, _) = before, after
    return [
        float(pieces_before),
        float(pieces_after),
        float(pieces_after - pieces_before),
        float(holes_before),
        float(holes_after),
        float(holes_after - holes_before),
    ]


def _reaching_features(loose: tuple[_Counts, _Counts], tight: tuple[_Counts, _Counts]) -> list[float]:
    """Copper pieces reaching the window's edge before and after, and their change, with 8- and with
    4-connected copper (`loose`, `tight`: the window's counts before and after).

    An open cuts a trace that runs on out of the window on both sides: one more piece reaches the edge. A
    scratch that closes on itself, or a bite that cuts a sliver off a pad, leaves an island inside the window
    instead: the piece counts go up as for an open, the reaching ones do not. Leave-one-group-out on three
    cached detector variants (the default, a 2.5 px floor, the affine fit; each fold's classifier fitted on
    the other six groups): mAP +0.0005 to +0.0009, official F +0.0008 to +0.0009, the final held-out group
    50600's mAP up in all three (docs/deeppcb.md, "Copper that reaches the window's edge").
    """
    features = []
    for before, after in (loose, tight):
        features += [float(before[2]), float(after[2]), float(after[2] - before[2])]
    return features


def _bulk_features(bulk_before: NDArray[np.uint8], bulk_after: NDArray[np.uint8]) -> list[float]:
    """Pieces of the copper's bulk (the copper eroded by a 3 x 3 square) reaching the window's edge before and
    after, and their change.

    A cut across a trace that leaves a sliver of copper one or two pixels wide is an open to DeepPCB's
    annotators (and, electrically, all but one), yet the piece counts see one trace and the rules a
    mousebite. The erosion takes slivers of up to two pixels away and leaves every trace wider than that,
    so the cut trace's two sides reach the window's edge as two pieces of bulk; a bite into the edge
    leaves one. Nothing tuned: the smallest square there is. Leave-one-group-out on three cached detector
    variants (the default, a 2.5 px floor, the affine fit; each fold's classifier fitted on the other six
    groups): mAP +0.0010 to +0.0012, official F +0.0007 to +0.0010, opens named mousebites 24 -> 21 on the
    default (docs/deeppcb.md, "The copper's bulk").
    """
    before, after = (_copper_counts(bulk, 8)[1] for bulk in (bulk_before, bulk_after))
    return [float(before), float(after), float(after - before)]


def _surroundings(
    before: NDArray[np.uint8], changes: tuple[NDArray[np.uint8], NDArray[np.uint8]]
) -> list[float]:
    """What surrounds the change (copper added, removed) in the template: a spur touches copper once, a
    short twice, spurious copper never; a pin-hole is all copper around, a mousebite board on one side, an
    open on two."""
    added, removed = changes
    board = 1 - before
    features = []
    for change, around in ((added, before), (removed, board)):
        ring = np.asarray(cv2.dilate(change, _SQUARE), dtype=np.uint8) & (1 - change)
        touching = around & ring  # 0/1 uint8
        touched = np.count_nonzero(touching)
        # No pixel touched: no piece of it either (no labelling to run).
        pieces = labelled(touching, 8)[0] - 1 if touched else 0
        features += [float(touched) / max(float(np.count_nonzero(ring)), 1.0), float(pieces)]
    # Width of the copper a removal bites into, and of the board an addition grows into.
    for change, material in ((removed, before), (added, board)):
        if not change.any():  # nothing changed this way: no width, and no transform to compute
            features.append(0.0)
            continue
        distance = cv2.distanceTransform(material, cv2.DIST_L2, 3)  # 0/1 uint8 already
        features.append(float(distance[change > 0].max()))
    return features


def _box_features(
    template: NDArray[np.floating],
    test: NDArray[np.floating],
    box: NDArray[np.int64],
    strength: float,
    area: float,
) -> list[float]:
    x1, y1, x2, y2 = (int(value) for value in box)
    rows, cols = test.shape
    features = [float(x2 - x1), float(y2 - y1), strength, area]
    # Every window lies in the largest (the box grown by the largest growth, clipped): copper is found there
    # once and each window is a view of it.
    grown = max(_WINDOW_GROWTH_PX)
    outer_top, outer_left = max(0, y1 - grown), max(0, x1 - grown)
    outer = (
        slice(outer_top, min(rows, y2 + 1 + grown)),
        slice(outer_left, min(cols, x2 + 1 + grown)),
    )
    copper_before = (template[outer] < COPPER_BELOW_DN).astype(np.uint8)
    copper_after = (test[outer] < COPPER_BELOW_DN).astype(np.uint8)
    # Eroded over the largest window, so that a window's edge does not thin the copper that runs on past it.
    bulk_before, bulk_after = (
        np.asarray(cv2.erode(copper, _SQUARE), dtype=np.uint8) for copper in (copper_before, copper_after)
    )
    tight: list[float] = []
    reaching: list[float] = []
    bulk: list[float] = []
    for growth in _WINDOW_GROWTH_PX:
        top, bottom = max(0, y1 - growth), min(rows, y2 + 1 + growth)
        left, right = max(0, x1 - growth), min(cols, x2 + 1 + growth)
        if bottom - top < _MIN_WINDOW_PX or right - left < _MIN_WINDOW_PX:
            top, bottom, left, right = y1, y2 + 1, x1, x2 + 1
        window = (
            slice(top - outer_top, bottom - outer_top),
            slice(left - outer_left, right - outer_left),
        )
        before, after = copper_before[window], copper_after[window]
        loose = (_piece_counts(before, 8), _piece_counts(after, 8))
        tight_counts = (_piece_counts(before, 4), _piece_counts(after, 4))
        pieces = (loose[0][:2], loose[1][:2])
        changes = (after & (1 - before), before & (1 - after))
        counted = _window_features(before, after, changes, pieces)
        features += counted
        tight += _tight_features(*tight_counts)
        reaching += _reaching_features(loose, tight_counts)
        bulk += _bulk_features(bulk_before[window], bulk_after[window])
        if growth == 0:
            features += _surroundings(before, changes)
            # The rules' class on the same window, pieces and changes (classify_window, counted once).
            rule = _class_of_change((counted[0], counted[1], counted[2], counted[3]), *pieces)
            features += [float(rule), _core_px(before, after)]
    return features + tight + reaching + bulk


def defect_features(
    template: NDArray[np.floating],
    test: NDArray[np.floating],
    boxes_xyxy: NDArray[np.integer],
    strengths: NDArray[np.floating],
    areas: NDArray[np.floating],
) -> FloatArray:
    """Topology features of each detection (rows) for :class:`DefectClassifier`.

    Parameters
    ----------
    template, test : ndarray of shape (M, N)
        The registered template and the tested board (grey, 0..255).
    boxes_xyxy : ndarray of shape (D, 4)
        Corners-inclusive boxes inside the image.
    strengths, areas : ndarray of shape (D,)
        The detection's largest |test statistic| and its pixel count.

    Returns
    -------
    ndarray of shape (D, FEATURES), float64
    """
    template_image = as_image(template, "template")
    test_image = as_image(test, "test")
    same_shape(template_image, test_image, ("template", "test"))
    return _checked_features(template_image, test_image, boxes_xyxy, strengths, areas)


def _checked_features(
    template: NDArray[np.floating],
    test: NDArray[np.floating],
    boxes_xyxy: NDArray[np.integer],
    strengths: object,
    areas: object,
) -> FloatArray:
    """:func:`defect_features` of images already checked (2-D, finite, the same shape): the boxes and the
    per-box values are still checked."""
    template_image, test_image = template, test
    boxes = _boxes_inside(boxes_xyxy, test_image.shape)
    strength_values = as_float_array(strengths, "strengths").reshape(-1)
    area_values = as_float_array(areas, "areas").reshape(-1)
    if strength_values.size != len(boxes) or area_values.size != len(boxes):
        raise InputError(
            f"strengths and areas must hold one value per box ({len(boxes)}); got {strength_values.size} "
            f"and {area_values.size}."
        )
    rows = [
        _box_features(template_image, test_image, box, float(strength), float(area))
        for box, strength, area in zip(boxes, strength_values, area_values, strict=True)
    ]
    return np.array(rows, dtype=np.float64).reshape(len(boxes), FEATURES)


def rule_classes(features: object) -> tuple[IntArray, FloatArray]:
    """The topology rules' classes and confidences, read from :func:`defect_features`' columns.

    They equal :func:`rsi.datasets.pcb_classes.classify_defects` on the same boxes (the features hold
    its :func:`~rsi.datasets.pcb_classes.classify_window` of each box), without naming every box again.
    """
    table = _as_features(features, "features")
    return table[:, _RULE_COLUMN].astype(np.int64), table[:, _RULE_COLUMN + 1].copy()


def _as_features(features: object, name: str) -> FloatArray:
    table = as_float_array(features, name)
    if table.ndim != 2 or table.shape[1] != FEATURES or not np.isfinite(table).all():
        raise InputError(
            f"{name} must be a finite array of shape (D, {FEATURES}) from defect_features; "
            f"got shape {table.shape}."
        )
    return table


@dataclass(frozen=True)
class DefectClassifier:
    """A fitted classifier: :meth:`predict` names defects and scores them for average precision."""

    model: Any  # sklearn.ensemble.HistGradientBoostingClassifier, fitted

    def predict(self, features: object) -> tuple[IntArray, FloatArray]:
        """Class (1-6, never 0) of each row and its probability (the confidence).

        A detection is always named (it was detected); "no defect" only lowers its confidence.
        """
        table = _as_features(features, "features")
        if len(table) == 0:
            return np.zeros(0, dtype=np.int64), np.zeros(0, dtype=np.float64)
        probabilities = np.zeros((len(table), 7))
        probabilities[:, self.model.classes_] = self.model.predict_proba(table[:, _LEARNED_COLUMNS])
        named = 1 + np.argmax(probabilities[:, 1:], axis=1)
        return named.astype(np.int64), probabilities[np.arange(len(table)), named]


def fit_classifier(features: object, labels: object) -> DefectClassifier:
    """Fit on training detections: `labels` 0 (no defect) or a DeepPCB class 1-6 per row of `features`.

    Raises
    ------
    InputError
        If the rows and labels disagree, a label is outside 0-6, or no row carries a defect class.
    """
    from sklearn.ensemble import HistGradientBoostingClassifier

    table = _as_features(features, "features")
    classes = as_float_array(labels, "labels").reshape(-1)
    if classes.size != len(table) or not np.all(np.isin(classes, np.arange(7))):
        raise InputError(
            f"labels must hold one class 0-6 per row of features ({len(table)}); got {labels!r:.80}."
        )
    if not np.any(classes > 0):
        raise InputError("labels name no defect (all 0); pass detections paired with ground-truth boxes.")
    if np.unique(classes).size < 2:
        raise InputError(
            f"labels hold one class only ({int(classes[0])}): nothing to tell apart. Train on detections of "
            "several defect classes, or name defects by the topology rules (classes='rules')."
        )
    model = HistGradientBoostingClassifier(random_state=0).fit(
        table[:, _LEARNED_COLUMNS], classes.astype(np.int64)
    )
    return DefectClassifier(model)
