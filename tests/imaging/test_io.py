"""Image files: exact round trips at the file's depth, colour to grey, atomic writes, named errors."""

from __future__ import annotations

import os
import stat
from pathlib import Path

import cv2
import numpy as np
import pytest

from rsi.errors import ImageFileError
from rsi.imaging.io import read_image, write_image


def _ramp(dtype: type, top: float) -> np.ndarray:
    return (np.linspace(0, top, 48 * 64).reshape(48, 64)).astype(dtype)


@pytest.mark.parametrize(
    ("name", "image"),
    [
        ("eight.png", _ramp(np.uint8, 255)),
        ("sixteen.png", _ramp(np.uint16, 65535)),
        ("eight.tif", _ramp(np.uint8, 255)),
        ("sixteen.TIFF", _ramp(np.uint16, 65535)),
        ("float.tif", _ramp(np.float32, 3.75) - 1.5),
    ],
)
def test_round_trip_keeps_values_in_the_files_digital_numbers(
    tmp_path: Path, name: str, image: np.ndarray
) -> None:
    path = tmp_path / name
    write_image(path, image)
    back = read_image(path)
    assert back.dtype == np.float32
    np.testing.assert_array_equal(back, image.astype(np.float32))


def test_float64_is_written_as_float32_tiff(tmp_path: Path) -> None:
    image = np.linspace(-1.0, 1.0, 30).reshape(5, 6)
    write_image(str(tmp_path / "f.tif"), image)
    np.testing.assert_array_equal(read_image(tmp_path / "f.tif"), image.astype(np.float32))


def test_sixteen_bit_png_is_really_sixteen_bit(tmp_path: Path) -> None:
    write_image(tmp_path / "deep.png", np.full((4, 4), 40000, dtype=np.uint16))
    stored = cv2.imread(str(tmp_path / "deep.png"), cv2.IMREAD_UNCHANGED)
    assert stored is not None
    assert stored.dtype == np.uint16


@pytest.mark.parametrize("alpha", [False, True])
def test_colour_becomes_grey_by_luminance_weights(tmp_path: Path, alpha: bool) -> None:
    bgr = np.zeros((3, 4, 4 if alpha else 3), dtype=np.uint8)
    bgr[0, :, 0], bgr[1, :, 1], bgr[2, :, 2] = 255, 255, 255  # blue, green, red rows
    if alpha:
        bgr[..., 3] = 255
    path = tmp_path / "colour.png"
    assert cv2.imwrite(str(path), bgr)
    grey = read_image(path)
    np.testing.assert_allclose(grey[:, 0], [0.114 * 255, 0.587 * 255, 0.299 * 255], atol=0.01)


def test_jpeg_reads_as_grey(tmp_path: Path) -> None:
    path = tmp_path / "grey.jpeg"
    assert cv2.imwrite(str(path), np.full((16, 16), 100, dtype=np.uint8))
    np.testing.assert_allclose(read_image(path), 100.0, atol=1.0)


def test_write_creates_parent_folders_and_leaves_no_temporary_files(tmp_path: Path) -> None:
    path = tmp_path / "a" / "b" / "image.png"
    write_image(path, np.zeros((3, 3), dtype=np.uint8))
    write_image(path, np.full((3, 3), 9, dtype=np.uint8))  # replaces the old file
    assert sorted(p.name for p in path.parent.iterdir()) == ["image.png"]
    np.testing.assert_array_equal(read_image(path), 9.0)


def test_written_files_get_the_permissions_of_a_plain_open(tmp_path: Path) -> None:
    write_image(tmp_path / "image.png", np.zeros((3, 3), dtype=np.uint8))
    (tmp_path / "plain").write_bytes(b"")
    modes = [stat.S_IMODE((tmp_path / name).stat().st_mode) for name in ("image.png", "plain")]
    assert modes[0] == modes[1]


def test_missing_file_error_names_the_path(tmp_path: Path) -> None:
    path = tmp_path / "nowhere.png"
    with pytest.raises(ImageFileError, match=r"nowhere\.png.*cannot be read"):
        read_image(path)


