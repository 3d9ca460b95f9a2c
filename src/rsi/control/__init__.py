"""Seed §3.1: proximity-based arm control as pure functions (distances in, velocities out).

- :mod:`rsi.control.proximity_law`  the piecewise-linear velocity law, regions A-F, avoidance and servo
- :mod:`rsi.control.blending`       Fig. 4: joystick + trajectory + proximity, two sensors combined

Sign convention: velocities along the sensor axis are positive toward the surface (a joystick push).
"""

from __future__ import annotations

from rsi.control.blending import BlendedCommand, blend_commands, law_distance_m, proximity_term
from rsi.control.proximity_law import ProximityCommand, ProximityLaw, proximity_velocity

__all__ = [
    "BlendedCommand",
    "ProximityCommand",
    "ProximityLaw",
    "blend_commands",
    "law_distance_m",
    "proximity_term",
    "proximity_velocity",
]
