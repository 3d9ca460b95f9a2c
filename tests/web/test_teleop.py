"""The console's teleop on the one §3.1 loop (Fig. 4): the blend, region C's non-override, hold-to-move."""

from __future__ import annotations

import numpy as np
import pytest

from rsi.control.proximity_law import proximity_velocity
from rsi.errors import InputError
from rsi.sim.arm import RANGEFINDER_RECESS_M, Arm, Wall
from rsi.sim.proximity_loop import ProximityLoop
from rsi.web.teleop import TELEOP_LAW, clamp_operator, teleop_loop, teleop_step

FULL_PUSH = [0.0, 0.0, TELEOP_LAW.joystick_speed_m_s]


def _loop_facing_wall(sensed_m: float) -> ProximityLoop:
    """The console's loop on the standalone arm at home, a wall `sensed_m` in front of its rangefinders."""
    return teleop_loop(Arm([Wall(distance_m=sensed_m - RANGEFINDER_RECESS_M)]), seed=0)


def test_the_console_loop_is_the_seed_law_in_avoidance() -> None:
    loop = _loop_facing_wall(0.5)
    assert loop.law == TELEOP_LAW and loop.mode == "avoidance" and loop.apply_proximity


def test_a_full_push_in_region_c_cannot_move_the_tool_toward_the_surface() -> None:
    law = TELEOP_LAW
    sensed = (law.avoidance_start_m + law.hold_distance_m) / 2  # inside region C
    loop = _loop_facing_wall(sensed)
    step = teleop_step(loop, FULL_PUSH, held=True)
    assert step.regions == ("C", "C")
    assert step.operator_m_s[2] == law.joystick_speed_m_s
    assert step.proximity_m_s <= -law.joystick_speed_m_s  # seed §3.1: C's law is below -Vjs
    assert step.commanded_m_s[2] <= 0.0  # the push is not obeyed: net retreat or hold
    true_m = []
    for _ in range(20):
        assert teleop_step(loop, FULL_PUSH, held=True).commanded_m_s[2] <= 0.0
        true_m.append(float(loop.rig.rangefinder_distances_m().min()))
    assert min(true_m) >= sensed - 1e-6  # the tool never got closer (true distance) over 20 full pushes


def test_far_from_the_surface_the_push_passes_through_unchanged() -> None:
    loop = _loop_facing_wall(0.70)  # region F: the law commands nothing
    before, rotation = loop.rig.tool_pose()
    step = teleop_step(loop, FULL_PUSH, held=True)
    assert step.regions == ("F", "F") and step.proximity_m_s == 0.0
    assert np.allclose(step.commanded_m_s, FULL_PUSH)
    advanced = float((loop.rig.tool_pose()[0] - before) @ rotation[:, 2])
    assert advanced == pytest.approx(TELEOP_LAW.joystick_speed_m_s / 44.0, rel=0.05)


def test_sideways_commands_pass_through_the_loop() -> None:
    loop = _loop_facing_wall(0.70)
    before, rotation = loop.rig.tool_pose()
    step = teleop_step(loop, [0.04, -0.03, 0.0], held=True)
    np.testing.assert_allclose(step.commanded_m_s, [0.04, -0.03, 0.0])
    moved = rotation.T @ (loop.rig.tool_pose()[0] - before)
    np.testing.assert_allclose(moved, [0.04 / 44.0, -0.03 / 44.0, 0.0], atol=2e-4)


def test_released_the_arm_does_not_move_at_all_even_where_the_law_would_retreat() -> None:
    arm = Arm([Wall(distance_m=0.13 - RANGEFINDER_RECESS_M)])  # region C, 2 cm in front of the jaw tips
    assert proximity_velocity(0.13, TELEOP_LAW).velocity_m_s < 0  # the law alone would retreat
    loop, joints = teleop_loop(arm, seed=0), arm.joint_positions
    for _ in range(10):
        step = teleop_step(loop, FULL_PUSH, held=False)
        assert np.array_equal(arm.joint_positions, joints)
        assert step.tool_speed_m_s == 0.0 and not step.commanded_m_s.any()
        assert step.regions == ("C", "C") and step.proximity_m_s < 0  # still sensed, shown, not sent
    assert loop.samples == 10  # the sensors' filters kept running at 44 Hz while released


def test_operator_commands_are_clamped_and_checked() -> None:
    assert np.allclose(clamp_operator([1.0, -1.0, 0.01]), [0.05, -0.05, 0.01])
    with pytest.raises(InputError, match=r"command_m_s must be 3 finite velocities"):
        clamp_operator([0.0, np.nan, 0.0])
    with pytest.raises(InputError, match=r"command_m_s must be 3 finite velocities"):
        clamp_operator([0.0, 0.0])
    with pytest.raises(InputError, match=r"command_m_s must be 3 finite velocities"):
        teleop_step(_loop_facing_wall(0.5), [0.0, 0.0], held=True)
