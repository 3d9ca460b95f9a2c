"""The one §3.1 proximity loop (Fig. 4) on the arm: step, driver, frames, determinism, bad input."""

from __future__ import annotations

import numpy as np
import pytest

from rsi.control.blending import proximity_term
from rsi.errors import InputError
from rsi.sensors.proximity import ProximitySensor
from rsi.sim.arm import Arm, Wall
from rsi.sim.proximity_loop import ARM_LAW, ProximityLoop, run_closed_loop

WALL_M = 0.49  # tool tip to wall: the sensors (recessed 0.11 m) read 0.60 m, inside the law's region E


def _arm() -> Arm:
    return Arm([Wall(WALL_M)])


def test_a_step_sends_joystick_plus_trajectory_plus_law_along_the_sensor_axis() -> None:
    arm = _arm()
    loop = ProximityLoop(arm, mode="servo", rng=3)
    tip_before, rotation = arm.tool_pose()
    sample = loop.step([0.02, 0.0, 0.05], joystick_m_s=0.1)
    expected, _, _ = proximity_term(sample.reading_m, ARM_LAW, mode="servo")
    assert sample.proximity_m_s == float(expected) > 0.0  # region E attracts toward the wall
    assert sample.command_m_s == pytest.approx(0.1 + 0.05 + sample.proximity_m_s, abs=1e-15)
    assert sample.true_m == pytest.approx([WALL_M + 0.11] * 2, abs=1e-9)
    assert sample.time_s == 0.0 and loop.samples == 1
    # the arm moved one period of the command along the axis and of the free motion across it
    moved = rotation.T @ (arm.tool_pose()[0] - tip_before)
    np.testing.assert_allclose(moved, [0.02 * loop.dt_s, 0.0, sample.command_m_s * loop.dt_s], atol=2e-4)


def test_world_and_tool_frames_give_the_same_step() -> None:
    samples, tips = [], []
    for frame in ("tool", "world"):
        arm = _arm()
        rotation = arm.tool_pose()[1]
        tool_velocity = np.array([0.03, 0.0, -0.02])
        velocity = tool_velocity if frame == "tool" else rotation @ tool_velocity
        loop = ProximityLoop(arm, mode="servo", rng=1)
        samples.append(loop.step(velocity, frame=frame))
        tips.append(arm.tool_pose()[0])
    tool, world = samples
    assert tool.trajectory_m_s == pytest.approx(world.trajectory_m_s, abs=1e-15)
    assert tool.command_m_s == pytest.approx(world.command_m_s, abs=1e-15)
    np.testing.assert_allclose(tips[0], tips[1], atol=1e-9)


def test_the_driver_is_the_step_repeated() -> None:
    trace = run_closed_loop(_arm(), duration_s=0.25, mode="servo", joystick_m_s=-0.05, rng=7)
    loop = ProximityLoop(_arm(), mode="servo", rng=7)
    samples = [loop.step(joystick_m_s=-0.05) for _ in range(trace.time_s.size)]
    assert trace.time_s.size == 11  # 0.25 s at 44 Hz
    np.testing.assert_array_equal(trace.command_m_s, [sample.command_m_s for sample in samples])
    np.testing.assert_array_equal(trace.reading_m, [sample.reading_m for sample in samples])
    np.testing.assert_allclose(np.diff(trace.time_s), 1 / 44.0)


def test_the_trace_keeps_the_trajectory_term_it_was_given() -> None:
    # Fig. 4's x_tg along the sensor axis, as the driver's schedule gave it at each sample's time
    trace = run_closed_loop(_arm(), duration_s=0.2, trajectory_m_s=lambda time_s: -0.01 - time_s, rng=0)
    np.testing.assert_allclose(trace.trajectory_m_s, -0.01 - trace.time_s, rtol=0, atol=1e-15)


