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


def board_pairs(group: str, count: int) -> dict[str, tuple[np.ndarray, np.ndarray, str]]:
    """`count` pairs of board group `group` (five digits), each with copper added on bare board (annotated
    spurious copper, 5) and a hole punched in a round pad (pin-hole, 6), boxes padded as DeepPCB's."""
    pairs = {}
    for index in range(count):
        reference = np.full((192, 192), 255, np.uint8)
        cv2.line(reference, (20, 60), (170, 60), (0,), 7)
        pad, blob = (30 + 35 * (index % 4), 130), (165, 100 + 8 * (index % 6))
        cv2.circle(reference, pad, 14, (0,), -1)
        inspection = reference.copy()
        cv2.circle(inspection, blob, 5, (0,), -1)
        cv2.circle(inspection, pad, 4, (255,), -1)
        boxes = [(*blob, 5), (*pad, 6)]
        annotation = "\n".join(f"{x - 14} {y - 14} {x + 13} {y + 13} {kind}" for x, y, kind in boxes)
        pairs[f"{group}{index:03d}"] = (reference, inspection, annotation)
    return pairs


@pytest.fixture
def two_group_tree(tmp_path: Path) -> Path:
    """Trainval of two board groups and a test split of two more pairs; each group's 20 pairs (40
    detections) are the least that let the classifier (leaves of 20 detections) learn the other group's two
    classes."""
    root = tmp_path / "deeppcb-two-groups"
    write_deeppcb_tree(root, board_pairs("00041", 20) | board_pairs("13000", 20))
    return write_deeppcb_tree(root, board_pairs("92000", 2), split="test")


@pytest.fixture(scope="session")
def proximity_progress() -> list[tuple[str, int, int]]:
    """The progress calls of the shared proximity-demo run (filled by :func:`proximity_demo`)."""
    return []


@pytest.fixture(scope="session")
def proximity_demo(proximity_progress: list[tuple[str, int, int]]) -> ProximityDemoResult:
    """One run of the ISEE proximity demo (seed 0, about 5 s), shared by the sim, report and CLI tests."""
    from rsi.mission.proximity_demo import simulate_proximity_demo

    return simulate_proximity_demo(seed=0, progress=lambda *call: proximity_progress.append(call))
