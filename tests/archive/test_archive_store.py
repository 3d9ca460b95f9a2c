"""The archive's API: vistas, content-addressed images, references, runs, findings, flaw history, export."""

from __future__ import annotations

import json
from collections.abc import Iterator
from datetime import datetime, timedelta, timezone
from pathlib import Path
from typing import Any

import cv2
import numpy as np
import pytest
from sqlalchemy import event

from rsi.archive import SCHEMA_VERSION, Archive, ArchiveFileError, Finding, FlawHistory, VistaPoint
from rsi.detection.detect import Flaw
from rsi.errors import InputError
from rsi.sim.mockup import Vista

T0 = datetime(2030, 1, 1, tzinfo=timezone.utc)
DAY = timedelta(days=1)


@pytest.fixture
def archive(tmp_path: Path) -> Iterator[Archive]:
    with Archive.open(tmp_path / "archive.db") as opened:
        opened.add_vista("A_door")
        opened.add_vista("B_panel")
        yield opened


def png(value: int) -> bytes:
    ok, encoded = cv2.imencode(".png", np.full((8, 8), value, np.uint8))
    assert ok
    return encoded.tobytes()


def impact(x_m: float, size_m: float, vista: str = "A_door", kind: str = "impact") -> Finding:
    return Finding(vista, kind, 0.9, position_m=(x_m, 0.2, 1.0), size_m=size_m)


def finished_run(archive: Archive, findings: list[Finding], started_at: datetime) -> tuple[int, list[int]]:
    run_id = archive.start_run(started_at=started_at)
    stored = archive.add_findings(run_id, findings)
    archive.finish_run(run_id, finished_at=started_at + timedelta(hours=1))
    return run_id, [finding.finding_id for finding in stored]


# ---------------------------------------------------------------------- opening


def test_open_creates_an_archive_and_reopens_it_with_its_contents(tmp_path: Path) -> None:
    path = tmp_path / "nested" / "archive.db"
    with Archive.open(path) as archive:
        assert archive.schema_version == SCHEMA_VERSION
        assert archive.location == str(path)
        assert archive.images_dir == tmp_path / "nested" / "archive.db.images"
        archive.add_vista("A_door")
        run_id = archive.start_run(seed=3, settings={"p_false_alarm": 1e-4}, label="reference pass")
        assert f"schema_version={SCHEMA_VERSION}" in repr(archive)
    with Archive.open(str(path), create=False) as again:
        run = again.run(run_id)
        assert (run.status, run.seed, run.label) == ("running", 3, "reference pass")
        assert run.settings == {"p_false_alarm": 1e-4}
        assert run.finished_at is None
        assert again.vistas() == (VistaPoint("A_door"),)


def test_open_takes_a_sqlalchemy_url_and_an_in_memory_database(tmp_path: Path) -> None:
    with Archive.open(f"sqlite:///{tmp_path / 'by-url.db'}") as archive:
        assert archive.location == str(tmp_path / "by-url.db")
    with Archive.open("sqlite://", images_dir=tmp_path / "images") as memory:
        memory.add_vista("A_door")
        digest = memory.store_reference("A_door", png(7))
        assert memory.reference("A_door") == png(7)
        assert (tmp_path / "images" / digest[:2] / digest).exists()


def test_open_rejects_bad_locations_naming_them(tmp_path: Path) -> None:
    with pytest.raises(InputError, match=r"there is no archive at .*missing.db"):
        Archive.open(tmp_path / "missing.db", create=False)
    assert not (tmp_path / "missing.db").exists()
    with pytest.raises(InputError, match=r"is a folder"):
        Archive.open(tmp_path)
    (tmp_path / "plain").write_text("x")
    with pytest.raises(InputError, match=r"plain is a file, not a folder"):
        Archive.open(tmp_path / "plain" / "archive.db")
    with pytest.raises(InputError, match=r"url_or_path must be a file path or a SQLAlchemy URL"):
        Archive.open(3)  # type: ignore[arg-type]
    with pytest.raises(InputError, match=r"url_or_path must be"):
        Archive.open("")
    with pytest.raises(InputError, match=r"is not a database URL"):
        Archive.open("not a url://x")
    with pytest.raises(InputError, match=r"images_dir is needed .*postgresql://rsi:\*\*\*@host/rsi"):
        Archive.open("postgresql://rsi:secret@host/rsi")
    with pytest.raises(InputError, match=r"busy_timeout_s"):
        Archive.open(tmp_path / "a.db", busy_timeout_s=-1)


# ---------------------------------------------------------------------- vistas


