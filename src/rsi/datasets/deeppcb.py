"""DeepPCB: real reference/inspection pairs of printed-circuit boards with ground-truth defect boxes.

Tang, He, Huang & Yang, "Online PCB Defect Detector On A New PCB Defect Dataset", arXiv:1902.06197
(https://github.com/tangsanli5201/DeepPCB). The layout read here::

    <root>/PCBData/<split>.txt                       "<image path> <annotation path>" per line
    <root>/PCBData/groupNNNNN/NNNNN/<id>_temp.jpg    defect-free template  -> the reference image
    <root>/PCBData/groupNNNNN/NNNNN/<id>_test.jpg    the same board, with defects -> the inspection image
    <root>/PCBData/groupNNNNN/NNNNN_not/<id>.txt     one defect per line: "x1 y1 x2 y2 type"

The image path in a split file names ``<id>.jpg``, which is not a file: the pair is ``<id>_temp.jpg`` and
``<id>_test.jpg``. Boxes are integer pixels of the inspection image, origin top-left, x = column,
(x1, y1) the top-left and (x2, y2) the bottom-right corner, both inside the box.

Images are never copied into rsi; pass the folder where the dataset lies.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from rsi._files import read_regular_file
from rsi._validate import choice, instance_of
from rsi.errors import DatasetError, InputError

SPLITS = ("trainval", "test")
# DeepPCB README: the six defect classes, by the integer in the last column of an annotation line.
DEFECT_TYPES = {1: "open", 2: "short", 3: "mousebite", 4: "spur", 5: "spurious copper", 6: "pin-hole"}

_REFERENCE_SUFFIX = "_temp.jpg"
_INSPECTION_SUFFIX = "_test.jpg"
_SPLIT_FIELDS = 2
_BOX_FIELDS = 5

IntArray = NDArray[np.int64]
PathLike = str | os.PathLike[str]
_MAX_ANNOTATION_BYTES = 2**20
"""DeepPCB's annotations hold a few boxes of about 20 characters each (at most a few hundred bytes); a
megabyte is no annotation."""


@dataclass(frozen=True)
class DeepPcbPair:
    """One reference/inspection pair of DeepPCB and its ground truth.

    Attributes
    ----------
    pair_id : str
        The split file's image path without ``.jpg`` (e.g. ``"group20085/20085/20085000"``).
    reference_path, inspection_path : pathlib.Path
        The template (``_temp.jpg``) and the tested board (``_test.jpg``).
    annotation_path : pathlib.Path
        The ``.txt`` file the boxes were read from.
    boxes_xyxy : ndarray of shape (K, 4), int64
        ``(x1, y1, x2, y2)`` per defect, inspection-image pixels, corners inclusive.
    defect_types : ndarray of shape (K,), int64
        Class of each box, a key of :data:`DEFECT_TYPES`.
    """

    pair_id: str
    reference_path: Path
    inspection_path: Path
    annotation_path: Path
    boxes_xyxy: IntArray
    defect_types: IntArray


def _pcb_folder(root: PathLike) -> Path:
    if not isinstance(root, (str, os.PathLike)):
        raise InputError(f"root must be a folder path (str or os.PathLike); got {type(root).__name__}.")
    folder = Path(root)
    try:
        is_folder = folder.is_dir()
    except OSError as failure:  # a name too long, a loop of links: no folder by that name
        raise DatasetError(f"root={str(folder)[:80]!r}... cannot be read: {failure.strerror}.") from None
    if not is_folder:
        raise DatasetError(
            f"root={str(folder)!r} is not a folder. Pass the DeepPCB folder that holds PCBData/ "
            "(a clone of https://github.com/tangsanli5201/DeepPCB)."
        )
    # Accept both the repository root and its PCBData/ folder: users point at either.
    return folder / "PCBData" if (folder / "PCBData").is_dir() else folder


def _parse_box(text: str, path: Path, line_number: int) -> tuple[int, int, int, int, int]:
    fields = text.split()
    where = f"{str(path)!r} line {line_number}"
    if len(fields) != _BOX_FIELDS:
        raise DatasetError(
            f"{where} has {len(fields)} field(s): {text!r}. Expected 'x1 y1 x2 y2 type' separated by spaces."
        )
    try:
        x1, y1, x2, y2, kind = (int(field) for field in fields)
    except ValueError as error:
        raise DatasetError(f"{where} is not five integers: {text!r}. Expected 'x1 y1 x2 y2 type'.") from error
    if x2 < x1 or y2 < y1 or min(x1, y1) < 0:
        raise DatasetError(
            f"{where} is not a box: {text!r}. "
            "Expected 0 <= x1 <= x2 and 0 <= y1 <= y2 (top-left, bottom-right)."
        )
    if kind not in DEFECT_TYPES:
        raise DatasetError(f"{where} has defect type {kind}; expected one of {sorted(DEFECT_TYPES)}.")
    return x1, y1, x2, y2, kind


def read_annotation(path: PathLike) -> tuple[IntArray, IntArray]:
    """Read one DeepPCB annotation file.

    Parameters
    ----------
    path : str or os.PathLike
        A ``.txt`` file with one ``x1 y1 x2 y2 type`` line per defect; blank lines are skipped.

    Returns
    -------
    boxes_xyxy : ndarray of shape (K, 4), int64
        Corners (x1, y1, x2, y2), inclusive.
    defect_types : ndarray of shape (K,), int64
        Class of each box (see :data:`DEFECT_TYPES`).

    Raises
    ------
    DatasetError
        If the file is missing or a line is malformed; the message names the file and the line number.
    """
    if not isinstance(path, (str, os.PathLike)) or not str(path):
        raise InputError(f"path must be an annotation file path (str or os.PathLike); got {path!r:.60}.")
    file = Path(path)
    # a regular file of bounded size: a device or a FIFO named .txt is refused, never read without end
    data = read_regular_file(
        file, max_bytes=_MAX_ANNOTATION_BYTES, error=DatasetError, too_big="not a DeepPCB annotation"
    )
    try:
        lines = data.decode("utf-8").splitlines()
    except UnicodeDecodeError as error:
        raise DatasetError(
            f"annotation {str(file)!r} is not UTF-8 text ({error.reason} at byte {error.start}). "
            "Check that the dataset is complete."
        ) from None
    rows = [_parse_box(line, file, number) for number, line in enumerate(lines, start=1) if line.strip()]
    table = np.array(rows, dtype=np.int64).reshape(-1, _BOX_FIELDS)
    return table[:, :4].copy(), table[:, 4].copy()


def _pair_from_line(text: str, folder: Path, split_file: Path, line_number: int) -> DeepPcbPair:
    fields = text.split()
    where = f"{str(split_file)!r} line {line_number}"
    if len(fields) != _SPLIT_FIELDS or not fields[0].endswith(".jpg"):
        raise DatasetError(
            f"{where} is malformed: {text!r}. "
            "Expected '<group>/<id>.jpg <group>/<id>.txt' separated by a space."
        )
    pair_id = fields[0][: -len(".jpg")]
    reference = folder / (pair_id + _REFERENCE_SUFFIX)
    inspection = folder / (pair_id + _INSPECTION_SUFFIX)
    for image in (reference, inspection):
        if not image.is_file():
            raise DatasetError(f"{where} names pair {pair_id!r}, but {str(image)!r} does not exist.")
    annotation = folder / fields[1]
    if not annotation.is_file():
        raise DatasetError(f"{where} names annotation {str(annotation)!r}, which does not exist.")
    boxes, types = read_annotation(annotation)
    return DeepPcbPair(pair_id, reference, inspection, annotation, boxes, types)


def load_split(root: PathLike, split: str = "trainval") -> tuple[DeepPcbPair, ...]:
    """List the pairs of a DeepPCB split with their boxes, checking every file exists.

    Parameters
    ----------
    root : str or os.PathLike
        The DeepPCB folder (the one holding ``PCBData/``) or ``PCBData/`` itself.
    split : {"trainval", "test"}
        Which official split file to read (``PCBData/<split>.txt``).

    Returns
    -------
    tuple of DeepPcbPair
        In the split file's order.

    Raises
    ------
    DatasetError
        If the folder, the split file, an image or an annotation is missing, or a line is malformed (the
        message names the file and the line number).

    Examples
    --------
    >>> pairs = load_split("../shared/data/deeppcb", "trainval")  # doctest: +SKIP
    >>> pairs[0].boxes_xyxy.shape  # doctest: +SKIP
    (3, 4)
    """
    chosen = choice(split, "split", SPLITS)
    folder = _pcb_folder(root)
    split_file = folder / f"{chosen}.txt"
    if not split_file.is_file():
        raise DatasetError(
            f"split file {str(split_file)!r} does not exist. DeepPCB keeps '{chosen}.txt' in PCBData/; "
            f"the splits are {', '.join(SPLITS)}."
        )
    lines = split_file.read_text(encoding="utf-8").splitlines()
    pairs = tuple(
        _pair_from_line(line, folder, split_file, number)
        for number, line in enumerate(lines, start=1)
        if line.strip()
    )
    if not pairs:
        raise DatasetError(f"split file {str(split_file)!r} lists no pairs. Expected one pair per line.")
    return pairs


def read_pair(pair: DeepPcbPair) -> tuple[NDArray[np.float32], NDArray[np.float32]]:
    """Read a pair's images as grey float32 (0..255; the 62 RGB files are converted to grey).

    Parameters
    ----------
    pair : DeepPcbPair
        From :func:`load_split`.

    Returns
    -------
    reference, inspection : ndarray of shape (M, N), float32
        The template and the tested board.
    """
    from rsi.imaging.io import read_image

    instance_of(pair, "pair", DeepPcbPair, none_allowed=False)

    return read_image(pair.reference_path), read_image(pair.inspection_path)
