"""Fig. 4 blending (seed §3.1): the sum, nearer reading for avoidance, mean for servoing, range handling."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from rsi.control.blending import blend_commands, proximity_term
from rsi.control.proximity_law import ProximityLaw, proximity_velocity
from rsi.errors import InputError

LAW = ProximityLaw()
readings_m = st.one_of(st.floats(0.0, 1.0), st.just(float("inf")))


def test_command_is_joystick_plus_trajectory_plus_proximity() -> None:
    command = blend_commands(0.02, -0.01, [0.15, 0.5], LAW)
    expected_proximity = proximity_velocity(0.15, LAW).velocity_m_s
    assert command.proximity_m_s == pytest.approx(expected_proximity)
    assert command.velocity_m_s == pytest.approx(0.02 - 0.01 + expected_proximity)
    assert command.nearest_m == 0.15


@settings(max_examples=80, deadline=None)
@given(first=readings_m, second=readings_m, mode=st.sampled_from(["avoidance", "servo"]))
def test_repulsion_is_never_weaker_than_avoidance_at_the_nearer_reading(
    first: float, second: float, mode: str
) -> None:
    velocity, nearest, _ = proximity_term([first, second], LAW, mode=mode)
    repulsion = proximity_velocity(nearest, LAW).velocity_m_s
    if repulsion < 0 or mode == "avoidance":
        assert velocity <= repulsion + 1e-15
    else:  # the nearer sensor is beyond the standoff: servoing may attract, never repel
        assert velocity >= 0.0


@settings(max_examples=80, deadline=None)
@given(
    near=st.floats(0.0, LAW.hold_distance_m),
    other=readings_m,
    joystick_fraction=st.floats(-1.0, 1.0),
    mode=st.sampled_from(["avoidance", "servo"]),
)
def test_one_sensor_in_c_means_no_joystick_can_push_in(
    near: float, other: float, joystick_fraction: float, mode: str
) -> None:
    joystick = joystick_fraction * LAW.joystick_speed_m_s
    command = blend_commands(joystick, 0.0, [near, other], LAW, mode=mode)
    assert command.velocity_m_s <= 1e-15


def test_servoing_follows_the_mean_beyond_the_standoff() -> None:
    readings = [LAW.standoff_m + 0.01, LAW.standoff_m + 0.05]
    velocity, _, _ = proximity_term(readings, LAW, mode="servo")
    expected = proximity_velocity(np.mean(readings), LAW, mode="servo").velocity_m_s
    assert velocity == pytest.approx(expected)
    assert velocity > proximity_velocity(readings[0], LAW, mode="servo").velocity_m_s


def test_avoidance_mode_does_not_attract() -> None:
    velocity, _, _ = proximity_term([LAW.standoff_m + 0.05] * 2, LAW, mode="avoidance")
    assert velocity == 0.0


def test_out_of_range_sensors_are_ignored_and_none_valid_is_flagged() -> None:
    readings = np.array([[np.inf, 0.35], [0.9, 0.35], [0.35, 0.35], [np.inf, 0.8]])
    command = blend_commands(np.zeros(4), 0.0, readings, LAW, mode="servo")
    assert command.proximity_m_s[:3] == pytest.approx([command.proximity_m_s[2]] * 3)
    assert command.no_valid_reading.tolist() == [False, False, False, True]
    assert command.proximity_m_s[3] == 0.0
    assert np.isinf(command.nearest_m[3])


def test_too_near_readings_are_kept_and_retreat() -> None:
    command = blend_commands(0.0, 0.0, [0.01, np.inf], LAW)
    assert command.proximity_m_s == -LAW.retreat_speed_m_s


@pytest.mark.parametrize(
    ("joystick", "trajectory", "distances", "fragment"),
    [
        (0.06, 0.0, [0.3, 0.3], r"joystick_m_s must lie in \[-0.05, 0.05\]"),
        (float("nan"), 0.0, [0.3, 0.3], "joystick_m_s contains NaN"),
        (0.0, float("inf"), [0.3, 0.3], "trajectory_m_s contains NaN or inf"),
        (0.0, 0.0, [-0.3, 0.3], "distances_m must be >= 0 m"),
        (0.0, 0.0, [float("nan"), 0.3], "distances_m contains NaN"),
        (0.0, 0.0, 0.3, r"distances_m must have shape \(..., sensors\)"),
        (0.0, 0.0, np.zeros((2, 0)), r"distances_m must have shape \(..., sensors\)"),
    ],
)
def test_blend_rejects_bad_input_by_name(
    joystick: float, trajectory: float, distances: object, fragment: str
) -> None:
    with pytest.raises(InputError, match=fragment):
        blend_commands(joystick, trajectory, distances, LAW)


def test_blend_rejects_unknown_mode() -> None:
    with pytest.raises(InputError, match="mode='hover' is not known"):
        proximity_term([0.3, 0.3], LAW, mode="hover")
