"""Files shared by every package: atomic writes (nothing stored is ever half-overwritten) and bounded reads
(only a regular file, only up to a size: a FIFO, a device or a huge file never hangs or floods a process)."""

from __future__ import annotations

import contextlib
import os
import stat
import tempfile
from pathlib import Path

from rsi.errors import FileError, InputError


def _read_umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


# mkstemp makes private (0600) files; a written file gets the permissions a plain open() would give it.
_FILE_MODE = 0o666 & ~_read_umask()


def atomic_write_bytes(path: str | os.PathLike[str], data: bytes) -> Path:
    """Write `data` to `path` atomically: a temporary file in the same folder, fsync, then ``os.replace``.

    Readers see the old file or the whole new one, never a part; on any failure the old file is kept and the
    temporary removed. The folder is created if missing.

    Parameters
    ----------
    path : str or os.PathLike
        Destination.
    data : bytes
        File contents.

    Returns
    -------
    Path
        The destination.

    Raises
    ------
    FileError
        `path` names something that is not a regular file (a device, a FIFO, a folder): replacing it would
        swap the node itself (run as root, ``/dev/zero`` became a 4-byte file) (issue 17).
    OSError
        If the folder or file cannot be written.
    """
    target = Path(path)
    if target.exists() and not target.is_file():
        raise FileError(
            f"path {str(target)!r} is not a regular file (a device, FIFO or folder); nothing was written. "
            "Choose a file path."
        )
    target.parent.mkdir(parents=True, exist_ok=True)
    handle, temporary = tempfile.mkstemp(dir=target.parent, prefix=f".{target.name}.", suffix=".tmp")
    try:
        with os.fdopen(handle, "wb") as stream:
            stream.write(data)
            stream.flush()
            os.fsync(stream.fileno())
        os.chmod(temporary, _FILE_MODE)
        os.replace(temporary, target)
    except BaseException:
        with contextlib.suppress(FileNotFoundError):
            os.unlink(temporary)
        raise
    return target


def read_regular_file(
    path: str | os.PathLike[str],
    *,
    max_bytes: int,
    error: type[FileError] = FileError,
    too_big: str = "raise the limit if the file is genuine",
) -> bytes:
    """The bytes of a regular file of at most `max_bytes`; anything else raises `error` naming the path.

    The file is opened without blocking (a FIFO with no writer would otherwise wait forever) and checked on
    the open descriptor: a folder, FIFO, socket or device, or a link to one, is refused before a byte is
    read, as is a file larger than `max_bytes` (`too_big` says what to do about it).

    Raises
    ------
    FileError (or `error`)
        Missing, unreadable, not a regular file, or too large.
    """
    file = Path(path)
    try:
        descriptor = os.open(file, os.O_RDONLY | os.O_NONBLOCK)
    except ValueError:  # a NUL in the name: no file has one
        raise error(f"path {str(file)!r} holds a NUL character; pass a file path without one.") from None
    except OSError as failure:
        raise error(f"path {str(file)!r} cannot be read: {failure.strerror or failure}.") from failure
    try:
        status = os.fstat(descriptor)
        if not stat.S_ISREG(status.st_mode):
            raise error(
                f"path {str(file)!r} is not a regular file (a folder, FIFO, socket or device, or a link to "
                "one); pass a file."
            )
        if status.st_size > max_bytes:
            raise error(f"path {str(file)!r} is {status.st_size} bytes, over {max_bytes}: {too_big}.")
        with os.fdopen(os.dup(descriptor), "rb") as stream:
            # The size it has, and one byte more to see it grow (reading max_bytes + 1 at once would first
            # allocate that many: a gigabyte for an image's limit, a third of reading a DeepPCB JPEG).
            data = stream.read(min(status.st_size, max_bytes) + 1)
            if len(data) > status.st_size:
                data += stream.read(max_bytes + 1 - len(data))
    except OSError as failure:
        raise error(f"path {str(file)!r} cannot be read: {failure.strerror or failure}.") from failure
    finally:
        os.close(descriptor)
    if len(data) > max_bytes:  # it grew after the size check
        raise error(f"path {str(file)!r} is over {max_bytes} bytes: {too_big}.")
    return data


MAX_NAME_CHARS = 255 - 16
"""Longest file or folder name written: the file system's 255 bytes less the temporary name's dot, random
part and ``.tmp`` (:func:`atomic_write_bytes`)."""


def name_fits(path: Path, name: str) -> None:
    """Raise FileError naming `name` when a part of `path` is longer than the file system takes, or when it
    holds a NUL (no file system takes one; Python's own error would not name the argument)."""
    if "\x00" in str(path):
        raise FileError(f"{name}={str(path)[:60]!r} holds a NUL character; no file name can. Remove it.")
    for part in path.parts:
        if len(os.fsencode(part)) > MAX_NAME_CHARS:
            raise FileError(
                f"{name}={str(path)[:60]!r}... has a name of {len(os.fsencode(part))} bytes; the file system "
                f"takes at most {MAX_NAME_CHARS} per folder or file name here. Choose a shorter name."
            )


def writable_folder(out_dir: object, name: str) -> tuple[Path, Path | None]:
    """`out_dir` as a folder that can be written, checked before any work is done.

    Returns the folder and the outermost folder a writer will have to create (None if it exists).

    Raises
    ------
    InputError
        `out_dir` is not a path.
    FileError
        It is a file, lies under a file, or cannot be written by this user.
    """
    if not isinstance(out_dir, (str, os.PathLike)) or not str(out_dir):
        raise InputError(f"{name} must be a folder path (str or pathlib.Path); got {out_dir!r:.60}.")
    folder = Path(out_dir)
    name_fits(folder, name)
    existing, missing = folder, None
    while not existing.exists() and existing.parent != existing:
        existing, missing = existing.parent, existing
    if not existing.is_dir():
        where = "is a file" if existing == folder else f"lies under {str(existing)!r}, which is a file"
        raise FileError(
            f"{name}={str(folder)!r} {where}, not a folder; nothing was written. "
            "Choose an existing folder or a path where one can be created."
        )
    if not os.access(existing, os.W_OK | os.X_OK):
        raise FileError(
            f"{name}={str(folder)!r} cannot be written: {str(existing)!r} is not writable by this user; "
            "nothing was written. Choose a folder you can write to."
        )
    return folder, missing
