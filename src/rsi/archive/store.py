"""The inspection archive: vista points, references, runs, findings and flaw history in one SQL database.

SQLite file by default (WAL journal, busy timeout, every write in one ``BEGIN IMMEDIATE`` transaction), any
SQLAlchemy URL otherwise. Images are content-addressed files in a folder next to the database. See
docs/archive.md for the schema, concurrency and crash behaviour, and measured figures.
"""

from __future__ import annotations

import bisect
import contextlib
import json
import math
import os
import socket
from collections.abc import Iterable, Iterator, Sequence
from dataclasses import asdict
from datetime import datetime, timezone
from pathlib import Path
from types import TracebackType
from typing import Any
from urllib.parse import quote

import numpy as np
import sqlalchemy as sa
from sqlalchemy import Connection, Engine, ExceptionContext, Row, event, exc, func, select
from sqlalchemy.pool import StaticPool

from rsi import __version__
from rsi._files import atomic_write_bytes, writable_folder
from rsi._validate import choice, in_range
from rsi.archive import _images, _integrity, schema
from rsi.archive.records import (
    END_STATUSES,
    RUN_STATUSES,
    Finding,
    FlawHistory,
    ReferenceImage,
    Review,
    Run,
    StoredFinding,
    VistaLike,
    VistaPoint,
    check_name,
    check_sha256,
    json_text,
)
from rsi.errors import FileError, InputError, RsiError

_MAX_SEED = 2**63
_MAX_NOTE = 10_000
_MAX_BUSY_TIMEOUT_S = 86_400.0


class ArchiveError(RsiError):
    """The archive cannot do what was asked (e.g. the database stayed locked past the busy timeout)."""


class ArchiveFileError(ArchiveError, FileError):
    """The archive file is unusable: corrupt, another program's database, or a newer schema."""


def _check_id(value: object, name: str) -> None:
    """Ids are SQL integers: 1 to 2**63 - 1 (a larger int cannot even be compared by the database)."""
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or not 1 <= value < _MAX_SEED:
        raise InputError(f"{name} must be an integer in [1, 2**63); got {value!r:.60}.")


def _prepare_path(path: Path, *, create: bool) -> None:
    """Refuse a folder or a path under a file; create the parent folder of a new archive (`create`)."""
    if "\0" in str(path):
        raise InputError(f"archive path {str(path)[:120]!r} holds a NUL character; no file name has one.")
    if path.is_dir():
        raise InputError(f"archive path {path} is a folder; pass a database file path inside it.")
    if path.parent.exists() and not path.parent.is_dir():
        raise InputError(f"archive path {path}: {path.parent} is a file, not a folder.")
    if not path.exists():
        if not create:
            raise ArchiveFileError(
                f"there is no archive at {path}; check the path, or open it with create=True."
            )
        path.parent.mkdir(parents=True, exist_ok=True)


def _read_only_url(path: Path) -> sa.URL:
    """SQLite's read-only URI for a file: no write of any kind, not even a journal-mode change."""
    return sa.URL.create("sqlite", database=f"file:{quote(path.as_posix())}?mode=ro", query={"uri": "true"})


def _now() -> datetime:
    return datetime.now(timezone.utc)


def _to_db(moment: datetime) -> datetime:
    """Naive UTC for the database (SQLite keeps no time zone)."""
    return moment.astimezone(timezone.utc).replace(tzinfo=None)


def _from_db(moment: datetime) -> datetime:
    return moment.replace(tzinfo=timezone.utc)


def _moment(value: object, name: str) -> datetime:
    if not isinstance(value, datetime) or value.tzinfo is None:
        raise InputError(
            f"{name} must be a time-zone-aware datetime; got {value!r}. Try datetime.now(timezone.utc)."
        )
    return value


def _sqlite_connect(dbapi_connection: Any, _record: Any) -> None:
    # The driver must not open transactions itself: the "begin" hook below issues BEGIN or BEGIN IMMEDIATE.
    dbapi_connection.isolation_level = None
    cursor = dbapi_connection.cursor()
    try:
        cursor.execute("PRAGMA foreign_keys=ON")
        # FULL: a commit is on disk before it returns, so a committed run survives a power cut, not only a
        # killed process (docs/archive.md measures the cost).
        cursor.execute("PRAGMA synchronous=FULL")
    finally:
        cursor.close()


def _sqlite_begin(connection: Connection) -> None:
    # A write takes the database's write lock at BEGIN (waiting up to the busy timeout), never half-way
    # through, when SQLite would fail at once rather than deadlock two writers upgrading a read lock.
    write = connection.get_execution_options().get("rsi_write", False)
    connection.exec_driver_sql("BEGIN IMMEDIATE" if write else "BEGIN")


def _sqlite_error(context: ExceptionContext) -> None:
    # An interrupt (Ctrl-C, a signal turned into an exception) mid-statement makes SQLAlchemy close the
    # connection; with a statement still open on the cursor, SQLite keeps the closed connection alive, write
    # lock and all, until the cursor is garbage-collected, and every other writer waits. Finalise it now.
    execution = context.execution_context
    if execution is not None and execution.cursor is not None:
        with contextlib.suppress(Exception):
            execution.cursor.close()


def _location(url_or_path: object) -> tuple[sa.URL, Path | None]:
    """The SQLAlchemy URL and, for a SQLite file, its path."""
    if isinstance(url_or_path, str) and "://" in url_or_path:
        try:
            url = sa.make_url(url_or_path)
        except exc.ArgumentError as error:
            raise InputError(f"url_or_path={url_or_path!r} is not a database URL: {error}.") from None
        if url.get_backend_name() == "sqlite" and url.database not in (None, "", ":memory:"):
            return url, Path(url.database).absolute()
        return url, None
    if not isinstance(url_or_path, (str, os.PathLike)) or not str(url_or_path):
        raise InputError(
            f"url_or_path must be a file path or a SQLAlchemy URL such as 'sqlite:///archive.db' or "
            f"'postgresql://host/rsi'; got {url_or_path!r}."
        )
    path = Path(url_or_path).expanduser().absolute()
    return sa.URL.create("sqlite", database=str(path)), path


