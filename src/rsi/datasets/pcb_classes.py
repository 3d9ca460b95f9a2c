"""Name a printed-circuit-board defect from the topology of the copper around it (no learning).

DeepPCB's six classes are changes of the copper's topology between the template and the tested board
(Tang et al. 2019, fig. 2). Within each detection's box, with copper the dark pixels of both binarised
images (the template brought into the tested board's frame by the registration):

- copper **added** (more copper pixels in the test than in the template):
  - it **joins** copper pieces (fewer connected pieces of copper): a *short*;
  - it is a **new piece** on its own (more pieces): *spurious copper*;
  - otherwise it grows out of a trace: a *spur*.
- copper **removed**:
  - it makes a **hole** inside copper (more pieces of board enclosed by copper): a *pin-hole*;
  - it **splits** a piece (more pieces): an *open*;
  - otherwise it bites into a trace's edge: a *mousebite*.

Pieces are 8-connected for copper and 4-connected for the board (so that a diagonal touch of copper
does not also count as a hole's wall being broken). Changed pixels are counted after a 3 x 3 opening, so
that the 1-2 px slivers left along copper edges by etching and resampling do not decide the sign.
"""

from __future__ import annotations

import cv2
import numpy as np
from numpy.typing import NDArray

from rsi._validate import as_float_array, as_image, same_shape
from rsi.errors import InputError
from rsi.imaging._components import labelled

COPPER_BELOW_DN = 127.5  # DeepPCB's images are binarised: copper dark (0), board light (255)
OPEN, SHORT, MOUSEBITE, SPUR, SPURIOUS_COPPER, PIN_HOLE = 1, 2, 3, 4, 5, 6
_OPENING = np.ones((3, 3), np.uint8)
# The confidence counts changed pixels that survive this erosion. Chosen on every 5th trainval pair among
# the opened count (mAP 0.923), the raw count (0.917) and this core (0.946); the classes are unchanged.
_CORE = np.ones((5, 5), np.uint8)
# Smallest piece of copper or board counted; DeepPCB's smallest pin-holes are ~4 px across.
_MIN_PIECE_PX = 12

IntArray = NDArray[np.int64]
FloatArray = NDArray[np.float64]


def _copper_pieces(copper: NDArray[np.uint8]) -> tuple[int, int]:
    """(copper pieces, holes): 8-connected copper components and 4-connected board components off the
    window's border, each of at least _MIN_PIECE_PX (a sliver cut off at the window's edge is no piece)."""
    pieces, holes, _ = _piece_counts(copper, 8)
    return pieces, holes


def _piece_counts(copper: NDArray[np.uint8], connectivity: int) -> tuple[int, int, int]:
    """(copper pieces, holes, copper pieces reaching the window's edge) of a 0/1 copper window.

    Copper is `connectivity`-connected (4 or 8) and the board the other way; pieces and holes are at least
    _MIN_PIECE_PX, a hole is board that never reaches the window's edge. With 4-connected copper a crack
    that leaves copper touching only at pixel corners splits a trace, and a hole whose wall is broken only
    at a corner is still a hole: binarisation leaves such contacts on many opens and pin-holes
    (:mod:`rsi.datasets.pcb_features` reads both connectivities). The third count is the copper
    pieces that do reach it: a trace running on out of the window (what an open cuts) rather than an island
    inside it (what a scratch closing on itself leaves, :mod:`rsi.datasets.pcb_features`).
    """
    pieces, reaching = _copper_counts(copper, connectivity)
    return pieces, _holes(1 - copper, 12 - connectivity), reaching


def _copper_counts(copper: NDArray[np.uint8], connectivity: int) -> tuple[int, int]:
    """(copper pieces, those reaching the window's edge) of a 0/1 copper window (:func:`_piece_counts`)."""
    # Areas from the labels (OpenCV's statistics cost more than the labelling on these small windows); a
    # window with one piece (most) has it counted directly.
    count, labels = labelled(copper, connectivity)
    if count <= 2:
        whole = count == 2 and np.count_nonzero(copper) >= _MIN_PIECE_PX
        return int(whole), int(whole and _edge_labels(labels).any())
    large = np.bincount(labels.ravel(), minlength=count) >= _MIN_PIECE_PX
    large[0] = False
    return int(np.count_nonzero(large)), int(np.count_nonzero(large & _on_edge(labels, count)))


