"""Defect classes from the copper's topology: each of DeepPCB's six, drawn by hand."""

from __future__ import annotations

import numpy as np
import pytest

from rsi.datasets.deeppcb import DEFECT_TYPES
from rsi.datasets.pcb_classes import classify_defects, classify_window

BOARD, COPPER = 255.0, 0.0


def two_traces() -> np.ndarray:
    """A 40 x 40 window: two horizontal traces 8 px wide, 8 px apart, across the whole window."""
    window = np.full((40, 40), BOARD)
    window[8:16, :] = COPPER
    window[24:32, :] = COPPER
    return window


def pad() -> np.ndarray:
    """A 40 x 40 window of solid copper around a small board margin."""
    window = np.full((40, 40), BOARD)
    window[4:36, 4:36] = COPPER
    return window


def changed(kind: str) -> tuple[np.ndarray, np.ndarray]:
    if kind == "pin-hole":
        template = pad()
        test = template.copy()
        test[18:23, 18:23] = BOARD
        return template, test
    template = two_traces()
    test = template.copy()
    if kind == "open":
        test[8:16, 18:24] = BOARD  # the upper trace cut through
    elif kind == "short":
        test[16:24, 18:24] = COPPER  # a bridge between the traces
    elif kind == "mousebite":
        test[8:12, 18:24] = BOARD  # half the trace's width bitten away
    elif kind == "spur":
        test[16:20, 18:24] = COPPER  # a stub growing towards the other trace, not reaching it
    elif kind == "spurious copper":
        test[34:39, 18:24] = COPPER  # a lone blob on the board
    return template, test


@pytest.mark.parametrize("kind", list(DEFECT_TYPES.values()))
def test_each_class_is_named_from_its_topology(kind: str) -> None:
    template, test = changed(kind)
    cls, changed_px = classify_window(template, test)
    assert DEFECT_TYPES[cls] == kind
    assert changed_px >= 0


def test_boxes_are_classified_in_place() -> None:
    template = np.full((100, 100), BOARD)
    test = template.copy()
    template[50:90, 10:50] = two_traces()
    test[50:90, 10:50] = changed("short")[1]
    test[5:10, 70:75] = COPPER
    classes, confidences = classify_defects(template, test, np.array([[10, 50, 49, 89], [60, 0, 85, 20]]))
    assert [DEFECT_TYPES[c] for c in classes] == ["short", "spurious copper"]
    # The 8 x 6 bridge keeps a 4 x 2 core under a 5 x 5 erosion; the 5 x 5 blob keeps its centre pixel.
    assert confidences.tolist() == [8.0, 1.0]
