"""The console's teleop step (seed §3.1, Fig. 4): the blend, region C's non-override, hold-to-move."""

from __future__ import annotations

import numpy as np
import pytest

from rsi.control.proximity_law import proximity_velocity
from rsi.errors import InputError
from rsi.sim.arm import RANGEFINDER_RECESS_M, Arm, Wall
from rsi.web.teleop import TELEOP_LAW, clamp_operator, sensed_distances_m, teleop_step

FULL_PUSH = [0.0, 0.0, TELEOP_LAW.joystick_speed_m_s]


def _arm_facing_wall(sensed_m: float) -> Arm:
    """The standalone arm at home, a wall `sensed_m` in front of its rangefinders."""
    return Arm([Wall(distance_m=sensed_m - RANGEFINDER_RECESS_M)])


def test_a_full_push_in_region_c_cannot_move_the_tool_toward_the_surface() -> None:
    law = TELEOP_LAW
    sensed = (law.avoidance_start_m + law.hold_distance_m) / 2  # inside region C
    arm = _arm_facing_wall(sensed)
    step = teleop_step(arm, FULL_PUSH, held=True)
    assert step.regions == ("C", "C")
    assert step.operator_m_s[2] == law.joystick_speed_m_s
    assert step.proximity_m_s <= -law.joystick_speed_m_s  # seed §3.1: C's law is below -Vjs
    assert step.commanded_m_s[2] <= 0.0  # the push is not obeyed: net retreat or hold
    distances = [teleop_step(arm, FULL_PUSH, held=True).distances_m.min() for _ in range(20)]
    assert min(distances) >= sensed - 1e-6  # the tool never got closer over 20 periods of a full push


def test_far_from_the_surface_the_push_passes_through_unchanged() -> None:
    arm = _arm_facing_wall(0.70)  # region F: the law commands nothing
    before = arm.tool_pose()[0]
    step = teleop_step(arm, FULL_PUSH, held=True)
    assert step.regions == ("F", "F") and step.proximity_m_s == 0.0
    assert np.allclose(step.commanded_m_s, FULL_PUSH)
    axis = arm.tool_pose()[1][:, 2]
    advanced = float((arm.tool_pose()[0] - before) @ axis)
    assert advanced == pytest.approx(TELEOP_LAW.joystick_speed_m_s / 44.0, rel=0.05)


def test_released_the_arm_does_not_move_at_all_even_where_the_law_would_retreat() -> None:
    arm = _arm_facing_wall(0.13)  # region C, 2 cm in front of the jaw tips: the law alone would retreat
    assert proximity_velocity(0.13, TELEOP_LAW).velocity_m_s < 0
    joints = arm.joint_positions
    step = teleop_step(arm, FULL_PUSH, held=False)
    assert np.array_equal(arm.joint_positions, joints)
    assert step.tool_speed_m_s == 0.0 and not step.commanded_m_s.any()


def test_sideways_commands_pass_and_operator_commands_are_clamped() -> None:
    assert np.allclose(clamp_operator([1.0, -1.0, 0.01]), [0.05, -0.05, 0.01])
    with pytest.raises(InputError, match=r"command_m_s must be 3 finite velocities"):
        clamp_operator([0.0, np.nan, 0.0])
    with pytest.raises(InputError, match=r"command_m_s must be 3 finite velocities"):
        clamp_operator([0.0, 0.0])
    assert np.array_equal(sensed_distances_m(np.array([-0.75, 0.75, 0.3])), [np.inf, np.inf, 0.3])
