"""`rsi console`: bad options fail before anything starts, naming the option, with the right exit code."""

from __future__ import annotations

from pathlib import Path

import pytest
from typer.testing import CliRunner

from rsi import cli
from rsi.cli import app

runner = CliRunner()


@pytest.mark.parametrize(
    ("arguments", "message"),
    [
        (["--host", "localhost"], "host must be an IP address such as 127.0.0.1; got 'localhost'"),
        (["--port", "70000"], "port must be an integer in [0, 65535]; got 70000"),
        (["--token", "short"], "token must be at least 16 characters"),
        (["--layout", "station"], "layout"),
    ],
)
def test_bad_options_are_named_and_nothing_starts(arguments: list[str], message: str) -> None:
    result = runner.invoke(app, ["console", *arguments])
    assert result.exit_code == cli.EXIT_INVALID_VALUE
    assert message in " ".join(result.output.split())


def test_an_archive_that_is_a_folder_is_refused(tmp_path: Path) -> None:
    result = runner.invoke(app, ["console", "--archive", str(tmp_path)])
    assert result.exit_code == cli.EXIT_INVALID_VALUE
    assert "is a folder; give the archive's file" in " ".join(result.output.split())


def test_a_damaged_archive_is_refused_before_the_server_starts_and_left_as_it_was(tmp_path: Path) -> None:
    damaged = tmp_path / "archive.db"
    damaged.write_bytes(b"not a database, only text\n" * 200)
    before = damaged.read_bytes()
    result = runner.invoke(app, ["console", "--archive", str(damaged)])
    assert result.exit_code == cli.EXIT_FILE
    assert "is not a readable rsi archive" in " ".join(result.output.split())
    assert "open http" not in result.output  # refused before the start URL
    assert damaged.read_bytes() == before


def test_a_seed_beyond_the_archive_integer_is_refused_by_the_option() -> None:
    result = runner.invoke(app, ["console", "--seed", str(2**63)])
    assert result.exit_code == cli.EXIT_USAGE
    assert "9223372036854775807" in " ".join(result.output.split())
