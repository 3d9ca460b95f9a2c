"""Batch inspection of many reference/inspection image pairs, scaled out with dask.distributed.

A manifest (CSV) lists the pairs; :func:`read_manifest` checks it whole before anything runs, and
:func:`run_batch` sends one task per pair to a cluster: local worker processes by default (one
single-threaded process per core), or an existing cluster by its scheduler address, with the same code.
Each task reads its two images, runs :func:`rsi.detection.pair.inspect_pair` (seed §2.3-2.4: register, then
test every pixel at a chosen false-alarm probability) and returns a plain :class:`PairRecord`: the flaws and
timings, or the error that stopped the pair. A task never raises, so a bad pair is reported and skipped and
never stops the batch. Only the driver writes to the archive (one writer, one run), in short transactions as
results arrive, so a batch that dies keeps every pair already written.

Two kinds of bad input, two behaviours (see docs/batch.md):

- a *malformed manifest row* (wrong field count, empty path, unknown setting, bad value, duplicate id) is a
  mistake in the list itself: :func:`read_manifest` raises one :class:`~rsi.errors.DatasetError` naming the
  file and every bad line, before any pair runs or anything is stored;
- a *bad pair* (missing, unreadable or corrupt image, images that cannot be compared) is only found by
  reading it: it becomes a failure record, stored in the archive as a finding of kind ``"failure"``.

Importing this module stays cheap: dask, OpenCV and the archive load when a function runs.
"""

from __future__ import annotations

import contextlib
import csv
import io
import json
import logging
import math
import os
import socket
import time
from collections.abc import Callable, Iterator, Mapping, Sequence
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path
from typing import TYPE_CHECKING, Any

from rsi import _validate as v
from rsi._files import atomic_write_bytes, read_regular_file
from rsi.errors import DatasetError, InputError

if TYPE_CHECKING:
    from distributed import Client, Future

    from rsi.archive import Archive, Finding

ProgressFn = Callable[[str, int, int], None]
"""Called as ``progress(pair_id, completed, total)`` each time a pair finishes (inspected or failed)."""

PathLike = str | os.PathLike[str]

REQUIRED_COLUMNS = ("reference", "inspection")
"""Manifest columns every row needs: image paths, relative to the manifest's folder or absolute."""
# Kept in step with rsi.detection / rsi.imaging by a test; spelled out here so that checking a manifest
# imports neither OpenCV nor the detector.
FLAW_MODELS = ("single", "uniform", "peak")
POLARITIES = ("both", "dark", "bright")
REGISTRATION_MODELS = ("translation", "euclidean", "similarity", "affine", "homography")
METHODS = ("lrt", "erosion")

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
CONNECT_TIMEOUT_S = 10.0
_MAX_LISTED_ERRORS = 10
_MAX_ID = 200
MAX_MANIFEST_BYTES = 64 * 2**20
"""Largest manifest read: about a million pairs of 60-character paths."""
MAX_FIELD_CHARS = 4096
"""Longest manifest cell: PATH_MAX on Linux; a longer path cannot be opened anyway."""
MAX_CONNECT_TIMEOUT_S = 3600.0
MAX_CLUSTER_WORKERS = 100_000
"""Most workers a batch waits for on an existing cluster."""


def max_local_workers() -> int:
    """Most local worker processes: two per usable core. One single-threaded process per core is the most
    that runs at once; past two per core they only add memory (each holds its own interpreter and images)."""
    try:
        cores = len(os.sched_getaffinity(0))
    except (AttributeError, OSError):
        cores = os.cpu_count() or 1
    return 2 * max(cores, 1)


