"""Batch inspection of many reference/inspection image pairs, scaled out with dask.distributed.

A manifest (CSV) lists the pairs; :func:`read_manifest` (:mod:`rsi.mission.batch_manifest`) checks it whole
before anything runs, and :func:`run_batch` sends one task per pair to a cluster
(:mod:`rsi.mission.batch_cluster`): local worker processes by default (one single-threaded process per
core), or an existing cluster by its scheduler address, with the same code. Each task reads its two images,
runs :func:`rsi.detection.pair.inspect_pair` (seed §2.3-2.4: register, then test every pixel at a chosen
false-alarm probability) and returns a plain :class:`PairRecord`: the detector's own flaws and the timings,
or the error that stopped the pair. A task never raises, so a bad pair is reported and skipped and never
stops the batch. Only the driver writes to the archive (one writer, one run), in short transactions as
results arrive, so a batch that dies keeps every pair already written. The results folder (pairs.csv,
flaws.csv, batch.json) is drawn by :func:`rsi.report.batch.write_batch_report`.

Two kinds of bad input, two behaviours (see docs/batch.md):

- a *malformed manifest row* (wrong field count, empty path, unknown setting, bad value, duplicate id) is a
  mistake in the list itself: :func:`read_manifest` raises one :class:`~rsi.errors.DatasetError` naming the
  file and every bad line, before any pair runs or anything is stored;
- a *bad pair* (missing, unreadable or corrupt image, images that cannot be compared) is only found by
  reading it: it becomes a failure record, stored in the archive as a finding of kind ``"failure"``.

Importing this module stays cheap: dask, OpenCV and the archive load when a function runs.
"""

from __future__ import annotations

import math
import os
import socket
import time
from collections.abc import Callable, Sequence
from dataclasses import asdict, dataclass, replace
from typing import TYPE_CHECKING, Any

from rsi import _validate as v
from rsi.errors import InputError
from rsi.mission.batch_cluster import (
    CONNECT_TIMEOUT_S,
    MAX_CLUSTER_WORKERS,
    MAX_CONNECT_TIMEOUT_S,
    max_local_workers,
    open_cluster,
)
from rsi.mission.batch_manifest import (
    FLAW_MODELS,
    MANIFEST_COLUMNS,
    MAX_FIELD_CHARS,
    MAX_MANIFEST_BYTES,
    METHODS,
    POLARITIES,
    REGISTRATION_MODELS,
    REQUIRED_COLUMNS,
    SETTING_COLUMNS,
    BatchItem,
    PairSettings,
    read_manifest,
)
from rsi.mission.batch_records import PairRecord, flaw_confidence
from rsi.mission.batch_store import FINDING_KINDS, RunWriter, abandon_run

if TYPE_CHECKING:
    from distributed import Client, Future

    from rsi.archive import Archive

__all__ = [
    "CONNECT_TIMEOUT_S",
    "FINDING_KINDS",
    "FLAW_MODELS",
    "MANIFEST_COLUMNS",
    "MAX_CLUSTER_WORKERS",
    "MAX_CONNECT_TIMEOUT_S",
    "MAX_FIELD_CHARS",
    "MAX_MANIFEST_BYTES",
    "METHODS",
    "POLARITIES",
    "REGISTRATION_MODELS",
    "REQUIRED_COLUMNS",
    "SETTING_COLUMNS",
    "BatchItem",
    "BatchResult",
    "PairRecord",
    "PairSettings",
    "ProgressFn",
    "flaw_confidence",
    "inspect_item",
    "inspect_sequentially",
    "max_local_workers",
    "read_manifest",
    "run_batch",
]

ProgressFn = Callable[[str, int, int], None]
"""Called as ``progress(pair_id, completed, total)`` each time a pair finishes (inspected or failed)."""


