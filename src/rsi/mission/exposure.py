"""Exposure of each visit, metered from the pre-flash's pixels (seed §2.1-2.2): the shutter that holds
sunlight down, the strobe energy that lifts dark surfaces, and the frame taken again with them.

The meter reads the camera's digital numbers, as a camera's does: the unlit field of the interlaced
pre-flash is the ambient alone, and the lit field less that ambient (seed §2.2 compensation) is the strobe.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from rsi.constants import FIELD_S, SHUTTER_S
from rsi.mission.settings import MissionSettings
from rsi.mission.views import Sensed, inspection_region, reflashed

if TYPE_CHECKING:
    from rsi.imaging.bracket import AmbientImage
    from rsi.imaging.camera import Frame
    from rsi.mission.tour import Tour
    from rsi.sim.world import World

# a percentile within this many DN of the sensor's top may be clipped: the reading is a lower bound
_CLIPPED_DN = 3.0
# pre-flashes the meter may take before it settles (a clipped ambient shrinks the shutter each time)
_METER_TRIES = 3
# a clipped pre-flash is taken again this much weaker: two steps span the strobe's 1..0.1 of the seed's
_FLASH_STEP = 4.0


def unlit_rows(frame: Frame) -> NDArray[np.bool_]:
    """Pixels of the rows the strobe did not light in `frame` (seed §2.2: the ambient alone)."""
    rows = np.arange(frame.raw.shape[0])[:, None] % 2
    return np.broadcast_to((rows == 0) if frame.lit_field == "odd" else (rows == 1), frame.raw.shape)


def ambient_dn(sensed: Sensed, settings: MissionSettings, region: NDArray[np.bool_] | None = None) -> float:
    """The pre-flash's ambient in DN above black at the meter percentile over the inspection region (0: none).

    Read on the unlit field's rows (seed §2.2: they hold the ambient alone).
    """
    frame = sensed.capture.frames[0]
    region = inspection_region(sensed, settings) if region is None else region
    pixels = region & unlit_rows(frame)
    if not pixels.any():
        return 0.0
    level = float(np.percentile(frame.raw[pixels], settings.meter_percentile))
    return max(level - frame.camera.black_level_dn, 0.0)


def strobe_dn(sensed: Sensed, settings: MissionSettings, region: NDArray[np.bool_] | None = None) -> float:
    """The pre-flash's strobe alone in DN at the meter percentile: the lit rows less their ambient."""
    from rsi.imaging.compensation import compensate_interlaced

    frame = sensed.capture.frames[0]
    region = inspection_region(sensed, settings) if region is None else region
    field = compensate_interlaced(frame)
    start = 1 if frame.lit_field == "odd" else 0
    pixels = region[start::2][: field.image.shape[0]] & field.valid
    if not pixels.any():
        return 0.0
    return float(np.percentile(field.image[pixels], settings.meter_percentile))


def clipped(sensed: Sensed, settings: MissionSettings) -> bool:
    """Whether the ambient reading sits at the sensor's top (the true ambient may be far brighter)."""
    camera = sensed.capture.frames[0].camera
    top = 2**camera.bits - 1 - camera.black_level_dn
    return bool(ambient_dn(sensed, settings) >= top - _CLIPPED_DN)


def flash_clipped(sensed: Sensed, settings: MissionSettings) -> bool:
    """Whether the lit rows read at the sensor's top at the meter percentile: the strobe reading is then a
    lower bound (close to a glossy surface, the flash's 1/d^2 and its specular return saturate the sensor)."""
    frame = sensed.capture.frames[0]
    pixels = inspection_region(sensed, settings) & ~unlit_rows(frame)
    if not pixels.any():
        return False
    top = 2**frame.camera.bits - 1
    return bool(np.percentile(frame.raw[pixels], settings.meter_percentile) >= top - _CLIPPED_DN)


def metered_shutter(sensed: Sensed, settings: MissionSettings, taken_at: float = 1.0) -> float:
    """Shutter (fraction of the seed's) that holds the sunlit surface's ambient to the target DN.

    `taken_at` is the shutter the pre-flash was taken with. Seed §2.2 subtracts the ambient, so sunlight is
    only noise and compensation error to the strobe image: at the seed's shutter a sunlit aluminium face reads
    ~170 DN of ambient alone, and strobe plus ambient saturate where an impact may be. The ~20 us flash fits
    in any shutter down to MIN_SHUTTER.
    """
    from rsi.sim.world import MIN_SHUTTER

    ambient = ambient_dn(sensed, settings) / taken_at
    if ambient <= settings.ambient_target_dn:
        return 1.0
    return float(np.clip(settings.ambient_target_dn / ambient, MIN_SHUTTER, 1.0))


