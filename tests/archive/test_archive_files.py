"""The archive file: schema versions, migrations, corrupt or foreign files refused untouched, busy writers."""

from __future__ import annotations

import sqlite3
from pathlib import Path

import pytest
from sqlalchemy import Connection, text

from rsi.archive import Archive, ArchiveError, ArchiveFileError, Finding, schema
from rsi.errors import InputError


def make_archive(path: Path) -> None:
    with Archive.open(path) as archive:
        archive.add_vista("A_door")
        run_id = archive.start_run()
        archive.add_findings(run_id, [Finding("A_door", "impact", 0.9, position_m=(0.1, 0.2, 1.0))])
        archive.finish_run(run_id)


def set_version(path: Path, version: int) -> None:
    with sqlite3.connect(path) as connection:
        connection.execute("UPDATE rsi_archive SET schema_version = ?", (version,))
    connection.close()


def snapshot(folder: Path) -> dict[str, bytes]:
    return {path.name: path.read_bytes() for path in sorted(folder.iterdir()) if path.is_file()}


def test_a_new_archive_uses_wal_and_records_its_version(tmp_path: Path) -> None:
    make_archive(tmp_path / "a.db")
    connection = sqlite3.connect(tmp_path / "a.db")
    try:
        assert connection.execute("PRAGMA journal_mode").fetchone() == ("wal",)
        version, created_by = connection.execute(
            "SELECT schema_version, created_by FROM rsi_archive"
        ).fetchone()
    finally:
        connection.close()
    assert (version, created_by) == (schema.SCHEMA_VERSION, "rsi 0.1.0")


def test_an_archive_from_a_newer_rsi_is_refused_untouched(tmp_path: Path) -> None:
    path = tmp_path / "a.db"
    make_archive(path)
    set_version(path, schema.SCHEMA_VERSION + 1)
    before = snapshot(tmp_path)
    newer = schema.SCHEMA_VERSION + 1
    with pytest.raises(ArchiveFileError, match=f"{path} has schema version {newer}, newer .*Upgrade rsi"):
        Archive.open(path)
    assert snapshot(tmp_path) == before


