"""A mission's visits (seed §2.2-2.3, §3.1, §4.1): the arm's transit to each vista, the lamp on the orbit's
sun at the visit's mission-clock time, and the frame from where the arm holds the ISEE camera.

:class:`Tour` drives :func:`rsi.mission.transit.transit` and :mod:`rsi.mission.sun` for
:func:`rsi.mission.run_mission`. See docs/mission.md.
"""

from __future__ import annotations

import math
from collections import Counter
from dataclasses import replace
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from rsi import _validate as v
from rsi._seeds import SeedLike, keyed, seed_sequence
from rsi.errors import InputError
from rsi.mission.sun import SunSetting, lamp_move_s, light_by_sun, sun_setting
from rsi.mission.transit import Transit, transit
from rsi.mission.viewing import focal_px, look_rotation, world_arm, world_vista
from rsi.sim.capture import capture

if TYPE_CHECKING:
    from rsi.imaging.camera import Frame
    from rsi.sim.capture import Capture
    from rsi.sim.world import View, World

FloatArray = NDArray[np.float64]

FRAME_S = 1.0 / 30.0  # seed §2.2: one interlaced frame
NOMINAL_TRANSIT_S = 5.0  # mission-clock time of a visit without the arm (measured arm transits: 2-7 s)
JAW_SPEED_M_S = 0.04  # a parallel gripper's travel (no figure in the seed): the jaws' 4 cm in about a second
STAGES = ("reference", "inspection")