def test_folder_is_not_readable_as_an_image(tmp_path: Path) -> None:
    folder = tmp_path / "folder.png"
    folder.mkdir()
    with pytest.raises(ImageFileError, match=r"folder\.png"):
        read_image(folder)


@pytest.mark.parametrize("keep", [0, 40, 0.5])
def test_corrupt_or_truncated_png_error_names_the_path(tmp_path: Path, keep: float) -> None:
    whole = tmp_path / "whole.png"
    write_image(whole, _ramp(np.uint8, 255))
    data = whole.read_bytes()
    path = tmp_path / "cut.png"
    path.write_bytes(data[: int(keep * len(data)) if isinstance(keep, float) else keep])
    with pytest.raises(ImageFileError, match=r"cut\.png.*not a readable image"):
        read_image(path)


def test_garbage_with_an_image_suffix_is_rejected(tmp_path: Path) -> None:
    path = tmp_path / "noise.tif"
    path.write_bytes(b"this is not a tiff" * 10)
    with pytest.raises(ImageFileError, match=r"noise\.tif"):
        read_image(path)


def test_unsupported_suffix_is_rejected(tmp_path: Path) -> None:
    path = tmp_path / "picture.bmp"
    path.write_bytes(b"BM")
    with pytest.raises(ImageFileError, match=r"picture\.bmp.*'\.bmp', which is not supported"):
        read_image(path)


def test_unusual_channel_counts_are_rejected(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    path = tmp_path / "two.tif"
    write_image(path, np.zeros((4, 4), dtype=np.uint8))
    monkeypatch.setattr(cv2, "imdecode", lambda *_: np.zeros((4, 4, 2), dtype=np.uint8))
    with pytest.raises(ImageFileError, match=r"two\.tif.*2 channels"):
        read_image(path)


@pytest.mark.parametrize(
    ("name", "image", "fragment"),
    [
        ("a.png", np.zeros((3, 3), dtype=np.int32), "dtype=int32"),
        ("a.png", np.zeros((3, 3), dtype=bool), "dtype=bool"),
        ("a.png", np.zeros((3, 3, 3), dtype=np.uint8), "2-D"),
        ("a.png", [[0, 1], [2, 3]], "2-D"),
        ("a.png", np.zeros((0, 3), dtype=np.uint8), "non-empty"),
        ("a.png", np.zeros((3, 3), dtype=np.float32), "must be written as .tif or .tiff"),
        ("a.jpg", np.zeros((3, 3), dtype=np.uint8), "must be written as .png"),
    ],
)
def test_write_rejects_bad_images_naming_the_path(
    tmp_path: Path, name: str, image: object, fragment: str
) -> None:
    with pytest.raises(ImageFileError, match=r"a\.(png|jpg)") as caught:
        write_image(tmp_path / name, image)  # type: ignore[arg-type]
    assert fragment in str(caught.value)
    assert not list(tmp_path.iterdir())


def test_write_into_a_file_instead_of_a_folder_fails_cleanly(tmp_path: Path) -> None:
    blocker = tmp_path / "blocker"
    blocker.write_text("")
    with pytest.raises(ImageFileError, match=r"blocker.*cannot be written"):
        write_image(blocker / "image.png", np.zeros((3, 3), dtype=np.uint8))


def test_failed_replace_keeps_the_old_file_and_removes_the_temporary(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    path = tmp_path / "kept.png"
    write_image(path, np.full((3, 3), 7, dtype=np.uint8))

    def refuse(*_: object) -> None:
        raise PermissionError(13, "Permission denied")

    monkeypatch.setattr(os, "replace", refuse)
    with pytest.raises(ImageFileError, match=r"kept\.png.*cannot be written"):
        write_image(path, np.zeros((3, 3), dtype=np.uint8))
    assert [p.name for p in tmp_path.iterdir()] == ["kept.png"]
    np.testing.assert_array_equal(read_image(path), 7.0)


def test_encoder_failure_is_reported(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(cv2, "imencode", lambda *_: (False, None))
    with pytest.raises(ImageFileError, match=r"e\.png.*could not encode"):
        write_image(tmp_path / "e.png", np.zeros((3, 3), dtype=np.uint8))