@dataclass(frozen=True)
class BatchResult:
    """A finished batch.

    Attributes
    ----------
    run_id : int
        The archive run holding every pair's results and failures.
    records : tuple of PairRecord
        One per pair, in the order the pairs were given (not the order they finished).
    workers : int
        Worker processes (or threads) the cluster had when the batch started.
    scheduler : str
        ``"local"`` or the address of the cluster used.
    startup_s : float
        Seconds to start (or connect to) the cluster.
    elapsed_s : float
        Wall time of the whole batch: cluster start, every pair, every archive write, shutdown excluded.
    """

    run_id: int
    records: tuple[PairRecord, ...]
    workers: int
    scheduler: str
    startup_s: float
    elapsed_s: float

    @property
    def failures(self) -> tuple[PairRecord, ...]:
        """The pairs that could not be inspected, in input order."""
        return tuple(record for record in self.records if not record.ok)

    @property
    def flaw_count(self) -> int:
        """Flaws found over all pairs."""
        return sum(len(record.flaws) for record in self.records)

    @property
    def pairs_per_s(self) -> float:
        """Pairs finished (inspected or failed) per second of :attr:`elapsed_s`, cluster start included."""
        return len(self.records) / self.elapsed_s if self.elapsed_s > 0 else math.inf

    def summary(self) -> dict[str, Any]:
        """Plain dict of the figures (for JSON): counts, timings, throughput and each failure."""
        return {
            "run_id": self.run_id,
            "pairs": len(self.records),
            "inspected": len(self.records) - len(self.failures),
            "failures": len(self.failures),
            "flaws": self.flaw_count,
            "workers": self.workers,
            "scheduler": self.scheduler,
            "startup_s": self.startup_s,
            "elapsed_s": self.elapsed_s,
            "pairs_per_s": self.pairs_per_s,
            "failed": [
                {"pair_id": record.pair_id, "stage": record.stage, "error": record.error}
                for record in self.failures
            ],
        }


# ------------------------------------------------------------------------------------------- one task


def inspect_item(item: BatchItem, settings: PairSettings) -> PairRecord:
    """Read and inspect one pair and return its record; the task each worker runs. Never raises.

    Parameters
    ----------
    item : BatchItem
        The pair.
    settings : PairSettings
        The pair's settings (the run's, with the item's overrides applied).

    Returns
    -------
    PairRecord
        ``status="ok"`` with the flaws, or ``status="failed"`` with the error and the stage it stopped at.
    """
    v.instance_of(item, "item", BatchItem)
    v.instance_of(settings, "settings", PairSettings)
    worker = f"{socket.gethostname()}:{os.getpid()}"
    start_s = time.perf_counter()
    try:
        import cv2

        from rsi.imaging.io import read_image

        # One pair per worker thread is the unit of parallelism: OpenCV's own pool would only oversubscribe.
        cv2.setNumThreads(1)
        reference = read_image(item.reference)
        inspection = read_image(item.inspection)
    except Exception as error:
        return _failed(item, "read", error, read_s=time.perf_counter() - start_s, worker=worker)
    read_s = time.perf_counter() - start_s
    try:
        from rsi.detection.pair import inspect_pair

        result = inspect_pair(reference, inspection, **asdict(settings))
        detection = result.detection
        registration = result.registration
        translation = None if registration is None else tuple(map(float, registration.translation_xy))
    except Exception as error:
        inspect_s = time.perf_counter() - start_s - read_s
        return _failed(item, "inspect", error, read_s=read_s, inspect_s=inspect_s, worker=worker)
    rows, cols = inspection.shape
    return PairRecord(
        pair_id=item.pair_id,
        status="ok",
        flaws=tuple(result.flaws),
        shape=(int(rows), int(cols)),
        threshold=float(detection.threshold),
        translation_xy=None if translation is None else (translation[0], translation[1]),
        converged=None if registration is None else bool(registration.converged),
        tested_polarity=settings.polarity,
        read_s=read_s,
        inspect_s=time.perf_counter() - start_s - read_s,
        worker=worker,
    )