def test_vistas_store_a_simulator_pose_once_and_move_only_when_asked(archive: Archive) -> None:
    vista = Vista("C_tank", (1.0, 0.0, 1.2), (1.0, -0.5, 1.2), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0), 0.5)
    record = archive.add_vista(vista)
    assert record == VistaPoint(
        "C_tank", (1.0, -0.5, 1.2), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0), (1.0, 0.0, 1.2), 0.5
    )
    assert archive.add_vista(vista) == record
    assert archive.vista("C_tank") == record
    moved = VistaPoint("C_tank", (1.0, -0.6, 1.2), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0), (1.0, 0.0, 1.2), 0.6)
    with pytest.raises(InputError, match=r"'C_tank' is already stored with another pose.*replace=True"):
        archive.add_vista(moved)
    assert archive.add_vista(moved, replace=True) == moved
    assert [point.name for point in archive.vistas()] == ["A_door", "B_panel", "C_tank"]
    assert archive.vista("C_tank") == moved


def test_vistas_reject_bad_input_naming_it(archive: Archive) -> None:
    with pytest.raises(InputError, match=r"partial pose"):
        VistaPoint("X", position_m=(0.0, 0.0, 1.0))
    with pytest.raises(InputError, match=r"vista name must be a non-empty string"):
        VistaPoint(" ")
    with pytest.raises(InputError, match=r"forward must be three finite numbers"):
        VistaPoint("X", (0.0, 0.0, 1.0), (0.0, 1.0), (0.0, 0.0, 1.0), (0.0, 0.0, 0.0), 1.0)  # type: ignore[arg-type]
    with pytest.raises(InputError, match=r"standoff_m must be in"):
        VistaPoint("X", (0.0, 0.0, 1.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0), (0.0, 0.0, 0.0), -1.0)
    with pytest.raises(InputError, match=r"object has no 'name'"):
        archive.add_vista(object())  # type: ignore[arg-type]
    with pytest.raises(InputError, match=r"vista 'nowhere' is not in the archive .*Archive.add_vista"):
        archive.vista("nowhere")


# ---------------------------------------------------------------------- images and references


def test_images_are_content_addressed_and_stored_once(archive: Archive) -> None:
    first = archive.store_image(png(10))
    assert archive.store_image(png(10)) == first
    files = [path for path in archive.images_dir.rglob("*") if path.is_file()]
    assert [path.name for path in files] == [first]
    assert archive.image(first) == png(10)
    array = np.arange(12, dtype=np.uint16).reshape(3, 4)
    digest = archive.store_image(array)
    assert archive.store_image(np.asfortranarray(array)) == digest  # same pixels, same file
    restored = archive.image(digest)
    assert isinstance(restored, np.ndarray)
    assert restored.dtype == np.uint16
    np.testing.assert_array_equal(restored, array)
    assert not list(archive.images_dir.rglob("*.tmp"))


def test_images_reject_what_cannot_be_stored(archive: Archive) -> None:
    with pytest.raises(InputError, match=r"image is empty \(0 bytes\)"):
        archive.store_image(b"")
    with pytest.raises(InputError, match=r"non-empty numeric or bool array; got dtype=object"):
        archive.store_image(np.array([None, 1]))
    with pytest.raises(InputError, match=r"got dtype=float64, shape \(0,\)"):
        archive.store_image(np.zeros(0))
    with pytest.raises(InputError, match=r"bytes .* or a numpy array; got str"):
        archive.store_image("picture.png")  # type: ignore[arg-type]
    with pytest.raises(InputError, match=r"no image with sha256="):
        archive.image("0" * 64)
    with pytest.raises(InputError, match=r"sha256 must be a SHA-256 as 64 lower-case hex digits"):
        archive.image("abc")


def test_a_damaged_or_missing_image_file_is_named_and_storing_again_repairs_it(archive: Archive) -> None:
    digest = archive.store_image(png(20))
    path = archive.images_dir / digest[:2] / digest
    path.write_bytes(b"\x89PNG\r\n\x1a\n damaged")
    with pytest.raises(ArchiveFileError, match=f"image file {path} is damaged"):
        archive.image(digest)
    assert archive.store_image(png(20)) == digest
    assert archive.image(digest) == png(20)
    path.unlink()
    with pytest.raises(ArchiveFileError, match=f"image file {path} is missing"):
        archive.image(digest)