class Archive:
    """The inspection archive (seed §2.3: references and inspections kept and compared across missions).

    Open it with :meth:`Archive.open`; every method takes and returns plain records
    (:mod:`rsi.archive.records`). An ``Archive`` is for one process: open it again in each process (a
    forked copy of an open one is not safe). It is a context manager that closes the database connections.
    """

    def __init__(
        self, engine: Engine, *, location: str, images_dir: Path, schema_version: int, read_only: bool = False
    ) -> None:
        self._engine = engine
        self._location = location
        self._images_dir = images_dir
        self._schema_version = schema_version
        self._read_only = read_only

    # ------------------------------------------------------------------ opening

    @classmethod
    def open(
        cls,
        url_or_path: str | os.PathLike[str],
        *,
        images_dir: str | os.PathLike[str] | None = None,
        create: bool = True,
        busy_timeout_s: float = 30.0,
        read_only: bool = False,
    ) -> Archive:
        """Open (or create) an archive.

        A writable open of an existing archive first checks it whole (SQLite's ``quick_check``, every table
        and column of the schema, every row readable): a damaged archive is refused before anything is
        written to it, and left byte for byte as it was.

        Parameters
        ----------
        url_or_path : str or os.PathLike
            A SQLite file path, or any SQLAlchemy URL (``"sqlite:///a.db"``, ``"postgresql://host/rsi"``).
        images_dir : str or os.PathLike, optional
            Folder of the content-addressed image files. Default: ``<database file>.images`` next to a
            SQLite file; required for any other URL.
        create : bool, default True
            Create a missing archive. With False a missing file raises instead.
        busy_timeout_s : float, default 30
            How long a write waits for another writer before giving up.
        read_only : bool, default False
            Open for reading only (implies ``create=False``): nothing is written, not even the journal mode,
            so an archive one may not write can be read, and a damaged one is never touched. Writes raise
            :class:`ArchiveError`.

        Raises
        ------
        InputError
            Bad arguments, or `create` is False and there is no archive.
        ArchiveFileError
            The file is corrupt, another program's database, or from a newer rsi; an older archive with no
            migration. The file is not modified.
        """
        busy_timeout_s = in_range(busy_timeout_s, "busy_timeout_s", low=0.0, high=_MAX_BUSY_TIMEOUT_S)
        if not isinstance(read_only, bool) or not isinstance(create, bool):
            raise InputError(f"create and read_only must be True or False; got {create!r} and {read_only!r}.")
        create = create and not read_only
        url, path = _location(url_or_path)
        if path is not None:
            try:
                _prepare_path(path, create=create)
            except OSError as failure:  # a name too long for the file system, a folder we may not enter
                raise ArchiveFileError(
                    f"archive path {str(path)[:120]!r} cannot be used: {failure.strerror}."
                ) from None
        if images_dir is None:
            if path is None:
                raise InputError(
                    f"images_dir is needed for the database {url.render_as_string(hide_password=True)}: "
                    "pass the folder where the archive keeps its image files."
                )
            images_dir = path.with_name(path.name + ".images")
        if not isinstance(images_dir, (str, os.PathLike)) or not str(images_dir):
            raise InputError(f"images_dir must be a folder path; got {images_dir!r}.")
        location = str(path) if path is not None else url.render_as_string(hide_password=True)
        if read_only and path is not None:
            url = _read_only_url(path)
        engine = cls._engine_for(url, busy_timeout_s)
        archive = cls(
            engine,
            location=location,
            images_dir=Path(images_dir).absolute(),
            schema_version=0,
            read_only=read_only,
        )
        try:
            archive._schema_version = archive._prepare_schema()
            if url.get_backend_name() == "sqlite" and not read_only:
                archive._use_wal()
        except BaseException:
            engine.dispose()
            raise
        return archive

    @staticmethod
    def _engine_for(url: sa.URL, busy_timeout_s: float) -> Engine:
        if url.get_backend_name() != "sqlite":
            try:
                return sa.create_engine(url)
            except (ImportError, exc.NoSuchModuleError, exc.ArgumentError) as error:
                raise InputError(
                    f"the database {url.render_as_string(hide_password=True)} cannot be opened: its driver "
                    f"is missing or unknown ({error}). Install it (e.g. pip install 'psycopg[binary]')."
                ) from None
        in_memory = url.database in (None, "", ":memory:")
        engine = sa.create_engine(
            url,
            connect_args={"timeout": busy_timeout_s, "check_same_thread": not in_memory},
            poolclass=StaticPool if in_memory else None,
        )
        event.listen(engine, "connect", _sqlite_connect)
        event.listen(engine, "begin", _sqlite_begin)
        event.listen(engine, "handle_error", _sqlite_error)
        return engine

    def _prepare_schema(self) -> int:
        """Create the tables of a new archive; check an existing one whole; migrate an older one."""
        with self._transaction(write=not self._read_only) as connection:
            tables = set(sa.inspect(connection).get_table_names())
            if not tables and not self._read_only:
                schema.metadata.create_all(connection)
                connection.execute(
                    schema.archive_info.insert().values(
                        id=1,
                        schema_version=schema.SCHEMA_VERSION,
                        created_at=_to_db(_now()),
                        created_by=f"rsi {__version__}",
                    )
                )
                return schema.SCHEMA_VERSION
            if schema.archive_info.name not in tables:
                raise ArchiveFileError(
                    f"{self._location} is a database but not an rsi archive (its tables: "
                    f"{', '.join(sorted(tables)) or 'none'}); it was not modified. Open another path."
                )
            version = self._stored_version(connection)
            if version > schema.SCHEMA_VERSION:
                raise ArchiveFileError(
                    f"archive {self._location} has schema version {version}, newer than this rsi "
                    f"{__version__} understands ({schema.SCHEMA_VERSION}); it was not modified. "
                    "Upgrade rsi (pip install -U rsi) to open it."
                )
            if version == schema.SCHEMA_VERSION and not self._read_only:
                self._check_whole(connection)
            while version < schema.SCHEMA_VERSION:
                step = schema.MIGRATIONS.get(version)
                if step is None or self._read_only:
                    why = "opens it read-only: it cannot migrate it" if step else "has no migration from it"
                    raise ArchiveFileError(
                        f"archive {self._location} has schema version {version} and this rsi {why} to "
                        f"{schema.SCHEMA_VERSION}; it was not modified. Open it writable with this rsi, or "
                        "with the rsi that wrote it and export its runs (rsi archive export)."
                    )
                step(connection)
                version += 1
                connection.execute(schema.archive_info.update().values(schema_version=version))
            return int(version)

    def _stored_version(self, connection: Connection) -> int:
        rows = connection.exec_driver_sql("SELECT schema_version FROM rsi_archive").fetchmany(2)
        if (
            len(rows) != 1
            or isinstance(rows[0][0], bool)
            or not isinstance(rows[0][0], int)
            or rows[0][0] < 1
        ):
            found = "no row" if not rows else ("several rows" if len(rows) > 1 else f"{rows[0][0]!r}")
            raise ArchiveFileError(
                f"archive {self._location} has no valid schema version (table rsi_archive holds {found}); it "
                "was not modified. Restore it from a backup."
            )
        return int(rows[0][0])

    def _check_whole(self, connection: Connection) -> None:
        """Refuse a damaged archive before any write: SQLite's page check, the schema, every row."""
        if connection.dialect.name == "sqlite":
            verdict = [str(row[0]) for row in connection.exec_driver_sql("PRAGMA quick_check(5)")]
            if verdict != ["ok"]:
                said = " ".join("; ".join(verdict).split())
                raise ArchiveFileError(
                    f"archive {self._location} is damaged (SQLite quick_check: {said}); it was not modified. "
                    "Restore it from a backup; `rsi archive list` may still read it."
                )
        missing = _integrity.missing_schema(connection)
        if missing:
            raise ArchiveFileError(
                f"archive {self._location} lacks {', '.join(missing)}; it is damaged and was not modified. "
                "Restore it from a backup."
            )
        self._refuse_bad_rows(connection)

    def _refuse_bad_rows(self, connection: Connection) -> None:
        bad = _integrity.bad_rows(connection)
        if bad:
            raise self._rows_error(bad)

    def _rows_error(self, bad: list[str]) -> ArchiveFileError:
        return ArchiveFileError(
            f"archive {self._location} has rows it cannot read back ({'; '.join(bad)}); it was not "
            "modified. Fix or delete those rows, or restore the archive from a backup."
        )

    def _use_wal(self) -> None:
        """Switch a SQLite archive to the WAL journal (persistent; set once the file is known to be ours).

        WAL: readers never block the writer nor see a half-written transaction, and a writer killed mid-write
        leaves only an uncommitted tail of the log, which the next open discards.
        """
        raw = self._engine.raw_connection()
        try:
            cursor = raw.cursor()
            cursor.execute("PRAGMA journal_mode=WAL")
            cursor.close()
        finally:
            raw.close()

    @contextlib.contextmanager
    def _transaction(self, *, write: bool) -> Iterator[Connection]:
        """One transaction; database failures and unreadable rows become errors that name the archive."""
        if write and self._read_only:
            raise ArchiveError(
                f"archive {self._location} was opened read-only; open it with read_only=False to write."
            )
        try:
            with self._engine.connect() as connection:
                if write:
                    connection.execution_options(rsi_write=True)
                with connection.begin():
                    yield connection
        except RsiError:
            raise
        except exc.DatabaseError as error:
            message = str(error.orig)
            if isinstance(error, exc.IntegrityError):
                raise
            if isinstance(error, exc.OperationalError) and ("locked" in message or "busy" in message):
                raise ArchiveError(
                    f"archive {self._location} stayed locked by another writer past the busy timeout "
                    f"({message}); retry, or open it with a longer busy_timeout_s."
                ) from error
            raise self._unreadable(error) from error
        except (ValueError, TypeError, OverflowError, KeyError) as error:
            # A stored value the archive cannot turn back into a record (a tampered row): name the row.
            raise self._bad_row_error(error) from error

    def _bad_row_error(self, error: Exception) -> Exception:
        try:
            with self._engine.connect() as connection, connection.begin():
                bad = _integrity.bad_rows(connection)
        except exc.DatabaseError:
            bad = []
        return self._rows_error(bad) if bad else error

    def _unreadable(self, error: exc.DBAPIError) -> ArchiveFileError:
        return ArchiveFileError(
            f"{self._location} is not a readable rsi archive: the database says {str(error.orig)!r}. "
            "It was not modified; restore it from a backup or open another path."
        )

    def close(self) -> None:
        """Close the database connections (the archive can be opened again)."""
        self._engine.dispose()

    def __enter__(self) -> Archive:
        return self

    def __exit__(
        self,
        kind: type[BaseException] | None,
        error: BaseException | None,
        traceback: TracebackType | None,
    ) -> None:
        self.close()

    def __repr__(self) -> str:
        return f"Archive({self._location!r}, schema_version={self._schema_version})"

    @property
    def location(self) -> str:
        """The database file path, or its URL without password."""
        return self._location

    @property
    def read_only(self) -> bool:
        """Whether the archive was opened read-only (every write raises :class:`ArchiveError`)."""
        return self._read_only

    @property
    def images_dir(self) -> Path:
        """Folder of the content-addressed image files."""
        return self._images_dir

    @property
    def schema_version(self) -> int:
        """Schema version of the open archive (always :data:`rsi.archive.schema.SCHEMA_VERSION`)."""
        return self._schema_version

    # ------------------------------------------------------------------ vistas

    def add_vista(self, vista: VistaLike | VistaPoint | str, *, replace: bool = False) -> VistaPoint:
        """Store a vista point (a name alone, a :class:`VistaPoint`, or anything with a vista's pose).

        Adding the same vista again is a no-op; a different pose under a stored name raises unless `replace`.
        """
        if isinstance(vista, str):
            record = VistaPoint(vista)
        elif isinstance(vista, VistaPoint):
            record = vista
        else:
            try:
                record = VistaPoint.from_pose(vista)
            except AttributeError as error:
                raise InputError(
                    f"vista must be a name, a VistaPoint, or an object with name, position_m, forward, up, "
                    f"target_m and standoff_m; {type(vista).__name__} has no {error.name!r}."
                ) from None
        values = {"name": record.name, "standoff_m": record.standoff_m}
        for prefix in ("position_m", "forward", "up", "target_m"):
            vector = getattr(record, prefix)
            for axis, value in zip("xyz", vector if vector is not None else (None,) * 3, strict=True):
                values[f"{prefix}_{axis}"] = value
        table = schema.vistas
        with self._transaction(write=True) as connection:
            row = connection.execute(select(table).where(table.c.name == record.name)).first()
            if row is None:
                connection.execute(table.insert().values(**values, added_at=_to_db(_now())))
            elif _vista_of(row) != record:
                if not replace:
                    raise InputError(
                        f"vista {record.name!r} is already stored with another pose ({_vista_of(row)}); "
                        "pass replace=True to move it, or use a new name."
                    )
                connection.execute(table.update().where(table.c.id == row.id).values(**values))
        return record

    def vistas(self) -> tuple[VistaPoint, ...]:
        """Every vista point, in the order added."""
        with self._transaction(write=False) as connection:
            rows = connection.execute(select(schema.vistas).order_by(schema.vistas.c.id)).all()
        return tuple(_vista_of(row) for row in rows)

    def vista(self, name: str) -> VistaPoint:
        """The vista point called `name`."""
        with self._transaction(write=False) as connection:
            return _vista_of(self._vista_row(connection, name))

    def _vista_row(self, connection: Connection, name: str) -> Row[Any]:
        check_name(name, "vista")
        row = connection.execute(select(schema.vistas).where(schema.vistas.c.name == name)).first()
        if row is None:
            raise InputError(
                f"vista {name!r} is not in the archive {self._location}; add it with Archive.add_vista "
                "first (Archive.vistas() lists those stored)."
            )
        return row

    # ------------------------------------------------------------------ images and references

    def store_image(self, image: bytes | np.ndarray) -> str:
        """Store an image (encoded file bytes, or an array kept exactly as ``.npy``); return its SHA-256.

        The file is written atomically under :attr:`images_dir` before its row is committed, so a row never
        names a missing file; identical images are stored once.
        """
        data, media = _images.encode(image, "image")
        return self._store_bytes(data, media)

    def _store_bytes(self, data: bytes, media: str, connection: Connection | None = None) -> str:
        digest = _images.write(self._images_dir, data)
        values = {"sha256": digest, "media": media, "size_bytes": len(data), "stored_at": _to_db(_now())}
        table = schema.images
        with contextlib.ExitStack() as stack:
            if connection is None:
                connection = stack.enter_context(self._transaction(write=True))
            exists = connection.execute(select(table.c.sha256).where(table.c.sha256 == digest)).first()
            if exists is None:
                connection.execute(table.insert().values(**values))
        return digest

    def image(self, sha256: str) -> bytes | np.ndarray:
        """The stored image with this SHA-256: an array if an array was stored, else the bytes."""
        check_sha256(sha256, "sha256")
        with self._transaction(write=False) as connection:
            media = connection.execute(
                select(schema.images.c.media).where(schema.images.c.sha256 == sha256)
            ).scalar_one_or_none()
        if media is None:
            raise InputError(f"no image with sha256={sha256} in the archive {self._location}.")
        return _images.decode(self._read_checked(sha256), media)

    def _read_checked(self, sha256: str) -> bytes:
        try:
            return _images.read(self._images_dir, sha256)
        except _images.ImageIntegrityError as error:
            raise ArchiveFileError(f"archive {self._location}: {error}") from None

    def store_reference(self, vista: str, image: bytes | np.ndarray) -> str:
        """Make `image` the reference of `vista` (already added) and return its SHA-256.

        Earlier references stay stored (findings made against them still name them).
        """
        data, media = _images.encode(image, "image")
        with self._transaction(write=True) as connection:
            vista_id = self._vista_row(connection, vista).id
            digest = self._store_bytes(data, media, connection)
            connection.execute(
                schema.references.insert().values(vista_id=vista_id, sha256=digest, stored_at=_to_db(_now()))
            )
        return digest

    def reference_info(self, vista: str) -> ReferenceImage:
        """The current reference of `vista`: hash, media type, size, when stored and the file."""
        refs, image_table = schema.references, schema.images
        with self._transaction(write=False) as connection:
            vista_id = self._vista_row(connection, vista).id
            row = connection.execute(
                select(refs.c.sha256, refs.c.stored_at, image_table.c.media, image_table.c.size_bytes)
                .join(image_table, image_table.c.sha256 == refs.c.sha256)
                .where(refs.c.vista_id == vista_id)
                .order_by(refs.c.id.desc())
                .limit(1)
            ).first()
        if row is None:
            raise InputError(
                f"vista {vista!r} has no reference image in the archive {self._location}; run a reference "
                "pass or store one with Archive.store_reference."
            )
        return ReferenceImage(
            vista=vista,
            sha256=row.sha256,
            media=row.media,
            size_bytes=int(row.size_bytes),
            stored_at=_from_db(row.stored_at),
            path=_images.path_of(self._images_dir, row.sha256),
        )

    def reference(self, vista: str) -> bytes | np.ndarray:
        """The current reference image of `vista` (an array if an array was stored, else the bytes)."""
        info = self.reference_info(vista)
        return _images.decode(self._read_checked(info.sha256), info.media)

    # ------------------------------------------------------------------ runs

    def start_run(
        self,
        *,
        label: str = "",
        seed: int | None = None,
        settings: dict[str, Any] | None = None,
        started_at: datetime | None = None,
    ) -> int:
        """Record a new run as "running" and return its id (committed at once)."""
        if not isinstance(label, str) or len(label) > 200:
            raise InputError(f"label must be a string of at most 200 characters; got {label!r}.")
        if seed is not None and (
            isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or not 0 <= seed < _MAX_SEED
        ):
            raise InputError(f"seed must be None or an integer in [0, 2**63); got {seed!r}.")
        settings_text = json_text({} if settings is None else settings, "settings")
        moment = _now() if started_at is None else _moment(started_at, "started_at")
        with self._transaction(write=True) as connection:
            run_id = connection.execute(
                schema.runs.insert().values(
                    label=label,
                    status="running",
                    seed=None if seed is None else int(seed),
                    settings_json=settings_text,
                    started_at=_to_db(moment),
                    host=socket.gethostname()[:255],
                    pid=os.getpid(),
                )
            ).inserted_primary_key
        assert run_id is not None
        return int(run_id[0])

    def finish_run(
        self, run_id: int, status: str = "finished", *, finished_at: datetime | None = None
    ) -> Run:
        """End a running run with `status` ("finished", "failed" or "aborted")."""
        choice(status, "status", END_STATUSES)
        moment = _now() if finished_at is None else _moment(finished_at, "finished_at")
        with self._transaction(write=True) as connection:
            self._running_row(connection, run_id)
            connection.execute(
                schema.runs.update()
                .where(schema.runs.c.id == run_id)
                .values(status=status, finished_at=_to_db(moment))
            )
        return self.run(run_id)

    def _run_row(self, connection: Connection, run_id: int) -> Row[Any]:
        _check_id(run_id, "run_id")
        row = connection.execute(select(schema.runs).where(schema.runs.c.id == int(run_id))).first()
        if row is None:
            raise InputError(
                f"run {run_id} is not in the archive {self._location}; Archive.runs() lists those stored."
            )
        return row

    def _running_row(self, connection: Connection, run_id: int) -> Row[Any]:
        row = self._run_row(connection, run_id)
        if row.status != "running":
            raise InputError(
                f"run {run_id} is already {row.status}; findings are added to, and runs finished from, a "
                "running run only. Start a new run with Archive.start_run."
            )
        return row

    def runs(self, *, status: str | None = None) -> tuple[Run, ...]:
        """Every run (or those with `status`), oldest first, with their finding counts."""
        if status is not None:
            choice(status, "status", RUN_STATUSES)
        with self._transaction(write=False) as connection:
            return self._runs(connection, status=status)

    def _runs(
        self, connection: Connection, *, status: str | None = None, run_id: int | None = None
    ) -> tuple[Run, ...]:
        counts = (
            select(schema.findings.c.run_id, func.count().label("finding_count"))
            .group_by(schema.findings.c.run_id)
            .subquery()
        )
        query = (
            select(schema.runs, func.coalesce(counts.c.finding_count, 0).label("finding_count"))
            .outerjoin(counts, counts.c.run_id == schema.runs.c.id)
            .order_by(schema.runs.c.id)
        )
        if status is not None:
            query = query.where(schema.runs.c.status == status)
        if run_id is not None:
            query = query.where(schema.runs.c.id == run_id)
        return tuple(_run_of(row) for row in connection.execute(query))

    def run(self, run_id: int) -> Run:
        """The run with this id."""
        with self._transaction(write=False) as connection:
            self._run_row(connection, run_id)
            return self._runs(connection, run_id=int(run_id))[0]

    # ------------------------------------------------------------------ findings and flaw history

    def add_findings(
        self,
        run_id: int,
        findings: Iterable[Finding],
        *,
        tolerance_m: float = 0.005,
        tolerance_px: float = 3.0,
    ) -> tuple[StoredFinding, ...]:
        """Store findings of a running run in one transaction (all or none) and link each to its history.

        A finding is the same flaw as an earlier sighting when the vista and kind match and its position
        lies within `tolerance_m` (both have ``position_m``) or its bbox centre within `tolerance_px` (else).
        Among the finished runs that started before this one, the latest with such a sighting is used, and
        within it the nearest sighting.
        """
        if isinstance(findings, (str, bytes, Finding)) or not isinstance(findings, Iterable):
            raise InputError(f"findings must be an iterable of Finding; got {type(findings).__name__}.")
        batch = tuple(findings)
        for index, finding in enumerate(batch):
            if not isinstance(finding, Finding):
                raise InputError(
                    f"findings[{index}] must be an rsi.archive.Finding; got {type(finding).__name__}. "
                    "Build one with Finding(...) or Finding.from_flaw(flaw, ...)."
                )
        tolerance_m = in_range(tolerance_m, "tolerance_m", low=0.0)
        tolerance_px = in_range(tolerance_px, "tolerance_px", low=0.0)
        with self._transaction(write=True) as connection:
            run = self._running_row(connection, run_id)
            vista_ids = {name: self._vista_row(connection, name).id for name in {f.vista for f in batch}}
            self._check_images(connection, batch)
            current_reference = {
                name: self._current_reference(connection, vista_id) for name, vista_id in vista_ids.items()
            }
            earlier = self._earlier_sightings(
                connection, run, batch, vista_ids, tolerance_m=tolerance_m, tolerance_px=tolerance_px
            )
            rows = [
                {
                    "run_id": run.id,
                    "vista_id": vista_ids[finding.vista],
                    "reference_sha256": finding.reference_sha256 or current_reference[finding.vista],
                    "previous_id": None if previous is None else previous[0],
                    "track_id": None if previous is None else previous[1],
                    **_finding_columns(finding),
                }
                for finding, previous in zip(batch, earlier, strict=True)
            ]
            if not rows:
                return ()
            table = schema.findings
            connection.execute(table.insert(), rows)
            # The batch's ids: the write lock is held and one process writes a run, so the run's newest ids
            # are this batch's, in order (one executemany, where INSERT ... RETURNING would go row by row).
            newest = (
                select(table.c.id)
                .where(table.c.run_id == run.id)
                .order_by(table.c.id.desc())
                .limit(len(rows))
            )
            new_ids = sorted(connection.execute(newest).scalars())
            # A first sighting starts its own track.
            connection.execute(
                table.update()
                .where(table.c.run_id == run.id, table.c.track_id.is_(None))
                .values(track_id=table.c.id)
            )
        return tuple(
            StoredFinding(
                finding_id=int(new_id),
                run_id=int(run.id),
                vista=finding.vista,
                kind=finding.kind,
                confidence=finding.confidence,
                position_m=finding.position_m,
                bbox=finding.bbox,
                size_m=finding.size_m,
                area_px=finding.area_px,
                score=finding.score,
                reference_sha256=row["reference_sha256"],
                inspection_sha256=finding.inspection_sha256,
                extras=finding.extras,
                previous_id=row["previous_id"],
                track_id=int(new_id) if row["track_id"] is None else int(row["track_id"]),
                seen_at=_from_db(run.started_at),
            )
            for new_id, finding, row in zip(new_ids, batch, rows, strict=True)
        )

    def _check_images(self, connection: Connection, batch: Sequence[Finding]) -> None:
        named = {
            digest
            for finding in batch
            for digest in (finding.reference_sha256, finding.inspection_sha256)
            if digest is not None
        }
        if not named:
            return
        found = set(
            connection.execute(
                select(schema.images.c.sha256).where(schema.images.c.sha256.in_(sorted(named)))
            ).scalars()
        )
        missing = sorted(named - found)
        if missing:
            raise InputError(
                f"findings name images not in the archive {self._location}: {', '.join(missing)}; store them "
                "with Archive.store_image first."
            )

    def _current_reference(self, connection: Connection, vista_id: int) -> str | None:
        refs = schema.references
        digest: str | None = connection.execute(
            select(refs.c.sha256).where(refs.c.vista_id == vista_id).order_by(refs.c.id.desc()).limit(1)
        ).scalar_one_or_none()
        return digest

    def _earlier_sightings(
        self,
        connection: Connection,
        run: Row[Any],
        batch: Sequence[Finding],
        vista_ids: dict[str, int],
        *,
        tolerance_m: float,
        tolerance_px: float,
    ) -> list[tuple[int, int] | None]:
        """(id, track id) of each finding's earlier sighting, or None: one query per vista, kind and frame."""
        groups: dict[tuple[str, str, bool], list[int]] = {}
        for index, finding in enumerate(batch):
            groups.setdefault((finding.vista, finding.kind, finding.position_m is not None), []).append(index)
        earlier: list[tuple[int, int] | None] = [None] * len(batch)
        for (vista, kind, by_position), indices in groups.items():
            centres = [_centre(batch[index], by_position) for index in indices]
            tolerance = tolerance_m if by_position else tolerance_px
            candidates = self._candidates(
                connection,
                run,
                vista_ids[vista],
                kind,
                by_position=by_position,
                centres=centres,
                tolerance=tolerance,
            )
            # Candidates sorted on the first coordinate: each finding checks only those within tolerance of
            # it on that axis (bisect), so a long history costs O(log n) per finding, not O(n).
            located = sorted(
                (
                    (_row_centre(row, by_position), -_from_db(row.started_at).timestamp(), row)
                    for row in candidates
                ),
                key=lambda item: item[0][0],
            )
            firsts = [item[0][0] for item in located]
            for index, centre in zip(indices, centres, strict=True):
                best: tuple[tuple[float, float], Row[Any]] | None = None
                low = bisect.bisect_left(firsts, centre[0] - tolerance)
                high = bisect.bisect_right(firsts, centre[0] + tolerance)
                for where, age, row in located[low:high]:
                    distance = math.dist(centre, where)
                    # Latest earlier run first, then the nearest sighting in it.
                    if distance <= tolerance and (best is None or (age, distance) < best[0]):
                        best = ((age, distance), row)
                if best is not None:
                    earlier[index] = (int(best[1].id), int(best[1].track_id))
        return earlier

    def _candidates(
        self,
        connection: Connection,
        run: Row[Any],
        vista_id: int,
        kind: str,
        *,
        by_position: bool,
        centres: Sequence[tuple[float, ...]],
        tolerance: float,
    ) -> list[Row[Any]]:
        """Sightings in finished runs started before `run`, at the vista and of the kind, near the centres."""
        table, runs = schema.findings, schema.runs
        near: sa.ColumnElement[bool]
        if by_position:
            # Indexed range on x (vista, kind, x); the exact distance is checked by the caller.
            near = table.c.position_m_x.between(
                min(c[0] for c in centres) - tolerance, max(c[0] for c in centres) + tolerance
            )
        else:
            # Twice the bbox centre is an integer sum: prefilter rows, the exact distance is checked later.
            near = (table.c.row0 + table.c.row1).between(
                2 * (min(c[0] for c in centres) - tolerance), 2 * (max(c[0] for c in centres) + tolerance)
            ) & table.c.row0.is_not(None)
        query = (
            select(table.c.id, table.c.track_id, runs.c.started_at, *_position_columns(table))
            .join(runs, runs.c.id == table.c.run_id)
            .where(
                table.c.vista_id == vista_id,
                table.c.kind == kind,
                near,
                runs.c.status == "finished",
                runs.c.id != run.id,
                runs.c.started_at <= run.started_at,
            )
        )
        return list(connection.execute(query))

    def findings(self, run_id: int) -> tuple[StoredFinding, ...]:
        """The findings of a run, in the order stored."""
        with self._transaction(write=False) as connection:
            self._run_row(connection, run_id)
            return self._findings(connection, schema.findings.c.run_id == int(run_id))

    def finding(self, finding_id: int) -> StoredFinding:
        """The finding with this id."""
        _check_id(finding_id, "finding_id")
        with self._transaction(write=False) as connection:
            found = self._findings(connection, schema.findings.c.id == int(finding_id))
        if not found:
            raise InputError(f"finding {finding_id} is not in the archive {self._location}.")
        return found[0]

    def history(self, finding_id: int) -> FlawHistory:
        """Every sighting of the flaw that `finding_id` is a sighting of, oldest first (its growth)."""
        track_id = self.finding(finding_id).track_id
        with self._transaction(write=False) as connection:
            sightings = self._findings(connection, schema.findings.c.track_id == track_id)
        return FlawHistory(track_id=track_id, sightings=sightings)

    def _findings(
        self, connection: Connection, condition: sa.ColumnElement[bool]
    ) -> tuple[StoredFinding, ...]:
        table = schema.findings
        query = (
            select(table, schema.vistas.c.name.label("vista_name"), schema.runs.c.started_at)
            .join(schema.vistas, schema.vistas.c.id == table.c.vista_id)
            .join(schema.runs, schema.runs.c.id == table.c.run_id)
            .where(condition)
            .order_by(schema.runs.c.started_at, table.c.id)
        )
        return tuple(_stored_finding_of(row) for row in connection.execute(query))

    # ------------------------------------------------------------------ reviews

    def review_finding(
        self, finding_id: int, verdict: str, *, note: str = "", reviewer: str = "operator"
    ) -> Review:
        """Record an operator's verdict on a finding: confirmed, rejected, or a note alone (issue 16).

        Reviews are kept, never overwritten; the newest is the finding's standing (:meth:`reviews`).
        Raises InputError for an unknown finding or verdict, or a note over 10,000 characters.
        """
        if verdict not in schema.REVIEW_VERDICTS:
            choices = ", ".join(map(repr, schema.REVIEW_VERDICTS))
            raise InputError(f"verdict={verdict!r} is not known. Choose one of {choices}.")
        if not isinstance(note, str) or len(note) > _MAX_NOTE:
            raise InputError(f"note must be a string of at most {_MAX_NOTE} characters; got {note!r:.80}.")
        if not isinstance(reviewer, str) or not 0 < len(reviewer) <= 200:
            raise InputError(f"reviewer must be a name of 1 to 200 characters; got {reviewer!r:.80}.")
        self.finding(finding_id)  # names a missing finding
        moment = _now()
        with self._transaction(write=True) as connection:
            review_id = connection.execute(
                schema.reviews.insert().values(
                    finding_id=int(finding_id),
                    verdict=verdict,
                    note=note,
                    reviewer=reviewer,
                    reviewed_at=_to_db(moment),
                )
            ).inserted_primary_key
        assert review_id is not None
        return Review(int(review_id[0]), int(finding_id), verdict, note, reviewer, moment)

    def reviews(self, finding_id: int) -> tuple[Review, ...]:
        """Every review of a finding, oldest first (the last is its standing); empty if never reviewed."""
        self.finding(finding_id)
        table = schema.reviews
        with self._transaction(write=False) as connection:
            rows = connection.execute(
                select(table).where(table.c.finding_id == int(finding_id)).order_by(table.c.id)
            ).all()
        return tuple(
            Review(row.id, row.finding_id, row.verdict, row.note, row.reviewer, _from_db(row.reviewed_at))
            for row in rows
        )

    # ------------------------------------------------------------------ export

    def export_run(self, run_id: int, out_dir: str | os.PathLike[str]) -> Path:
        """Write a run as ``run-<id>.json`` plus the images its findings name (``images/<sha256>.<ext>``).

        Every file is written atomically; the JSON is written last, so its presence means a complete export.

        Returns
        -------
        Path
            The JSON file.
        """
        folder, _ = writable_folder(out_dir, "out_dir")
        with self._transaction(write=False) as connection:
            self._run_row(connection, run_id)
            run = self._runs(connection, run_id=int(run_id))[0]
            found = self._findings(connection, schema.findings.c.run_id == int(run_id))
            names = sorted({finding.vista for finding in found})
            vista_rows = connection.execute(
                select(schema.vistas).where(schema.vistas.c.name.in_(names)).order_by(schema.vistas.c.name)
            ).all()
            digests = sorted(
                {
                    digest
                    for finding in found
                    for digest in (finding.reference_sha256, finding.inspection_sha256)
                    if digest is not None
                }
            )
            image_table = schema.images
            rows = connection.execute(
                select(image_table.c.sha256, image_table.c.media).where(image_table.c.sha256.in_(digests))
            )
            media = {row.sha256: row.media for row in rows}
        files = {}
        for digest in digests:
            relative = f"images/{digest}{_images.EXTENSIONS[media[digest]]}"
            atomic_write_bytes(folder / relative, self._read_checked(digest))
            files[digest] = relative
        document = {
            "archive": self._location,
            "schema_version": self._schema_version,
            "exported_by": f"rsi {__version__}",
            "run": _jsonable(run),
            "vistas": [_jsonable(_vista_of(row)) for row in vista_rows],
            "findings": [_jsonable(finding) for finding in found],
            "images": files,
        }
        text = json.dumps(document, indent=2, sort_keys=True)
        return atomic_write_bytes(folder / f"run-{int(run_id)}.json", text.encode("utf-8"))


