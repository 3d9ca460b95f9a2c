"""Integrity of an archive's contents: every table there, every row of a shape the archive can read back.

Rows are read as raw database values (no SQLAlchemy type conversion, which would fail on the first bad
value without saying where), so a tampered or damaged row is named by its table and id. Run before any
write (a damaged archive is never written to) and to explain a read that failed.
"""

from __future__ import annotations

import json
import math
from collections.abc import Callable, Iterator, Mapping
from datetime import datetime
from typing import Any

import sqlalchemy as sa
from sqlalchemy import Connection

from rsi.archive import schema
from rsi.archive.records import RUN_STATUSES

_MAX_ID = 2**63 - 1
_HEX = frozenset("0123456789abcdef")


def _integer(value: object, *, low: int = 0, high: int = _MAX_ID) -> bool:
    return isinstance(value, int) and not isinstance(value, bool) and low <= value <= high


def _identifier(value: object) -> bool:
    return _integer(value, low=1)


def _kind(check: Callable[[object], bool], kind: str) -> Callable[[object], bool]:
    check.sql_kind = kind  # type: ignore[attr-defined]
    return check


def _optional(check: Callable[[object], bool]) -> Callable[[object], bool]:
    return _kind(lambda value: value is None or check(value), f"optional:{check.sql_kind}")  # type: ignore[attr-defined]


def _number(value: object) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool) and math.isfinite(value)


def _text(limit: int) -> Callable[[object], bool]:
    return _kind(lambda value: isinstance(value, str) and len(value) <= limit, f"text{limit}")


def _name(value: object) -> bool:
    return isinstance(value, str) and bool(value.strip()) and len(value) <= 200


def _moment(value: object) -> bool:
    if isinstance(value, datetime):
        return True
    if not isinstance(value, str):
        return False
    try:
        datetime.fromisoformat(value)
    except ValueError:
        return False
    return True


def _json_object(value: object) -> bool:
    if not isinstance(value, str):
        return False
    try:
        return isinstance(json.loads(value), dict)
    except ValueError:
        return False


def _sha256(value: object) -> bool:
    return isinstance(value, str) and len(value) == 64 and set(value) <= _HEX


def _confidence(value: object) -> bool:
    return _number(value) and 0.0 <= float(value) <= 1.0  # type: ignore[arg-type]


for _check, _name_of_kind in (
    (_identifier, "id"),
    (_integer, "integer"),
    (_number, "number"),
    (_name, "name"),
    (_moment, "moment"),
    (_json_object, "json"),
    (_sha256, "sha256"),
    (_confidence, "confidence"),
):
    _kind(_check, _name_of_kind)

_POSITION = {f"{prefix}_{axis}": _optional(_number) for prefix in ("position_m",) for axis in "xyz"}
_POSE = {
    f"{prefix}_{axis}": _optional(_number)
    for prefix in ("position_m", "forward", "up", "target_m")
    for axis in "xyz"
}
_BBOX = {name: _optional(_integer) for name in ("row0", "col0", "row1", "col1")}

#: What each column of each table must hold for the archive to read the row back.
COLUMN_CHECKS: Mapping[str, Mapping[str, Callable[[object], bool]]] = {
    "rsi_archive": {
        "id": _identifier,
        "schema_version": _identifier,
        "created_at": _moment,
        "created_by": _text(64),
    },
    "vistas": {
        "id": _identifier,
        "name": _name,
        **_POSE,
        "standoff_m": _optional(_number),
        "added_at": _moment,
    },
    "images": {"sha256": _sha256, "media": _text(16), "size_bytes": _integer, "stored_at": _moment},
    "references": {"id": _identifier, "vista_id": _identifier, "sha256": _sha256, "stored_at": _moment},
    "runs": {
        "id": _identifier,
        "label": _text(200),
        "status": _kind(lambda value: value in RUN_STATUSES, "status"),
        "seed": _optional(_integer),
        "settings_json": _json_object,
        "started_at": _moment,
        "finished_at": _optional(_moment),
        "host": _text(255),
        "pid": _integer,
    },
    "findings": {
        "id": _identifier,
        "run_id": _identifier,
        "vista_id": _identifier,
        "kind": _name,
        "confidence": _confidence,
        **_POSITION,
        **_BBOX,
        "size_m": _optional(_number),
        "area_px": _optional(_integer),
        "score": _optional(_number),
        "reference_sha256": _optional(_sha256),
        "inspection_sha256": _optional(_sha256),
        "extras_json": _json_object,
        "previous_id": _optional(_identifier),
        "track_id": _optional(_identifier),
    },
}