def test_an_older_archive_is_migrated_step_by_step(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    path = tmp_path / "a.db"
    make_archive(path)

    def add_operator(connection: Connection) -> None:
        connection.execute(text("ALTER TABLE runs ADD COLUMN operator VARCHAR(64)"))

    current = schema.SCHEMA_VERSION
    monkeypatch.setattr(schema, "SCHEMA_VERSION", current + 1)
    monkeypatch.setitem(schema.MIGRATIONS, current, add_operator)
    with Archive.open(path) as archive:
        assert archive.schema_version == current + 1
        assert archive.runs()[0].finding_count == 1
    connection = sqlite3.connect(path)
    try:
        assert connection.execute("SELECT schema_version FROM rsi_archive").fetchone() == (current + 1,)
        assert "operator" in {row[1] for row in connection.execute("PRAGMA table_info(runs)")}
    finally:
        connection.close()


def test_an_older_archive_without_a_migration_is_refused_untouched(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    path = tmp_path / "a.db"
    make_archive(path)
    before = snapshot(tmp_path)
    current = schema.SCHEMA_VERSION
    monkeypatch.setattr(schema, "SCHEMA_VERSION", current + 2)
    with pytest.raises(
        ArchiveFileError,
        match=rf"schema version {current} and this rsi has no migration from it to {current + 2}",
    ):
        Archive.open(path)
    assert snapshot(tmp_path) == before


def test_a_failed_migration_leaves_the_archive_as_it_was(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    path = tmp_path / "a.db"
    make_archive(path)

    def half_done(connection: Connection) -> None:
        connection.execute(text("ALTER TABLE runs ADD COLUMN operator VARCHAR(64)"))
        raise RuntimeError("migration bug")

    current = schema.SCHEMA_VERSION
    monkeypatch.setattr(schema, "SCHEMA_VERSION", current + 1)
    monkeypatch.setitem(schema.MIGRATIONS, current, half_done)
    with pytest.raises(RuntimeError, match=r"migration bug"):
        Archive.open(path)
    monkeypatch.undo()
    with Archive.open(path) as archive:
        assert archive.schema_version == current
        assert archive.runs()[0].finding_count == 1


def test_a_garbage_file_is_named_and_nothing_is_written(tmp_path: Path) -> None:
    path = tmp_path / "archive.db"
    garbage = bytes(range(256)) * 64
    path.write_bytes(garbage)
    with pytest.raises(ArchiveFileError, match=f"{path} is not a readable rsi archive.*not a database"):
        Archive.open(path)
    assert snapshot(tmp_path) == {"archive.db": garbage}
    assert [entry.name for entry in tmp_path.iterdir()] == ["archive.db"]  # no images folder, no journal


def test_another_programs_database_is_refused_untouched(tmp_path: Path) -> None:
    path = tmp_path / "other.db"
    connection = sqlite3.connect(path)
    with connection:
        connection.execute("CREATE TABLE parts (name TEXT)")
    connection.close()
    before = snapshot(tmp_path)
    with pytest.raises(
        ArchiveFileError, match=r"other.db is a database but not an rsi archive \(its tables: parts\)"
    ):
        Archive.open(path)
    assert snapshot(tmp_path) == before


def test_a_damaged_page_is_reported_naming_the_archive(tmp_path: Path) -> None:
    path = tmp_path / "a.db"
    with Archive.open(path) as archive:
        archive.add_vista("A_door")
        run_id = archive.start_run()
        archive.add_findings(
            run_id, [Finding("A_door", "impact", 0.9, position_m=(0.001 * i, 0.0, 1.0)) for i in range(400)]
        )
    data = bytearray(path.read_bytes())
    assert len(data) > 6 * 4096
    data[2 * 4096 : len(data) - 4096] = b"\xa5" * (len(data) - 3 * 4096)  # keep the header page
    path.write_bytes(bytes(data))
    # A writable open checks the pages before anything is written, and leaves the file as it is.
    with pytest.raises(ArchiveFileError, match=f"{path} is damaged \\(SQLite quick_check: .*Page"):
        Archive.open(path)
    assert path.read_bytes() == bytes(data)
    # A read-only open does not check the whole file; the read that meets the damage names the archive.
    with (
        pytest.raises(ArchiveFileError, match=f"{path} is not a readable rsi archive.*malformed"),
        Archive.open(path, read_only=True) as archive,
    ):
        archive.findings(run_id)
    assert path.read_bytes() == bytes(data)


def test_a_writer_locked_out_past_the_busy_timeout_gets_a_clear_error(tmp_path: Path) -> None:
    path = tmp_path / "a.db"
    make_archive(path)
    blocker = sqlite3.connect(path, isolation_level=None)
    try:
        with Archive.open(path, busy_timeout_s=0.05) as archive:
            blocker.execute("BEGIN IMMEDIATE")
            with pytest.raises(ArchiveError, match=r"stayed locked by another writer .*busy_timeout_s"):
                archive.start_run()
            # WAL: reading goes on while another writer holds the lock.
            assert archive.runs()[0].status == "finished"
            blocker.execute("ROLLBACK")
            assert archive.start_run() == 2
    finally:
        blocker.close()


def test_a_version_1_archive_gains_the_reviews_table_and_keeps_its_findings(tmp_path: Path) -> None:
    path = tmp_path / "a.db"
    make_archive(path)
    with sqlite3.connect(path) as connection:  # what rsi wrote before issue 16: no reviews table
        connection.execute("DROP TABLE reviews")
        connection.execute("UPDATE rsi_archive SET schema_version = 1")
    connection.close()
    with Archive.open(path) as archive:
        assert archive.schema_version == 2
        finding = archive.findings(archive.runs()[0].run_id)[0]
        assert archive.reviews(finding.finding_id) == ()
        archive.review_finding(finding.finding_id, "confirmed", note="seen on the door")
        assert [r.verdict for r in archive.reviews(finding.finding_id)] == ["confirmed"]


def test_reviews_are_kept_newest_last_and_bad_ones_are_named(tmp_path: Path) -> None:
    path = tmp_path / "a.db"
    make_archive(path)
    with Archive.open(path) as archive:
        finding_id = archive.findings(archive.runs()[0].run_id)[0].finding_id
        archive.review_finding(finding_id, "confirmed")
        archive.review_finding(finding_id, "rejected", note="a reflection", reviewer="ana")
        standing = archive.reviews(finding_id)
        assert [(r.verdict, r.note, r.reviewer) for r in standing] == [
            ("confirmed", "", "operator"),
            ("rejected", "a reflection", "ana"),
        ]
        with pytest.raises(InputError, match=r"verdict='maybe' is not known. Choose one of 'confirmed'"):
            archive.review_finding(finding_id, "maybe")
        with pytest.raises(InputError, match=r"note must be a string of at most 10000 characters"):
            archive.review_finding(finding_id, "note", note="x" * 10_001)
        with pytest.raises(InputError, match=r"reviewer must be a name of 1 to 200 characters"):
            archive.review_finding(finding_id, "note", reviewer="")
        with pytest.raises(InputError, match=r"finding 999 is not in the archive"):
            archive.review_finding(999, "confirmed")
