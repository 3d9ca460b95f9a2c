"""Lazy public names for a package (PEP 562): ``import rsi.x`` stays cheap, a name loads its module on use."""

from __future__ import annotations

import importlib
from collections.abc import Callable, Mapping
from typing import Any


def lazy_getattr(package: str, modules_of: Mapping[str, str]) -> Callable[[str], Any]:
    """A module ``__getattr__`` that imports ``modules_of[name]`` the first time `name` is asked for.

    Parameters
    ----------
    package : str
        The package's ``__name__`` (for the error message).
    modules_of : mapping of str to str
        Public name -> the module that defines it.
    """

    def attribute(name: str) -> Any:
        if name in modules_of:
            return getattr(importlib.import_module(modules_of[name]), name)
        raise AttributeError(f"module {package!r} has no attribute {name!r}")

    return attribute