def _holes(board: NDArray[np.uint8], connectivity: int) -> int:
    """Pieces of a 0/1 board window that never reach its edge (:func:`_piece_counts`)."""
    count, labels = labelled(board, connectivity)
    if count <= 2:
        # No board, or one piece of it: a hole only if it never reaches the window's edge.
        return int(count == 2 and not _edge_labels(labels).any() and np.count_nonzero(board) >= _MIN_PIECE_PX)
    enclosed = np.bincount(labels.ravel(), minlength=count) >= _MIN_PIECE_PX
    enclosed[0] = False
    enclosed &= ~_on_edge(labels, count)
    return int(np.count_nonzero(enclosed))


def _edge_labels(labels: NDArray[np.int32]) -> NDArray[np.int32]:
    """The labels along the window's four edges (0: background)."""
    return np.concatenate((labels[0], labels[-1], labels[:, 0], labels[:, -1]))


def _on_edge(labels: NDArray[np.int32], count: int) -> NDArray[np.bool_]:
    """For each of `count` labels, whether it reaches the window's edge."""
    reaching = np.zeros(count, dtype=bool)
    reaching[_edge_labels(labels)] = True
    return reaching


def _window(value: object, name: str) -> NDArray[np.float64]:
    """A non-empty 2-D window of grey values (one pixel wide is allowed: a box may be that thin)."""
    window = as_float_array(value, name)
    if window.ndim != 2 or window.size == 0:
        raise InputError(f"{name} must be a non-empty 2-D grey window; got shape {window.shape}.")
    return window


def _boxes_inside(boxes_xyxy: object, shape: tuple[int, ...]) -> NDArray[np.int64]:
    """Corners-inclusive boxes (D, 4) of whole pixels, each inside an image of `shape`, x1 <= x2, y1 <= y2."""
    boxes = as_float_array(boxes_xyxy, "boxes_xyxy")
    if boxes.size == 0:
        return np.empty((0, 4), dtype=np.int64)
    rows, cols = shape
    inside = (
        boxes.ndim == 2
        and boxes.shape[1] == 4
        and bool(np.all(boxes == np.round(boxes)))
        and bool(np.all((boxes[:, 0] >= 0) & (boxes[:, 0] <= boxes[:, 2]) & (boxes[:, 2] < cols)))
        and bool(np.all((boxes[:, 1] >= 0) & (boxes[:, 1] <= boxes[:, 3]) & (boxes[:, 3] < rows)))
    )
    if not inside:
        raise InputError(
            "boxes_xyxy must be whole-pixel boxes (x1, y1, x2, y2) of shape (D, 4) with "
            f"0 <= x1 <= x2 < {cols} and 0 <= y1 <= y2 < {rows}; got {boxes_xyxy!r:.80}. "
            "Clip the boxes to the image."
        )
    return boxes.astype(np.int64)


def classify_window(template: NDArray[np.floating], test: NDArray[np.floating]) -> tuple[int, float]:
    """The class of the change between two aligned grey windows, and the changed pixels (a confidence).

    Returns
    -------
    class : int
        A key of :data:`rsi.datasets.deeppcb.DEFECT_TYPES`.
    changed_px : float
        Pixels that changed copper state and survive a 5 x 5 erosion: the solid core of the change, which
        the 1-2 px slivers of etching and resampling along edges never have (the detector's own
        rationale, docs/deeppcb.md); it ranks detections for average precision.
    """
    before = (_window(template, "template") < COPPER_BELOW_DN).astype(np.uint8)
    after = (_window(test, "test") < COPPER_BELOW_DN).astype(np.uint8)
    same_shape(before, after, ("template", "test"))
    return classify_copper(before, after, _copper_pieces(before), _copper_pieces(after))


