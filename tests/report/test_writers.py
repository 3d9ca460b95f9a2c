"""The report layer: atomic files, flaw tables matching the overlay numbers, valid pictures, no algorithms."""

from __future__ import annotations

import csv
import io
import json
import os
import subprocess
import sys
from pathlib import Path

import cv2
import numpy as np
import pytest

from rsi.detection.detect import Detection, Flaw
from rsi.detection.pair import PairResult
from rsi.detection.roc import RocCurve
from rsi.errors import InputError
from rsi.report import figures, writers

PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"
SHAPE = (40, 60)


def decode_png(data: bytes) -> np.ndarray:
    assert data.startswith(PNG_SIGNATURE)
    image = cv2.imdecode(np.frombuffer(data, np.uint8), cv2.IMREAD_UNCHANGED)
    assert image is not None
    return image


def make_flaws() -> tuple[Flaw, ...]:
    return (
        Flaw(row=10.0, col=20.0, bbox=(9, 19, 12, 22), area_px=9, score=12.5, polarity="dark"),
        Flaw(row=30.0, col=45.0, bbox=(30, 45, 31, 46), area_px=1, score=6.0, polarity="bright"),
    )


def make_pair(*, threshold: float = 4.4) -> PairResult:
    rng = np.random.default_rng(0)
    image = rng.random(SHAPE).astype(np.float32)
    valid = np.ones(SHAPE, bool)
    valid[:, :3] = False
    flaws = make_flaws()
    detection = Detection(
        score=np.abs(rng.normal(size=SHAPE)).astype(np.float32),
        statistic=rng.normal(size=SHAPE).astype(np.float32),
        mask=np.zeros(SHAPE, bool),
        threshold=threshold,
        flaws=flaws,
        difference=rng.normal(size=SHAPE).astype(np.float32),
        sigma=np.ones(SHAPE, np.float32),
        valid=valid,
        registration=None,
        flaw_model="uniform",
        method="lrt",
        p_false_alarm=1e-5,
        polarity="both",
    )
    return PairResult(reference=image, inspection=image, detection=detection, elapsed_s=0.01)


def test_atomic_write_replaces_whole_file_and_leaves_no_temporary(tmp_path: Path) -> None:
    target = tmp_path / "sub" / "file.txt"
    writers.atomic_write_text(target, "old")
    writers.atomic_write_text(target, "new")
    assert target.read_text() == "new"
    assert os.listdir(target.parent) == ["file.txt"]


