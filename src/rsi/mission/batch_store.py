"""The batch's archive writes: one run, pose-less vistas named by pair id, short buffered transactions.

Only the driver writes (one writer, one run): finished pairs are buffered and written in short transactions
as they arrive, so a batch that dies keeps every pair already written (docs/batch.md).
"""

from __future__ import annotations

import contextlib
import time
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from rsi.archive import Archive, Finding
    from rsi.mission.batch_manifest import BatchItem
    from rsi.mission.batch_records import PairRecord

FINDING_KINDS = {"flaw": "flaw", "inspected": "inspected", "failure": "failure"}
"""Kinds of the findings a batch stores: one ``"flaw"`` per detected flaw, one ``"inspected"`` summary per
pair that ran (so a pair with no flaw still leaves a trace in the run), one ``"failure"`` per pair that did
not."""
WHOLE_PAIR_BBOX = (0, 0, 1, 1)
"""Placeholder bbox of a failure record: a failure concerns the whole pair, whose size may be unknown."""
FLUSH_PAIRS = 64
FLUSH_S = 1.0
"""The driver writes buffered results when this many pairs are waiting or this many seconds have passed:
short transactions (few fsyncs) that never hold the archive's write lock for long."""


def abandon_run(archive: Archive, run_id: int, writer: RunWriter, *, interrupted: bool) -> None:
    """Keep what was computed and mark the run as not finished; never mask the error that stopped it."""
    with contextlib.suppress(Exception):
        writer.flush()
    with contextlib.suppress(Exception):
        archive.finish_run(run_id, "aborted" if interrupted else "failed")


class RunWriter:
    """Buffers finished pairs and writes them to the run in short transactions (the driver is the only
    writer): pose-less vistas for new pair ids first, then every buffered finding in one add_findings."""

    def __init__(self, archive: Archive, run_id: int, batch: tuple[BatchItem, ...]) -> None:
        self._archive = archive
        self._run_id = run_id
        self._batch = batch
        self._known = {vista.name for vista in archive.vistas()}
        self._pending: list[tuple[int, PairRecord]] = []
        self._last_flush_s = time.perf_counter()

    def add(self, index: int, record: PairRecord) -> None:
        self._pending.append((index, record))
        if len(self._pending) >= FLUSH_PAIRS or time.perf_counter() - self._last_flush_s >= FLUSH_S:
            self.flush()

    def flush(self) -> None:
        pending, self._pending = sorted(self._pending, key=lambda entry: entry[0]), []
        self._last_flush_s = time.perf_counter()
        if not pending:
            return
        for _, record in pending:
            if record.pair_id not in self._known:
                self._archive.add_vista(record.pair_id)
                self._known.add(record.pair_id)
        findings = [finding for index, record in pending for finding in _findings(self._batch[index], record)]
        self._archive.add_findings(self._run_id, findings)


def _findings(item: BatchItem, record: PairRecord) -> list[Finding]:
    from rsi.archive import Finding

    paths = {"reference": str(item.reference), "inspection": str(item.inspection)}
    timings = {"read_s": record.read_s, "inspect_s": record.inspect_s, "worker": record.worker}
    if not record.ok:
        extras = {"error": record.error, "stage": record.stage, **paths, **timings}
        return [Finding(item.pair_id, FINDING_KINDS["failure"], 1.0, bbox=WHOLE_PAIR_BBOX, extras=extras)]
    assert record.shape is not None
    rows, cols = record.shape
    summary = Finding(
        item.pair_id,
        FINDING_KINDS["inspected"],
        1.0,
        bbox=(0, 0, rows, cols),
        extras={
            "flaws": len(record.flaws),
            "threshold": record.threshold,
            "translation_xy": None if record.translation_xy is None else list(record.translation_xy),
            "converged": record.converged,
            **paths,
            **timings,
        },
    )
    flaws = [
        Finding.from_flaw(flaw, vista=item.pair_id, confidence=confidence, kind=FINDING_KINDS["flaw"])
        for flaw, confidence in zip(record.flaws, record.confidences, strict=True)
    ]
    return [summary, *flaws]


# run_batch's internals, no public API (PEP 8: an empty __all__): every caller is
# :func:`rsi.mission.run_batch`, with values it built and checked (docs/reliability.md).
__all__: list[str] = []