def classify_copper(
    before: NDArray[np.uint8],
    after: NDArray[np.uint8],
    pieces_before: tuple[int, int],
    pieces_after: tuple[int, int],
) -> tuple[int, float]:
    """:func:`classify_window` from the windows' copper (1) and their (pieces, holes) already counted.

    For callers that count the pieces anyway (:mod:`rsi.datasets.pcb_features`): the connected components
    are most of the time of naming a defect. Raises InputError for windows that are not equal-shaped 2-D
    0/1 uint8 arrays or counts that are not two whole numbers >= 0 each.
    """
    for window, name in ((before, "before"), (after, "after")):
        if (
            not isinstance(window, np.ndarray)
            or window.dtype != np.uint8
            or window.ndim != 2
            or window.size == 0
        ):
            raise InputError(
                f"{name} must be a non-empty 2-D uint8 array of copper (1) and board (0); got "
                f"{type(window).__name__} {getattr(window, 'shape', '')}. Threshold the grey window first."
            )
    same_shape(before, after, ("before", "after"))
    for counts, name in ((pieces_before, "pieces_before"), (pieces_after, "pieces_after")):
        if not (
            isinstance(counts, tuple)
            and len(counts) == 2
            and all(isinstance(c, (int, np.integer)) and not isinstance(c, bool) and c >= 0 for c in counts)
        ):
            raise InputError(
                f"{name} must be a (pieces, holes) tuple of two whole numbers >= 0; got {counts!r:.80}."
            )
    added, removed = after & (1 - before), before & (1 - after)
    # The windows are 0/1: pixel sums are counts.
    changed = (
        float(np.count_nonzero(added)),
        float(np.count_nonzero(removed)),
        float(np.count_nonzero(cv2.morphologyEx(added, cv2.MORPH_OPEN, _OPENING))),
        float(np.count_nonzero(cv2.morphologyEx(removed, cv2.MORPH_OPEN, _OPENING))),
    )
    return _class_of_change(changed, pieces_before, pieces_after), _core_px(before, after)


def _class_of_change(
    changed: tuple[float, float, float, float], pieces_before: tuple[int, int], pieces_after: tuple[int, int]
) -> int:
    """:func:`classify_copper`'s class from the changed pixels counted already: copper added and removed,
    raw and after the 3 x 3 opening (:mod:`rsi.datasets.pcb_features`'s first window features)."""
    added, removed = changed[2], changed[3]
    if added == removed == 0:
        # Nothing survives the opening: decide on the raw difference (a thin defect).
        added, removed = changed[0], changed[1]
    return _name(bool(added > removed), pieces_before, pieces_after)


def _core_px(before: NDArray[np.uint8], after: NDArray[np.uint8]) -> float:
    """Pixels that changed copper state and survive a 5 x 5 erosion (:func:`classify_window`'s confidence)."""
    return float(np.count_nonzero(cv2.erode(before ^ after, _CORE)))


def _name(grown: bool, before: tuple[int, int], after: tuple[int, int]) -> int:
    """The class from the sign of the change and the (pieces, holes) before and after it."""
    (pieces_before, holes_before), (pieces_after, holes_after) = before, after
    if grown:
        if pieces_after < pieces_before:
            return SHORT
        if pieces_after > pieces_before:
            return SPURIOUS_COPPER
        return SPUR
    # An open never encloses board; a pin-hole near the window's edge can cut copper in two there.
    if holes_after > holes_before:
        return PIN_HOLE
    if pieces_after > pieces_before:
        return OPEN
    return MOUSEBITE


def classify_defects(
    template: NDArray[np.floating], test: NDArray[np.floating], boxes_xyxy: NDArray[np.integer]
) -> tuple[IntArray, FloatArray]:
    """Class and confidence of each box's defect (corners-inclusive boxes in the test's pixels).

    Parameters
    ----------
    template : ndarray of shape (M, N)
        The template registered into the test's frame (grey, 0..255).
    test : ndarray of shape (M, N)
        The tested board.
    boxes_xyxy : ndarray of shape (D, 4)
        ``(x1, y1, x2, y2)`` per defect.

    Returns
    -------
    classes : ndarray of shape (D,), int64
    confidences : ndarray of shape (D,), float64
        Changed pixels in the box: bigger changes first when ranking for average precision.
    """
    template_image = as_image(template, "template")
    test_image = as_image(test, "test")
    same_shape(template_image, test_image, ("template", "test"))
    boxes = _boxes_inside(boxes_xyxy, test_image.shape)
    classes = np.zeros(len(boxes), dtype=np.int64)
    confidences = np.zeros(len(boxes), dtype=np.float64)
    for index, (x1, y1, x2, y2) in enumerate(boxes):
        window = (slice(int(y1), int(y2) + 1), slice(int(x1), int(x2) + 1))
        classes[index], confidences[index] = classify_window(template_image[window], test_image[window])
    return classes, confidences
