"""Time ``rsi.mission.batch.run_batch`` (dask.distributed, local worker processes) against a plain loop.

Makes N synthetic 640x640 8-bit PNG pairs in a temporary folder (or ``--data DIR``, kept for re-runs) and
inspects them three ways, each with the same settings (single-pixel model, P_F = 1e-5):

- the plain sequential loop on one core a user would write instead (read, ``inspect_pair``, keep the flaws;
  no archive, no cluster);
- ``run_batch`` with 1 worker process, and with 2 worker processes (this machine's core count), each
  storing every pair in a fresh SQLite archive and counting the cluster's start-up in its time.

Pairs: 20 textured scenes (``rsi.datasets.synthetic.synthetic_pair``, each its own sub-pixel shift and
photometry), and per pair a fresh flaw pattern (9 dark 3x3 flaws, jittered grid) and fresh sensor noise,
so no two pairs share pixels. Generating a scene costs ~0.2 s; 1,000 scenes would dominate the benchmark.

Run: ``.venv/bin/python benchmarks/bench_batch.py [--pairs 1000] [--workers 1 2]``.
"""

from __future__ import annotations

import os

for _variable in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ[_variable] = "1"

import argparse
import statistics
import tempfile
import time
from pathlib import Path

import cv2
import numpy as np

from rsi.archive import Archive
from rsi.datasets.synthetic import flaw_pattern, synthetic_pair
from rsi.mission.batch import BatchItem, inspect_sequentially, read_manifest, run_batch

SIDE_PX = 640
SCENES = 20
NOISE_SIGMA = 2 / 255
FLAW_SPACING_PX = 213  # a 3x3 grid of flaws per 640x640 pair
FLAW_STRENGTH = 0.15


def make_pairs(folder: Path, count: int, *, seed: int = 0) -> Path:
    """Write `count` PNG pairs and their manifest to `folder` (reused when the manifest is already there)."""
    manifest = folder / f"manifest_{count}.csv"
    if manifest.exists():
        return manifest
    folder.mkdir(parents=True, exist_ok=True)
    rng = np.random.default_rng(seed)
    scenes = [
        synthetic_pair(
            (SIDE_PX, SIDE_PX),
            shift_xy=(float(rng.uniform(-6, 6)), float(rng.uniform(-6, 6))),
            gain=float(rng.uniform(0.9, 1.1)),
            noise_sigma=0.0,
            flaw_strength=0.0,
            rng=rng,
        )
        for _ in range(SCENES)
    ]
    lines = ["id,reference,inspection"]
    shape = (SIDE_PX, SIDE_PX)
    for index in range(count):
        scene = scenes[index % SCENES]
        flaws = flaw_pattern(shape, size_px=3, spacing_px=FLAW_SPACING_PX, strength=FLAW_STRENGTH,
                             polarity="dark", rng=rng)  # fmt: skip
        reference = scene.reference + NOISE_SIGMA * rng.standard_normal(shape)
        inspection = scene.inspection + flaws.signal + NOISE_SIGMA * rng.standard_normal(shape)
        # 0.8 keeps the gain-scaled texture inside 8 bits.
        for name, image in ((f"{index:05d}_ref.png", reference), (f"{index:05d}_insp.png", inspection)):
            cv2.imwrite(str(folder / name), np.clip(np.rint(0.8 * 255 * image), 0, 255).astype(np.uint8))
        lines.append(f"pair{index:05d},{index:05d}_ref.png,{index:05d}_insp.png")
    manifest.write_text("\n".join(lines) + "\n", encoding="utf-8")
    return manifest


def time_sequential(items: tuple[BatchItem, ...]) -> tuple[float, int]:
    cv2.setNumThreads(1)
    start_s = time.perf_counter()
    records = inspect_sequentially(items)
    elapsed_s = time.perf_counter() - start_s
    assert all(record.ok for record in records), [record.error for record in records if not record.ok][:3]
    return elapsed_s, sum(len(record.flaws) for record in records)


def time_batch(items: tuple[BatchItem, ...], workers: int, folder: Path) -> tuple[float, float, int, float]:
    with Archive.open(folder / f"archive_{workers}.db") as archive:
        result = run_batch(items, archive=archive, workers=workers)
        stored = archive.run(result.run_id).finding_count
    assert not result.failures, result.failures[:3]
    assert stored == result.flaw_count + len(items), (stored, result.flaw_count)
    mean_pair_s = statistics.fmean(record.read_s + record.inspect_s for record in result.records)
    return result.elapsed_s, result.startup_s, result.flaw_count, mean_pair_s


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--pairs", type=int, default=1000)
    parser.add_argument("--workers", type=int, nargs="+", default=[1, 2])
    parser.add_argument("--data", type=Path, default=None, help="keep the generated pairs here")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as scratch:
        folder = args.data or Path(scratch)
        start_s = time.perf_counter()
        items = read_manifest(make_pairs(folder, args.pairs))
        print(f"{len(items)} pairs of {SIDE_PX}x{SIDE_PX} ready in {time.perf_counter() - start_s:.1f} s "
              f"({os.cpu_count()} CPUs)")  # fmt: skip
        sequential_s, flaws = time_sequential(items)
        rows = [("plain loop, 1 core, no archive", sequential_s, 0.0, flaws)]
        for workers in args.workers:
            elapsed_s, startup_s, batch_flaws, mean_pair_s = time_batch(items, workers, Path(scratch))
            assert batch_flaws == flaws, (batch_flaws, flaws)
            rows.append((f"run_batch, {workers} worker(s), archive", elapsed_s, startup_s, batch_flaws))
            print(f"  {workers} worker(s): mean read+inspect per pair {1e3 * mean_pair_s:.1f} ms")
    print()
    print("| method | time s | cluster start s | pairs/s | vs plain loop | vs 1 worker | flaws |")
    print("| --- | --- | --- | --- | --- | --- | --- |")
    one_worker_s = next((row[1] for row in rows if "1 worker" in row[0]), None)
    for label, elapsed_s, startup_s, found in rows:
        versus_worker = f"{one_worker_s / elapsed_s:.2f}x" if one_worker_s and "run_batch" in label else ""
        print(f"| {label} | {elapsed_s:.1f} | {startup_s:.1f} | {len(items) / elapsed_s:.1f} | "
              f"{sequential_s / elapsed_s:.2f}x | {versus_worker} | {found} |")  # fmt: skip


if __name__ == "__main__":
    main()
