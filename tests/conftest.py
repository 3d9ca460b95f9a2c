"""Shared test set-up: fixed hypothesis seeds, a DeepPCB-layout tree, one run of the proximity demo."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING

import cv2
import numpy as np
import pytest
from hypothesis import settings

# Seeds fixed: hypothesis draws the same examples on every run (and no timing deadline on a loaded CI box).
settings.register_profile("rsi", derandomize=True, deadline=None, print_blob=True)
settings.load_profile("rsi")

if TYPE_CHECKING:
    from rsi.mission.proximity_records import ProximityDemoResult

TreeWriter = Callable[..., Path]


def write_deeppcb_tree(
    root: Path, pairs: dict[str, tuple[np.ndarray, np.ndarray, str]], split: str = "trainval"
) -> Path:
    """Write a DeepPCB-layout tree: {pair id: (reference, inspection, annotation text)}."""
    folder = root / "PCBData"
    lines = []
    for pair_id, (reference, inspection, annotation) in pairs.items():
        group, number = f"group{pair_id[:5]}", pair_id[:5]
        images, notes = folder / group / number, folder / group / f"{number}_not"
        images.mkdir(parents=True, exist_ok=True)
        notes.mkdir(parents=True, exist_ok=True)
        for suffix, image in (("_temp", reference), ("_test", inspection)):
            cv2.imwrite(str(images / f"{pair_id}{suffix}.jpg"), image, [cv2.IMWRITE_JPEG_QUALITY, 95])
        (notes / f"{pair_id}.txt").write_text(annotation)
        lines.append(f"{group}/{number}/{pair_id}.jpg {group}/{number}_not/{pair_id}.txt")
    # DeepPCB's split file has no trailing newline after the last line.
    (folder / f"{split}.txt").write_text("\n".join(lines))
    return root


def synthetic_board(rng: np.random.Generator, side_px: int = 192) -> np.ndarray:
    """A binarised board: white with black traces and round pads (copper black, as in DeepPCB)."""
    image = np.full((side_px, side_px), 255, np.uint8)
    for _ in range(8):
        x0, y0, x1, y1 = (int(value) for value in rng.integers(10, side_px - 10, 4))
        cv2.line(image, (x0, y0), (x1, y1), (0,), int(rng.integers(4, 9)))
        cv2.circle(image, (x1, y1), int(rng.integers(6, 10)), (0,), -1)
    return image


@pytest.fixture
def tree_writer() -> TreeWriter:
    """The DeepPCB tree writer, for tests that build their own pairs."""
    return write_deeppcb_tree


@pytest.fixture
def defect_tree(tmp_path: Path) -> Path:
    """Three board pairs off by a pixel, two flipped ~8 px defects each, boxes padded as DeepPCB's."""
    rng = np.random.default_rng(7)
    pairs = {}
    for index in range(3):
        reference = synthetic_board(rng)
        inspection = np.roll(reference, (1, -1), axis=(0, 1))  # DeepPCB pairs are off by about a pixel
        inspection[:, -1] = 255
        inspection[-1, :] = 255
        boxes = []
        for row, col in ((40 + 30 * index, 150), (150, 40 + 20 * index)):
            # Defects of DeepPCB size (about 8 px) flip the binary image: extra copper or a missing one.
            patch = inspection[row - 4 : row + 4, col - 4 : col + 4]
            inspection[row - 4 : row + 4, col - 4 : col + 4] = 255 - patch.max()
            boxes.append(f"{col - 14} {row - 14} {col + 13} {row + 13} 5")
        if index == 0:
            reference[:, :4] = 0  # a crop-frame stripe in the template only: border_px ignores it
        pairs[f"0004100{index}"] = (reference, inspection, "\n".join(boxes))
    return write_deeppcb_tree(tmp_path / "deeppcb", pairs)


@pytest.fixture(scope="session")
def proximity_progress() -> list[tuple[str, int, int]]:
    """The progress calls of the shared proximity-demo run (filled by :func:`proximity_demo`)."""
    return []


@pytest.fixture(scope="session")
def proximity_demo(proximity_progress: list[tuple[str, int, int]]) -> ProximityDemoResult:
    """One run of the ISEE proximity demo (seed 0, about 5 s), shared by the sim, report and CLI tests."""
    from rsi.mission.proximity_demo import simulate_proximity_demo

    return simulate_proximity_demo(seed=0, progress=lambda *call: proximity_progress.append(call))
