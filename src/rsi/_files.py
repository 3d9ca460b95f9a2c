"""Atomic file writes shared by every package: nothing already stored is ever half-overwritten."""

from __future__ import annotations

import contextlib
import os
import tempfile
from pathlib import Path


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
    OSError
        If the folder or file cannot be written.
    """
    target = Path(path)
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