# ---------------------------------------------------------------------- row <-> record


def _vector(row: Row[Any], prefix: str) -> tuple[float, float, float] | None:
    values = (getattr(row, f"{prefix}_x"), getattr(row, f"{prefix}_y"), getattr(row, f"{prefix}_z"))
    return None if values[0] is None else (float(values[0]), float(values[1]), float(values[2]))


def _vista_of(row: Row[Any]) -> VistaPoint:
    return VistaPoint(
        name=row.name,
        position_m=_vector(row, "position_m"),
        forward=_vector(row, "forward"),
        up=_vector(row, "up"),
        target_m=_vector(row, "target_m"),
        standoff_m=row.standoff_m,
    )


def _run_of(row: Row[Any]) -> Run:
    return Run(
        run_id=int(row.id),
        label=row.label,
        status=row.status,
        seed=row.seed,
        settings=_json_mapping(row.settings_json),
        started_at=_from_db(row.started_at),
        finished_at=None if row.finished_at is None else _from_db(row.finished_at),
        finding_count=int(row.finding_count),
        host=row.host,
        pid=int(row.pid),
    )


def _json_mapping(text: str) -> dict[str, Any]:
    """A stored JSON object; anything else is a damaged row (ValueError, named by the caller's check)."""
    value = json.loads(text)
    if not isinstance(value, dict):
        raise ValueError(f"stored JSON {text[:40]!r} is not an object")
    return value


