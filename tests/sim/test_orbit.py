"""The orbit's sun, its eclipses, the lab exposure and the lamp path that reproduces it (seed §4.1, §2.1)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from rsi.errors import InputError
from rsi.sim import orbit as ob
from rsi.sim import solar_simulator as ss

DEG = math.pi / 180.0
# Independent constants, typed here rather than imported, so a wrong constant in the module fails a test.
MU_M3_S2 = 3.986004418e14
R_EARTH_M = 6378137.0
SPOT = (0.0, 0.0, 1.0)  # 2 m across the default rail, level with it


def test_period_of_a_400_km_orbit_is_keplers() -> None:
    a = R_EARTH_M + 400e3
    assert ob.orbital_period_s(ob.Orbit(altitude_m=400e3)) == pytest.approx(
        2 * math.pi * math.sqrt(a**3 / MU_M3_S2), abs=0.1
    )
    assert ob.orbital_period_s() == pytest.approx(92.56 * 60, abs=1.0)  # the familiar ~92.6 min


def test_critical_beta_is_the_textbook_one() -> None:
    assert ob.critical_beta_rad(400e3) == pytest.approx(math.asin(R_EARTH_M / (R_EARTH_M + 400e3)), abs=1e-12)
    assert math.degrees(ob.critical_beta_rad(400e3)) == pytest.approx(70.2, abs=0.05)
    beta_star = ob.critical_beta_rad(400e3)
    assert ob.eclipse(ob.Orbit(beta_rad=beta_star + 1e-6)).fraction == 0.0
    assert ob.eclipse(ob.Orbit(beta_rad=-beta_star - 1e-6)).entry_time_s is None
    assert ob.eclipse(ob.Orbit(beta_rad=beta_star - 1e-3)).fraction > 0.0


@pytest.mark.parametrize("beta_deg", [0.0, 30.0, -52.0, 65.0, 70.0, 75.0, 90.0])
def test_eclipse_fraction_matches_the_closed_form_and_the_geometry(beta_deg: float) -> None:
    orbit = ob.Orbit(beta_rad=beta_deg * DEG)
    h, a = 400e3, R_EARTH_M + 400e3
    cosine = math.sqrt(h * h + 2 * R_EARTH_M * h) / (a * math.cos(beta_deg * DEG) + 1e-300)
    textbook = math.acos(cosine) / math.pi if cosine < 1 else 0.0
    closed = ob.eclipse(orbit)
    assert closed.fraction == pytest.approx(textbook, abs=1e-12)
    period = ob.orbital_period_s(orbit)
    times = np.linspace(0.0, period, 200_001)[:-1]
    sampled = 1.0 - ob.in_sunlight(orbit, times).mean()
    assert sampled == pytest.approx(closed.fraction, abs=2e-5)  # one grid step is 5e-6 of an orbit
    assert closed.duration_s == pytest.approx(closed.fraction * period)


def test_eclipse_entry_and_exit_times_bracket_the_shadow() -> None:
    orbit = ob.Orbit(beta_rad=20 * DEG, start_angle_rad=-1.0)
    shadow = ob.eclipse(orbit)
    assert shadow.entry_time_s is not None and shadow.exit_time_s is not None
    assert shadow.entry_angle_rad == pytest.approx(math.pi - shadow.fraction * math.pi)
    step = 1e-3
    lit = ob.in_sunlight(
        orbit,
        [
            shadow.entry_time_s - step,
            shadow.entry_time_s + step,
            shadow.exit_time_s - step,
            shadow.exit_time_s + step,
        ],
    )
    assert lit.tolist() == [True, False, False, True]
    assert shadow.exit_time_s - shadow.entry_time_s == pytest.approx(shadow.duration_s)


@settings(max_examples=100)
@given(
    st.floats(0.0, 1e6),
    st.floats(-math.pi / 2, math.pi / 2),
    st.floats(-10.0, 10.0),
    st.floats(200e3, 2000e3),
)
def test_sun_direction_is_a_unit_vector_with_the_beta_angle(
    time_s: float, beta_rad: float, start_rad: float, altitude_m: float
) -> None:
    orbit = ob.Orbit(altitude_m=altitude_m, beta_rad=beta_rad, start_angle_rad=start_rad)
    sun = ob.sun_direction_lvlh(orbit, time_s)
    assert np.linalg.norm(sun, axis=-1) == pytest.approx(1.0, abs=1e-12)
    # y_LVLH is minus the orbit normal: the sun sits beta above the orbit plane
    assert sun[0, 1] == pytest.approx(-math.sin(beta_rad), abs=1e-12)


def test_sun_is_overhead_at_noon_rising_ahead_and_setting_behind() -> None:
    period = ob.orbital_period_s()
    sun = ob.sun_direction_lvlh(ob.Orbit(start_angle_rad=-math.pi / 2), [0.0, period / 4, period / 2])
    assert np.allclose(sun, [[1, 0, 0], [0, 0, -1], [-1, 0, 0]], atol=1e-12)  # ram, zenith (-z), wake


def test_orbit_angle_advances_at_the_orbital_rate() -> None:
    orbit = ob.Orbit(start_angle_rad=0.3)
    period = ob.orbital_period_s(orbit)
    assert ob.orbit_angle_rad(orbit, [0.0, period]) == pytest.approx([0.3, 0.3 + 2 * math.pi])


def test_lab_exposure_compensates_the_dimmer_sun() -> None:
    # seed §2.1: 130000 lux * 0.1 m^2 * 1/10000 s = 1.3 lm s of sun against a 1.3 lm s strobe; at 1.5 % of
    # sunlight the lab shutter must stay open 1/0.015 ~ 67 times longer for the same ratio.
    settings_ = ob.compensating_exposure(0.015 * 130_000)
    assert settings_.orbit_ambient_lm_s == pytest.approx(1.3)
    assert settings_.ambient_to_strobe_ratio == pytest.approx(1.0)
    assert settings_.exposure_ratio == pytest.approx(1 / 0.015)
    assert 66 < settings_.exposure_ratio < 67
    assert settings_.lab_exposure_s == pytest.approx(1e-4 / 0.015)
    assert settings_.lab_ambient_lm_s == pytest.approx(settings_.orbit_ambient_lm_s)
    assert settings_.lab_exposure_s < 1 / 60  # still inside one video field
    brighter = ob.compensating_exposure(0.03 * 130_000)
    assert brighter.lab_exposure_s == pytest.approx(settings_.lab_exposure_s / 2)


def test_exposure_rejects_a_lab_sun_too_dim_for_one_field() -> None:
    with pytest.raises(
        InputError, match=r"lab_illuminance_lux=500 .*longer than one field.*at least 780 lux"
    ):
        ob.compensating_exposure(500.0)
    with pytest.raises(InputError, match="lab_illuminance_lux"):
        ob.compensating_exposure(math.nan)
    with pytest.raises(InputError, match="strobe_lm_s"):
        ob.compensating_exposure(1950.0, strobe_lm_s=0.0)


# ------------------------------------------------------------------------------------------- sun path

REACHABLE_S = np.arange(0.0, 900.0, 10.0)  # orbit noon to ~58 deg past it: inside the rail's reach


def test_a_reachable_sun_path_is_reproduced_with_the_intensity_held() -> None:
    path = ob.sun_path(None, REACHABLE_S, spot_world_m=SPOT)
    assert not path.clipped.any()
    assert path.sunlit.all()
    assert path.target_intensity_lux == pytest.approx(1950.0)
    # issue 3 acceptance: intensity held within 1 % along a reachable sun path
    assert np.abs(path.intensity_lux / path.target_intensity_lux - 1).max() < 0.01
    assert path.direction_error_rad.max() < 1e-9
    # the light turns at the orbital rate (beta = 0: the sun moves on a great circle)
    steps = np.arccos(np.clip(np.sum(path.light_world[1:] * path.light_world[:-1], axis=1), -1, 1))
    rate = 2 * math.pi / ob.orbital_period_s()
    assert steps / np.diff(path.time_s) == pytest.approx(np.full(steps.size, rate), rel=1e-6)
    assert path.exposure.exposure_ratio == pytest.approx(1 / 0.015)


def test_the_intensity_is_held_between_samples_too() -> None:
    # The lamp moves linearly between samples; the spot stays put, so rho is the true lamp-spot distance.
    path = ob.sun_path(None, REACHABLE_S, spot_world_m=SPOT)
    middle = ss.sample_trajectory(path.trajectory, REACHABLE_S[:-1] + 5.0)
    lamps = np.column_stack(
        [middle.lambda_m, np.full(middle.lambda_m.size, -2.0), np.ones(middle.lambda_m.size)]
    )
    rho = np.linalg.norm(np.asarray(SPOT) - lamps, axis=1)
    intensity = [
        ss.spot_intensity_lux(r, ss.beam_half_angle_rad(g)) for r, g in zip(rho, middle.gamma_m, strict=True)
    ]
    assert np.abs(np.asarray(intensity) / 1950.0 - 1).max() < 0.01


def test_a_whole_orbit_keeps_every_limit_and_flags_what_it_cannot_do() -> None:
    period = ob.orbital_period_s()
    times = np.arange(0.0, period, 10.0)
    path = ob.sun_path(None, times, spot_world_m=SPOT)
    trajectory = path.trajectory
    joints = trajectory.joints
    for column, name in enumerate(ss.ACTUATED):
        low, high = ss.LIMITS[name]
        assert (joints[:, column] >= low).all() and (joints[:, column] <= high).all()
    speeds = np.abs(np.diff(joints, axis=0)) / np.diff(times)[:, None]
    assert (speeds <= ss.RateLimits().as_array() * (1 + 1e-9)).all()
    # The morning (sun ahead, world -x) lies outside the pan range: clipped and flagged.
    morning = (path.orbit_angle_rad > 1.5 * math.pi) & (path.orbit_angle_rad < 1.9 * math.pi) & path.sunlit
    assert path.direction_unreachable[morning].all()
    assert path.direction_error_rad[morning].min() > 0.1
    # In the shadow the lamp is off.
    assert (path.intensity_lux[~path.sunlit] == 0).all()
    assert (~path.sunlit).mean() == pytest.approx(ob.eclipse().fraction, abs=0.01)
    # Where nothing is flagged and the sun is up, the lab reproduces the orbit.
    good = ~path.clipped & path.sunlit
    assert good.sum() > 80
    assert np.abs(path.intensity_lux[good] / 1950.0 - 1).max() < 0.01
    assert path.direction_error_rad[good].max() <= math.radians(0.5)


def test_a_jump_beyond_the_rate_limits_is_followed_and_flagged() -> None:
    slow = ss.RateLimits(lambda_m_s=0.001)
    path = ob.sun_path(None, REACHABLE_S, spot_world_m=SPOT, rates=slow)
    assert path.rate_limited.any()
    lam = path.trajectory.lambda_m
    assert (np.abs(np.diff(lam)) / 10.0 <= 0.001 * (1 + 1e-9)).all()


def test_a_focus_range_too_narrow_to_hold_the_intensity_is_flagged() -> None:
    narrow = ss.LampOptics(spot_half_angle_rad=20 * DEG, flood_half_angle_rad=22 * DEG)
    path = ob.sun_path(None, REACHABLE_S, spot_world_m=SPOT, optics=narrow)
    assert path.focus_clipped.any()
    assert not path.focus_clipped.all()
    held = ~path.focus_clipped
    assert np.abs(path.intensity_lux[held] / 1950.0 - 1).max() < 1e-9
    assert np.abs(path.intensity_lux[path.focus_clipped] / 1950.0 - 1).min() > 1e-6


def test_out_of_plane_sun_is_flagged_when_beta_exceeds_the_tolerance() -> None:
    path = ob.sun_path(ob.Orbit(beta_rad=10 * DEG), REACHABLE_S, spot_world_m=SPOT)
    # the rail only gives directions in the plane of the rail and the spot: beta out of it is lost
    assert path.direction_unreachable.all()
    assert path.direction_error_rad == pytest.approx(np.full(REACHABLE_S.size, 10 * DEG), abs=1e-9)


def test_sun_path_is_deterministic() -> None:
    first = ob.sun_path(None, REACHABLE_S, spot_world_m=SPOT)
    second = ob.sun_path(None, REACHABLE_S, spot_world_m=SPOT)
    assert np.array_equal(first.trajectory.joints, second.trajectory.joints)


def test_sun_path_rejects_bad_input() -> None:
    with pytest.raises(InputError, match=r"time_s must be >= 0 s"):
        ob.sun_path(None, [-1.0, 0.0], spot_world_m=SPOT)
    with pytest.raises(InputError, match="time_s contains NaN"):
        ob.sun_path(None, [0.0, math.nan], spot_world_m=SPOT)
    with pytest.raises(InputError, match="strictly increasing"):
        ob.sun_path(None, [0.0, 0.0], spot_world_m=SPOT)
    with pytest.raises(InputError, match="time_s must be numbers"):
        ob.sun_path(None, ["noon"], spot_world_m=SPOT)
    with pytest.raises(InputError, match="time_s must be a scalar or a non-empty 1-D array"):
        ob.sun_path(None, [], spot_world_m=SPOT)
    with pytest.raises(InputError, match=r"spot_world_m=.*far side of the rail"):
        ob.sun_path(None, [0.0], spot_world_m=(0.0, -5.0, 1.0))
    with pytest.raises(InputError, match="spot_world_m contains NaN"):
        ob.sun_path(None, [0.0], spot_world_m=(0.0, math.nan, 1.0))
    with pytest.raises(InputError, match=r"world_from_lvlh must be a proper rotation"):
        ob.sun_path(None, [0.0], spot_world_m=SPOT, world_from_lvlh=-np.eye(3))
    with pytest.raises(InputError, match=r"world_from_lvlh must be a finite 3x3"):
        ob.sun_path(None, [0.0], spot_world_m=SPOT, world_from_lvlh=np.eye(2))
    with pytest.raises(InputError, match="world_from_lvlh must be a 3x3"):
        ob.sun_path(None, [0.0], spot_world_m=SPOT, world_from_lvlh="identity")
    with pytest.raises(InputError, match="lab_sun_fraction"):
        ob.sun_path(None, [0.0], spot_world_m=SPOT, lab_sun_fraction=0.0)
    with pytest.raises(InputError, match="direction_tolerance_rad"):
        ob.sun_path(None, [0.0], spot_world_m=SPOT, direction_tolerance_rad=math.nan)
    with pytest.raises(InputError, match="orbit must be an Orbit"):
        ob.sun_path("LEO", [0.0], spot_world_m=SPOT)  # type: ignore[arg-type]


def test_orbit_settings_reject_bad_input() -> None:
    with pytest.raises(InputError, match="altitude_m"):
        ob.Orbit(altitude_m=-1.0)
    with pytest.raises(InputError, match="beta_rad"):
        ob.Orbit(beta_rad=2.0)
    with pytest.raises(InputError, match="start_angle_rad must be finite"):
        ob.Orbit(start_angle_rad=math.inf)
    with pytest.raises(InputError, match="altitude_m"):
        ob.critical_beta_rad(0.0)
    with pytest.raises(InputError, match="time_s must be >= 0 s"):
        ob.sun_direction_lvlh(None, -5.0)
    with pytest.raises(InputError, match="time_s contains NaN"):
        ob.in_sunlight(None, [math.inf])
    with pytest.raises(InputError, match="orbit must be an Orbit"):
        ob.eclipse(400e3)  # type: ignore[arg-type]