def _failed(
    item: BatchItem,
    stage: str,
    error: BaseException | str,
    *,
    read_s: float = 0.0,
    inspect_s: float = 0.0,
    worker: str = "",
) -> PairRecord:
    message = error if isinstance(error, str) else f"{type(error).__name__}: {error}"
    return PairRecord(
        pair_id=item.pair_id,
        status="failed",
        error=" ".join(message.split()),
        stage=stage,
        read_s=read_s,
        inspect_s=inspect_s,
        worker=worker,
    )


# ------------------------------------------------------------------------------------------- the driver


def run_batch(
    items: Sequence[BatchItem],
    *,
    archive: Archive,
    scheduler: str | None = None,
    workers: int | None = None,
    settings: PairSettings | None = None,
    label: str = "batch",
    progress: ProgressFn | None = None,
    connect_timeout_s: float = CONNECT_TIMEOUT_S,
) -> BatchResult:
    """Inspect many pairs in parallel with dask.distributed and store every result and failure in one run.

    Parameters
    ----------
    items : sequence of BatchItem
        The pairs (e.g. from :func:`read_manifest`); ids must be unique.
    archive : Archive
        Open archive; this process is its only writer for the run. Each pair's id becomes a (pose-less)
        vista holding its findings (:data:`FINDING_KINDS`: flaws, an inspected summary, or a failure).
    scheduler : str, optional
        Address of an existing dask scheduler (``tcp://host:8786``). Default: local worker processes, one
        thread each, started for this batch and closed after it.
    workers : int, optional
        Local worker processes (default: the CPU count); with `scheduler`, the workers to wait for.
    settings : PairSettings, optional
        Settings of every pair (each item's overrides applied on top). Default: ``PairSettings()``.
    label : str
        Label of the archive run.
    progress : callable, optional
        ``progress(pair_id, completed, total)`` after each finished pair.
    connect_timeout_s : float
        How long to wait for `scheduler` (and its workers) before giving up.

    Returns
    -------
    BatchResult
        Its results folder is drawn by :func:`rsi.report.batch.write_batch_report`.

    Raises
    ------
    InputError
        For bad arguments (before anything is stored) and a scheduler that cannot be reached; never for a
        bad pair. A stopped driver (Ctrl-C, a failing archive) keeps the pairs written; the run is "aborted"
        or "failed".
    """
    batch, pair_settings = _checked(items, settings)
    workers, connect_timeout_s = _checked_cluster(archive, scheduler, workers, connect_timeout_s)
    start_s = time.perf_counter()
    with open_cluster(scheduler, workers, connect_timeout_s) as client:
        startup_s = time.perf_counter() - start_s
        worker_count = len(client.scheduler_info()["workers"])
        about = {"pairs": len(batch), "scheduler": scheduler or "local", "workers": worker_count,
                 "settings": asdict(settings or PairSettings())}  # fmt: skip
        run_id = archive.start_run(label=label, settings={"batch": about})
        records = _run(
            client, archive, run_id=run_id, batch=batch, pair_settings=pair_settings, progress=progress
        )
        elapsed_s = time.perf_counter() - start_s
    return BatchResult(run_id, records, worker_count, scheduler or "local", startup_s, elapsed_s)


def _checked_cluster(
    archive: Archive, scheduler: str | None, workers: int | None, connect_timeout_s: float
) -> tuple[int | None, float]:
    """The archive, scheduler, worker count and timeout checked; returns (workers, connect_timeout_s)."""
    from rsi.archive import Archive

    v.instance_of(archive, "archive", Archive)
    if scheduler is not None and (
        not isinstance(scheduler, str) or not scheduler.strip() or len(scheduler) > 1000
    ):
        raise InputError(f"scheduler must be an address such as 'tcp://host:8786'; got {scheduler!r:.80}.")
    if workers is not None:
        most = MAX_CLUSTER_WORKERS if scheduler is not None else max_local_workers()
        workers = v.positive_int(workers, "workers", maximum=most)
    timeout_s = v.in_range(
        connect_timeout_s, "connect_timeout_s", low=0.0, high=MAX_CONNECT_TIMEOUT_S, low_inclusive=False
    )
    return workers, timeout_s