def test_references_the_latest_wins_and_a_missing_one_names_the_vista(archive: Archive) -> None:
    with pytest.raises(InputError, match=r"vista 'A_door' has no reference image .*reference pass"):
        archive.reference("A_door")
    with pytest.raises(InputError, match=r"vista 'C_nowhere' is not in the archive"):
        archive.store_reference("C_nowhere", png(1))
    old = archive.store_reference("A_door", png(1))
    new = archive.store_reference("A_door", np.eye(4, dtype=np.float32))
    info = archive.reference_info("A_door")
    assert (info.sha256, info.media, info.vista) == (new, "npy", "A_door")
    assert info.path.read_bytes()[:6] == b"\x93NUMPY"
    assert info.size_bytes == info.path.stat().st_size
    np.testing.assert_array_equal(archive.reference("A_door"), np.eye(4))
    assert archive.image(old) == png(1)  # earlier references stay stored


# ---------------------------------------------------------------------- runs


def test_runs_go_from_running_to_an_end_status_once(archive: Archive) -> None:
    first = archive.start_run(seed=np.int64(5))
    second = archive.start_run()
    done = archive.finish_run(first)
    assert (done.status, done.seed) == ("finished", 5)
    assert done.finished_at is not None
    assert done.finished_at >= done.started_at
    assert archive.finish_run(second, "failed").status == "failed"
    assert [run.run_id for run in archive.runs()] == [first, second]
    assert [run.run_id for run in archive.runs(status="failed")] == [second]
    with pytest.raises(InputError, match=r"run 1 is already finished"):
        archive.finish_run(first)
    with pytest.raises(InputError, match=r"run 1 is already finished.*start_run"):
        archive.add_findings(first, [impact(0.1, 0.001)])


def test_runs_reject_bad_input_naming_it(archive: Archive) -> None:
    with pytest.raises(InputError, match=r"seed must be None or an integer"):
        archive.start_run(seed=-1)
    with pytest.raises(InputError, match=r"seed must be None or an integer"):
        archive.start_run(seed=True)
    with pytest.raises(InputError, match=r"settings must hold only JSON values"):
        archive.start_run(settings={"image": np.zeros(2)})
    with pytest.raises(InputError, match=r"settings must be a mapping with string keys"):
        archive.start_run(settings={1: "x"})  # type: ignore[dict-item]
    with pytest.raises(InputError, match=r"label must be a string"):
        archive.start_run(label=7)  # type: ignore[arg-type]
    with pytest.raises(InputError, match=r"started_at must be a time-zone-aware datetime"):
        archive.start_run(started_at=datetime(2030, 1, 1))
    run_id = archive.start_run()
    with pytest.raises(InputError, match=r"status='done' is not known. Choose one of 'finished'"):
        archive.finish_run(run_id, "done")
    with pytest.raises(InputError, match=r"status='done' is not known"):
        archive.runs(status="done")
    with pytest.raises(InputError, match=r"run 99 is not in the archive"):
        archive.run(99)
    with pytest.raises(InputError, match=r"run_id must be an integer"):
        archive.findings("1")  # type: ignore[arg-type]
    assert archive.runs(status="running")[0].run_id == run_id  # nothing was stored by the failures
    assert len(archive.runs()) == 1


# ---------------------------------------------------------------------- findings


def test_findings_round_trip_with_their_reference_and_images(archive: Archive) -> None:
    reference = archive.store_reference("A_door", png(3))
    inspection = archive.store_image(png(4))
    flaw = Flaw(row=10.5, col=20.0, bbox=(8, 18, 13, 23), area_px=19, score=7.5, polarity="dark")
    run_id = archive.start_run()
    stored = archive.add_findings(
        run_id,
        [
            Finding.from_flaw(flaw, vista="A_door", confidence=0.8, inspection_sha256=inspection),
            Finding("B_panel", "hot_spot", 1.0, position_m=(0.5, 0.0, 1.5), extras={"temperature_k": 390.0}),
        ],
    )
    assert archive.findings(run_id) == stored
    door, panel = stored
    assert door.bbox == (8, 18, 13, 23)
    assert (door.area_px, door.score, door.kind) == (19, 7.5, "flaw")
    assert door.extras == {"row": 10.5, "col": 20.0, "polarity": "dark"}
    assert (door.reference_sha256, door.inspection_sha256) == (reference, inspection)
    assert panel.reference_sha256 is None
    assert panel.extras == {"temperature_k": 390.0}
    assert archive.finding(panel.finding_id) == panel
    assert archive.run(run_id).finding_count == 2