@dataclass(frozen=True)
class PairSettings:
    """Detection settings of one pair: the keywords of :func:`rsi.detection.pair.inspect_pair`.

    A run's settings apply to every pair; a manifest row may override any of them in a column of the same
    name. Checked when built, so a bad value fails before the batch starts.
    """

    flaw_model: str = "single"
    size: int = 3
    p_false_alarm: float = 1e-5
    polarity: str = "both"
    registration_model: str = "translation"
    method: str = "lrt"
    noise_sigma: float | None = None
    misregistration_std_px: float = 0.0

    def __post_init__(self) -> None:
        v.choice(self.flaw_model, "flaw_model", FLAW_MODELS)
        size = v.positive_int(self.size, "size")
        if size % 2 == 0:
            raise InputError(f"size must be an odd integer >= 1 (a centred flaw window); got {size}.")
        v.in_range(self.p_false_alarm, "p_false_alarm", low=0.0, high=0.5, low_inclusive=False,
                   high_inclusive=False)  # fmt: skip
        v.choice(self.polarity, "polarity", POLARITIES)
        v.choice(self.registration_model, "registration_model", REGISTRATION_MODELS)
        v.choice(self.method, "method", METHODS)
        if self.noise_sigma is not None:
            v.in_range(self.noise_sigma, "noise_sigma", low=0.0, low_inclusive=False)
        v.in_range(self.misregistration_std_px, "misregistration_std_px", low=0.0)


_SETTING_TYPES: dict[str, Callable[[str], Any]] = {
    "flaw_model": str,
    "size": int,
    "p_false_alarm": float,
    "polarity": str,
    "registration_model": str,
    "method": str,
    "noise_sigma": float,
    "misregistration_std_px": float,
}
SETTING_COLUMNS = tuple(_SETTING_TYPES)
"""Optional manifest columns: per-pair overrides of the run's :class:`PairSettings` (empty cell: no
override)."""
MANIFEST_COLUMNS = ("id", *REQUIRED_COLUMNS, *SETTING_COLUMNS)


@dataclass(frozen=True)
class BatchItem:
    """One pair to inspect.

    Attributes
    ----------
    pair_id : str
        Unique name of the pair; the archive's vista name for its findings (so one pair's flaws are linked
        across batches). From the manifest's ``id`` column, else the ``inspection`` cell as written.
    reference, inspection : Path
        Image files (absolute once read from a manifest). Workers read them: on a cluster they must be
        reachable at this path from every worker (a shared file system).
    settings : dict of str to value
        Overrides of the run's :class:`PairSettings` for this pair (keys from :data:`SETTING_COLUMNS`).
    line : int or None
        Manifest line the pair came from, for messages.
    """

    pair_id: str
    reference: Path
    inspection: Path
    settings: dict[str, Any] = field(default_factory=dict)
    line: int | None = None

    def __post_init__(self) -> None:
        if not isinstance(self.pair_id, str) or not self.pair_id.strip() or len(self.pair_id) > _MAX_ID:
            raise InputError(
                f"pair_id must be a non-empty string of at most {_MAX_ID} characters; got {self.pair_id!r}."
            )
        if not isinstance(self.settings, Mapping) or any(not isinstance(key, str) for key in self.settings):
            raise InputError(
                f"settings of pair {self.pair_id!r} must be a dict of setting name to value; got "
                f"{type(self.settings).__name__}."
            )
        for name in ("reference", "inspection"):
            if not isinstance(getattr(self, name), (str, os.PathLike)):
                raise InputError(
                    f"{name} of pair {self.pair_id!r} must be a path; got {getattr(self, name)!r:.60}."
                )
        unknown = sorted(set(self.settings) - set(SETTING_COLUMNS))
        if unknown:
            raise InputError(
                f"pair {self.pair_id!r} has unknown setting(s) {', '.join(unknown)}. "
                f"Use any of {', '.join(SETTING_COLUMNS)}."
            )
        object.__setattr__(self, "reference", Path(self.reference))
        object.__setattr__(self, "inspection", Path(self.inspection))


@dataclass(frozen=True)
class FlawRecord:
    """A detected flaw as plain values (satisfies :class:`rsi.archive.records.FlawLike`).

    Attributes
    ----------
    row, col : float
        Centroid, inspection-image pixels.
    bbox : (int, int, int, int)
        ``(row0, col0, row1, col1)``, half-open.
    area_px : int
        Pixels in the component.
    score : float
        Peak score (in noise sigmas for the likelihood-ratio test).
    polarity : {"dark", "bright"}
        Sign of the change.
    confidence : float
        ``1 - P_F(score)``: one minus the per-pixel false-alarm probability of the peak score under the
        Gaussian null of the test statistic (two-sided for polarity "both"; seed §2.4). For the erosion test
        this is a lower bound (the eroded score's null tail is thinner).
    """

    row: float
    col: float
    bbox: tuple[int, int, int, int]
    area_px: int
    score: float
    polarity: str
    confidence: float