# The same checks in SQLite's SQL, to find the bad rows without converting every row in Python (10,000
# findings: 0.7 s in Python, a few ms here). Python then names the column of the few rows found.
_NUMBER_SQL = "(typeof({c}) IN ('integer', 'real') AND abs({c}) <= 1.7976931348623157e308)"
_SQL = {
    "id": "(typeof({c}) = 'integer' AND {c} >= 1)",
    "integer": "(typeof({c}) = 'integer' AND {c} >= 0)",
    "number": _NUMBER_SQL,
    "confidence": f"({_NUMBER_SQL} AND {{c}} BETWEEN 0 AND 1)",
    "moment": "(typeof({c}) = 'text' AND julianday({c}) IS NOT NULL)",
    "json": "(typeof({c}) = 'text' AND json_valid({c}) AND json_type({c}) = 'object')",
    "sha256": "(typeof({c}) = 'text' AND length({c}) = 64 AND {c} NOT GLOB '*[^0-9a-f]*')",
    "name": "(typeof({c}) = 'text' AND length(trim({c})) > 0 AND length({c}) <= 200)",
    "status": "({c} IN (" + ", ".join(f"'{status}'" for status in RUN_STATUSES) + "))",
}


def _sql_of(check: Callable[[object], bool], column: str) -> str | None:
    kind = getattr(check, "sql_kind", None)
    if kind is None:
        return None
    optional, _, base = kind.partition(":") if kind.startswith("optional:") else ("", "", kind)
    if base.startswith("text"):
        clause = f"(typeof({column}) = 'text' AND length({column}) <= {int(base[4:])})"
    else:
        clause = _SQL[base].format(c=column)
    return f"({column} IS NULL OR {clause})" if optional else clause


def missing_schema(connection: Connection) -> list[str]:
    """Tables, or table.columns, of this rsi's schema that the database lacks."""
    inspector = sa.inspect(connection)
    present = set(inspector.get_table_names())
    missing: list[str] = []
    for table in schema.metadata.sorted_tables:
        if table.name not in present:
            missing.append(f"table {table.name!r}")
            continue
        columns = {column["name"] for column in inspector.get_columns(table.name)}
        missing.extend(f"column {table.name}.{name}" for name in table.columns.keys() if name not in columns)  # noqa: SIM118
    return missing


def bad_rows(connection: Connection, *, limit: int = 5) -> list[str]:
    """Up to `limit` descriptions of rows the archive could not read back: ``table row key: column=value``."""
    found: list[str] = []
    for table, checks in COLUMN_CHECKS.items():
        for problem in _table_problems(connection, table, checks):
            found.append(problem)
            if len(found) >= limit:
                return found
    found.extend(_version_problems(connection)[: limit - len(found)])
    return found


def _table_problems(
    connection: Connection, table: str, checks: Mapping[str, Callable[[object], bool]]
) -> Iterator[str]:
    columns = list(checks)
    key = columns[0]
    quoted = ", ".join(_quote(connection, name) for name in columns)
    # Raw values, no type processing: a value SQLAlchemy would fail to convert is seen as it is stored.
    query = f"SELECT {quoted} FROM {_quote(connection, table)}"
    filtered = connection.dialect.name == "sqlite"
    if filtered:
        clauses = [_sql_of(check, _quote(connection, name)) for name, check in checks.items()]
        query += f" WHERE NOT ({' AND '.join(clause for clause in clauses if clause)})"
    for raw in connection.exec_driver_sql(query):
        row = dict(zip(columns, raw, strict=True))
        for name, check in checks.items():
            value: Any = row[name]
            if not check(value):
                shown = repr(value)
                shown = shown if len(shown) <= 60 else shown[:57] + "..."
                yield f"table {table} row {key}={row[key]!r}: {name}={shown} is not valid"
                break
        else:
            if filtered:  # SQLite's test and Python's differ in some corner: still a row to look at
                yield f"table {table} row {key}={row[key]!r}: a value is not valid"


def _version_problems(connection: Connection) -> list[str]:
    count = connection.exec_driver_sql(f"SELECT count(*) FROM {_quote(connection, 'rsi_archive')}").scalar()
    if count != 1:
        return [f"table rsi_archive has {count} rows where it must have exactly one (the schema version)"]
    return []


def _quote(connection: Connection, name: str) -> str:
    return str(connection.dialect.identifier_preparer.quote(name))
