"""Read and write grey images: 8/16-bit PNG, TIFF (also float32) and JPEG, values kept in the file's DN.

Values are not rescaled: an 8-bit file reads 0..255, a 16-bit file 0..65535 and a float TIFF as stored, so a
camera's digital numbers survive a round trip and stay linear (seed §2.1: linear response is what makes
ambient subtraction valid). Colour files become grey by the luminance weights (seed §2.1: only the luminance
signal is used).
"""

from __future__ import annotations

import contextlib
import os
import struct
import tempfile
import threading
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import cv2
import numpy as np
from numpy.typing import NDArray

from rsi._files import atomic_write_bytes, read_regular_file
from rsi._validate import positive_int
from rsi.errors import ImageFileError, InputError

PathLike = str | os.PathLike[str]

READ_SUFFIXES = (".png", ".tif", ".tiff", ".jpg", ".jpeg")
# The format follows the dtype: integers stay exact in PNG (or TIFF), floats need a float32 TIFF.
_WRITE_SUFFIXES: dict[str, tuple[str, ...]] = {
    "uint8": (".png", ".tif", ".tiff"),
    "uint16": (".png", ".tif", ".tiff"),
    "float32": (".tif", ".tiff"),
    "float64": (".tif", ".tiff"),
}
_TO_GREY = {3: cv2.COLOR_BGR2GRAY, 4: cv2.COLOR_BGRA2GRAY}


DEFAULT_MAX_IMAGE_PIXELS = 2**26
"""Pixels (rows x cols) :func:`read_image` decodes by default: 8192 x 8192, about 1 GiB while a 16-bit BGRA
file of that size is decoded and turned grey. A header claiming more is refused before anything is decoded
(a 389 KB PNG can claim 20000 x 20000 and grow a process to 24 GB). Raise it per call with `max_pixels`, or
for every process of a run (CLI, batch workers) with the environment variable ``RSI_MAX_IMAGE_PIXELS``."""
MAX_IMAGE_PIXELS_ENV = "RSI_MAX_IMAGE_PIXELS"
# A file may hold at most 4 channels of 32 bits per pixel plus headers: anything larger is not an image of
# the allowed size (and reading it whole would be the memory bomb the pixel limit is there to stop).
_BYTES_PER_PIXEL = 16
_HEADER_ALLOWANCE_BYTES = 1 << 20
_PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"
_JPEG_SIGNATURE = b"\xff\xd8"
_TIFF_SIGNATURES = {b"II*\x00": ("<", 4), b"MM\x00*": (">", 4), b"II+\x00": ("<", 8), b"MM\x00+": (">", 8)}
# JPEG start-of-frame markers (baseline, progressive, lossless, arithmetic); C4, C8 and CC are not frames.
_JPEG_FRAMES = frozenset(range(0xC0, 0xD0)) - {0xC4, 0xC8, 0xCC}
_JPEG_STANDALONE = frozenset({0x01, *range(0xD0, 0xD8)})
_STDERR_LOCK = threading.Lock()


def max_image_pixels() -> int:
    """The pixel limit of :func:`read_image`: ``RSI_MAX_IMAGE_PIXELS`` if set, else the default.

    Raises
    ------
    InputError
        If ``RSI_MAX_IMAGE_PIXELS`` is set but not an integer >= 1.
    """
    text = os.environ.get(MAX_IMAGE_PIXELS_ENV, "").strip()
    if not text:
        return DEFAULT_MAX_IMAGE_PIXELS
    if not text.isdigit() or int(text) < 1 or len(text) > 18:
        raise InputError(
            f"{MAX_IMAGE_PIXELS_ENV}={text[:40]!r} is not a pixel count; set it to an integer in [1, 10**18) "
            f"or unset it (default {DEFAULT_MAX_IMAGE_PIXELS})."
        )
    return int(text)


