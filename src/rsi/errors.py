"""Errors raised by rsi.

Every error names the argument, the value it got and how to fix it, so a user can act on the message alone.
"""

from __future__ import annotations


class RsiError(Exception):
    """Base class of every error rsi raises on purpose."""


class InputError(RsiError, ValueError):
    """An argument has the wrong type, shape, dtype, value or range."""


class FileError(InputError):
    """A file or folder is missing, unreadable, corrupt or of the wrong kind."""


class ImageFileError(FileError):
    """An image file is missing, unreadable or of an unsupported kind."""


class ConvergenceError(RsiError):
    """An iterative method could not produce a usable answer (registration reports, it does not raise)."""


class DatasetError(FileError):
    """A dataset folder does not have the documented layout."""
