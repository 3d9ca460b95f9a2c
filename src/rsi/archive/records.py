"""Plain records the archive takes and returns: frozen dataclasses, never SQLAlchemy objects.

Records going in (:class:`VistaPoint`, :class:`Finding`) check their fields when built, so a bad value fails
where it was made, naming the field, the value and the fix.
"""

from __future__ import annotations

import json
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from datetime import datetime
from pathlib import Path
from typing import Any, Protocol

import numpy as np

from rsi._validate import finite_number, in_range, store_checked
from rsi.errors import InputError

Vector3 = tuple[float, float, float]
BBox = tuple[int, int, int, int]

#: Run states. A run is "running" from :meth:`Archive.start_run` until :meth:`Archive.finish_run`; a writer
#: that dies in between leaves it "running" forever, so a half-run is never reported as finished.
RUN_STATUSES = ("running", "finished", "failed", "aborted")
#: States :meth:`Archive.finish_run` may set.
END_STATUSES = RUN_STATUSES[1:]

_MAX_NAME = 200
_SHA256_HEX = 64


class VistaLike(Protocol):
    """Anything with a vista's name and pose, e.g. ``rsi.sim.mockup.Vista`` (not imported here)."""

    @property
    def name(self) -> str: ...

    @property
    def position_m(self) -> Sequence[float]: ...

    @property
    def forward(self) -> Sequence[float]: ...

    @property
    def up(self) -> Sequence[float]: ...

    @property
    def target_m(self) -> Sequence[float]: ...

    @property
    def standoff_m(self) -> float: ...


class FlawLike(Protocol):
    """Anything with a detected flaw's fields, e.g. ``rsi.detection.Flaw`` (not imported here)."""

    @property
    def row(self) -> float: ...

    @property
    def col(self) -> float: ...

    @property
    def bbox(self) -> tuple[int, int, int, int]: ...

    @property
    def area_px(self) -> int: ...

    @property
    def score(self) -> float: ...

    @property
    def polarity(self) -> str: ...


def check_name(value: object, name: str) -> str:
    """Return `value` if it is a non-empty string of at most 200 characters, else raise naming `name`."""
    if not isinstance(value, str) or not value.strip() or len(value) > _MAX_NAME:
        raise InputError(
            f"{name} must be a non-empty string of at most {_MAX_NAME} characters; got {value!r}."
        )
    return value


def check_sha256(value: object, name: str) -> str:
    """Return `value` if it is a 64-digit lower-case hex SHA-256, else raise naming `name`."""
    if (
        not isinstance(value, str)
        or len(value) != _SHA256_HEX
        or any(char not in "0123456789abcdef" for char in value)
    ):
        raise InputError(
            f"{name} must be a SHA-256 as 64 lower-case hex digits (what Archive.store_image returns); "
            f"got {value!r}."
        )
    return value


def _vector3(value: object, name: str) -> Vector3:
    if isinstance(value, (str, bytes)) or not isinstance(value, (Sequence, np.ndarray)) or len(value) != 3:
        raise InputError(f"{name} must be three finite numbers (x, y, z); got {value!r}.")
    x, y, z = (finite_number(item, f"{name}[{index}]") for index, item in enumerate(value))
    return (x, y, z)


def _bbox(value: object, name: str) -> BBox:
    if isinstance(value, (str, bytes)) or not isinstance(value, (Sequence, np.ndarray)) or len(value) != 4:
        raise InputError(f"{name} must be (row0, col0, row1, col1), four integers; got {value!r}.")
    items = tuple(value)
    if any(isinstance(item, bool) or not isinstance(item, (int, np.integer)) for item in items):
        raise InputError(f"{name} must be (row0, col0, row1, col1), four integers; got {value!r}.")
    row0, col0, row1, col1 = (int(item) for item in items)
    if not (0 <= row0 < row1 and 0 <= col0 < col1):
        raise InputError(
            f"{name} must be half-open with 0 <= row0 < row1 and 0 <= col0 < col1; got {value!r}."
        )
    return (row0, col0, row1, col1)


def json_text(value: object, name: str) -> str:
    """Return `value` as canonical JSON text (a mapping with string keys), else raise naming `name`."""
    if not isinstance(value, Mapping) or any(not isinstance(key, str) for key in value):
        raise InputError(f"{name} must be a mapping with string keys; got {value!r}.")
    try:
        return json.dumps(value, sort_keys=True, allow_nan=False)
    except (TypeError, ValueError) as error:
        raise InputError(
            f"{name} must hold only JSON values (str, finite numbers, bool, None, lists, dicts); {error}. "
            "Convert arrays with .tolist() and numpy scalars with float()/int()."
        ) from None