def _centre(finding: Finding, by_position: bool) -> tuple[float, ...]:
    """Where a finding is, for matching: its position (metres) or its bbox centre (pixels, row and col)."""
    if by_position:
        assert finding.position_m is not None
        return finding.position_m
    assert finding.bbox is not None
    row0, col0, row1, col1 = finding.bbox
    return ((row0 + row1) / 2, (col0 + col1) / 2)


def _row_centre(row: Row[Any], by_position: bool) -> tuple[float, ...]:
    if by_position:
        return (row.position_m_x, row.position_m_y, row.position_m_z)
    return ((row.row0 + row.row1) / 2, (row.col0 + row.col1) / 2)


def _position_columns(table: sa.Table) -> list[sa.Column[Any]]:
    names = ("position_m_x", "position_m_y", "position_m_z", "row0", "col0", "row1", "col1")
    return [table.c[name] for name in names]


def _finding_columns(finding: Finding) -> dict[str, Any]:
    position = finding.position_m or (None, None, None)
    bbox = finding.bbox or (None, None, None, None)
    return {
        "kind": finding.kind,
        "confidence": finding.confidence,
        "position_m_x": position[0],
        "position_m_y": position[1],
        "position_m_z": position[2],
        "row0": bbox[0],
        "col0": bbox[1],
        "row1": bbox[2],
        "col1": bbox[3],
        "size_m": finding.size_m,
        "area_px": finding.area_px,
        "score": finding.score,
        "inspection_sha256": finding.inspection_sha256,
        "extras_json": json_text(finding.extras, "extras"),
    }


