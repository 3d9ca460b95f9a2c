"""One test (or a few) per defect class of issue 17, each on the case the hostile run found."""

from __future__ import annotations

import os
import shutil
import socket
import sqlite3
import struct
import threading
import time
import zlib
from collections.abc import Iterator
from pathlib import Path

import cv2
import numpy as np
import pytest
import scipy.ndimage as ndi
from typer.testing import CliRunner

from rsi import _validate as v
from rsi._files import read_regular_file, writable_folder
from rsi.archive import Archive, ArchiveError, ArchiveFileError, Finding
from rsi.cli import EXIT_FILE, EXIT_INTERNAL, EXIT_INVALID_VALUE, app
from rsi.control.redundancy import limit_avoidance_velocity
from rsi.detection.detect import detect
from rsi.detection.flaw_models import flaw_kernel
from rsi.detection.pair import score_flaws
from rsi.detection.roc import thresholds
from rsi.errors import DatasetError, FileError, ImageFileError, InputError
from rsi.imaging.camera import expose
from rsi.imaging.compensation import compensate_interlaced
from rsi.imaging.io import MAX_IMAGE_PIXELS_ENV, max_image_pixels, read_image, write_image
from rsi.imaging.registration import register
from rsi.mission.batch import (
    BatchItem,
    PairSettings,
    inspect_item,
    max_local_workers,
    read_manifest,
    run_batch,
)
from rsi.sensors.lamps import LampController, simulate_lamp
from rsi.sensors.proximity import read_proximity
from rsi.sensors.pyrometer import Pyrometer, invert_band_radiance_k, read_pyrometer

runner = CliRunner()
TEXTURE = ndi.gaussian_filter(np.random.default_rng(0).random((64, 64)), 2.0) * 255.0


def png_claiming(cols: int, rows: int) -> bytes:
    def chunk(kind: bytes, body: bytes) -> bytes:
        return struct.pack(">I", len(body)) + kind + body + struct.pack(">I", zlib.crc32(kind + body))

    header = struct.pack(">IIBBBBB", cols, rows, 8, 0, 0, 0, 0)
    return (
        b"\x89PNG\r\n\x1a\n"
        + chunk(b"IHDR", header)
        + chunk(b"IDAT", zlib.compress(b"\x00" * (cols + 1) * 4))
        + chunk(b"IEND", b"")
    )


# ------------------------------------------------------------------------------ resource limits


@pytest.mark.parametrize(("cols", "rows"), [(20000, 20000), (100000, 100000)])
def test_a_decompression_bomb_is_refused_before_decoding(tmp_path: Path, cols: int, rows: int) -> None:
    path = tmp_path / "bomb.png"
    path.write_bytes(png_claiming(cols, rows))
    assert path.stat().st_size < 10_000  # tiny on disk: only the header says how big it is
    with pytest.raises(ImageFileError, match=rf"{cols * rows} pixels, over the limit of {2**26}"):
        read_image(path)