@dataclass(frozen=True)
class VistaPoint:
    """A vista point as stored: a name and, when known, the camera pose (seed §2.3: revisited every pass).

    Attributes
    ----------
    name : str
        Unique vista name, e.g. ``"A_door"`` (a batch pair id for real image pairs).
    position_m, forward, up, target_m : (float, float, float) or None
        Camera centre (world frame, metres), unit viewing direction, unit image-up direction and the surface
        point at the image centre; all four are None for a vista without a pose.
    standoff_m : float or None
        Camera-to-target distance.
    """

    name: str
    position_m: Vector3 | None = None
    forward: Vector3 | None = None
    up: Vector3 | None = None
    target_m: Vector3 | None = None
    standoff_m: float | None = None

    def __post_init__(self) -> None:
        check_name(self.name, "vista name")
        pose = (self.position_m, self.forward, self.up, self.target_m, self.standoff_m)
        if all(part is None for part in pose):
            return
        if any(part is None for part in pose):
            raise InputError(
                f"vista {self.name!r} has a partial pose {pose!r}; give all of position_m, forward, up, "
                "target_m and standoff_m, or none."
            )
        store_checked(
            self,
            {
                "position_m": _vector3(self.position_m, "position_m"),
                "forward": _vector3(self.forward, "forward"),
                "up": _vector3(self.up, "up"),
                "target_m": _vector3(self.target_m, "target_m"),
                "standoff_m": in_range(self.standoff_m, "standoff_m", low=0.0),
            },
        )

    @classmethod
    def from_pose(cls, vista: VistaLike) -> VistaPoint:
        """The record of any object with a vista's name and pose attributes."""
        return cls(
            name=vista.name,
            position_m=_vector3(vista.position_m, "position_m"),
            forward=_vector3(vista.forward, "forward"),
            up=_vector3(vista.up, "up"),
            target_m=_vector3(vista.target_m, "target_m"),
            standoff_m=vista.standoff_m,
        )