def _stored_finding_of(row: Row[Any]) -> StoredFinding:
    bbox = None if row.row0 is None else (int(row.row0), int(row.col0), int(row.row1), int(row.col1))
    return StoredFinding(
        finding_id=int(row.id),
        run_id=int(row.run_id),
        vista=row.vista_name,
        kind=row.kind,
        confidence=float(row.confidence),
        position_m=_vector(row, "position_m"),
        bbox=bbox,
        size_m=row.size_m,
        area_px=row.area_px,
        score=row.score,
        reference_sha256=row.reference_sha256,
        inspection_sha256=row.inspection_sha256,
        extras=_json_mapping(row.extras_json),
        previous_id=row.previous_id,
        track_id=int(row.track_id),
        seen_at=_from_db(row.started_at),
    )


def _jsonable(record: object) -> dict[str, Any]:
    """A record as JSON values (datetimes as ISO 8601, tuples as lists)."""

    def convert(value: object) -> object:
        if isinstance(value, datetime):
            return value.isoformat()
        if isinstance(value, Path):
            return str(value)
        if isinstance(value, (list, tuple)):
            return [convert(item) for item in value]
        if isinstance(value, dict):
            return {key: convert(item) for key, item in value.items()}
        return value

    result: dict[str, Any] = {key: convert(value) for key, value in asdict(record).items()}  # type: ignore[call-overload]
    return result
