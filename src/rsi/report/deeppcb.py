"""A DeepPCB evaluation's results folder: the record as JSON, the official rule per class as a table and a bar
chart, and the confusion of paired boxes as a picture (``rsi eval deeppcb --out``, issue 12).

A view only: it draws the record :meth:`rsi.datasets.evaluate.EvaluationResult.to_dict` gives and computes
nothing. The confusion is drawn on a logarithmic colour scale: the diagonal holds a thousand boxes a class and
the confusions a few, and a linear scale shows only the diagonal.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from rsi._files import writable_folder
from rsi.errors import InputError
from rsi.report.figures import figure_png
from rsi.report.writers import csv_text, to_json, write_files

CLASS_COLUMNS = ("boxes", "detections", "precision", "recall", "ap")
"""Columns of per_class.csv after the class (the record's ``per_class`` keys, DeepPCB's official rule)."""
MAX_CLASSES = 64
"""Most classes a record may name: the pictures give each a row and a column (DeepPCB names 6)."""
_RATES = (("precision", "precision"), ("recall", "recall"), ("ap", "AP"))
_POOLED = (("official_f", "official F"), ("map", "mAP"))
_CountArray = NDArray[np.int64]


def _checked(record: object) -> tuple[dict[str, Mapping[str, float]], _CountArray]:
    """The record's per-class figures and its confusion (classes + 1 rows and columns: "none" first)."""
    if not isinstance(record, Mapping) or not isinstance(record.get("per_class"), Mapping):
        raise InputError(
            "record must be a DeepPCB evaluation record (EvaluationResult.to_dict()) holding per_class and "
            f"confusion; got {type(record).__name__} without per_class."
        )
    per_class = dict(record["per_class"])
    if not 0 < len(per_class) <= MAX_CLASSES:
        raise InputError(
            f"record['per_class'] must name 1 to {MAX_CLASSES} classes (DeepPCB has 6); got {len(per_class)}."
        )
    for name, row in per_class.items():
        if (
            not isinstance(name, str)
            or not isinstance(row, Mapping)
            or not all(_is_number(row.get(key)) for key in CLASS_COLUMNS)
        ):
            raise InputError(
                f"record['per_class'][{name!r:.40}] must hold a finite number for each of "
                f"{', '.join(CLASS_COLUMNS)}; got {row!r:.80}."
            )
    try:
        confusion = np.asarray(record.get("confusion"), dtype=np.int64)
    except (TypeError, ValueError, OverflowError):
        confusion = np.zeros((0, 0), dtype=np.int64)
    side = len(per_class) + 1
    if confusion.shape != (side, side) or (confusion < 0).any():
        raise InputError(
            f"record['confusion'] must be {side} x {side} counts >= 0 (none and the {len(per_class)} "
            f"classes, rows true, columns detected); got shape {confusion.shape}."
        )
    return per_class, confusion


def _is_number(value: object) -> bool:
    """A finite int or float, not a bool (the record's figures and counts)."""
    return isinstance(value, (int, float)) and not isinstance(value, bool) and math.isfinite(value)


def per_class_csv(record: Mapping[str, Any]) -> str:
    """The official rule per class as CSV: class, then :data:`CLASS_COLUMNS`."""
    per_class, _ = _checked(record)
    rows = [{"class": name, **{key: row[key] for key in CLASS_COLUMNS}} for name, row in per_class.items()]
    return csv_text(("class", *CLASS_COLUMNS), rows)


def per_class_png(record: Mapping[str, Any]) -> bytes:
    """Precision, recall and AP of each class (the official rule: IoU > 0.33 and the same class), as bars,
    with the pooled F-score and mAP in the title."""
    per_class, _ = _checked(record)
    from matplotlib.figure import Figure

    figure = Figure(figsize=(7.5, 4.0), dpi=100)
    axes = figure.subplots()
    names = list(per_class)
    positions = np.arange(len(names), dtype=np.float64)
    width = 0.8 / len(_RATES)
    lowest = 1.0
    for index, (key, label) in enumerate(_RATES):
        values = [float(per_class[name][key]) for name in names]
        lowest = min(lowest, *values)
        axes.bar(positions + (index - 1) * width, values, width, label=label)
    axes.set_xticks(positions, names, rotation=20, ha="right")
    # The figures sit near 1: the axis starts a little below the lowest, so that their differences show.
    axes.set_ylim(max(0.0, min(0.9, lowest - 0.02)), 1.0)
    axes.set_ylabel("official rule (IoU > 0.33, same class)")
    axes.grid(True, axis="y", alpha=0.3)
    axes.legend(loc="upper left", bbox_to_anchor=(1.0, 1.0), fontsize="small")  # beside: bars fill the axes
    axes.set_title(_title(record), fontsize="medium")
    return figure_png(figure)


def confusion_png(record: Mapping[str, Any]) -> bytes:
    """The confusion of paired boxes (rows: true class, columns: detected; "none" = a box missed or a false
    alarm) with each count written in its cell, on a logarithmic colour scale."""
    per_class, confusion = _checked(record)
    from matplotlib.colors import LogNorm
    from matplotlib.figure import Figure

    names = ["none", *per_class]
    figure = Figure(figsize=(7.0, 6.0), dpi=100)
    axes = figure.subplots()
    top = max(int(confusion.max()), 2)
    shown = np.ma.masked_equal(confusion, 0)  # an empty cell is left white: log(0) has no colour
    image = axes.imshow(shown, cmap="Blues", norm=LogNorm(vmin=1, vmax=top))
    for (row, col), count in np.ndenumerate(confusion):
        dark = count > 0 and np.log(count) > 0.6 * np.log(top)
        axes.text(col, row, str(count), ha="center", va="center", color="white" if dark else "black")
    axes.set_xticks(range(len(names)), names, rotation=30, ha="right")
    axes.set_yticks(range(len(names)), names)
    axes.set_xlabel("detected class")
    axes.set_ylabel("true class")
    axes.set_title(_title(record), fontsize="medium")
    figure.colorbar(image, ax=axes, label="boxes (log scale)")
    return figure_png(figure)


def _title(record: Mapping[str, Any]) -> str:
    """The pairs, the pooled official figures and who named the classes, as far as the record gives them."""
    parts = [f"{record['pairs']} pairs"] if _is_number(record.get("pairs")) else []
    parts += [f"{label} {float(record[key]):.4f}" for key, label in _POOLED if _is_number(record.get(key))]
    classes = record.get("classes")
    return ", ".join(parts) + (f"; classes: {classes}" if isinstance(classes, str) else "")


def write_deeppcb_report(out_dir: Path | str, record: Mapping[str, Any]) -> dict[str, Path]:
    """Write deeppcb.json (the record), per_class.csv, per_class.png and confusion.png to `out_dir`.

    Parameters
    ----------
    out_dir : path
        Results folder (created if missing; other files in it are kept).
    record : mapping
        :meth:`rsi.datasets.evaluate.EvaluationResult.to_dict` of an evaluation.

    Returns
    -------
    dict of str to Path
        File name -> written path.
    """
    writable_folder(out_dir, "out_dir")
    _checked(record)
    contents = {
        "deeppcb.json": to_json(record).encode(),
        "per_class.csv": per_class_csv(record).encode(),
        "per_class.png": per_class_png(record),
        "confusion.png": confusion_png(record),
    }
    return write_files(out_dir, contents)


__all__ = [
    "CLASS_COLUMNS",
    "MAX_CLASSES",
    "confusion_png",
    "per_class_csv",
    "per_class_png",
    "write_deeppcb_report",
]
