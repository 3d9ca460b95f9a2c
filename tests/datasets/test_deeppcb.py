"""DeepPCB loader: a fake tree with known content, every DatasetError, and a real-data smoke test."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import cv2
import numpy as np
import pytest

from rsi.datasets.deeppcb import DEFECT_TYPES, SPLITS, load_split, read_annotation, read_pair
from rsi.errors import DatasetError, InputError

REAL_ROOT = Path(__file__).resolve().parents[2].parent / "shared" / "data" / "deeppcb"
SIDE_PX = 96


def board(shape: tuple[int, int] = (SIDE_PX, SIDE_PX)) -> np.ndarray:
    """A binarised synthetic board: white (255) with black copper traces and pads."""
    image = np.full(shape, 255, np.uint8)
    image[20:28, 8:88] = 0
    image[60:68, 8:88] = 0
    image[8:88, 40:46] = 0
    cv2.circle(image, (70, 40), 6, (0,), -1)
    return image


@pytest.fixture
def tree(tmp_path: Path, tree_writer: Callable[..., Path]) -> Path:
    reference = board()
    inspection = reference.copy()
    inspection[40:48, 70:78] = 0
    colour = cv2.cvtColor(reference, cv2.COLOR_GRAY2BGR)  # DeepPCB stores a few files as RGB
    return tree_writer(
        tmp_path,
        {
            "00041000": (reference, inspection, "66 36 81 51 5\n"),
            "00041001": (colour, reference, "1 2 30 40 1\n\n10 12 20 22 6"),
        },
    )


def test_load_split_reads_pairs_in_order(tree: Path) -> None:
    pairs = load_split(tree, "trainval")
    assert [pair.pair_id for pair in pairs] == ["group00041/00041/00041000", "group00041/00041/00041001"]
    assert pairs[0].reference_path.name == "00041000_temp.jpg"
    assert pairs[0].inspection_path.name == "00041000_test.jpg"
    np.testing.assert_array_equal(pairs[1].boxes_xyxy, [[1, 2, 30, 40], [10, 12, 20, 22]])
    np.testing.assert_array_equal(pairs[1].defect_types, [1, 6])
    assert pairs[0].boxes_xyxy.dtype == np.int64


def test_load_split_accepts_the_pcbdata_folder(tree: Path) -> None:
    assert len(load_split(tree / "PCBData", "trainval")) == 2


def test_read_pair_gives_grey_float32_even_for_colour_files(tree: Path) -> None:
    reference, inspection = read_pair(load_split(tree)[1])
    assert reference.dtype == np.float32 and reference.shape == (SIDE_PX, SIDE_PX)
    assert np.abs(reference - inspection).max() < 40  # the same board; JPEG noise only


def test_empty_annotation_gives_no_boxes(tmp_path: Path) -> None:
    note = tmp_path / "a.txt"
    note.write_text("\n")
    boxes, types = read_annotation(note)
    assert boxes.shape == (0, 4) and types.shape == (0,)


def test_constants() -> None:
    assert SPLITS == ("trainval", "test")
    assert DEFECT_TYPES[3] == "mousebite"


def test_missing_root_raises(tmp_path: Path) -> None:
    with pytest.raises(DatasetError, match="is not a folder"):
        load_split(tmp_path / "nowhere")


def test_missing_split_file_raises(tree: Path) -> None:
    with pytest.raises(DatasetError, match=r"test\.txt.*does not exist"):
        load_split(tree, "test")


def test_unknown_split_raises(tree: Path) -> None:
    with pytest.raises(InputError, match="split='val' is not known"):
        load_split(tree, "val")


def test_empty_split_file_raises(tree: Path) -> None:
    (tree / "PCBData" / "trainval.txt").write_text("\n")
    with pytest.raises(DatasetError, match="lists no pairs"):
        load_split(tree)


def test_malformed_split_line_names_file_and_line(tree: Path) -> None:
    split = tree / "PCBData" / "trainval.txt"
    split.write_text(split.read_text() + "\ngroup00041/00041/00041002.png")
    with pytest.raises(DatasetError, match=r"trainval\.txt' line 3 is malformed"):
        load_split(tree)


def test_missing_image_raises(tree: Path) -> None:
    (tree / "PCBData" / "group00041" / "00041" / "00041001_test.jpg").unlink()
    with pytest.raises(DatasetError, match=r"line 2 names pair .*00041001_test\.jpg' does not exist"):
        load_split(tree)


def test_missing_annotation_raises(tree: Path) -> None:
    (tree / "PCBData" / "group00041" / "00041_not" / "00041000.txt").unlink()
    with pytest.raises(DatasetError, match=r"line 1 names annotation .*00041000\.txt'"):
        load_split(tree)


def test_unreadable_annotation_raises(tmp_path: Path) -> None:
    with pytest.raises(DatasetError, match="cannot be read"):
        read_annotation(tmp_path / "missing.txt")


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("1 2 3 4", "has 4 field"),
        ("1 2 3 4 5 6", "has 6 field"),
        ("1,2,3,4,5", "has 1 field"),
        ("1 2 3 x 5", "not five integers"),
        ("9 2 3 4 5", "is not a box"),
        ("1 9 3 4 5", "is not a box"),
        ("-1 2 3 4 5", "is not a box"),
        ("1 2 3 4 7", "defect type 7"),
    ],
)
def test_malformed_annotation_line_names_file_and_line(tmp_path: Path, text: str, message: str) -> None:
    note = tmp_path / "b.txt"
    note.write_text(f"1 2 3 4 1\n{text}\n")
    with pytest.raises(DatasetError, match=rf"b\.txt' line 2 .*{message}"):
        read_annotation(note)


def test_real_trainval_layout() -> None:
    if not (REAL_ROOT / "PCBData" / "trainval.txt").is_file():
        pytest.skip(f"DeepPCB not found at {REAL_ROOT}: real-data test skipped (see its README.md there)")
    pairs = load_split(REAL_ROOT, "trainval")
    assert len(pairs) == 1000
    assert sum(len(pair.boxes_xyxy) for pair in pairs) == 6873  # README: 6,873 boxes
    reference, inspection = read_pair(pairs[0])
    assert reference.shape == inspection.shape == (640, 640)
