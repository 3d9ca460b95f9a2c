"""Feedback-controlled halogen lamps and jaw-mounted strobes (seed §2.1, §3 A-B)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from rsi.errors import InputError
from rsi.sensors.lamps import HalogenLamp, LampController, LampDisturbance, Strobe, simulate_lamp

SETTLED_S = 0.3
SETPOINT_LUX = LampController().setpoint_lux


def _worst_error_after_settling(closed_loop: bool, seed: int) -> float:
    run = simulate_lamp(3.0, closed_loop=closed_loop, rng=seed)
    return float(np.abs(run.relative_error(SETPOINT_LUX)[run.time_s >= SETTLED_S]).max())


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_feedback_holds_illumination_within_one_percent(seed: int) -> None:
    # seed §3: supply fluctuation and bulb ageing do not move the controlled illumination
    assert _worst_error_after_settling(closed_loop=True, seed=seed) < 0.01


def test_without_feedback_the_same_disturbances_move_it_far() -> None:
    assert _worst_error_after_settling(closed_loop=False, seed=0) > 0.10


def test_the_loop_compensates_ageing_by_raising_the_duty() -> None:
    run = simulate_lamp(
        3.0, disturbance=LampDisturbance(supply_noise_relative=0.0, supply_sag_per_s=0.0), rng=0
    )
    late, early = run.duty[-100:].mean(), run.duty[400:500].mean()
    # light ~ efficacy * duty^gamma: the duty must rise by efficacy^(-1/gamma)
    expected = (run.efficacy[-50] / run.efficacy[450]) ** (-1.0 / HalogenLamp().light_exponent)
    assert late / early == pytest.approx(expected, rel=0.01)


def test_duty_stays_in_range_and_runs_are_deterministic() -> None:
    first, again = simulate_lamp(1.0, rng=9), simulate_lamp(1.0, rng=9)
    np.testing.assert_array_equal(first.illuminance_lux, again.illuminance_lux)
    assert ((first.duty >= 0.0) & (first.duty <= 1.0)).all()
    assert not np.array_equal(first.supply_v, simulate_lamp(1.0, rng=10).supply_v)


def test_strobe_exposure_is_untouched_by_a_short_shutter() -> None:
    strobe = Strobe()
    # seed §2.1: 1.3 lm s over 0.1 m^2, a 20 us flash inside a 1/10000 s shutter
    assert strobe.luminous_exposure_lux_s(1e-4, 0.1) == pytest.approx(13.0)
    assert strobe.luminous_exposure_lux_s(1e-5, 0.1) == pytest.approx(6.5)


def test_strobe_angle_follows_the_jaw_opening() -> None:
    strobe = Strobe()
    openings = np.linspace(0.0, strobe.max_jaw_opening_m, 5)
    angles = strobe.illumination_angle_rad(openings, 0.2)
    assert (np.diff(angles) > 0).all()
    assert angles[0] == pytest.approx(np.arctan(0.02 / 0.31))
    assert strobe.illumination_angle_rad(0.04, 0.5) < strobe.illumination_angle_rad(0.04, 0.1)


@pytest.mark.parametrize(
    ("settings_class", "changes", "fragment"),
    [
        (HalogenLamp, {"rated_illuminance_lux": 0.0}, "rated_illuminance_lux must be in"),
        (HalogenLamp, {"supply_voltage_v": 10.0}, "supply_voltage_v must be in"),
        (HalogenLamp, {"filament_time_s": float("nan")}, "filament_time_s must be finite"),
        (LampController, {"setpoint_lux": -1.0}, "setpoint_lux must be in"),
        (LampController, {"proportional_gain": 0.0}, "proportional_gain must be in"),
        (LampController, {"sensor_noise_relative": -0.1}, "sensor_noise_relative must be in"),
        (LampDisturbance, {"supply_noise_relative": 0.5}, "supply_noise_relative must be in"),
        (LampDisturbance, {"supply_correlation_s": 0.0}, "supply_correlation_s must be in"),
        (LampDisturbance, {"supply_sag_per_s": -0.1}, "supply_sag_per_s must be in"),
        (LampDisturbance, {"ageing_per_s": -0.1}, "ageing_per_s must be in"),
        (Strobe, {"pulse_s": 0.0}, "pulse_s must be in"),
        (Strobe, {"luminous_energy_lm_s": -1.0}, "luminous_energy_lm_s must be in"),
        (Strobe, {"mount_offset_m": -0.01}, "mount_offset_m must be in"),
        (Strobe, {"setback_m": -0.01}, "setback_m must be in"),
        (Strobe, {"max_jaw_opening_m": 0.0}, "max_jaw_opening_m must be in"),
    ],
)
def test_settings_reject_each_bad_field_by_name(
    settings_class: type, changes: dict[str, float], fragment: str
) -> None:
    with pytest.raises(InputError, match=fragment):
        dataclasses.replace(settings_class(), **changes)


def test_functions_reject_bad_arguments_by_name() -> None:
    with pytest.raises(InputError, match="duration_s must be in"):
        simulate_lamp(0.0)
    with pytest.raises(InputError, match="burns the bulb out"):
        simulate_lamp(30.0)
    with pytest.raises(InputError, match="exposure_s must be in"):
        Strobe().luminous_exposure_lux_s(0.0, 0.1)
    with pytest.raises(InputError, match="scene_area_m2 must be in"):
        Strobe().luminous_exposure_lux_s(1e-4, -0.1)
    with pytest.raises(InputError, match=r"jaw_opening_m must lie in \[0, 0.08\] m"):
        Strobe().illumination_angle_rad(0.1, 0.2)
    with pytest.raises(InputError, match="standoff_m must be finite and >= 0 m"):
        Strobe().illumination_angle_rad(0.04, float("nan"))
