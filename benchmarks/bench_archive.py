"""Time the inspection archive against what a user would write instead: plain sqlite3, or a JSON file per run.

Writes `runs` runs of `findings` findings each (batches of 100, the same flaws every run so every finding is
matched to its earlier sighting), then reads them back; stores and reads a 1024x1024 float32 reference; times
one writer against two writer processes on one archive. The alternatives store the same rows with no history
links: ``sqlite3`` (WAL, synchronous=FULL, one ``executemany`` transaction per batch) and a JSON file per run
written atomically.

Run: ``.venv/bin/python benchmarks/bench_archive.py [--runs 40] [--findings 200]``.
"""

from __future__ import annotations

import argparse
import itertools
import json
import multiprocessing
import sqlite3
import statistics
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np

from rsi._files import atomic_write_bytes
from rsi.archive import Archive, Finding

BATCH = 100


def findings_for(run: int, count: int) -> list[Finding]:
    return [
        Finding(
            f"V{item % 12}",
            "impact",
            0.9,
            position_m=(0.05 * item, 0.0, 1.0),
            size_m=0.001 * (1 + 0.01 * run),
            bbox=(10, 10, 20, 20),
            score=8.0,
            extras={"polarity": "dark"},
        )
        for item in range(count)
    ]


def write_archive(path: Path, runs: int, count: int, label: str = "") -> None:
    with Archive.open(path, busy_timeout_s=120) as archive:
        for vista in range(12):
            archive.add_vista(f"V{vista}")
        for run in range(runs):
            run_id = archive.start_run(seed=run, label=label)
            batch = findings_for(run, count)
            for start in range(0, count, BATCH):
                archive.add_findings(run_id, batch[start : start + BATCH])
            archive.finish_run(run_id)


def write_sqlite3(path: Path, runs: int, count: int) -> None:
    connection = sqlite3.connect(path, isolation_level=None)
    connection.execute("PRAGMA journal_mode=WAL")
    connection.execute("PRAGMA synchronous=FULL")
    connection.execute("CREATE TABLE runs (id INTEGER PRIMARY KEY, seed INTEGER, status TEXT)")
    connection.execute(
        "CREATE TABLE findings (id INTEGER PRIMARY KEY, run_id INTEGER, vista TEXT, kind TEXT,"
        " confidence REAL, x REAL, y REAL, z REAL, row0 INT, col0 INT, row1 INT, col1 INT, size_m REAL,"
        " score REAL, extras TEXT)"
    )
    for run in range(runs):
        run_id = connection.execute("INSERT INTO runs (seed, status) VALUES (?, 'running')", (run,)).lastrowid
        rows = [
            (
                run_id,
                f.vista,
                f.kind,
                f.confidence,
                *(f.position_m or ()),
                *(f.bbox or ()),
                f.size_m,
                f.score,
                json.dumps(dict(f.extras)),
            )
            for f in findings_for(run, count)
        ]
        for start in range(0, count, BATCH):
            connection.execute("BEGIN IMMEDIATE")
            connection.executemany(
                "INSERT INTO findings (run_id, vista, kind, confidence, x, y, z, row0, col0, row1, col1,"
                " size_m, score, extras) VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?)",
                rows[start : start + BATCH],
            )
            connection.execute("COMMIT")
        connection.execute("UPDATE runs SET status = 'finished' WHERE id = ?", (run_id,))
    connection.close()


def write_json(folder: Path, runs: int, count: int) -> None:
    for run in range(runs):
        document = {
            "seed": run,
            "status": "finished",
            "findings": [
                {
                    "vista": f.vista,
                    "kind": f.kind,
                    "confidence": f.confidence,
                    "position_m": f.position_m,
                    "bbox": f.bbox,
                    "size_m": f.size_m,
                    "score": f.score,
                    "extras": dict(f.extras),
                }
                for f in findings_for(run, count)
            ],
        }
        atomic_write_bytes(folder / f"run-{run}.json", json.dumps(document).encode())


def timed(action: Callable[[], object], repeats: int = 1) -> float:
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        action()
        times.append(time.perf_counter() - start)
    return statistics.median(times)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=40)
    parser.add_argument("--findings", type=int, default=200)
    options = parser.parse_args()
    runs, count = options.runs, options.findings
    total = runs * count
    with tempfile.TemporaryDirectory() as scratch:
        root = Path(scratch)
        print(f"write {runs} runs x {count} findings (batches of {BATCH}), one pass each")
        rows = []
        for name, action in (
            ("rsi Archive (history links)", lambda: write_archive(root / "rsi.db", runs, count)),
            ("plain sqlite3 executemany", lambda: write_sqlite3(root / "plain.db", runs, count)),
            ("JSON file per run", lambda: write_json(root / "json", runs, count)),
        ):
            seconds = timed(action)
            rows.append((name, seconds, total / seconds))
        for name, seconds, rate in rows:
            print(
                f"  {name:30s} {seconds:7.2f} s  {rate:9.0f} findings/s  ({rows[0][1] / seconds:5.2f}x rsi)"
            )

        with Archive.open(root / "rsi.db") as archive:
            last = archive.runs()[-1].run_id
            first_finding = archive.findings(1)[0].finding_id
            sightings = len(archive.history(first_finding).sightings)
            image = np.random.default_rng(0).random((1024, 1024), dtype=np.float32)
            reads: list[tuple[str, Callable[[], object], int]] = [
                ("open an existing archive", lambda: Archive.open(root / "rsi.db").close(), 5),
                ("runs() with finding counts", archive.runs, 5),
                (f"findings(run) ({count} findings)", lambda: archive.findings(last), 5),
                (f"history(finding) ({sightings} sightings)", lambda: archive.history(first_finding), 5),
                ("store_reference 1024^2 float32 (new)", lambda: archive.store_reference("V0", image), 1),
                ("store_reference (same image again)", lambda: archive.store_reference("V0", image), 5),
                ("reference (read, hash-checked)", lambda: archive.reference("V0"), 5),
            ]
            print(f"read back ({total} findings stored) and references (4 MB)")
            for name, action, repeats in reads:
                print(f"  {name:40s} {1e3 * timed(action, repeats):7.1f} ms")

        per_writer = max(runs // 2, 1)
        one = timed(lambda: write_archive(root / "one.db", 2 * per_writer, count))
        Archive.open(root / "two.db").close()
        context = multiprocessing.get_context("spawn")
        start = time.perf_counter()
        workers = [
            context.Process(target=write_archive, args=(root / "two.db", per_writer, count, name))
            for name in ("left", "right")
        ]
        for worker in workers:
            worker.start()
        for worker in workers:
            worker.join()
        two = time.perf_counter() - start
        with Archive.open(root / "two.db") as archive:
            stored = archive.runs()
            labels = "".join(run.label[0] for run in stored)
            assert sum(run.finding_count for run in stored) == 2 * per_writer * count
        switches = sum(a != b for a, b in itertools.pairwise(labels))
        print(f"{2 * per_writer} runs by one writer vs two writer processes (spawn start included)")
        print(f"  one writer   {one:6.2f} s")
        print(
            f"  two writers  {two:6.2f} s  ({switches} switches between writers in run order; nothing lost)"
        )


if __name__ == "__main__":
    main()
