"""Content-addressed image files: the SHA-256 of the bytes is the file name, so identical images are one file.

Arrays are stored as ``.npy`` bytes (exact dtype and shape, no pickle); bytes (an encoded PNG, JPEG, ...) are
stored as given. Files are written atomically and checked against their name when read.
"""

from __future__ import annotations

import hashlib
import io
from pathlib import Path

import numpy as np

from rsi._files import atomic_write_bytes
from rsi.errors import InputError

Image = bytes | np.ndarray

# File signatures, for the media type of stored bytes and the extension of an exported copy.
_SIGNATURES = (
    (b"\x93NUMPY", "npy"),
    (b"\x89PNG\r\n\x1a\n", "png"),
    (b"\xff\xd8\xff", "jpeg"),
    (b"II*\x00", "tiff"),
    (b"MM\x00*", "tiff"),
    (b"BM", "bmp"),
)
EXTENSIONS = {"npy": ".npy", "png": ".png", "jpeg": ".jpg", "tiff": ".tif", "bmp": ".bmp", "bytes": ".bin"}


class ImageIntegrityError(Exception):
    """A stored image file is missing or its bytes no longer hash to its name (raised as ArchiveFileError)."""


def encode(image: object, name: str) -> tuple[bytes, str]:
    """Return the bytes to store for `image` and their media type."""
    if isinstance(image, (bytes, bytearray, memoryview)):
        data = bytes(image)
        if not data:
            raise InputError(f"{name} is empty (0 bytes); pass the image file's bytes or a numpy array.")
        media = next((kind for magic, kind in _SIGNATURES if data.startswith(magic)), "bytes")
        return data, media
    if isinstance(image, np.ndarray):
        if image.dtype.hasobject or image.dtype.kind not in "biufc" or image.size == 0:
            raise InputError(
                f"{name} must be a non-empty numeric or bool array; got dtype={image.dtype}, "
                f"shape {image.shape}. Try image.astype('float32')."
            )
        stream = io.BytesIO()
        # C order always, so the same pixels give the same bytes (and one file) whatever the memory layout.
        np.save(stream, np.ascontiguousarray(image), allow_pickle=False)
        return stream.getvalue(), "npy"
    raise InputError(
        f"{name} must be bytes (an encoded image file) or a numpy array; got {type(image).__name__}."
    )


def decode(data: bytes, media: str) -> Image:
    """The stored image: an array for ``"npy"``, else the bytes as stored."""
    if media == "npy":
        array: np.ndarray = np.load(io.BytesIO(data), allow_pickle=False)
        return array
    return data


def sha256(data: bytes) -> str:
    return hashlib.sha256(data).hexdigest()


def path_of(folder: Path, digest: str) -> Path:
    """Where the image with SHA-256 `digest` lives (two-digit fan-out keeps folders small)."""
    return folder / digest[:2] / digest


def write(folder: Path, data: bytes) -> str:
    """Store `data` (once) and return its SHA-256; a damaged copy already there is replaced."""
    digest = sha256(data)
    target = path_of(folder, digest)
    try:
        if target.stat().st_size == len(data) and sha256(target.read_bytes()) == digest:
            return digest
    except FileNotFoundError:
        pass
    atomic_write_bytes(target, data)
    return digest


def read(folder: Path, digest: str) -> bytes:
    """The bytes of image `digest`, checked against their hash."""
    target = path_of(folder, digest)
    try:
        data = target.read_bytes()
    except FileNotFoundError:
        raise ImageIntegrityError(
            f"image file {target} is missing; restore the images folder {folder} from a backup."
        ) from None
    if sha256(data) != digest:
        raise ImageIntegrityError(
            f"image file {target} is damaged (its SHA-256 is no longer {digest}); restore it from a backup "
            "or store the image again."
        )
    return data
