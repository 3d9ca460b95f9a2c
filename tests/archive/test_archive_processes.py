"""Real processes on one archive: a writer killed (SIGKILL) mid-run, and two writers at once.

The writer (tests/archive/writer.py) prints a line after each commit, so the test knows exactly which writes
were committed before the kill and checks every one of them survived.
"""

from __future__ import annotations

import os
import re
import signal
import sqlite3
import subprocess
import sys
import time
from pathlib import Path

import pytest

from rsi.archive import Archive

WRITER = Path(__file__).with_name("writer.py")
BATCHES, PER_BATCH = 4, 25
PER_RUN = BATCHES * PER_BATCH


def spawn(
    path: Path, name: str, runs: int, *pause_at: int, go_file: Path | None = None
) -> subprocess.Popen[str]:
    environment = dict(os.environ) if go_file is None else {**os.environ, "GO_FILE": str(go_file)}
    return subprocess.Popen(
        [sys.executable, str(WRITER), str(path), name, str(runs), str(BATCHES), str(PER_BATCH)]
        + [str(call) for call in pause_at],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        env=environment,
    )


def integrity(path: Path) -> str:
    connection = sqlite3.connect(path)
    try:
        return str(connection.execute("PRAGMA integrity_check").fetchone()[0])
    finally:
        connection.close()


@pytest.mark.parametrize("delay_s", [0.0, 0.002, 0.005])
def test_a_writer_killed_mid_run_leaves_every_committed_write_and_no_false_finish(
    tmp_path: Path, delay_s: float
) -> None:
    path = tmp_path / "archive.db"
    committed: dict[int, int] = {}  # run id -> findings the writer saw committed
    finished_before: list[tuple[int, str, int]] = []
    for round_index in range(2):  # kill, reopen, write again on the recovered archive, kill again
        writer = spawn(path, f"writer{round_index}", runs=50)
        assert writer.stdout is not None
        started = 0
        for line in writer.stdout:
            if match := re.fullmatch(r"batch (\d+) (\d+)\n", line):
                committed[int(match[1])] = (int(match[2]) + 1) * PER_BATCH
            started += line.startswith("started")
            if started == 3 and line.startswith("batch") and line.endswith(" 1\n"):
                break  # the third run is half written: kill it in the middle of its next transaction
        time.sleep(delay_s)
        os.kill(writer.pid, signal.SIGKILL)
        writer.communicate()
        assert writer.returncode == -signal.SIGKILL

        assert integrity(path) == "ok"
        with Archive.open(path, create=False) as archive:
            runs = archive.runs()
            finished = [
                (run.run_id, run.status, run.finding_count) for run in runs if run.status == "finished"
            ]
            for run in runs:
                assert run.finding_count >= committed.get(run.run_id, 0), "a committed batch was lost"
                assert run.finding_count % PER_BATCH == 0, "a half-written batch is visible"
                if run.status == "finished":
                    assert run.finding_count == PER_RUN
                else:
                    assert run.status == "running"  # the killed run is never reported as finished
            assert len([run for run in runs if run.status == "running"]) == round_index + 1
            assert finished[: len(finished_before)] == finished_before  # earlier runs untouched
            assert len(finished) >= len(finished_before) + 2
            finished_before = finished
            for vista in ("A_door", "B_panel", "C_tubing"):
                assert archive.reference(vista).shape == (16, 16)  # type: ignore[union-attr]
            last = archive.findings(finished[-1][0])[0]
            assert len(archive.history(last.finding_id).sightings) >= 2  # history links survive


def test_two_writers_at_once_lose_nothing(tmp_path: Path) -> None:
    path = tmp_path / "archive.db"
    runs_each = 12
    Archive.open(path).close()  # both writers open an existing archive (creating it at once is tested below)
    go_file = tmp_path / "go"
    writers = [spawn(path, name, runs_each, go_file=go_file) for name in ("left", "right")]
    go_file.touch()  # both start writing together: one waits on the other's write lock (busy timeout)
    for writer in writers:
        _, errors = writer.communicate(timeout=60)
        assert writer.returncode == 0, errors
    with Archive.open(path, create=False) as archive:
        runs = archive.runs()
        assert len(runs) == 2 * runs_each
        assert {run.status for run in runs} == {"finished"}
        assert [run.finding_count for run in runs] == [PER_RUN] * len(runs)
        for name in ("left", "right"):
            mine = [run for run in runs if run.settings == {"writer": name}]
            assert sorted(run.seed for run in mine) == list(range(runs_each))
            assert sum(len(archive.findings(run.run_id)) for run in mine) == runs_each * PER_RUN
        assert [vista.name for vista in archive.vistas()] == ["A_door", "B_panel", "C_tubing"]
        stored = [path for path in archive.images_dir.rglob("*") if path.is_file()]
        assert len(stored) == 3  # both stored the same three references: one file each


def test_two_processes_creating_one_archive_at_once_agree(tmp_path: Path) -> None:
    path = tmp_path / "new.db"
    writers = [spawn(path, name, 1) for name in ("left", "right")]
    for writer in writers:
        _, errors = writer.communicate(timeout=60)
        assert writer.returncode == 0, errors
    with Archive.open(path, create=False) as archive:
        assert [run.finding_count for run in archive.runs()] == [PER_RUN, PER_RUN]


def test_a_writer_killed_inside_a_transaction_leaves_none_of_it(tmp_path: Path) -> None:
    path = tmp_path / "archive.db"
    # Stop inside the third run's second batch: its findings written, not committed.
    writer = spawn(path, "paused", 50, 2 * BATCHES + 2)
    assert writer.stdout is not None
    lines = []
    for line in writer.stdout:
        lines.append(line.strip())
        if line == "inside\n":
            break
    os.kill(writer.pid, signal.SIGKILL)
    writer.communicate()
    assert lines[-3:] == ["started 3", "batch 3 0", "inside"]
    assert Path(f"{path}-wal").exists()  # the killed writer's log is left behind, uncommitted tail and all
    assert integrity(path) == "ok"
    with Archive.open(path, create=False) as archive:
        assert [(run.status, run.finding_count) for run in archive.runs()] == [
            ("finished", PER_RUN),
            ("finished", PER_RUN),
            ("running", PER_BATCH),
        ]
        run_id = archive.start_run()  # the recovered archive takes new writes
        assert run_id == 4