def test_the_pixel_limit_is_settable_per_call_and_by_environment(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    path = tmp_path / "image.png"
    write_image(path, np.zeros((40, 50), np.uint8))
    with pytest.raises(ImageFileError, match="2000 pixels, over the limit of 1999"):
        read_image(path, max_pixels=1999)
    assert read_image(path, max_pixels=2000).shape == (40, 50)
    monkeypatch.setenv(MAX_IMAGE_PIXELS_ENV, "1999")
    assert max_image_pixels() == 1999
    with pytest.raises(ImageFileError, match="over the limit of 1999"):
        read_image(path)
    for text in ("many", "0", "1" * 30):
        monkeypatch.setenv(MAX_IMAGE_PIXELS_ENV, text)
        with pytest.raises(InputError, match=MAX_IMAGE_PIXELS_ENV):
            max_image_pixels()
    with pytest.raises(InputError, match="max_pixels must be an integer"):
        read_image(path, max_pixels=0)


def test_a_file_larger_than_any_image_within_the_limit_is_not_read(tmp_path: Path) -> None:
    path = tmp_path / "big.png"
    path.write_bytes(png_claiming(10, 10) + b"\x00" * (2 << 20))
    with pytest.raises(ImageFileError, match="bytes, over"):
        read_image(path, max_pixels=100)


def test_a_file_that_grows_past_the_limit_while_read_is_refused(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    path = tmp_path / "growing.bin"
    path.write_bytes(b"x" * 100)
    real_fstat = os.fstat
    monkeypatch.setattr(
        os, "fstat", lambda fd: os.stat_result((*real_fstat(fd)[:6], 10, *real_fstat(fd)[7:]))
    )
    with pytest.raises(FileError, match="is over 50 bytes"):
        read_regular_file(path, max_bytes=50)


@pytest.mark.parametrize("kind", ["fifo", "device_link", "folder"])
def test_only_regular_files_are_read_and_a_fifo_never_blocks(tmp_path: Path, kind: str) -> None:
    path = tmp_path / "image.png"
    if kind == "fifo":
        os.mkfifo(path)
    elif kind == "device_link":
        os.symlink("/dev/zero", path)
    else:
        path.mkdir()
    start_s = time.perf_counter()
    with pytest.raises(ImageFileError, match="is not a regular file"):
        read_image(path)
    (tmp_path / "pairs.csv").unlink(missing_ok=True)
    manifest = tmp_path / "pairs.csv"
    os.mkfifo(manifest) if kind == "fifo" else os.symlink(path, manifest)
    with pytest.raises(DatasetError, match="is not a regular file"):
        read_manifest(manifest)
    assert time.perf_counter() - start_s < 5.0


@pytest.mark.parametrize(
    ("data", "message"),
    [
        (b"BM" + b"\x00" * 60, "not a PNG, TIFF or JPEG"),
        (b"", "it is empty"),
        (b"\x89PNG\r\n\x1a\n" + b"\x00" * 30, "PNG header is truncated"),
        (b"\xff\xd8\xff\xda\x00\x08" + b"\x00" * 20, "JPEG header is truncated"),
        (b"II*\x00\x08\x00\x00\x00\x00\x00", "TIFF header is truncated"),
    ],
)
def test_headers_that_give_no_size_are_refused(tmp_path: Path, data: bytes, message: str) -> None:
    path = tmp_path / "image.tif"
    path.write_bytes(data)
    with pytest.raises(ImageFileError, match=message):
        read_image(path)


def test_a_path_of_the_wrong_type_is_named() -> None:
    with pytest.raises(InputError, match="path must be a file path"):
        read_image(42)  # type: ignore[arg-type]
    with pytest.raises(InputError, match="path must be"):
        write_image(b"x.png", np.zeros((2, 2), np.uint8))  # type: ignore[arg-type]


def test_decoder_chatter_stays_off_stderr_and_goes_into_the_message(
    tmp_path: Path, capfd: pytest.CaptureFixture[str]
) -> None:
    whole = tmp_path / "whole.png"
    write_image(whole, TEXTURE.astype(np.uint8))
    cut = tmp_path / "cut.png"
    cut.write_bytes(whole.read_bytes()[:200])
    with pytest.raises(ImageFileError, match="not a readable image"):
        read_image(cut)
    assert capfd.readouterr().err == ""


def test_sizes_counts_and_workers_are_bounded() -> None:
    with pytest.raises(InputError, match=r"size must be an integer in \[1, 255\]"):
        flaw_kernel("uniform", size=99999)
    with pytest.raises(InputError, match=rf"workers must be an integer in \[1, {max_local_workers()}\]"):
        run_batch([BatchItem("p", Path("a.png"), Path("b.png"))], archive=_archive_in_memory(), workers=10**6)
    with pytest.raises(InputError, match="loop steps"):
        simulate_lamp(1e6, controller=LampController(sample_rate_hz=1e6))
    with pytest.raises(InputError, match=r"sample_rate_hz must be in \(0.0, 1000000.0\]"):
        LampController(sample_rate_hz=1e300)


def _archive_in_memory() -> Archive:
    return Archive.open("sqlite://", images_dir=Path("unused-images"))


@pytest.mark.parametrize(("option", "value"), [("--size", "99999"), ("--noise-sigma", "1e200")])
def test_the_cli_refuses_unbounded_sizes_and_numbers(tmp_path: Path, option: str, value: str) -> None:
    write_image(tmp_path / "a.png", TEXTURE.astype(np.uint8))
    result = runner.invoke(app, ["inspect", str(tmp_path / "a.png"), str(tmp_path / "a.png"),
                                 "--out", str(tmp_path / "out"), option, value])  # fmt: skip
    assert result.exit_code == EXIT_INVALID_VALUE
    assert result.stderr.startswith("rsi: error: ") and result.stderr.count("\n") == 1
    if option == "--size":
        roc = runner.invoke(app, ["roc", "--strength", "3", "--out", str(tmp_path / "roc"), option, value])
        assert roc.exit_code == EXIT_INVALID_VALUE


# ------------------------------------------------------------------------------ numbers


def test_python_ints_beyond_the_float_range_and_bad_seeds_are_named() -> None:
    with pytest.raises(InputError, match=r"p_false_alarm must be finite .* an integer of 1329 bits"):
        v.finite_number(10**400, "p_false_alarm")
    with pytest.raises(InputError, match="rng seed must be an integer >= 0; got -1"):
        v.as_rng(-1)
    with pytest.raises(InputError, match="rng must be a numpy Generator"):
        v.as_rng("seven")  # type: ignore[arg-type]
    with pytest.raises(InputError, match="wrench must be a number or an array of numbers"):
        v.as_float_array([10**400], "wrench")
    with pytest.raises(InputError, match="x must be a number or an array of numbers"):
        v.as_float_array(np.array([1 + 2j]), "x")
    with pytest.raises(InputError, match="limits must be a JointLimits"):
        limit_avoidance_velocity(np.zeros(3), limits=np.zeros(3))  # type: ignore[arg-type]
    with pytest.raises(InputError, match="sensor must be a ProximitySensor"):
        read_proximity(np.ones(4), sensor="SA1D")  # type: ignore[arg-type]
    with pytest.raises(InputError, match=r"method=.* is not known"):
        thresholds(np.array([1e-3]), polarity="both", method=None, weights=np.ones((1, 1)))  # type: ignore[arg-type]


@pytest.mark.parametrize(
    ("call", "message"),
    [
        (lambda: Pyrometer(band_m=(12e-6, 8e-6)), r"band_m must be \(low, high\) with 0 < low < high"),
        (lambda: Pyrometer(band_m="8-12 um"), "band_m must be a pair"),  # type: ignore[arg-type]
        (lambda: invert_band_radiance_k(1.0, bracket_k=("a", 3)), r"bracket_k\[0\] must be a number"),
        (lambda: invert_band_radiance_k(np.nan, bracket_k=(200, 300)), "radiance_w_m2_sr contains NaN"),
        (lambda: read_pyrometer(np.full(3, 350.0), np.full(2, 0.9)), "must broadcast"),
        (lambda: read_pyrometer(350.0, 0.9, pyrometer=0.95), "pyrometer must be a Pyrometer"),  # type: ignore[arg-type]
        (lambda: v.increasing_pair((1.0, 2.0, 3.0), "pair"), "pair must be a pair"),
    ],
)
def test_sensor_settings_reach_no_bare_numpy_or_solver_error(call: object, message: str) -> None:
    with pytest.raises(InputError, match=message):
        call()  # type: ignore[operator]


def test_expose_saturates_instead_of_failing_inside_numpy() -> None:
    for lux_s in (1e16, 1e300):
        frame = expose(np.full((4, 4), lux_s), np.zeros((4, 4)), exposure_s=1.0, rng=0)
        assert frame.saturated.all() and int(frame.raw.min()) == frame.camera.max_dn


def test_compensation_never_returns_inf_or_nan_on_valid_pixels() -> None:
    with pytest.raises(InputError, match="frame holds a value of magnitude 1e\\+39 DN, over 1e\\+15"):
        compensate_interlaced(np.full((12, 8), 1e39), lit_field="odd")
    with pytest.raises(InputError, match="saturation_dn must be in"):
        compensate_interlaced(np.zeros((12, 8)), lit_field="odd", saturation_dn=1e300)
    frame = np.random.default_rng(0).uniform(-1e15, 1e15, (12, 8))
    result = compensate_interlaced(frame, lit_field="odd", saturation_dn=1e15)
    assert result.valid.any()
    assert np.isfinite(result.image[result.valid]).all() and np.isfinite(result.variance[result.valid]).all()


def test_registration_and_detection_refuse_intensities_beyond_float32_squares() -> None:
    with pytest.raises(InputError, match=r"inspection holds a pixel of magnitude .*e\+18, over 1e\+15"):
        register(TEXTURE * 1e16, TEXTURE * 1e16)
    with pytest.raises(InputError, match=r"reference holds a pixel of magnitude .*e\+18, over 1e\+15"):
        register(TEXTURE * 1e16, TEXTURE)
    with pytest.raises(InputError, match="noise_sigma must be in"):
        detect(TEXTURE, TEXTURE, noise_sigma=1e200)


def test_a_world_exposure_is_bounded() -> None:
    import rsi.sim

    world = rsi.sim.load("truss", seed=0)
    with pytest.raises(InputError, match=r"exposure_s must be in \(0.0, 1.0\]"):
        world.render(world.vistas[0], size=(16, 16), exposure_s=1e16)


# ------------------------------------------------------------------------------ silently wrong


@pytest.mark.parametrize("level", [0.0, 255.0])
def test_a_textured_reference_against_a_flat_inspection_is_reported_not_registered(level: float) -> None:
    flat = np.full_like(TEXTURE, level)
    result = register(TEXTURE, flat)
    assert not result.converged and result.reason == "flat_inspection"
    assert result.translation_xy == (0.0, 0.0) and result.gain == 1.0
    assert register(flat, TEXTURE).reason == "flat_reference"
    with pytest.raises(InputError, match="the pair carries no information"):
        detect(TEXTURE, flat)


def test_inspect_of_a_black_frame_fails_with_the_reason(tmp_path: Path) -> None:
    write_image(tmp_path / "ref.png", TEXTURE.astype(np.uint8))
    write_image(tmp_path / "black.png", np.zeros((64, 64), np.uint8))
    result = runner.invoke(app, ["inspect", str(tmp_path / "ref.png"), str(tmp_path / "black.png"),
                                 "--out", str(tmp_path / "out")])  # fmt: skip
    assert result.exit_code == EXIT_INVALID_VALUE
    assert "carries no information" in result.stderr


def test_score_flaws_names_its_bad_arguments() -> None:
    with pytest.raises(InputError, match="flaws must be a tuple of Flaw"):
        score_flaws(None, np.zeros((1, 2)))  # type: ignore[arg-type]
    with pytest.raises(InputError, match=r"flaws\[0\] must have a bbox of four integers"):
        score_flaws(("flaw",), np.zeros((1, 2)))  # type: ignore[arg-type]
    with pytest.raises(InputError, match="centres_rc must be"):
        score_flaws((), np.array([0.5, 1.0]))
    with pytest.raises(InputError, match="beyond 2\\*\\*31"):
        score_flaws((), np.array([[1e12, 1.0]]))
    with pytest.raises(InputError, match="valid must be a 2-D bool array"):
        score_flaws((), np.zeros((1, 2)), valid=[True])  # type: ignore[arg-type]
    with pytest.raises(InputError, match="outside valid's shape"):
        score_flaws((), np.array([[5, 5]]), valid=np.ones((2, 2), bool))


# ------------------------------------------------------------------------------ exit codes, stderr


def test_a_folder_problem_exits_4_in_every_command(tmp_path: Path) -> None:
    write_image(tmp_path / "a.png", TEXTURE.astype(np.uint8))
    (tmp_path / "file").write_text("x")
    (tmp_path / "pairs.csv").write_text("reference,inspection\na.png,a.png\n")
    out = str(tmp_path / "file")
    commands = [
        ["inspect", str(tmp_path / "a.png"), str(tmp_path / "a.png"), "--out", out],
        ["sim", "render", "--out", out],
        ["archive", "export", "1", "--out", out, "--archive", str(tmp_path / "x.db")],
        ["batch", str(tmp_path / "pairs.csv"), "--out", out, "--archive", str(tmp_path / "b.db")],
        ["roc", "--strength", "3", "--out", out],
    ]
    for command in commands:
        result = runner.invoke(app, command)
        assert result.exit_code == EXIT_FILE, (command, result.stderr)
        assert result.stderr == f"rsi: error: --out={out!r} is a file, not a folder; nothing was written. " \
            "Choose an existing folder or a path where one can be created.\n"  # fmt: skip
    with pytest.raises(InputError, match="out_dir must be a folder path"):
        writable_folder(3, "out_dir")
    with pytest.raises(FileError, match="lies under"):
        writable_folder(tmp_path / "file" / "below", "out_dir")


def test_an_unreadable_image_exits_4_with_one_line(tmp_path: Path) -> None:
    (tmp_path / "cut.png").write_bytes(png_claiming(8, 8)[:40])
    result = runner.invoke(app, ["register", str(tmp_path / "cut.png"), str(tmp_path / "cut.png")])
    assert result.exit_code == EXIT_FILE
    assert result.stderr.count("\n") == 1 and result.stderr.startswith("rsi: error: path ")


def test_an_internal_memory_error_says_so(monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> None:
    import rsi.detection.roc

    def exhausted(*_args: object, **_kwargs: object) -> None:
        raise MemoryError

    monkeypatch.setattr(rsi.detection.roc, "theoretical_roc", exhausted)
    result = runner.invoke(app, ["roc", "--strength", "3", "--out", str(tmp_path / "roc")])
    assert result.exit_code == EXIT_INTERNAL
    assert result.stderr.startswith("rsi: error: internal error: out of memory")


def test_runtime_warnings_do_not_reach_stderr(monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> None:
    import warnings

    import rsi.detection.roc

    real = rsi.detection.roc.theoretical_roc

    def noisy(*args: object, **kwargs: object) -> object:
        warnings.warn("overflow encountered in multiply", RuntimeWarning, stacklevel=1)
        warnings.warn("raise the strength for a readable curve", UserWarning, stacklevel=1)
        return real(*args, **kwargs)  # type: ignore[arg-type]

    monkeypatch.setattr(rsi.detection.roc, "theoretical_roc", noisy)
    result = runner.invoke(
        app, ["roc", "--strength", "3", "--out", str(tmp_path / "roc"), "--flaw-model", "single"]
    )
    assert result.exit_code == 0
    assert result.stderr == "rsi: warning: raise the strength for a readable curve\n"


def test_sim_render_help_promises_what_it_accepts() -> None:
    text = runner.invoke(app, ["sim", "render", "--help"]).output
    assert "4096" not in text and "2048" in text


# ------------------------------------------------------------------------------ archive


@pytest.fixture
def archive_file(tmp_path: Path) -> Path:
    path = tmp_path / "archive.db"
    with Archive.open(path) as archive:
        archive.add_vista("A_door")
        run_id = archive.start_run(seed=1)
        archive.add_findings(run_id, [Finding("A_door", "impact", 0.5, bbox=(0, 0, 2, 2))])
        archive.finish_run(run_id)
    return path


def _tamper(path: Path, statement: str) -> bytes:
    connection = sqlite3.connect(path)
    connection.execute("PRAGMA journal_mode=DELETE")
    connection.execute("PRAGMA foreign_keys=OFF")
    connection.execute(statement)
    connection.commit()
    connection.close()
    return path.read_bytes()


@pytest.mark.parametrize(
    ("statement", "message"),
    [
        ("UPDATE runs SET settings_json = '{bad'", "table runs row id=1: settings_json='{bad' is not valid"),
        ("UPDATE runs SET started_at = 'yesterday'", "table runs row id=1: started_at='yesterday'"),
        ("UPDATE findings SET extras_json = '[1]'", "table findings row id=1: extras_json='\\[1\\]'"),
        ("DELETE FROM rsi_archive", "no valid schema version \\(table rsi_archive holds no row\\)"),
        ("UPDATE rsi_archive SET schema_version = 'one'", "holds 'one'"),
        ("DROP TABLE findings", "lacks table 'findings'"),
        (
            "INSERT INTO rsi_archive SELECT 2, schema_version, created_at, created_by FROM rsi_archive",
            "several",
        ),
    ],
)
def test_a_tampered_archive_is_named_by_row_and_never_written(
    archive_file: Path, tmp_path: Path, statement: str, message: str
) -> None:
    before = _tamper(archive_file, statement)
    with pytest.raises(ArchiveFileError, match=message):
        Archive.open(archive_file)  # a writable open checks everything first
    (tmp_path / "pairs.csv").write_text("reference,inspection\na.png,b.png\n")
    result = runner.invoke(app, ["batch", str(tmp_path / "pairs.csv"), "--out", str(tmp_path / "out"),
                                 "--archive", str(archive_file)])  # fmt: skip
    assert result.exit_code == EXIT_FILE and "not modified" in result.stderr
    for command in (["list"], ["show", "1"], ["export", "1", "--out", str(tmp_path / "export")]):
        listed = runner.invoke(app, ["archive", *command, "--archive", str(archive_file)])
        assert listed.exit_code in (0, EXIT_FILE), listed.stderr
    assert archive_file.read_bytes() == before


def test_a_damaged_page_is_found_before_any_write(archive_file: Path) -> None:
    with Archive.open(archive_file) as archive:
        run_id = archive.start_run()
        archive.add_findings(
            run_id, [Finding("A_door", "impact", 0.5, bbox=(i, i, i + 2, i + 2)) for i in range(400)]
        )
    data = bytearray(archive_file.read_bytes())
    data[2 * 4096 : len(data) - 4096] = b"\xa5" * (len(data) - 3 * 4096)
    archive_file.write_bytes(bytes(data))
    with pytest.raises(ArchiveFileError, match="is damaged \\(SQLite quick_check"):
        Archive.open(archive_file)
    assert archive_file.read_bytes() == bytes(data)


def test_read_only_opening_writes_nothing_and_refuses_writes(archive_file: Path) -> None:
    connection = sqlite3.connect(archive_file)
    connection.execute("PRAGMA journal_mode=DELETE")  # as a copied or restored file may be
    connection.close()
    before = archive_file.read_bytes()
    with Archive.open(archive_file, read_only=True) as archive:
        assert archive.read_only and [run.run_id for run in archive.runs()] == [1]
        with pytest.raises(ArchiveError, match="opened read-only"):
            archive.start_run()
    assert archive_file.read_bytes() == before  # not even the journal mode (WAL) was switched
    with pytest.raises(ArchiveFileError, match="there is no archive"):
        Archive.open(archive_file.with_name("missing.db"), read_only=True)
    with pytest.raises(InputError, match="create and read_only must be True or False"):
        Archive.open(archive_file, read_only="yes")  # type: ignore[arg-type]
    with pytest.raises(InputError, match="images_dir must be a folder path"):
        Archive.open(archive_file, images_dir=3)  # type: ignore[arg-type]


def test_run_ids_beyond_sql_integers_are_input_errors(archive_file: Path) -> None:
    with Archive.open(archive_file, read_only=True) as archive:
        for bad in (2**63, 0, -1):
            with pytest.raises(InputError, match=r"run_id must be an integer in \[1, 2\*\*63\)"):
                archive.run(bad)
        with pytest.raises(InputError, match="finding_id must be an integer"):
            archive.finding(2**64)
    result = runner.invoke(app, ["archive", "show", str(2**63), "--archive", str(archive_file)])
    assert result.exit_code == EXIT_INVALID_VALUE


def test_a_non_sqlite_url_takes_an_images_dir(tmp_path: Path) -> None:
    result = runner.invoke(app, ["archive", "list", "--archive", "postgresql://u:secret@127.0.0.1:1/rsi",
                                 "--images-dir", str(tmp_path / "images")])  # fmt: skip
    assert result.exit_code == EXIT_INVALID_VALUE
    assert "images_dir is needed" not in result.stderr and "secret" not in result.stderr
    assert (
        "driver" in result.stderr or "cannot be opened" in result.stderr or "not a readable" in result.stderr
    )
    url = f"sqlite:///{tmp_path / 'other.db'}"
    with Archive.open(url, images_dir=tmp_path / "elsewhere") as archive:
        archive.store_image(np.zeros((2, 2)))
    assert (tmp_path / "elsewhere").is_dir()


def test_archive_methods_check_their_collections(archive_file: Path) -> None:
    with Archive.open(archive_file) as archive:
        run_id = archive.start_run()
        with pytest.raises(InputError, match="findings must be an iterable of Finding"):
            archive.add_findings(run_id, None)  # type: ignore[arg-type]
        with pytest.raises(InputError, match=r"status=.* is not known"):
            archive.runs(status=np.array([]))  # type: ignore[arg-type]


# ------------------------------------------------------------------------------ batch


def test_manifest_fields_are_bounded_and_named_by_line(tmp_path: Path) -> None:
    manifest = tmp_path / "pairs.csv"
    manifest.write_text("reference,inspection\na.png,b.png\n" + "x" * 200_000 + ",b.png\n")
    with pytest.raises(DatasetError, match=r"pairs.csv:3: is not valid CSV"):
        read_manifest(manifest)
    manifest.write_text("reference,inspection\n" + "y" * 5000 + ",b.png\n")
    with pytest.raises(DatasetError, match=r"pairs.csv:2: the reference cell is 5000 characters"):
        read_manifest(manifest)
    with pytest.raises(InputError, match="path must be the manifest's file path"):
        read_manifest(None)  # type: ignore[arg-type]


def test_batch_items_and_tasks_check_their_types() -> None:
    with pytest.raises(InputError, match="settings of pair 'p' must be a dict"):
        BatchItem("p", Path("a.png"), Path("b.png"), settings=None)  # type: ignore[arg-type]
    with pytest.raises(InputError, match="reference of pair 'p' must be a path"):
        BatchItem("p", None, Path("b.png"))  # type: ignore[arg-type]
    with pytest.raises(InputError, match="item must be a BatchItem"):
        inspect_item("pair", PairSettings())  # type: ignore[arg-type]
    with pytest.raises(InputError, match="archive must be a Archive"):
        run_batch([BatchItem("p", Path("a.png"), Path("b.png"))], archive="archive.db")  # type: ignore[arg-type]
    with pytest.raises(InputError, match="scheduler must be an address"):
        run_batch([BatchItem("p", Path("a"), Path("b"))], archive=_archive_in_memory(), scheduler="x" * 2000)


@pytest.fixture
def fake_scheduler(request: pytest.FixtureRequest) -> Iterator[str]:
    """A TCP server that answers like something else (HTTP) or never says anything."""
    server = socket.socket()
    server.bind(("127.0.0.1", 0))
    server.listen(4)
    stop = threading.Event()
    held: list[socket.socket] = []

    def serve() -> None:
        server.settimeout(0.2)
        while not stop.is_set():
            try:
                connection, _ = server.accept()
            except TimeoutError:
                continue
            held.append(connection)
            if request.param == "garbage":
                connection.sendall(b"HTTP/1.1 200 OK\r\n\r\n" * 10)

    thread = threading.Thread(target=serve, daemon=True)
    thread.start()
    yield f"tcp://127.0.0.1:{server.getsockname()[1]}"
    stop.set()
    thread.join()
    for connection in held:
        connection.close()
    server.close()


@pytest.mark.parametrize(
    ("fake_scheduler", "message"),
    [("garbage", "answered, but not as a dask scheduler"), ("silent", "sent no dask handshake within 1 s")],
    indirect=["fake_scheduler"],
)
def test_a_scheduler_that_is_not_dask_is_refused_within_the_timeout(
    fake_scheduler: str, message: str
) -> None:
    start_s = time.perf_counter()
    with pytest.raises(InputError, match=message):
        run_batch(
            [BatchItem("p", Path("a"), Path("b"))],
            archive=_archive_in_memory(),
            scheduler=fake_scheduler,
            connect_timeout_s=1.0,
        )
    assert time.perf_counter() - start_s < 10.0


def test_an_unused_port_is_refused_at_once() -> None:
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        port = probe.getsockname()[1]
    start_s = time.perf_counter()
    with pytest.raises(InputError, match="connection refused"):
        run_batch([BatchItem("p", Path("a"), Path("b"))], archive=_archive_in_memory(),
                  scheduler=f"tcp://127.0.0.1:{port}", connect_timeout_s=30.0)  # fmt: skip
    assert time.perf_counter() - start_s < 5.0


def test_the_image_cv2_reads_and_rsi_reads_agree(tmp_path: Path) -> None:
    # The header parser must not refuse what OpenCV writes: PNG, 16-bit PNG, TIFF (incl. float), JPEG.
    image = TEXTURE.astype(np.uint8)
    for name, data in (("a.png", image), ("b.png", image.astype(np.uint16) * 200), ("c.tif", image),
                       ("d.tif", TEXTURE.astype(np.float32)), ("e.jpg", image)):  # fmt: skip
        assert cv2.imwrite(str(tmp_path / name), data)
        assert read_image(tmp_path / name).shape == (64, 64)
    shutil.rmtree(tmp_path)
