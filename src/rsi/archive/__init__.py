"""Inspection archive (STORE): vista points, reference images, runs, findings and flaw history.

SQLAlchemy 2 over a SQLite file by default, any SQL URL otherwise; images are content-addressed files next to
the database. It stores and returns plain records and runs no algorithm. See docs/archive.md.

>>> from rsi.archive import Archive, Finding
>>> with Archive.open("archive.db") as archive:  # doctest: +SKIP
...     archive.add_vista("A_door")
...     run_id = archive.start_run(seed=0)
...     archive.add_findings(run_id, [Finding("A_door", "impact", 0.9, position_m=(0.1, 0.2, 1.0))])
...     archive.finish_run(run_id)
"""

from __future__ import annotations

from rsi.archive.records import (
    END_STATUSES,
    RUN_STATUSES,
    Finding,
    FlawHistory,
    ReferenceImage,
    Review,
    Run,
    StoredFinding,
    VistaPoint,
)
from rsi.archive.schema import REVIEW_VERDICTS, SCHEMA_VERSION
from rsi.archive.store import Archive, ArchiveError, ArchiveFileError

__all__ = [
    "END_STATUSES",
    "REVIEW_VERDICTS",
    "RUN_STATUSES",
    "SCHEMA_VERSION",
    "Archive",
    "ArchiveError",
    "ArchiveFileError",
    "Finding",
    "FlawHistory",
    "ReferenceImage",
    "Review",
    "Run",
    "StoredFinding",
    "VistaPoint",
]
