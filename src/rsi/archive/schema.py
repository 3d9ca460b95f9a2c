"""The archive's tables (SQLAlchemy Core) and its schema version with the migrations between versions.

Tables
------
``rsi_archive``  one row: the schema version, when and by which rsi the archive was created.
``vistas``       vista points and their camera poses (world frame, metres).
``images``       content-addressed image files: the SHA-256 of the bytes names the file.
``references``   which image is a vista's reference, and since when (the latest row wins).
``runs``         inspection runs: status, seed, settings JSON, start and end, the writer's host and pid.
``findings``     what a run found: vista, kind, position, bbox, size, confidence, score, images, extras
                 JSON, and the flaw history links ``previous_id`` (earlier sighting) and ``track_id``
                 (first sighting).
``reviews``      an operator's verdict on a finding (confirmed, rejected or a note alone), newest row
                 wins; added in version 2 (the operator console, issue 16).
"""

from __future__ import annotations

from collections.abc import Callable

from sqlalchemy import (
    BigInteger,
    Column,
    Connection,
    DateTime,
    Float,
    ForeignKey,
    Index,
    Integer,
    MetaData,
    String,
    Table,
    Text,
)

#: The schema version this rsi writes. Raise it with every change to the tables below and add the step from
#: the previous version to :data:`MIGRATIONS`.
SCHEMA_VERSION = 2

#: ``MIGRATIONS[v](connection)`` upgrades an archive of version ``v`` to ``v + 1`` inside the open
#: transaction (SQLite DDL is transactional, so a failed migration leaves the archive as it was).
MIGRATIONS: dict[int, Callable[[Connection], None]] = {}  # filled at the end of this module

metadata = MetaData()

archive_info = Table(
    "rsi_archive",
    metadata,
    Column("id", Integer, primary_key=True),
    Column("schema_version", Integer, nullable=False),
    Column("created_at", DateTime, nullable=False),
    Column("created_by", String(64), nullable=False),
)


def _xyz(prefix: str) -> list[Column[float]]:
    return [Column(f"{prefix}_{axis}", Float, nullable=True) for axis in "xyz"]


vistas = Table(
    "vistas",
    metadata,
    Column("id", Integer, primary_key=True),
    Column("name", String(200), nullable=False, unique=True),
    *_xyz("position_m"),
    *_xyz("forward"),
    *_xyz("up"),
    *_xyz("target_m"),
    Column("standoff_m", Float, nullable=True),
    Column("added_at", DateTime, nullable=False),
)

images = Table(
    "images",
    metadata,
    Column("sha256", String(64), primary_key=True),
    Column("media", String(16), nullable=False),
    Column("size_bytes", BigInteger, nullable=False),
    Column("stored_at", DateTime, nullable=False),
)

references = Table(
    "references",
    metadata,
    Column("id", Integer, primary_key=True),
    Column("vista_id", Integer, ForeignKey("vistas.id"), nullable=False),
    Column("sha256", String(64), ForeignKey("images.sha256"), nullable=False),
    Column("stored_at", DateTime, nullable=False),
    Index("ix_references_vista", "vista_id", "id"),
)

runs = Table(
    "runs",
    metadata,
    Column("id", Integer, primary_key=True),
    Column("label", String(200), nullable=False),
    Column("status", String(16), nullable=False),
    Column("seed", BigInteger, nullable=True),
    Column("settings_json", Text, nullable=False),
    Column("started_at", DateTime, nullable=False),
    Column("finished_at", DateTime, nullable=True),
    Column("host", String(255), nullable=False),
    Column("pid", Integer, nullable=False),
)

findings = Table(
    "findings",
    metadata,
    Column("id", Integer, primary_key=True),
    Column("run_id", Integer, ForeignKey("runs.id"), nullable=False, index=True),
    Column("vista_id", Integer, ForeignKey("vistas.id"), nullable=False),
    Column("kind", String(200), nullable=False),
    Column("confidence", Float, nullable=False),
    *_xyz("position_m"),
    Column("row0", Integer, nullable=True),
    Column("col0", Integer, nullable=True),
    Column("row1", Integer, nullable=True),
    Column("col1", Integer, nullable=True),
    Column("size_m", Float, nullable=True),
    Column("area_px", Integer, nullable=True),
    Column("score", Float, nullable=True),
    Column("reference_sha256", String(64), ForeignKey("images.sha256"), nullable=True),
    Column("inspection_sha256", String(64), ForeignKey("images.sha256"), nullable=True),
    Column("extras_json", Text, nullable=False),
    Column("previous_id", Integer, ForeignKey("findings.id"), nullable=True),
    Column("track_id", Integer, nullable=True, index=True),
    # Flaw history looks up earlier sightings by vista, kind and a range of x.
    Index("ix_findings_vista_kind_x", "vista_id", "kind", "position_m_x"),
)

#: A reviewer's verdicts; ``"note"`` keeps the finding's standing and records a remark.
REVIEW_VERDICTS = ("confirmed", "rejected", "note")

reviews = Table(
    "reviews",
    metadata,
    Column("id", Integer, primary_key=True),
    Column("finding_id", Integer, ForeignKey("findings.id"), nullable=False, index=True),
    Column("verdict", String(16), nullable=False),
    Column("note", Text, nullable=False),
    Column("reviewer", String(200), nullable=False),
    Column("reviewed_at", DateTime, nullable=False),
)


def _add_reviews(connection: Connection) -> None:
    """Version 1 -> 2: the reviews table (an archive of version 1 has no verdicts to carry over)."""
    reviews.create(connection)


MIGRATIONS[1] = _add_reviews