def test_the_law_can_be_left_out_and_switched_between_steps() -> None:
    loop = ProximityLoop(_arm(), rng=2, apply_proximity=False)
    sample = loop.step([0.0, 0.0, -0.05], joystick_m_s=0.02)
    assert sample.command_m_s == pytest.approx(-0.03) and sample.proximity_m_s == 0.0  # avoidance: F is 0
    loop.mode = "servo"
    assert loop.step().proximity_m_s > 0.0  # computed (region E attracts), not applied


def test_sense_reads_the_sensors_and_leaves_the_arm_where_it_is() -> None:
    arm = _arm()
    joints, tip = arm.joint_positions, arm.tool_pose()[0]
    loop = ProximityLoop(arm, mode="servo", rng=5)
    samples = [loop.sense() for _ in range(10)]
    # not even a zero step: the joints are bit-identical (redundancy resolution would move the null space)
    assert np.array_equal(arm.joint_positions, joints) and np.array_equal(arm.tool_pose()[0], tip)
    assert loop.samples == 10 and samples[-1].time_s == pytest.approx(9 * loop.dt_s)  # the clock runs
    for sample in samples:
        assert sample.command_m_s == sample.joystick_m_s == sample.trajectory_m_s == 0.0
        expected, _, _ = proximity_term(sample.reading_m, ARM_LAW, mode="servo")
        assert sample.proximity_m_s == float(expected) > 0.0  # what the law would command, not sent
        assert sample.true_m == pytest.approx([WALL_M + 0.11] * 2, abs=1e-9)
    # the filtered readings of a still arm stay within the sensor's noise of the truth
    np.testing.assert_allclose([sample.reading_m for sample in samples], WALL_M + 0.11, atol=0.02)


def test_sense_and_step_read_the_same_sensors_with_the_same_noise() -> None:
    sensed = ProximityLoop(_arm(), rng=8).sense()
    stepped = ProximityLoop(_arm(), rng=8).step()
    np.testing.assert_array_equal(sensed.reading_m, stepped.reading_m)
    np.testing.assert_array_equal(sensed.origin_m, stepped.origin_m)


def test_sense_with_nothing_in_range_reads_no_return() -> None:
    sample = ProximityLoop(Arm([Wall(2.0)]), rng=0).sense()
    assert np.isinf(sample.true_m).all() and sample.out_of_range.all()
    assert sample.proximity_m_s == 0.0


def test_same_seed_same_run() -> None:
    first, again, other = (run_closed_loop(_arm(), duration_s=0.2, rng=seed) for seed in (4, 4, 5))
    np.testing.assert_array_equal(first.reading_m, again.reading_m)
    assert not np.array_equal(first.reading_m, other.reading_m)


def test_bad_input_names_the_argument() -> None:
    arm = _arm()
    with pytest.raises(InputError, match="duration_s"):
        run_closed_loop(arm, duration_s=0.0)
    with pytest.raises(InputError, match="mode"):
        run_closed_loop(arm, duration_s=0.1, mode="hover")
    with pytest.raises(InputError, match="sample_rate_hz"):
        run_closed_loop(arm, duration_s=0.1, sensor=ProximitySensor(sample_rate_hz=100.0))
    with pytest.raises(InputError, match="tangential_m_s"):
        run_closed_loop(arm, duration_s=0.1, tangential_m_s=float("nan"))
    loop = ProximityLoop(arm)
    with pytest.raises(InputError, match="law must be a ProximityLaw"):
        loop.law = "fast"  # type: ignore[assignment]
    with pytest.raises(InputError, match="mode"):
        loop.mode = "hover"
    with pytest.raises(InputError, match="velocity must be 3"):
        loop.step([0.0, 0.0])
    with pytest.raises(InputError, match="velocity must be 3"):
        loop.step([0.0, 0.0, np.nan])
    with pytest.raises(InputError, match="frame"):
        loop.step(frame="base")
    with pytest.raises(InputError, match="joystick_m_s must lie in"):
        loop.step(joystick_m_s=1.0)
    assert loop.samples == 0  # nothing moved
