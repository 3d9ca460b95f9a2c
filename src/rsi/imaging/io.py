"""Read and write grey images: 8/16-bit PNG, TIFF (also float32) and JPEG, values kept in the file's DN.

Values are not rescaled: an 8-bit file reads 0..255, a 16-bit file 0..65535 and a float TIFF as stored, so a
camera's digital numbers survive a round trip and stay linear (seed §2.1: linear response is what makes
ambient subtraction valid). Colour files become grey by the luminance weights (seed §2.1: only the luminance
signal is used).
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

import cv2
import numpy as np
from numpy.typing import NDArray

from rsi._files import atomic_write_bytes
from rsi.errors import ImageFileError

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


def read_image(path: PathLike) -> NDArray[np.float32]:
    """Read an image file as a grey float32 array in the file's own digital numbers.

    Parameters
    ----------
    path : str or os.PathLike
        A PNG, TIFF or JPEG file, 8 or 16 bits per channel (or float32 TIFF), grey, BGR or BGRA.

    Returns
    -------
    ndarray of shape (M, N), float32
        Grey values on the file's scale (0..255 for 8 bits, 0..65535 for 16 bits); colour is converted with
        the Rec. 601 luminance weights before any rounding.

    Raises
    ------
    ImageFileError
        If the file is missing, unreadable, corrupt or not a supported image; the message names the path.
    """
    file = Path(path)
    if file.suffix.lower() not in READ_SUFFIXES:
        raise ImageFileError(
            f"path {str(file)!r} has suffix {file.suffix!r}, which is not supported. "
            f"Use one of {', '.join(READ_SUFFIXES)}."
        )
    try:
        data = np.frombuffer(file.read_bytes(), dtype=np.uint8)
    except OSError as error:
        raise ImageFileError(f"path {str(file)!r} cannot be read: {error.strerror or error}.") from error
    # imdecode (not imread) so that non-ASCII paths work everywhere and corrupt data is reported, not printed
    image = cv2.imdecode(data, cv2.IMREAD_UNCHANGED) if data.size else None
    if image is None:
        raise ImageFileError(
            f"path {str(file)!r} is not a readable image (corrupt, truncated or empty). Re-export the file."
        )
    return _grey(image, file)


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
    file = Path(path)
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
