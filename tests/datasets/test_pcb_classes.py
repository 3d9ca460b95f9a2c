"""Defect classes from the copper's topology: each of DeepPCB's six, drawn by hand."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import pytest

from rsi.datasets.deeppcb import DEFECT_TYPES
from rsi.datasets.pcb_classes import classify_copper, classify_defects, classify_window
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
