"""A writer process for the crash and concurrency tests: runs, each with findings in several transactions.

Usage: python writer.py ARCHIVE NAME RUNS BATCHES PER_BATCH [PAUSE_IN]
Prints "started RUN" and "batch RUN K" (flushed) after each commit, so a test knows where the writer is. With
PAUSE_IN it prints "inside" and sleeps right after writing its PAUSE_IN-th batch of findings: inside the open
transaction, the rows written but not committed. With the environment variable GO_FILE set, it waits for
that file to exist before its first run, so two writers start writing together.
"""

from __future__ import annotations

import os
import sys
import time
from typing import Any

import numpy as np
from sqlalchemy import event

from rsi.archive import Archive, Finding

VISTAS = ("A_door", "B_panel", "C_tubing")


def pause_in(archive: Archive, batch: int) -> None:
    """Stop the writer right after the INSERT of its `batch`-th batch of findings (1-based), before COMMIT."""
    inserts = [0]

    def after_execute(_connection: Any, _cursor: Any, statement: str, *_args: Any) -> None:
        if statement.startswith("INSERT INTO findings"):
            inserts[0] += 1
            if inserts[0] == batch:
                print("inside", flush=True)
                time.sleep(60)

    event.listen(archive._engine, "after_cursor_execute", after_execute)


def main(path: str, name: str, runs: int, batches: int, per_batch: int, *, pause: int | None) -> None:
    with Archive.open(path, busy_timeout_s=60.0) as archive:
        if pause is not None:
            pause_in(archive, pause)
        for vista in VISTAS:
            archive.add_vista(vista)
            # Both writers store the same reference: one file, written atomically by whichever comes first.
            archive.store_reference(vista, np.full((16, 16), VISTAS.index(vista), np.float32))
        go_file = os.environ.get("GO_FILE")
        while go_file is not None and not os.path.exists(go_file):
            time.sleep(0.005)
        for index in range(runs):
            run_id = archive.start_run(label=f"{name} {index}", seed=index, settings={"writer": name})
            print(f"started {run_id}", flush=True)
            for batch in range(batches):
                findings = [
                    Finding(
                        VISTAS[item % len(VISTAS)],
                        "impact",
                        0.9,
                        position_m=(0.1 * item, 0.01 * batch, 1.0),
                        size_m=0.001 * (1 + index),
                        extras={"writer": name, "batch": batch},
                    )
                    for item in range(per_batch)
                ]
                archive.add_findings(run_id, findings)
                print(f"batch {run_id} {batch}", flush=True)
            archive.finish_run(run_id)


if __name__ == "__main__":
    runs, batches, per_batch = (int(value) for value in sys.argv[3:6])
    pause = int(sys.argv[6]) if len(sys.argv) > 6 else None
    main(sys.argv[1], sys.argv[2], runs, batches, per_batch, pause=pause)
