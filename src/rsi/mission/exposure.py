"""Exposure of each visit, metered from the pre-flash (seed §2.1-2.2): the shutter that holds sunlight down,
the strobe energy that lifts dark surfaces, and the frame taken again with them.
"""

from __future__ import annotations

from dataclasses import replace
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from rsi.mission.settings import MissionSettings
from rsi.mission.views import inspection_region

if TYPE_CHECKING:
    from rsi.sim.world import View, World


def ambient_dn(
    world: World, view: View, settings: MissionSettings, region: NDArray[np.bool_] | None = None
) -> float:
    """The pre-flash's ambient in DN at the meter percentile over the inspection region (0: none)."""
    camera = world.camera
    region = inspection_region(view, settings) if region is None else region
    if not region.any():
        return 0.0
    lux = float(np.percentile(view.ambient_lux[region], settings.meter_percentile))
    return lux * view.frame.exposure_s * camera.electrons_per_lux_s / camera.gain_e_per_dn


def metered_shutter(world: World, view: View, settings: MissionSettings) -> float:
    """Shutter (fraction of the pre-flash's) that holds the sunlit surface's ambient to the target DN.

    Seed §2.2 subtracts the ambient, so sunlight is only noise and compensation error to the strobe image:
    at the seed's shutter a sunlit aluminium face reads ~170 DN of ambient alone, and strobe plus ambient
    saturate where an impact may be. The ~20 us flash fits in any shutter down to MIN_SHUTTER.
    """
    from rsi.sim.world import MIN_SHUTTER

    ambient = ambient_dn(world, view, settings)
    if ambient <= settings.ambient_target_dn:
        return 1.0
    return float(np.clip(settings.ambient_target_dn / ambient, MIN_SHUTTER, 1.0))


def settle(world: World, *, door_angle_rad: float) -> None:
    """The door at `door_angle_rad`, the strobe and the shutter back at the seed's settings (seed §2.1)."""
    world.set_door(door_angle_rad)
    world.set_strobe_energy(1.0)
    world.set_shutter(1.0)


def metered_energy(world: World, view: View, settings: MissionSettings, shutter: float = 1.0) -> float:
    """Strobe energy that lifts the surface's brightest strobe pixels to the target DN (seed §2.1).

    The view is the pre-flash at the seed's 1.3 lm s. Dark solar cells and Kapton then read a few tens of DN,
    where read noise and 8-bit quantisation swamp a millimetre impact; more flash raises the contrast in
    proportion and the shot noise only as its square root. Never less than the seed's energy.
    """
    from rsi.sim.world import MAX_STROBE_ENERGY

    camera = world.camera
    dn_per_lux_s = camera.electrons_per_lux_s / camera.gain_e_per_dn
    region = inspection_region(view, settings)
    if not region.any():
        return 1.0
    strobe = float(np.percentile(view.strobe_lux_s[region], settings.meter_percentile)) * dn_per_lux_s
    headroom = (
        settings.strobe_target_dn
        - camera.black_level_dn
        - ambient_dn(world, view, settings, region) * shutter
    )
    if strobe <= 0.0:
        return MAX_STROBE_ENERGY
    return float(np.clip(headroom / strobe, settings.min_strobe_energy, MAX_STROBE_ENERGY))


def reflashed(world: World, view: View, energy: float, shutter: float) -> View:
    """The visit's frame taken again from the same pose, the strobe at `energy` times the pre-flash and the
    shutter at `shutter` times its own."""
    if energy == 1.0 and shutter == 1.0:
        return view
    flashed = replace(
        view,
        strobe_lux_s=(view.strobe_lux_s * np.float32(energy)).astype(np.float32),
        frame=replace(view.frame, exposure_s=view.frame.exposure_s * shutter),
    )
    return replace(flashed, frame=world.next_frame(flashed, lit_field=view.frame.lit_field))
