"""The orbit's sun on the mock-up, for the console (seed §4.1): the mission's own sun on the lamp."""

from __future__ import annotations

import math
from typing import Any

from rsi.mission.sun import light_by_sun, sun_setting
from rsi.sim.orbit import orbital_period_s
from rsi.sim.world import World

# The lamp lights the front of the middle bay, where the ISEE works from its home pose (rsi.sim.world).
SPOT_M = (0.9, -0.47, 1.2)


def sun_at(world: World, time_s: float) -> dict[str, Any]:
    """Pose the lamp as the orbit's sun at `time_s` (off in the Earth's shadow); the setting as JSON."""
    setting = sun_setting(SPOT_M, time_s)
    light_by_sun(world, setting)
    period_s = orbital_period_s()
    return {
        "orbit_angle_deg": round(math.degrees(setting.orbit_angle_rad), 2),
        "orbit_fraction": round((time_s % period_s) / period_s, 4),
        "period_s": round(period_s, 1),
        "sunlit": setting.sunlit,
        "sun_world": [round(x, 4) for x in setting.sun_world],
        "direction_error_deg": round(math.degrees(setting.direction_error_rad), 3),
        "reachable": setting.reachable,
    }