def test_atomic_write_failure_keeps_old_file_and_removes_temporary(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    target = tmp_path / "file.txt"
    target.write_text("old")

    def broken_replace(source: str, destination: object) -> None:
        raise OSError("disk full")

    monkeypatch.setattr(os, "replace", broken_replace)
    with pytest.raises(OSError, match="disk full"):
        writers.atomic_write_text(target, "new")
    assert target.read_text() == "old"
    assert os.listdir(tmp_path) == ["file.txt"]


def test_flaws_csv_and_json_agree_and_number_strongest_first() -> None:
    pair = make_pair()
    rows = list(csv.DictReader(io.StringIO(writers.flaws_csv(pair.flaws))))
    document = json.loads(writers.to_json(writers.flaws_document(pair.detection)))
    assert tuple(rows[0]) == writers.FLAW_COLUMNS
    assert [int(row["number"]) for row in rows] == [1, 2]
    assert document["count"] == 2
    assert document["flaws"][0]["score"] == pytest.approx(12.5)
    assert [row["polarity"] for row in rows] == [flaw["polarity"] for flaw in document["flaws"]]
    assert (document["flaws"][0]["row0"], document["flaws"][0]["col1"]) == (9, 22)


def test_ground_truth_verdict_column_when_known() -> None:
    rows = list(csv.DictReader(io.StringIO(writers.flaws_csv(make_flaws(), is_true=(True, False)))))
    assert [row["true_flaw"] for row in rows] == ["True", "False"]


def test_json_is_strict_non_finite_becomes_null() -> None:
    text = writers.to_json({"threshold": float("inf"), "values": np.array([1.0, np.nan]), "n": np.int64(3)})
    assert json.loads(text) == {"threshold": None, "values": [1.0, None], "n": 3}


def test_roc_csv_has_one_row_per_operating_point() -> None:
    curves = [
        RocCurve(np.array([1e-5, 1e-3]), np.array([0.5, 0.9]), np.array([4.4, 3.1]), "a"),
        RocCurve(np.array([1e-4]), np.array([0.7]), np.array([3.7]), "b"),
    ]
    rows = list(csv.DictReader(io.StringIO(writers.roc_csv(curves))))
    assert [row["label"] for row in rows] == ["a", "a", "b"]
    assert float(rows[2]["p_detection"]) == pytest.approx(0.7)


def test_pair_report_writes_every_file_and_valid_pictures(tmp_path: Path) -> None:
    files = writers.write_pair_report(tmp_path, make_pair())
    assert set(files) == {
        "flaws.json",
        "flaws.csv",
        "overlay.png",
        "difference.png",
        "score.png",
        "summary.json",
    }
    for name, path in files.items():
        assert path == tmp_path / name
        if name.endswith(".png"):
            decode_png(path.read_bytes())
    summary = json.loads((tmp_path / "summary.json").read_text())
    assert summary["flaws"] == 2
    assert summary["registration"] is None
    assert summary["valid_fraction"] == pytest.approx(57 / 60)
    assert not [name for name in os.listdir(tmp_path) if name.endswith(".tmp")]


def test_overlay_is_enlarged_by_a_whole_factor_and_draws_boxes() -> None:
    image = np.full(SHAPE, 0.5)
    plain = decode_png(figures.overlay_png(image, ()))
    boxed = decode_png(figures.overlay_png(image, make_flaws()))
    factor = -(-768 // max(SHAPE))
    assert plain.shape == (SHAPE[0] * factor, SHAPE[1] * factor, 3)
    assert (boxed != plain).any(axis=2).sum() > 0
    assert (plain[..., 0] == plain[..., 2]).all()  # without flaws: grey only


def test_invalid_pixels_are_mid_grey_and_zero_difference_is_the_colour_map_centre() -> None:
    difference = np.zeros(SHAPE)
    difference[0, 0], difference[0, 1] = -1.0, 1.0
    valid = np.ones(SHAPE, bool)
    valid[5, 5] = False
    image = decode_png(figures.colour_png(difference, cmap="RdBu_r", symmetric=True, valid=valid))
    assert tuple(image[5, 5]) == (96, 96, 96)
    centre = tuple(image[10, 10])
    assert tuple(image[0, 0]) != centre != tuple(image[0, 1])
    assert abs(int(centre[0]) - int(centre[2])) < 10  # RdBu's middle is near white/grey


def test_constant_image_renders() -> None:
    assert decode_png(figures.grey_png(np.ones(SHAPE))).shape == SHAPE


def test_unknown_colour_map_names_the_fix() -> None:
    with pytest.raises(InputError, match=r"cmap='nope'.*Try"):
        figures.colour_png(np.zeros(SHAPE), cmap="nope")


def test_roc_report_writes_png_and_csv(tmp_path: Path) -> None:
    curve = RocCurve(np.logspace(-6, 0, 10), np.linspace(0.1, 1, 10), np.linspace(5, 0, 10), "x: theory")
    measured = RocCurve(np.array([0.0, 1e-4]), np.array([0.8, 1.0]), np.array([6.0, 3.0]), "x: measured")
    files = writers.write_roc_report(tmp_path, [curve, measured], title="t")
    assert decode_png(files["roc.png"].read_bytes()).ndim == 3
    assert files["roc.csv"].read_text().count("\n") == 13


def test_report_imports_no_algorithm_and_plots_without_pyplot(tmp_path: Path) -> None:
    # ARCHITECTURE.md: report -> result records only. Drawing a ROC must not load a registration, a detector
    # or pyplot (a bare Agg Figure keeps no global state). The curve is a stand-in of the record's class name
    # (the report checks records by name, never importing their modules).
    code = (
        "import sys, numpy as np, rsi.report;"
        "from rsi.report.writers import write_roc_report;"
        "from types import SimpleNamespace;"
        "C = type('RocCurve', (SimpleNamespace,), {});"
        f"write_roc_report({str(tmp_path)!r}, [C(p_false_alarm=np.array([1e-5]), p_detection=np.array([0.5]),"
        " threshold=np.array([4.0]), label='a')]);"
        "bad = [m for m in ('rsi.imaging.registration', 'rsi.detection.detect', 'matplotlib.pyplot') "
        "if m in sys.modules]; print(bad)"
    )
    completed = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert completed.stdout.strip() == "[]"
    assert (tmp_path / "roc.png").exists()
