"""Configuration-control redundancy resolution (seed §1 [9]): DLS, null space, limits, arm angle."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from rsi.control.redundancy import (
    JointLimits,
    RedundancySettings,
    arm_angle_jacobian,
    arm_angle_rad,
    damped_least_squares,
    damped_pseudo_inverse,
    limit_avoidance_velocity,
    null_space_projector,
    orientation_error,
    resolve_joint_rates,
    singularity_damping,
)
from rsi.errors import InputError

N = 8
LIMITS = JointLimits(lower=-np.full(N, 2.0), upper=np.full(N, 2.0), max_rate=np.full(N, 1.0))


def _rotation(vector: np.ndarray) -> np.ndarray:
    angle = np.linalg.norm(vector)
    k = vector / angle
    skew = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    result: np.ndarray = np.eye(3) + np.sin(angle) * skew + (1 - np.cos(angle)) * skew @ skew
    return result


def test_zero_damping_on_a_square_regular_jacobian_is_the_inverse() -> None:
    jacobian = np.random.default_rng(1).normal(size=(6, 6))
    np.testing.assert_allclose(damped_pseudo_inverse(jacobian), np.linalg.inv(jacobian), atol=1e-10)
    velocity = np.arange(6.0)
    np.testing.assert_allclose(
        damped_least_squares(jacobian, velocity), np.linalg.solve(jacobian, velocity), atol=1e-10
    )


def test_zero_damping_on_a_wide_jacobian_is_the_pseudo_inverse() -> None:
    jacobian = np.random.default_rng(2).normal(size=(6, 8))
    np.testing.assert_allclose(damped_pseudo_inverse(jacobian), np.linalg.pinv(jacobian), atol=1e-10)


def test_damping_matches_the_normal_equations() -> None:
    jacobian = np.random.default_rng(3).normal(size=(6, 8))
    expected = jacobian.T @ np.linalg.inv(jacobian @ jacobian.T + 0.3**2 * np.eye(6))
    np.testing.assert_allclose(damped_pseudo_inverse(jacobian, damping=0.3), expected, atol=1e-12)


def test_damped_rates_are_bounded_at_an_exact_singularity() -> None:
    # rank 5: sigma = 0 in one direction; DLS gain sigma / (sigma^2 + lambda^2) <= 1 / (2 lambda)
    rng = np.random.default_rng(4)
    jacobian = rng.normal(size=(6, 5)) @ rng.normal(size=(5, 8))
    velocity = rng.normal(size=6)
    lam = singularity_damping(0.0, threshold=0.05, max_damping=0.05)
    assert lam == pytest.approx(0.05)
    rates = damped_least_squares(jacobian, velocity, damping=lam)
    assert np.linalg.norm(rates) <= np.linalg.norm(velocity) / (2 * lam) + 1e-12
    nearly = jacobian + 1e-9 * rng.normal(size=jacobian.shape)  # undamped: huge
    assert np.linalg.norm(damped_least_squares(nearly, velocity)) > 1e3 * np.linalg.norm(rates)


def test_singularity_damping_is_zero_above_the_threshold_and_grows_below() -> None:
    assert singularity_damping(0.2, threshold=0.1, max_damping=0.05) == 0.0
    values = [singularity_damping(s, threshold=0.1, max_damping=0.05) for s in (0.09, 0.05, 0.01, 0.0)]
    assert values == sorted(values)
    assert values[-1] == pytest.approx(0.05)


@settings(max_examples=40)
@given(seed=st.integers(0, 10_000))
def test_null_space_motion_does_not_move_the_task(seed: int) -> None:
    rng = np.random.default_rng(seed)
    jacobian = rng.normal(size=(7, 8))
    projector = null_space_projector(jacobian)
    motion = projector @ rng.normal(size=8)
    assert np.max(np.abs(jacobian @ motion)) < 1e-9
    assert np.trace(projector) == pytest.approx(1.0)  # one redundant direction: 8 joints, 7 rows


def test_resolved_rates_meet_both_tasks_away_from_singularities_and_limits() -> None:
    rng = np.random.default_rng(5)
    jacobian, extra = rng.normal(size=(6, 8)), rng.normal(size=8)
    twist = 0.05 * rng.normal(size=6)
    result = resolve_joint_rates(
        jacobian,
        twist,
        joint_positions=np.zeros(8),
        limits=LIMITS,
        dt_s=0.02,
        additional_jacobian=extra,
        additional_velocity=0.01,
        settings=RedundancySettings(singular_threshold=1e-3),
    )
    assert result.damping == 0.0 and result.rate_scale == 1.0
    np.testing.assert_allclose(jacobian @ result.joint_velocity, twist, atol=1e-10)
    assert extra @ result.joint_velocity == pytest.approx(0.01, abs=1e-10)


def test_limit_avoidance_acts_only_in_the_null_space() -> None:
    rng = np.random.default_rng(6)
    jacobian = rng.normal(size=(6, 8))
    near_limit = np.zeros(8)
    near_limit[3] = 1.95  # inside the 10 % zone of [-2, 2]
    push = limit_avoidance_velocity(near_limit, LIMITS, margin=0.1, gain_per_s=1.0)
    assert push[3] < 0 and np.count_nonzero(push) == 1
    still = resolve_joint_rates(
        jacobian,
        np.zeros(6),
        joint_positions=near_limit,
        limits=LIMITS,
        dt_s=0.02,
        settings=RedundancySettings(singular_threshold=1e-3),
    )
    assert np.max(np.abs(jacobian @ still.joint_velocity)) < 1e-9
    assert still.joint_velocity[3] < 0  # the joint backs off its limit while the tool stays


def test_a_joint_at_its_limit_is_locked_and_the_others_keep_the_task() -> None:
    rng = np.random.default_rng(7)
    jacobian = rng.normal(size=(6, 8))
    at_limit = np.zeros(8)
    at_limit[0] = 2.0
    twist = jacobian @ np.eye(8)[0] * 0.1  # pure motion of joint 0 beyond its limit
    result = resolve_joint_rates(
        jacobian,
        twist,
        joint_positions=at_limit,
        limits=LIMITS,
        dt_s=0.02,
        settings=RedundancySettings(singular_threshold=1e-3, limit_gain_per_s=0.0),
    )
    assert result.locked[0] and result.joint_velocity[0] <= 0.0
    np.testing.assert_allclose(jacobian @ result.joint_velocity, twist, atol=1e-9)


@settings(max_examples=150)
@given(
    seed=st.integers(0, 10_000),
    speed=st.floats(0.0, 5.0),
    dt_s=st.floats(0.001, 0.1),
)
def test_position_and_rate_limits_are_never_exceeded(seed: int, speed: float, dt_s: float) -> None:
    rng = np.random.default_rng(seed)
    jacobian = rng.normal(size=(6, 8))
    limits = JointLimits(
        lower=rng.uniform(-3, -0.1, 8), upper=rng.uniform(0.1, 3, 8), max_rate=rng.uniform(0.2, 2.0, 8)
    )
    q = rng.uniform(limits.lower, limits.upper)
    q[rng.integers(0, 8)] = limits.upper[0] if rng.random() < 0.5 else q[0]
    q = np.clip(q, limits.lower, limits.upper)
    twist = speed * rng.normal(size=6)
    result = resolve_joint_rates(
        jacobian,
        twist,
        joint_positions=q,
        limits=limits,
        dt_s=dt_s,
        additional_jacobian=rng.normal(size=8),
        additional_velocity=speed,
    )
    dq = result.joint_velocity
    assert np.all(np.abs(dq) <= limits.max_rate * (1 + 1e-12))
    assert np.all(q + dq * dt_s <= limits.upper + 1e-12)
    assert np.all(q + dq * dt_s >= limits.lower - 1e-12)
    assert 0 < result.rate_scale <= 1


def test_arm_angle_of_known_geometry() -> None:
    shoulder, wrist = np.zeros(3), np.array([1.0, 0.0, 0.0])
    up = np.array([0.0, 0.0, 1.0])
    assert arm_angle_rad(shoulder, [0.5, 0, 0.3], wrist, reference=up) == pytest.approx(0.0)
    # elbow swung to -y: a right-handed quarter turn about the shoulder-wrist line (+x) from up
    assert arm_angle_rad(shoulder, [0.5, -0.3, 0], wrist, reference=up) == pytest.approx(np.pi / 2)
    assert abs(arm_angle_rad(shoulder, [0.5, 0, -0.3], wrist, reference=up)) == pytest.approx(np.pi)


def test_arm_angle_jacobian_matches_finite_differences_of_a_swivel() -> None:
    # one "joint" that swivels the elbow about the shoulder-wrist line: d psi / dq = 1
    shoulder, elbow, wrist = np.zeros(3), np.array([0.5, 0.0, 0.3]), np.array([1.0, 0.0, 0.0])
    elbow_jacobian = np.cross([1.0, 0.0, 0.0], elbow - shoulder).reshape(3, 1)
    row = arm_angle_jacobian(
        shoulder,
        elbow,
        wrist,
        shoulder_jacobian=np.zeros((3, 1)),
        elbow_jacobian=elbow_jacobian,
        wrist_jacobian=np.zeros((3, 1)),
        reference=[0, 0, 1],
    )
    assert row[0] == pytest.approx(1.0, abs=1e-8)


def test_orientation_error_recovers_a_known_rotation() -> None:
    vector = np.array([0.2, -0.4, 0.1])
    base = _rotation(np.array([0.3, 0.2, -1.0]))
    np.testing.assert_allclose(orientation_error(_rotation(vector) @ base, base), vector, atol=1e-12)
    half = orientation_error(_rotation(np.array([0.0, np.pi, 0.0])), np.eye(3))
    assert np.linalg.norm(half) == pytest.approx(np.pi)
    assert abs(half[1]) == pytest.approx(np.pi)
    np.testing.assert_allclose(orientation_error(base, base), 0.0, atol=1e-15)


@pytest.mark.parametrize(
    ("call", "message"),
    [
        (lambda: JointLimits(np.zeros(2), np.ones(3), np.ones(2)), "upper"),
        (lambda: JointLimits(np.ones(2), np.zeros(2), np.ones(2)), "lower must be below"),
        (lambda: JointLimits(np.zeros(2), np.ones(2), np.array([1.0, 0.0])), "max_rate"),
        (lambda: JointLimits(np.array([np.nan, 0]), np.ones(2), np.ones(2)), "lower"),
        (lambda: RedundancySettings(max_damping=-1), "max_damping"),
        (lambda: RedundancySettings(singular_threshold=0), "singular_threshold"),
        (lambda: RedundancySettings(limit_margin=0.7), "limit_margin"),
        (lambda: RedundancySettings(additional_task_weight=0), "additional_task_weight"),
        (lambda: RedundancySettings(limit_gain_per_s=-1), "limit_gain_per_s"),
        (lambda: RedundancySettings(joint_weights=np.array([1.0, 0.0])), "joint_weights"),
        (lambda: damped_pseudo_inverse(np.zeros(3)), "jacobian"),
        (lambda: damped_pseudo_inverse("J"), "jacobian"),
        (lambda: damped_pseudo_inverse(np.full((2, 2), np.inf)), "jacobian"),
        (lambda: damped_pseudo_inverse(np.eye(2), damping=-1.0), "damping"),
        (lambda: damped_least_squares(np.eye(2), np.ones(3)), "task_velocity"),
        (lambda: damped_least_squares(np.eye(2), np.ones((2, 2))), "task_velocity"),
        (lambda: damped_least_squares(np.eye(2), object()), "task_velocity"),
        (lambda: null_space_projector(np.eye(2), rank_tolerance=0), "rank_tolerance"),
        (lambda: singularity_damping(-1, threshold=1, max_damping=1), "min_singular_value"),
        (lambda: singularity_damping(0, threshold=0, max_damping=1), "threshold"),
        (lambda: limit_avoidance_velocity(np.zeros(3), LIMITS), "joint_positions"),
        (lambda: limit_avoidance_velocity(np.zeros(8), LIMITS, margin=0), "margin"),
        (lambda: limit_avoidance_velocity(np.zeros(8), LIMITS, gain_per_s=-1), "gain_per_s"),
        (lambda: orientation_error(np.eye(2), np.eye(3)), "rotation_desired"),
        (lambda: arm_angle_rad([0, 0, 0], [1, 0, 0], [0, 0, 0], reference=[0, 0, 1]), "wrist_m"),
        (lambda: arm_angle_rad([0, 0, 0], [1, 0, 0], [2, 0, 0], reference=[0, 0, 0]), "reference"),
        (lambda: arm_angle_rad([0, 0], [1, 0, 0], [2, 0, 0], reference=[0, 0, 1]), "shoulder_m"),
        (
            lambda: arm_angle_jacobian(
                [0, 0, 0],
                [1, 1, 0],
                [2, 0, 0],
                shoulder_jacobian=np.zeros((3, 2)),
                elbow_jacobian=np.zeros((3, 3)),
                wrist_jacobian=np.zeros((3, 2)),
                reference=[0, 0, 1],
            ),
            "elbow_jacobian",
        ),
        (
            lambda: resolve_joint_rates(
                np.eye(6, 8), np.ones(6), joint_positions=np.zeros(8), limits=LIMITS, dt_s=0
            ),
            "dt_s",
        ),
        (
            lambda: resolve_joint_rates(
                np.eye(6, 7), np.ones(6), joint_positions=np.zeros(7), limits=LIMITS, dt_s=0.1
            ),
            "limits",
        ),
        (
            lambda: resolve_joint_rates(
                np.eye(6, 8), np.ones(6), joint_positions=np.full(8, 3.0), limits=LIMITS, dt_s=0.1
            ),
            "joint_positions",
        ),
        (
            lambda: resolve_joint_rates(
                np.eye(6, 8),
                np.ones(6),
                joint_positions=np.zeros(8),
                limits=LIMITS,
                dt_s=0.1,
                additional_jacobian=np.ones(8),
            ),
            "additional",
        ),
        (
            lambda: resolve_joint_rates(
                np.eye(6, 8),
                np.ones(6),
                joint_positions=np.zeros(8),
                limits=LIMITS,
                dt_s=0.1,
                additional_jacobian=np.ones(7),
                additional_velocity=0.0,
            ),
            "additional_jacobian",
        ),
        (
            lambda: resolve_joint_rates(
                np.eye(6, 8),
                np.ones(6),
                joint_positions=np.zeros(8),
                limits=LIMITS,
                dt_s=0.1,
                settings=RedundancySettings(joint_weights=np.ones(3)),
            ),
            "joint_weights",
        ),
    ],
)
def test_bad_input_raises_naming_the_argument(call: object, message: str) -> None:
    with pytest.raises(InputError, match=message):
        call()  # type: ignore[operator]
