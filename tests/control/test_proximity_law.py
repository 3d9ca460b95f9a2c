"""Proximity law (seed §3.1, Fig. 5): continuity, bounds, non-override in C, servo peak, F, range, errors."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st

from rsi.control.proximity_law import MODES, ProximityLaw, proximity_velocity
from rsi.errors import InputError

TINY_M_S = 1e-12


@st.composite
def laws(draw: st.DrawFn) -> ProximityLaw:
    """Valid laws: speeds and breakpoints drawn so that every constraint can hold, then checked."""
    joystick = draw(st.floats(0.01, 0.5))
    avoidance = joystick * draw(st.floats(1.05, 3.0))
    retreat = avoidance * draw(st.floats(1.0, 2.0))
    peak = joystick * draw(st.floats(0.05, 0.95))
    gaps = [draw(st.floats(0.02, 0.3)) for _ in range(4)]
    edges = np.cumsum([draw(st.floats(0.02, 0.2)), *gaps])
    try:
        law = ProximityLaw(
            joystick_speed_m_s=joystick,
            retreat_speed_m_s=retreat,
            avoidance_speed_m_s=avoidance,
            servo_peak_speed_m_s=peak,
            min_distance_m=float(edges[0]),
            avoidance_start_m=float(edges[1]),
            hold_distance_m=float(edges[2]),
            servo_end_m=float(edges[3]),
            max_distance_m=float(edges[4]),
            sample_rate_hz=draw(st.floats(20.0, 1000.0)),
        )
    except InputError:
        assume(False)
        raise
    return law


def _velocity(law: ProximityLaw, distance_m: object, mode: str) -> np.ndarray:
    return proximity_velocity(distance_m, law, mode=mode).velocity_m_s


def _max_slope(law: ProximityLaw) -> float:
    knots, speeds = law.knots_m
    return float(np.max(np.abs(np.diff(speeds) / np.diff(knots))))


def test_default_law_has_the_documented_shape() -> None:
    law = ProximityLaw()
    assert law.avoidance_slope_per_s == pytest.approx(0.375)
    assert law.standoff_m == pytest.approx(0.20 + 0.05 / 0.375)
    assert law.peak_distance_m == pytest.approx(0.20 + 0.08 / 0.375)
    command = proximity_velocity([0.0, 0.1, 0.15, 0.3, 0.42, 0.5, 0.75, 0.8, np.inf], law, mode="servo")
    assert command.region.tolist() == ["A", "B", "C", "D", "E", "F", "F", "-", "-"]
    assert command.out_of_range.tolist() == [False] * 7 + [True] * 2
    assert command.velocity_m_s[0] == -0.12  # region A: keep retreating
    assert command.velocity_m_s[5:].tolist() == [0.0] * 4


@settings(max_examples=60, deadline=None)
@given(law=laws(), mode=st.sampled_from(sorted(MODES)))
def test_law_is_continuous_at_every_breakpoint(law: ProximityLaw, mode: str) -> None:
    step_m = 1e-9
    for breakpoint_m in law.breakpoints_m[:5]:
        below, above = _velocity(law, [breakpoint_m - step_m, breakpoint_m + step_m], mode)
        assert abs(above - below) <= 2 * step_m * _max_slope(law) + TINY_M_S


@settings(max_examples=60, deadline=None)
@given(law=laws(), joystick_fraction=st.floats(-1.0, 1.0))
def test_full_joystick_push_cannot_override_regions_a_to_c(
    law: ProximityLaw, joystick_fraction: float
) -> None:
    joystick = joystick_fraction * law.joystick_speed_m_s
    distance = np.linspace(0.0, law.hold_distance_m, 401)
    for mode in MODES:
        net = _velocity(law, distance, mode) + joystick
        assert (net <= TINY_M_S).all()  # seed §3.1: region C cannot be overridden


@settings(max_examples=60, deadline=None)
@given(law=laws())
def test_bounds_servo_peak_and_pull_away(law: ProximityLaw) -> None:
    distance = np.linspace(0.0, law.max_distance_m * 1.2, 2001)
    servo = _velocity(law, distance, "servo")
    avoidance = _velocity(law, distance, "avoidance")
    assert servo.min() >= -law.retreat_speed_m_s - TINY_M_S
    assert servo.max() <= law.servo_peak_speed_m_s + TINY_M_S
    assert servo.max() < law.joystick_speed_m_s
    # a full negative joystick command always pulls the arm away
    assert (servo - law.joystick_speed_m_s < 0).all()
    np.testing.assert_array_equal(avoidance, np.minimum(servo, 0.0))
    assert (np.diff(avoidance) >= -TINY_M_S).all()  # the nearer, the harder it retreats


@settings(max_examples=60, deadline=None)
@given(law=laws(), fraction=st.floats(0.0, 1.0), beyond_m=st.floats(1e-9, 100.0))
def test_zero_in_f_and_flagged_zero_out_of_range(law: ProximityLaw, fraction: float, beyond_m: float) -> None:
    in_f = law.servo_end_m + fraction * (law.max_distance_m - law.servo_end_m)
    for mode in MODES:
        command = proximity_velocity([in_f, law.max_distance_m + beyond_m, np.inf], law, mode=mode)
        assert command.velocity_m_s.tolist() == [0.0, 0.0, 0.0]
        assert command.out_of_range.tolist() == [False, True, True]
        assert command.region.tolist() == ["F", "-", "-"]


def test_servo_attracts_beyond_the_standoff_and_avoidance_does_not() -> None:
    law = ProximityLaw()
    beyond = [law.standoff_m + 0.01, law.peak_distance_m]
    assert (_velocity(law, beyond, "servo") > 0).all()
    assert (_velocity(law, beyond, "avoidance") == 0).all()
    assert _velocity(law, law.peak_distance_m, "servo") == pytest.approx(law.servo_peak_speed_m_s)
    assert _velocity(law, law.standoff_m, "servo") == pytest.approx(0.0, abs=1e-15)


def test_vectorised_evaluation_keeps_shape() -> None:
    distance = np.full((3, 4), 0.15)
    command = proximity_velocity(distance)
    assert command.velocity_m_s.shape == command.region.shape == command.out_of_range.shape == (3, 4)


@pytest.mark.parametrize(
    ("changes", "fragment"),
    [
        ({"avoidance_start_m": 0.07}, "avoidance_start_m=0.07 must be greater than min_distance_m"),
        ({"hold_distance_m": 0.12}, "hold_distance_m=0.12 must be greater than avoidance_start_m"),
        ({"servo_end_m": 0.19}, "servo_end_m=0.19 must be greater than hold_distance_m"),
        ({"max_distance_m": 0.4}, "max_distance_m=0.4 must be greater than servo_end_m"),
        ({"servo_end_m": 0.40}, "servo_end_m=0.4 must be beyond the servo peak"),
        ({"joystick_speed_m_s": -0.05}, "joystick_speed_m_s must be in"),
        ({"retreat_speed_m_s": -0.1}, "retreat_speed_m_s must be in"),
        ({"avoidance_speed_m_s": 0.0}, "avoidance_speed_m_s must be in"),
        ({"servo_peak_speed_m_s": -0.01}, "servo_peak_speed_m_s must be in"),
        ({"min_distance_m": -0.08}, "min_distance_m must be in"),
        ({"sample_rate_hz": 0.0}, "sample_rate_hz must be in"),
        ({"min_distance_m": float("nan")}, "min_distance_m must be finite"),
        ({"servo_peak_speed_m_s": 0.05}, "servo_peak_speed_m_s=0.05 must be below joystick_speed_m_s"),
        ({"servo_peak_speed_m_s": 0.06}, "servo_peak_speed_m_s=0.06 must be below joystick_speed_m_s"),
        ({"avoidance_speed_m_s": 0.05}, "avoidance_speed_m_s=0.05 must exceed joystick_speed_m_s"),
        ({"retreat_speed_m_s": 0.07}, "retreat_speed_m_s=0.07 must be >= avoidance_speed_m_s"),
        ({"sample_rate_hz": 1.0}, "avoidance_start_m=0.12 makes a segment of slope"),
        ({"avoidance_start_m": 0.199}, "hold_distance_m=0.2 makes a segment"),
        ({"servo_end_m": 0.414, "max_distance_m": 0.75}, "servo_end_m=0.414 makes a segment"),
    ],
)
def test_law_rejects_each_bad_setting_by_name(changes: dict[str, float], fragment: str) -> None:
    with pytest.raises(InputError, match=fragment.replace("(", r"\(")):
        dataclasses.replace(ProximityLaw(), **changes)


@pytest.mark.parametrize(
    ("distance", "fragment"),
    [
        ([0.1, float("nan")], "distance_m contains NaN"),
        ([-0.01, 0.2], "distance_m must be >= 0 m"),
        (["near"], "distance_m must be a number or an array of numbers"),
    ],
)
def test_law_rejects_bad_distances(distance: object, fragment: str) -> None:
    with pytest.raises(InputError, match=fragment):
        proximity_velocity(distance)


def test_law_rejects_unknown_mode() -> None:
    with pytest.raises(InputError, match="mode='follow' is not known"):
        proximity_velocity(0.3, mode="follow")
