"""The solar-illumination simulator: kinematics, optics, limits and trajectories (seed §4.1, Fig. 10)."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from rsi.errors import InputError
from rsi.sim import solar_simulator as ss

ROUND_TRIP_TOL = 1e-9  # issue 3 acceptance: forward then inverse within 1e-9
DEG = math.pi / 180.0


def _between(low: float, high: float) -> st.SearchStrategy[float]:
    # The limits themselves are drawn on purpose: corners of the joint box are where rounding bites.
    return st.one_of(st.just(low), st.just(high), st.floats(low, high, allow_nan=False))


configurations = st.builds(
    ss.LampConfiguration,
    rho_m=_between(ss.RHO_MIN_M, 20.0),
    theta_rad=_between(*ss.THETA_RANGE_RAD),
    phi_rad=_between(*ss.PHI_RANGE_RAD),
    lambda_m=_between(*ss.LAMBDA_RANGE_M),
    gamma_m=_between(*ss.GAMMA_RANGE_M),
)


# The default mount is axis-aligned; a skewed, sloping rail makes the frame rotation round, which is where a
# spot straight back along the rail (theta = 180 deg) can come out a hair below y_R = 0.
mounts = st.sampled_from(
    [
        ss.LampMount(),
        ss.LampMount(rail_origin_world_m=(0.3, -1.7, 0.4), rail_direction_world=(0.8, 0.55, 0.2)),
    ]
)


def _joint_errors(first: ss.LampConfiguration, second: ss.LampConfiguration) -> np.ndarray:
    return np.abs(np.subtract(dataclasses.astuple(first), dataclasses.astuple(second)))


def _in_limits(configuration: ss.LampConfiguration) -> bool:
    values = dataclasses.astuple(configuration)
    return all(low <= value <= high for value, (low, high) in zip(values, ss.LIMITS.values(), strict=True))


# ------------------------------------------------------------------------------------------- kinematics


@settings(max_examples=300)
@given(configurations, mounts)
def test_forward_then_inverse_with_the_rail_given_round_trips(
    configuration: ss.LampConfiguration, mount: ss.LampMount
) -> None:
    task = ss.forward_kinematics(configuration, mount=mount)
    back = ss.inverse_kinematics(
        task.spot_world_m, beam_angle_rad=task.beam_angle_rad, rail_m=configuration.lambda_m, mount=mount
    )
    assert _joint_errors(configuration, back).max() < ROUND_TRIP_TOL


@settings(max_examples=300)
@given(configurations, mounts)
def test_forward_then_inverse_from_the_light_direction_and_intensity_round_trips(
    configuration: ss.LampConfiguration, mount: ss.LampMount
) -> None:
    # The rail is redundant; asking for light from where this lamp is must find this lambda again.
    task = ss.forward_kinematics(configuration, mount=mount)
    light_from = -ss.lamp_pose(configuration, mount=mount).beam_axis_world
    back = ss.inverse_kinematics(
        task.spot_world_m, intensity_lux=task.intensity_lux, light_from=light_from, mount=mount
    )
    assert _joint_errors(configuration, back).max() < ROUND_TRIP_TOL


spots = st.tuples(st.floats(-2.0, 7.0), st.floats(-3.0, 6.0), st.floats(-2.0, 4.0))


@settings(max_examples=300)
@given(spots, st.floats(10.0, 1e5), st.floats(0.0, 4.5))
def test_inverse_kinematics_answers_within_limits_or_raises(
    spot: tuple[float, float, float], intensity_lux: float, rail_m: float
) -> None:
    try:
        configuration = ss.inverse_kinematics(spot, intensity_lux=intensity_lux, rail_m=rail_m)
    except InputError as error:
        assert "seed §4.1" in str(error)
        return
    assert _in_limits(configuration)
    task = ss.forward_kinematics(configuration)
    assert np.allclose(task.spot_world_m, spot, rtol=0.0, atol=1e-9)
    assert task.intensity_lux == pytest.approx(intensity_lux, rel=1e-9)


@settings(max_examples=200)
@given(spots, st.floats(-1.0, 1.0), st.floats(-1.0, 1.0), st.floats(-1.0, 1.0))
def test_inverse_kinematics_from_a_direction_stays_within_limits(
    spot: tuple[float, float, float], dx: float, dy: float, dz: float
) -> None:
    try:
        configuration = ss.inverse_kinematics(
            spot, beam_angle_rad=20 * DEG, light_from=(dx, dy, dz), direction_tolerance_rad=math.pi
        )
    except InputError as error:
        assert "spot_world_m" in str(error) or "light_from" in str(error)
        return
    assert _in_limits(configuration)
    assert np.allclose(ss.forward_kinematics(configuration).spot_world_m, spot, rtol=0.0, atol=1e-9)


def test_the_frames_are_as_documented() -> None:
    # Default mount: rail along world +x at (0, -2, 1); theta = 90 deg, phi = 90 deg looks across the rail
    # (world +y), theta = 180 deg back along it (world -x), phi = 60 deg tilts 30 deg up.
    across = ss.LampConfiguration(rho_m=2.0, theta_rad=90 * DEG, phi_rad=90 * DEG, lambda_m=1.0, gamma_m=0.0)
    assert ss.forward_kinematics(across).spot_world_m == pytest.approx((1.0, 0.0, 1.0), abs=1e-12)
    back = dataclasses.replace(across, theta_rad=180 * DEG)
    assert ss.forward_kinematics(back).spot_world_m == pytest.approx((-1.0, -2.0, 1.0), abs=1e-12)
    up = dataclasses.replace(across, phi_rad=60 * DEG)
    assert ss.forward_kinematics(up).spot_world_m == pytest.approx(
        (1.0, 2.0 * math.sin(60 * DEG) - 2.0, 1.0 + 2.0 * math.cos(60 * DEG)), abs=1e-12
    )
    pose = ss.lamp_pose(up)
    rotation = pose.rotation_world_from_head
    assert np.allclose(rotation.T @ rotation, np.eye(3), atol=1e-12)
    assert np.linalg.det(rotation) == pytest.approx(1.0)
    assert pose.position_world_m == pytest.approx((1.0, -2.0, 1.0))


def test_a_tilted_rail_carries_its_frame() -> None:
    mount = ss.LampMount(rail_origin_world_m=(1.0, 2.0, 0.5), rail_direction_world=(0.0, -2.0, 0.0))
    rotation = ss.rotation_world_from_rail(mount)
    assert np.allclose(rotation, [[0, 1, 0], [-1, 0, 0], [0, 0, 1]], atol=1e-12)
    configuration = ss.LampConfiguration(
        rho_m=1.0, theta_rad=90 * DEG, phi_rad=90 * DEG, lambda_m=0.5, gamma_m=0.0
    )
    # lambda runs along world -y; theta = 90 deg looks along y_R = z x x_R = world +x
    assert ss.forward_kinematics(configuration, mount=mount).spot_world_m == pytest.approx((2.0, 1.5, 0.5))


# ----------------------------------------------------------------------------------------------- optics


def test_beam_angle_is_linear_in_focus_from_spot_to_flood() -> None:
    optics = ss.LampOptics()
    assert ss.beam_half_angle_rad(0.0) == pytest.approx(optics.spot_half_angle_rad)
    assert ss.beam_half_angle_rad(0.076) == pytest.approx(optics.flood_half_angle_rad)
    assert ss.beam_half_angle_rad(0.038) == pytest.approx(
        (optics.spot_half_angle_rad + optics.flood_half_angle_rad) / 2
    )
    angles = [ss.beam_half_angle_rad(gamma) for gamma in np.linspace(0.0, 0.076, 20)]
    assert np.all(np.diff(angles) > 0)
    assert ss.focus_for_beam_angle_m(ss.beam_half_angle_rad(0.05)) == pytest.approx(0.05)


def test_intensity_falls_with_rho_squared_at_fixed_focus() -> None:
    near = ss.spot_intensity_lux(1.0, 20 * DEG)
    assert ss.spot_intensity_lux(2.0, 20 * DEG) == pytest.approx(near / 4)
    assert ss.spot_intensity_lux(3.0, 20 * DEG) == pytest.approx(near / 9)
    # I = P / (pi (rho tan s)^2)
    assert near == pytest.approx(ss.LampOptics().beam_flux_lm / (math.pi * math.tan(20 * DEG) ** 2))


def test_focus_holds_the_intensity_as_rho_changes() -> None:
    for rho in (1.5, 2.5, 4.0):
        gamma = ss.focus_for_intensity_m(rho, 1950.0)
        assert ss.spot_intensity_lux(rho, ss.beam_half_angle_rad(gamma)) == pytest.approx(1950.0, rel=1e-12)
    # farther needs a narrower beam: focus toward the spot end
    assert ss.focus_for_intensity_m(4.0, 1950.0) < ss.focus_for_intensity_m(2.0, 1950.0)


def test_an_unreachable_intensity_names_the_focus_limit_and_the_range() -> None:
    with pytest.raises(InputError, match=r"intensity_lux=.*gamma's range \[0, 0.076\] m.*lux"):
        ss.focus_for_intensity_m(0.5, 1950.0)  # too close: even the flood is too bright
    with pytest.raises(InputError, match="intensity_lux"):
        ss.focus_for_intensity_m(2.0, -1.0)
    with pytest.raises(InputError, match="rho_m"):
        ss.focus_for_intensity_m(0.1, 1950.0)


def test_optics_functions_reject_bad_input() -> None:
    with pytest.raises(InputError, match=r"gamma_m=0.1 is outside gamma's range"):
        ss.beam_half_angle_rad(0.1)
    with pytest.raises(InputError, match="gamma_m must be finite"):
        ss.beam_half_angle_rad(math.nan)
    with pytest.raises(InputError, match=r"beam_angle_rad=.*gamma's range"):
        ss.focus_for_beam_angle_m(60 * DEG)
    with pytest.raises(InputError, match="beam_angle_rad"):
        ss.spot_intensity_lux(1.0, 0.0)
    with pytest.raises(InputError, match="rho_m"):
        ss.spot_intensity_lux(0.1, 0.2)


# --------------------------------------------------------------------------------------- errors, limits


@pytest.mark.parametrize(
    ("spot", "rail_m", "limit"),
    [
        ((5.5, 0.0, 1.0), 4.5, "theta"),  # ahead of the lamp: pan would pass 90 deg
        ((1.0, -1.9, 3.0), 1.0, "phi"),  # nearly overhead: tilt beyond 60 deg
        ((1.0, -1.95, 1.0), 1.0, "rho"),  # 5 cm from the lamp
    ],
)
def test_a_spot_needing_a_joint_outside_its_range_names_that_limit(
    spot: tuple[float, float, float], rail_m: float, limit: str
) -> None:
    with pytest.raises(InputError, match=rf"spot_world_m=.*needs {limit}=.*outside {limit}'s range"):
        ss.inverse_kinematics(spot, beam_angle_rad=20 * DEG, rail_m=rail_m)


def test_rail_and_spot_requests_outside_the_rail_raise() -> None:
    with pytest.raises(InputError, match=r"rail_m=5.0 is outside lambda's range \[0, 4.5\] m"):
        ss.inverse_kinematics((1.0, 0.0, 1.0), beam_angle_rad=20 * DEG, rail_m=5.0)
    with pytest.raises(InputError, match=r"spot_world_m=.*beyond the rail's lambda range"):
        ss.inverse_kinematics((6.0, 0.0, 1.0), beam_angle_rad=20 * DEG, light_from=(1.0, -1.0, 0.0))
    with pytest.raises(InputError, match=r"spot_world_m=.*far side of the rail"):
        ss.inverse_kinematics((1.0, -3.0, 1.0), beam_angle_rad=20 * DEG, light_from=(0.0, 1.0, 0.0))


@pytest.mark.parametrize(
    ("light_from", "reason"),
    [
        ((1.0, -1.0, 1.0), "in the plane through the spot and the rail"),
        ((-1.0, -1.0, 0.0), r"set by theta's range \[90, 180\] deg"),
        ((1.0, -0.01, 0.0), "the rail ends at lambda = 4.5 m"),
    ],
)
def test_a_light_direction_the_rail_cannot_give_says_why(
    light_from: tuple[float, float, float], reason: str
) -> None:
    with pytest.raises(InputError, match=rf"light_from=.*cannot be reproduced.*{reason}"):
        ss.inverse_kinematics((0.0, 0.0, 1.0), beam_angle_rad=20 * DEG, light_from=light_from)


def test_inverse_kinematics_rejects_bad_arguments() -> None:
    spot = (1.0, 0.0, 1.0)
    with pytest.raises(InputError, match="exactly one of rail_m"):
        ss.inverse_kinematics(spot, beam_angle_rad=0.3)
    with pytest.raises(InputError, match="exactly one of rail_m"):
        ss.inverse_kinematics(spot, beam_angle_rad=0.3, rail_m=1.0, light_from=(0, -1, 0))
    with pytest.raises(InputError, match="exactly one of beam_angle_rad or intensity_lux"):
        ss.inverse_kinematics(spot, rail_m=1.0)
    with pytest.raises(InputError, match="exactly one of beam_angle_rad or intensity_lux"):
        ss.inverse_kinematics(spot, rail_m=1.0, beam_angle_rad=0.3, intensity_lux=100.0)
    with pytest.raises(InputError, match="spot_world_m contains NaN"):
        ss.inverse_kinematics((math.nan, 0.0, 1.0), beam_angle_rad=0.3, rail_m=1.0)
    with pytest.raises(InputError, match=r"spot_world_m must have shape \(3,\)"):
        ss.inverse_kinematics((1.0, 0.0), beam_angle_rad=0.3, rail_m=1.0)
    with pytest.raises(InputError, match="spot_world_m must be a number or an array of numbers"):
        ss.inverse_kinematics(("a", 0.0, 1.0), beam_angle_rad=0.3, rail_m=1.0)
    with pytest.raises(InputError, match="rail_m must be finite"):
        ss.inverse_kinematics(spot, beam_angle_rad=0.3, rail_m=math.nan)
    with pytest.raises(InputError, match="beam_angle_rad must be finite"):
        ss.inverse_kinematics(spot, beam_angle_rad=math.nan, rail_m=1.0)
    with pytest.raises(InputError, match="intensity_lux must be in"):
        ss.inverse_kinematics(spot, intensity_lux=0.0, rail_m=1.0)
    with pytest.raises(InputError, match=r"intensity_lux=1e\+09.*gamma's range"):
        ss.inverse_kinematics(spot, intensity_lux=1e9, rail_m=1.0)
    with pytest.raises(InputError, match="light_from must be a non-zero direction"):
        ss.inverse_kinematics(spot, beam_angle_rad=0.3, light_from=(0.0, 0.0, 0.0))
    with pytest.raises(InputError, match="direction_tolerance_rad"):
        ss.inverse_kinematics(spot, beam_angle_rad=0.3, light_from=(0, -1, 0), direction_tolerance_rad=-1.0)
    with pytest.raises(InputError, match="configuration must be a LampConfiguration"):
        ss.forward_kinematics((1.0, 2.0, 1.5, 1.0, 0.0))  # type: ignore[arg-type]


@pytest.mark.parametrize(
    ("field", "value", "message"),
    [
        ("rho_m", 0.1, r"rho_m=0.1 is outside rho's range \[0.15, inf\] m"),
        ("theta_rad", 1.0, r"theta_rad=1.0 is outside theta's range \[90, 180\] deg"),
        ("phi_rad", 2.2, r"phi_rad=2.2 is outside phi's range \[60, 120\] deg"),
        ("lambda_m", -0.1, r"lambda_m=-0.1 is outside lambda's range \[0, 4.5\] m"),
        ("gamma_m", 0.08, r"gamma_m=0.08 is outside gamma's range \[0, 0.076\] m"),
        ("rho_m", math.nan, "rho_m must be finite"),
        ("theta_rad", "2", "theta_rad must be a number"),
    ],
)
def test_a_configuration_outside_the_seed_ranges_names_the_limit(
    field: str, value: object, message: str
) -> None:
    values: dict[str, object] = {
        "rho_m": 1.0,
        "theta_rad": 2.0,
        "phi_rad": 1.5,
        "lambda_m": 1.0,
        "gamma_m": 0.01,
    }
    values[field] = value
    with pytest.raises(InputError, match=message):
        ss.LampConfiguration(**values)  # type: ignore[arg-type]


def test_mount_optics_and_rates_validate() -> None:
    with pytest.raises(InputError, match=r"rail_direction_world=.*vertical"):
        ss.LampMount(rail_direction_world=(0.0, 0.001, 1.0))
    with pytest.raises(InputError, match="rail_direction_world must be a non-zero direction"):
        ss.LampMount(rail_direction_world=(0.0, 0.0, 0.0))
    with pytest.raises(InputError, match="rail_origin_world_m contains NaN"):
        ss.LampMount(rail_origin_world_m=(0.0, math.inf, 0.0))
    with pytest.raises(InputError, match="spot_half_angle_rad"):
        ss.LampOptics(spot_half_angle_rad=0.8, flood_half_angle_rad=0.7)
    with pytest.raises(InputError, match="flood_half_angle_rad"):
        ss.LampOptics(flood_half_angle_rad=math.pi / 2)
    with pytest.raises(InputError, match="beam_flux_lm"):
        ss.LampOptics(beam_flux_lm=0.0)
    with pytest.raises(InputError, match="gamma_m_s"):
        ss.RateLimits(gamma_m_s=-0.01)
    assert ss.LampMount(rail_direction_world=(2.0, 0.0, 0.0)).rail_direction_world == (1.0, 0.0, 0.0)


# ---------------------------------------------------------------------------------------- trajectories


@settings(max_examples=100)
@given(st.lists(configurations, min_size=2, max_size=6))
def test_planned_trajectories_keep_rates_and_limits(waypoints: list[ss.LampConfiguration]) -> None:
    distinct = [waypoints[0]]
    for point in waypoints[1:]:
        if _joint_errors(point, distinct[-1])[1:].max() > 0:
            distinct.append(point)
    if len(distinct) < 2:
        return
    rates = ss.RateLimits()
    trajectory = ss.plan_trajectory(distinct, rates=rates)
    speeds = np.abs(np.diff(trajectory.joints, axis=0)) / np.diff(trajectory.time_s)[:, None]
    assert (speeds <= rates.as_array() * (1 + 1e-9)).all()
    # minimum time: on every segment some joint runs at its limit
    assert np.allclose((speeds / rates.as_array()).max(axis=1), 1.0)
    fine = ss.sample_trajectory(trajectory, np.linspace(trajectory.time_s[0], trajectory.time_s[-1], 200))
    fine_speeds = np.abs(np.diff(fine.joints, axis=0)) / np.diff(fine.time_s)[:, None]
    assert (fine_speeds <= rates.as_array() * (1 + 1e-9)).all()
    assert all(_in_limits(fine.configuration(index)) for index in range(len(fine.time_s)))
    # sampling at the waypoint times gives the waypoints back
    again = ss.sample_trajectory(trajectory, trajectory.time_s)
    for index, point in enumerate(distinct):
        assert _joint_errors(again.configuration(index), point).max() < 1e-12


def test_plan_trajectory_times_a_single_pan_move() -> None:
    start = ss.LampConfiguration(rho_m=2.0, theta_rad=90 * DEG, phi_rad=90 * DEG, lambda_m=1.0, gamma_m=0.0)
    end = dataclasses.replace(start, theta_rad=180 * DEG)
    trajectory = ss.plan_trajectory([start, end], rates=ss.RateLimits(theta_rad_s=0.25), start_time_s=2.0)
    assert trajectory.time_s == pytest.approx([2.0, 2.0 + (math.pi / 2) / 0.25])
    middle = ss.sample_trajectory(trajectory, 2.0 + math.pi)
    assert middle.theta_rad[0] == pytest.approx(135 * DEG)


def test_trajectory_functions_reject_bad_input() -> None:
    point = ss.LampConfiguration(rho_m=2.0, theta_rad=2.0, phi_rad=1.5, lambda_m=1.0, gamma_m=0.0)
    other = dataclasses.replace(point, lambda_m=2.0)
    with pytest.raises(InputError, match="waypoints must hold at least one"):
        ss.plan_trajectory([])
    with pytest.raises(InputError, match=r"waypoints\[1\] has the same actuated joints"):
        ss.plan_trajectory([point, dataclasses.replace(point, rho_m=3.0)])
    with pytest.raises(InputError, match=r"waypoints\[0\] must be a LampConfiguration"):
        ss.plan_trajectory([(1, 2, 3, 4, 5)])  # type: ignore[list-item]
    with pytest.raises(InputError, match="start_time_s"):
        ss.plan_trajectory([point, other], start_time_s=-1.0)
    trajectory = ss.plan_trajectory([point, other])
    with pytest.raises(InputError, match=r"time_s must lie within the trajectory's \[0, 4\] s"):
        ss.sample_trajectory(trajectory, [0.0, 5.0])
    with pytest.raises(InputError, match="time_s must lie within"):
        ss.sample_trajectory(trajectory, -1.0)
    with pytest.raises(InputError, match="time_s must be a finite"):
        ss.sample_trajectory(trajectory, [math.nan])
    with pytest.raises(InputError, match="time_s must be numbers"):
        ss.sample_trajectory(trajectory, "soon")
    with pytest.raises(InputError, match="strictly increasing"):
        ss.sample_trajectory(trajectory, [2.0, 1.0])
    with pytest.raises(InputError, match="trajectory must be a Trajectory"):
        ss.sample_trajectory("path", 0.0)  # type: ignore[arg-type]
    ones = np.ones(2)
    with pytest.raises(InputError, match=r"theta_rad\[0\]=0.0 is outside theta's range"):
        ss.Trajectory(np.array([0.0, 1.0]), ones, np.zeros(2), ones * 1.5, ones, ones * 0.01)
    with pytest.raises(InputError, match=r"rho_m must have shape \(2,\)"):
        ss.Trajectory(np.array([0.0, 1.0]), np.ones(3), ones * 2, ones * 1.5, ones, ones * 0.01)
    with pytest.raises(InputError, match="time_s must be a non-empty 1-D array"):
        ss.Trajectory(np.array([]), *(np.array([]),) * 5)


def test_trajectories_are_read_only() -> None:
    point = ss.LampConfiguration(rho_m=2.0, theta_rad=2.0, phi_rad=1.5, lambda_m=1.0, gamma_m=0.0)
    trajectory = ss.plan_trajectory([point, dataclasses.replace(point, lambda_m=2.0)])
    with pytest.raises(ValueError, match="read-only"):
        trajectory.lambda_m[0] = 4.0
