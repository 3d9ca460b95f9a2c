"""Hand-drawn DeepPCB defects shared by the class tests (rules and learned)."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import pytest

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


@pytest.fixture
def drawn_defect() -> Callable[[str], tuple[np.ndarray, np.ndarray]]:
    """`drawn_defect(kind)`: (template, test) 40 x 40 windows with one defect of a DeepPCB class."""
    return changed
