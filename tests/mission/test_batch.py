"""Batch inspection over dask.distributed: the manifest, bad pairs skipped, the archive run, the CLI."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from typer.testing import CliRunner

from rsi.archive import Archive
from rsi.cli import EXIT_FILE, EXIT_INVALID_VALUE, EXIT_OK, app
from rsi.datasets.synthetic import synthetic_pair
from rsi.errors import DatasetError, InputError
from rsi.imaging.io import write_image
from rsi.mission import batch as batch_module
from rsi.mission.batch import (
    BatchItem,
    PairRecord,
    PairSettings,
    flaw_confidence,
    inspect_sequentially,
    read_manifest,
    run_batch,
)
from rsi.mission.batch_cluster import environment_kept
from rsi.report.batch import write_batch_report

GOOD_PAIRS = 8
BAD_PAIRS = ("missing", "corrupt")


@dataclass(frozen=True)
class Pairs:
    folder: Path
    manifest: Path
    items: tuple[BatchItem, ...]


@pytest.fixture(scope="module")
def pairs(tmp_path_factory: pytest.TempPathFactory) -> Pairs:
    """Eight tiny PNG pairs with seeded flaws, one pair whose inspection is missing, one that is corrupt."""
    folder = tmp_path_factory.mktemp("batch")
    (folder / "images").mkdir()
    lines = ["id,reference,inspection"]
    for index in range(GOOD_PAIRS):
        pair = synthetic_pair((96, 112), rng=index, flaw_spacing_px=36)
        for kind, image in (("ref", pair.reference), ("insp", pair.inspection)):
            pixels = np.clip(np.rint(image * 200.0), 0, 255).astype(np.uint8)
            write_image(folder / "images" / f"{index}_{kind}.png", pixels)
        lines.append(f"pair{index},images/{index}_ref.png,images/{index}_insp.png")
    (folder / "images" / "corrupt.png").write_bytes(b"\x89PNG\r\n\x1a\n not really a png")
    lines += ["missing,images/0_ref.png,images/gone.png", "corrupt,images/0_ref.png,images/corrupt.png"]
    manifest = folder / "pairs.csv"
    manifest.write_text("\n".join(lines) + "\n", encoding="utf-8")
    return Pairs(folder, manifest, read_manifest(manifest))


@pytest.fixture(scope="module")
def scheduler() -> Iterator[str]:
    """A two-process local cluster shared by the tests that pass `scheduler=` (closed at module end)."""
    from distributed import LocalCluster

    with (
        environment_kept(),  # the nannies' settings must not reach the processes later tests spawn
        LocalCluster(
            n_workers=2, threads_per_worker=1, processes=True, host="127.0.0.1", dashboard_address=":0"
        ) as cluster,
    ):
        yield cluster.scheduler_address


def open_archive(folder: Path) -> Archive:
    return Archive.open(folder / "archive.db")


# ------------------------------------------------------------------------------------------- manifest


def test_manifest_paths_are_relative_to_its_folder_and_ids_default_to_the_inspection(tmp_path: Path) -> None:
    elsewhere = tmp_path / "other" / "absolute.png"
    text = (
        "\ufeffReference, Inspection ,p_false_alarm,size,id\n"
        "a/r.png,a/i.png,,,\n"
        "\n"
        f'b/r.png,"{elsewhere}",1e-6,5,hinge\n'
    )
    (tmp_path / "lists").mkdir()
    manifest = tmp_path / "lists" / "m.csv"
    manifest.write_text(text, encoding="utf-8")
    first, second = read_manifest(manifest)
    assert first == BatchItem(
        "a/i.png", tmp_path / "lists" / "a/r.png", tmp_path / "lists" / "a/i.png", {}, 2
    )
    assert second.pair_id == "hinge"
    assert second.inspection == elsewhere
    assert second.settings == {"p_false_alarm": 1e-6, "size": 5}
    assert second.line == 4


MALFORMED = {
    "field count": ("reference,inspection\na.png,b.png,c.png\n", ":2: has 3 field(s) where the header has 2"),
    "empty path": ("reference,inspection\na.png, \n", ":2: the inspection path is empty"),
    "not a number": (
        "reference,inspection,p_false_alarm\na.png,b.png,often\n",
        "p_false_alarm='often' is not a float",
    ),
    "not an int": ("reference,inspection,size\na.png,b.png,3.5\n", "size='3.5' is not an int"),
    "even size": ("reference,inspection,size\na.png,b.png,4\n", ":2: size must be an odd integer"),
    "out of range": (
        "reference,inspection,p_false_alarm\na.png,b.png,0.7\n",
        "p_false_alarm must be in (0.0, 0.5)",
    ),
    "bad choice": ("reference,inspection,flaw_model\na.png,b.png,blob\n", "flaw_model='blob' is not known"),
    "repeated id": ("id,reference,inspection\nx,a.png,b.png\nx,c.png,d.png\n", ":3: id 'x' repeats line 2"),
    "unknown column": (
        "reference,inspection,p_false_alarms\na.png,b.png,1e-6\n",
        "unknown column(s) 'p_false_alarms'",
    ),
    "missing column": ("reference,inspektion\na.png,b.png\n", "no 'inspection' column"),
    "repeated column": (
        "reference,inspection,reference\na.png,b.png,c.png\n",
        "repeated column(s) 'reference'",
    ),
    "no header": ("", ":1 has no header"),
    "no pairs": ("reference,inspection\n\n", "has a header but no pairs"),
}  # fmt: skip


@pytest.mark.parametrize("case", sorted(MALFORMED))
def test_malformed_manifest_raises_naming_the_file_and_line(tmp_path: Path, case: str) -> None:
    text, expected = MALFORMED[case]
    manifest = tmp_path / "m.csv"
    manifest.write_text(text, encoding="utf-8")
    with pytest.raises(DatasetError) as raised:
        read_manifest(manifest)
    assert str(manifest) in str(raised.value)
    assert expected in str(raised.value)


def test_every_malformed_row_is_named_at_once(tmp_path: Path) -> None:
    rows = "".join(f"a{n}.png,b{n}.png,x\n" if n % 2 else f"a{n}.png,b{n}.png\n" for n in range(30))
    manifest = tmp_path / "m.csv"
    manifest.write_text("reference,inspection\n" + rows, encoding="utf-8")
    with pytest.raises(DatasetError, match=r"has 15 malformed row\(s\); nothing was run") as raised:
        read_manifest(manifest)
    message = str(raised.value)
    assert f"{manifest}:3:" in message and f"{manifest}:21:" in message
    assert "... and 5 more malformed row(s)" in message


def test_unreadable_manifest_raises(tmp_path: Path) -> None:
    with pytest.raises(DatasetError, match="cannot be read"):
        read_manifest(tmp_path / "absent.csv")
    latin = tmp_path / "latin.csv"
    latin.write_bytes("reference,inspection\nr\xe9f.png,b.png\n".encode("latin-1"))
    with pytest.raises(DatasetError, match="is not UTF-8 text"):
        read_manifest(latin)


# ------------------------------------------------------------------------------------------- the batch


def test_bad_pairs_are_reported_and_skipped_and_the_rest_are_in_the_archive(
    pairs: Pairs, tmp_path: Path
) -> None:
    calls: list[tuple[str, int, int]] = []
    environment = dict(os.environ)
    with open_archive(tmp_path) as archive:
        result = run_batch(  # the default: a local cluster of its own
            pairs.items, archive=archive, workers=2, progress=lambda *call: calls.append(call),
        )  # fmt: skip
        write_batch_report(tmp_path / "out", result, pairs.items)
        run = archive.run(result.run_id)
        stored = archive.findings(result.run_id)
    assert [record.pair_id for record in result.records] == [item.pair_id for item in pairs.items]
    assert {record.pair_id for record in result.failures} == set(BAD_PAIRS)
    by_id = {record.pair_id: record for record in result.failures}
    assert by_id["missing"].stage == by_id["corrupt"].stage == "read"
    assert "gone.png" in str(by_id["missing"].error) and "No such file" in str(by_id["missing"].error)
    assert "corrupt.png" in str(by_id["corrupt"].error) and "not a readable image" in str(
        by_id["corrupt"].error
    )
    assert result.workers == 2 and result.scheduler == "local"
    # dask's nannies write OMP_NUM_THREADS, MALLOC_TRIM_THRESHOLD_, ... into the parent's environment: the
    # caller's processes spawned later must not inherit them (rsi.mission.batch_cluster.environment_kept)
    assert dict(os.environ) == environment
    assert sorted(completed for _, completed, _ in calls) == list(range(1, len(pairs.items) + 1))
    assert {total for *_, total in calls} == {len(pairs.items)}
    # The archive: one finished run; per inspected pair a summary and its flaws, per bad pair a failure.
    assert run.status == "finished"
    assert run.settings["batch"]["pairs"] == len(pairs.items)
    kinds: dict[str, list[str]] = {}
    for finding in stored:
        kinds.setdefault(finding.vista, []).append(finding.kind)
    for record in result.records:
        if record.ok:
            assert sorted(kinds[record.pair_id]) == sorted(["inspected"] + ["flaw"] * len(record.flaws))
        else:
            assert kinds[record.pair_id] == ["failure"]
    failure = next(f for f in stored if f.vista == "missing")
    assert failure.extras["stage"] == "read" and "gone.png" in failure.extras["error"]
    assert run.finding_count == len(stored) == result.flaw_count + len(pairs.items)
    assert all(record.flaws for record in result.records if record.ok)
    # The results folder.
    summary = json.loads((tmp_path / "out" / "batch.json").read_text())
    assert summary["failures"] == 2 and summary["inspected"] == GOOD_PAIRS
    pair_rows = (tmp_path / "out" / "pairs.csv").read_text().splitlines()
    assert len(pair_rows) == 1 + len(pairs.items)
    flaw_rows = (tmp_path / "out" / "flaws.csv").read_text().splitlines()
    assert len(flaw_rows) == 1 + result.flaw_count
    # The columns are a contract (docs/batch.md); each row is its pair's flaw and that flaw's confidence.
    assert flaw_rows[0] == "pair_id,number,row,col,row0,col0,row1,col1,area_px,score,polarity,confidence"
    assert pair_rows[0] == "pair_id,status,flaws,stage,error,reference,inspection,read_s,inspect_s,worker"
    expected = [
        f"{record.pair_id},{number},{flaw.score},{confidence}"
        for record in result.records
        for number, (flaw, confidence) in enumerate(
            zip(record.flaws, record.confidences, strict=True), start=1
        )
    ]
    cells = [row.split(",") for row in flaw_rows[1:]]
    assert [f"{c[0]},{c[1]},{c[9]},{c[11]}" for c in cells] == expected


def test_batch_is_deterministic_and_equals_the_plain_loop(
    pairs: Pairs, scheduler: str, tmp_path: Path
) -> None:
    settings = PairSettings(flaw_model="uniform", p_false_alarm=1e-4)
    expected = inspect_sequentially(pairs.items, settings=settings)
    with open_archive(tmp_path) as archive:
        first = run_batch(pairs.items, archive=archive, scheduler=scheduler, settings=settings)
        second = run_batch(pairs.items, archive=archive, scheduler=scheduler, settings=settings)
        stored = [archive.findings(result.run_id) for result in (first, second)]
    assert first.records == second.records == expected
    assert first.scheduler == scheduler and first.workers == 2
    for record in first.records:
        assert len(record.confidences) == len(record.flaws)
        assert all(1.0 - 1e-4 < confidence <= 1.0 for confidence in record.confidences)

    def content(findings: Any) -> list[tuple[Any, ...]]:
        # Stored in the order pairs finish, which varies; the content does not.
        return sorted((f.vista, f.kind, f.bbox, f.score or 0.0, f.confidence) for f in findings)

    assert content(stored[0]) == content(stored[1])
    # The second batch sees the same flaws again: each is linked to its first sighting.
    assert all(finding.previous_id is not None for finding in stored[1])


def test_per_pair_overrides_apply_to_their_pair_only(pairs: Pairs, scheduler: str, tmp_path: Path) -> None:
    good = pairs.items[:2]
    strict = (
        good[0],
        BatchItem(good[1].pair_id, good[1].reference, good[1].inspection, {"p_false_alarm": 1e-9}),
    )
    with open_archive(tmp_path) as archive:
        loose = run_batch(good, archive=archive, scheduler=scheduler)
        tight = run_batch(strict, archive=archive, scheduler=scheduler)
    assert tight.records[0] == loose.records[0]
    assert tight.records[1].threshold is not None and loose.records[1].threshold is not None
    assert tight.records[1].threshold > loose.records[1].threshold


@pytest.mark.parametrize("stop", [RuntimeError("disk full"), KeyboardInterrupt()])
def test_a_stopped_driver_keeps_what_it_computed(
    pairs: Pairs, scheduler: str, tmp_path: Path, stop: BaseException
) -> None:
    def progress(pair_id: str, completed: int, total: int) -> None:
        if completed == 3:
            raise stop

    with open_archive(tmp_path) as archive:
        with pytest.raises(type(stop)):
            run_batch(pairs.items, archive=archive, scheduler=scheduler, progress=progress)
        (run,) = archive.runs()
    assert run.status == ("aborted" if isinstance(stop, KeyboardInterrupt) else "failed")
    assert run.finding_count >= 3  # the three finished pairs, each with at least its summary or failure


class _LostFuture:
    key = "lost"

    def result(self) -> PairRecord:
        raise RuntimeError("worker tcp://127.0.0.1:1 died while running this task")


def test_a_task_lost_by_the_cluster_becomes_a_failure_record(pairs: Pairs) -> None:
    record = batch_module._outcome(_LostFuture(), pairs.items[0])  # type: ignore[arg-type]
    assert record.status == "failed" and record.stage == "worker"
    assert record.error == "RuntimeError: worker tcp://127.0.0.1:1 died while running this task"


def test_inspect_item_never_raises(pairs: Pairs) -> None:
    unreadable = BatchItem("odd", pairs.items[0].reference, pairs.folder / "images" / "corrupt.png")
    assert batch_module.inspect_item(unreadable, PairSettings()).stage == "read"
    holes = pairs.folder / "holes.tif"
    write_image(holes, np.full((96, 112), np.nan, np.float32))  # reads fine, cannot be inspected
    record = batch_module.inspect_item(BatchItem("holes", pairs.items[0].reference, holes), PairSettings())
    assert record.status == "failed" and record.stage == "inspect"
    assert record.error is not None and record.error.startswith("InputError: ")


def test_confidence_is_one_minus_the_null_tail_of_the_peak_score() -> None:
    # seed §2.4: the statistic is a standard normal under the null; "both" doubles the one-sided tail.
    assert flaw_confidence(0.0, "dark") == pytest.approx(0.5)
    assert flaw_confidence(0.0, "both") == 0.0  # the two-sided tail at zero is the whole mass
    assert flaw_confidence(1.959963984540054, "both") == pytest.approx(0.95)
    assert flaw_confidence(1.6448536269514722, "bright") == pytest.approx(0.95)
    with pytest.raises(InputError, match="score must be finite"):
        flaw_confidence(float("nan"), "both")
    with pytest.raises(InputError, match="polarity='up' is not known"):
        flaw_confidence(3.0, "up")


BAD_ARGUMENTS = {
    "empty": ({"items": ()}, "items is empty"),
    "a path": ({"items": "pairs.csv"}, "Read a manifest with read_manifest"),
    "not items": ({"items": [("a.png", "b.png")]}, r"items\[0\] must be a BatchItem"),
    "repeated id": ({"items": "twice"}, r"items\[1\] repeats pair_id 'a'"),
    "workers": ({"workers": 0}, r"workers must be an integer in \[1, "),
    "settings": ({"settings": {"size": 3}}, "settings must be a PairSettings"),
    "scheduler": ({"scheduler": " "}, "scheduler must be an address"),
    "timeout": ({"connect_timeout_s": 0}, r"connect_timeout_s must be in \(0.0, 3600.0\]"),
    "unreachable": ({"scheduler": "tcp://127.0.0.1:9", "connect_timeout_s": 0.5}, "cannot be reached"),
}


@pytest.mark.parametrize("case", sorted(BAD_ARGUMENTS))
def test_bad_arguments_raise_before_anything_is_stored(pairs: Pairs, tmp_path: Path, case: str) -> None:
    overrides, message = BAD_ARGUMENTS[case]
    item = pairs.items[0]
    twice = (BatchItem("a", item.reference, item.inspection), BatchItem("a", item.reference, item.inspection))
    arguments: dict[str, Any] = {"items": pairs.items[:1], **overrides}
    if arguments["items"] == "twice":
        arguments["items"] = twice
    with open_archive(tmp_path) as archive:
        with pytest.raises(InputError, match=message):
            run_batch(archive=archive, **arguments)
        assert archive.runs() == ()


def test_waiting_for_more_workers_than_the_cluster_has_raises(
    pairs: Pairs, scheduler: str, tmp_path: Path
) -> None:
    with open_archive(tmp_path) as archive, pytest.raises(InputError, match="has 2 worker"):
        run_batch(pairs.items[:1], archive=archive, scheduler=scheduler, workers=3, connect_timeout_s=0.5)


@pytest.mark.parametrize(
    ("settings", "message"),
    [
        ({"flaw_model": "kernel"}, "flaw_model='kernel' is not known"),
        ({"size": 0}, "size must be an integer >= 1"),
        ({"polarity": "up"}, "polarity='up' is not known"),
        ({"registration_model": "rigid"}, "registration_model='rigid' is not known"),
        ({"method": "max"}, "method='max' is not known"),
        ({"noise_sigma": 0.0}, r"noise_sigma must be in \(0.0, inf\]"),
        ({"misregistration_std_px": -1.0}, r"misregistration_std_px must be in \[0.0, inf\]"),
    ],
)
def test_bad_settings_raise(settings: dict[str, Any], message: str) -> None:
    with pytest.raises(InputError, match=message):
        PairSettings(**settings)


def test_bad_batch_items_raise(tmp_path: Path) -> None:
    with pytest.raises(InputError, match="pair_id must be a non-empty string"):
        BatchItem(" ", tmp_path / "r.png", tmp_path / "i.png")
    with pytest.raises(InputError, match="unknown setting"):
        BatchItem("a", tmp_path / "r.png", tmp_path / "i.png", {"threshold": 3.0})


def test_setting_choices_follow_the_library() -> None:
    from rsi.detection.flaw_models import FLAW_MODELS
    from rsi.detection.roc import METHODS, POLARITIES
    from rsi.imaging.registration import MODELS

    # "kernel" needs an array, which a CSV cell cannot hold.
    assert tuple(model for model in FLAW_MODELS if model != "kernel") == batch_module.FLAW_MODELS
    assert batch_module.POLARITIES == POLARITIES
    assert batch_module.METHODS == METHODS
    assert batch_module.REGISTRATION_MODELS == MODELS


def test_importing_batch_loads_neither_dask_nor_opencv() -> None:
    heavy = "{'dask', 'distributed', 'cv2', 'sqlalchemy'}"
    code = f"import sys, rsi.mission.batch; print(sorted({heavy} & set(sys.modules)))"
    result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=False)
    assert result.returncode == 0, result.stderr
    assert result.stdout.strip() == "[]"


# ------------------------------------------------------------------------------------------- the command

runner = CliRunner()


def test_cli_batch_json_last_line(pairs: Pairs, scheduler: str, tmp_path: Path) -> None:
    archive = tmp_path / "runs.db"
    arguments = ["batch", str(pairs.manifest), "--out", str(tmp_path / "out"), "--archive", str(archive),
                 "--scheduler", scheduler, "--flaw-model", "uniform"]  # fmt: skip
    result = runner.invoke(app, [*arguments, "--json"])
    assert result.exit_code == EXIT_OK, result.output
    document = json.loads(result.stdout.strip().splitlines()[-1])
    assert document["pairs"] == len(pairs.items) and document["failures"] == 2
    assert document["inspected"] == GOOD_PAIRS and document["flaws"] > 0 and document["pairs_per_s"] > 0
    assert {failure["pair_id"] for failure in document["failed"]} == set(BAD_PAIRS)
    assert Path(document["files"]["batch.json"]).exists()
    with Archive.open(archive, create=False) as store:
        assert store.run(document["run_id"]).settings["batch"]["settings"]["flaw_model"] == "uniform"
    table = runner.invoke(app, arguments)
    assert table.exit_code == EXIT_OK, table.output
    text = " ".join(table.stdout.split())
    assert f"{len(pairs.items)} pairs done: {GOOD_PAIRS} inspected, 2 failed" in text
    assert "2 pair(s) skipped" in text and "pairs/s" in text


def test_cli_batch_exit_codes(pairs: Pairs, tmp_path: Path) -> None:
    out = ["--out", str(tmp_path / "out"), "--archive", str(tmp_path / "a.db")]
    malformed = tmp_path / "bad.csv"
    malformed.write_text("reference,inspection\na.png\n", encoding="utf-8")
    result = runner.invoke(app, ["batch", str(malformed), *out])
    assert result.exit_code == EXIT_FILE
    assert f"{malformed}:2: has 1 field(s)" in " ".join(result.stderr.split())
    missing = runner.invoke(app, ["batch", str(tmp_path / "none.csv"), *out])
    assert missing.exit_code == EXIT_FILE
    invalid = runner.invoke(app, ["batch", str(pairs.manifest), *out, "--p-false-alarm", "0.7"])
    assert invalid.exit_code == EXIT_INVALID_VALUE
    assert "p_false_alarm must be in (0.0, 0.5)" in invalid.stderr
    assert not (tmp_path / "a.db").exists()  # nothing was stored
