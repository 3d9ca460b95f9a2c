"""The solar simulator's lamp on the orbit's sun at a visit's mission-clock time (issue 5 item 1; seed §4.1):
the sun reproduced on ORU A, the nearest direction recorded where the rail cannot, eclipse, bad input."""

from __future__ import annotations

import math
import os
from collections.abc import Iterator

import numpy as np
import pytest

os.environ.setdefault("MUJOCO_GL", "egl")

from rsi.errors import InputError
from rsi.mission import MissionSettings, plan_vistas
from rsi.mission.sun import lab_world_from_lvlh, lamp_light_direction, light_by_sun, pass_starts, sun_setting
from rsi.sim import orbit as orbits
from rsi.sim.world import World, load

SEED = 0
TINY = (64, 80)
PERIOD_S = orbits.orbital_period_s()


@pytest.fixture(scope="module")
def world() -> Iterator[World]:
    built = load("truss", seed=SEED)
    plan_vistas(built, MissionSettings(plan="hand"))  # the hand plan's panel view from above
    yield built
    built.close()


def _angle(first: np.ndarray, second: np.ndarray) -> float:
    return float(np.arctan2(np.linalg.norm(np.cross(first, second)), np.dot(first, second)))


# --------------------------------------------------------------------------------------------- sun


def _sun_world(time_s: float) -> np.ndarray:
    """The orbit's sun in the lab, computed independently of sun_setting."""
    return np.asarray(orbits.sun_direction_lvlh(orbits.Orbit(), time_s)[0] @ lab_world_from_lvlh().T)


def test_the_lamp_gives_the_orbits_sun_on_oru_a(world: World) -> None:
    spot = world.vista("A_kapton").target_m
    for time_s in (0.0, 250.0, 500.0, 800.0):
        setting = sun_setting(spot, time_s)
        light_by_sun(world, setting)
        assert setting.sunlit and setting.reachable and world.lamp_on
        assert _angle(lamp_light_direction(world, spot), _sun_world(time_s)) < 1e-6
        assert setting.intensity_lux == pytest.approx(1950.0) and not setting.focus_clipped


def test_an_unreachable_sun_gets_the_nearest_lamp_direction_recorded(world: World) -> None:
    # before orbit noon the sun rises from the -x side; the lamp's pan range only lights from +x (seed §4.1)
    spot = world.vista("A_kapton").target_m
    setting = sun_setting(spot, PERIOD_S - 300.0)
    light_by_sun(world, setting)
    measured = _angle(lamp_light_direction(world, spot), _sun_world(PERIOD_S - 300.0))
    assert not setting.reachable and setting.direction_error_rad == pytest.approx(measured, abs=1e-9)
    assert setting.direction_error_rad == pytest.approx(2 * math.pi * 300.0 / PERIOD_S, abs=1e-6)
    # the panel's top lies out of the rail's plane through ORU A: recorded, not hidden
    top = world.vista("C_panel_west_front").target_m
    panel = sun_setting(top, 400.0)
    light_by_sun(world, panel)
    assert not panel.reachable and panel.direction_error_rad > math.radians(5)
    assert panel.direction_error_rad == pytest.approx(
        _angle(lamp_light_direction(world, top), _sun_world(400.0)), abs=1e-9
    )


def test_in_eclipse_the_lamp_is_off_and_frames_get_no_sun(world: World) -> None:
    midnight = PERIOD_S / 2
    setting = sun_setting(world.vista("B_tank").target_m, midnight)
    assert not setting.sunlit and setting.intensity_lux == 0.0
    light_by_sun(world, setting)
    assert not world.lamp_on and world.readouts()["lamp_intensity_lux"] == 0.0
    dark = world.render("A_kapton", size=TINY, truth=False)
    assert not dark.ambient_lux.any() and dark.strobe_lux_s.any()
    light_by_sun(world, sun_setting(world.vista("B_tank").target_m, 400.0))
    assert world.lamp_on and world.render("A_kapton", size=TINY, truth=False).ambient_lux.any()


def test_bad_input_names_the_argument(world: World) -> None:
    cases = [
        (lambda: sun_setting((0.3, -0.47, 1.2), -5.0), "time_s"),
        (lambda: sun_setting((0.3, -0.47, 1.2), math.nan), "time_s"),
        (lambda: sun_setting((0.3, -0.47, 1.2), "noon"), "time_s"),  # type: ignore[arg-type]
        (lambda: light_by_sun(world, "noon"), "setting"),  # type: ignore[arg-type]
        (lambda: pass_starts((400.0,)), "orbit_start_s"),
        (lambda: pass_starts((400.0, -1.0)), "orbit_start_s"),
        (lambda: world.switch_lamp("on"), "on"),  # type: ignore[arg-type]
    ]
    for call, argument in cases:
        with pytest.raises(InputError) as caught:
            call()
        assert argument in str(caught.value), (argument, str(caught.value))
