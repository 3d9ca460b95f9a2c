"""Components of a sparse mask as its pixels, on its box and occupied rows: the whole frame's, bit for bit."""

from __future__ import annotations

import cv2
import numpy as np

from rsi.imaging._components import (
    component_stats,
    flat_nonzero,
    kept_rows,
    labelled,
    nonzero_pixels,
    occupied,
    pixel_components,
)


def _sparse_mask(rng: np.random.Generator, shape: tuple[int, int], blobs: int) -> np.ndarray:
    mask = np.zeros(shape, dtype=np.uint8)
    for _ in range(blobs):
        row, col = int(rng.integers(0, shape[0])), int(rng.integers(0, shape[1]))
        height, width = int(rng.integers(1, 9)), int(rng.integers(1, 9))
        blob = mask[row : row + height, col : col + width]
        blob[...] = rng.random(blob.shape) < 0.7
    return mask


def test_pixel_components_on_the_box_are_the_whole_frame_s() -> None:
    # Same count, same numbering at every pixel, same statistics and centroids (bit for bit), for odd and
    # even offsets, long runs of empty rows, blobs touching the frame's edges, and both connectivities.
    rng = np.random.default_rng(11)
    for trial in range(600):
        shape = (int(rng.integers(2, 160)), int(rng.integers(2, 90)))
        mask = _sparse_mask(rng, shape, int(rng.integers(0, 12)))
        connectivity = 8 if trial % 2 else 4
        count, labels, stats, centroids = cv2.connectedComponentsWithStats(mask, connectivity=connectivity)
        top, left, bottom, right = occupied(mask)
        got_count, rows, cols, owner = pixel_components(
            np.ascontiguousarray(mask[top:bottom, left:right]), connectivity
        )
        rows, cols = rows + top, cols + left
        expected_rows, expected_cols = np.nonzero(mask)
        assert got_count == count
        np.testing.assert_array_equal(rows, expected_rows)
        np.testing.assert_array_equal(cols, expected_cols)
        np.testing.assert_array_equal(owner, labels[expected_rows, expected_cols])
        got_stats, got_centroids = component_stats(got_count, rows, cols, owner)
        np.testing.assert_array_equal(got_stats[1:], stats[1:])
        np.testing.assert_array_equal(got_centroids[1:], centroids[1:])


def test_kept_rows_are_the_occupied_pairs_and_one_empty_pair_after_each() -> None:
    mask = np.zeros((13, 8), dtype=np.uint8)
    assert kept_rows(mask).size == 0
    mask[3, 2] = mask[9, 5] = 1  # pairs 1 and 4 hold pixels; 2 and 5 follow them; 0, 3 and 6 are dropped
    np.testing.assert_array_equal(kept_rows(mask), [2, 3, 4, 5, 8, 9, 10, 11])
    mask[12, 0] = 1  # the last, unpaired row
    np.testing.assert_array_equal(kept_rows(mask), [2, 3, 4, 5, 8, 9, 10, 11, 12])
    count, rows, cols, owner = pixel_components(np.zeros((5, 5), np.uint8), 8)
    assert count == 1 and rows.size == cols.size == owner.size == 0


def test_the_box_starts_on_even_pixels_and_holds_the_margin() -> None:
    mask = np.zeros((20, 30), dtype=np.uint8)
    assert occupied(mask) == (0, 0, 1, 1)  # empty: a 1 x 1 box of background
    mask[7, 9] = mask[11, 14] = 1
    assert occupied(mask) == (6, 8, 12, 15)
    assert occupied(mask, 3) == (4, 6, 15, 18)
    assert occupied(mask, 50) == (0, 0, 20, 30)  # clipped to the frame


def test_the_faster_algorithms_give_the_default_labels() -> None:
    # BBDT (8-connected) and SAUF (4-connected) replace OpenCV's default for speed: same count and labels
    # (numbering included), on sparse and dense random masks and dilated blobs.
    rng = np.random.default_rng(3)
    for trial in range(600):
        shape = (int(rng.integers(2, 100)), int(rng.integers(2, 100)))
        mask = (rng.random(shape) < (0.05, 0.2, 0.45, 0.6)[trial % 4]).astype(np.uint8)
        if trial % 3 == 0:
            mask = cv2.dilate(mask * (rng.random(shape) < 0.1).astype(np.uint8), np.ones((3, 3), np.uint8))
        for connectivity in (4, 8):
            count, labels = cv2.connectedComponents(mask, connectivity=connectivity)
            got_count, got_labels = labelled(mask, connectivity)
            assert got_count == count
            np.testing.assert_array_equal(got_labels, labels)


def test_nonzero_pixels_are_numpys_in_numpys_order() -> None:
    # Masks with few occupied rows take the row-search path.
    rng = np.random.default_rng(6)
    for trial in range(600):
        shape = (int(rng.integers(1, 80)), int(rng.integers(1, 10)) * (8 if trial % 3 else 1))
        mask = (rng.random(shape) < (0.0, 0.003, 0.01, 0.5, 1.0)[trial % 5]).astype(np.uint8)
        # Views of a larger array too: rows cut, and columns cut (rows no longer contiguous).
        view = (mask, mask[1:], mask[:, 1:])[trial % 3] if min(shape) > 1 else mask
        rows, cols = nonzero_pixels(view)
        expected_rows, expected_cols = np.nonzero(view)
        assert rows.dtype == expected_rows.dtype
        np.testing.assert_array_equal(rows, expected_rows)
        np.testing.assert_array_equal(cols, expected_cols)


def test_flat_nonzero_is_numpys() -> None:
    rng = np.random.default_rng(7)
    for trial in range(200):
        mask = rng.random((int(rng.integers(1, 50)), int(rng.integers(1, 50)))) < (0.0, 0.05, 0.5)[trial % 3]
        view = mask[::2] if trial % 2 else mask  # strided rows, as the registration's used rows
        np.testing.assert_array_equal(flat_nonzero(view), np.flatnonzero(view))
        np.testing.assert_array_equal(flat_nonzero(view.astype(np.uint8)), np.flatnonzero(view))
