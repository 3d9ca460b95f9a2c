"""Write result records to a results folder: PNG pictures, ROC plot and table, flaws.json/csv, summary.json.

A view only: every number written here was computed by the algorithms and sits in the record. Each file is
written atomically (temporary file in the same folder, then ``os.replace``), so a crash or a concurrent
reader never sees half a file.
"""

from __future__ import annotations

import csv
import io
import json
import math
import os
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from rsi import _validate as v
from rsi._files import atomic_write_bytes, name_fits, writable_folder
from rsi.errors import InputError
from rsi.report import figures

if TYPE_CHECKING:
    from rsi.datasets.demo import DemoResult
    from rsi.detection.detect import Detection, Flaw
    from rsi.detection.pair import PairResult
    from rsi.detection.roc import RocCurve
    from rsi.imaging.registration import Registration

FLAW_COLUMNS = ("number", "row", "col", "row0", "col0", "row1", "col1", "area_px", "score", "polarity")
"""Columns of flaws.csv (and keys of each flaw in flaws.json); ``number`` matches the overlay labels."""
ROC_COLUMNS = ("label", "threshold", "p_false_alarm", "p_detection")


def atomic_write_text(path: Path | str, text: str) -> Path:
    """Write UTF-8 `text` to `path` atomically (see :func:`atomic_write_bytes`)."""
    _path(path, "path")
    _text(text, "text")
    return atomic_write_bytes(path, text.encode("utf-8"))


def json_ready(value: Any) -> Any:
    """Convert numpy scalars/arrays, tuples and paths to JSON types; NaN and inf become null (strict JSON)."""
    if isinstance(value, os.PathLike):
        return os.fspath(value)
    if isinstance(value, Mapping):
        return {str(key): json_ready(item) for key, item in value.items()}
    if isinstance(value, (list, tuple, np.ndarray)):
        return [json_ready(item) for item in value]
    if isinstance(value, (bool, np.bool_)):
        return bool(value)
    if isinstance(value, (int, np.integer)):
        return int(value)
    if isinstance(value, (float, np.floating)):
        number = float(value)
        return number if math.isfinite(number) else None
    return value


def to_json(record: Mapping[str, Any]) -> str:
    """Serialise a record to strict JSON (no NaN/inf), indented, with a trailing newline."""
    if not isinstance(record, Mapping):
        raise InputError(f"record must be a mapping (a dict); got {type(record).__name__}.")
    return json.dumps(json_ready(record), indent=2, allow_nan=False) + "\n"


def flaw_records(flaws: Sequence[Flaw], *, is_true: Sequence[bool] | None = None) -> list[dict[str, Any]]:
    """One plain dict per flaw with the :data:`FLAW_COLUMNS` (plus ``true_flaw`` when `is_true` is given).

    Parameters
    ----------
    flaws : sequence of Flaw
        Flaws, strongest first; ``number`` is the 1-based position.
    is_true : sequence of bool, optional
        Ground-truth verdict per flaw (the demo knows it).

    Returns
    -------
    list of dict
    """
    flaws = v.records_named(flaws, "flaws", "Flaw")
    _flags(is_true, "is_true", len(flaws))
    records = []
    for number, flaw in enumerate(flaws, start=1):
        row0, col0, row1, col1 = flaw.bbox
        record: dict[str, Any] = {
            "number": number,
            "row": float(flaw.row),
            "col": float(flaw.col),
            "row0": int(row0),
            "col0": int(col0),
            "row1": int(row1),
            "col1": int(col1),
            "area_px": int(flaw.area_px),
            "score": float(flaw.score),
            "polarity": flaw.polarity,
        }
        if is_true is not None:
            record["true_flaw"] = bool(is_true[number - 1])
        records.append(record)
    return records


def flaws_document(detection: Detection, *, is_true: Sequence[bool] | None = None) -> dict[str, Any]:
    """flaws.json content: the test's settings and threshold, then the flaws (strongest first)."""
    v.record_named(detection, "detection", "Detection")
    return {
        "count": len(detection.flaws),
        "flaw_model": detection.flaw_model,
        "method": detection.method,
        "polarity": detection.polarity,
        "p_false_alarm": detection.p_false_alarm,
        "threshold": detection.threshold,
        "flaws": flaw_records(detection.flaws, is_true=is_true),
    }


def csv_text(columns: Sequence[str], rows: Sequence[Mapping[str, Any]]) -> str:
    _texts(columns, "columns")
    _rows(rows, "rows")
    buffer = io.StringIO()
    writer = csv.DictWriter(buffer, fieldnames=list(columns), extrasaction="ignore", lineterminator="\n")
    writer.writeheader()
    writer.writerows(rows)
    return buffer.getvalue()