def test_findings_reject_bad_fields_naming_them() -> None:
    with pytest.raises(InputError, match=r"has neither position_m nor bbox"):
        Finding("A_door", "impact", 0.5)
    with pytest.raises(InputError, match=r"confidence must be in \[0, 1\]"):
        Finding("A_door", "impact", 1.5, position_m=(0.0, 0.0, 0.0))
    with pytest.raises(InputError, match=r"position_m must be three finite numbers"):
        Finding("A_door", "impact", 0.5, position_m="here")  # type: ignore[arg-type]
    with pytest.raises(InputError, match=r"must be finite"):
        Finding("A_door", "impact", 0.5, position_m=(0.0, np.nan, 0.0))
    with pytest.raises(InputError, match=r"bbox must be half-open"):
        Finding("A_door", "impact", 0.5, bbox=(5, 5, 5, 9))
    with pytest.raises(InputError, match=r"bbox must be .* four integers"):
        Finding("A_door", "impact", 0.5, bbox=(1.0, 2, 3, 4))  # type: ignore[arg-type]
    with pytest.raises(InputError, match=r"bbox must be .* four integers"):
        Finding("A_door", "impact", 0.5, bbox=(1, 2, 3))  # type: ignore[arg-type]
    with pytest.raises(InputError, match=r"size_m must be in"):
        Finding("A_door", "impact", 0.5, bbox=(1, 2, 3, 4), size_m=-0.1)
    with pytest.raises(InputError, match=r"area_px must be an integer"):
        Finding("A_door", "impact", 0.5, bbox=(1, 2, 3, 4), area_px=2.5)  # type: ignore[arg-type]
    with pytest.raises(InputError, match=r"score must be finite"):
        Finding("A_door", "impact", 0.5, bbox=(1, 2, 3, 4), score=np.inf)
    with pytest.raises(InputError, match=r"inspection_sha256 must be a SHA-256"):
        Finding("A_door", "impact", 0.5, bbox=(1, 2, 3, 4), inspection_sha256="x")
    with pytest.raises(InputError, match=r"extras must hold only JSON values"):
        Finding("A_door", "impact", 0.5, bbox=(1, 2, 3, 4), extras={"t": np.float32(1)})
    with pytest.raises(InputError, match=r"kind must be a non-empty string"):
        Finding("A_door", "", 0.5, bbox=(1, 2, 3, 4))


def test_a_bad_batch_stores_nothing(archive: Archive) -> None:
    run_id = archive.start_run()
    good = impact(0.1, 0.001)
    with pytest.raises(InputError, match=r"vista 'Z_unknown' is not in the archive"):
        archive.add_findings(run_id, [good, impact(0.1, 0.001, vista="Z_unknown")])
    with pytest.raises(InputError, match=r"findings name images not in the archive .*: " + "a" * 64):
        archive.add_findings(
            run_id, [Finding("A_door", "impact", 0.5, bbox=(1, 2, 3, 4), reference_sha256="a" * 64)]
        )
    with pytest.raises(InputError, match=r"findings\[1\] must be an rsi.archive.Finding; got dict"):
        archive.add_findings(run_id, [good, {"vista": "A_door"}])  # type: ignore[list-item]
    with pytest.raises(InputError, match=r"tolerance_m must be in"):
        archive.add_findings(run_id, [good], tolerance_m=-1)
    with pytest.raises(InputError, match=r"finding 42 is not in the archive"):
        archive.finding(42)
    with pytest.raises(InputError, match=r"finding_id must be an integer"):
        archive.history("1")  # type: ignore[arg-type]
    assert archive.findings(run_id) == ()


def test_a_failure_after_the_rows_are_written_rolls_the_whole_batch_back(archive: Archive) -> None:
    run_id = archive.start_run()

    def interrupt(_connection: Any, _cursor: Any, statement: str, *_args: Any) -> None:
        if statement.startswith("INSERT INTO findings"):
            raise KeyboardInterrupt  # e.g. the operator's Ctrl-C between the INSERT and the COMMIT

    engine = archive._engine
    event.listen(engine, "after_cursor_execute", interrupt)
    with pytest.raises(KeyboardInterrupt):
        archive.add_findings(run_id, [impact(0.1 * i, 0.001) for i in range(5)])
    event.remove(engine, "after_cursor_execute", interrupt)
    assert archive.findings(run_id) == ()
    assert len(archive.add_findings(run_id, [impact(0.1 * i, 0.001) for i in range(5)])) == 5
    assert archive.add_findings(run_id, []) == ()


# ---------------------------------------------------------------------- flaw history


