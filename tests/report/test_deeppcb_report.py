"""A DeepPCB evaluation's results folder: the record, its per-class table and its two pictures."""

from __future__ import annotations

import csv
import io
import json
from pathlib import Path
from typing import Any

import cv2
import numpy as np
import pytest

from rsi.datasets.deeppcb import DEFECT_TYPES
from rsi.errors import InputError
from rsi.report.deeppcb import (
    CLASS_COLUMNS,
    confusion_png,
    per_class_csv,
    per_class_png,
    write_deeppcb_report,
)

PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"


def _record(confusion: np.ndarray | None = None) -> dict[str, Any]:
    """A record as EvaluationResult.to_dict() gives one: six classes, a confusion with "none" first."""
    names = list(DEFECT_TYPES.values())
    if confusion is None:
        confusion = np.diag([0, 1259, 1013, 1340, 1137, 1008, 1025])
        confusion[1, 3], confusion[3, 1], confusion[0, 4], confusion[2, 0] = 17, 22, 15, 11
    per_class = {
        name: {
            "boxes": 1000 + index,
            "detections": 990 + index,
            "precision": 0.97,
            "recall": 0.98,
            "ap": 0.975,
        }
        for index, name in enumerate(names)
    }
    return {
        "pairs": 1000,
        "official_f": 0.9876,
        "map": 0.9862,
        "per_class": per_class,
        "confusion": confusion.tolist(),
        "classes": "rules",
    }


def _decoded(data: bytes) -> np.ndarray:
    assert data.startswith(PNG_SIGNATURE)
    image = cv2.imdecode(np.frombuffer(data, np.uint8), cv2.IMREAD_COLOR)
    assert image is not None
    return image


def test_the_results_folder_holds_the_record_its_table_and_its_pictures(tmp_path: Path) -> None:
    record = _record()
    written = write_deeppcb_report(tmp_path / "out", record)
    assert sorted(written) == ["confusion.png", "deeppcb.json", "per_class.csv", "per_class.png"]
    assert json.loads(written["deeppcb.json"].read_text()) == record
    rows = list(csv.DictReader(io.StringIO(written["per_class.csv"].read_text())))
    assert [row["class"] for row in rows] == list(DEFECT_TYPES.values())
    assert all(int(row["boxes"]) == record["per_class"][row["class"]]["boxes"] for row in rows)
    for name in ("per_class.png", "confusion.png"):
        rows_px, cols_px, _ = _decoded(written[name].read_bytes()).shape
        assert rows_px > 200 and cols_px > 300


def test_the_confusion_picture_follows_the_counts() -> None:
    # Another count in one cell is another picture; nothing paired at all (every cell 0) still draws.
    record = _record()
    other = _record()
    other["confusion"][1][3] = 40
    assert _decoded(confusion_png(record)).shape[2] == 3
    assert confusion_png(record) != confusion_png(other)
    empty = _record(np.zeros((7, 7), dtype=np.int64))
    assert _decoded(confusion_png(empty)).size > 0
    assert per_class_png(record) != per_class_png({**record, "map": 0.5})


def test_the_table_has_a_column_per_figure() -> None:
    header = per_class_csv(_record()).splitlines()[0].split(",")
    assert header == ["class", *CLASS_COLUMNS]


@pytest.mark.parametrize(
    ("change", "named"),
    [
        (lambda record: [record], "record must be"),
        (lambda record: {**record, "per_class": None}, "record must be"),
        (lambda record: {**record, "per_class": {"open": {"boxes": 1}}}, "per_class"),
        (lambda record: {**record, "per_class": {}}, "1 to 64 classes"),
        (lambda record: {**record, "per_class": {f"c{i}": {} for i in range(65)}}, "1 to 64 classes"),
        (
            lambda record: {
                **record,
                "per_class": {**record["per_class"], "open": dict.fromkeys(CLASS_COLUMNS, "x")},
            },
            "finite number",
        ),
        (
            lambda record: {
                **record,
                "per_class": {**record["per_class"], "open": dict.fromkeys(CLASS_COLUMNS, float("nan"))},
            },
            "finite number",
        ),
        (lambda record: {**record, "confusion": [[0, 1], [1, 0]]}, "7 x 7"),
        (lambda record: {**record, "confusion": "many"}, "7 x 7"),
        (lambda record: {**record, "confusion": (-np.eye(7, dtype=int)).tolist()}, ">= 0"),
    ],
)
def test_a_record_that_is_not_an_evaluation_is_refused(change: Any, named: str, tmp_path: Path) -> None:
    with pytest.raises(InputError, match=named):
        write_deeppcb_report(tmp_path, change(_record()))
    assert list(tmp_path.iterdir()) == []  # refused before anything is written