def flaws_csv(flaws: Sequence[Flaw], *, is_true: Sequence[bool] | None = None) -> str:
    """flaws.csv content: a header of :data:`FLAW_COLUMNS` (+ ``true_flaw``) and one row per flaw."""
    columns = (*FLAW_COLUMNS, "true_flaw") if is_true is not None else FLAW_COLUMNS
    return csv_text(columns, flaw_records(flaws, is_true=is_true))


def roc_csv(curves: Sequence[RocCurve]) -> str:
    """ROC table in long form: one row per (curve, operating point) with :data:`ROC_COLUMNS`."""
    v.records_named(curves, "curves", "RocCurve")
    rows = [
        {
            "label": curve.label,
            "threshold": threshold,
            "p_false_alarm": p_false_alarm,
            "p_detection": p_detection,
        }
        for curve in curves
        for threshold, p_false_alarm, p_detection in zip(
            np.ravel(curve.threshold), np.ravel(curve.p_false_alarm), np.ravel(curve.p_detection), strict=True
        )
    ]
    return csv_text(ROC_COLUMNS, rows)


def registration_record(registration: Registration | None) -> dict[str, Any] | None:
    """Plain dict of a registration result (None stays None), for JSON and tables."""
    if registration is not None:
        v.record_named(registration, "registration", "Registration")
    if registration is None:
        return None
    return {
        "model": registration.model,
        "matrix": np.asarray(registration.matrix).tolist(),
        "translation_xy": tuple(registration.translation_xy),
        "gain": registration.gain,
        "bias": registration.bias,
        "converged": registration.converged,
        "reason": registration.reason,
        "iterations": registration.iterations,
        "residual_rms": registration.residual_rms,
        "shift_std_px": tuple(registration.shift_std_px),
        "elapsed_s": registration.elapsed_s,
        **_local_record(registration),
    }


def _local_record(registration: Registration) -> dict[str, Any]:
    """A local registration's field in brief: its size, worst uncertainty and the tiles that fell back."""
    local = registration.local
    if local is None:
        return {}
    return {
        "tile_px": local.tile_px,
        "field_max_px": float(np.abs(local.shift_xy).max(initial=0.0)),
        "field_std_max_px": float(local.shift_std_px.max(initial=0.0)),
        "fallback_tiles": [[int(row), int(col)] for row, col in np.argwhere(local.fallback)],
    }


def pair_summary(result: PairResult) -> dict[str, Any]:
    """summary.json content for one inspected pair: settings, threshold, registration, flaw count, timing."""
    v.record_named(result, "result", "PairResult")
    detection = result.detection
    return {
        "shape": result.inspection.shape,
        "flaw_model": detection.flaw_model,
        "method": detection.method,
        "polarity": detection.polarity,
        "p_false_alarm": detection.p_false_alarm,
        "threshold": detection.threshold,
        "flaws": len(detection.flaws),
        "valid_fraction": float(np.mean(detection.valid)),
        "registration": registration_record(result.registration),
        "elapsed_s": result.elapsed_s,
    }


def demo_summary(demo: DemoResult) -> dict[str, Any]:
    """summary.json content for the demo: the pair summary plus the truth and the score against it."""
    v.record_named(demo, "demo", "DemoResult")
    score = demo.score
    return {
        "seed": demo.seed,
        **pair_summary(demo.pair),
        "true_shift_xy": demo.shift_xy,
        "seeded_flaws": score.truth_count,
        "found_flaws": score.found_count,
        "recall": score.recall,
        "precision": score.precision,
        "false_alarms": score.false_alarms,
        "single_pixel_flaws": len(demo.single_pixel.flaws),
        "simulation_s": demo.elapsed_s,
    }


def _pair_files(result: PairResult, *, is_true: Sequence[bool] | None = None) -> dict[str, bytes]:
    detection = result.detection
    return {
        "flaws.json": to_json(flaws_document(detection, is_true=is_true)).encode(),
        "flaws.csv": flaws_csv(detection.flaws, is_true=is_true).encode(),
        "overlay.png": figures.overlay_png(result.inspection, detection.flaws, valid=detection.valid),
        "difference.png": figures.colour_png(
            detection.difference, cmap="RdBu_r", symmetric=True, valid=detection.valid
        ),
        "score.png": figures.colour_png(detection.score, cmap="magma", valid=detection.valid),
        "summary.json": to_json(pair_summary(result)).encode(),
    }


def write_files(out_dir: Path | str, contents: Mapping[str, bytes]) -> dict[str, Path]:
    writable_folder(out_dir, "out_dir")
    _contents(contents)
    folder = Path(out_dir)
    return {name: atomic_write_bytes(folder / name, data) for name, data in contents.items()}


