"""The K1207-style arm on its rail with the ISEE (seed §1, §3): tracking, singularities, limits, ranges."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from rsi.control.redundancy import JointLimits, RedundancySettings, resolve_joint_rates
from rsi.errors import InputError
from rsi.sim.arm import (
    HOME_Q,
    LIMITS,
    RANGEFINDER_CUTOFF_M,
    RANGEFINDER_RECESS_M,
    Arm,
    CurvedSurface,
    SteppedSurface,
    Wall,
    track_path,
)

DT_S = 1.0 / 44.0  # seed §3.1: the 44 Hz loop


@pytest.fixture(scope="module")
def arm() -> Arm:
    return Arm()


@pytest.mark.parametrize("path", ["line", "circle"])
def test_cartesian_paths_are_tracked_within_a_millimetre_with_the_arm_angle_held(path: str) -> None:
    result = track_path(path, speed_m_s=0.1, rate_hz=44.0)
    assert result.arm_tracking_error_m <= 0.001
    assert result.additional_task_error_deg <= 1.0
    assert result.orientation_error_rad <= 1e-3
    assert result.max_rate_ratio <= 1.0


def test_tracking_holds_a_swivelled_arm_angle() -> None:
    result = track_path("circle", arm_angle_set_rad=0.4)
    assert result.arm_tracking_error_m <= 0.001
    assert result.additional_task_error_deg <= 1.0


def test_servo_mode_tracks_under_physics() -> None:
    # position actuators under full dynamics: lag at the velocity step limits it to a few mm
    result = track_path("line", mode="servo")
    assert result.arm_tracking_error_m <= 0.005
    assert result.additional_task_error_deg <= 1.0


def test_jacobian_matches_finite_differences(arm: Arm) -> None:
    q = HOME_Q + 0.1
    arm.reset(q)
    jacobian, psi_row = arm.jacobian(), arm.arm_angle_jacobian()
    h = 1e-6
    for j in range(8):
        step = np.eye(8)[j] * h
        arm.reset(q + step)
        plus, psi_plus = arm.tool_pose()[0], arm.arm_angle_rad()
        arm.reset(q - step)
        minus, psi_minus = arm.tool_pose()[0], arm.arm_angle_rad()
        np.testing.assert_allclose(jacobian[:3, j], (plus - minus) / (2 * h), atol=1e-7)
        assert psi_row[j] == pytest.approx((psi_plus - psi_minus) / (2 * h), abs=1e-6)
    arm.reset()


def test_home_pose_points_the_tool_at_the_truss(arm: Arm) -> None:
    arm.reset()
    _, rotation = arm.tool_pose()
    np.testing.assert_allclose(rotation[:, 2], [0.0, 1.0, 0.0], atol=1e-12)
    assert arm.arm_angle_rad() == pytest.approx(0.0, abs=1e-12)
    assert arm.jacobian().shape == (6, 8)


def test_damped_least_squares_bounds_rates_at_a_straight_wrist(arm: Arm) -> None:
    q = HOME_Q.copy()
    q[2], q[6] = -np.pi / 2, 0.0  # upper arm level, forearm down, w2 = 0: w1 and w3 aligned
    arm.reset(q)
    jacobian = arm.jacobian()
    augmented = np.vstack([jacobian, arm.arm_angle_jacobian()])
    assert np.linalg.svd(augmented, compute_uv=False)[-1] < 1e-9  # tool + arm angle: rank 6 of 7
    free = JointLimits(LIMITS.lower, LIMITS.upper, np.full(8, np.inf))
    conf = RedundancySettings(limit_gain_per_s=0.0)
    worst = 0.0
    for twist in np.random.default_rng(0).normal(size=(20, 6)) * 0.1:
        result = resolve_joint_rates(
            jacobian,
            twist,
            joint_positions=q,
            limits=free,
            dt_s=DT_S,
            additional_jacobian=arm.arm_angle_jacobian(),
            additional_velocity=0.0,
            settings=conf,
        )
        assert result.damping == pytest.approx(conf.max_damping)
        worst = max(worst, float(np.linalg.norm(result.joint_velocity) / np.linalg.norm(twist)))
    assert worst <= 1 / (2 * conf.max_damping)
    arm.reset()


def test_driving_through_the_wrist_singularity_keeps_rates_bounded(arm: Arm) -> None:
    q = HOME_Q.copy()
    q[2], q[6] = -np.pi / 2, 0.05
    arm.reset(q)
    # pitch the tool about its x axis (world x): w2 sweeps through 0 while the tip holds still
    rates, damped = [], []
    for _ in range(40):
        step = arm.step_velocity([0, 0, 0, -0.1, 0, 0], DT_S)
        rates.append(np.max(np.abs(step.joint_velocity) / LIMITS.max_rate))
        damped.append(step.damping > 0)
    assert arm.joint_positions[6] < -0.02  # it went through
    assert max(rates) <= 1.0 and any(damped)
    arm.reset()


@settings(max_examples=30)
@given(seed=st.integers(0, 10_000), speed=st.floats(0.0, 3.0))
def test_joint_position_and_rate_limits_are_never_exceeded(arm: Arm, seed: int, speed: float) -> None:
    rng = np.random.default_rng(seed)
    arm.reset(arm.random_configuration(rng, margin=0.02))
    for _ in range(15):
        twist = speed * rng.normal(size=6)
        step = arm.step_velocity(twist, DT_S, additional_task_rate=float(rng.normal()))
        q = arm.joint_positions
        assert np.all(q >= LIMITS.lower) and np.all(q <= LIMITS.upper)
        assert np.all(np.abs(step.joint_velocity) <= LIMITS.max_rate * (1 + 1e-12))
    arm.reset()


def test_identical_seeds_give_identical_trajectories() -> None:
    def run(seed: int) -> np.ndarray:
        arm, rng = Arm(), np.random.default_rng(seed)
        arm.reset(arm.random_configuration(rng))
        return np.array(
            [arm.step_velocity(0.05 * rng.normal(size=6), DT_S).tool_position_m for _ in range(20)]
        )

    np.testing.assert_array_equal(run(3), run(3))
    assert not np.array_equal(run(3), run(4))


@pytest.mark.parametrize("distance_m", [0.05, 0.2, 0.45, 0.6])
def test_rangefinders_read_the_wall_distance_plus_the_recess(distance_m: float) -> None:
    arm = Arm(obstacles=[Wall(distance_m)])
    np.testing.assert_allclose(arm.rangefinder_distances_m(), distance_m + RANGEFINDER_RECESS_M, atol=1e-3)
    # move 0.1 m toward it along the tool axis: the reading drops by the same
    for _ in range(44):
        arm.step_velocity([0.0, 0.0, 0.1 * 0.5], DT_S, frame="tool")
    np.testing.assert_allclose(
        arm.rangefinder_distances_m(), distance_m - 0.05 + RANGEFINDER_RECESS_M, atol=1e-3
    )


def test_rangefinders_report_no_return_and_saturation_as_mujoco_does() -> None:
    np.testing.assert_array_equal(Arm().rangefinder_distances_m(), -RANGEFINDER_CUTOFF_M)  # nothing there
    np.testing.assert_array_equal(Arm(obstacles=[Wall(0.9)]).rangefinder_distances_m(), RANGEFINDER_CUTOFF_M)


def test_stepped_and_curved_surfaces_read_their_profiles() -> None:
    for obstacle in (SteppedSurface(0.4), CurvedSurface(0.3, radius_m=0.25, centre_m=0.1)):
        arm = Arm(obstacles=[obstacle])
        x0 = arm.tool_pose()[0][0]
        for _ in range(70):  # scan along the rail direction at 0.1 m/s
            arm.step_velocity([0.1, 0.0, 0.0], DT_S)
            left = arm.site_position_m("range_left")[0] - x0
            right = arm.site_position_m("range_right")[0] - x0
            tool_y = arm.tool_pose()[0][1] - arm.site_position_m("range_left")[1]  # the recess, m
            expected = obstacle.surface_distance_m(np.array([left, right])) + tool_y
            readings = arm.rangefinder_distances_m()
            # one sensor can straddle a step edge within a millimetre of travel: skip those samples
            edge = [abs(x - e) < 2e-3 for x in (left, right) for e in (0.1, 0.3, 0.5)]
            if not any(edge):
                np.testing.assert_allclose(readings, expected, atol=1e-3)


def test_force_torque_and_cameras_exist(arm: Arm) -> None:
    arm.reset()
    force, torque = arm.force_torque()
    assert force.shape == torque.shape == (3,)
    names = {arm.model.camera(i).name for i in range(arm.model.ncam)}
    lights = {arm.model.light(i).name for i in range(arm.model.nlight)}
    assert {"isee_left", "isee_right"} <= names
    assert {"strobe_left", "strobe_right", "halogen_left", "halogen_right"} <= lights


def test_the_flange_carries_the_isee_weight_wherever_the_arm_drives_it(arm: Arm) -> None:
    """Kinematic mode, no contact: the F/T reads the weight of the body under its site and nothing else,
    however far the tool is driven (it once grew like a spring, to 290 N after 0.1 m)."""
    arm.reset()
    start = arm.tool_pose()[0]
    site = next(k for k in range(arm.model.nsite) if arm.model.site(k).name.endswith("ft"))
    weight_n = arm.model.body_subtreemass[arm.model.site_bodyid[site]] * np.linalg.norm(arm.model.opt.gravity)
    readings = []
    for command in ([0.0, 0.0, 0.02], [0.02, 0.0, 0.0], [0.0, 0.02, 0.0]):
        for _ in range(110):  # 5 cm each way at 2 cm/s and 44 Hz
            arm.step_velocity(command, 1 / 44.0, frame="tool")
        readings.append(np.linalg.norm(arm.force_torque()[0]))
    assert np.linalg.norm(arm.tool_pose()[0] - start) > 0.08  # it did drive
    np.testing.assert_allclose(readings, weight_n, rtol=1e-4)  # the joint rates add ~4e-5 of Coriolis load


@pytest.mark.parametrize(
    ("call", "message"),
    [
        (lambda: Arm(mode="teleport"), "mode"),
        (lambda: Arm(position_gain=0.0), "position_gain"),
        (lambda: Wall(-0.1), "distance_m"),
        (lambda: SteppedSurface(0.4, steps=((0.3, 0.2, 0.05),)), "steps"),
        (lambda: SteppedSurface(0.4, steps=((0.1, 0.2, 0.5),)), "height"),
        (lambda: SteppedSurface(0.4, steps=((0.1, 0.2),)), "steps"),  # type: ignore[arg-type]
        (lambda: CurvedSurface(0.3, radius_m=0.0), "radius_m"),
        (lambda: CurvedSurface(0.3, wall_distance_m=0.2), "wall_distance_m"),
        (lambda: track_path("square"), "path"),
        (lambda: track_path("line", speed_m_s=0.0), "speed_m_s"),
    ],
)
def test_bad_input_raises_naming_the_argument(call: object, message: str) -> None:
    with pytest.raises(InputError, match=message):
        call()  # type: ignore[operator]


@pytest.mark.parametrize(
    ("command", "kwargs", "message"),
    [
        (np.zeros(4), {}, "twist_or_velocity"),
        (np.array([np.nan, 0, 0]), {}, "twist_or_velocity"),
        (np.zeros(3), {"frame": "camera"}, "frame"),
        (np.zeros(3), {"additional_task_rate": np.inf}, "additional_task_rate"),
    ],
)
def test_bad_step_commands_raise(
    arm: Arm, command: np.ndarray, kwargs: dict[str, object], message: str
) -> None:
    with pytest.raises(InputError, match=message):
        arm.step_velocity(command, DT_S, **kwargs)  # type: ignore[arg-type]
    with pytest.raises(InputError, match="dt_s"):
        arm.step_velocity(np.zeros(3), 0.0)


def test_bad_reset_and_obstacle_raise(arm: Arm) -> None:
    with pytest.raises(InputError, match="joint_positions"):
        arm.reset(np.zeros(7))
    with pytest.raises(InputError, match="outside the limits"):
        arm.reset(np.full(8, 3.0))
    with pytest.raises(InputError, match="jaw_opening_m"):
        arm.reset(jaw_opening_m=0.5)
    with pytest.raises(InputError, match="name"):
        arm.site_position_m("nose")
    with pytest.raises(InputError, match="obstacle"):
        Arm(obstacles=["wall"])  # type: ignore[list-item]
    arm.reset()