def read_image(path: PathLike, *, max_pixels: int | None = None) -> NDArray[np.float32]:
    """Read an image file as a grey float32 array in the file's own digital numbers.

    Only a regular file is read (a FIFO, a device or a link to one is refused, never waited on), only up to
    the size an image of `max_pixels` can have, and its header's rows x cols are checked against
    `max_pixels` before a pixel is decoded. The decoder's own warnings (libpng, libjpeg) never reach stderr:
    when they explain a failure they end up in the error message.

    Parameters
    ----------
    path : str or os.PathLike
        A PNG, TIFF or JPEG file, 8 or 16 bits per channel (or float32 TIFF), grey, BGR or BGRA.
    max_pixels : int, optional
        Largest rows x cols accepted; default :func:`max_image_pixels` (2**26 unless
        ``RSI_MAX_IMAGE_PIXELS`` says otherwise).

    Returns
    -------
    ndarray of shape (M, N), float32
        Grey values on the file's scale (0..255 for 8 bits, 0..65535 for 16 bits); colour is converted with
        the Rec. 601 luminance weights before any rounding.

    Raises
    ------
    ImageFileError
        If the file is missing, not a regular file, unreadable, corrupt, larger than `max_pixels` or not a
        supported image; the message names the path.
    InputError
        If `max_pixels` is not an integer >= 1.
    """
    limit = max_image_pixels() if max_pixels is None else positive_int(max_pixels, "max_pixels")
    file = _as_path(path)
    if file.suffix.lower() not in READ_SUFFIXES:
        raise ImageFileError(
            f"path {str(file)!r} has suffix {file.suffix!r}, which is not supported. "
            f"Use one of {', '.join(READ_SUFFIXES)}."
        )
    data = read_regular_file(
        file,
        max_bytes=limit * _BYTES_PER_PIXEL + _HEADER_ALLOWANCE_BYTES,
        error=ImageFileError,
        too_big=f"more than an image within the pixel limit can hold; raise max_pixels (or "
        f"{MAX_IMAGE_PIXELS_ENV}) if it is genuine",
    )
    rows, cols = _header_size(data, file)
    if rows * cols > limit:
        raise ImageFileError(
            f"path {str(file)!r} is {rows} x {cols} = {rows * cols} pixels, over the limit of {limit}. "
            f"If the image is genuine, raise max_pixels (or {MAX_IMAGE_PIXELS_ENV})."
        )
    # imdecode (not imread) so that non-ASCII paths work everywhere; the decoder's chatter is captured.
    with _captured_stderr() as chatter:
        image = cv2.imdecode(np.frombuffer(data, dtype=np.uint8), cv2.IMREAD_UNCHANGED)
    if image is None:
        said = " ".join(chatter.text.split())
        raise ImageFileError(
            f"path {str(file)!r} is not a readable image (corrupt or truncated"
            f"{'; the decoder says: ' + said[:300] if said else ''}). Re-export the file."
        )
    return _grey(image, file)


def _header_size(data: bytes, file: Path) -> tuple[int, int]:
    """(rows, cols) as the file's header states them, read without decoding any pixel."""
    size: tuple[int, int] | None = None
    kind = "image"
    try:
        if data.startswith(_PNG_SIGNATURE):
            kind = "PNG"
            size = _png_size(data)
        elif data.startswith(_JPEG_SIGNATURE):
            kind = "JPEG"
            size = _jpeg_size(data)
        elif data[:4] in _TIFF_SIGNATURES:
            kind = "TIFF"
            size = _tiff_size(data)
        else:
            raise ImageFileError(
                f"path {str(file)!r} is not a readable image: not a PNG, TIFF or JPEG file (it starts "
                f"{data[:8]!r}{', it is empty' if not data else ''}). Re-export the file."
            )
    except struct.error:
        size = None
    if size is None or min(size) < 1:
        raise ImageFileError(
            f"path {str(file)!r} is not a readable image: its {kind} header is truncated or corrupt (no "
            "size in it). Re-export the file."
        )
    return size


def _png_size(data: bytes) -> tuple[int, int] | None:
    # The first chunk of a PNG is IHDR: width and height, big-endian, right after its type.
    if data[12:16] != b"IHDR":
        return None
    cols, rows = struct.unpack(">II", data[16:24])
    return rows, cols


def _jpeg_size(data: bytes) -> tuple[int, int] | None:
    # Walk the marker segments to the first start-of-frame: precision, height, width.
    offset = 2
    while offset + 4 <= len(data):
        if data[offset] != 0xFF:
            return None
        marker = data[offset + 1]
        if marker == 0xFF:  # fill byte
            offset += 1
            continue
        if marker in _JPEG_STANDALONE:
            offset += 2
            continue
        (length,) = struct.unpack(">H", data[offset + 2 : offset + 4])
        if marker in _JPEG_FRAMES:
            rows, cols = struct.unpack(">HH", data[offset + 5 : offset + 9])
            return rows, cols
        if marker == 0xDA or length < 2:  # scan data before any frame header: corrupt
            return None
        offset += 2 + length
    return None