def settle(world: World, *, door_angle_rad: float) -> None:
    """The door at `door_angle_rad`, the strobe and the shutter back at the seed's settings (seed §2.1)."""
    world.set_door(door_angle_rad)
    world.set_strobe_energy(1.0)
    world.set_shutter(1.0)


def metered_energy(
    sensed: Sensed,
    settings: MissionSettings,
    shutter: float = 1.0,
    taken_at: float = 1.0,
    flashed_at: float = 1.0,
) -> float:
    """Strobe energy that brings the surface's brightest strobe pixels to the target DN (seed §2.1).

    The view is the pre-flash at `flashed_at` times the seed's 1.3 lm s, its shutter `taken_at`; `shutter`
    the one the frame will be taken with. Close to a glossy surface the seed's flash saturates the sensor
    and a weaker one is metered; far from a dark one a stronger. Dark solar cells and Kapton then read a
    few tens of DN, where read noise and 8-bit quantisation swamp a millimetre impact; more flash raises the
    contrast in proportion and the shot noise only as its square root. Never less than
    ``settings.min_strobe_energy``.
    """
    from rsi.sim.world import MAX_STROBE_ENERGY

    region = inspection_region(sensed, settings)
    if not region.any():
        return 1.0
    strobe = strobe_dn(sensed, settings, region)
    camera = sensed.capture.frames[0].camera
    headroom = (
        settings.strobe_target_dn
        - camera.black_level_dn
        - ambient_dn(sensed, settings, region) * shutter / taken_at
    )
    if strobe <= 0.0:
        return MAX_STROBE_ENERGY
    return float(np.clip(flashed_at * headroom / strobe, settings.min_strobe_energy, MAX_STROBE_ENERGY))


def metered(tour: Tour, sensed: Sensed, settings: MissionSettings) -> tuple[Sensed, float, float]:
    """The visit taken again at its metered shutter and strobe energy: (visit, shutter, energy).

    A clipped ambient is only a lower bound, so the meter shortens the shutter and looks again, up to
    ``_METER_TRIES`` pre-flashes; a clipped flash likewise, at a ``_FLASH_STEP`` weaker flash each time (not
    below ``settings.min_strobe_energy``). The strobe energy is then metered from the last one.
    """
    from rsi.sim.world import MIN_SHUTTER

    taken_at = 1.0
    shutter = metered_shutter(sensed, settings, taken_at)
    for _ in range(_METER_TRIES - 1):
        if not clipped(sensed, settings) or taken_at <= MIN_SHUTTER:
            break
        sensed = reflashed(sensed, tour.reflash(strobe_energy=1.0, shutter=shutter))
        taken_at = shutter
        shutter = min(metered_shutter(sensed, settings, taken_at), taken_at)
    flashed_at = 1.0
    for _ in range(_METER_TRIES - 1):
        if not flash_clipped(sensed, settings) or flashed_at <= settings.min_strobe_energy:
            break
        flashed_at = max(flashed_at / _FLASH_STEP, settings.min_strobe_energy)
        sensed = reflashed(sensed, tour.reflash(strobe_energy=flashed_at, shutter=shutter))
        taken_at = shutter
    energy = metered_energy(sensed, settings, shutter, taken_at, flashed_at)
    if energy != flashed_at or shutter != taken_at:
        sensed = reflashed(sensed, tour.reflash(strobe_energy=energy, shutter=shutter))
    return sensed, shutter, energy


def shortened(
    tour: Tour, sensed: Sensed, settings: MissionSettings, *, shutter: float, energy: float
) -> tuple[Sensed, float]:
    """A later visit taken again at a shorter shutter where its sun is brighter than the metered one's:
    (visit, shutter).

    The inspection pass keeps the reference's strobe energy, so that both passes' strobe images match
    (seed §2.3 fits only a small gain). The shutter is free: the ~20 us flash fits in any shutter
    (seed §2.1), so shortening it changes the ambient alone, and a sun that moved onto the surface since the
    reference would otherwise saturate strobe and ambient together where an impact may be. Never longer
    than `shutter`: a dimmer sun needs nothing.
    """
    from rsi.sim.world import MIN_SHUTTER

    taken_at = shutter
    for _ in range(_METER_TRIES):
        shorter = min(metered_shutter(sensed, settings, taken_at), taken_at)
        if shorter >= taken_at or taken_at <= MIN_SHUTTER:
            break
        sensed = reflashed(sensed, tour.reflash(strobe_energy=energy, shutter=shorter))
        taken_at = shorter
        if not clipped(sensed, settings):
            break
    return sensed, taken_at