def write_pair_report(out_dir: Path | str, result: PairResult) -> dict[str, Path]:
    """Write flaws.json, flaws.csv, overlay.png, difference.png, score.png and summary.json for one pair.

    Parameters
    ----------
    out_dir : path
        Results folder (created if missing).
    result : PairResult
        The inspected pair.

    Returns
    -------
    dict of str to Path
        File name -> written path.
    """
    writable_folder(out_dir, "out_dir")
    v.record_named(result, "result", "PairResult")
    return write_files(out_dir, _pair_files(result))


def write_roc_report(
    out_dir: Path | str, curves: Sequence[RocCurve], *, title: str = "ROC"
) -> dict[str, Path]:
    """Write roc.png (P_D against P_F, seed §2.4) and roc.csv for the given curves.

    Parameters
    ----------
    out_dir : path
        Results folder (created if missing).
    curves : sequence of RocCurve
        Curves to plot and tabulate, each with its `label`.
    title : str
        Plot title.

    Returns
    -------
    dict of str to Path
        File name -> written path.
    """
    writable_folder(out_dir, "out_dir")
    v.records_named(curves, "curves", "RocCurve")
    _text(title, "title")
    contents = {"roc.png": figures.roc_png(curves, title=title), "roc.csv": roc_csv(curves).encode()}
    return write_files(out_dir, contents)


def write_demo_report(out_dir: Path | str, demo: DemoResult) -> dict[str, Path]:
    """Write the demo's results folder.

    Files: reference.png and inspection.png (raw interlaced frames), reference_compensated.png and
    inspection_compensated.png (strobe-only estimates, seed §2.2), difference.png, score.png, overlay.png
    (numbered flaw boxes), roc.png and roc.csv (theory against measurement, seed §2.4), flaws.json and
    flaws.csv (with each flaw's ground-truth verdict) and summary.json (recall, false alarms, registration).

    Parameters
    ----------
    out_dir : path
        Results folder (created if missing).
    demo : DemoResult
        The simulated run.

    Returns
    -------
    dict of str to Path
        File name -> written path.
    """
    writable_folder(out_dir, "out_dir")
    v.record_named(demo, "demo", "DemoResult")
    reference, inspection = demo.reference_compensated, demo.inspection_compensated
    contents = {
        "reference.png": figures.grey_png(demo.reference_frame.raw),
        "inspection.png": figures.grey_png(demo.inspection_frame.raw),
        "reference_compensated.png": figures.grey_png(reference.image, valid=reference.valid),
        "inspection_compensated.png": figures.grey_png(inspection.image, valid=inspection.valid),
        **_pair_files(demo.pair, is_true=demo.score.is_true),
        "summary.json": to_json(demo_summary(demo)).encode(),
    }
    files = write_files(out_dir, contents)
    title = f"Demo ROC: {demo.pair.detection.flaw_model} and single-pixel flaw models (seed {demo.seed})"
    files.update(write_roc_report(out_dir, demo.curves, title=title))
    return files


def _path(value: object, name: str) -> None:
    if not isinstance(value, (str, os.PathLike)) or not str(value):
        raise InputError(f"{name} must be a file path (str or pathlib.Path); got {value!r:.80}.")
    name_fits(Path(value), name)


def _text(value: object, name: str) -> None:
    if not isinstance(value, str):
        raise InputError(f"{name} must be a str; got {type(value).__name__} {value!r:.60}.")


def _texts(value: object, name: str) -> None:
    if not isinstance(value, (list, tuple)) or not all(isinstance(item, str) for item in value):
        raise InputError(f"{name} must be a list of str (the column names); got {value!r:.80}.")


def _rows(value: object, name: str) -> None:
    if not isinstance(value, (list, tuple)) or not all(isinstance(item, Mapping) for item in value):
        raise InputError(f"{name} must be a list of dicts (one per row); got {value!r:.80}.")


def _flags(value: object, name: str, count: int) -> None:
    """None, or one truth value per flaw (a list or tuple of `count` bools)."""
    if value is None:
        return
    if not isinstance(value, (list, tuple, np.ndarray)) or len(value) != count:
        raise InputError(f"{name} must be None or {count} bools, one per flaw; got {value!r:.80}.")


def _contents(value: object) -> None:
    if not isinstance(value, Mapping) or not all(
        isinstance(key, str) and key and isinstance(data, bytes) for key, data in value.items()
    ):
        raise InputError(f"contents must map file names (str) to bytes; got {value!r:.80}.")
    for key in value:
        name_fits(Path(key), "contents")