@dataclass(frozen=True)
class PairRecord:
    """What one pair's task returned: its flaws, or the error that stopped it. Never raised, always returned.

    Attributes
    ----------
    pair_id : str
        The pair's id.
    status : {"ok", "failed"}
        Whether the pair was inspected.
    flaws : tuple of FlawRecord
        Found flaws, strongest first (empty when failed).
    shape : (int, int) or None
        (rows, cols) of the inspection image.
    threshold : float or None
        Score threshold of the requested per-pixel false-alarm probability.
    translation_xy : (float, float) or None
        Registration's (dx, dy), pixels.
    converged : bool or None
        Whether registration converged.
    error : str or None
        ``"<ErrorType>: <message>"`` for a failed pair.
    stage : str or None
        Where a failed pair stopped: ``"read"`` (an image), ``"inspect"`` (registration or detection) or
        ``"worker"`` (the task itself was lost, e.g. its worker process died).
    read_s, inspect_s : float
        Seconds spent reading both images and inspecting them (not compared between records).
    worker : str
        ``host:pid`` of the process that ran it (not compared).
    """

    pair_id: str
    status: str
    flaws: tuple[FlawRecord, ...] = ()
    shape: tuple[int, int] | None = None
    threshold: float | None = None
    translation_xy: tuple[float, float] | None = None
    converged: bool | None = None
    error: str | None = None
    stage: str | None = None
    read_s: float = field(default=0.0, compare=False)
    inspect_s: float = field(default=0.0, compare=False)
    worker: str = field(default="", compare=False)

    @property
    def ok(self) -> bool:
        """True when the pair was inspected."""
        return self.status == "ok"


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
    files : dict of str to Path
        Files written to ``out_dir`` (empty without one).
    """

    run_id: int
    records: tuple[PairRecord, ...]
    workers: int
    scheduler: str
    startup_s: float
    elapsed_s: float
    files: Mapping[str, Path] = field(default_factory=dict)

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


# ------------------------------------------------------------------------------------------- manifest


def read_manifest(path: PathLike) -> tuple[BatchItem, ...]:
    """Read a batch manifest: a CSV file with one reference/inspection pair per row.

    The header names the columns: ``reference`` and ``inspection`` (required), ``id`` (optional; default:
    the inspection cell as written) and any of :data:`SETTING_COLUMNS` (optional per-pair overrides; an
    empty cell keeps the run's value). Paths are relative to the manifest's folder unless absolute. Blank
    lines are skipped. The images are not opened here: a missing or corrupt image is a bad pair, reported
    when the batch reaches it.

    Parameters
    ----------
    path : str or os.PathLike
        The manifest file (UTF-8, an optional byte-order mark is accepted).

    Returns
    -------
    tuple of BatchItem
        In file order.

    Raises
    ------
    DatasetError
        If the file cannot be read, has no header or no pairs, names an unknown or repeated column, or has
        malformed rows (wrong number of fields, an empty path, a bad setting, a repeated id). Every bad line
        is named, ``<file>:<line>``, in one message, so the list is fixed in one go; nothing has run yet.

    Examples
    --------
    >>> print(open("pairs.csv").read())  # doctest: +SKIP
    id,reference,inspection,p_false_alarm
    door,ref/door.png,new/door.png,
    hinge,ref/hinge.png,new/hinge.png,1e-6
    """
    if not isinstance(path, (str, os.PathLike)) or not str(path):
        raise InputError(f"path must be the manifest's file path (str or os.PathLike); got {path!r:.60}.")
    file = Path(path)
    data = read_regular_file(
        file,
        max_bytes=MAX_MANIFEST_BYTES,
        error=DatasetError,
        too_big="split the manifest into several batches",
    )
    try:
        text = data.decode("utf-8-sig")
    except UnicodeDecodeError as error:
        raise DatasetError(
            f"manifest {str(file)!r} is not UTF-8 text ({error.reason} at byte {error.start}). "
            "Save it as UTF-8 CSV."
        ) from None
    rows = _csv_rows(file, text)
    header = _header(file, next(rows, (1, None))[1])
    folder = file.resolve().parent
    items: list[BatchItem] = []
    problems: list[str] = []
    first_line: dict[str, int] = {}
    for line, cells in rows:
        if cells is None:  # the CSV reader gave up on this line
            problems.append(
                f"{file}:{line}: is not valid CSV (a field over the CSV reader's limit of "
                f"{csv.field_size_limit()} characters); nothing after it was read."
            )
            break
        if not any(cell.strip() for cell in cells):
            continue
        try:
            item = _item(header, cells, line, folder)
        except InputError as error:
            problems.append(f"{file}:{line}: {error}")
            continue
        if item.pair_id in first_line:
            problems.append(
                f"{file}:{line}: id {item.pair_id!r} repeats line {first_line[item.pair_id]}. "
                "Give each pair its own id (an 'id' column)."
            )
            continue
        first_line[item.pair_id] = line
        items.append(item)
    if problems:
        listed = problems[:_MAX_LISTED_ERRORS]
        more = len(problems) - len(listed)
        tail = f"\n... and {more} more malformed row(s)" if more else ""
        raise DatasetError(
            f"manifest {str(file)!r} has {len(problems)} malformed row(s); nothing was run. Fix them:\n"
            + "\n".join(listed)
            + tail
        )
    if not items:
        raise DatasetError(
            f"manifest {str(file)!r} has a header but no pairs. Add rows 'reference,inspection' below it."
        )
    return tuple(items)


def _csv_rows(file: Path, text: str) -> Iterator[tuple[int, list[str] | None]]:
    """(line, cells) of each CSV row; (line, None) once, where the reader fails (then it stops)."""
    reader = csv.reader(io.StringIO(text, newline=""))
    while True:
        try:
            cells = next(reader)
        except StopIteration:
            return
        except csv.Error:
            yield reader.line_num, None
            return
        yield reader.line_num, cells


def _header(file: Path, cells: list[str] | None) -> tuple[str, ...]:
    if cells is None or not any(cell.strip() for cell in cells):
        raise DatasetError(
            f"manifest {str(file)!r}:1 has no header. The first line must name the columns, e.g. "
            "'reference,inspection' (optional: id and per-pair settings)."
        )
    header = tuple(cell.strip().lower() for cell in cells)
    unknown = [name for name in header if name not in MANIFEST_COLUMNS]
    repeated = sorted({name for name in header if header.count(name) > 1})
    missing = [name for name in REQUIRED_COLUMNS if name not in header]
    if unknown or repeated or missing:
        reasons = [
            *([f"unknown column(s) {', '.join(map(repr, unknown))}"] if unknown else []),
            *([f"repeated column(s) {', '.join(map(repr, repeated))}"] if repeated else []),
            *([f"no {' or '.join(map(repr, missing))} column"] if missing else []),
        ]
        raise DatasetError(
            f"manifest {str(file)!r}:1 header {','.join(cells)!r} has {'; '.join(reasons)}. "
            f"Columns: reference and inspection (required), id and {', '.join(SETTING_COLUMNS)} (optional)."
        )
    return header


def _item(header: tuple[str, ...], cells: list[str], line: int, folder: Path) -> BatchItem:
    if len(cells) != len(header):
        raise InputError(
            f"has {len(cells)} field(s) where the header has {len(header)} ({','.join(header)}). "
            "Quote cells that hold commas."
        )
    values = {name: cell.strip() for name, cell in zip(header, cells, strict=True)}
    for name, value in values.items():
        if len(value) > MAX_FIELD_CHARS or "\x00" in value:
            raise InputError(
                f"the {name} cell is {len(value)} characters long or holds a NUL byte; cells are at most "
                f"{MAX_FIELD_CHARS} characters (the longest path Linux opens)."
            )
    for name in REQUIRED_COLUMNS:
        if not values[name]:
            raise InputError(f"the {name} path is empty. Give the image file, relative to the manifest.")
    overrides: dict[str, Any] = {}
    for name in SETTING_COLUMNS:
        text = values.get(name, "")
        if not text:
            continue
        try:
            overrides[name] = _SETTING_TYPES[name](text)
        except ValueError:
            kind = _SETTING_TYPES[name].__name__
            raise InputError(f"{name}={text!r} is not {'an' if kind == 'int' else 'a'} {kind}.") from None
    replace(PairSettings(), **overrides)  # checks each value with the error the API gives
    return BatchItem(
        pair_id=values.get("id") or values["inspection"],
        reference=folder / values["reference"],
        inspection=folder / values["inspection"],
        settings=overrides,
        line=line,
    )


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
        flaws = tuple(_flaw_record(flaw, settings.polarity) for flaw in result.flaws)
        registration = result.registration
        translation = None if registration is None else tuple(map(float, registration.translation_xy))
    except Exception as error:
        inspect_s = time.perf_counter() - start_s - read_s
        return _failed(item, "inspect", error, read_s=read_s, inspect_s=inspect_s, worker=worker)
    rows, cols = inspection.shape
    return PairRecord(
        pair_id=item.pair_id,
        status="ok",
        flaws=flaws,
        shape=(int(rows), int(cols)),
        threshold=float(detection.threshold),
        translation_xy=None if translation is None else (translation[0], translation[1]),
        converged=None if registration is None else bool(registration.converged),
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


def _flaw_record(flaw: Any, polarity: str) -> FlawRecord:
    score = float(flaw.score)
    # seed §2.4: under the null the likelihood-ratio statistic is a standard normal.
    tail = 0.5 * math.erfc(score / math.sqrt(2.0))
    p_false_alarm = min(1.0, 2.0 * tail if polarity == "both" else tail)
    row0, col0, row1, col1 = (int(value) for value in flaw.bbox)
    return FlawRecord(
        row=float(flaw.row),
        col=float(flaw.col),
        bbox=(row0, col0, row1, col1),
        area_px=int(flaw.area_px),
        score=score,
        polarity=str(flaw.polarity),
        confidence=1.0 - p_false_alarm,
    )


# ------------------------------------------------------------------------------------------- the driver


def run_batch(
    items: Sequence[BatchItem],
    *,
    archive: Archive,
    out_dir: PathLike | None = None,
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
        vista; its flaws are findings of kind ``"flaw"``, plus one ``"inspected"`` summary per inspected
        pair and one ``"failure"`` per failed pair (see :data:`FINDING_KINDS`).
    out_dir : str or os.PathLike, optional
        Folder for ``pairs.csv`` (one row per pair), ``flaws.csv`` (one row per flaw) and ``batch.json``
        (the summary), each written atomically at the end.
    scheduler : str, optional
        Address of an existing dask scheduler (``tcp://host:8786``). Default: a local cluster of worker
        processes, one thread each, started for this batch and closed after it.
    workers : int, optional
        Local worker processes (default: the CPU count). With `scheduler`, wait until the cluster has at
        least this many workers.
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

    Raises
    ------
    InputError
        For bad arguments (before anything is stored) and for a scheduler that cannot be reached. A bad
        pair never raises. If the driver itself is stopped (Ctrl-C, a failing archive), the pairs already
        written stay, and the run is marked "aborted" or "failed".
    """
    from rsi.archive import Archive

    batch, pair_settings = _checked(items, settings)
    v.instance_of(archive, "archive", Archive)
    if scheduler is not None and (
        not isinstance(scheduler, str) or not scheduler.strip() or len(scheduler) > 1000
    ):
        raise InputError(f"scheduler must be an address such as 'tcp://host:8786'; got {scheduler!r:.80}.")
    if workers is not None:
        most = MAX_CLUSTER_WORKERS if scheduler is not None else max_local_workers()
        workers = v.positive_int(workers, "workers", maximum=most)
    connect_timeout_s = v.in_range(
        connect_timeout_s, "connect_timeout_s", low=0.0, high=MAX_CONNECT_TIMEOUT_S, low_inclusive=False
    )
    start_s = time.perf_counter()
    with _cluster(scheduler, workers, connect_timeout_s) as client:
        startup_s = time.perf_counter() - start_s
        worker_count = len(client.scheduler_info()["workers"])
        run_settings = {
            "batch": {
                "pairs": len(batch),
                "scheduler": scheduler or "local",
                "workers": worker_count,
                "settings": asdict(settings or PairSettings()),
            }
        }
        run_id = archive.start_run(label=label, settings=run_settings)
        writer = _RunWriter(archive, run_id, batch)
        try:
            records = _gather(
                client,
                run_id=run_id,
                batch=batch,
                pair_settings=pair_settings,
                writer=writer,
                progress=progress,
            )
            writer.flush()
        except BaseException as error:
            _abandon(archive, run_id, writer, interrupted=isinstance(error, KeyboardInterrupt))
            raise
        archive.finish_run(run_id)
        elapsed_s = time.perf_counter() - start_s
    result = BatchResult(
        run_id=run_id,
        records=records,
        workers=worker_count,
        scheduler=scheduler or "local",
        startup_s=startup_s,
        elapsed_s=elapsed_s,
    )
    if out_dir is None:
        return result
    return replace(result, files=_write_outputs(Path(out_dir), result, batch))


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


@contextlib.contextmanager
def _cluster(scheduler: str | None, workers: int | None, timeout_s: float) -> Iterator[Client]:
    import dask
    from distributed import Client, LocalCluster

    if scheduler is None:
        # Processes, one thread each: the detector holds the GIL between OpenCV calls, so threads would not
        # scale. Every port is chosen by the OS (":0": the scheduler's HTTP server otherwise tries 8787 and
        # warns when it is taken) and bound to the loopback interface only: the cluster is private.
        with (
            # distributed sets MALLOC_TRIM_THRESHOLD_ in its workers; an explicit trim threshold turns off
            # glibc's dynamic mmap threshold, so every image-sized temporary becomes a fresh mmap whose pages
            # fault in zeroed: 43 -> 80 ms per 640x640 pair here. A task keeps nothing between pairs, so
            # trimming buys nothing.
            dask.config.set({"distributed.nanny.pre-spawn-environ.MALLOC_TRIM_THRESHOLD_": None}),
            LocalCluster(  # type: ignore[no-untyped-call]
                n_workers=workers or os.cpu_count() or 1,
                threads_per_worker=1,
                processes=True,
                host="127.0.0.1",
                dashboard_address=":0",
                silence_logs=logging.ERROR,
            ) as cluster,
            Client(cluster) as client,  # type: ignore[no-untyped-call]
        ):
            yield client
        return
    _probe_handshake(scheduler, timeout_s)
    try:
        client = Client(scheduler, timeout=f"{timeout_s}s")  # type: ignore[no-untyped-call]
    except (OSError, TimeoutError, ValueError) as error:
        reason = " ".join(str(error).split()) or type(error).__name__
        raise InputError(
            f"scheduler={scheduler!r} cannot be reached ({reason[:300]}). "
            "Give the address a running `dask scheduler` prints (tcp://host:8786), or omit it for local "
            "worker processes."
        ) from None
    except (Exception, MemoryError) as error:
        # Something answered that is not a dask scheduler: its bytes, read as dask frames, give absurd
        # lengths (a MemoryError from allocating one) or garbage. The handshake failed; nothing was allocated.
        raise InputError(
            f"scheduler={scheduler!r} answered, but not as a dask scheduler (handshake failed: "
            f"{type(error).__name__}). Check the address and port (`dask scheduler` prints them)."
        ) from None
    with client:
        if workers is not None:
            try:
                client.wait_for_workers(workers, timeout=timeout_s)
            except TimeoutError:
                have = len(client.scheduler_info()["workers"])
                raise InputError(
                    f"workers={workers}: the cluster at {scheduler!r} has {have} worker(s) after "
                    f"{timeout_s:g} s. Start more workers or ask for fewer."
                ) from None
        yield client


_MAX_HANDSHAKE_BYTES = 64 * 2**20


def _probe_handshake(scheduler: str, timeout_s: float) -> None:
    """Check that a TCP scheduler address answers like dask before the client trusts it.

    A dask scheduler writes its handshake as soon as a connection is accepted: an 8-byte little-endian
    length, then a few dozen bytes. A server that says nothing would make the client wait forever, and one
    that says something else gives the client an absurd length to allocate (a MemoryError). A scheduler
    refusing the connection is not there; other failures (an unknown host) and other schemes (tls://) are
    left to the client, which names the reason.
    """
    scheme, _, rest = scheduler.strip().rpartition("://")
    host, _, port = rest.rpartition(":")
    if scheme not in ("", "tcp") or not port.isdigit() or not host:
        return
    try:
        with socket.create_connection((host.strip("[]"), int(port)), timeout=timeout_s) as connection:
            connection.settimeout(timeout_s)
            prelude = connection.recv(8, socket.MSG_WAITALL)
    except ConnectionRefusedError:
        raise InputError(
            f"scheduler={scheduler!r} cannot be reached (connection refused: nothing listens there). Give "
            "the address a running `dask scheduler` prints (tcp://host:8786), or omit it for local workers."
        ) from None
    except TimeoutError:
        raise InputError(
            f"scheduler={scheduler!r} accepted the connection but sent no dask handshake within "
            f"{timeout_s:g} s (connect_timeout_s). Check the address and port (`dask scheduler` prints them)."
        ) from None
    except OSError:
        return
    length = int.from_bytes(prelude, "little") if len(prelude) == 8 else 0
    if not 0 < length <= _MAX_HANDSHAKE_BYTES:
        raise InputError(
            f"scheduler={scheduler!r} answered, but not as a dask scheduler (its first bytes {prelude!r}). "
            "Check the address and port (`dask scheduler` prints them)."
        )


def _gather(
    client: Client,
    *,
    run_id: int,
    batch: tuple[BatchItem, ...],
    pair_settings: tuple[PairSettings, ...],
    writer: _RunWriter,
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


def _abandon(archive: Archive, run_id: int, writer: _RunWriter, *, interrupted: bool) -> None:
    """Keep what was computed and mark the run as not finished; never mask the error that stopped it."""
    with contextlib.suppress(Exception):
        writer.flush()
    with contextlib.suppress(Exception):
        archive.finish_run(run_id, "aborted" if interrupted else "failed")


class _RunWriter:
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
        Finding.from_flaw(flaw, vista=item.pair_id, confidence=flaw.confidence, kind=FINDING_KINDS["flaw"])
        for flaw in record.flaws
    ]
    return [summary, *flaws]


# ------------------------------------------------------------------------------------------- outputs

PAIR_COLUMNS = ("pair_id", "status", "flaws", "stage", "error", "reference", "inspection", "read_s",
                "inspect_s", "worker")  # fmt: skip
FLAW_COLUMNS = ("pair_id", "number", "row", "col", "row0", "col0", "row1", "col1", "area_px", "score",
                "polarity", "confidence")  # fmt: skip


def _write_outputs(out_dir: Path, result: BatchResult, batch: tuple[BatchItem, ...]) -> dict[str, Path]:
    pair_rows = [
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
        for item, record in zip(batch, result.records, strict=True)
    ]
    flaw_rows = [
        {
            "pair_id": record.pair_id,
            "number": number,
            "row": flaw.row,
            "col": flaw.col,
            "row0": flaw.bbox[0],
            "col0": flaw.bbox[1],
            "row1": flaw.bbox[2],
            "col1": flaw.bbox[3],
            "area_px": flaw.area_px,
            "score": flaw.score,
            "polarity": flaw.polarity,
            "confidence": flaw.confidence,
        }
        for record in result.records
        for number, flaw in enumerate(record.flaws, start=1)
    ]
    contents = {
        "pairs.csv": _csv(PAIR_COLUMNS, pair_rows),
        "flaws.csv": _csv(FLAW_COLUMNS, flaw_rows),
        "batch.json": json.dumps(result.summary(), indent=2, allow_nan=False) + "\n",
    }
    return {name: atomic_write_bytes(out_dir / name, text.encode("utf-8")) for name, text in contents.items()}


def _csv(columns: Sequence[str], rows: Sequence[Mapping[str, Any]]) -> str:
    buffer = io.StringIO()
    writer = csv.DictWriter(buffer, fieldnames=list(columns), lineterminator="\n")
    writer.writeheader()
    writer.writerows(rows)
    return buffer.getvalue()


def inspect_sequentially(
    items: Sequence[BatchItem], *, settings: PairSettings | None = None
) -> tuple[PairRecord, ...]:
    """Inspect the pairs one after another in this process, with no cluster and no archive.

    The plain loop a user would write instead of a batch: the reference for determinism tests and the
    single-core baseline of ``benchmarks/bench_batch.py``.
    """
    batch, pair_settings = _checked(items, settings)
    return tuple(inspect_item(item, chosen) for item, chosen in zip(batch, pair_settings, strict=True))