# An ambient-only frame needs no headroom for a flash: the brightest 0.5 % of the surface lifted to this DN
# keep 55 DN below the 8-bit top for the sun's change over a visit
_AMBIENT_FRAME_DN = 200.0
# a pixel under this many DN above black is in shadow for the bracket: 8-bit steps and read noise are
# >= 10 % of its reading (seed §1: "a large dynamic range with sharp shadows")
_SHADOW_DN = 10.0
# each longer frame of the bracket opens the shutter this much more: four stops, a 10 DN shadow to 160 DN
_BRACKET_STEP = 16.0
# the camera's longest electronic shutter, one video field (seed §2.1: 1/60 s), in the seed's 1/10000 s
MAX_AMBIENT_SHUTTER = FIELD_S / SHUTTER_S
# frames past the strobe pair: the metered ambient frame and the shadows' two steps reach 256 x its shutter
_MAX_AMBIENT_FRAMES = 3


def ambient_bracket(tour: Tour, sensed: Sensed, settings: MissionSettings, *, shutter: float) -> AmbientImage:
    """The visit's ambient-lit image (seed §2 further work): the unlit rows of its two strobe frames
    (shutter `shutter`, a fraction of the seed's), and ambient-only frames at longer shutters metered from
    the pixels, merged (:func:`rsi.imaging.bracket.merge_ambient`).

    The strobe frames' shutter holds sunlight down for the flash (:func:`metered_shutter`), so the ambient
    reads a few tens of DN. The first frame lifts the brightest 0.5 % of the inspected surface to
    ``_AMBIENT_FRAME_DN``; where more than 0.5 % of it then still reads under ``_SHADOW_DN``, the next opens
    the shutter ``_BRACKET_STEP`` times longer, while that lifts the shadows at all (a shadow no light
    reaches stays black however long the shutter) and up to one video field. The strobe frames' readings
    keep the sunlit pixels the longer frames clip.
    """
    from rsi.imaging.bracket import merge_ambient
    from rsi.sim.world import MAX_EXPOSURE_S

    frames = list(sensed.capture.frames)
    seconds_per_shutter = frames[0].exposure_s / shutter
    # the laboratory's dimmer sun is taken with a longer shutter for the same ratio (seed §2.1's practical
    # note): its field's worth may pass the camera's longest exposure
    longest = min(MAX_AMBIENT_SHUTTER, MAX_EXPOSURE_S / seconds_per_shutter)
    region = inspection_region(sensed, settings)
    bright = ambient_dn(sensed, settings, region)
    # no ambient at all in view (a face the sun does not reach): one field's exposure shows what is there
    longer = shutter * _AMBIENT_FRAME_DN / bright if bright >= _SHADOW_DN / _BRACKET_STEP else longest
    while len(frames) < 2 + _MAX_AMBIENT_FRAMES and shutter < longer:
        longer = min(longer, longest)
        frames.append(tour.ambient_frame(exposure_s=seconds_per_shutter * longer))
        if longer >= longest or not _shadows_to_lift(frames, region, settings):
            break
        longer *= _BRACKET_STEP
    return merge_ambient(frames)


def _shadows_to_lift(frames: list[Frame], region: NDArray[np.bool_], settings: MissionSettings) -> bool:
    """Whether more than the meter's 0.5 % of `region` reads under ``_SHADOW_DN`` in the last frame and a
    longer shutter may lift it: the first ambient frame's shadows may be lit faintly; a later frame that
    read them no brighter than the one before shows no light reaches them."""
    last = frames[-1]
    dark = region & (last.raw.astype(np.float32) - np.float32(last.camera.black_level_dn) < _SHADOW_DN)
    if dark.sum() <= (1.0 - settings.meter_percentile / 100.0) * region.sum():
        return False
    first_ambient = len(frames) == 3  # the two strobe frames' unlit rows before it
    return first_ambient or _mean_dn(last, dark) > _mean_dn(frames[-2], dark) + 1.0


def _mean_dn(frame: Frame, pixels: NDArray[np.bool_]) -> float:
    """Mean reading above black of `frame` over `pixels` (0 where none)."""
    if not pixels.any():
        return 0.0
    return float(frame.raw[pixels].mean()) - frame.camera.black_level_dn


# run_mission's internals, no public API (PEP 8: an empty __all__): every caller is
# :func:`rsi.mission.run_mission`, with values it built and checked (docs/reliability.md).
__all__: list[str] = []
