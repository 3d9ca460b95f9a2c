"""A batch's results folder: pairs.csv (one row per pair), flaws.csv (one row per flaw), batch.json.

A view only: every number written here sits in the batch's records (:mod:`rsi.mission.batch`). The columns
are a contract (docs/batch.md); each file is written atomically.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

from rsi import _validate as v
from rsi._files import writable_folder
from rsi.errors import InputError
from rsi.report.writers import FLAW_COLUMNS as _PAIR_FLAW_COLUMNS
from rsi.report.writers import csv_text, flaw_records, to_json, write_files

if TYPE_CHECKING:
    from rsi.mission.batch import BatchResult
    from rsi.mission.batch_manifest import BatchItem

PAIR_COLUMNS = ("pair_id", "status", "flaws", "stage", "error", "reference", "inspection", "read_s",
                "inspect_s", "worker")  # fmt: skip
"""Columns of pairs.csv."""
FLAW_COLUMNS = ("pair_id", *_PAIR_FLAW_COLUMNS, "confidence")
"""Columns of flaws.csv: the pair, then a single pair's flaw columns, then the flaw's confidence."""


def pair_rows(result: BatchResult, items: Sequence[BatchItem]) -> list[dict[str, Any]]:
    """One plain dict per pair (:data:`PAIR_COLUMNS`), in the order of `items` (the records' order)."""
    _batch(result, items)
    return [
        {
            "pair_id": record.pair_id,
            "status": record.status,
            "flaws": len(record.flaws),
            "stage": record.stage or "",
            "error": record.error or "",
            "reference": str(item.reference),
            "inspection": str(item.inspection),
            "read_s": f"{record.read_s:.4f}",
            "inspect_s": f"{record.inspect_s:.4f}",
            "worker": record.worker,
        }
        for item, record in zip(items, result.records, strict=True)
    ]


def batch_flaw_rows(result: BatchResult) -> list[dict[str, Any]]:
    """One plain dict per flaw of every pair (:data:`FLAW_COLUMNS`), pairs in order, strongest flaw first."""
    v.record_named(result, "result", "BatchResult")
    return [
        {"pair_id": record.pair_id, **row, "confidence": confidence}
        for record in result.records
        for row, confidence in zip(flaw_records(record.flaws), record.confidences, strict=True)
    ]


def write_batch_report(
    out_dir: Path | str, result: BatchResult, items: Sequence[BatchItem]
) -> dict[str, Path]:
    """Write pairs.csv, flaws.csv and batch.json (``result.summary()``) for a finished batch.

    Parameters
    ----------
    out_dir : path
        Results folder (created if missing).
    result : BatchResult
        The batch.
    items : sequence of BatchItem
        The batch's pairs, in the order of ``result.records``.

    Returns
    -------
    dict of str to Path
        File name -> written path.
    """
    writable_folder(out_dir, "out_dir")
    _batch(result, items)
    contents = {
        "pairs.csv": csv_text(PAIR_COLUMNS, pair_rows(result, items)).encode(),
        "flaws.csv": csv_text(FLAW_COLUMNS, batch_flaw_rows(result)).encode(),
        "batch.json": to_json(result.summary()).encode(),
    }
    return write_files(out_dir, contents)


def _batch(result: object, items: object) -> None:
    v.record_named(result, "result", "BatchResult")
    listed = v.records_named(items, "items", "BatchItem")
    records = getattr(result, "records", ())
    if len(listed) != len(records):
        raise InputError(
            f"items must hold one BatchItem per record of result ({len(records)}); got {len(listed)}. "
            "Pass the manifest's items the batch ran."
        )