def _run(
    client: Client,
    archive: Archive,
    *,
    run_id: int,
    batch: tuple[BatchItem, ...],
    pair_settings: tuple[PairSettings, ...],
    progress: ProgressFn | None,
) -> tuple[PairRecord, ...]:
    """Every pair's record, each stored as it arrives; the run finished, or marked aborted/failed."""
    writer = RunWriter(archive, run_id, batch)
    try:
        records = _gather(
            client, run_id=run_id, batch=batch, pair_settings=pair_settings, writer=writer, progress=progress
        )
        writer.flush()
    except BaseException as error:
        abandon_run(archive, run_id, writer, interrupted=isinstance(error, KeyboardInterrupt))
        raise
    archive.finish_run(run_id)
    return records


def _checked(
    items: Sequence[BatchItem], settings: PairSettings | None
) -> tuple[tuple[BatchItem, ...], tuple[PairSettings, ...]]:
    if isinstance(items, (str, bytes, os.PathLike)) or not isinstance(items, Sequence):
        raise InputError(
            f"items must be a sequence of BatchItem; got {type(items).__name__}. "
            "Read a manifest with read_manifest(path)."
        )
    batch = tuple(items)
    if not batch:
        raise InputError("items is empty; give at least one BatchItem.")
    seen: set[str] = set()
    for index, item in enumerate(batch):
        if not isinstance(item, BatchItem):
            raise InputError(f"items[{index}] must be a BatchItem; got {type(item).__name__}.")
        if item.pair_id in seen:
            raise InputError(f"items[{index}] repeats pair_id {item.pair_id!r}; pair ids must be unique.")
        seen.add(item.pair_id)
    if settings is not None and not isinstance(settings, PairSettings):
        raise InputError(
            f"settings must be a PairSettings; got {type(settings).__name__}. Try PairSettings(**settings)."
        )
    base = settings or PairSettings()
    return batch, tuple(replace(base, **item.settings) for item in batch)


def _gather(
    client: Client,
    *,
    run_id: int,
    batch: tuple[BatchItem, ...],
    pair_settings: tuple[PairSettings, ...],
    writer: RunWriter,
    progress: ProgressFn | None,
) -> tuple[PairRecord, ...]:
    from distributed import as_completed

    # Keys name the run and the pair's index: unique on a shared cluster, and no hashing of the arguments.
    keys = [f"rsi-batch-{run_id}-{os.getpid()}-{index}" for index in range(len(batch))]
    futures = client.map(inspect_item, batch, pair_settings, key=keys, pure=False)
    index_of = {future.key: index for index, future in enumerate(futures)}
    records: list[PairRecord | None] = [None] * len(batch)
    for completed, future in enumerate(as_completed(futures), start=1):  # type: ignore[no-untyped-call]
        index = index_of[future.key]
        record = _outcome(future, batch[index])
        records[index] = record
        future.release()
        writer.add(index, record)
        if progress is not None:
            progress(record.pair_id, completed, len(batch))
    return tuple(record for record in records if record is not None)


def _outcome(future: Future[PairRecord], item: BatchItem) -> PairRecord:
    """The task's record; a task lost by the cluster (a dead worker, a cancelled key) becomes a failure."""
    try:
        record = future.result()
    except (KeyboardInterrupt, SystemExit):
        raise
    except BaseException as error:  # CancelledError is a BaseException
        return _failed(item, "worker", error)
    if not isinstance(record, PairRecord):
        return _failed(item, "worker", f"the task returned {type(record).__name__}, not a PairRecord")
    return record


def inspect_sequentially(
    items: Sequence[BatchItem], *, settings: PairSettings | None = None
) -> tuple[PairRecord, ...]:
    """Inspect the pairs one after another in this process, with no cluster and no archive.

    The plain loop a user would write instead of a batch: the reference for determinism tests and the
    single-core baseline of ``benchmarks/bench_batch.py``.
    """
    batch, pair_settings = _checked(items, settings)
    return tuple(inspect_item(item, chosen) for item, chosen in zip(batch, pair_settings, strict=True))