@dataclass(frozen=True)
class Finding:
    """A finding to store: what was found at a vista point, where, how big and how sure.

    Attributes
    ----------
    vista : str
        Name of a vista already in the archive.
    kind : str
        Anomaly type, e.g. ``"impact"``, ``"missing_screw"``, ``"hot_spot"``, ``"gas_leak"``, ``"flaw"``.
    confidence : float
        In [0, 1].
    position_m : (float, float, float) or None
        Location on the structure, world frame, metres.
    bbox : (int, int, int, int) or None
        ``(row0, col0, row1, col1)``, half-open, inspection-image pixels. At least one of `position_m` and
        `bbox` is given; flaw history matches on `position_m` when both findings have it, else on the bbox
        centre.
    size_m : float or None
        Characteristic size (e.g. impact diameter); tracked across runs as the flaw's growth.
    area_px : int or None
        Pixels in the detected component.
    score : float or None
        Detector score (e.g. the likelihood-ratio peak).
    reference_sha256, inspection_sha256 : str or None
        Stored images the finding was made from (:meth:`Archive.store_image`). A missing
        `reference_sha256` is filled with the vista's current reference, if any.
    extras : mapping of str to JSON values
        Anything else (polarity, sensor readings, ...).
    """

    vista: str
    kind: str
    confidence: float
    position_m: Vector3 | None = None
    bbox: BBox | None = None
    size_m: float | None = None
    area_px: int | None = None
    score: float | None = None
    reference_sha256: str | None = None
    inspection_sha256: str | None = None
    extras: Mapping[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        check_name(self.vista, "vista")
        check_name(self.kind, "kind")
        if self.position_m is None and self.bbox is None:
            raise InputError(
                f"finding of kind {self.kind!r} at vista {self.vista!r} has neither position_m nor bbox; "
                "give at least one so the flaw can be found again."
            )
        checked: dict[str, object] = {"confidence": in_range(self.confidence, "confidence", low=0, high=1)}
        if self.position_m is not None:
            checked["position_m"] = _vector3(self.position_m, "position_m")
        if self.bbox is not None:
            checked["bbox"] = _bbox(self.bbox, "bbox")
        if self.size_m is not None:
            checked["size_m"] = in_range(self.size_m, "size_m", low=0.0)
        if self.area_px is not None:
            if isinstance(self.area_px, bool) or not isinstance(self.area_px, (int, np.integer)):
                raise InputError(f"area_px must be an integer >= 0; got {self.area_px!r}.")
            checked["area_px"] = int(in_range(self.area_px, "area_px", low=0))
        if self.score is not None:
            checked["score"] = finite_number(self.score, "score")
        for name in ("reference_sha256", "inspection_sha256"):
            if getattr(self, name) is not None:
                check_sha256(getattr(self, name), name)
        checked["extras"] = json.loads(json_text(self.extras, "extras"))
        store_checked(self, checked)

    @classmethod
    def from_flaw(
        cls,
        flaw: FlawLike,
        *,
        vista: str,
        confidence: float,
        kind: str = "flaw",
        position_m: Vector3 | None = None,
        size_m: float | None = None,
        reference_sha256: str | None = None,
        inspection_sha256: str | None = None,
    ) -> Finding:
        """A finding from a detected flaw (``rsi.detection.Flaw``): bbox, area, score; centroid and polarity
        go to `extras`."""
        return cls(
            vista=vista,
            kind=kind,
            confidence=confidence,
            position_m=position_m,
            bbox=flaw.bbox,
            size_m=size_m,
            area_px=flaw.area_px,
            score=flaw.score,
            reference_sha256=reference_sha256,
            inspection_sha256=inspection_sha256,
            extras={"row": float(flaw.row), "col": float(flaw.col), "polarity": str(flaw.polarity)},
        )


@dataclass(frozen=True)
class StoredFinding:
    """A finding as stored, with its place in the flaw's history.

    Attributes
    ----------
    finding_id, run_id : int
        Its id and its run's.
    vista, kind, confidence, position_m, bbox, size_m, area_px, score, reference_sha256, inspection_sha256,
    extras
        As in :class:`Finding`.
    previous_id : int or None
        The earlier sighting of the same flaw (None for a first sighting).
    track_id : int
        Id of the flaw's first sighting; every sighting of one flaw shares it.
    seen_at : datetime
        Start of the run that saw it (UTC).
    """

    finding_id: int
    run_id: int
    vista: str
    kind: str
    confidence: float
    position_m: Vector3 | None
    bbox: BBox | None
    size_m: float | None
    area_px: int | None
    score: float | None
    reference_sha256: str | None
    inspection_sha256: str | None
    extras: Mapping[str, Any]
    previous_id: int | None
    track_id: int
    seen_at: datetime


@dataclass(frozen=True)
class Run:
    """An inspection run.

    Attributes
    ----------
    run_id : int
        Its id.
    label : str
        Free text, e.g. ``"reference pass"``.
    status : str
        One of :data:`RUN_STATUSES`. "running" after a crash: the run never finished.
    seed : int or None
        Seed the run used.
    settings : mapping
        Settings the run used (JSON).
    started_at, finished_at : datetime
        UTC; `finished_at` is None while running.
    finding_count : int
        Findings stored for it.
    host : str
        Host name of the writer.
    pid : int
        Process id of the writer.
    """

    run_id: int
    label: str
    status: str
    seed: int | None
    settings: Mapping[str, Any]
    started_at: datetime
    finished_at: datetime | None
    finding_count: int
    host: str
    pid: int


@dataclass(frozen=True)
class ReferenceImage:
    """A vista's current reference image.

    Attributes
    ----------
    vista : str
        Vista name.
    sha256 : str
        SHA-256 of the stored bytes (its file name).
    media : str
        ``"npy"`` (a stored array) or the sniffed file type of stored bytes: ``"png"``, ``"jpeg"``,
        ``"tiff"``, ``"bmp"``, ``"bytes"``.
    size_bytes : int
        File size.
    stored_at : datetime
        When it became the vista's reference (UTC).
    path : Path
        The content-addressed file.
    """

    vista: str
    sha256: str
    media: str
    size_bytes: int
    stored_at: datetime
    path: Path


@dataclass(frozen=True)
class Review:
    """An operator's verdict on a stored finding (issue 16: the console's confirm / reject / annotate).

    Attributes
    ----------
    review_id, finding_id : int
        Its id and the finding's.
    verdict : {"confirmed", "rejected", "note"}
        ``"note"`` records a remark and leaves the finding's standing as it was.
    note : str
        Free text (may be empty).
    reviewer : str
        Who reviewed (free text, e.g. the console's operator name).
    reviewed_at : datetime
        UTC.
    """

    review_id: int
    finding_id: int
    verdict: str
    note: str
    reviewer: str
    reviewed_at: datetime


@dataclass(frozen=True)
class FlawHistory:
    """Every sighting of one flaw across runs, oldest first.

    Attributes
    ----------
    track_id : int
        Id of the first sighting.
    sightings : tuple of StoredFinding
        Ordered by run start.
    """

    track_id: int
    sightings: tuple[StoredFinding, ...]

    @property
    def seen_at(self) -> tuple[datetime, ...]:
        """Run start of each sighting."""
        return tuple(sighting.seen_at for sighting in self.sightings)

    @property
    def sizes_m(self) -> tuple[float | None, ...]:
        """Size at each sighting (None where not measured)."""
        return tuple(sighting.size_m for sighting in self.sightings)

    @property
    def growth_m(self) -> float | None:
        """Last measured size minus first measured size (None with fewer than two measured sizes)."""
        sizes = [size for size in self.sizes_m if size is not None]
        return sizes[-1] - sizes[0] if len(sizes) >= 2 else None

    @property
    def growth_rate_m_s(self) -> float | None:
        """Growth per second between the first and last measured sightings (None if undefined)."""
        measured = [sighting for sighting in self.sightings if sighting.size_m is not None]
        if len(measured) < 2:
            return None
        elapsed_s = (measured[-1].seen_at - measured[0].seen_at).total_seconds()
        growth_m = self.growth_m
        if growth_m is None or elapsed_s <= 0 or not math.isfinite(elapsed_s):
            return None
        return growth_m / elapsed_s
