"""Labelling a sparse mask on the box of its pixels gives the whole frame's components, to the last bit."""

from __future__ import annotations

import cv2
import numpy as np

from rsi.imaging._components import (
    components_with_stats,
    flat_nonzero,
    labelled,
    labelled_with_stats,
    nonzero_pixels,
    occupied,
)


def _sparse_mask(rng: np.random.Generator, shape: tuple[int, int], blobs: int) -> np.ndarray:
    mask = np.zeros(shape, dtype=np.uint8)
    for _ in range(blobs):
        row, col = int(rng.integers(0, shape[0])), int(rng.integers(0, shape[1]))
        height, width = int(rng.integers(1, 9)), int(rng.integers(1, 9))
        blob = mask[row : row + height, col : col + width]
        blob[...] = rng.random(blob.shape) < 0.7
    return mask


def test_the_box_labels_equal_the_whole_frame_labels() -> None:
    # Same count, same numbering, same statistics and centroids (bit for bit), for odd and even offsets,
    # blobs touching the frame's edges, and both connectivities.
    rng = np.random.default_rng(11)
    for trial in range(200):
        shape = (int(rng.integers(2, 90)), int(rng.integers(2, 90)))
        mask = _sparse_mask(rng, shape, int(rng.integers(0, 12)))
        connectivity = 8 if trial % 2 else 4
        count, labels, stats, centroids = cv2.connectedComponentsWithStats(mask, connectivity=connectivity)
        got_count, got_labels, got_stats, got_centroids, box = components_with_stats(mask, connectivity)
        top, left, bottom, right = box
        assert got_count == count
        assert not labels[:top].any() and not labels[bottom:].any()
        assert not labels[:, :left].any() and not labels[:, right:].any()
        np.testing.assert_array_equal(got_labels, labels[top:bottom, left:right])
        np.testing.assert_array_equal(got_stats[1:], stats[1:])
        np.testing.assert_array_equal(got_centroids[1:], centroids[1:])


def test_the_box_starts_on_even_pixels_and_holds_the_margin() -> None:
    mask = np.zeros((20, 30), dtype=np.uint8)
    assert occupied(mask) == (0, 0, 1, 1)  # empty: a 1 x 1 box of background
    mask[7, 9] = mask[11, 14] = 1
    assert occupied(mask) == (6, 8, 12, 15)
    assert occupied(mask, 3) == (4, 6, 15, 18)
    assert occupied(mask, 50) == (0, 0, 20, 30)  # clipped to the frame


def test_the_faster_algorithm_gives_the_default_labels() -> None:
    # BBDT replaces OpenCV's default 8-connected labelling for speed: same count, labels (numbering
    # included), statistics and centroids, on sparse and dense random masks and dilated blobs.
    rng = np.random.default_rng(3)
    for trial in range(600):
        shape = (int(rng.integers(2, 100)), int(rng.integers(2, 100)))
        mask = (rng.random(shape) < (0.05, 0.2, 0.45, 0.6)[trial % 4]).astype(np.uint8)
        if trial % 3 == 0:
            mask = cv2.dilate(mask * (rng.random(shape) < 0.1).astype(np.uint8), np.ones((3, 3), np.uint8))
        for connectivity in (4, 8):
            expected = cv2.connectedComponentsWithStats(mask, connectivity=connectivity)
            got = labelled_with_stats(mask, connectivity)
            assert got[0] == expected[0]
            for got_array, expected_array in zip(got[1:], expected[1:], strict=True):
                np.testing.assert_array_equal(got_array, expected_array)
            count, labels = labelled(mask, connectivity)
            assert count == expected[0]
            np.testing.assert_array_equal(labels, expected[1])


def test_odd_sides_are_padded_without_changing_anything() -> None:
    # labelled_with_stats pads odd sides with background (OpenCV's statistics are 3x slower there): labels,
    # statistics and centroids equal OpenCV's on the unpadded mask, the background's (label 0) included;
    # a mask without background keeps OpenCV's own placeholder for label 0.
    rng = np.random.default_rng(5)
    for trial in range(1500):
        shape = (int(rng.integers(1, 60)), int(rng.integers(1, 60)))
        mask = (rng.random(shape) < (0.02, 0.3, 0.6, 1.0, 0.0)[trial % 5]).astype(np.uint8)
        for connectivity in (4, 8):
            expected = cv2.connectedComponentsWithStats(mask, connectivity=connectivity)
            got = labelled_with_stats(mask, connectivity)
            assert got[0] == expected[0]
            for got_array, expected_array in zip(got[1:], expected[1:], strict=True):
                np.testing.assert_array_equal(got_array, expected_array)


def test_nonzero_pixels_are_numpys_in_numpys_order() -> None:
    # Widths that are multiples of 8 and masks with few occupied rows take the row-search path.
    rng = np.random.default_rng(6)
    for trial in range(600):
        shape = (int(rng.integers(1, 80)), int(rng.integers(1, 10)) * (8 if trial % 3 else 1))
        mask = (rng.random(shape) < (0.0, 0.003, 0.01, 0.5, 1.0)[trial % 5]).astype(np.uint8)
        view = mask[1:, ::1] if trial % 2 and shape[0] > 1 else mask  # a view of a larger array too
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


def test_statistics_from_the_pixels_are_opencvs() -> None:
    # Sparse boxes take their statistics from their pixels: OpenCV's, background and centroids included.
    from rsi.imaging._components import _stats_of_pixels

    rng = np.random.default_rng(9)
    for _ in range(400):
        shape = (int(rng.integers(1, 70)), int(rng.integers(1, 70)))
        mask = _sparse_mask(rng, shape, int(rng.integers(0, 8)))
        mask[0, 0] = 0  # some background: what the sparse path is for
        for connectivity in (4, 8):
            expected = cv2.connectedComponentsWithStats(mask, connectivity=connectivity)
            got = _stats_of_pixels(mask, connectivity)
            assert got[0] == expected[0]
            for got_array, expected_array in zip(got[1:], expected[1:], strict=True):
                np.testing.assert_array_equal(got_array, expected_array)