def _tiff_size(data: bytes) -> tuple[int, int] | None:
    # The first image file directory (the page OpenCV decodes) holds ImageWidth (256) and ImageLength (257).
    order, offset_bytes = _TIFF_SIGNATURES[data[:4]]
    big = offset_bytes == 8
    offset = struct.unpack(order + ("Q" if big else "I"), data[8:16] if big else data[4:8])[0]
    count_format, entry_bytes = ("Q", 20) if big else ("H", 12)
    (count,) = struct.unpack(order + count_format, data[offset : offset + (8 if big else 2)])
    first = offset + (8 if big else 2)
    found: dict[int, int] = {}
    for index in range(min(int(count), 4096)):
        entry = first + index * entry_bytes
        tag, kind = struct.unpack(order + "HH", data[entry : entry + 4])
        if tag not in (256, 257):
            continue
        value_at = entry + (12 if big else 8)
        value_format = {3: "H", 4: "I", 16: "Q"}.get(kind)
        if value_format is None:
            return None
        (found[tag],) = struct.unpack(
            order + value_format, data[value_at : value_at + struct.calcsize(value_format)]
        )
    if 256 not in found or 257 not in found:
        return None
    return found[257], found[256]


class _Captured:
    """What the decoder wrote to stderr while captured (read once the block ends)."""

    def __init__(self) -> None:
        self.text = ""


@contextlib.contextmanager
def _captured_stderr() -> Iterator[_Captured]:
    """Point file descriptor 2 at a temporary file for the block: libpng and libjpeg write their warnings
    straight to it, bypassing Python. Serialised by a lock (the descriptor is process-wide)."""
    captured = _Captured()
    with _STDERR_LOCK, tempfile.TemporaryFile() as stream:
        try:
            saved = os.dup(2)
        except OSError:  # no stderr at all: nothing to protect
            yield captured
            return
        try:
            os.dup2(stream.fileno(), 2)
            yield captured
        finally:
            os.dup2(saved, 2)
            os.close(saved)
            stream.seek(0)
            captured.text = stream.read(4096).decode("utf-8", "replace")


def _as_path(path: object) -> Path:
    if not isinstance(path, (str, os.PathLike)) or not str(path):
        raise InputError(
            f"path must be a file path (str or os.PathLike); got {type(path).__name__} {path!r:.60}."
        )
    try:
        return Path(path)
    except TypeError:  # an os.PathLike returning bytes
        raise InputError(f"path must be a text file path; got {path!r:.60}.") from None


def _grey(image: NDArray[Any], file: Path) -> NDArray[np.float32]:
    channels = 1 if image.ndim == 2 else image.shape[2]
    if channels not in (1, *_TO_GREY):
        raise ImageFileError(f"path {str(file)!r} has {channels} channels; expected grey, BGR or BGRA.")
    grey = image.reshape(image.shape[:2]) if channels == 1 else image
    grey = grey.astype(np.float32)
    if channels > 1:
        grey = cv2.cvtColor(grey, _TO_GREY[channels])
    return np.asarray(grey, dtype=np.float32)


def write_image(path: PathLike, image: NDArray[Any]) -> None:
    """Write a grey image atomically: readers see the old file or the whole new one, never a part.

    Parameters
    ----------
    path : str or os.PathLike
        Destination; missing parent folders are created. uint8 and uint16 images go to ``.png`` (8- or 16-bit)
        or ``.tif``; float32 and float64 images to a float32 ``.tif``.
    image : ndarray of shape (M, N), uint8, uint16, float32 or float64
        The grey image, values written as they are (no rescaling).

    Raises
    ------
    ImageFileError
        If the dtype, shape or suffix does not fit, or the file cannot be written; the message names the path.
    """
    file = _as_path(path)
    payload = _encode(file, image)
    try:
        atomic_write_bytes(file, payload)
    except OSError as error:
        raise ImageFileError(f"path {str(file)!r} cannot be written: {error.strerror or error}.") from error


def _encode(file: Path, image: NDArray[Any]) -> bytes:
    if not isinstance(image, np.ndarray) or image.ndim != 2 or image.size == 0:
        raise ImageFileError(
            f"image for path {str(file)!r} must be a non-empty 2-D (rows, cols) numpy array; got "
            f"{type(image).__name__} with shape {getattr(image, 'shape', None)}. Convert colour to grey."
        )
    suffixes = _WRITE_SUFFIXES.get(image.dtype.name)
    if suffixes is None:
        raise ImageFileError(
            f"image for path {str(file)!r} has dtype={image.dtype}, which is not supported. "
            "Try image.astype('uint8'), 'uint16' or 'float32'."
        )
    if file.suffix.lower() not in suffixes:
        raise ImageFileError(
            f"path {str(file)!r}: a {image.dtype} image must be written as {' or '.join(suffixes)}; "
            f"got suffix {file.suffix!r}."
        )
    pixels = image.astype(np.float32) if image.dtype == np.float64 else image
    ok, encoded = cv2.imencode(file.suffix.lower(), pixels)
    if not ok:
        raise ImageFileError(f"path {str(file)!r}: OpenCV could not encode the image.")
    return bytes(encoded.tobytes())
