"""Fig. 4 blending (seed §3.1): the sum, nearer reading for avoidance, the servo distance sliding to the mean,
continuity across the standoff, range handling."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st

from rsi.control.blending import blend_commands, law_distance_m, proximity_term
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


def test_servoing_follows_the_mean_beyond_the_servo_peak() -> None:
    readings = [LAW.peak_distance_m + 0.01, LAW.peak_distance_m + 0.05]
    velocity, _, _ = proximity_term(readings, LAW, mode="servo")
    expected = proximity_velocity(np.mean(readings), LAW, mode="servo").velocity_m_s
    assert velocity == pytest.approx(expected)
    assert velocity < proximity_velocity(readings[0], LAW, mode="servo").velocity_m_s  # E falls with distance


@pytest.mark.parametrize("fraction", [0.0, 0.25, 0.5, 1.0])
def test_the_servo_distance_slides_from_the_nearer_reading_to_the_mean(fraction: float) -> None:
    # along D's rising half (standoff to peak) the weight of the mean rises as the law does
    nearer = LAW.standoff_m + fraction * (LAW.peak_distance_m - LAW.standoff_m)
    distance, nearest, _ = law_distance_m([nearer + 0.06, nearer], LAW, mode="servo")
    assert nearest == nearer
    assert distance == pytest.approx(nearer + fraction * 0.03, abs=1e-12)
    assert law_distance_m([nearer + 0.06, nearer], LAW)[0] == nearer  # avoidance: the nearer reading


def test_crossing_the_standoff_with_a_step_in_view_is_continuous() -> None:
    # one sensor on a step's top crosses the standoff while the other still sees the base 10 cm farther:
    # the command moves by the law's slope times the reading's change, not by the servo law at the mean
    epsilon_m = 1e-4
    inside, _, _ = proximity_term([LAW.standoff_m - epsilon_m, LAW.standoff_m + 0.1], LAW, mode="servo")
    outside, _, _ = proximity_term([LAW.standoff_m + epsilon_m, LAW.standoff_m + 0.1], LAW, mode="servo")
    slope = LAW.avoidance_slope_per_s
    assert abs(float(outside - inside)) <= slope * (1 + 0.05 / (LAW.peak_distance_m - LAW.standoff_m)) * 2e-4
    assert abs(float(inside)) < 1e-3  # the avoidance law at the standoff is zero


def _steepest_slope_per_s(law: ProximityLaw) -> float:
    distances, velocities = law.knots_m
    return float(np.max(np.abs(np.diff(velocities) / np.diff(distances))))


@settings(max_examples=60, deadline=None)
@given(
    start=st.tuples(st.floats(0.0, 0.75), st.floats(0.0, 0.75)),
    steps=st.lists(st.tuples(st.floats(-1.0, 1.0), st.floats(-1.0, 1.0)), min_size=2, max_size=60),
    delta_m=st.floats(1e-4, 0.02),
    mode=st.sampled_from(["avoidance", "servo"]),
)
@example(  # the nearer sensor crosses the standoff while the other sees a surface 8 cm farther
    start=(LAW.standoff_m - 0.005, LAW.standoff_m + 0.08),
    steps=[(1.0, 0.0)] * 10,
    delta_m=0.001,
    mode="servo",
)
def test_a_lipschitz_signal_gives_a_bounded_command_step(
    start: tuple[float, float], steps: list[tuple[float, float]], delta_m: float, mode: str
) -> None:
    # readings within range, each moving at most delta_m per sample: the command moves at most
    # s_max (1 + g / (peak - standoff)) delta_m, s_max the law's steepest slope, g the larger mean - nearest
    readings = np.clip(
        np.asarray(start) + np.cumsum(np.vstack([[0.0, 0.0], steps]), axis=0) * delta_m,
        0.0,
        LAW.max_distance_m,
    )
    assert np.abs(np.diff(readings, axis=0)).max() <= delta_m + 1e-12
    velocity, _, _ = proximity_term(readings, LAW, mode=mode)
    gap = np.abs(readings[:, 0] - readings[:, 1]) / 2
    larger_gap = np.maximum(gap[1:], gap[:-1])
    ramp_m = LAW.peak_distance_m - LAW.standoff_m
    bound = _steepest_slope_per_s(LAW) * (1 + larger_gap / ramp_m) * delta_m
    assert np.all(np.abs(np.diff(velocity)) <= bound + 1e-12)


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