def test_a_flaw_seen_again_is_linked_and_its_growth_is_tracked(archive: Archive) -> None:
    _, (first, other) = finished_run(archive, [impact(0.100, 0.0010), impact(0.300, 0.0020)], T0)
    _, (second, _) = finished_run(
        archive, [impact(0.102, 0.0015), impact(0.300, 0.0020, kind="dent")], T0 + DAY
    )
    _, (third,) = finished_run(archive, [impact(0.099, 0.0030)], T0 + 3 * DAY)
    history = archive.history(third)
    assert [sighting.finding_id for sighting in history.sightings] == [first, second, third]
    assert archive.history(first) == history
    assert history.track_id == first
    assert archive.finding(third).previous_id == second
    assert history.seen_at == (T0, T0 + DAY, T0 + 3 * DAY)
    assert history.sizes_m == (0.0010, 0.0015, 0.0030)
    assert history.growth_m == pytest.approx(0.0020)
    assert history.growth_rate_m_s == pytest.approx(0.0020 / (3 * 86400))
    # The other impact was not seen again; the same place with another kind is another flaw.
    assert [sighting.finding_id for sighting in archive.history(other).sightings] == [other]
    single = archive.history(other)
    assert (single.growth_m, single.growth_rate_m_s) == (None, None)


def test_history_links_only_within_tolerance_and_to_finished_earlier_runs(archive: Archive) -> None:
    _, (first,) = finished_run(archive, [impact(0.100, 0.001)], T0)
    _, (far,) = finished_run(archive, [impact(0.110, 0.001)], T0 + DAY)  # 10 mm away: another flaw
    assert archive.finding(far).previous_id is None
    unfinished = archive.start_run(started_at=T0 + 2 * DAY)
    (pending,) = archive.add_findings(unfinished, [impact(0.200, 0.001)])
    _, (after_crash,) = finished_run(archive, [impact(0.200, 0.001)], T0 + 3 * DAY)
    assert archive.finding(after_crash).previous_id is None  # a run that never finished is no history
    _, (replayed,) = finished_run(archive, [impact(0.101, 0.001)], T0 - DAY)  # started before the others
    assert archive.finding(replayed).previous_id is None
    _, (wider,) = finished_run(archive, [impact(0.109, 0.002)], T0 + 4 * DAY)
    assert archive.finding(wider).previous_id == far  # the latest earlier run wins
    assert pending.previous_id is None
    assert archive.history(first).sightings[0].finding_id == first


def test_history_matches_image_findings_by_bbox_centre(archive: Archive) -> None:
    def box(row: int, size_px: int) -> Finding:
        return Finding(
            "B_panel", "flaw", 0.7, bbox=(row, 40, row + size_px, 40 + size_px), area_px=size_px**2
        )

    _, (first,) = finished_run(archive, [box(20, 4)], T0)
    _, (second,) = finished_run(archive, [box(21, 6)], T0 + DAY)  # centre moved 2 px: the same flaw
    _, (third,) = finished_run(archive, [box(40, 6)], T0 + 2 * DAY)
    assert archive.finding(second).previous_id == first
    assert archive.finding(third).previous_id is None
    assert [sighting.area_px for sighting in archive.history(second).sightings] == [16, 36]
    assert archive.history(second).growth_m is None  # no physical size measured
    assert isinstance(archive.history(second), FlawHistory)


# ---------------------------------------------------------------------- export


def test_export_writes_the_run_and_its_images_atomically(archive: Archive, tmp_path: Path) -> None:
    reference = archive.store_reference("A_door", png(30))
    inspection = archive.store_image(np.ones((4, 4), np.float32))
    run_id, _ = finished_run(
        archive,
        [
            Finding("A_door", "flaw", 0.6, bbox=(1, 1, 3, 3), inspection_sha256=inspection),
            impact(0.1, 0.002, vista="B_panel"),
        ],
        T0,
    )
    out = tmp_path / "export"
    written = archive.export_run(run_id, out)
    assert written == out / f"run-{run_id}.json"
    document = json.loads(written.read_text())
    assert document["run"]["status"] == "finished"
    assert document["run"]["started_at"] == T0.isoformat()
    assert [finding["kind"] for finding in document["findings"]] == ["flaw", "impact"]
    assert [vista["name"] for vista in document["vistas"]] == ["A_door", "B_panel"]
    assert document["images"] == {
        reference: f"images/{reference}.png",
        inspection: f"images/{inspection}.npy",
    }
    assert (out / document["images"][reference]).read_bytes() == png(30)
    np.testing.assert_array_equal(np.load(out / document["images"][inspection]), np.ones((4, 4)))
    assert not list(out.rglob("*.tmp"))
    assert archive.export_run(run_id, out) == written  # again over the same folder
    with pytest.raises(InputError, match=r"out_dir=.* is a file"):
        archive.export_run(run_id, written)
    with pytest.raises(InputError, match=r"run 77 is not in the archive"):
        archive.export_run(77, out)
