"""The batch manifest: a CSV list of reference/inspection pairs, checked whole before anything runs.

:func:`read_manifest` reads the list into :class:`BatchItem` s with their per-pair :class:`PairSettings`
overrides. A *malformed manifest row* (wrong field count, empty path, unknown setting, bad value, duplicate
id) is a mistake in the list itself: one :class:`~rsi.errors.DatasetError` names the file and every bad line,
before any pair runs or anything is stored (docs/batch.md). The images are not opened here: a missing or
corrupt image is a bad pair, found by the task that reads it (:mod:`rsi.mission.batch`).

Importing this module stays cheap: neither OpenCV nor the detector is loaded.
"""

from __future__ import annotations

import csv
import io
import os
from collections.abc import Callable, Iterator, Mapping
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

from rsi import _validate as v
from rsi._files import read_regular_file
from rsi.errors import DatasetError, InputError

PathLike = str | os.PathLike[str]

REQUIRED_COLUMNS = ("reference", "inspection")
"""Manifest columns every row needs: image paths, relative to the manifest's folder or absolute."""
# Kept in step with rsi.detection / rsi.imaging by a test; spelled out here so that checking a manifest
# imports neither OpenCV nor the detector.
FLAW_MODELS = ("single", "uniform", "disc", "peak")
POLARITIES = ("both", "dark", "bright")
REGISTRATION_MODELS = ("translation", "euclidean", "similarity", "affine", "homography")
METHODS = ("lrt", "erosion")
_MAX_LISTED_ERRORS = 10
_MAX_ID = 200
MAX_MANIFEST_BYTES = 64 * 2**20
"""Largest manifest read: about a million pairs of 60-character paths."""
MAX_FIELD_CHARS = 4096


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
    rows = _csv_rows(file, _manifest_text(file))
    header = _header(file, next(rows, (1, None))[1])
    items, problems = _items(file, header, rows)
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
    return items


def _manifest_text(file: Path) -> str:
    data = read_regular_file(
        file,
        max_bytes=MAX_MANIFEST_BYTES,
        error=DatasetError,
        too_big="split the manifest into several batches",
    )
    try:
        return data.decode("utf-8-sig")
    except UnicodeDecodeError as error:
        raise DatasetError(
            f"manifest {str(file)!r} is not UTF-8 text ({error.reason} at byte {error.start}). "
            "Save it as UTF-8 CSV."
        ) from None


def _items(
    file: Path, header: tuple[str, ...], rows: Iterator[tuple[int, list[str] | None]]
) -> tuple[tuple[BatchItem, ...], list[str]]:
    """The well-formed rows' items, and one ``<file>:<line>: reason`` per malformed row."""
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
    return tuple(items), problems


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