class Tour:
    """A mission's visits: the arm's transits, the frames from the ISEE, the lamp on the orbit's sun.

    Parameters
    ----------
    world : World
        The mission's world (with the arm when `arm`).
    seed : int or numpy.random.SeedSequence
        Seeds the visits' repeatability draws and the rangefinders' noise (the world's own streams are not
        touched, so ``arm=False, orbit=False`` visits are exactly ``World.render``'s).
    size : (int, int)
        Frame size; the repeatability error is drawn in pixels of it, as ``World.render`` draws it.
    arm : bool
        Move the arm to each reachable vista and take the frame from the ISEE; otherwise (and for vistas out
        of reach) ``World.render`` teleports the free camera.
    orbit : bool
        Light each visit by the orbit's sun at the visit's mission-clock time.
    """

    def __init__(
        self, world: World, *, seed: SeedLike, size: tuple[int, int], arm: bool = True, orbit: bool = True
    ) -> None:
        from rsi.sim.world import World, frame_size

        v.instance_of(world, "world", World, none_allowed=False)
        size = frame_size(size)
        for name, flag in (("arm", arm), ("orbit", orbit)):
            if not isinstance(flag, bool):
                raise InputError(f"{name} must be True or False; got {flag!r}.")
        if arm:
            world_arm(world)
        self.world = world
        self.size = size
        self.arm = arm
        self.orbit = orbit
        self._streams = seed_sequence(seed)
        self._visits: Counter[tuple[str, str]] = Counter()
        self.clock_s = 0.0
        self.stage = ""
        self.transits: list[Transit] = []
        self.suns: list[SunSetting] = []
        self.views: list[tuple[str, View]] = []
        self._last: Capture | None = None
        self._pre_flash: View | None = None

    def start_pass(self, stage: str, start_s: float) -> None:
        """Set the mission clock to a pass's start (seed §2.2: the passes may see different suns)."""
        self.stage = v.choice(stage, "stage", STAGES)
        self.clock_s = v.in_range(start_s, "start_s", low=0.0)

    def set_jaws(self, opening_m: float) -> None:
        """Move the gripper's jaws to `opening_m` for the next visits (seed §3.1: they lie in the cameras'
        view); the clock advances by their travel. Without the arm there are no jaws: nothing happens."""
        if not self.arm:
            return
        arm = self.world.arm
        travel = abs(arm.jaw_opening_m - opening_m)
        arm.set_jaw_opening(opening_m)
        self.clock_s += travel / JAW_SPEED_M_S

    def visit(self, label: str, vista: str, *, state: str, truth: bool = True) -> Capture:
        """Go to `vista` (plan point `label`), light it, take the frames; the clock advances.

        Returns what the ISEE gives (:class:`rsi.sim.capture.Capture`: frames, stereo pair, believed pose,
        CAD expectation). The simulator's record of the visit, its truth, goes to :attr:`views` for scoring
        (`truth` False: the frames only, no rendered truth).
        """
        if not isinstance(label, str) or not label:
            raise InputError(f"label must be a non-empty string naming the plan point; got {label!r}.")
        view = self._view(label, vista, state=state, truth=truth)
        self.views.append((label, view))
        self._pre_flash = view
        self._last = capture(self.world, view)
        return self._last

    def reflash(self, *, strobe_energy: float, shutter: float) -> Capture:
        """The last visit's frames taken again from the same pose, the strobe at `strobe_energy` times the
        seed's and the shutter at `shutter` times its (seed §2.1 metering); the stereo pair is kept."""
        if self._last is None or self._pre_flash is None:
            raise InputError("reflash needs a visit first: call Tour.visit.")
        label, _ = self.views[-1]
        # always from the visit as taken: the world's strobe and shutter settings are the ones it had
        again = self.world.reflash(self._pre_flash, strobe_energy=strobe_energy, shutter=shutter)
        self.views[-1] = (label, again)
        self._last = capture(self.world, again, cad=self._last.cad)
        return self._last

    def ambient_frame(self, *, exposure_s: float) -> Frame:
        """A frame of the last visit with no flash, its shutter open `exposure_s` seconds (seed §2 further
        work: the ambient-lit image's bracket); the clock advances by a frame."""
        if self._last is None:
            raise InputError("ambient_frame needs a visit first: call Tour.visit.")
        self.clock_s += FRAME_S
        return self.world.ambient_frame(self.views[-1][1], exposure_s=exposure_s)

    def other_strobe_frames(self) -> tuple[Frame, Frame]:
        """The last visit's two frames again with the ISEE's other strobe (seed §3 B, §2.5), from where the
        camera still stands; the clock advances by the two frames."""
        if self._last is None:
            raise InputError("other_strobe_frames needs a visit first: call Tour.visit.")
        self.clock_s += 2 * FRAME_S
        return self.world.other_strobe_frames(self.views[-1][1])

    def _view(self, label: str, vista: str, *, state: str, truth: bool) -> View:
        from rsi.sim.world import REPEATABILITY_PX

        world_vista(self.world, vista)
        # each visit draws from its own stream (the pass, the plan point, its how-many-th visit there): a
        # second look taken or not leaves every other visit's viewpoint error and noise as they were
        key = f"{self.stage}/{label}/{self._visits[self.stage, label]}"
        self._visits[self.stage, label] += 1
        self.world.begin_visit(key)
        if not self.arm:
            self.clock_s += NOMINAL_TRANSIT_S if self.orbit else 0.0
            self._light(label, vista)
            self.clock_s += FRAME_S
            return self.world.render(vista, size=self.size, state=state, truth=truth, stereo=True)
        low, high = REPEATABILITY_PX[self.world.repeatability]
        draws, noise = keyed(self._streams, key).spawn(2)
        draw = np.random.default_rng(draws)
        magnitude, angle = draw.uniform(low, high), draw.uniform(0.0, 2 * math.pi)
        # seed §2.3: the arm misses the vista by its repeatability (flexure, thermal growth: not in the
        # encoders); World.render's draw, as a goal offset
        offset_px = magnitude * np.array([math.cos(angle), math.sin(angle)])
        offset_m = offset_px * self.world.vista(vista).standoff_m / focal_px(self.size[0])
        moved = transit(
            self.world,
            vista,
            offset_m=(float(offset_m[0]), float(offset_m[1])),
            rng=np.random.default_rng(noise),
            label=label,
            stage=self.stage,
            clock_s=self.clock_s,
        )
        self.transits.append(moved)
        self.clock_s += moved.duration_s if moved.time_s.size else NOMINAL_TRANSIT_S
        self._light(label, vista)
        self.clock_s += FRAME_S
        if not moved.reached:  # documented fallback: the free camera, as without the arm
            return self.world.render(vista, size=self.size, state=state, truth=truth, stereo=True)
        view = self.world.render_from_tool(
            size=self.size,
            state=state,
            truth=truth,
            stereo=True,
            unsensed_offset_m=(float(offset_m[0]), float(offset_m[1])),
        )
        return replace(view, vista=vista, pose_error_px=self._pose_error_px(vista, moved.camera_m))

    def _pose_error_px(self, vista: str, camera_m: FloatArray) -> tuple[float, float]:
        """Image shift of the target plane caused by the camera's lateral miss, as ``World.render`` gives."""
        point = self.world.vista(vista)
        rotation = look_rotation(np.asarray(point.forward, float), np.asarray(point.up, float))
        miss = rotation[:, :2].T @ (camera_m - np.asarray(point.position_m, float))
        shift = miss * focal_px(self.size[0]) / point.standoff_m
        return (float(-shift[0]), float(shift[1]))

    def _light(self, label: str, vista: str) -> None:
        if not self.orbit:
            return
        target = self.world.vista(vista).target_m
        setting = sun_setting(target, self.clock_s, label=label, stage=self.stage)
        if self.suns:
            setting = replace(setting, lamp_move_s=lamp_move_s(self.suns[-1].lamp, setting.lamp))
        light_by_sun(self.world, setting)
        self.suns.append(setting)


__all__ = ["FRAME_S", "JAW_SPEED_M_S", "NOMINAL_TRANSIT_S", "STAGES", "Tour"]
