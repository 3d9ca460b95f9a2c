"""Defect classes from the copper's topology: each of DeepPCB's six, drawn by hand."""

from __future__ import annotations

from collections.abc import Callable

import cv2
import numpy as np
import pytest

from rsi.datasets.deeppcb import DEFECT_TYPES
from rsi.datasets.pcb_classes import (
    _copper_pieces,
    _piece_counts,
    classify_copper,
    classify_defects,
    classify_window,
)
from rsi.errors import InputError

BOARD, COPPER = 255.0, 0.0
Drawn = Callable[[str], tuple[np.ndarray, np.ndarray]]


@pytest.mark.parametrize("kind", list(DEFECT_TYPES.values()))
def test_each_class_is_named_from_its_topology(kind: str, drawn_defect: Drawn) -> None:
    template, test = drawn_defect(kind)
    cls, changed_px = classify_window(template, test)
    assert DEFECT_TYPES[cls] == kind
    assert changed_px >= 0


def test_boxes_are_classified_in_place(drawn_defect: Drawn) -> None:
    template = np.full((100, 100), BOARD)
    test = template.copy()
    template[50:90, 10:50], test[50:90, 10:50] = drawn_defect("short")
    test[5:10, 70:75] = COPPER
    classes, confidences = classify_defects(template, test, np.array([[10, 50, 49, 89], [60, 0, 85, 20]]))
    assert [DEFECT_TYPES[c] for c in classes] == ["short", "spurious copper"]
    # The 8 x 6 bridge keeps a 4 x 2 core under a 5 x 5 erosion; the 5 x 5 blob keeps its centre pixel.
    assert confidences.tolist() == [8.0, 1.0]


@pytest.mark.parametrize(
    ("arguments", "named"),
    [
        ((None, None, (1, 0), (1, 0)), "before"),
        ((np.zeros((4, 4), np.uint8), np.zeros((4, 4)), (1, 0), (1, 0)), "after"),
        ((np.zeros((4, 4), np.uint8), np.zeros((5, 4), np.uint8), (1, 0), (1, 0)), "same shape"),
        ((np.zeros((4, 4), np.uint8), np.zeros((4, 4), np.uint8), None, (1, 0)), "pieces_before"),
        ((np.zeros((4, 4), np.uint8), np.zeros((4, 4), np.uint8), (1, 0), (1, -2)), "pieces_after"),
    ],
)
def test_classify_copper_refuses_what_is_not_counted_copper(arguments: tuple, named: str) -> None:
    with pytest.raises(InputError, match=named):
        classify_copper(*arguments)


def _reaching_by_opencv_statistics(copper: np.ndarray) -> int:
    """Copper pieces of 12 px or more with a pixel on the window's edge, from OpenCV's statistics."""
    count, _, stats, _ = cv2.connectedComponentsWithStats(copper, connectivity=8)
    rows, cols = copper.shape
    left, top = stats[1:, cv2.CC_STAT_LEFT], stats[1:, cv2.CC_STAT_TOP]
    right, bottom = left + stats[1:, cv2.CC_STAT_WIDTH], top + stats[1:, cv2.CC_STAT_HEIGHT]
    # a piece touches the edge iff its bounding box does (the box's sides hold a pixel of the piece)
    on_edge = (left == 0) | (top == 0) | (right == cols) | (bottom == rows)
    return int((on_edge & (stats[1:, cv2.CC_STAT_AREA] >= 12)).sum()) if count > 1 else 0


def _pieces_by_opencv_statistics(copper: np.ndarray) -> tuple[int, int]:
    """The count as first written: OpenCV's statistics and a set of the border's labels."""
    _, _, stats, _ = cv2.connectedComponentsWithStats(copper, connectivity=8)
    pieces = int((stats[1:, cv2.CC_STAT_AREA] >= 12).sum())
    count, labels, stats, _ = cv2.connectedComponentsWithStats((1 - copper).astype(np.uint8), connectivity=4)
    edge = np.unique(np.concatenate([labels[0], labels[-1], labels[:, 0], labels[:, -1]]))
    enclosed = np.ones(count, dtype=bool)
    enclosed[[0, *edge]] = False
    return pieces, int((enclosed & (stats[:, cv2.CC_STAT_AREA] >= 12)).sum())


def test_pieces_and_holes_are_counted_as_by_opencvs_statistics() -> None:
    # _copper_pieces reads areas from the labels (faster): the same counts on random copper windows,
    # blobs and rings of every size (pieces and holes on both sides of the 12 px cut-off), views included.
    rng = np.random.default_rng(12)
    for trial in range(400):
        shape = (int(rng.integers(1, 70)), int(rng.integers(1, 70)))
        copper = (rng.random(shape) < (0.3, 0.5, 0.7, 0.0, 1.0)[trial % 5]).astype(np.uint8)
        if trial % 2:
            copper = cv2.morphologyEx(copper, cv2.MORPH_CLOSE, np.ones((3, 3), np.uint8))
        window = copper[1:, 1:] if trial % 3 == 0 and min(shape) > 1 else copper
        contiguous = np.ascontiguousarray(window)
        assert _copper_pieces(window) == _pieces_by_opencv_statistics(contiguous)
        # the pieces reaching the window's edge (the classifier's open against a closed scratch)
        assert _piece_counts(window, 8)[2] == _reaching_by_opencv_statistics(contiguous)
    # One piece of copper around one piece of board (the counted-directly case): a hole if 12 px or more.
    for side, holes in ((4, 1), (3, 0)):
        copper = np.ones((20, 20), np.uint8)
        copper[8 : 8 + side, 8 : 8 + side] = 0
        assert _copper_pieces(copper) == (1, holes) == _pieces_by_opencv_statistics(copper)
    copper[:, 0] = 0  # the board now reaches the edge too: two pieces of board, one on the edge
    assert _copper_pieces(copper) == (1, 0) == _pieces_by_opencv_statistics(copper)
