"""Canonical, rounded form of a mock-up's geometry: what pins the truss layout (test_layouts.py)."""

from __future__ import annotations

import dataclasses
from typing import Any

import numpy as np

DECIMALS = 9  # 1 nm: far below a pixel, above the last-bit noise of re-ordered float sums


def canonical(value: Any) -> Any:
    """Dataclasses, mappings and sequences as plain JSON values, floats rounded to `DECIMALS`."""
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        fields = {f.name: canonical(getattr(value, f.name)) for f in dataclasses.fields(value)}
        return {"__type__": type(value).__name__, **fields}
    if isinstance(value, dict):
        return {str(key): canonical(item) for key, item in value.items()}
    if isinstance(value, (tuple, list, np.ndarray)):
        return [canonical(item) for item in value]
    if isinstance(value, (bool, str)) or value is None:
        return value
    if isinstance(value, (int, np.integer)):
        return int(value)
    number = round(float(value), DECIMALS)
    return 0.0 if number == 0.0 else number


def mockup_geometry(mockup: Any) -> dict[str, Any]:
    """What the simulator and the mission read of a mock-up, canonical."""
    hinge = getattr(mockup, "door_hinge_m", None)
    if hinge is None:
        hinge = mockup.door.hinge_m
    return {
        "parts": canonical(mockup.parts),
        "door_hinge_m": canonical(hinge),
        "candidates": canonical(mockup.candidates),
        "vistas": canonical(mockup.vistas),
        "components": canonical(mockup.components),
    }
